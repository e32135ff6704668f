"""Verdicts on the bounds (monitoring.bounds, ``MonitorConfig.uncertainty``): a limit passes only
when the whole 95 % interval (value ± k·u, k from the budget's shape and at least 1.96:
``bounds.verdict_half_width``) clears it; an interval across it is a WARN of its own
code naming the dominant source; below the limit the finding it always was, with the ballast that
clears it at the interval's bound. The live path (``Monitor.step``) and the replay's (``Monitor.run``)
give the same verdicts and budgets; without the option the verdicts are today's."""

from __future__ import annotations

import warnings
from collections import Counter
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from linkage_monitor.cli.verdict import judge
from linkage_monitor.mechanics import Inputs, Solver, apply_overrides, load_preset
from linkage_monitor.mechanics.error_sources import Motion
from linkage_monitor.mechanics.machine import MachineModel
from linkage_monitor.mechanics.uncertainty import UncertaintyModel
from linkage_monitor.monitoring.motion import MotionTracker
from linkage_monitor.monitoring.bounds import (LimitUncertainties, ballast_at_bound, interval_checks,
                                               VERDICT_FACTOR_FLOOR, uncertain_findings, verdict_half_width)
from linkage_monitor.monitoring.checks import Check
from linkage_monitor.monitoring.core import Monitor
from linkage_monitor.monitoring.events import ConfigEvent
from linkage_monitor.monitoring.findings import Code, Level
from linkage_monitor.offline.fleet import analyse_bag
from linkage_monitor.offline.replay import replay
from linkage_monitor.monitoring.config import MonitorConfig
from linkage_monitor.monitoring.events import JointStateEvent, PressureEvent
from linkage_monitor.sim.telemetry import Noise, simulate
from support.monitor_steps import step_by_step

MECH = load_preset("belarus_1221")


def _judged(pressure: float, uncertainty: bool = True):
    ri = MECH.reference_inputs
    inputs = Inputs(cylinders=dict(ri["cylinders"]), angles=dict(ri["angles"]),
                    pressures={"lift_cap_pressure": pressure})
    return judge(MECH, MECH.name, inputs, uncertainty=uncertainty)


def test_a_margin_whose_interval_clears_zero_is_ok() -> None:
    step = _judged(10.132e6)   # Popov 2009's working pose: margin 0.055, u 0.0043
    margin = step.pose.budget.line("steerability_margin")
    assert margin.value - verdict_half_width(step.pose.budget, "steerability_margin") > 0.0
    assert step.level is Level.OK


def test_a_margin_whose_interval_straddles_zero_warns_naming_the_source() -> None:
    step = _judged(13.6e6)
    margin = step.pose.budget.line("steerability_margin")
    assert 0.0 < margin.value < verdict_half_width(step.pose.budget, "steerability_margin")
    codes = [f.code for f in step.findings]
    assert codes == [Code.STEERABILITY_UNCERTAIN]
    text = step.findings[0].text
    assert "lift_cylinder seal friction" in text and "95 %" in text and "lower bound" in text
    # without the option, today's verdict: OK
    assert _judged(13.6e6, uncertainty=False).level is Level.OK


def test_below_the_limit_is_todays_finding_with_the_ballast_at_the_bound() -> None:
    step = _judged(14.5e6)
    assert [f.code for f in step.findings] == [Code.STEERABILITY_LOW]
    assert "lower bound" in step.findings[0].text
    assert _judged(14.5e6, uncertainty=False).findings[0].text in step.findings[0].text


def test_the_ballast_at_the_bound_brings_the_lower_bound_to_ratio_min() -> None:
    """Closed form: the ballast Δm added to the file's front ballast, the same pose re-solved: its ratio
    minus the old 95 % half-width is ratio_min (Popov 2009's moment balance is exact in Δm)."""
    step = _judged(14.5e6)
    ratio = step.pose.budget.line("steerability_ratio")
    half_width = verdict_half_width(step.pose.budget, "steerability_ratio")
    total = step.pose.machine.value("total_weight")
    mass = ballast_at_bound(MECH, ratio.value, half_width, total)
    heavier = apply_overrides(MECH, {"tractor.front_ballast.mass": MECH.tractor.front_ballast.mass + mass})
    again = MachineModel(heavier, Solver(heavier)).solve(step.inputs)
    assert again.machine.value("ratio") - half_width == pytest.approx(MECH.tractor.ratio_min, abs=1e-12)


