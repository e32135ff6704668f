"""YAML mechanism description -> validated :class:`Mechanism` (docs/mechanism-schema.md).

Every problem raises :class:`MechanismFileError` naming the file, the key path
(``hinges[3].bodies``) and what is wrong.
"""

from __future__ import annotations

import copy
import math
import re
import stat
from pathlib import Path
from typing import Any, Mapping

import numpy as np
import yaml

from .error_sources import read_error_sources
from .errors import MechanismFileError
from .model import (AngleSensor, Body, Contact, Cylinder, FrontBallast, Hinge, Implement, Load,
                    Measurements, Mechanism, Mount, PressureSensor, Spring, Tractor)

_TOP_KEYS = {"name", "description", "source", "gravity", "points", "bodies", "hinges", "cylinders",
             "springs", "contacts", "loads", "implement", "measurements", "reference_inputs",
             "tractor", "error_sources"}
_NAME = re.compile(r"^[a-z0-9_]+$")
MAX_FILE_BYTES = 1 << 20     # a mechanism description is a few kB; more is not a mechanism
MAX_DEPTH = 32               # nesting of mappings/lists (the schema needs 5)
MAX_POINTS = 10_000
MAX_MAGNITUDE = 1e9          # no number of the schema (m, kg, N, Pa, N/m) is larger
MAX_COORDINATE = 1e3         # m: a linkage point farther than 1 km from the wheels is a typo
MAX_GRAVITY = 100.0          # m/s²
_FLOAT = re.compile(r"^[-+]?(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?$")


def load_mechanism(path: str | Path) -> Mechanism:
    """Read and validate a mechanism YAML file (SI units, frame x forward / z up, origin B).

    Only a regular file of at most MAX_FILE_BYTES is read (a FIFO or a device would block).
    """
    path = Path(path)
    try:
        info = path.stat()
    except OSError as exc:
        raise MechanismFileError(str(path), "", f"cannot read the file ({exc.strerror})") from exc
    if not stat.S_ISREG(info.st_mode):
        raise MechanismFileError(str(path), "", "not a regular file (a directory, FIFO or device): give a YAML file")
    if info.st_size > MAX_FILE_BYTES:
        raise MechanismFileError(str(path), "", f"{info.st_size} bytes: larger than the {MAX_FILE_BYTES} bytes a "
                                 "mechanism description may have")
    try:
        with open(path, "rb") as stream:
            data = stream.read(MAX_FILE_BYTES + 1)
    except OSError as exc:
        raise MechanismFileError(str(path), "", f"cannot read the file ({exc.strerror})") from exc
    return mechanism_from_text(data, file=str(path))


_LIBYAML_LOADER = getattr(yaml, "CSafeLoader", yaml.SafeLoader)   # libyaml: ~9x faster than PyYAML's own parser
_OPENS, _CLOSES = (yaml.MappingStartEvent, yaml.SequenceStartEvent), (yaml.MappingEndEvent, yaml.SequenceEndEvent)


def _refuse_aliases_and_depth(text: str) -> None:
    """Raise a YAML error at the first alias (``*name``: no expansion bombs) or at nesting deeper than
    MAX_DEPTH, from the parser's events, before anything is composed."""
    depth = 0
    try:
        for event in yaml.parse(text, Loader=_LIBYAML_LOADER):
            if isinstance(event, yaml.AliasEvent):
                raise yaml.constructor.ConstructorError(None, None, "aliases (*name) are not allowed in a mechanism "
                                                        "description: write the value out", event.start_mark)
            depth += isinstance(event, _OPENS) - isinstance(event, _CLOSES)
            if depth > MAX_DEPTH:
                raise yaml.constructor.ConstructorError(None, None, f"nesting deeper than {MAX_DEPTH} levels",
                                                        event.start_mark)
    except yaml.scanner.ScannerError as exc:   # libyaml stops at 1000 open brackets itself, scanning ahead
        if "maximum nesting depth" not in str(exc.problem):
            raise
        raise yaml.constructor.ConstructorError(None, None, f"nesting deeper than {MAX_DEPTH} levels",
                                                exc.problem_mark) from None


