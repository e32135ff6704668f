"""One monitoring step per sensor message, without rclpy: the core of the live node.

A sensor message updates the latest inputs (inputs.py); if every input is fresh the
linkage is solved (mechanics), the machine-level results are added, and the three output
messages are built (outputs.py). Every step ends in a diagnostic level, a message naming
the input and the reason, and key-values with the numbers. Nothing with garbage values is
returned: a failed step has `outputs = None`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import Any, Mapping, Sequence

from linkage_monitor.ros import messages as out
from linkage_monitor.monitoring.inputs import InputConfig, InputTracker, StaleInputError
from linkage_monitor.mechanics import (AssemblyError, DeadCentreError, InputError, Inputs, LinkageError, Mechanism, Result,
                        Solver)
from linkage_monitor.mechanics.results import Status
from linkage_monitor.mechanics.machine import MachineModel, MachineResult

OK, WARN, ERROR = 0, 1, 2  # diagnostic_msgs/DiagnosticStatus levels
# Redundant measurements (e.g. stroke and lift-arm angle) never agree exactly: up to
# CONSISTENCY_WARN_M of loop-closure residual is sensor noise, above it a WARN, above
# ASSEMBLY_LIMIT_M the pose cannot be assembled from the inputs (ERROR).
CONSISTENCY_WARN_M = 1e-3
ASSEMBLY_LIMIT_M = 20e-3
WARNING_JOIN = " | "  # between several warnings of one step (a warning itself may contain "; ")
FAILURE_STATUS = {AssemblyError: Status.ASSEMBLY, DeadCentreError: Status.DEAD_CENTRE, InputError: Status.INPUT}
FAILURE_TEXT = {Status.ASSEMBLY: "cannot assemble", Status.DEAD_CENTRE: "dead centre", Status.INPUT: "malformed input"}


@dataclass(frozen=True)
class Pending:
    """A solve that is due: the trigger's stamp (ns), the inputs, their values for the diagnostic."""

    stamp_ns: int
    inputs: Inputs
    values: dict[str, str]


@dataclass
class Step:
    """The outcome of one sensor message: outputs (None if nothing was solved) and a diagnostic."""

    stamp_ns: int
    level: int
    message: str
    values: dict[str, str] = field(default_factory=dict)
    outputs: out.Outputs | None = None
    result: Result | None = None
    machine: MachineResult | None = None


