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
from linkage_monitor.mechanics.dynamics import (BodyAcceleration, ImuBody, RestLoad, carried_axle_loads,
                                                dynamic_balance, imu_body_acceleration, implement_at_rest,
                                                ratio_reference, static_at_rest)
from linkage_monitor.mechanics.kernels import STEERABILITY_COLUMNS
from linkage_monitor.mechanics.machine import MachineModel, machine_parameters

STROKE = (0.515, 0.715)  # m, Popov 2009 Table 1's range of S


def _road_balance(tractor, g, batch, body, measured=True):
    """The static rows at rest and the dynamic values of ``batch``'s poses, each with the body's
    acceleration of its own instant (``mechanics.dynamics``' parts, as ``monitoring.road`` joins them)."""
    load, x6 = batch.implement_load, batch.implement_cg[:, 0]
    implement = implement_at_rest(load, body.at(x6), g, load_measured=measured)
    static = static_at_rest(machine_parameters(tractor, g), batch.frame_load_points, batch.frame_load_forces, load, x6, implement.rest)
    front, total = carried_axle_loads(tractor, static, load, implement.rest, x6)
    inertia = np.zeros_like(load) if measured else implement.inertia
    return static, dynamic_balance(tractor, g, front, total, ratio_reference(tractor, g, static), inertia, x6, body)


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
    found_static, found_dynamic = _road_balance(t, g, batch, body)
    front, rear = found_dynamic[0, 0], found_dynamic[0, 1]
    bodies = ((t.mass, x_tr), (t.front_ballast.mass, t.front_ballast.x), (implement_mass, x6))
    forces = sum(m * (g + vertical + pitch * x) for m, x in bodies)
    moments = sum(m * (g + vertical + pitch * x) * x for m, x in bodies) + t.mass * x_tr * (L - x_tr) * pitch
    scale = forces   # N: the residuals against the unit's weight
    assert abs(front + rear - forces) <= 1e-9 * scale
    assert abs(L * front - moments) <= 1e-9 * scale * L
    # the static balance is the unit at rest, whatever the bounce: the pose solved with the weight alone
    static = rest_model.evaluate_batch(rest).steerability
    for j, key in enumerate(STEERABILITY_COLUMNS):
        np.testing.assert_allclose(found_static[0, j], static[key][0], rtol=1e-9, atol=1e-6, err_msg=key)
    # the dynamic ratio over the weight at rest, its margin against ratio_min
    np.testing.assert_allclose(found_dynamic[0, 2], front / static["total_weight"][0], rtol=1e-12)
    np.testing.assert_allclose(found_dynamic[0, 3], found_dynamic[0, 2] - t.ratio_min, rtol=1e-12)


@pytest.mark.parametrize("vertical", [np.nan, -5.0])
def test_without_an_acceleration_the_static_rows_are_as_without_an_imu(vertical):
    """No IMU reading (NaN), or the implement falling faster than g/2 (its load says too little of its
    weight): the static rows as without an IMU; the dynamic values NaN without a reading, and with the
    falling implement those of the measured load (the pressures carry its inertia, whatever it is)."""
    model, batch = _carried(1200.0, 1.3, 0.6)
    body = BodyAcceleration(np.array([vertical]), np.array([0.0]))
    found_static, found_dynamic = _road_balance(model.mech.tractor, model.mech.gravity, batch, body)
    today = model.evaluate_batch(batch).steerability
    np.testing.assert_array_equal(found_static[0], [today[k][0] for k in STEERABILITY_COLUMNS])
    assert np.isnan(found_dynamic).all() == np.isnan(vertical)


def test_the_body_s_acceleration_of_a_known_motion_at_the_pitch_window_s_centre():
    """β(t) = B·sin(ωt): α = −B·ω²·sin(ωt); the gyro reads ω_y = −dβ/dt (REP 103: nose up turns −y);
    the body heaves a_B(t) = A·cos(ωt) at B, and an IMU at x_i reads f_z = g + a_B + α·x_i. The
    least-squares slope over 75 ms at 400 Hz is the derivative at the window's centre, to its
    curvature error (a least-squares slope of a sine over ±h falls short by about (ω·h)²/10: 3.5 %
    of α's amplitude here, h = 37.5 ms); the body's acceleration is given at the centre sample's
    stamp, a_B recovered there to that error times x_i."""
    rate_hz, b, w, heave, x_i = 400.0, 0.02, 2.0 * np.pi * 2.5, 1.5, 1.2
    imu = ImuBody(x_i)
    seen = []
    for k in range(400):
        t = k / rate_hz
        alpha = -b * w**2 * np.sin(w * t)
        body = imu.add(round(t * 1e9), 9.80665 + heave * np.cos(w * t) + alpha * x_i, -b * w * np.cos(w * t))
        if body is not None:
            seen.append(body)
    assert len(seen) >= 370   # from 0.8 of the window's span on
    for body in seen:
        t = body.stamp_ns * 1e-9
        assert body.acceleration.pitch == pytest.approx(-b * w**2 * np.sin(w * t), abs=0.04 * b * w**2)
        assert body.acceleration.vertical == pytest.approx(heave * np.cos(w * t), abs=0.04 * b * w**2 * x_i)
    assert seen[-1].stamp_ns == round((399 - 15) / rate_hz * 1e9)   # 15 samples (37.5 ms) before the newest
    # an IMU at x_i reads f_z = g + a_B + α·x_i: the body's acceleration at B is recovered
    body = imu_body_acceleration(9.80665 + 0.7 + 2.0 * 1.5, 2.0, 1.5)
    assert body.vertical == pytest.approx(0.7) and body.pitch == 2.0


