"""YAML mechanism description -> validated :class:`Mechanism` (docs/mechanism-schema.md).

Every problem raises :class:`MechanismFileError` naming the file, the key path
(``hinges[3].bodies``) and what is wrong.
"""

from __future__ import annotations

import copy
import re
from pathlib import Path
from typing import Any

import numpy as np

from .error_sources import read_error_sources
from .model import (AngleSensor, Body, Contact, Cylinder, FrontBallast, Hinge, Implement, Load,
                    Measurements, Mechanism, PressureSensor, Spring, Tractor)
from .safe_yaml import parse_yaml, read_file
from .schema_values import ValueReader

_TOP_KEYS = {"name", "description", "source", "gravity", "points", "bodies", "hinges", "cylinders",
             "springs", "contacts", "loads", "implement", "measurements", "reference_inputs",
             "tractor", "error_sources"}
_NAME = re.compile(r"^[a-z0-9_]+$")
MAX_POINTS = 10_000
MAX_COORDINATE = 1e3         # m: a linkage point farther than 1 km from the wheels is a typo
MAX_GRAVITY = 100.0          # m/s²


def load_mechanism(path: str | Path) -> Mechanism:
    """Read and validate a mechanism YAML file (SI units, frame x forward / z up, origin B).

    Only a regular file of at most MAX_FILE_BYTES is read (a FIFO or a device would block).
    """
    path = Path(path)
    return mechanism_from_text(read_file(path), file=str(path))


def mechanism_from_text(text: bytes | str, file: str = "<text>") -> Mechanism:
    """Parse and validate a mechanism description given as YAML text; ``file`` names it in errors."""
    return mechanism_from_dict(parse_yaml(text, file), file=file)


def mechanism_from_dict(data: Any, file: str = "<dict>") -> Mechanism:
    """Validate a parsed description (the YAML's top-level mapping) and build the :class:`Mechanism`."""
    return _Reader(file).mechanism(data)


