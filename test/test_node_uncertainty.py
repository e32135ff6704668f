"""The live node with the error budget and the weighing on (`uncertainty:=true`,
`implement_mass_source:=estimate`), over real topics: a node process, a test client in this process.

The standard uncertainties (1 sigma) it publishes are the budget that ``mechanics.uncertainty``
computes here, offline, for the same inputs; the weighing fields of HitchState follow a simulated
work cycle (``sim.work_cycle``: lifts, lowers, transport, 4 % seal friction) whose true implement
the node does not see; what it records reads back with rosbags and with mcap-ros2-support as it was
published, and its Rerun recording holds the 95 % bands and the weighed mass and cg. With both off
(the default node) the fields are NaN and the weighing OFF.
"""

from __future__ import annotations

import math
import time

import numpy as np
import pytest
import rclpy

from linkage_monitor.mechanics import Inputs, Solver, load_preset
from linkage_monitor.mechanics.constants import ATMOSPHERIC_PRESSURE
from linkage_monitor.mechanics.error_sources import Motion
from linkage_monitor.mechanics.machine import MachineModel
from linkage_monitor.mechanics.uncertainty import UncertaintyModel
from linkage_monitor.monitoring.core import ASSEMBLY_LIMIT_M
from linkage_monitor.monitoring.motion import MOTION_WINDOW_S
from linkage_monitor.msg import HitchState
from linkage_monitor.sim.friction import SealFriction
from linkage_monitor.sim.telemetry import Noise
from linkage_monitor.sim.work_cycle import ImplementTruth, WorkCycle, simulate_work
from support.lift_pose import lift_pose
from support.ros_harness import node_bag, read_bag_rosbags, running_node, settle, stop
from support.rerun_tables import temporal_tables

