"""The fast paths of the solver: LAPACK helpers for one matrix (oracle: numpy.linalg), and a live
node's single-pose solves that start from the previous pose (oracle: virtual work)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from linkage_monitor.mechanics import Inputs, Solver, load_mechanism
from linkage_monitor.mechanics.linalg import det_sign_and_condition, inverse_and_condition, solve_square
from test_mechanics_oracles import FIXTURES, virtual_work

H = 1e-5  # m, finite-difference step in the stroke


@settings(max_examples=40, deadline=None)
@given(n_pose=st.sampled_from([1, 3]), k=st.integers(2, 8), seed=st.integers(0, 2**31))
def test_linalg_helpers_match_numpy(n_pose: int, k: int, seed: int) -> None:
    rng = np.random.default_rng(seed)
    a = rng.standard_normal((n_pose, k, k)) + 0.5 * k * np.eye(k) * rng.choice([-1.0, 1.0], (n_pose, 1, 1))
    b = rng.standard_normal((n_pose, k))
    np.testing.assert_allclose(solve_square(a, b), np.linalg.solve(a, b[..., None])[..., 0], rtol=1e-9, atol=1e-12)
    # one matrix shared by several right-hand sides (the tangent predictor's case)
    np.testing.assert_allclose(solve_square(a[:1], b), np.linalg.solve(a[0], b.T).T, rtol=1e-9, atol=1e-12)
    sign, cond = det_sign_and_condition(a)
    np.testing.assert_array_equal(sign, np.sign(np.linalg.det(a)))
    np.testing.assert_allclose(cond, np.linalg.cond(a, 1), rtol=1e-9)
    inv, cond2 = inverse_and_condition(a)
    np.testing.assert_allclose(inv, np.linalg.inv(a), rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(cond2, np.linalg.cond(a, 1), rtol=1e-9)


@pytest.mark.parametrize("n_pose", [1, 2])
def test_linalg_helpers_on_a_singular_matrix(n_pose: int) -> None:
    a = np.tile(np.array([[1.0, 2.0], [2.0, 4.0]]), (n_pose, 1, 1))  # rank 1
    sign, cond = det_sign_and_condition(a)
    assert np.all(sign == 0.0) and np.all(cond > 1e12)  # σ_min is 0 up to round-off: far above any dead-centre limit
    b = np.tile([1.0, 2.0], (n_pose, 1))                                # in the range: pinv solves it
    np.testing.assert_allclose(np.einsum("nij,nj->ni", a, solve_square(a, b)), b, atol=1e-12)


def test_live_stroke_from_previous_pose_satisfies_virtual_work() -> None:
    """A node's sequence of single solves (slow stroke, then a jump back) gives the cylinder force
    that virtual work predicts from cold batched kinematics at the same strokes."""
    mech = load_mechanism(FIXTURES / "hitch.yaml")
    live = Solver(mech)
    length0 = live.kin.reference_inputs()[0]
    lengths = length0 + np.concatenate([0.03 * np.sin(np.linspace(0.0, 3.0, 30)), [-0.04, 0.0]])
    forces, previous = [], None
    for x in lengths:   # each solve warm-starts from the previous one, as the node's
        previous = live.solve(Inputs(cylinders={"lift_cylinder": float(x)}), previous=previous)
        forces.append(previous.cylinders["lift_cylinder"].force)
    forces = np.array(forces)
    cold = Solver(mech)
    plus, minus, centre = (cold.solve_batch(cylinders={"lift_cylinder": lengths + d}) for d in (H, -H, 0.0))
    assert np.all(plus.status == 0) and np.all(minus.status == 0)
    # F·dL + Σ load·dp = 0 for a pushing cylinder force F (principle of virtual work)
    expected = -virtual_work(mech, plus, minus, centre, H)
    np.testing.assert_allclose(forces, expected, rtol=1e-6)


def test_warm_start_and_cold_start_give_the_same_pose() -> None:
    """The pose does not depend on where Newton started (the reference pose's assembly branch)."""
    mech = load_mechanism(FIXTURES / "four_bar.yaml")
    solver = Solver(mech)
    length0 = solver.kin.reference_inputs()[0]
    res = None
    for x in length0 * (1.0 + 0.02 * np.sin(np.arange(20))):
        res = solver.solve(Inputs(cylinders={"drive": float(x)}), previous=res)
        cold = solver.solve(Inputs(cylinders={"drive": float(x)}))
        for name, pt in res.points.items():
            np.testing.assert_allclose(pt, cold.points[name], atol=1e-12)

