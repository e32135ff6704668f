"""Whether the monitor is still solving: the live node's heartbeat goes STALE when no input has
been solved for the staleness limit, whatever else arrives (refused inputs, frames that map to no
input, inputs on topics nobody publishes). No rclpy: the driver hands in its steady clock (s).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

from .findings import Code, Finding, fmt


@dataclass
class Freshness:
    """The steady-clock time (s) of the last solved input, None before the first."""

    last_solved_s: float | None = None

    def solved(self, now_s: float) -> None:
        """An input was solved at ``now_s`` (s, steady clock)."""
        self.last_solved_s = now_s

    def stale(self, now_s: float, limit_s: float, sources: Sequence[str]) -> Finding | None:
        """The NOT_SOLVING finding at ``now_s`` (s) if nothing was solved within ``limit_s`` (s, the
        staleness limit), naming the ``sources`` the monitor takes its inputs from; else None."""
        listening = ", ".join(sources) or "(nothing)"
        if self.last_solved_s is None:
            return Finding(Code.NOT_SOLVING, f"no input solved yet; subscribed to {listening}: check that the "
                                             "sensors publish there (topic names, joint_map, pressure_topics)")
        idle_s = now_s - self.last_solved_s
        if idle_s <= limit_s:
            return None
        return Finding(Code.NOT_SOLVING, f"no input solved for {idle_s:.1f} s (staleness_limit {fmt(limit_s)} s): "
                                         f"the results are out of date; inputs from {listening}")
