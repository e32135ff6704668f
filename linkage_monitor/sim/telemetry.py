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

import math

import numpy as np

from linkage_monitor.mechanics import LinkageError, Mechanism

from .ground import GROUND_SCENARIOS, GroundDrive, ground_profile
from .plant import Plant, chamber_pressure
from .scenarios import (CYLINDER_DRIVES, CYLINDER_SCENARIOS, SCENARIOS, Setting, check_overload, check_scenario,
                        default_duration)
from .stream import GroundTruth, Noise, SimulatedStream, Stroke

__all__ = ["CYLINDER_SCENARIOS", "SCENARIOS", "GroundTruth", "Noise", "Plant", "SimulatedStream", "Stroke",
           "chamber_pressure", "default_duration", "find_stroke", "simulate"]


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
    check_scenario(scenario)
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
    setting = Setting(stroke=stroke, w0=mech.implement.mass * g, w_max=w_max,
                       w_relief=plant.relief_load(stroke.transport))
    if scenario == "overload":
        check_overload(mech, setting)
    profile = CYLINDER_DRIVES[scenario][0](t, setting, rng_scenario)
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
