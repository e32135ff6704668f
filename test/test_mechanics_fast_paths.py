"""The fast paths of the solver: the compiled kernels' small dense linear algebra (oracle:
numpy.linalg), and a live node's single-pose solves that start from the previous pose (oracle:
virtual work)."""

from __future__ import annotations

import sys
from concurrent.futures import ThreadPoolExecutor

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from linkage_monitor.mechanics import Inputs, Mechanism, Solver, load_mechanism, load_preset
from linkage_monitor.mechanics.machine import MachineModel
from linkage_monitor.mechanics.results import Status
from linkage_monitor.mechanics.programs import ROW_SCALARS, ValueRow
from linkage_monitor.mechanics import kernels
from support.fixtures import FIXTURES
from support.statics_oracle import virtual_work

H = 1e-5  # m, finite-difference step in the stroke


@settings(max_examples=60, deadline=None)
@given(k=st.integers(1, 24), m_extra=st.integers(0, 3), seed=st.integers(0, 2**31))
def test_compiled_linear_algebra_matches_numpy(k: int, m_extra: int, seed: int) -> None:
    """The kernels' LU (solve, least squares, 1-norm condition, determinant sign) against numpy.linalg."""
    rng = np.random.default_rng(seed)
    a = rng.standard_normal((k, k)) + 0.5 * k * np.eye(k) * rng.choice([-1.0, 1.0])
    b = rng.standard_normal(k)
    np.testing.assert_allclose(kernels.solve_linear(a, b), np.linalg.solve(a, b), rtol=1e-9, atol=1e-12)
    tall = rng.standard_normal((k + m_extra, k)) + np.eye(k + m_extra, k) * k
    rhs = rng.standard_normal(k + m_extra)
    np.testing.assert_allclose(kernels.solve_linear(tall, rhs), np.linalg.lstsq(tall, rhs, rcond=None)[0],
                               rtol=1e-7, atol=1e-10)
    lu, piv, cond = kernels.factor_and_condition(a)
    np.testing.assert_allclose(cond, np.linalg.cond(a, 1), rtol=1e-9)
    np.testing.assert_allclose(kernels.lu_solve(lu, piv, b), np.linalg.solve(a, b), rtol=1e-9, atol=1e-12)
    assert kernels.det_sign(a) == np.sign(np.linalg.det(a))


def test_compiled_linear_algebra_on_a_singular_matrix() -> None:
    a = np.array([[1.0, 2.0], [0.0, 0.0]])   # an exact zero pivot
    assert kernels.det_sign(a) == 0.0
    assert kernels.factor_and_condition(a)[2] == np.inf
    assert np.isnan(kernels.solve_linear(a, np.array([1.0, 0.0]))).all()   # Newton stops on a non-finite step


def test_live_stroke_from_previous_pose_satisfies_virtual_work() -> None:
    """A node's sequence of single solves (slow stroke, then a jump back) gives the cylinder force
    that virtual work predicts from cold batched kinematics at the same strokes."""
    mech = load_mechanism(FIXTURES / "hitch.yaml")
    live = Solver(mech)
    length0 = live.kin.reference_inputs()[0]
    lengths = length0 + np.concatenate([0.03 * np.sin(np.linspace(0.0, 3.0, 30)), [-0.04, 0.0]])
    forces, previous = [], None
    for x in lengths:   # each solve warm-starts from the previous one, as the node's
        previous = live.solve(Inputs(cylinders={"lift_cylinder": float(x)}), previous=previous)
        forces.append(previous.cylinders["lift_cylinder"].force)
    forces = np.array(forces)
    cold = Solver(mech)
    plus, minus, centre = (cold.solve_batch(cylinders={"lift_cylinder": lengths + d}) for d in (H, -H, 0.0))
    assert np.all(plus.status == 0) and np.all(minus.status == 0)
    # F·dL + Σ load·dp = 0 for a pushing cylinder force F (principle of virtual work)
    expected = -virtual_work(mech, plus, minus, centre, H)
    np.testing.assert_allclose(forces, expected, rtol=1e-6)


def test_warm_start_and_cold_start_give_the_same_pose() -> None:
    """The pose does not depend on where Newton started (the reference pose's assembly branch)."""
    mech = load_mechanism(FIXTURES / "four_bar.yaml")
    solver = Solver(mech)
    length0 = solver.kin.reference_inputs()[0]
    res = None
    for x in length0 * (1.0 + 0.02 * np.sin(np.arange(20))):
        res = solver.solve(Inputs(cylinders={"drive": float(x)}), previous=res)
        cold = solver.solve(Inputs(cylinders={"drive": float(x)}))
        for name, pt in res.points.items():
            np.testing.assert_allclose(pt, cold.points[name], atol=1e-12)



