"""The closed-form pose of a chain of dyads (mechanics/chain.py, kernels.chain_pose).

Oracles: the loop-closure equations themselves (``kernels.residual_jacobian``: every hinge gap and
every driving input's row zero at the chain's pose), the assembly branch of the general solver
(the sign of each loop's block of the constraint Jacobian, ``Kinematics.branch``), and the pose the
general solver finds by Newton from the reference pose (``Kinematics.newton``, no chain involved).
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from linkage_monitor.mechanics import Solver, kernels, load_mechanism, load_preset, preset_names
from linkage_monitor.mechanics.chain import ANGLE, CYLINDER, RRR
from support.fixtures import FIXTURES

MECHANISMS = ([load_preset(name) for name in preset_names()]
              + [load_mechanism(f) for f in sorted(FIXTURES.glob("*.yaml"))])
KINEMATICS = {m.name: Solver(m).kin for m in MECHANISMS}
NOT_A_CHAIN = {"triad"}   # test/fixtures/triad.yaml: a class-III group, no dyads
CHAINS = [name for name in KINEMATICS if name not in NOT_A_CHAIN]


@pytest.mark.parametrize("name", CHAINS)
def test_every_shipped_mechanism_is_a_chain_driven_by_as_many_inputs_as_it_has_degrees_of_freedom(name: str) -> None:
    kin = KINEMATICS[name]
    kinds = kin.chain_int[:, 0]
    placed = [b for row in kin.chain_int for b in ((row[1], row[5]) if row[0] == RRR else (row[1],))]
    assert sorted(placed) == list(range(kin.n // 3)), kin.chain_steps   # every moving body once
    _, jac = kin.residual_jacobian(kin.q_ref[None], kin.reference_inputs()[None])
    hinge_rows = 2 * kin.hinge_att.shape[1]
    dof = kin.n - np.linalg.matrix_rank(jac[0, :hinge_rows])
    assert np.count_nonzero((kinds == ANGLE) | (kinds == CYLINDER)) == dof


def _inputs(kin, stretch: float, turn: float) -> np.ndarray:
    """Inputs near the reference pose: lengths × stretch, angles + turn (rad)."""
    s = kin.reference_inputs().copy()
    nc = kin.cyl_att.shape[1]
    s[:nc] *= stretch
    s[nc:] += turn
    return s


@settings(max_examples=40, deadline=None)
@given(name=st.sampled_from(CHAINS), stretch=st.floats(0.95, 1.05), turn=st.floats(-0.15, 0.15))
def test_the_chain_pose_closes_every_hinge_and_meets_its_driving_inputs_on_the_reference_branch(
        name: str, stretch: float, turn: float) -> None:
    kin = KINEMATICS[name]
    s = _inputs(kin, stretch, turn)
    q, ok = kernels.chain_pose(s, kin.n, *kin.geometry[:2], kin.chain_int, kin.chain_float)
    newton_q, newton_phi, _ = kin.newton(kin.q_ref[None], s[None])   # the general solver, from the reference pose
    if not ok:   # out of reach: then the general solver cannot close these inputs either
        assert not np.abs(newton_phi).max() < 1e-9
        return
    phi, jac = kin.residual_jacobian(q[None], s[None])
    driving = [r for r in kin.drive_rows if r >= 2 * kin.hinge_att.shape[1]]
    assert np.abs(phi[0, :2 * kin.hinge_att.shape[1]]).max() < 1e-12   # m
    assert np.abs(phi[0, driving]).max(initial=0.0) < 1e-12
    assert kin.on_branch(jac)[0]
    newton_on_branch = kin.on_branch(kin.residual_jacobian(newton_q, s[None])[1])[0]
    if kin.m == kin.n and np.abs(newton_phi).max() < 1e-12 and newton_on_branch:
        wrapped = newton_q[0].copy()
        wrapped[2::3] = q[2::3] + np.remainder(wrapped[2::3] - q[2::3] + np.pi, 2 * np.pi) - np.pi
        np.testing.assert_allclose(q, wrapped, atol=1e-9)


def test_a_cylinder_beyond_reach_is_reported_not_placed() -> None:
    kin = KINEMATICS["belarus_1221"]
    s = kin.reference_inputs() * np.array([3.0, 1.0])   # the lift cylinder three times its length
    _, ok = kernels.chain_pose(s, kin.n, *kin.geometry[:2], kin.chain_int, kin.chain_float)
    assert not ok


def test_a_class_three_group_has_no_chain_and_places_nothing() -> None:
    """The triad does not decompose: no steps, and the chain does not claim a pose (an empty chain
    returned all bodies at the origin as placed, and Newton started there instead of from the
    tangent prediction)."""
    kin = KINEMATICS["triad"]
    assert kin.chain_int.shape[0] == 0 and kin.chain_steps == []
    _, ok = kernels.chain_pose(kin.reference_inputs(), kin.n, *kin.geometry[:2], kin.chain_int, kin.chain_float)
    assert not ok


REDUNDANT = [name for name in CHAINS if KINEMATICS[name].m > KINEMATICS[name].n]


@settings(max_examples=40, deadline=None)
@given(name=st.sampled_from(REDUNDANT), stretch=st.floats(0.95, 1.05), misread=st.floats(-0.03, 0.03))
def test_the_fit_along_the_chain_finds_the_closed_pose_newton_finds_over_all_coordinates(
        name: str, stretch: float, misread: float) -> None:
    """Redundant sensors that disagree (angles off by ``misread`` rad): ``kernels.chain_fit`` (Gauss-
    Newton over the chain's driving inputs, derivatives by differences) and ``Kinematics.newton``
    (Gauss-Newton over every coordinate, hinges held by ``closed_step``) reach the same pose."""
    kin = KINEMATICS[name]
    s = _inputs(kin, stretch, 0.0)
    q_chain, ok = kernels.chain_pose(s, kin.n, *kin.geometry[:2], kin.chain_int, kin.chain_float)
    assert ok
    nc = kin.cyl_att.shape[1]
    angle_rows = kin.residual_jacobian(q_chain[None], s[None])[0][0, 2 * kin.hinge_att.shape[1] + nc:]
    readings = s.copy()
    readings[nc:] = s[nc:] + angle_rows / kin.lc + misread   # the angles the strokes' pose shows, misread
    (att_body, att_ref, _, cyl_att, angle_body, angle_reference, lc) = kin.geometry
    q, closed, converged = kernels.chain_fit(readings, kin.n, att_body, att_ref, cyl_att, angle_body, angle_reference,
                                             lc, kin.chain_int, kin.chain_float, 25)
    assert closed and converged
    newton_q, _, _ = kin.newton(q_chain[None], readings[None])
    phi, _ = kin.residual_jacobian(q[None], readings[None])
    assert np.abs(phi[0, :2 * kin.hinge_att.shape[1]]).max() < 1e-12   # m: every hinge closed
    difference = q - newton_q[0]
    difference[2::3] = np.remainder(difference[2::3] + np.pi, 2 * np.pi) - np.pi   # rotations: the same modulo 2π
    np.testing.assert_allclose(difference, 0.0, atol=1e-10)


@pytest.mark.parametrize("name", CHAINS)
def test_a_batch_of_chain_poses_is_on_the_branch_and_closure_the_jacobians_give(name: str) -> None:
    """``solve_poses`` takes a chain's pose (closed form; fitted along the chain where sensors are
    redundant) as it is, on_branch by the chain's reference sides, without a Jacobian unless the
    condition number is asked for. Oracle: at every pose it returns, the Jacobian and Φ of
    ``residual_jacobian`` — its loop signs (``Kinematics.on_branch``) decide the branch, its
    condition number is the one returned. The inputs sweep ±25 % of every length and ±0.6 rad of
    every angle (poses out of reach included where a cylinder drives, disagreeing sensors where
    they are redundant)."""
    kin = KINEMATICS[name]
    rng = np.random.default_rng(7)
    n_pose = 400
    nc = kin.cyl_att.shape[1]
    s = np.repeat(kin.reference_inputs()[None], n_pose, axis=0)
    s[:, :nc] *= rng.uniform(0.75, 1.25, (n_pose, nc))
    s[:, nc:] += rng.uniform(-0.6, 0.6, (n_pose, s.shape[1] - nc))
    start = kin.reference
    args = (start.q[-1:], start.s[-1:], s, 25, kin.program)
    q, phi, cond, on_branch = kernels.solve_poses(*args, with_condition=True)
    q_plain, phi_plain, cond_plain, on_branch_plain = kernels.solve_poses(*args, with_condition=False)
    phi_at_q, jac_at_q = kin.residual_jacobian(q, s)
    closed = np.abs(phi[:, :2 * kin.hinge_att.shape[1]]).max(axis=1) <= 1e-9 * kin.lc
    assert closed.sum() > n_pose // 4
    np.testing.assert_allclose(phi[closed], phi_at_q[closed], rtol=0, atol=1e-14)
    np.testing.assert_array_equal(on_branch[closed], kin.on_branch(jac_at_q[closed]))
    np.testing.assert_allclose(cond[closed], [kernels.condition(j, kin.column_scale) for j in jac_at_q[closed]],
                               rtol=1e-12)
    np.testing.assert_array_equal(q_plain, q)
    np.testing.assert_array_equal(phi_plain, phi)
    np.testing.assert_array_equal(on_branch_plain, on_branch)
    assert np.isnan(cond_plain).all()
