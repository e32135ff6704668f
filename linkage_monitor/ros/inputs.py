"""Where the live node's inputs come from: an ``InputSource`` the node starts once it can solve
and asks, at every heartbeat and at its end, for what it reports. The sensor subscriptions
(``SensorTopics``, JointState and FluidPressure) are the node's own source; the CAN bridge's is the
bus or the frames' topic (``can.node.CanFrames``). A source hands what it takes to the node's public
side: ``subscribe``, ``now``, ``recording.input``, ``monitor.step``, ``outputs.publish``, ``publish_status``.
"""

from __future__ import annotations

from typing import Any, Callable, Protocol

from sensor_msgs.msg import FluidPressure, Imu, JointState

from linkage_monitor.mechanics import Mechanism
from linkage_monitor.monitoring.config import MonitorConfig
from linkage_monitor.monitoring.core import Monitor
from linkage_monitor.monitoring.findings import Level
from linkage_monitor.monitoring.sources import SourceGate
from linkage_monitor.monitoring.steps import Step
from linkage_monitor.wire.sensor_messages import FLUID_PRESSURE, IMU, JOINT_STATE, input_event

from .parameters import trusted_publishers
from .publishers import PublisherNames
from .publishing import OutputPublisher
from .recording import Recording

InputCallback = Callable[[bytes, dict], None]   # an input's CDR bytes and rclpy's message info


class InputHost(Protocol):
    """What a source uses of the node it feeds (``ros.node.LinkageMonitorNode``): its monitor, recording and
    output publisher, its subscriptions, clock, statuses, logger and timers."""

    monitor: Monitor
    recording: Recording
    outputs: OutputPublisher

    @property
    def input_subscriptions(self) -> list[Any]:
        """The node's input subscriptions."""

    def subscribe(self, msg_type: type, topic: str, callback: InputCallback) -> None:
        """Take ``topic``'s messages serialized into ``callback``, their losses counted."""

    def now(self) -> int:
        """The node's clock, ns."""

    def publish_status(self, part: str, level: Level, message: str, now: int) -> None:
        """One /diagnostics status of ``part``."""

    def get_logger(self) -> Any:
        """The node's logger."""

    def create_timer(self, timer_period_sec: float, callback: Any) -> Any:
        """A timer on the node's clock."""

    def resolve_topic_name(self, topic: str, *, only_expand: bool = False) -> str:
        """``topic`` with the node's namespace and remappings."""

    def get_parameter(self, name: str) -> Any:
        """A node parameter."""

    def get_publishers_info_by_topic(self, topic_name: str, no_mangle: bool = False) -> list[Any]:
        """The graph's publishers of ``topic_name`` (node name, namespace, endpoint GID)."""


class InputSource(Protocol):
    """The node's way in for its inputs."""

    def described(self, description: Mechanism, config: MonitorConfig) -> Mechanism:
        """The mechanism as the node monitors and records it: ``description`` with what the source knows
        of its inputs (a CAN mapping's resolutions); before the monitor is built."""

    def start(self, node: InputHost) -> None:
        """Subscribe to (or open) the inputs and create the source's timers on ``node``, whose monitor is
        built; errors of the source's own settings raise (ValueError, LinkageError: the node's start fails)."""

    def names(self) -> list[str]:
        """Where the inputs come from (topics, a bus): what the STALE status names."""

    def on_heartbeat(self) -> None:
        """The source's own statuses at the node's heartbeat."""

    def close(self) -> None:
        """What the source holds released, its last statuses published (the node's end)."""


REFUSED = "/refused"   # an input topic's messages the node did not use are recorded on <topic>/refused


