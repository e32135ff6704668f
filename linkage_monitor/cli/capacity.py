"""``linkage-monitor capacity``: lift capacity and steerability limit over the lift cylinder's stroke.

Transport poses (implement raised, weights only), solved batched. SI units in JSON (m, N, kg);
the table and the plot use kN. Frame x forward, z up, origin at the rear wheels' ground contact.
"""

from __future__ import annotations

import argparse
import json
from dataclasses import dataclass

import numpy as np

from linkage_monitor.cli.arguments import add_mechanism_group, bounded, mechanism_from_args, output_file
from linkage_monitor.cli.commands import COMMANDS, EXIT_CODES
from linkage_monitor.cli.main import emit
from linkage_monitor.cli.verdict import exit_code, finding_json, finding_line, judge_strokes, worst
from linkage_monitor.mechanics import LinkageError, Mechanism, Solver
from linkage_monitor.mechanics.capacity import (interval_around, lift_cylinder, reference_length, relief_pressure,
                                                stroke_mechanism)
from linkage_monitor.mechanics.machine import MachineBatch, MachineModel
from linkage_monitor.mechanics.results import Status
from linkage_monitor.monitoring.core import Step
from linkage_monitor.monitoring.findings import Finding

SCAN_POINTS = 401  # cylinder lengths tried between 0.5 and 1.5 × the reference length to find the stroke


def add_capacity_parser(subparsers: argparse._SubParsersAction) -> argparse.ArgumentParser:
    """Add the ``capacity`` subcommand to ``subparsers``; returns its parser."""
    p = subparsers.add_parser(
        "capacity", help=COMMANDS["capacity"].help, epilog=EXIT_CODES,
        description="Lift capacity at p_max*eta over the lift cylinder's stroke (transport poses) with the "
                    "largest implement weight the tractor can steer with (Popov 2009, Fig. 4-5).")
    add_mechanism_group(p)
    p.add_argument("--stroke", nargs=2, type=bounded(0.0, 100.0, "m", lo_open=True), metavar=("MIN_M", "MAX_M"),
                   help="lift cylinder lengths to sweep, m (default: the range around the reference length in "
                        "which the linkage assembles and the implement rises)")
    p.add_argument("--points", type=bounded(2, 100_000, integer=True), default=101,
                   help="number of cylinder lengths, 2 to 100000 (default 101)")
    p.add_argument("--plot", metavar="FILE.png", type=output_file, help="write the capacity curve as a PNG")
    p.add_argument("--json", action="store_true", help="print one JSON object instead of a table")
    return p


def lifting_stroke(model: MachineModel, cylinder: str, length: float) -> tuple[float, float]:
    """Shortest and longest length (m) of ``cylinder`` around ``length`` over which the linkage
    assembles and lengthening the cylinder raises the implement's cg (past that the lower links toggle)."""
    lengths = np.linspace(0.5, 1.5, SCAN_POINTS) * length
    batch = model.stroke_poses(cylinder, lengths)
    ok = (batch.status == Status.OK) & (np.gradient(batch.implement_cg[:, 1], lengths) > 0.0)
    stroke = interval_around(lengths, ok, length)
    if stroke is None:
        raise LinkageError(f"cylinder '{cylinder}': at its reference length {length:.4f} m the linkage "
                           f"does not assemble or does not lift the implement; give --stroke MIN MAX")
    return stroke


@dataclass(frozen=True)
class CapacityCurve:
    """The capacity curve: ``table`` the JSON-ready dict (m, N, kg: lengths, capacities, steerability
    limit, ratio axis/610 mm, the monitor's level and findings per pose); ``machine`` the machine-level
    results it came from; ``steps`` the node's monitor's Step of each pose."""

    table: dict
    machine: MachineBatch
    steps: list[Step]


