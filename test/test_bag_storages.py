"""Every rosbag2 storage in: the bundled bag's messages copied by rosbags' own writer (not this
package's) into a sqlite3 bag, a split sqlite3 bag, a split MCAP bag and one MCAP file (the twin);
each replays to outputs identical, byte for byte, to the twin's. The split bags' metadata.yaml lists
their files as rosbag2 does, checked by rosbags' reader reading each split bag as one. A ROS 1 bag
is refused with one line naming the command that converts it.
"""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest
import yaml
from rosbags.highlevel import AnyReader
from rosbags.rosbag2 import Reader, StoragePlugin, Writer
from rosbags.typesys import Stores, get_typestore

from linkage_monitor.bag.errors import BagError
from linkage_monitor.cli.main import main as cli_main
from linkage_monitor.offline.fleet import find_bags
from support.bag_outputs import output_bytes

SOURCE = Path(__file__).resolve().parents[1] / "bags" / "belarus_1221_lift_transport"
INPUTS = ("/linkage_monitor/mechanism", "/linkage_monitor/config", "/joint_states", "/pressure/lift_cap_pressure")


def _source_messages():
    """The source bag's input topics as (topic, msgtype, log time ns, CDR bytes), read by rosbags."""
    with AnyReader([SOURCE], default_typestore=get_typestore(Stores.EMPTY)) as reader:
        store = reader.typestore
        wanted = [c for c in reader.connections if c.topic in INPUTS]
        messages = [(c.topic, c.msgtype, t, bytes(raw)) for c, t, raw in reader.messages(connections=wanted)]
    return store, messages


def _write(path: Path, plugin: StoragePlugin, store, messages) -> Path:
    """A rosbag2 bag written by rosbags.rosbag2.Writer; the path of its storage file."""
    with Writer(path, version=9, storage_plugin=plugin) as writer:
        connections = {}
        for topic, msgtype, stamp, data in messages:
            if topic not in connections:
                connections[topic] = writer.add_connection(topic, msgtype, typestore=store)
            writer.write(connections[topic], stamp, data)
    return next(p for p in path.iterdir() if p.suffix in (".db3", ".mcap"))


