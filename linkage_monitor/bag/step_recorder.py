"""A monitoring run into a bag, in the one order the live node and the replay both record it.

The bag begins with the mechanism description and the configuration; then, per input, the
input's bytes as they arrived (stamped with its header stamp, or with its receive time when the
header cannot be read), followed by what its step sent (``wire.step_messages``): HingeReactions,
HitchState, Steerability, the linkage markers, the DiagnosticArray, each stamped with the step's
stamp. Everything of one input is logged at its receive time (ns, the monitor's clock), so the
replay of a node's bag writes the node's bag again, message for message.
"""

from __future__ import annotations

from typing import NamedTuple

import yaml
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from std_msgs.msg import String

from linkage_monitor.mechanics import Mechanism
from linkage_monitor.monitoring.config import CONFIG_TOPIC, MonitorConfig, Topics
from linkage_monitor.wire.diagnostics import DIAGNOSTIC_ARRAY
from linkage_monitor.wire.markers import MARKER_ARRAY
from linkage_monitor.wire.outputs import HINGE_REACTIONS, HITCH_STATE, STEERABILITY
from linkage_monitor.wire.step_messages import StepMessages

from .writer import BagWriter

CONFIG_QOS = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL)


class RecordedInput(NamedTuple):
    """An input message as the bag holds it: its CDR bytes as they arrived on ``topic``; ``stamp_ns``:
    its header stamp (its receive time when unreadable), ``receive_ns``: its log time (ns)."""

    topic: str
    type_name: str
    stamp_ns: int
    receive_ns: int
    data: bytes


def mechanism_yaml(description: Mechanism) -> str:
    """The mechanism description as the node publishes and records it (YAML text)."""
    return yaml.safe_dump(dict(description.raw), sort_keys=False, allow_unicode=True)


class StepRecorder:
    """Records a monitoring run into ``writer``: its beginning, inputs, steps and statuses.

    topics: the run's topics; input_qos / output_qos: the offered QoS recorded for the input and
    output topics (None: the writer's default).
    """

    def __init__(self, writer: BagWriter, topics: Topics, input_qos: QoSProfile | None = None,
                 output_qos: QoSProfile | None = None) -> None:
        self.writer, self.topics = writer, topics
        self.input_qos, self.output_qos = input_qos, output_qos

    def begin(self, description: Mechanism, config: MonitorConfig, now_ns: int) -> None:
        """The mechanism description and the configuration, at ``now_ns`` (ns)."""
        self.writer.record_mechanism(mechanism_yaml(description), now_ns)
        self.config(config, now_ns)

    def config(self, config: MonitorConfig, now_ns: int) -> None:
        """A configuration that applies from the next input on, at ``now_ns`` (ns)."""
        self.writer.write(CONFIG_TOPIC, String(data=config.to_yaml()), now_ns, qos=CONFIG_QOS, log_time_ns=now_ns)

    def input(self, topic: str, type_name: str, data: bytes, stamp_ns: int, receive_ns: int) -> None:
        """An input message's CDR bytes as they arrived on ``topic``: ``stamp_ns`` its header stamp (its
        receive time when unreadable), ``receive_ns`` its receive time (ns)."""
        self.writer.write(topic, data, stamp_ns, type_name=type_name, qos=self.input_qos, log_time_ns=receive_ns)

    def step(self, messages: StepMessages, receive_ns: int) -> None:
        """What a step sent, after its input: the outputs, the markers, the diagnostic (those sent)."""
        topics, write, stamp, qos = self.topics, self.writer.write, messages.stamp_ns, self.output_qos
        out = messages.outputs
        if out is not None:
            write(topics.hinge_reactions, out.hinge_reactions, stamp, type_name=HINGE_REACTIONS, qos=qos,
                  log_time_ns=receive_ns)
            write(topics.hitch_state, out.hitch_state, stamp, type_name=HITCH_STATE, qos=qos, log_time_ns=receive_ns)
            write(topics.steerability, out.steerability, stamp, type_name=STEERABILITY, qos=qos,
                  log_time_ns=receive_ns)
        if messages.markers is not None:
            write(topics.markers, messages.markers, stamp, type_name=MARKER_ARRAY, qos=qos, log_time_ns=receive_ns)
        if messages.diagnostic is not None:
            self.status(messages.diagnostic, stamp, receive_ns)

    def status(self, diagnostic: bytes, stamp_ns: int, receive_ns: int) -> None:
        """A DiagnosticArray (CDR bytes) on the diagnostics topic, stamped ``stamp_ns``, logged at ``receive_ns``."""
        self.writer.write(self.topics.diagnostics, diagnostic, stamp_ns, type_name=DIAGNOSTIC_ARRAY,
                          qos=self.output_qos, log_time_ns=receive_ns)
