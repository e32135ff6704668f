"""can-to-bag on blocks of frames, held to the one-frame-at-a-time path and to the libraries it stands
in for: the candump reader to python-can's reader (the shipped log and a log of every special case),
the signals' raw values to cantools' decoding, the block decoder to ``CanDecoder.decode`` frame for
frame (outcomes, events, findings, counts), the CDR rows to the per-message encoders and rclpy, the
bag's chunks written by ``BagWriter.write_rows`` to ``BagWriter.write`` message by message (read back by
mcap and rosbags), and a whole conversion to the per-frame recording of the same frames."""

from __future__ import annotations

import struct
from dataclasses import replace
from pathlib import Path

import can
import numpy as np
import pytest
from mcap.reader import NonSeekingReader, make_reader
from mcap.writer import CompressionType
from rosbags.rosbag2 import Reader

from linkage_monitor.bag.row_block import MessageRows
from linkage_monitor.bag.split_files import MIN_SPLIT_SIZE
from linkage_monitor.bag.writer import BagWriter
from linkage_monitor.can.candump import RefusedLine, parse_candump, read_candump
from linkage_monitor.can.decoder import CanDecoder, load_databases
from linkage_monitor.can.frame_msg import FRAME_TYPE, frames_cdr, from_cdr, to_cdr
from linkage_monitor.can.frames import Frame, FrameBlock, to_message
from linkage_monitor.can.input_msg import (
    fluid_pressure_cdr, fluid_pressures_cdr, joint_state_cdr, joint_states_cdr)
from linkage_monitor.can.j1939 import Raw, classify, is_value
from linkage_monitor.can.mapping import load_mapping, mapping_from_text
from linkage_monitor.can.outcomes import OUTCOMES
from linkage_monitor.can.position_table import PositionTable
from linkage_monitor.can.signals import raw_values, signal_layout, words
from linkage_monitor.can.sources import read_log, read_log_blocks
from linkage_monitor.can.to_bag import RAW_TOPIC, blocks_to_bag
from linkage_monitor.mechanics import InputError, load_description
from linkage_monitor.monitoring.config import MonitorConfig
from linkage_monitor.monitoring.events import JointStateEvent
from support.can_per_frame import per_frame_bag

ROOT = Path(__file__).resolve().parent.parent
LOG = ROOT / "bags" / "can" / "belarus_1221_lift.log"
MAP = ROOT / "config" / "can" / "belarus_1221.yaml"
T0 = 1_767_225_600_000_000_000   # ns

# every kind of line python-can's candump reader reads, and how it reads them (error frames of other
# classes than bus errors, which python-can reads as data frames: test_hostile_can.py)
SPECIAL_LINES = """\
(1767225600.000000) can0 0CFE45F0#2A40FFFFFF3F0000 R
(1767225600.000500) can0 123#DEAD T
(1767225600.000600) can0 123#

(1767225600.000700) vcan1 7FF#R
(1767225600.000800) can0 1FFFFFFF#R8 R
(1767225600.000850) can0 1FFFFFFF#r
(1767225600.000900) can0 123##1000102030405060708090A0B0C0D0E0F
(1767225600.000950) can0 18FF2021##3000102030405060708090A0B0C0D0E0F101112131415161718191A1B1C1D1E1F
(1767225600.001000) can0 20000080#0000000000000000
(0.0) vcan0 001#8d00100100820100
(1.5) vcan0 001#8d
   (1767225600.001200) can0 123#0102
(1767225600.001300)\tcan0\t123#0102
(1767225600.001400) 1 123#abcdef
(1767225600.001500) can0 12345#01
(1767225600.001600) can0 0123#01
(1767225600.001700) can0 80000123#01 R
(1767225600.001800) can0 123#ABC
(1767225600.001900) can0 123#0102030405060708090A
(1767225600.0019999) can0 123#01
(1767225600.002000) can0 123#01 t
(1767225600.002100) can0 123#01 r
(01767225600.002100) can0 123#01
(1767225600.002200) can0#x 123#01
(1767225600.002300) can0 0CFE45F0#7D40FFFFFF3F0000
"""


