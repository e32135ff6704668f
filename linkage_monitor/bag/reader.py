"""Read rosbag2 bags (ours, `ros2 bag record`, rosbags) back into rclpy messages.

Every rosbag2 storage: MCAP files and sqlite3 files (`.db3`, rosbag2's default storage before
Iron), one file or a split bag (several storage files listed in one metadata.yaml, read one after
the other as one bag). A ROS 1 `.bag` is refused with the command that converts it.

`read_bag` yields decoded messages one by one (a message that does not decode as its type is
left out with a warning in the log). A message recorded with another definition of its type than
the installed one (an MCAP file's schema record carries the definition it was written with, e.g.
a HitchState from before `min_transmission_angle`) is decoded by the recorded definition and
handed over as the installed class: fields of the same name copied, a float field the recording
lacks NaN (not known), any other one its default; `read_bag_raw` yields their bytes undecoded (the replay
reads its inputs itself and reports an unreadable one as the node does); `read_inputs`
gathers the sensor topics the solver needs (JointState, FluidPressure) into numpy columns.
A bag whose writer was killed, or a file cut mid-record (an interrupted copy, a dying card), is
read record by record up to its last complete record. What cannot be read as recorded is a
``ReadFault`` naming the file, the byte and the messages (a cut, a chunk that fails its CRC, a file
metadata.yaml does not list, a sqlite3 topic that is not its declared type): logged as a warning,
and collected by ``read_faults()`` for a caller that reports them (fleet's rows).
"""

from __future__ import annotations

import functools
import importlib
import io
import logging
import math
import os
import re
import sqlite3
import struct
from collections.abc import Collection, Iterator
from contextlib import contextmanager
from contextvars import ContextVar
from dataclasses import dataclass
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np
import yaml
from mcap.exceptions import McapError
from mcap._message_queue import make_message_queue
from mcap.data_stream import ReadDataStream
from mcap.reader import SeekingReader
from mcap.records import Channel, Chunk, ChunkIndex, Message, Schema
from mcap.opcode import Opcode
from mcap.stream_reader import CRCValidationError, breakup_chunk, get_chunk_data_stream
from rclpy.serialization import deserialize_message
from rosbags.typesys import Stores, get_types_from_msg, get_typestore
from rosidl_parser.definition import AbstractNestedType, BasicType, NamespacedType

from linkage_monitor.bag.writer import BagError
from linkage_monitor.wire.cdr import is_xcdr1, stamp_ns
from linkage_monitor.wire.definitions import MessageDefinitionError, exact_cdr, message_definition
from linkage_monitor.wire.sensor_messages import FLUID_PRESSURE, JOINT_STATE

_MCAP_MAGIC = b"\x89MCAP0\r\n"
_SQLITE_MAGIC = b"SQLite format 3\x00"
_ROS1_MAGIC = b"#ROSBAG V"
STORAGE_SUFFIXES = (".mcap", ".db3")
_log = logging.getLogger(__name__)


@dataclass(frozen=True)
class JointStateColumns:
    """One JointState topic as columns; row i is message i in log-time order.

    stamp_ns, log_time_ns: header stamp and receive time, ns since the epoch, shape (N,).
    names: joint names, the column order of position and velocity.
    position: rad (revolute) or m (prismatic), shape (N, len(names)); NaN where a message
    lacks the joint. velocity: rad/s or m/s, same shape; NaN where not given.
    """

    stamp_ns: np.ndarray
    log_time_ns: np.ndarray
    names: tuple[str, ...]
    position: np.ndarray
    velocity: np.ndarray


@dataclass(frozen=True)
class PressureColumns:
    """One FluidPressure topic as columns: stamp_ns, log_time_ns (ns since the epoch),
    fluid_pressure (Pa, absolute), variance (Pa^2, 0 = unknown), each shape (N,)."""

    stamp_ns: np.ndarray
    log_time_ns: np.ndarray
    fluid_pressure: np.ndarray
    variance: np.ndarray


@dataclass(frozen=True)
class ReadFault:
    """Part of a bag that could not be read as recorded, named: ``file``, ``kind`` ('cut_off': the file
    ends in an incomplete record; 'chunk_skipped': a chunk fails its CRC or does not read;
    'unlisted_file': a storage file metadata.yaml does not list; 'type_mismatch': a topic whose messages
    are not its declared type (sqlite3); 'no_channel': messages whose channel
    is not defined), ``offset`` (byte in the file where it starts, None when it is a whole file),
    ``messages`` (messages read before a cut, or lost in a chunk; None when not known) and ``text``,
    the sentence that says it and what follows from it."""

    file: str
    kind: str
    offset: int | None
    messages: int | None
    text: str

    def __str__(self) -> str:
        return self.text


