"""The live node's own bag, read by readers we did not write: rosbags AnyReader, mcap with
mcap-ros2-support, and Rerun's MCAP import.

What the bag must hold is known from this side: the inputs the test client published and the
outputs it received from the node over the wire.
"""

from __future__ import annotations

import math
import signal
import time
from pathlib import Path

import rclpy
import yaml
from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory

from linkage_monitor.mechanics.constants import ATMOSPHERIC_PRESSURE
from linkage_monitor.monitoring.config import CONFIG_TOPIC
from linkage_monitor.wire.cdr import stamp_ns
from linkage_monitor.bag.writer import MECHANISM_TOPIC
from support.lift_pose import lift_pose
from support.ros_harness import MonitorClient, node_bag, read_bag_rosbags, settle, stop

T0 = (time.time_ns() // 10**9) * 10**9  # ns, now (whole s): the node refuses stamps far from its clock
JOINTS = ["lift_cylinder", "lift_arm_angle"]
PRESSURE_TOPIC = "pressure/lift_cap_pressure"
INPUT_TOPICS = ("/joint_states", "/" + PRESSURE_TOPIC)
OUTPUT_TOPICS = ("/hinge_reactions", "/hitch_state", "/steerability", "/diagnostics", "/linkage_markers")
FLUSH_PERIOD_S = 1.0  # s, the node's BagWriter flushes this often (recording.BagWriter default)


def _stop_and_read(client: MonitorClient, proc, tmp_path: Path) -> tuple[Path, list]:
    settle(client, "diagnostics", quiet=0.5)
    code = stop(proc)
    assert code == 0, f"node exit code {code}:\n" + (tmp_path / "node.log").read_text()
    bag = node_bag(tmp_path / "bags")
    return bag, read_bag_rosbags(bag)


def test_bag_holds_every_topic_and_three_readers_decode_it(node):
    client, proc, tmp_path = node
    sent = []   # (topic, stamp, values)
    for k, (stroke, gauge) in enumerate([(0.54, 9.9e6), (0.62, 8.7e6), (0.70, 9.2e6)]):
        s, angle = lift_pose(stroke)
        stamp = T0 + k * 100_000_000
        client.publish_pressure(PRESSURE_TOPIC, stamp, gauge + ATMOSPHERIC_PRESSURE)
        client.spin_until(lambda: False, 0.3)   # two DDS writers keep no order between them
        client.publish_joint_state(stamp + 1000, JOINTS, [s, angle])
        sent += [(INPUT_TOPICS[1], stamp, (gauge + ATMOSPHERIC_PRESSURE,)), (INPUT_TOPICS[0], stamp + 1000, (s, angle))]
    assert client.spin_until(lambda: len(client.received["hitch_state"]) >= 5, 20)
    bag, rows = _stop_and_read(client, proc, tmp_path)

    # metadata.yaml: rosbag2 v9, mcap storage, counts as in the file
    info = yaml.safe_load((bag / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
    assert info["version"] == 9 and info["storage_identifier"] == "mcap"
    counts = {t["topic_metadata"]["name"]: t["message_count"] for t in info["topics_with_message_count"]}
    assert set(counts) == {*INPUT_TOPICS, *OUTPUT_TOPICS, MECHANISM_TOPIC, CONFIG_TOPIC}
    by_topic: dict[str, list] = {}
    for topic, _, msg in rows:
        by_topic.setdefault(topic, []).append(msg)
    assert {t: len(v) for t, v in by_topic.items()} == counts
    assert info["message_count"] == len(rows)

    # rosbags: the inputs exactly as sent, the outputs exactly as the client received them
    got_inputs = [(t, stamp_ns(m.header), (m.fluid_pressure,) if t == INPUT_TOPICS[1] else tuple(m.position))
                  for t, _, m in rows if t in INPUT_TOPICS]
    assert got_inputs == sent
    for topic in ("hinge_reactions", "hitch_state", "steerability"):
        wire = client.received[topic]
        recorded = by_topic["/" + topic]
        assert [stamp_ns(m.header) for m in recorded] == [stamp_ns(m.header) for m in wire]
    for wire, recorded in zip(client.received["hitch_state"], by_topic["/hitch_state"]):
        assert (recorded.implement_load, recorded.lift_reserve, recorded.cylinders[0].force) == (
            wire.implement_load, wire.lift_reserve, wire.cylinders[0].force)
    for wire, recorded in zip(client.received["hinge_reactions"], by_topic["/hinge_reactions"]):
        assert [(h.name, h.fx, h.fz) for h in recorded.hinges] == [(h.name, h.fx, h.fz) for h in wire.hinges]
    for wire, recorded in zip(client.received["steerability"], by_topic["/steerability"]):
        assert (recorded.margin, recorded.front_axle_load) == (wire.margin, wire.front_axle_load)
    # STALE (level 3: nothing solved within staleness_limit, from start-up) is the live node's own, not recorded
    wire_diag = [(stamp_ns(m.header), m.status[0].message) for m in client.received["diagnostics"]
                 if m.status[0].level != b"\x03"]
    recorded_diag = [(stamp_ns(m.header), m.status[0].message) for m in by_topic["/diagnostics"]]
    # the heartbeat repeats the last status on the wire once a second; the bag holds each once
    distinct = [d for i, d in enumerate(wire_diag) if i == 0 or d != wire_diag[i - 1]]
    assert distinct == recorded_diag[:len(distinct)]
    description = client.received["mechanism_description"][0].data
    assert [m.data for m in by_topic[MECHANISM_TOPIC]] == [description]
    assert yaml.safe_load(description)["name"] == "belarus_1221"

    # mcap + mcap-ros2-support: every message decodes, the same sequence, and the attachment
    with open(bag / f"{bag.name}_0.mcap", "rb") as stream:
        reader = make_reader(stream, decoder_factories=[DecoderFactory()])
        decoded = [(c.topic, m.log_time, msg) for _, c, m, msg in reader.iter_decoded_messages()]
        attachments = list(reader.iter_attachments())
    assert [(t, _identity(m)) for t, _, m in decoded] == [(t, _identity(m)) for t, _, m in rows]
    assert [m.data for t, _, m in decoded if t == MECHANISM_TOPIC] == [description]
    assert [(a.name, a.media_type, a.data.decode()) for a in attachments] == [
        ("mechanism.yaml", "application/yaml", description)]

    # Rerun's MCAP import: every topic arrives with one row per message
    rerun_rows = _rerun_rows(bag / f"{bag.name}_0.mcap")
    for topic, count in counts.items():
        assert rerun_rows.get(topic) == count, (topic, rerun_rows.get(topic), count)
    assert _rerun_hitch_loads(bag / f"{bag.name}_0.mcap") == [m.implement_load for m in client.received["hitch_state"]]


def test_input_is_recorded_even_when_its_solve_fails(node):
    client, proc, tmp_path = node
    s, angle = lift_pose(0.60)
    client.publish_pressure(PRESSURE_TOPIC, T0, 9.0e6 + ATMOSPHERIC_PRESSURE)
    client.spin_until(lambda: False, 0.3)
    client.publish_joint_state(T0 + 1000, JOINTS, [s, math.nan])
    assert client.spin_until(lambda: client.diagnostics_at(T0 + 1000), 20), "no diagnostic for the NaN angle"
    assert client.diagnostics_at(T0 + 1000)[0].level == b"\x02"
    assert not client.outputs_at("hitch_state", T0 + 1000)
    _, rows = _stop_and_read(client, proc, tmp_path)
    joints = [m for t, _, m in rows if t == "/joint_states"]
    assert [stamp_ns(m.header) for m in joints] == [T0 + 1000]
    assert joints[0].position[0] == s and math.isnan(joints[0].position[1])
    assert [stamp_ns(m.header) for t, _, m in rows if t == "/hitch_state"] == []
    errors = [m.status[0] for t, _, m in rows if t == "/diagnostics" and stamp_ns(m.header) == T0 + 1000]
    assert errors and "lift_arm_angle' position is nan" in errors[0].message


def _identity(msg) -> object:
    """What tells two decodings of one recorded message apart: its header stamp, or its text."""
    if hasattr(msg, "markers"):   # visualization_msgs/MarkerArray: its markers carry the stamp
        return stamp_ns(msg.markers[0].header)
    return stamp_ns(msg.header) if hasattr(msg, "header") else msg.data


def _rerun_hitch_loads(path: Path) -> list[float]:
    """implement_load of every HitchState as Rerun's MCAP importer decodes it, in log-time order."""
    import rerun.chunk as rc

    rows = []
    for chunk in rc.McapReader(path).stream():
        batch = chunk.to_record_batch()
        if str(chunk.entity_path) == "/hitch_state" and "message_log_time" in batch.schema.names:
            column = "linkage_monitor.msg.HitchState:message"
            rows += zip(batch.column("message_log_time").cast("int64").to_pylist(), batch.column(column).to_pylist())
    return [message[0]["implement_load"] for _, message in sorted(rows, key=lambda row: row[0])]


def _rerun_rows(path: Path, recover: bool = False) -> dict[str, int]:
    """Messages per topic as Rerun's MCAP importer sees them (rows of the topic's entity, or of
    its first sub-entity for the types Rerun maps onto its own components)."""
    import rerun.chunk as rc

    rows: dict[str, dict[str, int]] = {}
    for chunk in rc.McapReader(path, recover=recover).stream():
        entity = str(chunk.entity_path)
        batch = chunk.to_record_batch()
        if "message_log_time" not in batch.schema.names:
            continue
        topic = next((t for t in (*INPUT_TOPICS, *OUTPUT_TOPICS, MECHANISM_TOPIC, CONFIG_TOPIC)
                      if entity == t or entity.startswith(t + "/")), None)
        if topic is not None:
            rows.setdefault(topic, {}).setdefault(entity, 0)
            rows[topic][entity] += batch.num_rows
    return {topic: max(per_entity.values()) for topic, per_entity in rows.items()}


def test_killed_node_leaves_a_readable_bag(node):
    """SIGKILL while inputs stream in at 25 Hz: the bag opens and holds everything up to at most
    one flush period (+ 1 s slack for a busy 2-core machine) before the kill."""
    client, proc, tmp_path = node
    s, angle = lift_pose(0.60)
    sent: dict[str, list[tuple[int, tuple]]] = {t: [] for t in INPUT_TOPICS}
    period_ns = 40_000_000   # 25 Hz: 50 inputs/s, each ~7 ms of node CPU (bench_node.py), headroom on 2 busy cores
    start = time.time_ns()
    i = 0
    while time.time_ns() - start < 3.5e9:
        stamp = time.time_ns()   # wall time: the bag's log times are wall time too
        gauge = 9.0e6 + 1000.0 * i
        client.publish_pressure(PRESSURE_TOPIC, stamp, gauge + ATMOSPHERIC_PRESSURE)
        client.publish_joint_state(stamp, JOINTS, [s, angle])
        sent[INPUT_TOPICS[1]].append((stamp, (gauge + ATMOSPHERIC_PRESSURE,)))
        sent[INPUT_TOPICS[0]].append((stamp, (s, angle)))
        i += 1
        while (wait := start + i * period_ns - time.time_ns()) > 0:   # collect outputs until the next sample
            rclpy.spin_once(client.node, timeout_sec=wait * 1e-9)
    assert client.received["hitch_state"], "the node solved nothing before the kill"
    kill_ns = time.time_ns()
    proc.send_signal(signal.SIGKILL)
    proc.wait(timeout=10)
    bag = node_bag(tmp_path / "bags")

    rows = read_bag_rosbags(bag)   # rosbags on the directory: metadata.yaml + the footer-less MCAP
    for topic in INPUT_TOPICS:
        got = [(stamp_ns(m.header), (m.fluid_pressure,) if topic == INPUT_TOPICS[1] else tuple(m.position))
               for t, _, m in rows if t == topic]
        assert got and got == sent[topic][:len(got)], f"{topic}: not a prefix of what was sent"
    last_log = max(log for t, log, _ in rows if t in INPUT_TOPICS)
    assert kill_ns - last_log < (FLUSH_PERIOD_S + 1.0) * 1e9, f"lost the last {(kill_ns - last_log) * 1e-9:.2f} s"
    assert {t for t, _, _ in rows} >= {*INPUT_TOPICS, "/hitch_state", MECHANISM_TOPIC}

    with open(bag / f"{bag.name}_0.mcap", "rb") as stream:
        decoded = [(c.topic, _identity(msg)) for _, c, _, msg in make_reader(
            stream, decoder_factories=[DecoderFactory()]).iter_decoded_messages()]
    assert decoded == [(t, _identity(m)) for t, _, m in rows]
    rerun_rows = _rerun_rows(bag / f"{bag.name}_0.mcap", recover=True)
    assert rerun_rows["/joint_states"] == sum(t == "/joint_states" for t, _, _ in rows)
