"""The CAN surfaces under a hostile field test: two ECUs sending one parameter group, units and
factors the mapping gets wrong, a multiplexed DBC message, duplicate mapping keys, a non-UTF-8
mapping, garbage and cut lines in a candump log, error frames of every class in a log, and a
bus flooded beyond what the bridge works off. Each test reproduces the fault it holds."""

from __future__ import annotations

import subprocess
import time
import sys
from pathlib import Path

import can
import pytest

from linkage_monitor.can.candump import read_candump
from linkage_monitor.can.decoder import CanDecoder, load_databases
from linkage_monitor.can.frames import Frame, FrameBlock, to_message
from linkage_monitor.can.mapping import load_mapping, mapping_from_text
from linkage_monitor.can.outcomes import Outcome
from linkage_monitor.can.sources import read_log_blocks
from linkage_monitor.can.to_bag import blocks_to_bag
from linkage_monitor.mechanics import InputError, load_description
from linkage_monitor.monitoring.config import MonitorConfig
from linkage_monitor.monitoring.events import JointStateEvent
from linkage_monitor.monitoring.findings import Code, Level

ROOT = Path(__file__).resolve().parent.parent
DBC = ROOT / "config" / "can" / "isobus_hitch.dbc"
MAP = ROOT / "config" / "can" / "belarus_1221.yaml"
LOG = ROOT / "bags" / "can" / "belarus_1221_lift.log"
STAMP = 1_767_225_600_000_000_000
HITCH_F0, HITCH_80 = 0x0CFE45F0, 0x0CFE4580   # PGN 65093 (rear hitch status) from the TECU (0xF0) and from 0x80


def _decoder(mapping_text: str | None = None, folder: Path = ROOT / "config" / "can") -> CanDecoder:
    mapping = load_mapping(MAP) if mapping_text is None else mapping_from_text(mapping_text, "m.yaml", folder)
    mech = load_description("belarus_1221")
    return CanDecoder(load_databases(mapping.dbc), mapping, mech, MonitorConfig.default("belarus_1221", mech), "can0")


def _hitch(ident: int, position_raw: int, k: int) -> Frame:
    """A rear hitch status frame: position raw · 0.4 % (byte 1), the rest of the shipped log's first frame."""
    return Frame(STAMP + k * 10_000_000, ident, True, False, False, 8,
                 bytes([position_raw, 0x40, 0xFF, 0xFF, 0xFF, 0x3F, 0, 0]))


def _two_ecus(n: int = 20) -> list[Frame]:
    """Two ECUs sending PGN 65093 in turn with different positions: 50 % from 0xF0, 60 % from 0x80."""
    return [_hitch(HITCH_F0, 125, k) if k % 2 == 0 else _hitch(HITCH_80, 150, k) for k in range(n)]


# ---- 1. two sources for one input ---------------------------------------------------------------------------
def test_two_sources_for_one_input_are_refused_and_named() -> None:
    decoder = _decoder()
    out = [decoder.decode(f, f.stamp_ns) for f in _two_ecus()]
    # the first frame (one source so far) is decoded; from the second source on, neither is used
    assert out[0].outcome is Outcome.DECODED
    assert all(d.outcome is Outcome.REFUSED and d.events == () for d in out[1:])
    finding = out[1].finding
    assert finding is not None and finding.code is Code.SENSORS_DISAGREE
    assert "0xF0" in finding.text and "0x80" in finding.text and "source_address" in finding.text
    assert decoder.counts.two_sources == {"RearHitchStatus": [0xF0, 0x80]}
    assert decoder.counts.refused == 19
    assert "RearHitchStatus sent by 2 sources (0xF0, 0x80)" in decoder.counts.summary()
    assert decoder.counts.level is Level.WARN   # the bridge's frame-count status: not OK


def test_two_sources_in_blocks_as_frame_by_frame() -> None:
    frames = _two_ecus()
    one, many = _decoder(), _decoder()
    expected = [one.decode(f, f.stamp_ns) for f in frames]
    result = many.decode_block(FrameBlock.of(frames))
    assert [o.outcome for o in expected] == [Outcome.DECODED] + [Outcome.REFUSED] * 19
    assert [f.text for f in result.refusals()] == [d.finding.text for d in expected if d.finding is not None]
    assert many.counts == one.counts


