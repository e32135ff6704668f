"""The linkage as visualization_msgs/MarkerArray, for RViz and Foxglove 3D panels.

Frame ``linkage`` (FRAME): the mechanism's plane x–z with y = 0 (x forward, z up, origin at
the rear wheels' ground contact; REP 103 axes), units m. Per solved pose, namespaces:

- ``links``: one LINE_STRIP per body (its outline, as in the Rerun view), ``cylinders``: one
  LINE_STRIP per cylinder (base to rod end);
- ``hinges``: one SPHERE_LIST of all hinge points;
- ``reactions``: one ARROW per hinge from the hinge point along the force on the hinge's second
  body, drawn ``force_scale`` m per N (the largest force of the first drawn pose is
  ARROW_LENGTH = 0.4 m long: the Rerun view's scale), ``cylinder_forces`` likewise at the rod end;
- ``labels``: one TEXT_VIEW_FACING per hinge, ``<hinge> <force> kN``.

Published at a display rate (DisplayGate), not at every message; the bag records what is published.
The MarkerArray is written straight to its CDR bytes (``ros.cdr.Writer``), not built from rclpy's
message classes and serialized (oracle of that: test/oracles/markers.py).
"""

from __future__ import annotations

from typing import Sequence

import numpy as np
from visualization_msgs.msg import Marker

from linkage_monitor.mechanics import Mechanism, Result
from linkage_monitor.viz.drawing import (BODY_COLORS, CYLINDER_COLOR, GROUND_COLOR, HINGE_FORCE_COLOR, body_outline,
                                         force_scale)

from .cdr import Writer

MARKER_ARRAY = "visualization_msgs/msg/MarkerArray"
FRAME = "linkage"
DEFAULT_RATE_HZ = 10.0
LINE_WIDTH = 0.02      # m
HINGE_DIAMETER = 0.05  # m
TEXT_HEIGHT = 0.05     # m
LIFETIME_S = 2         # a marker not refreshed for this long disappears (the node stopped solving)


class DisplayGate:
    """Lets a solved pose through at most ``rate_hz`` times per second of header stamps (0: never)."""

    def __init__(self, rate_hz: float) -> None:
        self.period_ns = int(1e9 / rate_hz) if rate_hz > 0.0 else None
        self.last_ns: int | None = None

    def due(self, stamp_ns: int) -> bool:
        """True (and remembered) when ``stamp_ns`` is a period or more from the last pose let through."""
        if self.period_ns is None:
            return False
        if self.last_ns is None or abs(stamp_ns - self.last_ns) >= self.period_ns:
            self.last_ns = stamp_ns
            return True
        return False


