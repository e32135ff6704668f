"""The statics in reduced coordinates: equilibrium along the chain of dyads (``chain.py``) from the
outermost step inward, with no linear system, and each step's transmission measure."""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba import njit, prange

from ..chain import (A_BODY, A_BODY2, A_END, A_JOINT1, A_JOINT2, A_OTHER, A_PARENT, A_PARENT2, BODY, BODY2,
                     CYLINDER, KIND, RRR, STEP_HINGE, STEP_HINGE2, STEP_JOINT)
from ..programs import ReducedProgram, StaticsProgram
from .equilibrium import _add_generalized, _known_loads, _member_axes, _term_force
from .threads import PARALLEL_PARTS, _parallel


@njit(cache=True)
def _sine_between(ux: float, uz: float, vx: float, vz: float) -> float:
    """|sin| of the angle between two vectors: |u × v| / (|u|·|v|) (NaN when either is zero)."""
    return abs(ux * vz - uz * vx) / (math.sqrt(ux * ux + uz * uz) * math.sqrt(vx * vx + vz * vz))


@njit(cache=True)
def step_transmission(p: np.ndarray, row: np.ndarray) -> float:
    """The transmission measure of one chain step at attachment positions p (K, 2) m, in [0, 1]:
    RRR: |sin μ|, μ the transmission angle between its two links at their common hinge H (the
    angle A1–H–A2, A1 and A2 the links' pivots on placed bodies); CYLINDER: |sin| of the angle
    between the cylinder's line and the arm's radius from the pivot to the cylinder end (the
    cylinder's moment arm about the pivot over that radius); ANGLE: NaN (no transmission)."""
    if row[KIND] == RRR:
        hx, hz = p[row[A_JOINT1], 0], p[row[A_JOINT1], 1]
        return _sine_between(hx - p[row[A_PARENT], 0], hz - p[row[A_PARENT], 1],
                             hx - p[row[A_PARENT2], 0], hz - p[row[A_PARENT2], 1])
    if row[KIND] == CYLINDER:
        ex, ez = p[row[A_END], 0], p[row[A_END], 1]
        return _sine_between(ex - p[row[A_PARENT], 0], ez - p[row[A_PARENT], 1],
                             ex - p[row[A_OTHER], 0], ez - p[row[A_OTHER], 1])
    return math.nan


@njit(cache=True)
def transmission_pose(p: np.ndarray, chain_int: np.ndarray, sine: np.ndarray) -> int:
    """Each step's ``step_transmission`` at positions p (K, 2) into sine (S,); returns the step
    with the smallest (the pose's measure), −1 when no step has one (angle-driven steps only)."""
    weakest = -1
    for k in range(chain_int.shape[0]):
        sine[k] = step_transmission(p, chain_int[k])
        if not math.isnan(sine[k]) and (weakest < 0 or sine[k] < sine[weakest]):
            weakest = k
    return weakest


@njit(cache=True)
def transmission_batch(p: np.ndarray, chain_int: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``transmission_pose`` of N poses p (N, K, 2): per step |sin| (N, S + 1) in
    ``solve_reduced_statics``' layout (the free load's column NaN: it depends on the statics), the
    weakest step (N,)."""
    n_steps = chain_int.shape[0]
    sine = np.full((p.shape[0], n_steps + 1), math.nan)
    weakest = np.empty(p.shape[0], dtype=np.int64)
    for i in range(p.shape[0]):
        weakest[i] = transmission_pose(p[i], chain_int, sine[i, :n_steps])
    return sine, weakest


@njit(cache=True)
def smallest_sine(sine: np.ndarray, weakest: int) -> float:
    """The pose's transmission measure from its measures' |sin| (``_reduced_pose``): that of the
    weakest, 1 when none has one, 0 when the weakest's is undefined (a free load doing no work)."""
    if weakest < 0:
        return 1.0
    value = sine[weakest]
    return 0.0 if math.isnan(value) else min(value, 1.0)


