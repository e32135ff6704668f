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
instead of making the system singular. The rows' scatter is the larger of what the declared
pressure noise gives and the residuals' own (a Newey & West 1987 covariance over neighbouring
bins, whose residuals a bounce may correlate, scaled by the pairs over the degrees of freedom
left and widened by a Student factor for them). The sensors' calibration (a gain and an offset
of the pressure, ``SensorErrors``) is common to all rows: it is propagated through the fit's gain
matrix and added. Units SI.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

HAC_LAGS = 4   # neighbouring bins whose residuals may be correlated (Newey & West 1987)
SUMS = ("n", "u0", "ux", "uz", "y", "yy", "force")   # the columns of a bin's sums, in this order
N, U0, UX, UZ, Y, YY, FORCE = range(len(SUMS))


# The fit's records (declared errors, priors, the fit): fields of their own data, alike in form only
# to sim.work_cycle's records (the simulated truth) and sim.road's.
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
class Fit:
    """θ = (W N, W·dx N·m, W·dz N·m), its covariance (3, 3), the pairs used, the rows' RMS residual (N),
    the mean friction share (half the lifting-lowering difference over the mean, -)."""

    theta: np.ndarray
    covariance: np.ndarray
    pairs: int
    scatter: float
    friction_share: float


def student_factor(dof: int) -> float:
    """t(0.975, dof)/1.96: how much wider a 95 % interval is when σ comes from dof residuals
    (Cornish-Fisher expansion of Student's t, to 0.5 % for dof ≥ 2)."""
    if dof <= 0:
        return math.inf
    z = 1.959964
    t = z + (z**3 + z) / (4 * dof) + (5 * z**5 + 16 * z**3 + 3 * z) / (96 * dof**2) \
        + (3 * z**7 + 19 * z**5 + 17 * z**3 - 15 * z) / (384 * dof**3)
    return t / z


def fit(sums: np.ndarray, errors: SensorErrors, priors: Priors, min_samples: int) -> Fit | None:
    """The fit over the paired bins of ``sums`` (bins, 2 directions, len(SUMS)); None without a pair."""
    counts = sums[:, :, N]
    paired = np.flatnonzero((counts[:, 0] >= min_samples) & (counts[:, 1] >= min_samples))
    if paired.size == 0:
        return None
    means = sums[paired] / counts[paired][:, :, None]                 # (K, 2, SUMS)
    rows = 0.5 * (means[:, 0, U0:UZ + 1] + means[:, 1, U0:UZ + 1])    # (K, 3)
    y = 0.5 * (means[:, 0, Y] + means[:, 1, Y])
    force = 0.5 * (means[:, 0, FORCE] + means[:, 1, FORCE])
    half_gap = 0.5 * (means[:, 0, Y] - means[:, 1, Y])
    n_eff = 4.0 / (1.0 / counts[paired, 0] + 1.0 / counts[paired, 1])   # a pair mean's variance: σ²/n_eff
    weight0 = float(rows[:, 0] @ y / (rows[:, 0] @ rows[:, 0]))
    prior_precision = np.diag([0.0, 1.0 / (weight0 * priors.x) ** 2, 1.0 / (weight0 * priors.z) ** 2])
    noise_var = errors.noise**2 / n_eff                                # per row, from the declared noise
    w = 1.0 / noise_var
    normal = rows.T @ (rows * w[:, None]) + prior_precision
    inverse = np.linalg.inv(normal)
    theta = inverse @ (rows.T @ (w * y))
    residual = y - rows @ theta
    dof = paired.size - float(np.trace(inverse @ (rows.T @ (rows * w[:, None]))))
    covariance = inverse
    if dof >= 1.0:   # the residuals' own scatter, where it is larger than the declared noise's
        scores = rows * (w * residual)[:, None]
        meat = scores.T @ scores
        for lag in range(1, HAC_LAGS + 1):
            cross = scores[:-lag].T @ scores[lag:]
            meat += (1.0 - lag / (HAC_LAGS + 1)) * (cross + cross.T)
        observed = inverse @ (meat * (paired.size / dof) + prior_precision) @ inverse
        if observed[0, 0] > inverse[0, 0]:
            covariance = observed * student_factor(max(1, int(dof))) ** 2
    gain = inverse @ (rows.T * w)                                      # θ per newton of each row
    calibration = (np.outer(gain @ force, gain @ force) * errors.gain**2
                   + np.outer(gain.sum(axis=1), gain.sum(axis=1)) * errors.offset**2)
    return Fit(theta=theta, covariance=covariance + calibration, pairs=int(paired.size),
               scatter=float(math.sqrt(np.mean(residual**2))),
               friction_share=float(np.mean(half_gap) / np.mean(y)) if np.mean(y) != 0.0 else math.nan)
