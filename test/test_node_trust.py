"""Never wrong with OK, never down — the faults a tractor's sensors and network produce, over real topics.

The live node runs in a child process (or, to inject a failure, in this process); inputs go
over real rclpy pub/sub. Oracles: a fresh solver from the reference pose on the true
(unwrapped) inputs, and the readers we did not write (rosbags, mcap) for the bag.
"""

from __future__ import annotations

import math
import time

import numpy as np
import pytest
import rclpy
from builtin_interfaces.msg import Time
from rclpy.executors import SingleThreadedExecutor
from rosgraph_msgs.msg import Clock

from linkage_monitor.bag.reader import read_bag
from linkage_monitor.mechanics.constants import ATMOSPHERIC_PRESSURE
from linkage_monitor.mechanics import Solver, load_preset
from linkage_monitor.monitoring.core import ASSEMBLY_LIMIT_M
from linkage_monitor.wire.cdr import stamp_ns
from linkage_monitor.sim.telemetry import Noise, simulate
from support.ros_harness import MonitorClient, node_bag, read_bag_rosbags, settle, start_node, stop

PRESSURE_TOPIC = "pressure/lift_cap_pressure"
BELARUS = load_preset("belarus_1221")


def _lift(start_ns: int):
    """The simulator's full lift of belarus_1221 (stroke + lift-arm angle + cap pressure), noise-free,
    the pressure held at its first value (two topics keep no order between them: with a constant
    pressure every solve sees the value the oracle uses)."""
    stream = simulate(BELARUS, "lift", rate_hz=20.0, noise=Noise(0.0, 0.0, 0.0), seed=1, start_ns=start_ns)
    stream.pressure_values[:] = stream.pressure_values[0]
    return stream


def _fresh(stream) -> dict[str, np.ndarray]:
    """Hinge forces (N, 2) per hinge from a fresh solver on the stream's true inputs (the oracle)."""
    names = list(stream.joint_names)
    batch = Solver(BELARUS, consistency_tol=ASSEMBLY_LIMIT_M).solve_batch(
        cylinders={"lift_cylinder": stream.joint_positions[:, names.index("lift_cylinder")]},
        angles={"lift_arm_angle": stream.joint_positions[:, names.index("lift_arm_angle")]},
        pressures={"lift_cap_pressure": stream.pressure_values[:, 0]})
    assert np.all(batch.status == 0)
    return batch.hinge_force


def _burst(client: MonitorClient, stream) -> int:
    """One joint state the node takes (1 ms before the stream), then the stream's joint states ten times
    over as fast as the client publishes, stamps 1 ns apart from the stream's on; returns how many the
    burst published. The input taken first: losses before the first message the node takes from a
    publisher are invisible to sequence-gap counting (monitoring/loss.py), the burst's are not."""
    names = list(stream.joint_names)
    first = int(stream.stamps_ns[0]) - 1_000_000
    client.publish_joint_state(first, names, stream.joint_positions[0].tolist())
    assert client.spin_until(lambda: client.outputs_at("hinge_reactions", first), 10)
    sent = 0
    for _ in range(10):
        for i, stamp in enumerate(stream.stamps_ns.tolist()):
            client.publish_joint_state(stamp + sent + 1, names, stream.joint_positions[i].tolist())
            sent += 1
    return sent


def _play(client: MonitorClient, stream, angle_of, pace: float = 0.02) -> None:
    """Pressure at stamp, then the joint state at stamp + 1 µs (which triggers the solve)."""
    names = list(stream.joint_names)
    k = names.index("lift_arm_angle")
    for i, stamp in enumerate(stream.stamps_ns.tolist()):
        client.publish_pressure(PRESSURE_TOPIC, stamp, float(stream.pressure_values[i, 0]) + ATMOSPHERIC_PRESSURE)
        client.spin_until(lambda: False, pace / 2)
        positions = stream.joint_positions[i].tolist()
        positions[k] = angle_of(i, positions[k])
        client.publish_joint_state(stamp + 1000, names, positions)
        client.spin_until(lambda: False, pace / 2)
    settle(client, "hinge_reactions", quiet=1.0)


