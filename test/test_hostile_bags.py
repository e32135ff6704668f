"""Bags as the field delivers them: cut mid-record (an interrupted copy, a dying SD card), split bags
whose metadata.yaml is missing or does not list every file, chunks that fail their CRC. Every
complete record is read, what could not be is named (file, byte, messages), nothing is skipped
without a word. Oracles: mcap's StreamReader (the records of a file in order, as far as they read)
and rosbags' AnyReader (a split bag with its metadata, as rosbag2 reads it)."""

from __future__ import annotations

import shutil
import struct
from pathlib import Path

import pytest
from mcap.reader import make_reader
from mcap.records import Message
from mcap.stream_reader import StreamReader
from rosbags.highlevel import AnyReader
from rosbags.typesys import Stores, get_typestore

from linkage_monitor.bag.faults import read_faults
from linkage_monitor.bag.reader import read_bag_raw
from linkage_monitor.bag.storage import storage_files
from linkage_monitor.bag.writer import BagWriter
from linkage_monitor.offline.fleet import analyse_bag, find_bags

BAGS = Path(__file__).resolve().parents[1] / "bags"
DAMPING = BAGS / "damping_hitch_lift" / "damping_hitch_lift_0.mcap"
INPUTS = ("/linkage_monitor/mechanism", "/linkage_monitor/config", "/joint_states", "/pressure/lift_cap_pressure")


def _stream_reader_messages(file: Path) -> list[tuple[int, bytes]]:
    """(log time, data) of every message mcap's StreamReader reads (CRCs checked) before the file stops reading."""
    read = []
    with open(file, "rb") as stream:
        try:
            for record in StreamReader(stream, validate_crcs=True).records:
                if isinstance(record, Message):
                    read.append((record.log_time, record.data))
        except Exception:  # noqa: BLE001 - the oracle stops where the file does not read on
            pass
    return read


def _cut(source: Path, target: Path, fraction: float) -> Path:
    data = source.read_bytes()
    target.write_bytes(data[:int(len(data) * fraction)])
    return target


@pytest.mark.parametrize("fraction", [0.999, 0.6])
def test_a_cut_mcap_file_keeps_every_complete_record_and_names_the_cut(tmp_path, fraction):
    """`head -c 99.9 %` (only the summary lost) and `head -c 60 %` (a chunk cut in two) of a bundled bag:
    every message mcap's StreamReader reads before the cut is read (0 before), and one ReadFault names
    the byte where the incomplete record starts (its head says it runs past the end) and the count."""
    cut = _cut(DAMPING, tmp_path / "cut.mcap", fraction)
    expected = _stream_reader_messages(cut)
    assert len(expected) > 1000   # the bundled bag holds 5036 messages; a cut at 60 % keeps about 3000
    with read_faults() as faults:
        read = [(m.log_time_ns, m.data) for m in read_bag_raw(cut)]
    assert sorted(read) == sorted(expected)
    assert [f.kind for f in faults] == ["cut_off"]
    fault, data = faults[0], cut.read_bytes()
    _, length = struct.unpack_from("<BQ", data, fault.offset)
    assert fault.offset + 9 + length > len(data) and fault.messages == len(expected)
    assert str(cut) in fault.text and f"byte {fault.offset}" in fault.text and f"{len(expected)} messages" in fault.text
    assert ("none lost" in fault.text) == (fraction > 0.99)


def test_a_cut_file_is_named_once_however_often_the_bag_is_read(tmp_path):
    cut = _cut(DAMPING, tmp_path / "cut.mcap", 0.6)
    with read_faults() as faults:
        for _ in range(3):
            sum(1 for _ in read_bag_raw(cut))
    assert len(faults) == 1


def test_replay_names_a_cut_on_a_line_of_its_own_beside_its_progress_bar(tmp_path, capsys):
    """`linkage-monitor replay t.mcap` of a cut file with its progress bar: the cut is written on a line of
    its own (the bar cleared and drawn again after it), not glued to the bar's "replay: 0msg [...]"."""
    import re

    from linkage_monitor.cli.main import main

    cut = _cut(DAMPING, tmp_path / "t.mcap", 0.999)
    assert main(["replay", str(cut), "--out", str(tmp_path / "out")]) == 0
    err = capsys.readouterr().err
    pieces = re.split(r"[\r\n]", err)
    assert any(p.startswith(f"{cut} is cut off at byte ") for p in pieces), err
    assert any(p.startswith("replay: ") for p in pieces), err   # the bar is there


