"""rosbag2-compatible MCAP bag writer: `<dir>/metadata.yaml` + `<dir>/<name>_0.mcap` (`_1.mcap`, ... when split).

What `ros2 bag record -s mcap` writes (rosbag2_storage_mcap, foxglove registry.md): profile
`ros2`, schema name `pkg/msg/Type` with encoding `ros2msg` (msg_schema.message_definition),
messages `cdr` (rclpy.serialization), channel metadata `offered_qos_profiles`, a `rosbag2`
metadata record and a version-9 `metadata.yaml`.

Crash safety: every `flush_period_s` (and on `flush()`) the open chunk is closed and written,
and the file is made to end in a valid DataEnd + Footer (no summary), so a process killed
with SIGKILL leaves a bag that footer-reading readers (rosbags, mcap SeekingReader, Rerun)
open and that holds everything written up to the last flush. `metadata.yaml` is rewritten
at the same time.

Splitting (``max_bag_size``, ``max_bag_duration_s``; off by default), as ``ros2 bag record
--max-bag-size --max-bag-duration`` does: when the file being written has reached the size (bytes,
counted at the message about to be written, chunks uncompressed) or holds messages spanning the
duration (receive time), it is finished (summary, indexes, the ``rosbag2`` metadata record) and the
next message starts `<name>_<k+1>.mcap` with the same schemas, channels and attachments, so every
file is readable on its own; `metadata.yaml` lists every file with its span. The crash safety and
the cut-back on a full disk below hold for the file being written.

Off the caller's path: `write` queues the message (its bytes, times and channel) and returns;
the background thread writes the queue into the MCAP chunk every WRITE_PERIOD_S, in order (a
live node's callback pays a list append per message, not the MCAP writer's record building,
and the thread writes tens of messages in a row). `flush` and `close` write the queue first;
above MAX_QUEUED queued messages `write` writes the queue itself (memory stays bounded, nothing
is dropped).

Many messages at once: ``write_rows`` takes a block of messages as arrays (``MessageRows``: one topic's
CDR payloads as the rows of a uint8 array, or of any sizes one after another with their sizes, with their
places in the block, publish and receive times) and writes them straight into MCAP chunks built with
numpy (``_RowBlock``), with the records, message indexes, chunk indexes and statistics `write` one by
one would give them; the crash-safe tail, the splitting and the cut-back on a full disk hold as for `write`.
"""

from __future__ import annotations

import functools
import importlib.metadata
import os
import struct
import threading
import time
import zlib
from dataclasses import dataclass
from pathlib import Path
from typing import Any, NamedTuple, Sequence

import numpy as np
import yaml
from numpy.lib.stride_tricks import as_strided
from mcap import writer as mcap_writer
from mcap.opcode import Opcode
from mcap.records import ChunkIndex
from mcap.writer import CompressionType, Writer
from rclpy.qos import (
    DurabilityPolicy, HistoryPolicy, LivelinessPolicy, QoSProfile, ReliabilityPolicy)
from rclpy.serialization import serialize_message

from linkage_monitor.bag.errors import BagError
from linkage_monitor.wire.definitions import exact_cdr, message_definition

MECHANISM_TOPIC = "/linkage_monitor/mechanism"
"""Topic of the mechanism description (std_msgs/String holding the mechanism YAML)."""

ROSBAG2_VERSION = 9
_U64 = 1 << 64
_MCAP_MAGIC = b"\x89MCAP0\r\n"
# DataEnd (op 0x0F, crc 0 = not computed) + Footer (op 0x02, summary_start 0 = no summary,
# summary_offset_start 0, summary_crc 0) + magic: the smallest valid MCAP ending.
_TAIL = (struct.pack("<BQI", 0x0F, 4, 0) + struct.pack("<BQQQI", 0x02, 20, 0, 0, 0)
         + _MCAP_MAGIC)
WRITE_PERIOD_S = 0.05   # s, the background thread writes the queued messages this often
MAX_QUEUED = 10_000     # messages queued at most; beyond, write() writes the queue (in order) itself
# B, the smallest max_bag_size (but 0, no splitting): rosbag2's minimum split size of its sqlite3 storage
# (SqliteStorage::get_minimum_split_file_size, 84 KiB; `ros2 bag record` refuses a smaller --max-bag-size
# with it, with its MCAP storage below 1024 B). Every file of ours carries its schemas, channels,
# attachments and summary, and a file is finished at a chunk at the earliest: a smaller size makes a
# file per write (max_bag_size 1: 1,830 files for 450 inputs, minutes to close them at exit).
MIN_SPLIT_SIZE = 86_016
# zstd level of the chunks ``write_rows`` builds (mcap's own chunks: its level 3): the bundled bag's
# chunks compressed in 37 % less time at level 1 than at level 3, to 0.1 % more bytes
ROW_CHUNK_ZSTD_LEVEL = 1
_YAML_DUMPER = getattr(yaml, "CSafeDumper", yaml.SafeDumper)   # libyaml: 4x faster, the same text


def yaml_text(data: Any, **options: Any) -> str:
    """``yaml.safe_dump(data, sort_keys=False, **options)``'s text, written by libyaml where PyYAML has it
    (a bag's metadata at every flush and file, each channel's QoS, the mechanism it records)."""
    return yaml.dump(data, Dumper=_YAML_DUMPER, sort_keys=False, **options)


def message_type_name(msg: Any) -> str:
    """Return the ROS type name `pkg/msg/Type` of an rclpy message object."""
    cls = type(msg)
    package, interface = cls.__module__.split(".")[:2]
    return f"{package}/{interface}/{cls.__name__}"


