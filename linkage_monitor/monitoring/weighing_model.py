"""What the lift cylinder's force says about the implement: a table over the stroke (no rclpy).

By virtual work, at a pose of a hitch with one degree of freedom the lift cylinder's force is
affine in the implement's weight W and in where its line of action lies. A vertical load W at a
point of the implement body costs the cylinder W·(dz/ds) (z the point's height, s the cylinder's
length), and dz/ds of a point of a rigid body is affine in the point's horizontal position, which
is affine in the point's offset (dx, dz) from the file's cg in the implement's own frame
(reference-pose coordinates, turning with the body). So, per pose,

    F(s) = F_link(s) + W·u0(s) + (W·dx)·ux(s) + (W·dz)·uz(s)

with F_link the force the linkage's own bodies and the file's other loads need (implement
weightless), u0 the force per newton of implement weight at the file's cg, ux and uz its change
per metre of cg offset along the implement's x and z. dz enters through the implement's pitch
only: it is identifiable where the implement turns over the stroke, x where the lift moves it.
The columns come from the solver itself (four solves of the stroke grid: implement weightless,
at the cg, at the cg moved by OFFSET along x and along z), not from a second formulation.

Other measured cylinders are held at their reference lengths, as in the simulator. Units SI;
frame x forward, z up, origin at the rear wheels' ground contact.
"""

from __future__ import annotations

import copy
import math
from typing import NamedTuple

import numpy as np

from linkage_monitor.mechanics import Mechanism, Solver, UnobservableError, mechanism_from_dict
from linkage_monitor.mechanics.capacity import interval_around, reference_length, stroke_mechanism
from linkage_monitor.mechanics.results import Status

GRID_POINTS = 401      # lengths of the table over the assemblable stroke
OFFSET = 0.5           # m, the cg offset of the two solves that give ux and uz
UNIT_MASS = 1000.0     # kg, the implement mass of the solves (everything is linear in it)


class ForceColumns(NamedTuple):
    """The lift cylinder's force model at one length (N, N/N, N/(N·m)): F = link + W·u0 + W·dx·ux + W·dz·uz;
    ``cg_height`` (m) of the file's cg at that length."""

    link: float
    u0: float
    ux: float
    uz: float
    cg_height: float


class WeighingModel:
    """The force model of ``mechanism``'s lift cylinder tabulated over its stroke.

    ``cylinder``: the first measured cylinder with a pressure sensor (the one the weighing reads);
    ``low``/``high``: its assemblable lengths (m) around the reference; ``reference_cg``: the
    file's implement cg (m, reference pose). ``lifting_sign``: +1 when extending the cylinder
    lifts the implement, -1 when retracting does.
    """

    def __init__(self, mechanism: Mechanism) -> None:
        implement = mechanism.implement
        if implement is None:
            raise ValueError(f"{mechanism.file}: weighing needs an 'implement' block (the body it weighs)")
        meas = mechanism.measurements
        gauged = [p.cylinder for p in meas.pressures]
        driver = next((c for c in meas.cylinders if c in gauged), None)
        if driver is None:
            raise ValueError(f"{mechanism.file}: weighing needs a measured cylinder length with a pressure sensor "
                             f"(measurements.cylinders and measurements.pressures)")
        self.cylinder = driver
        self.gravity = mechanism.gravity
        self.reference_cg = np.asarray(implement.cg, dtype=float).copy()
        try:
            raw = copy.deepcopy(dict(stroke_mechanism(mechanism).raw))
        except UnobservableError as exc:
            raise ValueError(f"weighing tabulates the stroke by the measured cylinder lengths: {exc}") from exc
        given = mechanism.reference_inputs.get("cylinders", {})
        held = {c: float(given.get(c, reference_length(mechanism, c))) for c in meas.cylinders}
        self.reference_length = held[driver]
        grid = np.linspace(0.5 * self.reference_length, 1.5 * self.reference_length, GRID_POINTS)
        forces = []
        cg = self.reference_cg
        variants = ((0.0, cg), (UNIT_MASS, cg), (UNIT_MASS, cg + (OFFSET, 0.0)), (UNIT_MASS, cg + (0.0, OFFSET)))
        for mass, where in variants:
            raw["implement"]["mass"] = mass
            raw["implement"]["cg"] = [float(where[0]), float(where[1])]
            solver = Solver(mechanism_from_dict(copy.deepcopy(raw), mechanism.file))
            batch = solver.solve_batch(cylinders={c: grid if c == driver else np.full(grid.shape, v)
                                                  for c, v in held.items()})
            forces.append((batch.cylinder_force[driver], batch.status == Status.OK, batch.implement_cg[:, 1]))
        ok = np.logical_and.reduce([f[1] for f in forces])
        stroke = interval_around(grid, ok, self.reference_length)
        if stroke is None:
            raise ValueError(f"{mechanism.file}: cylinder '{driver}' does not assemble at its reference length")
        self.low, self.high = stroke
        keep = (grid >= self.low) & (grid <= self.high)
        weight = UNIT_MASS * self.gravity
        self.lengths = grid[keep]
        link, at_cg, along_x, along_z = (f[0][keep] for f in forces)
        self.link = link
        self.u0 = (at_cg - link) / weight
        self.ux = (along_x - at_cg) / (weight * OFFSET)
        self.uz = (along_z - at_cg) / (weight * OFFSET)
        self.cg_height = forces[1][2][keep]
        rise = float(np.sign(self.cg_height[-1] - self.cg_height[0]))
        self.lifting_sign = int(rise) if rise != 0.0 else 1
        self._step = float(self.lengths[1] - self.lengths[0])
        self._rows = list(zip(self.link.tolist(), self.u0.tolist(), self.ux.tolist(), self.uz.tolist(),
                              self.cg_height.tolist()))

    def contact_edge(self, share: float) -> float:
        """The driver's length (m) ``share`` of the stroke from the reference (working) length toward
        lifting: up to it the implement may rest on the ground (``grounded``)."""
        return self.reference_length + self.lifting_sign * share * (self.high - self.low)

    def grounded(self, length: float, edge: float) -> bool:
        """The driver at ``length`` (m) short of ``edge`` (``contact_edge``): the ground may carry part of the load."""
        return (length - edge) * self.lifting_sign < 0.0

    def at(self, length: float) -> ForceColumns | None:
        """The force model at cylinder ``length`` (m), linear between grid lengths; None off the stroke."""
        where = (length - self.low) / self._step
        if not (-1e-9 <= where <= len(self._rows) - 1 + 1e-9) or math.isnan(where):
            return None
        i = min(max(int(where), 0), len(self._rows) - 2)
        t = where - i
        a, b = self._rows[i], self._rows[i + 1]
        return ForceColumns(a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1]), a[2] + t * (b[2] - a[2]),
                            a[3] + t * (b[3] - a[3]), a[4] + t * (b[4] - a[4]))
