"""``linkage-monitor calibrate``: fit geometry parameters of a mechanism to a CSV file or a bag.

Thin adapter: reads the data into columns (CSV header names, or a rosbag2 bag's JointState
and FluidPressure topics), hands them to :func:`linkage_monitor.mechanics.calibration.calibrate`
and writes the fitted description. Column names and units: docs/calibration.md. SI units (m,
rad, N, gauge Pa); frame x forward, z up, origin at the rear wheels' ground contact.
"""

from __future__ import annotations

import argparse
import csv
from pathlib import Path

import numpy as np

from linkage_monitor.cli.arguments import add_mechanism_group, mechanism_from_args, output_file
from linkage_monitor.cli.commands import COMMANDS
from linkage_monitor.mechanics import InputError, LinkageError, Mechanism
from linkage_monitor.mechanics.calibration import UNITS, FitResult, calibrate, fitted_yaml
from linkage_monitor.mechanics.constants import ATMOSPHERIC_PRESSURE
from linkage_monitor.monitoring.name_value import name_value, number



def add_calibrate_parser(subparsers: argparse._SubParsersAction) -> argparse.ArgumentParser:
    """Add the ``calibrate`` subcommand to ``subparsers``; returns its parser."""
    # the form of every subcommand's parser (cli/commands.py names them); the words are this command's own
    p = subparsers.add_parser(
        "calibrate", help=COMMANDS["calibrate"].help,
        description="Bounded nonlinear least squares of the --free parameters of the start mechanism to the "
                    "data; reports the residual per column, each parameter's uncertainty and the parameters "
                    "the data cannot determine (docs/calibration.md).")
    add_mechanism_group(p)
    p.add_argument("--data", required=True, metavar="FILE.csv|BAG",
                   help="CSV with a header of column names, or a rosbag2 bag (directory, .mcap or .db3)")
    p.add_argument("--free", required=True, action="append", metavar="PARAM[,PARAM...]",
                   help="parameters to fit, dotted keys: points.P05.x, points.S6.z, implement.mass, "
                        "cylinders.lift_cylinder.bore, measurements.angles.NAME.reference (repeatable)")
    p.add_argument("--out", required=True, metavar="FITTED.yaml", type=output_file,
                   help="write the fitted mechanism here")
    p.add_argument("--inputs", metavar="NAME[,NAME...]",
                   help="data columns that drive the linkage (default: the measured cylinders, plus the "
                        "angle sensors if the cylinders do not fix the pose)")
    # repeatable NAME=VALUE options, alike in form only to solve's --pressure and --set: other meanings
    p.add_argument("--sigma", action="append", default=[], metavar="COLUMN=VALUE",
                   help="standard deviation of a measured column in its unit (default: 1 mm, 1 mrad, "
                        "0.05 MPa, 500 N by kind)")
    p.add_argument("--bound", action="append", default=[], metavar="PARAM=HALF_WIDTH",
                   help="fit PARAM within start ± HALF_WIDTH (default: 0.05 m for coordinates, 0.2 rad for "
                        "angle references, 50 %% of the start value otherwise)")
    p.add_argument("--gauge-pressure", action="store_true",
                   help="the bag's FluidPressure values are gauge (default: absolute, as the message defines)")
    return p


def _numbers(texts: list[str], option: str) -> dict[str, float]:
    pairs = (name_value(text, option) for text in texts)
    return {name: number(value, option, name) for name, value in pairs}


def read_csv_columns(path: Path) -> dict[str, np.ndarray]:
    """Columns of a CSV file: header row of names, then numbers; lines starting with # are skipped."""
    try:
        with open(path, newline="", encoding="utf-8") as stream:
            rows = [r for r in csv.reader(line for line in stream if not line.lstrip().startswith("#")) if r]
    except (OSError, UnicodeDecodeError) as exc:
        raise InputError(f"--data {path}: cannot read the file ({getattr(exc, 'strerror', None) or exc})") from None
    if len(rows) < 2:
        raise InputError(f"--data {path}: expected a header row of column names and at least one row of numbers")
    header = [h.strip() for h in rows[0]]
    repeated = sorted({h for h in header if header.count(h) > 1 or not h})
    if repeated:
        raise InputError(f"--data {path}: the header names column {repeated[0]!r} twice or not at all: "
                         f"give every column one unique name")
    values = np.empty((len(rows) - 1, len(header)))
    for i, row in enumerate(rows[1:], start=2):
        if len(row) != len(header):
            raise InputError(f"--data {path}: data row {i} has {len(row)} values, the header names {len(header)}")
        for j, cell in enumerate(row):
            try:
                values[i - 2, j] = float(cell)
            except ValueError:
                raise InputError(f"--data {path}: data row {i}, column '{header[j]}': {cell!r} is not a number") from None
    return {name: values[:, j] for j, name in enumerate(header)}


