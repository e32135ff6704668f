"""Machine-level results: axle loads, steerability and lift capacity, per pose and batched.

Axle loads come from the free body of the tractor (Popov 2009's moment balance about B, done on
the tractor alone so that soil forces on the implement count correctly): tractor weight at its
cg, the front ballast, and every force the linkage puts on the frame (``Result.frame_load_forces``);
the wheel traction forces act at ground level (z = 0) and have no moment about B.
SI units (m, N, kg, Pa); frame x forward, z up, origin at the rear wheels' ground contact B;
moments M = x·Fz − z·Fx (positive turns +x towards +z).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from functools import cached_property
from typing import NamedTuple, Sequence

import numpy as np

from . import kernels
from .capacity import capacity_force, capacity_points, lift_cylinder, reference_length
from .inputs import ArrayMap, Inputs
from .kinematics import KinematicState
from .model import Mechanism, Tractor
from .programs import ROW_SCALARS, MachineProgram, ValueRow
from .results import BatchResult, Status, Result
from .series import Series
from .solver import Solver

_EMPTY = np.zeros(0)
STEERABILITY_KEYS = kernels.STEERABILITY_COLUMNS   # front_axle_load, rear_axle_load, total_weight, wheelbase, ratio,
# ratio_min, margin, front_ballast_needed, ratio_unit, ratio_tractor, max_implement_mass
CAPACITY_KEYS = ("hitch_axis", "behind_610mm", "implement_cg")


@dataclass
class MachineBatch:
    """Machine-level results for N poses (arrays of shape (N,); NaN where a pose or a part failed).

    ``steerability`` keys = ``STEERABILITY_KEYS`` (N, N, N, m, -, -, -, kg, -, -, kg);
    ``lift_capacity`` keys = the capacity points (``hitch_axis``, ``behind_610mm``,
    ``implement_cg``; N, vertical load the cylinder holds at p_max·η) plus ``reserve``
    (capacity at the implement cg / present implement load, -). Empty dicts when the mechanism
    has no ``tractor`` block / no lift cylinder. Judging them against limits is the monitor's
    (monitoring.core: steerability margin < 0, lift reserve < 1).
    """

    steerability: dict[str, np.ndarray]
    lift_capacity: dict[str, np.ndarray]
    size: int   # N, the number of poses (the dicts may be empty)

    def result(self, i: int) -> "MachineResult":
        """Pose i as a :class:`MachineResult`, as ``MachineModel.evaluate`` returns it."""
        i = range(self.size)[i]   # IndexError out of range; a negative i counts from the end
        return self.results(slice(i, i + 1))[0]

    def results(self, rows: slice | np.ndarray = slice(None)) -> list["MachineResult"]:
        """The poses ``rows`` (a slice, or an index array) as :class:`MachineResult` objects, in that order
        (rows of the stacked arrays)."""
        n = len(np.arange(self.size)[rows])
        steer_keys, capacity_keys = tuple(self.steerability), tuple(self.lift_capacity)
        steer = (np.stack([v[rows] for v in self.steerability.values()], axis=1) if steer_keys
                 else np.zeros((n, 0)))
        capacity = (np.stack([v[rows] for v in self.lift_capacity.values()], axis=1) if capacity_keys
                    else np.zeros((n, 0)))
        return [MachineResult(steer[j], capacity[j], steer_keys, capacity_keys) for j in range(n)]


# built per input event: a plain dataclass, not a frozen one (docs/architecture.md, One pipeline)
@dataclass(eq=False)
class MachineResult:
    """Machine-level results of one pose: rows in the order of their keys (the dicts of
    :class:`MachineBatch` for one pose, built when first asked for; empty without a ``tractor``
    block / lift capacity)."""

    steerability_row: np.ndarray = field(default_factory=lambda: np.zeros(0))
    capacity_row: np.ndarray = field(default_factory=lambda: np.zeros(0))
    steerability_keys: tuple[str, ...] = ()
    capacity_keys: tuple[str, ...] = ()

    @cached_property
    def steerability(self) -> dict[str, float]:
        """``STEERABILITY_KEYS`` -> value (N, m, -, kg as in :class:`MachineBatch`)."""
        return dict(zip(self.steerability_keys, self.steerability_row.tolist()))

    @cached_property
    def lift_capacity(self) -> dict[str, float]:
        """Capacity points -> N, and ``reserve`` (-)."""
        return dict(zip(self.capacity_keys, self.capacity_row.tolist()))

    def value(self, key: str) -> float:
        """One value of either row by its key (e.g. ``margin``, ``reserve``); NaN when it is not computed
        (read from the row: the dicts are not built for it)."""
        for keys, row in ((self.steerability_keys, self.steerability_row), (self.capacity_keys, self.capacity_row)):
            if key in keys:
                return float(row[keys.index(key)])
        return math.nan


class MachineSeries(NamedTuple):
    """``MachineModel.solve_series``' answer: the poses, their machine-level results, their value
    rows (N, ``programs.ValueRow.width``) and which of those the compiled series wrote (N,) (the
    others are not meaningful: ``value_rows`` gives them)."""

    batch: BatchResult
    machine: MachineBatch
    values: np.ndarray
    plain: np.ndarray


class SeriesSolve:
    """``MachineModel.solve_series`` part by part (``solver.Series``): ``add`` the poses as they come (in
    another thread if need be), ``finish`` for the ``MachineSeries`` of all of them."""

    def __init__(self, model: MachineModel, series: Series) -> None:
        self._model, self._series = model, series

    def add(self, cylinders: ArrayMap, angles: ArrayMap, pressures: ArrayMap) -> None:
        """The next poses (arrays (n,)), solved now."""
        self._series.add(cylinders, angles, pressures)

    def finish(self) -> MachineSeries:
        """The ``MachineSeries`` of every pose added."""
        return self._model._machine_series(*self._series.finish())


class MachinePose(NamedTuple):
    """``MachineModel.solve``'s answer: the pose, its machine-level results and, when the compiled
    call solved it, its value row (``programs.ValueRow``, with this model's capacity and
    steerability rows; None otherwise)."""

    result: Result
    machine: MachineResult
    values: np.ndarray | None


def _summary(capacity: dict, steer: dict) -> dict:
    """The ``solve --json`` dicts: CAPACITY_KEYS / STEERABILITY_KEYS as floats (NaN → None), None when absent."""
    def pick(group: dict, keys: tuple[str, ...]) -> dict | None:
        return {k: (None if np.isnan(float(group[k])) else float(group[k])) for k in keys if k in group} if group else None

    return {"lift_capacity": pick(capacity, CAPACITY_KEYS), "steerability": pick(steer, STEERABILITY_KEYS)}


def machine_parameters(tractor: Tractor, gravity: float) -> np.ndarray:
    """The tractor's constants as ``kernels.steerability_pose`` takes them (STEERABILITY_PARAMETERS order);
    with no front ballast configured, 0 kg at the front axle (x = wheelbase)."""
    fb = tractor.front_ballast
    ballast_mass, ballast_x = (fb.mass, fb.x) if fb is not None else (0.0, tractor.wheelbase)
    return np.array([gravity, tractor.wheelbase, tractor.ratio_min, tractor.mass, tractor.cg[0], ballast_mass,
                     ballast_x, 1.0 if tractor.steerability_reference == "unit" else 0.0])


def steerability(tractor: Tractor, gravity: float, frame_load_points: np.ndarray, frame_load_forces: np.ndarray,
                 implement_load: np.ndarray, implement_x: np.ndarray) -> dict[str, np.ndarray]:
    """Axle loads and steerability (``STEERABILITY_KEYS``, arrays (N,)) of N poses from the forces the
    linkage puts ON the frame (points / forces (N, K, 2), m / N) and the implement load (N,) N at x
    (N,) m: the tractor's free body (Popov 2009's moment balance about B, done on the tractor alone so
    that soil forces on the implement count correctly; wheel traction acts at z = 0) and Popov 2009's
    steerability k = R_A / W ≥ ratio_min (formulas: ``kernels.steerability_pose``)."""
    rows = _steerability_rows(machine_parameters(tractor, gravity), frame_load_points, frame_load_forces,
                              implement_load, implement_x)
    return {k: rows[:, j] for j, k in enumerate(STEERABILITY_KEYS)}


def _steerability_rows(parameters: np.ndarray, frame_load_points: np.ndarray, frame_load_forces: np.ndarray,
                       implement_load: np.ndarray, implement_x: np.ndarray) -> np.ndarray:
    """``kernels.steerability_rows`` of N poses: (N, len(STEERABILITY_KEYS)), with the tractor's
    ``parameters`` (``machine_parameters``)."""
    return kernels.steerability_rows(
        np.ascontiguousarray(frame_load_points, dtype=float), np.ascontiguousarray(frame_load_forces, dtype=float),
        np.ascontiguousarray(implement_load, dtype=float), np.ascontiguousarray(implement_x, dtype=float), parameters)


class MachineModel:
    """Everything machine-level that depends only on the mechanism, built once.

    ``solver`` solves the present poses (its mechanism must be ``mech``). Lift capacity at each
    capacity point (``capacity_points``) comes from virtual work at the solved pose
    (``kernels.lift_capacity``: the lift cylinder at p_max·η, the implement's weight replaced by
    the unknown load at the point, the other bodies' weights and the springs as they are; loads
    and ground contacts left out: capacity is a transport-pose rating, ISO 730).
    ``lift_cylinder``: name, default the first cylinder with a ``relief_pressure``. Parts the file
    cannot support are left out: ``has_steerability`` needs a ``tractor`` block, ``has_capacity``
    an implement and a cylinder with ``relief_pressure``.
    """

    def __init__(self, mech: Mechanism, solver: Solver, lift_cylinder_name: str | None = None) -> None:
        self.mech, self.solver = mech, solver
        self._tractor = machine_parameters(mech.tractor, mech.gravity) if mech.tractor is not None else None
        self.capacity_points: dict[str, np.ndarray] = {}
        self.capacity_force = float("nan")
        self.capacity_error = ""
        # the keys of MachineResult's rows: empty for a part the mechanism does not support
        self.steerability_keys: tuple[str, ...] = STEERABILITY_KEYS if self._tractor is not None else ()
        self.capacity_keys: tuple[str, ...] = ()
        # what kernels.live_series takes to give this model's rows in the live solve (kernels.NO_MACHINE's types)
        self.program = kernels.NO_MACHINE._replace(parameters=self._tractor if self._tractor is not None else _EMPTY)
        if mech.implement is None or not any(c.relief_pressure is not None for c in mech.cylinders):
            self.capacity_error = "no implement or no cylinder with relief_pressure: lift capacity not computed"
            return
        cyl = lift_cylinder(mech, lift_cylinder_name)
        self.capacity_force = capacity_force(cyl)
        self.capacity_points = capacity_points(mech)
        kin, imp = solver.kin, mech.implement
        layout = solver.statics_layout(frozenset())
        others = kin.body_index[imp.body] != layout.mass_body   # the implement's weight is the unknown load
        all_cylinders = np.array([[kin.attach(c.base.body, c.base.point) for c in mech.cylinders],
                                  [kin.attach(c.rod_end.body, c.rod_end.point) for c in mech.cylinders]],
                                 dtype=np.int64)
        point_att = np.array([kin.attach(imp.body, f"capacity point {k}", pt) for k, pt in self.capacity_points.items()],
                             dtype=np.int64)
        self._layout = layout
        self.capacity_keys = (*self.capacity_points, "reserve")
        self._cg_column = list(self.capacity_points).index("implement_cg")
        self._no_spring_force = np.zeros((1, 0))   # spring_force of a mechanism without springs (never indexed)
        lift = [c.name for c in mech.cylinders].index(cyl.name)
        weight_att, weight_mass = layout.mass_att[others], layout.mass[others]
        self._spring_att = layout.member_att[:, :layout.n_springs].copy()   # (2, n_springs): the springs' ends
        self.program = MachineProgram(
            parameters=self.program.parameters, hinge_att=np.ascontiguousarray(kin.hinge_att, dtype=np.int64),
            cylinder_att=all_cylinders, lift=lift, lift_force=float(self.capacity_force), gravity=float(mech.gravity),
            weight_att=weight_att.astype(np.int64), weight_mass=weight_mass.astype(float), point_att=point_att,
            cg_point=self._cg_column)

    @property
    def has_steerability(self) -> bool:
        """True when axle loads and steerability are computed (the file has a ``tractor`` block)."""
        return self._tractor is not None

    @property
    def has_capacity(self) -> bool:
        """True when lift capacity is computed (implement and a cylinder with relief_pressure)."""
        return bool(self.capacity_points)

    def value_rows(self, results: Sequence[Result], machines: Sequence[MachineResult]) -> np.ndarray:
        """The value rows (N, width) of N solved poses of ``self.solver`` with their machine-level
        results (``programs.ValueRow``, as the compiled call writes them; NaN for a part a pose lacks)."""
        solver = self.solver
        row = ValueRow.of(len(solver.names.hinges), len(solver.names.points), len(solver.names.cylinders),
                          len(self.capacity_keys), len(self.steerability_keys))
        no_capacity, no_steerability = np.full(len(self.capacity_keys), math.nan), np.full(len(self.steerability_keys),
                                                                                          math.nan)
        return kernels.pack_rows(
            _stacked([r.hinge_force for r in results]), _stacked([r.point_xz for r in results]),
            _stacked([r.cylinder_values for r in results]),
            np.array([[getattr(r, name) for name in ROW_SCALARS] for r in results]).reshape(len(results), -1),
            _stacked([r.implement_cg for r in results]),
            _stacked([m.capacity_row if m.capacity_row.size else no_capacity for m in machines]),
            _stacked([m.steerability_row if m.steerability_row.size else no_steerability for m in machines]), row.width)

    # ---- batched (replay, capacity curve) and one pose (the node) ------------------------------
    def evaluate_batch(self, batch: BatchResult) -> MachineBatch:
        """Axle loads, steerability and lift capacity for every pose of ``batch`` (from ``self.solver``)."""
        return self._batch_of(*self._batch_rows(batch, slice(None)), len(batch))

    def solve(self, inputs: Inputs, previous: Result | None = None) -> MachinePose:
        """One pose (``Solver.solve``, warm-started from ``previous``) with its machine-level results,
        the usual live pose in one compiled call (``Solver.solve_with_machine``); raises as ``solve``."""
        solved = self.solver.solve_with_machine(inputs, previous, self.program)
        if solved.steerability is None or solved.capacity is None:
            return MachinePose(solved.result, self.evaluate(solved.result), None)
        return MachinePose(solved.result, MachineResult(solved.steerability, solved.capacity, self.steerability_keys,
                                                        self.capacity_keys), solved.values)

    def solve_series(self, cylinders: ArrayMap, angles: ArrayMap, pressures: ArrayMap) -> MachineSeries:
        """A recorded series of poses as the live node solves them, with their machine-level results
        (``Solver.solve_series``; replay): as ``solve_batch`` + ``evaluate_batch`` would give them,
        and the value rows of the poses the compiled series solved. ``series`` solves them in parts."""
        series = self.series()
        series.add(cylinders, angles, pressures)
        return series.finish()

    def series(self) -> SeriesSolve:
        """A ``SeriesSolve``: ``solve_series`` part by part as the inputs come."""
        return SeriesSolve(self, self.solver.series(self.program))

    def _machine_series(self, batch: BatchResult, steer: np.ndarray, capacity: np.ndarray, values: np.ndarray,
                        plain: np.ndarray) -> MachineSeries:
        """``solve_series``' answer from ``Solver.solve_series``': the general path's poses' machine-level rows
        computed (``evaluate_batch``'s)."""
        general = np.flatnonzero(~plain)
        if general.size:
            steer_rows, capacity_rows = self._batch_rows(batch, general)
            if steer_rows is not None:
                steer[general] = steer_rows
            if capacity_rows is not None:
                capacity[general] = capacity_rows
        return MachineSeries(batch, self._batch_of(steer if self.steerability_keys else None,
                                                   capacity if self.capacity_keys else None, len(batch)), values, plain)

    def evaluate(self, result: Result) -> MachineResult:
        """Machine-level results of one solved pose (a ``Result`` of ``self.solver``)."""
        state = result.state
        q = (state.q[-1:] if isinstance(state, KinematicState)   # the live solve's pose, as solved
             else result.body_q.reshape(1, -1))
        steer, capacity = self._rows(q, np.isfinite(q).all(axis=1), result.frame_load_points[None],
                                     result.frame_load_forces[None], np.array([result.implement_load]),
                                     result.implement_cg[:1])
        return MachineResult(steer[0] if steer is not None else _EMPTY, capacity[0] if capacity is not None else _EMPTY,
                             self.steerability_keys, self.capacity_keys)

    def _capacity(self, q: np.ndarray, ok: np.ndarray, implement_load: np.ndarray) -> np.ndarray:
        """Lift capacity (N) at each capacity point for the solved poses q (N, n) (virtual work,
        ``kernels.lift_capacity``), then the lift reserve (capacity at the implement cg / implement
        load (N,) N): (N, len(capacity points) + 1) in ``capacity_keys`` order. NaN where not ``ok``
        (failed), where the motion is at a dead centre, or at a point that the cylinder pushing at
        p_max lowers instead of lifting (e.g. the front axle of Akhmetov & Usmanov 2018's base-change
        parallelogram: no lift capacity, not a negative load)."""
        kin = self.solver.kin
        q = np.ascontiguousarray(q, dtype=float)
        spring_force = self._layout.spring_forces(kin.positions(q)[0]) if self._layout.n_springs else \
            self._no_spring_force
        return kernels.lift_capacity(q, kin.program, self.program, spring_att=self._spring_att,
                                     spring_force=spring_force, max_condition=self.solver.dead_centre_cond,
                                     ok=np.ascontiguousarray(ok, dtype=np.bool_),
                                     implement_load=np.ascontiguousarray(implement_load, dtype=float))

    def _batch_rows(self, batch: BatchResult, index: "slice | np.ndarray") -> tuple[np.ndarray | None,
                                                                                  np.ndarray | None]:
        """``_rows`` of the poses ``index`` of ``batch`` (failed ones NaN)."""
        q = np.concatenate([batch.body_poses[b.name][index] for b in self.mech.moving_bodies], axis=1)
        ok = (batch.status[index] < Status.INPUT) & np.isfinite(q).all(axis=1)
        return self._rows(q, ok, batch.frame_load_points[index], batch.frame_load_forces[index],
                          batch.implement_load[index], batch.implement_cg[index, 0])

    def _batch_of(self, steer: np.ndarray | None, capacity: np.ndarray | None, size: int) -> MachineBatch:
        """A :class:`MachineBatch` (a column per key) of rows (N, keys); None for a part not computed."""
        return MachineBatch({k: steer[:, j] for j, k in enumerate(self.steerability_keys)} if steer is not None else {},
                            {k: capacity[:, j] for j, k in enumerate(self.capacity_keys)} if capacity is not None
                            else {}, size)

    def _rows(self, q: np.ndarray, ok: np.ndarray, frame_load_points: np.ndarray, frame_load_forces: np.ndarray,
              implement_load: np.ndarray, implement_x: np.ndarray) -> tuple[np.ndarray | None, np.ndarray | None]:
        """Steerability from the frame loads (N, len(STEERABILITY_KEYS)), lift capacity at the poses
        q (N, n) where ``ok`` and the lift reserve (N, len(capacity points) + 1); None for a part the
        mechanism does not support."""
        steer = (_steerability_rows(self._tractor, frame_load_points, frame_load_forces, implement_load, implement_x)
                 if self._tractor is not None else None)
        return steer, self._capacity(q, ok, implement_load) if self.has_capacity else None

    def stroke_poses(self, cylinder: str, lengths: np.ndarray) -> BatchResult:
        """Transport poses with ``cylinder`` at ``lengths`` (m), solved batched by ``self.solver``.

        ``self.solver`` must be driven by cylinder lengths only (``capacity.stroke_mechanism``); other
        measured cylinders stay at their reference length; no pressures are given, so the implement
        load is its configured weight.
        """
        held = {c: reference_length(self.mech, c) for c in self.mech.measurements.cylinders if c != cylinder}
        return self.solver.solve_batch(cylinders={**held, cylinder: np.asarray(lengths, dtype=float)})

    def capacity_curve(self, cylinder: str, lengths: np.ndarray) -> tuple[BatchResult, MachineBatch]:
        """Transport poses over a stroke (``stroke_poses``) and their machine-level results (batched)."""
        batch = self.stroke_poses(cylinder, lengths)
        return batch, self.evaluate_batch(batch)


def machine_summary(solver: Solver, result: Result, model: MachineModel | None = None) -> dict:
    """``{"lift_capacity": {hitch_axis, behind_610mm, implement_cg} N | None, "steerability": {STEERABILITY_KEYS} | None}``
    for ``linkage-monitor solve --json`` (NaN → None). Pass ``model`` to reuse a built MachineModel."""
    model = model or MachineModel(solver.mech, solver)
    res = model.evaluate(result)
    return _summary(res.lift_capacity, res.steerability)


def _stacked(arrays: list[np.ndarray]) -> np.ndarray:
    """The arrays stacked along a new first axis (one pose: a view)."""
    return arrays[0][None] if len(arrays) == 1 else np.stack(arrays)
