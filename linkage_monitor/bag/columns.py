"""The sensor topics a replay reads (JointState, FluidPressure) as numpy columns (``read_inputs``)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np


@dataclass(frozen=True)
class JointStateColumns:
    """One JointState topic as columns; row i is message i in log-time order.

    stamp_ns, log_time_ns: header stamp and receive time, ns since the epoch, shape (N,).
    names: joint names, the column order of position and velocity.
    position: rad (revolute) or m (prismatic), shape (N, len(names)); NaN where a message
    lacks the joint. velocity: rad/s or m/s, same shape; NaN where not given.
    """

    stamp_ns: np.ndarray
    log_time_ns: np.ndarray
    names: tuple[str, ...]
    position: np.ndarray
    velocity: np.ndarray


@dataclass(frozen=True)
class PressureColumns:
    """One FluidPressure topic as columns: stamp_ns, log_time_ns (ns since the epoch),
    fluid_pressure (Pa, absolute), variance (Pa^2, 0 = unknown), each shape (N,)."""

    stamp_ns: np.ndarray
    log_time_ns: np.ndarray
    fluid_pressure: np.ndarray
    variance: np.ndarray


def joint_columns(rows: list[tuple[int, int, Any]]) -> JointStateColumns:
    """The columns of a JointState topic's (header stamp, log time, message) rows."""
    names = tuple(dict.fromkeys(n for _, _, msg in rows for n in msg.name))
    column = {n: i for i, n in enumerate(names)}
    position = np.full((len(rows), len(names)), np.nan)
    velocity = np.full((len(rows), len(names)), np.nan)
    for i, (_, _, msg) in enumerate(rows):
        index = [column[n] for n in msg.name]
        position[i, index[:len(msg.position)]] = msg.position
        velocity[i, index[:len(msg.velocity)]] = msg.velocity
    return JointStateColumns(
        stamp_ns=np.array([r[0] for r in rows], dtype=np.int64),
        log_time_ns=np.array([r[1] for r in rows], dtype=np.int64),
        names=names, position=position, velocity=velocity)


def pressure_columns(rows: list[tuple[int, int, Any]]) -> PressureColumns:
    """The columns of a FluidPressure topic's (header stamp, log time, message) rows."""
    return PressureColumns(
        stamp_ns=np.array([r[0] for r in rows], dtype=np.int64),
        log_time_ns=np.array([r[1] for r in rows], dtype=np.int64),
        fluid_pressure=np.array([r[2].fluid_pressure for r in rows], dtype=float),
        variance=np.array([r[2].variance for r in rows], dtype=float))
