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

import numpy as np

from linkage_monitor.mechanics import Inputs, Mechanism
from linkage_monitor.mechanics.limits import Limit, input_limits

from .config import MonitorConfig
from .input_columns import InputColumns
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
        if not stamp_refused(stamp_ns, now_ns, tolerance):
            return
        if stamp_ns <= 0:
            raise Refused(Finding(Code.BAD_STAMP, f"{what}: header stamp {stamp_ns} ns is not after 1970: "
                                  "the sensor's clock is not set"))
        offset = (stamp_ns - now_ns) / NS   # refused after 1970: too far from the clock
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

    # ---- many events at once (the replay) ------------------------------------------------------
    def accept_run(self, run: InputColumns) -> DueRun:
        """The longest leading run of the events in ``run`` that ``accept_joint_state`` /
        ``accept_pressure`` each accept with every input then fresh (``inputs_at`` gives inputs),
        accepted at once: the readings as after taking them one by one, and their solves' inputs. The
        run ends before the first event refused or lacking an input, or on a topic that maps to no
        pressure sensor or to one another topic also does (none with kinetostatics): the caller takes
        that one alone. The same rules with the same arithmetic, on arrays (``Limit.inside``,
        ``stamp_refused``, the newest stamp per input, the staleness limit)."""
        if self.config.kinetostatics:
            return _no_run()
        sources, end = _sources(self, run)
        if sources is None or end == 0:
            return _no_run()
        run = run.head(end)
        sources = [s.head(end) for s in sources]
        ok = ~stamp_refused(run.stamps_ns, run.receive_ns, self.config.stamp_tolerance_s)
        ok &= np.abs(run.stamps_ns - run.receive_ns) < _EXACT_NS
        for source in sources:
            ok[source.at] &= source.clean & (source.stamps >= source.previous)
        end = int(np.argmin(ok)) if not ok.all() else run.size   # the first refused: every one before accepted
        count = self._fresh_count(run.stamps_ns[:end], [s.head(end) for s in sources])
        if not count:
            return _no_run()
        taken = [s.head(count) for s in sources]
        due = DueRun(count, *({n: _filled_at(count, taken, n, self.readings) for n in order}
                              for order in (self._cylinder_order, self._angle_order, self._pressure_order)))
        self._take(taken)
        return due

    def _fresh_count(self, stamps: np.ndarray, sources: list[_Source]) -> int:
        """How many of the accepted events at ``stamps`` (ns) in a row from the first have every input
        there and none stale at their stamp (``inputs_at``'s rule)."""
        fresh = np.ones(len(stamps), bool)
        limit_ns = self.config.staleness_limit_s * NS
        for name in self._required_order:
            reading, there = _latest_stamps(len(stamps), sources, name, self.readings)
            age = np.abs(stamps - reading)
            fresh &= there & (age <= limit_ns) & (age < _EXACT_NS)
        return int(np.argmin(fresh)) if not fresh.all() else len(stamps)

    def _take(self, sources: list[_Source]) -> None:
        """The readings after the events of ``sources`` (accepted), as ``accept_*`` leave them."""
        for source in sources:
            if not len(source.at):
                continue
            for target, values, rates in zip(source.targets, source.values, source.rates):
                previous = self.readings.get(target)
                if len(source.at) > 1:   # the reading before the last, for the last's acceleration
                    previous = Reading(float(values[-2]), float(rates[-2]), math.nan, int(source.stamps[-2]))
                value, rate, stamp = float(values[-1]), float(rates[-1]), int(source.stamps[-1])
                self.readings[target] = (previous.then(value, rate, stamp) if previous is not None
                                         else Reading(value, rate, math.nan, stamp))
            if source.unknown is not None:
                self.unknown_joints = source.unknown

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


class DueRun(NamedTuple):
    """``InputTracker.accept_run``'s answer: its first ``accepted`` events were accepted, each with its
    solve due, and the inputs of each solve as
    ``inputs_at`` gives them: cylinders (m), angles (rad), pressures (Pa gauge), by name, arrays (accepted,)."""

    accepted: int
    cylinders: dict[str, np.ndarray]
    angles: dict[str, np.ndarray]
    pressures: dict[str, np.ndarray]


def stamp_refused(stamp_ns: int | np.ndarray, now_ns: int | np.ndarray, tolerance_s: float) -> bool | np.ndarray:
    """Whether a header stamp (ns) is refused: ≤ 0, or farther than ``tolerance_s`` (s) from the monitor's
    clock ``now_ns`` (ns); one stamp, or arrays of them elementwise (the same division and comparison:
    exact alike for stamps less than 2**53 ns apart)."""
    return (stamp_ns <= 0) | (abs((stamp_ns - now_ns) / NS) > tolerance_s)


def _zero_if_nan(value: float) -> float:
    """A rate not given (or not yet differenced) counts as 0 (quasi-static)."""
    return 0.0 if math.isnan(value) else value


_EXACT_NS = 2**53                       # ns: differences of stamps below it are exact as float64 (the rules' arithmetic)
_NONE_BEFORE = np.iinfo(np.int64).min   # the stamp before an input's first reading: any stamp is newer


