"""A mechanism with scalars of its description set by dotted key (``cylinders.lift.bore``; list items
by name), re-validated as a whole."""

from __future__ import annotations

import copy
from typing import Any, Mapping

from .errors import MechanismFileError
from .model import Mechanism
from .schema import mechanism_from_dict


def apply_overrides(mech: Mechanism, overrides: Mapping[str, Any]) -> Mechanism:
    """Copy of ``mech`` with scalars set by dotted key (list items by name), re-validated."""
    raw = copy.deepcopy(dict(mech.raw))
    for key, value in overrides.items():
        _set_dotted(raw, key, value, mech.file)
    return mechanism_from_dict(raw, file=mech.file)


def with_sensor_resolutions(mech: Mechanism, steps: Mapping[str, tuple[str, float]]) -> Mechanism:
    """Copy of ``mech`` whose sensors' resolution is at least the step given, name -> (kind as ``Inputs``
    names it, step in the sensor's SI unit), e.g. a CAN signal's DBC scale (``ErrorSources.with_resolutions``),
    written into its description (``error_sources.sensors``: bias, noise and resolution of each sensor it
    changes) so that a recording of it replays with the same sources; ``mech`` itself when none changes."""
    sources = mech.error_sources.with_resolutions(steps)
    changed = {name: sources.sensors[name] for name in steps
               if sources.sensors.get(name) != mech.error_sources.sensors.get(name)}
    if not changed:
        return mech
    raw = copy.deepcopy(dict(mech.raw))
    block = raw.setdefault("error_sources", {}) or {}
    raw["error_sources"] = block
    listed = block.setdefault("sensors", {}) or {}
    block["sensors"] = listed
    for name, error in changed.items():
        listed[name] = {"bias": error.bias, "noise": error.noise, "resolution": error.resolution}
    return mechanism_from_dict(raw, file=mech.file)


def _set_dotted(raw: dict, key: str, value: Any, file: str) -> None:
    parts = key.split(".")
    node: Any = raw
    path = ""
    for i, part in enumerate(parts):
        last = i == len(parts) - 1
        if isinstance(node, list):
            matches = [item for item in node if isinstance(item, dict) and item.get("name") == part]
            if not matches:
                names = ", ".join(str(it.get("name")) for it in node if isinstance(it, dict))
                raise MechanismFileError(file, key, f"no item named '{part}' in {path} ({names})")
            if last:
                raise MechanismFileError(file, key, "only scalars can be overridden, not a whole item")
            node = matches[0]
        elif isinstance(node, dict):
            if last:
                if isinstance(node.get(part), (dict, list)):
                    raise MechanismFileError(file, key, "only scalars can be overridden, not a mapping/list")
                if isinstance(value, (dict, list)) or value is None:
                    raise MechanismFileError(file, key, f"override value {value!r} is not a scalar")
                node[part] = value
                return
            if part not in node:
                raise MechanismFileError(file, key, f"'{part}' is not set in {path or 'the file'}")
            node = node[part]
        else:
            raise MechanismFileError(file, key, f"{path} is a scalar, it has no '{part}'")
        path = f"{path}.{part}" if path else part

