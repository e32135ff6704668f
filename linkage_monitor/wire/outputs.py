"""Monitoring steps -> the package's output messages (used by the live node and the replay).

The three outputs of a solved pose (HingeReactions, HitchState, Steerability) are written
straight to their CDR bytes: published as serialized messages and recorded as they are, with no
rclpy message object in between. Their layout comes from msg/*.msg (``wire.layout``); the values
are named by field here. It is fixed for a mechanism (hinge, cylinder and body names) up to the
status texts, so ``OutputEncoder`` lays it out once per status text (``wire.template``) and fills
the numbers of each pose in — of one pose (the node) or of a whole recording's poses at once (the
replay), the same bytes.

With the error budget on (``MonitorConfig.uncertainty``) the ``*_u`` fields carry each value's
standard uncertainty (1 sigma, ``Pose.budget``); with the weighing on (``implement_mass_source``
other than ``file``) HitchState carries its estimate and state (``Step.weighing``). Both are
columns after the value row's (``_extra_row``); when they are off the fields are NaN (and the
weighing's state fields zero) in the template itself: nothing is added to the default step.

Units SI (m, N, Pa, kg); frame x forward, z up, origin at the rear wheels' ground contact.
Every output carries the header stamp of the triggering input, never wall-clock time.
"""

from __future__ import annotations

import functools
import math
from typing import Any, Callable, Hashable, NamedTuple, Sequence

import numpy as np

from linkage_monitor.mechanics import Mechanism, Result
from linkage_monitor.mechanics.dynamics import DYNAMIC_KEYS
from linkage_monitor.mechanics.machine import STEERABILITY_KEYS
from linkage_monitor.mechanics.programs import ROW_SCALARS, ValueRow
from linkage_monitor.mechanics.results import CylinderResult
from linkage_monitor.monitoring.core import NO_FINDINGS, Monitor, Pose, Step, Steps
from linkage_monitor.monitoring.findings import Code, Level
from linkage_monitor.monitoring.implement_mass import WeighingState
from linkage_monitor.monitoring.road import NO_DYNAMIC

from .compose import STAMP, Column, Composer, Flag
from .layout import constants
from .template import Template

FRAME_ID = "base_footprint"  # REP 105 frame at the ground below the tractor: x forward, z up
HINGE_REACTIONS, HITCH_STATE, STEERABILITY = ("linkage_monitor/msg/HingeReactions", "linkage_monitor/msg/HitchState",
                                              "linkage_monitor/msg/Steerability")
# HitchState's capacity fields <- MachineResult.lift_capacity keys
CAPACITY_FIELDS = {"lift_capacity_hitch_axis": "hitch_axis", "lift_capacity_610mm": "behind_610mm",
                   "lift_capacity_implement_cg": "implement_cg", "lift_reserve": "reserve"}
# Steerability's float64 fields are MachineResult.steerability keys and, with an IMU, mechanics.dynamics.DYNAMIC_KEYS
# (Pose.dynamic) of the same names
# the standard uncertainty fields (1 sigma) <- the error budget's outputs (mechanics.output_table.OutputTable)
HITCH_UNCERTAINTIES = {"implement_load_u": "implement_load",
                       "lift_capacity_hitch_axis_u": "lift_capacity.hitch_axis",
                       "lift_capacity_610mm_u": "lift_capacity.behind_610mm",
                       "lift_capacity_implement_cg_u": "lift_capacity.implement_cg", "lift_reserve_u": "lift_reserve"}
STEERABILITY_UNCERTAINTIES = {"front_axle_load_u": "front_axle_load", "rear_axle_load_u": "rear_axle_load",
                              "ratio_u": "steerability_ratio", "margin_u": "steerability_margin"}
# HitchState's weighing estimate fields, in the order of ``weighing_row``'s columns
WEIGHING_FIELDS = ("implement_mass_estimate", "implement_mass_estimate_u", "implement_cg_x_estimate",
                   "implement_cg_x_estimate_u", "implement_cg_z_estimate", "implement_cg_z_estimate_u")
_NO_ESTIMATE = (math.nan,) * len(WEIGHING_FIELDS)
HINGE_TAIL, HITCH_TAIL = "status", "status_text"   # the first field of each message's varying tail


class Outputs(NamedTuple):
    """The three output messages of one solve, serialized (CDR, as published and recorded)."""

    hinge_reactions: bytes
    hitch_state: bytes
    steerability: bytes


