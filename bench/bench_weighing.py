"""The weighing estimator against simulated work whose truth it does not see (docs/weighing.md).

On each hitch preset, ``--runs`` random implements (mass uniform over the preset's range, the
cg up to ±0.3 m along x and ±0.2 m along z from the file's, in the implement's frame), seal
friction 2-8 % of the force (breakaway 1.5×), the pressure sensor's gain and offset drawn from
their declared σ (0.5 %, 0.02 MPa) plus 0.02 MPa noise, stroke 0.2 mm and angle 0.5 mrad noise,
a road at 3-8 m/s bouncing the implement by up to ±0.3 g in transport, 120 s of ordinary work
cycles (``sim.work_cycle``: work on the ground, lift, transport, lower) at 50 Hz. The monitor's
steps are the solver's poses of the noisy inputs. Printed per preset:

- the mass error (RMS and worst, % of the true mass) and the cg x error (RMS, mm) of the
  patents' methods (``weighing_methods.py``) and of the estimator with and without the IMU;
- the estimator's 95 % intervals' coverage of the true mass and cg x with its binomial 95 %
  confidence interval (Clopper & Pearson 1934; ±2.1 % over the default 400 runs, ±5.5 % over 60:
  wider than the goal's band), and the RMS of the errors over their u (1 where u is right);
- a second set of ``--change-runs`` runs whose implement's mass changes by ±30 % in the second
  transport: the share detected by the end of the next lift/lower cycle, false detections, and
  the mass error one cycle after the change;
- the estimator's cost per step (CPU time, median over the runs, all steps, refits included).

Goals: mass RMS ≤ 2 %, worst ≤ 4 %; cg x RMS ≤ 20 mm; coverage 93-97 %;
a change detected and re-estimated within one lift/lower cycle; ≤ 10 µs per step.

``--mass LOW HIGH`` draws the implements from another range (the light ones, where the pressure's
offset and noise weigh most); ``--pressure-noise/--pressure-gain/--pressure-offset`` set another
transducer class (the simulator draws from it, the estimator is told it). The estimator's runs
worse than 4 % are counted, with the heaviest of them.

Run: ``.venv/bin/python bench/bench_weighing.py [--runs 400] [--change-runs 40] [--preset belarus_1221]
[--mass 200 400] [--pressure-noise 2e4 --pressure-gain 0.005 --pressure-offset 2e4]``
"""

from __future__ import annotations

import argparse
import copy
import math
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy.stats import beta

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
sys.path.insert(0, str(Path(__file__).resolve().parent))
from linkage_monitor.mechanics import Mechanism, Solver, load_preset, mechanism_from_dict  # noqa: E402
from linkage_monitor.mechanics.constants import STANDARD_GRAVITY  # noqa: E402
from linkage_monitor.monitoring.weighing import WeighingEstimator, WeighingSettings  # noqa: E402
from linkage_monitor.monitoring.weighing_model import WeighingModel  # noqa: E402
from linkage_monitor.sim.friction import SealFriction  # noqa: E402
from linkage_monitor.sim.road import Road  # noqa: E402
from linkage_monitor.sim.telemetry import Noise  # noqa: E402
from linkage_monitor.sim.work_cycle import (ImplementTruth, LoadChange, PressureErrors, WorkCycle,  # noqa: E402
                                            WorkRun, simulate_work)
from weighing_methods import lift_lower_pair, one_pose, two_poses  # noqa: E402

ANGLE_NOISE, LENGTH_NOISE = 0.0005, 0.0002   # rad, m
CYCLE = WorkCycle()
DURATION = 120.0
RATE = 50.0


def hitches() -> dict[str, tuple[Mechanism, tuple[float, float]]]:
    """The hitch presets with their implement mass ranges (kg). damping_hitch lifted out of the soil:
    its draft load dropped, and its strut's pressure not used (without the draft the strut pulls,
    which its one measured chamber cannot show); its assumed 100 mm cylinder reaches its 20 MPa
    relief near 1,800 kg with friction, hence 200-1,500 kg."""
    damping = load_preset("damping_hitch")
    raw = copy.deepcopy(dict(damping.raw))
    raw.pop("loads")
    raw["measurements"]["pressures"] = [p for p in raw["measurements"]["pressures"] if p["cylinder"] == "lift_cylinder"]
    return {"belarus_1221": (load_preset("belarus_1221"), (200.0, 2500.0)),
            "damping_hitch (lifted)": (mechanism_from_dict(raw, damping.file), (200.0, 1500.0))}


@dataclass(frozen=True)
class Transducer:
    """The pressure transducer's accuracy (1 σ): noise per reading (Pa), gain (relative, -), offset (Pa).
    The simulator draws its errors from it and the estimator is told it (``WeighingSettings``)."""

    noise: float = 2e4
    gain: float = 0.005
    offset: float = 2e4


DECLARED = Transducer()   # the declared sensor's (WeighingSettings' defaults)


