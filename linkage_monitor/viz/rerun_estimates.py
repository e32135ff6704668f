"""What the Rerun view draws of the uncertainties (with the error budget or the weighing on).

- 95 % bands: beside a plotted series ``<path>`` (a cylinder force, a hinge reaction, the
  steerability ratio, the lift reserve, the weighed mass), two thin series ``<path>/low95`` and
  ``<path>/high95`` = value ∓ its 95 % half-width in the series' unit: k·u from the poses' error
  budgets (``budget_bands``; ``mechanics.uncertainty``, k from the budget's shape), 1.96 u for the
  weighing's estimate (its intervals);
- the weighing: ``weighing/mass`` (kg, the estimate converging, with its band) and on the linkage
  ``linkage/implement_cg`` the weighed centre of gravity carried with the implement to the pose,
  and ``linkage/implement_cg/interval`` its 95 % box (±1.96 u along x and z of the reference pose).

Units SI but the forces in kN, as the view plots them; frame x forward, z up (drawn at (x, −z)).
"""

from __future__ import annotations

from typing import Mapping, Sequence

import numpy as np
import rerun as rr

from linkage_monitor.mechanics import Mechanism
from linkage_monitor.mechanics.budget import Budget

COVERAGE_FACTOR = 1.96   # the weighing estimate's 95 % half-width in standard uncertainties (WeighingEstimate.interval)
BAND_PARTS = ("low95", "high95")
CG_PATH, CG_BOX_PATH = "linkage/implement_cg", "linkage/implement_cg/interval"
MASS_PATH = "weighing/mass"
MASS_COLOR = (255, 0, 255)   # the weighed implement: mass series, cg point and box
_DRAW = np.array([1.0, -1.0])  # (x, z) -> Rerun 2D (x, y down), as rerun_view


def budget_bands(mechanism: Mechanism, budgets: Sequence[Budget | None]) -> dict[str, np.ndarray]:
    """The 95 % half-width (``Budget.half_width_of``: k times the standard uncertainty, k from the budget's
    shape) of every series the view plots that the budgets cover, by entity path, (N,) each in the
    series' unit (cylinder forces and hinge reactions kN, the steerability ratio and the lift reserve
    dimensionless); NaN for a pose without a budget."""
    outputs = {**{f"forces/cylinders/{rr.escape_entity_path_part(c.name)}": (f"{c.name}.force", 1e-3)
                  for c in mechanism.cylinders},
               **{f"forces/hinges/{rr.escape_entity_path_part(h.name)}": (f"{h.name}.magnitude", 1e-3)
                  for h in mechanism.hinges},
               "steerability/ratio": ("steerability_ratio", 1.0), "lift/reserve": ("lift_reserve", 1.0)}
    bands = {}
    for path, (output, scale) in outputs.items():
        half = np.array([b.half_width_of(output) if b is not None else np.nan for b in budgets]) * scale
        if np.isfinite(half).any():
            bands[path] = half
    return bands


def band_series(values: Mapping[str, np.ndarray], bands: Mapping[str, np.ndarray]
                ) -> list[tuple[str, str, np.ndarray]]:
    """(band path, the series' path, band values) of each plotted series with a band (its 95 %
    half-width by path, the series' unit): its ``low95`` and ``high95`` (value ∓ half-width)."""
    out = []
    for path, half in bands.items():
        value = values.get(path)
        if value is None:
            continue
        out += [(f"{path}/{BAND_PARTS[0]}", path, value - half), (f"{path}/{BAND_PARTS[1]}", path, value + half)]
    return out


def band_style(name: str, color: tuple[int, int, int] | None) -> rr.SeriesLines:
    """The static style of a band series of the series called ``name`` drawn in ``color``."""
    return rr.SeriesLines(names=f"{name}: 95 % band", colors=color, widths=0.75)


def implement_cg_at(mechanism: Mechanism, body_poses: np.ndarray, cg_ref: np.ndarray) -> np.ndarray:
    """Points ``cg_ref`` (N, 2) m, given in the mechanism's reference pose, carried with its implement
    body to N poses ``body_poses`` (N, 3): (x, z) of the body's origin (the centroid of its points in
    the reference pose) and its rotation from the reference pose (rad) -> (N, 2) m."""
    body = next(b for b in mechanism.bodies if b.name == mechanism.implement.body)   # type: ignore[union-attr]
    origin = np.mean([mechanism.points[p] for p in body.points], axis=0)
    theta = body_poses[:, 2]
    c, s = np.cos(theta), np.sin(theta)
    d = np.asarray(cg_ref, dtype=float) - origin
    return body_poses[:, :2] + np.column_stack([c * d[:, 0] - s * d[:, 1], s * d[:, 0] + c * d[:, 1]])


def log_static(recording: rr.RecordingStream) -> None:
    """The styles of the weighed cg on the linkage, once."""
    recording.log(CG_PATH, rr.Points2D.from_fields(labels="implement cg weighed", colors=MASS_COLOR, radii=0.04,
                                                   draw_order=50.0), static=True)
    recording.log(CG_BOX_PATH, rr.Boxes2D.from_fields(colors=MASS_COLOR, radii=0.006, draw_order=45.0), static=True)


def send_implement_cg(recording: rr.RecordingStream, timeline: str, times: np.ndarray, cg_xz: np.ndarray,
                      cg_u: np.ndarray) -> None:
    """The weighed cg at N poses (``cg_xz`` (N, 2) m, carried to the pose: ``implement_cg_at``) with its
    95 % box (``cg_u`` (N, 2) m, standard uncertainties along x and z); poses without one left out."""
    keep = np.isfinite(cg_xz).all(axis=1) & np.isfinite(cg_u).all(axis=1)
    if not keep.any():
        return
    index = [rr.TimeColumn(timeline, timestamp=times[keep])]
    centres = cg_xz[keep] * _DRAW
    recording.send_columns(CG_PATH, index, rr.Points2D.columns(positions=centres))
    recording.send_columns(CG_BOX_PATH, index, rr.Boxes2D.columns(centers=centres,
                                                                  half_sizes=COVERAGE_FACTOR * cg_u[keep]))