class _StrictLoader(_LIBYAML_LOADER):   # type: ignore[misc,valid-type]  # CSafeLoader or SafeLoader
    """Safe loader that refuses duplicate keys and absurdly long integers (aliases and deep nesting:
    ``_refuse_aliases_and_depth``, first)."""

    def construct_mapping(self, node, deep=False):
        seen = set()
        for key_node, _ in node.value:
            key = self.construct_object(key_node, deep=deep)
            if key in seen:
                raise yaml.constructor.ConstructorError(None, None, f"duplicate key {key!r}", key_node.start_mark)
            seen.add(key)
        return super().construct_mapping(node, deep=deep)

    def construct_yaml_int(self, node):
        if len(str(node.value)) > 30:
            raise yaml.constructor.ConstructorError(None, None, f"integer of {len(str(node.value))} digits: "
                                                    "not a quantity of a linkage", node.start_mark)
        return super().construct_yaml_int(node)


_StrictLoader.add_constructor("tag:yaml.org,2002:int", _StrictLoader.construct_yaml_int)
_StrictLoader.add_constructor("tag:yaml.org,2002:map", _StrictLoader.construct_yaml_map)


def mechanism_from_text(text: bytes | str, file: str = "<text>") -> Mechanism:
    """Parse and validate a mechanism description given as YAML text; ``file`` names it in errors."""
    if isinstance(text, bytes):
        if len(text) > MAX_FILE_BYTES:
            raise MechanismFileError(file, "", f"larger than the {MAX_FILE_BYTES} bytes a mechanism description "
                                     "may have")
        try:
            text = text.decode("utf-8")
        except UnicodeDecodeError as exc:
            raise MechanismFileError(file, "", f"not UTF-8 text (byte {exc.start}: {exc.reason}); save the file "
                                     "as UTF-8") from exc
    try:
        _refuse_aliases_and_depth(text)
        data = yaml.load(text, Loader=_StrictLoader)  # noqa: S506 - a safe loader's subclass
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        where = f"line {mark.line + 1}, column {mark.column + 1}" if mark is not None else "YAML"
        problem = getattr(exc, "problem", None) or str(exc).splitlines()[0]
        raise MechanismFileError(file, where, f"malformed YAML: {problem}") from exc
    except RecursionError as exc:
        raise MechanismFileError(file, "YAML", f"nesting deeper than {MAX_DEPTH} levels") from exc
    return mechanism_from_dict(data, file=file)


def mechanism_from_dict(data: Any, file: str = "<dict>") -> Mechanism:
    """Validate a parsed description (the YAML's top-level mapping) and build the :class:`Mechanism`."""
    return _Reader(file).mechanism(data)


def apply_overrides(mech: Mechanism, overrides: Mapping[str, Any]) -> Mechanism:
    """Copy of ``mech`` with scalars set by dotted key (list items by name), re-validated."""
    raw = copy.deepcopy(dict(mech.raw))
    for key, value in overrides.items():
        _set_dotted(raw, key, value, mech.file)
    return mechanism_from_dict(raw, file=mech.file)


def _set_dotted(raw: dict, key: str, value: Any, file: str) -> None:
    parts = key.split(".")
    node: Any = raw
    path = ""
    for i, part in enumerate(parts):
        last = i == len(parts) - 1
        if isinstance(node, list):
            matches = [item for item in node if isinstance(item, dict) and item.get("name") == part]
            if not matches:
                names = ", ".join(str(it.get("name")) for it in node if isinstance(it, dict))
                raise MechanismFileError(file, key, f"no item named '{part}' in {path} ({names})")
            if last:
                raise MechanismFileError(file, key, "only scalars can be overridden, not a whole item")
            node = matches[0]
        elif isinstance(node, dict):
            if last:
                if isinstance(node.get(part), (dict, list)):
                    raise MechanismFileError(file, key, "only scalars can be overridden, not a mapping/list")
                if isinstance(value, (dict, list)) or value is None:
                    raise MechanismFileError(file, key, f"override value {value!r} is not a scalar")
                node[part] = value
                return
            if part not in node:
                raise MechanismFileError(file, key, f"'{part}' is not set in {path or 'the file'}")
            node = node[part]
        else:
            raise MechanismFileError(file, key, f"{path} is a scalar, it has no '{part}'")
        path = f"{path}.{part}" if path else part