def _source_messages() -> list[tuple[str, str, int, bytes]]:
    """(topic, type, log time ns, CDR) of a bundled bag's inputs, read by rosbags."""
    with AnyReader([BAGS / "belarus_1221_lift_transport"], default_typestore=get_typestore(Stores.EMPTY)) as reader:
        wanted = [c for c in reader.connections if c.topic in INPUTS]
        return [(c.topic, c.msgtype, t, bytes(raw)) for c, t, raw in reader.messages(connections=wanted)]


@pytest.fixture(scope="module")
def split_bag(tmp_path_factory) -> Path:
    """The bundled lift's inputs in a bag split by duration into 11 or more files (`_0` .. `_10` and on:
    how many depends on the gaps in the recording's stamps)."""
    messages = _source_messages()
    span_s = (messages[-1][2] - messages[0][2]) / 1e9
    bag = tmp_path_factory.mktemp("split") / "lift"
    with BagWriter(bag, chunk_size=16 * 1024, max_bag_duration_s=span_s / 13.5) as writer:
        for topic, type_name, stamp, data in messages:
            writer.write(topic, data, stamp, type_name=type_name, log_time_ns=stamp)
    assert len(list(bag.glob("*.mcap"))) >= 11
    return bag


def _rosbags_order(bag: Path) -> list[tuple[str, int]]:
    with AnyReader([bag], default_typestore=get_typestore(Stores.EMPTY)) as reader:
        return [(c.topic, t) for c, t, _ in reader.messages()]


def _copy(bag: Path, target: Path) -> Path:
    shutil.copytree(bag, target)
    return target


def test_a_split_bag_without_metadata_reads_in_the_order_of_its_files_stamps(split_bag, tmp_path):
    """metadata.yaml removed: `_10` and `_11` are read after `_9` (by their first log times), not after `_1`:
    the same messages in the same order as rosbags reads the bag with its metadata."""
    bag = _copy(split_bag, tmp_path / "lift")
    (bag / "metadata.yaml").unlink()
    files = len(list(bag.glob("*.mcap")))
    assert [f.name for f in storage_files(bag)] == [f"lift_{i}.mcap" for i in range(files)]
    assert [(m.topic, m.log_time_ns) for m in read_bag_raw(bag)] == _rosbags_order(split_bag)


def test_a_file_metadata_does_not_list_is_read_in_stamp_order_and_named(split_bag, tmp_path):
    """lift_5.mcap left out of metadata.yaml (a recorder killed before it rewrote it): read where its
    log times put it, and named once as not listed."""
    bag = _copy(split_bag, tmp_path / "lift")
    metadata = bag / "metadata.yaml"
    metadata.write_text("\n".join(line for line in metadata.read_text().splitlines() if "- lift_5.mcap" not in line))
    with read_faults() as faults:
        read = [(m.topic, m.log_time_ns) for m in read_bag_raw(bag)]
    assert read == _rosbags_order(split_bag)
    assert [(f.kind, Path(f.file).name) for f in faults] == [("unlisted_file", "lift_5.mcap")]
    assert "not listed in its metadata.yaml" in faults[0].text


def test_a_split_bag_whose_last_file_is_cut_reads_every_complete_record(split_bag, tmp_path):
    bag = _copy(split_bag, tmp_path / "lift")
    last = f"lift_{len(list(bag.glob('*.mcap'))) - 1}.mcap"
    _cut(split_bag / last, bag / last, 0.5)
    expected = sum(1 for _ in read_bag_raw(split_bag)) - sum(1 for _ in read_bag_raw(split_bag / last)) \
        + len(_stream_reader_messages(bag / last))
    with read_faults() as faults:
        assert sum(1 for _ in read_bag_raw(bag)) == expected
    assert [(f.kind, Path(f.file).name) for f in faults] == [("cut_off", last)]


