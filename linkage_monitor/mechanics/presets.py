"""The bundled presets: ``linkage_monitor/presets/<name>.yaml``."""

from __future__ import annotations

from pathlib import Path

import yaml

from .errors import MechanismFileError
from .model import Mechanism
from .schema import load_mechanism

PRESET_DIR = Path(__file__).resolve().parent.parent / "presets"


def preset_names() -> list[str]:
    """Names of the bundled presets (file stems), sorted."""
    return sorted(p.stem for p in PRESET_DIR.glob("*.yaml"))


def preset_path(name: str) -> Path:
    """Path of preset ``name``; MechanismFileError listing the presets if there is none."""
    path = PRESET_DIR / f"{name}.yaml"
    if not path.is_file():
        raise MechanismFileError(f"preset '{name}'", "", f"no such preset (available: {', '.join(preset_names()) or 'none'})")
    return path


def load_preset(name: str) -> Mechanism:
    """Load and validate the bundled preset ``name`` (e.g. ``belarus_1221``)."""
    return load_mechanism(preset_path(name))


def preset_description(name: str) -> str:
    """The preset's one-line ``description`` ('' if missing or unreadable)."""
    try:
        data = yaml.safe_load(preset_path(name).read_text(encoding="utf-8"))
    except (OSError, yaml.YAMLError):
        return ""
    return str(data.get("description", "")) if isinstance(data, dict) else ""
