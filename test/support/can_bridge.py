"""The live CAN bridge run from a test: its command line, waiting for its log line and for its
frame count on /diagnostics (a test node spun here), and the messages of the bag it recorded."""

from __future__ import annotations

import subprocess
import sys
import time
from pathlib import Path

import rclpy
from diagnostic_msgs.msg import DiagnosticArray
from rclpy.qos import QoSProfile, ReliabilityPolicy
from rosbags.rosbag2 import Reader
from rosbags.typesys import Stores, get_types_from_msg, get_typestore


def cli_command(*args: str) -> list[str]:
    """The argv that runs `linkage-monitor ARGS` with this interpreter."""
    return [sys.executable, "-m", "linkage_monitor.cli.main", *args]


def bag_messages(bag: Path, topic: str) -> list:
    """The messages of ``topic`` decoded by rosbags with the bag's own definitions."""
    with Reader(bag) as reader:
        [connection] = [c for c in reader.connections if c.topic == topic]
        store = get_typestore(Stores.EMPTY)
        store.register(get_types_from_msg(connection.msgdef.data, connection.msgtype))
        return [store.deserialize_cdr(data, connection.msgtype) for _, _, data in reader.messages([connection])]


def wait_for_frame_count(total: int, timeout: float = 90.0) -> str:
    """Spin a test node on /diagnostics until the bridge's frame-count status says ``total`` frames
    were received (it repeats it every heartbeat); returns that status text."""
    node = rclpy.create_node("can_bridge_test")
    seen: list[str] = []
    node.create_subscription(DiagnosticArray, "/diagnostics",
                             lambda m: seen.extend(s.message for s in m.status if s.name.endswith(": can")),
                             QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE))
    try:
        end = time.monotonic() + timeout
        while time.monotonic() < end:
            rclpy.spin_once(node, timeout_sec=0.1)
            if seen and seen[-1].startswith(f"{total} frames"):
                return seen[-1]
        raise AssertionError(f"the bridge did not count {total} frames within {timeout} s: {seen[-1:]}")
    finally:
        node.destroy_node()


def wait_for_log_line(path: Path, text: str, proc: subprocess.Popen, timeout: float = 60.0) -> None:
    """Wait until the log file at ``path`` holds ``text``; fails if ``proc`` exits first or ``timeout`` s pass."""
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if path.exists() and text in path.read_text():
            return
        assert proc.poll() is None, f"bridge exited ({proc.returncode}):\n{path.read_text()}"
        time.sleep(0.1)
    raise AssertionError(f"bridge did not log {text!r} within {timeout} s:\n{path.read_text()}")


def close_rig(sender, executor, bridge, listener) -> None:
    """Shut down a test's CAN sender (a python-can bus) and its executor, then close and destroy the
    bridge node and the test's listener node, in that order."""
    sender.shutdown()
    executor.shutdown()
    bridge.close()
    bridge.destroy_node()
    listener.destroy_node()
