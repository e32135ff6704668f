"""``linkage-monitor`` command line: list presets, solve one pose of a mechanism.

Thin adapter over :mod:`linkage_monitor.mechanics`; SI units (m, rad, N, Pa), frame x forward,
z up, origin at the rear wheels' ground contact.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
import tempfile
from pathlib import Path
from typing import NoReturn, Sequence

import yaml

from linkage_monitor.bag.writer import BagError
from linkage_monitor.cli.arguments import add_mechanism_group, bounded, mechanism_from_args, new_directory, output_file
from linkage_monitor.cli.calibrate import add_calibrate_parser, run_calibrate
from linkage_monitor.cli.can import COMMANDS as CAN_COMMANDS
from linkage_monitor.cli.can import add_can_parsers, add_redecode_arguments, redecoded, run_can_command
from linkage_monitor.cli.capacity import add_capacity_parser, run_capacity
from linkage_monitor.cli.fleet import add_fleet_parser, add_spectrum_arguments, run_fleet_command
from linkage_monitor.cli.simulate import add_simulate_parser, run_simulate
from linkage_monitor.mechanics import kernels
from linkage_monitor.mechanics import Inputs, LinkageError, Mechanism, Result, Solver, apply_overrides, preset_names
from linkage_monitor.mechanics.machine import machine_summary
from linkage_monitor.mechanics.presets import preset_description
from linkage_monitor.monitoring.name_value import name_value, number
from linkage_monitor.offline.history import LoadHistory, spectra_table
from linkage_monitor.offline.replay import replay


class _Parser(argparse.ArgumentParser):
    def error(self, message: str) -> NoReturn:  # one line on stderr, exit code 2
        self.exit(2, f"{self.prog}: error: {message}\n")


def build_parser() -> argparse.ArgumentParser:
    """The argparse parser with its subcommands (presets, solve, capacity, calibrate, simulate, replay, fleet)."""
    parser = _Parser(prog="linkage-monitor", description="Loads in a tractor hitch linkage from cylinder "
                     "strokes, joint angles and pressures (SI units: m, rad, N, Pa).")
    sub = parser.add_subparsers(dest="command", required=True, parser_class=_Parser)
    sub.add_parser("presets", help="list the bundled mechanisms with their description")
    solve = sub.add_parser("solve", help="solve one pose: hinge reactions, cylinder forces, implement load",
                           description="Solve one pose. Inputs default to the file's reference_inputs.")
    add_mechanism_group(solve)
    solve.add_argument("--stroke", action="append", default=[], metavar="CYL=METRES",
                       help="measured cylinder length pin to pin, m (repeatable)")
    solve.add_argument("--angle", action="append", default=[], metavar="SENSOR=RAD",
                       help="joint-angle sensor reading, rad (repeatable)")
    solve.add_argument("--pressure", action="append", default=[], metavar="CYL=CAP_PA[:ROD_PA]",
                       help="gauge pressures of a cylinder's cap (and rod) chamber, Pa; makes its force "
                            "measured and the implement load estimated (repeatable)")
    solve.add_argument("--set", action="append", default=[], metavar="dotted.key=VALUE",
                       help="override a scalar of the file, e.g. implement.mass=1530 or "
                            "cylinders.lift_cylinder.bore=0.11 (repeatable)")
    solve.add_argument("--json", action="store_true", help="print one JSON object instead of a table")
    solve.add_argument("--explain", action="store_true",
                       help="print whether reduced coordinates (along the chain of dyads) serve the statics of "
                            "each set of measured cylinder forces, or only the general linear system does, and why; "
                            "then exit")
    add_capacity_parser(sub)
    add_calibrate_parser(sub)
    add_simulate_parser(sub)
    replay = sub.add_parser("replay", help="re-run the monitor offline over a recorded bag",
                            description="Replay the JointState + FluidPressure messages of a rosbag2 bag "
                                        "(MCAP or sqlite3, one file or split; ours or from `ros2 bag record`) "
                                        "through the monitor, batched, and "
                                        "write the outputs to a new bag and/or a Rerun .rrd; prints a summary.")
    replay.add_argument("bag", metavar="BAG",
                        help="bag directory (metadata.yaml + .mcap or .db3 files) or one .mcap / .db3 file")
    add_mechanism_group(replay, required=False, default="the one recorded in the bag")
    replay.add_argument("--out", metavar="DIR", type=new_directory,
                        help="write inputs + outputs + /diagnostics to this new bag directory")
    replay.add_argument("--rrd", metavar="FILE", type=output_file, help="write a Rerun recording (open with `rerun FILE`)")
    replay.add_argument("--rate", type=bounded(0.0, 1e6, "times real time", lo_open=True), metavar="X",
                        help="write at X times real time (default: as fast as possible)")
    replay.add_argument("--quiet", action="store_true", help="no progress bar")
    replay.add_argument("--spectra", action="store_true",
                        help="print each hinge's rainflow load spectrum and damage-equivalent load (docs/fleet.md)")
    add_spectrum_arguments(replay)
    add_redecode_arguments(replay)
    add_fleet_parser(sub)
    add_can_parsers(sub)
    return parser


def _inputs(mech: Mechanism, args: argparse.Namespace) -> Inputs:
    ref = mech.reference_inputs
    cylinders = dict(ref.get("cylinders", {}))
    angles = dict(ref.get("angles", {}))
    pressures = dict(ref.get("pressures", {}))
    for text in args.stroke:
        name, value = name_value(text, "--stroke")
        cylinders[name] = number(value, "--stroke", name)
    for text in args.angle:
        name, value = name_value(text, "--angle")
        angles[name] = number(value, "--angle", name)
    for text in args.pressure:
        name, value = name_value(text, "--pressure")
        chambers = dict(zip(("cap", "rod"), value.split(":", 1)))
        sensors = {ps.chamber: ps.name for ps in mech.measurements.pressures if ps.cylinder == name}
        if not sensors:
            gauged = sorted({ps.cylinder for ps in mech.measurements.pressures})
            raise LinkageError(f"--pressure {text}: cylinder '{name}' has no pressure sensor "
                               f"(cylinders with sensors: {', '.join(gauged) or 'none'})")
        for chamber, v in chambers.items():
            if chamber not in sensors:
                raise LinkageError(f"--pressure {text}: cylinder '{name}' has no {chamber}-chamber sensor")
            pressures[sensors[chamber]] = number(v, "--pressure", name)
    return Inputs(cylinders=cylinders, angles=angles, pressures=pressures)


def result_json(res: Result) -> dict:
    """The JSON object printed by ``solve --json`` (N, m, Pa)."""
    return {
        "hinges": {n: {"fx": h.fx, "fz": h.fz, "magnitude": h.magnitude} for n, h in res.hinges.items()},
        "cylinders": {n: {"length": c.length, "force": c.force, "cap_pressure": c.cap_pressure_predicted}
                      for n, c in res.cylinders.items()},
        "points": {n: [float(p[0]), float(p[1])] for n, p in res.points.items()},
        "implement": {"cg": [float(v) for v in res.implement_cg], "weight": res.implement_load},
        "status": res.status,
        "residual": res.residual,
    }


def _machine_lines(summary: dict) -> list[str]:
    lines = []
    cap = summary.get("lift_capacity")
    if cap:
        lines.append("lift capacity [kN]: " + ", ".join(
            f"{k} {v / 1e3:.2f}" if v is not None else f"{k} n/a" for k, v in cap.items()))
    steer = summary.get("steerability")
    if steer:
        lines.append(f"axle loads [kN]: front {steer['front_axle_load'] / 1e3:.2f}, rear {steer['rear_axle_load'] / 1e3:.2f}; "
                     f"steerability ratio {steer['ratio']:.3f} (min {steer['ratio_min']:.2f}, margin {steer['margin']:+.3f}); "
                     f"extra front ballast needed {steer['front_ballast_needed']:.0f} kg")
    return lines


def _table(res: Result) -> str:
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
    lines.append(f"status {res.status}{': ' + res.message if res.message else ''}; equilibrium residual {res.residual:.2e} N")
    return "\n".join(lines)


def _solve(args: argparse.Namespace) -> int:
    mech = mechanism_from_args(args)
    assert mech is not None   # the group is required
    overrides = {}
    for text in args.set:
        key, value = name_value(text, "--set")
        overrides[key] = yaml.safe_load(value)
    if overrides:
        mech = apply_overrides(mech, overrides)
    solver = Solver(mech)
    if args.explain:
        print("\n".join([f"{mech.name}: chain {'; '.join(solver.kin.chain_steps) or 'none (not a chain of dyads)'}",
                          *solver.explain()]))
        return 0
    res = solver.solve(_inputs(mech, args))
    summary = machine_summary(solver, res)
    if args.json:
        print(json.dumps({**result_json(res), **{k: v or {} for k, v in summary.items()}}))
    else:
        print("\n".join([_table(res), *_machine_lines(summary)]))
    return 0


def _replay(args: argparse.Namespace) -> int:
    if args.map:   # the bag's raw CAN frames decoded again first
        with tempfile.TemporaryDirectory() as work:
            return _replay_bag(args, redecoded(args, Path(work)))
    return _replay_bag(args, Path(args.bag))


def _replay_bag(args: argparse.Namespace, bag: Path) -> int:
    replayed = replay(bag, mechanism_from_args(args), out_dir=args.out, rrd=args.rrd, rate=args.rate,
                      progress=None if args.quiet else sys.stderr)
    summary = replayed.summary
    print(summary.table())
    if args.spectra:
        print("\n" + spectra_table(LoadHistory.from_run(replayed.run), args.slope, args.bin))
    if summary.solved == 0:
        print(f"linkage-monitor: error: no pose of {args.bag} was solved ({summary.inputs} inputs; see the findings "
              "above): is it the right mechanism?", file=sys.stderr)
        return 1
    if args.out:
        print(f"\noutputs written to {args.out}")
    if args.rrd:
        print(f"Rerun recording written to {args.rrd}: open it with `.venv/bin/rerun {args.rrd}`")
    return 0


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command line; returns the exit code (0 ok, 2 bad input: one line on stderr)."""
    args = build_parser().parse_args(argv)
    if args.command in ("capacity", "calibrate", "replay"):
        kernels.allow_threads()   # large batches on every core (fleet: one process per core instead)
    try:
        if args.command == "presets":
            try:
                for name in preset_names():
                    print(f"{name:<24} {preset_description(name)}")
            except BrokenPipeError:   # `linkage-monitor presets | head -1`
                sys.stdout = open(os.devnull, "w")  # noqa: SIM115 - the interpreter closes it at exit
            return 0
        if args.command == "capacity":
            return run_capacity(args)
        if args.command == "calibrate":
            return run_calibrate(args)
        if args.command == "simulate":
            return run_simulate(args)
        if args.command == "fleet":
            return run_fleet_command(args)
        if args.command == "replay":
            return _replay(args)
        if args.command in CAN_COMMANDS:
            return run_can_command(args)
        return _solve(args)
    except (LinkageError, BagError, yaml.YAMLError) as exc:
        print(f"linkage-monitor: error: {str(exc).splitlines()[0]}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