class Monitor:
    """Holds the mechanism, its solver and the latest inputs; turns sensor messages into Steps.

    residual_warn_n: N, equilibrium residual above which a solve is a WARN.
    """

    def __init__(self, mech: Mechanism, config: InputConfig) -> None:
        self.config = config
        self.tracker = InputTracker(mech, config)
        self.mechanism = mech
        self._build(mech)

    def _build(self, mech: Mechanism) -> None:
        self.mechanism = mech
        self.solver = Solver(mech, consistency_tol=ASSEMBLY_LIMIT_M)
        self.machine = MachineModel(mech, self.solver)
        self.overdetermined = self.solver.kin.m > self.solver.kin.n
        self.estimates_load = bool(self.tracker.pressure_names)

    def apply_overrides(self, overrides: Mapping[str, Any]) -> None:
        """Change scalars of the description (e.g. {'implement.mass': 1530.0}); from the next step on."""
        self._build(self.mechanism.with_overrides(overrides))

    def set_staleness_limit(self, seconds: float) -> None:
        """Largest age (s) of any input relative to the triggering message, from the next step on."""
        self.config = replace(self.config, staleness_limit_s=float(seconds))
        self.tracker.config = self.config

    def on_joint_state(self, names: Sequence[str], positions: Sequence[float], stamp_ns: int) -> Step:
        """A sensor_msgs/JointState arrived (positions rad / m, stamp ns): accept, solve, finish."""
        return self._solve(self.accept_joint_state(names, positions, stamp_ns))

    def on_pressure(self, topic: str, fluid_pressure: float, stamp_ns: int) -> Step:
        """A sensor_msgs/FluidPressure arrived on `topic` (Pa, stamp ns): accept, solve, finish."""
        return self._solve(self.accept_pressure(topic, fluid_pressure, stamp_ns))

    # ---- the stages, shared with the batched replay ----------------------------------------------
    def accept_joint_state(self, names: Sequence[str], positions: Sequence[float], stamp_ns: int) -> Pending | Step:
        """Update the latest inputs from a JointState; the pending solve, or an ERROR/WARN Step."""
        try:
            self.tracker.update_joint_state(names, positions, stamp_ns)
        except InputError as exc:
            return Step(stamp_ns, ERROR, f"malformed input: {exc}", {"input": "joint_states"})
        return self._pending(stamp_ns, "joint_states")

    def accept_pressure(self, topic: str, fluid_pressure: float, stamp_ns: int) -> Pending | Step:
        """Update the latest inputs from a FluidPressure; the pending solve, or an ERROR/WARN Step."""
        try:
            self.tracker.update_pressure(topic, fluid_pressure, stamp_ns)
        except InputError as exc:
            return Step(stamp_ns, ERROR, f"malformed input: {exc}", {"input": topic})
        return self._pending(stamp_ns, topic)

    def _pending(self, stamp_ns: int, trigger: str) -> Pending | Step:
        try:
            inputs = self.tracker.inputs_at(stamp_ns)
        except StaleInputError as exc:
            return Step(stamp_ns, WARN, f"no solve: {exc}", {"input": trigger})
        values = {"input": trigger}
        values.update({f"input {k} [m]": f"{v:.6g}" for k, v in inputs.cylinders.items()})
        values.update({f"input {k} [rad]": f"{v:.6g}" for k, v in inputs.angles.items()})
        values.update({f"input {k} [Pa gauge]": f"{v:.6g}" for k, v in inputs.pressures.items()})
        return Pending(stamp_ns, inputs, values)

    def _solve(self, pending: Pending | Step) -> Step:
        if isinstance(pending, Step):
            return pending
        try:
            result = self.solver.solve(pending.inputs)
        except LinkageError as exc:
            return self.failed(pending, FAILURE_STATUS.get(type(exc), Status.INPUT), str(exc))
        return self.finish(pending, result, self.machine.evaluate(result))

    @staticmethod
    def failed(pending: Pending, status: int, message: str) -> Step:
        """The ERROR Step of a pose the solver rejected (status: results.STATUS_*)."""
        return Step(pending.stamp_ns, ERROR, f"{FAILURE_TEXT[status]}: {message}", pending.values)

    def finish(self, pending: Pending, result: Result, machine: MachineResult) -> Step:
        """Output messages and the diagnostic of one solved pose with its machine-level results."""
        mech, stamp_ns, values = self.mechanism, pending.stamp_ns, dict(pending.values)
        warnings = list(machine.warnings)
        if result.consistency_residual > CONSISTENCY_WARN_M:
            warnings.append(f"measurements disagree: kinematic residual {result.consistency_residual * 1e3:.2f} mm "
                            f"> {CONSISTENCY_WARN_M * 1e3:.1f} mm (check sensor calibration)")
        if out.residual_too_high(result):
            warnings.append(out.residual_too_high(result))
        if result.status != "ok":
            warnings.append(result.message or result.status)
        reserve = machine.lift_capacity.get("reserve", math.nan)
        reference = mech.tractor.steerability_reference if mech.tractor else "unit"
        outputs = out.Outputs(
            hinge_reactions=out.hinge_reactions(mech, stamp_ns, result, self.overdetermined),
            hitch_state=out.hitch_state(mech, stamp_ns, result, machine.lift_capacity, reserve,
                                        self.estimates_load, warnings),
            steerability=out.steerability(stamp_ns, machine.steerability, reference))
        steer = machine.steerability
        values.update({
            "implement load [N]": f"{result.implement_load:.6g}",
            "steerability ratio [-]": f"{steer.get('ratio', math.nan):.4f}",
            "steerability margin [-]": f"{steer.get('margin', math.nan):.4f}",
            "front axle load [N]": f"{steer.get('front_axle_load', math.nan):.6g}",
            "lift reserve [-]": f"{reserve:.4f}",
            "largest hinge reaction [N]": max((f"{h.magnitude:.6g}" for h in result.hinges.values()),
                                              key=float, default="nan"),
            "equilibrium residual [N]": f"{result.residual:.3g}",
            "kinematic residual [m]": f"{result.consistency_residual:.3g}",
        })
        level = WARN if warnings else OK
        return Step(stamp_ns, level, WARNING_JOIN.join(warnings) or "ok", values, outputs, result, machine=machine)