def test_the_trusted_source_is_named_in_the_mapping() -> None:
    text = MAP.read_text().replace("    signal: RearHitchPosition\n", "    signal: RearHitchPosition\n"
                                   "    source_address: 0xF0\n")
    decoder = _decoder(text)
    out = [decoder.decode(f, f.stamp_ns) for f in _two_ecus()]
    assert [d.outcome for d in out] == [Outcome.DECODED, Outcome.IGNORED] * 10
    # 125 · 0.4 = 50 %: the 0xF0 frames' position, never the 60 % of 0x80
    positions = {e.positions for d in out for e in d.events if isinstance(e, JointStateEvent)}
    assert len(positions) == 1
    assert decoder.counts.untrusted_ids == {HITCH_80: 10}
    assert "10 of sources the mapping does not trust 0xCFE4580 ×10" in decoder.counts.summary()


def test_source_address_only_for_j1939_messages(tmp_path: Path) -> None:
    (tmp_path / "plain.dbc").write_text(PLAIN_DBC)
    text = ("mechanism: belarus_1221\ndbc: [plain.dbc]\ninputs:\n  lift_cap_pressure: {message: Plain, signal: Cap, "
            "unit: kPa, pressure: gauge, source_address: 0x21}\n")
    with pytest.raises(InputError, match="inputs.lift_cap_pressure.source_address: Plain is not a J1939 message"):
        _decoder(text, tmp_path)
    with pytest.raises(InputError, match=r"source_address: 300: expected the J1939 source address"):
        mapping_from_text(text.replace("0x21", "300"), "m.yaml", tmp_path)


def test_two_sources_offline_from_a_candump_log(tmp_path: Path) -> None:
    log = tmp_path / "two.log"
    with can.CanutilsLogWriter(str(log), channel="can0") as writer:
        for frame in _two_ecus():
            writer.on_message_received(to_message(frame))
    decoder = _decoder()
    converted = blocks_to_bag(read_log_blocks(log, []), decoder, load_description("belarus_1221"), decoder.config,
                              tmp_path / "bag")
    assert (converted.counts.decoded, converted.counts.refused) == (1, 19)
    assert {f.code for f in converted.refusals} == {Code.SENSORS_DISAGREE}


# ---- 2, 3. units and factors ----------------------------------------------------------------------------------
PRESSURE_MAP = """mechanism: belarus_1221
dbc: [isobus_hitch.dbc]
inputs:
  lift_cap_pressure: {{message: ExampleLiftCylinderPressure, signal: LiftCylinderCapPressure, pressure: gauge{extra}}}
"""


@pytest.mark.parametrize("extra, words", [
    # the DBC gives kPa: read as Pa (no unit) the pressure is 1000 times too small
    ("", "the DBC gives ExampleLiftCylinderPressure.LiftCylinderCapPressure in kPa, the mapping reads it as Pa "
         "(no 'unit' given: SI): write 'unit: kPa'"),
    (", unit: bar", "in kPa, the mapping reads it as 'bar': write 'unit: kPa'"),
])
def test_a_unit_other_than_the_dbc_s_is_refused_at_load(extra: str, words: str) -> None:
    with pytest.raises(InputError) as error:
        _decoder(PRESSURE_MAP.format(extra=extra))
    assert "inputs.lift_cap_pressure.unit" in str(error.value) and words in str(error.value)
    _decoder(PRESSURE_MAP.format(extra=", unit: kPa"))


def test_a_signal_of_another_quantity_or_an_unknown_unit_needs_a_unit_or_table(tmp_path: Path) -> None:
    (tmp_path / "plain.dbc").write_text(PLAIN_DBC)
    head = "mechanism: belarus_1221\ndbc: [plain.dbc]\ninputs:\n"
    with pytest.raises(InputError, match=r"lift_arm_angle: the DBC gives Plain.Cap in kPa \(a pressure\)"):
        _decoder(head + "  lift_arm_angle: {message: Plain, signal: Cap}\n", tmp_path)
    with pytest.raises(InputError, match=r"lift_arm_angle.unit: the DBC gives Plain.Percent in '%'"):
        _decoder(head + "  lift_arm_angle: {message: Plain, signal: Percent, scale: 0.01}\n", tmp_path)
    _decoder(head + "  lift_arm_angle: {message: Plain, signal: Percent, scale: 0.01, unit: rad}\n", tmp_path)


