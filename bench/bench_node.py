"""The live node under load, against a no-op rclpy relay (bench/node_load.py) measured in the same run.

Usage: .venv/bin/python bench/bench_node.py [--quick] [--repeats R] [--soak-minutes M] [--no-soak] [--imu]
       [--uncertainty]

Paired: the relay and the node run side by side (namespaces /relay and /monitor), and every rate
step is measured R times for each, alternating which goes first, so that both see the same
moments of this shared machine (whose speed drifts by tens of percent within minutes); the
ratios are of the medians over the repeats, with the spread of the per-repeat ratios.

Per input rate (JointState on `joint_states`, reliable QoS, depth 1000 here, 100 at the node;
one FluidPressure first, staleness limit 1 h, so every JointState triggers one solve):
- loss: JointStates sent minus HitchStates received (reliable keep-last: a node that falls
  more than its queue depth behind drops the oldest);
- added latency: receive time here minus header.stamp (= wall time at publish), p50 / p99;
- CPU: the target process's user+system CPU time over the step / messages it handled.
With ``--imu`` the node also takes a sensor_msgs/Imu (``imu_topic``) before every JointState, at
the same rate (the relays are sent it too and do not subscribe): the steerability's dynamic fields
computed on every solve (docs/dynamics.md). With ``--uncertainty`` the node carries every pose's error
budget and judges the bounds on their intervals (the node parameter ``uncertainty``, docs/accuracy.md).
The highest sustained rate (zero loss and a latency that does not grow over the step), and ratios node / relay, are printed. Then the node's RSS
while it is fed 1 kHz for --soak-minutes (default 1; more than it can solve: it drops, the point
is whether memory grows). The node records its bag (default parameters) to a temporary directory.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import numpy as np
import psutil
import rclpy
from rclpy.qos import QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import FluidPressure, Imu, JointState
from std_msgs.msg import String

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "test"))
from support.ros_env import isolate_ros_domain  # noqa: E402  (before any rclpy context)
from support.ros_harness import LATCHED, stop  # noqa: E402

from linkage_monitor.mechanics.constants import ATMOSPHERIC_PRESSURE  # noqa: E402
from linkage_monitor.msg import HitchState  # noqa: E402
from linkage_monitor.ros.messages import header  # noqa: E402
from linkage_monitor.wire.cdr import stamp_ns  # noqa: E402

RELIABLE = QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE)
JOINTS = ["lift_cylinder", "lift_arm_angle"]
POSE = [0.60, -3.273065553967803]    # m, rad: a consistent belarus_1221 pose (work..transport)
GAUGE = 9.0e6                        # Pa, lift cylinder cap pressure
BACKLOG_LIMIT_MS = 20.0              # ms, latency growth over a step that counts as a queue building up


@dataclass
class StepResult:
    """One rate step: messages sent / received, latencies (ms), CPU per message (ms)."""

    rate: float
    sent: int
    received: int
    latency_ms: np.ndarray
    cpu_ms: float

    @property
    def lost(self) -> int:
        return self.sent - self.received

    @property
    def backlog_ms(self) -> float:
        """Growth of the latency over the step (median of the last third − of the first third), ms:
        a queue that builds up means the target does not keep up, even before it drops."""
        third = self.latency_ms.size // 3
        if third == 0:
            return float("nan")
        return float(np.median(self.latency_ms[-third:]) - np.median(self.latency_ms[:third]))

    @property
    def sustained(self) -> bool:
        """No message lost and no queue building up (latency growth < BACKLOG_LIMIT_MS)."""
        return self.lost == 0 and self.backlog_ms < BACKLOG_LIMIT_MS

    def line(self, label: str) -> str:
        p50, p99 = (np.percentile(self.latency_ms, q) if self.latency_ms.size else float("nan") for q in (50, 99))
        return (f"{label:<8s} {self.rate:>7.0f} Hz  sent {self.sent:>6d}  lost {self.lost:>6d}  "
                f"latency p50 {p50:>8.2f} ms  p99 {p99:>8.2f} ms  growth {self.backlog_ms:>7.1f} ms  "
                f"CPU {self.cpu_ms:>6.2f} ms/msg{'' if self.sustained else '  NOT SUSTAINED'}")


class Driver:
    """This process: publishes the inputs of the target in namespace ``ns`` and timestamps every
    HitchState on arrival."""

    def __init__(self, ns: str, imu: bool = False) -> None:
        self.ns = ns
        self.node = rclpy.create_node(f"bench_driver_{ns.strip('/')}")
        self.imu_pub = self.node.create_publisher(Imu, f"{ns}/imu", RELIABLE) if imu else None
        self.joint_pub = self.node.create_publisher(JointState, f"{ns}/joint_states", RELIABLE)
        self.pressure_pub = self.node.create_publisher(FluidPressure, f"{ns}/pressure/lift_cap_pressure", RELIABLE)
        self.arrivals: list[tuple[int, int]] = []   # (receive ns, stamp ns)
        self.node.create_subscription(HitchState, f"{ns}/hitch_state",
                                      lambda m: self.arrivals.append((time.time_ns(), stamp_ns(m.header))), RELIABLE)
        self.up: list = []
        self.node.create_subscription(String, f"{ns}/mechanism_description", self.up.append, LATCHED)

    def spin_for(self, seconds: float) -> None:
        end = time.monotonic() + seconds
        while (left := end - time.monotonic()) > 0:
            rclpy.spin_once(self.node, timeout_sec=left)

    def wait_for_target(self, timeout: float = 60.0) -> None:
        end = time.monotonic() + timeout
        while not (self.up and self.joint_pub.get_subscription_count() > 0
                   and self.node.count_publishers(f"{self.ns}/hitch_state") > 0):
            if time.monotonic() > end:
                raise RuntimeError("target process did not come up")
            rclpy.spin_once(self.node, timeout_sec=0.05)
        self.spin_for(0.5)
        self.up.clear()
        self.pressure_pub.publish(FluidPressure(header=header(time.time_ns()),
                                                fluid_pressure=GAUGE + ATMOSPHERIC_PRESSURE))
        self.spin_for(0.5)

    def drive(self, rate: float, seconds: float) -> int:
        """Publish JointStates at `rate` Hz for `seconds` s, stamped with the wall time (each after an Imu
        of a body at rest with ``--imu``); returns the count."""
        period_ns = int(1e9 / rate)
        start = time.time_ns()
        i = 0
        while time.time_ns() - start < seconds * 1e9:
            if self.imu_pub is not None:
                imu = Imu(header=header(time.time_ns()))
                imu.header.frame_id, imu.linear_acceleration.z = "imu_link", 9.80665
                self.imu_pub.publish(imu)
            self.joint_pub.publish(JointState(header=header(time.time_ns()), name=JOINTS, position=POSE))
            i += 1
            while (wait := start + i * period_ns - time.time_ns()) > 0:
                rclpy.spin_once(self.node, timeout_sec=wait * 1e-9)
        return i

    def drain(self, quiet: float = 1.0, timeout: float = 60.0) -> None:
        end, count, last = time.monotonic() + timeout, -1, time.monotonic()
        while time.monotonic() < end and time.monotonic() - last < quiet:
            rclpy.spin_once(self.node, timeout_sec=0.05)
            if len(self.arrivals) != count:
                count, last = len(self.arrivals), time.monotonic()


def run_step(driver: Driver, pid: int, rate: float, seconds: float, label: str) -> StepResult:
    """One rate step of one target: drive, drain, measure its CPU and the latencies."""
    proc = psutil.Process(pid)
    driver.arrivals.clear()
    cpu0 = sum(proc.cpu_times()[:2])
    sent = driver.drive(rate, seconds)
    driver.drain()
    cpu = sum(proc.cpu_times()[:2]) - cpu0
    latency = np.array([(r - s) * 1e-6 for r, s in driver.arrivals])
    step = StepResult(rate, sent, len(driver.arrivals), latency, 1e3 * cpu / max(1, len(driver.arrivals)))
    print(step.line(label), flush=True)
    return step


def run_paired(targets: dict[str, tuple[Driver, int]], rates: list[float], seconds: float, repeats: int
               ) -> dict[str, list[list[StepResult]]]:
    """Every rate, ``repeats`` times for each target, alternating which goes first; per target the list
    of rates, each with its repeats. Stops after two rates where the node kept up in no repeat."""
    results: dict[str, list[list[StepResult]]] = {name: [] for name in targets}
    names = list(targets)
    for rate in rates:
        for name in names:
            results[name].append([])
        for rep in range(repeats):
            for name in (names if rep % 2 == 0 else names[::-1]):
                driver, pid = targets[name]
                results[name][-1].append(run_step(driver, pid, rate, seconds, name))
        node = results["node"]
        if len(node) >= 2 and not any(s.sustained for s in node[-1] + node[-2]):
            break
    return results


def soak(driver: Driver, pid: int, minutes: float) -> None:
    """Feed 1 kHz for `minutes`; print the node's RSS every tenth of the time."""
    proc = psutil.Process(pid)
    rss0 = proc.memory_info().rss
    print(f"soak at 1 kHz for {minutes:g} min: RSS at start {rss0 / 2**20:.1f} MiB", flush=True)
    slices = 10
    sent = 0
    driver.arrivals.clear()
    for k in range(slices):
        sent += driver.drive(1000.0, 60.0 * minutes / slices)
        driver.arrivals.clear()   # keep this process's memory flat
        print(f"  t = {(k + 1) * minutes / slices:5.2f} min  RSS {proc.memory_info().rss / 2**20:7.1f} MiB", flush=True)
    print(f"  sent {sent} JointStates; RSS growth {(proc.memory_info().rss - rss0) / 2**20:+.1f} MiB", flush=True)


