"""Verdicts on the bounds: the machine-level limits judged on the 95 % interval of each value
(docs/accuracy.md), when the configuration asks for it (``MonitorConfig.uncertainty``).

A value beyond its limit is the finding it always was (``steerability_low``, ``lift_reserve_low``,
``axle_lift_off``). A value on the right side of its limit whose 95 % interval (value ± k·u, u the
standard uncertainty of the declared error sources, ``mechanics.uncertainty``, k for a verdict the
factor of its budget's shape that leaves no more than 2.5 % on either side, ``Budget.tail_k`` — with a
moving seal's friction, of known sign, wider than the interval's 95 % in all — taken no smaller than the
normal's 1.96: ``verdict_half_width``) reaches across it
— or whose u is unbounded — is a WARN of its own code (``steerability_uncertain``,
``lift_reserve_uncertain``, ``axle_load_uncertain``) naming the dominant source; the steerability's
also gives the front ballast that clears the limit at the interval's lower bound. Only a value whose
whole interval clears its limit passes. One rule for the live pose (floats) and a replayed segment
(arrays (N,)), as ``checks.pose_checks``. Units SI (N, kg).
"""

from __future__ import annotations

import math
from typing import Mapping, NamedTuple

import numpy as np

from linkage_monitor.mechanics.coverage_factor import NORMAL_FACTOR
from linkage_monitor.mechanics.model import Mechanism
from linkage_monitor.mechanics.results import Result
from linkage_monitor.mechanics.budget import Budget

from .checks import LOAD_AMPLIFICATION_WARN, Check
from .findings import Code, Finding, fmt

# the diagnostic's standard uncertainties (with MonitorConfig.uncertainty): label, budget output, unit
UNCERTAINTY_KEYS = (("implement load", "implement_load", "N"), ("steerability margin", "steerability_margin", "-"),
                    ("front axle load", "front_axle_load", "N"), ("rear axle load", "rear_axle_load", "N"),
                    ("lift reserve", "lift_reserve", "-"))
# A verdict's half-width is at least this many u: the shape's k alone (1.645-1.69 where a seal's friction
# dominates) passed 5 of belarus_1221's 1,261 steps whose true lift reserve is below 1, all of one run
# whose seals held their whole breakaway band (bench/bench_uncertainty_coverage.py, seed 51); the
# normal's factor passes none. It only ever widens: where the shape's k is larger, k holds.
VERDICT_FACTOR_FLOOR = NORMAL_FACTOR


class LimitUncertainties(NamedTuple):
    """The 95 % half-widths (k·u) of the values judged against a limit, for one pose (floats) or N
    poses (arrays (N,)): axle loads N, steerability margin and lift reserve (-); NaN where unbounded."""

    front_axle_load: float | np.ndarray
    rear_axle_load: float | np.ndarray
    margin: float | np.ndarray
    reserve: float | np.ndarray

    @staticmethod
    def of(budget: Budget) -> "LimitUncertainties":
        """The four from a pose's budget (NaN for one the mechanism does not compute), each as
        ``verdict_half_width`` gives it."""
        return LimitUncertainties._make(verdict_half_width(budget, name) for name in _LIMIT_OUTPUTS)


_LIMIT_OUTPUTS = ("front_axle_load", "rear_axle_load", "steerability_margin", "lift_reserve")   # the budget's names


class LimitRows(NamedTuple):
    """The rows of the values judged against a limit in a budget (``Budget.index``), −1 for one the
    mechanism does not compute; ``budget_interval_checks`` takes them, found once per output table."""

    front_axle_load: int
    rear_axle_load: int
    margin: int
    reserve: int

    @staticmethod
    def of(index: Mapping[str, int]) -> "LimitRows":
        """The four's rows in a budget's ``index`` (output name -> row)."""
        return LimitRows._make(index.get(name, -1) for name in _LIMIT_OUTPUTS)


def verdict_half_width(budget: Budget, name: str) -> float:
    """The half-width a verdict judges the output ``name`` on: its tail's factor times u (``Budget.tail_k``),
    no smaller than VERDICT_FACTOR_FLOOR·u (the output's unit; NaN where unbounded or not computed)."""
    k = budget.index.get(name)
    if k is None:
        return math.nan
    return max(float(budget.tail_k[k]), VERDICT_FACTOR_FLOOR) * float(budget.u[k])


_STEER, _RESERVE = int(Check.STEERABILITY_UNCERTAIN), int(Check.LIFT_RESERVE_UNCERTAIN)
_FRONT, _REAR = int(Check.FRONT_AXLE_UNCERTAIN), int(Check.REAR_AXLE_UNCERTAIN)


