"""The IMU's input: the tractor body's acceleration as the monitor takes it, and the axle loads on
the road of the solved poses (no rclpy).

An ``ImuEvent`` (``sensor_msgs/Imu`` on ``MonitorConfig.topics.imu``) is accepted whole — its
frame the configured ``imu_frame`` (its axes the body's, REP 103: the monitor does no transform),
its values finite, its stamp near the clock and not older than the one before — or refused whole
with a finding; it solves nothing. Each solve takes the body's acceleration of the newest IMU
message (``mechanics.dynamics``: the specific force along z, the gyro's rate differentiated), if
that is not older than the staleness limit: the pose's static steerability is then that of the unit
at rest (the implement's inertia taken out of the measured load) and its dynamic one is computed;
without it, the static one is as without an IMU and the dynamic one NaN. Units SI (m/s², rad/s,
rad/s², N); frame x forward, z up, origin at the rear wheels' ground contact.
"""

from __future__ import annotations

import math
from typing import Sequence

import numpy as np

from linkage_monitor.mechanics import Mechanism
from linkage_monitor.mechanics.constants import STANDARD_GRAVITY
from linkage_monitor.mechanics.dynamics import (DYNAMIC_KEYS, BodyAcceleration, ImplementAtRest, PitchAcceleration,
                                                RestLoad, RoadBalance, imu_body_acceleration, implement_at_rest,
                                                road_balance)

from .config import MonitorConfig
from .events import ImuEvent
from .findings import Code, Finding, fmt
from .inputs import NS, Refused

NO_DYNAMIC = np.full(len(DYNAMIC_KEYS), math.nan)   # the dynamic values of a pose without an IMU reading
# The plausible readings of an IMU on a tractor body driving on its wheels: the specific force along z
# within g ± 0.8 g (the road's bumps are a few tenths of g; 0 is a reading with gravity removed, which
# sensor_msgs/Imu's linear_acceleration includes, REP 145), the pitch rate within ±2 rad/s (a body on
# its wheels pitches a few tenths of rad/s; a gyro in deg/s reads 57x more). A reading outside is
# refused: it would take the implement's weight at rest (P·g/(g + a)) anywhere.
SPECIFIC_FORCE_Z_RANGE = (0.2 * STANDARD_GRAVITY, 1.8 * STANDARD_GRAVITY)   # m/s²
PITCH_RATE_MAX = 2.0   # rad/s


class RoadInput:
    """The newest body acceleration from the IMU of ``config`` on ``mechanism``'s tractor; ``load_measured``:
    the implement load comes from pressures (it carries the implement's inertia)."""

    def __init__(self, mechanism: Mechanism, config: MonitorConfig, load_measured: bool) -> None:
        self.mechanism, self.config, self.load_measured = mechanism, config, load_measured
        self._pitch, self._rest = PitchAcceleration(), RestLoad()
        self._body: BodyAcceleration | None = None
        self._stamp_ns = 0

    def carry_over(self, previous: RoadInput) -> None:
        """Keep ``previous``'s readings (a reconfiguration with the same IMU)."""
        self._pitch, self._rest = previous._pitch, previous._rest
        self._body, self._stamp_ns = previous._body, previous._stamp_ns

    def accept(self, event: ImuEvent) -> None:
        """Take an IMU message (its stamp checked against the clock by ``InputTracker.check_stamp``), or
        raise Refused naming what is wrong with it."""
        cfg = self.config
        what = f"Imu on topic '{event.topic}'"
        if event.frame_id != cfg.imu_frame:
            raise Refused(Finding(Code.UNKNOWN_INPUT, f"{what} is in frame '{event.frame_id}', expected imu_frame "
                                  f"'{cfg.imu_frame}' (axes of the tractor body, REP 103): not used"))
        if not (math.isfinite(event.specific_force_z) and math.isfinite(event.rate_y)):
            raise Refused(Finding(Code.MALFORMED_INPUT, f"{what}: linear_acceleration.z {event.specific_force_z} m/s² "
                                  f"and angular_velocity.y {event.rate_y} rad/s must be finite"))
        low, high = SPECIFIC_FORCE_Z_RANGE
        if not low <= event.specific_force_z <= high:
            raise Refused(Finding(Code.OUT_OF_RANGE, f"{what}: linear_acceleration.z {fmt(event.specific_force_z)} m/s² "
                                  f"outside [{fmt(low)}, {fmt(high)}] m/s² (a body on its wheels feels g; gravity "
                                  "removed, or not in m/s²?): not used"))
        if abs(event.rate_y) > PITCH_RATE_MAX:
            raise Refused(Finding(Code.OUT_OF_RANGE, f"{what}: angular_velocity.y {fmt(event.rate_y)} rad/s beyond "
                                  f"±{fmt(PITCH_RATE_MAX)} rad/s (deg/s sent as rad/s?): not used"))
        if event.stamp_ns < self._stamp_ns:
            raise Refused(Finding(Code.OUT_OF_ORDER, f"{what}: stamped {fmt((self._stamp_ns - event.stamp_ns) / 1e6)} "
                                  "ms before the one in use: not applied"))
        pitch = self._pitch.add(event.stamp_ns, event.rate_y)
        self._body = imu_body_acceleration(event.specific_force_z, pitch, cfg.imu_x)
        self._stamp_ns = event.stamp_ns

    def body_at(self, stamp_ns: int) -> BodyAcceleration | None:
        """The body's acceleration for a solve at ``stamp_ns``: the newest, unless it is older than the
        staleness limit (or none yet)."""
        if self._body is None or abs(stamp_ns - self._stamp_ns) > self.config.staleness_limit_s * NS:
            return None
        return self._body

    def balance(self, stamps_ns: np.ndarray, frame_load_points: np.ndarray, frame_load_forces: np.ndarray,
                implement_load: np.ndarray, implement_x: np.ndarray,
                bodies: Sequence[BodyAcceleration | None]) -> RoadBalance:
        """``mechanics.dynamics.road_balance`` of N solved poses in input order (their stamps (N,) ns, the
        other arrays as it takes them), each with its body acceleration (None: no IMU reading in use;
        NaN then); a measured load's weight at rest smoothed from pose to pose (``RestLoad``; held while
        the implement falls faster than ``mechanics.dynamics.FALLING``·g)."""
        vertical = np.array([b.vertical if b is not None else math.nan for b in bodies], dtype=float)
        pitch = np.array([b.pitch if b is not None else math.nan for b in bodies], dtype=float)
        body = BodyAcceleration(vertical, pitch)
        mech = self.mechanism
        assert mech.tractor is not None   # RoadInput is built for a mechanism with a tractor block only
        load = np.asarray(implement_load, dtype=float)
        implement = implement_at_rest(load, np.asarray(body.at(implement_x)), mech.gravity, self.load_measured)
        if self.load_measured:
            rest = self._rest.series(stamps_ns, implement.rest)
            rest[~np.isfinite(vertical)] = math.nan   # no IMU reading: as without an IMU
            implement = ImplementAtRest(rest, load - rest)
        return road_balance(mech.tractor, mech.gravity, frame_load_points, frame_load_forces, load, implement_x, body,
                            implement)
