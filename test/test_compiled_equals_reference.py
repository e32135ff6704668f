"""The compiled solver (mechanics.kernels behind Solver) equals the frozen numpy solver
(oracles.numpy_solver, the same formulation as whole-array numpy code) to 1e-9 on every preset and test
fixture: batched poses scattered around the reference inputs (many fail: off the branch, out of
reach, NaN), a live sequence of warm-started single solves, kinetostatics from rates, springs and
ground contacts, and the dead-centre and cannot-assemble verdicts of the failure fixtures.
"""

from __future__ import annotations

import math
import re

import numpy as np
import pytest

from linkage_monitor.mechanics import (Inputs, LinkageError, Mechanism, Solver, load_mechanism, load_preset,
                                       mechanism_from_dict, preset_names)
from linkage_monitor.mechanics.capacity import stroke_mechanism
from linkage_monitor.mechanics.results import BatchResult, angle_readings
from oracles.numpy_solver import Solver as NumpySolver
from support.arm_mechanism import arm_mechanism
from support.fixtures import FIXTURES

REL = 1e-9
MECHANISMS = [("preset", n) for n in preset_names()] + [("fixture", p.name) for p in sorted(FIXTURES.glob("*.yaml"))]


def _load(kind: str, name: str) -> Mechanism:
    return load_preset(name) if kind == "preset" else load_mechanism(FIXTURES / name)


def _scattered_inputs(mech: Mechanism, n: int, seed: int, rates: bool) -> dict[str, dict[str, np.ndarray]]:
    """Inputs around the reference pose: lengths ±12 %, angles ±0.4 rad (some wrapped by 2π),
    pressures 0.3–1.7×; a few NaN. Far ones fail to assemble or leave the branch."""
    rng = np.random.default_rng(seed)
    kin = Solver(mech).kin
    nc = kin.cyl_att.shape[1]
    reference = dict(zip(kin.input_names, kin.reference_inputs()))
    out: dict[str, dict[str, np.ndarray]] = {"cylinders": {}, "angles": {}, "pressures": {}}
    for name in kin.input_names[:nc]:
        out["cylinders"][name] = reference[name] * rng.uniform(0.88, 1.12, n)
    wraps = 2 * math.pi * rng.integers(-1, 2, n)
    if kin.m > kin.n:   # redundant: the angles the strokes give, ±5 mrad
        solved = NumpySolver(stroke_mechanism(mech)).solve_batch(cylinders=out["cylinders"])
        for name, v in angle_readings(mech, solved).items():
            out["angles"][name] = np.where(np.isfinite(v), v, reference[name]) + rng.normal(0, 0.005, n) + wraps
    else:
        for name in kin.input_names[nc:]:
            out["angles"][name] = reference[name] + rng.uniform(-0.4, 0.4, n) + wraps
    given = mech.reference_inputs.get("pressures", {})
    for sensor in mech.measurements.pressures:
        out["pressures"][sensor.name] = given.get(sensor.name, 5e6) * rng.uniform(0.3, 1.7, n)
    first = next(iter(out["cylinders"].values())) if out["cylinders"] else next(iter(out["angles"].values()))
    first[:3] = np.nan
    if rates:
        names = list(out["cylinders"]) + list(out["angles"])
        out["rates"] = {k: rng.normal(0.0, 0.3, n) for k in names}
        out["accelerations"] = {k: rng.normal(0.0, 1.0, n) for k in names}
    return out


def assert_batches_equal(got: BatchResult, expected: BatchResult) -> None:
    """Verdicts and messages exactly; every number to REL of its field's scale (NaN where NaN)."""
    np.testing.assert_array_equal(got.status, expected.status)
    assert [_tie_free(m) for m in got.messages] == [_tie_free(m) for m in expected.messages]
    fields = ["points", "body_poses", "hinge_force", "cylinder_length", "cylinder_force", "contact_normal"]
    for name in fields:
        for key, value in getattr(expected, name).items():
            _close(getattr(got, name)[key], value, f"{name}[{key}]")
    for name in ("implement_load", "frame_load_forces", "residual", "consistency_residual", "largest_force"):
        _close(getattr(got, name), getattr(expected, name), name)
    # the condition number: the oracle's is the larger of the kinematic and the equilibrium matrix's;
    # where the reduced path serves a pose (a transmission angle) there is no equilibrium matrix
    general = (expected.status < 2) & np.isnan(got.transmission_angle)
    _close(got.condition[general], expected.condition[general], "condition", rel=1e-6)


