"""Axle loads and steerability from the tractor's free body (linkage_monitor.mechanics.machine).

Oracle: Popov 2009's moment balance of the whole tractor-implement unit about the rear wheels'
ground contact B. Our frame: x forward, z up, origin B; the implement's cg lies behind B, so
x_S6 < 0 and its weight turns the unit backwards:
    L·R_A = P_tr·x_tr + P_cw·x_cw + P_6·x_S6        (Popov 2009's R_A, signs from this convention)
with P = m·g (N), x in m. Valid in transport (only weights act; the Belarus links are weightless).
"""

from __future__ import annotations

import copy

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st

from linkage_monitor.mechanics import Inputs, Solver, apply_overrides, load_preset, mechanism_from_dict
from linkage_monitor.mechanics.capacity import reference_length, stroke_mechanism
from linkage_monitor.monitoring.config import MonitorConfig
from linkage_monitor.monitoring.core import Monitor
from linkage_monitor.monitoring.findings import Code, Level
from linkage_monitor.mechanics.machine import MachineModel

STROKE = (0.515, 0.715)  # m, Popov 2009 Table 1's range of S


def _unit_front_axle_load(mech, x_s6: float, implement_weight: float) -> float:
    """Popov 2009: R_A = (P_cw·x_cw + P_tr·x_tr + P_6·x_S6) / L (our frame, x_S6 < 0), N."""
    t, g = mech.tractor, mech.gravity
    return (t.front_ballast.mass * g * t.front_ballast.x + t.mass * g * t.cg[0] + implement_weight * x_s6) / t.wheelbase


def _model(overrides: dict) -> MachineModel:
    mech = apply_overrides(stroke_mechanism(load_preset("belarus_1221")), overrides)
    return MachineModel(mech, Solver(mech))


@settings(max_examples=15, deadline=None)
@given(tractor_mass=st.floats(3000.0, 12000.0), ballast=st.floats(0.0, 1500.0), ballast_x=st.floats(2.8, 4.0),
       implement_mass=st.floats(0.0, 3000.0), length=st.floats(*STROKE))
def test_transport_free_body_equals_whole_unit_balance(tractor_mass, ballast, ballast_x, implement_mass, length):
    model = _model({"tractor.mass": tractor_mass, "tractor.front_ballast.mass": ballast,
                    "tractor.front_ballast.x": ballast_x, "implement.mass": implement_mass})
    mech = model.mech
    batch = model.stroke_poses("lift_cylinder", np.array([length]))
    steer = model.evaluate_batch(batch).steerability
    weight = implement_mass * mech.gravity
    expected = _unit_front_axle_load(mech, batch.implement_cg[0, 0], weight)
    assert batch.implement_cg[0, 0] < 0.0  # the header hangs behind B
    np.testing.assert_allclose(steer["front_axle_load"][0], expected, rtol=1e-9)
    # vertical balance of the whole unit: R_A + R_B = P_tr + P_cw + P_6 (all weights, N)
    total = (tractor_mass + ballast) * mech.gravity + weight
    np.testing.assert_allclose(steer["front_axle_load"][0] + steer["rear_axle_load"][0], total, rtol=1e-9)
    np.testing.assert_allclose(steer["total_weight"][0], total, rtol=1e-9)
    # Popov 2009: k = R_A / (P_tr + P_cw + P_6); the manual rule: k = R_A / P_tr
    np.testing.assert_allclose(steer["ratio_unit"][0], expected / total, rtol=1e-9)
    np.testing.assert_allclose(steer["ratio_tractor"][0], expected / (tractor_mass * mech.gravity), rtol=1e-9)


def test_steerability_limits_close_the_inequality():
    """The ballast and implement mass reported make k = ratio_min exactly (Popov 2009's inequality, solved by hand)."""
    model = _model({})
    mech, g = model.mech, model.mech.gravity
    batch = model.stroke_poses("lift_cylinder", np.array([0.555]))
    steer = model.evaluate_batch(batch).steerability
    x_s6, t = batch.implement_cg[0, 0], mech.tractor
    # largest implement: R_A(m) / (P_tr + P_cw + m·g) = 0.2 with R_A(m) from Popov 2009's balance
    m = steer["max_implement_mass"][0]
    k = _unit_front_axle_load(mech, x_s6, m * g) / ((t.mass + t.front_ballast.mass + m) * g)
    np.testing.assert_allclose(k, 0.2, rtol=1e-9)
    # docs/belarus-1221-geometry.md (independent scratch script): header allowed by k = 0.2 is 20.5 kN at XS6 = 1.832 m
    assert abs(m * g / 1e3 - 20.5) < 0.05
    # ballast for k = 0.2 with a 2500 kg implement (heavier than the limit): balance by hand again
    heavy = _model({"implement.mass": 2500.0})
    steer = heavy.evaluate_batch(heavy.stroke_poses("lift_cylinder", np.array([0.555]))).steerability
    extra = steer["front_ballast_needed"][0]   # kg beyond the ballast carried (Steerability.msg)
    mb = t.front_ballast.mass + extra
    r_a = (mb * g * t.front_ballast.x + t.mass * g * t.cg[0] + 2500.0 * g * x_s6) / t.wheelbase
    np.testing.assert_allclose(r_a / ((t.mass + mb + 2500.0) * g), 0.2, rtol=1e-9)
    assert extra > 0.0


