"""`linkage-monitor fleet`: replay many bags on Dask; per bag and hinge the load spectrum and
damage-equivalent load; bags.parquet, spectra.parquet, fleet.png and the worst bags printed
(thin CLI over :mod:`linkage_monitor.offline.fleet`; docs/fleet.md)."""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

from linkage_monitor.cli.arguments import add_mechanism_group, bounded, mechanism_from_args
from linkage_monitor.offline.fleet import DEFAULT_BIN_N, DEFAULT_SLOPE, find_bags, run_fleet, worst_table, write_parquet


def add_spectrum_arguments(parser: argparse.ArgumentParser) -> None:
    """--slope and --bin, shared by `fleet` and `replay --spectra`."""
    parser.add_argument("--slope", type=bounded(1.0, 20.0), default=DEFAULT_SLOPE, metavar="M",
                        help=f"Wöhler (S-N) slope m of the damage-equivalent load (default {DEFAULT_SLOPE:g})")
    parser.add_argument("--bin", type=bounded(0.0, 1e9, "N", lo_open=True), default=DEFAULT_BIN_N, metavar="N",
                        help=f"width of the spectra's range bins, N (default {DEFAULT_BIN_N:g})")


def add_fleet_parser(sub: argparse._SubParsersAction) -> None:
    parser = sub.add_parser(
        "fleet", help="analyse many bags on Dask: load spectra, damage-equivalent loads, margins",
        description="Replay every bag (one Dask task each) and write DIR/bags.parquet (one row per bag), "
                    "DIR/spectra.parquet (rainflow cycle counts per bag, hinge and range bin) and DIR/fleet.png; "
                    "print the worst bags. A bag that cannot be read or solved gets its error in its row; the "
                    "run goes on. Column meanings: docs/fleet.md.")
    parser.add_argument("bags", nargs="+", metavar="BAG_OR_DIR",
                        help="bag directories, .mcap or .db3 files, or directories searched for them")
    parser.add_argument("--out", required=True, metavar="DIR", type=Path, help="output directory (created)")
    parser.add_argument("--scheduler", metavar="ADDRESS",
                        help="an existing Dask scheduler, e.g. tcp://host:8786 (default: a LocalCluster here)")
    parser.add_argument("--workers", type=bounded(1, 1024, integer=True), default=None, metavar="N",
                        help=f"LocalCluster worker processes (default: the cores, here {os.cpu_count()})")
    add_mechanism_group(parser, required=False, default="the one recorded in each bag")
    add_spectrum_arguments(parser)
    parser.add_argument("--uncertainty", action="store_true",
                        help="replay with the error budget: the limits judged on their 95 %% intervals, and the "
                             "time each margin was uncertain (docs/accuracy.md)")
    parser.add_argument("--quiet", action="store_true", help="no progress bar")


def run_fleet_command(args: argparse.Namespace) -> int:
    from linkage_monitor.viz.fleet_plot import plot_fleet

    if args.out.exists() and not args.out.is_dir():
        print(f"linkage-monitor: error: --out {args.out} is a file: give a directory", file=sys.stderr)
        return 2
    bags = find_bags([Path(b) for b in args.bags])
    missing = [b for b in bags if not b.exists()]
    if missing:
        print(f"linkage-monitor: error: {missing[0]} does not exist", file=sys.stderr)
        return 2
    if not bags:
        print(f"linkage-monitor: error: no bags (directories with metadata.yaml, .mcap or .db3 files) under "
              f"{' '.join(args.bags)}", file=sys.stderr)
        return 2
    fleet = run_fleet(bags, mechanism_from_args(args), slope=args.slope, bin_width=args.bin,
                      scheduler=args.scheduler, workers=args.workers,
                      progress=None if args.quiet else sys.stderr, uncertainty=args.uncertainty)
    bags_file, spectra_file = write_parquet(fleet, args.out)
    plot_fleet(fleet.rows, args.slope, args.out / "fleet.png")
    print(worst_table(fleet))
    failed = sum(1 for r in fleet.rows if r["error"] is not None)
    in_part = sum(1 for r in fleet.rows if r.get("warning") is not None)
    print(f"\n{len(fleet.rows)} bags, {failed} failed, {in_part} read in part; written: {bags_file}, {spectra_file}, {args.out / 'fleet.png'}")
    return 0
