"""Kotov & Krol: KSU-1 mower header linkage in field-copying mode (preset ``ksu1_mower_adapter``).

The paper's finding (Fig. 2, conclusions): the shoe drag T70 = f*N70 changes the tilt-cylinder
force HI noticeably, while the lift-cylinder force AC follows the spring block only. Its
dimensions are not printed, so the preset's are assumed; the finding is a property of the
topology (lever 2 is loaded by the spring block and the lift cylinder alone, eq. 4), which the
tests check together with the forces against an independent virtual-work oracle.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import brentq

from linkage_monitor.mechanics import Solver, apply_overrides, load_preset
from oracles.kotov_krol import Header, forces, pose

FRICTIONS = (0.0, 0.5, 0.6, 0.7, 0.8)  # Kotov & Krol: f = 0; 0.5; 0.6; 0.7; 0.8
COPY = 0.125  # m, Kotov & Krol: copying range +-125 mm from the conditional horizon


@pytest.fixture(scope="module")
def mech():
    return load_preset("ksu1_mower_adapter")


def _ref(mech) -> dict[str, np.ndarray]:
    return {k: np.asarray(v, dtype=float) for k, v in mech.points.items()}


def _header(mech, friction: float) -> Header:
    s = mech.springs[0]
    return Header(weight=mech.implement.mass * mech.gravity, stiffness=s.stiffness,
                  free_length=s.free_length, preload=s.preload, friction=friction)


def _angle_for_height(ref, dz: float) -> float:
    """Lever-5 angle (rad) at which the shoes are ``dz`` m above the reference line (oracle kinematics)."""
    return brentq(lambda t: pose(ref, t)["R"][1] - ref["R"][1] - dz, -0.6, 0.6, xtol=1e-14)


@pytest.fixture(scope="module")
def angles(mech) -> np.ndarray:
    ref = _ref(mech)
    return np.array([_angle_for_height(ref, dz) for dz in np.linspace(-COPY, COPY, 9)])


@pytest.fixture(scope="module")
def sweep(mech, angles):
    """Solver results over the copying range for each f: {f: BatchResult}."""
    out = {}
    for f in FRICTIONS:
        solver = Solver(apply_overrides(mech, {"contacts.shoe.friction": f}))
        ref = _ref(mech)  # locked lengths exactly as in the reference pose (the file rounds them to 0.1 um)
        locked = {"lift_cylinder": np.hypot(*(ref["C"] - ref["A"])), "tilt_cylinder": np.hypot(*(ref["I"] - ref["H"]))}
        batch = solver.solve_batch(cylinders=locked,
                                   angles={"float_lever_angle": angles})
        assert np.all(batch.status == 0), batch.messages
        out[f] = batch
    return out


def test_copying_mode_has_one_dof_closed_by_the_lever_angle(mech):
    """3 moving bodies, 3 hinges: 9 - 6 = 3 DOF; two locked cylinders and one angle close them."""
    solver = Solver(mech)
    kin = solver.kin
    _, jac = kin.residual_jacobian(kin.q_ref[None], kin.reference_inputs()[None])
    assert kin.n - np.linalg.matrix_rank(jac[0, :2 * len(mech.hinges)]) == 3
    assert np.linalg.matrix_rank(jac[0, :2 * len(mech.hinges) + 2]) == kin.n - 1  # cylinders locked: s2 left
    assert np.linalg.matrix_rank(jac[0]) == kin.n


def test_forces_match_virtual_work_oracle(mech, angles, sweep):
    """N70, HI and AC from the solver equal the virtual-work oracle for every f and height."""
    ref = _ref(mech)
    for f, batch in sweep.items():
        for i, psi in enumerate(angles):
            expected = forces(ref, _header(mech, f), float(psi))
            assert batch.contact_normal["shoe"][i] == pytest.approx(expected["shoe"], rel=1e-7)
            assert batch.contact_tangential["shoe"][i] == pytest.approx(f * expected["shoe"], rel=1e-7)
            for cyl in ("tilt_cylinder", "lift_cylinder"):
                assert batch.cylinder_force[cyl][i] == pytest.approx(expected[cyl], rel=1e-7)


def test_lift_force_follows_the_spring_only_by_eq_4(mech, angles, sweep):
    """Kotov & Krol, eq. (4): R23 = -((BD x R24).e_z) / ((BC x ort(AC)).e_z), R24 = spring force on lever 2."""
    ref = _ref(mech)
    s = mech.springs[0]
    bd, bc = ref["D"] - ref["B"], ref["C"] - ref["B"]
    ort_ac = (ref["C"] - ref["A"]) / np.hypot(*(ref["C"] - ref["A"]))
    batch = sweep[0.0]
    for i, _ in enumerate(angles):
        e, d = batch.points["E"][i], batch.points["D"][i]
        length = np.hypot(*(e - d))
        push = s.stiffness * (s.free_length - length) + s.preload       # schema: springs[]
        r24 = push * (d - e) / length                                     # on lever 2 at D
        r23 = -(bd[0] * r24[1] - bd[1] * r24[0]) / (bc[0] * ort_ac[1] - bc[1] * ort_ac[0])
        assert batch.cylinder_force["lift_cylinder"][i] == pytest.approx(r23, rel=1e-9)


def test_shoe_drag_changes_the_tilt_force_and_not_the_lift_force(sweep):
    """The paper's finding over +-125 mm and f = 0 ... 0.8 (Kotov & Krol, Fig. 2 a, b)."""
    lift0, tilt0 = sweep[0.0].cylinder_force["lift_cylinder"], sweep[0.0].cylinder_force["tilt_cylinder"]
    for f in FRICTIONS[1:]:
        lift = sweep[f].cylinder_force["lift_cylinder"]
        assert np.max(np.abs(lift - lift0) / np.abs(lift0)) < 1e-9
    tilt = np.array([sweep[f].cylinder_force["tilt_cylinder"] for f in FRICTIONS])
    change = np.abs(tilt[-1] - tilt0) / np.abs(tilt0)
    assert np.min(change) > 0.02   # f = 0.8 moves HI by 4 % (low end) ... 12 % (high end) here
    steps = np.diff(tilt, axis=0)  # the curves for increasing f do not cross: monotonic in f
    assert np.all(steps < 0.0) or np.all(steps > 0.0)
    # and the shoes keep touching the ground over the whole range
    assert all(np.all(sweep[f].contact_normal["shoe"] > 0.0) for f in FRICTIONS)
