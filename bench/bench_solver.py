"""Solver speed: single-pose solve time (µs) and batched poses/s, against numpy's batched dense
``np.linalg.solve`` of the same system size timed in the same run (the floor for one linear solve
per pose). Run: ``.venv/bin/python bench/bench_solver.py``. Goal: ``solve_batch`` at the speed of
its compiled kernels, ≤ 1.10× the time of the kernels alone on every core, the dead-centre verdict
included. One pose is judged by the node's step (``bench_step.py``) and printed here against one
``np.linalg.solve``. Also printed: where the compiled kernels' time goes, and the floor of the
kinematics — the chain's closed-form placement alone, and the trigonometric calls that placing
its bodies needs at the least."""

from __future__ import annotations

import sys
import time
from pathlib import Path

import math

import numba
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from linkage_monitor.mechanics import chain, kernels  # noqa: E402
from linkage_monitor.mechanics.programs import KinematicsProgram  # noqa: E402
from linkage_monitor.mechanics.reduced import ReducedStatics  # noqa: E402
from linkage_monitor.mechanics import (Inputs, Solver, load_mechanism, load_preset, mechanism_from_dict,  # noqa: E402
                                       preset_names)


def stroke_only(mech):
    """The same mechanism with only the cylinder strokes measured (the bench sweeps the stroke)."""
    raw = dict(mech.raw)
    raw["measurements"] = {**raw["measurements"], "angles": []}
    raw["reference_inputs"] = {k: v for k, v in (raw.get("reference_inputs") or {}).items() if k != "angles"}
    return mechanism_from_dict(raw, file=mech.file)


def best_of(fn, repeat: int = 5) -> float:
    """Smallest wall time (s) of ``repeat`` calls."""
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return min(times)


def best_of_alternating(first, second, repeat: int = 5) -> tuple[float, float]:
    """Smallest wall times (s) of ``first`` and ``second`` over ``repeat`` runs each, run in turns (a
    loaded machine slows both alike)."""
    times: tuple[list[float], list[float]] = ([], [])
    for _ in range(repeat):
        for fn, acc in zip((first, second), times):
            t0 = time.perf_counter()
            fn()
            acc.append(time.perf_counter() - t0)
    return min(times[0]), min(times[1])


def per_call(fn, calls: int, repeat: int = 5) -> float:
    """Smallest wall time (s) per call of ``fn`` (which makes ``calls`` calls), over ``repeat`` runs."""
    return best_of(fn, repeat) / calls


