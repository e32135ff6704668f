"""Test-wide set-up: DDS isolation before any rclpy context exists."""

import os

import pytest
import rclpy
from hypothesis import settings

from support.ros_env import isolate_ros_domain

isolate_ros_domain()

# CI (CI=true) replays the same examples every run, so a submission is judged on what was
# tested here; a developer's run keeps exploring new examples.
settings.register_profile("ci", derandomize=True, database=None)
if os.environ.get("CI"):
    settings.load_profile("ci")


@pytest.fixture(scope="module")
def ros():
    """An rclpy context in this test process for the tests of one module."""
    rclpy.init()
    yield
    rclpy.shutdown()


@pytest.fixture
def node(ros, tmp_path):
    """A belarus_1221 node in a child process (recording into tmp_path/bags, reliable inputs,
    staleness 0.5 s, stamps accepted within an hour of the clock) and a test client here: yields (client, process, tmp_path). A node the test
    did not stop or kill itself must exit cleanly (code 0) on Ctrl-C."""
    from support.ros_harness import MonitorClient, start_node, stop

    proc = start_node({"mechanism": "belarus_1221", "record_dir": str(tmp_path / "bags"),
                       "sensor_qos": "reliable", "staleness_limit": 0.5, "stamp_tolerance": 3600.0},
                      tmp_path / "node.log")
    client = MonitorClient()
    try:
        client.wait_for_node()
        yield client, proc, tmp_path
    finally:
        client.close()
        still_running = proc.poll() is None
        code = stop(proc)
        assert code == 0 or not still_running, f"node exit code {code}:\n" + (tmp_path / "node.log").read_text()


@pytest.fixture
def tmpfs(tmp_path):
    """Mount a tmpfs of the given options at a fresh directory (the tests run as root, as CI does)."""
    import subprocess

    mounted = []

    def mount(options: str):
        where = tmp_path / f"mnt{len(mounted)}"
        where.mkdir()
        subprocess.run(["mount", "-t", "tmpfs", "-o", options, "tmpfs", str(where)], check=True)
        mounted.append(where)
        return where
    yield mount
    for where in mounted:
        subprocess.run(["umount", str(where)], check=False)
