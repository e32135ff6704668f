"""A pose's published numbers: the measured cylinder forces from the pressures, the largest
force, and the pose's one value row (``programs.ValueRow``)."""

from __future__ import annotations

import math

import numpy as np
from numba import njit


@njit(cache=True)
def measured_force(cap: float, rod: float, cap_area: float, rod_area: float) -> float:
    """Axial force (N, + pushing) of a cylinder group from its gauge pressures (Pa; NaN = that
    chamber not measured, taken as 0) and its chambers' areas × count (m²): F = count·(p_cap·A_cap
    − p_rod·A_rod) (schema, cylinders[])."""
    return (0.0 if math.isnan(cap) else cap) * cap_area - (0.0 if math.isnan(rod) else rod) * rod_area


@njit(cache=True)
def measured_forces(cap: np.ndarray, rod: np.ndarray, force_areas: np.ndarray) -> np.ndarray:
    """``measured_force`` of N poses: cap, rod (N, C) Pa gauge, force_areas (2, C) m² -> (N, C) N."""
    out = np.empty(cap.shape)
    for i in range(cap.shape[0]):
        for k in range(cap.shape[1]):
            out[i, k] = measured_force(cap[i, k], rod[i, k], force_areas[0, k], force_areas[1, k])
    return out


@njit(cache=True)
def largest_force(hinge_force: np.ndarray, cylinder_force: np.ndarray) -> float:
    """The largest hinge reaction or cylinder force magnitude (N) of one pose: hinge_force (H, 2)
    N, cylinder_force (C,) N; 0 with neither, NaN where any of them is NaN (a failed pose)."""
    largest = 0.0
    for h in range(hinge_force.shape[0]):
        magnitude = math.hypot(hinge_force[h, 0], hinge_force[h, 1])
        if math.isnan(magnitude):
            return math.nan
        largest = max(largest, magnitude)
    for c in range(cylinder_force.shape[0]):
        magnitude = abs(cylinder_force[c])
        if math.isnan(magnitude):
            return math.nan
        largest = max(largest, magnitude)
    return largest


# The batch loop of a per-pose function, written out as reduced.smallest_sines' is: a compiled function
# given another as an argument is compiled again at every start (numba keeps no cache of it).
@njit(cache=True)
def largest_forces(hinge_force: np.ndarray, cylinder_force: np.ndarray) -> np.ndarray:
    """``largest_force`` of N poses: hinge_force (N, H, 2), cylinder_force (N, C) -> (N,) N."""
    out = np.empty(hinge_force.shape[0])
    for i in range(hinge_force.shape[0]):
        out[i] = largest_force(hinge_force[i], cylinder_force[i])
    return out


@njit(cache=True)
def pack_row(out: np.ndarray, hinge_force: np.ndarray, point_xz: np.ndarray, cylinder_values: np.ndarray,
             scalars: np.ndarray, implement_cg: np.ndarray, capacity: np.ndarray, steerability: np.ndarray) -> None:
    """A pose's value row (``programs.ValueRow``) into out: from its hinge forces (H, 2) N, points
    (P, 2) m, cylinder values (C, 5), ``ROW_SCALARS`` (4,), implement cg (2,) m, capacity and
    steerability rows."""
    k = 0
    for h in range(hinge_force.shape[0]):
        out[k], out[k + 1] = hinge_force[h, 0], hinge_force[h, 1]
        k += 2
    for h in range(hinge_force.shape[0]):
        out[k] = math.hypot(hinge_force[h, 0], hinge_force[h, 1])
        k += 1
    for a in range(point_xz.shape[0]):
        out[k], out[k + 1] = point_xz[a, 0], point_xz[a, 1]
        k += 2
    for c in range(cylinder_values.shape[0]):
        for j in range(5):
            out[k + j] = cylinder_values[c, j]
        k += 5
    k = _copy_into(out, k, scalars)
    k = _copy_into(out, k, implement_cg)
    k = _copy_into(out, k, capacity)
    _copy_into(out, k, steerability)


@njit(cache=True)
def _copy_into(out: np.ndarray, k: int, part: np.ndarray) -> int:
    """part (1-d) into out from column k on; the column after it."""
    for j in range(part.shape[0]):
        out[k + j] = part[j]
    return k + part.shape[0]


@njit(cache=True)
def pack_rows(hinge_force: np.ndarray, point_xz: np.ndarray, cylinder_values: np.ndarray, scalars: np.ndarray,
              implement_cg: np.ndarray, capacity: np.ndarray, steerability: np.ndarray, width: int) -> np.ndarray:
    """``pack_row`` of N poses (each argument with a first axis of poses) -> (N, width)."""
    out = np.empty((hinge_force.shape[0], width))
    for i in range(hinge_force.shape[0]):
        pack_row(out[i], hinge_force[i], point_xz[i], cylinder_values[i], scalars[i], implement_cg[i], capacity[i],
                 steerability[i])
    return out
