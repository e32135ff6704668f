"""Khaliullin et al. 2023 oracle: the general solver on the `damping_hitch` preset vs the paper's closed forms.

The closed forms (test/oracles/khaliullin2023.py, Khaliullin et al. 2023, eqs. 6-72) are derived
link by link by hand; the solver assembles one global system. Where the printed formulas
are right they must agree to round-off; where they are wrong (eq. 20's typo, Heron arms and
arccos losing a sign) the tests assert the error the derivation in
docs/damping-hitch-closed-forms.md predicts.
"""

from __future__ import annotations

import copy

import numpy as np
import pytest
import yaml
from hypothesis import given, settings
from hypothesis import strategies as st

from linkage_monitor.mechanics import Inputs, Solver, mechanism_from_dict, preset_path
from oracles import khaliullin2023 as oracle

PRESET = yaml.safe_load(preset_path("damping_hitch").read_text(encoding="utf-8"))
POINT_NAMES = sorted(PRESET["points"])
RTOL = 1e-9  # relative to the largest force of the pose: both sides are exact up to round-off


def hitch(points_xz: dict[str, list[float]], r_x: float, r_y: float) -> dict:
    """The preset with other points and the paper's implement load (R_X rearward, R_Y down, N) at G."""
    data = copy.deepcopy(PRESET)
    data["points"] = points_xz
    data["implement"]["mass"] = 0.0
    data["loads"] = [{"name": "implement_load", "body": "implement", "point": "G", "force": [-r_x, -r_y]}]
    data.pop("reference_inputs")
    return data


def solve(data: dict):
    """Solver result in the pose of the file's points (cylinder lengths taken from them)."""
    p = {k: np.asarray(v, dtype=float) for k, v in data["points"].items()}
    lengths = {"lift_cylinder": float(np.hypot(*(p["L"] - p["H"]))),
               "damping_element": float(np.hypot(*(p["N"] - p["O2"])))}
    return Solver(mechanism_from_dict(data)).solve(Inputs(cylinders=lengths))


def solver_forces_paper(res) -> dict[str, np.ndarray]:
    """The solver's hinge reactions (force on bodies[1] from bodies[0]) in the paper frame, N."""
    return {name: np.array([-h.fx, h.fz]) for name, h in res.hinges.items()}


def oracle_forces_paper(pts: oracle.Points, r: dict[str, float]) -> dict[str, np.ndarray]:
    """The paper's reactions as the forces the preset's hinges report (paper frame, N).

    Each line is the paper's sign convention (oracle docstring) applied to the preset's
    `hinges[].bodies` order, e.g. hinge B is [lower_link, implement]: the lower link pushes
    the implement with (-R_BX, R_BY); hinge C is [top_link, implement]: tension R_C pulls C
    towards D.
    """
    def along(tail: str, head: str, magnitude: float) -> np.ndarray:
        d = pts[head] - pts[tail]
        return magnitude * d / np.hypot(*d)

    return {
        "B": np.array([-r["R_BX"], r["R_BY"]]),
        "C": along("C", "D", r["R_C"]),
        "D": along("D", "C", r["R_D"]),
        "O": np.array([r["R_OX"], r["R_OY"]]),
        "K": along("M", "K", r["R_K"]),
        "M": along("K", "M", r["R_M"]),
        "A": np.array([r["R_AX"], r["R_AY"]]),
        "O1": np.array([r["R_O1X"], r["R_O1Y"]]),
        "F": along("F", "E", r["R_F"]),
        "E": along("E", "F", r["R_E"]),
        "O3": np.array([r["R_O3X"], r["R_O3Y"]]),
    }


def perturbed(offsets: list[float]) -> dict[str, list[float]]:
    """Preset points moved by `offsets` (m), two per point in POINT_NAMES order."""
    return {n: [PRESET["points"][n][0] + offsets[2 * i], PRESET["points"][n][1] + offsets[2 * i + 1]]
            for i, n in enumerate(POINT_NAMES)}


