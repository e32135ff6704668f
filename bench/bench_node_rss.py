"""The node's memory over a long run: RSS while it is fed JointStates at a steady rate.

Usage: .venv/bin/python bench/bench_node_rss.py [--rate HZ] [--minutes M] [--warm-up-minutes W]

The node (belarus_1221, reliable inputs, recording its bag to a temporary directory, as deployed)
is fed one FluidPressure and then JointStates at --rate Hz (default 400) for --minutes (default
60). Its RSS is printed every minute; the figure is the growth from the end of the warm-up
(default 5 min: caches, allocator arenas and the bag writer's buffers reach their size) to the end
of the run, against the goal of < 5 MiB. HitchStates received and JointStates sent are counted,
so that a run where the node fell behind says so.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

import psutil
import rclpy

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_node import Driver, start_monitor  # noqa: E402
from support.ros_env import isolate_ros_domain  # noqa: E402  (bench_node put test/ on the path)
from support.ros_harness import stop  # noqa: E402

GOAL_MIB = 5.0   # MiB, RSS growth after the warm-up


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rate", type=float, default=400.0, help="JointState input rate, Hz (default 400)")
    parser.add_argument("--minutes", type=float, default=60.0, help="length of the run, min (default 60)")
    parser.add_argument("--warm-up-minutes", type=float, default=5.0,
                        help="minutes before the growth is measured from (default 5)")
    args = parser.parse_args()
    isolate_ros_domain()
    rclpy.init()
    proc = None
    try:
        with tempfile.TemporaryDirectory() as tmp:
            work = Path(tmp)
            proc = start_monitor("/monitor", {"mechanism": "belarus_1221", "sensor_qos": "reliable",
                                              "staleness_limit": 3600.0, "record_dir": str(work / "bags")},
                                 work / "node.log")
            driver = Driver("/monitor")
            driver.wait_for_target()
            node = psutil.Process(proc.pid)
            sent = received = 0
            rss_warm = None
            start = time.monotonic()
            for minute in range(1, int(round(args.minutes)) + 1):
                sent += driver.drive(args.rate, 60.0)
                received += len(driver.arrivals)
                driver.arrivals.clear()   # keep this process's memory flat
                rss = node.memory_info().rss / 2**20
                if rss_warm is None and minute >= args.warm_up_minutes:
                    rss_warm = rss
                print(f"t = {minute:3d} min  RSS {rss:7.1f} MiB  sent {sent}  HitchStates {received}  "
                      f"({time.monotonic() - start:.0f} s)", flush=True)
            driver.drain()
            received += len(driver.arrivals)
            rss_end = node.memory_info().rss / 2**20
            growth = rss_end - (rss_warm if rss_warm is not None else rss_end)
            print(f"{args.rate:g} Hz for {args.minutes:g} min: sent {sent} JointStates, {received} HitchStates back; "
                  f"RSS after the {args.warm_up_minutes:g}-min warm-up {rss_warm:.1f} MiB, at the end {rss_end:.1f} MiB: "
                  f"growth {growth:+.1f} MiB (goal < {GOAL_MIB:g} MiB)", flush=True)
    finally:
        if proc is not None:
            stop(proc)
        rclpy.shutdown()


if __name__ == "__main__":
    main()