@numba.njit
def chain_placements(s: np.ndarray, program: KinematicsProgram, n: int) -> float:
    """The chain's closed-form placement alone (``kernels.dyads._chain_pose_into``) for each row of s, into
    one pose and one rotation array (no residual, no allocation per pose): the floor of the
    kinematics; n: the pose's coordinates. Returns a sum of the poses so that the work is not
    optimised away."""
    q, rotation, total = np.zeros(n), np.empty((2, n // 3)), 0.0
    for i in range(s.shape[0]):
        kernels.dyads._chain_pose_into(q, rotation, s[i], program.att_body, program.att_ref, program.chain_int,
                                 program.chain_float)
        total += q[0]
    return total


@numba.njit
def trigonometry(x: np.ndarray, calls: int) -> float:
    """``calls`` × (atan2, cos, sin, sqrt) per row of x: what placing ``calls`` bodies evaluates at
    the least (a direction, the body's rotation, a distance)."""
    total = 0.0
    for i in range(x.shape[0]):
        for k in range(calls):
            angle = math.atan2(x[i] + k, x[i])
            total += math.cos(angle) + math.sin(angle) + math.sqrt(x[i] + k)
    return total


def main() -> None:
    if "belarus_1221" in preset_names():
        mech, label = load_preset("belarus_1221"), "preset belarus_1221"
    else:
        mech, label = load_mechanism(Path(__file__).resolve().parents[1] / "test/fixtures/hitch.yaml"), "fixture hitch"
    if mech.measurements.angles:
        full = Solver(mech)
        ref = Inputs(**{k: dict(v) for k, v in mech.reference_inputs.items()})
        full.solve(ref)
        t_full = per_call(lambda: [full.solve(ref) for _ in range(200)], 200)
        print(f"single pose with all measurements (stroke + angles, least squares): {t_full * 1e6:8.1f} us")
        mech = stroke_only(mech)
    solver = Solver(mech)
    cyl = mech.measurements.cylinders[0]
    length0 = solver.kin.reference_inputs()[0]
    n_sys = solver.kin.n
    print(f"{label}: {len(mech.moving_bodies)} moving bodies, system size {n_sys}x{n_sys}")

    # the node's case: a slowly moving stroke, <= 1.3 mm per message (0.06 m/s at 50 Hz)
    moving = [Inputs(cylinders={cyl: float(s)}) for s in length0 + 0.02 * np.sin(2 * np.pi * np.arange(200) / 100)]
    # cold: every pose from the reference pose, strokes anywhere within +-3 %
    jumps = [Inputs(cylinders={cyl: float(s)}) for s in length0 * np.random.default_rng(3).uniform(0.97, 1.03, 200)]

    def cold() -> None:
        for inputs in jumps:
            solver.solve(inputs)

    def warm() -> None:
        previous = solver.solve(moving[-1])
        for inputs in moving:
            previous = solver.solve(inputs, previous=previous)

    t_cold = per_call(cold, len(jumps))
    t_warm = per_call(warm, len(moving))
    print(f"single pose, cold (from the reference pose):              {t_cold * 1e6:8.1f} us")
    print(f"single pose, continuing from the previous pose (node):    {t_warm * 1e6:8.1f} us  (judged by bench_step.py's step)")

    n = 100_000
    batch_strokes = length0 * np.random.default_rng(0).uniform(0.97, 1.03, n)

    # the compiled kernels alone, as solve_batch runs them (no Python result objects), one thread and
    # all: the kinematics without the condition number, the statics in reduced coordinates
    kin, layout = solver.kin, solver.statics_layout(frozenset())
    reduced = ReducedStatics(kin, layout)
    s_in = batch_strokes[:, None]

    def kernels_only() -> None:
        q = kin.continue_from(kin.reference, s_in, with_condition=not reduced.served)[0]
        p, _ = kin.positions(q)
        solve = (lambda *a: kernels.solve_reduced_statics(*a, reduced.program)) if reduced.served \
            else kernels.solve_statics
        solve(p, np.zeros((n, len(mech.cylinders))), np.zeros((1, 1, 2)), np.zeros((1, 1)), False,
              layout.n_unknowns, layout.program)

    # where the kernels' time goes: the kinematics, then the statics in reduced coordinates (the
    # product's path) against the general 15x15 system with its condition number (their oracle)
    p, _ = kin.positions(kin.continue_from(kin.reference, s_in, with_condition=False)[0])
    member_force, no_accel = np.zeros((n, layout.member_att.shape[1])), (np.zeros((1, 1, 2)), np.zeros((1, 1)))

    def general_statics() -> tuple[np.ndarray, ...]:
        return kernels.solve_statics(p, member_force, *no_accel, False, layout.n_unknowns, layout.program)

    def reduced_statics() -> tuple[np.ndarray, ...]:
        return kernels.solve_reduced_statics(p, member_force, *no_accel, False, layout.n_unknowns, layout.program,
                                             reduced.program)

    u_general, u_reduced = general_statics()[0], reduced_statics()[0]   # loaded from the cache; the oracle
    numba.set_num_threads(1)
    t_k1 = best_of(kernels_only, 2)
    t_kinematics = best_of(lambda: kin.continue_from(kin.reference, s_in, with_condition=False), 2)
    t_general, t_reduced = best_of(general_statics, 2), best_of(reduced_statics, 3)
    placed = sum(2 if row[chain.KIND] == chain.RRR else 1 for row in kin.chain_int)   # bodies the chain places
    chain_placements(s_in, kin.program, kin.n), trigonometry(s_in[:, 0], placed)            # compiled before timing
    t_chain = best_of(lambda: chain_placements(s_in, kin.program, kin.n), 3)
    t_trig = best_of(lambda: trigonometry(s_in[:, 0], placed), 3)
    numba.set_num_threads(numba.config.NUMBA_NUM_THREADS)
    # solve_batch (on every core by default) and its kernels alone, timed in turns
    t_batch, t_kn = best_of_alternating(lambda: solver.solve_batch(cylinders={cyl: batch_strokes}), kernels_only)
    print(f"batched, {n} poses from the reference pose:        {n / t_batch / 1e6:8.3f} M poses/s")
    print(f"compiled kernels only, {n} poses, 1 thread:          {n / t_k1 / 1e6:8.3f} M poses/s")
    print(f"compiled kernels only, {n} poses, {numba.config.NUMBA_NUM_THREADS} threads:         "
          f"{n / t_kn / 1e6:8.3f} M poses/s")
    print(f"  of which, 1 thread: kinematics (chain of dyads) {t_kinematics / n * 1e9:6.0f} ns/pose, statics in "
          f"reduced coordinates {t_reduced / n * 1e9:5.0f} ns/pose (the general 15x15 statics {t_general / n * 1e9:5.0f} "
          f"ns/pose: {t_general / t_reduced:.1f}x; largest difference {np.abs(u_reduced - u_general).max():.2g} N "
          f"of {np.abs(u_general).max():.3g} N)")
    print(f"  the floor, 1 thread: the chain's placement alone {t_chain / n * 1e9:5.0f} ns/pose ({placed} bodies; "
          f"{placed} x (atan2, cos, sin, sqrt) alone {t_trig / n * 1e9:4.0f} ns/pose)")

    a = np.random.default_rng(1).standard_normal((n, n_sys, n_sys)) + n_sys * np.eye(n_sys)
    b = np.random.default_rng(2).standard_normal((n, n_sys, 1))
    t_np = best_of(lambda: np.linalg.solve(a, b), 3)
    t_np1 = per_call(lambda: [np.linalg.solve(a[i], b[i]) for i in range(200)], 200)
    print(f"baseline np.linalg.solve batched {n_sys}x{n_sys}:           {n / t_np / 1e6:8.3f} M solves/s")
    print(f"baseline np.linalg.solve one {n_sys}x{n_sys}:               {t_np1 * 1e6:8.1f} us")
    print(f"ratio batched solver / one batched linear solve: {t_batch / t_np:6.1f}x the time")
    print(f"ratio compiled kernels (1 thread) / one batched linear solve: {t_k1 / t_np:6.2f}x the time")
    print(f"ratio batched solver / compiled kernels alone ({numba.config.NUMBA_NUM_THREADS} threads): "
          f"{t_batch / t_kn:6.2f}x the time  (goal <= 1.10x)")
    print(f"ratio single cold solver / one single linear solve:  {t_cold / t_np1:6.1f}x the time")
    print(f"ratio single continuing / one single linear solve:   {t_warm / t_np1:6.1f}x the time")


if __name__ == "__main__":
    main()