_COLLECTED: ContextVar[list[ReadFault] | None] = ContextVar("linkage_monitor_bag_read_faults", default=None)


@contextmanager
def read_faults() -> Iterator[list[ReadFault]]:
    """Collect the ``ReadFault``s of every bag read in this context (each once, in the order found;
    a bag read several times names its faults once). Each is also logged as a warning when first found."""
    found: list[ReadFault] = []
    token = _COLLECTED.set(found)
    try:
        yield found
    finally:
        _COLLECTED.reset(token)


def _report(fault: ReadFault) -> None:
    """Log ``fault`` as a warning and add it to the ``read_faults`` being collected (once)."""
    found = _COLLECTED.get()
    if found is not None:
        if fault in found:
            return
        found.append(fault)
    _log.warning("%s", fault.text)


# libyaml's safe loader where PyYAML was built with it (4x faster on a rosbag2 metadata.yaml), else PyYAML's
_SAFE_LOADER = getattr(yaml, "CSafeLoader", yaml.SafeLoader)


def storage_files(path: str | os.PathLike[str]) -> list[Path]:
    """Return the storage files of a bag, in reading order: a rosbag2 directory or a single `.mcap` /
    `.db3` file. A directory's files in metadata.yaml's order; without metadata.yaml, or with storage
    files it does not list, every storage file by its first message's log time (ties and files without
    messages by the split index `_N` of their names, numerically: `_2` before `_10`). Raises BagError
    saying what is wrong (a ROS 1 bag: the command that converts it)."""
    path = Path(path)
    if not path.exists():
        raise BagError(f"bag {path} does not exist: give a bag directory, an .mcap or a .db3 file")
    if not path.is_dir():
        _storage_of(path)
        return [path]
    listed = _files_from_metadata(path)
    for file in listed or []:
        if not file.is_file():
            raise BagError(f"bag file {file} listed in {path / 'metadata.yaml'} is missing")
    on_disk = [f for f in path.iterdir() if f.suffix in STORAGE_SUFFIXES and f.is_file()]
    for file in on_disk if listed is None else listed:
        _storage_of(file)
    files = _directory_order(path, listed, on_disk)
    if not files:
        ros1 = sorted(path.glob("*.bag"))
        raise BagError(_ros1_advice(ros1[0]) if ros1 else
                       f"bag directory {path} holds no .mcap or .db3 file: give a rosbag2 bag")
    return files


def _directory_order(directory: Path, listed: list[Path] | None, on_disk: list[Path]) -> list[Path]:
    """The reading order of a bag directory's storage files (``storage_files``).

    A storage file metadata.yaml does not list is read, not skipped: rosbag2 rewrites metadata.yaml
    only when a file is closed, so such a file is most often the last one of a recorder that was
    killed, or one copied in afterwards; its messages are the recording's and leaving them out would
    lose them without a word. It is read in the order of its messages' log times, with every other
    file, and named in a ``ReadFault`` (a file of another recording shows up there: remove it)."""
    if listed is not None:
        unlisted = [file for file in sorted(set(on_disk) - set(listed), key=_split_order)
                    if _unlisted_is_read(directory, file)]
        if not unlisted:
            return listed
        on_disk = listed + unlisted
    starts = {file: _first_log_time(file) for file in on_disk}
    return sorted(on_disk, key=lambda f: (starts[f] is None, starts[f] or 0, _split_order(f)))


def _unlisted_is_read(directory: Path, file: Path) -> bool:
    """Whether the storage file ``file`` that bag ``directory``'s metadata.yaml does not list is read (it
    is an MCAP or sqlite3 file) or left out (it is not); named in a ``ReadFault`` either way."""
    try:
        _storage_of(file)
    except BagError as exc:
        _report(ReadFault(str(file), "unlisted_file", None, None,
                          f"{file} is in bag {directory} but not listed in its metadata.yaml, and not read: {exc}"))
        return False
    _report(ReadFault(str(file), "unlisted_file", None, None,
                      f"{file} is in bag {directory} but not listed in its metadata.yaml: read in the order of its "
                      "log times with the listed files (remove it if it is not this recording's)"))
    return True


