"""First-order error budget against Monte Carlo: at random poses of every preset (samples of the
simulator's scenario for it), every output's first-order standard uncertainty
(``mechanics.uncertainty``) against the standard deviation of the outputs over draws of the declared
sources (``test/oracles/monte_carlo.py``: bias and noise normal, resolution and seal friction uniform),
the lift cylinder standing (the widest friction band).

Goal: every output within 10 % of the Monte Carlo one at 200 poses of each preset with >= 10,000
samples each; printed: the worst ratio u_first_order / u_monte_carlo per preset over the outputs with a
bounded u (and which output, where), how many poses have an output the budget calls unbounded (u NaN:
near a weak inference's pole, docs/dead-centre.md; no interval claimed, not compared), the share of
samples the monitor refused (they leave the spread), the time per budget.

With the presets' sources and, on the linkages one measured input drives (belarus_1221, drill_coulter,
ttz1080_base_change), point tolerances of ``--point-tolerance`` (default 1 mm) drawn over
``--geometries`` linkages.

    .venv/bin/python bench/bench_uncertainty_mc.py [--poses 200] [--samples 10000] [--seed 51] [--preset NAME]
        [--point-tolerance 0.001] [--geometries 1000]
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "test"))
from linkage_monitor.mechanics import preset_names  # noqa: E402
from linkage_monitor.mechanics.error_sources import Motion  # noqa: E402
from linkage_monitor.mechanics.geometry_budget import driving_input  # noqa: E402
from linkage_monitor.mechanics.uncertainty import UncertaintyModel  # noqa: E402
from oracles.monte_carlo import (NEGLIGIBLE, REFUSED_SHARE, comparable, geometry_pool, monte_carlo,  # noqa: E402
                                 sample_poses)

GOAL = 0.10   # |u_first_order / u_monte_carlo − 1|
# The presets declare no point tolerance (error_sources.DEFAULT_POINT_TOLERANCE): the bench declares this one
# (m, 1 sigma, each coordinate of every point) on those one measured input drives, to hold the tabulated
# geometry derivatives (geometry_budget) to the spread over drawn linkages; GEOMETRIES of them per preset,
# each sample solved by one in turn (the spread of the geometry's share then within about 1/√(2·GEOMETRIES)).
POINT_TOLERANCE = 1.0e-3
GEOMETRIES = 1000
FLOOR = 1e-9  # an output whose Monte Carlo u is below FLOOR·max(1, |value|) has nothing to compare


def study(preset: str, poses: int, samples: int, rng: np.random.Generator, point_tolerance: float = 0.0,
          geometries: int = 0) -> bool:
    """The study of one preset, printed; True when every compared output is within GOAL. With
    ``point_tolerance`` (m, 1 sigma, every point) on a linkage one measured input drives, the points are
    drawn too: ``geometries`` models of the linkage with its points drawn, the samples shared among them."""
    sampled = sample_poses(preset, poses, rng)
    sources = sampled.mechanism.error_sources
    if point_tolerance > 0.0 and driving_input(sampled.mechanism, sampled.model.solver) is not None:
        sources = dataclasses.replace(sources, point_tolerance=point_tolerance)
    um = UncertaintyModel(sampled.model, sources)
    t0 = time.perf_counter()
    pool = geometry_pool(um, geometries, rng)
    if pool:
        print(f"{preset}: points drawn with {point_tolerance * 1e3:g} mm (1 sigma) per coordinate, {len(pool)} "
              f"linkages built in {time.perf_counter() - t0:.0f} s", flush=True)
    worst, negligible = Worst(), Worst()
    failed, truncated, budget_time = 0, 0, 0.0
    unbounded_poses, unbounded_outputs = 0, 0
    for k, (inputs, pose) in enumerate(sampled.poses):
        t0 = time.perf_counter()
        budget = um.budget(inputs, pose.result, pose.machine, Motion.STANDING)
        budget_time += time.perf_counter() - t0
        mc = monte_carlo(um, inputs, budget, samples, rng, pool)
        failed += mc.failed
        if mc.truncated:
            truncated += 1
            continue
        unbounded = np.isfinite(budget.values) & np.isnan(budget.u)
        unbounded_poses += bool(unbounded.any())
        unbounded_outputs += int(unbounded.sum())
        ok = np.isfinite(budget.u) & np.isfinite(mc.u) & (mc.u > FLOOR * np.maximum(1.0, np.abs(budget.values)))
        small = ok & ~comparable(budget, mc)
        where = f"pose {k} " + ", ".join(f"{n}={v:.5g}" for group in (inputs.cylinders, inputs.angles,
                                                                      inputs.pressures) for n, v in group.items())
        names = [o.name for o in budget.outputs]
        worst.update(budget.u, mc.u, ok & ~small, names, where)
        negligible.update(budget.u, mc.u, small, names, where)
    passed = abs(worst.ratio - 1.0) <= GOAL
    print(f"{preset:<22} worst u_first_order/u_mc {worst.ratio:.4f} ({'ok' if passed else 'FAIL'}: within "
          f"{GOAL:.0%}) over {worst.compared} outputs x poses; refused samples {failed / (poses * samples):.2%}; "
          f"budget {budget_time / poses * 1e3:.2f} ms/pose\n    worst: {worst.where}", flush=True)
    if unbounded_poses:
        print(f"    {unbounded_poses} poses with an unbounded output ({unbounded_outputs} outputs x poses: u NaN, the "
              "pole of a weak inference within reach; not compared)")
    if truncated:
        print(f"    {truncated} poses left out: more than {REFUSED_SHARE:.0%} of their samples refused (a reading near "
              "the end of its range, e.g. a chamber near vacuum: the spread is cut short)")
    if negligible.compared:
        print(f"    u_mc < {NEGLIGIBLE:g} of the value (extremum along the stroke, second order): "
              f"{negligible.compared} outputs x poses, worst ratio {negligible.ratio:.4f} ({negligible.where})")
    return passed


class Worst:
    """The ratio u_first_order / u_mc farthest from 1 so far, and where."""

    def __init__(self) -> None:
        self.ratio, self.where, self.compared = 1.0, "", 0

    def update(self, first_order: np.ndarray, monte_carlo: np.ndarray, mask: np.ndarray, names: list[str],
               where: str) -> None:
        """Take the outputs ``mask`` of one pose."""
        ratio = first_order[mask] / monte_carlo[mask]
        self.compared += int(mask.sum())
        if ratio.size:
            j = int(np.argmax(np.abs(ratio - 1.0)))
            if abs(ratio[j] - 1.0) > abs(self.ratio - 1.0):
                self.ratio, self.where = float(ratio[j]), f"{np.array(names)[mask][j]} at {where}"


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--poses", type=int, default=200)
    parser.add_argument("--samples", type=int, default=10_000)
    parser.add_argument("--seed", type=int, default=51)
    parser.add_argument("--preset", action="append", default=[], help="only this preset (repeatable; default: all)")
    parser.add_argument("--point-tolerance", type=float, default=POINT_TOLERANCE,
                        help="m, 1 sigma per point coordinate, on the presets one measured input drives (0: none)")
    parser.add_argument("--geometries", type=int, default=GEOMETRIES, help="linkages drawn per preset (point tolerances)")
    args = parser.parse_args()
    rng = np.random.default_rng(args.seed)
    print(f"first order vs Monte Carlo: {args.poses} poses per preset, {args.samples} samples each, standing")
    results = [study(preset, args.poses, args.samples, rng, args.point_tolerance, args.geometries)
               for preset in args.preset or preset_names()]
    return 0 if all(results) else 1


if __name__ == "__main__":
    sys.exit(main())
