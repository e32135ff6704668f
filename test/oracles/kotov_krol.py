"""Kotov & Krol oracle: the KSU-1 header linkage by kinematics and virtual work.

Closed-form position analysis (lever 5 turns about O; the adapter closes the four-bar
O-F-I-H with the locked tilt cylinder; lever 2 turns about B when the lift cylinder's length
changes) and virtual work with the shoe force N*(n - f*t) (Kotov & Krol: T70 = f*N70):

- N70:  spring*dL_spring + (-G7)*dz_G + N*(dz_R - f*dx_R) = 0 along the one DOF (lever 5 turns);
- HI:   F_HI*ds + (-G7)*dz_G + N*(dz_R - f*dx_R) = 0 when only the tilt cylinder's length s
        changes (lever 5 held);
- AC:   F_AC*da + spring*dL_spring = 0 when only the lift cylinder's length a changes: lever 2
        (Kotov & Krol, eq. 4) sees the spring block and the lift cylinder only.

Derivatives by a 5-point central difference (error ~1e-11 relative). Nothing here imports
``linkage_monitor``. Frame x forward, z up, m, N; points by the preset's letters.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, Mapping

import numpy as np

Points = Mapping[str, np.ndarray]


@dataclass(frozen=True)
class Header:
    """Loads of the adapter: weight (N, down at G), spring block (N/m, m, N), shoe friction f."""

    weight: float
    stiffness: float
    free_length: float
    preload: float
    friction: float


def _rotate(v: np.ndarray, angle: float) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    return np.array([c * v[0] - s * v[1], s * v[0] + c * v[1]])


def _angle(v: np.ndarray) -> float:
    return float(np.arctan2(v[1], v[0]))


def _circles(c1: np.ndarray, r1: float, c2: np.ndarray, r2: float, near: np.ndarray) -> np.ndarray:
    """Intersection of circle (c1, r1) and circle (c2, r2) nearest to ``near``."""
    d = c2 - c1
    dist = float(np.hypot(*d))
    a = (r1**2 - r2**2 + dist**2) / (2 * dist)
    h = np.sqrt(r1**2 - a**2)
    mid = c1 + a * d / dist
    n = np.array([-d[1], d[0]]) / dist
    return min((mid + h * n, mid - h * n), key=lambda q: float(np.hypot(*(q - near))))


def _length(p: Points, a: str, b: str) -> float:
    return float(np.hypot(*(p[a] - p[b])))


def pose(ref: Points, psi: float, tilt: float | None = None, lift: float | None = None) -> dict[str, np.ndarray]:
    """Points (m) with lever 5 turned by ``psi`` rad, tilt cylinder HI ``tilt`` m, lift cylinder AC ``lift`` m.

    ``None`` keeps a cylinder at its reference-pose length.
    """
    p = {k: np.asarray(v, dtype=float) for k, v in ref.items()}
    if lift is not None:
        c = _circles(p["B"], _length(ref, "B", "C"), p["A"], lift, p["C"])
        turn = _angle(c - p["B"]) - _angle(ref["C"] - ref["B"])
        p["C"], p["D"] = c, p["B"] + _rotate(ref["D"] - ref["B"], turn)
    p["E"] = p["O"] + _rotate(ref["E"] - ref["O"], psi)
    p["F"] = p["O"] + _rotate(ref["F"] - ref["O"], psi)
    s = _length(ref, "H", "I") if tilt is None else tilt
    p["I"] = _circles(p["F"], _length(ref, "F", "I"), p["H"], s, ref["I"])
    turn = _angle(p["I"] - p["F"]) - _angle(ref["I"] - ref["F"])
    for name in ("G", "R"):
        p[name] = p["F"] + _rotate(ref[name] - ref["F"], turn)
    return p


def _d(fun: Callable[[float], float], x: float, h: float = 1e-4) -> float:
    """5-point central difference."""
    return (-fun(x + 2 * h) + 8 * fun(x + h) - 8 * fun(x - h) + fun(x - 2 * h)) / (12 * h)


def spring_force(ref: Points, header: Header, psi: float) -> float:
    """Spring-block force (N, + = pushing) at lever-5 angle ``psi`` (lift cylinder locked)."""
    return header.stiffness * (header.free_length - _length(pose(ref, psi), "D", "E")) + header.preload


def forces(ref: Points, header: Header, psi: float) -> dict[str, float]:
    """Shoe normal N70, tilt-cylinder force HI and lift-cylinder force AC (N, + = pushing) at ``psi``."""
    f, w = header.friction, header.weight
    spring = spring_force(ref, header, psi)

    def shoe_rate(moving: Callable[[float], dict[str, np.ndarray]], x: float) -> float:
        return _d(lambda t: moving(t)["R"][1], x) - f * _d(lambda t: moving(t)["R"][0], x)

    dof = lambda t: pose(ref, t)  # noqa: E731
    n70 = -(spring * _d(lambda t: _length(dof(t), "D", "E"), psi) - w * _d(lambda t: dof(t)["G"][1], psi)) \
        / shoe_rate(dof, psi)
    s0 = _length(pose(ref, psi), "H", "I")
    tilt = lambda s: pose(ref, psi, tilt=s)  # noqa: E731
    f_hi = w * _d(lambda s: tilt(s)["G"][1], s0) - n70 * shoe_rate(tilt, s0)
    a0 = _length(ref, "A", "C")
    f_ac = -spring * _d(lambda a: _length(pose(ref, psi, lift=a), "D", "E"), a0)
    return {"shoe": n70, "tilt_cylinder": f_hi, "lift_cylinder": f_ac}
