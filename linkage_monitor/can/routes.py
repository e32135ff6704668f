"""The mapping's routes over the DBC files: which signal of which DBC message feeds which of the
mechanism's measurements (checked against the DBC and the mechanism: InputError naming the mapping
key), the mapped messages looked up by identifier (J1939: by parameter group number and source
address, whatever the priority), and which of their signals numpy reads. Units SI (rad, m, Pa).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, NamedTuple

import numpy as np
from cantools.database import Database

from linkage_monitor.mechanics import InputError, Mechanism
from linkage_monitor.monitoring.config import MonitorConfig

from .frames import FrameBlock
from .j1939 import pgn, source_address
from .mapping import UNITS, CanMapping, InputMap
from .signals import SignalLayout, signal_layout
from .units import ANGLE, CYLINDER, KIND_UNITS, PRESSURE, SI_UNIT, check_signal, input_kinds

EXACT = 1 << 53   # integers up to this are exact as float64


@dataclass(frozen=True)
class Route:
    """One mapped signal: the input it feeds, its kind, the DBC signal, the unit's factor to SI."""

    input: InputMap
    kind: str
    signal: Any          # cantools Signal
    factor: float
    topic: str           # the input's topic (JointState topic, or the pressure sensor's)

    @property
    def resolution(self) -> float:
        """The input's quantization step in SI (m, rad, Pa): one count of the DBC signal (its scale)
        through the mapping (its scale, or its table's steepest segment) and the unit's factor."""
        item = self.input
        per_count = abs(self.signal.scale) * (item.table.steepest() if item.table is not None else abs(item.scale))
        return per_count * self.factor


class Vector(NamedTuple):
    """A mapped signal read with numpy: its route, where it lies in the data, whether its raw value has
    J1939 error / not-available ranges."""

    route: Route
    layout: SignalLayout
    j1939: bool


@dataclass(frozen=True)
class MessageRoute:
    """One mapped message: its mapped signals, whether it is a J1939 parameter group, and the source
    address trusted for them."""

    message: Any         # cantools Message
    routes: tuple[Route, ...]
    j1939: bool
    vector: tuple[Vector, ...] | None   # its signals read with numpy; None: decoded one frame at a time
    source_address: int | None = None    # J1939: the one ECU trusted; None: any one source


class RowKeys(NamedTuple):
    """Per frame of a block: its mapped message (index into ``Routing.routes``; -1: none), whether
    a DBC knows its identifier and whether it is of a source the mapping does not trust."""

    route: np.ndarray
    known: np.ndarray
    untrusted: np.ndarray


def _vector_of(message: Any, routes: list[Route], j1939: bool) -> tuple[Vector, ...] | None:
    """The mapped signals of ``message`` as numpy reads them, or None if it cannot read one of them: a
    signal ``signals`` does not lay out, or one whose physical values are not all exact as float64
    (then ``decode``'s integer arithmetic could differ)."""
    vector = []
    for r in routes:
        layout = signal_layout(message, r.signal)
        if layout is None or (1 << r.signal.length) * abs(r.signal.scale) + abs(r.signal.offset) >= EXACT:
            return None
        vector.append(Vector(r, layout, j1939 and not r.signal.is_signed))
    return tuple(vector)


def _is_j1939(message: Any) -> bool:
    """Whether a cantools message is a J1939 parameter group (29-bit, the DBC's ProtocolType J1939)."""
    return bool(message.is_extended_frame and message.protocol == "j1939")


class Routing:
    """The routes of ``mapping`` over the DBC database ``db`` into ``mechanism``'s measurements under
    ``config`` (its topics); InputError naming the mapping key when the mapping does not fit the DBC or
    the mechanism. ``routes``: the mapped messages, one per message and trusted source address."""

    def __init__(self, db: Database, mapping: CanMapping, mechanism: Mechanism, config: MonitorConfig) -> None:
        kinds = input_kinds(mechanism)
        topic_of_sensor = {sensor: topic for topic, sensor in config.pressure_topics.items()}
        grouped: dict[tuple[str, int | None], list[Route]] = {}
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
            check_signal(where, item, kind, message, signal)
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
                Route(item, kind, signal, units[unit], topic))
        self.by_id: dict[tuple[int, bool], MessageRoute] = {}
        self.by_pgn: dict[int, dict[int | None, MessageRoute]] = {}
        self.known_ids = {(m.frame_id, m.is_extended_frame) for m in db.messages}
        self.known_pgns = {pgn(m.frame_id) for m in db.messages if _is_j1939(m)}
        self.routes: list[MessageRoute] = []
        for (name, source_address), routes in grouped.items():
            message = db.get_message_by_name(name)
            j1939 = _is_j1939(message)
            route = MessageRoute(message, tuple(routes), j1939, _vector_of(message, routes, j1939), source_address)
            self.routes.append(route)
            if j1939:
                self.by_pgn.setdefault(pgn(message.frame_id), {})[source_address] = route
            else:
                self.by_id[(message.frame_id, message.is_extended_frame)] = route

    @property
    def resolutions(self) -> dict[str, tuple[str, float]]:
        """Each mapped input's name -> its kind as ``Inputs`` names it (``cylinders``, ``angles``,
        ``pressures``) and its quantization step in SI (``Route.resolution``)."""
        kinds = {ANGLE: "angles", CYLINDER: "cylinders", PRESSURE: "pressures"}
        return {r.input.name: (kinds[r.kind], r.resolution) for route in self.routes for r in route.routes}

    def route_of(self, ident: int, extended: bool) -> MessageRoute | None:
        """The mapped message of an identifier (J1939: by parameter group number and source address: the
        source's own route, else the route of any source), None if unmapped or of an untrusted source."""
        route = self.by_id.get((ident, extended))
        if route is None and extended:
            by_source = self.by_pgn.get(pgn(ident), {})
            route = by_source.get(source_address(ident), by_source.get(None))
        return route

    def untrusted(self, ident: int, extended: bool) -> bool:
        """Whether a J1939 frame is of a mapped parameter group whose inputs trust other sources only."""
        return extended and pgn(ident) in self.by_pgn and self.route_of(ident, extended) is None

    def known(self, ident: int, extended: bool) -> bool:
        """Whether a DBC knows the identifier (J1939: its parameter group number)."""
        return (ident, extended) in self.known_ids or (extended and pgn(ident) in self.known_pgns)

    def key_rows(self, block: FrameBlock) -> RowKeys:
        """Each frame's mapped message and whether a DBC knows its identifier, looked up once per
        identifier of the block."""
        keys, inverse = np.unique(block.arbitration_id * 2 + block.is_extended, return_inverse=True)
        index = {id(route): k for k, route in enumerate(self.routes)}
        route, known, untrusted = np.full(len(keys), -1, np.int64), np.zeros(len(keys), bool), np.zeros(len(keys), bool)
        for k, value in enumerate(keys.tolist()):
            ident, extended = value >> 1, bool(value & 1)
            found = self.route_of(ident, extended)
            route[k] = -1 if found is None else index[id(found)]
            known[k] = self.known(ident, extended)
            untrusted[k] = self.untrusted(ident, extended)
        inverse = inverse.ravel()
        return RowKeys(route[inverse], known[inverse], untrusted[inverse])

