"""Batched (kineto)statics: 3 equations per moving body, unknown reactions solved per pose.

Equations per moving body: ΣFx = 0, ΣFz = 0, ΣM about the origin B = 0 (moment rows divided by
the length scale ``lc`` so the matrix is dimensionless). Unknowns: hinge reactions (fx, fz: the
force on ``bodies[1]`` from ``bodies[0]``), axial forces of cylinders whose force is not measured
(+ = pushing), contact normal forces (friction T = f·N folded into the column, Kotov & Krol), and,
when measured cylinder forces leave an extra equation, the vertical load at the implement cg.
The index structure (:class:`StaticsLayout`) is built once per set of measured cylinder forces;
the per-pose assembly and solution run compiled (``kernels.solve_statics``).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property
from typing import Any

import numpy as np

from .errors import UnobservableError
from .kinematics import Kinematics
from . import kernels
from .model import Mechanism
from .programs import StaticsProgram

_UNIT = {"x": (1.0, 0.0), "z": (0.0, 1.0), "down": (0.0, -1.0)}


@dataclass
class StaticsSolution:
    """Unknowns u (N, n_unknowns), equilibrium residual (N,) N, condition number (N,), per-pose member axes."""

    unknowns: np.ndarray
    residual: np.ndarray
    condition: np.ndarray
    cylinder_axis: np.ndarray
    cylinder_length: np.ndarray
    spring_force: np.ndarray
    spring_axis: np.ndarray


_NO_ACCEL_LINEAR, _NO_ACCEL_ANGULAR = np.zeros((1, 1, 2)), np.zeros((1, 1))   # not read: has_accel False


class StaticsLayout:
    """Columns, rows and known-load terms of the statics for one set of force-measured cylinders."""

    def __init__(self, mech: Mechanism, kin: Kinematics, force_known: frozenset[str]) -> None:
        self.mech, self.kin, self.force_known = mech, kin, force_known
        bi = kin.body_index
        self.n_eq = kin.n
        self.columns: list[str] = []
        terms: list[tuple[int, int, int, str, Any]] = []  # (column, attachment, body, kind, parameter)

        def column(name: str, parts: list[tuple[str, str, str, object]]) -> None:
            col = len(self.columns)
            self.columns.append(name)
            for body, key, kind, param in parts:
                if bi[body] >= 0:
                    pos = np.asarray(param, dtype=float) if kind == "down" else None
                    terms.append((col, kin.attach(body, key, pos), bi[body], kind, param))

        for h in mech.hinges:
            a, b = h.bodies
            for axis in ("x", "z"):
                column(f"hinge '{h.name}' f{axis}", [(b, h.point, axis, 1.0), (a, h.point, axis, -1.0)])
        self.hinge_cols = np.arange(2 * len(mech.hinges)).reshape(-1, 2)
        self.cyl_col = {}
        for k, c in enumerate(mech.cylinders):
            if c.name not in force_known:
                self.cyl_col[c.name] = len(self.columns)
                column(f"cylinder '{c.name}' force", [(c.rod_end.body, c.rod_end.point, "cyl", (k, 1.0)),
                                                      (c.base.body, c.base.point, "cyl", (k, -1.0))])
        self.contact_col = {}
        for contact in mech.contacts:
            self.contact_col[contact.name] = len(self.columns)
            column(f"contact '{contact.name}' normal force", [(contact.body, contact.point, "dir",
                                                              contact.force_direction)])
        # per cylinder (mech order): force measured, else the column of its unknown force (0 for measured ones)
        self.force_measured = np.array([c.name in force_known for c in mech.cylinders], dtype=bool)
        self.cylinder_cols = np.array([self.cyl_col.get(c.name, 0) for c in mech.cylinders], dtype=np.intp)
        self.contact_cols = np.array(list(self.contact_col.values()), dtype=np.intp)   # mech.contacts order
        self.implement_col: int | None = None
        imp = mech.implement
        if imp is not None and force_known and len(self.columns) < self.n_eq:
            self.implement_col = len(self.columns)
            column(f"implement '{imp.body}' vertical load", [(imp.body, f"cg of {imp.body}", "down", imp.cg)])
        self.n_unknowns = len(self.columns)
        # column terms as arrays
        self.t_col = np.array([t[0] for t in terms], dtype=np.int64)
        self.t_att = np.array([t[1] for t in terms], dtype=np.int64)
        self.t_body = np.array([t[2] for t in terms], dtype=np.int64)
        const = np.zeros((len(terms), 2))
        cyl_t, cyl_k, cyl_s = [], [], []
        for i, (_, _, _, kind, param) in enumerate(terms):
            if kind in ("x", "z"):
                const[i] = np.array(_UNIT[kind]) * float(param)   # a sign, ±1.0
            elif kind == "down":
                const[i] = _UNIT["down"]
            elif kind == "dir":
                const[i] = np.asarray(param, dtype=float)
            else:
                k_cyl, sign = param   # (cylinder index, ±1.0)
                cyl_t.append(i)
                cyl_k.append(k_cyl)
                cyl_s.append(sign)
        self.t_const = const
        self._build_known_terms()
        # a cylinder's column terms act along its axis: member n_springs + k, with its sign
        self.t_member = np.full(len(terms), -1, dtype=np.int64)
        self.t_sign = np.zeros(len(terms))
        self.t_member[cyl_t] = self.n_springs + np.array(cyl_k, dtype=np.int64)
        self.t_sign[cyl_t] = cyl_s
        self.null_space_error: UnobservableError | None = self._check_observable()

    def determined(self) -> StaticsLayout:
        """This layout, where its statics determine every unknown; else its UnobservableError raised."""
        if self.null_space_error is not None:
            raise self.null_space_error
        return self

    # ---- known loads --------------------------------------------------------------------------
    def _build_known_terms(self) -> None:
        """Attachments and bodies of gravity, constant loads, springs and measured cylinders."""
        mech, kin = self.mech, self.kin
        bi = kin.body_index
        att, body, force = [], [], []
        mass_att, mass_body, masses, inertias = [], [], [], []  # every moving body, for inertia loads
        for b in mech.moving_bodies:
            mass, cg, inertia = b.mass, b.cg, b.inertia
            if mech.implement is not None and b.name == mech.implement.body:
                mass, cg = mech.implement.mass, mech.implement.cg
            if cg is None:
                cg = kin.q_ref[3 * bi[b.name]:3 * bi[b.name] + 2]
            k = kin.attach(b.name, f"cg of {b.name}", cg)
            mass_att.append(k)
            mass_body.append(bi[b.name])
            masses.append(mass)
            inertias.append(inertia)
            if mass > 0.0 and not (self.implement_col is not None and mech.implement is not None
                                   and b.name == mech.implement.body):
                att.append(k)
                body.append(bi[b.name])
                force.append((0.0, -mass * mech.gravity))
        for ld in mech.loads:
            att.append(kin.attach(ld.body, f"load {ld.name}", ld.position))
            body.append(bi[ld.body])
            force.append(tuple(ld.force))
        self.const_force = np.array(force, dtype=float).reshape(-1, 2)
        # two-force members with known force: springs and force-measured cylinders
        members = [(s.a, s.b) for s in mech.springs] + [(c.base, c.rod_end) for c in mech.cylinders]
        self.n_springs = len(mech.springs)
        self.member_att = np.array([[kin.attach(a.body, a.point) for a, _ in members],
                                    [kin.attach(b.body, b.point) for _, b in members]], dtype=np.int64).reshape(2, -1)
        end_member, end_sign = [], []
        for m, (mount_a, mount_b) in enumerate(members):
            for end, sign in ((mount_b, 1.0), (mount_a, -1.0)):
                if bi[end.body] >= 0:
                    end_member.append(m)
                    end_sign.append(sign)
                    att.append(kin.attach(end.body, end.point))
                    body.append(bi[end.body])
        self.end_member, self.end_sign = np.array(end_member, dtype=np.int64), np.array(end_sign, dtype=float)
        # known-load terms in the order ``known`` stacks them: constant loads, member ends, then
        # (kinetostatics only) the inertia loads at each cg
        self.mass_att, self.mass_body = np.array(mass_att, dtype=np.int64), np.array(mass_body, dtype=np.int64)
        self.mass, self.inertia = np.array(masses, dtype=float), np.array(inertias, dtype=float)
        self.known_att, self.known_body = np.array(att, dtype=np.int64), np.array(body, dtype=np.int64)
        self.spring_stiffness = np.array([s.stiffness for s in mech.springs])
        self.spring_free_length = np.array([s.free_length for s in mech.springs])
        self.spring_preload = np.array([s.preload for s in mech.springs])
        self.unmeasured = self.n_springs + np.array([k for k, c in enumerate(mech.cylinders)
                                                      if c.name not in self.force_known], dtype=int)

    # ---- assembly and solution ----------------------------------------------------------------
    def member_axes(self, p: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Unit axes (N, M, 2) from end a to end b and lengths (N, M) of springs then cylinders."""
        d = p.take(self.member_att[1], axis=1) - p.take(self.member_att[0], axis=1)
        length = np.sqrt(np.sum(d * d, axis=-1))
        return d / length[..., None], length

    def spring_forces(self, p: np.ndarray) -> np.ndarray:
        """Spring forces (N, n_springs) N, + = pushing: k·(free length − length) + preload, at attachment
        positions p (N, K, 2)."""
        if not self.n_springs:
            return np.zeros((p.shape[0], 0))
        length = self.member_axes(p)[1][:, :self.n_springs]
        return self.spring_stiffness * (self.spring_free_length - length) + self.spring_preload

    @cached_property
    def program(self) -> StaticsProgram:
        """The layout as ``kernels.solve_statics`` takes it (see there)."""
        return StaticsProgram(
            lc=self.kin.lc, n_eq=self.n_eq, t_col=self.t_col, t_att=self.t_att, t_body=self.t_body, t_const=self.t_const,
            t_member=self.t_member, t_sign=self.t_sign, const_force=self.const_force, known_att=self.known_att,
            known_body=self.known_body, end_member=self.end_member, end_sign=self.end_sign, member_att=self.member_att,
            mass_att=self.mass_att, mass_body=self.mass_body, mass=self.mass, inertia=self.inertia)

    def matrix(self, p: np.ndarray, axes: np.ndarray) -> np.ndarray:
        """Equilibrium matrix A (N, n_eq, n_unknowns) at attachment positions p (N, K, 2)."""
        return np.array([kernels.equilibrium_matrix(pi, ai, self.kin.lc, self.n_eq, self.n_unknowns, self.t_col,
                                                    self.t_att, self.t_body, self.t_const, self.t_member, self.t_sign)
                         for pi, ai in zip(p, axes)])

    def solve(self, p: np.ndarray, cylinder_force: np.ndarray, accel: tuple[np.ndarray, np.ndarray] | None
              ) -> StaticsSolution:
        """Unknown reactions for N poses; ``cylinder_force`` (N, n_cyl) N is used where measured.
        ``accel``: accelerations (N, K, 2) m/s² of every attachment and angular accelerations (N, n_bodies)
        rad/s² of the bodies, for the inertia loads (kinetostatics, Naumenko et al. 2021)."""
        ns = self.n_springs
        member_force, lin, alpha, has_accel = self.kernel_loads(p, cylinder_force, accel)
        u, residual, cond, axes, length = kernels.solve_statics(np.ascontiguousarray(p, dtype=float), member_force,
                                                                lin, alpha, has_accel, self.n_unknowns, self.program)
        return StaticsSolution(unknowns=u, residual=residual, condition=cond,
                               cylinder_axis=axes[:, ns:], cylinder_length=length[:, ns:],
                               spring_force=member_force[:, :ns], spring_axis=axes[:, :ns])

    def kernel_loads(self, p: np.ndarray, cylinder_force: np.ndarray, accel: tuple[np.ndarray, np.ndarray] | None
                     ) -> tuple[np.ndarray, np.ndarray, np.ndarray, bool]:
        """``solve``'s arguments as the kernels take them: member forces (N, M) N (springs from their
        length, measured cylinders as given, the unknown ones 0), the cgs' accelerations (N, n_mass,
        2) m/s², the angular ones (N, n_mass) rad/s², and whether there are any."""
        member_force = np.ascontiguousarray(np.concatenate([self.spring_forces(p), cylinder_force], axis=1),
                                            dtype=float)
        member_force[:, self.unmeasured] = 0.0   # their force is an unknown (NaN on input)
        if accel is None:
            return member_force, _NO_ACCEL_LINEAR, _NO_ACCEL_ANGULAR, False
        return (member_force, np.ascontiguousarray(accel[0][:, self.mass_att]),
                np.ascontiguousarray(accel[1][:, self.mass_body]), True)

    def _check_observable(self) -> UnobservableError | None:
        """Structural rank check; the error names the undetermined unknowns.

        The reference positions are jittered (fixed seed, 10 % of the length scale) so that a
        reference pose which happens to be a dead centre is not mistaken for a structural defect.
        """
        p, _ = self.kin.positions(self.kin.q_ref[None])
        p = p + 0.1 * self.kin.lc * np.random.default_rng(0).standard_normal(p.shape)
        axes, _ = self.member_axes(p)
        a = self.matrix(p, axes)[0]
        if self.n_unknowns > self.n_eq:
            _, s, vt = np.linalg.svd(a)
            null = vt[self.n_eq:]
        else:
            _, s, vt = np.linalg.svd(a)
            null = vt[s < 1e-10 * s[0]]
        if null.shape[0] == 0:
            return None
        weight = np.sqrt(np.sum(null**2, axis=0))
        names = [self.columns[i] for i in np.flatnonzero(weight > 1e-6)]
        known = ", ".join(sorted(self.force_known)) or "none"
        return UnobservableError(
            f"{self.mech.file}: the statics leave {null.shape[0]} load(s) undetermined ({self.n_unknowns} unknowns, "
            f"{self.n_eq} equations, rank {self.n_unknowns - null.shape[0]}); unknowns in the null space: "
            f"{', '.join(names)}. Measure a cylinder force (pressures; measured now: {known}) or remove a member.")


def layouts_by_measured_forces(mech: Mechanism, kin: Kinematics, layout: type[StaticsLayout] = StaticsLayout
                               ) -> dict[frozenset[str], StaticsLayout]:
    """One ``layout`` per set of force-measured cylinders — every subset of the cylinders with a
    pressure sensor, keyed by their names — all built at once (so the attachments they add are fixed)."""
    gauged = sorted({ps.cylinder for ps in mech.measurements.pressures})
    subsets = [frozenset(c for k, c in enumerate(gauged) if bits >> k & 1) for bits in range(2 ** len(gauged))]
    return {known: layout(mech, kin, known) for known in subsets}

