"""Axle loads on the road (linkage_monitor.mechanics.dynamics): the static balance at rest and the dynamic one.

Oracle: the whole tractor-implement unit's equilibrium with d'Alembert's inertia forces, about the
rear wheels' ground contact B (frame x forward, z up, origin B; the Belarus links weightless): each
body k of mass m_k at x_k moving up with a_k = a_B + α·x_k, the tractor's pitch inertia
J = m_tr·x_tr·(L − x_tr) (module docstring), so that
    ΣF: R_A* + R_B* − Σ m_k·(g + a_k) = 0,    ΣM_B: L·R_A* − Σ m_k·(g + a_k)·x_k − J·α = 0,
and at rest (a = α = 0) Popov 2009's L·R_A = P_tr·x_tr + P_cw·x_cw + P_6·x_S6, with the
implement's weight, not the load its bouncing puts on the linkage.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from linkage_monitor.mechanics import Solver, apply_overrides, load_preset
from linkage_monitor.mechanics.capacity import stroke_mechanism
from linkage_monitor.mechanics.dynamics import (BodyAcceleration, PitchAcceleration, RestLoad, imu_body_acceleration,
                                                implement_at_rest, road_balance)
from linkage_monitor.mechanics.kernels import STEERABILITY_COLUMNS
from linkage_monitor.mechanics.machine import MachineModel

STROKE = (0.515, 0.715)  # m, Popov 2009 Table 1's range of S


def _carried(implement_mass: float, load_factor: float, length: float):
    """A transport pose of belarus_1221 whose linkage carries implement_mass·g·load_factor (the
    measured load of a bouncing implement), and its machine model."""
    mech = apply_overrides(stroke_mechanism(load_preset("belarus_1221")),
                           {"implement.mass": implement_mass * load_factor})
    model = MachineModel(mech, Solver(mech))
    return model, model.stroke_poses("lift_cylinder", np.array([length]))


@settings(max_examples=20, deadline=None)
# up to ±4.7 m/s² at the implement (±0.48 g: below dynamics.FALLING, where a measured load is not weighed at rest)
@given(implement_mass=st.floats(200.0, 2500.0), vertical=st.floats(-2.5, 2.5), pitch=st.floats(-1.0, 1.0),
       length=st.floats(*STROKE))
def test_dynamic_axle_loads_balance_the_unit_with_its_inertia(implement_mass, vertical, pitch, length):
    body = BodyAcceleration(np.array([vertical]), np.array([pitch]))
    rest_model, rest = _carried(implement_mass, 1.0, length)
    x6 = float(rest.implement_cg[0, 0])
    a6 = float(body.at(x6)[0])
    # the pressures carry m_6·(g + a_6)
    model, batch = _carried(implement_mass, 1.0 + a6 / rest_model.mech.gravity, length)
    mech, t = model.mech, model.mech.tractor
    g, L, x_tr = mech.gravity, t.wheelbase, float(t.cg[0])
    implement = implement_at_rest(batch.implement_load, body.at(batch.implement_cg[:, 0]), g, load_measured=True)
    found = road_balance(t, g, batch.frame_load_points, batch.frame_load_forces, batch.implement_load,
                         batch.implement_cg[:, 0], body, implement)
    front, rear = found.dynamic[0, 0], found.dynamic[0, 1]
    bodies = ((t.mass, x_tr), (t.front_ballast.mass, t.front_ballast.x), (implement_mass, x6))
    forces = sum(m * (g + vertical + pitch * x) for m, x in bodies)
    moments = sum(m * (g + vertical + pitch * x) * x for m, x in bodies) + t.mass * x_tr * (L - x_tr) * pitch
    scale = forces   # N: the residuals against the unit's weight
    assert abs(front + rear - forces) <= 1e-9 * scale
    assert abs(L * front - moments) <= 1e-9 * scale * L
    # the static balance is the unit at rest, whatever the bounce: the pose solved with the weight alone
    static = rest_model.evaluate_batch(rest).steerability
    for j, key in enumerate(STEERABILITY_COLUMNS):
        np.testing.assert_allclose(found.static[0, j], static[key][0], rtol=1e-9, atol=1e-6, err_msg=key)
    # the dynamic ratio over the weight at rest, its margin against ratio_min
    np.testing.assert_allclose(found.dynamic[0, 2], front / static["total_weight"][0], rtol=1e-12)
    np.testing.assert_allclose(found.dynamic[0, 3], found.dynamic[0, 2] - t.ratio_min, rtol=1e-12)


@pytest.mark.parametrize("vertical", [np.nan, -5.0])
def test_without_an_acceleration_the_static_rows_are_as_without_an_imu(vertical):
    """No IMU reading (NaN), or the implement falling faster than g/2 (its load says too little of its
    weight): the static rows as without an IMU, the dynamic values NaN."""
    model, batch = _carried(1200.0, 1.3, 0.6)
    body = BodyAcceleration(np.array([vertical]), np.array([0.0]))
    implement = implement_at_rest(batch.implement_load, body.at(batch.implement_cg[:, 0]), 9.80665, load_measured=True)
    found = road_balance(model.mech.tractor, model.mech.gravity, batch.frame_load_points, batch.frame_load_forces,
                         batch.implement_load, batch.implement_cg[:, 0], body, implement)
    today = model.evaluate_batch(batch).steerability
    np.testing.assert_array_equal(found.static[0], [today[k][0] for k in STEERABILITY_COLUMNS])
    assert np.isnan(found.dynamic).all()


def test_pitch_acceleration_and_imu_mounting_of_a_known_motion():
    """β(t) = B·sin(ωt): α = −B·ω²·sin(ωt); the gyro reads ω_y = −dβ/dt (REP 103: nose up turns −y).
    The least-squares slope over 50 ms at 400 Hz lags by 25 ms (half its window): compared with α
    there, to the window's curvature error (a least-squares slope of a sine over ±h falls short by
    about (ω·h)²/10: 1.5 % of α's amplitude here, h = 25 ms)."""
    rate_hz, b, w = 400.0, 0.02, 2.0 * np.pi * 2.5
    t = np.arange(0.0, 1.0, 1.0 / rate_hz)
    stamps = np.round(t * 1e9).astype(np.int64)
    gyro_y = -b * w * np.cos(w * t)
    found = PitchAcceleration(0.05).series(stamps, gyro_y)
    lagged = -b * w**2 * np.sin(w * (t - 0.025))
    settled = t >= 0.05
    np.testing.assert_allclose(found[settled], lagged[settled], atol=0.02 * b * w**2)
    assert np.isnan(found[0])
    # an IMU at x_i reads f_z = g + a_B + α·x_i: the body's acceleration at B is recovered
    body = imu_body_acceleration(9.80665 + 0.7 + 2.0 * 1.5, 2.0, 1.5)
    assert body.vertical == pytest.approx(0.7) and body.pitch == 2.0


def test_the_weight_at_rest_is_an_exponential_average_over_its_time_constant():
    """Closed form: a step from 1000 N to 2000 N at t = 0 reaches 2000 − 1000·exp(−t/τ); a NaN (an
    implement falling faster than g/2) changes nothing and is answered with the value before."""
    rest = RestLoad(0.1)
    stamps = np.arange(0, 30) * 10_000_000   # 100 Hz
    values = np.where(stamps > 0, 2000.0, 1000.0)
    values[5] = np.nan
    found = rest.series(stamps, values)
    t = stamps * 1e-9
    expected = 2000.0 - 1000.0 * np.exp(-t / 0.1)
    keep = np.arange(30) != 5
    np.testing.assert_allclose(found[keep], expected[keep], rtol=1e-12)
    assert found[5] == found[4]
