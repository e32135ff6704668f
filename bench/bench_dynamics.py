"""Steerability on the road: the dynamic margin against the simulator's truth, the static one with and
without bumps (docs/dynamics.md).

belarus_1221 (the preset with a ``tractor`` block) carries ``--runs`` random implements (mass
uniform 200-2,500 kg, the cg up to ±0.3 m along x and ±0.2 m along z from the file's, known to the
monitor: the machine-level results use the implement's file or the weighing's estimate) through
ordinary work cycles (``sim.work_cycle``) at ``--rate`` Hz for 60 s, on a road at 3-8 m/s that
bounces the implement by up to ±0.3 g in transport; the IMU over the rear axle, at mid-wheelbase and
over the front axle in turn (the pitch acceleration, noisy, counts with the distance
from the IMU to the body whose inertia it gives), with the simulator's noise (0.05 m/s²,
0.005 rad/s), the pressure sensors with 0.02 MPa noise, the stroke 0.2 mm and the angle
0.5 mrad; no seal friction (the weighing's matter, bench_weighing.py). The monitor's side: the
solver's poses of the noisy inputs, the IMU's samples one by one (``mechanics.dynamics.ImuBody``: the
gyro differentiated over ``PITCH_WINDOW``, centred) and ``monitoring.road.RoadInput.balance`` as the node
and the replay compute it (the weight at rest averaged while the implement is carried, ``RestLoad``); each step's
dynamic values and static margin are those of the solve at its body's stamp and are compared with that
solve's truth.
The truth, from the simulator's true body motion and implement mass: the unit at rest (the solver at the true lengths with the implement's
weight), and d'Alembert's inertia forces added by the unit's moment balance about B (the oracle of
test/test_machine_dynamics.py, written out here again on purpose: the truth must not come from the
code under test).

Printed per IMU place: the RMS error of the dynamic margin against the truth over all solved steps
and over the transport, the worst run's, and the static margin's RMS error against the rest truth
with the bumps and its ratio to the error on the same runs without a road (goal: ≤ 1.5, the static
margin "unaffected by the bumps"); then that error without a road and with the bumps without the
IMU's correction (the pressures carry the implement's inertia); the
truth's dynamic dips (its lowest margin minus the static one). Goal: dynamic margin RMS error ≤ 0.01.

Run: ``.venv/bin/python bench/bench_dynamics.py [--runs 10] [--rate 400] [--accel-noise 0.05] [--gyro-noise 0.005]``
(the last two: the IMU's noise, to see what a better sensor buys).
"""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path
from typing import NamedTuple

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from linkage_monitor.mechanics import Mechanism, Solver, load_preset  # noqa: E402
from linkage_monitor.mechanics.dynamics import DYNAMIC_MARGIN, BodyAt, ImuBody  # noqa: E402
from linkage_monitor.mechanics.kernels import STEERABILITY_COLUMNS  # noqa: E402
from linkage_monitor.mechanics.machine import MachineModel  # noqa: E402
from linkage_monitor.monitoring.config import MonitorConfig  # noqa: E402
from linkage_monitor.monitoring.road import RoadInput  # noqa: E402
from linkage_monitor.sim.friction import SealFriction  # noqa: E402
from linkage_monitor.sim.road import ImuNoise, ImuReadings, Road  # noqa: E402
from linkage_monitor.sim.telemetry import Noise  # noqa: E402
from linkage_monitor.sim.work_cycle import ImplementTruth, WorkRun, simulate_work, with_implement  # noqa: E402

NOISE = Noise(angle=0.0005, length=0.0002, pressure=2e4)
DURATION = 60.0
MARGIN = STEERABILITY_COLUMNS.index("margin")


