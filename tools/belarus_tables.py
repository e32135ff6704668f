"""Popov 2009 Tables 1-2 next to what the solver computes for the ``belarus_1221`` preset.

Generates docs/belarus-1221-tables.md:

    .venv/bin/python tools/belarus_tables.py --out docs/belarus-1221-tables.md

Frame conversion (docs/belarus-1221-geometry.md): the paper's origin is the rear wheels' ground
contact B with X rearward and Y up, so X = −x, Y = z, and a paper angle = π − our angle.
R34 and R05 of the paper are per side: ours (both sides summed) are halved; F_pr, R03, R07 are
totals. I_S = dY_S6/dS by central differences of the solver's poses; G_s = the lift capacity
at the header's cg from ``mechanics.machine`` (p_max·η·A / I_S, 165 kN / I_S in the paper).
"""

from __future__ import annotations

import argparse
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Sequence

import numpy as np

from linkage_monitor.mechanics import Mechanism, Solver, load_preset
from linkage_monitor.mechanics.capacity import stroke_mechanism
from linkage_monitor.mechanics.machine import MachineModel

PRESET = "belarus_1221"
CYLINDER = "lift_cylinder"
DIFF_STEP = 1e-5  # m, cylinder-length step of the central difference for I_S

# Popov (2009), Table 1 (rows S = 0.535 ... 0.715 m; the S = 0.515 row has no XS6/YS6/phi6):
# S [m], Y56 [m], XS6 [m], YS6 [m], phi6 [deg], I_S [-]
PAPER_TABLE_1 = np.array([
    [0.535, 0.305, 1.819, 0.340, 88.551, 7.164],
    [0.555, 0.403, 1.832, 0.478, 91.606, 6.647],
    [0.575, 0.492, 1.831, 0.608, 94.777, 6.427],
    [0.595, 0.577, 1.818, 0.736, 98.174, 6.343],
    [0.615, 0.657, 1.794, 0.862, 101.882, 6.336],
    [0.635, 0.733, 1.759, 0.989, 105.983, 6.369],
    [0.655, 0.806, 1.711, 1.117, 110.554, 6.411],
    [0.675, 0.875, 1.650, 1.246, 115.670, 6.426],
    [0.695, 0.941, 1.574, 1.374, 121.390, 6.362],
    [0.715, 1.002, 1.481, 1.499, 127.731, 6.148],
])
# Popov (2009), Table 2: S [m], G_s [kN], R34 [kN], R03 [kN], R05 [kN], R07 [kN], F_pr [kN], P2 [MPa]
PAPER_TABLE_2 = np.array([
    [0.535, 23.03, 20.55, 116.11, 15.82, 18.43, 107.52, 10.132],
    [0.555, 24.82, 21.11, 110.12, 14.96, 18.69, 99.71, 9.368],
    [0.575, 25.67, 21.83, 108.23, 14.25, 19.02, 96.43, 9.057],
    [0.595, 26.01, 22.73, 108.31, 13.64, 19.39, 95.15, 8.939],
    [0.615, 26.04, 23.73, 109.52, 13.11, 19.74, 95.04, 8.929],
    [0.635, 25.90, 24.84, 111.30, 12.66, 20.03, 95.53, 8.975],
    [0.655, 25.73, 26.06, 113.32, 12.36, 20.19, 96.17, 9.035],
    [0.675, 25.67, 27.29, 115.11, 12.28, 20.12, 96.39, 9.056],
    [0.695, 25.93, 28.36, 115.63, 12.44, 19.69, 95.42, 8.965],
    [0.715, 26.83, 28.99, 113.80, 12.76, 18.75, 92.23, 8.665],
])


@dataclass(frozen=True)
class BelarusTableValues:
    """The solver's values in the paper's frame and units at the cylinder lengths ``s`` (m), shape (N,) each.

    y56, xs6, ys6 m (X rearward from B, Y up); phi6 deg (the mast P56→P67, paper's sense); i_s [-];
    g_s, f_pr, r34, r03, r05, r07 kN (r34, r05 per side); p2 MPa (cap pressure, gauge).
    """

    s: np.ndarray
    y56: np.ndarray
    xs6: np.ndarray
    ys6: np.ndarray
    phi6: np.ndarray
    i_s: np.ndarray
    g_s: np.ndarray
    f_pr: np.ndarray
    p2: np.ndarray
    r34: np.ndarray
    r03: np.ndarray
    r05: np.ndarray
    r07: np.ndarray


def belarus_table_values(mech: Mechanism, s: np.ndarray) -> BelarusTableValues:
    """Solve ``mech`` (the belarus_1221 layout) at cylinder lengths ``s`` (m) and convert to the paper's frame."""
    stroke = stroke_mechanism(mech)
    model = MachineModel(stroke, Solver(stroke), CYLINDER)
    batch, machine = model.capacity_curve(CYLINDER, s)
    if np.any(batch.status != 0):
        bad = int(np.flatnonzero(batch.status != 0)[0])
        raise RuntimeError(f"belarus_1221 does not solve at S = {s[bad]} m: {batch.messages[bad]}")
    up = model.stroke_poses(CYLINDER, s + DIFF_STEP).points["S6"][:, 1]
    down = model.stroke_poses(CYLINDER, s - DIFF_STEP).points["S6"][:, 1]
    mast = batch.points["P67"] - batch.points["P56"]
    half = lambda hinge: np.hypot(*batch.hinge_force[hinge].T) / 2e3  # noqa: E731  (per side, kN)
    total = lambda hinge: np.hypot(*batch.hinge_force[hinge].T) / 1e3  # noqa: E731
    return BelarusTableValues(
        s=s, y56=batch.points["P56"][:, 1], xs6=-batch.points["S6"][:, 0], ys6=batch.points["S6"][:, 1],
        phi6=np.degrees(np.pi - np.arctan2(mast[:, 1], mast[:, 0])),
        i_s=(up - down) / (2 * DIFF_STEP),  # Popov 2009: I_S = dY_S6/dS
        g_s=machine.lift_capacity["implement_cg"] / 1e3, f_pr=batch.cylinder_force[CYLINDER] / 1e3,
        p2=batch.cap_pressure_predicted[CYLINDER] / 1e6,
        r34=half("P34"), r03=total("P03"), r05=half("P05"), r07=total("P07"))


