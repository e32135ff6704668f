"""The monitor's input messages read straight from their CDR bytes into the core's input
events (live node and replay).

sensor_msgs/JointState (positions: rad for revolute joints, m for cylinder strokes; velocities
rad/s, m/s) becomes a ``JointStateEvent``, sensor_msgs/FluidPressure (Pa) a ``PressureEvent``,
sensor_msgs/Imu (m/s², rad/s; the tractor body's, optional) an ``ImuEvent`` (``monitoring.events``). They are read by their layouts (``wire.read``: field by field, or at once
by the shape of a message of the sensor before) instead of rclpy's ``deserialize_message``: the same values (test_sensor_messages.py compares both on
generated and on damaged messages), without building an rclpy message object, which costs
12 µs in a loop and 170–240 µs after the few milliseconds of idle between two sensor messages
(docs/performance.md). A message that is not the CDR of its type raises ``CdrError`` naming the
field and the byte (``input_event`` makes it an ``UnreadableEvent``). The rare XCDR2 payload
(alignment and headers of its own) is left to rclpy, imported then (the wire layer does not
import rclpy otherwise).
"""

from __future__ import annotations

import importlib
from typing import Any, Callable, Union

from linkage_monitor.monitoring.events import ImuEvent, InputEvent, JointStateEvent, PressureEvent, UnreadableEvent

from .cdr import CdrError, is_xcdr1, stamp_ns
from .read import read_message

JOINT_STATE = "sensor_msgs/msg/JointState"
FLUID_PRESSURE = "sensor_msgs/msg/FluidPressure"
IMU = "sensor_msgs/msg/Imu"
SensorEvent = Union[JointStateEvent, PressureEvent, ImuEvent]


def read_joint_state(data: bytes, topic: str, receive_ns: int) -> JointStateEvent:
    """The JointState in ``data`` (its CDR bytes), received on ``topic`` at ``receive_ns`` (ns);
    CdrError if the bytes are not one. Efforts are read (checked) but not kept."""
    if len(data) >= 4 and not is_xcdr1(data):
        msg = _rclpy(data, JOINT_STATE)
        return JointStateEvent(topic=topic, names=list(msg.name), positions=tuple(msg.position),
                               velocities=tuple(msg.velocity), stamp_ns=stamp_ns(msg.header), receive_ns=receive_ns)
    m = read_message(JOINT_STATE, data)
    return JointStateEvent(topic=topic, names=m["name"], positions=m["position"], velocities=m["velocity"],
                           stamp_ns=m["header.stamp"], receive_ns=receive_ns)


def read_fluid_pressure(data: bytes, topic: str, receive_ns: int) -> PressureEvent:
    """The FluidPressure in ``data`` (its CDR bytes), received on ``topic`` at ``receive_ns`` (ns);
    CdrError if the bytes are not one."""
    if len(data) >= 4 and not is_xcdr1(data):
        msg = _rclpy(data, FLUID_PRESSURE)
        return PressureEvent(topic=topic, fluid_pressure=float(msg.fluid_pressure), stamp_ns=stamp_ns(msg.header),
                             receive_ns=receive_ns)
    m = read_message(FLUID_PRESSURE, data)
    return PressureEvent(topic=topic, fluid_pressure=m["fluid_pressure"], stamp_ns=m["header.stamp"],
                         receive_ns=receive_ns)


def read_imu(data: bytes, topic: str, receive_ns: int) -> ImuEvent:
    """The Imu in ``data`` (its CDR bytes), received on ``topic`` at ``receive_ns`` (ns); CdrError if the
    bytes are not one. Only its frame, linear_acceleration.z and angular_velocity.y are kept."""
    if len(data) >= 4 and not is_xcdr1(data):
        msg = _rclpy(data, IMU)
        return ImuEvent(topic=topic, frame_id=msg.header.frame_id, specific_force_z=float(msg.linear_acceleration.z),
                        rate_y=float(msg.angular_velocity.y), stamp_ns=stamp_ns(msg.header), receive_ns=receive_ns)
    m = read_message(IMU, data)
    return ImuEvent(topic=topic, frame_id=m["header.frame_id"], specific_force_z=m["linear_acceleration.z"],
                    rate_y=m["angular_velocity.y"], stamp_ns=m["header.stamp"], receive_ns=receive_ns)


def _rclpy(data: bytes, type_name: str) -> Any:
    """rclpy's reading of a payload ``read_message`` does not read (XCDR2); its refusal as a CdrError."""
    from rclpy.serialization import deserialize_message
    package, _, name = type_name.split("/")
    try:
        return deserialize_message(data, getattr(importlib.import_module(f"{package}.msg"), name))
    except Exception as exc:  # noqa: BLE001 - rclpy raises RMWError and others for bytes it cannot read
        raise CdrError(f"{str(exc).splitlines()[0] if str(exc) else type(exc).__name__} "
                       f"(encapsulation {bytes(data[:2]).hex() or '(none)'})") from None


def read_input(type_name: str, data: bytes, topic: str, receive_ns: int) -> SensorEvent:
    """The input message of type ``type_name`` (JOINT_STATE, FLUID_PRESSURE or IMU) in ``data``, received on
    ``topic`` at ``receive_ns`` (ns); CdrError for bytes that do not read as it, whatever the reason
    (an unexpected one named by its type)."""
    read = _READERS[type_name]
    try:
        return read(data, topic, receive_ns)
    except CdrError:
        raise
    except Exception as exc:  # noqa: BLE001 - bytes that break the reader otherwise: the input's fault all the same
        raise CdrError(f"{type(exc).__name__}: {exc}") from exc


def input_event(type_name: str, data: bytes, topic: str, receive_ns: int) -> InputEvent:
    """``read_input``, or for bytes that do not read as ``type_name`` the UnreadableEvent saying why."""
    try:
        return read_input(type_name, data, topic, receive_ns)
    except CdrError as exc:
        return UnreadableEvent(topic=topic, type_name=type_name, size=len(data), reason=str(exc), receive_ns=receive_ns)


_READERS: dict[str, Callable[[bytes, str, int], SensorEvent]] = {
    JOINT_STATE: read_joint_state, FLUID_PRESSURE: read_fluid_pressure, IMU: read_imu}
