"""A run's true geometry: the mechanism's points where they really are, drawn once per run from their
declared tolerances (``error_sources.points``, normal, σ per coordinate), and the true inputs read off
that linkage (no rclpy).

The simulated stream's driving input (the length or angle that moves the linkage alone) is held: it is
what the linkage was driven to. The other measured lengths and angles are those the true linkage shows
there (a redundant sensor reads the true linkage, not the file's); the pressures carry the loads as
they are. The truth is the true mechanism solved from these inputs; the monitor solves the file's.
Units SI (m, rad, gauge Pa).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from linkage_monitor.mechanics import Mechanism, Solver
from linkage_monitor.mechanics.error_sources import ErrorSources
from linkage_monitor.mechanics.geometry_budget import moved_point, readings_along
from linkage_monitor.mechanics.machine import MachineModel

from .sensor_errors import TrueInputs


@dataclass(frozen=True)
class TrueGeometry:
    """One run's true ``mechanism`` (its points moved by ``offsets``: (point, axis 0 = x or 1 = z) -> m)
    and its ``model`` (the truth's solver, as the monitor's is built)."""

    mechanism: Mechanism
    offsets: dict[tuple[str, int], float]
    model: MachineModel


def draw_geometry(mech: Mechanism, sources: ErrorSources, rng: np.random.Generator, solver: Solver
                  ) -> TrueGeometry | None:
    """The true geometry of one run (None when no point has a tolerance); ``solver`` the monitor's (its
    settings are the truth model's)."""
    coordinates = sources.point_coordinates(mech.points)
    if not coordinates:
        return None
    offsets = {(point, axis): float(u * rng.standard_normal()) for point, axis, u in coordinates}
    true = mech
    for (point, axis), offset in offsets.items():
        true = moved_point(true, point, axis, offset)
    return TrueGeometry(true, offsets, MachineModel(true, Solver(
        true, dead_centre_cond=solver.dead_centre_cond, consistency_tol=solver.consistency_tol,
        dead_centre_transmission_deg=solver.dead_centre_transmission_deg)))


def read_on(geometry: TrueGeometry, truth: TrueInputs, driving: str, kind: str) -> TrueInputs:
    """``truth`` with its measured lengths and angles other than the ``driving`` input (of ``kind``) read
    off the true linkage at the driving input's values (NaN where the true linkage does not assemble)."""
    values = truth.values[kind][driving]
    ok, read = readings_along(geometry.mechanism, kind, driving, values)
    columns = {k: dict(group) for k, group in truth.values.items()}
    for group in ("cylinders", "angles"):
        for name in columns.get(group, {}):
            columns[group][name] = np.where(ok, read[group][name], np.nan)
    return TrueInputs(columns, truth.last_motion)

