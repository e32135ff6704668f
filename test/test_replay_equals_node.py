"""One pipeline, two drivers: the node's own recordings, replayed offline, give the node's
outputs — HingeReactions, HitchState, Steerability field by field to 1e-9 and the per-input
/diagnostics levels and messages exactly — under five configurations: the default, gauge
pressure, namespaced pressure topics, an implement mass changed at run time, and a bag that
also holds unrelated JointState topics with the same joint names.

The node runs in a child process with real rclpy pub/sub; its bag (our writer) is read back
by our reader, the replay writes its own bag, and the two are compared message by message
(linkage_monitor.offline.compare). The oracle is the node's own recorded output.
"""

from __future__ import annotations

import time
from pathlib import Path

import pytest
from rclpy.parameter import Parameter
from rclpy.parameter_client import AsyncParameterClient
from sensor_msgs.msg import JointState

from linkage_monitor.bag.reader import read_bag
from linkage_monitor.bag.writer import BagWriter
from linkage_monitor.mechanics.constants import ATMOSPHERIC_PRESSURE
from linkage_monitor.mechanics import load_preset
from linkage_monitor.offline.compare import compare_bags
from linkage_monitor.offline.replay import replay
from linkage_monitor.ros.messages import header
from linkage_monitor.sim.telemetry import Noise, simulate
from support.ros_harness import MonitorClient, node_bag, settle, start_node, stop

STATUS = "linkage_monitor: belarus_1221"
PACE_S = 0.01   # s between published inputs: below the node's solve rate, so nothing is lost


def _stream():
    """A noisy lift cycle of belarus_1221 (the simulator), stamped from now."""
    return simulate(load_preset("belarus_1221"), "lift", rate_hz=10.0, noise=Noise(0.001, 0.0002, 2e4),
                    seed=5, start_ns=time.time_ns())


def _run_node(tmp: Path, params: dict, pressure_topic: str | None, gauge: bool,
              change_at: int | None = None) -> Path:
    """Start the node, publish the lift cycle paced, (change implement_mass at input ``change_at``),
    stop it; returns its bag."""
    stream = _stream()
    proc = start_node({"mechanism": "belarus_1221", "record_dir": str(tmp / "bags"), "sensor_qos": "reliable",
                       "stamp_tolerance": 3600.0, **params}, tmp / "node.log")
    client = MonitorClient(pressure_topics=(pressure_topic,) if pressure_topic else ())
    try:
        client.wait_for_node()
        n = len(stream.stamps_ns)
        for i, stamp in enumerate(stream.stamps_ns.tolist()):
            if i == change_at:
                settle(client, "hinge_reactions", quiet=0.5)
                params_client = AsyncParameterClient(client.node, "linkage_monitor")
                assert params_client.wait_for_services(timeout_sec=10.0)
                future = params_client.set_parameters([Parameter("implement_mass", value=2500.0)])
                assert client.spin_until(future.done, 10.0)
                assert all(r.successful for r in future.result().results), future.result()
            client.publish_joint_state(stamp, list(stream.joint_names), stream.joint_positions[i].tolist())
            if pressure_topic:
                value = float(stream.pressure_values[i, 0]) + (0.0 if gauge else ATMOSPHERIC_PRESSURE)
                client.publish_pressure(pressure_topic, stamp, value)
            client.spin_until(lambda: False, PACE_S)
        settle(client, "hinge_reactions", quiet=1.0)
        assert len(client.received["hinge_reactions"]) > 0.9 * n, (tmp / "node.log").read_text()
    finally:
        client.close()
        assert stop(proc) == 0, (tmp / "node.log").read_text()
    return node_bag(tmp / "bags")


def _assert_replay_equals(live: Path, source: Path, out: Path) -> None:
    replay(source, out_dir=out, progress=None)
    comparison = compare_bags(live, out, STATUS, rel=1e-9)
    assert comparison.counts["/hinge_reactions"] > 50
    assert comparison.equal, comparison.differences[:5]


@pytest.mark.parametrize("case", ["default", "gauge_pressure", "namespaced_pressure", "split_bag"])
def test_replay_of_the_nodes_bag_equals_its_outputs(ros, tmp_path, case):
    params, topic, gauge = {
        "default": ({}, "pressure/lift_cap_pressure", False),
        "split_bag": ({"max_bag_duration": 0.5}, "pressure/lift_cap_pressure", False),
        "gauge_pressure": ({"pressure_absolute": False}, "pressure/lift_cap_pressure", True),
        "namespaced_pressure": ({"pressure_topics": ["/ns/pressure/lift=lift_cap_pressure"]}, "/ns/pressure/lift",
                                False),
    }[case]
    live = _run_node(tmp_path, params, topic, gauge)
    if case == "split_bag":   # a new file every 0.5 s of the run: the replay reads them as one bag
        assert len(list(live.glob("*.mcap"))) >= 3
    _assert_replay_equals(live, live, tmp_path / "offline")


def test_runtime_implement_mass_change_is_replayed_where_it_happened(ros, tmp_path, monkeypatch):
    # without pressures the implement load is the configured weight, so the change shows in it;
    # the replay encodes its outputs 7 steps at a time here (blocks that end anywhere, one across the change)
    monkeypatch.setattr("linkage_monitor.offline.replay.ENCODE_BLOCK", 7)
    live = _run_node(tmp_path, {"pressure_topics": ["none"]}, None, False, change_at=40)
    loads = [m.implement_load for *_, m in read_bag(live, topics=["/hitch_state"])]
    g = 9.80665  # m/s², the preset's gravity
    assert loads[0] == pytest.approx(1529.57 * g) and loads[-1] == pytest.approx(2500.0 * g)  # preset mass, then ours
    _assert_replay_equals(live, live, tmp_path / "offline")


def test_unrelated_joint_state_topics_are_not_fed_in(ros, tmp_path):
    live = _run_node(tmp_path, {}, "pressure/lift_cap_pressure", False)
    merged = tmp_path / "merged"   # what `ros2 bag record -a` would add: another JointState topic, same names
    with BagWriter(merged) as writer:
        for topic, type_name, stamp, log_time, msg in read_bag(live):
            writer.write(topic, msg, stamp, log_time_ns=log_time)
            if topic == "/joint_states":
                decoy = JointState(header=header(stamp), name=list(msg.name), position=[0.7, -2.5])
                writer.write("/front/joint_states", decoy, stamp, log_time_ns=log_time)
    assert any(t == "/front/joint_states" for t, *_ in read_bag(merged))
    _assert_replay_equals(live, merged, tmp_path / "offline")
