"""First-order propagation of the declared error sources (``error_sources``) to every published
output of a solved pose: its standard uncertainty (1 sigma, the output's unit) and each source's share.

Outputs (``OutputTable``): hinge reactions (fx, fz, magnitude, N), cylinder forces (N), the implement
load (N), axle loads (N), steerability ratio and margin (-), lift capacities (N) and the lift reserve
(-). Sources (``Source``): each measured input's bias, noise and resolution, each force-measured
cylinder's seal friction, the implement's mass.

Derivatives, through the same compiled solve as the pose (``MachineModel.solve``):
- loads (pressures, seal friction, implement mass) do not move the pose, and at a fixed pose the
  statics, the implement load and the axle loads are linear in them: the derivative is exact from
  one more solve (``(y(x + Δ) − y(x)) / Δ`` of a linear function), and the outputs that are not
  linear (hinge magnitude, steerability ratio and margin, lift reserve) follow from those by the
  chain rule (``_LinearisedOutputs``);
- cylinder lengths and angles move the pose along the linkage's degrees of freedom: a central
  difference of step ``pose_step`` (truncation error O(h²), held by test/test_uncertainty.py to a
  Richardson estimate).
u_y² = Σ_s (∂y/∂s · u_s)² (the sources independent); the share of s is (∂y/∂s · u_s)² / u_y².
Units SI (m, rad, Pa, N, kg); frame x forward, z up, origin at the rear wheels' ground contact.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from functools import cached_property
from typing import Mapping

import numpy as np

from .error_sources import ErrorSources, Motion
from .errors import LinkageError
from .inputs import Inputs
from .machine import STEERABILITY_KEYS, MachineModel, MachineResult
from .model import Mechanism
from .overrides import apply_overrides
from .results import Result
from .solver import Solver

LOAD_STEP_PRESSURE = 1.0e5   # Pa: the pressure step of a load derivative (any step: the outputs are linear)
LOAD_STEP_MASS = 100.0       # kg: the implement-mass step of a load derivative (likewise)
POSE_STEP_SHARE = 0.25       # the central difference's step, as a share of the input's standard uncertainty
POSE_STEP_MIN, POSE_STEP_MAX = 1e-6, 1e-3   # m or rad: its bounds (Newton's 1e-13 below, the curvature above)


@dataclass(frozen=True)
class Output:
    """One published number: ``name`` (``P03.fx``, ``lift_cylinder.force``, ``implement_load``,
    ``front_axle_load``, ``steerability_ratio``, ``lift_capacity.hitch_axis``, ``lift_reserve``...),
    ``kind`` (``hinge_fx``, ``hinge_fz``, ``hinge_magnitude``, ``cylinder_force``, ``implement_load``,
    ``axle_load``, ``steerability_ratio``, ``steerability_margin``, ``lift_capacity``,
    ``lift_reserve``) and ``unit`` (``N`` or ``-``)."""

    name: str
    kind: str
    unit: str


@dataclass(frozen=True)
class Source:
    """One declared error source at a pose: ``name`` (``lift_cap_pressure bias``, ``lift_cylinder seal
    friction``, ``implement mass``), the ``input`` it belongs to (a measurement, a cylinder or
    ``implement``), its ``part`` (``bias``, ``noise``, ``resolution``, ``friction``, ``mass``), its
    standard uncertainty ``u`` and ``unit`` (m, rad, Pa, N, kg)."""

    name: str
    input: str
    part: str
    u: float
    unit: str


@dataclass(frozen=True)
class OutputUncertainty:
    """One output's line of a budget: its value and standard uncertainty ``u`` (both in the output's
    unit; u NaN where a derivative could not be taken: the interval is unbounded) and each source's
    share of u² (source name -> 0..1, summing to 1 where u > 0)."""

    output: Output
    value: float
    u: float
    shares: Mapping[str, float]

    @property
    def dominant(self) -> str:
        """The name of the source with the largest share ("" when u is 0 or NaN)."""
        positive = {name: share for name, share in self.shares.items() if share > 0.0}
        return max(positive, key=positive.__getitem__) if positive else ""


@dataclass(eq=False)
class Budget:
    """The error budget of one pose: ``outputs`` and ``sources`` named, ``values`` (n_out,) and
    ``contributions`` (n_out, n_src) = ∂y/∂s · u_s in the output's unit (signed); ``motions`` the
    motion whose friction band each force-measured cylinder took."""

    outputs: tuple[Output, ...]
    sources: tuple[Source, ...]
    values: np.ndarray
    contributions: np.ndarray
    motions: Mapping[str, Motion]

    @cached_property
    def u(self) -> np.ndarray:
        """Standard uncertainty (n_out,) of every output (NaN where a contribution is)."""
        return np.sqrt(np.sum(self.contributions**2, axis=1))

    @cached_property
    def index(self) -> dict[str, int]:
        """Output name -> its row."""
        return {o.name: k for k, o in enumerate(self.outputs)}

    def line(self, name: str) -> OutputUncertainty:
        """The budget line of the output called ``name``."""
        k = self.index[name]
        u = float(self.u[k])
        squares = self.contributions[k] ** 2
        shares = ({s.name: float(c / u**2) for s, c in zip(self.sources, squares)} if u > 0.0
                  else {s.name: 0.0 for s in self.sources})
        return OutputUncertainty(self.outputs[k], float(self.values[k]), u, shares)

    def lines(self) -> list[OutputUncertainty]:
        """Every output's budget line, in the order of ``outputs``."""
        return [self.line(o.name) for o in self.outputs]

    def u_of(self, name: str) -> float:
        """The standard uncertainty of the output ``name`` (NaN for an output this budget lacks)."""
        k = self.index.get(name)
        return float(self.u[k]) if k is not None else math.nan


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
        self.n_hinges, self.n_cylinders = len(hinges), len(cylinders)
        self._steer_columns = [STEERABILITY_KEYS.index(k) for k in ("front_axle_load", "rear_axle_load", "ratio",
                                                                     "margin")]
        self.unit_reference = model.mech.tractor is not None and model.mech.tractor.steerability_reference == "unit"
        self.tractor_weight = model.mech.tractor.mass * model.mech.gravity if model.mech.tractor is not None else 1.0

    def values(self, result: Result, machine: MachineResult) -> np.ndarray:
        """The outputs of one solved pose, a row (n_out,) in the order of ``outputs``."""
        return self.rows(result.hinge_force[None], result.cylinder_values[None, :, 1],
                         np.array([result.implement_load]), machine.steerability_row[None],
                         machine.capacity_row[None])[0]

    def rows(self, hinge_force: np.ndarray, cylinder_force: np.ndarray, implement_load: np.ndarray,
             steerability: np.ndarray, capacity: np.ndarray) -> np.ndarray:
        """The outputs of N poses (N, n_out): hinge forces (N, H, 2) N, cylinder forces (N, C) N,
        implement loads (N,) N, steerability rows (N, STEERABILITY_KEYS) and capacity rows (N, P + 1)."""
        parts = [hinge_force[:, :, 0], hinge_force[:, :, 1], np.hypot(hinge_force[:, :, 0], hinge_force[:, :, 1]),
                 cylinder_force, implement_load[:, None]]
        if self.steerability:
            parts.append(steerability[:, self._steer_columns])
        if self.capacity_points or capacity.shape[1]:
            parts.append(capacity)
        return np.concatenate(parts, axis=1)


