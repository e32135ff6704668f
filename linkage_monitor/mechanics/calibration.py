"""Geometry calibration: fit chosen parameters of a mechanism to measured kinematics and forces.

Bounded nonlinear least squares (``scipy.optimize.least_squares``) over dotted parameter keys of
the mechanism description (docs/calibration.md): scalars as ``--set`` takes them
(``implement.mass``, ``cylinders.lift_cylinder.bore``,
``measurements.angles.lift_arm_angle.reference``) and one coordinate of an ``[x, z]`` pair by a
trailing ``.x`` / ``.z`` (``points.P05.x``, ``bodies.implement.cg.z``). Data are columns over
poses: the driving inputs (cylinder lengths m, angle-sensor readings rad) and measured columns
(``x:P56`` / ``z:P56`` m, angle-sensor readings rad, ``pressure:<sensor>`` gauge Pa,
``force:<cylinder>`` N, ``hinge:<hinge>`` N). The implement load is its configured weight
(``implement.mass``), so pressures and forces are predicted by the statics.

SI units; frame x forward, z up, origin at the rear wheels' ground contact B. No rclpy.
"""

from __future__ import annotations

import copy
from dataclasses import dataclass
from typing import Any, Mapping, Sequence

import numpy as np
import yaml

from .errors import InputError, LinkageError, MechanismFileError
from .model import Mechanism
from .results import Status, angle_readings
from .schema import mechanism_from_dict
from .solver import Solver

POINT_HALF_WIDTH = 0.05      # m, default bound of a coordinate around its start value
ANGLE_HALF_WIDTH = 0.2       # rad, default bound of an angle-sensor reference
RELATIVE_HALF_WIDTH = 0.5    # default bound of any other scalar: ± this share of its start value
DEFAULT_SIGMA = {"length": 1e-3, "angle": 1e-3, "pressure": 5e4, "force": 500.0}  # m, rad, Pa, N
UNITS = {"length": "m", "angle": "rad", "pressure": "Pa", "force": "N"}
FAILED_POSE_RESIDUAL = 1e3   # weighted residual (in sigmas) of a pose that does not solve at trial values
RANK_TOL = 1e-6              # singular value / largest (columns normalized) below which a direction is unobservable
NULL_SHARE = 0.1             # component in an unobservable direction above which a parameter is undetermined


# ---- parameters: dotted keys into the raw description --------------------------------------
def _locate(raw: Any, key: str, file: str) -> tuple[Any, Any]:
    """(container, index) of the number that ``key`` names in the raw description."""
    parts = key.split(".")
    node: Any = raw
    container: Any = None
    index: Any = None
    for depth, part in enumerate(parts):
        here = ".".join(parts[:depth]) or "the file"
        if isinstance(node, list) and len(node) == 2 and part in ("x", "z") and depth == len(parts) - 1:
            return node, 0 if part == "x" else 1
        if isinstance(node, list):
            match = [i for i, item in enumerate(node) if isinstance(item, dict) and item.get("name") == part]
            if not match:
                names = ", ".join(str(it.get("name")) for it in node if isinstance(it, dict)) or "none"
                raise MechanismFileError(file, key, f"no item named '{part}' in {here} (items: {names}); "
                                                    f"an [x, z] pair takes .x or .z")
            container, index = node, match[0]
        elif isinstance(node, dict):
            if part not in node:
                raise MechanismFileError(file, key, f"'{part}' is not set in {here}: write it into the start "
                                                    f"file to calibrate it")
            container, index = node, part
        else:
            hint = f" (a point name: calibrate points.{node}.x / .z instead)" if isinstance(node, str) else ""
            raise MechanismFileError(file, key, f"{here} is {node!r}, it has no '{part}'{hint}")
        node = container[index]
    if isinstance(node, list) and len(node) == 2:
        raise MechanismFileError(file, key, f"'{key}' is an [x, z] pair: name one coordinate, {key}.x or {key}.z")
    return container, index


