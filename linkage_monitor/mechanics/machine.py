"""Machine-level results: axle loads, steerability and lift capacity, per pose and batched.

Axle loads come from the free body of the tractor (seed 003's moment balance about B, done on
the tractor alone so that soil forces on the implement count correctly): tractor weight at its
cg, the front ballast, and every force the linkage puts on the frame (``Result.frame_loads``);
the wheel traction forces act at ground level (z = 0) and have no moment about B.
SI units (m, N, kg, Pa); frame x forward, z up, origin at the rear wheels' ground contact B;
moments M = x·Fz − z·Fx (positive turns +x towards +z).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from . import kernels
from .capacity import capacity_force, capacity_points, lift_cylinder, reference_length
from .model import Mechanism, Tractor
from .results import BatchResult, Status, Result
from .solver import Solver

STEERABILITY_KEYS = ("front_axle_load", "rear_axle_load", "total_weight", "wheelbase", "ratio", "ratio_min",
                     "margin", "front_ballast_needed", "ratio_unit", "ratio_tractor", "max_implement_mass")
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

    def result(self, i: int) -> "MachineResult":
        """Pose i as a :class:`MachineResult` (floats), as ``MachineModel.evaluate`` returns it."""
        return MachineResult({k: float(v[i]) for k, v in self.steerability.items()},
                             {k: float(v[i]) for k, v in self.lift_capacity.items()})


@dataclass(frozen=True)
class MachineResult:
    """Machine-level results of one pose: dicts as in :class:`MachineBatch` (floats)."""

    steerability: dict[str, float] = field(default_factory=dict)
    lift_capacity: dict[str, float] = field(default_factory=dict)


def _summary(capacity: dict, steer: dict) -> dict:
    """The ``solve --json`` dicts: CAPACITY_KEYS / STEERABILITY_KEYS as floats (NaN → None), None when absent."""
    def pick(group: dict, keys: tuple[str, ...]) -> dict | None:
        return {k: (None if np.isnan(float(group[k])) else float(group[k])) for k in keys if k in group} if group else None

    return {"lift_capacity": pick(capacity, CAPACITY_KEYS), "steerability": pick(steer, STEERABILITY_KEYS)}


def axle_loads(tractor: Tractor, gravity: float, frame_load_points: np.ndarray,
               frame_load_forces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Front and rear axle loads (N, + = ground pushes up), shape (N,), from the tractor's free body.

    frame_load_points / _forces (N, K, 2): m / N, forces the linkage puts ON the frame. Moment
    balance about B: L·R_A − m_tr·g·x_tr − m_cw·g·x_cw + Σ(x·Fz − z·Fx) = 0 (seed 003's balance,
    applied to the tractor alone); vertical balance gives R_B.
    """
    g, L = gravity, tractor.wheelbase
    ballast_mass, ballast_x = _ballast(tractor)
    moment = np.sum(frame_load_points[..., 0] * frame_load_forces[..., 1]
                    - frame_load_points[..., 1] * frame_load_forces[..., 0], axis=-1)
    front = (tractor.mass * g * tractor.cg[0] + ballast_mass * g * ballast_x - moment) / L
    rear = (tractor.mass + ballast_mass) * g - np.sum(frame_load_forces[..., 1], axis=-1) - front
    return front, rear


def _ballast(tractor: Tractor) -> tuple[float, float]:
    """Front ballast mass (kg) and x (m); with none configured, 0 kg at the front axle (x = wheelbase)."""
    fb = tractor.front_ballast
    return (fb.mass, fb.x) if fb is not None else (0.0, tractor.wheelbase)


