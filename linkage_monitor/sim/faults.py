"""Sensor streams with faults, for fuzzing the monitor (the fuzz test and bench/fuzz.py).

A lift cycle of the telemetry simulator, repeated, each JointState / FluidPressure message
kept or damaged the way real sensors and buses fail: NaN/inf and absurd values, readings
outside the plausibility limits, zero or subnormal pressures, a pressure in kPa sent as Pa
(1000x too small), duplicate or unknown joint names, array lengths that differ, stamps at zero,
negative, or far from the clock — and the benign oddities a monitor must take as valid: angles
reported in [0, 2π) or off by ±2π, extra unknown joints, inputs that cannot be assembled (a
valid message whose pose is impossible).
Each message says whether it is malformed (must be refused with an ERROR) and how.
Units SI (m, rad, Pa, ns).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Iterator

import numpy as np

from linkage_monitor.mechanics import Mechanism
from linkage_monitor.mechanics.constants import ATMOSPHERIC_PRESSURE
from linkage_monitor.mechanics.limits import UNIT_SLIP, Limit, input_limits
from linkage_monitor.monitoring.events import JointStateEvent, PressureEvent
from linkage_monitor.sim.telemetry import Noise, simulate

NS = 1_000_000_000
JOINT_FAULTS = ("nan", "inf", "huge", "out_of_range", "duplicate", "unknown_only", "length_mismatch",
                "zero_stamp", "negative_stamp", "future_stamp", "past_stamp", "velocity_nan")
PRESSURE_FAULTS = ("nan", "negative_absolute", "zero", "subnormal", "huge", "kpa_as_pa", "zero_stamp",
                   "future_stamp")
BENIGN = ("angle_plus_2pi", "angle_minus_2pi", "angle_0_2pi", "extra_unknown_joint", "unassemblable")


@dataclass(frozen=True)
class FuzzMessage:
    """One input event and what was done to it: ``malformed`` names the fault ('' when the
    message is valid, ``benign`` names a valid oddity)."""

    event: JointStateEvent | PressureEvent
    malformed: str = ""
    benign: str = ""


def fuzz_stream(mech: Mechanism, count: int, seed: int, fault_rate: float = 0.2, start_ns: int = 1_800_000_000 * NS,
                joint_topic: str = "/joint_states", pressure_prefix: str = "/pressure/") -> Iterator[FuzzMessage]:
    """``count`` messages: the simulator's lift cycle (JointState, then one FluidPressure per
    sensor, absolute Pa), a share ``fault_rate`` of them damaged or oddly valid; receive time =
    header stamp + 1 ms unless the stamp itself is the fault."""
    rng = np.random.default_rng(seed)
    stream = simulate(mech, "lift", rate_hz=50.0, noise=Noise(0.0005, 0.0002, 1e4), seed=seed, start_ns=0)
    angle_columns = [i for i, n in enumerate(stream.joint_names) if n in stream.angle_names]
    limits = input_limits(mech)
    period = int(stream.stamps_ns[-1]) + NS // 50
    made, cycle = 0, 0
    while made < count:
        for i, t in enumerate(stream.stamps_ns.tolist()):
            stamp = start_ns + cycle * period + int(t)
            names = list(stream.joint_names)
            positions = stream.joint_positions[i].astype(float).tolist()
            yield _joint(rng, fault_rate, names, positions, angle_columns, stamp, joint_topic, limits)
            made += 1
            for k, sensor in enumerate(stream.pressure_names):
                if made >= count:
                    return
                absolute = float(stream.pressure_values[i, k]) + ATMOSPHERIC_PRESSURE
                # its own stamp (1 µs after the joints'), so every output names its trigger
                yield _pressure(rng, fault_rate, pressure_prefix + sensor, absolute, stamp + 1000 * (k + 1))
                made += 1
            if made >= count:
                return
        cycle += 1


def _outside(limit: Limit, rng: np.random.Generator) -> float:
    """A reading outside ``limit``: beyond a cylinder's range, or (angles, compared modulo 2π) on
    the far side of the circle from the range's centre."""
    if limit.kind == "angle":
        if limit.hi - limit.lo >= 2.0 * math.pi:   # a full-circle range: only absurd values are outside
            return 10.0 * math.pi * (1 if rng.random() < 0.5 else -1)
        return 0.5 * (limit.lo + limit.hi) + math.pi
    return limit.hi + 0.1 + rng.uniform(0.0, 10.0) if math.isfinite(limit.hi) else -1.0


