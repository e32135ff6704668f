"""The monitoring core's two drivers agree: the same events through ``Monitor.step`` one at a time
(the live node) and through ``Monitor.run`` (the replay: segments solved and checked at once)
give the same Step for every event: the findings' codes and sentences, and the solved values.
And the replay's summary equals the Steps walked one by one. No ROS: the core alone (the node
and its recording: test_replay_equals_node.py)."""

from __future__ import annotations

import math
from collections import Counter

import numpy as np

from linkage_monitor.mechanics import load_preset
from linkage_monitor.monitoring.config import MonitorConfig
from linkage_monitor.monitoring.core import Monitor
from linkage_monitor.monitoring.events import ConfigEvent, JointStateEvent, PressureEvent
from linkage_monitor.monitoring.findings import Code
from linkage_monitor.offline.replay import Summary, _account
from linkage_monitor.sim.telemetry import Noise, simulate
from support.monitor_steps import step_by_step

PRESSURE_TOPIC = "/pressure/lift_cap_pressure"
# configurations that fire every check of a solved pose, with the factor on the measured lift
# pressure in each (the implement load is estimated from it). Overrides from
# test_machine_axle_loads.py: a 1 kg tractor with 10 t of front ballast stands on its nose; twice
# the 15 kN header's pressure is a ~3 t header: below the steerability ratio, above the lift capacity
SEGMENTS = (({}, 1.0), ({}, 2.0), ({"tractor.mass": 1.0, "tractor.front_ballast.mass": 10000.0}, 1.0), ({}, 1.0))


def _events():
    """A noisy lift cycle of belarus_1221 (the simulator; its pressure gives the load) cut into
    four configuration segments (SEGMENTS), with the lift-arm angle sensor 3° off in the second half of each
    (the measurements then disagree)."""
    mech = load_preset("belarus_1221")
    stream = simulate(mech, "lift", rate_hz=20.0, noise=Noise(0.001, 0.0002, 2e4), seed=11,
                      start_ns=1_700_000_000_000_000_000)
    base = MonitorConfig(mechanism=mech.name, pressure_topics={PRESSURE_TOPIC: "lift_cap_pressure"},
                         pressure_absolute=False, staleness_limit_s=3600.0, stamp_tolerance_s=1e9)
    names = list(stream.joint_names)
    angle = names.index("lift_arm_angle")
    events: list = []
    stamps = stream.stamps_ns.tolist()
    per_segment = len(stamps) // len(SEGMENTS)
    for i, stamp in enumerate(stamps):
        segment, place = divmod(i, per_segment)
        if place == 0 and segment < len(SEGMENTS):
            events.append(ConfigEvent(base.with_overrides(SEGMENTS[segment][0])))
        positions = stream.joint_positions[i].tolist()
        if place >= per_segment // 2:
            positions[angle] += math.radians(3.0)
        factor = SEGMENTS[min(segment, len(SEGMENTS) - 1)][1]
        events.append(PressureEvent(PRESSURE_TOPIC, factor * float(stream.pressure_values[i, 0]), stamp, stamp))
        events.append(JointStateEvent("joint_states", names, positions, [], stamp, stamp))
    return mech, base, events


def test_step_by_step_and_the_batched_run_give_the_same_steps() -> None:
    mech, config, events = _events()
    stepped = step_by_step(mech, config, events)
    run = Monitor(mech, config).run(events)
    assert len(run.steps) == len(stepped) and len(run.segments) == len(SEGMENTS)
    fired = Counter(f.code for s in stepped for f in s.findings)
    for code in (Code.SENSORS_DISAGREE, Code.STEERABILITY_LOW, Code.LIFT_RESERVE_LOW, Code.AXLE_LIFT_OFF):
        assert fired[code] > 0, code   # every check fires somewhere: the comparison below covers it
    for one, batched in zip(stepped, run.steps):
        assert [(f.code, f.text) for f in one.findings] == [(f.code, f.text) for f in batched.findings]
        assert (one.pose is None) == (batched.pose is None)
        if one.pose is not None:
            np.testing.assert_allclose(batched.pose.result.hinge_force, one.pose.result.hinge_force,
                                       rtol=1e-9, atol=1e-6)


