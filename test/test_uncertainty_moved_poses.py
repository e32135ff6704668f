"""The error budget's moved poses, solved in one compiled call each from the one before
(``UncertaintyModel.budget`` without its stroke tables, ``Solver.solve_moved``), against the per-source oracle
(test/oracles/per_source_budget.py: one ``MachineModel.solve`` per moved pose from the pose itself):
the same contributions but for Newton's convergence tolerance, at poses of every preset; and the
same where the compiled call does not take the inputs (rates given: each moved pose by
``MachineModel.solve``)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from linkage_monitor.mechanics import preset_names
from linkage_monitor.mechanics.error_sources import Motion
from linkage_monitor.mechanics.reduced import LOAD_AMPLIFICATION_WARN
from linkage_monitor.mechanics.uncertainty import UncertaintyModel
from oracles.monte_carlo import sample_poses
from oracles.per_source_budget import per_source_contributions

# Newton stops at a constraint residual of ~1e-13 of the linkage's size: a moved pose started from
# another moved pose differs from one started from the pose by that much, over a step of ≥ 1e-6
RTOL = 1e-6


def _agree(budget, oracle, weak: bool = False) -> None:
    """Every contribution within RTOL of its output's largest (NaN where the oracle's is); at a weak
    inference (``weak``) an output may be unbounded as well, every contribution NaN (the pole within
    reach: test/test_uncertainty_pole.py holds that verdict to its own oracle): not compared."""
    unbounded = np.isnan(budget.contributions).all(axis=1, keepdims=True) if weak else False
    assert np.array_equal(np.isnan(budget.contributions), np.isnan(oracle) | unbounded)
    oracle = np.where(unbounded, np.nan, oracle)
    scale = np.max(np.abs(np.nan_to_num(oracle)), axis=1, keepdims=True, initial=0.0)
    with np.errstate(invalid="ignore"):
        off = np.abs(budget.contributions - oracle) > RTOL * scale + 1e-12
    assert not np.any(off & ~np.isnan(oracle)), np.argwhere(off)


def _without_mass(um, budget):
    """``budget`` without the implement mass (a heavier implement: solved on its own, as before)."""
    if um.sources.implement_mass > 0.0 and um.mech.implement is not None:
        budget.contributions = budget.contributions[:, :-1]
        budget.sources = budget.sources[:-1]
    return budget


@pytest.mark.parametrize("preset", preset_names())
def test_moved_poses_in_one_call_agree_with_one_solve_each(preset) -> None:
    poses = sample_poses(preset, 3, np.random.default_rng(7))
    um = UncertaintyModel(poses.model, tabulate=False)
    for motion in (Motion.STANDING, Motion.LIFTING):
        for inputs, pose in poses.poses:
            budget = _without_mass(um, um.budget(inputs, pose.result, pose.machine, motion))
            assert budget.sources, preset
            _agree(budget, per_source_contributions(um, inputs, pose.result, budget),
                   pose.result.load_amplification > LOAD_AMPLIFICATION_WARN)


def test_inputs_the_compiled_call_does_not_take() -> None:
    poses = sample_poses("belarus_1221", 2, np.random.default_rng(8))
    um = UncertaintyModel(poses.model, tabulate=False)
    for inputs, _ in poses.poses:
        moving = replace(inputs, rates={name: 0.01 for name in inputs.cylinders})
        pose = poses.model.solve(moving)
        assert um.model.solver.solve_moved(moving, pose.result, um.model.program, um._plan(moving).inputs_moved) is None
        budget = _without_mass(um, um.budget(moving, pose.result, pose.machine))
        _agree(budget, per_source_contributions(um, moving, pose.result, budget))
