"""ROS 2 message definitions (`ros2msg` schema text) as rosbag2 embeds them in MCAP files.

`exact_cdr` cuts a CDR payload to the bytes its definition describes. No rclpy here: the `.msg` files are read from the installed share directories
(`<prefix>/share/<pkg>/msg/<Type>.msg`), the same place `ros2 bag record` reads them from.
"""

from __future__ import annotations

import functools
import os
import re
import sys
from pathlib import Path
from typing import Any

from rosbags.typesys import Stores, get_types_from_msg, get_typestore

# rosbag2_cpp local_message_definition_source.cpp: MSG_FIELD_TYPE_REGEX and PRIMITIVE_TYPES.
# The first word of every non-comment line is a field or constant type ("pkg/Type", "Type",
# with an optional "[..]" array suffix); bounded strings ("string<=8") never match.
_FIELD_TYPE = re.compile(r"(?:^|\n)\s*([a-zA-Z0-9_/]+)(?:\[[^\]]*\])?\s+")
_PRIMITIVES = frozenset({
    "bool", "byte", "char", "float32", "float64", "int8", "uint8", "int16", "uint16",
    "int32", "uint32", "int64", "uint64", "string",
})
_NAME = r"[a-zA-Z][a-zA-Z0-9_]*"
_TYPE_NAME = re.compile(rf"^({_NAME})/(?:({_NAME})/)?({_NAME})$")
_DELIMITER = "=" * 80 + "\n"
_MAX_DEPTH = 50  # rosbag2's ROSBAG2_CPP_LOCAL_MESSAGE_DEFINITION_SOURCE_MAX_RECURSION_DEPTH


class MessageDefinitionError(LookupError):
    """A message type's `.msg` file cannot be found or its name is not `pkg/msg/Type`."""


def share_prefixes() -> list[Path]:
    """Return the install prefixes searched for `share/<pkg>/msg/*.msg`, in search order.

    `$AMENT_PREFIX_PATH` entries first (as ament_index does), then this Python's prefix
    (the venv, where the ROS wheels and our own package install their share/ files).
    """
    prefixes = [Path(p) for p in os.environ.get("AMENT_PREFIX_PATH", "").split(os.pathsep) if p]
    prefixes.append(Path(sys.prefix))
    return list(dict.fromkeys(prefixes))


def msg_file(type_name: str) -> Path:
    """Return the path of the installed `.msg` file of `pkg/msg/Type` (or `pkg/Type`)."""
    match = _TYPE_NAME.match(type_name)
    if match is None:
        raise MessageDefinitionError(
            f"message type {type_name!r} is not of the form 'pkg/msg/Type' or 'pkg/Type'")
    package, interface, name = match.group(1), match.group(2) or "msg", match.group(3)
    prefixes = share_prefixes()
    for prefix in prefixes:
        candidate = prefix / "share" / package / interface / f"{name}.msg"
        if candidate.is_file():
            return candidate
    searched = ", ".join(str(p / "share" / package / interface) for p in prefixes)
    raise MessageDefinitionError(
        f"no {name}.msg for message type {type_name!r} in {searched}: install the package "
        f"{package!r} into this environment or add its install prefix to AMENT_PREFIX_PATH")


@functools.lru_cache(maxsize=None)
def msg_text(type_name: str) -> str:
    """The text of the installed `.msg` file of `pkg/msg/Type`."""
    return msg_file(type_name).read_text(encoding="utf-8")


def dependencies(text: str, package: str) -> list[str]:
    """Return the non-primitive field types of `.msg` text as sorted `pkg/Type` names.

    Types without a package are resolved in `package`. Sorted like rosbag2's std::set.
    """
    found = set()
    for match in _FIELD_TYPE.finditer(text):
        field_type = match.group(1)
        if field_type in _PRIMITIVES:
            continue
        found.add(field_type if "/" in field_type else f"{package}/{field_type}")
    return sorted(found)


@functools.lru_cache(maxsize=None)
def message_definition(type_name: str) -> str:
    """Return the `ros2msg` schema text of `type_name` exactly as rosbag2 writes it.

    The type's `.msg` text, then for every nested type (depth-first, each once, in sorted
    order within a level) a newline, a line of 80 '=', 'MSG: pkg/Type' and its `.msg` text
    (rosbag2_cpp LocalMessageDefinitionSource::get_full_text).
    """
    seen: set[str] = set()

    def append(name: str, depth: int) -> str:
        if depth <= 0:
            raise MessageDefinitionError(
                f"message type {type_name!r} nests deeper than {_MAX_DEPTH} levels (cycle?)")
        text = msg_text(name)
        package = name.split("/", 1)[0]
        for dependency in dependencies(text, package):
            if dependency not in seen:
                seen.add(dependency)
                text += "\n" + _DELIMITER + f"MSG: {dependency}\n" + append(dependency, depth - 1)
        return text

    return append(type_name, _MAX_DEPTH)


@functools.lru_cache(maxsize=None)
def _cdr_decoder(type_name: str) -> tuple[Any, Any]:
    store = get_typestore(Stores.EMPTY)
    store.register(get_types_from_msg(message_definition(type_name), type_name))
    return store, store.get_msgdef(type_name)


def exact_cdr(type_name: str, data: bytes) -> bytes:
    """Return `data` (a CDR payload of `type_name`) cut to the bytes the message occupies.

    `rclpy.serialization.serialize_message` (Kilted wheels, rmw_fastrtps) returns a buffer
    of the *estimated* size: up to several bytes of uninitialised memory follow the message.
    Wire data recorded by rosbag2 has at most 3 padding bytes, and rosbags rejects more
    ("CDR message size mismatch"). The length comes from decoding `data` with the message
    definition embedded in the bag, which also checks that the two agree.
    """
    store, msgdef = _cdr_decoder(type_name)
    decode = msgdef.deserialize_cdr_le if data[1] else msgdef.deserialize_cdr_be
    try:
        _, end = decode(data[4:], 0, msgdef.cls, store)
    except Exception as exc:  # struct.error, UnicodeDecodeError, ValueError, IndexError
        raise ValueError(f"CDR payload of {len(data)} bytes does not decode as {type_name} "
                         f"with the installed definition {msg_file(type_name)}: {exc}") from exc
    return data[:4 + end]
