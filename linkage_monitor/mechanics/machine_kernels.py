"""Compiled machine-level results (numba): axle loads and steerability, per pose.

The one implementation for one pose (the live node) and for N poses (replay, capacity curve,
simulator): a loop over plain arrays, no numpy temporaries per pose. Kept apart from
``kernels.py`` so that numba's on-disk cache of the linkage kernels stays valid when this file
changes. SI units (m, N, kg); frame x forward, z up, origin at the rear wheels' ground contact B;
moments M = x·Fz − z·Fx.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

# Parameters of ``steerability_rows`` (one float64 array, in this order)
PARAMETERS = ("gravity", "wheelbase", "ratio_min", "tractor_mass", "tractor_cg_x", "ballast_mass", "ballast_x",
              "unit_reference")
# Columns of its output (machine.STEERABILITY_KEYS in this order)
COLUMNS = ("front_axle_load", "rear_axle_load", "total_weight", "wheelbase", "ratio", "ratio_min", "margin",
           "front_ballast_needed", "ratio_unit", "ratio_tractor", "max_implement_mass")


@njit(cache=True)
def _not_negative(x: float) -> float:
    """max(0, x) that keeps NaN (as np.maximum does)."""
    return 0.0 if x < 0.0 else x


@njit(cache=True, error_model="numpy")
def steerability_rows(points: np.ndarray, forces: np.ndarray, implement_load: np.ndarray, implement_x: np.ndarray,
                      parameters: np.ndarray) -> np.ndarray:
    """Axle loads and steerability of N poses: (N, len(COLUMNS)) in COLUMNS order.

    points / forces (N, K, 2): m / N, the forces the linkage puts ON the frame (``frame_load_forces``);
    implement_load (N,) N and implement_x (N,) m: the implement's weight and its cg's x;
    parameters: PARAMETERS (``unit_reference`` 1.0: ratio of the unit's weight, 0.0: of the empty
    tractor's).

    Axle loads (seed 003's moment balance about B, on the tractor's free body):
    L·R_A = m_tr·g·x_tr + m_cw·g·x_cw − Σ(x·Fz − z·Fx); R_B = (m_tr + m_cw)·g − ΣFz − R_A.
    Steerability (seed 003): k = R_A / W ≥ ratio_min = r, W = R_A + R_B (unit) or m_tr·g (tractor).
    By global equilibrium R_A grows by g·x/L per kg at x, so with c = 1 for the unit and 0 for the
    tractor reference: front ballast for k = r, m_cw = m_cw0 + (r·W − R_A)/(g·(x_cw/L − r·c));
    largest implement mass m_6 = P_6/g + (R_A − r·W)/(g·(r·c − x_S6/L)); inf where the
    denominator is ≤ 0 (ballast or mass cannot reach the ratio), never below 0.
    """
    g, wheelbase, r = parameters[0], parameters[1], parameters[2]
    tractor_mass, tractor_x, ballast_mass, ballast_x = parameters[3], parameters[4], parameters[5], parameters[6]
    unit = parameters[7] > 0.5
    n_pose, n_loads = points.shape[0], points.shape[1]
    out = np.empty((n_pose, 11))
    tractor_weight = tractor_mass * g
    c = 1.0 if unit else 0.0
    ballast_slope = g * (ballast_x / wheelbase - r * c)
    for i in range(n_pose):
        moment, lift = 0.0, 0.0
        for k in range(n_loads):
            moment += points[i, k, 0] * forces[i, k, 1] - points[i, k, 1] * forces[i, k, 0]
            lift += forces[i, k, 1]
        front = (tractor_weight * tractor_x + ballast_mass * g * ballast_x - moment) / wheelbase
        rear = (tractor_mass + ballast_mass) * g - lift - front
        total = front + rear
        ratio_unit, ratio_tractor = front / total, front / tractor_weight
        ref_weight, ratio = (total, ratio_unit) if unit else (tractor_weight, ratio_tractor)
        ballast = (_not_negative(ballast_mass + (r * ref_weight - front) / ballast_slope) if ballast_slope > 0.0
                   else math.inf)
        implement_slope = g * (r * c - implement_x[i] / wheelbase)
        max_mass = (_not_negative(implement_load[i] / g + (front - r * ref_weight) / implement_slope)
                    if implement_slope > 0.0 else math.inf)
        row = out[i]
        row[0], row[1], row[2], row[3], row[4], row[5] = front, rear, total, wheelbase, ratio, r
        row[6], row[7], row[8], row[9], row[10] = ratio - r, ballast, ratio_unit, ratio_tractor, max_mass
    return out
