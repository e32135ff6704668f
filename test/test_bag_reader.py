"""read_bag / read_inputs on bags written by rosbags (the `ros2 bag record` layout) and by
BagWriter, and their errors."""

from __future__ import annotations

import zlib
from pathlib import Path

import numpy as np
import pytest
from mcap.data_stream import ReadDataStream
from mcap.reader import SeekingReader
from mcap.records import Chunk, Message
from mcap.stream_reader import breakup_chunk
from rosbags.rosbag2 import StoragePlugin, Writer
from rosbags.typesys import Stores, get_typestore
from sensor_msgs.msg import FluidPressure, JointState
from std_msgs.msg import String

from linkage_monitor.bag.columns import JointStateColumns, PressureColumns
from linkage_monitor.bag.errors import BagError
from linkage_monitor.bag.mcap_records import chunk_messages, indexed_offsets
from linkage_monitor.bag.reader import read_bag, read_bag_raw, read_bag_raw_blocks, read_inputs
from linkage_monitor.bag.writer import BagWriter

T0 = 1_700_000_000_000_000_000  # ns since the epoch
N = 25


def _rosbags_bag(directory: Path) -> Path:
    """A bag written by rosbags.rosbag2.Writer (version 9, MCAP) with Kilted type definitions:
    joint i at position 0.01*i rad, pressure 1e5 + 1e4*i Pa, stamps 20 ms apart."""
    store = get_typestore(Stores.ROS2_KILTED)
    JointStateT = store.types["sensor_msgs/msg/JointState"]
    FluidPressureT = store.types["sensor_msgs/msg/FluidPressure"]
    HeaderT = store.types["std_msgs/msg/Header"]
    TimeT = store.types["builtin_interfaces/msg/Time"]
    with Writer(directory, version=9, storage_plugin=StoragePlugin.MCAP) as writer:
        joints = writer.add_connection("/joint_states", JointStateT.__msgtype__, typestore=store)
        pressure = writer.add_connection("/lift_cylinder/pressure", FluidPressureT.__msgtype__,
                                         typestore=store)
        for i in range(N):
            stamp = T0 + i * 20_000_000
            header = HeaderT(stamp=TimeT(sec=stamp // 10**9, nanosec=stamp % 10**9), frame_id="")
            js = JointStateT(header=header, name=["lift_arm", "top_link"],
                             position=np.array([0.01 * i, 0.5]), velocity=np.array([0.2, 0.0]),
                             effort=np.array([], dtype=float))
            writer.write(joints, stamp + 7, store.serialize_cdr(js, JointStateT.__msgtype__))
            fp = FluidPressureT(header=header, fluid_pressure=1e5 + 1e4 * i, variance=0.0)
            writer.write(pressure, stamp + 9, store.serialize_cdr(fp, FluidPressureT.__msgtype__))
    return directory


def test_reads_rosbags_bag_message_for_message(tmp_path: Path) -> None:
    bag = _rosbags_bag(tmp_path / "rosbags_bag")
    rows = list(read_bag(bag))
    joints = [r for r in rows if r[0] == "/joint_states"]
    pressures = [r for r in rows if r[0] == "/lift_cylinder/pressure"]
    assert len(joints) == len(pressures) == N
    for i, (_, type_name, stamp, log_time, msg) in enumerate(joints):
        assert type_name == "sensor_msgs/msg/JointState" and isinstance(msg, JointState)
        assert (stamp, log_time) == (T0 + i * 20_000_000, T0 + i * 20_000_000 + 7)
        assert list(msg.name) == ["lift_arm", "top_link"]
        assert list(msg.position) == [0.01 * i, 0.5]
    for i, (_, _, _, log_time, msg) in enumerate(pressures):
        assert isinstance(msg, FluidPressure) and msg.fluid_pressure == 1e5 + 1e4 * i
        assert log_time == T0 + i * 20_000_000 + 9
    only = list(read_bag(bag, topics=["/lift_cylinder/pressure"]))
    assert [r[4].fluid_pressure for r in only] == [r[4].fluid_pressure for r in pressures]
    # a single .mcap file reads the same
    assert len(list(read_bag(next(bag.glob("*.mcap"))))) == 2 * N


def test_read_inputs_columns_equal_written_values(tmp_path: Path) -> None:
    inputs = read_inputs(_rosbags_bag(tmp_path / "rosbags_bag"))
    joints = inputs["/joint_states"]
    assert isinstance(joints, JointStateColumns)
    assert joints.names == ("lift_arm", "top_link")
    assert np.array_equal(joints.stamp_ns, T0 + np.arange(N, dtype=np.int64) * 20_000_000)
    assert np.array_equal(joints.position[:, 0], 0.01 * np.arange(N))
    assert np.array_equal(joints.velocity, np.tile([0.2, 0.0], (N, 1)))
    pressure = inputs["/lift_cylinder/pressure"]
    assert isinstance(pressure, PressureColumns)
    assert np.array_equal(pressure.fluid_pressure, 1e5 + 1e4 * np.arange(N))
    assert np.array_equal(pressure.log_time_ns, pressure.stamp_ns + 9)


def test_read_inputs_aligns_joint_names_across_messages(tmp_path: Path) -> None:
    with BagWriter(tmp_path / "ours") as writer:
        writer.write("/joint_states", JointState(name=["lift_arm"], position=[0.3]), 1,
                     log_time_ns=1)
        writer.write("/joint_states", JointState(name=["top_link", "lift_arm"],
                                                 position=[0.7, 0.4], velocity=[1.0, 2.0]), 2,
                     log_time_ns=2)
    joints = read_inputs(tmp_path / "ours")["/joint_states"]
    assert joints.names == ("lift_arm", "top_link")
    # row 0 has no top_link and no velocities; row 1 is reordered by name
    assert np.array_equal(joints.position, [[0.3, np.nan], [0.4, 0.7]], equal_nan=True)
    assert np.array_equal(joints.velocity, [[np.nan, np.nan], [2.0, 1.0]], equal_nan=True)


def test_errors_name_the_path_and_the_problem(tmp_path: Path) -> None:
    missing = tmp_path / "nowhere"
    with pytest.raises(BagError, match=f"{missing}.*does not exist"):
        list(read_bag(missing))
    not_a_bag = tmp_path / "notes.mcap"
    not_a_bag.write_text("SQLite form")   # neither magic in full
    with pytest.raises(BagError, match=f"{not_a_bag} is neither an MCAP nor a sqlite3 rosbag2 file"):
        list(read_bag(not_a_bag))
    empty_dir = tmp_path / "empty"
    empty_dir.mkdir()
    with pytest.raises(BagError, match="holds no .mcap or .db3 file"):
        list(read_bag(empty_dir))
    with BagWriter(tmp_path / "strings") as writer:
        writer.write("/chatter", String(data="hello"), 1)
    with pytest.raises(BagError, match="strings.*no sensor_msgs/msg/JointState"):
        read_inputs(tmp_path / "strings")


def test_a_message_that_does_not_decode_is_left_out_with_a_warning(tmp_path: Path, caplog) -> None:
    """The node records an input's bytes as they came, a cut JointState too: the readers of decoded
    messages leave it out and say so (file, size, topic, type); the raw reader yields it."""
    from rclpy.serialization import serialize_message

    from linkage_monitor.ros.messages import header

    good = [JointState(header=header(T0 + k), name=["lift_arm"], position=[0.1 * k]) for k in range(3)]
    cut = serialize_message(good[1])[:30]
    with BagWriter(tmp_path / "bag") as writer:
        writer.write("/joint_states", good[0], T0, log_time_ns=T0)
        writer.write("/joint_states", cut, T0 + 1, type_name="sensor_msgs/msg/JointState", log_time_ns=T0 + 1)
        writer.write("/joint_states", good[2], T0 + 2, log_time_ns=T0 + 2)
    with caplog.at_level("WARNING"):
        columns = read_inputs(tmp_path / "bag")["/joint_states"]
    assert isinstance(columns, JointStateColumns)
    assert columns.position[:, 0].tolist() == [0.0, 0.2]
    assert "1 message(s) on /joint_states do not decode as sensor_msgs/msg/JointState (the first: 30 bytes at " \
           "log time 1700000000000000001 ns" in caplog.text and "left out" in caplog.text
    assert [raw.data for raw in read_bag_raw(tmp_path / "bag")][1] == cut


@pytest.mark.parametrize("where", [0.5, 0.9])
def test_a_corrupt_chunk_is_named_skipped_and_counted(tmp_path, caplog, where):
    """A byte of a bundled bag's chunk overwritten (the bag as a damaged disk returns it): the chunk fails
    its CRC (or no longer decompresses) and is skipped with one warning naming the file, its byte
    offset and its message count; every other chunk reads as before; nothing of it is decoded."""
    import shutil

    from mcap.reader import make_reader

    source = Path(__file__).resolve().parents[1] / "bags" / "belarus_1221_lift_transport"
    bag = tmp_path / "damaged"
    shutil.copytree(source, bag)
    file = next(bag.glob("*.mcap"))
    with open(file, "rb") as stream:
        chunks = sorted(make_reader(stream).get_summary().chunk_indexes, key=lambda c: c.chunk_start_offset)
    victim = chunks[len(chunks) // 2]
    at = victim.chunk_start_offset + int(victim.chunk_length * where)
    data = bytearray(file.read_bytes())
    data[at] ^= 0xFF
    file.write_bytes(bytes(data))
    before = list(read_bag_raw(source))
    with caplog.at_level("WARNING"):
        after = list(read_bag_raw(bag))
    named = [r.getMessage() for r in caplog.records if f"the chunk at byte {victim.chunk_start_offset}" in r.getMessage()]
    assert len(named) == 1 and str(file) in named[0] and "skipped" in named[0], caplog.text
    lost = len(before) - len(after)
    assert lost > 0 and f"({lost} messages" in named[0] or "unknown number" in named[0], (lost, named[0])
    kept = {(r[0], r[3]) for r in after}
    assert kept <= {(r[0], r[3]) for r in before}   # nothing made up, the rest read as before


HITCH_STATE = "linkage_monitor/msg/HitchState"


def test_a_message_recorded_with_another_definition_reads_by_it(tmp_path: Path, caplog) -> None:
    """A HitchState recorded with a definition that lacks `min_transmission_angle`, the standard
    uncertainties and the weighing (the installed definition with those lines taken out: as a bag
    recorded before they were added), written by rosbags' writer, whose schema record carries
    that definition: read_bag decodes it by the recorded definition into the installed class —
    every field the recording has equal to what was written, the float fields it lacks NaN (not
    known: the nested CylinderState's `force_u` too), the others their defaults (weighing_phase
    WEIGHING_OFF) — and says once in the log which fields the recording lacks."""
    import math
    import re

    from rosbags.typesys import get_types_from_msg

    from linkage_monitor.msg import HitchState
    from linkage_monitor.wire.definitions import message_definition

    installed = message_definition(HITCH_STATE)
    later = (r"float64 min_transmission_angle|float64 \w+_u|float64 implement_\w+_estimate\w*|"
             r"uint8 weighing_phase|bool weighing_confident|uint8 implement_mass_in_use|uint8 (?:WEIGHING|MASS_FROM)_\w+=")
    older = re.sub(rf"^(?:{later})\b.*\n", "", installed, flags=re.M)
    assert older != installed
    store = get_typestore(Stores.EMPTY)
    store.register(get_types_from_msg(older, HITCH_STATE))
    T = store.types
    cylinder = T["linkage_monitor/msg/CylinderState"](name="lift_cylinder", length=0.6, force=1.2e5,
                                                       cap_pressure_measured=1.0e7, rod_pressure_measured=math.nan,
                                                       cap_pressure_predicted=1.01e7)
    header = T["std_msgs/msg/Header"](stamp=T["builtin_interfaces/msg/Time"](sec=T0 // 10**9, nanosec=5),
                                      frame_id="base_footprint")
    written = T[HITCH_STATE](header=header, cylinders=[cylinder], implement_load=15000.0,
                             implement_load_estimated=True, implement_cg_x=-1.8, implement_cg_z=0.34,
                             hitch_axis_height=0.30, lift_capacity_hitch_axis=31800.0, lift_capacity_610mm=24200.0,
                             lift_capacity_implement_cg=23000.0, lift_reserve=1.53, status=1,
                             status_text="lift reserve 0.98 < 1")
    with Writer(tmp_path / "older", version=9, storage_plugin=StoragePlugin.MCAP) as writer:
        connection = writer.add_connection("/hitch_state", HITCH_STATE, typestore=store)
        writer.write(connection, T0 + 5, store.serialize_cdr(written, HITCH_STATE))
    with caplog.at_level("INFO", logger="linkage_monitor.bag.reader"):
        rows = list(read_bag(tmp_path / "older"))
    assert len(rows) == 1
    topic, type_name, stamp, _, msg = rows[0]
    assert (topic, type_name, stamp) == ("/hitch_state", HITCH_STATE, T0 + 5) and isinstance(msg, HitchState)
    lacking = [name for name in HitchState.get_fields_and_field_types() if not hasattr(written, name)]
    assert "min_transmission_angle" in lacking and "implement_load_u" in lacking and "weighing_phase" in lacking
    for name, kind in HitchState.get_fields_and_field_types().items():
        if name in ("header", "cylinders"):
            continue
        if name not in lacking:
            assert getattr(msg, name) == getattr(written, name), name
        elif kind == "double":
            assert math.isnan(getattr(msg, name)), name
        else:
            assert getattr(msg, name) in (0, False), name
    assert msg.weighing_phase == HitchState.WEIGHING_OFF
    assert (msg.header.stamp.sec, msg.header.stamp.nanosec, msg.header.frame_id) == (T0 // 10**9, 5, "base_footprint")
    [c] = msg.cylinders
    assert (c.name, c.length, c.force, c.cap_pressure_measured, c.cap_pressure_predicted) == (
        "lift_cylinder", 0.6, 1.2e5, 1.0e7, 1.01e7) and math.isnan(c.rod_pressure_measured)
    assert math.isnan(c.force_u)
    said = [r.getMessage() for r in caplog.records if "another definition" in r.getMessage()]
    assert len(said) == 1 and all(name in said[0].partition("lacks ")[2] for name in lacking), caplog.text


def test_every_recorded_output_of_the_bundled_bag_reads() -> None:
    """The bundled bag's HitchState, HingeReactions and Steerability messages all decode (whichever
    definition of them the bag recorded)."""
    bag = Path(__file__).resolve().parents[1] / "bags" / "belarus_1221_lift_transport"
    topics = ["/hitch_state", "/hinge_reactions", "/steerability"]
    recorded = sum(1 for _ in read_bag_raw(bag, topics=topics))
    assert recorded > 0 and sum(1 for _ in read_bag(bag, topics=topics)) == recorded


# log times (ns) of the messages of each chunk, chunks in file order; topic "/a" or "/b" by position.
# Chunks apart in log time: messages out of order inside a chunk, chunks not in file order, equal log
# times where one chunk ends and the next begins.
IN_SEQUENCE = [[400, 410], [100, 130, 120, 130], [130, 200, 150], [200, 200, 250], [300], [300, 390]]
# Chunks whose log times overlap, with equal log times in two chunks.
OVERLAPPING = [[100, 300, 200], [150, 300, 300, 250], [300, 310], [50, 400, 120], [310, 305]]
# Chunks apart but for one log time where the later one in time ends: its messages at that time come first.
TOUCHING_BACKWARDS = [[500, 600, 500], [100, 400], [450, 500, 480]]


def _chunked_mcap(file: Path, chunks: list[list[int]]) -> Path:
    """An MCAP file of one chunk per entry of ``chunks`` (mcap's Writer, flushed after each), message k of a
    chunk on "/a" when k is even, else "/b", its bytes naming its chunk and position."""
    from mcap.writer import Writer as McapWriter

    with open(file, "wb") as stream:
        writer = McapWriter(stream)
        writer.start()
        schema = writer.register_schema("std_msgs/msg/String", "ros2msg", b"string data")
        channels = [writer.register_channel(topic, "cdr", schema) for topic in ("/a", "/b")]
        for c, log_times in enumerate(chunks):
            for k, log_time in enumerate(log_times):
                writer.add_message(channels[k % 2], log_time, f"{c}.{k}".encode(), log_time)
            writer.flush()
        writer.finish()
    return file


@pytest.mark.parametrize("chunks", [IN_SEQUENCE, OVERLAPPING, TOUCHING_BACKWARDS],
                         ids=["in_sequence", "overlapping", "touching_backwards"])
def test_messages_come_in_mcaps_log_time_order(tmp_path: Path, chunks: list[list[int]]) -> None:
    """read_bag_raw yields an MCAP file's messages in the order of mcap's SeekingReader (log time; equal
    log times by chunk offset, then position in the chunk), on all topics and on one; read_bag_raw_blocks
    the same messages as columns (a chunk at a time where the chunks are in sequence)."""
    from mcap.reader import SeekingReader

    file = _chunked_mcap(tmp_path / "chunks.mcap", chunks)
    with open(file, "rb") as stream:
        summary = SeekingReader(stream).get_summary()
        assert summary is not None and len(summary.chunk_indexes) == len(chunks)
        spans = sorted((c.message_start_time, c.message_end_time) for c in summary.chunk_indexes)
        assert any(end == start for (_, end), (start, _) in zip(spans, spans[1:]))   # a tie across chunks
        assert all(end <= start for (_, end), (start, _) in zip(spans, spans[1:])) == (chunks is not OVERLAPPING)
    for topics in (None, ["/b"]):
        with open(file, "rb") as stream:
            expected = [(channel.topic, message.log_time, message.data) for _, channel, message
                        in SeekingReader(stream).iter_messages(topics=topics, log_time_order=True)]
        assert [(m.topic, m.log_time_ns, m.data) for m in read_bag_raw(file, topics=topics)] == expected
        blocks = list(read_bag_raw_blocks(file, topics=topics))
        assert [m for b in blocks for m in zip(b.topic, b.log_time_ns, b.data)] == expected
        assert [t for b in blocks for t in b.type_name] == ["std_msgs/msg/String"] * len(expected)
        assert len(expected) == sum(len(c) if topics is None else len(c) // 2 for c in chunks)


SAMPLE_BAGS = Path(__file__).resolve().parents[1] / "bags"


@pytest.mark.parametrize("bag", ["belarus_1221_lift_transport", "damping_hitch_lift"])
def test_chunk_messages_are_mcaps_own(bag: str) -> None:
    """The chunk reader's records (``chunk_messages``: split by their heads, or taken at the offsets of
    the chunk's MessageIndex records; only the wanted channels built) are, field for field, the Message
    records mcap's ``breakup_chunk`` gives for the same channels, for every chunk of a bundled bag, with
    every channel wanted and with one; offsets that do not point at the wanted messages (one moved by a
    byte, one dropped into another channel's) are not taken: the records are split instead."""
    def fields(m: Message) -> tuple:
        return m.channel_id, m.sequence, m.log_time, m.publish_time, bytes(m.data)

    for file in sorted((SAMPLE_BAGS / bag).glob("*.mcap")):
        with open(file, "rb") as stream:
            summary = SeekingReader(stream).get_summary()
            assert summary is not None and summary.chunk_indexes
            one = {next(i for i, c in summary.channels.items() if c.topic == "/joint_states")}
            for index in summary.chunk_indexes:
                stream.seek(index.chunk_start_offset + 1 + 8)
                chunk = Chunk.read(ReadDataStream(stream))
                theirs = [fields(r) for r in breakup_chunk(chunk, validate_crc=True) if isinstance(r, Message)]
                mine = [t for t in theirs if t[0] in one]
                every = set(summary.channels)
                indexed_every, indexed_one = (indexed_offsets(stream, index, c) for c in (every, one))
                assert indexed_every is not None and len(indexed_every) == len(theirs)
                for wanted, offsets, expected in ((every, None, theirs), (one, None, mine),
                                                  (every, indexed_every, theirs), (one, indexed_one, mine),
                                                  (one, indexed_one + 1, mine), (one, indexed_every, mine)):
                    assert [fields(m) for m in chunk_messages(chunk, wanted, offsets)] == expected


def test_chunk_messages_refuse_a_record_past_the_chunk_end() -> None:
    """A chunk whose last record claims more bytes than the chunk holds is refused (ValueError; the
    bag reader then skips the chunk by name), never read short."""
    record = bytes([0x05]) + (40).to_bytes(8, "little") + bytes(30)   # a Message claiming 40 bytes, 30 there
    chunk = Chunk(compression="", data=record, message_end_time=0, message_start_time=0,
                  uncompressed_crc=zlib.crc32(record), uncompressed_size=len(record))
    with pytest.raises(ValueError, match="runs past"):
        chunk_messages(chunk, {0}, None)
