"""The bundled presets: one YAML per source paper beside this file (the package runs from files, never
from a zip: its messages and kernels are compiled modules; a path costs no importlib.resources)."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import yaml

from ..errors import MechanismFileError
from ..safe_yaml import LIBYAML_LOADER

if TYPE_CHECKING:   # the schema (numpy) only when a preset is loaded: `linkage-monitor presets` reads the files only
    from ..model import Mechanism

PRESET_DIR = Path(__file__).parent


def preset_names() -> list[str]:
    """Names of the bundled presets (file stems), sorted."""
    return sorted(p.name[:-5] for p in PRESET_DIR.iterdir() if p.name.endswith(".yaml"))


def preset_path(name: str) -> Path:
    """Path of preset ``name``; MechanismFileError listing the presets if there is none."""
    path = PRESET_DIR / f"{name}.yaml"
    if not path.is_file():
        raise MechanismFileError(f"preset '{name}'", "", f"no such preset (available: {', '.join(preset_names()) or 'none'})")
    return path


def load_preset(name: str) -> Mechanism:
    """Load and validate the bundled preset ``name`` (e.g. ``belarus_1221``)."""
    from ..schema import mechanism_from_text

    return mechanism_from_text(preset_path(name).read_bytes(), file=f"{name}.yaml (preset)")


def load_description(spec: str) -> Mechanism:
    """A Mechanism from a preset name or else a YAML file path: what every ``--preset/--mechanism``
    option and the node's ``mechanism`` parameter accept."""
    from ..schema import load_mechanism

    return load_preset(spec) if spec in preset_names() else load_mechanism(spec)


def preset_description(name: str) -> str:
    """The preset's one-line ``description`` ('' if missing or unreadable)."""
    try:
        data = yaml.load(preset_path(name).read_text(encoding="utf-8"), Loader=LIBYAML_LOADER)   # noqa: S506 - safe
    except (OSError, yaml.YAMLError):
        return ""
    return str(data.get("description", "")) if isinstance(data, dict) else ""
