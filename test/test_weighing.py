"""The weighing estimator on simulated work whose truth it does not see (monitoring.weighing).

Oracle: the simulator (``sim.work_cycle``), which solves the statics with the true implement's
mass and cg in the mechanism (``sim.plant.Plant``), not with the estimator's force model.
Without friction and noise the model is exact (virtual work: the force is linear in the weight
and the cg's offset), so the estimate is the truth up to the force table's interpolation.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from linkage_monitor.mechanics import Solver, load_preset
from linkage_monitor.mechanics.constants import STANDARD_GRAVITY
from linkage_monitor.monitoring.weighing import WeighingEstimator, WeighingPhase, WeighingSettings
from linkage_monitor.monitoring.weighing_fit import Priors
from linkage_monitor.monitoring.weighing_model import WeighingModel
from linkage_monitor.sim.friction import SealFriction
from linkage_monitor.sim.road import ImuNoise, Road
from linkage_monitor.sim.telemetry import Noise
from linkage_monitor.sim.work_cycle import ImplementTruth, LoadChange, WorkCycle, WorkRun, simulate_work

ROOT = Path(__file__).resolve().parent.parent
BELARUS = load_preset("belarus_1221")
REF = np.asarray(BELARUS.implement.cg)
TRUE = ImplementTruth(mass=1200.0, cg=(float(REF[0] + 0.2), float(REF[1] - 0.1)))
CYCLE = WorkCycle(work_s=2.0, transport_s=4.0)   # 13.6 s: three cycles in 41 s
NOISE = Noise(angle=0.0005, length=0.0002, pressure=2e4)


@pytest.fixture(scope="module")
def model() -> WeighingModel:
    return WeighingModel(BELARUS)


def _estimator(model: WeighingModel, run: WorkRun, settings: WeighingSettings = WeighingSettings(),
               imu: bool = False) -> tuple[WeighingEstimator, list[WeighingPhase]]:
    """The estimator over the monitor's solved poses of the run's (noisy) inputs."""
    batch = Solver(BELARUS).solve_batch(**run.stream.solver_inputs())
    assert np.all(batch.status == 0)
    estimator = WeighingEstimator(BELARUS, settings, model=model)
    accel = run.imu.linear_acceleration[:, 2] - STANDARD_GRAVITY if imu and run.imu is not None else None
    phases = estimator.run(run.stream.stamps_ns, batch.cylinder_length[model.cylinder],
                           batch.cylinder_force[model.cylinder], accel)
    return estimator, phases


def test_exact_without_friction_and_noise(model: WeighingModel) -> None:
    run = simulate_work(BELARUS, TRUE, duration_s=41.0, cycle=CYCLE, friction=SealFriction(share=0.0), road=None)
    wide = WeighingSettings(priors=Priors(x=1e3, z=1e3))   # no pull toward the file's cg
    estimator, _ = _estimator(model, run, wide)
    est = estimator.estimate
    assert est is not None and est.cg_x_identified and est.cg_z_identified
    # the force table's linear interpolation (1.3 mm steps) is the only approximation
    assert est.mass == pytest.approx(TRUE.mass, rel=2e-4)
    assert est.cg_x == pytest.approx(TRUE.cg[0], abs=1e-3)
    assert est.cg_z == pytest.approx(TRUE.cg[1], abs=1e-3)
    assert est.friction_share == pytest.approx(0.0, abs=1e-3)   # a bin's lifting and lowering steps lie apart


def test_friction_and_noise_within_the_interval(model: WeighingModel) -> None:
    run = simulate_work(BELARUS, TRUE, duration_s=41.0, cycle=CYCLE, friction=SealFriction(share=0.06),
                        road=None, noise=NOISE, seed=4)
    est = _estimator(model, run)[0].estimate
    assert est is not None
    low, high = est.interval(est.mass, est.mass_u)
    assert low <= TRUE.mass <= high
    low, high = est.interval(est.cg_x, est.cg_x_u)
    assert low <= TRUE.cg[0] <= high
    assert 0.0 < est.mass_u < 0.02 * TRUE.mass


def test_pairs_cancel_the_seal_friction(model: WeighingModel) -> None:
    """With 8 % friction (4-12 % of the load per stroke) the paired estimate moves by less than 0.2 %,
    and the friction it finds is the simulated Coulomb share (plus a little breakaway near the ends)."""
    masses = {}
    for share in (0.0, 0.08):
        run = simulate_work(BELARUS, TRUE, duration_s=41.0, cycle=CYCLE, friction=SealFriction(share=share),
                            road=None)
        est = _estimator(model, run)[0].estimate
        assert est is not None
        masses[share] = est.mass
        assert est.friction_share == pytest.approx(share, abs=0.005)
    assert masses[0.08] == pytest.approx(masses[0.0], rel=0.002)


def test_a_mass_change_is_detected_and_reestimated(model: WeighingModel) -> None:
    change_at = CYCLE.period + CYCLE.work_s + CYCLE.raise_s + 2.0   # standing in the second transport
    run = simulate_work(BELARUS, TRUE, duration_s=3 * CYCLE.period, cycle=CYCLE, friction=SealFriction(share=0.05),
                        road=None, noise=NOISE, change=LoadChange(change_at, 1.3), seed=2)
    estimator, _ = _estimator(model, run)
    assert len(estimator.changes) == 1
    found = estimator.changes[0]
    assert change_at < found.stamp_ns * 1e-9 < change_at + CYCLE.period   # the next lower, within one cycle
    assert found.relative_change == pytest.approx(0.3, abs=0.05)
    est = estimator.estimate
    assert est is not None
    assert est.mass == pytest.approx(1.3 * TRUE.mass, rel=0.02)


def test_phases_are_named(model: WeighingModel) -> None:
    run = simulate_work(BELARUS, TRUE, duration_s=CYCLE.period, cycle=CYCLE, road=None, noise=NOISE)
    _, phases = _estimator(model, run)
    by_truth = {name: [p for p, t in zip(phases, run.truth.phase) if t == name] for name in set(run.truth.phase)}
    assert set(by_truth["work"]) == {WeighingPhase.GROUND_CONTACT}
    assert set(by_truth["transport"]) == {WeighingPhase.STANDING}
    assert by_truth["raise"].count(WeighingPhase.LIFTING) > 0.6 * len(by_truth["raise"])
    assert by_truth["lower"].count(WeighingPhase.LOWERING) > 0.6 * len(by_truth["lower"])
    assert not {WeighingPhase.LOWERING} & set(by_truth["raise"])


def test_bouncing_is_rejected_with_and_without_an_imu(model: WeighingModel) -> None:
    """Lifting and lowering while the body bounces by up to ±0.3 g: the IMU's acceleration and, without
    it, the pressure's own variation name steps BOUNCING, and they are left out."""
    bumpy = WorkCycle(work_s=2.0, transport_s=4.0, headland_bounce=1.0)
    run = simulate_work(BELARUS, TRUE, duration_s=bumpy.period, cycle=bumpy, road=Road(speed=6.0), noise=NOISE,
                        imu_noise=ImuNoise())
    for imu in (True, False):
        _, phases = _estimator(model, run, imu=imu)
        moving = [p for p, t in zip(phases, run.truth.phase) if t in ("raise", "lower")]
        assert moving.count(WeighingPhase.BOUNCING) > 0.2 * len(moving)