def _python_can_frames(path: Path) -> list[Frame]:
    return list(read_log(path))


def _block_frames(path: Path, piece_bytes: int | None = None) -> list[Frame]:
    refused: list[RefusedLine] = []
    blocks = read_candump(path, refused) if piece_bytes is None else read_candump(path, refused, piece_bytes)
    frames = [frame for block in blocks for frame in block.frames()]
    assert refused == []
    return frames


def _special_log(tmp_path: Path) -> Path:
    """The special lines, then python-can's writer's own lines for frames of every kind, with CR LF and
    lone CR line ends and no newline at the end."""
    path = tmp_path / "special.log"
    written = tmp_path / "written.log"
    rng = np.random.default_rng(5)
    with can.CanutilsLogWriter(str(written), channel="can1") as writer:
        for k in range(200):
            extended = bool(rng.random() < 0.6)
            ident = int(rng.integers(0, 1 << 29 if extended else 1 << 11))
            kind = rng.choice(["data", "remote", "error", "fd"], p=[0.8, 0.08, 0.04, 0.08])
            length = int(rng.integers(0, 65 if kind == "fd" else 9))
            writer.on_message_received(can.Message(
                timestamp=1_767_225_600 + k * 0.000731, arbitration_id=ident, is_extended_id=extended,
                is_remote_frame=kind == "remote", is_error_frame=kind == "error", is_fd=kind == "fd",
                bitrate_switch=bool(rng.random() < 0.5), is_rx=bool(rng.random() < 0.5),
                data=bytes(rng.integers(0, 256, 0 if kind == "remote" else length, dtype=np.uint8)), check=False))
    lines = written.read_text().splitlines()
    text = SPECIAL_LINES + "\r\n".join(lines[:100]) + "\r" + "\n".join(lines[100:])
    path.write_bytes(text.encode())
    return path


# ---- the candump reader ---------------------------------------------------------------------------------
def test_the_shipped_log_reads_as_python_can_reads_it() -> None:
    assert _block_frames(LOG) == _python_can_frames(LOG)


@pytest.mark.parametrize("piece_bytes", [None, 97, 1000])
def test_every_special_line_reads_as_python_can_reads_it(tmp_path: Path, piece_bytes: int | None) -> None:
    path = _special_log(tmp_path)
    expected = _python_can_frames(path)
    assert len(expected) > 220
    assert _block_frames(path, piece_bytes) == expected


def test_most_lines_take_the_fast_path_and_the_rest_python_can() -> None:
    """The shipped log needs python-can for no line; a block of special lines mixes both, in order."""
    from linkage_monitor.can import candump

    calls: list[bytes] = []
    original = candump.python_can_line
    try:
        candump.python_can_line = lambda line: calls.append(line) or original(line)   # type: ignore[assignment]
        list(read_candump(LOG, []))
        assert calls == []
        parse_candump(SPECIAL_LINES.encode(), [])
    finally:
        candump.python_can_line = original   # type: ignore[assignment]
    assert b"(1767225600.000700) vcan1 7FF#R" in calls and b"(1767225600.000000) can0 0CFE45F0#2A40FFFFFF3F0000 R" \
        not in calls


@pytest.mark.parametrize("line", ["(1767225600.000000) can0 123#01 X", "(1767225600.000000) can0", "garbage",
                                  "(1767225600.000000) can0 XYZ#01", "(abc) can0 123#01"])
def test_a_line_python_can_refuses_is_refused(tmp_path: Path, line: str) -> None:
    """python-can's reader gives up on the whole log; the block reader refuses the line alone, by number."""
    path = tmp_path / "bad.log"
    path.write_text(f"(1767225600.000000) can0 123#01\n{line}\n(1767225600.000100) can0 124#02\n")
    with pytest.raises(InputError, match="unreadable"):
        list(read_log(path))
    refused: list[RefusedLine] = []
    frames = [f for block in read_log_blocks(path, refused) for f in block.frames()]
    assert [f.arbitration_id for f in frames] == [0x123, 0x124]
    assert [r.number for r in refused] == [2] and "not a CAN frame python-can reads" in refused[0].reason


