"""How long the live node takes to start: process start to its "monitoring ..." log line, which it
writes once the mechanism is loaded, the solver and the statics layouts are built and the compiled
kernels are loaded from numba's on-disk cache (``Monitor.load_kernels``), i.e. ready for the first
input. Goal: a warm node (kernels in numba's cache, the mechanism's input limits in theirs:
``mechanics.spans_cache``; the first, unreported start warms both) starts in ≤ 2 s. Baseline in
the same run: a Python process that imports rclpy and exits (the floor of any rclpy node).
Besides the wall time, the node's CPU time at that line (user + system, from /proc): steadier than
the wall time on a machine busy with other work. Whether the installed modules' bytecode is
compiled is printed too: without it every start compiles every module it imports (about 1.5 s of
CPU here; the Makefile's ``uv pip sync --compile-bytecode`` installs it).

Run: ``.venv/bin/python bench/bench_startup.py [RUNS]`` (default 5; median and range printed)
"""

from __future__ import annotations

import importlib.util
import os
import signal
import statistics
import subprocess
import sys
import time
from dataclasses import dataclass
from pathlib import Path


@dataclass(frozen=True)
class Start:
    """One start of the node: seconds from the process start to its "monitoring" line, and the CPU
    seconds (user + system) the process had used by then."""

    wall: float
    cpu: float


def cpu_seconds(pid: int) -> float:
    """User + system CPU seconds of the running process ``pid`` (/proc/<pid>/stat, fields 14 and 15)."""
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def node_ready() -> Start:
    """The node's start (no recording) to its "monitoring" line."""
    started = time.perf_counter()
    proc = subprocess.Popen([sys.executable, "-m", "linkage_monitor.ros.node", "--ros-args", "-p", "record:=false"],
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    assert proc.stdout is not None
    try:
        for line in proc.stdout:
            if "monitoring '" in line:
                return Start(wall=time.perf_counter() - started, cpu=cpu_seconds(proc.pid))
        raise RuntimeError("the node exited before it was monitoring")
    finally:
        proc.send_signal(signal.SIGINT)
        proc.wait(timeout=30)


def import_rclpy() -> float:
    started = time.perf_counter()
    subprocess.run([sys.executable, "-c", "import rclpy"], check=True)
    return time.perf_counter() - started


def bytecode_compiled() -> bool:
    """True when numba's modules (the bulk of the node's imports) have their bytecode on disk."""
    spec = importlib.util.find_spec("numba.core.dispatcher")
    return bool(spec and spec.cached and Path(spec.cached).exists())


def main() -> None:
    runs = int(sys.argv[1]) if len(sys.argv) > 1 else 5
    node_ready()   # the first start after an install may page everything in (and fills the caches)
    starts = [node_ready() for _ in range(runs)]
    floor = [import_rclpy() for _ in range(runs)]
    node = [start.wall for start in starts]
    print(f"node ready (process start -> 'monitoring' line), {runs} runs: median {statistics.median(node):.2f} s "
          f"(range {min(node):.2f}-{max(node):.2f} s; goal <= 2 s); its CPU time median "
          f"{statistics.median(start.cpu for start in starts):.2f} s")
    print(f"baseline: python -c 'import rclpy':              median {statistics.median(floor):.2f} s")
    print(f"ratio node ready / import rclpy: {statistics.median(node) / statistics.median(floor):.1f}x")
    print(f"installed modules' bytecode compiled: {'yes' if bytecode_compiled() else 'no (every start compiles them)'}")


if __name__ == "__main__":
    main()
