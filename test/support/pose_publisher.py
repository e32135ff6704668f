"""Child process for test_node_sources: a node of its own name publishing one pose on `joint_states`.

Usage: python pose_publisher.py NODE_NAME RATE_HZ JOINT=VALUE ... Waits for a subscriber, then publishes
a JointState of the given positions (rad, m) stamped with the wall clock, reliable, at RATE_HZ until
Ctrl-C; then prints `sent N` (the messages it published) and exits 0.
"""

from __future__ import annotations

import sys
import time

import rclpy
from rclpy.qos import QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import JointState

from linkage_monitor.ros.messages import header


def main() -> None:
    name, rate_hz = sys.argv[1], float(sys.argv[2])
    joints = dict(arg.split("=") for arg in sys.argv[3:])
    rclpy.init()
    node = rclpy.create_node(name)
    pub = node.create_publisher(JointState, "joint_states", QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE))
    sent = 0
    try:
        while pub.get_subscription_count() == 0:
            time.sleep(0.01)
        time.sleep(0.5)   # the subscriber sees the match after the publisher does
        print("publishing", flush=True)
        while True:
            pub.publish(JointState(header=header(time.time_ns()), name=list(joints),
                                   position=[float(v) for v in joints.values()]))
            sent += 1
            time.sleep(1.0 / rate_hz)
    except KeyboardInterrupt:
        pass
    print(f"sent {sent}", flush=True)
    node.destroy_node()
    rclpy.try_shutdown()


if __name__ == "__main__":
    main()
