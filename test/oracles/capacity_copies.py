"""Oracle for lift capacity: one mechanism copy per capacity point, solved as a mechanism of its own
by the frozen numpy solver (oracles.numpy_solver). The copy's implement load acts at the point, the
lift cylinder's cap pressure is "measured" at p_max·η (rod chamber at 0 gauge), loads and ground
contacts are removed; the solver's implement-load estimate in the copy is the vertical load (N) the
cylinder holds there (Popov 2009: G = p_max·η·A / I, by the equilibrium of every body). The package
computes the same by virtual work (mechanics.kernels.lift_capacity). SI units.
"""

from __future__ import annotations

import copy

import numpy as np

from linkage_monitor.mechanics import Mechanism
from linkage_monitor.mechanics.capacity import capacity_points, lift_cylinder, relief_pressure
from linkage_monitor.mechanics.model import Cylinder
from linkage_monitor.mechanics.schema import mechanism_from_dict

from .numpy_solver import Solver

CAPACITY_SENSOR = "capacity_cap_pressure"


def capacity_mechanism(mech: Mechanism, cyl: Cylinder, point: np.ndarray) -> Mechanism:
    """Copy of ``mech`` for lift capacity at ``point`` ([x, z] m, reference pose, on the implement).

    The implement load acts at ``point``; the only pressure sensor is the lift cylinder's cap at
    p_max·η (``CAPACITY_SENSOR``, rod chamber at 0 gauge); extra loads and ground contacts are
    removed (capacity is a transport-pose rating, ISO 730). Measured lengths and angles are kept.
    """
    raw = copy.deepcopy(dict(mech.raw))
    raw["implement"]["cg"] = [float(point[0]), float(point[1])]
    raw.pop("loads", None)
    raw.pop("contacts", None)
    meas = raw.setdefault("measurements", {})
    meas["pressures"] = [{"name": CAPACITY_SENSOR, "cylinder": cyl.name, "chamber": "cap"}]
    ref = raw.setdefault("reference_inputs", {}) or {}
    ref["pressures"] = {CAPACITY_SENSOR: relief_pressure(cyl) * cyl.efficiency}
    raw["reference_inputs"] = ref
    return mechanism_from_dict(raw, file=f"{mech.file} (lift capacity copy)")


def capacity_copies(mech: Mechanism) -> dict[str, tuple[Solver, dict[str, float]]]:
    """Per capacity point: the copy's solver and the pressure to give it (Pa gauge: p_max·η)."""
    cyl = lift_cylinder(mech)
    return {name: (Solver(capacity_mechanism(mech, cyl, point)), {CAPACITY_SENSOR: relief_pressure(cyl) * cyl.efficiency})
            for name, point in capacity_points(mech).items()}
