"""Replay a recorded bag offline: the node's logic, with the solver batched over all poses.

Reads every sensor_msgs/JointState and sensor_msgs/FluidPressure of a rosbag2 MCAP bag (ours
or one from `ros2 bag record`), feeds them in recording order through the same input stages
as the live node (monitor.Monitor: latest value of every input, staleness, validation), solves
all due poses at once (Solver.solve_batch, MachineModel.evaluate_batch), and builds the same
output messages and diagnostics as the node. Outputs go to a new bag and/or an .rrd file.
Units SI; frame x forward, z up, origin at the rear wheels' ground contact.
"""

from __future__ import annotations

import math
import re
import sys
import time
from collections import Counter
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Iterator, TextIO

import numpy as np
import yaml
from tqdm import tqdm

from linkage_monitor.bag.reader import FLUID_PRESSURE, JOINT_STATE, read_bag
from linkage_monitor.ros.diagnostics import DiagnosticGate, diagnostic_array
from linkage_monitor.monitoring.inputs import InputConfig
from linkage_monitor.mechanics import BatchResult, Mechanism, mechanism_from_dict
from linkage_monitor.mechanics.machine import MachineBatch
from linkage_monitor.mechanics.results import Status
from linkage_monitor.monitoring.core import ERROR, OK, WARN, WARNING_JOIN, Monitor, Pending, Step
from linkage_monitor.bag.writer import MECHANISM_TOPIC, BagError, BagWriter

OUTPUT_TOPICS = ("/hinge_reactions", "/hitch_state", "/steerability")


@dataclass
class Summary:
    """What a replay found: message counts, peaks and limits with their times (s from the first input)."""

    inputs: int = 0
    solved: int = 0
    start_ns: int = 0
    peak_hinge: dict[str, tuple[float, float]] = field(default_factory=dict)   # name -> (N, s)
    min_margin: tuple[float, float] | None = None                              # (-, s)
    min_reserve: tuple[float, float] | None = None                             # (-, s)
    kinds: Counter = field(default_factory=Counter)                             # (level, kind) -> count
    seconds: float = 0.0

    def table(self) -> str:
        """The summary as a plain-text table."""
        lines = [f"replayed {self.inputs} input messages, {self.solved} poses solved in {self.seconds:.2f} s "
                 f"({self.inputs / max(self.seconds, 1e-9):,.0f} msg/s)", "",
                 "hinge      peak reaction [kN]   at [s]"]
        for name, (value, at) in self.peak_hinge.items():
            lines.append(f"{name:<10} {value / 1e3:18.2f} {at:8.2f}")
        if self.min_margin is not None:
            lines.append(f"\nminimum steerability margin {self.min_margin[0]:+.3f} at {self.min_margin[1]:.2f} s")
        if self.min_reserve is not None:
            lines.append(f"minimum lift reserve {self.min_reserve[0]:.2f} at {self.min_reserve[1]:.2f} s")
        lines.append("\nlevel  count  kind")
        if not self.kinds:
            lines.append("(no warnings or errors)")
        for (level, kind), count in sorted(self.kinds.items()):
            lines.append(f"{level:<6} {count:5d}  {kind}")
        return "\n".join(lines)


def _kind(message: str) -> str:
    """The kind of a diagnostic message: the clause before its first ':', numbers as '#'."""
    return re.sub(r"[-+]?\d[\d.,e+-]*", "#", message.split(":", 1)[0]).strip()


def mechanism_in_bag(path: Path) -> Mechanism:
    """The mechanism description the node stored in its bag (MECHANISM_TOPIC)."""
    for _, _, _, _, msg in read_bag(path, topics=[MECHANISM_TOPIC]):
        return mechanism_from_dict(yaml.safe_load(msg.data), file=f"{path} ({MECHANISM_TOPIC})")
    raise BagError(f"bag {path} holds no mechanism description on {MECHANISM_TOPIC}: "
                   "give --preset NAME or --mechanism FILE")


def _events(path: Path) -> Iterator[tuple[str, str, int, object]]:
    for topic, type_name, stamp, _, msg in read_bag(path, types=(JOINT_STATE, FLUID_PRESSURE)):
        yield topic, type_name, stamp, msg


