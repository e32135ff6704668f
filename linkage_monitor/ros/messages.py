"""Monitoring steps -> the package's output messages (used by the live node and the replay).

The three outputs of a solved pose (HingeReactions, HitchState, Steerability) are written
straight to their CDR bytes (``ros.cdr``): published as serialized messages and recorded as
they are, with no rclpy message object in between. Their layout is fixed for a mechanism
(hinge, cylinder and body names) up to the status texts, so ``OutputEncoder`` lays it out once
per status text and fills the numbers of each pose in — of one pose (the node) or of a whole
recording's poses at once (the replay), the same bytes.

Units SI (m, N, Pa, kg); frame x forward, z up, origin at the rear wheels' ground contact.
Every output carries the header stamp of the triggering input, never wall-clock time.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Callable, Hashable, Sequence

import numpy as np
from builtin_interfaces.msg import Time
from std_msgs.msg import Header

from linkage_monitor.mechanics import Mechanism, Result
from linkage_monitor.mechanics.machine import MachineResult
from linkage_monitor.monitoring.core import Monitor, Step
from linkage_monitor.monitoring.findings import Code, Level
from linkage_monitor.msg import HingeReactions, HitchState, Steerability

from .cdr import Template, Writer, stamp_ns  # noqa: F401 - stamp_ns: part of this module's interface

FRAME_ID = "base_footprint"  # REP 105 frame at the ground below the tractor: x forward, z up
HINGE_REACTIONS, HITCH_STATE, STEERABILITY = ("linkage_monitor/msg/HingeReactions", "linkage_monitor/msg/HitchState",
                                              "linkage_monitor/msg/Steerability")
# Steerability's float64 fields after `reference`, in message order (msg/Steerability.msg)
STEERABILITY_RATIOS = ("ratio", "ratio_unit", "ratio_tractor", "ratio_min", "margin", "front_ballast_needed",
                       "max_implement_mass")
STEERABILITY_LOADS = ("front_axle_load", "rear_axle_load", "total_weight", "wheelbase")
STEERABILITY_FIELDS = STEERABILITY_LOADS + STEERABILITY_RATIOS   # the float64 slots in order
CAPACITY_FIELDS = ("hitch_axis", "behind_610mm", "implement_cg", "reserve")   # MachineResult.lift_capacity keys
# msg/CylinderState.msg's float64 fields (length, force, cap / rod measured, cap predicted) as columns of
# Result.cylinder_values (CylinderResult order: length, force, cap predicted, cap / rod measured)
CYLINDER_STATE_ORDER = np.array([0, 1, 3, 4, 2], dtype=np.intp)


@dataclass(frozen=True)
class Outputs:
    """The three output messages of one solve, serialized (CDR, as published and recorded)."""

    hinge_reactions: bytes
    hitch_state: bytes
    steerability: bytes


def header(stamp_ns: int) -> Header:
    """A std_msgs/Header with the given stamp (ns since the epoch) and FRAME_ID."""
    return Header(stamp=Time(sec=int(stamp_ns // 1_000_000_000), nanosec=int(stamp_ns % 1_000_000_000)),
                  frame_id=FRAME_ID)


def hinge_status(step: Step, result: Result, overdetermined: bool) -> tuple[int, str]:
    """HingeReactions.status and status_text: HIGH_RESIDUAL when the measured pressures disagree,
    OVERDETERMINED when more measurements than degrees of freedom were solved by least squares."""
    disagree = [f.text for f in step.findings if f.code is Code.PRESSURES_DISAGREE]
    if disagree:
        return HingeReactions.STATUS_HIGH_RESIDUAL, disagree[0]
    status = HingeReactions.STATUS_OVERDETERMINED if overdetermined else HingeReactions.STATUS_OK
    return status, result.message or "ok"


def hitch_status(step: Step) -> int:
    """HitchState.status of a solved step (WARN with any warning finding)."""
    return HitchState.STATUS_WARN if step.level == Level.WARN else HitchState.STATUS_OK


def steerability_reference(mech: Mechanism) -> int:
    """Steerability.reference: which weight the mechanism's ``ratio`` is taken of."""
    reference = mech.tractor.steerability_reference if mech.tractor else "unit"
    return Steerability.REFERENCE_TRACTOR if reference == "tractor" else Steerability.REFERENCE_UNIT


