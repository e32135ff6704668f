"""`make bench`: every benchmark, one after the other, each printing ratios against a
baseline measured in the same run (numbers on a shared 2-core machine are indicative).

    .venv/bin/python bench/run_all.py [--full]   # --full: the node bench's whole rate ladder and a 10-minute soak
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent


def main() -> int:
    full = "--full" in sys.argv[1:]
    runs = [["bench_solver.py"], ["bench_step.py"], ["bench_encode.py"], ["bench_memory.py"], ["bench_startup.py"], ["bench_cli_start.py"],
            ["bench_bag.py"], ["bench_replay.py"], ["bench_replay_process.py"], ["bench_spin.py"],
            ["bench_fleet.py"], ["bench_can.py"], ["bench_uncertainty_mc.py"], ["bench_uncertainty_coverage.py"],
            ["bench_uncertainty_step.py"],
            ["bench_weighing.py"], ["bench_dynamics.py"],
            ["bench_node.py", "--soak-minutes", "10"] if full else ["bench_node.py", "--quick"]]
    failed = 0
    for args in runs:
        print(f"\n=== {' '.join(args)}", flush=True)
        failed += subprocess.call([sys.executable, str(HERE / args[0]), *args[1:]], cwd=HERE.parent) != 0
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