def capacity_curve(mech: Mechanism, stroke: tuple[float, float] | None, points: int, spec: str = "") -> CapacityCurve:
    """The capacity curve over ``points`` lengths of the lift cylinder (``stroke``: m, default the lifting
    stroke), each pose judged by the node's monitor (``spec``: the mechanism as given, for the record)."""
    if points < 2:
        raise LinkageError(f"--points {points}: at least 2 cylinder lengths are needed")
    cyl = lift_cylinder(mech)
    sweep = stroke_mechanism(mech)
    solver = Solver(sweep)
    model = MachineModel(sweep, solver, cyl.name)
    if stroke is None:
        stroke = lifting_stroke(model, cyl.name, reference_length(mech, cyl.name))
    if not 0.0 < stroke[0] < stroke[1]:
        raise LinkageError(f"--stroke {stroke[0]} {stroke[1]}: expected 0 < MIN < MAX (m)")
    lengths = np.linspace(stroke[0], stroke[1], points)
    batch, machine = model.capacity_curve(cyl.name, lengths)
    held = {c: np.full(points, reference_length(sweep, c)) for c in sweep.measurements.cylinders if c != cyl.name}
    steps = judge_strokes(sweep, spec or mech.name, {**held, cyl.name: lengths})
    listed = lambda a: [None if np.isnan(v) else float(v) for v in a]  # noqa: E731
    assert mech.implement is not None   # lift_cylinder/capacity_points above require one
    out = {"mechanism": mech.name, "cylinder": cyl.name, "capacity_force": model.capacity_force,
           "implement_weight": mech.implement.mass * mech.gravity, "length": listed(lengths),
           "status": [int(s) for s in batch.status],
           "lift_capacity": {k: listed(v) for k, v in machine.lift_capacity.items() if k != "reserve"}}
    cap = machine.lift_capacity
    if "behind_610mm" in cap:
        out["ratio_axis_to_610mm"] = listed(cap["hitch_axis"] / cap["behind_610mm"])
    if machine.steerability:
        out["max_implement_mass"] = listed(machine.steerability["max_implement_mass"])
        out["max_implement_weight"] = listed(machine.steerability["max_implement_mass"] * mech.gravity)
    out["level"] = [s.level.name for s in steps]
    out["findings"] = [[finding_json(f) for f in s.findings] for s in steps]
    out["verdict"] = worst(steps).name
    return CapacityCurve(out, machine, steps)


def _findings_lines(curve: dict, steps: list[Step]) -> list[str]:
    """Per finding code, its first sentence along the stroke and at how many lengths the monitor reports it."""
    lengths = curve["length"]
    first: dict[str, Finding] = {}
    poses: dict[str, list[int]] = {}
    for i, step in enumerate(steps):
        for finding in step.findings:
            first.setdefault(finding.code.ident, finding)
            poses.setdefault(finding.code.ident, []).append(i)
    return [*(f"{finding_line(first[code])} [the first of {len(at)} of {len(steps)} lengths, S {lengths[at[0]]:.4f}"
              f"-{lengths[at[-1]]:.4f} m]" for code, at in poses.items()), f"verdict {curve['verdict']}"]


def _table(curve: dict, rows: int = 11) -> str:
    idx = np.unique(np.linspace(0, len(curve["length"]) - 1, rows).round().astype(int))
    cols: list[tuple[str, list, float, str]] = [("S [m]", curve["length"], 1.0, "{:8.4f}")]
    names = {"hitch_axis": "axis [kN]", "behind_610mm": "610mm [kN]", "implement_cg": "cg [kN]"}
    cols += [(names[k], v, 1e-3, "{:10.2f}") for k, v in curve["lift_capacity"].items()]
    if "max_implement_weight" in curve:
        cols.append(("steer max [kN]", curve["max_implement_weight"], 1e-3, "{:14.2f}"))
    lines = [f"{curve['mechanism']}: lift capacity at p_max*eta*A = {curve['capacity_force'] / 1e3:.2f} kN, "
             f"implement weight {curve['implement_weight'] / 1e3:.2f} kN (transport poses)",
             "  ".join([*(f"{c[0]:>{max(8, len(c[0]))}}" for c in cols), "verdict"])]
    for i in idx:
        cells = []
        for head, values, scale, fmt in cols:
            v = values[i]
            cells.append(f"{'-':>{max(8, len(head))}}" if v is None else fmt.format(v * scale).rjust(max(8, len(head))))
        lines.append("  ".join([*cells, curve["level"][i]]))
    return "\n".join(lines)


def run_capacity(args: argparse.Namespace) -> int:
    """Run ``linkage-monitor capacity``; returns the exit code: ``verdict.ERROR_EXIT`` when the monitor's
    verdict on a pose of the sweep is ERROR, else 0 (a LinkageError propagates to the caller)."""
    from linkage_monitor.viz.capacity_plot import (
        plot_capacity,  # matplotlib only when this subcommand runs
    )

    mech = mechanism_from_args(args)
    assert mech is not None   # the group is required
    sweep = capacity_curve(mech, tuple(args.stroke) if args.stroke else None, args.points, args.preset or args.mechanism)
    curve, machine = sweep.table, sweep.machine
    if args.plot:
        cyl = mech.cylinder(curve["cylinder"])
        title = (f"{mech.name}: lift capacity at p_max {relief_pressure(cyl) / 1e6:.1f} MPa × η {cyl.efficiency:.2f}"
                 f" (transport)")
        plot_capacity(np.array(curve["length"], dtype=float), machine, mech.gravity, curve["implement_weight"],
                      title, args.plot, mech.tractor.steerability_reference if mech.tractor else "unit")
    emit(json.dumps(curve) if args.json else "\n".join([_table(curve), *_findings_lines(curve, sweep.steps)]))
    return exit_code(worst(sweep.steps))
