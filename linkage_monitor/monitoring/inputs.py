"""Sensor inputs of the monitor: checks before physics, and the latest value of every input.

No rclpy: the drivers hand in the fields of `sensor_msgs/JointState` (positions: rad for
angle sensors, m for cylinder lengths; velocities rad/s, m/s) and `sensor_msgs/FluidPressure`
(Pa), with their header stamps and the monitor's receive time in ns. A message is either
accepted whole — every value finite, every name known once, inside the mechanism's
plausibility limits, the stamp positive, near the clock and not older than the reading in use of
any input it carries (per sensor the newest stamp wins: an older message arriving later, from a
second publisher or a reordered bag, is refused) — or refused whole with a Finding naming the
input and the reason; a refused message changes nothing. `inputs_at`
assembles the inputs of one solve when every input is there and none is stale.
"""

from __future__ import annotations

import math
from typing import Mapping, NamedTuple, Sequence

from linkage_monitor.mechanics import Inputs, Mechanism
from linkage_monitor.mechanics.limits import Limit, input_limits

from .config import MonitorConfig
from .findings import Code, Finding, fmt

NS = 1_000_000_000


class Refused(Exception):
    """An input message was refused; ``finding`` says why."""

    def __init__(self, finding: Finding) -> None:
        super().__init__(finding.text)
        self.finding = finding


class Reading(NamedTuple):
    """The latest accepted value of one input: value (m, rad or Pa gauge), rate (m/s, rad/s or
    NaN), its change since the previous reading (m/s², rad/s² or NaN: a finite difference over
    the header stamps), header stamp (ns)."""

    value: float
    rate: float
    acceleration: float
    stamp_ns: int

    def then(self, value: float, rate: float, stamp_ns: int) -> Reading:
        """The next reading of this input, its acceleration differenced from this one."""
        dt = (stamp_ns - self.stamp_ns) / NS
        accel = (rate - self.rate) / dt if dt > 0.0 and math.isfinite(rate) and math.isfinite(self.rate) else math.nan
        return Reading(value, rate, accel, stamp_ns)


