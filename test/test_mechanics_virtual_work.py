"""Virtual-work oracle: the cylinder force from equilibrium equals −Σ load·∂position/∂stroke,
derivatives by central finite differences of the solved kinematics (springs, friction included)."""

from __future__ import annotations

import numpy as np
import pytest

from linkage_monitor.mechanics import Solver, load_mechanism
from support.fixtures import FIXTURES
from support.statics_oracle import external_loads, virtual_work

H = 1e-5  # m, finite-difference step in the stroke


def _random_strokes(solver: Solver, n: int, spread: float, seed: int) -> np.ndarray:
    length0 = solver.kin.reference_inputs()[0]
    return length0 * (1.0 + np.random.default_rng(seed).uniform(-spread, spread, n))


def _solve_three(solver: Solver, cyl: str, lengths: np.ndarray, **kw):
    return [solver.solve_batch(cylinders={cyl: lengths + d}, **kw) for d in (H, -H, 0.0)]


def _load_scale(mech, batch) -> np.ndarray:
    return np.max([np.linalg.norm(f, axis=1) for _, f in external_loads(mech, batch)], axis=0)


@pytest.mark.parametrize("fixture, cyl, spread", [("four_bar", "drive", 0.025), ("hitch", "lift_cylinder", 0.12)])
def test_cylinder_force_equals_virtual_work(fixture: str, cyl: str, spread: float) -> None:
    mech = load_mechanism(FIXTURES / f"{fixture}.yaml")
    solver = Solver(mech)
    lengths = _random_strokes(solver, 600, spread, seed=1)
    plus, minus, centre = _solve_three(solver, cyl, lengths)
    ok = (plus.status == 0) & (minus.status == 0) & (centre.status == 0)
    assert ok.sum() >= 500, f"only {ok.sum()} of 600 random strokes assembled"
    # virtual work of a pushing cylinder force F over a stroke change dL is F·dL, so
    # F + Σ load·∂p/∂L = 0 (principle of virtual work, rigid links, frictionless pins)
    expected = -virtual_work(mech, plus, minus, centre, H)
    force = centre.cylinder_force[cyl]
    np.testing.assert_allclose(force[ok], expected[ok], rtol=1e-6, atol=1e-6 * _load_scale(mech, centre)[ok].max())


def test_spring_and_friction_contact_virtual_work() -> None:
    """Measured cylinder force (pressures) + spring + friction shoe: the solved normal force must make
    the virtual work of all forces vanish (Kotov & Krol structure)."""
    mech = load_mechanism(FIXTURES / "spring_contact.yaml")
    solver = Solver(mech)
    lengths = _random_strokes(solver, 600, 0.15, seed=2)
    p_cap = np.random.default_rng(3).uniform(0.0, 3e6, lengths.size)
    pressures = {"lift_cap": p_cap, "lift_rod": np.full(lengths.size, 0.2e6)}
    plus, minus, centre = _solve_three(solver, "lift", lengths, pressures=pressures)
    ok = (centre.status <= 1) & (plus.status <= 1) & (minus.status <= 1)  # lift-off poses still solve
    assert ok.sum() >= 500
    cyl = mech.cylinder("lift")
    force = p_cap * cyl.cap_area - 0.2e6 * cyl.rod_area  # schema: F = count·(p_cap·A_cap − p_rod·A_rod)
    residual = force + virtual_work(mech, plus, minus, centre, H)
    scale = np.maximum(np.abs(force), _load_scale(mech, centre))
    assert np.max(np.abs(residual[ok]) / scale[ok]) < 1e-6
    assert np.any(centre.contact_normal["shoe"][ok] > 0) and np.any(centre.contact_normal["shoe"][ok] < 0)


def test_implement_load_estimated_from_pressure_by_virtual_work() -> None:
    """With the lift-cylinder force measured, the vertical implement load W at the cg satisfies
    F·1 + Σ(other loads)·∂p/∂L − W·∂z_cg/∂L = 0 (virtual work)."""
    mech = load_mechanism(FIXTURES / "hitch.yaml")
    solver = Solver(mech)
    lengths = _random_strokes(solver, 300, 0.1, seed=4)
    p_cap = np.random.default_rng(5).uniform(5e6, 15e6, lengths.size)
    plus, minus, centre = _solve_three(solver, "lift_cylinder", lengths, pressures={"lift_cap": p_cap})
    ok = (plus.status == 0) & (minus.status == 0) & (centre.status == 0)
    assert ok.sum() >= 250
    force = p_cap * mech.cylinder("lift_cylinder").cap_area
    others = virtual_work(mech, plus, minus, centre, H, skip_implement_weight=True)
    dz_cg = (plus.implement_cg[:, 1] - minus.implement_cg[:, 1]) / (2 * H)
    expected = (force + others) / dz_cg
    np.testing.assert_allclose(centre.implement_load[ok], expected[ok], rtol=1e-6, atol=1e-3)
