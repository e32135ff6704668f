"""A solve's inputs: one pose's measurements by name, and the checks of named input arrays against
the mechanism's measurements (unknown or missing names, shapes, values no sensor gives).

SI units: cylinder lengths m, angles rad, gauge pressures Pa, their rates per s and s².
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Mapping, NamedTuple, Protocol

import numpy as np

from .constants import ATMOSPHERIC_PRESSURE   # a gauge pressure below −1 atm is a negative absolute pressure
from .errors import InputError, UnobservableError
from .model import Mechanism

ArrayMap = Mapping[str, "float | np.ndarray"]
InputArrays = dict[str, dict[str, np.ndarray]]   # kind ('cylinders', 'angles', ...) -> input name -> (N,)


# built per input event: a plain dataclass, not a frozen one (docs/architecture.md, One pipeline)
@dataclass
class Inputs:
    """One pose's measurements, keyed by the names in the file's ``measurements``.

    cylinders: cylinder name -> length (m, pin to pin); angles: angle-sensor name -> rad;
    pressures: pressure-sensor name -> gauge Pa; rates / accelerations (optional, for
    kinetostatics): cylinder or angle-sensor name -> m/s, rad/s / m/s², rad/s².
    """

    cylinders: Mapping[str, float] = field(default_factory=dict)
    angles: Mapping[str, float] = field(default_factory=dict)
    pressures: Mapping[str, float] = field(default_factory=dict)
    rates: Mapping[str, float] = field(default_factory=dict)
    accelerations: Mapping[str, float] = field(default_factory=dict)


class InputProblems(NamedTuple):
    """Per pose of a solve: what is wrong with its inputs ('' when nothing) and whether anything is (N,)."""

    problems: list[str]
    bad: np.ndarray


class MeasuredInputs(Protocol):
    """What the checks read of a kinematics: the measured inputs' names, cylinder lengths first,
    and their (base, rod end) attachments (2, nc)."""

    input_names: list[str]
    cyl_att: np.ndarray


class InputChecks:
    """The checks of a mechanism's named input arrays, and the (N, n_inputs) matrix the kinematics
    takes of them (cylinder lengths, then angles, in ``input_names``' order)."""

    def __init__(self, mech: Mechanism, kin: MeasuredInputs) -> None:
        self.input_names = list(kin.input_names)
        self.n_cylinders = kin.cyl_att.shape[1]   # measured cylinder lengths, the first inputs
        meas = mech.measurements
        valid = {"cylinders": list(meas.cylinders), "angles": [a.name for a in meas.angles],
                 "pressures": [p.name for p in meas.pressures]}
        valid["rates"] = valid["accelerations"] = valid["cylinders"] + valid["angles"]
        self.valid = valid

    def arrays(self, cylinders: ArrayMap, angles: ArrayMap, pressures: ArrayMap, rates: ArrayMap,
               accelerations: ArrayMap) -> tuple[int, InputArrays]:
        """The number of poses N and every input as an array (N,) (scalars broadcast), by kind and name;
        InputError for an unknown name, a value that is not a number or arrays of different lengths."""
        valid = self.valid
        given = {"cylinders": cylinders, "angles": angles, "pressures": pressures, "rates": rates,
                 "accelerations": accelerations}
        arrays: InputArrays = {}
        n_pose = 1
        for kind, group in given.items():
            arrays[kind] = {}
            for name, v in group.items():
                if name not in valid[kind]:
                    raise InputError(f"unknown {kind[:-1]} input '{name}': measured {kind} are "
                                     f"{', '.join(valid[kind]) or 'none'} (see the file's 'measurements')")
                try:
                    arr = np.atleast_1d(np.asarray(v, dtype=float))
                except (TypeError, ValueError) as exc:
                    raise InputError(f"{kind[:-1]} input '{name}': {v!r} is not a number") from exc
                if arr.ndim != 1 or (arr.size != 1 and n_pose not in (1, arr.size)):
                    raise InputError(f"{kind[:-1]} input '{name}': expected a scalar or an array of {n_pose} poses, "
                                     f"got shape {arr.shape}")
                n_pose = max(n_pose, arr.size)
                arrays[kind][name] = arr
        for group in arrays.values():
            for name, arr in group.items():
                if arr.size not in (1, n_pose):
                    raise InputError(f"input '{name}' has {arr.size} poses, others have {n_pose}")
                group[name] = np.broadcast_to(arr, (n_pose,))
        return n_pose, arrays

    def matrix(self, values: Mapping[str, ArrayMap], n_pose: int, kind: str) -> np.ndarray:
        """(N, n_inputs) matrix of cylinder lengths then angles (kind 'inputs': InputError for a
        missing one), or of their rates or accelerations (0 for a missing one)."""
        nc = self.n_cylinders
        out = np.empty((n_pose, len(self.input_names)))
        for j, name in enumerate(self.input_names):
            group = values["cylinders"] if j < nc else values["angles"]
            if name not in group:
                if kind != "inputs":
                    out[:, j] = 0.0
                    continue
                what = "cylinder length" if j < nc else "angle"
                raise InputError(f"missing {what} '{name}': all measured inputs are needed "
                                 f"({', '.join(self.input_names)})")
            out[:, j] = group[name]
        return out

    def problems(self, s: np.ndarray, arrays: InputArrays) -> InputProblems:
        """Per pose: '' or what is wrong with its inputs (NaN/inf, length <= 0, p_abs < 0), for the
        input matrix s (N, n_inputs) of ``arrays``."""
        nc = self.n_cylinders
        problems = [""] * s.shape[0]
        pressures = list(arrays["pressures"].values())
        rates = list(arrays["rates"].values()) + list(arrays["accelerations"].values())
        if (np.isfinite(s).all() and (s[:, :nc] > 0.0).all() and all(np.isfinite(v).all() for v in rates)
                and all((v >= -ATMOSPHERIC_PRESSURE).all() and np.isfinite(v).all() for v in pressures)):
            return InputProblems(problems, np.zeros(s.shape[0], dtype=bool))   # the usual case, whole-array
        checks = [(f"cylinder '{n}' length" if j < nc else f"angle '{n}'", s[:, j], "m", j < nc)
                  for j, n in enumerate(self.input_names)]
        checks += [(f"pressure '{n}'", v, "Pa", False) for n, v in arrays["pressures"].items()]
        checks += [(f"{kind[:-1]} of '{n}'", v, "", False) for kind in ("rates", "accelerations")
                   for n, v in arrays[kind].items()]
        for label, values, unit, positive in checks:
            for i in np.flatnonzero(~np.isfinite(values)):
                problems[i] = problems[i] or f"{label} is {values[i]}: a finite number is needed (sensor fault?)"
            if positive:
                for i in np.flatnonzero(values <= 0.0):
                    problems[i] = problems[i] or f"{label} is {values[i]} {unit}: a length must be > 0"
        for name, values in arrays["pressures"].items():
            for i in np.flatnonzero(values < -ATMOSPHERIC_PRESSURE):
                problems[i] = problems[i] or (f"pressure '{name}' is {values[i]:.0f} Pa gauge, i.e. a negative "
                                              f"absolute pressure: check the sensor and its zero offset")
        return InputProblems(problems, np.array([bool(p) for p in problems]))

    def rate_matrices(self, arrays: InputArrays, n_pose: int) -> tuple[np.ndarray, np.ndarray] | None:
        """The inputs' rates ṡ and accelerations s̈ (N, n_inputs) (0 where not given, NaN as 0), or
        None when no rate is given (statics, no inertia loads)."""
        if not (arrays["rates"] or arrays["accelerations"]):
            return None
        rate_in = {"cylinders": arrays["rates"], "angles": arrays["rates"]}
        acc_in = {"cylinders": arrays["accelerations"], "angles": arrays["accelerations"]}
        return (np.nan_to_num(self.matrix(rate_in, n_pose, "rates")),
                np.nan_to_num(self.matrix(acc_in, n_pose, "accelerations")))


class ObservedKinematics(MeasuredInputs, Protocol):
    """What ``check_observable`` reads of a kinematics: its coordinates' count n, the reference
    pose q_ref (n,) and inputs, and the constraint residual and Jacobian at poses."""

    n: int
    q_ref: np.ndarray

    def reference_inputs(self) -> np.ndarray: ...

    def residual_jacobian(self, q: np.ndarray, s: np.ndarray) -> tuple[np.ndarray, np.ndarray]: ...


def check_observable(mech: Mechanism, kin: ObservedKinematics) -> None:
    """UnobservableError unless the measured inputs close every degree of freedom of the linkage
    (the rank of the constraint Jacobian at the reference pose)."""
    _, jac = kin.residual_jacobian(kin.q_ref[None], kin.reference_inputs()[None])
    nh2 = 2 * len(mech.hinges)
    dof = kin.n - (np.linalg.matrix_rank(jac[0, :nh2]) if nh2 else 0)
    free = kin.n - np.linalg.matrix_rank(jac[0])
    if free > 0:
        measured = ", ".join(kin.input_names) or "none"
        raise UnobservableError(
            f"{mech.file}: the linkage has {dof} degree(s) of freedom but the measured inputs "
            f"({measured}) close only {dof - free}: {free} free DOF cannot be determined; add a cylinder "
            f"length or joint angle to 'measurements'")
