"""Coverage of the error budget against a truth the monitor does not see (``sim.coverage``, a small
version of ``bench/bench_uncertainty_coverage.py``): the sensors' errors drawn from the declared sources
(``sim.sensor_errors``), the monitor fed the erroneous readings only, each step's 95 % intervals held to
the same mechanics solved from the true inputs.

At this size (60 runs of 4 steps per preset) the steps of a run, and the outputs of a step, share the
run's biases and seal level: the coverage of a bias-dominated group varies like the share of 60 draws,
whose 0.1 % quantile is 51 of 60 (85 %) for an honest 95 % (Binomial(60, 0.95)); the floor, 80 %, leaves
room for a group's outputs that are not covered together. Intervals half as wide as they should be would
cover 67 % of a normal error; twice as wide, the mean half-width would be about 3.9 times the RMS error
(1.96 for honest ones). Zero steps passed whose true value is beyond a limit is the goal at any size."""

from __future__ import annotations

import numpy as np
import pytest

from linkage_monitor.mechanics import load_preset, preset_names
from linkage_monitor.mechanics.error_sources import DEFAULT_STROKE_RESOLUTION, SensorError
from linkage_monitor.sim.coverage import LIMITS, study
from linkage_monitor.sim.sensor_errors import RunErrors, SensorErrorSimulator, TrueInputs, motion_signs

RUNS, STEPS = 60, 4
COVERAGE_FLOOR = 0.80   # below the 0.1 % quantile of Binomial(60, 0.95) as a share (module docstring)
SHARPNESS_CEILING = 3.0   # between honest intervals (1.96) and ones twice too wide (3.9)
# outputs that exist at some poses only: ttz1080_base_change's lift capacity (and reserve) where its cylinder
# lifts the cg at all (machine.py: NaN where pushing it lowers the cg, Akhmetov & Usmanov 2018's front axle),
# near the load's line through pivot O, where the capacity grows without bound and many are unbounded
DEFINED_IN_PART = {"lift capacity", "lift reserve"}
# the share of an output kind's values the monitor may call unbounded: few, but on ttz1080_base_change, whose
# lift scenario holds its cylinder at 0.715 m, 1.5 mm (5 standard uncertainties of its stroke sensor) from the
# load's line through pivot O at 0.7135 m, 29 % of the time (sim.telemetry.simulate(..., "lift") at 100 Hz):
# there the pole is within reach (uncertainty.POLE_REACH_MAX: within 6.2 u) and every inferred output unbounded
UNBOUNDED_SHARE = {"ttz1080_base_change": 0.35}


@pytest.fixture(scope="module")
def tallies():
    rng = np.random.default_rng(51)
    return {preset: study(load_preset(preset), RUNS, STEPS, rng, streams_per_scenario=1) for preset in preset_names()}


@pytest.mark.parametrize("preset", preset_names())
def test_the_95_percent_intervals_hold_the_truth(tallies, preset: str) -> None:
    tally = tallies[preset]
    assert tally.runs == RUNS and tally.steps == RUNS * STEPS
    assert tally.untrue == 0   # the stretches are chosen where the truth solves
    # a reading the monitor refuses (a chamber near vacuum whose drawn bias reads below it) is an ERROR, not OK:
    # rare with the default transducer
    assert tally.refused <= 0.05 * tally.steps
    assert {"hinge force"} <= set(tally.groups)
    for group, g in tally.groups.items():
        # an output the monitor says it cannot bound (its first order fails over the interval, near a load's
        # line through a pivot: docs/dead-centre.md) is not compared, and is rare
        if group in DEFINED_IN_PART and preset == "ttz1080_base_change":
            continue   # a few values, where its capacity grows without bound towards pivot O (docs/accuracy.md)
        assert g.unbounded <= UNBOUNDED_SHARE.get(preset, 0.05) * (g.steps + g.unbounded), (group, g.unbounded)
        assert g.steps + g.unbounded >= RUNS * STEPS - tally.refused, group
        assert g.coverage >= COVERAGE_FLOOR, f"{group}: coverage {g.coverage:.1%}"
        assert not np.isfinite(g.sharpness) or g.sharpness <= SHARPNESS_CEILING, f"{group}: sharpness {g.sharpness:.2f}"


@pytest.mark.parametrize("preset", preset_names())
def test_no_step_passed_whose_truth_is_beyond_a_limit(tallies, preset: str) -> None:
    assert tallies[preset].wrong_with_ok == {}


@pytest.mark.parametrize("preset", preset_names())
def test_no_step_passed_whose_judged_value_is_unbounded(tallies, preset: str) -> None:
    """A value judged against a limit whose u the monitor calls unbounded (ttz1080_base_change's lift reserve
    wherever it exists: within reach of pivot O's pole, docs/accuracy.md) is a WARN, never OK."""
    assert tallies[preset].unbounded_ok == {}


def test_ttz1080s_lift_reserve_is_unbounded_and_never_ok() -> None:
    """ttz1080_base_change's lift reserve exists only where its lift capacity does, within 1.5 mm of the
    load's line through pivot O (the pole at a stroke of 0.7135 m, the stroke's end at 0.715 m; elsewhere
    pushing the cylinder lowers the front half-frame: NaN), within reach of the pole: every such value is
    unbounded, and each is a WARN. 40 runs of the lift (holding the stroke's end 29 % of its time) meet some."""
    tally = study(load_preset("ttz1080_base_change"), 40, 30, np.random.default_rng(5), streams_per_scenario=1)
    assert tally.unbounded_value.get("lift_reserve", 0) > 0
    assert tally.unbounded_ok == {}
    assert all(tally.groups[group].steps == 0 for group in DEFINED_IN_PART if group in tally.groups)


