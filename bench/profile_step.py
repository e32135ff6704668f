"""Where one in-process monitoring step's time goes, stage by stage (the step of ``bench_step.py``).

Each stage is wrapped with a wall-clock timer (``time.perf_counter``; a wrapper adds ~0.3 µs):
``Monitor.step`` (the whole step), its acceptance (``_accept``), the solve with the machine level
(``MachineModel.solve``; inside it the one compiled call, ``kernels.live_series``), the findings
(``_finish``) and the three output messages (``OutputEncoder.outputs``). Printed: µs per event, averaged over three passes of
belarus_1221's simulated lift at 100 Hz (2 events per sample). Not a benchmark with a baseline:
a profile, for docs/performance.md.

``--idle-ms T``: sleep T ms before every event, as a sensor stream leaves the CPU idle between
messages (one pass). On these machines a step that follows an idle gap runs several times slower
than in a tight loop (caches and the CPU are cold after the gap): the live node's steps are of
that kind (docs/performance.md, "A step after an idle gap").

Run: ``.venv/bin/python bench/profile_step.py [--idle-ms T]``
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path
from typing import Any, Callable

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from lift_events import PRESSURE_TOPIC, lift_events  # noqa: E402  # bench/ is the script's directory
from linkage_monitor.mechanics import kernels, machine  # noqa: E402
from linkage_monitor.monitoring import core  # noqa: E402
from linkage_monitor.wire.outputs import OutputEncoder  # noqa: E402
STAGES = [(core.Monitor, "step", "step (whole)"), (core.Monitor, "_accept", "  acceptance"),
          (machine.MachineModel, "solve", "  solve with machine level"),
          (kernels, "live_series", "    compiled call (kernels.live_series)"),
          (core.Monitor, "_finish", "  findings"), (OutputEncoder, "outputs", "three CDR messages (after the step)")]


def timed(spent: dict[str, list], label: str, function: Callable[..., Any],
          clock: Callable[[], float] = time.perf_counter) -> Callable[..., Any]:
    """``function`` counting its calls and the seconds of ``clock`` it takes into ``spent[label]``
    ([calls, seconds]; also used by profile_node.py with the thread CPU clock)."""
    entry = spent.setdefault(label, [0, 0.0])

    def wrapper(*args: Any, **kwargs: Any) -> Any:
        t0 = clock()
        try:
            return function(*args, **kwargs)
        finally:
            entry[0] += 1
            entry[1] += clock() - t0
    return wrapper


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--idle-ms", type=float, default=0.0, help="ms of sleep before every event (default 0)")
    idle_s = parser.parse_args().idle_ms * 1e-3
    spent: dict[str, list] = {}
    for owner, name, label in STAGES:
        setattr(owner, name, timed(spent, label, getattr(owner, name)))
    events = lift_events()
    mech, config, names, positions, pressures, stamps = (events.mech, events.config, events.names, events.positions,
                                                         events.pressures, events.stamps)

    def one_pass(idle: float) -> None:
        monitor, encoder = core.Monitor(mech, config), OutputEncoder()
        for i, stamp in enumerate(stamps):
            if idle:
                time.sleep(idle)
            encoder.outputs(monitor, monitor.on_pressure(PRESSURE_TOPIC, pressures[i], stamp, stamp))
            if idle:
                time.sleep(idle)
            encoder.outputs(monitor, monitor.on_joint_state(names, positions[i], [], stamp, stamp))

    one_pass(0.0)   # load the kernels, warm the caches
    for entry in spent.values():
        entry[:] = [0, 0.0]
    passes = 1 if idle_s else 3
    for _ in range(passes):
        one_pass(idle_s)
    events = passes * 2 * len(stamps)
    print(f"belarus_1221, {len(stamps)} samples at 100 Hz, {passes} pass(es), {events} events, "
          f"{1e3 * idle_s:g} ms idle before each; us per event:")
    for _, _, label in STAGES:
        print(f"{label:40s} {1e6 * spent[label][1] / events:7.1f}")


if __name__ == "__main__":
    main()
