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
        return Result(
            points={k: v[i].copy() for k, v in self.points.items()},
            body_poses={k: v[i].copy() for k, v in self.body_poses.items()},
            hinges={k: hinge_result(float(v[i, 0]), float(v[i, 1]), *self.hinge_bodies[k]) for k, v in self.hinge_force.items()},
            cylinders={k: CylinderResult(length=float(self.cylinder_length[k][i]), force=float(self.cylinder_force[k][i]),
                                         cap_pressure_predicted=float(self.cap_pressure_predicted[k][i]),
                                         cap_pressure_measured=float(self.cap_pressure_measured[k][i]),
                                         rod_pressure_measured=float(self.rod_pressure_measured[k][i]))
                       for k in self.cylinder_force},
            contacts={k: ContactResult(normal=float(v[i]), tangential=float(self.contact_tangential[k][i]))
                      for k, v in self.contact_normal.items()},
            implement_load=float(self.implement_load[i]), implement_cg=self.implement_cg[i].copy(),
            frame_load_points=self.frame_load_points[i].copy(), frame_load_forces=self.frame_load_forces[i].copy(),
            residual=float(self.residual[i]), consistency_residual=float(self.consistency_residual[i]),
            condition=float(self.condition[i]), status=Status(int(self.status[i])).label, message=self.messages[i])


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
