"""The mechanism as typed data (built and validated by :mod:`.schema`).

Units SI (m, rad, N, Pa, kg); frame: x forward, z up, origin at the rear wheels' ground
contact. All coordinates are those of the mechanism's reference pose.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from functools import cached_property
from typing import Any, Mapping

import numpy as np

from .error_sources import ErrorSources


@dataclass(frozen=True)
class Body:
    """A rigid body: its points, mass (kg), cg (m, reference pose) and inertia about the cg (kg·m²)."""

    name: str
    ground: bool
    points: tuple[str, ...]
    mass: float = 0.0
    cg: np.ndarray | None = None
    inertia: float = 0.0


# Hinge and Mount: alike in form only to sim.work_cycle's and monitoring.weighing_fit's records (fields of other data).
@dataclass(frozen=True)
class Hinge:
    """Revolute joint at ``point`` joining ``bodies = (a, b)``; its reaction is the force on b from a."""

    name: str
    point: str
    bodies: tuple[str, str]


@dataclass(frozen=True)
class Mount:
    """Where a two-force member attaches: a named point of a body."""

    point: str
    body: str


@dataclass(frozen=True)
class Cylinder:
    """Hydraulic cylinder (two-force member); force + = pushing, total of ``count`` cylinders."""

    name: str
    base: Mount
    rod_end: Mount
    bore: float
    rod: float
    count: int = 1
    relief_pressure: float | None = None
    efficiency: float = 1.0

    @property
    def cap_area(self) -> float:
        """Piston area of one cylinder, m²: π·bore²/4."""
        return math.pi * self.bore**2 / 4.0

    @property
    def rod_area(self) -> float:
        """Annulus area on the rod side of one cylinder, m²: A_cap − π·rod²/4."""
        return self.cap_area - math.pi * self.rod**2 / 4.0


@dataclass(frozen=True)
class Spring:
    """Spring between mounts a and b: force = stiffness·(free_length − length) + preload, + = pushing (N)."""

    name: str
    a: Mount
    b: Mount
    stiffness: float
    free_length: float
    preload: float = 0.0


# Spring and Contact, AngleSensor and PressureSensor: frozen records alike in form only (their own fields).
@dataclass(frozen=True)
class Contact:
    """Unilateral ground contact on ``body`` at ``point``: normal N along ``normal``, friction f·N against ``travel``."""

    name: str
    point: str
    body: str
    normal: np.ndarray
    friction: float
    travel: np.ndarray

    @property
    def force_direction(self) -> np.ndarray:
        """Force on the body per newton of normal force: n − f·t, t = travel projected ⟂ n (Kotov & Krol, T70 = f·N70)."""
        t = self.travel - np.dot(self.travel, self.normal) * self.normal
        norm = float(np.hypot(*t))
        t = t / norm if norm > 0.0 else t
        return self.normal - self.friction * t


@dataclass(frozen=True)
class Load:
    """Constant external force (N, global frame) acting at ``position`` (reference pose) of ``body``."""

    name: str
    body: str
    position: np.ndarray
    force: np.ndarray


@dataclass(frozen=True)
class Implement:
    """The hung implement: its body, mass (kg), cg (m, reference pose), hitch and mast point names."""

    body: str
    mass: float
    cg: np.ndarray
    hitch_point: str | None = None
    mast_point: str | None = None


@dataclass(frozen=True)
class AngleSensor:
    """Angle of ``hinge.bodies[1]`` relative to ``hinge.bodies[0]``, rad; reads ``reference`` in the reference pose."""

    name: str
    hinge: str
    reference: float = 0.0


# Alike in form only to Spring/Contact above and to viz.terminal_view's records: fields of other data.
@dataclass(frozen=True)
class PressureSensor:
    """Gauge pressure (Pa) of the ``cap`` or ``rod`` chamber of a cylinder."""

    name: str
    cylinder: str
    chamber: str


@dataclass(frozen=True)
class Measurements:
    """What is measured: cylinder lengths, joint angles, chamber pressures; ``limits`` = the file's
    plausibility range [min, max] per measurement name (m, rad, Pa absolute), see mechanics.limits."""

    cylinders: tuple[str, ...] = ()
    angles: tuple[AngleSensor, ...] = ()
    pressures: tuple[PressureSensor, ...] = ()
    limits: Mapping[str, tuple[float, float]] = field(default_factory=dict)


@dataclass(frozen=True)
class FrontBallast:
    """Front weights: mass (kg) hanging at x (m)."""

    mass: float
    x: float


@dataclass(frozen=True)
class Tractor:
    """Tractor data for axle loads and steerability (Popov 2009)."""

    mass: float
    cg: np.ndarray
    wheelbase: float
    front_ballast: FrontBallast | None = None
    ratio_min: float = 0.2
    steerability_reference: str = "unit"


@dataclass(frozen=True)
class Mechanism:
    """A validated planar linkage; build it with ``load_mechanism`` / ``load_preset``.

    ``raw`` keeps the description as read (a dict) so that ``overrides.apply_overrides`` can re-validate.
    """

    name: str
    file: str
    points: Mapping[str, np.ndarray]
    bodies: tuple[Body, ...]
    hinges: tuple[Hinge, ...]
    measurements: Measurements
    description: str = ""
    source: str = ""
    gravity: float = 9.80665
    cylinders: tuple[Cylinder, ...] = ()
    springs: tuple[Spring, ...] = ()
    contacts: tuple[Contact, ...] = ()
    loads: tuple[Load, ...] = ()
    implement: Implement | None = None
    reference_inputs: Mapping[str, Mapping[str, float]] = field(default_factory=dict)
    tractor: Tractor | None = None
    error_sources: ErrorSources = field(default_factory=ErrorSources)
    raw: Mapping[str, Any] = field(default_factory=dict, repr=False)

    @cached_property
    def description_key(self) -> str:
        """The description as canonical JSON (keys sorted): the same for every mechanism built from
        the same description, the key of what is kept per mechanism (its input limits' sweeps, its
        markers' layouts)."""
        return json.dumps(self.raw, sort_keys=True, default=repr)

    @property
    def ground(self) -> Body:
        """The fixed body (tractor frame)."""
        return next(b for b in self.bodies if b.ground)

    @property
    def moving_bodies(self) -> tuple[Body, ...]:
        """The bodies that move, in file order (their index is their coordinate block)."""
        return tuple(b for b in self.bodies if not b.ground)

    def body(self, name: str) -> Body:
        """The body called ``name``."""
        return next(b for b in self.bodies if b.name == name)

    def cylinder(self, name: str) -> Cylinder:
        """The cylinder called ``name``."""
        return next(c for c in self.cylinders if c.name == name)

