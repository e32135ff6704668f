"""The weighing inside the monitor: simulated work cycles of belarus_1221 (``sim.work_cycle``) whose true
implement (1,200 kg, cg 0.2 m behind and 0.1 m below the file's S6) the monitor does not see, fed as
the node feeds it (a FluidPressure and a JointState per sample).

With ``implement_mass_source: estimate_when_confident`` the machine-level results, once the estimate
is confident, are those of a monitor given the true implement; a mass change mid-run puts an
``implement_changed`` WARN on every solved step until a confident estimate is in use again; an
implement file chosen at runtime changes the results without a new Monitor; the live and the
batched paths agree; the replay's summary gives the estimate when it weighed."""

from __future__ import annotations

import dataclasses
import re
from pathlib import Path

import numpy as np
import pytest

from linkage_monitor.mechanics import MechanismFileError, load_preset
from linkage_monitor.mechanics.implements import implement_from_text, implement_names, load_implement, with_implement
from linkage_monitor.monitoring.config import MonitorConfig
from linkage_monitor.monitoring.core import Monitor, Step
from linkage_monitor.monitoring.events import ConfigEvent, InputEvent, JointStateEvent, PressureEvent
from linkage_monitor.monitoring.findings import Code, Level
from linkage_monitor.monitoring.implement_mass import confident
from linkage_monitor.offline.replay import replay_streaming
from linkage_monitor.sim.friction import SealFriction
from linkage_monitor.sim.telemetry import Noise
from linkage_monitor.sim.work_cycle import ImplementTruth, LoadChange, WorkCycle, simulate_work
from linkage_monitor.sim.work_cycle import with_implement as with_truth

BAG = Path(__file__).resolve().parent.parent / "bags" / "belarus_1221_lift_transport"
BELARUS = load_preset("belarus_1221")
REF = np.asarray(BELARUS.implement.cg)
TRUE = ImplementTruth(mass=1200.0, cg=(float(REF[0] + 0.2), float(REF[1] - 0.1)))
CYCLE = WorkCycle(work_s=2.0, transport_s=4.0)   # 13.6 s
NOISE = Noise(angle=0.0005, length=0.0002, pressure=2e4)
TOPIC = "/pressure/lift_cap_pressure"
START_NS = 1_700_000_000_000_000_000
CONFIG = MonitorConfig(mechanism=BELARUS.name, pressure_topics={TOPIC: "lift_cap_pressure"}, pressure_absolute=False,
                       staleness_limit_s=3600.0, stamp_tolerance_s=1e9)
WEIGHED = dataclasses.replace(CONFIG, implement_mass_source="estimate_when_confident")
LIMITS = ("front_axle_load", "rear_axle_load", "margin", "reserve")


def _events(change: LoadChange | None = None, cycles: int = 3) -> list[InputEvent]:
    run = simulate_work(BELARUS, TRUE, duration_s=cycles * CYCLE.period, cycle=CYCLE,
                        friction=SealFriction(share=0.04), road=None, noise=NOISE, change=change, seed=3)
    stream, events = run.stream, []
    for i, stamp in enumerate((stream.stamps_ns + START_NS).tolist()):
        events.append(PressureEvent(TOPIC, float(stream.pressure_values[i, 0]), stamp, stamp))
        events.append(JointStateEvent("joint_states", list(stream.joint_names), stream.joint_positions[i].tolist(),
                                      [], stamp, stamp))
    return events


def _stepped(monitor: Monitor, events: list[InputEvent]) -> list[Step]:
    """The live path: one event at a time."""
    return [monitor.step(e) for e in events]


def _limits(steps: list[Step]) -> np.ndarray:
    """(N, 4): each step's front and rear axle loads (N), steerability margin, lift reserve (NaN unsolved)."""
    return np.array([[s.pose.machine.value(k) if s.pose is not None else np.nan for k in LIMITS] for s in steps])


@pytest.fixture(scope="module")
def events() -> list[InputEvent]:
    return _events()


