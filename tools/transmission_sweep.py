"""The dead-centre threshold: which smallest transmission angle flags at least every pose that the
condition-number verdict (cond > 1e6) flags, on dense sweeps of every preset.

Run: .venv/bin/python tools/transmission_sweep.py [--points N]

Per preset, driven by its chain's driving inputs (a redundant sensor dropped: it does not move the
pose), every driving input is swept alone along lines through the reference pose and through
points at a quarter and three quarters of the other inputs' intervals:
- densely over the interval where the chain assembles, widened by WIDEN on each side (past it the
  linkage does not assemble: those poses are counted out);
- through each of its dead centres: the ends of that interval (where a dyad or a cylinder's arm
  goes straight, found by bisection to adjacent floating-point numbers) and the interior points
  where the equilibrium matrix's determinant changes sign (bisected the same way), approached
  from both sides by steps shrinking geometrically to 1e-16 of the interval.
Each assembled pose gets, for every set of measured cylinder forces the reduced path serves, the
general path's verdict — the kinematic condition number or the statics' above DEAD_CENTRE_COND —
and its smallest transmission angle (``ReducedStatics.solve``: the steps' and the free load's). The
table: per preset the poses, how many each verdict flags, and the largest transmission angle
among the poses the condition number flags: a threshold above it flags them all.
"""

from __future__ import annotations

import argparse
import copy
import sys
from pathlib import Path
from typing import Iterator, NamedTuple

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from linkage_monitor.mechanics import Mechanism, Solver, Status, kernels, load_preset, preset_names  # noqa: E402
from linkage_monitor.mechanics.chain import ANGLE, ANGLE_INPUT, CYLINDER_INPUT, KIND, RRR  # noqa: E402
from linkage_monitor.mechanics.kinematics import Kinematics  # noqa: E402
from linkage_monitor.mechanics.reduced import DEAD_CENTRE_TRANSMISSION_DEG, ReducedStatics  # noqa: E402
from linkage_monitor.mechanics.schema import mechanism_from_dict  # noqa: E402

DEAD_CENTRE_COND = 1e6    # the condition-number verdict (Solver.dead_centre_cond's default)
WIDEN = 0.05              # share of the assembling interval swept past each of its ends
SEARCH_SPAN = (0.3, 2.0)  # × reference length: where a cylinder's interval is looked for; an angle: ±π rad
APPROACH = np.logspace(-16, -1, 61)   # steps towards a dead centre, × the interval's width
TEST_FORCE = 1e4          # N, every measured cylinder force (the verdicts do not depend on it)


class SweepRow(NamedTuple):
    """One preset's line of the table: assembled poses, flagged by the condition number, flagged by
    the threshold, the largest smallest-transmission angle (deg) among the cond-flagged poses (NaN
    without any), and the cond-flagged poses the threshold misses."""

    preset: str
    poses: int
    flagged_by_cond: int
    flagged_by_threshold: int
    max_angle_cond_flagged: float
    missed: int


def driven(mech: Mechanism) -> Mechanism:
    """``mech`` measured by its chain's driving inputs only (redundant sensors dropped, pressures kept)."""
    kin = Solver(mech).kin
    drivers = {kin.input_names[row[ANGLE_INPUT] if row[KIND] == ANGLE else row[CYLINDER_INPUT]]
               for row in kin.chain_int if row[KIND] != RRR}
    raw = copy.deepcopy(dict(mech.raw))
    measurements = raw["measurements"]
    measurements["cylinders"] = [c for c in measurements.get("cylinders") or [] if c in drivers]
    measurements["angles"] = [a for a in measurements.get("angles") or [] if a["name"] in drivers]
    reference = raw.get("reference_inputs") or {}
    for kind in ("cylinders", "angles"):
        reference[kind] = {k: v for k, v in (reference.get(kind) or {}).items() if k in drivers}
    raw["reference_inputs"] = reference
    return mechanism_from_dict(raw, file=mech.file)


def _assembles(kin: Kinematics, s: np.ndarray) -> bool:
    return bool(kernels.chain_pose(s, kin.n, *kin.geometry[:2], kin.chain_int, kin.chain_float)[1])


def _bisect(inside: float, outside: float, holds) -> float:  # type: ignore[no-untyped-def]
    """The last value from ``inside`` towards ``outside`` where ``holds`` (to adjacent floats)."""
    while True:
        mid = 0.5 * (inside + outside)
        if mid in (inside, outside):
            return inside
        inside, outside = (mid, outside) if holds(mid) else (inside, mid)


def _line(kin: Kinematics, base: np.ndarray, j: int) -> tuple[float, float] | None:
    """The interval of input j (others at ``base``) around base[j] where the chain assembles."""
    nc = kin.cyl_att.shape[1]
    centre = base[j]
    span = (SEARCH_SPAN[0] * centre, SEARCH_SPAN[1] * centre) if j < nc else (centre - np.pi, centre + np.pi)

    def holds(v: float) -> bool:
        s = base.copy()
        s[j] = v
        return _assembles(kin, s)

    if not holds(centre):
        return None
    grid = np.linspace(span[0], span[1], 401)
    ok = np.array([holds(v) for v in grid])
    i = int(np.argmin(np.abs(grid - centre)))
    lo, hi = i, i
    while lo > 0 and ok[lo - 1]:
        lo -= 1
    while hi < len(grid) - 1 and ok[hi + 1]:
        hi += 1
    low = _bisect(grid[lo], grid[lo - 1], holds) if lo > 0 else grid[0]
    high = _bisect(grid[hi], grid[hi + 1], holds) if hi < len(grid) - 1 else grid[-1]
    return low, high


