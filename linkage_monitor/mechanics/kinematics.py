"""Batched position, velocity and acceleration analysis of a planar linkage.

Coordinates: (x, z, θ) per moving body: (x, z) the position (m) of the body's origin (the
centroid of its points in the reference pose), θ its rotation from the reference pose (rad,
from +x towards +z). Constraints (rows, all in metres): hinge coincidence (2 per hinge),
measured cylinder lengths, measured relative angles (scaled by the length scale ``lc``). The
hinges always close; sensors beyond the degrees of freedom (redundant) are fitted in least squares
over the closed linkage's poses (loop closure hard, sensors soft: ``kernels.closed_step``).
Every function works on a stack of N poses; the per-pose work runs in compiled code
(:mod:`.kernels`) over the index arrays built here once.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import connected_components, maximum_bipartite_matching

from . import chain, kernels
from .model import Mechanism
from .programs import Geometry, KinematicsProgram
from .results import Status



@dataclass
class KinematicState:
    """Solved poses for inputs s (N, n_inputs): q (N, n), constraint residual phi (N, m) m,
    status (N,), messages, condition (N,). A solve continues from the last pose (q, s)."""

    s: np.ndarray
    q: np.ndarray
    phi: np.ndarray
    status: np.ndarray
    messages: list[str]
    condition: np.ndarray


class Kinematics:
    """Constraint equations of one mechanism; index structure built once.

    An attachment is a point fixed on a body (body index, offset from the body's origin in the
    reference pose); the ground is the body index −1. The compiled kernels take these as plain
    arrays (``geometry``); the ground's (x, z, θ) are three zero columns appended to q
    (``_padded``) where rates are formed.
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
        self._arrays: Geometry | None = None
        self._program: KinematicsProgram | None = None
        self._att_body: list[int] = []
        self._att_ref: list[np.ndarray] = []
        # constraint rows
        hinge_a, hinge_b = [], []
        for h in mech.hinges:
            hinge_a.append(self.attach(h.bodies[0], h.point))
            hinge_b.append(self.attach(h.bodies[1], h.point))
        self.hinge_att = np.array([hinge_a, hinge_b], dtype=np.int64).reshape(2, -1)
        cyls = [mech.cylinder(c) for c in mech.measurements.cylinders]
        self.cyl_att = np.array([[self.attach(c.base.body, c.base.point) for c in cyls],
                                 [self.attach(c.rod_end.body, c.rod_end.point) for c in cyls]], dtype=np.int64).reshape(2, -1)
        hinges = {h.name: h for h in mech.hinges}
        self.angle_bodies = np.array([[self.body_index[hinges[a.hinge].bodies[k]] for a in mech.measurements.angles]
                                      for k in (0, 1)], dtype=np.int64).reshape(2, -1)
        self.angle_reference = np.array([a.reference for a in mech.measurements.angles], dtype=float)
        nh, nc, na = len(mech.hinges), len(cyls), len(mech.measurements.angles)
        self.m = 2 * nh + nc + na
        self.n_inputs = nc + na
        self.row_names = ([f"hinge '{h.name}' gap" for h in mech.hinges for _ in (0, 1)]
                          + [f"cylinder '{c.name}' length" for c in cyls]
                          + [f"angle '{a.name}'" for a in mech.measurements.angles])
        self.input_names = [c.name for c in cyls] + [a.name for a in mech.measurements.angles]
        self.column_scale = np.tile([1.0, 1.0, 1.0 / self.lc], self.n // 3)
        p, _ = self.positions(self.q_ref[None])
        self._s_ref = np.concatenate([np.hypot(*(p[0, self.cyl_att[1]] - p[0, self.cyl_att[0]]).T),
                                      self.angle_reference])
        phi_ref, jac_ref = self.residual_jacobian(self.q_ref[None], self._s_ref[None])
        self.drive_rows, self.fit_rows = self._driving_system(jac_ref[0])
        p_ref, _ = self.positions(self.q_ref[None])
        self.chain_int, self.chain_float, self.chain_steps = chain.decompose(
            mech, self.body_index, self.hinge_att, self.cyl_att, np.array(self._att_ref).reshape(-1, 2), p_ref[0])
        self._loops = self._loop_blocks(jac_ref[0])
        rows = [r for r, _ in self._loops]
        self._loop_arrays = (np.concatenate(rows or [np.zeros(0, dtype=int)]).astype(np.int64),
                             np.concatenate([c for _, c in self._loops] or [np.zeros(0, dtype=int)]).astype(np.int64),
                             np.cumsum([0] + [len(r) for r in rows]).astype(np.int64))
        self._ref_branch = self.branch(jac_ref)[0]   # the assembly branch (one sign per loop) every pose keeps
        ref_cond = np.array([kernels.condition(jac_ref[0], self.column_scale)])
        self._reference = KinematicState(s=self._s_ref[None], q=self.q_ref[None], phi=phi_ref,
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
            self._arrays = self._program = None
        return self._att[ident]

    @property
    def geometry(self) -> Geometry:
        """The loop closure as the kernels take it: attachment bodies (K,) and offsets (K, 2) m,
        hinge attachments (2, n_hinges), measured cylinders' (base, rod end) attachments (2, nc),
        angle sensors' bodies (2, na), their reference angles (na,) rad, the length scale lc m."""
        if self._arrays is None:
            self._arrays = Geometry(att_body=np.array(self._att_body, dtype=np.int64),
                                    att_ref=np.array(self._att_ref).reshape(-1, 2), hinge_att=self.hinge_att,
                                    cyl_att=self.cyl_att, angle_body=self.angle_bodies,
                                    angle_reference=self.angle_reference, lc=self.lc)
        return self._arrays

    @property
    def program(self) -> KinematicsProgram:
        """``geometry`` with what ``kernels.solve_poses`` also takes: the driving and fitted rows
        (``_driving_system``), the chain of dyads (``chain.decompose``), the column scale, the loops'
        index arrays and the reference assembly branch (``kernels.live_series``' ``kinematics``)."""
        if self._program is None:
            loop_rows, loop_cols, loop_ptr = self._loop_arrays
            self._program = KinematicsProgram(
                **self.geometry._asdict(), drive_rows=self.drive_rows, fit_rows=self.fit_rows,
                chain_int=self.chain_int, chain_float=self.chain_float, column_scale=self.column_scale,
                loop_rows=loop_rows, loop_cols=loop_cols, loop_ptr=loop_ptr, ref_branch=self._ref_branch)
        return self._program

    def _padded(self, q: np.ndarray) -> np.ndarray:
        """q (N, n) with the ground's (x, z, θ) = 0 appended as columns n..n+2."""
        return np.concatenate([q, np.zeros((q.shape[0], 3))], axis=1)

    def positions(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Positions P (N, K, 2) m of all attachments and their offsets from their body's origin.

        Ground attachments are offset from the global origin B, i.e. the offset is their position.
        """
        geometry = self.geometry
        return kernels.positions_batch(np.ascontiguousarray(q, dtype=float), geometry.att_body, geometry.att_ref)

    # ---- constraints ----------------------------------------------------------------------
    def residual_jacobian(self, q: np.ndarray, s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Constraint residual Φ (N, m) m and Jacobian ∂Φ/∂q (N, m, n) for inputs s (N, n_inputs)."""
        return kernels.residual_jacobian_batch(np.ascontiguousarray(q, dtype=float),
                                               np.ascontiguousarray(s, dtype=float), *self.geometry)

    def reference_inputs(self) -> np.ndarray:
        """Inputs (cylinder lengths m, angles rad) that the reference pose satisfies, shape (n_inputs,)."""
        return self._s_ref.copy()

    # ---- solving --------------------------------------------------------------------------
    def newton(self, q: np.ndarray, s: np.ndarray, max_iter: int = 25) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Newton / Gauss-Newton iterations from q (N, n) (``kernels.newton``): redundant sensors
        fitted in least squares with every hinge closed.

        Returns q, its residual Φ (N, m) and Jacobian (N, m, n), both evaluated at the returned q.
        A pose stops when |Φ| ≤ 1e-13·lc, or before a step that is not finite (singular) or,
        overdetermined, below 1e-13·lc (the fitted inputs' residual need not reach 0).
        """
        return kernels.newton_batch(np.ascontiguousarray(q, dtype=float), np.ascontiguousarray(s, dtype=float),
                                    max_iter, *(*self.geometry, self.drive_rows, self.fit_rows))

    def assembled(self, phi: np.ndarray, limit: float) -> np.ndarray:
        """(N,) whether each pose's residual Φ (N, m) is an assembled linkage: hinges closed to
        1e-9·lc, every row within ``limit`` m (``kernels.assembled``)."""
        return kernels.assembled_batch(np.ascontiguousarray(phi, dtype=float), 2 * self.hinge_att.shape[1], self.lc,
                                       limit)

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

    def _driving_system(self, jac_ref: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Rows (n,) of the square system that closes the linkage — every hinge row, then as many
        input rows (cylinders, then angles, in order) as close the degrees of freedom — and the
        remaining input rows (redundant sensors, fitted in least squares: ``kernels.closed_step``).
        Both empty when no such square system exists at the reference pose (hinge rows that are
        not independent): then every row is fitted in least squares."""
        nh2 = 2 * self.hinge_att.shape[1]
        rows = list(range(nh2))
        for r in range(nh2, self.m):          # input rows in order (cylinders, then angles), while they add rank
            if len(rows) == self.n:
                break
            if np.linalg.matrix_rank(jac_ref[rows + [r]]) == len(rows) + 1:
                rows.append(r)
        if len(rows) != self.n or np.linalg.matrix_rank(jac_ref[rows]) < self.n:
            return np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64)
        fit = [r for r in range(self.m) if r not in rows]
        return np.array(rows, dtype=np.int64), np.array(fit, dtype=np.int64)

    # ---- assembly branch: one sign per loop ------------------------------------------------------
    def _loop_blocks(self, jac_ref: np.ndarray) -> list[tuple[np.ndarray, np.ndarray]]:
        """(rows, columns) of each loop of the linkage: the diagonal blocks of the block-triangular
        form of the square driving system (hinge rows + as many input rows, cylinders first, as
        close the degrees of freedom), found from its structure (a maximum matching of rows to
        columns, then the strongly connected components of the matched graph). A chain of dyads
        gives one block per dyad; the sign of each block's determinant is that loop's assembly
        branch (the sign of one global determinant would miss two loops flipping together)."""
        rows = self.drive_rows.tolist()
        if not rows:
            return []                         # not closable by a square subsystem: no branch to keep
        # the structural non-zeros: those of the Jacobian at a pose in general position (jittered)
        q = self.q_ref + 0.1 * np.random.default_rng(0).standard_normal(self.n)
        pattern = self.residual_jacobian(q[None], self._s_ref[None])[1][0] != 0.0
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
        return np.array([kernels.loop_signs(j, *self._loop_arrays) for j in jac]).reshape(len(jac), len(self._loops))

    def on_branch(self, jac: np.ndarray) -> np.ndarray:
        """True (N,) where no loop is in the opposite assembly of the reference pose's (a loop at a
        dead centre, sign 0, is left to the dead-centre check)."""
        return ~np.any(self.branch(jac) * self._ref_branch < 0.0, axis=1)

    def solve(self, s: np.ndarray, previous: KinematicState | None, dead_centre_cond: float | None,
              consistency_tol: float, reach: bool = True) -> KinematicState:
        """Assemble N poses for inputs s (N, n_inputs), keeping the reference pose's assembly branch.

        Each pose is the chain of dyads' (``kernels._kinematic_pose``); without a chain, or with a
        step out of reach, Newton starts from the tangent prediction off ``previous`` (one solved
        pose: a live node passes its last one) or off the reference pose; poses that fail or land
        on another branch are redone by continuation from the reference pose.
        ``reach``: the message of a pose out of reach says how far it is (``reachable_fraction``, a
        bisection of ~30 Newton solves); False: which constraint stays open at the closest pose.
        ``dead_centre_cond``: a pose whose constraint Jacobian's condition number is above it is a
        kinematic dead centre; None: the condition number is not computed (NaN), the caller's
        statics decide (the reduced path's transmission measure covers every step of the chain).
        """
        n_pose = s.shape[0]
        s = self.wrap_angles(s)
        start = self._reference if previous is None else previous
        with_condition = dead_centre_cond is not None
        q, phi, cond, on_branch = self.continue_from(start, s, with_condition)
        limit = 1e-9 * self.lc if self.m == self.n else consistency_tol
        retry = np.flatnonzero(~on_branch | ~self.assembled(phi, limit))
        still = np.zeros(0, dtype=int)
        if retry.size:  # continuation from the reference pose along a straight input path
            s_ref = self._s_ref
            qr = np.broadcast_to(self.q_ref, (retry.size, self.n)).copy()
            for t in np.linspace(0.1, 1.0, 10):
                qr, _, _ = self.newton(qr, s_ref + t * (s[retry] - s_ref), max_iter=12)
            qr, phir, jacr = self.newton(qr, s[retry])
            qr[:, 2::3] = wrap_angle(qr[:, 2::3])   # whole turns: the rotation nearest the reference pose's (0)
            q[retry], phi[retry] = qr, phir
            if with_condition:
                cond[retry] = [kernels.condition(j, self.column_scale) for j in jacr]
            closed = self.assembled(phir, limit)
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
        if still.size and self.m == self.n and reach:  # say how far the inputs are out of reach
            fraction = self.reachable_fraction(s[still])
            for i, t in zip(still, fraction):
                status[i], messages[i] = Status.ASSEMBLY, self.reach_message(s[i], t)
        for i in np.flatnonzero(~self.assembled(phi, limit) & (status == Status.OK)):
            status[i] = Status.ASSEMBLY
            messages[i] = self.assembly_message(phi[i], s[i])
        if dead_centre_cond is not None:
            for i in np.flatnonzero((status == Status.OK) & ~(cond <= dead_centre_cond)):
                status[i] = Status.DEAD_CENTRE
                messages[i] = (f"kinematic dead centre at {self.describe_inputs(s[i])}: constraint Jacobian "
                               f"condition number {cond[i]:.3g} > {dead_centre_cond:.3g}")
        return KinematicState(s=s, q=q, phi=phi, status=status, messages=messages, condition=cond)

    def wrap_angles(self, s: np.ndarray) -> np.ndarray:
        """Inputs s (..., n_inputs) with each angle (rad) as the nearest equivalent (modulo 2π) of the
        reference pose's reading: a sensor in [−π, π) or [0, 2π) gives the same pose."""
        nc = self.cyl_att.shape[1]
        s = np.array(s, dtype=float)
        s[..., nc:] = self.angle_reference + wrap_angle(s[..., nc:] - self.angle_reference)
        return s

    def continue_from(self, start: KinematicState, s: np.ndarray, with_condition: bool = True
                      ) -> tuple[np.ndarray, ...]:
        """``kernels.solve_poses`` from the last pose of ``start`` for inputs s (N, n_inputs): q, Φ,
        condition number (NaN without ``with_condition``) and whether each pose is on the reference
        assembly branch."""
        return kernels.solve_poses(start.q[-1:], start.s[-1:], np.ascontiguousarray(s, dtype=float), 25, self.program,
                                   with_condition)

    @property
    def reference(self) -> KinematicState:
        """The reference pose, solved (where a cold solve starts)."""
        return self._reference

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
        att_body = self.geometry.att_body
        col = np.where(att_body >= 0, 3 * att_body, self.n)
        qp = self._padded(q_dot)        # the ground's rates are the appended zeros
        w = qp[:, col + 2]
        relc = rel[..., 0] + 1j * rel[..., 1]
        v = qp[:, col] + 1j * qp[:, col + 1] + 1j * w * relc
        return as_xz(v), as_xz(-w * w * relc)

    def _solve_linear(self, jac: np.ndarray, rhs: np.ndarray) -> np.ndarray:
        """x (N, n) with jac·x = rhs (N, m); overdetermined: the hinge rows exactly and the inputs in
        least squares (``kernels.closed_step``, as the positions are fitted)."""
        if self.m == self.n:
            return np.linalg.solve(jac, rhs[..., None])[..., 0]
        n_hard = 2 * self.hinge_att.shape[1]
        return np.array([kernels.closed_step(j, r, self.drive_rows, self.fit_rows, n_hard)
                         for j, r in zip(np.ascontiguousarray(jac, dtype=float), np.ascontiguousarray(rhs, dtype=float))]
                        ).reshape(rhs.shape[0], self.n)


def wrap_angle(a: np.ndarray) -> np.ndarray:
    """Angles (rad) taken modulo 2π into [−π, π)."""
    return np.remainder(a + np.pi, 2.0 * np.pi) - np.pi


def as_xz(z: np.ndarray) -> np.ndarray:
    """(..., 2) real array [x, z] of a complex array x + i·z (a view when z is C-contiguous)."""
    return np.ascontiguousarray(z).view(np.float64).reshape(z.shape + (2,))