class LinkageMarkers:
    """Builds the MarkerArray of solved poses of one mechanism (module docstring: what is drawn)."""

    def __init__(self, mechanism: Mechanism) -> None:
        self.mechanism = mechanism
        self.force_scale: float | None = None   # m/N, fixed by the first pose drawn
        self._bodies = [(b.name, body_outline(mechanism, b.points),
                         GROUND_COLOR if b.ground else BODY_COLORS[k % len(BODY_COLORS)])
                        for k, b in enumerate(mechanism.bodies)]
        self._hinges = [(h.name, h.point) for h in mechanism.hinges]
        self._cylinders = [(c.name, c.base.point, c.rod_end.point) for c in mechanism.cylinders]
        self._blocks: dict = {}   # Writer.constant's cache

    def markers(self, stamp_ns: int, result: Result) -> bytes:
        """The drawing of one solved pose, stamped ``stamp_ns`` (the input's header stamp), as the
        CDR bytes of a visualization_msgs/MarkerArray (published and recorded as they are)."""
        points = dict(zip(result.names.points, result.point_xz.tolist()))   # name -> [x, z]
        hinge_f, cyl_f = result.hinge_force, result.cylinder_values[:, 1]   # rows in the mechanism's order
        if self.force_scale is None:
            self.force_scale = force_scale(hinge_f, cyl_f)
        scale = self.force_scale
        w = Writer()
        w.uint32(len(self._bodies) + 2 * len(self._cylinders) + 1 + 2 * len(self._hinges))

        def marker(ns: str, ident: int, kind: int, color: tuple[int, int, int], size: tuple[float, float, float],
                   where: Sequence[tuple[float, float]] = (), text: str = "",
                   position: tuple[float, float] = (0.0, 0.0)) -> None:
            """One visualization_msgs/Marker, in message order (Marker.msg, Kilted); the runs of fields
            that do not change between poses come from ``self._blocks`` (``Writer.constant``)."""
            w.time(stamp_ns)                                   # header
            w.constant((ns, ident, kind), lambda b: _identity(b, ns, ident, kind), self._blocks)
            w.float64s(position[0], 0.0, position[1], 0.0, 0.0, 0.0, 1.0)   # pose: position, orientation
            w.constant((size, color), lambda b: _appearance(b, size, color), self._blocks)
            w.uint32(len(where))                               # points (geometry_msgs/Point: x, y, z)
            if where:
                w.float64s(*[c for x, z in where for c in (x, 0.0, z)])
            w.constant("before text", _before_text, self._blocks)
            w.string(text)
            w.constant("after text", _after_text, self._blocks)

        for k, (_, outline, color) in enumerate(self._bodies):
            marker("links", k, Marker.LINE_STRIP, color, (LINE_WIDTH, 0.0, 0.0), [points[p] for p in outline])
        for k, (_, base, rod_end) in enumerate(self._cylinders):
            marker("cylinders", k, Marker.LINE_STRIP, CYLINDER_COLOR, (1.5 * LINE_WIDTH, 0.0, 0.0),
                   [points[base], points[rod_end]])
        marker("hinges", 0, Marker.SPHERE_LIST, (240, 240, 240), (HINGE_DIAMETER,) * 3,
               [points[p] for _, p in self._hinges])
        for k, ((name, p), (fx, fz)) in enumerate(zip(self._hinges, hinge_f)):
            x, z = points[p]
            marker("reactions", k, Marker.ARROW, HINGE_FORCE_COLOR, (0.015, 0.03, 0.05),
                   [(x, z), (x + fx * scale, z + fz * scale)])
            marker("labels", k, Marker.TEXT_VIEW_FACING, (255, 255, 255), (0.0, 0.0, TEXT_HEIGHT),
                   text=f"{name} {np.hypot(fx, fz) / 1e3:.1f} kN", position=(x, z + 1.5 * TEXT_HEIGHT))
        for k, ((_, base, rod_end), force) in enumerate(zip(self._cylinders, cyl_f)):
            (bx, bz), (rx, rz) = points[base], points[rod_end]
            length = max(float(np.hypot(rx - bx, rz - bz)), 1e-12)
            ux, uz = (rx - bx) / length, (rz - bz) / length   # + pushing: away from the base
            marker("cylinder_forces", k, Marker.ARROW, CYLINDER_COLOR, (0.015, 0.03, 0.05),
                   [(rx, rz), (rx + ux * force * scale, rz + uz * force * scale)])
        return bytes(w.data)


def _identity(w: Writer, ns: str, ident: int, kind: int) -> None:
    """Marker fields header.frame_id .. action."""
    w.string(FRAME)
    w.string(ns)
    w.int32(ident)
    w.int32(kind)
    w.int32(Marker.ADD)


def _appearance(w: Writer, size: tuple[float, float, float], color: tuple[int, int, int]) -> None:
    """Marker fields scale .. frame_locked."""
    w.float64s(*size)
    w.float32s(color[0] / 255, color[1] / 255, color[2] / 255, 1.0)
    w.time(LIFETIME_S * 1_000_000_000)                 # lifetime
    w.uint8(0)                                         # frame_locked


def _before_text(w: Writer) -> None:
    """Marker fields colors .. uv_coordinates: empty."""
    w.uint32(0)                                        # colors
    w.string("")                                       # texture_resource
    w.time(0)                                          # texture (sensor_msgs/CompressedImage): header,
    w.string("")
    w.string("")                                       # format,
    w.uint32(0)                                        # data
    w.uint32(0)                                        # uv_coordinates


def _after_text(w: Writer) -> None:
    """Marker fields mesh_resource .. mesh_use_embedded_materials: empty."""
    w.string("")                                       # mesh_resource
    w.string("")                                       # mesh_file: filename,
    w.uint32(0)                                        # data
    w.uint8(0)                                         # mesh_use_embedded_materials
