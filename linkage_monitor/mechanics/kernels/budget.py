"""An error budget's derivatives and its summary in compiled code (``uncertainty``: the method, the
table and the rules; here the arithmetic): the chain rule from the outputs linear in the loads to
the others (``chain_rule``), and the budget of a pose on a tabulated one-DOF linkage in one call
(``tabulated_budget``): its derivatives interpolated from the table, its contributions, standard
uncertainties and coverage factors. Units SI (N, m, rad, Pa, kg)."""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba import njit
from numba.core import types
from numba.experimental import structref

from .coverage import coverage_factors


class OutputLayout(NamedTuple):
    """Where the outputs of a budget sit in its row (``output_table.OutputTable``): the first fx, fz and
    magnitude columns of the hinges and their count, the implement load's column; with steerability
    (``steer``), the front and rear axle loads', the ratio's and the margin's, whether the ratio is of
    the unit's weight (``unit_reference``) or of the tractor's (``tractor_weight``, N); the capacity at
    the implement's cg (−1: none) and the lift reserve's (−1: none)."""

    fx: int
    fz: int
    magnitude: int
    n_hinges: int
    load: int
    steer: bool
    front: int
    rear: int
    ratio: int
    margin: int
    unit_reference: bool
    tractor_weight: float
    capacity_cg: int
    reserve: int


@njit(cache=True, error_model="numpy")
def chain_rule(d: np.ndarray, y0: np.ndarray, layout: OutputLayout) -> None:
    """The derivatives of the outputs not linear in the loads, from those that are, in place in each
    row of ``d`` (R, n_out; a row per source, its linear columns given) at the pose of outputs ``y0``
    (n_out,): a hinge's magnitude from its fx and fz (|d| where the magnitude is 0), the steerability
    ratio and margin from the axle loads, the lift reserve from the capacity at the cg and the
    implement load (NaN or inf where the load is 0: no derivative)."""
    for r in range(d.shape[0]):
        for h in range(layout.n_hinges):
            fx, fz, magnitude = y0[layout.fx + h], y0[layout.fz + h], y0[layout.magnitude + h]
            dfx, dfz = d[r, layout.fx + h], d[r, layout.fz + h]
            d[r, layout.magnitude + h] = ((fx * dfx + fz * dfz) / magnitude if magnitude > 0.0
                                          else math.hypot(dfx, dfz))
        if layout.steer:
            front, rear = y0[layout.front], y0[layout.rear]
            d_front, d_rear = d[r, layout.front], d[r, layout.rear]
            ratio = ((d_front - y0[layout.ratio] * (d_front + d_rear)) / (front + rear) if layout.unit_reference
                     else d_front / layout.tractor_weight)
            d[r, layout.ratio], d[r, layout.margin] = ratio, ratio
        if layout.capacity_cg >= 0:
            d[r, layout.reserve] = (d[r, layout.capacity_cg] - y0[layout.reserve] * d[r, layout.load]) / y0[layout.load]


@njit(cache=True)
def output_rows(hinge_force: np.ndarray, cylinder_force: np.ndarray, implement_load: np.ndarray,
                steerability: np.ndarray, capacity: np.ndarray, steer_columns: np.ndarray, out: np.ndarray) -> None:
    """The outputs of N poses into ``out`` (N, n_out) in ``output_table.OutputTable``'s order
    (``_output_row``): hinge forces (N, H, 2) N, cylinder forces (N, C) N, implement loads (N,) N,
    steerability rows (N, S) and capacity rows (N, P + 1)."""
    for i in range(out.shape[0]):
        _output_row(hinge_force[i], cylinder_force[i], implement_load[i], steerability[i], capacity[i], steer_columns,
                    out[i])


@njit(cache=True)
def _output_row(hinge_force: np.ndarray, cylinder_force: np.ndarray, implement_load: float,
                steerability: np.ndarray, capacity: np.ndarray, steer_columns: np.ndarray, out: np.ndarray) -> None:
    """The outputs of one pose into ``out`` (n_out,): hinge forces (H, 2) N as fx, fz and magnitude per
    hinge, cylinder forces (C,) N, the implement load N, the ``steer_columns`` of the steerability row
    (S,) (none: no steerability), the capacity row (P + 1,) whole."""
    n_hinges = hinge_force.shape[0]
    for h in range(n_hinges):
        fx, fz = hinge_force[h, 0], hinge_force[h, 1]
        out[h], out[n_hinges + h], out[2 * n_hinges + h] = fx, fz, math.hypot(fx, fz)
    at = 3 * n_hinges
    for c in range(cylinder_force.shape[0]):
        out[at + c] = cylinder_force[c]
    at += cylinder_force.shape[0]
    out[at] = implement_load
    at += 1
    for j in range(steer_columns.shape[0]):
        out[at + j] = steerability[steer_columns[j]]
    at += steer_columns.shape[0]
    for j in range(capacity.shape[0]):
        out[at + j] = capacity[j]


