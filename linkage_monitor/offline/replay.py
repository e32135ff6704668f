"""Replay a recorded bag offline: the live node's monitoring core, driven by the recording.

The bag's own record decides what is computed: the mechanism description the node stored
(MECHANISM_TOPIC), its configuration (CONFIG_TOPIC: input topics, joint map, pressure
convention, limits, overrides — a new copy at every runtime parameter change, applied from
there on). Inputs are read by their recorded topics only (a `ros2 bag record -a` bag may hold
other JointState topics). A bag without a recorded configuration (from `ros2 bag record`) gets
the default one. The events go through `Monitor.runs` (the same acceptance and finishing stages
as the node, the due poses solved in batches), ENCODE_BLOCK inputs at a time: each piece is
accounted in the summary and its outputs, built by the same functions as the node's, go to a new
bag and/or an .rrd file before the next piece is read (``replay_streaming`` then lets it go:
memory flat in the bag's length; ``replay`` keeps every Step for its caller).
Units SI; frame x forward, z up, origin at the rear wheels' ground contact.
"""

from __future__ import annotations

import functools
import gc
import logging
import math
import sys
import time
from collections import Counter
from contextlib import contextmanager
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Callable, Iterator, ParamSpec, TextIO, TypeVar

import numpy as np
from rclpy.serialization import deserialize_message
from std_msgs.msg import String

from linkage_monitor.bag.mcap_file import MessageColumns
from linkage_monitor.bag.reader import read_bag, read_bag_raw, read_bag_raw_blocks
from linkage_monitor.bag.step_recorder import RecordedInputs
from linkage_monitor.bag.errors import BagError
from linkage_monitor.bag.writer import MECHANISM_TOPIC
from linkage_monitor.mechanics import Mechanism, Status, mechanism_from_text
from linkage_monitor.monitoring.config import CONFIG_TOPIC, MonitorConfig
from linkage_monitor.monitoring.core import Monitor, Run, Segment, Step, Steps
from linkage_monitor.monitoring.events import ConfigEvent, Event, InputEvent
from linkage_monitor.monitoring.input_columns import InputColumns
from linkage_monitor.monitoring.weighing import WeighingEstimate, estimate_text
from linkage_monitor.wire.input_block import input_items
from linkage_monitor.wire.sensor_messages import FLUID_PRESSURE, IMU, JOINT_STATE

from .history import HistoryRecorder, LoadHistory
from .replay_outputs import ENCODE_BLOCK, BagOutput, RerunOutput

READ_BLOCK = 1024     # input messages read from their bytes at once


@dataclass
class Summary:
    """What a replay found: message counts, peaks and limits with their times (s from the first input)."""

    inputs: int = 0
    solved: int = 0
    start_ns: int = 0
    peak_hinge: dict[str, tuple[float, float]] = field(default_factory=dict)   # name -> (N, s)
    min_margin: tuple[float, float] | None = None                              # (-, s)
    min_reserve: tuple[float, float] | None = None                             # (-, s)
    kinds: Counter = field(default_factory=Counter)                             # (level, finding code) -> count
    notes: list[str] = field(default_factory=list)                              # what the replay assumed
    weighed: bool = False                             # the weighing ran (MonitorConfig.implement_mass_source)
    estimate: WeighingEstimate | None = None          # its estimate at the end (None: no lift/lower pair)
    seconds: float = 0.0

    def table(self) -> str:
        """The summary as a plain-text table."""
        lines = [*self.notes,
                 f"replayed {self.inputs} input messages, {self.solved} poses solved in {self.seconds:.2f} s "
                 f"({self.inputs / max(self.seconds, 1e-9):,.0f} msg/s)", "",
                 "hinge      peak reaction [kN]   at [s]"]
        for name, (value, at) in self.peak_hinge.items():
            lines.append(f"{name:<10} {value / 1e3:18.2f} {at:8.2f}")
        if self.min_margin is not None:
            lines.append(f"\nminimum steerability margin {self.min_margin[0]:+.3f} at {self.min_margin[1]:.2f} s")
        if self.min_reserve is not None:
            lines.append(f"minimum lift reserve {self.min_reserve[0]:.2f} at {self.min_reserve[1]:.2f} s")
        if self.weighed:
            lines.append("\nimplement weighed: " + estimate_text(self.estimate, None).replace("\n", "\n  "))
        lines.append("\nlevel  count  finding")
        if not self.kinds:
            lines.append("(no warnings or errors)")
        for (level, kind), count in sorted(self.kinds.items()):
            lines.append(f"{level:<6} {count:5d}  {kind}")
        return "\n".join(lines)


