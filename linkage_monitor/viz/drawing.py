"""What a drawing of the linkage shows, shared by the Rerun view and the ROS markers: each body's
outline, the body colours, and the force-arrow scale (m of arrow per N). Units SI; points (x, z)
in the mechanism frame (x forward, z up, origin at the rear wheels' ground contact)."""

from __future__ import annotations

from typing import Sequence

import numpy as np

from linkage_monitor.mechanics import Mechanism

ARROW_LENGTH = 0.4
"""m: drawn length of the largest force of the first pose (live) or of the whole batch (replay)."""
BODY_COLORS = [(90, 170, 250), (120, 220, 120), (250, 200, 80), (200, 130, 250), (90, 220, 220),
               (250, 140, 180), (180, 180, 120)]
GROUND_COLOR = (120, 120, 120)
CYLINDER_COLOR = (255, 140, 0)
"""RGB of the cylinders in the drawings and of the first cylinder's force series."""
HINGE_FORCE_COLOR = (255, 70, 70)


def body_outline(mechanism: Mechanism, names: Sequence[str]) -> list[str]:
    """Point names of a body in drawing order: as listed for 2 points; for >= 3 points sorted by
    angle about their centroid in the reference pose and closed (first point repeated)."""
    if len(names) < 3:
        return list(names)
    xz = np.array([mechanism.points[p] for p in names])
    centre = xz.mean(axis=0)
    order = np.argsort(np.arctan2(xz[:, 1] - centre[1], xz[:, 0] - centre[0]))
    ordered = [names[k] for k in order]
    return ordered + ordered[:1]


def force_scale(hinge_forces: np.ndarray, cylinder_forces: np.ndarray) -> float:
    """m/N such that the largest of these forces (hinge (..., 2) N, cylinder (...) N) is drawn
    ARROW_LENGTH long (forces below 1 N count as 1 N)."""
    largest = max(np.nanmax(np.hypot(hinge_forces[..., 0], hinge_forces[..., 1]), initial=0.0),
                  np.nanmax(np.abs(cylinder_forces), initial=0.0))
    return ARROW_LENGTH / max(float(largest), 1.0)
