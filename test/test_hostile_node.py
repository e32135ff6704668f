"""What a hostile field test found, held: the monitor goes STALE when nothing is solved (from
start-up, after the last input, with only refused inputs or unmapped CAN frames arriving), a
pressure 1000x too small (kPa sent as Pa) is refused with a hint about its unit on both paths, a
misspelt joint beside a right one is named, integers are taken for double parameters at start, the
dead-centre threshold's documented range (0 to 45 degrees) is exact, and ``--help`` prints the
parameters without starting anything.

The core's tests need no ROS; the node's run it in a child process (support.ros_harness), the CAN
bridge's in this process on python-can's virtual bus (frames and node in one process: the virtual
bus carries frames inside one process only).
"""

from __future__ import annotations

import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from linkage_monitor.mechanics import Solver, load_preset
from linkage_monitor.mechanics.capacity import stroke_mechanism
from linkage_monitor.mechanics.constants import ATMOSPHERIC_PRESSURE
from linkage_monitor.mechanics.limits import RELIEF_FACTOR
from linkage_monitor.mechanics.results import angle_readings
from linkage_monitor.monitoring.config import MonitorConfig
from linkage_monitor.monitoring.core import Monitor, Step
from linkage_monitor.monitoring.events import JointStateEvent, PressureEvent
from linkage_monitor.monitoring.findings import Code, Level
from linkage_monitor.monitoring.freshness import Freshness

