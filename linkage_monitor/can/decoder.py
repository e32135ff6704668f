"""CAN frames -> the monitoring core's input events, with the DBC files and the mapping.

Each frame ends in exactly one of three ways, counted (decoded + ignored + refused = received):
decoded (it fed one or more inputs: a JointStateEvent of its angles and cylinder lengths, a
PressureEvent per pressure), ignored (an identifier no DBC knows, a DBC message the mapping does
not use, a remote request) or refused with a Finding naming the frame and the reason (an error
frame, bus-off, a data length other than the DBC's, a J1939 'error indicator' or 'not
available' value, a value outside the signal's DBC range or outside the mapping's table). A
refused frame feeds nothing: the monitor never solves on a value that is not there.
J1939 frames (29-bit identifiers of a J1939 DBC message) are matched by parameter group number and
source address, whatever their priority: an input whose mapping names a ``source_address`` takes
frames of that ECU only (those of other sources are ignored, counted per identifier); an input that
names none takes one source, and once a second one sends its parameter group both are refused
(``sensors_disagree``, naming the two): two ECUs give two values, and the monitor would alternate
between them. A multiplexed message feeds the mapped signals its multiplexer selects in each frame.
Units SI (rad, m, Pa).

``decode_block`` decodes a FrameBlock (many frames, as columns) with numpy: the mapped signals' raw
values from the data bytes (``signals``), scaled, checked and converted by the same arithmetic as
``decode``, element by element (so the same floats); every frame that numpy does not decode cleanly —
an error frame, a remote request of a mapped message, a length other than the DBC's, a value that
is refused, a message whose signals numpy does not read — goes through ``decode``, whose outcome and
finding it then has. test_can_blocks.py holds the two equal frame for frame, with cantools as the
oracle of the raw values.
"""

from __future__ import annotations

from collections import Counter
from dataclasses import dataclass, field
from enum import Enum
from pathlib import Path
from typing import Any, Iterable, NamedTuple, Sequence, TypeVar

import cantools
import numpy as np
from cantools.database import Database

from linkage_monitor.mechanics import InputError, Mechanism
from linkage_monitor.monitoring.config import MonitorConfig
from linkage_monitor.monitoring.events import InputEvent, JointStateEvent, PressureEvent
from linkage_monitor.monitoring.findings import Code, Finding, Level, fmt

from .frames import CAN_ERR_MASK, Frame, FrameBlock
from .j1939 import CAN_ERR_BUSOFF, Raw, classify, is_value, pgn
from .mapping import UNITS, CanMapping, InputMap
from .signals import SignalLayout, raw_values, signal_layout, words

ANGLE, CYLINDER, PRESSURE = "angle", "cylinder", "pressure"
KIND_UNITS = {ANGLE: "angle", CYLINDER: "length", PRESSURE: "pressure"}
SI_UNIT = {ANGLE: "rad", CYLINDER: "m", PRESSURE: "Pa"}


class Outcome(Enum):
    """How a frame ended."""

    DECODED = "decoded"
    IGNORED = "ignored"
    REFUSED = "refused"


