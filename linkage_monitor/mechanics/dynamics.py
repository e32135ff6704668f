"""Axle loads on the road: the static balance at rest and a dynamic one with the bodies' inertia (no rclpy).

The tractor body heaves and pitches on its tyres; an IMU on it (``sensor_msgs/Imu``, its axes the
body's, REP 103: x forward, y left, z up) reads the specific force f and the angular velocity ω.
With small pitch angles a point of the body at x (m from the rear wheels' ground contact B) moves
up with a(x) = a_B + α·x (m/s²): a_B the vertical acceleration at B, α the pitch's angular
acceleration (rad/s², nose up +). From an IMU mounted at x_i: a_i = f_z − g (cos β ≈ 1: below
0.05 rad of pitch the error is under 0.13 % of g), α = −dω_y/dt (nose up turns −y), and
a_B = a_i − α·x_i.

**Pitch acceleration: the gyro's rate differentiated, centred** (one IMU gives it; two
accelerometers a known distance apart would give it without differencing a noisy rate, but need a
second sensor): the least-squares slope of ω_y over the samples of the last ``PITCH_WINDOW``
seconds is the derivative at the window's centre, to its curvature error, with noise
σ_ω·√(12/(n·(n²−1)))·rate for n samples. The road's pitch acceleration is broadband (on the
simulator's road up to 16 Hz, where a tyre follows the profile): assigned to the newest sample a
slope is 37.5 ms late and its error is as large as the signal, so ``ImuBody`` gives the body's
acceleration **at the window's centre**, paired with the specific force there (the quadratic
least-squares fit of f_z over the same window, at its centre: Savitzky & Golay 1964): known 37.5 ms
late, and the monitor gives the dynamic values (and, with a measured load, the static rows) of the
solve at that stamp (``monitoring.road``; bench/bench_dynamics.py). The slope is shrunk by Wiener's gain S/(S + N), N
its variance from the window's own residuals, S its mean square over the last 0.3 s less N: a
quiet body's gyro noise is not taken for a pitch.

**Static balance at rest** (Popov 2009, ``kernels.steerability_pose``, as without an IMU): the
pressures measure the implement's load P = m_6·(g + a_6), its weight and its inertia together; the
weight at rest P·g/(g + a_6) (``implement_at_rest``; P and a_6 of one instant) replaces P: the
difference ΔP is an upward force at the implement's cg on the frame (by the linkage's equilibrium
the same change of the frame loads' resultant), so that the static axle loads, ratio, margin,
ballast advice and largest implement mass are those of the unit at rest and do not follow the
bumps. The weight at rest is averaged (``RestLoad``) over ``REST_TIME_CONSTANT`` while the
implement is carried (its weight does not change, and what the correction leaves of the body's
motion, the pitch acceleration's error at the implement's lever and the sensors' noise, averages
out) and followed at once near the working position, where the ground takes or gives up the
implement (``monitoring.road`` tells the two by the lift cylinder's length). A
load not measured (no pressures: the implement's configured weight) is the weight at rest already.

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
from .model import Tractor

PITCH_WINDOW = 0.075   # s: the gyro's rate differentiated over 75 ms, centred (bench/bench_dynamics.py)
FULL_SPAN = 0.8   # share of PITCH_WINDOW the gyro's samples must span before a pitch acceleration is given
REBASE_S = 0.5   # s: the running sums' time origin moved on after this (the fit's 4th moments' rounding stays ~1e-10)
SUMS = 11   # ImuBody's running sums: Σ1, Σt, Σw, Σt², Σt·w, Σw², Σt³, Σt⁴, Σa, Σt·a, Σt²·a (a = f_z − g)
BOUNCE_WINDOW = 0.3   # s: the pitch acceleration's mean square over 0.3 s is its signal's (Wiener's S, ImuBody)
FALLING = 0.5   # × g: an implement accelerating down faster than this is not weighed at rest (implement_at_rest)
REST_TIME_CONSTANT = 1.0   # s: the weight at rest averaged over 1 s while the implement is carried (RestLoad)
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


class BodyAt(NamedTuple):
    """The body's acceleration at the IMU sample of header stamp ``stamp_ns`` (ns)."""

    stamp_ns: int
    acceleration: BodyAcceleration


