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
The MarkerArray is written straight to its CDR bytes (``ros.cdr``: laid out once per pattern of
label lengths, then filled per pose), not built from rclpy's message classes and serialized
(oracle of that: test/oracles/markers.py).
"""

from __future__ import annotations

from typing import Sequence

import numpy as np
from visualization_msgs.msg import Marker

from linkage_monitor.mechanics import Mechanism, Result
from linkage_monitor.viz.drawing import (BODY_COLORS, CYLINDER_COLOR, GROUND_COLOR, HINGE_FORCE_COLOR, body_outline,
                                         force_scale)

from .cdr import Writer, string_bytes, time_bytes

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
    """Builds the MarkerArray of solved poses of one mechanism (module docstring: what is drawn).

    The message's layout is fixed for a mechanism up to the lengths of the label texts, whose
    residues modulo 8 set the alignment padding after each. So each pattern of those residues is
    laid out once (``_lay_out``: the bytes without the texts, the byte offsets of the stamps and of
    the numbers that change with the pose), and a pose is that copy with its numbers scattered in
    and its label texts spliced in: no field-by-field writing per pose.
    """

    MAX_LAYOUTS = 64   # label-length patterns kept (a lift passes through a few)

    def __init__(self, mechanism: Mechanism) -> None:
        self.mechanism = mechanism
        self.force_scale: float | None = None   # m/N, fixed by the first pose drawn
        self._bodies = [(b.name, body_outline(mechanism, b.points),
                         GROUND_COLOR if b.ground else BODY_COLORS[k % len(BODY_COLORS)])
                        for k, b in enumerate(mechanism.bodies)]
        self._point_names = tuple(mechanism.points)
        self._row = {p: k for k, p in enumerate(self._point_names)}
        self._hinge_names = [h.name for h in mechanism.hinges]
        self._hinge_rows = np.array([self._row[h.point] for h in mechanism.hinges], dtype=np.intp)
        self._base_rows, self._rod_rows = (np.array([self._row[getattr(c, end).point] for c in mechanism.cylinders],
                                                    dtype=np.intp) for end in ("base", "rod_end"))
        self._layouts: dict[tuple[int, ...], _Layout] = {}

    def markers(self, stamp_ns: int, result: Result) -> bytes:
        """The drawing of one solved pose, stamped ``stamp_ns`` (the input's header stamp), as the
        CDR bytes of a visualization_msgs/MarkerArray (published and recorded as they are)."""
        xz = result.point_xz
        if result.names.points != self._point_names:
            xz = xz[[result.names.points.index(p) for p in self._point_names]]
        hinge_f, cyl_f = result.hinge_force, result.cylinder_values[:, 1]   # rows in the mechanism's order
        if self.force_scale is None:
            self.force_scale = force_scale(hinge_f, cyl_f)
        scale = self.force_scale
        at, base, rod = xz[self._hinge_rows], xz[self._base_rows], xz[self._rod_rows]
        length = np.maximum(np.hypot(rod[:, 0] - base[:, 0], rod[:, 1] - base[:, 1]), 1e-12)
        along = (rod - base) / length[:, None]   # + pushing: away from the base
        source = np.concatenate([xz.ravel(), (at + hinge_f * scale).ravel(), at[:, 1] + 1.5 * TEXT_HEIGHT,
                                 (rod + along * cyl_f[:, None] * scale).ravel()])
        texts = [string_bytes(f"{name} {force / 1e3:.1f} kN")
                 for name, force in zip(self._hinge_names, result.hinge_magnitude.tolist())]
        key = tuple(len(text) % 8 for text in texts)   # the padding after each text depends on these
        layout = self._layouts.get(key)
        if layout is None:
            if len(self._layouts) >= self.MAX_LAYOUTS:
                self._layouts.clear()
            layout = self._layouts[key] = self._lay_out(key)
        data = layout.data.copy()
        data[layout.slots] = np.concatenate([np.frombuffer(time_bytes(stamp_ns), dtype=np.uint8),
                                             source.astype("<f8").view(np.uint8)])[layout.sources]
        raw = data.data   # sliced without copies: the join below is the one copy
        pieces: list[bytes | memoryview] = []
        last = 0
        for cut, text in zip(layout.cuts, texts):
            pieces += (raw[last:cut], text)
            last = cut
        pieces.append(raw[last:])
        return b"".join(pieces)

    def _lay_out(self, residues: tuple[int, ...]) -> "_Layout":
        """The message for label texts whose serialized sizes are ``residues`` modulo 8 (placeholders
        of those sizes; a text 8·k bytes longer shifts what follows it by whole 8-byte words). What changes
        with the pose is given as indices into ``markers``' source vector (ints; floats are constant):
        [x, z of every point | arrow tip x, z per hinge | label z per hinge | arrow tip x, z per
        cylinder]."""
        n_points, n_hinges = len(self._point_names), len(self._hinge_names)
        tip, label_z, cylinder_tip = 2 * n_points, 2 * n_points + 2 * n_hinges, 2 * n_points + 3 * n_hinges
        w = Writer()
        slots: list[tuple[int, int]] = []   # (byte offset, byte of the source: 0-7 the stamp, then 8 per value)
        texts: list[tuple[int, int]] = []   # (start, end) of each placeholder text's serialization

        def numbers(*values: float | int) -> None:
            for value in values:
                if isinstance(value, int):
                    at = w.float64()
                    slots.extend((at + b, 8 + 8 * value + b) for b in range(8))
                else:
                    w.float64(value)

        def point(p: str) -> tuple[int, int]:
            return 2 * self._row[p], 2 * self._row[p] + 1

        def marker(ns: str, ident: int, kind: int, color: tuple[int, int, int], size: tuple[float, float, float],
                   where: Sequence[tuple[int, int]] = (), text: int | None = None,
                   position: tuple[float | int, float | int] = (0.0, 0.0)) -> None:
            """One visualization_msgs/Marker, in message order (Marker.msg, Kilted)."""
            w.align(4)
            slots.extend((len(w.data) + b, b) for b in range(8))
            w.time(0)                                          # header: stamp,
            _identity(w, ns, ident, kind)                      # frame_id .. action
            numbers(position[0], 0.0, position[1], 0.0, 0.0, 0.0, 1.0)   # pose: position, orientation
            _appearance(w, size, color)
            w.uint32(len(where))                               # points (geometry_msgs/Point: x, y, z)
            for x, z in where:
                numbers(x, 0.0, z)
            _before_text(w)
            w.align(4)
            start = len(w.data)
            w.string("" if text is None else "x" * ((residues[text] - 5) % 8))   # 4 + length + NUL bytes
            if text is not None:
                texts.append((start, len(w.data)))
            _after_text(w)

        w.uint32(len(self._bodies) + 2 * len(self.mechanism.cylinders) + 1 + 2 * n_hinges)
        for k, (_, outline, color) in enumerate(self._bodies):
            marker("links", k, Marker.LINE_STRIP, color, (LINE_WIDTH, 0.0, 0.0), [point(p) for p in outline])
        for k, c in enumerate(self.mechanism.cylinders):
            marker("cylinders", k, Marker.LINE_STRIP, CYLINDER_COLOR, (1.5 * LINE_WIDTH, 0.0, 0.0),
                   [point(c.base.point), point(c.rod_end.point)])
        marker("hinges", 0, Marker.SPHERE_LIST, (240, 240, 240), (HINGE_DIAMETER,) * 3,
               [point(h.point) for h in self.mechanism.hinges])
        for k, h in enumerate(self.mechanism.hinges):
            x, z = point(h.point)
            marker("reactions", k, Marker.ARROW, HINGE_FORCE_COLOR, (0.015, 0.03, 0.05),
                   [(x, z), (tip + 2 * k, tip + 2 * k + 1)])
            marker("labels", k, Marker.TEXT_VIEW_FACING, (255, 255, 255), (0.0, 0.0, TEXT_HEIGHT), text=k,
                   position=(x, label_z + k))
        for k, c in enumerate(self.mechanism.cylinders):
            marker("cylinder_forces", k, Marker.ARROW, CYLINDER_COLOR, (0.015, 0.03, 0.05),
                   [point(c.rod_end.point), (cylinder_tip + 2 * k, cylinder_tip + 2 * k + 1)])
        return _Layout(w.data, texts, slots)


class _Layout:
    """The MarkerArray of one pattern of label lengths (``LinkageMarkers._lay_out``): its bytes with
    the label texts cut out, where each text goes, and which byte of the source (stamp, then the
    float64 values) each changing byte takes."""

    def __init__(self, data: bytearray, texts: list[tuple[int, int]], slots: list[tuple[int, int]]) -> None:
        keep = np.ones(len(data), dtype=bool)
        for start, end in texts:
            keep[start:end] = False
        shift = np.cumsum(~keep) - ~keep   # bytes cut out before each offset
        self.data = np.frombuffer(bytes(data), dtype=np.uint8)[keep].copy()
        self.cuts = [start - int(shift[start]) for start, _ in texts]   # where each text goes in ``data``
        offsets, sources = np.array(slots, dtype=np.intp).reshape(-1, 2).T
        self.slots, self.sources = offsets - shift[offsets], sources


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
