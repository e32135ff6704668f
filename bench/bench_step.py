"""One full monitoring step in-process, as the live node takes it (no rclpy): an input event
through ``Monitor.step`` (acceptance, solve from the previous pose, lift capacity, axle loads,
steerability, findings) and the three output messages written (``OutputEncoder``, CDR bytes).

belarus_1221, the simulator's lift at 100 Hz (stroke + lift-arm angle in one JointState, the
cap pressure on its own topic: each event is a step, each step solves). Printed: the median
and 90th percentile per step, the share of the solve alone (``Solver.solve``), against one
15×15 ``np.linalg.solve`` timed in the same run. Goals: step ≤ 50 µs median, the
solve ≤ 1× one ``np.linalg.solve``.

Run: ``.venv/bin/python bench/bench_step.py``
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from linkage_monitor.mechanics import Inputs, load_preset  # noqa: E402
from linkage_monitor.monitoring.config import MonitorConfig  # noqa: E402
from linkage_monitor.monitoring.core import Monitor  # noqa: E402
from linkage_monitor.wire.outputs import OutputEncoder  # noqa: E402
from linkage_monitor.sim.telemetry import simulate  # noqa: E402

PRESSURE_TOPIC = "/pressure/lift_cap_pressure"


def main() -> None:
    mech = load_preset("belarus_1221")
    stream = simulate(mech, "lift", rate_hz=100.0, start_ns=1_700_000_000_000_000_000)
    config = MonitorConfig(mechanism=mech.name, pressure_topics={PRESSURE_TOPIC: "lift_cap_pressure"},
                           pressure_absolute=False, staleness_limit_s=3600.0, stamp_tolerance_s=1e9)
    names = list(stream.joint_names)
    positions = stream.joint_positions.tolist()
    pressures = stream.pressure_values[:, 0].tolist()
    stamps = stream.stamps_ns.tolist()

    def run_steps() -> np.ndarray:
        """Seconds per event of one pass over the stream (a fresh Monitor: the first pose starts cold)."""
        monitor, encoder = Monitor(mech, config), OutputEncoder()
        times = np.empty(2 * len(stamps))
        clock = time.perf_counter
        for i, stamp in enumerate(stamps):
            t0 = clock()
            encoder.outputs(monitor, monitor.on_pressure(PRESSURE_TOPIC, pressures[i], stamp, stamp))
            t1 = clock()
            encoder.outputs(monitor, monitor.on_joint_state(names, positions[i], [], stamp, stamp))
            t2 = clock()
            times[2 * i], times[2 * i + 1] = t1 - t0, t2 - t1
        return times[2:]   # the first two events: no value yet for the joints, nothing solved

    run_steps()   # load the kernels, warm the caches
    steps = np.concatenate([run_steps() for _ in range(3)])

    monitor = Monitor(mech, config)
    inputs = [Inputs(cylinders={"lift_cylinder": p[1]}, angles={"lift_arm_angle": p[0]},
                     pressures={"lift_cap_pressure": pressures[i]}) for i, p in enumerate(positions)]
    solve_times = []
    for _ in range(3):
        previous = None
        for x in inputs:
            t0 = time.perf_counter()
            previous = monitor.solver.solve(x, previous=previous)
            solve_times.append(time.perf_counter() - t0)
    solve = np.array(solve_times)

    n = monitor.solver.kin.n
    rng = np.random.default_rng(0)
    a = rng.standard_normal((200, n, n)) + n * np.eye(n)
    b = rng.standard_normal((200, n))
    linear = []
    for _ in range(5):
        t0 = time.perf_counter()
        for k in range(200):
            np.linalg.solve(a[k], b[k])
        linear.append((time.perf_counter() - t0) / 200)
    one_linear = min(linear)

    us = 1e6
    print(f"belarus_1221, {len(stamps)} samples at 100 Hz (2 events each), 3 passes")
    print(f"one monitoring step (event -> solve, capacity, axle loads, findings, 3 messages as CDR): "
          f"median {np.median(steps) * us:7.1f} us, p90 {np.percentile(steps, 90) * us:7.1f} us  (goal <= 50 us)")
    print(f"the solve alone (Solver.solve from the previous pose):                     "
          f"median {np.median(solve) * us:7.1f} us")
    print(f"baseline: one {n}x{n} np.linalg.solve:                                      {one_linear * us:7.1f} us")
    print(f"ratio step / one linear solve:  {np.median(steps) / one_linear:6.1f}x")
    print(f"ratio solve / one linear solve: {np.median(solve) / one_linear:6.1f}x  (goal <= 1x)")


if __name__ == "__main__":
    main()
