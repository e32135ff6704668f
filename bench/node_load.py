"""The floor of bench_node.py: a no-op rclpy node that republishes every JointState's header as a
HitchState on `hitch_state` (same QoS as linkage_monitor's node, nothing solved, nothing recorded).

Usage: .venv/bin/python bench/node_load.py   (run by bench/bench_node.py; Ctrl-C ends it)
"""

from __future__ import annotations

import rclpy
from rclpy.executors import ExternalShutdownException
from rclpy.qos import QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import JointState
from std_msgs.msg import String

from linkage_monitor.msg import HitchState
from linkage_monitor.ros.node import LATCHED, OUTPUT_QOS

INPUT_QOS = QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE)  # the node's sensor_qos = reliable


def main() -> None:
    """Spin the relay until Ctrl-C; publishes a latched `mechanism_description` so the bench knows it is up."""
    rclpy.init()
    node = rclpy.create_node("bench_relay")
    pub = node.create_publisher(HitchState, "hitch_state", OUTPUT_QOS)
    node.create_publisher(String, "mechanism_description", LATCHED).publish(String(data="relay"))
    node.create_subscription(JointState, "joint_states", lambda msg: pub.publish(HitchState(header=msg.header)),
                             INPUT_QOS)
    try:
        rclpy.spin(node)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        node.destroy_node()
        rclpy.try_shutdown()


if __name__ == "__main__":
    main()
