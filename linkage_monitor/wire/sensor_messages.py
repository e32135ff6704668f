"""The monitor's two input messages read straight from their CDR bytes (live node and replay).

sensor_msgs/JointState (positions: rad for revolute joints, m for cylinder strokes; velocities
rad/s, m/s) and sensor_msgs/FluidPressure (Pa) are read field by field by their layouts
(``wire.read``) instead of rclpy's ``deserialize_message``: the same values (test_sensor_messages.py compares
both on generated and on damaged messages), without building an rclpy message object, which
costs 12 µs in a loop and 170–240 µs after the few milliseconds of idle between two sensor
messages on these machines (docs/performance.md, ninth session). A message that is not the
CDR of its type raises ``CdrError`` naming the field and the byte. The rare XCDR2 payload
(alignment and headers of its own) is left to rclpy, imported then (the wire layer does not import
rclpy otherwise).
"""

from __future__ import annotations

import importlib
from typing import Any, Callable, NamedTuple

from .cdr import CdrError, is_xcdr1, stamp_ns
from .read import read_message

JOINT_STATE = "sensor_msgs/msg/JointState"
FLUID_PRESSURE = "sensor_msgs/msg/FluidPressure"


class JointStateReading(NamedTuple):
    """A sensor_msgs/JointState: header stamp (ns since the epoch), joint names, positions
    (rad / m) and velocities (rad/s / m/s; may be empty). Efforts are read (checked) but not kept."""

    stamp_ns: int
    names: list[str]
    position: tuple[float, ...]
    velocity: tuple[float, ...]


class FluidPressureReading(NamedTuple):
    """A sensor_msgs/FluidPressure: header stamp (ns since the epoch) and fluid_pressure (Pa)."""

    stamp_ns: int
    fluid_pressure: float


def read_joint_state(data: bytes) -> JointStateReading:
    """The JointState in ``data`` (its CDR bytes); CdrError if they are not one."""
    if len(data) >= 4 and not is_xcdr1(data):
        msg = _rclpy(data, JOINT_STATE)
        return JointStateReading(stamp_ns(msg.header), list(msg.name), tuple(msg.position), tuple(msg.velocity))
    m = read_message(JOINT_STATE, data)
    return JointStateReading(m["header.stamp"], m["name"], m["position"], m["velocity"])


def read_fluid_pressure(data: bytes) -> FluidPressureReading:
    """The FluidPressure in ``data`` (its CDR bytes); CdrError if they are not one."""
    if len(data) >= 4 and not is_xcdr1(data):
        msg = _rclpy(data, FLUID_PRESSURE)
        return FluidPressureReading(stamp_ns(msg.header), float(msg.fluid_pressure))
    m = read_message(FLUID_PRESSURE, data)
    return FluidPressureReading(m["header.stamp"], m["fluid_pressure"])


def _rclpy(data: bytes, type_name: str) -> Any:
    """rclpy's reading of a payload ``read_message`` does not read (XCDR2); its refusal as a CdrError."""
    from rclpy.serialization import deserialize_message
    package, _, name = type_name.split("/")
    try:
        return deserialize_message(data, getattr(importlib.import_module(f"{package}.msg"), name))
    except Exception as exc:  # noqa: BLE001 - rclpy raises RMWError and others for bytes it cannot read
        raise CdrError(f"{str(exc).splitlines()[0] if str(exc) else type(exc).__name__} "
                       f"(encapsulation {bytes(data[:2]).hex() or '(none)'})") from None


def read_input(type_name: str, data: bytes) -> JointStateReading | FluidPressureReading:
    """The input message of type ``type_name`` (JOINT_STATE or FLUID_PRESSURE) in ``data``; CdrError
    for bytes that do not read as it, whatever the reason (an unexpected one named by its type)."""
    read = _READERS[type_name]
    try:
        return read(data)
    except CdrError:
        raise
    except Exception as exc:  # noqa: BLE001 - bytes that break the reader otherwise: the input's fault all the same
        raise CdrError(f"{type(exc).__name__}: {exc}") from exc


_READERS: dict[str, Callable[[bytes], JointStateReading | FluidPressureReading]] = {
    JOINT_STATE: read_joint_state, FLUID_PRESSURE: read_fluid_pressure}
