"""Counting inputs the monitor never saw (no rclpy: the node hands in what the middleware says).

Two sources, because neither sees everything: the middleware's message-lost event (samples
the DDS reader knows it missed, e.g. best-effort gaps) and gaps in each publisher's
publication sequence numbers as delivered to the callback (also samples pushed out of a full
subscription queue before the executor took them). A gap counts once: the event's count is
kept apart and both are reported. Not seen by either: samples of a publisher pushed out of the
queue before the first one the node takes from it (that first sequence number may as well follow
messages published before the node subscribed, which are no loss).
"""

from __future__ import annotations

from dataclasses import dataclass, field


@dataclass
class LossCounter:
    """Inputs received, and inputs lost by sequence gaps and by middleware events, per topic."""

    received: dict[str, int] = field(default_factory=dict)
    gaps: dict[str, int] = field(default_factory=dict)
    events: dict[str, int] = field(default_factory=dict)
    _last_seq: dict[tuple[str, object], int] = field(default_factory=dict)
    _reported: int = 0

    def on_message(self, topic: str, publisher: object, sequence: int | None) -> None:
        """One message of ``topic`` from ``publisher`` (any hashable id) with its publication
        sequence number (None when the middleware gives none)."""
        self.received[topic] = self.received.get(topic, 0) + 1
        if sequence is None or sequence <= 0:
            return
        key = (topic, publisher)
        last = self._last_seq.get(key)
        if last is not None and sequence > last + 1:
            self.gaps[topic] = self.gaps.get(topic, 0) + sequence - last - 1
        if last is None or sequence > last:
            self._last_seq[key] = sequence

    def on_lost_event(self, topic: str, count_change: int) -> None:
        """The middleware reports ``count_change`` more samples of ``topic`` lost."""
        self.events[topic] = self.events.get(topic, 0) + int(count_change)

    @property
    def lost(self) -> int:
        """Inputs known lost so far (the larger of the two counts per topic)."""
        return sum(max(self.gaps.get(t, 0), self.events.get(t, 0)) for t in set(self.gaps) | set(self.events))

    def new_since_report(self) -> int:
        """Inputs lost since the last call (and mark them reported)."""
        lost = self.lost
        new, self._reported = lost - self._reported, lost
        return new

    def summary(self) -> str:
        """``/joint_states: 3 lost of 1203 received (sequence gaps 3, middleware 0); ...``."""
        topics = sorted(set(self.received) | set(self.gaps) | set(self.events))
        return "; ".join(f"{t}: {max(self.gaps.get(t, 0), self.events.get(t, 0))} lost of {self.received.get(t, 0)} "
                         f"received (sequence gaps {self.gaps.get(t, 0)}, middleware {self.events.get(t, 0)})"
                         for t in topics)
