"""CAN frames -> the monitoring core's input events, with the DBC files and the mapping.

Each frame ends in exactly one of three ways, counted (decoded + ignored + refused = received):
decoded (it fed one or more inputs: a JointStateEvent of its angles and cylinder lengths, a
PressureEvent per pressure), ignored (an identifier no DBC knows, a DBC message the mapping does
not use, a remote request) or refused with a Finding naming the frame and the reason (an error
frame, bus-off, a data length other than the DBC's, a J1939 'error indicator' or 'not
available' value, a value outside the signal's DBC range or outside the mapping's table). A
refused frame feeds nothing: the monitor never solves on a value that is not there.
J1939 frames (29-bit identifiers of a J1939 DBC message) are matched by parameter group number,
whatever their source address and priority. Units SI (rad, m, Pa).
"""

from __future__ import annotations

from collections import Counter
from dataclasses import dataclass, field
from enum import Enum
from pathlib import Path
from typing import Any, Iterable, Sequence

import cantools
from cantools.database import Database

from linkage_monitor.mechanics import InputError, Mechanism
from linkage_monitor.monitoring.config import MonitorConfig
from linkage_monitor.monitoring.events import InputEvent, JointStateEvent, PressureEvent
from linkage_monitor.monitoring.findings import Code, Finding, fmt

from .frames import Frame
from .j1939 import CAN_ERR_BUSOFF, Raw, classify, pgn
from .mapping import UNITS, CanMapping, InputMap

ANGLE, CYLINDER, PRESSURE = "angle", "cylinder", "pressure"
KIND_UNITS = {ANGLE: "angle", CYLINDER: "length", PRESSURE: "pressure"}
SI_UNIT = {ANGLE: "rad", CYLINDER: "m", PRESSURE: "Pa"}


class Outcome(Enum):
    """How a frame ended."""

    DECODED = "decoded"
    IGNORED = "ignored"
    REFUSED = "refused"


@dataclass(frozen=True)
class Decoded:
    """One frame's outcome: the input events it gives (decoded) or the finding why not (refused)."""

    outcome: Outcome
    events: tuple[InputEvent, ...] = ()
    finding: Finding | None = None


@dataclass
class FrameCounts:
    """Frames received and how they ended; unknown identifiers with their counts."""

    received: int = 0
    decoded: int = 0
    ignored: int = 0
    refused: int = 0
    unknown_ids: Counter = field(default_factory=Counter)

    def summary(self) -> str:
        """``1203 frames: 1200 decoded, 2 ignored (1 unknown identifier), 1 refused``."""
        ids = ", ".join(f"0x{i:X}" for i, _ in self.unknown_ids.most_common(5))
        unknown = f" ({sum(self.unknown_ids.values())} of unknown identifiers {ids})" if self.unknown_ids else ""
        return (f"{self.received} frames: {self.decoded} decoded, {self.ignored} ignored{unknown}, "
                f"{self.refused} refused")


@dataclass(frozen=True)
class _Route:
    """One mapped signal: the input it feeds, its kind, the DBC signal, the unit's factor to SI."""

    input: InputMap
    kind: str
    signal: Any          # cantools Signal
    factor: float
    topic: str           # the input's topic (JointState topic, or the pressure sensor's)


@dataclass(frozen=True)
class _MessageRoute:
    message: Any         # cantools Message
    routes: tuple[_Route, ...]
    j1939: bool


def load_databases(paths: Sequence[str | Path]) -> Database:
    """The DBC files as one cantools database; InputError naming a file that is not one."""
    if not paths:
        raise InputError("no DBC file: give --dbc FILE or list them under 'dbc' in the mapping")
    db = cantools.database.Database()
    for path in paths:
        try:
            db.add_dbc_file(str(path))
        except FileNotFoundError:
            raise InputError(f"DBC {path}: no such file") from None
        except Exception as exc:  # noqa: BLE001 - cantools raises its own parse errors, ValueError, ...
            raise InputError(f"DBC {path}: not a DBC file cantools can read ({str(exc).splitlines()[0]})") from None
    return db


def input_kinds(mech: Mechanism) -> dict[str, str]:
    """Measurement name -> its kind (angle, cylinder, pressure) in ``mech``."""
    kinds = {a.name: ANGLE for a in mech.measurements.angles}
    kinds.update({c: CYLINDER for c in mech.measurements.cylinders})
    kinds.update({p.name: PRESSURE for p in mech.measurements.pressures})
    return kinds


