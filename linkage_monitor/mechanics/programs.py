"""What the compiled kernels (``kernels``) take and give, as named records.

A *program* is a mechanism (or one statics layout of it) as plain arrays, built once by the class
named in its docstring and handed to every compiled call; the kernels read its fields by name
(numba compiles a NamedTuple's attribute access to a struct field). The live calls take the five
programs of a configuration as one ``LivePrograms`` object, built once (``kernels.live_programs``
from plain tuples of their fields, ``fields``): numba types a NamedTuple argument in Python, and
unboxes every array of a tuple argument at every call (about 0.2 µs an array: some 20 µs for
the ~80 arrays of the five programs), while an object holding them passes as one pointer.
``LiveRows`` is what the live solve writes, per pose; a ``LiveBuffer`` holds them with the
poses' inputs, again as one object. Indices are attachments (points fixed on
bodies, ``Kinematics.attach``), hinges, members (springs then cylinders) or columns of the
statics' unknowns. SI units: m, rad, N, kg; frame x forward, z up.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba.core import types
from numba.experimental import structref


# KinematicsProgram below starts with these fields again, flat (numba's parallel loop takes no nested record).
class Geometry(NamedTuple):
    """The loop closure's geometry (``Kinematics.geometry``): attachment bodies (K,) (−1: ground)
    and offsets (K, 2) m, hinge attachments (2, H), measured cylinders' (base, rod end)
    attachments (2, nc), angle sensors' bodies (2, na), their reference readings (na,) rad, the
    length scale lc m."""

    att_body: np.ndarray
    att_ref: np.ndarray
    hinge_att: np.ndarray
    cyl_att: np.ndarray
    angle_body: np.ndarray
    angle_reference: np.ndarray
    lc: float


# Geometry's fields again, flat, not the record: numba's parallel loop takes a record of arrays and
# scalars, not one that holds a record. Geometry above: the same first fields.
class KinematicsProgram(NamedTuple):
    """The loop closure (``Kinematics.program``): attachment bodies (K,) (−1: ground) and offsets
    (K, 2) m; hinge attachments (2, H); measured cylinders' (base, rod end) attachments (2, nc);
    angle sensors' bodies (2, na) and reference readings (na,) rad; the length scale lc m; the
    driving and fitted rows of the closure system; the chain of dyads (``chain.decompose``: int
    and float tables); the column scale (n,); the loops' rows, columns and offsets; the
    reference assembly branch (one sign per loop)."""

    att_body: np.ndarray
    att_ref: np.ndarray
    hinge_att: np.ndarray
    cyl_att: np.ndarray
    angle_body: np.ndarray
    angle_reference: np.ndarray
    lc: float
    drive_rows: np.ndarray
    fit_rows: np.ndarray
    chain_int: np.ndarray
    chain_float: np.ndarray
    column_scale: np.ndarray
    loop_rows: np.ndarray
    loop_cols: np.ndarray
    loop_ptr: np.ndarray
    ref_branch: np.ndarray


class StaticsProgram(NamedTuple):
    """One statics layout (``StaticsLayout.program``; ``kernels.solve_statics`` says how it is
    used): lc m, the number of equations; column terms (column, attachment, body, constant unit
    force, member, sign); known loads (constant forces, their attachments and bodies, the member
    ends of known force and their signs); the members' end attachments (2, M); the bodies' cgs,
    masses (kg) and inertias (kg·m²) for kinetostatics."""

    lc: float
    n_eq: int
    t_col: np.ndarray
    t_att: np.ndarray
    t_body: np.ndarray
    t_const: np.ndarray
    t_member: np.ndarray
    t_sign: np.ndarray
    const_force: np.ndarray
    known_att: np.ndarray
    known_body: np.ndarray
    end_member: np.ndarray
    end_sign: np.ndarray
    member_att: np.ndarray
    mass_att: np.ndarray
    mass_body: np.ndarray
    mass: np.ndarray
    inertia: np.ndarray


class ReducedProgram(NamedTuple):
    """The statics along the chain of dyads (``ReducedStatics.program``): attachment bodies (K,),
    hinge attachments (2, H), the chain (S, fields), the hinges' columns (H, 2); per step the
    column of its cylinder's unknown force (−1: none or measured), its member and the sign of
    its force on the step's body; the free load's column and its closing step (−1: none)."""

    att_body: np.ndarray
    hinge_att: np.ndarray
    chain_int: np.ndarray
    hinge_cols: np.ndarray
    step_col: np.ndarray
    step_member: np.ndarray
    step_sign: np.ndarray
    free_col: int
    closing_step: int


class OutputsProgram(NamedTuple):
    """What the live solve needs beyond the statics layout to write a ``Result``'s rows
    (``Solver.outputs_program``): the number of unknowns; the springs' stiffness (N/m), free
    length (m) and preload (N); the hinges' columns (H, 2); which cylinders' forces are measured
    and the columns of the others; the contacts' columns and friction coefficients; the
    implement load's column (−1: its weight, ``implement_weight`` N, is known); 1 / (count·cap
    area) per cylinder (1/m²); count·cap area and count·rod area (2, C) (m², ``kernels.measured_force``);
    the result points' attachments; the implement cg's (−1: none);
    the frame loads' attachments, hinges and members with their signs (+1: the force on the
    ground). ``reduced``: whether the reduced coordinates serve the layout (then its
    ``ReducedProgram`` solves it and ``dead_centre_sine`` = sin of the dead-centre transmission
    angle decides). ``measure_count``: the chain's transmission measures (steps + the free load)."""

    n_unknowns: int
    spring_stiffness: np.ndarray
    spring_free_length: np.ndarray
    spring_preload: np.ndarray
    hinge_cols: np.ndarray
    force_measured: np.ndarray
    cylinder_cols: np.ndarray
    contact_cols: np.ndarray
    implement_col: int
    implement_weight: float
    per_cap_area: np.ndarray
    force_areas: np.ndarray
    friction: np.ndarray
    point_rows: np.ndarray
    cg_att: int
    frame_att: np.ndarray
    frame_hinge_index: np.ndarray
    frame_hinge_sign: np.ndarray
    frame_member_index: np.ndarray
    frame_member_sign: np.ndarray
    reduced: bool
    dead_centre_sine: float
    measure_count: int


