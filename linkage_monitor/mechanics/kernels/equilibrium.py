"""Equilibrium of every moving body of a pose in one linear system A·u + b = 0 (the general
statics): rows ΣFx, ΣFz, ΣM/lc per body; known loads, member forces along their axes, and in
kinetostatics the inertia loads (Naumenko et al. 2021)."""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba import njit, prange

from ..programs import StaticsProgram
from .linalg import factor_and_condition, gram, lu_solve
from .threads import _parallel


@njit(cache=True)
def _add_generalized(vec: np.ndarray, row0: int, px: float, pz: float, fx: float, fz: float, lc: float) -> None:
    """Add [Fx, Fz, (x·Fz − z·Fx)/lc] of a force (fx, fz) N at (px, pz) m to vec[row0:row0+3]."""
    vec[row0] += fx
    vec[row0 + 1] += fz
    vec[row0 + 2] += (px * fz - pz * fx) / lc


@njit(cache=True)
def equilibrium_matrix(p: np.ndarray, axes: np.ndarray, lc: float, n_eq: int, n_unknowns: int, t_col: np.ndarray,
                       t_att: np.ndarray, t_body: np.ndarray, t_const: np.ndarray, t_member: np.ndarray,
                       t_sign: np.ndarray) -> np.ndarray:
    """Equilibrium matrix A (n_eq, n_unknowns) of one pose: attachment positions p (K, 2) m, member
    axes (M, 2); column term t is a unit force (t_const, or t_sign times the axis of member
    t_member ≥ 0) at attachment t_att on body t_body, in column t_col."""
    a_mat = np.zeros((n_eq, n_unknowns))
    col = np.zeros(3)
    for t in range(t_col.shape[0]):
        fx, fz = _term_force(t, axes, t_const, t_member, t_sign)
        col[:] = 0.0
        _add_generalized(col, 0, p[t_att[t], 0], p[t_att[t], 1], fx, fz, lc)
        for j in range(3):
            a_mat[3 * t_body[t] + j, t_col[t]] += col[j]
    return a_mat


@njit(cache=True)
def _term_force(t: int, axes: np.ndarray, t_const: np.ndarray, t_member: np.ndarray, t_sign: np.ndarray
                ) -> tuple[float, float]:
    """The force (N per unit of its column's unknown) of column term t: t_sign times the axis of
    member t_member ≥ 0, else t_const."""
    if t_member[t] >= 0:
        return t_sign[t] * axes[t_member[t], 0], t_sign[t] * axes[t_member[t], 1]
    return t_const[t, 0], t_const[t, 1]


# The loads' fields stand again in reduced.ReducedJob: a record holding a record cannot enter numba's parallel
# loop, and the reduced statics write the transmission where these write the condition number.
class StaticsJob(NamedTuple):
    """A batch of ``solve_statics`` (``_statics_pose``): what it writes — u (N, n_unknowns), the
    residual (N,) N, the condition number (N,), member axes (N, M, 2) and lengths (N, M) m —, and
    the loads it balances: positions p (N, K, 2) m, member forces (N, M) N, with ``has_accel`` the
    cg accelerations (N, n_mass, 2) m/s² and angular accelerations (N, n_mass) rad/s².
    ``reduced.ReducedJob`` writes the transmission in place of the condition number, from the same
    loads."""

    u: np.ndarray
    residual: np.ndarray
    condition: np.ndarray
    axes: np.ndarray
    lengths: np.ndarray
    p: np.ndarray
    member_force: np.ndarray
    accel: np.ndarray
    alpha: np.ndarray
    has_accel: bool


def solve_statics(p: np.ndarray, member_force: np.ndarray, accel: np.ndarray, alpha: np.ndarray,
                  has_accel: bool, n_unknowns: int, layout: StaticsProgram) -> tuple[np.ndarray, ...]:
    """Equilibrium of every moving body for N poses: unknowns u (N, n_unknowns) with A·u + b = 0.

    p (N, K, 2): attachment positions, m. member_force (N, M): force of springs then cylinders, N
    (+ = pushing; the unknown members' entries are ignored). accel (N, n_mass, 2), alpha (N, n_mass):
    acceleration (m/s²) of each body's cg and its angular acceleration (rad/s²) when ``has_accel``.
    ``layout`` (``StaticsLayout.program``): lc, n_eq; column terms t — a unit force (t_const, or
    t_sign times the axis of member t_member ≥ 0) at attachment t_att on body t_body in column
    t_col; known loads — const_force at the first known attachments (known_att, known_body), then
    the member ends (end_sign · force · axis of end_member), then (kinetostatics) −m·a at each cg
    (mass_att, mass_body, mass) and −I·α about it (inertia); member_att (2, M): the members' ends.
    More equations than unknowns: least squares (normal equations).

    Returns u, the equilibrium residual |A·u + b| (N,) N (moment rows × lc), the condition number
    (N,) (1-norm; square root of that of AᵀA when least squares), member unit axes (N, M, 2) from
    end a to end b and member lengths (N, M) m.
    """
    n_pose = p.shape[0]
    n_members = member_force.shape[1]
    job = StaticsJob(u=np.empty((n_pose, n_unknowns)), residual=np.empty(n_pose), condition=np.empty(n_pose),
                     axes=np.empty((n_pose, n_members, 2)), lengths=np.empty((n_pose, n_members)), p=p,
                     member_force=member_force, accel=accel, alpha=alpha, has_accel=bool(has_accel))
    (_statics_parallel if _parallel(n_pose) else _statics_serial)(n_pose, job, layout)
    return job.u, job.residual, job.condition, job.axes, job.lengths


