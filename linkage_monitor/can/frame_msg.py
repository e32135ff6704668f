"""can_msgs/msg/Frame (ros2_socketcan's /from_can_bus) <-> Frame.

The message (interfaces/can_msgs/msg/Frame.msg): std_msgs/Header header (stamp, frame_id),
uint32 id, bool is_rtr, bool is_extended, bool is_error, uint8 dlc, uint8[8] data (the first dlc
bytes are the frame's). ``to_cdr`` lays it out in little-endian CDR field by field from that
definition, padding zeroed (rclpy's serializer leaves the padding after the header's frame_id
uninitialised: the same frame would be recorded as different bytes); read back with rclpy.
"""

from __future__ import annotations

import struct

from can_msgs.msg import Frame as FrameMsg
from rclpy.serialization import deserialize_message

from .frames import Frame

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