def test_the_same_inputs_again_give_the_pose_before() -> None:
    """A pressure reading between two joint states solves the joint states' inputs again: the live
    path takes the pose before as it is (``kernels._kinematic_pose``; fitting the disagreeing stroke
    and lift-arm angle again takes 3-4 Gauss-Newton steps), still in its one compiled call, and
    gives what the batch path (from the reference pose) gives, the forces of the new pressure."""
    mech = load_preset("belarus_1221")
    solver = Solver(mech)
    model = MachineModel(mech, solver)
    reference = {k: dict(v) for k, v in mech.reference_inputs.items()}
    angles = {n: v + 2e-3 for n, v in reference["angles"].items()}   # rad: the sensors disagree by 2 mrad
    before = model.solve(Inputs(cylinders=reference["cylinders"], angles=angles,
                                pressures={"lift_cap_pressure": 6e6})).result
    again = Inputs(cylinders=reference["cylinders"], angles=angles, pressures={"lift_cap_pressure": 9e6})
    one, _, values = model.solve(again, previous=before)
    assert values is not None   # the live path's one compiled call
    assert before.consistency_residual > 1e-4   # m: a misfit to fit, not readings that agree
    np.testing.assert_array_equal(one.body_q, before.body_q)
    _same_result(one, solver.solve_batch(cylinders=again.cylinders, angles=again.angles,
                                         pressures=again.pressures).result(0), "the same inputs again")
    assert one.cylinders["lift_cylinder"].force > 1.4 * before.cylinders["lift_cylinder"].force


def test_one_solver_in_several_threads_gives_each_pose_its_own_rows() -> None:
    """The live path writes each pose into a row of rows it keeps (``Solver``'s row pool) and the
    Result holds views of it: four threads solving with one Solver, switching threads every
    microsecond, keep the poses a solver of their own gives, read after all have finished."""
    mech = load_preset("belarus_1221")
    shared, own = Solver(mech), Solver(mech)
    reference = {k: dict(v) for k, v in mech.reference_inputs.items()}
    series = [[Inputs(cylinders={n: v * (1.0 + 1e-4 * (k - 2) + 2e-6 * j) for n, v in reference["cylinders"].items()},
                      angles=reference["angles"], pressures={"lift_cap_pressure": 5e6 + 1e4 * j})
               for j in range(150)] for k in range(4)]

    def solve_all(inputs: list[Inputs]) -> list:
        previous, results = None, []
        for x in inputs:
            previous = shared.solve(x, previous=previous)
            results.append(previous)
        return results

    interval = sys.getswitchinterval()
    sys.setswitchinterval(1e-6)
    try:
        with ThreadPoolExecutor(4) as pool:
            solved = list(pool.map(solve_all, series))
    finally:
        sys.setswitchinterval(interval)
    for inputs, results in zip(series, solved):
        previous = None
        for x, got in zip(inputs, results):
            previous = own.solve(x, previous=previous)
            np.testing.assert_array_equal(got.body_q, previous.body_q)
            np.testing.assert_array_equal(got.hinge_force, previous.hinge_force)


