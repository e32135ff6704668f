"""Memory of a long recording's solve: peak RSS growth per pose against the size of the results.

Run: .venv/bin/python bench/bench_memory.py [--poses N]

A replay solves each configuration segment in one call (``MachineModel.solve_series``: an hour at
100 Hz is 360,000 poses), calibration and capacity sweeps call ``Solver.solve_batch``. Each is run
in a fresh process on N belarus_1221 poses (stroke + lift-arm angle + cap pressure, a slow lift with
2 mrad of angle noise); printed: the process's peak RSS growth during the call, per pose, and as a
ratio to the baseline measured in the same process — the bytes of the arrays the call returns (the
results themselves: points, hinge forces, machine rows, ...), what any solver must hold.
"""

from __future__ import annotations

import argparse
import resource
import subprocess
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))


def _nbytes(value: object) -> int:
    """Bytes of the numpy arrays in a value (dataclass fields, dicts, tuples)."""
    if isinstance(value, np.ndarray):
        return value.nbytes
    if isinstance(value, dict):
        return sum(_nbytes(v) for v in value.values())
    if isinstance(value, (tuple, list)):
        return sum(_nbytes(v) for v in value)
    if hasattr(value, "__dataclass_fields__"):
        return sum(_nbytes(getattr(value, f)) for f in value.__dataclass_fields__)
    return 0


def measure(call: str, n: int) -> None:
    """One call on n poses in this process: prints 'peak_bytes result_bytes'."""
    from linkage_monitor.mechanics import Solver, load_preset
    from linkage_monitor.mechanics.capacity import stroke_mechanism
    from linkage_monitor.mechanics.machine import MachineModel
    from linkage_monitor.mechanics.results import angle_readings

    mech = load_preset("belarus_1221")
    solver = Solver(mech, consistency_tol=20e-3)
    model = MachineModel(mech, solver)
    stroke0 = solver.kin.reference_inputs()[0]
    stroke = stroke0 * (1.0 + 0.02 * np.sin(np.linspace(0.0, 60.0, n)))
    grid = np.linspace(stroke.min(), stroke.max(), 2000)
    closed = Solver(stroke_mechanism(mech)).solve_batch(cylinders={"lift_cylinder": grid})
    angle = (np.interp(stroke, grid, angle_readings(mech, closed)["lift_arm_angle"])
             + np.random.default_rng(0).normal(0.0, 0.002, n))
    pressure = np.full(n, 9e6)
    model.solve_series({"lift_cylinder": stroke[:10]}, {"lift_arm_angle": angle[:10]},
                       {"lift_cap_pressure": pressure[:10]})          # compiled / loaded before measuring
    solver.solve_batch(cylinders={"lift_cylinder": stroke[:10]}, angles={"lift_arm_angle": angle[:10]})
    before = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024
    if call == "solve_series":
        result: object = model.solve_series({"lift_cylinder": stroke}, {"lift_arm_angle": angle},
                                            {"lift_cap_pressure": pressure})
    else:
        result = solver.solve_batch(cylinders={"lift_cylinder": stroke}, angles={"lift_arm_angle": angle},
                                    pressures={"lift_cap_pressure": pressure})
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024 - before
    print(peak, _nbytes(result))


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--poses", type=int, default=200_000, help="poses per call (default 200000)")
    parser.add_argument("--measure", choices=("solve_series", "solve_batch"), help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.measure:
        measure(args.measure, args.poses)
        return 0
    print(f"belarus_1221, {args.poses} poses per call, each call in a fresh process:")
    for call in ("solve_series", "solve_batch"):
        out = subprocess.run([sys.executable, __file__, "--measure", call, "--poses", str(args.poses)],
                             capture_output=True, text=True, check=True, cwd=ROOT).stdout.split()
        peak, results = int(out[-2]), int(out[-1])
        print(f"  {call:<13} peak RSS growth {peak / 2**20:7.1f} MiB = {peak / args.poses:6.0f} B/pose; "
              f"the results it returns {results / 2**20:6.1f} MiB ({results / args.poses:5.0f} B/pose): "
              f"ratio {peak / results:.2f}x")
    return 0


if __name__ == "__main__":
    sys.exit(main())
