"""Test oracle (frozen numpy implementation, see __init__). Batched position, velocity and acceleration analysis of a planar linkage.

Coordinates: (x, z, θ) per moving body: (x, z) the position (m) of the body's origin (the
centroid of its points in the reference pose), θ its rotation from the reference pose (rad,
from +x towards +z). Constraints (rows, all in metres): hinge coincidence (2 per hinge),
measured cylinder lengths, measured relative angles (scaled by the length scale ``lc``).
Every function works on a stack of N poses.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import connected_components, maximum_bipartite_matching

from .linalg import condition_1, det_sign_and_condition, solve_square
from linkage_monitor.mechanics.model import Mechanism
from linkage_monitor.mechanics.results import Status



@dataclass
class KinematicState:
    """Solved poses for inputs s (N, n_inputs): q (N, n), constraint residual phi (N, m) m and
    Jacobian jac (N, m, n) at q, status (N,), messages, condition (N,)."""

    s: np.ndarray
    q: np.ndarray
    phi: np.ndarray
    jac: np.ndarray
    status: np.ndarray
    messages: list[str]
    condition: np.ndarray


class Kinematics:
    """Constraint equations of one mechanism; index structure built once.

    Inside, points are complex numbers x + i·z: rotating an offset by θ is a multiplication by
    e^{iθ}, which keeps the per-pose work to a few whole-array operations (what makes a single
    pose cheap). The ground is the body index −1; its (x, z, θ) are three zero columns appended
    to q (``_padded``), so ground attachments need no special case.
    """

    def __init__(self, mech: Mechanism) -> None:
        self.mech = mech
        moving = mech.moving_bodies
        self.body_index = {b.name: i for i, b in enumerate(moving)}
        self.body_index[mech.ground.name] = -1
        self.n = 3 * len(moving)
        origins = np.array([np.mean([mech.points[p] for p in b.points], axis=0) for b in moving])
        allp = np.array(list(mech.points.values()))
        self.lc = max(float(np.sqrt(np.mean(np.sum((allp - allp.mean(0)) ** 2, axis=1)))), 1e-3)
        self.q_ref = np.column_stack([origins, np.zeros(len(moving))]).ravel()
        self._origins = origins
        self._att: dict[tuple[str, str], int] = {}
        self._arrays: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray] | None = None
        self._att_body: list[int] = []
        self._att_ref: list[np.ndarray] = []
        # constraint rows
        hinge_a, hinge_b = [], []
        for h in mech.hinges:
            hinge_a.append(self.attach(h.bodies[0], h.point))
            hinge_b.append(self.attach(h.bodies[1], h.point))
        self.hinge_att = np.array([hinge_a, hinge_b], dtype=int).reshape(2, -1)
        cyls = [mech.cylinder(c) for c in mech.measurements.cylinders]
        self.cyl_att = np.array([[self.attach(c.base.body, c.base.point) for c in cyls],
                                 [self.attach(c.rod_end.body, c.rod_end.point) for c in cyls]], dtype=int).reshape(2, -1)
        hinges = {h.name: h for h in mech.hinges}
        self.angle_bodies = np.array([[self.body_index[hinges[a.hinge].bodies[k]] for a in mech.measurements.angles]
                                      for k in (0, 1)], dtype=int).reshape(2, -1)
        self.angle_reference = np.array([a.reference for a in mech.measurements.angles])
        nh, nc, na = len(mech.hinges), len(cyls), len(mech.measurements.angles)
        self.m = 2 * nh + nc + na
        self.n_inputs = nc + na
        self.row_names = ([f"hinge '{h.name}' gap" for h in mech.hinges for _ in (0, 1)]
                          + [f"cylinder '{c.name}' length" for c in cyls]
                          + [f"angle '{a.name}'" for a in mech.measurements.angles])
        self.input_names = [c.name for c in cyls] + [a.name for a in mech.measurements.angles]
        self._angle_theta = np.where(self.angle_bodies >= 0, 3 * self.angle_bodies + 2, self.n + 2)
        self._constraint_arrays = self._attachment_arrays()  # only these enter Φ: Newton skips the rest
        self._build_jacobian_template(nh, nc)
        self._column_scale = np.tile([1.0, 1.0, 1.0 / self.lc], self.n // 3)
        p, _ = self._complex_positions(self._padded(self.q_ref[None]), self._constraint_arrays)
        self._s_ref = np.concatenate([np.abs(p[0, self.cyl_att[1]] - p[0, self.cyl_att[0]]), self.angle_reference])
        phi_ref, jac_ref = self.residual_jacobian(self.q_ref[None], self._s_ref[None])
        # redundant sensors: the hinge rows hold exactly (constraints of the least squares) when independent
        self._n_hard = 2 * nh if nh and np.linalg.matrix_rank(jac_ref[0, :2 * nh]) == 2 * nh else 0
        _, ref_cond = self._branch_and_condition(jac_ref)
        self._loops = self._loop_blocks(jac_ref[0])
        self._ref_branch = self.branch(jac_ref)[0]   # the assembly branch (one sign per loop) every pose keeps
        self._reference = KinematicState(s=self._s_ref[None], q=self.q_ref[None], phi=phi_ref, jac=jac_ref,
                                         status=np.zeros(1, dtype=int), messages=[""], condition=ref_cond)

    # ---- attachments: points fixed on bodies ------------------------------------------------
    def attach(self, body: str, key: str, position: np.ndarray | None = None) -> int:
        """Index of the point ``key`` (a point name, or a tag with ``position``) fixed on ``body``."""
        ident = (body, key)
        if ident not in self._att:
            pos = self.mech.points[key] if position is None else np.asarray(position, dtype=float)
            bi = self.body_index[body]
            self._att[ident] = len(self._att_body)
            self._att_body.append(bi)
            self._att_ref.append(pos - self._origins[bi] if bi >= 0 else pos.copy())
            self._arrays = None
        return self._att[ident]

    def _attachment_arrays(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Columns of each attachment's body x, z, θ in the padded q (K,) each, and its reference
        offset x + i·z (K,)."""
        if self._arrays is None:
            body = np.array(self._att_body, dtype=int)
            ref = np.array(self._att_ref).reshape(-1, 2)
            col = np.where(body >= 0, 3 * body, self.n)
            self._arrays = (col, col + 1, col + 2, ref[:, 0] + 1j * ref[:, 1])
        return self._arrays

    def _padded(self, q: np.ndarray) -> np.ndarray:
        """q (N, n) with the ground's (x, z, θ) = 0 appended as columns n..n+2."""
        return np.concatenate([q, np.zeros((q.shape[0], 3))], axis=1)

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

    def reference_inputs(self) -> np.ndarray:
        """Inputs (cylinder lengths m, angles rad) that the reference pose satisfies, shape (n_inputs,)."""
        return self._s_ref.copy()

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

    def reachable_fraction(self, s: np.ndarray, steps: int = 30) -> np.ndarray:
        """Largest t in [0, 1] (N,) such that inputs s_ref + t·(s − s_ref) still assemble (bisection)."""
        s_ref = self._s_ref
        n_pose = s.shape[0]
        lo, hi = np.zeros(n_pose), np.ones(n_pose)
        q_lo = np.broadcast_to(self.q_ref, (n_pose, self.n)).copy()
        tol = 1e-9 * self.lc
        for _ in range(steps):
            mid = 0.5 * (lo + hi)
            q, phi, _ = self.newton(q_lo, s_ref + mid[:, None] * (s - s_ref))
            ok = np.max(np.abs(phi), axis=1) <= tol
            lo, hi = np.where(ok, mid, lo), np.where(ok, hi, mid)
            q_lo[ok] = q[ok]
        return lo

    def _branch_and_condition(self, jac: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Sign of det ∂Φ/∂q (1 when overdetermined) (N,) and the 1-norm condition number (N,) of the
        Jacobian made dimensionless (θ columns / lc; positive scaling keeps the sign)."""
        js = jac * self._column_scale
        if self.m != self.n:
            return np.ones(jac.shape[0]), np.sqrt(condition_1(np.swapaxes(js, 1, 2) @ js))
        return det_sign_and_condition(js)

    # ---- assembly branch: one sign per loop ------------------------------------------------------
    def _loop_blocks(self, jac_ref: np.ndarray) -> list[tuple[np.ndarray, np.ndarray]]:
        """(rows, columns) of each loop of the linkage: the diagonal blocks of the block-triangular
        form of the square driving system (hinge rows + as many input rows, cylinders first, as
        close the degrees of freedom), found from its structure (a maximum matching of rows to
        columns, then the strongly connected components of the matched graph). A chain of dyads
        gives one block per dyad; the sign of each block's determinant is that loop's assembly
        branch (the sign of one global determinant would miss two loops flipping together)."""
        nh2 = 2 * self.hinge_att.shape[1]
        rows = list(range(nh2))
        for r in range(nh2, self.m):          # input rows in order (cylinders, then angles), while they add rank
            if len(rows) == self.n:
                break
            if np.linalg.matrix_rank(jac_ref[rows + [r]]) == len(rows) + 1:
                rows.append(r)
        if len(rows) != self.n or np.linalg.matrix_rank(jac_ref[rows]) < self.n:
            return []                         # not closable by a square subsystem: no branch to keep
        pattern = np.zeros((self.m, self.n), dtype=bool)
        pattern.flat[self._jac_flat] = True
        pattern |= self._jac0 != 0.0
        sub = csr_matrix(pattern[rows].astype(np.int8))
        match = maximum_bipartite_matching(sub, perm_type="column")   # match[row] = its column
        if np.any(match < 0):
            return []
        order = np.argsort(match)            # row matched to each column
        graph = csr_matrix(pattern[rows][order].astype(np.int8))    # column j -> columns of its matched row
        count, label = connected_components(graph, directed=True, connection="strong")
        blocks = []
        for b in range(count):
            cols = np.flatnonzero(label == b)
            blocks.append((np.array(rows)[order[cols]], cols))
        return blocks

    def branch(self, jac: np.ndarray) -> np.ndarray:
        """Sign of the determinant of each loop's block (N, n_loops): +1, −1, or 0 at a dead centre."""
        out = np.ones((jac.shape[0], len(self._loops)))
        for k, (rows, cols) in enumerate(self._loops):
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
        n_pose = s.shape[0]
        nc = self.cyl_att.shape[1]
        s = s.copy()   # angles as the nearest equivalent (modulo 2π) of the reference pose's: a sensor
        s[:, nc:] = self.angle_reference + wrap_angle(s[:, nc:] - self.angle_reference)  # in [−π, π) or [0, 2π)
        start = self._reference if previous is None else previous
        q, phi, jac = self.newton(self.predict(start, s), s)
        _, cond = self._branch_and_condition(jac)
        limit = 1e-9 * self.lc if self.m == self.n else consistency_tol
        retry = np.flatnonzero(~self.on_branch(jac) | ~self._assembled(phi, limit))
        still = np.zeros(0, dtype=int)
        if retry.size:  # continuation from the reference pose along a straight input path
            s_ref = self._s_ref
            qr = np.broadcast_to(self.q_ref, (retry.size, self.n)).copy()
            for t in np.linspace(0.1, 1.0, 10):
                qr, _, _ = self.newton(qr, s_ref + t * (s[retry] - s_ref), max_iter=12)
            qr, phir, jacr = self.newton(qr, s[retry])
            q[retry], phi[retry], jac[retry] = qr, phir, jacr
            cond[retry] = self._branch_and_condition(jacr)[1]
            closed = self._assembled(phir, limit)
            still = retry[~closed]
            off = retry[~self.on_branch(jacr) & closed]
        status = np.zeros(n_pose, dtype=int)
        messages = [""] * n_pose
        if retry.size:
            for i in off:
                status[i] = Status.ASSEMBLY
                messages[i] = (f"cannot assemble the linkage for {self.describe_inputs(s[i])} on the reference "
                               "pose's assembly branch: the inputs fit only a mirrored assembly of a loop (check the "
                               "sensors and their zero offsets)")
        if still.size and self.m == self.n:  # say how far the inputs are out of reach
            reach = self.reachable_fraction(s[still])
            for i, t in zip(still, reach):
                status[i], messages[i] = Status.ASSEMBLY, self.reach_message(s[i], t)
        for i in np.flatnonzero(~self._assembled(phi, limit) & (status == Status.OK)):
            status[i] = Status.ASSEMBLY
            messages[i] = self.assembly_message(phi[i], s[i])
        for i in np.flatnonzero((status == Status.OK) & ~(cond <= dead_centre_cond)):
            status[i] = Status.DEAD_CENTRE
            messages[i] = (f"kinematic dead centre at {self.describe_inputs(s[i])}: constraint Jacobian "
                           f"condition number {cond[i]:.3g} > {dead_centre_cond:.3g}")
        return KinematicState(s=s, q=q, phi=phi, jac=jac, status=status, messages=messages, condition=cond)

    def describe_inputs(self, s: np.ndarray) -> str:
        """``lift_cylinder = 0.6100 m, ...`` for messages."""
        nc = self.cyl_att.shape[1]
        return ", ".join(f"{n} = {v:.4f} {'m' if i < nc else 'rad'}" for i, (n, v) in enumerate(zip(self.input_names, s)))

    def reach_message(self, s: np.ndarray, t: float) -> str:
        """Which inputs are out of reach and by how much (mm, deg), given the reachable fraction t."""
        s_ref = self._s_ref
        nc = self.cyl_att.shape[1]
        miss = (1.0 - t) * (s - s_ref)
        parts = [f"{name} by {1e3 * abs(d):.1f} mm" if j < nc else f"{name} by {np.degrees(abs(d)):.2f} deg"
                 for j, (name, d) in enumerate(zip(self.input_names, miss)) if abs(d) > 0.0]
        return (f"cannot assemble the linkage for {self.describe_inputs(s)}: going there from the reference pose "
                f"it assembles only up to {self.describe_inputs(s_ref + t * (s - s_ref))}; out of reach: "
                f"{', '.join(parts)} (check the sensor or the geometry)")

    def assembly_message(self, phi: np.ndarray, s: np.ndarray) -> str:
        """Which constraint stays open, and by how much (mm), at the pose closest to assembly."""
        nh = self.hinge_att.shape[1]
        size = np.abs(phi.copy())
        size[: 2 * nh] = np.repeat(np.hypot(phi[0:2 * nh:2], phi[1:2 * nh:2]), 2)
        k = int(np.nanargmax(size)) if np.isfinite(size).any() else 0
        return (f"cannot assemble the linkage for {self.describe_inputs(s)}: at best {self.row_names[k]} "
                f"is off by {1e3 * size[k]:.1f} mm (total constraint residual {1e3 * np.linalg.norm(phi):.1f} mm)")

    # ---- rates ----------------------------------------------------------------------------
    def rates(self, q: np.ndarray, s_dot: np.ndarray, s_ddot: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Body velocities q̇ and accelerations q̈ (N, n) from input rates ṡ and s̈ (Naumenko et al. 2021, φ', φ'')."""
        n_pose = q.shape[0]
        nh, nc = self.hinge_att.shape[1], self.cyl_att.shape[1]
        _, jac = self.residual_jacobian(q, np.zeros((n_pose, self.n_inputs)))
        p, rel = self.positions(q)
        rhs = np.zeros((n_pose, self.m))
        rhs[:, 2 * nh:2 * nh + nc] = s_dot[:, :nc]
        rhs[:, 2 * nh + nc:] = self.lc * s_dot[:, nc:]
        q_dot = self._solve_linear(jac, rhs)
        v, centripetal = self.point_rates(q_dot, rel)
        gamma = np.zeros((n_pose, self.m))
        gamma[:, :2 * nh] = (centripetal[:, self.hinge_att[0]] - centripetal[:, self.hinge_att[1]]).reshape(n_pose, 2 * nh)
        d = p[:, self.cyl_att[1]] - p[:, self.cyl_att[0]]
        length = np.linalg.norm(d, axis=-1)
        u = d / length[..., None]
        dv = v[:, self.cyl_att[1]] - v[:, self.cyl_att[0]]
        dc = centripetal[:, self.cyl_att[1]] - centripetal[:, self.cyl_att[0]]
        along = np.sum(u * dv, axis=-1)
        gamma[:, 2 * nh:2 * nh + nc] = np.sum(u * dc, axis=-1) + (np.sum(dv * dv, axis=-1) - along**2) / length
        rhs2 = np.zeros((n_pose, self.m))
        rhs2[:, 2 * nh:2 * nh + nc] = s_ddot[:, :nc]
        rhs2[:, 2 * nh + nc:] = self.lc * s_ddot[:, nc:]
        return q_dot, self._solve_linear(jac, rhs2 - gamma)

    def point_rates(self, q_dot: np.ndarray, rel: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Velocities (N, K, 2) of all attachments and their centripetal accelerations −θ̇²·rel."""
        cx, cz, ct, _ = self._attachment_arrays()
        qp = self._padded(q_dot)        # the ground's rates are the appended zeros
        w = qp[:, ct]
        relc = rel[..., 0] + 1j * rel[..., 1]
        v = qp[:, cx] + 1j * qp[:, cz] + 1j * w * relc
        return as_xz(v), as_xz(-w * w * relc)

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


def wrap_angle(a: np.ndarray) -> np.ndarray:
    """Angles (rad) taken modulo 2π into [−π, π)."""
    return np.remainder(a + np.pi, 2.0 * np.pi) - np.pi


def as_xz(z: np.ndarray) -> np.ndarray:
    """(..., 2) real array [x, z] of a complex array x + i·z (a view when z is C-contiguous)."""
    return np.ascontiguousarray(z).view(np.float64).reshape(z.shape + (2,))