class PoseTable(NamedTuple):
    """The derivatives of a one-DOF linkage's outputs tabulated over its coordinate θ (the solved value
    of its first input, m or rad; ``budget_table.StrokeTable``): nodes θ = ``origin`` + j·``step``;
    at each node, per load level, a row per source input (the lengths and angles, the pressures, the
    implement mass) of the outputs' derivatives (``raw`` (nodes, levels, rows, n_out), the columns not
    linear in the loads left 0: ``chain_rule`` gives them) and the measured cylinders' forces of each
    level (``forces`` (nodes, levels, K) N): level 0, then level 1 + c with cylinder c's force alone
    changed (the derivatives are affine in those forces at a pose); each node's ``state`` (nodes,)
    (NODE_EMPTY, NODE_FILLED, NODE_FAILED). θ of a pose (``pose_coordinate``): the length of cylinder
    ``cylinder`` (its row of the cylinder values), or (−1) the angle sensor's reading of bodies
    ``angle_first`` and ``angle_second`` (−1: the ground) plus ``angle_offset``, the one nearest
    ``reference`` (rad)."""

    origin: float
    step: float
    raw: np.ndarray
    forces: np.ndarray
    state: np.ndarray
    cylinder: int
    angle_first: int
    angle_second: int
    angle_offset: float
    reference: float


NODE_EMPTY, NODE_FILLED, NODE_FAILED = 0, 1, 2   # a table node's state
NOT_TABULATED = -1   # ``tabulated_budget``'s answer for a pose the table does not serve


@njit(cache=True)
def pose_coordinate(table: PoseTable, cylinder_values: np.ndarray, body_q: np.ndarray) -> float:
    """θ of a pose (``PoseTable``) from its cylinder values (C, 5) and body poses (B, 3) (x, z, θ)."""
    if table.cylinder >= 0:
        return cylinder_values[table.cylinder, 0]
    turned = table.angle_offset
    if table.angle_second >= 0:
        turned += body_q[table.angle_second, 2]
    if table.angle_first >= 0:
        turned -= body_q[table.angle_first, 2]
    return table.reference + (turned - table.reference + math.pi) % (2.0 * math.pi) - math.pi


class SourceColumns(NamedTuple):
    """The sources of a tabulated budget as columns of its contributions: the table row each takes (``rows`` (n_src,):
    a length's, an angle's, a pressure sensor's — a seal friction's through its sensor's — or the implement mass's),
    its u in its input's unit (``scales`` (n_src,), a friction's set per pose) and whether uniform (``uniform``
    (n_src,): ``coverage_factor.coverage_factors``; the signs, a friction's by its motion, are
    ``tabulated_budget``'s ``sign``); the measured cylinders of the table's levels (``cylinders`` (K,), their rows
    of the cylinder values), each one's friction column (``friction_at`` (K,)), seal friction band
    (``friction_share``, ``friction_force`` N, ``friction_breakaway``: as ``error_sources.SealFriction``) and N per
    Pa of its sensor (``per_pascal`` (K,)); the steerability columns of the outputs (``steer_columns``,
    ``output_rows``)."""

    rows: np.ndarray
    scales: np.ndarray
    uniform: np.ndarray
    cylinders: np.ndarray
    friction_at: np.ndarray
    friction_share: np.ndarray
    friction_force: np.ndarray
    friction_breakaway: np.ndarray
    per_pascal: np.ndarray
    steer_columns: np.ndarray


# a cylinder's motion as ``tabulated_budget`` takes it (``error_sources.Motion``)
MOTION_STANDING, MOTION_LIFTING, MOTION_LOWERING = 0, 1, 2


@structref.register
class BudgetProgramType(types.StructRef):
    """numba's type of ``BudgetProgram``: its fields typed as the records and arrays they hold."""

    def preprocess_fields(self, fields: tuple) -> tuple:
        return tuple((name, types.unliteral(typ)) for name, typ in fields)


class BudgetProgram(structref.StructRefProxy):
    """What ``tabulated_budget`` takes of one set of inputs, in one object built once (``budget_program``;
    one pointer to pass, where its three records took ~3 µs at every call): ``table`` a PoseTable,
    ``columns`` the SourceColumns, ``layout`` the OutputLayout, the coverage factors' table
    (``factors``, ``shares``, ``inverse_counts``, ``shift_step``: ``coverage_factor.FactorTable``) and
    the normal's factor. It holds references to the arrays (the table's nodes filled later are seen), not copies."""


structref.define_proxy(BudgetProgram, BudgetProgramType,
                       ["table", "columns", "layout", "factors", "shares", "inverse_counts", "shift_step",
                        "normal_factor"])


