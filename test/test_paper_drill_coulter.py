"""Naumenko et al. 2021: seed-drill coulter parallelogram over a sinusoidal relief (preset ``drill_coulter``).

Relief of Naumenko et al. 2021: wavelength l = 0.2 m, amplitude A = 0.049 m with A = h/2 (the paper: "wave
length l = 2a, amplitude A = h/2", Fig. 2), so y = (h/2)(1 - cos(2 pi x/l)) rises 0 ... h = 0.098 m.
Checks: (1) the solver's kinematics with the measured angle -phi(t) from eq. (16) put the wheel
centre on the relief; (2) kinetostatics with phi', phi'' from eq. (17)-(18) match a d'Alembert
virtual-work oracle and global force balance; (3) inertia terms scale with v^2 and vanish as v -> 0.
"""

from __future__ import annotations

import numpy as np
import pytest

from linkage_monitor.mechanics import Solver, load_preset
from oracles.naumenko2021 import (Parallelogram, Relief, Rotor, normal_force, phi_at, phi_rates, rotor_acceleration)

RELIEF = Relief(h=2 * 0.049, l=0.2)  # Naumenko et al. 2021: l = 0.2 m, A = 0.049 m = h/2
ANGLE = "upper_link_angle"            # reads -phi (the preset's convention)


# the preset and its solver, once per module: the same two fixtures in each paper's test, of its own preset
@pytest.fixture(scope="module")
def mech():
    return load_preset("drill_coulter")


@pytest.fixture(scope="module")
def solver(mech):
    return Solver(mech)


def _link(mech) -> Parallelogram:
    """AB and phi0 read from the preset: B - A = AB*(-sin phi0, -cos phi0), eq. (14)-(15)."""
    d = np.asarray(mech.points["B"]) - np.asarray(mech.points["A"])
    return Parallelogram(ab=float(np.hypot(*d)), phi0=float(np.arctan2(-d[0], -d[1])))


def _rotors(mech) -> tuple[Rotor, ...]:
    pivots = {"upper_link": "A", "lower_link": "C"}
    return tuple(Rotor(mass=b.mass, inertia=b.inertia, pivot=np.asarray(mech.points[pivots[b.name]]),
                       cg=np.asarray(b.cg)) for b in mech.moving_bodies if b.name in pivots)


def _period(n: int) -> np.ndarray:
    """Travelled distances s = v t (m) over one wavelength."""
    return np.linspace(0.0, RELIEF.l, n, endpoint=False)


def test_paper_rates_17_18_are_the_derivatives_of_16(mech):
    """phi', phi'' of eq. (17)-(18) against central differences of phi(t) from eq. (16)."""
    link, v, dt = _link(mech), 1.5, 1e-5
    for s in (0.013, 0.05, 0.11, 0.17):
        _, dphi, ddphi = phi_rates(s, v, link, RELIEF)
        ph = [phi_at(s + k * v * dt, link, RELIEF) for k in (-1, 0, 1)]
        assert dphi == pytest.approx((ph[2] - ph[0]) / (2 * dt), rel=1e-6)
        assert ddphi == pytest.approx((ph[2] - 2 * ph[1] + ph[0]) / dt**2, rel=1e-3)


def test_wheel_centre_follows_the_relief_over_one_period(mech, solver):
    """Solver kinematics with the angle from eq. (16): W rises by y(v t + dx_W) (eq. 13)."""
    link = _link(mech)
    s = _period(40)
    phi = np.array([phi_at(x, link, RELIEF) for x in s])
    batch = solver.solve_batch(angles={ANGLE: -phi})
    assert np.all(batch.status == 0), batch.messages
    w0 = np.asarray(mech.points["W"])
    dx = batch.points["W"][:, 0] - w0[0]
    dz = batch.points["W"][:, 1] - w0[1]
    assert dz == pytest.approx([RELIEF.y(x) for x in s + dx], abs=1e-9)
    # the post translates (parallelogram): B moves like W
    assert batch.points["B"] - np.asarray(mech.points["B"]) == pytest.approx(batch.points["W"] - w0, abs=1e-9)


