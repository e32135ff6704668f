"""The CAN mapping file: which DBC signal feeds which input of the monitor (docs/can-mapping.md).

Validated whole when loaded; every error names the file and the key (``inputs.lift_arm_angle.unit``)
and says what is expected. Checked against the DBC files and the mechanism by ``routes``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Mapping

import yaml

from linkage_monitor.mechanics import InputError
from linkage_monitor.mechanics.schema_values import yaml_number

from .position_table import PositionTable, TableError

# unit name -> factor to SI, per kind of input
UNITS: dict[str, dict[str, float]] = {
    "angle": {"rad": 1.0, "deg": math.pi / 180.0},
    "length": {"m": 1.0, "mm": 1e-3, "cm": 1e-2},
    "pressure": {"Pa": 1.0, "kPa": 1e3, "bar": 1e5, "MPa": 1e6, "psi": 6894.757293168},
}
DEFAULT_SILENCE_S = 1.0
TOP_KEYS = {"mechanism", "dbc", "silence_timeout", "inputs"}
INPUT_KEYS = {"message", "signal", "unit", "scale", "offset", "table", "pressure", "source_address"}
PRESSURE_KINDS = ("gauge", "absolute")
MAX_SOURCE_ADDRESS = 253   # J1939: 254 is the null address, 255 global


@dataclass(frozen=True)
class InputMap:
    """One input of the monitor fed from one DBC signal.

    name: the mechanism's measurement (angle sensor, cylinder, pressure sensor); message / signal:
    DBC names; unit: the unit of the signal's physical value (after the DBC's scaling) or of the
    table's values; scale / offset: value = scale · signal + offset, in ``unit``; table: signal ->
    value in ``unit`` instead of scale/offset; pressure: 'gauge' or 'absolute' (pressures only);
    source_address: the J1939 source address (ECU) whose frames are trusted, None: any one source.
    """

    name: str
    message: str
    signal: str
    unit: str | None = None
    scale: float = 1.0
    offset: float = 0.0
    table: PositionTable | None = None
    pressure: str | None = None
    source_address: int | None = None


@dataclass(frozen=True)
class CanMapping:
    """A mapping file: the mechanism it is for, its DBC files (resolved against the file's
    folder), the silence timeout (s) and the inputs."""

    source: str
    mechanism: str | None
    dbc: tuple[Path, ...]
    silence_timeout_s: float
    inputs: tuple[InputMap, ...] = field(default_factory=tuple)


def _fail(source: str, key: str, problem: str) -> InputError:
    return InputError(f"mapping {source}: {key}: {problem}")


def _number(value: Any, source: str, key: str) -> float:
    value = yaml_number(value)
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise _fail(source, key, f"{value!r} is not a finite number")
    return float(value)


def _input(name: str, data: Any, source: str) -> InputMap:
    where = f"inputs.{name}"
    if not isinstance(data, Mapping):
        raise _fail(source, where, "expected a mapping with message, signal and optionally unit, scale, "
                    "offset, table, pressure")
    unknown = sorted(set(data) - INPUT_KEYS)
    if unknown:
        raise _fail(source, f"{where}.{unknown[0]}", f"unknown key (known: {', '.join(sorted(INPUT_KEYS))})")
    for key in ("message", "signal"):
        if not isinstance(data.get(key), str) or not data[key]:
            raise _fail(source, f"{where}.{key}", "required: the DBC " + key + " name")
    unit = data.get("unit")
    known_units = sorted({u for units in UNITS.values() for u in units})
    if unit is not None and unit not in known_units:
        raise _fail(source, f"{where}.unit", f"{unit!r} is not one of {', '.join(known_units)}")
    table = None
    if "table" in data:
        if "scale" in data or "offset" in data:
            raise _fail(source, f"{where}.table", "give either a table or scale/offset, not both")
        raw = data["table"]
        if not isinstance(raw, Mapping) or set(raw) != {"signal", "value"}:
            raise _fail(source, f"{where}.table", "expected {signal: [points...], value: [values...]}")
        try:
            table = PositionTable(tuple(_number(v, source, f"{where}.table.signal") for v in raw["signal"]),
                                  tuple(_number(v, source, f"{where}.table.value") for v in raw["value"]))
        except TypeError:
            raise _fail(source, f"{where}.table", "signal and value must be lists of numbers") from None
        except TableError as exc:
            raise _fail(source, f"{where}.table", str(exc)) from None
    pressure = data.get("pressure")
    if pressure is not None and pressure not in PRESSURE_KINDS:
        raise _fail(source, f"{where}.pressure", f"{pressure!r}: expected gauge or absolute")
    scale = _number(data.get("scale", 1.0), source, f"{where}.scale")
    if scale == 0:
        raise _fail(source, f"{where}.scale", f"0 makes every value of {data['signal']} the offset: give the "
                    "signal's factor (default 1)")
    return InputMap(name=name, message=data["message"], signal=data["signal"], unit=unit, scale=scale,
                    offset=_number(data.get("offset", 0.0), source, f"{where}.offset"), table=table,
                    pressure=pressure, source_address=_source_address(data.get("source_address"), source, where))


def _source_address(value: Any, source: str, where: str) -> int | None:
    """The J1939 source address an input trusts (0 to MAX_SOURCE_ADDRESS), None if not given."""
    if value is None:
        return None
    if isinstance(value, bool) or not isinstance(value, int) or not 0 <= value <= MAX_SOURCE_ADDRESS:
        raise _fail(source, f"{where}.source_address", f"{value!r}: expected the J1939 source address of the ECU "
                    f"to trust, 0 to {MAX_SOURCE_ADDRESS} (0xFD), e.g. 0xF0")
    return value


class _UniqueKeyLoader(yaml.SafeLoader):
    """yaml's safe loader refusing a key given twice in one mapping (yaml keeps the last silently)."""

    def construct_mapping(self, node: yaml.MappingNode, deep: bool = False) -> dict[Any, Any]:
        seen: dict[Any, int] = {}
        for key_node, _ in node.value:
            key = self.construct_object(key_node, deep=deep)
            line = key_node.start_mark.line + 1
            if key in seen:
                raise yaml.constructor.ConstructorError(
                    None, None, f"key {key!r} given twice (lines {seen[key]} and {line}): keep one", key_node.start_mark)
            seen[key] = line
        return super().construct_mapping(node, deep=deep)


