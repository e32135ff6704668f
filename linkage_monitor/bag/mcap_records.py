"""MCAP records by hand: the magic, record heads, chunk and message index records built from arrays and
read back, and mcap's writer opened to chunks built outside it.

The one module that touches mcap's private names (``MCAP_PRIVATE_NAMES``: the Writer's
``_Writer__chunk_builder``, ``_Writer__chunk_indices``, ``_Writer__statistics``, ... and
``mcap._message_queue``); ``mcap_internals_missing`` lists those the installed mcap lacks, and every use
of one that is gone fails with ``mcap_changed``'s sentence naming the mcap version and the name
(test/test_mcap_internals.py). Layouts from the MCAP specification (mcap.dev/spec).
"""

from __future__ import annotations

import functools
import importlib.metadata
import io
import struct
import zlib
from collections.abc import Collection
from typing import Any, NamedTuple

import numpy as np
from mcap import writer as mcap_writer
from mcap.opcode import Opcode
from mcap.records import Chunk, ChunkIndex, Message
from mcap.stream_reader import breakup_chunk, get_chunk_data_stream
from mcap.writer import CompressionType, Writer

MCAP_MAGIC = b"\x89MCAP0\r\n"
# DataEnd (op 0x0F, crc 0 = not computed) + Footer (op 0x02, summary_start 0 = no summary,
# summary_offset_start 0, summary_crc 0) + magic: the smallest valid MCAP ending.
TAIL = (struct.pack("<BQI", 0x0F, 4, 0) + struct.pack("<BQQQI", 0x02, 20, 0, 0, 0) + MCAP_MAGIC)
RECORD_HEAD = struct.Struct("<BQ")          # a record's opcode and the length of its body
MESSAGE_HEAD = struct.Struct("<HIQQ")       # a Message record's channel id, sequence, log and publish time
MESSAGE_RECORD_HEAD = np.dtype([("opcode", "u1"), ("length", "<u8"), ("channel", "<u2"), ("sequence", "<u4"),
                                ("log_time", "<u8"), ("publish_time", "<u8")])   # a Message record before its data
INDEX_HEAD = struct.Struct("<BQHI")         # a MessageIndex record's opcode, length, channel id, entries' size
INDEX_ENTRY = np.dtype([("log_time", "<u8"), ("offset", "<u8")])   # a MessageIndex record's entry
# zstd level of the chunks ``BagWriter.write_rows`` builds (mcap's own chunks: its level 3): the bundled bag's
# chunks compressed in 37 % less time at level 1 than at level 3, to 0.1 % more bytes
ROW_CHUNK_ZSTD_LEVEL = 1

_WRITER_PRIVATE = ("chunk_builder", "chunk_indices", "statistics", "compression", "enable_crcs", "enable_data_crcs")
_CHUNK_BUILDER_PRIVATE = ("num_messages", "record_writer")
MCAP_PRIVATE_NAMES = (*(f"Writer.__{name}" for name in _WRITER_PRIVATE),
                      *(f"ChunkBuilder.{name}" for name in _CHUNK_BUILDER_PRIVATE),
                      "mcap.writer.zstandard", "mcap.writer.lz4", "mcap._message_queue.make_message_queue")
"""mcap's private names this module uses (mcap 1.x)."""


def mcap_changed(name: str) -> str:
    """The sentence for a private name of mcap this module uses that the installed mcap lacks."""
    return (f"mcap {importlib.metadata.version('mcap')} has no {name}, a private name of mcap 1.x that "
            "linkage_monitor/bag/mcap_records.py uses: install the mcap version it was written for (1.x) "
            "or bring mcap_records.py up to this one")


try:
    from mcap._message_queue import make_message_queue
except ImportError as _exc:   # the sentence that says so, not a bare ImportError at the first bag read
    raise ImportError(mcap_changed("mcap._message_queue.make_message_queue")) from _exc


def mcap_internals_missing() -> list[str]:
    """Those of ``MCAP_PRIVATE_NAMES`` the installed mcap lacks (on a Writer made for the purpose)."""
    writer = Writer(io.BytesIO())
    missing = [f"Writer.__{name}" for name in _WRITER_PRIVATE if not hasattr(writer, f"_Writer__{name}")]
    builder = getattr(writer, "_Writer__chunk_builder", None)
    missing += [f"ChunkBuilder.{name}" for name in _CHUNK_BUILDER_PRIVATE
                if builder is not None and not hasattr(builder, name)]
    missing += [f"mcap.writer.{name}" for name in ("zstandard", "lz4") if not hasattr(mcap_writer, name)]
    try:
        queue = importlib.import_module("mcap._message_queue")
    except ImportError:
        queue = None
    if not hasattr(queue, "make_message_queue"):
        missing.append("mcap._message_queue.make_message_queue")
    return missing