def _overload_events():
    """The simulator's overload of belarus_1221 (a load ramp from 15 kN to 30.7 kN at the transport
    pose: the margin and the reserve cross their limits), noisy, the implement mass changed half-way
    (a new configuration segment)."""
    stream = simulate(MECH, "overload", rate_hz=20.0, noise=Noise(0.001, 0.0002, 2e4), seed=5,
                      start_ns=1_700_000_000_000_000_000)
    topic = "/pressure/lift_cap_pressure"
    config = MonitorConfig(mechanism=MECH.name, pressure_topics={topic: "lift_cap_pressure"}, pressure_absolute=False,
                           staleness_limit_s=3600.0, stamp_tolerance_s=1e9, uncertainty=True)
    names = list(stream.joint_names)
    events: list = []
    for i, stamp in enumerate(stream.stamps_ns.tolist()):
        if i == len(stream) // 2:
            events.append(ConfigEvent(config.with_overrides({"implement.mass": 1600.0})))
        events.append(PressureEvent(topic, float(stream.pressure_values[i, 0]), stamp, stamp))
        events.append(JointStateEvent("joint_states", names, stream.joint_positions[i].tolist(), [], stamp, stamp))
    return config, events


def test_live_and_replay_give_the_same_verdicts_and_budgets() -> None:
    config, events = _overload_events()
    stepped = step_by_step(MECH, config, events)
    run = Monitor(MECH, config).run(events)
    fired = Counter(f.code for s in stepped for f in s.findings)
    for code in (Code.STEERABILITY_UNCERTAIN, Code.LIFT_RESERVE_UNCERTAIN, Code.STEERABILITY_LOW):
        assert fired[code] > 0, (code, fired)
    assert len(run.steps) == len(stepped)
    for one, batched in zip(stepped, run.steps):
        assert [(f.code, f.text) for f in one.findings] == [(f.code, f.text) for f in batched.findings]
        assert (one.pose is None) == (batched.pose is None)
        if one.pose is not None:
            assert one.pose.budget.motions == batched.pose.budget.motions
            np.testing.assert_allclose(batched.pose.budget.u, one.pose.budget.u, rtol=1e-6, atol=1e-9)


def test_the_cylinder_moves_beyond_its_deadband() -> None:
    tracker = MotionTracker.of(MECH, MECH.error_sources)
    # default stroke sensor: 1 mm steps, u = 0.29 mm: a change of 3·√2·0.29 mm = 1.2 mm is motion
    assert tracker.deadband["lift_cylinder"] == pytest.approx(3 * np.sqrt(2) * 1e-3 / np.sqrt(12))
    ms = 1_000_000

    def motion(length: float, stamp_ms: int) -> Motion:
        return tracker.motions(Inputs(cylinders={"lift_cylinder": length}), stamp_ms * ms)["lift_cylinder"]

    assert motion(0.535, 0) is Motion.STANDING   # the first reading
    assert motion(0.5355, 20) is Motion.STANDING
    assert motion(0.540, 40) is Motion.LIFTING
    assert motion(0.530, 60) is Motion.LOWERING   # against 0.535 at 0 ms, within the window


def test_a_slow_rod_moves_over_the_window() -> None:
    """A rod at 20 mm/s read by 1 mm steps at 50 Hz changes by 0 or 1 mm a reading (within the 1.2 mm
    deadband) but 2 mm over the 0.1 s window: lifting, once the window holds that travel; a stop reads
    standing once the window's change is back within the deadband."""
    tracker = MotionTracker.of(MECH, MECH.error_sources)
    stamps = np.arange(40) * 20_000_000   # 50 Hz
    true = 0.535 + np.minimum(np.arange(40), 20) * 0.020 * 0.020   # 20 mm/s for 20 readings, then stands
    read = np.round(true / 1e-3) * 1e-3
    motions = [tracker.motions(Inputs(cylinders={"lift_cylinder": float(x)}), int(t))["lift_cylinder"]
               for x, t in zip(read, stamps)]
    assert all(abs(d) < tracker.deadband["lift_cylinder"] for d in np.diff(read))   # no reading to the next
    assert motions[0] is Motion.STANDING and set(motions[5:20]) == {Motion.LIFTING}
    assert set(motions[26:]) == {Motion.STANDING}   # 0.1 s (5 readings) and one step after the stop


