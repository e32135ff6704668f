"""Our CDR bytes against rclpy's: rclpy's buffer is cut to the message's exact length (rosbags'
decoder, wire.definitions.exact_cdr) and must equal ours byte for byte, except the alignment padding
bytes, which rclpy leaves uninitialised (ours are zero). Where the padding is comes from our
writer; a layout that differs from rclpy's shifts the data bytes after it, which then differ."""

from __future__ import annotations

from typing import Any

from rclpy.serialization import serialize_message

from linkage_monitor.wire.compose import Composer
from linkage_monitor.wire.definitions import exact_cdr
from linkage_monitor.wire.layout import layout


def _rclpy_values(msg: Any, type_name: str) -> dict[str, Any]:
    """The values of an rclpy message, by its layout (the inverse of building it field by field)."""
    found: dict[str, Any] = {}
    for f in layout(type_name).fields:
        value = getattr(msg, f.name)
        if f.nested:
            value = [_rclpy_values(v, f.kind) for v in value] if f.array is not None else _rclpy_values(value, f.kind)
        elif f.kind == "byte":
            value = [v[0] for v in value] if f.array is not None else value[0]
        elif f.array is not None:
            value = list(value)
        found[f.name] = value
    return found


def assert_rclpy_bytes(type_name: str, ours: bytes, msg: Any) -> None:
    """``ours`` is serialize_message(msg) byte for byte, alignment padding aside (module docstring)."""
    theirs = bytearray(exact_cdr(type_name, serialize_message(msg)))
    composer = Composer().message(type_name, _rclpy_values(msg, type_name))
    assert bytes(composer.data) == ours, f"{type_name}: the template's bytes are not the layout's"
    for start, end in composer.writer.padding:
        assert ours[start:end] == bytes(end - start), (type_name, "padding not zero", start)
        theirs[start:end] = bytes(end - start)
    assert len(ours) == len(theirs), (type_name, len(ours), len(theirs))
    differ = [k for k in range(len(ours)) if ours[k] != theirs[k]]
    assert not differ, f"{type_name}: bytes differ from rclpy's at {differ[:10]}"