def parameter_value(mech: Mechanism, key: str) -> float:
    """Value (SI) of the parameter ``key`` (dotted, ``.x`` / ``.z`` for one coordinate) in ``mech``."""
    container, index = _locate(mech.raw, key, mech.file)
    value = container[index]
    try:
        if isinstance(value, bool):
            raise ValueError
        return float(value)
    except (TypeError, ValueError):
        raise MechanismFileError(mech.file, key, f"{value!r} is not a number: only numbers can be calibrated") from None


def with_parameters(mech: Mechanism, values: Mapping[str, float]) -> Mechanism:
    """Copy of ``mech`` with the parameters ``values`` (dotted key -> SI value) replaced, re-validated."""
    raw = copy.deepcopy(dict(mech.raw))
    for key, value in values.items():
        container, index = _locate(raw, key, mech.file)
        container[index] = float(value)
    return mechanism_from_dict(raw, file=mech.file)


@dataclass(frozen=True)
class Parameter:
    """A free parameter: dotted key, start value and bounds (SI units of the key)."""

    key: str
    start: float
    lower: float
    upper: float


def default_half_width(key: str, start: float) -> float:
    """Half-width of the default bound: coordinates 0.05 m, angle references 0.2 rad, else 50 % of |start|."""
    last = key.rsplit(".", 1)[-1]
    if last in ("x", "z"):
        return POINT_HALF_WIDTH
    if last == "reference":
        return ANGLE_HALF_WIDTH
    return RELATIVE_HALF_WIDTH * abs(start) if start != 0.0 else 1.0


def free_parameters(mech: Mechanism, keys: Sequence[str], half_widths: Mapping[str, float] | None = None
                    ) -> list[Parameter]:
    """The parameters ``keys`` with start values from ``mech`` and bounds start ± half-width."""
    half_widths = dict(half_widths or {})
    unknown = sorted(set(half_widths) - set(keys))
    if unknown:
        raise InputError(f"bound given for '{unknown[0]}', which is not a free parameter (free: {', '.join(keys)})")
    if len(set(keys)) != len(keys):
        raise InputError(f"free parameters listed twice: {', '.join(sorted(k for k in set(keys) if list(keys).count(k) > 1))}")
    out = []
    for key in keys:
        start = parameter_value(mech, key)
        half = half_widths.get(key, default_half_width(key, start))
        if not half > 0.0:
            raise InputError(f"bound of '{key}' is {half}: the half-width must be > 0 (SI units of the parameter)")
        out.append(Parameter(key, start, start - half, start + half))
    return out


# ---- data columns --------------------------------------------------------------------------
@dataclass(frozen=True)
class Column:
    """A measured data column: its header, what it measures (``kind``: length, angle, pressure,
    force) and how it is predicted (``source``: point_x, point_z, angle, pressure, force, hinge of ``ref``)."""

    name: str
    kind: str
    source: str
    ref: str


def measured_column(mech: Mechanism, name: str) -> Column:
    """Interpret one measured column header (see the module docstring); InputError if unknown."""
    prefix, sep, ref = name.partition(":")
    angle_names = [a.name for a in mech.measurements.angles]
    if not sep:
        if name in angle_names:
            return Column(name, "angle", "angle", name)
    elif prefix in ("x", "z") and ref in mech.points:
        return Column(name, "length", f"point_{prefix}", ref)
    elif prefix == "pressure" and ref in [p.name for p in mech.measurements.pressures]:
        return Column(name, "pressure", "pressure", ref)
    elif prefix == "force" and ref in [c.name for c in mech.cylinders]:
        return Column(name, "force", "force", ref)
    elif prefix == "hinge" and ref in [h.name for h in mech.hinges]:
        return Column(name, "force", "hinge", ref)
    raise InputError(
        f"data column '{name}' is not understood: expected a measured cylinder ({', '.join(mech.measurements.cylinders)}) "
        f"or angle sensor ({', '.join(angle_names) or 'none'}), x:POINT / z:POINT (points: {', '.join(mech.points)}), "
        f"pressure:SENSOR ({', '.join(p.name for p in mech.measurements.pressures) or 'none'}), "
        f"force:CYLINDER or hinge:HINGE")