def _split(path: Path, plugin: StoragePlugin, store, messages, parts: int = 3) -> Path:
    """A split bag: ``parts`` storage files (each from rosbags' writer, with every input topic's
    connection) under one metadata.yaml listing them as rosbag2 does."""
    size = -(-len(messages) // parts)
    files, infos = [], []
    for k in range(parts):
        chunk = messages[k * size:(k + 1) * size]
        part = _write(path.parent / f"{path.name}_part{k}", plugin, store, chunk)
        files.append(part)
        infos.append(yaml.safe_load((part.parent / "metadata.yaml").read_text())["rosbag2_bagfile_information"])
    path.mkdir()
    names = [f"{path.name}_{k}{f.suffix}" for k, f in enumerate(files)]
    for f, name in zip(files, names):
        shutil.copy(f, path / name)
    info = infos[0]
    counts: dict[str, int] = {}
    for part in infos:
        for entry in part["topics_with_message_count"]:
            counts[entry["topic_metadata"]["name"]] = counts.get(entry["topic_metadata"]["name"], 0) + entry["message_count"]
    topics = {e["topic_metadata"]["name"]: e for part in infos for e in part["topics_with_message_count"]}
    start = min(p["starting_time"]["nanoseconds_since_epoch"] for p in infos)
    end = max(p["starting_time"]["nanoseconds_since_epoch"] + p["duration"]["nanoseconds"] for p in infos)
    info.update(
        relative_file_paths=names,
        message_count=sum(p["message_count"] for p in infos),
        starting_time={"nanoseconds_since_epoch": start},
        duration={"nanoseconds": end - start},
        topics_with_message_count=[{**e, "message_count": counts[t]} for t, e in topics.items()],
        files=[{**p["files"][0], "path": name} for p, name in zip(infos, names)],
    )
    (path / "metadata.yaml").write_text(yaml.safe_dump({"rosbag2_bagfile_information": info}))
    return path


@pytest.fixture(scope="module")
def bags(tmp_path_factory):
    root = tmp_path_factory.mktemp("storages")
    store, messages = _source_messages()
    made = {"mcap_twin": root / "mcap_twin", "sqlite3": root / "sqlite3"}
    _write(made["mcap_twin"], StoragePlugin.MCAP, store, messages)
    _write(made["sqlite3"], StoragePlugin.SQLITE3, store, messages)
    made["sqlite3_file"] = next(made["sqlite3"].glob("*.db3"))
    made["sqlite3_split"] = _split(root / "sqlite3_split", StoragePlugin.SQLITE3, store, messages)
    made["mcap_split"] = _split(root / "mcap_split", StoragePlugin.MCAP, store, messages)
    return made, len(messages)



def _replay(bag: Path, out: Path) -> dict[str, list[bytes]]:
    assert cli_main(["replay", str(bag), "--out", str(out), "--quiet"]) == 0
    return output_bytes(out)


@pytest.mark.slow
@pytest.mark.parametrize("kind", ["sqlite3", "sqlite3_file", "sqlite3_split", "mcap_split"])
def test_a_bag_in_any_storage_replays_as_its_mcap_twin(bags, kind, tmp_path):
    made, count = bags
    twin = _replay(made["mcap_twin"], tmp_path / "twin_out")
    assert sum(len(v) for v in twin.values()) > 3000   # the bundled lift: 3257 of each output (its own bag)
    assert _replay(made[kind], tmp_path / f"{kind}_out") == twin


@pytest.mark.parametrize("kind", ["sqlite3_split", "mcap_split"])
def test_a_split_bag_is_one_bag_to_rosbags(bags, kind):
    made, count = bags
    assert len(yaml.safe_load((made[kind] / "metadata.yaml").read_text())
               ["rosbag2_bagfile_information"]["relative_file_paths"]) == 3
    with Reader(made[kind]) as reader:
        assert reader.message_count == count
    with AnyReader([made[kind]], default_typestore=get_typestore(Stores.EMPTY)) as reader:
        assert sum(1 for _ in reader.messages()) == count


def test_the_fleet_finds_sqlite3_bags(bags):
    made, _ = bags
    found = find_bags([made["sqlite3"].parent])
    assert made["sqlite3"] in found and made["sqlite3_split"] in found and made["mcap_twin"] in found


def test_calibrate_reads_a_sqlite3_bag(bags, tmp_path):
    made, _ = bags
    code = cli_main(["calibrate", "--preset", "belarus_1221", "--data", str(made["sqlite3"]),
                     "--free", "tractor.mass", "--out", str(tmp_path / "fit.yaml")])
    assert code == 0, "calibrate on the sqlite3 bag failed"
    assert "tractor" in (tmp_path / "fit.yaml").read_text()


def test_a_ros1_bag_is_refused_with_the_command_that_converts_it(tmp_path, capsys):
    bag = tmp_path / "field.bag"
    bag.write_bytes(b"#ROSBAG V2.0\n" + bytes(64))
    assert cli_main(["replay", str(bag), "--quiet"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "ROS 1 bag" in err[0] and "rosbags-convert" in err[0], err


def test_a_file_that_is_no_bag_says_so(tmp_path):
    from linkage_monitor.bag.storage import storage_files

    junk = tmp_path / "junk.mcap"
    junk.write_bytes(b"not a bag at all")
    with pytest.raises(BagError, match="neither an MCAP nor a sqlite3"):
        storage_files(junk)


@pytest.mark.parametrize("payload", ["lying schema", "huge count"])
def test_calibrate_on_a_hostile_bag_is_one_line(tmp_path, capsys, payload):
    """3259 messages under a JointState schema that are not JointStates (a FluidPressure's bytes cut
    short; a JointState whose name count claims 2^31 strings): calibrate refuses the bag in one line."""
    import struct

    from rclpy.serialization import serialize_message
    from sensor_msgs.msg import FluidPressure, JointState

    from linkage_monitor.bag.writer import BagWriter
    from linkage_monitor.wire.sensor_messages import JOINT_STATE

    if payload == "lying schema":
        data = serialize_message(FluidPressure(fluid_pressure=1e5))[:20]
    else:
        good = serialize_message(JointState(name=["lift_cylinder"], position=[0.6]))
        at = 4 + 8 + 4   # encapsulation, stamp, empty frame_id's length (an empty string: length 1 + NUL)
        at += 4          # the frame_id's one byte, padded to 4
        data = good[:at] + struct.pack("<I", 2**31) + good[at + 4:]
    bag = tmp_path / "hostile"
    with BagWriter(bag) as writer:
        for k in range(3259):
            writer.write("/joint_states", data, 10**18 + k, type_name=JOINT_STATE, log_time_ns=10**18 + k)
    code = cli_main(["calibrate", "--preset", "belarus_1221", "--data", str(bag), "--free", "tractor.mass",
                     "--out", str(tmp_path / "fit.yaml")])
    err = [line for line in capsys.readouterr().err.splitlines() if line.strip()]
    assert code == 2 and len(err) == 1, err
    assert str(bag) in err[0] and "do not decode" in err[0]
