"""The output messages written as CDR bytes, alone: one pose's three outputs (``OutputEncoder.outputs``),
a recording's worth at once (``OutputEncoder.output_rows``, as the replay), one MarkerArray
(``LinkageMarkers.markers``) and one DiagnosticArray (``diagnostic_array``, CDR bytes published and
recorded as they are), against rclpy's ``serialize_message`` of the same HitchState built with the
generated class, timed in the same run. For the DiagnosticArray also what a message object costs on
its way out: ``serialize_message`` to publish it, again with ``exact_cdr`` to record it.

belarus_1221's simulated lift at 100 Hz, solved once; the encoders then run over the solved steps.
Printed: µs per message (median of 5 passes) and the ratios to ``serialize_message``.

Run: ``.venv/bin/python bench/bench_encode.py``
"""

from __future__ import annotations

import sys
import time
from pathlib import Path
from typing import Callable

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from diagnostic_msgs.msg import DiagnosticArray  # noqa: E402
from rclpy.serialization import deserialize_message, serialize_message  # noqa: E402

from linkage_monitor.mechanics import load_preset  # noqa: E402
from linkage_monitor.monitoring.config import MonitorConfig  # noqa: E402
from linkage_monitor.monitoring.core import Monitor  # noqa: E402
from linkage_monitor.msg import CylinderState, HitchState  # noqa: E402
from linkage_monitor.sim.telemetry import simulate  # noqa: E402
from linkage_monitor.wire.definitions import exact_cdr  # noqa: E402
from linkage_monitor.wire.diagnostics import DIAGNOSTIC_ARRAY, diagnostic_array  # noqa: E402
from linkage_monitor.wire.markers import LinkageMarkers  # noqa: E402
from linkage_monitor.wire.outputs import OutputEncoder  # noqa: E402

PRESSURE_TOPIC = "/pressure/lift_cap_pressure"


def per_item(run: Callable[[], object], count: int) -> float:
    """Median over 5 passes of the seconds per item of ``run`` (which handles ``count`` items)."""
    run()
    times = []
    for _ in range(5):
        t0 = time.perf_counter()
        run()
        times.append((time.perf_counter() - t0) / count)
    return float(np.median(times))


def main() -> None:
    mech = load_preset("belarus_1221")
    stream = simulate(mech, "lift", rate_hz=100.0, start_ns=1_700_000_000_000_000_000)
    config = MonitorConfig(mechanism=mech.name, pressure_topics={PRESSURE_TOPIC: "lift_cap_pressure"},
                           pressure_absolute=False, staleness_limit_s=3600.0, stamp_tolerance_s=1e9)
    monitor = Monitor(mech, config)
    names = list(stream.joint_names)
    steps = []
    for i, stamp in enumerate(stream.stamps_ns.tolist()):
        monitor.on_pressure(PRESSURE_TOPIC, float(stream.pressure_values[i, 0]), stamp, stamp)
        steps.append(monitor.on_joint_state(names, stream.joint_positions[i].tolist(), [], stamp, stamp))
    solved = [s for s in steps if s.pose is not None]
    encoder, markers = OutputEncoder(), LinkageMarkers(monitor.mechanism)

    def one_by_one() -> None:
        for step in solved:
            encoder.outputs(monitor, step)

    def drawn() -> None:
        for step in solved:
            markers.markers(step.stamp_ns, step.pose.result)   # type: ignore[union-attr]

    def diagnostics() -> None:
        for step in solved:
            diagnostic_array(step, "linkage_monitor", mech.name, step.stamp_ns)

    hitch = HitchState(cylinders=[CylinderState(name=c.name) for c in mech.cylinders], status_text="ok")

    def rclpy_hitch() -> None:
        for _ in solved:
            serialize_message(hitch)

    objects = [deserialize_message(diagnostic_array(step, "linkage_monitor", mech.name, step.stamp_ns), DiagnosticArray)
               for step in solved]

    def rclpy_diagnostics() -> None:
        for msg in objects:
            serialize_message(msg)
            exact_cdr(DIAGNOSTIC_ARRAY, serialize_message(msg))

    n, us = len(solved), 1e6
    base = per_item(rclpy_hitch, n)
    print(f"belarus_1221, {n} solved poses; median of 5 passes, us per pose")
    print(f"baseline: rclpy serialize_message(HitchState):     {base * us:7.2f} us")
    for label, run in (("OutputEncoder.outputs (3 messages)", one_by_one),
                       ("OutputEncoder.output_rows (3 messages)", lambda: encoder.output_rows(monitor, solved)),
                       ("LinkageMarkers.markers (MarkerArray)", drawn), ("diagnostic_array (DiagnosticArray)", diagnostics),
                       ("an rclpy DiagnosticArray published+recorded", rclpy_diagnostics)):
        t = per_item(run, n)
        print(f"{label:38s} {t * us:7.2f} us   {t / base:5.2f}x baseline")


if __name__ == "__main__":
    main()
