"""The monitor with an IMU on the tractor body (monitoring.road): ImuEvents taken, each solve's static
steerability at rest and its dynamic one, the steerability_dynamic_low verdict, the live and the
batched paths alike. No ROS: the core alone.

Oracle: a body heaving without pitch (every point up with the same a, the gyro still) is the unit
at rest under gravity g + a (d'Alembert: each mass m adds m·a where its weight m·g acts), so every
axle load scales by (g + a)/g: R_A* = R_A·(g + a)/g, and the dynamic ratio is R_A*/W at rest.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from linkage_monitor.mechanics import load_preset
from linkage_monitor.mechanics.constants import STANDARD_GRAVITY
from linkage_monitor.mechanics.dynamics import PITCH_WINDOW
from linkage_monitor.mechanics.kernels import STEERABILITY_COLUMNS
from linkage_monitor.monitoring.config import MonitorConfig, Topics
from linkage_monitor.monitoring.core import Monitor
from linkage_monitor.monitoring.events import ImuEvent, JointStateEvent
from linkage_monitor.monitoring.findings import Code, Level
from support.monitor_steps import step_by_step

START = 1_700_000_000_000_000_000
IMU_RATE_NS = 2_500_000   # 400 Hz


def _config(mech, **changes) -> MonitorConfig:
    """belarus_1221 without pressures (the implement's load is its file's weight), the IMU on /imu."""
    return replace(MonitorConfig(mechanism=mech.name, topics=Topics(imu="/imu"), staleness_limit_s=0.5), **changes)


def _events(mech, heave: float, frame: str = "imu_link", count: int = 40) -> list:
    """``count`` IMU messages of a body heaving with ``heave`` m/s² (a float, or a function of the sample
    index; no pitch), each followed by the reference pose's JointState of its stamp."""
    inputs = mech.reference_inputs
    names = [*inputs["angles"], *inputs["cylinders"]]
    positions = [*inputs["angles"].values(), *inputs["cylinders"].values()]
    events: list = []
    for k in range(count):
        stamp = START + k * IMU_RATE_NS
        a = heave(k) if callable(heave) else heave
        events += [ImuEvent("/imu", frame, STANDARD_GRAVITY + a, 0.0, stamp, stamp),
                   JointStateEvent("joint_states", names, positions, [], stamp, stamp)]
    return events


def _static(mech, config) -> dict:
    """The reference pose's steerability without an IMU."""
    steps = step_by_step(mech, replace(config, topics=Topics()), _events(mech, 0.0)[-1:])
    return steps[-1].pose.machine.steerability


@pytest.mark.parametrize("heave", [-3.0, 2.0])
def test_a_heave_scales_the_axle_loads_and_the_static_ones_stay(heave):
    mech = load_preset("belarus_1221")
    config = _config(mech)
    rest = _static(mech, config)
    events = _events(mech, heave)
    for steps in (step_by_step(mech, config, events), Monitor(mech, config).run(events).steps):
        assert all(s.pose is None and not s.findings for s in list(steps)[0::2])   # an IMU message solves nothing
        pose = steps[-1].pose
        assert pose.machine.steerability == rest   # without pressures the load carries no inertia: as without an IMU
        front, rear, ratio, margin = pose.dynamic.tolist()
        scale = (STANDARD_GRAVITY + heave) / STANDARD_GRAVITY
        assert front == pytest.approx(rest["front_axle_load"] * scale, rel=1e-9)
        assert rear == pytest.approx(rest["rear_axle_load"] * scale, rel=1e-9)
        assert ratio == pytest.approx(front / rest["total_weight"], rel=1e-12)
        assert margin == pytest.approx(ratio - rest["ratio_min"], rel=1e-12)


def test_the_dynamic_values_are_those_of_the_solve_at_the_pitch_window_s_centre():
    """The body's acceleration is known half the pitch window late (the gyro's rate differentiated over
    75 ms, centred, and the specific force's quadratic fit over the same window, at its centre): a
    heave growing 0.02 m/s² a sample (which the fit follows exactly) reaches the dynamic values of
    the solve at sample k − 15 (37.5 ms at 400 Hz) with the heave of sample k − 15, each scaling the
    axle loads at rest by (g + a)/g (module docstring's oracle)."""
    mech = load_preset("belarus_1221")
    config = _config(mech)
    rest = _static(mech, config)
    heave = lambda k: 0.02 * k   # noqa: E731
    events = _events(mech, heave, count=80)
    lag = round(PITCH_WINDOW / 2 * 1e9 / IMU_RATE_NS)
    for steps in (step_by_step(mech, config, events), Monitor(mech, config).run(events).steps):
        for k in range(40, 80):
            front = steps[2 * k + 1].pose.dynamic[0]
            scale = (STANDARD_GRAVITY + heave(k - lag)) / STANDARD_GRAVITY
            assert front == pytest.approx(rest["front_axle_load"] * scale, rel=1e-9), k


