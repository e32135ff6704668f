"""A linkage as a chain of dyads: its pose in closed form from the driving inputs (reduced coordinates).

A textbook (and Popov 2009) assembles a hitch step by step from the frame outward: the lift arm
turned about its pivot by the lift cylinder's length (law of cosines) or by its angle sensor, then
each pair of links hinged to each other and each to a placed body (an RRR dyad: two circles
intersect). ``decompose`` finds such a chain from the mechanism's data (bodies, hinges, measured
cylinders and angles); ``kernels.chain_pose`` evaluates it for one pose — a few trigonometric
functions per body, no iteration — on the reference pose's side of every circle intersection (its
assembly branch). The solver takes that pose as it is (``kernels.assembly._kinematic_pose``: on the
reference branch by those sides, its loop-closure residual checking that it closes); with
redundant sensors ``kernels.chain_fit`` moves the driving inputs along the chain to the closed pose
nearest all readings.

Steps (rows of the int table ``CHAIN_INT`` fields, float table ``CHAIN_FLOAT`` fields; attachments
as in :class:`~.kinematics.Kinematics`, the ground's at fixed positions, bodies' by their offsets
from the body origin in the reference pose):

- ANGLE: body B hinged at a placed body P, turned by an angle sensor on that hinge:
  θ_B = θ_P + sign·(s − reference) (sign −1 when B is the hinge's first body, the sensor reading
  θ(bodies[1]) − θ(bodies[0]) + reference); B's origin from the hinge point.
- CYLINDER: body B hinged at a placed body P, with a measured cylinder from B to a placed body Q:
  B's cylinder end lies at ρ from the pivot and at the cylinder's length s from Q's end.
- RRR: bodies B1, B2 hinged to each other at H and each to a placed body: H lies at ρ1 from B1's
  pivot and ρ2 from B2's.

A mechanism that does not decompose this way (a class-III group, an unmeasured degree of freedom)
has an empty chain (``chain_pose`` then places nothing and says so) and Newton starts from the
tangent prediction, as before (test fixture: triad.yaml).
"""

from __future__ import annotations

import math

import numpy as np

from .model import Mechanism

ANGLE, CYLINDER, RRR = 0, 1, 2
# int fields: kind, then per kind (unused: -1)
#   ANGLE:    B, a_parent (the hinge on P), a_body (the hinge on B), input column, sign
#   CYLINDER: B, a_parent (pivot on P), a_body (pivot on B), a_end (cylinder end on B), a_other (end on Q), input column
#   RRR:      B1, a_parent1, a_body1, a_joint1 (H on B1), B2, a_parent2, a_body2, a_joint2 (H on B2)
# then the hinges the step closes (indices into mech.hinges): ANGLE / CYLINDER: the pivot B–P in
# STEP_HINGE; RRR: B1–P1 in STEP_HINGE, B2–P2 in STEP_HINGE2, the joint B1–B2 (bodies[0] = B1) in STEP_JOINT
KIND, BODY, A_PARENT, A_BODY = 0, 1, 2, 3
ANGLE_INPUT, ANGLE_SIGN = 4, 5                                              # ANGLE
A_END, A_OTHER, CYLINDER_INPUT = 4, 5, 6                                    # CYLINDER
A_JOINT1, BODY2, A_PARENT2, A_BODY2, A_JOINT2 = 4, 5, 6, 7, 8               # RRR
STEP_HINGE, STEP_HINGE2, STEP_JOINT = 10, 11, 12
CHAIN_INT = 13
# float fields: CYLINDER: side, φ0 (direction pivot → end on B at θ = 0, rad), ρ (m); ANGLE: reference (rad);
#               RRR: side, φ1_0, ρ1, φ2_0, ρ2
CHAIN_FLOAT = 5


def _cross_sign(a: np.ndarray, b: np.ndarray, p: np.ndarray) -> float:
    """Sign of cross(b − a, p − a): on which side of the line a → b the point p lies."""
    u, w = b - a, p - a
    return float(np.sign(u[0] * w[1] - u[1] * w[0]))


def _polar(v: np.ndarray) -> tuple[float, float]:
    """(angle rad, length m) of a vector."""
    return math.atan2(v[1], v[0]), math.hypot(v[0], v[1])