_SPLIT_NAME = re.compile(r"^(?P<stem>.+)_(?P<index>[0-9]+)$")   # rosbag2's `<bag>_<N>.<storage>`


def _split_order(file: Path) -> tuple[str, int, str]:
    """A storage file's place by its name: the stem, then rosbag2's split index `_N` as a number."""
    match = _SPLIT_NAME.match(file.stem)
    return (match["stem"], int(match["index"]), file.name) if match else (file.stem, -1, file.name)


def is_split_bag(directory: Path) -> bool:
    """Whether ``directory`` is one bag: it has metadata.yaml, or it holds no directory and its storage
    files are named as the files of one rosbag2 bag, `<stem>_<N>.mcap` / `.db3` with one stem (a split
    bag without metadata)."""
    if (directory / "metadata.yaml").is_file():
        return True
    entries = list(directory.iterdir())
    names = [_SPLIT_NAME.match(f.stem) for f in entries if f.suffix in STORAGE_SUFFIXES]
    return (bool(names) and all(names) and len({m["stem"] for m in names if m}) == 1
            and not any(f.is_dir() for f in entries))


def _first_log_time(file: Path) -> int | None:
    """The log time (ns since the epoch) of a storage file's first message; None when it holds none or
    that cannot be read."""
    if _storage_of(file) == "sqlite3":
        try:
            connection = sqlite3.connect(f"{file.resolve().as_uri()}?mode=ro", uri=True)
            try:
                first = connection.execute("SELECT MIN(timestamp) FROM messages").fetchone()[0]
            finally:
                connection.close()
        except sqlite3.Error:
            return None
        return int(first) if first is not None else None
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


def _storage_of(file: Path) -> str:
    """'mcap' or 'sqlite3', from the file's first bytes; BagError for anything else."""
    with open(file, "rb") as stream:
        head = stream.read(len(_SQLITE_MAGIC))
    if head.startswith(_MCAP_MAGIC):
        return "mcap"
    if head.startswith(_SQLITE_MAGIC):
        return "sqlite3"
    if head.startswith(_ROS1_MAGIC):
        raise BagError(_ros1_advice(file))
    raise BagError(f"{file} is neither an MCAP nor a sqlite3 rosbag2 file (starts with {head[:8]!r}): "
                   "give a rosbag2 bag")


def _ros1_advice(file: Path) -> str:
    return (f"{file} is a ROS 1 bag: convert it to a rosbag2 bag with `rosbags-convert --src {file} "
            f"--dst {file.with_suffix('')}` (rosbags, installed with linkage_monitor), then give that directory")


class BagMessage(NamedTuple):
    """A decoded message of a bag (``read_bag``): its topic, type name `pkg/msg/Type`, header stamp
    (ns since the epoch; the MCAP publish_time without a header), log time (ns, the receive
    time) and the rclpy message."""

    topic: str
    type_name: str
    stamp_ns: int
    log_time_ns: int
    message: Any


class RawMessage(NamedTuple):
    """A message of a bag as recorded (``read_bag_raw``): its topic, type name, MCAP publish and
    log times (ns since the epoch) and CDR bytes."""

    topic: str
    type_name: str
    publish_time_ns: int
    log_time_ns: int
    data: bytes


def read_bag(path: str | os.PathLike[str], topics: Collection[str] | None = None,
             types: Collection[str] | None = None) -> Iterator[BagMessage]:
    """Yield every message of the bag, decoded (``BagMessage``).

    msg is the rclpy message (class found from type_name `pkg/msg/Type`). stamp_ns is the
    header stamp (ns since the epoch) for messages with a header, else the MCAP publish_time;
    log_time_ns is the receive time. Messages come in log-time order per file (in write
    order for a file without index, e.g. from a killed writer).
    topics: only these topics; types: only these `pkg/msg/Type`s (default: all; others are
    skipped before they are decoded).
    """
    yield from _messages(path, topics=topics, types=types)


def read_bag_raw(path: str | os.PathLike[str], topics: Collection[str] | None = None
                 ) -> Iterator[RawMessage]:
    """Every message (on ``topics``) undecoded, as recorded, in ``read_bag``'s order."""
    for file in storage_files(path):
        for schema, channel, message in _raw_messages(file, topics):
            yield RawMessage(channel.topic, schema.name if schema is not None else "", message.publish_time,
                             message.log_time, message.data)


