"""Load spectra of a time series: rainflow cycle counting and the damage-equivalent load.

Cycles are counted by the rainflow method of ASTM E1049-85 (section 5.4.4) with the
``rainflow`` package (its ``extract_cycles``: half cycles count 0.5). The damage-equivalent
load (DEL) is the constant range that, repeated N_eq times, does the same Miner damage as the
counted cycles under a Wöhler (S-N) curve N·S^m = const:

    DEL = (Σ_i n_i · S_i^m / N_eq)^(1/m),   N_eq = f_eq · T

with n_i the count and S_i the range (N) of cycle i, T the duration (s) and f_eq = 1 Hz (the
"1 Hz equivalent load" of IEC 61400-13 practice). It is a relative measure of damage between
bags and hinges; a life needs the pin's own S-N curve (docs/fleet.md).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import rainflow

EQUIVALENT_FREQUENCY_HZ = 1.0


@dataclass(frozen=True)
class Spectrum:
    """Rainflow cycles of one signal: ranges (N,) in the signal's unit (N for forces), counts (N,)
    (1 = full cycle, 0.5 = half cycle), over ``duration_s`` seconds."""

    ranges: np.ndarray
    counts: np.ndarray
    duration_s: float

    def damage_equivalent(self, slope: float) -> float:
        """DEL (signal unit) for Wöhler slope m = ``slope`` at N_eq = 1 Hz · duration; 0 without cycles."""
        cycles = EQUIVALENT_FREQUENCY_HZ * self.duration_s
        if not self.ranges.size or cycles <= 0.0:
            return 0.0
        return float((np.sum(self.counts * self.ranges**slope) / cycles) ** (1.0 / slope))

    def binned(self, width: float) -> tuple[np.ndarray, np.ndarray]:
        """Cycle counts per range bin [k·width, (k+1)·width): (lower edges, counts) of the
        non-empty bins, in increasing range."""
        if not self.ranges.size:
            return np.zeros(0), np.zeros(0)
        index = np.floor(self.ranges / width).astype(np.int64)
        bins, where = np.unique(index, return_inverse=True)
        return bins * width, np.bincount(where, weights=self.counts)


def rainflow_spectrum(signal: np.ndarray, duration_s: float) -> Spectrum:
    """Rainflow-count ``signal`` (finite samples in time order; NaN samples are dropped)."""
    values = np.asarray(signal, dtype=float)
    values = values[np.isfinite(values)]
    if values.size < 2:
        return Spectrum(np.zeros(0), np.zeros(0), duration_s)
    cycles = [(rng, count) for rng, _, count, _, _ in rainflow.extract_cycles(values) if rng > 0.0]
    if not cycles:
        return Spectrum(np.zeros(0), np.zeros(0), duration_s)
    ranges, counts = np.array(cycles).T
    return Spectrum(ranges, counts, duration_s)