def default_inputs(mech: Mechanism, names: Sequence[str]) -> list[str]:
    """The driving inputs among the data columns ``names``: the measured cylinders, plus the angle
    sensors if the cylinders alone leave the linkage free."""
    cylinders = [n for n in names if n in mech.measurements.cylinders]
    angles = [n for n in names if n in [a.name for a in mech.measurements.angles]]
    try:
        Solver(drive_mechanism(mech, cylinders))
        return cylinders
    except LinkageError:
        return cylinders + angles


def drive_mechanism(mech: Mechanism, inputs: Sequence[str]) -> Mechanism:
    """Copy of ``mech`` measuring only the driving ``inputs`` (cylinders, angle sensors) and no pressure,
    so that the statics take the implement load from ``implement.mass``."""
    raw = copy.deepcopy(dict(mech.raw))
    meas = raw.setdefault("measurements", {})
    meas["cylinders"] = [c for c in meas.get("cylinders") or [] if c in inputs]
    meas["angles"] = [a for a in meas.get("angles") or [] if a.get("name") in inputs]
    meas["pressures"] = []
    ref = dict(raw.get("reference_inputs") or {})
    ref["cylinders"] = {k: v for k, v in (ref.get("cylinders") or {}).items() if k in inputs}
    ref["angles"] = {k: v for k, v in (ref.get("angles") or {}).items() if k in inputs}
    ref.pop("pressures", None)
    raw["reference_inputs"] = ref
    return mechanism_from_dict(raw, file=f"{mech.file} (driven by {', '.join(inputs) or 'nothing'})")


def predict(mech: Mechanism, inputs: Mapping[str, np.ndarray], columns: Sequence[Column]) -> dict[str, np.ndarray]:
    """Predicted values of ``columns`` (m, rad, gauge Pa, N) at the driving ``inputs`` (N,) each; NaN where
    a pose does not solve. Pressure of one chamber: it carries the whole cylinder force, the other is at tank."""
    drive = drive_mechanism(mech, list(inputs))
    solver = Solver(drive)
    cylinders = {k: v for k, v in inputs.items() if k in drive.measurements.cylinders}
    angles = {k: v for k, v in inputs.items() if k not in cylinders}
    batch = solver.solve_batch(cylinders=cylinders, angles=angles)
    failed = batch.status >= Status.INPUT   # input, assembly or dead-centre error (lift-off still solves)
    readings = angle_readings(mech, batch)
    out = {}
    for col in columns:
        if col.source in ("point_x", "point_z"):
            value = batch.points[col.ref][:, 0 if col.source == "point_x" else 1]
        elif col.source == "angle":
            value = readings[col.ref]
        elif col.source == "pressure":  # F = count·(p_cap·A_cap − p_rod·A_rod) (schema, cylinders[])
            sensor = next(p for p in mech.measurements.pressures if p.name == col.ref)
            cyl = mech.cylinder(sensor.cylinder)
            force = batch.cylinder_force[cyl.name]
            value = (force / (cyl.count * cyl.cap_area) if sensor.chamber == "cap"
                     else -force / (cyl.count * cyl.rod_area))
        elif col.source == "force":
            value = batch.cylinder_force[col.ref]
        else:
            value = np.hypot(*batch.hinge_force[col.ref].T)
        out[col.name] = np.where(failed, np.nan, value)
    return out


