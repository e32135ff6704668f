"""Where a solved pose's numbers go in its result: the attachments of the named points and the
implement cg, the frame loads (frame-side hinges and member mounts), the result's names; and the
``BatchResult`` of poses whose unknowns a statics solve gave.

SI units (m, N, Pa); frame x forward, z up, origin at the rear wheels' ground contact B.
"""

from __future__ import annotations

from typing import Protocol

import numpy as np

from . import kernels
from .model import Mechanism
from .programs import FrameRows
from .reduced import ReducedSolution
from .results import BatchResult, ResultNames
from .statics import StaticsLayout, StaticsSolution


class Attaching(Protocol):
    """What the layout takes of a kinematics: the index of a point fixed on a body."""

    def attach(self, body: str, key: str, position: np.ndarray | None = None) -> int: ...


class ResultLayout:
    """The result layout of one mechanism, built once: attachments of ``mech.points`` and the
    implement cg, the frame loads (``frame_load_names``: frame-side hinges, then the frame-side ends
    of springs and cylinders) and the names of a ``Result``'s rows; the same as index arrays for the
    compiled outputs (``Solver.outputs_program``)."""

    def __init__(self, mech: Mechanism, kin: Attaching) -> None:
        self.mech = mech
        self.point_att: dict[str, int] = {}
        for name in mech.points:
            owner = next((b for b in mech.moving_bodies if name in b.points), mech.ground)
            self.point_att[name] = kin.attach(owner.name, name)
        self.cg_att = kin.attach(mech.implement.body, f"cg of {mech.implement.body}") if mech.implement else None
        ground = mech.ground.name
        self.frame_load_names: list[str] = []
        self.frame_hinges: list[tuple[int, int, float]] = []   # (hinge index, attachment, sign of the force on the ground)
        for i, h in enumerate(mech.hinges):
            if ground in h.bodies:
                self.frame_hinges.append((i, kin.attach(ground, h.point), 1.0 if h.bodies[1] == ground else -1.0))
                self.frame_load_names.append(f"hinge {h.name}")
        self.frame_members: list[tuple[int, int, float]] = []   # (member index: springs then cylinders, attachment, sign)
        members = [(s.name, s.a, s.b) for s in mech.springs] + [(c.name, c.base, c.rod_end) for c in mech.cylinders]
        for m, (name, a, b) in enumerate(members):
            for end, sign in ((a, -1.0), (b, 1.0)):
                if end.body == ground:
                    self.frame_members.append((m, kin.attach(ground, end.point), sign))
                    self.frame_load_names.append(f"{name} {end.point}")
        self.point_rows = np.array(list(self.point_att.values()), dtype=np.intp)   # attachments of mech.points
        # the frame loads of one pose as index arrays: hinges, then member ends
        self.frame_att = np.array([a for _, a, _ in self.frame_hinges] + [a for _, a, _ in self.frame_members],
                                  dtype=np.intp)
        self.frame_hinge_index = np.array([i for i, _, _ in self.frame_hinges], dtype=np.intp)
        self.frame_hinge_sign = np.array([[sg] for _, _, sg in self.frame_hinges]).reshape(-1, 1)
        self.frame_member_index = np.array([m for m, _, _ in self.frame_members], dtype=np.intp)
        self.frame_member_sign = np.array([[sg] for _, _, sg in self.frame_members]).reshape(-1, 1)
        self._frame_rows: dict[frozenset[str], FrameRows] = {}
        self.names = ResultNames(tuple(self.point_att), tuple(b.name for b in mech.moving_bodies),
                                 tuple((h.name, h.bodies[1], h.bodies[0]) for h in mech.hinges),
                                 tuple(c.name for c in mech.cylinders), tuple(c.name for c in mech.contacts))

    def frame_rows(self, layout: StaticsLayout) -> FrameRows:
        """The ``FrameRows`` of poses solved with ``layout`` (``kernels.batch_outputs``), built once per layout."""
        rows = self._frame_rows.get(layout.force_known)
        if rows is None:
            rows = self._frame_rows[layout.force_known] = FrameRows(
                hinge_cols=np.ascontiguousarray(layout.hinge_cols, dtype=np.int64), frame_att=self.frame_att.astype(np.int64),
                frame_hinge_index=self.frame_hinge_index.astype(np.int64),
                frame_hinge_sign=self.frame_hinge_sign.ravel().astype(float),
                frame_member_index=self.frame_member_index.astype(np.int64),
                frame_member_sign=self.frame_member_sign.ravel().astype(float))
        return rows

    def batch(self, n_pose: int, q: np.ndarray, p: np.ndarray, u: np.ndarray,
              sol: StaticsSolution | ReducedSolution, layout: StaticsLayout, measured_force: np.ndarray,
              cap: dict[str, np.ndarray], rod: dict[str, np.ndarray], failed: np.ndarray) -> BatchResult:
        """The ``BatchResult`` of N poses: body coordinates q (N, n), attachment positions p (N, K, 2) m,
        the statics' unknowns u (N, n_unknowns) and solution ``sol`` in ``layout``, the measured
        cylinder forces (N, C) N, the chambers' gauge pressures (N,) Pa by cylinder, which poses
        failed (N,). Verdicts, messages, residuals and transmission angles are the caller's to set."""
        mech = self.mech
        cyl_force = {}
        for k, c in enumerate(mech.cylinders):
            f = measured_force[:, k] if c.name in layout.force_known else u[:, layout.cyl_col[c.name]]
            cyl_force[c.name] = np.where(failed, np.nan, f)
        contact_n = {c.name: u[:, layout.contact_col[c.name]] for c in mech.contacts}
        imp = mech.implement
        if layout.implement_col is not None:
            imp_load = u[:, layout.implement_col]
        elif imp is not None:
            imp_load = np.where(failed, np.nan, imp.mass * mech.gravity)
        else:
            imp_load = np.full(n_pose, np.nan)
        cylinders = np.column_stack(list(cyl_force.values())) if cyl_force else np.zeros((n_pose, 0))   # (N, C)
        member_force = np.concatenate([sol.spring_force, cylinders], axis=1)
        axes = np.concatenate([sol.spring_axis, sol.cylinder_axis], axis=1)
        # the hinge forces (N, H, 2), frame loads (N, F, 2) and largest forces of all poses in one compiled pass
        out = kernels.batch_outputs(u, p, member_force, axes, cylinders, self.frame_rows(layout))
        hinge_force = {h.name: out.hinge_force[:, i] for i, h in enumerate(mech.hinges)}
        return BatchResult(
            points={n: p[:, a] for n, a in self.point_att.items()},
            body_poses={b.name: q[:, 3 * i:3 * i + 3] for i, b in enumerate(mech.moving_bodies)},
            hinge_force=hinge_force, hinge_bodies={h.name: h.bodies for h in mech.hinges},
            cylinder_length={c.name: np.where(failed, np.nan, sol.cylinder_length[:, k]) for k, c in enumerate(mech.cylinders)},
            cylinder_force=cyl_force,
            cap_pressure_predicted={c.name: cyl_force[c.name] / (c.count * c.cap_area) for c in mech.cylinders},
            cap_pressure_measured=cap, rod_pressure_measured=rod,
            contact_normal=contact_n,
            contact_tangential={c.name: c.friction * contact_n[c.name] for c in mech.contacts},
            implement_load=imp_load,
            implement_cg=p[:, self.cg_att] if self.cg_att is not None else np.full((n_pose, 2), np.nan),
            frame_load_names=list(self.frame_load_names),
            frame_load_points=out.frame_points, frame_load_forces=out.frame_forces,
            residual=np.where(failed, np.nan, sol.residual), consistency_residual=np.zeros(n_pose),
            condition=np.zeros(n_pose), largest_force=out.largest, status=np.zeros(n_pose, dtype=int),
            messages=[""] * n_pose,
            transmission_angle=np.full(n_pose, np.nan), weakest_transmission=[""] * n_pose,
            load_amplification=np.full(n_pose, np.nan))
