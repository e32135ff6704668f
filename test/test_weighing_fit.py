"""The weighing's least squares (monitoring.weighing_fit): its uncertainty against the exact variance
of the estimate, for errors white along the stroke, correlated, alternating, and from few strokes.

Oracle: synthetic strokes over K bins whose force-model rows are fixed and whose bins' errors in
each stroke are a stationary AR(2) process along the bins (a bounce moving neighbouring bins
together: positive coefficients; in turn: negative) plus the declared noise, independent from
stroke to stroke; each stroke's bins carry a seal friction of +3 % lifting and −3 % lowering.
With equal counts the fit is θ = G·ȳ (G its gain, the priors negligible) and a pair's mean error
is the mean of C lifting and C lowering strokes' errors, so the exact variance of W is
g0ᵀ·Σ·g0 / (2C) with Σ the process's covariance along the bins (from its impulse response).
A u too large (an interval that covers too often) fails as surely as one too small.
"""

from __future__ import annotations

import numpy as np
import pytest

from linkage_monitor.monitoring.weighing_fit import SUMS, UNITS, Priors, SensorErrors, fit, student_factor

K = 20            # pairs of stroke bins (the benchmark's runs pair 18-19)
SAMPLES = 40      # steps per bin and stroke
THETA = np.array([12_000.0, -600.0, 300.0])   # N, N·m, N·m: W, W·dx, W·dz
SIGMA = 60.0      # N, the innovation of a stroke's bin errors (a bounce's)
NOISE = 250.0     # N, the declared noise per reading (40 N on a stroke's bin)
BURN = 60         # bins of the process run before the stroke: stationary


def _rows() -> np.ndarray:
    """Smooth force-model columns over the stroke (u0 near 1, ux and uz slowly varying), (K, 3)."""
    s = np.linspace(0.0, 1.0, K)
    return np.column_stack([1.0 + 0.3 * s, 0.2 + 0.5 * s - 0.2 * s**2, 0.1 * np.sin(2.0 * s)])


def _process_covariance(ar: tuple[float, float], sigma: float) -> np.ndarray:
    """The stationary AR(2) process's covariance along K bins (N²), from its impulse response."""
    impulse = np.zeros(K + 400)
    impulse[0] = 1.0
    for k in range(1, impulse.size):
        impulse[k] = ar[0] * impulse[k - 1] + (ar[1] * impulse[k - 2] if k >= 2 else 0.0)
    autocovariance = [sigma**2 * float(impulse[:impulse.size - h] @ impulse[h:]) for h in range(K)]
    lag = np.abs(np.subtract.outer(np.arange(K), np.arange(K)))
    return np.asarray(autocovariance)[lag]


def _stroke_errors(rng: np.random.Generator, ar: tuple[float, float], sigma: float) -> np.ndarray:
    x = np.zeros(BURN + K)
    for k in range(2, x.size):
        x[k] = ar[0] * x[k - 1] + ar[1] * x[k - 2] + rng.normal(0.0, sigma)
    return x[BURN:] + rng.normal(0.0, NOISE / np.sqrt(SAMPLES), K)