class _Reader:
    """Validating reader; ``self.file`` prefixes every error."""

    def __init__(self, file: str) -> None:
        self.file = file
        self.points: dict[str, np.ndarray] = {}
        self.bodies: dict[str, Body] = {}

    def fail(self, key: str, reason: str) -> MechanismFileError:
        return MechanismFileError(self.file, key, reason)

    # ---- primitive readers -------------------------------------------------------------
    def mapping(self, value: Any, key: str, allowed: set[str], required: frozenset[str] | set[str] = frozenset()) -> dict:
        if not isinstance(value, dict):
            raise self.fail(key, f"expected a mapping, got {type(value).__name__}")
        unknown = sorted(set(map(str, value)) - allowed)
        if unknown:
            raise self.fail(f"{key}.{unknown[0]}" if key else unknown[0],
                            f"unknown key (allowed: {', '.join(sorted(allowed))})")
        missing = sorted(required - set(value))
        if missing:
            raise self.fail(key or missing[0], f"missing required key '{missing[0]}'")
        return value

    def seq(self, value: Any, key: str) -> list:
        if value is None:
            return []
        if not isinstance(value, list):
            raise self.fail(key, f"expected a list, got {type(value).__name__}")
        return value

    def number(self, value: Any, key: str, minimum: float | None = None, positive: bool = False,
               maximum: float | None = None) -> float:
        if isinstance(value, str) and _FLOAT.match(value.strip()):
            value = float(value)  # YAML 1.1 reads 20e6 / 1.5e-3 (no sign in the exponent) as strings
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise self.fail(key, f"expected a number, got {value!r}")
        try:
            x = float(value)
        except OverflowError:
            raise self.fail(key, "a number too large to be a quantity of a linkage") from None
        if not math.isfinite(x):
            raise self.fail(key, f"{x} is not a finite number")
        if abs(x) > MAX_MAGNITUDE:
            raise self.fail(key, f"{x:.6g} is out of range (|value| <= {MAX_MAGNITUDE:.0e} in SI units)")
        if positive and x <= 0.0:
            raise self.fail(key, f"must be > 0, got {x}")
        if minimum is not None and x < minimum:
            raise self.fail(key, f"must be >= {minimum}, got {x}")
        if maximum is not None and x > maximum:
            raise self.fail(key, f"must be <= {maximum}, got {x}")
        return x

    def text(self, value: Any, key: str) -> str:
        if not isinstance(value, str) or not value:
            raise self.fail(key, f"expected a non-empty string, got {value!r}")
        return value

    def vector(self, value: Any, key: str, nonzero: bool = False) -> np.ndarray:
        if not isinstance(value, list) or len(value) != 2:
            raise self.fail(key, f"expected [x, z] (two numbers), got {value!r}")
        v = np.array([self.number(value[0], f"{key}[0]"), self.number(value[1], f"{key}[1]")])
        if nonzero and not np.any(v):
            raise self.fail(key, "must not be the zero vector")
        return v

    def point_name(self, value: Any, key: str) -> str:
        name = self.text(value, key)
        if name not in self.points:
            raise self.fail(key, f"point '{name}' is not defined in points")
        return name

    def position(self, value: Any, key: str) -> np.ndarray:
        """A point name or literal [x, z] -> coordinates (m)."""
        if isinstance(value, str):
            return self.points[self.point_name(value, key)].copy()
        return self.vector(value, key)

    def body_name(self, value: Any, key: str, moving: bool = False) -> str:
        name = self.text(value, key)
        if name not in self.bodies:
            raise self.fail(key, f"body '{name}' is not defined (bodies: {', '.join(self.bodies)})")
        if moving and self.bodies[name].ground:
            raise self.fail(key, f"body '{name}' is the ground; a moving body is needed here")
        return name

    def on_body(self, point: str, body: str, key: str) -> None:
        if point not in self.bodies[body].points:
            raise self.fail(key, f"point '{point}' is not on body '{body}' (its points: "
                                 f"{', '.join(self.bodies[body].points)})")

    def mount(self, value: Any, key: str) -> Mount:
        m = self.mapping(value, key, {"point", "body"}, {"point", "body"})
        body = self.body_name(m["body"], f"{key}.body")
        point = self.point_name(m["point"], f"{key}.point")
        self.on_body(point, body, f"{key}.point")
        return Mount(point=point, body=body)

    def unique(self, names: list[str], key: str) -> None:
        seen: set[str] = set()
        for i, n in enumerate(names):
            if n in seen:
                raise self.fail(f"{key}[{i}].name", f"duplicate name '{n}'")
            seen.add(n)

    # ---- sections ------------------------------------------------------------------------
    def mechanism(self, data: Any) -> Mechanism:
        top = self.mapping(data, "", _TOP_KEYS, {"name", "points", "bodies", "hinges", "measurements"})
        name = self.text(top["name"], "name")
        if not _NAME.match(name):
            raise self.fail("name", f"'{name}' must match [a-z0-9_]+")
        pts = top["points"]
        if not isinstance(pts, dict) or not pts:
            raise self.fail("points", f"expected a mapping name -> [x, z], got {pts!r}")
        if len(pts) > MAX_POINTS:
            raise self.fail("points", f"{len(pts)} points: more than the {MAX_POINTS} a linkage description may have")
        self.points = {str(k): self.vector(v, f"points.{k}") for k, v in pts.items()}
        for k, v in self.points.items():
            if np.abs(v).max() > MAX_COORDINATE:
                raise self.fail(f"points.{k}", f"{v.tolist()} m is farther than {MAX_COORDINATE:.0f} m from the "
                                "origin (the rear wheels' ground contact): units are metres")
        bodies = self.read_bodies(top["bodies"])
        hinges = self.read_hinges(top["hinges"])
        cylinders = self.read_cylinders(top.get("cylinders"))
        implement = self.read_implement(top.get("implement"))
        measurements = self.read_measurements(top["measurements"], hinges, cylinders)
        mech = Mechanism(
            name=name, file=self.file, points=self.points, bodies=bodies, hinges=hinges,
            measurements=measurements,
            description=str(top.get("description", "") or ""), source=str(top.get("source", "") or ""),
            gravity=self.number(top.get("gravity", 9.80665), "gravity", minimum=0.0, maximum=MAX_GRAVITY),
            cylinders=cylinders, springs=self.read_springs(top.get("springs")),
            contacts=self.read_contacts(top.get("contacts")), loads=self.read_loads(top.get("loads")),
            implement=implement, reference_inputs=self.read_reference_inputs(top.get("reference_inputs"), measurements),
            tractor=self.read_tractor(top.get("tractor")),
            error_sources=read_error_sources(self, top.get("error_sources"), {c.name for c in cylinders}),
            raw=copy.deepcopy(top))
        self.check_geometry(mech)
        return mech

    def check_geometry(self, mech: Mechanism) -> None:
        """Degenerate geometry, named: a moving body whose points coincide (no direction to rotate
        about), a cylinder or spring of zero length."""
        for i, body in enumerate(mech.bodies):
            pts = np.array([mech.points[p] for p in body.points])
            if not body.ground and len(pts) >= 2 and np.ptp(pts, axis=0).max() < 1e-6:
                raise self.fail(f"bodies[{i}].points", f"all points of body '{body.name}' coincide: a rigid body needs "
                                "two distinct points")
        members = [("cylinders", c.name, c.base.point, c.rod_end.point) for c in mech.cylinders]
        members += [("springs", s.name, s.a.point, s.b.point) for s in mech.springs]
        for section, name, a, b in members:
            if np.hypot(*(mech.points[a] - mech.points[b])) < 1e-6:
                raise self.fail(f"{section}.{name}", f"its ends {a} and {b} coincide: zero length in the reference pose")

    def read_bodies(self, value: Any) -> tuple[Body, ...]:
        items = self.seq(value, "bodies")
        out = []
        for i, item in enumerate(items):
            k = f"bodies[{i}]"
            b = self.mapping(item, k, {"name", "ground", "points", "mass", "cg", "inertia"}, {"name", "points"})
            name = self.text(b["name"], f"{k}.name")
            ground = b.get("ground", False)
            if not isinstance(ground, bool):
                raise self.fail(f"{k}.ground", f"expected true/false, got {ground!r}")
            pts = tuple(self.point_name(p, f"{k}.points[{j}]") for j, p in enumerate(self.seq(b["points"], f"{k}.points")))
            if not pts:
                raise self.fail(f"{k}.points", "a body needs at least one point")
            mass = self.number(b.get("mass", 0.0), f"{k}.mass", minimum=0.0)
            if mass > 0.0 and "cg" not in b:
                raise self.fail(f"{k}.cg", f"required because mass is {mass} kg")
            cg = self.position(b["cg"], f"{k}.cg") if "cg" in b else None
            out.append(Body(name=name, ground=ground, points=pts, mass=mass, cg=cg,
                            inertia=self.number(b.get("inertia", 0.0), f"{k}.inertia", minimum=0.0)))
        self.unique([b.name for b in out], "bodies")
        grounds = [b.name for b in out if b.ground]
        if len(grounds) != 1:
            raise self.fail("bodies", f"exactly one body must have ground: true, found {len(grounds)} ({', '.join(grounds)})")
        if len(out) < 2:
            raise self.fail("bodies", "at least one moving body is needed")
        self.bodies = {b.name: b for b in out}
        return tuple(out)

    def read_hinges(self, value: Any) -> tuple[Hinge, ...]:
        out = []
        for i, item in enumerate(self.seq(value, "hinges")):
            k = f"hinges[{i}]"
            h = self.mapping(item, k, {"name", "point", "bodies"}, {"name", "bodies"})
            name = self.text(h["name"], f"{k}.name")
            point = self.point_name(h.get("point", name), f"{k}.point")
            pair = h["bodies"]
            if not isinstance(pair, list) or len(pair) != 2:
                raise self.fail(f"{k}.bodies", f"expected [body_a, body_b], got {pair!r}")
            a = self.body_name(pair[0], f"{k}.bodies")
            b = self.body_name(pair[1], f"{k}.bodies")
            if a == b:
                raise self.fail(f"{k}.bodies", f"a hinge joins two different bodies, got '{a}' twice")
            self.on_body(point, a, f"{k}.bodies")
            self.on_body(point, b, f"{k}.bodies")
            out.append(Hinge(name=name, point=point, bodies=(a, b)))
        self.unique([h.name for h in out], "hinges")
        return tuple(out)

    def read_cylinders(self, value: Any) -> tuple[Cylinder, ...]:
        out = []
        for i, item in enumerate(self.seq(value, "cylinders")):
            k = f"cylinders[{i}]"
            c = self.mapping(item, k, {"name", "base", "rod_end", "bore", "rod", "count", "relief_pressure",
                                        "efficiency"}, {"name", "base", "rod_end", "bore", "rod"})
            base, rod_end = self.mount(c["base"], f"{k}.base"), self.mount(c["rod_end"], f"{k}.rod_end")
            if base.body == rod_end.body:
                raise self.fail(f"{k}.rod_end.body", f"base and rod end are both on '{base.body}'")
            bore = self.number(c["bore"], f"{k}.bore", positive=True)
            rod = self.number(c["rod"], f"{k}.rod", minimum=0.0)
            if rod >= bore:
                raise self.fail(f"{k}.rod", f"rod diameter {rod} m must be smaller than the bore {bore} m")
            count = c.get("count", 1)
            if isinstance(count, bool) or not isinstance(count, int) or count < 1:
                raise self.fail(f"{k}.count", f"expected an integer >= 1, got {count!r}")
            relief = c.get("relief_pressure")
            out.append(Cylinder(
                name=self.text(c["name"], f"{k}.name"), base=base, rod_end=rod_end, bore=bore, rod=rod,
                count=count,
                relief_pressure=None if relief is None else self.number(relief, f"{k}.relief_pressure", positive=True),
                efficiency=self.number(c.get("efficiency", 1.0), f"{k}.efficiency", positive=True, maximum=1.0)))
        self.unique([c.name for c in out], "cylinders")
        return tuple(out)

    def read_springs(self, value: Any) -> tuple[Spring, ...]:
        out = []
        for i, item in enumerate(self.seq(value, "springs")):
            k = f"springs[{i}]"
            s = self.mapping(item, k, {"name", "a", "b", "stiffness", "free_length", "preload"},
                             {"name", "a", "b", "stiffness", "free_length"})
            a, b = self.mount(s["a"], f"{k}.a"), self.mount(s["b"], f"{k}.b")
            if a.body == b.body:
                raise self.fail(f"{k}.b.body", f"both ends are on '{a.body}'")
            out.append(Spring(name=self.text(s["name"], f"{k}.name"), a=a, b=b,
                              stiffness=self.number(s["stiffness"], f"{k}.stiffness", minimum=0.0),
                              free_length=self.number(s["free_length"], f"{k}.free_length", positive=True),
                              preload=self.number(s.get("preload", 0.0), f"{k}.preload")))
        self.unique([s.name for s in out], "springs")
        return tuple(out)

    def read_contacts(self, value: Any) -> tuple[Contact, ...]:
        out = []
        for i, item in enumerate(self.seq(value, "contacts")):
            k = f"contacts[{i}]"
            c = self.mapping(item, k, {"name", "point", "body", "normal", "friction", "travel"},
                             {"name", "point", "body", "normal"})
            body = self.body_name(c["body"], f"{k}.body", moving=True)
            point = self.point_name(c["point"], f"{k}.point")
            self.on_body(point, body, f"{k}.point")
            normal = self.vector(c["normal"], f"{k}.normal", nonzero=True)
            travel = self.vector(c.get("travel", [1.0, 0.0]), f"{k}.travel", nonzero=True)
            out.append(Contact(name=self.text(c["name"], f"{k}.name"), point=point, body=body,
                               normal=normal / np.hypot(*normal),
                               friction=self.number(c.get("friction", 0.0), f"{k}.friction", minimum=0.0),
                               travel=travel / np.hypot(*travel)))
        self.unique([c.name for c in out], "contacts")
        return tuple(out)

    def read_loads(self, value: Any) -> tuple[Load, ...]:
        out = []
        for i, item in enumerate(self.seq(value, "loads")):
            k = f"loads[{i}]"
            ld = self.mapping(item, k, {"name", "body", "point", "force"}, {"name", "body", "point", "force"})
            out.append(Load(name=self.text(ld["name"], f"{k}.name"),
                            body=self.body_name(ld["body"], f"{k}.body", moving=True),
                            position=self.position(ld["point"], f"{k}.point"),
                            force=self.vector(ld["force"], f"{k}.force")))
        self.unique([ld.name for ld in out], "loads")
        return tuple(out)

    def read_implement(self, value: Any) -> Implement | None:
        if value is None:
            return None
        k = "implement"
        m = self.mapping(value, k, {"body", "mass", "cg", "hitch_point", "mast_point"}, {"body"})
        body = self.bodies[self.body_name(m["body"], f"{k}.body", moving=True)]
        mass = self.number(m.get("mass", body.mass), f"{k}.mass", minimum=0.0)
        if "cg" in m:
            cg = self.position(m["cg"], f"{k}.cg")
        elif body.cg is not None:
            cg = body.cg
        else:
            raise self.fail(f"{k}.cg", f"required: body '{body.name}' has no cg")
        pts = {}
        for key in ("hitch_point", "mast_point"):
            if key in m:
                pts[key] = self.point_name(m[key], f"{k}.{key}")
                self.on_body(pts[key], body.name, f"{k}.{key}")
        return Implement(body=body.name, mass=mass, cg=cg, **pts)

    def read_measurements(self, value: Any, hinges: tuple[Hinge, ...], cylinders: tuple[Cylinder, ...]) -> Measurements:
        k = "measurements"
        m = self.mapping(value if value is not None else {}, k, {"cylinders", "angles", "pressures", "limits"})
        cyl_names = [c.name for c in cylinders]
        hinge_names = [h.name for h in hinges]
        cyls = []
        for i, c in enumerate(self.seq(m.get("cylinders"), f"{k}.cylinders")):
            if c not in cyl_names:
                raise self.fail(f"{k}.cylinders[{i}]", f"cylinder '{c}' is not defined (cylinders: {', '.join(cyl_names)})")
            if c in cyls:
                raise self.fail(f"{k}.cylinders[{i}]", f"cylinder '{c}' is listed twice")
            cyls.append(c)
        angles = []
        for i, a in enumerate(self.seq(m.get("angles"), f"{k}.angles")):
            ka = f"{k}.angles[{i}]"
            am = self.mapping(a, ka, {"name", "hinge", "reference"}, {"name", "hinge"})
            if am["hinge"] not in hinge_names:
                raise self.fail(f"{ka}.hinge", f"hinge '{am['hinge']}' is not defined (hinges: {', '.join(hinge_names)})")
            angles.append(AngleSensor(name=self.text(am["name"], f"{ka}.name"), hinge=am["hinge"],
                                      reference=self.number(am.get("reference", 0.0), f"{ka}.reference")))
        self.unique([a.name for a in angles], f"{k}.angles")
        pressures = []
        for i, p in enumerate(self.seq(m.get("pressures"), f"{k}.pressures")):
            kp = f"{k}.pressures[{i}]"
            pm = self.mapping(p, kp, {"name", "cylinder", "chamber"}, {"name", "cylinder", "chamber"})
            if pm["cylinder"] not in cyl_names:
                raise self.fail(f"{kp}.cylinder", f"cylinder '{pm['cylinder']}' is not defined (cylinders: {', '.join(cyl_names)})")
            if pm["chamber"] not in ("cap", "rod"):
                raise self.fail(f"{kp}.chamber", f"expected 'cap' or 'rod', got {pm['chamber']!r}")
            pressures.append(PressureSensor(name=self.text(pm["name"], f"{kp}.name"), cylinder=pm["cylinder"],
                                            chamber=pm["chamber"]))
        self.unique([p.name for p in pressures], f"{k}.pressures")
        measured = set(cyls) | {a.name for a in angles} | {p.name for p in pressures}
        limits = {}
        lm = m.get("limits") or {}
        if not isinstance(lm, dict):
            raise self.fail(f"{k}.limits", f"expected a mapping measurement name -> [min, max], got {type(lm).__name__}")
        for name, pair in lm.items():
            kl = f"{k}.limits.{name}"
            if name not in measured:
                raise self.fail(kl, f"'{name}' is not a measurement (measured: {', '.join(sorted(measured))})")
            if not isinstance(pair, list) or len(pair) != 2:
                raise self.fail(kl, f"expected [min, max], got {pair!r}")
            lo, hi = self.number(pair[0], f"{kl}[0]"), self.number(pair[1], f"{kl}[1]")
            if not lo < hi:
                raise self.fail(kl, f"min {lo} must be below max {hi}")
            limits[str(name)] = (lo, hi)
        return Measurements(cylinders=tuple(cyls), angles=tuple(angles), pressures=tuple(pressures), limits=limits)

    def read_reference_inputs(self, value: Any, meas: Measurements) -> dict[str, dict[str, float]]:
        k = "reference_inputs"
        m = self.mapping(value if value is not None else {}, k, {"cylinders", "angles", "pressures"})
        valid = {"cylinders": list(meas.cylinders), "angles": [a.name for a in meas.angles],
                 "pressures": [p.name for p in meas.pressures]}
        out: dict[str, dict[str, float]] = {}
        for kind, names in valid.items():
            sub = m.get(kind) or {}
            if not isinstance(sub, dict):
                raise self.fail(f"{k}.{kind}", f"expected a mapping name -> value, got {type(sub).__name__}")
            for name, v in sub.items():
                if name not in names:
                    raise self.fail(f"{k}.{kind}.{name}", f"not a measured {kind[:-1]} (measured: {', '.join(names)})")
            out[kind] = {str(n): self.number(v, f"{k}.{kind}.{n}") for n, v in sub.items()}
        return out

    def read_tractor(self, value: Any) -> Tractor | None:
        if value is None:
            return None
        k = "tractor"
        t = self.mapping(value, k, {"mass", "cg", "wheelbase", "front_ballast", "ratio_min",
                                    "steerability_reference"}, {"mass", "cg", "wheelbase"})
        ballast = None
        if t.get("front_ballast") is not None:
            fb = self.mapping(t["front_ballast"], f"{k}.front_ballast", {"mass", "x"}, {"mass", "x"})
            ballast = FrontBallast(mass=self.number(fb["mass"], f"{k}.front_ballast.mass", minimum=0.0),
                                   x=self.number(fb["x"], f"{k}.front_ballast.x"))
        ref = t.get("steerability_reference", "unit")
        if ref not in ("unit", "tractor"):
            raise self.fail(f"{k}.steerability_reference", f"expected 'unit' or 'tractor', got {ref!r}")
        return Tractor(mass=self.number(t["mass"], f"{k}.mass", positive=True), cg=self.vector(t["cg"], f"{k}.cg"),
                       wheelbase=self.number(t["wheelbase"], f"{k}.wheelbase", positive=True), front_ballast=ballast,
                       ratio_min=self.number(t.get("ratio_min", 0.2), f"{k}.ratio_min", minimum=0.0, maximum=1.0),
                       steerability_reference=ref)
