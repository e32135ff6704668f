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

import math
from dataclasses import dataclass
from typing import Any, Callable, Hashable, Sequence

import numpy as np

from linkage_monitor.mechanics import Mechanism, Result
from linkage_monitor.mechanics.machine import STEERABILITY_KEYS, MachineResult
from linkage_monitor.mechanics.results import CylinderResult
from linkage_monitor.monitoring.core import Monitor, Step
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


@dataclass(frozen=True)
class Outputs:
    """The three output messages of one solve, serialized (CDR, as published and recorded)."""

    hinge_reactions: bytes
    hitch_state: bytes
    steerability: bytes


def hinge_status(step: Step, result: Result, overdetermined: bool) -> tuple[int, str]:
    """HingeReactions.status and status_text: HIGH_RESIDUAL when the measured pressures disagree,
    OVERDETERMINED when more measurements than degrees of freedom were solved by least squares."""
    disagree = [f.text for f in step.findings if f.code is Code.PRESSURES_DISAGREE]
    status = constants(HINGE_REACTIONS)
    if disagree:
        return status["STATUS_HIGH_RESIDUAL"], disagree[0]
    return status["STATUS_OVERDETERMINED" if overdetermined else "STATUS_OK"], result.message or "ok"


def hitch_status(step: Step) -> int:
    """HitchState.status of a solved step (WARN with any warning finding)."""
    return constants(HITCH_STATE)["STATUS_WARN" if step.level == Level.WARN else "STATUS_OK"]


def steerability_reference(mech: Mechanism) -> int:
    """Steerability.reference: which weight the mechanism's ``ratio`` is taken of."""
    reference = mech.tractor.steerability_reference if mech.tractor else "unit"
    return constants(STEERABILITY)["REFERENCE_TRACTOR" if reference == "tractor" else "REFERENCE_UNIT"]


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
        source = self._values([result], [machine])[0]
        hinges = self._hinge_template(hinge_status(step, result, self._overdetermined))
        hitch = self._hitch_template(step.message)
        return Outputs(bytes(hinges.fill(stamp, source.take(hinges.columns))),
                       bytes(hitch.fill(stamp, source.take(hitch.columns), (hitch_status(step),))),
                       bytes(self._steerability.fill(stamp, source.take(self._steerability.columns))))

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
        source = self._values(results, [step.pose.machine for step in poses])  # type: ignore[union-attr]
        stamps = np.array([step.stamp_ns for step in poses], dtype=np.int64)
        hinge_keys = [hinge_status(step, result, self._overdetermined) for step, result in zip(poses, results)]
        flags = np.array([[hitch_status(step)] for step in poses], dtype=np.uint8)
        hinges = _filled(self._hinge_template, hinge_keys, stamps, source)
        hitches = _filled(self._hitch_template, [step.message for step in poses], stamps, source, flags)
        steers = _filled(lambda _: self._steerability, [None] * len(poses), stamps, source)
        for k, a, b, c in zip(solved, hinges, hitches, steers):
            found[k] = Outputs(a, b, c)
        return found

    # ---- layouts: the messages' fields by name, their values as columns of the ``_values`` rows ----
    def _lay_out(self, monitor: Monitor) -> None:
        """The templates of the three messages for ``monitor``'s mechanism. The source rows
        (``_values``) are [fx, fz per hinge | |F| per hinge | x, z per point | CylinderResult fields
        per cylinder | residual, consistency residual, implement load, NaN, transmission angle |
        implement cg x, z | capacity row | steerability row]; every float64 field is a ``Column`` of
        them."""
        mech, machine = monitor.mechanism, monitor.machine
        self._mechanism, self._overdetermined = mech, monitor.overdetermined
        n_h, n_p, n_c = len(mech.hinges), len(mech.points), len(mech.cylinders)
        magnitude, point, cylinder = 2 * n_h, 3 * n_h, 3 * n_h + 2 * n_p
        residual, consistency, load, nan, transmission = (cylinder + 5 * n_c + k for k in range(5))
        cg, capacity = transmission + 1, transmission + 3
        steer = capacity + len(machine.capacity_keys)
        points = list(mech.points)
        header = {"stamp": STAMP, "frame_id": FRAME_ID}

        def xz(name: str) -> tuple[Column, Column]:
            at = point + 2 * points.index(name)
            return Column(at), Column(at + 1)

        hinges = [{"name": h.name, "on_body": h.bodies[1], "from_body": h.bodies[0],   # on: the second body
                   "fx": Column(2 * k), "fz": Column(2 * k + 1), "magnitude": Column(magnitude + k),
                   "x": xz(h.point)[0], "z": xz(h.point)[1]} for k, h in enumerate(mech.hinges)]
        self._hinges = Template.of(Composer(strict=True).message(
            HINGE_REACTIONS, {"header": header, "mechanism": mech.name, "hinges": hinges}, stop=HINGE_TAIL))
        self._hinge_tail = {"equilibrium_residual": Column(residual), "kinematic_residual": Column(consistency)}
        self._hinge_texts: dict[tuple[int, str], Template] = {}

        cylinders = [{"name": c.name, **{f: Column(cylinder + 5 * k + j) for j, f in enumerate(CylinderResult._fields)}}
                     for k, c in enumerate(mech.cylinders)]
        hitch_point = mech.implement.hitch_point if mech.implement else None
        capacities = {f: Column(capacity + machine.capacity_keys.index(key) if key in machine.capacity_keys else nan)
                      for f, key in CAPACITY_FIELDS.items()}
        self._hitch = Template.of(Composer(strict=True).message(HITCH_STATE, {
            "header": header, "cylinders": cylinders, "implement_load": Column(load),
            "implement_load_estimated": int(monitor.estimates_load), "implement_cg_x": Column(cg),
            "implement_cg_z": Column(cg + 1),
            "hitch_axis_height": xz(hitch_point)[1] if hitch_point is not None else Column(nan),
            **capacities, "min_transmission_angle": Column(transmission), "status": Flag(0)}, stop=HITCH_TAIL))
        self._hitch_texts: dict[str, Template] = {}

        ratios = {f: Column(steer + machine.steerability_keys.index(f) if f in machine.steerability_keys else nan)
                  for f in STEERABILITY_KEYS}
        self._steerability = Template.of(Composer(strict=True).message(
            STEERABILITY, {"header": header, "reference": steerability_reference(mech), **ratios}))
        self._no_capacity = np.full(len(machine.capacity_keys), math.nan)
        self._no_steerability = np.full(len(machine.steerability_keys), math.nan)

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

    # ---- the numbers -------------------------------------------------------------------------
    def _values(self, results: Sequence[Result], machines: Sequence[MachineResult]) -> np.ndarray:
        """The source rows of N poses (``_lay_out``: the columns), NaN for what a pose lacks."""
        n = len(results)
        force = _stacked([r.hinge_force for r in results]).reshape(n, -1)
        return np.concatenate([
            force, np.hypot(force[:, 0::2], force[:, 1::2]),   # as Result.hinge_magnitude
            _stacked([r.point_xz for r in results]).reshape(n, -1),
            _stacked([r.cylinder_values for r in results]).reshape(n, -1),
            np.array([(r.residual, r.consistency_residual, r.implement_load, math.nan, r.transmission_angle)
                      for r in results]),
            _stacked([r.implement_cg for r in results]),
            _stacked([m.capacity_row if m.capacity_row.size else self._no_capacity for m in machines]),
            _stacked([m.steerability_row if m.steerability_row.size else self._no_steerability for m in machines])],
            axis=1)


