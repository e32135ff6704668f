"""Monitoring steps -> the package's output messages (used by the live node and the replay).

The three outputs of a solved pose (HingeReactions, HitchState, Steerability) are written
straight to their CDR bytes (``ros.cdr``): published as serialized messages and recorded as
they are, with no rclpy message object in between. Their layout is fixed for a mechanism
(hinge, cylinder and body names), so ``OutputEncoder`` lays it out once and fills the numbers
of each pose in; only the status texts are appended per message.

Units SI (m, N, Pa, kg); frame x forward, z up, origin at the rear wheels' ground contact.
Every output carries the header stamp of the triggering input, never wall-clock time.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

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
    is reconfigured. ``outputs`` returns None for a step without a solved pose.
    """

    def __init__(self) -> None:
        self._mechanism: Mechanism | None = None

    def outputs(self, monitor: Monitor, step: Step) -> Outputs | None:
        """The serialized outputs of ``step`` (a step of ``monitor``), or None without a solved pose."""
        if step.pose is None:
            return None
        if monitor.mechanism is not self._mechanism:
            self._lay_out(monitor)
        result, machine = step.pose.result, step.pose.machine
        return Outputs(self._hinge_reactions(step, result), self._hitch_state(step, result, machine),
                       bytes(self._steerability.fill(step.stamp_ns, self._steer_values.of(machine.steerability_row))))

    # ---- layouts -----------------------------------------------------------------------------
    def _lay_out(self, monitor: Monitor) -> None:
        mech = monitor.mechanism
        self._mechanism, self._overdetermined = mech, monitor.overdetermined
        points = list(mech.points)
        self._hinge_rows = np.array([points.index(h.point) for h in mech.hinges], dtype=np.intp)
        self._steer_values = _Picked(monitor.machine.steerability_keys, STEERABILITY_FIELDS)
        self._capacity_values = _Picked(monitor.machine.capacity_keys, CAPACITY_FIELDS)
        self._hinge_values = np.empty((len(mech.hinges), 5))         # fx, fz, magnitude, x, z per hinge
        self._hitch_values = np.empty(5 * len(mech.cylinders) + 4 + len(CAPACITY_FIELDS))
        w, slots = Writer(), []
        w.header(FRAME_ID)                              # msg/HingeReactions.msg, field by field
        w.string(mech.name)
        w.uint32(len(mech.hinges))
        for h in mech.hinges:                            # msg/HingeReaction.msg
            w.string(h.name)
            w.string(h.bodies[1])                        # on_body: the hinge's second body
            w.string(h.bodies[0])                        # from_body
            slots += [w.float64() for _ in range(5)]     # fx, fz, magnitude, x, z
        self._hinges = Template.of(w, slots)

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
        self._hitch = Template.of(w, slots, (status,))
        hitch_point = mech.implement.hitch_point if mech.implement else None
        self._hitch_row = points.index(hitch_point) if hitch_point is not None else None

        w, slots = Writer(), []
        w.header(FRAME_ID)                              # msg/Steerability.msg
        slots += [w.float64() for _ in STEERABILITY_LOADS]
        w.uint8(steerability_reference(mech))
        slots += [w.float64() for _ in STEERABILITY_RATIOS]
        self._steerability = Template.of(w, slots)

    # ---- per step ----------------------------------------------------------------------------
    def _hinge_reactions(self, step: Step, result: Result) -> bytes:
        values = self._hinge_values
        values[:, :2] = result.hinge_force
        values[:, 2] = result.hinge_magnitude
        values[:, 3:] = result.point_xz[self._hinge_rows]
        status, text = hinge_status(step, result, self._overdetermined)
        w = Writer(self._hinges.fill(step.stamp_ns, values.ravel()))
        w.uint8(status)
        w.string(text)
        w.float64(result.residual)
        w.float64(result.consistency_residual)
        return bytes(w.data)

    def _hitch_state(self, step: Step, result: Result, machine: MachineResult) -> bytes:
        values, row = self._hitch_values, self._hitch_row
        n = result.cylinder_values.size
        values[:n] = result.cylinder_values[:, CYLINDER_STATE_ORDER].ravel()
        values[n:n + 4] = (result.implement_load, result.implement_cg[0], result.implement_cg[1],
                           result.point_xz[row, 1] if row is not None else math.nan)
        values[n + 4:] = self._capacity_values.of(machine.capacity_row)
        w = Writer(self._hitch.fill(step.stamp_ns, values, (hitch_status(step),)))
        w.string(step.message)
        return bytes(w.data)


class _Picked:
    """The values of a message's ``fields`` from a MachineResult row whose columns are ``keys``
    (NaN for a field the row lacks, and for all of them when the row is empty)."""

    def __init__(self, keys: tuple[str, ...], fields: tuple[str, ...]) -> None:
        self._position = np.array([k for k, f in enumerate(fields) if f in keys], dtype=np.intp)
        self._column = np.array([keys.index(f) for f in fields if f in keys], dtype=np.intp)
        self._values = np.full(len(fields), math.nan)

    def of(self, row: np.ndarray) -> np.ndarray:
        """``row``'s values in field order (a buffer reused by the next call)."""
        if row.size:
            self._values[self._position] = row[self._column]
        else:
            self._values[:] = math.nan
        return self._values
