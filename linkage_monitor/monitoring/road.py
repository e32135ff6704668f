"""The IMU's input: the tractor body's acceleration as the monitor takes it, and the axle loads on
the road of the solved poses (no rclpy).

An ``ImuEvent`` (``sensor_msgs/Imu`` on ``MonitorConfig.topics.imu``) is accepted whole — its
frame the configured ``imu_frame`` (its axes the body's, REP 103: the monitor does no transform),
its values finite, its stamp near the clock and not older than the one before — or refused whole
with a finding; it solves nothing. Each solve takes the body's acceleration of the newest IMU
message (``mechanics.dynamics.ImuBody``: the specific force along z and the gyro's rate
differentiated, both at the centre of the pitch window, 37.5 ms before the newest message), if that
message is not older than the staleness limit: the pose then carries the dynamic values of the solve
at the body's stamp and, with a measured load, that solve's static steerability at rest (the
implement's inertia taken out of its load): the values of one instant; without it, the static one
is as without an IMU and the dynamic one NaN. Units SI (m/s², rad/s, rad/s², N); frame x forward,
z up, origin at the rear wheels' ground contact.
"""

from __future__ import annotations

import math
from bisect import bisect_left, bisect_right
from typing import Mapping, NamedTuple, Sequence

import numpy as np

from linkage_monitor.mechanics import Mechanism
from linkage_monitor.mechanics.constants import STANDARD_GRAVITY
from linkage_monitor.mechanics.machine import machine_parameters
from linkage_monitor.mechanics.dynamics import (DYNAMIC_KEYS, PITCH_WINDOW, BodyAcceleration, BodyAt, ImuBody,
                                                RestLoad, RoadBalance, carried_axle_loads, dynamic_balance,
                                                implement_at_rest, ratio_reference, static_at_rest)

from .config import MonitorConfig
from .events import ImuEvent
from .findings import Code, Finding, fmt
from .inputs import NS, Refused
from .weighing import WeighingSettings
from .weighing_model import WeighingModel

NO_DYNAMIC = np.full(len(DYNAMIC_KEYS), math.nan)   # the dynamic values of a pose without an IMU reading
# The plausible readings of an IMU on a tractor body driving on its wheels: the specific force along z
# within g ± 0.8 g (the road's bumps are a few tenths of g; 0 is a reading with gravity removed, which
# sensor_msgs/Imu's linear_acceleration includes, REP 145), the pitch rate within ±2 rad/s (a body on
# its wheels pitches a few tenths of rad/s; a gyro in deg/s reads 57x more). A reading outside is
# refused: it would take the implement's weight at rest (P·g/(g + a)) anywhere.
SPECIFIC_FORCE_Z_RANGE = (0.2 * STANDARD_GRAVITY, 1.8 * STANDARD_GRAVITY)   # m/s²
PITCH_RATE_MAX = 2.0   # rad/s
PRUNE_AT = 1024   # solves forgotten before the history's lists are cut


class _History:
    """The recent solves, by header stamp (ns, non-decreasing): the implement load (N) at its cg's x (m),
    whether it is carried (off the ground-contact zone) and the forces the linkage puts on the frame
    (points / forces (K, 2), m / N), so that a solve's rows at rest can be taken once its body's
    acceleration is known (``RoadInput.balance``)."""

    def __init__(self) -> None:
        self.stamps: list[int] = []
        self.load: list[float] = []
        self.x: list[float] = []
        self.carried: list[bool] = []
        self.points: list[np.ndarray] = []
        self.forces: list[np.ndarray] = []
        self.start = 0

    def extend(self, stamps: np.ndarray, load: np.ndarray, x: np.ndarray, carried: np.ndarray, points: np.ndarray,
               forces: np.ndarray) -> None:
        if self.stamps and stamps.size and int(stamps[0]) < self.stamps[-1]:   # a stamp going back: start again
            self.__init__()   # type: ignore[misc]
        self.stamps += stamps.tolist()
        self.load += load.tolist()
        self.x += x.tolist()
        self.carried += carried.tolist()
        self.points += list(np.array(points, dtype=float))   # copies: the solver's arrays are not kept
        self.forces += list(np.array(forces, dtype=float))

    def nearest(self, stamp_ns: int, tolerance_ns: float) -> int:
        """The index of the solve nearest ``stamp_ns`` (of equal stamps the last), −1 if none is within the tolerance."""
        at = bisect_right(self.stamps, stamp_ns, lo=self.start)
        candidates = [k for k in (at - 1, at) if self.start <= k < len(self.stamps)]
        if not candidates:
            return -1
        best = min(candidates, key=lambda k: (abs(self.stamps[k] - stamp_ns), -k))
        return best if abs(self.stamps[best] - stamp_ns) <= tolerance_ns else -1

    def prune(self, keep_ns: float) -> None:
        """Forget the solves more than ``keep_ns`` before the newest."""
        if not self.stamps:
            return
        self.start = bisect_left(self.stamps, self.stamps[-1] - keep_ns, lo=self.start)
        if self.start > PRUNE_AT:
            for name in ("stamps", "load", "x", "carried", "points", "forces"):
                setattr(self, name, getattr(self, name)[self.start:])
            self.start = 0


