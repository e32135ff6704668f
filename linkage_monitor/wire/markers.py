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
The MarkerArray is written straight to its CDR bytes (by its layout, ``wire.compose``: laid out once
per pattern of label lengths, then filled for each pose, or for many poses at once), not built from rclpy's message classes and serialized
(oracle of that: test/oracles/markers.py).
"""

from __future__ import annotations

from typing import Any, Sequence

import numpy as np

from linkage_monitor.mechanics import Mechanism, Result
from linkage_monitor.viz.drawing import (BODY_COLORS, CYLINDER_COLOR, GROUND_COLOR, HINGE_FORCE_COLOR, body_outline,
                                         force_scale)

from .cdr import string_bytes, time_bytes
from .compose import STAMP, Column, Composer, Spliced
from .layout import constants

MARKER_ARRAY, MARKER = "visualization_msgs/msg/MarkerArray", "visualization_msgs/msg/Marker"
FRAME = "linkage"
DEFAULT_RATE_HZ = 10.0
LINE_WIDTH = 0.02      # m
HINGE_DIAMETER = 0.05  # m
TEXT_HEIGHT = 0.05     # m
LIFETIME_S = 2         # a marker not refreshed for this long disappears (the node stopped solving)


DESCRIPTIONS_KEPT = 16   # mechanism descriptions whose layouts are kept (a replay, a fleet worker's next bag)
_LAYOUTS: dict[str, dict[tuple[int, ...], "_Layout"]] = {}   # description_key -> label residues -> layout


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
    the numbers that change with the pose; kept per mechanism description, for the process), and a
    pose is that copy with its numbers scattered in and its label texts spliced in: no
    field-by-field writing per pose.
    """

    MAX_LAYOUTS = 64   # label-length patterns kept per mechanism description (a lift passes through a few)

    def __init__(self, mechanism: Mechanism) -> None:
        self.mechanism = mechanism
        self.force_scale: float | None = None   # m/N, fixed by the first pose drawn
        # test/oracles/markers.py writes these lines again on purpose: an oracle shares no code with what it checks.
        self._bodies = [(b.name, body_outline(mechanism, b.points),
                         GROUND_COLOR if b.ground else BODY_COLORS[k % len(BODY_COLORS)])
                        for k, b in enumerate(mechanism.bodies)]
        self._point_names = tuple(mechanism.points)
        self._row = {p: k for k, p in enumerate(self._point_names)}
        self._hinge_names = [h.name for h in mechanism.hinges]
        self._hinge_rows = np.array([self._row[h.point] for h in mechanism.hinges], dtype=np.intp)
        self._base_rows, self._rod_rows = (np.array([self._row[getattr(c, end).point] for c in mechanism.cylinders],
                                                    dtype=np.intp) for end in ("base", "rod_end"))
        self._layouts = _LAYOUTS.pop(mechanism.description_key, {})   # those of this description laid out before
        _LAYOUTS[mechanism.description_key] = self._layouts
        while len(_LAYOUTS) > DESCRIPTIONS_KEPT:
            del _LAYOUTS[next(iter(_LAYOUTS))]

    def markers(self, stamp_ns: int, result: Result) -> bytes:
        """The drawing of one solved pose, stamped ``stamp_ns`` (the input's header stamp), as the
        CDR bytes of a visualization_msgs/MarkerArray (published and recorded as they are)."""
        return self.markers_of([stamp_ns], [result])[0]

    def markers_of(self, stamps_ns: Sequence[int], results: Sequence[Result]) -> list[bytes]:
        """``markers`` of each of ``results`` (solved poses) stamped with ``stamps_ns``: the numbers of all
        of them computed at once, then each pattern of label lengths filled for all its poses at once."""
        if not results:
            return []
        xz = np.stack([r.point_xz if r.names.points == self._point_names
                       else r.point_xz[[r.names.points.index(p) for p in self._point_names]] for r in results])
        hinge_f = np.stack([r.hinge_force for r in results])             # (K, H, 2), rows in the mechanism's order
        cyl_f = np.stack([r.cylinder_values[:, 1] for r in results])     # (K, C)
        if self.force_scale is None:
            self.force_scale = force_scale(hinge_f[0], cyl_f[0])
        scale, n = self.force_scale, len(results)
        at, base, rod = xz[:, self._hinge_rows], xz[:, self._base_rows], xz[:, self._rod_rows]
        length = np.maximum(np.hypot(rod[..., 0] - base[..., 0], rod[..., 1] - base[..., 1]), 1e-12)
        along = (rod - base) / length[..., None]   # + pushing: away from the base
        source = np.concatenate([xz.reshape(n, -1), (at + hinge_f * scale).reshape(n, -1), at[..., 1] + 1.5 * TEXT_HEIGHT,
                                 (rod + along * cyl_f[..., None] * scale).reshape(n, -1)], axis=1)
        stamps = np.frombuffer(b"".join(map(time_bytes, stamps_ns)), np.uint8).reshape(n, 8)
        numbers = np.concatenate([stamps, source.astype("<f8").view(np.uint8)], axis=1)   # per pose: stamp, floats
        texts = [[string_bytes(f"{name} {force / 1e3:.1f} kN") for name, force in zip(self._hinge_names, forces)]
                 for forces in np.hypot(hinge_f[..., 0], hinge_f[..., 1]).tolist()]
        by_pattern: dict[tuple[int, ...], list[int]] = {}
        for k, labels in enumerate(texts):   # the padding after each text depends on its length modulo 8
            by_pattern.setdefault(tuple(len(text) % 8 for text in labels), []).append(k)
        found: list[bytes] = [b""] * n
        for key, poses in by_pattern.items():
            layout = self._layout(key)
            data = np.tile(layout.data, (len(poses), 1))
            data[:, layout.slots] = numbers[poses][:, layout.sources]
            for row, k in zip(data, poses):
                raw = row.data   # sliced without copies: the join below is the one copy
                pieces: list[bytes | memoryview] = []
                last = 0
                for cut, text in zip(layout.cuts, texts[k]):
                    pieces += (raw[last:cut], text)
                    last = cut
                pieces.append(raw[last:])
                found[k] = b"".join(pieces)
        return found

    def _layout(self, residues: tuple[int, ...]) -> "_Layout":
        """The layout of the label residues ``residues``, laid out at its first use (``_lay_out``)."""
        layout = self._layouts.get(residues)
        if layout is None:
            if len(self._layouts) >= self.MAX_LAYOUTS:
                self._layouts.clear()
            layout = self._layouts[residues] = self._lay_out(residues)
        return layout

    def _lay_out(self, residues: tuple[int, ...]) -> "_Layout":
        """The message for label texts whose serialized sizes are ``residues`` modulo 8 (placeholders
        of those sizes; a text 8·k bytes longer shifts what follows it by whole 8-byte words). What changes
        with the pose is a ``Column`` of ``markers``' source vector (floats are constant):
        [x, z of every point | arrow tip x, z per hinge | label z per hinge | arrow tip x, z per
        cylinder]; every marker's stamp is a ``STAMP``."""
        n_points, n_hinges = len(self._point_names), len(self._hinge_names)
        tip, label_z, cylinder_tip = 2 * n_points, 2 * n_points + 2 * n_hinges, 2 * n_points + 3 * n_hinges
        kinds = constants(MARKER)

        def point(p: str) -> tuple[Column, Column]:
            return Column(2 * self._row[p]), Column(2 * self._row[p] + 1)

        def marker(ns: str, ident: int, kind: str, color: tuple[int, int, int], size: tuple[float, float, float],
                   where: Sequence[tuple[Column, Column]] = (), text: int | None = None,
                   position: tuple[float | Column, float | Column] = (0.0, 0.0)) -> dict[str, Any]:
            """One visualization_msgs/Marker's values (the fields not named: their defaults, empty)."""
            return {"header": {"stamp": STAMP, "frame_id": FRAME}, "ns": ns, "id": ident, "type": kinds[kind],
                    "action": kinds["ADD"],
                    "pose": {"position": {"x": position[0], "y": 0.0, "z": position[1]}, "orientation": {"w": 1.0}},
                    "scale": dict(zip("xyz", size)),
                    "color": {"r": color[0] / 255, "g": color[1] / 255, "b": color[2] / 255, "a": 1.0},
                    "lifetime": LIFETIME_S * 1_000_000_000, "frame_locked": False,
                    "points": [{"x": x, "y": 0.0, "z": z} for x, z in where],
                    "text": "" if text is None else Spliced("x" * ((residues[text] - 5) % 8))}   # 4 + length + NUL bytes

        markers = [marker("links", k, "LINE_STRIP", color, (LINE_WIDTH, 0.0, 0.0), [point(p) for p in outline])
                   for k, (_, outline, color) in enumerate(self._bodies)]
        markers += [marker("cylinders", k, "LINE_STRIP", CYLINDER_COLOR, (1.5 * LINE_WIDTH, 0.0, 0.0),
                           [point(c.base.point), point(c.rod_end.point)]) for k, c in enumerate(self.mechanism.cylinders)]
        markers.append(marker("hinges", 0, "SPHERE_LIST", (240, 240, 240), (HINGE_DIAMETER,) * 3,
                              [point(h.point) for h in self.mechanism.hinges]))
        for k, h in enumerate(self.mechanism.hinges):
            x, z = point(h.point)
            markers.append(marker("reactions", k, "ARROW", HINGE_FORCE_COLOR, (0.015, 0.03, 0.05),
                                  [(x, z), (Column(tip + 2 * k), Column(tip + 2 * k + 1))]))
            markers.append(marker("labels", k, "TEXT_VIEW_FACING", (255, 255, 255), (0.0, 0.0, TEXT_HEIGHT), text=k,
                                  position=(x, Column(label_z + k))))
        markers += [marker("cylinder_forces", k, "ARROW", CYLINDER_COLOR, (0.015, 0.03, 0.05),
                           [point(c.rod_end.point), (Column(cylinder_tip + 2 * k), Column(cylinder_tip + 2 * k + 1))])
                    for k, c in enumerate(self.mechanism.cylinders)]
        composer = Composer().message(MARKER_ARRAY, {"markers": markers})
        slots = [(at + b, b) for at in composer.stamps for b in range(8)]   # (byte offset, byte of the source:
        slots += [(at + b, 8 + 8 * column + b) for at, column in composer.columns for b in range(8)]   # 0-7 stamp)
        return _Layout(composer.data, composer.spliced, slots)


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