# The batch loop of a per-pose function, written out (as rows.batch_outputs' is): a compiled function
# given another as an argument is compiled again at every start (numba keeps no cache of it).
@njit(cache=True)
def smallest_sines(sine: np.ndarray, weakest: np.ndarray) -> np.ndarray:
    """``smallest_sine`` of N poses: sine (N, measures), weakest (N,)."""
    out = np.empty(weakest.shape[0])
    for i in range(weakest.shape[0]):
        out[i] = smallest_sine(sine[i], weakest[i])
    return out


@njit(cache=True)
def _wrench_about(g: np.ndarray, body: int, ax: float, az: float, lc: float) -> tuple[float, float, float]:
    """The loads on ``body`` gathered in g ([Fx, Fz, M/lc] per body, M about the origin) as (Fx, Fz) N
    and their moment (N·m) about the point (ax, az) m: M − (a × F)."""
    fx, fz = g[3 * body], g[3 * body + 1]
    return fx, fz, g[3 * body + 2] * lc - (ax * fz - az * fx)


@njit(cache=True)
def _hinge_force(u: np.ndarray, hinge_cols: np.ndarray, att_body: np.ndarray, hinge_att: np.ndarray, h: int,
                 body: int, fx: float, fz: float) -> None:
    """Hinge h's force (fx, fz) N on ``body`` into u, as the statics report it: on bodies[1] from bodies[0]."""
    sign = 1.0 if att_body[hinge_att[1, h]] == body else -1.0
    u[hinge_cols[h, 0]], u[hinge_cols[h, 1]] = sign * fx, sign * fz


@njit(cache=True)
def _pivot_reaction(g: np.ndarray, u: np.ndarray, p: np.ndarray, lc: float, att_body: np.ndarray,
                    hinge_att: np.ndarray, hinge_cols: np.ndarray, h: int, body: int, a_parent: int, fx: float,
                    fz: float) -> None:
    """``body``'s loads summing to (fx, fz) N are held at hinge h by its placed parent: the hinge's
    force on ``body`` is −(fx, fz) (ΣF = 0), and (fx, fz) goes on to the parent at ``a_parent``."""
    _hinge_force(u, hinge_cols, att_body, hinge_att, h, body, -fx, -fz)
    parent = att_body[a_parent]
    if parent >= 0:
        _add_generalized(g, 3 * parent, p[a_parent, 0], p[a_parent, 1], fx, fz, lc)


