"""Akhmetov & Usmanov 2018: TTZ-1080 wheelbase-change parallelogram OKMN (preset ``ttz1080_base_change``).

What the paper's numbers allow to check (docs/parallelogram-mower-coulter-checks.md has the full account):

- Checkable and reproduced: the mobility W = 1 (eq. 1); the arithmetic of eqs. (6), (7), (12),
  the force-component square roots and the 9 deg decomposition; the paper's vertical balance of
  KM (F12t + F32t = G_n); F_H = 12560 kgf as the full thrust of a 100 mm bore at 160 kgf/cm2;
  eq. (7) and (12) from the solver when it derives the cylinder force from G_n; eq. (6) and the
  F10t of eq. (8) from the solver when the cylinder force is the measured 12560 kgf.
- Not checkable: the paper fixes BOTH the cylinder force F_H = 12560 kgf AND the axle load
  G_n = 1976 kgf. A 1-DOF mechanism allows one of them only: by virtual work the load component
  perpendicular to OK equals F_H*h_c/l1 = 3257.3 kgf (eq. 6), more than the whole axle load
  (1976.3 kgf with P_f). So the force plans built on both (|F12| = 9144, F10 = 4367,
  F23 = 9548.6 kgf) describe no equilibrium state and are not compared with the solver.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from linkage_monitor.mechanics import Inputs, Solver, load_preset
from oracles.akhmetov2018 import G_PAPER, arm_about, cylinder_force, theta_for_length, vertical_load

KGF = G_PAPER  # N per kgf as the paper uses it: 1976 kgf = 19384.56 N (Akhmetov & Usmanov 2018 table)
G_N = 19384.56  # N, front-axle weight (Akhmetov & Usmanov 2018 table)
F_ROLL = 0.018  # rolling resistance coefficient on concrete (Akhmetov & Usmanov 2018 table)
F_H_PAPER = 12560.0 * KGF  # N, cylinder push (Akhmetov & Usmanov 2018, eq. 6)


# the preset and its solver, once per module: the same two fixtures in each paper's test, of its own preset
@pytest.fixture(scope="module")
def mech():
    return load_preset("ttz1080_base_change")


@pytest.fixture(scope="module")
def solver(mech):
    return Solver(mech)


def _points(mech) -> dict[str, np.ndarray]:
    return {k: np.asarray(v, dtype=float) for k, v in mech.points.items()}


# ---- structure ---------------------------------------------------------------------------

def test_mobility_is_one_and_the_cylinder_closes_it(mech, solver):
    """W = 3n - 2p2 - p1 = 3*3 - 2*4 - 0 = 1 (Akhmetov & Usmanov 2018, eq. 1); the measured cylinder makes it 0."""
    n, p2 = len(mech.moving_bodies), len(mech.hinges)
    assert (n, p2) == (3, 4)  # Akhmetov & Usmanov 2018, Fig. 2: links OK, KM, MN; hinges O, K, M, N
    assert 3 * n - 2 * p2 - len(mech.measurements.cylinders) == 0
    kin = solver.kin
    _, jac = kin.residual_jacobian(kin.q_ref[None], kin.reference_inputs()[None])
    hinge_rows = jac[0, :2 * p2]
    assert kin.n - np.linalg.matrix_rank(hinge_rows) == 1  # one DOF, not a locked/degenerate parallelogram
    assert np.linalg.matrix_rank(jac[0]) == kin.n  # closed by the cylinder length: full rank


def test_preset_geometry_matches_the_paper(mech):
    """|OK| = |MN| = 0.380, |KM| = |ON| = 0.600, R_c = 0.170, h_c = 98.55 mm (Akhmetov & Usmanov 2018 table, eq. 6)."""
    p = _points(mech)
    dist = lambda a, b: float(np.hypot(*(p[a] - p[b])))  # noqa: E731
    assert dist("O", "K") == pytest.approx(0.380, abs=2e-5)
    assert dist("M", "N") == pytest.approx(0.380, abs=2e-5)
    assert dist("K", "M") == pytest.approx(0.600, abs=2e-5)
    assert dist("O", "N") == pytest.approx(0.600, abs=2e-5)
    assert dist("O", "C") == pytest.approx(0.170, abs=2e-5)
    assert arm_about(p, "O") == pytest.approx(0.09855, abs=2e-5)       # h_c, eq. (6)
    assert arm_about(p, "K") == pytest.approx(0.12148, rel=5e-3)       # h'_10 = 121.48 mm, eq. after (8)
    assert p["K"][1] - p["W"][1] == pytest.approx(0.75065, abs=1e-5)   # arm of M_f, eq. (7)
    assert p["W"][0] - p["M"][0] == pytest.approx(0.34062, abs=3e-5)   # h2, eq. (7)
    assert p["K"][0] - p["W"][0] == pytest.approx(0.25936, abs=3e-5)   # h2', eq. (12)


# ---- the paper's own arithmetic -----------------------------------------------------------

def test_paper_arithmetic_of_eqs_6_to_12():
    """Pure arithmetic of Akhmetov & Usmanov 2018 with its printed inputs (kgf, mm)."""
    f_h, h_c, l1, l2, g_n = 12560.0, 98.55, 380.0, 600.0, 1976.0
    m_f = 35.57 * 750.65                                              # P_f * arm, eq. (7)
    assert 0.018 * g_n == pytest.approx(35.57, abs=0.005)             # P_f = f * G_n (table)
    assert g_n * KGF == pytest.approx(19384.56, abs=0.01)             # table: 1976 kgf = 19384.56 N
    assert f_h * h_c / l1 == pytest.approx(3257.3, abs=0.05)          # F21t, eq. (6)
    assert (g_n * 340.62 - m_f) / l2 == pytest.approx(1077.3, abs=0.05)   # F12t, eq. (7)
    assert (g_n * 259.36 + m_f) / l2 == pytest.approx(898.7, abs=0.05)    # F32t, eq. (12)
    assert math.sqrt(9144**2 - 3257.3**2) == pytest.approx(8544.2, abs=0.05)   # F21n
    assert math.sqrt(9144**2 - 1077.3**2) == pytest.approx(9080.3, abs=0.05)   # F12n
    assert f_h * 121.48 / l1 == pytest.approx(4015.2, abs=0.05)       # F10t, eq. after (8)
    assert math.sqrt(4367**2 - 4015.2**2) == pytest.approx(1717.2, abs=0.05)   # F10n
    assert math.sqrt(9548.6**2 - 898.7**2) == pytest.approx(9506.2, abs=0.05)  # F32n
    assert 9548.6 * math.cos(math.radians(9)) == pytest.approx(9430.9, abs=0.2)  # paper rounds 9431.04 down
    assert 9548.6 * math.sin(math.radians(9)) == pytest.approx(1493.7, abs=0.05)
    assert 898.7 * KGF == pytest.approx(8816.25, abs=0.01)            # conclusions, N
    assert 9506.2 * KGF == pytest.approx(93255.82, abs=0.01)          # conclusions, N


def test_paper_internal_consistency():
    """What the paper's numbers satisfy among themselves (Akhmetov & Usmanov 2018)."""
    # KM: F12t and F32t are the vertical hinge forces of a horizontal bar; with G_n they balance
    assert 1077.3 + 898.7 == pytest.approx(1976.0, abs=0.05)
    assert 340.62 + 259.36 == pytest.approx(600.0, abs=0.05)          # h2 + h2' = |KM|
    # F_H is the full thrust of the 100 mm bore at 160 kgf/cm2 (pi*10^2/4 cm2 * 160)
    assert math.pi * 10.0**2 / 4.0 * 160.0 == pytest.approx(12560.0, rel=1e-3)
    # the rod end C lies on OK: the cylinder line's distances from K and O are as (l1-R_c):R_c
    assert 121.48 / 98.55 == pytest.approx((380.0 - 170.0) / 170.0, rel=5e-3)


