"""The cylinder-driven scenarios of the simulator (see ``sim.telemetry``): per sample, the driving
cylinder's length (m), the implement load (N, + = down) and the phase's name; their natural lengths
and the checks that a scenario can run on a mechanism (t in s).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable

import numpy as np

from linkage_monitor.mechanics import Mechanism

from .ground import GROUND_SCENARIOS
from .stream import Stroke

CYLINDER_SCENARIOS = ("lift", "transport", "field", "overload")   # driven by the lift cylinder
SCENARIOS = (*CYLINDER_SCENARIOS, *GROUND_SCENARIOS)


@dataclass(frozen=True)
class Setting:
    """What the scenarios build on: the stroke (m), implement weight W0, largest steerable load
    W_max (NaN without a tractor) and the load that opens the relief valve at transport (N)."""

    stroke: Stroke
    w0: float
    w_max: float
    w_relief: float


@dataclass(frozen=True)
class Profile:
    """A scenario per sample: driving cylinder length (m), implement load (N, + = down), phase name."""

    length: np.ndarray
    load: np.ndarray
    phase: np.ndarray


def _sines(t: np.ndarray, amplitudes: tuple[float, ...], freqs: tuple[float, ...], rng: np.random.Generator) -> np.ndarray:
    phases = rng.uniform(0.0, 2.0 * np.pi, len(freqs))
    return sum(a * np.sin(2.0 * np.pi * f * t + p) for a, f, p in zip(amplitudes, freqs, phases))


LIFT_SEGMENTS = (("work", 2.0), ("raise", 3.6), ("transport", 3.0), ("lower", 4.0))  # s; Popov 2009: lift 3.5-3.8 s


def _lift(t: np.ndarray, setting: Setting, rng: np.random.Generator) -> Profile:
    stroke = setting.stroke
    period = sum(d for _, d in LIFT_SEGMENTS)
    tau = np.mod(t, period)
    raised = np.zeros_like(t)             # share of the way from work (0) to transport (1)
    phase = np.empty(t.shape, dtype=object)
    start = 0.0
    for name, dur in LIFT_SEGMENTS:
        seg = (tau >= start) & (tau < start + dur)
        ramp = 0.5 * (1.0 - np.cos(np.pi * (tau[seg] - start) / dur))   # raised cosine: zero speed at both ends
        raised[seg] = {"work": 0.0, "raise": ramp, "transport": 1.0, "lower": 1.0 - ramp}[name]
        phase[seg] = name
        start += dur
    length = stroke.work + raised * (stroke.transport - stroke.work)
    return Profile(length, np.full(t.shape, setting.w0), phase.astype(str))


def _transport(t: np.ndarray, setting: Setting, rng: np.random.Generator) -> Profile:
    accel_g = _sines(t, (0.15, 0.10, 0.05), (1.1, 2.3, 3.7), rng)   # a/g, |a| <= 0.3 g
    return Profile(np.full(t.shape, setting.stroke.transport), setting.w0 * (1.0 + accel_g),
                    np.full(t.shape, "transport"))


def _field(t: np.ndarray, setting: Setting, rng: np.random.Generator) -> Profile:
    stroke, w0 = setting.stroke, setting.w0
    support = w0 * 0.3 * (1.0 + _sines(t, (0.5, 0.3, 0.2), (0.05, 0.13, 0.31), rng))   # 0-60 % of W0
    draft = _sines(t, (0.5, 0.3, 0.2), (0.08, 0.21, 0.47), rng)                        # relative, |d| <= 1
    travel = min(0.005, 0.25 * (stroke.work - stroke.low), 0.25 * (stroke.high - stroke.work))  # m
    return Profile(stroke.work + travel * draft, w0 - support, np.full(t.shape, "field"))


OVERLOAD_HOLD, OVERLOAD_RAMP, OVERLOAD_END = 2.0, 10.0, 3.0   # s
OVERLOAD_FACTOR = 1.5    # ramp target, × the largest steerable load ...
RELIEF_SHARE = 0.95      # ... but at most this share of the load that opens the relief valve


def _overload(t: np.ndarray, setting: Setting, rng: np.random.Generator) -> Profile:
    w_max = setting.w_max
    w_start = min(setting.w0, 0.75 * w_max)
    w_end = min(OVERLOAD_FACTOR * w_max, RELIEF_SHARE * setting.w_relief)
    load = w_start + np.clip((t - OVERLOAD_HOLD) / OVERLOAD_RAMP, 0.0, 1.0) * (w_end - w_start)
    phase = np.where(t < OVERLOAD_HOLD, "transport", np.where(load > w_max, "overloaded", "loading"))
    return Profile(np.full(t.shape, setting.stroke.transport), load, phase)


CYLINDER_DRIVES: dict[str, tuple[Callable[..., Profile], float]] = {
    "lift": (_lift, sum(d for _, d in LIFT_SEGMENTS)),
    "transport": (_transport, 20.0),
    "field": (_field, 60.0),
    "overload": (_overload, OVERLOAD_HOLD + OVERLOAD_RAMP + OVERLOAD_END),
}


def default_duration(scenario: str) -> float:
    """Natural length of a scenario, s (one lift cycle, 20 s transport, 60 s field, 15 s overload,
    30 s field_copy, 8 s relief)."""
    scenario = check_scenario(scenario)
    return GROUND_SCENARIOS[scenario] if scenario in GROUND_SCENARIOS else CYLINDER_DRIVES[scenario][1]


def check_scenario(scenario: str) -> str:
    if scenario not in SCENARIOS:
        raise ValueError(f"unknown scenario '{scenario}': choose one of {', '.join(SCENARIOS)}")
    return scenario


def check_overload(mech: Mechanism, setting: Setting) -> None:
    """Raise ValueError if the overload scenario cannot drive the steerability margin below zero."""
    if mech.tractor is None:
        raise ValueError(f"{mech.file}: the overload scenario needs the 'tractor' block (steerability)")
    if not (math.isfinite(setting.w_max) and setting.w_max > 0.0):
        raise ValueError(f"{mech.file}: the tractor stays steerable for any implement load (largest steerable "
                         f"load {setting.w_max:.6g} N): the overload scenario cannot overload it")
    if RELIEF_SHARE * setting.w_relief <= setting.w_max:
        raise ValueError(f"{mech.file}: the relief valve limits the implement load ({setting.w_relief:.0f} N) "
                         f"before steerability does ({setting.w_max:.0f} N): the overload scenario cannot "
                         f"make the tractor unsteerable; use transport or lift")

