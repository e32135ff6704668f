"""Day-long recordings: the bag writer splits by size and by duration as `ros2 bag record
--max-bag-size --max-bag-duration` does. Each file is a complete MCAP file that mcap's own reader
opens alone (summary and all); metadata.yaml lists the files as rosbag2 does, checked by rosbags'
reader taking the split bag as one; the replay of a split bag equals the replay of the same
messages in one file, byte for byte. The messages: the bundled bag's inputs, read by rosbags.
"""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml
from mcap.reader import make_reader
from rosbags.highlevel import AnyReader
from rosbags.typesys import Stores, get_typestore

from linkage_monitor.bag.errors import BagError
from linkage_monitor.bag.split_files import MIN_SPLIT_SIZE
from linkage_monitor.bag.writer import BagWriter
from linkage_monitor.cli.main import main as cli_main
from support.bag_outputs import output_bytes

SOURCE = Path(__file__).resolve().parents[1] / "bags" / "belarus_1221_lift_transport"
INPUTS = ("/linkage_monitor/mechanism", "/linkage_monitor/config", "/joint_states", "/pressure/lift_cap_pressure")
MECHANISM_YAML = "name: any\n"   # an attachment each file must carry


def _source_messages() -> list[tuple[str, str, int, bytes]]:
    """(topic, type, log time ns, CDR) of the bundled bag's inputs, in log-time order."""
    with AnyReader([SOURCE], default_typestore=get_typestore(Stores.EMPTY)) as reader:
        wanted = [c for c in reader.connections if c.topic in INPUTS]
        return [(c.topic, c.msgtype, t, bytes(raw)) for c, t, raw in reader.messages(connections=wanted)]


def _record(path: Path, messages: list[tuple[str, str, int, bytes]], **split: float) -> Path:
    with BagWriter(path, chunk_size=16 * 1024, **split) as writer:   # type: ignore[arg-type]
        writer.attach("mechanism.yaml", MECHANISM_YAML.encode(), "application/yaml", messages[0][2])
        for topic, type_name, stamp, data in messages:
            writer.write(topic, data, stamp, type_name=type_name, log_time_ns=stamp)
    return path


@pytest.fixture(scope="module")
def recorded(tmp_path_factory):
    root = tmp_path_factory.mktemp("split")
    messages = _source_messages()
    span_s = (messages[-1][2] - messages[0][2]) / 1e9
    return messages, span_s, {
        "one": _record(root / "one", messages),
        "size": _record(root / "size", messages, max_bag_size=MIN_SPLIT_SIZE),
        "duration": _record(root / "duration", messages, max_bag_duration_s=span_s / 3.5),
    }


def _info(bag: Path) -> dict:
    return yaml.safe_load((bag / "metadata.yaml").read_text())["rosbag2_bagfile_information"]


@pytest.mark.parametrize("kind", ["size", "duration"])
def test_each_file_of_a_split_bag_stands_alone_and_metadata_lists_them(recorded, kind):
    messages, span_s, bags = recorded
    bag = bags[kind]
    info = _info(bag)
    names = info["relative_file_paths"]
    assert len(names) >= (2 if kind == "size" else 3) and sorted(p.name for p in bag.glob("*.mcap")) == sorted(names)
    assert [f["path"] for f in info["files"]] == names
    total = 0
    for entry in info["files"]:
        with open(bag / entry["path"], "rb") as stream:
            reader = make_reader(stream)
            summary = reader.get_summary()   # a finished file: summary and statistics
            assert summary is not None and summary.statistics is not None
            count = sum(1 for _ in reader.iter_messages())
            assert count == entry["message_count"] == summary.statistics.message_count
            assert [a.name for a in reader.iter_attachments()] == ["mechanism.yaml"]
        total += count
        if kind == "duration":   # each file's messages span less than the duration
            assert entry["duration"]["nanoseconds"] < span_s / 3.5 * 1e9
    assert total == info["message_count"] == len(messages)
    if kind == "size":   # every file but the last reached the size within one chunk (16 KiB)
        assert all((bag / n).stat().st_size < MIN_SPLIT_SIZE + 2 * 16 * 1024 for n in names[:-1])


@pytest.mark.parametrize("kind", ["size", "duration"])
def test_rosbags_reads_a_split_bag_as_the_messages_written(recorded, kind):
    messages, _, bags = recorded
    with AnyReader([bags[kind]], default_typestore=get_typestore(Stores.EMPTY)) as reader:
        read = [(c.topic, c.msgtype, t, bytes(raw)) for c, t, raw in reader.messages()]
    assert read == messages



@pytest.mark.slow
def test_a_split_bag_replays_as_the_unsplit_one(recorded, tmp_path):
    _, _, bags = recorded
    replayed = {}
    for kind in ("one", "duration"):
        assert cli_main(["replay", str(bags[kind]), "--out", str(tmp_path / kind), "--quiet"]) == 0
        replayed[kind] = output_bytes(tmp_path / kind)
    assert sum(len(v) for v in replayed["one"].values()) > 3000   # the bundled lift: 3257 of each output
    assert replayed["duration"] == replayed["one"]


def test_negative_split_limits_are_refused(tmp_path):
    with pytest.raises(ValueError, match="max_bag_size"):
        BagWriter(tmp_path / "bag", max_bag_size=-1)


@pytest.mark.parametrize("size", [1, 1024, MIN_SPLIT_SIZE - 1])
def test_split_sizes_below_the_minimum_are_refused_by_name(tmp_path, size):
    """max_bag_size 1 (the node's parameter given in MB or GB by mistake) made a file per write: refused, as
    `ros2 bag record` refuses a size below its storage's minimum (rosbag2's sqlite3 storage: 86016 B),
    naming the parameter and the smallest size; nothing is created."""
    with pytest.raises(BagError, match=f"max_bag_size {size} B is below the smallest split size, {MIN_SPLIT_SIZE} B"):
        BagWriter(tmp_path / "bag", max_bag_size=size)
    assert not (tmp_path / "bag").exists()
    with BagWriter(tmp_path / "ok", max_bag_size=MIN_SPLIT_SIZE):
        pass