def _assert_outputs_equal_fresh(client: MonitorClient, stream) -> None:
    expected = _fresh(stream)
    got = {stamp_ns(m.header): m for m in client.received["hinge_reactions"]}
    for i, stamp in enumerate(stream.stamps_ns.tolist()):
        msg = got.get(stamp + 1000)
        assert msg is not None, f"no HingeReactions for pose {i}"
        for h in msg.hinges:
            ref = expected[h.name][i]
            scale = max(float(np.hypot(*ref)), 1.0)
            assert abs(h.fx - ref[0]) <= 1e-9 * scale and abs(h.fz - ref[1]) <= 1e-9 * scale, (i, h.name, h, ref)


def _wrap_pm_pi(_: int, a: float) -> float:
    return (a + math.pi) % (2 * math.pi) - math.pi


def _wrap_0_2pi(_: int, a: float) -> float:
    return a % (2 * math.pi)


@pytest.mark.parametrize("convention", [_wrap_pm_pi, _wrap_0_2pi], ids=["minus_pi_to_pi", "zero_to_2pi"])
def test_wrapping_angle_sensor_over_a_full_lift_gives_the_fresh_solvers_loads(node, convention):
    client, proc, _ = node
    stream = _lift(time.time_ns())
    angles = stream.joint_positions[:, list(stream.joint_names).index("lift_arm_angle")]
    wrapped = np.array([convention(0, a) for a in angles])
    assert np.any(np.abs(wrapped - angles) > 6.0), "the lift must cross the sensor's wrap"
    _play(client, stream, convention)
    _assert_outputs_equal_fresh(client, stream)
    assert proc.poll() is None


