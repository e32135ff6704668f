"""Assembling poses: Newton from a start pose, the assembly branch (the loops' determinant signs),
the kinematic condition number, and the per-pose kinematics of a batch (the chain's pose, or
Newton from the tangent prediction)."""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba import njit, prange

from ..programs import KinematicsProgram
from .closure import _residuals, _rotations, _wrap, residual_jacobian
from .dyads import _chain_pose_into, chain_fit
from .linalg import _max_abs, closed_step, det_sign, factor_and_condition, gram
from .threads import _parallel


@njit(cache=True)
def _same_inputs(s: np.ndarray, s_start: np.ndarray) -> bool:
    """Whether the inputs s are exactly the start pose's (then the start pose is theirs)."""
    for j in range(s.shape[0]):
        if s[j] != s_start[j]:
            return False
    return True


@njit(cache=True)
def newton(q0: np.ndarray, s: np.ndarray, max_iter: int, att_body: np.ndarray, att_ref: np.ndarray,
           hinge_att: np.ndarray, cyl_att: np.ndarray, angle_body: np.ndarray, angle_reference: np.ndarray,
           lc: float, drive_rows: np.ndarray, fit_rows: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Newton / Gauss-Newton from q0: (q, Φ, ∂Φ/∂q), both at the returned q; each step a
    ``closed_step`` (redundant sensors: hinges closed, inputs fitted in least squares).

    Stops when |Φ| ≤ 1e-13·lc, or before a step that is not finite (singular) or, overdetermined,
    not above 1e-13·lc (the fitted inputs' residual need not reach 0).
    """
    tol = 1e-13 * lc
    n_hard = 2 * hinge_att.shape[1]
    q = q0.copy()
    phi, jac = residual_jacobian(q, s, att_body, att_ref, hinge_att, cyl_att, angle_body, angle_reference, lc)
    m, n = jac.shape
    for _ in range(max_iter):
        if _max_abs(phi) <= tol:
            break
        dq = closed_step(jac, -phi, drive_rows, fit_rows, n_hard)
        step = _max_abs(dq)
        if not math.isfinite(step) or (m > n and not step > tol):
            break
        q += dq
        phi, jac = residual_jacobian(q, s, att_body, att_ref, hinge_att, cyl_att, angle_body, angle_reference, lc)
    return q, phi, jac


@njit(cache=True)
def newton_batch(q0: np.ndarray, s: np.ndarray, max_iter: int, att_body: np.ndarray, att_ref: np.ndarray,
                 hinge_att: np.ndarray, cyl_att: np.ndarray, angle_body: np.ndarray, angle_reference: np.ndarray,
                 lc: float, drive_rows: np.ndarray, fit_rows: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``newton`` for N poses q0 (N, n), s (N, n_inputs): q, Φ, ∂Φ/∂q stacked."""
    n_pose, n = q0.shape
    m = 2 * hinge_att.shape[1] + cyl_att.shape[1] + angle_body.shape[1]
    q_out = np.empty((n_pose, n))
    phi_out = np.empty((n_pose, m))
    jac_out = np.empty((n_pose, m, n))
    for i in range(n_pose):
        q_out[i], phi_out[i], jac_out[i] = newton(q0[i], s[i], max_iter, att_body, att_ref, hinge_att, cyl_att,
                                                  angle_body, angle_reference, lc, drive_rows, fit_rows)
    return q_out, phi_out, jac_out


@njit(cache=True)
def assembled(phi: np.ndarray, n_hard: int, lc: float, limit: float) -> bool:
    """Whether a pose's loop-closure residual Φ (m,) is an assembled linkage: the hinge rows
    ``phi[:n_hard]`` closed (≤ 1e-9·lc) and every row within ``limit`` (m; the inputs' misfit when
    sensors are redundant)."""
    return _max_abs(phi[:n_hard]) <= 1e-9 * lc and _max_abs(phi) <= limit


@njit(cache=True)
def assembled_batch(phi: np.ndarray, n_hard: int, lc: float, limit: float) -> np.ndarray:
    """``assembled`` for N poses Φ (N, m): (N,) bool."""
    out = np.empty(phi.shape[0], dtype=np.bool_)
    for i in range(phi.shape[0]):
        out[i] = assembled(phi[i], n_hard, lc, limit)
    return out


@njit(cache=True)
def condition(jac: np.ndarray, column_scale: np.ndarray) -> float:
    """1-norm condition number of the Jacobian made dimensionless (θ columns / lc); for more rows
    than columns the square root of that of JᵀJ."""
    js = jac * column_scale
    if js.shape[0] != js.shape[1]:
        return math.sqrt(factor_and_condition(gram(js))[2])
    return factor_and_condition(js)[2]


@njit(cache=True)
def loop_signs(jac: np.ndarray, loop_rows: np.ndarray, loop_cols: np.ndarray, loop_ptr: np.ndarray) -> np.ndarray:
    """Sign of the determinant of each loop's diagonal block (+1, −1, 0 at a dead centre)."""
    n_loops = loop_ptr.shape[0] - 1
    out = np.ones(n_loops)
    for k in range(n_loops):
        rows = loop_rows[loop_ptr[k]:loop_ptr[k + 1]]
        cols = loop_cols[loop_ptr[k]:loop_ptr[k + 1]]
        block = np.empty((rows.shape[0], cols.shape[0]))
        for i in range(rows.shape[0]):
            for j in range(cols.shape[0]):
                block[i, j] = jac[rows[i], cols[j]]
        out[k] = det_sign(block)
    return out


@njit(cache=True)
def _nearest_turn(q: np.ndarray, q_start: np.ndarray) -> None:
    """Each rotation in q by whole turns (as Newton or atan2 may give it) to its equivalent nearest q_start's."""
    for b in range(q.shape[0] // 3):
        q[3 * b + 2] = q_start[3 * b + 2] + _wrap(q[3 * b + 2] - q_start[3 * b + 2])


class KinematicJob(NamedTuple):
    """A batch of ``solve_poses`` (``_kinematic_pose``): what it writes — q (N, n), Φ (N, m), the
    condition number (N,), on_branch (N,) —, the start pose q_start (1, n) with its inputs s_start
    (1, n_inputs), the inputs s (N, n_inputs) (m, rad), Newton's iteration limit, and whether the
    condition number is computed."""

    q: np.ndarray
    phi: np.ndarray
    condition: np.ndarray
    on_branch: np.ndarray
    q_start: np.ndarray
    s_start: np.ndarray
    s: np.ndarray
    max_iter: int
    with_condition: bool


@njit(cache=True)
def _kinematic_pose(i: int, job: KinematicJob, kin: KinematicsProgram) -> None:
    """Pose i of ``solve_poses``, written into the job's outputs (the condition number NaN unless
    ``with_condition``).

    A chain's pose — in closed form, or fitted along the chain where sensors are redundant — places
    every circle intersection on the reference pose's side: it is on the reference branch
    (test_chain.py holds it against the Jacobian's loop signs), and Φ says it closes; no Newton,
    and a Jacobian only for the condition number. Otherwise (no chain, a step out of reach, a fit
    that does not converge, a closed form that does not close) Newton, from the tangent prediction
    off the start pose (its Jacobian evaluated here) or from the chain's pose, and the loop signs
    of the Jacobian decide the branch. Inputs exactly the start pose's: the start pose (solved for
    them, on the branch)."""
    q_out, phi_out, cond, on_branch, q_start, s_start, s = (job.q, job.phi, job.condition, job.on_branch,
                                                            job.q_start, job.s_start, job.s)
    max_iter, with_condition = job.max_iter, job.with_condition
    m, n = phi_out.shape[1], q_out.shape[1]
    n_in = s.shape[1]
    nc = kin.cyl_att.shape[1]
    att_body, att_ref, hinge_att, cyl_att, lc = kin.att_body, kin.att_ref, kin.hinge_att, kin.cyl_att, kin.lc
    angle_body, angle_reference = kin.angle_body, kin.angle_reference
    rotation = np.empty((2, n // 3))
    if _same_inputs(s[i], s_start[0]) and math.isfinite(_max_abs(q_start[0])):   # the start pose's inputs again
        # (a pressure reading between two joint states): the start pose, solved for them, is theirs
        q_out[i] = q_start[0]
        _rotations(q_out[i], rotation)
        _residuals(q_out[i], rotation, s[i], kin, phi_out[i])
        cond[i] = math.nan
        if with_condition:
            _, jac = residual_jacobian(q_out[i], s[i], att_body, att_ref, hinge_att, cyl_att, angle_body,
                                       angle_reference, lc)
            cond[i] = condition(jac, kin.column_scale)
        on_branch[i] = True
        return
    if m > n:   # redundant sensors: fitted along the chain's closed poses
        q0, closed, converged = chain_fit(s[i], n, att_body, att_ref, cyl_att, angle_body, angle_reference, lc,
                                          kin.chain_int, kin.chain_float, max_iter)
        if converged:
            _rotations(q0, rotation)
    else:
        q0 = np.zeros(n)
        closed = converged = _chain_pose_into(q0, rotation, s[i], att_body, att_ref, kin.chain_int, kin.chain_float)
    if converged:
        _residuals(q0, rotation, s[i], kin, phi_out[i])
        if m > n or _max_abs(phi_out[i]) <= 1e-13 * lc:   # (with redundant sensors Φ holds their misfit)
            _nearest_turn(q0, q_start[0])
            q_out[i] = q0
            cond[i] = math.nan
            if with_condition:
                _, jac = residual_jacobian(q0, s[i], att_body, att_ref, hinge_att, cyl_att, angle_body,
                                           angle_reference, lc)
                cond[i] = condition(jac, kin.column_scale)
            on_branch[i] = True
            return
    if not closed:   # the tangent prediction
        _, jac_start = residual_jacobian(q_start[0], s_start[0], att_body, att_ref, hinge_att, cyl_att, angle_body,
                                         angle_reference, lc)
        r0 = m - n_in
        shift = np.zeros(m)
        for j in range(n_in):
            ds = s[i, j] - s_start[0, j]
            shift[r0 + j] = ds if j < nc else lc * ds
        q0 = q_start[0] + closed_step(jac_start, shift, kin.drive_rows, kin.fit_rows, 2 * hinge_att.shape[1])
    q, phi, jac = newton(q0, s[i], max_iter, att_body, att_ref, hinge_att, cyl_att, angle_body, angle_reference,
                         lc, kin.drive_rows, kin.fit_rows)
    _nearest_turn(q, q_start[0])
    q_out[i], phi_out[i] = q, phi
    cond[i] = condition(jac, kin.column_scale) if with_condition else math.nan
    signs = loop_signs(jac, kin.loop_rows, kin.loop_cols, kin.loop_ptr)
    on_branch[i] = True
    for k in range(signs.shape[0]):
        if signs[k] * kin.ref_branch[k] < 0.0:
            on_branch[i] = False


def solve_poses(q_start: np.ndarray, s_start: np.ndarray, s: np.ndarray, max_iter: int, kin: KinematicsProgram,
                with_condition: bool = True) -> tuple[np.ndarray, ...]:
    """Assemble N poses for inputs s (N, n_inputs) (``_kinematic_pose``): the chain's pose, or Newton
    from the tangent prediction off one solved pose (q_start (1, n), its inputs s_start (1, n_inputs))
    — J·dq = E·(s − s_start) as a ``closed_step``, E the input rows' unit / lc entries —, then the
    condition number and the assembly branch.

    ``kin``: the mechanism (``Kinematics.program``). Returns q (N, n), Φ (N, m), condition (N,; NaN
    without ``with_condition``: where the reduced path's transmission measure is the verdict, the
    Jacobian's 1-norm condition number is not needed and is most of a pose's time), on_branch (N,):
    False where a loop is in the opposite assembly of ``ref_branch`` (a loop at a dead centre, sign
    0, counts as on it). Large batches run on every core (``allow_threads``).
    """
    n_pose, n = s.shape[0], q_start.shape[1]
    m = 2 * kin.hinge_att.shape[1] + kin.cyl_att.shape[1] + kin.angle_body.shape[1]
    job = KinematicJob(q=np.empty((n_pose, n)), phi=np.empty((n_pose, m)), condition=np.empty(n_pose),
                       on_branch=np.empty(n_pose, dtype=np.bool_), q_start=q_start, s_start=s_start, s=s,
                       max_iter=int(max_iter), with_condition=bool(with_condition))
    (_kinematics_parallel if _parallel(n_pose) else _kinematics_serial)(n_pose, job, kin)
    return job.q, job.phi, job.condition, job.on_branch


# The serial and parallel loops of a batch kernel, a pair per kernel (equilibrium, reduced, capacity and
# closure have theirs): one pair for every kernel, the kernel chosen by its job's type through a numba
# overload, cost every pose a call (kinematics 5-8 % slower, positions 10-18 %; docs/performance.md).
@njit(cache=True)
def _kinematics_serial(n_pose: int, job: KinematicJob, kin: KinematicsProgram) -> None:
    for i in range(n_pose):
        _kinematic_pose(i, job, kin)


@njit(cache=True, parallel=True)
def _kinematics_parallel(n_pose: int, job: KinematicJob, kin: KinematicsProgram) -> None:
    for i in prange(n_pose):
        _kinematic_pose(i, job, kin)
