"""Reading a message from its CDR bytes by its layout (``wire.layout``, parsed from the `.msg`
definition): field by field with ``cdr.Reader``, checked at every step (``CdrError`` names the field,
as ``header.frame_id``, and the byte).

A message reads as a flat dict keyed by field path (``header.stamp``, ``name``): a
builtin_interfaces/Time as an int of ns since the epoch, strings as str, float64 as float,
sequences of them as a list / tuple. The field kinds the monitor's inputs carry are read; a type
with others is a LayoutError when it is first read.
"""

from __future__ import annotations

import functools
from typing import Any, Callable

from .cdr import Reader
from .layout import Field, LayoutError, layout

TIME = "builtin_interfaces/msg/Time"
_Plan = tuple[tuple[str, Callable[[Reader], Any]], ...]


def read_message(type_name: str, data: bytes) -> dict[str, Any]:
    """The ``type_name`` message in ``data`` (its CDR bytes) by field path; CdrError if they are not one."""
    reader = Reader(data)
    return {path: read(reader) for path, read in _plan(type_name, "")}


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
    elif f.array == 0:
        if f.kind == "string":
            return lambda r: r.strings(what)
        if f.kind == "float64":
            return lambda r: r.float64s(what)
    raise LayoutError(f"{what}: {f.kind}{'' if f.array is None else '[]'} is not read by the wire layer")
