"""Khaliullin et al. 2023 closed forms, an oracle for the `damping_hitch` preset.

The paper solves its hitch link by link with hand-derived formulas, eqs. (1)-(72). This
module implements the reactions it prints, eqs. (6)-(8), (18)-(20), (40)-(42), (61)-(63)
and (70)-(72), in two variants (see docs/damping-hitch-closed-forms.md for the derivation):

- ``"printed"``: the formulas as printed. Every lever arm is a triangle height from
  Heron's formula, ``arm = 2 S / base`` (eqs. 2-5 and alike), hence never negative; the
  angle of link KM is ``delta = arccos((Y_K - Y_M) / l_KM)`` (eq. 65), hence
  ``sin(delta) >= 0``; eq. (20) keeps its typo ``X_K - X_D`` (from the third line of eq. 9).
  Obvious misprints of *names* are read as meant: ``cos((X_C - X_D)/l_DC)`` in (1) is the
  direction cosine ``(X_C - X_D)/l_DC`` used in (7); ``O''`` in (62)-(63) is ``O'''``;
  ``S_OCC`` in (11) is ``S_OCD``; ``l_O''N'`` in (67)-(68) is ``l_O'N``.
- ``"corrected"``: the same equations with signed lever arms (moment of a unit force,
  counter-clockwise positive in the paper frame, times the sense the paper's figure
  implies), the signed ``sin(delta) = (X_K - X_M) / l_KM`` and ``X_K - X_O`` in eq. (20).
  Equal to the printed forms while the linkage keeps the figure's orientation and
  ``X_D = X_O``; right for any non-degenerate pose.

Paper frame: X rearward, Y up, metres (the schema frame mirrored: ``X = -x``, ``Y = z``,
see `paper_frame`). Points, by the paper's letters, with ``O1 = O'``, ``O2 = O''`` and
``O3 = O'''``: implement B (lower hitch point), C (top-link point), G (centre of gravity,
where R_X, R_Y act); top link D-C; rocker O-D-K; link K-M; lower link A-B with F; lift rod
E-F; lift arm O3-E-L; actuator H-L; sub-frame O1-A-M-N; elastic-damping element N-O2.

Sign conventions of the returned quantities (N), derived from eqs. (1), (9), (31), (43),
(64) (all forces in the paper frame):
- ``R_X`` rearward, ``R_Y`` downward: the implement load at G is ``(R_X, -R_Y)``;
- ``R_BX, R_BY``: the lower link pushes the implement at B with ``(-R_BX, +R_BY)``;
- ``R_C = R_D`` top-link tension; ``R_F = R_E`` lift-rod tension;
- ``R_K = R_M`` compression of link KM; ``R_L`` push of the actuator H-L on L;
- ``R_N`` compression of the element N-O2 (it pushes N away from O2);
- ``R_OX, R_OY`` / ``R_O1X, R_O1Y`` / ``R_O3X, R_O3Y``: the frame's force on the rocker /
  the sub-frame / the lift arm at its pivot;
- ``R_AX, R_AY``: the lower link's force on the sub-frame at A (the sub-frame pushes the
  lower link with ``(-R_AX, -R_AY)``).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Literal

import numpy as np

Variant = Literal["printed", "corrected"]
Points = Mapping[str, np.ndarray]


def paper_frame(points_xz: Mapping[str, Sequence[float]]) -> dict[str, np.ndarray]:
    """Points of the schema frame (x forward, z up, m) in the paper frame (X rearward, Y up, m)."""
    return {name: np.array([-float(p[0]), float(p[1])]) for name, p in points_xz.items()}


def paper_force_to_xz(force: Sequence[float]) -> np.ndarray:
    """A force (N) of the paper frame (X rearward, Y up) in the schema frame (x forward, z up)."""
    return np.array([-float(force[0]), float(force[1])])


def length(p: np.ndarray, q: np.ndarray) -> float:
    """Distance between two points, m; eq. (5) and alike."""
    return float(np.hypot(*(q - p)))


def heron_area(a: float, b: float, c: float) -> float:
    """Area of a triangle from its sides (m -> m^2), Heron's formula; eqs. (3)-(4)."""
    p = (a + b + c) / 2.0
    return float(np.sqrt(max(p * (p - a) * (p - b) * (p - c), 0.0)))


