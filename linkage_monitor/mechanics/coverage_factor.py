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

A moving seal's friction, of known sign, shifts the error by the mean of its one-sided term
(D = Σ √3·c/2 over such terms; its spread about that mean, uniform ±√3·c/2, is one of the terms
above, Y of standard deviation σ). The 95 % interval about the value is then value ± (|D| + q·σ), q
from F(q) + F(q + 2t) = 1.95 (F the distribution function of Y/σ, t = |D|/σ): 95 % of the error in
all, the tail on the shift's side up to 5 % (q = k at t = 0, falling to Y's one-sided 95 % quantile as
the shift grows); the table holds q over t too (``SHIFTS``), interpolated linearly in t. A verdict on
a bound judges each tail on its own, as a normal error's 95 % interval does, 2.5 % each: its factor
(``Factors.tail``) is (|D| + k·σ)/u, no tail of the declared distributions beyond it above 2.5 %
(the interval's, with a shift, holds 95 % with one tail up to 5 %; the bench's coverage counts both).
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
_SHARES = np.linspace(0.0, 1.0, 21)   # w: the uniform terms' share of u² (evenly spaced: the kernel reads it by index)
_INVERSE_COUNTS = np.array([0.0, 1 / 8, 1 / 6, 1 / 4, 1 / 3, 1 / 2, 1.0])   # 1/n (0: the normal)
_GRID = 801   # points of a sum of uniforms' density
# t = |D|/σ, the shift of a moving seal's friction over the spread of the rest: the grid's step (uniform, read
# by index) and its end; beyond it q is its last value (the far tail below 1e-7 there for every shape)
SHIFT_STEP, SHIFT_END = 0.125, 4.0
SHIFTS = np.arange(0.0, SHIFT_END + SHIFT_STEP / 2, SHIFT_STEP)
# where Y/σ's distribution function is tabulated for the shifts (beyond 7, 1 within 1e-11 for every shape), and
# the points of the uniforms' sum there: the linear interpolation between them errs by < 1e-3 in q
_SPREAD_POINTS = np.linspace(0.0, 7.0, 141)
_SPREAD_GRID = 101


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


def _mixture(share: float, count: int, grid: int = _GRID) -> tuple[np.ndarray, np.ndarray, float]:
    """Y = a normal of variance 1 − ``share`` plus ``count`` equal uniforms of total variance ``share``
    (unit variance in all) as the uniforms' sum on ``grid`` points, their weights and the normal's σ."""
    half = math.sqrt(3.0 * share / count)   # each uniform on ±half
    x = (np.arange(grid) + 0.5) / grid * count   # midpoints over [0, count]
    weight = _irwin_hall(count, x) * (count / grid)
    return half * (2.0 * x - count), weight / weight.sum(), math.sqrt(max(1.0 - share, 0.0))


def _distribution(share: float, count: int, x: np.ndarray, grid: int) -> np.ndarray:
    """P(Y ≤ x) for ``_mixture``'s Y on ``grid`` points (the normal's alone for count 0)."""
    from scipy.special import ndtr   # here: the monitor without error budgets never needs it (~0.1 s to import)

    if count == 0 or share <= 0.0:
        return ndtr(x)
    s, weight, sigma = _mixture(share, count, grid)
    if sigma < 1e-9:   # uniforms alone: the Irwin–Hall distribution function, rescaled to ±count·half
        half = math.sqrt(3.0 * share / count)
        return _cumulative_irwin_hall(count, (x / half + count) / 2.0)
    return np.sum(weight[None, :] * ndtr((x[:, None] - s[None, :]) / sigma), axis=1)


def exact_factor(share: float, count: int) -> float:
    """k with P(|X| ≤ k) = COVERAGE for X = normal of variance 1 − ``share`` plus ``count`` equal
    uniforms of total variance ``share`` (unit variance in all)."""
    if count == 0 or share <= 0.0:
        return NORMAL_FACTOR
    half = math.sqrt(3.0 * share / count)   # each uniform on ±half
    s, weight, sigma = _mixture(share, count)
    if sigma < 1e-9:   # uniforms alone: the Irwin–Hall distribution function, rescaled to ±count·half
        def inside(t: float) -> float:
            ends = (np.array([-t, t]) / half + count) / 2.0
            low, high = _cumulative_irwin_hall(count, ends)
            return float(high - low)
    else:
        from scipy.special import ndtr

        def inside(t: float) -> float:
            return float(np.sum(weight * (ndtr((t - s) / sigma) - ndtr((-t - s) / sigma))))
    low, high = 1.5, 2.0   # k of any such mix lies between the uniform's 1.645 and the normal's 1.96
    for _ in range(30):
        mid = 0.5 * (low + high)
        low, high = (mid, high) if inside(mid) < COVERAGE else (low, mid)
    return 0.5 * (low + high)


