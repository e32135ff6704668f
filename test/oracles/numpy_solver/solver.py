"""Test oracle (the numpy implementation, see __init__): the solver, sensor inputs -> pose, hinge
reactions, cylinder forces, per pose or batched — its own kinematics and statics (``.kinematics``,
``.statics``), the package's input checks (``mechanics.inputs``), result layout
(``mechanics.result_layout``) and result types.

SI units (m, rad, N, Pa); frame x forward, z up, origin at the rear wheels' ground contact B.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from linkage_monitor.mechanics.errors import AssemblyError, DeadCentreError, InputError
from linkage_monitor.mechanics.general_path import lift_off_verdicts, static_dead_centre_verdicts
from linkage_monitor.mechanics.inputs import ArrayMap, InputChecks, Inputs, check_observable
from linkage_monitor.mechanics.model import Mechanism
from linkage_monitor.mechanics.result_layout import ResultLayout
from linkage_monitor.mechanics.results import BatchResult, Result, Status
from linkage_monitor.mechanics.statics import layouts_by_measured_forces
from .kinematics import Kinematics, KinematicState
from .statics import StaticsLayout


class Solver:
    """Everything that depends only on the mechanism, built once; ``solve`` / ``solve_batch`` per pose(s).

    dead_centre_cond: condition number (1-norm, dimensionless matrices) above which a pose is a
    dead centre; consistency_tol: m, largest constraint residual accepted when more inputs than
    degrees of freedom are measured.
    """

    def __init__(self, mech: Mechanism, dead_centre_cond: float = 1e6, consistency_tol: float = 1e-3) -> None:
        self.mech = mech
        self.dead_centre_cond = dead_centre_cond
        self.consistency_tol = consistency_tol
        self.kin = kin = Kinematics(mech)
        check_observable(mech, kin)
        self.checks = InputChecks(mech, kin)
        self._layouts = layouts_by_measured_forces(mech, kin, StaticsLayout)
        self.result_layout = ResultLayout(mech, kin)
        self._sensors = {ps.name: ps for ps in mech.measurements.pressures}

    def solve(self, inputs: Inputs, previous: Result | None = None) -> Result:
        """Solve one pose; raises a LinkageError subclass on failure.

        Warm start is explicit: pass the previous solved pose (``previous``, a Result of this
        solver) and Newton starts from the tangent prediction off it; without it, from the
        reference pose. Either way the answer is the same pose on the reference assembly branch.
        """
        given = {kind: {k: np.array([v], dtype=float) for k, v in getattr(inputs, kind).items()}
                 for kind in ("cylinders", "angles", "pressures", "rates", "accelerations")}
        start = previous.state if previous is not None else None
        batch, ks = self._solve(start if isinstance(start, KinematicState) else None, **given)
        res = batch.result(0)
        code = int(batch.status[0])
        if code in (Status.OK, Status.LIFT_OFF):
            return replace(res, state=ks)
        raise {Status.INPUT: InputError, Status.ASSEMBLY: AssemblyError, Status.DEAD_CENTRE: DeadCentreError}[Status(code)](
            res.message)

    def solve_batch(self, cylinders: ArrayMap | None = None, angles: ArrayMap | None = None,
                    pressures: ArrayMap | None = None, rates: ArrayMap | None = None,
                    accelerations: ArrayMap | None = None) -> BatchResult:
        """Solve N poses at once (arrays of shape (N,), scalars broadcast), from the reference pose.

        Per-pose failures are reported in ``status`` / ``messages``; unknown or missing input
        names and an unobservable mechanism raise.
        """
        batch, _ = self._solve(None, cylinders or {}, angles or {}, pressures or {}, rates or {}, accelerations or {})
        return batch

    def _solve(self, previous: KinematicState | None, cylinders: ArrayMap, angles: ArrayMap, pressures: ArrayMap,
               rates: ArrayMap, accelerations: ArrayMap) -> tuple[BatchResult, KinematicState]:
        mech, kin, checks = self.mech, self.kin, self.checks
        n_pose, arrays = checks.arrays(cylinders, angles, pressures, rates, accelerations)
        s = checks.matrix(arrays, n_pose, "inputs")
        problems, bad = checks.problems(s, arrays)
        ks = kin.solve(np.where(bad[:, None], kin.reference_inputs(), s), previous, self.dead_centre_cond,
                       self.consistency_tol)
        status, messages = ks.status.copy(), list(ks.messages)
        for i in np.flatnonzero(bad):
            status[i], messages[i] = Status.INPUT, problems[i]
        # kinetostatics: the attachments' accelerations (N, K, 2) m/s² and the bodies' angular ones (N, n_bodies) rad/s²
        input_rates = checks.rate_matrices(arrays, n_pose)
        accel = None
        if input_rates is not None:
            q_dot, q_ddot = kin.rates(ks.q, *input_rates)
            accel = (kin.accelerations(ks.q, q_dot, q_ddot), q_ddot[:, 2::3])
        # measured cylinder forces: F = count·(p_cap·A_cap − p_rod·A_rod) (schema, cylinders[])
        nan = np.full(n_pose, np.nan)
        cap = {c.name: nan for c in mech.cylinders}
        rod = {c.name: nan for c in mech.cylinders}
        for name, values in arrays["pressures"].items():
            sensor = self._sensors[name]
            (cap if sensor.chamber == "cap" else rod)[sensor.cylinder] = values
        force_known = frozenset(self._sensors[n].cylinder for n in arrays["pressures"])
        measured_force = np.full((n_pose, len(mech.cylinders)), np.nan)
        for k, c in enumerate(mech.cylinders):
            if c.name in force_known:
                measured_force[:, k] = c.count * (np.nan_to_num(cap[c.name]) * c.cap_area
                                                  - np.nan_to_num(rod[c.name]) * c.rod_area)
        layout = self._layouts[force_known].determined()
        p, _ = kin.positions(ks.q)
        sol = layout.solve(p, measured_force, accel)
        static_dead_centre_verdicts(kin, s, sol.condition, self.dead_centre_cond, status, messages)
        lift_off_verdicts(mech, layout, sol.unknowns, status, messages)
        failed = status >= Status.INPUT
        batch = self.result_layout.batch(
            n_pose, np.where(failed[:, None], np.nan, ks.q), np.where(failed[:, None, None], np.nan, p),
            np.where(failed[:, None], np.nan, sol.unknowns), sol, layout, measured_force, cap, rod, failed)
        batch.largest_force = largest_forces(batch)
        batch.status, batch.messages = status, messages
        batch.consistency_residual = np.where(failed, np.nan, np.linalg.norm(ks.phi, axis=1))
        batch.condition = np.maximum(sol.condition, ks.condition)
        return batch, ks


def largest_forces(batch: BatchResult) -> np.ndarray:
    """The largest hinge reaction or cylinder force magnitude (N,) N of each pose (NaN where a pose failed)."""
    n_pose = len(batch.status)
    magnitudes = ([np.hypot(f[:, 0], f[:, 1]) for f in batch.hinge_force.values()]
                  + [np.abs(f) for f in batch.cylinder_force.values()])
    return np.max(np.stack(magnitudes + [np.zeros(n_pose)], axis=1), axis=1)   # NaN propagates (failed)
