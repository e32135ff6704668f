"""``linkage-monitor solve``: one pose of a mechanism, judged by the monitoring core as the node judges it.

The measured cylinder lengths and angles given (``--stroke``, ``--angle``) need only fix the pose:
the measurements not given are predicted from them (the linkage placed by its kinematics driven by
the given ones) and printed; given none, the file's ``reference_inputs`` are used. The pose's inputs
then go through the node's monitor (``cli.verdict``): its findings are printed, and the exit code
is ``verdict.ERROR_EXIT`` when its verdict is ERROR. SI units (m, rad, N, gauge Pa); frame x
forward, z up, origin at the rear wheels' ground contact.
"""

from __future__ import annotations

import argparse
import json
import math
from dataclasses import dataclass

import yaml

from linkage_monitor.cli.arguments import add_mechanism_group, mechanism_from_args
from linkage_monitor.cli.budget import budget_json, budget_lines
from linkage_monitor.cli.commands import COMMANDS, EXIT_CODES
from linkage_monitor.cli.main import emit
from linkage_monitor.cli.verdict import exit_code, finding_json, finding_line, judge
from linkage_monitor.mechanics import (InputError, Inputs, Mechanism, Result, Solver,
                                       UnobservableError, apply_overrides)
from linkage_monitor.mechanics.calibration import drive_mechanism
from linkage_monitor.mechanics.machine import CAPACITY_KEYS, STEERABILITY_KEYS, MachineResult
from linkage_monitor.mechanics.results import Status, angle_readings
from linkage_monitor.mechanics.budget import Budget
from linkage_monitor.monitoring.core import Step
from linkage_monitor.monitoring.name_value import name_value, number


def add_solve_parser(subparsers: argparse._SubParsersAction) -> argparse.ArgumentParser:
    """Add the ``solve`` subcommand to ``subparsers``; returns its parser."""
    parser = subparsers.add_parser(
        "solve", help=COMMANDS["solve"].help, epilog=EXIT_CODES,
        description="Solve one pose and judge it as the monitor node does. Give measured cylinder lengths and "
                    "angles that fix the pose (those not given are predicted from them and printed; with "
                    "redundant sensors, give several and the monitor checks them against each other), or none: "
                    "then the file's reference_inputs. Prints the pose, the machine level, and the node's "
                    "verdict with its findings (level, code, message).")
    add_solve_arguments(parser)
    return parser


def add_solve_arguments(parser: argparse.ArgumentParser) -> None:
    """The options of ``solve``."""
    add_mechanism_group(parser)
    parser.add_argument("--stroke", action="append", default=[], metavar="CYL=METRES",
                        help="measured cylinder length pin to pin, m (repeatable)")
    parser.add_argument("--angle", action="append", default=[], metavar="SENSOR=RAD",
                        help="joint-angle sensor reading, rad (repeatable)")
    # repeatable NAME=VALUE options, alike in form only to calibrate's --sigma and --bound: other meanings
    parser.add_argument("--pressure", action="append", default=[], metavar="CYL=CAP_PA[:ROD_PA]",
                        help="gauge pressures of a cylinder's cap (and rod) chamber, Pa; makes its force "
                             "measured and the implement load estimated (repeatable)")
    parser.add_argument("--set", action="append", default=[], metavar="dotted.key=VALUE",
                        help="override a scalar of the file, e.g. implement.mass=1530 or "
                             "cylinders.lift_cylinder.bore=0.11 (repeatable)")
    parser.add_argument("--json", action="store_true", help="print one JSON object instead of a table")
    parser.add_argument("--uncertainty", action="store_true",
                        help="print every output's standard uncertainty (1 sigma, same unit as the value) and "
                             "the share of each declared error source, and judge the limits on their 95 %% "
                             "intervals (docs/accuracy.md); one pose stands: its seal friction takes the whole "
                             "breakaway band")
    parser.add_argument("--explain", action="store_true",
                        help="print whether reduced coordinates (along the chain of dyads) serve the statics of "
                             "each set of measured cylinder forces, or only the general linear system does, and "
                             "why; then exit")


@dataclass(frozen=True)
class PoseInputs:
    """The pose to judge: the mechanism, its inputs (SI units) and which of its cylinder lengths and
    angles were predicted from the given ones (name -> value, m or rad). Where the given measurements
    place no linkage, the mechanism is the one measuring only them (``drive_mechanism``) and the inputs
    are the given ones: the node's verdict on them says why."""

    mechanism: Mechanism
    inputs: Inputs
    predicted: dict[str, float]


