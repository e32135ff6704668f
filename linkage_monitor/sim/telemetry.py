"""Telemetry simulator: physically consistent sensor streams of a hitch (no rclpy).

``simulate(mechanism, scenario, ...)`` drives the mechanism's lift cylinder (the first
measured cylinder with a pressure sensor, else the first measured cylinder; other measured
cylinders are held at their reference length) through a scenario and gives, per sample:

- the joint-angle sensor values that the kinematics gives for those cylinder lengths (rad),
- the chamber pressures that hold the implement's vertical load at that instant (gauge Pa):
  the statics gives the cylinder force F (linear in the load: two batched solves with implement
  mass 0 and 1000 kg), the pressures follow from the schema's F = count·(p_cap·A_cap − p_rod·A_rod)
  (see ``chamber_pressure``),
- the ground truth (noise-free values, implement load, implement cg, phase, steerability margin
  from ``mechanics.machine``).

Scenarios (t in s; ``W0`` = implement weight = implement.mass·g, N; "work" = the reference
length of the driving cylinder; "transport" = work + 0.6·(top of the assemblable stroke − work);
belarus_1221: work 0.535 m, assemblable 0.4993-0.7989 m, transport 0.6934 m; Popov 2009 Table 1
spans 0.515-0.715 m):

``lift``      one lift cycle of 12.6 s, repeated: work position 2.0 s → raise to transport in
              3.6 s (Popov 2009: lift time 3.5-3.8 s; raised-cosine stroke, peak cylinder speed
              π/2·Δs/3.6 s = 0.069 m/s for belarus_1221) → hold 3.0 s → lower in 4.0 s
              (throttled, by gravity). Load = W0 (quasi-static, inertia neglected as in Popov 2009).
              Phases ``work``, ``raise``, ``transport``, ``lower``.
``transport`` raised, driving over bumps: the cylinder is held at transport, the implement's
              vertical acceleration is a(t) = g·Σ A_k·sin(2π·f_k·t + φ_k), A = 0.15, 0.10, 0.05
              (|a| ≤ 0.3 g), f = 1.1, 2.3, 3.7 Hz, φ_k random from the seed; load = W0·(1 + a/g),
              i.e. ±30 %. Default 20 s. Phase ``transport``.
``field``     working position: soil support s(t) = W0·0.3·(1 + Σ B_k·sin(2π·g_k·t + ψ_k)),
              B = 0.5, 0.3, 0.2, g = 0.05, 0.13, 0.31 Hz (0-60 % of the weight), load = W0 − s;
              the draft varies as d(t) = Σ B_k·sin(2π·h_k·t + χ_k), h = 0.08, 0.21, 0.47 Hz,
              and the hitch control answers it by moving the cylinder ±5 mm (d·5 mm, at most a
              quarter of the stroke to either end) around work. The draft force itself is not
              a solver input (the solver estimates the vertical load only) and is not simulated.
              Default 60 s. Phase ``field``.
``overload``  transport position, a static load ramp (e.g. a hopper being filled): W0 (at most
              0.75·W_max) for 2 s, then linear in 10 s up to min(1.5·W_max, 0.95·W_relief), then
              held 3 s (default 15 s). W_max = the largest implement load the tractor can steer
              with (Popov 2009's moment balance about B, ``mechanics.machine.steerability``) at the
              transport pose; W_relief = the load that brings the cap pressure to relief_pressure.
              belarus_1221: W0 = 15.00 kN, W_max = 22.91 kN, ramp end 30.73 kN (18.41 MPa).
              Phases ``transport``, ``loading``, ``overloaded`` (margin < 0);
              ``truth.overload_index`` = first sample with a negative margin (50 Hz: 352, t = 7.04 s).
              Needs the mechanism's ``tractor`` block.

``field_copy``, ``relief``: driven by the ground, not by a cylinder (Kotov & Krol; Naumenko et al. 2021): see
              :mod:`linkage_monitor.sim.ground`.

Frame: x forward, z up, origin at the rear wheels' ground contact B; SI units.
"""

from __future__ import annotations

import copy
import math
from dataclasses import dataclass
from typing import Any, Callable

