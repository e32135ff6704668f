"""The live node's own .rrd (rerun=save), opened in the real viewer: the side view draws the
linkage, as the replay's file does (the side view is not empty).

The stream is what a tractor sends: a pressure and a JointState with the same header stamp
(two solves per stamp), stamps arriving slightly out of order, at 50 Hz for 4 s."""

from __future__ import annotations

import time

import pytest

from linkage_monitor.mechanics.constants import ATMOSPHERIC_PRESSURE
from linkage_monitor.viz.drawing import BODY_COLORS, CYLINDER_COLOR
from support.rerun_shot import pixels_of, screenshot
from support.ros_harness import MonitorClient, settle, start_node, stop

JOINTS = ["lift_cylinder", "lift_arm_angle"]
PRESSURE_TOPIC = "pressure/lift_cap_pressure"


@pytest.mark.timeout(300)
def test_live_rrd_draws_the_linkage(ros, tmp_path):
    from support.lift_pose import lift_pose   # consistent (stroke, angle) pairs from the offline kinematics

    rrd = tmp_path / "live.rrd"
    proc = start_node({"mechanism": "belarus_1221", "record": False, "rerun": "save", "rerun_path": str(rrd),
                       "sensor_qos": "reliable", "stamp_tolerance": 3600.0}, tmp_path / "node.log")
    client = MonitorClient()
    try:
        client.wait_for_node()
        t0 = time.time_ns()
        poses = [lift_pose(0.54 + 0.16 * k / 199) for k in range(200)]
        for k, (stroke, angle) in enumerate(poses):
            stamp = t0 + k * 20_000_000 - (7_000_000 if k % 5 == 3 else 0)   # every 5th a little late
            client.publish_pressure(PRESSURE_TOPIC, stamp, 9e6 + ATMOSPHERIC_PRESSURE)
            client.publish_joint_state(stamp, JOINTS, [stroke, angle])
            client.spin_until(lambda: False, 0.02)
        assert client.spin_until(lambda: len(client.received["hinge_reactions"]) >= 150, 30)
        settle(client, "hinge_reactions", quiet=0.5)
    finally:
        client.close()
        assert stop(proc) == 0, (tmp_path / "node.log").read_text()
    rgb = screenshot(rrd, tmp_path / "viewer")
    assert pixels_of(rgb, CYLINDER_COLOR) > 500            # the lift cylinder in the side view
    assert sum(pixels_of(rgb, c) > 200 for c in BODY_COLORS[:6]) >= 3   # and the links' colours