def _draw(rng: np.random.Generator, rows: np.ndarray, cycles: int, ar: tuple[float, float], sigma: float,
          gain: float = 0.0, offset: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """The bins' sums (K, 2, SUMS) of ``cycles`` lifts and lowers and their groups (UNITS, K, 2, SUMS),
    the force read with a calibration error common to all strokes (``gain`` -, ``offset`` N)."""
    units = np.zeros((UNITS, K, 2, len(SUMS)))
    for c in range(cycles):
        for d, sign in enumerate((1.0, -1.0)):
            y = (1.0 + gain) * (rows @ THETA + _stroke_errors(rng, ar, sigma)) * (1.0 + sign * 0.03) + offset
            stroke = np.column_stack([np.full(K, SAMPLES), SAMPLES * rows, SAMPLES * y, SAMPLES * y**2, SAMPLES * y])
            units[c % UNITS, :, d] += stroke
    return units.sum(axis=0), units


@pytest.mark.parametrize(("ar", "cycles", "sigma", "most"), [
    ((0.0, 0.0), 5, SIGMA, 0.975),     # white along the stroke
    ((0.6, 0.0), 5, SIGMA, 0.975),     # neighbouring bins together (smooth: the fit's residuals hide it)
    ((-0.5, 0.0), 5, SIGMA, 0.975),    # in turn
    ((-0.3, -0.5), 5, SIGMA, 0.975),   # a bounce of about three bins' period
    ((0.6, 0.0), 12, SIGMA, 0.975),    # more strokes than groups: several strokes a group
    ((0.0, 0.0), 2, SIGMA, 0.975),     # two lifts and two lowers: a jackknife of one degree of freedom each
    ((0.0, 0.0), 1, SIGMA, 0.975),     # one lift and one lower: the rows' scatter, white
    ((0.0, 0.0), 5, 0.0, 0.985),  # the declared noise alone: u kept at least the declared (+17 % in u²)
])
def test_the_weight_s_uncertainty_matches_its_exact_variance(ar, cycles, sigma, most):
    rows = _rows()
    rng = np.random.default_rng(49)
    gain = np.linalg.pinv(rows)
    exact = ((gain @ _process_covariance(ar, sigma) @ gain.T)[0, 0]
             + NOISE**2 / SAMPLES * (gain @ gain.T)[0, 0]) / (2 * cycles)
    errors = SensorErrors(noise=NOISE, gain=0.0, offset=0.0)
    variances, covered = [], []
    for _ in range(400):
        sums, units = _draw(rng, rows, cycles, ar, sigma)
        result = fit(sums, errors, Priors(x=1e3, z=1e3), min_samples=1, units=units)
        assert result is not None and result.pairs == K
        weight = result.spread(np.array([1.0, 0.0, 0.0]))
        variances.append(weight.variance)
        u = np.sqrt(weight.variance) * student_factor(weight.dof)
        covered.append(abs(result.theta[0] - THETA[0]) <= 1.96 * u)
    # the mean of u² over 400 draws against the exact variance: ±20 % (the draws' own spread: a
    # jackknife over 2 × 5 groups has about 8 degrees of freedom, ±2.5 % on the mean of 400)
    assert 0.8 <= np.mean(variances) / exact <= 1.2, (np.mean(variances) / exact, ar, cycles)
    # the Student-widened 95 % interval: 400 draws give a coverage to ±1.1 % (1 σ)
    assert 0.925 <= np.mean(covered) <= most, (np.mean(covered), ar, cycles)


GAIN, OFFSET = 0.02, 40.0   # the declared calibration (1 σ; -, N): the weight's error mostly a gain's


@pytest.mark.parametrize(("ar", "cycles"), [((0.0, 0.0), 5), ((0.6, 0.0), 3)])
def test_each_quantity_takes_its_own_degrees_of_freedom(ar, cycles):
    """A calibration drawn once per draw from its declared σ: it dominates the weight's variance
    (exact, many degrees of freedom) but a gain scales W·dx with W and leaves the cg's offset
    dx = θ1/θ0 to the strokes' scatter and the jackknife's few degrees of freedom. Widened by the
    weight's, dx's interval would cover about 91 % (5 cycles: t(0.975, 8) = 2.31 against 1.96)."""
    rows = _rows()
    rng = np.random.default_rng(51)
    gain = np.linalg.pinv(rows)
    scatter = (gain @ _process_covariance(ar, SIGMA) @ gain.T + NOISE**2 / SAMPLES * gain @ gain.T) / (2 * cycles)
    ones = gain.sum(axis=1)
    exact_weight = scatter[0, 0] + (GAIN * THETA[0]) ** 2 + (OFFSET * ones[0]) ** 2
    jac = np.array([-THETA[1] / THETA[0] ** 2, 1.0 / THETA[0], 0.0])   # dx = θ1/θ0 at the truth
    exact_dx = float(jac @ scatter @ jac + (OFFSET * jac @ ones) ** 2)   # a gain leaves dx as it is
    errors = SensorErrors(noise=NOISE, gain=GAIN, offset=OFFSET)
    found: dict[str, list[tuple[float, bool]]] = {"weight": [], "dx": []}
    for _ in range(400):
        sums, units = _draw(rng, rows, cycles, ar, SIGMA, rng.normal(0.0, GAIN), rng.normal(0.0, OFFSET))
        result = fit(sums, errors, Priors(x=1e3, z=1e3), min_samples=1, units=units)
        assert result is not None
        theta = result.theta
        at = np.array([-theta[1] / theta[0] ** 2, 1.0 / theta[0], 0.0])
        for name, spread, error in (("weight", result.spread(np.array([1.0, 0.0, 0.0])), theta[0] - THETA[0]),
                                    ("dx", result.spread(at), theta[1] / theta[0] - THETA[1] / THETA[0])):
            u = np.sqrt(spread.variance) * student_factor(spread.dof)
            found[name].append((spread.variance, abs(error) <= 1.96 * u))
    for name, exact in (("weight", exact_weight), ("dx", exact_dx)):
        variances, covered = (np.array(v) for v in zip(*found[name]))
        assert 0.8 <= np.mean(variances) / exact <= 1.2, (name, np.mean(variances) / exact, ar, cycles)
        assert 0.925 <= np.mean(covered) <= 0.975, (name, np.mean(covered), ar, cycles)


@pytest.mark.parametrize("support", [0.0, 0.4, 0.02])
def test_the_contact_zone_s_bins_are_taken_only_where_the_ground_carries_nothing(support):
    """The last 3 bins are the contact zone (from its edge toward the working position); the ground
    carries ``support`` of the load in the last 2 of them. Without support the 3 are taken; with 40 %
    (the simulator's) or 2 % (about 9 σ of a bin's declared noise here) only the one left free."""
    rows = _rows()
    sums, units = _draw(np.random.default_rng(7), rows, 5, (0.0, 0.0), 0.0)
    carried = np.zeros(K)
    carried[-2:] = support
    for data in (sums[None], units):   # y, y² and the force as the ground leaves them (in place)
        data[..., :, :, 4:] *= (1.0 - carried)[:, None, None] ** np.array([1.0, 2.0, 1.0])
    contact = np.array([K - 3, K - 2, K - 1])
    errors = SensorErrors(noise=NOISE, gain=0.0, offset=0.0)
    free = fit(sums, errors, Priors(), 3, units, contact)
    without = fit(sums, errors, Priors(), 3, units, contact[:0])
    assert free is not None and without is not None
    assert free.pairs == (K if support == 0.0 else K - 2)
    assert abs(free.theta[0] - THETA[0]) <= 1.96 * np.sqrt(free.floor[0, 0])
    if support:   # the grounded bins taken would bias the weight by several σ
        assert abs(without.theta[0] - THETA[0]) > 3.0 * np.sqrt(without.floor[0, 0])
