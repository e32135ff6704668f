"""DBC decoding of hand-built ISO 11783-7 frames against the standard's scaling worked out by hand,
the decoder's refusals (J1939 'error' / 'not available', DLC, DBC range, table range, error
frames, bus-off) and its frame accounting, the mapping's validation, the position table's fit."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import cantools
import numpy as np
import pytest
import yaml

from linkage_monitor.can.decoder import CanDecoder, load_databases
from linkage_monitor.can.frames import Frame
from linkage_monitor.can.j1939 import Raw, classify, pgn
from linkage_monitor.can.mapping import load_mapping, mapping_from_text
from linkage_monitor.can.outcomes import Outcome
from linkage_monitor.can.position_table import fit_table
from linkage_monitor.mechanics import InputError, load_description
from linkage_monitor.mechanics.error_sources import ErrorSources, SensorError
from linkage_monitor.mechanics.overrides import with_sensor_resolutions
from linkage_monitor.mechanics.schema import mechanism_from_dict
from linkage_monitor.bag.step_recorder import mechanism_yaml
from linkage_monitor.monitoring.config import MonitorConfig
from linkage_monitor.monitoring.events import JointStateEvent, PressureEvent
from linkage_monitor.monitoring.findings import Code

ROOT = Path(__file__).resolve().parent.parent
DBC = ROOT / "config" / "can" / "isobus_hitch.dbc"
MAP = ROOT / "config" / "can" / "belarus_1221.yaml"
STAMP = 1_767_225_600_000_000_000
REAR_HITCH, WHEEL_SPEED, PRESSURE_ID = 0x0CFE45F0, 0x0CFE48F0, 0x18FF2021


@pytest.fixture(scope="module")
def db() -> cantools.database.Database:
    return cantools.database.load_file(str(DBC))


def test_rear_hitch_status_scaling_by_hand(db) -> None:
    # byte 1: 0xAF = 175 -> 175 * 0.4 % = 70 %; byte 2: 0x98 = 0b10011000 -> in-work = bits 7-8 = 0b10 = 2
    # (error), position limit = bits 4-6 = 0b011 = 3; byte 3: 0xC8 = 200 -> 200 * 0.8 - 100 = 60 %;
    # bytes 4-5 little endian 0x8010 = 32784 -> 32784 * 10 - 320000 = 7840 N; byte 6: 0x3F -> 63
    data = bytes([0xAF, 0x98, 0xC8, 0x10, 0x80, 0x3F, 0xFF, 0xFF])
    values = db.get_message_by_frame_id(REAR_HITCH).decode(data, decode_choices=False)
    assert values["RearHitchPosition"] == pytest.approx(70.0, abs=1e-12)
    assert values["RearHitchInWorkIndication"] == 2
    assert values["RearHitchPositionLimitStatus"] == 3
    assert values["RearNominalLowerLinkForce"] == pytest.approx(60.0, abs=1e-12)
    assert values["RearDraft"] == pytest.approx(7840.0, abs=1e-9)
    assert values["RearHitchExitReasonCode"] == 63
    assert pgn(REAR_HITCH) == 65093 and pgn(0x0CFE46F0) == 65094


def test_wheel_speed_and_aux_valve_scaling_by_hand(db) -> None:
    # speed 0x05DC = 1500 * 0.001 = 1.5 m/s; distance 0x00002710 = 10000 * 0.001 = 10 m;
    # byte 8 0x45 = 0b01_00_01_01: direction 1, key switch 1, start/stop 0, operator reversed 1
    speed = db.get_message_by_frame_id(WHEEL_SPEED).decode(bytes([0xDC, 0x05, 0x10, 0x27, 0, 0, 0xFF, 0x45]),
                                                           decode_choices=False)
    assert speed["WheelBasedMachineSpeed"] == pytest.approx(1.5, abs=1e-12)
    assert speed["WheelBasedMachineDistance"] == pytest.approx(10.0, abs=1e-9)
    assert (speed["MachineDirection"], speed["KeySwitchState"], speed["ImplementStartStopOperations"],
            speed["OperatorDirectionReversed"]) == (1, 1, 0, 1)
    # valve 3 measured flow: PGN 65056 + 3 = 65059 = 0xFE23. Extend flow 135 - 125 = +10 %, retract 125 - 125
    # = 0 %; extend port 0x0FA0 = 4000 * 5 kPa = 20000 kPa; retract 0x0064 = 100 * 5 = 500 kPa; return
    # 10 * 16 = 160 kPa; byte 8 0x20 >> 5 = limit status 1
    aux = db.get_message_by_frame_id(0x0CFE23F0)
    assert aux.name == "AuxValve3MeasuredFlow" and pgn(aux.frame_id) == 65059
    v = aux.decode(bytes([135, 125, 0xA0, 0x0F, 0x64, 0x00, 10, 0x20]), decode_choices=False)
    assert (v["AuxValve3ExtendPortMeasuredFlow"], v["AuxValve3RetractPortMeasuredFlow"]) == (10, 0)
    assert v["AuxValve3ExtendPortPressure"] == 20000 and v["AuxValve3RetractPortPressure"] == 500
    assert v["AuxValve3ReturnPortPressure"] == 160 and v["AuxValve3LimitStatus"] == 1


def test_j1939_ranges() -> None:
    assert [classify(v, 8) for v in (0xFA, 0xFB, 0xFE, 0xFF)] == [Raw.VALUE, Raw.VALUE, Raw.ERROR, Raw.NOT_AVAILABLE]
    assert [classify(v, 16) for v in (0xFAFF, 0xFE00, 0xFEFF, 0xFF00, 0xFFFF)] == [
        Raw.VALUE, Raw.ERROR, Raw.ERROR, Raw.NOT_AVAILABLE, Raw.NOT_AVAILABLE]
    assert [classify(v, 2) for v in (0, 1, 2, 3)] == [Raw.VALUE, Raw.VALUE, Raw.ERROR, Raw.NOT_AVAILABLE]
    assert pgn(0x18EA00F9) == 0xEA00   # PDU1: the destination byte is not part of the PGN


@pytest.fixture
def decoder() -> CanDecoder:
    mapping = load_mapping(MAP)
    mech = load_description("belarus_1221")
    return CanDecoder(load_databases(mapping.dbc), mapping, mech, MonitorConfig.default("belarus_1221", mech), "can0")


def _frame(ident: int, data: bytes, **kw) -> Frame:
    return Frame(kw.pop("stamp_ns", STAMP), ident, kw.pop("is_extended", True), False, kw.pop("is_error", False),
                 kw.pop("dlc", len(data)), data)


def test_decoded_inputs_from_the_mapping_by_hand(decoder: CanDecoder) -> None:
    table = yaml.safe_load(MAP.read_text())["inputs"]["lift_arm_angle"]["table"]
    # 0x7D = 125 -> 50 %: between the table's points 49.2 % and 52 %, linearly
    k = table["signal"].index(49.2)
    x0, x1, y0, y1 = 49.2, 52.0, table["value"][k], table["value"][k + 1]
    expected = y0 + (50.0 - x0) / (x1 - x0) * (y1 - y0)
    out = decoder.decode(_frame(0x0CFE4580, bytes([0x7D, 0x40, 0xFF, 0xFF, 0xFF, 0x3F, 0, 0])), STAMP + 5)
    assert out.outcome is Outcome.DECODED   # matched by PGN from another source address (0x80)
    [event] = out.events
    assert isinstance(event, JointStateEvent) and event.stamp_ns == STAMP and event.receive_ns == STAMP + 5
    assert event.names[0] == "lift_arm_angle" and event.positions[0] == pytest.approx(expected, abs=1e-12)
    # 10132 kPa gauge (0x2794) -> FluidPressure absolute, as the default configuration reads it: + 101325 Pa
    out = decoder.decode(_frame(PRESSURE_ID, bytes([0x94, 0x27, 0xFF, 0xFF, 0, 0, 0, 0])), STAMP)
    [event] = out.events
    assert isinstance(event, PressureEvent) and event.topic == "/pressure/lift_cap_pressure"
    assert event.fluid_pressure == pytest.approx(10_132e3 + 101_325.0, abs=1e-6)


@pytest.mark.parametrize("frame, code, words", [
    (_frame(REAR_HITCH, bytes([0xFF, 0x40, 0xFF, 0xFF, 0xFF, 0x3F, 0, 0])), Code.NO_VALUE_YET, "not available"),
    (_frame(REAR_HITCH, bytes([0xFE, 0x40, 0xFF, 0xFF, 0xFF, 0x3F, 0, 0])), Code.MALFORMED_INPUT, "error indicator"),
    (_frame(PRESSURE_ID, bytes([0x00, 0xFF, 0xFF, 0xFF, 0, 0, 0, 0])), Code.NO_VALUE_YET, "not available"),
    # 0xFB = 251 -> 100.4 %: above the DBC's maximum of 100 %
    (_frame(REAR_HITCH, bytes([0xFB, 0x40, 0xFF, 0xFF, 0xFF, 0x3F, 0, 0])), Code.OUT_OF_RANGE, "DBC range"),
    # 10 -> 4 %: below the mapping table's first point (16.8 %)
    (_frame(REAR_HITCH, bytes([10, 0x40, 0xFF, 0xFF, 0xFF, 0x3F, 0, 0])), Code.OUT_OF_RANGE, "table"),
    (_frame(REAR_HITCH, bytes([0x7D, 0x40, 0xFF, 0xFF, 0xFF])), Code.MALFORMED_INPUT, "DLC 5"),
    (_frame(0x004, bytes(8), is_error=True, is_extended=False), Code.MALFORMED_INPUT, "error frame"),
    (_frame(0x040, bytes(8), is_error=True, is_extended=False), Code.INPUTS_LOST, "bus-off"),
])
def test_refused_frames_feed_nothing(decoder: CanDecoder, frame: Frame, code: Code, words: str) -> None:
    out = decoder.decode(frame, STAMP)
    assert out.outcome is Outcome.REFUSED and out.events == ()
    assert out.finding is not None and out.finding.code is code and words in out.finding.text
    assert "can0" in out.finding.text


def test_every_frame_accounted_for(decoder: CanDecoder) -> None:
    frames = [_frame(REAR_HITCH, bytes([0x7D, 0x40, 0xFF, 0xFF, 0xFF, 0x3F, 0, 0])),   # decoded
              _frame(WHEEL_SPEED, bytes(8)),                                          # known, not mapped
              _frame(0x0CF00400, bytes(8)), _frame(0x0CF00400, bytes(8)),             # unknown (EEC1)
              _frame(0x123, bytes(2), is_extended=False),                             # unknown 11-bit
              _frame(REAR_HITCH, bytes([0xFF] * 8)),                                  # refused
              replace(_frame(REAR_HITCH, b""), is_remote=True)]                       # remote request
    outcomes = [decoder.decode(f, STAMP).outcome for f in frames]
    counts = decoder.counts
    assert outcomes.count(Outcome.DECODED) == counts.decoded == 1
    assert outcomes.count(Outcome.IGNORED) == counts.ignored == 5
    assert outcomes.count(Outcome.REFUSED) == counts.refused == 1
    assert counts.received == len(frames) == counts.decoded + counts.ignored + counts.refused
    assert counts.unknown_ids == {0x0CF00400: 2, 0x123: 1}


GOOD = """mechanism: belarus_1221
dbc: [{dbc}]
inputs:
  lift_cap_pressure: {{message: ExampleLiftCylinderPressure, signal: LiftCylinderCapPressure, unit: kPa,
                      pressure: gauge}}
