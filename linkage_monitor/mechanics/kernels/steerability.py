"""Axle loads and steerability of the tractor with its implement (Popov 2009)."""

from __future__ import annotations

import math

import numpy as np
from numba import njit


# ``steerability_pose``'s parameters (one float64 array, in this order) and its row's columns
# (machine.STEERABILITY_KEYS in this order)
STEERABILITY_PARAMETERS = ("gravity", "wheelbase", "ratio_min", "tractor_mass", "tractor_cg_x", "ballast_mass",
                           "ballast_x", "unit_reference")


STEERABILITY_COLUMNS = ("front_axle_load", "rear_axle_load", "total_weight", "wheelbase", "ratio", "ratio_min",
                        "margin", "front_ballast_needed", "ratio_unit", "ratio_tractor", "max_implement_mass")


N_STEERABILITY = len(STEERABILITY_COLUMNS)


@njit(cache=True)
def _not_negative(x: float) -> float:
    """max(0, x) that keeps NaN (as np.maximum does)."""
    return 0.0 if x < 0.0 else x


@njit(cache=True, error_model="numpy")
def steerability_pose(points: np.ndarray, forces: np.ndarray, implement_load: float, implement_x: float,
                      parameters: np.ndarray, row: np.ndarray) -> None:
    """Axle loads and steerability of one pose into ``row`` (len(STEERABILITY_COLUMNS)).

    points / forces (K, 2): m / N, the forces the linkage puts ON the frame (``frame_load_forces``);
    implement_load N and implement_x m: the implement's weight and its cg's x; parameters:
    STEERABILITY_PARAMETERS (``unit_reference`` 1.0: ratio of the unit's weight, 0.0: of the empty
    tractor's).

    Axle loads (Popov 2009's moment balance about B, on the tractor's free body):
    L·R_A = m_tr·g·x_tr + m_cw·g·x_cw − Σ(x·Fz − z·Fx); R_B = (m_tr + m_cw)·g − ΣFz − R_A.
    Steerability (Popov 2009): k = R_A / W ≥ ratio_min = r, W = R_A + R_B (unit) or m_tr·g (tractor).
    By global equilibrium R_A grows by g·x/L per kg at x, so with c = 1 for the unit and 0 for the
    tractor reference: the extra front ballast for k = r (front_ballast_needed, beyond the m_cw0
    carried) Δm_cw = max(0, (r·W − R_A)/(g·(x_cw/L − r·c))), 0 when k ≥ r;
    largest implement mass m_6 = P_6/g + (R_A − r·W)/(g·(r·c − x_S6/L)); inf where the
    denominator is ≤ 0 and the ratio is not reached (ballast or mass cannot reach it), never below 0.
    """
    g, wheelbase, r = parameters[0], parameters[1], parameters[2]
    tractor_mass, tractor_x, ballast_mass, ballast_x = parameters[3], parameters[4], parameters[5], parameters[6]
    unit = parameters[7] > 0.5
    tractor_weight = tractor_mass * g
    c = 1.0 if unit else 0.0
    ballast_slope = g * (ballast_x / wheelbase - r * c)
    moment, lift = 0.0, 0.0
    for k in range(points.shape[0]):
        moment += points[k, 0] * forces[k, 1] - points[k, 1] * forces[k, 0]
        lift += forces[k, 1]
    front = (tractor_weight * tractor_x + ballast_mass * g * ballast_x - moment) / wheelbase
    rear = (tractor_mass + ballast_mass) * g - lift - front
    total = front + rear
    ratio_unit, ratio_tractor = front / total, front / tractor_weight
    ref_weight, ratio = (total, ratio_unit) if unit else (tractor_weight, ratio_tractor)
    shortfall = r * ref_weight - front   # N of front axle load missing for k = r
    if ratio >= r:   # none missing: decided as the margin is (a shortfall of rounding is not a ballast)
        ballast = 0.0
    else:
        ballast = max(shortfall / ballast_slope, 0.0) if ballast_slope > 0.0 else math.inf
    implement_slope = g * (r * c - implement_x / wheelbase)
    max_mass = (_not_negative(implement_load / g + (front - r * ref_weight) / implement_slope)
                if implement_slope > 0.0 else math.inf)
    row[0], row[1], row[2], row[3], row[4], row[5] = front, rear, total, wheelbase, ratio, r
    row[6], row[7], row[8], row[9], row[10] = ratio - r, ballast, ratio_unit, ratio_tractor, max_mass


@njit(cache=True, error_model="numpy")
def steerability_rows(points: np.ndarray, forces: np.ndarray, implement_load: np.ndarray, implement_x: np.ndarray,
                      parameters: np.ndarray) -> np.ndarray:
    """``steerability_pose`` of N poses (points / forces (N, K, 2), implement_load / implement_x
    (N,)): (N, len(STEERABILITY_COLUMNS))."""
    out = np.empty((points.shape[0], N_STEERABILITY))
    for i in range(points.shape[0]):
        steerability_pose(points[i], forces[i], implement_load[i], implement_x[i], parameters, out[i])
    return out