def test_imu_reads_rest_gravity_in_rep103(model: WeighingModel) -> None:
    """On a road scaled to no bumps the IMU reads +g on z (REP 145: the specific force), nothing on x, y."""
    run = simulate_work(BELARUS, TRUE, duration_s=2.0, cycle=CYCLE, road=Road(peak_g=0.0),
                        imu_noise=ImuNoise(0.0, 0.0))
    assert run.imu is not None
    np.testing.assert_allclose(run.imu.linear_acceleration, [[0.0, 0.0, STANDARD_GRAVITY]] * len(run.stream),
                               atol=1e-12)
    message = run.imu.message(0)
    assert message.orientation_covariance[0] == -1.0   # sensor_msgs/Imu: no orientation given
    assert message.linear_acceleration.z == pytest.approx(STANDARD_GRAVITY)


def test_seal_friction_opposes_motion_with_breakaway() -> None:
    friction = SealFriction(share=0.05, breakaway=1.5, stribeck_speed=0.005)
    speed = np.array([0.0, 1e-6, 0.1, 0.0, 0.0, -0.1, 0.0])
    force = np.full(speed.shape, 1000.0)
    f = friction.force(speed, force)
    assert f[0] == 0.0                                   # before any motion
    assert f[1] == pytest.approx(75.0, rel=1e-3)         # starting from rest: breakaway 1.5 × 50 N
    assert f[2] == pytest.approx(50.0, rel=1e-6)         # sliding: Coulomb, against the extension
    assert f[3] == f[4] == f[2]                          # standing: what the last motion left
    assert f[5] == pytest.approx(-50.0, rel=1e-6) and f[6] == f[5]


def test_weigh_command_on_the_bundled_bag(capsys: pytest.CaptureFixture[str]) -> None:
    """`linkage-monitor weigh` on the bundled belarus_1221 lift bag (simulated with the file's
    implement, 1,529.57 kg at S6, no friction): the file's mass within its 95 % interval, the cg x
    within its 99 % one (±2.58 u): one bag is one draw, which a 95 % interval misses once in 20
    (its cg x is 2.0 u off; the intervals' coverage is measured over 400 runs by bench_weighing)."""
    import json

    from linkage_monitor.cli.main import main

    assert main(["weigh", str(ROOT / "bags" / "belarus_1221_lift_transport"), "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    est = out["estimate"]
    low, high = est["mass_95_kg"]
    assert low <= BELARUS.implement.mass <= high
    assert abs(est["cg_x_m"] - REF[0]) <= 2.58 * est["cg_x_u_m"]
    assert out["phase_steps"]["lifting"] > 0 and out["phase_steps"]["lowering"] > 0
    assert out["implement_changes"] == []