class OutputRows(NamedTuple):
    """Output messages of one kind and one layout for several steps (``OutputEncoder.output_rows``):
    ``kind`` the ``Outputs`` field they are, ``steps`` (n,) the steps' indices, ``rows`` (n, size) uint8
    their CDR bytes, a row per step."""

    kind: str
    steps: np.ndarray
    rows: np.ndarray


class _Statuses(NamedTuple):
    """The status constants of HingeReactions and HitchState (from their definitions)."""

    hinge_ok: int
    hinge_overdetermined: int
    hinge_high_residual: int
    hitch_ok: int
    hitch_warn: int


@functools.cache
def _statuses() -> _Statuses:
    hinge, hitch = constants(HINGE_REACTIONS), constants(HITCH_STATE)
    return _Statuses(hinge["STATUS_OK"], hinge["STATUS_OVERDETERMINED"], hinge["STATUS_HIGH_RESIDUAL"],
                     hitch["STATUS_OK"], hitch["STATUS_WARN"])


def hinge_status(step: Step, result: Result, overdetermined: bool) -> tuple[int, str]:
    """HingeReactions.status and status_text: HIGH_RESIDUAL when the measured pressures disagree,
    OVERDETERMINED when more measurements than degrees of freedom were solved by least squares."""
    for finding in step.findings:
        if finding.code is Code.PRESSURES_DISAGREE:
            return _statuses().hinge_high_residual, finding.text
    return solve_status(result.message, overdetermined)


def solve_status(message: str, overdetermined: bool) -> tuple[int, str]:
    """HingeReactions.status and status_text of a solved pose without a finding on its pressures:
    OVERDETERMINED or OK, with the solve's ``message`` (``Result.message``; 'ok' when empty)."""
    statuses = _statuses()
    return statuses.hinge_overdetermined if overdetermined else statuses.hinge_ok, message or NO_FINDINGS


def hitch_status(step: Step) -> int:
    """HitchState.status of a solved step (WARN with any warning finding)."""
    statuses = _statuses()
    return statuses.hitch_warn if step.findings and step.level == Level.WARN else statuses.hitch_ok


def steerability_reference(mech: Mechanism) -> int:
    """Steerability.reference: which weight the mechanism's ``ratio`` is taken of."""
    reference = mech.tractor.steerability_reference if mech.tractor else "unit"
    return constants(STEERABILITY)["REFERENCE_TRACTOR" if reference == "tractor" else "REFERENCE_UNIT"]


def weighing_row(state: WeighingState) -> tuple[float, ...]:
    """HitchState's WEIGHING_FIELDS of a step's weighing (kg, m; NaN without an estimate, a cg
    coordinate and its uncertainty NaN where the strokes do not identify it)."""
    e = state.estimate
    if e is None:
        return _NO_ESTIMATE
    x = (e.cg_x, e.cg_x_u) if e.cg_x_identified else (math.nan, math.nan)
    z = (e.cg_z, e.cg_z_u) if e.cg_z_identified else (math.nan, math.nan)
    return (e.mass, e.mass_u, *x, *z)


def weighing_flags(state: WeighingState | None) -> tuple[int, int, int]:
    """HitchState's weighing_phase, weighing_confident and implement_mass_in_use of a step's weighing
    (None: the estimator is off, or the step was not solved)."""
    c = constants(HITCH_STATE)
    if state is None:
        return c["WEIGHING_OFF"], 0, c["MASS_FROM_FILE"]
    return (c["WEIGHING_" + state.phase.name], int(state.confident),
            c["MASS_FROM_ESTIMATE" if state.estimate_in_use else "MASS_FROM_FILE"])


