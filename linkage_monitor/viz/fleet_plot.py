"""The fleet picture (fleet.png): per hinge the damage-equivalent load across bags, and the
distribution of the bags' minimum steerability margin, the worst bags named.

Left: one column per hinge (``mechanism: hinge`` when the fleet mixes mechanisms), a dot per bag
at its DEL (kN, Wöhler slope m), the worst bag of each hinge labelled. Right: histogram of the
minimum steerability margin (front-axle share minus its minimum, −) per bag, the limit 0 drawn,
the three lowest bags labelled.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use("Agg")  # files only, no display needed
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402


def plot_fleet(rows: list[dict[str, Any]], slope: float, path: str | Path) -> None:
    """Write fleet.png from the bags' rows (offline.fleet: ``<hinge>_del_N``, ``min_margin``)."""
    ok = [r for r in rows if r.get("error") is None]
    mechanisms = {r["mechanism"] for r in ok}
    columns: dict[tuple[str, str], list[tuple[float, str]]] = {}
    for r in ok:
        for key, value in r.items():
            if key.endswith("_del_N") and value is not None:
                columns.setdefault((r["mechanism"], key[:-len("_del_N")]), []).append((value / 1e3, _name(r["bag"])))
    fig, (left, right) = plt.subplots(1, 2, figsize=(13.0, 5.5), dpi=110, gridspec_kw={"width_ratios": [3, 2]})
    rng = np.random.default_rng(0)   # horizontal jitter only, so equal loads stay readable
    labels = []
    top = max((v for points in columns.values() for v, _ in points), default=0.0)
    for x, ((mech, hinge), points) in enumerate(columns.items()):
        values = np.array([v for v, _ in points])
        left.scatter(x + rng.uniform(-0.18, 0.18, values.size), values, s=18, alpha=0.7, color="tab:blue")
        worst = int(np.argmax(values))
        if values.size >= 3 or values[worst] == top:   # name the worst bag where there is a spread to speak of
            left.annotate(points[worst][1], (x, values[worst]), xytext=(4, 4), textcoords="offset points", fontsize=7)
        labels.append(f"{mech}: {hinge}" if len(mechanisms) > 1 else hinge)
    left.set_xticks(range(len(labels)), labels, rotation=45 if len(labels) > 8 else 0, ha="right"
                    if len(labels) > 8 else "center", fontsize=8)
    left.set_ylabel(f"damage-equivalent load, 1 Hz, m = {slope:g} [kN]")
    left.set_title(f"Hinge reactions: damage-equivalent load per bag ({len(ok)} bags)")
    left.grid(axis="y", alpha=0.3)
    margins = [(r["min_margin"], _name(r["bag"])) for r in ok if not math.isnan(r["min_margin"])]
    if margins:
        values = np.array([m for m, _ in margins])
        _, edges, patches = right.hist(values, bins=min(20, max(5, values.size // 2)), color="tab:green", alpha=0.8)
        for lower, patch in zip(edges, patches):
            if lower < 0.0:
                patch.set_facecolor("tab:red")   # bags that went below the limit
        right.yaxis.get_major_locator().set_params(integer=True)
        right.axvline(0.0, color="tab:red", lw=2, label="limit: share = minimum")
        for m, name in sorted(margins)[:3]:
            right.annotate(name, (m, 0), xytext=(0, 18 + 14 * sorted(margins).index((m, name))),
                           textcoords="offset points", fontsize=7, rotation=0,
                           arrowprops={"arrowstyle": "-", "color": "0.5"})
        right.legend(fontsize=8)
    else:
        right.text(0.5, 0.5, "no steerability results\n(no tractor in the mechanisms)", ha="center",
                   transform=right.transAxes)
    right.set_xlabel("minimum steerability margin of the bag [−]")
    right.set_ylabel("bags")
    right.set_title("Steerability: lowest margin per bag")
    failed = len(rows) - len(ok)
    if failed:
        fig.text(0.01, 0.01, f"{failed} bag(s) could not be analysed: see bags.parquet 'error'", fontsize=8,
                 color="tab:red")
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)


def _name(bag: str) -> str:
    """A bag's short name: its directory or file name."""
    return Path(bag).name
