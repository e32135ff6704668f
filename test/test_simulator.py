"""The telemetry simulator: physically consistent streams, noise, overload, real ROS publishing.

Oracles: the solver's estimate of the implement load from the simulated sensors (the
simulator computes pressures the other way round, from a load), Popov 2009 Table 1-2 and its
whole-unit moment balance for steerability (written out here), the FluidPressure definition
(absolute pressure), and the statistics of Gaussian noise.
"""

from __future__ import annotations

import argparse
import copy
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from linkage_monitor.mechanics import Inputs, Solver, load_preset, mechanism_from_dict
from linkage_monitor.cli.simulate import add_simulate_parser, run_simulate
from linkage_monitor.sim.ground import COPY_RANGE_M, GroundDrive, ground_profile
from linkage_monitor.sim.telemetry import CYLINDER_SCENARIOS, Noise, find_stroke, simulate

ROOT = Path(__file__).resolve().parents[1]
G = 9.80665                   # m/s², the preset's gravity
W_HEADER = 15.00e3            # N, Popov 2009: F_pr = 15.00 kN · I_S, the ZhSK-4V header's weight


# the preset and its solver, once per module: the same two fixtures in each paper's test, of its own preset
@pytest.fixture(scope="module")
def belarus():
    return load_preset("belarus_1221")


@pytest.fixture(scope="module")
def solver(belarus):
    return Solver(belarus)


def popov_margin(tractor, load: np.ndarray, cg_x: np.ndarray) -> np.ndarray:
    """k − 0.2 from Popov 2009's moment balance about B: R_A = (P_tr·b + P_cw·x_cw + P_6·x_S6)/L, k = R_A/ΣP."""
    p_tr, p_cw = tractor.mass * G, tractor.front_ballast.mass * G
    r_a = (p_tr * tractor.cg[0] + p_cw * tractor.front_ballast.x + load * cg_x) / tractor.wheelbase
    return r_a / (p_tr + p_cw + load) - 0.2


# ---- consistency with the solver -----------------------------------------------------------------
@pytest.mark.parametrize("scenario", CYLINDER_SCENARIOS)
def test_zero_noise_stream_gives_back_the_load_through_the_solver(belarus, solver, scenario):
    duration = 12.6 if scenario in ("lift", "overload") else 6.0   # a whole lift cycle; most of the ramp
    stream = simulate(belarus, scenario, rate_hz=20.0, duration_s=duration, noise=Noise(), seed=3, start_ns=0)
    res = solver.solve_batch(**stream.solver_inputs())
    assert np.all(res.status == 0), res.messages
    np.testing.assert_allclose(res.implement_load, stream.truth.implement_load, rtol=1e-6)
    # the angle sensor agrees with the cylinder length: over-determined kinematics closes exactly
    assert np.max(res.consistency_residual) < 1e-9   # m
    low, high = stream.stroke.low, stream.stroke.high
    assert np.all((stream.truth.cylinder_lengths >= low) & (stream.truth.cylinder_lengths <= high))


def test_work_position_pressure_matches_popov_table2(belarus):
    stream = simulate(belarus, "lift", rate_hz=20.0, duration_s=1.0, noise=Noise(), seed=0, start_ns=0)
    cyl = belarus.cylinder("lift_cylinder")
    force = stream.truth.pressures[:, 0] * cyl.count * cyl.cap_area
    assert np.all(stream.truth.cylinder_lengths[:, 0] == 0.535)   # work = the preset's reference length
    # Popov 2009 Table 2, S = 0.535 m: F_pr = 107.52 kN; the preset's fit is within 0.1 kN (docs/belarus-1221-geometry.md)
    np.testing.assert_allclose(force, 107.52e3, atol=0.1e3)
    np.testing.assert_allclose(stream.truth.implement_load, W_HEADER, rtol=1e-4)   # 1529.57 kg · g


def test_stroke_is_the_assemblable_range(belarus):
    stroke = find_stroke(belarus)
    raw = copy.deepcopy(dict(belarus.raw))
    raw["measurements"] = {"cylinders": ["lift_cylinder"]}
    raw["reference_inputs"] = {"cylinders": {"lift_cylinder": 0.535}}
    res = Solver(mechanism_from_dict(raw)).solve_batch(
        cylinders={"lift_cylinder": [stroke.low - 0.002, stroke.low, stroke.high, stroke.high + 0.002]})
    assert list(res.status) == [3, 0, 0, 3]   # assembly error 2 mm outside (grid step 0.9 mm), ok at the ends
    # Popov 2009 Table 1 prints poses for S = 0.515 ... 0.715 m: all assemblable
    assert stroke.low <= 0.515 and stroke.high >= 0.715
    assert stroke.work < stroke.transport < stroke.high


