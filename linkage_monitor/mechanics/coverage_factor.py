"""The 95 % coverage factor of an output from the shape of its error budget (GUM Supplement 1's
propagation of distributions, for the two shapes the declared sources have).

An output's error is a sum of independent terms, each a source's contribution c (the output's unit,
``budget.Budget.contributions``): a normal one for a sensor's bias and noise and the implement's
mass, a uniform one over ±√3·|c| for a quantization step and a standing seal's friction, and over 0 to
±√3·c for a moving seal's friction, whose sign the motion gives (``Source.uniform``, ``coverage_factors``). The
95 % interval is value ± k·u, k the 95 % quantile of |error| / u. For normal terms alone k = 1.96;
a uniform term alone, 0.95·√3 = 1.645; a mix lies between.

k is read from a table in two numbers of the budget: the uniform terms' share of u², w = Σ c_j² / u²,
and their effective count n = (Σ c_j²)² / Σ c_j⁴ (1 for one uniform term or one dominant one; the
count for equal ones), the terms taken as n equal uniforms beside a normal of variance (1 − w)·u².
The table (``factor_table``) is exact for that model: P(|N + S| ≤ t) with S the Irwin–Hall sum of n
uniforms, from its density on a fine grid, solved for t by bisection, once per process. Between
its rows k is interpolated bilinearly in w and 1/n (n → ∞: the normal's 1.96).
test/test_coverage_factor.py holds k to a Monte Carlo of the declared distributions within 0.5 %
of coverage for budgets of unequal terms (the equal-terms model's error, kurtosis matched).
"""

from __future__ import annotations

import math
from functools import cache
from typing import NamedTuple

import numpy as np

from . import kernels

COVERAGE = 0.95
NORMAL_FACTOR = 1.959963984540054   # the normal's 95 % coverage factor (its 0.975 quantile)
_SHARES = np.linspace(0.0, 1.0, 21)                                   # w: the uniform terms' share of u²
_INVERSE_COUNTS = np.array([0.0, 1 / 8, 1 / 6, 1 / 4, 1 / 3, 1 / 2, 1.0])   # 1/n (0: the normal)
_GRID = 801   # points of a sum of uniforms' density


def _irwin_hall(n: int, x: np.ndarray) -> np.ndarray:
    """The density of the sum of n independent uniforms on [0, 1] at x."""
    total = np.zeros_like(x)
    for k in range(n + 1):
        total += (-1) ** k * math.comb(n, k) * np.where(x > k, np.maximum(x - k, 0.0) ** (n - 1), 0.0)
    return np.where((x >= 0.0) & (x <= n), total / math.factorial(n - 1), 0.0)


def _cumulative_irwin_hall(n: int, x: np.ndarray) -> np.ndarray:
    """The distribution function of the sum of n independent uniforms on [0, 1] at x."""
    total = np.zeros_like(x)
    for k in range(n + 1):
        total += (-1) ** k * math.comb(n, k) * np.where(x > k, x - k, 0.0) ** n
    return np.clip(total / math.factorial(n), 0.0, 1.0)


def exact_factor(share: float, count: int) -> float:
    """k with P(|X| ≤ k) = COVERAGE for X = normal of variance 1 − ``share`` plus ``count`` equal
    uniforms of total variance ``share`` (unit variance in all)."""
    if count == 0 or share <= 0.0:
        return NORMAL_FACTOR
    half = math.sqrt(3.0 * share / count)   # each uniform on ±half
    sigma = math.sqrt(max(1.0 - share, 0.0))
    if sigma < 1e-9:   # uniforms alone: the Irwin–Hall distribution function, rescaled to ±count·half
        def inside(t: float) -> float:
            ends = (np.array([-t, t]) / half + count) / 2.0
            low, high = _cumulative_irwin_hall(count, ends)
            return float(high - low)
    else:
        from scipy.special import ndtr   # here: the monitor without error budgets never needs it (~0.1 s to import)

        x = (np.arange(_GRID) + 0.5) / _GRID * count   # midpoints over [0, count]
        weight = _irwin_hall(count, x) * (count / _GRID)
        weight /= weight.sum()
        s = half * (2.0 * x - count)

        def inside(t: float) -> float:
            return float(np.sum(weight * (ndtr((t - s) / sigma) - ndtr((-t - s) / sigma))))
    low, high = 1.5, 2.0   # k of any such mix lies between the uniform's 1.645 and the normal's 1.96
    for _ in range(30):
        mid = 0.5 * (low + high)
        low, high = (mid, high) if inside(mid) < COVERAGE else (low, mid)
    return 0.5 * (low + high)


class FactorTable(NamedTuple):
    """k (len(shares), len(inverse_counts)) at each uniform share w (``shares``) and inverse count 1/n
    (``inverse_counts``; 1/n = 0: the normal), as ``kernels.coverage_factors`` takes them."""

    factors: np.ndarray
    shares: np.ndarray
    inverse_counts: np.ndarray


@cache
def factor_table() -> FactorTable:
    """The coverage factors' table (``FactorTable``), computed once per process."""
    table = np.empty((_SHARES.size, _INVERSE_COUNTS.size))
    for i, share in enumerate(_SHARES):
        for j, inverse in enumerate(_INVERSE_COUNTS):
            table[i, j] = NORMAL_FACTOR if inverse == 0.0 else exact_factor(float(share), round(1.0 / inverse))
    return FactorTable(table, _SHARES, _INVERSE_COUNTS)


def coverage_factors(contributions: np.ndarray, uniform: np.ndarray, sign: np.ndarray) -> np.ndarray:
    """The 95 % coverage factor (n_out,) of each output of a budget: ``contributions`` (n_out, n_src)
    each source's ∂y/∂s·u_s (the output's unit, signed), ``uniform`` (n_src,) bool, the sources uniform
    (the others normal), ``sign`` (n_src,): 0 for a uniform source over ±√3·u, +1 or −1 for one whose
    sign is known (a moving cylinder's seal friction: between 0 and ±√3·u, ``Motion``). NaN where a
    contribution is NaN (u unbounded); 1.96 where u is 0.

    A source of known sign leaves the output's error between 0 and d = sign·√3·c: a shift d/2 and a
    uniform ±|d|/2 about it. The factor is the symmetric bound's: k·u = |Σ d/2| + k_Y·u_Y, Y the error
    without the shifts (its normal and uniform terms, the table's k_Y), so that neither side's tail
    is above 2.5 % (a verdict on either bound errs on the safe side). With no source of known sign
    it is the 95 % quantile of |error| / u. The rows in one compiled call (``kernels.coverage_factors``)."""
    return kernels.coverage_factors(np.ascontiguousarray(contributions, dtype=np.float64), np.asarray(uniform, np.bool_),
                                    np.asarray(sign, np.float64), *factor_table(), NORMAL_FACTOR)
