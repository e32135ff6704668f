"""The CDR bytes of the sensor messages a decoded frame stands for, as recorded in the bag:
sensor_msgs/msg/JointState (header, name[], position[] rad / m, velocity[] and effort[] empty)
and sensor_msgs/msg/FluidPressure (header, fluid_pressure Pa, variance 0 = unknown).

Laid out in little-endian CDR field by field from the two definitions, padding zeroed, frame_id
empty (the bag's replay reads them with ``wire.sensor_messages`` as the node's inputs; the tests
compare them with rclpy's serialization). The header stamp is the frame's.

``joint_states_cdr`` and ``fluid_pressures_cdr`` write the same bytes for many decoded frames at once:
the message laid out once by ``wire.compose`` from the installed definition (a ``wire.template``
Template), each frame's stamp and values filled in, one row per message.
"""

from __future__ import annotations

import functools
import struct
from typing import Sequence

import numpy as np

from linkage_monitor.wire.compose import STAMP, Column, Composer
from linkage_monitor.wire.sensor_messages import FLUID_PRESSURE, JOINT_STATE
from linkage_monitor.wire.template import Template

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


_HEADER_VALUES = {"stamp": STAMP, "frame_id": ""}


@functools.lru_cache(maxsize=None)
def joint_state_template(names: tuple[str, ...]) -> Template:
    """sensor_msgs/JointState of ``names``, a position slot per name, no velocities or efforts."""
    composer = Composer(strict=True).message(JOINT_STATE, {
        "header": _HEADER_VALUES, "name": list(names), "position": [Column(k) for k in range(len(names))],
        "velocity": [], "effort": []})
    return Template.of(composer)


@functools.cache
def fluid_pressure_template() -> Template:
    """sensor_msgs/FluidPressure with a fluid_pressure slot, variance 0 (unknown)."""
    composer = Composer(strict=True).message(FLUID_PRESSURE, {
        "header": _HEADER_VALUES, "fluid_pressure": Column(0), "variance": 0.0})
    return Template.of(composer)


def joint_states_cdr(stamps_ns: np.ndarray, names: tuple[str, ...], positions: np.ndarray) -> np.ndarray:
    """``joint_state_cdr`` of each row: stamps (n,) ns, positions (n, len(names)) rad / m; an (n, size)
    uint8 array, one message per row."""
    return joint_state_template(names).fill_rows(stamps_ns, positions)


def fluid_pressures_cdr(stamps_ns: np.ndarray, pascal: np.ndarray) -> np.ndarray:
    """``fluid_pressure_cdr`` of each value: stamps (n,) ns, pascal (n,) Pa; an (n, size) uint8 array."""
    return fluid_pressure_template().fill_rows(stamps_ns, np.asarray(pascal, float)[:, None])
