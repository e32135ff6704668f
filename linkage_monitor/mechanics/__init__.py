"""Planar linkage mechanics: model + YAML schema, kinematics, statics (no rclpy).

SI units (m, rad, N, Pa, kg); frame x forward, z up, origin at the rear wheels' ground contact.
The names below are loaded when first used (PEP 562): ``from linkage_monitor.mechanics.presets import
preset_names`` or the errors do not load numpy, numba or scipy (``linkage-monitor presets`` and
``--help`` answer at once); the solver loads the compiled kernels.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

from .errors import (AssemblyError, DeadCentreError, InputError, LinkageError, MechanismFileError,
                     UnobservableError)

if TYPE_CHECKING:
    from .inputs import Inputs
    from .model import Mechanism
    from .presets import load_description, load_preset, preset_description, preset_names, preset_path
    from .results import BatchResult, ContactResult, CylinderResult, HingeResult, Result, Status
    from .overrides import apply_overrides
    from .schema import load_mechanism, mechanism_from_dict, mechanism_from_text
    from .solver import Solver

_LAZY = {**dict.fromkeys(("Mechanism",), ".model"),
         **dict.fromkeys(("load_description", "load_preset", "preset_description", "preset_names", "preset_path"),
                         ".presets"),
         **dict.fromkeys(("BatchResult", "ContactResult", "CylinderResult", "HingeResult", "Result", "Status"),
                         ".results"),
         **dict.fromkeys(("load_mechanism", "mechanism_from_dict", "mechanism_from_text"), ".schema"),
         "apply_overrides": ".overrides", "Inputs": ".inputs", "Solver": ".solver"}


def __getattr__(name: str) -> Any:
    """The name from its module, imported at its first use (then kept in this module)."""
    module = _LAZY.get(name)
    if module is None:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    value = getattr(importlib.import_module(module, __name__), name)
    globals()[name] = value
    return value


__all__ = [
    "AssemblyError", "BatchResult", "apply_overrides", "ContactResult", "CylinderResult", "DeadCentreError", "HingeResult",
    "InputError", "Inputs", "LinkageError", "Mechanism", "MechanismFileError", "Result", "Status",
    "Solver", "UnobservableError", "load_description", "load_mechanism", "load_preset", "mechanism_from_dict",
    "mechanism_from_text",
    "preset_description", "preset_names", "preset_path",
]
