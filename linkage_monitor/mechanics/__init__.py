"""Planar linkage mechanics: model + YAML schema, kinematics, statics (no rclpy).

SI units (m, rad, N, Pa, kg); frame x forward, z up, origin at the rear wheels' ground contact.
"""

from .numba_cache import ensure_writable

ensure_writable()   # before kernels.py defines the cached kernels: numba needs a writable cache directory

from .errors import (AssemblyError, DeadCentreError, InputError, LinkageError, MechanismFileError,
                     UnobservableError)
from .model import Mechanism
from .presets import load_description, load_preset, preset_description, preset_names, preset_path
from .results import BatchResult, ContactResult, CylinderResult, HingeResult, Result, Status
from .schema import apply_overrides, load_mechanism, mechanism_from_dict, mechanism_from_text
from .solver import Inputs, Solver

__all__ = [
    "AssemblyError", "BatchResult", "apply_overrides", "ContactResult", "CylinderResult", "DeadCentreError", "HingeResult",
    "InputError", "Inputs", "LinkageError", "Mechanism", "MechanismFileError", "Result", "Status",
    "Solver", "UnobservableError", "load_description", "load_mechanism", "load_preset", "mechanism_from_dict",
    "mechanism_from_text",
    "preset_description", "preset_names", "preset_path",
]
