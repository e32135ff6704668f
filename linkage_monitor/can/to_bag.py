"""A CAN log -> a rosbag2 bag of the monitor's inputs, for ``linkage-monitor replay``.

The bag holds what the live bridge (``linkage-monitor can``) records of the same frames: every
raw frame as can_msgs/msg/Frame (on ``raw_topic``, so the bag can be decoded again with a
corrected DBC or mapping), the inputs decoded from it (sensor_msgs/JointState,
sensor_msgs/FluidPressure, stamped with the frame's stamp), the mechanism description and the
monitor's configuration. Receive time = the frame's stamp (the log's own time), so the replay's
stamp check judges the inputs against the time they were logged.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Iterable

from linkage_monitor.bag.step_recorder import StepRecorder
from linkage_monitor.bag.writer import BagWriter
from linkage_monitor.mechanics import Mechanism
from linkage_monitor.monitoring.config import MonitorConfig
from linkage_monitor.monitoring.events import InputEvent, JointStateEvent, PressureEvent
from linkage_monitor.monitoring.findings import Finding
from linkage_monitor.wire.sensor_messages import FLUID_PRESSURE, JOINT_STATE

from .decoder import CanDecoder, FrameCounts
from .frame_msg import FRAME_TYPE, to_cdr
from .frames import Frame
from .input_msg import fluid_pressure_cdr, joint_state_cdr

RAW_TOPIC = "/from_can_bus"
"""Topic of the raw frames (can_msgs/msg/Frame), ros2_socketcan's default."""


def input_record(event: InputEvent) -> tuple[str, bytes]:
    """(type name, CDR bytes) of the sensor message a decoded input event stands for."""
    if isinstance(event, JointStateEvent):
        return JOINT_STATE, joint_state_cdr(event.stamp_ns, event.names, event.positions)
    assert isinstance(event, PressureEvent)
    return FLUID_PRESSURE, fluid_pressure_cdr(event.stamp_ns, event.fluid_pressure)


@dataclass(frozen=True)
class Converted:
    """What a conversion did: the frame counts, the refusals (finding per refused frame, in order)."""

    counts: FrameCounts
    refusals: list[Finding]


def can_to_bag(frames: Iterable[Frame], decoder: CanDecoder, description: Mechanism, config: MonitorConfig,
               out: Path, raw_topic: str = RAW_TOPIC) -> Converted:
    """Write ``frames`` (raw and decoded) with the mechanism and configuration into a new bag ``out``."""
    refusals: list[Finding] = []
    with BagWriter(out) as writer:
        recorder = StepRecorder(writer, config.topics)
        started = False
        for frame in frames:
            stamp = frame.stamp_ns
            if not started:
                recorder.begin(description, config, stamp)
                started = True
            recorder.input(raw_topic, FRAME_TYPE, to_cdr(frame), stamp, stamp)
            decoded = decoder.decode(frame, stamp)
            for event in decoded.events:
                type_name, data = input_record(event)
                recorder.input(event.topic, type_name, data, event.stamp_ns, stamp)
            if decoded.finding is not None:
                refusals.append(decoded.finding)
    return Converted(decoder.counts, refusals)
