"""Popov 2009 (Belarus-1221 + ZhSK-4V header): the preset against the paper's Tables 1-2.

Every expected number is typed from Popov (2009), Table 1 and Table 2. Ours come from
the real solver (``belarus_table_values``: batched solve driven by the cylinder length S, frame
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
from belarus_tables import PAPER_TABLE_1, PAPER_TABLE_2, belarus_table_values  # tools/belarus_tables.py

REPO = Path(__file__).resolve().parent.parent

# The paper's tables, typed once from Popov (2009) (with the docs generator):
# Table 1: S [m], Y56 [m], XS6 [m], YS6 [m], phi6 [deg], I_S [-]
TABLE_1 = PAPER_TABLE_1
# Table 2: S [m], G_s, R34 (per side), R03, R05 (per side), R07, F_pr [kN], P2 [MPa]
TABLE_2 = PAPER_TABLE_2


def _rms(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.sqrt(np.mean((a - b) ** 2)))


def test_table_1_kinematics_within_5_mm_and_half_a_degree():
    ours = belarus_table_values(load_preset("belarus_1221"), TABLE_1[:, 0])
    assert _rms(ours.y56, TABLE_1[:, 1]) <= 0.005       # Table 1, Y56 (hitch axis height)
    assert _rms(ours.xs6, TABLE_1[:, 2]) <= 0.005       # Table 1, XS6 (header cg behind B)
    assert _rms(ours.ys6, TABLE_1[:, 3]) <= 0.005       # Table 1, YS6 (header cg height)
    assert _rms(ours.phi6, TABLE_1[:, 4]) <= 0.5        # Table 1, phi6 (mast angle), deg


def test_table_1_first_row_hitch_height_and_ratio():
    """S = 0.515 m (below work) prints only Y56 = 0.191 m and I_S = 8.695 (Table 1, first row)."""
    ours = belarus_table_values(load_preset("belarus_1221"), np.array([0.515]))
    assert ours.y56[0] == pytest.approx(0.191, abs=0.005)
    assert ours.i_s[0] == pytest.approx(8.695, rel=0.01)


@pytest.mark.parametrize("row", range(len(TABLE_2)))
def test_table_2_forces_per_row(row: int):
    s, g_s, r34, r03, r05, r07, f_pr, p2 = TABLE_2[row]
    ours = belarus_table_values(load_preset("belarus_1221"), np.array([s]))
    assert ours.f_pr[0] == pytest.approx(f_pr, rel=0.01)   # Table 2, F_pr (both cylinders)
    assert ours.p2[0] == pytest.approx(p2, rel=0.01)       # Table 2, P2 (cap pressure)
    assert ours.g_s[0] == pytest.approx(g_s, rel=0.01)     # Table 2, G_s = 165 kN / I_S
    assert ours.r34[0] == pytest.approx(r34, rel=0.05)     # Table 2, R34 (per side)
    assert ours.r03[0] == pytest.approx(r03, rel=0.05)     # Table 2, R03 (rockshaft, total)
    assert ours.r05[0] == pytest.approx(r05, rel=0.05)     # Table 2, R05 (per side)
    assert ours.r07[0] == pytest.approx(r07, rel=0.05)     # Table 2, R07 (top link)


@pytest.mark.slow
def test_generated_doc_is_current(tmp_path: Path):
    """docs/belarus-1221-tables.md is exactly what its command prints (regenerate: see the doc's first lines)."""
    out = tmp_path / "belarus-1221-tables.md"
    subprocess.run([sys.executable, str(REPO / "tools" / "belarus_tables.py"), "--out", str(out)], cwd=REPO, check=True,
                   timeout=120)
    committed = (REPO / "docs" / "belarus-1221-tables.md").read_text(encoding="utf-8")
    assert out.read_text(encoding="utf-8") == committed, (
        "docs/belarus-1221-tables.md is stale: run .venv/bin/python tools/belarus_tables.py "
        "--out docs/belarus-1221-tables.md")
