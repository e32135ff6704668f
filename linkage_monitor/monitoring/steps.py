"""What the monitoring core returns: one ``Step`` per input event (level, findings, the
diagnostic's key-values, the solved ``Pose``), and for a batched run the ``Run`` of its Steps with
the solved configuration ``Segment``s as arrays; ``Due``, an accepted event whose solve is due.
Units SI (m, rad, N, Pa, kg); frame x forward, z up, origin at the rear wheels' ground contact.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property

import numpy as np

from linkage_monitor.mechanics import BatchResult, Inputs, Mechanism, Result
from linkage_monitor.mechanics.dynamics import DYNAMIC_FRONT, DYNAMIC_MARGIN, BodyAcceleration
from linkage_monitor.mechanics.error_sources import Motion
from linkage_monitor.mechanics.machine import MachineBatch, MachineResult
from linkage_monitor.mechanics.budget import Budget

from .bounds import uncertainty_values
from .config import MonitorConfig
from .findings import Finding, Level, fmt
from .implement_mass import WeighingState, weighing_values

MESSAGE_JOIN = " | "  # between the sentences of several findings of one step
NO_FINDINGS = "ok"    # the message of a step without findings


# built per input event: a plain dataclass, not a frozen one (docs/architecture.md, One pipeline)
@dataclass(eq=False)
class Pose:
    """A solved pose: the solver's result and the machine-level results (axle loads,
    steerability, lift capacity), both domain types in SI units."""

    result: Result
    machine: MachineResult
    values: np.ndarray | None = None   # its value row (mechanics.programs.ValueRow) when the compiled call wrote one
    budget: Budget | None = None       # its error budget, with MonitorConfig.uncertainty
    # with an IMU reading: mechanics.dynamics.DYNAMIC_KEYS (N, N, -, -); the steerability row is then the unit's at rest
    dynamic: np.ndarray | None = None


# built per input event: a plain dataclass, not a frozen one (docs/architecture.md, One pipeline)
@dataclass(eq=False)
class Step:
    """The outcome of one input event (stamp = its header stamp, ns)."""

    stamp_ns: int
    trigger: str
    findings: tuple[Finding, ...] = ()
    pose: Pose | None = None
    inputs: Inputs | None = None   # what was solved (None when no solve was due)
    weighing: WeighingState | None = None   # the weighing after this step (a solved step, with the estimator on)

    @cached_property
    def values(self) -> dict[str, str]:
        """The key-values of the step's diagnostic, as text (SI units in the keys): the input topic,
        the inputs of a due solve, the main results of a solved pose (with the smallest transmission
        angle and the step attaining it where the reduced path solved it). Formatted when first asked
        for (most steps are never reported)."""
        values = {"input": self.trigger}
        if self.inputs is not None:
            values.update({f"input {k} [m]": fmt(v) for k, v in self.inputs.cylinders.items()})
            values.update({f"input {k} [rad]": fmt(v) for k, v in self.inputs.angles.items()})
            values.update({f"input {k} [Pa gauge]": fmt(v) for k, v in self.inputs.pressures.items()})
        if self.pose is not None:
            result, steer, capacity = self.pose.result, self.pose.machine.steerability, self.pose.machine.lift_capacity
            values.update({
                "implement load [N]": fmt(result.implement_load),
                "steerability ratio [-]": f"{steer.get('ratio', math.nan):.4f}",
                "steerability margin [-]": f"{steer.get('margin', math.nan):.4f}",
                "front axle load [N]": fmt(steer.get("front_axle_load", math.nan)),
                **({"dynamic steerability margin [-]": f"{self.pose.dynamic[DYNAMIC_MARGIN]:.4f}",
                    "dynamic front axle load [N]": fmt(float(self.pose.dynamic[DYNAMIC_FRONT]))}
                   if self.pose.dynamic is not None else {}),
                "lift reserve [-]": f"{capacity.get('reserve', math.nan):.4f}",
                "largest hinge reaction [N]": fmt(max(result.hinge_magnitude.tolist(), default=math.nan)),
                "equilibrium residual [N]": f"{result.residual:.3g}",
                "kinematic residual [m]": f"{result.consistency_residual:.3g}",
            })
            if math.isfinite(result.transmission_angle):   # NaN on the general path
                values["min transmission angle [rad]"] = f"{result.transmission_angle:.4f}"
            if result.weakest_transmission:
                values["weakest transmission"] = result.weakest_transmission
            if self.pose.budget is not None:   # standard uncertainties (1 sigma) of the judged values
                values.update(uncertainty_values(self.pose.budget))
        if self.weighing is not None:
            values.update(weighing_values(self.weighing))
        return values

    @property
    def level(self) -> Level:
        """The worst level of the findings (OK without any)."""
        if not self.findings:   # most steps: asked several times per step (diagnostics, markers, the summary)
            return Level.OK
        return max(f.level for f in self.findings)

    @property
    def message(self) -> str:
        """The findings' sentences joined, or 'ok'."""
        return MESSAGE_JOIN.join(f.text for f in self.findings) or NO_FINDINGS


@dataclass(frozen=True)
class Segment:
    """The poses of one configuration segment of a batched run, solved together.

    steps: index (into ``Run.steps``) of each pose's Step; stamps_ns: their header stamps;
    batch / machine: the solver's and the machine-level results (arrays, SI units; failed poses
    NaN with their status); mechanism: the effective mechanism of the segment; config: the
    configuration it was solved with.
    """

    steps: np.ndarray
    stamps_ns: np.ndarray
    batch: BatchResult
    machine: MachineBatch
    mechanism: Mechanism
    config: MonitorConfig


@dataclass(frozen=True)
class Run:
    """A batched run, or a piece of one (``Monitor.runs``): one Step per input event, and the solved
    segments as arrays (their ``steps`` index these Steps)."""

    steps: list[Step]
    segments: list[Segment]


# built per input event: a plain dataclass, not a frozen one (docs/architecture.md, One pipeline)
@dataclass(eq=False)
class Due:
    """An accepted input event whose solve is due."""

    stamp_ns: int
    trigger: str
    inputs: Inputs
    motions: dict[str, Motion] | None = None   # each measured cylinder's motion since the due before (uncertainty)
    body: BodyAcceleration | None = None       # the tractor body's acceleration in use (an IMU configured)

