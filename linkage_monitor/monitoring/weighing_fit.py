"""The weighing's least squares: lift/lower pairs of stroke bins -> weight and cg, with uncertainty.

A bin of the lift cylinder's stroke collects, per direction of motion, the sums of the force
model's columns (u0, ux, uz; ``weighing_model``), of the load's share of the measured force
y = F − F_link, of y² and of F. Seal friction adds +f to y while lifting and −f while lowering
(Bosch DE4328143), so the mean of a bin's lifting and lowering means cancels it where the seal
friction is the same both ways at that pose; a bin with both directions is a *pair*, one row
of the fit

    ȳ_k = W·ū0_k + (W·dx)·ūx_k + (W·dz)·ūz_k

over the pairs k (the unknowns θ = (W, W·dx, W·dz): linear). dx and dz are the cg's offset from
the file's cg in the implement's frame (m, reference pose); each has a Gaussian prior around
the file's cg (``Priors``), so that what the stroke does not identify (dz where the implement
hardly turns, everything from one pair) stays at the file's value with its prior uncertainty
instead of making the system singular.

Near the working position the ground may carry part of the load, lowering a bin's lifting and
lowering force alike (the pair's mean shows it). The bins reaching into that zone are taken one
by one from its edge toward the working position while each one's pair agrees with the fit of
the bins taken so far (``CONTACT_AGREEMENT`` σ): the stroke the fit sees is longer where the
implement leaves the ground early, which separates the weight from the cg's x (their columns are
nearly proportional over a short stroke).

The uncertainty: a bin's error is not independent of its neighbours' (a bounce during a stroke
moves the loads of the bins the rod crosses meanwhile, in turn or together), and the weight's
variance is the sum of those correlations weighted by the fit's smooth gain, which the
residuals of one fit cannot estimate (their long-range part is what the fit absorbs). The
strokes are what is independent: each lift and each lower meets its own bounce and noise. The
estimator keeps its strokes' sums in groups (``UNITS`` per direction, a stroke to each in turn)
and the fit's covariance is the jackknife over them, stratified by direction (Quenouille 1956,
Efron & Stein 1981: each group left out in turn; a direction's friction stays cancelled, as the
pair's mean takes each direction's mean), with its degrees of freedom (Satterthwaite 1946) for
the Student widening; never below what the declared pressure noise gives. With fewer than two
groups in a direction the rows' own scatter stands in (the residuals scaled by the degrees of
freedom left, taken white: right for a noise white along the stroke, not for a bounce that
moves neighbouring bins together, so that an estimate from one lift and one lower says so by its
few degrees of freedom). The sensors' calibration (a gain and an offset of the pressure,
``SensorErrors``) is common to all rows: it is propagated through the fit's gain matrix and
added as declared (exact). Each quantity (the weight, a cg offset) takes its degrees of freedom
from its own parts (``Fit.spread``): the calibration dominates the weight's variance and lends it
many, while a gain error scales W·dx with W and leaves the cg's offset to the strokes' scatter and
its few. Units SI.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

CONTACT_AGREEMENT = 3.0   # σ within which a contact-zone bin's pair must agree with the fit to be taken
UNITS = 8   # groups of strokes per direction that the jackknife leaves out in turn
SUMS = ("n", "u0", "ux", "uz", "y", "yy", "force")   # the columns of a bin's sums, in this order
N, U0, UX, UZ, Y, YY, FORCE = range(len(SUMS))


# The fit's records (declared errors, priors, a part of the covariance, a quantity's spread, the
# fit): fields of their own data, alike in form only to sim.work_cycle's records (the simulated
# truth), sim.road's and mechanics.model's joints and mounts.
@dataclass(frozen=True)
class SensorErrors:
    """The pressure measurement's declared errors (1 σ), as force on the lift cylinder: noise per
    reading (N), gain (relative, -), offset (N)."""

    noise: float
    gain: float
    offset: float


@dataclass(frozen=True)
class Priors:
    """The cg's prior standard deviations around the file's cg (m): along the implement's x and z."""

    x: float = 0.5
    z: float = 0.3


@dataclass(frozen=True)
class Part:
    """A share of θ's covariance estimated from the data (N², N²·m, N²·m²; (3, 3)) and its degrees of freedom."""

    covariance: np.ndarray
    dof: float


@dataclass(frozen=True)
class Spread:
    """A quantity's variance (its unit²) and the degrees of freedom it is known to (∞: declared alone)."""

    variance: float
    dof: float


