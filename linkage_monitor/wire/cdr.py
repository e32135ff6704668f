"""Writing and reading CDR: the serialized form in which ROS 2 messages travel and are recorded.

Plain little-endian CDR (XCDR1, encapsulation 0x0001), as rmw_fastrtps publishes and rosbag2
records: every primitive is aligned to its own size, counted from the first byte after the
4-byte encapsulation header; a string is a uint32 length (bytes + 1) followed by its UTF-8
bytes and a NUL; a sequence is a uint32 count followed by its elements.

``Writer`` holds the payload that ``wire.compose`` writes by a message's layout (the field order
is never written here). ``Reader`` takes the primitives back out of a payload, checked at every
step (``CdrError`` names what is cut off or malformed), for the few input messages the monitor
reads itself (``wire.sensor_messages``).
"""

from __future__ import annotations

import functools
import struct
from typing import Any

from linkage_monitor.mechanics.errors import InputError

ENCAPSULATION = b"\x00\x01\x00\x00"   # CDR little endian, no options
_U32, _F64, _STAMP = struct.Struct("<I"), struct.Struct("<d"), struct.Struct("<iI")
_BIG_ENDIAN = struct.Struct(">I"), struct.Struct(">iI"), struct.Struct(">d")
_NS = 1_000_000_000


class Writer:
    """Appends CDR to ``data`` (a payload that starts with the encapsulation header); ``padding``
    keeps the (start, end) of every run of alignment padding it wrote (zeros)."""

    def __init__(self, data: bytearray | None = None) -> None:
        self.data = data if data is not None else bytearray(ENCAPSULATION)
        self.padding: list[tuple[int, int]] = []

    def align(self, size: int) -> None:
        """Pad with zeros to a multiple of ``size`` bytes from the payload start."""
        pad = (len(ENCAPSULATION) - len(self.data)) % size
        if pad:
            self.padding.append((len(self.data), len(self.data) + pad))
            self.data += bytes(pad)

    def uint32(self, value: int) -> None:
        """A uint32 (a string length or sequence count)."""
        self.align(4)
        self.data += _U32.pack(value)


class CdrError(ValueError):
    """A payload that is not the CDR of the expected message: says what is wrong and where."""


TIME_SECONDS = (-2**31, 2**31 - 1)   # s, what builtin_interfaces/Time's int32 sec holds: 13 Dec 1901 to 19 Jan 2038


class StampRangeError(InputError, struct.error):
    """A stamp that no builtin_interfaces/Time holds (int32 seconds, TIME_SECONDS): names the stamp and
    the reason; a struct.error too, as struct.pack gives for the int32 it does not fit."""


def check_stamp(stamp_ns: int, what: str = "a stamp") -> int:
    """``stamp_ns`` (ns since the epoch) when a builtin_interfaces/Time holds it; StampRangeError else."""
    seconds = stamp_ns // _NS
    if not TIME_SECONDS[0] <= seconds <= TIME_SECONDS[1]:
        raise StampRangeError(
            f"{what} of {seconds} s since the epoch is outside a ROS header stamp's int32 seconds (13 Dec 1901 "
            "to 19 Jan 2038 03:14:07 UTC): correct the clock or the stamps")
    return stamp_ns


def is_xcdr1(data: bytes) -> bool:
    """Whether ``data`` is XCDR1 (encapsulation 0x0000-0x0003: plain or parameter-list CDR, big or
    little endian), what every ROS 2 middleware sends: the encodings ``Reader`` reads."""
    return len(data) >= len(ENCAPSULATION) and data[0] == 0 and data[1] <= 3


@functools.cache
def option_padding_honoured() -> bool:
    """Whether the installed middleware's CDR reader takes the last option byte's two low bits as
    padding bytes at the end of the payload (not data): Fast CDR 2.3 (Kilted) does, Fast CDR 2.2
    (Jazzy) reads the payload whole. Probed once through rclpy: a std_msgs/UInt32 whose options
    declare 3 bytes of padding, which leaves too few bytes for its field when honoured."""
    from rclpy.serialization import deserialize_message
    from std_msgs.msg import UInt32
    try:
        deserialize_message(b"\x00\x01\x00\x03\x07\x00\x00\x00", UInt32)
    except Exception:  # noqa: BLE001 - rclpy raises RMWError (or others) for bytes it cannot read
        return True
    return False