import numpy as np

from linkage_monitor.mechanics import LinkageError, Mechanism, Solver, UnobservableError, mechanism_from_dict
from linkage_monitor.mechanics.capacity import interval_around, reference_length, stroke_mechanism
from linkage_monitor.mechanics.constants import ATMOSPHERIC_PRESSURE
from linkage_monitor.mechanics.machine import steerability
from linkage_monitor.mechanics.model import PressureSensor
from linkage_monitor.mechanics.results import Status, angle_readings

from .ground import GROUND_SCENARIOS, GroundDrive, ground_profile

CYLINDER_SCENARIOS = ("lift", "transport", "field", "overload")   # driven by the lift cylinder
SCENARIOS = (*CYLINDER_SCENARIOS, *GROUND_SCENARIOS)
TRANSPORT_FRACTION = 0.6  # transport length = work + this share of the assemblable stroke above work
_UNIT_MASS = 1000.0       # kg, implement mass of the second statics solve (the load is linear in it)


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


# ---- the plant: kinematics and statics of the driven mechanism --------------------------------
@dataclass(frozen=True)
class _Poses:
    """Per sample: angle-sensor values (N, A) rad, implement cg (N, 2) m, cylinder forces (N,) N by name,
    and the forces the linkage puts on the frame: points (N, K, 2) m, forces (N, K, 2) N."""

    angles: np.ndarray
    implement_cg: np.ndarray
    cylinder_force: dict[str, np.ndarray]
    frame_load_points: np.ndarray
    frame_load_forces: np.ndarray

    def steerability_margin(self, mech: Mechanism, load: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(k − ratio_min, largest steerable implement load N) per sample (Popov 2009, via mechanics.machine)."""
        assert mech.tractor is not None   # the callers check: only mechanisms with a tractor block
        steer = steerability(mech.tractor, mech.gravity, self.frame_load_points, self.frame_load_forces,
                             np.broadcast_to(load, self.implement_cg[:, 0].shape), self.implement_cg[:, 0])
        return steer["margin"], steer["max_implement_mass"] * mech.gravity


class Plant:
    """Forward model: cylinder lengths -> angles, implement cg, cylinder forces (affine in the load)."""

    def __init__(self, mech: Mechanism) -> None:
        if mech.implement is None:
            raise ValueError(f"{mech.file}: the simulator needs an 'implement' block (its load is what it varies)")
        meas = mech.measurements
        if not meas.cylinders:
            raise ValueError(f"{mech.file}: the simulator drives the linkage by a measured cylinder length, "
                             f"but measurements.cylinders is empty")
        gauged = [p.cylinder for p in meas.pressures]
        self.driver = next((c for c in meas.cylinders if c in gauged), meas.cylinders[0])
        self.mech = mech
        try:
            raw = copy.deepcopy(dict(stroke_mechanism(mech).raw))   # lengths only: the angles follow from them
        except UnobservableError as exc:
            raise ValueError(f"the simulator drives the linkage by its measured cylinder lengths: {exc}") from exc
        self._solvers = []
        for mass in (0.0, _UNIT_MASS):   # two implement loads: the statics is linear in the load
            raw["implement"]["mass"] = mass
            self._solvers.append(Solver(mechanism_from_dict(copy.deepcopy(raw), mech.file)))
        given = mech.reference_inputs.get("cylinders", {})
        self.reference_length = {c: float(given.get(c, reference_length(mech, c))) for c in meas.cylinders}

    def lengths(self, driver: np.ndarray) -> dict[str, np.ndarray]:
        """All measured cylinder lengths (m): the driver's, the others at their reference length."""
        return {c: driver if c == self.driver else np.full(driver.shape, self.reference_length[c])
                for c in self.mech.measurements.cylinders}

    def poses(self, driver: np.ndarray, load: np.ndarray) -> _Poses:
        """Angles, implement cg and cylinder forces for driver lengths (m) and implement loads (N), per sample.

        Each distinct length is solved once. The statics is linear in the implement load:
        F = F(0) + (F(m₁·g) − F(0))·load/(m₁·g), from two solves with implement mass 0 and m₁.
        """
        lengths, inverse = np.unique(driver, return_inverse=True)
        empty, unit = (s.solve_batch(cylinders=self.lengths(lengths)) for s in self._solvers)
        bad = np.flatnonzero(empty.status != 0)
        if bad.size:
            raise LinkageError(f"{self.mech.file}: {empty.messages[bad[0]]}")
        readings = angle_readings(self.mech, empty)
        angles = np.array([readings[a.name][inverse] for a in self.mech.measurements.angles]
                          ).T.reshape(len(driver), len(self.mech.measurements.angles))
        share = load / (_UNIT_MASS * self.mech.gravity)
        forces = {c.name: empty.cylinder_force[c.name][inverse]
                  + share * (unit.cylinder_force[c.name] - empty.cylinder_force[c.name])[inverse]
                  for c in self.mech.cylinders}
        frame = (empty.frame_load_forces[inverse]
                 + share[:, None, None] * (unit.frame_load_forces - empty.frame_load_forces)[inverse])
        return _Poses(angles=angles, implement_cg=empty.implement_cg[inverse], cylinder_force=forces,
                      frame_load_points=empty.frame_load_points[inverse], frame_load_forces=frame)

    def relief_load(self, driver_length: float) -> float:
        """Implement load (N) at which the driver's cap pressure reaches its relief pressure (inf if none)."""
        cyl = self.mech.cylinder(self.driver)
        if cyl.relief_pressure is None:
            return math.inf
        f0, f1 = self.poses(np.full(2, driver_length), np.array([0.0, 1.0])).cylinder_force[cyl.name]
        return (cyl.relief_pressure * cyl.count * cyl.cap_area - f0) / (f1 - f0) if f1 > f0 else math.inf

    def stroke(self, points: int = 601) -> Stroke:
        """Assemblable range of the driver (grid over ±50 % of its reference length), work, transport."""
        work = float(self.reference_length[self.driver])
        grid = np.linspace(0.5 * work, 1.5 * work, points)
        ok = self._solvers[0].solve_batch(cylinders=self.lengths(grid)).status == Status.OK
        stroke = interval_around(grid, ok, work)
        if stroke is None:
            raise ValueError(f"{self.mech.file}: cylinder '{self.driver}' does not assemble at its reference "
                             f"length {work:.4f} m: check reference_inputs")
        low, high = stroke
        return Stroke(cylinder=self.driver, low=low, high=high, work=work,
                      transport=work + TRANSPORT_FRACTION * (high - work))


# ---- scenarios: driver length (m), implement load (N), phase per sample ----------------------
@dataclass(frozen=True)
class _Setting:
    """What the scenarios build on: the stroke (m), implement weight W0, largest steerable load
    W_max (NaN without a tractor) and the load that opens the relief valve at transport (N)."""

    stroke: Stroke
    w0: float
    w_max: float
    w_relief: float


@dataclass(frozen=True)
class _Profile:
    """A scenario per sample: driving cylinder length (m), implement load (N, + = down), phase name."""

    length: np.ndarray
    load: np.ndarray
    phase: np.ndarray


def _sines(t: np.ndarray, amplitudes: tuple[float, ...], freqs: tuple[float, ...], rng: np.random.Generator) -> np.ndarray:
    phases = rng.uniform(0.0, 2.0 * np.pi, len(freqs))
    return sum(a * np.sin(2.0 * np.pi * f * t + p) for a, f, p in zip(amplitudes, freqs, phases))


LIFT_SEGMENTS = (("work", 2.0), ("raise", 3.6), ("transport", 3.0), ("lower", 4.0))  # s; Popov 2009: lift 3.5-3.8 s


def _lift(t: np.ndarray, setting: _Setting, rng: np.random.Generator) -> _Profile:
    stroke = setting.stroke
    period = sum(d for _, d in LIFT_SEGMENTS)
    tau = np.mod(t, period)
    raised = np.zeros_like(t)             # share of the way from work (0) to transport (1)
    phase = np.empty(t.shape, dtype=object)
    start = 0.0
    for name, dur in LIFT_SEGMENTS:
        seg = (tau >= start) & (tau < start + dur)
        ramp = 0.5 * (1.0 - np.cos(np.pi * (tau[seg] - start) / dur))   # raised cosine: zero speed at both ends
        raised[seg] = {"work": 0.0, "raise": ramp, "transport": 1.0, "lower": 1.0 - ramp}[name]
        phase[seg] = name
        start += dur
    length = stroke.work + raised * (stroke.transport - stroke.work)
    return _Profile(length, np.full(t.shape, setting.w0), phase.astype(str))


def _transport(t: np.ndarray, setting: _Setting, rng: np.random.Generator) -> _Profile:
    accel_g = _sines(t, (0.15, 0.10, 0.05), (1.1, 2.3, 3.7), rng)   # a/g, |a| <= 0.3 g
    return _Profile(np.full(t.shape, setting.stroke.transport), setting.w0 * (1.0 + accel_g),
                    np.full(t.shape, "transport"))


def _field(t: np.ndarray, setting: _Setting, rng: np.random.Generator) -> _Profile:
    stroke, w0 = setting.stroke, setting.w0
    support = w0 * 0.3 * (1.0 + _sines(t, (0.5, 0.3, 0.2), (0.05, 0.13, 0.31), rng))   # 0-60 % of W0
    draft = _sines(t, (0.5, 0.3, 0.2), (0.08, 0.21, 0.47), rng)                        # relative, |d| <= 1
    travel = min(0.005, 0.25 * (stroke.work - stroke.low), 0.25 * (stroke.high - stroke.work))  # m
    return _Profile(stroke.work + travel * draft, w0 - support, np.full(t.shape, "field"))


OVERLOAD_HOLD, OVERLOAD_RAMP, OVERLOAD_END = 2.0, 10.0, 3.0   # s
OVERLOAD_FACTOR = 1.5    # ramp target, × the largest steerable load ...
RELIEF_SHARE = 0.95      # ... but at most this share of the load that opens the relief valve


def _overload(t: np.ndarray, setting: _Setting, rng: np.random.Generator) -> _Profile:
    w_max = setting.w_max
    w_start = min(setting.w0, 0.75 * w_max)
    w_end = min(OVERLOAD_FACTOR * w_max, RELIEF_SHARE * setting.w_relief)
    load = w_start + np.clip((t - OVERLOAD_HOLD) / OVERLOAD_RAMP, 0.0, 1.0) * (w_end - w_start)
    phase = np.where(t < OVERLOAD_HOLD, "transport", np.where(load > w_max, "overloaded", "loading"))
    return _Profile(np.full(t.shape, setting.stroke.transport), load, phase)


_SCENARIOS: dict[str, tuple[Callable[..., _Profile], float]] = {
    "lift": (_lift, sum(d for _, d in LIFT_SEGMENTS)),
    "transport": (_transport, 20.0),
    "field": (_field, 60.0),
    "overload": (_overload, OVERLOAD_HOLD + OVERLOAD_RAMP + OVERLOAD_END),
}


def default_duration(scenario: str) -> float:
    """Natural length of a scenario, s (one lift cycle, 20 s transport, 60 s field, 15 s overload,
    30 s field_copy, 8 s relief)."""
    scenario = _check_scenario(scenario)
    return GROUND_SCENARIOS[scenario] if scenario in GROUND_SCENARIOS else _SCENARIOS[scenario][1]


def _check_scenario(scenario: str) -> str:
    if scenario not in SCENARIOS:
        raise ValueError(f"unknown scenario '{scenario}': choose one of {', '.join(SCENARIOS)}")
    return scenario


def _check_overload(mech: Mechanism, setting: _Setting) -> None:
    """Raise ValueError if the overload scenario cannot drive the steerability margin below zero."""
    if mech.tractor is None:
        raise ValueError(f"{mech.file}: the overload scenario needs the 'tractor' block (steerability)")
    if not (math.isfinite(setting.w_max) and setting.w_max > 0.0):
        raise ValueError(f"{mech.file}: the tractor stays steerable for any implement load (largest steerable "
                         f"load {setting.w_max:.6g} N): the overload scenario cannot overload it")
    if RELIEF_SHARE * setting.w_relief <= setting.w_max:
        raise ValueError(f"{mech.file}: the relief valve limits the implement load ({setting.w_relief:.0f} N) "
                         f"before steerability does ({setting.w_max:.0f} N): the overload scenario cannot "
                         f"make the tractor unsteerable; use transport or lift")


def find_stroke(mechanism: Mechanism) -> Stroke:
    """The driving cylinder's assemblable range, work and transport lengths (m) for ``mechanism``."""
    return Plant(mechanism).stroke()


def simulate(mechanism: Mechanism, scenario: str = "lift", rate_hz: float = 50.0, duration_s: float | None = None,
             noise: Noise = Noise(), seed: int = 0, start_ns: int = 0) -> SimulatedStream:
    """Simulate ``scenario`` (see the module docstring) sampled at ``rate_hz`` for ``duration_s`` s.

    Sample i is stamped ``start_ns + round(i·1e9/rate_hz)`` ns. The scenario's random phases come
    from ``seed``, the noise from an independent stream of the same seed (noise does not change
    the truth). Zero noise gives the exact model values. Raises ValueError naming the bad argument.
    """
    _check_scenario(scenario)
    if not (math.isfinite(rate_hz) and rate_hz > 0.0):
        raise ValueError(f"rate_hz is {rate_hz}: it must be a positive number of samples per second")
    duration_s = default_duration(scenario) if duration_s is None else duration_s
    if not (math.isfinite(duration_s) and duration_s > 0.0):
        raise ValueError(f"duration_s is {duration_s}: it must be a positive number of seconds")
    mech = mechanism
    n = max(1, int(math.floor(duration_s * rate_hz + 1e-9)))
    t = np.arange(n) / rate_hz
    rng_scenario, rng_noise = (np.random.default_rng([seed, k]) for k in (0, 1))
    stamps = start_ns + np.round(np.arange(n) * (1e9 / rate_hz)).astype(np.int64)
    if scenario in GROUND_SCENARIOS:
        return _simulate_ground(mech, scenario, rate_hz, t, stamps, noise, rng_scenario, rng_noise)
    plant = Plant(mech)
    stroke = plant.stroke()
    g = mech.gravity
    tractor = mech.tractor
    w_max = float("nan")
    if tractor is not None:   # largest steerable load at the transport pose (margin(W) = 0)
        w_max = float(plant.poses(np.array([stroke.transport]), np.zeros(1)).steerability_margin(mech, np.zeros(1))[1][0])
    assert mech.implement is not None   # the plant (above) refuses a mechanism without an implement
    setting = _Setting(stroke=stroke, w0=mech.implement.mass * g, w_max=w_max,
                       w_relief=plant.relief_load(stroke.transport))
    if scenario == "overload":
        _check_overload(mech, setting)
    profile = _SCENARIOS[scenario][0](t, setting, rng_scenario)
    try:
        poses = plant.poses(profile.length, profile.load)
    except LinkageError as exc:
        raise LinkageError(f"scenario '{scenario}' leaves the assemblable stroke: {exc}") from exc
    load, cg, truth_angles = profile.load, poses.implement_cg, poses.angles
    truth_pressures = np.column_stack([chamber_pressure(mech, ps, poses.cylinder_force[ps.cylinder])
                                       for ps in mech.measurements.pressures] or [np.zeros((n, 0))])
    cyl_names = tuple(mech.measurements.cylinders)
    lengths_all = plant.lengths(profile.length)
    truth_lengths = np.column_stack([lengths_all[c] for c in cyl_names])
    margin = poses.steerability_margin(mech, load)[0] if tractor is not None else np.full(n, np.nan)
    below = np.flatnonzero(margin < 0.0)
    overload_index = int(below[0]) if scenario == "overload" and below.size else None

    angle_names = tuple(a.name for a in mech.measurements.angles)
    joints = np.concatenate([truth_angles + noise.angle * rng_noise.standard_normal(truth_angles.shape),
                             truth_lengths + noise.length * rng_noise.standard_normal(truth_lengths.shape)], axis=1)
    measured_p = truth_pressures + noise.pressure * rng_noise.standard_normal(truth_pressures.shape)
    return SimulatedStream(
        mechanism=mech.name, scenario=scenario, rate_hz=float(rate_hz), stamps_ns=stamps,
        joint_names=angle_names + cyl_names, joint_positions=joints,
        pressure_names=tuple(p.name for p in mech.measurements.pressures), pressure_values=measured_p,
        angle_names=angle_names, cylinder_names=cyl_names, stroke=stroke, noise=noise,
        truth=GroundTruth(cylinder_lengths=truth_lengths, angles=truth_angles, pressures=truth_pressures,
                          implement_load=load, implement_cg=cg, phase=profile.phase,
                          steerability_margin=margin, largest_steerable_load=w_max, overload_index=overload_index))


def _simulate_ground(mech: Mechanism, scenario: str, rate_hz: float, t: np.ndarray, stamps: np.ndarray,
                     noise: Noise, rng_scenario: np.random.Generator, rng_noise: np.random.Generator
                     ) -> SimulatedStream:
    """A ground-driven scenario (sim.ground): the angle reading and its rate from the ground's
    height under the contact, cylinders held, pressures from the statics."""
    drive = GroundDrive(mech)
    n = t.size
    dh, dh_dt, phase = ground_profile(scenario, t, rng_scenario)
    angle, dtheta_dh = drive.angle(drive.reference_height + dh)
    cyl_names = tuple(mech.measurements.cylinders)
    truth_lengths = np.array([[drive.lengths[c] for c in cyl_names]] * n).reshape(n, len(cyl_names))
    forces = drive.cylinder_forces(angle) if mech.measurements.pressures else {}
    truth_pressures = np.column_stack([chamber_pressure(mech, ps, forces[ps.cylinder])
                                       for ps in mech.measurements.pressures] or [np.zeros((n, 0))])
    truth_angles = angle[:, None]
    joints = np.concatenate([truth_angles + noise.angle * rng_noise.standard_normal(truth_angles.shape),
                             truth_lengths + noise.length * rng_noise.standard_normal(truth_lengths.shape)], axis=1)
    rates = np.concatenate([(dtheta_dh * dh_dt)[:, None], np.zeros((n, len(cyl_names)))], axis=1)
    nan = np.full(n, np.nan)
    return SimulatedStream(
        mechanism=mech.name, scenario=scenario, rate_hz=float(rate_hz), stamps_ns=stamps,
        joint_names=(drive.sensor.name,) + cyl_names, joint_positions=joints,
        pressure_names=tuple(p.name for p in mech.measurements.pressures),
        pressure_values=truth_pressures + noise.pressure * rng_noise.standard_normal(truth_pressures.shape),
        angle_names=(drive.sensor.name,), cylinder_names=cyl_names, stroke=None, noise=noise,
        truth=GroundTruth(cylinder_lengths=truth_lengths, angles=truth_angles, pressures=truth_pressures,
                          implement_load=nan, implement_cg=np.full((n, 2), np.nan), phase=phase,
                          steerability_margin=nan, largest_steerable_load=math.nan, overload_index=None),
        joint_velocities=rates)


def chamber_pressure(mech: Mechanism, sensor: PressureSensor, force: np.ndarray) -> np.ndarray:
    """Gauge pressure (Pa) of ``sensor``'s chamber for the cylinder force (N, + = pushing).

    F = count·(p_cap·A_cap − p_rod·A_rod) (schema). Both chambers measured: the pushed side
    carries the force, the other is at 0 gauge (tank). One chamber measured: it carries all
    of F (a cap chamber's pressure is negative gauge if the cylinder pulls).
    """
    cyl = mech.cylinder(sensor.cylinder)
    chambers = {p.chamber for p in mech.measurements.pressures if p.cylinder == cyl.name}
    both = len(chambers) == 2
    if sensor.chamber == "cap":
        return (np.maximum(force, 0.0) if both else force) / (cyl.count * cyl.cap_area)
    return (np.maximum(-force, 0.0) if both else -force) / (cyl.count * cyl.rod_area)
