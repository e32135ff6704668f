"""Statics in reduced coordinates (mechanics/reduced.py) against the general formulation, timed in
the same run. Run: .venv/bin/python bench/bench_reduced_coordinates.py

belarus_1221, stroke measured only (as bench/bench_solver.py's batch), 100,000 poses within ±3 % of
the reference stroke, one thread: the pose from the chain of dyads (``Kinematics.continue_from``;
the general path also computes the constraint Jacobian's condition number, its kinematic verdict,
which the reduced path leaves to the transmission measure), then the statics either by the general path (``kernels.solve_statics``: the
15×15 equilibrium system per pose, LU and its exact 1-norm condition number, the dead-centre
verdict) or in reduced coordinates (``kernels.solve_reduced_statics``: moment equations about each
dyad's hinges, no linear system, the transmission measure as the verdict). The general path is the
oracle for every number (largest difference printed); numpy's batched 15×15 solve and one
``np.linalg.solve`` are the baselines. Then which path every preset and test fixture takes.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numba
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_solver import best_of, stroke_only  # noqa: E402

from linkage_monitor.mechanics import Solver, kernels, load_mechanism, load_preset, preset_names  # noqa: E402
from linkage_monitor.mechanics.reduced import ReducedStatics  # noqa: E402

N_POSES = 100_000
NO_ACCEL = (np.zeros((1, 1, 2)), np.zeros((1, 1)))   # not read: no inertia loads


def main() -> int:
    solver = Solver(stroke_only(load_preset("belarus_1221")))
    kin, layout = solver.kin, solver.statics_layout(frozenset())
    reduced = ReducedStatics(kin, layout)
    strokes = kin.reference_inputs()[0] * np.random.default_rng(0).uniform(0.97, 1.03, N_POSES)
    q = kin.continue_from(kin.reference, strokes[:, None])[0]
    p, _ = kin.positions(q)
    member_force = np.zeros((N_POSES, layout.member_att.shape[1]))

    def general() -> tuple[np.ndarray, ...]:
        return kernels.solve_statics(p, member_force, *NO_ACCEL, False, layout.n_unknowns, layout.program)

    def in_reduced() -> tuple[np.ndarray, ...]:
        return kernels.solve_reduced_statics(p, member_force, *NO_ACCEL, False, layout.n_unknowns, layout.program,
                                             reduced.program)

    u_general, u_reduced = general()[0], in_reduced()[0]   # compile (or load from the cache), and the oracle
    largest = np.abs(u_general).max()
    print(f"belarus_1221, stroke only, {N_POSES} poses within ±3 % of the reference stroke: reduced against general "
          f"statics, largest difference {np.abs(u_reduced - u_general).max():.3g} N "
          f"({np.abs(u_reduced - u_general).max() / largest:.2g} of the largest force, {largest / 1e3:.1f} kN)")
    numba.set_num_threads(1)
    t_general, t_reduced = best_of(general, 3), best_of(in_reduced, 5)
    t_kinematics = best_of(lambda: kin.positions(kin.continue_from(kin.reference, strokes[:, None], False)[0]), 3)
    t_kinematics_cond = best_of(lambda: kin.positions(kin.continue_from(kin.reference, strokes[:, None])[0]), 3)
    numba.set_num_threads(numba.config.NUMBA_NUM_THREADS)
    n_sys = kin.n
    a = np.random.default_rng(1).standard_normal((N_POSES, n_sys, n_sys)) + n_sys * np.eye(n_sys)
    b = np.random.default_rng(2).standard_normal((N_POSES, n_sys, 1))
    t_numpy = best_of(lambda: np.linalg.solve(a, b), 3)
    print("one thread, per pose:")
    for label, seconds in (("statics, general (15x15 LU + condition number)", t_general),
                           ("statics, reduced coordinates (+ transmission)", t_reduced),
                           ("kinematics (chain of dyads), reduced path", t_kinematics),
                           ("kinematics + condition number, general path", t_kinematics_cond),
                           (f"numpy batched {n_sys}x{n_sys} np.linalg.solve (baseline)", t_numpy)):
        print(f"  {label:<52} {N_POSES / seconds / 1e6:6.2f} M poses/s  {seconds / N_POSES * 1e9:7.0f} ns/pose")
    print(f"  reduced statics {t_general / t_reduced:.1f}x faster than the general; kinematics + reduced statics "
          f"{N_POSES / (t_kinematics + t_reduced) / 1e6:.2f} M poses/s")
    one_p, one_force = p[:1].copy(), member_force[:1].copy()
    t_one = best_of(lambda: [kernels.solve_reduced_statics(one_p, one_force, *NO_ACCEL, False, layout.n_unknowns,
                                                           layout.program, reduced.program) for _ in range(2000)]) / 2000
    a1, b1 = a[0], b[0]
    t_np1 = best_of(lambda: [np.linalg.solve(a1, b1) for _ in range(2000)]) / 2000
    print(f"one pose per call: reduced statics {t_one * 1e6:.2f} us (the Python call included), one {n_sys}x{n_sys} "
          f"np.linalg.solve {t_np1 * 1e6:.2f} us: {t_one / t_np1:.2f}x")
    print("which path each preset and test fixture takes (per set of measured cylinder forces):")
    fixtures = Path(__file__).resolve().parents[1] / "test" / "fixtures"
    for mech in [load_preset(name) for name in preset_names()] + [load_mechanism(f) for f in
                                                                  sorted(fixtures.glob("*.yaml"))]:
        for line in Solver(mech).explain():
            print(f"  {mech.name:<20} {line}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
