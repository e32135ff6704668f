"""Lift capacity (linkage_monitor.mechanics.machine + capacity) against Popov 2009 and virtual work.

Production method: virtual work at the solved pose (mechanics.kernels.lift_capacity). Oracles: a
mechanism copy per capacity point solved on its own by the frozen numpy solver (oracles.capacity_copies), Popov 2009's G = p_max·η·A / I with I = dz_point/dS from central
differences of the kinematics (virtual work, weightless links), and Tables 1-2 of Popov 2009.
"""

from __future__ import annotations

import numpy as np
import pytest

from linkage_monitor.mechanics import Solver, load_preset
from linkage_monitor.mechanics.capacity import capacity_force, lift_cylinder, reference_length, stroke_mechanism
from linkage_monitor.mechanics.machine import MachineModel
from oracles.capacity_copies import capacity_copies

# Popov 2009 Table 1 (S [m], I_S [-]) and Table 2 (G_s [kN]): Popov (2009)
TABLE_S = np.array([0.535, 0.555, 0.575, 0.595, 0.615, 0.635, 0.655, 0.675, 0.695, 0.715])
TABLE_I_S = np.array([7.164, 6.647, 6.427, 6.343, 6.336, 6.369, 6.411, 6.426, 6.362, 6.148])
TABLE_G_S = np.array([23.03, 24.82, 25.67, 26.01, 26.04, 25.90, 25.73, 25.67, 25.93, 26.83])
STEP = 1e-5  # m, central-difference step in S


@pytest.fixture(scope="module")
def belarus() -> MachineModel:
    mech = stroke_mechanism(load_preset("belarus_1221"))
    return MachineModel(mech, Solver(mech))


def _points_610(batch) -> np.ndarray:
    """ISO 730 reading: 0.610 m from P56, perpendicular to the mast P56→P67, rearward when the mast is vertical."""
    hitch, mast = batch.points["P56"], batch.points["P67"]
    u = (mast - hitch) / np.linalg.norm(mast - hitch, axis=1, keepdims=True)
    return hitch + 0.610 * np.column_stack([-u[:, 1], u[:, 0]])


def _velocity_ratios(model: MachineModel, lengths: np.ndarray) -> dict[str, np.ndarray]:
    """I = dz/dS (-) of the hitch axis, the 610 mm point and the implement cg by central differences."""
    lo = model.stroke_poses("lift_cylinder", lengths - STEP)
    hi = model.stroke_poses("lift_cylinder", lengths + STEP)
    z = {"hitch_axis": lambda b: b.points["P56"][:, 1], "behind_610mm": lambda b: _points_610(b)[:, 1],
         "implement_cg": lambda b: b.implement_cg[:, 1]}
    return {k: (f(hi) - f(lo)) / (2 * STEP) for k, f in z.items()}


def test_statics_capacity_equals_virtual_work_capacity(belarus):
    """Popov 2009: G = p_max·η·A / I; the Belarus links are weightless, so virtual work is exact."""
    lengths = np.linspace(0.52, 0.71, 7)
    _, machine = belarus.capacity_curve("lift_cylinder", lengths)
    force = capacity_force(lift_cylinder(belarus.mech))
    for key, ratio in _velocity_ratios(belarus, lengths).items():
        np.testing.assert_allclose(machine.lift_capacity[key], force / ratio, rtol=1e-6, err_msg=key)


def test_capacity_point_610mm_is_on_the_implement(belarus):
    """The 610 mm point, moved with the implement, stays 0.610 m from P56 and perpendicular to the mast."""
    pts = belarus.capacity_points
    d = pts["behind_610mm"] - pts["hitch_axis"]
    mast = belarus.mech.points["P67"] - pts["hitch_axis"]
    np.testing.assert_allclose(np.hypot(*d), 0.610, rtol=1e-12)
    assert abs(np.dot(d, mast)) < 1e-12 and d[0] < 0.0  # perpendicular, behind the axis


def test_table2_lift_capacity_at_the_header_cg(belarus):
    """Popov 2009 Table 2: G_s = 165.0 kN / I_S, the capacity at the header's cg (docs/belarus-1221-geometry.md)."""
    _, machine = belarus.capacity_curve("lift_cylinder", TABLE_S)
    i_s = _velocity_ratios(belarus, TABLE_S)["implement_cg"]
    matches = np.abs(i_s - TABLE_I_S) < 0.01  # rows where the preset's kinematics match Table 1 (I_S to 0.01)
    ours = machine.lift_capacity["implement_cg"] / 1e3
    print("\nS [m]  I_S paper/ours   G_s paper  165/I_S(ours)  capacity@cg  error [kN]")
    for s, ip, io, g, c in zip(TABLE_S, TABLE_I_S, i_s, TABLE_G_S, ours):
        print(f"{s:.3f}  {ip:.3f} {io:.3f}   {g:6.2f}   {165.0 / io:8.3f}   {c:9.3f}   {c - g:+.3f}")
    assert matches.all(), f"Table 1 I_S not reproduced at S = {TABLE_S[~matches]}"
    # Table 2 itself is 165.0 kN / I_S to 4 digits (Popov 2009): check the paper's consistency first
    np.testing.assert_allclose(165.0 / TABLE_I_S, TABLE_G_S, atol=0.01)
    # p_max·η·A = 165.0 kN (preset: 19.384 MPa × 0.80 × 0.01064 m²)
    np.testing.assert_allclose(capacity_force(lift_cylinder(belarus.mech)) / 1e3, 165.0, rtol=1e-4)
    # ours vs the paper: the fitted geometry reproduces G_s within 0.013 kN (docs/belarus-1221-geometry.md);
    # allowed 0.05 kN = printed rounding 0.005 kN + the fit's I_S error up to 0.005 (0.02 kN)
    np.testing.assert_allclose(ours, TABLE_G_S, atol=0.05)