ROOT = Path(__file__).resolve().parent.parent
T0 = (time.time_ns() // 10**9) * 10**9  # ns, now (whole s): the node refuses stamps far from its clock
JOINTS = ["lift_cylinder", "lift_arm_angle"]
PRESSURE_TOPIC = "/pressure/lift_cap_pressure"
STATUS = "linkage_monitor: belarus_1221"   # the monitor's own status on /diagnostics (the per-input one)
# belarus_1221's lift cylinder: relief pressure 19.384 MPa (its preset file); the plausible absolute
# pressures reach RELIEF_FACTOR times it + 1 atm, and that upper limit's kPa sent as Pa is the lower one
LOWEST_PLAUSIBLE_PA = 1e-3 * (RELIEF_FACTOR * 19.384e6 + ATMOSPHERIC_PRESSURE)   # 29.2 kPa absolute


def _pose(stroke: float) -> tuple[float, float]:
    """A consistent (stroke m, lift-arm angle rad) pair: the angle from the offline kinematics."""
    mech = load_preset("belarus_1221")
    batch = Solver(stroke_mechanism(mech)).solve_batch(cylinders={"lift_cylinder": np.array([stroke])})
    return stroke, float(angle_readings(mech, batch)["lift_arm_angle"][0])


def _monitor() -> Monitor:
    mech = load_preset("belarus_1221")
    return Monitor(mech, MonitorConfig(mechanism=mech.name, pressure_topics={PRESSURE_TOPIC: "lift_cap_pressure"},
                                       staleness_limit_s=0.5, stamp_tolerance_s=3600.0))


def _both_paths(events: list) -> tuple[list[Step], list[Step]]:
    """The steps of ``events`` through the live path (Monitor.step) and the replay's (Monitor.run)."""
    live = _monitor()
    return [live.step(e) for e in events], _monitor().run(events).steps


# ---- the core: the replay and the node share it ---------------------------------------------------------
def test_a_pressure_sent_in_kpa_as_pa_is_out_of_range_with_a_unit_hint_on_both_paths():
    """9.2 MPa absolute sent as 9.2 kPa: below LOWEST_PLAUSIBLE_PA, refused (no pose), the finding says
    what the unit slip looks like; 0 gauge (a lowered implement in float) is still a pressure."""
    stroke, angle = _pose(0.60)
    events = [PressureEvent(PRESSURE_TOPIC, 9.2e3, T0, T0),
              JointStateEvent("/joint_states", JOINTS, [stroke, angle], [], T0 + 1000, T0 + 1000)]
    for steps in _both_paths(events):
        refused = steps[0]
        assert [f.code for f in refused.findings] == [Code.OUT_OF_RANGE]
        assert "looks like kPa sent as Pa?" in refused.message and "9.2e+06 Pa would be inside" in refused.message
        assert f"[{LOWEST_PLAUSIBLE_PA:.6g}," in refused.message
        assert refused.pose is None
        assert steps[1].pose is None and [f.code for f in steps[1].findings] == [Code.NO_VALUE_YET]
    floating = [PressureEvent(PRESSURE_TOPIC, ATMOSPHERIC_PRESSURE, T0, T0),
                JointStateEvent("/joint_states", JOINTS, [stroke, angle], [], T0 + 1000, T0 + 1000)]
    for steps in _both_paths(floating):
        assert [f.code for f in steps[0].findings] == [Code.NO_VALUE_YET]   # accepted: only the joints missing
        assert steps[1].findings == () and steps[1].pose is not None


def test_an_unknown_joint_beside_a_known_one_is_named_on_both_paths():
    """lift_arm_angle misspelt: the cylinder is taken, the solve misses the angle, and the unknown
    name is a finding of its own naming the expected names."""
    stroke, angle = _pose(0.60)
    events = [PressureEvent(PRESSURE_TOPIC, 9.2e6, T0, T0),
              JointStateEvent("/joint_states", ["lift_cylinder", "lift_arm_angel"], [stroke, angle], [], T0 + 1000,
                              T0 + 1000)]
    for steps in _both_paths(events):
        step = steps[1]
        assert [f.code for f in step.findings] == [Code.NO_VALUE_YET, Code.UNKNOWN_INPUT]
        assert ("unknown joint 'lift_arm_angel' in /joint_states; expected one of lift_arm_angle, lift_cylinder"
                in step.message)
    right = [*events, JointStateEvent("/joint_states", JOINTS, [stroke, angle], [], T0 + 2000, T0 + 2000)]
    for steps in _both_paths(right):
        assert steps[2].pose is not None and steps[2].findings == ()   # named no longer once it is right


def test_freshness_is_stale_before_the_first_solve_and_after_the_staleness_limit():
    freshness = Freshness()
    first = freshness.stale(10.0, 0.5, ["/joint_states", PRESSURE_TOPIC])
    assert first is not None and first.level == Level.STALE == 3   # diagnostic_msgs/DiagnosticStatus.STALE
    assert first.text.startswith(f"no input solved yet; subscribed to /joint_states, {PRESSURE_TOPIC}")
    freshness.solved(10.0)
    assert freshness.stale(10.5, 0.5, ["/joint_states"]) is None
    late = freshness.stale(13.2, 0.5, ["/joint_states"])
    assert late is not None and late.text.startswith("no input solved for 3.2 s (staleness_limit 0.5 s)")


def test_parameter_ranges_are_exact_and_help_lists_every_parameter_with_its_unit():
    from linkage_monitor.ros.node import PARAMETERS, check_bounds, usage

    check_bounds("dead_centre_transmission_deg", 45.0)
    with pytest.raises(ValueError, match=r"dead_centre_transmission_deg = 45.0000001: outside its range \[0, 45\] "
                                         "degrees"):
        check_bounds("dead_centre_transmission_deg", 45.0000001)
    text = usage()
    for name, declaration in PARAMETERS.items():
        [row] = [line for line in text.splitlines() if line.split()[:1] == [name]]
        assert repr(declaration.default) in row and (declaration.unit or "-") in row.split()


# ---- the node in a process of its own -------------------------------------------------------------------
def _statuses(client) -> list:
    return [s for m in client.received["diagnostics"] for s in m.status if s.name == STATUS]


@pytest.mark.ros
@pytest.mark.slow
def test_wrong_topic_names_show_as_stale_from_start_naming_the_topics(ros, tmp_path):
    from support.ros_harness import MonitorClient, start_node, stop

    proc = start_node({"mechanism": "belarus_1221", "record": False, "joint_state_topic": "joint_statez",
                       "pressure_topics": ["hydraulics/lift=lift_cap_pressure"]}, tmp_path / "node.log")
    client = MonitorClient(pressure_topics=())
    try:
        assert client.spin_until(lambda: any(s.level == b"\x03" for s in _statuses(client)), 30), \
            (tmp_path / "node.log").read_text()
        first = next(s for s in _statuses(client) if s.level == b"\x03")
        assert first.message.startswith("no input solved yet; subscribed to /joint_statez, /hydraulics/lift")
    finally:
        client.close()
        assert stop(proc) == 0, (tmp_path / "node.log").read_text()


@pytest.mark.ros
@pytest.mark.slow
def test_the_status_goes_stale_after_the_last_solve_whatever_else_arrives(node):
    """One solved pose (OK), then only refused inputs (a joint name nobody knows): STALE within the
    staleness limit (0.5 s) + the heartbeat's period (1 s); a solve again: OK at once, its stamp."""
    client, _, _ = node
    stroke, angle = _pose(0.60)
    client.publish_pressure("pressure/lift_cap_pressure", T0, 9.2e6)
    client.spin_until(lambda: False, 0.3)
    client.publish_joint_state(T0 + 1000, JOINTS, [stroke, angle])
    assert client.spin_until(lambda: client.outputs_at("hitch_state", T0 + 1000), 20)
    client.spin_until(lambda: False, 0.1)
    count = len(_statuses(client))
    for k in range(1, 30):   # 3 s of refused inputs
        client.publish_joint_state(T0 + k * 100_000_000, ["wheel_left"], [0.0])
        client.spin_until(lambda: False, 0.1)
    stale = [s for s in _statuses(client)[count:] if s.level == b"\x03"]
    assert stale and stale[0].message.startswith("no input solved for"), [s.message for s in _statuses(client)]
    count = len(_statuses(client))
    client.publish_pressure("pressure/lift_cap_pressure", T0 + 4_000_000_000, 9.2e6)
    client.spin_until(lambda: False, 0.3)
    client.publish_joint_state(T0 + 4_000_001_000, JOINTS, [stroke, angle])
    assert client.spin_until(lambda: any(s.level == b"\x00" for s in _statuses(client)[count:]), 10)
    [recovered] = client.diagnostics_at(T0 + 4_000_001_000)
    assert recovered.level == b"\x00" and recovered.message == "ok"


@pytest.mark.ros
@pytest.mark.slow
def test_a_pressure_sent_in_kpa_as_pa_is_refused_by_the_node_and_nothing_is_published(node):
    client, _, _ = node
    stroke, angle = _pose(0.60)
    client.publish_pressure("pressure/lift_cap_pressure", T0, 9.2e3)
    client.spin_until(lambda: False, 0.3)
    client.publish_joint_state(T0 + 1000, JOINTS, [stroke, angle])
    assert client.spin_until(lambda: client.diagnostics_at(T0 + 1000), 20)
    [refused] = client.diagnostics_at(T0)
    assert refused.level == b"\x02" and "looks like kPa sent as Pa?" in refused.message
    assert "out_of_range" in {kv.value for kv in refused.values}
    assert not client.outputs_at("hitch_state", T0 + 1000) and not client.outputs_at("hitch_state", T0)


@pytest.mark.ros
@pytest.mark.slow
def test_an_integer_for_a_double_parameter_at_start_and_an_exact_dead_centre_range_at_run_time(ros, tmp_path):
    from rcl_interfaces.srv import GetParameters, SetParameters
    from rclpy.parameter import Parameter

    from support.ros_harness import MonitorClient, start_node, stop

    proc = start_node({"mechanism": "belarus_1221", "record": False, "implement_mass": 1500}, tmp_path / "node.log")
    client = MonitorClient(pressure_topics=())
    try:
        assert client.spin_until(lambda: bool(client.received["mechanism_description"]) or proc.poll() is not None,
                                 30) and proc.poll() is None, (tmp_path / "node.log").read_text()
        getter = client.node.create_client(GetParameters, "/linkage_monitor/get_parameters")
        assert getter.wait_for_service(timeout_sec=10)
        got = getter.call_async(GetParameters.Request(names=["implement_mass"]))
        assert client.spin_until(got.done, 10)
        assert got.result().values[0].double_value == 1500.0
        setter = client.node.create_client(SetParameters, "/linkage_monitor/set_parameters")
        assert setter.wait_for_service(timeout_sec=10)
        refused = setter.call_async(SetParameters.Request(parameters=[
            Parameter("dead_centre_transmission_deg", value=45.0000001).to_parameter_msg()]))
        assert client.spin_until(refused.done, 10)
        result = refused.result().results[0]
        assert not result.successful and "outside its range [0, 45] degrees" in result.reason, result
    finally:
        client.close()
        assert stop(proc) == 0, (tmp_path / "node.log").read_text()


@pytest.mark.slow
@pytest.mark.parametrize("flag", ["--help", "-h"])
def test_help_prints_the_parameters_and_starts_nothing(flag, tmp_path):
    script = Path(sys.executable).parent / "linkage_monitor_node"
    command = [str(script)] if script.exists() else [sys.executable, "-m", "linkage_monitor.ros.node"]
    proc = subprocess.run([*command, flag], cwd=tmp_path, capture_output=True, text=True, timeout=60)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.startswith("usage: linkage_monitor_node")
    assert "implement_mass" in proc.stdout and "staleness_limit" in proc.stdout
    assert list(tmp_path.iterdir()) == []   # no out/bags, nothing recorded
    assert "rclpy" not in proc.stderr and proc.stderr == ""


# ---- the CAN bridge: the node's heartbeat, frames that map to nothing -------------------------------------
@pytest.mark.ros
def test_the_can_bridge_goes_stale_while_only_unmapped_frames_arrive(ros, tmp_path):
    """Frames keep the bus busy (the bridge's silence check stays quiet), none maps to an input: STALE."""
    import can
    import rclpy
    from diagnostic_msgs.msg import DiagnosticArray
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.parameter import Parameter

    from linkage_monitor.can.mapping import load_mapping
    from linkage_monitor.can.node import CanBridgeNode, CanSource
    from support.can_bridge import close_rig

    mapping = load_mapping(ROOT / "config" / "can" / "belarus_1221.yaml")
    channel = f"hostile_{time.monotonic_ns()}"
    source = CanSource(mapping=mapping, dbc=mapping.dbc, bus=f"virtual:{channel}")
    bridge = CanBridgeNode(source, parameter_overrides=[Parameter("mechanism", value="belarus_1221"),
                                                        Parameter("record", value=False)])
    listener = rclpy.create_node("hostile_listener")
    statuses: list = []
    listener.create_subscription(DiagnosticArray, "/diagnostics", lambda m: statuses.extend(m.status), 100)
    sender = can.Bus(interface="virtual", channel=channel)
    executor = SingleThreadedExecutor()
    executor.add_node(bridge)
    executor.add_node(listener)
    try:
        end = time.monotonic() + 3.0
        while time.monotonic() < end:
            sender.send(can.Message(arbitration_id=0x123, data=bytes(8), is_extended_id=False))   # maps to nothing
            executor.spin_once(timeout_sec=0.02)
        mine = [s for s in statuses if s.name == STATUS]
        assert mine and all(s.level == b"\x03" for s in mine), [(s.level, s.message) for s in mine]
        assert mine[0].message.startswith(f"no input solved yet; subscribed to virtual:{channel}")
        assert not any("no CAN frame" in s.message for s in statuses)   # the bus was never silent
        counts = [s.message for s in statuses if s.name.endswith(": can")]
        assert counts and not counts[-1].startswith("0 frames"), counts
        # python-can's virtual bus has no socket whose drops could be counted: the frame count says so
        assert counts[-1].endswith(f"; the frames virtual:{channel} drops cannot be counted here"), counts[-1]
    finally:
        close_rig(sender, executor, bridge, listener)
