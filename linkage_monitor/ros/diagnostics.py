"""Monitoring steps -> diagnostic_msgs/DiagnosticArray, the way diagnostic_updater reports.

One DiagnosticStatus per step (level OK / WARN / ERROR, the message naming the input and the
reason, key-values with the numbers and the stamp of the triggering input). A step is
reported when it is not OK or when the status changed; the live node repeats the last one
as a heartbeat.
"""

from __future__ import annotations

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue

from linkage_monitor.monitoring.core import Step
from linkage_monitor.monitoring.findings import Level
from linkage_monitor.ros.messages import header

STAMP_KEY = "input stamp [ns]"
MAX_TIME_NS = 2**31 * 1_000_000_000  # builtin_interfaces/Time.sec is int32
CODES_KEY = "findings"  # the findings' codes (monitoring.findings.Code identifiers), space-separated


def diagnostic_array(step: Step, name: str, hardware_id: str, now_ns: int) -> DiagnosticArray:
    """A DiagnosticArray with the one status of `step`, stamped like every output with the
    input's stamp, or with `now_ns` (the monitor's clock) when that stamp cannot be a ROS time
    (negative, or beyond int32 seconds: the fault being reported); the input's stamp is a key-value."""
    values = [KeyValue(key=k, value=v) for k, v in step.values.items()]
    values.append(KeyValue(key=STAMP_KEY, value=str(step.stamp_ns)))
    if step.findings:
        values.append(KeyValue(key=CODES_KEY, value=" ".join(f.code.ident for f in step.findings)))
    status = DiagnosticStatus(level=bytes([step.level]), name=name, message=step.message,
                              hardware_id=hardware_id, values=values)
    stamp = step.stamp_ns if 0 <= step.stamp_ns < MAX_TIME_NS else now_ns
    return DiagnosticArray(header=header(stamp), status=[status])


class DiagnosticGate:
    """Decides which steps are reported: every WARN/ERROR, and an OK that ends one."""

    def __init__(self) -> None:
        self._last: tuple[Level, str] | None = None

    def due(self, step: Step) -> bool:
        """True if `step` should be reported now."""
        key = (step.level, step.message)
        report = step.level != Level.OK or key != self._last
        self._last = key
        return report
