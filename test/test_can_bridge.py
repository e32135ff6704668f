"""The live CAN bridge in a process of its own, fed by another process: over a python-can bus
and over can_msgs/msg/Frame on /from_can_bus (real rclpy pub/sub); its bag replayed, and its
raw frames turned into a candump log, through can-to-bag and replay: the same outputs.

The bus: python-can's `udp_multicast` interface on the loopback. Its `virtual` interface carries
frames inside one process only, and a kernel `vcan0` cannot be made here (`ip link add vcan0
type vcan`: "Unknown device type", no vcan module), so udp_multicast is the bus two processes
share. Each test uses its own multicast group and UDP port (python-can binds the port on every
address, and Linux hands a socket every group joined on its port: a group alone does not keep runs
at the same time apart); the port reaches both processes as python-can's CAN_CONFIG.
"""

from __future__ import annotations

import json
import random
import subprocess
import sys
import time
from collections import Counter
from pathlib import Path

import can
import pytest
from rosbags.rosbag2 import Reader
from rosbags.typesys import Stores, get_types_from_msg, get_typestore

from support.can_bridge import bag_messages, cli_command, wait_for_frame_count, wait_for_log_line
from support.ros_harness import node_bag, stop

pytestmark = pytest.mark.ros

ROOT = Path(__file__).resolve().parent.parent
LOG = ROOT / "bags" / "can" / "belarus_1221_lift.log"
MAP = ROOT / "config" / "can" / "belarus_1221.yaml"
OUTPUTS = ("/hinge_reactions", "/hitch_state", "/steerability")
RATE = 600.0   # frames/s sent (the log's 120 frames/s at 5x)


def _topic_bytes(bag: Path, topics: tuple[str, ...]) -> dict[str, list[bytes]]:
    """Every message of ``topics`` in the bag as recorded (rosbags reads it: a reader we did not write)."""
    out: dict[str, list[bytes]] = {t: [] for t in topics}
    with Reader(bag) as reader:
        connections = [c for c in reader.connections if c.topic in topics]
        for connection, _, data in reader.messages(connections=connections):
            out[connection.topic].append(bytes(data))
    return out


def _frames_in_bag(bag: Path) -> list[can.Message]:
    """The raw frames the bridge recorded (can_msgs/msg/Frame, decoded by rosbags with the bag's
    own definition) as python-can messages."""
    with Reader(bag) as reader:
        [connection] = [c for c in reader.connections if c.topic == "/from_can_bus"]
        store = get_typestore(Stores.EMPTY)
        store.register(get_types_from_msg(connection.msgdef.data, "can_msgs/msg/Frame"))
        frames = []
        for _, _, data in reader.messages(connections=[connection]):
            f = store.deserialize_cdr(data, "can_msgs/msg/Frame")
            frames.append(can.Message(timestamp=f.header.stamp.sec + f.header.stamp.nanosec * 1e-9,
                                      arbitration_id=f.id, is_extended_id=f.is_extended, is_error_frame=f.is_error,
                                      dlc=f.dlc, data=bytes(f.data[:f.dlc])))
    return frames


def _expected_counts() -> tuple[int, int]:
    """(mapped, other) frames of the shipped log, counted by identifier from its text: the rear hitch
    status (0x0CFE45F0) and the maker pressure frame (0x18FF2021) feed the monitor, the wheel speed
    and the engine's EEC1 do not."""
    ids = Counter(line.split()[2].split("#")[0] for line in LOG.read_text().splitlines())
    mapped = ids["0CFE45F0"] + ids["18FF2021"]
    return mapped, sum(ids.values()) - mapped


@pytest.mark.parametrize("source", ["bus", "topic"])
def test_live_bridge_equals_replay_and_can_to_bag(source: str, tmp_path: Path, ros: None,
                                                  monkeypatch: pytest.MonkeyPatch) -> None:
    chance = random.SystemRandom()   # not the test-wide random state, which test runs may share
    group = f"239.74.{chance.randint(0, 255)}.{chance.randint(1, 254)}"
    monkeypatch.setenv("CAN_CONFIG", json.dumps({"port": chance.randint(20000, 60000)}))
    where = ["--bus", f"udp_multicast:{group}"] if source == "bus" else ["--topic"]
    bridge_log = tmp_path / "bridge.log"
    bridge = subprocess.Popen(cli_command("can", "--map", str(MAP), *where, "--ros-args", "-p",
                                   f"record_dir:={tmp_path / 'bags'}", "-p", "sensor_qos:=reliable"),
                              stdout=bridge_log.open("w"), stderr=subprocess.STDOUT)
    try:
        wait_for_log_line(bridge_log, "CAN frames from", bridge)
        time.sleep(1.5)   # longer than the mapping's silence_timeout (1 s): the silent bus is a finding
        target = f"udp_multicast:{group}" if source == "bus" else "/from_can_bus"
        sent = subprocess.run([sys.executable, str(ROOT / "test" / "support" / "can_sender.py"), source, target,
                               str(LOG), str(RATE)], capture_output=True, text=True, timeout=120)
        assert sent.returncode == 0, sent.stderr
        mapped, other = _expected_counts()
        faults = 3   # the sender's error frame, bus-off and 'not available' position
        status = wait_for_frame_count(mapped + other + faults)
    finally:
        code = stop(bridge)
    assert code == 0, bridge_log.read_text()
    live = node_bag(tmp_path / "bags")

    # every frame arrived and is accounted for: decoded + ignored + refused = received = sent
    assert int(sent.stdout.strip()) == mapped + other + faults
    raw = _frames_in_bag(live)
    assert len(raw) == mapped + other + faults
    assert status.startswith(f"{mapped + other + faults} frames: {mapped} decoded, {other} ignored")
    assert status.endswith(f"{faults} refused")
    # the silent bus, the error frame, bus-off and the missing value: findings on /diagnostics (as recorded)
    findings = [s for m in bag_messages(live, "/diagnostics") for s in m.status]
    for words, level in (("no CAN frame on", 1), ("error frame on", 2), ("bus-off on", 1), ("'not available'", 1)):
        assert any(words in s.message and s.level == level for s in findings), words

    # the bag replayed: the live outputs, byte for byte and in order
    live_out = _topic_bytes(live, OUTPUTS)
    assert len(live_out["/hinge_reactions"]) > 0.9 * mapped   # one output per solved input
    replayed = tmp_path / "replayed"
    subprocess.run(cli_command("replay", str(live), "--out", str(replayed), "--quiet"), check=True, capture_output=True)
    assert _topic_bytes(replayed, OUTPUTS) == live_out

    # the recorded raw frames as a candump log (python-can's writer), can-to-bag, replay: the same outputs
    candump = tmp_path / "recorded.log"
    with can.CanutilsLogWriter(str(candump), channel="can0") as writer:
        for msg in raw:
            writer.on_message_received(msg)
    converted, replayed_log = tmp_path / "converted", tmp_path / "replayed_log"
    subprocess.run(cli_command("can-to-bag", str(candump), "--map", str(MAP), "--out", str(converted)), check=True,
                   capture_output=True)
    subprocess.run(cli_command("replay", str(converted), "--out", str(replayed_log), "--quiet"), check=True,
                   capture_output=True)
    assert _topic_bytes(replayed_log, OUTPUTS) == live_out
