"""The values of a mechanism description checked one by one, each error naming the file and the key
path (``hinges[3].bodies``): mappings with their allowed and required keys, lists, finite numbers
in range (SI units), names, [x, z] vectors (m), the points and bodies named, mounts, unique names.
"""

from __future__ import annotations

import math
import re
from typing import Any, Callable, Protocol, TypeVar

import numpy as np

from .errors import MechanismFileError
from .model import Body, Mount

MAX_MAGNITUDE = 1e9          # no number of the schema (m, kg, N, Pa, N/m) is larger
_FLOAT = re.compile(r"^[-+]?(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?$")


def yaml_number(value: Any) -> Any:
    """``value``, or the float a string of it writes: YAML 1.1 reads a number without a dot or without a
    sign in its exponent (``20e6``, ``1e-3``) as a string. Used by every YAML the package reads numbers
    from (mechanism files, CAN mappings)."""
    return float(value) if isinstance(value, str) and _FLOAT.match(value.strip()) else value


class _HasName(Protocol):
    @property
    def name(self) -> str: ...


_Named = TypeVar("_Named", bound=_HasName)


class ValueReader:
    """Checked values of the description; ``self.file`` prefixes every error, ``points`` (m) and
    ``bodies`` are those read so far (the names the values may refer to)."""

    def __init__(self, file: str) -> None:
        self.file = file
        self.points: dict[str, np.ndarray] = {}
        self.bodies: dict[str, Body] = {}

    def fail(self, key: str, reason: str) -> MechanismFileError:
        return MechanismFileError(self.file, key, reason)

    def mapping(self, value: Any, key: str, allowed: set[str], required: frozenset[str] | set[str] = frozenset()) -> dict:
        if not isinstance(value, dict):
            raise self.fail(key, f"expected a mapping, got {type(value).__name__}")
        unknown = sorted(set(map(str, value)) - allowed)
        if unknown:
            raise self.fail(f"{key}.{unknown[0]}" if key else unknown[0],
                            f"unknown key (allowed: {', '.join(sorted(allowed))})")
        missing = sorted(required - set(value))
        if missing:
            raise self.fail(key or missing[0], f"missing required key '{missing[0]}'")
        return value

    def seq(self, value: Any, key: str) -> list:
        if value is None:
            return []
        if not isinstance(value, list):
            raise self.fail(key, f"expected a list, got {type(value).__name__}")
        return value

    def number(self, value: Any, key: str, minimum: float | None = None, positive: bool = False,
               maximum: float | None = None) -> float:
        value = yaml_number(value)
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise self.fail(key, f"expected a number, got {value!r}")
        try:
            x = float(value)
        except OverflowError:
            raise self.fail(key, "a number too large to be a quantity of a linkage") from None
        if not math.isfinite(x):
            raise self.fail(key, f"{x} is not a finite number")
        if abs(x) > MAX_MAGNITUDE:
            raise self.fail(key, f"{x:.6g} is out of range (|value| <= {MAX_MAGNITUDE:.0e} in SI units)")
        if positive and x <= 0.0:
            raise self.fail(key, f"must be > 0, got {x}")
        if minimum is not None and x < minimum:
            raise self.fail(key, f"must be >= {minimum}, got {x}")
        if maximum is not None and x > maximum:
            raise self.fail(key, f"must be <= {maximum}, got {x}")
        return x

    def text(self, value: Any, key: str) -> str:
        if not isinstance(value, str) or not value:
            raise self.fail(key, f"expected a non-empty string, got {value!r}")
        return value

    def vector(self, value: Any, key: str, nonzero: bool = False) -> np.ndarray:
        if not isinstance(value, list) or len(value) != 2:
            raise self.fail(key, f"expected [x, z] (two numbers), got {value!r}")
        v = np.array([self.number(value[0], f"{key}[0]"), self.number(value[1], f"{key}[1]")])
        if nonzero and not np.any(v):
            raise self.fail(key, "must not be the zero vector")
        return v

    def point_name(self, value: Any, key: str) -> str:
        name = self.text(value, key)
        if name not in self.points:
            raise self.fail(key, f"point '{name}' is not defined in points")
        return name

    def position(self, value: Any, key: str) -> np.ndarray:
        """A point name or literal [x, z] -> coordinates (m)."""
        if isinstance(value, str):
            return self.points[self.point_name(value, key)].copy()
        return self.vector(value, key)

    def body_name(self, value: Any, key: str, moving: bool = False) -> str:
        name = self.text(value, key)
        if name not in self.bodies:
            raise self.fail(key, f"body '{name}' is not defined (bodies: {', '.join(self.bodies)})")
        if moving and self.bodies[name].ground:
            raise self.fail(key, f"body '{name}' is the ground; a moving body is needed here")
        return name

    def on_body(self, point: str, body: str, key: str) -> None:
        if point not in self.bodies[body].points:
            raise self.fail(key, f"point '{point}' is not on body '{body}' (its points: "
                                 f"{', '.join(self.bodies[body].points)})")

    def mount(self, value: Any, key: str) -> Mount:
        m = self.mapping(value, key, {"point", "body"}, {"point", "body"})
        body = self.body_name(m["body"], f"{key}.body")
        point = self.point_name(m["point"], f"{key}.point")
        self.on_body(point, body, f"{key}.point")
        return Mount(point=point, body=body)

    def named_items(self, value: Any, key: str, read: Callable[[Any, str], _Named]) -> tuple[_Named, ...]:
        """The list ``key`` (None: empty) read item by item, ``read(item, f"{key}[i]")``; names unique."""
        items = tuple(read(item, f"{key}[{i}]") for i, item in enumerate(self.seq(value, key)))
        self.unique([item.name for item in items], key)
        return items

    def unique(self, names: list[str], key: str) -> None:
        seen: set[str] = set()
        for i, n in enumerate(names):
            if n in seen:
                raise self.fail(f"{key}[{i}].name", f"duplicate name '{n}'")
            seen.add(n)
