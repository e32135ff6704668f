"""CAN logs through python-can's own readers (the shipped candump log; .asc and .blf written by
python-can's writers), can-to-bag read back by rosbags, a bag's raw frames decoded again by
`replay --map`, and the CAN commands' one-line errors."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import can
import pytest
from rosbags.rosbag2 import Reader
from rosbags.typesys import Stores, get_types_from_msg, get_typestore

from linkage_monitor.can.frames import to_message
from linkage_monitor.can.sources import read_log
from linkage_monitor.mechanics import load_description
from linkage_monitor.offline.replay import mechanism_in_bag

ROOT = Path(__file__).resolve().parent.parent
LOG = ROOT / "bags" / "can" / "belarus_1221_lift.log"
MAP = ROOT / "config" / "can" / "belarus_1221.yaml"


def _cli(*args: str, cwd: Path | None = None) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "linkage_monitor.cli.main", *args], capture_output=True, text=True,
                          cwd=cwd)


def _by_topic(bag: Path) -> dict[str, list]:
    """Every message of the bag decoded by rosbags with the bag's own definitions (a reader we did not write)."""
    out: dict[str, list] = {}
    with Reader(bag) as reader:
        store = get_typestore(Stores.EMPTY)
        for c in reader.connections:
            store.register(get_types_from_msg(c.msgdef.data, c.msgtype))
        for c, _, data in reader.messages():
            out.setdefault(c.topic, []).append(store.deserialize_cdr(data, c.msgtype))
    return out


def test_shipped_log_read_by_python_can() -> None:
    lines = LOG.read_text().splitlines()
    frames = list(read_log(LOG))
    assert len(frames) == len(lines)
    # the first line, by hand: "(1767225600.000000) can0 0CFE45F0#2A40FFFFFF3F0000 R"
    first = frames[0]
    assert lines[0].startswith("(1767225600.000000) can0 0CFE45F0#2A40FFFFFF3F0000")
    assert (first.stamp_ns, first.arbitration_id, first.is_extended, first.dlc) == (1_767_225_600 * 10**9, 0x0CFE45F0,
                                                                                    True, 8)
    assert first.data == bytes.fromhex("2A40FFFFFF3F0000")


@pytest.mark.slow
@pytest.mark.parametrize("suffix, writer", [(".asc", can.ASCWriter), (".blf", can.BLFWriter)])
def test_asc_and_blf_written_by_python_can_give_the_same_inputs(tmp_path: Path, suffix: str, writer) -> None:
    frames = list(read_log(LOG))
    path = tmp_path / f"lift{suffix}"
    with writer(str(path)) as w:
        for frame in frames:
            w.on_message_received(to_message(frame))
    again = list(read_log(path))
    assert [(f.arbitration_id, f.is_extended, f.dlc, f.data) for f in again] == \
           [(f.arbitration_id, f.is_extended, f.dlc, f.data) for f in frames]
    bags = {}
    for name, log in (("log", LOG), ("other", path)):
        result = _cli("can-to-bag", str(log), "--map", str(MAP), "--out", str(tmp_path / name))
        assert result.returncode == 0, result.stderr
        assert result.stdout.startswith(f"{len(frames)} frames: 2520 decoded, 504 ignored")
        bags[name] = _by_topic(tmp_path / name)
    for topic in ("/joint_states", "/pressure/lift_cap_pressure"):
        a, b = bags["log"][topic], bags["other"][topic]
        assert len(a) == len(b) == 1260
        values = (lambda m: list(m.position)) if topic == "/joint_states" else (lambda m: m.fluid_pressure)
        assert [values(m) for m in a] == [values(m) for m in b]


@pytest.mark.slow
def test_can_to_bag_holds_raw_frames_and_inputs(tmp_path: Path) -> None:
    result = _cli("can-to-bag", str(LOG), "--map", str(MAP), "--out", str(tmp_path / "bag"))
    assert result.returncode == 0, result.stderr
    topics = _by_topic(tmp_path / "bag")
    frames = list(read_log(LOG))
    raw = topics["/from_can_bus"]
    assert len(raw) == len(frames)
    for msg, frame in zip(raw[:50], frames[:50]):
        assert msg.header.stamp.sec * 10**9 + msg.header.stamp.nanosec == frame.stamp_ns
        assert (msg.id, msg.is_extended, msg.is_error, msg.is_rtr, msg.dlc) == (frame.arbitration_id, True, False,
                                                                               False, 8)
        assert bytes(msg.data) == frame.data
    # the decoded inputs carry the frames' stamps: the hitch status every 20 ms from the first frame on
    joints = topics["/joint_states"]
    assert [m.header.stamp.sec * 10**9 + m.header.stamp.nanosec for m in joints[:3]] == [
        frames[0].stamp_ns, frames[0].stamp_ns + 20_000_000, frames[0].stamp_ns + 40_000_000]
    assert list(joints[0].name) == ["lift_arm_angle", "lift_cylinder"]
    # gauge 10.132 MPa... the pressure frame's first value by hand: 0x279A = 10138 kPa gauge -> + 101325 Pa absolute
    assert frames[1].data[:2] == bytes([0x9A, 0x27])
    assert topics["/pressure/lift_cap_pressure"][0].fluid_pressure == pytest.approx(10_138e3 + 101_325.0, abs=1e-6)
    # the bag's mechanism takes the pressure signal's DBC scale, 1 kPa/bit, as its sensor's resolution: a
    # replay budgets what the bridge budgets (the angle's and stroke's through their tables: test_can_decode.py)
    recorded = mechanism_in_bag(tmp_path / "bag").error_sources.sensor("lift_cap_pressure", "pressures")
    assert recorded.resolution == pytest.approx(1000.0)
    assert recorded.bias == pytest.approx(load_description("belarus_1221").error_sources.sensor(
        "lift_cap_pressure", "pressures").bias)   # the rest as the file (here its defaults) has it


