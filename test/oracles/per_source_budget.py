"""Per-source oracle of the first-order error budget (``mechanics.uncertainty``): each derivative from
its own solves, one ``MachineModel.solve`` per moved pose from the pose itself, as the budget took
them before its moved poses were solved in one compiled call.

A pressure sensor: one pose moved by LOAD_STEP_PRESSURE (the linear outputs exact, the others by
the chain rule, ``_LinearisedOutputs``); a seal friction: its sensor's derivative per N of force; a
length or angle: a central difference of ``pose_step``. The contributions ∂y/∂s · u_s (n_out,
n_src) in the budget's source order. SI units (m, rad, Pa, N).
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from linkage_monitor.mechanics import LinkageError
from linkage_monitor.mechanics.inputs import Inputs
from linkage_monitor.mechanics.results import Result
from linkage_monitor.mechanics.budget import Budget
from linkage_monitor.mechanics.output_table import force_per_pressure
from linkage_monitor.mechanics.uncertainty import LOAD_STEP_PRESSURE, UncertaintyModel, pose_step


def per_source_contributions(um: UncertaintyModel, inputs: Inputs, result: Result, budget: Budget) -> np.ndarray:
    """The contributions (n_out, n_src) of ``budget``'s sources (not the implement mass) at the pose
    ``result`` of ``inputs``, each derivative from its own solves."""
    y0 = budget.values

    def solved(kind: str, name: str, step: float) -> np.ndarray:
        group = dict(getattr(inputs, kind))
        group[name] += step
        try:
            pose = um.model.solve(replace(inputs, **{kind: group}), result)
        except LinkageError:
            return np.full(len(y0), math.nan)
        return um.table.values(pose.result, pose.machine)

    def derivative(kind: str, name: str) -> np.ndarray:
        if kind == "pressures":
            return um._linear.derivative(y0, solved(kind, name, LOAD_STEP_PRESSURE), LOAD_STEP_PRESSURE)
        step = pose_step(um.sources.sensor(name, kind).total)
        with np.errstate(invalid="ignore"):
            return (solved(kind, name, step) - solved(kind, name, -step)) / (2.0 * step)

    kind_of = {name: kind for kind in ("cylinders", "angles", "pressures") for name in getattr(inputs, kind)}
    columns = []
    for source in budget.sources:
        if source.part == "friction":
            sensor = um.friction_sensor(source.input, inputs)
            assert sensor is not None
            columns.append(derivative("pressures", sensor) / force_per_pressure(um.mech, sensor) * source.u)
        else:
            columns.append(derivative(kind_of[source.input], source.input) * source.u)
    return np.column_stack(columns)
