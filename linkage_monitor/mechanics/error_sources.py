"""The declared error sources of a mechanism: what its sensors, cylinder seals, point coordinates and
implement data are known to within (``error_sources`` of the mechanism YAML, docs/mechanism-schema.md; the model and the
defaults: docs/accuracy.md).

Every figure is a standard uncertainty (1 sigma) in the quantity's SI unit (m, rad, Pa, N, kg) once
read: a datasheet's ± bound (``accuracy``, ``class`` of ``full_scale``) is the half-width of a uniform
distribution, u = bound/√3; a quantization step q gives u = q/√12. A sensor or cylinder the file does
not list takes the default of its kind (``DEFAULT_*``, each with its source); one it lists takes
exactly what it lists (the figures it leaves out are 0).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from enum import Enum
from typing import Any, Iterable, Mapping, Protocol

SQRT3, SQRT12 = math.sqrt(3.0), math.sqrt(12.0)


class Motion(Enum):
    """How the lift cylinder moves at a pose: the seal friction's band depends on it."""

    LIFTING = "lifting"
    LOWERING = "lowering"
    STANDING = "standing"


@dataclass(frozen=True)
class SensorError:
    """One sensor's declared errors in its unit (m, rad or gauge Pa): ``bias`` (1 sigma, the same over
    a run), ``noise`` (1 sigma, drawn anew per sample) and ``resolution`` (the quantization step);
    ``origin`` says where the figures come from."""

    bias: float = 0.0
    noise: float = 0.0
    resolution: float = 0.0
    origin: str = ""

    def components(self) -> dict[str, float]:
        """Standard uncertainty of each part, by name (``bias``, ``noise``, ``resolution`` = step/√12)."""
        return {"bias": self.bias, "noise": self.noise, "resolution": self.resolution / SQRT12}

    @property
    def total(self) -> float:
        """The sensor's combined standard uncertainty (the parts independent): √(Σ u²)."""
        return math.sqrt(sum(u * u for u in self.components().values()))


@dataclass(frozen=True)
class SealFriction:
    """A cylinder's seal friction band while it moves: ``share`` of its force magnitude plus ``force``
    (N); standing, ``breakaway`` times that band (the static friction the seals can hold).
    ``origin`` says where the figures come from."""

    share: float = 0.0
    force: float = 0.0
    breakaway: float = 1.0
    origin: str = ""

    def band(self, cylinder_force: float, motion: Motion) -> float:
        """Half-width (N) of the band the friction lies in at a pose whose cylinder force is
        ``cylinder_force`` (N): moving, the kinetic band (its sign follows the motion, its size is not
        known better than the band); standing, the whole breakaway band, either sign."""
        kinetic = self.share * abs(cylinder_force) + self.force
        return kinetic * (self.breakaway if motion is Motion.STANDING else 1.0)

    def standard_uncertainty(self, cylinder_force: float, motion: Motion) -> float:
        """u (N) of the friction force: the band's half-width / √3 (uniform over the band)."""
        return self.band(cylinder_force, motion) / SQRT3


# The defaults (docs/accuracy.md, "Defaults"): a datasheet bound is the half-width of a uniform distribution.
DEFAULT_PRESSURE_FULL_SCALE = 25.0e6   # Pa: a 250 bar transducer, the usual range on a 20 MPa tractor hydraulic system
DEFAULT_PRESSURE_CLASS = 0.5           # % of full scale: accuracy class of an industrial pressure transducer
DEFAULT_ANGLE_ACCURACY = math.radians(0.2)   # rad: ± bound of a Hall-effect rotary position sensor
DEFAULT_STROKE_RESOLUTION = 1.0e-3     # m: ISO 11783-7 rear hitch position, 0.4 %/bit, over a 0.25 m stroke
DEFAULT_FRICTION_SHARE = 0.03          # of the force: seal friction of a hydraulic cylinder, a few per cent
DEFAULT_BREAKAWAY = 1.5                # static / kinetic seal friction
# m, 1 sigma per coordinate of a point the file does not list: 0, the coordinates as exact. A file's
# coordinates come from a drawing, a fit to published tables or a tape on the tractor, each to its own
# accuracy, which only its author knows (a tape and a plumb line give a few mm); a default would dominate
# every budget with a figure of none of them (docs/accuracy.md, "Geometry"): declare yours.
DEFAULT_POINT_TOLERANCE = 0.0

DEFAULT_PRESSURE = SensorError(bias=DEFAULT_PRESSURE_CLASS / 100.0 * DEFAULT_PRESSURE_FULL_SCALE / SQRT3,
                               origin="default: accuracy class 0.5 % of a 25 MPa full scale (pressure transducer)")
