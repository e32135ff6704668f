"""Reading one MCAP file: by its summary's chunk indexes when it has one, else by a scan of its records
in file order that keeps every whole record before a cut; what cannot be read is a ``ReadFault``."""

from __future__ import annotations

import io
import os
import struct
from collections.abc import Collection, Iterable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np

from mcap.data_stream import ReadDataStream
from mcap.exceptions import McapError
from mcap.opcode import Opcode
from mcap.reader import SeekingReader
from mcap.records import Channel, Chunk, ChunkIndex, Message, Schema
from mcap.stream_reader import CRCValidationError

from linkage_monitor.bag.errors import BagError
from linkage_monitor.bag.faults import ReadFault, report
from linkage_monitor.bag.mcap_records import (
    MCAP_MAGIC, RECORD_HEAD, ChunkColumns, chunk_columns, indexed_offsets, log_time_queue, message_count,
    split_chunk)


class _Record(NamedTuple):
    """A message of an MCAP file with its schema (None: the channel has none) and channel records."""

    schema: Any
    channel: Any
    message: Message


def mcap_first_log_time(file: Path) -> int | None:
    """The log time (ns since the epoch) of the file's first message; None when it holds none or that
    cannot be read."""
    with open(file, "rb") as stream:
        try:
            summary = SeekingReader(stream).get_summary()
        except (McapError, OSError, struct.error, ValueError):
            summary = None
        if summary is not None and summary.chunk_indexes:
            return min(index.message_start_time for index in summary.chunk_indexes)
        try:
            return next((r.message.log_time for r in _scanned_messages(file, stream, None)), None)
        except BagError:
            return None


def mcap_messages(file: Path, topics: Collection[str] | None) -> Iterator[tuple[Any, Any, Any]]:
    """(schema, channel, message) records of one MCAP file: indexed when it has a summary, else by a
    scan of its records in file order (``_scanned_messages``) that keeps every whole record before a cut."""
    topic_list = list(topics) if topics is not None else None
    with open(file, "rb") as stream:
        try:
            summary = SeekingReader(stream).get_summary()
        except (McapError, OSError, struct.error, ValueError):   # no footer or summary (killed writer, cut copy)
            summary = None
        if summary is None:
            yield from _scanned_messages(file, stream, topic_list)
            return
        count = 0
        try:
            for record in _indexed_messages(file, stream, summary, topic_list):
                count += 1
                yield record
        except Exception as exc:  # noqa: BLE001 - damaged data: decompression, lengths
            raise _damaged(file, count, exc) from exc


def _record_stream(body: bytes) -> ReadDataStream:
    return ReadDataStream(io.BytesIO(body))


@dataclass
class _Scan:
    """What a scan of an MCAP file has read so far: its schema and channel records by id, the messages
    read (on any topic) and those whose channel was not defined before them."""

    schemas: dict[int, Schema]
    channels: dict[int, Channel]
    messages: int = 0
    orphans: int = 0
    data_end: bool = False


def _scanned_messages(file: Path, stream: Any, topics: list[str] | None) -> Iterator[_Record]:
    """The records of an MCAP file without summary (a killed writer, a cut copy, a dying card), in file
    order, each chunk's messages by log time (ties in chunk order): the writer writes chunks in log-time
    order. A record is read only when the file holds all of it (its length from its head); the first
    that runs past the end stops the scan with a ``ReadFault`` naming its byte and the messages read
    before it. A chunk that fails its CRC or does not read is skipped and named; the scan goes on."""
    size = os.fstat(stream.fileno()).st_size
    stream.seek(len(MCAP_MAGIC))
    position = len(MCAP_MAGIC)
    scan = _Scan({}, {})
    while True:
        head = stream.read(RECORD_HEAD.size)
        opcode, length = RECORD_HEAD.unpack(head) if len(head) == RECORD_HEAD.size else (None, 0)
        if opcode is None or position + RECORD_HEAD.size + length > size:
            _report_end(file, position, size, scan)
            return
        body = stream.read(length)
        if opcode == Opcode.FOOTER:
            break
        if opcode == Opcode.CHUNK:
            yield from _scanned_chunk(file, position, body, scan, topics)
        elif opcode == Opcode.DATA_END:
            scan.data_end = True
        else:
            yield from _scanned_records(file, [_top_level(file, position, opcode, length, body)], scan, topics)
        position += RECORD_HEAD.size + length
    if scan.orphans:
        report(ReadFault(str(file), "no_channel", None, scan.orphans,
                         f"{file}: {scan.orphans} message(s) name a channel the file does not define before "
                         "them: left out"))


