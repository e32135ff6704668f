"""Where the live node's time goes per message: the node in this process under cProfile, fed
JointStates by bench_node.py's driver in a child process (reliable QoS, one FluidPressure first,
so every JointState is one solve), then the profile's top entries.

Usage: .venv/bin/python bench/profile_node.py [--rate HZ] [--seconds S] [--top N]
(default 200 Hz for 6 s; the table in docs/performance.md comes from this command)
"""

from __future__ import annotations

import argparse
import cProfile
import os
import pstats
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent / "test"))
sys.path.insert(0, str(HERE))


def drive(rate: float, seconds: float) -> None:
    """The child process: bench_node's Driver at ``rate`` Hz for ``seconds`` s."""
    import rclpy

    from bench_node import Driver

    rclpy.init()
    driver = Driver()
    driver.wait_for_target()
    sent = driver.drive(rate, seconds)
    driver.drain()
    print(f"driver: {sent} JointStates sent, {len(driver.arrivals)} HitchStates received", flush=True)
    driver.node.destroy_node()
    rclpy.shutdown()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rate", type=float, default=200.0)
    parser.add_argument("--seconds", type=float, default=6.0)
    parser.add_argument("--top", type=int, default=30)
    parser.add_argument("--drive", action="store_true", help=argparse.SUPPRESS)   # the child process
    args = parser.parse_args()
    from support.ros_env import isolate_ros_domain

    if args.drive:
        drive(args.rate, args.seconds)
        return
    isolate_ros_domain()
    import rclpy
    from rclpy.parameter import Parameter

    from linkage_monitor.ros.node import LinkageMonitorNode

    rclpy.init()
    with tempfile.TemporaryDirectory() as tmp:
        node = LinkageMonitorNode(parameter_overrides=[
            Parameter("sensor_qos", value="reliable"), Parameter("staleness_limit", value=3600.0),
            Parameter("record_dir", value=tmp)])
        child = subprocess.Popen([sys.executable, __file__, "--drive", "--rate", str(args.rate), "--seconds",
                                  str(args.seconds)], env=dict(os.environ))
        profile = cProfile.Profile()
        cpu = time.process_time()
        profile.enable()
        while child.poll() is None:
            rclpy.spin_once(node, timeout_sec=0.1)
        profile.disable()
        print(f"node process CPU while driven (profiled): {time.process_time() - cpu:.2f} s")
        node.close()
        node.destroy_node()
    rclpy.shutdown()
    stats = pstats.Stats(profile)
    stats.sort_stats("cumulative").print_stats(args.top)


if __name__ == "__main__":
    main()
