"""``linkage-monitor replay``: re-run the monitor offline over a recorded bag (thin CLI over
:mod:`linkage_monitor.offline.replay`); prints the summary, optionally the load spectra."""

from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

from linkage_monitor.cli.arguments import add_recorded_bag, bounded, mechanism_from_args, new_directory, output_file
from linkage_monitor.cli.can import add_redecode_arguments, redecoded
from linkage_monitor.cli.commands import COMMANDS
from linkage_monitor.cli.fleet import add_spectrum_arguments
from linkage_monitor.monitoring.config import IMPLEMENT_MASS_SOURCES
from linkage_monitor.offline.history import spectra_table
from linkage_monitor.offline.replay import replay_streaming


def add_replay_parser(subparsers: argparse._SubParsersAction) -> argparse.ArgumentParser:
    """Add the ``replay`` subcommand to ``subparsers``; returns its parser."""
    # the form of every subcommand's parser (cli/commands.py names them); the words are this command's own
    parser = subparsers.add_parser(
        "replay", help=COMMANDS["replay"].help,
        description="Replay the JointState + FluidPressure messages of a rosbag2 bag (MCAP or sqlite3, one file "
                    "or split; ours or from `ros2 bag record`) through the monitor, batched, and write the "
                    "outputs to a new bag and/or a Rerun .rrd; prints a summary.")
    add_recorded_bag(parser)
    parser.add_argument("--out", metavar="DIR", type=new_directory,
                        help="write inputs + outputs + /diagnostics to this new bag directory")
    parser.add_argument("--rrd", metavar="FILE", type=output_file,
                        help="write a Rerun recording (open with `rerun FILE`)")
    parser.add_argument("--rate", type=bounded(0.0, 1e6, "times real time", lo_open=True), metavar="X",
                        help="write at X times real time (default: as fast as possible)")
    parser.add_argument("--uncertainty", action="store_true",
                        help="write every output's standard uncertainty (1 sigma, the *_u fields) and judge the "
                             "limits on their 95 %% intervals (each pose's error budget from the mechanism's "
                             "declared error sources, docs/accuracy.md), whatever the bag recorded")
    parser.add_argument("--implement-mass-source", choices=IMPLEMENT_MASS_SOURCES, metavar="SOURCE",
                        help="where the machine-level results take the implement's mass and cg from: "
                             f"{', '.join(IMPLEMENT_MASS_SOURCES)} (default: as recorded, else file); other than "
                             "file, the implement is weighed and the summary gives the estimate (docs/implements.md)")
    parser.add_argument("--quiet", action="store_true", help="no progress bar")
    parser.add_argument("--spectra", action="store_true",
                        help="print each hinge's rainflow load spectrum and damage-equivalent load (docs/fleet.md)")
    add_spectrum_arguments(parser)
    add_redecode_arguments(parser)
    return parser


def run_replay(args: argparse.Namespace) -> int:
    """Run ``linkage-monitor replay``; returns the exit code (1 when no pose was solved)."""
    if args.map:   # the bag's raw CAN frames decoded again first
        with tempfile.TemporaryDirectory() as work:
            return _replay_bag(args, redecoded(args, Path(work)))
    return _replay_bag(args, Path(args.bag))


def _replay_bag(args: argparse.Namespace, bag: Path) -> int:
    replayed = replay_streaming(bag, mechanism_from_args(args), out_dir=args.out, rrd=args.rrd, rate=args.rate,
                                progress=None if args.quiet else sys.stderr, history=args.spectra,
                                uncertainty=args.uncertainty, implement_mass_source=args.implement_mass_source)
    summary = replayed.summary
    print(summary.table())
    if replayed.history is not None:
        print("\n" + spectra_table(replayed.history, args.slope, args.bin))
    if summary.solved == 0:
        print(f"linkage-monitor: error: no pose of {args.bag} was solved ({summary.inputs} inputs; see the findings "
              "above): is it the right mechanism?", file=sys.stderr)
        return 1
    if args.out:
        print(f"\noutputs written to {args.out}")
    if args.rrd:
        print(f"Rerun recording written to {args.rrd}: open it with `.venv/bin/rerun {args.rrd}`")
    return 0
