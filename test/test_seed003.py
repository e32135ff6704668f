"""Seed 003 (Popov 2009, Belarus-1221 + ZhSK-4V header): the preset against the paper's Tables 1-2.

Every expected number is typed from REFERENCE.md section 003 (Table 1, Table 2). Ours come from
the real solver (``seed003_values``: batched solve driven by the cylinder length S, frame
conversion X = -x, Y = z, phi6 = 180 deg - our mast angle, R34/R05 halved to the paper's per-side
values, G_s from ``mechanics.machine`` lift capacity at the header cg).
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from linkage_monitor.mechanics import load_preset
from linkage_monitor.seed003_table import seed003_values

REPO = Path(__file__).resolve().parent.parent

# REFERENCE.md 003, Table 1: S [m], Y56 [m], XS6 [m], YS6 [m], phi6 [deg]
TABLE_1 = np.array([
    [0.535, 0.305, 1.819, 0.340, 88.551],
    [0.555, 0.403, 1.832, 0.478, 91.606],
    [0.575, 0.492, 1.831, 0.608, 94.777],
    [0.595, 0.577, 1.818, 0.736, 98.174],
    [0.615, 0.657, 1.794, 0.862, 101.882],
    [0.635, 0.733, 1.759, 0.989, 105.983],
    [0.655, 0.806, 1.711, 1.117, 110.554],
    [0.675, 0.875, 1.650, 1.246, 115.670],
    [0.695, 0.941, 1.574, 1.374, 121.390],
    [0.715, 1.002, 1.481, 1.499, 127.731],
])
# REFERENCE.md 003, Table 2: S [m], G_s, R34 (per side), R03, R05 (per side), R07, F_pr [kN], P2 [MPa]
TABLE_2 = np.array([
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


def _rms(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.sqrt(np.mean((a - b) ** 2)))


def test_table_1_kinematics_within_5_mm_and_half_a_degree():
    ours = seed003_values(load_preset("belarus_1221"), TABLE_1[:, 0])
    assert _rms(ours.y56, TABLE_1[:, 1]) <= 0.005       # Table 1, Y56 (hitch axis height)
    assert _rms(ours.xs6, TABLE_1[:, 2]) <= 0.005       # Table 1, XS6 (header cg behind B)
    assert _rms(ours.ys6, TABLE_1[:, 3]) <= 0.005       # Table 1, YS6 (header cg height)
    assert _rms(ours.phi6, TABLE_1[:, 4]) <= 0.5        # Table 1, phi6 (mast angle), deg


def test_table_1_first_row_hitch_height_and_ratio():
    """S = 0.515 m (below work) prints only Y56 = 0.191 m and I_S = 8.695 (Table 1, first row)."""
    ours = seed003_values(load_preset("belarus_1221"), np.array([0.515]))
    assert ours.y56[0] == pytest.approx(0.191, abs=0.005)
    assert ours.i_s[0] == pytest.approx(8.695, rel=0.01)


@pytest.mark.parametrize("row", range(len(TABLE_2)))
def test_table_2_forces_per_row(row: int):
    s, g_s, r34, r03, r05, r07, f_pr, p2 = TABLE_2[row]
    ours = seed003_values(load_preset("belarus_1221"), np.array([s]))
    assert ours.f_pr[0] == pytest.approx(f_pr, rel=0.01)   # Table 2, F_pr (both cylinders)
    assert ours.p2[0] == pytest.approx(p2, rel=0.01)       # Table 2, P2 (cap pressure)
    assert ours.g_s[0] == pytest.approx(g_s, rel=0.01)     # Table 2, G_s = 165 kN / I_S
    assert ours.r34[0] == pytest.approx(r34, rel=0.05)     # Table 2, R34 (per side)
    assert ours.r03[0] == pytest.approx(r03, rel=0.05)     # Table 2, R03 (rockshaft, total)
    assert ours.r05[0] == pytest.approx(r05, rel=0.05)     # Table 2, R05 (per side)
    assert ours.r07[0] == pytest.approx(r07, rel=0.05)     # Table 2, R07 (top link)


def test_generated_doc_is_current(tmp_path: Path):
    """docs/seed003_tables.md is exactly what its command prints (regenerate: see the doc's first lines)."""
    out = tmp_path / "seed003_tables.md"
    subprocess.run([sys.executable, "-m", "linkage_monitor.seed003_table", "--out", str(out)], cwd=REPO, check=True,
                   timeout=120)
    committed = (REPO / "docs" / "seed003_tables.md").read_text(encoding="utf-8")
    assert out.read_text(encoding="utf-8") == committed, (
        "docs/seed003_tables.md is stale: run .venv/bin/python -m linkage_monitor.seed003_table "
        "--out docs/seed003_tables.md")
