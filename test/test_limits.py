"""Plausibility limits (mechanics.limits): defaults from the geometry hold every valid reading of
the presets, refuse the readings a linkage cannot produce, compare angles modulo 2π, and the
file's own `measurements.limits` wins."""

from __future__ import annotations

import copy
import math

import numpy as np
import pytest

from linkage_monitor.mechanics import MechanismFileError, load_preset, mechanism_from_dict, preset_names
from linkage_monitor.mechanics.capacity import stroke_mechanism
from linkage_monitor.mechanics.constants import ATMOSPHERIC_PRESSURE
from linkage_monitor.mechanics.limits import MIN_ABSOLUTE_PRESSURE, RELIEF_FACTOR, input_limits
from linkage_monitor.mechanics.results import angle_readings
from linkage_monitor.mechanics import Solver


@pytest.mark.parametrize("preset", preset_names())
def test_reference_inputs_are_inside_their_limits(preset):
    mech = load_preset(preset)
    limits = input_limits(mech)
    ref = mech.reference_inputs
    for group in ("cylinders", "angles"):
        for name, value in ref.get(group, {}).items():
            assert limits[name].check(value) is None, (name, value, limits[name])
    for name, gauge in ref.get("pressures", {}).items():
        assert limits[name].check(gauge + 101325.0) is None   # limits hold absolute pressures


def test_belarus_stroke_of_the_paper_and_its_angles_are_inside():
    """Popov 2009 Table 1 runs the stroke S from 0.515 m to 0.715 m."""
    mech = load_preset("belarus_1221")
    limits = input_limits(mech)
    strokes = np.linspace(0.515, 0.715, 30)
    batch = Solver(stroke_mechanism(mech)).solve_batch(cylinders={"lift_cylinder": strokes})
    angles = angle_readings(mech, batch)["lift_arm_angle"]
    assert all(limits["lift_cylinder"].check(s) is None for s in strokes)
    for a in angles:   # as computed, as a sensor in [-pi, pi) reports it, and as one in [0, 2pi)
        for reported in (a, (a + math.pi) % (2 * math.pi) - math.pi, a % (2 * math.pi)):
            assert limits["lift_arm_angle"].check(reported) is None, reported
    assert "outside" in limits["lift_cylinder"].check(1.5)
    centre = 0.5 * (limits["lift_arm_angle"].lo + limits["lift_arm_angle"].hi)
    assert "outside" in limits["lift_arm_angle"].check(centre + math.pi)   # the far side of the circle
    assert "not an angle" in limits["lift_arm_angle"].check(3e220)
    assert "outside" in limits["lift_cap_pressure"].check(0.0)           # a dead transducer
    assert "outside" in limits["lift_cap_pressure"].check(1e12)


def test_the_files_limits_win_and_are_validated():
    mech = load_preset("belarus_1221")
    raw = copy.deepcopy(dict(mech.raw))
    raw["measurements"]["limits"] = {"lift_cylinder": [0.53, 0.72]}
    limit = input_limits(mechanism_from_dict(raw))["lift_cylinder"]
    assert (limit.lo, limit.hi, limit.source) == (0.53, 0.72, "file")
    raw["measurements"]["limits"] = {"lift_cylinder": [0.8, 0.5]}
    with pytest.raises(MechanismFileError, match="limits.lift_cylinder"):
        mechanism_from_dict(raw)
    raw["measurements"]["limits"] = {"rockshaft": [0.0, 1.0]}
    with pytest.raises(MechanismFileError, match="not a measurement"):
        mechanism_from_dict(raw)


@pytest.mark.parametrize("preset", preset_names())
def test_a_pressure_sent_in_kpa_as_pa_is_below_the_limit_of_a_cylinder_with_a_relief_pressure(preset):
    """With a relief pressure the lower limit is 1e-3 of the upper one (RELIEF_FACTOR x relief + 1 atm):
    every pressure the circuit can hold, its kPa sent as Pa, falls below it, and the refusal says so;
    the reference pressure (gauge, + 1 atm) and 0 gauge stay inside."""
    mech = load_preset(preset)
    limits = input_limits(mech)
    for p in mech.measurements.pressures:
        limit, relief = limits[p.name], mech.cylinder(p.cylinder).relief_pressure
        if not relief:
            assert limit.lo == MIN_ABSOLUTE_PRESSURE   # without a relief pressure the circuit's range is unknown
            continue
        assert limit.hi == pytest.approx(RELIEF_FACTOR * relief + ATMOSPHERIC_PRESSURE, rel=1e-15)
        assert limit.lo == pytest.approx(1e-3 * limit.hi, rel=1e-15)
        absolute = mech.reference_inputs.get("pressures", {}).get(p.name, 0.0) + ATMOSPHERIC_PRESSURE
        assert limit.check(absolute) is None and limit.check(ATMOSPHERIC_PRESSURE) is None
        problem = limit.check(absolute * 1e-3)
        assert problem is not None and "looks like kPa sent as Pa?" in problem, problem
