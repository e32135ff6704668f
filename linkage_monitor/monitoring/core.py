"""The monitoring core: sensor events in, domain results and findings out (no rclpy).

One core, two drivers. The live node hands each input event (``monitoring.events``) to ``step``
(each solve warm-starts from the last solved pose, which the core holds explicitly); the
replay hands a whole recording to ``run``, which takes every event through the same
acceptance stage, solves the due poses of each configuration segment as one series (each pose
from the one before, part by part in a worker thread while the next events are accepted), and
checks them all at once with the live path's rule (``checks.pose_checks``). Both return one ``Step``
per input event: a level, the findings (code + sentence naming the input and the reason), the
key-values for the diagnostic, and the solved ``Pose`` or None — nothing with garbage values.
Units SI (m, rad, N, Pa, kg); frame x forward, z up, origin at the rear wheels' ground contact.
"""

from __future__ import annotations

import math
from concurrent.futures import ThreadPoolExecutor
from dataclasses import replace
from typing import Iterable, Iterator, Sequence

import numpy as np

from linkage_monitor.mechanics import (AssemblyError, DeadCentreError, InputError, Inputs, LinkageError, Mechanism,
                                       Result, Solver, Status)
from linkage_monitor.mechanics.dynamics import DYNAMIC_MARGIN
from linkage_monitor.mechanics.machine import MachineBatch, MachineModel, MachineResult
from linkage_monitor.mechanics.programs import ValueRow
from linkage_monitor.mechanics.budget import Budget
from linkage_monitor.mechanics.uncertainty import UncertaintyModel

from .bounds import LimitRows, LimitUncertainties, budget_interval_checks, interval_checks
from .checks import Check, CheckedValues, pose_checks
from .config import MonitorConfig
from .events import ConfigEvent, Event, ImuEvent, InputEvent, JointStateEvent, PressureEvent, UnreadableEvent
from .findings import Code, Finding
from .implement_mass import ImplementMass, effective_mechanism
from .input_columns import InputColumns
from .motion import MotionTracker
from .inputs import DueRun, InputTracker, Refused
from .road import RoadInput
from .segment_series import INPUT_KINDS, Cut, SegmentSeries, input_columns, limit_values, segment_checks
from .steps import NO_FINDINGS, Due, DueColumns, Pose, QuietPoses, Run, Segment, Step, Steps
from .wording import failed_step, pose_findings

__all__ = ["ASSEMBLY_LIMIT_M", "NO_FINDINGS", "Monitor", "Pose", "Run", "Segment", "Step", "Steps"]

# A pose whose sensors misfit the closed linkage by more than this cannot be assembled from the inputs
# (an ERROR; up to checks.CONSISTENCY_WARN_M the misfit is sensor noise, between the two a WARN).
ASSEMBLY_LIMIT_M = 20e-3
EXCEPTION_STATUS = {InputError: Status.INPUT, AssemblyError: Status.ASSEMBLY, DeadCentreError: Status.DEAD_CENTRE}


_LIFT_OFF = Status.LIFT_OFF.label
WEIGHING_PIECE = 1024   # with the weighing, the batched path's longest piece: a new estimate is put in use after it
ACCEPT_BLOCK = 1024     # input events the batched path reads before it accepts them (runs of them at once)
ACCEPT_WINDOW_MIN = 16  # the shortest window a run is tried on; after a miss, this many events taken alone


