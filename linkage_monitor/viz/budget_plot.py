"""The error budget over a cylinder's stroke as a PNG (matplotlib): per output, the share of u² of
each declared source (stacked, which source dominates where) and the relative standard uncertainty
u/|value| (%) on the right axis (docs/accuracy.md).
"""

from __future__ import annotations

from pathlib import Path
from typing import Sequence

import matplotlib

matplotlib.use("Agg")  # files only, no display needed
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from linkage_monitor.mechanics.budget import Budget  # noqa: E402


def plot_budget(lengths: np.ndarray, budgets: Sequence[Budget], outputs: Sequence[str], xlabel: str, title: str,
                path: str | Path) -> None:
    """Write the budgets of the poses at ``lengths`` (N,) m (one Budget each, the same sources) to
    ``path``: a panel per output name of ``outputs``."""
    sources = [s.name for s in budgets[0].sources]
    colours = plt.get_cmap("tab10")(np.arange(len(sources)) % 10)
    fig, axes = plt.subplots(len(outputs), 1, figsize=(8.0, 2.4 * len(outputs)), dpi=110, sharex=True)
    for ax, output in zip(np.atleast_1d(axes), outputs):
        lines = [b.line(output) for b in budgets]
        shares = np.array([[line.shares.get(s, 0.0) for s in sources] for line in lines]).T
        ax.stackplot(lengths, shares, colors=colours, labels=sources, alpha=0.75)
        ax.set_ylim(0.0, 1.0)
        ax.set_ylabel("share of u²")
        ax.set_title(f"{output} [{lines[0].output.unit}]", fontsize=10, loc="left")
        relative = ax.twinx()
        percent = np.array([100.0 * line.u / abs(line.value) for line in lines])
        relative.plot(lengths, percent, color="black", lw=1.8, label="u / |value|")
        relative.set_ylabel("u / |value| [%]")
        relative.set_ylim(0.0, 1.25 * float(np.nanmax(percent)))
    first = np.atleast_1d(axes)[0]
    handles, labels = first.get_legend_handles_labels()
    handles += [plt.Line2D([], [], color="black", lw=1.8)]
    labels += ["u / |value| (right axis)"]
    fig.legend(handles, labels, loc="lower center", ncol=3, fontsize=8, frameon=False)
    np.atleast_1d(axes)[-1].set_xlabel(xlabel)
    fig.suptitle(title, fontsize=11)
    fig.tight_layout(rect=(0.0, 0.08, 1.0, 0.97))
    fig.savefig(path)
    plt.close(fig)