def _kinetostatics(solver, mech, s: np.ndarray, v: float):
    link = _link(mech)
    rates = np.array([phi_rates(x, v, link, RELIEF) for x in s])
    batch = solver.solve_batch(angles={ANGLE: -rates[:, 0]}, rates={ANGLE: -rates[:, 1]},
                               accelerations={ANGLE: -rates[:, 2]})
    return batch, rates


def test_kinetostatics_match_dalembert_oracle(mech, solver):
    """At v = 1 m/s: wheel load N against virtual work, hinge forces against global force balance."""
    link, rotors = _link(mech), _rotors(mech)
    post = mech.body("post")
    contact = mech.contacts[0]
    s = _period(12)
    batch, rates = _kinetostatics(solver, mech, s, v=1.0)
    assert np.all(batch.status <= 1), batch.messages   # ok or lift_off (the values are still solved)
    for i, (phi, dphi, ddphi) in enumerate(rates):
        n = normal_force(phi, dphi, ddphi, rotors, post.mass, link, contact.friction, mech.gravity)
        assert batch.contact_normal["support_wheel"][i] == pytest.approx(n, rel=1e-8, abs=1e-8)
        # Newton for all moving bodies: frame hinges + ground + weights = sum m a
        frame = batch.hinge_force["A"][i] + batch.hinge_force["C"][i]      # on the links from the frame
        ground = n * np.array([-contact.friction, 1.0])
        weight = -mech.gravity * (sum(r.mass for r in rotors) + post.mass) * np.array([0.0, 1.0])
        ma = sum(r.mass * rotor_acceleration(r, phi, dphi, ddphi) for r in rotors) \
            + post.mass * link.post_acceleration(phi, dphi, ddphi)
        assert frame + ground + weight == pytest.approx(ma, abs=1e-6)   # N
    # at 1 m/s the inertia load exceeds the weight: past the crest the wheel would have to be
    # pulled down to follow the relief, which the solver reports as lift-off (N < 0)
    assert np.any(batch.status == 1) and np.all(batch.contact_normal["support_wheel"][batch.status == 1] < 0.0)
    slow, _ = _kinetostatics(solver, mech, s, v=0.1)
    assert np.all(slow.status == 0)


def test_inertia_loads_scale_with_v_squared_and_vanish_at_rest(mech, solver):
    """Same poses (fixed s = v t), speeds 0.05 ... 1 m/s: (result - static) / v^2 is constant."""
    s = np.array([0.02, 0.07, 0.12, 0.18])
    link = _link(mech)
    phi = np.array([phi_at(x, link, RELIEF) for x in s])
    static = solver.solve_batch(angles={ANGLE: -phi})
    ref = None
    for v in (1.0, 0.5, 0.2, 0.05):
        batch, _ = _kinetostatics(solver, mech, s, v)
        scaled = np.concatenate([(batch.contact_normal["support_wheel"] - static.contact_normal["support_wheel"])[:, None]]
                                + [batch.hinge_force[h] - static.hinge_force[h] for h in "ABCD"], axis=1) / v**2
        if ref is None:
            ref = scaled
            assert np.max(np.abs(ref)) > 10.0   # N per (m/s)^2: the inertia term is really there
        else:
            assert scaled == pytest.approx(ref, rel=1e-6, abs=1e-6)
    # v -> 0: the kinetostatic result tends to the static one (difference = ref * v^2)
    slow, _ = _kinetostatics(solver, mech, s, 1e-3)
    gap = np.abs(slow.contact_normal["support_wheel"] - static.contact_normal["support_wheel"])
    assert np.all(gap <= 1.01 * np.abs(ref[:, 0]) * 1e-6 + 1e-9)   # N: ref * v^2 at v = 1 mm/s