@dataclass(frozen=True)
class Recording:
    """What a bag says about the run that made it: the mechanism description and the first
    configuration (None when the bag does not hold them)."""

    description: Mechanism | None
    config: MonitorConfig | None


def recording_in_bag(path: Path) -> Recording:
    """The mechanism description and the first configuration the node stored in its bag."""
    description = config = None
    for topic, _, _, _, msg in read_bag(path, topics=[MECHANISM_TOPIC, CONFIG_TOPIC]):
        if topic == MECHANISM_TOPIC and description is None:
            description = mechanism_from_text(msg.data, file=f"{path} ({MECHANISM_TOPIC})")
        elif topic == CONFIG_TOPIC and config is None:
            config = MonitorConfig.from_yaml(msg.data, source=f"{path} ({CONFIG_TOPIC})")
        if description is not None and config is not None:
            break
    return Recording(description, config)


def mechanism_in_bag(path: Path) -> Mechanism:
    """The mechanism description the node stored in its bag (MECHANISM_TOPIC)."""
    description = recording_in_bag(path).description
    if description is None:
        raise BagError(f"bag {path} holds no mechanism description on {MECHANISM_TOPIC}: "
                       "give --preset NAME or --mechanism FILE")
    return description


@dataclass(frozen=True)
class Replayed:
    """A finished replay: the summary, one Step per input event, the solved segments (arrays; a
    configuration segment in pieces of up to ENCODE_BLOCK inputs, the pieces the replay solved)."""

    summary: Summary
    run: Run
    config: MonitorConfig

    @property
    def steps(self) -> Steps:
        return self.run.steps


@dataclass(frozen=True)
class Streamed:
    """A finished replay that kept no Steps (``replay_streaming``): the summary, the configuration
    and, when asked for, the load history of its solved poses."""

    summary: Summary
    config: MonitorConfig
    history: LoadHistory | None


def _default_config(bag: Path, description: Mechanism) -> MonitorConfig:
    """The default configuration, with the default pressure topics the bag actually holds."""
    config = MonitorConfig.default(description.name, description)
    held = {raw.topic for raw in read_bag_raw(bag, topics=list(config.pressure_topics))}
    return replace(config, pressure_topics={t: s for t, s in config.pressure_topics.items() if t in held})


def _events(path: Path, config: MonitorConfig, raw: RecordedInputs) -> Iterator[Event | InputColumns]:
    """The bag's input and configuration events in recording order, read as they are asked for (a block of
    columns at a time: ``read_bag_raw_blocks``), the inputs READ_BLOCK messages at a time as runs of columns
    and single events (``wire.input_block``); inputs also appended to ``raw`` (the caller takes them out
    piece by piece). The inputs are read from their bytes as the node reads them (``wire.sensor_messages``);
    bytes that are not their type (the node records them as they came) are an UnreadableEvent, as in the node."""
    imu = config.topics.imu   # the IMU the node was configured with ('' none; MonitorConfig)
    wanted = [config.topics.joint_states, *config.pressure_topics, *([imu] if imu else []), CONFIG_TOPIC]
    inputs = {(config.topics.joint_states, JOINT_STATE), *((topic, FLUID_PRESSURE) for topic in config.pressure_topics),
              *([(imu, IMU)] if imu else [])}   # (topic, type name) of the inputs read
    first_config = True
    block = MessageColumns([], [], [], [])   # inputs read, not yet handed over
    for read in read_bag_raw_blocks(path, topics=wanted):
        start = 0
        for end in [*(i for i, topic in enumerate(read.topic) if topic == CONFIG_TOPIC), len(read.topic)]:
            taken = [i for i, kind in enumerate(zip(read.topic[start:end], read.type_name[start:end]), start)
                     if kind in inputs]
            block.topic.extend([read.topic[i] for i in taken])
            block.type_name.extend([read.type_name[i] for i in taken])
            block.log_time_ns.extend([read.log_time_ns[i] for i in taken])
            block.data.extend([read.data[i] for i in taken])
            while len(block.data) >= READ_BLOCK:
                yield from _read_inputs(block, raw, READ_BLOCK)
            if end < len(read.topic):   # a configuration change
                yield from _read_inputs(block, raw, len(block.data))
                if not first_config:
                    yield ConfigEvent(_recorded_change(path, config, read.data[end], read.log_time_ns[end]))
                first_config = False
            start = end + 1
    yield from _read_inputs(block, raw, len(block.data))


