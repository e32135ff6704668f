"""Bouncing at road speed: a road profile, the tractor body's heave and pitch, an IMU (no rclpy).

The road is a random profile h(x) = Σ a_k·sin(2π·n_k·x + φ_k) with the ISO 8608 shape
G(n) = G0·(n/n0)^−2 (n0 = 0.1 cycle/m) over 0.05-2 cycles/m, a_k = √(2·G(n_k)·Δn); G0 is scaled
so that the largest vertical acceleration at the implement over the run is ``peak_g``·g. At road
speed v the rear wheels see h(v·t), the front ones h(v·t + wheelbase). Each axle carries the body
on its tyres as a base-excited oscillator (natural frequency ``axle_hz``, damping ratio
``damping``; the axles decoupled, as for a body whose pitch inertia is m·a·b): the body's
height at the rear axle z_r and at the front z_f are the steady responses, sine by sine, exact.
A point at x (m) of the body moves z(x) = z_r + (z_f − z_r)·x/wheelbase; the pitch (nose up,
in the mechanism's x-z plane) is β = (z_f − z_r)/wheelbase. Longitudinal accelerations are
neglected (constant speed).

The IMU on the body at (x, z) reads, in its REP 103 body frame (x forward, y left, z up), the
specific force f = a − g: f_x = (a_z + g)·sin β, f_z = (a_z + g)·cos β (m/s², +g on z at rest) and
the angular velocity ω_y = −dβ/dt (rad/s; nose up is a negative rotation about y-left), with
Gaussian noise. Units SI.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from linkage_monitor.mechanics.constants import STANDARD_GRAVITY

REFERENCE_WAVENUMBER = 0.1    # cycles/m, ISO 8608's n0
WAVENUMBERS = np.linspace(0.05, 2.0, 60)   # cycles/m


@dataclass(frozen=True)
class Road:
    """speed (m/s), peak_g: the largest vertical acceleration at the implement (× g), the tyres'
    axle_hz (Hz) and damping ratio (-)."""

    speed: float = 5.0
    peak_g: float = 0.3
    axle_hz: float = 2.5
    damping: float = 0.25


# Alike in form only to monitoring.weighing_fit's and sim.work_cycle's records: fields of other data.
@dataclass(frozen=True)
class ImuNoise:
    """Standard deviations of the IMU's noise: accelerometer (m/s²), gyroscope (rad/s)."""

    acceleration: float = 0.05
    angular_velocity: float = 0.005


@dataclass(frozen=True)
class ImuReadings:
    """Per sample: linear_acceleration (N, 3) m/s² and angular_velocity (N, 3) rad/s in the REP 103
    body frame, as ``sensor_msgs/Imu`` carries them (orientation not given); ``noise`` the sigmas."""

    stamps_ns: np.ndarray
    linear_acceleration: np.ndarray
    angular_velocity: np.ndarray
    noise: ImuNoise

    def message(self, i: int, frame_id: str = "imu_link") -> Any:
        """Sample i as a ``sensor_msgs/Imu`` (orientation_covariance[0] = −1: no orientation given)."""
        from sensor_msgs.msg import Imu

        msg = Imu()
        msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(int(self.stamps_ns[i]), 1_000_000_000)
        msg.header.frame_id = frame_id
        msg.orientation_covariance[0] = -1.0
        msg.linear_acceleration.x, msg.linear_acceleration.y, msg.linear_acceleration.z = (
            float(v) for v in self.linear_acceleration[i])
        msg.angular_velocity.x, msg.angular_velocity.y, msg.angular_velocity.z = (
            float(v) for v in self.angular_velocity[i])
        msg.linear_acceleration_covariance[0::4] = [self.noise.acceleration ** 2] * 3
        msg.angular_velocity_covariance[0::4] = [self.noise.angular_velocity ** 2] * 3
        return msg


class BodyMotion:
    """The tractor body's motion over a road: heights and accelerations of its points over time."""

    def __init__(self, road: Road, wheelbase: float, implement_x: float, rng: np.random.Generator) -> None:
        self.road, self.wheelbase = road, wheelbase
        dn = float(WAVENUMBERS[1] - WAVENUMBERS[0])
        self._amplitude = np.sqrt(2.0 * (WAVENUMBERS / REFERENCE_WAVENUMBER) ** -2.0 * dn)   # G0 = 1, scaled below
        self._phase = rng.uniform(0.0, 2.0 * np.pi, WAVENUMBERS.size)
        omega = 2.0 * np.pi * road.axle_hz
        w = 2.0 * np.pi * road.speed * WAVENUMBERS                            # rad/s of each sine
        self._omega = w
        self._gain = (omega**2 + 2j * road.damping * omega * w) / (omega**2 - w**2 + 2j * road.damping * omega * w)
        self._implement_x = implement_x
        self._scale = 1.0

    def scale_to_peak(self, t: np.ndarray) -> None:
        """Scale the road so that the implement's largest vertical acceleration over ``t`` is peak_g·g."""
        self._scale = 1.0
        peak = float(np.max(np.abs(self.vertical_acceleration(t, self._implement_x)))) if t.size else 0.0
        self._scale = self.road.peak_g * STANDARD_GRAVITY / peak if peak > 0.0 else 0.0

    def _axles(self, t: np.ndarray, derivative: int) -> tuple[np.ndarray, np.ndarray]:
        """The body's height (derivative 0, m), speed (1) or acceleration (2) over the rear and front axles."""
        out = []
        for lead in (0.0, self.wheelbase):
            arg = (self._omega[None, :] * t[:, None] + 2.0 * np.pi * WAVENUMBERS[None, :] * lead
                   + self._phase[None, :] + np.angle(self._gain)[None, :])
            a = self._scale * self._amplitude * np.abs(self._gain) * self._omega ** derivative
            shifted = arg + derivative * np.pi / 2.0
            out.append(np.sin(shifted) @ a)
        return out[0], out[1]

    def vertical_acceleration(self, t: np.ndarray, x: float) -> np.ndarray:
        """Vertical acceleration (m/s², + up) of the body's point at x (m) over ``t`` (s)."""
        rear, front = self._axles(t, 2)
        return rear + (front - rear) * x / self.wheelbase

    def pitch(self, t: np.ndarray, derivative: int = 0) -> np.ndarray:
        """Pitch β (rad, nose up) or its derivatives over ``t``."""
        rear, front = self._axles(t, derivative)
        return (front - rear) / self.wheelbase

    def imu(self, t: np.ndarray, stamps_ns: np.ndarray, x: float, noise: ImuNoise,
            rng: np.random.Generator) -> ImuReadings:
        """The IMU at x (m) on the body: specific force and angular velocity in its REP 103 frame."""
        beta, rate = self.pitch(t), self.pitch(t, 1)
        up = self.vertical_acceleration(t, x) + STANDARD_GRAVITY
        accel = np.column_stack([up * np.sin(beta), np.zeros_like(t), up * np.cos(beta)])
        gyro = np.column_stack([np.zeros_like(t), -rate, np.zeros_like(t)])
        return ImuReadings(stamps_ns=stamps_ns,
                           linear_acceleration=accel + noise.acceleration * rng.standard_normal(accel.shape),
                           angular_velocity=gyro + noise.angular_velocity * rng.standard_normal(gyro.shape),
                           noise=noise)

