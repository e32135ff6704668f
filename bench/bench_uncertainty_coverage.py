"""Coverage of the error budget against a truth the monitor does not see (``sim.coverage``): per preset,
runs of the simulator's scenarios with the sensors' errors drawn from the declared sources (biases and the
seals' level in their friction band once per run, noise per sample, readings quantized to their step;
``sim.sensor_errors``), a fresh monitor with ``MonitorConfig.uncertainty`` fed the erroneous readings only,
each step's outputs compared with the same mechanics solved from the true inputs.

Goals, per preset and output kind, over >= 200 runs and >= 5,000 steps: the 95 % interval (value ± k·u,
k from the budget's shape) holds the true value in 93-97 % of the steps (coverage); the mean 95 %
half-width is <= 2.5 times the RMS of the actual error (sharpness); no step passed by the monitor (no
finding about the limit) whose true steerability margin, lift reserve or axle load is beyond its limit
(wrong with OK), nor one whose judged value's u is unbounded (OK while unbounded: no interval to
clear). 1,000 runs by default: a group whose error a bias dominates (one draw per run) has a
coverage as scattered as the runs', about ±3 % (95 %) at 200 runs, wider than the goal's band, ±1.4 %
at 1,000. Every figure printed, with the goal it meets or misses.

With ``--point-tolerance`` (m), the points of the presets one measured input drives are declared to it
(the presets declare none) and each run's true linkage is drawn from it (``sim.true_geometry``).

    .venv/bin/python bench/bench_uncertainty_coverage.py [--runs 1000] [--steps 30] [--seed 51] [--preset NAME]
        [--point-tolerance 0.001]
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from linkage_monitor.mechanics import Solver, load_preset, preset_names  # noqa: E402
from linkage_monitor.mechanics.geometry_budget import driving_input, with_point_tolerance  # noqa: E402
from linkage_monitor.sim.coverage import CoverageTally, study  # noqa: E402

COVERAGE_GOAL = (0.93, 0.97)
SHARPNESS_GOAL = 2.5


def report(preset: str, tally: CoverageTally, seconds: float) -> bool:
    """Print one preset's figures; True when every goal is met."""
    compared = tally.steps - tally.refused - tally.untrue
    print(f"{preset}: {tally.runs} runs, {tally.steps} steps ({tally.refused} refused by the monitor, "
          f"{tally.untrue} whose truth does not solve), {seconds:.0f} s", flush=True)
    met = compared >= 5000 and tally.runs >= 200
    for group, g in tally.groups.items():
        if g.steps == 0 and g.unbounded:   # e.g. a lift capacity that exists only within reach of a pole
            print(f"    {group:<20} every one of its {g.unbounded} values unbounded (u NaN: no interval claimed, "
                  f"coverage not measured, its verdicts WARN)", flush=True)
            continue
        if g.squared_error == 0.0 and g.half_width == 0.0:   # e.g. the configured implement weight: no source
            print(f"    {group:<20} exact: no error and u 0 over {g.steps} values", flush=True)
            continue
        cover_ok = COVERAGE_GOAL[0] <= g.coverage <= COVERAGE_GOAL[1]
        sharp_ok = g.sharpness <= SHARPNESS_GOAL
        met = met and cover_ok and sharp_ok
        print(f"    {group:<20} coverage {g.coverage:7.2%} ({'ok' if cover_ok else 'MISS'})   sharpness "
              f"{g.sharpness:.3f} ({'ok' if sharp_ok else 'MISS'})   over {g.steps} values"
              + (f" ({g.unbounded} more unbounded: no interval claimed)" if g.unbounded else ""), flush=True)
    for output, beyond in tally.beyond.items():
        wrong = tally.wrong_with_ok.get(output, 0)
        met = met and wrong == 0
        print(f"    wrong with OK: {output} {wrong} of {beyond} steps truly beyond the limit "
              f"({'ok' if wrong == 0 else 'MISS'})")
    if not tally.beyond:
        print("    wrong with OK: no step truly beyond a limit (or the mechanism has none)")
    for output, unbounded in tally.unbounded_value.items():
        passed = tally.unbounded_ok.get(output, 0)
        met = met and passed == 0
        print(f"    OK while unbounded: {output} {passed} of {unbounded} steps whose value clears the limit with "
              f"its u unbounded ({'ok' if passed == 0 else 'MISS'})")
    return met


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=1000)
    parser.add_argument("--steps", type=int, default=30, help="samples per run (50 Hz)")
    parser.add_argument("--seed", type=int, default=51)
    parser.add_argument("--preset", action="append", default=[], help="only this preset (repeatable; default: all)")
    parser.add_argument("--point-tolerance", type=float, default=0.0,
                        help="m, 1 sigma per point coordinate, declared on the presets one measured input drives "
                             "(default 0: the presets' own, none)")
    args = parser.parse_args()
    rng = np.random.default_rng(args.seed)
    print(f"coverage of the 95 % intervals: {args.runs} runs x {args.steps} steps per preset, goals coverage "
          f"{COVERAGE_GOAL[0]:.0%}-{COVERAGE_GOAL[1]:.0%}, sharpness <= {SHARPNESS_GOAL}, wrong with OK 0")
    met = []
    for preset in args.preset or preset_names():
        t0 = time.perf_counter()
        mech = load_preset(preset)
        if args.point_tolerance > 0.0 and driving_input(mech, Solver(mech)) is not None:
            mech = with_point_tolerance(mech, args.point_tolerance)
            print(f"{preset}: points declared to {args.point_tolerance * 1e3:g} mm (1 sigma) per coordinate")
        tally = study(mech, args.runs, args.steps, rng)
        met.append(report(preset, tally, time.perf_counter() - t0))
    return 0 if all(met) else 1


if __name__ == "__main__":
    sys.exit(main())
