"""A long bag for the replay's memory and rate: the bundled bag's inputs played again and again.

Run: .venv/bin/python bench/long_bag.py OUT --inputs N [--source BAG]
Writes OUT/<OUT name>_0.mcap: the source bag's mechanism description and first configuration (as
recorded), then its input messages (the JointState and FluidPressure topics) repeated until N
inputs, each repetition shifted in time by the source's input span plus the mean input period
(log times, publish times and the header stamps in the CDR bytes alike), so that every stamp is
newer than the one before on its topic and the monitor takes every repetition as new inputs.
The source's outputs are not copied (a replay writes its own).
"""

from __future__ import annotations

import argparse
import struct
import sys
from dataclasses import dataclass
from pathlib import Path

from mcap.reader import make_reader
from mcap.writer import CompressionType, Writer

BAG = Path(__file__).resolve().parent.parent / "bags" / "belarus_1221_lift_transport"
SETUP_TOPICS = ("/linkage_monitor/mechanism", "/linkage_monitor/config")
INPUT_TYPES = ("sensor_msgs/msg/JointState", "sensor_msgs/msg/FluidPressure")
STAMP = struct.Struct("<iI")   # std_msgs/Header.stamp (sec, nanosec) right after the 4-byte CDR encapsulation
STAMP_AT = 4


@dataclass(frozen=True)
class Recorded:
    """One message of the source: its channel id (in the new file), times (ns) and CDR bytes."""

    channel: int
    log_time_ns: int
    publish_time_ns: int
    data: bytes


def shifted(data: bytes, shift_ns: int) -> bytes:
    """``data`` (a little-endian CDR message starting with a std_msgs/Header) with its stamp moved by ``shift_ns``."""
    sec, nanosec = STAMP.unpack_from(data, STAMP_AT)
    stamp = sec * 10**9 + nanosec + shift_ns
    return data[:STAMP_AT] + STAMP.pack(stamp // 10**9, stamp % 10**9) + data[STAMP_AT + STAMP.size:]


def write_long_bag(source: Path, out: Path, inputs: int) -> Path:
    """``out``/<out name>_0.mcap holding ``inputs`` input messages (see the module's docstring)."""
    out.mkdir(parents=True, exist_ok=True)
    path = out / f"{out.name}_0.mcap"
    with open(next(source.glob("*.mcap")), "rb") as f, open(path, "wb") as target:
        writer = Writer(target, compression=CompressionType.ZSTD)
        writer.start(profile="ros2", library="bench/long_bag.py")
        schemas: dict[int, int] = {}
        channels: dict[int, int] = {}
        setup: list[Recorded] = []
        recorded: list[Recorded] = []
        for schema, channel, message in make_reader(f).iter_messages(log_time_order=True):
            is_input = schema is not None and schema.name in INPUT_TYPES
            if not is_input and channel.topic not in SETUP_TOPICS:
                continue
            if schema is not None and schema.id not in schemas:
                schemas[schema.id] = writer.register_schema(schema.name, schema.encoding, schema.data)
            if channel.id not in channels:
                channels[channel.id] = writer.register_channel(channel.topic, channel.message_encoding,
                                                               schemas.get(channel.schema_id, 0), channel.metadata)
            row = Recorded(channels[channel.id], message.log_time, message.publish_time, message.data)
            (recorded if is_input else setup).append(row)
        setup = [next(r for r in setup if r.channel == c) for c in dict.fromkeys(r.channel for r in setup)]
        for row in setup:
            writer.add_message(row.channel, row.log_time_ns, row.data, row.publish_time_ns)
        span = recorded[-1].log_time_ns - recorded[0].log_time_ns
        period = span // max(len(recorded) - 1, 1)
        written, repetition = 0, 0
        while written < inputs:
            shift = repetition * (span + period)
            for row in recorded[:inputs - written]:
                writer.add_message(row.channel, row.log_time_ns + shift, shifted(row.data, shift),
                                   row.publish_time_ns + shift)
            written += min(len(recorded), inputs - written)
            repetition += 1
        writer.finish()
    return path


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("out", type=Path, help="the new bag's directory")
    parser.add_argument("--inputs", type=int, required=True, help="input messages to write")
    parser.add_argument("--source", type=Path, default=BAG, help=f"the bag to repeat (default {BAG.name})")
    args = parser.parse_args()
    print(write_long_bag(args.source, args.out, args.inputs))
    return 0


if __name__ == "__main__":
    sys.exit(main())