def _tie_free(message: str) -> str:
    """The message without what round-off decides: the name of the most-open constraint (a pose can
    leave two rows open by the same amount, a hinge gap and a cylinder length equal to 0.1 mm; the
    amount is still compared), and the figure of a dead centre's condition number — at an exact
    dead centre (the arm fixture's cylinder at 2.0 m) it is that of a singular matrix, 1e7 or 1e16
    depending on where Newton stopped within 1e-13 m (the verdict, the inputs and the limit are
    still compared)."""
    message = re.sub(r"at best .*? is off by", "at best (a constraint) is off by", message)
    message = re.sub(r"condition number \S+ >", "condition number (above the limit) >", message)
    # a dead centre's reason: the oracle has only the condition numbers (the kinematic one, then the
    # equilibrium matrix's), the reduced path names the transmission it lost, kinematic or static
    # (test_reduced_coordinates holds that verdict)
    return re.sub(r"(?:kinematic |static )?dead centre at ([^:]*):.*", r"dead centre at \1: (the reason)", message)


def _close(got: np.ndarray, expected: np.ndarray, what: str, rel: float = REL) -> None:
    scale = max(float(np.nanmax(np.abs(expected), initial=0.0)), 1.0)
    np.testing.assert_allclose(got, expected, rtol=rel, atol=rel * scale, equal_nan=True, err_msg=what)


@pytest.mark.parametrize("kind,name", MECHANISMS)
def test_batched_poses_equal_the_numpy_solver(kind: str, name: str) -> None:
    mech = _load(kind, name)
    rates = any(b.mass > 0.0 for b in mech.moving_bodies)   # kinetostatics wherever there is inertia
    inputs = _scattered_inputs(mech, 60, seed=len(name), rates=rates)
    got = Solver(mech).solve_batch(**inputs)
    expected = NumpySolver(mech).solve_batch(**inputs)
    assert (got.status == 0).sum() >= 10, "the scatter should solve most poses"
    assert_batches_equal(got, expected)


@pytest.mark.parametrize("kind,name", MECHANISMS)
def test_live_sequence_equals_the_numpy_solver(kind: str, name: str) -> None:
    """Warm-started single solves along a slow sweep with glitches (the node's path): same pose,
    forces and verdicts as the numpy solver warm-started the same way."""
    mech = _load(kind, name)
    inputs = _scattered_inputs(mech, 40, seed=7, rates=False)
    compiled, numpy_solver = Solver(mech), NumpySolver(mech)
    prev_c = prev_n = None
    for i in range(40):
        one = Inputs(**{kind_: {k: float(v[i]) for k, v in group.items()} for kind_, group in inputs.items()})
        try:
            expected = numpy_solver.solve(one, previous=prev_n)
        except LinkageError as exc:
            with pytest.raises(type(exc)) as raised:
                compiled.solve(one, previous=prev_c)
            assert _tie_free(str(raised.value)) == _tie_free(str(exc))
            prev_c = prev_n = None
            continue
        got = compiled.solve(one, previous=prev_c)
        assert got.status == expected.status
        for h in expected.hinges:
            assert got.hinges[h].fx == pytest.approx(expected.hinges[h].fx, rel=REL, abs=1e-6)
            assert got.hinges[h].fz == pytest.approx(expected.hinges[h].fz, rel=REL, abs=1e-6)
        assert got.implement_load == pytest.approx(expected.implement_load, rel=REL, nan_ok=True)
        prev_c, prev_n = got, expected


@pytest.mark.parametrize("measure,key,values", [
    ({"cylinders": ["cyl"]}, "cylinders", [math.sqrt(2.0), 2.0, 2.1, 1.5, 0.05]),          # dead centre, out of reach
    ({"angles": [{"name": "arm_angle", "hinge": "O"}]}, "angles", [-math.pi / 4, -math.pi / 2, 0.3, 2 * math.pi - 0.3]),
])
def test_failure_verdicts_equal_the_numpy_solver(measure: dict, key: str, values: list[float]) -> None:
    """Kinematic and static dead centres and cannot-assemble (support.arm_mechanism's arm)."""
    mech = mechanism_from_dict(arm_mechanism(measure))
    name = measure[key][0] if key == "cylinders" else measure[key][0]["name"]
    got = Solver(mech).solve_batch(**{key: {name: np.array(values)}})
    expected = NumpySolver(mech).solve_batch(**{key: {name: np.array(values)}})
    assert set(expected.status) - {0}, "the cases should include failures"
    assert_batches_equal(got, expected)
