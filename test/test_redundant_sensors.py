"""Redundant sensors: the linkage closes exactly and the sensors are fitted over its poses.

belarus_1221 measures the lift cylinder's length and the lift arm's angle, one more input than its
one degree of freedom. The monitor's rule (docs/architecture.md, "Redundant sensors"): every hinge
closes; among the closed poses, the one whose sensor readings are nearest the measured ones —
Σ (length − measured)² + (lc·(angle − measured))² least, lc the mechanism's length scale (m per
rad, the weight of an angle row). Oracles, none of them the fitting code:
- the constrained least-squares step against numpy's KKT system (Lagrange multipliers);
- the fitted pose against a sweep of the stroke-only mechanism (a square system, Newton): it is
  one of its closed poses, and its stroke is where the sensors' misfit along them is least
  (a zero derivative by central differences, a larger misfit on either side).
"""

from __future__ import annotations

import math

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from linkage_monitor.mechanics import Solver, kernels, load_preset
from linkage_monitor.mechanics.capacity import stroke_mechanism
from linkage_monitor.cli.simulate import NOISE_ANGLE, NOISE_LENGTH, NOISE_PRESSURE
from linkage_monitor.mechanics.results import Status, angle_readings
from linkage_monitor.monitoring.config import MonitorConfig
from linkage_monitor.monitoring.core import Monitor
from linkage_monitor.monitoring.findings import Code
from linkage_monitor.sim.telemetry import Noise, simulate

H = 1e-6   # m, central-difference step in the stroke


@settings(max_examples=60, deadline=None)
@given(n=st.integers(2, 12), dof=st.integers(1, 3), extra=st.integers(1, 3), seed=st.integers(0, 2**31))
def test_closed_step_is_the_constrained_least_squares_of_numpys_kkt_system(n: int, dof: int, extra: int,
                                                                            seed: int) -> None:
    """Rows [hard (n − dof); driving (dof); fitted (extra)]: the hard rows hold exactly, the others
    in least squares — the same x as the KKT system [AᵀA Cᵀ; C 0]·[x; λ] = [Aᵀb; d] solved by numpy."""
    dof = min(dof, n)
    rng = np.random.default_rng(seed)
    jac = rng.standard_normal((n + extra, n)) + np.eye(n + extra, n) * n
    rhs = rng.standard_normal(n + extra)
    n_hard = n - dof
    x = kernels.closed_step(jac, rhs, np.arange(n, dtype=np.int64), np.arange(n, n + extra, dtype=np.int64), n_hard)
    c, d = jac[:n_hard], rhs[:n_hard]
    a, b = jac[n_hard:], rhs[n_hard:]
    kkt = np.block([[a.T @ a, c.T], [c, np.zeros((n_hard, n_hard))]])
    expected = np.linalg.solve(kkt, np.concatenate([a.T @ b, d]))[:n]
    np.testing.assert_allclose(x, expected, rtol=1e-8, atol=1e-10)
    np.testing.assert_allclose(c @ x, d, atol=1e-10)


MECH = load_preset("belarus_1221")
FUSED, CLOSED = Solver(MECH, consistency_tol=20e-3), Solver(stroke_mechanism(MECH))
STROKE_REF, ANGLE_REF = FUSED.kin.reference_inputs()


def _misfit(stroke: np.ndarray, measured_stroke: float, measured_angle: float) -> np.ndarray:
    """m², the sensors' weighted misfit at the closed poses of the stroke-only mechanism."""
    angle = angle_readings(MECH, CLOSED.solve_batch(cylinders={"lift_cylinder": stroke}))["lift_arm_angle"]
    return (stroke - measured_stroke) ** 2 + (FUSED.kin.lc * (angle - measured_angle)) ** 2