# ---- signals, tables, J1939 ranges ---------------------------------------------------------------------------
def test_raw_values_are_cantools_raw_values() -> None:
    """Random signals (Intel and Motorola, signed and unsigned, 1 to 52 bits, messages of 1 to 8 bytes)
    read from random data: cantools' ``decode(scaling=False)`` is the oracle."""
    from cantools.database.can import Message, Signal

    rng = np.random.default_rng(11)
    for _ in range(300):
        length_bytes = int(rng.integers(1, 9))
        bits = int(rng.integers(1, min(52, 8 * length_bytes) + 1))
        order = str(rng.choice(["little_endian", "big_endian"]))
        first = int(rng.integers(0, 8 * length_bytes - bits + 1))   # Intel: the LSB; Motorola: the MSB (network order)
        start = first if order == "little_endian" else 8 * (first // 8) + 7 - first % 8
        signal = Signal("s", start=start, length=bits, byte_order=order, is_signed=bool(rng.random() < 0.5))
        message = Message(frame_id=1, name="m", length=length_bytes, signals=[signal], strict=False)
        data = np.zeros((40, 8), np.uint8)
        data[:, :length_bytes] = rng.integers(0, 256, (40, length_bytes))
        layout = signal_layout(message, signal)
        assert layout is not None
        got = raw_values(words(data), layout).tolist()
        assert got == [message.decode(bytes(row[:length_bytes]), decode_choices=False, scaling=False)["s"]
                       for row in data]


def test_table_lookup_of_many_is_lookup_of_each() -> None:
    table = load_mapping(MAP).inputs[0].table
    assert table is not None
    x = np.concatenate([np.arange(0.0, 100.4, 0.4), np.array(table.signal), np.random.default_rng(2).uniform(0, 100, 500)])
    values, inside = table.lookup_many(x)
    for xi, vi, ii in zip(x.tolist(), values.tolist(), inside.tolist()):
        expected = table.lookup(xi)
        assert ii == (expected is not None) and (expected is None or vi == expected)
    assert PositionTable((0.0, 1.0), (5.0, 3.0)).lookup_many(np.array([1.0]))[0][0] == 3.0


def test_j1939_value_ranges_of_many_are_classify_of_each() -> None:
    for length in range(1, 33):
        top = 1 << length
        raw = np.unique(np.concatenate([np.arange(min(top, 300)), top - 1 - np.arange(min(top, 300))]))
        assert is_value(raw, length).tolist() == [classify(int(r), length) is Raw.VALUE for r in raw]


# ---- the block decoder against decode() ------------------------------------------------------------------
SYNTHETIC_DBC = """VERSION ""

NS_ :

BS_:

BU_: ECU

BO_ 2566856738 Mixed: 8 ECU
 SG_ Angle : 7|16@0- (0.01,0) [-180|180] "deg" ECU
 SG_ Stroke : 20|12@1+ (0.5,100) [100|2000] "mm" ECU
 SG_ Nibble : 36|4@1+ (1,0) [0|15] "" ECU

BO_ 512 Pressure: 6 ECU
 SG_ Cap : 8|16@1+ (5,-100) [-100|300000] "kPa" ECU

BO_ 513 FloatPressure: 8 ECU
 SG_ Cap : 0|32@1- (1,0) [0|40000] "kPa" ECU

BA_DEF_ BO_ "VFrameFormat" ENUM "StandardCAN","ExtendedCAN","reserved","J1939PG";
BA_DEF_DEF_ "VFrameFormat" "J1939PG";
BA_DEF_ "ProtocolType" STRING ;
BA_DEF_DEF_ "ProtocolType" "J1939";
BA_ "ProtocolType" "J1939";
BA_ "VFrameFormat" BO_ 2566856738 3;
SIG_VALTYPE_ 513 Cap : 1;
"""
# numpy decodes every mapped message / the float pressure is decoded one frame at a time
SYNTHETIC_MAPS = {
    "numpy": """mechanism: belarus_1221
dbc: [synthetic.dbc]
inputs:
  lift_arm_angle: {message: Mixed, signal: Angle, unit: deg, scale: 1.5, offset: -160, source_address: 0x22}
  lift_cylinder: {message: Mixed, signal: Stroke, unit: mm, source_address: 0x22}
  lift_cap_pressure: {message: Pressure, signal: Cap, unit: kPa, pressure: absolute}
""",
    "one by one": """mechanism: belarus_1221
dbc: [synthetic.dbc]
inputs:
  lift_arm_angle: {message: Mixed, signal: Nibble, table: {signal: [1, 5, 14], value: [-2.9, -2.8, -2.7]},
                   source_address: 0x80}
  lift_cap_pressure: {message: FloatPressure, signal: Cap, unit: kPa, pressure: gauge}
""",
}
SYNTHETIC_IDS = [0x18FF2022, 0x18FF2080, 0x200, 0x201, 0x202, 0x0CFE45F0, 0x123]
SHIPPED_IDS = [0x0CFE45F0, 0x0CFE4580, 0x18FF2021, 0x0CFE48F0, 0x0CF00400, 0x0CFE23F0, 0x123, 0x7FF]


def _decoder(mapping_text: str | None, folder: Path) -> CanDecoder:
    mech = load_description("belarus_1221")
    if mapping_text is None:
        mapping = load_mapping(MAP)
    else:
        (folder / "synthetic.dbc").write_text(SYNTHETIC_DBC)
        mapping = mapping_from_text(mapping_text, "synthetic.yaml", folder)
    return CanDecoder(load_databases(mapping.dbc), mapping, mech, MonitorConfig.default("belarus_1221", mech), "can0")


def _random_frames(ids: list[int], n: int, seed: int) -> list[Frame]:
    """Frames of ``ids`` with random data, some with J1939 'error' / 'not available' bytes, other data
    lengths or DLCs, remote requests and error frames (bus-off among them)."""
    rng = np.random.default_rng(seed)
    frames = []
    for k in range(n):
        ident = int(rng.choice(ids))
        size = int(rng.choice([8, 8, 8, 6, 6, 5, 0, 12]))
        data = bytearray(rng.integers(0, 256, size, dtype=np.uint8).tobytes())
        if size and rng.random() < 0.3:
            data[int(rng.integers(0, size))] = int(rng.choice([0xFE, 0xFF, 0xFB, 0x00, 0x7D]))
        error = bool(rng.random() < 0.03)
        frames.append(Frame(T0 + k * 500_000, int(rng.choice([0x40, 0x04])) if error else ident, ident > 0x7FF,
                            bool(rng.random() < 0.04), error, size if rng.random() > 0.05 else 8, bytes(data)))
    return frames


def _bits(values) -> tuple[str, ...]:
    """Floats as their bytes (a float signal may read NaN: equal to itself here)."""
    return tuple(struct.pack("<d", v).hex() for v in values)


def _events(decoded_events: tuple) -> list[tuple]:
    return [("joint", e.topic, tuple(e.names), _bits(e.positions), e.stamp_ns) if isinstance(e, JointStateEvent)
            else ("pressure", e.topic, _bits([e.fluid_pressure]), e.stamp_ns) for e in decoded_events]


def _block_events(block: FrameBlock, result) -> dict[int, list[tuple]]:
    out: dict[int, list[tuple]] = {}
    for d in result.inputs:
        for j, row in enumerate(d.rows.tolist()):
            stamp = int(block.stamp_ns[row])
            events = [("joint", d.joint_topic, d.joint_names, _bits(d.positions[j].tolist()), stamp)] if d.joint_names else []
            events += [("pressure", topic, _bits([d.pressures[j, k]]), stamp) for k, topic in enumerate(d.pressure_topics)]
            out[row] = events
    for row, one in result.single.items():
        out[row] = _events(one.events)
    return out


@pytest.mark.parametrize("case", ["shipped", "numpy", "one by one"])
def test_block_decoding_is_decode_of_each_frame(tmp_path: Path, case: str) -> None:
    text = None if case == "shipped" else SYNTHETIC_MAPS[case]
    frames = _random_frames(SHIPPED_IDS if case == "shipped" else SYNTHETIC_IDS, 6000, seed=len(case))
    if case == "shipped":
        frames = _python_can_frames(LOG) + frames
    block_decoder, frame_decoder = _decoder(text, tmp_path), _decoder(text, tmp_path)
    block = FrameBlock.of(frames)
    result = block_decoder.decode_block(block)
    expected = [frame_decoder.decode(f, f.stamp_ns) for f in frames]
    assert [OUTCOMES[o] for o in result.outcome] == [d.outcome for d in expected]
    got = _block_events(block, result)
    assert all(got.get(k, []) == _events(d.events) for k, d in enumerate(expected))
    assert [(f.code, f.text) for f in result.refusals()] == [(d.finding.code, d.finding.text) for d in expected
                                                             if d.finding is not None]
    assert block_decoder.counts == frame_decoder.counts
    assert list(block_decoder.counts.unknown_ids.items()) == list(frame_decoder.counts.unknown_ids.items())
    counts = block_decoder.counts
    assert counts.decoded > 200 and counts.refused > 200 and counts.ignored > 200
    assert counts.decoded + counts.ignored + counts.refused == counts.received == len(frames)
    if case == "one by one":
        assert all(d.pressure_topics == () for d in result.inputs)   # the float pressure: decode(), frame by frame


# ---- CDR rows -------------------------------------------------------------------------------------------------------
def test_frame_rows_are_to_cdr_and_read_by_rclpy(tmp_path: Path) -> None:
    frames = _python_can_frames(_special_log(tmp_path)) + _random_frames(SHIPPED_IDS, 300, seed=3)
    rows = frames_cdr(FrameBlock.of(frames))
    for row, frame in zip(rows, frames):
        assert row.tobytes() == to_cdr(frame)
        back = from_cdr(row.tobytes())
        assert (back.stamp_ns, back.arbitration_id, back.is_extended, back.is_remote, back.is_error, back.dlc) == (
            frame.stamp_ns, frame.arbitration_id, frame.is_extended, frame.is_remote, frame.is_error, frame.dlc)
        assert back.data == (frame.data + bytes(8))[:min(frame.dlc, 8)]   # the message holds 8 bytes, dlc of them used
    with pytest.raises(struct.error):
        frames_cdr(FrameBlock.of([Frame(1 << 62, 1, False, False, False, 0, b"")]))


@pytest.mark.parametrize("names", [("lift_arm_angle", "lift_cylinder"), ("a",), ("abcd",), ("abc", "de", "fgh")])
def test_input_rows_are_the_per_message_encoders(names: tuple[str, ...]) -> None:
    rng = np.random.default_rng(len(names))
    stamps = np.array([T0, T0 + 123_456_789, 5, 0])
    positions = rng.normal(size=(4, len(names)))
    rows = joint_states_cdr(stamps, names, positions)
    assert [r.tobytes() for r in rows] == [joint_state_cdr(int(s), names, p.tolist()) for s, p in zip(stamps, positions)]
    pascal = rng.uniform(0, 3e7, 4)
    rows = fluid_pressures_cdr(stamps, pascal)
    assert [r.tobytes() for r in rows] == [fluid_pressure_cdr(int(s), float(p)) for s, p in zip(stamps, pascal)]


# ---- the bag: chunks written in blocks against write() message by message ------------------------------------
def _mcap_messages(bag: Path, indexed: bool = True) -> list[tuple]:
    out = []
    for file in sorted(bag.glob("*.mcap")):
        with open(file, "rb") as f:
            reader = make_reader(f) if indexed else NonSeekingReader(f)
            out += [(file.name[len(bag.name):], c.topic, s.name, s.data, dict(c.metadata), m.sequence, m.log_time,
                     m.publish_time, m.data) for s, c, m in reader.iter_messages()]
    return out


def _rosbags_messages(bag: Path) -> list[tuple]:
    with Reader(bag) as reader:
        return [(c.topic, c.msgtype, t, bytes(d)) for c, t, d in reader.messages()]


def _parts(n: int, seed: int) -> list[MessageRows]:
    """n frames' raw messages and a pressure after half of them, a stamp going back now and then."""
    frames = _random_frames(SHIPPED_IDS, n, seed)
    block = FrameBlock.of(frames)
    block.stamp_ns[::97] -= 3_000_000   # out of order: log times are moved up, as write() moves them
    rng = np.random.default_rng(seed)
    chosen = np.flatnonzero(rng.random(n) < 0.5)
    per_frame = np.ones(n, np.int64)
    per_frame[chosen] += 1
    raw_at = np.cumsum(per_frame) - per_frame
    stamps = block.stamp_ns
    return [MessageRows(RAW_TOPIC, FRAME_TYPE, frames_cdr(block), raw_at, stamps, stamps),
            MessageRows("/p", "sensor_msgs/msg/FluidPressure", fluid_pressures_cdr(stamps[chosen], rng.uniform(0, 1e7, len(chosen))),
                        raw_at[chosen] + 1, stamps[chosen], stamps[chosen])]


def _messages(part: MessageRows) -> list[bytes]:
    """A part's messages: its rows, or its bytes cut at its sizes."""
    if part.sizes is None:
        return [row.tobytes() for row in part.data]
    ends = np.cumsum(part.sizes).tolist()
    return [part.data[end - size:end].tobytes() for end, size in zip(ends, part.sizes.tolist())]


def _one_by_one(writer: BagWriter, parts: list[MessageRows]) -> None:
    order = sorted((int(p.position[r]), k, r) for k, p in enumerate(parts) for r in range(len(p.position)))
    messages = [_messages(p) for p in parts]
    for _, k, r in order:
        p = parts[k]
        writer.write(p.topic, messages[k][r], int(p.stamp_ns[r]), type_name=p.type_name, qos=p.qos,
                     log_time_ns=int(p.log_time_ns[r]))


@pytest.mark.parametrize("options", [{}, {"chunk_size": 4096}, {"chunk_size": 4096, "max_bag_duration_s": 0.15}],
                         ids=["one chunk", "small chunks", "split by duration"])
def test_rows_written_in_chunks_read_as_written_one_by_one(tmp_path: Path, options: dict) -> None:
    from std_msgs.msg import String

    blocks = [_parts(900, seed=1), _parts(700, seed=2)]
    for name in ("single", "rows"):
        with BagWriter(tmp_path / name, **options) as writer:
            writer.write("/start", String(data="before"), T0, log_time_ns=T0)
            for parts in blocks:
                if name == "single":
                    _one_by_one(writer, parts)
                else:
                    writer.write_rows(parts)
                writer.write("/between", String(data="queued"), T0 + 1, log_time_ns=T0 + 1)
    single, rows = tmp_path / "single", tmp_path / "rows"
    assert _mcap_messages(rows) == _mcap_messages(single)
    assert _mcap_messages(rows, indexed=False) == _mcap_messages(single, indexed=False)
    assert _rosbags_messages(rows) == _rosbags_messages(single)
    assert (rows / "metadata.yaml").read_text().replace("rows_", "X_") == \
        (single / "metadata.yaml").read_text().replace("single_", "X_")
    files = len(list(rows.glob("*.mcap")))
    assert files == len(list(single.glob("*.mcap"))) and (files > 2) == ("max_bag_duration_s" in options)


def _sized_parts(n: int, seed: int) -> list[MessageRows]:
    """n messages on three topics in a random order, several to a log time, one going back: two of messages
    of any sizes (0 to 300 B, ``MessageRows.of_messages``), one of them with a QoS of its own, and one of rows;
    the topic of the block's first message comes last among the parts."""
    from rclpy.qos import DurabilityPolicy, QoSProfile

    rng = np.random.default_rng(seed)
    topic = rng.integers(0, 3, n)
    topic[0] = 2
    log_time = T0 + np.cumsum(rng.integers(0, 2, n)) * 1_000_000 + seed * 10**9
    log_time[n // 2] -= 5_000_000
    stamp = log_time - rng.integers(0, 1000, n)
    where = [np.flatnonzero(topic == k) for k in range(3)]
    return [MessageRows.of_messages("/any", "std_msgs/msg/String",
                                    [rng.bytes(int(size)) for size in rng.integers(0, 301, len(where[0]))],
                                    where[0], stamp[where[0]], log_time[where[0]]),
            MessageRows("/rows", "sensor_msgs/msg/FluidPressure", rng.integers(0, 256, (len(where[1]), 48), np.uint8),
                        where[1], stamp[where[1]], log_time[where[1]]),
            MessageRows.of_messages(RAW_TOPIC, FRAME_TYPE,
                                    [rng.bytes(int(size)) for size in rng.integers(0, 301, len(where[2]))],
                                    where[2], stamp[where[2]], log_time[where[2]],
                                    QoSProfile(depth=3, durability=DurabilityPolicy.TRANSIENT_LOCAL))]


@pytest.mark.parametrize("options", [{}, {"chunk_size": 4096}, {"chunk_size": 4096, "max_bag_duration_s": 0.15}],
                         ids=["one chunk", "small chunks", "split by duration"])
def test_rows_of_any_sizes_read_as_written_one_by_one(tmp_path: Path, options: dict) -> None:
    """Messages of any sizes, a part's own QoS, parts not in the order of their first messages: the bag
    written in chunks is the bag written message by message (topics and channels registered in the order
    of their first messages, the QoS offered for each topic, the same records)."""
    blocks = [_sized_parts(700, seed=1), _sized_parts(600, seed=2)]
    for name in ("single", "rows"):
        with BagWriter(tmp_path / name, **options) as writer:
            for parts in blocks:
                if name == "single":
                    _one_by_one(writer, parts)
                else:
                    writer.write_rows(parts)
    single, rows = tmp_path / "single", tmp_path / "rows"
    assert _mcap_messages(rows) == _mcap_messages(single)
    assert _mcap_messages(rows, indexed=False) == _mcap_messages(single, indexed=False)
    assert _rosbags_messages(rows) == _rosbags_messages(single)
    with Reader(rows) as reader:
        assert reader.connections[0].topic == RAW_TOPIC
    assert (rows / "metadata.yaml").read_text().replace("rows_", "X_") == \
        (single / "metadata.yaml").read_text().replace("single_", "X_")
    files = len(list(rows.glob("*.mcap")))
    assert files == len(list(single.glob("*.mcap"))) and (files > 2) == ("max_bag_duration_s" in options)


def test_rows_of_sizes_that_do_not_cut_their_bytes_are_refused(tmp_path: Path) -> None:
    part = MessageRows.of_messages("/any", "std_msgs/msg/String", [b"abc", b"de"], np.array([0, 1]),
                                   np.array([T0, T0]), np.array([T0, T0]))
    with BagWriter(tmp_path / "bag") as writer:
        for wrong in (part._replace(sizes=np.array([3, 3])), part._replace(sizes=np.array([5])),
                      part._replace(data=part.data.reshape(1, 5))):
            with pytest.raises(ValueError, match="/any"):
                writer.write_rows([wrong])


def test_rows_split_by_size_and_every_file_reads_alone(tmp_path: Path) -> None:
    with BagWriter(tmp_path / "bag", chunk_size=4096, max_bag_size=MIN_SPLIT_SIZE) as writer:
        for seed in range(12):
            writer.write_rows(_parts(800, seed))
    files = sorted((tmp_path / "bag").glob("*.mcap"))
    assert len(files) >= 4
    counts = []
    for file in files:
        with open(file, "rb") as f:
            reader = make_reader(f)
            counts.append(sum(1 for _ in reader.iter_messages()))
            assert reader.get_summary() is not None
    assert sum(counts) == sum(len(p.position) for seed in range(12) for p in _parts(800, seed)) and min(counts) > 0


def test_rows_leave_a_readable_file_before_close(tmp_path: Path) -> None:
    """Crash safety: the file ends in a valid tail after every chunk written in blocks."""
    writer = BagWriter(tmp_path / "bag", chunk_size=4096)
    parts = _parts(500, seed=4)
    writer.write_rows(parts)
    with open(next((tmp_path / "bag").glob("*.mcap")), "rb") as f:
        assert sum(1 for _ in NonSeekingReader(f).iter_messages()) == sum(len(p.position) for p in parts)
    writer.close()


def test_rows_on_a_full_disk_are_reported_and_the_bag_stays_readable(tmpfs) -> None:
    disk = tmpfs("size=256k")
    writer = BagWriter(disk / "run", chunk_size=16 * 1024, compression=CompressionType.NONE)
    total = 0
    for seed in range(12):
        parts = _parts(1500, seed)
        total += sum(len(p.position) for p in parts)
        writer.write_rows(parts)   # never raises
    assert writer.error is not None and "No space left" in writer.error
    assert 0 < writer.unwritten < total
    writer.close()
    with open(next((disk / "run").glob("*.mcap")), "rb") as f:
        readable = sum(1 for _ in NonSeekingReader(f).iter_messages())
    assert readable == total - writer.unwritten == sum(1 for _ in _rosbags_messages(disk / "run"))


# ---- a whole conversion against the per-frame recording ------------------------------------------------------
@pytest.mark.slow
@pytest.mark.parametrize("case", ["shipped", "numpy", "one by one"])
def test_can_to_bag_in_blocks_records_what_the_bridge_records(tmp_path: Path, case: str) -> None:
    text = None if case == "shipped" else SYNTHETIC_MAPS[case]
    frames = _random_frames(SHIPPED_IDS if case == "shipped" else SYNTHETIC_IDS, 3000, seed=7)
    if case == "shipped":
        frames = _python_can_frames(LOG) + [replace(f, stamp_ns=f.stamp_ns + 10**11) for f in frames]
    log = tmp_path / "frames.log"
    with can.CanutilsLogWriter(str(log), channel="can0") as writer:
        for frame in frames:
            writer.on_message_received(to_message(frame))
    frames = _python_can_frames(log)   # as the log holds them (python-can's reading)
    decoder = _decoder(text, tmp_path)
    converted = blocks_to_bag(read_log_blocks(log, []), decoder, load_description("belarus_1221"), decoder.config,
                              tmp_path / "blocks")
    reference = _decoder(text, tmp_path)
    per_frame_bag(frames, reference, load_description("belarus_1221"), tmp_path / "frames")
    assert _mcap_messages(tmp_path / "blocks") == [(n.replace("frames_", "blocks_"), *rest) for n, *rest in
                                                   _mcap_messages(tmp_path / "frames")]
    assert _rosbags_messages(tmp_path / "blocks") == _rosbags_messages(tmp_path / "frames")
    assert converted.counts == reference.counts
    again = _decoder(text, tmp_path)   # a new decoder: the sources a decoder has seen are its state
    refused = [frame for frame in frames if again.decode(frame, frame.stamp_ns).finding is not None]
    assert len(converted.refusals) == len(refused) > 0


@pytest.mark.slow
def test_the_cli_prints_the_counts_of_every_special_line(tmp_path: Path) -> None:
    import subprocess
    import sys

    path = _special_log(tmp_path)
    decoder = _decoder(None, tmp_path)
    for frame in _python_can_frames(path):
        decoder.decode(frame, frame.stamp_ns)
    result = subprocess.run([sys.executable, "-m", "linkage_monitor.cli.main", "can-to-bag", str(path), "--map", str(MAP),
                             "--out", str(tmp_path / "bag")], capture_output=True, text=True)
    assert result.returncode == 0, result.stderr
    assert result.stdout.splitlines()[0] == decoder.counts.summary()
