"""What the live node records: the run's MCAP bag (``bag.step_recorder.StepRecorder``; none with
``record`` false) and its Rerun view (``viz.rerun_view``; none with ``rerun`` 'off').

A recording fault never stops the monitoring: a failed bag write is an ERROR ``<node>: recording``
(the input's, at once; the writer's own, at every heartbeat), a failed Rerun sink one too, after
which the Rerun logging stops while solving, publishing and the bag go on. Stamps and receive
times in ns.
"""

from __future__ import annotations

from typing import Any, Callable

import numpy as np

from linkage_monitor.bag.step_recorder import StepRecorder
from linkage_monitor.mechanics import Mechanism
from linkage_monitor.monitoring.config import MonitorConfig
from linkage_monitor.monitoring.core import Step
from linkage_monitor.monitoring.findings import Level
from linkage_monitor.monitoring.implement_mass import weighing_series
from linkage_monitor.wire.markers import DisplayGate
from linkage_monitor.wire.step_messages import StepMessages

ABANDONED_RERUN: list[Any] = []   # Rerun views whose sink failed (Recording.rerun_failed)

StatusReport = Callable[[str, Level, str, int], None]
"""Publishes a status ``<node>: <part>``: (part, level, message, now ns)."""


class Recording:
    """The node's bag and Rerun view; ``report`` publishes a recording fault as a status, ``logger``
    is the node's."""

    def __init__(self, recorder: StepRecorder | None, report: StatusReport, logger: Any) -> None:
        self.recorder = recorder
        self.rerun: Any = None
        self.rerun_target = ""
        self.rerun_gate = DisplayGate(0.0)
        self._report = report
        self._logger = logger

    def open_rerun(self, mode: str, path: str, rate_hz: float, description: Mechanism, weighing: bool = False) -> None:
        """The Rerun view of ``mode`` ('off', 'save' to ``path``, 'connect'), poses at most ``rate_hz`` Hz;
        ``weighing``: its layout shows the weighed implement mass."""
        self.rerun_target = path if mode == "save" else "(viewer)"
        self.rerun_gate = DisplayGate(rate_hz)
        if mode != "off":
            from linkage_monitor.viz.rerun_view import RerunView, default_blueprint
            blueprint = default_blueprint(description, live=mode != "save", weighing=weighing)
            self.rerun = (RerunView.to_file(description, path, blueprint=blueprint) if mode == "save"
                          else RerunView.to_viewer(description, blueprint=blueprint))

    def begin(self, description: Mechanism, config: MonitorConfig, now: int) -> None:
        """The bag's first messages: the mechanism description and the configuration."""
        if self.recorder is not None:
            self.recorder.begin(description, config, now)

    def config(self, config: MonitorConfig, now: int) -> None:
        """A configuration changed at run time, in the bag."""
        if self.recorder is not None:
            self.recorder.config(config, now)

    def input(self, topic: str, type_name: str, data: bytes, stamp_ns: int, now: int) -> None:
        """Record an input's CDR bytes as they came (``StepRecorder.input``); a recording fault is an
        ERROR ``<node>: recording`` and the monitoring goes on."""
        if self.recorder is None:
            return
        try:
            self.recorder.input(topic, type_name, data, stamp_ns, now)
        except Exception as exc:  # noqa: BLE001 - a recording fault must not stop the monitoring
            self._report("recording", Level.ERROR, f"recording failed for {topic}: {type(exc).__name__}: {exc}; "
                         "solving and publishing go on", now)

    def status(self, diagnostic: bytes, now: int) -> None:
        """A status's DiagnosticArray (CDR), in the bag."""
        if self.recorder is not None:
            self.recorder.status(diagnostic, now, now)

    def step(self, messages: StepMessages, step: Step, dead_centre_transmission_deg: float, now: int) -> None:
        """What a step sent, in the bag; the step in the Rerun view (``log_rerun``)."""
        if self.recorder is not None:
            self.recorder.step(messages, now)
        if self.rerun is not None:
            try:
                self._log_rerun(step, dead_centre_transmission_deg)
            except Exception as exc:  # noqa: BLE001 - a failed Rerun sink must not stop the monitor
                self.rerun_failed(exc, now)

    def _log_rerun(self, step: Step, dead_centre_transmission_deg: float) -> None:
        """Solved poses at most at rerun_rate; every ERROR's text."""
        from linkage_monitor.viz.rerun_estimates import budget_bands
        from linkage_monitor.viz.rerun_view import machine_series

        if step.pose is not None:
            if self.rerun_gate.due(step.stamp_ns):
                m, result, budget = step.pose.machine, step.pose.result, step.pose.budget
                self.rerun.log_pose(step.stamp_ns, result, machine_series(
                    m.steerability, m.lift_capacity, result.transmission_angle, dead_centre_transmission_deg),
                    budget_bands(self.rerun.mechanism, [budget]) if budget is not None else None)
                implement = self.rerun.mechanism.implement
                if step.weighing is not None and implement is not None:
                    self.rerun.log_weighing(np.array([step.stamp_ns]), result.body_poses[implement.body][None],
                                            **weighing_series([step.weighing])._asdict())
        elif step.level == Level.ERROR:
            self.rerun.log_status(step.stamp_ns, step.message)

    def heartbeat(self, now: int) -> None:
        """The bag writer's fault reported (ERROR ``<node>: recording``), the Rerun recording flushed."""
        error = self.recorder.writer.error if self.recorder is not None else None
        if error:
            self._report("recording", Level.ERROR, f"recording failed: {error}; solving and publishing go on", now)
        self.flush_rerun(now)

    def flush_rerun(self, now: int) -> None:
        """The Rerun recording written out (every heartbeat: a power cut loses at most about a second
        of it); a failed sink (its disk full) is an ERROR ``<node>: recording`` naming the file, the
        Rerun logging stops, solving, publishing and the bag go on."""
        if self.rerun is None:
            return
        try:
            self.rerun.flush()
        except Exception as exc:  # noqa: BLE001 - rerun raises RuntimeError (and others) for a failed sink
            self.rerun_failed(exc, now)

    def rerun_failed(self, exc: Exception, now: int) -> None:
        """The Rerun view given up after its sink failed with ``exc`` (logged, an ERROR status)."""
        reason = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        # a failed file sink can be neither flushed, closed nor dropped: each waits forever for its
        # writer (rerun-sdk 0.41), so it is kept, never touched again, and main() exits past it
        ABANDONED_RERUN.append(self.rerun)
        text = (f"Rerun recording {self.rerun_target} failed: {reason} (disk full, or too slow?); the Rerun logging "
                "stops, solving, publishing and the bag go on")
        self.rerun = None
        self._logger.error(text)
        self._report("recording", Level.ERROR, text, now)

    def close_bag(self) -> None:
        """The bag finished (nothing logged)."""
        if self.recorder is not None:
            self.recorder.writer.close()

    def close(self) -> None:
        """The bag finished (its outcome logged), the Rerun recording finished."""
        if self.recorder is not None:
            writer = self.recorder.writer
            writer.close()
            (self._logger.info if writer.error is None else self._logger.error)(writer.outcome)
        if self.rerun is not None:
            try:
                self.rerun.close()
            except Exception as exc:  # noqa: BLE001 - one line, no traceback: the disk may be full
                self._logger.error(f"Rerun recording {self.rerun_target} not finished: "
                                   f"{str(exc).splitlines()[0] if str(exc) else type(exc).__name__}")
