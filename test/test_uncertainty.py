"""The declared error sources and their first-order propagation (mechanics.error_sources,
mechanics.uncertainty; docs/accuracy.md).

- the ``error_sources`` block: defaults for a file without it, a datasheet class read as a uniform
  bound (u = class·full_scale/√3), contradictions refused;
- with every source at zero the outputs are the model's own, bit for bit, and every u is 0;
- the load derivatives are exact: the linear outputs do not depend on the step, the chain-rule ones
  (magnitude, ratio, margin, reserve) equal a fine central difference;
- the pose derivatives' truncation error is small against a Richardson estimate from the step halved;
- first order against Monte Carlo (test/oracles/monte_carlo.py, 2,000 samples of the declared
  sources) at poses of every preset within 10 % (the full study: bench/bench_uncertainty_mc.py);
- ``linkage-monitor solve --uncertainty --json`` lists every output with u and shares.
"""

from __future__ import annotations

import copy
import json
import math
from dataclasses import replace

import numpy as np
import pytest

from linkage_monitor.cli.main import main
from linkage_monitor.mechanics import (Inputs, MechanismFileError, Solver, load_preset,
                                       mechanism_from_dict, preset_names)
from linkage_monitor.mechanics.error_sources import (DEFAULT_PRESSURE, NONE_DECLARED, SQRT3, Motion,
                                                     SealFriction)
from linkage_monitor.mechanics.machine import MachineModel
from linkage_monitor.mechanics.uncertainty import LOAD_STEP_PRESSURE, UncertaintyModel, pose_step
from oracles.monte_carlo import NEGLIGIBLE, comparable, monte_carlo, sample_poses


def _model(mech) -> MachineModel:
    return MachineModel(mech, Solver(mech))


def _belarus_with(block: dict):
    raw = copy.deepcopy(dict(load_preset("belarus_1221").raw))
    raw["error_sources"] = block
    return mechanism_from_dict(raw)


def _reference(mech) -> Inputs:
    return Inputs(**{k: dict(v) for k, v in mech.reference_inputs.items()})


def test_a_file_without_the_block_takes_the_defaults() -> None:
    mech = load_preset("belarus_1221")
    assert not mech.error_sources.declared
    assert mech.error_sources.sensor("lift_cap_pressure", "pressures") == DEFAULT_PRESSURE
    # 0.5 % of 25 MPa as a uniform bound: u = 125 kPa / √3 (error_sources.DEFAULT_PRESSURE's datasheet class)
    assert DEFAULT_PRESSURE.total == pytest.approx(125e3 / math.sqrt(3))


def test_a_declared_block_is_read_in_si_as_standard_uncertainties() -> None:
    mech = _belarus_with({"sensors": {"lift_cap_pressure": {"class": 0.25, "full_scale": 40e6, "noise": 2e4,
                                                            "resolution": 1e4},
                                      "lift_arm_angle": {"accuracy": 0.01}},
                          "cylinders": {"lift_cylinder": {"friction_share": 0.02, "friction_force": 300,
                                                          "breakaway": 2.0}},
                          "implement": {"mass": 40}})
    sources = mech.error_sources
    pressure = sources.sensor("lift_cap_pressure", "pressures")
    assert pressure.components() == pytest.approx({"bias": 0.0025 * 40e6 / SQRT3, "noise": 2e4,
                                                   "resolution": 1e4 / math.sqrt(12)})
    assert sources.sensor("lift_arm_angle", "angles").bias == pytest.approx(0.01 / SQRT3)
    # not listed: the default of its kind
    assert sources.sensor("lift_cylinder", "cylinders").resolution == pytest.approx(1e-3)
    friction = sources.seal_friction("lift_cylinder")
    # moving: 2 % of 10 kN + 300 N; standing: twice that
    assert friction.band(10e3, Motion.LIFTING) == pytest.approx(500.0)
    assert friction.band(-10e3, Motion.STANDING) == pytest.approx(1000.0)
    assert sources.implement_mass == 40


@pytest.mark.parametrize("block, words", [
    ({"sensors": {"lift_cap_pressure": {"bias": 1e4, "accuracy": 2e4}}}, ["lift_cap_pressure", "not both"]),
    ({"sensors": {"lift_cap_pressure": {"class": 0.5}}}, ["full_scale"]),
    ({"sensors": {"lift_cap_pressure": {"bias": -1}}}, ["bias", ">= 0"]),
    ({"cylinders": {"nope": {"friction_share": 0.1}}}, ["nope", "unknown key"]),
    ({"cylinders": {"lift_cylinder": {"breakaway": 0.5}}}, ["breakaway", ">= 1"]),
    ({"sensor": {}}, ["error_sources.sensor", "unknown key"]),
])
def test_a_bad_block_is_refused_by_name(block, words) -> None:
    with pytest.raises(MechanismFileError) as err:
        _belarus_with(block)
    assert all(w in str(err.value) for w in words), err.value