def _stacked(arrays: list[np.ndarray]) -> np.ndarray:
    """The arrays stacked along a new first axis (one pose: a view)."""
    return arrays[0][None] if len(arrays) == 1 else np.stack(arrays)


def _cached(cache: dict, key: Hashable, base: Template, tail: Callable[[Composer], None], limit: int) -> Template:
    """``base.extended(tail)``, kept in ``cache`` under ``key`` (the cache emptied first when full)."""
    template = cache.get(key)
    if template is None:
        if len(cache) >= limit:
            cache.clear()
        template = cache[key] = base.extended(tail)
    return template


def _filled(template_of: Callable[[Any], Template], keys: list, stamps: np.ndarray, source: np.ndarray,
            flags: np.ndarray | None = None) -> list[bytes]:
    """The messages of N poses: ``template_of(keys[i])`` filled with stamps[i], its columns of
    source[i] and flags[i] (one ``Template.fill_rows`` per distinct key)."""
    rows: dict[Any, list[int]] = {}
    for i, key in enumerate(keys):
        rows.setdefault(key, []).append(i)
    found: list[bytes] = [b""] * len(keys)
    for key, index in rows.items():
        template = template_of(key)
        at = np.array(index, dtype=np.intp)
        data = template.fill_rows(stamps[at], source[np.ix_(at, template.columns)],
                                  flags[at] if flags is not None else None).tobytes()
        size = len(template.data)
        for j, i in enumerate(index):
            found[i] = data[j * size:(j + 1) * size]
    return found