def decompose(mech: Mechanism, body_index: dict[str, int], hinge_att: np.ndarray, cyl_att: np.ndarray,
              att_ref: np.ndarray, att_position: np.ndarray) -> tuple[np.ndarray, np.ndarray, list[str]]:
    """The chain of ``mech`` from its measured inputs: (int table (S, CHAIN_INT), float table
    (S, CHAIN_FLOAT), a line per step for people). Empty tables when some body stays unplaced.

    Rules, applied until none does (cylinders before angles, as ``KinematicLayout.driving_rows``
    chooses the driving inputs): a body hinged to a placed body, turned by a measured cylinder from
    a placed body or by an angle sensor on that hinge; two bodies hinged to each other and each to a
    placed body. ``hinge_att`` (2, H) and ``cyl_att`` (2, C) are the attachments of the hinges'
    bodies and the measured cylinders' (base, rod end); ``att_ref`` their offsets, ``att_position``
    their positions in the reference pose (m).
    """
    placed = {b.name for b in mech.bodies if b.ground}
    hinges = [(k, h.bodies[0], h.bodies[1]) for k, h in enumerate(mech.hinges)]
    nc = cyl_att.shape[1]
    cylinders = [mech.cylinder(c) for c in mech.measurements.cylinders]
    drivers: list[tuple[str, int]] = ([("cylinder", k) for k in range(nc)]
                                      + [("angle", k) for k in range(len(mech.measurements.angles))])
    hinge_of_angle = {k: next(i for i, h in enumerate(mech.hinges) if h.name == a.hinge)
                      for k, a in enumerate(mech.measurements.angles)}
    ints: list[list[int]] = []
    floats: list[list[float]] = []
    lines: list[str] = []

    def pivot(body: str, skip: int = -1) -> tuple[int, int, int] | None:
        """(hinge, attachment on the placed body, attachment on ``body``) of a hinge of ``body`` to a placed body."""
        for k, a, b in hinges:
            if k != skip and body in (a, b) and a != b and ({a, b} - {body}) <= placed:
                mine = 0 if a == body else 1
                return k, int(hinge_att[1 - mine, k]), int(hinge_att[mine, k])
        return None

    progress = True
    while progress:
        progress = False
        for driver in list(drivers):
            kind, k = driver
            if kind == "angle":
                h = hinge_of_angle[k]
                b0, b1 = mech.hinges[h].bodies
                if (b0 in placed) == (b1 in placed):
                    continue
                mine = 0 if b1 in placed else 1          # the unplaced body's end of the hinge
                body = (b0, b1)[mine]
                row = [ANGLE, body_index[body], int(hinge_att[1 - mine, h]), int(hinge_att[mine, h]), nc + k,
                       1 if mine == 1 else -1]
                floats.append([mech.measurements.angles[k].reference] + [0.0] * (CHAIN_FLOAT - 1))
                lines.append(f"{body} about {mech.hinges[h].name} by angle {mech.measurements.angles[k].name}")
            else:
                ends = (cylinders[k].base.body, cylinders[k].rod_end.body)
                if (ends[0] in placed) == (ends[1] in placed):
                    continue
                mine = 0 if ends[1] in placed else 1
                body = ends[mine]
                found = pivot(body)
                if found is None:
                    continue
                h, a_parent, a_body = found
                a_end, a_other = int(cyl_att[mine, k]), int(cyl_att[1 - mine, k])
                phi0, rho = _polar(att_ref[a_end] - att_ref[a_body])
                side = _cross_sign(att_position[a_parent], att_position[a_other], att_position[a_end])
                row = [CYLINDER, body_index[body], a_parent, a_body, a_end, a_other, k]
                floats.append([side, phi0, rho] + [0.0] * (CHAIN_FLOAT - 3))
                lines.append(f"{body} about {mech.hinges[h].name} by cylinder {cylinders[k].name}")
            ints.append(row + [-1] * (STEP_HINGE - len(row)) + [h, -1, -1])   # the pivot B–P
            placed.add(body)
            drivers.remove(driver)
            progress = True
        for k, x, y in hinges:
            if x in placed or y in placed or x == y:
                continue
            px, py = pivot(x, skip=k), pivot(y, skip=k)
            if px is None or py is None:
                continue
            a_x, a_y = int(hinge_att[0, k]), int(hinge_att[1, k])   # the joint H on x and on y
            phi_x, rho_x = _polar(att_ref[a_x] - att_ref[px[2]])
            phi_y, rho_y = _polar(att_ref[a_y] - att_ref[py[2]])
            side = _cross_sign(att_position[px[1]], att_position[py[1]], att_position[a_x])
            ints.append([RRR, body_index[x], px[1], px[2], a_x, body_index[y], py[1], py[2], a_y, -1, px[0], py[0], k])
            floats.append([side, phi_x, rho_x, phi_y, rho_y])
            lines.append(f"RRR({x}, {y}) at {mech.hinges[k].name}")
            placed |= {x, y}
            progress = True
    if any(b.name not in placed for b in mech.bodies):
        return np.zeros((0, CHAIN_INT), dtype=np.int64), np.zeros((0, CHAIN_FLOAT)), []
    return np.array(ints, dtype=np.int64).reshape(-1, CHAIN_INT), np.array(floats).reshape(-1, CHAIN_FLOAT), lines