class _Reader(ValueReader):
    """Validating reader of the description's sections; ``self.file`` prefixes every error."""

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
        hinges = self.named_items(top["hinges"], "hinges", self.read_hinge)
        cylinders = self.named_items(top.get("cylinders"), "cylinders", self.read_cylinder)
        implement = self.read_implement(top.get("implement"))
        measurements = self.read_measurements(top["measurements"], hinges, cylinders)
        mech = Mechanism(
            name=name, file=self.file, points=self.points, bodies=bodies, hinges=hinges,
            measurements=measurements,
            description=str(top.get("description", "") or ""), source=str(top.get("source", "") or ""),
            gravity=self.number(top.get("gravity", 9.80665), "gravity", minimum=0.0, maximum=MAX_GRAVITY),
            cylinders=cylinders, springs=self.named_items(top.get("springs"), "springs", self.read_spring),
            contacts=self.named_items(top.get("contacts"), "contacts", self.read_contact),
            loads=self.named_items(top.get("loads"), "loads", self.read_load),
            implement=implement, reference_inputs=self.read_reference_inputs(top.get("reference_inputs"), measurements),
            tractor=self.read_tractor(top.get("tractor")),
            error_sources=read_error_sources(self, top.get("error_sources"), {c.name for c in cylinders},
                                               set(self.points)),
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
        out = self.named_items(value, "bodies", self.read_body)
        grounds = [b.name for b in out if b.ground]
        if len(grounds) != 1:
            raise self.fail("bodies", f"exactly one body must have ground: true, found {len(grounds)} ({', '.join(grounds)})")
        if len(out) < 2:
            raise self.fail("bodies", "at least one moving body is needed")
        self.bodies = {b.name: b for b in out}
        return out

    def read_body(self, item: Any, k: str) -> Body:
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
        return Body(name=name, ground=ground, points=pts, mass=mass, cg=cg,
                    inertia=self.number(b.get("inertia", 0.0), f"{k}.inertia", minimum=0.0))

    def read_hinge(self, item: Any, k: str) -> Hinge:
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
        return Hinge(name=name, point=point, bodies=(a, b))

    def read_cylinder(self, item: Any, k: str) -> Cylinder:
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
        return Cylinder(
            name=self.text(c["name"], f"{k}.name"), base=base, rod_end=rod_end, bore=bore, rod=rod,
            count=count,
            relief_pressure=None if relief is None else self.number(relief, f"{k}.relief_pressure", positive=True),
            efficiency=self.number(c.get("efficiency", 1.0), f"{k}.efficiency", positive=True, maximum=1.0))

    def read_spring(self, item: Any, k: str) -> Spring:
        s = self.mapping(item, k, {"name", "a", "b", "stiffness", "free_length", "preload"},
                         {"name", "a", "b", "stiffness", "free_length"})
        a, b = self.mount(s["a"], f"{k}.a"), self.mount(s["b"], f"{k}.b")
        if a.body == b.body:
            raise self.fail(f"{k}.b.body", f"both ends are on '{a.body}'")
        return Spring(name=self.text(s["name"], f"{k}.name"), a=a, b=b,
                      stiffness=self.number(s["stiffness"], f"{k}.stiffness", minimum=0.0),
                      free_length=self.number(s["free_length"], f"{k}.free_length", positive=True),
                      preload=self.number(s.get("preload", 0.0), f"{k}.preload"))

    def read_contact(self, item: Any, k: str) -> Contact:
        c = self.mapping(item, k, {"name", "point", "body", "normal", "friction", "travel"},
                         {"name", "point", "body", "normal"})
        body = self.body_name(c["body"], f"{k}.body", moving=True)
        point = self.point_name(c["point"], f"{k}.point")
        self.on_body(point, body, f"{k}.point")
        normal = self.vector(c["normal"], f"{k}.normal", nonzero=True)
        travel = self.vector(c.get("travel", [1.0, 0.0]), f"{k}.travel", nonzero=True)
        return Contact(name=self.text(c["name"], f"{k}.name"), point=point, body=body,
                       normal=normal / np.hypot(*normal),
                       friction=self.number(c.get("friction", 0.0), f"{k}.friction", minimum=0.0),
                       travel=travel / np.hypot(*travel))

    def read_load(self, item: Any, k: str) -> Load:
        ld = self.mapping(item, k, {"name", "body", "point", "force"}, {"name", "body", "point", "force"})
        return Load(name=self.text(ld["name"], f"{k}.name"),
                    body=self.body_name(ld["body"], f"{k}.body", moving=True),
                    position=self.position(ld["point"], f"{k}.point"),
                    force=self.vector(ld["force"], f"{k}.force"))

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
        angles = self.named_items(m.get("angles"), f"{k}.angles", lambda a, ka: self.read_angle(a, ka, hinge_names))
        pressures = self.named_items(m.get("pressures"), f"{k}.pressures",
                                     lambda p, kp: self.read_pressure(p, kp, cyl_names))
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
        return Measurements(cylinders=tuple(cyls), angles=angles, pressures=pressures, limits=limits)

    def read_angle(self, a: Any, ka: str, hinge_names: list[str]) -> AngleSensor:
        am = self.mapping(a, ka, {"name", "hinge", "reference"}, {"name", "hinge"})
        if am["hinge"] not in hinge_names:
            raise self.fail(f"{ka}.hinge", f"hinge '{am['hinge']}' is not defined (hinges: {', '.join(hinge_names)})")
        return AngleSensor(name=self.text(am["name"], f"{ka}.name"), hinge=am["hinge"],
                           reference=self.number(am.get("reference", 0.0), f"{ka}.reference"))

    def read_pressure(self, p: Any, kp: str, cyl_names: list[str]) -> PressureSensor:
        pm = self.mapping(p, kp, {"name", "cylinder", "chamber"}, {"name", "cylinder", "chamber"})
        if pm["cylinder"] not in cyl_names:
            raise self.fail(f"{kp}.cylinder", f"cylinder '{pm['cylinder']}' is not defined (cylinders: {', '.join(cyl_names)})")
        if pm["chamber"] not in ("cap", "rod"):
            raise self.fail(f"{kp}.chamber", f"expected 'cap' or 'rod', got {pm['chamber']!r}")
        return PressureSensor(name=self.text(pm["name"], f"{kp}.name"), cylinder=pm["cylinder"], chamber=pm["chamber"])

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