@pytest.mark.slow
def test_a_bag_recorded_without_it_replays_with_the_default_sources() -> None:
    """The bundled overload bag (recorded without the option): replayed with it, the steps below a
    limit are the same as the recording's verdicts, and some of those above it become uncertain."""
    bag = Path(__file__).resolve().parent.parent / "bags" / "belarus_1221_overload"
    plain = replay(bag, progress=None).summary.kinds
    bounded = replay(bag, progress=None, uncertainty=True)
    kinds = bounded.summary.kinds
    assert bounded.config.uncertainty and any("95 %" in note for note in bounded.summary.notes)
    for code in ("steerability_low", "lift_reserve_low", "sensors_disagree"):
        assert kinds[("WARN", code)] == plain[("WARN", code)] > 0, code
    assert kinds[("WARN", "steerability_uncertain")] > 0 and kinds[("WARN", "lift_reserve_uncertain")] > 0
    assert ("WARN", "steerability_uncertain") not in plain


@pytest.mark.slow
def test_the_fleet_row_gives_the_time_uncertain() -> None:
    """``analyse_bag`` of the bundled overload bag: with the budget the time below each limit is the
    same, and the time uncertain is the time its interval straddles the limit (walked pose by pose
    from the replay's steps: each pose holds until the next)."""
    bag = Path(__file__).resolve().parent.parent / "bags" / "belarus_1221_overload"
    plain, bounded = analyse_bag(bag).row, analyse_bag(bag, uncertainty=True).row
    assert "uncertain_margin_s" not in plain
    assert bounded["below_margin_s"] == plain["below_margin_s"] > 0
    assert bounded["below_reserve_s"] == plain["below_reserve_s"] > 0
    steps = [s for s in replay(bag, progress=None, uncertainty=True).steps if s.pose is not None]
    stamps = np.array([s.stamp_ns for s in steps], dtype=np.int64)
    t = (stamps - stamps[0]) * 1e-9
    straddling = np.array([any(f.code is Code.STEERABILITY_UNCERTAIN for f in s.findings) for s in steps])
    assert bounded["uncertain_margin_s"] == pytest.approx(float(np.sum(np.diff(t)[straddling[:-1]])), rel=1e-9)
    assert bounded["uncertain_margin_s"] > 0 and bounded["uncertain_reserve_s"] > 0


def test_the_interval_rule_one_pose_and_many_alike() -> None:
    """``interval_checks``: a value clearing its limit by less than its half-width (here 1.96 u), or of
    unbounded u, straddles;
    one clearing by more, one beyond the limit (its own finding), NaN (not computed) and an infinite
    reserve (no load) do not; a pose's floats and a segment's arrays give the same bits."""
    margin = np.array([0.05, 0.005, -0.01, np.nan, 0.05])
    u_margin = np.array([0.004, 0.004, 0.004, 0.004, np.nan])
    reserve = np.array([1.5, 1.01, np.inf, 0.9, 1.2])
    u_reserve = np.array([0.04, 0.04, np.nan, 0.04, 0.01])
    axle = np.array([1e4, 50.0, 1e4, -5.0, 1e4])
    u_axle = np.array([100.0, 100.0, 100.0, 100.0, 100.0])
    u = LimitUncertainties(*(1.96 * a for a in (u_axle, u_axle, u_margin, u_reserve)))   # 95 % half-widths
    bits = interval_checks(axle, axle, margin, reserve, u)
    steer, res = int(Check.STEERABILITY_UNCERTAIN), int(Check.LIFT_RESERVE_UNCERTAIN)
    front, rear = int(Check.FRONT_AXLE_UNCERTAIN), int(Check.REAR_AXLE_UNCERTAIN)
    assert bits.tolist() == [0, steer + res + front + rear, 0, 0, steer]
    one = [int(interval_checks(axle[k], axle[k], margin[k], reserve[k], LimitUncertainties(*(a[k] for a in u))))
           for k in range(len(margin))]
    assert one == bits.tolist()


