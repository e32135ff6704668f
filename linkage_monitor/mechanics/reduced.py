"""Statics and transmission in reduced coordinates: along the chain of dyads, no linear system.

A mechanism that :func:`.chain.decompose` turns into a chain of steps (ANGLE / CYLINDER / RRR) is
solved as a textbook (and Popov 2009) solves a hitch by hand: from the outermost step inward, the
moment of each step's bodies about its pivots gives the step's unknowns — a 2×2 in closed form per
RRR dyad, a scalar per cylinder — and the force sums give the pivots' reactions
(``kernels.solve_reduced_statics``). The same pass yields each step's transmission measure
(``kernels.step_transmission``): |sin μ| of an RRR dyad's transmission angle μ, the sine of the
angle between a driving cylinder and its arm's radius, and the free load's (below: its moment arm
about the closing step's pivot over its radius; without it a contact or implement load that
stops being determined would go unseen). The pose's measure is the smallest; a pose whose angle
is below DEAD_CENTRE_TRANSMISSION_DEG is a dead centre (``Solver`` still takes the general path
and its condition-number verdict; ``Solver.explain`` says which layouts this module serves).

``ReducedStatics.reason`` is '' when the reduced path serves a set of force-measured cylinders:

1. the mechanism decomposes into a chain (a class-III group does not: triad.yaml);
2. every hinge is closed by a step (none joins two bodies placed already);
3. the statics are square (as many unknowns as equations: not the least squares the general
   path fits when more cylinder forces are measured than it can use); and
4. at most one load is left free by the steps — a contact's normal force, the implement's
   vertical load (a measured cylinder force), the force of a cylinder that drives no step — and
   it is found by the one closing step (an angle-driven step, or a cylinder step whose force is
   measured), whose moment it makes vanish.

Everything else is the general path's (``StaticsLayout.solve``, 3 equations per body in one
linear system, its condition number the dead-centre verdict). Within the rule every load the
general path takes is served, from the same tables (``StaticsLayout.program``): gravity, constant
loads, springs, measured cylinder forces, contacts with friction, kinetostatic inertia loads.
SI units: m, N, N·m.
"""

from __future__ import annotations

from functools import cached_property
from typing import NamedTuple

import numpy as np

from . import chain, kernels
from .kinematics import Kinematics
from .programs import ReducedProgram
from .statics import StaticsLayout

DEAD_CENTRE_TRANSMISSION_DEG = 1.0
"""Degrees: a pose whose smallest transmission angle (its steps' and its free load's) is below this
is a dead centre. From tools/transmission_sweep.py: on dense sweeps of every preset, driven through
each of its dead centres, the poses the condition-number verdict (cond > 1e6) flags all have a
smallest angle of at most 0.033° (ksu1_mower_adapter, ttz1080_base_change; 0.006° to 0.027° for the
others); 1° flags every one of them, with a margin of 30× for mechanisms beyond the presets
(test_reduced_coordinates.py holds the claim on a smaller sweep)."""

# A load inferred from a measured cylinder force (``Result.load_amplification``, N of load per N of
# force) whose amplification exceeds this is a weak inference: a force error (the transducer's, the
# seals' friction) becomes a load error this many times larger. Its line passes near the pivot of the
# step that balances it; the linkage holds it (docs/dead-centre.md). 10 lies above the amplification
# of every pose the bundled bags solve away from that pivot: at most 7.4 on ttz1080_base_change_lift
# outside the poses whose load transmission is below 1 degree (8.3 to 858 within them), 0.16 on the
# belarus_1221 bags, 0.19 on damping_hitch_lift.
LOAD_AMPLIFICATION_WARN = 10.0


class Transmission(NamedTuple):
    """Transmission of N poses along the chain: |sin| (N, S + 1) in [0, 1] per step (NaN for an
    angle-driven step) and, last, the free load's (``kernels.reduced._reduced_pose``; NaN without one or
    without the statics); which of these attains the smallest (N,) (−1: none has a measure); the
    pose's measure as an angle (N,) rad in [0, π/2] (π/2 when none has one, 0 when the free
    load's is undefined: it does no work on any motion)."""

    sine: np.ndarray
    weakest: np.ndarray
    angle: np.ndarray