class OutputEncoder:
    """Writes the three output messages of solved steps as CDR bytes.

    The layout follows the monitor's effective mechanism and is laid out again when the monitor
    is reconfigured. A message's fixed part (names, counts) is a ``Template``; the status texts
    after it make one template per text (kept for the texts seen last, ``MAX_TEMPLATES``).
    ``outputs`` writes one step's messages (the live node), ``output_rows`` those of many steps at
    once, the same bytes as rows (the replay: each template filled for all its steps in a few array
    operations, recorded without a bytes object per message).
    """

    MAX_TEMPLATES = 64   # per message type: most steps share "ok"; texts with numbers in them are not kept long

    def __init__(self) -> None:
        self._machine: object | None = None   # the monitor's MachineModel laid out for (rebuilt with each configuration)

    def outputs(self, monitor: Monitor, step: Step) -> Outputs | None:
        """The serialized outputs of ``step`` (a step of ``monitor``), or None without a solved pose."""
        if step.pose is None:
            return None
        if monitor.machine is not self._machine:
            self._lay_out(monitor)
        pose, stamp = step.pose, step.stamp_ns
        result = pose.result
        source = pose.values if pose.values is not None else monitor.machine.value_rows([result], [pose.machine])[0]
        flags: tuple[int, ...] = (hitch_status(step),)
        if self._extra_width:   # the error budget, the weighing or an IMU: off by default
            source = np.concatenate([source, self._extra_row(step)])
            flags += weighing_flags(step.weighing) if self._weighed else ()
        hinges = self._hinge_template(hinge_status(step, result, self._overdetermined))
        hitch = self._hitch_template(step.message)
        return Outputs(hinges.fill(stamp, source.take(hinges.columns)),
                       hitch.fill(stamp, source.take(hitch.columns), flags),
                       self._steerability.fill(stamp, source.take(self._steerability.columns)))

    def output_rows(self, monitor: Monitor, steps: Sequence[Step]) -> list[OutputRows]:
        """The messages ``outputs`` gives each of ``steps`` (steps of ``monitor`` in its present
        configuration), as rows: per message kind, one ``OutputRows`` per layout (status text). The quiet
        poses of ``Steps`` are taken from their segments' columns, their Steps not built."""
        steps = steps if isinstance(steps, Steps) else Steps(list(steps))
        solved = [(k, step) for k, step in steps.said() if step.pose is not None]
        if not solved and not steps.quiet:
            return []
        if monitor.machine is not self._machine:
            self._lay_out(monitor)
        poses = [step for _, step in solved]
        results = [step.pose.result for step in poses]   # type: ignore[union-attr]  # solved: a pose each
        source = (_value_rows(monitor, [step.pose for step in poses]) if poses  # type: ignore[misc]  # solved: a pose each
                  else np.zeros((0, self._row_width)))
        stamps = np.array([step.stamp_ns for step in poses], dtype=np.int64)
        hinge_keys = [hinge_status(step, result, self._overdetermined) for step, result in zip(poses, results)]
        if self._extra_width:
            source = np.concatenate([source, np.stack([self._extra_row(step) for step in poses])], axis=1)
        flags = np.array([(hitch_status(step), *weighing_flags(step.weighing)) if self._weighed
                          else (hitch_status(step),) for step in poses],
                         dtype=np.uint8).reshape(len(poses), 1 + 3 * self._weighed)   # Flag(0..3): status, weighing
        index, texts = np.array([k for k, _ in solved], dtype=np.intp), [step.message for step in poses]
        if steps.quiet:   # no finding, no budget, weighing or IMU (QuietPoses): OK and the solve's own status
            assert not self._extra_width, "a quiet pose's configuration adds no columns"
            quiet = steps.quiet
            index = np.concatenate([index, *(q.index for q in quiet)])
            source = np.concatenate([source, *(q.values for q in quiet)])
            stamps = np.concatenate([stamps, *(q.segment.stamps_ns[q.rows] for q in quiet)])
            messages = [q.segment.batch.messages[k] for q in quiet for k in q.rows.tolist()]
            statuses = {message: solve_status(message, self._overdetermined) for message in set(messages)}
            hinge_keys += [statuses[message] for message in messages]
            texts += [NO_FINDINGS] * len(messages)
            flags = np.concatenate([flags, np.full((len(messages), 1), _statuses().hitch_ok, np.uint8)])
            order = np.argsort(index, kind="stable")
            index, source, stamps, flags = index[order], source[order], stamps[order], flags[order]
            hinge_keys, texts = [hinge_keys[k] for k in order.tolist()], [texts[k] for k in order.tolist()]
        return [*_filled("hinge_reactions", self._hinge_template, hinge_keys, index, stamps, source),
                *_filled("hitch_state", self._hitch_template, texts, index, stamps, source, flags),
                *_filled("steerability", lambda _: self._steerability, [None] * len(index), index, stamps, source)]

    # ---- layouts: the messages' fields by name, their values as columns of the poses' value rows ----
    def _lay_out(self, monitor: Monitor) -> None:
        """The templates of the three messages for ``monitor``'s mechanism: every float64 field is
        a ``Column`` of the poses' value rows (``mechanics.programs.ValueRow``), or NaN
        where the mechanism has no such value."""
        mech, machine = monitor.mechanism, monitor.machine
        self._machine, self._overdetermined = machine, monitor.overdetermined
        n_h, n_c = len(mech.hinges), len(mech.cylinders)
        row = ValueRow.of(n_h, len(mech.points), n_c, len(machine.capacity_keys),
                          len(machine.steerability_keys))
        # the extra columns after the value row: the budget's standard uncertainties, then the weighing's,
        # then the dynamic steerability (an IMU)
        outputs = monitor.uncertainty.outputs if monitor.uncertainty is not None else ()
        self._n_budget, self._weighed, self._dynamic = len(outputs), monitor.weighing is not None, monitor.road is not None
        self._row_width = row.width
        dynamic_at = row.width + self._n_budget + len(WEIGHING_FIELDS) * self._weighed
        self._extra_width = dynamic_at - row.width + len(DYNAMIC_KEYS) * self._dynamic
        budget_at = {o.name: row.width + k for k, o in enumerate(outputs)}

        def u(output: str) -> Column | float:
            """The standard uncertainty column of the budget output ``output`` (NaN: no budget, or none)."""
            return Column(budget_at[output]) if output in budget_at else math.nan

        weighing = ({f: Column(row.width + self._n_budget + k) for k, f in enumerate(WEIGHING_FIELDS)} if self._weighed
                    else dict.fromkeys(WEIGHING_FIELDS, math.nan))
        residual, consistency, load, transmission = (Column(row.scalars + ROW_SCALARS.index(name)) for name in (
            "residual", "consistency_residual", "implement_load", "transmission_angle"))
        points = list(mech.points)
        header = {"stamp": STAMP, "frame_id": FRAME_ID}

        def xz(name: str) -> tuple[Column, Column]:
            at = row.point_xz + 2 * points.index(name)
            return Column(at), Column(at + 1)

        hinges = [{"name": h.name, "on_body": h.bodies[1], "from_body": h.bodies[0],   # on: the second body
                   "fx": Column(row.hinge_force + 2 * k), "fz": Column(row.hinge_force + 2 * k + 1),
                   "magnitude": Column(row.hinge_magnitude + k), "fx_u": u(f"{h.name}.fx"),
                   "fz_u": u(f"{h.name}.fz"), "magnitude_u": u(f"{h.name}.magnitude"),
                   "x": xz(h.point)[0], "z": xz(h.point)[1]}
                  for k, h in enumerate(mech.hinges)]
        self._hinges = Template.of(Composer(strict=True).message(
            HINGE_REACTIONS, {"header": header, "mechanism": mech.name, "hinges": hinges}, stop=HINGE_TAIL))
        self._hinge_tail = {"equilibrium_residual": residual, "kinematic_residual": consistency}
        self._hinge_texts: dict[tuple[int, str], Template] = {}

        cylinders = [{"name": c.name, **{f: Column(row.cylinder_values + 5 * k + j)
                                         for j, f in enumerate(CylinderResult._fields)},
                      "force_u": u(f"{c.name}.force")}
                     for k, c in enumerate(mech.cylinders)]
        hitch_point = mech.implement.hitch_point if mech.implement else None
        capacities = {f: Column(row.capacity + machine.capacity_keys.index(key)) if key in machine.capacity_keys
                      else math.nan for f, key in CAPACITY_FIELDS.items()}
        self._hitch = Template.of(Composer(strict=True).message(HITCH_STATE, {
            "header": header, "cylinders": cylinders, "implement_load": load,
            "implement_load_estimated": int(monitor.estimates_load), "implement_cg_x": Column(row.implement_cg),
            "implement_cg_z": Column(row.implement_cg + 1),
            "hitch_axis_height": xz(hitch_point)[1] if hitch_point is not None else math.nan,
            **capacities, **{f: u(output) for f, output in HITCH_UNCERTAINTIES.items()}, **weighing,
            "weighing_phase": Flag(1), "weighing_confident": Flag(2), "implement_mass_in_use": Flag(3),
            "min_transmission_angle": transmission, "status": Flag(0)}, stop=HITCH_TAIL))
        self._hitch_texts: dict[str, Template] = {}

        ratios = {f: Column(row.steerability + machine.steerability_keys.index(f)) if f in machine.steerability_keys
                  else math.nan for f in STEERABILITY_KEYS}
        dynamic = {f: Column(dynamic_at + k) if self._dynamic else math.nan for k, f in enumerate(DYNAMIC_KEYS)}
        self._steerability = Template.of(Composer(strict=True).message(
            STEERABILITY, {"header": header, "reference": steerability_reference(mech), **ratios,
                           **{f: u(output) for f, output in STEERABILITY_UNCERTAINTIES.items()}, **dynamic}))

    def _extra_row(self, step: Step) -> np.ndarray:
        """The extra columns of a solved step (``_lay_out``): its budget's standard uncertainties (NaN
        without a budget), its weighing's ``weighing_row`` and its dynamic steerability (NaN without an
        IMU reading)."""
        budget = step.pose.budget if step.pose is not None else None
        parts = [budget.u if budget is not None else np.full(self._n_budget, math.nan)] if self._n_budget else []
        if self._weighed:
            parts.append(np.array(weighing_row(step.weighing) if step.weighing is not None else _NO_ESTIMATE))
        if self._dynamic:
            dynamic = step.pose.dynamic if step.pose is not None else None
            parts.append(dynamic if dynamic is not None else NO_DYNAMIC)
        return np.concatenate(parts)

    def _hinge_template(self, key: tuple[int, str]) -> Template:
        """HingeReactions with status, status_text = ``key`` and the residual slots."""
        def tail(c: Composer) -> None:
            c.message(HINGE_REACTIONS, {"status": key[0], "status_text": key[1], **self._hinge_tail}, start=HINGE_TAIL)
        return _cached(self._hinge_texts, key, self._hinges, tail, self.MAX_TEMPLATES)

    def _hitch_template(self, text: str) -> Template:
        """HitchState with status_text = ``text``."""
        def tail(c: Composer) -> None:
            c.message(HITCH_STATE, {"status_text": text}, start=HITCH_TAIL)
        return _cached(self._hitch_texts, text, self._hitch, tail, self.MAX_TEMPLATES)


