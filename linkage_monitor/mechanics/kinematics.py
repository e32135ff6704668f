"""Batched position, velocity and acceleration analysis of a planar linkage.

Coordinates, attachments and constraint rows: ``kinematic_layout``. The hinges always close;
sensors beyond the degrees of freedom (redundant) are fitted in least squares over the closed
linkage's poses (loop closure hard, sensors soft: ``kernels.closed_step``). Every function works
on a stack of N poses; the per-pose work runs in compiled code (:mod:`.kernels`) over the index
arrays built once.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from . import chain, kernels
from .kinematic_layout import KinematicLayout, as_xz, wrap_angle
from .model import Mechanism
from .programs import KinematicsProgram


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


class Kinematics(KinematicLayout):
    """Constraint equations of one mechanism over its index structure (``KinematicLayout``), built once.

    The compiled kernels take the attachments as plain arrays (``geometry``) and the rest of the
    loop closure as ``program``.
    """

    def __init__(self, mech: Mechanism) -> None:
        super().__init__(mech)
        self._program: KinematicsProgram | None = None
        p, _ = self.positions(self.q_ref[None])
        self._s_ref = np.concatenate([np.hypot(*(p[0, self.cyl_att[1]] - p[0, self.cyl_att[0]]).T),
                                      self.angle_reference])
        phi_ref, jac_ref = self.residual_jacobian(self.q_ref[None], self._s_ref[None])
        self.drive_rows, self.fit_rows = self.driving_rows(jac_ref[0])
        p_ref, _ = self.positions(self.q_ref[None])
        self.chain_int, self.chain_float, self.chain_steps = chain.decompose(
            mech, self.body_index, self.hinge_att, self.cyl_att, np.array(self._att_ref).reshape(-1, 2), p_ref[0])
        # the structural non-zeros: those of the Jacobian at a pose in general position (jittered)
        q = self.q_ref + 0.1 * np.random.default_rng(0).standard_normal(self.n)
        self._loops = self.loop_blocks(self.drive_rows.tolist(),
                                       self.residual_jacobian(q[None], self._s_ref[None])[1][0] != 0.0)
        rows = [b.rows for b in self._loops]
        columns = [b.columns for b in self._loops]
        self._loop_arrays = (np.concatenate(rows or [np.zeros(0, dtype=int)]).astype(np.int64),
                             np.concatenate(columns or [np.zeros(0, dtype=int)]).astype(np.int64),
                             np.cumsum([0] + [len(r) for r in rows]).astype(np.int64))
        self._ref_branch = self.branch(jac_ref)[0]   # the assembly branch (one sign per loop) every pose keeps
        ref_cond = np.array([kernels.condition(jac_ref[0], self.column_scale)])
        self._reference = KinematicState(s=self._s_ref[None], q=self.q_ref[None], phi=phi_ref,
                                         status=np.zeros(1, dtype=int), messages=[""], condition=ref_cond)

    def _attachments_changed(self) -> None:
        """Forget ``program`` with the layout's geometry."""
        super()._attachments_changed()
        self._program = None

    @property
    def program(self) -> KinematicsProgram:
        """``geometry`` with what ``kernels.solve_poses`` also takes: the driving and fitted rows
        (``driving_rows``), the chain of dyads (``chain.decompose``), the column scale, the loops'
        index arrays and the reference assembly branch (``kernels.live_series``' ``kinematics``)."""
        if self._program is None:
            loop_rows, loop_cols, loop_ptr = self._loop_arrays
            self._program = KinematicsProgram(
                **self.geometry._asdict(), drive_rows=self.drive_rows, fit_rows=self.fit_rows,
                chain_int=self.chain_int, chain_float=self.chain_float, column_scale=self.column_scale,
                loop_rows=loop_rows, loop_cols=loop_cols, loop_ptr=loop_ptr, ref_branch=self._ref_branch)
        return self._program

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

        Each pose is the chain of dyads' (``kernels.assembly._kinematic_pose``); without a chain, or with a
        step out of reach, Newton starts from the tangent prediction off ``previous`` (one solved
        pose: a live node passes its last one) or off the reference pose; poses that fail or land
        on another branch are redone by continuation from the reference pose.
        ``reach``: the message of a pose out of reach says how far it is (``reachable_fraction``, a
        bisection of ~30 Newton solves); False: which constraint stays open at the closest pose.
        ``dead_centre_cond``: a pose whose constraint Jacobian's condition number is above it is a
        kinematic dead centre; None: the condition number is not computed (NaN), the caller's
        statics decide (the reduced path's transmission measure covers every step of the chain).
        """
        s = self.wrap_angles(s)
        start = self._reference if previous is None else previous
        with_condition = dead_centre_cond is not None
        q, phi, cond, on_branch = self.continue_from(start, s, with_condition)
        limit = 1e-9 * self.lc if self.m == self.n else consistency_tol
        assembled = self.assembled(phi, limit)
        retry = np.flatnonzero(~on_branch | ~assembled)
        still = off = np.zeros(0, dtype=int)
        if retry.size:  # continuation from the reference pose along a straight input path
            qr, phir, jacr = self.continuation(s[retry])
            qr[:, 2::3] = wrap_angle(qr[:, 2::3])   # whole turns: the rotation nearest the reference pose's (0)
            q[retry], phi[retry] = qr, phir
            if with_condition:
                cond[retry] = [kernels.condition(j, self.column_scale) for j in jacr]
            closed = assembled[retry] = self.assembled(phir, limit)
            still = retry[~closed]
            off = retry[~self.on_branch(jacr) & closed]
        status, messages = self.verdicts(s, phi, cond, assembled, off, still, dead_centre_cond, reach)
        return KinematicState(s=s, q=q, phi=phi, status=status, messages=messages, condition=cond)

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

