"""What one monitoring step sends: its output messages, the linkage markers when due, its
DiagnosticArray when due — decided and written once for the live node (published and recorded)
and the replay (recorded), so both send the same messages for the same steps.
"""

from __future__ import annotations

from typing import NamedTuple, Sequence

import numpy as np

from linkage_monitor.mechanics import Mechanism
from linkage_monitor.monitoring.core import Step, Steps

from .diagnostics import DiagnosticGate, diagnostic_array
from .markers import DisplayGate, LinkageMarkers
from .outputs import Outputs


class StepMessages(NamedTuple):
    """The messages of one step, CDR bytes as published and recorded (None: not sent), all stamped
    ``stamp_ns`` (the step's: its input's header stamp, ns)."""

    stamp_ns: int
    outputs: Outputs | None     # HingeReactions, HitchState, Steerability of a solved pose
    markers: bytes | None       # visualization_msgs/MarkerArray of a solved pose, at most at the marker rate
    diagnostic: bytes | None    # diagnostic_msgs/DiagnosticArray: every WARN / ERROR, an OK that ends one


class SentBesides(NamedTuple):
    """What several steps send besides their outputs (``StepMessenger.sent_of``), by the step's place:
    the markers (CDR bytes) of the steps drawn, the DiagnosticArray of the steps reported."""

    markers: dict[int, bytes]
    diagnostics: dict[int, bytes]


class StepMessenger:
    """The messages of each step of one monitored mechanism, in the order the steps come.

    status_name: the DiagnosticStatus name (``<node>: <mechanism>``); marker_rate_hz: the largest
    rate (Hz of header stamps) of the markers (0: none).
    """

    def __init__(self, description: Mechanism, status_name: str, marker_rate_hz: float) -> None:
        self.status_name, self.hardware_id = status_name, description.name
        self.markers = LinkageMarkers(description)
        self._marker_gate = DisplayGate(marker_rate_hz)
        self._diagnostic_gate = DiagnosticGate()

    def messages(self, step: Step, outputs: Outputs | None, now_ns: int) -> StepMessages:
        """What ``step`` sends, its ``outputs`` written by ``wire.outputs.OutputEncoder``; ``now_ns``: the
        monitor's clock (ns), the diagnostic's stamp when the step's cannot be a ROS time."""
        markers = (self.markers.markers(step.stamp_ns, step.pose.result)
                   if step.pose is not None and self._marker_gate.due(step.stamp_ns) else None)
        return self._sent(step, outputs, markers, now_ns)

    def messages_of(self, steps: Sequence[Step], outputs: Sequence[Outputs | None],
                    now_ns: Sequence[int]) -> list[StepMessages]:
        """``messages`` of each of ``steps`` in turn (the markers of those drawn made at once)."""
        sent = self.sent_of(steps, now_ns)
        return [StepMessages(step.stamp_ns, out, sent.markers.get(k), sent.diagnostics.get(k))
                for k, (step, out) in enumerate(zip(steps, outputs))]

    def sent_of(self, steps: Sequence[Step], now_ns: Sequence[int]) -> SentBesides:
        """What ``messages`` of each of ``steps`` in turn sends besides their outputs, by step (the markers
        of those drawn made at once); the quiet poses of ``Steps`` from their segments' columns, the Step
        of one built only when it is reported (an OK that ends a WARN)."""
        steps = steps if isinstance(steps, Steps) else Steps(list(steps))
        solved = steps.is_quiet.copy()
        for k, step in steps.said():
            solved[k] = step.pose is not None
        stamps, drawn_now = steps.stamps_ns.tolist(), self._marker_gate.due
        drawn = [k for k in np.flatnonzero(solved).tolist() if drawn_now(stamps[k])]
        markers = dict(zip(drawn, self.markers.markers_of([stamps[k] for k in drawn], steps.results(drawn))))
        gate, quiet = self._diagnostic_gate, steps.is_quiet
        # of a run of quiet poses only the first may be reported (an OK after a WARN): the gate sees the others alike
        asked = np.flatnonzero(~quiet | ~np.concatenate([[False], quiet[:-1]])).tolist()
        reported = [k for k in asked
                    if (gate.due_quiet() if quiet[k] else gate.due(steps.made[k]))]  # type: ignore[arg-type]  # made
        return SentBesides(markers, {k: self.diagnostic(step, now_ns[k]) for k, step in zip(reported, steps.at(reported))})

    def _sent(self, step: Step, outputs: Outputs | None, markers: bytes | None, now_ns: int) -> StepMessages:
        """``step``'s messages with its ``outputs`` and ``markers``, and its diagnostic when one is due."""
        return StepMessages(step.stamp_ns, outputs, markers,
                            self.diagnostic(step, now_ns) if self._diagnostic_gate.due(step) else None)

    def diagnostic(self, step: Step, now_ns: int) -> bytes:
        """The DiagnosticArray of ``step`` (also the heartbeat's repetition of the last one)."""
        return diagnostic_array(step, self.status_name, self.hardware_id, now_ns)