def _same_result(a, b, where: str) -> None:
    """Two Results field by field: names equal, numbers to 1e-9 relative (1e-9 N / m absolute)."""
    assert (a.status, a.message) == (b.status, b.message), where
    for field in ("points", "body_poses"):
        assert getattr(a, field).keys() == getattr(b, field).keys()
        for k in getattr(a, field):
            np.testing.assert_allclose(getattr(a, field)[k], getattr(b, field)[k], rtol=1e-9, atol=1e-9,
                                       err_msg=f"{where} {field} {k}")
    for field in ("hinges", "cylinders", "contacts"):
        assert list(getattr(a, field)) == list(getattr(b, field)), where
        for k, x in getattr(a, field).items():
            y = getattr(b, field)[k]
            for name, value in x._asdict().items():
                if isinstance(value, str):
                    assert value == getattr(y, name), (where, field, k, name)
                else:
                    np.testing.assert_allclose(value, getattr(y, name), rtol=1e-9, atol=1e-6,
                                               err_msg=f"{where} {field} {k} {name}")
    assert a.frame_load_points.shape == b.frame_load_points.shape == b.frame_load_forces.shape
    np.testing.assert_allclose(a.frame_load_points, b.frame_load_points, rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(a.frame_load_forces, b.frame_load_forces, rtol=1e-9, atol=1e-6)
    for field in ("implement_load", "implement_cg", "residual", "consistency_residual", "largest_force"):
        np.testing.assert_allclose(getattr(a, field), getattr(b, field), rtol=1e-9, atol=1e-6, err_msg=f"{where} {field}")
    for result in (a, b):   # each its own arrays' largest magnitude, by numpy (0 with no force)
        magnitudes = np.concatenate([np.hypot(result.hinge_force[:, 0], result.hinge_force[:, 1]),
                                     np.abs(result.cylinder_values[:, 1]), [0.0]])
        assert result.largest_force == magnitudes.max(), where


PRESETS = ["belarus_1221", "damping_hitch", "drill_coulter", "ksu1_mower_adapter", "ttz1080_base_change"]
MECHANISMS = PRESETS + [f"fixture:{f}" for f in ("arm_angle", "four_bar", "hitch", "spring_contact")]


def _mechanism(name: str) -> tuple[Mechanism, Solver, MachineModel]:
    """A preset, or ``fixture:<file stem>`` of test/fixtures, with its solver and machine model."""
    mech = load_mechanism(FIXTURES / f"{name[8:]}.yaml") if name.startswith("fixture:") else load_preset(name)
    solver = Solver(mech)
    return mech, solver, MachineModel(mech, solver)


@pytest.mark.parametrize("name", MECHANISMS)
def test_one_pose_path_gives_what_the_batch_path_gives(name: str) -> None:
    """MachineModel.solve takes a usual pose through one compiled call (kernels.live_series, via
    Solver._solve_plain); the same inputs through the general batched path (solve_batch from the
    reference pose, then MachineModel.evaluate_batch) give the same Result and machine-level rows.
    Poses: a live sequence around the reference inputs (warm starts), pressures from 0.3 to 3
    times a reference value, angle readings wrapped by ±2π."""
    mech, solver, model = _mechanism(name)
    kin = solver.kin
    s_ref, nc = kin.reference_inputs(), kin.cyl_att.shape[1]
    rng = np.random.default_rng(11)
    previous, checked = None, 0
    for k in range(40):
        s = s_ref * (1.0 + 0.002 * np.sin(k / 5.0)) if kin.m == kin.n else s_ref.copy()
        s[nc:] += 2.0 * np.pi * rng.integers(-1, 2, s.size - nc)
        inputs = Inputs(cylinders={n: float(v) for n, v in zip(kin.input_names[:nc], s[:nc])},
                        angles={n: float(v) for n, v in zip(kin.input_names[nc:], s[nc:])},
                        pressures={p.name: 5e6 * rng.uniform(0.3, 3.0) for p in mech.measurements.pressures})
        batch = solver.solve_batch(cylinders=inputs.cylinders, angles=inputs.angles, pressures=inputs.pressures)
        plain = solver._solve_plain(inputs, previous.state if previous else None, model.program) is not None
        assert plain == (batch.status[0] == Status.OK), f"{name} pose {k}: {batch.messages[0]}"
        one, machine, values = model.solve(inputs, previous=previous)
        assert (values is not None) == plain
        if values is not None:
            _same_value_row(values, one, machine)
        _same_result(one, batch.result(0), f"{name} pose {k}")
        expected = model.evaluate_batch(batch).result(0)
        assert (machine.steerability_keys, machine.capacity_keys) == (expected.steerability_keys,
                                                                      expected.capacity_keys)
        np.testing.assert_allclose(machine.steerability_row, expected.steerability_row, rtol=1e-9, atol=1e-9)
        np.testing.assert_allclose(machine.capacity_row, expected.capacity_row, rtol=1e-9, atol=1e-9)
        _same_result(solver.solve(inputs, previous=previous), one, f"{name} pose {k}, without the machine")
        previous, checked = one, checked + plain
    assert checked >= 10   # the usual pose is the one-call path's (lifting off takes the general one)


def _same_value_row(values: np.ndarray, result, machine) -> None:
    """A value row holds each part of the pose where ``ValueRow`` says it is."""
    row = ValueRow.of(len(result.hinge_force), len(result.point_xz), len(result.cylinder_values),
                      machine.capacity_row.size, machine.steerability_row.size)
    assert values.shape == (row.width,)
    expected = {"hinge_force": result.hinge_force.ravel(),
                "hinge_magnitude": np.hypot(result.hinge_force[:, 0], result.hinge_force[:, 1]),
                "point_xz": result.point_xz.ravel(), "cylinder_values": result.cylinder_values.ravel(),
                "scalars": np.array([getattr(result, name) for name in ROW_SCALARS]),
                "implement_cg": result.implement_cg, "capacity": machine.capacity_row,
                "steerability": machine.steerability_row}
    for part, value in expected.items():
        start = getattr(row, part)
        np.testing.assert_array_equal(values[start:start + value.size], value, err_msg=part)


def _same_batch(a, b, where: str) -> None:
    """Two BatchResults pose by pose (``_same_result``), statuses and messages equal."""
    assert list(a.status) == list(b.status), where
    assert a.messages == b.messages, where
    for i in range(len(a)):
        if a.status[i] < Status.INPUT:
            _same_result(a.result(i), b.result(i), f"{where} pose {i}")


def _series_inputs(mech, solver) -> tuple[dict, dict, dict]:
    """The series of ``test_series_path_gives_what_the_batch_path_gives``: cylinders, angles, pressures."""
    kin = solver.kin
    s_ref, nc = kin.reference_inputs(), kin.cyl_att.shape[1]
    rng = np.random.default_rng(5)
    n_pose = 60
    scale = 1.0 + 0.003 * np.sin(np.arange(n_pose) / 6.0) if kin.m == kin.n else np.ones(n_pose)
    s = s_ref[None] * scale[:, None]
    s[:, nc:] += 2.0 * np.pi * rng.integers(-1, 2, (n_pose, s.shape[1] - nc))
    s[20, 0] = np.nan                  # a sensor fault
    s[30:33] = 1.8 * s_ref             # out of reach (or off the branch) for three poses, then back
    s[40, nc:] += 3.0                  # an angle reading that jumps
    s[11:14] = s[10]                   # the same inputs again, with other pressures
    cylinders = {n: s[:, j] for j, n in enumerate(kin.input_names[:nc])}
    angles = {n: s[:, nc + j] for j, n in enumerate(kin.input_names[nc:])}
    pressures = {p.name: 5e6 * rng.uniform(0.3, 3.0, n_pose) for p in mech.measurements.pressures}
    return cylinders, angles, pressures


@pytest.mark.parametrize("name", MECHANISMS)
def test_a_series_solved_in_parts_is_the_series_solved_at_once(name: str) -> None:
    """``MachineModel.series`` (the replay: the poses solved part by part as the inputs are read, each
    from the one before across the parts) gives ``solve_series``' answer bit for bit, with parts that
    cut the series before, inside and after its bad inputs, jumps and repeated inputs."""
    mech, solver, model = _mechanism(name)
    cylinders, angles, pressures = _series_inputs(mech, solver)
    whole = model.solve_series(cylinders, angles, pressures)
    parts = model.series()
    for lo, hi in zip((0, 1, 8, 11, 12, 21, 31, 45), (1, 8, 11, 12, 21, 31, 45, 60)):
        parts.add(*({k: v[lo:hi] for k, v in group.items()} for group in (cylinders, angles, pressures)))
    split = parts.finish()
    np.testing.assert_array_equal(split.plain, whole.plain)
    np.testing.assert_array_equal(split.values[whole.plain], whole.values[whole.plain])
    assert split.batch.messages == whole.batch.messages and split.batch.weakest_transmission == whole.batch.weakest_transmission
    for field in ("points", "body_poses", "hinge_force", "cylinder_force", "cap_pressure_measured"):
        for key, column in getattr(whole.batch, field).items():
            np.testing.assert_array_equal(getattr(split.batch, field)[key], column, err_msg=f"{name} {field} {key}")
    for field in ("implement_load", "residual", "consistency_residual", "condition", "status", "transmission_angle"):
        np.testing.assert_array_equal(getattr(split.batch, field), getattr(whole.batch, field), err_msg=f"{name} {field}")
    for group in ("steerability", "lift_capacity"):
        for key, column in getattr(whole.machine, group).items():
            np.testing.assert_array_equal(getattr(split.machine, group)[key], column, err_msg=f"{name} {group} {key}")


@pytest.mark.parametrize("name", MECHANISMS)
def test_series_path_gives_what_the_batch_path_gives(name: str) -> None:
    """MachineModel.solve_series (replay: a recording solved as the live node solves it, each pose
    from the one before, in one compiled call) gives what solve_batch + evaluate_batch give (every
    pose from the reference pose). The series: a slow stroke around the reference inputs with
    pressures from 0.3 to 3 times a reference value and angle readings wrapped by ±2π, and in it a
    NaN reading, inputs far out of reach and a jump back, and inputs repeated with other pressures
    (a pressure reading between two joint states: the pose and its capacities kept, its reserve not)."""
    mech, solver, model = _mechanism(name)
    cylinders, angles, pressures = _series_inputs(mech, solver)
    series, machine, values, plain = model.solve_series(cylinders, angles, pressures)
    batch = solver.solve_batch(cylinders=cylinders, angles=angles, pressures=pressures)
    _same_batch(series, batch, name)
    expected = model.evaluate_batch(batch)
    assert plain.sum() >= 20
    np.testing.assert_allclose(values[plain], model.value_rows(batch.results(), expected.results())[plain], rtol=1e-9,
                               atol=1e-9, err_msg=f"{name} value rows")
    for group in ("steerability", "lift_capacity"):
        assert getattr(machine, group).keys() == getattr(expected, group).keys()
        for key, column in getattr(machine, group).items():
            np.testing.assert_allclose(column, getattr(expected, group)[key], rtol=1e-9, atol=1e-9,
                                       err_msg=f"{name} {group} {key}")
    assert (series.status == Status.OK).sum() >= 20