@njit(cache=True)
def _statics_pose(i, job: StaticsJob, layout: StaticsProgram):
    """Pose i of ``solve_statics``, written into the job's outputs."""
    u_out, p, axes = job.u, job.p, job.axes
    n_unknowns = u_out.shape[1]
    lc, n_eq = layout.lc, layout.n_eq
    _member_axes(i, axes, job.lengths, p, layout.member_att)
    a_mat = equilibrium_matrix(p[i], axes[i], lc, n_eq, n_unknowns, layout.t_col, layout.t_att, layout.t_body,
                               layout.t_const, layout.t_member, layout.t_sign)
    b = np.zeros(n_eq)
    _known_loads(b, i, job, layout)
    if n_unknowns == n_eq:
        lu, piv, c = factor_and_condition(a_mat)
        u = -lu_solve(lu, piv, b) if math.isfinite(c) else np.full(n_unknowns, np.nan)
    else:
        lu, piv, c = factor_and_condition(gram(a_mat))
        u = -lu_solve(lu, piv, a_mat.T @ b) if math.isfinite(c) else np.full(n_unknowns, np.nan)
        c = math.sqrt(c)
    res = a_mat @ u + b
    acc = 0.0
    for r in range(n_eq):
        v = res[r] * lc if r % 3 == 2 else res[r]
        acc += v * v
    u_out[i] = u
    job.residual[i] = math.sqrt(acc)
    job.condition[i] = c


@njit(cache=True)
def _member_axes(i: int, axes: np.ndarray, lengths: np.ndarray, p: np.ndarray, member_att: np.ndarray) -> None:
    """Unit axes (from end a to end b) and lengths (m) of the members (springs then cylinders) of pose i."""
    for k in range(member_att.shape[1]):
        a, b = member_att[0, k], member_att[1, k]
        dx, dz = p[i, b, 0] - p[i, a, 0], p[i, b, 1] - p[i, a, 1]
        length = math.sqrt(dx * dx + dz * dz)
        lengths[i, k] = length
        axes[i, k, 0], axes[i, k, 1] = dx / length, dz / length


@njit(cache=True)
def _known_loads(b: np.ndarray, i: int, job, layout: StaticsProgram) -> None:
    """The known loads of pose i of ``job`` (a ``StaticsJob`` or ``reduced.ReducedJob``: its
    positions, member axes and forces, accelerations) as generalized forces into b (n_eq,) ([Fx,
    Fz, M/lc] per body, ``solve_statics``' layout): constant loads, the ends of members of known
    force, and with ``has_accel`` the inertia loads −m·a at each cg and −I·α (Naumenko et al. 2021)."""
    p, axes, member_force, accel, alpha = job.p, job.axes, job.member_force, job.accel, job.alpha
    lc, const_force, known_att, known_body = layout.lc, layout.const_force, layout.known_att, layout.known_body
    end_member, end_sign, mass_att, mass_body = layout.end_member, layout.end_sign, layout.mass_att, layout.mass_body
    mass, inertia = layout.mass, layout.inertia
    n_const = const_force.shape[0]
    for k in range(n_const):
        att = known_att[k]
        _add_generalized(b, 3 * known_body[k], p[i, att, 0], p[i, att, 1], const_force[k, 0], const_force[k, 1], lc)
    for e in range(end_member.shape[0]):
        att = known_att[n_const + e]
        f = end_sign[e] * member_force[i, end_member[e]]
        _add_generalized(b, 3 * known_body[n_const + e], p[i, att, 0], p[i, att, 1],
                         f * axes[i, end_member[e], 0], f * axes[i, end_member[e], 1], lc)
    if job.has_accel:
        for k in range(mass_att.shape[0]):
            att = mass_att[k]
            _add_generalized(b, 3 * mass_body[k], p[i, att, 0], p[i, att, 1], -mass[k] * accel[i, k, 0],
                             -mass[k] * accel[i, k, 1], lc)
            b[3 * mass_body[k] + 2] -= inertia[k] * alpha[i, k] / lc


# a pair per kernel, as assembly's (why: there)
@njit(cache=True)
def _statics_serial(n_pose: int, job: StaticsJob, layout: StaticsProgram) -> None:
    for i in range(n_pose):
        _statics_pose(i, job, layout)


@njit(cache=True, parallel=True)
def _statics_parallel(n_pose: int, job: StaticsJob, layout: StaticsProgram) -> None:
    for i in prange(n_pose):
        _statics_pose(i, job, layout)
