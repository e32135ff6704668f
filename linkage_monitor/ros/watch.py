"""The subscriber side of ``linkage-monitor watch``: the monitor node's output topics taken in, the
latest values kept as a ``viz.terminal_view.WatchRecord``.

Topics as the node names them (``ros/node.py``): ``hinge_reactions``, ``hitch_state``,
``steerability`` relative to the namespace (the watch node is created in the monitor's namespace,
so ``--ros-args -r`` remappings apply to both alike) and ``/diagnostics``. /diagnostics is shared
by every node of the ROS domain: a status is taken only when its name is ``<node>: ...`` for the
node that publishes the watched ``hinge_reactions`` (rclpy's message info carries no publisher
gid to tell two nodes apart); the others are counted by name (the record's ``ignored``), not shown.
When nodes of that name in more than one namespace publish /diagnostics, their statuses cannot be
told apart: the record says so in a WARN status of the watch itself.

Forces N, angles rad, times s (receive times: the middleware's, since the epoch).
"""

from __future__ import annotations

import math
import time
from collections import deque
from dataclasses import dataclass, field
from typing import Any, Callable

from diagnostic_msgs.msg import DiagnosticArray
from rclpy.node import Node
from rclpy.qos import QoSProfile, ReliabilityPolicy
from rclpy.serialization import deserialize_message

from linkage_monitor.monitoring.findings import Level
from linkage_monitor.msg import HingeReactions, HitchState, Steerability
from linkage_monitor.viz.terminal_view import HingeLoad, StatusLine, TopicRate, WatchRecord

HINGE_REACTIONS, HITCH_STATE, STEERABILITY = "hinge_reactions", "hitch_state", "steerability"  # as the node names them
DIAGNOSTICS = "/diagnostics"
# reliable, as the node publishes its outputs (ros/node.py OUTPUT_QOS): every solve is seen, so the peaks are
# the peaks; keep-last, so a watch that falls behind never holds the node up
WATCH_QOS = QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE)
GRAPH_PERIOD_S = 1.0   # s, the ROS graph is asked at most this often which node publishes the outputs
RATE_WINDOW_S = 2.0   # s, the received rates are counted over this window
RATE_MIN_SPAN_S = 0.5   # s, the shortest time a rate is taken over (right after a topic's first arrival)
CODES_KEY = "findings"   # wire.diagnostics.CODES_KEY (importing wire loads the compiled kernels: seconds)
INPUTS_STATUS = ": inputs"   # the node's input-stream status (<node>: inputs): its losses
REFERENCES = {Steerability.REFERENCE_UNIT: "unit", Steerability.REFERENCE_TRACTOR: "tractor"}


@dataclass
class _Arrivals:
    """Receive times of one topic within the rate window (s since the epoch: the middleware's, so a
    watch that takes a backlog late still rates the stream as it came), the first ever, and the count in all."""

    times: deque[float] = field(default_factory=deque)
    first: float | None = None
    count: int = 0

    def arrived(self, received_s: float) -> None:
        self.times.append(received_s)
        self.first = received_s if self.first is None else self.first
        self.count += 1

    def rate(self, now: float) -> float:
        """Messages per second received in the last RATE_WINDOW_S, or since the first arrival when that
        is later but at least RATE_MIN_SPAN_S ago (a topic that started lately is not rated over time it
        did not exist; 0 before an arrival). A burst counts as its number of messages, never over its own
        short span."""
        while self.times and self.times[0] < now - RATE_WINDOW_S:
            self.times.popleft()
        if self.first is None:
            return 0.0
        return len(self.times) / max(RATE_MIN_SPAN_S, min(RATE_WINDOW_S, now - self.first))


