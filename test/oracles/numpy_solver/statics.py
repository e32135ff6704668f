"""Test oracle (frozen numpy implementation, see __init__). Batched (kineto)statics: 3 equations per moving body, unknown reactions solved per pose.

Equations per moving body: ΣFx = 0, ΣFz = 0, ΣM about the origin B = 0 (moment rows divided by
the length scale ``lc`` so the matrix is dimensionless). Unknowns: hinge reactions (fx, fz: the
force on ``bodies[1]`` from ``bodies[0]``), axial forces of cylinders whose force is not measured
(+ = pushing), contact normal forces (friction T = f·N folded into the column, Kotov & Krol), and,
when measured cylinder forces leave an extra equation, the vertical load at the implement cg.
The index structure (:class:`StaticsLayout`) is built once per set of measured cylinder forces.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from linkage_monitor.mechanics.errors import UnobservableError
from .kinematics import Kinematics
from .linalg import inverse_and_condition
from linkage_monitor.mechanics.model import Mechanism

_UNIT = {"x": (1.0, 0.0), "z": (0.0, 1.0), "down": (0.0, -1.0)}


def generalized(points: np.ndarray, forces: np.ndarray, lc: float) -> np.ndarray:
    """[Fx, Fz, (x·Fz − z·Fx)/lc] (N, T, 3) of forces (N, T, 2) N acting at points (N, T, 2) m."""
    moment = points[..., 0] * forces[..., 1] - points[..., 1] * forces[..., 0]
    return np.concatenate([forces, (moment / lc)[..., None]], axis=-1)


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
        self.implement_col: int | None = None
        imp = mech.implement
        if imp is not None and force_known and len(self.columns) < self.n_eq:
            self.implement_col = len(self.columns)
            column(f"implement '{imp.body}' vertical load", [(imp.body, f"cg of {imp.body}", "down", imp.cg)])
        self.n_unknowns = len(self.columns)
        # column terms as arrays
        self.t_col = np.array([t[0] for t in terms], dtype=int)
        self.t_att = np.array([t[1] for t in terms], dtype=int)
        self.t_body = np.array([t[2] for t in terms], dtype=int)
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
        self.t_cyl = (np.array(cyl_t, dtype=int), np.array(cyl_k, dtype=int), np.array(cyl_s))
        # where term t's (Fx, Fz, M/lc) lands in the flattened matrix: rows 3·body + j, its column
        rows = 3 * self.t_body[:, None] + np.arange(3)
        self._matrix_flat = (rows * self.n_unknowns + self.t_col[:, None]).ravel()
        self._build_known_terms()
        self.null_space_error: UnobservableError | None = self._check_observable()

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
                                    [kin.attach(b.body, b.point) for _, b in members]], dtype=int).reshape(2, -1)
        end_member, end_sign = [], []
        for m, (mount_a, mount_b) in enumerate(members):
            for end, sign in ((mount_b, 1.0), (mount_a, -1.0)):
                if bi[end.body] >= 0:
                    end_member.append(m)
                    end_sign.append(sign)
                    att.append(kin.attach(end.body, end.point))
                    body.append(bi[end.body])
        self.end_member, self.end_sign = np.array(end_member, dtype=int), np.array(end_sign).reshape(-1, 1)
        # known-load terms in the order ``known`` stacks them: constant loads, member ends, then
        # (kinetostatics only) the inertia loads at each cg
        self.mass_att, self.mass_body = np.array(mass_att, dtype=int), np.array(mass_body, dtype=int)
        self.mass, self.inertia = np.array(masses, dtype=float), np.array(inertias, dtype=float)
        self.known_att = np.array(att, dtype=int)
        self.known_att_accel = np.concatenate([self.known_att, self.mass_att])
        self._scatter_static = self._scatter(np.array(body, dtype=int))
        self._scatter_accel = self._scatter(np.concatenate([np.array(body, dtype=int), self.mass_body]))
        self.spring_stiffness = np.array([s.stiffness for s in mech.springs])
        self.spring_free_length = np.array([s.free_length for s in mech.springs])
        self.spring_preload = np.array([s.preload for s in mech.springs])
        self.unmeasured = self.n_springs + np.array([k for k, c in enumerate(mech.cylinders)
                                                      if c.name not in self.force_known], dtype=int)

    def _scatter(self, bodies: np.ndarray) -> np.ndarray:
        """0/1 matrix (3T, n_eq) adding generalized forces of T terms into their body's rows."""
        s = np.zeros((3 * len(bodies), self.n_eq))
        for t, b in enumerate(bodies):
            s[3 * t:3 * t + 3, 3 * b:3 * b + 3] = np.eye(3)
        return s

    # ---- assembly and solution ----------------------------------------------------------------
    def member_axes(self, p: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Unit axes (N, M, 2) from end a to end b and lengths (N, M) of springs then cylinders."""
        d = p.take(self.member_att[1], axis=1) - p.take(self.member_att[0], axis=1)
        length = np.sqrt(np.sum(d * d, axis=-1))
        return d / length[..., None], length

    def matrix(self, p: np.ndarray, axes: np.ndarray) -> np.ndarray:
        """Equilibrium matrix A (N, n_eq, n_unknowns) at attachment positions p (N, K, 2)."""
        n_pose = p.shape[0]
        d = np.repeat(self.t_const[None], n_pose, axis=0)
        ti, tk, ts = self.t_cyl
        d[:, ti] = ts[:, None] * axes.take(self.n_springs + tk, axis=1)
        g = generalized(p.take(self.t_att, axis=1), d, self.kin.lc)
        a = np.zeros((n_pose, self.n_eq, self.n_unknowns))
        a.reshape(n_pose, self.n_eq * self.n_unknowns)[:, self._matrix_flat] = g.reshape(n_pose, 3 * g.shape[1])
        return a

    def known(self, p: np.ndarray, axes: np.ndarray, member_force: np.ndarray,
              accel: tuple[np.ndarray, np.ndarray] | None) -> np.ndarray:
        """Generalized known loads b (N, n_eq): gravity, loads, springs, measured cylinders, inertia."""
        n_pose = p.shape[0]
        forces = [np.broadcast_to(self.const_force, (n_pose,) + self.const_force.shape),
                  self.end_sign * member_force.take(self.end_member, axis=1)[..., None] * axes.take(self.end_member, axis=1)]
        att, scatter = self.known_att, self._scatter_static
        moments: float | np.ndarray = 0.0
        if accel is not None:  # kinetostatics (Naumenko et al. 2021): −m·a_cg at the cg, −I·α about it
            a_att, alpha = accel
            forces.append(-self.mass[:, None] * a_att[:, self.mass_att])
            att, scatter = self.known_att_accel, self._scatter_accel
            inertial = np.zeros((n_pose, self.n_eq))
            inertial[:, 3 * self.mass_body + 2] -= self.inertia * alpha[:, self.mass_body] / self.kin.lc
            moments = inertial
        g = generalized(p.take(att, axis=1), np.concatenate(forces, axis=1), self.kin.lc)
        return g.reshape(n_pose, scatter.shape[0]) @ scatter + moments

    def solve(self, p: np.ndarray, cylinder_force: np.ndarray, accel: tuple[np.ndarray, np.ndarray] | None
              ) -> StaticsSolution:
        """Unknown reactions for N poses; ``cylinder_force`` (N, n_cyl) N is used where measured."""
        axes, length = self.member_axes(p)
        ns = self.n_springs
        spring_force = self.spring_stiffness * (self.spring_free_length - length[:, :ns]) + self.spring_preload
        member_force = np.concatenate([spring_force, cylinder_force], axis=1)
        member_force[:, self.unmeasured] = 0.0   # their force is an unknown (NaN on input)
        a = self.matrix(p, axes)
        b = self.known(p, axes, member_force, accel)
        if self.n_unknowns == self.n_eq:
            u, cond = solve_with_condition(a, -b)
        else:
            at = np.swapaxes(a, 1, 2)
            u, cond = solve_with_condition(at @ a, -(at @ b[..., None])[..., 0])
            cond = np.sqrt(cond)
        res = (a @ u[..., None])[..., 0] + b
        res[:, 2::3] *= self.kin.lc
        return StaticsSolution(unknowns=u, residual=np.sqrt(np.sum(res * res, axis=1)), condition=cond,
                               cylinder_axis=axes[:, ns:], cylinder_length=length[:, ns:],
                               spring_force=spring_force, spring_axis=axes[:, :ns])

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


def solve_with_condition(a: np.ndarray, rhs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Solve stacked square systems a x = rhs; returns x (N, k) and the 1-norm condition number (N,)."""
    inv, cond = inverse_and_condition(a)
    return (inv @ rhs[..., None])[..., 0], cond