class _Sample(NamedTuple):
    """One IMU sample: header stamp (ns), −ω_y (rad/s, nose up +), f_z (m/s²)."""

    stamp_ns: int
    nose_up_rate: float
    specific_force_z: float


class ImuBody:
    """The body's acceleration from an IMU at x = ``mount_x`` (m) on it, sample by sample (REP 103 body
    axes): the pitch acceleration is the least-squares slope of −ω_y over the samples of the last
    ``window`` s, which is the derivative at the window's centre; it is paired there with the sample
    of that time (its stamp) and the quadratic least-squares fit of f_z over the window at that time
    (Savitzky & Golay 1964: the accelerometer's white noise σ leaves 0.27·σ for 31 samples), so that
    the body's acceleration is given ``window``/2 late
    and without the lag a slope assigned to its newest sample has (module docstring). The slope is
    shrunk by Wiener's gain S/(S + N): N its variance from its own residuals (σ_ω²/Σ(t − t̄)²), S its
    mean square over ``BOUNCE_WINDOW`` less N, so that a still body's gyro noise is not taken for a
    pitch. Running sums: O(1) per sample. None until the samples span ``FULL_SPAN`` of the window."""

    def __init__(self, mount_x: float, window: float = PITCH_WINDOW, gravity: float = STANDARD_GRAVITY) -> None:
        self.mount_x, self.gravity = mount_x, gravity
        self.window_ns = int(round(window * 1e9))
        self._samples: deque[_Sample] = deque()
        self._slopes: deque[tuple[int, float]] = deque()   # (stamp ns, slope²) over BOUNCE_WINDOW
        self._slope_sum = 0.0
        self._origin = 0
        self._sums = [0.0] * SUMS

    def _count(self, sample: _Sample, sign: float) -> None:
        t, w, a = (sample.stamp_ns - self._origin) * 1e-9, sample.nose_up_rate, sample.specific_force_z - self.gravity
        tt = t * t
        sums = self._sums
        sums[0] += sign
        sums[1] += sign * t
        sums[2] += sign * w
        sums[3] += sign * tt
        sums[4] += sign * t * w
        sums[5] += sign * w * w
        sums[6] += sign * tt * t
        sums[7] += sign * tt * tt
        sums[8] += sign * a
        sums[9] += sign * t * a
        sums[10] += sign * tt * a

    def add(self, stamp_ns: int, specific_force_z: float, rate_y: float) -> BodyAt | None:
        """One IMU sample (header stamp ns, f_z m/s², ω_y rad/s): the body's acceleration at the
        window's centre sample, or None (a stamp going back starts again)."""
        samples = self._samples
        if samples and stamp_ns <= samples[-1].stamp_ns:
            samples.clear()
            self._slopes.clear()
            self._slope_sum = 0.0
        samples.append(_Sample(stamp_ns, -rate_y, specific_force_z))
        if len(samples) == 1 or (stamp_ns - self._origin) * 1e-9 > REBASE_S:   # the sums again from a new origin
            self._origin, self._sums = samples[0].stamp_ns, [0.0] * SUMS
            for sample in samples:
                self._count(sample, 1.0)
        else:
            self._count(samples[-1], 1.0)
        while samples[0].stamp_ns < stamp_ns - self.window_ns:
            self._count(samples.popleft(), -1.0)
        if len(samples) < 3 or stamp_ns - samples[0].stamp_ns < FULL_SPAN * self.window_ns:
            return None
        n, st, sw, stt, stw, sww = self._sums[:6]
        spread = stt - st * st / n   # Σ(t − t̄)², s²
        slope = (stw - st * sw / n) / spread
        noise = max(sww - sw * sw / n - slope * slope * spread, 0.0) / (n - 2) / spread   # the slope's variance
        self._slopes.append((stamp_ns, slope * slope))
        self._slope_sum += slope * slope
        while self._slopes[0][0] < stamp_ns - BOUNCE_WINDOW * 1e9:
            self._slope_sum -= self._slopes.popleft()[1]
        signal = max(self._slope_sum / len(self._slopes) - noise, 0.0)
        pitch = slope * signal / (signal + noise) if signal > 0.0 else 0.0
        centre = samples[len(samples) // 2]
        vertical = self._fit_at((centre.stamp_ns - self._origin) * 1e-9)
        return BodyAt(centre.stamp_ns, imu_body_acceleration(vertical + self.gravity, pitch, self.mount_x,
                                                             self.gravity))

    def _fit_at(self, tc: float) -> float:
        """The quadratic least-squares fit of f_z − g (m/s²) over the window's samples at ``tc`` (s from the
        origin): the moments about tc from the running sums, the normal equations by Cramer's rule."""
        s0, s1, _, s2, _, _, s3, s4, a0, a1, a2 = self._sums
        d, d2 = tc, tc * tc
        m1 = s1 - d * s0
        m2 = s2 - 2.0 * d * s1 + d2 * s0
        m3 = s3 - 3.0 * d * s2 + 3.0 * d2 * s1 - d2 * d * s0
        m4 = s4 - 4.0 * d * s3 + 6.0 * d2 * s2 - 4.0 * d2 * d * s1 + d2 * d2 * s0
        g0, g1, g2 = a0, a1 - d * a0, a2 - 2.0 * d * a1 + d2 * a0
        minor = m2 * m4 - m3 * m3
        det = s0 * minor - m1 * (m1 * m4 - m2 * m3) + m2 * (m1 * m3 - m2 * m2)
        return (g0 * minor - m1 * (g1 * m4 - g2 * m3) + m2 * (g1 * m3 - g2 * m2)) / det


def imu_body_acceleration(specific_force_z: float | np.ndarray, pitch_acceleration: float | np.ndarray,
                          mount_x: float, gravity: float = STANDARD_GRAVITY) -> BodyAcceleration:
    """The body's acceleration from an IMU at x = ``mount_x`` (m): its specific force along the body's
    z (m/s², +g at rest) and the pitch acceleration (rad/s², ``ImuBody``)."""
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
    """The implement's weight at rest averaged from IMU sample to IMU sample: an exponential average
    over ``time_constant`` s of the samples' stamps while the implement is carried (its driver beyond
    the ground-contact zone, ``monitoring.road``), followed at once while it is not. A carried
    implement's weight at rest does not change, so what the correction leaves of the body's motion
    (the pitch acceleration's error at the implement's lever, the gyro's and the accelerometer's noise)
    averages out; near the working position the ground takes or gives up the implement within a few
    tenths of a second, and the weight at rest follows it. The first value is taken as it is; a NaN
    (an implement falling faster than ``FALLING``·g) leaves it as it was and is answered with it."""

    def __init__(self, time_constant: float = REST_TIME_CONSTANT) -> None:
        self.time_constant = time_constant
        self._last: tuple[int, float] | None = None

    def add(self, stamp_ns: int, rest: float, carried: bool) -> float:
        """The averaged weight at rest (N) after a sample at ``stamp_ns`` whose weight at rest is ``rest``
        (N), the implement ``carried`` (off the ground) or not."""
        last = self._last
        if not math.isfinite(rest):
            return last[1] if last is not None else math.nan
        if carried and last is not None and stamp_ns > last[0] and self.time_constant > 0.0:
            rest = last[1] + (1.0 - math.exp(-(stamp_ns - last[0]) * 1e-9 / self.time_constant)) * (rest - last[1])
        self._last = (stamp_ns, rest)
        return rest


class RoadBalance(NamedTuple):
    """Steerability rows at rest (N, len(STEERABILITY_COLUMNS), as ``kernels.steerability_rows``) and the
    dynamic values (N, len(DYNAMIC_KEYS)): N, N, -, -."""

    static: np.ndarray
    dynamic: np.ndarray


def static_at_rest(params: np.ndarray, frame_load_points: np.ndarray, frame_load_forces: np.ndarray,
                   implement_load: np.ndarray, implement_x: np.ndarray, rest: np.ndarray) -> np.ndarray:
    """The steerability rows of N poses at rest (N, len(STEERABILITY_COLUMNS)): the machine's parameters
    (``machine.machine_parameters``), the linkage's forces on the frame (points / forces (N, K, 2),
    m / N), the implement load (N,) N at its cg's x (N,) m and its weight at rest (N,) N, whose
    difference ΔP is taken off where the load acts (module docstring). Where ``rest`` is NaN (no
    IMU reading) the rows are those without an IMU."""
    load, x6 = np.asarray(implement_load, dtype=float), np.asarray(implement_x, dtype=float)
    rest = np.where(np.isfinite(rest), rest, load)
    n, k = frame_load_points.shape[:2]
    points, forces = np.zeros((n, k + 1, 2)), np.zeros((n, k + 1, 2))
    points[:, :k], forces[:, :k] = frame_load_points, frame_load_forces
    points[:, k, 0], forces[:, k, 1] = x6, load - rest   # ΔP taken off where P acts
    return kernels.steerability_rows(points, forces, rest, np.ascontiguousarray(x6), params)
def carried_axle_loads(tractor: Tractor, static: np.ndarray, implement_load: np.ndarray, rest: np.ndarray,
                       implement_x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The front axle load and the total (N,) N with the implement's load as the linkage carries it,
    from the rows at rest ``static`` (``static_at_rest``): ΔP = load − rest put back at its x."""
    lift = np.asarray(implement_load, dtype=float) - np.where(np.isfinite(rest), rest, implement_load)
    return (static[:, _STEER["front_axle_load"]] + lift * np.asarray(implement_x) / tractor.wheelbase,
            static[:, _STEER["total_weight"]] + lift)


def dynamic_balance(tractor: Tractor, gravity: float, front: np.ndarray, total: np.ndarray, reference: np.ndarray,
                    implement_inertia: np.ndarray, implement_x: np.ndarray, body: BodyAcceleration) -> np.ndarray:
    """The dynamic values (N, len(DYNAMIC_KEYS)) of N poses (module docstring): their front axle load and
    total (N,) N with the implement's load as the linkage carries it (``carried_axle_loads``), the
    weight the ratio is taken over (N,) N, the implement's d'Alembert force not in that load (N,) N
    (m_6·a_6 for a configured load, 0 for a measured one) at its cg's x (N,) m, and the body's
    acceleration (arrays (N,)); NaN where it is."""
    L, x_tr, m_tr = tractor.wheelbase, float(tractor.cg[0]), tractor.mass
    ballast = tractor.front_ballast
    m_cw, x_cw = (ballast.mass, ballast.x) if ballast is not None else (0.0, L)
    vertical, pitch = np.asarray(body.vertical, dtype=float), np.asarray(body.pitch, dtype=float)
    # Σ m_k·a(x_k)·x_k + J·α and Σ m_k·a(x_k) over the tractor and the ballast, a(x) = a_B + α·x, J = m·a·b
    mass, first = m_tr + m_cw, m_tr * x_tr + m_cw * x_cw
    second = m_tr * x_tr * x_tr + m_cw * x_cw * x_cw + m_tr * x_tr * (L - x_tr)
    front = front + (implement_inertia * implement_x + first * vertical + second * pitch) / L
    heave = implement_inertia + mass * vertical + first * pitch
    ratio = front / reference
    return np.stack([front, total + heave - front, ratio, ratio - tractor.ratio_min], axis=1)


def ratio_reference(tractor: Tractor, gravity: float, static: np.ndarray) -> np.ndarray:
    """The weight (N,) N the dynamic ratio is taken over: the unit's at rest or the empty tractor's (as ``ratio``)."""
    total = static[:, _STEER["total_weight"]]
    return total if tractor.steerability_reference == "unit" else np.full_like(total, tractor.mass * gravity)