def test_a_factor_of_zero_is_refused_at_load(tmp_path: Path) -> None:
    (tmp_path / "plain.dbc").write_text(PLAIN_DBC)
    head = "mechanism: belarus_1221\ndbc: [plain.dbc]\ninputs:\n"
    with pytest.raises(InputError, match="inputs.lift_cap_pressure.signal: Plain.Zero has factor 0 in the DBC"):
        _decoder(head + "  lift_cap_pressure: {message: Plain, signal: Zero, unit: kPa, pressure: gauge}\n", tmp_path)
    with pytest.raises(InputError, match="inputs.lift_cap_pressure.scale: 0 makes every value of Cap the offset"):
        mapping_from_text(head + "  lift_cap_pressure: {message: Plain, signal: Cap, unit: kPa, scale: 0, "
                          "pressure: gauge}\n", "m.yaml", tmp_path)


@pytest.mark.parametrize("written, value", [("1e-3", 1e-3), ("2E+2", 200.0), ("-5e0", -5.0)])
def test_a_number_yaml_reads_as_text_is_read_as_in_a_mechanism_file(written: str, value: float) -> None:
    """`scale: 1e-3` (no dot: YAML 1.1 leaves it a string) was refused as "'1e-3' is not a finite number",
    where a mechanism file reads 20e6 as the number; both read it as the number now."""
    text = MAP.read_text().replace("    unit: kPa\n", f"    unit: kPa\n    scale: {written}\n    offset: {written}\n")
    [item] = [i for i in mapping_from_text(text, "m.yaml", ROOT).inputs if i.name == "lift_cap_pressure"]
    assert (item.scale, item.offset) == (value, value)
    with pytest.raises(InputError, match=r"inputs.lift_cap_pressure.scale: '1e-3x' is not a finite number"):
        mapping_from_text(text.replace(f"scale: {written}", "scale: 1e-3x"), "m.yaml", ROOT)


PLAIN_DBC = """VERSION ""

NS_ :

BS_:

BU_: ECU

BO_ 513 Plain: 8 ECU
 SG_ Cap : 0|16@1+ (1,0) [0|64255] "kPa" ECU
 SG_ Zero : 16|16@1+ (0,0) [0|0] "kPa" ECU
 SG_ Percent : 32|8@1+ (0.4,0) [0|100] "%" ECU

BO_ 514 Muxed: 8 ECU
 SG_ Kind M : 0|8@1+ (1,0) [0|255] "" ECU
 SG_ Cap m1 : 8|16@1+ (1,0) [0|64255] "kPa" ECU
 SG_ Rod m2 : 8|16@1+ (1,0) [0|64255] "kPa" ECU
"""


# ---- 7. multiplexed messages, duplicate keys; 6. a mapping that is not UTF-8 ---------------------------------
def test_a_multiplexed_signal_is_decoded_where_its_multiplexer_selects_it(tmp_path: Path) -> None:
    (tmp_path / "plain.dbc").write_text(PLAIN_DBC)
    decoder = _decoder("mechanism: belarus_1221\ndbc: [plain.dbc]\ninputs:\n  lift_cap_pressure: {message: Muxed, "
                       "signal: Cap, unit: kPa, pressure: absolute}\n", tmp_path)
    cap = decoder.decode(Frame(STAMP, 514, False, False, False, 8, bytes([1, 0x10, 0x27, 0, 0, 0, 0, 0])), STAMP)
    rod = decoder.decode(Frame(STAMP, 514, False, False, False, 8, bytes([2, 0x10, 0x27, 0, 0, 0, 0, 0])), STAMP)
    assert cap.outcome is Outcome.DECODED and rod.outcome is Outcome.IGNORED
    [event] = cap.events
    assert event.fluid_pressure == 10_000e3   # 0x2710 = 10000 kPa, absolute as the monitor reads it


def test_a_key_given_twice_in_the_mapping_is_refused(tmp_path: Path) -> None:
    text = MAP.read_text().replace("silence_timeout: 1.0", "silence_timeout: 1.0\nsilence_timeout: 5.0")
    with pytest.raises(InputError, match=r"mapping m.yaml: line 9: key 'silence_timeout' given twice \(lines 8 and 9\)"):
        mapping_from_text(text, "m.yaml", ROOT)


def test_a_mapping_that_is_not_utf8_is_one_clear_error(tmp_path: Path) -> None:
    path = tmp_path / "latin1.yaml"
    path.write_bytes(MAP.read_text().replace("# CAN mapping", "# CAN Zuordnung f\u00fcr").encode("latin-1"))
    with pytest.raises(InputError, match=r"latin1.yaml: not UTF-8 text \(byte 0xFC at offset 17\): save it as UTF-8"):
        load_mapping(path)