class GroundZone(NamedTuple):
    """Where the ground may carry the implement: the lift cylinder's length (m) short of ``edge``
    (``WeighingModel.contact_edge``, the weighing's ``ground_contact`` share of the stroke from the
    working length)."""

    model: WeighingModel
    edge: float

    def carried(self, lengths: Mapping[str, np.ndarray], count: int) -> np.ndarray:
        """(count,) bool: the solves whose lift cylinder (of ``lengths``, m by name) is beyond the zone."""
        if self.model.cylinder not in lengths:
            return np.zeros(count, dtype=bool)
        return np.array([not self.model.grounded(length, self.edge) for length in lengths[self.model.cylinder].tolist()],
                        dtype=bool)


def ground_zone(mechanism: Mechanism) -> GroundZone | None:
    """``mechanism``'s ground-contact zone, None where its lift cylinder's length is not measured with a
    pressure (or it has no implement): the implement then never counts as carried."""
    try:
        model = WeighingModel(mechanism)
    except ValueError:
        return None
    return GroundZone(model, model.contact_edge(WeighingSettings().ground_contact))


class RoadInput:
    """The body's acceleration from the IMU of ``config`` on ``mechanism``'s tractor; ``load_measured``:
    the implement load comes from pressures (it carries the implement's inertia)."""

    def __init__(self, mechanism: Mechanism, config: MonitorConfig, load_measured: bool) -> None:
        self.mechanism, self.config, self.load_measured = mechanism, config, load_measured
        # the ground-contact zone, found when first needed (a stroke's sweep: tenths of a second) and kept
        # over a reconfiguration of the same linkage (another implement or its estimate in use)
        self._zone: GroundZone | None = None
        self._zone_found = not load_measured
        self._linkage = (mechanism.file, repr(mechanism.points), repr(mechanism.reference_inputs))
        self._imu, self._rest = ImuBody(config.imu_x, gravity=mechanism.gravity), RestLoad()
        assert mechanism.tractor is not None   # RoadInput is built for a mechanism with a tractor block only
        self._params = machine_parameters(mechanism.tractor, mechanism.gravity)
        self._history = _History()
        self._rest_at: tuple[int, float] = (-1, math.nan)   # the weight at rest of the newest body's stamp
        self._body: BodyAt | None = None
        self._stamp_ns = 0

    def carry_over(self, previous: RoadInput) -> None:
        """Keep ``previous``'s readings (a reconfiguration with the same IMU); the body's acceleration from
        the next message on with this configuration's mounting (``imu_x``)."""
        self._imu, self._rest, self._history = previous._imu, previous._rest, previous._history
        if self.load_measured and previous._linkage == self._linkage:
            self._zone, self._zone_found = previous._zone, previous._zone_found
        self._imu.mount_x, self._imu.gravity = self.config.imu_x, self.mechanism.gravity
        self._rest_at, self._stamp_ns = previous._rest_at, previous._stamp_ns
        self._body = previous._body if previous.config.imu_x == self.config.imu_x else None

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
        body = self._imu.add(event.stamp_ns, event.specific_force_z, event.rate_y)
        if body is not None:
            self._body = body
        self._stamp_ns = event.stamp_ns

    def ground(self) -> GroundZone | None:
        """The ground-contact zone of a measured load (``ground_zone``, found once), None without one."""
        if not self._zone_found:
            self._zone, self._zone_found = ground_zone(self.mechanism), True
        return self._zone

    def body_at(self, stamp_ns: int) -> BodyAt | None:
        """The body's acceleration for a solve at ``stamp_ns``: the newest (half the pitch window before the
        newest IMU message), unless that message is older than the staleness limit (or none yet)."""
        if self._body is None or abs(stamp_ns - self._stamp_ns) > self.config.staleness_limit_s * NS:
            return None
        return self._body

    def balance(self, stamps_ns: np.ndarray, frame_load_points: np.ndarray, frame_load_forces: np.ndarray,
                implement_load: np.ndarray, implement_x: np.ndarray, cylinder_lengths: Mapping[str, np.ndarray],
                bodies: Sequence[BodyAt | None]) -> RoadBalance:
        """The static rows at rest and the dynamic values of N solved poses in input order (their stamps (N,)
        ns, cylinder lengths (N,) m by name, the other arrays as ``mechanics.dynamics.static_at_rest``
        takes them), each with its body
        acceleration (None: no IMU reading in use; the rows then as without an IMU, the dynamic values
        NaN). The body's acceleration is known half the pitch window late, so a pose's values are
        **those of the solve at its body's stamp** (``PITCH_WINDOW``/2 = 37.5 ms before the newest IMU
        message): the dynamic ones, and, with a measured load, the static rows, the solve's load with its
        own inertia taken out (its weight at rest averaged while the implement is carried, off the
        ground-contact zone: ``RestLoad``, ``GroundZone``), so that no
        load is paired with a weight at rest of another instant (the ground taking or giving up the
        implement changes the load within a few tenths of a second). Without a solve within the
        staleness limit of the body's stamp (or where that solve failed) the dynamic values are NaN and
        the static rows the pose's own with the last weight at rest."""
        mech = self.mechanism
        assert mech.tractor is not None   # RoadInput is built for a mechanism with a tractor block only
        g, history, tolerance = mech.gravity, self._history, self.config.staleness_limit_s * NS
        load, x6 = np.asarray(implement_load, dtype=float), np.asarray(implement_x, dtype=float)
        zone = self.ground()
        carried = zone.carried(cylinder_lengths, load.size) if zone is not None else np.zeros(load.size, dtype=bool)
        history.extend(np.asarray(stamps_ns, dtype=np.int64), load, x6, carried, frame_load_points, frame_load_forces)
        found = [history.nearest(b.stamp_ns, tolerance) if b is not None else -1 for b in bodies]
        rest = np.full(load.size, math.nan)   # a measured load's weight at rest, of the solve the row is taken of
        for k, (body, j) in enumerate(zip(bodies, found)):
            if body is None or not self.load_measured:
                continue
            if body.stamp_ns != self._rest_at[0] and j >= 0:
                at_rest = implement_at_rest(np.array([history.load[j]]),
                                            np.array([body.acceleration.at(history.x[j])]), g, True).rest[0]
                self._rest_at = (body.stamp_ns, self._rest.add(body.stamp_ns, float(at_rest), history.carried[j]))
            rest[k] = self._rest_at[1]   # the last average while no solve is at the body's stamp
        static = static_at_rest(self._params, frame_load_points, frame_load_forces, load, x6, rest)
        dynamic = np.full((load.size, len(DYNAMIC_KEYS)), math.nan)
        used = [(k, j, b.acceleration) for k, (j, b) in enumerate(zip(found, bodies)) if j >= 0 and b is not None]
        if used:
            at = np.array([k for k, _, _ in used])
            load_j = np.array([history.load[j] for _, j, _ in used])
            x_j = np.array([history.x[j] for _, j, _ in used])
            rest_j = rest[at] if self.load_measured else load_j   # a configured load is the weight at rest
            rows = static_at_rest(self._params, np.stack([history.points[j] for _, j, _ in used]),
                                  np.stack([history.forces[j] for _, j, _ in used]), load_j, x_j, rest_j)
            if self.load_measured:   # but where either solve failed: no rows of a failed pose, none from one
                solved = np.isfinite(static[at, 0]) & np.isfinite(rows[:, 0])
                static[at[solved]] = rows[solved]
            acceleration = BodyAcceleration(np.array([a.vertical for _, _, a in used], dtype=float),
                                            np.array([a.pitch for _, _, a in used], dtype=float))
            inertia = (np.zeros(at.size) if self.load_measured
                       else implement_at_rest(load_j, np.asarray(acceleration.at(x_j)), g, False).inertia)
            dynamic[at] = dynamic_balance(mech.tractor, g, *carried_axle_loads(mech.tractor, rows, load_j, rest_j, x_j),
                                          ratio_reference(mech.tractor, g, rows), inertia, x_j, acceleration)
        history.prune(tolerance + PITCH_WINDOW * NS)
        return RoadBalance(static, dynamic)
