"""The numeric checks of a solved pose: one rule for the live pose and for a replayed segment.

Each check is a bit of a :class:`Check` flag set. ``pose_checks`` takes the values of one pose
as floats (the live node) or of N poses as arrays (N,) (a replay segment) and makes the same
comparisons either way. NaN, a value not computed (no ``tractor`` block, no lift capacity),
passes every check. ``monitoring.core`` words the findings of the bits that are set.
Units SI (m, N).
"""

from __future__ import annotations

import math
from enum import IntFlag
from typing import NamedTuple

import numpy as np

from linkage_monitor.mechanics.reduced import LOAD_AMPLIFICATION_WARN

# Redundant measurements (e.g. stroke and lift-arm angle) never agree exactly: the solver closes
# every hinge and fits the sensors in least squares. Up to CONSISTENCY_WARN_M of their misfit
# (the kinematic residual) is sensor noise; above it a WARN (above core.ASSEMBLY_LIMIT_M the pose
# cannot be assembled from the inputs: an ERROR). With a ~0.1° rockshaft angle sensor and a 0.5 mm
# stroke sensor (the simulator's default noise) the misfit's sigma is ~0.55 mm on belarus_1221, and
# an angle sensor off by 1° adds only 1.8-2.6 mm (the stroke predicts the angle closely): at 1.5 mm
# a simulated lift WARNs on 2 of 252 healthy poses, on 219 of 252 with the angle off by 1°, on every
# pose with 2° (test_redundant_sensors.py); on the bundled bag it WARNs on 14 of 1630 poses.
CONSISTENCY_WARN_M = 1.5e-3
# With more measured forces than needed (e.g. two cylinder pressures), equilibrium is met in
# the least-squares sense; a residual above this share of the largest force means the
# pressures disagree beyond sensor noise.
RESIDUAL_WARN_SHARE = 0.01


class Check(IntFlag):
    """One failed check of a solved pose, in the order its finding is worded."""

    LIFT_OFF = 1              # a ground contact would pull
    SENSORS_DISAGREE = 2      # kinematic residual > CONSISTENCY_WARN_M
    PRESSURES_DISAGREE = 4    # equilibrium residual > RESIDUAL_WARN_SHARE of the largest force
    FRONT_AXLE_LIFT_OFF = 8   # front axle load < 0
    REAR_AXLE_LIFT_OFF = 16   # rear axle load < 0
    STEERABILITY_LOW = 32     # steerability margin < 0
    LIFT_RESERVE_LOW = 64     # lift reserve < 1
    # the 95 % interval of a value that clears its limit reaches across it (monitoring.bounds)
    FRONT_AXLE_UNCERTAIN = 128
    REAR_AXLE_UNCERTAIN = 256
    STEERABILITY_UNCERTAIN = 512
    LIFT_RESERVE_UNCERTAIN = 1024
    LOAD_INFERENCE_WEAK = 2048    # the inferred load's amplification > LOAD_AMPLIFICATION_WARN
    STEERABILITY_DYNAMIC_LOW = 4096   # the dynamic steerability margin < 0 while the static one is not (an IMU)


class CheckedValues(NamedTuple):
    """What the checks look at, for one pose (floats) or N poses (arrays (N,)).

    lift_off: the solver's LIFT_OFF verdict; consistency_residual m, residual N: the solver's
    kinematic and equilibrium residuals; largest_force N (``Result.largest_force``); front/rear_axle_load
    N, margin (steerability margin, -), reserve (lift reserve, -): the machine-level results;
    load_amplification (N per N, ``Result.load_amplification``; NaN: no load inferred); dynamic_margin
    (-): the dynamic steerability margin with an IMU (``mechanics.dynamics``), else NaN.
    """

    lift_off: bool | np.ndarray
    consistency_residual: float | np.ndarray
    residual: float | np.ndarray
    largest_force: float | np.ndarray
    front_axle_load: float | np.ndarray
    rear_axle_load: float | np.ndarray
    margin: float | np.ndarray
    reserve: float | np.ndarray
    load_amplification: float | np.ndarray
    dynamic_margin: float | np.ndarray = math.nan


# the bits as plain ints (an IntFlag member in arithmetic costs as much as the comparison)
_LIFT_OFF, _SENSORS, _PRESSURES, _FRONT, _REAR, _STEER, _RESERVE, _WEAK, _DYNAMIC = (int(c) for c in (
    Check.LIFT_OFF, Check.SENSORS_DISAGREE, Check.PRESSURES_DISAGREE, Check.FRONT_AXLE_LIFT_OFF,
    Check.REAR_AXLE_LIFT_OFF, Check.STEERABILITY_LOW, Check.LIFT_RESERVE_LOW, Check.LOAD_INFERENCE_WEAK,
    Check.STEERABILITY_DYNAMIC_LOW))


def pose_checks(values: CheckedValues) -> int | np.ndarray:
    """The :class:`Check` bits that fail: an int for one pose, an int array (N,) for N poses."""
    v = values
    return (v.lift_off * _LIFT_OFF
            + (v.consistency_residual > CONSISTENCY_WARN_M) * _SENSORS
            + (v.residual > RESIDUAL_WARN_SHARE * v.largest_force) * _PRESSURES
            + (v.front_axle_load < 0.0) * _FRONT
            + (v.rear_axle_load < 0.0) * _REAR
            + (v.margin < 0.0) * _STEER
            + (v.reserve < 1.0) * _RESERVE
            + (v.load_amplification > LOAD_AMPLIFICATION_WARN) * _WEAK
            + (v.dynamic_margin < 0.0) * (v.margin >= 0.0) * _DYNAMIC)