def _value_rows(monitor: Monitor, poses: list[Pose]) -> np.ndarray:
    """The value rows of ``poses`` (N, width): their own, ``MachineModel.value_rows`` for those without one."""
    without = [pose for pose in poses if pose.values is None]
    made = iter(monitor.machine.value_rows([p.result for p in without], [p.machine for p in without]) if without
                else ())
    return np.stack([pose.values if pose.values is not None else next(made) for pose in poses])


def per_step(output_rows: Sequence[OutputRows], n: int) -> list[Outputs | None]:
    """The ``Outputs`` of each of n steps from their ``OutputEncoder.output_rows`` (None: not solved)."""
    found: list[dict[str, bytes]] = [{} for _ in range(n)]
    for rows in output_rows:
        for k, row in zip(rows.steps.tolist(), rows.rows):
            found[k][rows.kind] = row.tobytes()
    return [Outputs(**messages) if messages else None for messages in found]


def _cached(cache: dict, key: Hashable, base: Template, tail: Callable[[Composer], None], limit: int) -> Template:
    """``base.extended(tail)``, kept in ``cache`` under ``key`` (the cache emptied first when full)."""
    template = cache.get(key)
    if template is None:
        if len(cache) >= limit:
            cache.clear()
        template = cache[key] = base.extended(tail)
    return template


def _filled(kind: str, template_of: Callable[[Any], Template], keys: list, steps: np.ndarray, stamps: np.ndarray,
            source: np.ndarray, flags: np.ndarray | None = None) -> list[OutputRows]:
    """The ``kind`` messages of N poses (of ``steps``): ``template_of(keys[i])`` filled with stamps[i], its
    columns of source[i] and flags[i]; one ``Template.fill_rows`` per distinct key."""
    codes = {key: number for number, key in enumerate(dict.fromkeys(keys))}   # each distinct key's, by first use
    code = np.fromiter(map(codes.__getitem__, keys), np.intp, len(keys)) if len(codes) > 1 else None
    found = []
    for key, number in codes.items():
        template = template_of(key)
        at = np.flatnonzero(code == number) if code is not None else np.arange(len(keys))
        found.append(OutputRows(kind, steps[at], template.fill_rows(stamps[at], source[np.ix_(at, template.columns)],
                                                                    flags[at] if flags is not None else None)))
    return found
