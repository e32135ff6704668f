"""Sensor readings of the belarus_1221 hitch that agree with each other, for tests that publish
joint states to a live node."""

from __future__ import annotations

import numpy as np

from linkage_monitor.mechanics import Solver, load_preset
from linkage_monitor.mechanics.capacity import stroke_mechanism


def lift_pose(stroke: float) -> tuple[float, float]:
    """A consistent (stroke m, lift-arm angle rad) pair from the offline kinematics."""
    mech = load_preset("belarus_1221")
    batch = Solver(stroke_mechanism(mech)).solve_batch(cylinders={"lift_cylinder": np.array([stroke])})
    sensor = mech.measurements.angles[0]
    hinge = next(h for h in mech.hinges if h.name == sensor.hinge)
    theta = lambda body: batch.body_poses[body][0, 2] if body in batch.body_poses else 0.0  # noqa: E731
    return stroke, sensor.reference + theta(hinge.bodies[1]) - theta(hinge.bodies[0])
