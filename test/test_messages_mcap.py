"""Each custom message, serialized by rclpy into an MCAP bag with its `ros2msg` schema
(nested definitions included) and `cdr` encoding, decodes back with readers we did not
write: mcap-ros2-support and rosbags."""

from __future__ import annotations

import math
from pathlib import Path

from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory
from rosbags.highlevel import AnyReader
from rosbags.typesys import Stores, get_typestore

from linkage_monitor.bag.writer import BagWriter
from support.messages import CUSTOM_TYPES, samples, to_dict

STAMP_NS = 1_763_000_000_123_456_789


def _plain(value):
    """A decoded message of either reader as nested dicts/lists of plain values."""
    if hasattr(value, "__dataclass_fields__") or hasattr(value, "__slots__") and not isinstance(
            value, (int, float, str, bytes)):
        fields = getattr(value, "__dataclass_fields__", None) or value.__slots__
        return {name: _plain(getattr(value, name)) for name in fields
                if name != "__msgtype__"}
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    if hasattr(value, "tolist"):
        return value.tolist()
    return value


def _same(decoded, expected) -> bool:
    if isinstance(expected, dict):
        return all(_same(decoded[k], v) for k, v in expected.items())
    if isinstance(expected, list):
        return len(decoded) == len(expected) and all(map(_same, decoded, expected))
    if isinstance(expected, float):
        return decoded == expected or (math.isnan(decoded) and math.isnan(expected))
    return decoded == expected


def _write(bag: Path) -> dict[str, dict]:
    expected = {}
    with BagWriter(bag) as writer:
        for name, msg in samples(11).items():
            writer.write(f"/samples/{name}", msg, STAMP_NS)
            expected[f"/samples/{name}"] = to_dict(msg)
    return expected


def test_mcap_ros2_support_decodes_every_custom_message(tmp_path):
    bag = tmp_path / "bag"
    expected = _write(bag)
    decoded = {}
    with open(next(bag.glob("*.mcap")), "rb") as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        for schema, channel, message, ros_msg in reader.iter_decoded_messages():
            assert schema.encoding == "ros2msg" and channel.message_encoding == "cdr"
            assert schema.name == "linkage_monitor/msg/" + channel.topic.rsplit("/", 1)[-1]
            assert message.publish_time == STAMP_NS
            decoded[channel.topic] = _plain(ros_msg)
    assert sorted(decoded) == sorted(expected)
    for topic, fields in expected.items():
        assert _same(decoded[topic], fields), topic


def test_rosbags_decodes_every_custom_message_from_embedded_schemas(tmp_path):
    bag = tmp_path / "bag"
    expected = _write(bag)
    decoded = {}
    # Stores.EMPTY: rosbags knows none of our types; it must build them from the schemas.
    with AnyReader([bag], default_typestore=get_typestore(Stores.EMPTY)) as reader:
        for connection, _, raw in reader.messages():
            assert connection.msgtype.startswith("linkage_monitor/msg/")
            decoded[connection.topic] = _plain(reader.deserialize(raw, connection.msgtype))
    assert sorted(decoded) == sorted(f"/samples/{name}" for name in CUSTOM_TYPES)
    for topic, fields in expected.items():
        assert _same(decoded[topic], fields), topic