# Perturbations of +-15 mm keep the preset's orientation (every signed arm of the corrected
# forms stays positive, K stays behind M): there the printed Heron arms are right.
offsets_15mm = st.lists(st.floats(-0.015, 0.015), min_size=2 * len(POINT_NAMES), max_size=2 * len(POINT_NAMES))
loads = st.tuples(st.floats(-5e3, 30e3), st.floats(0.0, 20e3))  # R_X (draft, N), R_Y (weight minus soil support, N)


@settings(max_examples=25, deadline=None)
@given(offsets=offsets_15mm, load=loads)
def test_solver_equals_the_closed_forms_around_the_preset_pose(offsets, load):
    """Every hinge and both members: solver == corrected forms; == printed forms except R_O (eq. 20)."""
    data = hitch(perturbed(offsets), *load)
    pts = oracle.paper_frame(data["points"])
    arms = [("B", "C", "D"), ("O", "D", "C"), ("O", "K", "M"), ("K", "D", "C"), ("D", "K", "M"), ("A", "F", "E"),
            ("B", "E", "F"), ("O3", "H", "L"), ("O3", "F", "E"), ("L", "F", "E"), ("E", "H", "L"), ("O1", "O2", "N")]
    assert all(oracle.lever_arm(pts, *a, "corrected") > 0 for a in arms), "premise: the figure's orientation"
    assert pts["K"][0] > pts["M"][0], "premise: sin(delta) > 0"

    res = solve(data)
    got = solver_forces_paper(res)
    corrected = oracle.hitch_reactions(pts, *load, "corrected")
    printed = oracle.hitch_reactions(pts, *load, "printed")
    scale = max(abs(v) for v in corrected.values())
    for name, expected in oracle_forces_paper(pts, corrected).items():
        np.testing.assert_allclose(got[name], expected, rtol=0, atol=RTOL * scale, err_msg=f"hinge {name}")
    for name, expected in oracle_forces_paper(pts, printed).items():
        if name != "O":  # eq. (20) typo, see test_eq20_typo
            np.testing.assert_allclose(got[name], expected, rtol=0, atol=RTOL * scale, err_msg=f"hinge {name}")
    for member, key in (("lift_cylinder", "R_L"), ("damping_element", "R_N")):
        assert res.cylinders[member].force == pytest.approx(corrected[key], abs=RTOL * scale)
        assert res.cylinders[member].force == pytest.approx(printed[key], abs=RTOL * scale)


def test_eq20_typo_x_d_for_x_o():
    """Eq. (20) (third line of eq. 9) has X_K - X_D where the moment about K needs X_K - X_O.

    Its numerator is right, so the printed R_OY is the true one times den_true/den_printed,
    den = (X_D - X_O)(Y_O - Y_K) + (X_K - X_?)(Y_D - Y_O); the typo vanishes when X_D = X_O.
    """
    r_x, r_y = 12e3, 700 * 9.80665  # the preset's draft and weight
    data = hitch(copy.deepcopy(PRESET["points"]), r_x, r_y)
    pts = oracle.paper_frame(data["points"])
    got = solver_forces_paper(solve(data))["O"]
    printed = oracle.hitch_reactions(pts, r_x, r_y, "printed")
    O, D, K = pts["O"], pts["D"], pts["K"]
    den_true = (D[0] - O[0]) * (O[1] - K[1]) + (K[0] - O[0]) * (D[1] - O[1])
    den_printed = (D[0] - O[0]) * (O[1] - K[1]) + (K[0] - D[0]) * (D[1] - O[1])
    assert printed["R_OY"] == pytest.approx(got[1] * den_true / den_printed, rel=1e-9)
    assert abs(printed["R_OY"] / got[1] - 1.0) > 0.05  # X_D - X_O = 20 mm: a 10 % error

    # D straight below O (X_D = X_O): the printed eq. (20) is right
    data["points"]["D"] = [data["points"]["O"][0], data["points"]["D"][1]]
    pts = oracle.paper_frame(data["points"])
    got = solver_forces_paper(solve(data))["O"]
    printed = oracle.hitch_reactions(pts, r_x, r_y, "printed")
    np.testing.assert_allclose([printed["R_OX"], printed["R_OY"]], got, rtol=1e-9)


