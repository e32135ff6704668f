"""Batched position, velocity and acceleration analysis of a planar linkage.

Coordinates: (x, z, θ) per moving body: (x, z) the position (m) of the body's origin (the
centroid of its points in the reference pose), θ its rotation from the reference pose (rad,
from +x towards +z). Constraints (rows, all in metres): hinge coincidence (2 per hinge),
measured cylinder lengths, measured relative angles (scaled by the length scale ``lc``).
Every function works on a stack of N poses.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .model import Mechanism

OK, ASSEMBLY, DEAD_CENTRE = 0, 3, 4  # status codes shared with solver.py (1 = lift-off, 2 = input)


@dataclass
class KinematicState:
    """Solved poses: q (N, n), constraint residual phi (N, m) m, status (N,), messages, condition (N,)."""

    q: np.ndarray
    phi: np.ndarray
    status: np.ndarray
    messages: list[str]
    condition: np.ndarray


class Kinematics:
    """Constraint equations of one mechanism; index structure built once."""

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
        self._arrays: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None
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
        self._build_jacobian_template(nh, nc)
        self._ref_sign: float | None = None

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

    def _attachment_arrays(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        if self._arrays is None:
            body = np.array(self._att_body, dtype=int)
            self._arrays = (body, np.array(self._att_ref).reshape(-1, 2), body >= 0)
        return self._arrays

    def positions(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Positions P (N, K, 2) m of all attachments and their offsets from their body origin."""
        body, ref, moving = self._attachment_arrays()
        bi = np.where(moving, body, 0)
        th = q[:, 3 * bi + 2]
        c, s = np.cos(th), np.sin(th)
        rel = np.stack([c * ref[:, 0] - s * ref[:, 1], s * ref[:, 0] + c * ref[:, 1]], axis=-1)
        rel = np.where(moving[None, :, None], rel, 0.0)
        origin = np.stack([q[:, 3 * bi], q[:, 3 * bi + 1]], axis=-1)
        p = np.where(moving[None, :, None], origin + rel, ref[None, :, :])
        return p, rel

    # ---- constraints ----------------------------------------------------------------------
    def _build_jacobian_template(self, nh: int, nc: int) -> None:
        body, _, _ = self._attachment_arrays()
        rows, cols, vals = [], [], []          # constant entries (±1, ±lc)
        trows, tcols, tatt, tcomp, tsign = [], [], [], [], []  # hinge θ entries: tsign·rel[comp]
        for h in range(nh):
            for sign, att in ((1.0, self.hinge_att[0, h]), (-1.0, self.hinge_att[1, h])):
                b = body[att]
                if b < 0:
                    continue
                rows += [2 * h, 2 * h + 1]
                cols += [3 * b, 3 * b + 1]
                vals += [sign, sign]
                trows += [2 * h, 2 * h + 1]
                tcols += [3 * b + 2, 3 * b + 2]
                tatt += [att, att]
                tcomp += [1, 0]
                tsign += [-sign, sign]
        r0 = 2 * nh + nc
        for k in range(self.angle_bodies.shape[1]):
            for sign, b in ((-1.0, self.angle_bodies[0, k]), (1.0, self.angle_bodies[1, k])):
                if b >= 0:
                    rows.append(r0 + k)
                    cols.append(3 * b + 2)
                    vals.append(sign * self.lc)
        self._const = (np.array(rows, dtype=int), np.array(cols, dtype=int), np.array(vals))
        self._theta = tuple(np.array(a, dtype=int) for a in (trows, tcols, tatt, tcomp)) + (np.array(tsign),)
        crow, cbody, catt, ccyl, csign = [], [], [], [], []
        for k in range(nc):
            for sign, att in ((-1.0, self.cyl_att[0, k]), (1.0, self.cyl_att[1, k])):
                if body[att] >= 0:
                    crow.append(2 * nh + k)
                    cbody.append(body[att])
                    catt.append(att)
                    ccyl.append(k)
                    csign.append(sign)
        self._cyl = tuple(np.array(a, dtype=int) for a in (crow, cbody, catt, ccyl)) + (np.array(csign),)

    def residual_jacobian(self, q: np.ndarray, s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Constraint residual Φ (N, m) m and Jacobian ∂Φ/∂q (N, m, n) for inputs s (N, n_inputs)."""
        n_pose = q.shape[0]
        p, rel = self.positions(q)
        nh = self.hinge_att.shape[1]
        nc = self.cyl_att.shape[1]
        gap = p[:, self.hinge_att[0]] - p[:, self.hinge_att[1]]
        d = p[:, self.cyl_att[1]] - p[:, self.cyl_att[0]]
        length = np.sqrt(np.sum(d * d, axis=-1))
        u = d / length[..., None]
        ang = (q[:, 3 * self.angle_bodies[1] + 2] * (self.angle_bodies[1] >= 0)
               - q[:, 3 * self.angle_bodies[0] + 2] * (self.angle_bodies[0] >= 0) + self.angle_reference)
        phi = np.concatenate([gap.reshape(n_pose, 2 * nh), length - s[:, :nc], self.lc * (ang - s[:, nc:])], axis=1)
        jac = np.zeros((n_pose, self.m, self.n))
        r, c, v = self._const
        jac[:, r, c] = v
        tr, tc, ta, tco, ts = self._theta
        jac[:, tr, tc] = ts * rel[:, ta, tco]
        cr, cb, ca, ck, cs = self._cyl
        ux, uz = u[:, ck, 0], u[:, ck, 1]
        jac[:, cr, 3 * cb] = cs * ux
        jac[:, cr, 3 * cb + 1] = cs * uz
        jac[:, cr, 3 * cb + 2] = cs * (uz * rel[:, ca, 0] - ux * rel[:, ca, 1])
        return phi, jac

    def reference_inputs(self) -> np.ndarray:
        """Inputs (cylinder lengths m, angles rad) that the reference pose satisfies, shape (n_inputs,)."""
        p, _ = self.positions(self.q_ref[None])
        d = p[0, self.cyl_att[1]] - p[0, self.cyl_att[0]]
        return np.concatenate([np.hypot(d[:, 0], d[:, 1]), self.angle_reference])

    # ---- solving --------------------------------------------------------------------------
    def _step(self, phi: np.ndarray, jac: np.ndarray, damping: np.ndarray | None = None) -> np.ndarray:
        """Gauss-Newton (or Levenberg-Marquardt with ``damping``) step dq (N, n)."""
        if damping is None and self.m == self.n:
            a, rhs = jac, -phi
        else:
            a = np.einsum("nmi,nmj->nij", jac, jac)
            rhs = -np.einsum("nmi,nm->ni", jac, phi)
            if damping is not None:
                diag = np.einsum("nii->ni", a)
                a = a + (damping[:, None] * (diag + 1e-12))[:, :, None] * np.eye(self.n)
        try:
            return np.linalg.solve(a, rhs[..., None])[..., 0]
        except np.linalg.LinAlgError:
            return np.einsum("nij,nj->ni", np.linalg.pinv(a), rhs)

    def newton(self, q: np.ndarray, s: np.ndarray, max_iter: int = 25) -> tuple[np.ndarray, np.ndarray]:
        """Newton / Gauss-Newton iterations from q (N, n); returns q and its residual Φ (N, m)."""
        q = q.copy()
        tol = 1e-13 * self.lc
        active = np.ones(q.shape[0], dtype=bool)
        phi = np.zeros((q.shape[0], self.m))
        for _ in range(max_iter):
            idx = np.flatnonzero(active)
            phi_a, jac = self.residual_jacobian(q[idx], s[idx])
            phi[idx] = phi_a
            done = np.max(np.abs(phi_a), axis=1) <= tol
            dq = self._step(phi_a[~done], jac[~done])
            q[idx[~done]] += dq
            still = np.max(np.abs(dq), axis=1) > tol if self.m > self.n else np.isfinite(dq).all(axis=1)
            active[idx[done]] = False
            active[idx[~done][~still]] = False
            if not active.any():
                break
        phi, _ = self.residual_jacobian(q, s)
        return q, phi

    def reachable_fraction(self, s: np.ndarray, steps: int = 30) -> np.ndarray:
        """Largest t in [0, 1] (N,) such that inputs s_ref + t·(s − s_ref) still assemble (bisection)."""
        s_ref = self.reference_inputs()
        n_pose = s.shape[0]
        lo, hi = np.zeros(n_pose), np.ones(n_pose)
        q_lo = np.broadcast_to(self.q_ref, (n_pose, self.n)).copy()
        tol = 1e-9 * self.lc
        for _ in range(steps):
            mid = 0.5 * (lo + hi)
            q, phi = self.newton(q_lo, s_ref + mid[:, None] * (s - s_ref))
            ok = np.max(np.abs(phi), axis=1) <= tol
            lo, hi = np.where(ok, mid, lo), np.where(ok, hi, mid)
            q_lo[ok] = q[ok]
        return lo

    def condition(self, jac: np.ndarray) -> np.ndarray:
        """1-norm condition number (N,) of the Jacobian made dimensionless (θ columns / lc)."""
        scale = np.tile([1.0, 1.0, 1.0 / self.lc], self.n // 3)
        js = jac * scale
        if self.m != self.n:
            js = np.einsum("nmi,nmj->nij", js, js)
        cond = condition_1(js)
        return np.sqrt(cond) if self.m != self.n else cond

    def _branch_sign(self, jac: np.ndarray) -> np.ndarray:
        if self.m != self.n:
            return np.ones(jac.shape[0])
        return np.linalg.slogdet(jac)[0]

    def solve(self, s: np.ndarray, q_start: np.ndarray | None, dead_centre_cond: float,
              consistency_tol: float) -> KinematicState:
        """Assemble N poses for inputs s (N, n_inputs), keeping the reference pose's assembly branch."""
        n_pose = s.shape[0]
        q0 = np.broadcast_to(self.q_ref if q_start is None else q_start, (n_pose, self.n))
        q, phi = self.newton(q0, s)
        if self._ref_sign is None:
            _, jac_ref = self.residual_jacobian(self.q_ref[None], self.reference_inputs()[None])
            self._ref_sign = float(self._branch_sign(jac_ref)[0])
        tol = 1e-9 * self.lc
        limit = tol if self.m == self.n else consistency_tol

        _, jac = self.residual_jacobian(q, s)
        off_branch = self._branch_sign(jac) != self._ref_sign
        retry = np.flatnonzero(off_branch | ~(np.max(np.abs(phi), axis=1) <= limit))
        still = np.zeros(0, dtype=int)
        if retry.size:  # continuation from the reference pose along a straight input path
            s_ref = self.reference_inputs()
            qr = np.broadcast_to(self.q_ref, (retry.size, self.n)).copy()
            for t in np.linspace(0.1, 1.0, 10):
                qr, phir = self.newton(qr, s_ref + t * (s[retry] - s_ref), max_iter=12)
            qr, phir = self.newton(qr, s[retry])
            q[retry], phi[retry] = qr, phir
            still = retry[~(np.max(np.abs(phir), axis=1) <= limit)]
        status = np.zeros(n_pose, dtype=int)
        messages = [""] * n_pose
        if still.size and self.m == self.n:  # say how far the inputs are out of reach
            reach = self.reachable_fraction(s[still])
            for i, t in zip(still, reach):
                status[i], messages[i] = ASSEMBLY, self.reach_message(s[i], t)
        worst = np.max(np.abs(phi), axis=1)
        for i in np.flatnonzero(~(worst <= limit) & (status == OK)):
            status[i] = ASSEMBLY
            messages[i] = self.assembly_message(phi[i], s[i])
        _, jac = self.residual_jacobian(q, s)
        cond = self.condition(jac)
        for i in np.flatnonzero((status == OK) & ~(cond <= dead_centre_cond)):
            status[i] = DEAD_CENTRE
            messages[i] = (f"kinematic dead centre at {self.describe_inputs(s[i])}: constraint Jacobian "
                           f"condition number {cond[i]:.3g} > {dead_centre_cond:.3g}")
        return KinematicState(q=q, phi=phi, status=status, messages=messages, condition=cond)

    def describe_inputs(self, s: np.ndarray) -> str:
        """``lift_cylinder = 0.6100 m, ...`` for messages."""
        nc = self.cyl_att.shape[1]
        return ", ".join(f"{n} = {v:.4f} {'m' if i < nc else 'rad'}" for i, (n, v) in enumerate(zip(self.input_names, s)))

    def reach_message(self, s: np.ndarray, t: float) -> str:
        """Which inputs are out of reach and by how much (mm, deg), given the reachable fraction t."""
        s_ref = self.reference_inputs()
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
        """Body velocities q̇ and accelerations q̈ (N, n) from input rates ṡ and s̈ (seed 004, φ', φ'')."""
        n_pose = q.shape[0]
        nh, nc = self.hinge_att.shape[1], self.cyl_att.shape[1]
        _, jac = self.residual_jacobian(q, np.zeros((n_pose, self.n_inputs)))
        p, rel = self.positions(q)
        rhs = np.zeros((n_pose, self.m))
        rhs[:, 2 * nh:2 * nh + nc] = s_dot[:, :nc]
        rhs[:, 2 * nh + nc:] = self.lc * s_dot[:, nc:]
        q_dot = self._lsq(jac, rhs)
        v, centripetal = self.point_rates(q_dot, rel)
        gamma = np.zeros((n_pose, self.m))
        gamma[:, :2 * nh] = (centripetal[:, self.hinge_att[0]] - centripetal[:, self.hinge_att[1]]).reshape(n_pose, -1)
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
        return q_dot, self._lsq(jac, rhs2 - gamma)

    def point_rates(self, q_dot: np.ndarray, rel: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Velocities (N, K, 2) of all attachments and their centripetal accelerations −θ̇²·rel."""
        body, _, moving = self._attachment_arrays()
        bi = np.where(moving, body, 0)
        w = q_dot[:, 3 * bi + 2][..., None]
        v = np.stack([q_dot[:, 3 * bi], q_dot[:, 3 * bi + 1]], axis=-1) + w * np.stack([-rel[..., 1], rel[..., 0]], axis=-1)
        mask = moving[None, :, None]
        return np.where(mask, v, 0.0), np.where(mask, -w * w * rel, 0.0)

    def _lsq(self, jac: np.ndarray, rhs: np.ndarray) -> np.ndarray:
        if self.m == self.n:
            return np.linalg.solve(jac, rhs[..., None])[..., 0]
        return np.linalg.solve(np.einsum("nmi,nmj->nij", jac, jac), np.einsum("nmi,nm->ni", jac, rhs)[..., None])[..., 0]


def condition_1(a: np.ndarray) -> np.ndarray:
    """1-norm condition number of each square matrix in a stack (N, k, k); inf if singular."""
    try:
        inv = np.linalg.inv(a)
    except np.linalg.LinAlgError:
        sv = np.linalg.svd(a, compute_uv=False)
        with np.errstate(divide="ignore"):
            return np.where(sv[:, -1] > 0, sv[:, 0] / sv[:, -1], np.inf) * a.shape[-1]
    return np.max(np.sum(np.abs(a), axis=1), axis=1) * np.max(np.sum(np.abs(inv), axis=1), axis=1)
