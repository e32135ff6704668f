"""How long the live node takes to start: process start to its "monitoring ..." log line, which it
writes once the mechanism is loaded, the solver and the statics layouts are built and the compiled
kernels are loaded from numba's on-disk cache (``Monitor.load_kernels``), i.e. ready for the first
input. Goal: a warm node starts in ≤ 2 s. Baseline in the same run: a Python process
that imports rclpy and exits (the floor of any rclpy node).

Run: ``.venv/bin/python bench/bench_startup.py [RUNS]`` (default 5; median and range printed)
"""

from __future__ import annotations

import signal
import statistics
import subprocess
import sys
import time


def node_ready() -> float:
    """Seconds from starting the node (no recording) to its "monitoring" line."""
    started = time.perf_counter()
    proc = subprocess.Popen([sys.executable, "-m", "linkage_monitor.ros.node", "--ros-args", "-p", "record:=false"],
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    assert proc.stdout is not None
    try:
        for line in proc.stdout:
            if "monitoring '" in line:
                return time.perf_counter() - started
        raise RuntimeError("the node exited before it was monitoring")
    finally:
        proc.send_signal(signal.SIGINT)
        proc.wait(timeout=30)


def import_rclpy() -> float:
    started = time.perf_counter()
    subprocess.run([sys.executable, "-c", "import rclpy"], check=True)
    return time.perf_counter() - started


def main() -> None:
    runs = int(sys.argv[1]) if len(sys.argv) > 1 else 5
    node_ready()   # the first start after an install may page everything in
    node = [node_ready() for _ in range(runs)]
    floor = [import_rclpy() for _ in range(runs)]
    print(f"node ready (process start -> 'monitoring' line), {runs} runs: median {statistics.median(node):.2f} s "
          f"(range {min(node):.2f}-{max(node):.2f} s; goal <= 2 s)")
    print(f"baseline: python -c 'import rclpy':              median {statistics.median(floor):.2f} s")
    print(f"ratio node ready / import rclpy: {statistics.median(node) / statistics.median(floor):.1f}x")


if __name__ == "__main__":
    main()
