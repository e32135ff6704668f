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
                     shares: np.ndarray, inverse_counts: np.ndarray, normal_factor: float) -> np.ndarray:
    """The coverage factor (n_out,) of each row of ``contributions`` (n_out, n_src; the output's unit,
    signed): ``uniform`` (n_src,) the uniform sources, ``sign`` (n_src,) 0 or the known sign of a
    uniform one, ``table`` (len(shares), len(inverse_counts)) k at each uniform share w and inverse
    effective count 1/n. As ``coverage_factor.coverage_factors`` states it: NaN where u² is not
    finite, ``normal_factor`` where it is 0."""
    n_out, n_src = contributions.shape
    out = np.empty(n_out)
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
            out[r] = math.nan
            continue
        if total <= 0.0:
            out[r] = normal_factor
            continue
        spread = normal + flat
        share = flat / spread if spread > 0.0 else 0.0
        inverse = flat_squares / flat**2 if flat > 0.0 else 0.0
        i, a = _cell(shares, share)
        j, b = _cell(inverse_counts, inverse)
        k = ((1 - a) * (1 - b) * table[i, j] + a * (1 - b) * table[i + 1, j] + (1 - a) * b * table[i, j + 1]
             + a * b * table[i + 1, j + 1])
        out[r] = (0.5 * math.sqrt(3.0) * abs(shift) + k * math.sqrt(spread)) / math.sqrt(total)
    return out
