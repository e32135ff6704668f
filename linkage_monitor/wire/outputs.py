"""Monitoring steps -> the package's output messages (used by the live node and the replay).

The three outputs of a solved pose (HingeReactions, HitchState, Steerability) are written
straight to their CDR bytes: published as serialized messages and recorded as they are, with no
rclpy message object in between. Their layout comes from msg/*.msg (``wire.layout``); the values
are named by field here. It is fixed for a mechanism (hinge, cylinder and body names) up to the
status texts, so ``OutputEncoder`` lays it out once per status text (``wire.template``) and fills
the numbers of each pose in — of one pose (the node) or of a whole recording's poses at once (the
replay), the same bytes.

Units SI (m, N, Pa, kg); frame x forward, z up, origin at the rear wheels' ground contact.
Every output carries the header stamp of the triggering input, never wall-clock time.
"""

from __future__ import annotations

import functools
import math
from typing import Any, Callable, Hashable, NamedTuple, Sequence

import numpy as np

from linkage_monitor.mechanics import Mechanism, Result
from linkage_monitor.mechanics.machine import STEERABILITY_KEYS
from linkage_monitor.mechanics.programs import ROW_SCALARS, ValueRow
from linkage_monitor.mechanics.results import CylinderResult
from linkage_monitor.monitoring.core import NO_FINDINGS, Monitor, Pose, Step
from linkage_monitor.monitoring.findings import Code, Level

from .compose import STAMP, Column, Composer, Flag
from .layout import constants
from .template import Template

FRAME_ID = "base_footprint"  # REP 105 frame at the ground below the tractor: x forward, z up
HINGE_REACTIONS, HITCH_STATE, STEERABILITY = ("linkage_monitor/msg/HingeReactions", "linkage_monitor/msg/HitchState",
                                              "linkage_monitor/msg/Steerability")
# HitchState's capacity fields <- MachineResult.lift_capacity keys
CAPACITY_FIELDS = {"lift_capacity_hitch_axis": "hitch_axis", "lift_capacity_610mm": "behind_610mm",
                   "lift_capacity_implement_cg": "implement_cg", "lift_reserve": "reserve"}
# Steerability's float64 fields are MachineResult.steerability keys of the same names
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
    statuses = _statuses()
    for finding in step.findings:
        if finding.code is Code.PRESSURES_DISAGREE:
            return statuses.hinge_high_residual, finding.text
    return statuses.hinge_overdetermined if overdetermined else statuses.hinge_ok, result.message or NO_FINDINGS


def hitch_status(step: Step) -> int:
    """HitchState.status of a solved step (WARN with any warning finding)."""
    statuses = _statuses()
    return statuses.hitch_warn if step.findings and step.level == Level.WARN else statuses.hitch_ok