@dataclass(frozen=True)
class Fit:
    """θ = (W N, W·dx N·m, W·dz N·m) and its covariance (3, 3) in parts: the ``parts`` estimated from
    the data (the jackknife's per direction, or the rows' scatter) plus the priors' share
    (``estimated``, their sum and the prior's), the ``floor`` the declared pressure noise gives,
    the sensors' ``calibration``; the pairs used, the rows' RMS residual (N), the mean friction share
    (half the lifting-lowering difference over the mean, -)."""

    theta: np.ndarray
    parts: tuple[Part, ...]
    estimated: np.ndarray
    floor: np.ndarray
    calibration: np.ndarray
    pairs: int
    scatter: float
    friction_share: float

    def spread(self, jacobian: np.ndarray) -> Spread:
        """The variance of the linear combination ``jacobian``·θ and its degrees of freedom: the
        estimated parts never below the declared noise's (known to as many more degrees of
        freedom as the floor is above them), plus the calibration (declared: no degrees of
        freedom lost), combined by Satterthwaite (1946). Each quantity takes its own: the
        calibration that dominates the weight's variance scales W·dx with W and leaves the cg's
        offset almost all to the strokes' scatter and its few degrees of freedom."""
        j = np.asarray(jacobian, dtype=float)
        random = max(float(j @ self.estimated @ j), float(j @ self.floor @ j))
        variance = random + float(j @ self.calibration @ j)
        denominator = sum(float(j @ p.covariance @ j) ** 2 / p.dof for p in self.parts)
        return Spread(variance, variance**2 / denominator if denominator > 0.0 else math.inf)


def student_factor(dof: float) -> float:
    """t(0.975, dof)/1.96: how much wider a 95 % interval is when σ comes from ``dof`` degrees of
    freedom (Student's t quantile; 1 for dof = ∞, ∞ for dof ≤ 0)."""
    if dof <= 0.0:
        return math.inf
    if math.isinf(dof):
        return 1.0
    from scipy.special import stdtrit   # here: a monitor that weighs nothing never needs it (~0.2 s to import)
    return float(stdtrit(dof, 0.975)) / 1.959963984540054


@dataclass(frozen=True)
class _Solution:
    """One least squares: θ, the posterior covariance from the declared noise and the priors
    (inverse), the gain (3, K) of θ per newton of each row, the rows (K, 3), their y and mean
    force (K,), residuals (K,), declared variances (K,), the lifting-lowering half gap (K,)."""

    theta: np.ndarray
    inverse: np.ndarray
    prior: np.ndarray
    gain: np.ndarray
    rows: np.ndarray
    y: np.ndarray
    force: np.ndarray
    residual: np.ndarray
    noise_var: np.ndarray
    half_gap: np.ndarray


def _solve(sums: np.ndarray, errors: SensorErrors, priors: Priors, min_samples: int) -> _Solution | None:
    counts = sums[:, :, N]
    paired = np.flatnonzero((counts[:, 0] >= min_samples) & (counts[:, 1] >= min_samples))
    if paired.size == 0:
        return None
    means = sums[paired] / counts[paired][:, :, None]                 # (K, 2, SUMS)
    rows = 0.5 * (means[:, 0, U0:UZ + 1] + means[:, 1, U0:UZ + 1])    # (K, 3)
    y = 0.5 * (means[:, 0, Y] + means[:, 1, Y])
    n_eff = 4.0 / (1.0 / counts[paired, 0] + 1.0 / counts[paired, 1])   # a pair mean's variance: σ²/n_eff
    weight0 = float(rows[:, 0] @ y / (rows[:, 0] @ rows[:, 0]))
    prior = np.diag([0.0, 1.0 / (weight0 * priors.x) ** 2, 1.0 / (weight0 * priors.z) ** 2])
    noise_var = errors.noise**2 / n_eff                                # per row, from the declared noise
    w = 1.0 / noise_var
    inverse = np.linalg.inv(rows.T @ (rows * w[:, None]) + prior)
    gain = inverse @ (rows.T * w)
    theta = gain @ y
    return _Solution(theta=theta, inverse=inverse, prior=prior, gain=gain, rows=rows, y=y,
                     force=0.5 * (means[:, 0, FORCE] + means[:, 1, FORCE]), residual=y - rows @ theta,
                     noise_var=noise_var, half_gap=0.5 * (means[:, 0, Y] - means[:, 1, Y]))


