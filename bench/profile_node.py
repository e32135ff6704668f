"""Where the live node's time goes per message: the node in this process under cProfile, fed
JointStates by bench_node.py's driver in a child process (reliable QoS, one FluidPressure first,
so every JointState is one solve), then the profile's top entries.

Usage: .venv/bin/python bench/profile_node.py [--rate HZ] [--seconds S] [--top N] [--stages]
(default 200 Hz for 6 s; the table in docs/performance.md comes from this command)

--stages: instead of cProfile (which inflates Python code several times), the node's stages
timed on its own thread's CPU clock (``time.thread_time``): per input the whole callback
(``on_input``), the monitoring step, the outputs (three publishes + recording + markers), each
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
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.parameter import Parameter

    from linkage_monitor.ros.node import LinkageMonitorNode
    from linkage_monitor.ros.spin import InputSpinner

    rclpy.init()
    with tempfile.TemporaryDirectory() as tmp:
        node = LinkageMonitorNode(parameter_overrides=[
            Parameter("sensor_qos", value="reliable"), Parameter("staleness_limit", value=3600.0),
            Parameter("record_dir", value=tmp)])
        spent = _time_stages(node) if args.stages else None
        child = subprocess.Popen([sys.executable, __file__, "--drive", "--rate", str(args.rate), "--seconds",
                                  str(args.seconds)], env=dict(os.environ))
        profile = cProfile.Profile()
        threads, cpu = _thread_cpu(), time.process_time()
        if spent is None:
            profile.enable()
        executor = SingleThreadedExecutor()   # as the node's main() spins it
        executor.add_node(node)
        spinner = InputSpinner(node, executor, lambda: node.input_subscriptions, node.take_inputs)
        while child.poll() is None:
            spinner.spin_once(0.1)
        profile.disable()
        cpu, threads = time.process_time() - cpu, _thread_cpu(threads)
        inputs = node.loss.received.get("/joint_states", 0)
        print(f"node process CPU while driven{'' if spent else ' (profiled)'}: {cpu:.2f} s, "
              f"{1e6 * cpu / max(inputs, 1):.0f} us per JointState ({inputs}); by thread (name: us per JointState):")
        for name, seconds in sorted(threads.items(), key=lambda t: -t[1]):
            print(f"    {name:24s} {1e6 * seconds / max(inputs, 1):8.0f}")
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


def _thread_cpu(since: dict[str, float] | None = None) -> dict[str, float]:
    """CPU seconds (user + system) of this process's threads by thread name, the main thread apart
    (/proc/self/task; clock ticks of 10 ms), less ``since``'s: which threads besides the node's own spend the process CPU
    (the middleware's, the bag writer's)."""
    tick, found = os.sysconf("SC_CLK_TCK"), dict.fromkeys(since or (), 0.0)
    for task in Path("/proc/self/task").iterdir():
        try:
            name = (task / "comm").read_text().strip() + ("" if task.name != str(os.getpid()) else " (main)")
            fields = (task / "stat").read_text().rsplit(")", 1)[1].split()
        except OSError:   # the thread ended meanwhile
            continue
        found[name] = found.get(name, 0.0) + (int(fields[11]) + int(fields[12])) / tick   # utime, stime
    return {name: seconds - (since or {}).get(name, 0.0) for name, seconds in found.items()}


def _time_stages(node: Any) -> dict[str, list]:
    """Wrap the node's stages with thread-CPU timers (profile_step.timed); returns label -> [calls, seconds]."""
    from profile_step import timed

    spent: dict[str, list] = {}
    monitor = node.monitor
    outputs = node.outputs
    for owner, name, label in ((node.input_source, "on_input", "input callback (whole)"),
                               (monitor, "step", "  monitoring step"),
                               (monitor, "_accept", "    acceptance"),
                               (monitor.machine, "solve", "    solve with the machine level"),
                               (monitor.solver, "solve_with_machine", "      the solver's part"),
                               (monitor, "_finish", "    findings"),
                               (outputs, "publish", "  outputs: encode, publish, record"),
                               (outputs.encoder, "outputs", "    encode the three outputs"),
                               (outputs.messenger.markers, "markers", "    a MarkerArray (marker_rate)"),
                               (node.recording.recorder.writer, "write", "  a recording call (BagWriter.write)"),
                               (outputs.pub_hitch, "publish", "  a publish (HitchState)")):
        setattr(owner, name, timed(spent, label, getattr(owner, name), time.thread_time))
    return spent


if __name__ == "__main__":
    main()