class ReducedSolution(NamedTuple):
    """``StaticsLayout.solve``'s unknowns in its column order (N, n_unknowns) N, the residual (N,)
    N·m left in the closing equation, the transmission, the free load's amplification (N,) (N of
    load per N of the measured force it is inferred from; NaN where it is not inferred:
    ``kernels.reduced._reduced_pose``), and the members' axes (from end a to end b) and lengths (m)
    as ``StaticsSolution`` has them."""

    unknowns: np.ndarray
    residual: np.ndarray
    transmission: Transmission
    amplification: np.ndarray
    cylinder_axis: np.ndarray
    cylinder_length: np.ndarray
    spring_force: np.ndarray
    spring_axis: np.ndarray


def smallest_sine(sine: np.ndarray, weakest: np.ndarray) -> np.ndarray:
    """The pose's measure (N,) as |sin| in [0, 1]: its weakest step's, 1 without one, 0 where that is
    undefined (``kernels.smallest_sine``, the live path's rule, of N poses)."""
    return kernels.smallest_sines(np.ascontiguousarray(sine, dtype=float),
                                  np.ascontiguousarray(weakest, dtype=np.int64))


def transmission_angle(sine: np.ndarray, weakest: np.ndarray) -> np.ndarray:
    """The pose's measure (N,) rad in [0, π/2]: arcsin of its weakest step's |sin|, π/2 without one."""
    return np.arcsin(smallest_sine(sine, weakest))


def step_names(kin: Kinematics) -> list[str]:
    """A name per chain step for people: an RRR dyad by the angle its links make at their common
    hinge ('P34–P45–P05'), a cylinder step by the cylinder and its pivot, an angle step by its sensor."""
    mech = kin.mech
    hinge_point = [h.point for h in mech.hinges]
    names = []
    for row in kin.chain_int:
        if row[chain.KIND] == chain.RRR:
            names.append(f"{hinge_point[row[chain.STEP_HINGE]]}–{hinge_point[row[chain.STEP_JOINT]]}–"
                         f"{hinge_point[row[chain.STEP_HINGE2]]}")
        elif row[chain.KIND] == chain.CYLINDER:
            names.append(f"{kin.input_names[row[chain.CYLINDER_INPUT]]} about {hinge_point[row[chain.STEP_HINGE]]}")
        else:
            names.append(f"{kin.input_names[row[chain.ANGLE_INPUT]]} about {hinge_point[row[chain.STEP_HINGE]]}")
    return names


def transmission(kin: Kinematics, q: np.ndarray) -> Transmission:
    """The transmission of N poses q (N, n) (``kernels.transmission_batch``); an empty chain: no step."""
    p, _ = kin.positions(q)
    sine, weakest = kernels.transmission_batch(p, kin.chain_int)
    return Transmission(sine, weakest, transmission_angle(sine, weakest))


