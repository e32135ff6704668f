"""What the linkage looks like in Rerun: side view of the links, hinge and cylinder forces, time series.

Solver results (SI, global frame x forward, z up, origin at the rear wheels' ground contact)
go to a Rerun recording (rerun-sdk 0.41) under these entity paths:

- ``linkage/links``: one line strip per body (closed polygon for bodies with >= 3 points);
  ``linkage/hinges``: hinge points; ``linkage/cylinders``: cylinder axes (base to rod end);
  ``linkage/hinges/forces``, ``linkage/cylinders/forces``: force arrows (one scale, stated in
  the ``linkage/force_scale`` text log); ``linkage/ground``: the ground line and the origin B (static).
- ``forces/cylinders/<name>``, ``forces/hinges/<name>``: force magnitudes, kN (cylinder: + pushing).
- whatever the caller passes as ``extra`` (``steerability/ratio``, ``steerability/ratio_min``,
  ``lift/reserve``; ``lift/reserve_limit`` = 1.0 is added with ``lift/reserve``;
  ``transmission/min_angle``, the smallest transmission angle along the linkage's chain of dyads
  in degrees, with ``transmission/dead_centre``, the dead-centre threshold in degrees, where it is
  defined: see :func:`machine_series`).
- ``status``: a text line for every pose whose status is not ok.
- with the error budget or the weighing on: the 95 % bands of the plotted series, the weighed
  implement mass and its centre of gravity on the linkage (``viz.rerun_estimates``).

Drawing frame: Rerun's 2D y axis points down, so a point (x, z) is drawn at (x, -z): the
tractor stands upright, forward is to the right and the rear hitch (x < 0) on the left.
Time is the ROS header stamp on the ``ros_time`` timeline, never wall time.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, Mapping, Sequence

import numpy as np
import rerun as rr
import rerun.blueprint as rrb

from linkage_monitor.mechanics import BatchResult, Mechanism, Result, Status

from . import rerun_estimates as estimates
from .drawing import BODY_COLORS, CYLINDER_COLOR, GROUND_COLOR, HINGE_FORCE_COLOR, body_outline, force_scale

APPLICATION_ID = "linkage_monitor"
TIMELINE = "ros_time"
BOUNDS_MARGIN = 0.35
"""m: free space around the linkage in the 2D view (room for the force arrows and labels)."""
FLUSH_TIMEOUT_S = 0.5   # s, longest wait for a flush of the live node's .rrd before it counts as failed
FILE_BATCHING = rr.ChunkBatcherConfig(flush_tick=5.0, flush_num_bytes=64 * 2**20, flush_num_rows=100_000)
"""Chunks of a file recording: one per entity per 5 s of logging. A live file of tiny chunks (the
default 200 ms tick; out-of-order stamps split them further) opened in the viewer 0.41 with its
side view stuck loading — no linkage drawn, deterministically — while `rerun rrd optimize` of
the same file drew it (test/test_rerun_live.py)."""
LARGEST_HINGES = 5
"""How many hinge reactions the hinge plot shows by default (see :func:`largest_hinges`)."""

_DRAW = np.array([1.0, -1.0])  # (x, z) -> Rerun 2D (x, y down): flip z
_CYLINDER_SERIES_COLORS = [CYLINDER_COLOR, (255, 220, 0), (255, 90, 160), (160, 110, 40)]
_HINGE_COLOR = (240, 240, 240)
_CYLINDER_FORCE_COLOR = (255, 200, 0)
_SERIES_STYLES: dict[str, tuple[str, tuple[int, int, int], float]] = {
    "steerability/ratio": ("front axle share of the unit's weight", (90, 170, 250), 2.0),
    "steerability/ratio_min": ("required minimum", (255, 70, 70), 1.5),
    "lift/reserve": ("lift reserve = capacity / needed force", (120, 220, 120), 2.0),
    "lift/reserve_limit": ("1.0 = at capacity", (255, 70, 70), 1.5),
    "transmission/min_angle": ("smallest transmission angle", (200, 140, 255), 2.0),
    "transmission/dead_centre": ("dead-centre threshold", (255, 70, 70), 1.5),
    estimates.MASS_PATH: ("implement mass weighed", estimates.MASS_COLOR, 2.0),
}
_REFERENCE_LINES = {"lift/reserve": ("lift/reserve_limit", 1.0)}  # series -> (reference series, value)


def machine_series(steerability: Mapping[str, Any], lift_capacity: Mapping[str, Any],
                   transmission_angle: Any = None, dead_centre_deg: float | None = None) -> dict[str, Any]:
    """The machine-level series the blueprint plots, by entity path (floats or (N,) arrays):
    steerability ratio and its minimum (-), lift reserve (-); with ``transmission_angle`` (rad, the
    solver's ``transmission_angle``, NaN where the general path solved) the smallest transmission
    angle in degrees, and with ``dead_centre_deg`` (degrees) the dead-centre threshold beside it
    wherever the angle is defined. Missing values are left out."""
    series = {"steerability/ratio": steerability.get("ratio"), "steerability/ratio_min": steerability.get("ratio_min"),
              "lift/reserve": lift_capacity.get("reserve")}
    if transmission_angle is not None:
        degrees = np.degrees(np.asarray(transmission_angle, dtype=float))
        series["transmission/min_angle"] = degrees if degrees.ndim else float(degrees)
        if dead_centre_deg is not None:
            threshold = np.where(np.isfinite(degrees), float(dead_centre_deg), np.nan)
            series["transmission/dead_centre"] = threshold if threshold.ndim else float(threshold)
    return {path: value for path, value in series.items() if value is not None}


def drawing_xy(points_xz: np.ndarray) -> np.ndarray:
    """Rerun 2D coordinates (x, y down) of points (x, z) in m, frame x forward / z up: (x, -z)."""
    return np.asarray(points_xz, dtype=float) * _DRAW


def linkage_bounds(points_xz: np.ndarray, margin: float = BOUNDS_MARGIN) -> rrb.VisualBounds2D:
    """2D view bounds (drawing frame) fitting points (x, z) in m and the ground line z = 0, plus ``margin`` m."""
    pts = np.asarray(points_xz, dtype=float).reshape(-1, 2)
    pts = pts[np.isfinite(pts).all(axis=1)]
    if pts.size == 0:
        raise ValueError("linkage_bounds: no finite point to fit the view to; pass the mechanism's points (m)")
    xy = drawing_xy(np.vstack([pts, [[pts[:, 0].min(), 0.0]]]))
    lo, hi = xy.min(axis=0) - margin, xy.max(axis=0) + margin
    return rrb.VisualBounds2D(x_range=[lo[0], hi[0]], y_range=[lo[1], hi[1]])


def largest_hinges(batch: BatchResult, n: int = LARGEST_HINGES) -> list[str]:
    """Names of the ``n`` hinges with the largest peak reaction magnitude (N) over the batch, largest first."""
    peak = {name: np.nanmax(np.hypot(f[:, 0], f[:, 1]), initial=0.0) for name, f in batch.hinge_force.items()}
    return sorted(peak, key=peak.__getitem__, reverse=True)[:n]


def default_blueprint(mechanism: Mechanism, *, hinges: Sequence[str] | None = None,
                      extent_xz: np.ndarray | None = None, live: bool = False, weighing: bool = False) -> rrb.Blueprint:
    """The layout a recording opens in: linkage side view + status log (left), five time series (right).

    hinges: hinge names shown in the hinge-reaction plot (default all; see :func:`largest_hinges`);
    extent_xz: points (x, z) in m the 2D view must fit (default the mechanism's reference points);
    live: the time cursor follows the latest pose (a running viewer); else (an .rrd file) it opens
    paused on the first pose. (Rerun 0.41's viewer, following the end of some finished files, draws
    an empty side view: test_rerun_view.py.) weighing: a sixth plot, the weighed implement mass.
    """
    extent = np.array(list(mechanism.points.values())) if extent_xz is None else extent_xz
    hinge_contents = ("$origin/**" if hinges is None
                      else [f"forces/hinges/{rr.escape_entity_path_part(h)}/**" for h in hinges])   # with its band
    linkage = rrb.Spatial2DView(origin="linkage", name=f"{mechanism.name}: side view (x forward, z up)",
                                visual_bounds=linkage_bounds(extent))
    plots = rrb.Vertical(
        rrb.TimeSeriesView(origin="forces/cylinders", name="Cylinder force, kN (+ pushing)",
                           plot_legend=rrb.PlotLegend(corner="RightTop")),
        rrb.TimeSeriesView(origin="forces/hinges", contents=hinge_contents, name="Hinge reactions, kN",
                           plot_legend=rrb.PlotLegend(corner="RightTop")),
        rrb.TimeSeriesView(origin="steerability", name="Steerability: front axle load share"),
        rrb.TimeSeriesView(origin="lift", name="Lift reserve (< 1: cannot lift)"),
        rrb.TimeSeriesView(origin="transmission", name="Transmission angle, ° (below red: dead centre)"),
        *([rrb.TimeSeriesView(origin="weighing", name="Implement mass weighed, kg (95 % band)")] if weighing else []),
    )
    status = rrb.TextLogView(origin="/", name="Status", columns=rrb.archetypes.TextLogColumns(text_log_columns=[
        rrb.encodings.TextLogColumn("EntityPath", visible=False), rrb.encodings.TextLogColumn("LogLevel"),
        rrb.encodings.TextLogColumn("Body")]))
    left = rrb.Vertical(linkage, status, row_shares=[5, 1])
    return rrb.Blueprint(rrb.Horizontal(left, plots, column_shares=[3, 2]),
                         rrb.BlueprintPanel(state="collapsed"), rrb.SelectionPanel(state="collapsed"),
                         rrb.TimePanel(state="collapsed", timeline=TIMELINE,
                                       play_state="following" if live else "paused"))


class RerunView:
    """Logs solver results of one mechanism to a Rerun recording (entity paths: see the module docstring).

    force_scale: m of arrow per N of force; None = chosen so that the largest force of the first
    logged pose (``log_pose``) or of the batch (``log_batch``) is drawn ``drawing.ARROW_LENGTH`` m long.
    The recording's wall-clock timelines (log_time, log_tick) are switched off: ``ros_time`` only.
    """

    def __init__(self, mechanism: Mechanism, recording: rr.RecordingStream, *,
                 force_scale: float | None = None) -> None:
        self.mechanism = mechanism
        self.recording = recording
        self.force_scale = force_scale
        self._bodies = [(b, body_outline(mechanism, b.points)) for b in mechanism.bodies]
        self._hinge_names = [h.name for h in mechanism.hinges]
        self._hinge_points = [h.point for h in mechanism.hinges]
        self._cylinders = [(c.name, c.base.point, c.rod_end.point) for c in mechanism.cylinders]
        self._styled: set[str] = set()
        self._weighing_styled = False
        self._scale_logged = False
        recording.set_log_time_enabled(False)
        recording.set_log_tick_enabled(False)
        self._log_static()

    # ---- constructors -------------------------------------------------------------------------
    @classmethod
    def to_file(cls, mechanism: Mechanism, path: str | Path, *, blueprint: rrb.Blueprint | None = None,
                force_scale: float | None = None) -> "RerunView":
        """A view writing to an .rrd file at ``path`` (opens with ``rerun <path>``), with ``default_blueprint``."""
        recording = rr.RecordingStream(APPLICATION_ID, batcher_config=FILE_BATCHING)
        recording.save(path, default_blueprint=blueprint or default_blueprint(mechanism))
        return cls(mechanism, recording, force_scale=force_scale)

    @classmethod
    def to_viewer(cls, mechanism: Mechanism, url: str | None = None, *, blueprint: rrb.Blueprint | None = None,
                  force_scale: float | None = None) -> "RerunView":
        """A view streaming to a running Rerun viewer (``url`` as ``connect_grpc``; None = local default)."""
        recording = rr.RecordingStream(APPLICATION_ID)
        recording.connect_grpc(url, default_blueprint=blueprint or default_blueprint(mechanism, live=True))
        return cls(mechanism, recording, force_scale=force_scale)

    def flush(self, timeout_s: float = FLUSH_TIMEOUT_S) -> None:
        """Write everything logged so far to the sink, waiting at most ``timeout_s`` (the live node
        calls it every second, so that a power cut loses at most about a second of the .rrd; the
        write of a second's poses takes well under a millisecond). RuntimeError when it is not
        written in time: the sink has failed (its disk is full; Rerun's file writer does not say
        so otherwise) or cannot keep up."""
        self.recording.flush(timeout_sec=timeout_s)

    def close(self) -> None:
        """Flush everything logged so far and close the sink (the .rrd file is complete afterwards).
        RuntimeError when the sink has failed (e.g. its disk is full)."""
        try:
            self.recording.flush()
        finally:
            self.recording.disconnect()

    # ---- live: one pose -----------------------------------------------------------------------
    def log_pose(self, stamp_ns: int, result: Result, extra: Mapping[str, float] | None = None,
                 bands: Mapping[str, np.ndarray] | None = None) -> None:
        """Log one solved pose at ROS time ``stamp_ns`` (ns since the epoch, header stamp).

        extra: machine-level scalars by entity path (e.g. ``steerability/ratio``: 1, ``lift/reserve``: 1);
        non-finite values are skipped. A pose whose status is not ok is also written to ``status``.
        bands: 95 % half-widths of plotted series by entity path, (1,) each in the series' unit
        (``rerun_estimates.budget_bands``): their 95 % bands beside them.
        """
        rec = self.recording
        series = _with_reference_lines({k: np.array([v], dtype=float) for k, v in (extra or {}).items()})
        for path, _ in series:
            self._style_series(path)
        rec.set_time(TIMELINE, timestamp=np.datetime64(int(stamp_ns), "ns"))
        if result.status != "ok":
            self.log_status(stamp_ns, f"{result.status}: {result.message}", level="WARN")
        points = result.point_xz   # rows in the mechanism's order, as hinge_force and cylinder_values
        if not np.isfinite(points).all():
            return
        hinge_f, cyl_f = result.hinge_force, result.cylinder_values[:, 1]
        self._fix_scale(stamp_ns, hinge_f, cyl_f)
        strips, hinge_xy, cyl_strips, cyl_vec = self._geometry({k: v[None] for k, v in result.points.items()},
                                                               hinge_f[None], cyl_f[None])
        rec.log("linkage/links", rr.LineStrips2D(strips))
        rec.log("linkage/hinges", rr.Points2D(hinge_xy))
        rec.log("linkage/hinges/forces", rr.Arrows2D(origins=hinge_xy, vectors=drawing_xy(hinge_f) * self.force_scale))
        if self._cylinders:
            rec.log("linkage/cylinders", rr.LineStrips2D(cyl_strips))
            rec.log("linkage/cylinders/forces", rr.Arrows2D(origins=cyl_strips[:, 1], vectors=cyl_vec))
        plotted = {**{f"forces/hinges/{rr.escape_entity_path_part(name)}": np.array([np.hypot(*f) / 1e3])
                      for name, f in zip(self._hinge_names, hinge_f)},
                   **{f"forces/cylinders/{rr.escape_entity_path_part(name)}": np.array([f / 1e3])
                      for (name, _, _), f in zip(self._cylinders, cyl_f)}}
        for path, value in plotted.items():
            rec.log(path, rr.Scalars(float(value[0])))
        for path, value in series:
            if np.isfinite(value[0]):
                rec.log(path, rr.Scalars(float(value[0])))
        for path, source, value in estimates.band_series({**plotted, **dict(series)}, bands or {}):
            self._style_band(path, source)
            if np.isfinite(value[0]):
                rec.log(path, rr.Scalars(float(value[0])))

    def log_status(self, stamp_ns: int, text: str, level: str = "ERROR") -> None:
        """Write ``text`` to the ``status`` log at ROS time ``stamp_ns`` (ns), e.g. a pose the solver rejected."""
        self.recording.set_time(TIMELINE, timestamp=np.datetime64(int(stamp_ns), "ns"))
        self.recording.log("status", rr.TextLog(text, level=level))

    # ---- replay: many poses as columns --------------------------------------------------------
    def log_batch(self, stamps_ns: np.ndarray, batch: BatchResult,
                  extra: Mapping[str, np.ndarray] | None = None, bands: Mapping[str, np.ndarray] | None = None
                  ) -> None:
        """Log N solved poses at ROS times ``stamps_ns`` (N,) ns with ``send_columns`` (geometry and scalars).

        extra: machine-level series by entity path, each (N,); non-finite samples are skipped.
        bands: 95 % half-widths of plotted series, (N,) each (as ``log_pose``'s).
        Poses whose status is not ok go to ``status``; poses that could not be solved (NaN) are
        left out of the geometry and of the series.
        """
        stamps = np.asarray(stamps_ns, dtype=np.int64)
        n = len(batch)
        if stamps.shape != (n,):
            raise ValueError(f"log_batch: stamps_ns has shape {stamps.shape}, the batch has {n} poses: "
                             f"pass one header stamp (ns) per pose")
        series = {k: np.asarray(v, dtype=float) for k, v in (extra or {}).items()}
        for path, values in series.items():
            self._style_series(path)
            if values.shape != (n,):
                raise ValueError(f"log_batch: extra['{path}'] has shape {values.shape}, expected ({n},): "
                                 f"one value per pose")
        times = np.array(stamps, dtype="datetime64[ns]")
        for i in np.flatnonzero(batch.status != 0):
            self.log_status(int(stamps[i]), f"pose {i}: {batch.messages[i] or 'status ' + str(batch.status[i])}",
                            level="WARN" if batch.status[i] == Status.LIFT_OFF else "ERROR")
        points = np.stack([batch.points[p] for p in self.mechanism.points], axis=1)
        ok = np.isfinite(points).all(axis=(1, 2))
        hinge_f = np.stack([batch.hinge_force[h] for h in self._hinge_names], axis=1).reshape(n, -1, 2)
        cyl_f = np.array([batch.cylinder_force[c] for c, _, _ in self._cylinders]).T.reshape(n, -1)
        if ok.any():
            self._fix_scale(int(stamps[np.argmax(ok)]), hinge_f[ok], cyl_f[ok])
            self._send_geometry(times[ok], {k: v[ok] for k, v in batch.points.items()}, hinge_f[ok], cyl_f[ok])
        plotted = {**{f"forces/hinges/{rr.escape_entity_path_part(name)}": np.hypot(f[:, 0], f[:, 1]) / 1e3
                      for name, f in zip(self._hinge_names, np.moveaxis(hinge_f, 1, 0))},
                   **{f"forces/cylinders/{rr.escape_entity_path_part(name)}": f / 1e3
                      for (name, _, _), f in zip(self._cylinders, cyl_f.T)}}
        for path, values in plotted.items():
            self._send_series(path, times, values)
        for path, values in _with_reference_lines(series):
            self._style_series(path)  # the reference lines
            self._send_series(path, times, values)
        for path, source, values in estimates.band_series({**plotted, **series}, bands or {}):
            self._style_band(path, source)
            self._send_series(path, times, values)

    def log_weighing(self, stamps_ns: np.ndarray, implement_poses: np.ndarray, mass: np.ndarray,
                     mass_u: np.ndarray, cg: np.ndarray, cg_u: np.ndarray) -> None:
        """The weighing's estimate at N poses (ROS times ``stamps_ns`` (N,) ns): the implement ``mass`` (kg)
        with its 95 % band from ``mass_u`` (kg, 1 sigma), and its centre of gravity ``cg`` (N, 2) m in the
        reference pose, drawn on the linkage where the implement body is (``implement_poses`` (N, 3): x, z
        of its origin, m, its rotation from the reference pose, rad) with its 95 % box (``cg_u`` (N, 2) m,
        1 sigma). NaN where there is no estimate (left out)."""
        times = np.array(np.asarray(stamps_ns, dtype=np.int64), dtype="datetime64[ns]")
        if not self._weighing_styled:
            estimates.log_static(self.recording)
            self._style_series(estimates.MASS_PATH)
            self._weighing_styled = True
        self._send_series(estimates.MASS_PATH, times, mass)
        for path, source, values in estimates.band_series({estimates.MASS_PATH: mass},
                                                          {estimates.MASS_PATH: estimates.COVERAGE_FACTOR * mass_u}):
            self._style_band(path, source)
            self._send_series(path, times, values)
        estimates.send_implement_cg(self.recording, TIMELINE, times,
                                    estimates.implement_cg_at(self.mechanism, implement_poses, cg), cg_u)

    # ---- internals ----------------------------------------------------------------------------
    def _log_static(self) -> None:
        """Labels, colours, widths and series styles, once, as static data."""
        rec, mech = self.recording, self.mechanism
        colors = [GROUND_COLOR if b.ground else BODY_COLORS[k % len(BODY_COLORS)]
                  for k, (b, _) in enumerate(self._bodies)]
        rec.log("linkage/links", rr.LineStrips2D.from_fields(labels=[b.name for b, _ in self._bodies], colors=colors,
                                                             radii=[0.008 if b.ground else 0.018 for b, _ in self._bodies],
                                                             draw_order=10.0),
                static=True)
        rec.log("linkage/hinges", rr.Points2D.from_fields(labels=self._hinge_names, colors=_HINGE_COLOR, radii=0.03,
                                                          draw_order=30.0),
                static=True)
        rec.log("linkage/cylinders", rr.LineStrips2D.from_fields(labels=[c for c, _, _ in self._cylinders],
                                                                 colors=CYLINDER_COLOR, radii=0.03,
                                                                 draw_order=20.0), static=True)
        rec.log("linkage/hinges/forces", rr.Arrows2D.from_fields(colors=HINGE_FORCE_COLOR, radii=0.012,
                                                                        draw_order=40.0), static=True)
        rec.log("linkage/cylinders/forces", rr.Arrows2D.from_fields(colors=_CYLINDER_FORCE_COLOR, radii=0.012,
                                                                           draw_order=40.0), static=True)
        pts = np.array(list(mech.points.values()))
        rec.log("linkage/ground", rr.LineStrips2D([drawing_xy(np.array([[pts[:, 0].min() - 1.0, 0.0], [pts[:, 0].max() + 1.0, 0.0]]))],
                                                  colors=GROUND_COLOR, radii=0.01), static=True)
        rec.log("linkage/ground/origin", rr.Points2D([[0.0, 0.0]], labels="origin: rear wheels' ground contact",
                                                     colors=GROUND_COLOR, radii=0.03), static=True)
        for k, h in enumerate(self._hinge_names):
            rec.log(f"forces/hinges/{rr.escape_entity_path_part(h)}",
                    rr.SeriesLines(names=f"{h} (on {mech.hinges[k].bodies[1]})",
                                   colors=BODY_COLORS[k % len(BODY_COLORS)]), static=True)
        for k, (c, _, _) in enumerate(self._cylinders):
            rec.log(f"forces/cylinders/{rr.escape_entity_path_part(c)}",
                    rr.SeriesLines(names=c, colors=_CYLINDER_SERIES_COLORS[k % len(_CYLINDER_SERIES_COLORS)]),
                    static=True)

    def _style_series(self, path: str) -> None:
        """Static SeriesLines for an ``extra`` series the first time it appears (known paths get names/colours)."""
        if path in self._styled:
            return
        if not path or path.startswith("/"):
            raise ValueError(f"extra series '{path}': use an entity path without a leading slash, e.g. 'lift/reserve'")
        name, color, width = _SERIES_STYLES.get(path, (path, None, 2.0))
        self.recording.log(path, rr.SeriesLines(names=name, colors=color, widths=width), static=True)
        self._styled.add(path)

    def _style_band(self, path: str, source: str) -> None:
        """Static SeriesLines for the band ``path`` of the series ``source`` the first time it appears:
        thin, in the series' colour where the view gives it one."""
        if path in self._styled:
            return
        name, color, _ = _SERIES_STYLES.get(source, (source.rsplit("/", 1)[-1], (160, 160, 160), 2.0))
        self.recording.log(path, estimates.band_style(name, color), static=True)
        self._styled.add(path)

    def _fix_scale(self, stamp_ns: int, hinge_f: np.ndarray, cyl_f: np.ndarray) -> None:
        """Choose the arrow scale (m/N) from the given forces if not set yet, and say it in ``linkage/force_scale``."""
        if self.force_scale is None:
            self.force_scale = force_scale(hinge_f, cyl_f)
        if not self._scale_logged:
            self.recording.set_time(TIMELINE, timestamp=np.datetime64(int(stamp_ns), "ns"))
            self.recording.log("linkage/force_scale", rr.TextLog(
                f"force arrows: 1 m = {1e-3 / self.force_scale:.0f} kN "
                f"(hinges red: force on the second body of the hinge; cylinders yellow: force on the rod end)",
                level="INFO"))
            self._scale_logged = True

    def _geometry(self, points: Mapping[str, np.ndarray], hinge_f: np.ndarray,
                  cyl_f: np.ndarray) -> tuple[list[np.ndarray], np.ndarray, np.ndarray, np.ndarray]:
        """Drawing-frame geometry of M poses: body strips (M·B, pose-major), hinge points (M·H, 2),
        cylinder strips (M·C, 2, 2) and cylinder force arrows (M·C, 2, scaled to m)."""
        m = len(hinge_f)
        outlines = [drawing_xy(np.stack([points[p] for p in outline], axis=1)) for _, outline in self._bodies]
        strips = [o[i] for i in range(m) for o in outlines]
        hinge_xy = drawing_xy(np.stack([points[p] for p in self._hinge_points], axis=1)).reshape(-1, 2)
        ends = (np.stack([np.stack([points[b], points[r]], axis=1) for _, b, r in self._cylinders], axis=1)
                if self._cylinders else np.empty((m, 0, 2, 2)))
        cyl_strips = drawing_xy(ends).reshape(-1, 2, 2)
        axis = cyl_strips[:, 1] - cyl_strips[:, 0]
        unit = axis / np.maximum(np.hypot(axis[:, 0], axis[:, 1]), 1e-12)[:, None]
        cyl_vec = unit * (cyl_f.reshape(-1) * self.force_scale)[:, None]  # + pushing: away from the base
        return strips, hinge_xy, cyl_strips, cyl_vec

    def _send_geometry(self, times: np.ndarray, points: Mapping[str, np.ndarray], hinge_f: np.ndarray,
                       cyl_f: np.ndarray) -> None:
        """Geometry of M solved poses as columns, one partition (all bodies/hinges/cylinders) per time step."""
        rec, m = self.recording, len(times)
        index = [rr.TimeColumn(TIMELINE, timestamp=times)]
        strips, hinge_xy, cyl_strips, cyl_vec = self._geometry(points, hinge_f, cyl_f)
        n_b, n_h, n_c = len(self._bodies), len(self._hinge_names), len(self._cylinders)
        rec.send_columns("linkage/links", index, rr.LineStrips2D.columns(strips=strips).partition([n_b] * m))
        rec.send_columns("linkage/hinges", index, rr.Points2D.columns(positions=hinge_xy).partition([n_h] * m))
        rec.send_columns("linkage/hinges/forces", index, rr.Arrows2D.columns(
            origins=hinge_xy, vectors=drawing_xy(hinge_f).reshape(-1, 2) * self.force_scale).partition([n_h] * m))
        if n_c:
            rec.send_columns("linkage/cylinders", index, rr.LineStrips2D.columns(strips=cyl_strips).partition([n_c] * m))
            rec.send_columns("linkage/cylinders/forces", index, rr.Arrows2D.columns(
                origins=cyl_strips[:, 1], vectors=cyl_vec).partition([n_c] * m))

    def _send_series(self, path: str, times: np.ndarray, values: np.ndarray) -> None:
        """One scalar series as a column; non-finite samples (unsolved poses) are left out."""
        keep = np.isfinite(values)
        if keep.any():
            self.recording.send_columns(path, [rr.TimeColumn(TIMELINE, timestamp=times[keep])],
                                        rr.Scalars.columns(scalars=values[keep]))


def _with_reference_lines(series: Mapping[str, np.ndarray]) -> list[tuple[str, np.ndarray]]:
    """The ``extra`` series plus their constant reference lines (``lift/reserve`` -> ``lift/reserve_limit`` = 1)."""
    out = list(series.items())
    for path, values in series.items():
        if path in _REFERENCE_LINES:
            ref_path, ref_value = _REFERENCE_LINES[path]
            out.append((ref_path, np.where(np.isfinite(values), ref_value, np.nan)))
    return out
