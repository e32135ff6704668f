"""Lift capacity inputs (Popov 2009: G = p_max·η·A / I): the lift cylinder, its largest force, the
points where capacity is reported; and the stroke-only copy of a mechanism for stroke sweeps.
SI units; frame x forward, z up, origin at the rear wheels' ground contact B.
"""

from __future__ import annotations

import copy

import numpy as np

from .errors import MechanismFileError, UnobservableError
from .model import Cylinder, Mechanism
from .schema import mechanism_from_dict
from .solver import Solver

BEHIND_DISTANCE = 0.610  # m, ISO 730 / Popov 2009: "610 mm behind the hitch axis"


def lift_cylinder(mech: Mechanism, name: str | None = None) -> Cylinder:
    """The cylinder that lifts the implement: ``name``, else the first with a ``relief_pressure``."""
    if name is not None:
        if name not in [c.name for c in mech.cylinders]:
            raise MechanismFileError(mech.file, "cylinders", f"lift cylinder '{name}' is not defined "
                                     f"(cylinders: {', '.join(c.name for c in mech.cylinders) or 'none'})")
        cyl = mech.cylinder(name)
    else:
        found = next((c for c in mech.cylinders if c.relief_pressure is not None), None)
        if found is None:
            raise MechanismFileError(mech.file, "cylinders", "no cylinder has a 'relief_pressure': set it "
                                     "(Pa) on the lift cylinder to compute lift capacity")
        cyl = found
    if cyl.relief_pressure is None:
        raise MechanismFileError(mech.file, f"cylinders.{cyl.name}.relief_pressure",
                                 "required for lift capacity (Pa, the relief valve setting p_max)")
    return cyl


def reference_length(mech: Mechanism, cylinder: str) -> float:
    """Pin-to-pin length (m) of ``cylinder`` in the reference pose."""
    cyl = mech.cylinder(cylinder)
    return float(np.hypot(*(np.asarray(mech.points[cyl.rod_end.point]) - np.asarray(mech.points[cyl.base.point]))))


def capacity_force(cyl: Cylinder) -> float:
    """Largest pushing force of the lift cylinder(s), N: count·p_max·η·A_cap (Popov 2009, G·I = p_max·η·A)."""
    return cyl.count * relief_pressure(cyl) * cyl.efficiency * cyl.cap_area


def relief_pressure(cyl: Cylinder) -> float:
    """The cylinder's relief pressure p_max (Pa); MechanismFileError naming the key if the file has none."""
    if cyl.relief_pressure is None:
        raise MechanismFileError("", f"cylinders.{cyl.name}.relief_pressure",
                                 "required for lift capacity (Pa, the relief valve setting p_max)")
    return cyl.relief_pressure


def capacity_points(mech: Mechanism, distance: float = BEHIND_DISTANCE) -> dict[str, np.ndarray]:
    """Reference-pose [x, z] (m) of the points where capacity is reported, fixed on the implement.

    ``hitch_axis`` = implement.hitch_point; ``behind_610mm`` = ``distance`` from the hitch point,
    perpendicular to the mast line hitch_point → mast_point, on the side away from the tractor
    frame (ISO 730 measures it with the mast vertical: then it is horizontally behind the axis);
    ``implement_cg`` = implement.cg. Missing hitch/mast points leave their entries out.
    """
    imp = mech.implement
    if imp is None:
        raise MechanismFileError(mech.file, "implement", "required for lift capacity (body, mass, cg)")
    out: dict[str, np.ndarray] = {}
    if imp.hitch_point is not None:
        hitch = np.asarray(mech.points[imp.hitch_point], dtype=float)
        out["hitch_axis"] = hitch
        if imp.mast_point is not None:
            mast = np.asarray(mech.points[imp.mast_point], dtype=float) - hitch
            normal = np.array([-mast[1], mast[0]]) / np.hypot(*mast)
            frame_centre = np.mean([mech.points[p] for p in mech.ground.points], axis=0)
            if np.dot(normal, hitch - frame_centre) < 0.0:
                normal = -normal
            out["behind_610mm"] = hitch + distance * normal
    out["implement_cg"] = np.asarray(imp.cg, dtype=float)
    return out


def stroke_mechanism(mech: Mechanism) -> Mechanism:
    """Copy of ``mech`` driven by its measured cylinder lengths only (angle and pressure sensors dropped).

    For sweeping a cylinder over its stroke; UnobservableError if the cylinder lengths alone do
    not close the linkage's degrees of freedom.
    """
    raw = copy.deepcopy(dict(mech.raw))
    meas = raw.setdefault("measurements", {})
    meas["angles"], meas["pressures"] = [], []
    ref = raw.get("reference_inputs") or {}
    ref.pop("angles", None)
    ref.pop("pressures", None)
    raw["reference_inputs"] = ref
    stroke = mechanism_from_dict(raw, file=mech.file)
    try:
        Solver(stroke)
    except UnobservableError as exc:
        raise UnobservableError(f"{mech.file}: the measured cylinder lengths alone do not fix the pose, so "
                                f"the stroke cannot be swept ({exc})") from exc
    return stroke


def interval_around(grid: np.ndarray, ok: np.ndarray, centre: float) -> tuple[float, float] | None:
    """The widest run of ``ok`` grid values (e.g. cylinder lengths, m) that contains the grid
    point nearest ``centre``; None if that point itself is not ok."""
    i = int(np.argmin(np.abs(grid - centre)))
    if not ok[i]:
        return None
    lo, hi = i, i
    while lo > 0 and ok[lo - 1]:
        lo -= 1
    while hi < len(ok) - 1 and ok[hi + 1]:
        hi += 1
    return float(grid[lo]), float(grid[hi])