OUTCOMES = tuple(Outcome)   # BlockDecoded.outcome holds indices into this
DECODED, IGNORED, REFUSED = (OUTCOMES.index(o) for o in (Outcome.DECODED, Outcome.IGNORED, Outcome.REFUSED))
EXACT = 1 << 53   # integers up to this are exact as float64
_Pascal = TypeVar("_Pascal", float, np.ndarray)
_Ident = TypeVar("_Ident", int, np.ndarray)


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
    lost: int = 0   # frames dropped before the bridge read them (the socket's receive buffer was full)
    unknown_ids: Counter = field(default_factory=Counter)
    untrusted_ids: Counter = field(default_factory=Counter)   # J1939 frames of a source the mapping does not name
    two_sources: dict[str, list[int]] = field(default_factory=dict)   # message -> the source addresses sending it

    def summary(self) -> str:
        """``1203 frames: 1200 decoded, 2 ignored (2 of unknown identifiers 0x123 ×2), 1 refused``, then
        the frames of untrusted sources and the messages sent by two sources."""
        ignored = [f"{sum(ids.values())} of {what} {_counted(ids)}" for what, ids in (
            ("unknown identifiers", self.unknown_ids), ("sources the mapping does not trust", self.untrusted_ids)) if ids]
        text = (f"{self.received} frames: {self.decoded} decoded, {self.ignored} ignored"
                f"{' (' + '; '.join(ignored) + ')' if ignored else ''}, {self.refused} refused")
        if self.lost:
            text += f"; {self.lost} lost before the bridge read them (receive buffer full)"
        for message, sources in self.two_sources.items():
            text += (f"; {message} sent by {len(sources)} sources ({', '.join(f'0x{a:02X}' for a in sources)}): "
                     "not used, name the one to trust (source_address)")
        return text

    @property
    def level(self) -> Level:
        """WARN while frames were lost or an input's parameter group has two sources (not used), else OK."""
        return Level.WARN if self.lost or self.two_sources else Level.OK

    def lose(self, dropped: int, source: str) -> Finding:
        """Count ``dropped`` frames lost at the bus's socket before the bridge read them; the finding."""
        self.lost += dropped
        return Finding(Code.INPUTS_LOST, (
            f"{dropped} CAN frame(s) lost on {source} ({self.lost} in all): the socket's receive buffer overflowed "
            "before the bridge read them (more frames per second than it decodes and solves); none of them is used"))


SHOWN_IDS = 10   # identifiers a summary lists with their counts


def _counted(ids: Counter) -> str:
    """``0x123 ×2, 0x18FEF100 ×1`` (the most frequent SHOWN_IDS, then how many more)."""
    shown = ", ".join(f"0x{i:X} ×{n}" for i, n in ids.most_common(SHOWN_IDS))
    return shown + (f" and {len(ids) - SHOWN_IDS} more" if len(ids) > SHOWN_IDS else "")


@dataclass(frozen=True)
class _Route:
    """One mapped signal: the input it feeds, its kind, the DBC signal, the unit's factor to SI."""

    input: InputMap
    kind: str
    signal: Any          # cantools Signal
    factor: float
    topic: str           # the input's topic (JointState topic, or the pressure sensor's)


class _Vector(NamedTuple):
    """A mapped signal read with numpy: its route, where it lies in the data, whether its raw value has
    J1939 error / not-available ranges."""

    route: _Route
    layout: SignalLayout
    j1939: bool


@dataclass(frozen=True)
class _MessageRoute:
    message: Any         # cantools Message
    routes: tuple[_Route, ...]
    j1939: bool
    vector: tuple[_Vector, ...] | None   # its signals read with numpy; None: decoded one frame at a time
    source_address: int | None = None    # J1939: the one ECU trusted; None: any one source


class _RowKeys(NamedTuple):
    """Per frame of a block: its mapped message (index into the decoder's routes; -1: none), whether
    a DBC knows its identifier and whether it is of a source the mapping does not trust."""

    route: np.ndarray
    known: np.ndarray
    untrusted: np.ndarray


class DecodedInputs(NamedTuple):
    """The inputs one mapped message gave in a block: ``rows`` (m,) the frames (rows of the block) it
    decoded; the JointState on ``joint_topic`` of ``joint_names`` (none: no JointState) at ``positions``
    (m, len(joint_names)) rad / m; a FluidPressure on each of ``pressure_topics`` of ``pressures``
    (m, len(pressure_topics)) Pa, in the monitor's convention. Each frame's events in ``decode``'s order:
    the JointState, then the pressures."""

    rows: np.ndarray
    joint_topic: str
    joint_names: tuple[str, ...]
    positions: np.ndarray
    pressure_topics: tuple[str, ...]
    pressures: np.ndarray

    @property
    def events_per_frame(self) -> int:
        """The input events each of its frames gives."""
        return (1 if self.joint_names else 0) + len(self.pressure_topics)