def test_lift_cycle_timing_and_transport_bumps(belarus):
    rate = 50.0
    lift = simulate(belarus, "lift", rate_hz=rate, duration_s=None, noise=Noise(), seed=0, start_ns=0)
    raise_time = np.count_nonzero(lift.truth.phase == "raise") / rate
    assert 3.5 <= raise_time <= 3.8                       # Popov 2009: lift time 3.5-3.8 s
    lengths = lift.truth.cylinder_lengths[:, 0]
    assert lengths[0] == lift.stroke.work and np.isclose(lengths.max(), lift.stroke.transport, atol=1e-6)
    transport = simulate(belarus, "transport", rate_hz=rate, duration_s=None, noise=Noise(), seed=5, start_ns=0)
    ratio = transport.truth.implement_load / (belarus.implement.mass * G)
    assert np.max(np.abs(ratio - 1.0)) <= 0.3 + 1e-12     # vertical acceleration within ±0.3 g
    assert np.std(ratio) > 0.05                           # and it does vary
    assert np.ptp(transport.truth.pressures[:, 0]) > 0.0


# ---- noise -------------------------------------------------------------------------------------------
def test_noise_statistics_match_sigma_and_do_not_touch_the_truth(belarus):
    sigma = Noise(angle=0.01, length=0.002, pressure=1e5)   # rad, m, Pa
    noisy = simulate(belarus, "field", rate_hz=100.0, duration_s=30.0, noise=sigma, seed=11, start_ns=0)
    exact = simulate(belarus, "field", rate_hz=100.0, duration_s=30.0, noise=Noise(), seed=11, start_ns=0)
    np.testing.assert_array_equal(noisy.truth.implement_load, exact.truth.implement_load)
    np.testing.assert_array_equal(exact.joint_positions[:, 0], exact.truth.angles[:, 0])          # zero noise: exact
    np.testing.assert_array_equal(exact.pressure_values, exact.truth.pressures)
    n = len(noisy)
    for err, s in ((noisy.joint_positions[:, 0] - exact.truth.angles[:, 0], sigma.angle),
                   (noisy.joint_positions[:, 1] - exact.truth.cylinder_lengths[:, 0], sigma.length),
                   (noisy.pressure_values[:, 0] - exact.truth.pressures[:, 0], sigma.pressure)):
        # sample std of n Gaussians: relative spread 1/sqrt(2n) = 1.3 %; allow 5 of those
        assert abs(np.std(err) / s - 1.0) < 5.0 / np.sqrt(2 * n)
        assert abs(np.mean(err)) < 5.0 * s / np.sqrt(n)


# ---- overload: steerability margin crosses zero ------------------------------------------------------
def test_overload_margin_crosses_zero_at_the_announced_sample(belarus, solver):
    stream = simulate(belarus, "overload", rate_hz=50.0, duration_s=None, noise=Noise(), seed=0, start_ns=0)
    idx = stream.truth.overload_index
    assert idx is not None and 0 < idx < len(stream)
    res = solver.solve_batch(**stream.solver_inputs())
    margin = popov_margin(belarus.tractor, res.implement_load, res.implement_cg[:, 0])
    assert margin[idx - 1] > 0.0 > margin[idx]
    assert np.all(margin[:idx] > 0.0) and np.all(margin[idx:] < 0.0)      # a monotone ramp crosses once
    assert np.all(stream.truth.phase[idx:] == "overloaded")
    assert abs(popov_margin(belarus.tractor, stream.truth.largest_steerable_load,
                              stream.truth.implement_cg[0, 0])) < 1e-12
    # the relief valve is never exceeded: the load ramps to at most 95 % of what it can hold
    assert stream.truth.pressures.max() <= belarus.cylinder("lift_cylinder").relief_pressure


# ---- messages ----------------------------------------------------------------------------------------
def test_messages_carry_names_stamps_and_absolute_pressure(belarus):
    stream = simulate(belarus, "lift", rate_hz=20.0, duration_s=1.0, noise=Noise(pressure=2e4), seed=1,
                      start_ns=1_700_000_000_123_456_789)
    js = stream.joint_state(3)
    assert list(js.name) == ["lift_arm_angle", "lift_cylinder"]
    assert list(js.position) == list(stream.joint_positions[3])
    assert (js.header.stamp.sec, js.header.stamp.nanosec) == (1_700_000_000, 123_456_789 + 3 * 50_000_000)
    absolute = stream.pressures(3)["lift_cap_pressure"]
    gauge = stream.pressures(3, gauge=True)["lift_cap_pressure"]
    assert absolute.fluid_pressure == pytest.approx(stream.pressure_values[3, 0] + 101325.0)   # ISO 2533 atmosphere
    assert gauge.fluid_pressure == stream.pressure_values[3, 0]
    assert absolute.variance == pytest.approx(2e4 ** 2)   # FluidPressure: variance in Pa²


def test_cli_parses_and_rejects_bad_input(capsys):
    top = argparse.ArgumentParser(prog="linkage-monitor")
    add_simulate_parser(top.add_subparsers(dest="command"))
    args = top.parse_args(["simulate", "--preset", "belarus_1221", "--scenario", "overload", "--rate", "20",
                           "--noise-pressure", "0", "--gauge", "--loop"])
    assert (args.command, args.scenario, args.rate, args.noise_pressure, args.gauge, args.loop) == \
        ("simulate", "overload", 20.0, 0.0, True, True)
    bad = top.parse_args(["simulate", "--preset", "no_such_tractor"])
    assert run_simulate(bad) == 2
    assert "no_such_tractor" in capsys.readouterr().err


