"""The Rerun view: what lands in the .rrd (entities, one sample per solved pose, drawing frame,
arrow scale), the file passes `rerun rrd verify`, and the real viewer renders it (screenshot)."""

from __future__ import annotations

import copy
import subprocess
from pathlib import Path

import numpy as np
import pytest

from linkage_monitor.mechanics import BatchResult, Inputs, Mechanism, Solver, load_preset, mechanism_from_dict
from linkage_monitor.viz.drawing import ARROW_LENGTH, CYLINDER_COLOR
from linkage_monitor.mechanics.reduced import DEAD_CENTRE_TRANSMISSION_DEG
from linkage_monitor.viz.rerun_view import APPLICATION_ID, RerunView, default_blueprint, largest_hinges, linkage_bounds
from linkage_monitor.viz.rerun_view import machine_series as view_series
from support.rerun_shot import RERUN, pixels_of, screenshot
from support.rerun_tables import column, temporal_tables

T0_NS = 1_700_000_000_000_000_000  # an arbitrary ROS header stamp, ns
PERIOD_NS = 20_000_000             # 50 Hz


def belarus_stroke_only() -> Mechanism:
    """belarus_1221 measured by the lift cylinder's stroke alone (its angle sensor dropped), so
    that a stroke sweep is a complete set of inputs."""
    mech = load_preset("belarus_1221")
    raw = copy.deepcopy(dict(mech.raw))
    raw["measurements"].pop("angles")
    raw["reference_inputs"].pop("angles")
    return mechanism_from_dict(raw, file=mech.file)


def machine_series(mech: Mechanism, batch: BatchResult) -> dict[str, np.ndarray]:
    """Stand-ins for the machine-level results the caller passes as ``extra`` (the real ones come
    from the mechanics' machine-level module); only their shape matters to the view.

    Front axle share: moments about the rear wheels' contact of tractor, ballast and implement
    weights / wheelbase / total weight (Popov 2009's steerability); lift reserve: relief force of
    the cylinders (p·A·count·η) / cylinder force.
    """
    t, cyl = mech.tractor, mech.cylinders[0]
    masses = np.array([t.mass, t.front_ballast.mass, mech.implement.mass])
    moment = t.mass * t.cg[0] + t.front_ballast.mass * t.front_ballast.x + mech.implement.mass * batch.implement_cg[:, 0]
    capacity = cyl.relief_pressure * cyl.cap_area * cyl.count * cyl.efficiency
    return {"steerability/ratio": moment / t.wheelbase / masses.sum(),
            "steerability/ratio_min": np.full(len(batch), t.ratio_min),
            "lift/reserve": capacity / batch.cylinder_force[cyl.name]}


def write_batch_rrd(path: Path, strokes: np.ndarray) -> tuple[Mechanism, BatchResult, np.ndarray]:
    """Solve the belarus hitch over ``strokes`` (m) and log it with ``log_batch`` to ``path``."""
    mech = belarus_stroke_only()
    batch = Solver(mech).solve_batch(cylinders={"lift_cylinder": strokes})
    stamps = T0_NS + PERIOD_NS * np.arange(len(strokes), dtype=np.int64)
    solved = np.concatenate([v[np.isfinite(v).all(axis=1)] for v in batch.points.values()])
    view = RerunView.to_file(mech, path, blueprint=default_blueprint(mech, hinges=largest_hinges(batch),
                                                                     extent_xz=solved))
    transmission = view_series({}, {}, batch.transmission_angle, DEAD_CENTRE_TRANSMISSION_DEG)   # the solver's
    view.log_batch(stamps, batch, {**machine_series(mech, batch), **transmission})
    view.close()
    return mech, batch, stamps


@pytest.fixture(scope="module")
def replay(tmp_path_factory):
    """A replay over the working stroke 0.52-0.71 m (Popov 2009, Table 1) with two poses that
    cannot be solved: a NaN stroke (sensor fault) and 2.0 m (out of reach)."""
    strokes = np.linspace(0.52, 0.71, 60)
    strokes[[7, 40]] = [np.nan, 2.0]
    path = tmp_path_factory.mktemp("rerun") / "replay.rrd"
    mech, batch, stamps = write_batch_rrd(path, strokes)
    return path, mech, batch, stamps