# ---- 4. candump logs: bad lines refused one by one, error frames of every class, refusals named -------------
def _hostile_log(tmp_path: Path) -> Path:
    """The shipped log's first 40 lines with garbage at line 3, error frames of classes 0x4 (controller),
    0x40 (bus-off) and 0x100 at lines 11-13, and its 41st line cut short, with no newline, as the last."""
    lines = LOG.read_text().splitlines()
    body = lines[:2] + ["garbage \xff"] + lines[2:9] + [
        "(1767225600.200000) can0 20000004#0000000000000000",
        "(1767225600.200100) can0 20000040#0000000000000000",
        "(1767225600.200200) can0 20000100#0000000000000000"] + lines[9:40]
    path = tmp_path / "hostile.log"
    path.write_bytes(("\n".join(body) + "\n" + lines[40][:17]).encode("latin-1"))
    return path


def test_bad_lines_are_refused_one_by_one_and_error_frames_of_every_class_read_as_error_frames(tmp_path: Path) -> None:
    refused: list = []
    frames = [f for block in read_log_blocks(_hostile_log(tmp_path), refused) for f in block.frames()]
    assert [r.number for r in refused] == [3, 45]   # the garbage; the cut line after 40 + 1 + 3 lines
    assert len(frames) == 40 + 3
    errors = [f for f in frames if f.is_error]
    assert [(f.arbitration_id, f.is_extended) for f in errors] == [(0x4, False), (0x40, False), (0x100, False)]
    decoder = _decoder()
    outcomes = [decoder.decode(f, f.stamp_ns) for f in errors]
    assert [d.finding.code for d in outcomes if d.finding] == [Code.MALFORMED_INPUT, Code.INPUTS_LOST,
                                                                Code.MALFORMED_INPUT]
    # the same frames as the live bridge's: an error frame through python-can's bus is read so
    bus = can.Bus(interface="virtual", channel="hostile-errors", receive_own_messages=True)
    try:
        bus.send(can.Message(arbitration_id=0x40, is_extended_id=False, is_error_frame=True, data=bytes(8)))
        from linkage_monitor.can.frames import from_message
        live = from_message(bus.recv(1.0))
    finally:
        bus.shutdown()
    assert (live.arbitration_id, live.is_extended, live.is_error, live.data) == (0x40, False, True, bytes(8))


def test_refused_frames_are_named_by_kind() -> None:
    from linkage_monitor.can.to_bag import refusal_lines

    decoder = _decoder()
    frames = [_hitch(HITCH_F0, 0xFF, k) for k in range(420)]   # 'not available' positions
    refusals = [d.finding for d in (decoder.decode(f, f.stamp_ns) for f in frames) if d.finding]
    [line] = refusal_lines(refusals)
    assert line.startswith("WARN      420  no_value_yet  first: CAN frame RearHitchStatus (0x0CFE45F0) on can0 "
                           "signal RearHitchPosition reads 'not available'")


def test_unknown_identifiers_are_counted_in_the_summary() -> None:
    decoder = _decoder()
    for k, ident in enumerate([0x123] * 3 + [0x18FEF100] + [0x7FF] * 2):
        decoder.decode(Frame(STAMP + k, ident, ident > 0x7FF, False, False, 8, bytes(8)), STAMP)
    assert "6 of unknown identifiers 0x123 ×3, 0x7FF ×2, 0x18FEF100 ×1" in decoder.counts.summary()


def _cli(*args: str, **kw) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, "-m", "linkage_monitor.cli.main", *args], text=True,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, **kw)


@pytest.mark.slow
def test_can_to_bag_converts_around_bad_lines_and_names_them(tmp_path: Path) -> None:
    run = _cli("can-to-bag", str(_hostile_log(tmp_path)), "--map", str(MAP), "--out", str(tmp_path / "bag"))
    out, err = run.communicate(timeout=120)
    assert run.returncode == 0, err
    assert err.startswith("linkage-monitor: CAN log ") and "2 line(s) refused, not converted: line 3 (" in err
    assert "line 45 (" in err and "Traceback" not in err
    assert out.splitlines()[0].startswith("43 frames: ")
    assert "INPUTS_LOST".lower() in out and (tmp_path / "bag" / "metadata.yaml").is_file()


