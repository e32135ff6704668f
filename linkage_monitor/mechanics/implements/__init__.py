"""The implement library: one YAML per implement beside this file (docs/implements.md; read as
files, as the presets), and the implement files a user keeps anywhere else.

An implement file names the mechanism whose points it uses and gives the implement's mass (kg),
centre of gravity (a point name of that mechanism, or [x, z] m in its reference pose; frame x
forward, z up, origin at the rear wheels' ground contact), hitch and mast points, and what the
mass and cg are known to within (``tolerances``: the mass's standard uncertainty feeds the
mechanism's declared error sources, ``error_sources.implement.mass``; the cg's are the weighing
estimator's priors). ``with_implement`` hangs one on a mechanism: a validated copy.
"""

from __future__ import annotations

import copy
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import yaml

from ..errors import MechanismFileError
from ..safe_yaml import LIBYAML_LOADER

if TYPE_CHECKING:   # the schema (numpy) only when an implement is hung: `linkage-monitor presets` reads the files only
    from ..model import Mechanism

IMPLEMENT_DIR = Path(__file__).parent
_KEYS = {"name", "description", "mechanism", "mass", "cg", "hitch_point", "mast_point", "tolerances"}
_REQUIRED = ("name", "mechanism", "mass", "cg")


@dataclass(frozen=True)
class Tolerances:
    """What an implement's data are known to within (1 σ): mass kg; cg_x, cg_z m (None: not declared)."""

    mass: float | None = None
    cg_x: float | None = None
    cg_z: float | None = None


@dataclass(frozen=True)
class ImplementFile:
    """One implement file: ``mechanism`` the mechanism's name whose points it names; mass kg; cg a point
    name or (x, z) m in the mechanism's reference pose; ``file`` where it was read (for messages)."""

    name: str
    description: str
    mechanism: str
    mass: float
    cg: str | tuple[float, float]
    hitch_point: str | None
    mast_point: str | None
    tolerances: Tolerances
    file: str


def implement_names() -> list[str]:
    """Names of the bundled implements (file stems), sorted."""
    return sorted(p.name[:-5] for p in IMPLEMENT_DIR.iterdir() if p.name.endswith(".yaml"))


def load_implement(spec: str) -> ImplementFile:
    """The bundled implement ``spec`` or else the implement file at path ``spec``; MechanismFileError
    naming the file and the key when it is not one."""
    if spec in implement_names():
        path = IMPLEMENT_DIR / f"{spec}.yaml"
        file = f"{spec}.yaml (implement)"
    else:
        path, file = Path(spec), spec
        if not path.is_file():
            raise MechanismFileError(file, "", "no such implement file or bundled implement (bundled: "
                                     f"{', '.join(implement_names()) or 'none'})")
    return implement_from_text(path.read_text(encoding="utf-8"), file)


def implement_from_text(text: str, file: str = "<text>") -> ImplementFile:
    """Parse and check an implement file's YAML text (module docstring; docs/implements.md)."""
    try:
        data = yaml.load(text, Loader=LIBYAML_LOADER)   # noqa: S506 - a safe loader
    except yaml.YAMLError as exc:
        raise MechanismFileError(file, "", f"not YAML ({exc})") from exc
    if not isinstance(data, dict):
        raise MechanismFileError(file, "", "expected a mapping of the implement's keys")
    unknown = sorted(set(map(str, data)) - _KEYS)
    if unknown:
        raise MechanismFileError(file, unknown[0], f"unknown key (known: {', '.join(sorted(_KEYS))})")
    for key in _REQUIRED:
        if key not in data:
            raise MechanismFileError(file, key, "missing")
    cg = data["cg"]
    if not isinstance(cg, str):
        x, z = _pair(cg, file, "cg", minimum=None)
        cg = (x, z)
    tolerances = data.get("tolerances") or {}
    if not isinstance(tolerances, dict) or set(tolerances) - {"mass", "cg"}:
        raise MechanismFileError(file, "tolerances", f"expected {{mass: kg, cg: [x, z] m}}, got {tolerances!r}")
    cg_u = _pair(tolerances["cg"], file, "tolerances.cg", minimum=0.0) if "cg" in tolerances else (None, None)
    return ImplementFile(
        name=str(data["name"]), description=str(data.get("description", "")), mechanism=str(data["mechanism"]),
        mass=_number(data["mass"], file, "mass", minimum=0.0), cg=cg,
        hitch_point=_optional_name(data, "hitch_point"), mast_point=_optional_name(data, "mast_point"),
        tolerances=Tolerances(mass=_number(tolerances["mass"], file, "tolerances.mass", minimum=0.0)
                              if "mass" in tolerances else None, cg_x=cg_u[0], cg_z=cg_u[1]),
        file=file)


def implement_description(name: str) -> str:
    """The bundled implement's one-line description ('' if unreadable)."""
    try:
        return load_implement(name).description
    except MechanismFileError:
        return ""


def with_implement(mechanism: Mechanism, implement: ImplementFile) -> Mechanism:
    """A copy of ``mechanism`` carrying ``implement`` (mass, cg, hitch and mast points; its mass
    tolerance as the declared ``error_sources.implement.mass``), validated: MechanismFileError naming
    the implement file when it belongs to another mechanism or names a point the mechanism lacks."""
    from ..schema import mechanism_from_dict

    if implement.mechanism != mechanism.name:
        raise MechanismFileError(implement.file, "mechanism", f"the implement is for '{implement.mechanism}', "
                                 f"not for '{mechanism.name}'")
    if mechanism.implement is None:
        raise MechanismFileError(implement.file, "", f"mechanism '{mechanism.name}' has no implement block")
    raw = copy.deepcopy(dict(mechanism.raw))
    block = raw["implement"]
    block["mass"] = implement.mass
    block["cg"] = implement.cg if isinstance(implement.cg, str) else list(implement.cg)
    for key in ("hitch_point", "mast_point"):
        if getattr(implement, key) is not None:
            block[key] = getattr(implement, key)
    if implement.tolerances.mass is not None:
        sources = raw.setdefault("error_sources", {}) or {}
        raw["error_sources"] = sources
        sources["implement"] = {"mass": implement.tolerances.mass}
    try:
        return mechanism_from_dict(raw, mechanism.file)
    except MechanismFileError as exc:
        raise MechanismFileError(implement.file, exc.key, f"on '{mechanism.name}': {exc.reason}") from exc


def _number(value: Any, file: str, key: str, minimum: float | None) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or value != value:
        raise MechanismFileError(file, key, f"expected a number, got {value!r}")
    if minimum is not None and value < minimum:
        raise MechanismFileError(file, key, f"must be ≥ {minimum:g}, got {value!r}")
    return float(value)


def _pair(value: Any, file: str, key: str, minimum: float | None) -> tuple[float, float]:
    if not isinstance(value, (list, tuple)) or len(value) != 2:
        raise MechanismFileError(file, key, f"expected [x, z] (m){' or a point name' if key == 'cg' else ''}, "
                                 f"got {value!r}")
    return _number(value[0], file, f"{key}[0]", minimum), _number(value[1], file, f"{key}[1]", minimum)


def _optional_name(data: dict, key: str) -> str | None:
    return None if data.get(key) is None else str(data[key])