class OutputEncoder:
    """Writes the three output messages of solved steps as CDR bytes.

    The layout follows the monitor's effective mechanism and is laid out again when the monitor
    is reconfigured. A message's fixed part (names, counts) is a ``Template``; the status texts
    after it make one template per text (kept for the texts seen last, ``MAX_TEMPLATES``).
    ``outputs`` writes one step's messages (the live node), ``outputs_of`` those of many steps at
    once, the same bytes (the replay: each template filled for all its steps in a few array
    operations).
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
        result, machine, stamp = step.pose.result, step.pose.machine, step.stamp_ns
        hinge, hitch, steer = self._values([result], [machine])
        return Outputs(bytes(self._hinge_template(hinge_status(step, result, self._overdetermined)).fill(stamp, hinge[0])),
                       bytes(self._hitch_template(step.message).fill(stamp, hitch[0], (hitch_status(step),))),
                       bytes(self._steerability.fill(stamp, steer[0])))

    def outputs_of(self, monitor: Monitor, steps: Sequence[Step]) -> list[Outputs | None]:
        """``outputs`` of each of ``steps`` (steps of ``monitor`` in its present configuration)."""
        solved = [k for k, step in enumerate(steps) if step.pose is not None]
        found: list[Outputs | None] = [None] * len(steps)
        if not solved:
            return found
        if monitor.mechanism is not self._mechanism:
            self._lay_out(monitor)
        poses = [steps[k] for k in solved]
        results = [step.pose.result for step in poses]   # type: ignore[union-attr]  # solved: a pose each
        hinge, hitch, steer = self._values(results, [step.pose.machine for step in poses])  # type: ignore[union-attr]
        stamps = np.array([step.stamp_ns for step in poses], dtype=np.int64)
        hinge_keys = [hinge_status(step, result, self._overdetermined) for step, result in zip(poses, results)]
        flags = np.array([[hitch_status(step)] for step in poses], dtype=np.uint8)
        hinges = _filled(self._hinge_template, hinge_keys, stamps, hinge)
        hitches = _filled(self._hitch_template, [step.message for step in poses], stamps, hitch, flags)
        steers = _filled(lambda _: self._steerability, [None] * len(poses), stamps, steer)
        for k, a, b, c in zip(solved, hinges, hitches, steers):
            found[k] = Outputs(a, b, c)
        return found

    # ---- layouts -----------------------------------------------------------------------------
    def _lay_out(self, monitor: Monitor) -> None:
        mech = monitor.mechanism
        self._mechanism, self._overdetermined = mech, monitor.overdetermined
        self._lay_out_values(monitor)
        w, slots = Writer(), []
        w.header(FRAME_ID)                              # msg/HingeReactions.msg, field by field
        w.string(mech.name)
        w.uint32(len(mech.hinges))
        for h in mech.hinges:                            # msg/HingeReaction.msg
            w.string(h.name)
            w.string(h.bodies[1])                        # on_body: the hinge's second body
            w.string(h.bodies[0])                        # from_body
            slots += [w.float64() for _ in range(5)]     # fx, fz, magnitude, x, z
        self._hinges = Template.of(w, slots)             # then status, status_text, residual, consistency
        self._hinge_texts: dict[tuple[int, str], Template] = {}

        w, slots = Writer(), []
        w.header(FRAME_ID)                              # msg/HitchState.msg
        w.uint32(len(mech.cylinders))
        for c in mech.cylinders:                         # msg/CylinderState.msg
            w.string(c.name)
            slots += [w.float64() for _ in range(5)]     # length, force, cap / rod measured, cap predicted
        slots.append(w.float64())                        # implement_load
        w.uint8(int(monitor.estimates_load))            # implement_load_estimated
        slots += [w.float64() for _ in range(7)]         # cg x, z, hitch axis height, 3 capacities, reserve
        status = w.uint8(HitchState.STATUS_OK)
        self._hitch = Template.of(w, slots, (status,))   # then status_text
        self._hitch_texts: dict[str, Template] = {}

        w, slots = Writer(), []
        w.header(FRAME_ID)                              # msg/Steerability.msg
        slots += [w.float64() for _ in STEERABILITY_LOADS]
        w.uint8(steerability_reference(mech))
        slots += [w.float64() for _ in STEERABILITY_RATIOS]
        self._steerability = Template.of(w, slots)

    def _hinge_template(self, key: tuple[int, str]) -> Template:
        """HingeReactions with status, status_text = ``key`` and the residual slots."""
        def tail(w: Writer) -> list[int]:
            w.uint8(key[0])
            w.string(key[1])
            return [w.float64(), w.float64()]              # residual, consistency_residual
        return _cached(self._hinge_texts, key, self._hinges, tail, self.MAX_TEMPLATES)

    def _hitch_template(self, text: str) -> Template:
        """HitchState with status_text = ``text``."""
        def tail(w: Writer) -> list[int]:
            w.string(text)
            return []
        return _cached(self._hitch_texts, text, self._hitch, tail, self.MAX_TEMPLATES)

    # ---- the numbers -------------------------------------------------------------------------
    def _lay_out_values(self, monitor: Monitor) -> None:
        """Where each message's float64 slots come from: one column each of the ``_values`` source
        rows, laid out as [fx, fz per hinge | |F| per hinge | x, z per point | CylinderResult fields
        per cylinder | residual, consistency residual, implement load, NaN | implement cg x, z |
        capacity row | steerability row]."""
        mech, machine = monitor.mechanism, monitor.machine
        n_h, n_p, n_c = len(mech.hinges), len(mech.points), len(mech.cylinders)
        magnitude, point, cylinder = 2 * n_h, 3 * n_h, 3 * n_h + 2 * n_p
        residual, consistency, load, nan = (cylinder + 5 * n_c + k for k in range(4))
        cg, capacity = nan + 1, nan + 3
        steer = capacity + len(machine.capacity_keys)
        points = list(mech.points)
        hinge = []
        for k, h in enumerate(mech.hinges):   # fx, fz, magnitude, x, z
            at = point + 2 * points.index(h.point)
            hinge += [2 * k, 2 * k + 1, magnitude + k, at, at + 1]
        self._hinge_take = np.array(hinge + [residual, consistency], dtype=np.intp)
        hitch = [cylinder + 5 * c + int(j) for c in range(n_c) for j in CYLINDER_STATE_ORDER]
        hitch_point = mech.implement.hitch_point if mech.implement else None
        row = points.index(hitch_point) if hitch_point is not None else None
        hitch += [load, cg, cg + 1, point + 2 * row + 1 if row is not None else nan]
        hitch += [capacity + machine.capacity_keys.index(f) if f in machine.capacity_keys else nan
                  for f in CAPACITY_FIELDS]
        self._hitch_take = np.array(hitch, dtype=np.intp)
        self._steer_take = np.array([steer + machine.steerability_keys.index(f) if f in machine.steerability_keys
                                     else nan for f in STEERABILITY_FIELDS], dtype=np.intp)
        self._no_capacity = np.full(len(machine.capacity_keys), math.nan)
        self._no_steerability = np.full(len(machine.steerability_keys), math.nan)

    def _values(self, results: Sequence[Result], machines: Sequence[MachineResult]
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The float64 slots of the three messages for N poses, in slot order: (N, 5·hinges + 2),
        (N, 5·cylinders + 8), (N, len(STEERABILITY_FIELDS)); NaN for what a pose lacks."""
        n = len(results)
        force = _stacked([r.hinge_force for r in results]).reshape(n, -1)
        source = np.concatenate([
            force, np.hypot(force[:, 0::2], force[:, 1::2]),   # as Result.hinge_magnitude
            _stacked([r.point_xz for r in results]).reshape(n, -1),
            _stacked([r.cylinder_values for r in results]).reshape(n, -1),
            np.array([(r.residual, r.consistency_residual, r.implement_load, math.nan) for r in results]),
            _stacked([r.implement_cg for r in results]),
            _stacked([m.capacity_row if m.capacity_row.size else self._no_capacity for m in machines]),
            _stacked([m.steerability_row if m.steerability_row.size else self._no_steerability for m in machines])],
            axis=1)
        return (source.take(self._hinge_take, axis=1), source.take(self._hitch_take, axis=1),
                source.take(self._steer_take, axis=1))


