"""The cost of the error budget in the live step: ``Monitor.step`` with ``MonitorConfig.uncertainty``
(every solved pose's budget and the verdicts on the bounds) against the same step without it, timed
in the same run over the same events.

belarus_1221, the simulator's lift at 100 Hz (stroke + lift-arm angle in one JointState, the cap
pressure on its own topic: each event is a step, each step solves). Printed: the median per step
with and without, and their ratio. Goal: with ≤ 1.5× without.

Run: ``.venv/bin/python bench/bench_uncertainty_step.py``
"""

from __future__ import annotations

import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from linkage_monitor.mechanics import load_preset  # noqa: E402
from linkage_monitor.monitoring.config import MonitorConfig  # noqa: E402
from linkage_monitor.monitoring.core import Monitor  # noqa: E402
from linkage_monitor.sim.telemetry import simulate  # noqa: E402

PRESSURE_TOPIC = "/pressure/lift_cap_pressure"
GOAL = 1.5


def main() -> int:
    mech = load_preset("belarus_1221")
    stream = simulate(mech, "lift", rate_hz=100.0, start_ns=1_700_000_000_000_000_000)
    plain = MonitorConfig(mechanism=mech.name, pressure_topics={PRESSURE_TOPIC: "lift_cap_pressure"},
                          pressure_absolute=False, staleness_limit_s=3600.0, stamp_tolerance_s=1e9)
    names, positions = list(stream.joint_names), stream.joint_positions.tolist()
    pressures, stamps = stream.pressure_values[:, 0].tolist(), stream.stamps_ns.tolist()

    def median_step(config: MonitorConfig) -> float:
        """Median seconds per event of one pass over the stream (a fresh Monitor)."""
        monitor = Monitor(mech, config)
        times = np.empty(2 * len(stamps))
        clock = time.perf_counter
        for i, stamp in enumerate(stamps):
            t0 = clock()
            monitor.on_pressure(PRESSURE_TOPIC, pressures[i], stamp, stamp)
            t1 = clock()
            monitor.on_joint_state(names, positions[i], [], stamp, stamp)
            t2 = clock()
            times[2 * i], times[2 * i + 1] = t1 - t0, t2 - t1
        return float(np.median(times[2:]))

    with_budget = replace(plain, uncertainty=True)
    median_step(plain), median_step(with_budget)   # load the kernels, warm the caches
    without = min(median_step(plain) for _ in range(3))
    with_ = min(median_step(with_budget) for _ in range(3))
    ratio = with_ / without
    print(f"Monitor.step, belarus_1221 lift at 100 Hz: {without * 1e6:.1f} µs without the error budget, "
          f"{with_ * 1e6:.1f} µs with it: {ratio:.1f}x ({'ok' if ratio <= GOAL else 'over'} the goal <= {GOAL}x)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
