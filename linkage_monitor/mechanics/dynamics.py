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
weight at rest P·g/(g + a_6) (``implement_at_rest``), smoothed over ``REST_TIME_CONSTANT`` from
solve to solve (``RestLoad``: what the correction leaves of a bump, its pitch acceleration late and
noisy, is faster), replaces P: the difference ΔP is an upward force at the implement's cg on the
frame (by the linkage's equilibrium the same change of the frame loads' resultant), so that the
static axle loads, ratio, margin, ballast advice and largest implement mass are those of the
unit at rest and do not follow the bumps. A load not measured (no pressures: the implement's
configured weight) is the weight at rest already.

**Dynamic balance** (d'Alembert: each body's mass times its acceleration applied, reversed, at its
cg, and its pitch inertia times α; then the moment balance about B of the static case): the
front-axle load R_A* = R_A + (F_6·x_6 + Σ m_k·a(x_k)·x_k + J·α) / L over the implement (F_6, its
d'Alembert force: what the measured load carries beyond the weight at rest, P − P_rest; m_6·a_6
with m_6 = P/g for a configured load), the tractor (m_tr at x_tr, J = m_tr·x_tr·(L − x_tr):
its mass lumped at the two axles, dynamic index 1, as the simulator's decoupled axles) and the
front ballast (at x_cw); the total R_A* + R_B* = W + F_6 + Σ m_k·a(x_k). The dynamic ratio is R_A*
over the reference weight at rest (the unit's or the empty tractor's, as ``ratio``): it dips when
the front axle unloads, whatever bounces. The bodies' own rotary inertia about their cgs (but the
tractor's), the links' masses and horizontal accelerations are neglected. Units SI; frame x
forward, z up, origin B.
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
FULL_SPAN = 0.8   # share of PITCH_WINDOW the gyro's samples must span before a pitch acceleration is given
FALLING = 0.5   # × g: an implement accelerating down faster than this is not weighed at rest (implement_at_rest)
REST_TIME_CONSTANT = 0.1   # s: the implement's weight at rest smoothed over 0.1 s (bench/bench_dynamics.py)
DYNAMIC_KEYS = ("dynamic_front_axle_load", "dynamic_rear_axle_load", "dynamic_ratio", "dynamic_margin")
DYNAMIC_FRONT, DYNAMIC_MARGIN = DYNAMIC_KEYS.index("dynamic_front_axle_load"), DYNAMIC_KEYS.index("dynamic_margin")
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
    the least-squares slope of −ω_y over the samples of the last ``window`` s (causal; NaN until the
    samples span ``FULL_SPAN`` of it: a slope over a few samples is mostly the gyro's noise)."""

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
        if len(samples) < 2 or stamp_ns - samples[0][0] < FULL_SPAN * self.window_ns:
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


class ImplementAtRest(NamedTuple):
    """The implement's load split (arrays (N,), N, + down as the load): its weight at rest and its
    d'Alembert force m_6·a_6; NaN where the body's acceleration is."""

    rest: np.ndarray
    inertia: np.ndarray


def implement_at_rest(implement_load: np.ndarray, implement_acceleration: np.ndarray, gravity: float,
                      load_measured: bool) -> ImplementAtRest:
    """The implement's weight at rest and inertia from its load (N,) N and its cg's vertical
    acceleration (N,) m/s²: a measured load P = m_6·(g + a_6) carries both (rest P·g/(g + a_6)); a
    configured one is the weight (inertia P·a_6/g). NaN where the implement falls faster than
    ``FALLING``·g: the load then says too little of the weight."""
    load, a6 = np.asarray(implement_load, dtype=float), np.asarray(implement_acceleration, dtype=float)
    a6 = np.where(a6 > -FALLING * gravity, a6, math.nan)
    rest = load * gravity / (gravity + a6) if load_measured else load + 0.0 * a6
    return ImplementAtRest(rest, load * a6 / (gravity + a6) if load_measured else load * a6 / gravity)


class RestLoad:
    """The implement's weight at rest smoothed from solve to solve: an exponential average over
    ``time_constant`` s of the header stamps (the first value taken as it is; a NaN, an implement
    falling faster than ``FALLING``·g, leaves it as it was and is answered with it).
    What the IMU's correction leaves of a bump (its pitch acceleration comes late and noisy) is
    faster than that; a load that truly changes (the ground taking the implement) is followed
    ``time_constant`` late."""

    def __init__(self, time_constant: float = REST_TIME_CONSTANT) -> None:
        self.time_constant = time_constant
        self._last: tuple[int, float] | None = None

    def add(self, stamp_ns: int, rest: float) -> float:
        """The smoothed weight at rest (N) after a solve at ``stamp_ns`` with weight at rest ``rest`` (N)."""
        last = self._last
        if not math.isfinite(rest):
            return last[1] if last is not None else math.nan
        if last is not None and stamp_ns > last[0]:
            rest = last[1] + (1.0 - math.exp(-(stamp_ns - last[0]) * 1e-9 / self.time_constant)) * (rest - last[1])
        self._last = (stamp_ns, rest)
        return rest

    def series(self, stamps_ns: np.ndarray, rest: np.ndarray) -> np.ndarray:
        """``add`` of each solve in turn (arrays (N,)): (N,) N."""
        return np.array([self.add(int(s), float(r)) for s, r in zip(stamps_ns.tolist(), rest.tolist())])


class RoadBalance(NamedTuple):
    """Steerability rows at rest (N, len(STEERABILITY_COLUMNS), as ``kernels.steerability_rows``) and the
    dynamic values (N, len(DYNAMIC_KEYS)): N, N, -, -."""

    static: np.ndarray
    dynamic: np.ndarray


def road_balance(tractor: Tractor, gravity: float, frame_load_points: np.ndarray, frame_load_forces: np.ndarray,
                 implement_load: np.ndarray, implement_x: np.ndarray, body: BodyAcceleration,
                 implement: ImplementAtRest) -> RoadBalance:
    """The static balance at rest and the dynamic one of N poses (module docstring): the linkage's
    forces on the frame (points / forces (N, K, 2), m / N), the implement load (N,) N at its cg's x
    (N,) m, the body's accelerations (arrays (N,)) and the implement's weight at rest and inertia
    (``implement_at_rest``, smoothed or not). Where they are NaN (no IMU reading) the static rows
    are those without an IMU and the dynamic values NaN."""
    params = machine_parameters(tractor, gravity)
    load, x6 = np.asarray(implement_load, dtype=float), np.asarray(implement_x, dtype=float)
    rest = np.where(np.isfinite(implement.rest), implement.rest, load)
    points = np.concatenate([frame_load_points, np.stack([x6, np.zeros_like(x6)], axis=1)[:, None, :]], axis=1)
    lift = np.stack([np.zeros_like(x6), load - rest], axis=1)[:, None, :]   # ΔP taken off where P acts
    static = kernels.steerability_rows(np.ascontiguousarray(points, dtype=float),
                                       np.ascontiguousarray(np.concatenate([frame_load_forces, lift], axis=1),
                                                            dtype=float),
                                       np.ascontiguousarray(rest), np.ascontiguousarray(x6), params)
    L, x_tr, m_tr = tractor.wheelbase, float(tractor.cg[0]), tractor.mass
    ballast = tractor.front_ballast
    m_cw, x_cw = (ballast.mass, ballast.x) if ballast is not None else (0.0, L)
    pitch = np.asarray(body.pitch, dtype=float)
    tractor_parts = ((m_tr, x_tr), (m_cw, x_cw))
    moment = (implement.inertia * x6 + sum(m * body.at(x) * x for m, x in tractor_parts)
              + m_tr * x_tr * (L - x_tr) * pitch)   # J·α, J = m·a·b
    heave = implement.inertia + sum(m * body.at(x) for m, x in tractor_parts)
    front = static[:, _STEER["front_axle_load"]] + moment / L
    total = static[:, _STEER["total_weight"]] + heave
    reference = static[:, _STEER["total_weight"]] if tractor.steerability_reference == "unit" else m_tr * gravity
    ratio = front / reference
    dynamic = np.stack([front, total - front, ratio, ratio - tractor.ratio_min], axis=1)
    return RoadBalance(static, dynamic)
