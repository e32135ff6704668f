"""The patents' weighing methods, on the same steps as the estimator (for ``bench_weighing.py``).

Each takes the steps' lift cylinder lengths (m) and forces (N), the phases the estimator named
(which steps move up, down, or stand raised) and the force model (``WeighingModel``), and gives
the implement's mass (kg) and, where the method finds it, the cg's x (m, reference pose). The
cg they do not find is the mechanism file's (the operator's guess).

- one pose (the basic hitch weighing): the force standing raised, at the file's cg; the seal
  friction the cylinder was left with is in it.
- two poses (CNH US7588089): the forces at two hitch positions while lifting, solved for the
  weight and the cg's x (the cg's z at the file's); the lifting friction is in it.
- lift/lower pair (Bosch DE4328143): the mean of the lifting and the lowering force at one pose,
  at the file's cg: friction cancelled, the cg assumed.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from linkage_monitor.monitoring.weighing import WeighingPhase
from linkage_monitor.monitoring.weighing_model import WeighingModel

WINDOW = 0.01   # m of cylinder travel around a pose whose steps are averaged


@dataclass(frozen=True)
class MethodEstimate:
    """mass (kg), cg_x (m, NaN where the method does not find it)."""

    mass: float
    cg_x: float


def _columns(model: WeighingModel, lengths: np.ndarray) -> np.ndarray:
    """(N, 4): link, u0, ux, uz per step (NaN off the table)."""
    rows = [model.at(float(s)) for s in lengths]
    return np.array([[c.link, c.u0, c.ux, c.uz] if c is not None else [math.nan] * 4 for c in rows]).reshape(-1, 4)


def _near(lengths: np.ndarray, chosen: np.ndarray, at: float) -> np.ndarray:
    return chosen & (np.abs(lengths - at) < WINDOW)


def one_pose(model: WeighingModel, lengths: np.ndarray, forces: np.ndarray, phases: list[WeighingPhase]
             ) -> MethodEstimate:
    """The first raised standstill, at the file's cg."""
    standing = np.array([p is WeighingPhase.STANDING for p in phases])
    raised = standing & ((lengths - model.reference_length) * model.lifting_sign > 0.3 * (model.high - model.low))
    first = np.flatnonzero(raised)
    if first.size == 0:
        return MethodEstimate(math.nan, math.nan)
    run = first[: np.argmax(np.diff(first) > 1) + 1] if np.any(np.diff(first) > 1) else first
    cols = _columns(model, lengths[run])
    weight = np.mean((forces[run] - cols[:, 0]) / cols[:, 1])
    return MethodEstimate(float(weight / model.gravity), math.nan)


def _travel(lengths: np.ndarray, mask: np.ndarray, share: float) -> float:
    low, high = np.min(lengths[mask]), np.max(lengths[mask])
    return float(low + share * (high - low))


def two_poses(model: WeighingModel, lengths: np.ndarray, forces: np.ndarray, phases: list[WeighingPhase]
              ) -> MethodEstimate:
    """Two positions (a third and nine tenths of the lifted travel) of the first lift: W and W·dx."""
    lifting = np.array([p is WeighingPhase.LIFTING for p in phases])
    if not lifting.any():
        return MethodEstimate(math.nan, math.nan)
    rows, ys = [], []
    for share in (0.3, 0.9):
        near = _near(lengths, lifting, _travel(lengths, lifting, share))
        first = np.flatnonzero(near)
        run = first[: np.argmax(np.diff(first) > 1) + 1] if np.any(np.diff(first) > 1) else first
        cols = _columns(model, lengths[run])
        rows.append(cols[:, 1:3].mean(axis=0))
        ys.append(float(np.mean(forces[run] - cols[:, 0])))
    weight, moment = np.linalg.solve(np.array(rows), np.array(ys))
    return MethodEstimate(float(weight / model.gravity), float(model.reference_cg[0] + moment / weight))


def lift_lower_pair(model: WeighingModel, lengths: np.ndarray, forces: np.ndarray, phases: list[WeighingPhase]
                    ) -> MethodEstimate:
    """Lifting and lowering at the middle of the travel, averaged, at the file's cg."""
    lifting = np.array([p is WeighingPhase.LIFTING for p in phases])
    lowering = np.array([p is WeighingPhase.LOWERING for p in phases])
    if not (lifting.any() and lowering.any()):
        return MethodEstimate(math.nan, math.nan)
    at = _travel(lengths, lifting, 0.5)
    loads = []
    for mask in (lifting, lowering):
        near = np.flatnonzero(_near(lengths, mask, at))
        cols = _columns(model, lengths[near])
        loads.append(float(np.mean((forces[near] - cols[:, 0]) / cols[:, 1])))
    return MethodEstimate(float(0.5 * sum(loads) / model.gravity), math.nan)
