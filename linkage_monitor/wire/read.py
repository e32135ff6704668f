"""Reading a message from its CDR bytes by its layout (``wire.layout``, parsed from the `.msg`
definition): field by field with ``cdr.Reader``, checked at every step (``CdrError`` names the field,
as ``header.frame_id``, and the byte).

A message reads as a flat dict keyed by field path (``header.stamp``, ``name``): a
builtin_interfaces/Time as an int of ns since the epoch, strings as str, float64 as float,
sequences of them as a list / tuple. The field kinds the monitor's inputs carry are read; a type
with others is a LayoutError when it is first read.

A sensor's messages differ from one to the next in their numbers only: the same frame_id, joint
names and sequence lengths put every number at the same byte. So a message read field by field
leaves its ``Shape``: the bytes that are not numbers (the encapsulation, lengths, counts, texts,
padding) and where the numbers are. A later message of the same size whose other bytes are those
bytes is read with one ``struct`` call; any other is read field by field (and leaves its shape).
The two readings give the same dict (test_sensor_messages.py).
"""

from __future__ import annotations

import functools
import re
import struct
from typing import Any, Callable, NamedTuple, Sequence

import numpy as np

from .cdr import Reader
from .layout import Field, LayoutError, layout

TIME = "builtin_interfaces/msg/Time"
_Plan = tuple[tuple[str, Callable[[Reader], Any]], ...]
_NS = 1_000_000_000
SHAPES_KEPT = 4      # shapes kept per message type and size (a few sensors of one type on several topics)
SIZES_KEPT = 256     # message types and sizes whose shapes are kept (the cache is emptied beyond)


def read_message(type_name: str, data: bytes) -> dict[str, Any]:
    """The ``type_name`` message in ``data`` (its CDR bytes) by field path; CdrError if they are not one."""
    shapes = _SHAPES.get((type_name, len(data)))
    if shapes is not None:
        for shape in shapes:
            if int.from_bytes(data[:shape.end], "little") & shape.mask == shape.skeleton:
                return shape.read(data)
    return _read_whole(type_name, data)


class Block(NamedTuple):
    """Messages of one type and size read at once by a shape (``read_block``): ``fits`` (n,) whether each
    has the shape's bytes (the others are not read: their values below are not theirs); ``values``
    by field path as ``read_message``'s, a column each: a time int64 ns (n,), a float (n,), floats
    (n, k); a field of the shape's own bytes (texts, an empty sequence) its one value."""

    fits: np.ndarray
    values: dict[str, Any]


def read_block(type_name: str, datas: Sequence[bytes]) -> Block | None:
    """The ``type_name`` messages ``datas`` (their CDR bytes, all of one size) read at once by the shape
    of the first (one a message of that type and size read before left, ``read_message``); None when
    there is none."""
    first = datas[0] if datas else b""
    shape = next((shape for shape in _SHAPES.get((type_name, len(first)), ())
                  if int.from_bytes(first[:shape.end], "little") & shape.mask == shape.skeleton), None)
    if shape is None:
        return None
    size, n = len(datas[0]), len(datas)
    joined = b"".join(datas)
    rows = np.frombuffer(joined, np.uint8).reshape(n, size)
    mask = np.frombuffer(shape.mask.to_bytes(shape.end, "little"), np.uint8)
    skeleton = np.frombuffer(shape.skeleton.to_bytes(shape.end, "little"), np.uint8)
    fits = ((rows[:, :shape.end] & mask) == skeleton).all(axis=1)

    def column(code: str, offset: int, count: int = 1) -> np.ndarray:
        dtype = np.dtype(code)
        return np.ndarray((n, count), dtype, joined, offset, (size, dtype.itemsize))

    offsets = _offsets(shape.numbers.format)
    values: dict[str, Any] = {}
    k = 0
    for field in shape.fields:
        if field.kind == "same":
            values[field.path] = field.value
        elif field.kind == "time":
            values[field.path] = (column("<i4", offsets[k])[:, 0].astype(np.int64) * _NS
                                  + column("<u4", offsets[k + 1])[:, 0].astype(np.int64))
        elif field.kind == "float":
            values[field.path] = column("<f8", offsets[k])[:, 0]
        else:
            values[field.path] = column("<f8", offsets[k], field.numbers)
        k += field.numbers
    return Block(fits, values)


@functools.lru_cache(maxsize=SIZES_KEPT)
def _offsets(layout: str) -> tuple[int, ...]:
    """The byte offset of each number a ``Shape``'s struct format (``<``, ``Nx``, ``i``, ``I``, ``Nd``) unpacks."""
    found, at = [], 0
    for count, code in re.findall(r"(\d*)([xiId])", layout):
        many = int(count or 1)
        if code == "x":
            at += many
            continue
        width = 4 if code in "iI" else 8
        found += [at + width * j for j in range(many)]
        at += width * many
    return tuple(found)


class ShapeField(NamedTuple):
    """How a ``Shape`` makes one field's value from its next ``numbers``: ``kind`` "time" (2: sec,
    nanosec), "float" (1), "floats" (a tuple of them), or "same" (0; ``value``: a text, texts or an
    empty sequence, as read)."""

    path: str
    kind: str
    numbers: int
    value: Any


