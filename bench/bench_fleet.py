"""Fleet analysis on Dask: 60 bags (10 copies of each of the six bundled sample bags) through
`offline.fleet.run_fleet` on a LocalCluster of 1 and of 2 worker processes, against the same
bags analysed one after the other in this process (`analyse_bag`, no Dask) — the baseline of
the same run. Prints wall times, bags/s, the 2-worker speed-up beside the ideal (2.0 on 2
cores; goal >= 1.8) and the Dask overhead against the single-process loop: first as
`linkage-monitor fleet` runs (the LocalCluster started and stopped within the run, its workers
importing the package and loading the kernels), then on a running cluster (`run_fleet`'s
``scheduler``, as with a cluster of one's own: started, and its workers warmed by one bag each,
before the clock starts), which is the speed-up of the bags' work alone.

Run: .venv/bin/python bench/bench_fleet.py [--copies N]
"""

from __future__ import annotations

import argparse
import os
import shutil
import sys
import tempfile
import time
from pathlib import Path

from dask.distributed import LocalCluster

from linkage_monitor.offline.fleet import Fleet, analyse_bag, find_bags, run_fleet

SAMPLES = Path(__file__).resolve().parent.parent / "bags"


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--copies", type=int, default=10, help="copies of each sample bag (default 10: 60 bags)")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        for k in range(args.copies):
            for bag in sorted(p for p in SAMPLES.iterdir() if (p / "metadata.yaml").is_file()):   # not bags/can/
                shutil.copytree(bag, Path(tmp) / f"{bag.name}_{k:02d}")
        bags = find_bags([Path(tmp)])
        started = time.perf_counter()
        for bag in bags:
            analyse_bag(bag)
        single = time.perf_counter() - started
        walls, running = {}, {}
        for workers in (1, 2):
            started = time.perf_counter()
            check(run_fleet(bags, workers=workers, progress=None))
            walls[workers] = time.perf_counter() - started
        for workers in (1, 2):
            with LocalCluster(n_workers=workers, threads_per_worker=1, processes=True,
                              dashboard_address=None) as cluster:
                check(run_fleet(bags[:workers], scheduler=cluster.scheduler_address, progress=None))   # warm
                started = time.perf_counter()
                check(run_fleet(bags, scheduler=cluster.scheduler_address, progress=None))
                running[workers] = time.perf_counter() - started
    n = len(bags)
    print(f"{n} bags, {os.cpu_count()} cores")
    print(f"{'run':<58} {'wall [s]':>9} {'bags/s':>8} {'ratio':>8}")
    print(f"{'single process, no Dask (baseline)':<58} {single:9.2f} {n / single:8.2f} {1.0:8.2f}")
    for label, times in (("LocalCluster started and stopped in the run", walls),
                         ("running cluster, workers warm", running)):
        for workers, wall in times.items():
            print(f"{f'{label}, {workers} worker(s)':<58} {wall:9.2f} {n / wall:8.2f} {single / wall:8.2f}")
    print(f"\nspeed-up 2 workers over 1, the cluster started in the run: {walls[1] / walls[2]:.2f}x "
          "(ideal 2.00x, goal >= 1.8x)")
    print(f"speed-up 2 workers over 1, on a running cluster:         {running[1] / running[2]:.2f}x")
    return 0


def check(fleet: Fleet) -> None:
    """Every bag analysed without an error."""
    assert all(r["error"] is None for r in fleet.rows), [r["error"] for r in fleet.rows if r["error"]]


if __name__ == "__main__":
    sys.exit(main())
