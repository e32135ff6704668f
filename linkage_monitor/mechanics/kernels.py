"""Compiled per-pose physics (numba): loop closure, assembly branch, equilibrium, lift capacity.

The one numeric path of the solver. Every function works on plain arrays that describe the
mechanism (built once by :class:`~.kinematics.Kinematics` and :class:`~.statics.StaticsLayout`)
and loops over poses in compiled code, so a single pose costs microseconds, not the ~150
numpy calls of the array formulation that the tests keep as their oracle
(``test/oracles/numpy_solver/``). Compiled once, cached on disk (``cache=True``).

Conventions (as in kinematics.py / statics.py): q holds (x, z, θ) per moving body (m, m, rad;
x forward, z up); an attachment is a point fixed on a body, at ``ref`` (m) from the body's
origin in the reference pose, or at ``ref`` in the frame when its body is the ground (−1).
Rows of the loop-closure system: 2 per hinge (x, z gap, m), 1 per measured cylinder (length
error, m), 1 per measured angle (error · lc, m). Equilibrium rows: ΣFx, ΣFz, ΣM/lc per body.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numba import njit, prange

from .chain import (A_BODY, A_BODY2, A_END, A_JOINT1, A_JOINT2, A_OTHER, A_PARENT, A_PARENT2, ANGLE, ANGLE_INPUT,
                    ANGLE_SIGN, BODY, BODY2, CYLINDER, CYLINDER_INPUT, KIND, RRR, STEP_HINGE, STEP_HINGE2, STEP_JOINT)
from .programs import (POSE_VALUES, KinematicsProgram, LiveBuffer, LivePrograms, LiveRows, MachineProgram,
                       OutputsProgram, ReducedProgram, StaticsProgram, ValueRow)

TWO_PI = 2.0 * math.pi
PARALLEL_MIN = 512  # poses: smaller batches stay on the calling thread (no thread-pool wake-up)
PARALLEL_PARTS = 64  # a parallel loop's parts, each with its own work arrays (several per core: balanced)
_threads = {"allowed": False}


def allow_threads(allowed: bool = True) -> None:
    """Let batches of ≥ PARALLEL_MIN poses run on every core (numba's thread pool). Off by default:
    the live node solves one pose at a time and keeps no thread pool; the offline commands
    (replay, fleet, calibrate, capacity) turn it on."""
    _threads["allowed"] = allowed


def _parallel(n_pose: int) -> bool:
    return _threads["allowed"] and n_pose >= PARALLEL_MIN


# ---- small dense linear algebra (partial-pivoting LU) --------------------------------------------
@njit(cache=True)
def lu_factor(a: np.ndarray) -> tuple[np.ndarray, np.ndarray, int, bool]:
    """LU of a square matrix (a copy): (lu, row permutation, number of row swaps, singular)."""
    k = a.shape[0]
    lu = a.copy()
    piv = np.arange(k)
    swaps = 0
    for j in range(k):
        p = j
        big = abs(lu[j, j])
        for i in range(j + 1, k):
            if abs(lu[i, j]) > big:
                big, p = abs(lu[i, j]), i
        if big == 0.0 or not math.isfinite(big):
            return lu, piv, swaps, True
        if p != j:
            for c in range(k):
                lu[j, c], lu[p, c] = lu[p, c], lu[j, c]
            piv[j], piv[p] = piv[p], piv[j]
            swaps += 1
        inv = 1.0 / lu[j, j]
        for i in range(j + 1, k):
            f = lu[i, j] * inv
            lu[i, j] = f
            if f != 0.0:
                for c in range(j + 1, k):
                    lu[i, c] -= f * lu[j, c]
    return lu, piv, swaps, False


@njit(cache=True)
def lu_solve(lu: np.ndarray, piv: np.ndarray, b: np.ndarray) -> np.ndarray:
    """x with a·x = b from ``lu_factor(a)``."""
    k = lu.shape[0]
    x = np.empty(k)
    for i in range(k):
        x[i] = b[piv[i]]
    for i in range(k):
        acc = x[i]
        for c in range(i):
            acc -= lu[i, c] * x[c]
        x[i] = acc
    for i in range(k - 1, -1, -1):
        acc = x[i]
        for c in range(i + 1, k):
            acc -= lu[i, c] * x[c]
        x[i] = acc / lu[i, i]
    return x


@njit(cache=True)
def norm_1(a: np.ndarray) -> float:
    """Matrix 1-norm: the largest absolute column sum."""
    best = 0.0
    for c in range(a.shape[1]):
        acc = 0.0
        for r in range(a.shape[0]):
            acc += abs(a[r, c])
        if acc > best:
            best = acc
    return best


@njit(cache=True)
def inverse_norm_1(lu: np.ndarray, piv: np.ndarray) -> float:
    """1-norm of a⁻¹ from ``lu_factor(a)``: L·U·X = P solved for all columns together, row operations
    over whole rows (independent columns: vectorized, no dependency chain along a column)."""
    k = lu.shape[0]
    x = np.zeros((k, k))
    for i in range(k):
        x[i, piv[i]] = 1.0
    for i in range(k):
        for j in range(i):
            f = lu[i, j]
            if f != 0.0:
                for c in range(k):
                    x[i, c] -= f * x[j, c]
    column_sum = np.zeros(k)
    for i in range(k - 1, -1, -1):
        for j in range(i + 1, k):
            f = lu[i, j]
            if f != 0.0:
                for c in range(k):
                    x[i, c] -= f * x[j, c]
        inv = 1.0 / lu[i, i]
        for c in range(k):
            x[i, c] *= inv
            column_sum[c] += abs(x[i, c])
    best = 0.0
    for c in range(k):
        if not column_sum[c] <= best:
            best = column_sum[c]
    return best


@njit(cache=True)
def factor_and_condition(a: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
    """LU of a square matrix (``lu_factor``) and its exact 1-norm condition number ‖a‖₁·‖a⁻¹‖₁ (inf when
    singular)."""
    lu, piv, _, singular = lu_factor(a)
    if singular:
        return lu, piv, np.inf
    return lu, piv, norm_1(a) * inverse_norm_1(lu, piv)


@njit(cache=True)
def det_sign(a: np.ndarray) -> float:
    """Sign of det(a): +1, −1, or 0 when singular."""
    lu, _, swaps, singular = lu_factor(a)
    if singular:
        return 0.0
    sign = -1.0 if swaps % 2 else 1.0
    for i in range(a.shape[0]):
        if lu[i, i] < 0.0:
            sign = -sign
    return sign


@njit(cache=True)
def gram(a: np.ndarray) -> np.ndarray:
    """aᵀ·a, a row at a time over its nonzero entries only (a constraint Jacobian's row has at most six)."""
    m, n = a.shape
    out = np.zeros((n, n))
    cols = np.empty(n, dtype=np.int64)
    for r in range(m):
        k = 0
        for c in range(n):
            if a[r, c] != 0.0:
                cols[k] = c
                k += 1
        for i in range(k):
            ci = cols[i]
            v = a[r, ci]
            for j in range(k):
                out[ci, cols[j]] += v * a[r, cols[j]]
    return out


@njit(cache=True)
def solve_linear(jac: np.ndarray, rhs: np.ndarray) -> np.ndarray:
    """x with jac·x = rhs; least squares by the normal equations when jac has more rows than columns.
    NaN where the system is singular."""
    m, n = jac.shape
    if m == n:
        a, b = jac, rhs
    else:
        a, b = gram(jac), jac.T @ rhs
    lu, piv, _, singular = lu_factor(a)
    if singular:
        return np.full(n, np.nan)
    return lu_solve(lu, piv, b)


@njit(cache=True)
def closed_step(jac: np.ndarray, rhs: np.ndarray, drive_rows: np.ndarray, fit_rows: np.ndarray,
                n_hard: int) -> np.ndarray:
    """x with jac·x = rhs for the loop closure: the linkage closed, the measured inputs fitted.

    Square (as many inputs as degrees of freedom): solved. More rows than columns (redundant
    sensors): the hinge rows ``drive_rows[:n_hard]`` hold exactly and the input rows in least
    squares. The k = n − n_hard inputs ``drive_rows[n_hard:]`` close the square system M
    (``drive_rows``); their misfit y is the reduced coordinate: x = M⁻¹(rhs_M + E·y), E the unit
    columns of those rows, the ``fit_rows``' misfit c + B·y with c = J_R·M⁻¹rhs_M − rhs_R and
    B = J_R·M⁻¹E, and y minimises |y|² + |c + B·y|²: (I + BᵀB)·y = −Bᵀc. Without ``drive_rows``
    (no square subsystem closes the pose) every row in least squares (normal equations). NaN where
    singular.
    """
    m, n = jac.shape
    if m == n or drive_rows.shape[0] == 0:
        return solve_linear(jac, rhs)
    a = np.empty((n, n))
    b = np.empty(n)
    for i in range(n):
        a[i] = jac[drive_rows[i]]
        b[i] = rhs[drive_rows[i]]
    lu, piv, _, singular = lu_factor(a)
    if singular:
        return np.full(n, np.nan)
    x = lu_solve(lu, piv, b)
    k = n - n_hard
    g = np.empty((n, k))
    e = np.zeros(n)
    for j in range(k):
        e[n_hard + j] = 1.0
        g[:, j] = lu_solve(lu, piv, e)
        e[n_hard + j] = 0.0
    n_fit = fit_rows.shape[0]
    c = np.empty(n_fit)
    bm = np.empty((n_fit, k))
    for r in range(n_fit):
        row = jac[fit_rows[r]]
        c[r] = row @ x - rhs[fit_rows[r]]
        bm[r] = row @ g
    h = bm.T @ bm
    for j in range(k):
        h[j, j] += 1.0
    lu_h, piv_h, _, singular_h = lu_factor(h)
    if singular_h:
        return np.full(n, np.nan)
    return x + g @ lu_solve(lu_h, piv_h, -(bm.T @ c))


# ---- positions and loop closure --------------------------------------------------------------------
@njit(cache=True)
def positions(q: np.ndarray, att_body: np.ndarray, att_ref: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Positions p (K, 2) m of all attachments for one pose q, and their offsets rel (K, 2) from their
    body's origin (rotated with the body; for ground attachments the position itself)."""
    k_att = att_body.shape[0]
    p = np.empty((k_att, 2))
    rel = np.empty((k_att, 2))
    _positions_into(q, att_body, att_ref, p, rel, np.empty((2, q.shape[0] // 3)))
    return p, rel


@njit(cache=True)
def _positions_into(q: np.ndarray, att_body: np.ndarray, att_ref: np.ndarray, p: np.ndarray, rel: np.ndarray,
                    rotation: np.ndarray) -> None:
    """``positions`` into p, rel (K, 2); ``rotation`` (2, bodies): room for each body's cos θ, sin θ."""
    _rotations(q, rotation)
    c, s = rotation[0], rotation[1]
    for a in range(att_body.shape[0]):
        b = att_body[a]
        rx, rz = att_ref[a, 0], att_ref[a, 1]
        if b < 0:
            rel[a, 0], rel[a, 1] = rx, rz
            p[a, 0], p[a, 1] = rx, rz
        else:
            rel[a, 0] = c[b] * rx - s[b] * rz
            rel[a, 1] = s[b] * rx + c[b] * rz
            p[a, 0] = q[3 * b] + rel[a, 0]
            p[a, 1] = q[3 * b + 1] + rel[a, 1]


@njit(cache=True)
def _wrap(a: float) -> float:
    """An angle (rad) modulo 2π in [−π, π)."""
    return a - TWO_PI * math.floor((a + math.pi) / TWO_PI)


@njit(cache=True)
def _theta(q: np.ndarray, body: int) -> float:
    return q[3 * body + 2] if body >= 0 else 0.0


@njit(cache=True)
def _add_point_rows(jac: np.ndarray, row: int, att: int, sign: float, att_body: np.ndarray,
                    rel: np.ndarray) -> None:
    """∂P/∂(x, z, θ) of attachment ``att`` (= I and i·rel), times ``sign``, into rows row (x), row+1 (z)."""
    b = att_body[att]
    if b >= 0:
        jac[row, 3 * b] += sign
        jac[row + 1, 3 * b + 1] += sign
        jac[row, 3 * b + 2] -= sign * rel[att, 1]
        jac[row + 1, 3 * b + 2] += sign * rel[att, 0]


@njit(cache=True)
def _add_length_row(jac: np.ndarray, row: int, att: int, sign: float, ux: float, uz: float,
                    att_body: np.ndarray, rel: np.ndarray) -> None:
    """∂|P_rod − P_base|/∂(x, z, θ) of one end (u·∂P, u the unit axis), times ``sign``, into ``row``."""
    b = att_body[att]
    if b >= 0:
        jac[row, 3 * b] += sign * ux
        jac[row, 3 * b + 1] += sign * uz
        jac[row, 3 * b + 2] += sign * (uz * rel[att, 0] - ux * rel[att, 1])


@njit(cache=True)
def _angle_residual(q: np.ndarray, k: int, s: np.ndarray, nc: int, angle_body: np.ndarray,
                    angle_reference: np.ndarray, lc: float) -> float:
    """Φ's row of angle sensor k (m): lc·wrap(θ(bodies[1]) − θ(bodies[0]) + reference − s)."""
    return lc * _wrap(_theta(q, angle_body[1, k]) - _theta(q, angle_body[0, k]) + angle_reference[k] - s[nc + k])


@njit(cache=True)
def _input_residuals(q: np.ndarray, rotation: np.ndarray, s: np.ndarray, att_body: np.ndarray, att_ref: np.ndarray,
                     cyl_att: np.ndarray, angle_body: np.ndarray, angle_reference: np.ndarray, lc: float,
                     out: np.ndarray) -> None:
    """The input rows of Φ (``residual_jacobian``'s, m) at pose q (its bodies' ``rotation``) into out
    (n_inputs,): cylinder k |P(rod end) − P(base)| − s_k, then the angles (``_angle_residual``)."""
    nc = cyl_att.shape[1]
    for k in range(nc):
        bx, bz = _point(q, rotation, cyl_att[0, k], att_body, att_ref)
        rx, rz = _point(q, rotation, cyl_att[1, k], att_body, att_ref)
        out[k] = math.sqrt((rx - bx) * (rx - bx) + (rz - bz) * (rz - bz)) - s[k]
    for k in range(angle_body.shape[1]):
        out[nc + k] = _angle_residual(q, k, s, nc, angle_body, angle_reference, lc)


@njit(cache=True)
def _residuals(q: np.ndarray, rotation: np.ndarray, s: np.ndarray, kin: KinematicsProgram, out: np.ndarray) -> None:
    """Φ (m,) m of pose q (its bodies' ``rotation``) for inputs s into out, as ``residual_jacobian``
    computes it, without the Jacobian: the hinge gaps, then the input rows (``_input_residuals``)."""
    hinge_att, att_body, att_ref = kin.hinge_att, kin.att_body, kin.att_ref
    nh = hinge_att.shape[1]
    for h in range(nh):
        ax, az = _point(q, rotation, hinge_att[0, h], att_body, att_ref)
        bx, bz = _point(q, rotation, hinge_att[1, h], att_body, att_ref)
        out[2 * h], out[2 * h + 1] = ax - bx, az - bz
    _input_residuals(q, rotation, s, att_body, att_ref, kin.cyl_att, kin.angle_body, kin.angle_reference, kin.lc,
                     out[2 * nh:])


@njit(cache=True)
def _rotations(q: np.ndarray, rotation: np.ndarray) -> None:
    """cos θ, sin θ of every body of pose q into rotation (2, bodies)."""
    for b in range(rotation.shape[1]):
        rotation[0, b], rotation[1, b] = math.cos(q[3 * b + 2]), math.sin(q[3 * b + 2])


@njit(cache=True)
def residual_jacobian(q: np.ndarray, s: np.ndarray, att_body: np.ndarray, att_ref: np.ndarray,
                      hinge_att: np.ndarray, cyl_att: np.ndarray, angle_body: np.ndarray,
                      angle_reference: np.ndarray, lc: float) -> tuple[np.ndarray, np.ndarray]:
    """Loop-closure residual Φ (m,) m and Jacobian ∂Φ/∂q (m, n) of one pose q for inputs s.

    Hinge h: P(bodies[0]) − P(bodies[1]); cylinder k: |P(rod end) − P(base)| − s_k; angle k:
    lc·wrap(θ(bodies[1]) − θ(bodies[0]) + reference − s) (angles modulo 2π).
    """
    n = q.shape[0]
    nh, nc, na = hinge_att.shape[1], cyl_att.shape[1], angle_body.shape[1]
    m = 2 * nh + nc + na
    p, rel = positions(q, att_body, att_ref)
    phi = np.empty(m)
    jac = np.zeros((m, n))
    for h in range(nh):
        a, b = hinge_att[0, h], hinge_att[1, h]
        phi[2 * h] = p[a, 0] - p[b, 0]
        phi[2 * h + 1] = p[a, 1] - p[b, 1]
        _add_point_rows(jac, 2 * h, a, 1.0, att_body, rel)
        _add_point_rows(jac, 2 * h, b, -1.0, att_body, rel)
    for k in range(nc):
        base, rod = cyl_att[0, k], cyl_att[1, k]
        dx, dz = p[rod, 0] - p[base, 0], p[rod, 1] - p[base, 1]
        length = math.sqrt(dx * dx + dz * dz)
        r = 2 * nh + k
        phi[r] = length - s[k]   # as ``_input_residuals``, from the positions already computed
        _add_length_row(jac, r, rod, 1.0, dx / length, dz / length, att_body, rel)
        _add_length_row(jac, r, base, -1.0, dx / length, dz / length, att_body, rel)
    for k in range(na):
        b0, b1 = angle_body[0, k], angle_body[1, k]
        r = 2 * nh + nc + k
        phi[r] = _angle_residual(q, k, s, nc, angle_body, angle_reference, lc)
        if b1 >= 0:
            jac[r, 3 * b1 + 2] += lc
        if b0 >= 0:
            jac[r, 3 * b0 + 2] -= lc
    return phi, jac


# ---- the pose in closed form: a chain of dyads (chain.py) -----------------------------------------
@njit(cache=True)
def _point(q: np.ndarray, rotation: np.ndarray, a: int, att_body: np.ndarray, att_ref: np.ndarray
           ) -> tuple[float, float]:
    """Position (m) of attachment ``a`` in pose q (its body already placed, its cos θ and sin θ in
    ``rotation`` (2, bodies))."""
    b = att_body[a]
    if b < 0:
        return att_ref[a, 0], att_ref[a, 1]
    c, s = rotation[0, b], rotation[1, b]
    return (q[3 * b] + c * att_ref[a, 0] - s * att_ref[a, 1],
            q[3 * b + 1] + s * att_ref[a, 0] + c * att_ref[a, 1])


@njit(cache=True)
def _circles(ax: float, az: float, ra: float, bx: float, bz: float, rb: float,
             side: float) -> tuple[float, float, bool]:
    """The point at ``ra`` from a and ``rb`` from b on ``side`` (sign of cross(b − a, p − a)); False
    when the circles do not meet (out of reach)."""
    dx, dz = bx - ax, bz - az
    d = math.sqrt(dx * dx + dz * dz)
    if not d > 0.0:
        return math.nan, math.nan, False
    along = (ra * ra - rb * rb + d * d) / (2.0 * d)
    h2 = ra * ra - along * along
    if not h2 >= 0.0:
        return math.nan, math.nan, False
    h = math.sqrt(h2) * side
    return ax + (along * dx - h * dz) / d, az + (along * dz + h * dx) / d, True


@njit(cache=True)
def _place(q: np.ndarray, rotation: np.ndarray, body: int, theta: float, px: float, pz: float, a_body: int,
           att_ref: np.ndarray) -> None:
    """Body ``body`` at rotation θ with its attachment ``a_body`` at (px, pz): its (x, z, θ) into q,
    cos θ and sin θ into ``rotation``."""
    c, s = math.cos(theta), math.sin(theta)
    rotation[0, body], rotation[1, body] = c, s
    q[3 * body] = px - (c * att_ref[a_body, 0] - s * att_ref[a_body, 1])
    q[3 * body + 1] = pz - (s * att_ref[a_body, 0] + c * att_ref[a_body, 1])
    q[3 * body + 2] = theta


@njit(cache=True)
def chain_pose(s: np.ndarray, n: int, att_body: np.ndarray, att_ref: np.ndarray, chain_int: np.ndarray,
               chain_float: np.ndarray) -> tuple[np.ndarray, bool]:
    """The pose q (n,) of a chain of dyads (``chain.decompose``) for inputs s (cylinder lengths m,
    angles rad), each circle intersection on its reference side; False when a step is out of reach
    or there is no chain (a mechanism that does not decompose: nothing placed)."""
    q = np.zeros(n)
    return q, _chain_pose_into(q, np.empty((2, n // 3)), s, att_body, att_ref, chain_int, chain_float)


@njit(cache=True)
def _chain_pose_into(q: np.ndarray, rotation: np.ndarray, s: np.ndarray, att_body: np.ndarray, att_ref: np.ndarray,
                     chain_int: np.ndarray, chain_float: np.ndarray) -> bool:
    """``chain_pose`` into q (zeros on entry) and its bodies' cos θ, sin θ into ``rotation``."""
    if chain_int.shape[0] == 0:
        return q.shape[0] == 0
    return _place_chain(q, rotation, s, att_body, att_ref, chain_int, chain_float)


@njit(cache=True)
def _place_chain(q: np.ndarray, rotation: np.ndarray, s: np.ndarray, att_body: np.ndarray, att_ref: np.ndarray,
                 chain_int: np.ndarray, chain_float: np.ndarray) -> bool:
    """``chain_pose`` into q and ``rotation`` (every body the chain places is written); False when a
    step is out of reach."""
    for k in range(chain_int.shape[0]):
        row, f = chain_int[k], chain_float[k]
        if row[KIND] == ANGLE:         # θ_B = θ_P + sign·(s − reference), about the hinge point
            parent = att_body[row[A_PARENT]]
            theta_p = q[3 * parent + 2] if parent >= 0 else 0.0
            px, pz = _point(q, rotation, row[A_PARENT], att_body, att_ref)
            _place(q, rotation, row[BODY], theta_p + row[ANGLE_SIGN] * (s[row[ANGLE_INPUT]] - f[0]), px, pz,
                   row[A_BODY], att_ref)
        elif row[KIND] == CYLINDER:    # the end on B at ρ from the pivot and s from the other end
            px, pz = _point(q, rotation, row[A_PARENT], att_body, att_ref)
            ox, oz = _point(q, rotation, row[A_OTHER], att_body, att_ref)
            ex, ez, ok = _circles(px, pz, f[2], ox, oz, s[row[CYLINDER_INPUT]], f[0])
            if not ok:
                return False
            _place(q, rotation, row[BODY], math.atan2(ez - pz, ex - px) - f[1], px, pz, row[A_BODY], att_ref)
        else:                          # RRR: the joint at ρ1 from B1's pivot and ρ2 from B2's
            p1x, p1z = _point(q, rotation, row[A_PARENT], att_body, att_ref)
            p2x, p2z = _point(q, rotation, row[A_PARENT2], att_body, att_ref)
            hx, hz, ok = _circles(p1x, p1z, f[2], p2x, p2z, f[4], f[0])
            if not ok:
                return False
            _place(q, rotation, row[BODY], math.atan2(hz - p1z, hx - p1x) - f[1], p1x, p1z, row[A_BODY], att_ref)
            _place(q, rotation, row[BODY2], math.atan2(hz - p2z, hx - p2x) - f[3], p2x, p2z, row[A_BODY2], att_ref)
    return True


@njit(cache=True)
def chain_fit(s: np.ndarray, n: int, att_body: np.ndarray, att_ref: np.ndarray, cyl_att: np.ndarray,
              angle_body: np.ndarray, angle_reference: np.ndarray, lc: float, chain_int: np.ndarray,
              chain_float: np.ndarray, max_iter: int) -> tuple[np.ndarray, bool, bool]:
    """Redundant sensors in the chain's own coordinates: the closed pose whose inputs are nearest the
    readings s — the least squares ``closed_step``'s Gauss-Newton solves over all coordinates (every
    input row of Φ squared, angle rows × lc) — found over the chain's driving inputs σ alone: the
    chain's pose at σ (``chain_pose``) closes every hinge, so Σ Φ_input(σ)² is minimised by
    Gauss-Newton on σ, its derivative by central differences (h = 1e-6·lc for a length, 1e-6 rad
    for an angle). Stops when every input row is ≤ 1e-13·lc (the readings agree) or a step is no
    larger (``newton``'s two tests).

    Returns (q, closed: every chain step within reach, converged). Not converged (a step out of
    reach on the way, no convergence in ``max_iter``): Newton in all coordinates takes over from q.
    """
    n_in = s.shape[0]
    nc = cyl_att.shape[1]
    drivers = np.empty(chain_int.shape[0], dtype=np.int64)   # the input column of each ANGLE / CYLINDER step
    d = 0
    for k in range(chain_int.shape[0]):
        if chain_int[k, KIND] == ANGLE:
            drivers[d] = chain_int[k, ANGLE_INPUT]
            d += 1
        elif chain_int[k, KIND] == CYLINDER:
            drivers[d] = chain_int[k, CYLINDER_INPUT]
            d += 1
    q, rotation = np.zeros(n), np.empty((2, n // 3))
    if d == 0 or not _place_chain(q, rotation, s, att_body, att_ref, chain_int, chain_float):
        return q, False, False
    tol = 1e-13 * lc
    r = np.empty(n_in)
    _input_residuals(q, rotation, s, att_body, att_ref, cyl_att, angle_body, angle_reference, lc, r)
    if _max_abs(r) <= tol:   # the readings agree (``newton``'s first test): the chain's pose
        return q, True, True
    sigma = s.copy()
    q_plus, q_minus = np.zeros(n), np.zeros(n)
    rotation_plus, rotation_minus = np.empty((2, n // 3)), np.empty((2, n // 3))
    r_plus, r_minus = np.empty(n_in), np.empty(n_in)
    slope = np.empty((n_in, d))
    normal = np.empty((d, d + 1))   # [slopeᵀ·slope | −slopeᵀ·r]
    for _ in range(max_iter):
        for j in range(d):
            c = drivers[j]
            h = 1e-6 * lc if c < nc else 1e-6
            at = sigma[c]
            sigma[c] = at + h
            ok_plus = _place_chain(q_plus, rotation_plus, sigma, att_body, att_ref, chain_int, chain_float)
            sigma[c] = at - h
            ok_minus = _place_chain(q_minus, rotation_minus, sigma, att_body, att_ref, chain_int, chain_float)
            sigma[c] = at
            if not (ok_plus and ok_minus):
                return q, True, False
            _input_residuals(q_plus, rotation_plus, s, att_body, att_ref, cyl_att, angle_body, angle_reference, lc,
                             r_plus)
            _input_residuals(q_minus, rotation_minus, s, att_body, att_ref, cyl_att, angle_body, angle_reference, lc,
                             r_minus)
            for i in range(n_in):
                slope[i, j] = (r_plus[i] - r_minus[i]) / (2.0 * h)
        for j in range(d):   # Gauss-Newton: the normal equations
            acc = 0.0
            for i in range(n_in):
                acc -= slope[i, j] * r[i]
            normal[j, d] = acc
            for k in range(d):
                acc = 0.0
                for i in range(n_in):
                    acc += slope[i, j] * slope[i, k]
                normal[j, k] = acc
        if not _solve_normal(normal):
            return q, True, False
        size = 0.0
        for j in range(d):
            v = abs(normal[j, d]) * (1.0 if drivers[j] < nc else lc)
            if not v <= size:
                size = v
        if not math.isfinite(size):
            return q, True, False
        for j in range(d):
            sigma[drivers[j]] += normal[j, d]
        if not _place_chain(q, rotation, sigma, att_body, att_ref, chain_int, chain_float):
            return q, False, False
        if size <= tol:
            return q, True, True
        _input_residuals(q, rotation, s, att_body, att_ref, cyl_att, angle_body, angle_reference, lc, r)
    return q, True, False


@njit(cache=True)
def _same_inputs(s: np.ndarray, s_start: np.ndarray) -> bool:
    """Whether the inputs s are exactly the start pose's (then the start pose is theirs)."""
    for j in range(s.shape[0]):
        if s[j] != s_start[j]:
            return False
    return True


@njit(cache=True)
def _solve_normal(a: np.ndarray) -> bool:
    """Gauss-Jordan in place on a (d, d + 1) = [A | b], A symmetric positive definite (normal
    equations: no pivoting needed): the solution into the last column; False when A is singular."""
    d = a.shape[0]
    for j in range(d):
        pivot = a[j, j]
        if not pivot > 0.0:
            return False
        for c in range(j, d + 1):
            a[j, c] /= pivot
        for i in range(d):
            if i != j:
                f = a[i, j]
                for c in range(j, d + 1):
                    a[i, c] -= f * a[j, c]
    return True


@njit(cache=True)
def _max_abs(v: np.ndarray) -> float:
    """Largest |v_i|; NaN if any entry is NaN."""
    big = 0.0
    for x in v:
        if not abs(x) <= big:
            big = abs(x)
    return big


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


@njit(cache=True)
def _kinematic_pose(i: int, q_out: np.ndarray, phi_out: np.ndarray, cond: np.ndarray, on_branch: np.ndarray,
                    q_start: np.ndarray, s_start: np.ndarray, s: np.ndarray, max_iter: int, with_condition: bool,
                    kin: KinematicsProgram) -> None:
    """Pose i of ``solve_poses``, written into the output arrays (the condition number NaN unless
    ``with_condition``).

    A chain's pose — in closed form, or fitted along the chain where sensors are redundant — places
    every circle intersection on the reference pose's side: it is on the reference branch
    (test_chain.py holds it against the Jacobian's loop signs), and Φ says it closes; no Newton,
    and a Jacobian only for the condition number. Otherwise (no chain, a step out of reach, a fit
    that does not converge, a closed form that does not close) Newton, from the tangent prediction
    off the start pose (its Jacobian evaluated here) or from the chain's pose, and the loop signs
    of the Jacobian decide the branch. Inputs exactly the start pose's: the start pose (solved for
    them, on the branch)."""
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
    out = (np.empty((n_pose, n)), np.empty((n_pose, m)), np.empty(n_pose), np.empty(n_pose, dtype=np.bool_))
    driver: Any = _kinematics_parallel if _parallel(n_pose) else _kinematics_serial
    driver(n_pose, *out, q_start, s_start, s, max_iter, with_condition, *kin)
    return out


_KINEMATIC_ARGS = 9   # ``_kinematic_pose``'s arguments before its program (outputs, start, inputs, max_iter, ...)


@njit(cache=True)
def _kinematics_serial(n_pose, *args):
    kin = KinematicsProgram(*args[_KINEMATIC_ARGS:])
    for i in range(n_pose):
        _kinematic_pose(i, *args[:_KINEMATIC_ARGS], kin)


@njit(cache=True, parallel=True)
def _kinematics_parallel(n_pose, *args):   # a record cannot enter a parallel loop: rebuilt in it from its fields
    for i in prange(n_pose):
        _kinematic_pose(i, *args[:_KINEMATIC_ARGS], KinematicsProgram(*args[_KINEMATIC_ARGS:]))


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
def residual_jacobian_batch(q: np.ndarray, s: np.ndarray, att_body: np.ndarray, att_ref: np.ndarray,
                            hinge_att: np.ndarray, cyl_att: np.ndarray, angle_body: np.ndarray,
                            angle_reference: np.ndarray, lc: float) -> tuple[np.ndarray, np.ndarray]:
    """``residual_jacobian`` for N poses: Φ (N, m), ∂Φ/∂q (N, m, n)."""
    n_pose, n = q.shape
    m = 2 * hinge_att.shape[1] + cyl_att.shape[1] + angle_body.shape[1]
    phi_out = np.empty((n_pose, m))
    jac_out = np.empty((n_pose, m, n))
    for i in range(n_pose):
        phi_out[i], jac_out[i] = residual_jacobian(q[i], s[i], att_body, att_ref, hinge_att, cyl_att, angle_body,
                                                   angle_reference, lc)
    return phi_out, jac_out


def positions_batch(q: np.ndarray, att_body: np.ndarray, att_ref: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``positions`` for N poses: p, rel (N, K, 2). Large batches run on every core (``allow_threads``)."""
    n_pose, k_att = q.shape[0], att_body.shape[0]
    p, rel = np.empty((n_pose, k_att, 2)), np.empty((n_pose, k_att, 2))
    driver: Any = _positions_parallel if _parallel(n_pose) else _positions_serial
    driver(q, att_body, att_ref, p, rel)
    return p, rel


@njit(cache=True)
def _positions_serial(q: np.ndarray, att_body: np.ndarray, att_ref: np.ndarray, p: np.ndarray, rel: np.ndarray
                      ) -> None:
    rotation = np.empty((2, q.shape[1] // 3))
    for i in range(q.shape[0]):
        _positions_into(q[i], att_body, att_ref, p[i], rel[i], rotation)


@njit(cache=True, parallel=True)
def _positions_parallel(q: np.ndarray, att_body: np.ndarray, att_ref: np.ndarray, p: np.ndarray, rel: np.ndarray
                        ) -> None:
    n_pose = q.shape[0]
    n_parts = min(n_pose, PARALLEL_PARTS)
    for part in prange(n_parts):
        rotation = np.empty((2, q.shape[1] // 3))
        for i in range(part * n_pose // n_parts, (part + 1) * n_pose // n_parts):
            _positions_into(q[i], att_body, att_ref, p[i], rel[i], rotation)


# ---- equilibrium -----------------------------------------------------------------------------------
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
    out = (np.empty((n_pose, n_unknowns)), np.empty(n_pose), np.empty(n_pose), np.empty((n_pose, n_members, 2)),
           np.empty((n_pose, n_members)))
    driver = _statics_parallel if _parallel(n_pose) else _statics_serial
    driver(n_pose, *out, p, member_force, accel, alpha, has_accel, *layout)
    return out


_STATICS_ARGS = 10   # ``_statics_pose``'s arguments before its program (outputs, positions, loads)


@njit(cache=True)
def _statics_pose(i, u_out, residual, cond, axes, lengths, p, member_force, accel, alpha, has_accel,
                  layout: StaticsProgram):
    """Pose i of ``solve_statics``, written into the output arrays."""
    n_unknowns = u_out.shape[1]
    lc, n_eq = layout.lc, layout.n_eq
    _member_axes(i, axes, lengths, p, layout.member_att)
    a_mat = equilibrium_matrix(p[i], axes[i], lc, n_eq, n_unknowns, layout.t_col, layout.t_att, layout.t_body,
                               layout.t_const, layout.t_member, layout.t_sign)
    b = np.zeros(n_eq)
    _known_loads(b, i, p, axes, member_force, accel, alpha, has_accel, layout)
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
    residual[i] = math.sqrt(acc)
    cond[i] = c


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
def _known_loads(b: np.ndarray, i: int, p: np.ndarray, axes: np.ndarray, member_force: np.ndarray,
                 accel: np.ndarray, alpha: np.ndarray, has_accel: bool, layout: StaticsProgram) -> None:
    """The known loads of pose i as generalized forces into b (n_eq,) ([Fx, Fz, M/lc] per body,
    ``solve_statics``' layout): constant loads, the ends of members of known force, and with
    ``has_accel`` the inertia loads −m·a at each cg and −I·α (Naumenko et al. 2021)."""
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
    if has_accel:
        for k in range(mass_att.shape[0]):
            att = mass_att[k]
            _add_generalized(b, 3 * mass_body[k], p[i, att, 0], p[i, att, 1], -mass[k] * accel[i, k, 0],
                             -mass[k] * accel[i, k, 1], lc)
            b[3 * mass_body[k] + 2] -= inertia[k] * alpha[i, k] / lc


@njit(cache=True)
def _statics_serial(n_pose, *args):
    layout = StaticsProgram(*args[_STATICS_ARGS:])
    for i in range(n_pose):
        _statics_pose(i, *args[:_STATICS_ARGS], layout)


@njit(cache=True, parallel=True)
def _statics_parallel(n_pose, *args):   # a record cannot enter a parallel loop: rebuilt in it from its fields
    for i in prange(n_pose):
        _statics_pose(i, *args[:_STATICS_ARGS], StaticsProgram(*args[_STATICS_ARGS:]))


# ---- reduced coordinates: transmission and statics along the chain of dyads (chain.py) ---------------
@njit(cache=True)
def _sine_between(ux: float, uz: float, vx: float, vz: float) -> float:
    """|sin| of the angle between two vectors: |u × v| / (|u|·|v|) (NaN when either is zero)."""
    return abs(ux * vz - uz * vx) / (math.sqrt(ux * ux + uz * uz) * math.sqrt(vx * vx + vz * vz))


@njit(cache=True)
def step_transmission(p: np.ndarray, row: np.ndarray) -> float:
    """The transmission measure of one chain step at attachment positions p (K, 2) m, in [0, 1]:
    RRR: |sin μ|, μ the transmission angle between its two links at their common hinge H (the
    angle A1–H–A2, A1 and A2 the links' pivots on placed bodies); CYLINDER: |sin| of the angle
    between the cylinder's line and the arm's radius from the pivot to the cylinder end (the
    cylinder's moment arm about the pivot over that radius); ANGLE: NaN (no transmission)."""
    if row[KIND] == RRR:
        hx, hz = p[row[A_JOINT1], 0], p[row[A_JOINT1], 1]
        return _sine_between(hx - p[row[A_PARENT], 0], hz - p[row[A_PARENT], 1],
                             hx - p[row[A_PARENT2], 0], hz - p[row[A_PARENT2], 1])
    if row[KIND] == CYLINDER:
        ex, ez = p[row[A_END], 0], p[row[A_END], 1]
        return _sine_between(ex - p[row[A_PARENT], 0], ez - p[row[A_PARENT], 1],
                             ex - p[row[A_OTHER], 0], ez - p[row[A_OTHER], 1])
    return math.nan


@njit(cache=True)
def transmission_pose(p: np.ndarray, chain_int: np.ndarray, sine: np.ndarray) -> int:
    """Each step's ``step_transmission`` at positions p (K, 2) into sine (S,); returns the step
    with the smallest (the pose's measure), −1 when no step has one (angle-driven steps only)."""
    weakest = -1
    for k in range(chain_int.shape[0]):
        sine[k] = step_transmission(p, chain_int[k])
        if not math.isnan(sine[k]) and (weakest < 0 or sine[k] < sine[weakest]):
            weakest = k
    return weakest


@njit(cache=True)
def transmission_batch(p: np.ndarray, chain_int: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``transmission_pose`` of N poses p (N, K, 2): per step |sin| (N, S + 1) in
    ``solve_reduced_statics``' layout (the free load's column NaN: it depends on the statics), the
    weakest step (N,)."""
    n_steps = chain_int.shape[0]
    sine = np.full((p.shape[0], n_steps + 1), math.nan)
    weakest = np.empty(p.shape[0], dtype=np.int64)
    for i in range(p.shape[0]):
        weakest[i] = transmission_pose(p[i], chain_int, sine[i, :n_steps])
    return sine, weakest


@njit(cache=True)
def _wrench_about(g: np.ndarray, body: int, ax: float, az: float, lc: float) -> tuple[float, float, float]:
    """The loads on ``body`` gathered in g ([Fx, Fz, M/lc] per body, M about the origin) as (Fx, Fz) N
    and their moment (N·m) about the point (ax, az) m: M − (a × F)."""
    fx, fz = g[3 * body], g[3 * body + 1]
    return fx, fz, g[3 * body + 2] * lc - (ax * fz - az * fx)


@njit(cache=True)
def _hinge_force(u: np.ndarray, hinge_cols: np.ndarray, att_body: np.ndarray, hinge_att: np.ndarray, h: int,
                 body: int, fx: float, fz: float) -> None:
    """Hinge h's force (fx, fz) N on ``body`` into u, as the statics report it: on bodies[1] from bodies[0]."""
    sign = 1.0 if att_body[hinge_att[1, h]] == body else -1.0
    u[hinge_cols[h, 0]], u[hinge_cols[h, 1]] = sign * fx, sign * fz


@njit(cache=True)
def _pivot_reaction(g: np.ndarray, u: np.ndarray, p: np.ndarray, lc: float, att_body: np.ndarray,
                    hinge_att: np.ndarray, hinge_cols: np.ndarray, h: int, body: int, a_parent: int, fx: float,
                    fz: float) -> None:
    """``body``'s loads summing to (fx, fz) N are held at hinge h by its placed parent: the hinge's
    force on ``body`` is −(fx, fz) (ΣF = 0), and (fx, fz) goes on to the parent at ``a_parent``."""
    _hinge_force(u, hinge_cols, att_body, hinge_att, h, body, -fx, -fz)
    parent = att_body[a_parent]
    if parent >= 0:
        _add_generalized(g, 3 * parent, p[a_parent, 0], p[a_parent, 1], fx, fz, lc)


@njit(cache=True, error_model="numpy")
def _reverse_pass(g: np.ndarray, u: np.ndarray, p: np.ndarray, axes: np.ndarray, lc: float, att_body: np.ndarray,
                  hinge_att: np.ndarray, chain_int: np.ndarray, hinge_cols: np.ndarray, step_col: np.ndarray,
                  step_member: np.ndarray, step_sign: np.ndarray) -> float:
    """Equilibrium of one pose step by step from the outermost step inward (reverse placement
    order), for the loads g (n_eq,) ([Fx, Fz, M/lc] per body; the reactions found are added to the
    placed bodies as they are found): the step's unknowns into u (the statics layout's columns).

    - RRR (B1 pivoted at A1, B2 at A2, hinged to each other at H): moments about A1 of B1 and
      about A2 of B2 give the joint force J on B1 (2×2, Cramer):
      (H − A1) × J = −M1, (H − A2) × J = M2, det = (H − A1) × (H − A2) = |HA1|·|HA2|·sin μ;
      then the pivots' forces from ΣF: −(F1 + J) on B1, −(F2 − J) on B2 (Popov 2009's hand solution,
      the moment about each dyad's hinges).
    - CYLINDER with an unknown force (B pivoted at A, the cylinder on B's end E): the moment about A,
      M + (E − A) × f·e = 0, e the unit force on B per newton: f = −M / ((E − A) × e); its other end
      takes −f·e; the pivot's force from ΣF.
    - ANGLE, or CYLINDER with a measured force (already among the known loads): the pivot's force
      from ΣF; the moment about the pivot is left over (no actuator holds it): returned, the
      closing equation ``_reduced_pose`` makes vanish.

    Returns the closing step's moment (N·m), 0 without one (at most one: ``ReducedStatics``' rule).
    """
    closing = 0.0
    for k in range(chain_int.shape[0] - 1, -1, -1):
        row = chain_int[k]
        body = row[BODY]
        ax, az = p[row[A_BODY], 0], p[row[A_BODY], 1]
        fx, fz, moment = _wrench_about(g, body, ax, az, lc)
        if row[KIND] == RRR:
            body2 = row[BODY2]
            a2x, a2z = p[row[A_BODY2], 0], p[row[A_BODY2], 1]
            f2x, f2z, moment2 = _wrench_about(g, body2, a2x, a2z, lc)
            r1x, r1z = p[row[A_JOINT1], 0] - ax, p[row[A_JOINT1], 1] - az
            r2x, r2z = p[row[A_JOINT2], 0] - a2x, p[row[A_JOINT2], 1] - a2z
            det = r1x * r2z - r1z * r2x
            jx = (-moment * r2x - r1x * moment2) / det
            jz = (-r1z * moment2 - r2z * moment) / det
            _hinge_force(u, hinge_cols, att_body, hinge_att, row[STEP_JOINT], body, jx, jz)
            _pivot_reaction(g, u, p, lc, att_body, hinge_att, hinge_cols, row[STEP_HINGE], body, row[A_PARENT],
                            fx + jx, fz + jz)
            _pivot_reaction(g, u, p, lc, att_body, hinge_att, hinge_cols, row[STEP_HINGE2], body2, row[A_PARENT2],
                            f2x - jx, f2z - jz)
            continue
        if row[KIND] == CYLINDER and step_col[k] >= 0:
            ex, ez = step_sign[k] * axes[step_member[k], 0], step_sign[k] * axes[step_member[k], 1]
            force = -moment / ((p[row[A_END], 0] - ax) * ez - (p[row[A_END], 1] - az) * ex)
            u[step_col[k]] = force
            fx, fz = fx + force * ex, fz + force * ez
            other = row[A_OTHER]
            if att_body[other] >= 0:
                _add_generalized(g, 3 * att_body[other], p[other, 0], p[other, 1], -force * ex, -force * ez, lc)
        else:
            closing = moment
        _pivot_reaction(g, u, p, lc, att_body, hinge_att, hinge_cols, row[STEP_HINGE], body, row[A_PARENT], fx, fz)
    return closing


def solve_reduced_statics(p: np.ndarray, member_force: np.ndarray, accel: np.ndarray, alpha: np.ndarray,
                          has_accel: bool, n_unknowns: int, layout: StaticsProgram, reduced: ReducedProgram
                          ) -> tuple[np.ndarray, ...]:
    """``solve_statics`` in reduced coordinates: the same unknowns u (N, n_unknowns) for the same
    loads (arguments as there; ``layout``: ``StaticsLayout.program``), found along the chain of
    dyads (``_reverse_pass``) with no linear system. ``reduced``: ``ReducedStatics.program``.

    Returns u, the equilibrium residual (N,) N·m (the closing equation's moment left over; 0
    without one), the transmission (N, S + 1): each step's |sin| (``step_transmission``) then the
    free load's (``_reduced_pose``; NaN without one), the weakest of them (N,) (S: the free load;
    −1: none), member unit axes (N, M, 2) and lengths (N, M) m.
    """
    n_pose = p.shape[0]
    n_members = member_force.shape[1]
    out = (np.empty((n_pose, n_unknowns)), np.empty(n_pose), np.empty((n_pose, reduced.chain_int.shape[0] + 1)),
           np.empty(n_pose, dtype=np.int64), np.empty((n_pose, n_members, 2)), np.empty((n_pose, n_members)))
    driver = _reduced_parallel if _parallel(n_pose) else _reduced_serial
    driver(n_pose, *out, p, member_force, accel, alpha, has_accel, *layout, *reduced)
    return out


_REDUCED_ARGS = 11   # ``_reduced_pose``'s arguments before its programs (outputs, positions, loads)
_REDUCED_LAYOUT_END = _REDUCED_ARGS + len(StaticsProgram._fields)


@njit(cache=True, error_model="numpy")
def _reduced_pose(i, u_out, residual, sine, weakest, axes, lengths, p, member_force, accel, alpha, has_accel,
                  layout: StaticsProgram, reduced: ReducedProgram, work: np.ndarray):
    """Pose i of ``solve_reduced_statics``, written into the output arrays; ``work``: room for its
    loads and unknowns (``_reduced_work``), overwritten.

    The statics are linear in the loads: with a free load λ (``free_col`` ≥ 0: a contact's normal
    force, the implement's vertical load, a cylinder that drives no step), the chain is solved for
    the known loads and for λ = 1 alone (superposition), and λ makes the closing step's moment
    vanish: λ = −M_known / M_unit.

    The free load's transmission, as a cylinder step's: its moment arm about the closing step's
    pivot A over the radius from A to its point P (to the farther of its points on moving bodies),
    |sin| = |M_unit| / (|e|·|P − A|), e its force per unit λ — for a load on the closing step's own
    body the sine of the angle between its line and that radius; through the chain M_unit is the
    load's virtual work per unit rotation of the closing step (1 when larger than the radius). At
    0 the load does no work on the motion the closing equation balances, and it is not determined:
    a static dead centre of the general path that no link's transmission shows.
    """
    lc, t_col = layout.lc, layout.t_col
    chain_int, free_col, closing_step = reduced.chain_int, reduced.free_col, reduced.closing_step
    _member_axes(i, axes, lengths, p, layout.member_att)
    n_steps = chain_int.shape[0]
    n_cases = work.shape[0]   # the known loads; λ = 1 alone (with a free load)
    n_eq = layout.n_eq
    work[:, :] = 0.0
    loads, u = work[:, :n_eq], work[:, n_eq:]
    _known_loads(loads[0], i, p, axes, member_force, accel, alpha, has_accel, layout)
    size, radius = 0.0, 0.0   # |e| N per unit λ; |P − A| m
    if free_col >= 0:
        pivot = chain_int[closing_step, A_BODY]
        for t in range(t_col.shape[0]):
            if t_col[t] == free_col:
                fx, fz = _term_force(t, axes[i], layout.t_const, layout.t_member, layout.t_sign)
                px, pz = p[i, layout.t_att[t], 0], p[i, layout.t_att[t], 1]
                _add_generalized(loads[1], 3 * layout.t_body[t], px, pz, fx, fz, lc)
                size = math.sqrt(fx * fx + fz * fz)
                radius = max(radius, math.hypot(px - p[i, pivot, 0], pz - p[i, pivot, 1]))
    closing_known = _reverse_pass(loads[0], u[0], p[i], axes[i], lc, reduced.att_body, reduced.hinge_att, chain_int,
                                  reduced.hinge_cols, reduced.step_col, reduced.step_member, reduced.step_sign)
    closing_unit = 0.0 if n_cases == 1 else _reverse_pass(
        loads[1], u[1], p[i], axes[i], lc, reduced.att_body, reduced.hinge_att, chain_int, reduced.hinge_cols,
        reduced.step_col, reduced.step_member, reduced.step_sign)
    weakest[i] = transmission_pose(p[i], chain_int, sine[i, :n_steps])
    if free_col >= 0:
        free = -closing_known / closing_unit
        for j in range(u_out.shape[1]):
            u_out[i, j] = u[0, j] + free * u[1, j]
        u_out[i, free_col] = free
        residual[i] = abs(closing_known + free * closing_unit)
        sine[i, n_steps] = min(abs(closing_unit) / (size * radius), 1.0)
        if weakest[i] < 0 or not sine[i, n_steps] >= sine[i, weakest[i]]:
            weakest[i] = n_steps
    else:
        u_out[i] = u[0]
        residual[i] = 0.0
        sine[i, n_steps] = math.nan


@njit(cache=True)
def _reduced_work(layout: StaticsProgram, reduced: ReducedProgram, n_unknowns: int) -> np.ndarray:
    """Room for ``_reduced_pose``'s loads and unknowns: a row per load case (the known loads, and
    λ = 1 alone with a free load), the n_eq loads then the unknowns."""
    return np.empty((2 if reduced.free_col >= 0 else 1, layout.n_eq + n_unknowns))


@njit(cache=True)
def _reduced_serial(n_pose, *args):
    layout = StaticsProgram(*args[_REDUCED_ARGS:_REDUCED_LAYOUT_END])
    reduced = ReducedProgram(*args[_REDUCED_LAYOUT_END:])
    work = _reduced_work(layout, reduced, args[0].shape[1])
    for i in range(n_pose):
        _reduced_pose(i, *args[:_REDUCED_ARGS], layout, reduced, work)


@njit(cache=True, parallel=True)
def _reduced_parallel(n_pose, *args):   # records cannot enter a parallel loop: rebuilt in it from their fields
    n_parts = min(n_pose, PARALLEL_PARTS)   # each part its own work room
    for part in prange(n_parts):
        layout = StaticsProgram(*args[_REDUCED_ARGS:_REDUCED_LAYOUT_END])
        reduced = ReducedProgram(*args[_REDUCED_LAYOUT_END:])
        work = _reduced_work(layout, reduced, args[0].shape[1])
        for i in range(part * n_pose // n_parts, (part + 1) * n_pose // n_parts):
            _reduced_pose(i, *args[:_REDUCED_ARGS], layout, reduced, work)


# ---- lift capacity by virtual work ------------------------------------------------------------------
def lift_capacity(q: np.ndarray, att_body: np.ndarray, att_ref: np.ndarray, hinge_att: np.ndarray,
                  cyl_att: np.ndarray, lift: int, force: float, gravity: float, weight_att: np.ndarray,
                  weight_mass: np.ndarray, spring_att: np.ndarray, spring_force: np.ndarray,
                  point_att: np.ndarray, column_scale: np.ndarray, max_condition: float, ok: np.ndarray,
                  implement_load: np.ndarray, cg_point: int) -> np.ndarray:
    """Vertical load (N, + = down) that the lift cylinder ``lift`` pushing with ``force`` (N) holds
    at each capacity point (attachments ``point_att``), for N poses q (N, n): virtual work along
    the motion with every hinge closed, every other cylinder held at its length and the lift
    cylinder extending by δs:

        G·δz_point = F·δs − Σ m·g·δz_cg + Σ F_spring·δL_spring        (Popov 2009: G = p_max·η·A·ds/dz)

    (weights m at ``weight_att``, spring forces (N, n_springs) + = pushing). The motion δq solves
    [hinge rows; cylinder rows]·δq = e_lift, one factorization per pose for every point.

    Returns (N, n_points + 1): G at each point, NaN where the pose is not ``ok`` (failed), where
    that system is near-singular (condition > ``max_condition``: a dead centre) or not square, and
    where G ≤ 0 (the cylinder lowers the point instead of lifting it: no capacity, not a negative
    load); then the lift reserve, G at point ``cg_point`` / ``implement_load`` (N,) N, inf where
    that load is not > 0.
    """
    n_pose, n = q.shape
    out = np.full((n_pose, point_att.shape[0] + 1), np.nan)
    square = 2 * hinge_att.shape[1] + cyl_att.shape[1] == n
    driver = _capacity_parallel if _parallel(n_pose) else _capacity_serial
    driver(n_pose, out, q, att_body, att_ref, hinge_att, cyl_att, lift, force, gravity, weight_att, weight_mass,
           spring_att, spring_force, point_att, column_scale, max_condition, ok, square, implement_load, cg_point)
    return out


@njit(cache=True)
def _capacity_pose(i, out, q, att_body, att_ref, hinge_att, cyl_att, lift, force, gravity, weight_att,
                   weight_mass, spring_att, spring_force, point_att, column_scale, max_condition, ok, square,
                   implement_load, cg_point):
    """Pose i of ``lift_capacity``, written into ``out`` (NaN on entry)."""
    if ok[i] and square:
        _capacity_points(i, out, q, att_body, att_ref, hinge_att, cyl_att, lift, force, gravity, weight_att,
                         weight_mass, spring_att, spring_force, point_att, column_scale, max_condition)
    _reserve(out[i], cg_point, implement_load[i])


@njit(cache=True)
def _reserve(row, cg_point, load):
    """The lift reserve, the capacity row's last value: the capacity at the implement's cg (its
    ``cg_point``-th value) over the implement load ``load`` (N; ∞ without a load)."""
    row[-1] = row[cg_point] / load if load > 0.0 else math.inf


@njit(cache=True)
def _capacity_points(i, out, q, att_body, att_ref, hinge_att, cyl_att, lift, force, gravity, weight_att,
                     weight_mass, spring_att, spring_force, point_att, column_scale, max_condition):
    """G at each point of pose i (``lift_capacity``), written into ``out`` where > 0."""
    n = q.shape[1]
    nh, nc = hinge_att.shape[1], cyl_att.shape[1]
    _, jac = residual_jacobian(q[i], np.zeros(nc), att_body, att_ref, hinge_att, cyl_att,
                               np.zeros((2, 0), dtype=np.int64), np.zeros(0), 1.0)
    lu, piv, cond = factor_and_condition(jac * column_scale)   # square: ``condition``'s, and its LU for δq
    if not cond <= max_condition:
        return
    e = np.zeros(n)
    e[2 * nh + lift] = 1.0
    dq = lu_solve(lu, piv, e) * column_scale   # (J·diag(scale))·(δq / scale) = e
    p, rel = positions(q[i], att_body, att_ref)
    work = force
    for k in range(weight_att.shape[0]):
        work -= weight_mass[k] * gravity * _dp(dq, weight_att[k], att_body, rel)[1]
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
def _capacity_serial(n_pose, *args):
    for i in range(n_pose):
        _capacity_pose(i, *args)


@njit(cache=True, parallel=True)
def _capacity_parallel(n_pose, *args):
    for i in prange(n_pose):
        _capacity_pose(i, *args)


@njit(cache=True)
def _dp(dq: np.ndarray, att: int, att_body: np.ndarray, rel: np.ndarray) -> tuple[float, float]:
    """Displacement (δx, δz) of an attachment for the body motion dq (∂P/∂θ = i·rel)."""
    b = att_body[att]
    if b < 0:
        return 0.0, 0.0
    return dq[3 * b] - rel[att, 1] * dq[3 * b + 2], dq[3 * b + 1] + rel[att, 0] * dq[3 * b + 2]


# ---- axle loads and steerability (Popov 2009) --------------------------------------------------------
# ``steerability_pose``'s parameters (one float64 array, in this order) and its row's columns
# (machine.STEERABILITY_KEYS in this order)
STEERABILITY_PARAMETERS = ("gravity", "wheelbase", "ratio_min", "tractor_mass", "tractor_cg_x", "ballast_mass",
                           "ballast_x", "unit_reference")
STEERABILITY_COLUMNS = ("front_axle_load", "rear_axle_load", "total_weight", "wheelbase", "ratio", "ratio_min",
                        "margin", "front_ballast_needed", "ratio_unit", "ratio_tractor", "max_implement_mass")
N_STEERABILITY = len(STEERABILITY_COLUMNS)


@njit(cache=True)
def _not_negative(x: float) -> float:
    """max(0, x) that keeps NaN (as np.maximum does)."""
    return 0.0 if x < 0.0 else x


@njit(cache=True, error_model="numpy")
def steerability_pose(points: np.ndarray, forces: np.ndarray, implement_load: float, implement_x: float,
                      parameters: np.ndarray, row: np.ndarray) -> None:
    """Axle loads and steerability of one pose into ``row`` (len(STEERABILITY_COLUMNS)).

    points / forces (K, 2): m / N, the forces the linkage puts ON the frame (``frame_load_forces``);
    implement_load N and implement_x m: the implement's weight and its cg's x; parameters:
    STEERABILITY_PARAMETERS (``unit_reference`` 1.0: ratio of the unit's weight, 0.0: of the empty
    tractor's).

    Axle loads (Popov 2009's moment balance about B, on the tractor's free body):
    L·R_A = m_tr·g·x_tr + m_cw·g·x_cw − Σ(x·Fz − z·Fx); R_B = (m_tr + m_cw)·g − ΣFz − R_A.
    Steerability (Popov 2009): k = R_A / W ≥ ratio_min = r, W = R_A + R_B (unit) or m_tr·g (tractor).
    By global equilibrium R_A grows by g·x/L per kg at x, so with c = 1 for the unit and 0 for the
    tractor reference: the extra front ballast for k = r (front_ballast_needed, beyond the m_cw0
    carried) Δm_cw = max(0, (r·W − R_A)/(g·(x_cw/L − r·c))), 0 when k ≥ r;
    largest implement mass m_6 = P_6/g + (R_A − r·W)/(g·(r·c − x_S6/L)); inf where the
    denominator is ≤ 0 and the ratio is not reached (ballast or mass cannot reach it), never below 0.
    """
    g, wheelbase, r = parameters[0], parameters[1], parameters[2]
    tractor_mass, tractor_x, ballast_mass, ballast_x = parameters[3], parameters[4], parameters[5], parameters[6]
    unit = parameters[7] > 0.5
    tractor_weight = tractor_mass * g
    c = 1.0 if unit else 0.0
    ballast_slope = g * (ballast_x / wheelbase - r * c)
    moment, lift = 0.0, 0.0
    for k in range(points.shape[0]):
        moment += points[k, 0] * forces[k, 1] - points[k, 1] * forces[k, 0]
        lift += forces[k, 1]
    front = (tractor_weight * tractor_x + ballast_mass * g * ballast_x - moment) / wheelbase
    rear = (tractor_mass + ballast_mass) * g - lift - front
    total = front + rear
    ratio_unit, ratio_tractor = front / total, front / tractor_weight
    ref_weight, ratio = (total, ratio_unit) if unit else (tractor_weight, ratio_tractor)
    shortfall = r * ref_weight - front   # N of front axle load missing for k = r
    if ratio >= r:   # none missing: decided as the margin is (a shortfall of rounding is not a ballast)
        ballast = 0.0
    else:
        ballast = max(shortfall / ballast_slope, 0.0) if ballast_slope > 0.0 else math.inf
    implement_slope = g * (r * c - implement_x / wheelbase)
    max_mass = (_not_negative(implement_load / g + (front - r * ref_weight) / implement_slope)
                if implement_slope > 0.0 else math.inf)
    row[0], row[1], row[2], row[3], row[4], row[5] = front, rear, total, wheelbase, ratio, r
    row[6], row[7], row[8], row[9], row[10] = ratio - r, ballast, ratio_unit, ratio_tractor, max_mass


@njit(cache=True, error_model="numpy")
def steerability_rows(points: np.ndarray, forces: np.ndarray, implement_load: np.ndarray, implement_x: np.ndarray,
                      parameters: np.ndarray) -> np.ndarray:
    """``steerability_pose`` of N poses (points / forces (N, K, 2), implement_load / implement_x
    (N,)): (N, len(STEERABILITY_COLUMNS))."""
    out = np.empty((points.shape[0], N_STEERABILITY))
    for i in range(points.shape[0]):
        steerability_pose(points[i], forces[i], implement_load[i], implement_x[i], parameters, out[i])
    return out


@njit(cache=True)
def largest_force(hinge_force: np.ndarray, cylinder_force: np.ndarray) -> float:
    """The largest hinge reaction or cylinder force magnitude (N) of one pose: hinge_force (H, 2)
    N, cylinder_force (C,) N; 0 with neither, NaN where any of them is NaN (a failed pose)."""
    largest = 0.0
    for h in range(hinge_force.shape[0]):
        magnitude = math.hypot(hinge_force[h, 0], hinge_force[h, 1])
        if math.isnan(magnitude):
            return math.nan
        largest = max(largest, magnitude)
    for c in range(cylinder_force.shape[0]):
        magnitude = abs(cylinder_force[c])
        if math.isnan(magnitude):
            return math.nan
        largest = max(largest, magnitude)
    return largest


@njit(cache=True)
def largest_forces(hinge_force: np.ndarray, cylinder_force: np.ndarray) -> np.ndarray:
    """``largest_force`` of N poses: hinge_force (N, H, 2), cylinder_force (N, C) -> (N,) N."""
    out = np.empty(hinge_force.shape[0])
    for i in range(hinge_force.shape[0]):
        out[i] = largest_force(hinge_force[i], cylinder_force[i])
    return out


@njit(cache=True)
def pack_row(out: np.ndarray, hinge_force: np.ndarray, point_xz: np.ndarray, cylinder_values: np.ndarray,
             scalars: np.ndarray, implement_cg: np.ndarray, capacity: np.ndarray, steerability: np.ndarray) -> None:
    """A pose's value row (``programs.ValueRow``) into out: from its hinge forces (H, 2) N, points
    (P, 2) m, cylinder values (C, 5), ``ROW_SCALARS`` (4,), implement cg (2,) m, capacity and
    steerability rows."""
    k = 0
    for h in range(hinge_force.shape[0]):
        out[k], out[k + 1] = hinge_force[h, 0], hinge_force[h, 1]
        k += 2
    for h in range(hinge_force.shape[0]):
        out[k] = math.hypot(hinge_force[h, 0], hinge_force[h, 1])
        k += 1
    for a in range(point_xz.shape[0]):
        out[k], out[k + 1] = point_xz[a, 0], point_xz[a, 1]
        k += 2
    for c in range(cylinder_values.shape[0]):
        for j in range(5):
            out[k + j] = cylinder_values[c, j]
        k += 5
    k = _copy_into(out, k, scalars)
    k = _copy_into(out, k, implement_cg)
    k = _copy_into(out, k, capacity)
    _copy_into(out, k, steerability)


@njit(cache=True)
def _copy_into(out: np.ndarray, k: int, part: np.ndarray) -> int:
    """part (1-d) into out from column k on; the column after it."""
    for j in range(part.shape[0]):
        out[k + j] = part[j]
    return k + part.shape[0]


@njit(cache=True)
def pack_rows(hinge_force: np.ndarray, point_xz: np.ndarray, cylinder_values: np.ndarray, scalars: np.ndarray,
              implement_cg: np.ndarray, capacity: np.ndarray, steerability: np.ndarray, width: int) -> np.ndarray:
    """``pack_row`` of N poses (each argument with a first axis of poses) -> (N, width)."""
    out = np.empty((hinge_force.shape[0], width))
    for i in range(hinge_force.shape[0]):
        pack_row(out[i], hinge_force[i], point_xz[i], cylinder_values[i], scalars[i], implement_cg[i], capacity[i],
                 steerability[i])
    return out


# ---- one live pose, end to end; a series of them -----------------------------------------------
def live_rows(n_pose: int, n: int, m: int, outputs: OutputsProgram, machine: MachineProgram) -> LiveRows:
    """Empty ``LiveRows`` for n_pose poses, for ``live_series`` to write, which also fills what a
    pose may leave unwritten (``_live_pose_at``).
    Allocated by the caller, uninitialised: numba returns a record of fresh arrays slower than it
    takes one in, and filling them here cost a third of this function's time on the live pose."""
    n_steer = N_STEERABILITY if machine.parameters.shape[0] > 0 else 0
    n_capacity = machine.point_att.shape[0] + 1 if machine.point_att.shape[0] > 0 else 0
    n_frame = outputs.frame_att.shape[0]
    return LiveRows(
        plain=np.zeros(n_pose, dtype=np.bool_), q=np.empty((n_pose, n)), phi=np.empty((n_pose, m)),
        kinematic_condition=np.empty(n_pose),
        point_xz=np.empty((n_pose, outputs.point_rows.shape[0], 2)),
        hinge_force=np.empty((n_pose, outputs.hinge_cols.shape[0], 2)),
        cylinder_values=np.empty((n_pose, outputs.per_cap_area.shape[0], 5)),
        contact_values=np.empty((n_pose, outputs.contact_cols.shape[0], 2)), implement_cg=np.empty((n_pose, 2)),
        frame_load_points=np.empty((n_pose, n_frame, 2)), frame_load_forces=np.empty((n_pose, n_frame, 2)),
        pose=np.empty(n_pose, dtype=POSE_VALUES), steerability=np.empty((n_pose, n_steer)),
        capacity=np.empty((n_pose, n_capacity)),
        values=np.empty((n_pose, ValueRow.of(outputs.hinge_cols.shape[0], outputs.point_rows.shape[0],
                                             outputs.per_cap_area.shape[0], n_capacity, n_steer).width)))


@njit(cache=True)
def live_programs(kin_fields, statics_fields, outputs_fields, reduced_fields, machine_fields):
    """The ``LivePrograms`` of one configuration from each program as a plain tuple of its fields
    (``programs.fields``): ``Kinematics.program``, ``StaticsLayout.program``,
    ``Solver.outputs_program`` of that layout, ``ReducedStatics.program`` of it,
    ``MachineModel.program`` (``NO_MACHINE`` when no machine-level results are wanted)."""
    return LivePrograms(KinematicsProgram(*kin_fields), StaticsProgram(*statics_fields),
                        OutputsProgram(*outputs_fields), ReducedProgram(*reduced_fields),
                        MachineProgram(*machine_fields))


@njit(cache=True)
def measured_force(cap: float, rod: float, cap_area: float, rod_area: float) -> float:
    """Axial force (N, + pushing) of a cylinder group from its gauge pressures (Pa; NaN = that
    chamber not measured, taken as 0) and its chambers' areas × count (m²): F = count·(p_cap·A_cap
    − p_rod·A_rod) (schema, cylinders[])."""
    return (0.0 if math.isnan(cap) else cap) * cap_area - (0.0 if math.isnan(rod) else rod) * rod_area


@njit(cache=True)
def measured_forces(cap: np.ndarray, rod: np.ndarray, force_areas: np.ndarray) -> np.ndarray:
    """``measured_force`` of N poses: cap, rod (N, C) Pa gauge, force_areas (2, C) m² -> (N, C) N."""
    out = np.empty(cap.shape)
    for i in range(cap.shape[0]):
        for k in range(cap.shape[1]):
            out[i, k] = measured_force(cap[i, k], rod[i, k], force_areas[0, k], force_areas[1, k])
    return out


@njit(cache=True)
def live_buffer(rows_fields, s, pressures):
    """The ``LiveBuffer`` of rows (``live_rows``' of N poses, as a plain tuple) and the inputs of the
    poses: s (N, n_inputs), pressures (N, 2, C) (``live_series``)."""
    return LiveBuffer(LiveRows(*rows_fields), s, pressures)


@njit(cache=True, nogil=True)   # a replay reads its next inputs while a part is solved
def live_series(programs, buffer, q_start, s_start, limit, max_condition, first, stop):
    """Poses first..stop−1 of ``buffer`` (``live_buffer``) as the live node solves them, in one
    compiled call: the live node's one pose (a row of the rows it keeps), a recorded series (replay:
    all its rows). Pose i from the last pose before it from ``first`` on that took this path, the
    first from (q_start (1, n), s_start (1, n_inputs)). The buffer's s (N, n_inputs): inputs (m,
    rad); its pressures (N, 2, C): per cylinder the cap and rod gauge pressures (Pa, NaN = not
    measured; ``measured_force`` of those whose force the layout takes as measured). limit: largest constraint residual
    accepted (m); max_condition: the dead-centre condition number of the general path (the
    kinematics' and the statics'; the reduced path's verdict is the transmission measure, and its
    kinematic condition number is NaN). ``programs``: the configuration's ``LivePrograms``
    (``live_programs``). Writes rows first..stop−1 of the buffer's rows.

    Each pose, from the per-pose kernels above: loop closure (``_kinematic_pose``), equilibrium with
    the measured cylinder forces — along the chain of dyads with the transmission verdict
    (``_reduced_pose``) where ``outputs.reduced``, else in one linear system with the
    condition-number verdict (``_statics_pose``) —, the arrays of a ``Result``, lift capacity
    (``_capacity_pose``) and steerability (``steerability_pose``), into the rows;
    ``plain[i]`` is False when pose i is not the usual one — off the reference branch, not
    assembled to ``limit``, at a dead centre, a contact lifting off — and then its rows are not
    meaningful: the general path (``Solver._solve``) words the verdict.
    """
    kin, statics, outputs, reduced, machine = (programs.kin, programs.statics, programs.outputs, programs.reduced,
                                               programs.machine)
    rows, s, pressures = buffer.rows, buffer.s, buffer.pressures
    last = -1
    for i in range(first, stop):
        if last < 0:
            _live_pose_at(i, rows, s, pressures, q_start, s_start, rows.capacity[i, :0], limit, max_condition, kin,
                          statics, outputs, reduced, machine)
        else:
            _live_pose_at(i, rows, s, pressures, rows.q[last:last + 1], s[last:last + 1], rows.capacity[last], limit,
                          max_condition, kin, statics, outputs, reduced, machine)
        if rows.plain[i]:
            last = i


@njit(cache=True)
def smallest_sine(sine: np.ndarray, weakest: int) -> float:
    """The pose's transmission measure from its measures' |sin| (``_reduced_pose``): that of the
    weakest, 1 when none has one, 0 when the weakest's is undefined (a free load doing no work)."""
    if weakest < 0:
        return 1.0
    value = sine[weakest]
    return 0.0 if math.isnan(value) else min(value, 1.0)


@njit(cache=True)
def smallest_sines(sine: np.ndarray, weakest: np.ndarray) -> np.ndarray:
    """``smallest_sine`` of N poses: sine (N, measures), weakest (N,)."""
    out = np.empty(weakest.shape[0])
    for i in range(weakest.shape[0]):
        out[i] = smallest_sine(sine[i], weakest[i])
    return out


@njit(cache=True)
def _live_statics(i, rows, p, member_force, u_out, axes, lengths, max_condition, statics, outputs, reduced) -> bool:
    """Equilibrium of pose i of ``live_series`` into u_out (1, n_unknowns), member axes and lengths,
    its residual, condition and transmission into ``rows``: False at a dead centre — the smallest
    transmission below ``outputs.dead_centre_sine`` (reduced path) or the condition number above
    ``max_condition`` (general path)."""
    residual, no_accel, no_alpha = np.empty(1), np.zeros((1, 1, 2)), np.zeros((1, 1))
    if outputs.reduced:
        sine, weakest = np.empty((1, outputs.measure_count)), np.empty(1, dtype=np.int64)
        _reduced_pose(0, u_out, residual, sine, weakest, axes, lengths, p, member_force, no_accel, no_alpha, False,
                      statics, reduced, _reduced_work(statics, reduced, u_out.shape[1]))
        smallest = smallest_sine(sine[0], weakest[0])
        if not smallest >= outputs.dead_centre_sine:
            return False
        rows.pose[i].transmission_angle, rows.pose[i].weakest = math.asin(smallest), weakest[0]
        rows.pose[i].condition = rows.kinematic_condition[i]
    else:
        cond = np.empty(1)
        _statics_pose(0, u_out, residual, cond, axes, lengths, p, member_force, no_accel, no_alpha, False, statics)
        if not cond[0] <= max_condition:
            return False
        rows.pose[i].transmission_angle, rows.pose[i].weakest = math.nan, -1
        rows.pose[i].condition = max(cond[0], rows.kinematic_condition[i])
    rows.pose[i].residual = residual[0]
    return True


@njit(cache=True)
def _live_pose_at(i, rows, s, pressures, q_start, s_start, capacity_start, limit, max_condition, kin, statics,
                  outputs, reduced, machine):
    """Pose i of ``live_series``, written into its rows of ``rows`` (``LiveRows``). The rows of a
    pose that is not plain are left as they are (the general path writes them), except the
    implement cg and the capacities, NaN until written (no implement; a capacity not computed),
    and the transmission measure, NaN and −1 until the reduced statics give it. ``capacity_start``:
    the start pose's capacity row (empty when not known): a pose with the start pose's inputs has
    its capacities at the points (they depend on the pose alone) and only its reserve is computed."""
    rows.implement_cg[i, 0], rows.implement_cg[i, 1] = math.nan, math.nan
    rows.capacity[i, :] = math.nan
    rows.pose[i].transmission_angle, rows.pose[i].weakest = math.nan, -1
    member_att = statics.member_att   # (2, M): the ends of springs then cylinders
    n, m = rows.q.shape[1], rows.phi.shape[1]
    n_springs, n_cylinders = outputs.spring_stiffness.shape[0], outputs.per_cap_area.shape[0]
    n_members = n_springs + n_cylinders
    on_branch = np.empty(1, dtype=np.bool_)
    _kinematic_pose(0, rows.q[i:i + 1], rows.phi[i:i + 1], rows.kinematic_condition[i:i + 1], on_branch, q_start,
                    s_start, s[i:i + 1], 25, not outputs.reduced, kin)
    if not (on_branch[0] and assembled(rows.phi[i], 2 * kin.hinge_att.shape[1], kin.lc, limit)
            and (outputs.reduced or rows.kinematic_condition[i] <= max_condition)):
        return
    p1, _ = positions(rows.q[i], kin.att_body, kin.att_ref)
    p = p1.reshape((1, p1.shape[0], 2))
    member_force = np.empty((1, n_members))
    for k in range(n_springs):   # k·(free length − length) + preload (StaticsLayout.spring_forces)
        a, b = member_att[0, k], member_att[1, k]
        dx, dz = p1[b, 0] - p1[a, 0], p1[b, 1] - p1[a, 1]
        member_force[0, k] = outputs.spring_stiffness[k] * (outputs.spring_free_length[k] - math.sqrt(dx * dx + dz * dz)) \
            + outputs.spring_preload[k]
    measured = np.empty(n_cylinders)   # N: an unmeasured cylinder's force is an unknown
    for k in range(n_cylinders):
        measured[k] = measured_force(pressures[i, 0, k], pressures[i, 1, k], outputs.force_areas[0, k],
                                     outputs.force_areas[1, k]) if outputs.force_measured[k] else 0.0
        member_force[0, n_springs + k] = measured[k]
    u_out = np.empty((1, outputs.n_unknowns))
    axes, lengths = np.empty((1, n_members, 2)), np.empty((1, n_members))
    if not _live_statics(i, rows, p, member_force, u_out, axes, lengths, max_condition, statics, outputs, reduced):
        return
    u = u_out[0]
    contact_cols = outputs.contact_cols
    for k in range(contact_cols.shape[0]):
        if u[contact_cols[k]] < 0.0:   # lifts off
            return
    for k in range(contact_cols.shape[0]):
        normal = u[contact_cols[k]]
        rows.contact_values[i, k, 0], rows.contact_values[i, k, 1] = normal, outputs.friction[k] * normal
    for k in range(outputs.point_rows.shape[0]):
        a = outputs.point_rows[k]
        rows.point_xz[i, k, 0], rows.point_xz[i, k, 1] = p1[a, 0], p1[a, 1]
    hinge_cols = outputs.hinge_cols
    for h in range(hinge_cols.shape[0]):   # N on bodies[1] from bodies[0]
        rows.hinge_force[i, h, 0], rows.hinge_force[i, h, 1] = u[hinge_cols[h, 0]], u[hinge_cols[h, 1]]
    for k in range(n_cylinders):
        force = measured[k] if outputs.force_measured[k] else u[outputs.cylinder_cols[k]]
        member_force[0, n_springs + k] = force
        cylinder = rows.cylinder_values[i, k]   # CylinderResult's fields
        cylinder[0], cylinder[1] = lengths[0, n_springs + k], force
        cylinder[2] = force * outputs.per_cap_area[k]
        cylinder[3], cylinder[4] = pressures[i, 0, k], pressures[i, 1, k]
    rows.pose[i].largest_force = largest_force(rows.hinge_force[i], rows.cylinder_values[i, :, 1])
    n_frame_hinges = outputs.frame_hinge_index.shape[0]
    frame_points, frame_forces = rows.frame_load_points[i], rows.frame_load_forces[i]
    for j in range(outputs.frame_att.shape[0]):   # the forces ON the ground body: hinges, then member ends
        a = outputs.frame_att[j]
        frame_points[j, 0], frame_points[j, 1] = p1[a, 0], p1[a, 1]
        if j < n_frame_hinges:
            sign, h = outputs.frame_hinge_sign[j], outputs.frame_hinge_index[j]
            frame_forces[j, 0], frame_forces[j, 1] = sign * rows.hinge_force[i, h, 0], sign * rows.hinge_force[i, h, 1]
        else:
            e = outputs.frame_member_index[j - n_frame_hinges]
            f = outputs.frame_member_sign[j - n_frame_hinges] * member_force[0, e]
            frame_forces[j, 0], frame_forces[j, 1] = f * axes[0, e, 0], f * axes[0, e, 1]
    if outputs.cg_att >= 0:
        rows.implement_cg[i, 0], rows.implement_cg[i, 1] = p1[outputs.cg_att, 0], p1[outputs.cg_att, 1]
    load = u[outputs.implement_col] if outputs.implement_col >= 0 else outputs.implement_weight
    consistency = 0.0
    for r in range(m):
        consistency += rows.phi[i, r] * rows.phi[i, r]
    rows.pose[i].implement_load, rows.pose[i].consistency_residual = load, math.sqrt(consistency)
    if machine.parameters.shape[0]:
        steerability_pose(frame_points, frame_forces, load, rows.implement_cg[i, 0], machine.parameters,
                          rows.steerability[i])
    if machine.point_att.shape[0] and capacity_start.shape[0] and _same_inputs(s[i], s_start[0]):
        rows.capacity[i, :] = capacity_start
        _reserve(rows.capacity[i], machine.cg_point, load)
    elif machine.point_att.shape[0]:
        square = 2 * machine.hinge_att.shape[1] + machine.cylinder_att.shape[1] == n
        _capacity_pose(0, rows.capacity[i:i + 1], rows.q[i:i + 1], kin.att_body, kin.att_ref, machine.hinge_att,
                       machine.cylinder_att, machine.lift, machine.lift_force, machine.gravity, machine.weight_att,
                       machine.weight_mass, member_att[:, :n_springs].copy(), member_force[:, :n_springs].copy(),
                       machine.point_att, kin.column_scale, max_condition, np.ones(1, dtype=np.bool_), square,
                       np.full(1, load), machine.cg_point)
    pose = rows.pose[i]
    scalars = np.array((pose.residual, pose.consistency_residual, load, pose.transmission_angle))   # ROW_SCALARS
    pack_row(rows.values[i], rows.hinge_force[i], rows.point_xz[i], rows.cylinder_values[i], scalars,
             rows.implement_cg[i], rows.capacity[i], rows.steerability[i])
    rows.plain[i] = True


# ``live_series``' machine program when no machine-level results are wanted
NO_MACHINE = MachineProgram(parameters=np.zeros(0), hinge_att=np.zeros((2, 0), dtype=np.int64),
                            cylinder_att=np.zeros((2, 0), dtype=np.int64), lift=0, lift_force=math.nan,
                            gravity=math.nan, weight_att=np.zeros(0, dtype=np.int64), weight_mass=np.zeros(0),
                            point_att=np.zeros(0, dtype=np.int64), cg_point=0)