def log_time_queue() -> Any:
    """mcap's queue of chunk indexes and messages, popped in log-time order (as SeekingReader.iter_messages
    orders them)."""
    return make_message_queue(log_time_order=True)


class McapWriter(Writer):
    """mcap's Writer, which also takes chunks built outside it (``BagWriter.write_rows``):
    ``take_pending_records`` hands over the schema and channel records registered since its last chunk,
    ``add_chunk`` counts a chunk written to its stream in its chunk indexes and statistics, as its own
    chunks are. test_can_blocks.py holds a bag written by chunks equal to one written message by
    message, as mcap and rosbags read it."""

    def _private(self, name: str) -> Any:
        """The Writer's private attribute ``name`` (``__name`` inside mcap's Writer)."""
        try:
            return getattr(self, f"_Writer__{name}")
        except AttributeError:
            raise AttributeError(mcap_changed(f"Writer.__{name}")) from None

    def compression_name(self) -> str:
        """The chunk compression as MCAP names it: "zstd", "lz4" or ""."""
        return {CompressionType.ZSTD: "zstd", CompressionType.LZ4: "lz4"}.get(self._private("compression"), "")

    def compress(self, data: bytes | memoryview) -> bytes:
        """``data`` compressed by this writer's chunk compression; zstd at ROW_CHUNK_ZSTD_LEVEL."""
        kind = self._private("compression")
        if kind == CompressionType.ZSTD:
            return bytes(self._zstd.compress(data))
        if kind == CompressionType.LZ4:
            return bytes(mcap_writer.lz4.frame.compress(data))
        return bytes(data)

    @functools.cached_property
    def _zstd(self) -> Any:
        """This writer's zstd compressor for ``compress`` (one per writer: a compressor is not thread-safe)."""
        return mcap_writer.zstandard.ZstdCompressor(level=ROW_CHUNK_ZSTD_LEVEL)

    def chunk_crc(self, data: bytes | memoryview) -> int:
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


def chunk_record(start: int, end: int, uncompressed_size: int, crc: int, compression: str, data: bytes) -> bytes:
    """An MCAP Chunk record (opcode, length, then its fields) of messages logged from ``start`` to ``end``
    (ns) holding ``data`` (compressed by ``compression`` from ``uncompressed_size`` bytes of CRC ``crc``)."""
    name = compression.encode()
    body = struct.pack("<QQQI", start, end, uncompressed_size, crc)
    body += struct.pack("<I", len(name)) + name + struct.pack("<Q", len(data))
    return RECORD_HEAD.pack(int(Opcode.CHUNK), len(body) + len(data)) + body + data


def message_index_records(channel: np.ndarray, log_time: np.ndarray, offset: np.ndarray) -> list[tuple[int, bytes]]:
    """(channel id, MessageIndex record) for each channel among a chunk's messages, in the order of each
    channel's first message: its messages' (log time, offset in the chunk's records)."""
    ids, first = np.unique(channel, return_index=True)
    out = []
    for channel_id in ids[np.argsort(first)].tolist():
        mine = channel == channel_id
        entries = np.empty(int(mine.sum()), INDEX_ENTRY)
        entries["log_time"], entries["offset"] = log_time[mine], offset[mine]
        data = entries.tobytes()
        out.append((channel_id, INDEX_HEAD.pack(int(Opcode.MESSAGE_INDEX), 6 + len(data), channel_id, len(data))
                    + data))
    return out


def indexed_offsets(stream: Any, chunk_index: ChunkIndex, channel_ids: Collection[int]) -> np.ndarray | None:
    """Where the chunk's messages on ``channel_ids`` start in its records (byte offsets, in order), from
    the MessageIndex records after it (``message_index_offsets``); None when the chunk has none or one
    does not read as one (then the chunk's records are walked)."""
    indexes = chunk_index.message_index_offsets
    if not indexes:
        return None
    found = [np.zeros(0, np.uint64)]
    for at in sorted(offset for channel, offset in indexes.items() if channel in channel_ids):
        stream.seek(at)
        head = stream.read(INDEX_HEAD.size)
        if len(head) < INDEX_HEAD.size:
            return None
        opcode, _, _, size = INDEX_HEAD.unpack(head)
        body = stream.read(size)
        if opcode != Opcode.MESSAGE_INDEX or size % INDEX_ENTRY.itemsize or len(body) != size:
            return None
        found.append(np.frombuffer(body, INDEX_ENTRY)["offset"])
    offsets = np.sort(np.concatenate(found))
    return offsets if np.all(offsets[1:] > offsets[:-1]) else None   # an offset twice is no index