@dataclass(frozen=True)
class BlockDecoded:
    """How each frame of a block ended: ``outcome`` (n,) indices into OUTCOMES; the inputs decoded with
    numpy, per mapped message; the frames decoded one by one (``decode``) with their Decoded, by row."""

    outcome: np.ndarray
    inputs: tuple[DecodedInputs, ...]
    single: dict[int, Decoded]

    def refusals(self) -> list[Finding]:
        """The finding of each refused frame, in frame order."""
        return [d.finding for _, d in sorted(self.single.items()) if d.finding is not None]


def _vector_of(message: Any, routes: list[_Route], j1939: bool) -> tuple[_Vector, ...] | None:
    """The mapped signals of ``message`` as numpy reads them, or None if it cannot read one of them: a
    signal ``signals`` does not lay out, or one whose physical values are not all exact as float64
    (then ``decode``'s integer arithmetic could differ)."""
    vector = []
    for r in routes:
        layout = signal_layout(message, r.signal)
        if layout is None or (1 << r.signal.length) * abs(r.signal.scale) + abs(r.signal.offset) >= EXACT:
            return None
        vector.append(_Vector(r, layout, j1939 and not r.signal.is_signed))
    return tuple(vector)


def _table(columns: list[np.ndarray], rows: np.ndarray) -> np.ndarray:
    """``columns`` (each (n,)) side by side, the ``rows`` (bool (n,)) kept: (kept, len(columns))."""
    if not columns:
        return np.zeros((int(rows.sum()), 0))
    return np.stack(columns, axis=1)[rows]


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


def _is_j1939(message: Any) -> bool:
    """Whether a cantools message is a J1939 parameter group (29-bit, the DBC's ProtocolType J1939)."""
    return bool(message.is_extended_frame and message.protocol == "j1939")


def source_address(ident: _Ident) -> _Ident:
    """The J1939 source address of a 29-bit identifier (its low byte; also of an array of them)."""
    return ident & 0xFF


# DBC unit spellings -> the mapping's unit names (UNITS), beside the names themselves in any case
UNIT_ALIASES = {"°": "deg", "degree": "deg", "degrees": "deg", "millimetre": "mm", "millimeter": "mm"}


def dbc_unit(text: str | None) -> tuple[str, str] | None:
    """(quantity, unit) of a DBC signal's unit string when it is one of UNITS (``kPa`` -> pressure, kPa;
    ``KPA`` too), None for an empty or other unit (``%``, ``rpm``)."""
    name = (text or "").strip()
    name = UNIT_ALIASES.get(name.lower(), name)
    for quantity, units in UNITS.items():
        for unit in units:
            if name == unit or name.lower() == unit.lower():
                return quantity, unit
    return None