def test_results_equal_the_true_implements_once_confident(events: list[InputEvent]) -> None:
    weighed = Monitor(BELARUS, WEIGHED)
    steps = _stepped(weighed, events)
    truth = _limits(_stepped(Monitor(with_truth(BELARUS, TRUE), CONFIG), events))
    filed = _limits(_stepped(Monitor(BELARUS, CONFIG), events))
    used = weighed.weighing.in_use
    assert used is not None and confident(used)
    for value, u, true in ((used.mass, used.mass_u, TRUE.mass), (used.cg_x, used.cg_x_u, TRUE.cg[0]),
                           (used.cg_z, used.cg_z_u, TRUE.cg[1])):
        assert abs(value - true) <= 1.96 * u   # the truth within the 95 % interval
    assert weighed.mechanism.implement.mass == pytest.approx(used.mass)
    assert weighed.mechanism.error_sources.implement_mass == pytest.approx(used.mass_u)
    # the last cycle is solved with the estimate in use: its results are the truth's, to a tenth of
    # what the file's cg (0.2 m off along x, 0.1 m along z) makes them miss by
    last = slice(len(events) * 2 // 3, None)
    got = _limits(steps)
    assert np.all(np.isfinite(got[last]))
    assert np.all(np.abs(got[last] - truth[last]) <= 0.1 * np.abs(filed[last] - truth[last]) + 1e-9)
    assert np.abs(filed[last] - truth[last]).max(axis=0)[0] > 50.0   # N: the file's cg does miss


def test_the_batched_path_weighs_as_the_live_one(events: list[InputEvent]) -> None:
    live = _stepped(Monitor(BELARUS, WEIGHED), events)
    batched = Monitor(BELARUS, WEIGHED).run(events).steps
    assert [s.level for s in batched].count(Level.OK) > 0
    # the batched path puts a new estimate in use after its piece (core.WEIGHING_PIECE steps), the live
    # one at once, so they may use estimates of different fits (apart by less than MOVED of their u):
    # over the last cycle, long after both were confident, the loads agree to 0.1 %, the margin to 0.001
    last = slice(len(events) * 2 // 3, None)
    np.testing.assert_allclose(_limits(batched)[last], _limits(live)[last], rtol=1e-3, atol=1e-3)


def test_an_implement_change_warns_until_reweighed() -> None:
    change_at = CYCLE.period + CYCLE.work_s + CYCLE.raise_s + 2.0   # standing in the second transport: +30 %
    events = _events(LoadChange(change_at, 1.3), cycles=4)
    live, batched = Monitor(BELARUS, WEIGHED), Monitor(BELARUS, WEIGHED)
    for monitor, steps in ((live, _stepped(live, events)), (batched, batched.run(events).steps)):
        changed = [i for i, s in enumerate(steps) if any(f.code is Code.IMPLEMENT_CHANGED for f in s.findings)]
        assert changed, "the change was not reported"
        first, last = changed[0], changed[-1]
        stamp = lambda i: (steps[i].stamp_ns - START_NS) * 1e-9   # noqa: E731 - s from the start
        assert change_at < stamp(first) < change_at + CYCLE.period   # found at the next stroke
        # from the finding on, no solved step is OK until the re-weighed mass is in use
        solved = [i for i in range(first, last + 1) if steps[i].pose is not None]
        assert solved == changed[:len(solved)] and all(steps[i].level >= Level.WARN for i in solved)
        assert stamp(last) < change_at + 2 * CYCLE.period   # re-weighed within a cycle after the finding
        assert any(s.level is Level.OK for s in steps[last + 1:])
        used = monitor.weighing.in_use   # the mass in use is the new one
        assert used is not None and abs(used.mass - 1.3 * TRUE.mass) <= 1.96 * used.mass_u


def test_a_runtime_implement_choice_changes_the_results(events: list[InputEvent], tmp_path: Path) -> None:
    heavier_behind = tmp_path / "header_moved.yaml"
    heavier_behind.write_text(f"name: header_moved\nmechanism: belarus_1221\nmass: {TRUE.mass}\n"
                              f"cg: [{TRUE.cg[0]}, {TRUE.cg[1]}]\ntolerances: {{mass: 25.0, cg: [0.05, 0.05]}}\n")
    monitor = Monitor(BELARUS, CONFIG)
    half = len(events) // 2
    before = [monitor.step(e) for e in events[:half]]
    config = monitor.select_implement(str(heavier_behind))
    assert config.implement == str(heavier_behind)
    assert monitor.mechanism.error_sources.implement_mass == 25.0
    after = [monitor.step(e) for e in events[half:]]
    expected = _stepped(Monitor(with_truth(BELARUS, TRUE), CONFIG), events)
    np.testing.assert_allclose(_limits(after)[2:], _limits(expected[half:])[2:], rtol=1e-9)
    assert not np.allclose(_limits(before)[2:], _limits(expected[:half])[2:], rtol=1e-3)
    monitor.select_implement("zhsk4v_header")   # back to the bundled header: the file's values
    assert monitor.mechanism.implement.mass == BELARUS.implement.mass
    # a recorded choice (the configuration the node records) replays through the batched path alike
    replayed = Monitor(BELARUS, CONFIG).run([*events[:half], ConfigEvent(config), *events[half:]]).steps
    np.testing.assert_allclose(_limits(replayed[half:])[2:], _limits(expected[half:])[2:], rtol=1e-9)


def test_the_replay_summary_gives_the_estimate_when_weighed() -> None:
    """The bundled bag carries the preset's header (1,529.57 kg at S6, no seal friction)."""
    weighed = replay_streaming(BAG, progress=None, implement_mass_source="estimate").summary
    estimate = weighed.estimate
    assert weighed.weighed and estimate is not None
    low, high = estimate.interval(estimate.mass, estimate.mass_u)
    assert low <= BELARUS.implement.mass <= high
    assert f"implement weighed: implement mass {estimate.mass:.1f} kg, 95 % interval {low:.1f} .. {high:.1f} kg" \
        in weighed.table()
    plain = replay_streaming(BAG, progress=None).summary   # the recorded source, file: no weighing
    assert not plain.weighed and plain.estimate is None and "implement weighed" not in plain.table()


def test_the_bundled_implements_are_their_presets() -> None:
    assert "zhsk4v_header" in implement_names() and "cultivator_700kg" in implement_names()
    damping = load_preset("damping_hitch")
    for mechanism, name in ((BELARUS, "zhsk4v_header"), (damping, "cultivator_700kg")):
        hung, filed = with_implement(mechanism, load_implement(name)).implement, mechanism.implement
        assert (hung.mass, hung.hitch_point, hung.mast_point) == (filed.mass, filed.hitch_point, filed.mast_point)
        np.testing.assert_array_equal(hung.cg, filed.cg)


@pytest.mark.parametrize(("text", "named"), [
    ("name: x\nmechanism: belarus_1221\ncg: S6\n", "mass: missing"),
    ("name: x\nmechanism: belarus_1221\nmass: -3\ncg: S6\n", "mass: must be ≥ 0"),
    ("name: x\nmechanism: belarus_1221\nmass: 3\ncg: [1.0]\n", "cg: expected [x, z] (m) or a point name"),
    ("name: x\nmechanism: belarus_1221\nmass: 3\ncg: S6\nweight: 3\n", "weight: unknown key"),
    ("name: x\nmechanism: belarus_1221\nmass: 3\ncg: S6\ntolerances: {mass: -1}\n", "tolerances.mass: must be ≥ 0"),
    ("name: x\nmechanism: damping_hitch\nmass: 3\ncg: S6\n", "mechanism: the implement is for 'damping_hitch'"),
    ("name: x\nmechanism: belarus_1221\nmass: 3\ncg: S9\n", "implement.cg: on 'belarus_1221': point 'S9'"),
])
def test_implement_file_errors_are_named(text: str, named: str) -> None:
    with pytest.raises(MechanismFileError, match=re.escape(named)) as err:
        with_implement(BELARUS, implement_from_text(text, "bad.yaml"))
    assert str(err.value).startswith("bad.yaml: ")


def test_a_bad_runtime_choice_changes_nothing() -> None:
    monitor = Monitor(BELARUS, CONFIG)
    with pytest.raises(MechanismFileError, match="no such implement file"):
        monitor.select_implement("no_such_header")
    assert monitor.config.implement == "" and monitor.mechanism.implement == BELARUS.implement


def test_a_mechanism_that_cannot_be_weighed_is_named() -> None:
    mower = load_preset("ksu1_mower_adapter")   # no pressure sensor: nothing to weigh with
    with pytest.raises(MechanismFileError, match="implement_mass_source 'estimate' cannot weigh: weighing needs a "
                                                 "measured cylinder length with a pressure sensor"):
        Monitor(mower, dataclasses.replace(MonitorConfig.default(mower.name, mower), implement_mass_source="estimate"))
