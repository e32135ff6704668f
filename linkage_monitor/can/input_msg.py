"""The CDR bytes of the sensor messages a decoded frame stands for, as recorded in the bag:
sensor_msgs/msg/JointState (header, name[], position[] rad / m, velocity[] and effort[] empty)
and sensor_msgs/msg/FluidPressure (header, fluid_pressure Pa, variance 0 = unknown).

Laid out in little-endian CDR field by field from the two definitions, padding zeroed, frame_id
empty (the bag's replay reads them with ``wire.sensor_messages`` as the node's inputs; the tests
compare them with rclpy's serialization). The header stamp is the frame's.
"""

from __future__ import annotations

import struct
from typing import Sequence

NS = 1_000_000_000
_CDR_LE = b"\x00\x01\x00\x00"
_HEADER = struct.Struct("<iII")    # stamp sec, nanosec, frame_id length (1: the empty string's NUL)


def _header(stamp_ns: int) -> bytes:
    sec, nanosec = divmod(stamp_ns, NS)
    return _HEADER.pack(sec, nanosec, 1) + b"\0"


def joint_state_cdr(stamp_ns: int, names: Sequence[str], positions: Sequence[float]) -> bytes:
    """sensor_msgs/JointState of ``names`` at ``positions`` (rad / m), no velocities or efforts."""
    body = bytearray(_header(stamp_ns))
    body += bytes(-len(body) % 4) + struct.pack("<I", len(names))
    for name in names:
        text = name.encode() + b"\0"
        body += bytes(-len(body) % 4) + struct.pack("<I", len(text)) + text
    body += bytes(-len(body) % 4) + struct.pack("<I", len(positions))
    if positions:
        body += bytes(-len(body) % 8) + struct.pack(f"<{len(positions)}d", *positions)
    body += bytes(-len(body) % 4) + struct.pack("<II", 0, 0)   # velocity[], effort[]: empty
    return _CDR_LE + bytes(body)


def fluid_pressure_cdr(stamp_ns: int, pascal: float) -> bytes:
    """sensor_msgs/FluidPressure of ``pascal`` (Pa), variance 0 (unknown)."""
    body = bytearray(_header(stamp_ns))
    body += bytes(-len(body) % 8) + struct.pack("<dd", pascal, 0.0)
    return _CDR_LE + bytes(body)