def _stacked(arrays: list[np.ndarray]) -> np.ndarray:
    """The arrays stacked along a new first axis (one pose: a view)."""
    return arrays[0][None] if len(arrays) == 1 else np.stack(arrays)


def _cached(cache: dict, key: Hashable, base: Template, tail: Callable[[Writer], list[int]], limit: int) -> Template:
    """``base.extended(tail)``, kept in ``cache`` under ``key`` (the cache emptied first when full)."""
    template = cache.get(key)
    if template is None:
        if len(cache) >= limit:
            cache.clear()
        template = cache[key] = base.extended(tail)
    return template


def _filled(template_of: Callable[[Any], Template], keys: list, stamps: np.ndarray, values: np.ndarray,
            flags: np.ndarray | None = None) -> list[bytes]:
    """The messages of N poses: ``template_of(keys[i])`` filled with stamps[i], values[i] and flags[i]
    (one ``Template.fill_rows`` per distinct key)."""
    rows: dict[Any, list[int]] = {}
    for i, key in enumerate(keys):
        rows.setdefault(key, []).append(i)
    found: list[bytes] = [b""] * len(keys)
    for key, index in rows.items():
        template = template_of(key)
        at = np.array(index, dtype=np.intp)
        data = template.fill_rows(stamps[at], values[at], flags[at] if flags is not None else None).tobytes()
        size = len(template.data)
        for j, i in enumerate(index):
            found[i] = data[j * size:(j + 1) * size]
    return found
