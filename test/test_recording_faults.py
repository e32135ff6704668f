"""Recording faults, made real: a full disk (a 256 KiB tmpfs), a read-only directory (a read-only
tmpfs), a file where the directory should be, and stamps MCAP cannot store. The writer reports
the fault (``error``), never raises from ``write``/``close``, and the bag on disk stays readable
by readers we did not write (mcap, rosbags) up to its last complete chunk."""

from __future__ import annotations

from pathlib import Path

import pytest
from mcap.reader import NonSeekingReader
from rosbags.highlevel import AnyReader
from rosbags.typesys import Stores, get_typestore
from std_msgs.msg import String

from linkage_monitor.bag.errors import BagError
from linkage_monitor.bag.split_files import MIN_SPLIT_SIZE
from linkage_monitor.bag.writer import BagWriter

T0 = 1_700_000_000_000_000_000  # ns, an arbitrary recording start


def _count_readable(bag: Path) -> tuple[int, int]:
    """Messages read back by mcap (linear scan of every file) and by rosbags."""
    by_mcap = 0
    for file in bag.glob("*.mcap"):
        with open(file, "rb") as f:
            by_mcap += sum(1 for _ in NonSeekingReader(f).iter_messages())
    with AnyReader([bag], default_typestore=get_typestore(Stores.EMPTY)) as reader:
        by_rosbags = sum(1 for _ in reader.messages())
    return by_mcap, by_rosbags


@pytest.mark.slow
@pytest.mark.parametrize("split", [0, MIN_SPLIT_SIZE], ids=["one file", "split by size"])
def test_full_disk_is_reported_and_the_bag_stays_readable(tmpfs, split):
    """Split by size, the disk fills while the fourth or so file is written: the files before are
    finished, the last one cut back to its last complete chunk; all of them read as one bag."""
    disk = tmpfs("size=512k")
    writer = BagWriter(disk / "run", chunk_size=16 * 1024, flush_period_s=0.05, max_bag_size=split)
    payload = "x" * 2000   # incompressible enough: 2 kB per message
    written = 0
    import random
    rng = random.Random(1)
    for i in range(2000):
        text = "".join(rng.choice("abcdefghijklmnopqrstuvwxyz0123456789") for _ in range(len(payload)))
        writer.write("/chatter", String(data=text), T0 + i, log_time_ns=T0 + i)   # never raises
        if writer.error is None:
            written = i + 1
        writer.flush()
    assert writer.error is not None and "No space left" in writer.error and str(disk) in writer.error
    assert writer.unwritten > 0
    writer.close()   # never raises
    # the line the node logs at its end: the recording failed, and where the partial bag is (not "bag written")
    assert writer.outcome.startswith("recording failed: ") and "bag written" not in writer.outcome
    assert f"{writer.unwritten} message(s) not recorded" in writer.outcome and str(disk / "run") in writer.outcome
    by_mcap, by_rosbags = _count_readable(disk / "run")
    assert 0 < by_mcap == by_rosbags <= written
    assert len(list((disk / "run").glob("*.mcap"))) == (1 if not split else len(writer.paths)) and \
        (not split or len(writer.paths) >= 3)


def test_read_only_directory_is_one_clear_error(tmpfs):
    ro = tmpfs("size=64k,ro")
    with pytest.raises(BagError) as err:
        BagWriter(ro / "run")
    assert str(ro) in str(err.value) and "Read-only" in str(err.value) and "\n" not in str(err.value)


def test_a_file_in_the_path_is_one_clear_error(tmp_path):
    (tmp_path / "bags").write_text("not a directory")
    with pytest.raises(BagError) as err:
        BagWriter(tmp_path / "bags" / "run")
    assert "bags" in str(err.value) and "\n" not in str(err.value)


def test_stamps_mcap_cannot_store_are_written_as_zero(tmp_path):
    with BagWriter(tmp_path / "run") as writer:
        writer.write("/a", String(data="negative"), -5_000_000_000, log_time_ns=T0)
        writer.write("/a", String(data="beyond 2^64"), 1 << 70, log_time_ns=T0 + 1)
        writer.write("/a", String(data="negative log time"), T0, log_time_ns=-1)
        assert writer.error is None
    with open(next((tmp_path / "run").glob("*.mcap")), "rb") as f:
        times = [(m.publish_time, m.log_time) for _, _, m in NonSeekingReader(f).iter_messages()]
    assert times[0] == (0, T0) and times[1] == (0, T0 + 1)
    assert times[2][0] == T0 and times[2][1] >= T0 + 1   # receive time: now, never before the last
    assert _count_readable(tmp_path / "run") == (3, 3)


def test_a_finished_recording_says_bag_written(tmp_path):
    with BagWriter(tmp_path / "run") as writer:
        writer.write("/a", String(data="x"), T0, log_time_ns=T0)
    assert writer.outcome == f"bag written: {tmp_path / 'run'} (1 message(s))"


# rclpy's release series per distribution, from ros2/rclpy's branches (jazzy 7.x, kilted 9.x): written
# here, not imported from the writer, so a wrong table in the writer fails this test
_DISTRO_OF_RCLPY_MAJOR = {"7": "jazzy", "9": "kilted"}


@pytest.mark.parametrize("environment", ["", "rolling"])
def test_ros_distro_is_the_installed_one_when_ros_distro_is_unset(tmp_path, monkeypatch, environment):
    """metadata.yaml's ros_distro: ROS_DISTRO when set, else the distribution of the installed rclpy (the
    `ros-jazzy-rclpy` wheel, rclpy 7.x, in .venv; Kilted's, 9.x, in .venv-kilted), never a default of
    another distribution."""
    from importlib.metadata import version

    import yaml

    from linkage_monitor.bag.metadata import ros_distro

    installed = _DISTRO_OF_RCLPY_MAJOR[version("rclpy").split(".")[0]]   # KeyError: a venv make setup does not build
    expected = environment or installed
    monkeypatch.setenv("ROS_DISTRO", environment)
    ros_distro.cache_clear()
    try:
        with BagWriter(tmp_path / "run"):
            pass
    finally:
        ros_distro.cache_clear()
    info = yaml.safe_load((tmp_path / "run" / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
    assert info["ros_distro"] == expected