class FrameRows(NamedTuple):
    """What ``kernels.batch_outputs`` takes of a statics layout and a result layout
    (``ResultLayout.frame_rows``): the hinges' columns (H, 2) in the unknowns, and the frame loads as
    ``OutputsProgram`` has them: their attachments (F,), the frame-side hinges' indices and signs, the
    frame-side member ends' member indices and signs."""

    hinge_cols: np.ndarray
    frame_att: np.ndarray
    frame_hinge_index: np.ndarray
    frame_hinge_sign: np.ndarray
    frame_member_index: np.ndarray
    frame_member_sign: np.ndarray


class MachineProgram(NamedTuple):
    """The machine-level results in the live solve (``MachineModel.program``): the steerability
    parameters (``kernels.STEERABILITY_PARAMETERS``; empty: no tractor block); for the lift
    capacity by virtual work (empty ``point_att``: not computed) the hinge attachments, every
    cylinder's (base, rod end) attachments, the lift cylinder's index and force (N), gravity
    (m/s²), the other bodies' cg attachments and masses (kg), the capacity points' attachments
    and which of them is the implement's cg."""

    parameters: np.ndarray
    hinge_att: np.ndarray
    cylinder_att: np.ndarray
    lift: int
    lift_force: float
    gravity: float
    weight_att: np.ndarray
    weight_mass: np.ndarray
    point_att: np.ndarray
    cg_point: int


POSE_VALUES = np.dtype([("implement_load", np.float64), ("residual", np.float64),
                        ("consistency_residual", np.float64), ("condition", np.float64),
                        ("transmission_angle", np.float64), ("largest_force", np.float64),
                        ("weakest", np.int64), ("load_amplification", np.float64)])
"""The scalars of one pose in ``LiveRows.pose``: implement load N, equilibrium residual N (N·m on
the reduced path), consistency residual m, condition number (the kinematic one on the reduced
path), smallest transmission angle rad (NaN on the general path), the largest hinge or cylinder
force N (``kernels.largest_force``), the index of the transmission measure (−1: none) and the free
load's amplification (N per N of the measured force it is inferred from; NaN: not inferred)."""


ROW_SCALARS = ("residual", "consistency_residual", "implement_load", "transmission_angle")
"""The scalars of a pose's value row, in order (``ValueRow.scalars``): as ``Result``'s fields."""


