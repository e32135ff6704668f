"""A monitoring run into a bag, in the one order the live node and the replay both record it.

The bag begins with the mechanism description and the configuration; then, per input, the
input's bytes as they arrived (stamped with its header stamp, or with its receive time when the
header cannot be read), followed by what its step sent (``wire.step_messages``): HingeReactions,
HitchState, Steerability, the linkage markers, the DiagnosticArray, each stamped with the step's
stamp. Everything of one input is logged at its receive time (ns, the monitor's clock), so the
replay of a node's bag writes the node's bag again, message for message.

The node records message by message as the messages come (``input``, ``step``, ``status``); the
replay records many inputs and their steps at once (``steps``: one ``BagWriter.write_rows`` call, the
same messages in the same order). ``STEP_SENDS`` is the order of a step's messages for both.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable, Iterator, NamedTuple, Sequence

import numpy as np
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from std_msgs.msg import String

from linkage_monitor.mechanics import Mechanism
from linkage_monitor.monitoring.config import CONFIG_TOPIC, MonitorConfig, Topics
from linkage_monitor.wire.diagnostics import DIAGNOSTIC_ARRAY
from linkage_monitor.wire.markers import MARKER_ARRAY
from linkage_monitor.wire.outputs import HINGE_REACTIONS, HITCH_STATE, STEERABILITY, OutputRows
from linkage_monitor.wire.step_messages import SentBesides, StepMessages

from .metadata import yaml_text
from .row_block import MessageRows
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


@dataclass
class RecordedInputs:
    """Input messages as the bag holds them (each a ``RecordedInput``), as columns in their order: topics,
    type names, header stamps (ns; the receive time of one that does not read), receive times (ns), CDR bytes."""

    topic: list[str] = field(default_factory=list)
    type_name: list[str] = field(default_factory=list)
    stamp_ns: list[int] = field(default_factory=list)
    receive_ns: list[int] = field(default_factory=list)
    data: list[bytes] = field(default_factory=list)

    def __len__(self) -> int:
        return len(self.data)

    def __iter__(self) -> Iterator[RecordedInput]:
        return map(RecordedInput, self.topic, self.type_name, self.stamp_ns, self.receive_ns, self.data)

    def span(self, lo: int, hi: int) -> RecordedInputs:
        """The inputs lo..hi-1."""
        return RecordedInputs(self.topic[lo:hi], self.type_name[lo:hi], self.stamp_ns[lo:hi], self.receive_ns[lo:hi],
                              self.data[lo:hi])

    def extend(self, more: RecordedInputs) -> None:
        """``more`` added after these."""
        for mine, theirs in zip(self._columns(), more._columns()):
            mine += theirs

    def take(self, count: int) -> RecordedInputs:
        """The first ``count`` inputs, taken out of these."""
        taken = self.span(0, count)
        for column in self._columns():
            del column[:count]
        return taken

    def _columns(self) -> tuple[list, ...]:
        return self.topic, self.type_name, self.stamp_ns, self.receive_ns, self.data


class StepSend(NamedTuple):
    """A message a step may send: ``topic`` the ``Topics`` field naming its topic, its type name, and
    ``of``: its CDR bytes among a step's messages (None: not sent)."""

    topic: str
    type_name: str
    of: Callable[[StepMessages], bytes | None]


STEP_SENDS = (   # what a step sends, in the order it is recorded after its input
    StepSend("hinge_reactions", HINGE_REACTIONS, lambda m: None if m.outputs is None else m.outputs.hinge_reactions),
    StepSend("hitch_state", HITCH_STATE, lambda m: None if m.outputs is None else m.outputs.hitch_state),
    StepSend("steerability", STEERABILITY, lambda m: None if m.outputs is None else m.outputs.steerability),
    StepSend("markers", MARKER_ARRAY, lambda m: m.markers),
    StepSend("diagnostics", DIAGNOSTIC_ARRAY, lambda m: m.diagnostic),
)