def steerability(tractor: Tractor, gravity: float, front: np.ndarray, rear: np.ndarray,
                 implement_load: np.ndarray, implement_x: np.ndarray) -> dict[str, np.ndarray]:
    """Steerability quantities (``STEERABILITY_KEYS``) from the axle loads (N) and the implement load (N) at x (m).

    seed 003: k = R_A / W ≥ ratio_min with W the unit's weight on the wheels (R_A + R_B; in
    transport = P_tr + P_cw + P_6) or the empty tractor's weight (``steerability_reference``).
    By global equilibrium R_A grows by g·x/L per kg at x, so (with c = 1 for the unit, 0 for the
    tractor reference, as W then does not change): front ballast for k = ratio_min
    m_cw = m_cw0 + (r·W − R_A)/(g·(x_cw/L − r·c)); largest implement mass
    m_6 = P_6/g + (R_A − r·W)/(g·(r·c − x_S6/L)) (inf if the denominator is ≤ 0).
    """
    g, L, r = gravity, tractor.wheelbase, tractor.ratio_min
    total = front + rear
    tractor_weight = tractor.mass * g
    ratio_unit, ratio_tractor = front / total, front / tractor_weight
    unit = tractor.steerability_reference == "unit"
    ref_weight, c = (total, 1.0) if unit else (np.full_like(front, tractor_weight), 0.0)
    ratio = ratio_unit if unit else ratio_tractor
    ballast_mass, ballast_x = _ballast(tractor)
    with np.errstate(divide="ignore", invalid="ignore"):
        ballast_slope = g * (ballast_x / L - r * c)
        ballast = np.where(ballast_slope > 0.0, np.maximum(0.0, ballast_mass + (r * ref_weight - front) / ballast_slope),
                           np.inf)
        implement_slope = g * (r * c - implement_x / L)
        max_mass = np.where(implement_slope > 0.0,
                            np.maximum(0.0, implement_load / g + (front - r * ref_weight) / implement_slope), np.inf)
    return {"front_axle_load": front, "rear_axle_load": rear, "total_weight": total,
            "wheelbase": np.full_like(front, L), "ratio": ratio, "ratio_min": np.full_like(front, r),
            "margin": ratio - r, "front_ballast_needed": ballast, "ratio_unit": ratio_unit,
            "ratio_tractor": ratio_tractor, "max_implement_mass": max_mass}


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
        self.has_steerability = mech.tractor is not None
        self.capacity_points: dict[str, np.ndarray] = {}
        self.capacity_force = float("nan")
        self.capacity_error = ""
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
        self._capacity_args = (kin.hinge_att, all_cylinders, [c.name for c in mech.cylinders].index(cyl.name),
                               self.capacity_force, mech.gravity, layout.mass_att[others], layout.mass[others],
                               layout.member_att[:, :layout.n_springs].copy(), point_att)

    @property
    def has_capacity(self) -> bool:
        """True when lift capacity is computed (implement and a cylinder with relief_pressure)."""
        return bool(self.capacity_points)

    # ---- batched (replay, capacity curve) and one pose (the node) ------------------------------
    def evaluate_batch(self, batch: BatchResult) -> MachineBatch:
        """Axle loads, steerability and lift capacity for every pose of ``batch`` (from ``self.solver``)."""
        return self._combine(batch, self._capacity(batch) if self.has_capacity else {})

    def evaluate(self, result: Result) -> MachineResult:
        """Machine-level results of one solved pose (a ``Result`` of ``self.solver``)."""
        return self.evaluate_batch(_as_batch(result, self.solver.frame_load_names)).result(0)

    def _capacity(self, batch: BatchResult) -> dict[str, np.ndarray]:
        """Lift capacity (N) at each capacity point for the solved poses of ``batch`` (virtual work,
        ``kernels.lift_capacity``); NaN where the pose failed or the motion is at a dead centre."""
        kin = self.solver.kin
        q = np.concatenate([batch.body_poses[b.name] for b in self.mech.moving_bodies], axis=1)
        ok = (batch.status < Status.INPUT) & np.isfinite(q).all(axis=1)
        q = np.ascontiguousarray(np.where(ok[:, None], q, kin.q_ref))   # failed poses: solved anywhere, masked below
        hinge_att, cylinder_att, lift, force, gravity, weight_att, weight_mass, spring_att, point_att = self._capacity_args
        spring_force = self._layout.spring_forces(kin.positions(q)[0]) if self._layout.n_springs else \
            np.zeros((len(q), 0))
        att_body, att_ref = kin.geometry[:2]
        g = kernels.lift_capacity(q, att_body, att_ref, hinge_att, cylinder_att, lift, force, gravity, weight_att,
                                  weight_mass, spring_att, spring_force, point_att, kin.column_scale,
                                  self.solver.dead_centre_cond)
        return {name: np.where(ok, g[:, k], np.nan) for k, name in enumerate(self.capacity_points)}

    def _combine(self, batch: BatchResult, capacity: dict[str, np.ndarray]) -> MachineBatch:
        """Steerability from the frame loads and the lift reserve from the capacity."""
        mech = self.mech
        steer: dict[str, np.ndarray] = {}
        if self.has_steerability and mech.tractor is not None:
            front, rear = axle_loads(mech.tractor, mech.gravity, batch.frame_load_points, batch.frame_load_forces)
            steer = steerability(mech.tractor, mech.gravity, front, rear, batch.implement_load, batch.implement_cg[:, 0])
        if capacity:
            # A point that the cylinder pushing at p_max lowers instead of lifting (e.g. the front
            # axle of seed 001's base-change parallelogram) has no lift capacity: NaN, not a negative load.
            capacity = {k: np.where(v > 0.0, v, np.nan) for k, v in capacity.items()}
            with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
                capacity["reserve"] = np.where(batch.implement_load > 0.0,
                                               capacity["implement_cg"] / batch.implement_load, np.inf)
        return MachineBatch(steer, capacity)

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


def _as_batch(result: Result, frame_load_names: list[str]) -> BatchResult:
    """A one-pose BatchResult view of ``result`` with the fields machine-level results read."""
    points = np.array([p for p, _ in result.frame_loads]).reshape(1, -1, 2)
    forces = np.array([f for _, f in result.frame_loads]).reshape(1, -1, 2)
    one = lambda v: np.array([v])  # noqa: E731
    return BatchResult(
        points={}, body_poses={k: v[None] for k, v in result.body_poses.items()}, hinge_force={}, hinge_bodies={},
        cylinder_length={k: one(c.length) for k, c in result.cylinders.items()}, cylinder_force={},
        cap_pressure_predicted={}, cap_pressure_measured={}, rod_pressure_measured={}, contact_normal={},
        contact_tangential={}, implement_load=one(result.implement_load), implement_cg=result.implement_cg[None],
        frame_load_names=list(frame_load_names), frame_load_points=points, frame_load_forces=forces,
        residual=one(result.residual), consistency_residual=one(result.consistency_residual),
        condition=one(result.condition), status=np.zeros(1, dtype=int), messages=[""])


def machine_summary(solver: Solver, result: Result, model: MachineModel | None = None) -> dict:
    """``{"lift_capacity": {hitch_axis, behind_610mm, implement_cg} N | None, "steerability": {STEERABILITY_KEYS} | None}``
    for ``linkage-monitor solve --json`` (NaN → None). Pass ``model`` to reuse a built MachineModel."""
    model = model or MachineModel(solver.mech, solver)
    res = model.evaluate(result)
    return _summary(res.lift_capacity, res.steerability)