def _top_level(file: Path, position: int, opcode: int, length: int, body: bytes) -> Any:
    """The Schema, Channel or Message record ``body`` at byte ``position`` (None for any other record:
    not read); BagError naming the byte when it is whole but does not read as its kind."""
    try:
        if opcode == Opcode.SCHEMA:
            return Schema.read(_record_stream(body))
        if opcode == Opcode.CHANNEL:
            return Channel.read(_record_stream(body))
        if opcode == Opcode.MESSAGE:
            return Message.read(_record_stream(body), length)
    except (McapError, struct.error, UnicodeDecodeError, ValueError) as exc:
        raise BagError(f"{file}: the record at byte {position} is damaged ({type(exc).__name__}): "
                       "copy what can be read with an MCAP tool or record again") from exc
    return None


def _scanned_chunk(file: Path, position: int, body: bytes, scan: _Scan, topics: list[str] | None
                   ) -> Iterator[_Record]:
    """The wanted messages of the chunk record at byte ``position`` (its records after mcap's
    ``breakup_chunk``, CRC checked), by log time; none, with a ``ReadFault``, when it does not read."""
    chunk = None
    try:
        chunk = Chunk.read(_record_stream(body))
        records = split_chunk(chunk)
    except Exception as exc:  # noqa: BLE001 - a CRC mismatch, data that does not decompress, a broken record
        _report_chunk(file, position, chunk, exc)
        return
    messages = sorted((r for r in records if isinstance(r, Message)), key=lambda m: m.log_time)
    yield from _scanned_records(file, [r for r in records if not isinstance(r, Message)] + messages, scan, topics)


def _scanned_records(file: Path, records: list[Any], scan: _Scan, topics: list[str] | None) -> Iterator[_Record]:
    """Schema and channel records kept in ``scan``; messages on ``topics`` yielded with theirs."""
    for record in records:
        if isinstance(record, Schema):
            scan.schemas[record.id] = record
        elif isinstance(record, Channel):
            scan.channels[record.id] = record
        elif isinstance(record, Message):
            scan.messages += 1
            channel = scan.channels.get(record.channel_id)
            if channel is None:
                scan.orphans += 1
            elif topics is None or channel.topic in topics:
                yield _Record(scan.schemas.get(channel.schema_id), channel, record)


def _report_end(file: Path, position: int, size: int, scan: _Scan) -> None:
    """The ``ReadFault`` of an MCAP file that ends at byte ``position`` without its footer."""
    if position == size:
        text = (f"{file} ends at byte {size} without its summary (the writer stopped): "
                f"{scan.messages} messages read, all it holds")
    else:
        text = (f"{file} is cut off at byte {position} of {size} (an incomplete record: an interrupted copy "
                f"or a failing medium): {scan.messages} messages read before it"
                + (", none lost (only the summary after the data is cut)" if scan.data_end else
                   ", what followed is lost"))
    report(ReadFault(str(file), "cut_off", position, scan.messages, text))