def _given(texts: list[str], option: str, known: list[str], kind: str) -> dict[str, float]:
    """``NAME=VALUE`` options as numbers, each NAME one of the mechanism's measured ``known`` inputs."""
    values = {}
    for text in texts:
        name, value = name_value(text, option)
        if name not in known:
            raise InputError(f"{option} {text}: '{name}' is not a measured {kind} of the mechanism "
                             f"(measured: {', '.join(known) or 'none'}): unknown input")
        values[name] = number(value, option, name)
    return values


def _pressures(mech: Mechanism, texts: list[str]) -> dict[str, float]:
    """``--pressure CYL=CAP[:ROD]`` as gauge Pa per pressure sensor."""
    pressures = {}
    for text in texts:
        name, value = name_value(text, "--pressure")
        sensors = {ps.chamber: ps.name for ps in mech.measurements.pressures if ps.cylinder == name}
        if not sensors:
            gauged = sorted({ps.cylinder for ps in mech.measurements.pressures})
            raise InputError(f"--pressure {text}: cylinder '{name}' has no pressure sensor "
                             f"(cylinders with sensors: {', '.join(gauged) or 'none'})")
        for chamber, v in dict(zip(("cap", "rod"), value.split(":", 1))).items():
            if chamber not in sensors:
                raise InputError(f"--pressure {text}: cylinder '{name}' has no {chamber}-chamber sensor")
            pressures[sensors[chamber]] = number(v, "--pressure", name)
    return pressures


def _option(mech: Mechanism, name: str) -> str:
    """How the measurement ``name`` is given: ``--stroke NAME=M`` or ``--angle NAME=RAD``."""
    return f"--stroke {name}=M" if name in mech.measurements.cylinders else f"--angle {name}=RAD"


def pose_inputs(mech: Mechanism, args: argparse.Namespace) -> PoseInputs:
    """The pose from the options: the given lengths and angles, the measured ones not given predicted from
    them (all from the file's ``reference_inputs`` when none is given), the given pressures (else the
    reference ones). InputError naming the missing measurements when the given ones do not fix the pose."""
    cylinders = _given(args.stroke, "--stroke", list(mech.measurements.cylinders), "cylinder")
    angle_names = [a.name for a in mech.measurements.angles]
    angles = _given(args.angle, "--angle", angle_names, "angle sensor")
    reference = mech.reference_inputs
    pressures = _pressures(mech, args.pressure) or dict(reference.get("pressures", {}))
    if not cylinders and not angles:
        return PoseInputs(mech, Inputs(cylinders=dict(reference.get("cylinders", {})),
                                       angles=dict(reference.get("angles", {})), pressures=pressures), {})
    given = [*cylinders, *angles]
    missing = [n for n in [*mech.measurements.cylinders, *angle_names] if n not in given]
    if not missing:
        return PoseInputs(mech, Inputs(cylinders=cylinders, angles=angles, pressures=pressures), {})
    drive = drive_mechanism(mech, given)
    try:
        solver = Solver(drive)
    except UnobservableError:
        raise InputError(f"the given measurements ({', '.join(given)}) do not fix the pose of '{mech.name}': give also "
                         f"{' and '.join(_option(mech, n) for n in missing)} (measurements not given are "
                         "predicted only where the given ones fix the linkage)") from None
    batch = solver.solve_batch(cylinders=cylinders, angles=angles)
    if batch.status[0] >= Status.INPUT:
        return PoseInputs(drive, Inputs(cylinders=cylinders, angles=angles), {})
    readings = {**{n: float(v[0]) for n, v in batch.cylinder_length.items()},
                **{n: float(v[0]) for n, v in angle_readings(mech, batch).items()}}
    predicted = {n: readings[n] for n in missing}
    return PoseInputs(mech, Inputs(cylinders={**cylinders, **{n: predicted[n] for n in missing if n not in angle_names}},
                                   angles={**angles, **{n: predicted[n] for n in missing if n in angle_names}},
                                   pressures=pressures), predicted)


def result_json(res: Result) -> dict:
    """The pose's part of the JSON object printed by ``solve --json`` (N, m, Pa)."""
    return {
        "hinges": {n: {"fx": h.fx, "fz": h.fz, "magnitude": h.magnitude} for n, h in res.hinges.items()},
        "cylinders": {n: {"length": c.length, "force": c.force, "cap_pressure": c.cap_pressure_predicted}
                      for n, c in res.cylinders.items()},
        "points": {n: [float(p[0]), float(p[1])] for n, p in res.points.items()},
        "implement": {"cg": [float(v) for v in res.implement_cg], "weight": res.implement_load},
        "status": res.status,
        "residual": res.residual,
    }


def machine_json(machine: MachineResult) -> dict:
    """``{"lift_capacity": {CAPACITY_KEYS} N, "steerability": {STEERABILITY_KEYS}}`` of the judged pose
    (NaN -> None; {} without a tractor block or lift capacity)."""
    def pick(values: dict[str, float], keys: tuple[str, ...]) -> dict:
        return {k: None if math.isnan(values[k]) else values[k] for k in keys if k in values}

    return {"lift_capacity": pick(machine.lift_capacity, CAPACITY_KEYS),
            "steerability": pick(machine.steerability, STEERABILITY_KEYS)}


