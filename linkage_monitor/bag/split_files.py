"""The MCAP files of a bag being written: the one being written, those finished, and when the next one
starts.

Splitting (``max_bag_size``, ``max_bag_duration_s``; off by default), as ``ros2 bag record
--max-bag-size --max-bag-duration`` does: when the file being written has reached the size (bytes,
counted at the message about to be written, chunks uncompressed) or holds messages spanning the
duration (receive time), it is finished (summary, indexes, the ``rosbag2`` metadata record) and the
next message starts `<name>_<k+1>.mcap` with the same schemas, channels and attachments, so every
file is readable on its own; `metadata.yaml` lists every file with its span.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

from mcap.writer import CompressionType

from linkage_monitor.bag.mcap_records import McapWriter
from linkage_monitor.bag.metadata import FileSpan, Span, Topic, yaml_text
from linkage_monitor.bag.tailed_file import TailedFile
from linkage_monitor.wire.definitions import message_definition

# B, the smallest max_bag_size (but 0, no splitting): rosbag2's minimum split size of its sqlite3 storage
# (SqliteStorage::get_minimum_split_file_size, 84 KiB; `ros2 bag record` refuses a smaller --max-bag-size
# with it, with its MCAP storage below 1024 B). Every file of ours carries its schemas, channels,
# attachments and summary, and a file is finished at a chunk at the earliest: a smaller size makes a
# file per write (max_bag_size 1: 1,830 files for 450 inputs, minutes to close them at exit).
MIN_SPLIT_SIZE = 86_016


@dataclass
class Attachment:
    """An MCAP attachment: a file stored in the bag (``name``, ``data``, ``media_type``), logged at
    ``log_time_ns`` (ns since the epoch)."""

    name: str
    data: bytes
    media_type: str
    log_time_ns: int


class StorageFile:
    """One MCAP file of the bag being written: its tailed file, MCAP writer, the schema and channel
    ids registered in it, and the span of its messages."""

    def __init__(self, path: Path, chunk_size: int, compression: CompressionType) -> None:
        self.path = path
        self.file = TailedFile(path)
        self.writer = McapWriter(self.file, chunk_size=chunk_size,  # type: ignore[arg-type]  # file-like
                                 compression=compression)
        self.writer.start(profile="ros2", library="linkage_monitor.bag.writer")
        self.file.enable_tail()
        self.file.write(b"")  # end the header in a valid tail right away
        self.schemas: dict[str, int] = {}
        self.channels: dict[str, int] = {}
        self.span = Span()
        self.pending_bytes = 0      # message bytes given to the writer since the file last grew
        self._end_seen = self.file.tell()

    def size(self) -> int:
        """Bytes in the file plus the messages still in the open chunk (uncompressed), B."""
        if self.file.tell() != self._end_seen:
            self._end_seen, self.pending_bytes = self.file.tell(), 0
        return self._end_seen + self.pending_bytes

    def channel(self, topic: Topic) -> int:
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

    def attach(self, item: Attachment) -> None:
        self.writer.add_attachment(create_time=item.log_time_ns, log_time=item.log_time_ns, name=item.name,
                                   media_type=item.media_type, data=item.data)


def file_path(directory: Path, name: str, index: int) -> Path:
    """The path of file ``index`` (0, 1, ...) of bag ``name`` in ``directory``: `<name>_<index>.mcap`."""
    return directory / f"{name}_{index}.mcap"


class BagFiles:
    """The MCAP files of one bag: ``current`` (being written), the finished ones, the attachments every
    file carries, and the limits at which the next file starts (``max_size``, B, and ``max_duration_ns``,
    ns; 0: none). OSError from writing as the files raise it."""

    def __init__(self, directory: Path, name: str, chunk_size: int, compression: CompressionType,
                 max_size: int, max_duration_ns: int) -> None:
        self.directory, self.name = directory, name
        self.chunk_size, self.compression = chunk_size, compression
        self.max_size, self.max_duration_ns = max_size, max_duration_ns
        self.attachments: list[Attachment] = []
        self.finished: list[FileSpan] = []   # files written and closed
        self.current = StorageFile(file_path(directory, name, 0), chunk_size, compression)

    @property
    def paths(self) -> list[Path]:
        """The bag's MCAP files, in order (the last one being written until the bag is closed)."""
        return [self.directory / file.name for file in self.finished] + [self.current.path]

    def spans(self) -> list[FileSpan]:
        """Every file of the bag with the span of its messages, in order."""
        return [*self.finished, FileSpan(self.current.path.name, self.current.span)]

    def split_due(self, log_time_ns: int) -> bool:
        """True when the file being written is full by size or duration (and holds a message)."""
        span = self.current.span
        if span.start is None:
            return False
        return ((self.max_size > 0 and self.current.size() >= self.max_size)
                or (self.max_duration_ns > 0 and log_time_ns - span.start >= self.max_duration_ns))

    def finish(self, information: dict[str, Any]) -> None:
        """The current file's ``rosbag2`` metadata record (``information``: the bag's rosbag2 metadata),
        summary and indexes (the file left open)."""
        self.current.writer.add_metadata("rosbag2", {"serialized_metadata": yaml_text(information)})
        self.current.writer.finish()

    def next_file(self, information: dict[str, Any]) -> None:
        """Finish the file being written (``finish``), close it and start the next one, which carries
        every attachment."""
        self.finish(information)
        self.current.file.close()
        self.finished.append(FileSpan(self.current.path.name, self.current.span))
        self.current = StorageFile(file_path(self.directory, self.name, len(self.finished)), self.chunk_size,
                                   self.compression)
        for item in self.attachments:
            self.current.attach(item)

    def attach(self, item: Attachment) -> None:
        """Store ``item`` in the file being written and in every later file of the bag."""
        self.attachments.append(item)
        self.current.attach(item)
