"""Result objects of the solver: one pose (:class:`Result`) and a stack of poses (:class:`BatchResult`).

SI units, global frame (x forward, z up, origin at the rear wheels' ground contact B).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from enum import IntEnum
from functools import cached_property
from typing import TYPE_CHECKING, NamedTuple

import numpy as np


if TYPE_CHECKING:
    from .model import Mechanism



class Status(IntEnum):
    """Verdict of the solver on one pose (``BatchResult.status`` holds these values as ints).

    OK and LIFT_OFF are solved poses (LIFT_OFF: a ground contact would pull, the forces are
    still published with a warning); the others are failures that produce no forces.
    """

    OK = 0
    LIFT_OFF = 1
    INPUT = 2        # an input is not a finite number / out of its physical range
    ASSEMBLY = 3     # the linkage cannot be assembled for the inputs (or only off its branch)
    DEAD_CENTRE = 4  # near-singular kinematics or statics

    @property
    def solved(self) -> bool:
        """True for a pose with forces (OK or LIFT_OFF)."""
        return self < Status.INPUT

    @property
    def label(self) -> str:
        """Lower-case name for messages and JSON (``ok``, ``lift_off``, ``input``, ...)."""
        return self.name.lower()


# BatchResult's per-cylinder and per-contact fields, in the column order of Result.cylinder_values /
# contact_values (the fields of CylinderResult and ContactResult)
CYLINDER_FIELDS = ("cylinder_length", "cylinder_force", "cap_pressure_predicted", "cap_pressure_measured",
                   "rod_pressure_measured")
CONTACT_FIELDS = ("contact_normal", "contact_tangential")
STATUS_LABELS: tuple[str, ...] = tuple(status.label for status in Status)   # index: the Status value (0, 1, ...)


class HingeResult(NamedTuple):
    """Reaction at a hinge: force (N, global frame) on ``on_body`` from ``from_body``.
    (The small per-pose results are NamedTuples: immutable, and built in a fraction of a frozen
    dataclass's time; a pose has one per hinge.)"""

    fx: float
    fz: float
    magnitude: float
    on_body: str
    from_body: str


class CylinderResult(NamedTuple):
    """Cylinder length (m), axial force (N, + = pushing, all ``count``), pressures (Pa gauge).

    ``cap_pressure_predicted`` = force / (count·A_cap) (rod chamber at 0 gauge); measured
    pressures are NaN when not measured.
    """

    length: float
    force: float
    cap_pressure_predicted: float
    cap_pressure_measured: float
    rod_pressure_measured: float


class ContactResult(NamedTuple):
    """Ground contact: normal force N (N, ≥ 0 unless lifting off) and friction force magnitude f·N (N)."""

    normal: float
    tangential: float


@dataclass(frozen=True)
class ResultNames:
    """The names a :class:`Result`'s rows follow, the same for every pose of one solver:
    ``points`` (mechanism points), ``bodies`` (moving bodies), ``hinges`` (name, on_body,
    from_body), ``cylinders``, ``contacts``."""

    points: tuple[str, ...]
    bodies: tuple[str, ...]
    hinges: tuple[tuple[str, str, str], ...]
    cylinders: tuple[str, ...]
    contacts: tuple[str, ...]


# built per input event: a plain dataclass, not a frozen one (docs/architecture.md, One pipeline)
@dataclass(eq=False)
class Result:
    """Everything solved for one pose, as arrays whose rows follow ``names``; the per-name views
    (``points``, ``body_poses``, ``hinges``, ``cylinders``, ``contacts``) are built when first
    asked for (the live node's outputs are written from the arrays).

    ``point_xz`` (P, 2) m: the mechanism's points. ``body_q`` (B, 3): per moving body [x, z, θ],
    position (m) of the body's origin (centroid of its points in the reference pose) and rotation
    from the reference pose (rad). ``hinge_force`` (H, 2) N: the reaction on ``on_body`` from
    ``from_body``. ``cylinder_values`` (C, 5): the fields of :class:`CylinderResult` (m, N, Pa).
    ``contact_values`` (K, 2): those of :class:`ContactResult` (N). ``frame_load_points`` /
    ``frame_load_forces`` (F, 2): where (m) and what force (N) the linkage puts ON the ground body,
    one row per frame-side hinge and cylinder/spring mount (names in ``Solver.frame_load_names``).
    ``implement_load`` = vertical load (N, + = down) at ``implement_cg``: estimated when a
    cylinder force is measured, else the configured weight. ``residual`` = norm of the
    equilibrium residual (N; moments divided by the length scale), ``condition`` = the
    general path's dead-centre measure: the larger of the kinematic Jacobian's and the
    equilibrium matrix's condition numbers (NaN where the reduced path serves: its measure is
    ``transmission_angle``), ``consistency_residual`` =
    norm of the kinematic constraint residual (m). ``largest_force`` = the largest hinge reaction or
    cylinder force magnitude (N; 0 with neither; ``kernels.largest_force``). ``status`` = "ok" or
    "lift_off" (a contact pulls: N < 0; ``message`` names it). ``load_amplification``: where the
    reduced path infers a free load (the implement's, a contact's) from a measured cylinder force, N
    of that load per N of the force (|∂λ/∂F|; large where the load's line passes near the closing
    step's pivot: docs/dead-centre.md); NaN where no load is so inferred.
    """

    names: ResultNames
    point_xz: np.ndarray
    body_q: np.ndarray
    hinge_force: np.ndarray
    cylinder_values: np.ndarray
    contact_values: np.ndarray
    implement_load: float
    implement_cg: np.ndarray
    frame_load_points: np.ndarray
    frame_load_forces: np.ndarray
    residual: float
    consistency_residual: float
    condition: float
    largest_force: float
    status: str
    message: str = ""
    state: object = field(default=None, repr=False)  # the solver's pose, to warm-start the next solve
    transmission_angle: float = math.nan
    weakest_transmission: str = ""
    load_amplification: float = math.nan

    @cached_property
    def hinge_magnitude(self) -> np.ndarray:
        """|F| (H,) N of each hinge reaction."""
        return np.hypot(self.hinge_force[:, 0], self.hinge_force[:, 1])

    @cached_property
    def points(self) -> dict[str, np.ndarray]:
        """Point name -> [x, z] m."""
        return dict(zip(self.names.points, self.point_xz))

    @cached_property
    def body_poses(self) -> dict[str, np.ndarray]:
        """Moving body name -> [x, z, θ] (m, m, rad)."""
        return dict(zip(self.names.bodies, self.body_q))

    @cached_property
    def hinges(self) -> dict[str, HingeResult]:
        """Hinge name -> its reaction."""
        return {name: HingeResult(fx, fz, magnitude, on, off) for (name, on, off), (fx, fz), magnitude
                in zip(self.names.hinges, self.hinge_force.tolist(), self.hinge_magnitude.tolist())}

    @cached_property
    def cylinders(self) -> dict[str, CylinderResult]:
        """Cylinder name -> length, force and pressures."""
        return {name: CylinderResult(*row) for name, row in zip(self.names.cylinders, self.cylinder_values.tolist())}

    @cached_property
    def contacts(self) -> dict[str, ContactResult]:
        """Ground contact name -> normal and friction force."""
        return {name: ContactResult(*row) for name, row in zip(self.names.contacts, self.contact_values.tolist())}


@dataclass
class BatchResult:
    """The same quantities for N poses as arrays (first axis = pose); failed poses hold NaN.

    ``status`` (N,) int: a :class:`Status` value per pose; ``messages[i]`` says what went wrong with pose i ("" when ok).
    ``hinge_force[name]`` (N, 2) N on bodies[1] from bodies[0]; ``frame_load_points`` and
    ``frame_load_forces`` (N, K, 2) in the order of ``frame_load_names``. ``largest_force`` (N,) N,
    ``transmission_angle`` (N,) rad, ``weakest_transmission`` (N names) and ``load_amplification`` (N,)
    as :class:`Result`'s.
    """

    points: dict[str, np.ndarray]
    body_poses: dict[str, np.ndarray]
    hinge_force: dict[str, np.ndarray]
    hinge_bodies: dict[str, tuple[str, str]]
    cylinder_length: dict[str, np.ndarray]
    cylinder_force: dict[str, np.ndarray]
    cap_pressure_predicted: dict[str, np.ndarray]
    cap_pressure_measured: dict[str, np.ndarray]
    rod_pressure_measured: dict[str, np.ndarray]
    contact_normal: dict[str, np.ndarray]
    contact_tangential: dict[str, np.ndarray]
    implement_load: np.ndarray
    implement_cg: np.ndarray
    frame_load_names: list[str]
    frame_load_points: np.ndarray
    frame_load_forces: np.ndarray
    residual: np.ndarray
    consistency_residual: np.ndarray
    condition: np.ndarray
    largest_force: np.ndarray
    status: np.ndarray
    messages: list[str]
    transmission_angle: np.ndarray
    weakest_transmission: list[str]
    load_amplification: np.ndarray

    def __len__(self) -> int:
        return len(self.status)

    def assign(self, index: np.ndarray, other: "BatchResult") -> None:
        """Poses ``index`` (len(other),) replaced by the poses of ``other`` (the same solver's)."""
        for name, value in vars(self).items():
            theirs = getattr(other, name)
            if isinstance(value, dict):
                for key, column in value.items():
                    if isinstance(column, np.ndarray):
                        column[index] = theirs[key]
            elif isinstance(value, np.ndarray):
                value[index] = theirs
            elif isinstance(value, list) and name != "frame_load_names":   # messages, weakest_transmission
                for i, text in zip(index.tolist(), theirs):
                    value[i] = text

    def result(self, i: int) -> Result:
        """Pose i as a :class:`Result` (its status may be an error: check ``status``/``message``)."""
        i = range(len(self))[i]   # IndexError out of range; a negative i counts from the end
        return self.results(slice(i, i + 1))[0]

    def results(self, rows: slice | np.ndarray = slice(None)) -> list[Result]:
        """The poses ``rows`` (a slice, or an index array) as :class:`Result` objects, in that order: the
        arrays are stacked (copied) once for all of them, each pose's rows are views of the stack."""
        names = self.names
        n = len(self.status[rows])
        picked = (lambda texts: texts[rows]) if isinstance(rows, slice) else (lambda texts: [texts[i] for i in rows.tolist()])

        def stacked(group: dict[str, np.ndarray], keys: tuple[str, ...], width: int) -> np.ndarray:
            return np.stack([group[k][rows] for k in keys], axis=1) if keys else np.zeros((n, 0, width))

        def columns(*groups: dict[str, np.ndarray], keys: tuple[str, ...]) -> np.ndarray:
            return (np.stack([np.stack([g[k][rows] for g in groups], axis=-1) for k in keys], axis=1) if keys
                    else np.zeros((n, 0, len(groups))))

        points, poses = stacked(self.points, names.points, 2), stacked(self.body_poses, names.bodies, 3)
        hinges = stacked(self.hinge_force, tuple(h for h, _, _ in names.hinges), 2)
        cylinders = columns(*(getattr(self, field) for field in CYLINDER_FIELDS), keys=names.cylinders)
        contacts = columns(*(getattr(self, field) for field in CONTACT_FIELDS), keys=names.contacts)
        cgs, load_points, load_forces = (np.array(a[rows]) for a in (self.implement_cg, self.frame_load_points,
                                                                     self.frame_load_forces))
        scalars = zip(*(a[rows].tolist() for a in (self.implement_load, self.residual, self.consistency_residual,
                                                    self.condition, self.largest_force, self.status,
                                                    self.transmission_angle, self.load_amplification)))
        views = zip(points, poses, hinges, cylinders, contacts, cgs, load_points, load_forces)   # views, one per pose
        return [Result(names, point, pose, hinge, cylinder, contact, load, cg, load_point, load_force, residual,
                       consistency, condition, largest_force, STATUS_LABELS[int(status)], message,
                       transmission_angle=angle, weakest_transmission=weakest, load_amplification=amplification)
                for (point, pose, hinge, cylinder, contact, cg, load_point, load_force),
                (load, residual, consistency, condition, largest_force, status, angle, amplification), message, weakest
                in zip(views, scalars, picked(self.messages), picked(self.weakest_transmission))]

    @classmethod
    def from_stacked(cls, names: ResultNames, hinge_bodies: dict[str, tuple[str, str]], point_xz: np.ndarray,
                     body_q: np.ndarray, hinge_force: np.ndarray, cylinder_values: np.ndarray,
                     contact_values: np.ndarray, implement_load: np.ndarray, implement_cg: np.ndarray,
                     frame_load_names: list[str], frame_load_points: np.ndarray, frame_load_forces: np.ndarray,
                     residual: np.ndarray, consistency_residual: np.ndarray, condition: np.ndarray,
                     largest_force: np.ndarray, transmission_angle: np.ndarray, weakest_transmission: list[str],
                     load_amplification: np.ndarray) -> "BatchResult":
        """N solved poses (status OK) from arrays stacked as :class:`Result`'s, with a first axis of
        poses (``results`` the other way round); each column is a view of the stack."""
        n_pose = len(residual)
        return cls(
            points={n: point_xz[:, k] for k, n in enumerate(names.points)},
            body_poses={n: body_q[:, k] for k, n in enumerate(names.bodies)},
            hinge_force={h: hinge_force[:, k] for k, (h, _, _) in enumerate(names.hinges)},
            hinge_bodies=hinge_bodies,
            **{field: {n: cylinder_values[:, k, j] for k, n in enumerate(names.cylinders)}
               for j, field in enumerate(CYLINDER_FIELDS)},
            **{field: {n: contact_values[:, k, j] for k, n in enumerate(names.contacts)}
               for j, field in enumerate(CONTACT_FIELDS)},
            implement_load=implement_load, implement_cg=implement_cg, frame_load_names=frame_load_names,
            frame_load_points=frame_load_points, frame_load_forces=frame_load_forces, residual=residual,
            consistency_residual=consistency_residual, condition=condition, largest_force=largest_force,
            status=np.zeros(n_pose, dtype=int),
            messages=[""] * n_pose, transmission_angle=transmission_angle, weakest_transmission=weakest_transmission,
            load_amplification=load_amplification)

    @property
    def names(self) -> ResultNames:
        """The names the rows of this batch's :class:`Result` objects follow."""
        return ResultNames(tuple(self.points), tuple(self.body_poses),
                           tuple((h, on, off) for h, (off, on) in self.hinge_bodies.items()),
                           tuple(self.cylinder_force), tuple(self.contact_normal))


def angle_readings(mech: "Mechanism", batch: BatchResult) -> dict[str, np.ndarray]:
    """What each angle sensor of ``mech`` reads (rad, (N,)) in the solved poses of ``batch``:
    reference + θ(bodies[1]) − θ(bodies[0]) of its hinge (schema, ``measurements.angles``),
    θ the rotation from the reference pose; the ground body does not rotate."""
    hinges = {h.name: h for h in mech.hinges}

    def theta(body: str) -> np.ndarray:
        pose = batch.body_poses.get(body)
        return pose[:, 2] if pose is not None else np.zeros(len(batch))

    return {a.name: a.reference + theta(hinges[a.hinge].bodies[1]) - theta(hinges[a.hinge].bodies[0])
            for a in mech.measurements.angles}
