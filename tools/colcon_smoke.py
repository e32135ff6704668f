"""Part of `make colcon-check`: run from a colcon workspace's environment (its install/setup.sh
sourced). Checks that linkage_monitor and its messages are imported from that install tree (not
from the repository), then starts the node from it and checks the outputs of one input pose.

Usage: python -P tools/colcon_smoke.py INSTALL_DIR
"""

from __future__ import annotations

import importlib.util
import os
import signal
import subprocess
import sys
import time
from pathlib import Path


def main() -> int:
    install = Path(sys.argv[1]).resolve()
    import linkage_monitor
    from linkage_monitor.msg import HingeReactions, HitchState, Steerability

    for module in (linkage_monitor, sys.modules[HingeReactions.__module__]):
        where = Path(module.__file__ or "").resolve()
        print(f"{module.__name__}: {where}")
        if install not in where.parents:
            print(f"colcon-check: {module.__name__} was imported from {where}, not from {install}", file=sys.stderr)
            return 1
    print(f"typesupport: {importlib.util.find_spec('linkage_monitor.linkage_monitor_s__rosidl_typesupport_c').origin}")

    import rclpy
    from rclpy.qos import QoSProfile, ReliabilityPolicy
    from sensor_msgs.msg import FluidPressure, JointState
    from std_msgs.msg import Header

    os.environ.setdefault("ROS_DOMAIN_ID", str(100 + os.getpid() % 100))
    node = subprocess.Popen([sys.executable, "-P", "-m", "linkage_monitor.ros.node", "--ros-args",
                             "-p", "record:=false", "-p", "sensor_qos:=reliable"], env=dict(os.environ))
    rclpy.init()
    client = rclpy.create_node("colcon_smoke")
    qos = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE)
    got: dict[str, list] = {"hinge_reactions": [], "hitch_state": [], "steerability": []}
    for topic, cls in (("hinge_reactions", HingeReactions), ("hitch_state", HitchState), ("steerability", Steerability)):
        client.create_subscription(cls, topic, got[topic].append, qos)
    joints = client.create_publisher(JointState, "joint_states", qos)
    pressure = client.create_publisher(FluidPressure, "pressure/lift_cap_pressure", qos)
    try:
        end = time.monotonic() + 300.0   # s: a node that compiles its kernels subscribes after
        while time.monotonic() < end and not (joints.get_subscription_count() and pressure.get_subscription_count()):
            rclpy.spin_once(client, timeout_sec=0.1)
        time.sleep(0.5)
        stamp = client.get_clock().now().to_msg()
        ref_pressure = 9.1e6   # Pa absolute, a loaded lift
        pressure.publish(FluidPressure(header=Header(stamp=stamp), fluid_pressure=ref_pressure))
        time.sleep(0.2)
        # belarus_1221's reference pose (its preset file: reference_inputs)
        from linkage_monitor.mechanics import load_preset
        ref = load_preset("belarus_1221").reference_inputs
        joints.publish(JointState(header=Header(stamp=stamp), name=[*ref["cylinders"], *ref["angles"]],
                                  position=[*ref["cylinders"].values(), *ref["angles"].values()]))
        end = time.monotonic() + 20.0
        while time.monotonic() < end and not all(got.values()):
            rclpy.spin_once(client, timeout_sec=0.1)
    finally:
        client.destroy_node()
        rclpy.shutdown()
        node.send_signal(signal.SIGINT)
        code = node.wait(timeout=20)
    if not all(got.values()) or code != 0:
        print(f"colcon-check: outputs received {[(k, len(v)) for k, v in got.items()]}, node exit code {code}",
              file=sys.stderr)
        return 1
    h = got["hinge_reactions"][-1]
    print(f"node from the install tree: {len(h.hinges)} hinge reactions, status {h.status}, "
          f"P03 {next(x.magnitude for x in h.hinges if x.name == 'P03') / 1e3:.1f} kN; "
          f"lift reserve {got['hitch_state'][-1].lift_reserve:.2f}; steerability margin {got['steerability'][-1].margin:+.3f}")
    print("colcon-check: ok")
    return 0


if __name__ == "__main__":
    sys.exit(main())
