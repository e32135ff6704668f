"""Where a replay's steps go (``replay``): the output bag, written as the node records it, and the
Rerun recording.
Units SI; frame x forward, z up, origin at the rear wheels' ground contact.
"""

from __future__ import annotations

import time
from concurrent.futures import Future, ThreadPoolExecutor
from pathlib import Path
from typing import TYPE_CHECKING

from linkage_monitor.bag.step_recorder import RecordedInputs, StepRecorder
from linkage_monitor.bag.writer import BagWriter
from linkage_monitor.mechanics import Mechanism
from linkage_monitor.monitoring.config import MonitorConfig
from linkage_monitor.monitoring.core import Monitor, Run
from linkage_monitor.monitoring.findings import Level
from linkage_monitor.monitoring.implement_mass import weighing_series
from linkage_monitor.wire.outputs import OutputEncoder, per_step

if TYPE_CHECKING:
    from linkage_monitor.viz.rerun_view import RerunView

ENCODE_BLOCK = 4096   # inputs replayed at once: read, solved, accounted, encoded and written, then let go


class BagOutput:
    """The output bag: inputs (their recorded bytes, unchanged), outputs and diagnostics in recording
    order, as the node records them (``bag.step_recorder``), ENCODE_BLOCK steps at a time: their outputs
    encoded at once (``OutputEncoder.output_rows``, with the monitor in the steps' configuration; a quiet
    pose's from its segment's columns, its Step not built: ``monitoring.steps.Steps``) and,
    as fast as possible, all their messages written at once (``StepRecorder.steps``), in a thread of its own
    while the next steps are read and solved (the block's chunks are compressed beside the building of the
    next chunk's records, and the thread, not the replay, waits for them). With ``rate`` the
    messages go one by one (``StepRecorder.input``, ``step``), each input's written at its receive time
    scaled by 1 / ``rate`` from the first: a block written at once cannot keep that pace."""

    def __init__(self, out_dir: Path, description: Mechanism, config: MonitorConfig, first_receive_ns: int,
                 rate: float | None) -> None:
        from linkage_monitor.wire.markers import DEFAULT_RATE_HZ
        from linkage_monitor.wire.step_messages import StepMessenger

        self.writer = BagWriter(out_dir)
        try:
            self.recorder = StepRecorder(self.writer, config.topics)
            self.recorder.begin(description, config, first_receive_ns)
        except BaseException:
            self.writer.close()
            raise
        self._writing = ThreadPoolExecutor(max_workers=1, thread_name_prefix="replay output")
        self._written: Future[None] | None = None   # the block being written (one at a time: memory stays flat)
        self.messenger = StepMessenger(description, f"linkage_monitor: {description.name}", DEFAULT_RATE_HZ)
        self.encoder = OutputEncoder()
        self.first, self.rate, self.pace_start = first_receive_ns, rate, time.perf_counter()

    def write(self, monitor: Monitor, raw: RecordedInputs, piece: Run) -> None:
        """The messages of a piece's steps (``raw``: their inputs, in order)."""
        for start in range(0, len(raw), ENCODE_BLOCK):
            inputs, steps = raw.span(start, start + ENCODE_BLOCK), piece.steps[start:start + ENCODE_BLOCK]
            outputs = self.encoder.output_rows(monitor, steps)
            if not self.rate:
                besides = self.messenger.sent_of(steps, inputs.receive_ns)
                self._wait()
                self._written = self._writing.submit(self.recorder.steps, inputs, steps.stamps_ns, besides, outputs)
                continue
            sent = self.messenger.messages_of(steps, per_step(outputs, len(steps)), inputs.receive_ns)
            for recorded, messages in zip(inputs, sent):
                receive = recorded.receive_ns
                delay = (receive - self.first) * 1e-9 / self.rate - (time.perf_counter() - self.pace_start)
                if delay > 0:
                    time.sleep(delay)
                self.recorder.input(recorded.topic, recorded.type_name, recorded.data, recorded.stamp_ns, receive)
                self.recorder.step(messages, receive)

    def close(self) -> None:
        try:
            self._wait()
        finally:
            self._writing.shutdown()
            self.writer.close()

    def _wait(self) -> None:
        """Once the block being written is (what its writing raised raised here)."""
        if self._written is not None:
            written, self._written = self._written, None
            written.result()


class RerunOutput:
    """The Rerun recording: every solved pose as columns (one send per entity per piece), refused
    inputs as status text; opened at the first piece, its hinge plot showing the largest hinges of
    the first piece's first segment."""

    def __init__(self, path: Path, description: Mechanism) -> None:
        self.path, self.description = path, description
        self.view: RerunView | None = None

    def log(self, piece: Run) -> None:
        from linkage_monitor.viz.rerun_estimates import budget_bands
        from linkage_monitor.viz.rerun_view import RerunView, default_blueprint, largest_hinges, machine_series

        segments = piece.segments
        if self.view is None:
            hinges = largest_hinges(segments[0].batch) if segments else None
            weighing = bool(segments) and segments[0].config.implement_mass_source != "file"
            self.view = RerunView.to_file(self.description, self.path, blueprint=default_blueprint(
                self.description, hinges=hinges, weighing=weighing))
        view = self.view
        solved_in_batch = {int(i) for seg in segments for i in seg.steps}   # log_batch reports the solver's rejections
        for i, s in enumerate(piece.steps):
            if s.pose is None and s.level == Level.ERROR and i not in solved_in_batch:
                view.log_status(s.stamp_ns, s.message)
        for seg in segments:
            m = seg.machine
            steps = [piece.steps[i] for i in seg.steps.tolist()]
            bands = (budget_bands(self.description, [s.pose.budget if s.pose is not None else None for s in steps])
                     if seg.config.uncertainty else None)
            view.log_batch(seg.stamps_ns, seg.batch, machine_series(m.steerability, m.lift_capacity,
                                                                    seg.batch.transmission_angle,
                                                                    seg.config.dead_centre_transmission_deg), bands)
            implement = self.description.implement
            if seg.config.implement_mass_source != "file" and implement is not None:
                view.log_weighing(seg.stamps_ns, seg.batch.body_poses[implement.body],
                                  **weighing_series([s.weighing for s in steps])._asdict())

    def close(self) -> None:
        if self.view is not None:
            self.view.close()