class InputTracker:
    """The latest accepted reading of every input of one mechanism under one configuration."""

    def __init__(self, mech: Mechanism, config: MonitorConfig) -> None:
        self.config = config
        self.angle_names = frozenset(a.name for a in mech.measurements.angles)
        self.cylinder_names = frozenset(mech.measurements.cylinders)
        self.pressure_names = frozenset(config.pressure_topics.values())
        self.limits: Mapping[str, Limit] = input_limits(mech)
        known_pressures = {p.name for p in mech.measurements.pressures}
        unknown = sorted(self.pressure_names - known_pressures)
        if unknown:
            raise ValueError(f"pressure sensor(s) {', '.join(unknown)} are not in the mechanism's "
                             f"measurements.pressures ({', '.join(sorted(known_pressures)) or 'none'})")
        measured = self.angle_names | self.cylinder_names
        bad_targets = sorted(set(config.joint_map.values()) - measured)
        if bad_targets:
            raise ValueError(f"joint_map targets {', '.join(bad_targets)} are not measured angles or "
                             f"cylinders of the mechanism ({', '.join(sorted(measured))})")
        self._joint_to_input = {name: name for name in measured}
        self._joint_to_input.update(config.joint_map)
        self.readings: dict[str, Reading] = {}
        self.unknown_joints: tuple[str, ...] = ()   # names of the last accepted JointState that map to nothing
        # names of every input a solve needs (angles, cylinder lengths, mapped pressures), and in name order
        self.required = measured | self.pressure_names
        self._required_order = tuple(sorted(self.required))
        self._cylinder_order, self._angle_order, self._pressure_order, self._kinematic_order = (
            tuple(sorted(names)) for names in (self.cylinder_names, self.angle_names, self.pressure_names, measured))

    def carry_over(self, previous: InputTracker) -> None:
        """Keep the readings of ``previous`` (a configuration change does not forget the sensors)."""
        self.readings = {k: v for k, v in previous.readings.items() if k in self.required}

    # ---- acceptance ---------------------------------------------------------------------------
    def check_stamp(self, what: str, stamp_ns: int, now_ns: int) -> None:
        """Refuse a header stamp that is ≤ 0 or farther than stamp_tolerance_s from ``now_ns``."""
        tolerance = self.config.stamp_tolerance_s
        if stamp_ns <= 0:
            raise Refused(Finding(Code.BAD_STAMP, f"{what}: header stamp {stamp_ns} ns is not after 1970: "
                                  "the sensor's clock is not set"))
        offset = (stamp_ns - now_ns) / NS
        if abs(offset) > tolerance:
            side = "ahead of" if offset > 0 else "behind"
            cause = ("check the sensor's clock synchronisation" if offset > 0 else
                     "check the sensor's clock synchronisation, or the monitor is behind its inputs (more "
                     "messages per second than it solves: they wait in its queue)")
            raise Refused(Finding(Code.BAD_STAMP, f"{what}: header stamp is {fmt(abs(offset))} s {side} the "
                                  f"monitor's clock (stamp_tolerance {fmt(tolerance)} s): {cause}"))

    def accept_joint_state(self, names: Sequence[str], positions: Sequence[float], velocities: Sequence[float],
                           stamp_ns: int, now_ns: int) -> None:
        """Accept a JointState whole or raise Refused."""
        what = "JointState"
        if len(names) != len(positions):
            raise Refused(Finding(Code.MALFORMED_INPUT, f"{what} has {len(names)} names but {len(positions)} "
                                  "positions: the arrays must have the same length"))
        if velocities and len(velocities) != len(names):
            raise Refused(Finding(Code.MALFORMED_INPUT, f"{what} has {len(names)} names but {len(velocities)} "
                                  "velocities: give none or one per joint"))
        seen: set[str] = set()
        for name in names:
            if name in seen:
                raise Refused(Finding(Code.DUPLICATE_JOINT, f"{what} names joint '{name}' twice: which value "
                                      "is meant cannot be known"))
            seen.add(name)
        self.check_stamp(what, stamp_ns, now_ns)
        updates: dict[str, Reading] = {}
        unknown: list[str] = []
        for k, name in enumerate(names):
            target = self._joint_to_input.get(name)
            if target is None:
                unknown.append(name)
                continue
            value = float(positions[k])
            rate = float(velocities[k]) if velocities else math.nan
            if not math.isfinite(value):
                raise Refused(Finding(Code.MALFORMED_INPUT, f"{what} joint '{name}' position is {value} "
                                      f"{self._unit(target)}: a finite value is required (sensor fault?)"))
            if velocities and not math.isfinite(rate):
                raise Refused(Finding(Code.MALFORMED_INPUT, f"{what} joint '{name}' velocity is {rate} "
                                      f"{self._unit(target)}/s: a finite value is required"))
            self._check_limit(target, value, "joint", name)
            previous = self.readings.get(target)
            self._check_order(previous, stamp_ns, what, name)
            updates[target] = (previous.then(value, rate, stamp_ns) if previous is not None
                               else Reading(value, rate, math.nan, stamp_ns))
        if not updates:
            expected = ", ".join(sorted(self._joint_to_input))
            shown = ", ".join(map(repr, names[:5])) + (", ..." if len(names) > 5 else "")
            raise Refused(Finding(Code.UNKNOWN_INPUT, f"{what} joint name(s) {shown or '(none)'} are unknown: "
                                  f"expected {expected} (map others with the joint_map parameter)"))
        self.readings.update(updates)
        self.unknown_joints = tuple(unknown)

    def unknown_joints_finding(self, stamp_ns: int) -> Finding | None:
        """The joint names of the last accepted JointState that map to no measurement, named, or None.
        A JointState may carry joints the mechanism does not measure; they are named where a solve
        triggered at ``stamp_ns`` (ns) lacks a joint's reading, missing or stale (a misspelt name is
        then the likely cause), not where only a pressure is lacking."""
        if not self.unknown_joints:
            return None
        limit_ns = self.config.staleness_limit_s * NS
        fed_by_joints = set(self._joint_to_input.values()) & self.required
        if all(n in self.readings and abs(stamp_ns - self.readings[n].stamp_ns) <= limit_ns for n in fed_by_joints):
            return None
        shown = ", ".join(f"'{n}'" for n in self.unknown_joints[:5]) + (", ..." if len(self.unknown_joints) > 5 else "")
        return Finding(Code.UNKNOWN_INPUT, f"unknown joint {shown} in {self.config.topics.joint_states}; expected one "
                                           f"of {', '.join(sorted(self._joint_to_input))} (map others with the "
                                           "joint_map parameter)")

    def accept_pressure(self, topic: str, fluid_pressure: float, stamp_ns: int, now_ns: int) -> None:
        """Accept a FluidPressure (Pa, absolute or gauge per config) or raise Refused; stores gauge Pa."""
        sensor = self.config.pressure_topics.get(topic)
        if sensor is None:
            raise Refused(Finding(Code.UNKNOWN_INPUT, f"FluidPressure on topic '{topic}' maps to no pressure "
                                  f"sensor (pressure_topics: {', '.join(sorted(self.config.pressure_topics))})"))
        what = f"pressure '{sensor}' (topic '{topic}')"
        value = float(fluid_pressure)
        if not math.isfinite(value):
            raise Refused(Finding(Code.MALFORMED_INPUT, f"{what} is {value} Pa: a finite value is required"))
        self.check_stamp(what, stamp_ns, now_ns)
        cfg = self.config
        absolute = value if cfg.pressure_absolute else value + cfg.atmospheric_pressure
        if absolute < 0.0:
            kind = "absolute" if cfg.pressure_absolute else "gauge"
            raise Refused(Finding(Code.OUT_OF_RANGE, f"{what} is {fmt(value)} Pa {kind}: a negative absolute "
                                  f"pressure ({fmt(absolute)} Pa) is impossible; check the sensor and the "
                                  "pressure_absolute parameter"))
        self._check_limit(sensor, absolute, "topic", topic)
        self._check_order(self.readings.get(sensor), stamp_ns, what)
        self.readings[sensor] = Reading(absolute - cfg.atmospheric_pressure, math.nan, math.nan, stamp_ns)

    def _unit(self, target: str) -> str:
        """The unit of input ``target``'s value: rad for an angle sensor, m for a cylinder length."""
        return "rad" if target in self.angle_names else "m"

    @staticmethod
    def _check_order(previous: Reading | None, stamp_ns: int, what: str, joint: str | None = None) -> None:
        """Refuse a reading stamped before the one in use for the same input (the newest stamp wins);
        the finding names ``what`` (and the ``joint``), worded only when it refuses."""
        if previous is not None and stamp_ns < previous.stamp_ns:
            source = what if joint is None else f"{what} joint '{joint}'"
            raise Refused(Finding(Code.OUT_OF_ORDER, f"{source}: stamped {fmt((previous.stamp_ns - stamp_ns) / NS)} s "
                                  "before the reading in use: not applied (a second publisher, or a bag played "
                                  "out of order); it is recorded"))

    def _check_limit(self, name: str, value: float, source: str, source_name: str) -> None:
        """Refuse ``value`` outside the plausibility limit of input ``name``; the finding names the
        joint or topic (``source`` '``source_name``') it came from."""
        limit = self.limits.get(name)
        problem = limit.check(value) if limit is not None else None
        if problem:
            raise Refused(Finding(Code.OUT_OF_RANGE, f"{problem} ({source} '{source_name}')"))

    # ---- the inputs of a solve ----------------------------------------------------------------
    def inputs_at(self, stamp_ns: int) -> Inputs | Finding:
        """The inputs of a solve triggered at ``stamp_ns`` (ns), or the Finding why there is none.

        Staleness is the absolute difference of stamps: a reading from the future is as stale as
        one from the past.
        """
        r = self.readings
        if not self.required <= r.keys():
            missing = sorted(self.required - r.keys())
            return Finding(Code.NO_VALUE_YET, f"no solve: no value yet for {', '.join(missing)}")
        limit_ns = self.config.staleness_limit_s * NS
        stale = [(n, age) for n in self._required_order if (age := abs(stamp_ns - r[n].stamp_ns)) > limit_ns]
        if stale:
            ages = ", ".join(f"{n} ({fmt(age / NS)} s)" for n, age in stale)
            return Finding(Code.STALE_INPUT, f"no solve: stale input {ages} > staleness limit "
                                             f"{fmt(self.config.staleness_limit_s)} s")
        kinematic = self._kinematic_order
        dynamic = self.config.kinetostatics
        return Inputs(cylinders={n: r[n].value for n in self._cylinder_order},
                      angles={n: r[n].value for n in self._angle_order},
                      pressures={n: r[n].value for n in self._pressure_order},
                      rates={n: _zero_if_nan(r[n].rate) for n in kinematic} if dynamic else {},
                      accelerations={n: _zero_if_nan(r[n].acceleration) for n in kinematic} if dynamic else {})


def _zero_if_nan(value: float) -> float:
    """A rate not given (or not yet differenced) counts as 0 (quasi-static)."""
    return 0.0 if math.isnan(value) else value
