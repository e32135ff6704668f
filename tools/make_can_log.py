"""Generate the sample CAN log bags/can/belarus_1221_lift.log from the telemetry simulator.

The demo tractor (belarus_1221, two cycles of the simulator's `lift` scenario at 50 Hz, seed 0, the
simulator's default pressure noise) as its bus would carry them, written by python-can's candump
writer (`can.CanutilsLogWriter`):

- PGN 65093 rear hitch status (config/can/isobus_hitch.dbc) every 20 ms: the position from the
  true lift arm angle through this example tractor's position sensor, linear in the angle, 0 % /
  100 % at the angles of the work / transport positions widened by a quarter of their span on
  each side, quantized to 0.4 %; in-work 1 in the `work` phase, else 0; lower link force and draft
  'not available' (the simulator has no draft);
- the example maker frame ExampleLiftCylinderPressure every 20 ms, 0.5 ms after the hitch
  status: the cap-chamber gauge pressure in kPa (rounded), the rod chamber 'not available';
- PGN 65096 wheel-based speed and distance every 100 ms (1.5 m/s at the headland);
- SAE J1939 EEC1 (PGN 61444, engine speed) every 100 ms: a frame no DBC of the monitor knows
  (counted as unknown, not an error).

Beside it bags/can/belarus_1221_lift_truth/ (rosbag2, MCAP): the simulator's true lift arm angle
and cylinder length (sensor_msgs/JointState, rad, m) at the same stamps, from which
`linkage-monitor can-calibrate` fits the mapping's position tables.
Run: `.venv/bin/python tools/make_can_log.py [--out bags/can]`.
"""

from __future__ import annotations

import argparse
import shutil
import sys
from pathlib import Path

import can
import numpy as np
import yaml

from linkage_monitor.bag.writer import BagWriter
from linkage_monitor.can.input_msg import joint_state_cdr
from linkage_monitor.mechanics import load_description
from linkage_monitor.sim.telemetry import Noise, simulate
from linkage_monitor.wire.sensor_messages import JOINT_STATE

ROOT = Path(__file__).resolve().parent.parent
DBC = ROOT / "config" / "can" / "isobus_hitch.dbc"
START_NS = 1_767_225_600 * 1_000_000_000   # 2026-01-01T00:00:00Z
RATE_HZ = 50.0
CYCLES = 2
PRESSURE_DELAY_NS = 500_000   # the pressure frame 0.5 ms after the hitch status of the same sample
SPEED_M_S = 1.5
NOISE_PRESSURE = 0.05e6       # Pa, the simulator's default (linkage-monitor simulate)
SENSOR_WIDENING = 0.25        # the position sensor's range beyond work..transport, share of that span


def _message(db, name: str, stamp_ns: int, values: dict) -> can.Message:
    m = db.get_message_by_name(name)
    return can.Message(timestamp=stamp_ns / 1e9, arbitration_id=m.frame_id, is_extended_id=m.is_extended_frame,
                       data=m.encode(values, scaling=False, strict=False))


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=ROOT / "bags" / "can", help="directory of the sample files")
    args = parser.parse_args(argv)
    import cantools
    db = cantools.database.load_file(str(DBC))
    mech = load_description("belarus_1221")
    stream = simulate(mech, "lift", rate_hz=RATE_HZ, duration_s=CYCLES * 12.6, noise=Noise(pressure=NOISE_PRESSURE),
                      seed=0, start_ns=START_NS)
    angle = stream.truth.angles[:, stream.angle_names.index("lift_arm_angle")]
    length = stream.truth.cylinder_lengths[:, stream.cylinder_names.index("lift_cylinder")]
    work, transport = angle[stream.truth.phase == "work"].mean(), angle[stream.truth.phase == "transport"].mean()
    span = transport - work
    lowered, raised = work - SENSOR_WIDENING * span, transport + SENSOR_WIDENING * span
    position_raw = np.round(100.0 * (angle - lowered) / (raised - lowered) / 0.4).astype(int)
    cap_kpa = np.round(stream.pressure_values[:, stream.pressure_names.index("lift_cap_pressure")] / 1e3).astype(int)
    messages: list[can.Message] = []
    for i, stamp in enumerate(stream.stamps_ns.tolist()):
        in_work = 1 if stream.truth.phase[i] == "work" else 0
        messages.append(_message(db, "RearHitchStatus", stamp, {
            "RearHitchPosition": int(position_raw[i]), "RearHitchPositionLimitStatus": 0,
            "RearHitchInWorkIndication": in_work, "RearNominalLowerLinkForce": 0xFF, "RearDraft": 0xFFFF,
            "RearHitchExitReasonCode": 0x3F}))
        messages.append(_message(db, "ExampleLiftCylinderPressure", stamp + PRESSURE_DELAY_NS, {
            "LiftCylinderCapPressure": int(cap_kpa[i]), "LiftCylinderRodPressure": 0xFFFF}))
        if i % 5 == 0:
            t = (stamp - START_NS) / 1e9
            messages.append(_message(db, "WheelBasedSpeedAndDistance", stamp + 2 * PRESSURE_DELAY_NS, {
                "WheelBasedMachineSpeed": round(SPEED_M_S / 0.001), "WheelBasedMachineDistance": round(SPEED_M_S * t / 0.001),
                "MaximumTimeOfTractorPower": 0xFF, "MachineDirection": 1, "KeySwitchState": 1,
                "ImplementStartStopOperations": 3, "OperatorDirectionReversed": 0}))
            rpm = 1500 + int(100 * np.sin(t))
            messages.append(can.Message(timestamp=(stamp + 3 * PRESSURE_DELAY_NS) / 1e9, arbitration_id=0x0CF00400,
                                        is_extended_id=True,
                                        data=bytes([0xF0, 0x7D, 0x7D]) + (rpm * 8).to_bytes(2, "little")
                                        + bytes([0x00, 0xF0, 0x7D])))
    args.out.mkdir(parents=True, exist_ok=True)
    log = args.out / "belarus_1221_lift.log"
    with can.CanutilsLogWriter(str(log), channel="can0") as writer:
        for msg in messages:
            writer.on_message_received(msg)
    truth = args.out / "belarus_1221_lift_truth"
    shutil.rmtree(truth, ignore_errors=True)
    with BagWriter(truth) as bag:   # self-describing: the mechanism recorded as the node records it
        bag.record_mechanism(yaml.safe_dump(dict(mech.raw), sort_keys=False, allow_unicode=True),
                             int(stream.stamps_ns[0]))
        for i, stamp in enumerate(stream.stamps_ns.tolist()):
            bag.write("/joint_states", joint_state_cdr(stamp, ("lift_arm_angle", "lift_cylinder"),
                                                       (float(angle[i]), float(length[i]))),
                      stamp, type_name=JOINT_STATE, log_time_ns=stamp)
    print(f"{log}: {len(messages)} frames; {truth}: {len(stream.stamps_ns)} true poses")
    return 0


if __name__ == "__main__":
    sys.exit(main())
