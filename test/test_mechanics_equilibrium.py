"""Equilibrium oracles: every moving body's free-body diagram and the whole machine (external
loads vs. what the linkage puts on the frame) sum to zero force and moment; plus property
tests on random four-bar geometries and batched == single-pose results."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import HealthCheck, assume, example, given, settings
from hypothesis import strategies as st

from linkage_monitor.mechanics import Inputs, Solver, UnobservableError, load_mechanism, mechanism_from_dict
from support.fixtures import FIXTURES
from support.statics_oracle import body_point, contact_direction, moment, mount, spring_forces, virtual_work


def free_body_forces(mech, batch) -> dict[str, list[tuple[np.ndarray, np.ndarray]]]:
    """(point, force) acting on each body, built from the reported results and the YAML data."""
    n = len(batch)
    fb: dict[str, list] = {b.name: [] for b in mech.bodies}
    for h in mech.hinges:
        f = batch.hinge_force[h.name]
        pt = batch.points[h.point]
        fb[h.bodies[1]].append((pt, f))
        fb[h.bodies[0]].append((pt, -f))
    members = [(c.base, c.rod_end, batch.cylinder_force[c.name]) for c in mech.cylinders]
    members += [(s.a, s.b, f) for s, (_, f) in zip(mech.springs, spring_forces(mech, batch))]
    for a, b, f in members:
        pa, pb = mount(mech, batch, a), mount(mech, batch, b)
        u = (pb - pa) / np.linalg.norm(pb - pa, axis=1)[:, None]
        fb[b.body].append((pb, f[:, None] * u))
        fb[a.body].append((pa, -f[:, None] * u))
    for b in mech.moving_bodies:
        if mech.implement is not None and b.name == mech.implement.body:
            fb[b.name].append((batch.implement_cg, np.column_stack([np.zeros(n), -batch.implement_load])))
        elif b.mass > 0:
            fb[b.name].append((body_point(mech, batch, b.name, b.cg), np.tile([0.0, -b.mass * mech.gravity], (n, 1))))
    for ld in mech.loads:
        fb[ld.body].append((body_point(mech, batch, ld.body, ld.position), np.tile(ld.force, (n, 1))))
    for c in mech.contacts:
        fb[c.body].append((batch.points[c.point], batch.contact_normal[c.name][:, None] * contact_direction(c)))
    return fb


def check_equilibrium(mech, batch, ok) -> None:
    fb = free_body_forces(mech, batch)
    scale = max(np.nanmax(np.linalg.norm(f[ok], axis=1)) for lst in fb.values() for _, f in lst)
    lever = max(np.nanmax(np.abs(p[ok])) for lst in fb.values() for p, _ in lst)
    for b in mech.moving_bodies:
        force = sum(f for _, f in fb[b.name])[ok]
        mom = sum(moment(p, f) for p, f in fb[b.name])[ok]
        assert np.max(np.abs(force)) <= 1e-9 * scale, b.name
        assert np.max(np.abs(mom)) <= 1e-9 * scale * lever, b.name
    # whole machine: the linkage's loads on the frame equal the sum of all external loads on it
    frame_f = batch.frame_load_forces.sum(axis=1)[ok]
    frame_m = moment(batch.frame_load_points, batch.frame_load_forces).sum(axis=1)[ok]
    # Σ over moving bodies of all forces = 0 ⇒ frame reactions on the linkage = −Σ externals;
    # the frame receives the opposite: Σ frame loads = Σ external loads (gravity, loads, contacts)
    ext_f = sum(f for p, f in _externals(mech, batch))[ok]
    ext_m = sum(moment(p, f) for p, f in _externals(mech, batch))[ok]
    assert np.max(np.abs(frame_f - ext_f)) <= 1e-9 * scale
    assert np.max(np.abs(frame_m - ext_m)) <= 1e-9 * scale * lever


def _externals(mech, batch):
    n = len(batch)
    out = []
    for b in mech.moving_bodies:
        if mech.implement is not None and b.name == mech.implement.body:
            out.append((batch.implement_cg, np.column_stack([np.zeros(n), -batch.implement_load])))
        elif b.mass > 0:
            out.append((body_point(mech, batch, b.name, b.cg), np.tile([0.0, -b.mass * mech.gravity], (n, 1))))
    out += [(body_point(mech, batch, ld.body, ld.position), np.tile(ld.force, (n, 1))) for ld in mech.loads]
    out += [(batch.points[c.point], batch.contact_normal[c.name][:, None] * contact_direction(c)) for c in mech.contacts]
    # springs/cylinders with both ends on moving bodies are internal; one end on the frame: the
    # frame load includes them, so they are neither external nor missing
    return out


@pytest.mark.parametrize("fixture, cyl, pressures", [
    ("four_bar", "drive", {}),
    ("hitch", "lift_cylinder", {}),
    ("hitch", "lift_cylinder", {"lift_cap": 9e6, "lift_rod_side": 0.5e6}),
    ("spring_contact", "lift", {"lift_cap": 2e6}),
])
def test_body_and_machine_equilibrium(fixture, cyl, pressures) -> None:
    mech = load_mechanism(FIXTURES / f"{fixture}.yaml")
    solver = Solver(mech)
    length0 = solver.kin.reference_inputs()[0]
    batch = solver.solve_batch(cylinders={cyl: length0 * np.linspace(0.97, 1.03, 50)}, pressures=pressures)
    ok = batch.status <= 1
    assert ok.sum() >= 40
    check_equilibrium(mech, batch, ok)
    assert np.all(batch.residual[ok] <= 1e-9 * max(1.0, np.nanmax(np.abs(np.concatenate(list(batch.hinge_force.values()))))))


def test_batched_equals_single_pose() -> None:
    mech = load_mechanism(FIXTURES / "hitch.yaml")
    solver = Solver(mech)
    lengths = solver.kin.reference_inputs()[0] * np.random.default_rng(7).uniform(0.9, 1.1, 20)
    caps = np.random.default_rng(8).uniform(4e6, 12e6, 20)
    batch = solver.solve_batch(cylinders={"lift_cylinder": lengths}, pressures={"lift_cap": caps})
    single = Solver(mech)
    for i in range(20):
        res = single.solve(Inputs(cylinders={"lift_cylinder": lengths[i]}, pressures={"lift_cap": caps[i]}))
        scale = max(h.magnitude for h in res.hinges.values())
        for name, h in res.hinges.items():
            np.testing.assert_allclose(batch.hinge_force[name][i], [h.fx, h.fz], atol=1e-9 * scale)
        np.testing.assert_allclose(batch.implement_load[i], res.implement_load, rtol=1e-9)
        for name, pt in res.points.items():
            np.testing.assert_allclose(batch.points[name][i], pt, atol=1e-12)
        assert res.status == "ok"


def _four_bar(a, b, c, d, e, h_on_rocker, load, masses):
    return {
        "name": "random_four_bar",
        "points": {"A": a, "B": b, "C": c, "D": d, "E": e, "H": h_on_rocker},
        "bodies": [
            {"name": "frame", "ground": True, "points": ["A", "D", "E"]},
            {"name": "crank", "points": ["A", "B"], "mass": masses[0], "cg": "B"},
            {"name": "coupler", "points": ["B", "C"], "mass": masses[1], "cg": "C"},
            {"name": "rocker", "points": ["D", "C", "H"], "mass": masses[2], "cg": "H"},
        ],
        "hinges": [{"name": "A", "bodies": ["frame", "crank"]}, {"name": "B", "bodies": ["crank", "coupler"]},
                   {"name": "C", "bodies": ["coupler", "rocker"]}, {"name": "D", "bodies": ["frame", "rocker"]}],
        "cylinders": [{"name": "drive", "base": {"point": "E", "body": "frame"},
                       "rod_end": {"point": "H", "body": "rocker"}, "bore": 0.1, "rod": 0.05}],
        "loads": [{"name": "tool", "body": "coupler", "point": "B", "force": load}],
        "measurements": {"cylinders": ["drive"]},
    }


coord = st.floats(-1.5, 1.5, allow_nan=False)
pt = st.lists(coord, min_size=2, max_size=2)


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow, HealthCheck.filter_too_much])
@given(b=pt, c=pt, d=pt, e=pt, h=pt, load=st.lists(st.floats(-5e3, 5e3), min_size=2, max_size=2),
       masses=st.lists(st.floats(0.0, 50.0), min_size=3, max_size=3), dl=st.floats(-0.02, 0.02))
# found by hypothesis: strong curvature of the motion, where steps of 1e-4 m gave a 2e-6 oracle error
@example(b=[1.0, 0.0], c=[-1.0, 1.0], d=[0.0, 0.75], e=[-0.5, 0.8515625], h=[1.5, 0.546875], load=[0.0, 0.0],
         masses=[1.0, 0.0, 0.0], dl=0.0)
def test_random_four_bars_virtual_work_and_equilibrium(b, c, d, e, h, load, masses, dl) -> None:
    pts = np.array([[0.0, 0.0], b, c, d, e, h])
    dist = np.linalg.norm(pts[:, None] - pts[None], axis=-1)
    assume(np.min(dist[np.triu_indices(6, 1)]) > 0.2)   # no coincident points
    mech = mechanism_from_dict(_four_bar([0.0, 0.0], b, c, d, e, h, load, masses))
    try:
        solver = Solver(mech)
    except UnobservableError:
        assume(False)  # degenerate (e.g. collinear) geometry: correctly refused, nothing to check
    length = solver.kin.reference_inputs()[0] + dl
    hstep = 1e-5  # Richardson-extrapolated central differences: error O(h^4); positions solved to 1e-13 m

    def solved(d: float):
        return solver.solve_batch(cylinders={"drive": np.array([length + d])})

    centre = solved(0.0)
    # well away from a dead centre: its measure is the smallest transmission angle where the reduced
    # path serves (every four-bar of this shape), the condition number on the general path
    angle = centre.transmission_angle[0]
    assume(centre.status[0] == 0 and (angle > math.radians(2.0) if math.isfinite(angle) else centre.condition[0] < 1e4))
    estimates = []
    for h_ in (hstep, hstep / 2):
        plus, minus = solved(h_), solved(-h_)
        assume(plus.status[0] == 0 and minus.status[0] == 0)
        estimates.append(-virtual_work(mech, plus, minus, centre, h_)[0])
    expected = (4 * estimates[1] - estimates[0]) / 3
    # the finite differences are only an oracle where the motion is smooth over ±h (no branch change)
    assume(abs(estimates[0] - estimates[1]) <= 1e-3 * max(abs(expected), 1.0))
    scale = max(abs(expected), np.hypot(*load), 9.81 * sum(masses), 1.0)
    assert abs(centre.cylinder_force["drive"][0] - expected) <= 1e-6 * scale
    check_equilibrium(mech, centre, np.array([True]))