@pytest.mark.slow
def test_can_to_bag_into_a_closed_pipe_and_a_latin1_mapping_end_quietly(tmp_path: Path) -> None:
    run = _cli("can-to-bag", str(LOG), "--map", str(MAP), "--out", str(tmp_path / "bag"))
    assert run.stdout is not None
    run.stdout.close()   # `| head -0`: the reader is gone before anything is printed
    _, err = run.communicate(timeout=120)
    assert run.returncode == 0 and "Traceback" not in err and "BrokenPipe" not in err, err
    latin1 = tmp_path / "latin1.yaml"
    latin1.write_bytes(MAP.read_text().replace("# CAN mapping", "# Zuordnung f\u00fcr").encode("latin-1"))
    run = _cli("can-to-bag", str(LOG), "--map", str(latin1), "--out", str(tmp_path / "bag2"))
    _, err = run.communicate(timeout=120)
    assert run.returncode == 2 and err.count("\n") == 1 and "not UTF-8 text" in err, err


# ---- 5. a flood: frames the socket drops are counted -----------------------------------------------------------
def test_frames_dropped_at_the_socket_are_counted_and_reported() -> None:
    """A receiver that does not read while 3000 frames arrive into a 4 kB receive buffer: the kernel drops
    most of them. The frames read and the frames counted as dropped are every frame sent."""
    import random

    from linkage_monitor.can.sources import DropCount, open_bus, receive_buffer

    chance = random.SystemRandom()
    group = f"239.74.{chance.randint(0, 255)}.{chance.randint(1, 254)}"
    port = chance.randint(20_000, 60_000)
    receiver = open_bus(f"udp_multicast:{group}", port=port)
    sender = can.Bus(interface="udp_multicast", channel=group, port=port)
    try:
        receive_buffer(receiver, 4096)
        drops = DropCount(receiver)
        assert drops.known
        sent = 3000
        for k in range(sent):
            sender.send(can.Message(arbitration_id=HITCH_F0, data=bytes([125, 0x40, 0xFF, 0xFF, 0xFF, 0x3F, 0, k % 256])))
        time.sleep(0.2)
        read = 0
        while receiver.recv(0.05) is not None:
            read += 1
        dropped = drops.new()
    finally:
        sender.shutdown()
        receiver.shutdown()
    assert dropped > 0 and read + dropped == sent
    decoder = _decoder()
    finding = decoder.counts.lose(dropped, f"udp_multicast:{group}")
    assert finding.code is Code.INPUTS_LOST and f"{dropped} CAN frame(s) lost on udp_multicast:{group}" in finding.text
    assert f"{dropped} lost before the bridge read them" in decoder.counts.summary()
    assert decoder.counts.level is Level.WARN


# ---- 1, live: the bridge on a bus where two ECUs send the rear hitch status ----------------------------------
@pytest.mark.slow
@pytest.mark.ros
def test_live_bridge_refuses_two_sources(tmp_path: Path, ros: None, monkeypatch: pytest.MonkeyPatch) -> None:
    import json
    import random

    from support.can_bridge import bag_messages, cli_command, wait_for_frame_count, wait_for_log_line
    from support.ros_harness import node_bag, stop

    log = tmp_path / "two.log"
    with can.CanutilsLogWriter(str(log), channel="can0") as writer:
        for frame in _two_ecus():
            writer.on_message_received(to_message(frame))
    chance = random.SystemRandom()
    group = f"239.74.{chance.randint(0, 255)}.{chance.randint(1, 254)}"
    monkeypatch.setenv("CAN_CONFIG", json.dumps({"port": chance.randint(20000, 60000)}))
    bridge_log = tmp_path / "bridge.log"
    bridge = subprocess.Popen(cli_command("can", "--map", str(MAP), "--bus", f"udp_multicast:{group}", "--ros-args",
                                          "-p", f"record_dir:={tmp_path / 'bags'}"),
                              stdout=bridge_log.open("w"), stderr=subprocess.STDOUT)
    try:
        wait_for_log_line(bridge_log, "CAN frames from", bridge)
        sent = subprocess.run([sys.executable, str(ROOT / "test" / "support" / "can_sender.py"), "bus",
                               f"udp_multicast:{group}", str(log), "100"], capture_output=True, text=True, timeout=60)
        assert sent.returncode == 0, sent.stderr
        # the 20 frames of the two ECUs, then the sender's error frame, bus-off and 'not available' position
        status = wait_for_frame_count(23)
    finally:
        code = stop(bridge)
    assert code == 0, bridge_log.read_text()
    assert status.startswith("23 frames: 1 decoded, 0 ignored, 22 refused; RearHitchStatus sent by 2 sources (0xF0, "
                             "0x80)"), status
    bag = node_bag(tmp_path / "bags")
    findings = [s.message for m in bag_messages(bag, "/diagnostics") for s in m.status]
    assert any("0xF0 and 0x80 both send PGN 65093" in text for text in findings)
    assert len(bag_messages(bag, "/joint_states")) == 1   # the first frame's, before the second source was heard