def read_bag_columns(path: Path, mech: Mechanism, gauge: bool = False) -> dict[str, np.ndarray]:
    """Columns of a bag: the JointState positions of the measured cylinders (m) and angle sensors (rad),
    one row per message, and each ``.../pressure/<sensor>`` FluidPressure topic as ``pressure:<sensor>``
    (gauge Pa, interpolated at the JointState stamps; rows outside the pressure record are dropped)."""
    from linkage_monitor.bag.columns import JointStateColumns
    from linkage_monitor.bag.errors import BagError
    from linkage_monitor.bag.reader import read_inputs  # rclpy only when a bag is read

    try:
        topics = read_inputs(path)
    except BagError as exc:
        raise InputError(f"--data {path}: {exc}") from None
    wanted = set(mech.measurements.cylinders) | {a.name for a in mech.measurements.angles}
    joints = {t: c for t, c in topics.items() if isinstance(c, JointStateColumns) and wanted & set(c.names)}
    if len(joints) != 1:
        raise InputError(f"--data {path}: expected one JointState topic with the joints {', '.join(sorted(wanted))}, "
                         f"found {len(joints)} ({', '.join(joints) or 'none'})")
    js = next(iter(joints.values()))
    columns = {n: js.position[:, k] for k, n in enumerate(js.names) if n in wanted}
    stamps = js.stamp_ns.astype(float)
    keep = np.all(np.isfinite(np.column_stack(list(columns.values()))), axis=1)
    for sensor in mech.measurements.pressures:
        match = [c for t, c in topics.items() if t.rstrip("/").endswith(f"pressure/{sensor.name}")
                 and not isinstance(c, JointStateColumns)]
        if not match:
            continue
        pc = match[0]
        order = np.argsort(pc.stamp_ns)
        p_stamps = pc.stamp_ns[order].astype(float)
        value = pc.fluid_pressure[order] - (0.0 if gauge else ATMOSPHERIC_PRESSURE)
        columns[f"pressure:{sensor.name}"] = np.interp(stamps, p_stamps, value)
        keep &= (stamps >= p_stamps[0]) & (stamps <= p_stamps[-1])
    if not np.any(keep):
        raise InputError(f"--data {path}: no JointState message has all of {', '.join(columns)} inside the "
                         f"pressure record")
    return {n: v[keep] for n, v in columns.items()}


def report(result: FitResult) -> str:
    """Human-readable fit report: parameters (start, fitted, uncertainty, bounds), residuals per column."""
    lines = [f"{result.n_poses} poses, driving inputs {', '.join(result.inputs)}; {result.message}",
             f"{'parameter':<46} {'start':>11} {'fitted':>11} {'± 1 sigma':>10}  bounds"]
    for p, v, u in zip(result.parameters, result.values, result.uncertainty):
        notes = (["UNDETERMINED"] if p.key in result.undetermined else []) + (["at bound"] if p.key in result.at_bound else [])
        lines.append(f"{p.key:<46} {p.start:11.6g} {v:11.6g} {u:10.2g}  [{p.lower:.6g}, {p.upper:.6g}]"
                     f"{'  ' + ', '.join(notes) if notes else ''}")
    lines.append(f"{'measured column':<46} {'RMS start':>11} {'RMS fitted':>11}  unit")
    for c in result.columns:
        lines.append(f"{c.name:<46} {result.rms_start[c.name]:11.4g} {result.rms[c.name]:11.4g}  {UNITS[c.kind]}")
    if result.undetermined:
        lines.append(f"the data cannot determine: {', '.join(result.undetermined)} (fix them or add data that "
                     f"depends on them)")
    if result.failed_poses:
        lines.append(f"warning: {result.failed_poses} pose(s) do not solve with the fitted values")
    return "\n".join(lines)


def run_calibrate(args: argparse.Namespace) -> int:
    """Run ``linkage-monitor calibrate``; returns the exit code (LinkageError propagates to the caller)."""
    start = mechanism_from_args(args)
    assert start is not None   # the group is required
    from linkage_monitor.bag.storage import STORAGE_SUFFIXES   # the bag reader's imports only when needed

    data_path = Path(args.data)
    if data_path.is_dir() or data_path.suffix in STORAGE_SUFFIXES:
        columns = read_bag_columns(data_path, start, args.gauge_pressure)
    else:
        columns = read_csv_columns(data_path)
    free = [k.strip() for text in args.free for k in text.split(",") if k.strip()]
    inputs = [k.strip() for k in args.inputs.split(",") if k.strip()] if args.inputs else None
    result = calibrate(start, columns, free, inputs=inputs, sigma=_numbers(args.sigma, "--sigma"),
                       half_widths=_numbers(args.bound, "--bound"))
    text = fitted_yaml(result, args.mechanism or f"preset {args.preset}", str(data_path))
    try:
        Path(args.out).write_text(text, encoding="utf-8")
    except OSError as exc:
        raise LinkageError(f"--out {args.out}: cannot write the file ({exc.strerror})") from None
    print(report(result))
    print(f"wrote {args.out}")
    return 0