def straddles(value: float | np.ndarray, half_width: float | np.ndarray, limit: float | np.ndarray) -> np.ndarray:
    """True where a finite ``value`` clears ``limit`` (≥) but its 95 % interval, value ± ``half_width``,
    does not, or the half-width is unbounded (a NaN value fails no check; an infinite one, a reserve
    without load, clears); a 0-d array for one pose (the three broadcast together). The same rule on
    floats: ``budget_interval_checks`` (kept apart: numpy's calls took ten times its time)."""
    with np.errstate(invalid="ignore"):
        bound = np.subtract(value, np.asarray(half_width))
        return np.asarray(np.isfinite(value) & np.greater_equal(value, limit) & ~np.greater_equal(bound, limit))


_LIMITS = np.array([0.0, 0.0, 0.0, 1.0])   # the limits of the four (``LimitUncertainties``' order)
_BITS = np.array([_FRONT, _REAR, _STEER, _RESERVE])
_LIMIT_LIST, _BIT_LIST = _LIMITS.tolist(), _BITS.tolist()   # the same, for one live pose on floats


def interval_checks(front_axle_load: float | np.ndarray, rear_axle_load: float | np.ndarray,
                    margin: float | np.ndarray, reserve: float | np.ndarray, u: LimitUncertainties) -> np.ndarray:
    """The ``Check`` bits of the values whose interval straddles their limit: a 0-d int array for one
    pose, an int array (N,) for N poses (the limits of ``checks.pose_checks``: 0 N, 0, 1); a live pose
    is judged on its budget by ``budget_interval_checks``, the same rule on floats."""
    values = np.array([front_axle_load, rear_axle_load, margin, reserve], dtype=float)   # (4,) or (4, N)
    shape = (4,) + (1,) * (values.ndim - 1)
    crossed = straddles(values, np.array(u, dtype=float), _LIMITS.reshape(shape))
    return np.asarray(np.sum(crossed * _BITS.reshape(shape), axis=0))


def budget_interval_checks(front_axle_load: float, rear_axle_load: float, margin: float, reserve: float,
                           budget: Budget, rows: LimitRows) -> int:
    """``interval_checks`` of a live pose on its budget's half-widths (``verdict_half_width``) in one pass
    over floats, ``rows`` the four's rows of ``budget.index`` (``LimitRows.of``): a half-width is taken only
    for a value that clears its limit. ``straddles``' rule and ``verdict_half_width``'s factor, written out
    on floats (kept apart: numpy's calls and a list of half-widths took ~2.5 µs of the live step's budget
    of ~14 µs, bench_uncertainty_step.py)."""
    u, k = budget.u, budget.tail_k
    bits = 0
    for value, row, limit, bit in zip((front_axle_load, rear_axle_load, margin, reserve), rows, _LIMIT_LIST,
                                      _BIT_LIST):
        if math.isfinite(value) and value >= limit:
            if row < 0:   # not computed: unbounded (NaN), as verdict_half_width gives it
                bits |= bit
                continue
            factor = k.item(row)   # max(factor, floor) by max()'s rule, as verdict_half_width takes it
            if not value - (VERDICT_FACTOR_FLOOR if VERDICT_FACTOR_FLOOR > factor else factor) * u.item(row) >= limit:
                bits |= bit
    return bits


def ballast_at_bound(mech: Mechanism, ratio: float, half_width: float, total_weight: float) -> float:
    """kg of extra front ballast (at the configured ballast's x) after which the 95 % interval of the
    steerability ratio, ``ratio`` ± ``half_width``, clears ratio_min r at its lower bound: the ratio brought
    to t = r + half_width by Popov 2009's moment balance (``kernels.steerability_pose``: R_A grows by
    g·x_cw/L and W by g per kg) — Δm = (t·W − R_A) / (g·(x_cw/L − t·c)), c = 1 for the unit's weight and
    0 for the tractor's, the half-width taken as unchanged by the ballast; 0 when the bound already
    clears, inf where no ballast can."""
    tractor = mech.tractor
    assert tractor is not None
    unit = tractor.steerability_reference == "unit"
    weight = total_weight if unit else tractor.mass * mech.gravity
    x = tractor.front_ballast.x if tractor.front_ballast is not None else tractor.wheelbase
    target = tractor.ratio_min + half_width
    slope = mech.gravity * (x / tractor.wheelbase - target * (1.0 if unit else 0.0))
    shortfall = (target - ratio) * weight
    if shortfall <= 0.0:
        return 0.0
    return shortfall / slope if slope > 0.0 else math.inf


