"""Ordinary work cycles with a known implement: what the weighing estimator must face (no rclpy).

``simulate_work`` runs a hitch through repeated cycles of ``WorkCycle``: the implement in its
working position on the ground (the ground carries ``ground_support`` of its weight, the
cylinder stands), a lift to transport (raised-cosine stroke, as ``sim.telemetry``'s ``lift``), a
transport stretch driven on a road (the cylinder stands, the valve closed, the body bounces:
``sim.road``), a lower to work. The tractor drives slowly while lifting and lowering (a
headland): the body bounces with ``headland_bounce`` of the transport's acceleration.

The truth the estimator does not see: the implement's mass and cg (``ImplementTruth``, placed in a
copy of the mechanism), an optional change of its mass mid-run (``LoadChange``: coupling,
filling; at the same cg), the seal friction (``sim.friction``), the pressure sensors'
calibration errors (``PressureErrors``: a gain and an offset per run, on top of the noise) and
the implement's vertical acceleration, the body's (``mechanics.dynamics.BodyAcceleration``: at the
rear axle and the pitch's). The IMU sits on the body at x = ``imu_x``. The cylinder's force is the statics' for the
implement's load W·(1 + a/g) (the links' own inertia neglected) plus the friction. Units SI;
frame x forward, z up, origin at the rear wheels' ground contact.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from linkage_monitor.mechanics import Mechanism
from linkage_monitor.mechanics.constants import STANDARD_GRAVITY
from linkage_monitor.mechanics.dynamics import BodyAcceleration
from linkage_monitor.mechanics.implements import ImplementFile, Tolerances
from linkage_monitor.mechanics.implements import with_implement as hang_implement

from .friction import SealFriction
from .plant import Plant, chamber_pressure
from .road import BodyMotion, ImuNoise, ImuReadings, Road
from .stream import GroundTruth, Noise, SimulatedStream

DEFAULT_WHEELBASE = 2.5   # m, when the mechanism has no tractor block
CONTACT_TRAVEL = 0.005    # m of cylinder travel over which the implement leaves the ground


# The work cycle's records (its durations, the true implement, a load change, pressure errors, the
# truth per sample): fields of their own data, alike in form only to mechanics.model's joints and
# mounts, monitoring.weighing's settings and weighing_fit's records, sim.road's and sim.coverage's
# records and test/support/fuzz_check's tally.
@dataclass(frozen=True)
class WorkCycle:
    """Durations (s) of the cycle's phases; ground_support: the share of the implement's weight the
    ground carries in the working position; headland_bounce: the body's acceleration while lifting
    and lowering as a share of the transport's."""

    work_s: float = 4.0
    raise_s: float = 3.6
    transport_s: float = 10.0
    lower_s: float = 4.0
    ground_support: float = 0.4
    headland_bounce: float = 0.1

    @property
    def period(self) -> float:
        """One cycle, s."""
        return self.work_s + self.raise_s + self.transport_s + self.lower_s


@dataclass(frozen=True)
class ImplementTruth:
    """The true implement: mass (kg) and cg (m, reference pose of the mechanism)."""

    mass: float
    cg: tuple[float, float]


@dataclass(frozen=True)
class LoadChange:
    """The implement's mass multiplied by ``factor`` from ``at_s`` (s) on (coupling, filling)."""

    at_s: float
    factor: float


@dataclass(frozen=True)
class PressureErrors:
    """A pressure sensor's calibration error: reading = (1 + gain)·p + offset (-, Pa)."""

    gain: float = 0.0
    offset: float = 0.0


@dataclass(frozen=True)
class WorkTruth:
    """Per sample: the implement's mass (kg), its vertical acceleration (m/s², + up), the body's
    (vertical at the rear axle, m/s², and pitch, rad/s², nose up), the seal friction (N), the phase; the cg (m, reference pose), the index of the first sample after the
    mass change (None without one), the pressure errors applied."""

    mass: np.ndarray
    acceleration: np.ndarray
    body: BodyAcceleration
    friction: np.ndarray
    phase: np.ndarray
    cg: tuple[float, float]
    change_index: int | None
    pressure_errors: PressureErrors


@dataclass(frozen=True)
class WorkRun:
    """A simulated work run: the sensor stream (JointState + FluidPressure), the IMU (None without a
    road) and the truth."""

    stream: SimulatedStream
    imu: ImuReadings | None
    truth: WorkTruth


def with_implement(mechanism: Mechanism, implement: ImplementTruth) -> Mechanism:
    """A copy of ``mechanism`` whose implement has the given mass and cg (hung as an implement file is:
    ``mechanics.implements.with_implement``)."""
    truth = ImplementFile(name="truth", description="the simulator's true implement", mechanism=mechanism.name,
                          mass=float(implement.mass), cg=(float(implement.cg[0]), float(implement.cg[1])),
                          hitch_point=None, mast_point=None, tolerances=Tolerances(), file="<simulator>")
    return hang_implement(mechanism, truth)


def _cycle(t: np.ndarray, cycle: WorkCycle) -> tuple[np.ndarray, np.ndarray]:
    """Per sample: the share of the way from work (0) to transport (1), and the phase name."""
    tau = np.mod(t, cycle.period)
    raised = np.zeros_like(t)
    phase = np.empty(t.shape, dtype=object)
    start = 0.0
    for name, dur in (("work", cycle.work_s), ("raise", cycle.raise_s), ("transport", cycle.transport_s),
                      ("lower", cycle.lower_s)):
        seg = (tau >= start) & (tau < start + dur)
        ramp = 0.5 * (1.0 - np.cos(np.pi * (tau[seg] - start) / dur))
        raised[seg] = {"work": 0.0, "raise": ramp, "transport": 1.0, "lower": 1.0 - ramp}[name]
        phase[seg] = name
        start += dur
    return raised, phase.astype(str)