def replay(bag: Path, mech: Mechanism, out_dir: Path | None = None, rrd: Path | None = None,
           rate: float | None = None, config: InputConfig | None = None, progress: TextIO | None = sys.stderr
           ) -> tuple[Summary, list[Step]]:
    """Re-run the monitor over `bag`; write outputs to `out_dir` (a new bag) and/or `rrd`.

    config: how topics map to the mechanism's sensors; default: identity joint names and the
    pressure sensors whose `pressure/<sensor>` topics the bag holds.
    rate: play at this multiple of real time (None: as fast as possible). Returns the summary
    and every Step (one per input message, in recording order).
    """
    started = time.perf_counter()
    events = list(_events(bag))
    if config is None:  # the pressure sensors whose default topics were recorded
        recorded = {topic.lstrip("/") for topic, *_ in events}
        default = InputConfig.default(mech)
        config = replace(default, pressure_topics={t: s for t, s in default.pressure_topics.items() if t in recorded})
    monitor = Monitor(mech, config)
    writer = BagWriter(out_dir) if out_dir is not None else None
    summary = Summary()
    stages: list[Pending | Step] = []
    raw: list[tuple[str, int, object]] = []
    for topic, type_name, stamp, msg in events:
        if type_name == JOINT_STATE:
            stages.append(monitor.accept_joint_state(list(msg.name), list(msg.position), stamp))
        else:
            stages.append(monitor.accept_pressure(topic.lstrip("/"), msg.fluid_pressure, stamp))
        raw.append((topic, stamp, msg))
    if not raw:
        raise BagError(f"bag {bag} holds no {JOINT_STATE} or {FLUID_PRESSURE} messages: nothing to replay")
    summary.inputs, summary.start_ns = len(raw), raw[0][1]
    steps, solved = _solve_all(monitor, stages)
    if writer is not None:
        writer.record_mechanism(yaml.safe_dump(dict(mech.raw), sort_keys=False, allow_unicode=True), raw[0][1])
    gate = DiagnosticGate()
    pace_start = time.perf_counter()
    for (topic, stamp, msg), step in tqdm(list(zip(raw, steps)), desc="replay", unit="msg", file=progress,
                                          disable=progress is None, mininterval=0.5):
        if rate:
            delay = (stamp - summary.start_ns) * 1e-9 / rate - (time.perf_counter() - pace_start)
            if delay > 0:
                time.sleep(delay)
        _account(summary, step)
        if writer is not None:
            writer.write(topic, msg, stamp, log_time_ns=stamp)
            if step.outputs is not None:
                o = step.outputs
                for out_topic, out_msg in zip(OUTPUT_TOPICS, (o.hinge_reactions, o.hitch_state, o.steerability)):
                    writer.write(out_topic, out_msg, step.stamp_ns, log_time_ns=stamp)
            if gate.due(step):
                writer.write("/diagnostics", diagnostic_array(step, f"linkage_monitor: {mech.name}", mech.name),
                             step.stamp_ns, log_time_ns=stamp)
    if rrd is not None:
        _log_rerun(rrd, mech, steps, solved)
    if writer is not None:
        writer.close()
    summary.seconds = time.perf_counter() - started
    return summary, steps


@dataclass(frozen=True)
class Solved:
    """The batch of every pose that was due: stamps (ns), solver and machine-level results."""

    stamps_ns: np.ndarray
    batch: BatchResult
    machine: MachineBatch


def _solve_all(monitor: Monitor, stages: list[Pending | Step]) -> tuple[list[Step], Solved | None]:
    """Solve every pending pose in one batch and finish it exactly as the live node does."""
    due = [i for i, s in enumerate(stages) if isinstance(s, Pending)]
    steps: list[Step | None] = [s if isinstance(s, Step) else None for s in stages]
    if not due:
        return steps, None  # type: ignore[return-value]
    pending = [stages[i] for i in due]

    def column(kind: str) -> dict[str, np.ndarray]:
        names = getattr(pending[0].inputs, kind).keys()
        return {n: np.array([getattr(p.inputs, kind)[n] for p in pending]) for n in names}

    batch = monitor.solver.solve_batch(cylinders=column("cylinders"), angles=column("angles"),
                                       pressures=column("pressures"))
    machine = monitor.machine.evaluate_batch(batch)
    for k, (i, p) in enumerate(zip(due, pending)):
        code = int(batch.status[k])
        if code in (Status.OK, Status.LIFT_OFF):
            steps[i] = monitor.finish(p, batch.result(k), machine.result(k))
        else:
            steps[i] = monitor.failed(p, code, batch.messages[k])
    stamps = np.array([p.stamp_ns for p in pending], dtype=np.int64)
    return steps, Solved(stamps, batch, machine)  # type: ignore[return-value]


def _account(summary: Summary, step: Step) -> None:
    at = (step.stamp_ns - summary.start_ns) * 1e-9
    if step.level != OK:
        for part in step.message.split(WARNING_JOIN):
            summary.kinds[({WARN: "WARN", ERROR: "ERROR"}[step.level], _kind(part))] += 1
    if step.outputs is None:
        return
    summary.solved += 1
    for h in step.outputs.hinge_reactions.hinges:
        if h.magnitude > summary.peak_hinge.get(h.name, (-1.0, 0.0))[0]:
            summary.peak_hinge[h.name] = (h.magnitude, at)
    margin = step.outputs.steerability.margin
    if math.isfinite(margin) and (summary.min_margin is None or margin < summary.min_margin[0]):
        summary.min_margin = (margin, at)
    reserve = step.outputs.hitch_state.lift_reserve
    if math.isfinite(reserve) and (summary.min_reserve is None or reserve < summary.min_reserve[0]):
        summary.min_reserve = (reserve, at)


def _log_rerun(path: Path, mech: Mechanism, steps: list[Step], solved: Solved | None) -> None:
    """Every solved pose as columns (one send per entity); rejected inputs as status text."""
    from linkage_monitor.viz.rerun_view import RerunView, default_blueprint, largest_hinges, machine_series

    hinges = largest_hinges(solved.batch) if solved is not None else None
    view = RerunView.to_file(mech, path, blueprint=default_blueprint(mech, hinges=hinges))
    for s in steps:
        if s.result is None and s.level == ERROR and not s.message.startswith(("cannot", "dead")):
            view.log_status(s.stamp_ns, s.message)  # the batch logs the poses the solver rejected
    if solved is not None:
        m = solved.machine
        view.log_batch(solved.stamps_ns, solved.batch, machine_series(m.steerability, m.lift_capacity))
    view.close()
