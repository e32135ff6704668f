"""What the monitoring core returns: one ``Step`` per input event (level, findings, the
diagnostic's key-values, the solved ``Pose``), and for a batched run the ``Run`` of its ``Steps`` with
the solved configuration ``Segment``s as arrays (a quiet pose's Step built only when asked for:
``QuietPoses``); ``Due``, an accepted event whose solve is due.
Units SI (m, rad, N, Pa, kg); frame x forward, z up, origin at the rear wheels' ground contact.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property
from typing import Callable, Iterator, Mapping, Sequence, overload

import numpy as np

from linkage_monitor.mechanics import BatchResult, Inputs, Mechanism, Result
from linkage_monitor.mechanics.dynamics import DYNAMIC_FRONT, DYNAMIC_MARGIN, BodyAt
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
class QuietPoses:
    """Solved poses of one ``Segment`` whose checks found nothing, their Steps not built (``Steps``):
    ``index`` their places among the Steps, ``rows`` their rows of the segment's arrays, ``values`` their
    value rows (``mechanics.programs.ValueRow``, one per pose), ``dues`` what was solved (by row).
    Such a pose's Step has no finding, no error budget, no dynamic steerability and no weighing."""

    index: np.ndarray
    rows: np.ndarray
    segment: Segment
    values: np.ndarray
    dues: Callable[[np.ndarray], list[Due]]   # the Dues of rows of the segment (ascending)

    def within(self, lo: int, hi: int) -> QuietPoses:
        """Those of places lo..hi-1, their places counted from lo."""
        taken = (self.index >= lo) & (self.index < hi)
        return QuietPoses(self.index[taken] - lo, self.rows[taken], self.segment, self.values[taken], self.dues)

    def steps(self, which: np.ndarray) -> list[Step]:
        """The Steps of poses ``which`` (positions in these arrays), as ``Monitor`` builds a solved pose's."""
        batch, machine = self.segment.batch, self.segment.machine
        rows = self.rows[which]
        return [Step(due.stamp_ns, due.trigger, (), Pose(result, machine_result, values), due.inputs)
                for due, result, machine_result, values in zip(self.dues(rows), batch.results(rows),
                                                               machine.results(rows), self.values[which])]