def test_replay_has_every_entity_with_one_sample_per_solved_pose(replay):
    path, mech, batch, stamps = replay
    tables = temporal_tables(path)
    solved = int(np.sum(batch.status == 0))
    assert solved == len(batch) - 2  # the two bad poses above, nothing else
    solver_series = ([f"forces/hinges/{h.name}" for h in mech.hinges] + ["forces/cylinders/lift_cylinder",
                      "steerability/ratio", "lift/reserve", "lift/reserve_limit", "transmission/min_angle",
                      "transmission/dead_centre"])
    geometry = ["linkage/links", "linkage/hinges", "linkage/hinges/forces", "linkage/cylinders",
                "linkage/cylinders/forces"]
    for entity in solver_series + geometry:
        assert entity in tables, f"{entity} missing from the .rrd"
        assert sum(rb.num_rows for rb in tables[entity]) == solved, entity
    # a series the caller gives at every pose (a constant limit) keeps every sample
    assert sum(rb.num_rows for rb in tables["steerability/ratio_min"]) == len(batch)
    times = sorted(t for rb in tables["linkage/links"] for t in rb.column("ros_time").cast("int64").to_pylist())
    assert times == list(stamps[batch.status == 0])  # header stamps, not wall time
    status = [row[0] for row in column(tables, "status", "TextLog:text")]
    assert len(status) == 2 and "nan" in status[0] and "cannot assemble" in status[1]
    assert column(tables, "lift/reserve_limit", "Scalars:scalars") == [[1.0]] * solved
    # the smallest transmission angle in degrees (the solver's, in rad: finite on this chain of dyads,
    # in [0, 90]) beside the dead-centre threshold (the default, DEAD_CENTRE_TRANSMISSION_DEG)
    angles = np.array(column(tables, "transmission/min_angle", "Scalars:scalars"))[:, 0]
    np.testing.assert_allclose(angles, np.degrees(batch.transmission_angle[batch.status == 0]), rtol=1e-12)
    assert np.all((angles >= 0.0) & (angles <= 90.0))
    assert column(tables, "transmission/dead_centre", "Scalars:scalars") == [[DEAD_CENTRE_TRANSMISSION_DEG]] * solved


def test_replay_draws_the_solver_points_upright_and_scales_the_largest_force(replay):
    path, mech, batch, _ = replay
    tables = temporal_tables(path)
    ok = np.flatnonzero(batch.status == 0)
    hinges = np.array(column(tables, "linkage/hinges", "Points2D:positions"))        # (poses, H, 2)
    expected = np.stack([batch.points[h.point][ok] for h in mech.hinges], axis=1)
    # drawing frame = (x, -z): Rerun's 2D y points down, the frame's z up
    np.testing.assert_allclose(hinges[..., 0], expected[..., 0], atol=1e-6)
    np.testing.assert_allclose(hinges[..., 1], -expected[..., 1], atol=1e-6)
    hitch, pivot = mech.hinges[[h.name for h in mech.hinges].index("P56")], "P05"
    assert np.all(batch.points[hitch.point][ok, 0] < batch.points[pivot][ok, 0])  # hitch behind: drawn left
    arrows = np.array(column(tables, "linkage/hinges/forces", "Arrows2D:vectors"))
    forces = np.stack([batch.hinge_force[h.name][ok] for h in mech.hinges], axis=1)
    scale = ARROW_LENGTH / max(np.abs(batch.cylinder_force["lift_cylinder"][ok]).max(),
                               np.hypot(forces[..., 0], forces[..., 1]).max())  # the documented rule
    np.testing.assert_allclose(arrows, forces * [1.0, -1.0] * scale, rtol=1e-5, atol=1e-7)
    text = column(tables, "linkage/force_scale", "TextLog:text")[0][0]
    assert f"1 m = {1e-3 / scale:.0f} kN" in text


