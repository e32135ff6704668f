"""How long the ``linkage-monitor`` command line takes to answer, against baselines timed in the same
run: ``--help`` and ``presets`` against ``python -c pass`` (goal: <= 0.3 s and <= 3x), ``solve`` of one
pose (the node's monitor, warm numba cache) against ``python -c "import numpy"`` (goal: <= 1.5 s).
Each command runs as its own process (``python -m linkage_monitor.cli``); wall time and the process's
CPU time (user + system), median of RUNS. The processes write and read their bytecode (``.pyc``) in a
directory of this run (``PYTHONPYCACHEPREFIX``; ``PYTHONDONTWRITEBYTECODE`` unset), as a user's second
run reads it: without it every run compiles numba's and scipy's sources again (~4 s).

Run: ``.venv/bin/python bench/bench_cli_start.py [RUNS]`` (default 7)
"""

from __future__ import annotations

import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from typing import NamedTuple

CLI = [sys.executable, "-m", "linkage_monitor.cli"]
COMMANDS = {
    "python -c pass": [sys.executable, "-c", "pass"],
    "python -c 'import numpy'": [sys.executable, "-c", "import numpy"],
    "linkage-monitor --help": [*CLI, "--help"],
    "linkage-monitor presets": [*CLI, "presets"],
    "linkage-monitor solve --preset belarus_1221 --stroke lift_cylinder=0.6": [
        *CLI, "solve", "--preset", "belarus_1221", "--stroke", "lift_cylinder=0.6"],
}
# command -> (its baseline, goal in s, goal as a ratio to the baseline or None)
GOALS = {"linkage-monitor --help": ("python -c pass", 0.3, 3.0),
         "linkage-monitor presets": ("python -c pass", 0.3, 3.0),
         "linkage-monitor solve --preset belarus_1221 --stroke lift_cylinder=0.6": ("python -c 'import numpy'", 1.5, None)}


class Timing(NamedTuple):
    """Medians over the runs of one command, s."""

    wall: float
    cpu: float


def timed(argv: list[str], env: dict[str, str]) -> tuple[float, float]:
    """Wall and CPU time (user + system of the child), s, of one run of ``argv``."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    started = time.perf_counter()
    subprocess.run(argv, check=True, stdout=subprocess.DEVNULL, env=env)
    wall = time.perf_counter() - started
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    return wall, (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)


def measure(argv: list[str], runs: int, env: dict[str, str]) -> Timing:
    """Medians of ``runs`` runs, after one run that writes the bytecode and pages everything in (and
    warms numba's cache)."""
    timed(argv, env)
    walls, cpus = zip(*(timed(argv, env) for _ in range(runs)))
    return Timing(statistics.median(walls), statistics.median(cpus))


def main() -> None:
    runs = int(sys.argv[1]) if len(sys.argv) > 1 else 7
    with tempfile.TemporaryDirectory(prefix="bench_cli_start-") as pycache:
        env = {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}
        env["PYTHONPYCACHEPREFIX"] = pycache
        timings = {name: measure(argv, runs, env) for name, argv in COMMANDS.items()}
    print(f"{'command':<72} {'wall [s]':>9} {'cpu [s]':>8}   (median of {runs})")
    for name, t in timings.items():
        print(f"{name:<72} {t.wall:9.3f} {t.cpu:8.3f}")
    for name, (baseline, seconds, ratio) in GOALS.items():
        t, base = timings[name], timings[baseline]
        goal = f"goal <= {seconds:g} s" + (f" and <= {ratio:g}x" if ratio else "")
        print(f"{name}: {t.wall:.3f} s wall = {t.wall / base.wall:.1f}x {baseline} "
              f"(cpu {t.cpu / base.cpu:.1f}x); {goal}")


if __name__ == "__main__":
    main()
