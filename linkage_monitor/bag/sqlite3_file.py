"""Reading one rosbag2 sqlite3 file (`.db3`, rosbag2's default storage before Iron): tables `topics` and
`messages`, as rosbag2's sqlite3 storage plugin writes them."""

from __future__ import annotations

import sqlite3
from collections.abc import Collection, Iterator
from pathlib import Path
from typing import Any, NamedTuple

from linkage_monitor.bag.errors import BagError
from linkage_monitor.bag.faults import ReadFault, report
from linkage_monitor.wire.cdr import is_xcdr1
from linkage_monitor.wire.definitions import MessageDefinitionError, exact_cdr

TYPE_PROBES = 8   # first messages of a topic tried against its declared type: one that decodes clears it
_CDR_PADDING = 3   # bytes a rosbag2 CDR payload may hold after its message (alignment to 4)


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


def _connect(file: Path) -> sqlite3.Connection:
    """The file opened read-only."""
    return sqlite3.connect(f"{file.resolve().as_uri()}?mode=ro", uri=True)


def sqlite3_first_log_time(file: Path) -> int | None:
    """The receive time (ns since the epoch) of the file's first message; None when it holds none or
    that cannot be read."""
    try:
        connection = _connect(file)
        try:
            first = connection.execute("SELECT MIN(timestamp) FROM messages").fetchone()[0]
        finally:
            connection.close()
    except sqlite3.Error:
        return None
    return int(first) if first is not None else None


def sqlite3_messages(file: Path, topics: Collection[str] | None) -> Iterator[tuple[Any, Any, Any]]:
    """The (schema, channel, message) records of one rosbag2 sqlite3 file, in receive-time order (then
    insertion order), as the MCAP reader gives them. The storage keeps one time per message, the receive
    time: it stands for the publish time too. The file holds no definitions, only each topic's type name:
    a topic whose messages are not its declared type (``_declared_type_fails``) is left out, named once
    in a ``ReadFault``."""
    query = ("SELECT topics.name, topics.type, topics.serialization_format, messages.timestamp, messages.data "
             "FROM messages JOIN topics ON messages.topic_id = topics.id")
    wanted = list(topics) if topics is not None else None
    if wanted is not None:
        query += f" WHERE topics.name IN ({', '.join('?' * len(wanted))})"
    query += " ORDER BY messages.timestamp, messages.id"
    try:
        connection = _connect(file)
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
            report(ReadFault(str(file), "type_mismatch", None, count,
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
