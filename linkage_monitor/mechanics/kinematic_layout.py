"""The index structure of a planar linkage's loop closure, built once: coordinates, attachments
(points fixed on bodies), constraint rows, measured inputs; the structure of its loops; the
wording of its assembly verdicts. No equations: ``Kinematics`` solves them.

Coordinates: (x, z, θ) per moving body: (x, z) the position (m) of the body's origin (the
centroid of its points in the reference pose), θ its rotation from the reference pose (rad,
from +x towards +z). Constraint rows (all in metres): hinge coincidence (2 per hinge), measured
cylinder lengths, measured relative angles (scaled by the length scale ``lc``).
"""

from __future__ import annotations

from abc import ABC, abstractmethod

import numpy as np

from .loops import LoopBlock, diagonal_blocks
from .model import Mechanism
from .programs import Geometry
from .results import Status


class KinematicLayout(ABC):
    """Coordinates, attachments and constraint rows of one mechanism; the equations are a subclass's.

    An attachment is a point fixed on a body (body index, offset from the body's origin in the
    reference pose); the ground is the body index −1. The ground's (x, z, θ) are three zero
    columns appended to q (``_padded``) where rates are formed.
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
        self._geometry: Geometry | None = None
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
        self._s_ref = np.zeros(self.n_inputs)   # the reference pose's inputs: the subclass's to compute

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
            self._attachments_changed()
        return self._att[ident]

    def _attachments_changed(self) -> None:
        """Forget what was built of the attachments (a subclass forgets its own too)."""
        self._geometry = None

    @property
    def geometry(self) -> Geometry:
        """The loop closure as plain arrays: attachment bodies (K,) and offsets (K, 2) m, hinge
        attachments (2, n_hinges), measured cylinders' (base, rod end) attachments (2, nc), angle
        sensors' bodies (2, na), their reference angles (na,) rad, the length scale lc m."""
        if self._geometry is None:
            self._geometry = Geometry(att_body=np.array(self._att_body, dtype=np.int64),
                                      att_ref=np.array(self._att_ref).reshape(-1, 2), hinge_att=self.hinge_att,
                                      cyl_att=self.cyl_att, angle_body=self.angle_bodies,
                                      angle_reference=self.angle_reference, lc=self.lc)
        return self._geometry

    def _padded(self, q: np.ndarray) -> np.ndarray:
        """q (N, n) with the ground's (x, z, θ) = 0 appended as columns n..n+2."""
        return np.concatenate([q, np.zeros((q.shape[0], 3))], axis=1)

    def reference_inputs(self) -> np.ndarray:
        """Inputs (cylinder lengths m, angles rad) that the reference pose satisfies, shape (n_inputs,)."""
        return self._s_ref.copy()

    def wrap_angles(self, s: np.ndarray) -> np.ndarray:
        """Inputs s (..., n_inputs) with each angle (rad) as the nearest equivalent (modulo 2π) of the
        reference pose's reading: a sensor in [−π, π) or [0, 2π) gives the same pose."""
        nc = self.cyl_att.shape[1]
        s = np.array(s, dtype=float)
        s[..., nc:] = self.angle_reference + wrap_angle(s[..., nc:] - self.angle_reference)
        return s

    # ---- the equations (a subclass's) ------------------------------------------------------------
    @abstractmethod
    def newton(self, q: np.ndarray, s: np.ndarray, max_iter: int = 25) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """q (N, n) assembled for inputs s (N, n_inputs) from q, its residual Φ (N, m) m and Jacobian (N, m, n)."""

    # ---- the structure of the loops ------------------------------------------------------------
    def driving_rows(self, jac_ref: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Rows (n,) of the square system that closes the linkage — every hinge row, then as many
        input rows (cylinders, then angles, in order) as close the degrees of freedom — and the
        remaining input rows (redundant sensors, fitted in least squares), from the Jacobian
        ``jac_ref`` (m, n) at the reference pose. Both empty when no such square system exists
        (hinge rows that are not independent): then every row is fitted in least squares."""
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

    @staticmethod
    def loop_blocks(rows: list[int], pattern: np.ndarray) -> list[LoopBlock]:
        """The rows (of the Jacobian) and columns of each loop of the linkage: the diagonal blocks of
        the block-triangular form of the square driving system ``rows`` (``driving_rows``), found
        from the structural non-zeros ``pattern`` (m, n) of the Jacobian (``loops.diagonal_blocks``).
        A chain of dyads gives one block per dyad; the sign of each block's determinant is that
        loop's assembly branch (the sign of one global determinant would miss two loops flipping
        together)."""
        if not rows:
            return []                         # not closable by a square subsystem: no branch to keep
        return [LoopBlock(rows=np.array(rows, dtype=np.int64)[block.rows], columns=block.columns)
                for block in diagonal_blocks(pattern[rows])]

    # ---- out of reach: continuation from the reference pose --------------------------------------
    def continuation(self, s: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``newton`` for inputs s (N, n_inputs) along a straight input path from the reference pose
        (ten steps): q (N, n), Φ (N, m), Jacobian (N, m, n) at the end."""
        s_ref = self._s_ref
        qr = np.broadcast_to(self.q_ref, (s.shape[0], self.n)).copy()
        for t in np.linspace(0.1, 1.0, 10):
            qr, _, _ = self.newton(qr, s_ref + t * (s - s_ref), max_iter=12)
        return self.newton(qr, s)

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

    # ---- verdicts -------------------------------------------------------------------------------
    def verdicts(self, s: np.ndarray, phi: np.ndarray, condition: np.ndarray, assembled: np.ndarray,
                 mirrored: np.ndarray, unreached: np.ndarray, dead_centre_cond: float | None, reach: bool
                 ) -> tuple[np.ndarray, list[str]]:
        """Status (N,) and message of each pose solved for inputs s (N, n_inputs): ASSEMBLY where
        only a mirrored loop assembles (indices ``mirrored``), where the inputs are out of reach
        (indices ``unreached``; with ``reach`` how far, ``reachable_fraction``) or where the pose
        is not ``assembled`` (N,) (which constraint stays open, from Φ (N, m) m); DEAD_CENTRE where
        the constraint Jacobian's ``condition`` (N,) is above ``dead_centre_cond`` (None: not judged)."""
        n_pose = s.shape[0]
        status = np.zeros(n_pose, dtype=int)
        messages = [""] * n_pose
        for i in mirrored:
            status[i] = Status.ASSEMBLY
            messages[i] = (f"cannot assemble the linkage for {self.describe_inputs(s[i])} on the reference "
                           "pose's assembly branch: the inputs fit only a mirrored assembly of a loop (check the "
                           "sensors and their zero offsets)")
        if unreached.size and self.m == self.n and reach:  # say how far the inputs are out of reach
            fraction = self.reachable_fraction(s[unreached])
            for i, t in zip(unreached, fraction):
                status[i], messages[i] = Status.ASSEMBLY, self.reach_message(s[i], t)
        for i in np.flatnonzero(~assembled & (status == Status.OK)):
            status[i] = Status.ASSEMBLY
            messages[i] = self.assembly_message(phi[i], s[i])
        if dead_centre_cond is not None:
            for i in np.flatnonzero((status == Status.OK) & ~(condition <= dead_centre_cond)):
                status[i] = Status.DEAD_CENTRE
                messages[i] = (f"kinematic dead centre at {self.describe_inputs(s[i])}: constraint Jacobian "
                               f"condition number {condition[i]:.3g} > {dead_centre_cond:.3g}")
        return status, messages

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


def wrap_angle(a: np.ndarray) -> np.ndarray:
    """Angles (rad) taken modulo 2π into [−π, π)."""
    return np.remainder(a + np.pi, 2.0 * np.pi) - np.pi


def as_xz(z: np.ndarray) -> np.ndarray:
    """(..., 2) real array [x, z] of a complex array x + i·z (a view when z is C-contiguous)."""
    return np.ascontiguousarray(z).view(np.float64).reshape(z.shape + (2,))