def steerability_reference(mech: Mechanism) -> int:
    """Steerability.reference: which weight the mechanism's ``ratio`` is taken of."""
    reference = mech.tractor.steerability_reference if mech.tractor else "unit"
    return constants(STEERABILITY)["REFERENCE_TRACTOR" if reference == "tractor" else "REFERENCE_UNIT"]


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
        self._mechanism: Mechanism | None = None

    def outputs(self, monitor: Monitor, step: Step) -> Outputs | None:
        """The serialized outputs of ``step`` (a step of ``monitor``), or None without a solved pose."""
        if step.pose is None:
            return None
        if monitor.mechanism is not self._mechanism:
            self._lay_out(monitor)
        pose, stamp = step.pose, step.stamp_ns
        result = pose.result
        source = pose.values if pose.values is not None else monitor.machine.value_rows([result], [pose.machine])[0]
        hinges = self._hinge_template(hinge_status(step, result, self._overdetermined))
        hitch = self._hitch_template(step.message)
        return Outputs(hinges.fill(stamp, source.take(hinges.columns)),
                       hitch.fill(stamp, source.take(hitch.columns), (hitch_status(step),)),
                       self._steerability.fill(stamp, source.take(self._steerability.columns)))

    def output_rows(self, monitor: Monitor, steps: Sequence[Step]) -> list[OutputRows]:
        """The messages ``outputs`` gives each of ``steps`` (steps of ``monitor`` in its present
        configuration), as rows: per message kind, one ``OutputRows`` per layout (status text)."""
        solved = [k for k, step in enumerate(steps) if step.pose is not None]
        if not solved:
            return []
        if monitor.mechanism is not self._mechanism:
            self._lay_out(monitor)
        poses = [steps[k] for k in solved]
        results = [step.pose.result for step in poses]   # type: ignore[union-attr]  # solved: a pose each
        source = _value_rows(monitor, [step.pose for step in poses])  # type: ignore[misc]  # solved: a pose each
        stamps = np.array([step.stamp_ns for step in poses], dtype=np.int64)
        hinge_keys = [hinge_status(step, result, self._overdetermined) for step, result in zip(poses, results)]
        flags = np.array([[hitch_status(step)] for step in poses], dtype=np.uint8)
        index = np.array(solved, dtype=np.intp)
        return [*_filled("hinge_reactions", self._hinge_template, hinge_keys, index, stamps, source),
                *_filled("hitch_state", self._hitch_template, [step.message for step in poses], index, stamps, source,
                         flags),
                *_filled("steerability", lambda _: self._steerability, [None] * len(poses), index, stamps, source)]

    # ---- layouts: the messages' fields by name, their values as columns of the poses' value rows ----
    def _lay_out(self, monitor: Monitor) -> None:
        """The templates of the three messages for ``monitor``'s mechanism: every float64 field is
        a ``Column`` of the poses' value rows (``mechanics.programs.ValueRow``), or NaN
        where the mechanism has no such value."""
        mech, machine = monitor.mechanism, monitor.machine
        self._mechanism, self._overdetermined = mech, monitor.overdetermined
        n_h, n_c = len(mech.hinges), len(mech.cylinders)
        row = ValueRow.of(n_h, len(mech.points), n_c, len(machine.capacity_keys),
                          len(machine.steerability_keys))
        residual, consistency, load, transmission = (Column(row.scalars + ROW_SCALARS.index(name)) for name in (
            "residual", "consistency_residual", "implement_load", "transmission_angle"))
        points = list(mech.points)
        header = {"stamp": STAMP, "frame_id": FRAME_ID}

        def xz(name: str) -> tuple[Column, Column]:
            at = row.point_xz + 2 * points.index(name)
            return Column(at), Column(at + 1)

        hinges = [{"name": h.name, "on_body": h.bodies[1], "from_body": h.bodies[0],   # on: the second body
                   "fx": Column(row.hinge_force + 2 * k), "fz": Column(row.hinge_force + 2 * k + 1),
                   "magnitude": Column(row.hinge_magnitude + k), "x": xz(h.point)[0], "z": xz(h.point)[1]}
                  for k, h in enumerate(mech.hinges)]
        self._hinges = Template.of(Composer(strict=True).message(
            HINGE_REACTIONS, {"header": header, "mechanism": mech.name, "hinges": hinges}, stop=HINGE_TAIL))
        self._hinge_tail = {"equilibrium_residual": residual, "kinematic_residual": consistency}
        self._hinge_texts: dict[tuple[int, str], Template] = {}

        cylinders = [{"name": c.name, **{f: Column(row.cylinder_values + 5 * k + j)
                                         for j, f in enumerate(CylinderResult._fields)}}
                     for k, c in enumerate(mech.cylinders)]
        hitch_point = mech.implement.hitch_point if mech.implement else None
        capacities = {f: Column(row.capacity + machine.capacity_keys.index(key)) if key in machine.capacity_keys
                      else math.nan for f, key in CAPACITY_FIELDS.items()}
        self._hitch = Template.of(Composer(strict=True).message(HITCH_STATE, {
            "header": header, "cylinders": cylinders, "implement_load": load,
            "implement_load_estimated": int(monitor.estimates_load), "implement_cg_x": Column(row.implement_cg),
            "implement_cg_z": Column(row.implement_cg + 1),
            "hitch_axis_height": xz(hitch_point)[1] if hitch_point is not None else math.nan,
            **capacities, "min_transmission_angle": transmission, "status": Flag(0)}, stop=HITCH_TAIL))
        self._hitch_texts: dict[str, Template] = {}

        ratios = {f: Column(row.steerability + machine.steerability_keys.index(f)) if f in machine.steerability_keys
                  else math.nan for f in STEERABILITY_KEYS}
        self._steerability = Template.of(Composer(strict=True).message(
            STEERABILITY, {"header": header, "reference": steerability_reference(mech), **ratios}))

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
    rows: dict[Any, list[int]] = {}
    for i, key in enumerate(keys):
        rows.setdefault(key, []).append(i)
    found = []
    for key, index in rows.items():
        template = template_of(key)
        at = np.array(index, dtype=np.intp)
        found.append(OutputRows(kind, steps[at], template.fill_rows(stamps[at], source[np.ix_(at, template.columns)],
                                                                    flags[at] if flags is not None else None)))
    return found