@dataclass(frozen=True)
class Outcome:
    """One run: the true mass (kg) and cg x (m), each method's (mass, cg x), the estimator's
    uncertainties, the detection delay (s, NaN: not detected), false detections, cost (µs/step)."""

    mass: float
    cg_x: float
    methods: dict[str, tuple[float, float]]
    mass_u: float
    cg_x_u: float
    detected_after: float
    false_changes: int
    mass_after_change: float
    step_us: float


def _run(mech: Mechanism, model: WeighingModel, mass_range: tuple[float, float], seed: int,
         change: float | None, sensor: Transducer = DECLARED) -> Outcome:
    rng = np.random.default_rng([seed, 49])
    ref = np.asarray(mech.implement.cg)
    implement = ImplementTruth(mass=float(rng.uniform(*mass_range)),
                          cg=(float(ref[0] + rng.uniform(-0.3, 0.3)), float(ref[1] + rng.uniform(-0.2, 0.2))))
    change_at = CYCLE.period + CYCLE.work_s + CYCLE.raise_s + 0.5 * CYCLE.transport_s
    run = simulate_work(mech, implement, DURATION, RATE, CYCLE,
                        friction=SealFriction(share=float(rng.uniform(0.02, 0.08))),
                        road=Road(speed=float(rng.uniform(3.0, 8.0))),
                        noise=Noise(angle=ANGLE_NOISE, length=LENGTH_NOISE, pressure=sensor.noise),
                        pressure_errors=PressureErrors(float(rng.normal(0.0, sensor.gain)),
                                                       float(rng.normal(0.0, sensor.offset))),
                        change=LoadChange(change_at, 1.0 + change) if change else None, seed=seed)
    settings = WeighingSettings(pressure_noise=sensor.noise, pressure_gain=sensor.gain, pressure_offset=sensor.offset)
    batch = Solver(mech).solve_batch(**run.stream.solver_inputs())
    lengths, forces = batch.cylinder_length[model.cylinder], batch.cylinder_force[model.cylinder]
    stamps = run.stream.stamps_ns
    methods: dict[str, tuple[float, float]] = {}
    outcome_u = (math.nan, math.nan)
    after_change, detected, false, cost = math.nan, math.nan, 0, math.nan
    for label, imu in (("estimator, IMU", True), ("estimator, no IMU", False)):
        estimator = WeighingEstimator(mech, settings, model=model)
        accel = _imu_vertical(run) if imu else None
        start = time.process_time()   # CPU time: the machine may be shared
        phases = estimator.run(stamps, lengths, forces, accel)
        cost = (time.process_time() - start) / len(stamps) * 1e6 if imu else cost
        est = estimator.estimate
        methods[label] = (est.mass, est.cg_x) if est is not None else (math.nan, math.nan)
        if imu:
            outcome_u = (est.mass_u, est.cg_x_u) if est is not None else outcome_u
            changes = [c.stamp_ns * 1e-9 for c in estimator.changes]
            false = sum(t < change_at for t in changes) if change else len(changes)
            later = [t - change_at for t in changes if t >= change_at]
            detected = later[0] if (change and later) else math.nan
            if change:
                after_change = _mass_at(mech, model, settings, run, lengths, forces, accel, change_at + CYCLE.period)
            for name, method in (("one pose", one_pose), ("two poses", two_poses),
                                 ("lift/lower pair", lift_lower_pair)):
                found = method(model, lengths, forces, phases)
                methods[name] = (found.mass, found.cg_x)
    return Outcome(float(run.truth.mass[-1]), implement.cg[0], methods, outcome_u[0], outcome_u[1], detected, false,
                   after_change, cost)


def _imu_vertical(run: WorkRun) -> np.ndarray:
    assert run.imu is not None
    return run.imu.linear_acceleration[:, 2] - STANDARD_GRAVITY


def _mass_at(mech: Mechanism, model: WeighingModel, settings: WeighingSettings, run: WorkRun, lengths: np.ndarray, forces: np.ndarray,
             accel: np.ndarray | None, until_s: float) -> float:
    """The estimator's mass (kg) from the steps up to ``until_s``."""
    keep = run.stream.stamps_ns * 1e-9 <= until_s
    estimator = WeighingEstimator(mech, settings, model=model)
    estimator.run(run.stream.stamps_ns[keep], lengths[keep], forces[keep], None if accel is None else accel[keep])
    est = estimator.estimate
    return est.mass if est is not None else math.nan


