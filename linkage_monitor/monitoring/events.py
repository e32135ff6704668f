"""The events the monitoring core takes: one type per input message, and a configuration change.

The drivers build them: the live node and the replay read them from the inputs' CDR bytes
(``wire.sensor_messages``), the CAN bridge decodes them from frames (``can.decoder``), the tests
and benches write them directly. Every input event carries its topic, its header stamp and its
receive time (ns since the epoch, the monitor's clock); values in SI units.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence, Union

from .config import MonitorConfig


# built per input event: a plain dataclass, not a frozen one (docs/architecture.md, One pipeline)
@dataclass
class JointStateEvent:
    """A sensor_msgs/JointState: joint names, positions (rad for revolute joints, m for cylinder
    lengths), velocities (rad/s, m/s; may be empty), header stamp and receive time (ns)."""

    topic: str
    names: Sequence[str]
    positions: Sequence[float]
    velocities: Sequence[float]
    stamp_ns: int
    receive_ns: int


# built per input event: a plain dataclass, not a frozen one (docs/architecture.md, One pipeline)
@dataclass
class PressureEvent:
    """A sensor_msgs/FluidPressure: fluid_pressure (Pa), header stamp and receive time (ns)."""

    topic: str
    fluid_pressure: float
    stamp_ns: int
    receive_ns: int


# built per input event: a plain dataclass, not a frozen one (docs/architecture.md, One pipeline)
@dataclass
class ImuEvent:
    """A sensor_msgs/Imu on the tractor's body (REP 103 axes: x forward, y left, z up): its frame_id,
    the specific force along z (m/s², +g at rest) and the angular velocity about y (rad/s), header
    stamp and receive time (ns). The other components are not used (``mechanics.dynamics``)."""

    topic: str
    frame_id: str
    specific_force_z: float
    rate_y: float
    stamp_ns: int
    receive_ns: int


@dataclass(frozen=True)
class UnreadableEvent:
    """An input message whose bytes are not its type: ``size`` (bytes), ``reason`` (what is wrong,
    where). The header being unreadable, its stamp is its receive time (ns)."""

    topic: str
    type_name: str
    size: int
    reason: str
    receive_ns: int

    @property
    def stamp_ns(self) -> int:
        """The receive time (ns): the stamp of an input whose header cannot be read."""
        return self.receive_ns


@dataclass(frozen=True)
class ConfigEvent:
    """The configuration changed (runtime parameters); applies to the events after it."""

    config: MonitorConfig


InputEvent = Union[JointStateEvent, PressureEvent, ImuEvent, UnreadableEvent]
Event = Union[InputEvent, ConfigEvent]