def test_with_every_source_zero_the_outputs_are_the_models_own() -> None:
    plain, zero = load_preset("belarus_1221"), _belarus_with({"defaults": False})
    inputs = _reference(plain)
    a, b = _model(plain).solve(inputs), _model(zero).solve(inputs)
    for field in ("hinge_force", "cylinder_values", "point_xz", "frame_load_forces"):
        assert np.array_equal(getattr(a.result, field), getattr(b.result, field), equal_nan=True)
    assert np.array_equal(a.machine.steerability_row, b.machine.steerability_row, equal_nan=True)
    assert np.array_equal(a.machine.capacity_row, b.machine.capacity_row, equal_nan=True)
    for sources in (zero.error_sources, NONE_DECLARED):
        model = _model(zero)
        budget = UncertaintyModel(model, sources).budget(inputs, b.result, b.machine)
        assert budget.sources == () and np.all(budget.u == 0.0)
        assert np.array_equal(budget.values, UncertaintyModel(model).table.values(b.result, b.machine), equal_nan=True)


def test_load_derivatives_are_exact() -> None:
    mech = load_preset("belarus_1221")
    model = _model(mech)
    um = UncertaintyModel(model)
    inputs = _reference(mech)
    pose = model.solve(inputs)
    y0 = um.table.values(pose.result, pose.machine)
    d = um._load_derivative(inputs, pose.result, y0, "pressures", "lift_cap_pressure")
    # the linear outputs: the same slope from a step 100 times larger
    big = um._linear.derivative(y0, um._solved(model, replace(inputs, pressures={"lift_cap_pressure": 10.132e6 + 1e7}),
                                                pose.result), 1e7)
    linear = [k for k, o in enumerate(um.outputs) if o.kind not in ("hinge_magnitude", "steerability_ratio",
                                                                    "steerability_margin", "lift_reserve")]
    np.testing.assert_allclose(d[linear], big[linear], rtol=1e-9, atol=1e-12)
    # the chain-rule outputs: a central difference of 1 Pa (truncation ~(1 Pa)² · y''', far below 1e-7)
    h = 1.0
    up = um._solved(model, replace(inputs, pressures={"lift_cap_pressure": 10.132e6 + h}), pose.result)
    down = um._solved(model, replace(inputs, pressures={"lift_cap_pressure": 10.132e6 - h}), pose.result)
    central = (up - down) / (2 * h)
    nonlinear = [k for k in range(len(um.outputs)) if k not in linear]
    np.testing.assert_allclose(d[nonlinear], central[nonlinear], rtol=1e-6)
    assert LOAD_STEP_PRESSURE != h and LOAD_STEP_PRESSURE != 1e7


@pytest.mark.parametrize("preset", ["belarus_1221", "ksu1_mower_adapter", "drill_coulter"])
def test_pose_derivative_truncation_error_is_small(preset) -> None:
    """Central difference D(h) against the Richardson estimate R = (4·D(h/2) − D(h)) / 3 (error O(h⁴)):
    |D(h) − R| (the truncation error of D(h), to leading order) below 1 % of the contribution u·|R|
    it scales, for every measured length and angle."""
    mech = load_preset(preset)
    model = _model(mech)
    um = UncertaintyModel(model)
    inputs = _reference(mech)
    pose = model.solve(inputs)
    for kind in ("cylinders", "angles"):
        for name, value in getattr(inputs, kind).items():
            u = um.sources.sensor(name, kind).total
            h = pose_step(u)
            coarse = um._pose_derivative(inputs, pose.result, kind, name, value, h)
            fine = um._pose_derivative(inputs, pose.result, kind, name, value, h / 2)
            richardson = (4 * fine - coarse) / 3
            scale = np.abs(richardson) * u + 1e-9 * np.maximum(1.0, np.abs(um.table.values(pose.result, pose.machine)))
            ok = np.isfinite(richardson)
            assert np.all(np.abs(coarse - richardson)[ok] * u <= 0.01 * scale[ok]), (preset, name)


