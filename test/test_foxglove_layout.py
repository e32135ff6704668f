"""docs/foxglove_layout.json is a layout Foxglove can import and every plotted value exists: the
JSON parses, every panel of the layout tree has its configuration and every configuration a place
in the tree, and every Plot path (Foxglove's message path syntax: ``/topic.field``, ``[k]`` and ``[:]``
on a sequence, ``{name=="P03"}`` filtering one) names a field of the output message of its topic,
walked through the message layouts of msg/*.msg (``wire.layout``) down to a float64 or integer."""

from __future__ import annotations

import json
import re
from pathlib import Path

import pytest

from linkage_monitor.wire.layout import PRIMITIVES, layout

LAYOUT = Path(__file__).resolve().parent.parent / "docs" / "foxglove_layout.json"
TOPIC_TYPES = {"/hinge_reactions": "linkage_monitor/msg/HingeReactions", "/hitch_state": "linkage_monitor/msg/HitchState",
               "/steerability": "linkage_monitor/msg/Steerability"}   # as the node names them (ros/node.py)
_PART = re.compile(r"\.(\w+)|\[(?::|\d+)\]|\{(\w+)==\"[^\"]*\"\}")


def _panels(tree) -> list[str]:
    if isinstance(tree, str):
        return [tree]
    return _panels(tree["first"]) + _panels(tree["second"])


def _plot_paths() -> list[str]:
    config = json.loads(LAYOUT.read_text())["configById"]
    return [p["value"] for key, panel in config.items() if key.startswith("Plot!") for p in panel["paths"]]


def test_the_layout_parses_and_every_panel_is_placed():
    data = json.loads(LAYOUT.read_text())
    placed = _panels(data["layout"])
    assert sorted(placed) == sorted(data["configById"]) and len(set(placed)) == len(placed)


def test_the_plots_show_the_standard_uncertainties_and_the_weighing():
    paths = _plot_paths()
    for wanted in ("/steerability.margin_u", "/hitch_state.lift_reserve_u", "/hitch_state.implement_load_u",
                   "/hitch_state.implement_mass_estimate", "/hitch_state.implement_mass_estimate_u"):
        assert wanted in paths, wanted


@pytest.mark.parametrize("path", _plot_paths())
def test_every_plotted_path_is_a_number_of_its_topics_message(path):
    topic = path.partition(".")[0]
    kind, sequence = TOPIC_TYPES[topic], False
    at = len(topic)
    for match in _PART.finditer(path, at):
        assert match.start() == at, f"{path}: cannot read {path[at:]!r}"
        at = match.end()
        field_name, filtered = match.group(1), match.group(2)
        if field_name is not None:
            assert not sequence, f"{path}: .{field_name} of a sequence (index it first)"
            field = layout(kind).field(field_name)
            kind, sequence = field.kind, field.array == 0
        elif filtered is not None:
            assert not sequence
            layout(kind).field(filtered)   # the filter's field exists
        else:
            assert sequence, f"{path}: an index of a field that is not a sequence"
            sequence = False
    assert at == len(path), f"{path}: cannot read {path[at:]!r}"
    assert not sequence and kind in PRIMITIVES and kind != "bool", f"{path}: {kind} is not a number to plot"
