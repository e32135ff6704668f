"""Ill-conditioned is not dead centre (docs/dead-centre.md): a load inferred from a measured cylinder
force whose line passes near the pivot of the step that balances it is published with a WARN
``load_inference_weak`` on its amplification (N of load per N of force), not refused; a step of the
linkage itself near a dead centre, or a load that does no work at all, stays an ERROR.

The oracles: the amplification is the derivative of the inferred load with respect to the measured
force, taken from two solves of the same pose (the statics are linear in the loads: exact); the
spared poses' unknowns are the general path's (``StaticsLayout.solve``, one linear system) to the
reduced path's tolerance times the amplification; and a replay of the bundled
ttz1080_base_change_lift with the spare switched off (today's rule before it: every pose whose
smallest transmission is below 1 degree refused) publishes, at every pose it publishes, bit for
bit what the replay with the spare publishes.
"""

from __future__ import annotations

from collections import Counter
from pathlib import Path

import numpy as np
import pytest

from linkage_monitor.mechanics import (Inputs, LinkageError, Solver, general_path, kernels, load_mechanism,
                                       load_preset)
from linkage_monitor.mechanics.machine import MachineModel
from linkage_monitor.mechanics.limits import input_limits
from linkage_monitor.mechanics.reduced import DEAD_CENTRE_TRANSMISSION_DEG, LOAD_AMPLIFICATION_WARN, ReducedStatics
from linkage_monitor.mechanics.uncertainty import UncertaintyModel
from linkage_monitor.monitoring.findings import Code
from linkage_monitor.offline.replay import replay
from support.fixtures import FIXTURES

BAG = Path(__file__).resolve().parent.parent / "bags" / "ttz1080_base_change_lift"
RELATIVE = 1e-9   # of the largest force: the reduced path against the general one (test_reduced_coordinates.py)
# (preset, its force-measured cylinder): the layouts whose free load is inferred from that cylinder's force
INFERRED = [("belarus_1221", "lift_cylinder"), ("ttz1080_base_change", "base_change_cylinder")]


def _poses(preset: str, n: int) -> tuple[Solver, ReducedStatics, np.ndarray]:
    """The solver, the reduced statics of the layout with ``preset``'s cylinder force measured and the
    positions (n, K, 2) of n poses spread over the driving cylinder's stroke where the chain assembles."""
    solver = Solver(load_preset(preset))
    kin = solver.kin
    known = frozenset({dict(INFERRED)[preset]})
    reduced = ReducedStatics(kin, solver._layouts[known])
    limit = input_limits(solver.mech)[kin.input_names[0]]
    positions = []
    for length in np.linspace(limit.lo, limit.hi, n):
        s = kin.reference_inputs()
        s[0] = length
        q, ok = kernels.chain_pose(s, kin.n, *kin.geometry[:2], kin.chain_int, kin.chain_float)
        if ok:
            positions.append(kin.positions(q[None])[0][0])
    return solver, reduced, np.array(positions)


@pytest.mark.parametrize("preset, cylinder", INFERRED)
def test_the_amplification_is_the_derivative_of_the_inferred_load(preset: str, cylinder: str) -> None:
    solver, reduced, p = _poses(preset, 41)
    assert len(p) > 10
    force = np.full((len(p), 1), 50e3)
    one = reduced.solve(p, force, None)
    other = reduced.solve(p, force + 1e3, None)   # 1 kN more: the load changes by 1 kN times the amplification
    column = reduced.free_col
    derivative = np.abs(other.unknowns[:, column] - one.unknowns[:, column]) / 1e3
    assert np.all(np.isfinite(one.amplification))
    np.testing.assert_allclose(one.amplification, derivative, rtol=1e-6)


def test_a_load_closed_by_an_angle_step_is_a_reaction_not_an_inference() -> None:
    """arm_angle.yaml's free load, the force of a cylinder that drives no step, closes an angle step:
    nothing measured is amplified, its amplification is NaN and its transmission stays the verdict."""
    solver = Solver(load_mechanism(FIXTURES / "arm_angle.yaml"))
    kin = solver.kin
    reduced = ReducedStatics(kin, solver._layouts[frozenset()])
    p, _ = kin.positions(kin.q_ref[None])
    assert np.isnan(reduced.solve(p, np.full((1, 1), np.nan), None).amplification).all()