# ---- the fit -------------------------------------------------------------------------------
@dataclass(frozen=True)
class FitResult:
    """Outcome of :func:`calibrate`.

    values, uncertainty: fitted value and 1-sigma uncertainty per parameter (SI units of its key;
    uncertainty = sqrt(diag((JᵀJ)⁻¹)·s²), s² = weighted residual sum of squares / (m − n), NaN
    if m ≤ n); undetermined: keys the data cannot determine (rank-deficient Jacobian or an
    uncertainty wider than the bound); rms_start / rms: RMS residual per measured column (its unit)
    at the start and fitted values; failed_poses: poses that do not solve with the fitted values.
    """

    parameters: list[Parameter]
    values: np.ndarray
    uncertainty: np.ndarray
    undetermined: list[str]
    inputs: list[str]
    columns: list[Column]
    rms_start: dict[str, float]
    rms: dict[str, float]
    n_poses: int
    failed_poses: int
    at_bound: list[str]
    message: str
    mechanism: Mechanism


def calibrate(start: Mechanism, data: Mapping[str, np.ndarray], free: Sequence[str],
              inputs: Sequence[str] | None = None, sigma: Mapping[str, float] | None = None,
              half_widths: Mapping[str, float] | None = None) -> FitResult:
    """Fit the parameters ``free`` (dotted keys) of ``start`` to the data columns (N,) each.

    inputs: the columns that drive the linkage (default :func:`default_inputs`); every other column
    is measured. sigma: column -> standard deviation (its unit; defaults ``DEFAULT_SIGMA`` by kind)
    weighting the residuals. half_widths: parameter -> bound half-width (``default_half_width``).
    """
    if not free:
        raise InputError("no free parameter: name at least one (e.g. points.P05.x, implement.mass)")
    arrays = {}
    n_poses = None
    for name, values in data.items():
        arr = np.asarray(values, dtype=float).ravel()
        if n_poses is not None and arr.size != n_poses:
            raise InputError(f"data column '{name}' has {arr.size} values, others have {n_poses}")
        n_poses = arr.size
        arrays[name] = arr
    inputs = list(inputs) if inputs is not None else default_inputs(start, list(arrays))
    missing = [n for n in inputs if n not in arrays]
    if missing:
        raise InputError(f"driving input '{missing[0]}' is not a data column (columns: {', '.join(arrays)})")
    columns = [measured_column(start, n) for n in arrays if n not in inputs]
    if not columns:
        raise InputError(f"the data hold only driving inputs ({', '.join(inputs)}): add a measured column")
    sigma = dict(sigma or {})
    for name, s in sigma.items():
        if name not in [c.name for c in columns]:
            raise InputError(f"sigma given for '{name}', which is not a measured column "
                             f"({', '.join(c.name for c in columns)})")
        if not s > 0.0:
            raise InputError(f"sigma of '{name}' is {s}: it must be > 0 (unit of the column)")
    weights = np.array([sigma.get(c.name, DEFAULT_SIGMA[c.kind]) for c in columns])
    params = free_parameters(start, list(free), half_widths)
    x0 = np.array([p.start for p in params])
    half = np.array([(p.upper - p.lower) / 2.0 for p in params])
    drive_in = {n: arrays[n] for n in inputs}
    measured = np.column_stack([arrays[c.name] for c in columns])  # (N, C)
    if not np.all(np.isfinite(measured)) or not all(np.all(np.isfinite(v)) for v in drive_in.values()):
        raise InputError("the data hold NaN or inf values: remove those rows")

    def mechanism_at(u: np.ndarray) -> Mechanism:
        return with_parameters(start, {p.key: float(v) for p, v in zip(params, x0 + half * u)})

    def residual_matrix(mech: Mechanism) -> np.ndarray:
        pred = predict(mech, drive_in, columns)
        return np.column_stack([pred[c.name] for c in columns]) - measured

    def weighted(u: np.ndarray) -> np.ndarray:
        r = residual_matrix(mechanism_at(u)) / weights
        return np.where(np.isfinite(r), r, FAILED_POSE_RESIDUAL).ravel()

    r0 = residual_matrix(start)
    if np.all(np.isnan(r0)):
        raise LinkageError("no pose of the data solves with the start mechanism: check the driving inputs' units "
                           "(m, rad) and that they are in the linkage's range")
    from scipy.optimize import least_squares   # here: `solve` uses drive_mechanism without the fit (0.6 s to import)

    sol = least_squares(weighted, np.zeros(len(params)), bounds=(-np.ones(len(params)), np.ones(len(params))),
                        x_scale=1.0, diff_step=1e-6, xtol=1e-12, ftol=1e-12, gtol=1e-12, max_nfev=200)
    fitted = mechanism_at(sol.x)
    r = residual_matrix(fitted)
    ok = np.all(np.isfinite(r), axis=1)
    uncertainty, undetermined = _uncertainty(sol.jac, sol.fun, half, [p.key for p in params])
    at_bound = [p.key for p, active in zip(params, sol.active_mask) if active != 0]
    rms = lambda res: {c.name: float(np.sqrt(np.nanmean(res[:, k] ** 2))) for k, c in enumerate(columns)}  # noqa: E731
    return FitResult(parameters=params, values=x0 + half * sol.x, uncertainty=uncertainty,
                     undetermined=undetermined, inputs=inputs, columns=columns, rms_start=rms(r0), rms=rms(r),
                     n_poses=int(n_poses or 0), failed_poses=int(np.sum(~ok)), at_bound=at_bound,
                     message=sol.message, mechanism=fitted)


