"""Geometry tolerances in the error budget (``mechanics.geometry_budget``): the schema's point tolerances,
the tabulated derivatives against a direct central difference (one model of the mechanism per moved
coordinate, solved at the pose), and no geometry source where none is declared."""

from __future__ import annotations

import copy
import dataclasses

import numpy as np
import pytest

from linkage_monitor.mechanics import Inputs, LinkageError, Solver, load_preset
from linkage_monitor.mechanics.error_sources import NONE_DECLARED, PointTolerance
from linkage_monitor.mechanics.errors import MechanismFileError
from linkage_monitor.mechanics.geometry_budget import POINT_STEP, moved_point
from linkage_monitor.mechanics.machine import MachineModel
from linkage_monitor.mechanics.schema import mechanism_from_dict
from linkage_monitor.mechanics.uncertainty import UncertaintyModel
from linkage_monitor.monitoring.core import ASSEMBLY_LIMIT_M
from linkage_monitor.sim.sensor_errors import TrueInputs
from linkage_monitor.sim.true_geometry import draw_geometry, read_on


MECH = load_preset("belarus_1221")


def _declared(block: dict):
    """belarus_1221 with this ``error_sources`` block."""
    return mechanism_from_dict({**copy.deepcopy(dict(MECH.raw)), "error_sources": block}, file=MECH.file)


def _model(mech):
    return MachineModel(mech, Solver(mech, consistency_tol=ASSEMBLY_LIMIT_M))


def test_the_file_declares_point_tolerances() -> None:
    mech = _declared({"point_tolerance": 0.002, "points": {"P03": 0.0005, "P56": {"x": 0.003}}})
    sources = mech.error_sources
    assert sources.point("P03") == PointTolerance(0.0005, 0.0005, "file")
    assert sources.point("P56") == PointTolerance(0.003, 0.0, "file")
    assert (sources.point("P01").x, sources.point("P01").z) == (0.002, 0.002)
    coordinates = sources.point_coordinates(["P56", "P01"])
    assert coordinates == [("P56", 0, 0.003), ("P01", 0, 0.002), ("P01", 1, 0.002)]
    # the default: every coordinate exact (error_sources.DEFAULT_POINT_TOLERANCE)
    assert MECH.error_sources.point_coordinates(MECH.points) == []
    with pytest.raises(MechanismFileError, match="points"):
        _declared({"points": {"P99": 0.001}})
    with pytest.raises(MechanismFileError, match="P03.y"):
        _declared({"points": {"P03": {"y": 0.001}}})


@pytest.mark.parametrize("preset", ["belarus_1221", "ttz1080_base_change", "drill_coulter"])
def test_the_table_gives_the_direct_central_difference(preset: str) -> None:
    """At poses between the table's nodes, each coordinate's contribution from the table is within 1 % of
    the output's u of the one from the moved models solved at the pose (the same step): the linear
    interpolation's error, far inside the 10 % the budget is held to (bench_uncertainty_mc.py)."""
    mech = load_preset(preset)
    model = _model(mech)
    um = UncertaintyModel(model, dataclasses.replace(mech.error_sources, point_tolerance=0.001))
    nodes, held = um.geometry.stroke_inputs()
    rng = np.random.default_rng(5)
    pressures = dict(mech.reference_inputs.get("pressures", {}))
    checked = 0
    for k in rng.choice(np.arange(10, len(nodes) - 10), 3, replace=False).tolist():
        w = float(rng.uniform(0.2, 0.8))
        inputs = Inputs(**{kind: {n: float((1 - w) * v[k] + w * v[k + 1]) for n, v in group.items()}
                           for kind, group in held.items()}, pressures=pressures)
        try:
            pose = model.solve(inputs)
        except LinkageError:   # e.g. a dead centre of the weak inference near ttz1080's pivot O
            continue
        budget = um.budget(inputs, pose.result, pose.machine)
        table = um._linear.chain(budget.values, um.geometry.derivatives(inputs))
        for g, (point, axis, u) in enumerate(um.geometry.coordinates):
            moved = []
            for sign in (1.0, -1.0):
                other = _model(moved_point(mech, point, axis, sign * POINT_STEP))
                solved = other.solve(inputs)   # cold: a warm start takes the same inputs as solved
                moved.append(um.table.values(solved.result, solved.machine))
            direct = um._linear.chain(budget.values, (moved[0] - moved[1]) / (2 * POINT_STEP))
            ok = np.isfinite(budget.u) & (budget.u > 1e-9 * np.maximum(1.0, np.abs(budget.values)))
            share = np.abs(table[g] - direct)[ok] * u / budget.u[ok]
            assert share.max() < 0.01, (point, axis, share.max())
        checked += 1
    assert checked >= 2