@njit(cache=True)
def budget_program(table_fields, columns_fields, layout_fields, factors, shares, inverse_counts, shift_step,
                   normal_factor):
    """The ``BudgetProgram`` of a PoseTable, SourceColumns and OutputLayout as plain tuples of their
    fields (``programs.fields``) and the coverage factors' table."""
    return BudgetProgram(PoseTable(*table_fields), SourceColumns(*columns_fields), OutputLayout(*layout_fields),
                         factors, shares, inverse_counts, shift_step, normal_factor)


@njit(cache=True, error_model="numpy")
def tabulated_budget(program, hinge_force, cylinder_values, body_q, implement_load, steerability, capacity, motions,
                     sign, summary, contributions):
    """The budget of one pose from ``program.table`` (``program``: a ``BudgetProgram``), in one call: its coordinate θ
    (``pose_coordinate`` of its cylinder values (C, 5) and body poses (B, 3)); its outputs into ``summary[0]`` (y0,
    n_out; ``summary`` (5, n_out): one array to pass and allocate where five took ~0.1 µs and more each) from its
    hinge forces (H, 2) N, cylinder forces, implement load N, steerability and capacity rows (``_output_row``); each
    measured cylinder's seal friction by its motion (``motions`` (K,), MOTION_* codes; K <= n_out) into the first K
    of ``summary[4]`` N: u = band/√3, the band share·|F| + force, standing times the breakaway
    (``error_sources.SealFriction.standard_uncertainty``'s rule: kept apart, a compiled call;
    test_uncertainty_table.py holds the two equal); ``sign`` (n_src,) each column's sign at these motions (read
    only: built once per set of motions); the two nodes' rows at the measured cylinders' forces (affine in them),
    interpolated linearly in θ, the chain rule (``chain_rule``), times each source's u into ``contributions``
    (n_out, n_src); the standard uncertainties into ``summary[1]`` (u), the coverage factors (``coverage_factors``)
    into ``summary[2]`` (k, the 95 % interval's) and ``summary[3]`` (a verdict's bound's).

    Returns the node below θ (≥ 0) when done; NOT_TABULATED where θ is beyond the table, a node next to it failed or
    a seal friction is 0; −2 − j where node j or j + 1 is not filled yet (fill them, call again)."""
    table, columns = program.table, program.columns
    y0, u, k, tail, friction_u = summary[0], summary[1], summary[2], summary[3], summary[4]
    theta = pose_coordinate(table, cylinder_values, body_q)
    position = (theta - table.origin) / table.step
    if not (position >= 0.0 and position < table.state.shape[0] - 1):
        return NOT_TABULATED
    node = int(math.floor(position))
    for j in range(node, node + 2):
        if table.state[j] == NODE_EMPTY:
            return -2 - node
        if table.state[j] != NODE_FILLED:
            return NOT_TABULATED
    n_src = columns.rows.shape[0]
    scales = columns.scales.copy()
    for c in range(columns.cylinders.shape[0]):
        band = columns.friction_share[c] * abs(cylinder_values[columns.cylinders[c], 1]) + columns.friction_force[c]
        if motions[c] == MOTION_STANDING:
            band *= columns.friction_breakaway[c]
        friction_u[c] = band / math.sqrt(3.0)
        if not friction_u[c] > 0.0:
            return NOT_TABULATED
        scales[columns.friction_at[c]] = friction_u[c] / columns.per_pascal[c]
    _output_row(hinge_force, cylinder_values[:, 1], implement_load, steerability, capacity, columns.steer_columns, y0)
    raw, levels = table.raw, table.forces
    n_rows, n_out = raw.shape[2], raw.shape[3]
    a = position - node
    d = np.zeros((n_rows, n_out))
    n_cylinders = columns.cylinders.shape[0]
    at_level = np.empty(n_cylinders)   # each measured force's place between the node's two load levels
    for t in range(2):
        j, weight = node + t, a if t else 1.0 - a
        for c in range(n_cylinders):
            force, span = cylinder_values[columns.cylinders[c], 1], levels[j, 1 + c, c] - levels[j, 0, c]
            at_level[c] = (force - levels[j, 0, c]) / span
        for r in range(n_rows):
            for o in range(n_out):
                value = raw[j, 0, r, o]
                for c in range(n_cylinders):
                    value += at_level[c] * (raw[j, 1 + c, r, o] - raw[j, 0, r, o])
                d[r, o] += weight * value
    chain_rule(d, y0, program.layout)
    for s in range(n_src):
        for o in range(n_out):
            contributions[o, s] = d[columns.rows[s], o] * scales[s]
    for o in range(n_out):
        total = 0.0
        for s in range(n_src):
            total += contributions[o, s] * contributions[o, s]
        u[o] = math.sqrt(total)
    coverage_factors(contributions, columns.uniform, sign, program.factors, program.shares, program.inverse_counts,
                     program.shift_step, program.normal_factor, k, tail)
    return node
