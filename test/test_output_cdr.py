"""The outputs written as CDR bytes (wire.outputs.OutputEncoder) are the messages rclpy builds
and serializes field by field (oracle: test/oracles/output_messages.py, builders that fill
rclpy's message classes), for every preset and fixture, OK and WARN steps, NaN fields and a reconfigured monitor
(arbitrary values: test/test_wire.py); and they decode with readers we did not write (rclpy, rosbags).

How each check compares: rclpy's ``deserialize_message`` of our bytes equals the oracle
message field by field (NaN equal to NaN, floats bit for bit), and our length equals the
message's exact CDR length (rclpy's buffer cut by rosbags' decoder, wire.definitions.exact_cdr), and
the bytes are rclpy's serialization but for the alignment padding (support.rclpy_bytes.assert_rclpy_bytes).
"""

from __future__ import annotations

import math
import struct

import numpy as np
import pytest
from rclpy.serialization import deserialize_message, serialize_message

from linkage_monitor.wire.definitions import exact_cdr
from linkage_monitor.bag.writer import message_type_name
from linkage_monitor.mechanics import load_mechanism, load_preset, preset_names
from linkage_monitor.monitoring.config import MonitorConfig
from linkage_monitor.monitoring.core import Monitor
from linkage_monitor.msg import HitchState
from linkage_monitor.wire.outputs import OutputEncoder, per_step
from linkage_monitor.sim.telemetry import Noise, simulate
from oracles.output_messages import outputs as oracle_outputs
from support.fixtures import FIXTURES
from support.messages import assert_same_message
from support.rclpy_bytes import assert_rclpy_bytes

FIELDS = ("hinge_reactions", "hitch_state", "steerability")


def _check(monitor: Monitor, encoder: OutputEncoder, step) -> int:
    ours, theirs = encoder.outputs(monitor, step), oracle_outputs(monitor, step)
    if theirs is None:
        assert ours is None
        return 0
    for name in FIELDS:
        data, msg = getattr(ours, name), getattr(theirs, name)
        assert isinstance(data, bytes)
        assert_same_message(deserialize_message(data, type(msg)), msg, name)
        assert len(data) == len(exact_cdr(message_type_name(msg), serialize_message(msg))), name
        assert_rclpy_bytes(message_type_name(msg), data, msg)   # and byte for byte, padding aside
    return 1


def _monitor(mech) -> Monitor:
    sensors = [p.name for p in mech.measurements.pressures]
    return Monitor(mech, MonitorConfig(mechanism=mech.name, pressure_topics={f"/pressure/{s}": s for s in sensors},
                                       pressure_absolute=False, staleness_limit_s=3600.0, stamp_tolerance_s=1e9))


# (spring_contact.yaml is left out: its statics need a measured force, and it has no pressure sensor)
MECHANISMS = ([("preset", n) for n in preset_names()]
              + [("fixture", f) for f in ("hitch.yaml", "four_bar.yaml", "arm_angle.yaml")])


@pytest.mark.parametrize("kind,name", MECHANISMS)
def test_every_preset_and_fixture_as_rclpy_builds_it(kind, name):
    """Poses around the reference inputs (strokes and angles ±0.1 %), pressures from 0.5 to 3 times
    the reference: OK and WARN steps (lift reserve, disagreeing sensors), some NaN fields."""
    mech = load_preset(name) if kind == "preset" else load_mechanism(FIXTURES / name)
    monitor, encoder = _monitor(mech), OutputEncoder()
    ref = mech.reference_inputs
    names, values = list(monitor.solver.kin.input_names), monitor.solver.kin.reference_inputs()   # the reference pose's
    pressures = {p.name: float(ref.get("pressures", {}).get(p.name, 5e6)) for p in mech.measurements.pressures}
    rng = np.random.default_rng(7)
    stamp, solved, steps = 1_700_000_000_000_000_000, 0, []
    for k in range(12):
        stamp += 10_000_000
        for sensor, value in pressures.items():   # the reference's, or 5 MPa where it has none
            pressure = value * rng.uniform(0.5, 3.0)
            steps.append(monitor.on_pressure(f"/pressure/{sensor}", pressure, stamp, stamp))
            solved += _check(monitor, encoder, steps[-1])
        inputs = values * (1.0 + 0.001 * rng.uniform(-1.0, 1.0, values.size) * (k > 0))
        steps.append(monitor.on_joint_state(names, inputs.tolist(), [], stamp, stamp))
        solved += _check(monitor, encoder, steps[-1])
    assert solved > 0
    # all steps at once (the replay's encoding), a fresh encoder: the same bytes as one step at a time
    assert per_step(OutputEncoder().output_rows(monitor, steps), len(steps)) == [encoder.outputs(monitor, step)
                                                                                 for step in steps]