@njit(cache=True, error_model="numpy")
def _reverse_pass(g: np.ndarray, u: np.ndarray, p: np.ndarray, axes: np.ndarray, lc: float, att_body: np.ndarray,
                  hinge_att: np.ndarray, chain_int: np.ndarray, hinge_cols: np.ndarray, step_col: np.ndarray,
                  step_member: np.ndarray, step_sign: np.ndarray) -> float:
    """Equilibrium of one pose step by step from the outermost step inward (reverse placement
    order), for the loads g (n_eq,) ([Fx, Fz, M/lc] per body; the reactions found are added to the
    placed bodies as they are found): the step's unknowns into u (the statics layout's columns).

    - RRR (B1 pivoted at A1, B2 at A2, hinged to each other at H): moments about A1 of B1 and
      about A2 of B2 give the joint force J on B1 (2×2, Cramer):
      (H − A1) × J = −M1, (H − A2) × J = M2, det = (H − A1) × (H − A2) = |HA1|·|HA2|·sin μ;
      then the pivots' forces from ΣF: −(F1 + J) on B1, −(F2 − J) on B2 (Popov 2009's hand solution,
      the moment about each dyad's hinges).
    - CYLINDER with an unknown force (B pivoted at A, the cylinder on B's end E): the moment about A,
      M + (E − A) × f·e = 0, e the unit force on B per newton: f = −M / ((E − A) × e); its other end
      takes −f·e; the pivot's force from ΣF.
    - ANGLE, or CYLINDER with a measured force (already among the known loads): the pivot's force
      from ΣF; the moment about the pivot is left over (no actuator holds it): returned, the
      closing equation ``_reduced_pose`` makes vanish.

    Returns the closing step's moment (N·m), 0 without one (at most one: ``ReducedStatics``' rule).
    """
    closing = 0.0
    for k in range(chain_int.shape[0] - 1, -1, -1):
        row = chain_int[k]
        body = row[BODY]
        ax, az = p[row[A_BODY], 0], p[row[A_BODY], 1]
        fx, fz, moment = _wrench_about(g, body, ax, az, lc)
        if row[KIND] == RRR:
            body2 = row[BODY2]
            a2x, a2z = p[row[A_BODY2], 0], p[row[A_BODY2], 1]
            f2x, f2z, moment2 = _wrench_about(g, body2, a2x, a2z, lc)
            r1x, r1z = p[row[A_JOINT1], 0] - ax, p[row[A_JOINT1], 1] - az
            r2x, r2z = p[row[A_JOINT2], 0] - a2x, p[row[A_JOINT2], 1] - a2z
            det = r1x * r2z - r1z * r2x
            jx = (-moment * r2x - r1x * moment2) / det
            jz = (-r1z * moment2 - r2z * moment) / det
            _hinge_force(u, hinge_cols, att_body, hinge_att, row[STEP_JOINT], body, jx, jz)
            _pivot_reaction(g, u, p, lc, att_body, hinge_att, hinge_cols, row[STEP_HINGE], body, row[A_PARENT],
                            fx + jx, fz + jz)
            _pivot_reaction(g, u, p, lc, att_body, hinge_att, hinge_cols, row[STEP_HINGE2], body2, row[A_PARENT2],
                            f2x - jx, f2z - jz)
            continue
        if row[KIND] == CYLINDER and step_col[k] >= 0:
            ex, ez = step_sign[k] * axes[step_member[k], 0], step_sign[k] * axes[step_member[k], 1]
            force = -moment / ((p[row[A_END], 0] - ax) * ez - (p[row[A_END], 1] - az) * ex)
            u[step_col[k]] = force
            fx, fz = fx + force * ex, fz + force * ez
            other = row[A_OTHER]
            if att_body[other] >= 0:
                _add_generalized(g, 3 * att_body[other], p[other, 0], p[other, 1], -force * ex, -force * ez, lc)
        else:
            closing = moment
        _pivot_reaction(g, u, p, lc, att_body, hinge_att, hinge_cols, row[STEP_HINGE], body, row[A_PARENT], fx, fz)
    return closing


# equilibrium.StaticsJob's loads again: a record holding a record cannot enter numba's parallel loop, and
# these write the transmission where those write the condition number.
class ReducedJob(NamedTuple):
    """A batch of ``solve_reduced_statics`` (``_reduced_pose``): what it writes — u (N,
    n_unknowns), the residual (N,) N·m, each measure's |sin| (N, S + 1), the weakest (N,), the free
    load's amplification (N,), member axes (N, M, 2) and lengths (N, M) m —, and the loads it
    balances, as ``equilibrium.StaticsJob`` (which writes the condition number instead)."""

    u: np.ndarray
    residual: np.ndarray
    sine: np.ndarray
    weakest: np.ndarray
    amplification: np.ndarray
    axes: np.ndarray
    lengths: np.ndarray
    p: np.ndarray
    member_force: np.ndarray
    accel: np.ndarray
    alpha: np.ndarray
    has_accel: bool


