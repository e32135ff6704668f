"""Test oracle (frozen numpy implementation, see __init__). The solver: sensor inputs -> pose, hinge reactions, cylinder forces, per pose or batched.

SI units (m, rad, N, Pa); frame x forward, z up, origin at the rear wheels' ground contact B.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Mapping

import numpy as np

from linkage_monitor.mechanics.errors import AssemblyError, DeadCentreError, InputError, UnobservableError
from .kinematics import Kinematics, KinematicState
from linkage_monitor.mechanics.model import Mechanism
from linkage_monitor.mechanics.results import BatchResult, Result, Status
from .statics import StaticsLayout

ATMOSPHERE = 101325.0  # Pa; a gauge pressure below −1 atm is a negative absolute pressure
ArrayMap = Mapping[str, "float | np.ndarray"]


@dataclass(frozen=True)
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
        self._check_kinematics_observable()
        # one statics layout per set of force-measured cylinders, all built now (attachments fixed)
        gauged = sorted({ps.cylinder for ps in mech.measurements.pressures})
        self._layouts = {frozenset(c for k, c in enumerate(gauged) if bits >> k & 1):
                         StaticsLayout(mech, kin, frozenset(c for k, c in enumerate(gauged) if bits >> k & 1))
                         for bits in range(2 ** len(gauged))}
        self._point_att = {}
        for name in mech.points:
            owner = next((b for b in mech.moving_bodies if name in b.points), mech.ground)
            self._point_att[name] = kin.attach(owner.name, name)
        self._cg_att = kin.attach(mech.implement.body, f"cg of {mech.implement.body}") if mech.implement else None
        ground = mech.ground.name
        self.frame_load_names: list[str] = []
        self._frame_hinges = []   # (hinge index, attachment, sign of the force on the ground)
        for i, h in enumerate(mech.hinges):
            if ground in h.bodies:
                self._frame_hinges.append((i, kin.attach(ground, h.point), 1.0 if h.bodies[1] == ground else -1.0))
                self.frame_load_names.append(f"hinge {h.name}")
        self._frame_members = []  # (member index: springs then cylinders, attachment, sign)
        members = [(s.name, s.a, s.b) for s in mech.springs] + [(c.name, c.base, c.rod_end) for c in mech.cylinders]
        for m, (name, a, b) in enumerate(members):
            for end, sign in ((a, -1.0), (b, 1.0)):
                if end.body == ground:
                    self._frame_members.append((m, kin.attach(ground, end.point), sign))
                    self.frame_load_names.append(f"{name} {end.point}")
        self._sensors = {ps.name: ps for ps in mech.measurements.pressures}

    # ---- public API -------------------------------------------------------------------------
    def solve(self, inputs: Inputs, previous: Result | None = None) -> Result:
        """Solve one pose; raises a LinkageError subclass on failure.

        Warm start is explicit: pass the previous solved pose (``previous``, a Result of this
        solver) and Newton starts from the tangent prediction off it (a live node's inputs change
        little between messages: 2 iterations); without it, from the reference pose. Either way
        the answer is the same pose on the reference assembly branch (the solver keeps no state).
        """
        arrays = {kind: {k: np.array([v], dtype=float) for k, v in getattr(inputs, kind).items()}
                  for kind in ("cylinders", "angles", "pressures", "rates", "accelerations")}
        start = previous.state if previous is not None else None
        batch, ks = self._solve(start if isinstance(start, KinematicState) else None, **arrays)
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

    # ---- internals --------------------------------------------------------------------------
    def _check_kinematics_observable(self) -> None:
        kin = self.kin
        _, jac = kin.residual_jacobian(kin.q_ref[None], kin.reference_inputs()[None])
        nh2 = 2 * len(self.mech.hinges)
        dof = kin.n - (np.linalg.matrix_rank(jac[0, :nh2]) if nh2 else 0)
        free = kin.n - np.linalg.matrix_rank(jac[0])
        if free > 0:
            measured = ", ".join(kin.input_names) or "none"
            raise UnobservableError(
                f"{self.mech.file}: the linkage has {dof} degree(s) of freedom but the measured inputs "
                f"({measured}) close only {dof - free}: {free} free DOF cannot be determined; add a cylinder "
                f"length or joint angle to 'measurements'")

    def statics_layout(self, force_known: frozenset[str]) -> StaticsLayout:
        """The equilibrium layout with the forces of these cylinders measured (UnobservableError if it is not determined)."""
        layout = self._layouts[force_known]
        if layout.null_space_error is not None:
            raise layout.null_space_error
        return layout

    def _input_matrix(self, values: Mapping[str, ArrayMap], n_pose: int, kind: str) -> np.ndarray:
        """(N, n_inputs) matrix of cylinder lengths then angles (or their rates)."""
        kin = self.kin
        nc = kin.cyl_att.shape[1]
        out = np.empty((n_pose, kin.n_inputs))
        for j, name in enumerate(kin.input_names):
            group = values["cylinders"] if j < nc else values["angles"]
            if name not in group:
                if kind != "inputs":
                    out[:, j] = 0.0
                    continue
                what = "cylinder length" if j < nc else "angle"
                raise InputError(f"missing {what} '{name}': all measured inputs are needed "
                                 f"({', '.join(kin.input_names)})")
            out[:, j] = group[name]
        return out

    def _arrays(self, cylinders: ArrayMap, angles: ArrayMap, pressures: ArrayMap, rates: ArrayMap,
                accelerations: ArrayMap) -> tuple[int, dict[str, dict[str, np.ndarray]]]:
        meas = self.mech.measurements
        valid = {"cylinders": list(meas.cylinders), "angles": [a.name for a in meas.angles],
                 "pressures": [p.name for p in meas.pressures]}
        valid["rates"] = valid["accelerations"] = valid["cylinders"] + valid["angles"]
        given = {"cylinders": cylinders, "angles": angles, "pressures": pressures, "rates": rates,
                 "accelerations": accelerations}
        arrays: dict[str, dict[str, np.ndarray]] = {}
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

    def _input_problems(self, s: np.ndarray, arrays: dict[str, dict[str, np.ndarray]]) -> list[str]:
        """Per pose: '' or what is wrong with its inputs (NaN/inf, length <= 0, p_abs < 0)."""
        kin = self.kin
        nc = kin.cyl_att.shape[1]
        problems = [""] * s.shape[0]
        pressures = list(arrays["pressures"].values())
        rates = list(arrays["rates"].values()) + list(arrays["accelerations"].values())
        if (np.isfinite(s).all() and (s[:, :nc] > 0.0).all() and all(np.isfinite(v).all() for v in rates)
                and all((v >= -ATMOSPHERE).all() and np.isfinite(v).all() for v in pressures)):
            return problems  # the usual case, checked whole-array; below: which pose, which input
        checks = [(f"cylinder '{n}' length" if j < nc else f"angle '{n}'", s[:, j], "m", j < nc)
                  for j, n in enumerate(kin.input_names)]
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
            for i in np.flatnonzero(values < -ATMOSPHERE):
                problems[i] = problems[i] or (f"pressure '{name}' is {values[i]:.0f} Pa gauge, i.e. a negative "
                                              f"absolute pressure: check the sensor and its zero offset")
        return problems

    def _solve(self, previous: KinematicState | None, cylinders: ArrayMap, angles: ArrayMap, pressures: ArrayMap,
               rates: ArrayMap, accelerations: ArrayMap) -> tuple[BatchResult, KinematicState]:
        mech, kin = self.mech, self.kin
        n_pose, arrays = self._arrays(cylinders, angles, pressures, rates, accelerations)
        s = self._input_matrix(arrays, n_pose, "inputs")
        problems = self._input_problems(s, arrays)
        bad = np.array([bool(p) for p in problems])
        s_clean = np.where(bad[:, None], kin.reference_inputs(), s)
        ks = kin.solve(s_clean, previous, self.dead_centre_cond, self.consistency_tol)
        status, messages = ks.status.copy(), list(ks.messages)
        for i in np.flatnonzero(bad):
            status[i], messages[i] = Status.INPUT, problems[i]
        p, rel = kin.positions(ks.q)
        accel = None
        if arrays["rates"] or arrays["accelerations"]:
            rate_in = {"cylinders": arrays["rates"], "angles": arrays["rates"]}
            acc_in = {"cylinders": arrays["accelerations"], "angles": arrays["accelerations"]}
            s_dot = np.nan_to_num(self._input_matrix(rate_in, n_pose, "rates"))
            s_ddot = np.nan_to_num(self._input_matrix(acc_in, n_pose, "accelerations"))
            q_dot, q_ddot = kin.rates(ks.q, s_dot, s_ddot)
            linear, _ = kin.point_rates(q_ddot, rel)
            _, centripetal = kin.point_rates(q_dot, rel)
            accel = (linear + centripetal, q_ddot[:, 2::3])
        # measured cylinder forces: F = count·(p_cap·A_cap − p_rod·A_rod) (schema, cylinders[])
        sensors = self._sensors
        nan = np.full(n_pose, np.nan)
        cap = {c.name: nan for c in mech.cylinders}
        rod = {c.name: nan for c in mech.cylinders}
        for name, values in arrays["pressures"].items():
            ps = sensors[name]
            (cap if ps.chamber == "cap" else rod)[ps.cylinder] = values
        force_known = frozenset(sensors[n].cylinder for n in arrays["pressures"])
        measured_force = np.full((n_pose, len(mech.cylinders)), np.nan)
        for k, c in enumerate(mech.cylinders):
            if c.name in force_known:
                measured_force[:, k] = c.count * (np.nan_to_num(cap[c.name]) * c.cap_area
                                                  - np.nan_to_num(rod[c.name]) * c.rod_area)
        layout = self.statics_layout(force_known)
        sol = layout.solve(p, measured_force, accel)
        for i in np.flatnonzero((status == Status.OK) & ~(sol.condition <= self.dead_centre_cond)):
            status[i] = Status.DEAD_CENTRE
            messages[i] = (f"static dead centre at {kin.describe_inputs(s[i])}: equilibrium matrix condition number "
                           f"{sol.condition[i]:.3g} > {self.dead_centre_cond:.3g} (a member is aligned with a "
                           f"hinge; forces would be unbounded)")
        u = sol.unknowns
        for contact in mech.contacts:
            normal = u[:, layout.contact_col[contact.name]]
            for i in np.flatnonzero((status == Status.OK) & (normal < 0.0)):
                status[i] = Status.LIFT_OFF
                messages[i] = f"contact '{contact.name}' lifts off: its normal force would be {normal[i]:.1f} N (pulling)"
        failed = status >= Status.INPUT
        u = np.where(failed[:, None], np.nan, u)
        q = np.where(failed[:, None], np.nan, ks.q)
        p = np.where(failed[:, None, None], np.nan, p)
        batch = self._assemble(n_pose, q, p, u, sol, layout, measured_force, cap, rod, failed)
        batch.status, batch.messages = status, messages
        batch.consistency_residual = np.where(failed, np.nan, np.linalg.norm(ks.phi, axis=1))
        batch.condition = np.maximum(sol.condition, ks.condition)
        return batch, ks

    def _assemble(self, n_pose: int, q: np.ndarray, p: np.ndarray, u: np.ndarray, sol, layout: StaticsLayout,
                  measured_force: np.ndarray, cap: dict, rod: dict, failed: np.ndarray) -> BatchResult:
        mech = self.mech
        cyl_force = {}
        for k, c in enumerate(mech.cylinders):
            f = measured_force[:, k] if c.name in layout.force_known else u[:, layout.cyl_col[c.name]]
            cyl_force[c.name] = np.where(failed, np.nan, f)
        hinge_force = {h.name: u[:, layout.hinge_cols[i]] for i, h in enumerate(mech.hinges)}
        contact_n = {c.name: u[:, layout.contact_col[c.name]] for c in mech.contacts}
        imp = mech.implement
        if layout.implement_col is not None:
            imp_load = u[:, layout.implement_col]
        elif imp is not None:
            imp_load = np.where(failed, np.nan, imp.mass * mech.gravity)
        else:
            imp_load = np.full(n_pose, np.nan)
        member_force = np.concatenate([sol.spring_force, np.column_stack(list(cyl_force.values()))
                                       if cyl_force else np.zeros((n_pose, 0))], axis=1)
        axes = np.concatenate([sol.spring_axis, sol.cylinder_axis], axis=1)
        fl_points, fl_forces = [], []
        for i, att, sign in self._frame_hinges:
            fl_points.append(p[:, att])
            fl_forces.append(sign * hinge_force[mech.hinges[i].name])
        for m, att, sign in self._frame_members:
            fl_points.append(p[:, att])
            fl_forces.append(sign * member_force[:, m, None] * axes[:, m])
        shape = (n_pose, 0, 2)
        magnitudes = [np.hypot(f[:, 0], f[:, 1]) for f in hinge_force.values()] + [np.abs(f) for f in cyl_force.values()]
        largest = np.max(np.stack(magnitudes + [np.zeros(n_pose)], axis=1), axis=1)   # NaN propagates (failed)
        return BatchResult(
            points={n: p[:, a] for n, a in self._point_att.items()},
            body_poses={b.name: q[:, 3 * i:3 * i + 3] for i, b in enumerate(mech.moving_bodies)},
            hinge_force=hinge_force, hinge_bodies={h.name: h.bodies for h in mech.hinges},
            cylinder_length={c.name: np.where(failed, np.nan, sol.cylinder_length[:, k]) for k, c in enumerate(mech.cylinders)},
            cylinder_force=cyl_force,
            cap_pressure_predicted={c.name: cyl_force[c.name] / (c.count * c.cap_area) for c in mech.cylinders},
            cap_pressure_measured=cap, rod_pressure_measured=rod,
            contact_normal=contact_n,
            contact_tangential={c.name: c.friction * contact_n[c.name] for c in mech.contacts},
            implement_load=imp_load,
            implement_cg=p[:, self._cg_att] if self._cg_att is not None else np.full((n_pose, 2), np.nan),
            frame_load_names=list(self.frame_load_names),
            frame_load_points=np.stack(fl_points, axis=1) if fl_points else np.zeros(shape),
            frame_load_forces=np.stack(fl_forces, axis=1) if fl_forces else np.zeros(shape),
            residual=np.where(failed, np.nan, sol.residual), consistency_residual=np.zeros(n_pose),
            condition=np.zeros(n_pose), largest_force=largest, status=np.zeros(n_pose, dtype=int),
            messages=[""] * n_pose,
            transmission_angle=np.full(n_pose, np.nan), weakest_transmission=[""] * n_pose)