def test_the_dynamic_margin_below_zero_while_the_static_one_clears_it_is_a_warning():
    """ratio_min set 0.05 below the ratio at rest: a drop of 3 m/s² takes the front axle's share down
    by 3/g ≈ 31 %, below ratio_min (the dynamic margin < 0), the static margin +0.05."""
    mech = load_preset("belarus_1221")
    ratio = _static(mech, _config(mech))["ratio"]
    config = _config(mech).with_overrides({"tractor.ratio_min": ratio - 0.05})
    events = _events(mech, -3.0)
    for steps in (step_by_step(mech, config, events), Monitor(mech, config).run(events).steps):
        step = steps[-1]
        assert step.pose.machine.value("margin") == pytest.approx(0.05, abs=1e-9)
        assert step.pose.dynamic[3] < 0.0
        assert [f.code for f in step.findings] == [Code.STEERABILITY_DYNAMIC_LOW] and step.level == Level.WARN
        assert f"dynamic steerability margin {step.pose.dynamic[3]:+.3f} < 0 (static +0.050)" in step.message
    # the same drop, the static margin itself below 0: steerability_low says it, not the dynamic one again
    low = _config(mech).with_overrides({"tractor.ratio_min": ratio + 0.05})
    codes = [f.code for f in step_by_step(mech, low, _events(mech, -3.0))[-1].findings]
    assert codes == [Code.STEERABILITY_LOW]


def test_without_a_recent_imu_message_the_dynamic_values_are_nan_and_a_foreign_frame_is_refused():
    mech = load_preset("belarus_1221")
    config = _config(mech, staleness_limit_s=0.01)
    events = _events(mech, 1.0)
    late = replace(events[-1], stamp_ns=events[-1].stamp_ns + 20_000_000, receive_ns=events[-1].receive_ns + 20_000_000)
    pose = step_by_step(mech, config, [*events[:-1], late])[-1].pose
    assert np.isnan(pose.dynamic).all() and pose.machine.steerability == _static(mech, config)
    steps = step_by_step(mech, _config(mech), _events(mech, 1.0, frame="base_link"))
    assert steps[0].findings[0].code is Code.UNKNOWN_INPUT and "frame 'base_link'" in steps[0].message
    assert np.isnan(steps[-1].pose.dynamic).all()   # every IMU message refused: none in use


@pytest.mark.parametrize("fault, hint", [("gravity removed", "gravity removed"), ("1e308", "gravity removed"),
                                         ("gyro in deg/s", "deg/s sent as rad/s")])
def test_an_implausible_imu_reading_is_refused_and_the_solve_is_as_without_an_imu(fault, hint):
    """An IMU publishing its acceleration with gravity removed (f_z ≈ 0: the implement at rest would
    weigh P·g/(g + a) → ∞), an absurd one, or its gyro in deg/s: each message refused out_of_range with
    the hint, none in use; the static steerability is that without an IMU, the dynamic one NaN."""
    mech = load_preset("belarus_1221")
    config = _config(mech)
    events = _events(mech, 0.0)
    change = {"gravity removed": {"specific_force_z": 0.05},
              "1e308": {"specific_force_z": 1e308},
              "gyro in deg/s": {"rate_y": np.degrees(0.1)}}[fault]
    events = [replace(e, **change) if isinstance(e, ImuEvent) else e for e in events]
    for steps in (step_by_step(mech, config, events), Monitor(mech, config).run(events).steps):
        refused = list(steps)[0::2]
        assert all(s.findings and s.findings[0].code is Code.OUT_OF_RANGE and hint in s.message for s in refused)
        pose = steps[-1].pose
        assert np.isnan(pose.dynamic).all() and pose.machine.steerability == _static(mech, config)