def solve_reduced_statics(p: np.ndarray, member_force: np.ndarray, accel: np.ndarray, alpha: np.ndarray,
                          has_accel: bool, n_unknowns: int, layout: StaticsProgram, reduced: ReducedProgram
                          ) -> tuple[np.ndarray, ...]:
    """``solve_statics`` in reduced coordinates: the same unknowns u (N, n_unknowns) for the same
    loads (arguments as there; ``layout``: ``StaticsLayout.program``), found along the chain of
    dyads (``_reverse_pass``) with no linear system. ``reduced``: ``ReducedStatics.program``.

    Returns u, the equilibrium residual (N,) N·m (the closing equation's moment left over; 0
    without one), the transmission (N, S + 1): each step's |sin| (``step_transmission``) then the
    free load's (``_reduced_pose``; NaN without one), the weakest of them (N,) (S: the free load;
    −1: none), the free load's amplification (N,) (``_reduced_pose``), member unit axes (N, M, 2)
    and lengths (N, M) m.
    """
    n_pose = p.shape[0]
    n_members = member_force.shape[1]
    job = ReducedJob(u=np.empty((n_pose, n_unknowns)), residual=np.empty(n_pose),
                     sine=np.empty((n_pose, reduced.chain_int.shape[0] + 1)), weakest=np.empty(n_pose, dtype=np.int64),
                     amplification=np.empty(n_pose), axes=np.empty((n_pose, n_members, 2)),
                     lengths=np.empty((n_pose, n_members)), p=p, member_force=member_force, accel=accel, alpha=alpha,
                     has_accel=bool(has_accel))
    (_reduced_parallel if _parallel(n_pose) else _reduced_serial)(n_pose, job, layout, reduced)
    return job.u, job.residual, job.sine, job.weakest, job.amplification, job.axes, job.lengths


@njit(cache=True)
def _reduced_work(layout: StaticsProgram, reduced: ReducedProgram, n_unknowns: int) -> np.ndarray:
    """Room for ``_reduced_pose``'s loads and unknowns: a row per load case (the known loads, and
    λ = 1 alone with a free load), the n_eq loads then the unknowns."""
    return np.empty((2 if reduced.free_col >= 0 else 1, layout.n_eq + n_unknowns))


