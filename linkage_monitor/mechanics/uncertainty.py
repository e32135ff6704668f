"""First-order propagation of the declared error sources (``error_sources``) to every published
output of a solved pose: its standard uncertainty (1 sigma, the output's unit) and each source's share.

Outputs (``OutputTable``): hinge reactions (fx, fz, magnitude, N), cylinder forces (N), the implement
load (N), axle loads (N), steerability ratio and margin (-), lift capacities (N) and the lift reserve
(-). Sources (``Source``): each measured input's bias, noise and resolution, each force-measured
cylinder's seal friction, the implement's mass, each toleranced point coordinate (tabulated once per
mechanism over its stroke: ``geometry_budget``).

Derivatives, from the pose's inputs moved one at a time, all the moved poses solved in one call of
the same compiled solve as the pose (``Solver.solve_moved``; a moved pose it does not take: by
``MachineModel.solve``, which words it), each from the one before, the first from the pose:
- loads (pressures, seal friction, implement mass) do not move the pose, and at a fixed pose the
  statics, the implement load and the axle loads are linear in them: the derivative is exact from
  one more pose (``(y(x + Δ) − y(x)) / Δ`` of a linear function), and the outputs that are not
  linear (hinge magnitude, steerability ratio and margin, lift reserve) follow from those by the
  chain rule (``_LinearisedOutputs``); the implement mass, a heavier implement, is one solve of
  its own;
- cylinder lengths and angles move the pose along the linkage's degrees of freedom: a central
  difference of step ``pose_step`` (truncation error O(h²), held by test/test_uncertainty.py to a
  Richardson estimate); at a pose whose load is a weak inference (``Result.load_amplification``
  above ``reduced.LOAD_AMPLIFICATION_WARN``: near the load's line through a pivot, where it goes as
  1/distance) the same two poses give the second difference, and an output whose second-order
  change over ±2 u is a large share of its interval (``NONLINEAR_SHARE``) has no first-order
  interval: its u is NaN (unbounded).
What moves for a set of input names is worked out once (``_Plan``).
u_y² = Σ_s (∂y/∂s · u_s)² (the sources independent); the share of s is (∂y/∂s · u_s)² / u_y².
The 95 % interval is y ± k·u_y, k from the shape of the budget (``coverage_factor``: 1.96 for normal
sources, down to 1.645 where one uniform source, a seal's friction or a quantization step, dominates).
Units SI (m, rad, Pa, N, kg); frame x forward, z up, origin at the rear wheels' ground contact.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Mapping, NamedTuple

import numpy as np

from .budget import FRICTION_SIGN, Budget, Output, Source
from .coverage_factor import NORMAL_FACTOR
from .error_sources import ErrorSources, Motion
from .errors import LinkageError
from .geometry_budget import GeometryBudget
from .inputs import Inputs
from .live_path import InputMoves
from .machine import STEERABILITY_KEYS, MachineModel, MachineResult
from .model import Mechanism
from .overrides import apply_overrides
from .reduced import LOAD_AMPLIFICATION_WARN
from .results import Result
from .solver import Solver

LOAD_STEP_PRESSURE = 1.0e5   # Pa: the pressure step of a load derivative (any step: the outputs are linear)
LOAD_STEP_MASS = 100.0       # kg: the implement-mass step of a load derivative (likewise)
POSE_STEP_SHARE = 0.25       # the central difference's step, as a share of the input's standard uncertainty
POSE_STEP_MIN, POSE_STEP_MAX = 1e-6, 1e-3   # m or rad: its bounds (Newton's 1e-13 below, the curvature above)
# An output whose second-order change over ±2 u of the lengths and angles is above this share of its
# first-order 95 % half-width (1.96 u) has no first-order interval: its u is unbounded (NaN). Near a
# load's line through a pivot (docs/dead-centre.md) the inferred load goes as 1/distance: the ratio of
# the second-order change to the first is the interval's reach over the distance: at a half, the
# interval reaches half the way to where the load is not determined.
NONLINEAR_SHARE = 0.5


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
        self.fx, self.fz, self.magnitude = slice(0, h), slice(h, 2 * h), slice(2 * h, 3 * h)
        self.load = 3 * h + c
        self.table = table
        steer = self.load + 1
        self.front, self.rear, self.ratio, self.margin = steer, steer + 1, steer + 2, steer + 3
        capacity = self.load + 1 + 4 * table.steerability
        self.capacity_cg = (capacity + table.capacity_points.index("implement_cg")
                            if "implement_cg" in table.capacity_points else None)
        self.reserve = len(table.outputs) - 1

    def derivative(self, y0: np.ndarray, y1: np.ndarray, step: float) -> np.ndarray:
        """∂y/∂x (n_out,) from y0 = y(x) and y1 = y(x + step) at one pose; of several loads at once with
        y1 (L, n_out), a row each: (L, n_out)."""
        with np.errstate(invalid="ignore", divide="ignore"):   # an infinite reserve (no load) has no derivative
            return self.chain(y0, (y1 - y0) / step)

    def chain(self, y0: np.ndarray, d: np.ndarray) -> np.ndarray:
        """``d`` (n_out,) or (R, n_out), derivatives whose outputs linear in the loads are right, with the
        others (hinge magnitude, steerability ratio and margin, lift reserve) by the chain rule at ``y0``."""
        with np.errstate(invalid="ignore", divide="ignore"):   # an infinite reserve (no load) has no derivative
            fx, fz, magnitude = y0[self.fx], y0[self.fz], y0[self.magnitude]
            d[..., self.magnitude] = np.where(magnitude > 0.0,
                                              (fx * d[..., self.fx] + fz * d[..., self.fz]) / magnitude,
                                              np.hypot(d[..., self.fx], d[..., self.fz]))
            if self.table.steerability:
                front, rear = y0[self.front], y0[self.rear]
                d_front, d_rear = d[..., self.front], d[..., self.rear]
                d[..., self.ratio] = ((d_front - y0[self.ratio] * (d_front + d_rear)) / (front + rear)
                                      if self.table.unit_reference else d_front / self.table.tractor_weight)
                d[..., self.margin] = d[..., self.ratio]
            if self.capacity_cg is not None:
                d[..., self.reserve] = (d[..., self.capacity_cg] - y0[self.reserve] * d[..., self.load]) / y0[self.load]
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


class _Move(NamedTuple):
    """One moved pose of a budget: the ``kind`` input (``cylinders``, ``angles``, ``pressures``) ``name``
    moved by ``step`` (m, rad or Pa)."""

    kind: str
    name: str
    step: float


@dataclass(frozen=True)
class _Plan:
    """What the budget of a pose with one set of input names solves, worked out once for the set:
    ``moves`` a row each (as ``inputs_moved``; None when a name is not the solver's: each moved pose
    is then solved on its own), the derivatives they give, a row each of (P + L, n_out): P lengths
    and angles (central differences of rows ``up`` and ``down`` over ``spans`` (P, 1), twice their
    steps; ``reach`` (P, 1) each input's combined standard uncertainty) then L pressure sensors (rows ``loads``, step LOAD_STEP_PRESSURE), ``derivative`` by input name; the
    sources of the measured inputs (``sources``, each from its input's derivative ``which``; their
    ``scales`` u and ``uniform`` shapes) and the
    sensor each cylinder's seal friction enters by (``friction_sensors``: None for one whose force is
    not measured) with its N per Pa (``per_pascal``)."""

    moves: tuple[_Move, ...]
    inputs_moved: InputMoves | None
    up: slice
    down: slice
    spans: np.ndarray
    reach: np.ndarray
    loads: slice
    derivative: Mapping[str, int]
    sources: tuple[Source, ...]
    which: tuple[int, ...]
    scales: tuple[float, ...]
    uniform: tuple[bool, ...]
    friction_sensors: Mapping[str, str | None]
    per_pascal: Mapping[str, float]


class UncertaintyModel:
    """The error budget of the poses of one ``MachineModel`` under the declared ``sources`` (default: the
    mechanism's own, ``Mechanism.error_sources``)."""

    def __init__(self, model: MachineModel, sources: ErrorSources | None = None) -> None:
        self.model, self.mech = model, model.mech
        self.sources = sources if sources is not None else model.mech.error_sources
        self.table = OutputTable(model)
        self._linear = _LinearisedOutputs(self.table)
        self._heavier: MachineModel | None = None   # the implement LOAD_STEP_MASS heavier, built when first needed
        self._plans: dict[tuple[tuple[str, ...], ...], _Plan] = {}   # by input names (``_plan``)
        self.geometry = GeometryBudget(model, self.sources, self.table)

    @property
    def outputs(self) -> tuple[Output, ...]:
        """The outputs of every budget, in order."""
        return self.table.outputs

    def budget(self, inputs: Inputs, result: Result, machine: MachineResult,
               motion: Motion | Mapping[str, Motion] = Motion.STANDING) -> Budget:
        """The error budget of the solved pose (``result``, ``machine``: ``self.model``'s answer to
        ``inputs``), each seal friction's band by ``motion``: one for every cylinder, or per cylinder
        name (a cylinder not named: standing)."""
        motions = ({c.name: motion for c in self.mech.cylinders} if isinstance(motion, Motion)
                   else {c.name: motion.get(c.name, Motion.STANDING) for c in self.mech.cylinders})
        plan = self._plan(inputs)
        y0 = self.table.values(result, machine)
        moved = self._moved_outputs(inputs, result, plan.moves, plan.inputs_moved)
        with np.errstate(invalid="ignore"):   # an infinite reserve (no load) has no derivative
            per_pose = (moved[plan.up] - moved[plan.down]) / plan.spans
        derivatives = np.concatenate([per_pose, self._linear.derivative(y0, moved[plan.loads], LOAD_STEP_PRESSURE)])
        sources, which, scales = list(plan.sources), list(plan.which), list(plan.scales)
        uniform, sign = list(plan.uniform), [0.0] * len(sources)
        used = {}
        forces = result.cylinders
        for cylinder, sensor in plan.friction_sensors.items():
            u = self.sources.seal_friction(cylinder).standard_uncertainty(forces[cylinder].force, motions[cylinder])
            if sensor is None or u <= 0.0:
                continue
            used[cylinder] = motions[cylinder]
            sources.append(Source(f"{cylinder} seal friction", cylinder, "friction", u, "N"))
            which.append(plan.derivative[sensor])
            scales.append(u / plan.per_pascal[sensor])
            uniform.append(True)
            sign.append(FRICTION_SIGN[motions[cylinder]])
        contributions = derivatives[which].T * np.array(scales)
        if self.geometry.sources:   # the point coordinates' tolerances, from their table (geometry_budget)
            sources += self.geometry.sources
            uniform += [False] * len(self.geometry.sources)
            sign += [0.0] * len(self.geometry.sources)
            per_point = self._linear.chain(y0, self.geometry.derivatives(inputs))
            contributions = np.column_stack([contributions, per_point.T * self.geometry.scales])
        if self.sources.implement_mass > 0.0 and self.mech.implement is not None:
            sources.append(Source("implement mass", "implement", "mass", self.sources.implement_mass, "kg"))
            uniform.append(False)
            sign.append(0.0)
            contributions = np.column_stack([contributions,
                                             self._mass_derivative(inputs, y0) * self.sources.implement_mass])
        if result.load_amplification > LOAD_AMPLIFICATION_WARN:   # a weak inference: does the first order hold?
            with np.errstate(invalid="ignore"):   # the second-order change over ±2 u of each length and angle
                curvature = (moved[plan.up] + moved[plan.down] - 2.0 * y0) / (plan.spans / 2.0) ** 2
                second = np.sum(2.0 * np.abs(curvature) * plan.reach**2, axis=0)
                linear = NONLINEAR_SHARE * NORMAL_FACTOR * np.sqrt(np.sum(contributions**2, axis=1))
            contributions[second > linear] = math.nan   # not over the interval: unbounded
        return Budget(self.table.outputs, tuple(sources), y0, contributions, used, self.table.index,
                      np.array(uniform, dtype=bool), np.array(sign))

    def _plan(self, inputs: Inputs) -> _Plan:
        """The ``_Plan`` of the input names of ``inputs`` (in their order), built once for them."""
        key = (tuple(inputs.cylinders), tuple(inputs.angles), tuple(inputs.pressures))
        plan = self._plans.get(key)
        if plan is None:
            plan = self._plans[key] = self._new_plan(*key)
        return plan

    def _new_plan(self, cylinders: tuple[str, ...], angles: tuple[str, ...], pressures: tuple[str, ...]) -> _Plan:
        """The ``_Plan`` of these input names (``_plan``)."""
        units = {"cylinders": "m", "angles": "rad", "pressures": "Pa"}
        parts = {name: {part: u for part, u in self.sources.sensor(name, kind).components().items() if u > 0.0}
                 for kind, names in (("cylinders", cylinders), ("angles", angles), ("pressures", pressures))
                 for name in names}
        given = Inputs(cylinders=dict.fromkeys(cylinders, 0.0), angles=dict.fromkeys(angles, 0.0),
                       pressures=dict.fromkeys(pressures, 0.0))
        friction_sensors = {c.name: self.friction_sensor(c.name, given) for c in self.mech.cylinders}
        moves: list[_Move] = []
        derivative: dict[str, int] = {}
        for kind, names in (("cylinders", cylinders), ("angles", angles)):
            for name in names:
                if parts[name]:
                    step = pose_step(self.sources.sensor(name, kind).total)
                    derivative[name] = len(derivative)
                    moves += [_Move(kind, name, step), _Move(kind, name, -step)]
        loads = [name for name in pressures if parts[name] or name in friction_sensors.values()]
        for name in loads:
            derivative[name] = len(derivative)
            moves.append(_Move("pressures", name, LOAD_STEP_PRESSURE))
        n_pose = 2 * (len(derivative) - len(loads))
        sources, which = [], []
        for kind, names in (("cylinders", cylinders), ("angles", angles), ("pressures", pressures)):
            for name in names:
                for part, u in parts[name].items():
                    sources.append(Source(f"{name} {part}", name, part, u, units[kind]))
                    which.append(derivative[name])
        return _Plan(tuple(moves), self._inputs_moved(moves), slice(0, n_pose, 2), slice(1, n_pose, 2),
                     np.array([2.0 * move.step for move in moves[:n_pose:2]]).reshape(-1, 1),
                     np.array([self.sources.sensor(move.name, move.kind).total
                               for move in moves[:n_pose:2]]).reshape(-1, 1), slice(n_pose, None),
                     derivative,
                     tuple(sources), tuple(which), tuple(s.u for s in sources), tuple(s.uniform for s in sources),
                     friction_sensors,
                     {sensor: force_per_pressure(self.mech, sensor)
                      for sensor in friction_sensors.values() if sensor is not None})

    def _inputs_moved(self, moves: list[_Move]) -> InputMoves | None:
        """``moves`` as ``Solver.solve_moved`` takes them; None when a name is not the solver's."""
        solver = self.model.solver
        columns = {name: j for j, name in enumerate(solver.kin.input_names)}
        s = np.zeros((len(moves), len(columns)))
        pressures = np.zeros((len(moves), 2, len(self.mech.cylinders)))
        for row, move in enumerate(moves):
            if move.kind == "pressures":
                sensor = solver.sensors.get(move.name)
                if sensor is None:
                    return None
                pressures[row, 0 if sensor.chamber == "cap" else 1, solver.cylinder_index[sensor.cylinder]] = move.step
            elif move.name in columns:
                s[row, columns[move.name]] = move.step
            else:
                return None
        return InputMoves(s, pressures)

    def _moved_outputs(self, inputs: Inputs, result: Result, moves: tuple[_Move, ...],
                       inputs_moved: InputMoves | None) -> np.ndarray:
        """The outputs (R, n_out) of ``inputs`` moved by each of ``moves`` (``inputs_moved`` the same as
        ``Solver.solve_moved`` takes them), solved from ``result``: in one compiled call, the poses it
        does not take one by one (``_solved``; NaN where a pose fails)."""
        if not moves:
            return np.zeros((0, len(self.table.outputs)))
        solved = (self.model.solver.solve_moved(inputs, result, self.model.program, inputs_moved)
                  if inputs_moved is not None else None)
        if solved is None:
            outputs, taken = np.empty((len(moves), len(self.table.outputs))), np.zeros(len(moves), dtype=bool)
        else:
            rows, span = solved
            outputs = self.table.rows(rows.hinge_force[span], rows.cylinder_values[span, :, 1],
                                      rows.pose["implement_load"][span], rows.steerability[span], rows.capacity[span])
            taken = rows.plain[span]
        if not taken.all():
            for k in np.flatnonzero(~taken):
                outputs[k] = self._solved(self.model, _moved(inputs, *moves[k]), result)
        return outputs

    def friction_sensor(self, cylinder: str, inputs: Inputs) -> str | None:
        """The pressure sensor through which ``cylinder``'s seal friction enters the outputs (the friction
        is a force the measured pressure does not see): its cap-chamber sensor when ``inputs`` give it,
        else its rod-chamber one; None when no pressure of it is given (its force is then solved, not
        measured, and the friction is the statics' own)."""
        given = sorted((ps.chamber != "cap", ps.name) for ps in self.mech.measurements.pressures
                       if ps.cylinder == cylinder and ps.name in inputs.pressures)
        return given[0][1] if given else None

    def _load_derivative(self, inputs: Inputs, result: Result, y0: np.ndarray, kind: str, name: str) -> np.ndarray:
        """∂y/∂p (n_out,) per Pa of the pressure sensor ``name``: one more pose, at the same pose."""
        moves = (_Move(kind, name, LOAD_STEP_PRESSURE),)
        y1 = self._moved_outputs(inputs, result, moves, self._inputs_moved(list(moves)))[0]
        return self._linear.derivative(y0, y1, LOAD_STEP_PRESSURE)

    def _pose_derivative(self, inputs: Inputs, result: Result, kind: str, name: str, value: float, step: float
                         ) -> np.ndarray:
        """∂y/∂x (n_out,) per m or rad of the length or angle ``name`` (now ``value``): a central
        difference of ``step``."""
        moves = (_Move(kind, name, step), _Move(kind, name, -step))
        up, down = self._moved_outputs(inputs, result, moves, self._inputs_moved(list(moves)))
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
