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
from lift_events import lift_events, timed_pass  # noqa: E402  # bench/ is the script's directory
from linkage_monitor.mechanics import Inputs  # noqa: E402
from linkage_monitor.monitoring.core import Monitor  # noqa: E402
from linkage_monitor.wire.outputs import OutputEncoder  # noqa: E402


def main() -> None:
    events = lift_events()
    mech, config, positions, pressures, stamps = (events.mech, events.config, events.positions, events.pressures,
                                                  events.stamps)

    def run_steps() -> np.ndarray:
        """Seconds per event of one pass over the stream, its three messages written (a fresh Monitor:
        the first pose starts cold)."""
        return timed_pass(events, config, OutputEncoder().outputs)

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