def test_paper_fixes_both_cylinder_force_and_axle_load_which_one_dof_forbids():
    """Virtual work: the load on KM perpendicular to OK is F_H*h_c/l1; it cannot exceed |load|."""
    perpendicular = 12560.0 * 98.55 / 380.0                  # kgf, eq. (6)
    whole_load = math.hypot(1976.0, 0.018 * 1976.0)          # kgf, G_n and P_f (table)
    assert perpendicular > 1.6 * whole_load                  # 3257.3 vs 1976.3 kgf: no pose balances both


# ---- the solver on this preset -------------------------------------------------------------

def _derived(solver, length: float):
    return solver.solve(Inputs(cylinders={"base_change_cylinder": length}))


def test_cylinder_force_derived_from_axle_load_matches_virtual_work(mech, solver):
    """Over the stroke, the solver's push equals the virtual-work value for G_n and P_f (oracle)."""
    p = _points(mech)
    load = np.asarray(mech.loads[0].force)
    assert load == pytest.approx([-F_ROLL * G_N, G_N])  # Akhmetov & Usmanov 2018 table: G_n up, P_f = f*G_n back
    lengths = np.linspace(0.55, 0.84, 7)
    batch = solver.solve_batch(cylinders={"base_change_cylinder": lengths})
    assert np.all(batch.status == 0), batch.messages
    for i, length in enumerate(lengths):
        theta = theta_for_length(p, length)
        expected = cylinder_force(p, theta, load)
        assert batch.cylinder_force["base_change_cylinder"][i] == pytest.approx(expected, rel=1e-9)
        k_oracle = p["O"] + np.array([[np.cos(theta), -np.sin(theta)], [np.sin(theta), np.cos(theta)]]) @ (p["K"] - p["O"])
        assert batch.points["K"][i] == pytest.approx(k_oracle, abs=1e-9)


