"""What the live node publishes: each step's outputs (HingeReactions, HitchState, Steerability),
the linkage markers, the /diagnostics of steps, of the node's own parts and of the heartbeat
(STALE, or the last status again), the latched mechanism description — and, as it publishes, what
the bag and the Rerun view record (``ros.recording``). Stamps and receive times in ns.
"""

from __future__ import annotations

import time
from typing import Any, Callable, Sequence

from diagnostic_msgs.msg import DiagnosticArray
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from std_msgs.msg import String
from visualization_msgs.msg import MarkerArray

from linkage_monitor.bag.step_recorder import mechanism_yaml
from linkage_monitor.monitoring.core import Monitor, Step
from linkage_monitor.monitoring.findings import Level
from linkage_monitor.monitoring.freshness import Freshness
from linkage_monitor.msg import HingeReactions, HitchState, Steerability
from linkage_monitor.wire.diagnostics import status_array
from linkage_monitor.wire.outputs import OutputEncoder
from linkage_monitor.wire.step_messages import StepMessenger

from .recording import Recording

LATCHED = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL)
OUTPUT_QOS = QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE)   # a drained burst publishes in a row
HEARTBEAT_S = 1.0  # s, /diagnostics is repeated at least this often

MakePublisher = Callable[[type, str, QoSProfile], Any]
"""Creates one of the node's publishers: (message type, topic, QoS)."""


class OutputPublisher:
    """The node's publishers and the state of its /diagnostics: the last step reported (what the
    heartbeat repeats), whether the last status sent was STALE, when the last one went out.

    make_publisher: the node's (lifecycle publishers for the managed node); node_name: the statuses'
    ``<node>: <part>`` prefix; clock: the node's (the statuses' stamps); logger: the node's.
    """

    def __init__(self, monitor: Monitor, recording: Recording, make_publisher: MakePublisher, node_name: str,
                 marker_rate_hz: float, clock: Any, logger: Any) -> None:
        description, topics = monitor.description, monitor.config.topics
        self.monitor, self.recording = monitor, recording
        self.node_name, self._clock, self._logger = node_name, clock, logger
        self.encoder = OutputEncoder()
        self.messenger = StepMessenger(description, f"{node_name}: {description.name}", marker_rate_hz)
        self.freshness = Freshness()   # STALE on /diagnostics when nothing was solved for staleness_limit
        self._reported: Step | None = None   # the last step the gate let through: what the heartbeat repeats
        self._stale = True   # the last status the heartbeat sent was STALE: the next step is reported
        self._last_heartbeat = 0.0
        self.pub_hinges = make_publisher(HingeReactions, topics.hinge_reactions, OUTPUT_QOS)
        self.pub_hitch = make_publisher(HitchState, topics.hitch_state, OUTPUT_QOS)
        self.pub_steer = make_publisher(Steerability, topics.steerability, OUTPUT_QOS)
        self.pub_diag = make_publisher(DiagnosticArray, topics.diagnostics, OUTPUT_QOS)
        self.pub_mech = make_publisher(String, "mechanism_description", LATCHED)
        self.publish_description()
        self.pub_markers = make_publisher(MarkerArray, topics.markers, OUTPUT_QOS)

    def publish_description(self) -> None:
        """The mechanism description (YAML text) on the latched ``mechanism_description``."""
        self.pub_mech.publish(String(data=mechanism_yaml(self.monitor.description)))

    def publish(self, step: Step, now: int) -> None:
        """Publish and record what ``step`` sends (``wire.step_messages``), log it to Rerun."""
        messages = self.messenger.messages(step, self.encoder.outputs(self.monitor, step), now)
        out = messages.outputs
        if out is not None:   # serialized: published and recorded as they are
            self.pub_hinges.publish(out.hinge_reactions)
            self.pub_hitch.publish(out.hitch_state)
            self.pub_steer.publish(out.steerability)
        if messages.markers is not None:
            self.pub_markers.publish(messages.markers)
        if step.pose is not None:
            self.freshness.solved(time.monotonic())
        if messages.diagnostic is not None:
            self._reported = step
            self._send_diagnostic(messages.diagnostic)
        elif self._stale:   # the STALE the heartbeat sent is replaced at once (not recorded: the gate did not pass it)
            self._reported = step
            self._send_diagnostic(self.messenger.diagnostic(step, now))
        self._stale = False
        self.recording.step(messages, step, self.monitor.config.dead_centre_transmission_deg, now)
        if step.level == Level.ERROR:
            self._logger.error(step.message, throttle_duration_sec=1.0)
        elif step.level == Level.WARN:
            self._logger.warning(step.message, throttle_duration_sec=1.0)

    def status(self, part: str, level: Level, message: str, now: int) -> None:
        """A separate DiagnosticStatus ``<node>: <part>`` (input stream, recording, internal); recorded
        unless it is the recording's own."""
        msg = status_array(self._clock.now().nanoseconds, level, f"{self.node_name}: {part}", message,
                           self.monitor.mechanism.name, {"part": part})
        if part != "recording":
            self.recording.status(msg, now)
        self.pub_diag.publish(msg)

    def report_stale(self, now: int, sources: Sequence[str]) -> bool:
        """The monitor's status STALE (``monitoring.freshness``) if nothing was solved within the
        staleness limit, naming the input ``sources``: stamped ``now``, published, not recorded (the
        replay solves what the bag holds, whenever); whether it was."""
        finding = self.freshness.stale(time.monotonic(), self.monitor.config.staleness_limit_s, sources)
        self._stale = finding is not None
        if finding is not None:
            self._send_diagnostic(self.messenger.diagnostic(Step(now, ", ".join(sources), (finding,)), now))
        return self._stale

    def repeat_status(self, now: int) -> None:
        """The last reported status again if none went out for HEARTBEAT_S (diagnostic_updater style;
        the bag holds it once already)."""
        if self._reported is not None and time.monotonic() - self._last_heartbeat >= HEARTBEAT_S:
            self._send_diagnostic(self.messenger.diagnostic(self._reported, now))

    def _send_diagnostic(self, diagnostic: bytes) -> None:
        """Publish a step's DiagnosticArray; the heartbeat repeats the last one HEARTBEAT_S after."""
        self.pub_diag.publish(diagnostic)
        self._last_heartbeat = time.monotonic()