def _joint(rng: np.random.Generator, rate: float, names: list[str], positions: list[float],
           angle_columns: list[int], stamp: int, topic: str, limits: dict[str, Limit]) -> FuzzMessage:
    receive, velocities, malformed, benign = stamp + 1_000_000, [], "", ""
    if rng.random() < rate:
        kinds = JOINT_FAULTS + BENIGN if angle_columns else JOINT_FAULTS + ("extra_unknown_joint", "unassemblable")
        kind = str(rng.choice(kinds))
        j = int(rng.integers(len(names)))
        a = angle_columns[int(rng.integers(len(angle_columns)))] if angle_columns else j
        if kind == "nan":
            positions[j] = math.nan
        elif kind == "inf":
            positions[j] = math.inf * (1 if rng.random() < 0.5 else -1)
        elif kind == "huge":
            positions[j] = float(10.0 ** rng.uniform(12, 308)) * (1 if rng.random() < 0.5 else -1)
        elif kind == "out_of_range":
            positions[j] = _outside(limits[names[j]], rng)
        elif kind == "duplicate":
            names, positions = names + [names[j]], positions + [positions[j]]
        elif kind == "unknown_only":
            names, positions = ["not_a_joint"], [0.1]
        elif kind == "length_mismatch":
            positions = positions[:-1]
        elif kind == "zero_stamp":
            stamp = 0
        elif kind == "negative_stamp":
            stamp = -int(rng.integers(1, 10**12))
        elif kind == "future_stamp":
            stamp += int(rng.uniform(11, 10**6) * NS)
        elif kind == "past_stamp":
            stamp -= int(rng.uniform(11, 10**6) * NS)
        elif kind == "velocity_nan":
            velocities = [0.0] * len(names)
            velocities[j] = math.nan
        elif kind == "angle_plus_2pi":
            positions[a] += 2 * math.pi
        elif kind == "angle_minus_2pi":
            positions[a] -= 2 * math.pi
        elif kind == "angle_0_2pi":
            positions[a] %= 2 * math.pi
        elif kind == "extra_unknown_joint":
            names, positions = names + ["steering_angle"], positions + [0.3]
        elif kind == "unassemblable":   # inside each limit, but the two inputs contradict each other
            positions[j] += 0.1 if j not in angle_columns else 0.4
        malformed, benign = (kind, "") if kind in JOINT_FAULTS else ("", kind)
    return FuzzMessage(JointStateEvent(topic, names, positions, velocities, stamp, receive), malformed, benign)


def _pressure(rng: np.random.Generator, rate: float, topic: str, absolute: float, stamp: int) -> FuzzMessage:
    receive, malformed = stamp + 1_000_000, ""
    if rng.random() < rate:
        malformed = str(rng.choice(PRESSURE_FAULTS))
        absolute = {"nan": math.nan, "negative_absolute": -abs(absolute), "zero": 0.0, "subnormal": 5e-324,
                    "huge": float(10.0 ** rng.uniform(12, 308)),
                    "kpa_as_pa": absolute * UNIT_SLIP}.get(malformed, absolute)
        if malformed == "zero_stamp":
            stamp = 0
        elif malformed == "future_stamp":
            stamp += int(rng.uniform(11, 10**6) * NS)
    return FuzzMessage(PressureEvent(topic, absolute, stamp, receive), malformed)
