"""A monotone table from a CAN signal (e.g. the ISOBUS hitch position, %) to a measurement of
the mechanism (the lift arm's angle, rad; a cylinder's length, m), linear between its points,
and its fit from a recorded lift whose true values are known.

A tractor that reports only its hitch position gives the monitor no angle: the table is the
tractor's own relation between the two, taken once from a lift where both were recorded
(``linkage-monitor can-calibrate``).
"""

from __future__ import annotations

from bisect import bisect_right
from dataclasses import dataclass

import numpy as np

from linkage_monitor.monitoring.findings import fmt


class TableError(ValueError):
    """A table that is not one (lengths differ, not strictly monotone, too few points)."""


@dataclass(frozen=True)
class PositionTable:
    """signal: the points' signal values, strictly increasing; value: the measurement there (SI),
    strictly increasing or strictly decreasing. Outside [signal[0], signal[-1]] there is no value."""

    signal: tuple[float, ...]
    value: tuple[float, ...]

    def __post_init__(self) -> None:
        s, v = np.asarray(self.signal, float), np.asarray(self.value, float)
        if s.size != v.size:
            raise TableError(f"{s.size} signal points but {v.size} values: give one value per point")
        if s.size < 2:
            raise TableError("a table needs at least 2 points")
        if not (np.all(np.isfinite(s)) and np.all(np.isfinite(v))):
            raise TableError("every point and value must be a finite number")
        if not np.all(np.diff(s) > 0):
            raise TableError("the signal points must increase strictly")
        dv = np.diff(v)
        if not (np.all(dv > 0) or np.all(dv < 0)):
            raise TableError("the values must increase strictly or decrease strictly (a monotone table)")

    def lookup(self, x: float) -> float | None:
        """The value at signal ``x`` (linear between the points), None outside the table. Plain
        Python: numpy's interp costs ~10 µs a call on a table of tuples, ~0.5 µs here."""
        s, v = self.signal, self.value
        if not s[0] <= x <= s[-1]:
            return None
        k = bisect_right(s, x) - 1
        if k == len(s) - 1:
            return v[-1]
        return v[k] + (x - s[k]) * (v[k + 1] - v[k]) / (s[k + 1] - s[k])

    def lookup_many(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``lookup`` of every value of ``x`` (n,): the values (n,) and where they are inside the table
        (n,) bool; outside, the value is meaningless. The same arithmetic as ``lookup``, element by
        element, so the same floats."""
        s, v = np.asarray(self.signal, float), np.asarray(self.value, float)
        x = np.asarray(x, float)
        inside = (s[0] <= x) & (x <= s[-1])
        k = np.clip(np.searchsorted(s, x, side="right") - 1, 0, len(s) - 2)
        between = v[k] + (x - s[k]) * (v[k + 1] - v[k]) / (s[k + 1] - s[k])
        return np.where(x >= s[-1], v[-1], between), inside

    def steepest(self) -> float:
        """The largest |Δvalue / Δsignal| of its segments (the value's unit per the signal's): where one
        step of the signal moves the value most."""
        return float(np.max(np.abs(np.diff(self.value) / np.diff(self.signal))))

    def span(self) -> str:
        """The table's signal range as text."""
        return f"{fmt(self.signal[0])}..{fmt(self.signal[-1])}"


def _isotonic(y: np.ndarray, w: np.ndarray) -> np.ndarray:
    """Weighted least-squares non-decreasing fit of ``y`` (pool adjacent violators)."""
    blocks: list[list[float]] = []   # [mean, weight, count]
    for yi, wi in zip(y.tolist(), w.tolist()):
        blocks.append([yi, wi, 1])
        while len(blocks) > 1 and blocks[-2][0] > blocks[-1][0]:
            m2, w2, n2 = blocks.pop()
            m1, w1, n1 = blocks.pop()
            blocks.append([(m1 * w1 + m2 * w2) / (w1 + w2), w1 + w2, n1 + n2])
    return np.concatenate([np.full(int(n), m) for m, _, n in blocks])


def fit_table(signal: np.ndarray, truth: np.ndarray, points: int = 26) -> PositionTable:
    """The monotone table that best reproduces ``truth`` from ``signal`` (paired samples of a
    recorded lift): the mean true value at each distinct signal value (the signal is quantized,
    e.g. 0.4 %), made monotone in the direction of the overall trend by pool-adjacent-violators,
    then at most ``points`` points evenly spread over the distinct signal values (first and last
    kept). Raises TableError if the lift does not span at least two signal values."""
    s, t = np.asarray(signal, float), np.asarray(truth, float)
    keep = np.isfinite(s) & np.isfinite(t)
    s, t = s[keep], t[keep]
    levels, inverse, counts = np.unique(s, return_inverse=True, return_counts=True)
    if levels.size < 2:
        raise TableError(f"the recorded lift spans {levels.size} signal value(s): record a lift over the "
                         "whole hitch range")
    means = np.bincount(inverse, weights=t) / counts
    rising = np.polyfit(levels, means, 1)[0] >= 0
    fitted = _isotonic(means if rising else -means, counts.astype(float))
    fitted = fitted if rising else -fitted
    chosen = np.unique(np.round(np.linspace(0, levels.size - 1, min(points, levels.size))).astype(int))
    x, y = levels[chosen], fitted[chosen]
    x = np.round(x, 9)   # the signal's quantum (e.g. 0.4 %) without binary noise (27.200000000000003)
    xs, ys = [float(x[0])], [float(y[0])]
    for xi, yi in zip(x[1:].tolist(), y[1:].tolist()):
        if yi != ys[-1]:   # pooled blocks share a value: keep the first point of each
            xs.append(xi)
            ys.append(yi)
    return PositionTable(tuple(xs), tuple(ys))
