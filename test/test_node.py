"""The live node over real topics: a node process, a test client in this process.

Expected values come from the offline solver (linkage_monitor.mechanics, called here on the
same inputs), never from the node's own code path.
"""

from __future__ import annotations

import math
import time

import numpy as np
import pytest
from rcl_interfaces.srv import SetParameters
from rclpy.parameter import Parameter

from linkage_monitor.mechanics.constants import ATMOSPHERIC_PRESSURE
from linkage_monitor.mechanics import DeadCentreError, Inputs, Solver, apply_overrides, load_preset
from linkage_monitor.mechanics.capacity import stroke_mechanism
from linkage_monitor.mechanics.machine import MachineModel
from linkage_monitor.mechanics.results import angle_readings
from linkage_monitor.wire.cdr import stamp_ns
from linkage_monitor.offline.replay import replay
from support.fixtures import FIXTURES
from support.ros_harness import MonitorClient, node_bag, start_node, stop

T0 = (time.time_ns() // 10**9) * 10**9  # ns, now (whole s): the node refuses stamps far from its clock
JOINTS = ["lift_cylinder", "lift_arm_angle"]
PRESSURE_TOPIC = "pressure/lift_cap_pressure"


def _pose(stroke: float) -> tuple[float, float]:
    """A consistent (stroke m, lift-arm angle rad) pair: the angle from the offline kinematics
    driven by the stroke alone."""
    mech = load_preset("belarus_1221")
    batch = Solver(stroke_mechanism(mech)).solve_batch(cylinders={"lift_cylinder": np.array([stroke])})
    return stroke, float(angle_readings(mech, batch)["lift_arm_angle"][0])


def _send(client: MonitorClient, stamp: int, stroke: float, angle: float, gauge_pa: float) -> None:
    """Pressure at `stamp`, then (after it has had time to arrive: two DDS writers keep no
    order between them) the joint state at `stamp` + 1 µs, whose solve uses both."""
    client.publish_pressure(PRESSURE_TOPIC, stamp, gauge_pa + ATMOSPHERIC_PRESSURE)
    client.spin_until(lambda: False, 0.3)
    client.publish_joint_state(stamp + 1000, JOINTS, [stroke, angle])


def test_outputs_equal_offline_solver_and_carry_input_stamps(node):
    client, _, _ = node
    mech = load_preset("belarus_1221")
    offline = Solver(mech)
    machine = MachineModel(mech, offline)
    cases = []
    for k, (stroke, gauge) in enumerate([(0.54, 9.9e6), (0.60, 8.7e6), (0.66, 9.4e6), (0.70, 9.2e6)]):
        s, angle = _pose(stroke)
        stamp = T0 + k * 100_000_000
        _send(client, stamp, s, angle, gauge)
        cases.append((stamp + 1000, s, angle, gauge))
    assert client.spin_until(lambda: all(client.outputs_at("steerability", c[0]) for c in cases), 30)
    for stamp, s, angle, gauge in cases:
        expected = offline.solve(Inputs(cylinders={"lift_cylinder": s}, angles={"lift_arm_angle": angle},
                                        pressures={"lift_cap_pressure": gauge}))
        hinges = client.outputs_at("hinge_reactions", stamp)[0]
        assert stamp_ns(hinges.header) == stamp
        assert [h.name for h in hinges.hinges] == [h.name for h in mech.hinges]
        for h in hinges.hinges:
            ref = expected.hinges[h.name]
            assert h.fx == pytest.approx(ref.fx, rel=1e-9, abs=1e-6)
            assert h.fz == pytest.approx(ref.fz, rel=1e-9, abs=1e-6)
        hitch = client.outputs_at("hitch_state", stamp)[0]
        assert hitch.implement_load == pytest.approx(expected.implement_load, rel=1e-9)
        # stroke, angle and the cap pressure: a chain of dyads the reduced path solves, the angle finite
        assert math.isfinite(expected.transmission_angle) and 0.0 <= expected.transmission_angle <= math.pi / 2
        assert hitch.min_transmission_angle == pytest.approx(expected.transmission_angle, rel=1e-9)
        assert hitch.implement_load_estimated
        cyl = hitch.cylinders[0]
        assert cyl.force == pytest.approx(expected.cylinders["lift_cylinder"].force, rel=1e-9)
        assert cyl.cap_pressure_measured == pytest.approx(gauge, rel=1e-12)
        steer = client.outputs_at("steerability", stamp)[0]
        ref_machine = machine.evaluate(expected)
        assert steer.front_axle_load == pytest.approx(ref_machine.steerability["front_axle_load"], rel=1e-9)
        assert steer.margin == pytest.approx(ref_machine.steerability["margin"], rel=1e-9, abs=1e-12)
        assert hitch.lift_capacity_implement_cg == pytest.approx(ref_machine.lift_capacity["implement_cg"],
                                                                  rel=1e-9)


@pytest.mark.parametrize("bad, expect", [
    ("nan_angle", "lift_arm_angle' position is nan"),
    ("inf_stroke", "lift_cylinder' position is inf"),
    ("length_mismatch", "2 names but 1 positions"),
    ("unknown_joint", "'rockshaft' are unknown"),
    ("negative_pressure", "negative absolute pressure"),
    ("unassemblable", "cannot assemble"),
])
def test_bad_input_gives_error_diagnostic_then_good_input_solves(node, bad, expect):
    client, proc, _ = node
    mech = load_preset("belarus_1221")
    s, angle = _pose(0.60)
    good = T0 + 5_000_000_000
    _send(client, good, s, angle, 9.0e6)
    assert client.spin_until(lambda: client.outputs_at("hitch_state", good + 1000), 20)
    stamp = good + 50_000_000
    if bad == "nan_angle":
        client.publish_joint_state(stamp, JOINTS, [s, math.nan])
    elif bad == "inf_stroke":
        client.publish_joint_state(stamp, JOINTS, [math.inf, angle])
    elif bad == "length_mismatch":
        client.publish_joint_state(stamp, JOINTS, [s])
    elif bad == "unknown_joint":
        client.publish_joint_state(stamp, ["rockshaft"], [0.3])
    elif bad == "negative_pressure":
        client.publish_pressure(PRESSURE_TOPIC, stamp, -2.0e5)
    elif bad == "unassemblable":
        client.publish_joint_state(stamp, JOINTS, [0.75, angle])   # in range, but not with this angle
    assert client.spin_until(lambda: client.diagnostics_at(stamp), 20), "no diagnostic for the bad input"
    status = client.diagnostics_at(stamp)[0]
    assert status.level == b"\x02", status
    assert expect in status.message, status.message
    assert not client.outputs_at("hitch_state", stamp), "garbage was published"
    # the node is alive and solves the next good message correctly
    later = stamp + 50_000_000
    s2, angle2 = _pose(0.62)
    _send(client, later, s2, angle2, 9.1e6)
    assert client.spin_until(lambda: client.outputs_at("hitch_state", later + 1000), 20)
    assert proc.poll() is None
    expected = Solver(mech).solve(Inputs(cylinders={"lift_cylinder": s2}, angles={"lift_arm_angle": angle2},
                                         pressures={"lift_cap_pressure": 9.1e6}))
    got = client.outputs_at("hitch_state", later + 1000)[0]
    assert got.implement_load == pytest.approx(expected.implement_load, rel=1e-9)


def test_bytes_that_are_not_the_input_type_are_an_error_recorded_as_they_came_and_replayed(node):
    """A publisher's bytes that are not a JointState / FluidPressure (cut short): an ERROR on the
    monitor's status naming the topic and the type, nothing published, the bytes in the bag as
    they came (read back by rosbags), the next good input solved; the replay of the node's bag
    reports the same two errors and copies the bytes on."""
    from rclpy.serialization import serialize_message
    from rosbags.highlevel import AnyReader
    from rosbags.typesys import Stores, get_typestore
    from sensor_msgs.msg import FluidPressure, JointState

    from linkage_monitor.offline.replay import replay
    from linkage_monitor.ros.messages import header
    from support.ros_harness import node_bag

    client, proc, tmp_path = node
    s, angle = _pose(0.60)
    good = T0 + 7_000_000_000
    _send(client, good, s, angle, 9.0e6)
    assert client.spin_until(lambda: client.outputs_at("hitch_state", good + 1000), 20)
    cut_joints = serialize_message(JointState(header=header(good + 2000), name=JOINTS, position=[s, angle]))[:40]
    cut_pressure = serialize_message(FluidPressure(header=header(good + 3000), fluid_pressure=9e6))[:20]
    client.joint_pub.publish(cut_joints)
    client.spin_until(lambda: False, 0.3)
    client._pressure_pubs[PRESSURE_TOPIC].publish(cut_pressure)

    def errors() -> list:
        return [st for m in client.received["diagnostics"] for st in m.status if "cannot be read as" in st.message]
    assert client.spin_until(lambda: len(errors()) >= 2, 20), "no diagnostic for the unreadable inputs"
    joint_error, pressure_error = errors()[:2]
    assert joint_error.level == b"\x02" and joint_error.name == "linkage_monitor: belarus_1221"
    assert "input on /joint_states (40 bytes) cannot be read as sensor_msgs/msg/JointState" in joint_error.message
    assert joint_error.message.endswith(": name: 2 strings cannot fit in the 40-byte message; recorded, not solved")
    assert f"input on /{PRESSURE_TOPIC} (20 bytes) cannot be read as sensor_msgs/msg/FluidPressure" \
        in pressure_error.message
    later = good + 100_000_000
    s2, angle2 = _pose(0.62)
    _send(client, later, s2, angle2, 9.1e6)
    assert client.spin_until(lambda: client.outputs_at("hitch_state", later + 1000), 20)
    published = {stamp_ns(m.header) for m in client.received["hitch_state"]}
    assert published == {good + 1000, later, later + 1000}, "something was published for the unreadable inputs"
    assert stop(proc) == 0

    bag = node_bag(tmp_path / "bags")
    with AnyReader([bag], default_typestore=get_typestore(Stores.EMPTY)) as reader:
        recorded = [raw for c, _, raw in reader.messages() if c.topic in ("/joint_states", f"/{PRESSURE_TOPIC}")]
    assert cut_joints in recorded and cut_pressure in recorded and len(recorded) == 6
    replayed = replay(bag, out_dir=tmp_path / "replayed", progress=None)
    assert replayed.summary.kinds[("ERROR", "malformed_input")] == 2
    assert replayed.summary.solved == 3
    with AnyReader([tmp_path / "replayed"], default_typestore=get_typestore(Stores.EMPTY)) as reader:
        copied = [raw for c, _, raw in reader.messages() if c.topic in ("/joint_states", f"/{PRESSURE_TOPIC}")]
    assert copied == recorded


def test_dead_centre_over_a_topic_is_an_error_and_the_node_goes_on(ros, tmp_path):
    proc = start_node({"mechanism": str(FIXTURES / "arm_angle.yaml"), "record_dir": str(tmp_path), "stamp_tolerance": 3600.0,
                       "sensor_qos": "reliable"}, tmp_path / "node.log")
    client = MonitorClient(pressure_topics=())
    try:
        client.wait_for_node()
        for k, angle in enumerate([-math.pi / 4, -math.pi / 2, -math.pi / 3]):
            client.publish_joint_state(T0 + k, ["arm_angle"], [angle])
            assert client.spin_until(lambda k=k: client.diagnostics_at(T0 + k) or client.outputs_at(
                "hitch_state", T0 + k), 20)
        dead = client.diagnostics_at(T0 + 1)[0]
        assert dead.level == b"\x02" and dead.message.startswith("dead centre") and "transmission angle" in dead.message
        assert not client.outputs_at("hinge_reactions", T0 + 1)
        # 60 deg below the vertical: moment balance about O (closed form) for the good pose after it
        after = client.outputs_at("hitch_state", T0 + 2)[0].cylinders[0].force
        t = np.array([math.cos(-math.pi / 3 + math.pi / 2), math.sin(-math.pi / 3 + math.pi / 2)])
        u = (t - [-1.0, 0.0]) / np.linalg.norm(t - [-1.0, 0.0])
        assert after == pytest.approx(10.0 * 9.80665 * t[0] / (t[0] * u[1] - t[1] * u[0]), rel=1e-9)
    finally:
        client.close()
        assert stop(proc) == 0


def test_stale_input_warns_and_does_not_solve(node):
    client, _, _ = node
    s, angle = _pose(0.60)
    _send(client, T0, s, angle, 9.0e6)
    assert client.spin_until(lambda: client.outputs_at("hitch_state", T0 + 1000), 20)
    late = T0 + 2_000_000_000  # 2 s after the last pressure; staleness_limit is 0.5 s
    client.publish_joint_state(late, JOINTS, [s, angle])
    assert client.spin_until(lambda: client.diagnostics_at(late), 20)
    status = client.diagnostics_at(late)[0]
    assert status.level == b"\x01" and "stale input lift_cap_pressure (2 s)" in status.message
    assert not client.outputs_at("hitch_state", late)


def test_implement_mass_changed_at_runtime_applies_from_the_next_message(ros, tmp_path):
    proc = start_node({"mechanism": "belarus_1221", "record_dir": str(tmp_path), "sensor_qos": "reliable", "stamp_tolerance": 3600.0,
                       "pressure_topics": ["none"]}, tmp_path / "node.log")
    client = MonitorClient(pressure_topics=())
    try:
        client.wait_for_node()
        s, angle = _pose(0.62)
        client.publish_joint_state(T0, JOINTS, [s, angle])
        assert client.spin_until(lambda: client.outputs_at("steerability", T0), 20)
        setter = client.node.create_client(SetParameters, "/linkage_monitor/set_parameters")
        assert setter.wait_for_service(timeout_sec=10)
        refused = setter.call_async(SetParameters.Request(parameters=[
            Parameter("implement_mass", value=-0.5).to_parameter_msg()]))   # only exactly -1 keeps the file's value
        assert client.spin_until(refused.done, 10) and not refused.result().results[0].successful
        assert "implement_mass = -0.5: a value must be >= 0" in refused.result().results[0].reason
        future = setter.call_async(SetParameters.Request(parameters=[
            Parameter("implement_mass", value=3000).to_parameter_msg()]))   # an integer: taken as 3000.0 kg
        assert client.spin_until(future.done, 10) and future.result().results[0].successful, future.result()
        client.publish_joint_state(T0 + 1, JOINTS, [s, angle])
        assert client.spin_until(lambda: client.outputs_at("steerability", T0 + 1), 20)
    finally:
        client.close()
        assert stop(proc) == 0
    mech = load_preset("belarus_1221")
    before, after = (client.outputs_at("hitch_state", T0 + k)[0] for k in (0, 1))
    assert not after.implement_load_estimated
    assert before.implement_load == pytest.approx(mech.implement.mass * 9.80665, rel=1e-12)  # the file's mass
    assert after.implement_load == pytest.approx(3000.0 * 9.80665, rel=1e-12)               # the new parameter
    heavy = apply_overrides(load_preset("belarus_1221"), {"implement.mass": 3000.0})
    offline = Solver(heavy).solve(Inputs(cylinders={"lift_cylinder": s}, angles={"lift_arm_angle": angle}))
    expected = MachineModel(heavy, Solver(heavy)).evaluate(offline).steerability["margin"]
    assert client.outputs_at("steerability", T0 + 1)[0].margin == pytest.approx(expected, rel=1e-9)


def test_dead_centre_threshold_changed_at_runtime_applies_from_the_next_message(node):
    """dead_centre_transmission_deg set at run time: 50 (outside its range, 0 to 45 degrees) is
    refused with rclpy's reason; 45, above this pose's lift cylinder step's transmission angle (the
    offline solver's, 42 degrees at a 0.53 m stroke; its implement load's, 26 degrees, is an inference
    from the pressure, judged by its amplification: docs/dead-centre.md), makes the same pose a dead
    centre from the next message on (an ERROR diagnostic, no outputs), as the offline solver with that
    threshold says; back at 1 degree (the default) the pose is solved again."""
    client, proc, tmp_path = node
    mech = load_preset("belarus_1221")
    s, angle = _pose(0.53)
    inputs = Inputs(cylinders={"lift_cylinder": s}, angles={"lift_arm_angle": angle},
                    pressures={"lift_cap_pressure": 9.0e6})
    expected = Solver(mech).solve(inputs).transmission_angle   # rad
    assert math.isfinite(expected) and math.degrees(expected) < 45.0
    with pytest.raises(DeadCentreError):
        Solver(mech, dead_centre_transmission_deg=45.0).solve(inputs)
    setter = client.node.create_client(SetParameters, "/linkage_monitor/set_parameters")
    assert setter.wait_for_service(timeout_sec=10)

    def set_threshold(degrees: float):
        future = setter.call_async(SetParameters.Request(parameters=[
            Parameter("dead_centre_transmission_deg", value=degrees).to_parameter_msg()]))
        assert client.spin_until(future.done, 10)
        return future.result().results[0]

    stamps = [T0 + k * 100_000_000 for k in range(3)]
    _send(client, stamps[0], s, angle, 9.0e6)
    assert client.spin_until(lambda: client.outputs_at("hitch_state", stamps[0] + 1000), 20)
    assert client.outputs_at("hitch_state", stamps[0] + 1000)[0].min_transmission_angle == pytest.approx(expected,
                                                                                                       rel=1e-9)
    refused = set_threshold(50.0)
    assert not refused.successful and "dead_centre_transmission_deg out of range" in refused.reason, refused
    assert set_threshold(45.0).successful
    _send(client, stamps[1], s, angle, 9.0e6)
    assert client.spin_until(lambda: client.diagnostics_at(stamps[1] + 1000), 20)
    dead = client.diagnostics_at(stamps[1] + 1000)[0]
    assert dead.level == b"\x02" and dead.message.startswith("dead centre"), dead.message
    assert not client.outputs_at("hitch_state", stamps[1] + 1000)
    assert set_threshold(1.0).successful
    _send(client, stamps[2], s, angle, 9.0e6)
    assert client.spin_until(lambda: client.outputs_at("hitch_state", stamps[2] + 1000), 20)
    # the bag records each change with the configuration; its replay makes the same verdicts
    assert stop(proc) == 0
    steps = {step.stamp_ns: step for step in replay(node_bag(tmp_path / "bags"), progress=None).steps}
    assert [steps[t + 1000].pose is not None for t in stamps] == [True, False, True]
    assert steps[stamps[1] + 1000].message.startswith("dead centre")


def test_a_cold_kernel_cache_is_compiled_before_the_inputs_are_subscribed(ros, tmp_path, monkeypatch):
    """A node whose numba cache is cold (a colcon install without the warm-up, a new cache
    directory) compiles its kernels before it subscribes: a sensor that publishes as soon as it
    sees the subscription is solved, not left waiting in the queue until its stamp is older than
    stamp_tolerance (the default, 10 s; the compile takes longer here). The log says it compiled."""
    monkeypatch.setenv("NUMBA_CACHE_DIR", str(tmp_path / "numba_cache"))   # numba's cache, empty
    proc = start_node({"mechanism": "belarus_1221", "record_dir": str(tmp_path / "bags"), "sensor_qos": "reliable"},
                      tmp_path / "node.log")
    client = MonitorClient()
    try:
        client.wait_for_node(timeout=600.0)
        now = client.node.get_clock().now().nanoseconds
        stroke, angle = _pose(0.60)
        _send(client, now, stroke, angle, 9.0e6)
        assert client.spin_until(lambda: bool(client.outputs_at("hitch_state", now + 1000)), 30), \
            (tmp_path / "node.log").read_text()
    finally:
        client.close()
        assert stop(proc) == 0
    log = (tmp_path / "node.log").read_text()
    assert "numba compiled" in log and "physics kernel(s)" in log, log
    assert any((tmp_path / "numba_cache").rglob("*.nbc")), "the node should have compiled into NUMBA_CACHE_DIR"
