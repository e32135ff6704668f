"""CPU of a monitor node process per solved input: the plain node against the managed one.

    .venv/bin/python bench/node_cpu_per_input.py plain|managed

Starts the node (``linkage_monitor.ros.node`` or ``linkage_monitor.ros.lifecycle_node``, the latter
configured and activated over its lifecycle services), publishes 1000 JointStates of belarus_1221
at 200 Hz (no pressure, no recording) and prints the node process's user + system CPU time per
input, ms, from /proc/<pid>/stat. Run the two alternately: the machine's load moves both.
"""

from __future__ import annotations

import os
import subprocess
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "test"))
from support.ros_env import isolate_ros_domain  # noqa: E402

isolate_ros_domain()
import rclpy  # noqa: E402
from lifecycle_msgs.msg import Transition  # noqa: E402
from lifecycle_msgs.srv import ChangeState  # noqa: E402
from support.ros_harness import MonitorClient  # noqa: E402

INPUTS, RATE_HZ = 1000, 200.0
MODULES = {"plain": "linkage_monitor.ros.node", "managed": "linkage_monitor.ros.lifecycle_node"}


def _cpu_s(pid: int) -> float:
    fields = Path(f"/proc/{pid}/stat").read_text().split()
    return (int(fields[13]) + int(fields[14])) / os.sysconf("SC_CLK_TCK")


def main(mode: str) -> int:
    proc = subprocess.Popen([sys.executable, "-m", MODULES[mode], "--ros-args", "-p", "record:=false",
                             "-p", "pressure_topics:=['none']", "-p", "sensor_qos:=reliable"],
                            stdout=subprocess.DEVNULL, stderr=subprocess.STDOUT)
    rclpy.init()
    client = MonitorClient(pressure_topics=())
    try:
        if mode == "managed":
            change = client.node.create_client(ChangeState, "/linkage_monitor/change_state")
            assert change.wait_for_service(timeout_sec=30)
            for transition in (Transition.TRANSITION_CONFIGURE, Transition.TRANSITION_ACTIVATE):
                future = change.call_async(ChangeState.Request(transition=Transition(id=transition)))
                client.spin_until(future.done, 60)
                assert future.result().success, transition
        assert client.spin_until(lambda: client.joint_pub.get_subscription_count() > 0, 60)
        client.spin_until(lambda: False, 2.0)
        start = _cpu_s(proc.pid)
        for k in range(INPUTS):
            client.publish_joint_state(time.time_ns(), ["lift_cylinder", "lift_arm_angle"],
                                       [0.60, -3.2730655539678026 + 1e-7 * k])
            client.spin_until(lambda: False, 1.0 / RATE_HZ)
        client.spin_until(lambda: len(client.received["hitch_state"]) >= INPUTS, 20)
        used = _cpu_s(proc.pid) - start
        print(f"{mode}: {len(client.received['hitch_state'])} outputs of {INPUTS} inputs, "
              f"{1000 * used / INPUTS:.3f} ms CPU per input")
    finally:
        client.close()
        proc.send_signal(2)
        proc.wait(20)
        rclpy.shutdown()
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1] if len(sys.argv) > 1 else "plain"))
