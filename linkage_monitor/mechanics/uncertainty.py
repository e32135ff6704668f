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
  chain rule (``LinearisedOutputs``); the implement mass, a heavier implement, is one solve of
  its own;
- cylinder lengths and angles move the pose along the linkage's degrees of freedom: a central
  difference of step ``pose_step`` (truncation error O(h²), held by test/test_uncertainty.py to a
  Richardson estimate); at a pose whose load is a weak inference (``Result.load_amplification``
  above ``reduced.LOAD_AMPLIFICATION_WARN``: near the load's line through the closing pivot, its
  *pole*, where the inferred load goes as 1/d, d the line's distance from the pivot) the pole's reach
  u_d/|d| is measured (``pole_reach``), and beyond ``POLE_REACH_MAX`` (from the 1/d model) every
  output the statics infer has no first-order interval: its u is NaN (unbounded).
What moves for a set of input names is worked out once (``_Plan``).
On a linkage of one degree of freedom the derivatives come from a table over the stroke, each node
from these moved poses, interpolated per pose, the rest of the budget in one compiled call
(``budget_table``, ``kernels.tabulated_budget``); the moved poses serve what the table does not.
u_y² = Σ_s (∂y/∂s · u_s)² (the sources independent); the share of s is (∂y/∂s · u_s)² / u_y².
The 95 % interval is y ± k·u_y, k from the shape of the budget (``coverage_factor``: 1.96 for normal
sources, down to 1.645 where one uniform source, a seal's friction or a quantization step, dominates; with a
moving seal's friction, of known sign, 95 % of the error within and a verdict's bound apart, ``Factors``).
Units SI (m, rad, Pa, N, kg); frame x forward, z up, origin at the rear wheels' ground contact.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from functools import partial
from itertools import repeat
from types import MappingProxyType
from typing import Mapping, NamedTuple

import numpy as np

from . import kernels
from .budget import FRICTION_SIGN, Budget, Output, Source
from .budget_table import RawRows, StrokeTable, one_dof
from .coverage_factor import NORMAL_FACTOR, factor_table
from .error_sources import ErrorSources, Motion, SealFriction
from .errors import LinkageError
from .geometry_budget import GeometryBudget
from .inputs import Inputs
from .live_path import InputMoves
from .machine import MachineModel, MachineResult
from .output_table import LinearisedOutputs, OutputTable, force_per_pressure
from .overrides import apply_overrides
from .programs import fields
from .reduced import LOAD_AMPLIFICATION_WARN
from .results import Result
from .solver import Solver

LOAD_STEP_PRESSURE = 1.0e5   # Pa: the pressure step of a load derivative (any step: the outputs are linear)
LOAD_STEP_MASS = 100.0       # kg: the implement-mass step of a load derivative (likewise)
POSE_STEP_SHARE = 0.25       # the central difference's step, as a share of the input's standard uncertainty
POSE_STEP_MIN, POSE_STEP_MAX = 1e-6, 1e-3   # m or rad: its bounds (Newton's 1e-13 below, the curvature above)
# The pole's reach (``pole_reach``): near a load's line through the closing pivot (docs/dead-centre.md)
# the inferred load goes as a/d, d the line's distance from the pivot, and so does every output the
# statics infer from it. With d normal of standard uncertainty u_d (the declared lengths, angles and
# points that move the line) and r = u_d/|d| (the relative first-order u of a/d), the standard deviation
# of a/d is its first-order one, a·u_d/d², times √(1 + 8 r² + O(r⁴)) (1/(1 + ε) = 1 − ε + ε² − ε³ ...,
# Var = r² + 8 r⁴ in units of 1/d²), and over the whole normal it is infinite: the pole lies 1/r
# standard uncertainties away, and 10⁴ Monte Carlo draws reach about 4 (r = 0.25). The first order is
# within FIRST_ORDER_GOAL of the spread while √(1 + 8 r²) <= 1 + FIRST_ORDER_GOAL:
# r <= r_1 = √(((1 + FIRST_ORDER_GOAL)² − 1)/8) = 0.162. The monitor sees d as read; the true d may lie
# anywhere in its 95 % interval, as near as |d| − k·u_d (k = NORMAL_FACTOR), where the reach is
# u_d/(|d| − k·u_d): it stays within r_1 while r <= r_1/(1 + k·r_1) = 0.123, the pole beyond 8.1 u_d (a bound
# on the read r alone would pass exactly the readings that err away from the pole). Beyond, every output the
# statics infer is unbounded (u NaN): the smallest share of the pole in an output (a hinge's fx through a
# point's tolerance) has an infinite variance once the draws reach it.
FIRST_ORDER_GOAL = 0.10
_FIRST_ORDER_REACH = math.sqrt(((1.0 + FIRST_ORDER_GOAL) ** 2 - 1.0) / 8.0)
POLE_REACH_MAX = _FIRST_ORDER_REACH / (1.0 + NORMAL_FACTOR * _FIRST_ORDER_REACH)


def pose_step(u: float) -> float:
    """The central difference's step (m or rad) for an input of standard uncertainty ``u``."""
    return min(max(POSE_STEP_SHARE * u, POSE_STEP_MIN), POSE_STEP_MAX)


class _Move(NamedTuple):
    """One moved pose of a budget: the ``kind`` input (``cylinders``, ``angles``, ``pressures``) ``name``
    moved by ``step`` (m, rad or Pa)."""

    kind: str
    name: str
    step: float


class _Friction(NamedTuple):
    """A force-measured cylinder's seal friction at a pose: its pressure ``sensor`` (through which it
    enters), its standard uncertainty ``u`` (N) and the ``motion`` whose band it took."""

    cylinder: str
    sensor: str
    u: float
    motion: Motion


class _Columns(NamedTuple):
    """The sources of one budget as columns: ``sources``, the derivative row each takes (``rows``), its
    u in its input's unit (``scales``), its shape (``uniform``, ``sign``: ``Budget``'s) and the
    motions of the frictions taken."""

    sources: tuple[Source, ...]
    rows: np.ndarray
    scales: np.ndarray
    uniform: np.ndarray
    sign: np.ndarray
    motions: Mapping[str, Motion]


class _Fast(NamedTuple):
    """What a budget from the stroke's table takes of its ``_Plan``: the compiled call's ``program``
    (``kernels.BudgetProgram``), its columns' shapes (``uniform``) with every measured cylinder's
    friction (``cylinders``, in the columns' order), the implement mass's source (``mass``, empty
    without), the cylinders' motions as the call takes them (``motions``, each set once), and the
    shapes of the arrays the call writes (``summary`` (5, n_out), ``contributions`` (n_out, n_src))."""

    program: kernels.BudgetProgram
    uniform: np.ndarray
    cylinders: tuple[str, ...]
    mass: tuple[Source, ...]
    motions: list["_Motions"]   # each set of the cylinders' motions met, built when first met
    summary: tuple[int, int]
    contributions: tuple[int, int]
    sign: np.ndarray   # the columns' signs (``Budget.sign``), the frictions' 0: a set of motions sets theirs
    frictions: slice   # the frictions' columns
    last: list["_Given"]   # one item: the read-only motions given last, and their set


class _Given(NamedTuple):
    """A read-only mapping of motions a budget was given (``given``: ``MotionTracker.motions`` hands the
    same one on while the motions hold) and its set (``codes``): the next budget given the same object
    takes the set without reading the mapping (~1 µs of a live step)."""

    given: Mapping[str, Motion]
    codes: "_Motions"


class _Motions(NamedTuple):
    """A set of the measured cylinders' motions (``moving``, in ``_Fast.cylinders``' order) as
    ``kernels.tabulated_budget`` takes them (``codes``, MOTION_*, and the columns' signs at them,
    ``sign``) and as a budget names them (``motions``, cylinder name -> motion); read-only: budgets
    share them."""

    moving: tuple[Motion, ...]
    codes: np.ndarray
    sign: np.ndarray
    motions: Mapping[str, Motion]


# no budget yet
_NOTHING_GIVEN = _Given(MappingProxyType({}), _Motions((), np.zeros(0, np.int64), np.zeros(0), MappingProxyType({})))
_STANDING = Motion.STANDING   # read once: a lookup on the Enum class takes ~0.1 µs
# a cylinder's motion as kernels.tabulated_budget takes it
_MOTION_CODES = {Motion.STANDING: kernels.MOTION_STANDING, Motion.LIFTING: kernels.MOTION_LIFTING,
                 Motion.LOWERING: kernels.MOTION_LOWERING}


@dataclass(frozen=True)
class _Plan:
    """What the budget of a pose with one set of input names solves, worked out once for the set:
    ``moves`` a row each (as ``inputs_moved``; None when a name is not the solver's: each moved pose
    is then solved on its own), the derivatives they give, a row each of (P + L, n_out): P lengths
    and angles (central differences of rows ``up`` and ``down`` over ``spans`` (P, 1), twice their
    steps; ``reach`` (P, 1) each input's combined standard uncertainty) then L pressure sensors (moved
    rows ``loads``, step LOAD_STEP_PRESSURE; derivative rows ``load_rows``), then with ``mass`` (the
    implement mass a declared source) the implement mass's row; ``derivative`` the row by input
    name; the sources of the measured inputs (``sources``, each from its input's derivative
    ``which``; their ``scales`` u and ``uniform`` shapes) and the sensor each cylinder's seal friction
    enters by (``friction_sensors``: None for one whose force is not measured) with its N per Pa
    (``per_pascal``), and per force-measured cylinder (``seals``) its name, sensor, row of the cylinder
    values and seal friction; on a one-DOF linkage the stroke's table (``stroke``, ``budget_table``) and the
    columns its budgets take with every measured cylinder's friction (``fast``)."""

    moves: tuple[_Move, ...]
    inputs_moved: InputMoves | None
    up: slice
    down: slice
    spans: np.ndarray
    reach: np.ndarray
    loads: slice
    load_rows: slice
    derivative: Mapping[str, int]
    sources: tuple[Source, ...]
    which: tuple[int, ...]
    scales: tuple[float, ...]
    uniform: tuple[bool, ...]
    friction_sensors: Mapping[str, str | None]
    per_pascal: Mapping[str, float]
    seals: tuple[tuple[str, str, int, SealFriction], ...]
    mass: bool
    stroke: StrokeTable | None = None
    fast: _Fast | None = None


class UncertaintyModel:
    """The error budget of the poses of one ``MachineModel`` under the declared ``sources`` (default: the
    mechanism's own, ``Mechanism.error_sources``); ``tabulate`` False: every budget from its moved poses,
    none from a stroke's table (``budget_table``)."""

    def __init__(self, model: MachineModel, sources: ErrorSources | None = None, tabulate: bool = True) -> None:
        self.model, self.mech = model, model.mech
        self._tabulate = tabulate
        self.sources = sources if sources is not None else model.mech.error_sources
        self.table = OutputTable(model)
        self._linear = LinearisedOutputs(self.table)
        self._heavier: MachineModel | None = None   # the implement LOAD_STEP_MASS heavier, built when first needed
        self._plans: dict[tuple[str | None, ...], _Plan] = {}   # by input names, kinds apart by None (``_plan``)
        self.geometry = GeometryBudget(model, self.sources, self.table)

    @property
    def outputs(self) -> tuple[Output, ...]:
        """The outputs of every budget, in order."""
        return self.table.outputs

    def budget(self, inputs: Inputs, result: Result, machine: MachineResult,
               motion: Motion | Mapping[str, Motion] = Motion.STANDING) -> Budget:
        """The error budget of the solved pose (``result``, ``machine``: ``self.model``'s answer to
        ``inputs``), each seal friction's band by ``motion``: one for every cylinder, or per cylinder
        name (a cylinder not named: standing; a read-only ``MappingProxyType`` is taken to stay as it is:
        given the same object again, its motions are not read again, as ``MotionTracker.motions`` hands
        them on). From the stroke's table where it applies (``budget_table``), else from the pose's
        moved poses."""
        plan = self._plan(inputs)
        if plan.stroke is not None and not result.load_amplification > LOAD_AMPLIFICATION_WARN:
            budget = self._tabulated(plan, inputs, result, machine, motion)
            if budget is not None:
                return budget
        y0 = self.table.values(result, machine)
        moved, derivatives = self.raw_rows(inputs, result, y0, plan)
        kernels.chain_rule(derivatives[plan.load_rows.start:], y0, self.table.layout)   # the loads' and the mass's rows
        columns = self._columns(plan, self._frictions(plan, result, motion))
        columns, contributions = self._with_geometry(plan, columns, derivatives[columns.rows].T * columns.scales, y0,
                                                     inputs)
        if result.load_amplification > LOAD_AMPLIFICATION_WARN:   # a weak inference: does the first order hold?
            if not self.pole_reach(plan, inputs, result, moved, derivatives) <= POLE_REACH_MAX:
                contributions[self.table.of_the_pole] = math.nan   # the pole within reach: unbounded
        return Budget(self.table.outputs, columns.sources, y0, contributions, columns.motions, self.table.index,
                      columns.uniform, columns.sign)

    def pole_reach(self, plan: _Plan, inputs: Inputs, result: Result, moved: np.ndarray, derivatives: np.ndarray
                   ) -> float:
        """The pole's reach at a weak inference, r = u_d/|d| (-; ``POLE_REACH_MAX``): d the distance of the
        load's line from the closing pivot, u_d its standard uncertainty from the declared lengths, angles
        and points. The implement load's N per Pa of a pressure, B = ∂λ/∂p = ±A·area (A the load's
        amplification, |m/d|, m the cylinder's arm, slow beside d there), goes as 1/d: r is the relative
        first-order change of B over those sources, sqrt(Σ_s (∂B/∂s·u_s)²)/|B| — the lengths' and angles'
        from B at the budget's central-difference poses, each solved again with the pressure moved; the
        points' from the geometry table's ∂B/∂g — the largest over the given pressures. NaN where a moved
        pose fails (unbounded). A step across the pole (|d| below the step, a quarter of u_d) turns B's
        sign: r then reads at least 1/POSE_STEP_SHARE."""
        n_pose = 2 * len(plan.reach)
        load = self.table.layout.load
        sensors = [move.name for move in plan.moves[plan.loads]]
        both = [(plan.moves[k], _Move("pressures", sensor, LOAD_STEP_PRESSURE)) for sensor in sensors
                for k in range(n_pose)]
        solved = self._moved_outputs(inputs, result, tuple(both), self._inputs_moved_both(plan, len(sensors)))
        geometry = self.geometry
        reach = [0.0]
        with np.errstate(divide="ignore", invalid="ignore"):
            for l, sensor in enumerate(sensors):
                b0 = derivatives[plan.derivative[sensor], load]
                b = (solved[l * n_pose:(l + 1) * n_pose, load] - moved[:n_pose, load]) / LOAD_STEP_PRESSURE
                changes = [(b[plan.up] - b[plan.down]) / plan.spans[:, 0] * plan.reach[:, 0]]
                if geometry.sources:
                    changes.append(geometry.derivatives(inputs, per_pascal=sensor)[:, load] * geometry.scales)
                reach.append(math.sqrt(float(np.sum(np.concatenate(changes) ** 2))) / abs(b0))
        return float(np.max(reach))   # NaN where one is

    def _inputs_moved_both(self, plan: _Plan, n_sensors: int) -> InputMoves | None:
        """The budget's length and angle moves (``plan.inputs_moved``'s first rows), each with one given
        pressure moved by LOAD_STEP_PRESSURE too, pressure after pressure; None as ``plan.inputs_moved``."""
        moves = plan.inputs_moved
        if moves is None:
            return None
        n_pose = 2 * len(plan.reach)
        loads = moves.pressures[plan.loads][:n_sensors]
        return InputMoves(np.tile(moves.s[:n_pose], (n_sensors, 1)),
                          np.repeat(loads, n_pose, axis=0) + np.tile(moves.pressures[:n_pose], (n_sensors, 1, 1)))

    def raw_rows(self, inputs: Inputs, result: Result, y0: np.ndarray, plan: _Plan) -> tuple[np.ndarray, np.ndarray]:
        """The moved poses' outputs (R, n_out) of the pose ``result`` of ``inputs`` (outputs ``y0``) and
        the derivatives they give, a row per source input (``_Plan``: the lengths' and angles' central
        differences, then per pressure sensor and for the implement mass (y(x + Δ) − y(x)) / Δ, the
        columns not linear in the loads as they come: ``kernels.chain_rule`` gives them)."""
        moved = self._moved_outputs(inputs, result, plan.moves, plan.inputs_moved)
        with np.errstate(invalid="ignore"):   # an infinite reserve (no load) has no derivative
            parts = [(moved[plan.up] - moved[plan.down]) / plan.spans, (moved[plan.loads] - y0) / LOAD_STEP_PRESSURE]
            if plan.mass:
                parts.append(((self._heavier_outputs(inputs) - y0) / LOAD_STEP_MASS)[None])
        return moved, np.concatenate(parts)

    def _tabulated(self, plan: _Plan, inputs: Inputs, result: Result, machine: MachineResult,
                   motion: Motion | Mapping[str, Motion]) -> Budget | None:
        """The budget of the pose from the stroke's table (``budget_table``, ``kernels.tabulated_budget``);
        None where the table does not hold it, or a measured cylinder's seal friction is 0."""
        stroke, fast = plan.stroke, plan.fast
        assert stroke is not None and fast is not None
        last = fast.last[0]
        if motion is last.given:   # a read-only mapping's object: the same motions
            codes = last.codes
        else:
            codes = self._motion_codes(fast, motion)
            if type(motion) is MappingProxyType:
                fast.last[0] = _Given(motion, codes)
        summary = np.empty(fast.summary)   # y0, u, k, the verdicts' factor and the frictions' u, as rows
        contributions = np.empty(fast.contributions)
        sign = codes.sign
        args = (fast.program, result.hinge_force, result.cylinder_values, result.body_q, result.implement_load,
                machine.steerability_row, machine.capacity_row, codes.codes, sign, summary, contributions)
        node = kernels.tabulated_budget(*args)
        if node <= -2:   # a node next to the pose not computed yet
            stroke.fill(-2 - node, result)
            node = kernels.tabulated_budget(*args)
        if node < 0:
            return None
        y0, u, k, tail = summary[0], summary[1], summary[2], summary[3]   # indexed (iterating takes twice)
        sources = partial(_tabulated_sources, plan.sources, fast, summary)
        if self.geometry.sources:   # the point coordinates' columns join: u and k of them all, as Budget has them
            columns, contributions = self._with_geometry(plan, _Columns(sources(), np.zeros(0, dtype=np.int64),
                                                                        np.zeros(len(sign)), fast.uniform, sign,
                                                                        codes.motions),
                                                         contributions, y0, inputs)
            return Budget(self.table.outputs, columns.sources, y0, contributions, codes.motions, self.table.index,
                          columns.uniform, columns.sign)
        return Budget.summarised(self.table.outputs, sources, y0, contributions, codes.motions, self.table.index,
                                 fast.uniform, sign, u, k, tail)

    @staticmethod
    def _motion_codes(fast: _Fast, motion: Motion | Mapping[str, Motion]) -> _Motions:
        """The set of the measured cylinders' motions ``motion`` gives (one for every cylinder, or per
        cylinder name: a cylinder not named stands), built when first met."""
        moving = ((motion,) * len(fast.cylinders) if isinstance(motion, Motion)
                  else tuple(map(motion.get, fast.cylinders, repeat(_STANDING))))
        for codes in fast.motions:   # compared by identity: a Motion's hash is a Python call
            if codes.moving == moving:
                return codes
        sign = fast.sign.copy()
        sign[fast.frictions] = [FRICTION_SIGN[m] for m in moving]
        sign.flags.writeable = False
        codes = _Motions(moving, np.array([_MOTION_CODES[m] for m in moving], np.int64), sign,
                         MappingProxyType(dict(zip(fast.cylinders, moving))))
        fast.motions.append(codes)
        return codes

    def _with_geometry(self, plan: _Plan, columns: _Columns, contributions: np.ndarray, y0: np.ndarray,
                       inputs: Inputs) -> tuple[_Columns, np.ndarray]:
        """``columns`` and their ``contributions`` (n_out, n_src) with the toleranced point coordinates'
        (``geometry_budget``: their linear outputs' derivatives from its table, the others by the chain
        rule) joined last; as they are without point tolerances."""
        geometry = self.geometry
        if not geometry.sources:
            return columns, contributions
        per_point = geometry.derivatives(inputs)
        kernels.chain_rule(per_point, y0, self.table.layout)
        g = len(geometry.sources)
        joined = np.concatenate([contributions, per_point.T * geometry.scales], axis=1)
        return (_Columns(columns.sources + geometry.sources, columns.rows,
                         np.concatenate([columns.scales, geometry.scales]),
                         np.concatenate([columns.uniform, np.zeros(g, dtype=bool)]),
                         np.concatenate([columns.sign, np.zeros(g)]), columns.motions), joined)

    def _frictions(self, plan: _Plan, result: Result, motion: Motion | Mapping[str, Motion]) -> list[_Friction]:
        """The seal frictions of the pose: each force-measured cylinder's whose band is not 0, by its
        ``motion`` (one for every cylinder, or per cylinder name: a cylinder not named stands)."""
        found = []
        forces = result.cylinder_values
        for cylinder, sensor, row, seal in plan.seals:
            moving = motion if isinstance(motion, Motion) else motion.get(cylinder, Motion.STANDING)
            u = seal.standard_uncertainty(float(forces[row, 1]), moving)
            if u > 0.0:
                found.append(_Friction(cylinder, sensor, u, moving))
        return found

    def _columns(self, plan: _Plan, frictions: list[_Friction]) -> _Columns:
        """The sources of a budget as its columns: the inputs' (``plan.sources``), the seal frictions,
        the implement mass."""
        sources, rows, scales = list(plan.sources), list(plan.which), list(plan.scales)
        uniform, sign = list(plan.uniform), [0.0] * len(sources)
        for f in frictions:
            sources.append(Source(f"{f.cylinder} seal friction", f.cylinder, "friction", f.u, "N"))
            rows.append(plan.derivative[f.sensor])
            scales.append(f.u / plan.per_pascal[f.sensor])
            uniform.append(True)
            sign.append(FRICTION_SIGN[f.motion])
        if plan.mass:
            sources.append(Source("implement mass", "implement", "mass", self.sources.implement_mass, "kg"))
            rows.append(plan.load_rows.stop)
            scales.append(self.sources.implement_mass)
            uniform.append(False)
            sign.append(0.0)
        return _Columns(tuple(sources), np.array(rows, dtype=np.int64), np.array(scales), np.array(uniform, dtype=bool),
                        np.array(sign), {f.cylinder: f.motion for f in frictions})

    def _plan(self, inputs: Inputs) -> _Plan:
        """The ``_Plan`` of the input names of ``inputs`` (in their order), built once for them."""
        key = (*inputs.cylinders, None, *inputs.angles, None, *inputs.pressures)   # one tuple: ~0.2 µs less than three
        plan = self._plans.get(key)
        if plan is None:
            plan = self._plans[key] = self._new_plan(tuple(inputs.cylinders), tuple(inputs.angles),
                                                     tuple(inputs.pressures))
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
        plan = _Plan(tuple(moves), self._inputs_moved(moves), slice(0, n_pose, 2), slice(1, n_pose, 2),
                     np.array([2.0 * move.step for move in moves[:n_pose:2]]).reshape(-1, 1),
                     np.array([self.sources.sensor(move.name, move.kind).total
                               for move in moves[:n_pose:2]]).reshape(-1, 1), slice(n_pose, None),
                     slice(n_pose // 2, n_pose // 2 + len(loads)),
                     derivative,
                     tuple(sources), tuple(which), tuple(s.u for s in sources), tuple(s.uniform for s in sources),
                     friction_sensors,
                     {sensor: force_per_pressure(self.mech, sensor)
                      for sensor in friction_sensors.values() if sensor is not None},
                     tuple((c, sensor, self.model.solver.cylinder_index[c], self.sources.seal_friction(c))
                           for c, sensor in friction_sensors.items() if sensor is not None),
                     self.sources.implement_mass > 0.0 and self.mech.implement is not None)
        return self._with_stroke(plan, pressures) if self._tabulate else plan

    def _with_stroke(self, plan: _Plan, pressures: tuple[str, ...]) -> _Plan:
        """``plan`` with its stroke's table (``budget_table``) where one applies: a one-DOF linkage, every
        input of the compiled path given."""
        solver = self.model.solver
        if plan.inputs_moved is None or not one_dof(self.model) or not plan.sources:
            return plan
        measured = [(c, sensor) for c, sensor in plan.friction_sensors.items() if sensor is not None]
        level_sensors = [sensor for _, sensor in measured]
        reference = self.mech.reference_inputs.get("pressures", {})
        n_rows = plan.load_rows.stop + plan.mass
        stroke = StrokeTable(self.model, {name: float(reference.get(name, 0.0)) for name in pressures}, level_sensors,
                             n_rows, len(self.table.outputs), self._node_rows(plan))
        every = self._columns(plan, [_Friction(c, sensor, 1.0, Motion.STANDING) for c, sensor in measured])
        seals = [self.sources.seal_friction(c) for c, _ in measured]
        n_fixed = len(plan.sources)
        columns = kernels.SourceColumns(
            rows=every.rows, scales=every.scales, uniform=every.uniform,
            cylinders=np.array([solver.cylinder_index[c] for c, _ in measured], dtype=np.int64),
            friction_at=np.arange(n_fixed, n_fixed + len(measured), dtype=np.int64),
            friction_share=np.array([seal.share for seal in seals]), friction_force=np.array([seal.force for seal in seals]),
            friction_breakaway=np.array([seal.breakaway for seal in seals]),
            per_pascal=np.array([plan.per_pascal[sensor] for _, sensor in measured]),
            steer_columns=self.table.steer_columns)
        program = kernels.budget_program(fields(stroke.table), fields(columns), fields(self.table.layout),
                                         *factor_table(), NORMAL_FACTOR)
        n_out = len(self.table.outputs)
        assert len(measured) <= n_out   # the frictions' u in a row of the call's summary (a force output each)
        return replace(plan, stroke=stroke, fast=_Fast(program, every.uniform, tuple(c for c, _ in measured),
                                                       every.sources[len(every.sources) - plan.mass:], [],
                                                       (5, n_out), (n_out, len(every.uniform)), every.sign,
                                                       slice(n_fixed, n_fixed + len(measured)), [_NOTHING_GIVEN]))

    def _node_rows(self, plan: _Plan) -> RawRows:
        """The rows of a table node (``budget_table.RawRows``): ``raw_rows`` at the node's pose, the
        columns not linear in the loads 0 (the chain rule gives them per pose); None where a moved pose
        fails (NaN where the pose's own output is finite)."""
        def rows(inputs: Inputs, result: Result, machine: MachineResult) -> np.ndarray | None:
            y0 = self.table.values(result, machine)
            _, raw = self.raw_rows(inputs, result, y0, plan)
            raw[:, self.table.nonlinear] = 0.0
            return raw if np.isfinite(raw[:, np.isfinite(y0)]).all() else None
        return rows

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

    def _moved_outputs(self, inputs: Inputs, result: Result, moves: tuple[_Move | tuple[_Move, ...], ...],
                       inputs_moved: InputMoves | None) -> np.ndarray:
        """The outputs (R, n_out) of ``inputs`` moved by each of ``moves`` (``inputs_moved`` the same as
        ``Solver.solve_moved`` takes them; a move of several inputs at once, a tuple), solved from
        ``result``: in one compiled call, the poses it does not take one by one (``_solved``; NaN where
        a pose fails)."""
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
                outputs[k] = self._solved(self.model, _moved(inputs, moves[k]), result)
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

    def _heavier_outputs(self, inputs: Inputs) -> np.ndarray:
        """The outputs (n_out,) of the same inputs solved with the implement LOAD_STEP_MASS heavier."""
        if self._heavier is None:
            assert self.mech.implement is not None
            heavier = apply_overrides(self.mech, {"implement.mass": self.mech.implement.mass + LOAD_STEP_MASS})
            solver = self.model.solver
            self._heavier = MachineModel(heavier, Solver(
                heavier, dead_centre_cond=solver.dead_centre_cond, consistency_tol=solver.consistency_tol,
                dead_centre_transmission_deg=solver.dead_centre_transmission_deg))
        return self._solved(self._heavier, inputs, None)

    def _solved(self, model: MachineModel, inputs: Inputs, previous: Result | None) -> np.ndarray:
        """The outputs of ``inputs`` solved by ``model`` from ``previous``; NaN where the pose fails."""
        try:
            pose = model.solve(inputs, previous)
        except LinkageError:
            return np.full(len(self.table.outputs), math.nan)
        return self.table.values(pose.result, pose.machine)


def _tabulated_sources(fixed: tuple[Source, ...], fast: _Fast, summary: np.ndarray) -> tuple[Source, ...]:
    """The sources of a budget from the stroke's table: the inputs' (``fixed``), each measured cylinder's
    seal friction of u (N) the call's ``summary`` gives (its row 4), the implement mass."""
    return (*fixed, *(Source(f"{c} seal friction", c, "friction", f, "N")
                      for c, f in zip(fast.cylinders, summary[4, :len(fast.cylinders)].tolist())), *fast.mass)


def _moved(inputs: Inputs, move: _Move | tuple[_Move, ...]) -> Inputs:
    """``inputs`` with the ``kind`` input ``name`` of ``move`` moved by its ``step`` (of each, for several)."""
    for kind, name, step in (move,) if isinstance(move, _Move) else move:
        group = dict(getattr(inputs, kind))
        group[name] = group[name] + step
        inputs = replace(inputs, **{kind: group})
    return inputs