class ChunkColumns(NamedTuple):
    """Message records of a chunk (``chunk_columns``) as columns, in their order in the chunk: channel ids,
    sequence numbers, log and publish times (ns) and data."""

    channel_id: np.ndarray     # (n,) uint16
    sequence: np.ndarray       # (n,) uint32
    log_time: np.ndarray       # (n,) uint64
    publish_time: np.ndarray   # (n,) uint64
    data: list[bytes]

    def messages(self) -> list[Message]:
        """The records as mcap's Message records."""
        return [Message(channel_id=channel_id, log_time=log_time, publish_time=publish_time, sequence=sequence,
                        data=data)
                for channel_id, sequence, log_time, publish_time, data in zip(
                    self.channel_id.tolist(), self.sequence.tolist(), self.log_time.tolist(),
                    self.publish_time.tolist(), self.data)]


def chunk_messages(chunk: Chunk, channel_ids: Collection[int], offsets: np.ndarray | None) -> list[Message]:
    """``chunk_columns`` as mcap's Message records."""
    return chunk_columns(chunk, channel_ids, offsets).messages()


def chunk_columns(chunk: Chunk, channel_ids: Collection[int], offsets: np.ndarray | None) -> ChunkColumns:
    """The Message records of ``chunk`` on ``channel_ids``, in their order in the chunk. The chunk is
    decompressed and its CRC checked by mcap (``get_chunk_data_stream``, as ``breakup_chunk`` does);
    then only the wanted messages are read (most of a node's recording are outputs a replay does not
    read): those at ``offsets`` (``indexed_offsets``; their heads read at once), or, without them or
    where they do not point at such a message, those the records split by their heads hold. Raises
    ValueError for a record that runs past the chunk's end."""
    data_stream, size = get_chunk_data_stream(chunk, validate_crc=True)
    data = data_stream.read(size)
    if offsets is not None:
        indexed = _columns_at(data, offsets, channel_ids)
        if indexed is not None:
            return indexed
    heads: list[tuple[int, int, int, int]] = []
    datas = []
    position = 0
    while position < size:
        if size - position < RECORD_HEAD.size:
            raise ValueError(f"a record head at byte {position} of the chunk is cut off")
        opcode, length = RECORD_HEAD.unpack_from(data, position)
        body = position + RECORD_HEAD.size
        position = body + length
        if position > size:
            raise ValueError(f"a record at byte {body - RECORD_HEAD.size} runs past the chunk's end")
        if opcode == Opcode.MESSAGE:
            if length < MESSAGE_HEAD.size:
                raise ValueError(f"a message record at byte {body - RECORD_HEAD.size} is shorter than its head")
            head = MESSAGE_HEAD.unpack_from(data, body)   # channel id, sequence, log time, publish time
            if head[0] in channel_ids:
                heads.append(head)
                datas.append(data[body + MESSAGE_HEAD.size:position])
    columns = np.array(heads, np.uint64).reshape(-1, 4)
    return ChunkColumns(columns[:, 0].astype(np.uint16), columns[:, 1].astype(np.uint32), columns[:, 2],
                        columns[:, 3], datas)


def _columns_at(data: bytes, offsets: np.ndarray, channel_ids: Collection[int]) -> ChunkColumns | None:
    """The Message records at ``offsets`` (increasing) of the chunk's records ``data``, their heads read at
    once; None if one is not a whole Message record on ``channel_ids`` there."""
    size, head_size = len(data), MESSAGE_RECORD_HEAD.itemsize
    if len(offsets) and int(offsets[-1]) + head_size > size:
        return None
    at = offsets.astype(np.int64)
    heads = np.frombuffer(data, np.uint8)[at[:, None] + np.arange(head_size)].view(MESSAGE_RECORD_HEAD)[:, 0]
    length = heads["length"]
    if not (np.all(heads["opcode"] == Opcode.MESSAGE) and np.all(length >= MESSAGE_HEAD.size)
            and np.all(length <= size)):
        return None
    end = at + RECORD_HEAD.size + length.astype(np.int64)
    if (len(end) and int(end.max()) > size) or not np.all(np.isin(heads["channel"], list(channel_ids))):
        return None
    return ChunkColumns(heads["channel"], heads["sequence"], heads["log_time"], heads["publish_time"],
                        [data[start:stop] for start, stop in zip((at + head_size).tolist(), end.tolist())])


def split_chunk(chunk: Chunk) -> list[Any]:
    """Every record of ``chunk`` (mcap's ``breakup_chunk``, its CRC checked); raises what mcap raises for a
    chunk that does not read (``CRCValidationError`` for a CRC mismatch)."""
    return breakup_chunk(chunk, validate_crc=True)


def message_count(chunk: Any) -> str:
    """How many message records a damaged chunk's bytes hold, if they can be split at all."""
    if chunk is None:
        return "an unknown number of"
    try:
        return str(sum(1 for record in breakup_chunk(chunk, validate_crc=False) if isinstance(record, Message)))
    except Exception:  # noqa: BLE001 - the bytes do not even split into records
        return "an unknown number of"
