"""``linkage-monitor weigh``: the implement's mass and cg from a recorded bag (docs/weighing.md).

The bag is replayed through the monitor (``offline.replay``), and each solved step's lift
cylinder length and force go through the ``WeighingEstimator``: printed are the estimate with
its 95 % interval (±1.96 standard uncertainties), the steps of each phase (which were used),
and the implement changes found. Units SI: kg, m.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from linkage_monitor.cli.arguments import add_recorded_bag, mechanism_from_args
from linkage_monitor.cli.commands import COMMANDS
from linkage_monitor.monitoring.weighing import USED, WeighingEstimate, WeighingEstimator, estimate_text
from linkage_monitor.offline.replay import mechanism_in_bag, replay


def add_weigh_parser(subparsers: argparse._SubParsersAction) -> argparse.ArgumentParser:
    """Add the ``weigh`` subcommand to ``subparsers``; returns its parser."""
    # the form of every subcommand's parser (cli/commands.py names them); the words are this command's own
    parser = subparsers.add_parser(
        "weigh", help=COMMANDS["weigh"].help,
        description="Replay a bag through the monitor and weigh the implement from its lifts and lowers: the "
                    "mass and the cg the strokes identify, with their 95 % intervals, the phases used and the "
                    "implement changes found. Best from a few full lifts and lowers at a steady speed.")
    add_recorded_bag(parser)
    parser.add_argument("--json", action="store_true", help="print one JSON object instead of text")
    return parser


def run_weigh(args: argparse.Namespace) -> int:
    """Run ``linkage-monitor weigh``; returns the exit code (1 when no estimate came out)."""
    bag = Path(args.bag)
    mech = mechanism_from_args(args) or mechanism_in_bag(bag)
    replayed = replay(bag, mech, progress=None)
    estimator = WeighingEstimator(mech)
    last = 0
    for step in replayed.steps:
        if step.pose is not None:
            estimator.step_result(step.stamp_ns, step.pose.result)
            last = step.stamp_ns
    estimator.finish(last)
    estimate = estimator.estimate
    phases = {phase.value: count for phase, count in estimator.phase_steps.items()}
    changes = [{"stamp_ns": c.stamp_ns, "relative_change": c.relative_change} for c in estimator.changes]
    if args.json:
        print(json.dumps({"estimate": _estimate_json(estimate), "phase_steps": phases,
                          "used_phases": [p.value for p in USED], "implement_changes": changes}, indent=2))
    else:
        print(estimate_text(estimate, mech.implement.mass if mech.implement is not None else None))
        print("\nsteps per phase (used: " + ", ".join(p.value for p in USED) + ")")
        for name, count in phases.items():
            print(f"  {name:<15} {count:8d}")
        print(f"\nimplement changes found: {len(changes)}")
        for change in changes:
            print(f"  at {change['stamp_ns'] * 1e-9:.2f} s: load {change['relative_change'] * 100:+.1f} %")
    if estimate is None:
        print("linkage-monitor: error: no estimate: the bag holds no lift and lower over the same poses",
              file=sys.stderr)
        return 1
    return 0


def _estimate_json(estimate: WeighingEstimate | None) -> dict | None:
    if estimate is None:
        return None
    return {"mass_kg": estimate.mass, "mass_u_kg": estimate.mass_u,
            "mass_95_kg": list(estimate.interval(estimate.mass, estimate.mass_u)),
            "cg_x_m": estimate.cg_x, "cg_x_u_m": estimate.cg_x_u, "cg_x_identified": estimate.cg_x_identified,
            "cg_z_m": estimate.cg_z, "cg_z_u_m": estimate.cg_z_u, "cg_z_identified": estimate.cg_z_identified,
            "pairs": estimate.pairs, "friction_share": estimate.friction_share}
