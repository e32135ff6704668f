"""One CAN frame as the bridge sees it, whatever it came from (a bus, a log, a can_msgs/Frame).

Stamps are ns since the epoch at µs resolution: the resolution of candump logs and of the
frames' kernel timestamps as python-can reports them in float seconds; rounding every source to
the µs gives a frame the same stamp whether it was received live, written to a log or recorded
as can_msgs/msg/Frame, so the inputs decoded from it are the same.
"""

from __future__ import annotations

from dataclasses import dataclass

import can

US = 1_000


@dataclass(frozen=True, slots=True)
class Frame:
    """A classic CAN frame: stamp (ns since the epoch), identifier (11 or 29 bit), flags, the
    data length code and the data bytes (``dlc`` of them for a data frame)."""

    stamp_ns: int
    arbitration_id: int
    is_extended: bool
    is_remote: bool
    is_error: bool
    dlc: int
    data: bytes


def stamp_of(seconds: float) -> int:
    """ns since the epoch of a python-can timestamp (float s), rounded to the µs."""
    return round(seconds * 1e6) * US


def from_message(msg: can.Message) -> Frame:
    """The Frame of a python-can message (bus or log reader)."""
    return Frame(stamp_of(msg.timestamp), int(msg.arbitration_id), bool(msg.is_extended_id),
                 bool(msg.is_remote_frame), bool(msg.is_error_frame), int(msg.dlc), bytes(msg.data))


def to_message(frame: Frame) -> can.Message:
    """The python-can message of a Frame (for python-can's log writers and buses)."""
    return can.Message(timestamp=frame.stamp_ns / 1e9, arbitration_id=frame.arbitration_id,
                       is_extended_id=frame.is_extended, is_remote_frame=frame.is_remote,
                       is_error_frame=frame.is_error, dlc=frame.dlc, data=frame.data, check=False)