def test_warnings_and_a_reconfigured_monitor():
    """A heavy implement (lift reserve < 1: WARN, HitchState.STATUS_WARN with the text) and a
    mechanism changed at run time (the layout is laid out again)."""
    mech = load_preset("belarus_1221")
    stream = simulate(mech, "lift", rate_hz=5.0, seed=1, start_ns=1_700_000_000_000_000_000)
    monitor, encoder = _monitor(mech), OutputEncoder()
    levels = set()
    for i, stamp in enumerate(stream.stamps_ns.tolist()):
        if i == len(stream) // 2:
            monitor.reconfigure(MonitorConfig(**{**monitor.config.__dict__, "overrides": {"implement.mass": 9000.0}}))
        pressure = float(stream.pressure_values[i, 0]) * (3.0 if i >= len(stream) // 2 else 1.0)
        _check(monitor, encoder, monitor.on_pressure("/pressure/lift_cap_pressure", pressure, stamp, stamp))
        step = monitor.on_joint_state(list(stream.joint_names), stream.joint_positions[i].tolist(), [], stamp, stamp)
        _check(monitor, encoder, step)
        levels.add(step.level.name)
    assert "WARN" in levels and "OK" in levels


def test_with_an_imu_the_dynamic_fields_as_rclpy_builds_them():
    """An IMU on /imu (monitoring.road): the steerability's dynamic fields filled, NaN before the
    first IMU reading; one step at a time and all at once, the same bytes."""
    from dataclasses import replace

    from linkage_monitor.monitoring.config import Topics
    from linkage_monitor.monitoring.events import ImuEvent

    mech = load_preset("belarus_1221")
    stream = simulate(mech, "lift", rate_hz=20.0, seed=2, start_ns=1_700_000_000_000_000_000)
    monitor, encoder = _monitor(mech), OutputEncoder()
    monitor.reconfigure(replace(monitor.config, topics=Topics(imu="/imu")))
    steps, dynamic = [], 0
    for i, stamp in enumerate(stream.stamps_ns.tolist()):
        if i >= 3:   # a heaving, pitching body from the fourth sample on
            for k in range(25):
                at = stamp - 50_000_000 + 2_000_000 * k
                steps.append(monitor.step(ImuEvent("/imu", "imu_link", 9.80665 + math.sin(at * 1e-8), 0.1 * math.cos(
                    at * 1e-8), at, at)))
        steps.append(monitor.on_pressure("/pressure/lift_cap_pressure", float(stream.pressure_values[i, 0]), stamp,
                                         stamp))
        steps.append(monitor.on_joint_state(list(stream.joint_names), stream.joint_positions[i].tolist(), [], stamp,
                                            stamp))
        for step in steps[-2:]:
            _check(monitor, encoder, step)
            dynamic += step.pose is not None and bool(np.isfinite(step.pose.dynamic).all())
    assert dynamic > 0 and np.isnan(steps[1].pose.dynamic).all()
    assert per_step(OutputEncoder().output_rows(monitor, steps), len(steps)) == [encoder.outputs(monitor, step)
                                                                                 for step in steps]


def test_many_steps_at_once_as_one_at_a_time():
    """``output_rows`` (the replay's: one template per status text, filled for all its steps at once)
    writes the bytes ``outputs`` writes, over a simulated lift with sensor noise: OK steps, WARN
    steps whose texts carry numbers (one template each), steps without a pose, more distinct texts
    than the encoder keeps templates for."""
    mech = load_preset("belarus_1221")
    stream = simulate(mech, "lift", rate_hz=50.0, seed=3, start_ns=1_700_000_000_000_000_000,
                      noise=Noise(angle=0.0017, length=0.0005, pressure=2e4))
    monitor, encoder = _monitor(mech), OutputEncoder()
    steps = []
    for i, stamp in enumerate(stream.stamps_ns.tolist()):
        pressure = float(stream.pressure_values[i, 0]) * (3.0 if i % 3 == 0 else 1.0)   # lift reserve < 1: WARN
        steps.append(monitor.on_pressure("/pressure/lift_cap_pressure", pressure, stamp, stamp))
        positions = stream.joint_positions[i].tolist()
        if i % 50 == 7:
            positions[0] = math.nan   # an input refused: a step without a pose
        steps.append(monitor.on_joint_state(list(stream.joint_names), positions, [], stamp, stamp))
    ours = per_step(OutputEncoder().output_rows(monitor, steps), len(steps))
    assert ours == [encoder.outputs(monitor, step) for step in steps]
    texts = {step.message for step in steps if step.pose is not None}
    assert any(o is None for o in ours) and len(texts) > OutputEncoder.MAX_TEMPLATES, len(texts)


def test_the_smallest_transmission_angle_in_hitch_state_and_the_diagnostic():
    """HitchState.min_transmission_angle is the solver's Result.transmission_angle, bit for bit, and
    the diagnostic's key-values carry it with the step attaining it. belarus_1221 measured by stroke,
    lift-arm angle and the lift cylinder's cap pressure is a chain of dyads the reduced path serves:
    a finite angle in [0, π/2] rad on every solved pose of a simulated lift; the triad fixture (a
    class-III group, test/fixtures/triad.yaml) only the general path solves: NaN, and no such keys."""
    mech = load_preset("belarus_1221")
    stream = simulate(mech, "lift", rate_hz=5.0, seed=1, start_ns=1_700_000_000_000_000_000)
    monitor, encoder = _monitor(mech), OutputEncoder()
    solved = 0
    for i, stamp in enumerate(stream.stamps_ns.tolist()):
        monitor.on_pressure("/pressure/lift_cap_pressure", float(stream.pressure_values[i, 0]), stamp, stamp)
        step = monitor.on_joint_state(list(stream.joint_names), stream.joint_positions[i].tolist(), [], stamp, stamp)
        if step.pose is None:
            continue
        solved += 1
        result = step.pose.result
        msg = deserialize_message(encoder.outputs(monitor, step).hitch_state, HitchState)
        assert struct.pack("<d", msg.min_transmission_angle) == struct.pack("<d", result.transmission_angle)
        assert math.isfinite(msg.min_transmission_angle) and 0.0 <= msg.min_transmission_angle <= math.pi / 2
        assert step.values["min transmission angle [rad]"] == f"{result.transmission_angle:.4f}"
        assert step.values["weakest transmission"] == result.weakest_transmission != ""
    assert solved > 0.9 * len(stream)

    triad = load_mechanism(FIXTURES / "triad.yaml")
    monitor = _monitor(triad)
    names, values = list(monitor.solver.kin.input_names), monitor.solver.kin.reference_inputs()
    step = monitor.on_joint_state(names, values.tolist(), [], 1_700_000_000_000_000_000, 1_700_000_000_000_000_000)
    assert step.pose is not None, step.message
    msg = deserialize_message(OutputEncoder().outputs(monitor, step).hitch_state, HitchState)
    assert math.isnan(msg.min_transmission_angle)
    assert "min transmission angle [rad]" not in step.values and "weakest transmission" not in step.values


def test_standard_uncertainties_and_the_weighing_as_rclpy_builds_them():
    """With the error budget and the weighing on (``uncertainty``, ``implement_mass_source``): every
    ``*_u`` field is the standard uncertainty (1 sigma) of the step's budget (mechanics.uncertainty,
    the oracle's ``Budget.u_of`` by output name), HitchState's weighing fields the step's
    ``WeighingState``; one step at a time and all at once, the same bytes. A simulated work cycle of
    belarus_1221 (sim.work_cycle: lifts, lowers, transport, 4 % seal friction) gives an estimate,
    its phases and the estimate put in use; with both off, the fields are NaN and the phase OFF."""
    from linkage_monitor.sim.friction import SealFriction
    from linkage_monitor.sim.work_cycle import ImplementTruth, WorkCycle, simulate_work

    mech = load_preset("belarus_1221")
    cycle = WorkCycle(work_s=2.0, transport_s=4.0)
    run = simulate_work(mech, ImplementTruth(mass=1200.0, cg=mech.implement.cg), duration_s=2 * cycle.period,
                        cycle=cycle, friction=SealFriction(share=0.04), road=None,
                        noise=Noise(angle=0.0005, length=0.0002, pressure=2e4), seed=3)
    stream = run.stream
    base = _monitor(mech)
    config = MonitorConfig(**{**base.config.__dict__, "uncertainty": True, "implement_mass_source": "estimate"})
    monitor, encoder, steps = Monitor(mech, config), OutputEncoder(), []
    for i, stamp in enumerate((stream.stamps_ns + 1_700_000_000_000_000_000).tolist()[::4]):
        k = 4 * i
        steps.append(monitor.on_pressure("/pressure/lift_cap_pressure", float(stream.pressure_values[k, 0]), stamp,
                                         stamp))
        steps.append(monitor.on_joint_state(list(stream.joint_names), stream.joint_positions[k].tolist(), [], stamp,
                                            stamp))
        _check(monitor, encoder, steps[-2])
        _check(monitor, encoder, steps[-1])
    solved = [s for s in steps if s.pose is not None]
    assert solved and all(s.pose.budget is not None and s.weighing is not None for s in solved)
    last = deserialize_message(encoder.outputs(monitor, solved[-1]).hitch_state, HitchState)
    assert last.implement_mass_estimate > 0.0 and last.implement_mass_estimate_u > 0.0
    assert last.implement_load_u > 0.0 and last.cylinders[0].force_u > 0.0
    phases = {deserialize_message(encoder.outputs(monitor, s).hitch_state, HitchState).weighing_phase for s in solved}
    assert {HitchState.WEIGHING_LIFTING, HitchState.WEIGHING_LOWERING} <= phases, phases
    assert any(s.weighing.estimate_in_use for s in solved)
    assert per_step(OutputEncoder().output_rows(monitor, steps), len(steps)) == [encoder.outputs(monitor, s)
                                                                                 for s in steps]
    base.on_pressure("/pressure/lift_cap_pressure", float(stream.pressure_values[0, 0]), 1_700_000_000_000_000_000,
                     1_700_000_000_000_000_000)
    off = deserialize_message(OutputEncoder().outputs(base, base.on_joint_state(
        list(stream.joint_names), stream.joint_positions[0].tolist(), [], 1_700_000_000_000_000_000,
        1_700_000_000_000_000_000)).hitch_state, HitchState)
    assert math.isnan(off.implement_load_u) and math.isnan(off.implement_mass_estimate)
    assert off.weighing_phase == HitchState.WEIGHING_OFF
