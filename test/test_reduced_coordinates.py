"""Statics in reduced coordinates (mechanics/reduced.py) against the general 15-coordinate path.

The oracle: ``StaticsLayout.solve`` (3 equations per body, one linear system per pose) on the same
pose, the same measured cylinder forces and the same inertia loads; the reduced path must give its
unknowns — hinge reactions, cylinder forces, contact normals, the implement load — to 1e-9 of the
largest of them (the tolerance of the dead-centre decision), over random poses inside each
mechanism's input range (``limits.input_limits``) of every preset and test fixture that decomposes.
The transmission measure is checked against its definition computed from the points by hand, and
the Belarus-1221 hitch (Popov 2009) against its paper's table.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st

from linkage_monitor.mechanics import Solver, kernels, load_mechanism, load_preset, preset_names
from linkage_monitor.mechanics.chain import BODY, CYLINDER, CYLINDER_INPUT, KIND, RRR, STEP_HINGE, STEP_HINGE2, STEP_JOINT
from linkage_monitor.mechanics.limits import input_limits
from linkage_monitor.mechanics.reduced import DEAD_CENTRE_TRANSMISSION_DEG, ReducedStatics, transmission
from support.fixtures import FIXTURES
from transmission_sweep import sweep, table   # tools/transmission_sweep.py

MECHANISMS = {m.name: m for m in [load_preset(name) for name in preset_names()]
              + [load_mechanism(f) for f in sorted(FIXTURES.glob("*.yaml"))]}
SOLVERS = {name: Solver(m) for name, m in MECHANISMS.items()}
NOT_A_CHAIN = {"triad"}   # test/fixtures/triad.yaml: a class-III group (chain.decompose finds no chain)
# (mechanism, force-measured cylinders) the general path keeps, by the rule in reduced.py's docstring
GENERAL = {("damping_hitch", frozenset({"damping_element", "lift_cylinder"})),   # 23 unknowns, 24 equations
           ("four_bar", frozenset({"drive"})),                                    # 8 unknowns, 9 equations
           ("spring_contact", frozenset())}                                       # 4 unknowns, 3 equations
REDUCED = [(name, known) for name, solver in SOLVERS.items() if name not in NOT_A_CHAIN
           for known in solver._layouts if (name, known) not in GENERAL]
RELATIVE = 1e-9    # of the largest force: the decision's tolerance for the reduced path against the general one
DEAD_CENTRE_COND = 1e6   # the general path's verdict (Solver.dead_centre_cond's default): poses beyond it are left out


def _reduced(name: str, known: frozenset[str]) -> ReducedStatics:
    solver = SOLVERS[name]
    return ReducedStatics(solver.kin, solver._layouts[known])


def test_the_triad_does_not_decompose_and_keeps_the_general_path() -> None:
    reduced = _reduced("triad", frozenset())
    assert not reduced.served
    assert "does not decompose" in reduced.reason


@pytest.mark.parametrize("name, known", sorted(GENERAL, key=str))
def test_statics_that_are_not_square_keep_the_general_path(name: str, known: frozenset[str]) -> None:
    reduced = _reduced(name, known)
    assert not reduced.served
    assert "not square" in reduced.reason


def test_every_layout_of_a_chain_outside_the_rule_is_named_here() -> None:
    served = {(name, known) for name, known in REDUCED if _reduced(name, known).served}
    assert served == set(REDUCED), set(REDUCED) - served


def _input_ranges(name: str) -> list[tuple[float, float]]:
    """[lo, hi] (m, rad) of each input: the monitor's plausibility limits (``limits.input_limits``);
    for spring_contact, whose statics need a measured force to be determined (``input_limits``
    raises UnobservableError while sweeping its stroke alone), ±10 % of the reference length."""
    kin = SOLVERS[name].kin
    if name == "spring_contact":
        return [(0.9 * length, 1.1 * length) for length in kin.reference_inputs()]
    limits = input_limits(MECHANISMS[name])
    return [(limits[input_name].lo, limits[input_name].hi) for input_name in kin.input_names]


RANGES = {name: _input_ranges(name) for name, _ in REDUCED}


def _pose(name: str, fractions: list[float]) -> tuple[np.ndarray, bool]:
    """The chain's pose (kernels.chain_pose) for inputs at ``fractions`` of their ranges
    (``_input_ranges``; redundant inputs do not move the chain's pose)."""
    kin = SOLVERS[name].kin
    s = kin.reference_inputs()
    for j, ((lo, hi), t) in enumerate(zip(RANGES[name], fractions)):
        s[j] = lo + t * (hi - lo)
    q, ok = kernels.chain_pose(s, kin.n, *kin.geometry[:2], kin.chain_int, kin.chain_float)
    return q, ok


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.filter_too_much])
@given(case=st.sampled_from(REDUCED), fractions=st.lists(st.floats(0.0, 1.0), min_size=3, max_size=3),
       force=st.floats(-1e5, 1e5), moving=st.booleans(), seed=st.integers(0, 2**16))
