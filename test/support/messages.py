"""Deterministic sample messages with every field set, and field-by-field comparison."""

from __future__ import annotations

import importlib
import math
import random
import struct
from typing import Any

CUSTOM_TYPES = ["HingeReaction", "HingeReactions", "CylinderState", "HitchState", "Steerability"]


def message_class(type_name: str) -> type:
    """Class of a ROS message from 'pkg/msg/Type' or 'pkg/Type'."""
    parts = type_name.split("/")
    pkg, name = parts[0], parts[-1]
    return getattr(importlib.import_module(f"{pkg}.msg"), name)


def _value(field_type: str, rng: random.Random, depth: int) -> Any:
    base = field_type.split("<=")[0]
    if base.startswith("sequence<"):
        inner = base[len("sequence<"):-1].split(",")[0]
        return [_value(inner, rng, depth + 1) for _ in range(2)]
    if base in ("double", "float"):
        return rng.uniform(-1e5, 1e5)
    if base == "string":
        return "".join(rng.choice("abcdefghij_P0123") for _ in range(rng.randint(1, 12)))
    if base == "boolean":
        return rng.random() < 0.5
    if base in ("uint8", "octet"):
        return rng.randint(0, 255)
    if base in ("int32",):
        return rng.randint(-2**31, 2**31 - 1)
    if base in ("uint32",):
        return rng.randint(0, 2**32 - 1)
    if "/" in base:
        return sample_message(message_class(base), rng, depth + 1)
    raise NotImplementedError(f"no sample for field type {field_type}")


def sample_message(cls: type, rng: random.Random, depth: int = 0) -> Any:
    """An instance of `cls` with every field (recursively) set from `rng`."""
    msg = cls()
    for name, field_type in cls.get_fields_and_field_types().items():
        setattr(msg, name, _value(field_type, rng, depth))
    return msg


def to_dict(msg: Any) -> Any:
    """Plain nested dict/list of a message, for field-by-field comparison."""
    if hasattr(msg, "get_fields_and_field_types"):
        return {name: to_dict(getattr(msg, name)) for name in msg.get_fields_and_field_types()}
    if isinstance(msg, (list, tuple)):
        return [to_dict(item) for item in msg]
    return msg


def samples(seed: int = 7) -> dict[str, Any]:
    """One sample of each custom message type, deterministic in `seed`."""
    rng = random.Random(seed)
    return {name: sample_message(message_class(f"linkage_monitor/msg/{name}"), rng)
            for name in CUSTOM_TYPES}


def assert_same_message(a: object, b: object, where: str = "msg") -> None:
    """Field-by-field equality of two rclpy messages; floats bit for bit (NaN == NaN)."""
    if isinstance(a, float):
        assert struct.pack("<d", a) == struct.pack("<d", b) or (math.isnan(a) and math.isnan(b)), (where, a, b)
    elif hasattr(a, "get_fields_and_field_types"):
        for name in a.get_fields_and_field_types():
            assert_same_message(getattr(a, name), getattr(b, name), f"{where}.{name}")
    elif isinstance(a, (list, tuple)) or hasattr(a, "tolist"):
        a, b = list(a), list(b)
        assert len(a) == len(b), (where, len(a), len(b))
        for k, (x, y) in enumerate(zip(a, b)):
            assert_same_message(x, y, f"{where}[{k}]")
    else:
        assert a == b, (where, a, b)