def _truth(mech: Mechanism, run: WorkRun) -> tuple[np.ndarray, np.ndarray]:
    """The true static margin at rest and dynamic margin (N,): the tractor's free body with the
    linkage's true forces (the true pressures: the implement's weight, its inertia, the ground's
    support) and the unit's balance about B with the inertia forces (test/test_machine_dynamics.py's
    oracle): the implement's true inertia m_6·a_6 taken out of the rest, the tractor's (J = m·a·b)
    and the ballast's added to the dynamic, from the simulator's true motion and mass."""
    truth, body = run.stream.truth, run.truth.body
    solved = Solver(mech).solve_batch(cylinders=dict(zip(run.stream.cylinder_names, truth.cylinder_lengths.T)),
                                      angles=dict(zip(run.stream.angle_names, truth.angles.T)),
                                      pressures=dict(zip(run.stream.pressure_names, truth.pressures.T)))
    steer = MachineModel(mech, Solver(mech)).evaluate_batch(solved).steerability   # the linkage's true forces
    t, g = mech.tractor, mech.gravity
    L, x_tr, r = t.wheelbase, float(t.cg[0]), t.ratio_min
    x6, inertia = solved.implement_cg[:, 0], run.truth.mass * run.truth.acceleration
    front = steer["front_axle_load"]
    total = steer["total_weight"] - inertia
    rest = front - inertia * x6 / L
    dynamic = front + (t.mass * body.at(x_tr) * x_tr + t.mass * x_tr * (L - x_tr) * body.pitch
                       + t.front_ballast.mass * body.at(t.front_ballast.x) * t.front_ballast.x) / L
    return rest / total - r, dynamic / total - r


class Margins(NamedTuple):
    """The monitor's static and dynamic margins (N,) and, per step, the index of the step its dynamic
    values are those of (−1: none)."""

    static: np.ndarray
    dynamic: np.ndarray
    described: np.ndarray


def _margins(mech: Mechanism, batch, stamps_ns: np.ndarray, imu: ImuReadings, imu_x: float) -> Margins:
    """The monitor's margins of the solved poses, each with the body's acceleration from the IMU samples
    up to its own (``mechanics.dynamics.ImuBody``, ``monitoring.road.RoadInput``, as the node and the
    replay compute them)."""
    road = RoadInput(mech, MonitorConfig(mech.name, imu_x=imu_x), load_measured=True)
    body = ImuBody(imu_x, gravity=mech.gravity)
    bodies: list[BodyAt | None] = []
    newest: BodyAt | None = None
    for stamp, f_z, rate in zip(imu.stamps_ns.tolist(), imu.linear_acceleration[:, 2].tolist(),
                                imu.angular_velocity[:, 1].tolist()):
        newest = body.add(stamp, f_z, rate) or newest
        bodies.append(newest)
    found = road.balance(stamps_ns, batch.frame_load_points, batch.frame_load_forces, batch.implement_load,
                         batch.implement_cg[:, 0], batch.cylinder_length, bodies)
    described = np.array([int(np.searchsorted(stamps_ns, b.stamp_ns)) if b is not None else -1 for b in bodies])
    return Margins(found.static[:, MARGIN], found.dynamic[:, DYNAMIC_MARGIN], described)


