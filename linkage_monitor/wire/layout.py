"""Message layouts parsed from their `.msg` definitions: each type's fields in order, with their types,
array kinds, `.msg` default values and constants.

The definitions are the installed `.msg` files (``wire.definitions``: the package's own msg/*.msg and
those of std_msgs, sensor_msgs, ... under `<prefix>/share/<pkg>/msg/`), parsed by rosbags' typesys
(``get_types_from_msg``). Every encoder of ``wire`` walks these layouts: no field order is written
twice. No rclpy here.
"""

from __future__ import annotations

import functools
import re
from dataclasses import dataclass
from typing import Any, Mapping

from rosbags.typesys import get_types_from_msg
from rosbags.typesys.base import Nodetype

from .definitions import message_definition, msg_text

# primitive type -> (struct format, size); bool, byte and char are one byte as uint8
PRIMITIVES: dict[str, tuple[str, int]] = {
    "bool": ("B", 1), "byte": ("B", 1), "char": ("B", 1), "uint8": ("B", 1), "int8": ("b", 1),
    "int16": ("h", 2), "uint16": ("H", 2), "int32": ("i", 4), "uint32": ("I", 4), "float32": ("f", 4),
    "int64": ("q", 8), "uint64": ("Q", 8), "float64": ("d", 8),
}
# `type name default` lines of a .msg text (a constant has "=" instead: `type NAME=value`)
_DEFAULT = re.compile(r"^[ \t]*([a-z0-9]+)[ \t]+([a-z][a-z0-9_]*)[ \t]+([^\s=#][^#\n]*?)[ \t]*(?:#.*)?$", re.MULTILINE)


class LayoutError(ValueError):
    """A message type the wire layer cannot lay out, or values that do not fit its layout."""


@dataclass(frozen=True)
class Field:
    """One field of a message: ``kind`` a primitive (PRIMITIVES, "string") or a message type
    (``nested``, "pkg/msg/Type"); ``array`` None for one value, 0 for a sequence (bounded or not:
    the same bytes), n > 0 for a fixed array of n; ``default`` the `.msg` default of a scalar primitive."""

    name: str
    kind: str
    nested: bool
    array: int | None
    default: Any


@dataclass(frozen=True)
class MessageLayout:
    """A message type's fields in wire order and its constants (name -> value)."""

    type_name: str
    fields: tuple[Field, ...]
    constants: Mapping[str, Any]

    def field(self, name: str) -> Field:
        """The field called ``name`` (LayoutError naming the type if there is none)."""
        for field in self.fields:
            if field.name == name:
                return field
        raise LayoutError(f"{self.type_name} has no field {name!r}")


@functools.lru_cache(maxsize=None)
def layout(type_name: str) -> MessageLayout:
    """The layout of ``pkg/msg/Type`` from its installed definition (parsed once per process)."""
    return _parsed(type_name)[type_name]


def constants(type_name: str) -> Mapping[str, Any]:
    """The constants of ``pkg/msg/Type`` (e.g. Marker.ARROW), as its definition states them."""
    return layout(type_name).constants


@functools.lru_cache(maxsize=None)
def _parsed(type_name: str) -> dict[str, MessageLayout]:
    """Every type of ``type_name``'s full definition (itself and what it nests), laid out."""
    types = get_types_from_msg(message_definition(type_name), type_name)
    found = {}
    for name, (consts, fields) in types.items():
        defaults = _defaults(name)
        found[name] = MessageLayout(name, tuple(_field(f, node, defaults) for f, node in fields),
                                    {c: value for c, _, value in consts})
    return found


def _field(name: str, node: tuple[Any, Any], defaults: Mapping[str, Any]) -> Field:
    kind, detail = node
    array: int | None = None
    if kind in (Nodetype.ARRAY, Nodetype.SEQUENCE):
        array = detail[1] if kind == Nodetype.ARRAY else 0
        kind, detail = detail[0]
    if kind == Nodetype.NAME:
        return Field(name, detail, True, array, None)
    primitive = detail[0]
    if primitive not in PRIMITIVES and primitive != "string":
        raise LayoutError(f"field {name!r}: type {primitive!r} is not supported by the wire layer")
    return Field(name, primitive, False, array, defaults.get(name) if array is None else None)


def _defaults(type_name: str) -> dict[str, Any]:
    """The default values (`type name value`) of ``type_name``'s scalar numeric/bool fields."""
    found: dict[str, Any] = {}
    for kind, name, text in _DEFAULT.findall(msg_text(type_name)):
        if kind in PRIMITIVES:
            found[name] = (text.strip().lower() == "true") if kind == "bool" else \
                (float(text) if kind.startswith("float") else int(text, 0))
    return found