def _machine_lines(summary: dict) -> list[str]:
    lines = []
    cap = summary["lift_capacity"]
    if cap:
        lines.append("lift capacity [kN]: " + ", ".join(
            f"{k} {v / 1e3:.2f}" if v is not None else f"{k} n/a" for k, v in cap.items()))
    steer = summary["steerability"]
    if steer:
        lines.append(f"axle loads [kN]: front {steer['front_axle_load'] / 1e3:.2f}, rear {steer['rear_axle_load'] / 1e3:.2f}; "
                     f"steerability ratio {steer['ratio']:.3f} (min {steer['ratio_min']:.2f}, margin {steer['margin']:+.3f}); "
                     f"extra front ballast needed {steer['front_ballast_needed']:.0f} kg")
    return lines


def _table(res: Result) -> list[str]:
    lines = ["hinge        fx [kN]   fz [kN]  |F| [kN]  (force on body from body)"]
    for n, h in res.hinges.items():
        lines.append(f"{n:<10} {h.fx / 1e3:9.3f} {h.fz / 1e3:9.3f} {h.magnitude / 1e3:9.3f}  ({h.on_body} from {h.from_body})")
    lines.append("cylinder        length [m]  force [kN]  cap pressure [MPa]")
    for n, c in res.cylinders.items():
        lines.append(f"{n:<15} {c.length:10.4f} {c.force / 1e3:11.3f} {c.cap_pressure_predicted / 1e6:19.3f}")
    for n, contact in res.contacts.items():
        lines.append(f"contact {n}: normal {contact.normal / 1e3:.3f} kN, friction {contact.tangential / 1e3:.3f} kN")
    if not math.isnan(res.implement_load):
        cg = res.implement_cg
        lines.append(f"implement load {res.implement_load / 1e3:.3f} kN at cg ({cg[0]:.3f}, {cg[1]:.3f}) m")
    lines.append(f"equilibrium residual {res.residual:.2e} N")
    return lines


def _predicted_lines(mech: Mechanism, predicted: dict[str, float]) -> list[str]:
    return [f"predicted {n} = {v:.6g} {'m' if n in mech.measurements.cylinders else 'rad'} (not given: placed by "
            "the given measurements)" for n, v in predicted.items()]


def _verdict_lines(step: Step) -> list[str]:
    return [f"verdict {step.level.name}", *(finding_line(f) for f in step.findings)]


def _mechanism(args: argparse.Namespace) -> Mechanism:
    mech = mechanism_from_args(args)
    assert mech is not None   # the group is required
    overrides = {}
    for text in args.set:
        key, value = name_value(text, "--set")
        overrides[key] = yaml.safe_load(value)
    return apply_overrides(mech, overrides) if overrides else mech


def run_solve(args: argparse.Namespace) -> int:
    """Run ``linkage-monitor solve``; returns the exit code: ``verdict.ERROR_EXIT`` when the monitor's
    verdict on the pose is ERROR, else 0 (a LinkageError about the options propagates to the caller)."""
    mech = _mechanism(args)
    if args.explain:
        solver = Solver(mech)
        print("\n".join([f"{mech.name}: chain {'; '.join(solver.kin.chain_steps) or 'none (not a chain of dyads)'}",
                          *solver.explain()]))
        return 0
    pose = pose_inputs(mech, args)
    step = judge(pose.mechanism, args.preset or args.mechanism, pose.inputs, uncertainty=args.uncertainty)
    return _print(mech, step, pose.predicted, args.json, step.pose.budget if step.pose is not None else None)


def _print(mech: Mechanism, step: Step, predicted: dict[str, float], as_json: bool, budget: Budget | None) -> int:
    """Print the judged pose (its table, or JSON), its error budget when given, and the verdict; the
    exit code of the verdict."""
    if as_json:
        out: dict = {"level": step.level.name, "findings": [finding_json(f) for f in step.findings],
                     "predicted": predicted}
        if step.pose is not None:
            out.update({**result_json(step.pose.result), **machine_json(step.pose.machine)})
        if budget is not None:
            out["uncertainty"] = budget_json(budget)
        emit(json.dumps(out))
    else:
        lines = _predicted_lines(mech, predicted)
        if step.pose is not None:
            lines += [*_table(step.pose.result), *_machine_lines(machine_json(step.pose.machine))]
        if budget is not None:
            lines += budget_lines(budget)
        emit("\n".join([*lines, *_verdict_lines(step)]))
    return exit_code(step.level)

