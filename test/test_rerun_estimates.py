"""The Rerun view with the error budget and the weighing on (``viz.rerun_estimates``): a replay of the
bundled belarus_1221 lift-and-transport bag with ``uncertainty`` and ``implement_mass_source: estimate``,
its .rrd read back. The 95 % bands are the plotted value ∓ the 95 % half-width of each step's error
budget (``Budget.half_width_of``, k·u; ``mechanics.uncertainty``, on the replay's Steps); the weighed mass is the
steps' estimate; the weighed cg is carried with the implement body to the pose (checked against the
solver's own implement cg: the file's cg carried the same way lands on it); and the real viewer draws it.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from linkage_monitor.mechanics import Solver, load_preset
from linkage_monitor.offline.replay import replay
from linkage_monitor.viz.rerun_estimates import COVERAGE_FACTOR, MASS_COLOR, implement_cg_at
from linkage_monitor.viz.rerun_view import APPLICATION_ID, default_blueprint
from support.rerun_shot import pixels_of, screenshot
from support.rerun_tables import temporal_tables

BAG = Path(__file__).resolve().parent.parent / "bags" / "belarus_1221_lift_transport"


@pytest.fixture(scope="module")
def replayed(tmp_path_factory):
    rrd = tmp_path_factory.mktemp("estimates") / "weighed.rrd"
    done = replay(BAG, rrd=rrd, progress=None, uncertainty=True, implement_mass_source="estimate")
    return rrd, done, temporal_tables(rrd)


def _by_time(tables: dict, entity: str, component: str) -> dict[int, list]:
    rows = [(t, v) for rb in tables[entity]
            for t, v in zip(rb.column("ros_time").cast("int64").to_pylist(), rb.column(component).to_pylist())]
    return dict(rows)


def test_the_bands_are_the_budgets_95_percent_intervals(replayed):
    rrd, done, tables = replayed
    solved = {s.stamp_ns: s for s in done.steps if s.pose is not None and s.pose.budget is not None}
    assert len(solved) > 1000
    value = _by_time(tables, "forces/cylinders/lift_cylinder", "Scalars:scalars")
    for side, sign in (("low95", -1.0), ("high95", 1.0)):
        band = _by_time(tables, f"forces/cylinders/lift_cylinder/{side}", "Scalars:scalars")
        ratio = _by_time(tables, f"steerability/ratio/{side}", "Scalars:scalars")
        assert len(band) > 0.9 * len(solved), side
        for stamp, (v,) in band.items():
            budget = solved[stamp].pose.budget
            # the .rrd holds one sample per stamp: the last step of that stamp (a pressure and a joint state)
            assert v == pytest.approx(value[stamp][0] + sign * budget.half_width_of("lift_cylinder.force") / 1e3,
                                      rel=1e-9)
        for stamp, (v,) in list(ratio.items())[::50]:
            line = solved[stamp].pose.budget.line("steerability_ratio")
            assert v == pytest.approx(line.value + sign * line.half_width, rel=1e-9)
    assert all(b < v[0] for (b,), v in zip(_by_time(tables, "lift/reserve/low95", "Scalars:scalars").values(),
                                           _by_time(tables, "lift/reserve", "Scalars:scalars").values()))


def test_the_weighed_mass_with_its_band_and_its_cg_at_every_estimate(replayed):
    rrd, done, tables = replayed
    weighed = {s.stamp_ns: s.weighing.estimate for s in done.steps
               if s.weighing is not None and s.weighing.estimate is not None}
    assert weighed
    mass = _by_time(tables, "weighing/mass", "Scalars:scalars")
    low = _by_time(tables, "weighing/mass/low95", "Scalars:scalars")
    assert set(mass) == set(weighed) == set(low)
    for stamp, estimate in weighed.items():
        assert mass[stamp][0] == estimate.mass
        assert low[stamp][0] == pytest.approx(estimate.mass - COVERAGE_FACTOR * estimate.mass_u, rel=1e-12)
    centres = _by_time(tables, "linkage/implement_cg", "Points2D:positions")
    boxes = _by_time(tables, "linkage/implement_cg/interval", "Boxes2D:half_sizes")
    assert set(centres) == set(boxes) == set(weighed)
    for stamp, estimate in weighed.items():   # float32 in the .rrd
        np.testing.assert_allclose(boxes[stamp][0], COVERAGE_FACTOR * np.array([estimate.cg_x_u, estimate.cg_z_u]),
                                   rtol=1e-6)


def test_the_cg_carried_to_the_pose_is_the_solvers():
    """The file's cg (reference pose) carried with the implement body over the stroke equals the
    solver's ``implement_cg`` at each pose, to 1e-9 m."""
    mech = load_preset("belarus_1221")
    solver = Solver(mech)
    strokes = np.linspace(0.55, 0.68, 7)
    batch = solver.solve_batch(cylinders={"lift_cylinder": strokes},
                               angles={"lift_arm_angle": _angles(mech, strokes)})
    assert np.all(batch.status == 0)
    carried = implement_cg_at(mech, batch.body_poses[mech.implement.body], np.tile(mech.implement.cg, (7, 1)))
    np.testing.assert_allclose(carried, batch.implement_cg, atol=1e-9)


def _angles(mech, strokes: np.ndarray) -> np.ndarray:
    from support.lift_pose import lift_pose

    return np.array([lift_pose(float(s))[1] for s in strokes])


@pytest.mark.slow
@pytest.mark.timeout(180)
def test_the_viewer_draws_the_weighed_cg(replayed, tmp_path):
    """The real viewer, its time cursor following the end (the live layout, with the mass plot),
    draws the weighed cg's point and box in the side view."""
    rrd, _, _ = replayed
    blueprint = tmp_path / "live.rbl"
    default_blueprint(load_preset("belarus_1221"), live=True, weighing=True).save(APPLICATION_ID, str(blueprint))
    rgb = screenshot(rrd, tmp_path / "viewer", blueprint=blueprint)
    assert pixels_of(rgb, MASS_COLOR) > 100
