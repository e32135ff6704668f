"""The managed node (``linkage_monitor_lifecycle_node``) in a child process, driven over its lifecycle
services from this process: configure, activate, outputs, deactivate (nothing solved), cleanup, a
reconfigure to another mechanism, shutdown and a clean exit.

Expected values come from the offline solver (``linkage_monitor.mechanics``, called here on the same
inputs), as for the plain node in test/test_node.py: the managed node's outputs are the plain node's.
"""

from __future__ import annotations

import math
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
import yaml
from lifecycle_msgs.msg import Transition
from lifecycle_msgs.srv import ChangeState, GetState
from rcl_interfaces.srv import SetParameters
from rclpy.parameter import Parameter

from linkage_monitor.mechanics import Inputs, Solver, load_preset
from linkage_monitor.mechanics.capacity import stroke_mechanism
from linkage_monitor.mechanics.constants import ATMOSPHERIC_PRESSURE
from linkage_monitor.mechanics.machine import MachineModel
from linkage_monitor.mechanics.results import angle_readings
from support.ros_harness import MonitorClient, stop

pytestmark = [pytest.mark.ros, pytest.mark.slow]

NODE = "/linkage_monitor"
T0 = (time.time_ns() // 10**9) * 10**9  # ns, now (whole s): the node refuses stamps far from its clock
BELARUS_TOPIC = "pressure/lift_cap_pressure"
TTZ_TOPICS = ("pressure/base_change_cap", "pressure/base_change_rod")


def _start(params: dict[str, str], log: Path) -> subprocess.Popen:
    args = [sys.executable, "-m", "linkage_monitor.ros.lifecycle_node", "--ros-args"]
    for name, value in params.items():
        args += ["-p", f"{name}:={value}"]
    return subprocess.Popen(args, stdout=log.open("w"), stderr=subprocess.STDOUT, env=dict(os.environ))


class Lifecycle:
    """The managed node's /change_state and /get_state, called from the test's client node."""

    def __init__(self, client: MonitorClient) -> None:
        self.client = client
        self.change = client.node.create_client(ChangeState, f"{NODE}/change_state")
        self.get = client.node.create_client(GetState, f"{NODE}/get_state")
        self.set_params = client.node.create_client(SetParameters, f"{NODE}/set_parameters")

    def _call(self, service, request, timeout: float = 30.0):
        assert service.wait_for_service(timeout_sec=timeout), f"{service.srv_name} not offered"
        future = service.call_async(request)
        assert self.client.spin_until(future.done, timeout), f"{service.srv_name}: no answer"
        return future.result()

    def transition(self, transition_id: int) -> bool:
        return self._call(self.change, ChangeState.Request(transition=Transition(id=transition_id))).success

    def state(self) -> str:
        return self._call(self.get, GetState.Request()).current_state.label

    def set(self, **values) -> list:
        request = SetParameters.Request(parameters=[Parameter(k, value=v).to_parameter_msg() for k, v in values.items()])
        return self._call(self.set_params, request).results


def _belarus_pose(stroke: float) -> tuple[float, float]:
    """A consistent (stroke m, lift-arm angle rad) pair of belarus_1221's two sensors (test_node.py's)."""
    mech = load_preset("belarus_1221")
    batch = Solver(stroke_mechanism(mech)).solve_batch(cylinders={"lift_cylinder": np.array([stroke])})
    return stroke, float(angle_readings(mech, batch)["lift_arm_angle"][0])


def _send(client: MonitorClient, stamp: int, pressures: dict[str, float], joints: dict[str, float]) -> None:
    """Gauge pressures (Pa) at ``stamp``, then (once they have arrived) the joint state at ``stamp`` + 1 µs."""
    for topic, gauge in pressures.items():
        client.publish_pressure(topic, stamp, gauge + ATMOSPHERIC_PRESSURE)
    client.spin_until(lambda: False, 0.3)
    client.publish_joint_state(stamp + 1000, list(joints), list(joints.values()))


def _assert_outputs_equal_offline(client: MonitorClient, preset: str, stamp: int, inputs: Inputs) -> None:
    """The three outputs at ``stamp`` equal the offline solver's on ``inputs`` to 1e-9."""
    mech = load_preset(preset)
    solver = Solver(mech)
    expected = solver.solve(inputs)
    machine = MachineModel(mech, solver).evaluate(expected)
    hinges = client.outputs_at("hinge_reactions", stamp)[0]
    assert [h.name for h in hinges.hinges] == [h.name for h in mech.hinges]
    for h in hinges.hinges:
        assert h.fx == pytest.approx(expected.hinges[h.name].fx, rel=1e-9, abs=1e-6)
        assert h.fz == pytest.approx(expected.hinges[h.name].fz, rel=1e-9, abs=1e-6)
    hitch = client.outputs_at("hitch_state", stamp)[0]
    assert hitch.implement_load == pytest.approx(expected.implement_load, rel=1e-9)
    for cylinder in hitch.cylinders:
        assert cylinder.force == pytest.approx(expected.cylinders[cylinder.name].force, rel=1e-9)
    # a mechanism without a tractor (ttz1080_base_change) has no machine level: NaN published
    capacity = machine.lift_capacity.get("implement_cg", math.nan)
    assert hitch.lift_capacity_implement_cg == pytest.approx(capacity, rel=1e-9, nan_ok=True)
    steer = client.outputs_at("steerability", stamp)[0]
    axle, margin = (machine.steerability.get(k, math.nan) for k in ("front_axle_load", "margin"))
    assert steer.front_axle_load == pytest.approx(axle, rel=1e-9, nan_ok=True)
    assert steer.margin == pytest.approx(margin, rel=1e-9, abs=1e-12, nan_ok=True)


def _wait_active(client: MonitorClient, preset: str, pressure_topics: tuple[str, ...]) -> None:
    """Until ``preset``'s description (latched) has arrived and the node subscribes to the joint
    states and ``pressure_topics`` (then 0.5 s: the subscriber sees the match after the publisher)."""
    publishers = [client.joint_pub, *(client._pressure_pubs[t] for t in pressure_topics)]
    assert client.spin_until(lambda: bool(client.received["mechanism_description"])
                             and preset in client.received["mechanism_description"][-1].data
                             and all(p.get_subscription_count() > 0 for p in publishers), 20)
    client.spin_until(lambda: False, 0.5)


def _quiet(client: MonitorClient, seconds: float) -> int:
    """Spin ``seconds``; the number of messages received on any output in that time."""
    before = {k: len(v) for k, v in client.received.items()}
    client.spin_until(lambda: False, seconds)
    return sum(len(client.received[k]) - before[k] for k in ("hinge_reactions", "hitch_state", "steerability",
                                                             "diagnostics"))


def test_managed_node_transitions_outputs_and_reconfigure(ros, tmp_path):
    log = tmp_path / "node.log"
    proc = _start({"record_dir": str(tmp_path / "bags"), "sensor_qos": "reliable", "stamp_tolerance": "3600.0"}, log)
    client = MonitorClient(pressure_topics=(BELARUS_TOPIC, *TTZ_TOPICS), name="lifecycle_test_client")
    life = Lifecycle(client)
    try:
        assert life.state() == "unconfigured"
        assert client.joint_pub.get_subscription_count() == 0   # nothing subscribed before activate
        assert life.transition(Transition.TRANSITION_CONFIGURE), log.read_text()
        assert life.state() == "inactive"
        assert client.joint_pub.get_subscription_count() == 0
        assert life.transition(Transition.TRANSITION_ACTIVATE), log.read_text()
        assert life.state() == "active"
        _wait_active(client, "belarus_1221", (BELARUS_TOPIC,))

        # active: the plain node's outputs (test_node.py's cases)
        cases = []
        for k, (stroke, gauge) in enumerate([(0.54, 9.9e6), (0.66, 9.4e6)]):
            s, angle = _belarus_pose(stroke)
            stamp = T0 + k * 100_000_000
            _send(client, stamp, {BELARUS_TOPIC: gauge}, {"lift_cylinder": s, "lift_arm_angle": angle})
            cases.append((stamp + 1000, Inputs(cylinders={"lift_cylinder": s}, angles={"lift_arm_angle": angle},
                                               pressures={"lift_cap_pressure": gauge})))
        assert client.spin_until(lambda: all(client.outputs_at("steerability", stamp) for stamp, _ in cases),
                                 20), log.read_text()
        for stamp, inputs in cases:
            _assert_outputs_equal_offline(client, "belarus_1221", stamp, inputs)

        # the mechanism is read at configure: refused while configured, naming what to do
        refused = life.set(mechanism="ttz1080_base_change")[0]
        assert not refused.successful and "deactivate and clean up" in refused.reason

        # inactive: unsubscribed, nothing solved or published (not the heartbeat either)
        assert life.transition(Transition.TRANSITION_DEACTIVATE)
        assert life.state() == "inactive"
        assert client.joint_pub.get_subscription_count() == 0
        unseen = T0 + 1_000_000_000
        s, angle = _belarus_pose(0.60)
        _send(client, unseen, {BELARUS_TOPIC: 9.0e6}, {"lift_cylinder": s, "lift_arm_angle": angle})
        assert _quiet(client, 1.5) == 0   # > HEARTBEAT_S: a running heartbeat would have published

        # activated again in the same configuration: subscribed and solving again
        assert life.transition(Transition.TRANSITION_ACTIVATE)
        _wait_active(client, "belarus_1221", (BELARUS_TOPIC,))
        again = T0 + 1_500_000_000
        s, angle = _belarus_pose(0.57)
        _send(client, again, {BELARUS_TOPIC: 9.6e6}, {"lift_cylinder": s, "lift_arm_angle": angle})
        assert client.spin_until(lambda: client.outputs_at("steerability", again + 1000), 20), log.read_text()
        _assert_outputs_equal_offline(client, "belarus_1221", again + 1000, Inputs(
            cylinders={"lift_cylinder": s}, angles={"lift_arm_angle": angle}, pressures={"lift_cap_pressure": 9.6e6}))
        assert life.transition(Transition.TRANSITION_DEACTIVATE)

        # reconfigure: cleanup, another mechanism, configure, activate
        assert life.transition(Transition.TRANSITION_CLEANUP)
        assert life.state() == "unconfigured"
        out_of_range = life.set(staleness_limit=3600.001)[0]   # unconfigured: checked against its exact range
        assert not out_of_range.successful and "outside its range" in out_of_range.reason
        # a mechanism that does not load fails the configure; the node stays unconfigured, the process up
        assert all(r.successful for r in life.set(mechanism=str(tmp_path / "no_such_tractor.yaml")))
        assert not life.transition(Transition.TRANSITION_CONFIGURE)
        assert life.state() == "unconfigured"
        assert "configure failed: " in log.read_text() and "no_such_tractor.yaml" in log.read_text()
        assert all(r.successful for r in life.set(mechanism="ttz1080_base_change"))
        assert life.transition(Transition.TRANSITION_CONFIGURE), log.read_text()
        assert life.transition(Transition.TRANSITION_ACTIVATE)
        _wait_active(client, "ttz1080_base_change", TTZ_TOPICS)
        stamp = T0 + 2_000_000_000
        pressures = {"base_change_cap": 6.0e6, "base_change_rod": 0.4e6}
        _send(client, stamp, dict(zip(TTZ_TOPICS, pressures.values())), {"base_change_cylinder": 0.56})
        assert client.spin_until(lambda: client.outputs_at("steerability", stamp + 1000), 20), log.read_text()
        _assert_outputs_equal_offline(client, "ttz1080_base_change", stamp + 1000,
                                      Inputs(cylinders={"base_change_cylinder": 0.56}, pressures=pressures))
        assert not client.outputs_at("hitch_state", unseen + 1000)   # what came while inactive was never solved

        # shutdown: finalized, the process ends by itself with 0, each configuration's bag finished
        assert life.transition(Transition.TRANSITION_ACTIVE_SHUTDOWN)
        assert proc.wait(timeout=20) == 0, log.read_text()
        bags = sorted(p.parent.name for p in (tmp_path / "bags").glob("*/metadata.yaml"))
        assert [b.rsplit("_", 2)[0] for b in bags] == ["belarus_1221", "ttz1080_base_change"], bags
    finally:
        client.close()
        if proc.poll() is None:
            stop(proc)


LAUNCH = Path(__file__).resolve().parent.parent / "launch" / "monitor_lifecycle.launch.py"
CONFIG = Path(__file__).resolve().parent.parent / "config"


def _params_file(tmp_path: Path, **changes) -> Path:
    """config/belarus_1221.yaml with ``changes`` (recording under tmp_path)."""
    params = yaml.safe_load((CONFIG / "belarus_1221.yaml").read_text())["/linkage_monitor"]["ros__parameters"]
    params.update(record_dir=str(tmp_path / "bags"), **changes)
    path = tmp_path / "params.yaml"
    path.write_text(yaml.safe_dump({"/linkage_monitor": {"ros__parameters": params}}))
    return path


def test_launch_file_configures_and_activates_the_managed_node(ros, tmp_path):
    log = tmp_path / "launch.log"
    proc = subprocess.Popen([sys.executable, str(LAUNCH), "--params", str(_params_file(tmp_path))],
                            stdout=log.open("w"), stderr=subprocess.STDOUT)
    client = MonitorClient(pressure_topics=(BELARUS_TOPIC,), name="lifecycle_launch_client")
    try:
        _wait_active(client, "belarus_1221", (BELARUS_TOPIC,))
        assert Lifecycle(client).state() == "active"
        s, angle = _belarus_pose(0.60)
        stamp = time.time_ns()   # the parameter file's stamp_tolerance: 10 s
        _send(client, stamp, {BELARUS_TOPIC: 9.0e6}, {"lift_cylinder": s, "lift_arm_angle": angle})
        assert client.spin_until(lambda: client.outputs_at("hitch_state", stamp + 1000), 20), log.read_text()
    finally:
        client.close()
        assert stop(proc) == 0, log.read_text()   # Ctrl-C to the launcher: passed on, the node's bag finished
    assert len(list((tmp_path / "bags").glob("*/metadata.yaml"))) == 1


def test_launch_file_exits_1_when_configure_fails(tmp_path):
    proc = subprocess.run([sys.executable, str(LAUNCH), "--params",
                           str(_params_file(tmp_path, mechanism="/no/such/tractor.yaml"))],
                          capture_output=True, text=True, timeout=60)
    assert proc.returncode == 1, proc.stdout + proc.stderr
    assert "configure failed: " in proc.stdout + proc.stderr   # the node's log line: the input and the reason
    assert "/no/such/tractor.yaml" in proc.stdout + proc.stderr
    lines = [line for line in proc.stderr.splitlines() if line.startswith("monitor_lifecycle.launch.py:")]
    assert len(lines) == 1 and "configure of /linkage_monitor failed" in lines[0], proc.stderr
    assert "Traceback" not in proc.stdout + proc.stderr