class OutputWatch:
    """Subscribes ``node`` to the monitor's outputs and keeps their latest values, each hinge's
    peak since the watch started, the latest status of each name on /diagnostics and the rates.

    ``stale_after_s``: the record says STALE when no output arrived for longer (s)."""

    def __init__(self, node: Node, stale_after_s: float) -> None:
        self.node, self.stale_after_s = node, stale_after_s
        self.topics = {name: node.resolve_topic_name(name) for name in (HINGE_REACTIONS, HITCH_STATE, STEERABILITY,
                                                                        DIAGNOSTICS)}
        self._arrivals = {topic: _Arrivals() for topic in self.topics.values()}
        self._hinges: HingeReactions | None = None
        self._latest: dict[str, bytes] = {}   # hitch_state, steerability: the latest CDR bytes, read when drawn
        self._peaks: dict[str, float] = {}
        self._last_output: float | None = None
        self._statuses: dict[str, StatusLine] = {}
        self._monitors: set[str] = set()
        self._graph_asked, self._ambiguous = -GRAPH_PERIOD_S, ""
        self._status_counts: dict[str, int] = {}   # status name -> statuses received
        self._subscriptions: list[tuple[Any, Callable[[Any, dict], None]]] = []
        # every HingeReactions is read (the peaks); of the two others only the latest, when the record is made
        for name, msg_type, callback, raw in (
                (HINGE_REACTIONS, HingeReactions, self._output_callback(HINGE_REACTIONS), False),
                (HITCH_STATE, HitchState, self._output_callback(HITCH_STATE), True),
                (STEERABILITY, Steerability, self._output_callback(STEERABILITY), True),
                (DIAGNOSTICS, DiagnosticArray, self._on_diagnostics, False)):
            # a callback of two arguments is given the message info too (rclpy's stubs know one argument only)
            sub = node.create_subscription(msg_type, name, callback, WATCH_QOS, raw=raw)  # type: ignore[arg-type]
            self._subscriptions.append((sub, callback))

    def drain(self) -> None:
        """Take every message waiting in the subscriptions' queues (rclpy's executor takes one per wake-up)."""
        for sub, callback in self._subscriptions:
            while True:
                with sub.handle:   # as rclpy's executor takes a message (Executor._take_subscription)
                    taken = sub.handle.take_message(sub.msg_type, sub.raw)
                if taken is None:
                    break
                callback(*taken)

    def _output_callback(self, name: str) -> Callable[[Any, dict], None]:
        def callback(msg: Any, info: dict) -> None:
            received = _received_s(info)
            self._arrivals[self.topics[name]].arrived(received)
            self._last_output = received
            if name == HINGE_REACTIONS:
                self._on_hinges(msg)
            else:
                self._latest[name] = msg
        return callback

    def _on_hinges(self, msg: HingeReactions) -> None:
        self._hinges = msg
        for h in msg.hinges:
            if math.isfinite(h.magnitude):
                self._peaks[h.name] = max(self._peaks.get(h.name, 0.0), h.magnitude)

    def _on_diagnostics(self, msg: DiagnosticArray, info: dict) -> None:
        """Every status kept, the latest per name, and counted: whose they are is decided when the
        record is made (the graph may not know the monitor yet when its first statuses arrive)."""
        self._arrivals[self.topics[DIAGNOSTICS]].arrived(_received_s(info))
        for status in msg.status:
            codes = next((kv.value for kv in status.values if kv.key == CODES_KEY), "")
            self._statuses[status.name] = StatusLine(status.name, _level_name(status.level), status.message, codes)
            self._status_counts[status.name] = self._status_counts.get(status.name, 0) + 1

    def _monitor_names(self) -> set[str]:
        """The names of the nodes that publish the watched ``hinge_reactions`` (the graph asked at most
        once a second)."""
        now = time.monotonic()
        if now - self._graph_asked >= GRAPH_PERIOD_S:
            self._graph_asked = now
            self._monitors = {p.node_name for p in self.node.get_publishers_info_by_topic(self.topics[HINGE_REACTIONS])}
            namespaces = sorted({p.node_namespace for p in self.node.get_publishers_info_by_topic(DIAGNOSTICS)
                                 if p.node_name in self._monitors})
            self._ambiguous = "" if len(namespaces) <= 1 else (
                f"nodes named {', '.join(sorted(self._monitors))} in {len(namespaces)} namespaces "
                f"({', '.join(namespaces)}) publish /diagnostics: the statuses shown may be another monitor's; "
                "give each monitor its own node name (--ros-args -r __node:=NAME)")
        return self._monitors

    def missing(self) -> list[str]:
        """The watched topics on which nothing has arrived yet (for /diagnostics: no status of the monitor)."""
        missing = [self.topics[HINGE_REACTIONS]] if self._hinges is None else []
        missing += [self.topics[name] for name in (HITCH_STATE, STEERABILITY) if name not in self._latest]
        monitors = self._monitor_names()
        return missing + ([] if any(name.partition(": ")[0] in monitors for name in self._statuses) else [DIAGNOSTICS])

    def _read(self, name: str, msg_type: type) -> Any:
        """The latest message of ``name`` (None before the first)."""
        data = self._latest.get(name)
        return deserialize_message(data, msg_type) if data is not None else None

    def record(self) -> WatchRecord:
        """What the watch knows now."""
        now = time.time()
        hinges, hitch, steer = self._hinges, self._read(HITCH_STATE, HitchState), self._read(STEERABILITY, Steerability)
        monitors = self._monitor_names()
        mine = [s for name, s in self._statuses.items() if name.partition(": ")[0] in monitors]
        loss = next((s for s in mine if s.name.endswith(INPUTS_STATUS)), None)
        return WatchRecord(
            namespace=self.node.get_namespace(), topics=tuple(self.topics.values()),
            mechanism=hinges.mechanism if hinges is not None else "",
            hinges=tuple(HingeLoad(h.name, h.magnitude, self._peaks.get(h.name, math.nan))
                         for h in (hinges.hinges if hinges is not None else ())),
            ratio=steer.ratio if steer is not None else math.nan,
            ratio_min=steer.ratio_min if steer is not None else math.nan,
            margin=steer.margin if steer is not None else math.nan,
            ratio_reference=REFERENCES.get(steer.reference, "") if steer is not None else "",
            lift_reserve=hitch.lift_reserve if hitch is not None else math.nan,
            implement_load_n=hitch.implement_load if hitch is not None else math.nan,
            min_transmission_angle_rad=hitch.min_transmission_angle if hitch is not None else math.nan,
            statuses=tuple(s for s in mine if s is not loss) + (
                (StatusLine("watch", "WARN", self._ambiguous),) if self._ambiguous else ()), loss=loss,
            ignored=tuple(sorted((name, n) for name, n in self._status_counts.items()
                                 if name.partition(": ")[0] not in monitors)),
            rates=tuple(TopicRate(topic, arrivals.rate(now), arrivals.count)
                        for topic, arrivals in self._arrivals.items()),
            output_age_s=None if self._last_output is None else now - self._last_output,
            stale_after_s=self.stale_after_s)


def _received_s(info: dict) -> float:
    """When the middleware received a message (its info's ``received_timestamp``), s since the epoch;
    now when it gives none."""
    received_ns = info.get("received_timestamp") or 0
    return received_ns / 1e9 if received_ns > 0 else time.time()


def _level_name(level: bytes | int) -> str:
    """A DiagnosticStatus level (rclpy gives its ``byte`` field as bytes) as its name: OK, WARN, ERROR,
    STALE, or ``level N`` for a value diagnostic_msgs does not define."""
    number = level[0] if isinstance(level, bytes) else int(level)
    return Level(number).name if number in set(Level) else f"level {number}"
