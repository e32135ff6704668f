"""The custom messages travel between processes through real rclpy, field for field."""

from __future__ import annotations

import subprocess
import sys
import time
from pathlib import Path

import rclpy
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy

from support.messages import CUSTOM_TYPES, message_class, samples, to_dict

HERE = Path(__file__).parent


def test_every_custom_message_is_received_in_another_process_field_for_field():
    seed = 20261122
    child = subprocess.Popen([sys.executable, str(HERE / "support" / "publish_samples.py"),
                              str(seed), "30"])
    received: dict[str, object] = {}
    rclpy.init()
    try:
        node = rclpy.create_node("sample_subscriber")
        qos = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE,
                         durability=DurabilityPolicy.TRANSIENT_LOCAL)
        for name in CUSTOM_TYPES:
            node.create_subscription(message_class(f"linkage_monitor/msg/{name}"),
                                     f"samples/{name}",
                                     lambda msg, name=name: received.setdefault(name, msg), qos)
        deadline = time.monotonic() + 25
        while len(received) < len(CUSTOM_TYPES) and time.monotonic() < deadline:
            rclpy.spin_once(node, timeout_sec=0.1)
        node.destroy_node()
    finally:
        rclpy.shutdown()
        child.terminate()
        child.wait(timeout=10)
    expected = samples(seed)  # same seed, built independently in this process
    assert sorted(received) == sorted(CUSTOM_TYPES)
    for name in CUSTOM_TYPES:
        assert to_dict(received[name]) == to_dict(expected[name]), name


def test_samples_fill_every_field_with_non_default_values():
    """Guards the test above: a sample equal to the default message would prove nothing."""
    for name, msg in samples(3).items():
        default = to_dict(message_class(f"linkage_monitor/msg/{name}")())
        values = to_dict(msg)
        for field, value in values.items():
            if field != "header":
                assert value != default[field], (name, field)