def test_live_poses_log_one_sample_each(tmp_path):
    mech = belarus_stroke_only()
    solver = Solver(mech)
    strokes = np.linspace(0.55, 0.65, 5)
    view = RerunView.to_file(mech, tmp_path / "live.rrd")
    angles = []
    for k, s in enumerate(strokes):
        result = solver.solve(Inputs(cylinders={"lift_cylinder": float(s)}))
        angles.append(np.degrees(result.transmission_angle))
        view.log_pose(T0_NS + k * PERIOD_NS, result, {"lift/reserve": 1.5, "steerability/ratio": float("nan"),
                                                      **view_series({}, {}, result.transmission_angle, 2.5)})
    view.log_status(T0_NS + 5 * PERIOD_NS, "lift_cylinder: stroke sensor timed out")
    view.close()
    tables = temporal_tables(tmp_path / "live.rrd")
    for entity in ["linkage/links", "linkage/hinges/forces", "forces/hinges/P03", "forces/cylinders/lift_cylinder",
                   "lift/reserve", "lift/reserve_limit", "transmission/min_angle", "transmission/dead_centre"]:
        assert sum(rb.num_rows for rb in tables[entity]) == len(strokes), entity
    # degrees of the solver's transmission angle; the threshold as given (2.5 degrees)
    np.testing.assert_allclose(np.array(column(tables, "transmission/min_angle", "Scalars:scalars"))[:, 0], angles,
                               rtol=1e-12)
    assert column(tables, "transmission/dead_centre", "Scalars:scalars") == [[2.5]] * len(strokes)
    assert "steerability/ratio" not in tables  # NaN samples are skipped
    assert column(tables, "status", "TextLog:text") == [["lift_cylinder: stroke sensor timed out"]]


def test_bad_arguments_say_what_to_pass(tmp_path):
    mech = belarus_stroke_only()
    batch = Solver(mech).solve_batch(cylinders={"lift_cylinder": np.linspace(0.55, 0.6, 3)})
    view = RerunView.to_file(mech, tmp_path / "bad.rrd")
    with pytest.raises(ValueError, match="one header stamp"):
        view.log_batch(np.arange(2), batch)
    with pytest.raises(ValueError, match="one value per pose"):
        view.log_batch(np.arange(3), batch, {"lift/reserve": np.ones(4)})
    with pytest.raises(ValueError, match="without a leading slash"):
        view.log_batch(np.arange(3), batch, {"/lift/reserve": np.ones(3)})
    view.close()


def test_bounds_fit_every_point_and_the_ground():
    mech = belarus_stroke_only()
    pts = np.array(list(mech.points.values()))
    bounds = linkage_bounds(pts, margin=0.1)
    ranges = bounds.range.as_arrow_array().to_pylist()[0]
    (x0, x1), (y0, y1) = ranges["x_range"], ranges["y_range"]
    assert x0 <= pts[:, 0].min() - 0.1 + 1e-9 and x1 >= pts[:, 0].max() + 0.1 - 1e-9
    assert y0 <= -pts[:, 1].max() - 0.1 + 1e-9 and y1 >= 0.1 - 1e-9  # up = -y; ground z = 0 inside


def test_rrd_verify_accepts_the_file(replay):
    out = subprocess.run([str(RERUN), "rrd", "verify", str(replay[0])], capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stdout + out.stderr


@pytest.mark.slow
@pytest.mark.timeout(180)
def test_viewer_screenshot_shows_the_linkage(replay, tmp_path):
    rgb = screenshot(replay[0], tmp_path)
    assert rgb.std() > 10.0  # not a blank window (the viewer chrome alone gives ~26: the check below matters)
    assert pixels_of(rgb, CYLINDER_COLOR) > 500  # the lift cylinder is drawn in the linkage view


@pytest.mark.slow
@pytest.mark.timeout(180)
def test_a_finished_file_opens_on_a_pose_the_viewer_draws(tmp_path):
    """A recording of the live node (belarus_1221 lifting, 82 poses; written under
    test_rerun_live.py) on which Rerun 0.41's viewer, its time cursor following the end of the
    recording as a live viewer's does, draws an empty side view (0 cylinder pixels, every time).
    Opened in the file blueprint (paused, on the first pose) it draws the linkage."""
    fixture = Path(__file__).parent / "fixtures" / "rerun" / "node_lift_following_draws_nothing.rrd"
    blueprint = tmp_path / "file.rbl"
    default_blueprint(load_preset("belarus_1221")).save(APPLICATION_ID, str(blueprint))
    rgb = screenshot(fixture, tmp_path / "viewer", blueprint=blueprint)
    assert pixels_of(rgb, CYLINDER_COLOR) > 500