def test_the_reduced_path_gives_the_general_paths_reactions_and_cylinder_forces(
        case: tuple[str, frozenset[str]], fractions: list[float], force: float, moving: bool, seed: int) -> None:
    name, known = case
    solver = SOLVERS[name]
    kin, layout = solver.kin, solver._layouts[known]
    q, ok = _pose(name, fractions)
    assume(ok)   # inside the limits but out of reach (the limits are widened past the assembly)
    p, rel = kin.positions(q[None])
    cylinder_force = np.full((1, len(MECHANISMS[name].cylinders)), force)   # N; read for the measured ones only
    accel = None
    if moving:   # kinetostatics (Naumenko et al. 2021): random input rates and accelerations, the inertia loads they give
        rng = np.random.default_rng(seed)
        q_dot, q_ddot = kin.rates(q[None], rng.uniform(-1, 1, (1, kin.n_inputs)), rng.uniform(-5, 5, (1, kin.n_inputs)))
        linear, _ = kin.point_rates(q_ddot, rel)
        _, centripetal = kin.point_rates(q_dot, rel)
        accel = (linear + centripetal, q_ddot[:, 2::3])
    general = layout.solve(p, cylinder_force, accel)
    assume(general.condition[0] <= DEAD_CENTRE_COND)
    reduced = _reduced(name, known).solve(p, cylinder_force, accel)
    largest = np.abs(general.unknowns).max()
    assert np.abs(reduced.unknowns - general.unknowns).max() <= RELATIVE * largest, layout.columns
    assert reduced.cylinder_length == pytest.approx(general.cylinder_length, abs=1e-15)


@pytest.mark.parametrize("name", sorted(set(MECHANISMS) - NOT_A_CHAIN))
def test_the_transmission_measure_is_its_definition_from_the_points(name: str) -> None:
    """|sin| from the reference pose's points by hand: an RRR dyad's angle at its joint between the
    links to its pivots, a cylinder step's angle between the cylinder and the radius pivot → end."""
    kin = SOLVERS[name].kin
    measure = transmission(kin, kin.q_ref[None])
    p, _ = kin.positions(kin.q_ref[None])
    att_ref = {key: p[0, index] for key, index in kin._att.items()}
    mech = MECHANISMS[name]

    def sine(vertex: np.ndarray, a: np.ndarray, b: np.ndarray) -> float:
        u, v = a - vertex, b - vertex
        return abs(float(u[0] * v[1] - u[1] * v[0])) / (np.hypot(*u) * np.hypot(*v))

    for k, row in enumerate(kin.chain_int):
        step = kin.chain_steps[k]
        if row[KIND] == RRR:
            joint = mech.hinges[row[STEP_JOINT]]
            pivots = [mech.hinges[row[STEP_HINGE]], mech.hinges[row[STEP_HINGE2]]]
            by_hand = sine(*(att_ref[(h.bodies[0], h.point)] for h in (joint, *pivots)))
        elif row[KIND] == CYLINDER:
            cylinder = mech.cylinder(kin.input_names[row[CYLINDER_INPUT]])
            pivot = mech.hinges[row[STEP_HINGE]]
            body = mech.moving_bodies[row[BODY]].name
            end, other = ((cylinder.rod_end, cylinder.base) if cylinder.rod_end.body == body
                          else (cylinder.base, cylinder.rod_end))
            by_hand = sine(att_ref[(body, end.point)], att_ref[(body, pivot.point)],
                           att_ref[(other.body, other.point)])
        else:
            assert math.isnan(measure.sine[0, k])   # an angle-driven step has none
            continue
        assert measure.sine[0, k] == pytest.approx(by_hand, rel=1e-12), step
    weakest = measure.weakest[0]
    assert measure.angle[0] == pytest.approx(math.asin(np.nanmin(measure.sine[0])) if weakest >= 0 else math.pi / 2)