def test_fleet_takes_a_split_bag_without_metadata_for_one_bag(split_bag, tmp_path):
    root = tmp_path / "fleet"
    bag = _copy(split_bag, root / "lift")
    (bag / "metadata.yaml").unlink()
    _cut(DAMPING, root / "loose_0.mcap", 1.0)
    assert find_bags([root]) == [bag, root / "loose_0.mcap"]   # a directory beside it: root is not a bag
    _cut(DAMPING, root / "other_0.mcap", 1.0)
    assert find_bags([root]) == [bag, root / "loose_0.mcap", root / "other_0.mcap"]


def _crc_damaged(tmp_path: Path) -> tuple[Path, int]:
    """The bundled damping bag with a byte of its middle chunk flipped; the chunk's byte offset."""
    bag = tmp_path / "damaged.mcap"
    data = bytearray(DAMPING.read_bytes())
    with open(DAMPING, "rb") as stream:
        chunks = sorted(make_reader(stream).get_summary().chunk_indexes, key=lambda c: c.chunk_start_offset)
    victim = chunks[len(chunks) // 2]
    data[victim.chunk_start_offset + victim.chunk_length // 2] ^= 0xFF
    bag.write_bytes(bytes(data))
    return bag, victim.chunk_start_offset


@pytest.mark.slow
def test_a_fleet_row_names_a_skipped_chunk_and_a_cut(tmp_path):
    """A bag with a chunk that fails its CRC, and one cut at 99.9 %: replayed (error null), and the row's
    warning names the chunk (its byte and lost messages) or the cut (its byte and messages read)."""
    damaged, offset = _crc_damaged(tmp_path)
    row = analyse_bag(damaged).row
    assert row["error"] is None and row["inputs"] > 0
    assert f"the chunk at byte {offset}" in row["warning"] and "skipped" in row["warning"], row["warning"]
    cut = analyse_bag(_cut(DAMPING, tmp_path / "cut.mcap", 0.999)).row
    assert cut["error"] is None and cut["inputs"] > 0 and "is cut off at byte" in cut["warning"], cut
    whole = analyse_bag(DAMPING).row
    assert whole["warning"] is None and whole["inputs"] == cut["inputs"]


def _db3(path: Path, declared: dict[str, str]) -> Path:
    """The damping bag's inputs in a rosbag2 sqlite3 bag written by rosbags, a topic's type column set to
    ``declared[topic]`` where given (the bytes stay what they are)."""
    from rosbags.rosbag2 import StoragePlugin, Writer

    with AnyReader([DAMPING.parent], default_typestore=get_typestore(Stores.EMPTY)) as reader:
        store = reader.typestore
        wanted = [c for c in reader.connections if c.topic in INPUTS]
        messages = [(c.topic, c.msgtype, t, bytes(raw)) for c, t, raw in reader.messages(connections=wanted)]
    with Writer(path, version=9, storage_plugin=StoragePlugin.SQLITE3) as writer:
        connections = {}
        for topic, msgtype, stamp, data in messages:
            if topic not in connections:
                connections[topic] = writer.add_connection(topic, declared.get(topic, msgtype), typestore=store)
            writer.write(connections[topic], stamp, data)
    return path


def test_a_db3_whose_topics_table_lies_about_a_type_names_the_topic_once(tmp_path):
    """/joint_states declared sensor_msgs/msg/FluidPressure in the topics table: its messages read as
    pressures of 3e-313 Pa before (1,629 no_value_yet findings in a replay, no cause). rosbags refuses to
    decode them as that type (the oracle); the reader leaves the topic out with one ReadFault naming the
    topic, the declared type and why, and reads the other topics as before."""
    from rosbags.serde import SerdeError

    lying = _db3(tmp_path / "lying", {"/joint_states": "sensor_msgs/msg/FluidPressure"})
    honest = _db3(tmp_path / "honest", {})
    joint_states = [m for m in read_bag_raw(honest) if m.topic == "/joint_states"]
    store = get_typestore(Stores.LATEST)
    with pytest.raises(SerdeError):
        store.deserialize_cdr(joint_states[0].data, "sensor_msgs/msg/FluidPressure")
    with read_faults() as faults:
        read = list(read_bag_raw(lying))
        read_again = list(read_bag_raw(lying))
    assert [(f.kind, f.messages) for f in faults] == [("type_mismatch", len(joint_states))]
    assert "/joint_states" in faults[0].text and "sensor_msgs/msg/FluidPressure" in faults[0].text \
        and "left over" in faults[0].text, faults[0].text
    assert [(m.topic, m.data) for m in read] == [(m.topic, m.data) for m in read_bag_raw(honest)
                                                 if m.topic != "/joint_states"] == [(m.topic, m.data) for m in read_again]
    with read_faults() as faults:
        assert len(list(read_bag_raw(honest))) > len(read)
    assert faults == []


CAN_LOG = BAGS / "can" / "belarus_1221_lift.log"
CAN_MAP = Path(__file__).resolve().parents[1] / "config" / "can" / "belarus_1221.yaml"


@pytest.mark.parametrize("seconds", ["2767225600", "17672256000"], ids=["after 2038", "11 digits"])
def test_can_log_stamps_no_header_stamp_holds_are_refused_by_name(tmp_path, capsys, seconds):
    """candump lines stamped after 19 January 2038 or with 11 digits of seconds: a 27-line traceback before
    (struct.error packing the int32 sec, OverflowError filling int64 ns). rosbags' serializer cannot write
    such a builtin_interfaces/Time (the oracle); each line is refused naming its stamp and the reason, the
    other lines are converted; a log of such lines only is one error line, exit 2, and no bag."""
    from linkage_monitor.cli.main import main

    store = get_typestore(Stores.LATEST)
    with pytest.raises(struct.error):
        store.serialize_cdr(store.types["builtin_interfaces/msg/Time"](sec=int(seconds), nanosec=0),
                            "builtin_interfaces/msg/Time")
    lines = CAN_LOG.read_text().splitlines()[:40]
    bad = [f"({seconds}.{line.split(')')[0].split('.')[1]}){line.split(')', 1)[1]}" for line in lines[:10]]
    mixed = tmp_path / "mixed.log"
    mixed.write_text("\n".join(bad + lines[10:]) + "\n")
    assert main(["can-to-bag", str(mixed), "--map", str(CAN_MAP), "--out", str(tmp_path / "mixed")]) == 0
    err = capsys.readouterr().err
    assert "Traceback" not in err and "10 line(s) refused" in err and f"a stamp of {seconds} s since the epoch" in err
    assert "int32 seconds" in err
    only_bad = tmp_path / "bad.log"
    only_bad.write_text("\n".join(bad) + "\n")
    assert main(["can-to-bag", str(only_bad), "--map", str(CAN_MAP), "--out", str(tmp_path / "bad")]) == 2
    err_lines = capsys.readouterr().err.strip().splitlines()
    assert len(err_lines) == 1 and f"{seconds} s since the epoch" in err_lines[0], err_lines
    assert not (tmp_path / "bad").exists()   # a log that gives no bag leaves none behind (a partial one before)


def test_a_header_stamp_beyond_int32_seconds_is_a_named_input_error():
    """Wherever a header stamp is packed (wire.cdr.time_bytes, the output templates): a named InputError
    (the stamp, the reason), still the struct.error struct.pack gives."""
    import struct as struct_module

    from linkage_monitor.mechanics import InputError
    from linkage_monitor.wire.cdr import StampRangeError, time_bytes

    assert time_bytes((2**31 - 1) * 10**9) == struct_module.pack("<iI", 2**31 - 1, 0)
    for beyond in (2**31 * 10**9, -2**31 * 10**9 - 1):
        with pytest.raises(StampRangeError, match=f"{beyond // 10**9} s since the epoch") as err:
            time_bytes(beyond)
        assert isinstance(err.value, InputError) and isinstance(err.value, struct_module.error)


def test_an_unlisted_file_that_is_no_storage_file_is_named_not_fatal(split_bag, tmp_path):
    """A stray `.mcap` of garbage beside the listed files: named and left out; the bag reads as listed."""
    bag = _copy(split_bag, tmp_path / "lift")
    (bag / "stray.mcap").write_bytes(b"not an mcap file")
    with read_faults() as faults:
        read = [(m.topic, m.log_time_ns) for m in read_bag_raw(bag)]
    assert read == _rosbags_order(split_bag)
    assert [(f.kind, Path(f.file).name) for f in faults] == [("unlisted_file", "stray.mcap")]
    assert "not read" in faults[0].text and "neither an MCAP nor a sqlite3" in faults[0].text