def qos_to_dict(qos: QoSProfile) -> dict[str, Any]:
    """Return `qos` as one entry of rosbag2 v9 `offered_qos_profiles` (policy names, sec/nsec)."""

    def duration(ns: int) -> dict[str, int]:
        return {"sec": ns // 1_000_000_000, "nsec": ns % 1_000_000_000}

    return {
        "history": HistoryPolicy(qos.history).name.lower(),
        "depth": int(qos.depth),
        "reliability": ReliabilityPolicy(qos.reliability).name.lower(),
        "durability": DurabilityPolicy(qos.durability).name.lower(),
        "deadline": duration(qos.deadline.nanoseconds),
        "lifespan": duration(qos.lifespan.nanoseconds),
        "liveliness": LivelinessPolicy(qos.liveliness).name.lower(),
        "liveliness_lease_duration": duration(qos.liveliness_lease_duration.nanoseconds),
        "avoid_ros_namespace_conventions": bool(qos.avoid_ros_namespace_conventions),
    }


class _TailedFile:
    """Unbuffered file that ends in a valid MCAP tail after every write.

    Each write is followed by `_TAIL`, and the position moves back before it, so the next
    write overwrites it. `tell()` is the logical end; `close()` truncates the last tail.
    """

    def __init__(self, path: Path) -> None:
        self._file = open(path, "xb", buffering=0)  # noqa: SIM115 (closed in close())
        self._tail = False

    def enable_tail(self) -> None:
        self._tail = True

    def write(self, data: bytes | memoryview) -> int:
        """Write all of ``data`` (then the tail); on an I/O error (ENOSPC, EIO) the file is cut back
        to where this write began and ends in the tail again, so it stays readable, and the error
        is raised."""
        start = self._file.tell()
        try:
            view = memoryview(data)
            while view:
                view = view[self._file.write(view):]
            if self._tail:
                self._write_tail()
        except OSError:
            self._rollback(start)
            raise
        return len(data)

    def _write_tail(self) -> None:
        view = memoryview(_TAIL)
        while view:
            view = view[self._file.write(view):]
        self._file.seek(-len(_TAIL), os.SEEK_CUR)

    def _rollback(self, position: int) -> None:
        """Cut the file back to ``position`` and end it in the tail again (best effort: the cut frees
        the space the tail needs)."""
        try:
            self._file.truncate(position)
            self._file.seek(position)
            if self._tail:
                self._write_tail()
        except OSError:
            pass

    def tell(self) -> int:
        return self._file.tell()

    def flush(self) -> None:
        """Nothing buffered in-process; data written is in the OS page cache."""

    def fsync(self) -> None:
        os.fsync(self._file.fileno())

    def close(self, keep_tail: bool = False) -> None:
        """Close; ``keep_tail``: leave the file ending in the tail (after an I/O error, when the
        MCAP writer cannot finish its summary)."""
        try:
            if not keep_tail:
                self._file.truncate(self._file.tell())
        finally:
            self._file.close()


class _McapWriter(Writer):
    """mcap's Writer, which also takes chunks built outside it (``write_rows``): ``take_pending_records``
    hands over the schema and channel records registered since its last chunk, ``add_chunk`` counts a
    chunk written to its stream in its chunk indexes and statistics, as its own chunks are. The only
    code that reaches into the Writer's private state (mcap 1.x: ``_Writer__chunk_builder``,
    ``_Writer__chunk_indices``, ``_Writer__statistics``); test_can_blocks.py holds a bag written by
    chunks equal to one written message by message, as mcap and rosbags read it."""

    def _private(self, name: str) -> Any:
        """The Writer's private attribute ``name`` (``__name`` inside mcap's Writer)."""
        return getattr(self, f"_Writer__{name}")

    def compression_name(self) -> str:
        """The chunk compression as MCAP names it: "zstd", "lz4" or ""."""
        return {CompressionType.ZSTD: "zstd", CompressionType.LZ4: "lz4"}.get(self._private("compression"), "")

    def compress(self, data: bytes) -> bytes:
        """``data`` compressed by this writer's chunk compression; zstd at ROW_CHUNK_ZSTD_LEVEL."""
        kind = self._private("compression")
        if kind == CompressionType.ZSTD:
            return bytes(self._zstd.compress(data))
        if kind == CompressionType.LZ4:
            return bytes(mcap_writer.lz4.frame.compress(data))
        return data

    @functools.cached_property
    def _zstd(self) -> Any:
        """This writer's zstd compressor for ``compress`` (one per writer: a compressor is not thread-safe)."""
        return mcap_writer.zstandard.ZstdCompressor(level=ROW_CHUNK_ZSTD_LEVEL)

    def chunk_crc(self, data: bytes) -> int:
        """The uncompressed CRC this writer gives a chunk of ``data`` (0: CRCs off)."""
        return zlib.crc32(data) if self._private("enable_crcs") else 0

    def take_pending_records(self) -> bytes:
        """The schema and channel records waiting in the open chunk, taken out of it (it must hold no
        message: call ``flush`` first); they go at the front of the next chunk written outside."""
        builder = self._private("chunk_builder")
        if builder.num_messages:
            raise RuntimeError("the open chunk holds messages: flush the writer before writing chunks outside it")
        return bytes(builder.record_writer.end())

    def add_chunk(self, index: ChunkIndex, channel_counts: dict[int, int]) -> None:
        """Count a chunk written to the stream at ``index.chunk_start_offset`` (its messages per channel
        id: ``channel_counts``) in the summary: its chunk index and the statistics."""
        if self._private("enable_data_crcs"):
            raise RuntimeError("chunks written outside the writer carry no data section CRC")
        stats = self._private("statistics")
        count = sum(channel_counts.values())
        stats.message_start_time = (index.message_start_time if stats.message_count == 0
                                    else min(stats.message_start_time, index.message_start_time))
        stats.message_end_time = max(stats.message_end_time, index.message_end_time)
        for channel_id, n in channel_counts.items():
            stats.channel_message_counts[channel_id] += n
        stats.message_count += count
        stats.chunk_count += 1
        self._private("chunk_indices").append(index)


@dataclass
class _Topic:
    """A recorded topic: its type, offered QoS (rosbag2 v9 form) and messages written in all files."""

    name: str
    type_name: str
    qos: dict[str, Any]
    count: int = 0


@dataclass
class _Span:
    """Receive-time span of the messages written, ns since the epoch."""

    start: int | None = None
    end: int | None = None
    count: int = 0

    def add(self, log_time_ns: int) -> None:
        self.start = log_time_ns if self.start is None else min(self.start, log_time_ns)
        self.end = log_time_ns if self.end is None else max(self.end, log_time_ns)
        self.count += 1

    def add_many(self, first_ns: int, last_ns: int, count: int) -> None:
        """``count`` messages logged from ``first_ns`` to ``last_ns`` (ns, in order), as ``add`` of each."""
        self.start = first_ns if self.start is None else min(self.start, first_ns)
        self.end = last_ns if self.end is None else max(self.end, last_ns)
        self.count += count

    def information(self) -> dict[str, Any]:
        """rosbag2's starting_time, duration and message_count of this span."""
        start = self.start or 0
        return {"starting_time": {"nanoseconds_since_epoch": start},
                "duration": {"nanoseconds": (self.end or start) - start},
                "message_count": self.count}


@dataclass
class _Attachment:
    name: str
    data: bytes
    media_type: str
    log_time_ns: int


class _StorageFile:
    """One MCAP file of the bag being written: its tailed file, MCAP writer, the schema and channel
    ids registered in it, and the span of its messages."""

    def __init__(self, path: Path, chunk_size: int, compression: CompressionType) -> None:
        self.path = path
        self.file = _TailedFile(path)
        self.writer = _McapWriter(self.file, chunk_size=chunk_size,  # type: ignore[arg-type]  # file-like
                                  compression=compression)
        self.writer.start(profile="ros2", library="linkage_monitor.bag.writer")
        self.file.enable_tail()
        self.file.write(b"")  # end the header in a valid tail right away
        self.schemas: dict[str, int] = {}
        self.channels: dict[str, int] = {}
        self.span = _Span()
        self.pending_bytes = 0      # message bytes given to the writer since the file last grew
        self._end_seen = self.file.tell()

    def size(self) -> int:
        """Bytes in the file plus the messages still in the open chunk (uncompressed), B."""
        if self.file.tell() != self._end_seen:
            self._end_seen, self.pending_bytes = self.file.tell(), 0
        return self._end_seen + self.pending_bytes

    def channel(self, topic: _Topic) -> int:
        """The channel id of ``topic`` in this file, its schema and channel registered at first use."""
        channel_id = self.channels.get(topic.name)
        if channel_id is None:
            schema_id = self.schemas.get(topic.type_name)
            if schema_id is None:
                schema_id = self.writer.register_schema(
                    name=topic.type_name, encoding="ros2msg",
                    data=message_definition(topic.type_name).encode("utf-8"))
                self.schemas[topic.type_name] = schema_id
            channel_id = self.writer.register_channel(
                topic=topic.name, message_encoding="cdr", schema_id=schema_id,
                metadata={"offered_qos_profiles": yaml_text([topic.qos])})
            self.channels[topic.name] = channel_id
        return channel_id

    def attach(self, item: _Attachment) -> None:
        self.writer.add_attachment(create_time=item.log_time_ns, log_time=item.log_time_ns, name=item.name,
                                   media_type=item.media_type, data=item.data)


class MessageRows(NamedTuple):
    """Messages of one topic and type for ``BagWriter.write_rows``: ``data`` their CDR bytes, (n, size) uint8
    with a row per message of one size, or, with ``sizes`` (n,) given, (total,) uint8 holding the messages one
    after another (message k: ``sizes[k]`` B); ``position`` (n,) their places in the block's order (the parts
    of a block take every place 0..N-1 once); ``stamp_ns`` (n,) header stamps (MCAP publish time) and
    ``log_time_ns`` (n,) receive times (MCAP log time), ns since the epoch; ``qos``: the offered QoS recorded
    for the topic at its first message (None: the one ``write_rows`` is given)."""

    topic: str
    type_name: str
    data: np.ndarray
    position: np.ndarray
    stamp_ns: np.ndarray
    log_time_ns: np.ndarray
    sizes: np.ndarray | None = None
    qos: QoSProfile | None = None

    @staticmethod
    def of_messages(topic: str, type_name: str, messages: Sequence[bytes], position: np.ndarray,
                    stamp_ns: np.ndarray, log_time_ns: np.ndarray, qos: QoSProfile | None = None) -> MessageRows:
        """The rows of ``messages`` (CDR bytes of any sizes), one after another with their sizes."""
        sizes = np.fromiter(map(len, messages), np.int64, len(messages))
        return MessageRows(topic, type_name, np.frombuffer(b"".join(messages), np.uint8), position, stamp_ns,
                           log_time_ns, sizes, qos)

    def payloads(self) -> tuple[np.ndarray, np.ndarray]:
        """The messages' bytes one after another (1-D uint8) and each message's size (B); ValueError when
        ``data`` does not hold ``position``'s messages."""
        n = len(self.position)
        if self.sizes is None:
            if self.data.ndim != 2 or len(self.data) != n:
                raise ValueError(f"{self.topic}: data of shape {self.data.shape} is not one row per message ({n})")
            return np.ascontiguousarray(self.data, np.uint8).reshape(-1), np.full(n, self.data.shape[1], np.int64)
        sizes = np.asarray(self.sizes, np.int64)
        if self.data.ndim != 1 or len(sizes) != n or (n and sizes.min() < 0) or int(sizes.sum()) != len(self.data):
            raise ValueError(f"{self.topic}: {len(sizes)} sizes summing to {int(sizes.sum())} B do not cut data of "
                             f"shape {self.data.shape} into {n} messages")
        return np.ascontiguousarray(self.data, np.uint8), sizes


_RECORD_HEAD = np.dtype([("opcode", "u1"), ("length", "<u8"), ("channel", "<u2"), ("sequence", "<u4"),
                         ("log_time", "<u8"), ("publish_time", "<u8")])   # an MCAP Message record before its data
_INDEX_ENTRY = np.dtype([("log_time", "<u8"), ("offset", "<u8")])       # a MessageIndex record's entry


@dataclass(frozen=True)
class _RowBlock:
    """A block of messages in writing order, as columns (one entry per message): ``part`` and ``start``
    where its bytes are (``data[part][start:start + size]``, ``data`` each part's messages one after
    another), ``topic`` its topic's index in ``entries``, ``size`` its payload bytes, ``log_time`` /
    ``publish_time`` as MCAP stores them (log times never before the previous one), ``sequence`` per
    topic; ``record_end`` / ``payload_end``: cumulative record and payload bytes up to and including it."""

    data: list[np.ndarray]
    entries: list[_Topic]
    part: np.ndarray
    start: np.ndarray
    topic: np.ndarray
    size: np.ndarray
    log_time: np.ndarray
    publish_time: np.ndarray
    sequence: np.ndarray
    record_end: np.ndarray
    payload_end: np.ndarray

    @staticmethod
    def of(parts: Sequence[MessageRows], entries: list[_Topic], last_log_time: int) -> _RowBlock:
        """The block of ``parts`` (their topics' ``entries``); log times are moved up to the one before,
        as ``_write_queued`` does, the first to at least ``last_log_time``; times MCAP cannot store as
        ``write`` stores them (a log time: now; a publish time: 0)."""
        n = sum(len(p.position) for p in parts)
        part, start = np.empty(n, np.int64), np.empty(n, np.int64)
        topic, size = np.empty(n, np.int64), np.empty(n, np.int64)
        log_time, publish_time = np.empty(n, np.int64), np.empty(n, np.int64)
        unique: list[_Topic] = []
        topic_index: dict[int, int] = {}
        for entry in entries:
            if id(entry) not in topic_index:
                topic_index[id(entry)] = len(unique)
                unique.append(entry)
        every = np.concatenate([np.asarray(p.position, np.int64) for p in parts]) if parts else np.zeros(0, np.int64)
        if n and (every.min() < 0 or every.max() >= n or np.bincount(every, minlength=n).max() != 1):
            raise ValueError(f"the parts' positions must take every place of the block (0..{n - 1}) exactly once")
        data = []
        for k, (p, entry) in enumerate(zip(parts, entries)):
            where = np.asarray(p.position, np.int64)
            payloads, sizes = p.payloads()
            data.append(payloads)
            part[where], start[where] = k, np.cumsum(sizes) - sizes
            topic[where], size[where] = topic_index[id(entry)], sizes
            log_time[where] = _storable(p.log_time_ns, time.time_ns())
            publish_time[where] = _storable(p.stamp_ns, 0)
        log_time[:1] = np.maximum(log_time[:1], last_log_time)
        log_time = np.maximum.accumulate(log_time)
        sequence = np.empty(n, np.int64)
        for k, entry in enumerate(unique):
            mine = np.flatnonzero(topic == k)
            sequence[mine] = (entry.count + np.arange(len(mine))) % (1 << 32)
        return _RowBlock(data, unique, part, start, topic, size, log_time, publish_time, sequence,
                         np.cumsum(size + _RECORD_HEAD.itemsize), np.cumsum(size))

    def __len__(self) -> int:
        return len(self.part)

    def records(self, lo: int, hi: int, channels: np.ndarray, lead: bytes) -> tuple[bytes, np.ndarray]:
        """The uncompressed records of a chunk of messages ``lo``..``hi - 1``: ``lead`` (schema and channel
        records) then each message's Message record (its topic's channel id in ``channels``), and each
        message's record offset in them. The records' heads, then each part's payloads of one size, are
        copied as rows into a view of the chunk whose row k starts at byte k (``_starting_at``), from such a
        view of the part's bytes: a row copy per message, no index per byte."""
        head_size = _RECORD_HEAD.itemsize
        size = self.size[lo:hi]
        head = np.empty(hi - lo, _RECORD_HEAD)
        head["opcode"] = int(Opcode.MESSAGE)
        head["length"] = size + head_size - 9   # what follows the opcode and the length field
        head["channel"] = channels[self.topic[lo:hi]]
        head["sequence"] = self.sequence[lo:hi]
        head["log_time"] = self.log_time[lo:hi]
        head["publish_time"] = self.publish_time[lo:hi]
        before = int(self.record_end[lo - 1]) if lo else 0
        offset = len(lead) + self.record_end[lo:hi] - size - head_size - before
        out = np.empty(len(lead) + int(self.record_end[hi - 1]) - before, np.uint8)
        out[:len(lead)] = np.frombuffer(lead, np.uint8)
        _starting_at(out, head_size)[offset] = head.view(np.uint8).reshape(hi - lo, head_size)
        part, start, payload = self.part[lo:hi], self.start[lo:hi], offset + head_size
        for k in np.unique(part).tolist():
            mine = np.flatnonzero(part == k)
            sizes = size[mine]
            for width in np.unique(sizes).tolist():
                these = mine[sizes == width]
                _starting_at(out, width)[payload[these]] = _starting_at(self.data[k], width)[start[these]]
        return out.tobytes(), offset


def _starting_at(data: np.ndarray, width: int) -> np.ndarray:
    """A view of the 1-D ``data`` whose row k is the ``width`` bytes starting at byte k."""
    return as_strided(data, shape=(len(data) - width + 1, width), strides=(1, 1))


def _storable(times: np.ndarray, instead: int) -> np.ndarray:
    """``times`` (ns) with those MCAP cannot store (outside 0..2^64-1; int64 here: negative) replaced."""
    times = np.asarray(times, np.int64)
    return np.where(times >= 0, times, instead)


def _chunk_record(start: int, end: int, uncompressed_size: int, crc: int, compression: str, data: bytes) -> bytes:
    """An MCAP Chunk record (opcode, length, then its fields) of messages logged from ``start`` to ``end``
    (ns) holding ``data`` (compressed by ``compression`` from ``uncompressed_size`` bytes of CRC ``crc``)."""
    name = compression.encode()
    body = struct.pack("<QQQI", start, end, uncompressed_size, crc)
    body += struct.pack("<I", len(name)) + name + struct.pack("<Q", len(data))
    return struct.pack("<BQ", int(Opcode.CHUNK), len(body) + len(data)) + body + data


def _message_index_records(channel: np.ndarray, log_time: np.ndarray, offset: np.ndarray) -> list[tuple[int, bytes]]:
    """(channel id, MessageIndex record) for each channel among a chunk's messages, in the order of each
    channel's first message: its messages' (log time, offset in the chunk's records)."""
    ids, first = np.unique(channel, return_index=True)
    out = []
    for channel_id in ids[np.argsort(first)].tolist():
        mine = channel == channel_id
        entries = np.empty(int(mine.sum()), _INDEX_ENTRY)
        entries["log_time"], entries["offset"] = log_time[mine], offset[mine]
        data = entries.tobytes()
        out.append((channel_id, struct.pack("<BQHI", int(Opcode.MESSAGE_INDEX), 6 + len(data), channel_id, len(data))
                    + data))
    return out


# rclpy's release series of each ROS 2 distribution (ros2/rclpy: humble 3.3, iron 5.x, jazzy 7.x, kilted 9.x)
_RCLPY_SERIES = {3: "humble", 5: "iron", 7: "jazzy", 9: "kilted"}


@functools.lru_cache(maxsize=1)
def ros_distro() -> str:
    """The ROS 2 distribution this process runs on, for metadata.yaml's ``ros_distro``: ROS_DISTRO when
    set (a sourced ROS install), else the distribution in the name of the installed rclpy wheel
    (`ros-<distro>-rclpy`), else the one of rclpy's version (its release series); 'unknown' when none says."""
    if os.environ.get("ROS_DISTRO"):
        return os.environ["ROS_DISTRO"]
    for distribution in importlib.metadata.distributions():
        name = (distribution.metadata["Name"] or "").lower().replace("_", "-")
        if name.startswith("ros-") and name.endswith("-rclpy") and name.count("-") == 2:
            return name.split("-")[1]
    try:
        return _RCLPY_SERIES.get(int(importlib.metadata.version("rclpy").split(".")[0]), "unknown")
    except (importlib.metadata.PackageNotFoundError, ValueError):
        return "unknown"


class BagWriter:
    """Thread-safe writer of one rosbag2 MCAP bag directory.

    `BagWriter("bags/run1")` creates `bags/run1/metadata.yaml` and `bags/run1/run1_0.mcap`.
    A background thread writes the queued messages every WRITE_PERIOD_S and flushes every
    `flush_period_s` seconds, so a killed process loses at most that much. Use as a context
    manager or call `close()`.

    max_bag_size: B, start a new file once the current one has reached this size; 0: never (BagError
    below MIN_SPLIT_SIZE).
    max_bag_duration_s: s, start a new file once the current one's messages span this long; 0: never.
    """

    def __init__(self, directory: str | os.PathLike[str], name: str | None = None, *,
                 chunk_size: int = 1 << 20, flush_period_s: float = 1.0,
                 compression: CompressionType = CompressionType.ZSTD,
                 max_bag_size: int = 0, max_bag_duration_s: float = 0.0) -> None:
        self.directory = Path(directory)
        self.name = name or self.directory.name
        first = self._file_path(0)
        if (self.directory / "metadata.yaml").exists() or first.exists():
            raise BagError(f"bag directory {self.directory} already holds a bag: "
                           "choose a new directory or remove the old bag")
        if flush_period_s <= 0:
            raise ValueError(f"flush_period_s must be > 0 s, got {flush_period_s}")
        if not max_bag_size >= 0 or not max_bag_duration_s >= 0:
            raise ValueError(f"max_bag_size ({max_bag_size} B) and max_bag_duration_s ({max_bag_duration_s} s) "
                             "must be >= 0 (0: no splitting)")
        if 0 < max_bag_size < MIN_SPLIT_SIZE:
            raise BagError(f"max_bag_size {max_bag_size} B is below the smallest split size, {MIN_SPLIT_SIZE} B "
                           f"(as `ros2 bag record --max-bag-size`): give 0 (one file) or at least {MIN_SPLIT_SIZE} B")
        self._chunk_size, self._compression = chunk_size, compression
        self._max_size = int(max_bag_size)
        self._max_duration_ns = int(max_bag_duration_s * 1e9)
        self._lock = threading.Lock()         # the MCAP writer, the file, the span, the error state
        self._queue_lock = threading.Lock()   # _queued and closing (held for an append or a swap only)
        self._queued: list[tuple[_Topic, bytes, int, int]] = []   # (topic, CDR, log time, publish time)
        self._flush_period_s = flush_period_s
        self._span = _Span()                     # all files
        self._topics: dict[str, _Topic] = {}
        self._attachments: list[_Attachment] = []
        self._finished: list[tuple[str, _Span]] = []   # files written and closed: (name, span)
        self._dirty = False
        self._closed = threading.Event()
        self.error: str | None = None   # set at the first I/O error: what failed, on which path
        self.unwritten = 0              # messages not recorded because of that error
        try:
            self.directory.mkdir(parents=True, exist_ok=True)
            self._current = _StorageFile(first, chunk_size, compression)
            self._write_metadata_yaml()
        except OSError as exc:
            raise BagError(f"cannot record into {exc.filename or self.directory}: {exc.strerror or exc} "
                           "(choose a writable directory, e.g. with the record_dir parameter)") from None
        self._flusher = threading.Thread(target=self._write_loop, name=f"BagWriter {self.name}", daemon=True)
        self._flusher.start()

    def _file_path(self, index: int) -> Path:
        return self.directory / f"{self.name}_{index}.mcap"

    @property
    def paths(self) -> list[Path]:
        """The bag's MCAP files, in order (the last one being written until ``close``)."""
        return [self.directory / name for name, _ in self._finished] + [self._current.path]

    def __enter__(self) -> BagWriter:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def write(self, topic: str, msg: Any, stamp_ns: int, *, type_name: str | None = None,
              qos: QoSProfile | None = None, log_time_ns: int | None = None) -> None:
        """Record one message on `topic`.

        msg: an rclpy message object, or its CDR bytes (then `type_name` is required).
        stamp_ns: header stamp, ns since the epoch (MCAP publish_time).
        log_time_ns: receive time, ns since the epoch (MCAP log_time); default: now, never
        earlier than the last message. Keep explicit values in order too: readers of a bag
        whose writer was killed (no index) need messages in log_time order.
        qos: offered QoS recorded for the topic at its first message (default: rclpy's
        default publisher profile, keep_last 10, reliable, volatile).
        The message is queued and written by the background thread (module docstring); an
        I/O error while writing it shows in ``error`` and ``unwritten``.
        """
        if isinstance(msg, (bytes, bytearray, memoryview)):
            if type_name is None:
                raise ValueError(f"message on {topic!r} is raw bytes: pass type_name='pkg/msg/Type'")
            data = bytes(msg)
        else:
            type_name = type_name or message_type_name(msg)
            data = exact_cdr(type_name, serialize_message(msg))
        # MCAP times are unsigned 64-bit: a stamp that is not (negative, absurd) is stored as 0
        log_time = time.time_ns() if log_time_ns is None or not 0 <= log_time_ns < _U64 else int(log_time_ns)
        publish_time = int(stamp_ns) if 0 <= stamp_ns < _U64 else 0
        entry = self._topics.get(topic)
        if entry is None or entry.type_name != type_name:
            with self._lock:   # a new topic (another type: BagError)
                self._check_open()
                entry = self._topic(topic, type_name, qos) if self.error is None else None
        with self._queue_lock:
            self._check_open()
            if entry is None or self.error is not None:
                self.unwritten += 1
                return
            self._queued.append((entry, data, log_time, publish_time))
            full = len(self._queued) >= MAX_QUEUED
        if full:
            with self._lock:
                self._write_queued()

    def write_rows(self, parts: Sequence[MessageRows], qos: QoSProfile | None = None) -> None:
        """Record a block of messages (``MessageRows``) in the order of their positions, as ``write`` of each
        in that order would record them (the same records, sequence numbers, log times never before the
        last one, topics and channels registered in the order of their first messages; a part's ``qos``, else
        ``qos``, offered for a topic at its first message), written now into chunks of their own instead of
        queued; what ``write`` queued before goes first. The file is split where ``write`` would split it;
        an I/O error shows in ``error`` and ``unwritten`` as for ``write``."""
        n = sum(len(p.position) for p in parts)
        parts = sorted(parts, key=lambda p: int(np.min(p.position)) if len(p.position) else n)
        with self._lock:
            self._check_open()
            entries = ([self._topic(p.topic, p.type_name, p.qos if p.qos is not None else qos) for p in parts]
                       if self.error is None else [])
            self._write_queued()
            written = 0
            if self.error is None and n:
                written = self._write_block(_RowBlock.of(parts, entries, self._span.end or 0))
            if written < n:
                with self._queue_lock:
                    self.unwritten += n - written

    def _write_block(self, block: _RowBlock) -> int:
        """Write ``block`` in chunks (under ``_lock``), the writer's open chunk first; the messages written."""
        lo, split_next = 0, False
        try:
            self._current.writer.flush()
            while lo < len(block):
                if split_next or self._split_due(int(block.log_time[lo])):
                    self._next_file()
                hi, split_next = self._chunk_end(block, lo)
                self._write_chunk(block, lo, hi)
                lo = hi
        except OSError as exc:
            self._fail(exc)
        return lo

    def _chunk_end(self, block: _RowBlock, lo: int) -> tuple[int, bool]:
        """The end of the chunk that starts at message ``lo``: after the message that takes its records
        past ``chunk_size`` (as mcap's writer closes a chunk), or before the message at which the file
        is to be split (then True)."""
        n = len(block)
        before = int(block.record_end[lo - 1]) if lo else 0
        hi = min(int(np.searchsorted(block.record_end, before + self._chunk_size, side="right")) + 1, n)
        cut = hi
        if self._max_size > 0:   # the size before message i: the file and the payloads given since
            payload_before = int(block.payload_end[lo - 1]) if lo else 0
            need = self._max_size - self._current.size() + payload_before
            cut = min(cut, int(np.searchsorted(block.payload_end, need, side="left")) + 1)
        if self._max_duration_ns > 0:
            start = self._current.span.start if self._current.span.start is not None else int(block.log_time[lo])
            cut = min(cut, int(np.searchsorted(block.log_time, start + self._max_duration_ns, side="left")))
        cut = max(cut, lo + 1)
        return (cut, True) if cut < hi else (hi, False)

    def _write_chunk(self, block: _RowBlock, lo: int, hi: int) -> None:
        """Messages ``lo``..``hi - 1`` of ``block`` as one chunk and its message indexes (under ``_lock``):
        the channels they need registered, the chunk counted in the file's summary and the spans."""
        current, writer = self._current, self._current.writer
        topic = block.topic[lo:hi]
        present, first_at, counts = np.unique(topic, return_index=True, return_counts=True)
        channels = np.zeros(len(block.entries), np.int64)
        for t in present[np.argsort(first_at)].tolist():   # registered in the order of their first messages
            channels[t] = current.channel(block.entries[t])
        data, offset = block.records(lo, hi, channels, writer.take_pending_records())
        log = block.log_time[lo:hi]
        first, last = int(log[0]), int(log[-1])
        compressed = writer.compress(data)
        chunk = _chunk_record(first, last, len(data), writer.chunk_crc(data), writer.compression_name(), compressed)
        indexes = _message_index_records(channels[topic], log, offset)
        start = current.file.tell()
        index_offsets, at = {}, start + len(chunk)
        for channel_id, record in indexes:
            index_offsets[channel_id] = at
            at += len(record)
        current.file.write(b"".join([chunk, *(record for _, record in indexes)]))
        writer.add_chunk(ChunkIndex(message_start_time=first, message_end_time=last, chunk_start_offset=start,
                                    chunk_length=len(chunk), message_index_offsets=index_offsets,
                                    message_index_length=at - start - len(chunk), compression=writer.compression_name(),
                                    compressed_size=len(compressed), uncompressed_size=len(data)),
                         {int(channels[t]): int(c) for t, c in zip(present.tolist(), counts.tolist())})
        for t, c in zip(present.tolist(), counts.tolist()):
            block.entries[t].count += c
        self._span.add_many(first, last, hi - lo)
        current.span.add_many(first, last, hi - lo)
        self._dirty = True

    def _write_queued(self) -> None:
        """Write the queued messages into the MCAP writer, in order (under ``_lock``). Receive order
        = log_time order, which readers of a killed (unindexed) bag need: a log time earlier than
        the last one written is moved up to it."""
        with self._queue_lock:
            queued, self._queued = self._queued, []
        for k, (entry, data, log_time, publish_time) in enumerate(queued):
            log_time = max(log_time, self._span.end or 0)
            if self.error is None:
                try:
                    if self._split_due(log_time):
                        self._next_file()
                    current = self._current
                    current.writer.add_message(current.channel(entry), log_time=log_time, data=data,
                                               publish_time=publish_time, sequence=entry.count % (1 << 32))
                    current.pending_bytes += len(data)
                except OSError as exc:
                    self._fail(exc)
            if self.error is not None:
                with self._queue_lock:
                    self.unwritten += len(queued) - k
                return
            entry.count += 1
            self._span.add(log_time)
            self._current.span.add(log_time)
            self._dirty = True

    def _split_due(self, log_time_ns: int) -> bool:
        """True when the file being written is full by size or duration (and holds a message)."""
        span = self._current.span
        if span.start is None:
            return False
        return ((self._max_size > 0 and self._current.size() >= self._max_size)
                or (self._max_duration_ns > 0 and log_time_ns - span.start >= self._max_duration_ns))

    def _next_file(self) -> None:
        """Finish the file being written (under ``_lock``) and start the next one; OSError as writing."""
        self._finish_file()
        self._current.file.close()
        self._finished.append((self._current.path.name, self._current.span))
        self._current = _StorageFile(self._file_path(len(self._finished)), self._chunk_size, self._compression)
        for item in self._attachments:
            self._current.attach(item)
        self._write_metadata_yaml()

    def _finish_file(self) -> None:
        """The current file's ``rosbag2`` metadata record, summary and indexes (the file left open)."""
        self._current.writer.add_metadata("rosbag2", {
            "serialized_metadata": yaml_text(self._bag_information())})
        self._current.writer.finish()

    def record_mechanism(self, mechanism_yaml: str, stamp_ns: int) -> None:
        """Store the mechanism description: a std_msgs/String on MECHANISM_TOPIC
        (transient-local, as the node publishes it) and an MCAP attachment `mechanism.yaml`."""
        from std_msgs.msg import String

        qos = QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL)
        self.write(MECHANISM_TOPIC, String(data=mechanism_yaml), stamp_ns, qos=qos,
                   log_time_ns=stamp_ns)
        self.attach("mechanism.yaml", mechanism_yaml.encode("utf-8"), "application/yaml",
                    stamp_ns)

    def attach(self, name: str, data: bytes, media_type: str, log_time_ns: int | None = None
               ) -> None:
        """Add an MCAP attachment (a file stored in the bag, e.g. the mechanism YAML)."""
        item = _Attachment(name, data, media_type, time.time_ns() if log_time_ns is None else int(log_time_ns))
        with self._lock:
            self._check_open()
            self._attachments.append(item)   # every later file of a split bag carries it too
            self._current.attach(item)

    def flush(self) -> None:
        """Write everything recorded so far to disk in a readable form (chunk + footer +
        metadata.yaml). Called every flush_period_s by the background thread; the fsync runs
        outside the lock, so writers are not held up by a slow card."""
        with self._lock:
            if self._closed.is_set() or self.error is not None:
                return
            self._write_queued()
            if not self._dirty or self.error is not None:
                return
            try:
                self._current.writer.flush()
                self._write_metadata_yaml()
            except OSError as exc:
                self._fail(exc)
                return
            self._dirty = False
            current = self._current.file
        try:
            current.fsync()
        except (OSError, ValueError) as exc:   # ValueError: closed meanwhile
            if isinstance(exc, OSError):
                with self._lock:
                    self._fail(exc)

    def close(self) -> None:
        """Finish the MCAP file (summary, indexes, `rosbag2` metadata record) and write the
        final metadata.yaml. Idempotent."""
        with self._lock:
            with self._queue_lock:
                if self._closed.is_set():
                    return
                self._closed.set()   # write() refuses from here on
            self._write_queued()
            if self.error is None:
                try:
                    self._finish_file()
                except OSError as exc:
                    self._fail(exc)
            try:   # after an error the file keeps its last valid tail (readable without a summary)
                self._current.file.close(keep_tail=self.error is not None)
                self._write_metadata_yaml()
            except OSError as exc:
                self.error = self.error or f"{self.directory}: {exc.strerror or exc}"
        self._flusher.join()

    @property
    def outcome(self) -> str:
        """What became of the recording, one line for the console at its end: 'bag written: DIR (N
        messages)', or, after a fault (``error``), that the recording failed, why, how many messages
        were not recorded and where the partial bag is (readable up to its last complete chunk)."""
        written = sum(t.count for t in self._topics.values())
        if self.error is None:
            return f"bag written: {self.directory} ({written} message(s))"
        return (f"recording failed: {self.error}; {self.unwritten} message(s) not recorded; the partial bag "
                f"({written} message(s), readable up to its last complete chunk) is {self.directory}")

    def _fail(self, exc: OSError) -> None:
        """Enter the error state (under the lock): no more writing, the file stays readable."""
        if self.error is None:
            self.error = (f"{exc.filename or self._current.path}: {exc.strerror or exc} — the bag holds what was "
                          "written before; free space or fix the disk, then restart the recording")

    def _check_open(self) -> None:
        if self._closed.is_set():
            raise BagError(f"bag {self.directory} is closed: open a new BagWriter")

    def _topic(self, topic: str, type_name: str, qos: QoSProfile | None) -> _Topic:
        """The topic's entry, made at its first message (under ``_lock``; its channel is registered in
        each file as the file's first message on it is written); BagError for a second type on a topic."""
        entry = self._topics.get(topic)
        if entry is not None:   # (write() looked without the lock: another thread may have registered it)
            if entry.type_name != type_name:
                raise BagError(f"topic {topic!r} in bag {self.directory} holds {entry.type_name},"
                               f" cannot also record {type_name}: use another topic")
            return entry
        entry = _Topic(topic, type_name, qos_to_dict(qos if qos is not None else QoSProfile(depth=10)))
        self._topics[topic] = entry
        return entry

    def _bag_information(self) -> dict[str, Any]:
        """rosbag2 `rosbag2_bagfile_information` (metadata version 9) of what is written."""
        files = [*self._finished, (self._current.path.name, self._current.span)]
        return {
            "version": ROSBAG2_VERSION,
            "storage_identifier": "mcap",
            **self._span.information(),
            "topics_with_message_count": [
                {"topic_metadata": {"name": t.name, "type": t.type_name,
                                    "serialization_format": "cdr",
                                    "offered_qos_profiles": [t.qos]},
                 "message_count": t.count}
                for t in self._topics.values()],
            "compression_format": "",
            "compression_mode": "",
            "relative_file_paths": [name for name, _ in files],
            "files": [{"path": name, **span.information()} for name, span in files],
            "custom_data": None,
            "ros_distro": ros_distro(),
        }

    def _write_metadata_yaml(self) -> None:
        text = yaml_text({"rosbag2_bagfile_information": self._bag_information()})
        tmp = self.directory / "metadata.yaml.tmp"
        tmp.write_text(text, encoding="utf-8")
        os.replace(tmp, self.directory / "metadata.yaml")

    def _write_loop(self) -> None:
        """The background thread: write the queue every WRITE_PERIOD_S, flush every flush_period_s."""
        next_flush = time.monotonic() + self._flush_period_s
        while not self._closed.wait(min(WRITE_PERIOD_S, self._flush_period_s)):
            if time.monotonic() >= next_flush:
                next_flush = time.monotonic() + self._flush_period_s
                self.flush()
                continue
            with self._lock:
                if not self._closed.is_set():
                    self._write_queued()