def _recorded_change(path: Path, config: MonitorConfig, data: bytes, log_time_ns: int) -> MonitorConfig:
    """``config`` with the runtime parameters of the configuration change recorded (``data``, its CDR
    bytes, logged at ``log_time_ns``)."""
    try:
        text = deserialize_message(data, String).data
    except Exception as exc:  # noqa: BLE001 - rclpy raises RMWError for bytes it cannot read
        raise BagError(f"bag {path}: a configuration change on {CONFIG_TOPIC} (log time {log_time_ns} ns) "
                       f"does not decode as std_msgs/msg/String ({exc}): the bag is damaged") from None
    recorded = MonitorConfig.from_yaml(text, source=f"{path} ({CONFIG_TOPIC})")
    return replace(config, overrides=recorded.overrides, staleness_limit_s=recorded.staleness_limit_s,
                   stamp_tolerance_s=recorded.stamp_tolerance_s,
                   dead_centre_transmission_deg=recorded.dead_centre_transmission_deg, implement=recorded.implement)


def _read_inputs(block: MessageColumns, raw: RecordedInputs, count: int) -> Iterator[InputColumns | InputEvent]:
    """The first ``count`` input messages of ``block`` read (``wire.input_block.input_items``), each recorded
    in ``raw``, and taken out of ``block``."""
    if not count:
        return
    topics, type_names, receive, datas = (block.topic[:count], block.type_name[:count], block.log_time_ns[:count],
                                          block.data[:count])
    for column in block:
        del column[:count]
    items = input_items(topics, type_names, datas, receive)
    stamps: list[int] = []
    for item in items:
        stamps += item.stamps_ns.tolist() if isinstance(item, InputColumns) else [item.stamp_ns]
    raw.extend(RecordedInputs(topics, type_names, stamps, receive, datas))
    yield from items


_P = ParamSpec("_P")
_R = TypeVar("_R")


def _without_cyclic_gc(run: Callable[_P, _R]) -> Callable[_P, _R]:
    """``run`` with Python's cyclic garbage collector paused, and restored as it was after (on an
    error too). A replay makes few reference cycles, so a collection only walks live objects (with
    ``replay``, every Step kept so far): with it on, the bundled bag's replay writing its output bag
    took ~25 % longer (median of 5 runs, 0.41 s against 0.33 s). Reference counting still frees
    everything acyclic at once (the pieces ``replay_streaming`` lets go)."""
    @functools.wraps(run)
    def paused(*args: _P.args, **kwargs: _P.kwargs) -> _R:
        enabled = gc.isenabled()
        gc.disable()
        try:
            return run(*args, **kwargs)
        finally:
            if enabled:
                gc.enable()
    return paused


@_without_cyclic_gc
def replay(bag: Path, mech: Mechanism | None = None, out_dir: Path | None = None, rrd: Path | None = None,
           rate: float | None = None, config: MonitorConfig | None = None,
           progress: TextIO | None = sys.stderr, uncertainty: bool = False,
           implement_mass_source: str | None = None) -> Replayed:
    """Re-run the monitor over ``bag``; write outputs to ``out_dir`` (a new bag) and/or ``rrd``; keep
    every Step (memory grows with the bag: ``replay_streaming`` keeps none).

    mech / config: use these instead of what the bag recorded (the summary's notes say so);
    default: the recorded ones, else the default configuration of the mechanism.
    rate: write at this multiple of real time (None: as fast as possible). uncertainty: every pose's
    error budget, the limits judged on their 95 % intervals (``MonitorConfig.uncertainty``), whatever
    the bag recorded (a bag recorded before it replays with the mechanism's default error sources).
    implement_mass_source: where the machine-level results take the implement's mass and cg from
    (``MonitorConfig.implement_mass_source``; None: as recorded); other than ``file`` the weighing
    runs and the summary gives its estimate.
    """
    kept = _KeptRun()
    replayer = _Replayer(bag, mech, config, out_dir, rrd, rate, progress, [kept.add],
                         piece_steps=None if rrd is not None else ENCODE_BLOCK, uncertainty=uncertainty,
                         implement_mass_source=implement_mass_source)
    summary = replayer.replay()
    return Replayed(summary, kept.run(), replayer.config)