def test_one_reading_off_by_2pi_changes_nothing(node):
    client, proc, _ = node
    stream = _lift(time.time_ns())
    n = len(stream.stamps_ns)
    _play(client, stream, lambda i, a: a + 2 * math.pi if i == n // 2 else a)
    _assert_outputs_equal_fresh(client, stream)


def test_huge_stroke_after_good_inputs_is_refused_and_the_node_goes_on(node):
    """The three-message crash: a valid pressure, a valid JointState, then a stroke of 1e308."""
    client, proc, _ = node
    stream = _lift(time.time_ns())
    names = list(stream.joint_names)
    t = int(stream.stamps_ns[0])
    client.publish_pressure(PRESSURE_TOPIC, t, float(stream.pressure_values[0, 0]) + ATMOSPHERIC_PRESSURE)
    client.spin_until(lambda: False, 0.3)
    client.publish_joint_state(t + 1000, names, stream.joint_positions[0].tolist())
    assert client.spin_until(lambda: client.outputs_at("hinge_reactions", t + 1000), 20)
    bad = stream.joint_positions[1].tolist()
    bad[names.index("lift_cylinder")] = 1e308
    client.publish_joint_state(t + 2000, names, bad)
    assert client.spin_until(lambda: client.diagnostics_at(t + 2000), 20)
    status = client.diagnostics_at(t + 2000)[0]
    assert status.level == b"\x02" and "lift_cylinder" in status.message and "1e+308" in status.message
    assert not client.outputs_at("hinge_reactions", t + 2000)
    client.publish_joint_state(t + 3000, names, stream.joint_positions[1].tolist())
    assert client.spin_until(lambda: client.outputs_at("hinge_reactions", t + 3000), 20), "no solve after the glitch"
    assert proc.poll() is None


def test_negative_stamp_is_an_error_and_the_bag_stays_readable(node):
    client, proc, tmp_path = node
    stream = _lift(time.time_ns())
    names = list(stream.joint_names)
    from sensor_msgs.msg import JointState
    msg = JointState(name=names, position=stream.joint_positions[0].tolist())
    msg.header.stamp = Time(sec=-5, nanosec=0)
    client.joint_pub.publish(msg)
    assert client.spin_until(lambda: any(s.level == b"\x02" and "not after 1970" in s.message
                                         for m in client.received["diagnostics"] for s in m.status), 20)
    t = int(stream.stamps_ns[0])
    client.publish_pressure(PRESSURE_TOPIC, t, float(stream.pressure_values[0, 0]) + ATMOSPHERIC_PRESSURE)
    client.spin_until(lambda: False, 0.3)
    client.publish_joint_state(t + 1000, names, stream.joint_positions[0].tolist())
    assert client.spin_until(lambda: client.outputs_at("hinge_reactions", t + 1000), 20)
    assert stop(proc) == 0
    bag = node_bag(tmp_path / "bags")
    topics = [topic for topic, _, _ in read_bag_rosbags(bag)]
    assert topics.count("/joint_states") == 2       # the bad input is recorded as sent
    assert sum(1 for _ in read_bag(bag)) == len(topics)


def test_use_sim_time_stamps_are_judged_against_clock(ros, tmp_path):
    """With use_sim_time the node's clock is /clock: inputs stamped at sim time are solved,
    inputs stamped at wall time (far from sim time) are refused."""
    sim_ns = 1_000 * 10**9   # s into a simulation
    proc = start_node({"mechanism": "belarus_1221", "record_dir": str(tmp_path / "bags"), "sensor_qos": "reliable",
                       "use_sim_time": True}, tmp_path / "node.log")
    client = MonitorClient()
    clock = client.node.create_publisher(Clock, "/clock", 10)
    try:
        client.wait_for_node()
        for _ in range(20):
            clock.publish(Clock(clock=Time(sec=sim_ns // 10**9)))
            client.spin_until(lambda: False, 0.05)
        stream = _lift(sim_ns)
        names = list(stream.joint_names)
        client.publish_pressure(PRESSURE_TOPIC, sim_ns, float(stream.pressure_values[0, 0]) + ATMOSPHERIC_PRESSURE)
        client.spin_until(lambda: False, 0.3)
        client.publish_joint_state(sim_ns + 1000, names, stream.joint_positions[0].tolist())
        assert client.spin_until(lambda: client.outputs_at("hinge_reactions", sim_ns + 1000), 20), \
            (tmp_path / "node.log").read_text()
        wall = time.time_ns()
        client.publish_joint_state(wall, names, stream.joint_positions[0].tolist())
        assert client.spin_until(lambda: client.diagnostics_at(wall), 20)
        status = client.diagnostics_at(wall)[0]
        assert status.level == b"\x02" and "ahead of the monitor's clock" in status.message
    finally:
        client.close()
        assert stop(proc) == 0


def test_inputs_the_node_could_not_take_are_counted_and_reported(ros, tmp_path):
    """A burst far above the node's solve rate into a small reliable queue: what the node did
    not record it reports lost on /diagnostics — published = recorded + reported lost, in the
    node's bag (which also holds the report of losses found after the last heartbeat, written at
    shutdown) and, as far as the client listened, on /diagnostics."""
    proc = start_node({"mechanism": "belarus_1221", "record_dir": str(tmp_path / "bags"), "sensor_qos": "reliable",
                       "reliable_queue_depth": 100, "pressure_topics": ["none"]}, tmp_path / "node.log")
    client = MonitorClient(pressure_topics=())
    try:
        client.wait_for_node()
        sent = 1 + _burst(client, _lift(time.time_ns()))   # the input taken first, then the burst
        settle(client, "hinge_reactions", quiet=2.0)
        client.spin_until(lambda: False, 2.5)   # the next heartbeats carry the loss report
        reported = client.statuses(": inputs")
    finally:
        client.close()
        assert stop(proc) == 0
    bag = node_bag(tmp_path / "bags")
    recorded = sum(1 for _ in read_bag(bag, topics=["/joint_states"]))
    in_bag = [s for *_, m in read_bag(bag, topics=["/diagnostics"]) for s in m.status if s.name.endswith(": inputs")]
    lost = sum(int(s.message.split(" ", 1)[0]) for s in in_bag)
    assert recorded < sent, "the burst must exceed the node: otherwise this test shows nothing"
    assert all(s.level == b"\x01" for s in in_bag + reported)
    assert recorded + lost == sent, (recorded, lost, sent, in_bag[-1].message if in_bag else "no loss report")
    assert [s.message for s in reported] == [s.message for s in in_bag[:len(reported)]]   # published as recorded


def test_losses_are_reported_on_the_steady_clock_with_sim_time_stopped(ros, tmp_path):
    """use_sim_time with /clock published once and then stopped (a paused simulation, a bag player
    that died): a burst the node cannot take is still reported lost on /diagnostics within a couple
    of seconds of wall time (the heartbeat runs on the steady clock), not only at shutdown."""
    sim_ns = 2_000 * 10**9
    proc = start_node({"mechanism": "belarus_1221", "record_dir": str(tmp_path / "bags"), "sensor_qos": "reliable",
                       "reliable_queue_depth": 100, "pressure_topics": ["none"], "use_sim_time": True,
                       "stamp_tolerance": 1e6}, tmp_path / "node.log")
    client = MonitorClient(pressure_topics=())
    clock = client.node.create_publisher(Clock, "/clock", 10)

    def reported() -> list:
        return client.statuses(": inputs", b"\x01")
    try:
        client.wait_for_node()
        for _ in range(10):   # the simulation's clock, then it stops
            clock.publish(Clock(clock=Time(sec=sim_ns // 10**9)))
            client.spin_until(lambda: False, 0.05)
        _burst(client, _lift(sim_ns))
        burst_end = time.monotonic()
        assert client.spin_until(reported, 3.0), "no loss report within 3 s of wall time with /clock stopped"
        waited = time.monotonic() - burst_end
    finally:
        client.close()
        assert stop(proc) == 0
    assert int(reported()[0].message.split(" ", 1)[0]) > 0, reported()[0].message
    assert waited <= 3.0


def test_a_publisher_the_node_cannot_hear_is_named_on_diagnostics(ros, tmp_path):
    """The middleware's events of the inputs (taken at the heartbeat, ros/input_events.py): a
    best-effort JointState publisher while the node subscribes reliably never reaches the node — a
    WARN `<node>: inputs` names the topic and the policy, on /diagnostics and in the bag; the
    inputs of a matching publisher still solve."""
    from rclpy.qos import QoSProfile, ReliabilityPolicy
    from sensor_msgs.msg import JointState

    proc = start_node({"mechanism": "belarus_1221", "record_dir": str(tmp_path / "bags"), "sensor_qos": "reliable",
                       "stamp_tolerance": 600.0, "staleness_limit": 600.0}, tmp_path / "node.log")
    client = MonitorClient()

    def warned() -> list:
        return client.statuses(": inputs", b"\x01")
    try:
        client.wait_for_node()
        client.node.create_publisher(JointState, "joint_states", QoSProfile(depth=5,
                                                                            reliability=ReliabilityPolicy.BEST_EFFORT))
        assert client.spin_until(warned, 10.0), "no WARN about the best-effort publisher"
        stream = _lift(time.time_ns())
        stamp = int(stream.stamps_ns[0])
        client.publish_pressure(PRESSURE_TOPIC, stamp, float(stream.pressure_values[0, 0]) + ATMOSPHERIC_PRESSURE)
        client.spin_until(lambda: False, 0.2)
        client.publish_joint_state(stamp + 1, list(stream.joint_names), stream.joint_positions[0].tolist())
        assert client.spin_until(lambda: client.outputs_at("hinge_reactions", stamp + 1), 10)
    finally:
        client.close()
        assert stop(proc) == 0
    messages = [s.message for s in warned()]
    assert len(messages) == 1 and "1 publisher(s) on /joint_states" in messages[0], messages
    assert "policy: reliability" in messages[0], messages
    in_bag = [s.message for *_, m in read_bag(node_bag(tmp_path / "bags"), topics=["/diagnostics"]) for s in m.status
              if s.name.endswith(": inputs")]
    assert in_bag == messages


def test_a_burst_over_two_topics_is_worked_off_in_arrival_order(ros, tmp_path):
    """A burst of pressures and joint states, interleaved and published as fast as the client can,
    far above the node's solve rate, into its deep reliable queues: the node takes the queued
    messages of both topics (ros.node._drain: one per queue per cycle, as the executor does), so the
    bag holds every input, each topic in publish order (between topics the middleware keeps no
    order), and every event is solved: the topics advance together (no stale_input)."""
    proc = start_node({"mechanism": "belarus_1221", "record_dir": str(tmp_path / "bags"), "sensor_qos": "reliable",
                       "stamp_tolerance": 3600.0}, tmp_path / "node.log")
    client = MonitorClient()
    try:
        client.wait_for_node()
        stream = simulate(BELARUS, "lift", rate_hz=40.0, noise=Noise(0.0, 0.0, 0.0), seed=2,   # < 1000 per topic: the
                          start_ns=time.time_ns())                                   # client keeps them all
        names, sent = list(stream.joint_names), []
        for i, stamp in enumerate(stream.stamps_ns.tolist()):   # pressure at stamp, joints at stamp + 1 µs
            client.publish_pressure(PRESSURE_TOPIC, stamp, float(stream.pressure_values[i, 0]) + ATMOSPHERIC_PRESSURE)
            client.publish_joint_state(stamp + 1000, names, stream.joint_positions[i].tolist())
            sent += [("/" + PRESSURE_TOPIC, stamp), ("/joint_states", stamp + 1000)]
        solves = len(sent) - 1   # every event solves (the pressure and the joint state), but the first: no joints yet
        last = int(stream.stamps_ns[-1]) + 1000
        client.spin_until(lambda: client.outputs_at("hinge_reactions", last), 60)
        settle(client, "hinge_reactions", quiet=1.0)
    finally:
        client.close()
        assert stop(proc) == 0
    bag = node_bag(tmp_path / "bags")   # the node's own record (a client as busy as this one may miss some of a burst)
    recorded = [(topic, stamp) for topic, _, stamp, _, _ in read_bag(bag, topics=["/joint_states",
                                                                                  "/" + PRESSURE_TOPIC])]
    for topic in ("/joint_states", "/" + PRESSURE_TOPIC):   # each topic in publish order, none lost; between two
        assert [m for m in recorded if m[0] == topic] == [m for m in sent if m[0] == topic]   # topics no order is kept
    assert sum(1 for _ in read_bag(bag, topics=["/hinge_reactions"])) == solves
    assert not [s for *_, m in read_bag(bag, topics=["/diagnostics"]) for s in m.status if "stale input" in s.message]


def test_an_internal_failure_is_reported_and_the_node_goes_on(ros, tmp_path, monkeypatch):
    """A bug inside the monitor (injected: the solver raises) gives an ERROR diagnostic naming
    the input; the callback returns, the next input is solved."""
    from linkage_monitor.ros.node import LinkageMonitorNode

    node = LinkageMonitorNode(parameter_overrides=[
        rclpy.parameter.Parameter("record_dir", value=str(tmp_path / "bags")),
        rclpy.parameter.Parameter("sensor_qos", value="reliable")])
    client = MonitorClient()
    executor = SingleThreadedExecutor()
    executor.add_node(node)
    executor.add_node(client.node)
    try:
        assert _spin(executor, lambda: client.joint_pub.get_subscription_count() > 0, 10)
        _spin(executor, lambda: False, 0.5)
        stream = _lift(time.time_ns())
        names, t = list(stream.joint_names), int(stream.stamps_ns[0])
        client.publish_pressure(PRESSURE_TOPIC, t, float(stream.pressure_values[0, 0]) + ATMOSPHERIC_PRESSURE)
        _spin(executor, lambda: False, 0.3)
        real_solve = node.monitor.machine.solve

        def broken(*args, **kwargs):
            raise RuntimeError("injected failure")
        monkeypatch.setattr(node.monitor.machine, "solve", broken)
        client.publish_joint_state(t + 1000, names, stream.joint_positions[0].tolist())
        assert _spin(executor, lambda: client.diagnostics_at(t + 1000), 10)
        status = client.diagnostics_at(t + 1000)[0]
        assert status.level == b"\x02" and "internal error" in status.message and "injected failure" in status.message
        monkeypatch.setattr(node.monitor.machine, "solve", real_solve)
        client.publish_joint_state(t + 2000, names, stream.joint_positions[0].tolist())
        assert _spin(executor, lambda: client.outputs_at("hinge_reactions", t + 2000), 10)
    finally:
        executor.shutdown()
        client.close()
        node.close()
        node.destroy_node()


def _spin(executor: SingleThreadedExecutor, condition, timeout: float) -> bool:
    end = time.monotonic() + timeout
    while time.monotonic() < end and not condition():
        executor.spin_once(timeout_sec=0.02)
    return condition()


def test_a_second_monitor_with_the_same_name_is_reported_at_start(ros, tmp_path):
    """Two monitors named /linkage_monitor (both would solve, publish and record every input): a WARN
    `<node>: node name` on /diagnostics names the clash and says what to do."""
    params = {"mechanism": "belarus_1221", "sensor_qos": "reliable"}
    first = start_node({**params, "record_dir": str(tmp_path / "a")}, tmp_path / "a.log")
    client = MonitorClient()

    def warned() -> list:
        return client.statuses(": node name", b"\x01")
    second = None
    try:
        client.wait_for_node()
        second = start_node({**params, "record_dir": str(tmp_path / "b")}, tmp_path / "b.log")
        assert client.spin_until(warned, 15.0), "no WARN about the duplicate node name"
    finally:
        client.close()
        for proc in (first, second):
            if proc is not None:
                assert stop(proc) == 0
    assert "another node is named /linkage_monitor" in warned()[0].message
    assert "__node:=" in warned()[0].message