def _check_signal(where: str, item: InputMap, kind: str, message: Any, signal: Any) -> None:
    """InputError if the DBC signal cannot feed ``item`` as mapped: a scale of 0 (every value the
    offset), or a unit other than the mapping's: without a table, value = scale · signal + offset is
    read in the mapping's ``unit`` (SI when none), so a DBC unit of the input's quantity must be that
    unit, one of another quantity cannot be it, and any other DBC unit (``%``) needs ``unit`` written."""
    name = f"{message.name}.{signal.name}"
    if signal.scale == 0:
        raise InputError(f"{where}.signal: {name} has factor 0 in the DBC: every frame would read its offset "
                         f"({fmt(signal.offset)}); correct the signal's factor in the DBC")
    if item.table is not None:
        return   # the table maps the signal's unit to the mapping's
    declared = (signal.unit or "").strip()
    quantity = KIND_UNITS[kind]
    mapped = item.unit or SI_UNIT[kind]
    read_as = f"'{item.unit}'" if item.unit else f"{SI_UNIT[kind]} (no 'unit' given: SI)"
    found = dbc_unit(declared)
    if found is not None and found[0] != quantity:
        raise InputError(f"{where}: the DBC gives {name} in {declared} (a {found[0]}), but {item.name} is "
                         f"{'an' if kind == ANGLE else 'a'} {quantity}: map a {quantity} signal, or give a table")
    if found is not None and found[1] != mapped:
        raise InputError(f"{where}.unit: the DBC gives {name} in {declared}, the mapping reads it as {read_as}: "
                         f"write 'unit: {found[1]}' (scale and offset then in {found[1]})")
    if found is None and declared and item.unit is None:
        raise InputError(f"{where}.unit: the DBC gives {name} in '{declared}', not a unit of {quantity}: write the "
                         f"unit scale · signal + offset is in ('unit: {SI_UNIT[kind]}', ...), or give a table")


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
        grouped: dict[tuple[str, int | None], list[_Route]] = {}
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
            _check_signal(where, item, kind, message, signal)
            if kind == PRESSURE:
                if item.pressure is None:
                    raise InputError(f"{where}.pressure: required for a pressure: gauge or absolute")
                if item.name not in topic_of_sensor:
                    raise InputError(f"{where}: pressure sensor '{item.name}' has no topic in the monitor's "
                                     "configuration (pressure_topics)")
            elif item.pressure is not None:
                raise InputError(f"{where}.pressure: only for pressures ('{item.name}' is {'an' if kind == ANGLE else 'a'} "
                                 f"{kind})")
            if item.source_address is not None and not _is_j1939(message):
                raise InputError(f"{where}.source_address: {item.message} is not a J1939 message (29-bit, "
                                 "ProtocolType J1939): its identifier names its sender; remove source_address")
            topic = topic_of_sensor[item.name] if kind == PRESSURE else config.topics.joint_states
            grouped.setdefault((message.name, item.source_address), []).append(
                _Route(item, kind, signal, units[unit], topic))
        self._by_id: dict[tuple[int, bool], _MessageRoute] = {}
        self._by_pgn: dict[int, dict[int | None, _MessageRoute]] = {}
        self._known_ids = {(m.frame_id, m.is_extended_frame) for m in db.messages}
        self._known_pgns = {pgn(m.frame_id) for m in db.messages if _is_j1939(m)}
        self._routes: list[_MessageRoute] = []
        self._senders: dict[int, list[int]] = {}   # route index -> the source addresses seen (any-source routes)
        for (name, source_address), routes in grouped.items():
            message = db.get_message_by_name(name)
            j1939 = _is_j1939(message)
            route = _MessageRoute(message, tuple(routes), j1939, _vector_of(message, routes, j1939), source_address)
            self._routes.append(route)
            if j1939:
                self._by_pgn.setdefault(pgn(message.frame_id), {})[source_address] = route
            else:
                self._by_id[(message.frame_id, message.is_extended_frame)] = route

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

    def _route_of(self, ident: int, extended: bool) -> _MessageRoute | None:
        """The mapped message of an identifier (J1939: by parameter group number and source address: the
        source's own route, else the route of any source), None if unmapped or of an untrusted source."""
        route = self._by_id.get((ident, extended))
        if route is None and extended:
            by_source = self._by_pgn.get(pgn(ident), {})
            route = by_source.get(source_address(ident), by_source.get(None))
        return route

    def _untrusted(self, ident: int, extended: bool) -> bool:
        """Whether a J1939 frame is of a mapped parameter group whose inputs trust other sources only."""
        return extended and pgn(ident) in self._by_pgn and self._route_of(ident, extended) is None

    def _second_source(self, frame: Frame, index: int) -> Decoded | None:
        """The refusal of a frame of any-source route ``index`` once two sources send its parameter group
        (the sources seen kept in order), None while one source does."""
        senders = self._senders.setdefault(index, [])
        sender = source_address(frame.arbitration_id)
        if sender not in senders:
            senders.append(sender)
        if len(senders) < 2:
            return None
        route = self._routes[index]
        self.counts.two_sources[route.message.name] = list(senders)
        names = ", ".join(r.input.name for r in route.routes)
        return self._refuse(frame, Code.SENSORS_DISAGREE, (
            f"comes from source address 0x{sender:02X}; {' and '.join(f'0x{a:02X}' for a in senders)} both send "
            f"PGN {pgn(frame.arbitration_id)}: two ECUs give {names}, neither is used. Name the one to trust in "
            f"the mapping (inputs.{route.routes[0].input.name}.source_address: 0x{senders[0]:02X})"), route.message)

    def _known(self, ident: int, extended: bool) -> bool:
        """Whether a DBC knows the identifier (J1939: its parameter group number)."""
        return (ident, extended) in self._known_ids or (extended and pgn(ident) in self._known_pgns)

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
                f"error frame on {self.source} (error class 0x{frame.arbitration_id & CAN_ERR_MASK:X}): a frame was "
                "damaged on the wire (check wiring, termination and bit rate)")))
        route = self._route_of(frame.arbitration_id, frame.is_extended)
        if route is None:
            if self._untrusted(frame.arbitration_id, frame.is_extended):
                self.counts.untrusted_ids[frame.arbitration_id] += 1
            elif not self._known(frame.arbitration_id, frame.is_extended):
                self.counts.unknown_ids[frame.arbitration_id] += 1
            return Decoded(Outcome.IGNORED)
        if frame.is_remote:
            return Decoded(Outcome.IGNORED)
        if route.j1939 and route.source_address is None:
            refused = self._second_source(frame, self._routes.index(route))
            if refused is not None:
                return refused
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
            if signal.name not in raw:   # a multiplexed signal its multiplexer does not select in this frame
                continue
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
        return Decoded(Outcome.DECODED, tuple(events)) if events else Decoded(Outcome.IGNORED)

    # ---- many frames ---------------------------------------------------------------------------
    def decode_block(self, block: FrameBlock) -> BlockDecoded:
        """Every frame's outcome (counted), received = stamped (a log's time is its receive time); never
        raises. The same outcomes, events and findings as ``decode`` of each frame in order."""
        outcome = np.full(len(block), IGNORED, np.int8)
        keys = self._key_rows(block)
        single = block.is_error | (block.is_remote & (keys.route >= 0))
        unmapped = (keys.route < 0) & ~block.is_error
        self._count_ids(self.counts.untrusted_ids, block.arbitration_id[unmapped & keys.untrusted])
        self._count_ids(self.counts.unknown_ids, block.arbitration_id[unmapped & ~keys.untrusted & ~keys.known])
        inputs = []
        for index, route in enumerate(self._routes):
            rows = np.flatnonzero((keys.route == index) & ~single)
            if route.j1939 and route.source_address is None:
                rows = self._one_source_rows(index, block, rows, single)
            length = route.message.length
            fits = (block.dlc[rows] == length) & (block.length[rows] == length) & (route.vector is not None)
            single[rows[~fits]] = True
            decoded, good = self._decode_rows(route, block, rows[fits])
            single[rows[fits][~good]] = True
            if len(decoded.rows):
                outcome[decoded.rows] = DECODED
                inputs.append(decoded)
        counts = self.counts
        counts.received += int((~single).sum())
        counts.decoded += int((outcome == DECODED).sum())
        counts.ignored += int(((outcome == IGNORED) & ~single).sum())
        one_by_one = {}
        for k in np.flatnonzero(single).tolist():
            one_by_one[k] = self.decode(block.frame(k), int(block.stamp_ns[k]))
            outcome[k] = OUTCOMES.index(one_by_one[k].outcome)
        return BlockDecoded(outcome, tuple(inputs), one_by_one)

    def _key_rows(self, block: FrameBlock) -> _RowKeys:
        """Each frame's mapped message and whether a DBC knows its identifier, looked up once per
        identifier of the block."""
        keys, inverse = np.unique(block.arbitration_id * 2 + block.is_extended, return_inverse=True)
        index = {id(route): k for k, route in enumerate(self._routes)}
        route, known, untrusted = np.full(len(keys), -1, np.int64), np.zeros(len(keys), bool), np.zeros(len(keys), bool)
        for k, value in enumerate(keys.tolist()):
            ident, extended = value >> 1, bool(value & 1)
            found = self._route_of(ident, extended)
            route[k] = -1 if found is None else index[id(found)]
            known[k] = self._known(ident, extended)
            untrusted[k] = self._untrusted(ident, extended)
        inverse = inverse.ravel()
        return _RowKeys(route[inverse], known[inverse], untrusted[inverse])

    @staticmethod
    def _count_ids(counter: Counter, idents: np.ndarray) -> None:
        """Count frames of identifiers ``idents`` (in frame order) into ``counter`` as ``decode`` does: each
        identifier at its first appearance."""
        ids, first, count = np.unique(idents, return_index=True, return_counts=True)
        for k in np.argsort(first, kind="stable").tolist():
            counter[int(ids[k])] += int(count[k])

    def _one_source_rows(self, index: int, block: FrameBlock, rows: np.ndarray, single: np.ndarray) -> np.ndarray:
        """The frames ``rows`` of any-source route ``index`` sent while one source sends its parameter group
        (kept for numpy); from the first frame of a second source on, every one is marked ``single``, for
        ``decode`` to refuse (``_second_source``)."""
        if not len(rows):
            return rows
        senders = self._senders.get(index, [])
        sources = source_address(block.arbitration_id[rows])
        first = senders[0] if senders else int(sources[0])
        cut = len(rows) if len(senders) < 2 else 0
        other = np.flatnonzero(sources[:cut] != first)
        cut = int(other[0]) if len(other) else cut
        single[rows[cut:]] = True
        if cut:
            self._senders[index] = [first]
        return rows[:cut]

    def _decode_rows(self, route: _MessageRoute, block: FrameBlock, rows: np.ndarray
                     ) -> tuple[DecodedInputs, np.ndarray]:
        """The inputs of frames ``rows`` of mapped message ``route`` (of its DBC length), and which of
        them decode cleanly (the others are refused by ``decode``: an error / not-available value, a value
        outside the DBC's range or the mapping's table)."""
        good = np.ones(len(rows), bool)
        names, positions, topics, pressures = [], [], [], []
        w = words(block.data[rows])
        for vector in route.vector or ():
            r = vector.route
            signal, item = r.signal, r.input
            raw = raw_values(w, vector.layout)
            if vector.j1939:
                good &= is_value(raw, signal.length)
            physical = raw.astype(float) * signal.scale + signal.offset
            if signal.minimum is not None:
                good &= ~(physical < signal.minimum)
            if signal.maximum is not None:
                good &= ~(physical > signal.maximum)
            if item.table is not None:
                in_unit, inside = item.table.lookup_many(physical)
                good &= inside
            else:
                in_unit = item.scale * physical + item.offset
            si = in_unit * r.factor
            if r.kind == PRESSURE:
                topics.append(r.topic)
                pressures.append(self._fluid_pressure(si, item.pressure == "absolute"))
            else:
                names.append(item.name)
                positions.append(si)
        return DecodedInputs(rows[good], self.config.topics.joint_states, tuple(names), _table(positions, good),
                             tuple(topics), _table(pressures, good)), good

    def _fluid_pressure(self, pascal: _Pascal, absolute: bool) -> _Pascal:
        """The FluidPressure value (Pa) of a reading, in the convention the monitor is configured for."""
        cfg = self.config
        if absolute == cfg.pressure_absolute:
            return pascal
        return pascal + cfg.atmospheric_pressure if cfg.pressure_absolute else pascal - cfg.atmospheric_pressure

    def decode_all(self, frames: Iterable[Frame]) -> Iterable[tuple[Frame, Decoded]]:
        """Each frame with its outcome, received = stamped (logs: the log's time is the receive time)."""
        for frame in frames:
            yield frame, self.decode(frame, frame.stamp_ns)