class Shape(NamedTuple):
    """What one message's bytes say of every message of its type and size that has the same bytes
    where it has neither numbers nor alignment padding: ``skeleton`` those bytes up to the end of its
    last field (as one little-endian integer, every other byte 0), ``mask`` 0xff at those bytes and 0 at
    the others, ``end`` that end; ``numbers`` the struct that unpacks the numbers (every other byte
    skipped), ``fields`` how each field's value is made from them."""

    skeleton: int
    mask: int
    end: int
    numbers: struct.Struct
    fields: tuple[ShapeField, ...]

    def read(self, data: bytes) -> dict[str, Any]:
        """The message in ``data``, whose bytes are the shape's where its numbers are not."""
        numbers = self.numbers.unpack_from(data)
        values: dict[str, Any] = {}
        k = 0
        for field in self.fields:
            kind = field.kind
            if kind == "same":
                values[field.path] = list(field.value) if isinstance(field.value, list) else field.value
            elif kind == "time":
                values[field.path] = numbers[k] * _NS + numbers[k + 1]
            elif kind == "float":
                values[field.path] = numbers[k]
            else:
                values[field.path] = numbers[k:k + field.numbers]
            k += field.numbers
        return values


_SHAPES: dict[tuple[str, int], list[Shape]] = {}   # (type name, size) -> the shapes read last, newest first


class _Number(NamedTuple):
    """Where a field's numbers lie in a message: byte ``offset``, their ``struct`` code, how ``many``."""

    offset: int
    code: str
    many: int


class _Tracer(Reader):
    """A Reader that notes where the numbers it reads lie (``_Number``), and which bytes are alignment
    padding (whatever the writer left there): (start, end)."""

    def __init__(self, data: bytes) -> None:
        super().__init__(data)
        self.numbers: list[_Number] = []
        self.padding: list[tuple[int, int]] = []

    def _take(self, size: int, what: str, align: int) -> int:
        before = self.offset
        start = super()._take(size, what, align)
        if start > before:
            self.padding.append((before, start))
        return start

    def time_ns(self, what: str = "stamp") -> int:
        value = super().time_ns(what)
        self.numbers.append(_Number(self.offset - 8, "iI", 2))
        return value

    def float64(self, what: str) -> float:
        value = super().float64(what)
        self.numbers.append(_Number(self.offset - 8, "d", 1))
        return value

    def float64_array(self, what: str, count: int) -> tuple[float, ...]:
        values = super().float64_array(what, count)
        self.numbers.append(_Number(self.offset - 8 * count, f"{count}d", count))
        return values

    def float64s(self, what: str) -> tuple[float, ...]:
        values = super().float64s(what)
        if values:
            self.numbers.append(_Number(self.offset - 8 * len(values), f"{len(values)}d", len(values)))
        return values


def _read_whole(type_name: str, data: bytes) -> dict[str, Any]:
    """``read_message`` field by field; the message's shape kept (little-endian payloads)."""
    reader = _Tracer(data)
    values: dict[str, Any] = {}
    fields: list[ShapeField] = []
    for path, read in _plan(type_name, ""):
        before = len(reader.numbers)
        values[path] = read(reader)
        if len(reader.numbers) == before:
            fields.append(ShapeField(path, "same", 0, values[path]))
        else:
            last = reader.numbers[-1]
            fields.append(ShapeField(path, {"iI": "time", "d": "float"}.get(last.code, "floats"), last.many, None))
    if reader.order == "<":
        _keep(type_name, data, reader, tuple(fields))
    return values


def _keep(type_name: str, data: bytes, reader: _Tracer, fields: tuple[ShapeField, ...]) -> None:
    """Keep the shape of the message ``data`` as ``reader`` read it."""
    end = reader.offset
    mask = bytearray(b"\xff" * end)
    codes, at = ["<"], 0
    for number in reader.numbers:
        codes += [f"{number.offset - at}x"] * (number.offset > at) + [number.code]
        at = number.offset + 8 * (1 if number.code == "iI" else number.many)
        mask[number.offset:at] = bytes(at - number.offset)
    for start, stop in reader.padding:
        mask[start:stop] = bytes(stop - start)
    mask_int = int.from_bytes(mask, "little")
    if len(_SHAPES) >= SIZES_KEPT:
        _SHAPES.clear()
    shapes = _SHAPES.setdefault((type_name, len(data)), [])
    shapes.insert(0, Shape(int.from_bytes(data[:end], "little") & mask_int, mask_int, end,
                           struct.Struct("".join(codes)), fields))
    del shapes[SHAPES_KEPT:]


@functools.lru_cache(maxsize=None)
def _plan(type_name: str, prefix: str) -> _Plan:
    """How each field of ``type_name`` is read, in wire order, by path (``prefix`` + field name); a
    nested message's fields in its place."""
    plan: list[tuple[str, Callable[[Reader], Any]]] = []
    for f in layout(type_name).fields:
        path = prefix + f.name
        if f.nested and f.array is None and f.kind != TIME:
            plan += _plan(f.kind, path + ".")
        else:
            plan.append((path, _field(f, path)))
    return tuple(plan)


def _field(f: Field, what: str) -> Callable[[Reader], Any]:
    if f.array is None:
        if f.kind == TIME:
            return lambda r: r.time_ns(what)
        if f.kind == "string":
            return lambda r: r.string(what)
        if f.kind == "float64":
            return lambda r: r.float64(what)
    elif f.array > 0 and f.kind == "float64":   # a fixed array (Imu's covariances)
        count = f.array
        return lambda r: r.float64_array(what, count)
    elif f.array == 0:
        if f.kind == "string":
            return lambda r: r.strings(what)
        if f.kind == "float64":
            return lambda r: r.float64s(what)
    raise LayoutError(f"{what}: {f.kind}{'' if f.array is None else '[]'} is not read by the wire layer")
