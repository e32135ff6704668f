"""Lift-capacity curve over the cylinder stroke as a PNG (matplotlib), drawn like Popov 2009 Fig. 4-5.

Capacity at the hitch axis, 610 mm behind it and at the implement's centre of gravity (kN) vs. the
lift cylinder length (m), with the steerability limit: the largest implement weight the tractor
can still steer with (kN), which the implement weight must stay under.
"""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")  # files only, no display needed
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from linkage_monitor.mechanics.machine import MachineBatch  # noqa: E402

_CURVES = (("hitch_axis", "capacity at the hitch axis", "tab:blue", "-"),
           ("behind_610mm", "capacity 610 mm behind the axis", "tab:green", "-"),
           ("implement_cg", "capacity at the implement's cg", "tab:purple", "--"))


def plot_capacity(lengths: np.ndarray, machine: MachineBatch, gravity: float, implement_weight: float,
                  title: str, path: str | Path, reference: str = "unit") -> None:
    """Write the capacity curve to ``path`` (PNG).

    lengths (N,) m: lift cylinder lengths; ``machine``: their machine-level results (transport
    poses); gravity m/s²; implement_weight N: the configured implement's weight (drawn as a line);
    reference: ``unit`` or ``tractor``, the weight the steerability ratio is taken of (legend text).
    """
    fig, ax = plt.subplots(figsize=(8.0, 5.0), dpi=120)
    reference = {"unit": "unit weight", "tractor": "empty tractor weight"}[reference]
    for key, label, colour, style in _CURVES:
        if key in machine.lift_capacity:
            ax.plot(lengths, machine.lift_capacity[key] / 1e3, style, color=colour, lw=2, label=label)
    if machine.steerability:
        limit = machine.steerability["max_implement_mass"] * gravity / 1e3
        ratio_min = float(np.nanmax(machine.steerability["ratio_min"]))
        ax.plot(lengths, limit, color="tab:red", lw=2,
                label=f"steerability limit: largest implement weight (front axle ≥ {ratio_min:.0%} of {reference})")
        top = 1.5 * ax.get_ylim()[1]  # head room for the legend
        ax.fill_between(lengths, limit, top, color="tab:red", alpha=0.08, lw=0, label="implement too heavy to steer")
        ax.set_ylim(top=top)
    ax.axhline(implement_weight / 1e3, color="black", ls=":", lw=1.5,
               label=f"present implement weight {implement_weight / 1e3:.1f} kN")
    ax.set_xlabel("lift cylinder length S [m]")
    ax.set_ylabel("vertical load [kN]")
    ax.set_title(title)
    ax.set_xlim(lengths[0], lengths[-1])
    ax.set_ylim(bottom=0.0)
    ax.grid(True, alpha=0.3)
    ax.legend(loc="upper left", fontsize=8, framealpha=0.9)
    fig.tight_layout()
    fig.savefig(path, format="png")
    plt.close(fig)
