"""Many messages at once (``BagWriter.write_rows``): a block of messages as arrays (``MessageRows``: one
topic's CDR payloads as the rows of a uint8 array, or of any sizes one after another with their sizes,
with their places in the block, publish and receive times) written straight into MCAP chunks built with
numpy (``RowBlock``), with the records, message indexes, chunk indexes and statistics `BagWriter.write`
one by one would give them."""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import NamedTuple, Sequence

import numpy as np
from mcap.opcode import Opcode
from mcap.records import ChunkIndex
from numpy.lib.stride_tricks import as_strided
from rclpy.qos import QoSProfile

from linkage_monitor.bag.mcap_records import MESSAGE_RECORD_HEAD, chunk_record, message_index_records
from linkage_monitor.bag.metadata import Topic
from linkage_monitor.bag.split_files import BagFiles, StorageFile


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


@dataclass(frozen=True)
class RowBlock:
    """A block of messages in writing order, as columns (one entry per message): ``part`` and ``start``
    where its bytes are (``data[part][start:start + size]``, ``data`` each part's messages one after
    another), ``topic`` its topic's index in ``entries``, ``size`` its payload bytes, ``log_time`` /
    ``publish_time`` as MCAP stores them (log times never before the previous one), ``sequence`` per
    topic; ``record_end`` / ``payload_end``: cumulative record and payload bytes up to and including it."""

    data: list[np.ndarray]
    entries: list[Topic]
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
    def of(parts: Sequence[MessageRows], entries: list[Topic], last_log_time: int) -> RowBlock:
        """The block of ``parts`` (their topics' ``entries``); log times are moved up to the one before, as
        the writer does for the messages ``BagWriter.write`` queued, the first to at least ``last_log_time``;
        times MCAP cannot store as ``write`` stores them (a log time: now; a publish time: 0)."""
        n = sum(len(p.position) for p in parts)
        part, start = np.empty(n, np.int64), np.empty(n, np.int64)
        topic, size = np.empty(n, np.int64), np.empty(n, np.int64)
        log_time, publish_time = np.empty(n, np.int64), np.empty(n, np.int64)
        unique: list[Topic] = []
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
        return RowBlock(data, unique, part, start, topic, size, log_time, publish_time, sequence,
                         np.cumsum(size + MESSAGE_RECORD_HEAD.itemsize), np.cumsum(size))

    def __len__(self) -> int:
        return len(self.part)

    def records(self, lo: int, hi: int, channels: np.ndarray, lead: bytes) -> tuple[memoryview, np.ndarray]:
        """The uncompressed records of a chunk of messages ``lo``..``hi - 1``: ``lead`` (schema and channel
        records) then each message's Message record (its topic's channel id in ``channels``), and each
        message's record offset in them. The records' heads, then each part's payloads of one size, are
        copied as rows into a view of the chunk whose row k starts at byte k (``_starting_at``), from such a
        view of the part's bytes: a row copy per message, no index per byte. The records are a view of the
        array they were copied into (compressed and checked from there: no copy of the chunk's bytes)."""
        head_size = MESSAGE_RECORD_HEAD.itemsize
        size = self.size[lo:hi]
        head = np.empty(hi - lo, MESSAGE_RECORD_HEAD)
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
        return out.data, offset


def _starting_at(data: np.ndarray, width: int) -> np.ndarray:
    """A view of the 1-D ``data`` whose row k is the ``width`` bytes starting at byte k."""
    return as_strided(data, shape=(len(data) - width + 1, width), strides=(1, 1))


def _storable(times: np.ndarray, instead: int) -> np.ndarray:
    """``times`` (ns) with those MCAP cannot store (outside 0..2^64-1; int64 here: negative) replaced."""
    times = np.asarray(times, np.int64)
    return np.where(times >= 0, times, instead)