def test_popov_cylinder_force_in_the_reference_pose() -> None:
    """belarus_1221 at S = 0.535 m: F_pr = 107.52 kN (Popov 2009, Table 2, first row: docs/belarus-1221-geometry.md;
    the preset's geometry is fitted to that table within 0.1 kN)."""
    solver = SOLVERS["belarus_1221"]
    kin = solver.kin
    layout = solver._layouts[frozenset()]
    p, _ = kin.positions(kin.q_ref[None])
    reduced = ReducedStatics(kin, layout).solve(p, np.full((1, 1), np.nan), None)
    force = reduced.unknowns[0, layout.cyl_col["lift_cylinder"]]
    assert force == pytest.approx(107.52e3, abs=0.1e3)


@pytest.mark.parametrize("angle, expected", [(0.0, math.sqrt(0.5)), (-math.pi / 2, 0.0)])
def test_the_free_loads_transmission_is_its_moment_arm_over_its_radius(angle: float, expected: float) -> None:
    """arm_angle.yaml: the cylinder E-T drives no step, its force is the free load of the angle step
    about O. Reference pose: radius O→T (0, 1), cylinder E→T (1, 1): sin 45°; at −π/2 the cylinder's
    line passes through the pivot (the fixture's own comment: a static dead centre): 0."""
    solver = SOLVERS["arm_angle"]
    kin = solver.kin
    q, ok = kernels.chain_pose(np.array([angle]), kin.n, *kin.geometry[:2], kin.chain_int, kin.chain_float)
    p, _ = kin.positions(q[None])
    reduced = _reduced("arm_angle", frozenset())
    measure = reduced.solve(p, np.full((1, 1), np.nan), None).transmission
    assert measure.weakest[0] == len(reduced.step_names)   # the free load, the only measure
    assert np.nan_to_num(measure.sine[0, -1]) == pytest.approx(expected, abs=1e-12)
    assert reduced.measure_names[-1] == "cylinder 'cyl' force through arm_angle about O"


@pytest.mark.parametrize("preset", preset_names())
def test_the_default_threshold_flags_every_pose_the_condition_number_flags(preset: str) -> None:
    """The sweep table's claim (tools/transmission_sweep.py, at fewer points per line): every pose
    of the swept lines that cond > 1e6 calls a dead centre has a smallest transmission angle below
    DEAD_CENTRE_TRANSMISSION_DEG; and the sweep does reach dead centres."""
    row = sweep(MECHANISMS[preset], points=61)
    assert row.flagged_by_cond > 0
    assert row.missed == 0, row
    assert row.max_angle_cond_flagged < DEAD_CENTRE_TRANSMISSION_DEG


@pytest.mark.slow
def test_the_sweep_table_in_the_docs_is_what_the_sweep_gives() -> None:
    """docs/dead-centre.md's table is exactly what tools/transmission_sweep.py prints (at its default
    4,001 points per line), and no pose the condition number flags is missed on any preset."""
    rows = [sweep(load_preset(name), points=4001) for name in preset_names()]
    doc = (Path(__file__).resolve().parents[1] / "docs" / "dead-centre.md").read_text(encoding="utf-8")
    assert table(rows, DEAD_CENTRE_TRANSMISSION_DEG) in doc, (
        "docs/dead-centre.md's sweep table is stale: paste in what .venv/bin/python tools/transmission_sweep.py prints")
    assert all(row.missed == 0 for row in rows)