# ---- real ROS: the node publishes, this process receives ---------------------------------------------
def test_node_publishes_joint_states_and_fluid_pressure(belarus, solver):
    import rclpy
    from rclpy.qos import qos_profile_sensor_data
    from sensor_msgs.msg import FluidPressure, JointState

    child = subprocess.Popen(
        [sys.executable, "-m", "linkage_monitor.cli.simulate", "--preset", "belarus_1221", "--scenario", "lift",
         "--rate", "50", "--duration", "8", "--noise-angle", "0", "--noise-length", "0", "--noise-pressure", "0"],
        cwd=ROOT, env=dict(os.environ), stdout=subprocess.PIPE, stderr=subprocess.STDOUT)
    joints: dict[int, JointState] = {}
    pressures: dict[int, FluidPressure] = {}
    rclpy.init()
    try:
        node = rclpy.create_node("simulator_test_listener")
        stamp = lambda m: m.header.stamp.sec * 10**9 + m.header.stamp.nanosec   # noqa: E731
        node.create_subscription(JointState, "joint_states", lambda m: joints.setdefault(stamp(m), m),
                                 qos_profile_sensor_data)
        node.create_subscription(FluidPressure, "pressure/lift_cap_pressure",
                                 lambda m: pressures.setdefault(stamp(m), m), qos_profile_sensor_data)
        deadline = time.monotonic() + 40.0
        while len(set(joints) & set(pressures)) < 20 and time.monotonic() < deadline and child.poll() is None:
            rclpy.spin_once(node, timeout_sec=0.1)
        now_ns = node.get_clock().now().nanoseconds
        node.destroy_node()
    finally:
        rclpy.try_shutdown()
        child.terminate()
        out = child.communicate(timeout=20)[0].decode(errors="replace")
    common = sorted(set(joints) & set(pressures))
    assert len(common) >= 20, f"received {len(joints)} JointState, {len(pressures)} FluidPressure; node said:\n{out}"
    assert abs(now_ns - common[0]) < 60e9      # stamps start at the publisher's current time, not at 0
    for key in common:
        js, fp = joints[key], pressures[key]
        assert list(js.name) == ["lift_arm_angle", "lift_cylinder"]
        inputs = Inputs(angles={"lift_arm_angle": js.position[0]}, cylinders={"lift_cylinder": js.position[1]},
                        pressures={"lift_cap_pressure": fp.fluid_pressure - 101325.0})   # absolute -> gauge
        # the header's weight (Popov 2009: 15.00 kN = 1529.57 kg · g), whatever the pose of the lift cycle
        assert solver.solve(inputs).implement_load == pytest.approx(belarus.implement.mass * G, rel=1e-6)


# ---- ground-driven scenarios (Kotov & Krol, Naumenko et al. 2021) ------------------------------------------------------
@pytest.mark.parametrize("preset, scenario", [("ksu1_mower_adapter", "field_copy"), ("drill_coulter", "relief")])
def test_ground_stream_puts_the_contact_on_the_ground_and_rates_match_the_angles(preset, scenario):
    """Zero noise: the solver, given the stream's angle, puts the contact point at the ground
    height the scenario prescribes (reference height + profile); the published angle rates equal
    the central differences of the angles (oracle independent of the chain rule used)."""
    mech = load_preset(preset)
    rate = 1000.0
    stream = simulate(mech, scenario, rate_hz=rate, duration_s=2.0, noise=Noise(), seed=5, start_ns=0)
    res = Solver(mech).solve_batch(**stream.solver_inputs())
    assert np.all(res.status != 2), res.messages          # assembled (lift-off is a statics verdict)
    drive = GroundDrive(mech)
    height, _, _ = ground_profile(scenario, np.arange(len(stream)) / rate, np.random.default_rng([5, 0]))
    contact = mech.contacts[0].point
    np.testing.assert_allclose(res.points[contact][:, 1], drive.reference_height + height, atol=1e-6)
    angle, velocity = stream.joint_positions[:, 0], stream.joint_velocities[:, 0]
    central = (angle[2:] - angle[:-2]) * rate / 2.0
    smooth = np.abs(np.arange(1, len(stream) - 1) / rate - 1.0) > 1.5 / rate   # relief: the speed steps at 1 s
    np.testing.assert_allclose(velocity[1:-1][smooth], central[smooth], atol=1e-3 * np.abs(velocity).max())
    if scenario == "field_copy":
        assert np.abs(height).max() <= COPY_RANGE_M


def test_ground_scenario_needs_a_contact(belarus):
    with pytest.raises(ValueError, match="one angle sensor .* and a ground contact"):
        simulate(belarus, "field_copy", rate_hz=10.0, duration_s=1.0)
