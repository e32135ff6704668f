"""Monitoring steps -> diagnostic_msgs/DiagnosticArray, the way diagnostic_updater reports.

One DiagnosticStatus per step (level OK / WARN / ERROR, the message naming the input and the
reason, key-values with the numbers and the stamp of the triggering input). A step is
reported when it is not OK or when the status changed; the live node repeats the last one
as a heartbeat.
"""

from __future__ import annotations

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue

from linkage_monitor.monitoring.core import OK, Step
from linkage_monitor.ros.messages import header

STAMP_KEY = "input stamp [ns]"


def diagnostic_array(step: Step, name: str, hardware_id: str) -> DiagnosticArray:
    """A DiagnosticArray with the one status of `step`, stamped with its input's stamp."""
    values = [KeyValue(key=k, value=v) for k, v in step.values.items()]
    values.append(KeyValue(key=STAMP_KEY, value=str(step.stamp_ns)))
    status = DiagnosticStatus(level=bytes([step.level]), name=name, message=step.message,
                              hardware_id=hardware_id, values=values)
    return DiagnosticArray(header=header(step.stamp_ns), status=[status])


class DiagnosticGate:
    """Decides which steps are reported: every WARN/ERROR, and an OK that ends one."""

    def __init__(self) -> None:
        self._last: tuple[int, str] | None = None

    def due(self, step: Step) -> bool:
        """True if `step` should be reported now."""
        key = (step.level, step.message)
        report = step.level != OK or key != self._last
        self._last = key
        return report
