"""Test oracle (the numpy implementation, see __init__): batched (kineto)statics, 3 equations per
moving body, the unknown reactions solved per pose — its own equations over the package's index
structure (``statics.StaticsLayout``: columns, rows, known-load terms, the structural rank check).

Equations per moving body: ΣFx = 0, ΣFz = 0, ΣM about the origin B = 0 (moment rows divided by
the length scale ``lc`` so the matrix is dimensionless), assembled as whole arrays: each term's
generalized force [Fx, Fz, M/lc] scattered into its body's rows.
"""

from __future__ import annotations

from functools import cached_property

import numpy as np

from linkage_monitor.mechanics import statics
from linkage_monitor.mechanics.statics import StaticsSolution
from .linalg import inverse_and_condition


def generalized(points: np.ndarray, forces: np.ndarray, lc: float) -> np.ndarray:
    """[Fx, Fz, (x·Fz − z·Fx)/lc] (N, T, 3) of forces (N, T, 2) N acting at points (N, T, 2) m."""
    moment = points[..., 0] * forces[..., 1] - points[..., 1] * forces[..., 0]
    return np.concatenate([forces, (moment / lc)[..., None]], axis=-1)


class StaticsLayout(statics.StaticsLayout):
    """The package's layout for one set of force-measured cylinders, its equilibrium assembled and
    solved here as stacks of numpy arrays."""

    @cached_property
    def _cylinder_terms(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The column terms along a cylinder's axis: their indices, their cylinders' indices, their signs."""
        terms = np.flatnonzero(self.t_member >= 0)
        return terms, self.t_member[terms] - self.n_springs, self.t_sign[terms]

    @cached_property
    def _matrix_flat(self) -> np.ndarray:
        """Where term t's (Fx, Fz, M/lc) lands in the flattened matrix: rows 3·body + j, its column."""
        rows = 3 * self.t_body[:, None] + np.arange(3)
        return (rows * self.n_unknowns + self.t_col[:, None]).ravel()

    @cached_property
    def _scatter_static(self) -> np.ndarray:
        return self._scatter(self.known_body)

    @cached_property
    def _scatter_accel(self) -> np.ndarray:
        return self._scatter(np.concatenate([self.known_body, self.mass_body]))

    def _scatter(self, bodies: np.ndarray) -> np.ndarray:
        """0/1 matrix (3T, n_eq) adding generalized forces of T terms into their body's rows."""
        s = np.zeros((3 * len(bodies), self.n_eq))
        for t, b in enumerate(bodies):
            s[3 * t:3 * t + 3, 3 * b:3 * b + 3] = np.eye(3)
        return s

    # ---- assembly and solution ----------------------------------------------------------------
    def matrix(self, p: np.ndarray, axes: np.ndarray) -> np.ndarray:
        """Equilibrium matrix A (N, n_eq, n_unknowns) at attachment positions p (N, K, 2)."""
        n_pose = p.shape[0]
        d = np.repeat(self.t_const[None], n_pose, axis=0)
        ti, tk, ts = self._cylinder_terms
        d[:, ti] = ts[:, None] * axes.take(self.n_springs + tk, axis=1)
        g = generalized(p.take(self.t_att, axis=1), d, self.kin.lc)
        a = np.zeros((n_pose, self.n_eq, self.n_unknowns))
        a.reshape(n_pose, self.n_eq * self.n_unknowns)[:, self._matrix_flat] = g.reshape(n_pose, 3 * g.shape[1])
        return a

    def known(self, p: np.ndarray, axes: np.ndarray, member_force: np.ndarray,
              accel: tuple[np.ndarray, np.ndarray] | None) -> np.ndarray:
        """Generalized known loads b (N, n_eq): gravity, loads, springs, measured cylinders, inertia."""
        n_pose = p.shape[0]
        end_sign = self.end_sign[:, None]
        forces = [np.broadcast_to(self.const_force, (n_pose,) + self.const_force.shape),
                  end_sign * member_force.take(self.end_member, axis=1)[..., None] * axes.take(self.end_member, axis=1)]
        att, scatter = self.known_att, self._scatter_static
        moments: float | np.ndarray = 0.0
        if accel is not None:  # kinetostatics (Naumenko et al. 2021): −m·a_cg at the cg, −I·α about it
            a_att, alpha = accel
            forces.append(-self.mass[:, None] * a_att[:, self.mass_att])
            att, scatter = np.concatenate([self.known_att, self.mass_att]), self._scatter_accel
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


def solve_with_condition(a: np.ndarray, rhs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Solve stacked square systems a x = rhs; returns x (N, k) and the 1-norm condition number (N,)."""
    inv, cond = inverse_and_condition(a)
    return (inv @ rhs[..., None])[..., 0], cond