def _manual_minimum_ballast(t_l: float, t_v: float, i_h: float, a: float, b: float, c_plus_d: float,
                            r: float) -> float:
    """The tractor manuals' minimum front ballast (e.g. the "ballast calculation" of John Deere and
    Fendt operator's manuals): M_F,min = (I_H·(c + d) − T_V·b + r·T_L·b) / (a + b), kg, with T_L the
    empty tractor's mass, T_V its front axle load (kg) without ballast, I_H the rear implement's mass,
    a the front ballast's cg ahead of the front axle, b the wheelbase, c + d the implement's cg behind
    the rear axle (m); r = 0.2 of the empty tractor's weight on the front axle."""
    return (i_h * c_plus_d - t_v * b + r * t_l * b) / (a + b)


@settings(max_examples=300, deadline=None)
# the ratio exactly at r: the margin 0 and a shortfall of 1e-13 kg by rounding (the ballast was not 0)
@example(t_l=6894.757293168, x_tr_share=0.22939284303026936, carried=0.0, i_h=0.0, a=1.0, b=1.875, c_plus_d=1.0,
         r=0.22939284303026936)
@given(t_l=st.floats(1000.0, 15000.0), x_tr_share=st.floats(0.2, 0.7), carried=st.floats(0.0, 8000.0),
       i_h=st.floats(0.0, 6000.0), a=st.floats(0.2, 1.5), b=st.floats(1.8, 3.2), c_plus_d=st.floats(0.5, 3.0),
       r=st.floats(0.1, 0.3))
def test_extra_ballast_is_the_manuals_minimum_less_what_is_carried(t_l, x_tr_share, carried, i_h, a, b, c_plus_d, r):
    """front_ballast_needed = max(0, M_F,min − ballast carried): the manuals' formula, tractor reference,
    the implement's weight on the frame as one force at its cg (x = −(c + d) from the rear axle)."""
    from linkage_monitor.mechanics.kernels import STEERABILITY_COLUMNS, steerability_pose

    g = 9.81
    x_tr = x_tr_share * b
    parameters = np.array([g, b, r, t_l, x_tr, carried, b + a, 0.0])   # 0.0: ratio of the empty tractor's weight
    row = np.empty(len(STEERABILITY_COLUMNS))
    steerability_pose(np.array([[-c_plus_d, 0.7]]), np.array([[0.0, -i_h * g]]), i_h * g, -c_plus_d, parameters, row)
    steer = dict(zip(STEERABILITY_COLUMNS, row))
    expected = max(0.0, _manual_minimum_ballast(t_l, t_l * x_tr / b, i_h, a, b, c_plus_d, r) - carried)
    assert steer["front_ballast_needed"] == pytest.approx(expected, rel=1e-9, abs=1e-9 * t_l)
    if steer["margin"] >= 0.0:
        assert steer["front_ballast_needed"] == 0.0


def test_soil_forces_differ_from_whole_unit_balance_by_their_moment():
    """Implement working in soil: free body = whole-unit formula − M_B(soil)/L (M = x·Fz − z·Fx about B)."""
    base = stroke_mechanism(load_preset("belarus_1221"))
    raw = copy.deepcopy(dict(base.raw))
    soil = [("soil_support", [-1.95, 0.05], [0.0, 6000.0]),   # N, soil pushes the header up, 6 kN
            ("draft", [-1.80, 0.10], [-4000.0, 0.0])]         # N, soil drags it rearward, 4 kN
    raw["loads"] = [{"name": n, "body": "implement", "point": p, "force": f} for n, p, f in soil]
    mech = mechanism_from_dict(raw)
    model = MachineModel(mech, Solver(mech))
    # the reference pose (S = 0.535 m from the rounded points): the loads act at their file points
    batch = model.stroke_poses("lift_cylinder", np.array([reference_length(mech, "lift_cylinder")]))
    np.testing.assert_allclose(batch.body_poses["implement"][0, 2], 0.0, atol=1e-9)
    steer = model.evaluate_batch(batch).steerability
    whole_unit = _unit_front_axle_load(mech, batch.implement_cg[0, 0], mech.implement.mass * mech.gravity)
    moment = sum(p[0] * f[1] - p[1] * f[0] for _, p, f in soil)
    expected = whole_unit - moment / mech.tractor.wheelbase
    print(f"front axle load: free body {steer['front_axle_load'][0]:.1f} N, whole-unit formula {whole_unit:.1f} N, "
          f"soil moment/L {-moment / mech.tractor.wheelbase:+.1f} N")
    assert abs(steer["front_axle_load"][0] - whole_unit) > 1000.0  # the whole-unit formula is wrong in soil
    np.testing.assert_allclose(steer["front_axle_load"][0], expected, rtol=1e-9)
    # the wheels carry the weights minus the soil's vertical support
    total = (mech.tractor.mass + mech.tractor.front_ballast.mass + mech.implement.mass) * mech.gravity - 6000.0
    np.testing.assert_allclose(steer["total_weight"][0], total, rtol=1e-9)


