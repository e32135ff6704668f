"""Read rosbag2 bags (ours, `ros2 bag record`, rosbags) back into rclpy messages.

Every rosbag2 storage: MCAP files and sqlite3 files (`.db3`, rosbag2's default storage before
Iron), one file or a split bag (several storage files listed in one metadata.yaml, read one after
the other as one bag; ``bag.storage``). A ROS 1 `.bag` is refused with the command that converts it.

`read_bag` yields decoded messages one by one (a message that does not decode as its type is
left out with a warning in the log). A message recorded with another definition of its type than
the installed one (an MCAP file's schema record carries the definition it was written with, e.g.
a HitchState from before `min_transmission_angle`) is decoded by the recorded definition and
handed over as the installed class: fields of the same name copied, a float field the recording
lacks NaN (not known), any other one its default (``bag.decode``); `read_bag_raw` yields their bytes
undecoded (the replay reads its inputs itself and reports an unreadable one as the node does); `read_inputs`
gathers the sensor topics the solver needs (JointState, FluidPressure) into numpy columns (``bag.columns``).
A bag whose writer was killed, or a file cut mid-record (an interrupted copy, a dying card), is
read record by record up to its last complete record (``bag.mcap_file``). What cannot be read as recorded is a
``ReadFault`` naming the file, the byte and the messages (a cut, a chunk that fails its CRC, a file
metadata.yaml does not list, a sqlite3 topic that is not its declared type): logged as a warning,
and collected by ``read_faults()`` for a caller that reports them (fleet's rows; ``bag.faults``).
"""

from __future__ import annotations

import os
from collections.abc import Collection, Iterator
from typing import Any, NamedTuple

from linkage_monitor.bag.columns import JointStateColumns, PressureColumns, joint_columns, pressure_columns
from linkage_monitor.bag.decode import BagMessage, Undecoded, decoded, undecoded_lines
from linkage_monitor.bag.errors import BagError
from linkage_monitor.bag.faults import log
from linkage_monitor.bag.mcap_file import MessageColumns, blocks_of, mcap_columns
from linkage_monitor.bag.storage import raw_messages, storage_files, storage_of
from linkage_monitor.wire.sensor_messages import FLUID_PRESSURE, JOINT_STATE


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
        for schema, channel, message in raw_messages(file, topics):
            yield RawMessage(channel.topic, schema.name if schema is not None else "", message.publish_time,
                             message.log_time, message.data)


def read_bag_raw_blocks(path: str | os.PathLike[str], topics: Collection[str] | None = None
                        ) -> Iterator[MessageColumns]:
    """``read_bag_raw``'s messages in its order, as blocks of columns: an MCAP file's (``mcap_columns``: a
    chunk at a time, no object per message but its bytes, when it is indexed), a sqlite3 file's
    ``blocks_of`` its records."""
    for file in storage_files(path):
        yield from (mcap_columns(file, topics) if storage_of(file) == "mcap" else
                    blocks_of(raw_messages(file, topics)))


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
        log.warning("%s", line)
    return {topic: (joint_columns(r) if kinds[topic] == JOINT_STATE else pressure_columns(r))
            for topic, r in rows.items()}


def _messages(path: str | os.PathLike[str], topics: Collection[str] | None,
              types: Collection[str] | None, undecoded: Undecoded | None = None
              ) -> Iterator[BagMessage]:
    """The decoded messages of every storage file; those that do not decode are left out, counted in
    ``undecoded`` when given (the caller reports them), else logged as one warning per topic."""
    for file in storage_files(path):
        left_out: Undecoded = {} if undecoded is None else undecoded
        yield from decoded(file, topics, types, left_out)
        if undecoded is None:
            for line in undecoded_lines(left_out):
                log.warning("%s", line)