def _uncertainty(jac: np.ndarray, fun: np.ndarray, half: np.ndarray, keys: list[str]) -> tuple[np.ndarray, list[str]]:
    """1-sigma uncertainty (SI) per parameter and the keys the data cannot determine.

    jac: Jacobian of the weighted residuals w.r.t. the normalized parameters u = (p − start)/half.
    """
    m, n = jac.shape
    s2 = float(fun @ fun) / (m - n) if m > n else float("nan")
    cov = np.linalg.pinv(jac.T @ jac) * s2
    uncertainty = half * np.sqrt(np.clip(np.diag(cov), 0.0, None))
    norms = np.linalg.norm(jac, axis=0)
    undetermined = {keys[i] for i in np.flatnonzero(norms == 0.0)}
    scaled = jac / np.where(norms > 0.0, norms, 1.0)
    _, sv, vt = np.linalg.svd(scaled, full_matrices=False)
    for k in np.flatnonzero(sv < RANK_TOL * sv[0]):
        undetermined |= {keys[i] for i in np.flatnonzero(np.abs(vt[k]) > NULL_SHARE)}
    undetermined |= {keys[i] for i in np.flatnonzero(uncertainty > half)}
    return uncertainty, [k for k in keys if k in undetermined]


def fitted_yaml(result: FitResult, start_file: str, data_file: str) -> str:
    """The fitted mechanism as YAML: the start description with the fitted values, and a header comment."""
    lines = [f"# Calibrated by `linkage-monitor calibrate` from {start_file} on {data_file}.",
             "# Written by yaml.safe_dump: the comments of the start file are lost (see it for sources).",
             f"# {result.n_poses} poses; driving inputs: {', '.join(result.inputs)}.",
             "# Fitted parameters (SI units): start -> fitted +- 1-sigma uncertainty"]
    for p, v, u in zip(result.parameters, result.values, result.uncertainty):
        flag = "  UNDETERMINED by the data" if p.key in result.undetermined else ""
        lines.append(f"#   {p.key}: {p.start:.6g} -> {v:.6g} +- {u:.2g}{flag}")
    lines.append("# RMS residual per measured column (its unit): start -> fitted")
    for c in result.columns:
        lines.append(f"#   {c.name}: {result.rms_start[c.name]:.4g} -> {result.rms[c.name]:.4g} {UNITS[c.kind]}")
    body = yaml.safe_dump(dict(result.mechanism.raw), sort_keys=False, allow_unicode=True, default_flow_style=None)
    return "\n".join(lines) + "\n" + body