def mechanism_yaml(description: Mechanism) -> str:
    """The mechanism description as the node publishes and records it (YAML text)."""
    return yaml_text(dict(description.raw), allow_unicode=True)


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
        """What a step sent, after its input: the outputs, the markers, the diagnostic (those sent, in the
        order of ``STEP_SENDS``), stamped with the step's stamp, logged at ``receive_ns`` (ns)."""
        for send in STEP_SENDS:
            data = send.of(messages)
            if data is not None:
                self.writer.write(getattr(self.topics, send.topic), data, messages.stamp_ns, type_name=send.type_name,
                                  qos=self.output_qos, log_time_ns=receive_ns)

    def steps(self, inputs: RecordedInputs, stamps_ns: np.ndarray, sent: SentBesides,
              output_rows: Sequence[OutputRows]) -> None:
        """Each of ``inputs`` and what its step sent, as ``input`` then ``step`` of each in turn record them
        (the step's messages logged at its input's receive time), in one ``BagWriter.write_rows``: the inputs
        gathered by topic and type, each kind of step message by kind. ``stamps_ns``: the steps' stamps (ns);
        their markers and diagnostics are in ``sent`` (``StepMessenger.sent_of`` of the steps), their outputs
        in ``output_rows`` (``OutputEncoder.output_rows`` of the same steps)."""
        n = len(inputs)
        recorded = np.zeros((n, 1 + len(STEP_SENDS)), bool)   # per input: its own message, then each its step may send
        recorded[:, 0] = True
        column = {send.topic: 1 + k for k, send in enumerate(STEP_SENDS)}
        besides = {"markers": sent.markers, "diagnostics": sent.diagnostics}   # by STEP_SENDS topic
        for topic, by_step in besides.items():
            recorded[list(by_step), column[topic]] = True
        for rows in output_rows:
            recorded[rows.steps, column[rows.kind]] = True
        place = np.cumsum(recorded).reshape(recorded.shape) - 1   # each recorded message's place in the block
        receive = np.array(inputs.receive_ns, np.int64)
        input_stamp = np.array(inputs.stamp_ns, np.int64)
        step_stamp = stamps_ns
        kinds = list(zip(inputs.topic, inputs.type_name))
        codes = {kind: code for code, kind in enumerate(dict.fromkeys(kinds))}   # each (topic, type)'s, by first input
        kind_of = np.fromiter(map(codes.__getitem__, kinds), np.intp, n)
        parts = []
        for (topic, type_name), code in codes.items():
            at = np.flatnonzero(kind_of == code)
            parts.append(MessageRows.of_messages(topic, type_name, [inputs.data[i] for i in at.tolist()], place[at, 0],
                                                 input_stamp[at], receive[at], self.input_qos))
        for rows in output_rows:
            send, at = STEP_SENDS[column[rows.kind] - 1], rows.steps
            parts.append(MessageRows(getattr(self.topics, send.topic), send.type_name, rows.rows,
                                     place[at, column[rows.kind]], step_stamp[at], receive[at], qos=self.output_qos))
        for topic, by_step in besides.items():
            if by_step:
                k = column[topic]
                send, at = STEP_SENDS[k - 1], np.array(sorted(by_step), np.int64)
                parts.append(MessageRows.of_messages(getattr(self.topics, send.topic), send.type_name,
                                                     [by_step[i] for i in at.tolist()], place[at, k], step_stamp[at],
                                                     receive[at], self.output_qos))
        self.writer.write_rows(parts)

    def status(self, diagnostic: bytes, stamp_ns: int, receive_ns: int) -> None:
        """A DiagnosticArray (CDR bytes) on the diagnostics topic, stamped ``stamp_ns``, logged at ``receive_ns``."""
        self.writer.write(self.topics.diagnostics, diagnostic, stamp_ns, type_name=DIAGNOSTIC_ARRAY,
                          qos=self.output_qos, log_time_ns=receive_ns)
