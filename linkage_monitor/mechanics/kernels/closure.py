"""The loop closure of one pose: attachment positions, the residual Φ (m) and its Jacobian
∂Φ/∂q (rows: 2 per hinge, 1 per measured cylinder, 1 per measured angle × lc; the package's
conventions), one pose or a batch."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numba import njit, prange

from ..programs import KinematicsProgram
from .threads import PARALLEL_PARTS, _parallel


TWO_PI = 2.0 * math.pi


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
def _rotations(q: np.ndarray, rotation: np.ndarray) -> None:
    """cos θ, sin θ of every body of pose q into rotation (2, bodies)."""
    for b in range(rotation.shape[1]):
        rotation[0, b], rotation[1, b] = math.cos(q[3 * b + 2]), math.sin(q[3 * b + 2])


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