class _Source:
    """The events of a run that carry the same inputs (the JointStates, or one pressure sensor's
    FluidPressures): ``at`` their places in the run, ``stamps`` (ns), per input (``targets``) their
    ``values`` and ``rates`` as a reading takes them, ``clean`` where the rules that need no reading
    before pass, ``previous`` the stamp of the reading before each (the state's, then the one
    before in the run); ``unknown``: the JointStates' names that map to no input (None: pressures)."""

    def __init__(self, at: np.ndarray, stamps: np.ndarray, targets: tuple[str, ...], values: list[np.ndarray],
                 rates: list[np.ndarray], clean: np.ndarray, previous: np.ndarray,
                 unknown: tuple[str, ...] | None) -> None:
        self.at, self.stamps, self.targets, self.values, self.rates = at, stamps, targets, values, rates
        self.clean, self.previous, self.unknown = clean, previous, unknown

    @staticmethod
    def of(tracker: InputTracker, at: np.ndarray, stamps: np.ndarray, targets: tuple[str, ...],
           values: list[np.ndarray], rates: list[np.ndarray], clean: np.ndarray,
           unknown: tuple[str, ...] | None) -> _Source:
        """The source of the events at ``at`` of a run whose stamps are ``stamps``."""
        before = max((tracker.readings[t].stamp_ns for t in targets if t in tracker.readings), default=_NONE_BEFORE)
        own = stamps[at]
        return _Source(at, own, targets, values, rates, clean, np.concatenate(([before], own[:-1])), unknown)

    def head(self, end: int) -> _Source:
        """This source's events before place ``end`` of the run."""
        m = int(np.searchsorted(self.at, end))
        return _Source(self.at[:m], self.stamps[:m], self.targets, [v[:m] for v in self.values],
                       [r[:m] for r in self.rates], self.clean[:m], self.previous[:m], self.unknown)


def _inside(tracker: InputTracker, target: str, values: np.ndarray) -> np.ndarray | bool:
    """Where ``values`` of input ``target`` are inside its plausibility limit (everywhere without one)."""
    limit = tracker.limits.get(target)
    return limit.inside(values) if limit is not None else True


def _latest(size: int, sources: list[_Source], name: str) -> tuple[_Source | None, np.ndarray]:
    """The source carrying input ``name`` (None: no event of the run does) and, after each of the
    run's first ``size`` events, the index (in that source) of its reading of ``name`` in use
    (−1: the one before the run, if any)."""
    for source in sources:
        if name in source.targets and len(source.at):
            index = np.full(size, -1, np.intp)
            index[source.at] = np.arange(len(source.at))
            return source, np.maximum.accumulate(index)
    return None, np.full(size, -1, np.intp)


def _latest_stamps(size: int, sources: list[_Source], name: str, readings: Mapping[str, Reading]
                   ) -> tuple[np.ndarray, np.ndarray]:
    """After each of the run's first ``size`` events: the stamp (ns) of the reading of ``name`` in use,
    and whether there is one."""
    source, index = _latest(size, sources, name)
    before = readings.get(name)
    own = source.stamps[index] if source is not None else np.zeros(size, np.int64)
    earlier = before.stamp_ns if before is not None else 0
    return np.where(index >= 0, own, earlier), (index >= 0) | (before is not None)


def _filled_at(size: int, sources: list[_Source], name: str, readings: Mapping[str, Reading]) -> np.ndarray:
    """After each of the run's first ``size`` events (every input there): the value of the reading of ``name``."""
    source, index = _latest(size, sources, name)
    if source is None:
        return np.full(size, readings[name].value)
    own = source.values[source.targets.index(name)]
    return np.where(index >= 0, own[index], readings[name].value if name in readings else math.nan)


def _no_run() -> DueRun:
    """No event accepted at once."""
    return DueRun(0, {}, {}, {})


def _sources(tracker: InputTracker, run: InputColumns) -> tuple[list[_Source] | None, int]:
    """The sources (``_Source``) of ``run``'s events before the first one on a pressure topic that maps
    to no sensor or to one another topic also does, and that place; None when its JointStates are
    refused whatever their values (a name twice, no name of an input) or feed an input twice or a
    pressure sensor's."""
    found = []
    end, topics = run.size, tracker.config.pressure_topics
    sensors = [topics.get(t) for t in run.pressure_at]
    for topic, sensor in zip(run.pressure_at, sensors):
        if sensor is None or sensors.count(sensor) > 1:
            end = min(end, int(run.pressure_at[topic][0]))
    if len(run.joint_at):
        names = run.names
        mapped = [(k, tracker._joint_to_input.get(n)) for k, n in enumerate(names)]
        targets = tuple(t for _, t in mapped if t is not None)
        if (len(set(names)) != len(names) or not targets or len(set(targets)) != len(targets)
                or set(targets) & tracker.pressure_names):
            return None, 0
        columns = [k for k, t in mapped if t is not None]
        values = [run.positions[:, k] for k in columns]
        velocity = run.velocities
        rates = [velocity[:, k] if velocity is not None else np.full(len(run.joint_at), math.nan) for k in columns]
        clean = np.isfinite(run.positions[:, columns]).all(axis=1)
        if velocity is not None:
            clean &= np.isfinite(velocity[:, columns]).all(axis=1)
        for target, value in zip(targets, values):
            clean &= _inside(tracker, target, value)
        found.append(_Source.of(tracker, run.joint_at, run.stamps_ns, targets, values, rates, clean,
                                tuple(n for n, (_, t) in zip(names, mapped) if t is None)))
    cfg = tracker.config
    for topic, sensor in zip(run.pressure_at, sensors):
        if sensor is None or sensors.count(sensor) > 1:
            continue
        value, at = run.pressures[topic], run.pressure_at[topic]
        absolute = value if cfg.pressure_absolute else value + cfg.atmospheric_pressure
        clean = np.isfinite(value) & (absolute >= 0.0) & _inside(tracker, sensor, absolute)
        found.append(_Source.of(tracker, at, run.stamps_ns, (sensor,), [absolute - cfg.atmospheric_pressure],
                                [np.full(len(at), math.nan)], clean, None))
    return found, end
