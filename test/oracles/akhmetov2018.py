"""Akhmetov & Usmanov 2018 oracle: the TTZ-1080 parallelogram OKMN by virtual work.

The bar KM of a parallelogram does not rotate: it translates with K on the circle of radius
|OK| about O. Turning the front link OK by dtheta (counter-clockwise +) moves every point of KM
by dK = dtheta * e_y x (K - O) and changes the cylinder length by dL = u_AC . (e_y x (C - O)) dtheta.
Virtual work of the cylinder force F (N, + = pushing) and of a force P (N) acting on KM:
F * dL/dtheta + P . dK/dtheta = 0. Nothing here imports ``linkage_monitor``.

Frame: x forward, z up, metres; points are the preset's names O, N, A (frame), K, C (front
link), M, W (front half-frame).
"""

from __future__ import annotations

from typing import Mapping

import numpy as np
from scipy.optimize import brentq

G_PAPER = 9.81  # m/s^2: the paper converts 1976 kgf to 19384.56 N (and 898.7 kgf to 8816.25 N)


def _perp(v: np.ndarray) -> np.ndarray:
    """e_y x v in the x-z plane with counter-clockwise + angles: (-v_z, v_x)."""
    return np.array([-v[1], v[0]])


def _rotate(v: np.ndarray, angle: float) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    return np.array([c * v[0] - s * v[1], s * v[0] + c * v[1]])


def pose(points: Mapping[str, np.ndarray], theta: float) -> dict[str, np.ndarray]:
    """Positions (m) of O, A, C, K, M, N, W after turning OK by ``theta`` rad from the reference pose."""
    o = np.asarray(points["O"], dtype=float)
    c = o + _rotate(points["C"] - o, theta)
    k = o + _rotate(points["K"] - o, theta)
    shift = k - points["K"]
    return {"O": o, "A": np.asarray(points["A"], dtype=float), "N": np.asarray(points["N"], dtype=float),
            "C": c, "K": k, "M": points["M"] + shift, "W": points["W"] + shift}


def theta_for_length(points: Mapping[str, np.ndarray], length: float) -> float:
    """Rotation of OK (rad) at which the cylinder A-C is ``length`` m long (within -0.5..2.5 rad)."""
    return brentq(lambda t: float(np.hypot(*(pose(points, t)["C"] - points["A"]))) - length, -0.5, 2.5, xtol=1e-14)


def _rates(points: Mapping[str, np.ndarray], theta: float) -> tuple[float, np.ndarray]:
    """dL/dtheta (m/rad) of the cylinder and dK/dtheta (m/rad) of the bar KM."""
    p = pose(points, theta)
    u = (p["C"] - p["A"]) / np.hypot(*(p["C"] - p["A"]))
    return float(u @ _perp(p["C"] - p["O"])), _perp(p["K"] - p["O"])


def cylinder_force(points: Mapping[str, np.ndarray], theta: float, load: np.ndarray) -> float:
    """Cylinder force (N, + = pushing) that holds ``load`` [fx, fz] N acting on the bar KM."""
    dl, dk = _rates(points, theta)
    return -float(load @ dk) / dl


def vertical_load(points: Mapping[str, np.ndarray], theta: float, force: float, fx: float) -> float:
    """Upward force (N) on KM that the cylinder force ``force`` (N) holds, with ``fx`` N acting along x."""
    dl, dk = _rates(points, theta)
    return -(force * dl + fx * dk[0]) / dk[1]


def arm_about(points: Mapping[str, np.ndarray], centre: str, theta: float = 0.0) -> float:
    """Perpendicular distance (m) from point ``centre`` to the cylinder line A-C."""
    p = pose(points, theta)
    u = (p["C"] - p["A"]) / np.hypot(*(p["C"] - p["A"]))
    r = p["C"] - p[centre]
    return abs(float(r[0] * u[1] - r[1] * u[0]))