class ReducedStatics:
    """The reduced-coordinate statics of one mechanism and one set of force-measured cylinders
    (``layout``): which column each step solves, the free load and its closing step, or why the
    general path is needed (``reason``, see the module's rule)."""

    def __init__(self, kin: Kinematics, layout: StaticsLayout) -> None:
        self.kin, self.layout = kin, layout
        self.step_names = step_names(kin)
        mech = kin.mech
        rows = kin.chain_int
        n_steps = rows.shape[0]
        self.step_col = np.full(n_steps, -1, dtype=np.int64)      # CYLINDER with unknown force: its column
        self.step_member = np.full(n_steps, -1, dtype=np.int64)   # CYLINDER: member index (springs then cylinders)
        self.step_sign = np.zeros(n_steps)                        # CYLINDER: +1 rod end on B, −1 base on B
        cylinder_index = {c.name: k for k, c in enumerate(mech.cylinders)}
        closing_steps: list[int] = []
        solved: set[int] = set()
        for k, row in enumerate(rows):
            hinges = [h for h in row[[chain.STEP_HINGE, chain.STEP_HINGE2, chain.STEP_JOINT]] if h >= 0]
            solved |= {int(c) for h in hinges for c in layout.hinge_cols[h]}
            if row[chain.KIND] == chain.RRR:
                continue
            if row[chain.KIND] == chain.CYLINDER:
                j = int(row[chain.CYLINDER_INPUT])
                name = kin.input_names[j]
                self.step_member[k] = layout.n_springs + cylinder_index[name]
                self.step_sign[k] = 1.0 if row[chain.A_END] == kin.cyl_att[1, j] else -1.0
                if name in layout.cyl_col:
                    self.step_col[k] = layout.cyl_col[name]
                    solved.add(layout.cyl_col[name])
                    continue
            closing_steps.append(k)
        free = [c for c in range(layout.n_unknowns) if c not in solved]
        self.free_col = free[0] if len(free) == 1 else -1
        self.closing_step = closing_steps[0] if len(closing_steps) == 1 else -1
        unclosed = [h.name for k, h in enumerate(mech.hinges) if layout.hinge_cols[k, 0] not in solved]
        if n_steps == 0:
            self.reason = "the mechanism does not decompose into a chain of dyads (chain.decompose)"
        elif unclosed:
            self.reason = f"hinges {', '.join(unclosed)} are closed by no step (they join bodies already placed)"
        elif layout.n_unknowns != layout.n_eq:
            self.reason = f"the statics are not square ({layout.n_unknowns} unknowns, {layout.n_eq} equations)"
        elif len(free) != len(closing_steps) or len(free) > 1:
            self.reason = (f"{len(free)} loads left free by the steps for {len(closing_steps)} closing steps "
                           f"(the reduced path takes at most one)")
        else:
            self.reason = ""
        free_name = (f"{layout.columns[self.free_col]} through {self.step_names[self.closing_step]}"
                     if self.free_col >= 0 and self.closing_step >= 0 else "no free load")
        self.measure_names = [*self.step_names, free_name]   # a name per column of Transmission.sine

    @property
    def served(self) -> bool:
        """Whether the reduced path serves this layout (the module's rule)."""
        return not self.reason

    @cached_property
    def program(self) -> ReducedProgram:
        """What ``kernels.solve_reduced_statics`` takes beyond the statics layout (``ReducedProgram``)."""
        kin, layout = self.kin, self.layout
        return ReducedProgram(att_body=kin.geometry.att_body, hinge_att=kin.hinge_att, chain_int=kin.chain_int,
                              hinge_cols=np.ascontiguousarray(layout.hinge_cols, dtype=np.int64),
                              step_col=self.step_col, step_member=self.step_member, step_sign=self.step_sign,
                              free_col=self.free_col, closing_step=self.closing_step)

    def describe(self) -> str:
        """Whether the reduced path serves this layout and why, for people (``linkage-monitor solve --explain``)."""
        known = ", ".join(sorted(self.layout.force_known)) or "none"
        if self.layout.null_space_error is not None:
            return f"cylinder forces measured: {known}: the statics are not determined (no path solves them)"
        if not self.served:
            return f"cylinder forces measured: {known}: general path only ({self.reason})"
        free = (f"; free load {self.layout.columns[self.free_col]} from the moment of step "
                f"'{self.step_names[self.closing_step]}'" if self.free_col >= 0 else "")
        return f"cylinder forces measured: {known}: reduced coordinates serve it, steps {'; '.join(self.step_names)}{free}"

    def solve(self, p: np.ndarray, cylinder_force: np.ndarray, accel: tuple[np.ndarray, np.ndarray] | None
              ) -> ReducedSolution:
        """``StaticsLayout.solve`` (same arguments, same unknowns) in reduced coordinates; only for a
        layout the reduced path serves (``served``)."""
        layout = self.layout
        ns = layout.n_springs
        member_force, lin, alpha, has_accel = layout.kernel_loads(p, cylinder_force, accel)
        u, residual, sine, weakest, amplification, axes, length = kernels.solve_reduced_statics(
            np.ascontiguousarray(p, dtype=float), member_force, lin, alpha, has_accel, layout.n_unknowns,
            layout.program, self.program)
        return ReducedSolution(unknowns=u, residual=residual,
                               transmission=Transmission(sine, weakest, transmission_angle(sine, weakest)),
                               amplification=amplification,
                               cylinder_axis=axes[:, ns:], cylinder_length=length[:, ns:],
                               spring_force=member_force[:, :ns], spring_axis=axes[:, :ns])

