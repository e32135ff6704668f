"""The live path of a solve: the usual pose in one compiled call (``kernels.live_series`` of one
pose), its rows written straight into a ``Result``; and the programs that call takes, built once
per statics layout and machine program.

SI units (m, rad, N, Pa); frame x forward, z up, origin at the rear wheels' ground contact B.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from . import kernels
from .constants import ATMOSPHERIC_PRESSURE   # a gauge pressure below −1 atm is a negative absolute pressure
from .inputs import Inputs
from .kinematics import KinematicState
from .programs import POSE_VALUES, LivePrograms, LiveRows, MachineProgram, OutputsProgram, fields
from .results import Result, Status
from .row_pool import RowBlock, RowPool
from .solver_parts import SolverParts
from .statics import StaticsLayout

_SOLVED = np.zeros(1, dtype=int)   # KinematicState.status of one solved pose (shared, read-only)
_SOLVED.flags.writeable = False
POSE_NAMES: tuple[str, ...] = POSE_VALUES.names or ()   # LiveRows.pose's fields
_OK = Status.OK.label


class SolvedPose(NamedTuple):
    """``Solver.solve_with_machine``'s answer: the pose, and when the compiled call solved it its
    machine-level rows in ``MachineModel``'s key order and its value row (``programs.ValueRow``)
    (None: the general path solved the pose; ``MachineModel.evaluate`` gives the machine-level rows)."""

    result: Result
    steerability: np.ndarray | None
    capacity: np.ndarray | None
    values: np.ndarray | None


class InputMoves(NamedTuple):
    """Moves of a pose's inputs, a row per moved pose (``LivePath.solve_moved``): s (R, n_inputs) added
    to its inputs in ``Kinematics.input_names`` order (m, rad), pressures (R, 2, C) to each cylinder's
    cap and rod gauge pressures (Pa)."""

    s: np.ndarray
    pressures: np.ndarray


class PlainLive(NamedTuple):
    """What ``LivePath.solve`` takes for one set of pressure sensors and one machine program: the
    machine program (kept: the cache's key holds its id), the ``LivePrograms``, the transmission
    measures' names (then '' for none, index −1), the rows it solves into."""

    machine: MachineProgram
    programs: LivePrograms
    measure_names: list[str]
    rows: RowPool


class LiveInputs(NamedTuple):
    """A pose's inputs for the live path: ``s`` in ``Kinematics.input_names`` order (m, rad, angles not
    wrapped), per cylinder its ``cap`` and ``rod`` gauge pressures (Pa, NaN = not measured), and the
    programs and rows (``live``) for its pressure sensors."""

    s: list[float]
    cap: list[float]
    rod: list[float]
    live: PlainLive


class LivePath:
    """The compiled live path of ``solver``'s mechanism, with the programs and rows it builds once."""

    def __init__(self, solver: SolverParts) -> None:
        self._solver = solver
        mech, kin = solver.mech, solver.kin
        self._angle_reference = kin.angle_reference.tolist()   # rad, the angle inputs' readings in the reference pose
        self._cylinder_index = solver.cylinder_index
        self._per_cap_area = np.array([1.0 / (c.count * c.cap_area) for c in mech.cylinders])
        self._friction = np.array([c.friction for c in mech.contacts])
        self._outputs_programs: dict[frozenset[str], OutputsProgram] = {}
        self._plain: dict[tuple[tuple[str, ...], int], PlainLive] = {}   # (pressure sensors, id(machine)) -> solve's
        self._live_programs: dict[tuple[frozenset[str], int], tuple[MachineProgram, LivePrograms]] = {}

    def outputs_program(self, layout: StaticsLayout) -> OutputsProgram:
        """What ``kernels.live_series`` needs, beyond the layout's own program, to write a Result's
        arrays for poses solved with ``layout`` (its ``outputs``; built once per layout)."""
        program = self._outputs_programs.get(layout.force_known)
        if program is None:
            solver = self._solver
            mech, results = solver.mech, solver.result_layout
            imp = mech.implement
            reduced = solver.reduced[layout.force_known]
            program = OutputsProgram(
                n_unknowns=layout.n_unknowns, spring_stiffness=layout.spring_stiffness.astype(float),
                spring_free_length=layout.spring_free_length.astype(float),
                spring_preload=layout.spring_preload.astype(float),
                hinge_cols=np.ascontiguousarray(layout.hinge_cols, dtype=np.int64),
                force_measured=layout.force_measured.astype(np.bool_), cylinder_cols=layout.cylinder_cols.astype(np.int64),
                contact_cols=layout.contact_cols.astype(np.int64),
                implement_col=layout.implement_col if layout.implement_col is not None else -1,
                implement_weight=float(imp.mass * mech.gravity if imp is not None else math.nan),
                per_cap_area=self._per_cap_area, force_areas=solver.force_areas, friction=self._friction.astype(float),
                point_rows=results.point_rows.astype(np.int64),
                cg_att=results.cg_att if results.cg_att is not None else -1,
                frame_att=results.frame_att.astype(np.int64),
                frame_hinge_index=results.frame_hinge_index.astype(np.int64),
                frame_hinge_sign=results.frame_hinge_sign.ravel().astype(float),
                frame_member_index=results.frame_member_index.astype(np.int64),
                frame_member_sign=results.frame_member_sign.ravel().astype(float),
                reduced=reduced.served, dead_centre_sine=solver.dead_centre_sine,
                measure_count=len(reduced.measure_names))
            self._outputs_programs[layout.force_known] = program
        return program

    def live_programs(self, layout: StaticsLayout, machine: MachineProgram) -> LivePrograms:
        """The ``LivePrograms`` ``kernels.live_series`` takes for poses solved with ``layout`` and the
        machine-level rows of ``machine`` (``MachineModel.program`` or ``kernels.NO_MACHINE``), built
        once per layout and machine program."""
        key = (layout.force_known, id(machine))
        held = self._live_programs.get(key)
        if held is None or held[0] is not machine:   # the machine kept with it: its id is not reused
            solver = self._solver
            programs = kernels.live_programs(fields(solver.kin.program), fields(layout.program),
                                             fields(self.outputs_program(layout)),
                                             fields(solver.reduced[layout.force_known].program), fields(machine))
            held = self._live_programs[key] = (machine, programs)
        return held[1]

    def solve(self, inputs: Inputs, start: KinematicState | None, machine: MachineProgram) -> SolvedPose | None:
        """The usual live pose in one compiled call (``kernels.live_series`` of one pose): every input given, finite
        and in range, no rates, assembled on the reference branch from ``start`` (or the reference
        pose), no dead centre, no contact lifting off. None for anything else: the general path then
        solves the pose and words what is wrong. Gives what it and ``MachineModel.evaluate`` would
        (test_mechanics_fast_paths.py)."""
        given = self._live_inputs(inputs, machine)
        if given is None:
            return None
        solver = self._solver
        kin = solver.kin
        values = given.s
        for j, reference in enumerate(self._angle_reference, start=kin.cyl_att.shape[1]):   # kin.wrap_angles on floats
            values[j] = reference + ((values[j] - reference + math.pi) % (2.0 * math.pi) - math.pi)
        live = given.live
        block, i = live.rows.take()
        rows, s = block.rows, block.s
        s[i] = values
        block.pressures[i] = given.cap, given.rod
        self._series(live, block, start, i, i + 1)
        if not rows.plain[i]:
            return None
        q = rows.q[i:i + 1]
        state = KinematicState(s=s[i:i + 1], q=q, phi=rows.phi[i:i + 1], status=_SOLVED, messages=[""],
                               condition=rows.kinematic_condition[i:i + 1])
        pose = dict(zip(POSE_NAMES, rows.pose[i].item()))   # Python floats by name, in one call
        return SolvedPose(Result(solver.names, rows.point_xz[i], q[0].reshape(-1, 3), rows.hinge_force[i],
                                 rows.cylinder_values[i], rows.contact_values[i], pose["implement_load"],
                                 rows.implement_cg[i], rows.frame_load_points[i], rows.frame_load_forces[i],
                                 pose["residual"], pose["consistency_residual"], pose["condition"],
                                 pose["largest_force"], _OK, state=state,
                                 transmission_angle=pose["transmission_angle"],
                                 weakest_transmission=live.measure_names[pose["weakest"]],
                                 load_amplification=pose["load_amplification"]),
                          rows.steerability[i], rows.capacity[i], rows.values[i])

    def solve_moved(self, inputs: Inputs, start: KinematicState | None, machine: MachineProgram, moves: InputMoves
                    ) -> tuple[LiveRows, slice] | None:
        """The poses of ``inputs`` moved by each row of ``moves`` in one compiled call (``kernels.live_series``),
        each from the one before, the first from ``start`` (or the reference pose): the rows it wrote
        and which of them are these poses (``plain`` False where a pose is not the usual one: the
        general path is to solve it). None where ``inputs`` or a moved pose is not for this path (as
        ``solve``: an input missing, not finite or out of range, rates). The moves are finite."""
        given = self._live_inputs(inputs, machine)
        if given is None:
            return None
        kin = self._solver.kin
        live = given.live
        count = len(moves.s)
        block, first = live.rows.take_rows(count)
        s, pressures = block.s[first:first + count], block.pressures[first:first + count]
        np.add(given.s, moves.s, out=s)
        np.add((given.cap, given.rod), moves.pressures, out=pressures)
        # a length not positive, a pressure below vacuum (NaN: a chamber not measured)
        if (s[:, :kin.cyl_att.shape[1]] <= 0.0).any() or (pressures < -ATMOSPHERIC_PRESSURE).any():
            return None
        if len(self._angle_reference):
            s[:] = kin.wrap_angles(s)
        self._series(live, block, start, first, first + count)
        return block.rows, slice(first, first + count)

    def _series(self, live: PlainLive, block: RowBlock, start: KinematicState | None, lo: int, hi: int) -> None:
        """``kernels.live_series`` of the rows ``lo``..``hi - 1`` of ``block``, each pose from the one
        before, the first from ``start`` (or the reference pose)."""
        solver = self._solver
        start = start if start is not None else solver.kin.reference
        kernels.live_series(live.programs, block.buffer, start.q[-1:], start.s[-1:], solver.assembly_limit,
                            solver.dead_centre_cond, lo, hi)

    def _live_inputs(self, inputs: Inputs, machine: MachineProgram) -> LiveInputs | None:
        """The inputs of a pose for this path, with the programs and rows for its pressure sensors under
        ``machine``; None where they are not for it (an input missing, not finite or out of range, rates)."""
        solver = self._solver
        kin = solver.kin
        if inputs.rates or inputs.accelerations or len(inputs.cylinders) + len(inputs.angles) != kin.n_inputs:
            return None
        nc = kin.cyl_att.shape[1]
        sensors = solver.sensors
        try:
            values = [float(inputs.cylinders[n]) if j < nc else float(inputs.angles[n])
                      for j, n in enumerate(kin.input_names)]
            pressures = [(sensors[n], float(v)) for n, v in inputs.pressures.items()]
        except (KeyError, TypeError, ValueError):
            return None
        if not (all(math.isfinite(v) for v in values) and all(v > 0.0 for v in values[:nc])
                and all(math.isfinite(v) and v >= -ATMOSPHERIC_PRESSURE for _, v in pressures)):
            return None
        cylinders = solver.mech.cylinders
        cap, rod = [math.nan] * len(cylinders), [math.nan] * len(cylinders)
        for ps, value in pressures:
            (cap if ps.chamber == "cap" else rod)[self._cylinder_index[ps.cylinder]] = value
        return LiveInputs(values, cap, rod, self._plain_live(tuple(inputs.pressures), machine))

    def _plain_live(self, sensors: tuple[str, ...], machine: MachineProgram) -> PlainLive:
        """``solve``'s programs and rows for the pressure sensors ``sensors`` (in the order the inputs
        give them) and ``machine``, built once for each."""
        key = (sensors, id(machine))
        live = self._plain.get(key)
        if live is None or live.machine is not machine:   # the machine kept with it: its id is not reused
            solver = self._solver
            layout = solver.statics_layout(frozenset(solver.sensors[n].cylinder for n in sensors))
            outputs, kin = self.outputs_program(layout), solver.kin
            live = self._plain[key] = PlainLive(
                machine=machine, programs=self.live_programs(layout, machine),
                measure_names=[*solver.reduced[layout.force_known].measure_names, ""],
                rows=RowPool(lambda n_pose: kernels.live_rows(n_pose, kin.n, kin.m, outputs, machine),
                             kin.n_inputs, len(solver.mech.cylinders)))
        return live