def test_heron_arm_loses_the_sign_of_the_lift_cylinder_force():
    """Base H moved below L: the cylinder's line passes on the other side of the pivot O3.

    Its true moment about O3 changes sign, so it must pull; Heron's unsigned arm O'''l
    (eq. 44) keeps R_L (eq. 61) positive: the printed R_L is exactly minus the true force.
    """
    r_x, r_y = 12e3, 700 * 9.80665
    points = copy.deepcopy(PRESET["points"])
    points["H"] = [-0.35, 0.80]  # cylinder from below, pushing up and rearward (assumed)
    data = hitch(points, r_x, r_y)
    pts = oracle.paper_frame(points)
    assert oracle.lever_arm(pts, "O3", "H", "L", "corrected") < 0  # the premise: the arm changed sign
    force = solve(data).cylinders["lift_cylinder"].force
    printed = oracle.hitch_reactions(pts, r_x, r_y, "printed")["R_L"]
    assert force < 0
    assert printed == pytest.approx(-force, rel=1e-9)


def test_arccos_loses_the_sign_of_sin_delta():
    """M moved behind K: sin(delta) = (X_K - X_M)/l_KM < 0, but arccos in eq. (65) gives |sin|.

    Eq. (70) then errs by 2 R_M |sin(delta)| (Y_O' - Y_M) / O'n (its R_M sin(delta) term
    with the wrong sign); everything upstream of the sub-frame stays right.
    """
    r_x, r_y = 12e3, 700 * 9.80665
    points = copy.deepcopy(PRESET["points"])
    points["M"] = [-0.78, 0.86]  # 40 mm behind K instead of 40 mm ahead (assumed)
    data = hitch(points, r_x, r_y)
    pts = oracle.paper_frame(points)
    res = solve(data)
    printed = oracle.hitch_reactions(pts, r_x, r_y, "printed")
    K, M, O1 = pts["K"], pts["M"], pts["O1"]
    sin_abs = abs(K[0] - M[0]) / np.hypot(*(K - M))
    o1n = oracle.lever_arm(pts, "O1", "O2", "N", "printed")
    expected_error = 2.0 * printed["R_M"] * sin_abs * (O1[1] - M[1]) / o1n
    assert printed["R_M"] == pytest.approx(np.hypot(res.hinges["M"].fx, res.hinges["M"].fz), rel=1e-9)
    assert printed["R_N"] - res.cylinders["damping_element"].force == pytest.approx(expected_error, rel=1e-9)
    assert abs(expected_error) > 0.1 * abs(res.cylinders["damping_element"].force)


def test_element_pressure_gives_back_the_implement_weight():
    """The element's cap pressure set to the closed-form R_N / A_cap (eq. 70, preset pose, 700 kg
    and 12 kN draft): the solver's estimated vertical implement load is the weight 700 g
    (the preset's assumed mass) and its lift-cylinder force is eq. (61)'s R_L."""
    r_x, weight = 12e3, 700.0 * 9.80665
    data = copy.deepcopy(PRESET)
    p = {k: np.asarray(v, dtype=float) for k, v in data["points"].items()}
    closed = oracle.hitch_reactions(oracle.paper_frame(data["points"]), r_x, weight, "corrected")
    bore = data["cylinders"][1]["bore"]
    assert data["cylinders"][1]["name"] == "damping_element"
    inputs = Inputs(cylinders={"lift_cylinder": float(np.hypot(*(p["L"] - p["H"]))),
                               "damping_element": float(np.hypot(*(p["N"] - p["O2"])))},
                    pressures={"element_cap_pressure": closed["R_N"] / (np.pi * bore**2 / 4.0)})
    res = Solver(mechanism_from_dict(data)).solve(inputs)
    assert res.implement_load == pytest.approx(weight, rel=1e-9)
    assert res.cylinders["lift_cylinder"].force == pytest.approx(closed["R_L"], rel=1e-9)