def test_the_spared_poses_are_the_general_paths_solution() -> None:
    """ttz1080_base_change over its stroke: where the inferred load's transmission is below the
    dead-centre angle and the steps' own are not (``general_path.inferred_load_spared``), the reduced
    path's unknowns equal one linear system's to RELATIVE of the largest force times the
    amplification (the error a rounding of the measured force's moment becomes)."""
    solver, reduced, p = _poses("ttz1080_base_change", 4001)
    force = np.full((len(p), 1), 50e3)
    solution = reduced.solve(p, force, None)
    sine_limit = np.sin(np.radians(DEAD_CENTRE_TRANSMISSION_DEG))
    spared = general_path.inferred_load_spared(solution.transmission.sine, solution.transmission.weakest,
                                               solution.amplification, sine_limit)
    assert spared.sum() >= 20   # the stroke passes through the load's line crossing pivot O
    general = reduced.layout.solve(p[spared], force[spared], None)
    largest = np.abs(general.unknowns).max(axis=1, keepdims=True)
    error = np.abs(solution.unknowns[spared] - general.unknowns)
    assert np.all(error <= RELATIVE * largest * np.maximum(1.0, solution.amplification[spared, None]))


def _numbers(pose) -> list[np.ndarray]:
    """Every number a solved pose publishes: its result's arrays and scalars, its machine-level rows."""
    r = pose.result
    return [r.point_xz, r.body_q, r.hinge_force, r.cylinder_values, r.contact_values, r.implement_cg,
            r.frame_load_points, r.frame_load_forces, np.array([r.implement_load, r.residual, r.consistency_residual,
                                                                r.largest_force, r.transmission_angle]),
            pose.machine.steerability_row, pose.machine.capacity_row]


@pytest.mark.slow
def test_the_bag_publishes_the_poses_it_refused_with_a_warn_and_the_rest_bit_for_bit(monkeypatch) -> None:
    spared = replay(BAG, progress=None).steps
    with monkeypatch.context() as patch:   # the rule before: no pose spared
        patch.setattr(general_path, "inferred_load_spared", lambda sine, *_: np.zeros(len(sine), dtype=bool))
        before = replay(BAG, progress=None).steps
    assert len(spared) == len(before)
    codes_before = Counter(f.code for step in before for f in step.findings)
    codes_now = Counter(f.code for step in spared for f in step.findings)
    # 484 of 1,738 refused by the angle rule alone on the bundled bag (docs/dead-centre.md: it lifts
    # through the load's line over pivot O), none now
    assert codes_before[Code.DEAD_CENTRE] > len(before) // 5 and codes_now[Code.DEAD_CENTRE] == 0, (codes_before, codes_now)
    newly = 0
    for now, then in zip(spared, before):
        if then.pose is None:
            if any(f.code is Code.DEAD_CENTRE for f in then.findings):
                newly += 1
                assert now.pose is not None
                amplification = now.pose.result.load_amplification
                warned = any(f.code is Code.LOAD_INFERENCE_WEAK for f in now.findings)
                assert warned == (amplification > LOAD_AMPLIFICATION_WARN), (amplification, now.findings)
            continue
        for x, y in zip(_numbers(now.pose), _numbers(then.pose)):   # every published number, bit for bit
            assert np.array_equal(x, y, equal_nan=True)
        assert [f.code for f in now.findings] == [f.code for f in then.findings]
    assert newly == codes_before[Code.DEAD_CENTRE]
    assert codes_now[Code.LOAD_INFERENCE_WEAK] > 0.9 * newly


def test_near_the_pivot_the_budget_calls_the_inferred_load_unbounded() -> None:
    """Over ttz1080_base_change's stroke with its cap pressure measured: where the amplification is above
    LOAD_AMPLIFICATION_WARN the implement load's first order is checked over its interval, and closest to
    the load's line through pivot O (the largest amplifications) it fails: u NaN, no interval claimed;
    below the threshold every load has a finite u."""
    mech = load_preset("ttz1080_base_change")
    model = MachineModel(mech, Solver(mech))
    budgets = UncertaintyModel(model)
    limit = input_limits(mech)["base_change_cylinder"]
    amplification, bounded = [], []
    for length in np.linspace(limit.lo, limit.hi, 241):
        inputs = Inputs(cylinders={"base_change_cylinder": float(length)}, pressures={"base_change_cap": 8e6})
        try:
            pose = model.solve(inputs)
        except LinkageError:
            continue
        amplification.append(pose.result.load_amplification)
        bounded.append(np.isfinite(budgets.budget(inputs, pose.result, pose.machine).u_of("implement_load")))
    amplification, bounded = np.array(amplification), np.array(bounded)
    weak = amplification > LOAD_AMPLIFICATION_WARN
    assert weak.sum() >= 3 and bounded[~weak].all()
    assert not bounded[np.argmax(amplification)]
