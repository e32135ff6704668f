"""The coverage study of the error budget, with a truth the monitor does not see (no rclpy).

Each run takes a stretch of a simulated stream of a mechanism (``sim.telemetry``), draws the sensors'
errors from the declared sources (``sim.sensor_errors``: biases and the seals' level once per run,
noise per sample; where points have tolerances, the true linkage once per run: ``sim.true_geometry``)
and feeds a fresh ``Monitor`` (``MonitorConfig.uncertainty``) the erroneous readings only, one
JointState and the pressures per sample. The truth of each sample is the same mechanics (with the
run's true points) solved from the true inputs (the pressures of the true loads, the true lengths and
angles). Tallied per output kind (``KIND_GROUPS``): the share of steps whose 95 % interval (value ±
k·u) holds the true value, the mean 95 % half-width (k·u, ``Budget.half_width``) over the RMS of the
actual error (sharpness), and per machine-level limit the steps the monitor passed (no finding about
that limit) whose true value is beyond it (wrong with OK) and those it passed while it called the judged
value's u unbounded (OK unbounded: its verdict then has no interval to clear). Units SI (N, -).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from linkage_monitor.mechanics import LinkageError, Mechanism
from linkage_monitor.monitoring.config import MonitorConfig
from linkage_monitor.monitoring.core import Monitor, Step
from linkage_monitor.monitoring.findings import Code

from .sensor_errors import SensorErrorSimulator, TrueInputs
from .true_geometry import draw_geometry, read_on
from .telemetry import SimulatedStream, simulate

# output kind (mechanics.budget.Output.kind) -> the group it is tallied in
KIND_GROUPS = {"hinge_fx": "hinge force", "hinge_fz": "hinge force", "hinge_magnitude": "hinge force",
               "cylinder_force": "cylinder force", "implement_load": "implement load", "axle_load": "axle load",
               "steerability_ratio": "steerability ratio", "lift_reserve": "lift reserve",
               "lift_capacity": "lift capacity"}
CANDIDATE_SCENARIOS = ("lift", "overload", "field_copy", "relief")   # each preset runs those it can simulate
RATE_HZ = 50.0
START_NS = 1_700_000_000_000_000_000
SCALE_TOLERANCE = 1e-9   # an error within this share of max(1, |truth|) is covered even where u is 0


@dataclass(frozen=True)
class Limit:
    """A machine-level limit: the output judged, the value it must not fall below, the finding codes
    about it and the prefix of their text that names it (the axle findings name their axle)."""

    output: str
    limit: float
    codes: frozenset[Code]
    prefix: str = ""

    def flagged(self, step: Step) -> bool:
        """A finding of ``step`` is about this limit."""
        return any(f.code in self.codes and f.text.startswith(self.prefix) for f in step.findings)


LIMITS = (Limit("steerability_margin", 0.0, frozenset({Code.STEERABILITY_LOW, Code.STEERABILITY_UNCERTAIN})),
          Limit("lift_reserve", 1.0, frozenset({Code.LIFT_RESERVE_LOW, Code.LIFT_RESERVE_UNCERTAIN})),
          Limit("front_axle_load", 0.0, frozenset({Code.AXLE_LIFT_OFF, Code.AXLE_LOAD_UNCERTAIN}), "front axle"),
          Limit("rear_axle_load", 0.0, frozenset({Code.AXLE_LIFT_OFF, Code.AXLE_LOAD_UNCERTAIN}), "rear axle"))


# Sums as fields, alike in form only to sim.work_cycle.WorkCycle: other data.
@dataclass
class GroupTally:
    """One output group's sums: ``steps`` (output × step pairs compared), ``covered``, Σ 95 % half-width
    and Σ error² (the group's unit); ``unbounded``: the pairs whose value and truth are finite but whose
    u the monitor gave as unbounded (no interval claimed: not compared)."""

    steps: int = 0
    unbounded: int = 0
    covered: int = 0
    half_width: float = 0.0
    squared_error: float = 0.0

    @property
    def coverage(self) -> float:
        """Share of the compared values whose 95 % interval holds the truth."""
        return self.covered / self.steps if self.steps else float("nan")

    @property
    def sharpness(self) -> float:
        """Mean 95 % half-width / RMS of the actual error."""
        rms = np.sqrt(self.squared_error / self.steps) if self.steps else float("nan")
        return (self.half_width / self.steps) / rms if self.steps and rms > 0.0 else float("nan")


@dataclass
class CoverageTally:
    """A study's counts: ``runs``; ``steps`` (samples fed), ``refused`` (no pose: the monitor refused
    the readings), ``untrue`` (the truth did not solve); per group a ``GroupTally``; per limit output
    the steps whose true value is beyond it (``beyond``) and those of them the monitor passed
    (``wrong_with_ok``), the steps whose value clears it with its u unbounded (``unbounded_value``) and
    those of them the monitor passed (``unbounded_ok``)."""

    runs: int = 0
    steps: int = 0
    refused: int = 0
    untrue: int = 0
    groups: dict[str, GroupTally] = field(default_factory=dict)
    beyond: dict[str, int] = field(default_factory=dict)
    wrong_with_ok: dict[str, int] = field(default_factory=dict)
    unbounded_value: dict[str, int] = field(default_factory=dict)
    unbounded_ok: dict[str, int] = field(default_factory=dict)

    def add(self, step: Step, truth: np.ndarray, kinds: list[str], names: list[str]) -> None:
        """One step whose pose has a budget, against the true outputs ``truth`` (in the budget's order)."""
        budget = step.pose.budget if step.pose is not None else None
        if budget is None:
            self.refused += 1
            return
        u, half_width = budget.u, budget.half_width
        with np.errstate(invalid="ignore"):   # an infinite reserve (no load) on both sides
            error = budget.values - truth
            valid = np.isfinite(error) & np.isfinite(u)
            covered = np.abs(error) <= half_width + SCALE_TOLERANCE * np.maximum(1.0, np.abs(truth))
        for k in np.flatnonzero(np.isfinite(error) & ~np.isfinite(u)):
            group = KIND_GROUPS.get(kinds[k])
            if group is not None:
                self.groups.setdefault(group, GroupTally()).unbounded += 1
        for k in np.flatnonzero(valid):
            group = KIND_GROUPS.get(kinds[k])
            if group is None:
                continue
            tally = self.groups.setdefault(group, GroupTally())
            tally.steps += 1
            tally.covered += int(covered[k])
            tally.half_width += float(half_width[k])
            tally.squared_error += float(error[k]) ** 2
        index = {name: k for k, name in enumerate(names)}
        for limit in LIMITS:
            row = index.get(limit.output)
            if row is None:
                continue
            if math.isfinite(budget.values[row]) and budget.values[row] >= limit.limit and not math.isfinite(u[row]):
                self.unbounded_value[limit.output] = self.unbounded_value.get(limit.output, 0) + 1
                if not limit.flagged(step):
                    self.unbounded_ok[limit.output] = self.unbounded_ok.get(limit.output, 0) + 1
            if not truth[row] < limit.limit:
                continue
            self.beyond[limit.output] = self.beyond.get(limit.output, 0) + 1
            if not limit.flagged(step):
                self.wrong_with_ok[limit.output] = self.wrong_with_ok.get(limit.output, 0) + 1


def scenario_streams(mech: Mechanism, streams_per_scenario: int) -> list[SimulatedStream]:
    """The simulated streams the runs draw their stretches from: ``streams_per_scenario`` seeds of each
    scenario of ``CANDIDATE_SCENARIOS`` the simulator can run on ``mech``."""
    streams = []
    for scenario in CANDIDATE_SCENARIOS:
        try:
            streams += [simulate(mech, scenario, rate_hz=RATE_HZ, seed=seed, start_ns=START_NS)
                        for seed in range(streams_per_scenario)]
        except (ValueError, LinkageError):
            continue   # a scenario this mechanism cannot run (no tractor, no implement, ground-driven...)
    if not streams:
        raise ValueError(f"{mech.name}: the simulator runs none of {', '.join(CANDIDATE_SCENARIOS)}")
    return streams


def true_inputs(stream: SimulatedStream, start: int, steps: int) -> TrueInputs:
    """The true inputs of samples ``start`` .. ``start + steps`` of ``stream``; a pressure that is 0 gauge
    all along (a chamber at tank) is left out, as a chamber without a sensor is read (at tank)."""
    window = slice(start, start + steps)
    truth = stream.truth
    columns = {"cylinders": dict(zip(stream.cylinder_names, truth.cylinder_lengths[window].T)),
               "angles": dict(zip(stream.angle_names, truth.angles[window].T)),
               "pressures": {n: p for n, p in zip(stream.pressure_names, truth.pressures[window].T) if np.any(p != 0.0)}}
    last = {}
    for name, lengths in zip(stream.cylinder_names, truth.cylinder_lengths[: start + 1].T):
        moves = np.flatnonzero(np.diff(lengths) != 0.0)
        last[name] = float(np.sign(np.diff(lengths)[moves[-1]])) if moves.size else 0.0
    return TrueInputs({kind: {n: np.array(v) for n, v in group.items()} for kind, group in columns.items()}, last)


def run_once(mech: Mechanism, simulator: SensorErrorSimulator, truth: TrueInputs, stamps_ns: np.ndarray,
             rng: np.random.Generator, tally: CoverageTally) -> None:
    """One run: draw its errors (the sensors', the seals' and, where declared, the points': the true
    linkage, ``true_geometry``), feed a fresh monitor the readings sample by sample, tally each step
    against the truth."""
    topics = {f"/pressure/{name}": name for name in truth.values.get("pressures", {})}
    monitor = Monitor(mech, MonitorConfig(mechanism=mech.name, pressure_topics=topics, pressure_absolute=False,
                                          staleness_limit_s=3600.0, stamp_tolerance_s=1e9, uncertainty=True))
    assert monitor.uncertainty is not None
    errors = simulator.draw(rng)
    geometry = draw_geometry(mech, simulator.sources, rng, monitor.machine.solver)
    truth_model = monitor.machine
    if geometry is not None:
        truth = read_on(geometry, truth, monitor.uncertainty.geometry.driving, monitor.uncertainty.geometry.kind)
        truth_model = geometry.model
    readings = simulator.readings(truth, errors, rng)
    table = monitor.uncertainty.table
    kinds, names = [o.kind for o in table.outputs], [o.name for o in table.outputs]
    joint_readings = {**readings["angles"], **readings["cylinders"]}   # one JointState: angles, then lengths
    joints = list(joint_readings)
    joint_values = np.column_stack(list(joint_readings.values()))
    previous = None
    tally.runs += 1
    for i, stamp in enumerate(stamps_ns.tolist()):
        for topic, name in topics.items():
            monitor.on_pressure(topic, float(readings["pressures"][name][i]), stamp, stamp)
        step = monitor.on_joint_state(joints, joint_values[i].tolist(), [], stamp, stamp)
        tally.steps += 1
        try:
            pose = truth_model.solve(truth.at(i), previous)
        except LinkageError:
            tally.untrue += 1
            previous = None
            continue
        previous = pose.result
        tally.add(step, table.values(pose.result, pose.machine), kinds, names)


def window_starts(mech: Mechanism, stream: SimulatedStream, steps: int) -> np.ndarray:
    """The first samples (>= 1) of the stretches of ``steps`` samples of ``stream`` whose true inputs the
    monitor's model solves all along (not, e.g., a single-chamber pressure below vacuum, which no sensor
    reads, or a dead centre of the truth itself)."""
    model = Monitor(mech, MonitorConfig(mechanism=mech.name)).machine
    truth = true_inputs(stream, 0, len(stream))
    solvable = np.zeros(len(stream), dtype=bool)
    for i in range(len(stream)):
        try:
            model.solve(truth.at(i))
        except LinkageError:
            continue
        solvable[i] = True
    bad = np.concatenate([[0], np.cumsum(~solvable)])
    starts = np.arange(1, len(stream) - steps + 1)
    return starts[bad[starts + steps] == bad[starts]]


def study(mech: Mechanism, runs: int, steps: int, rng: np.random.Generator, streams_per_scenario: int = 2
          ) -> CoverageTally:
    """``runs`` runs of ``steps`` samples each of ``mech``, each a random stretch of one of its streams
    (the streams taken in turn) whose truth solves all along (``window_starts``)."""
    simulator = SensorErrorSimulator(mech)
    streams = [(s, window_starts(mech, s, steps)) for s in scenario_streams(mech, streams_per_scenario)]
    streams = [(s, starts) for s, starts in streams if starts.size]
    if not streams:
        raise ValueError(f"{mech.name}: no stretch of {steps} samples of its scenarios solves all along")
    tally = CoverageTally()
    for run in range(runs):
        stream, starts = streams[run % len(streams)]
        start = int(rng.choice(starts))
        run_once(mech, simulator, true_inputs(stream, start, steps), stream.stamps_ns[start: start + steps], rng, tally)
    return tally
