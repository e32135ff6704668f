"""Two nodes publishing one input topic, against the real node in a child process: a source is part of
an input's identity. Two publisher processes (test/support/pose_publisher.py) send different poses
of belarus_1221 on `joint_states`; the monitor node (ros/inputs.py, monitoring/sources.py) must use
neither while both are heard (sensors_disagree naming both), use the one `trusted_publishers` names,
solve again once the other has been silent for staleness_limit, and record every message it received:
used ones on `/joint_states`, the others on `/joint_states/refused` (read back with rosbags).
The two poses are the simulator's full lift of belarus_1221 at its start and its end; which one the
node solved is told by the implement's centre of gravity x (HitchState.implement_cg_x), which differs
between them by centimetres.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from linkage_monitor.mechanics import load_preset
from linkage_monitor.sim.telemetry import Noise, simulate
from support.ros_harness import MonitorClient, node_bag, read_bag_rosbags, settle, start_node, stop

PUBLISHER = Path(__file__).parent / "support" / "pose_publisher.py"
RATE_HZ = 50.0
FINDING = "sensors_disagree"


def _poses() -> tuple[list[str], list[str]]:
    """The JointState arguments (``name=value``) of the lift's first and last pose."""
    stream = simulate(load_preset("belarus_1221"), "lift", rate_hz=20.0, noise=Noise(0.0, 0.0, 0.0), seed=1)
    names = list(stream.joint_names)
    return tuple([f"{n}={float(stream.joint_positions[row, k])!r}" for k, n in enumerate(names)] for row in (0, -1))


def _publisher(name: str, pose: list[str], log: Path) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, str(PUBLISHER), name, str(RATE_HZ), *pose],
                            stdout=log.open("w"), stderr=subprocess.STDOUT)


def _sent(proc: subprocess.Popen, log: Path) -> int:
    assert stop(proc) == 0, log.read_text()
    return int(log.read_text().split("sent ")[-1])


def _publishing(log: Path, client: MonitorClient) -> None:
    assert client.spin_until(lambda: "publishing" in log.read_text(), 30), log.read_text()


def _cg_x(client: MonitorClient, start: int = 0) -> set[float]:
    return {round(m.implement_cg_x, 6) for m in client.received["hitch_state"][start:]}


def _node(tmp_path: Path, **params) -> tuple[subprocess.Popen, MonitorClient]:
    proc = start_node({"mechanism": "belarus_1221", "record_dir": str(tmp_path / "bags"), "sensor_qos": "reliable",
                       "pressure_topics": ["none"], "staleness_limit": 0.5, **params}, tmp_path / "node.log")
    client = MonitorClient(pressure_topics=())
    try:
        client.wait_for_node()
    except BaseException:
        _end(proc, client)
        raise
    return proc, client


def _end(node: subprocess.Popen, client: MonitorClient, *publishers: subprocess.Popen | None) -> None:
    """The publishers still running stopped, the client closed, the node stopped (exit code 0)."""
    for publisher in publishers:
        if publisher is not None:
            stop(publisher)
    client.close()
    assert stop(node) == 0


def _disagree(client: MonitorClient) -> list:
    return [s for m in client.received["diagnostics"] for s in m.status
            if any(kv.key == "findings" and FINDING in kv.value.split() for kv in s.values)]


def _recorded(tmp_path: Path) -> dict[str, list[tuple[float, ...]]]:
    """The JointState positions the node's bag holds per topic (rosbags)."""
    recorded: dict[str, list[tuple[float, ...]]] = {"/joint_states": [], "/joint_states/refused": []}
    for topic, _, msg in read_bag_rosbags(node_bag(tmp_path / "bags")):
        if topic in recorded:
            recorded[topic].append(tuple(float(p) for p in msg.position))
    return recorded


def _values(pose: list[str]) -> tuple[float, ...]:
    return tuple(float(arg.split("=")[1]) for arg in pose)


def test_two_publishers_are_used_by_neither_until_one_stops(ros, tmp_path):
    """A alone: solved. B too: a sensors_disagree naming both, nothing published. B stopped: after
    staleness_limit, A solved again. The bag holds every message either sent: B's all refused."""
    first, last = _poses()
    proc, client = _node(tmp_path)
    a = _publisher("pose_a", first, tmp_path / "a.log")
    b = None
    try:
        _publishing(tmp_path / "a.log", client)
        assert client.spin_until(lambda: len(client.received["hitch_state"]) >= 10, 20)
        alone = _cg_x(client)
        assert len(alone) == 1, alone
        b = _publisher("pose_b", last, tmp_path / "b.log")
        assert client.spin_until(lambda: bool(_disagree(client)), 30), "no sensors_disagree"
        message = _disagree(client)[0].message
        assert "/pose_a" in message and "/pose_b" in message and "/joint_states" in message, message
        client.spin_until(lambda: False, 0.3)   # what was published before the finding arrived
        during = len(client.received["hitch_state"])
        client.spin_until(lambda: False, 1.5)
        assert len(client.received["hitch_state"]) == during, "published while two nodes publish the input"
        sent_b = _sent(b, tmp_path / "b.log")
        b = None
        assert client.spin_until(lambda: len(client.received["hitch_state"]) >= during + 10, 20), "never resumed"
        assert _cg_x(client, during) == alone
        sent_a = _sent(a, tmp_path / "a.log")
        settle(client, "hitch_state")
    finally:
        _end(proc, client, a, b)
    recorded = _recorded(tmp_path)
    used, refused = recorded["/joint_states"], recorded["/joint_states/refused"]
    assert len(used) + len(refused) == sent_a + sent_b, (len(used), len(refused), sent_a, sent_b)
    assert refused.count(_values(last)) == sent_b and _values(last) not in used
    assert refused.count(_values(first)) > 0   # A's while B was heard


@pytest.mark.parametrize("trusted", ["pose_b", "/pose_b"])
def test_the_trusted_publisher_is_used_and_the_other_recorded_as_refused(ros, tmp_path, trusted):
    """trusted_publishers names B: while A and B both publish, B's pose is solved, A's messages are
    recorded on /joint_states/refused and counted on /diagnostics (``: sources``)."""
    first, last = _poses()
    proc, client = _node(tmp_path, trusted_publishers=[f"joint_states={trusted}"])
    a = _publisher("pose_a", first, tmp_path / "a.log")
    b = _publisher("pose_b", last, tmp_path / "b.log")
    try:
        _publishing(tmp_path / "a.log", client)
        _publishing(tmp_path / "b.log", client)
        assert client.spin_until(lambda: len(client.received["hitch_state"]) >= 20, 20)
        assert client.spin_until(lambda: bool(client.statuses(": sources")), 5)
        sent_a, sent_b = _sent(a, tmp_path / "a.log"), _sent(b, tmp_path / "b.log")
        a = b = None
        settle(client, "hitch_state")
        solved = _cg_x(client)
    finally:
        _end(proc, client, a, b)
    assert len(solved) == 1 and not _disagree(client), solved
    status = client.statuses(": sources")[0]
    assert status.level == b"\x00" and "/pose_a" in status.message, status.message
    recorded = _recorded(tmp_path)
    assert recorded["/joint_states"] == [_values(last)] * sent_b
    assert recorded["/joint_states/refused"] == [_values(first)] * sent_a
