"""Load histories of a replayed bag: per hinge the reaction magnitude over time, and the
machine-level margins, at every solved pose (what the fleet analysis and `replay --spectra` count).

Time t (s) is the header stamp from the first input of the bag. Units SI (N); the steerability
margin is the front-axle share minus its minimum (−, < 0 is too little weight on the steered
axle), the lift reserve the lift capacity over the implement load (−, < 1 cannot lift).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from linkage_monitor.monitoring.bounds import straddles, verdict_half_width
from linkage_monitor.monitoring.core import Run

from .spectra import Spectrum, rainflow_spectrum


@dataclass(frozen=True)
class LoadHistory:
    """Solved poses of one run: t (N,) s; hinge[name] (N,) reaction magnitude N; margin (N,)
    and reserve (N,) (NaN where the machine model has none); duration_s from the first to the
    last input stamp; margin_half_width and reserve_half_width (N,): the half-widths their verdicts
    judge (``monitoring.bounds.verdict_half_width``) where the run computed the error budget
    (``MonitorConfig.uncertainty``; NaN at a pose whose u is unbounded), None where it did not."""

    t: np.ndarray
    hinge: dict[str, np.ndarray]
    margin: np.ndarray
    reserve: np.ndarray
    duration_s: float
    margin_half_width: np.ndarray | None = None
    reserve_half_width: np.ndarray | None = None

    @classmethod
    def from_run(cls, run: Run) -> LoadHistory:
        recorder = HistoryRecorder()
        recorder.add(run)
        return recorder.history()

    def time_below(self, values: np.ndarray, limit: float) -> float:
        """Seconds spent with ``values`` < limit: each solved pose holds until the next one."""
        if self.t.size < 2:
            return 0.0
        dt = np.diff(self.t)
        return float(np.sum(np.where(values[:-1] < limit, dt, 0.0)))

    def time_uncertain(self, values: np.ndarray, half_width: np.ndarray, limit: float) -> float:
        """Seconds spent with ``values`` ≥ limit but their 95 % interval (± ``half_width``) reaching below
        it, or unbounded (``monitoring.bounds.straddles``): each solved pose holds until the next one."""
        if self.t.size < 2:
            return 0.0
        return float(np.sum(np.where(straddles(values[:-1], half_width[:-1], limit), np.diff(self.t), 0.0)))

    def spectra(self) -> dict[str, Spectrum]:
        """Rainflow spectrum of each hinge's reaction magnitude over the bag's duration."""
        return {name: rainflow_spectrum(values, self.duration_s) for name, values in self.hinge.items()}


class HistoryRecorder:
    """A ``LoadHistory`` gathered from the pieces of a run (``Monitor.runs``), in order: of each
    piece only the stamps (ns) and the solved poses' numbers are kept, as arrays (``add``)."""

    def __init__(self) -> None:
        self._first_ns: int | None = None   # the smallest and largest stamp of every step
        self._last_ns: int | None = None
        self._names: list[str] | None = None   # the hinges, from the first solved pose
        self._stamps: list[np.ndarray] = []
        self._magnitudes: list[np.ndarray] = []
        self._margin: list[np.ndarray] = []
        self._reserve: list[np.ndarray] = []
        self._u: list[np.ndarray] = []   # (n, 2): the margin's and the reserve's verdict half-widths, where budgets were computed
        self._budgets = True             # every solved pose so far carried its error budget

    def add(self, run: Run) -> None:
        """The next piece of the run."""
        stamps = [s.stamp_ns for s in run.steps]
        if stamps:
            first, last = min(stamps), max(stamps)
            self._first_ns = first if self._first_ns is None else min(self._first_ns, first)
            self._last_ns = last if self._last_ns is None else max(self._last_ns, last)
        poses = [(s.stamp_ns, s.pose) for s in run.steps if s.pose is not None]
        if not poses:
            return
        if self._names is None:
            self._names = [name for name, _, _ in poses[0][1].result.names.hinges]
        self._stamps.append(np.array([stamp for stamp, _ in poses], dtype=np.int64))
        self._magnitudes.append(np.array([p.result.hinge_magnitude for _, p in poses]).reshape(len(poses),
                                                                                          len(self._names)))
        self._margin.append(np.array([p.machine.value("margin") for _, p in poses]))
        self._reserve.append(np.array([p.machine.value("reserve") for _, p in poses]))
        self._budgets = self._budgets and all(p.budget is not None for _, p in poses)
        if self._budgets:
            self._u.append(np.array([[verdict_half_width(p.budget, "steerability_margin"), verdict_half_width(p.budget, "lift_reserve")]
                                     for _, p in poses if p.budget is not None]).reshape(len(poses), 2))

    def history(self) -> LoadHistory:
        """The ``LoadHistory`` of every piece added."""
        start = self._first_ns or 0
        duration = ((self._last_ns or 0) - start) * 1e-9
        names = self._names or []
        stamps = np.concatenate(self._stamps) if self._stamps else np.zeros(0, dtype=np.int64)
        magnitudes = np.concatenate(self._magnitudes) if self._magnitudes else np.zeros((0, len(names)))
        u = (np.concatenate(self._u) if self._u else np.zeros((0, 2))) if self._budgets and self._u else None
        return LoadHistory((stamps - start) * 1e-9, {name: magnitudes[:, k] for k, name in enumerate(names)},
                           np.concatenate(self._margin) if self._margin else np.zeros(0),
                           np.concatenate(self._reserve) if self._reserve else np.zeros(0), duration,
                           u[:, 0] if u is not None else None, u[:, 1] if u is not None else None)


def spectra_table(history: LoadHistory, slope: float, bin_width: float) -> str:
    """Each hinge's rainflow spectrum (cycles per range bin, kN) and damage-equivalent load, as text."""
    lines = [f"load spectra over {history.duration_s:.2f} s (rainflow, ASTM E1049; DEL at 1 Hz, m = {slope:g})"]
    for name, spectrum in history.spectra().items():
        lines.append(f"\nhinge {name}: {spectrum.counts.sum():g} cycles, damage-equivalent load "
                     f"{spectrum.damage_equivalent(slope) / 1e3:.3f} kN")
        lines.append("  range [kN]          cycles")
        for lower, count in zip(*spectrum.binned(bin_width)):
            lines.append(f"  {lower / 1e3:8.2f} - {(lower + bin_width) / 1e3:<8.2f} {count:8g}")
    return "\n".join(lines)
