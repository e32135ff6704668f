"""The 95 % coverage factor of each output of an error budget, read from its table
(``coverage_factor``: the model, the table and the rule; here the rule over the rows in one call)."""

from __future__ import annotations

import math

import numpy as np
from numba import njit


@njit(cache=True)
def _cell(grid: np.ndarray, x: float) -> tuple[int, float]:
    """The cell i of ``grid`` (ascending) that holds x (0 .. len − 2, the ends taken for beyond them)
    and x's place in it, 0..1."""
    i = 0
    while i < grid.size and grid[i] <= x:
        i += 1
    i = min(max(i - 1, 0), grid.size - 2)
    a = (x - grid[i]) / (grid[i + 1] - grid[i])
    return i, min(max(a, 0.0), 1.0)


@njit(cache=True, error_model="numpy")
def coverage_factors(contributions: np.ndarray, uniform: np.ndarray, sign: np.ndarray, table: np.ndarray,
                     shares: np.ndarray, inverse_counts: np.ndarray, shift_step: float, normal_factor: float,
                     interval: np.ndarray, tail: np.ndarray) -> None:
    """The coverage factors of each row of ``contributions`` (n_out, n_src; the output's unit, signed)
    into ``interval`` and ``tail`` (n_out,): ``uniform`` (n_src,) the uniform sources, ``sign`` (n_src,)
    0 or the known sign of a uniform one, ``table`` (len(shares), len(inverse_counts), n_shifts) q at
    each uniform share w (``shares``: evenly spaced from 0 to 1, read by index), inverse effective count
    1/n and shift t (a step of ``shift_step`` from 0). As
    ``coverage_factor.coverage_factors`` states it: NaN where u² is not finite, ``normal_factor`` where
    it is 0."""
    n_out, n_src = contributions.shape
    last, cells = table.shape[2] - 1, shares.size - 1
    for r in range(n_out):
        shift, total, normal, flat, flat_squares = 0.0, 0.0, 0.0, 0.0, 0.0
        for s in range(n_src):
            c = contributions[r, s]
            square = c * c
            total += square
            if not uniform[s]:
                normal += square
            elif sign[s] != 0.0:
                shift += c * sign[s]
                flat += 0.25 * square
                flat_squares += (0.25 * square) ** 2
            else:
                flat += square
                flat_squares += square * square
        if not math.isfinite(total):
            interval[r] = tail[r] = math.nan
            continue
        if total <= 0.0:
            interval[r] = tail[r] = normal_factor
            continue
        spread = normal + flat
        share = flat / spread if spread > 0.0 else 0.0
        inverse = flat_squares / flat**2 if flat > 0.0 else 0.0
        place = min(share * cells, float(cells))   # w's place on its even grid (0 ≤ w ≤ 1)
        i = min(int(place), cells - 1)
        a = place - i
        j, b = _cell(inverse_counts, inverse)
        k = ((1 - a) * (1 - b) * table[i, j, 0] + a * (1 - b) * table[i + 1, j, 0] + (1 - a) * b * table[i, j + 1, 0]
             + a * b * table[i + 1, j + 1, 0])
        half_shift, sigma = 0.5 * math.sqrt(3.0) * abs(shift), math.sqrt(spread)
        tail[r] = (half_shift + k * sigma) / math.sqrt(total)
        if half_shift == 0.0:
            interval[r] = tail[r]
            continue
        position = min(half_shift / sigma / shift_step, float(last))   # t's place on the table's grid
        m = min(int(position), last - 1)
        c = position - m
        q = 0.0
        for n, weight in ((m, 1.0 - c), (m + 1, c)):
            q += weight * ((1 - a) * (1 - b) * table[i, j, n] + a * (1 - b) * table[i + 1, j, n]
                           + (1 - a) * b * table[i, j + 1, n] + a * b * table[i + 1, j + 1, n])
        interval[r] = (half_shift + q * sigma) / math.sqrt(total)
