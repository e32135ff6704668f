"""Real rclpy plumbing for integration tests: the node in a child process, a test node here."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from contextlib import contextmanager
from pathlib import Path
from typing import Any, Callable, Iterator

import rclpy
from diagnostic_msgs.msg import DiagnosticArray
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import FluidPressure, JointState
from std_msgs.msg import String

from linkage_monitor.msg import HingeReactions, HitchState, Steerability
from linkage_monitor.ros.messages import header
from linkage_monitor.wire.cdr import stamp_ns

RELIABLE = QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE)
LATCHED = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL)


def start_node(params: dict[str, Any], log: Path) -> subprocess.Popen:
    """`python -m linkage_monitor.ros.node` with `-p name:=value` for every parameter."""
    args = [sys.executable, "-m", "linkage_monitor.ros.node", "--ros-args"]
    for name, value in params.items():
        if isinstance(value, bool):
            value = str(value).lower()
        elif isinstance(value, list):
            value = "[" + ",".join(f"'{v}'" for v in value) + "]"
        args += ["-p", f"{name}:={value}"]
    return subprocess.Popen(args, stdout=log.open("w"), stderr=subprocess.STDOUT, env=dict(os.environ))


@contextmanager
def running_node(params: dict[str, Any], log: Path) -> Iterator[tuple["MonitorClient", subprocess.Popen]]:
    """A node of ``params`` in a child process (``start_node``, its output in ``log``) and a test client
    here, once the node is up. A node the caller did not stop or kill itself must exit cleanly (code 0)
    on Ctrl-C."""
    proc = start_node(params, log)
    client = MonitorClient()
    try:
        client.wait_for_node()
        yield client, proc
    finally:
        client.close()
        still_running = proc.poll() is None
        code = stop(proc)
        assert code == 0 or not still_running, f"node exit code {code}:\n" + log.read_text()


def stop(proc: subprocess.Popen, sig: int = signal.SIGINT, timeout: float = 20.0) -> int:
    """Stop a child process (SIGINT = Ctrl-C) and return its exit code."""
    if proc.poll() is None:
        proc.send_signal(sig)
        try:
            return proc.wait(timeout=timeout)
        except subprocess.TimeoutExpired:
            proc.kill()
    return proc.wait(timeout=timeout)


class MonitorClient:
    """A test-side node: publishes inputs, collects every output of the monitor node."""

    def __init__(self, pressure_topics: tuple[str, ...] = ("pressure/lift_cap_pressure",),
                 name: str = "test_client") -> None:
        self.node = rclpy.create_node(name)
        self.received: dict[str, list] = {k: [] for k in ("hinge_reactions", "hitch_state", "steerability",
                                                           "diagnostics", "mechanism_description")}
        for topic, cls in (("hinge_reactions", HingeReactions), ("hitch_state", HitchState),
                           ("steerability", Steerability)):
            self.node.create_subscription(cls, topic, self.received[topic].append, RELIABLE)
        self.node.create_subscription(DiagnosticArray, "/diagnostics", self.received["diagnostics"].append,
                                      RELIABLE)
        self.node.create_subscription(String, "mechanism_description",
                                      self.received["mechanism_description"].append, LATCHED)
        self.joint_pub = self.node.create_publisher(JointState, "joint_states", RELIABLE)
        self._pressure_pubs = {topic: self.node.create_publisher(FluidPressure, topic, RELIABLE)
                               for topic in pressure_topics}

    def spin_until(self, condition: Callable[[], bool], timeout: float) -> bool:
        """Spin until `condition()` holds or `timeout` s pass; returns whether it held."""
        end = time.monotonic() + timeout
        while time.monotonic() < end:
            if condition():
                return True
            rclpy.spin_once(self.node, timeout_sec=0.05)
        return condition()

    def wait_for_node(self, timeout: float = 30.0) -> None:
        """Wait until the monitor node is up (its latched mechanism description arrived) and
        subscribed to our inputs."""
        publishers = [self.joint_pub, *self._pressure_pubs.values()]
        ok = self.spin_until(lambda: bool(self.received["mechanism_description"])
                             and all(p.get_subscription_count() > 0 for p in publishers), timeout)
        assert ok, "linkage_monitor node did not come up (no mechanism_description / no subscription)"
        # A publisher sees the match before the subscriber does; messages sent in between are lost.
        self.spin_until(lambda: False, 0.5)

    def publish_joint_state(self, stamp: int, names: list[str], positions: list[float]) -> None:
        self.joint_pub.publish(JointState(header=header(stamp), name=names, position=positions))

    def publish_pressure(self, topic: str, stamp: int, pascal: float) -> None:
        self._pressure_pubs[topic].publish(FluidPressure(header=header(stamp), fluid_pressure=pascal))

    def outputs_at(self, topic: str, stamp: int) -> list:
        return [m for m in self.received[topic] if stamp_ns(m.header) == stamp]

    def diagnostics_at(self, stamp: int) -> list:
        return [s for m in self.received["diagnostics"] if stamp_ns(m.header) == stamp for s in m.status]

    def statuses(self, name_end: str, level: bytes | None = None) -> list:
        """The DiagnosticStatus entries received whose name ends with ``name_end`` (``": inputs"``), of
        ``level`` (``b"\\x01"``: WARN) when given, in the order received."""
        return [s for m in self.received["diagnostics"] for s in m.status
                if s.name.endswith(name_end) and (level is None or s.level == level)]

    def close(self) -> None:
        self.node.destroy_node()


def start_simulator(args: list[str], log: Path) -> subprocess.Popen:
    """`python -m linkage_monitor.cli.simulate <args>` (the options of `linkage-monitor simulate`);
    it exits by itself once the scenario has been published."""
    return subprocess.Popen([sys.executable, "-m", "linkage_monitor.cli.simulate", *args],
                            stdout=log.open("w"), stderr=subprocess.STDOUT, env=dict(os.environ))


def wait_exit(proc: subprocess.Popen, log: Path, timeout: float) -> None:
    """Wait for a child that ends by itself; fail with its log if it does not, or exits non-zero."""
    try:
        code = proc.wait(timeout=timeout)
    except subprocess.TimeoutExpired:
        stop(proc)
        raise AssertionError(f"{proc.args} did not end within {timeout} s:\n{log.read_text()}") from None
    assert code == 0, f"{proc.args} exit code {code}:\n{log.read_text()}"


def settle(client: "MonitorClient", topic: str, quiet: float = 1.0, timeout: float = 30.0) -> int:
    """Spin until no new message has arrived on `topic` for `quiet` s; returns the count received."""
    end = time.monotonic() + timeout
    count, last_change = -1, time.monotonic()
    while time.monotonic() < end:
        rclpy.spin_once(client.node, timeout_sec=0.05)
        if len(client.received[topic]) != count:
            count, last_change = len(client.received[topic]), time.monotonic()
        elif time.monotonic() - last_change >= quiet:
            break
    return count


def node_bag(record_dir: Path) -> Path:
    """The one bag directory the node created under its `record_dir` parameter."""
    bags = sorted(p.parent for p in record_dir.glob("*/metadata.yaml"))
    assert len(bags) == 1, f"expected one bag under {record_dir}, found {bags}"
    return bags[0]


def read_bag_rosbags(bag: Path) -> list[tuple[str, int, Any]]:
    """Every message of a bag directory as (topic, log time ns, message), in the reader's order
    (log time), decoded by rosbags AnyReader from the schemas embedded in the bag only."""
    from rosbags.highlevel import AnyReader
    from rosbags.typesys import Stores, get_typestore

    with AnyReader([bag], default_typestore=get_typestore(Stores.EMPTY)) as reader:
        return [(c.topic, t, reader.deserialize(raw, c.msgtype)) for c, t, raw in reader.messages()]
