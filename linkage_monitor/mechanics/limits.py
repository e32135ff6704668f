"""Plausibility limits of the measured inputs: what a sensor can read on this linkage.

The monitor refuses a reading outside its limit before any physics (a sensor or bus fault
must not reach the solver). Limits come from the file (``measurements.limits``, name ->
[min, max]) or, by default, from the geometry:
- cylinder length, m: the interval of lengths around the reference length over which the
  linkage assembles (a sweep of the cylinder alone, the other cylinders at their reference
  length), widened by CYLINDER_MARGIN of it on each side — a reading just outside is then
  still judged by the solver ("cannot assemble ... by N mm"), a reading far outside is a fault;
- joint angle, rad: the angle's span over that sweep (or over a sweep of the angle itself when
  no cylinder drives the linkage), widened by ANGLE_MARGIN; compared modulo 2π, so a sensor
  reporting in [−π, π) or [0, 2π) reads inside the same range;
- chamber pressure, Pa absolute: up to RELIEF_FACTOR × the cylinder's relief pressure (gauge)
  + 1 atm, or DEFAULT_MAX_PRESSURE without one; from UNIT_SLIP × that upper limit with a relief
  pressure, else from MIN_ABSOLUTE_PRESSURE (a hydraulic transducer reading below it is dead or
  disconnected). The lower limit with a relief pressure is where every pressure the circuit can
  hold lands when its kPa are sent as Pa (9.2 MPa read as 9.2 kPa: a plausible-looking load near
  zero otherwise); a chamber that low (−72 kPa gauge for belarus_1221's 19.4 MPa relief) is oil
  under deep suction, releasing its air, not a chamber holding a load. (The pressure that holds
  the linkage's own weight is no lower limit: the presets' links are massless, it is 0 gauge, and
  a lowered implement in float reads about that, noise either side.)
Units SI; frame x forward, z up, origin at the rear wheels' ground contact.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Mapping

import numpy as np

from . import spans_cache
from .capacity import interval_around
from .constants import ATMOSPHERIC_PRESSURE
from .errors import LinkageError
from .model import Mechanism
from .results import Status, angle_readings
from .schema import mechanism_from_dict
from .solver import Solver

CYLINDER_MARGIN = 0.05     # share of the assemblable length interval added on each side
ANGLE_MARGIN = 0.2         # rad added on each side of the swept angle span
MIN_ABSOLUTE_PRESSURE = 1e3  # Pa absolute
UNIT_SLIP = 1e-3           # a pressure read in kPa and sent as Pa: this × the true value
RELIEF_FACTOR = 1.5        # × relief pressure (gauge): above it the reading is not a pressure the circuit can hold
DEFAULT_MAX_PRESSURE = 100e6  # Pa absolute, without a relief pressure in the file
SWEEP_POINTS = 141
MAX_ABS_ANGLE = 4.0 * math.pi   # rad: sensors report in [−π, π) or [0, 2π), ±2π off at most
UNDRIVEN_FACTOR = 4.0    # × reference length: the bound of a cylinder that does not drive the linkage alone
SPANS_KEPT = 16   # mechanism descriptions whose swept spans are kept (``_swept_spans_of``)
_SPANS: dict[str, dict[str, tuple[float, float]]] = {}   # a description (canonical JSON) -> its swept spans


@dataclass(frozen=True)
class Limit:
    """Plausible range [lo, hi] of one input (m, rad, or Pa absolute) and where it comes from."""

    name: str
    kind: str      # 'cylinder' | 'angle' | 'pressure'
    lo: float
    hi: float
    unit: str
    source: str    # 'file' | 'geometry' | 'relief pressure' | 'default'

    def inside(self, value: float | np.ndarray) -> bool | np.ndarray:
        """Whether ``value`` (one reading, or an array of readings: then elementwise) is inside: the
        rule ``check`` words. An angle is compared by its equivalent (modulo 2π) nearest the range, and
        one with |angle| > MAX_ABS_ANGLE is not inside; NaN is not inside."""
        v = value
        if self.kind != "angle":
            return (self.lo <= v) & (v <= self.hi)
        if self.hi - self.lo < 2.0 * math.pi:
            centre = 0.5 * (self.lo + self.hi)   # the equivalent (modulo 2π) nearest the range
            v = centre + (np.array([_remainder(x) for x in (v - centre).tolist()]) if isinstance(v, np.ndarray)
                          else _remainder(v - centre))
        size = np.abs(value) if isinstance(value, np.ndarray) else abs(value)
        return (size <= MAX_ABS_ANGLE) & (self.lo <= v) & (v <= self.hi)

    def check(self, value: float) -> str | None:
        """None if ``value`` is inside, else a sentence naming the input, the value and the limit."""
        if self.kind == "angle" and abs(value) > MAX_ABS_ANGLE:
            return (f"angle '{self.name}' = {value:.6g} rad is not an angle a sensor reports (|angle| > "
                    f"{MAX_ABS_ANGLE:.6g} rad): sensor fault?")
        if self.inside(value):
            return None
        v = value
        what = {"cylinder": "cylinder length", "angle": "angle", "pressure": "absolute pressure"}[self.kind]
        cause = "sensor fault?"
        if self.kind == "pressure" and self.lo <= v / UNIT_SLIP <= self.hi:
            cause = (f"looks like kPa sent as Pa? ({v / UNIT_SLIP:.6g} Pa would be inside; check the sensor's unit "
                     "scaling), or a sensor fault")
        return (f"{what} '{self.name}' = {value:.6g} {self.unit} is outside its plausible range "
                f"[{self.lo:.6g}, {self.hi:.6g}] {self.unit} (from the {self.source}): {cause}")


def _remainder(offset: float) -> float:
    """``offset`` (rad) moved by whole turns into [−π, π] (IEEE remainder); a NaN or infinite one as it is."""
    return math.remainder(offset, 2.0 * math.pi) if math.isfinite(offset) else offset



def input_limits(mech: Mechanism) -> dict[str, Limit]:
    """The limit of every measured input of ``mech``, keyed by measurement name."""
    out: dict[str, Limit] = {}
    spans = _swept_spans_of(mech)
    reference = mech.reference_inputs.get("cylinders", {})
    for name in mech.measurements.cylinders:
        if name in spans:
            out[name] = Limit(name, "cylinder", *spans[name], "m", "geometry")
        else:   # not drivable alone: a wide bound around the reference length
            out[name] = Limit(name, "cylinder", 0.0, UNDRIVEN_FACTOR * _reference_length(mech, name, reference),
                              "m", "default")
    for a in mech.measurements.angles:
        lo, hi = spans.get(a.name, (-math.inf, math.inf))
        out[a.name] = Limit(a.name, "angle", lo, hi, "rad", "geometry" if a.name in spans else "default")
    for p in mech.measurements.pressures:
        relief = mech.cylinder(p.cylinder).relief_pressure
        hi = RELIEF_FACTOR * relief + ATMOSPHERIC_PRESSURE if relief else DEFAULT_MAX_PRESSURE
        lo = max(MIN_ABSOLUTE_PRESSURE, UNIT_SLIP * hi) if relief else MIN_ABSOLUTE_PRESSURE
        out[p.name] = Limit(p.name, "pressure", lo, hi, "Pa", "relief pressure" if relief else "default")
    for name, (lo, hi) in mech.measurements.limits.items():
        out[name] = Limit(name, out[name].kind, lo, hi, out[name].unit, "file")
    return out


def _reference_length(mech: Mechanism, name: str, reference: Mapping[str, float]) -> float:
    cyl = mech.cylinder(name)
    return float(reference.get(name, np.hypot(*(mech.points[cyl.rod_end.point] - mech.points[cyl.base.point]))))


def driven_by(mech: Mechanism, kind: str, entry: object) -> Solver | None:
    """A solver of ``mech`` driven by this one input alone, or None if it does not fix the pose."""
    raw = {**dict(mech.raw), "measurements": {kind: [entry]}, "reference_inputs": {}}
    try:
        return Solver(mechanism_from_dict(raw, file=mech.file))
    except LinkageError:
        return None


def _swept_spans_of(mech: Mechanism) -> dict[str, tuple[float, float]]:
    """``_swept_spans`` of ``mech``, kept for the last SPANS_KEPT descriptions in this process and
    on disk (``spans_cache``) for the next: a replay, a fleet worker's every bag, a reconfigured or
    restarted node build a monitor of the same mechanism again, and the sweeps took most of the
    time a monitor takes to build (~30 ms of ~40 for belarus_1221, and the batch kernels only
    they load at start-up)."""
    key = mech.description_key
    spans = _SPANS.pop(key, None)
    if spans is None:
        stored = spans_cache.entry_key(key, {"cylinder_margin": CYLINDER_MARGIN, "angle_margin": ANGLE_MARGIN,
                                             "sweep_points": SWEEP_POINTS})
        names = [*mech.measurements.cylinders, *(a.name for a in mech.measurements.angles)]
        spans = spans_cache.load(stored, names)
        if spans is None:
            spans = _swept_spans(mech)
            spans_cache.store(stored, spans)
    _SPANS[key] = spans   # the last one used is the newest
    while len(_SPANS) > SPANS_KEPT:
        del _SPANS[next(iter(_SPANS))]
    return dict(spans)


def _swept_spans(mech: Mechanism) -> dict[str, tuple[float, float]]:
    """Geometry ranges (m, rad) of the inputs that drive the linkage alone: a measured cylinder swept
    alone gives its assemblable interval (widened by CYLINDER_MARGIN) and the span of every angle
    sensor over it (widened by ANGLE_MARGIN); an angle that drives alone is swept over a full turn."""
    spans: dict[str, tuple[float, float]] = {}
    angle_values: dict[str, list[np.ndarray]] = {a.name: [] for a in mech.measurements.angles}
    reference = mech.reference_inputs.get("cylinders", {})
    for cyl in mech.measurements.cylinders:
        solver = driven_by(mech, "cylinders", cyl)
        if solver is None:
            continue
        length0 = _reference_length(mech, cyl, reference)
        grid = np.linspace(0.4 * length0, 1.8 * length0, SWEEP_POINTS)
        batch = solver.solve_batch(cylinders={cyl: grid}, reach=False)
        ok = batch.status != Status.ASSEMBLY
        interval = interval_around(grid, ok, length0)
        if interval is None:
            continue
        lo, hi = interval
        pad = CYLINDER_MARGIN * (hi - lo) + (grid[1] - grid[0])
        spans[cyl] = (float(max(lo - pad, 0.0)), float(hi + pad))
        inside = ok & (grid >= lo) & (grid <= hi)
        for name, values in angle_readings(mech, batch).items():
            angle_values[name].append(values[inside])
    for a, entry in zip(mech.measurements.angles, mech.raw["measurements"].get("angles") or []):
        spans_of: list[np.ndarray] = [v for v in angle_values[a.name] if v.size]
        if not spans_of:
            solver = driven_by(mech, "angles", entry)
            if solver is not None:
                grid = a.reference + np.linspace(-math.pi, math.pi, SWEEP_POINTS)
                batch = solver.solve_batch(angles={a.name: grid}, reach=False)
                interval = interval_around(grid, batch.status != Status.ASSEMBLY, a.reference)
                spans_of = [np.array(interval)] if interval is not None else []
        if spans_of:
            allv = np.concatenate(spans_of)
            spans[a.name] = (float(allv.min()) - ANGLE_MARGIN, float(allv.max()) + ANGLE_MARGIN)
    return spans