def fit(sums: np.ndarray, errors: SensorErrors, priors: Priors, min_samples: int,
        units: np.ndarray | None = None, contact: np.ndarray = np.zeros(0, dtype=int),
        judge_contact: bool = True) -> Fit | None:
    """The fit over the paired bins of ``sums`` (bins, 2 directions, len(SUMS)); None without a pair.
    ``units`` (groups, bins, 2, len(SUMS)): the strokes' sums in independent groups, whose total is
    ``sums``, for the jackknife; without them (or fewer than two groups a direction) the rows' scatter.
    ``contact``: the bins where the ground may carry part of the load, from the zone's edge toward the
    working position (``_free_of_ground``: taken while their pair agrees with the fit of the others;
    none without ``judge_contact``)."""
    usable = _free_of_ground(sums, errors, priors, min_samples, contact, judge_contact)
    if usable is None:
        return None
    if not usable.all():
        sums = sums * usable[:, None, None]
        units = units * usable[None, :, None, None] if units is not None else None
    solution = _solve(sums, errors, priors, min_samples)
    if solution is None:
        return None
    s = solution
    parts = _jackknife(s, sums, units, errors, priors, min_samples) if units is not None else None
    if parts is None:
        parts = _scatter(s)
    calibration = (np.outer(s.gain @ s.force, s.gain @ s.force) * errors.gain**2
                   + np.outer(s.gain.sum(axis=1), s.gain.sum(axis=1)) * errors.offset**2)
    mean_y = float(np.mean(s.y))
    return Fit(theta=s.theta, parts=parts, estimated=s.inverse @ s.prior @ s.inverse + sum(p.covariance for p in parts),
               floor=s.inverse, calibration=calibration, pairs=int(s.y.size),
               scatter=float(math.sqrt(np.mean(s.residual**2))),
               friction_share=float(np.mean(s.half_gap)) / mean_y if mean_y != 0.0 else math.nan)


def _free_of_ground(sums: np.ndarray, errors: SensorErrors, priors: Priors, min_samples: int,
                    contact: np.ndarray, judge: bool) -> np.ndarray | None:
    """The bins to fit (bins,) bool: all but the ``contact`` bins, then these in their order (from the
    zone's edge toward the working position) while each one's pair mean lies within
    ``CONTACT_AGREEMENT`` standard deviations of the fit of the bins taken so far (its declared
    noise's, or the rows' scatter where larger, and the prediction's): a ground that carries part of
    the load lowers both directions' force alike, which the pair's mean shows and the friction's
    cancellation does not hide; none of them without ``judge``. None without a pair outside the zone."""
    usable = np.ones(sums.shape[0], dtype=bool)
    usable[contact] = False
    s = _solve(sums * usable[:, None, None], errors, priors, min_samples)
    if s is None:
        return None
    if not judge:
        return usable
    counts = sums[:, :, N]
    scatter = float(np.mean(s.residual**2))
    for k in contact.tolist():
        if counts[k, 0] < min_samples or counts[k, 1] < min_samples:
            break
        means = sums[k] / counts[k][:, None]
        row = 0.5 * (means[0, U0:UZ + 1] + means[1, U0:UZ + 1])
        n_eff = 4.0 / (1.0 / counts[k, 0] + 1.0 / counts[k, 1])
        variance = max(errors.noise**2 / n_eff, scatter) + float(row @ s.inverse @ row)
        if abs(0.5 * (means[0, Y] + means[1, Y]) - float(row @ s.theta)) > CONTACT_AGREEMENT * math.sqrt(variance):
            break
        usable[k] = True
        solved = _solve(sums * usable[:, None, None], errors, priors, min_samples)
        assert solved is not None   # more bins than the solve before
        s = solved
    return usable


def _scatter(s: _Solution) -> tuple[Part, ...]:
    """The covariance from the rows' own scatter taken white (the weighted residuals' mean square over
    the degrees of freedom left, times the declared-noise covariance) with its degrees of freedom;
    none where no residual is left (the declared noise alone)."""
    w = 1.0 / s.noise_var
    dof = s.y.size - float(np.trace(s.inverse @ (s.rows.T @ (s.rows * w[:, None]))))
    if dof < 1.0:
        return ()
    ratio = float(np.sum(w * s.residual**2)) / dof
    return (Part(s.inverse @ (s.rows.T @ (s.rows * (ratio * w)[:, None])) @ s.inverse, dof),)


def _jackknife(s: _Solution, sums: np.ndarray, units: np.ndarray, errors: SensorErrors, priors: Priors,
               min_samples: int) -> tuple[Part, ...] | None:
    """The stratified delete-a-group jackknife covariance of θ, a part per direction with its groups
    less one degrees of freedom; None where a direction has fewer than two groups."""
    parts = []
    for direction in (0, 1):
        present = np.flatnonzero(units[:, :, direction, N].sum(axis=1) > 0.0)
        if present.size < 2:
            return None
        thetas = []
        for group in present:
            left = sums.copy()
            left[:, direction] -= units[group, :, direction]
            other = _solve(left, errors, priors, min_samples)
            if other is None:
                return None
            thetas.append(other.theta)
        spread = np.asarray(thetas) - np.mean(thetas, axis=0)
        parts.append(Part(spread.T @ spread * (present.size - 1) / present.size, float(present.size - 1)))
    return tuple(parts)
