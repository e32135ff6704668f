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
from pathlib import Path
from typing import Any, Iterable, Sequence, TypeVar

import cantools
import numpy as np
from cantools.database import Database

from linkage_monitor.mechanics import InputError, Mechanism
from linkage_monitor.monitoring.config import MonitorConfig
from linkage_monitor.monitoring.events import InputEvent, JointStateEvent, PressureEvent
from linkage_monitor.monitoring.findings import Code, Finding, fmt
from linkage_monitor.monitoring.sources import two_sources

from .frames import CAN_ERR_MASK, Frame, FrameBlock
from .j1939 import CAN_ERR_BUSOFF, Raw, classify, is_value, pgn, source_address
from .mapping import CanMapping
from .outcomes import DECODED, IGNORED, OUTCOMES, BlockDecoded, Decoded, DecodedInputs, FrameCounts, Outcome
from .routes import MessageRoute, Routing
from .signals import raw_values, words
from .units import PRESSURE

_Pascal = TypeVar("_Pascal", float, np.ndarray)


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


class CanDecoder:
    """Frames -> input events of ``mechanism`` under ``config`` (its topics, pressure convention).

    source: the name frame-level findings carry as their input (a bus channel, a topic).
    Raises InputError naming the mapping key when the mapping does not fit the DBC or the mechanism.
    """

    def __init__(self, db: Database, mapping: CanMapping, mechanism: Mechanism, config: MonitorConfig,
                 source: str) -> None:
        self.mapping, self.config, self.source = mapping, config, source
        self.counts = FrameCounts()
        self._routing = Routing(db, mapping, mechanism, config)
        self._senders: dict[int, list[int]] = {}   # route index -> the source addresses seen (any-source routes)

    @property
    def resolutions(self) -> dict[str, tuple[str, float]]:
        """Each mapped input's kind and quantization step in SI, from its DBC signal's scale
        (``Routing.resolutions``): what the error budget takes as the sensor's resolution
        (``ErrorSources.with_resolutions``)."""
        return self._routing.resolutions

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

    def _second_source(self, frame: Frame, index: int) -> Decoded | None:
        """The refusal of a frame of any-source route ``index`` once two sources send its parameter group
        (the sources seen kept in order), None while one source does."""
        senders = self._senders.setdefault(index, [])
        sender = source_address(frame.arbitration_id)
        if sender not in senders:
            senders.append(sender)
        if len(senders) < 2:
            return None
        route = self._routing.routes[index]
        self.counts.two_sources[route.message.name] = list(senders)
        names = ", ".join(r.input.name for r in route.routes)
        return self._refuse(frame, Code.SENSORS_DISAGREE, f"comes from source address 0x{sender:02X}; " + two_sources(
            [f"0x{a:02X}" for a in senders], f"PGN {pgn(frame.arbitration_id)}", f"ECUs give {names}",
            f"in the mapping (inputs.{route.routes[0].input.name}.source_address: 0x{senders[0]:02X})"), route.message)

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
        route = self._routing.route_of(frame.arbitration_id, frame.is_extended)
        if route is None:
            if self._routing.untrusted(frame.arbitration_id, frame.is_extended):
                self.counts.untrusted_ids[frame.arbitration_id] += 1
            elif not self._routing.known(frame.arbitration_id, frame.is_extended):
                self.counts.unknown_ids[frame.arbitration_id] += 1
            return Decoded(Outcome.IGNORED)
        if frame.is_remote:
            return Decoded(Outcome.IGNORED)
        if route.j1939 and route.source_address is None:
            refused = self._second_source(frame, self._routing.routes.index(route))
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
        keys = self._routing.key_rows(block)
        single = block.is_error | (block.is_remote & (keys.route >= 0))
        unmapped = (keys.route < 0) & ~block.is_error
        self._count_ids(self.counts.untrusted_ids, block.arbitration_id[unmapped & keys.untrusted])
        self._count_ids(self.counts.unknown_ids, block.arbitration_id[unmapped & ~keys.untrusted & ~keys.known])
        inputs = []
        for index, route in enumerate(self._routing.routes):
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

    def _decode_rows(self, route: MessageRoute, block: FrameBlock, rows: np.ndarray
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