DEFAULT_ANGLE = SensorError(bias=DEFAULT_ANGLE_ACCURACY / SQRT3,
                            origin="default: ±0.2 deg (Hall-effect rotary position sensor)")
DEFAULT_STROKE = SensorError(resolution=DEFAULT_STROKE_RESOLUTION,
                             origin="default: 1 mm steps (ISO 11783-7 hitch position, 0.4 %/bit of a 0.25 m stroke)")
DEFAULT_FRICTION = SealFriction(share=DEFAULT_FRICTION_SHARE, breakaway=DEFAULT_BREAKAWAY,
                                origin="default: 3 % of the force, breakaway 1.5 times (hydraulic cylinder seals)")


@dataclass(frozen=True)
class PointTolerance:
    """A point's coordinate tolerances (m, 1 sigma, normal: the true point stays where it was built, the
    same over a run): ``x`` forward, ``z`` up; ``origin`` says where the figures come from."""

    x: float = 0.0
    z: float = 0.0
    origin: str = ""


@dataclass(frozen=True)
class ErrorSources:
    """The declared sources of one mechanism: ``sensors`` (measurement name -> SensorError; a measured
    input not listed takes the default of its kind, ``sensor``), ``friction`` (cylinder name ->
    SealFriction, likewise), ``points`` (point name -> PointTolerance; a point not listed takes
    ``point_tolerance``, m, for each coordinate) and ``implement_mass`` (kg, 1 sigma; 0 when the file
    gives none). ``declared`` False: the file has no ``error_sources`` block (every figure is a default)."""

    sensors: Mapping[str, SensorError] = field(default_factory=dict)
    friction: Mapping[str, SealFriction] = field(default_factory=dict)
    implement_mass: float = 0.0
    declared: bool = False
    defaults: bool = True
    points: Mapping[str, PointTolerance] = field(default_factory=dict)
    point_tolerance: float = DEFAULT_POINT_TOLERANCE

    def point(self, name: str) -> PointTolerance:
        """The coordinate tolerances of the point ``name``."""
        if name in self.points:
            return self.points[name]
        return PointTolerance(self.point_tolerance, self.point_tolerance,
                              "file: point_tolerance" if self.point_tolerance > 0.0 else "default: exact")

    def point_coordinates(self, names: Iterable[str]) -> list[tuple[str, int, float]]:
        """The toleranced coordinates of the points ``names``: (point, axis 0 = x or 1 = z, u in m) for
        each coordinate whose u is above 0, in the order of ``names``, x before z."""
        return [(name, axis, u) for name in names
                for axis, u in enumerate((self.point(name).x, self.point(name).z)) if u > 0.0]

    def sensor(self, name: str, kind: str) -> SensorError:
        """The errors of measurement ``name`` of ``kind`` (``cylinders``, ``angles``, ``pressures``)."""
        if name in self.sensors:
            return self.sensors[name]
        if not self.defaults:
            return SensorError(origin="none declared")
        return {"cylinders": DEFAULT_STROKE, "angles": DEFAULT_ANGLE, "pressures": DEFAULT_PRESSURE}[kind]

    def with_resolutions(self, steps: Mapping[str, tuple[str, float]]) -> "ErrorSources":
        """These sources with each named sensor's resolution at least the step given: name -> (kind, step
        in the sensor's SI unit), e.g. a CAN signal's DBC scale (``can.decoder.CanDecoder.resolutions``).
        A sensor whose declared (or default) resolution is coarser keeps it."""
        sensors = dict(self.sensors)
        for name, (kind, step) in steps.items():
            current = self.sensor(name, kind)
            if step > current.resolution:
                origin = f"{current.origin}; resolution {step:.4g} from its CAN signal's scale".lstrip("; ")
                sensors[name] = replace(current, resolution=step, origin=origin)
        return replace(self, sensors=sensors)

    def seal_friction(self, cylinder: str) -> SealFriction:
        """The seal friction of ``cylinder``."""
        if cylinder in self.friction:
            return self.friction[cylinder]
        return DEFAULT_FRICTION if self.defaults else SealFriction(origin="none declared")


NONE_DECLARED = ErrorSources(defaults=False, declared=True)   # every source 0: the model's own answer


class _Validator(Protocol):
    """What the schema's reader offers (``schema_values.ValueReader``): named failures and checked numbers."""

    def fail(self, key: str, reason: str) -> Exception: ...
    def mapping(self, value: Any, key: str, allowed: set[str], required: frozenset[str] | set[str] = ...) -> dict: ...
    def number(self, value: Any, key: str, minimum: float | None = None, positive: bool = False,
               maximum: float | None = None) -> float: ...


_SENSOR_KEYS = {"bias", "noise", "resolution", "accuracy", "class", "full_scale"}


