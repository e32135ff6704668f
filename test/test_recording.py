"""BagWriter output checked with readers we did not write: mcap + mcap-ros2-support,
rosbags (AnyReader from the embedded schemas only), and Rerun's MCAP import."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import textwrap
import threading
import time
from pathlib import Path

import numpy as np
import pytest
import yaml
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory
from rosbags.highlevel import AnyReader
from rosbags.typesys import Stores, get_types_from_msg, get_typestore
from sensor_msgs.msg import FluidPressure, JointState

from linkage_monitor.wire.definitions import dependencies, message_definition, msg_file
from linkage_monitor.bag.errors import BagError
from linkage_monitor.bag.writer import MECHANISM_TOPIC, BagWriter

REPO = Path(__file__).resolve().parents[1]
T0 = 1_700_000_000_000_000_000  # ns since the epoch, an arbitrary recording start
MECHANISM_YAML = "name: test_hitch\nlinks: []\n"


def _joint_state(i: int) -> JointState:
    msg = JointState(name=["lift_arm", "top_link"], position=[0.1 * i, -0.25],
                     velocity=[0.5, -1.5 * i])
    msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(T0 + i * 10_000_000, 10**9)
    msg.header.frame_id = "base_link"
    return msg


def _pressure(i: int) -> FluidPressure:
    msg = FluidPressure(fluid_pressure=1.0e5 + 2.5e5 * i, variance=4.0e6)
    msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(T0 + i * 10_000_000 + 5, 10**9)
    return msg


def _diagnostics(i: int) -> DiagnosticArray:
    status = DiagnosticStatus(level=DiagnosticStatus.WARN, name="linkage_monitor: solver",
                              message=f"residual {i}", hardware_id="hitch",
                              values=[KeyValue(key="residual_N", value=str(0.5 * i)),
                                      KeyValue(key="status", value="ok")])
    return DiagnosticArray(status=[status])


def _stamp(msg: JointState | FluidPressure) -> int:
    return msg.header.stamp.sec * 10**9 + msg.header.stamp.nanosec


@pytest.fixture(scope="module")
def bag(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A closed bag: 20 of each JointState, FluidPressure, DiagnosticArray + the mechanism."""
    directory = tmp_path_factory.mktemp("bags") / "run"
    with BagWriter(directory) as writer:
        writer.record_mechanism(MECHANISM_YAML, T0)
        for i in range(20):
            log = T0 + i * 10_000_000 + 1_000
            writer.write("/joint_states", _joint_state(i), _stamp(_joint_state(i)),
                         log_time_ns=log)
            writer.write("/hitch/lift_cylinder/pressure", _pressure(i), _stamp(_pressure(i)),
                         log_time_ns=log + 1)
            writer.write("/diagnostics", _diagnostics(i), log, log_time_ns=log + 2)
    return directory


def test_message_definition_follows_rosbag2_layout() -> None:
    # Expected text assembled from the installed .msg files by the rule of rosbag2_cpp
    # LocalMessageDefinitionSource::get_full_text: dependencies sorted per level, depth-first.
    def text(name: str) -> str:
        return msg_file(name).read_text()

    bar = "\n" + "=" * 80 + "\nMSG: "
    expected = (text("diagnostic_msgs/msg/DiagnosticArray")
                + bar + "diagnostic_msgs/DiagnosticStatus\n" + text("diagnostic_msgs/DiagnosticStatus")
                + bar + "diagnostic_msgs/KeyValue\n" + text("diagnostic_msgs/KeyValue")
                + bar + "std_msgs/Header\n" + text("std_msgs/Header")
                + bar + "builtin_interfaces/Time\n" + text("builtin_interfaces/Time"))
    assert message_definition("diagnostic_msgs/msg/DiagnosticArray") == expected
    # An independent parser (rosbags) finds all five types in it.
    types = get_types_from_msg(expected, "diagnostic_msgs/msg/DiagnosticArray")
    assert set(types) == {"diagnostic_msgs/msg/DiagnosticArray", "diagnostic_msgs/msg/DiagnosticStatus",
                          "diagnostic_msgs/msg/KeyValue", "std_msgs/msg/Header",
                          "builtin_interfaces/msg/Time"}


