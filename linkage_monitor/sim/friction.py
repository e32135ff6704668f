"""Seal friction of a hydraulic cylinder: Coulomb with breakaway (no rclpy).

The seals' friction force opposes the rod's motion. Moving at speed v (m/s) it is

    f(v) = sign(v)·share·|F|·(1 + (breakaway − 1)·exp(−|v|/stribeck_speed))

with F the force the load needs from the cylinder (seal friction grows with the pressure that
presses the seals, so it is a share of the force), a larger breakaway force when the rod starts
from rest and the Coulomb force once it slides (a Stribeck curve). The hydraulic force is the
load's plus the friction: F_hyd = F + f. Standing, the seals hold any force within
±breakaway·share·|F|: the simulator keeps the friction the last motion left (its direction and
the breakaway level at which the rod stopped), scaled with the load. Units SI.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class SealFriction:
    """share: Coulomb friction as a share of the cylinder force (-); breakaway: the friction at rest
    as a multiple of the Coulomb friction (-); stribeck_speed: the rod speed (m/s) over which the
    friction falls from breakaway to Coulomb."""

    share: float = 0.05
    breakaway: float = 1.5
    stribeck_speed: float = 0.005

    def __post_init__(self) -> None:
        if not (math.isfinite(self.share) and 0.0 <= self.share < 1.0):
            raise ValueError(f"friction share is {self.share}: it must be in [0, 1)")
        if not (math.isfinite(self.breakaway) and self.breakaway >= 1.0):
            raise ValueError(f"breakaway factor is {self.breakaway}: it must be >= 1")
        if not (math.isfinite(self.stribeck_speed) and self.stribeck_speed > 0.0):
            raise ValueError(f"Stribeck speed is {self.stribeck_speed} m/s: it must be > 0")

    def force(self, rod_speed: np.ndarray, load_force: np.ndarray) -> np.ndarray:
        """Friction force (N, + = the cylinder must push harder) per sample, for rod speeds (m/s,
        + = extending) and the load's cylinder forces (N); standing samples (speed 0) keep the
        friction share of the last motion (none before the first)."""
        speed = np.asarray(rod_speed, dtype=float)
        level = self.share * (1.0 + (self.breakaway - 1.0) * np.exp(-np.abs(speed) / self.stribeck_speed))
        signed = np.sign(speed) * level                       # friction per newton of load force
        moving = speed != 0.0
        last = np.maximum.accumulate(np.where(moving, np.arange(speed.size), -1))
        held = np.where(last >= 0, signed[np.maximum(last, 0)], 0.0)
        return held * np.abs(load_force)