class ValueRow(NamedTuple):
    """Where a pose's published numbers sit in its one float64 value row (``LiveRows.values``,
    written by ``kernels.pack_row``; the output messages take their float fields from it): the
    first column of each part, in this order: fx, fz per hinge (N); |F| per hinge (N); x, z per
    point (m); ``CylinderResult``'s fields per cylinder; ``ROW_SCALARS``; the implement cg's x, z
    (m); the lift capacity row (``MachineResult.capacity_row``); the steerability row
    (``MachineResult.steerability_row``); ``width`` the row's length."""

    hinge_force: int
    hinge_magnitude: int
    point_xz: int
    cylinder_values: int
    scalars: int
    implement_cg: int
    capacity: int
    steerability: int
    width: int

    @staticmethod
    def of(n_hinges: int, n_points: int, n_cylinders: int, n_capacity: int, n_steerability: int) -> "ValueRow":
        """The row of a pose with these counts of hinges, points, cylinders, capacity and
        steerability values."""
        sizes = (2 * n_hinges, n_hinges, 2 * n_points, 5 * n_cylinders, len(ROW_SCALARS), 2, n_capacity, n_steerability)
        starts = np.cumsum((0, *sizes)).tolist()
        return ValueRow(*starts)


class LiveRows(NamedTuple):
    """What ``kernels.live_series`` writes for N poses, in ``Result``'s and ``MachineResult``'s
    layouts: whether pose i took the live path (``plain``; False: its rows are not meaningful,
    the general path words it); q (N, n), Φ (N, m), the kinematic condition (N,); points
    (N, P, 2) m, hinge forces (N, H, 2) N, cylinder values (N, C, 5), contact values (N, K, 2),
    implement cg (N, 2) m, frame load points and forces (N, F, 2); the pose's scalars (N,)
    ``POSE_VALUES``; steerability rows (N, S) and capacity rows (N, P + 1); the value rows
    (N, ``ValueRow.width``)."""

    plain: np.ndarray
    q: np.ndarray
    phi: np.ndarray
    kinematic_condition: np.ndarray
    point_xz: np.ndarray
    hinge_force: np.ndarray
    cylinder_values: np.ndarray
    contact_values: np.ndarray
    implement_cg: np.ndarray
    frame_load_points: np.ndarray
    frame_load_forces: np.ndarray
    pose: np.ndarray
    steerability: np.ndarray
    capacity: np.ndarray
    values: np.ndarray


def fields(program: NamedTuple) -> tuple:
    """A program as the live calls take it (``kernels.live_programs``, ``live_series``' rows): a plain
    tuple of its fields."""
    return tuple(program)


@structref.register
class LiveProgramsType(types.StructRef):
    """numba's type of ``LivePrograms``: its fields typed as the records they hold."""

    def preprocess_fields(self, fields: tuple) -> tuple:
        return tuple((name, types.unliteral(typ)) for name, typ in fields)


class LivePrograms(structref.StructRefProxy):
    """The programs of one configuration as ``kernels.live_series`` takes them, in one object built
    once (``kernels.live_programs``): ``kin`` a KinematicsProgram, ``statics`` a StaticsProgram,
    ``outputs`` an OutputsProgram, ``reduced`` a ReducedProgram, ``machine`` a MachineProgram. It
    holds references to the arrays, not copies."""


structref.define_proxy(LivePrograms, LiveProgramsType, ["kin", "statics", "outputs", "reduced", "machine"])


@structref.register
class LiveBufferType(types.StructRef):
    """numba's type of ``LiveBuffer``: its fields typed as the arrays and the record they hold."""

    def preprocess_fields(self, fields: tuple) -> tuple:
        return tuple((name, types.unliteral(typ)) for name, typ in fields)


class LiveBuffer(structref.StructRefProxy):
    """What ``kernels.live_series`` solves and where it writes, in one object (``kernels.live_buffer``;
    one pointer to pass, where the arrays took ~0.1 µs each at every call): ``rows`` a ``LiveRows``
    of N poses, their inputs ``s`` (N, n_inputs) and ``pressures`` (N, 2, C). It holds
    references to the arrays, not copies."""


structref.define_proxy(LiveBuffer, LiveBufferType, ["rows", "s", "pressures"])