def read_inputs(path: str | os.PathLike[str]) -> dict[str, JointStateColumns | PressureColumns]:
    """Return every JointState and FluidPressure topic of the bag as numpy columns.

    Raises BagError if the bag holds neither type.
    """
    rows: dict[str, list[tuple[int, int, Any]]] = {}
    kinds: dict[str, str] = {}
    undecoded: Undecoded = {}
    for topic, type_name, stamp, log_time, msg in _messages(path, topics=None, types=(JOINT_STATE, FLUID_PRESSURE),
                                                            undecoded=undecoded):
        rows.setdefault(topic, []).append((stamp, log_time, msg))
        kinds[topic] = type_name
    if not rows:
        unreadable = sum(count for count, _ in undecoded.values())
        raise BagError(f"bag {path} holds no {JOINT_STATE} or {FLUID_PRESSURE} messages"
                       + (f" that decode ({unreadable} do not: {undecoded_lines(undecoded)[0]})" if undecoded else
                          ": nothing to replay (record the sensor topics)"))
    for line in undecoded_lines(undecoded):
        _log.warning("%s", line)
    return {topic: (_joint_columns(r) if kinds[topic] == JOINT_STATE else _pressure_columns(r))
            for topic, r in rows.items()}


def message_class(type_name: str) -> type:
    """Return the rclpy message class of `pkg/msg/Type` (the package must be installed)."""
    return _message_class(type_name)


@functools.lru_cache(maxsize=None)
def _message_class(type_name: str) -> type:
    package, interface, name = (type_name.split("/") + ["", ""])[:3]
    try:
        return getattr(importlib.import_module(f"{package}.{interface}"), name)
    except (ImportError, AttributeError, ValueError) as exc:
        raise BagError(f"message type {type_name!r} has no Python class {package}.{interface}."
                       f"{name}: install the package {package!r} into this environment"
                       ) from exc


def _files_from_metadata(directory: Path) -> list[Path] | None:
    """The files metadata.yaml lists, in its order; None when the directory has no metadata.yaml."""
    metadata = directory / "metadata.yaml"
    if not metadata.is_file():
        return None
    try:
        info = yaml.load(metadata.read_text(encoding="utf-8"), Loader=_SAFE_LOADER)["rosbag2_bagfile_information"]
        return [directory / Path(p).name for p in info["relative_file_paths"]]
    except (yaml.YAMLError, KeyError, TypeError, UnicodeDecodeError) as exc:
        raise BagError(f"{metadata} is not a rosbag2 metadata file ({type(exc).__name__}): fix or remove it"
                       ) from exc


Undecoded = dict[tuple[str, str, str], tuple[int, str]]   # (file, topic, type) -> (count, the first reason)


def _messages(path: str | os.PathLike[str], topics: Collection[str] | None,
              types: Collection[str] | None, undecoded: Undecoded | None = None
              ) -> Iterator[BagMessage]:
    """The decoded messages of every storage file; those that do not decode are left out, counted in
    ``undecoded`` when given (the caller reports them), else logged as one warning per topic."""
    for file in storage_files(path):
        left_out: Undecoded = {} if undecoded is None else undecoded
        yield from _decoded(file, topics, types, left_out)
        if undecoded is None:
            for line in undecoded_lines(left_out):
                _log.warning("%s", line)


def undecoded_lines(undecoded: Undecoded) -> list[str]:
    """One sentence per topic of a file whose messages did not decode."""
    return [f"{file}: {count} message(s) on {topic} do not decode as {type_name} (the first: {reason}): left out"
            for (file, topic, type_name), (count, reason) in undecoded.items()]


