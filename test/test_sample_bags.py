"""The shipped sample bags (bags/, made by `python tools/make_bags.py`) decode
message by message with three readers we did not write, and replay offline."""

from __future__ import annotations

from pathlib import Path

import pytest
from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory
from rerun.chunk import McapReader
from rosbags.highlevel import AnyReader
from rosbags.typesys import Stores, get_typestore

from linkage_monitor.offline.replay import mechanism_in_bag, replay

BAGS = sorted(p for p in (Path(__file__).resolve().parent.parent / "bags").iterdir() if (p / "metadata.yaml").is_file())


def test_there_are_sample_bags_for_four_presets():
    assert {mechanism_in_bag(b).name for b in BAGS} >= {"belarus_1221", "damping_hitch", "ttz1080_base_change"}
    assert sum(f.stat().st_size for b in BAGS for f in b.iterdir()) < 10e6  # a few MB in all


@pytest.mark.slow
@pytest.mark.parametrize("bag", BAGS, ids=[b.name for b in BAGS])
def test_sample_bag_decodes_with_three_readers_and_replays(bag):
    with AnyReader([bag], default_typestore=get_typestore(Stores.EMPTY)) as reader:
        topics = [c.topic for c, _, raw in reader.messages() if reader.deserialize(raw, c.msgtype) is not None]
    assert {"/joint_states", "/hinge_reactions", "/hitch_state", "/steerability", "/diagnostics"} <= set(topics)
    with open(next(bag.glob("*.mcap")), "rb") as f:
        decoded = [ch.topic for _, ch, _, _ in make_reader(f, decoder_factories=[DecoderFactory()]).iter_decoded_messages()]
    assert decoded == topics
    rows = sum(chunk.num_rows for chunk in McapReader(next(bag.glob("*.mcap"))).stream())
    assert rows >= len(topics)
    replayed = replay(bag, progress=None)
    summary, steps = replayed.summary, replayed.steps
    assert summary.solved > 0.9 * sum(1 for s in steps if s.level != 2)
