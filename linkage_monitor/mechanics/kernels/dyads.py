"""The pose in closed form along the chain of dyads (``chain.decompose``): each body placed by a
circle intersection on its reference side, and, with redundant sensors, the chain's driving
inputs fitted to the readings (Gauss-Newton)."""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from ..chain import (A_BODY, A_BODY2, A_OTHER, A_PARENT, A_PARENT2, ANGLE, ANGLE_INPUT, ANGLE_SIGN, BODY, BODY2,
                     CYLINDER, CYLINDER_INPUT, KIND)
from .closure import _input_residuals, _point
from .linalg import _max_abs, _solve_normal


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