def read_error_sources(reader: _Validator, value: Any, cylinders: set[str], points: set[str]) -> ErrorSources:
    """The ``error_sources`` block (None: every default) checked by ``reader``; ``cylinders`` and
    ``points`` are the mechanism's cylinder and point names."""
    if value is None:
        return ErrorSources()
    k = "error_sources"
    block = reader.mapping(value, k, {"defaults", "sensors", "cylinders", "implement", "points", "point_tolerance"})
    defaults = block.get("defaults", True)
    if not isinstance(defaults, bool):
        raise reader.fail(f"{k}.defaults", f"expected true or false, got {defaults!r}")
    listed = block.get("sensors") or {}
    if not isinstance(listed, dict):
        raise reader.fail(f"{k}.sensors", f"expected a mapping sensor name -> errors, got {type(listed).__name__}")
    # an entry naming no measurement of this mechanism is read and unused: a copy measuring fewer inputs
    # (calibration.drive_mechanism, capacity.stroke_mechanism) keeps the file's block
    sensors = {str(name): _sensor(reader, spec, f"{k}.sensors.{name}") for name, spec in listed.items()}
    friction = {}
    for name, spec in (reader.mapping(block.get("cylinders") or {}, f"{k}.cylinders", cylinders)).items():
        kc = f"{k}.cylinders.{name}"
        c = reader.mapping(spec, kc, {"friction_share", "friction_force", "breakaway"})
        friction[str(name)] = SealFriction(
            share=reader.number(c.get("friction_share", 0.0), f"{kc}.friction_share", minimum=0.0, maximum=1.0),
            force=reader.number(c.get("friction_force", 0.0), f"{kc}.friction_force", minimum=0.0),
            breakaway=reader.number(c.get("breakaway", 1.0), f"{kc}.breakaway", minimum=1.0), origin="file")
    implement = reader.mapping(block.get("implement") or {}, f"{k}.implement", {"mass"})
    mass = reader.number(implement.get("mass", 0.0), f"{k}.implement.mass", minimum=0.0)
    tolerances = {str(name): _point(reader, spec, f"{k}.points.{name}")
                  for name, spec in reader.mapping(block.get("points") or {}, f"{k}.points", points).items()}
    default_point = reader.number(block.get("point_tolerance", 0.0), f"{k}.point_tolerance", minimum=0.0)
    return ErrorSources(sensors=sensors, friction=friction, implement_mass=mass, declared=True, defaults=defaults,
                        points=tolerances, point_tolerance=default_point)


def _point(reader: _Validator, spec: Any, key: str) -> PointTolerance:
    """One point's entry: a number (m, 1 sigma, each coordinate) or ``{x: .., z: ..}`` (m, 1 sigma each)."""
    if not isinstance(spec, dict):
        u = reader.number(spec, key, minimum=0.0)
        return PointTolerance(u, u, "file")
    c = reader.mapping(spec, key, {"x", "z"})
    return PointTolerance(reader.number(c.get("x", 0.0), f"{key}.x", minimum=0.0),
                          reader.number(c.get("z", 0.0), f"{key}.z", minimum=0.0), "file")


def _sensor(reader: _Validator, spec: Any, key: str) -> SensorError:
    """One sensor's entry: ``bias`` (1 sigma) or a datasheet bound (``accuracy`` in the sensor's unit, or
    ``class`` in % of ``full_scale``), ``noise`` (1 sigma), ``resolution`` (step)."""
    s = reader.mapping(spec, key, _SENSOR_KEYS)
    given = [name for name in ("bias", "accuracy", "class") if name in s]
    if len(given) > 1:
        raise reader.fail(f"{key}.{given[1]}", f"give the bias one way: {' or '.join(given)}, not both")
    if ("class" in s) != ("full_scale" in s):
        raise reader.fail(f"{key}.{'full_scale' if 'class' in s else 'class'}",
                          "an accuracy class (% of full scale) needs both 'class' and 'full_scale'")
    bias = reader.number(s.get("bias", 0.0), f"{key}.bias", minimum=0.0)
    if "accuracy" in s:
        bias = reader.number(s["accuracy"], f"{key}.accuracy", minimum=0.0) / SQRT3
    if "class" in s:
        bias = (reader.number(s["class"], f"{key}.class", minimum=0.0, maximum=100.0) / 100.0
                * reader.number(s["full_scale"], f"{key}.full_scale", positive=True) / SQRT3)
    return SensorError(bias=bias, noise=reader.number(s.get("noise", 0.0), f"{key}.noise", minimum=0.0),
                       resolution=reader.number(s.get("resolution", 0.0), f"{key}.resolution", minimum=0.0),
                       origin="file")
