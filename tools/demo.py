"""`make demo`: the bundled belarus_1221 bag through the live node over real topics.

Starts the node (recording MCAP and Rerun), plays the bag's JointState + FluidPressure onto
their topics at recorded speed, stops the node, then replays the node's own recording offline
(batched) and checks that the offline outputs equal the live ones. Prints the summary table and
how to open the Rerun recording. Everything goes under out/demo_<time>/.
"""

from __future__ import annotations

import argparse
import os
import random
import signal
import subprocess
import sys
import time
from pathlib import Path

import rclpy
from rclpy.qos import QoSProfile, ReliabilityPolicy

from linkage_monitor.bag.step_recorder import RecordedInput
from linkage_monitor.mechanics import preset_names
from linkage_monitor.msg import HingeReactions
from linkage_monitor.ros.player import play, recorded_inputs
from linkage_monitor.offline.compare import compare_bags
from linkage_monitor.offline.replay import mechanism_in_bag, replay

DEFAULT_BAG = Path(__file__).resolve().parent.parent / "bags" / "belarus_1221_lift_transport"


def main(argv: list[str] | None = None) -> int:
    """Run the demo; returns 0 when the live run and the offline replay agree."""
    parser = argparse.ArgumentParser(prog="python tools/demo.py", description=__doc__.splitlines()[0])
    parser.add_argument("--bag", type=Path, default=DEFAULT_BAG, help="input bag (default: the bundled one)")
    parser.add_argument("--rate", type=float, default=1.0,
                        help="playback speed, times real time (default 1; on a 2-core x86 machine the node took and "
                             "solved every input at 10x, ~930 msg/s, refusing none; faster, it can fall "
                             "behind and refuse inputs stamped too far behind its clock, saying so)")
    parser.add_argument("--out", type=Path, default=Path("out"), help="output directory (default out/)")
    args = parser.parse_args(argv)
    os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    os.environ.setdefault("ROS_DOMAIN_ID", str(random.SystemRandom().randint(1, 101)))
    run_dir = args.out / time.strftime("demo_%Y%m%d_%H%M%S")
    rrd = run_dir / "live.rrd"
    mech = mechanism_in_bag(args.bag)
    preset = mech.name if mech.name in preset_names() else None
    messages = recorded_inputs(args.bag)
    print(f"demo: {len(messages)} sensor messages of '{mech.name}' from {args.bag}, played at {args.rate}x "
          f"through the live node (ROS_DOMAIN_ID={os.environ['ROS_DOMAIN_ID']})")

    node = subprocess.Popen([sys.executable, "-m", "linkage_monitor.ros.node", "--ros-args",
                             "-p", f"mechanism:={preset or mech.file}", "-p", "sensor_qos:=reliable",
                             "-p", f"record_dir:={run_dir}", "-p", "record_name:=live",
                             "-p", "rerun:=save", "-p", f"rerun_path:={rrd}", "-p", "use_sim_time:=true"],
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
    recorded = recorded_inputs(run_dir / "live")
    heard = len(recorded)
    lost = f" ({sent - heard} lost: more than the node can solve per second)" if heard < sent else ""
    # each topic is its own stream: across topics the node records in arrival order, which at high
    # rates interleaves them differently from the bag
    same = (" (byte for byte the bag's, in its order on each topic)"
            if _by_topic(recorded) == _by_topic(messages) else "")
    print(f"live node: {sent} inputs published, {heard} received and recorded by the node{same}{lost}, "
          f"{len(received)} HingeReactions published; its bag: {run_dir / 'live'}, its Rerun recording: {rrd}")

    summary = replay(run_dir / "live", out_dir=run_dir / "offline", rrd=run_dir / "offline.rrd",
                     progress=None).summary
    comparison = compare_bags(run_dir / "live", run_dir / "offline", f"linkage_monitor: {mech.name}")
    counts = ", ".join(f"{n} {t}" for t, n in comparison.counts.items())
    print(f"offline replay of the node's own recording (batched) against the live outputs: {counts} compared, "
          f"largest relative difference {comparison.worst:.1e}; "
          + ("all equal" if comparison.equal else f"DIFFERENT: {comparison.differences[:3]}") + "\n")
    print(summary.table())
    print(f"\nOpen the live recording in Rerun:   .venv/bin/rerun {rrd}")
    print(f"Inspect the bag with any MCAP tool: {run_dir / 'live'}  (rosbag2 layout, ros2 bag compatible)")
    ok = comparison.equal and comparison.counts["/hinge_reactions"] > 0
    if not ok:
        print("demo: the offline replay does not reproduce the live outputs", file=sys.stderr)
    return 0 if ok else 1


def _by_topic(rows: list[RecordedInput]) -> dict[str, list[bytes]]:
    """The CDR bytes of ``recorded_inputs`` rows, per topic in their order."""
    topics: dict[str, list[bytes]] = {}
    for row in rows:
        topics.setdefault(row.topic, []).append(row.data)
    return topics


if __name__ == "__main__":
    sys.exit(main())
