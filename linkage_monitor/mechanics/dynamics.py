"""Axle loads on the road: the static balance at rest and a dynamic one with the bodies' inertia (no rclpy).

The tractor body heaves and pitches on its tyres; an IMU on it (``sensor_msgs/Imu``, its axes the
body's, REP 103: x forward, y left, z up) reads the specific force f and the angular velocity ω.
With small pitch angles a point of the body at x (m from the rear wheels' ground contact B) moves
up with a(x) = a_B + α·x (m/s²): a_B the vertical acceleration at B, α the pitch's angular
acceleration (rad/s², nose up +). From an IMU mounted at x_i: a_i = f_z − g (cos β ≈ 1: below
0.05 rad of pitch the error is under 0.13 % of g), α = −dω_y/dt (nose up turns −y), and
a_B = a_i − α·x_i.

**Pitch acceleration: the gyro's rate differentiated** (one IMU gives it; two accelerometers a
known distance apart would give it without differencing a noisy rate, but need a second sensor):
a causal least-squares slope of ω_y over the samples of the last ``PITCH_WINDOW`` seconds, whose
noise is σ_ω·√(12/(n·(n²−1)))·rate for n samples and whose delay is half the window
(``PitchAcceleration``).

**Static balance at rest** (Popov 2009, ``kernels.steerability_pose``, as without an IMU): the
pressures measure the implement's load P = m_6·(g + a_6), its weight and its inertia together; the
inertia ΔP = P·a_6/(g + a_6) is taken out (an upward force ΔP at the implement's cg on the
frame, by the linkage's equilibrium the same change of the frame loads' resultant), so that the
static axle loads, ratio, margin, ballast advice and largest implement mass are those of the
unit at rest and do not follow the bumps.

**Dynamic balance** (d'Alembert: each body's mass times its acceleration applied, reversed, at its
cg, and its pitch inertia times α; then the moment balance about B of the static case): the
front-axle load R_A* = R_A + (Σ m_k·a(x_k)·x_k + J·α) / L over the implement (m_6 = (P − ΔP)/g at
its cg x_6), the tractor (m_tr at x_tr, J = m_tr·x_tr·(L − x_tr): its mass lumped at the two
axles, dynamic index 1, as the simulator's decoupled axles) and the front ballast (at x_cw);
the total R_A* + R_B* = W + Σ m_k·a(x_k). The dynamic ratio is R_A* over the reference weight at
rest (the unit's or the empty tractor's, as ``ratio``): it dips when the front axle unloads,
whatever bounces. The bodies' own rotary inertia about their cgs (but the tractor's), the links'
masses and horizontal accelerations are neglected. Units SI; frame x forward, z up, origin B.
"""

from __future__ import annotations

import math
from collections import deque
from typing import NamedTuple

import numpy as np

from . import kernels
from .constants import STANDARD_GRAVITY
from .machine import machine_parameters
from .model import Tractor

PITCH_WINDOW = 0.05   # s: the gyro's rate differentiated over the samples of the last 50 ms (bench/bench_dynamics.py)
DYNAMIC_KEYS = ("dynamic_front_axle_load", "dynamic_rear_axle_load", "dynamic_ratio", "dynamic_margin")
_STEER = {k: j for j, k in enumerate(kernels.STEERABILITY_COLUMNS)}


class BodyAcceleration(NamedTuple):
    """The tractor body's vertical acceleration at B (m/s², + up, gravity excluded) and its pitch's
    angular acceleration (rad/s², nose up +); arrays or floats."""

    vertical: float | np.ndarray
    pitch: float | np.ndarray

    def at(self, x: float | np.ndarray) -> float | np.ndarray:
        """Vertical acceleration (m/s², + up) of the body's point at x (m)."""
        return self.vertical + self.pitch * x