class Monitor:
    """Mechanism + configuration -> solver, machine model and the latest inputs; events -> Steps.

    ``description`` is the mechanism as described (preset or file, without the configuration's
    overrides); the effective mechanism is ``apply_overrides(description, config.overrides)``, with
    the configured implement hung on and the weighing's estimate in use (``implement_mass``).
    """

    def __init__(self, description: Mechanism, config: MonitorConfig) -> None:
        self.description = description
        self.config = config
        self.weighing: ImplementMass | None = None
        self.road: RoadInput | None = None
        self._build(config, previous=None)

    # ---- configuration ---------------------------------------------------------------------
    def _build(self, config: MonitorConfig, previous: InputTracker | None) -> None:
        mech, weighing = effective_mechanism(self.description, config, self.weighing)
        tracker = InputTracker(mech, config)   # raises ValueError for a bad mapping: nothing changed yet
        solver = Solver(mech, consistency_tol=ASSEMBLY_LIMIT_M,
                        dead_centre_transmission_deg=config.dead_centre_transmission_deg)
        machine = MachineModel(mech, solver)
        if previous is not None:
            tracker.carry_over(previous)
        self.config, self.mechanism, self.tracker, self.solver, self.machine = config, mech, tracker, solver, machine
        self.weighing = weighing
        self.overdetermined = solver.kin.m > solver.kin.n
        self.estimates_load = bool(tracker.pressure_names)
        self.warm: Result | None = None   # the last solved pose: where the next live solve starts
        self.uncertainty = UncertaintyModel(machine) if config.uncertainty else None
        # the rows of the values judged against a limit in every budget (``bounds.budget_interval_checks``)
        self._limit_rows = LimitRows.of(self.uncertainty.table.index if self.uncertainty is not None else {})
        self.motion = MotionTracker.of(mech, mech.error_sources)
        # the IMU (mechanics.dynamics): with a topic and a tractor block only; its readings carried over
        road = (RoadInput(mech, config, bool(tracker.pressure_names)) if config.topics.imu and machine.has_steerability
                else None)
        if road is not None and self.road is not None:
            road.carry_over(self.road)
        self.road = road
        self._steer_at = ValueRow.of(len(mech.hinges), len(mech.points), len(mech.cylinders),
                                     len(machine.capacity_keys), len(machine.steerability_keys)).steerability

    def load_kernels(self) -> None:
        """Solve the mechanism's reference pose once, cold and warm-started, with its machine-level
        results, and forget it: numba loads each compiled kernel from its cache at the first call
        (milliseconds each), which is better paid at start-up than on the first inputs; the same for
        the IMU's ground-contact zone (a sweep of the stroke)."""
        if self.road is not None:
            self.road.ground()
        reference = Inputs(**{k: dict(v) for k, v in self.mechanism.reference_inputs.items()})
        try:
            self.machine.evaluate(self.machine.solve(reference, previous=self.solver.solve(reference))[0])
        except LinkageError:
            pass   # a reference pose that does not solve is the file's problem, reported at the first input

    def reconfigure(self, config: MonitorConfig) -> None:
        """Apply a new configuration from the next event on (the latest readings are kept)."""
        self._build(config, previous=self.tracker)

    def select_implement(self, implement: str) -> MonitorConfig:
        """Hang the bundled implement or implement file ``implement`` ('' the mechanism file's) from the
        next event on, without a restart; returns the new configuration (to record). MechanismFileError
        naming the file, with nothing changed, when it is not one for this mechanism."""
        self.reconfigure(replace(self.config, implement=implement))
        return self.config

    def _weigh(self, steps: Iterable[tuple[Step | None, Due]]) -> None:
        """The weighing's look at solved steps in input order, each with its due (``implement_changed``
        added while the mass in use is stale); with an IMU reading, the body's vertical acceleration at
        the implement's cg tells it a bouncing implement."""
        weighing = self.weighing
        for step, due in steps:
            if weighing is not None and step is not None and step.pose is not None:
                result = step.pose.result
                weighing.observe(step.stamp_ns, result,
                                 float(due.body.acceleration.at(result.implement_cg[0])) if due.body is not None
                                 else None)
                step.weighing = weighing.state()
                finding = weighing.finding()
                if finding is not None:
                    step.findings += (finding,)

    def _use_estimate(self) -> bool:
        """Put the weighing's new estimate in use, if it has one (the mechanism rebuilt with it): True then."""
        estimate = self.weighing.pending() if self.weighing is not None else None
        if estimate is not None:
            self.weighing.put_in_use(estimate)  # type: ignore[union-attr]  # not None with an estimate
            self._build(self.config, previous=self.tracker)
        return estimate is not None

    # ---- the live path: one event at a time ------------------------------------------------------
    def on_joint_state(self, names: Sequence[str], positions: Sequence[float], velocities: Sequence[float],
                       stamp_ns: int, receive_ns: int, topic: str = "joint_states") -> Step:
        """``step`` of the JointStateEvent of these values."""
        return self.step(JointStateEvent(topic, names, positions, velocities, stamp_ns, receive_ns))

    def on_pressure(self, topic: str, fluid_pressure: float, stamp_ns: int, receive_ns: int) -> Step:
        """``step`` of the PressureEvent of these values."""
        return self.step(PressureEvent(topic, fluid_pressure, stamp_ns, receive_ns))

    def step(self, event: InputEvent) -> Step:
        """One input event end to end: accept, solve (warm start from the last solved pose), finish.
        Never raises (an internal failure is an ERROR Step); an UnreadableEvent is an ERROR Step and
        the last solved pose stays the warm start."""
        try:
            due = self._accept(event)
            if isinstance(due, Step):
                return due
            try:
                result, machine, values = self.machine.solve(due.inputs, previous=self.warm)
            except LinkageError as exc:
                self.warm = None
                return failed_step(due, EXCEPTION_STATUS.get(type(exc), Status.INPUT), str(exc))
            self.warm = result
            step = self._finish(due, result, machine, values)
            if self.weighing is not None:   # off by default: nothing added to the live step
                self._weigh(((step, due),))
                self._use_estimate()
            return step
        except Exception as exc:  # noqa: BLE001 - the adapter boundary: report, forget the warm start, go on
            return self._internal_error(event, exc)

    # ---- the batched path: a whole recording -----------------------------------------------------
    def run(self, events: Iterable[Event | InputColumns]) -> Run:
        """One Step per input event (ConfigEvents give none), the due poses solved in batches: a
        segment's series part by part in a worker thread while the next events are accepted
        (``SegmentSeries``); ``runs`` joined, one ``Segment`` per configuration segment."""
        steps: list[Step] = []
        segments: list[Segment] = []
        for piece in self.runs(events):
            segments.extend(replace(segment, steps=segment.steps + len(steps)) for segment in piece.segments)
            steps.extend(piece.steps)
        return Run(Steps(list(steps)), segments)

    def runs(self, events: Iterable[Event | InputColumns], piece_steps: int | None = None) -> Iterator[Run]:
        """``run`` in pieces, in order: a piece ends at each configuration change and, given
        ``piece_steps``, after every ``piece_steps`` Steps of a configuration segment (its series solved on
        across the pieces, each pose from the one before, as ``run`` solves it). A piece's segments
        index its own ``steps``. While the caller holds a piece the monitor is in that piece's
        configuration: the events of the next piece of the same configuration may have been read and
        accepted (without the weighing, a piece is handed over once the next is read, its series solved
        in the worker meanwhile), no further. What the caller lets go of a piece is freed, so that a
        recording read piece by piece takes memory flat in its length."""
        steps: list[Step | None] = []   # None: not solved yet, or a quiet pose (``QuietPoses``)
        held: tuple[Cut, list[Step | None]] | None = None   # a piece cut, handed over after the next is read
        with ThreadPoolExecutor(max_workers=1, thread_name_prefix="series") as worker:
            segment = SegmentSeries(self.machine, self.config.kinetostatics, worker)
            pending: list[InputEvent | InputColumns] = []   # read, not yet accepted: ACCEPT_BLOCK at a time
            size = 0   # the events pending

            def accept_pending() -> None:
                nonlocal size
                for due in self._accept_all(pending):
                    if isinstance(due, Step):
                        steps.append(due)
                    elif isinstance(due, DueColumns):
                        segment.add_columns(len(steps), due)
                        steps.extend([None] * len(due))
                    else:
                        segment.add(len(steps), due)
                        steps.append(None)
                pending.clear()
                size = 0

            for event in events:
                if isinstance(event, ConfigEvent):
                    accept_pending()
                    if held is not None:
                        yield self._piece(*held)
                        held = None
                    cut = segment.cut()
                    if steps:
                        yield self._piece(cut, steps)
                        steps = []
                    self.reconfigure(event.config)
                    segment = SegmentSeries(self.machine, self.config.kinetostatics, worker)
                    continue
                rest: InputEvent | InputColumns | None = event
                while rest is not None:   # columns split where a piece ends
                    limit = piece_steps if self.weighing is None else min(piece_steps or WEIGHING_PIECE, WEIGHING_PIECE)
                    room = limit - len(steps) - size if limit is not None else None
                    item, rest = rest, None
                    if isinstance(item, InputColumns) and room is not None and item.size > room:
                        item, rest = item.head(room), item.tail(room)
                    pending.append(item)
                    size += item.size if isinstance(item, InputColumns) else 1
                    full = limit is not None and len(steps) + size >= limit
                    if full or size >= ACCEPT_BLOCK:
                        accept_pending()
                    if not full:
                        continue
                    cut, cut_steps, steps = segment.cut(), steps, []
                    if self.weighing is not None:   # the estimate after this piece applies to the next
                        yield self._piece(cut, cut_steps)
                        if self._use_estimate():   # a new estimate: the next poses solved with it
                            segment = SegmentSeries(self.machine, self.config.kinetostatics, worker)
                        continue
                    if held is not None:
                        yield self._piece(*held)
                    held = (cut, cut_steps)
            accept_pending()
            if held is not None:
                yield self._piece(*held)
            cut = segment.cut()
            if steps:
                yield self._piece(cut, steps)

    def _piece(self, cut: Cut, steps: list[Step | None]) -> Run:
        """The piece of ``steps`` (None where a due of ``cut`` is), its dues solved and checked."""
        segments: list[Segment] = []
        quiet: list[QuietPoses] = []
        self._solve_segment(cut, steps, segments, quiet)
        return Run(Steps(steps, quiet), segments)

    def _accept_all(self, items: Sequence[InputEvent | InputColumns]) -> list[Due | DueColumns | Step]:
        """``_accept`` of each event of ``items`` in turn (an internal failure an ERROR Step, as in
        ``step``), the runs of events of one form taken as columns (``_accept_columns``)."""
        found: list[Due | DueColumns | Step] = []
        events: list[InputEvent] = []
        for item in [*items, None]:
            if isinstance(item, InputColumns) or item is None:
                i = 0
                while i < len(events):
                    columns = InputColumns.of_events(events[i:i + ACCEPT_BLOCK])
                    if columns is None:
                        found.append(self._accept_safely(events[i]))
                        i += 1
                    else:
                        found += self._accept_columns(columns)
                        i += columns.size
                events.clear()
                if item is not None:
                    found += self._accept_columns(item)
            else:
                events.append(item)
        return found

    def _accept_columns(self, columns: InputColumns) -> list[Due | DueColumns | Step]:
        """``_accept`` of each event of ``columns``, the runs the tracker accepts at once taken at once
        (``InputTracker.accept_run``: the same rules on arrays); each event it stops at taken alone, then
        the next run tried, on a window that grows while the runs are long and shrinks while they are
        short (after a run of none, a few events taken alone)."""
        found: list[Due | DueColumns | Step] = []
        i, window = 0, ACCEPT_BLOCK
        while i < columns.size:
            tried = columns.tail(i).head(window)
            run = self.tracker.accept_run(tried)
            if run.accepted:
                found += self._dues(tried, run)
            i += run.accepted
            window = min(ACCEPT_BLOCK, max(ACCEPT_WINDOW_MIN, 2 * run.accepted))
            alone = 0 if run.accepted == tried.size else 1 if run.accepted else ACCEPT_WINDOW_MIN
            for k in range(i, min(i + alone, columns.size)):
                found.append(self._accept_safely(columns.event(k)))
            i = min(i + alone, columns.size)
        return found

    def _accept_safely(self, event: InputEvent) -> Due | Step:
        """``_accept``, an internal failure an ERROR Step (as in ``step``)."""
        try:
            return self._accept(event)
        except Exception as exc:  # noqa: BLE001 - as in step()
            return self._internal_error(event, exc)

    def _dues(self, columns: InputColumns, run: DueRun) -> list[Due] | list[DueColumns]:
        """The due solves of the first ``run.accepted`` events of ``columns``, accepted at once (``_accept``'s):
        as columns, unless a Due carries more (the cylinders' motions with the error budget, an IMU's body)."""
        due = DueColumns(columns.stamps_ns[:run.accepted], columns.topics[:run.accepted], run.cylinders, run.angles,
                         run.pressures)
        if self.uncertainty is None and self.road is None:
            return [due]
        return [Due(d.stamp_ns, d.trigger, d.inputs,
                    self.motion.motions(d.inputs, d.stamp_ns) if self.uncertainty is not None else None,
                    self.road.body_at(d.stamp_ns) if self.road is not None else None)
                for d in due.dues(np.arange(run.accepted))]

    def _solve_segment(self, cut: Cut, steps: list[Step | None], segments: list[Segment],
                       quiet: list[QuietPoses]) -> None:
        """The Steps of the dues of ``cut`` (solved, checked, put in their places in ``steps``) and their
        ``Segment``, in the configuration they were accepted in (the monitor's until the next one). A pose
        solved by the series whose checks found nothing, in a configuration that adds nothing to its Step
        (no error budget, IMU or weighing), is left None in ``steps`` and goes to ``quiet``: its Step is
        built when asked for (``Steps``)."""
        taken, series = cut.dues, cut.series()
        if not len(taken):
            return
        if series is None:   # kinetostatics (rates and accelerations): the general path
            dues = taken.all()
            c = {kind: input_columns(dues, kind) for kind in INPUT_KINDS}
            batch = self.solver.solve_batch(cylinders=c["cylinders"], angles=c["angles"], pressures=c["pressures"],
                                            rates=c["rates"], accelerations=c["accelerations"])
            machine = self.machine.evaluate_batch(batch)
            values, plain = np.zeros((len(batch), 0)), np.zeros(len(batch), bool)
        else:   # each pose from the one before, as the live path solves them
            batch, machine = series.batch, series.machine
            values, plain = series.values, series.plain   # a row is the pose's where plain
        dynamic: np.ndarray | list[None] = [None] * len(batch)
        if self.road is not None:
            balance = self.road.balance(taken.stamps_ns, batch.frame_load_points, batch.frame_load_forces,
                                        batch.implement_load, batch.implement_cg[:, 0], batch.cylinder_length,
                                        [due.body for due in taken.all()])
            machine = MachineBatch(dict(zip(machine.steerability, balance.static.T)), machine.lift_capacity,
                                   machine.size)
            values = self._with_static(values, balance.static) if plain.any() else values
            dynamic = balance.dynamic
        checks = segment_checks(batch, machine, balance.dynamic[:, DYNAMIC_MARGIN] if self.road is not None else None)
        adds_nothing = self.uncertainty is None and self.road is None and self.weighing is None
        still = ((batch.status < Status.INPUT) & (checks == 0) & plain if adds_nothing
                 else np.zeros(len(batch), bool))
        said = np.flatnonzero(~still)   # every pose with the error budget on
        results, machine_results = batch.results(said), machine.results(said)
        said_dues = taken.dues(said)
        budgets = self._budgets(said_dues, results, machine_results, batch.status[said])
        if self.uncertainty is not None:
            front, rear, margin, reserve = limit_values(machine, len(batch))
            checks = checks + interval_checks(front, rear, margin, reserve, LimitUncertainties(*(
                np.array([getattr(LimitUncertainties.of(b), f) if b is not None else math.nan for b in budgets])
                for f in LimitUncertainties._fields)))
        for k, due, result, machine_result, budget in zip(said.tolist(), said_dues, results, machine_results, budgets):
            i, status = int(taken.steps[k]), int(batch.status[k])
            pose = Pose(result, machine_result, values[k] if plain[k] else None, budget, dynamic[k])
            steps[i] = (self._pose_step(due, pose, int(checks[k])) if status < Status.INPUT
                        else failed_step(due, Status(status), batch.messages[k]))
        if self.weighing is not None:
            self._weigh((steps[i], due) for i, due in zip(taken.steps.tolist(), taken.all()))
        solved = Segment(taken.steps, taken.stamps_ns, batch, machine, self.mechanism, self.config)
        segments.append(solved)
        if still.any():
            rows = np.flatnonzero(still)
            quiet.append(QuietPoses(solved.steps[rows], rows, solved, values[rows], taken.dues))

    # ---- the stages both paths share -------------------------------------------------------------
    def _accept(self, event: InputEvent) -> Due | Step:
        """Take the event's values (or refuse it whole); the due solve, or the Step that ends here."""
        tracker = self.tracker
        if isinstance(event, UnreadableEvent):
            return Step(event.stamp_ns, event.topic, (Finding(Code.MALFORMED_INPUT, (
                f"input on {event.topic} ({event.size} bytes) cannot be read as {event.type_name}: {event.reason}; "
                "recorded, not solved")),))
        if isinstance(event, ImuEvent):
            return self._accept_imu(event)
        try:
            if isinstance(event, JointStateEvent):
                tracker.accept_joint_state(event.names, event.positions, event.velocities, event.stamp_ns,
                                           event.receive_ns)
            else:
                tracker.accept_pressure(event.topic, event.fluid_pressure, event.stamp_ns, event.receive_ns)
        except Refused as refused:
            return Step(event.stamp_ns, event.topic, (refused.finding,))
        inputs = tracker.inputs_at(event.stamp_ns)
        if isinstance(inputs, Finding):   # an input missing or stale: a misspelt joint name is named
            unknown = tracker.unknown_joints_finding(event.stamp_ns)
            return Step(event.stamp_ns, event.topic, (inputs,) if unknown is None else (inputs, unknown))
        return Due(event.stamp_ns, event.topic, inputs,
                   self.motion.motions(inputs, event.stamp_ns) if self.uncertainty is not None else None,
                   self.road.body_at(event.stamp_ns) if self.road is not None else None)

    def _accept_imu(self, event: ImuEvent) -> Step:
        """Take an IMU message for the solves after it (``road``); its Step solves nothing (a finding
        when it is refused)."""
        if self.road is None:   # no IMU configured, or no tractor to apply it to
            return Step(event.stamp_ns, event.topic)
        try:
            self.tracker.check_stamp(f"Imu on topic '{event.topic}'", event.stamp_ns, event.receive_ns)
            self.road.accept(event)
        except Refused as refused:
            return Step(event.stamp_ns, event.topic, (refused.finding,))
        return Step(event.stamp_ns, event.topic)

    def _internal_error(self, event: InputEvent, exc: Exception) -> Step:
        self.warm = None
        text = (f"internal error while processing {event.topic} (stamp {event.stamp_ns} ns): "
                f"{type(exc).__name__}: {exc}; the input was recorded, the monitor goes on")
        return Step(event.stamp_ns, event.topic, (Finding(Code.INTERNAL_ERROR, text),))

    def _finish(self, due: Due, result: Result, machine: MachineResult, values: np.ndarray | None) -> Step:
        """The Step of one solved pose with its machine-level results and value row, if any
        (``checks.pose_checks``; with the uncertainty, ``bounds.budget_interval_checks`` too; with an IMU
        reading, the axle loads on the road: ``road``)."""
        dynamic = None
        if self.road is not None:
            balance = self.road.balance(np.array([due.stamp_ns]), result.frame_load_points[None],
                                        result.frame_load_forces[None],
                                        np.array([result.implement_load]), result.implement_cg[:1],
                                        dict(zip(result.names.cylinders, result.cylinder_values[:, None, 0])),
                                        [due.body])
            machine = MachineResult(balance.static[0], machine.capacity_row, machine.steerability_keys,
                                    machine.capacity_keys)
            values = self._with_static(values, balance.static[0]) if values is not None else None
            dynamic = balance.dynamic[0]
        limits = (machine.value("front_axle_load"), machine.value("rear_axle_load"), machine.value("margin"),
                  machine.value("reserve"))
        checks = int(pose_checks(CheckedValues(result.status == _LIFT_OFF, result.consistency_residual,
                                               result.residual, result.largest_force, *limits,
                                               result.load_amplification,
                                               dynamic[DYNAMIC_MARGIN] if dynamic is not None else math.nan)))
        budget = self._budget(due, result, machine) if self.uncertainty is not None else None
        if budget is not None:
            checks += budget_interval_checks(*limits, budget, self._limit_rows)
        return self._pose_step(due, Pose(result, machine, values, budget, dynamic), checks)

    def _with_static(self, values: np.ndarray, static: np.ndarray) -> np.ndarray:
        """A copy of the value row(s) ``values`` with the steerability row(s) ``static`` in their place."""
        values = values.copy()
        values[..., self._steer_at: self._steer_at + static.shape[-1]] = static
        return values

    def _budgets(self, dues: Sequence[Due], results: Sequence[Result], machines: Sequence[MachineResult],
                 status: Sequence[int] | np.ndarray) -> list[Budget | None]:
        """The error budget of each solved pose (None for a failed one, or when the configuration does
        not ask for them), each cylinder's seal friction by its motion since the due before."""
        if self.uncertainty is None:
            return [None] * len(dues)
        return [self._budget(due, result, machine) if code < Status.INPUT else None
                for due, result, machine, code in zip(dues, results, machines, status)]

    def _budget(self, due: Due, result: Result, machine: MachineResult) -> Budget:
        """The error budget of one solved pose (with ``MonitorConfig.uncertainty``), each cylinder's seal
        friction by its motion since the due before."""
        assert self.uncertainty is not None
        return self.uncertainty.budget(due.inputs, result, machine, due.motions or {})

    def _pose_step(self, due: Due, pose: Pose, checks: int) -> Step:
        """The Step of a solved pose whose failed checks are ``checks`` (``Check`` bits)."""
        findings = pose_findings(Check(checks), pose, self.mechanism) if checks else ()
        return Step(due.stamp_ns, due.trigger, findings, pose, due.inputs)