def test_dependencies_parse_every_field_form() -> None:
    text = textwrap.dedent("""\
        # comment: geometry_msgs/Fake not_a_field
        int32 MAX_JOINTS=8
        string<=8 short_name
        string[<=3] tags
        geometry_msgs/Point[] points   # unbounded array
        Wrench[2] wrenches
        std_msgs/Header[<=4] headers
        float64 load_N
        """)
    # the non-primitive types, own-package ones prefixed, sorted
    assert dependencies(text, "linkage_monitor") == [
        "geometry_msgs/Point", "linkage_monitor/Wrench", "std_msgs/Header"]


def test_mcap_ros2_decoder_reads_every_field(bag: Path) -> None:
    with open(bag / "run_0.mcap", "rb") as stream:
        reader = make_reader(stream, decoder_factories=[DecoderFactory()])
        assert reader.get_header().profile == "ros2"
        decoded = list(reader.iter_decoded_messages())
        summary = reader.get_summary()
    by_topic: dict[str, list] = {}
    for schema, channel, message, msg in decoded:
        by_topic.setdefault(channel.topic, []).append((schema, channel, message, msg))
        assert channel.message_encoding == "cdr" and schema.encoding == "ros2msg"
        assert schema.data.decode() == message_definition(schema.name)
        qos = yaml.safe_load(channel.metadata["offered_qos_profiles"])
        assert qos[0]["history"] == "keep_last"
    assert {t: len(v) for t, v in by_topic.items()} == {
        "/joint_states": 20, "/hitch/lift_cylinder/pressure": 20, "/diagnostics": 20,
        MECHANISM_TOPIC: 1}
    for i, (schema, _, message, msg) in enumerate(by_topic["/joint_states"]):
        assert schema.name == "sensor_msgs/msg/JointState"
        assert message.publish_time == _stamp(_joint_state(i))
        assert message.log_time == T0 + i * 10_000_000 + 1_000
        assert list(msg.name) == ["lift_arm", "top_link"]
        assert list(msg.position) == pytest.approx([0.1 * i, -0.25], abs=0)
        assert list(msg.velocity) == pytest.approx([0.5, -1.5 * i], abs=0)
        assert msg.header.frame_id == "base_link"
    for i, (_, _, _, msg) in enumerate(by_topic["/hitch/lift_cylinder/pressure"]):
        assert (msg.fluid_pressure, msg.variance) == (1.0e5 + 2.5e5 * i, 4.0e6)
    status = by_topic["/diagnostics"][7][3].status[0]
    assert (status.level, status.name, status.message) == (1, "linkage_monitor: solver", "residual 7")
    assert [(kv.key, kv.value) for kv in status.values] == [("residual_N", "3.5"), ("status", "ok")]
    mech = by_topic[MECHANISM_TOPIC][0]
    assert mech[3].data == MECHANISM_YAML
    assert yaml.safe_load(mech[1].metadata["offered_qos_profiles"])[0]["durability"] == "transient_local"
    assert summary is not None and len(summary.attachment_indexes) == 1