def start_relay(ns: str, log: Path, *options: str) -> subprocess.Popen:
    """bench/node_load.py (the relay; with ``--outputs --record-dir DIR`` the product's floor)."""
    return subprocess.Popen([sys.executable, str(Path(__file__).with_name("node_load.py")), *options, "--ros-args",
                             "-r", f"__ns:={ns}"], stdout=log.open("w"), stderr=subprocess.STDOUT, env=dict(os.environ))


def start_monitor(ns: str, params: dict, log: Path) -> subprocess.Popen:
    """The linkage_monitor node in namespace ``ns`` (the harness's start_node, with a namespace)."""
    args = [sys.executable, "-m", "linkage_monitor.ros.node", "--ros-args", "-r", f"__ns:={ns}"]
    for name, value in params.items():
        args += ["-p", f"{name}:={value}"]
    return subprocess.Popen(args, stdout=log.open("w"), stderr=subprocess.STDOUT, env=dict(os.environ))


def _median(steps: list[StepResult], value: Callable[[StepResult], float]) -> float:
    return float(np.median([value(s) for s in steps]))


def _p(q: float) -> Callable[[StepResult], float]:
    return lambda s: float(np.percentile(s.latency_ms, q)) if s.latency_ms.size else float("nan")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="fewer, shorter rate steps (about 2 min)")
    parser.add_argument("--repeats", type=int, default=2, help="measurements per rate and target (default 2)")
    parser.add_argument("--soak-minutes", type=float, default=1.0, help="minutes at 1 kHz for the RSS check")
    parser.add_argument("--no-soak", action="store_true")
    parser.add_argument("--imu", action="store_true", help="an Imu before every JointState (the node's imu_topic)")
    parser.add_argument("--uncertainty", action="store_true", help="the node's error budget on (parameter uncertainty)")
    args = parser.parse_args()
    isolate_ros_domain()
    rates = [50.0, 100.0, 200.0, 400.0] if args.quick else [50.0, 100.0, 150.0, 200.0, 250.0, 300.0, 400.0, 600.0,
                                                              1000.0]
    seconds = 3.0 if args.quick else 6.0
    rclpy.init()
    procs: list[subprocess.Popen] = []
    try:
        with tempfile.TemporaryDirectory() as tmp:
            work = Path(tmp)
            procs.append(start_relay("/relay", work / "relay.log"))
            procs.append(start_relay("/floor", work / "floor.log", "--outputs", "--record-dir", str(work / "floor")))
            procs.append(start_monitor("/monitor", {"mechanism": "belarus_1221", "sensor_qos": "reliable",
                                                    "staleness_limit": 3600.0, "record_dir": str(work / "bags"),
                                                    **({"imu_topic": "imu"} if args.imu else {}),
                                                    **({"uncertainty": True} if args.uncertainty else {})},
                                       work / "node.log"))
            drivers = {name: Driver(ns, args.imu) for name, ns in (("relay", "/relay"), ("floor", "/floor"),
                                                                     ("node", "/monitor"))}
            for driver in drivers.values():
                driver.wait_for_target()
            targets = {name: (drivers[name], proc.pid) for name, proc in zip(drivers, procs)}
            results = run_paired(targets, rates, seconds, args.repeats)
            if not args.no_soak and args.soak_minutes > 0:
                soak(drivers["node"], targets["node"][1], args.soak_minutes)
            for driver in drivers.values():
                driver.node.destroy_node()
    finally:
        for proc in procs:
            stop(proc)
        rclpy.shutdown()
    relay, floor, node = results["relay"], results["floor"], results["node"]

    def best(steps: list[list[StepResult]]) -> float:
        return max((rs[0].rate for rs in steps if all(s.sustained for s in rs)), default=0.0)
    print(f"highest sustained rate (zero loss, no queue building up, in every repeat): node {best(node):.0f} Hz, "
          f"relay {best(relay):.0f} Hz, floor {best(floor):.0f} Hz (rates tried: {', '.join(f'{r:g}' for r in rates)} "
          f"Hz, {seconds:g} s each, {args.repeats} repeats per target, interleaved)")
    for label, a, b in (("node / relay", node, relay), ("floor / relay", floor, relay), ("node / floor", node, floor)):
        _ratios(label, a, b)
    cpu = [_median(n, lambda s: s.cpu_ms) / _median(f, lambda s: s.cpu_ms) for n, f in zip(node, relay)]
    print(f"CPU per message node / relay over the rates: {min(cpu):.2f}-{max(cpu):.2f}x (goal <= 1.5x)")
    cpu = [_median(n, lambda s: s.cpu_ms) / _median(f, lambda s: s.cpu_ms) for n, f in zip(floor, relay)]
    print(f"CPU per message floor / relay over the rates: {min(cpu):.2f}-{max(cpu):.2f}x (the node's publishing and "
          "recording alone, nothing solved)")


def _ratios(label: str, a: list[list[StepResult]], b: list[list[StepResult]]) -> None:
    """Per rate, ratios a / b of the medians over the repeats [range of the per-repeat ratios]."""
    print(f"{label}, ratio of the medians over the repeats [range of the per-repeat ratios]:")
    for n, f in zip(a, b):
        if not all(s.latency_ms.size for s in n + f):
            continue
        parts = []
        for name, value in (("CPU", lambda s: s.cpu_ms), ("latency p50", _p(50)), ("p99", _p(99))):
            paired = [value(x) / value(y) for x, y in zip(n, f)]
            parts.append(f"{name} x{_median(n, value) / _median(f, value):.2f} [{min(paired):.2f}-{max(paired):.2f}]")
        print(f"{n[0].rate:>6.0f} Hz: " + ", ".join(parts))

if __name__ == "__main__":
    main()
