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
from dataclasses import replace
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from lift_events import lift_events, timed_pass  # noqa: E402  # bench/ is the script's directory
from linkage_monitor.monitoring.config import MonitorConfig  # noqa: E402
GOAL = 1.5


def main() -> int:
    events = lift_events()
    plain = events.config

    def median_step(config: MonitorConfig) -> float:
        """Median seconds per event of one pass over the stream (a fresh Monitor)."""
        return float(np.median(timed_pass(events, config)))

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