def _decoded(file: Path, topics: Collection[str] | None, types: Collection[str] | None,
             undecoded: Undecoded) -> Iterator[BagMessage]:
    """``_messages`` of one storage file; the messages that do not decode counted in ``undecoded``."""
    recorded: dict[tuple[str, bytes], Any] = {}   # (type, schema text) -> its typestore when it is not the installed
    for schema, channel, message in _raw_messages(file, topics):
        type_name = schema.name if schema is not None else ""
        if types is not None and type_name not in types:
            continue
        if channel.message_encoding != "cdr":
            raise BagError(f"{file}: topic {channel.topic!r} is encoded as "
                           f"{channel.message_encoding!r}, only 'cdr' is supported")
        msg_class = _message_class(type_name)   # BagError when the type's package is not installed
        key = (type_name, getattr(schema, "data", b"") or b"")
        if key not in recorded:
            recorded[key] = _recorded_typestore(*key)
            if recorded[key] is not None:
                _log.info("%s: %s is recorded with another definition of %s than the installed one: read by the "
                          "recorded definition (%s)", file, channel.topic, type_name, _missing_fields(*key))
        store = recorded[key]
        try:
            msg: Any = (deserialize_message(message.data, msg_class) if store is None else
                        _as_installed(store.deserialize_cdr(message.data, type_name), msg_class))
        except Exception as exc:  # noqa: BLE001 - e.g. an input the node recorded as it came, unreadable
            count, first = undecoded.get((str(file), channel.topic, type_name), (0, ""))
            undecoded[(str(file), channel.topic, type_name)] = (count + 1, first or (
                f"{len(message.data)} bytes at log time {message.log_time} ns: "
                f"{str(exc).splitlines()[0] if str(exc) else type(exc).__name__}"))
            continue
        header = getattr(msg, "header", None)
        stamp = stamp_ns(header) if header is not None else message.publish_time
        yield BagMessage(channel.topic, type_name, stamp, message.log_time, msg)


def _fields(text: str, type_name: str) -> dict[str, Any]:
    """Type name -> its fields (names and types, no constants) of every type in a ``ros2msg`` schema text."""
    return {name: fields for name, (_, fields) in get_types_from_msg(text, type_name).items()}


@functools.lru_cache(maxsize=64)
def _recorded_typestore(type_name: str, schema: bytes) -> Any | None:
    """A rosbags typestore holding ``schema`` (the ``ros2msg`` definition a bag recorded ``type_name``
    with) when its fields differ from the installed definition's; None when they agree, when the bag
    carries no definition (sqlite3) or when either cannot be parsed: rclpy decodes as installed."""
    try:
        text = schema.decode("utf-8")
        if not text or _fields(text, type_name) == _fields(message_definition(type_name), type_name):
            return None
        store = get_typestore(Stores.EMPTY)
        store.register(get_types_from_msg(text, type_name))
    except (MessageDefinitionError, UnicodeDecodeError):
        return None
    except Exception:  # noqa: BLE001 - rosbags' parser errors (TypesysError and others): decode as installed
        return None
    return store


def _missing_fields(type_name: str, schema: bytes) -> str:
    """What the recorded definition of ``type_name`` lacks of the installed one, and how it reads."""
    recorded = _fields(schema.decode("utf-8"), type_name).get(type_name, [])
    installed = _fields(message_definition(type_name), type_name).get(type_name, [])
    missing = [name for name, _ in installed if name not in {n for n, _ in recorded}]
    return (f"it lacks {', '.join(missing)}: NaN where a float, else the default" if missing else
            "fields of the same name copied")


def _as_installed(value: Any, cls: type) -> Any:
    """``value`` (a message decoded by rosbags) as the installed rclpy class ``cls``: fields of the same
    name copied (nested messages likewise), float fields ``value`` lacks NaN, any other lacking field
    its default; fields ``cls`` has not are dropped."""
    msg = cls()
    for name, slot in zip(cls.get_fields_and_field_types(), cls.SLOT_TYPES):   # type: ignore[attr-defined]
        if not hasattr(value, name):
            if isinstance(getattr(msg, name), float):
                setattr(msg, name, math.nan)
            continue
        field = getattr(value, name)
        element = slot.value_type if isinstance(slot, AbstractNestedType) else slot
        if isinstance(element, NamespacedType):
            nested = getattr(importlib.import_module(".".join(element.namespaces)), element.name)
            field = ([_as_installed(v, nested) for v in field] if isinstance(slot, AbstractNestedType)
                     else _as_installed(field, nested))
        elif isinstance(slot, AbstractNestedType):
            items = field.tolist() if isinstance(field, np.ndarray) else list(field)
            field = bytes(items) if isinstance(element, BasicType) and element.typename == "octet" else items
        setattr(msg, name, field)
    return msg


class _Schema(NamedTuple):
    """What the readers use of an MCAP schema record: the type name `pkg/msg/Type`."""

    name: str


class _Channel(NamedTuple):
    """What the readers use of an MCAP channel record."""

    topic: str
    message_encoding: str


class _Message(NamedTuple):
    """What the readers use of an MCAP message record: times in ns since the epoch, CDR bytes."""

    publish_time: int
    log_time: int
    data: bytes


class _Record(NamedTuple):
    """A message of an MCAP file with its schema (None: the channel has none) and channel records."""

    schema: Any
    channel: Any
    message: Message


