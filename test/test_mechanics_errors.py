"""Every failure kind: unassemblable (by how much), dead centre, unobservable, bad YAML naming
file + key, NaN / unknown inputs, negative absolute pressure; and overrides."""

from __future__ import annotations

import math

import numpy as np
import pytest

from linkage_monitor.mechanics import (AssemblyError, DeadCentreError, InputError, Inputs, MechanismFileError,
                                       Solver, UnobservableError, apply_overrides, load_mechanism, mechanism_from_dict)
from support.arm_mechanism import arm_mechanism
from support.fixtures import FIXTURES


def test_unassemblable_says_by_how_much() -> None:
    solver = Solver(mechanism_from_dict(arm_mechanism({"cylinders": ["cyl"]})))
    # longest possible cylinder: |EO| + |OT| = 2 m, so 2.1 m misses by 100 mm (triangle inequality)
    with pytest.raises(AssemblyError, match=r"cyl.*100\.0 mm"):
        solver.solve(Inputs(cylinders={"cyl": 2.1}))
    batch = solver.solve_batch(cylinders={"cyl": np.array([math.sqrt(2.0), 2.1])})
    assert list(batch.status) == [0, 3] and "100.0 mm" in batch.messages[1]
    assert np.isnan(batch.cylinder_force["cyl"][1]) and np.isfinite(batch.cylinder_force["cyl"][0])
    # a sweep that only needs the verdict skips the reach bisection: same statuses, the open constraint named
    quick = solver.solve_batch(cylinders={"cyl": np.array([math.sqrt(2.0), 2.1])}, reach=False)
    assert list(quick.status) == [0, 3] and "cannot assemble" in quick.messages[1]
    assert "assembles only up to" in batch.messages[1] and "assembles only up to" not in quick.messages[1]


def test_static_dead_centre_names_the_lost_transmission() -> None:
    # angle −π/2 puts T at (1, 0): the cylinder E-T passes through the pivot O, its moment arm is 0:
    # the cylinder's force (the load the angle-driven step leaves free) has no transmission left
    solver = Solver(mechanism_from_dict(arm_mechanism({"angles": [{"name": "arm_angle", "hinge": "O"}]})))
    with pytest.raises(DeadCentreError, match=r"transmission angle \S+ deg at cylinder 'cyl' force through "
                                              r"arm_angle about O < 1 deg"):
        solver.solve(Inputs(angles={"arm_angle": -math.pi / 2}))
    res = solver.solve(Inputs(angles={"arm_angle": -math.pi / 4}))
    # away from it: moment balance about O, weight 10 kg at T = (√½, √½) vs cylinder force (closed form)
    t = np.array([math.sqrt(0.5), math.sqrt(0.5)])
    u = (t - [-1.0, 0.0]) / np.linalg.norm(t - [-1.0, 0.0])
    arm = t[0] * u[1] - t[1] * u[0]
    assert res.cylinders["cyl"].force == pytest.approx(10.0 * 9.80665 * t[0] / arm, rel=1e-9)


def test_kinematic_dead_centre() -> None:
    # stroke 2 m = fully stretched (E, O, T collinear): dL/dθ = 0, the input cannot drive the arm;
    # the cylinder's step has lost its transmission (its line passes through the pivot O)
    solver = Solver(mechanism_from_dict(arm_mechanism({"cylinders": ["cyl"]})))
    with pytest.raises(DeadCentreError, match=r"transmission angle \S+ deg at cyl about O"):
        solver.solve(Inputs(cylinders={"cyl": 2.0}))


def test_unobservable_kinematics_names_free_dof() -> None:
    with pytest.raises(UnobservableError, match="1 free DOF"):
        Solver(mechanism_from_dict(arm_mechanism({})))


def test_unobservable_statics_names_null_space() -> None:
    solver = Solver(load_mechanism(FIXTURES / "spring_contact.yaml"))
    with pytest.raises(UnobservableError, match="contact 'shoe' normal force"):
        solver.solve(Inputs(cylinders={"lift": 0.8}))  # no pressures: cylinder force and shoe load both unknown


def test_nan_unknown_and_negative_pressure_inputs() -> None:
    solver = Solver(load_mechanism(FIXTURES / "hitch.yaml"))
    with pytest.raises(InputError, match="lift_cylinder.*nan"):
        solver.solve(Inputs(cylinders={"lift_cylinder": float("nan")}))
    with pytest.raises(InputError, match="unknown cylinder input 'lift_cyl'"):
        solver.solve(Inputs(cylinders={"lift_cyl": 0.57}))
    with pytest.raises(InputError, match="missing cylinder length 'lift_cylinder'"):
        solver.solve(Inputs())
    with pytest.raises(InputError, match="negative absolute pressure"):
        solver.solve(Inputs(cylinders={"lift_cylinder": 0.57}, pressures={"lift_cap": -2e5}))
    batch = solver.solve_batch(cylinders={"lift_cylinder": np.array([0.57, np.inf, 0.58])})
    assert list(batch.status) == [0, 2, 0] and "inf" in batch.messages[1]


def _write(tmp_path, text: str):
    path = tmp_path / "bad.yaml"
    path.write_text(text)
    return path


GOOD = (FIXTURES / "four_bar.yaml").read_text()


@pytest.mark.parametrize("old, new, key, reason", [
    ("[crank, coupler]", "[crank, coupler_x]", "hinges[1].bodies", "body 'coupler_x' is not defined"),
    ("{name: C, bodies: [coupler, rocker]}", "{name: C, point: B, bodies: [coupler, rocker]}",
     "hinges[2].bodies", "point 'B' is not on body 'rocker'"),
    ("mass: 10.0", "mass: -10.0", "bodies[2].mass", "must be >= 0"),
    ("bore: 0.08", "bore: wide", "cylinders[0].bore", "expected a number"),
    ("cylinders: [drive]", "cylinders: [drv]", "measurements.cylinders[0]", "cylinder 'drv' is not defined"),
    ("  E: [-0.3, 0.3]", "  E: [-0.3]", "points.E", "expected [x, z]"),
])
def test_bad_file_names_file_and_key(tmp_path, old, new, key, reason) -> None:
    assert old in GOOD
    with pytest.raises(MechanismFileError) as err:
        load_mechanism(_write(tmp_path, GOOD.replace(old, new)))
    assert str(err.value).startswith(f"{tmp_path / 'bad.yaml'}: {key}: ") and reason in str(err.value)


def test_malformed_yaml_gives_line(tmp_path) -> None:
    with pytest.raises(MechanismFileError, match=r"bad.yaml: line \d+, column \d+: malformed YAML"):
        load_mechanism(_write(tmp_path, "name: x\npoints:\n  A: [0, 0\n  B: [1, 1]\n"))


def test_overrides_by_dotted_key() -> None:
    mech = load_mechanism(FIXTURES / "hitch.yaml")
    heavier = apply_overrides(mech, {"implement.mass": 1530.0, "cylinders.lift_cylinder.bore": 0.12})
    assert heavier.implement.mass == 1530.0 and heavier.cylinder("lift_cylinder").bore == 0.12
    assert mech.implement.mass == 1200.0  # original untouched
    with pytest.raises(MechanismFileError, match="bodies.lower_lnk.mass: no item named 'lower_lnk'"):
        apply_overrides(mech, {"bodies.lower_lnk.mass": 1.0})
    with pytest.raises(MechanismFileError, match=r"bodies\[3\].mass: must be >= 0"):
        apply_overrides(mech, {"bodies.lower_link.mass": -1.0})