def test_the_weighing_takes_the_imu_s_vertical_acceleration():
    """The weighing (implement_mass_source 'estimate') over a simulated lift: without an IMU it uses the
    lifting steps; with an IMU reading 2 m/s² of heave (above its 0.03·g threshold) every moving step
    is BOUNCING, none used."""
    from linkage_monitor.monitoring.events import PressureEvent
    from linkage_monitor.monitoring.weighing import WeighingPhase
    from linkage_monitor.sim.telemetry import simulate

    mech = load_preset("belarus_1221")
    stream = simulate(mech, "lift", rate_hz=50.0, seed=4, start_ns=START)
    config = MonitorConfig(mechanism=mech.name, pressure_topics={"/pressure": "lift_cap_pressure"},
                           pressure_absolute=False, implement_mass_source="estimate")
    events: list = []
    for i, stamp in enumerate(stream.stamps_ns.tolist()):
        events += [ImuEvent("/imu", "imu_link", STANDARD_GRAVITY + 2.0, 0.0, stamp - k * IMU_RATE_NS,
                            stamp - k * IMU_RATE_NS) for k in (7, 5, 3, 1)] if i else []
        events += [PressureEvent("/pressure", float(stream.pressure_values[i, 0]), stamp, stamp),
                   JointStateEvent("joint_states", list(stream.joint_names), stream.joint_positions[i].tolist(), [],
                                   stamp, stamp)]
    phases = {}
    for imu in ("", "/imu"):
        steps = Monitor(mech, replace(config, topics=Topics(imu=imu))).run(events).steps
        phases[imu] = {s.weighing.phase for s in steps if s.weighing is not None}
    assert WeighingPhase.LIFTING in phases[""] and WeighingPhase.BOUNCING not in phases[""]
    assert WeighingPhase.BOUNCING in phases["/imu"] and WeighingPhase.LIFTING not in phases["/imu"]


def test_a_new_imu_mounting_takes_effect_without_a_restart():
    """A body pitching with a constant α = 1 rad/s² (the gyro's rate −α·t) whose IMU reads f_z = g + 0.5:
    at x_i the body's vertical acceleration at B is f_z − g − α·x_i (module docstring of
    mechanics.dynamics): 0.5 m/s² with imu_x 0, −0.5 m/s² once imu_x is set to 1 m at run time."""
    mech = load_preset("belarus_1221")
    monitor = Monitor(mech, _config(mech))
    alpha = 1.0

    def feed(first: int, count: int) -> None:
        for k in range(first, first + count):
            stamp = START + k * IMU_RATE_NS
            monitor.step(ImuEvent("/imu", "imu_link", STANDARD_GRAVITY + 0.5, -alpha * k * IMU_RATE_NS * 1e-9,
                                  stamp, stamp))

    feed(0, 40)
    body = monitor.road.body_at(START + 39 * IMU_RATE_NS)
    assert body.acceleration.vertical == pytest.approx(0.5) and body.acceleration.pitch == pytest.approx(alpha)
    monitor.reconfigure(replace(monitor.config, imu_x=1.0))
    assert monitor.road.body_at(START + 39 * IMU_RATE_NS) is None   # the last one was of the old mounting
    feed(40, 1)
    body = monitor.road.body_at(START + 40 * IMU_RATE_NS)
    assert body.acceleration.vertical == pytest.approx(-0.5) and body.acceleration.pitch == pytest.approx(alpha)



@pytest.mark.parametrize("heave", [0.0, 2.0])
def test_a_measured_load_s_static_rows_are_those_of_the_solve_at_the_body_s_stamp(heave):
    """40 solves of a simulated lift (the pose moving), their load stepping down by 40 % at solve 20 (the
    ground taking part of the implement), while the body heaves with a constant ``heave`` m/s², its
    acceleration known 15 solves (37.5 ms at 400 Hz) late. Oracle: the linkage's statics are linear
    in the load, so the unit at rest of solve j is that solve with its load and frame forces scaled by
    g/(g + a) (``kernels.steerability_rows`` on them). Each row k is solve k − 15's at rest, its pose
    and load with its own weight at rest (a row of solve k's pose with solve k − 15's weight at rest
    mixes two instants); a row without a body is the solve's own, as without an IMU. No lift cylinder
    length given: the implement is never taken as carried, its weight at rest followed at once."""
    from linkage_monitor.mechanics import Solver, kernels
    from linkage_monitor.mechanics.dynamics import BodyAcceleration, BodyAt
    from linkage_monitor.mechanics.machine import machine_parameters
    from linkage_monitor.monitoring.road import RoadInput
    from linkage_monitor.sim.telemetry import simulate

    mech = load_preset("belarus_1221")
    n, lag, first = 40, 15, 200   # solves 200-239 of the lift at 50 Hz: the implement's cg moves 0.1 m
    solved = Solver(mech).solve_batch(**simulate(mech, "lift", rate_hz=50.0, seed=4).solver_inputs())
    part = slice(first, first + n)
    scale = np.where(np.arange(n) < 20, 1.0, 0.6)
    points, x6 = solved.frame_load_points[part], solved.implement_cg[part, 0]
    load, forces = solved.implement_load[part] * scale, solved.frame_load_forces[part] * scale[:, None, None]
    stamps = START + np.arange(n) * IMU_RATE_NS
    bodies = [BodyAt(int(stamps[k - lag]), BodyAcceleration(heave, 0.0)) if k >= lag else None for k in range(n)]
    road = RoadInput(mech, _config(mech), load_measured=True)
    static = np.concatenate([road.balance(stamps[k:k + 1], points[k:k + 1], forces[k:k + 1], load[k:k + 1],
                                          x6[k:k + 1], {}, bodies[k:k + 1]).static for k in range(n)])
    params = machine_parameters(mech.tractor, mech.gravity)
    rest, j = STANDARD_GRAVITY / (STANDARD_GRAVITY + heave), np.arange(n) - lag
    expected = kernels.steerability_rows(points[j], forces[j] * rest, load[j] * rest, x6[j], params)
    np.testing.assert_allclose(static[lag:], expected[lag:], rtol=1e-9)
    np.testing.assert_array_equal(static[:lag], kernels.steerability_rows(points, forces, load, x6, params)[:lag])


