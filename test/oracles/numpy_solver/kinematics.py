"""Test oracle (the numpy implementation, see __init__): batched position, velocity and acceleration
analysis of a planar linkage — its own equations, in complex numbers, over the package's index
structure (``KinematicLayout``: coordinates, attachments, constraint rows, the loops' structure,
the verdicts' wording). Every function works on a stack of N poses.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from linkage_monitor.mechanics import kinematics
from linkage_monitor.mechanics.kinematic_layout import KinematicLayout, as_xz, wrap_angle
from linkage_monitor.mechanics.model import Mechanism
from .linalg import condition_1, det_sign_and_condition, solve_square


@dataclass
class KinematicState(kinematics.KinematicState):
    """The package's solved poses with the constraint Jacobian jac (N, m, n) at q (the tangent a
    warm start predicts along)."""

    jac: np.ndarray


class Kinematics(KinematicLayout):
    """Constraint equations of one mechanism over its index structure (``KinematicLayout``).

    Inside, points are complex numbers x + i·z: rotating an offset by θ is a multiplication by
    e^{iθ}, which keeps the per-pose work to a few whole-array operations (what makes a single
    pose cheap). The ground is the body index −1; its (x, z, θ) are three zero columns appended
    to q (``_padded``), so ground attachments need no special case.
    """

    def __init__(self, mech: Mechanism) -> None:
        super().__init__(mech)
        nh, nc = self.hinge_att.shape[1], self.cyl_att.shape[1]
        self._angle_theta = np.where(self.angle_bodies >= 0, 3 * self.angle_bodies + 2, self.n + 2)
        self._constraint_arrays = self._attachment_arrays()  # only these enter Φ: Newton skips the rest
        self._build_jacobian_template(nh, nc)
        p, _ = self._complex_positions(self._padded(self.q_ref[None]), self._constraint_arrays)
        self._s_ref = np.concatenate([np.abs(p[0, self.cyl_att[1]] - p[0, self.cyl_att[0]]), self.angle_reference])
        phi_ref, jac_ref = self.residual_jacobian(self.q_ref[None], self._s_ref[None])
        # redundant sensors: the hinge rows hold exactly (constraints of the least squares) when independent
        self._n_hard = 2 * nh if nh and np.linalg.matrix_rank(jac_ref[0, :2 * nh]) == 2 * nh else 0
        _, ref_cond = self._branch_and_condition(jac_ref)
        pattern = np.zeros((self.m, self.n), dtype=bool)   # the Jacobian's structural non-zeros
        pattern.flat[self._jac_flat] = True
        pattern |= self._jac0 != 0.0
        self._loops = self.loop_blocks(self.driving_rows(jac_ref[0])[0].tolist(), pattern)
        self._ref_branch = self.branch(jac_ref)[0]   # the assembly branch (one sign per loop) every pose keeps
        self._reference = KinematicState(s=self._s_ref[None], q=self.q_ref[None], phi=phi_ref, jac=jac_ref,
                                         status=np.zeros(1, dtype=int), messages=[""], condition=ref_cond)

    def _attachments_changed(self) -> None:
        """Forget the attachments' arrays (``_attachment_arrays``) with the layout's geometry."""
        super()._attachments_changed()
        self._arrays: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray] | None = None

    def _attachment_arrays(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Columns of each attachment's body x, z, θ in the padded q (K,) each, and its reference
        offset x + i·z (K,)."""
        if self._arrays is None:
            body = np.array(self._att_body, dtype=int)
            ref = np.array(self._att_ref).reshape(-1, 2)
            col = np.where(body >= 0, 3 * body, self.n)
            self._arrays = (col, col + 1, col + 2, ref[:, 0] + 1j * ref[:, 1])
        return self._arrays

    @staticmethod
    def _complex_positions(qp: np.ndarray, arrays: tuple[np.ndarray, ...]) -> tuple[np.ndarray, np.ndarray]:
        """Positions and offsets from their body's origin, x + i·z (N, K), of the attachments in
        ``arrays`` (from ``_attachment_arrays``), for padded q."""
        cx, cz, ct, ref = arrays
        theta = qp.take(ct, axis=1)             # take: a fraction of the cost of fancy indexing
        turn = np.empty(theta.shape, dtype=complex)
        np.cos(theta, out=turn.real)             # cheaper than exp(iθ) on large batches
        np.sin(theta, out=turn.imag)
        rel = ref * turn
        p = rel + qp.take(cx, axis=1)
        p.imag += qp.take(cz, axis=1)
        return p, rel

    def positions(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Positions P (N, K, 2) m of all attachments and their offsets from their body's origin.

        Ground attachments are offset from the global origin B, i.e. the offset is their position.
        """
        p, rel = self._complex_positions(self._padded(q), self._attachment_arrays())
        return as_xz(p), as_xz(rel)

    # ---- constraints ----------------------------------------------------------------------
    def _build_jacobian_template(self, nh: int, nc: int) -> None:
        """Constant Jacobian entries (±1, ±lc) and flat indices of the pose-dependent ones."""
        col = self._attachment_arrays()[0]
        moving = col < self.n
        n = self.n
        jac0 = np.zeros((self.m, n))
        theta_att, theta_sign, flat = [], [], []
        for h in range(nh):  # gap = P(bodies[0]) − P(bodies[1]); ∂P/∂(x, z) = I, ∂P/∂θ = i·rel
            for sign, att in ((1.0, self.hinge_att[0, h]), (-1.0, self.hinge_att[1, h])):
                if moving[att]:
                    jac0[2 * h, col[att]] = jac0[2 * h + 1, col[att] + 1] = sign
                    theta_att.append(att)
                    theta_sign.append(sign)
                    flat += [2 * h * n + col[att] + 2, (2 * h + 1) * n + col[att] + 2]
        r0 = 2 * nh + nc
        for k in range(self.angle_bodies.shape[1]):
            for sign, b in ((-1.0, self.angle_bodies[0, k]), (1.0, self.angle_bodies[1, k])):
                if b >= 0:
                    jac0[r0 + k, 3 * b + 2] = sign * self.lc
        cyl_end, cyl_att, cyl_sign, cyl_flat = [], [], [], []  # length = |rod end − base|; ∂/∂(x, z, θ) = ±(u, u·(i·rel))
        for k in range(nc):
            for sign, att in ((-1.0, self.cyl_att[0, k]), (1.0, self.cyl_att[1, k])):
                if moving[att]:
                    cyl_end.append(k)
                    cyl_att.append(att)
                    cyl_sign.append(sign)
                    cyl_flat += [(2 * nh + k) * n + col[att] + j for j in range(3)]
        self._jac0 = jac0
        self._theta = (np.array(theta_att, dtype=int), 1j * np.array(theta_sign))
        self._cyl = (np.array(cyl_end, dtype=int), np.array(cyl_att, dtype=int), np.array(cyl_sign))
        cyl_entries = np.array(cyl_flat, dtype=int).reshape(-1, 3)
        # pose-dependent entries in the order ``_jacobian`` concatenates them: hinge θ (x row, z row)
        # per term, then the cylinder x, z and θ entries, each for all terms
        self._jac_flat = np.concatenate([np.array(flat, dtype=int), cyl_entries.T.ravel()])
        # gap = P(hinge bodies[0]) − P(bodies[1]) and cylinder vector = P(rod end) − P(base): P(a) − P(b)
        self._diff_att = (np.concatenate([self.hinge_att[0], self.cyl_att[1]]),
                          np.concatenate([self.hinge_att[1], self.cyl_att[0]]))

    def residual_jacobian(self, q: np.ndarray, s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Constraint residual Φ (N, m) m and Jacobian ∂Φ/∂q (N, m, n) for inputs s (N, n_inputs)."""
        n_pose = q.shape[0]
        nh = self.hinge_att.shape[1]
        nc = self.cyl_att.shape[1]
        qp = self._padded(q)
        p, rel = self._complex_positions(qp, self._constraint_arrays)
        diff = p.take(self._diff_att[0], axis=1) - p.take(self._diff_att[1], axis=1)
        d = diff[:, nh:]
        length = np.abs(d)
        ang = qp.take(self._angle_theta[1], axis=1) - qp.take(self._angle_theta[0], axis=1) + self.angle_reference
        phi = np.concatenate([as_xz(diff[:, :nh]).reshape(n_pose, 2 * nh), length - s[:, :nc],
                              self.lc * wrap_angle(ang - s[:, nc:])], axis=1)
        return phi, self._jacobian(rel, d / length)

    def _jacobian(self, rel: np.ndarray, u: np.ndarray) -> np.ndarray:
        """∂Φ/∂q (N, m, n) from constraint offsets rel (N, K) and cylinder unit axes u (N, nc), x + i·z."""
        n_pose = rel.shape[0]
        t_att, t_sign = self._theta
        hinge_theta = as_xz(t_sign * rel.take(t_att, axis=1))            # (x row, z row) per term
        c_end, c_att, c_sign = self._cyl
        uc = c_sign * u.take(c_end, axis=1)
        # u · (i·rel) = −Im(conj(u)·rel): the length change per unit rotation of the body
        cyl_theta = -(uc.conj() * rel.take(c_att, axis=1)).imag
        jac = np.repeat(self._jac0[None], n_pose, axis=0)
        jac.reshape(n_pose, self.m * self.n)[:, self._jac_flat] = np.concatenate(
            [hinge_theta.reshape(n_pose, 2 * t_att.size), uc.real, uc.imag, cyl_theta], axis=1)
        return jac

    # ---- solving --------------------------------------------------------------------------
    def newton(self, q: np.ndarray, s: np.ndarray, max_iter: int = 25) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Newton / Gauss-Newton iterations from q (N, n).

        Returns q, its residual Φ (N, m) and Jacobian (N, m, n), both evaluated at the returned q
        (callers reuse the Jacobian for the branch and condition checks). A pose stops when
        |Φ| ≤ 1e-13·lc, or before a step that is not finite (singular) or, overdetermined, below
        1e-13·lc (the least-squares residual need not reach 0).
        """
        q = q.copy()
        tol = 1e-13 * self.lc
        phi, jac = self.residual_jacobian(q, s)
        idx = np.flatnonzero(np.abs(phi).max(axis=1) > tol)   # poses still iterating
        for _ in range(max_iter):
            if not idx.size:
                break
            every = idx.size == q.shape[0]   # then plain arrays: fancy indexing costs µs per call
            dq = self._solve_linear(jac, -phi) if every else self._solve_linear(jac[idx], -phi[idx])
            moves = np.abs(dq).max(axis=1) > tol if self.m > self.n else np.isfinite(dq).all(axis=1)
            if every and moves.all():
                q += dq
                phi, jac = self.residual_jacobian(q, s)
            else:
                idx, dq = idx[moves], dq[moves]
                q[idx] += dq
                phi[idx], jac[idx] = self.residual_jacobian(q[idx], s[idx])
            idx = idx[np.abs(phi[idx]).max(axis=1) > tol]
        return q, phi, jac

    def _branch_and_condition(self, jac: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Sign of det ∂Φ/∂q (1 when overdetermined) (N,) and the 1-norm condition number (N,) of the
        Jacobian made dimensionless (θ columns / lc; positive scaling keeps the sign)."""
        js = jac * self.column_scale
        if self.m != self.n:
            return np.ones(jac.shape[0]), np.sqrt(condition_1(np.swapaxes(js, 1, 2) @ js))
        return det_sign_and_condition(js)

    def branch(self, jac: np.ndarray) -> np.ndarray:
        """Sign of the determinant of each loop's block (N, n_loops): +1, −1, or 0 at a dead centre."""
        out = np.ones((jac.shape[0], len(self._loops)))
        for k, block in enumerate(self._loops):
            rows, cols = block.rows, block.columns
            out[:, k] = np.linalg.slogdet(jac[:, rows][:, :, cols])[0]
        return out

    def on_branch(self, jac: np.ndarray) -> np.ndarray:
        """True (N,) where no loop is in the opposite assembly of the reference pose's (a loop at a
        dead centre, sign 0, is left to the dead-centre check)."""
        return ~np.any(self.branch(jac) * self._ref_branch < 0.0, axis=1)

    def predict(self, previous: KinematicState, s: np.ndarray) -> np.ndarray:
        """Poses q (N, n) predicted for inputs s (N, n_inputs) along the tangent at one solved pose.

        This is the first Newton step from ``previous.q`` with ``previous.jac`` (no new evaluation,
        one factorization for all N): only the input rows of Φ depend on s (∂Φ/∂s = −1 for
        cylinders, −lc for angles), so J·dq = E·(s − s_prev) with E those unit / lc entries.
        """
        nc = self.cyl_att.shape[1]
        r0 = self.m - self.n_inputs            # input rows follow the hinge rows
        ds = s - previous.s
        shift = np.zeros((s.shape[0], self.m))
        shift[:, r0:r0 + nc] = ds[:, :nc]
        shift[:, r0 + nc:] = self.lc * ds[:, nc:]
        return previous.q + self._solve_linear(previous.jac, shift)

    def solve(self, s: np.ndarray, previous: KinematicState | None, dead_centre_cond: float,
              consistency_tol: float) -> KinematicState:
        """Assemble N poses for inputs s (N, n_inputs), keeping the reference pose's assembly branch.

        Newton starts from the tangent prediction off ``previous`` (one solved pose: a live node
        passes its last one, 2 iterations for a slowly moving stroke) or off the reference pose;
        poses that fail or land on another branch are redone by continuation from the reference pose.
        """
        s = self.wrap_angles(s)
        start = self._reference if previous is None else previous
        q, phi, jac = self.newton(self.predict(start, s), s)
        _, cond = self._branch_and_condition(jac)
        limit = 1e-9 * self.lc if self.m == self.n else consistency_tol
        retry = np.flatnonzero(~self.on_branch(jac) | ~self._assembled(phi, limit))
        mirrored = unreached = np.zeros(0, dtype=int)
        if retry.size:  # continuation from the reference pose along a straight input path
            q[retry], phi[retry], jac[retry] = self.continuation(s[retry])
            cond[retry] = self._branch_and_condition(jac[retry])[1]
            closed = self._assembled(phi[retry], limit)
            unreached = retry[~closed]
            mirrored = retry[~self.on_branch(jac[retry]) & closed]
        status, messages = self.verdicts(s, phi, cond, self._assembled(phi, limit), mirrored, unreached,
                                         dead_centre_cond, reach=True)
        return KinematicState(s=s, q=q, phi=phi, jac=jac, status=status, messages=messages, condition=cond)

    # ---- rates ----------------------------------------------------------------------------
    def rates(self, q: np.ndarray, s_dot: np.ndarray, s_ddot: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Body velocities q̇ and accelerations q̈ (N, n) from input rates ṡ and s̈ (Naumenko et al. 2021, φ', φ''):
        J·q̇ = ṡ and J·q̈ = s̈ − J̇·q̇ on the input rows (angles × lc), where J̇·q̇ is, in complex numbers,
        a hinge's −θ̇²·rel of its two sides and a cylinder's Re(ū·Δa) + Im(ū·Δv)²/L (ū its unit
        axis, Δv and Δa the relative velocity and centripetal acceleration of its ends, L its length)."""
        n_pose = q.shape[0]
        nh = self.hinge_att.shape[1]
        _, jac = self.residual_jacobian(q, np.zeros((n_pose, self.n_inputs)))
        cx, cz, ct, _ = arrays = self._attachment_arrays()
        p, rel = self._complex_positions(self._padded(q), arrays)
        q_dot = self._solve_linear(jac, self._input_rows(s_dot))
        qp_dot = self._padded(q_dot)
        w = qp_dot.take(ct, axis=1)                             # θ̇ of each attachment's body
        v = qp_dot.take(cx, axis=1) + 1j * qp_dot.take(cz, axis=1) + 1j * w * rel
        centripetal = -w * w * rel
        base, rod_end = self.cyl_att
        axis = p[:, rod_end] - p[:, base]
        length = np.abs(axis)
        unit_conj = np.conj(axis / length)
        dv, da = v[:, rod_end] - v[:, base], centripetal[:, rod_end] - centripetal[:, base]
        hinge_gap = centripetal[:, self.hinge_att[0]] - centripetal[:, self.hinge_att[1]]
        bias = np.zeros((n_pose, self.m))
        bias[:, :2 * nh] = as_xz(hinge_gap).reshape(n_pose, 2 * nh)
        bias[:, 2 * nh:2 * nh + length.shape[1]] = (unit_conj * da).real + (unit_conj * dv).imag ** 2 / length
        return q_dot, self._solve_linear(jac, self._input_rows(s_ddot) - bias)

    def _input_rows(self, rate: np.ndarray) -> np.ndarray:
        """(N, m) with the input rates (N, n_inputs) on the input rows (angles × lc), 0 on the hinge rows."""
        nc = self.cyl_att.shape[1]
        out = np.zeros((rate.shape[0], self.m))
        r0 = self.m - self.n_inputs
        out[:, r0:r0 + nc] = rate[:, :nc]
        out[:, r0 + nc:] = self.lc * rate[:, nc:]
        return out

    def accelerations(self, q: np.ndarray, q_dot: np.ndarray, q_ddot: np.ndarray) -> np.ndarray:
        """Accelerations (N, K, 2) m/s² of all attachments at body coordinates q, rates q̇, q̈ (N, n):
        (ẍ + i·z̈) + (i·θ̈ − θ̇²)·rel."""
        cx, cz, ct, _ = arrays = self._attachment_arrays()
        _, rel = self._complex_positions(self._padded(q), arrays)
        qp_ddot, w = self._padded(q_ddot), self._padded(q_dot).take(ct, axis=1)
        return as_xz(qp_ddot.take(cx, axis=1) + 1j * qp_ddot.take(cz, axis=1)
                     + (1j * qp_ddot.take(ct, axis=1) - w * w) * rel)

    def _solve_linear(self, jac: np.ndarray, rhs: np.ndarray) -> np.ndarray:
        """x (N, n) with jac·x = rhs (N, m); overdetermined: the hinge rows C exactly and the input
        rows A in least squares — the KKT system [AᵀA Cᵀ; C 0]·[x; λ] = [Aᵀb; d] (Lagrange
        multipliers λ), or every row in least squares when the hinge rows are not independent;
        jac (N, m, n), or (1, m, n) shared by all N right-hand sides."""
        if self.m == self.n:
            return solve_square(jac, rhs)
        h = self._n_hard
        c, a = jac[:, :h], jac[:, h:]
        at = np.swapaxes(a, 1, 2)
        kkt = np.zeros((jac.shape[0], self.n + h, self.n + h))
        kkt[:, :self.n, :self.n] = at @ a
        kkt[:, :self.n, self.n:] = np.swapaxes(c, 1, 2)
        kkt[:, self.n:, :self.n] = c
        rhs_kkt = np.concatenate([(at @ rhs[:, h:, None])[..., 0], rhs[:, :h]], axis=1)
        return solve_square(kkt, rhs_kkt)[:, :self.n]

    def _assembled(self, phi: np.ndarray, limit: float) -> np.ndarray:
        """(N,) hinges closed to 1e-9·lc and every row of Φ (N, m) within ``limit`` m."""
        return (np.abs(phi[:, :2 * self.hinge_att.shape[1]]).max(axis=1, initial=0.0) <= 1e-9 * self.lc) & (
            np.abs(phi).max(axis=1) <= limit)