@_without_cyclic_gc
def replay_streaming(bag: Path, mech: Mechanism | None = None, out_dir: Path | None = None, rrd: Path | None = None,
                     rate: float | None = None, config: MonitorConfig | None = None,
                     progress: TextIO | None = sys.stderr, history: bool = False, uncertainty: bool = False,
                     implement_mass_source: str | None = None) -> Streamed:
    """``replay`` keeping no Steps: the bag is read, solved, accounted and written ENCODE_BLOCK inputs
    at a time, each piece let go once written, so that memory stays flat in the bag's length
    (test_replay.py holds it). history: also the ``LoadHistory`` of the solved poses (its arrays,
    ~8 bytes per pose and series, grow with the bag). With ``rrd`` a configuration segment is
    replayed whole (the recording's hinge plot and force scale are chosen from the segment's
    poses): memory grows with the longest segment. uncertainty, implement_mass_source: as ``replay``'s."""
    recorder = HistoryRecorder() if history else None
    replayer = _Replayer(bag, mech, config, out_dir, rrd, rate, progress, [recorder.add] if recorder else [],
                         piece_steps=None if rrd is not None else ENCODE_BLOCK, uncertainty=uncertainty,
                         implement_mass_source=implement_mass_source)
    summary = replayer.replay()
    return Streamed(summary, replayer.config, recorder.history() if recorder else None)


class _KeptRun:
    """The pieces of a run joined into one ``Run`` (as ``Monitor.run`` joins them)."""

    def __init__(self) -> None:
        self._steps: list[Step | None] = []
        self._segments: list[Segment] = []

    def add(self, piece: Run) -> None:
        self._segments.extend(replace(s, steps=s.steps + len(self._steps)) for s in piece.segments)
        self._steps.extend(piece.steps)

    def run(self) -> Run:
        return Run(Steps(self._steps), self._segments)


class _Replayer:
    """One replay of ``bag``: its events through ``Monitor.runs`` piece by piece (``piece_steps``
    Steps, or a configuration segment when None), each piece accounted in the summary, written to
    the output bag and the Rerun recording when asked, handed to ``consumers``, then let go."""

    def __init__(self, bag: Path, mech: Mechanism | None, config: MonitorConfig | None, out_dir: Path | None,
                 rrd: Path | None, rate: float | None, progress: TextIO | None,
                 consumers: list[Callable[[Run], None]], piece_steps: int | None = None,
                 uncertainty: bool = False, implement_mass_source: str | None = None) -> None:
        self.started = time.perf_counter()
        self.bag, self.out_dir, self.rrd, self.rate, self.progress = bag, out_dir, rrd, rate, progress
        self.consumers, self.piece_steps = consumers, piece_steps
        self.summary = Summary()
        recorded = recording_in_bag(bag)
        description = mech or recorded.description
        if description is None:
            raise BagError(f"bag {bag} holds no mechanism description on {MECHANISM_TOPIC}: "
                           "give --preset NAME or --mechanism FILE")
        if mech is not None and recorded.description is not None:
            self.summary.notes.append(f"note: mechanism '{mech.name}' given instead of the recorded "
                                      f"'{recorded.description.name}'")
        if config is None:
            config = recorded.config or _default_config(bag, description)
            if recorded.config is None:
                self.summary.notes.append("note: the bag holds no monitor configuration: default topics "
                                          f"{config.topics.joint_states}, "
                                          f"{', '.join(config.pressure_topics) or 'no pressures'}")
        else:
            self.summary.notes.append("note: configuration given instead of the recorded one")
        if uncertainty and not config.uncertainty:
            config = replace(config, uncertainty=True)
            self.summary.notes.append("note: the limits judged on their 95 % intervals of the mechanism's declared "
                                      "error sources (docs/accuracy.md)")
        if implement_mass_source is not None and implement_mass_source != config.implement_mass_source:
            config = replace(config, implement_mass_source=implement_mass_source)
            self.summary.notes.append(f"note: the implement's mass and cg from: {implement_mass_source} "
                                      "(docs/implements.md)")
        self.description, self.config = description, config

    def replay(self) -> Summary:
        """The summary of the whole replay (its outputs written)."""
        monitor = Monitor(self.description, self.config)
        raw = RecordedInputs()
        output: BagOutput | None = None
        view: RerunOutput | None = None
        try:
            with _progress_bar(self.progress) as advance:
                for piece in monitor.runs(_events(self.bag, self.config, raw), self.piece_steps):
                    inputs = raw.take(len(piece.steps))
                    if not self.summary.inputs:
                        self.summary.start_ns = inputs.stamp_ns[0]
                        output = self._bag_output(inputs.receive_ns[0])
                        view = RerunOutput(self.rrd, self.description) if self.rrd is not None else None
                    self.summary.inputs += len(inputs)
                    _account(self.summary, piece)
                    if output is not None:
                        output.write(monitor, inputs, piece)
                    if view is not None:
                        view.log(piece)
                    for consume in self.consumers:
                        consume(piece)
                    advance(len(inputs))
                    del piece, inputs   # let go before the next piece is solved: one piece held at a time
        finally:
            if output is not None:
                output.close()
        if not self.summary.inputs:
            raise BagError(f"bag {self.bag} holds no {JOINT_STATE} on {self.config.topics.joint_states} or "
                           f"{FLUID_PRESSURE} on {', '.join(self.config.pressure_topics) or '(none configured)'}: "
                           "nothing to replay")
        if view is not None:
            view.close()
        if monitor.weighing is not None:
            self.summary.weighed, self.summary.estimate = True, monitor.weighing.final_estimate()
        self.summary.seconds = time.perf_counter() - self.started
        return self.summary

    def _bag_output(self, first_receive_ns: int) -> BagOutput | None:
        """The output bag (begun at the first input's receive time), or None when none is asked for."""
        if self.out_dir is None:
            return None
        return BagOutput(self.out_dir, self.description, self.config, first_receive_ns, self.rate)


