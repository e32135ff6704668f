"""The CAN bridge's recording of frames one at a time, as the live bridge records a frame: the raw
frame, then each input event ``decode`` gives, a bag ``write`` per message (test_can_blocks.py holds
``can-to-bag``'s blocks to it; bench/bench_can.py times it)."""

from __future__ import annotations

from pathlib import Path
from typing import Iterable

from linkage_monitor.bag.step_recorder import StepRecorder
from linkage_monitor.bag.writer import BagWriter
from linkage_monitor.can.decoder import CanDecoder
from linkage_monitor.can.frame_msg import FRAME_TYPE, to_cdr
from linkage_monitor.can.frames import Frame
from linkage_monitor.can.to_bag import RAW_TOPIC, input_record
from linkage_monitor.mechanics import Mechanism
from linkage_monitor.mechanics.overrides import with_sensor_resolutions


def per_frame_bag(frames: Iterable[Frame], decoder: CanDecoder, mech: Mechanism, out: Path) -> None:
    """The bag ``out`` of ``frames`` decoded by ``decoder`` (under its configuration), ``mech`` its
    mechanism with the decoder's resolutions (as the bridge records it: ``CanFrames.described``), each
    frame received at its own stamp."""
    config = decoder.config
    mech = with_sensor_resolutions(mech, decoder.resolutions)
    with BagWriter(out) as writer:
        recorder = StepRecorder(writer, config.topics)
        for k, frame in enumerate(frames):
            if k == 0:
                recorder.begin(mech, config, frame.stamp_ns)
            recorder.input(RAW_TOPIC, FRAME_TYPE, to_cdr(frame), frame.stamp_ns, frame.stamp_ns)
            for event in decoder.decode(frame, frame.stamp_ns).events:
                record = input_record(event)
                recorder.input(event.topic, record.type_name, record.data, event.stamp_ns, frame.stamp_ns)