def _report_chunk(file: Path, offset: int, chunk: Any, exc: Exception,
                  index: ChunkIndex | None = None) -> None:
    """The ``ReadFault`` of a chunk at byte ``offset`` that fails its CRC or does not read: skipped."""
    what = ("fails its CRC" if isinstance(exc, CRCValidationError) else
            f"is unreadable ({type(exc).__name__}: {str(exc).splitlines()[0] if str(exc) else 'damaged'})")
    count = message_count(chunk)
    times = (f", log times {index.message_start_time} to {index.message_end_time} ns" if index is not None else
             f", log times {chunk.message_start_time} to {chunk.message_end_time} ns" if chunk is not None else "")
    report(ReadFault(str(file), "chunk_skipped", offset, int(count) if count.isdigit() else None,
                     f"{file}: the chunk at byte {offset} ({count} messages{times}) {what}: skipped, not decoded"))


def _indexed_messages(file: Path, stream: Any, summary: Any, topics: list[str] | None
                      ) -> Iterator[tuple[Any, Any, Any]]:
    """The (schema, channel, message) records of an indexed MCAP file in log-time order, as mcap's
    SeekingReader.iter_messages yields them: sorted by (log time, byte offset of the chunk, position
    in the chunk), as the chunk indexes' time ranges place them. Chunks are read one at a time, every
    chunk's CRC checked: a chunk that fails it is skipped and named in one warning with the messages
    it held, never decoded.

    When no chunk's time range overlaps the next one's (``_in_sequence``), that order is chunk after
    chunk, each chunk's messages sorted by log time (ties in their order in the chunk); otherwise
    mcap's queue merges the chunks (a heap of chunks by first log time and of the messages read)."""
    chunks = sorted(summary.chunk_indexes, key=_chunk_start)
    channel_ids = {i for i, c in summary.channels.items() if topics is None or c.topic in topics}
    if _in_sequence(chunks):
        for chunk_index in chunks:
            records = _chunk_records(file, stream, chunk_index, summary, channel_ids)
            records.sort(key=_log_time)   # stable; a chunk's messages are usually in log-time order already
            yield from records
        return
    queue = log_time_queue()
    for chunk_index in chunks:
        queue.push(chunk_index)
    while queue:
        item = queue.pop()
        if isinstance(item, ChunkIndex):
            for position, record in enumerate(_chunk_records(file, stream, item, summary, channel_ids)):
                queue.push((record, item.chunk_start_offset, position))
        else:
            yield item[0]


def _chunk_start(chunk_index: ChunkIndex) -> tuple[int, int]:
    """Where a chunk's messages begin in log time (ns), then the chunk's byte offset in its file."""
    return chunk_index.message_start_time, chunk_index.chunk_start_offset


def _in_sequence(chunks: list[ChunkIndex]) -> bool:
    """Whether every chunk of ``chunks`` (sorted by ``_chunk_start``) holds only messages that sort before
    the next chunk's: its last log time before the next one's first, or at the same ns with the next
    chunk further in the file."""
    return all((before.message_end_time, before.chunk_start_offset) < _chunk_start(after)
               for before, after in zip(chunks, chunks[1:]))


def _log_time(record: _Record) -> int:
    return record.message.log_time


def _chunk_records(file: Path, stream: Any, chunk_index: ChunkIndex, summary: Any, channel_ids: set[int]
                   ) -> list[_Record]:
    """The messages of one chunk on the channels ``channel_ids``, in their order in the chunk (``_chunk_columns``)."""
    columns = _chunk_columns(file, stream, chunk_index, channel_ids)
    if columns is None:
        return []
    schemas, channels = summary.schemas, summary.channels
    return [_Record(schemas[channels[m.channel_id].schema_id] if channels[m.channel_id].schema_id else None,
                    channels[m.channel_id], m) for m in columns.messages()]