"""


@pytest.mark.parametrize("change, key", [
    ("inputs:\n", "inputs"),
    ("inputs:\n  lift_arm_angle: {signal: RearHitchPosition}\n", "inputs.lift_arm_angle.message"),
    ("inputs:\n  lift_arm_angle: {message: RearHitchStatus, signal: RearHitchPosition, unit: furlong}\n",
     "inputs.lift_arm_angle.unit"),
    ("inputs:\n  lift_arm_angle: {message: RearHitchStatus, signal: RearHitchPosition, colour: red}\n",
     "inputs.lift_arm_angle.colour"),
    ("inputs:\n  lift_arm_angle: {message: RearHitchStatus, signal: RearHitchPosition, table: {signal: [0, 50, 100], "
     "value: [1, 3, 2]}}\n", "inputs.lift_arm_angle.table"),
    ("silence_timeout: -1\ninputs:\n  a: {message: M, signal: S}\n", "silence_timeout"),
])
def test_mapping_errors_name_the_key(change: str, key: str) -> None:
    with pytest.raises(InputError, match=f"mapping m.yaml: {key}:"):
        mapping_from_text("mechanism: belarus_1221\n" + change, "m.yaml", ROOT)


@pytest.mark.parametrize("text, key", [
    ("inputs:\n  rockshaft: {message: RearHitchStatus, signal: RearHitchPosition}\n", "inputs.rockshaft"),
    ("inputs:\n  lift_arm_angle: {message: NoSuchMessage, signal: X}\n", "inputs.lift_arm_angle.message"),
    ("inputs:\n  lift_arm_angle: {message: RearHitchStatus, signal: X}\n", "inputs.lift_arm_angle.signal"),
    ("inputs:\n  lift_cap_pressure: {message: ExampleLiftCylinderPressure, signal: LiftCylinderCapPressure, "
     "unit: kPa}\n", "inputs.lift_cap_pressure.pressure"),
    ("inputs:\n  lift_arm_angle: {message: RearHitchStatus, signal: RearHitchPosition, unit: kPa}\n",
     "inputs.lift_arm_angle.unit"),
])
def test_mapping_checked_against_dbc_and_mechanism(text: str, key: str) -> None:
    mech = load_description("belarus_1221")
    mapping = mapping_from_text(text, "m.yaml", ROOT)
    with pytest.raises(InputError, match=f"mapping m.yaml: {key}"):
        CanDecoder(load_databases([DBC]), mapping, mech, MonitorConfig.default("belarus_1221", mech), "can0")
    good = mapping_from_text(GOOD.format(dbc=DBC), "m.yaml", ROOT)
    CanDecoder(load_databases(good.dbc), good, mech, MonitorConfig.default("belarus_1221", mech), "can0")


def test_table_fit_recovers_a_known_curve() -> None:
    # f(x) = -2.7 - 0.012 x - 2e-5 x^2 sampled at 0.4 % steps from 10 to 90 %, each level several
    # times with its exact value: the fitted points lie on f, and linear interpolation between
    # points h = 80/25 = 3.2 % apart errs by at most max|f''| h^2 / 8 = 4e-5 * 3.2^2 / 8 = 5.12e-5
    levels = np.round(np.arange(10.0, 90.0 + 1e-9, 0.4), 9)
    x = np.repeat(levels, 3)
    f = lambda v: -2.7 - 0.012 * v - 2e-5 * v**2   # noqa: E731
    table = fit_table(x, f(x), points=26)
    assert table.signal[0] == 10.0 and table.signal[-1] == 90.0 and len(table.signal) == 26
    assert np.all(np.diff(table.value) < 0)
    probe = np.linspace(10.0, 90.0, 1001)
    errors = [abs(table.lookup(p) - f(p)) for p in probe]
    assert max(errors) <= 5.12e-5 + 1e-12
    assert table.lookup(9.9) is None and table.lookup(90.1) is None


def test_table_fit_makes_a_noisy_lift_monotone() -> None:
    rng = np.random.default_rng(3)
    x = np.round(rng.uniform(20, 80, 2000) / 0.4) * 0.4
    table = fit_table(x, 0.5 + 0.003 * x + rng.normal(0, 0.004, x.size))
    assert np.all(np.diff(table.value) > 0) and np.all(np.diff(table.signal) > 0)


@pytest.mark.parametrize("names, positions", [(("lift_arm_angle", "lift_cylinder"), (-2.7747, 0.535)), (("a",), (1.0,)),
                                              (("abcd",), (2.0,)), ((), ())])
def test_recorded_inputs_are_the_messages_rclpy_reads(names, positions) -> None:
    """The CDR the bridge records for a decoded frame: rclpy and the replay's reader read the same
    fields, and it is as long as rclpy's own serialization cut to the message (the padding may differ:
    rclpy leaves it uninitialised)."""
    from rclpy.serialization import deserialize_message, serialize_message
    from sensor_msgs.msg import FluidPressure, JointState

    from linkage_monitor.can.input_msg import fluid_pressure_cdr, joint_state_cdr
    from linkage_monitor.wire.definitions import exact_cdr
    from linkage_monitor.wire.sensor_messages import FLUID_PRESSURE, JOINT_STATE, read_input

    stamp = STAMP + 123_456_000
    mine = joint_state_cdr(stamp, names, positions)
    msg = deserialize_message(mine, JointState)
    assert (msg.header.stamp.sec, msg.header.stamp.nanosec) == (1_767_225_600, 123_456_000)
    assert list(msg.name) == list(names) and list(msg.position) == list(positions)
    assert list(msg.velocity) == [] and list(msg.effort) == [] and msg.header.frame_id == ""
    reading = read_input(JOINT_STATE, mine, "/joint_states", stamp)
    assert (reading.stamp_ns, list(reading.names), list(reading.positions)) == (stamp, list(names), list(positions))
    reference = JointState(name=list(names), position=list(positions))
    reference.header.stamp.sec, reference.header.stamp.nanosec = 1_767_225_600, 123_456_000
    assert len(mine) == len(exact_cdr(JOINT_STATE, bytes(serialize_message(reference))))
    pressure = fluid_pressure_cdr(stamp, 10.2e6)
    assert deserialize_message(pressure, FluidPressure).fluid_pressure == 10.2e6
    assert read_input(FLUID_PRESSURE, pressure, "/pressure", stamp).fluid_pressure == 10.2e6


def test_a_mapping_passes_its_dbc_scale_on_as_the_resolution() -> None:
    """isobus_hitch.dbc: RearHitchPosition 0.4 %/bit, through the mapping's tables (the steepest segment's
    slope, per % of position); LiftCylinderCapPressure 1 kPa/bit = 1000 Pa. The error budget takes them
    as the sensors' resolution unless the mechanism declares a coarser one (belarus_1221 declares none:
    the stroke's default 1 mm is coarser than the table's step, the angle's and the pressure's have none)."""
    mapping = load_mapping(MAP)
    mech = load_description("belarus_1221")
    decoder = CanDecoder(load_databases(mapping.dbc), mapping, mech, MonitorConfig.default("belarus_1221", mech), "can0")
    steps = decoder.resolutions
    tables = {item.name: item.table for item in mapping.inputs if item.table is not None}
    for name, kind in (("lift_arm_angle", "angles"), ("lift_cylinder", "cylinders")):
        table = tables[name]
        slopes = [abs((b - a) / (t - s)) for s, t, a, b in zip(table.signal, table.signal[1:], table.value,
                                                                 table.value[1:])]
        assert steps[name] == (kind, pytest.approx(0.4 * max(slopes), rel=1e-12))
    assert steps["lift_cap_pressure"] == ("pressures", pytest.approx(1000.0, rel=1e-12))
    sources = mech.error_sources.with_resolutions(steps)
    assert sources.sensor("lift_cap_pressure", "pressures").resolution == pytest.approx(1000.0)
    assert sources.sensor("lift_arm_angle", "angles").resolution == steps["lift_arm_angle"][1]
    assert sources.sensor("lift_arm_angle", "angles").bias == mech.error_sources.sensor("lift_arm_angle", "angles").bias
    # the stroke's default is 1 mm (ISO 11783-7's 0.4 % of a 0.25 m stroke); the table's steepest 0.4 % is more
    assert steps["lift_cylinder"][1] > 1e-3
    assert sources.sensor("lift_cylinder", "cylinders").resolution == steps["lift_cylinder"][1]
    declared = ErrorSources(sensors={"lift_cap_pressure": SensorError(resolution=5000.0, origin="file")}, declared=True)
    kept = declared.with_resolutions(steps)   # a coarser declared step stays
    assert kept.sensor("lift_cap_pressure", "pressures") == declared.sensor("lift_cap_pressure", "pressures")


def test_the_mechanism_with_the_resolutions_is_written_as_it_reads() -> None:
    """``with_sensor_resolutions`` writes each changed sensor into the description (bias, noise and
    resolution: a sensor listed takes exactly what it lists), so the description read back has the same
    sources; a step no coarser than what the sensor has changes nothing."""
    mech = load_description("belarus_1221")
    steps = {"lift_cap_pressure": ("pressures", 1000.0), "lift_cylinder": ("cylinders", 1e-4)}
    changed = with_sensor_resolutions(mech, steps)
    assert changed.error_sources.sensor("lift_cap_pressure", "pressures") == SensorError(
        bias=mech.error_sources.sensor("lift_cap_pressure", "pressures").bias, resolution=1000.0, origin="file")
    assert changed.error_sources.sensor("lift_cylinder", "cylinders") == mech.error_sources.sensor(
        "lift_cylinder", "cylinders")   # 0.1 mm is finer than the default 1 mm
    again = mechanism_from_dict(yaml.safe_load(mechanism_yaml(changed)), file=changed.file)
    assert again.error_sources == changed.error_sources
    assert with_sensor_resolutions(mech, {"lift_cylinder": ("cylinders", 1e-4)}) is mech
