"""rosbag2-compatible MCAP bag writer: `<dir>/metadata.yaml` + `<dir>/<name>_0.mcap` (`_1.mcap`, ... when split).

What `ros2 bag record -s mcap` writes (rosbag2_storage_mcap, foxglove registry.md): profile
`ros2`, schema name `pkg/msg/Type` with encoding `ros2msg` (msg_schema.message_definition),
messages `cdr` (rclpy.serialization), channel metadata `offered_qos_profiles`, a `rosbag2`
metadata record and a version-9 `metadata.yaml` (``bag.metadata``).

Crash safety: every `flush_period_s` (and on `flush()`) the open chunk is closed and written,
and the file is made to end in a valid DataEnd + Footer (no summary; ``bag.tailed_file``), so a process
killed with SIGKILL leaves a bag that footer-reading readers (rosbags, mcap SeekingReader, Rerun)
open and that holds everything written up to the last flush. `metadata.yaml` is rewritten
at the same time.

Splitting by size or duration, as ``ros2 bag record --max-bag-size --max-bag-duration`` does
(``bag.split_files``). The crash safety and the cut-back on a full disk hold for the file being written.

Off the caller's path: `write` queues the message and a background thread writes the queue
(``bag.write_queue``). Many messages at once: ``write_rows`` takes a block of messages as arrays
(``MessageRows``) and writes them straight into MCAP chunks built with numpy (``bag.row_block``); the
crash-safe tail, the splitting and the cut-back on a full disk hold as for `write`.
"""

from __future__ import annotations

import os
import threading
import time
from concurrent.futures import Future, ThreadPoolExecutor
from pathlib import Path
from typing import Any, Sequence

import numpy as np
from mcap.writer import CompressionType
from rclpy.qos import DurabilityPolicy, QoSProfile
from rclpy.serialization import serialize_message

from linkage_monitor.bag.errors import BagError
from linkage_monitor.bag.metadata import Span, Topic, bag_information, qos_to_dict, write_metadata_yaml
from linkage_monitor.bag.row_block import (ChunkRecords, MessageRows, RowBlock, chunk_end, chunk_records, compressed,
                                           write_chunk)
from linkage_monitor.bag.split_files import MIN_SPLIT_SIZE, Attachment, BagFiles, StorageFile, file_path
from linkage_monitor.bag.write_queue import WriteQueue, WriteThread
from linkage_monitor.wire.definitions import exact_cdr

MECHANISM_TOPIC = "/linkage_monitor/mechanism"
"""Topic of the mechanism description (std_msgs/String holding the mechanism YAML)."""

_U64 = 1 << 64


