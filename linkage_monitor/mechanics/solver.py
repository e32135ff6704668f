"""The solver: sensor inputs -> pose, hinge reactions, cylinder forces, per pose or batched.

Built once per mechanism (``Solver``); a pose takes the live path (``live_path``: one compiled call)
or the general path (``general_path``: whole arrays, every verdict worded), a recorded series both
(``series``); the paths take it as a ``solver_parts.SolverParts``, what they use of it. Its inputs
are checked by ``inputs``, its results laid out by ``result_layout``.
SI units (m, rad, N, Pa); frame x forward, z up, origin at the rear wheels' ground contact B.
"""

from __future__ import annotations

import math
from dataclasses import replace
from typing import Mapping

import numpy as np

from . import kernels
from .errors import AssemblyError, DeadCentreError, InputError
from .general_path import solve_general
from .inputs import ArrayMap, InputChecks, Inputs, check_observable
from .kinematics import Kinematics, KinematicState
from .live_path import InputMoves, LivePath, SolvedPose
from .model import Mechanism
from .programs import LivePrograms, LiveRows, MachineProgram, OutputsProgram
from .reduced import DEAD_CENTRE_TRANSMISSION_DEG, ReducedStatics
from .result_layout import ResultLayout
from .results import BatchResult, Result, Status
from .series import Series
from .statics import StaticsLayout, layouts_by_measured_forces

__all__ = ["ArrayMap", "Inputs", "Series", "SolvedPose", "Solver"]