class _LinearisedOutputs:
    """The derivative of every output with respect to a load (pressure, friction, implement mass)
    from two solves at the same pose: exact for the outputs linear in the loads, the chain rule
    for the others (``derivative``)."""

    def __init__(self, table: OutputTable) -> None:
        h, c = table.n_hinges, table.n_cylinders
        self.fx, self.fz, self.magnitude = np.arange(h), np.arange(h, 2 * h), np.arange(2 * h, 3 * h)
        self.load = 3 * h + c
        self.table = table
        steer = self.load + 1
        self.front, self.rear, self.ratio, self.margin = steer, steer + 1, steer + 2, steer + 3
        capacity = self.load + 1 + 4 * table.steerability
        self.capacity_cg = (capacity + table.capacity_points.index("implement_cg")
                            if "implement_cg" in table.capacity_points else None)
        self.reserve = len(table.outputs) - 1

    def derivative(self, y0: np.ndarray, y1: np.ndarray, step: float) -> np.ndarray:
        """∂y/∂x (n_out,) from y0 = y(x) and y1 = y(x + step) at one pose."""
        with np.errstate(invalid="ignore", divide="ignore"):   # an infinite reserve (no load) has no derivative
            d = (y1 - y0) / step
            fx, fz, magnitude = y0[self.fx], y0[self.fz], y0[self.magnitude]
            d[self.magnitude] = np.where(magnitude > 0.0, (fx * d[self.fx] + fz * d[self.fz]) / magnitude,
                                         np.hypot(d[self.fx], d[self.fz]))
            if self.table.steerability:
                front, rear = y0[self.front], y0[self.rear]
                d_front, d_rear = d[self.front], d[self.rear]
                d[self.ratio] = ((d_front - y0[self.ratio] * (d_front + d_rear)) / (front + rear)
                                 if self.table.unit_reference else d_front / self.table.tractor_weight)
                d[self.margin] = d[self.ratio]
            if self.capacity_cg is not None:
                d[self.reserve] = (d[self.capacity_cg] - y0[self.reserve] * d[self.load]) / y0[self.load]
        return d


