"""The 95 % coverage factor of a budget's shape (mechanics/coverage_factor.py) against a Monte Carlo of
the declared distributions: normal terms (a sensor's bias and noise), uniform ones over ±√3·|c| (a
quantization step, a standing seal's friction) and, one-sided, over 0 to √3·c with the motion's sign (a
moving seal's friction).

The oracle draws 400,000 errors per budget, the terms independent, each of its contribution c: the
standard error of a coverage near 95 % is 0.03 %. The factor's table is exact for equal uniform terms
(checked against the closed forms: 1.96 for the normal, 0.95·√3 for one uniform); for unequal ones the
equal-terms model of the same kurtosis is an approximation, held here to 1 % of coverage (its error
over these budgets is at most about 0.6 %). With a one-sided term the interval (value ± k·u, symmetric)
holds 95 % of the error in all, and a verdict's bound (``Factors.tail``) leaves neither tail above 2.5 %
(a verdict on either bound errs on the safe side).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from linkage_monitor.mechanics.coverage_factor import (NORMAL_FACTOR, coverage_factors, exact_factor, factor_table,
                                                       shifted_factors)

pytestmark = pytest.mark.filterwarnings("error")
DRAWS = 400_000


def _errors(rng: np.random.Generator, c: np.ndarray, uniform: np.ndarray, sign: np.ndarray) -> np.ndarray:
    """DRAWS errors of the budget whose contributions are c (n_src,)."""
    total = np.zeros(DRAWS)
    for ci, flat, s in zip(c, uniform, sign):
        if not flat:
            total += ci * rng.standard_normal(DRAWS)
        elif s == 0.0:
            total += math.sqrt(3.0) * ci * rng.uniform(-1.0, 1.0, DRAWS)
        else:
            total += s * math.sqrt(3.0) * ci * rng.uniform(0.0, 1.0, DRAWS)
    return total


def test_the_closed_forms() -> None:
    assert exact_factor(0.0, 1) == NORMAL_FACTOR
    assert exact_factor(1.0, 1) == pytest.approx(0.95 * math.sqrt(3.0), abs=1e-6)   # one uniform: 1.645
    # two equal uniforms: their sum is triangular on ±2a (a = √1.5), P(|X| ≤ t) = 1 − (2a − t)²/(4a²)
    a = math.sqrt(1.5)
    assert exact_factor(1.0, 2) == pytest.approx(2 * a - math.sqrt(0.05 * 4 * a * a), abs=1e-6)
    factors = coverage_factors(np.array([[1.0, 0.0], [0.0, 2.0], [0.0, 0.0]]), np.array([False, True]), np.zeros(2))
    k = factors.interval
    assert k[0] == pytest.approx(NORMAL_FACTOR) and k[1] == pytest.approx(0.95 * math.sqrt(3.0), abs=1e-6)
    assert k[2] == NORMAL_FACTOR   # u = 0: no shape
    np.testing.assert_array_equal(factors.tail, k)   # no source of known sign: one factor
    # a moving seal's friction alone: the error uniform on 0..√3·c; 95 % of it within 0.95·√3·c, and its
    # upper 2.5 % tail beyond √3·c/2 + 0.95·√3·(c/2) (the rest about the shift, uniform ±√3·c/2)
    alone = coverage_factors(np.array([[2.0]]), np.array([True]), np.array([1.0]))
    assert alone.interval[0] == pytest.approx(0.95 * math.sqrt(3.0), abs=2e-3)
    assert alone.tail[0] == pytest.approx(0.5 * math.sqrt(3.0) + 0.95 * math.sqrt(3.0) / 2, abs=1e-6)


@pytest.mark.parametrize("seed", range(12))
def test_the_factor_covers_95_percent_of_the_declared_distributions(seed: int) -> None:
    rng = np.random.default_rng(seed)
    n_normal, n_uniform = int(rng.integers(0, 4)), int(rng.integers(1, 5))
    c = np.concatenate([rng.exponential(1.0, n_normal) * rng.uniform(0.0, 1.0), rng.exponential(1.0, n_uniform)])
    uniform = np.array([False] * n_normal + [True] * n_uniform)
    sign = np.zeros(c.size)
    k = coverage_factors(c[None], uniform, sign).interval[0]
    covered = np.mean(np.abs(_errors(rng, c, uniform, sign)) <= k * math.sqrt(np.sum(c**2)))
    assert covered == pytest.approx(0.95, abs=0.01)


@pytest.mark.parametrize("seed", range(8))
def test_with_a_moving_seal_the_interval_holds_95_percent_and_a_verdicts_bound_leaves_either_tail_2_5(seed: int
                                                                                                      ) -> None:
    rng = np.random.default_rng(100 + seed)
    c = np.array([rng.uniform(0.05, 0.6), rng.uniform(0.0, 0.8), rng.uniform(-1.0, 1.0)])
    uniform, sign = np.array([False, True, True]), np.array([0.0, 0.0, rng.choice([-1.0, 1.0])])
    factors = coverage_factors(c[None], uniform, sign)
    u = math.sqrt(np.sum(c**2))
    errors = _errors(rng, c, uniform, sign)
    assert np.mean(np.abs(errors) <= factors.interval[0] * u) == pytest.approx(0.95, abs=0.01)
    bound = factors.tail[0] * u
    assert np.mean(errors > bound) <= 0.025 + 0.003
    assert np.mean(errors < -bound) <= 0.025 + 0.003
    assert factors.tail[0] >= factors.interval[0]


def test_the_shifted_factors_table_is_its_fine_grids_within_a_thousandth() -> None:
    """The table's q over the shift, from the distribution function on a coarse grid (for its cost, once per
    process), against the same on a grid ten times finer: within the 1e-3 its comment states."""
    table = factor_table()
    for i, j in ((0, 0), (4, 6), (10, 6), (19, 6), (20, 6), (10, 3), (20, 1)):
        share, inverse = float(table.shares[i]), table.inverse_counts[j]
        q = shifted_factors(share, 0 if inverse == 0.0 else round(1.0 / inverse), float(table.factors[i, j, 0]),
                            np.linspace(0.0, 12.0, 2401), 801)
        np.testing.assert_allclose(table.factors[i, j], q, atol=1e-3)


def test_an_unbounded_output_has_no_factor() -> None:
    factors = coverage_factors(np.array([[np.nan, 1.0]]), np.array([False, True]), np.zeros(2))
    assert np.isnan(factors.interval[0]) and np.isnan(factors.tail[0])