def _run(base: Mechanism, seed: int, rate: float, places: dict[str, float], imu_noise: ImuNoise) -> dict[str, float]:
    """One implement on one road: the errors (RMS over the run) with the IMU at each of ``places`` (m)."""
    rng = np.random.default_rng([seed, 4903])
    ref = np.asarray(base.implement.cg)
    implement = ImplementTruth(mass=float(rng.uniform(200.0, 2500.0)),
                               cg=(float(ref[0] + rng.uniform(-0.3, 0.3)), float(ref[1] + rng.uniform(-0.2, 0.2))))
    road = Road(speed=float(rng.uniform(3.0, 8.0)))
    mech = with_implement(base, implement)
    smooth = simulate_work(base, implement, DURATION, rate, friction=SealFriction(share=0.0), road=None, noise=NOISE,
                           seed=seed)
    batch = Solver(mech).solve_batch(**smooth.stream.solver_inputs())
    static_truth = _truth(mech, smooth)[0]
    static = MachineModel(mech, Solver(mech)).evaluate_batch(batch).steerability["margin"]
    out = {"static smooth": math.sqrt(np.nanmean((static - static_truth) ** 2))}
    for place, imu_x in places.items():
        run = simulate_work(base, implement, DURATION, rate, friction=SealFriction(share=0.0), road=road,
                            noise=NOISE, imu_noise=imu_noise, seed=seed, imu_x=imu_x)
        assert run.imu is not None
        batch = Solver(mech).solve_batch(**run.stream.solver_inputs())
        static_truth, dynamic_truth = _truth(mech, run)
        found = _margins(mech, batch, run.stream.stamps_ns, run.imu, imu_x)
        static = found.static
        plain = MachineModel(mech, Solver(mech)).evaluate_batch(batch).steerability["margin"]
        ok = np.isfinite(found.dynamic) & (found.described >= 0) & np.isfinite(static)   # a solve that failed: none
        dyn_err = np.full(static.size, np.nan)   # each value against the truth of the step it describes
        dyn_err[ok] = found.dynamic[ok] - dynamic_truth[found.described[ok]]
        transport = ok & (run.truth.phase == "transport")
        out[f"{place} dynamic"] = math.sqrt(np.mean(dyn_err[ok] ** 2))
        out[f"{place} dynamic transport"] = math.sqrt(np.mean(dyn_err[transport] ** 2))
        out[f"{place} static"] = math.sqrt(np.mean((static[ok] - static_truth[found.described[ok]]) ** 2))
        out["static bumps, no IMU"] = math.sqrt(np.mean((plain[ok] - static_truth[ok]) ** 2))
        out["dip"] = float(np.min(dynamic_truth - static_truth))
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=10)
    parser.add_argument("--rate", type=float, default=400.0, help="sensor and IMU rate, Hz (default 400, the node's)")
    parser.add_argument("--accel-noise", type=float, default=ImuNoise().acceleration,
                        help="the IMU accelerometer's noise, m/s² (default %(default)s, the simulator's)")
    parser.add_argument("--gyro-noise", type=float, default=ImuNoise().angular_velocity,
                        help="the IMU gyroscope's noise, rad/s (default %(default)s, the simulator's)")
    args = parser.parse_args()
    base = load_preset("belarus_1221")
    wheelbase = base.tractor.wheelbase
    places = {"rear axle": 0.0, "mid-wheelbase": 0.5 * wheelbase, "front axle": wheelbase}
    imu_noise = ImuNoise(acceleration=args.accel_noise, angular_velocity=args.gyro_noise)
    runs = [_run(base, seed, args.rate, places, imu_noise) for seed in range(args.runs)]

    def rms(key: str) -> float:
        return math.sqrt(np.mean([r[key] ** 2 for r in runs]))

    print(f"belarus_1221: {args.runs} runs of {DURATION:.0f} s at {args.rate:.0f} Hz, implement bounced ±0.3 g "
          f"in transport, IMU noise {imu_noise.acceleration:g} m/s², {imu_noise.angular_velocity:g} rad/s")
    print(f"{'IMU at':<24} {'dynamic margin RMS error':>25} {'in transport':>13} {'worst run':>10} "
          f"{'static margin RMS error':>24} {'/ without a road':>17}")
    for place, imu_x in places.items():
        print(f"{place + f' ({imu_x:.2f} m)':<24} {rms(place + ' dynamic'):25.4f} "
              f"{rms(place + ' dynamic transport'):13.4f} {max(r[place + ' dynamic'] for r in runs):10.4f} "
              f"{rms(place + ' static'):24.4f} {rms(place + ' static') / rms('static smooth'):17.2f}")
    print(f"goal: dynamic <= 0.01, static / without a road <= 1.5. Static margin's RMS error without a road {rms('static smooth'):.4f}; "
          f"with the bumps and without the IMU's correction {rms('static bumps, no IMU'):.4f}")
    print(f"the truth's dynamic dips below the static margin: median {np.median([r['dip'] for r in runs]):.4f}, "
          f"deepest {min(r['dip'] for r in runs):.4f}")


if __name__ == "__main__":
    main()