class Reader:
    """Reads XCDR1 primitives from ``data`` in order, as rmw_fastrtps (Fast CDR) deserializes them:
    encapsulation 0x0000-0x0003 (plain or parameter-list CDR, big endian when even), the last option
    byte's two low bits = padding bytes at the end of the payload (not data) where the installed
    Fast CDR takes them so (``option_padding_honoured``), every primitive aligned to its size from
    the payload start, bytes after the last field ignored."""

    def __init__(self, data: bytes) -> None:
        if len(data) < len(ENCAPSULATION):
            raise CdrError(f"{len(data)}-byte message: shorter than the {len(ENCAPSULATION)}-byte CDR header")
        if not is_xcdr1(data):
            raise CdrError(f"not XCDR1: encapsulation {bytes(data[:2]).hex() or '(none)'}, expected 0000 to 0003")
        self.order = "<" if data[1] & 1 else ">"
        self._u32, self._stamp, self._f64 = (_U32, _STAMP, _F64) if self.order == "<" else _BIG_ENDIAN
        self.data = memoryview(data)[:len(data) - (data[3] & 0x03 if option_padding_honoured() else 0)]
        self.offset = len(ENCAPSULATION)

    def _take(self, size: int, what: str, align: int) -> int:
        """Skip the padding to ``align``, check that ``size`` bytes of ``what`` follow; their offset."""
        start = self.offset + (-(self.offset - len(ENCAPSULATION)) % align)
        if start + size > len(self.data):
            raise CdrError(f"{what} at byte {start} runs past the end of the {len(self.data)}-byte message")
        self.offset = start + size
        return start

    def uint32(self, what: str) -> int:
        """A uint32 (a string length or sequence count)."""
        return int(self._u32.unpack_from(self.data, self._take(4, what, 4))[0])

    def time_ns(self, what: str = "stamp") -> int:
        """A builtin_interfaces/Time (int32 sec, uint32 nanosec) as ns since the epoch."""
        sec, nanosec = self._stamp.unpack_from(self.data, self._take(8, what, 4))
        return int(sec) * _NS + int(nanosec)   # as stamp_ns of a decoded header

    def string(self, what: str) -> str:
        """A string: its length counts the NUL (length 0: empty); cut at the first NUL, invalid UTF-8
        replaced (as rclpy)."""
        size = self.uint32(f"length of {what}")
        start = self._take(size, what, 1)
        return self.data[start:start + size].tobytes().split(b"\x00", 1)[0].decode("utf-8", "replace")

    def strings(self, what: str) -> list[str]:
        """A sequence<string>."""
        count = self.uint32(f"count of {what}")
        if 4 * count > len(self.data) - self.offset:   # a string takes at least its length
            raise CdrError(f"{what}: {count} strings cannot fit in the {len(self.data)}-byte message")
        return [self.string(f"{what}[{k}]") for k in range(count)]

    def float64(self, what: str) -> float:
        """A float64."""
        return float(self._f64.unpack_from(self.data, self._take(8, what, 8))[0])

    def float64_array(self, what: str, count: int) -> tuple[float, ...]:
        """A float64[count] (a fixed array: no count on the wire)."""
        return struct.unpack_from(f"{self.order}{count}d", self.data, self._take(8 * count, f"{what} ({count} values)", 8))

    def float64s(self, what: str) -> tuple[float, ...]:
        """A sequence<float64> (not aligned when it is empty, as Fast CDR)."""
        count = self.uint32(f"count of {what}")
        if not count:
            return ()
        return struct.unpack_from(f"{self.order}{count}d", self.data, self._take(8 * count, f"{what} ({count} values)", 8))


def time_bytes(stamp_ns: int) -> bytes:
    """The 8 bytes of a builtin_interfaces/Time of ``stamp_ns`` ns (StampRangeError beyond int32 seconds)."""
    return _STAMP.pack(*stamp_fields(stamp_ns))


def string_bytes(text: str) -> bytes:
    """A CDR string after its alignment: uint32 length with the NUL, UTF-8 bytes, NUL (cut at an
    embedded NUL, as rclpy does)."""
    raw = text.split("\x00", 1)[0].encode("utf-8")
    return _U32.pack(len(raw) + 1) + raw + b"\x00"


def stamp_fields(stamp_ns: int) -> tuple[int, int]:
    """builtin_interfaces/Time (sec, nanosec) of a stamp in ns since the epoch (sec rounds down);
    StampRangeError beyond its int32 seconds."""
    check_stamp(stamp_ns)
    return stamp_ns // _NS, stamp_ns % _NS


def stamp_ns(msg_header: Any) -> int:
    """The stamp of a std_msgs/Header (an rclpy or rosbags message) in ns since the epoch: the
    inverse of ``stamp_fields``."""
    return int(msg_header.stamp.sec) * _NS + int(msg_header.stamp.nanosec)
