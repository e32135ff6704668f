"""One live pose, end to end, and a series of them, in one compiled call (``live_series``): loop
closure, equilibrium with the measured cylinder forces, the arrays of a ``Result``, lift
capacity and steerability, into ``LiveRows``."""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba import njit

from ..programs import (POSE_VALUES, KinematicsProgram, LiveBuffer, LivePrograms, LiveRows, MachineProgram,
                        OutputsProgram, ReducedProgram, StaticsProgram, ValueRow)
from .assembly import KinematicJob, _kinematic_pose, _same_inputs, assembled
from .capacity import CapacityJob, _capacity_pose, _reserve
from .closure import positions
from .equilibrium import StaticsJob, _statics_pose
from .reduced import ReducedJob, _reduced_pose, _reduced_work, smallest_sine
from .rows import frame_loads, largest_force, measured_force, pack_row
from .steerability import N_STEERABILITY, steerability_pose


def live_rows(n_pose: int, n: int, m: int, outputs: OutputsProgram, machine: MachineProgram) -> LiveRows:
    """Empty ``LiveRows`` for n_pose poses, for ``live_series`` to write, which also fills what a
    pose may leave unwritten (``_live_pose_at``).
    Allocated by the caller, uninitialised: numba returns a record of fresh arrays slower than it
    takes one in, and filling them here cost a third of this function's time on the live pose."""
    n_steer = N_STEERABILITY if machine.parameters.shape[0] > 0 else 0
    n_capacity = machine.point_att.shape[0] + 1 if machine.point_att.shape[0] > 0 else 0
    n_frame = outputs.frame_att.shape[0]
    return LiveRows(
        plain=np.zeros(n_pose, dtype=np.bool_), q=np.empty((n_pose, n)), phi=np.empty((n_pose, m)),
        kinematic_condition=np.empty(n_pose),
        point_xz=np.empty((n_pose, outputs.point_rows.shape[0], 2)),
        hinge_force=np.empty((n_pose, outputs.hinge_cols.shape[0], 2)),
        cylinder_values=np.empty((n_pose, outputs.per_cap_area.shape[0], 5)),
        contact_values=np.empty((n_pose, outputs.contact_cols.shape[0], 2)), implement_cg=np.empty((n_pose, 2)),
        frame_load_points=np.empty((n_pose, n_frame, 2)), frame_load_forces=np.empty((n_pose, n_frame, 2)),
        pose=np.empty(n_pose, dtype=POSE_VALUES), steerability=np.empty((n_pose, n_steer)),
        capacity=np.empty((n_pose, n_capacity)),
        values=np.empty((n_pose, ValueRow.of(outputs.hinge_cols.shape[0], outputs.point_rows.shape[0],
                                             outputs.per_cap_area.shape[0], n_capacity, n_steer).width)))


@njit(cache=True)
def live_programs(kin_fields, statics_fields, outputs_fields, reduced_fields, machine_fields):
    """The ``LivePrograms`` of one configuration from each program as a plain tuple of its fields
    (``programs.fields``): ``Kinematics.program``, ``StaticsLayout.program``,
    ``Solver.outputs_program`` of that layout, ``ReducedStatics.program`` of it,
    ``MachineModel.program`` (``NO_MACHINE`` when no machine-level results are wanted)."""
    return LivePrograms(KinematicsProgram(*kin_fields), StaticsProgram(*statics_fields),
                        OutputsProgram(*outputs_fields), ReducedProgram(*reduced_fields),
                        MachineProgram(*machine_fields))


@njit(cache=True)
def live_buffer(rows_fields, s, pressures):
    """The ``LiveBuffer`` of rows (``live_rows``' of N poses, as a plain tuple) and the inputs of the
    poses: s (N, n_inputs), pressures (N, 2, C) (``live_series``)."""
    return LiveBuffer(LiveRows(*rows_fields), s, pressures)


class LiveStart(NamedTuple):
    """Where a live pose starts from: a solved pose q (1, n) and its inputs s (1, n_inputs), with its
    capacity row (empty when not known)."""

    q: np.ndarray
    s: np.ndarray
    capacity: np.ndarray


