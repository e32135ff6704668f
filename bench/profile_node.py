"""Where the live node's time goes per message: the node in this process under cProfile, fed
JointStates by bench_node.py's driver in a child process (reliable QoS, one FluidPressure first,
so every JointState is one solve), then the profile's top entries.

Usage: .venv/bin/python bench/profile_node.py [--rate HZ] [--seconds S] [--top N] [--stages]
(default 200 Hz for 6 s; the table in docs/performance.md comes from this command)

--stages: instead of cProfile (which inflates Python code several times), the node's stages
timed on its own thread's CPU clock (``time.thread_time``): per input the whole callback
(``_guarded``), the monitoring step, the outputs (three publishes + recording + markers), each
recording call and the HitchState publish; and the process CPU per input (every thread: rclpy's,
the middleware's, the bag writer's).
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
from typing import Any

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent / "test"))
sys.path.insert(0, str(HERE))


def drive(rate: float, seconds: float) -> None:
    """The child process: bench_node's Driver at ``rate`` Hz for ``seconds`` s."""
    import rclpy

    from bench_node import Driver

    rclpy.init()
    driver = Driver("")   # the node runs in the root namespace
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
    parser.add_argument("--stages", action="store_true", help="stage timers on the thread CPU clock, no cProfile")
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
        spent = _time_stages(node) if args.stages else None
        child = subprocess.Popen([sys.executable, __file__, "--drive", "--rate", str(args.rate), "--seconds",
                                  str(args.seconds)], env=dict(os.environ))
        profile = cProfile.Profile()
        cpu = time.process_time()
        if spent is None:
            profile.enable()
        while child.poll() is None:
            rclpy.spin_once(node, timeout_sec=0.1)
        profile.disable()
        cpu = time.process_time() - cpu
        inputs = node.loss.received.get("/joint_states", 0)
        print(f"node process CPU while driven{'' if spent else ' (profiled)'}: {cpu:.2f} s, "
              f"{1e6 * cpu / max(inputs, 1):.0f} us per JointState ({inputs})")
        node.close()
        node.destroy_node()
    rclpy.shutdown()
    if spent is not None:
        print(f"{'stage (node thread CPU)':40s} {'calls':>7s} {'us per call':>12s}")
        for label, (calls, seconds) in spent.items():
            print(f"{label:40s} {calls:7d} {1e6 * seconds / max(calls, 1):12.1f}")
        return
    stats = pstats.Stats(profile)
    stats.sort_stats("cumulative").print_stats(args.top)


def _time_stages(node: Any) -> dict[str, list]:
    """Wrap the node's stages with thread-CPU timers (profile_step.timed); returns label -> [calls, seconds]."""
    from profile_step import timed

    spent: dict[str, list] = {}
    monitor = node.monitor
    for owner, name, label in ((node, "_guarded", "input callback (whole)"), (monitor, "step", "  monitoring step"),
                               (monitor, "_accept", "    acceptance"),
                               (monitor.machine, "solve", "    solve with the machine level"),
                               (monitor.solver, "solve_with_machine", "      the solver's part"),
                               (monitor, "_finish", "    findings"),
                               (node, "_publish", "  outputs: encode, publish, record"),
                               (node.encoder, "outputs", "    encode the three outputs"),
                               (node.markers, "markers", "    a MarkerArray (marker_rate)"),
                               (node, "_record", "  a recording call (BagWriter.write)"),
                               (node.pub_hitch, "publish", "  a publish (HitchState)")):
        setattr(owner, name, timed(spent, label, getattr(owner, name), time.thread_time))
    return spent


if __name__ == "__main__":
    main()
