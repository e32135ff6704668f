"""The error budget from a stroke's table (mechanics.budget_table, ``kernels.tabulated_budget``) against
the same budget from the pose's own moved poses (``UncertaintyModel(tabulate=False)``, held to the
per-source oracle and to Monte Carlo by test_uncertainty_moved_poses.py and test_uncertainty.py).

- on every one-DOF preset the table serves the poses of its scenario (but those whose load is a weak
  inference), with the same sources, values and coverage shapes, and contributions within the
  interpolation's error: TABLE_TOLERANCE of the output's largest contribution;
- the values are the pose's own, bit for bit (the table gives derivatives, never a published number);
- a linkage of more than one degree of freedom has no table: its budgets are the moved poses', exactly;
- a pose beyond the table's reach takes the moved poses.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from linkage_monitor.mechanics import kernels, preset_names
from linkage_monitor.mechanics.budget_table import one_dof
from linkage_monitor.mechanics.error_sources import Motion
from linkage_monitor.mechanics.reduced import LOAD_AMPLIFICATION_WARN
from linkage_monitor.mechanics.uncertainty import UncertaintyModel
from oracles.monte_carlo import sample_poses

# Linear interpolation between nodes TABLE_STEP apart errs by step²/8 of the derivative's curvature
# along the stroke: measured worst 0.74 % of an output's largest contribution over 20 poses of each
# one-DOF preset (belarus_1221's lift capacity at the implement's cg against the lift-arm angle's
# bias, where that capacity turns fastest), 0.3 % on ttz1080_base_change next to its weak inferences
TABLE_TOLERANCE = 0.02

ONE_DOF = ["belarus_1221", "drill_coulter", "ttz1080_base_change"]


def _cell(stroke, theta: float, result) -> int:
    """The table's node below ``theta`` when its cell is filled (filled from ``result`` first), else −1."""
    j = math.floor((theta - stroke.table.origin) / stroke.table.step)
    if not 0 <= j < len(stroke.table.state) - 1:
        return -1
    stroke.fill(j, result)
    return j if stroke.table.state[j] == stroke.table.state[j + 1] == kernels.NODE_FILLED else -1


def _tabulated(um: UncertaintyModel, inputs, pose) -> bool:
    """Whether the table serves this pose."""
    plan = um._plan(inputs)
    if plan.stroke is None or pose.result.load_amplification > LOAD_AMPLIFICATION_WARN:
        return False
    return _cell(plan.stroke, plan.stroke.theta(pose.result), pose.result) >= 0


def test_the_one_dof_presets_are_the_tabulated_ones() -> None:
    found = [name for name in preset_names() if one_dof(sample_poses(name, 1, np.random.default_rng(1)).model)]
    assert found == ONE_DOF


@pytest.mark.parametrize("preset", ONE_DOF)
def test_the_table_gives_the_moved_poses_budget_within_its_interpolation_error(preset) -> None:
    poses = sample_poses(preset, 20, np.random.default_rng(3))
    table, moved = UncertaintyModel(poses.model), UncertaintyModel(poses.model, tabulate=False)
    served = 0
    for motion in (Motion.STANDING, Motion.LIFTING, Motion.LOWERING):
        for inputs, pose in poses.poses:
            served += _tabulated(table, inputs, pose)
            a = table.budget(inputs, pose.result, pose.machine, motion)
            b = moved.budget(inputs, pose.result, pose.machine, motion)
            assert [s.name for s in a.sources] == [s.name for s in b.sources]
            assert [s.u for s in a.sources] == [s.u for s in b.sources]
            assert np.array_equal(a.values, b.values, equal_nan=True)
            assert np.array_equal(a.uniform, b.uniform) and np.array_equal(a.sign, b.sign)
            assert a.motions == b.motions
            assert np.array_equal(np.isnan(a.contributions), np.isnan(b.contributions))
            scale = np.max(np.abs(np.nan_to_num(b.contributions)), axis=1, keepdims=True, initial=0.0)
            with np.errstate(invalid="ignore"):   # an infinite contribution (no load: the reserve) in both
                off = np.abs(np.nan_to_num(a.contributions - b.contributions)) > TABLE_TOLERANCE * scale + 1e-12
            assert not off.any(), [(a.outputs[o].name, a.sources[s].name) for o, s in np.argwhere(off)]
            np.testing.assert_allclose(a.u, b.u, rtol=TABLE_TOLERANCE, atol=1e-12)
    weak = sum(pose.result.load_amplification > LOAD_AMPLIFICATION_WARN for _, pose in poses.poses)
    assert served == 3 * (len(poses.poses) - weak) > 0


@pytest.mark.parametrize("preset", sorted(set(preset_names()) - set(ONE_DOF)))
def test_a_linkage_of_more_degrees_of_freedom_takes_the_moved_poses(preset) -> None:
    poses = sample_poses(preset, 3, np.random.default_rng(4))
    table, moved = UncertaintyModel(poses.model), UncertaintyModel(poses.model, tabulate=False)
    for inputs, pose in poses.poses:
        assert not _tabulated(table, inputs, pose)
        a = table.budget(inputs, pose.result, pose.machine)
        b = moved.budget(inputs, pose.result, pose.machine)
        assert np.array_equal(a.contributions, b.contributions, equal_nan=True)


def test_a_pose_beyond_the_tables_reach_takes_the_moved_poses() -> None:
    poses = sample_poses("belarus_1221", 1, np.random.default_rng(5))
    inputs, pose = poses.poses[0]
    um = UncertaintyModel(poses.model)
    stroke = um._plan(inputs).stroke
    assert stroke is not None
    origin, step, count = stroke.table.origin, stroke.table.step, stroke.table.raw.shape[0]
    assert _cell(stroke, origin - step, pose.result) == -1
    assert _cell(stroke, origin + (count - 0.5) * step, pose.result) == -1
    assert _cell(stroke, stroke.theta(pose.result), pose.result) >= 0