def shifted_factors(share: float, count: int, k: float, points: np.ndarray = _SPREAD_POINTS,
                    grid: int = _SPREAD_GRID) -> np.ndarray:
    """q (len(SHIFTS),) at each shift t of SHIFTS: F(q) + F(q + 2t) = 1 + COVERAGE, F the distribution
    function of ``_mixture``'s Y (of k = ``exact_factor(share, count)``, q's value at t = 0; the uniforms'
    sum on ``grid`` points), by bisection over F tabulated at ``points`` (linear between them)."""
    table = _distribution(share, count, points, grid)
    q = np.empty(SHIFTS.size)
    q[0] = k
    low, high = np.zeros(SHIFTS.size - 1), np.full(SHIFTS.size - 1, k)
    for _ in range(40):
        mid = 0.5 * (low + high)
        inside = np.interp(mid, points, table) + np.interp(mid + 2.0 * SHIFTS[1:], points, table)
        below = inside < 1.0 + COVERAGE
        low, high = np.where(below, mid, low), np.where(below, high, mid)
    q[1:] = 0.5 * (low + high)
    return q


class FactorTable(NamedTuple):
    """q (len(shares), len(inverse_counts), len(SHIFTS)) at each uniform share w (``shares``), inverse
    count 1/n (``inverse_counts``; 1/n = 0: the normal) and shift t (SHIFTS, step ``shift_step``): at
    t = 0 the factor k of the shape, as ``kernels.coverage_factors`` takes them."""

    factors: np.ndarray
    shares: np.ndarray
    inverse_counts: np.ndarray
    shift_step: float


class Factors(NamedTuple):
    """The coverage factors (n_out,) of a budget's outputs: ``interval``, of its 95 % interval (value ±
    k·u, 95 % of the declared error within); ``tail``, of a verdict's bound (no tail beyond ±k·u above
    2.5 %). The same where no moving seal's friction enters."""

    interval: np.ndarray
    tail: np.ndarray


@cache
def factor_table() -> FactorTable:
    """The coverage factors' table (``FactorTable``), computed once per process."""
    table = np.empty((_SHARES.size, _INVERSE_COUNTS.size, SHIFTS.size))
    for i, share in enumerate(_SHARES):
        for j, inverse in enumerate(_INVERSE_COUNTS):
            count = 0 if inverse == 0.0 else round(1.0 / inverse)
            k = NORMAL_FACTOR if count == 0 else exact_factor(float(share), count)
            table[i, j] = shifted_factors(float(share), count, k)
    return FactorTable(table, _SHARES, _INVERSE_COUNTS, SHIFT_STEP)


def coverage_factors(contributions: np.ndarray, uniform: np.ndarray, sign: np.ndarray) -> Factors:
    """The 95 % coverage factors (``Factors``, each (n_out,)) of each output of a budget: ``contributions``
    (n_out, n_src) each source's ∂y/∂s·u_s (the output's unit, signed), ``uniform`` (n_src,) bool, the
    sources uniform (the others normal), ``sign`` (n_src,): 0 for a uniform source over ±√3·u, +1 or −1
    for one whose sign is known (a moving cylinder's seal friction: between 0 and ±√3·u, ``Motion``).
    NaN where a contribution is NaN (u unbounded); 1.96 where u is 0.

    A source of known sign leaves the output's error between 0 and d = sign·√3·c: a shift d/2 and a
    uniform ±|d|/2 about it. The interval's factor: k·u = |Σ d/2| + q·u_Y, Y the error without the
    shifts (its normal and uniform terms), q the table's at t = |Σ d/2|/u_Y, 95 % of the error within;
    the tail's: k·u = |Σ d/2| + k_Y·u_Y (k_Y the table's at t = 0), neither side's tail above 2.5 % (a
    verdict on either bound errs on the safe side). With no source of known sign both are the 95 %
    quantile of |error| / u. The rows in one compiled call (``kernels.coverage_factors``)."""
    interval, tail = (np.empty(contributions.shape[0]) for _ in range(2))
    kernels.coverage_factors(np.ascontiguousarray(contributions, dtype=np.float64), np.asarray(uniform, np.bool_),
                             np.asarray(sign, np.float64), *factor_table(), NORMAL_FACTOR, interval, tail)
    return Factors(interval, tail)
