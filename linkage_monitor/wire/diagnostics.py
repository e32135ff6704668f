"""Monitoring steps -> diagnostic_msgs/DiagnosticArray, the way diagnostic_updater reports, as CDR
bytes written by the message's layout (``wire.compose``: published and recorded as they are).

One DiagnosticStatus per step (level OK / WARN / ERROR, the message naming the input and the
reason, key-values with the numbers and the stamp of the triggering input). A step is
reported when it is not OK or when the status changed; the live node repeats the last one
as a heartbeat, or, when it has solved nothing for its staleness limit, sends STALE in its
place (``monitoring.freshness``: a status stamped with its clock, not recorded).
"""

from __future__ import annotations

from typing import Mapping

from linkage_monitor.monitoring.core import NO_FINDINGS, Step
from linkage_monitor.monitoring.findings import Level

from .compose import encode
from .outputs import FRAME_ID

DIAGNOSTIC_ARRAY = "diagnostic_msgs/msg/DiagnosticArray"
STAMP_KEY = "input stamp [ns]"
MAX_TIME_NS = 2**31 * 1_000_000_000  # builtin_interfaces/Time.sec is int32
CODES_KEY = "findings"  # the findings' codes (monitoring.findings.Code identifiers), space-separated


def status_array(stamp_ns: int, level: Level, name: str, message: str, hardware_id: str,
                 values: Mapping[str, str], frame_id: str = "") -> bytes:
    """A DiagnosticArray of one DiagnosticStatus, stamped ``stamp_ns`` (ns since the epoch)."""
    return encode(DIAGNOSTIC_ARRAY, {
        "header": {"stamp": stamp_ns, "frame_id": frame_id},
        "status": [{"level": int(level), "name": name, "message": message, "hardware_id": hardware_id,
                    "values": [{"key": k, "value": v} for k, v in values.items()]}]})


def diagnostic_array(step: Step, name: str, hardware_id: str, now_ns: int) -> bytes:
    """The DiagnosticArray with the one status of `step`, stamped like every output with the
    input's stamp, or with `now_ns` (the monitor's clock) when that stamp cannot be a ROS time
    (negative, or beyond int32 seconds: the fault being reported); the input's stamp is a key-value."""
    values = dict(step.values)
    values[STAMP_KEY] = str(step.stamp_ns)
    if step.findings:
        values[CODES_KEY] = " ".join(f.code.ident for f in step.findings)
    stamp = step.stamp_ns if 0 <= step.stamp_ns < MAX_TIME_NS else now_ns
    return status_array(stamp, step.level, name, step.message, hardware_id, values, FRAME_ID)


class DiagnosticGate:
    """Decides which steps are reported: every WARN/ERROR, and an OK that ends one."""

    def __init__(self) -> None:
        self._last: tuple[Level, str] | None = None

    def due(self, step: Step) -> bool:
        """True if `step` should be reported now (never a step that solved nothing and found nothing:
        an IMU message taken, which says nothing of the outputs)."""
        if step.pose is None and not step.findings:
            return False
        return self._due((step.level, step.message) if step.findings else _OK)   # most steps: OK without findings

    def due_quiet(self) -> bool:
        """``due`` of a solved step without findings (``monitoring.steps.QuietPoses``: its Step not built)."""
        return self._due(_OK)

    def _due(self, key: tuple[Level, str]) -> bool:
        report = key[0] != Level.OK or key != self._last
        self._last = key
        return report


_OK = (Level.OK, NO_FINDINGS)   # the level and message of a step without findings