def _raw_messages(file: Path, topics: Collection[str] | None) -> Iterator[tuple[Any, Any, Any]]:
    """(schema, channel, message) records of one storage file, in log-time order."""
    if _storage_of(file) == "sqlite3":
        return _sqlite3_messages(file, topics)
    return _mcap_messages(file, topics)


def _sqlite3_messages(file: Path, topics: Collection[str] | None) -> Iterator[tuple[Any, Any, Any]]:
    """The records of one rosbag2 sqlite3 file (tables `topics` and `messages`, as rosbag2's
    sqlite3 storage plugin writes them), in receive-time order (then insertion order). The
    storage keeps one time per message, the receive time: it stands for the publish time too.
    The file holds no definitions, only each topic's type name: a topic whose messages are not its
    declared type (``_declared_type_fails``) is left out, named once in a ``ReadFault``."""
    query = ("SELECT topics.name, topics.type, topics.serialization_format, messages.timestamp, messages.data "
             "FROM messages JOIN topics ON messages.topic_id = topics.id")
    wanted = list(topics) if topics is not None else None
    if wanted is not None:
        query += f" WHERE topics.name IN ({', '.join('?' * len(wanted))})"
    query += " ORDER BY messages.timestamp, messages.id"
    try:
        connection = sqlite3.connect(f"{file.resolve().as_uri()}?mode=ro", uri=True)
    except sqlite3.Error as exc:
        raise BagError(f"{file} is not a readable rosbag2 sqlite3 file ({exc}): "
                       "copy what can be read with `ros2 bag convert` or record again") from exc
    try:
        refused = _mistyped_topics(file, connection, wanted)
        rows = connection.execute(query, wanted or [])
        for topic, type_name, encoding, timestamp, data in rows:
            if topic not in refused:
                yield _Schema(type_name), _Channel(topic, encoding), _Message(timestamp, timestamp, bytes(data))
    except sqlite3.Error as exc:
        raise BagError(f"{file} is not a readable rosbag2 sqlite3 file ({exc}): "
                       "copy what can be read with `ros2 bag convert` or record again") from exc
    finally:
        connection.close()


TYPE_PROBES = 8   # first messages of a topic tried against its declared type: one that decodes clears it
_CDR_PADDING = 3   # bytes a rosbag2 CDR payload may hold after its message (alignment to 4)


def _mistyped_topics(file: Path, connection: sqlite3.Connection, wanted: list[str] | None) -> set[str]:
    """The topics of a sqlite3 file (on ``wanted``) whose declared type (the `topics` table's `type`)
    their messages are not: none of their first TYPE_PROBES messages decodes as it; each named once in a
    ``ReadFault`` (topic, declared type, why). One that decodes clears the topic: a damaged message
    alone is the replay's to report, as the node does."""
    refused = set()
    for topic_id, topic, type_name in connection.execute("SELECT id, name, type FROM topics"):
        if wanted is not None and topic not in wanted:
            continue
        probes = connection.execute("SELECT data FROM messages WHERE topic_id = ? ORDER BY timestamp, id LIMIT ?",
                                    (topic_id, TYPE_PROBES)).fetchall()
        reasons = [_declared_type_fails(type_name, bytes(data)) for (data,) in probes]
        if reasons and all(reasons):
            refused.add(topic)
            count = connection.execute("SELECT COUNT(*) FROM messages WHERE topic_id = ?", (topic_id,)).fetchone()[0]
            _report(ReadFault(str(file), "type_mismatch", None, count,
                              f"{file}: the messages on {topic} are not its declared type {type_name} (the "
                              f"first: {reasons[0]}): the file's topics table names a wrong type; its {count} "
                              "messages are left out (convert the bag with the right type)"))
    return refused


def _declared_type_fails(type_name: str, data: bytes) -> str | None:
    """Why the CDR payload ``data`` is not a ``type_name`` message (it does not decode as it, or bytes are
    left over beyond CDR's padding); None when it is, or cannot be told (a type whose definition is not
    installed, an encoding other than XCDR1)."""
    if not is_xcdr1(data):
        return None
    try:
        used = len(exact_cdr(type_name, data))
    except MessageDefinitionError:
        return None
    except ValueError as exc:
        return str(exc).split(": ")[-1] if str(exc) else "does not decode"
    if len(data) - used > _CDR_PADDING:
        return f"{len(data)} bytes, of which the type reads {used}: {len(data) - used} left over"
    return None