def test_margin_below_zero_and_reserve_below_one_are_flagged():
    """3000 kg header: k < 0.2 by Popov 2009's balance, and 29.4 kN > Table 2's G_s = 23.03 kN at S = 0.535 m."""
    mech = apply_overrides(load_preset("belarus_1221"), {"implement.mass": 3000.0})
    solver = Solver(mech)
    model = MachineModel(mech, solver)
    res = solver.solve(_reference_inputs(mech))
    g, t = mech.gravity, mech.tractor
    k = _unit_front_axle_load(mech, res.implement_cg[0], 3000.0 * g) / ((t.mass + t.front_ballast.mass + 3000.0) * g)
    assert k < 0.2
    out = model.evaluate(res)
    # redundant inputs (stroke + rounded angle) give a least-squares pose, consistency residual ~3e-6 m:
    # global equilibrium then holds to ~1e-5 only
    np.testing.assert_allclose(out.steerability["ratio"], k, rtol=1e-4)
    assert out.steerability["margin"] < 0.0 and out.lift_capacity["reserve"] < 1.0
    # the monitor turns them into WARN findings (the same numbers, the codes of monitoring.findings)
    steps = _monitor_steps(mech, 3000.0)
    codes = {f.code for f in steps.findings}
    assert {Code.STEERABILITY_LOW, Code.LIFT_RESERVE_LOW} <= codes and steps.level == Level.WARN
    assert any(f"{k - 0.2:+.3f}" in f.text for f in steps.findings if f.code is Code.STEERABILITY_LOW)
    # the preset's own 15.0 kN header: k = 0.254 (docs/belarus-1221-geometry.md), G_s 23.03 kN > 15 kN: no finding
    light = load_preset("belarus_1221")
    assert _monitor_steps(light, None).findings == ()


def _monitor_steps(mech, mass: float | None):
    """The monitoring core's Step for the reference pose (no pressures: the load is the weight)."""
    base = load_preset("belarus_1221")
    config = MonitorConfig(mechanism="belarus_1221", overrides={"implement.mass": mass} if mass else {})
    monitor = Monitor(base, config)
    ref = mech.reference_inputs
    names = ["lift_cylinder", "lift_arm_angle"]
    values = [ref["cylinders"]["lift_cylinder"], ref["angles"]["lift_arm_angle"]]
    return monitor.on_joint_state(names, values, [], 10**18, 10**18)


def _reference_inputs(mech) -> Inputs:
    """Stroke and lift-arm angle of the preset's reference pose, no pressures (implement load = its weight)."""
    ref = mech.reference_inputs
    return Inputs(cylinders=ref["cylinders"], angles=ref["angles"])


def test_a_negative_axle_load_is_an_error_on_either_axle():
    """A tractor on its nose (1 kg tractor, 10 t of front ballast: every value inside its declared range)
    and one on its tail (no ballast, a 9 t implement): the rear, then the front axle load is < 0 by the
    free body's moment balance; each is an ERROR finding naming the axle, never an OK step."""
    base = load_preset("belarus_1221")
    ref = base.reference_inputs
    names = ["lift_cylinder", "lift_arm_angle"]
    values = [ref["cylinders"]["lift_cylinder"], ref["angles"]["lift_arm_angle"]]
    cases = {"rear": {"tractor.mass": 1.0, "tractor.front_ballast.mass": 10000.0},
             "front": {"tractor.front_ballast.mass": 0.0, "implement.mass": 9000.0}}
    for axle, overrides in cases.items():
        monitor = Monitor(base, MonitorConfig(mechanism="belarus_1221", overrides=overrides))
        step = monitor.on_joint_state(names, values, [], 10**18, 10**18)
        loads = MachineModel(apply_overrides(base, overrides), Solver(apply_overrides(base, overrides)))
        steer = loads.evaluate(Solver(apply_overrides(base, overrides)).solve(_reference_inputs(base))).steerability
        assert steer[f"{axle}_axle_load"] < 0.0, (axle, steer)
        lift_off = [f for f in step.findings if f.code is Code.AXLE_LIFT_OFF]
        assert step.level == Level.ERROR and len(lift_off) == 1 and lift_off[0].text.startswith(f"{axle} axle load")
    light = Monitor(base, MonitorConfig(mechanism="belarus_1221")).on_joint_state(names, values, [], 10**18, 10**18)
    assert not any(f.code is Code.AXLE_LIFT_OFF for f in light.findings)