def test_rosbags_reads_directory_from_embedded_schemas(bag: Path) -> None:
    metadata = yaml.safe_load((bag / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
    assert metadata["version"] == 9 and metadata["storage_identifier"] == "mcap"
    assert metadata["relative_file_paths"] == ["run_0.mcap"]
    assert metadata["message_count"] == 61
    # log times span T0 (mechanism) .. T0 + 19*10 ms + 1 us + 2 ns (last diagnostics)
    assert metadata["starting_time"]["nanoseconds_since_epoch"] == T0
    assert metadata["duration"]["nanoseconds"] == 19 * 10_000_000 + 1_002
    with AnyReader([bag], default_typestore=get_typestore(Stores.EMPTY)) as reader:
        counts = {c.topic: c.msgcount for c in reader.connections}
        assert counts == {"/joint_states": 20, "/hitch/lift_cylinder/pressure": 20,
                          "/diagnostics": 20, MECHANISM_TOPIC: 1}
        rows = [(c.topic, t, reader.deserialize(raw, c.msgtype)) for c, t, raw in reader.messages()]
    joints = [m for topic, _, m in rows if topic == "/joint_states"]
    assert np.array_equal(np.array([m.position for m in joints]),
                          np.array([[0.1 * i, -0.25] for i in range(20)]))
    assert joints[3].header.stamp.nanosec == (T0 + 30_000_000) % 10**9
    pressures = [m.fluid_pressure for topic, _, m in rows if topic == "/hitch/lift_cylinder/pressure"]
    assert pressures == [1.0e5 + 2.5e5 * i for i in range(20)]
    diag = [m for topic, _, m in rows if topic == "/diagnostics"][19]
    assert diag.status[0].values[0].value == "9.5"
    assert [m.data for topic, _, m in rows if topic == MECHANISM_TOPIC] == [MECHANISM_YAML]


def test_rerun_mcap_import_reads_values(bag: Path) -> None:
    import pyarrow as pa
    import rerun.chunk as rc

    columns: dict[str, dict[str, list]] = {}
    for chunk in rc.McapReader(bag / "run_0.mcap").stream():
        batch = chunk.to_record_batch()
        for name in batch.schema.names:
            column = batch.column(name)
            if pa.types.is_timestamp(column.type):
                column = column.cast(pa.int64())  # ns since the epoch
            columns.setdefault(str(chunk.entity_path), {}).setdefault(name, []).extend(
                column.to_pylist())
    positions = columns["/joint_states/position"]
    order = np.argsort(positions["message_log_time"])
    scalars = np.array(positions["Scalars:scalars"], dtype=float)[order]
    assert np.array_equal(scalars, np.array([[0.1 * i, -0.25] for i in range(20)]))
    assert columns[MECHANISM_TOPIC]["TextDocument:text"] == [[MECHANISM_YAML]]
    pressure = columns["/hitch/lift_cylinder/pressure"]
    order = np.argsort(pressure["message_log_time"])
    assert [pressure["Measurements:values"][k] for k in order] == [
        [1.0e5 + 2.5e5 * i] for i in range(20)]
    assert pressure["Measurements:variances"][0] == [4.0e6]
    diagnostics = columns["/diagnostics"]
    last = diagnostics["diagnostic_msgs.msg.DiagnosticArray:message"][
        int(np.argmax(diagnostics["message_log_time"]))][0]
    assert last["status"][0]["message"] == "residual 19"
    assert last["status"][0]["values"][0] == {"key": "residual_N", "value": "9.5"}


def test_threads_write_concurrently(tmp_path: Path) -> None:
    directory = tmp_path / "threads"
    with BagWriter(directory, flush_period_s=0.05) as writer:
        def publish(topic: str) -> None:
            for i in range(300):
                writer.write(topic, _pressure(i), _stamp(_pressure(i)))

        threads = [threading.Thread(target=publish, args=(f"/p{k}",)) for k in range(4)]
        for thread in threads:
            thread.start()
        for thread in threads:
            thread.join()
    with AnyReader([directory], default_typestore=get_typestore(Stores.EMPTY)) as reader:
        counts = {c.topic: c.msgcount for c in reader.connections}
        times = [t for _, t, _ in reader.messages()]
    assert counts == {f"/p{k}": 300 for k in range(4)}
    assert len(times) == 1200


def test_a_writer_faster_than_the_background_thread_queues_at_most_max_queued(tmp_path: Path, monkeypatch) -> None:
    """write() only queues; past MAX_QUEUED queued messages it writes the queue itself, so memory
    stays bounded and every message lands, in order (read back by mcap-ros2-support)."""
    import linkage_monitor.bag.write_queue as write_queue

    monkeypatch.setattr(write_queue, "MAX_QUEUED", 50)
    directory = tmp_path / "burst"
    largest = 0
    with BagWriter(directory, flush_period_s=60.0) as writer:
        for i in range(1000):
            writer.write("/p", _pressure(i), T0 + i, log_time_ns=T0 + i)
            largest = max(largest, len(writer._queued))
    assert largest <= 50
    with open(next(directory.glob("*.mcap")), "rb") as f:
        stamps = [m.publish_time for _, _, m in make_reader(f).iter_messages(log_time_order=False)]
    assert stamps == [T0 + i for i in range(1000)]


def test_refuses_misuse(tmp_path: Path) -> None:
    writer = BagWriter(tmp_path / "bag")
    writer.write("/joint_states", _joint_state(0), 0)
    with pytest.raises(BagError, match="/joint_states"):
        writer.write("/joint_states", _pressure(0), 0)
    with pytest.raises(ValueError, match="type_name"):
        writer.write("/raw", b"\x00\x01\x00\x00", 0)
    writer.close()
    with pytest.raises(BagError, match="closed"):
        writer.write("/joint_states", _joint_state(1), 0)
    with pytest.raises(BagError, match="already holds a bag"):
        BagWriter(tmp_path / "bag")


_CHILD = """
import sys, time
from sensor_msgs.msg import JointState
from linkage_monitor.bag.writer import BagWriter
writer = BagWriter(sys.argv[1], flush_period_s={period})
i = 0
while True:
    now = time.time_ns()
    writer.write("/joint_states", JointState(name=["lift_arm"], position=[float(i)]), now,
                 log_time_ns=now)
    if i == 0:
        print("started", flush=True)
    i += 1
    time.sleep(0.002)
"""


@pytest.mark.slow
def test_killed_writer_leaves_a_readable_bag(tmp_path: Path) -> None:
    """SIGKILL mid-recording: every reader gets the messages up to the last flush."""
    import rerun.chunk as rc

    from linkage_monitor.bag.reader import read_bag

    period = 0.5
    directory = tmp_path / "killed"
    child = subprocess.Popen([sys.executable, "-c", _CHILD.format(period=period), str(directory)],
                             stdout=subprocess.PIPE, cwd=REPO,
                             env={**os.environ, "PYTHONPATH": str(REPO)})
    try:
        assert child.stdout is not None and child.stdout.readline().strip() == b"started"
        time.sleep(4 * period)
    finally:
        kill_ns = time.time_ns()
        child.send_signal(signal.SIGKILL)
        child.wait()
    positions = [msg.position[0] for _, _, _, _, msg in read_bag(directory)]
    log_times = [log_time for _, _, _, log_time, _ in read_bag(directory)]
    assert positions == [float(i) for i in range(len(positions))]  # none lost in between
    # The last flush was at most one period (+ scheduling slack on a busy machine) before the kill.
    assert kill_ns - log_times[-1] < (period + 1.0) * 1e9
    with AnyReader([directory], default_typestore=get_typestore(Stores.EMPTY)) as reader:
        assert [reader.deserialize(raw, c.msgtype).position[0]
                for c, _, raw in reader.messages()] == positions
    with open(directory / "killed_0.mcap", "rb") as stream:
        decoded = [m.position[0] for *_, m in make_reader(
            stream, decoder_factories=[DecoderFactory()]).iter_decoded_messages()]
    assert decoded == positions
    rerun_rows = sum(chunk.to_record_batch().num_rows for chunk in rc.McapReader(
        directory / "killed_0.mcap", recover=True,
        include_topic_regex=["joint_states"]).stream()
        if str(chunk.entity_path) == "/joint_states/position")
    assert rerun_rows == len(positions)