def lever_arm(pts: Points, about: str, tail: str, head: str, variant: Variant) -> float:
    """Lever arm (m) about point `about` of a force on the line tail-head, as the paper uses it.

    printed: the height of the triangle (about, tail, head) on the base tail-head,
    ``2 S / base`` with S from Heron's formula (eq. 2 and all the arms after it).
    corrected: the moment about `about` of a unit force at `tail` pointing to `head`,
    counter-clockwise positive in the paper frame. The caller orders tail/head so that the
    corrected arm is positive in the orientation of the paper's figure (the sense is
    derived for each arm in docs/damping-hitch-closed-forms.md).
    """
    p, q, r = pts[about], pts[tail], pts[head]
    base = length(q, r)
    if variant == "printed":
        return 2.0 * heron_area(length(p, q), length(q, r), length(p, r)) / base
    d = r - q
    return float(((q - p)[0] * d[1] - (q - p)[1] * d[0]) / base)


def implement_reactions(pts: Points, r_x: float, r_y: float, variant: Variant) -> dict[str, float]:
    """Top-link tension R_C = R_D and hinge B reaction R_BX, R_BY (N); Khaliullin et al. 2023 eqs. (6)-(8)."""
    X, Y = pts["G"]
    B, C, D = pts["B"], pts["C"], pts["D"]
    l_dc = length(D, C)
    bb = lever_arm(pts, "B", "C", "D", variant)  # eq. (2)
    r_c = (r_y * (X - B[0]) + r_x * (Y - B[1])) / bb  # eq. (6)
    r_bx = r_x - r_c * (C[0] - D[0]) / l_dc  # eq. (7)
    r_by = (r_bx * (C[1] - B[1]) + r_y * (X - C[0]) - r_x * (C[1] - Y)) / (B[0] - C[0])  # eq. (8)
    return {"R_C": r_c, "R_D": r_c, "R_BX": r_bx, "R_BY": r_by}


# Eqs. (18)-(20) have the form of the lift arm's (61)-(63): each set as printed, checked equation by equation.
def rocker_reactions(pts: Points, r_d: float, variant: Variant) -> dict[str, float]:
    """Link KM compression R_K = R_M and rocker pivot reaction R_OX, R_OY (N); eqs. (18)-(20)."""
    O, D, K = pts["O"], pts["D"], pts["K"]
    od = lever_arm(pts, "O", "D", "C", variant)  # eq. (10)
    ok = lever_arm(pts, "O", "K", "M", variant)  # eq. (14)
    kk = lever_arm(pts, "K", "D", "C", variant)  # eq. (21)
    dd = lever_arm(pts, "D", "K", "M", variant)  # eq. (26)
    r_k = r_d * od / ok  # eq. (18)
    x_typo = D[0] if variant == "printed" else O[0]  # eq. (20) prints X_K - X_D; X_K - X_O is right
    r_oy = (r_d * kk * (D[1] - O[1]) - r_k * dd * (O[1] - K[1])) / (
        (D[0] - O[0]) * (O[1] - K[1]) + (K[0] - x_typo) * (D[1] - O[1])
    )  # eq. (20)
    r_ox = (r_oy * (D[0] - O[0]) + r_k * dd) / (D[1] - O[1])  # eq. (19)
    return {"R_K": r_k, "R_M": r_k, "R_OX": r_ox, "R_OY": r_oy}


