"""The linkage as visualization_msgs/MarkerArray: published by the live node at its display
rate, recorded in its bag, decoded by rosbags and by mcap-ros2-support (readers we did not
write), and checked against a fresh solver's points and forces (a replay of the same bag); the
bytes the package writes by hand against rclpy's own message and serialization."""

from __future__ import annotations

import time

import dataclasses

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory

from rclpy.serialization import deserialize_message, serialize_message
from visualization_msgs.msg import MarkerArray

from linkage_monitor.wire.definitions import exact_cdr
from linkage_monitor.mechanics import Inputs, Solver, load_preset, preset_names
from linkage_monitor.mechanics.constants import ATMOSPHERIC_PRESSURE
from linkage_monitor.offline.replay import replay
from linkage_monitor.wire.markers import FRAME, MARKER_ARRAY, LinkageMarkers
from linkage_monitor.wire.cdr import stamp_ns
from linkage_monitor.viz.drawing import ARROW_LENGTH, body_outline
from oracles import markers as oracle_markers
from support.messages import assert_same_message
from support.ros_harness import node_bag, read_bag_rosbags, settle, stop

T0 = (time.time_ns() // 10**9) * 10**9
JOINTS = ["lift_cylinder", "lift_arm_angle"]
PRESSURE_TOPIC = "pressure/lift_cap_pressure"


def _markers_mcap(bag) -> list:
    with open(next(bag.glob("*.mcap")), "rb") as f:
        return [m for _, c, _, m in make_reader(f, decoder_factories=[DecoderFactory()]).iter_decoded_messages(
            topics=["/linkage_markers"])]


def test_node_publishes_and_records_the_linkage_as_markers(node):
    client, proc, tmp_path = node
    mech = load_preset("belarus_1221")
    from support.lift_pose import lift_pose   # a consistent (stroke, angle) pair from the offline kinematics

    strokes = [0.54, 0.58, 0.62, 0.66, 0.70]
    for k, stroke in enumerate(strokes):   # 150 ms apart: every pose is due at the default 10 Hz
        stamp = T0 + k * 150_000_000
        client.publish_pressure(PRESSURE_TOPIC, stamp, 9e6 + ATMOSPHERIC_PRESSURE)
        client.spin_until(lambda: False, 0.2)
        client.publish_joint_state(stamp + 1000, JOINTS, list(lift_pose(stroke)))
    assert client.spin_until(lambda: len(client.received["hinge_reactions"]) >= len(strokes), 20)
    settle(client, "diagnostics", quiet=0.5)
    assert stop(proc) == 0
    bag = node_bag(tmp_path / "bags")

    fresh = {s.stamp_ns: s.pose.result for s in replay(bag, progress=None).run.steps if s.pose is not None}
    by_rosbags = [m for t, _, m in read_bag_rosbags(bag) if t == "/linkage_markers"]
    by_mcap = _markers_mcap(bag)
    assert len(by_rosbags) == len(by_mcap) == len(strokes)   # one per solved JointState pose, none lost
    first = fresh[stamp_ns(by_mcap[0].markers[0].header)]
    largest = max(max(h.magnitude for h in first.hinges.values()),
                  max(abs(c.force) for c in first.cylinders.values()))
    scale = ARROW_LENGTH / largest      # the Rerun view's rule: the first pose's largest force is 0.4 m
    hinges = [(h.name, h.point) for h in mech.hinges]
    for array in (*by_rosbags, *by_mcap):
        stamp = stamp_ns(array.markers[0].header)
        result = fresh[stamp]
        ns = {}
        for m in array.markers:
            assert m.header.frame_id == FRAME and stamp_ns(m.header) == stamp
            ns.setdefault(m.ns, []).append(m)
        xz = lambda p: (p.x, p.z)   # noqa: E731 - the plane y = 0
        assert all(p.y == 0.0 for m in array.markers for p in m.points)
        for body, strip in zip(mech.bodies, ns["links"]):
            want = [result.points[p] for p in body_outline(mech, body.points)]
            np.testing.assert_allclose([xz(p) for p in strip.points], want, atol=1e-9)
        np.testing.assert_allclose([xz(p) for p in ns["hinges"][0].points],
                                   [result.points[p] for _, p in hinges], atol=1e-9)
        for (name, point), arrow, label in zip(hinges, ns["reactions"], ns["labels"]):
            r = result.hinges[name]
            start, end = np.array(xz(arrow.points[0])), np.array(xz(arrow.points[1]))
            np.testing.assert_allclose(start, result.points[point], atol=1e-9)
            np.testing.assert_allclose((end - start) / scale, [r.fx, r.fz], rtol=1e-9, atol=1e-6)
            assert label.text == f"{name} {r.magnitude / 1e3:.1f} kN"
        (cylinder,) = mech.cylinders
        arrow = ns["cylinder_forces"][0]
        drawn = np.linalg.norm(np.subtract(xz(arrow.points[1]), xz(arrow.points[0]))) / scale
        assert drawn == pytest.approx(abs(result.cylinders[cylinder.name].force), rel=1e-9)


@pytest.mark.parametrize("name", preset_names())
def test_marker_bytes_are_what_rclpy_builds(name):
    """The MarkerArray bytes the package writes (wire.markers, CDR by its layout) decode with rclpy to the
    message an rclpy builder makes field by field (oracle: test/oracles/markers.py), floats bit
    for bit, and have its exact CDR length (rclpy's buffer cut by rosbags' decoder); on every
    preset, over a simulated lift (several poses: the force scale fixed by the first)."""
    mech = load_preset(name)
    solver = Solver(mech)
    ref = solver.kin.reference_inputs()
    nc = len(mech.measurements.cylinders)
    ours, theirs = LinkageMarkers(mech), oracle_markers.LinkageMarkers(mech)
    stamp = 1_700_000_000_123_456_789
    for k, factor in enumerate((1.0, 1.0005, 0.9995)):
        s = ref * np.where(np.arange(ref.size) < nc, factor, 1.0)
        result = solver.solve(Inputs(cylinders=dict(zip(solver.kin.input_names[:nc], s[:nc])),
                                     angles=dict(zip(solver.kin.input_names[nc:], s[nc:])),
                                     pressures=dict(mech.reference_inputs.get("pressures", {}))))
        data, msg = ours.markers(stamp + k, result), theirs.markers(stamp + k, result)
        assert isinstance(data, bytes)
        wire = serialize_message(msg)   # what a subscriber of the oracle gets (float32 colours rounded)
        assert_same_message(deserialize_message(data, MarkerArray), deserialize_message(wire, MarkerArray), "markers")
        assert len(data) == len(exact_cdr(MARKER_ARRAY, wire))


@pytest.mark.parametrize("name", preset_names())
def test_the_markers_of_many_poses_at_once_are_those_of_each_pose(name):
    """``markers_of`` (the replay: all drawn poses of a block at once, grouped by their labels' lengths)
    gives each pose the bytes ``markers`` gives it alone, in order (the force scale fixed by the first):
    poses of a lift on every preset, their hinge forces scaled so that the labels take several lengths."""
    mech = load_preset(name)
    solver = Solver(mech)
    ref = solver.kin.reference_inputs()
    nc = len(mech.measurements.cylinders)
    results = []
    for k, factor in enumerate((1.0, 1.0005, 0.9995, 1.001)):
        s = ref * np.where(np.arange(ref.size) < nc, factor, 1.0)
        result = solver.solve(Inputs(cylinders=dict(zip(solver.kin.input_names[:nc], s[:nc])),
                                     angles=dict(zip(solver.kin.input_names[nc:], s[nc:])),
                                     pressures=dict(mech.reference_inputs.get("pressures", {}))))
        results.append(dataclasses.replace(result, hinge_force=result.hinge_force * 100.0 ** k))
    stamps = [1_700_000_000_123_456_789 + k * 100_000_000 for k in range(len(results))]
    one_by_one = LinkageMarkers(mech)
    assert LinkageMarkers(mech).markers_of(stamps, results) == [one_by_one.markers(t, r) for t, r in zip(stamps, results)]
    assert len(set(map(len, one_by_one.markers_of(stamps, results)))) > 1   # the labels took several lengths


@pytest.mark.slow
@settings(max_examples=60, deadline=None)
@given(exponents=st.lists(st.floats(-4.0, 7.0), min_size=1, max_size=12), sign=st.sampled_from([1.0, -1.0]))
def test_labels_of_any_length_are_spliced_as_rclpy_builds(exponents, sign):
    """The label texts change length with the forces ("P03 9.9 kN", "P03 10.0 kN", "P03 1234567.9 kN"),
    and with them the alignment padding after each: the package lays the message out once per pattern
    of text lengths and splices the texts in. Hinge forces scaled by 10^e (hypothesis), belarus_1221,
    compared with rclpy's message (oracle) pose after pose through one builder whose layout cache
    holds 2 patterns (so layouts are dropped and laid out again)."""
    mech = load_preset("belarus_1221")
    solver = Solver(mech)
    result = solver.solve(Inputs(**{k: dict(v) for k, v in mech.reference_inputs.items()}))
    ours, theirs = LinkageMarkers(mech), oracle_markers.LinkageMarkers(mech)
    ours.MAX_LAYOUTS = 2
    for k, e in enumerate(exponents):
        factor = sign * 10.0 ** (e + np.arange(len(mech.hinges)) * 0.37 % 3)   # a different length per hinge
        scaled = dataclasses.replace(result, hinge_force=result.hinge_force * factor[:, None])
        data, msg = ours.markers(1_700_000_000_000_000_000 + k, scaled), theirs.markers(1_700_000_000_000_000_000 + k,
                                                                                        scaled)
        assert_same_message(deserialize_message(data, MarkerArray),
                            deserialize_message(serialize_message(msg), MarkerArray), "markers")
        assert len(data) == len(exact_cdr(MARKER_ARRAY, serialize_message(msg)))
