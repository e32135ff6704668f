"""Two recordings of the monitor's outputs compared message by message, field by field.

Used by `make demo` (the live node's bag against the replay of it) and by the tests that hold
the replay to the node. Numbers are compared with a relative tolerance (scale: the largest
magnitude in the message, at least 1), text and integers exactly; diagnostics by the level and
message of the monitor's per-input status (heartbeat repeats are not recorded).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Iterator

from linkage_monitor.bag.reader import read_bag

OUTPUT_TOPICS = ("/hinge_reactions", "/hitch_state", "/steerability")


@dataclass
class Comparison:
    """Messages compared per topic, the largest relative difference of a number, and the first
    differences found (empty when the recordings agree)."""

    counts: dict[str, int] = field(default_factory=dict)
    worst: float = 0.0
    differences: list[str] = field(default_factory=list)

    @property
    def equal(self) -> bool:
        return not self.differences


def _numbers(msg: Any, prefix: str = "") -> Iterator[tuple[str, Any]]:
    """(path, value) of every leaf field of an rclpy message (lists indexed)."""
    for name in msg.get_fields_and_field_types():
        value = getattr(msg, name)
        path = f"{prefix}{name}"
        if hasattr(value, "get_fields_and_field_types"):
            yield from _numbers(value, path + ".")
        elif isinstance(value, (list, tuple)) or (hasattr(value, "__len__") and not isinstance(value, (str, bytes))):
            for i, item in enumerate(value):
                if hasattr(item, "get_fields_and_field_types"):
                    yield from _numbers(item, f"{path}[{i}].")
                else:
                    yield f"{path}[{i}]", item
        else:
            yield path, value


def _compare_message(a: Any, b: Any, where: str, rel: float, out: Comparison) -> None:
    fa, fb = list(_numbers(a)), list(_numbers(b))
    if [p for p, _ in fa] != [p for p, _ in fb]:
        out.differences.append(f"{where}: different fields")
        return
    scale = max([abs(v) for _, v in fa if isinstance(v, float) and math.isfinite(v)] + [1.0])
    for (path, va), (_, vb) in zip(fa, fb):
        if isinstance(va, float):
            if math.isnan(va) and math.isnan(vb):
                continue
            diff = abs(va - vb) / scale if math.isfinite(va) and math.isfinite(vb) else (0.0 if va == vb else math.inf)
            out.worst = max(out.worst, diff)
            if diff > rel:
                out.differences.append(f"{where}.{path}: {va!r} != {vb!r} (relative {diff:.2e})")
        elif va != vb:
            out.differences.append(f"{where}.{path}: {va!r} != {vb!r}")


def _diagnostics(bag: Path, status_name: str) -> list[tuple[int, str, str]]:
    """(level, message, input stamp) of the monitor's per-input statuses, in recording order."""
    rows = []
    for _, _, _, _, msg in read_bag(bag, topics=["/diagnostics"]):
        for s in msg.status:
            if s.name == status_name:
                stamp = next((kv.value for kv in s.values if kv.key == "input stamp [ns]"), "")
                rows.append((s.level[0] if isinstance(s.level, bytes) else int(s.level), s.message, stamp))
    return rows


def compare_bags(live: Path, offline: Path, status_name: str, rel: float = 1e-9,
                 topics: tuple[str, ...] = OUTPUT_TOPICS) -> Comparison:
    """Compare the outputs recorded in ``live`` with those in ``offline`` (same order expected)."""
    out = Comparison()
    for topic in topics:
        a = [m for *_, m in read_bag(live, topics=[topic])]
        b = [m for *_, m in read_bag(offline, topics=[topic])]
        out.counts[topic] = len(a)
        if len(a) != len(b):
            out.differences.append(f"{topic}: {len(a)} messages in {live}, {len(b)} in {offline}")
            continue
        for i, (ma, mb) in enumerate(zip(a, b)):
            _compare_message(ma, mb, f"{topic}[{i}]", rel, out)
    da, db = _diagnostics(live, status_name), _diagnostics(offline, status_name)
    out.counts["/diagnostics"] = len(da)
    if da != db:
        first = next((i for i, (x, y) in enumerate(zip(da, db)) if x != y), min(len(da), len(db)))
        out.differences.append(f"/diagnostics: {len(da)} vs {len(db)} statuses, first difference at {first}: "
                               f"{da[first] if first < len(da) else None} != {db[first] if first < len(db) else None}")
    return out