def chunk_end(block: RowBlock, lo: int, files: BagFiles) -> tuple[int, bool]:
    """The end of the chunk that starts at message ``lo``: after the message that takes its records
    past the files' ``chunk_size`` (as mcap's writer closes a chunk), or before the message at which the
    file being written is to be split (then True)."""
    n = len(block)
    before = int(block.record_end[lo - 1]) if lo else 0
    hi = min(int(np.searchsorted(block.record_end, before + files.chunk_size, side="right")) + 1, n)
    cut = hi
    if files.max_size > 0:   # the size before message i: the file and the payloads given since
        payload_before = int(block.payload_end[lo - 1]) if lo else 0
        need = files.max_size - files.current.size() + payload_before
        cut = min(cut, int(np.searchsorted(block.payload_end, need, side="left")) + 1)
    if files.max_duration_ns > 0:
        start = files.current.span.start if files.current.span.start is not None else int(block.log_time[lo])
        cut = min(cut, int(np.searchsorted(block.log_time, start + files.max_duration_ns, side="left")))
    cut = max(cut, lo + 1)
    return (cut, True) if cut < hi else (hi, False)


class ChunkRecords(NamedTuple):
    """Messages ``lo``..``hi - 1`` of a block as the uncompressed records of one chunk (``chunk_records``):
    ``data`` the records, ``offset`` each message's record offset in them, ``channels`` each topic's
    channel id (by the block's topic index), ``present`` / ``counts`` the topics in the chunk and their
    messages."""

    lo: int
    hi: int
    data: memoryview
    offset: np.ndarray
    channels: np.ndarray
    present: np.ndarray
    counts: np.ndarray


def chunk_records(block: RowBlock, lo: int, hi: int, current: StorageFile) -> ChunkRecords:
    """The records of messages ``lo``..``hi - 1`` of ``block`` as one chunk of ``current``: the channels
    they need registered (in the order of their first messages), the schema and channel records waiting
    in the writer at the front."""
    writer = current.writer
    present, first_at, counts = np.unique(block.topic[lo:hi], return_index=True, return_counts=True)
    channels = np.zeros(len(block.entries), np.int64)
    for t in present[np.argsort(first_at)].tolist():   # registered in the order of their first messages
        channels[t] = current.channel(block.entries[t])
    data, offset = block.records(lo, hi, channels, writer.take_pending_records())
    return ChunkRecords(lo, hi, data, offset, channels, present, counts)


def compressed(current: StorageFile, data: memoryview) -> tuple[bytes, int]:
    """``data`` compressed as ``current``'s chunks are, and its uncompressed CRC (both release the GIL:
    ``BagWriter`` runs this beside the next chunk's records)."""
    writer = current.writer
    return writer.compress(data), writer.chunk_crc(data)


def write_chunk(block: RowBlock, chunk: ChunkRecords, packed: tuple[bytes, int], current: StorageFile) -> None:
    """``chunk`` (its data compressed, and its CRC: ``packed``) and its message indexes written to ``current``:
    the chunk counted in the file's summary, the topics' counts and the file's span."""
    writer = current.writer
    lo, hi, data, offset, channels = chunk.lo, chunk.hi, chunk.data, chunk.offset, chunk.channels
    log = block.log_time[lo:hi]
    first, last = int(log[0]), int(log[-1])
    compressed_data, crc = packed
    record = chunk_record(first, last, len(data), crc, writer.compression_name(), compressed_data)
    indexes = message_index_records(channels[block.topic[lo:hi]], log, offset)
    start = current.file.tell()
    index_offsets, at = {}, start + len(record)
    for channel_id, index in indexes:
        index_offsets[channel_id] = at
        at += len(index)
    current.file.write(b"".join([record, *(index for _, index in indexes)]))
    present, counts = chunk.present.tolist(), chunk.counts.tolist()
    writer.add_chunk(ChunkIndex(message_start_time=first, message_end_time=last, chunk_start_offset=start,
                                chunk_length=len(record), message_index_offsets=index_offsets,
                                message_index_length=at - start - len(record), compression=writer.compression_name(),
                                compressed_size=len(compressed_data), uncompressed_size=len(data)),
                     {int(channels[t]): int(c) for t, c in zip(present, counts)})
    for t, c in zip(present, counts):
        block.entries[t].count += c
    current.span.add_many(first, last, hi - lo)
