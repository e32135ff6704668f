"""The outputs an error budget covers, in a fixed order (``OutputTable``: hinge reactions fx, fz and
magnitude, cylinder forces, the implement load, axle loads, steerability ratio and margin (N or -),
lift capacities (N), the lift reserve (-)), their values as one row per pose, and their derivatives
with respect to a load (``LinearisedOutputs``: pressure, seal friction, implement mass), exact for the
outputs linear in the loads and by the chain rule for the others.
Units SI (N, Pa, kg); frame x forward, z up, origin at the rear wheels' ground contact.
"""

from __future__ import annotations

import numpy as np

from . import kernels
from .budget import Output
from .machine import STEERABILITY_KEYS, MachineModel, MachineResult
from .model import Mechanism
from .results import Result


class OutputTable:
    """The outputs of a ``MachineModel``'s poses, in a fixed order, and their values as one row."""

    def __init__(self, model: MachineModel) -> None:
        names = model.solver.names
        hinges, cylinders = [h for h, _, _ in names.hinges], list(names.cylinders)
        outputs = [*(Output(f"{h}.fx", "hinge_fx", "N") for h in hinges),
                   *(Output(f"{h}.fz", "hinge_fz", "N") for h in hinges),
                   *(Output(f"{h}.magnitude", "hinge_magnitude", "N") for h in hinges),
                   *(Output(f"{c}.force", "cylinder_force", "N") for c in cylinders),
                   Output("implement_load", "implement_load", "N")]
        self.steerability = model.has_steerability
        if self.steerability:
            outputs += [Output("front_axle_load", "axle_load", "N"), Output("rear_axle_load", "axle_load", "N"),
                        Output("steerability_ratio", "steerability_ratio", "-"),
                        Output("steerability_margin", "steerability_margin", "-")]
        self.capacity_points = tuple(k for k in model.capacity_keys if k != "reserve")
        outputs += [Output(f"lift_capacity.{k}", "lift_capacity", "N") for k in self.capacity_points]
        if model.has_capacity:
            outputs.append(Output("lift_reserve", "lift_reserve", "-"))
        self.outputs: tuple[Output, ...] = tuple(outputs)
        self.index = {o.name: k for k, o in enumerate(self.outputs)}   # output name -> its column
        self.n_hinges, self.n_cylinders = len(hinges), len(cylinders)
        # the steerability row's columns of the axle loads, the ratio and the margin (none without them)
        self.steer_columns = np.array([STEERABILITY_KEYS.index(k) for k in ("front_axle_load", "rear_axle_load",
                                                                             "ratio", "margin")]
                                      if self.steerability else [], dtype=np.int64)
        tractor = model.mech.tractor
        h, c = self.n_hinges, self.n_cylinders
        load = 3 * h + c
        steer = load + 1
        capacity = load + 1 + 4 * self.steerability
        cg = capacity + self.capacity_points.index("implement_cg") if "implement_cg" in self.capacity_points else -1
        self.layout = kernels.OutputLayout(
            fx=0, fz=h, magnitude=2 * h, n_hinges=h, load=load, steer=self.steerability, front=steer,
            rear=steer + 1, ratio=steer + 2, margin=steer + 3,
            unit_reference=tractor is not None and tractor.steerability_reference == "unit",
            tractor_weight=tractor.mass * model.mech.gravity if tractor is not None else 1.0,
            capacity_cg=cg, reserve=len(self.outputs) - 1 if cg >= 0 else -1)
        # the outputs of a weak inference's pole (``POLE_REACH_MAX``): all the statics infer, not a cylinder's force
        self.of_the_pole = np.ones(len(self.outputs), dtype=bool)
        self.of_the_pole[3 * h:3 * h + c] = False
        # the outputs not linear in the loads (``kernels.chain_rule`` gives their derivatives)
        self.nonlinear = np.zeros(len(self.outputs), dtype=bool)
        self.nonlinear[2 * h:3 * h] = True
        if self.steerability:
            self.nonlinear[[steer + 2, steer + 3]] = True
        if cg >= 0:
            self.nonlinear[-1] = True

    def values(self, result: Result, machine: MachineResult) -> np.ndarray:
        """The outputs of one solved pose, a row (n_out,) in the order of ``outputs``."""
        return self.rows(result.hinge_force[None], result.cylinder_values[None, :, 1],
                         np.array([result.implement_load]), machine.steerability_row[None],
                         machine.capacity_row[None])[0]

    def rows(self, hinge_force: np.ndarray, cylinder_force: np.ndarray, implement_load: np.ndarray,
             steerability: np.ndarray, capacity: np.ndarray) -> np.ndarray:
        """The outputs of N poses (N, n_out): hinge forces (N, H, 2) N, cylinder forces (N, C) N,
        implement loads (N,) N, steerability rows (N, STEERABILITY_KEYS) and capacity rows (N, P + 1)
        (``kernels.output_rows``)."""
        out = np.empty((len(implement_load), len(self.outputs)))
        kernels.output_rows(np.ascontiguousarray(hinge_force), np.ascontiguousarray(cylinder_force),
                            np.asarray(implement_load, dtype=float), steerability, capacity, self.steer_columns, out)
        return out


class LinearisedOutputs:
    """The derivative of every output with respect to a load (pressure, friction, implement mass)
    from two solves at the same pose: exact for the outputs linear in the loads, the chain rule
    for the others (``kernels.chain_rule``)."""

    def __init__(self, table: OutputTable) -> None:
        self.layout = table.layout

    def derivative(self, y0: np.ndarray, y1: np.ndarray, step: float) -> np.ndarray:
        """∂y/∂x (n_out,) from y0 = y(x) and y1 = y(x + step) at one pose; of several loads at once with
        y1 (L, n_out), a row each: (L, n_out)."""
        with np.errstate(invalid="ignore"):   # an infinite reserve (no load) has no derivative
            return self.chain(y0, (y1 - y0) / step)

    def chain(self, y0: np.ndarray, d: np.ndarray) -> np.ndarray:
        """``d`` (n_out,) or (R, n_out), derivatives whose outputs linear in the loads are right, with the
        others (hinge magnitude, steerability ratio and margin, lift reserve) by the chain rule at ``y0``
        (in place; ``kernels.chain_rule``)."""
        kernels.chain_rule(np.atleast_2d(d), y0, self.layout)
        return d


def force_per_pressure(mech: Mechanism, sensor: str) -> float:
    """N of cylinder force per Pa of the pressure sensor ``sensor``: count·A_cap for a cap chamber,
    −count·A_rod for a rod chamber (F = count·(p_cap·A_cap − p_rod·A_rod))."""
    ps = next(p for p in mech.measurements.pressures if p.name == sensor)
    cyl = mech.cylinder(ps.cylinder)
    return cyl.count * (cyl.cap_area if ps.chamber == "cap" else -cyl.rod_area)