class SensorTopics:
    """The sensors' topics: the JointState topic, each pressure topic of the monitor's config and its
    IMU topic if it has one, taken serialized (the bag records the bytes that arrived), read into input events, solved.

    Each message's publisher is part of its identity (``ros.publishers``, ``monitoring.sources``): while two
    nodes publish one input topic neither is used (a ``sensors_disagree`` finding naming both), unless the
    parameter ``trusted_publishers`` names the one to take. A message not used is recorded on
    ``<topic>/refused`` (so a replay, which reads the input topics, solves what the node solved) and
    counted, the counts a status ``<node>: sources`` at the heartbeat."""

    def __init__(self) -> None:
        self._node: InputHost | None = None
        self._gate = SourceGate({}, "trusted_publishers")

    def described(self, description: Mechanism, config: MonitorConfig) -> Mechanism:
        """``description`` as it is: the topics tell nothing more of the sensors."""
        return description

    def start(self, node: InputHost) -> None:
        """Subscribe to the JointState topic, then to each pressure topic, then to the IMU's."""
        self._node = node
        self._gate = SourceGate(trusted_publishers(list(node.get_parameter("trusted_publishers").value),
                                                   node.resolve_topic_name), "trusted_publishers")
        self._publishers = PublisherNames(node.get_publishers_info_by_topic)
        topics = node.monitor.config.topics
        node.subscribe(JointState, topics.joint_states, self._callback(topics.joint_states, JOINT_STATE))
        for topic in node.monitor.config.pressure_topics:
            node.subscribe(FluidPressure, topic, self._callback(topic, FLUID_PRESSURE))
        if topics.imu:
            node.subscribe(Imu, topics.imu, self._callback(topics.imu, IMU))

    def _callback(self, topic: str, type_name: str) -> Callable[[bytes, dict], None]:
        def callback(data: bytes, info: dict) -> None:
            self.on_input(topic, type_name, data, info)
        return callback

    def on_input(self, topic: str, type_name: str, data: bytes, info: dict) -> None:
        """An input message's CDR bytes (``type_name``) arrived on ``topic`` (``info``: rclpy's message
        info, its publisher's GID and receive time): read them into an input event (``wire.sensor_messages``;
        bytes that are not the type: an UnreadableEvent, an ERROR step saying why); a message of its topic's
        one source (or of the trusted one) recorded as it came, solved, published; one not used recorded
        on ``<topic>/refused``, its finding (two sources) published."""
        node = self._node
        assert node is not None
        now = node.now()
        event = input_event(type_name, data, topic, now)
        publisher = self._publishers.of(topic, info)
        admission = self._gate.admit(topic, publisher.gid, publisher.name, info["received_timestamp"],
                                     int(node.monitor.config.staleness_limit_s * 1e9))
        node.recording.input(topic if admission.used else topic + REFUSED, type_name, data, event.stamp_ns, now)
        try:
            if not admission.used:
                if admission.finding is not None:
                    node.outputs.publish(Step(event.stamp_ns, topic, (admission.finding,)), now)
                return
            node.outputs.publish(node.monitor.step(event), now)
        except Exception as exc:  # noqa: BLE001 - the adapter boundary: report and go on
            node.get_logger().error(f"internal error on {topic}: {type(exc).__name__}: {exc}",
                                    throttle_duration_sec=1.0)
            node.publish_status("internal", Level.ERROR, f"internal error while publishing the results of "
                                f"{topic}: {type(exc).__name__}: {exc}", now)

    def names(self) -> list[str]:
        """The topics of the node's input subscriptions."""
        return [sub.topic_name for sub in self._node.input_subscriptions] if self._node is not None else []

    def on_heartbeat(self) -> None:
        """The messages not used since the last heartbeat, per topic and publisher, as a status
        ``<node>: sources`` (WARN: two sources; OK: the others of a trusted one); the node reports the
        subscriptions' losses."""
        report = self._gate.report()
        if report is not None and self._node is not None:
            self._node.publish_status("sources", report[0], f"input messages {report[1]} (recorded on "
                                      f"<topic>{REFUSED})", self._node.now())

    def close(self) -> None:
        """Nothing of its own: the node destroys the subscriptions."""
