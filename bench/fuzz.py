"""Fuzz the monitor with faulty sensor streams (linkage_monitor.sim.faults) and print the table
of what must never happen: inputs tried | crashes | results that differ from a fresh solver |
malformed inputs accepted as OK | inputs lost without a diagnostic (| valid inputs refused).

Run: .venv/bin/python bench/fuzz.py [--in-process N] [--topics N] [--preset NAME]
(defaults: 10^6 messages in-process, 2·10^4 over real topics to the live node, belarus_1221).
In-process: the live path of monitoring.core.Monitor, each solved pose re-solved by a fresh
solver. Over topics: the real node in a child process (reliable QoS, paced below its solve
rate, stamps from now); crashes = the node died or reported an internal error; lost = inputs
published minus inputs it recorded minus inputs it reported lost; differing = its recorded
outputs against a replay of its bag (a fresh batched solver); malformed accepted = an output
stamped like a malformed input (every fuzz message has its own stamp).
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(REPO / "test"))

from linkage_monitor.mechanics import load_preset  # noqa: E402
from linkage_monitor.monitoring.events import JointStateEvent  # noqa: E402
from linkage_monitor.sim.faults import fuzz_stream  # noqa: E402
from support.fuzz_check import FuzzTally, check_in_process  # noqa: E402

CHUNK = 20_000  # messages per in-process run (one fresh monitor each; seeds differ)


def in_process(preset: str, count: int) -> FuzzTally:
    mech = load_preset(preset)
    total = FuzzTally()
    started = time.perf_counter()
    for seed in range(0, count, CHUNK):
        n = min(CHUNK, count - seed)
        total.add(check_in_process(mech, fuzz_stream(mech, n, seed=seed, fault_rate=0.3)))
        done = seed + n
        print(f"  in-process {done:,}/{count:,} ({done / (time.perf_counter() - started):,.0f} msg/s)",
              file=sys.stderr)
    return total


def over_topics(preset: str, count: int) -> FuzzTally:
    import rclpy
    from sensor_msgs.msg import FluidPressure, JointState

    from linkage_monitor.bag.reader import read_bag
    from linkage_monitor.offline.compare import compare_bags
    from linkage_monitor.offline.replay import replay
    from linkage_monitor.ros.messages import header
    from linkage_monitor.wire.cdr import stamp_ns
    from linkage_monitor.wire.sensor_messages import FLUID_PRESSURE, JOINT_STATE
    from support.ros_env import isolate_ros_domain
    from support.ros_harness import MonitorClient, node_bag, settle, start_node, stop

    isolate_ros_domain()
    mech = load_preset(preset)
    tally = FuzzTally()
    with tempfile.TemporaryDirectory() as tmp:
        tmp_path = Path(tmp)
        proc = start_node({"mechanism": preset, "record_dir": str(tmp_path / "bags"), "sensor_qos": "reliable"},
                          tmp_path / "node.log")
        rclpy.init()
        malformed_stamps: set[int] = set()
        try:
            client = MonitorClient(pressure_topics=tuple(f"pressure/{p.name}" for p in mech.measurements.pressures))
            client.wait_for_node()
            publishers = {"/joint_states": client.joint_pub,
                          **{f"/pressure/{p.name}": client._pressure_pubs[f"pressure/{p.name}"]
                             for p in mech.measurements.pressures}}
            start = time.time_ns()
            for message in fuzz_stream(mech, count, seed=7, fault_rate=0.3, start_ns=start):
                e = message.event
                tally.inputs_tried += 1
                if message.malformed:
                    malformed_stamps.add(e.stamp_ns)
                msg_header = header(0)   # the stamp as the fuzz stream has it (negative ones too)
                msg_header.stamp.sec = min(max(e.stamp_ns // 10**9, -2**31), 2**31 - 1)
                msg_header.stamp.nanosec = e.stamp_ns % 10**9
                if isinstance(e, JointStateEvent):
                    publishers[e.topic].publish(JointState(header=msg_header, name=list(e.names),
                                                           position=list(e.positions), velocity=list(e.velocities)))
                else:
                    publishers[e.topic].publish(FluidPressure(header=msg_header, fluid_pressure=e.fluid_pressure))
                client.spin_until(lambda: False, 0.002)
            settle(client, "hinge_reactions", quiet=2.0, timeout=120)
            client.close()
        finally:
            rclpy.shutdown()
            code = stop(proc)
        if code != 0:
            tally.crashes += 1
        bag = node_bag(tmp_path / "bags")
        recorded = sum(1 for _ in read_bag(bag, types=(JOINT_STATE, FLUID_PRESSURE)))
        reported_lost = 0
        for *_, msg in read_bag(bag, topics=["/diagnostics"]):
            for s in msg.status:
                if "internal" in s.name or "internal error" in s.message:
                    tally.crashes += 1
                if s.name.endswith(": inputs"):
                    reported_lost += int(s.message.split(" ", 1)[0])
        tally.lost_without_diagnostic = max(0, tally.inputs_tried - recorded - reported_lost)
        outputs = [stamp_ns(m.header) for *_, m in read_bag(bag, topics=["/hinge_reactions"])]
        tally.malformed_accepted_as_ok = sum(1 for s in outputs if s in malformed_stamps)
        replay(bag, out_dir=tmp_path / "offline", progress=None)
        comparison = compare_bags(bag, tmp_path / "offline", f"linkage_monitor: {mech.name}")
        tally.differ_from_fresh_solver = len({d.split("]")[0] for d in comparison.differences
                                              if d.startswith("/hinge_reactions")})
    return tally


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--in-process", type=int, default=1_000_000, metavar="N")
    parser.add_argument("--topics", type=int, default=20_000, metavar="N")
    parser.add_argument("--preset", default="belarus_1221")
    args = parser.parse_args()
    rows = []
    if args.in_process:
        rows.append(("in-process", in_process(args.preset, args.in_process)))
    if args.topics:
        rows.append(("real topics", over_topics(args.preset, args.topics)))
    print(f"where | {FuzzTally.header()}")
    for where, tally in rows:
        print(f"{where} | {tally.row()}")
    return 0 if all(t == FuzzTally(inputs_tried=t.inputs_tried) for _, t in rows) else 1


if __name__ == "__main__":
    sys.exit(main())
