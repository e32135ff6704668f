"""The error budget of a one-DOF linkage from a table of its derivatives over the stroke
(``uncertainty.UncertaintyModel`` takes it where it applies; the method: docs/accuracy.md, "Propagation").

On a linkage of one degree of freedom every pose lies on one curve, fixed by one coordinate θ: the
solved value of its first input (a length, m, or an angle, rad). At a pose the outputs are linear in
the loads (the measured cylinder forces, the implement's weight), so their derivatives with respect
to every source are affine in the measured forces and otherwise depend on θ alone. They are
tabulated once per mechanism and set of inputs at nodes θ_j = origin + j·step (TABLE_STEP), each
node from the moved poses of the budget's own method (``UncertaintyModel.raw_rows``) at inputs
consistent with θ_j (the linkage driven by the first input alone, ``calibration.drive_mechanism``),
at one load level and one more per measured cylinder. A node is computed the first time a pose
between it and its neighbour asks for it. A pose's derivatives are the two nodes' interpolated
linearly in θ (error O(step²), held by test/test_uncertainty_table.py to the moved poses'), and
the rest of its budget is one compiled call (``kernels.tabulated_budget``).

Not tabulated (the moved poses solve the budget): a linkage of more than one degree of freedom, a
pose whose load is a weak inference (``Result.load_amplification`` above
``reduced.LOAD_AMPLIFICATION_WARN``: its second differences decide whether it has an interval), a
pose beyond the table's reach or next to a node that does not solve, and a seal friction of zero.
Units SI (m, rad, Pa, N, kg).
"""

from __future__ import annotations

import math
from typing import Callable

import numpy as np

from . import kernels
from .calibration import drive_mechanism
from .inputs import Inputs
from .machine import MachineModel, MachineResult
from .reduced import LOAD_AMPLIFICATION_WARN
from .results import Result
from .errors import LinkageError
from .solver import Solver

TABLE_STEP = {"cylinders": 1.0e-3, "angles": 2.0e-3}   # m, rad: the nodes' spacing along the first input
TABLE_REACH = {"cylinders": 0.6, "angles": math.pi}    # a length's share of its reference value; an angle's rad
LEVEL_PRESSURE_STEP = 1.0e6   # Pa: a measured cylinder's second load level, on its pressure sensor

# (inputs, result, machine) of a solved pose -> its rows (rows, n_out): the derivatives with respect to
# each source input, the columns not linear in the loads 0 (``UncertaintyModel.raw_rows``; NaN in an
# output the pose does not compute), or None where a moved pose fails
RawRows = Callable[[Inputs, Result, MachineResult], "np.ndarray | None"]


def one_dof(model: MachineModel) -> bool:
    """Whether ``model``'s linkage has one degree of freedom (its hinges leave one coordinate free)."""
    kin = model.solver.kin
    return kin.n - 2 * kin.hinge_att.shape[1] == 1