@settings(max_examples=25, deadline=None)
@given(stretch=st.floats(0.97, 1.03), disagreement=st.floats(-0.03, 0.03))
def test_disagreeing_sensors_give_the_closed_pose_that_fits_them_best(stretch: float, disagreement: float) -> None:
    """Stroke and angle readings that disagree by up to 0.03 rad (~20 mm of stroke): the solved
    pose closes every hinge, is the stroke-only mechanism's pose at its own stroke, and that stroke
    minimises the misfit along the closed poses."""
    stroke, angle = STROKE_REF * stretch, ANGLE_REF + disagreement
    fused = FUSED.solve_batch(cylinders={"lift_cylinder": np.array([stroke])},
                              angles={"lift_arm_angle": np.array([angle])})
    assert fused.status[0] == Status.OK, fused.messages[0]
    state = FUSED.kin.solve(np.array([[stroke, angle]]), None, FUSED.dead_centre_cond, FUSED.consistency_tol)
    assert np.abs(state.phi[0, :2 * len(MECH.hinges)]).max() < 1e-12   # m: every hinge closed
    fitted = float(fused.cylinder_length["lift_cylinder"][0])
    closed = CLOSED.solve_batch(cylinders={"lift_cylinder": np.array([fitted])})
    for point in MECH.points:
        np.testing.assert_allclose(fused.points[point][0], closed.points[point][0], atol=1e-9)
    around = _misfit(np.array([fitted - H, fitted, fitted + H]), stroke, angle)
    slope, curvature = (around[2] - around[0]) / (2 * H), (around[0] - 2 * around[1] + around[2]) / H**2
    assert curvature > 0.0 and around[1] <= min(around[0], around[2])
    assert abs(slope / curvature) < 1e-8   # m: the least misfit this close to the fitted stroke (a Newton step)


def test_agreeing_sensors_give_the_pose_either_sensor_gives() -> None:
    """Readings taken from one closed pose: the fit leaves nothing, the pose is the stroke's."""
    strokes = STROKE_REF * np.linspace(0.97, 1.03, 7)
    closed = CLOSED.solve_batch(cylinders={"lift_cylinder": strokes})
    angles = angle_readings(MECH, closed)["lift_arm_angle"]
    fused = FUSED.solve_batch(cylinders={"lift_cylinder": strokes}, angles={"lift_arm_angle": angles})
    assert (fused.status == Status.OK).all()
    assert np.nanmax(fused.consistency_residual) < 1e-12   # m
    for point in MECH.points:
        np.testing.assert_allclose(fused.points[point], closed.points[point], atol=1e-10)


def _disagreements(angle_offset: float) -> tuple[int, int]:
    """(solved poses, those with a sensors_disagree WARN) of the monitoring core on a simulated lift
    of belarus_1221 with the simulator's default sensor noise, its angle sensor off by angle_offset."""
    stream = simulate(MECH, "lift", rate_hz=20.0, noise=Noise(NOISE_ANGLE, NOISE_LENGTH, NOISE_PRESSURE), seed=3,
                      start_ns=1_700_000_000_000_000_000)
    monitor = Monitor(MECH, MonitorConfig(mechanism=MECH.name, pressure_topics={"/pressure/lift_cap_pressure":
                                                                                 "lift_cap_pressure"},
                                          pressure_absolute=False, staleness_limit_s=3600.0, stamp_tolerance_s=1e9))
    names = list(stream.joint_names)
    angle_column = names.index("lift_arm_angle")
    solved = warned = 0
    for i, stamp in enumerate(stream.stamps_ns.tolist()):
        monitor.on_pressure("/pressure/lift_cap_pressure", float(stream.pressure_values[i, 0]), stamp, stamp)
        positions = stream.joint_positions[i].copy()
        positions[angle_column] += angle_offset
        step = monitor.on_joint_state(names, positions.tolist(), [], stamp, stamp)
        if step.pose is not None:
            solved += 1
            warned += any(f.code == Code.SENSORS_DISAGREE for f in step.findings)
    return solved, warned


def test_healthy_sensors_rarely_disagree_and_a_miscalibrated_angle_sensor_always_does() -> None:
    """The sensors_disagree WARN (monitoring.checks, CONSISTENCY_WARN_M) on the fit's misfit: quiet on
    healthy sensors with the simulator's default noise (a ~0.1° angle sensor, 0.5 mm stroke; on at
    most 1 % of the poses), on every pose when the angle sensor is off by 2° (a calibration error)."""
    solved, warned = _disagreements(0.0)
    assert solved > 100 and warned <= 0.01 * solved, (solved, warned)
    solved, warned = _disagreements(math.radians(2.0))
    assert solved > 100 and warned == solved, (solved, warned)
