"""A CAN log -> a rosbag2 bag of the monitor's inputs, for ``linkage-monitor replay``.

The bag holds what the live bridge (``linkage-monitor can``) records of the same frames: every
raw frame as can_msgs/msg/Frame (on ``raw_topic``, so the bag can be decoded again with a
corrected DBC or mapping), the inputs decoded from it (sensor_msgs/JointState,
sensor_msgs/FluidPressure, stamped with the frame's stamp), the mechanism description and the
monitor's configuration. Receive time = the frame's stamp (the log's own time), so the replay's
stamp check judges the inputs against the time they were logged.

The frames go through in blocks (``FrameBlock``): decoded together (``CanDecoder.decode_block``),
their messages written as arrays of CDR rows (``frame_msg.frames_cdr``, ``input_msg``'s templates)
into the bag's chunks at once (``BagWriter.write_rows``), each frame's raw message followed by the
inputs it gave, as one frame at a time would record them.
"""

from __future__ import annotations

from collections import Counter, defaultdict
from dataclasses import dataclass
from pathlib import Path
from typing import Iterable, NamedTuple

import numpy as np

from linkage_monitor.bag.step_recorder import StepRecorder
from linkage_monitor.bag.row_block import MessageRows
from linkage_monitor.bag.writer import BagWriter
from linkage_monitor.mechanics import Mechanism
from linkage_monitor.mechanics.overrides import with_sensor_resolutions
from linkage_monitor.monitoring.config import MonitorConfig
from linkage_monitor.monitoring.events import InputEvent, JointStateEvent, PressureEvent
from linkage_monitor.monitoring.findings import Code, Finding
from linkage_monitor.wire.sensor_messages import FLUID_PRESSURE, JOINT_STATE

from .decoder import CanDecoder
from .frame_msg import FRAME_TYPE, frames_cdr
from .frames import Frame, FrameBlock, blocks_of
from .input_msg import fluid_pressure_cdr, fluid_pressures_cdr, joint_state_cdr, joint_states_cdr
from .outcomes import BlockDecoded, FrameCounts

RAW_TOPIC = "/from_can_bus"
"""Topic of the raw frames (can_msgs/msg/Frame), ros2_socketcan's default."""


class InputRecord(NamedTuple):
    """The sensor message a decoded input event stands for: its type name and CDR bytes."""

    type_name: str
    data: bytes


def input_record(event: InputEvent) -> InputRecord:
    """The sensor message (``InputRecord``) a decoded input event stands for."""
    if isinstance(event, JointStateEvent):
        return InputRecord(JOINT_STATE, joint_state_cdr(event.stamp_ns, event.names, event.positions))
    assert isinstance(event, PressureEvent)
    return InputRecord(FLUID_PRESSURE, fluid_pressure_cdr(event.stamp_ns, event.fluid_pressure))


@dataclass(frozen=True)
class Converted:
    """What a conversion did: the frame counts, the refusals (finding per refused frame, in order)."""

    counts: FrameCounts
    refusals: list[Finding]


def refusal_lines(refusals: list[Finding]) -> list[str]:
    """The refused frames by kind, one line each: level, count, code and the first one's finding (which
    names the frame, its signal and the reason), e.g. ``WARN      420  no_value_yet  CAN frame ...``."""
    first: dict[Code, Finding] = {}
    count: Counter = Counter()
    for finding in refusals:
        first.setdefault(finding.code, finding)
        count[finding.code] += 1
    return [f"{first[code].level.name:<6} {count[code]:6d}  {code.ident}  {'first: ' if count[code] > 1 else ''}"
            f"{first[code].text}" for code in sorted(first, key=lambda c: c.ident)]


def can_to_bag(frames: Iterable[Frame], decoder: CanDecoder, description: Mechanism, config: MonitorConfig,
               out: Path, raw_topic: str = RAW_TOPIC) -> Converted:
    """Write ``frames`` (raw and decoded) with the mechanism and configuration into a new bag ``out``."""
    return blocks_to_bag(blocks_of(frames), decoder, description, config, out, raw_topic)