class CanDecoder:
    """Frames -> input events of ``mechanism`` under ``config`` (its topics, pressure convention).

    source: the name frame-level findings carry as their input (a bus channel, a topic).
    Raises InputError naming the mapping key when the mapping does not fit the DBC or the mechanism.
    """

    def __init__(self, db: Database, mapping: CanMapping, mechanism: Mechanism, config: MonitorConfig,
                 source: str) -> None:
        self.mapping, self.config, self.source = mapping, config, source
        self.counts = FrameCounts()
        kinds = input_kinds(mechanism)
        topic_of_sensor = {sensor: topic for topic, sensor in config.pressure_topics.items()}
        grouped: dict[str, list[_Route]] = {}
        for item in mapping.inputs:
            where = f"mapping {mapping.source}: inputs.{item.name}"
            kind = kinds.get(item.name)
            if kind is None:
                raise InputError(f"{where}: '{item.name}' is not a measurement of mechanism '{mechanism.name}' "
                                 f"(measurements: {', '.join(sorted(kinds))})")
            try:
                message = db.get_message_by_name(item.message)
            except KeyError:
                raise InputError(f"{where}.message: '{item.message}' is in no DBC file (messages: "
                                 f"{', '.join(sorted(m.name for m in db.messages))})") from None
            try:
                signal = message.get_signal_by_name(item.signal)
            except KeyError:
                raise InputError(f"{where}.signal: '{item.signal}' is not a signal of {item.message} (signals: "
                                 f"{', '.join(s.name for s in message.signals)})") from None
            units = UNITS[KIND_UNITS[kind]]
            unit = item.unit or SI_UNIT[kind]
            if unit not in units:
                raise InputError(f"{where}.unit: '{unit}' is not a unit of {KIND_UNITS[kind]} ({', '.join(units)})")
            if kind == PRESSURE:
                if item.pressure is None:
                    raise InputError(f"{where}.pressure: required for a pressure: gauge or absolute")
                if item.name not in topic_of_sensor:
                    raise InputError(f"{where}: pressure sensor '{item.name}' has no topic in the monitor's "
                                     "configuration (pressure_topics)")
            elif item.pressure is not None:
                raise InputError(f"{where}.pressure: only for pressures ('{item.name}' is {'an' if kind == ANGLE else 'a'} "
                                 f"{kind})")
            topic = topic_of_sensor[item.name] if kind == PRESSURE else config.topics.joint_states
            grouped.setdefault(message.name, []).append(_Route(item, kind, signal, units[unit], topic))
        self._by_id: dict[tuple[int, bool], _MessageRoute] = {}
        self._by_pgn: dict[int, _MessageRoute] = {}
        self._known_ids = {(m.frame_id, m.is_extended_frame) for m in db.messages}
        self._known_pgns = {pgn(m.frame_id) for m in db.messages if m.is_extended_frame and m.protocol == "j1939"}
        for name, routes in grouped.items():
            message = db.get_message_by_name(name)
            j1939 = message.is_extended_frame and message.protocol == "j1939"
            route = _MessageRoute(message, tuple(routes), j1939)
            self._by_id[(message.frame_id, message.is_extended_frame)] = route
            if j1939:
                self._by_pgn[pgn(message.frame_id)] = route

    # ---- one frame ----------------------------------------------------------------------------
    def decode(self, frame: Frame, receive_ns: int) -> Decoded:
        """The frame's outcome (counted); never raises."""
        counts = self.counts
        counts.received += 1
        try:
            decoded = self._decode(frame, receive_ns)
        except Exception as exc:  # noqa: BLE001 - a frame that breaks the decoder is refused, not fatal
            decoded = self._refuse(frame, Code.MALFORMED_INPUT, f"cannot be decoded ({type(exc).__name__}: {exc})")
        if decoded.outcome is Outcome.DECODED:
            counts.decoded += 1
        elif decoded.outcome is Outcome.IGNORED:
            counts.ignored += 1
        else:
            counts.refused += 1
        return decoded

    def _name(self, frame: Frame, message: Any = None) -> str:
        ident = f"0x{frame.arbitration_id:08X}" if frame.is_extended else f"0x{frame.arbitration_id:03X}"
        return f"CAN frame {message.name + ' ' if message is not None else ''}({ident}) on {self.source}"

    def _refuse(self, frame: Frame, code: Code, reason: str, message: Any = None) -> Decoded:
        return Decoded(Outcome.REFUSED, finding=Finding(code, f"{self._name(frame, message)} {reason}; not used"))

    def _decode(self, frame: Frame, receive_ns: int) -> Decoded:
        if frame.is_error:
            if frame.arbitration_id & CAN_ERR_BUSOFF:
                return Decoded(Outcome.REFUSED, finding=Finding(Code.INPUTS_LOST, (
                    f"bus-off on {self.source}: the CAN controller left the bus after too many errors; frames "
                    "sent meanwhile are lost (check wiring, termination and bit rate)")))
            return Decoded(Outcome.REFUSED, finding=Finding(Code.MALFORMED_INPUT, (
                f"error frame on {self.source} (error class 0x{frame.arbitration_id & 0x1FFFFFFF:X}): a frame was "
                "damaged on the wire (check wiring, termination and bit rate)")))
        route = self._by_id.get((frame.arbitration_id, frame.is_extended))
        if route is None and frame.is_extended:
            route = self._by_pgn.get(pgn(frame.arbitration_id))
        if route is None:
            known = ((frame.arbitration_id, frame.is_extended) in self._known_ids
                     or (frame.is_extended and pgn(frame.arbitration_id) in self._known_pgns))
            if not known:
                self.counts.unknown_ids[frame.arbitration_id] += 1
            return Decoded(Outcome.IGNORED)
        if frame.is_remote:
            return Decoded(Outcome.IGNORED)
        message = route.message
        if frame.dlc != message.length or len(frame.data) != message.length:
            return self._refuse(frame, Code.MALFORMED_INPUT, f"has {len(frame.data)} data bytes (DLC {frame.dlc}), "
                                f"its DBC length is {message.length}", message)
        raw = message.decode(frame.data, decode_choices=False, scaling=False)
        names: list[str] = []
        positions: list[float] = []
        pressures: list[tuple[str, float]] = []
        for r in route.routes:
            signal = r.signal
            value = raw[signal.name]
            if route.j1939 and not signal.is_signed:
                meaning = classify(int(value), signal.length)
                if meaning is not Raw.VALUE:
                    code = Code.NO_VALUE_YET if meaning is Raw.NOT_AVAILABLE else Code.MALFORMED_INPUT
                    return self._refuse(frame, code, f"signal {signal.name} reads '{meaning.value}' "
                                        f"(raw 0x{int(value):X}): the tractor has no valid value for {r.input.name}",
                                        message)
            physical = value * signal.scale + signal.offset
            low, high = signal.minimum, signal.maximum
            if (low is not None and physical < low) or (high is not None and physical > high):
                return self._refuse(frame, Code.OUT_OF_RANGE, f"signal {signal.name} = {fmt(physical)} "
                                    f"{signal.unit or ''} is outside its DBC range [{fmt(low)}, {fmt(high)}]",
                                    message)
            item = r.input
            if item.table is not None:
                looked = item.table.lookup(physical)
                if looked is None:
                    return self._refuse(frame, Code.OUT_OF_RANGE, f"signal {signal.name} = {fmt(physical)} "
                                        f"{signal.unit or ''} is outside the mapping's table for {item.name} "
                                        f"({item.table.span()}): recalibrate the table (can-calibrate)", message)
                in_unit = looked
            else:
                in_unit = item.scale * physical + item.offset
            si = in_unit * r.factor
            if r.kind == PRESSURE:
                pressures.append((r.topic, self._fluid_pressure(si, item.pressure == "absolute")))
            else:
                names.append(item.name)
                positions.append(si)
        events: list[InputEvent] = []
        if names:
            events.append(JointStateEvent(self.config.topics.joint_states, tuple(names), tuple(positions), (),
                                          frame.stamp_ns, receive_ns))
        events.extend(PressureEvent(topic, value, frame.stamp_ns, receive_ns) for topic, value in pressures)
        return Decoded(Outcome.DECODED, tuple(events))

    def _fluid_pressure(self, pascal: float, absolute: bool) -> float:
        """The FluidPressure value (Pa) of a reading, in the convention the monitor is configured for."""
        cfg = self.config
        if absolute == cfg.pressure_absolute:
            return pascal
        return pascal + cfg.atmospheric_pressure if cfg.pressure_absolute else pascal - cfg.atmospheric_pressure

    def decode_all(self, frames: Iterable[Frame]) -> Iterable[tuple[Frame, Decoded]]:
        """Each frame with its outcome, received = stamped (logs: the log's time is the receive time)."""
        for frame in frames:
            yield frame, self.decode(frame, frame.stamp_ns)
