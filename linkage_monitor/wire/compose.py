"""Writing a message's CDR bytes by walking its layout (``wire.layout``, parsed from the `.msg`
definitions): the values are given by field name, the order, types, alignment and sequence counts
come from the definition.

Values: a Mapping (field name -> value) for a nested message, a list for a sequence or fixed array
(bytes for one of uint8 / byte), Python numbers, bools and str for primitives (a ``byte`` also as a
1-byte bytes, as rclpy); a builtin_interfaces/Time or Duration also as an int of ns. A field
without a value takes its `.msg` default (zero, empty) — or, with ``strict``, is a LayoutError
naming it, so that a field added to a definition cannot go out unset.

Some values are placeholders that make the bytes a template (``Template``, ``ros`` hot paths): a
``Column(k)`` float64 filled per message from column k of a source row, a ``Flag(k)`` uint8 / bool
filled per message, ``STAMP`` a Time filled per message (its byte offset recorded), a ``Spliced``
string whose serialization is cut out and spliced in per message (``spliced``: start and end).
"""

from __future__ import annotations

import functools
import struct
from typing import Any, Mapping, NamedTuple, Sequence

from .cdr import Writer, string_bytes, time_bytes
from .layout import PRIMITIVES, Field, LayoutError, layout

_STRUCTS = {kind: struct.Struct("<" + fmt) for kind, (fmt, _) in PRIMITIVES.items()}
_TIMES = frozenset({"builtin_interfaces/msg/Time", "builtin_interfaces/msg/Duration"})
_ZEROS = [bytes(n) for n in range(8)]
_MISSING = object()


class Column(NamedTuple):
    """A float64 placeholder: filled per message from column ``at`` of a source row."""

    at: int


class Flag(NamedTuple):
    """A uint8 / bool placeholder: filled per message with flag number ``at``."""

    at: int


class Spliced(NamedTuple):
    """A string placeholder: ``text`` (of the serialized size the real text will have modulo the
    alignment that follows) is cut out and the real text spliced in per message."""

    text: str


class _Stamp:
    """A builtin_interfaces/Time placeholder, filled per message."""

    def __repr__(self) -> str:
        return "STAMP"


STAMP = _Stamp()


class Composer:
    """Writes messages by their layouts into one payload and records where the placeholders are."""

    def __init__(self, data: bytearray | None = None, strict: bool = False) -> None:
        self.writer = Writer(data)
        self.strict = strict
        self.columns: list[tuple[int, int]] = []   # (byte offset of a float64, source column)
        self.flags: list[tuple[int, int]] = []     # (byte offset of a uint8, flag index)
        self.stamps: list[int] = []                # byte offsets of Time placeholders
        self.spliced: list[tuple[int, int]] = []   # (start, end) of Spliced strings' serializations

    @property
    def data(self) -> bytearray:
        """The payload written so far (encapsulation header first)."""
        return self.writer.data

    def message(self, type_name: str, values: Mapping[str, Any], start: str | None = None,
                stop: str | None = None) -> "Composer":
        """Write ``type_name``'s fields from ``values`` — all of them, or those from the field
        ``start`` up to (not including) the field ``stop``: a message written in two parts, the second
        after the first in the same payload (alignment counts from the payload start)."""
        plan = _plan(type_name)
        if not plan.names.issuperset(values):
            raise LayoutError(f"{type_name} has no field(s) {', '.join(sorted(set(values) - plan.names))}")
        fields = plan.fields
        if start is not None or stop is not None:
            fields = fields[plan.position[start] if start is not None else 0:
                            plan.position[stop] if stop is not None else len(fields)]
        for field, default in fields:
            value = values.get(field.name, _MISSING)
            if value is _MISSING:
                if self.strict:
                    raise LayoutError(f"no value for {type_name}.{field.name}")
                value = default
            if field.array is None and field.kind == "string" and type(value) is str:   # the common case, inline
                data = self.writer.data
                pad = (4 - len(data)) % 4
                if pad:
                    self.writer.padding.append((len(data), len(data) + pad))
                    data += _ZEROS[pad]
                data += string_bytes(value)
            else:
                self._field(type_name, field, value)
        return self

    def _field(self, owner: str, field: Field, value: Any) -> None:
        if field.array is None:
            self._one(owner, field, value)
            return
        if field.array == 0:
            self.writer.uint32(len(value))
        elif len(value) != field.array:
            raise LayoutError(f"{owner}.{field.name}: {len(value)} values for a fixed array of {field.array}")
        if not field.nested and field.kind in PRIMITIVES and not _has_placeholder(value):
            if len(value):   # an empty sequence is not aligned (Fast CDR)
                fmt, size = PRIMITIVES[field.kind]
                self.writer.align(size)
                self.writer.data += value if isinstance(value, (bytes, bytearray)) else \
                    struct.pack(f"<{len(value)}{fmt}", *value)
            return
        if field.nested and field.kind not in _TIMES:
            for item in value:
                self.message(field.kind, item)
            return
        for item in value:
            self._one(owner, field, item)

    def _one(self, owner: str, field: Field, value: Any) -> None:
        w = self.writer
        if field.nested:
            if field.kind in _TIMES and (value is STAMP or isinstance(value, int)):
                w.align(4)
                if isinstance(value, _Stamp):
                    self.stamps.append(len(w.data))
                w.data += time_bytes(0 if isinstance(value, _Stamp) else value)
            else:
                self.message(field.kind, value)
        elif field.kind == "string":
            w.align(4)
            if isinstance(value, Spliced):
                start = len(w.data)
                w.data += string_bytes(value.text)
                self.spliced.append((start, len(w.data)))
            else:
                w.data += string_bytes(value)
        else:
            size = PRIMITIVES[field.kind][1]
            w.align(size)
            if isinstance(value, Column):
                self.columns.append((len(w.data), value.at))
                value = 0.0
            elif isinstance(value, Flag):
                self.flags.append((len(w.data), value.at))
                value = 0
            elif isinstance(value, (bytes, bytearray)):
                value = value[0]
            w.data += _STRUCTS[field.kind].pack(value)


def encode(type_name: str, values: Mapping[str, Any], strict: bool = False) -> bytes:
    """The CDR bytes (encapsulation header first) of a ``type_name`` message of ``values``."""
    return bytes(Composer(strict=strict).message(type_name, values).data)


class _Plan(NamedTuple):
    """A type's fields with their values when none is given, and its field names."""

    fields: tuple[tuple[Field, Any], ...]
    names: frozenset[str]
    position: dict[str, int]


@functools.lru_cache(maxsize=None)
def _plan(type_name: str) -> _Plan:
    fields = layout(type_name).fields
    return _Plan(tuple((f, _default(f)) for f in fields), frozenset(f.name for f in fields),
                 {f.name: k for k, f in enumerate(fields)})


def _default(field: Field) -> Any:
    """A field's value when none is given: its `.msg` default, else zero / empty."""
    if field.array == 0:
        return []
    if field.array:
        return [_default(Field(field.name, field.kind, field.nested, None, None))] * field.array
    if field.nested:
        return {}
    if field.kind == "string":
        return ""
    return field.default if field.default is not None else 0


def _has_placeholder(values: Sequence[Any]) -> bool:
    return not isinstance(values, (bytes, bytearray)) and any(isinstance(v, (Column, Flag)) for v in values)

