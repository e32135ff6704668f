"""The events of the step benches (``bench_step.py``, ``bench_uncertainty_step.py``,
``profile_step.py``): belarus_1221, the simulator's lift at 100 Hz, the stroke and the lift-arm
angle in one JointState and the cap pressure (gauge Pa) on its own topic, so that each event is a
step and each step solves; and one pass of them through a fresh ``Monitor``, timed event by event."""

from __future__ import annotations

import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from linkage_monitor.mechanics import Mechanism, load_preset  # noqa: E402
from linkage_monitor.monitoring.config import MonitorConfig  # noqa: E402
from linkage_monitor.monitoring.core import Monitor  # noqa: E402
from linkage_monitor.sim.telemetry import simulate  # noqa: E402

PRESSURE_TOPIC = "/pressure/lift_cap_pressure"


@dataclass(frozen=True)
class LiftEvents:
    """The mechanism, the monitor's configuration, and per sample the joint names, positions (rad,
    m), the cap pressure (gauge Pa) and the stamp (ns)."""

    mech: Mechanism
    config: MonitorConfig
    names: list[str]
    positions: list[list[float]]
    pressures: list[float]
    stamps: list[int]


def lift_events() -> LiftEvents:
    """The lift's events (the module docstring), stamped from 1.7e18 ns on."""
    mech = load_preset("belarus_1221")
    stream = simulate(mech, "lift", rate_hz=100.0, start_ns=1_700_000_000_000_000_000)
    config = MonitorConfig(mechanism=mech.name, pressure_topics={PRESSURE_TOPIC: "lift_cap_pressure"},
                           pressure_absolute=False, staleness_limit_s=3600.0, stamp_tolerance_s=1e9)
    return LiftEvents(mech, config, list(stream.joint_names), stream.joint_positions.tolist(),
                      stream.pressure_values[:, 0].tolist(), stream.stamps_ns.tolist())


def timed_pass(events: LiftEvents, config: MonitorConfig, after: Callable[[Monitor, Any], Any] | None = None
               ) -> np.ndarray:
    """Seconds per event of one pass over ``events`` through a fresh Monitor of ``config`` (the first
    pose starts cold), ``after(monitor, step)`` timed with each step when given; the first two
    events are left out (no value yet for the joints: nothing solved)."""
    monitor = Monitor(events.mech, config)
    times = np.empty(2 * len(events.stamps))
    clock = time.perf_counter
    for i, stamp in enumerate(events.stamps):
        t0 = clock()
        step = monitor.on_pressure(PRESSURE_TOPIC, events.pressures[i], stamp, stamp)
        if after is not None:
            after(monitor, step)
        t1 = clock()
        step = monitor.on_joint_state(events.names, events.positions[i], [], stamp, stamp)
        if after is not None:
            after(monitor, step)
        t2 = clock()
        times[2 * i], times[2 * i + 1] = t1 - t0, t2 - t1
    return times[2:]