class PitchAcceleration:
    """The pitch's angular acceleration (rad/s², nose up +) from the gyro's ω_y (rad/s, REP 103):
    the least-squares slope of −ω_y over the samples of the last ``window`` s (causal; NaN until two
    samples span it)."""

    def __init__(self, window: float = PITCH_WINDOW) -> None:
        self.window_ns = int(round(window * 1e9))
        self._samples: deque[tuple[int, float]] = deque()

    def add(self, stamp_ns: int, rate_y: float) -> float:
        """One gyro sample (stamp ns, ω_y rad/s); the pitch acceleration at it (rad/s²)."""
        samples = self._samples
        if samples and stamp_ns <= samples[-1][0]:   # a stamp going back: start again
            samples.clear()
        samples.append((stamp_ns, -rate_y))
        while samples[0][0] < stamp_ns - self.window_ns:
            samples.popleft()
        if len(samples) < 2:
            return math.nan
        t = np.array([s[0] for s in samples], dtype=float) * 1e-9
        w = np.array([s[1] for s in samples])
        t -= t.mean()
        return float(np.dot(t, w - w.mean()) / np.dot(t, t))

    def series(self, stamps_ns: np.ndarray, rate_y: np.ndarray) -> np.ndarray:
        """``add`` of each sample in turn (arrays (N,)): (N,) rad/s²."""
        return np.array([self.add(int(s), float(r)) for s, r in zip(stamps_ns.tolist(), rate_y.tolist())])


def imu_body_acceleration(specific_force_z: float | np.ndarray, pitch_acceleration: float | np.ndarray,
                          mount_x: float, gravity: float = STANDARD_GRAVITY) -> BodyAcceleration:
    """The body's acceleration from an IMU at x = ``mount_x`` (m): its specific force along the body's
    z (m/s², +g at rest) and the pitch acceleration (rad/s², ``PitchAcceleration``)."""
    return BodyAcceleration(specific_force_z - gravity - pitch_acceleration * mount_x, pitch_acceleration)


class RoadBalance(NamedTuple):
    """Steerability rows at rest (N, len(STEERABILITY_COLUMNS), as ``kernels.steerability_rows``) and the
    dynamic values (N, len(DYNAMIC_KEYS)): N, N, -, -."""

    static: np.ndarray
    dynamic: np.ndarray


def road_balance(tractor: Tractor, gravity: float, frame_load_points: np.ndarray, frame_load_forces: np.ndarray,
                 implement_load: np.ndarray, implement_x: np.ndarray, body: BodyAcceleration) -> RoadBalance:
    """The static balance at rest and the dynamic one of N poses (module docstring): the linkage's
    forces on the frame (points / forces (N, K, 2), m / N), the measured implement load (N,) N at its
    cg's x (N,) m, the body's accelerations (arrays (N,)). Where an acceleration is NaN (no IMU
    reading) the static rows are those without an IMU and the dynamic values NaN."""
    params = machine_parameters(tractor, gravity)
    load, x6 = np.asarray(implement_load, dtype=float), np.asarray(implement_x, dtype=float)
    a6 = np.asarray(body.at(x6), dtype=float)
    inertia = load * a6 / (gravity + a6)                      # ΔP, N: the inertia the measured load carries
    inertia[~np.isfinite(inertia)] = 0.0
    points = np.concatenate([frame_load_points, np.stack([x6, np.zeros_like(x6)], axis=1)[:, None, :]], axis=1)
    lift = np.stack([np.zeros_like(x6), inertia], axis=1)[:, None, :]
    static = kernels.steerability_rows(np.ascontiguousarray(points, dtype=float),
                                       np.ascontiguousarray(np.concatenate([frame_load_forces, lift], axis=1),
                                                            dtype=float),
                                       np.ascontiguousarray(load - inertia), np.ascontiguousarray(x6), params)
    L, x_tr, m_tr = tractor.wheelbase, float(tractor.cg[0]), tractor.mass
    ballast = tractor.front_ballast
    m_cw, x_cw = (ballast.mass, ballast.x) if ballast is not None else (0.0, L)
    m6 = (load - inertia) / gravity
    pitch = np.asarray(body.pitch, dtype=float)
    masses = ((m6, x6), (m_tr, x_tr), (m_cw, x_cw))
    moment = sum(m * body.at(x) * x for m, x in masses) + m_tr * x_tr * (L - x_tr) * pitch   # J·α, J = m·a·b
    heave = sum(m * body.at(x) for m, x in masses)
    front = static[:, _STEER["front_axle_load"]] + moment / L
    total = static[:, _STEER["total_weight"]] + heave
    reference = static[:, _STEER["total_weight"]] if tractor.steerability_reference == "unit" else m_tr * gravity
    ratio = front / reference
    dynamic = np.stack([front, total - front, ratio, ratio - tractor.ratio_min], axis=1)
    return RoadBalance(static, dynamic)