def ballast_at_bound_text(budget: Budget, mech: Mechanism, total_weight: float) -> str:
    """``; N kg of front ballast clear the limit at the 95 % interval's lower bound`` (or why none can)."""
    ratio = budget.line("steerability_ratio")
    ballast = ballast_at_bound(mech, ratio.value, verdict_half_width(budget, "steerability_ratio"), total_weight)
    if not math.isfinite(ballast):
        return "; no front ballast clears the limit at the 95 % interval's lower bound"
    return f"; {fmt(round(ballast))} kg of front ballast clear the limit at the 95 % interval's lower bound"


def _dominant(budget: Budget, output: str) -> str:
    """``source (share)`` of the output's largest share, or why there is none."""
    line = budget.line(output)
    if not math.isfinite(line.u):
        return "unbounded: the pose cannot be solved within the sources' errors"
    return f"dominant source {line.dominant} ({line.shares[line.dominant]:.0%})" if line.dominant else "no source"


def uncertainty_values(budget: Budget) -> dict[str, str]:
    """The diagnostic's key-values of a pose's budget: the standard uncertainty (1 sigma) of each value
    judged against a limit (``nan`` where the mechanism has no such value) and, where it has, its
    dominant source, worded as the findings word it."""
    values = {f"{label} standard uncertainty [{unit}]": fmt(budget.u_of(name)) for label, name, unit in UNCERTAINTY_KEYS}
    values.update({f"{label} uncertainty": _dominant(budget, name) for label, name, _ in UNCERTAINTY_KEYS
                   if name in budget.index})
    return values


def _interval(budget: Budget, output: str, digits: str) -> str:
    line = budget.line(output)
    half_width = verdict_half_width(budget, output)
    return f"{line.value:{digits}} ± {half_width:{digits[1:] if digits.startswith('+') else digits}}"


def uncertain_findings(checks: Check, budget: Budget, mech: Mechanism, total_weight: float) -> list[Finding]:
    """The WARNs of the straddling intervals of one pose, worded with its budget (95 % intervals)."""
    findings = []
    for axle, check in (("front", Check.FRONT_AXLE_UNCERTAIN), ("rear", Check.REAR_AXLE_UNCERTAIN)):
        if check in checks:
            name = f"{axle}_axle_load"
            line = budget.line(name)
            findings.append(Finding(Code.AXLE_LOAD_UNCERTAIN, (
                f"{axle} axle load {fmt(line.value / 1e3)} ± {fmt(verdict_half_width(budget, name) / 1e3)} kN (95 %) may be "
                f"below 0: the machine may tip over its {'rear' if axle == 'front' else 'front'} axle; "
                f"{_dominant(budget, name)}")))
    if Check.STEERABILITY_UNCERTAIN in checks:
        findings.append(Finding(Code.STEERABILITY_UNCERTAIN, (
            f"steerability margin {_interval(budget, 'steerability_margin', '+.3f')} (95 %) reaches below 0: the "
            f"front axle may carry less than ratio_min; {_dominant(budget, 'steerability_margin')}"
            + ballast_at_bound_text(budget, mech, total_weight))))
    if Check.LIFT_RESERVE_UNCERTAIN in checks:
        findings.append(Finding(Code.LIFT_RESERVE_UNCERTAIN, (
            f"lift reserve {_interval(budget, 'lift_reserve', '.2f')} (95 %) reaches below 1: the implement load "
            f"may exceed the lift capacity; {_dominant(budget, 'lift_reserve')}")))
    return findings


def weak_inference_finding(result: Result, budget: Budget | None) -> Finding:
    """The WARN of a pose whose load is inferred from a measured cylinder force with an amplification
    above ``reduced.LOAD_AMPLIFICATION_WARN`` (``Result.load_amplification``): published, with the
    implement load's 95 % interval when the budget is computed."""
    interval = ""
    if budget is not None:
        line = budget.line("implement_load")
        interval = (f" ± {fmt(line.half_width / 1e3)} kN (95 %, {_dominant(budget, 'implement_load')})"
                    if math.isfinite(line.half_width) else " (its 95 % interval unbounded)")
    return Finding(Code.LOAD_INFERENCE_WEAK, (
        f"weak inference: implement load {fmt(result.implement_load / 1e3)} kN{interval} is inferred from the "
        f"measured cylinder force with an amplification of {fmt(result.load_amplification)} N per N "
        f"(> {fmt(LOAD_AMPLIFICATION_WARN)}): its line passes near the pivot of the step that balances it "
        f"(weakest transmission {result.weakest_transmission or '-'}); the linkage holds it, but a small pressure "
        "error is a large load error"))
