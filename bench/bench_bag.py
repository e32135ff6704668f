"""Write and read rates of linkage_monitor's bag writer/reader against raw `mcap` in one run.

Usage: .venv/bin/python bench/bench_bag.py [N]   (N JointState + N FluidPressure messages)
"""

from __future__ import annotations

import sys
import tempfile
import time
from pathlib import Path

from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory
from sensor_msgs.msg import FluidPressure, JointState

from linkage_monitor.bag.reader import read_bag, read_inputs
from linkage_monitor.bag.writer import BagWriter


def _rate(label: str, count: int, seconds: float) -> None:
    print(f"{label:<42s} {count / seconds:>10,.0f} msg/s  ({count} msgs, {seconds:.2f} s)")


def main(n: int) -> None:
    names = ["lift_arm", "lower_link", "top_link", "implement"]
    with tempfile.TemporaryDirectory() as tmp:
        bag = Path(tmp) / "bench"
        t0 = time.perf_counter()
        with BagWriter(bag) as writer:
            for i in range(n):
                stamp = 1_700_000_000_000_000_000 + i * 1_000_000
                writer.write("/joint_states", JointState(
                    name=names, position=[0.001 * i] * 4, velocity=[0.1] * 4), stamp,
                    log_time_ns=stamp)
                writer.write("/lift_cylinder/pressure", FluidPressure(fluid_pressure=1e5 + i),
                             stamp, log_time_ns=stamp + 1)
        _rate("BagWriter.write (incl. serialize)", 2 * n, time.perf_counter() - t0)

        mcap_file = bag / "bench_0.mcap"
        t0 = time.perf_counter()
        with open(mcap_file, "rb") as stream:
            count = sum(1 for _ in make_reader(stream).iter_messages())
        _rate("raw mcap iter_messages (no decode)", count, time.perf_counter() - t0)

        t0 = time.perf_counter()
        with open(mcap_file, "rb") as stream:
            count = sum(1 for _ in make_reader(
                stream, decoder_factories=[DecoderFactory()]).iter_decoded_messages())
        _rate("raw mcap + mcap_ros2 decode", count, time.perf_counter() - t0)

        t0 = time.perf_counter()
        count = sum(1 for _ in read_bag(bag))
        _rate("bag_reader.read_bag (rclpy messages)", count, time.perf_counter() - t0)

        t0 = time.perf_counter()
        columns = read_inputs(bag)
        count = sum(len(c.stamp_ns) for c in columns.values())
        _rate("bag_reader.read_inputs (numpy columns)", count, time.perf_counter() - t0)


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 20_000)
