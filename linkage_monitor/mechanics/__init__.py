"""Planar linkage mechanics: model + YAML schema, kinematics, statics (no rclpy).

SI units (m, rad, N, Pa, kg); frame x forward, z up, origin at the rear wheels' ground contact.
"""

from .errors import (AssemblyError, DeadCentreError, InputError, LinkageError, MechanismFileError,
                     UnobservableError)
from .model import Mechanism
from .presets import load_preset, preset_description, preset_names, preset_path
from .results import STATUS_NAMES, BatchResult, ContactResult, CylinderResult, HingeResult, Result
from .schema import load_mechanism, mechanism_from_dict
from .solver import Inputs, Solver

__all__ = [
    "AssemblyError", "BatchResult", "ContactResult", "CylinderResult", "DeadCentreError", "HingeResult",
    "InputError", "Inputs", "LinkageError", "Mechanism", "MechanismFileError", "Result", "STATUS_NAMES",
    "Solver", "UnobservableError", "load_mechanism", "load_preset", "mechanism_from_dict",
    "preset_description", "preset_names", "preset_path",
]