def _report(name: str, outcomes: list[Outcome], changed: list[Outcome]) -> None:
    truth_m = np.array([o.mass for o in outcomes])
    truth_x = np.array([o.cg_x for o in outcomes])
    print(f"\n{name}: {len(outcomes)} implements, {truth_m.min():.0f}-{truth_m.max():.0f} kg")
    print(f"{'method':<20} {'mass RMS %':>10} {'worst %':>8} {'cg x RMS mm':>12}")
    for method in outcomes[0].methods:
        m = np.array([o.methods[method][0] for o in outcomes])
        x = np.array([o.methods[method][1] for o in outcomes])
        rel = (m - truth_m) / truth_m * 100.0
        cg = f"{math.sqrt(np.mean((x - truth_x) ** 2)) * 1e3:12.1f}" if np.all(np.isfinite(x)) else f"{'(file)':>12}"
        print(f"{method:<20} {math.sqrt(np.nanmean(rel ** 2)):10.2f} {np.nanmax(np.abs(rel)):8.2f} {cg}")
    m = np.array([o.methods["estimator, IMU"][0] for o in outcomes])
    x = np.array([o.methods["estimator, IMU"][1] for o in outcomes])
    rel = np.abs(m - truth_m) / truth_m * 100.0
    worse = truth_m[~(rel <= 4.0)]
    print(f"estimator, IMU: runs worse than 4 %: {worse.size}/{len(outcomes)}"
          + (f", the heaviest of them {worse.max():.0f} kg; worst {np.nanmax(rel):.2f} % at {truth_m[np.nanargmax(rel)]:.0f} kg"
             if worse.size else ""))
    mu, xu = np.array([o.mass_u for o in outcomes]), np.array([o.cg_x_u for o in outcomes])
    for quantity, error, u in (("mass", m - truth_m, mu), ("cg x", x - truth_x, xu)):
        inside = int(np.sum(np.abs(error) <= 1.96 * u))
        low, high = _binomial_interval(inside, len(outcomes))
        print(f"95 % interval covers the true {quantity} in {inside}/{len(outcomes)} runs, "
              f"{inside / len(outcomes) * 100:.1f} % (binomial 95 %: {low * 100:.1f}-{high * 100:.1f} %; goal 93-97 %); "
              f"RMS of (estimate − truth) / u {math.sqrt(np.mean((error / u) ** 2)):.2f} (1 where u is right)")
    print(f"median u(mass) {np.median(mu / truth_m) * 100:.2f} %, u(cg x) {np.median(xu) * 1e3:.1f} mm")
    print(f"false implement changes in runs without one: {sum(o.false_changes for o in outcomes)}")
    if changed:
        delay = np.array([o.detected_after for o in changed])
        within = np.isfinite(delay) & (delay <= CYCLE.period)
        after = np.array([(o.mass_after_change - o.mass) / o.mass * 100.0 for o in changed])
        print(f"mass changed ±30 % in transport ({len(changed)} runs): detected within one cycle in "
              f"{within.sum()}/{len(changed)} (median {np.nanmedian(delay):.1f} s after the change, the cycle "
              f"{CYCLE.period:.1f} s), false before it {sum(o.false_changes for o in changed)}; mass one cycle "
              f"after: RMS {math.sqrt(np.nanmean(after ** 2)):.2f} %, worst {np.nanmax(np.abs(after)):.2f} %")
    print(f"estimator cost: {np.median([o.step_us for o in outcomes]):.1f} µs CPU per step (median of runs)")


def _binomial_interval(inside: int, runs: int) -> tuple[float, float]:
    """The Clopper-Pearson 95 % interval of a coverage seen in ``inside`` of ``runs`` runs (-)."""
    low = float(beta.ppf(0.025, inside, runs - inside + 1)) if inside > 0 else 0.0
    high = float(beta.ppf(0.975, inside + 1, runs - inside)) if inside < runs else 1.0
    return low, high


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=400,
                        help="implements per preset (default 400: the coverage known to about ±2 %%)")
    parser.add_argument("--change-runs", type=int, default=40, help="runs with a mass change per preset (default 40)")
    parser.add_argument("--preset", action="append", default=[], help="only this preset (repeatable; default: both)")
    parser.add_argument("--mass", type=float, nargs=2, metavar=("LOW", "HIGH"),
                        help="implement masses drawn from LOW-HIGH kg (default: the preset's range)")
    parser.add_argument("--pressure-noise", type=float, default=DECLARED.noise,
                        help="the pressure transducer's noise per reading, Pa 1 σ (default %(default)g: declared)")
    parser.add_argument("--pressure-gain", type=float, default=DECLARED.gain,
                        help="its gain error, relative 1 σ (default %(default)g: declared)")
    parser.add_argument("--pressure-offset", type=float, default=DECLARED.offset,
                        help="its offset error, Pa 1 σ (default %(default)g: declared)")
    args = parser.parse_args()
    sensor = Transducer(args.pressure_noise, args.pressure_gain, args.pressure_offset)
    if sensor != DECLARED:
        print(f"pressure transducer: noise {sensor.noise:g} Pa, gain {sensor.gain:g}, offset {sensor.offset:g} Pa "
              f"(1 σ; declared {DECLARED.noise:g}, {DECLARED.gain:g}, {DECLARED.offset:g}); the estimator is told it")
    for name, (mech, preset_masses) in hitches().items():
        if args.preset and name.split()[0] not in args.preset:
            continue
        masses = tuple(args.mass) if args.mass else preset_masses
        model = WeighingModel(mech)
        outcomes = [_run(mech, model, masses, seed, None, sensor) for seed in range(args.runs)]
        changed = [_run(mech, model, masses, 1000 + seed, 0.3 if seed % 2 else -0.3, sensor)
                   for seed in range(args.change_runs)]
        _report(name, outcomes, changed)


if __name__ == "__main__":
    main()
