"""Child process for test_messages: publishes the sample of each custom message.

Usage: python publish_samples.py SEED SECONDS. Publishes every sample on topic
`samples/<Type>` (reliable, transient local) and spins until SECONDS have passed.
"""

from __future__ import annotations

import sys
import time

import rclpy
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy

from messages import message_class, samples

LATCHED = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE,
                     durability=DurabilityPolicy.TRANSIENT_LOCAL)


def main() -> None:
    seed, seconds = int(sys.argv[1]), float(sys.argv[2])
    rclpy.init()
    node = rclpy.create_node("sample_publisher")
    for name, msg in samples(seed).items():
        node.create_publisher(message_class(f"linkage_monitor/msg/{name}"),
                              f"samples/{name}", LATCHED).publish(msg)
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        rclpy.spin_once(node, timeout_sec=0.1)
    node.destroy_node()
    rclpy.shutdown()


if __name__ == "__main__":
    main()
