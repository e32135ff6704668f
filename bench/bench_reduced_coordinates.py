"""How fast would reduced coordinates be? A measurement for issue 11's choice, not a second solver.

Run: .venv/bin/python bench/bench_reduced_coordinates.py

belarus_1221's hitch, stroke measured only (as bench/bench_solver.py's batch), decomposed by hand
into the chain of dyads a textbook (and seed 003) solves it with:
- kinematics: the lift arm's angle from the lift cylinder's length (law of cosines in the
  triangle P01-P03-P23), then two circle intersections: P45 (lift rod about P34, lower link
  about P05) and P67 (top link about P07, mast about P56), each on the reference pose's branch;
- statics (the implement's weight, weightless links): implement (moment about P56 gives the top
  link's axial force), lower link (moment about P05: the lift rod's), lift arm (moment about P03:
  the cylinder's) — three scalar equations and three force sums, no linear system.
The package's own batched path (`Solver.solve_batch`, the general 15-coordinate formulation)
is the oracle for every number it prints (largest differences below), and its compiled kernels
alone, and numpy's batched 15x15 solve, are timed in the same run as baselines.

What this prototype does not do (the general solver does): any mechanism from its YAML (an
Assur-group decomposition of the schema's bodies, hinges and cylinders would be needed),
redundant sensors (fitted over the closed loop: `lift_arm_fit` here shows the rule), contacts, springs, kinetostatics, exact condition numbers
for the dead-centre verdict (here only the dyads' own denominators), lift capacity.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import numba
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_solver import best_of, stroke_only  # noqa: E402

from linkage_monitor.bag.reader import JointStateColumns, read_inputs  # noqa: E402
from linkage_monitor.mechanics import Solver, Status, kernels, load_mechanism, load_preset, preset_names  # noqa: E402
from linkage_monitor.mechanics.constants import ATMOSPHERIC_PRESSURE  # noqa: E402
from linkage_monitor.mechanics.results import angle_readings  # noqa: E402

HINGES = ("P03", "P34", "P45", "P05", "P56", "P07", "P67")   # output columns, the preset's hinge order


@numba.njit(cache=True)
def _circles(a: np.ndarray, ra: float, b: np.ndarray, rb: float, side: float) -> tuple[float, float, float]:
    """The point at ``ra`` from a and ``rb`` from b on ``side`` (sign of cross(b - a, p - a)); h (m)."""
    dx, dz = b[0] - a[0], b[1] - a[1]
    d = np.hypot(dx, dz)
    along = (ra * ra - rb * rb + d * d) / (2.0 * d)
    h = np.sqrt(ra * ra - along * along) * side
    return a[0] + (along * dx - h * dz) / d, a[1] + (along * dz + h * dx) / d, h


@numba.njit(cache=True)
def dyads(stroke: np.ndarray, g: np.ndarray, out: np.ndarray) -> None:
    """Points and hinge forces of each pose; g = the geometry (``geometry``); out (N, 2 * 7 + 1)."""
    p01, p03, p05, p07 = g[0:2], g[2:4], g[4:6], g[6:8]
    d_01, alpha, r23, r34, off34 = g[8], g[9], g[10], g[11], g[12]
    rod, r45, side45, top, mast, side67 = g[13], g[14], g[15], g[16], g[17], g[18]
    lower_ref, r56, off56, implement_ref, r6, off6, weight, side23 = g[19], g[20], g[21], g[22], g[23], g[24], g[25], g[26]
    p34 = np.empty(2)
    p56 = np.empty(2)
    for i in range(stroke.shape[0]):
        s = stroke[i]
        # lift arm: triangle P01-P03-P23 (law of cosines), its angle from the cylinder's length
        phi23 = alpha + side23 * np.arccos((d_01 * d_01 + r23 * r23 - s * s) / (2.0 * d_01 * r23))
        x23, z23 = p03[0] + r23 * np.cos(phi23), p03[1] + r23 * np.sin(phi23)
        p34[0], p34[1] = p03[0] + r34 * np.cos(phi23 + off34), p03[1] + r34 * np.sin(phi23 + off34)
        # dyad 1: lift rod (about P34) and lower link (about P05) meet at P45
        x45, z45, _ = _circles(p34, rod, p05, r45, side45)
        turn = np.arctan2(z45 - p05[1], x45 - p05[0]) - lower_ref
        p56[0], p56[1] = p05[0] + r56 * np.cos(turn + off56), p05[1] + r56 * np.sin(turn + off56)
        # dyad 2: top link (about P07) and the implement's mast (about P56) meet at P67
        x67, z67, _ = _circles(p07, top, p56, mast, side67)
        turn6 = np.arctan2(z67 - p56[1], x67 - p56[0]) - implement_ref
        x6, z6 = p56[0] + r6 * np.cos(turn6 + off6), p56[1] + r6 * np.sin(turn6 + off6)
        # implement: moment about P56 -> top link force t (along P07->P67), then the force at P56
        ux, uz = (x67 - p07[0]) / top, (z67 - p07[1]) / top
        t = (x6 - p56[0]) * weight / ((x67 - p56[0]) * uz - (z67 - p56[1]) * ux)
        f56x, f56z = -t * ux, weight - t * uz
        # lower link: moment about P05 -> lift rod force r (along P34->P45), then the frame's force
        vx, vz = (x45 - p34[0]) / rod, (z45 - p34[1]) / rod
        r = ((p56[0] - p05[0]) * f56z - (p56[1] - p05[1]) * f56x) / ((x45 - p05[0]) * vz - (z45 - p05[1]) * vx)
        f05x, f05z = f56x - r * vx, f56z - r * vz
        # lift arm: moment about P03 -> cylinder force f (along P01->P23), then the frame's force
        cx, cz = (x23 - p01[0]) / s, (z23 - p01[1]) / s
        f = ((p34[0] - p03[0]) * r * vz - (p34[1] - p03[1]) * r * vx) / ((x23 - p03[0]) * cz - (z23 - p03[1]) * cx)
        row = out[i]
        row[0], row[1] = r * vx - f * cx, r * vz - f * cz      # P03: on the lift arm from the frame
        row[2], row[3] = r * vx, r * vz                        # P34: on the lift rod from the lift arm
        row[4], row[5] = r * vx, r * vz                        # P45: on the lower link from the lift rod
        row[6], row[7] = f05x, f05z                            # P05: on the lower link from the frame
        row[8], row[9] = f56x, f56z                            # P56: on the implement from the lower link
        row[10], row[11] = t * ux, t * uz                      # P07: on the top link from the frame
        row[12], row[13] = t * ux, t * uz                      # P67: on the implement from the top link
        row[14] = f


def geometry(mech) -> np.ndarray:
    """The dyad chain's constants from the preset's reference pose (lengths, offsets, branches)."""
    p = {k: np.asarray(v, dtype=float) for k, v in mech.points.items()}

    def angle(a: str, b: str) -> float:
        return float(np.arctan2(*(p[b] - p[a])[::-1]))

    def dist(a: str, b: str) -> float:
        return float(np.hypot(*(p[b] - p[a])))

    def side(a: str, b: str, c: str) -> float:   # sign of cross(b - a, c - a)
        u, w = p[b] - p[a], p[c] - p[a]
        return float(np.sign(u[0] * w[1] - u[1] * w[0]))

    alpha, phi23 = angle("P03", "P01"), angle("P03", "P23")
    side23 = float(np.sign(np.sin(phi23 - alpha)))
    weight = mech.body("implement").mass * mech.gravity   # N, the only body with a mass
    return np.array([*p["P01"], *p["P03"], *p["P05"], *p["P07"],
                     dist("P03", "P01"), alpha, dist("P03", "P23"), dist("P03", "P34"), angle("P03", "P34") - phi23,
                     dist("P34", "P45"), dist("P05", "P45"), side("P34", "P05", "P45"),
                     dist("P07", "P67"), dist("P56", "P67"), side("P07", "P56", "P67"),
                     angle("P05", "P45"), dist("P05", "P56"), angle("P05", "P56"),
                     angle("P56", "P67"), dist("P56", "S6"), angle("P56", "S6"), weight, side23, phi23])


def lift_arm_fit(stroke_m: np.ndarray, angle_m: np.ndarray, g: np.ndarray, reference_angle: float,
                 lc: float) -> np.ndarray:
    """The stroke of the closed loop that best fits both sensors: minimises (s - s_m)^2 +
    (lc * (angle(s) - angle_m))^2 over the one free coordinate (the package's weighting of an angle
    row: lc metres per radian), by Gauss-Newton from the measured stroke. angle(s): the lift arm's
    rotation from the reference pose (law of cosines) plus the sensor's reading there."""
    d_01, alpha, r23, side23 = g[8], g[9], g[10], g[26]
    phi_ref = g[27]   # rad, the reference points' P03->P23 angle

    def angle(s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        c = (d_01 * d_01 + r23 * r23 - s * s) / (2.0 * d_01 * r23)
        return alpha + side23 * np.arccos(c), side23 * s / (d_01 * r23 * np.sqrt(1.0 - c * c))

    s = stroke_m.copy()
    for _ in range(8):
        phi, dphi = angle(s)
        miss = np.angle(np.exp(1j * (reference_angle + phi - phi_ref - angle_m)))   # rad, wrapped
        s -= ((s - stroke_m) + lc * lc * miss * dphi) / (1.0 + (lc * dphi) ** 2)
    return s


def fusion_difference(bag: Path) -> None:
    """The redundant sensors' fusion on a recording, on the same poses and pressures: the package's
    fit of stroke + lift-arm angle (all 15 coordinates, every hinge closed, the sensors in least
    squares: ``kernels.closed_step``) against (a) the stroke alone with the loop closed exactly (a
    dyad chain driven by the stroke) and (b) the loop closed exactly at the stroke that best fits
    both sensors (``lift_arm_fit``: what a dyad chain fitting its one coordinate gives) — (b) is the
    same rule computed another way, so it should agree to rounding."""
    columns = read_inputs(bag)
    joints = next(c for c in columns.values() if isinstance(c, JointStateColumns))
    pressure = next(c for c in columns.values() if not isinstance(c, JointStateColumns))
    stroke = joints.position[:, joints.names.index("lift_cylinder")]
    angle = joints.position[:, joints.names.index("lift_arm_angle")]
    gauge = {"lift_cap_pressure": np.interp(joints.stamp_ns, pressure.stamp_ns, pressure.fluid_pressure)
             - ATMOSPHERIC_PRESSURE}
    mech = load_preset("belarus_1221")
    fused_solver, closed_solver = Solver(mech), Solver(stroke_only(mech))
    fused = fused_solver.solve_batch(cylinders={"lift_cylinder": stroke}, angles={"lift_arm_angle": angle},
                                     pressures=gauge)
    fitted = lift_arm_fit(stroke, angle, geometry(mech), mech.measurements.angles[0].reference, fused_solver.kin.lc)
    print(f"{bag.name}: {len(stroke)} poses; the sensors' misfit (kinematic residual) median "
          f"{1e3 * np.nanmedian(fused.consistency_residual):.2f} mm, largest {1e3 * np.nanmax(fused.consistency_residual):.2f} mm")
    # the fit's own check: readings that agree (the angle the closed loop gives at each stroke) return the stroke
    agreeing = angle_readings(mech, closed_solver.solve_batch(cylinders={"lift_cylinder": stroke}))["lift_arm_angle"]
    self_check = np.abs(lift_arm_fit(stroke, agreeing, geometry(mech), mech.measurements.angles[0].reference,
                                     fused_solver.kin.lc) - stroke).max()
    print(f"  (lift_arm_fit on agreeing readings returns the stroke to {self_check:.1g} m)")
    for label, s_closed in (("the stroke alone, loop closed", stroke), ("the best-fitting stroke, loop closed", fitted)):
        closed = closed_solver.solve_batch(cylinders={"lift_cylinder": s_closed}, pressures=gauge)
        ok = (fused.status < Status.INPUT) & (closed.status < Status.INPUT)
        share = max(float((np.hypot(*(fused.hinge_force[h][ok] - closed.hinge_force[h][ok]).T)
                           / np.hypot(*fused.hinge_force[h][ok].T)).max()) for h in HINGES)
        hitch = 1e3 * float(np.hypot(*(fused.points["P56"][ok] - closed.points["P56"][ok]).T).max())
        print(f"  the package's fit against {label}: hinge forces differ by up to {share:.2g} of the "
              f"hinge's force, the hitch point P56 by up to {hitch:.2g} mm ({int(ok.sum())} poses)")


def main() -> int:
    mech = stroke_only(load_preset("belarus_1221"))
    solver = Solver(mech)
    g = geometry(mech)
    n = 100_000
    length0 = solver.kin.reference_inputs()[0]
    strokes = length0 * np.random.default_rng(0).uniform(0.97, 1.03, n)
    out = np.empty((n, 15))
    dyads(strokes[:10], g, out[:10])   # compile (or load from the cache)

    # the oracle: the package's general path on a sample of the same poses
    sample = strokes[:2000]
    batch = solver.solve_batch(cylinders={"lift_cylinder": sample})
    assert (batch.status == 0).all(), "every sampled pose should solve"
    dyads(sample, g, out[:2000])
    scale = max(np.abs(batch.hinge_force[h]).max() for h in HINGES)
    force_error = max(np.abs(out[:2000, 2 * k:2 * k + 2] - batch.hinge_force[h]).max() for k, h in enumerate(HINGES))
    cyl_error = np.abs(out[:2000, 14] - batch.cylinder_force["lift_cylinder"]).max()
    print(f"belarus_1221, stroke only, {len(sample)} poses within +-3 % of the reference stroke, against "
          "Solver.solve_batch (general path):")
    print(f"  largest hinge force difference {force_error:.3g} N ({force_error / scale:.2g} of the largest, "
          f"{scale / 1e3:.1f} kN); cylinder force {cyl_error:.3g} N")

    numba.set_num_threads(1)
    t_dyads = best_of(lambda: dyads(strokes, g, out), 5)
    kin, layout = solver.kin, solver.statics_layout(frozenset())
    s_in = strokes[:, None]

    def general_kernels() -> None:
        q = kin.continue_from(kin.reference, s_in)[0]
        points, _ = kin.positions(q)
        kernels.solve_statics(points, np.zeros((n, len(mech.cylinders))), np.zeros((1, 1, 2)), np.zeros((1, 1)),
                              False, layout.n_unknowns, *layout.program)

    t_general = best_of(general_kernels, 2)
    numba.set_num_threads(numba.config.NUMBA_NUM_THREADS)
    n_sys = solver.kin.n
    a = np.random.default_rng(1).standard_normal((n, n_sys, n_sys)) + n_sys * np.eye(n_sys)
    b = np.random.default_rng(2).standard_normal((n, n_sys, 1))
    t_np = best_of(lambda: np.linalg.solve(a, b), 3)
    print(f"{n} poses, kinematics + statics, 1 thread:")
    print(f"  dyad chain (this prototype)                 {n / t_dyads / 1e6:7.2f} M poses/s  "
          f"{t_dyads / n * 1e9:6.0f} ns/pose")
    print(f"  the package's compiled kernels (general)    {n / t_general / 1e6:7.2f} M poses/s  "
          f"{t_general / n * 1e9:6.0f} ns/pose")
    print(f"  numpy batched {n_sys}x{n_sys} np.linalg.solve (baseline) {n / t_np / 1e6:7.2f} M solves/s")
    one_stroke, one_out = strokes[:1].copy(), out[:1]
    t_one = best_of(lambda: [dyads(one_stroke, g, one_out) for _ in range(2000)], 5) / 2000
    a1, b1 = a[0], b[0]
    t_np1 = best_of(lambda: [np.linalg.solve(a1, b1) for _ in range(2000)], 5) / 2000
    print(f"one pose per call: dyad chain {t_one * 1e6:.2f} us (numba's call overhead included), "
          f"one {n_sys}x{n_sys} np.linalg.solve {t_np1 * 1e6:.2f} us: {t_one / t_np1:.2f}x (goal <= 1x)")
    print(f"ratios: dyads / general kernels {t_general / t_dyads:.1f}x faster; dyads vs numpy's batched solve "
          f"{t_np / t_dyads:.1f}x faster (goal >= 10x, >= 2 M poses/s)")
    print("the reach of a dyad chain: how each shipped preset and test fixture decomposes from its measured inputs")
    fixtures = Path(__file__).resolve().parents[1] / "test" / "fixtures"
    for mechanism in [load_preset(name) for name in preset_names()] + [load_mechanism(f) for f in
                                                                       sorted(fixtures.glob("*.yaml"))]:
        kin = Solver(mechanism).kin   # the package's own decomposition (mechanics/chain.py)
        redundant = [kin.row_names[r] for r in kin.fit_rows]
        print(f"  {mechanism.name:<20} {'; '.join(kin.chain_steps) or 'NOT A CHAIN'}"
              + (f"; redundant: {', '.join(redundant)}" if redundant else ""))
    print("redundant sensors on the bundled bag (the package's fit against a dyad chain's):")
    fusion_difference(Path(__file__).resolve().parents[1] / "bags" / "belarus_1221_lift_transport")
    return 0


if __name__ == "__main__":
    sys.exit(main())