def test_axis_to_610mm_ratio_over_the_stroke(belarus):
    """Reported, not fitted: Belarus manuals give 30/18 = 1.67 (80.1/82.1) and 68/45 = 1.51 (1523)."""
    lengths = np.linspace(TABLE_S[0], TABLE_S[-1], 11)
    _, machine = belarus.capacity_curve("lift_cylinder", lengths)
    cap = machine.lift_capacity
    ratio = cap["hitch_axis"] / cap["behind_610mm"]
    print("\nS [m]  axis [kN]  610 mm [kN]  ratio (manuals: 1.67, 1.51)")
    for s, a, b, r in zip(lengths, cap["hitch_axis"], cap["behind_610mm"], ratio):
        print(f"{s:.3f}  {a / 1e3:8.2f}  {b / 1e3:10.2f}  {r:6.3f}")
    # the header tilts back while lifting (Table 1: phi6' > 0 in every row), so the point behind the axis
    # rises faster than the axis (larger I, smaller capacity)
    assert np.all(np.isfinite(ratio)) and np.all(ratio > 1.0)


def test_machine_summary_for_solve_json():
    """The two dicts `solve --json` prints; the preset's reference pose is Table 2's row S = 0.535 m."""
    from linkage_monitor.mechanics import Inputs
    from linkage_monitor.mechanics.machine import CAPACITY_KEYS, STEERABILITY_KEYS, machine_summary

    mech = load_preset("belarus_1221")
    solver = Solver(mech)
    ref = mech.reference_inputs
    summary = machine_summary(solver, solver.solve(Inputs(ref["cylinders"], ref["angles"], ref["pressures"])))
    assert set(summary) == {"lift_capacity", "steerability"}
    assert tuple(summary["lift_capacity"]) == CAPACITY_KEYS
    assert tuple(summary["steerability"]) == STEERABILITY_KEYS
    assert abs(summary["lift_capacity"]["implement_cg"] / 1e3 - 23.03) < 0.05  # Table 2, G_s at S = 0.535 m
    # docs/belarus-1221-geometry.md: R_A = 22.2 kN, k = 0.254 (header 15.0 kN; the pressure 10.132 MPa estimates 15.05 kN)
    assert abs(summary["steerability"]["front_axle_load"] / 1e3 - 22.2) < 0.1
    assert abs(summary["steerability"]["ratio"] - 0.254) < 0.002


def test_no_negative_capacity_where_the_cylinder_lowers_the_point():
    """Akhmetov & Usmanov 2018's base-change cylinder pushes the front axle down, not up: its 'implement' (the
    axle load) has no lift capacity; the summary says None instead of a negative load."""
    from linkage_monitor.mechanics import Inputs, Solver, load_preset
    from linkage_monitor.mechanics.machine import machine_summary

    mech = load_preset("ttz1080_base_change")
    solver = Solver(mech)
    result = solver.solve(Inputs(cylinders=dict(mech.reference_inputs["cylinders"])))
    assert result.cylinders["base_change_cylinder"].force > 0.0  # pushing holds the axle load
    assert machine_summary(solver, result)["lift_capacity"]["implement_cg"] is None


@pytest.mark.parametrize("preset", ["belarus_1221", "damping_hitch", "ttz1080_base_change"])
def test_capacity_by_virtual_work_equals_solving_each_capacity_copy(preset):
    """The oracle: each capacity copy solved as a mechanism of its own by the numpy solver (its own
    loop closure from the measured inputs read back from the pose, then its statics), against
    virtual work at the already solved pose — to 1e-9 over the stroke."""
    mech = load_preset(preset)
    stroke = stroke_mechanism(mech)
    model = MachineModel(stroke, Solver(stroke))
    cyl = lift_cylinder(mech).name
    length = reference_length(mech, cyl)
    batch = model.stroke_poses(cyl, np.linspace(0.97, 1.08, 25) * length)
    got = model.evaluate_batch(batch).lift_capacity
    lengths = {c: batch.cylinder_length[c] for c in stroke.measurements.cylinders}
    for name, (copy, pressures) in capacity_copies(stroke).items():
        oracle = copy.solve_batch(cylinders=lengths, pressures=pressures)
        expected = np.where(oracle.implement_load > 0.0, oracle.implement_load, np.nan)
        np.testing.assert_allclose(got[name], expected, rtol=1e-9, equal_nan=True)
        assert np.isfinite(got[name]).any() or preset == "ttz1080_base_change"
