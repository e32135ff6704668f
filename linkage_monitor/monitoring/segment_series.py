"""The due poses of one configuration segment of a batched run (``Monitor.runs``), solved a part
at a time in a worker thread as they are accepted, and the checks of a solved segment at once
(``checks.pose_checks``, the live path's rule). Units SI (m, rad, N, Pa).
"""

from __future__ import annotations

import math
from concurrent.futures import Future, ThreadPoolExecutor
from typing import Sequence

import numpy as np

from linkage_monitor.mechanics import BatchResult, Status
from linkage_monitor.mechanics.machine import MachineBatch, MachineModel, MachineSeries

from .checks import CheckedValues, pose_checks
from .steps import Due

INPUT_KINDS = ("cylinders", "angles", "pressures", "rates", "accelerations")   # the fields of ``Inputs``


def input_columns(dues: Sequence[Due], kind: str) -> dict[str, np.ndarray]:
    """The inputs of ``kind`` of ``dues`` (one configuration's: the same names) as arrays (N,) by name."""
    return {n: np.array([getattr(d.inputs, kind)[n] for d in dues]) for n in getattr(dues[0].inputs, kind)}


class SegmentSeries:
    """The due poses of one configuration segment of ``Monitor.runs`` (``dues``: (step index, due)),
    solved PART at a time in ``worker`` as they are accepted (``MachineModel.series``: each pose from the
    one before, as ``solve_series`` solves them all at once), unless the configuration takes
    kinetostatics (then ``take`` gives no series and ``Monitor._solve_segment`` solves them itself).
    ``take`` hands over the dues so far; the next ones go on from the last pose solved. ``machine``
    is the segment's machine model, ``kinetostatics`` its configuration's."""

    PART = 256   # poses per part: the last part, solved after the last input, is short

    def __init__(self, machine: MachineModel, kinetostatics: bool, worker: ThreadPoolExecutor) -> None:
        self.dues: list[tuple[int, Due]] = []
        self._series = None if kinetostatics else machine.series()
        self._worker = worker
        self._parts: list[Future[None]] = []
        self._sent = 0   # dues handed to the worker

    def add(self, step: int, due: Due) -> None:
        """The due solve of step ``step``."""
        self.dues.append((step, due))
        if len(self.dues) - self._sent >= self.PART:
            self._send()

    def take(self) -> tuple[list[tuple[int, Due]], MachineSeries | None]:
        """The dues added since the last ``take`` and their ``MachineSeries`` (every part solved; None
        for a kinetostatics segment or no dues); the segment is left empty."""
        dues = self.dues
        if self._series is None or not dues:
            self.dues = []
            return dues, None
        self._send()
        for part in self._parts:
            part.result()   # raises what the part raised
        self.dues, self._parts, self._sent = [], [], 0
        return dues, self._series.finish()

    def _send(self) -> None:
        """Hand the dues not yet handed to the worker."""
        if self._series is None or self._sent == len(self.dues):
            return
        dues = [d for _, d in self.dues[self._sent:]]
        self._sent = len(self.dues)
        self._parts.append(self._worker.submit(self._series.add, input_columns(dues, "cylinders"), input_columns(dues, "angles"),
                                               input_columns(dues, "pressures")))


def limit_values(machine: MachineBatch, size: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The values judged against a limit of a solved segment's poses: front and rear axle loads,
    steerability margin, lift reserve ((N,) each; NaN where not computed)."""
    steer, capacity, missing = machine.steerability, machine.lift_capacity, np.full(size, math.nan)
    return (steer.get("front_axle_load", missing), steer.get("rear_axle_load", missing), steer.get("margin", missing),
            capacity.get("reserve", missing))


def segment_checks(batch: BatchResult, machine: MachineBatch, dynamic_margin: np.ndarray | None = None) -> np.ndarray:
    """``pose_checks`` of every pose of a solved segment at once ((N,) ints; a failed pose's NaN
    values pass every check, and its verdict is worded from its status); ``dynamic_margin`` (N,)
    with an IMU (``monitoring.road``)."""
    return np.asarray(pose_checks(CheckedValues(
        batch.status == Status.LIFT_OFF, batch.consistency_residual, batch.residual, batch.largest_force,
        *limit_values(machine, len(batch)), batch.load_amplification,
        dynamic_margin if dynamic_margin is not None else math.nan)))
