"""Where frames come from: a python-can bus (``INTERFACE:CHANNEL``) or a log file read by
python-can's own readers (candump .log, .asc, .blf, ... : ``can.LogReader``); ``read_log_blocks``
reads candump logs with numpy (``candump``) in blocks of frames, the other formats through python-can."""

from __future__ import annotations

import socket
import struct
from pathlib import Path
from typing import Iterator

import can

from linkage_monitor.mechanics import InputError

from .candump import RefusedLine, read_candump
from .frames import Frame, FrameBlock, blocks_of, from_message

RECEIVE_BUFFER = 4 << 20   # bytes asked for the bus socket's receive buffer
LOG_SUFFIXES = (".log", ".asc", ".blf", ".csv", ".db", ".mf4", ".trc")


def parse_bus(spec: str) -> tuple[str, str]:
    """(interface, channel) of ``INTERFACE:CHANNEL`` (``socketcan:can0``, ``virtual:demo``,
    ``udp_multicast:239.74.163.2``); InputError if malformed or the interface is unknown."""
    interface, sep, channel = spec.partition(":")
    if not sep or not interface or not channel:
        raise InputError(f"--bus {spec!r}: expected INTERFACE:CHANNEL, e.g. socketcan:can0")
    if interface not in can.VALID_INTERFACES:
        raise InputError(f"--bus {spec!r}: python-can knows no interface '{interface}' "
                         f"(known: {', '.join(sorted(can.VALID_INTERFACES))})")
    return interface, channel


def open_bus(spec: str, **options: object) -> can.BusABC:
    """The python-can bus of ``INTERFACE:CHANNEL``; InputError saying why it cannot be opened. A socket
    bus gets a receive buffer of RECEIVE_BUFFER bytes (``receive_buffer``)."""
    interface, channel = parse_bus(spec)
    try:
        bus = can.Bus(interface=interface, channel=channel, **options)  # type: ignore[arg-type]
    except (can.CanError, OSError, ImportError, ValueError) as exc:
        raise InputError(f"--bus {spec}: cannot open ({type(exc).__name__}: {exc}); for socketcan the "
                         "interface must be up (ip link set can0 up type can bitrate 250000)") from None
    receive_buffer(bus)
    return bus


def receive_buffer(bus: can.BusABC, size: int = RECEIVE_BUFFER) -> int | None:
    """Ask for a receive buffer of ``size`` bytes on the bus's socket (socketcan: ``bus.socket``;
    udp_multicast: its multicast socket), capped by the kernel (net.core.rmem_max); the size granted,
    None for a bus without a socket. The frames wait there while the node solves: 212 kB (Linux's
    default) held ~0.1 s of a saturated bus's datagrams on udp_multicast, and the bridge lost 0.35 %
    of the frames at 8k frames/s (bench/bench_can.py)."""
    sock = _socket_of(bus)
    if sock is None:
        return None
    try:
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, size)
    except OSError:
        pass   # the default buffer stays
    return int(sock.getsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF))


def _socket_of(bus: can.BusABC) -> socket.socket | None:
    """The socket a bus receives on (socketcan: ``bus.socket``; udp_multicast: its multicast socket), None
    for a bus without one."""
    sock = getattr(bus, "socket", None) or getattr(getattr(bus, "_multicast", None), "_socket", None)
    return sock if isinstance(sock, socket.socket) else None


SO_MEMINFO = 55        # linux/socket.h (Linux >= 4.6): a socket's memory counters, u32 each ...
SK_MEMINFO_DROPS = 8   # ... of which this one counts what the kernel dropped at it (receive buffer full)


class DropCount:
    """The frames the kernel dropped at a bus's socket because its receive buffer was full (the bridge
    did not read fast enough): SO_MEMINFO's drop count, for every kind of socket (a raw CAN socket, the
    UDP socket of udp_multicast: one frame a datagram). ``known`` is False for a bus without a socket
    (python-can's virtual bus queues without limit) or a kernel without SO_MEMINFO."""

    def __init__(self, bus: can.BusABC) -> None:
        self._socket = _socket_of(bus)
        start = self._read()
        self.known = start is not None
        self._seen = start or 0

    def _read(self) -> int | None:
        if self._socket is None:
            return None
        try:
            counters = self._socket.getsockopt(socket.SOL_SOCKET, SO_MEMINFO, 4 * (SK_MEMINFO_DROPS + 1))
        except OSError:
            return None
        return int(struct.unpack_from(f"{SK_MEMINFO_DROPS + 1}I", counters)[SK_MEMINFO_DROPS])

    def new(self) -> int:
        """The frames dropped since the last call (since the bus opened at the first), 0 if not known."""
        now = self._read()
        if now is None:
            return 0
        dropped = (now - self._seen) % (1 << 32)   # the kernel's counter is 32 bits and wraps
        self._seen = now
        return dropped


def _checked_log(path: str | Path) -> Path:
    """``path`` if it is a log file of a format python-can reads; InputError saying why not."""
    path = Path(path)
    if not path.is_file():
        raise InputError(f"CAN log {path}: no such file")
    if path.suffix.lower() not in LOG_SUFFIXES:
        raise InputError(f"CAN log {path}: unknown format '{path.suffix}' (python-can reads "
                         f"{', '.join(LOG_SUFFIXES)})")
    return path


def read_log_blocks(path: str | Path, refused: list[RefusedLine]) -> Iterator[FrameBlock]:
    """The frames of a log file in file order, in blocks: a candump ``.log`` read with numpy
    (``candump.read_candump``, python-can's reading of every line; a line it cannot read appended to
    ``refused``, the others read on), other formats by ``read_log``. InputError for a missing file or
    an unknown format at once; for a file python-can's reader of another format gives up on, when reached."""
    path = _checked_log(path)
    if path.suffix.lower() != ".log":
        return blocks_of(read_log(path))
    return read_candump(path, refused)


def read_log(path: str | Path) -> Iterator[Frame]:
    """The frames of a log file in file order (python-can's LogReader picks the reader by suffix)."""
    path = _checked_log(path)
    try:
        with can.LogReader(str(path)) as reader:
            for msg in reader:
                yield from_message(msg)
    except (ValueError, can.CanError, IndexError, KeyError) as exc:
        raise InputError(f"CAN log {path}: unreadable ({type(exc).__name__}: {exc})") from None


def read_bag_frames(path: str | Path, topic: str) -> Iterator[Frame]:
    """The raw frames a bag recorded on ``topic`` (can_msgs/msg/Frame), in recording order; InputError
    if it holds none."""
    from linkage_monitor.bag.reader import read_bag_raw

    from .frame_msg import FRAME_TYPE, from_cdr

    found = False
    for raw in read_bag_raw(path, topics=[topic]):
        if raw.type_name == FRAME_TYPE:
            found = True
            yield from_cdr(raw.data)
    if not found:
        raise InputError(f"bag {path} holds no {FRAME_TYPE} on {topic}: it was not recorded from CAN frames")