@pytest.mark.slow
@pytest.mark.parametrize("preset", preset_names())
def test_first_order_agrees_with_monte_carlo(preset) -> None:
    """At 3 poses of each preset, standing (the widest friction band), every output's first-order u
    within 10 % of the standard deviation of 2,000 Monte Carlo samples (sampling error of a standard
    deviation from n samples: 1/√(2n) = 1.6 %), but where the Monte Carlo u is negligible
    (``oracles.monte_carlo.comparable``)."""
    rng = np.random.default_rng(51)
    sampled = sample_poses(preset, 3, rng)
    um = UncertaintyModel(sampled.model)
    measured = 0
    for inputs, pose in sampled.poses:
        budget = um.budget(inputs, pose.result, pose.machine, Motion.STANDING)
        mc = monte_carlo(um, inputs, budget, 2000, rng)
        if mc.truncated:   # a reading near the end of its range: no measure of u (bench: counted)
            continue
        measured += 1
        compared = comparable(budget, mc)
        ratio = budget.u[compared] / mc.u[compared]
        assert compared.sum() >= 0.5 * len(budget.outputs)
        assert np.all(np.abs(ratio - 1.0) < 0.10), (preset, inputs, ratio.min(), ratio.max())
        # the others: negligible both ways (an extremum along the stroke: first order tends to 0)
        small = ~compared & np.isfinite(budget.u) & np.isfinite(mc.u)
        assert np.all(budget.u[small] <= 2 * NEGLIGIBLE * np.maximum(1.0, np.abs(budget.values[small])))
    assert measured >= 2, preset


def test_seal_friction_band_by_motion() -> None:
    mech = load_preset("belarus_1221")
    model = _model(mech)
    inputs = _reference(mech)
    pose = model.solve(inputs)
    um = UncertaintyModel(model)
    standing, lifting = (um.budget(inputs, pose.result, pose.machine, motion) for motion in (Motion.STANDING,
                                                                                            Motion.LIFTING))
    friction = {s.part: s for s in standing.sources}["friction"]
    force = pose.result.cylinders["lift_cylinder"].force
    default = SealFriction(share=0.03, breakaway=1.5)
    assert friction.u == pytest.approx(default.band(force, Motion.STANDING) / SQRT3)
    assert {s.part: s for s in lifting.sources}["friction"].u == pytest.approx(friction.u / 1.5)
    line = standing.line("lift_cylinder.force")
    assert line.dominant == "lift_cylinder seal friction"
    assert sum(line.shares.values()) == pytest.approx(1.0)


def test_solve_uncertainty_json(capsys) -> None:
    assert main(["solve", "--preset", "belarus_1221", "--uncertainty", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)["uncertainty"]
    assert out["motions"] == {"lift_cylinder": "standing"}   # one pose: it stands
    assert {s["name"] for s in out["sources"]} == {"lift_cylinder resolution", "lift_arm_angle bias",
                                                   "lift_cap_pressure bias", "lift_cylinder seal friction"}
    margin = out["outputs"]["steerability_margin"]
    assert margin["unit"] == "-" and margin["u"] > 0 and sum(margin["shares"].values()) == pytest.approx(1.0)
    assert {"P03.fx", "P03.fz", "P03.magnitude", "lift_cylinder.force", "implement_load", "front_axle_load",
            "rear_axle_load", "steerability_ratio", "lift_capacity.hitch_axis", "lift_reserve"} <= set(out["outputs"])


def test_solve_uncertainty_table(capsys) -> None:
    assert main(["solve", "--preset", "belarus_1221", "--uncertainty"]) == 0
    text = capsys.readouterr().out
    assert "standard uncertainty" in text and "seal friction: lift_cylinder standing" in text
    assert any(line.startswith("steerability_margin [-]") and "lift_cylinder seal friction" in line
               for line in text.splitlines())


def test_the_budget_picture_is_a_real_image(tmp_path) -> None:
    """tools/accuracy_plot.py's drawing (viz.budget_plot) of three poses along the stroke."""
    import matplotlib.image

    from linkage_monitor.viz.budget_plot import plot_budget

    mech = load_preset("belarus_1221")
    model = _model(mech)
    um = UncertaintyModel(model)
    budgets = []
    for pressure in (9e6, 10e6, 11e6):
        inputs = replace(_reference(mech), pressures={"lift_cap_pressure": pressure})
        pose = model.solve(inputs)
        budgets.append(um.budget(inputs, pose.result, pose.machine))
    png = tmp_path / "budget.png"
    plot_budget(np.array([0.53, 0.535, 0.54]), budgets, ("implement_load", "steerability_margin"), "S [m]", "t", png)
    image = matplotlib.image.imread(png)
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and image.ndim == 3 and image.shape[0] > 300
    assert image[..., :3].std() > 0.05   # not a blank canvas


def test_an_implement_mass_tolerance_enters_the_configured_weight() -> None:
    """Without a pressure the implement load is the configured weight m·g: a tolerance of 40 kg gives it
    u = 40 kg · g exactly (closed form), the whole of it from the mass."""
    mech = _belarus_with({"implement": {"mass": 40}, "defaults": False})
    model = _model(mech)
    inputs = replace(_reference(mech), pressures={})
    pose = model.solve(inputs)
    line = UncertaintyModel(model).budget(inputs, pose.result, pose.machine).line("implement_load")
    assert line.value == pytest.approx(mech.implement.mass * mech.gravity)
    assert line.u == pytest.approx(40 * mech.gravity, rel=1e-9)
    assert line.shares == {"implement mass": pytest.approx(1.0)}
