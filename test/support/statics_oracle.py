"""The statics a solved pose must satisfy, computed without the solver's internals: rigid-body
motion of load points from solved named points, virtual work by central finite differences, and
free-body sums. The mechanics tests check the solver against these."""

from __future__ import annotations

import numpy as np

from linkage_monitor.mechanics import BatchResult, Mechanism


def body_point(mech: Mechanism, batch: BatchResult, body: str, ref_xz: np.ndarray) -> np.ndarray:
    """Position (N, 2) of a point fixed on ``body`` (given in the reference pose), carried rigidly
    by two of the body's named points as the solver placed them."""
    b = mech.body(body)
    if b.ground:
        return np.broadcast_to(np.asarray(ref_xz, float), (len(batch), 2))
    p0, p1 = b.points[0], b.points[1]
    a0, b0 = mech.points[p0], mech.points[p1]
    a, bb = batch.points[p0], batch.points[p1]
    theta = np.arctan2(*(bb - a)[:, ::-1].T) - np.arctan2(*(b0 - a0)[::-1])
    r = np.asarray(ref_xz, float) - a0
    c, s = np.cos(theta), np.sin(theta)
    return a + np.column_stack([c * r[0] - s * r[1], s * r[0] + c * r[1]])


def external_loads(mech: Mechanism, batch: BatchResult, skip_implement_weight: bool = False
                   ) -> list[tuple[np.ndarray, np.ndarray]]:
    """Known external forces (point (N,2), force (N,2)): gravity at every cg (implement mass/cg
    from ``implement``) and the constant ``loads``; read straight from the mechanism data."""
    n = len(batch)
    out = []
    for b in mech.moving_bodies:
        mass, cg = b.mass, b.cg
        if mech.implement is not None and b.name == mech.implement.body:
            if skip_implement_weight:
                continue
            mass, cg = mech.implement.mass, mech.implement.cg
        if mass > 0:
            out.append((body_point(mech, batch, b.name, cg), np.tile([0.0, -mass * mech.gravity], (n, 1))))
    for ld in mech.loads:
        out.append((body_point(mech, batch, ld.body, ld.position), np.tile(ld.force, (n, 1))))
    return out


def mount(mech: Mechanism, batch: BatchResult, m) -> np.ndarray:
    return body_point(mech, batch, m.body, mech.points[m.point])


def spring_forces(mech: Mechanism, batch: BatchResult) -> list[tuple[np.ndarray, np.ndarray]]:
    """(length (N,), pushing force (N,)) of each spring: stiffness·(free_length − length) + preload."""
    out = []
    for s in mech.springs:
        length = np.linalg.norm(mount(mech, batch, s.b) - mount(mech, batch, s.a), axis=1)
        out.append((length, s.stiffness * (s.free_length - length) + s.preload))
    return out


def contact_direction(c) -> np.ndarray:
    """n − f·t with t the travel direction projected perpendicular to n (Kotov & Krol: T = f·N)."""
    n = np.asarray(c.normal, float) / np.linalg.norm(c.normal)
    t = np.asarray(c.travel, float) - np.dot(c.travel, n) * n
    return n - c.friction * t / np.linalg.norm(t)


def virtual_work(mech: Mechanism, plus: BatchResult, minus: BatchResult, centre: BatchResult, h: float,
                 skip_implement_weight: bool = False) -> np.ndarray:
    """Σ (known force · ∂position/∂stroke) + Σ spring force·∂L_s/∂stroke + Σ contact N·d·∂p/∂stroke,
    derivatives by central differences over the input stroke (±h); N taken from ``centre``."""
    work = np.zeros(len(centre))
    for (p_plus, _), (p_minus, _), (_, f) in zip(external_loads(mech, plus, skip_implement_weight),
                                                  external_loads(mech, minus, skip_implement_weight),
                                                  external_loads(mech, centre, skip_implement_weight)):
        work += np.sum(f * (p_plus - p_minus), axis=1) / (2 * h)
    for (l_plus, _), (l_minus, _), (_, f) in zip(spring_forces(mech, plus), spring_forces(mech, minus),
                                                 spring_forces(mech, centre)):
        work += f * (l_plus - l_minus) / (2 * h)
    for c in mech.contacts:
        dp = (body_point(mech, plus, c.body, mech.points[c.point]) - body_point(mech, minus, c.body, mech.points[c.point]))
        work += centre.contact_normal[c.name] * (dp @ contact_direction(c)) / (2 * h)
    return work


def moment(point: np.ndarray, force: np.ndarray) -> np.ndarray:
    """Moment about the origin B (N·m, + from +x towards +z): x·Fz − z·Fx."""
    return point[..., 0] * force[..., 1] - point[..., 1] * force[..., 0]