class StrokeTable:
    """The tabulated derivatives (``table``, a ``kernels.PoseTable``) of one set of inputs on ``model``'s
    one-DOF linkage: ``pressures`` the pressure sensors given with their level-0 gauge pressure (Pa),
    ``level_sensors`` the sensor raised by LEVEL_PRESSURE_STEP for each measured cylinder's level,
    ``n_rows`` the rows and ``n_out`` the outputs ``raw_rows`` gives a node (``fill``)."""

    def __init__(self, model: MachineModel, pressures: dict[str, float], level_sensors: list[str], n_rows: int,
                 n_out: int, raw_rows: RawRows) -> None:
        self.model, self._raw_rows = model, raw_rows
        kin = model.solver.kin
        self.names = list(kin.input_names)
        self.n_cylinders = kin.cyl_att.shape[1]
        self._first_kind = "cylinders" if self.n_cylinders else "angles"
        self._row = 2 * kin.hinge_att.shape[1]   # Φ's row of the first input
        reference = model.mech.reference_inputs[self._first_kind][self.names[0]]
        reach = TABLE_REACH[self._first_kind] * (reference if self.n_cylinders else 1.0)
        step = TABLE_STEP[self._first_kind]
        count = int(2 * reach / step) + 1
        self._pressures, self._level_sensors = pressures, level_sensors
        self._cylinders = [model.solver.cylinder_index[model.solver.sensors[s].cylinder] for s in level_sensors]
        levels = 1 + len(level_sensors)
        angle = self.n_cylinders == 0   # the first input an angle sensor: θ its reading of its bodies
        self.table = kernels.PoseTable(
            origin=reference - reach, step=step, raw=np.zeros((count, levels, n_rows, n_out)),
            forces=np.zeros((count, levels, len(level_sensors))), state=np.full(count, kernels.NODE_EMPTY, np.uint8),
            cylinder=-1 if angle else model.solver.cylinder_index[self.names[0]],
            angle_first=int(kin.angle_bodies[0, 0]) if angle else -1,
            angle_second=int(kin.angle_bodies[1, 0]) if angle else -1,
            angle_offset=float(kin.angle_reference[0]) if angle else 0.0, reference=float(reference))
        self._drive: Solver | None = None

    def theta(self, result: Result) -> float:
        """The pose's coordinate: the solved value of its first input (m or rad; ``kernels.pose_coordinate``)."""
        return float(kernels.pose_coordinate(self.table, result.cylinder_values, result.body_q))

    def fill(self, j: int, result: Result) -> None:
        """Nodes j and j + 1 computed where they are not yet, from ``result`` (a pose between them)."""
        state = self.table.state
        for at in (j, j + 1):
            if state[at] == kernels.NODE_EMPTY:
                state[at] = kernels.NODE_FILLED if self._fill(at, result) else kernels.NODE_FAILED

    def _fill(self, j: int, result: Result) -> bool:
        """Node j's rows and forces from its poses (continued from ``result``); False where one fails."""
        table = self.table
        theta = table.origin + j * table.step
        inputs = self._consistent(theta, result)
        if inputs is None:
            return False
        previous = result
        for level in range(table.raw.shape[1]):
            pressures = dict(self._pressures)
            if level:
                pressures[self._level_sensors[level - 1]] += LEVEL_PRESSURE_STEP
            moved = Inputs(cylinders=inputs.cylinders, angles=inputs.angles, pressures=pressures)
            try:
                pose = self.model.solve(moved, previous)
            except LinkageError:
                return False
            if pose.result.load_amplification > LOAD_AMPLIFICATION_WARN:   # a weak inference: not tabulated
                return False
            rows = self._raw_rows(moved, pose.result, pose.machine)
            if rows is None:
                return False
            table.raw[j, level] = rows
            table.forces[j, level] = pose.result.cylinder_values[self._cylinders, 1]
            previous = pose.result
        return True

    def _consistent(self, theta: float, result: Result) -> Inputs | None:
        """The pose inputs at which the first input's solved value is ``theta`` and the others read what
        that pose gives them (the linkage driven by the first input alone, from ``result``'s pose)."""
        kin = self.model.solver.kin
        q_start = np.ascontiguousarray(result.body_q, dtype=float).reshape(1, -1)
        if len(self.names) > 1:
            if self._drive is None:
                self._drive = Solver(drive_mechanism(self.model.mech, self.names[:1]))
            drive = self._drive.kin
            start = np.array([[self.theta(result)]])
            q, phi, _, on_branch = kernels.solve_poses(q_start, start, np.array([[theta]]), 25, drive.program, False)
            if not (on_branch[0] and drive.assembled(phi, 1e-9 * drive.lc)[0]):
                return None
            readings, _ = kin.residual_jacobian(q, np.zeros((1, len(self.names))))
            values = readings[0, self._row:self._row + len(self.names)].copy()
            values[self.n_cylinders:] /= kin.lc
        else:
            values = np.array([theta])
        cylinders = {n: float(v) for n, v in zip(self.names[:self.n_cylinders], values)}
        angles = {n: float(v) for n, v in zip(self.names[self.n_cylinders:], values[self.n_cylinders:])}
        return Inputs(cylinders=cylinders, angles=angles)
