"""The solver: sensor inputs -> pose, hinge reactions, cylinder forces, per pose or batched.

SI units (m, rad, N, Pa); frame x forward, z up, origin at the rear wheels' ground contact B.
"""

from __future__ import annotations

import math
import threading
from dataclasses import dataclass, field, replace
from typing import Callable, Mapping, NamedTuple

import numpy as np

from . import kernels
from .constants import ATMOSPHERIC_PRESSURE   # a gauge pressure below −1 atm is a negative absolute pressure
from .errors import AssemblyError, DeadCentreError, InputError, UnobservableError
from .kinematics import Kinematics, KinematicState
from .model import Mechanism
from .programs import POSE_VALUES, LiveBuffer, LivePrograms, LiveRows, MachineProgram, OutputsProgram, fields
from .reduced import DEAD_CENTRE_TRANSMISSION_DEG, ReducedSolution, ReducedStatics, smallest_sine
from .results import BatchResult, Result, ResultNames, Status
from .statics import StaticsLayout, StaticsSolution

ArrayMap = Mapping[str, "float | np.ndarray"]
_SOLVED = np.zeros(1, dtype=int)   # KinematicState.status of one solved pose (shared, read-only)
_SOLVED.flags.writeable = False
POSE_NAMES: tuple[str, ...] = POSE_VALUES.names or ()   # LiveRows.pose's fields
_OK = Status.OK.label


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
        self._dead_centre_sine = math.sin(math.radians(dead_centre_transmission_deg))
        self.consistency_tol = consistency_tol
        self.kin = kin = Kinematics(mech)
        self._check_kinematics_observable()
        # one statics layout per set of force-measured cylinders, all built now (attachments fixed)
        gauged = sorted({ps.cylinder for ps in mech.measurements.pressures})
        self._layouts = {frozenset(c for k, c in enumerate(gauged) if bits >> k & 1):
                         StaticsLayout(mech, kin, frozenset(c for k, c in enumerate(gauged) if bits >> k & 1))
                         for bits in range(2 ** len(gauged))}
        # the reduced-coordinate statics of each layout; ``served`` says whether it takes the layout's poses
        self._reduced = {known: ReducedStatics(kin, layout) for known, layout in self._layouts.items()}
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
        self._point_rows = np.array(list(self._point_att.values()), dtype=np.intp)   # attachments of mech.points
        # the frame loads of one pose as index arrays (``outputs_program``): hinges, then member ends
        self._frame_att = np.array([a for _, a, _ in self._frame_hinges] + [a for _, a, _ in self._frame_members],
                                   dtype=np.intp)
        self._frame_hinge_index = np.array([i for i, _, _ in self._frame_hinges], dtype=np.intp)
        self._frame_hinge_sign = np.array([[sg] for _, _, sg in self._frame_hinges]).reshape(-1, 1)
        self._frame_member_index = np.array([m for m, _, _ in self._frame_members], dtype=np.intp)
        self._frame_member_sign = np.array([[sg] for _, _, sg in self._frame_members]).reshape(-1, 1)
        self.names = ResultNames(tuple(self._point_att), tuple(b.name for b in mech.moving_bodies),
                                 tuple((h.name, h.bodies[1], h.bodies[0]) for h in mech.hinges),
                                 tuple(c.name for c in mech.cylinders), tuple(c.name for c in mech.contacts))
        self._per_cap_area = np.array([1.0 / (c.count * c.cap_area) for c in mech.cylinders])
        # count·cap area and count·rod area (2, C) m²: the measured force of the chambers' pressures
        self._force_areas = np.array([[c.count * c.cap_area for c in mech.cylinders],
                                      [c.count * c.rod_area for c in mech.cylinders]]).reshape(2, -1)
        self._friction = np.array([c.friction for c in mech.contacts])
        self._angle_reference = kin.angle_reference.tolist()   # rad, the angle inputs' readings in the reference pose
        self._cylinder_index = {c.name: k for k, c in enumerate(mech.cylinders)}
        self._outputs_programs: dict[frozenset[str], OutputsProgram] = {}
        self._plain: dict[tuple[tuple[str, ...], int], _PlainLive] = {}   # (pressure sensors, id(machine)) -> _solve_plain's
        self._live_programs: dict[tuple[frozenset[str], int], tuple[MachineProgram, LivePrograms]] = {}
        # largest constraint residual (m) of an assembled pose (kin.solve's): 1e-9·lc when closed exactly
        self._assembly_limit = 1e-9 * kin.lc if kin.m == kin.n else consistency_tol

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
        batch, ks = self._solve(start, arrays["cylinders"], arrays["angles"], arrays["pressures"], arrays["rates"],
                                arrays["accelerations"])
        res = batch.result(0)
        code = int(batch.status[0])
        if code in (Status.OK, Status.LIFT_OFF):
            return SolvedPose(replace(res, state=ks), None, None, None)
        raise {Status.INPUT: InputError, Status.ASSEMBLY: AssemblyError, Status.DEAD_CENTRE: DeadCentreError}[Status(code)](
            res.message)

    def explain(self) -> list[str]:
        """Whether reduced coordinates serve the statics of each set of measured cylinder forces and
        why, a line each (``reduced.ReducedStatics.describe``; the rule in reduced.py's docstring),
        and the dead-centre verdict each path gives."""
        served = (f"reduced coordinates: a dead centre where the smallest transmission angle is below "
                  f"{self.dead_centre_transmission_deg:g} deg (the kinematic steps' and the statics' alike)")
        general = (f"general path: a dead centre where the constraint Jacobian's or the equilibrium matrix's "
                   f"condition number exceeds {self.dead_centre_cond:.3g}")
        return [*(reduced.describe() for reduced in self._reduced.values()), served, general]

    def solve_batch(self, cylinders: ArrayMap | None = None, angles: ArrayMap | None = None,
                    pressures: ArrayMap | None = None, rates: ArrayMap | None = None,
                    accelerations: ArrayMap | None = None, *, reach: bool = True) -> BatchResult:
        """Solve N poses at once (arrays of shape (N,), scalars broadcast), from the reference pose.

        Per-pose failures are reported in ``status`` / ``messages``; unknown or missing input
        names and an unobservable mechanism raise. ``reach=False``: a pose out of reach is not
        told how far it is (``Kinematics.solve``; for sweeps that only need the status).
        """
        batch, _ = self._solve(None, cylinders or {}, angles or {}, pressures or {}, rates or {}, accelerations or {},
                               reach=reach)
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

    def _series_part(self, cylinders: ArrayMap, angles: ArrayMap, pressures: ArrayMap, machine: MachineProgram,
                     start: tuple[np.ndarray, np.ndarray]) -> _SeriesPart:
        """One part of a ``Series``: its poses solved in one compiled call from ``start`` (q (1, n), s (1,
        n_inputs)), each from the one before."""
        kin = self.kin
        n_pose, arrays = self._arrays(cylinders, angles, pressures, {}, {})
        s = self._input_matrix(arrays, n_pose, "inputs")
        bad = self._input_problems(s, arrays).bad
        s = kin.wrap_angles(np.where(bad[:, None], kin.reference_inputs(), s))
        cap, rod = self._chamber_pressures(arrays["pressures"], n_pose)
        layout = self.statics_layout(frozenset(self._sensors[n].cylinder for n in arrays["pressures"]))
        rows = kernels.live_rows(n_pose, kin.n, kin.m, self.outputs_program(layout), machine)
        buffer = kernels.live_buffer(fields(rows), s, np.ascontiguousarray(np.stack([cap, rod], axis=1)))
        kernels.live_series(self.live_programs(layout, machine), buffer, start[0], start[1], self._assembly_limit,
                            self.dead_centre_cond, 0, n_pose)
        return _SeriesPart(arrays, bad, s, rows, layout.force_known)

    def _series_batch(self, parts: list[_SeriesPart]) -> tuple[BatchResult, np.ndarray, np.ndarray, np.ndarray,
                                                               np.ndarray]:
        """``solve_series``' answer from the parts of a ``Series``, in order (the list is emptied: each
        row of the parts is let go once it is joined, so that joining takes little more memory than
        the rows)."""
        mech = self.mech

        def joined(columns: list[np.ndarray]) -> np.ndarray:
            return columns[0] if len(columns) == 1 else np.concatenate(columns)

        force_known = parts[0].force_known
        arrays = {kind: {name: joined([part.arrays[kind][name] for part in parts]) for name in parts[0].arrays[kind]}
                  for kind in ("cylinders", "angles", "pressures")}
        bad = joined([part.bad for part in parts])
        columns = [list(column) for column in zip(*(part.rows for part in parts))]
        parts.clear()
        rows_joined = []
        for k, column in enumerate(columns):
            rows_joined.append(joined(column))
            columns[k] = []
        rows = LiveRows(*rows_joined)
        n_pose = len(rows.plain)
        plain = rows.plain & ~bad
        batch = BatchResult.from_stacked(
            self.names, {h.name: h.bodies for h in mech.hinges}, rows.point_xz, rows.q.reshape(n_pose, -1, 3),
            rows.hinge_force, rows.cylinder_values, rows.contact_values, rows.pose["implement_load"],
            rows.implement_cg, list(self.frame_load_names), rows.frame_load_points, rows.frame_load_forces,
            rows.pose["residual"], rows.pose["consistency_residual"], rows.pose["condition"],
            rows.pose["largest_force"], rows.pose["transmission_angle"],
            self._weakest_names(self._reduced[force_known], rows.pose["weakest"]))
        general = np.flatnonzero(~plain)
        if general.size:
            def taken(group: Mapping[str, np.ndarray]) -> dict[str, np.ndarray]:
                return {n: v[general] for n, v in group.items()}
            other, _ = self._solve(None, taken(arrays["cylinders"]), taken(arrays["angles"]),
                                   taken(arrays["pressures"]), {}, {})
            batch.assign(general, other)
        return batch, rows.steerability, rows.capacity, rows.values, plain

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

    def _input_problems(self, s: np.ndarray, arrays: dict[str, dict[str, np.ndarray]]) -> _InputProblems:
        """Per pose: '' or what is wrong with its inputs (NaN/inf, length <= 0, p_abs < 0)."""
        kin = self.kin
        nc = kin.cyl_att.shape[1]
        problems = [""] * s.shape[0]
        pressures = list(arrays["pressures"].values())
        rates = list(arrays["rates"].values()) + list(arrays["accelerations"].values())
        if (np.isfinite(s).all() and (s[:, :nc] > 0.0).all() and all(np.isfinite(v).all() for v in rates)
                and all((v >= -ATMOSPHERIC_PRESSURE).all() and np.isfinite(v).all() for v in pressures)):
            return _InputProblems(problems, np.zeros(s.shape[0], dtype=bool))   # the usual case, whole-array
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
            for i in np.flatnonzero(values < -ATMOSPHERIC_PRESSURE):
                problems[i] = problems[i] or (f"pressure '{name}' is {values[i]:.0f} Pa gauge, i.e. a negative "
                                              f"absolute pressure: check the sensor and its zero offset")
        return _InputProblems(problems, np.array([bool(p) for p in problems]))

    def _chamber_pressures(self, pressures: Mapping[str, np.ndarray], n_pose: int) -> tuple[np.ndarray, np.ndarray]:
        """The cap and rod gauge pressures (N, C) Pa of every cylinder from the pressure sensors'
        readings (N,) by name; NaN where a chamber is not measured."""
        cap = np.full((n_pose, len(self.mech.cylinders)), np.nan)
        rod = cap.copy()
        for name, values in pressures.items():
            ps = self._sensors[name]
            (cap if ps.chamber == "cap" else rod)[:, self._cylinder_index[ps.cylinder]] = values
        return cap, rod

    def outputs_program(self, layout: StaticsLayout) -> OutputsProgram:
        """What ``kernels.live_series`` needs, beyond the layout's own program, to write a Result's
        arrays for poses solved with ``layout`` (its ``outputs``; built once per layout)."""
        program = self._outputs_programs.get(layout.force_known)
        if program is None:
            mech = self.mech
            imp = mech.implement
            reduced = self._reduced[layout.force_known]
            program = OutputsProgram(
                n_unknowns=layout.n_unknowns, spring_stiffness=layout.spring_stiffness.astype(float),
                spring_free_length=layout.spring_free_length.astype(float),
                spring_preload=layout.spring_preload.astype(float),
                hinge_cols=np.ascontiguousarray(layout.hinge_cols, dtype=np.int64),
                force_measured=layout.force_measured.astype(np.bool_), cylinder_cols=layout.cylinder_cols.astype(np.int64),
                contact_cols=layout.contact_cols.astype(np.int64),
                implement_col=layout.implement_col if layout.implement_col is not None else -1,
                implement_weight=float(imp.mass * mech.gravity if imp is not None else math.nan),
                per_cap_area=self._per_cap_area, force_areas=self._force_areas, friction=self._friction.astype(float),
                point_rows=self._point_rows.astype(np.int64), cg_att=self._cg_att if self._cg_att is not None else -1,
                frame_att=self._frame_att.astype(np.int64), frame_hinge_index=self._frame_hinge_index.astype(np.int64),
                frame_hinge_sign=self._frame_hinge_sign.ravel().astype(float),
                frame_member_index=self._frame_member_index.astype(np.int64),
                frame_member_sign=self._frame_member_sign.ravel().astype(float),
                reduced=reduced.served, dead_centre_sine=self._dead_centre_sine,
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
            programs = kernels.live_programs(fields(self.kin.program), fields(layout.program),
                                             fields(self.outputs_program(layout)),
                                             fields(self._reduced[layout.force_known].program), fields(machine))
            held = self._live_programs[key] = (machine, programs)
        return held[1]

    @staticmethod
    def _weakest_names(reduced: ReducedStatics, weakest: np.ndarray) -> list[str]:
        """The name of each pose's weakest transmission measure (``ReducedStatics.measure_names``; '' for −1)."""
        names = np.array([*reduced.measure_names, ""], dtype=object)   # index −1: ''
        return names[weakest].tolist()

    def _solve_plain(self, inputs: Inputs, start: KinematicState | None, machine: MachineProgram
                     ) -> SolvedPose | None:
        """The usual live pose in one compiled call (``kernels.live_series`` of one pose): every input given, finite
        and in range, no rates, assembled on the reference branch from ``start`` (or the reference
        pose), no dead centre, no contact lifting off. None for anything else: ``_solve`` then solves
        the pose and words what is wrong. Gives what ``_solve`` and ``MachineModel.evaluate`` would
        (test_mechanics_fast_paths.py)."""
        kin = self.kin
        if inputs.rates or inputs.accelerations or len(inputs.cylinders) + len(inputs.angles) != kin.n_inputs:
            return None
        nc = kin.cyl_att.shape[1]
        sensors = self._sensors
        try:
            values = [float(inputs.cylinders[n]) if j < nc else float(inputs.angles[n])
                      for j, n in enumerate(kin.input_names)]
            pressures = [(sensors[n], float(v)) for n, v in inputs.pressures.items()]
        except (KeyError, TypeError, ValueError):
            return None
        if not (all(math.isfinite(v) for v in values) and all(v > 0.0 for v in values[:nc])
                and all(math.isfinite(v) and v >= -ATMOSPHERIC_PRESSURE for _, v in pressures)):
            return None
        for j, reference in enumerate(self._angle_reference, start=nc):   # kin.wrap_angles on floats
            values[j] = reference + ((values[j] - reference + math.pi) % (2.0 * math.pi) - math.pi)
        cylinders = self.mech.cylinders
        cap, rod = [math.nan] * len(cylinders), [math.nan] * len(cylinders)
        for ps, value in pressures:
            (cap if ps.chamber == "cap" else rod)[self._cylinder_index[ps.cylinder]] = value
        live = self._plain_live(tuple(inputs.pressures), machine)
        block, i = live.rows.take()
        rows, s = block.rows, block.s
        s[i] = values
        block.pressures[i] = cap, rod
        start = start if start is not None else kin.reference
        kernels.live_series(live.programs, block.buffer, start.q[-1:], start.s[-1:], self._assembly_limit,
                            self.dead_centre_cond, i, i + 1)
        if not rows.plain[i]:
            return None
        q = rows.q[i:i + 1]
        state = KinematicState(s=s[i:i + 1], q=q, phi=rows.phi[i:i + 1], status=_SOLVED, messages=[""],
                               condition=rows.kinematic_condition[i:i + 1])
        pose = dict(zip(POSE_NAMES, rows.pose[i].item()))   # Python floats by name, in one call
        return SolvedPose(Result(self.names, rows.point_xz[i], q[0].reshape(-1, 3), rows.hinge_force[i],
                                 rows.cylinder_values[i], rows.contact_values[i], pose["implement_load"],
                                 rows.implement_cg[i], rows.frame_load_points[i], rows.frame_load_forces[i],
                                 pose["residual"], pose["consistency_residual"], pose["condition"],
                                 pose["largest_force"], _OK, state=state,
                                 transmission_angle=pose["transmission_angle"],
                                 weakest_transmission=live.measure_names[pose["weakest"]]),
                          rows.steerability[i], rows.capacity[i], rows.values[i])

    def _plain_live(self, sensors: tuple[str, ...], machine: MachineProgram) -> _PlainLive:
        """``_solve_plain``'s programs and rows for the pressure sensors ``sensors`` (in the order the
        inputs give them) and ``machine``, built once for each."""
        key = (sensors, id(machine))
        live = self._plain.get(key)
        if live is None or live.machine is not machine:   # the machine kept with it: its id is not reused
            layout = self.statics_layout(frozenset(self._sensors[n].cylinder for n in sensors))
            outputs, kin = self.outputs_program(layout), self.kin
            live = self._plain[key] = _PlainLive(
                machine=machine, programs=self.live_programs(layout, machine),
                measure_names=[*self._reduced[layout.force_known].measure_names, ""],
                rows=_RowPool(lambda n_pose: kernels.live_rows(n_pose, kin.n, kin.m, outputs, machine),
                              kin.n_inputs, len(self.mech.cylinders)))
        return live

    def _solve(self, previous: KinematicState | None, cylinders: ArrayMap, angles: ArrayMap, pressures: ArrayMap,
               rates: ArrayMap, accelerations: ArrayMap, *, reach: bool = True) -> tuple[BatchResult, KinematicState]:
        mech, kin = self.mech, self.kin
        n_pose, arrays = self._arrays(cylinders, angles, pressures, rates, accelerations)
        s = self._input_matrix(arrays, n_pose, "inputs")
        problems, bad = self._input_problems(s, arrays)
        s_clean = np.where(bad[:, None], kin.reference_inputs(), s)
        sensors = self._sensors
        force_known = frozenset(sensors[n].cylinder for n in arrays["pressures"])
        reduced = self._reduced[force_known]   # served: its transmission measure is the dead-centre verdict
        ks = kin.solve(s_clean, previous, None if reduced.served else self.dead_centre_cond, self.consistency_tol,
                       reach)
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
        cap_pressures, rod_pressures = self._chamber_pressures(arrays["pressures"], n_pose)
        measured_force = kernels.measured_forces(cap_pressures, rod_pressures, self._force_areas)
        measured_force[:, [k for k, c in enumerate(mech.cylinders) if c.name not in force_known]] = np.nan
        cap = {c.name: cap_pressures[:, k] for k, c in enumerate(mech.cylinders)}
        rod = {c.name: rod_pressures[:, k] for k, c in enumerate(mech.cylinders)}
        layout = self.statics_layout(force_known)
        sol: StaticsSolution | ReducedSolution
        if reduced.served:   # along the chain of dyads; a dead centre where the transmission is lost
            sol = reduced.solve(p, measured_force, accel)
            sine, weakest = sol.transmission.sine, sol.transmission.weakest
            smallest = smallest_sine(sine, weakest)
            names = self._weakest_names(reduced, weakest)
            for i in np.flatnonzero((status == Status.OK) & ~(smallest >= self._dead_centre_sine)):
                status[i] = Status.DEAD_CENTRE
                messages[i] = (f"dead centre at {kin.describe_inputs(s[i])}: transmission angle "
                               f"{math.degrees(math.asin(smallest[i])):.3g} deg at {names[i]} < "
                               f"{self.dead_centre_transmission_deg:g} deg (the linkage cannot hold a load there; "
                               f"forces would be unbounded)")
            angle, statics_condition = np.arcsin(smallest), np.full(n_pose, np.nan)
        else:   # one linear system; a dead centre where it is near-singular
            general = sol = layout.solve(p, measured_force, accel)
            for i in np.flatnonzero((status == Status.OK) & ~(general.condition <= self.dead_centre_cond)):
                status[i] = Status.DEAD_CENTRE
                messages[i] = (f"static dead centre at {kin.describe_inputs(s[i])}: equilibrium matrix condition "
                               f"number {general.condition[i]:.3g} > {self.dead_centre_cond:.3g} (a member is "
                               f"aligned with a hinge; forces would be unbounded)")
            angle, names, statics_condition = np.full(n_pose, np.nan), [""] * n_pose, general.condition
        u = sol.unknowns
        for contact in mech.contacts:
            normal = u[:, layout.contact_col[contact.name]]
            for i in np.flatnonzero((status == Status.OK) & (normal < 0.0)):
                status[i] = Status.LIFT_OFF
                messages[i] = f"contact '{contact.name}' lifts off: its normal force would be {normal[i]:.1f} N (pulling)"
        failed = status >= Status.INPUT
        q = np.where(failed[:, None], np.nan, ks.q)   # a copy: the state's q is where a solve continues
        if failed.any():   # no values of a failed pose (u and p are this solve's own arrays)
            u[failed], p[failed] = np.nan, np.nan
            names = np.where(failed, "", np.array(names, dtype=object)).tolist()
        batch = self._assemble(n_pose, q, p, u, sol, layout, measured_force, cap, rod, failed)
        batch.status, batch.messages = status, messages
        batch.consistency_residual = np.where(failed, np.nan, np.linalg.norm(ks.phi, axis=1))
        batch.condition = np.fmax(statics_condition, ks.condition)
        batch.transmission_angle = np.where(failed, np.nan, angle)
        batch.weakest_transmission = names
        return batch, ks

    def _assemble(self, n_pose: int, q: np.ndarray, p: np.ndarray, u: np.ndarray,
                  sol: "StaticsSolution | ReducedSolution", layout: StaticsLayout,
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
        hinges = np.stack(list(hinge_force.values()), axis=1) if hinge_force else np.zeros(shape)
        largest = kernels.largest_forces(hinges, np.ascontiguousarray(member_force[:, sol.spring_force.shape[1]:]))
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


class SolvedPose(NamedTuple):
    """``Solver.solve_with_machine``'s answer: the pose, and when the compiled call solved it its
    machine-level rows in ``MachineModel``'s key order and its value row (``programs.ValueRow``)
    (None: the general path solved the pose; ``MachineModel.evaluate`` gives the machine-level rows)."""

    result: Result
    steerability: np.ndarray | None
    capacity: np.ndarray | None
    values: np.ndarray | None


class _InputProblems(NamedTuple):
    """Per pose of a solve: what is wrong with its inputs ('' when nothing) and whether anything is (N,)."""

    problems: list[str]
    bad: np.ndarray


class _RowBlock(NamedTuple):
    """Rows of SIZE live poses (``_RowPool``): ``rows`` a ``LiveRows``, the inputs it solves them
    from, s (SIZE, n_inputs) and pressures (SIZE, 2, C), all in ``buffer`` (as
    ``kernels.live_series`` takes them)."""

    rows: LiveRows
    s: np.ndarray
    pressures: np.ndarray
    buffer: LiveBuffer


class _RowPool:
    """Rows for the live poses of one configuration, handed out one pose at a time (``take``). A
    Result holds views of its pose's rows, so a row is never handed out twice: when a block's rows
    are all taken, a new block is allocated (the old one lives on with the Results that hold it).
    Allocating the rows per pose took as long as solving the pose."""

    SIZE = 64

    def __init__(self, allocate: Callable[[int], LiveRows], n_inputs: int, n_cylinders: int) -> None:
        self._allocate, self._n_inputs, self._n_cylinders = allocate, n_inputs, n_cylinders
        self._lock = threading.Lock()   # one row per caller, from several threads too
        self._block, self._next = self._new_block(), 0

    def take(self) -> tuple[_RowBlock, int]:
        """The block and index of the next free row."""
        with self._lock:
            if self._next == self.SIZE:
                self._block, self._next = self._new_block(), 0
            self._next += 1
            return self._block, self._next - 1

    def _new_block(self) -> _RowBlock:
        rows = self._allocate(self.SIZE)
        s, pressures = np.empty((self.SIZE, self._n_inputs)), np.empty((self.SIZE, 2, self._n_cylinders))
        return _RowBlock(rows, s, pressures, kernels.live_buffer(fields(rows), s, pressures))


class Series:
    """A recorded series solved part by part as its inputs come (``add``), each pose from the one before
    across the parts, as ``Solver.solve_series`` solves it in one call: the same poses, bit for bit
    (``finish`` gives its answer). ``add`` may run in another thread while the caller reads the next
    inputs: the compiled call releases the GIL."""

    def __init__(self, solver: Solver, machine: MachineProgram) -> None:
        self._solver, self._machine = solver, machine
        reference = solver.kin.reference
        self._start = (reference.q[-1:], reference.s[-1:])   # the last pose the compiled series took
        self._parts: list[_SeriesPart] = []

    def add(self, cylinders: ArrayMap, angles: ArrayMap, pressures: ArrayMap) -> None:
        """The next poses (arrays (n,), the same inputs every time), solved now."""
        part = self._solver._series_part(cylinders, angles, pressures, self._machine, self._start)
        taken = np.flatnonzero(part.rows.plain)
        if taken.size:
            k = int(taken[-1])
            self._start = (part.rows.q[k:k + 1], part.s[k:k + 1])
        self._parts.append(part)

    def finish(self) -> tuple[BatchResult, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """``Solver.solve_series``' answer for every pose added (once: the parts are let go)."""
        return self._solver._series_batch(self._parts)


class _SeriesPart(NamedTuple):
    """The poses of one ``Series.add``: their inputs by kind and name, which are bad, the inputs as the
    compiled call took them (s), its rows, and the cylinders whose force the layout takes as measured."""

    arrays: dict[str, dict[str, np.ndarray]]
    bad: np.ndarray
    s: np.ndarray
    rows: LiveRows
    force_known: frozenset[str]


class _PlainLive(NamedTuple):
    """What ``Solver._solve_plain`` takes for one set of pressure sensors and one machine program:
    the machine program (kept: the cache's key holds its id), the ``LivePrograms``, the
    transmission measures' names (then '' for none, index −1), the rows it solves into."""

    machine: MachineProgram
    programs: LivePrograms
    measure_names: list[str]
    rows: _RowPool
