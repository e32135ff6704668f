"""A pose's published numbers: the measured cylinder forces from the pressures, the largest
force, and the pose's one value row (``programs.ValueRow``)."""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba import njit, prange

from ..programs import FrameRows, OutputsProgram
from .threads import _parallel


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


@njit(cache=True)
def frame_loads(points: np.ndarray, forces: np.ndarray, p: np.ndarray, hinge_force: np.ndarray,
                member_force: np.ndarray, axes: np.ndarray, outputs: OutputsProgram | FrameRows) -> None:
    """A pose's frame loads into points and forces (F, 2): where (m) and what (N) acts ON the ground
    body, from the attachments' positions p (K, 2): the frame-side hinges (hinge_force (H, 2) N on
    bodies[1]), then the frame-side member ends (member_force (M,) N along axes (M, 2));
    ``outputs``: the frame rows of a ``programs.OutputsProgram`` or a ``FrameRows``."""
    n_frame_hinges = outputs.frame_hinge_index.shape[0]
    for j in range(outputs.frame_att.shape[0]):
        a = outputs.frame_att[j]
        points[j, 0], points[j, 1] = p[a, 0], p[a, 1]
        if j < n_frame_hinges:
            sign, h = outputs.frame_hinge_sign[j], outputs.frame_hinge_index[j]
            forces[j, 0], forces[j, 1] = sign * hinge_force[h, 0], sign * hinge_force[h, 1]
        else:
            e = outputs.frame_member_index[j - n_frame_hinges]
            f = outputs.frame_member_sign[j - n_frame_hinges] * member_force[e]
            forces[j, 0], forces[j, 1] = f * axes[e, 0], f * axes[e, 1]


class BatchOutputs(NamedTuple):
    """``batch_outputs``' arrays of N poses: hinge forces (N, H, 2) N, frame load points (N, F, 2) m and
    forces (N, F, 2) N, largest force (N,) N."""

    hinge_force: np.ndarray
    frame_points: np.ndarray
    frame_forces: np.ndarray
    largest: np.ndarray


def batch_outputs(u: np.ndarray, p: np.ndarray, member_force: np.ndarray, axes: np.ndarray, cylinder_force: np.ndarray,
                  outputs: FrameRows) -> BatchOutputs:
    """The hinge forces, frame loads and largest force of N poses from the statics' unknowns u (N,
    n_unknowns), the attachments' positions p (N, K, 2), the members' forces (N, M) N and axes
    (N, M, 2), the cylinders' forces (N, C) N. Large batches run on every core (``allow_threads``)."""
    n_pose = u.shape[0]
    out = BatchOutputs(np.empty((n_pose, outputs.hinge_cols.shape[0], 2)),
                       np.empty((n_pose, outputs.frame_att.shape[0], 2)),
                       np.empty((n_pose, outputs.frame_att.shape[0], 2)), np.empty(n_pose))
    driver = _outputs_parallel if _parallel(n_pose) else _outputs_serial
    driver(u, p, member_force, axes, cylinder_force, outputs, *out)
    return out


@njit(cache=True)
def _outputs_pose(i: int, u: np.ndarray, p: np.ndarray, member_force: np.ndarray, axes: np.ndarray,
                  cylinder_force: np.ndarray, outputs: FrameRows, hinge_force: np.ndarray,
                  frame_points: np.ndarray, frame_forces: np.ndarray, largest: np.ndarray) -> None:
    hinge_cols = outputs.hinge_cols
    for h in range(hinge_cols.shape[0]):   # N on bodies[1] from bodies[0]
        hinge_force[i, h, 0], hinge_force[i, h, 1] = u[i, hinge_cols[h, 0]], u[i, hinge_cols[h, 1]]
    largest[i] = largest_force(hinge_force[i], cylinder_force[i])
    frame_loads(frame_points[i], frame_forces[i], p[i], hinge_force[i], member_force[i], axes[i], outputs)


# _outputs_serial and _outputs_parallel: the same loop, one plain and one on numba's thread pool, a pair as
# every batch kernel has (kernels/assembly.py says why they are not one driver)
@njit(cache=True)
def _outputs_serial(u: np.ndarray, p: np.ndarray, member_force: np.ndarray, axes: np.ndarray,
                    cylinder_force: np.ndarray, outputs: FrameRows, hinge_force: np.ndarray,
                    frame_points: np.ndarray, frame_forces: np.ndarray, largest: np.ndarray) -> None:
    for i in range(u.shape[0]):
        _outputs_pose(i, u, p, member_force, axes, cylinder_force, outputs, hinge_force, frame_points, frame_forces,
                      largest)


# the pair of _outputs_serial (the same loop, on numba's thread pool)
@njit(cache=True, parallel=True)
def _outputs_parallel(u: np.ndarray, p: np.ndarray, member_force: np.ndarray, axes: np.ndarray,
                      cylinder_force: np.ndarray, outputs: FrameRows, hinge_force: np.ndarray,
                      frame_points: np.ndarray, frame_forces: np.ndarray, largest: np.ndarray) -> None:
    for i in prange(u.shape[0]):
        _outputs_pose(i, u, p, member_force, axes, cylinder_force, outputs, hinge_force, frame_points, frame_forces,
                      largest)
