"""An input's sources: who sends it is part of its identity. Two sources of one input (two nodes
publishing one topic, two ECUs sending one parameter group) give two values the monitor would
alternate between, all OK: while two are heard, neither is used (``sensors_disagree``, naming both)
unless the configuration names the one to trust. ``two_sources`` is the finding's wording for
every driver (the CAN decoder's source addresses, the node's publishers); ``SourceGate`` the
verdict on each message of the node's input topics. Times in ns.
"""

from __future__ import annotations

from collections import Counter
from dataclasses import dataclass
from typing import Hashable, Mapping, Sequence

from .findings import Code, Finding, Level


def two_sources(sources: Sequence[str], sends: str, give: str, trust: str) -> str:
    """``<a> and <b> both send <sends>: two <give>, neither is used. Name the one to trust <trust>``."""
    return f"{' and '.join(sources)} both send {sends}: two {give}, neither is used. Name the one to trust {trust}"


@dataclass
class Heard:
    """A source of a topic: its name (None while not known) and when it was last heard (ns)."""

    name: str | None
    last_ns: int


@dataclass(frozen=True)
class Admission:
    """The verdict on one message: ``used`` or not, and the finding that says why not (None when it is
    used, or when it comes from a source other than the trusted one: counted, reported at ``report``)."""

    used: bool
    finding: Finding | None = None


USED = Admission(True)


class SourceGate:
    """The sources heard on each topic within the staleness limit, and the verdict on each message.

    ``trusted``: topic -> the name of the one source to use (its other sources' messages are not used).
    A topic without one: while one source is heard, its messages are used; once a second one is heard
    (both within the staleness limit), neither is (``sensors_disagree``); when one has been silent for
    the staleness limit, the other is used again. A message whose source is not told (``key`` None) is
    used only while at most one source is heard and none is trusted.
    """

    def __init__(self, trusted: Mapping[str, str], option: str) -> None:
        self.trusted = dict(trusted)
        self._option = option   # what names the trusted sources, for the finding's hint
        self._heard: dict[str, dict[Hashable, Heard]] = {}
        self._refused: Counter[tuple[str, str]] = Counter()   # (topic, source name) -> not used since the last report
        self._untrusted: Counter[tuple[str, str]] = Counter()

    def admit(self, topic: str, key: Hashable | None, name: str | None, received_ns: int, limit_ns: int) -> Admission:
        """The verdict on a message of ``topic`` from source ``key`` (``name``: what the finding calls it,
        None if not known) received at ``received_ns``, sources silent for over ``limit_ns`` forgotten."""
        heard = self._heard.setdefault(topic, {})
        if key is not None:
            entry = heard.get(key)
            if entry is None:
                heard[key] = entry = Heard(name, received_ns)
            else:
                entry.last_ns = received_ns
                entry.name = name or entry.name
        if len(heard) > 1:
            for gone in [k for k, h in heard.items() if received_ns - h.last_ns > limit_ns]:
                del heard[gone]
        label = name or "a publisher not yet named in the graph"
        trusted = self.trusted.get(topic)
        if trusted is not None:
            if name == trusted:
                return USED
            self._untrusted[(topic, label)] += 1
            return Admission(False)
        if len(heard) <= 1:
            return USED
        self._refused[(topic, label)] += 1
        names = sorted(h.name or "a publisher not yet named" for h in heard.values())
        # the same text whichever of them sent this message: the diagnostics gate passes it once
        return Admission(False, Finding(Code.SENSORS_DISAGREE, two_sources(
            names, topic, f"nodes give its values (heard within staleness_limit, {limit_ns / 1e9:g} s)",
            f"with the node parameter {self._option} ('{topic}={names[0]}')") + "; not used"))

    def report(self) -> tuple[Level, str] | None:
        """What was not used since the last report, per topic and source (None if nothing): WARN for two
        sources, OK for the messages of sources other than a trusted one."""
        if not self._refused and not self._untrusted:
            return None
        parts = []
        if self._refused:
            parts.append("not used, two sources heard: " + _counts(self._refused))
        if self._untrusted:
            parts.append(f"not used, not the source {self._option} trusts: " + _counts(self._untrusted))
        level = Level.WARN if self._refused else Level.OK
        self._refused, self._untrusted = Counter(), Counter()
        return level, "; ".join(parts)


def _counts(counts: Counter[tuple[str, str]]) -> str:
    return ", ".join(f"{n} from {name} on {topic}" for (topic, name), n in sorted(counts.items()))
