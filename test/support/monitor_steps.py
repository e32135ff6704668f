"""The monitoring core driven as the live node drives it: events through ``Monitor.step`` one at a
time."""

from __future__ import annotations

from linkage_monitor.monitoring.config import MonitorConfig
from linkage_monitor.monitoring.core import Monitor
from linkage_monitor.monitoring.events import ConfigEvent


def step_by_step(mech, config: MonitorConfig, events: list) -> list:
    """The Steps of ``events`` through ``Monitor.step`` one at a time (a ConfigEvent reconfigures)."""
    live = Monitor(mech, config)
    stepped = []
    for event in events:
        if isinstance(event, ConfigEvent):
            live.reconfigure(event.config)
        else:
            stepped.append(live.step(event))
    return stepped