@pytest.mark.parametrize("beyond", [0.1, -0.01])
def test_the_weight_at_rest_is_averaged_while_the_lift_cylinder_is_beyond_the_ground_contact_zone(beyond):
    """The reference pose's load steps from its weight to 1.5 times it at solve 40 (400 Hz), the body still,
    the lift cylinder ``beyond`` (m) past the ground-contact zone's edge (``WeighingModel.contact_edge``,
    the weighing's 6 % of the stroke) or, negative, short of it (within the zone). Carried, the weight at rest is the
    exponential average over REST_TIME_CONSTANT (closed form); within the zone it follows at once. The
    static total weight is the tractor's with the weight at rest in place of the load (total at rest −
    total with the load = rest − load)."""
    from linkage_monitor.mechanics import Solver, kernels
    from linkage_monitor.mechanics.dynamics import REST_TIME_CONSTANT, BodyAcceleration, BodyAt
    from linkage_monitor.mechanics.machine import machine_parameters
    from linkage_monitor.monitoring.road import RoadInput, ground_zone
    from linkage_monitor.monitoring.weighing import WeighingSettings

    mech = load_preset("belarus_1221")
    solved = Solver(mech).solve_batch(cylinders={c: np.array([v]) for c, v in mech.reference_inputs["cylinders"].items()},
                                      angles={a: np.array([v]) for a, v in mech.reference_inputs["angles"].items()})
    zone = ground_zone(mech)
    assert zone.edge == pytest.approx(zone.model.contact_edge(WeighingSettings().ground_contact))
    n = 200
    scale = np.where(np.arange(n) < 40, 1.0, 1.5)
    points = np.repeat(solved.frame_load_points, n, axis=0)
    load, forces = solved.implement_load[0] * scale, solved.frame_load_forces[0][None] * scale[:, None, None]
    x6 = np.full(n, solved.implement_cg[0, 0])
    lengths = {zone.model.cylinder: np.full(n, zone.edge + zone.model.lifting_sign * beyond)}
    stamps = START + np.arange(n) * IMU_RATE_NS
    road = RoadInput(mech, _config(mech), load_measured=True)
    static = road.balance(stamps, points, forces, load, x6, lengths,
                          [BodyAt(int(s), BodyAcceleration(0.0, 0.0)) for s in stamps]).static
    total = STEERABILITY_COLUMNS.index("total_weight")
    rest = load + static[:, total] - kernels.steerability_rows(points, forces, load, x6,
                                                              machine_parameters(mech.tractor, mech.gravity))[:, total]
    t = np.maximum(np.arange(n) - 40 + 1, 0) * IMU_RATE_NS * 1e-9   # the average takes the step at solve 40
    expected = (load[-1] - (load[-1] - load[0]) * np.exp(-t / REST_TIME_CONSTANT) if beyond > 0.0
                else load.copy())
    expected[:40] = load[0]
    np.testing.assert_allclose(rest, expected, rtol=1e-9)


def test_the_ground_contact_zone_is_found_once_and_kept_over_a_reconfiguration_of_the_same_linkage():
    """The zone (a sweep of the stroke) is found at start-up (``load_kernels``), kept when the monitor is
    reconfigured on the same linkage (a new staleness limit), and its edge is the weighing's."""
    mech = load_preset("belarus_1221")
    config = MonitorConfig(mechanism=mech.name, topics=Topics(imu="/imu"), pressure_absolute=False,
                           pressure_topics={"/pressure": "lift_cap_pressure"})
    monitor = Monitor(mech, config)
    monitor.load_kernels()
    zone = monitor.road.ground()
    from linkage_monitor.monitoring.weighing import WeighingEstimator
    assert zone.edge == WeighingEstimator(mech)._contact_edge
    monitor.reconfigure(replace(config, staleness_limit_s=0.4))
    assert monitor.road.ground() is zone
