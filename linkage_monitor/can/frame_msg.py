"""can_msgs/msg/Frame (ros2_socketcan's /from_can_bus) <-> Frame.

The message (interfaces/can_msgs/msg/Frame.msg): std_msgs/Header header (stamp, frame_id),
uint32 id, bool is_rtr, bool is_extended, bool is_error, uint8 dlc, uint8[8] data (the first dlc
bytes are the frame's). ``to_cdr`` lays it out in little-endian CDR field by field from that
definition, padding zeroed (rclpy's serializer leaves the padding after the header's frame_id
uninitialised: the same frame would be recorded as different bytes); read back with rclpy.
``frames_cdr`` writes the same bytes for a whole FrameBlock at once, laid out by ``wire.compose`` from
the installed definition (``FRAME_LAYOUT``): one row per frame.
"""

from __future__ import annotations

import functools
import struct
from typing import NamedTuple

import numpy as np
from can_msgs.msg import Frame as FrameMsg
from rclpy.serialization import deserialize_message

from linkage_monitor.wire.cdr import check_stamp
from linkage_monitor.wire.compose import STAMP, Composer, Flag
from linkage_monitor.wire.layout import PRIMITIVES, layout

from .frames import Frame, FrameBlock

FRAME_TYPE = "can_msgs/msg/Frame"
NS = 1_000_000_000
_CDR_LE = b"\x00\x01\x00\x00"                 # encapsulation: plain CDR, little endian
_BODY = struct.Struct("<I???B8s")                # id, is_rtr, is_extended, is_error, dlc, data[8]


def to_msg(frame: Frame) -> FrameMsg:
    """The can_msgs/Frame of a frame (stamp in the header)."""
    msg = FrameMsg(id=frame.arbitration_id, is_rtr=frame.is_remote, is_extended=frame.is_extended,
                   is_error=frame.is_error, dlc=frame.dlc, data=list((frame.data + bytes(8))[:8]))
    msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(frame.stamp_ns, NS)
    return msg


def to_cdr(frame: Frame, frame_id: str = "") -> bytes:
    """The CDR bytes of the frame's can_msgs/Frame (header stamp = the frame's, ``frame_id``)."""
    sec, nanosec = divmod(frame.stamp_ns, NS)
    name = frame_id.encode() + b"\0"
    head = struct.pack("<iII", sec, nanosec, len(name)) + name
    return b"".join((_CDR_LE, head, bytes(-len(head) % 4),
                     _BODY.pack(frame.arbitration_id, frame.is_remote, frame.is_extended, frame.is_error, frame.dlc,
                                frame.data[:8])))


def from_msg(msg: FrameMsg) -> Frame:
    """The frame of a can_msgs/Frame (its header stamp, the first dlc data bytes)."""
    stamp = msg.header.stamp.sec * NS + msg.header.stamp.nanosec
    dlc = int(msg.dlc)
    return Frame(stamp, int(msg.id), bool(msg.is_extended), bool(msg.is_rtr), bool(msg.is_error), dlc,
                 bytes(msg.data.tobytes()[:min(dlc, 8)]))


def from_cdr(data: bytes) -> Frame:
    """The frame of a can_msgs/Frame's CDR bytes (rclpy raises on bytes that are not one)."""
    return from_msg(deserialize_message(data, FrameMsg))


class FieldSlot(NamedTuple):
    """Where a primitive field of a fixed layout lies: its byte offset from the encapsulation header's
    start, its primitive kind (``wire.layout.PRIMITIVES``) and its elements (1, or a fixed array's length)."""

    offset: int
    kind: str
    elements: int


class FixedLayout(NamedTuple):
    """A message of fixed size as a template: its bytes with every field zero (strings as given), the
    byte offset of its header stamp, and the slot of each field filled per message (by field name)."""

    template: bytes
    stamp: int
    slots: dict[str, FieldSlot]


@functools.cache
def frame_layout() -> FixedLayout:
    """can_msgs/msg/Frame laid out by its installed definition (empty frame_id): every field but the
    header is a slot."""
    fields = [f for f in layout(FRAME_TYPE).fields if f.name != "header"]
    values: dict[str, object] = {"header": {"stamp": STAMP, "frame_id": ""}}
    at = 0
    for f in fields:
        values[f.name] = Flag(at) if f.array is None else [Flag(at + k) for k in range(f.array)]
        at += 1 if f.array is None else f.array
    composer = Composer(strict=True).message(FRAME_TYPE, values)
    [stamp] = composer.stamps
    offset = dict((flag, offset) for offset, flag in composer.flags)
    slots, at = {}, 0
    for f in fields:
        slots[f.name] = FieldSlot(offset[at], f.kind, 1 if f.array is None else f.array)
        at += slots[f.name].elements
    return FixedLayout(bytes(composer.data), stamp, slots)


def put_stamps(rows: np.ndarray, offset: int, stamp_ns: np.ndarray) -> None:
    """builtin_interfaces/Time of each ``stamp_ns`` (ns since the epoch; sec rounds down) at byte ``offset``
    of each row; StampRangeError (a struct.error) beyond int32 seconds, naming the stamp."""
    if len(stamp_ns):
        check_stamp(int(np.min(stamp_ns)), "a frame's stamp")
        check_stamp(int(np.max(stamp_ns)), "a frame's stamp")
    sec, nanosec = np.divmod(np.asarray(stamp_ns, np.int64), NS)
    put(rows, FieldSlot(offset, "int32", 1), sec)
    put(rows, FieldSlot(offset + 4, "uint32", 1), nanosec)


def put(rows: np.ndarray, slot: FieldSlot, values: np.ndarray) -> None:
    """``values`` ((n,) or (n, elements)) written into ``slot`` of each row as its kind, little endian;
    struct.error for an integer outside its kind's range, as struct.pack."""
    fmt, size = PRIMITIVES[slot.kind]
    dtype = np.dtype("<" + fmt)
    values = np.asarray(values)
    if dtype.kind in "iu" and values.size:
        info = np.iinfo(dtype)
        if values.min() < info.min or values.max() > info.max:
            raise struct.error(f"'{fmt}' format requires {info.min} <= number <= {info.max}")
    n = len(rows)
    rows[:, slot.offset:slot.offset + size * slot.elements] = \
        np.ascontiguousarray(values.reshape(n, slot.elements), dtype=dtype).view(np.uint8)


def frames_cdr(block: FrameBlock) -> np.ndarray:
    """The CDR bytes of each frame's can_msgs/Frame (empty frame_id) as the rows of an (n, size) uint8
    array: the bytes ``to_cdr`` gives, frame for frame."""
    fixed = frame_layout()
    rows = np.empty((len(block), len(fixed.template)), np.uint8)
    rows[:] = np.frombuffer(fixed.template, np.uint8)
    put_stamps(rows, fixed.stamp, block.stamp_ns)
    slots = fixed.slots
    put(rows, slots["id"], block.arbitration_id)
    put(rows, slots["is_rtr"], block.is_remote)
    put(rows, slots["is_extended"], block.is_extended)
    put(rows, slots["is_error"], block.is_error)
    put(rows, slots["dlc"], block.dlc)
    put(rows, slots["data"], block.data[:, :slots["data"].elements])
    return rows