def _bases(kin: Kinematics, j: int) -> Iterator[np.ndarray]:
    """Points the lines of input j pass through: the reference, and for every other input its
    interval's quarter and three quarters (the others at reference)."""
    reference = kin.reference_inputs()
    yield reference
    for other in range(kin.n_inputs):
        if other == j:
            continue
        interval = _line(kin, reference, other)
        if interval is None:
            continue
        for share in (0.25, 0.75):
            base = reference.copy()
            base[other] = interval[0] + share * (interval[1] - interval[0])
            yield base


def _statics_sign(solver: Solver, kin: Kinematics, s: np.ndarray) -> float:
    """Sign of the determinant of the equilibrium matrix (no measured force) at the chain's pose for s."""
    q, _ = kernels.chain_pose(s, kin.n, *kin.geometry[:2], kin.chain_int, kin.chain_float)
    p, _ = kin.positions(q[None])
    layout = solver._layouts[frozenset()]
    axes, _ = layout.member_axes(p)
    return float(np.sign(np.linalg.det(layout.matrix(p, axes)[0])))


def sweep_inputs(solver: Solver, points: int) -> np.ndarray:
    """The swept inputs (N, n_inputs): every line's dense grid and its approaches to dead centres."""
    kin = solver.kin
    rows = []
    for j in range(kin.n_inputs):
        for base in _bases(kin, j):
            interval = _line(kin, base, j)
            if interval is None:
                continue
            lo, hi = interval
            width = hi - lo
            values = [np.linspace(lo - WIDEN * width, hi + WIDEN * width, points)]
            centres = [lo, hi]
            if solver._layouts[frozenset()].null_space_error is None:
                inside = np.linspace(lo, hi, points)[1:-1]

                def sign(v: float) -> float:
                    s = base.copy()
                    s[j] = v
                    return _statics_sign(solver, kin, s)

                signs = np.array([sign(v) for v in inside])
                for k in np.flatnonzero(signs[1:] * signs[:-1] < 0):
                    first = signs[k]
                    centres.append(_bisect(inside[k], inside[k + 1], lambda v: sign(v) == first))
            for centre in centres:
                values.append(centre + APPROACH * width)
                values.append(centre - APPROACH * width)
                values.append(np.array([centre]))
            grid = np.concatenate(values)
            s = np.repeat(base[None], grid.size, axis=0)
            s[:, j] = grid
            rows.append(s)
    return np.concatenate(rows)


def sweep(mech: Mechanism, points: int, threshold_deg: float = DEAD_CENTRE_TRANSMISSION_DEG) -> SweepRow:
    """The table's row of one mechanism (see the module's docstring), over every set of measured
    cylinder forces the reduced path serves (the others keep the condition-number verdict): a
    pose is flagged when it is for any of them; missed counts (pose, set) pairs."""
    solver = Solver(driven(mech))
    kin = solver.kin
    s = sweep_inputs(solver, points)
    state = kin.solve(s, None, DEAD_CENTRE_COND, 1e-3, reach=False)
    assembled = state.status != Status.ASSEMBLY
    p, _ = kin.positions(state.q)
    force = np.full((s.shape[0], len(mech.cylinders)), TEST_FORCE)
    by_cond = np.zeros(s.shape[0], dtype=bool)
    by_threshold = by_cond.copy()
    largest, missed = float("nan"), 0
    for layout in solver._layouts.values():
        reduced = ReducedStatics(kin, layout)
        if layout.null_space_error is not None or not reduced.served:
            continue
        statics = layout.solve(p, force, None).condition
        flagged = assembled & ~(np.maximum(state.condition, np.nan_to_num(statics, nan=np.inf)) <= DEAD_CENTRE_COND)
        angle = np.degrees(reduced.solve(p, force, None).transmission.angle)
        below = assembled & (angle < threshold_deg)
        by_cond |= flagged
        by_threshold |= below
        missed += int((flagged & ~below).sum())
        if flagged.any():
            largest = float(np.fmax(largest, angle[flagged].max()))
    return SweepRow(mech.name, int(assembled.sum()), int(by_cond.sum()), int(by_threshold.sum()), largest, missed)


def table(rows: list[SweepRow], threshold_deg: float) -> str:
    """The rows as a markdown table."""
    lines = [f"| preset | poses | flagged by cond > {DEAD_CENTRE_COND:.0e} | flagged by angle < {threshold_deg:g} deg "
             "| max angle among cond-flagged (deg) | cond-flagged missed |",
             "|---|---:|---:|---:|---:|---:|"]
    lines += [f"| {r.preset} | {r.poses} | {r.flagged_by_cond} | {r.flagged_by_threshold} | "
              f"{r.max_angle_cond_flagged:.3g} | {r.missed} |" for r in rows]
    return "\n".join(lines)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--points", type=int, default=4001, help="poses per line's dense grid")
    args = parser.parse_args()
    rows = [sweep(load_preset(name), args.points) for name in preset_names()]
    print(table(rows, DEAD_CENTRE_TRANSMISSION_DEG))
    largest = max((r.max_angle_cond_flagged for r in rows if r.flagged_by_cond), default=float("nan"))
    print(f"\nlargest smallest-transmission angle among cond-flagged poses: {largest:.3g} deg; "
          f"DEAD_CENTRE_TRANSMISSION_DEG = {DEAD_CENTRE_TRANSMISSION_DEG:g} deg")
    return 0 if all(r.missed == 0 for r in rows) else 1


if __name__ == "__main__":
    sys.exit(main())