@njit(cache=True, nogil=True)   # a replay reads its next inputs while a part is solved
def live_series(programs, buffer, q_start, s_start, limit, max_condition, first, stop):
    """Poses first..stop−1 of ``buffer`` (``live_buffer``) as the live node solves them, in one
    compiled call: the live node's one pose (a row of the rows it keeps), a recorded series (replay:
    all its rows). Pose i from the last pose before it from ``first`` on that took this path, the
    first from (q_start (1, n), s_start (1, n_inputs)). The buffer's s (N, n_inputs): inputs (m,
    rad); its pressures (N, 2, C): per cylinder the cap and rod gauge pressures (Pa, NaN = not
    measured; ``measured_force`` of those whose force the layout takes as measured). limit: largest constraint residual
    accepted (m); max_condition: the dead-centre condition number of the general path (the
    kinematics' and the statics'; the reduced path's verdict is the transmission measure, and its
    kinematic condition number is NaN). ``programs``: the configuration's ``LivePrograms``
    (``live_programs``). Writes rows first..stop−1 of the buffer's rows.

    Each pose, from the per-pose kernels above: loop closure (``_kinematic_pose``), equilibrium with
    the measured cylinder forces — along the chain of dyads with the transmission verdict
    (``_reduced_pose``) where ``outputs.reduced``, else in one linear system with the
    condition-number verdict (``_statics_pose``) —, the arrays of a ``Result``, lift capacity
    (``_capacity_pose``) and steerability (``steerability_pose``), into the rows;
    ``plain[i]`` is False when pose i is not the usual one — off the reference branch, not
    assembled to ``limit``, at a dead centre, a contact lifting off — and then its rows are not
    meaningful: the general path (``Solver._solve``) words the verdict.
    """
    rows, s = buffer.rows, buffer.s
    last = -1
    for i in range(first, stop):
        if last < 0:   # (two calls: the start's arrays of two layouts, each call compiled for its own)
            _live_pose_at(i, buffer, LiveStart(q=q_start, s=s_start, capacity=rows.capacity[i, :0]), limit,
                          max_condition, programs)
        else:
            _live_pose_at(i, buffer, LiveStart(q=rows.q[last:last + 1], s=s[last:last + 1],
                                               capacity=rows.capacity[last]), limit, max_condition, programs)
        if rows.plain[i]:
            last = i


@njit(cache=True)
def _live_statics(i, rows, job: StaticsJob, max_condition, programs) -> bool:
    """Equilibrium of pose i of ``live_series`` (``job``: one pose's, its u, member axes and lengths
    written), its residual, condition, transmission and the free load's amplification into ``rows``:
    False at a dead centre (the general path then words the verdict, and spares an inferred load:
    ``general_path``) — the smallest transmission below ``outputs.dead_centre_sine`` (reduced path)
    or the condition number above ``max_condition`` (general path)."""
    outputs, statics, reduced = programs.outputs, programs.statics, programs.reduced
    if outputs.reduced:
        sine, weakest = np.empty((1, outputs.measure_count)), np.empty(1, dtype=np.int64)
        amplification = np.empty(1)
        reduced_job = ReducedJob(u=job.u, residual=job.residual, sine=sine, weakest=weakest,
                                 amplification=amplification, axes=job.axes, lengths=job.lengths, p=job.p,
                                 member_force=job.member_force, accel=job.accel, alpha=job.alpha,
                                 has_accel=job.has_accel)
        _reduced_pose(0, reduced_job, statics, reduced, _reduced_work(statics, reduced, job.u.shape[1]))
        smallest = smallest_sine(sine[0], weakest[0])
        if not smallest >= outputs.dead_centre_sine:
            return False
        rows.pose[i].transmission_angle, rows.pose[i].weakest = math.asin(smallest), weakest[0]
        rows.pose[i].load_amplification = amplification[0]
        rows.pose[i].condition = rows.kinematic_condition[i]
    else:
        _statics_pose(0, job, statics)
        if not job.condition[0] <= max_condition:
            return False
        rows.pose[i].transmission_angle, rows.pose[i].weakest = math.nan, -1
        rows.pose[i].load_amplification = math.nan
        rows.pose[i].condition = max(job.condition[0], rows.kinematic_condition[i])
    rows.pose[i].residual = job.residual[0]
    return True