class Solver:
    """Everything that depends only on the mechanism, built once; ``solve`` / ``solve_batch`` per pose(s).

    dead_centre_cond: condition number (1-norm, dimensionless matrices) above which a pose is a
    dead centre on the general path; dead_centre_transmission_deg: degrees, the smallest
    transmission angle below which a pose is a dead centre on the reduced path
    (``reduced.DEAD_CENTRE_TRANSMISSION_DEG``); consistency_tol: m, largest constraint residual
    accepted when more inputs than degrees of freedom are measured.
    """

    def __init__(self, mech: Mechanism, dead_centre_cond: float = 1e6, consistency_tol: float = 1e-3,
                 dead_centre_transmission_deg: float = DEAD_CENTRE_TRANSMISSION_DEG) -> None:
        self.mech = mech
        self.dead_centre_cond = dead_centre_cond
        self.dead_centre_transmission_deg = dead_centre_transmission_deg
        self.dead_centre_sine = math.sin(math.radians(dead_centre_transmission_deg))
        self.consistency_tol = consistency_tol
        self.kin = kin = Kinematics(mech)
        check_observable(mech, kin)
        self.checks = InputChecks(mech, kin)
        self._layouts = layouts_by_measured_forces(mech, kin)
        # the reduced-coordinate statics of each layout; ``served`` says whether it takes the layout's poses
        self.reduced: dict[frozenset[str], ReducedStatics] = {
            known: ReducedStatics(kin, layout) for known, layout in self._layouts.items()}
        self.result_layout = results = ResultLayout(mech, kin)
        self.frame_load_names: list[str] = results.frame_load_names
        self.names = results.names
        self.sensors = {ps.name: ps for ps in mech.measurements.pressures}   # pressure sensors by name
        # count·cap area and count·rod area (2, C) m²: the measured force of the chambers' pressures
        self.force_areas = np.array([[c.count * c.cap_area for c in mech.cylinders],
                                     [c.count * c.rod_area for c in mech.cylinders]]).reshape(2, -1)
        self.cylinder_index = {c.name: k for k, c in enumerate(mech.cylinders)}   # mech.cylinders' order
        # largest constraint residual (m) of an assembled pose (kin.solve's): 1e-9·lc when closed exactly
        self.assembly_limit = 1e-9 * kin.lc if kin.m == kin.n else consistency_tol
        self._live = LivePath(self)

    # ---- public API -------------------------------------------------------------------------
    def solve(self, inputs: Inputs, previous: Result | None = None) -> Result:
        """Solve one pose; raises a LinkageError subclass on failure.

        Warm start is explicit: pass the previous solved pose (``previous``, a Result of this
        solver) and Newton starts from the tangent prediction off it (a live node's inputs change
        little between messages: 2 iterations); without it, from the reference pose. Either way
        the answer is the same pose on the reference assembly branch (the solver keeps no state).
        """
        return self.solve_with_machine(inputs, previous, kernels.NO_MACHINE).result

    def solve_with_machine(self, inputs: Inputs, previous: Result | None, machine: MachineProgram
                           ) -> SolvedPose:
        """``solve``, with the machine-level rows (steerability, lift capacity) of ``machine``
        (``MachineModel.program``) computed in the same compiled call — or None for them when the
        pose took the general path (then ``MachineModel.evaluate`` gives them)."""
        start = previous.state if previous is not None else None
        start = start if isinstance(start, KinematicState) else None
        plain = self._solve_plain(inputs, start, machine)
        if plain is not None:
            return plain
        arrays = {kind: {k: np.array([v], dtype=float) for k, v in getattr(inputs, kind).items()}
                  for kind in ("cylinders", "angles", "pressures", "rates", "accelerations")}
        batch, ks = solve_general(self, start, arrays["cylinders"], arrays["angles"], arrays["pressures"], arrays["rates"],
                                    arrays["accelerations"])
        res = batch.result(0)
        code = int(batch.status[0])
        if code in (Status.OK, Status.LIFT_OFF):
            return SolvedPose(replace(res, state=ks), None, None, None)
        raise {Status.INPUT: InputError, Status.ASSEMBLY: AssemblyError, Status.DEAD_CENTRE: DeadCentreError}[Status(code)](
            res.message)

    def solve_moved(self, inputs: Inputs, previous: Result | None, machine: MachineProgram, moves: InputMoves
                    ) -> tuple[LiveRows, slice] | None:
        """The poses of ``inputs`` moved by each row of ``moves`` (``live_path.InputMoves``: m, rad, Pa),
        with the machine-level rows of ``machine``, in one compiled call, each from the one before, the
        first from ``previous`` (as ``solve``'s warm start): the rows written and which of them are
        these poses; ``plain`` False for a pose the live path does not take (``solve`` words it). None
        where ``inputs`` or a moved pose is not for the live path (an input missing, not finite or out
        of range, rates): ``solve`` each moved pose then."""
        start = previous.state if previous is not None else None
        return self._live.solve_moved(inputs, start if isinstance(start, KinematicState) else None, machine, moves)

    def explain(self) -> list[str]:
        """Whether reduced coordinates serve the statics of each set of measured cylinder forces and
        why, a line each (``reduced.ReducedStatics.describe``; the rule in reduced.py's docstring),
        and the dead-centre verdict each path gives."""
        served = (f"reduced coordinates: a dead centre where the smallest transmission angle is below "
                  f"{self.dead_centre_transmission_deg:g} deg (the kinematic steps' and the statics' alike)")
        general = (f"general path: a dead centre where the constraint Jacobian's or the equilibrium matrix's "
                   f"condition number exceeds {self.dead_centre_cond:.3g}")
        return [*(reduced.describe() for reduced in self.reduced.values()), served, general]

    def solve_batch(self, cylinders: ArrayMap | None = None, angles: ArrayMap | None = None,
                    pressures: ArrayMap | None = None, rates: ArrayMap | None = None,
                    accelerations: ArrayMap | None = None, *, reach: bool = True) -> BatchResult:
        """Solve N poses at once (arrays of shape (N,), scalars broadcast), from the reference pose.

        Per-pose failures are reported in ``status`` / ``messages``; unknown or missing input
        names and an unobservable mechanism raise. ``reach=False``: a pose out of reach is not
        told how far it is (``Kinematics.solve``; for sweeps that only need the status).
        """
        batch, _ = solve_general(self, None, cylinders or {}, angles or {}, pressures or {}, rates or {},
                                 accelerations or {}, reach=reach)
        return batch

    def solve_series(self, cylinders: ArrayMap, angles: ArrayMap, pressures: ArrayMap, machine: MachineProgram
                     ) -> tuple[BatchResult, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """A recorded series of N poses (arrays (N,)) solved as the live node solves them, each from the
        one before (``kernels.live_series``, one compiled call); the poses it does not take (a bad
        input, off the branch, a dead centre, a contact lifting off) are solved by the general path
        (``solve_batch``'s, which words them). Same BatchResult as ``solve_batch``
        (test_mechanics_fast_paths.py); with the machine-level rows of ``machine``
        (``MachineModel.program``): steerability (N, S), capacity (N, P + 1), the value rows
        (N, ``ValueRow.width``), and which poses have them (N,) (the others: ``MachineModel.evaluate_batch``'s
        and ``MachineModel.value_rows``). ``series`` solves the same poses in parts."""
        series = self.series(machine)
        series.add(cylinders, angles, pressures)
        return series.finish()

    def series(self, machine: MachineProgram) -> Series:
        """A ``Series`` of poses to be solved part by part as ``solve_series`` solves them all at once."""
        return Series(self, machine)

    def statics_layout(self, force_known: frozenset[str]) -> StaticsLayout:
        """The equilibrium layout with the forces of these cylinders measured (UnobservableError if it is not determined)."""
        return self._layouts[force_known].determined()

    def chamber_pressures(self, pressures: Mapping[str, np.ndarray], n_pose: int) -> tuple[np.ndarray, np.ndarray]:
        """The cap and rod gauge pressures (N, C) Pa of every cylinder from the pressure sensors'
        readings (N,) by name; NaN where a chamber is not measured."""
        cap = np.full((n_pose, len(self.mech.cylinders)), np.nan)
        rod = cap.copy()
        for name, values in pressures.items():
            ps = self.sensors[name]
            (cap if ps.chamber == "cap" else rod)[:, self.cylinder_index[ps.cylinder]] = values
        return cap, rod

    def outputs_program(self, layout: StaticsLayout) -> OutputsProgram:
        """What ``kernels.live_series`` needs, beyond the layout's own program, to write a Result's
        arrays for poses solved with ``layout`` (``LivePath.outputs_program``)."""
        return self._live.outputs_program(layout)

    def live_programs(self, layout: StaticsLayout, machine: MachineProgram) -> LivePrograms:
        """The ``LivePrograms`` ``kernels.live_series`` takes for poses solved with ``layout`` and the
        machine-level rows of ``machine`` (``LivePath.live_programs``)."""
        return self._live.live_programs(layout, machine)

    def _solve_plain(self, inputs: Inputs, start: KinematicState | None, machine: MachineProgram
                     ) -> SolvedPose | None:
        """The usual live pose in one compiled call, or None where the general path is to solve it
        (``LivePath.solve``)."""
        return self._live.solve(inputs, start, machine)
