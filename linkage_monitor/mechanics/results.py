"""Result objects of the solver: one pose (:class:`Result`) and a stack of poses (:class:`BatchResult`).

SI units, global frame (x forward, z up, origin at the rear wheels' ground contact B).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from enum import IntEnum
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
class Result:
    """Everything solved for one pose.

    ``body_poses[name]`` = [x, z, θ]: position (m) of the body's origin (centroid of its points
    in the reference pose) and rotation from the reference pose (rad). ``frame_load_points`` /
    ``frame_load_forces`` (K, 2): where (m) and what force (N) the linkage puts ON the ground body,
    one row per frame-side hinge and cylinder/spring mount (names in ``Solver.frame_load_names``).
    ``implement_load`` = vertical load (N, + = down) at ``implement_cg``: estimated when a
    cylinder force is measured, else the configured weight. ``residual`` = norm of the
    equilibrium residual (N; moments divided by the length scale), ``consistency_residual`` =
    norm of the kinematic constraint residual (m). ``status`` = "ok" or "lift_off" (a contact
    pulls: N < 0; ``message`` names it).
    """

    points: dict[str, np.ndarray]
    body_poses: dict[str, np.ndarray]
    hinges: dict[str, HingeResult]
    cylinders: dict[str, CylinderResult]
    contacts: dict[str, ContactResult]
    implement_load: float
    implement_cg: np.ndarray
    frame_load_points: np.ndarray
    frame_load_forces: np.ndarray
    residual: float
    consistency_residual: float
    condition: float
    status: str
    message: str = ""
    state: object = field(default=None, repr=False, compare=False)  # the solver's pose, to warm-start the next solve


@dataclass
class BatchResult:
    """The same quantities for N poses as arrays (first axis = pose); failed poses hold NaN.

    ``status`` (N,) int: a :class:`Status` value per pose; ``messages[i]`` says what went wrong with pose i ("" when ok).
    ``hinge_force[name]`` (N, 2) N on bodies[1] from bodies[0]; ``frame_load_points`` and
    ``frame_load_forces`` (N, K, 2) in the order of ``frame_load_names``.
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
    status: np.ndarray
    messages: list[str]

    def __len__(self) -> int:
        return len(self.status)

    def result(self, i: int) -> Result:
        """Pose i as a :class:`Result` (its status may be an error: check ``status``/``message``)."""
        i = range(len(self))[i]   # IndexError out of range; a negative i counts from the end
        return self.results(i, i + 1)[0]

    def results(self, start: int = 0, stop: int | None = None) -> list[Result]:
        """Poses start..stop-1 as :class:`Result` objects: each array is read once for all of them
        (Python floats and row copies), not once per pose."""
        span = slice(start, stop)

        def rows(group: dict[str, np.ndarray]) -> dict[str, list[np.ndarray]]:
            return {k: list(v[span].copy()) for k, v in group.items()}

        def floats(*arrays: np.ndarray) -> list:
            return list(zip(*(a[span].tolist() for a in arrays)))

        points, poses = rows(self.points), rows(self.body_poses)
        hinges = {k: v[span].tolist() for k, v in self.hinge_force.items()}
        cylinders = {k: floats(self.cylinder_length[k], self.cylinder_force[k], self.cap_pressure_predicted[k],
                               self.cap_pressure_measured[k], self.rod_pressure_measured[k]) for k in self.cylinder_force}
        contacts = {k: floats(v, self.contact_tangential[k]) for k, v in self.contact_normal.items()}
        cgs, load_points, load_forces = (list(a[span].copy()) for a in (self.implement_cg, self.frame_load_points,
                                                                        self.frame_load_forces))
        scalars = floats(self.implement_load, self.residual, self.consistency_residual, self.condition, self.status)
        return [Result(points={k: v[j] for k, v in points.items()}, body_poses={k: v[j] for k, v in poses.items()},
                       hinges={k: hinge_result(v[j][0], v[j][1], *self.hinge_bodies[k]) for k, v in hinges.items()},
                       cylinders={k: CylinderResult(*v[j]) for k, v in cylinders.items()},
                       contacts={k: ContactResult(*v[j]) for k, v in contacts.items()},
                       implement_load=load, implement_cg=cgs[j], frame_load_points=load_points[j],
                       frame_load_forces=load_forces[j], residual=residual, consistency_residual=consistency,
                       condition=condition, status=Status(int(status)).label, message=message)
                for j, ((load, residual, consistency, condition, status), message)
                in enumerate(zip(scalars, self.messages[span]))]


def hinge_result(fx: float, fz: float, from_body: str, on_body: str) -> HingeResult:
    """HingeResult of the force (fx, fz) N on ``on_body`` from ``from_body`` (Python floats: cheap per pose)."""
    return HingeResult(fx, fz, math.hypot(fx, fz), on_body, from_body)


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