MOTION_WINDOW_NS = int(MOTION_WINDOW_S * 1e9)
T0 = (time.time_ns() // 10**9) * 10**9  # ns, now (whole s): the node refuses stamps far from its clock
JOINTS = ["lift_cylinder", "lift_arm_angle"]
PRESSURE_TOPIC = "pressure/lift_cap_pressure"
BELARUS = load_preset("belarus_1221")
TRUE = ImplementTruth(mass=1200.0, cg=BELARUS.implement.cg)
# the node solves warm-started, the offline model cold: the same pose to ~1e-13, which the budget's
# central differences (steps down to 1e-6 m) magnify to ~1e-8 relative at most
REL = 1e-6


@pytest.fixture(scope="module")
def budget_node(ros, tmp_path_factory):
    """A belarus_1221 node with the error budget and the weighing on, recording a bag and a Rerun .rrd
    (every solved pose); (client, process, dir)."""
    tmp = tmp_path_factory.mktemp("budget_node")
    with running_node({"mechanism": "belarus_1221", "record_dir": str(tmp / "bags"), "sensor_qos": "reliable",
                       "staleness_limit": 3600.0, "stamp_tolerance": 3600.0, "uncertainty": True,
                       "implement_mass_source": "estimate", "rerun": "save", "rerun_path": str(tmp / "live.rrd"),
                       "rerun_rate": 1000.0}, tmp / "node.log") as (client, proc):
        yield client, proc, tmp


def _hitch_u(hitch) -> dict[str, float]:
    return {"implement_load": hitch.implement_load_u, "lift_capacity.hitch_axis": hitch.lift_capacity_hitch_axis_u,
            "lift_capacity.behind_610mm": hitch.lift_capacity_610mm_u,
            "lift_capacity.implement_cg": hitch.lift_capacity_implement_cg_u, "lift_reserve": hitch.lift_reserve_u}


def test_published_standard_uncertainties_are_the_budget_of_the_same_inputs(budget_node):
    """Each pose: the joint state, then its pressure (the pressure's solve: the cylinder standing over the
    motion window, ``monitoring.motion.MOTION_WINDOW_S``, the poses further apart: the friction's whole band). Every ``*_u`` field equals ``UncertaintyModel.budget``
    of the same inputs, and the diagnostic of the first solved pose names each judged value's
    standard uncertainty and dominant source."""
    client, _, _ = budget_node
    model = MachineModel(BELARUS, Solver(BELARUS, consistency_tol=ASSEMBLY_LIMIT_M))
    uncertainty = UncertaintyModel(model)
    cases = []
    for k, (stroke, gauge) in enumerate([(0.54, 9.9e6), (0.60, 8.7e6), (0.66, 9.4e6)]):
        s, angle = lift_pose(stroke)
        stamp = T0 + k * 2 * MOTION_WINDOW_NS
        client.publish_joint_state(stamp, JOINTS, [s, angle])
        client.spin_until(lambda: False, 0.3)   # two DDS writers keep no order between them
        client.publish_pressure(PRESSURE_TOPIC, stamp + 1000, gauge + ATMOSPHERIC_PRESSURE)
        cases.append((stamp + 1000, Inputs(cylinders={"lift_cylinder": s}, angles={"lift_arm_angle": angle},
                                           pressures={"lift_cap_pressure": gauge})))
    assert client.spin_until(lambda: all(client.outputs_at("steerability", c[0]) for c in cases), 30)
    for stamp, inputs in cases:
        result, machine, _ = model.solve(inputs)
        budget = uncertainty.budget(inputs, result, machine, Motion.STANDING)
        hinges = client.outputs_at("hinge_reactions", stamp)[0]
        for h in hinges.hinges:
            for part in ("fx", "fz", "magnitude"):
                assert getattr(h, f"{part}_u") == pytest.approx(budget.u_of(f"{h.name}.{part}"), rel=REL), (h.name, part)
        hitch = client.outputs_at("hitch_state", stamp)[0]
        assert hitch.cylinders[0].force_u == pytest.approx(budget.u_of("lift_cylinder.force"), rel=REL)
        for name, value in _hitch_u(hitch).items():
            assert value == pytest.approx(budget.u_of(name), rel=REL), name
            assert value > 0.0, name
        steer = client.outputs_at("steerability", stamp)[0]
        for field, name in (("front_axle_load_u", "front_axle_load"), ("rear_axle_load_u", "rear_axle_load"),
                            ("ratio_u", "steerability_ratio"), ("margin_u", "steerability_margin")):
            assert getattr(steer, field) == pytest.approx(budget.u_of(name), rel=REL), field
        assert hitch.weighing_phase != HitchState.WEIGHING_OFF   # the estimator's smoothed rod speed names it
        assert math.isnan(hitch.implement_mass_estimate) and hitch.implement_mass_in_use == HitchState.MASS_FROM_FILE
    first = cases[0][0]
    assert client.spin_until(lambda: client.diagnostics_at(first), 10)
    values = {kv.key: kv.value for kv in client.diagnostics_at(first)[0].values}
    result, machine, _ = model.solve(cases[0][1])
    line = uncertainty.budget(cases[0][1], result, machine, Motion.STANDING).line("steerability_margin")
    assert float(values["steerability margin standard uncertainty [-]"]) == pytest.approx(line.u, rel=1e-5)
    assert values["steerability margin uncertainty"].startswith(f"dominant source {line.dominant} (")
    phase = client.outputs_at("hitch_state", first)[0].weighing_phase
    assert getattr(HitchState, "WEIGHING_" + values["weighing phase"].upper()) == phase
    assert values["implement mass in use"] == "file" and values["implement mass estimate"].startswith("none yet")


def test_the_weighing_of_a_work_cycle_is_published_and_recorded(budget_node):
    """Two work cycles of belarus_1221 carrying a 1,200 kg implement the node does not see: HitchState
    names the phases lifting and lowering, then carries an estimate whose 95 % interval holds the true
    mass (its standard uncertainty > 0) and the estimate in use; the recorded HitchState messages,
    read back by rosbags and by mcap-ros2-support, are those published."""
    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory

    client, proc, tmp = budget_node
    cycle = WorkCycle(work_s=2.0, transport_s=4.0)
    run = simulate_work(BELARUS, TRUE, duration_s=2 * cycle.period, rate_hz=20.0, cycle=cycle,
                        friction=SealFriction(share=0.04), road=None,
                        noise=Noise(angle=0.0005, length=0.0002, pressure=2e4), seed=3)
    stream = run.stream
    start = T0 + 10_000_000_000
    stamps = (stream.stamps_ns + start).tolist()
    for i, stamp in enumerate(stamps):
        client.publish_joint_state(stamp, list(stream.joint_names), stream.joint_positions[i].tolist())
        client.publish_pressure(PRESSURE_TOPIC, stamp + 1000, float(stream.pressure_values[i, 0]) + ATMOSPHERIC_PRESSURE)
        for _ in range(3):
            rclpy.spin_once(client.node, timeout_sec=0.0)
        time.sleep(0.002)
    settle(client, "hitch_state", quiet=1.0, timeout=60)
    published = [m for m in client.received["hitch_state"] if m.header.stamp.sec * 10**9 + m.header.stamp.nanosec
                 >= start]
    assert len(published) > 0.9 * 2 * len(stamps)
    phases = {m.weighing_phase for m in published}
    assert {HitchState.WEIGHING_LIFTING, HitchState.WEIGHING_LOWERING, HitchState.WEIGHING_STANDING} <= phases, phases
    last = published[-1]
    assert last.implement_mass_estimate_u > 0.0
    assert abs(last.implement_mass_estimate - TRUE.mass) <= 1.96 * last.implement_mass_estimate_u + 0.04 * TRUE.mass
    assert any(m.implement_mass_in_use == HitchState.MASS_FROM_ESTIMATE for m in published)
    assert all(math.isnan(m.implement_mass_estimate) for m in published if m.weighing_phase == HitchState.WEIGHING_OFF)

    code = stop(proc)
    assert code == 0, (tmp / "node.log").read_text()
    bag = node_bag(tmp / "bags")
    by_stamp = {(m.header.stamp.sec, m.header.stamp.nanosec): m for m in client.received["hitch_state"]}
    fields = ("implement_mass_estimate", "implement_mass_estimate_u", "implement_cg_x_estimate",
              "implement_cg_x_estimate_u", "implement_cg_z_estimate", "implement_cg_z_estimate_u", "weighing_phase",
              "weighing_confident", "implement_mass_in_use", "implement_load_u", "lift_reserve_u")
    recorded = [m for topic, _, m in read_bag_rosbags(bag) if topic == "/hitch_state"]
    assert len(recorded) == len(client.received["hitch_state"])
    for m in recorded:
        sent = by_stamp[(m.header.stamp.sec, m.header.stamp.nanosec)]
        assert np.array_equal([float(getattr(m, f)) for f in fields], [float(getattr(sent, f)) for f in fields],
                              equal_nan=True)
        assert np.array_equal([m.cylinders[0].force_u], [sent.cylinders[0].force_u], equal_nan=True)
    # the node's Rerun recording: the bands, the weighed mass and its cg drawn (viz.rerun_estimates)
    tables = temporal_tables(tmp / "live.rrd")
    for entity in ("forces/cylinders/lift_cylinder/low95", "steerability/ratio/high95", "lift/reserve/low95",
                   "weighing/mass", "weighing/mass/high95", "linkage/implement_cg", "linkage/implement_cg/interval"):
        assert entity in tables, entity
    masses = [v[0] for rb in tables["weighing/mass"] for v in rb.column("Scalars:scalars").to_pylist()]
    assert last.implement_mass_estimate in masses
    with open(next(bag.glob("*.mcap")), "rb") as file:
        decoded = [msg for _, channel, _, msg in make_reader(file, decoder_factories=[DecoderFactory()])
                   .iter_decoded_messages() if channel.topic == "/hitch_state"]
    assert [(m.implement_mass_estimate, m.weighing_phase) for m in decoded[-5:]] == [
        (m.implement_mass_estimate, m.weighing_phase) for m in recorded[-5:]]


def test_without_the_budget_and_the_weighing_the_fields_are_nan(node):
    """The default node: every standard uncertainty and the weighing estimate NaN, the phase OFF,
    the mass in use the file's."""
    client, _, _ = node
    s, angle = lift_pose(0.60)
    client.publish_pressure(PRESSURE_TOPIC, T0, 9.0e6 + ATMOSPHERIC_PRESSURE)
    client.spin_until(lambda: False, 0.3)
    client.publish_joint_state(T0 + 1000, JOINTS, [s, angle])
    assert client.spin_until(lambda: client.outputs_at("steerability", T0 + 1000), 20)
    hinges = client.outputs_at("hinge_reactions", T0 + 1000)[0]
    hitch = client.outputs_at("hitch_state", T0 + 1000)[0]
    steer = client.outputs_at("steerability", T0 + 1000)[0]
    values = ([getattr(h, f) for h in hinges.hinges for f in ("fx_u", "fz_u", "magnitude_u")]
              + [hitch.cylinders[0].force_u, *_hitch_u(hitch).values(), hitch.implement_mass_estimate,
                 hitch.implement_mass_estimate_u, hitch.implement_cg_x_estimate, hitch.implement_cg_z_estimate]
              + [steer.front_axle_load_u, steer.rear_axle_load_u, steer.ratio_u, steer.margin_u])
    assert values and all(math.isnan(v) for v in values)
    assert math.isfinite(hitch.implement_load)
    assert (hitch.weighing_phase, hitch.weighing_confident, hitch.implement_mass_in_use) == (
        HitchState.WEIGHING_OFF, False, HitchState.MASS_FROM_FILE)
