"""How CAN frames ended in the decoder: each frame's outcome (decoded, ignored, refused) with the
input events it gave or the finding why not, a block's outcomes with its inputs as arrays, and the
counts of all frames received (decoded + ignored + refused = received), with the identifiers that
were ignored and the frames lost before the bridge read them.
"""

from __future__ import annotations

from collections import Counter
from dataclasses import dataclass, field
from enum import Enum
from typing import NamedTuple

import numpy as np

from linkage_monitor.monitoring.events import InputEvent
from linkage_monitor.monitoring.findings import Code, Finding, Level


class Outcome(Enum):
    """How a frame ended."""

    DECODED = "decoded"
    IGNORED = "ignored"
    REFUSED = "refused"


OUTCOMES = tuple(Outcome)   # BlockDecoded.outcome holds indices into this
DECODED, IGNORED, REFUSED = (OUTCOMES.index(o) for o in (Outcome.DECODED, Outcome.IGNORED, Outcome.REFUSED))


@dataclass(frozen=True)
class Decoded:
    """One frame's outcome: the input events it gives (decoded) or the finding why not (refused)."""

    outcome: Outcome
    events: tuple[InputEvent, ...] = ()
    finding: Finding | None = None


# Counters as fields, alike in form only to test/support/fuzz_check.FuzzTally: other things counted.
@dataclass
class FrameCounts:
    """Frames received and how they ended; unknown identifiers with their counts."""

    received: int = 0
    decoded: int = 0
    ignored: int = 0
    refused: int = 0
    lost: int = 0   # frames dropped before the bridge read them (the socket's receive buffer was full)
    unknown_ids: Counter = field(default_factory=Counter)
    untrusted_ids: Counter = field(default_factory=Counter)   # J1939 frames of a source the mapping does not name
    two_sources: dict[str, list[int]] = field(default_factory=dict)   # message -> the source addresses sending it

    def summary(self) -> str:
        """``1203 frames: 1200 decoded, 2 ignored (2 of unknown identifiers 0x123 ×2), 1 refused``, then
        the frames of untrusted sources and the messages sent by two sources."""
        ignored = [f"{sum(ids.values())} of {what} {_counted(ids)}" for what, ids in (
            ("unknown identifiers", self.unknown_ids), ("sources the mapping does not trust", self.untrusted_ids)) if ids]
        text = (f"{self.received} frames: {self.decoded} decoded, {self.ignored} ignored"
                f"{' (' + '; '.join(ignored) + ')' if ignored else ''}, {self.refused} refused")
        if self.lost:
            text += f"; {self.lost} lost before the bridge read them (receive buffer full)"
        for message, sources in self.two_sources.items():
            text += (f"; {message} sent by {len(sources)} sources ({', '.join(f'0x{a:02X}' for a in sources)}): "
                     "not used, name the one to trust (source_address)")
        return text

    @property
    def level(self) -> Level:
        """WARN while frames were lost or an input's parameter group has two sources (not used), else OK."""
        return Level.WARN if self.lost or self.two_sources else Level.OK

    def lose(self, dropped: int, source: str) -> Finding:
        """Count ``dropped`` frames lost at the bus's socket before the bridge read them; the finding."""
        self.lost += dropped
        return Finding(Code.INPUTS_LOST, (
            f"{dropped} CAN frame(s) lost on {source} ({self.lost} in all): the socket's receive buffer overflowed "
            "before the bridge read them (more frames per second than it decodes and solves); none of them is used"))


SHOWN_IDS = 10   # identifiers a summary lists with their counts


def _counted(ids: Counter) -> str:
    """``0x123 ×2, 0x18FEF100 ×1`` (the most frequent SHOWN_IDS, then how many more)."""
    shown = ", ".join(f"0x{i:X} ×{n}" for i, n in ids.most_common(SHOWN_IDS))
    return shown + (f" and {len(ids) - SHOWN_IDS} more" if len(ids) > SHOWN_IDS else "")


class DecodedInputs(NamedTuple):
    """The inputs one mapped message gave in a block: ``rows`` (m,) the frames (rows of the block) it
    decoded; the JointState on ``joint_topic`` of ``joint_names`` (none: no JointState) at ``positions``
    (m, len(joint_names)) rad / m; a FluidPressure on each of ``pressure_topics`` of ``pressures``
    (m, len(pressure_topics)) Pa, in the monitor's convention. Each frame's events in ``decode``'s order:
    the JointState, then the pressures."""

    rows: np.ndarray
    joint_topic: str
    joint_names: tuple[str, ...]
    positions: np.ndarray
    pressure_topics: tuple[str, ...]
    pressures: np.ndarray

    @property
    def events_per_frame(self) -> int:
        """The input events each of its frames gives."""
        return (1 if self.joint_names else 0) + len(self.pressure_topics)


@dataclass(frozen=True)
class BlockDecoded:
    """How each frame of a block ended: ``outcome`` (n,) indices into OUTCOMES; the inputs decoded with
    numpy, per mapped message; the frames decoded one by one (``decode``) with their Decoded, by row."""

    outcome: np.ndarray
    inputs: tuple[DecodedInputs, ...]
    single: dict[int, Decoded]

    def refusals(self) -> list[Finding]:
        """The finding of each refused frame, in frame order."""
        return [d.finding for _, d in sorted(self.single.items()) if d.finding is not None]