def test_derive_mode_reproduces_eqs_7_and_12_but_not_the_papers_cylinder_force(mech, solver):
    """With F_H derived from G_n, KM's hinge forces are the paper's F12t and F32t (eqs. 7, 12).

    The derived push (about 6.8 tf in this pose) is far below the paper's 12560 kgf: the paper's
    F_H is the cylinder's full thrust, not the force the axle load needs.
    """
    res = _derived(solver, 0.550)
    # hinge K: force on the bar KM from OK; its vertical part is F12t (down on KM), eq. (7)
    assert -res.hinges["K"].fz == pytest.approx(1077.3 * KGF, rel=2e-4)
    # hinge M: force on MN from KM, vertical part F32t, eq. (12)
    assert res.hinges["M"].fz == pytest.approx(898.7 * KGF, rel=2e-4)
    # MN is a two-force member: its force lies along MN (the paper's F32t = F32*sin 9 deg does not)
    mn = res.points["N"] - res.points["M"]
    f = np.array([res.hinges["M"].fx, res.hinges["M"].fz])
    assert abs(mn[0] * f[1] - mn[1] * f[0]) / (np.hypot(*mn) * np.hypot(*f)) < 1e-9
    bound = 0.380 * math.hypot(G_N, F_ROLL * G_N) / 0.09855   # N: virtual-work bound for any pose
    assert 0.0 < res.cylinders["base_change_cylinder"].force < bound < F_H_PAPER


def test_axle_load_estimated_from_the_papers_cylinder_force(mech, solver):
    """Measured pressure = the paper's F_H: the solver estimates the axle load; eq. (6) and (8) hold.

    implement_load is the extra downward load at W on top of front_axle_load, so the axle-side
    support is G_n - implement_load (N); the oracle is virtual work with P_f held at f*G_n.
    """
    cyl = mech.cylinder("base_change_cylinder")
    res = solver.solve(Inputs(cylinders={"base_change_cylinder": 0.550},
                              pressures={"base_change_cap": F_H_PAPER / cyl.cap_area, "base_change_rod": 0.0}))
    assert res.cylinders["base_change_cylinder"].force == pytest.approx(F_H_PAPER, rel=1e-12)
    p = _points(mech)
    support = G_N - res.implement_load
    theta = theta_for_length(p, 0.550)  # ~1e-5 rad: the preset's points are rounded to 10 um
    assert support == pytest.approx(vertical_load(p, theta, F_H_PAPER, -F_ROLL * G_N), rel=1e-9)
    assert support > 1.7 * G_N  # about 3.6 tf: what 12560 kgf would hold, vs the paper's 1976 kgf
    # eq. (6): hinge K force on OK (= -F12) perpendicular to OK is F21t = 3257.3 kgf
    ok = (res.points["K"] - res.points["O"]) / 0.380
    normal = np.array([-ok[1], ok[0]])
    f21 = -np.array([res.hinges["K"].fx, res.hinges["K"].fz])
    assert abs(f21 @ normal) == pytest.approx(3257.3 * KGF, rel=5e-4)
    # eq. after (8): the frame's force on OK at O, perpendicular to OK, F10t = 4015.2 kgf; the
    # paper's arm 121.48 mm is 0.2 % shorter than (l1 - R_c)*h_c/R_c = 121.74 mm, hence rel=5e-3
    f10 = np.array([res.hinges["O"].fx, res.hinges["O"].fz])
    assert abs(f10 @ normal) == pytest.approx(4015.2 * KGF, rel=5e-3)
