"""The due poses of one configuration segment of a batched run (``Monitor.runs``), solved a part
at a time in a worker thread as they are accepted, and the checks of a solved segment at once
(``checks.pose_checks``, the live path's rule). Units SI (m, rad, N, Pa).
"""

from __future__ import annotations

import math
from concurrent.futures import Future, ThreadPoolExecutor
from typing import NamedTuple, Sequence

import numpy as np

from linkage_monitor.mechanics import BatchResult, Status
from linkage_monitor.mechanics.machine import MachineBatch, MachineModel, MachineSeries

from .checks import CheckedValues, pose_checks
from .steps import Due, DueColumns

INPUT_KINDS = ("cylinders", "angles", "pressures", "rates", "accelerations")   # the fields of ``Inputs``


def input_columns(dues: Sequence[Due], kind: str) -> dict[str, np.ndarray]:
    """The inputs of ``kind`` of ``dues`` (one configuration's: the same names) as arrays (N,) by name."""
    return {n: np.array([getattr(d.inputs, kind)[n] for d in dues]) for n in getattr(dues[0].inputs, kind)}


class TakenDues:
    """The dues of a segment ``SegmentSeries.cut`` hands over, in order: ``steps`` (n,) their Steps'
    places, ``stamps_ns`` (n,) their stamps, ``dues`` the Dues of some (a run accepted at once is held as
    ``DueColumns``: its Dues built when asked for)."""

    def __init__(self, parts: list[tuple[list[int], list[Due]] | tuple[np.ndarray, DueColumns]]) -> None:
        self._parts = [dues for _, dues in parts]
        self.steps = (np.concatenate([np.asarray(steps, np.int64) for steps, _ in parts]) if parts
                      else np.zeros(0, np.int64))
        self.stamps_ns = (np.concatenate([dues.stamps_ns if isinstance(dues, DueColumns)
                                          else np.array([d.stamp_ns for d in dues], np.int64) for dues in self._parts])
                          if parts else np.zeros(0, np.int64))
        self._ends = np.cumsum([len(dues) for dues in self._parts])

    def __len__(self) -> int:
        return len(self.steps)

    def dues(self, rows: np.ndarray) -> list[Due]:
        """The Dues of ``rows`` (ascending), in order (a run's built from its columns)."""
        part_of = np.searchsorted(self._ends, rows, side="right")
        found: list[Due] = []
        for part in np.unique(part_of).tolist():
            dues, at = self._parts[part], rows[part_of == part] - (int(self._ends[part - 1]) if part else 0)
            found += dues.dues(at) if isinstance(dues, DueColumns) else [dues[k] for k in at.tolist()]
        return found

    def all(self) -> list[Due]:
        """Every Due, in order."""
        return self.dues(np.arange(len(self)))


class Cut(NamedTuple):
    """The dues of a segment up to a cut (``SegmentSeries.cut``), their parts being solved and the series
    finished in the worker: ``series`` waits for them."""

    dues: TakenDues
    parts: list[Future[None]]
    finished: Future[MachineSeries] | None   # None: a kinetostatics segment, or no dues

    def series(self) -> MachineSeries | None:
        """The dues' ``MachineSeries`` (every part solved; None for a kinetostatics segment or no dues)."""
        for part in self.parts:
            part.result()   # raises what the part raised
        return self.finished.result() if self.finished is not None else None


class SegmentSeries:
    """The due poses of one configuration segment of ``Monitor.runs`` (``add``: a step's due; ``add_columns``:
    a run's, as columns), solved PART at a time in ``worker`` as they are accepted (``MachineModel.series``:
    each pose from the one before, as ``solve_series`` solves them all at once), unless the configuration
    takes kinetostatics (then ``cut`` gives no series and ``Monitor._solve_segment`` solves them itself).
    ``cut`` hands over the dues so far; the next ones go on from the last pose solved. ``machine``
    is the segment's machine model, ``kinetostatics`` its configuration's."""

    PART = 256   # poses per part: the last part, solved after the last input, is short

    def __init__(self, machine: MachineModel, kinetostatics: bool, worker: ThreadPoolExecutor) -> None:
        self._dues: list[tuple[list[int], list[Due]] | tuple[np.ndarray, DueColumns]] = []
        self._count = 0   # dues added
        self._series = None if kinetostatics else machine.series()
        self._worker = worker
        self._parts: list[Future[None]] = []
        self._sent = 0   # dues handed to the worker

    def add(self, step: int, due: Due) -> None:
        """The due solve of step ``step``."""
        last = self._dues[-1] if self._dues else None
        if last is not None and isinstance(last[1], list):
            last[0].append(step)
            last[1].append(due)
        else:
            self._dues.append(([step], [due]))
        self._added(1)

    def add_columns(self, first_step: int, dues: DueColumns) -> None:
        """The due solves of steps ``first_step``.. (one per due of ``dues``, in order)."""
        self._dues.append((np.arange(first_step, first_step + len(dues)), dues))
        self._added(len(dues))

    def _added(self, n: int) -> None:
        self._count += n
        if self._count - self._sent >= self.PART:
            self._send()

    def cut(self) -> Cut:
        """The dues added since the last ``cut``, their series finished by the worker after their parts
        (it takes its tasks in order), while the caller reads on; the segment is left empty, its next
        dues going on from the last pose of these."""
        dues = TakenDues(self._dues)
        if self._series is None or not len(dues):
            self._dues, self._count = [], 0
            return Cut(dues, [], None)
        self._send()
        cut = Cut(dues, self._parts, self._worker.submit(self._series.finish))
        self._dues, self._parts, self._sent, self._count = [], [], 0, 0
        return cut

    def _send(self) -> None:
        """Hand the dues not yet handed to the worker."""
        if self._series is None or self._sent == self._count:
            return
        lo, self._sent = self._sent, self._count
        parts = [dues for _, dues in self._dues]
        self._parts.append(self._worker.submit(self._series.add, *(_inputs(parts, kind, lo, self._count)
                                                                   for kind in ("cylinders", "angles", "pressures"))))


def _inputs(parts: list[list[Due] | DueColumns], kind: str, lo: int, hi: int) -> dict[str, np.ndarray]:
    """The inputs of ``kind`` (cylinders, angles or pressures) of dues lo..hi-1 of ``parts`` (in order) as
    arrays (hi - lo,) by name."""
    pieces: list[dict[str, np.ndarray]] = []
    start = 0
    for dues in parts:
        end = start + len(dues)
        a, b = max(lo, start) - start, min(hi, end) - start
        if a < b:
            pieces.append({n: c[a:b] for n, c in getattr(dues, kind).items()} if isinstance(dues, DueColumns)
                          else input_columns(dues[a:b], kind))
        start = end
    return {n: np.concatenate([p[n] for p in pieces]) if len(pieces) > 1 else pieces[0][n] for n in pieces[0]}


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