def message_type_name(msg: Any) -> str:
    """Return the ROS type name `pkg/msg/Type` of an rclpy message object."""
    cls = type(msg)
    package, interface = cls.__module__.split(".")[:2]
    return f"{package}/{interface}/{cls.__name__}"


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
        first = file_path(self.directory, self.name, 0)
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
        self._lock = threading.Lock()         # the MCAP writer, the files, the span, the error state
        self._queued = WriteQueue()           # its lock also guards closing and ``unwritten``
        self._span = Span()                     # all files
        self._topics: dict[str, Topic] = {}
        self._dirty = False
        self._closed = threading.Event()
        self.error: str | None = None   # set at the first I/O error: what failed, on which path
        self.unwritten = 0              # messages not recorded because of that error
        try:
            self.directory.mkdir(parents=True, exist_ok=True)
            self._files = BagFiles(self.directory, self.name, chunk_size, compression, int(max_bag_size),
                                   int(max_bag_duration_s * 1e9))
            self._write_metadata_yaml()
        except OSError as exc:
            raise BagError(f"cannot record into {exc.filename or self.directory}: {exc.strerror or exc} "
                           "(choose a writable directory, e.g. with the record_dir parameter)") from None
        self._flusher = WriteThread(f"BagWriter {self.name}", self._closed, flush_period_s,
                                    self._write_queued_if_open, self.flush)
        self._flusher.start()
        # write_rows' chunks compressed beside the building of the next (its thread started at the first)
        self._compressor = ThreadPoolExecutor(max_workers=1, thread_name_prefix=f"BagWriter {self.name} chunks")

    @property
    def paths(self) -> list[Path]:
        """The bag's MCAP files, in order (the last one being written until ``close``)."""
        return self._files.paths

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
        with self._queued.lock:
            self._check_open()
            if entry is None or self.error is not None:
                self.unwritten += 1
                return
            full = self._queued.append((entry, data, log_time, publish_time))
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
                written = self._write_block(RowBlock.of(parts, entries, self._span.end or 0))
            if written < n:
                with self._queued.lock:
                    self.unwritten += n - written

    def _write_block(self, block: RowBlock) -> int:
        """Write ``block`` in chunks (under ``_lock``), the writer's open chunk first; the messages written.
        A chunk is compressed in the compressor thread while the next chunk's records are built, unless
        the bag splits (where the next file starts depends on the chunk written last)."""
        files = self._files
        overlap = files.max_size == 0 and files.max_duration_ns == 0
        lo, split_next, written = 0, False, 0
        waiting: tuple[ChunkRecords, Future[tuple[bytes, int]], StorageFile] | None = None
        try:
            files.current.writer.flush()
            while lo < len(block):
                if split_next or files.split_due(int(block.log_time[lo])):
                    self._next_file()
                hi, split_next = chunk_end(block, lo, files)
                current = files.current
                chunk = chunk_records(block, lo, hi, current)
                packing = self._compressor.submit(compressed, current, chunk.data)
                if waiting is not None:
                    written = self._write_chunk(block, *waiting)
                waiting = (chunk, packing, current)
                if not overlap:
                    written, waiting = self._write_chunk(block, *waiting), None
                lo = hi
            if waiting is not None:
                written = self._write_chunk(block, *waiting)
        except OSError as exc:
            self._fail(exc)
        return written

    def _write_chunk(self, block: RowBlock, chunk: ChunkRecords, packing: Future[tuple[bytes, int]],
                     current: StorageFile) -> int:
        """``chunk`` of ``block`` written to ``current`` once compressed; the block's messages written so far."""
        write_chunk(block, chunk, packing.result(), current)
        self._span.add_many(int(block.log_time[chunk.lo]), int(block.log_time[chunk.hi - 1]), chunk.hi - chunk.lo)
        self._dirty = True
        return chunk.hi

    def _write_queued(self) -> None:
        """Write the queued messages into the MCAP writer, in order (under ``_lock``). Receive order
        = log_time order, which readers of a killed (unindexed) bag need: a log time earlier than
        the last one written is moved up to it."""
        queued = self._queued.take()
        for k, (entry, data, log_time, publish_time) in enumerate(queued):
            log_time = max(log_time, self._span.end or 0)
            if self.error is None:
                try:
                    if self._files.split_due(log_time):
                        self._next_file()
                    current = self._files.current
                    current.writer.add_message(current.channel(entry), log_time=log_time, data=data,
                                               publish_time=publish_time, sequence=entry.count % (1 << 32))
                    current.pending_bytes += len(data)
                except OSError as exc:
                    self._fail(exc)
            if self.error is not None:
                with self._queued.lock:
                    self.unwritten += len(queued) - k
                return
            entry.count += 1
            self._span.add(log_time)
            self._files.current.span.add(log_time)
            self._dirty = True

    def _write_queued_if_open(self) -> None:
        """The background thread's write of the queue (``_write_queued``), unless the bag is closed."""
        with self._lock:
            if not self._closed.is_set():
                self._write_queued()

    def _next_file(self) -> None:
        """Finish the file being written (under ``_lock``) and start the next one; OSError as writing."""
        self._files.next_file(self._bag_information())
        self._write_metadata_yaml()

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
        item = Attachment(name, data, media_type, time.time_ns() if log_time_ns is None else int(log_time_ns))
        with self._lock:
            self._check_open()
            self._files.attach(item)   # every later file of a split bag carries it too

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
                self._files.current.writer.flush()
                self._write_metadata_yaml()
            except OSError as exc:
                self._fail(exc)
                return
            self._dirty = False
            current = self._files.current.file
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
            with self._queued.lock:
                if self._closed.is_set():
                    return
                self._closed.set()   # write() refuses from here on
            self._write_queued()
            if self.error is None:
                try:
                    self._files.finish(self._bag_information())
                except OSError as exc:
                    self._fail(exc)
            try:   # after an error the file keeps its last valid tail (readable without a summary)
                self._files.current.file.close(keep_tail=self.error is not None)
                self._write_metadata_yaml()
            except OSError as exc:
                self.error = self.error or f"{self.directory}: {exc.strerror or exc}"
        self._flusher.join()
        self._compressor.shutdown()

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
            self.error = (f"{exc.filename or self._files.current.path}: {exc.strerror or exc} — the bag holds what "
                          "was written before; free space or fix the disk, then restart the recording")

    def _check_open(self) -> None:
        if self._closed.is_set():
            raise BagError(f"bag {self.directory} is closed: open a new BagWriter")

    def _topic(self, topic: str, type_name: str, qos: QoSProfile | None) -> Topic:
        """The topic's entry, made at its first message (under ``_lock``; its channel is registered in
        each file as the file's first message on it is written); BagError for a second type on a topic."""
        entry = self._topics.get(topic)
        if entry is not None:   # (write() looked without the lock: another thread may have registered it)
            if entry.type_name != type_name:
                raise BagError(f"topic {topic!r} in bag {self.directory} holds {entry.type_name},"
                               f" cannot also record {type_name}: use another topic")
            return entry
        entry = Topic(topic, type_name, qos_to_dict(qos if qos is not None else QoSProfile(depth=10)))
        self._topics[topic] = entry
        return entry

    def _bag_information(self) -> dict[str, Any]:
        """rosbag2 `rosbag2_bagfile_information` (metadata version 9) of what is written."""
        return bag_information(self._files.spans(), self._span, self._topics.values())

    def _write_metadata_yaml(self) -> None:
        write_metadata_yaml(self.directory, self._bag_information())