def blocks_to_bag(blocks: Iterable[FrameBlock], decoder: CanDecoder, description: Mechanism, config: MonitorConfig,
                  out: Path, raw_topic: str = RAW_TOPIC) -> Converted:
    """``can_to_bag`` of frames given in blocks (a log reader's, ``sources.read_log_blocks``). The bag
    records ``description`` with the decoder's resolutions, as the live bridge does (``CanFrames.described``)."""
    refusals: list[Finding] = []
    description = with_sensor_resolutions(description, decoder.resolutions)
    with BagWriter(out) as writer:
        recorder = StepRecorder(writer, config.topics)
        started = False
        for block in blocks:
            if not len(block):
                continue
            if not started:
                recorder.begin(description, config, int(block.stamp_ns[0]))
                started = True
            decoded = decoder.decode_block(block)
            writer.write_rows(block_records(block, decoded, raw_topic), qos=recorder.input_qos)
            refusals.extend(decoded.refusals())
    return Converted(decoder.counts, refusals)


def block_records(block: FrameBlock, decoded: BlockDecoded, raw_topic: str = RAW_TOPIC) -> list[MessageRows]:
    """The messages a block of frames records, in the order one frame at a time records them: each
    frame's raw can_msgs/Frame on ``raw_topic``, then the inputs decoded from it (its JointState, then
    its FluidPressures), every one stamped and logged at the frame's stamp."""
    stamps = block.stamp_ns
    events = np.zeros(len(block), np.int64)
    for d in decoded.inputs:
        events[d.rows] = d.events_per_frame
    for k, one in decoded.single.items():
        events[k] = len(one.events)
    raw_at = np.cumsum(events + 1) - (events + 1)   # each frame's place in the block's messages
    parts = [MessageRows(raw_topic, FRAME_TYPE, frames_cdr(block), raw_at, stamps, stamps)]
    for d in decoded.inputs:
        at, s = raw_at[d.rows] + 1, stamps[d.rows]
        if d.joint_names:
            parts.append(MessageRows(d.joint_topic, JOINT_STATE, joint_states_cdr(s, d.joint_names, d.positions),
                                     at, s, s))
            at = at + 1
        for k, topic in enumerate(d.pressure_topics):
            parts.append(MessageRows(topic, FLUID_PRESSURE, fluid_pressures_cdr(s, d.pressures[:, k]), at + k, s, s))
    return parts + _single_records(block, decoded, raw_at)


def _single_records(block: FrameBlock, decoded: BlockDecoded, raw_at: np.ndarray) -> list[MessageRows]:
    """The inputs of the frames decoded one by one, each right after its frame's raw message, gathered
    by topic, type and size."""
    gathered: dict[tuple[str, str, int], list[_Single]] = defaultdict(list)
    for k, one in sorted(decoded.single.items()):
        for j, event in enumerate(one.events):
            record = input_record(event)
            gathered[(event.topic, record.type_name, len(record.data))].append(
                _Single(record.data, int(raw_at[k]) + 1 + j, event.stamp_ns, int(block.stamp_ns[k])))
    return [MessageRows(topic, type_name,
                        np.frombuffer(b"".join(r.data for r in rows), np.uint8).reshape(len(rows), size),
                        np.array([r.position for r in rows], np.int64), np.array([r.stamp_ns for r in rows], np.int64),
                        np.array([r.log_time_ns for r in rows], np.int64))
            for (topic, type_name, size), rows in gathered.items()]


class _Single(NamedTuple):
    """One input decoded one frame at a time: its CDR bytes, its place in the block's order, its
    stamp and its frame's (ns)."""

    data: bytes
    position: int
    stamp_ns: int
    log_time_ns: int
