"""Replay: a bag recorded by `ros2 bag record`'s layout (rosbags.rosbag2.Writer, MCAP) goes
through `linkage-monitor replay`, and every file it writes is read back by readers we did not
write. (That a replay equals the live node: test_replay_equals_node.py.)"""

from __future__ import annotations

import gc
import subprocess
import sys
import time
from pathlib import Path
from typing import NamedTuple

import numpy as np
import pytest
from mcap.reader import NonSeekingReader, make_reader
from mcap_ros2.decoder import DecoderFactory
from rerun.chunk import McapReader, RrdReader
from rosbags.highlevel import AnyReader
from rosbags.rosbag2 import Reader, StoragePlugin, Writer
from rosbags.typesys import Stores, get_typestore

from linkage_monitor.cli.main import main as cli_main
from linkage_monitor.mechanics import load_preset
from linkage_monitor.offline.history import LoadHistory
from linkage_monitor.offline import replay as replay_module
from linkage_monitor.offline import replay_outputs
from linkage_monitor.mechanics.reduced import DEAD_CENTRE_TRANSMISSION_DEG
from linkage_monitor.sim.telemetry import Noise, simulate

ROOT = Path(__file__).resolve().parent.parent
T0 = (time.time_ns() // 10**9) * 10**9  # ns, now (whole s): the node refuses stamps far from its clock


@pytest.fixture(scope="module")
def ros2_bag(tmp_path_factory) -> Path:
    """A lift cycle of belarus_1221 (simulator, with sensor noise) written by rosbags in the
    `ros2 bag record` MCAP layout, with Kilted's own type definitions (not ours)."""
    stream = simulate(load_preset("belarus_1221"), "lift", rate_hz=10.0, noise=Noise(0.001, 0.0002, 2e4),
                      seed=3, start_ns=T0)
    store = get_typestore(Stores.ROS2_KILTED)
    JointStateT, FluidPressureT = (store.types[t] for t in ("sensor_msgs/msg/JointState",
                                                            "sensor_msgs/msg/FluidPressure"))
    HeaderT, TimeT = store.types["std_msgs/msg/Header"], store.types["builtin_interfaces/msg/Time"]
    path = tmp_path_factory.mktemp("ros2") / "lift"
    with Writer(path, version=9, storage_plugin=StoragePlugin.MCAP) as writer:
        joints = writer.add_connection("/joint_states", JointStateT.__msgtype__, typestore=store)
        pressures = {name: writer.add_connection(f"/pressure/{name}", FluidPressureT.__msgtype__, typestore=store)
                     for name in stream.pressure_names}
        for i, stamp in enumerate(stream.stamps_ns.tolist()):
            header = HeaderT(stamp=TimeT(sec=stamp // 10**9, nanosec=stamp % 10**9), frame_id="")
            js = JointStateT(header=header, name=list(stream.joint_names),
                             position=np.asarray(stream.joint_positions[i], dtype=float),
                             velocity=np.array([], dtype=float), effort=np.array([], dtype=float))
            writer.write(joints, stamp + 100, store.serialize_cdr(js, JointStateT.__msgtype__))
            for k, name in enumerate(stream.pressure_names):
                fp = FluidPressureT(header=header, fluid_pressure=float(stream.pressure_values[i, k]) + 101325.0,
                                    variance=0.0)
                writer.write(pressures[name], stamp + 200 + k, store.serialize_cdr(fp, FluidPressureT.__msgtype__))
    return path


@pytest.fixture(scope="module")
def replayed(ros2_bag, tmp_path_factory):
    out = tmp_path_factory.mktemp("replay")
    code = cli_main(["replay", str(ros2_bag), "--preset", "belarus_1221", "--out", str(out / "bag"),
                     "--rrd", str(out / "replay.rrd"), "--quiet"])
    assert code == 0
    return out


def test_replay_bag_is_read_by_rosbags_mcap_ros2_and_rerun(replayed):
    bag = replayed / "bag"
    typestore = get_typestore(Stores.EMPTY)
    with AnyReader([bag], default_typestore=typestore) as reader:
        counts: dict[str, int] = {}
        for connection, _, raw in reader.messages():
            reader.deserialize(raw, connection.msgtype)
            counts[connection.topic] = counts.get(connection.topic, 0) + 1
    assert {"/joint_states", "/pressure/lift_cap_pressure", "/hinge_reactions", "/hitch_state",
            "/steerability", "/diagnostics", "/linkage_monitor/mechanism"} <= set(counts)
    assert counts["/hinge_reactions"] == counts["/hitch_state"] == counts["/steerability"] > 0
    with open(next(bag.glob("*.mcap")), "rb") as f:
        decoded = sum(1 for _ in make_reader(f, decoder_factories=[DecoderFactory()]).iter_decoded_messages())
    assert decoded == sum(counts.values())
    rerun_entities = {str(chunk.entity_path) for chunk in McapReader(next(bag.glob("*.mcap"))).stream()}
    assert "/hinge_reactions" in rerun_entities and "/joint_states" in {e.split("/position")[0] for e in rerun_entities}


def test_replay_rrd_holds_one_sample_per_solved_pose(replayed):
    """One sample per solved pose in every series; the smallest transmission angle (finite here: stroke,
    angle and cap pressure make belarus_1221 a chain of dyads the reduced path solves) is the replayed
    bag's HitchState.min_transmission_angle in degrees, beside the default dead-centre threshold."""
    with AnyReader([replayed / "bag"], default_typestore=get_typestore(Stores.EMPTY)) as reader:
        solved = sum(1 for c, _, _ in reader.messages() if c.topic == "/hinge_reactions")
        hitch = [c for c in reader.connections if c.topic == "/hitch_state"]
        messages = [reader.deserialize(raw, c.msgtype) for c, _, raw in reader.messages(connections=hitch)]
    published = sorted((m.header.stamp.sec, m.header.stamp.nanosec, m.min_transmission_angle) for m in messages)
    rows: dict[str, int] = {}
    for chunk in RrdReader(replayed / "replay.rrd").stream().to_chunks():
        batch = chunk.to_record_batch()
        if "ros_time" in batch.schema.names:
            path = chunk.entity_path.lstrip("/")
            rows[path] = rows.get(path, 0) + batch.num_rows
    assert rows["forces/cylinders/lift_cylinder"] == solved
    assert rows["steerability/ratio"] == solved
    assert rows["linkage/links"] == solved
    assert {"forces/hinges/P03", "lift/reserve", "linkage/hinges/forces"} <= set(rows)
    assert rows["transmission/min_angle"] == rows["transmission/dead_centre"] == solved
    series = _series(replayed / "replay.rrd")
    expected = np.degrees([angle for *_, angle in published])
    np.testing.assert_allclose(series["transmission/min_angle"], expected, rtol=1e-12)
    assert np.all((expected >= 0.0) & (expected <= 90.0))
    assert np.all(series["transmission/dead_centre"] == DEAD_CENTRE_TRANSMISSION_DEG)


def _series(rrd: Path) -> dict[str, np.ndarray]:
    """Entity path -> its scalar samples in ros_time order, of every Scalars series in ``rrd``."""
    samples: dict[str, list] = {}
    for chunk in RrdReader(rrd).stream().to_chunks():
        batch = chunk.to_record_batch()
        if "ros_time" in batch.schema.names and "Scalars:scalars" in batch.schema.names:
            times = batch.column("ros_time").cast("int64").to_pylist()
            values = batch.column("Scalars:scalars").to_pylist()
            samples.setdefault(chunk.entity_path.lstrip("/"), []).extend(zip(times, (v[0] for v in values)))
    return {path: np.array([v for _, v in sorted(rows)]) for path, rows in samples.items()}


class Recorded(NamedTuple):
    """What a bag holds, as mcap and rosbags read it: its channels in id order (topic, offered QoS), its
    messages in log-time order and in file order (topic, type, sequence, log time, publish time, bytes),
    rosbags' messages (topic, type, log time, bytes) and its metadata.yaml with the bag's name taken out."""

    channels: list[tuple]
    in_time: list[tuple]
    in_file: list[tuple]
    by_rosbags: list[tuple]
    metadata: str


def _recorded(bag: Path) -> Recorded:
    (file,) = bag.glob("*.mcap")
    with open(file, "rb") as f:
        reader = make_reader(f)
        summary = reader.get_summary()
        assert summary is not None
        channels = [(c.topic, c.metadata["offered_qos_profiles"]) for _, c in sorted(summary.channels.items())]
        in_time = [(c.topic, s.name, m.sequence, m.log_time, m.publish_time, m.data)
                   for s, c, m in reader.iter_messages()]
    with open(file, "rb") as f:
        in_file = [(c.topic, s.name, m.sequence, m.log_time, m.publish_time, m.data)
                   for s, c, m in NonSeekingReader(f).iter_messages()]
    with Reader(bag) as reader:
        by_rosbags = [(c.topic, c.msgtype, t, bytes(d)) for c, t, d in reader.messages()]
    metadata = (bag / "metadata.yaml").read_text().replace(bag.name, "BAG")
    return Recorded(channels, in_time, in_file, by_rosbags, metadata)


@pytest.mark.parametrize("block", [replay_module.ENCODE_BLOCK, 37], ids=["one block", "blocks of 37 steps"])
def test_the_bag_written_in_blocks_is_the_bag_written_message_by_message(ros2_bag, tmp_path, monkeypatch, block):
    """The replay writes a block of steps' messages at once (``StepRecorder.steps``: one ``BagWriter.write_rows``);
    at a ``rate`` it writes them one by one (``StepRecorder.input``, ``step``). The two bags of one run hold the
    same messages in the same order: topics, types, QoS, sequence numbers, log and publish times, bytes."""
    monkeypatch.setattr(replay_module, "ENCODE_BLOCK", block)
    mech = load_preset("belarus_1221")
    replay_module.replay(ros2_bag, mech, out_dir=tmp_path / "blocks", progress=None)
    replay_module.replay(ros2_bag, mech, out_dir=tmp_path / "messages", rate=1e6, progress=None)   # no wait
    blocks, messages = _recorded(tmp_path / "blocks"), _recorded(tmp_path / "messages")
    assert blocks == messages
    topics = {topic for topic, *_ in blocks.in_time}
    assert {"/joint_states", "/pressure/lift_cap_pressure", "/hinge_reactions", "/hitch_state", "/steerability",
            "/linkage_markers", "/diagnostics"} <= topics


def test_replay_cli_errors_name_the_bag(tmp_path, capsys):
    assert cli_main(["replay", str(tmp_path / "missing"), "--preset", "belarus_1221", "--quiet"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "missing" in err[0]


def test_a_damaged_configuration_change_is_one_line_naming_the_bag(tmp_path, capsys):
    """A recorded configuration change whose bytes are not a String (a damaged bag) stops the replay
    with exit 2 and one line naming the bag, the topic and the log time — not rclpy's traceback."""
    import yaml
    from std_msgs.msg import String

    from linkage_monitor.bag.writer import BagWriter
    from linkage_monitor.monitoring.config import CONFIG_TOPIC, MonitorConfig
    from linkage_monitor.ros.messages import header
    from sensor_msgs.msg import JointState

    mech = load_preset("belarus_1221")
    config = MonitorConfig.default(mech.name, mech)
    with BagWriter(tmp_path / "bag") as writer:
        writer.record_mechanism(yaml.safe_dump(dict(mech.raw), sort_keys=False), T0)
        writer.write(CONFIG_TOPIC, String(data=config.to_yaml()), T0, log_time_ns=T0)
        writer.write("/joint_states", JointState(header=header(T0 + 1), name=["lift_cylinder"], position=[0.6]),
                     T0 + 1, log_time_ns=T0 + 1)
        writer.write(CONFIG_TOPIC, b"\x00\x01\x00\x00\xff\xff\xff\x7f", T0 + 2, type_name="std_msgs/msg/String",
                     log_time_ns=T0 + 2)
    assert cli_main(["replay", str(tmp_path / "bag"), "--quiet"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1, err
    assert str(tmp_path / "bag") in err[0] and f"{CONFIG_TOPIC} (log time {T0 + 2} ns) does not decode" in err[0]


def test_replay_pauses_the_cyclic_gc_only_while_it_runs(ros2_bag: Path, tmp_path: Path) -> None:
    """A replay runs with the cyclic garbage collector paused (it only walks the Steps the replay keeps)
    and leaves it as it found it: on after a replay and after one that fails, off when it was off."""
    seen: list[bool] = []
    original = replay_outputs.BagOutput.write

    def spy(*args, **kwargs):
        seen.append(gc.isenabled())
        return original(*args, **kwargs)

    replay_outputs.BagOutput.write = spy  # type: ignore[method-assign]
    try:
        replay_module.replay(ros2_bag, load_preset("belarus_1221"), out_dir=tmp_path / "out", progress=None)
    finally:
        replay_outputs.BagOutput.write = original  # type: ignore[method-assign]
    assert seen and not any(seen) and gc.isenabled()
    with pytest.raises(replay_module.BagError):
        replay_module.replay(tmp_path / "no_such_bag", progress=None)
    assert gc.isenabled()
    gc.disable()
    try:
        replay_module.replay(ros2_bag, load_preset("belarus_1221"), progress=None)
        assert not gc.isenabled()
    finally:
        gc.enable()


def _table(summary: replay_module.Summary) -> str:
    """The summary's table without its timing line."""
    return "\n".join(line for line in summary.table().splitlines() if not line.startswith("replayed "))


def test_a_replay_in_pieces_writes_the_bag_and_summary_of_a_replay_in_one_piece(ros2_bag, tmp_path, monkeypatch):
    """The replay reads, solves, accounts and writes ENCODE_BLOCK inputs at a time, the series of a
    configuration segment going on across the pieces: in pieces of 37 inputs (the bag holds 7 of them)
    it writes the bag, the summary and the load history of one piece, byte for byte and number for number."""
    mech = load_preset("belarus_1221")
    whole = replay_module.replay(ros2_bag, mech, out_dir=tmp_path / "whole", progress=None)
    assert len(whole.steps) < replay_module.ENCODE_BLOCK and len(whole.run.segments) == 1   # one piece
    monkeypatch.setattr(replay_module, "ENCODE_BLOCK", 37)
    pieces = replay_module.replay_streaming(ros2_bag, mech, out_dir=tmp_path / "pieces", progress=None, history=True)
    assert whole.summary.inputs > 5 * 37
    assert _recorded(tmp_path / "pieces") == _recorded(tmp_path / "whole")
    assert _table(pieces.summary) == _table(whole.summary)
    expected = LoadHistory.from_run(whole.run)
    assert pieces.history is not None and pieces.history.duration_s == expected.duration_s
    for got, want in [(pieces.history.t, expected.t), (pieces.history.margin, expected.margin),
                      (pieces.history.reserve, expected.reserve)] + [
                         (pieces.history.hinge[name], values) for name, values in expected.hinge.items()]:
        np.testing.assert_array_equal(got, want)
    assert pieces.history.hinge.keys() == expected.hinge.keys()


# Peak RSS (ru_maxrss) of `linkage-monitor replay --out` over a bag of SHORT and of 4 * SHORT inputs
# (bench/long_bag.py: the bundled bag's inputs repeated), each in its own process. Replaying holds one
# piece of ENCODE_BLOCK inputs at a time, so the longer bag may take at most a few pieces' worth more
# (the allocator's arenas, measured ~5 MB). A replay holding every input's Step, its bytes and its
# output rows until the end took ~7 kB per input (1.0 GB at 10^5 inputs, 7.4 GB at 10^6: 7.1 kB per
# input between them; 176 MB more here): the bound, 1 kB per extra input (24 MB), fails any such
# growth above 1 kB per input and leaves the measured noise a four-fold margin.
SHORT = 2 * 4096
GROWTH_PER_INPUT_KB = 1.0
MEASURE = """import resource, sys
from linkage_monitor.cli.main import main
code = main(["replay", sys.argv[1], "--out", sys.argv[2], "--quiet"])
print(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss if code == 0 else -code)"""


def _peak_rss_kb(bag: Path, out: Path) -> int:
    done = subprocess.run([sys.executable, "-c", MEASURE, str(bag), str(out)], capture_output=True, text=True,
                          check=True)
    return int(done.stdout.split()[-1])


@pytest.mark.slow
def test_the_replays_memory_does_not_grow_with_the_bags_length(tmp_path):
    peaks = {}
    for inputs in (SHORT, 4 * SHORT):
        bag = tmp_path / f"long{inputs}"
        subprocess.run([sys.executable, str(ROOT / "bench" / "long_bag.py"), str(bag), "--inputs", str(inputs)],
                       check=True, capture_output=True)
        peaks[inputs] = _peak_rss_kb(bag, tmp_path / f"out{inputs}")
    assert min(peaks.values()) > 0, peaks
    growth = peaks[4 * SHORT] - peaks[SHORT]
    assert growth < GROWTH_PER_INPUT_KB * 3 * SHORT, f"peak RSS {peaks} kB: {growth / (3 * SHORT):.2f} kB per input"
