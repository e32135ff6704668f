"""`make demo`: the bundled belarus_1221 bag through the live node over real topics.

Starts the node (recording MCAP and Rerun), plays the bag's JointState + FluidPressure onto
their topics at recorded speed, stops the node, then replays the node's own recording offline
(batched) and checks that the offline outputs equal the live ones. Prints the summary table and
how to open the Rerun recording. Everything goes under out/demo_<time>/.
"""

from __future__ import annotations

import argparse
import math
import os
import random
import signal
import subprocess
import sys
import time
from pathlib import Path

import rclpy
from rclpy.qos import QoSProfile, ReliabilityPolicy

from linkage_monitor.bag.reader import FLUID_PRESSURE, JOINT_STATE, read_bag
from linkage_monitor.mechanics import preset_names
from linkage_monitor.msg import HingeReactions
from linkage_monitor.ros.messages import stamp_ns
from linkage_monitor.ros.player import play, sensor_messages
from linkage_monitor.offline.replay import mechanism_in_bag, replay

DEFAULT_BAG = Path(__file__).resolve().parent.parent / "bags" / "belarus_1221_lift_transport"


def _largest_difference(live_bag: Path, offline_steps) -> tuple[int, float]:
    """Poses compared and the largest relative difference of a hinge reaction, live vs offline.

    Both are in input order (one joint state and one pressure may share a stamp), so they are
    compared in sequence, stamp by stamp.
    """
    live = [m for _, _, _, _, m in read_bag(live_bag, topics=["/hinge_reactions"])]
    offline = [s.outputs.hinge_reactions for s in offline_steps if s.outputs is not None]
    if len(live) != len(offline):
        return 0, math.inf
    worst = 0.0
    for a_msg, b_msg in zip(live, offline):
        if stamp_ns(a_msg.header) != stamp_ns(b_msg.header):
            return 0, math.inf
        for a, b in zip(a_msg.hinges, b_msg.hinges):
            scale = max(abs(b.magnitude), 1.0)
            worst = max(worst, abs(a.fx - b.fx) / scale, abs(a.fz - b.fz) / scale)
    return len(live), worst


def main(argv: list[str] | None = None) -> int:
    """Run the demo; returns 0 when the live run and the offline replay agree."""
    parser = argparse.ArgumentParser(prog="python tools/demo.py", description=__doc__.splitlines()[0])
    parser.add_argument("--bag", type=Path, default=DEFAULT_BAG, help="input bag (default: the bundled one)")
    parser.add_argument("--rate", type=float, default=1.0,
                        help="playback speed, times real time (default 1; the node keeps up with ~100 msg/s)")
    parser.add_argument("--out", type=Path, default=Path("out"), help="output directory (default out/)")
    args = parser.parse_args(argv)
    os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    os.environ.setdefault("ROS_DOMAIN_ID", str(random.SystemRandom().randint(1, 101)))
    run_dir = args.out / time.strftime("demo_%Y%m%d_%H%M%S")
    rrd = run_dir / "live.rrd"
    mech = mechanism_in_bag(args.bag)
    preset = mech.name if mech.name in preset_names() else None
    messages = sensor_messages(args.bag)
    print(f"demo: {len(messages)} sensor messages of '{mech.name}' from {args.bag}, played at {args.rate}x "
          f"through the live node (ROS_DOMAIN_ID={os.environ['ROS_DOMAIN_ID']})")

    node = subprocess.Popen([sys.executable, "-m", "linkage_monitor.ros.node", "--ros-args",
                             "-p", f"mechanism:={preset or mech.file}", "-p", "sensor_qos:=reliable",
                             "-p", f"record_dir:={run_dir}", "-p", "record_name:=live",
                             "-p", "rerun:=save", "-p", f"rerun_path:={rrd}"],
                            stdout=(run_dir.mkdir(parents=True, exist_ok=True) or (run_dir / "node.log").open("w")),
                            stderr=subprocess.STDOUT)
    rclpy.init()
    received = []
    try:
        client = rclpy.create_node("linkage_monitor_demo")
        client.create_subscription(HingeReactions, "hinge_reactions", received.append,
                                   QoSProfile(depth=10_000, reliability=ReliabilityPolicy.RELIABLE))
        sent = play(client, messages, rate=args.rate, wait_for_subscribers=30.0)
        end = time.monotonic() + 10.0
        last = -1
        while time.monotonic() < end and len(received) != last:  # until the node has gone quiet
            last = len(received)
            rclpy.spin_once(client, timeout_sec=1.0)
            for _ in range(20):
                rclpy.spin_once(client, timeout_sec=0.05)
        client.destroy_node()
    finally:
        rclpy.shutdown()
        node.send_signal(signal.SIGINT)
        node.wait(timeout=30)
    heard = sum(1 for _ in read_bag(run_dir / "live", types=(JOINT_STATE, FLUID_PRESSURE)))
    lost = f" ({sent - heard} lost: more than the node can solve per second)" if heard < sent else ""
    print(f"live node: {sent} inputs published, {heard} received and recorded by the node{lost}, "
          f"{len(received)} HingeReactions published; its bag: {run_dir / 'live'}, its Rerun recording: {rrd}")

    summary, steps = replay(run_dir / "live", mech, out_dir=run_dir / "offline", rrd=run_dir / "offline.rrd",
                            progress=None)
    compared, worst = _largest_difference(run_dir / "live", steps)
    print(f"offline replay of the node's own recording (batched): {compared} poses compared with the live "
          f"outputs, largest relative difference of a hinge reaction {worst:.1e}\n")
    print(summary.table())
    print(f"\nOpen the live recording in Rerun:   .venv/bin/rerun {rrd}")
    print(f"Inspect the bag with any MCAP tool: {run_dir / 'live'}  (rosbag2 layout, ros2 bag compatible)")
    ok = compared > 0 and math.isfinite(worst) and worst < 1e-6
    if not ok:
        print("demo: the offline replay does not reproduce the live outputs", file=sys.stderr)
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
