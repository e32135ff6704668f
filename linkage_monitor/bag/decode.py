"""A bag's messages decoded into rclpy messages: by the installed definition of their type, or by the
definition the bag recorded (an MCAP schema record) where that differs, handed over as the installed class
(fields of the same name copied, a float field the recording lacks NaN, any other one its default)."""

from __future__ import annotations

import functools
import importlib
import math
from collections.abc import Collection, Iterator
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np
from rclpy.serialization import deserialize_message
from rosbags.typesys import Stores, get_types_from_msg, get_typestore
from rosidl_parser.definition import AbstractNestedType, BasicType, NamespacedType

from linkage_monitor.bag.errors import BagError
from linkage_monitor.bag.faults import log
from linkage_monitor.bag.storage import raw_messages
from linkage_monitor.wire.cdr import stamp_ns
from linkage_monitor.wire.definitions import MessageDefinitionError, message_definition


class BagMessage(NamedTuple):
    """A decoded message of a bag (``read_bag``): its topic, type name `pkg/msg/Type`, header stamp
    (ns since the epoch; the MCAP publish_time without a header), log time (ns, the receive
    time) and the rclpy message."""

    topic: str
    type_name: str
    stamp_ns: int
    log_time_ns: int
    message: Any


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


Undecoded = dict[tuple[str, str, str], tuple[int, str]]   # (file, topic, type) -> (count, the first reason)


def undecoded_lines(undecoded: Undecoded) -> list[str]:
    """One sentence per topic of a file whose messages did not decode."""
    return [f"{file}: {count} message(s) on {topic} do not decode as {type_name} (the first: {reason}): left out"
            for (file, topic, type_name), (count, reason) in undecoded.items()]


def decoded(file: Path, topics: Collection[str] | None, types: Collection[str] | None,
            undecoded: Undecoded) -> Iterator[BagMessage]:
    """The decoded messages of one storage file (on ``topics``, of ``types``; None: all); the messages that
    do not decode counted in ``undecoded``."""
    recorded: dict[tuple[str, bytes], Any] = {}   # (type, schema text) -> its typestore when it is not the installed
    for schema, channel, message in raw_messages(file, topics):
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
                log.info("%s: %s is recorded with another definition of %s than the installed one: read by the "
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