# ---- 5, live: the bridge's own bus flooded while it cannot read ------------------------------------------------
@pytest.mark.slow
@pytest.mark.ros
def test_the_bridge_reports_the_frames_its_bus_dropped(ros: None, monkeypatch: pytest.MonkeyPatch) -> None:
    """A flood the bridge does not read fast enough (here: it is not spun while 3000 frames arrive into a 4 kB
    receive buffer): before, it handled what reached it and said nothing of the rest; now the frames the
    socket dropped are an ``inputs_lost`` WARN on /diagnostics naming the bus and how many, and the frame
    count says "lost" and is WARN. The frames counted plus the frames lost are every frame sent."""
    import json
    import random

    import rclpy
    from diagnostic_msgs.msg import DiagnosticArray
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.parameter import Parameter

    from linkage_monitor.can.node import CanBridgeNode, CanSource
    from linkage_monitor.can.sources import receive_buffer
    from support.can_bridge import close_rig

    chance = random.SystemRandom()
    group = f"239.74.{chance.randint(0, 255)}.{chance.randint(1, 254)}"
    port = chance.randint(20_000, 60_000)
    monkeypatch.setenv("CAN_CONFIG", json.dumps({"port": port}))   # python-can's bus options, as the CLI gets them
    bus = f"udp_multicast:{group}"
    mapping = load_mapping(MAP)
    bridge = CanBridgeNode(CanSource(mapping=mapping, dbc=mapping.dbc, bus=bus),
                           parameter_overrides=[Parameter("mechanism", value="belarus_1221"),
                                                Parameter("record", value=False)])
    listener = rclpy.create_node("flood_listener")
    statuses: list = []
    listener.create_subscription(DiagnosticArray, "/diagnostics", lambda m: statuses.extend(m.status), 1000)
    sender = can.Bus(interface="udp_multicast", channel=group, port=port)
    executor = SingleThreadedExecutor()
    executor.add_node(bridge)
    executor.add_node(listener)
    sent = 3000
    try:
        frames = bridge.input_source
        assert frames.drops.known
        receive_buffer(frames.bus, 4096)
        for k in range(sent):
            sender.send(can.Message(arbitration_id=HITCH_F0,
                                    data=bytes([125, 0x40, 0xFF, 0xFF, 0xFF, 0x3F, 0, k % 256])))
        time.sleep(0.2)
        end = time.monotonic() + 30.0
        while time.monotonic() < end and not _every_frame_accounted(statuses, sent):
            executor.spin_once(timeout_sec=0.05)
    finally:
        close_rig(sender, executor, bridge, listener)
    lost = [s for s in statuses if "inputs_lost" in {kv.value for kv in s.values}]
    assert lost and all(f"CAN frame(s) lost on {bus}" in s.message and s.level == b"\x01" for s in lost), \
        [(s.name, s.message) for s in statuses]
    dropped = sum(int(s.message.split()[0]) for s in lost)
    count = [s for s in statuses if s.name.endswith(": can")][-1]
    assert dropped > 0 and _every_frame_accounted(statuses, sent), (count.message, [s.message for s in lost])
    assert f"{dropped} lost before the bridge read them" in count.message and count.level == b"\x01"


def _every_frame_accounted(statuses: list, sent: int) -> bool:
    """Whether the bridge's last frame count says ``sent`` frames were received or lost at the socket."""
    counts = [s.message for s in statuses if s.name.endswith(": can")]
    if not counts or " lost before the bridge read them" not in counts[-1]:
        return False
    received = int(counts[-1].split()[0])
    lost = int(counts[-1].split(" lost before the bridge read them")[0].rsplit(maxsplit=1)[-1])
    return received + lost == sent
