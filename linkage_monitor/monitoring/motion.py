"""The direction each force-measured cylinder moves in, from its measured length (``Motion``): its
seal friction's band in the error budget follows it (``mechanics.error_sources.SealFriction``).

A length sensor's readings scatter by its noise and its resolution step, so a change between two
readings is motion only beyond a deadband (MOTION_DEADBAND_M, or MOTION_DEADBAND_SIGMAS standard
deviations of the difference of two readings). Between two consecutive readings a slow rod moves
less than that (a 1 mm step sensor at 50 Hz sees nothing below 61 mm/s, most of a lift's stroke):
the change is taken over a window of MOTION_WINDOW_S instead (the reading now against the oldest one
within the window), whose deadband is the same (the difference of two readings) while the rod's
travel over it is the window's length times its speed: at 0.1 s a 1 mm step sensor sees 12 mm/s.
Standing at the first reading and for a cylinder whose length is not measured. Units SI (m, s).
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import Mapping

from linkage_monitor.mechanics.error_sources import ErrorSources, Motion
from linkage_monitor.mechanics.inputs import Inputs
from linkage_monitor.mechanics.model import Mechanism

MOTION_DEADBAND_M = 1e-4   # m: the least change of a cylinder's length over the window that is motion
MOTION_DEADBAND_SIGMAS = 3.0   # ... or this many standard deviations of the change its noise and steps make
# s: the window the change is taken over. Longer sees slower rods but lags a stop by up to its length (the
# seal then holds what the motion left, within the breakaway band: the moving band is too narrow there);
# at 0.1 s a raised-cosine lift decelerates below the deadband's speed before it stops (docs/accuracy.md).
MOTION_WINDOW_S = 0.1
# the motions, read once: a lookup on the Enum class takes ~0.1 µs
_STANDING, _LIFTING, _LOWERING = Motion.STANDING, Motion.LIFTING, Motion.LOWERING


@dataclass
class MotionTracker:
    """Each measured cylinder's ``deadband`` (m) and its readings within the window (stamp ns, length m)."""

    deadband: dict[str, float]
    window_ns: int = int(MOTION_WINDOW_S * 1e9)
    readings: dict[str, deque[tuple[int, float]]] = field(default_factory=dict)
    last: Mapping[str, Motion] = field(default_factory=lambda: MappingProxyType({}))   # handed out last (``motions``)

    @staticmethod
    def of(mech: Mechanism, sources: ErrorSources) -> "MotionTracker":
        """The tracker of ``mech``'s measured cylinders."""
        deadband = {}
        for name in mech.measurements.cylinders:
            parts = sources.sensor(name, "cylinders").components()
            scatter = math.hypot(parts["noise"], parts["resolution"]) * math.sqrt(2.0)
            deadband[name] = max(MOTION_DEADBAND_M, MOTION_DEADBAND_SIGMAS * scatter)
        return MotionTracker(deadband)

    def motions(self, inputs: Inputs, stamp_ns: int) -> Mapping[str, Motion]:
        """Each measured cylinder's motion over the window ending at ``stamp_ns`` (ns), these inputs its
        latest reading; a stamp before the latest one starts the window anew. Read-only, and the same
        object as the call before while the motions are the same (the error budget then knows them
        by identity: ``UncertaintyModel.budget``)."""
        out = {}
        start = stamp_ns - self.window_ns
        for name, length in inputs.cylinders.items():
            kept = self.readings.get(name)
            if kept is None:
                kept = self.readings[name] = deque()
            elif kept and stamp_ns < kept[-1][0]:
                kept.clear()
            while kept and kept[0][0] < start:
                kept.popleft()
            change = length - kept[0][1] if kept else 0.0
            out[name] = (_STANDING if abs(change) <= self.deadband.get(name, MOTION_DEADBAND_M)
                         else _LIFTING if change > 0.0 else _LOWERING)
            kept.append((stamp_ns, length))
        if out != self.last:   # Motion compares by identity: no Python call
            self.last = MappingProxyType(out)
        return self.last
