"""Naumenko et al. 2021 oracle: coulter parallelogram over a sinusoidal relief.

Relief (Naumenko et al. 2021, eq. 13): y = (h/2)(1 - cos(2 pi x / l)), x = v t + x0 (here x0 = 0: the wheel
starts in a trough). The parallelogram turns by phi (Naumenko et al. 2021's sense: B rises and moves back):
x_r = AB sin(phi0 + phi) - AB sin(phi0), y_r = AB cos(phi0) - AB cos(phi0 + phi) (eq. 14-15), and
the post point follows the relief, which gives the implicit equation (16):

    AB cos(phi0) - AB cos(phi0 + phi) = (h/2) (1 - cos(2 pi/l (v t - AB sin(phi0 + phi) + AB sin(phi0))))

Its time derivatives (17)-(18) are derived here as y' = p'(X) X', y'' = p''(X) X'^2 + p'(X) X''
with X = v t - x_r, y = y_r (the printed (18) has sin(phi0 - phi) for sin(phi0 + phi)).
The kinetostatic oracle is d'Alembert + virtual work along phi. Nothing here imports
``linkage_monitor``. Frame: x forward, z up, m, s, rad (phi clockwise in this frame).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import brentq


@dataclass(frozen=True)
class Relief:
    """Sinusoidal field profile: height h (m, trough to crest = 2 * amplitude), wavelength l (m)."""

    h: float
    l: float

    def y(self, x: float) -> float:
        """Profile height (m) at field abscissa x (m), eq. (13)."""
        return self.h / 2 * (1 - np.cos(2 * np.pi * x / self.l))

    def dy(self, x: float) -> float:
        return self.h / 2 * (2 * np.pi / self.l) * np.sin(2 * np.pi * x / self.l)

    def ddy(self, x: float) -> float:
        return self.h / 2 * (2 * np.pi / self.l) ** 2 * np.cos(2 * np.pi * x / self.l)


@dataclass(frozen=True)
class Parallelogram:
    """Link length AB (m) and its reference angle phi0 from the downward vertical (rad), eq. (14)-(15)."""

    ab: float
    phi0: float

    def post_shift(self, phi: float) -> np.ndarray:
        """Translation (m) of the post from the reference pose: (-x_r, y_r), eq. (14)-(15)."""
        a = self.phi0 + phi
        return self.ab * np.array([np.sin(self.phi0) - np.sin(a), np.cos(self.phi0) - np.cos(a)])

    def post_shift_rate(self, phi: float) -> np.ndarray:
        """d(post shift)/d phi (m/rad)."""
        a = self.phi0 + phi
        return self.ab * np.array([-np.cos(a), np.sin(a)])

    def post_acceleration(self, phi: float, dphi: float, ddphi: float) -> np.ndarray:
        """Post acceleration (m/s^2): x3'' = AB sin(a) phi'^2 - AB cos(a) phi'', y3'' = AB cos(a) phi'^2 + AB sin(a) phi''."""
        a = self.phi0 + phi
        return self.ab * np.array([np.sin(a) * dphi**2 - np.cos(a) * ddphi, np.cos(a) * dphi**2 + np.sin(a) * ddphi])


def phi_at(s: float, link: Parallelogram, relief: Relief) -> float:
    """phi (rad) solving eq. (16) at travelled distance s = v t (m)."""

    def residual(phi: float) -> float:
        shift = link.post_shift(phi)
        return shift[1] - relief.y(s + shift[0])

    top = np.arccos(np.cos(link.phi0) - relief.h / link.ab) - link.phi0  # the post risen by h
    return brentq(residual, 0.0, top, xtol=1e-15)


def phi_rates(s: float, v: float, link: Parallelogram, relief: Relief) -> tuple[float, float, float]:
    """phi (rad), phi' (rad/s), phi'' (rad/s^2) at s = v t, eq. (16)-(18)."""
    phi = phi_at(s, link, relief)
    a = link.phi0 + phi
    x = s + link.post_shift(phi)[0]
    p1, p2 = relief.dy(x), relief.ddy(x)
    sa, ca = link.ab * np.sin(a), link.ab * np.cos(a)
    dphi = p1 * v / (sa + p1 * ca)                                   # eq. (17)
    dx = v - ca * dphi
    ddphi = (p2 * dx**2 + p1 * sa * dphi**2 - ca * dphi**2) / (sa + p1 * ca)   # eq. (18)
    return phi, dphi, ddphi


@dataclass(frozen=True)
class Rotor:
    """A link turning about a frame pivot by -phi: mass (kg), inertia about its cg (kg m^2), pivot and cg (m)."""

    mass: float
    inertia: float
    pivot: np.ndarray
    cg: np.ndarray


def _turn(v: np.ndarray, angle: float) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    return np.array([c * v[0] - s * v[1], s * v[0] + c * v[1]])


def rotor_cg(link: Rotor, phi: float) -> np.ndarray:
    """Position (m) of the link's cg after the parallelogram turned by phi (the link by -phi)."""
    return link.pivot + _turn(link.cg - link.pivot, -phi)


def rotor_acceleration(link: Rotor, phi: float, dphi: float, ddphi: float) -> np.ndarray:
    """Acceleration (m/s^2) of the link's cg: theta'' e_y x r - theta'^2 r, theta = -phi."""
    r = rotor_cg(link, phi) - link.pivot
    return -ddphi * np.array([-r[1], r[0]]) - dphi**2 * r


def normal_force(phi: float, dphi: float, ddphi: float, links: tuple[Rotor, ...], post_mass: float,
                 link: Parallelogram, friction: float, gravity: float) -> float:
    """Wheel normal force N (N) by virtual work along phi with d'Alembert forces (Naumenko et al. 2021, eq. 1-12).

    The ground force on the post is N*(0, 1) - f*N*(1, 0) (vertical normal, drag backwards).
    """
    work = 0.0
    for rotor in links:
        r = rotor_cg(rotor, phi) - rotor.pivot
        dr = -np.array([-r[1], r[0]])                                # d r_cg / d phi
        force = np.array([0.0, -rotor.mass * gravity]) - rotor.mass * rotor_acceleration(rotor, phi, dphi, ddphi)
        work += force @ dr - rotor.inertia * ddphi                   # -I theta'' * d theta/d phi, theta = -phi
    dpost = link.post_shift_rate(phi)
    work += (np.array([0.0, -post_mass * gravity]) - post_mass * link.post_acceleration(phi, dphi, ddphi)) @ dpost
    return -work / (dpost[1] - friction * dpost[0])