def lower_link_reactions(pts: Points, r_bx: float, r_by: float, variant: Variant) -> dict[str, float]:
    """Lift-rod tension R_F = R_E and hinge A reaction R_AX, R_AY (N); eqs. (40)-(42)."""
    A, B, E, F = pts["A"], pts["B"], pts["E"], pts["F"]
    aa = lever_arm(pts, "A", "F", "E", variant)  # eq. (32)
    bb = lever_arm(pts, "B", "E", "F", variant)  # eq. (36)
    r_f = (r_by * (B[0] - A[0]) + r_bx * (B[1] - A[1])) / aa  # eq. (40)
    r_ax = r_bx - r_f * (F[0] - E[0]) / length(E, F)  # eq. (41)
    r_ay = (r_ax * (B[1] - A[1]) + r_f * bb) / (B[0] - A[0])  # eq. (42)
    return {"R_F": r_f, "R_E": r_f, "R_AX": r_ax, "R_AY": r_ay}


# Eqs. (61)-(63) have the form of the rocker's (18)-(20): each set as printed, checked equation by equation.
def lift_arm_reactions(pts: Points, r_e: float, variant: Variant) -> dict[str, float]:
    """Actuator push R_L and lift-arm pivot reaction R_O3X, R_O3Y (N); eqs. (61)-(63), O'' read O'''."""
    O3, E, L = pts["O3"], pts["E"], pts["L"]
    o3l = lever_arm(pts, "O3", "H", "L", variant)  # eq. (44)
    o3e = lever_arm(pts, "O3", "F", "E", variant)  # eq. (48)
    le = lever_arm(pts, "L", "F", "E", variant)  # eq. (52)
    el = lever_arm(pts, "E", "H", "L", variant)  # eq. (56)
    r_l = r_e * o3e / o3l  # eq. (61)
    r_o3x = (r_e * le * (E[0] - O3[0]) - r_l * el * (O3[0] - L[0])) / (
        (E[1] - O3[1]) * (O3[0] - L[0]) + (L[1] - O3[1]) * (E[0] - O3[0])
    )  # eq. (63)
    r_o3y = (r_e * le - r_o3x * (L[1] - O3[1])) / (O3[0] - L[0])  # eq. (62)
    return {"R_L": r_l, "R_O3X": r_o3x, "R_O3Y": r_o3y}


def sub_frame_reactions(
    pts: Points, r_m: float, r_ax: float, r_ay: float, variant: Variant
) -> dict[str, float]:
    """Element compression R_N and sub-frame pivot reaction R_O1X, R_O1Y (N); eqs. (65)-(72)."""
    O1, O2, A, K, M, N = (pts[n] for n in ("O1", "O2", "A", "K", "M", "N"))
    l_km = length(K, M)
    cos_d = (K[1] - M[1]) / l_km  # eq. (65): delta = arccos(cos_d)
    sin_d = float(np.sin(np.arccos(cos_d))) if variant == "printed" else (K[0] - M[0]) / l_km
    o1n = lever_arm(pts, "O1", "O2", "N", variant)  # eq. (66)
    r_n = (
        r_m * cos_d * (M[0] - O1[0]) + r_m * sin_d * (O1[1] - M[1]) - r_ay * (A[0] - O1[0]) + r_ax * (A[1] - O1[1])
    ) / o1n  # eq. (70)
    l_no2 = length(N, O2)
    r_o1x = r_m * sin_d + r_n * (O2[0] - N[0]) / l_no2 - r_ax  # eq. (71)
    r_o1y = r_n * (O2[1] - N[1]) / l_no2 + r_m * cos_d - r_ay  # eq. (72)
    return {"R_N": r_n, "R_O1X": r_o1x, "R_O1Y": r_o1y}


def hitch_reactions(pts: Points, r_x: float, r_y: float, variant: Variant) -> dict[str, float]:
    """All reactions of Khaliullin et al. 2023, link by link in the paper's order (N); eqs. (6)-(72)."""
    out = implement_reactions(pts, r_x, r_y, variant)
    out |= rocker_reactions(pts, out["R_D"], variant)
    out |= lower_link_reactions(pts, out["R_BX"], out["R_BY"], variant)
    out |= lift_arm_reactions(pts, out["R_E"], variant)
    out |= sub_frame_reactions(pts, out["R_M"], out["R_AX"], out["R_AY"], variant)
    return out