def _mcap_messages(file: Path, topics: Collection[str] | None) -> Iterator[tuple[Any, Any, Any]]:
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
            raise BagError(f"{file} is damaged after {count} messages ({type(exc).__name__}: "
                           f"{str(exc).splitlines()[0] if str(exc) else 'unreadable data'}): "
                           "copy what can be read with an MCAP tool or record again") from exc


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
    stream.seek(len(_MCAP_MAGIC))
    position = len(_MCAP_MAGIC)
    scan = _Scan({}, {})
    while True:
        head = stream.read(_RECORD_HEAD.size)
        opcode, length = _RECORD_HEAD.unpack(head) if len(head) == _RECORD_HEAD.size else (None, 0)
        if opcode is None or position + _RECORD_HEAD.size + length > size:
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
        position += _RECORD_HEAD.size + length
    if scan.orphans:
        _report(ReadFault(str(file), "no_channel", None, scan.orphans,
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
        records = breakup_chunk(chunk, validate_crc=True)
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
    _report(ReadFault(str(file), "cut_off", position, scan.messages, text))


def _report_chunk(file: Path, offset: int, chunk: Any, exc: Exception,
                  index: ChunkIndex | None = None) -> None:
    """The ``ReadFault`` of a chunk at byte ``offset`` that fails its CRC or does not read: skipped."""
    what = ("fails its CRC" if isinstance(exc, CRCValidationError) else
            f"is unreadable ({type(exc).__name__}: {str(exc).splitlines()[0] if str(exc) else 'damaged'})")
    count = _message_count(chunk)
    times = (f", log times {index.message_start_time} to {index.message_end_time} ns" if index is not None else
             f", log times {chunk.message_start_time} to {chunk.message_end_time} ns" if chunk is not None else "")
    _report(ReadFault(str(file), "chunk_skipped", offset, int(count) if count.isdigit() else None,
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
    queue = make_message_queue(log_time_order=True)
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
    """The messages of one chunk on the channels ``channel_ids``, in their order in the chunk; none, with
    a warning naming the chunk, when it fails its CRC or does not read."""
    stream.seek(chunk_index.chunk_start_offset + 1 + 8)   # past the record's opcode and length
    chunk = None
    channels = summary.channels
    try:
        chunk = Chunk.read(ReadDataStream(stream))
        records = _chunk_messages(chunk, channel_ids, _indexed_offsets(stream, chunk_index, channel_ids))
    except Exception as exc:  # noqa: BLE001 - a CRC mismatch, data that does not decompress, a broken record
        _report_chunk(file, chunk_index.chunk_start_offset, chunk, exc, chunk_index)
        return []
    schemas = summary.schemas
    return [_Record(schemas[channels[m.channel_id].schema_id] if channels[m.channel_id].schema_id else None,
                    channels[m.channel_id], m) for m in records]


_RECORD_HEAD = struct.Struct("<BQ")          # a record's opcode and the length of its body (MCAP spec)
_MESSAGE_HEAD = struct.Struct("<HIQQ")       # a Message record's channel id, sequence, log and publish time


_INDEX_HEAD = struct.Struct("<BQHI")        # a MessageIndex record's opcode, length, channel id, entries' size
_INDEX_ENTRY = np.dtype([("log_time", "<u8"), ("offset", "<u8")])


def _indexed_offsets(stream: Any, chunk_index: ChunkIndex, channel_ids: Collection[int]) -> np.ndarray | None:
    """Where the chunk's messages on ``channel_ids`` start in its records (byte offsets, in order), from
    the MessageIndex records after it (``message_index_offsets``); None when the chunk has none or one
    does not read as one (then the chunk's records are walked)."""
    indexes = chunk_index.message_index_offsets
    if not indexes:
        return None
    found = [np.zeros(0, np.uint64)]
    for at in sorted(offset for channel, offset in indexes.items() if channel in channel_ids):
        stream.seek(at)
        head = stream.read(_INDEX_HEAD.size)
        if len(head) < _INDEX_HEAD.size:
            return None
        opcode, _, _, size = _INDEX_HEAD.unpack(head)
        body = stream.read(size)
        if opcode != Opcode.MESSAGE_INDEX or size % _INDEX_ENTRY.itemsize or len(body) != size:
            return None
        found.append(np.frombuffer(body, _INDEX_ENTRY)["offset"])
    offsets = np.sort(np.concatenate(found))
    return offsets if np.all(offsets[1:] > offsets[:-1]) else None   # an offset twice is no index


def _chunk_messages(chunk: Chunk, channel_ids: Collection[int], offsets: np.ndarray | None) -> list[Message]:
    """The Message records of ``chunk`` on ``channel_ids``, in their order in the chunk. The chunk is
    decompressed and its CRC checked by mcap (``get_chunk_data_stream``, as ``breakup_chunk`` does);
    then only the wanted messages are built (most of a node's recording are outputs a replay does not
    read): those at ``offsets`` (``_indexed_offsets``), or, without them or where they do not point at
    such a message, those the records split by their heads hold. Raises ValueError for a record that
    runs past the chunk's end."""
    data_stream, size = get_chunk_data_stream(chunk, validate_crc=True)
    data = data_stream.read(size)
    if offsets is not None:
        indexed = _messages_at(data, offsets.tolist(), channel_ids)
        if indexed is not None:
            return indexed
    messages = []
    position = 0
    while position < size:
        if size - position < _RECORD_HEAD.size:
            raise ValueError(f"a record head at byte {position} of the chunk is cut off")
        opcode, length = _RECORD_HEAD.unpack_from(data, position)
        body = position + _RECORD_HEAD.size
        position = body + length
        if position > size:
            raise ValueError(f"a record at byte {body - _RECORD_HEAD.size} runs past the chunk's end")
        if opcode == Opcode.MESSAGE:
            if length < _MESSAGE_HEAD.size:
                raise ValueError(f"a message record at byte {body - _RECORD_HEAD.size} is shorter than its head")
            channel_id, sequence, log_time, publish_time = _MESSAGE_HEAD.unpack_from(data, body)
            if channel_id in channel_ids:
                messages.append(Message(channel_id=channel_id, log_time=log_time, publish_time=publish_time,
                                        sequence=sequence, data=data[body + _MESSAGE_HEAD.size:position]))
    return messages


def _messages_at(data: bytes, offsets: list[int], channel_ids: Collection[int]) -> list[Message] | None:
    """The Message records at ``offsets`` of the chunk's records ``data``; None if one is not a whole
    Message record on ``channel_ids`` there."""
    messages = []
    size = len(data)
    for position in offsets:
        body = position + _RECORD_HEAD.size
        if body + _MESSAGE_HEAD.size > size:
            return None
        opcode, length = _RECORD_HEAD.unpack_from(data, position)
        end = body + length
        if opcode != Opcode.MESSAGE or length < _MESSAGE_HEAD.size or end > size:
            return None
        channel_id, sequence, log_time, publish_time = _MESSAGE_HEAD.unpack_from(data, body)
        if channel_id not in channel_ids:
            return None
        messages.append(Message(channel_id=channel_id, log_time=log_time, publish_time=publish_time,
                                sequence=sequence, data=data[body + _MESSAGE_HEAD.size:end]))
    return messages


def _message_count(chunk: Any) -> str:
    """How many message records a damaged chunk's bytes hold, if they can be split at all."""
    if chunk is None:
        return "an unknown number of"
    try:
        return str(sum(1 for record in breakup_chunk(chunk, validate_crc=False) if isinstance(record, Message)))
    except Exception:  # noqa: BLE001 - the bytes do not even split into records
        return "an unknown number of"


def _joint_columns(rows: list[tuple[int, int, Any]]) -> JointStateColumns:
    names = tuple(dict.fromkeys(n for _, _, msg in rows for n in msg.name))
    column = {n: i for i, n in enumerate(names)}
    position = np.full((len(rows), len(names)), np.nan)
    velocity = np.full((len(rows), len(names)), np.nan)
    for i, (_, _, msg) in enumerate(rows):
        index = [column[n] for n in msg.name]
        position[i, index[:len(msg.position)]] = msg.position
        velocity[i, index[:len(msg.velocity)]] = msg.velocity
    return JointStateColumns(
        stamp_ns=np.array([r[0] for r in rows], dtype=np.int64),
        log_time_ns=np.array([r[1] for r in rows], dtype=np.int64),
        names=names, position=position, velocity=velocity)


def _pressure_columns(rows: list[tuple[int, int, Any]]) -> PressureColumns:
    return PressureColumns(
        stamp_ns=np.array([r[0] for r in rows], dtype=np.int64),
        log_time_ns=np.array([r[1] for r in rows], dtype=np.int64),
        fluid_pressure=np.array([r[2].fluid_pressure for r in rows], dtype=float),
        variance=np.array([r[2].variance for r in rows], dtype=float))