def test_the_replay_summary_is_the_steps_walked_one_by_one() -> None:
    """``offline.replay``'s summary reduces the segments' columns; the oracle walks the Steps: the
    first pose with the largest reaction of each hinge, the smallest margin and reserve."""
    mech, config, events = _events()
    run = Monitor(mech, config).run(events)
    start = run.steps[0].stamp_ns
    summary = Summary(inputs=len(run.steps), start_ns=start)
    _account(summary, run)
    peaks: dict[str, tuple[float, float]] = {}
    margin = reserve = None
    kinds: Counter = Counter()
    for step in run.steps:
        kinds.update((f.level.name, f.code.ident) for f in step.findings)
        if step.pose is None:
            continue
        at = (step.stamp_ns - start) * 1e-9
        result, machine = step.pose.result, step.pose.machine
        for (name, _, _), magnitude in zip(result.names.hinges, result.hinge_magnitude.tolist()):
            if magnitude > peaks.get(name, (-1.0, 0.0))[0]:
                peaks[name] = (magnitude, at)
        value = machine.value("margin")
        if math.isfinite(value) and (margin is None or value < margin[0]):
            margin = (value, at)
        value = machine.value("reserve")
        if math.isfinite(value) and (reserve is None or value < reserve[0]):
            reserve = (value, at)
    assert summary.solved == sum(step.pose is not None for step in run.steps)
    assert summary.kinds == kinds and summary.peak_hinge == peaks
    assert (summary.min_margin, summary.min_reserve) == (margin, reserve)


def _same_step(quiet, built) -> None:
    assert (quiet.stamp_ns, quiet.trigger, quiet.findings, quiet.inputs) == (built.stamp_ns, built.trigger,
                                                                             built.findings, built.inputs)
    assert quiet.pose is not None and built.pose is not None and quiet.pose.budget is None
    np.testing.assert_array_equal(quiet.pose.values, built.pose.values)
    np.testing.assert_array_equal(quiet.pose.result.hinge_force, built.pose.result.hinge_force)
    assert quiet.pose.result.message == built.pose.result.message
    np.testing.assert_array_equal(quiet.pose.machine.steerability_row, built.pose.machine.steerability_row)


def test_a_quiet_pose_is_built_only_when_asked_for_as_the_run_builds_it() -> None:
    """``Monitor.runs``' pieces leave the Step of a solved pose without findings unbuilt (``Steps``: the
    replay writes its outputs from the segment's columns); asked for by index, through a slice or by
    ``results``, it is the Step ``Monitor.run`` gives the same event, and it is built once."""
    mech, config, events = _events()
    built = Monitor(mech, config).run(events).steps
    pieces = list(Monitor(mech, config).runs(events, piece_steps=97))
    quiet = [int(piece.steps.is_quiet.sum()) for piece in pieces]
    assert 0 < sum(quiet) < len(built), quiet   # the disagreeing halves are WARNs: built by the core
    assert all(piece.steps.made[i] is None for piece in pieces for i in np.flatnonzero(piece.steps.is_quiet))
    start = 0
    for piece in pieces:
        steps, half = piece.steps, len(piece.steps) // 2
        tail = steps[half:]
        np.testing.assert_array_equal(tail.stamps_ns, [s.stamp_ns for s in built[start + half:start + len(steps)]])
        for i in np.flatnonzero(tail.is_quiet).tolist():
            _same_step(tail[i], built[start + half + i])
            assert tail[i] is tail[i]
        assert all(piece.steps.made[i] is None for i in np.flatnonzero(steps.is_quiet))   # the slice built its own
        solved = [i for i in range(len(steps)) if built[start + i].pose is not None]
        for i, result in zip(solved, steps.results(solved)):
            np.testing.assert_array_equal(result.point_xz, built[start + i].pose.result.point_xz)
        for step, whole in zip(steps, built[start:start + len(steps)]):   # every Step of the piece built
            if step.findings or step.pose is None:
                assert [f.text for f in step.findings] == [f.text for f in whole.findings]
            else:
                _same_step(step, whole)
        start += len(steps)
    assert start == len(built)