def test_an_axle_load_whose_interval_reaches_below_zero_names_the_machine_tipping() -> None:
    step = _judged(10.132e6)
    findings = uncertain_findings(Check.REAR_AXLE_UNCERTAIN, step.pose.budget, MECH,
                                  step.pose.machine.value("total_weight"))
    assert [f.code for f in findings] == [Code.AXLE_LOAD_UNCERTAIN]
    assert "rear axle load" in findings[0].text and "tip over its front axle" in findings[0].text
    assert "dominant source lift_cylinder seal friction" in findings[0].text


def test_an_infinite_uncertainty_reads_as_unbounded() -> None:
    """A contribution that is infinite (the lift reserve where a moved pose's lift capacity is infinite,
    near ttz1080_base_change's pivot O) is an unbounded u, as a NaN one is: no share, no dominant source,
    no half-width, and the verdict on it straddles (WARN, never OK); read without a RuntimeWarning."""
    step = _judged(10.132e6)
    contributions = step.pose.budget.contributions.copy()
    row = step.pose.budget.index["lift_reserve"]
    contributions[row, 0] = -np.inf
    budget = replace(step.pose.budget, contributions=contributions)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        line = budget.line("lift_reserve")
        assert np.isnan(line.u) and np.isnan(line.half_width) and np.isnan(budget.half_width_of("lift_reserve"))
        assert set(line.shares.values()) == {0.0} and line.dominant == ""
        limits = LimitUncertainties.of(budget)
        assert np.isnan(limits.reserve) and np.isfinite(limits.margin)
        bits = int(interval_checks(budget.line("front_axle_load").value, budget.line("rear_axle_load").value,
                                   budget.line("steerability_margin").value, line.value, limits))
        assert bits == int(Check.LIFT_RESERVE_UNCERTAIN)   # the reserve's interval unbounded: it straddles
        findings = uncertain_findings(Check.LIFT_RESERVE_UNCERTAIN, budget, MECH, step.pose.machine.value("total_weight"))
        assert [f.code for f in findings] == [Code.LIFT_RESERVE_UNCERTAIN] and "unbounded" in findings[0].text
    assert budget.line("implement_load").u == step.pose.budget.line("implement_load").u   # the other rows as they were


def test_a_verdict_judges_each_tail_where_a_moving_seals_friction_shifts_the_error() -> None:
    """Lifting, the seal's friction has a known sign: the 95 % interval (k) holds 95 % of the error in all,
    one tail up to 5 %; a verdict's bound (``Budget.tail_k``, at least 1.96) leaves no more than 2.5 % on
    either side (test_coverage_factor.py), so it is wider. Standing, the two are one factor."""
    ri = MECH.reference_inputs
    inputs = Inputs(cylinders=dict(ri["cylinders"]), angles=dict(ri["angles"]),
                    pressures={"lift_cap_pressure": 10.132e6})
    model = MachineModel(MECH, Solver(MECH))
    pose = model.solve(inputs)
    budgets = {motion: UncertaintyModel(model).budget(inputs, pose.result, pose.machine, motion)
               for motion in (Motion.LIFTING, Motion.STANDING)}
    lifting, standing = budgets[Motion.LIFTING], budgets[Motion.STANDING]
    np.testing.assert_array_equal(standing.tail_k, standing.k)
    i = lifting.index["implement_load"]
    assert lifting.tail_k[i] > lifting.k[i] + 0.05   # the friction a large share of the load's u
    for name in ("steerability_margin", "implement_load"):
        i = lifting.index[name]
        assert verdict_half_width(lifting, name) == pytest.approx(max(lifting.tail_k[i], VERDICT_FACTOR_FLOOR)
                                                                   * lifting.u[i], rel=1e-12)
        assert verdict_half_width(lifting, name) >= lifting.half_width[i]
