"""Consecutive input events of one form as arrays: what the batched path accepts at once.

``InputColumns`` holds a run of JointStateEvents (all with the same joint names, positions and,
given or not alike, velocities of that length) and PressureEvents, in their order, as columns:
header stamps and receive times (ns), the JointStates' places in the run and their positions
(rad or m) and velocities (rad/s or m/s), each pressure topic's places and fluid pressures (Pa).
The replay reads them straight from a block of recorded messages (``wire.sensor_messages``);
``of_events`` gathers them from event objects. ``event`` gives any one of them back as its event,
the same values, for the path that takes one event at a time.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Sequence

import numpy as np

from .events import InputEvent, JointStateEvent, PressureEvent


@dataclass
class InputColumns:
    """A run of input events as arrays (module docstring). ``topics``: each event's topic;
    ``stamps_ns``, ``receive_ns`` (size,) int64; ``joint_at`` (m,) the JointStates' places, ``positions``
    (m, width), ``velocities`` (m, width) or None (none given); ``pressure_at`` / ``pressures``: per topic,
    its FluidPressures' places and values (Pa)."""

    topics: list[str]
    stamps_ns: np.ndarray
    receive_ns: np.ndarray
    joint_topic: str = ""
    names: tuple[str, ...] = ()
    joint_at: np.ndarray = field(default_factory=lambda: np.zeros(0, np.intp))
    positions: np.ndarray = field(default_factory=lambda: np.zeros((0, 0)))
    velocities: np.ndarray | None = None
    pressure_at: dict[str, np.ndarray] = field(default_factory=dict)
    pressures: dict[str, np.ndarray] = field(default_factory=dict)
    events: Sequence[InputEvent] | None = None   # the event objects they were gathered from, if any

    @property
    def size(self) -> int:
        return len(self.topics)

    @staticmethod
    def of_events(events: Sequence[InputEvent]) -> InputColumns | None:
        """The leading events of ``events`` of one form as columns (None when the first is not of it,
        or their numbers are not numbers)."""
        topics: list[str] = []
        stamps: list[int] = []
        receive: list[int] = []
        joint_at: list[int] = []
        positions: list[Sequence[float]] = []
        velocities: list[Sequence[float]] = []
        pressure_at: dict[str, list[int]] = {}
        pressures: dict[str, list[float]] = {}
        names: Sequence[str] = ()
        given, joint_topic = False, ""
        for i, event in enumerate(events):
            if isinstance(event, JointStateEvent):
                if not joint_at:
                    names, given, joint_topic = event.names, bool(event.velocities), event.topic
                width = len(names)
                if (event.topic != joint_topic or event.names != names or len(event.positions) != width
                        or bool(event.velocities) != given or (given and len(event.velocities) != width)):
                    break
                joint_at.append(i)
                positions.append(event.positions)
                velocities.append(event.velocities)
            elif isinstance(event, PressureEvent):
                pressure_at.setdefault(event.topic, []).append(i)
                pressures.setdefault(event.topic, []).append(event.fluid_pressure)
            else:
                break
            topics.append(event.topic)
            stamps.append(event.stamp_ns)
            receive.append(event.receive_ns)
        if not topics:
            return None
        try:
            shape = (len(joint_at), len(names))
            return InputColumns(topics, np.array(stamps, np.int64), np.array(receive, np.int64), joint_topic,
                                tuple(names), np.array(joint_at, np.intp), np.array(positions, float).reshape(shape),
                                np.array(velocities, float).reshape(shape) if given else None,
                                {t: np.array(at, np.intp) for t, at in pressure_at.items()},
                                {t: np.array(v, float) for t, v in pressures.items()}, events[:len(topics)])
        except (OverflowError, TypeError, ValueError):   # not numbers: the events one by one say so
            return None

    def head(self, end: int) -> InputColumns:
        """The first ``end`` events."""
        if end >= self.size:
            return self
        m = int(np.searchsorted(self.joint_at, end))
        kept = {t: int(np.searchsorted(at, end)) for t, at in self.pressure_at.items()}
        return InputColumns(self.topics[:end], self.stamps_ns[:end], self.receive_ns[:end], self.joint_topic,
                            self.names, self.joint_at[:m], self.positions[:m],
                            self.velocities[:m] if self.velocities is not None else None,
                            {t: at[:kept[t]] for t, at in self.pressure_at.items() if kept[t]},
                            {t: v[:kept[t]] for t, v in self.pressures.items() if kept[t]},
                            self.events[:end] if self.events is not None else None)

    def tail(self, start: int) -> InputColumns:
        """The events from place ``start`` on (their places counted from it)."""
        if start == 0:
            return self
        m = int(np.searchsorted(self.joint_at, start))
        cut = {t: int(np.searchsorted(at, start)) for t, at in self.pressure_at.items()}
        return InputColumns(self.topics[start:], self.stamps_ns[start:], self.receive_ns[start:], self.joint_topic,
                            self.names, self.joint_at[m:] - start, self.positions[m:],
                            self.velocities[m:] if self.velocities is not None else None,
                            {t: at[cut[t]:] - start for t, at in self.pressure_at.items() if cut[t] < len(at)},
                            {t: v[cut[t]:] for t, v in self.pressures.items() if cut[t] < len(v)},
                            self.events[start:] if self.events is not None else None)

    def event(self, i: int) -> InputEvent:
        """Event ``i`` as the event object it was read as (the one it was gathered from, if any)."""
        if self.events is not None:
            return self.events[i]
        stamp, receive = int(self.stamps_ns[i]), int(self.receive_ns[i])
        k = int(np.searchsorted(self.joint_at, i))
        if k < len(self.joint_at) and self.joint_at[k] == i:
            velocities = tuple(self.velocities[k].tolist()) if self.velocities is not None else ()
            return JointStateEvent(self.topics[i], list(self.names), tuple(self.positions[k].tolist()), velocities,
                                   stamp, receive)
        topic = self.topics[i]
        at = self.pressure_at[topic]
        return PressureEvent(topic, float(self.pressures[topic][int(np.searchsorted(at, i))]), stamp, receive)
