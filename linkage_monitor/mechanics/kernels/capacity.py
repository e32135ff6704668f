"""Lift capacity by virtual work (Popov 2009): the vertical load the lift cylinder holds at each
capacity point, and the lift reserve."""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba import njit, prange

from ..programs import KinematicsProgram, MachineProgram
from .closure import positions, residual_jacobian
from .linalg import factor_and_condition, lu_solve
from .threads import _parallel


class CapacityJob(NamedTuple):
    """A batch of ``lift_capacity`` (``_capacity_pose``): what it writes — the capacity rows (N,
    n_points + 1) N, NaN on entry —, the poses q (N, n) of the mechanism's attachments (att_body,
    att_ref: ``Geometry``) with the column scale of their Jacobian, which of them are solved (ok
    (N,)), their implement load (N,) N, the springs' ends (2, n_springs) and forces (N, n_springs)
    N, the dead-centre condition number, and whether the capacity's system is square."""

    out: np.ndarray
    q: np.ndarray
    att_body: np.ndarray
    att_ref: np.ndarray
    column_scale: np.ndarray
    ok: np.ndarray
    implement_load: np.ndarray
    spring_att: np.ndarray
    spring_force: np.ndarray
    max_condition: float
    square: bool


def lift_capacity(q: np.ndarray, kin: KinematicsProgram, machine: MachineProgram, spring_att: np.ndarray,
                  spring_force: np.ndarray, max_condition: float, ok: np.ndarray, implement_load: np.ndarray
                  ) -> np.ndarray:
    """Vertical load (N, + = down) that the lift cylinder ``machine.lift`` pushing with
    ``machine.lift_force`` (N) holds at each capacity point (attachments ``machine.point_att``), for
    N poses q (N, n) of the mechanism ``kin`` (``Kinematics.program``: its attachments and column
    scale): virtual work along the motion with every hinge closed, every other cylinder held at its
    length and the lift cylinder extending by δs:

        G·δz_point = F·δs − Σ m·g·δz_cg + Σ F_spring·δL_spring        (Popov 2009: G = p_max·η·A·ds/dz)

    (weights m at ``machine.weight_att``, spring forces (N, n_springs) + = pushing at the ends
    ``spring_att`` (2, n_springs)). The motion δq solves [hinge rows; cylinder rows]·δq = e_lift,
    one factorization per pose for every point.

    Returns (N, n_points + 1): G at each point, NaN where the pose is not ``ok`` (failed), where
    that system is near-singular (condition > ``max_condition``: a dead centre) or not square, and
    where G ≤ 0 (the cylinder lowers the point instead of lifting it: no capacity, not a negative
    load); then the lift reserve, G at point ``machine.cg_point`` / ``implement_load`` (N,) N, inf
    where that load is not > 0.
    """
    n_pose, n = q.shape
    job = CapacityJob(out=np.full((n_pose, machine.point_att.shape[0] + 1), np.nan), q=q, att_body=kin.att_body,
                      att_ref=kin.att_ref, column_scale=kin.column_scale, ok=ok, implement_load=implement_load,
                      spring_att=spring_att, spring_force=spring_force, max_condition=float(max_condition),
                      square=bool(2 * machine.hinge_att.shape[1] + machine.cylinder_att.shape[1] == n))
    (_capacity_parallel if _parallel(n_pose) else _capacity_serial)(n_pose, job, machine)
    return job.out


@njit(cache=True)
def _capacity_pose(i, job: CapacityJob, machine: MachineProgram):
    """Pose i of ``lift_capacity``, written into the job's rows (NaN on entry)."""
    if job.ok[i] and job.square:
        _capacity_points(i, job, machine)
    _reserve(job.out[i], machine.cg_point, job.implement_load[i])


@njit(cache=True)
def _reserve(row, cg_point, load):
    """The lift reserve, the capacity row's last value: the capacity at the implement's cg (its
    ``cg_point``-th value) over the implement load ``load`` (N; ∞ without a load)."""
    row[-1] = row[cg_point] / load if load > 0.0 else math.inf


@njit(cache=True)
def _capacity_points(i, job: CapacityJob, machine: MachineProgram):
    """G at each point of pose i (``lift_capacity``), written into the job's rows where > 0."""
    out, q, att_body, att_ref = job.out, job.q, job.att_body, job.att_ref
    hinge_att, cyl_att, gravity, weight_att = machine.hinge_att, machine.cylinder_att, machine.gravity, machine.weight_att
    spring_att, spring_force, point_att = job.spring_att, job.spring_force, machine.point_att
    n = q.shape[1]
    nh, nc = hinge_att.shape[1], cyl_att.shape[1]
    _, jac = residual_jacobian(q[i], np.zeros(nc), att_body, att_ref, hinge_att, cyl_att,
                               np.zeros((2, 0), dtype=np.int64), np.zeros(0), 1.0)
    lu, piv, cond = factor_and_condition(jac * job.column_scale)   # square: ``condition``'s, and its LU for δq
    if not cond <= job.max_condition:
        return
    e = np.zeros(n)
    e[2 * nh + machine.lift] = 1.0
    dq = lu_solve(lu, piv, e) * job.column_scale   # (J·diag(scale))·(δq / scale) = e
    p, rel = positions(q[i], att_body, att_ref)
    work = machine.lift_force
    for k in range(weight_att.shape[0]):
        work -= machine.weight_mass[k] * gravity * _dp(dq, weight_att[k], att_body, rel)[1]
    for k in range(spring_att.shape[1]):
        a, b = spring_att[0, k], spring_att[1, k]
        dx, dz = p[b, 0] - p[a, 0], p[b, 1] - p[a, 1]
        da = _dp(dq, a, att_body, rel)
        db = _dp(dq, b, att_body, rel)
        work += spring_force[i, k] * (dx * (db[0] - da[0]) + dz * (db[1] - da[1])) / math.sqrt(dx * dx + dz * dz)
    for k in range(point_att.shape[0]):
        g = work / _dp(dq, point_att[k], att_body, rel)[1]
        if g > 0.0:
            out[i, k] = g


@njit(cache=True)
def _dp(dq: np.ndarray, att: int, att_body: np.ndarray, rel: np.ndarray) -> tuple[float, float]:
    """Displacement (δx, δz) of an attachment for the body motion dq (∂P/∂θ = i·rel)."""
    b = att_body[att]
    if b < 0:
        return 0.0, 0.0
    return dq[3 * b] - rel[att, 1] * dq[3 * b + 2], dq[3 * b + 1] + rel[att, 0] * dq[3 * b + 2]


# a pair per kernel, as assembly's (why: there)
@njit(cache=True)
def _capacity_serial(n_pose: int, job: CapacityJob, machine: MachineProgram) -> None:
    for i in range(n_pose):
        _capacity_pose(i, job, machine)


@njit(cache=True, parallel=True)
def _capacity_parallel(n_pose: int, job: CapacityJob, machine: MachineProgram) -> None:
    for i in prange(n_pose):
        _capacity_pose(i, job, machine)