@njit(cache=True, error_model="numpy")
def _reduced_pose(i, job: ReducedJob, layout: StaticsProgram, reduced: ReducedProgram, work: np.ndarray):
    """Pose i of ``solve_reduced_statics``, written into the job's outputs; ``work``: room for its
    loads and unknowns (``_reduced_work``), overwritten.

    The statics are linear in the loads: with a free load λ (``free_col`` ≥ 0: a contact's normal
    force, the implement's vertical load, a cylinder that drives no step), the chain is solved for
    the known loads and for λ = 1 alone (superposition), and λ makes the closing step's moment
    vanish: λ = −M_known / M_unit.

    The free load's transmission, as a cylinder step's: its moment arm about the closing step's
    pivot A over the radius from A to its point P (to the farther of its points on moving bodies),
    |sin| = |M_unit| / (|e|·|P − A|), e its force per unit λ — for a load on the closing step's own
    body the sine of the angle between its line and that radius; through the chain M_unit is the
    load's virtual work per unit rotation of the closing step (1 when larger than the radius). At
    0 the load does no work on the motion the closing equation balances, and it is not determined:
    a static dead centre of the general path that no link's transmission shows.

    Where the closing step is a cylinder whose force is measured, the free load is inferred from
    that force (the linkage holds it whatever its size): its amplification, N of load per N of the
    cylinder's force, is |∂λ/∂F| = |m / M_unit|, m the cylinder's moment about the closing pivot per
    N of its force on the step's body (its other end on a body already placed, as a chain's cylinder
    step has it); infinite where M_unit is 0: the load is not determined. NaN otherwise (no free
    load, or one closed by an angle-driven step: a reaction, not an inference).
    """
    u_out, residual, sine, weakest, axes, p = job.u, job.residual, job.sine, job.weakest, job.axes, job.p
    amplification = job.amplification
    lc, t_col = layout.lc, layout.t_col
    chain_int, free_col, closing_step = reduced.chain_int, reduced.free_col, reduced.closing_step
    _member_axes(i, axes, job.lengths, p, layout.member_att)
    n_steps = chain_int.shape[0]
    n_cases = work.shape[0]   # the known loads; λ = 1 alone (with a free load)
    n_eq = layout.n_eq
    work[:, :] = 0.0
    loads, u = work[:, :n_eq], work[:, n_eq:]
    _known_loads(loads[0], i, job, layout)
    size, radius = 0.0, 0.0   # |e| N per unit λ; |P − A| m
    if free_col >= 0:
        pivot = chain_int[closing_step, A_BODY]
        for t in range(t_col.shape[0]):
            if t_col[t] == free_col:
                fx, fz = _term_force(t, axes[i], layout.t_const, layout.t_member, layout.t_sign)
                px, pz = p[i, layout.t_att[t], 0], p[i, layout.t_att[t], 1]
                _add_generalized(loads[1], 3 * layout.t_body[t], px, pz, fx, fz, lc)
                size = math.sqrt(fx * fx + fz * fz)
                radius = max(radius, math.hypot(px - p[i, pivot, 0], pz - p[i, pivot, 1]))
    closing_known = _reverse_pass(loads[0], u[0], p[i], axes[i], lc, reduced.att_body, reduced.hinge_att, chain_int,
                                  reduced.hinge_cols, reduced.step_col, reduced.step_member, reduced.step_sign)
    closing_unit = 0.0 if n_cases == 1 else _reverse_pass(
        loads[1], u[1], p[i], axes[i], lc, reduced.att_body, reduced.hinge_att, chain_int, reduced.hinge_cols,
        reduced.step_col, reduced.step_member, reduced.step_sign)
    weakest[i] = transmission_pose(p[i], chain_int, sine[i, :n_steps])
    amplification[i] = math.nan
    if free_col >= 0:
        closing = chain_int[closing_step]
        if closing[KIND] == CYLINDER:   # the free load inferred from the closing cylinder's measured force
            member, sign, at = reduced.step_member[closing_step], reduced.step_sign[closing_step], closing[A_BODY]
            arm = ((p[i, closing[A_END], 0] - p[i, at, 0]) * sign * axes[i, member, 1]
                   - (p[i, closing[A_END], 1] - p[i, at, 1]) * sign * axes[i, member, 0])
            amplification[i] = abs(arm / closing_unit) if closing_unit != 0.0 else math.inf
        free = -closing_known / closing_unit
        for j in range(u_out.shape[1]):
            u_out[i, j] = u[0, j] + free * u[1, j]
        u_out[i, free_col] = free
        residual[i] = abs(closing_known + free * closing_unit)
        sine[i, n_steps] = min(abs(closing_unit) / (size * radius), 1.0)
        if weakest[i] < 0 or not sine[i, n_steps] >= sine[i, weakest[i]]:
            weakest[i] = n_steps
    else:
        u_out[i] = u[0]
        residual[i] = 0.0
        sine[i, n_steps] = math.nan


# a pair per kernel, as assembly's (why: there)
@njit(cache=True)
def _reduced_serial(n_pose: int, job: ReducedJob, layout: StaticsProgram, reduced: ReducedProgram) -> None:
    work = _reduced_work(layout, reduced, job.u.shape[1])
    for i in range(n_pose):
        _reduced_pose(i, job, layout, reduced, work)


@njit(cache=True, parallel=True)
def _reduced_parallel(n_pose: int, job: ReducedJob, layout: StaticsProgram, reduced: ReducedProgram) -> None:
    n_parts = min(n_pose, PARALLEL_PARTS)   # each part its own work room
    for part in prange(n_parts):
        work = _reduced_work(layout, reduced, job.u.shape[1])
        for i in range(part * n_pose // n_parts, (part + 1) * n_pose // n_parts):
            _reduced_pose(i, job, layout, reduced, work)
