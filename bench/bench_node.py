"""The live node under load, against a no-op rclpy relay (bench/node_load.py) measured in the same run.

Usage: .venv/bin/python bench/bench_node.py [--quick] [--soak-minutes M] [--no-soak]

Per input rate (JointState on `joint_states`, reliable QoS, depth 1000 here, 100 at the node;
one FluidPressure first, staleness limit 1 h, so every JointState triggers one solve):
- loss: JointStates sent minus HitchStates received (reliable keep-last: a node that falls
  more than its queue depth behind drops the oldest);
- added latency: receive time here minus header.stamp (= wall time at publish), p50 / p99;
- CPU: the target process's user+system CPU time over the step / messages it handled.
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

import numpy as np
import psutil
import rclpy
from rclpy.qos import QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import FluidPressure, JointState
from std_msgs.msg import String

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "test"))
from support.ros_env import isolate_ros_domain  # noqa: E402  (before any rclpy context)
from support.ros_harness import LATCHED, start_node, stop  # noqa: E402

from linkage_monitor.mechanics.constants import ATMOSPHERIC_PRESSURE  # noqa: E402
from linkage_monitor.msg import HitchState  # noqa: E402
from linkage_monitor.ros.messages import header, stamp_ns  # noqa: E402

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
    """This process: publishes the inputs and timestamps every HitchState on arrival."""

    def __init__(self) -> None:
        self.node = rclpy.create_node("bench_driver")
        self.joint_pub = self.node.create_publisher(JointState, "joint_states", RELIABLE)
        self.pressure_pub = self.node.create_publisher(FluidPressure, "pressure/lift_cap_pressure", RELIABLE)
        self.arrivals: list[tuple[int, int]] = []   # (receive ns, stamp ns)
        self.node.create_subscription(HitchState, "hitch_state",
                                      lambda m: self.arrivals.append((time.time_ns(), stamp_ns(m.header))), RELIABLE)
        self.up: list = []
        self.node.create_subscription(String, "mechanism_description", self.up.append, LATCHED)

    def spin_for(self, seconds: float) -> None:
        end = time.monotonic() + seconds
        while (left := end - time.monotonic()) > 0:
            rclpy.spin_once(self.node, timeout_sec=left)

    def wait_for_target(self, timeout: float = 60.0) -> None:
        end = time.monotonic() + timeout
        while not (self.up and self.joint_pub.get_subscription_count() > 0
                   and self.node.count_publishers("hitch_state") > 0):
            if time.monotonic() > end:
                raise RuntimeError("target process did not come up")
            rclpy.spin_once(self.node, timeout_sec=0.05)
        self.spin_for(0.5)
        self.up.clear()
        self.pressure_pub.publish(FluidPressure(header=header(time.time_ns()),
                                                fluid_pressure=GAUGE + ATMOSPHERIC_PRESSURE))
        self.spin_for(0.5)

    def drive(self, rate: float, seconds: float) -> int:
        """Publish JointStates at `rate` Hz for `seconds` s, stamped with the wall time; returns the count."""
        period_ns = int(1e9 / rate)
        start = time.time_ns()
        i = 0
        while time.time_ns() - start < seconds * 1e9:
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


def run_ladder(driver: Driver, pid: int, rates: list[float], seconds: float, label: str) -> list[StepResult]:
    """Every rate in turn; stops after two unsustained steps in a row."""
    proc = psutil.Process(pid)
    results: list[StepResult] = []
    for rate in rates:
        driver.arrivals.clear()
        cpu0 = sum(proc.cpu_times()[:2])
        sent = driver.drive(rate, seconds)
        driver.drain()
        cpu = sum(proc.cpu_times()[:2]) - cpu0
        latency = np.array([(r - s) * 1e-6 for r, s in driver.arrivals])
        step = StepResult(rate, sent, len(driver.arrivals), latency, 1e3 * cpu / max(1, len(driver.arrivals)))
        print(step.line(label), flush=True)
        results.append(step)
        if len(results) >= 2 and not (results[-1].sustained or results[-2].sustained):
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


def measure(target: str, params: dict, rates: list[float], seconds: float, soak_minutes: float,
            workdir: Path) -> list[StepResult]:
    """Start the target process, run the rate ladder (and the soak for the node), stop it."""
    log = workdir / f"{target}.log"
    if target == "node":
        proc = start_node(params, log)
    else:
        proc = subprocess.Popen([sys.executable, str(Path(__file__).with_name("node_load.py"))],
                                stdout=log.open("w"), stderr=subprocess.STDOUT, env=dict(os.environ))
    driver = Driver()
    try:
        driver.wait_for_target()
        results = run_ladder(driver, proc.pid, rates, seconds, target)
        if soak_minutes > 0 and target == "node":
            soak(driver, proc.pid, soak_minutes)
    finally:
        driver.node.destroy_node()
        stop(proc)
    return results


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="fewer, shorter rate steps (about 1 min)")
    parser.add_argument("--soak-minutes", type=float, default=1.0, help="minutes at 1 kHz for the RSS check")
    parser.add_argument("--no-soak", action="store_true")
    args = parser.parse_args()
    isolate_ros_domain()
    rates = [50.0, 100.0, 200.0, 400.0] if args.quick else [50.0, 100.0, 150.0, 200.0, 250.0, 300.0, 400.0, 600.0,
                                                              1000.0]
    seconds = 3.0 if args.quick else 6.0
    rclpy.init()
    try:
        with tempfile.TemporaryDirectory() as tmp:
            work = Path(tmp)
            floor = measure("relay", {}, rates, seconds, 0.0, work)
            node = measure("node", {"mechanism": "belarus_1221", "sensor_qos": "reliable", "staleness_limit": 3600.0,
                                    "record_dir": str(work / "bags")},
                           rates, seconds, 0.0 if args.no_soak else args.soak_minutes, work)
    finally:
        rclpy.shutdown()
    best = max((s.rate for s in node if s.sustained), default=0.0)
    best_floor = max((s.rate for s in floor if s.sustained), default=0.0)
    print(f"highest sustained rate (zero loss, no queue building up): node {best:.0f} Hz, relay {best_floor:.0f} Hz (rates tried: "
          f"{', '.join(f'{r:g}' for r in rates)} Hz, {seconds:g} s each)")
    for n, f in zip(node, floor):
        if n.latency_ms.size and f.latency_ms.size:
            ratios = [np.percentile(n.latency_ms, q) / np.percentile(f.latency_ms, q) for q in (50, 99)]
            print(f"{n.rate:>6.0f} Hz: latency node/relay p50 x{ratios[0]:.1f}, p99 x{ratios[1]:.1f}; "
                  f"CPU node/relay x{n.cpu_ms / f.cpu_ms:.1f}")


if __name__ == "__main__":
    main()
