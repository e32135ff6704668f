"""A simulated sensor stream and what lies behind it: the noise sigmas, the driving cylinder's
stroke, the noise-free ground truth, and the samples as ROS messages (``sensor_msgs/JointState``,
``sensor_msgs/FluidPressure``). SI units; frame x forward, z up, origin at the rear wheels'
ground contact.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from linkage_monitor.mechanics.constants import ATMOSPHERIC_PRESSURE


@dataclass(frozen=True)
class Noise:
    """Standard deviations of the Gaussian sensor noise: angle (rad), length (m), pressure (Pa)."""

    angle: float = 0.0
    length: float = 0.0
    pressure: float = 0.0

    def __post_init__(self) -> None:
        for name in ("angle", "length", "pressure"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value >= 0.0):
                raise ValueError(f"noise {name} sigma is {value}: it must be a finite number >= 0")


@dataclass(frozen=True)
class Stroke:
    """The driving cylinder and its lengths (m): assemblable range [low, high], work and transport."""

    cylinder: str
    low: float
    high: float
    work: float
    transport: float


@dataclass(frozen=True)
class GroundTruth:
    """Noise-free values behind a stream, per sample (first axis).

    cylinder_lengths (N, C) m in the order of ``SimulatedStream.cylinder_names``; angles (N, A)
    rad and pressures (N, P) gauge Pa in the stream's order; implement_load (N,) N, + = down,
    vertical at the implement cg; implement_cg (N, 2) m; phase (N,) str; steerability_margin
    (N,) k − ratio_min (Popov 2009), NaN without a tractor block; largest_steerable_load N (NaN
    without a tractor block); overload_index: first sample with a negative margin, or None.
    """

    cylinder_lengths: np.ndarray
    angles: np.ndarray
    pressures: np.ndarray
    implement_load: np.ndarray
    implement_cg: np.ndarray
    phase: np.ndarray
    steerability_margin: np.ndarray
    largest_steerable_load: float
    overload_index: int | None


@dataclass(frozen=True)
class SimulatedStream:
    """A simulated sensor stream: N samples of joint positions and chamber pressures.

    stamps_ns (N,) int64; joint_names = angle sensors (rad) then measured cylinders (m, pin to
    pin) as in ``sensor_msgs/JointState``; joint_positions (N, J); pressure_names = pressure
    sensors; pressure_values (N, P) gauge Pa; noise = the sigmas applied; truth = noise-free values.
    """

    mechanism: str
    scenario: str
    rate_hz: float
    stamps_ns: np.ndarray
    joint_names: tuple[str, ...]
    joint_positions: np.ndarray
    pressure_names: tuple[str, ...]
    pressure_values: np.ndarray
    angle_names: tuple[str, ...]
    cylinder_names: tuple[str, ...]
    stroke: Stroke | None   # None for ground-driven scenarios (no driving cylinder)
    noise: Noise
    truth: GroundTruth
    joint_velocities: np.ndarray | None = None   # (N, J) rad/s, m/s when the scenario knows them

    def __len__(self) -> int:
        return len(self.stamps_ns)

    def solver_inputs(self) -> dict[str, dict[str, np.ndarray]]:
        """The (noisy) samples as ``Solver.solve_batch`` keyword arguments (m, rad, gauge Pa)."""
        na = len(self.angle_names)
        return {"cylinders": {n: self.joint_positions[:, na + k] for k, n in enumerate(self.cylinder_names)},
                "angles": {n: self.joint_positions[:, k] for k, n in enumerate(self.angle_names)},
                "pressures": {n: self.pressure_values[:, k] for k, n in enumerate(self.pressure_names)}}

    def joint_state(self, i: int, stamp_ns: int | None = None) -> Any:
        """Sample i as a ``sensor_msgs/JointState`` (position rad / m; velocity rad/s, m/s when the
        scenario gives rates, else empty; effort empty)."""
        from sensor_msgs.msg import JointState

        msg = JointState()
        _set_stamp(msg, self.stamps_ns[i] if stamp_ns is None else stamp_ns)
        msg.name = list(self.joint_names)
        msg.position = [float(v) for v in self.joint_positions[i]]
        if self.joint_velocities is not None:
            msg.velocity = [float(v) for v in self.joint_velocities[i]]
        return msg

    def pressures(self, i: int, gauge: bool = False, stamp_ns: int | None = None) -> dict[str, Any]:
        """Sample i as one ``sensor_msgs/FluidPressure`` per pressure sensor name.

        fluid_pressure in Pa, absolute (gauge + 101325 Pa, as the message defines) unless
        ``gauge``; variance = pressure noise sigma² (Pa²; 0 = unknown, as the message defines).
        """
        from sensor_msgs.msg import FluidPressure

        out = {}
        for k, name in enumerate(self.pressure_names):
            msg = FluidPressure()
            _set_stamp(msg, self.stamps_ns[i] if stamp_ns is None else stamp_ns)
            msg.fluid_pressure = float(self.pressure_values[i, k]) + (0.0 if gauge else ATMOSPHERIC_PRESSURE)
            msg.variance = float(self.noise.pressure ** 2)
            out[name] = msg
        return out


def _set_stamp(msg: Any, stamp_ns: int) -> None:
    stamp_ns = int(stamp_ns)
    msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(stamp_ns, 1_000_000_000)