class Steps(Sequence[Step]):
    """The Steps of a batched run or piece, one per input event, in order. ``made``: the Steps the core
    built (a finding, a failed or skipped solve, ...), None where a quiet pose's Step is not built yet;
    ``quiet``: those poses (``QuietPoses``), whose outputs a writer takes from the segments' columns
    (``is_quiet``). Asking for a quiet pose's Step (an index, iteration) builds it, once."""

    def __init__(self, made: list[Step | None], quiet: Sequence[QuietPoses] = ()) -> None:
        self.made, self.quiet = made, list(quiet)
        self.is_quiet = np.zeros(len(made), bool)
        for poses in self.quiet:
            self.is_quiet[poses.index] = True

    def __len__(self) -> int:
        return len(self.made)

    @overload
    def __getitem__(self, i: int) -> Step: ...

    @overload
    def __getitem__(self, i: slice) -> Steps: ...

    def __getitem__(self, i: int | slice) -> Step | Steps:
        if isinstance(i, slice):
            lo, hi, stride = i.indices(len(self.made))
            if stride != 1:
                raise ValueError("Steps are sliced with a stride of 1")
            hi = max(hi, lo)
            return Steps(self.made[lo:hi], [q.within(lo, hi) for q in self.quiet])
        step = self.made[i]
        if step is None:
            i = range(len(self.made))[i]
            for poses in self.quiet:
                at = int(np.searchsorted(poses.index, i))
                if at < len(poses.index) and poses.index[at] == i:
                    step = self.made[i] = poses.steps(np.array([at]))[0]
        assert step is not None, "every place is a Step made or a quiet pose"
        return step

    def __iter__(self) -> Iterator[Step]:
        for poses in self.quiet:
            self._build(poses, np.arange(len(poses.index)))
        return iter(self.made)  # type: ignore[arg-type]  # every None filled above

    def at(self, which: Sequence[int]) -> list[Step]:
        """``self[i]`` of each place of ``which``, the quiet poses' Steps not built yet built at once (one
        ``QuietPoses.steps`` per segment)."""
        wanted = np.asarray(which, np.int64)
        for poses in self.quiet:
            self._build(poses, np.flatnonzero(np.isin(poses.index, wanted)))
        return [self[i] for i in which]

    def _build(self, poses: QuietPoses, at: np.ndarray) -> None:
        """The Steps of ``poses`` at positions ``at`` (ascending) that are not built yet, built."""
        missing = at[np.fromiter((self.made[i] is None for i in poses.index[at].tolist()), bool, len(at))]
        if missing.size:
            for i, step in zip(poses.index[missing].tolist(), poses.steps(missing)):
                self.made[i] = step

    @property
    def stamps_ns(self) -> np.ndarray:
        """The Steps' stamps (ns), (N,) int64, without building a quiet pose's Step."""
        stamps = np.fromiter((0 if s is None else s.stamp_ns for s in self.made), np.int64, len(self.made))
        for poses in self.quiet:
            stamps[poses.index] = poses.segment.stamps_ns[poses.rows]
        return stamps

    def results(self, which: Sequence[int]) -> list[Result]:
        """The ``Result`` of each solved Step at ``which``, a quiet pose's from its segment's columns (its
        Step not built)."""
        wanted = np.asarray(which, np.int64)
        found: dict[int, Result] = {}
        for poses in self.quiet:
            at = np.flatnonzero(np.isin(poses.index, wanted))
            found.update(zip(poses.index[at].tolist(), poses.segment.batch.results(poses.rows[at])))
        return [found[k] if k in found else self._solved(k).result for k in which]

    def _solved(self, i: int) -> Pose:
        pose = self[i].pose
        if pose is None:
            raise ValueError(f"step {i} has no solved pose")
        return pose

    def said(self) -> Iterator[tuple[int, Step]]:
        """The place and Step of each Step that is not a quiet pose's (the only ones with findings)."""
        made = self.made
        return ((i, made[i]) for i in np.flatnonzero(~self.is_quiet).tolist())  # type: ignore[misc]  # not quiet: made


@dataclass(frozen=True)
class Run:
    """A batched run, or a piece of one (``Monitor.runs``): one Step per input event, and the solved
    segments as arrays (their ``steps`` index these Steps)."""

    steps: Steps
    segments: list[Segment]


# built per input event: a plain dataclass, not a frozen one (docs/architecture.md, One pipeline)
@dataclass(eq=False)
class Due:
    """An accepted input event whose solve is due."""

    stamp_ns: int
    trigger: str
    inputs: Inputs
    motions: Mapping[str, Motion] | None = None   # each measured cylinder's motion since the due before (uncertainty)
    body: BodyAt | None = None   # the tractor body's acceleration in use (an IMU configured), and its stamp



@dataclass(frozen=True)
class DueColumns:
    """Accepted input events whose solves are due, as columns (``InputTracker.accept_run``'s): their
    stamps (n,) ns, triggers (input topics) and inputs by name (cylinders m, angles rad, pressures Pa
    gauge; (n,) arrays each). For a configuration whose Due carries nothing else (no cylinder motions,
    no IMU body): ``dues`` builds the Dues of some of them, as the live path builds them."""

    stamps_ns: np.ndarray
    triggers: list[str]
    cylinders: dict[str, np.ndarray]
    angles: dict[str, np.ndarray]
    pressures: dict[str, np.ndarray]

    def __len__(self) -> int:
        return len(self.stamps_ns)

    def dues(self, at: np.ndarray) -> list[Due]:
        """The Dues of events ``at`` (indices), in that order."""
        kinds = [{n: c[at].tolist() for n, c in group.items()} for group in (self.cylinders, self.angles, self.pressures)]
        rows = [list(zip(*kind.values())) or [()] * len(at) for kind in kinds]
        return [Due(stamp, self.triggers[k], Inputs(cylinders=dict(zip(kinds[0], cylinders)),
                                                    angles=dict(zip(kinds[1], angles)),
                                                    pressures=dict(zip(kinds[2], pressures)), rates={},
                                                    accelerations={}))
                for k, stamp, cylinders, angles, pressures in zip(at.tolist(), self.stamps_ns[at].tolist(), *rows)]
