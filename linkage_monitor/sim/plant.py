"""The simulator's plant: the kinematics and statics of the driven mechanism (cylinder lengths ->
angle readings, implement cg, cylinder forces, the forces on the frame), the driving cylinder's
stroke, and the chamber pressures that carry a cylinder force. SI units (m, rad, N, Pa gauge).
"""

from __future__ import annotations

import copy
import math
from dataclasses import dataclass

import numpy as np

from linkage_monitor.mechanics import LinkageError, Mechanism, Solver, UnobservableError, mechanism_from_dict
from linkage_monitor.mechanics.capacity import interval_around, reference_length, stroke_mechanism
from linkage_monitor.mechanics.machine import steerability
from linkage_monitor.mechanics.model import PressureSensor
from linkage_monitor.mechanics.results import Status, angle_readings

from .stream import Stroke

TRANSPORT_FRACTION = 0.6  # transport length = work + this share of the assemblable stroke above work
_UNIT_MASS = 1000.0       # kg, implement mass of the second statics solve (the load is linear in it)


@dataclass(frozen=True)
class Poses:
    """Per sample: angle-sensor values (N, A) rad, implement cg (N, 2) m, cylinder forces (N,) N by name,
    and the forces the linkage puts on the frame: points (N, K, 2) m, forces (N, K, 2) N."""

    angles: np.ndarray
    implement_cg: np.ndarray
    cylinder_force: dict[str, np.ndarray]
    frame_load_points: np.ndarray
    frame_load_forces: np.ndarray

    def steerability_margin(self, mech: Mechanism, load: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(k − ratio_min, largest steerable implement load N) per sample (Popov 2009, via mechanics.machine)."""
        assert mech.tractor is not None   # the callers check: only mechanisms with a tractor block
        steer = steerability(mech.tractor, mech.gravity, self.frame_load_points, self.frame_load_forces,
                             np.broadcast_to(load, self.implement_cg[:, 0].shape), self.implement_cg[:, 0])
        return steer["margin"], steer["max_implement_mass"] * mech.gravity


class Plant:
    """Forward model: cylinder lengths -> angles, implement cg, cylinder forces (affine in the load)."""

    def __init__(self, mech: Mechanism) -> None:
        if mech.implement is None:
            raise ValueError(f"{mech.file}: the simulator needs an 'implement' block (its load is what it varies)")
        meas = mech.measurements
        if not meas.cylinders:
            raise ValueError(f"{mech.file}: the simulator drives the linkage by a measured cylinder length, "
                             f"but measurements.cylinders is empty")
        gauged = [p.cylinder for p in meas.pressures]
        self.driver = next((c for c in meas.cylinders if c in gauged), meas.cylinders[0])
        self.mech = mech
        try:
            raw = copy.deepcopy(dict(stroke_mechanism(mech).raw))   # lengths only: the angles follow from them
        except UnobservableError as exc:
            raise ValueError(f"the simulator drives the linkage by its measured cylinder lengths: {exc}") from exc
        self._solvers = []
        for mass in (0.0, _UNIT_MASS):   # two implement loads: the statics is linear in the load
            raw["implement"]["mass"] = mass
            self._solvers.append(Solver(mechanism_from_dict(copy.deepcopy(raw), mech.file)))
        given = mech.reference_inputs.get("cylinders", {})
        self.reference_length = {c: float(given.get(c, reference_length(mech, c))) for c in meas.cylinders}

    def lengths(self, driver: np.ndarray) -> dict[str, np.ndarray]:
        """All measured cylinder lengths (m): the driver's, the others at their reference length."""
        return {c: driver if c == self.driver else np.full(driver.shape, self.reference_length[c])
                for c in self.mech.measurements.cylinders}

    def poses(self, driver: np.ndarray, load: np.ndarray) -> Poses:
        """Angles, implement cg and cylinder forces for driver lengths (m) and implement loads (N), per sample.

        Each distinct length is solved once. The statics is linear in the implement load:
        F = F(0) + (F(m₁·g) − F(0))·load/(m₁·g), from two solves with implement mass 0 and m₁.
        """
        lengths, inverse = np.unique(driver, return_inverse=True)
        empty, unit = (s.solve_batch(cylinders=self.lengths(lengths)) for s in self._solvers)
        bad = np.flatnonzero(empty.status != 0)
        if bad.size:
            raise LinkageError(f"{self.mech.file}: {empty.messages[bad[0]]}")
        readings = angle_readings(self.mech, empty)
        angles = np.array([readings[a.name][inverse] for a in self.mech.measurements.angles]
                          ).T.reshape(len(driver), len(self.mech.measurements.angles))
        share = load / (_UNIT_MASS * self.mech.gravity)
        forces = {c.name: empty.cylinder_force[c.name][inverse]
                  + share * (unit.cylinder_force[c.name] - empty.cylinder_force[c.name])[inverse]
                  for c in self.mech.cylinders}
        frame = (empty.frame_load_forces[inverse]
                 + share[:, None, None] * (unit.frame_load_forces - empty.frame_load_forces)[inverse])
        return Poses(angles=angles, implement_cg=empty.implement_cg[inverse], cylinder_force=forces,
                      frame_load_points=empty.frame_load_points[inverse], frame_load_forces=frame)

    def relief_load(self, driver_length: float) -> float:
        """Implement load (N) at which the driver's cap pressure reaches its relief pressure (inf if none)."""
        cyl = self.mech.cylinder(self.driver)
        if cyl.relief_pressure is None:
            return math.inf
        f0, f1 = self.poses(np.full(2, driver_length), np.array([0.0, 1.0])).cylinder_force[cyl.name]
        return (cyl.relief_pressure * cyl.count * cyl.cap_area - f0) / (f1 - f0) if f1 > f0 else math.inf

    def stroke(self, points: int = 601) -> Stroke:
        """Assemblable range of the driver (grid over ±50 % of its reference length), work, transport."""
        work = float(self.reference_length[self.driver])
        grid = np.linspace(0.5 * work, 1.5 * work, points)
        ok = self._solvers[0].solve_batch(cylinders=self.lengths(grid)).status == Status.OK
        stroke = interval_around(grid, ok, work)
        if stroke is None:
            raise ValueError(f"{self.mech.file}: cylinder '{self.driver}' does not assemble at its reference "
                             f"length {work:.4f} m: check reference_inputs")
        low, high = stroke
        return Stroke(cylinder=self.driver, low=low, high=high, work=work,
                      transport=work + TRANSPORT_FRACTION * (high - work))



def chamber_pressure(mech: Mechanism, sensor: PressureSensor, force: np.ndarray) -> np.ndarray:
    """Gauge pressure (Pa) of ``sensor``'s chamber for the cylinder force (N, + = pushing).

    F = count·(p_cap·A_cap − p_rod·A_rod) (schema). Both chambers measured: the pushed side
    carries the force, the other is at 0 gauge (tank). One chamber measured: it carries all
    of F (a cap chamber's pressure is negative gauge if the cylinder pulls).
    """
    cyl = mech.cylinder(sensor.cylinder)
    chambers = {p.chamber for p in mech.measurements.pressures if p.cylinder == cyl.name}
    both = len(chambers) == 2
    if sensor.chamber == "cap":
        return (np.maximum(force, 0.0) if both else force) / (cyl.count * cyl.cap_area)
    return (np.maximum(-force, 0.0) if both else -force) / (cyl.count * cyl.rod_area)