def test_the_limits_are_exercised() -> None:
    """belarus_1221's overload scenario takes the true steerability margin and lift reserve below their
    limits: the zero above is over steps that could have been wrong."""
    tally = study(load_preset("belarus_1221"), 8, 10, np.random.default_rng(7), streams_per_scenario=1)
    assert tally.beyond.get("steerability_margin", 0) > 0
    assert {limit.output for limit in LIMITS} >= set(tally.beyond)
    assert tally.wrong_with_ok == {}


def test_readings_carry_the_drawn_bias_and_the_resolution_step() -> None:
    mech = load_preset("belarus_1221")
    simulator = SensorErrorSimulator(mech)
    truth = TrueInputs({"cylinders": {"lift_cylinder": np.array([0.5351, 0.5351, 0.5372])},
                        "angles": {"lift_arm_angle": np.array([0.1, 0.1, 0.11])},
                        "pressures": {"lift_cap_pressure": np.array([1.0e7, 1.0e7, 1.0e7])}}, {"lift_cylinder": 0.0})
    run = RunErrors(bias={"lift_cylinder": 0.0, "lift_arm_angle": 0.002, "lift_cap_pressure": 5.0e4},
                    level={"lift_cylinder": 0.0}, held_sign={"lift_cylinder": 1.0})
    read = simulator.readings(truth, run, np.random.default_rng(0))
    # the default stroke sensor: 1 mm steps, no bias or noise (error_sources.DEFAULT_STROKE)
    assert simulator.sources.sensor("lift_cylinder", "cylinders") == SensorError(
        resolution=DEFAULT_STROKE_RESOLUTION, origin=simulator.sources.sensor("lift_cylinder", "cylinders").origin)
    np.testing.assert_allclose(read["cylinders"]["lift_cylinder"], [0.535, 0.535, 0.537], atol=1e-15)
    np.testing.assert_allclose(read["angles"]["lift_arm_angle"], [0.102, 0.102, 0.112])   # angle: bias only
    np.testing.assert_allclose(read["pressures"]["lift_cap_pressure"], 1.005e7)   # seal level 0: no friction


def test_each_run_draws_where_the_resolution_steps_fall() -> None:
    """The grid's zero of a quantized sensor is drawn once per run within ±step/2: a cylinder standing at one
    length reads an error that differs from run to run, uniform over ±step/2 across runs (as the budget's
    resolution source declares), where a grid at zero would read the same error in every run."""
    mech = load_preset("belarus_1221")
    simulator = SensorErrorSimulator(mech)
    rng = np.random.default_rng(3)
    truth = TrueInputs({"cylinders": {"lift_cylinder": np.full(2, 0.5354)}}, {"lift_cylinder": 0.0})
    errors = []
    for _ in range(2000):
        run = simulator.draw(rng)
        assert abs(run.grid["lift_cylinder"]) <= DEFAULT_STROKE_RESOLUTION / 2
        read = simulator.readings(truth, run, rng)["cylinders"]["lift_cylinder"]
        assert read[0] == read[1]   # on the run's grid: the same reading while the length stands
        steps = (read[0] - run.grid["lift_cylinder"]) / DEFAULT_STROKE_RESOLUTION
        assert steps == pytest.approx(round(steps), abs=1e-6)
        errors.append(read[0] - 0.5354)
    errors = np.array(errors) / DEFAULT_STROKE_RESOLUTION
    assert np.abs(errors).max() <= 0.5 + 1e-9
    # uniform over ±1/2 step: standard deviation 1/√12 = 0.289 (2,000 draws: ±0.005 at 1 sigma)
    assert np.std(errors) == pytest.approx(1 / np.sqrt(12), abs=0.02) and abs(np.mean(errors)) < 0.03


def test_seal_friction_follows_the_motion() -> None:
    """Moving: the level times the band, against the motion; standing: the breakaway band, the sign of
    the last motion (the run's drawn sign before any)."""
    mech = load_preset("belarus_1221")
    simulator = SensorErrorSimulator(mech)
    seal = simulator.sources.seal_friction("lift_cylinder")
    p = 1.0e7
    lengths = np.array([0.50, 0.50, 0.51, 0.52, 0.52, 0.51, 0.51])
    truth = TrueInputs({"cylinders": {"lift_cylinder": lengths},
                        "pressures": {"lift_cap_pressure": np.full(7, p)}}, {"lift_cylinder": 0.0})
    run = RunErrors(bias={}, level={"lift_cylinder": 0.5}, held_sign={"lift_cylinder": -1.0})
    added = simulator.friction_pressures(truth, run)["lift_cap_pressure"]
    kinetic = 0.5 * seal.share * p   # the band share·|F| read back as a pressure: share·p
    np.testing.assert_allclose(added, kinetic * np.array([-seal.breakaway, -seal.breakaway, 1.0, 1.0,
                                                          seal.breakaway, -1.0, -seal.breakaway]))
    signs = motion_signs(None, 3, 1.0)
    assert not signs.moving.any() and (signs.sign == 1.0).all()