def _chunk_columns(file: Path, stream: Any, chunk_index: ChunkIndex, channel_ids: set[int]) -> ChunkColumns | None:
    """The messages of one chunk on the channels ``channel_ids`` as columns, in their order in the chunk; None,
    with a warning naming the chunk, when it fails its CRC or does not read."""
    stream.seek(chunk_index.chunk_start_offset + 1 + 8)   # past the record's opcode and length
    chunk = None
    try:
        chunk = Chunk.read(ReadDataStream(stream))
        return chunk_columns(chunk, channel_ids, indexed_offsets(stream, chunk_index, channel_ids))
    except Exception as exc:  # noqa: BLE001 - a CRC mismatch, data that does not decompress, a broken record
        _report_chunk(file, chunk_index.chunk_start_offset, chunk, exc, chunk_index)
        return None


BLOCK = 1024   # messages read one by one gathered into one MessageColumns (``blocks_of``)


class MessageColumns(NamedTuple):
    """Messages of a bag in ``mcap_messages``' order as columns: each one's topic, type (its schema's
    name, '' without one), log time (ns since the epoch) and CDR bytes."""

    topic: list[str]
    type_name: list[str]
    log_time_ns: list[int]
    data: list[bytes]


def blocks_of(records: Iterable[tuple[Any, Any, Any]]) -> Iterator[MessageColumns]:
    """(schema, channel, message) records gathered BLOCK at a time into columns."""
    block: list[tuple[Any, Any, Any]] = []
    for record in records:
        block.append(record)
        if len(block) == BLOCK:
            yield _gathered(block)
            block = []
    if block:
        yield _gathered(block)


def _gathered(records: list[tuple[Any, Any, Any]]) -> MessageColumns:
    return MessageColumns([channel.topic for _, channel, _ in records],
                          [schema.name if schema is not None else "" for schema, _, _ in records],
                          [message.log_time for _, _, message in records], [message.data for _, _, message in records])


def mcap_columns(file: Path, topics: Collection[str] | None) -> Iterator[MessageColumns]:
    """``mcap_messages`` of one MCAP file as columns: a chunk at a time, its messages read at once
    (``chunk_columns``) and sorted by log time, when the file is indexed and its chunks in sequence
    (``_in_sequence``: a recording's usual shape); else its records (``mcap_messages``) ``blocks_of``."""
    with open(file, "rb") as stream:
        try:
            summary = SeekingReader(stream).get_summary()
        except (McapError, OSError, struct.error, ValueError):   # no footer or summary: scanned by mcap_messages
            summary = None
        chunks = sorted(summary.chunk_indexes, key=_chunk_start) if summary is not None else []
        if summary is None or not _in_sequence(chunks):
            yield from blocks_of(mcap_messages(file, topics))
            return
        channels, schemas = summary.channels, summary.schemas
        channel_ids = {i for i, c in channels.items() if topics is None or c.topic in topics}
        topic = {i: channels[i].topic for i in channel_ids}
        type_name = {i: schemas[channels[i].schema_id].name if channels[i].schema_id else "" for i in channel_ids}
        count = 0
        try:
            for chunk_index in chunks:
                columns = _chunk_columns(file, stream, chunk_index, channel_ids)
                if columns is None or not columns.data:
                    continue
                order = np.argsort(columns.log_time, kind="stable")   # a chunk's messages: usually in order already
                ids = columns.channel_id[order].tolist()
                yield MessageColumns([topic[i] for i in ids], [type_name[i] for i in ids],
                                     columns.log_time[order].tolist(), [columns.data[k] for k in order.tolist()])
                count += len(ids)
        except Exception as exc:  # noqa: BLE001 - damaged data: decompression, lengths
            raise _damaged(file, count, exc) from exc


def _damaged(file: Path, count: int, exc: Exception) -> BagError:
    """The error of an indexed file that stops reading after ``count`` messages."""
    return BagError(f"{file} is damaged after {count} messages ({type(exc).__name__}: "
                    f"{str(exc).splitlines()[0] if str(exc) else 'unreadable data'}): "
                    "copy what can be read with an MCAP tool or record again")
