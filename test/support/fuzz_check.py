"""The fuzz oracle shared by test/test_fuzz.py and bench/fuzz.py: drive the monitoring core with a
faulty sensor stream (linkage_monitor.sim.faults) and count what must never happen."""

from __future__ import annotations

from dataclasses import dataclass, fields
from typing import Iterable

import numpy as np

from linkage_monitor.mechanics import Mechanism, Solver
from linkage_monitor.monitoring.config import MonitorConfig
from linkage_monitor.monitoring.core import ASSEMBLY_LIMIT_M, Monitor
from linkage_monitor.monitoring.findings import Code, Level
from linkage_monitor.sim.faults import FuzzMessage


# Counters as fields, alike in form only to can.outcomes.FrameCounts, monitoring.weighing's settings and
# sim.work_cycle's records: other things counted.
@dataclass
class FuzzTally:
    """The fuzz table's columns (and the valid inputs refused, which must be 0 too)."""

    inputs_tried: int = 0
    crashes: int = 0
    differ_from_fresh_solver: int = 0
    malformed_accepted_as_ok: int = 0
    lost_without_diagnostic: int = 0
    valid_refused: int = 0

    def row(self) -> str:
        return " | ".join(f"{getattr(self, f.name):,}" for f in fields(self))

    @staticmethod
    def header() -> str:
        return " | ".join(f.name.replace("_", " ") for f in fields(FuzzTally))

    def add(self, other: "FuzzTally") -> None:
        for f in fields(self):
            setattr(self, f.name, getattr(self, f.name) + getattr(other, f.name))


REFUSAL_CODES = {Code.MALFORMED_INPUT, Code.UNKNOWN_INPUT, Code.DUPLICATE_JOINT, Code.OUT_OF_RANGE, Code.BAD_STAMP}


def check_in_process(mech: Mechanism, messages: Iterable[FuzzMessage], rel: float = 1e-9) -> FuzzTally:
    """Feed ``messages`` one by one to a live-path Monitor; every solved pose is re-solved by a
    fresh solver (batched, from the reference pose) and compared hinge by hinge."""
    monitor = Monitor(mech, MonitorConfig.default(mech.name, mech))
    tally = FuzzTally()
    solved = []
    for message in messages:
        tally.inputs_tried += 1
        try:
            step = monitor.step(message.event)
        except Exception:  # noqa: BLE001 - counting is the point
            tally.crashes += 1
            continue
        if step is None or (step.pose is None and not step.findings):
            tally.lost_without_diagnostic += 1
            continue
        codes = {f.code for f in step.findings}
        if Code.INTERNAL_ERROR in codes:
            tally.crashes += 1
        if message.malformed and (step.pose is not None or step.level != Level.ERROR):
            tally.malformed_accepted_as_ok += 1
        if not message.malformed and codes & REFUSAL_CODES:
            tally.valid_refused += 1
        if step.pose is not None:
            solved.append(step)
    if solved:
        fresh = Solver(monitor.mechanism, consistency_tol=ASSEMBLY_LIMIT_M)
        inputs = [s.inputs for s in solved]
        batch = fresh.solve_batch(
            cylinders={n: np.array([i.cylinders[n] for i in inputs]) for n in inputs[0].cylinders},
            angles={n: np.array([i.angles[n] for i in inputs]) for n in inputs[0].angles},
            pressures={n: np.array([i.pressures[n] for i in inputs]) for n in inputs[0].pressures})
        for k, step in enumerate(solved):
            live = np.array([[h.fx, h.fz] for h in step.pose.result.hinges.values()])
            ref = np.stack([batch.hinge_force[n][k] for n in step.pose.result.hinges])
            scale = max(float(np.abs(ref).max()), 1.0)
            if not np.all(np.abs(live - ref) <= rel * scale):
                tally.differ_from_fresh_solver += 1
    return tally