def force_per_pressure(mech: Mechanism, sensor: str) -> float:
    """N of cylinder force per Pa of the pressure sensor ``sensor``: count·A_cap for a cap chamber,
    −count·A_rod for a rod chamber (F = count·(p_cap·A_cap − p_rod·A_rod))."""
    ps = next(p for p in mech.measurements.pressures if p.name == sensor)
    cyl = mech.cylinder(ps.cylinder)
    return cyl.count * (cyl.cap_area if ps.chamber == "cap" else -cyl.rod_area)


def pose_step(u: float) -> float:
    """The central difference's step (m or rad) for an input of standard uncertainty ``u``."""
    return min(max(POSE_STEP_SHARE * u, POSE_STEP_MIN), POSE_STEP_MAX)


class UncertaintyModel:
    """The error budget of the poses of one ``MachineModel`` under the declared ``sources`` (default: the
    mechanism's own, ``Mechanism.error_sources``)."""

    def __init__(self, model: MachineModel, sources: ErrorSources | None = None) -> None:
        self.model, self.mech = model, model.mech
        self.sources = sources if sources is not None else model.mech.error_sources
        self.table = OutputTable(model)
        self._linear = _LinearisedOutputs(self.table)
        self._kinds = {**{c: "cylinders" for c in self.mech.measurements.cylinders},
                       **{a.name: "angles" for a in self.mech.measurements.angles},
                       **{p.name: "pressures" for p in self.mech.measurements.pressures}}
        self._heavier: MachineModel | None = None   # the implement LOAD_STEP_MASS heavier, built when first needed

    @property
    def outputs(self) -> tuple[Output, ...]:
        """The outputs of every budget, in order."""
        return self.table.outputs

    def budget(self, inputs: Inputs, result: Result, machine: MachineResult,
               motion: Motion | Mapping[str, Motion] = Motion.STANDING) -> Budget:
        """The error budget of the solved pose (``result``, ``machine``: ``self.model``'s answer to
        ``inputs``), each seal friction's band by ``motion``: one for every cylinder, or per cylinder
        name (a cylinder not named: standing)."""
        motions = ({c.name: motion.get(c.name, Motion.STANDING) for c in self.mech.cylinders}
                   if isinstance(motion, Mapping) else {c.name: motion for c in self.mech.cylinders})
        y0 = self.table.values(result, machine)
        sources: list[Source] = []
        columns: list[np.ndarray] = []
        per_pascal: dict[str, np.ndarray] = {}   # ∂y/∂p of each pressure sensor, one solve each

        def load_derivative(sensor: str) -> np.ndarray:
            if sensor not in per_pascal:
                per_pascal[sensor] = self._load_derivative(inputs, result, y0, "pressures", sensor)
            return per_pascal[sensor]

        units = {"cylinders": "m", "angles": "rad", "pressures": "Pa"}
        for kind in ("cylinders", "angles", "pressures"):
            for name, value in getattr(inputs, kind).items():
                error = self.sources.sensor(name, kind)
                parts = {part: u for part, u in error.components().items() if u > 0.0}
                if not parts:
                    continue
                d = (load_derivative(name) if kind == "pressures"
                     else self._pose_derivative(inputs, result, kind, name, value, pose_step(error.total)))
                for part, u in parts.items():
                    sources.append(Source(f"{name} {part}", name, part, u, units[kind]))
                    columns.append(d * u)
        used = {}
        for sensor, cylinder, u in self._friction(inputs, result, motions):
            used[cylinder] = motions[cylinder]
            d = load_derivative(sensor) / force_per_pressure(self.mech, sensor)
            sources.append(Source(f"{cylinder} seal friction", cylinder, "friction", u, "N"))
            columns.append(d * u)
        if self.sources.implement_mass > 0.0 and self.mech.implement is not None:
            sources.append(Source("implement mass", "implement", "mass", self.sources.implement_mass, "kg"))
            columns.append(self._mass_derivative(inputs, y0) * self.sources.implement_mass)
        contributions = np.column_stack(columns) if columns else np.zeros((len(y0), 0))
        return Budget(self.table.outputs, tuple(sources), y0, contributions, used)

    def _friction(self, inputs: Inputs, result: Result, motions: Mapping[str, Motion]
                  ) -> list[tuple[str, str, float]]:
        """(pressure sensor, cylinder, u N) of every cylinder whose force is measured (a pressure of it
        given; its cap sensor when it has one) and whose seal friction is not 0."""
        out = []
        forces = result.cylinders
        for cyl in self.mech.cylinders:
            sensor = self.friction_sensor(cyl.name, inputs)
            u = self.sources.seal_friction(cyl.name).standard_uncertainty(forces[cyl.name].force, motions[cyl.name])
            if sensor is not None and u > 0.0:
                out.append((sensor, cyl.name, u))
        return out

    def friction_sensor(self, cylinder: str, inputs: Inputs) -> str | None:
        """The pressure sensor through which ``cylinder``'s seal friction enters the outputs (the friction
        is a force the measured pressure does not see): its cap-chamber sensor when ``inputs`` give it,
        else its rod-chamber one; None when no pressure of it is given (its force is then solved, not
        measured, and the friction is the statics' own)."""
        given = sorted((ps.chamber != "cap", ps.name) for ps in self.mech.measurements.pressures
                       if ps.cylinder == cylinder and ps.name in inputs.pressures)
        return given[0][1] if given else None

    def _load_derivative(self, inputs: Inputs, result: Result, y0: np.ndarray, kind: str, name: str) -> np.ndarray:
        """∂y/∂p (n_out,) per Pa of the pressure sensor ``name``: one more solve at the same pose."""
        y1 = self._solved(self.model, _moved(inputs, kind, name, LOAD_STEP_PRESSURE), result)
        return self._linear.derivative(y0, y1, LOAD_STEP_PRESSURE)

    def _pose_derivative(self, inputs: Inputs, result: Result, kind: str, name: str, value: float, step: float
                         ) -> np.ndarray:
        """∂y/∂x (n_out,) per m or rad of the length or angle ``name``: a central difference of ``step``."""
        up = self._solved(self.model, _moved(inputs, kind, name, step), result)
        down = self._solved(self.model, _moved(inputs, kind, name, -step), result)
        with np.errstate(invalid="ignore"):   # an infinite reserve (no load) has no derivative
            return (up - down) / (2.0 * step)

    def _mass_derivative(self, inputs: Inputs, y0: np.ndarray) -> np.ndarray:
        """∂y/∂m (n_out,) per kg of implement mass: the same inputs solved with the implement heavier."""
        if self._heavier is None:
            assert self.mech.implement is not None
            heavier = apply_overrides(self.mech, {"implement.mass": self.mech.implement.mass + LOAD_STEP_MASS})
            solver = self.model.solver
            self._heavier = MachineModel(heavier, Solver(
                heavier, dead_centre_cond=solver.dead_centre_cond, consistency_tol=solver.consistency_tol,
                dead_centre_transmission_deg=solver.dead_centre_transmission_deg))
        return self._linear.derivative(y0, self._solved(self._heavier, inputs, None), LOAD_STEP_MASS)

    def _solved(self, model: MachineModel, inputs: Inputs, previous: Result | None) -> np.ndarray:
        """The outputs of ``inputs`` solved by ``model`` from ``previous``; NaN where the pose fails."""
        try:
            pose = model.solve(inputs, previous)
        except LinkageError:
            return np.full(len(self.table.outputs), math.nan)
        return self.table.values(pose.result, pose.machine)


def _moved(inputs: Inputs, kind: str, name: str, step: float) -> Inputs:
    """``inputs`` with the ``kind`` input ``name`` moved by ``step``."""
    group = dict(getattr(inputs, kind))
    group[name] = group[name] + step
    return replace(inputs, **{kind: group})