def _rows(paper: np.ndarray, ours: Sequence[np.ndarray], fmts: Sequence[str], relative: Sequence[bool]) -> list[str]:
    lines = []
    for i, s in enumerate(paper[:, 0]):
        cells = [f"{s:.3f}"]
        for k, (fmt, rel) in enumerate(zip(fmts, relative)):
            p, o = paper[i, k + 1], ours[k][i]
            err = f"{100 * (o - p) / p:+.2f} %" if rel else f"{o - p:+.4f}"
            cells.append(f"{p:{fmt}} / {o:{fmt}} / {err}")
        lines.append("| " + " | ".join(cells) + " |")
    return lines


def render(v1: BelarusTableValues, v2: BelarusTableValues) -> str:
    """Markdown of both tables: paper / ours / error per cell, then the worst errors."""
    rms = lambda a, b: float(np.sqrt(np.mean((a - b) ** 2)))  # noqa: E731
    p1, p2 = PAPER_TABLE_1, PAPER_TABLE_2
    rel = lambda a, b: float(np.max(np.abs(a - b) / b) * 100)  # noqa: E731
    out = [
        "# Popov 2009 tables: paper vs the `belarus_1221` preset (generated)",
        "",
        "Generated by `.venv/bin/python tools/belarus_tables.py --out docs/belarus-1221-tables.md`;",
        "`test/test_paper_belarus_1221.py` regenerates it and fails if this file differs. Do not edit by hand.",
        "",
        "Paper: Popov (2009), Tables 1-2. Ours: the package's solver on",
        "`linkage_monitor/mechanics/presets/belarus_1221.yaml`, driven by the cylinder length S only, header",
        "weight 15.00 kN at S6, weightless links. Frame conversion (docs/belarus-1221-geometry.md): the",
        "paper's X is rearward from the rear wheels' ground contact B, Y up: X = -x, Y = z;",
        "phi6 (mast P56->P67) = 180 deg - our angle. I_S = dY_S6/dS by central differences",
        f"(step {DIFF_STEP:g} m). G_s = lift capacity at the header cg from `mechanics.machine`",
        "(p_max*eta*A / I_S). R34 and R05 are per side in the paper: ours (both sides) halved.",
        "Cells: paper / ours / error (absolute in the column's unit, or relative). Table 1's row",
        "S = 0.515 m (only Y56 and I_S printed) is checked in `test/test_paper_belarus_1221.py`.",
        "",
        "## Table 1: kinematics",
        "",
        "| S [m] | Y56 [m] | XS6 [m] | YS6 [m] | phi6 [deg] | I_S [-] |",
        "|---|---|---|---|---|---|",
        *_rows(p1, [v1.y56, v1.xs6, v1.ys6, v1.phi6, v1.i_s], [".3f", ".3f", ".3f", ".3f", ".3f"],
               [False, False, False, False, True]),
        "",
        f"RMS over the rows: Y56 {rms(v1.y56, p1[:, 1]) * 1e3:.2f} mm, XS6 {rms(v1.xs6, p1[:, 2]) * 1e3:.2f} mm, "
        f"YS6 {rms(v1.ys6, p1[:, 3]) * 1e3:.2f} mm, phi6 {rms(v1.phi6, p1[:, 4]):.3f} deg; "
        f"largest I_S error {rel(v1.i_s, p1[:, 5]):.2f} %.",
        "",
        "## Table 2: forces",
        "",
        "| S [m] | G_s [kN] | R34/side [kN] | R03 [kN] | R05/side [kN] | R07 [kN] | F_pr [kN] | P2 [MPa] |",
        "|---|---|---|---|---|---|---|---|",
        *_rows(p2, [v2.g_s, v2.r34, v2.r03, v2.r05, v2.r07, v2.f_pr, v2.p2], [".2f"] * 6 + [".3f"], [True] * 7),
        "",
        "Largest relative error over the rows: " + ", ".join(
            f"{name} {rel(v, p2[:, k + 1]):.2f} %" for k, (name, v) in enumerate(
                [("G_s", v2.g_s), ("R34", v2.r34), ("R03", v2.r03), ("R05", v2.r05), ("R07", v2.r07),
                 ("F_pr", v2.f_pr), ("P2", v2.p2)])) + ".",
        "",
    ]
    return "\n".join(out)


def main(argv: Sequence[str] | None = None) -> int:
    """Print (or write with --out) docs/belarus-1221-tables.md; returns 0."""
    parser = argparse.ArgumentParser(prog="python tools/belarus_tables.py", description=__doc__.splitlines()[0])
    parser.add_argument("--out", metavar="FILE.md", help="write here instead of stdout")
    args = parser.parse_args(argv)
    mech = load_preset(PRESET)
    text = render(belarus_table_values(mech, PAPER_TABLE_1[:, 0]), belarus_table_values(mech, PAPER_TABLE_2[:, 0]))
    if args.out:
        Path(args.out).write_text(text, encoding="utf-8")
    else:
        sys.stdout.write(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