def test_no_geometry_source_without_tolerances() -> None:
    """Declared at 0 (the default) the budget has no geometry source: the contributions as without."""
    model = _model(MECH)
    ri = MECH.reference_inputs
    inputs = Inputs(cylinders=dict(ri["cylinders"]), angles=dict(ri["angles"]), pressures=dict(ri["pressures"]))
    pose = model.solve(inputs)
    budget = UncertaintyModel(model).budget(inputs, pose.result, pose.machine)
    assert not any(s.part == "position" for s in budget.sources)
    assert not np.any(UncertaintyModel(model, NONE_DECLARED).budget(inputs, pose.result, pose.machine).u)
    with_points = UncertaintyModel(model, dataclasses.replace(MECH.error_sources, point_tolerance=0.001))
    wider = with_points.budget(inputs, pose.result, pose.machine)
    assert np.all(wider.u >= budget.u) and wider.line("lift_capacity.implement_cg").dominant.endswith("position")


def test_a_linkage_of_more_degrees_of_freedom_is_refused() -> None:
    mech = load_preset("damping_hitch")
    with pytest.raises(MechanismFileError, match="one degree of freedom"):
        UncertaintyModel(_model(mech), dataclasses.replace(mech.error_sources, point_tolerance=0.001))


def test_the_simulated_truth_moves_by_the_table() -> None:
    """The coverage study's true linkage (``sim.true_geometry``: points drawn once per run, the redundant
    angle read off it): the monitor's error at the same readings is the table's first order, −Σ ∂y/∂g·δ
    (0.1 mm tolerances: the RMS of what it misses, the second order, within 1 % of the RMS error over 20
    draws)."""
    sources = dataclasses.replace(NONE_DECLARED, point_tolerance=1e-4)
    model = _model(MECH)
    um = UncertaintyModel(model, sources)
    rng = np.random.default_rng(1)
    predicted, actual = [], []
    for _ in range(20):
        geometry = draw_geometry(MECH, sources, rng, model.solver)
        assert geometry is not None
        truth = read_on(geometry, TrueInputs({"cylinders": {"lift_cylinder": np.array([0.6])},
                                              "angles": {"lift_arm_angle": np.array([0.0])},
                                              "pressures": {"lift_cap_pressure": np.array([1.0e7])}}, {}),
                        "lift_cylinder", "cylinders")
        inputs = truth.at(0)
        true, seen = geometry.model.solve(inputs), model.solve(inputs)
        y = um.table.values(seen.result, seen.machine)
        delta = np.array([geometry.offsets[(point, axis)] for point, axis, _ in um.geometry.coordinates])
        predicted.append(-(um._linear.chain(y, um.geometry.derivatives(inputs)).T @ delta))
        actual.append(y - um.table.values(true.result, true.machine))
    predicted, actual = np.array(predicted), np.array(actual)
    rms = np.sqrt(np.mean(actual**2, axis=0))
    compared = rms > 1e-9 * np.maximum(1.0, np.abs(actual).max(axis=0))
    missed = np.sqrt(np.mean((predicted - actual)[:, compared] ** 2, axis=0))   # the second order's
    assert np.all(missed <= 0.01 * rms[compared])