@pytest.mark.slow
def test_replay_decodes_the_raw_frames_again(tmp_path: Path) -> None:
    assert _cli("can-to-bag", str(LOG), "--map", str(MAP), "--out", str(tmp_path / "bag")).returncode == 0
    same = _cli("replay", str(tmp_path / "bag"), "--quiet")
    again = _cli("replay", str(tmp_path / "bag"), "--map", str(MAP), "--quiet")
    assert again.returncode == 0, again.stderr
    assert "decoded again with" in again.stdout and "3024 frames: 2520 decoded" in again.stdout
    assert same.stdout.split("replayed")[1].split("\n", 1)[1] == again.stdout.split("replayed")[1].split("\n", 1)[1]
    # another mapping (the pressure scaled 100x: ~1 GPa, beyond the cylinder's plausibility limit) changes
    # what is computed: every pressure refused, no pose solved
    wrong = tmp_path / "scaled.yaml"
    wrong.write_text(MAP.read_text().replace("unit: kPa", "unit: kPa\n    scale: 100").replace("dbc: [isobus_hitch.dbc]",
                                                                             f"dbc: [{MAP.parent / 'isobus_hitch.dbc'}]"))
    changed = _cli("replay", str(tmp_path / "bag"), "--map", str(wrong), "--quiet")
    assert changed.returncode == 1 and "ERROR   1260  out_of_range" in changed.stdout


@pytest.mark.parametrize("args, words", [
    (["can-to-bag", "missing.log", "--map", str(MAP), "--out", "OUT"], "CAN log missing.log: no such file"),
    (["can-to-bag", str(LOG), "--map", "missing.yaml", "--out", "OUT"], "mapping missing.yaml: cannot be read"),
    (["can-to-bag", str(LOG), "--map", str(MAP), "--dbc", "missing.dbc", "--out", "OUT"], "DBC missing.dbc"),
    (["can", "--map", str(MAP), "--bus", "nosuch:can0"], "python-can knows no interface 'nosuch'"),
    (["can", "--map", str(MAP), "--bus", "can0"], "expected INTERFACE:CHANNEL"),
])
@pytest.mark.slow
def test_errors_are_one_line(tmp_path: Path, args: list[str], words: str) -> None:
    args = [str(tmp_path / a) if a == "OUT" else a for a in args]
    result = _cli(*args, cwd=tmp_path)   # nothing may be recorded: the errors come before the node starts
    assert result.returncode == 2 and not (tmp_path / "out").exists()
    assert words in result.stderr and len(result.stderr.strip().splitlines()) == 1 and "Traceback" not in result.stderr


@pytest.mark.slow
def test_calibration_reproduces_the_shipped_tables(tmp_path: Path) -> None:
    """can-calibrate on the shipped log and the simulator's truth gives the tables of the shipped mapping
    (written there to 9 significant digits), each within one position step's worth of the truth: the
    largest error is at most the angle (length) change over 0.4 %, the position's resolution."""
    out = tmp_path / "calibrated.yaml"
    result = _cli("can-calibrate", str(LOG), "--map", str(MAP), "--truth", str(ROOT / "bags" / "can" / "belarus_1221_lift_truth"),
                  "--out", str(out))
    assert result.returncode == 0, result.stderr
    import yaml
    fitted, shipped = yaml.safe_load(out.read_text())["inputs"], yaml.safe_load(MAP.read_text())["inputs"]
    for name in ("lift_arm_angle", "lift_cylinder"):
        assert fitted[name]["table"]["signal"] == shipped[name]["table"]["signal"]
        assert fitted[name]["table"]["value"] == pytest.approx(shipped[name]["table"]["value"], rel=1e-8)
        s, v = shipped[name]["table"]["signal"], shipped[name]["table"]["value"]
        step = max(abs(v[k + 1] - v[k]) / (s[k + 1] - s[k]) for k in range(len(s) - 1)) * 0.4
        line = next(l for l in result.stdout.splitlines() if l.startswith(f"# {name}:"))
        assert float(line.split("truth ")[1].split()[0]) <= step