@pytest.mark.parametrize("carried", [True, False])
def test_the_weight_at_rest_is_averaged_while_the_implement_is_carried(carried):
    """Closed form: a step from 1000 N to 2000 N at t = 0 reaches 2000 − 1000·exp(−t/τ), τ = 0.5 s, while the
    implement is carried; near the working position (not carried) it is followed at once; a NaN (an
    implement falling faster than g/2) changes nothing and is answered with the value before."""
    rest = RestLoad(0.5)
    stamps = np.arange(0, 30) * 10_000_000   # 100 Hz
    values = np.where(stamps > 0, 2000.0, 1000.0)
    values[5] = np.nan
    found = np.array([rest.add(int(s), float(v), carried) for s, v in zip(stamps, values)])
    t = stamps * 1e-9
    expected = 2000.0 - 1000.0 * np.exp(-t / 0.5) if carried else np.where(t > 0, 2000.0, 1000.0)
    keep = np.arange(30) != 5
    np.testing.assert_allclose(found[keep], expected[keep], rtol=1e-12)
    assert found[5] == found[4]


def test_a_still_body_s_gyro_noise_is_shrunk_and_a_bounce_kept():
    """Wiener's gain S/(S + N) on the slope: N the slope's variance from its own residuals (σ_ω²/Σ(t − t̄)²),
    S its mean square over 0.3 s less N. A still body whose gyro reads white noise (σ 0.005 rad/s at
    400 Hz: the slope's noise σ·√(12/(n·(n²−1)))·rate = 0.042 rad/s² for n = 31) gives a pitch
    acceleration of a small part of that; a pitching body (2 rad/s² at 2.5 Hz, the same noise) keeps
    its pitch acceleration to within the noise and the window's curvature error."""
    rng = np.random.default_rng(7)
    rate_hz, sigma, n = 400.0, 0.005, 31
    raw = sigma * np.sqrt(12.0 / (n * (n * n - 1))) * rate_hz
    for amplitude, check in ((0.0, "still"), (2.0, "pitching")):
        w = 2.0 * np.pi * 2.5
        imu = ImuBody(0.0)
        found, truth = [], []
        for k in range(1200):
            t = k / rate_hz
            body = imu.add(round(t * 1e9), 9.80665, amplitude / w * np.cos(w * t) + sigma * rng.standard_normal())
            if body is not None and k > 200:
                found.append(body.acceleration.pitch)
                truth.append(amplitude * np.sin(w * body.stamp_ns * 1e-9))
        error = np.sqrt(np.mean((np.array(found) - np.array(truth)) ** 2))
        if check == "still":
            assert error < 0.5 * raw, (error, raw)
        else:
            assert error < raw + 0.04 * amplitude, (error, raw)


def test_a_still_body_s_accelerometer_noise_is_smoothed_by_the_quadratic_fit():
    """The specific force is the quadratic least-squares fit over the pitch window, at its centre
    (Savitzky & Golay 1964): white noise σ per sample leaves σ·√(3·(3n² − 7)/(4n·(n² − 4))) at the
    centre of n equally spaced samples, 0.27·σ for n = 31 (75 ms at 400 Hz, both ends in): a still
    body's accelerometer reading σ = 0.05 m/s² gives a vertical acceleration of that RMS (±10 % over
    4,000 samples), not σ."""
    rng = np.random.default_rng(7)
    imu, sigma, n = ImuBody(0.0), 0.05, 31
    seen = [imu.add(k * 2_500_000, 9.80665 + sigma * float(rng.standard_normal()), 0.0) for k in range(4000)]
    vertical = np.array([body.acceleration.vertical for body in seen if body is not None])
    expected = sigma * np.sqrt(3.0 * (3 * n * n - 7) / (4.0 * n * (n * n - 4)))
    assert np.sqrt(np.mean(vertical ** 2)) == pytest.approx(expected, rel=0.1)
