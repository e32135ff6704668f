"""What one monitoring step sends: its output messages, the linkage markers when due, its
DiagnosticArray when due — decided and written once for the live node (published and recorded)
and the replay (recorded), so both send the same messages for the same steps.
"""

from __future__ import annotations

from typing import NamedTuple

from linkage_monitor.mechanics import Mechanism
from linkage_monitor.monitoring.core import Step

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
        stamp, pose = step.stamp_ns, step.pose
        markers = (self.markers.markers(stamp, pose.result)
                   if pose is not None and self._marker_gate.due(stamp) else None)
        diagnostic = self.diagnostic(step, now_ns) if self._diagnostic_gate.due(step) else None
        return StepMessages(stamp, outputs, markers, diagnostic)

    def diagnostic(self, step: Step, now_ns: int) -> bytes:
        """The DiagnosticArray of ``step`` (also the heartbeat's repetition of the last one)."""
        return diagnostic_array(step, self.status_name, self.hardware_id, now_ns)