@njit(cache=True)
def _live_pose_at(i, buffer, start: LiveStart, limit, max_condition, programs):
    """Pose i of ``live_series``, written into its rows of the buffer's rows (``LiveRows``). The rows
    of a pose that is not plain are left as they are (the general path writes them), except the
    implement cg and the capacities, NaN until written (no implement; a capacity not computed),
    and the transmission measure, NaN and −1 until the reduced statics give it. A pose with the
    start pose's inputs, the start's capacity row known, has its capacities at the points (they
    depend on the pose alone) and only its reserve is computed."""
    rows, s, pressures = buffer.rows, buffer.s, buffer.pressures
    kin, statics, outputs, machine = programs.kin, programs.statics, programs.outputs, programs.machine
    rows.implement_cg[i, 0], rows.implement_cg[i, 1] = math.nan, math.nan
    rows.capacity[i, :] = math.nan
    rows.pose[i].transmission_angle, rows.pose[i].weakest = math.nan, -1
    rows.pose[i].load_amplification = math.nan
    member_att = statics.member_att   # (2, M): the ends of springs then cylinders
    n, m = rows.q.shape[1], rows.phi.shape[1]
    n_springs, n_cylinders = outputs.spring_stiffness.shape[0], outputs.per_cap_area.shape[0]
    n_members = n_springs + n_cylinders
    on_branch = np.empty(1, dtype=np.bool_)
    kinematic_job = KinematicJob(q=rows.q[i:i + 1], phi=rows.phi[i:i + 1], condition=rows.kinematic_condition[i:i + 1],
                                 on_branch=on_branch, q_start=start.q, s_start=start.s, s=s[i:i + 1], max_iter=25,
                                 with_condition=not outputs.reduced)
    _kinematic_pose(0, kinematic_job, kin)
    if not (on_branch[0] and assembled(rows.phi[i], 2 * kin.hinge_att.shape[1], kin.lc, limit)
            and (outputs.reduced or rows.kinematic_condition[i] <= max_condition)):
        return
    p1, _ = positions(rows.q[i], kin.att_body, kin.att_ref)
    p = p1.reshape((1, p1.shape[0], 2))
    member_force = np.empty((1, n_members))
    for k in range(n_springs):   # k·(free length − length) + preload (StaticsLayout.spring_forces)
        a, b = member_att[0, k], member_att[1, k]
        dx, dz = p1[b, 0] - p1[a, 0], p1[b, 1] - p1[a, 1]
        member_force[0, k] = outputs.spring_stiffness[k] * (outputs.spring_free_length[k] - math.sqrt(dx * dx + dz * dz)) \
            + outputs.spring_preload[k]
    measured = np.empty(n_cylinders)   # N: an unmeasured cylinder's force is an unknown
    for k in range(n_cylinders):
        measured[k] = measured_force(pressures[i, 0, k], pressures[i, 1, k], outputs.force_areas[0, k],
                                     outputs.force_areas[1, k]) if outputs.force_measured[k] else 0.0
        member_force[0, n_springs + k] = measured[k]
    job = StaticsJob(u=np.empty((1, outputs.n_unknowns)), residual=np.empty(1), condition=np.empty(1),
                     axes=np.empty((1, n_members, 2)), lengths=np.empty((1, n_members)), p=p, member_force=member_force,
                     accel=np.zeros((1, 1, 2)), alpha=np.zeros((1, 1)), has_accel=False)
    if not _live_statics(i, rows, job, max_condition, programs):
        return
    u, axes, lengths = job.u[0], job.axes, job.lengths
    contact_cols = outputs.contact_cols
    for k in range(contact_cols.shape[0]):
        if u[contact_cols[k]] < 0.0:   # lifts off
            return
    for k in range(contact_cols.shape[0]):
        normal = u[contact_cols[k]]
        rows.contact_values[i, k, 0], rows.contact_values[i, k, 1] = normal, outputs.friction[k] * normal
    for k in range(outputs.point_rows.shape[0]):
        a = outputs.point_rows[k]
        rows.point_xz[i, k, 0], rows.point_xz[i, k, 1] = p1[a, 0], p1[a, 1]
    hinge_cols = outputs.hinge_cols
    for h in range(hinge_cols.shape[0]):   # N on bodies[1] from bodies[0]
        rows.hinge_force[i, h, 0], rows.hinge_force[i, h, 1] = u[hinge_cols[h, 0]], u[hinge_cols[h, 1]]
    for k in range(n_cylinders):
        force = measured[k] if outputs.force_measured[k] else u[outputs.cylinder_cols[k]]
        member_force[0, n_springs + k] = force
        cylinder = rows.cylinder_values[i, k]   # CylinderResult's fields
        cylinder[0], cylinder[1] = lengths[0, n_springs + k], force
        cylinder[2] = force * outputs.per_cap_area[k]
        cylinder[3], cylinder[4] = pressures[i, 0, k], pressures[i, 1, k]
    rows.pose[i].largest_force = largest_force(rows.hinge_force[i], rows.cylinder_values[i, :, 1])
    frame_points, frame_forces = rows.frame_load_points[i], rows.frame_load_forces[i]
    frame_loads(frame_points, frame_forces, p1, rows.hinge_force[i], member_force[0], axes[0], outputs)
    if outputs.cg_att >= 0:
        rows.implement_cg[i, 0], rows.implement_cg[i, 1] = p1[outputs.cg_att, 0], p1[outputs.cg_att, 1]
    load = u[outputs.implement_col] if outputs.implement_col >= 0 else outputs.implement_weight
    consistency = 0.0
    for r in range(m):
        consistency += rows.phi[i, r] * rows.phi[i, r]
    rows.pose[i].implement_load, rows.pose[i].consistency_residual = load, math.sqrt(consistency)
    if machine.parameters.shape[0]:
        steerability_pose(frame_points, frame_forces, load, rows.implement_cg[i, 0], machine.parameters,
                          rows.steerability[i])
    if machine.point_att.shape[0] and start.capacity.shape[0] and _same_inputs(s[i], start.s[0]):
        rows.capacity[i, :] = start.capacity
        _reserve(rows.capacity[i], machine.cg_point, load)
    elif machine.point_att.shape[0]:
        square = 2 * machine.hinge_att.shape[1] + machine.cylinder_att.shape[1] == n
        _capacity_pose(0, CapacityJob(out=rows.capacity[i:i + 1], q=rows.q[i:i + 1], att_body=kin.att_body,
                                      att_ref=kin.att_ref, column_scale=kin.column_scale, ok=np.ones(1, dtype=np.bool_),
                                      implement_load=np.full(1, load), spring_att=member_att[:, :n_springs].copy(),
                                      spring_force=member_force[:, :n_springs].copy(), max_condition=max_condition,
                                      square=square), machine)
    pose = rows.pose[i]
    scalars = np.array((pose.residual, pose.consistency_residual, load, pose.transmission_angle))   # ROW_SCALARS
    pack_row(rows.values[i], rows.hinge_force[i], rows.point_xz[i], rows.cylinder_values[i], scalars,
             rows.implement_cg[i], rows.capacity[i], rows.steerability[i])
    rows.plain[i] = True


# ``live_series``' machine program when no machine-level results are wanted
NO_MACHINE = MachineProgram(parameters=np.zeros(0), hinge_att=np.zeros((2, 0), dtype=np.int64),
                            cylinder_att=np.zeros((2, 0), dtype=np.int64), lift=0, lift_force=math.nan,
                            gravity=math.nan, weight_att=np.zeros(0, dtype=np.int64), weight_mass=np.zeros(0),
                            point_att=np.zeros(0, dtype=np.int64), cg_point=0)