@contextmanager
def _progress_bar(progress: TextIO | None) -> Iterator[Callable[[int], object]]:
    """The replay's progress bar on ``progress``, advanced by the callable given (messages replayed), with
    what the reader finds (a cut file, a skipped chunk) written on a line of its own; without ``progress``
    none, tqdm not even imported (~0.05 s with its logging bridge)."""
    if progress is None:
        yield lambda replayed: None
        return
    from tqdm import tqdm
    from tqdm.contrib.logging import logging_redirect_tqdm

    with tqdm(desc="replay", unit="msg", file=progress, mininterval=0.5) as bar, \
            logging_redirect_tqdm([logging.getLogger("linkage_monitor")]):
        yield bar.update


def _account(summary: Summary, run: Run) -> None:
    """The run's findings by level and code, its solved poses, and the peaks and minima of its
    segments' columns with their times (the first pose where a value ties). A quiet pose (no finding:
    ``Steps``) is counted from its segment's columns, its Step not built."""
    for _, step in run.steps.said():
        for finding in step.findings:
            summary.kinds[(finding.level.name, finding.code.ident)] += 1
    for segment in run.segments:
        solved = segment.batch.status < Status.INPUT
        summary.solved += int(solved.sum())
        at = (segment.stamps_ns - summary.start_ns) * 1e-9
        for name, force in segment.batch.hinge_force.items():
            magnitude = np.where(solved, np.hypot(force[:, 0], force[:, 1]), -math.inf)
            k = int(np.argmax(magnitude))   # a segment holds at least one pose
            if magnitude[k] > summary.peak_hinge.get(name, (-1.0, 0.0))[0]:
                summary.peak_hinge[name] = (float(magnitude[k]), float(at[k]))
        machine = segment.machine
        summary.min_margin = _smallest(machine.steerability.get("margin"), solved, at, summary.min_margin)
        summary.min_reserve = _smallest(machine.lift_capacity.get("reserve"), solved, at, summary.min_reserve)


def _smallest(values: np.ndarray | None, solved: np.ndarray, at: np.ndarray,
              smallest: tuple[float, float] | None) -> tuple[float, float] | None:
    """The smaller of ``smallest`` (value, s) and the first smallest finite value of the solved poses."""
    if values is None:
        return smallest
    candidates = np.where(solved & np.isfinite(values), values, math.inf)
    k = int(np.argmin(candidates))
    if candidates[k] < math.inf and (smallest is None or candidates[k] < smallest[0]):
        return float(candidates[k]), float(at[k])
    return smallest