def mapping_from_text(text: str, source: str, folder: Path) -> CanMapping:
    """Parse and check the structure of a mapping (not yet against DBC and mechanism)."""
    try:
        data = yaml.load(text, Loader=_UniqueKeyLoader)   # noqa: S506 - a safe loader
    except yaml.constructor.ConstructorError as exc:
        raise InputError(f"mapping {source}: line {exc.problem_mark.line + 1 if exc.problem_mark else '?'}: "
                         f"{exc.problem}") from None
    except yaml.YAMLError as exc:
        raise InputError(f"mapping {source}: not YAML ({str(exc).splitlines()[0]})") from None
    if not isinstance(data, Mapping):
        raise InputError(f"mapping {source}: expected a mapping with keys {', '.join(sorted(TOP_KEYS))}")
    unknown = sorted(set(data) - TOP_KEYS)
    if unknown:
        raise _fail(source, unknown[0], f"unknown key (known: {', '.join(sorted(TOP_KEYS))})")
    inputs = data.get("inputs")
    if not isinstance(inputs, Mapping) or not inputs:
        raise _fail(source, "inputs", "required: measurement name -> {message, signal, ...}")
    dbc = data.get("dbc", [])
    if isinstance(dbc, str):
        dbc = [dbc]
    if not isinstance(dbc, list) or not all(isinstance(d, str) for d in dbc):
        raise _fail(source, "dbc", "expected a DBC file name or a list of them (relative to the mapping file)")
    mechanism = data.get("mechanism")
    if mechanism is not None and not isinstance(mechanism, str):
        raise _fail(source, "mechanism", "expected a preset name or a mechanism file")
    silence = _number(data.get("silence_timeout", DEFAULT_SILENCE_S), source, "silence_timeout")
    if silence <= 0:
        raise _fail(source, "silence_timeout", f"{silence} s: expected a time > 0 s")
    return CanMapping(source=source, mechanism=mechanism, dbc=tuple(folder / d for d in dbc),
                      silence_timeout_s=silence,
                      inputs=tuple(_input(str(name), value, source) for name, value in inputs.items()))


def load_mapping(path: str | Path) -> CanMapping:
    """Read a mapping file; InputError naming the file and the key if it is not a valid one."""
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except OSError as exc:
        raise InputError(f"mapping {path}: cannot be read ({exc.strerror or exc})") from None
    except UnicodeDecodeError as exc:
        raise InputError(f"mapping {path}: not UTF-8 text (byte 0x{exc.object[exc.start]:02X} at offset {exc.start}): "
                         "save it as UTF-8") from None
    return mapping_from_text(text, str(path), path.parent)
