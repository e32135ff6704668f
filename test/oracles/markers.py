"""Oracle for the linkage markers: the MarkerArray of a solved pose built with rclpy's generated
message classes, field by field (how the package built it before it wrote the CDR bytes directly,
``linkage_monitor.wire.markers.LinkageMarkers``). Serialized by rclpy, it is what the package's
bytes must decode to (test/test_markers.py).

Frame ``linkage``: the mechanism's plane x–z with y = 0 (x forward, z up; REP 103 axes), units m.
"""

from __future__ import annotations

from typing import Sequence

import numpy as np
from builtin_interfaces.msg import Duration
from geometry_msgs.msg import Point, Vector3
from std_msgs.msg import ColorRGBA
from visualization_msgs.msg import Marker, MarkerArray

from linkage_monitor.mechanics import Mechanism, Result
from linkage_monitor.wire.markers import FRAME, HINGE_DIAMETER, LIFETIME_S, LINE_WIDTH, TEXT_HEIGHT
from linkage_monitor.ros.messages import header
from linkage_monitor.viz.drawing import (BODY_COLORS, CYLINDER_COLOR, GROUND_COLOR, HINGE_FORCE_COLOR, body_outline,
                                         force_scale)


class LinkageMarkers:
    """Builds the MarkerArray of solved poses of one mechanism (module docstring: what is drawn)."""

    def __init__(self, mechanism: Mechanism) -> None:
        self.mechanism = mechanism
        self.force_scale: float | None = None   # m/N, fixed by the first pose drawn
        # wire.markers.LinkageMarkers.__init__'s lines, again on purpose: an oracle shares no code with its subject
        self._bodies = [(b.name, body_outline(mechanism, b.points),
                         GROUND_COLOR if b.ground else BODY_COLORS[k % len(BODY_COLORS)])
                        for k, b in enumerate(mechanism.bodies)]
        self._hinges = [(h.name, h.point) for h in mechanism.hinges]
        self._cylinders = [(c.name, c.base.point, c.rod_end.point) for c in mechanism.cylinders]

    def markers(self, stamp_ns: int, result: Result) -> MarkerArray:
        """The drawing of one solved pose, stamped ``stamp_ns`` (the input's header stamp)."""
        points = {name: (float(x), float(z)) for name, (x, z) in result.points.items()}
        hinge_f = np.array([[result.hinges[h].fx, result.hinges[h].fz] for h, _ in self._hinges]).reshape(-1, 2)
        cyl_f = np.array([result.cylinders[c].force for c, _, _ in self._cylinders])
        if self.force_scale is None:
            self.force_scale = force_scale(hinge_f, cyl_f)
        scale = self.force_scale
        head = header(stamp_ns)
        head.frame_id = FRAME
        out: list[Marker] = []

        def marker(ns: str, ident: int, kind: int, color: tuple[int, int, int], size: tuple[float, float, float],
                   where: Sequence[tuple[float, float]] = (), text: str = "") -> Marker:
            m = Marker(header=head, ns=ns, id=ident, type=kind, action=Marker.ADD, text=text,
                       scale=Vector3(x=size[0], y=size[1], z=size[2]), lifetime=Duration(sec=LIFETIME_S),
                       color=ColorRGBA(r=color[0] / 255, g=color[1] / 255, b=color[2] / 255, a=1.0),
                       points=[Point(x=x, y=0.0, z=z) for x, z in where])
            m.pose.orientation.w = 1.0
            out.append(m)
            return m

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
            label = marker("labels", k, Marker.TEXT_VIEW_FACING, (255, 255, 255), (0.0, 0.0, TEXT_HEIGHT),
                           text=f"{name} {np.hypot(fx, fz) / 1e3:.1f} kN")
            label.pose.position = Point(x=x, y=0.0, z=z + 1.5 * TEXT_HEIGHT)
        for k, ((_, base, rod_end), force) in enumerate(zip(self._cylinders, cyl_f)):
            (bx, bz), (rx, rz) = points[base], points[rod_end]
            length = max(float(np.hypot(rx - bx, rz - bz)), 1e-12)
            ux, uz = (rx - bx) / length, (rz - bz) / length   # + pushing: away from the base
            marker("cylinder_forces", k, Marker.ARROW, CYLINDER_COLOR, (0.015, 0.03, 0.05),
                   [(rx, rz), (rx + ux * force * scale, rz + uz * force * scale)])
        return MarkerArray(markers=out)