def simulate_work(mechanism: Mechanism, implement: ImplementTruth, duration_s: float = 120.0, rate_hz: float = 50.0,
                  cycle: WorkCycle = WorkCycle(), friction: SealFriction = SealFriction(),
                  road: Road | None = Road(), noise: Noise = Noise(), imu_noise: ImuNoise = ImuNoise(),
                  pressure_errors: PressureErrors = PressureErrors(), change: LoadChange | None = None,
                  seed: int = 0, imu_x: float = 0.0) -> WorkRun:
    """Simulate ``duration_s`` s of work cycles of ``mechanism`` carrying ``implement`` (module docstring)."""
    if not (math.isfinite(duration_s) and duration_s > 0.0 and math.isfinite(rate_hz) and rate_hz > 0.0):
        raise ValueError(f"duration {duration_s} s and rate {rate_hz} Hz must be positive numbers")
    mech = with_implement(mechanism, implement)
    plant = Plant(mech)
    stroke = plant.stroke()
    n = max(2, int(math.floor(duration_s * rate_hz + 1e-9)))
    t = np.arange(n) / rate_hz
    stamps = np.round(np.arange(n) * (1e9 / rate_hz)).astype(np.int64)
    rng_road, rng_noise = (np.random.default_rng([seed, k]) for k in (2, 3))
    raised, phase = _cycle(t, cycle)
    length = stroke.work + raised * (stroke.transport - stroke.work)
    mass = np.full(n, float(implement.mass))
    change_index = None
    if change is not None:
        after = t >= change.at_s
        mass[after] *= change.factor
        change_index = int(np.argmax(after)) if after.any() else None
    cg_x = float(plant.poses(np.array([stroke.transport]), np.zeros(1)).implement_cg[0, 0])
    wheelbase = mech.tractor.wheelbase if mech.tractor is not None else DEFAULT_WHEELBASE
    envelope = np.select([phase == "transport", (phase == "raise") | (phase == "lower")],
                         [1.0, cycle.headland_bounce], 0.0)
    imu = None
    accel = np.zeros(n)
    body = BodyAcceleration(np.zeros(n), np.zeros(n))
    if road is not None:
        motion = BodyMotion(road, wheelbase, cg_x, rng_road)
        motion.scale_to_peak(t)
        accel = envelope * motion.vertical_acceleration(t, cg_x)
        body = BodyAcceleration(envelope * motion.vertical_acceleration(t, 0.0), envelope * motion.pitch(t, 2))
        imu_raw = motion.imu(t, stamps, imu_x, ImuNoise(0.0, 0.0), rng_noise)
        rest = np.array([0.0, 0.0, STANDARD_GRAVITY])
        imu = ImuReadings(stamps_ns=stamps,
                          linear_acceleration=rest + envelope[:, None] * (imu_raw.linear_acceleration - rest)
                          + imu_noise.acceleration * rng_noise.standard_normal((n, 3)),
                          angular_velocity=envelope[:, None] * imu_raw.angular_velocity
                          + imu_noise.angular_velocity * rng_noise.standard_normal((n, 3)),
                          noise=imu_noise)
    weight = mass * mech.gravity
    on_ground = np.clip(1.0 - (length - stroke.work) / CONTACT_TRAVEL, 0.0, 1.0)
    load = weight * (1.0 + accel / mech.gravity) - cycle.ground_support * weight * on_ground
    poses = plant.poses(length, load)
    rod_speed = np.gradient(length, t)
    rod_speed[np.abs(rod_speed) < 1e-9] = 0.0
    forces = dict(poses.cylinder_force)
    seal = friction.force(rod_speed, forces[plant.driver])
    forces[plant.driver] = forces[plant.driver] + seal
    true_p = np.column_stack([chamber_pressure(mech, ps, forces[ps.cylinder]) for ps in mech.measurements.pressures])
    measured_p = ((1.0 + pressure_errors.gain) * true_p + pressure_errors.offset
                  + noise.pressure * rng_noise.standard_normal(true_p.shape))
    cyl_names = tuple(mech.measurements.cylinders)
    lengths = plant.lengths(length)
    true_lengths = np.column_stack([lengths[c] for c in cyl_names])
    angle_names = tuple(a.name for a in mech.measurements.angles)
    joints = np.concatenate([poses.angles + noise.angle * rng_noise.standard_normal(poses.angles.shape),
                             true_lengths + noise.length * rng_noise.standard_normal(true_lengths.shape)], axis=1)
    nan = np.full(n, np.nan)
    stream = SimulatedStream(
        mechanism=mech.name, scenario="work_cycle", rate_hz=float(rate_hz), stamps_ns=stamps,
        joint_names=angle_names + cyl_names, joint_positions=joints,
        pressure_names=tuple(p.name for p in mech.measurements.pressures), pressure_values=measured_p,
        angle_names=angle_names, cylinder_names=cyl_names, stroke=stroke, noise=noise,
        truth=GroundTruth(cylinder_lengths=true_lengths, angles=poses.angles, pressures=true_p, implement_load=load,
                          implement_cg=poses.implement_cg, phase=phase, steerability_margin=nan,
                          largest_steerable_load=math.nan, overload_index=None))
    return WorkRun(stream=stream, imu=imu,
                   truth=WorkTruth(mass=mass, acceleration=accel, body=body, friction=seal, phase=phase,
                                   cg=(float(implement.cg[0]), float(implement.cg[1])), change_index=change_index,
                                   pressure_errors=pressure_errors))
