"""The live node with an IMU on the tractor body over real topics, its bag replayed.

A node process (belarus_1221 without pressures: the implement's load is its file's weight) takes
sensor_msgs/Imu on ``imu`` and JointState; a body heaving without pitch (every point up with the
same a, the gyro still) is the unit at rest under gravity g + a (d'Alembert), so the dynamic
axle loads are the static ones times (g + a)/g. Expected values: the offline solver on the same
pose (linkage_monitor.mechanics), never the node's own path. The replay of the node's bag gives
the same Steerability bytes.
"""

from __future__ import annotations

import time

import numpy as np
import pytest

from linkage_monitor.mechanics import Inputs, Solver, load_preset
from linkage_monitor.mechanics.capacity import stroke_mechanism
from linkage_monitor.mechanics.constants import STANDARD_GRAVITY
from linkage_monitor.mechanics.machine import MachineModel
from linkage_monitor.mechanics.results import angle_readings
from support.ros_harness import MonitorClient, node_bag, start_node, stop

pytestmark = pytest.mark.ros
T0 = (time.time_ns() // 10**9) * 10**9   # ns, now (whole s): the node refuses stamps far from its clock
JOINTS = ["lift_cylinder", "lift_arm_angle"]
HEAVE = -3.0   # m/s², the body dropping


def test_the_node_publishes_the_dynamic_steerability_and_the_replay_gives_the_same(ros, tmp_path):
    from rclpy.qos import QoSProfile, ReliabilityPolicy
    from rosbags.highlevel import AnyReader
    from rosbags.typesys import Stores, get_typestore
    from sensor_msgs.msg import Imu

    from linkage_monitor.offline.replay import replay
    from linkage_monitor.ros.messages import header

    proc = start_node({"mechanism": "belarus_1221", "record_dir": str(tmp_path / "bags"), "sensor_qos": "reliable",
                       "stamp_tolerance": 3600.0, "pressure_topics": ["none"], "imu_topic": "imu"},
                      tmp_path / "node.log")
    client = MonitorClient(pressure_topics=())
    imu_pub = client.node.create_publisher(Imu, "imu", QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE))
    mech = load_preset("belarus_1221")
    batch = Solver(stroke_mechanism(mech)).solve_batch(cylinders={"lift_cylinder": np.array([0.62])})
    s, angle = 0.62, float(angle_readings(mech, batch)["lift_arm_angle"][0])
    try:
        client.wait_for_node()
        assert client.spin_until(lambda: imu_pub.get_subscription_count() > 0, 10)
        client.publish_joint_state(T0, JOINTS, [s, angle])   # before any IMU message: dynamic NaN
        assert client.spin_until(lambda: client.outputs_at("steerability", T0), 20)
        for k in range(30):   # 72.5 ms: the gyro's samples span the pitch's differentiation window
            msg = Imu(header=header(T0 + 1_000_000 + k * 2_500_000))
            msg.header.frame_id = "imu_link"
            msg.linear_acceleration.z = STANDARD_GRAVITY + HEAVE
            imu_pub.publish(msg)
        client.spin_until(lambda: False, 0.5)
        client.publish_joint_state(T0 + 100_000_000, JOINTS, [s, angle])
        assert client.spin_until(lambda: client.outputs_at("steerability", T0 + 100_000_000), 20)
    finally:
        client.close()
        assert stop(proc) == 0
    rest = MachineModel(mech, Solver(mech)).evaluate(
        Solver(mech).solve(Inputs(cylinders={"lift_cylinder": s}, angles={"lift_arm_angle": angle}))).steerability
    before, after = (client.outputs_at("steerability", T0 + d)[0] for d in (0, 100_000_000))
    assert np.isnan([before.dynamic_front_axle_load, before.dynamic_margin]).all()
    for msg in (before, after):
        assert msg.front_axle_load == pytest.approx(rest["front_axle_load"], rel=1e-9)
        assert msg.margin == pytest.approx(rest["margin"], rel=1e-9, abs=1e-12)
    scale = (STANDARD_GRAVITY + HEAVE) / STANDARD_GRAVITY
    assert after.dynamic_front_axle_load == pytest.approx(rest["front_axle_load"] * scale, rel=1e-9)
    assert after.dynamic_rear_axle_load == pytest.approx(rest["rear_axle_load"] * scale, rel=1e-9)
    assert after.dynamic_ratio == pytest.approx(rest["front_axle_load"] * scale / rest["total_weight"], rel=1e-9)
    assert after.dynamic_margin == pytest.approx(after.dynamic_ratio - rest["ratio_min"], rel=1e-9)

    bag = node_bag(tmp_path / "bags")
    replayed = replay(bag, out_dir=tmp_path / "replayed", progress=None)
    assert replayed.summary.solved == 2

    def steerability(path) -> list[bytes]:
        with AnyReader([path], default_typestore=get_typestore(Stores.EMPTY)) as reader:
            imu = [raw for c, _, raw in reader.messages() if c.topic == "/imu"]
            assert len(imu) == 30   # recorded as they came, copied on by the replay
            return [raw for c, _, raw in reader.messages() if c.topic == "/steerability"]
    assert steerability(tmp_path / "replayed") == steerability(bag)
