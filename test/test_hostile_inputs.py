"""Hostile files and arguments: each is refused with one line naming
the input and the reason, exit code 2 from the CLI, never a traceback or a hang."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from linkage_monitor.bag.errors import BagError
from linkage_monitor.cli.main import main
from linkage_monitor.mechanics import MechanismFileError, load_mechanism, preset_path
from linkage_monitor.offline.replay import replay

REPO = Path(__file__).resolve().parent.parent
PRESET = preset_path("belarus_1221").read_text(encoding="utf-8")
SAMPLE_BAG = REPO / "bags" / "belarus_1221_overload"


def _points_coincident(text: str) -> str:
    lines = []
    for line in text.splitlines():
        key = line.strip().split(":")[0]
        lines.append(f"  {key}: [0.0, 0.0]" if key[:1] in "PS" and key[1:2].isdigit() and "[" in line else line)
    return "\n".join(lines)


HOSTILE_FILES = {   # name: (bytes of the file, words the error must contain)
    "utf16": (PRESET.encode("utf-16"), "not UTF-8"),
    "latin1": (b"# caf\xe9\n" + PRESET.encode(), "not UTF-8"),
    "deep_nesting": (b"a: " + b"[" * 20000 + b"]" * 20000 + b"\n", "nesting deeper"),
    "nesting_40": (b"a: " + b"[" * 40 + b"]" * 40 + b"\n", "nesting deeper than 32"),   # libyaml takes 40
    "5001_digit_integer": (PRESET.replace("gravity: 9.80665", "gravity: " + "9" * 5001).encode(), "5001 digits"),
    "gravity_1e308": (PRESET.replace("gravity: 9.80665", "gravity: 1e308").encode(), "gravity"),
    "alias_bomb": (b'a: &a ["lol","lol","lol","lol","lol","lol","lol","lol","lol"]\n'
                   + b"".join(f"{c}: &{c} [{','.join([f'*{p}'] * 9)}]\n".encode()
                              for p, c in zip("abcdefgh", "bcdefghi")), "aliases"),
    "duplicate_key": ((PRESET + "\nname: other\n").encode(), "duplicate key 'name'"),
    "points_coincident": (_points_coincident(PRESET).encode(), "coincide"),
    "millions_of_points": (b"points:\n" + b"  p: [0, 0]\n" * 230_000, "bytes"),
}


@pytest.mark.parametrize("case", sorted(HOSTILE_FILES))
def test_hostile_mechanism_file_is_one_named_error(tmp_path, case, capsys):
    data, words = HOSTILE_FILES[case]
    path = tmp_path / f"{case}.yaml"
    path.write_bytes(data)
    with pytest.raises(MechanismFileError) as err:
        load_mechanism(path)
    assert str(path) in str(err.value) and words in str(err.value), str(err.value)
    assert main(["solve", "--mechanism", str(path)]) == 2
    err_lines = capsys.readouterr().err.strip().splitlines()
    assert len(err_lines) == 1 and words in err_lines[0]


@pytest.mark.slow
def test_fifo_is_refused_without_blocking(tmp_path):
    fifo = tmp_path / "mechanism.yaml"
    os.mkfifo(fifo)
    run = subprocess.run([sys.executable, "-m", "linkage_monitor.cli", "solve", "--mechanism", str(fifo)],
                         capture_output=True, text=True, timeout=60)   # a blocking open would hang here
    assert run.returncode == 2 and "not a regular file" in run.stderr and len(run.stderr.strip().splitlines()) == 1


def _broken_bags(tmp_path: Path) -> dict[str, Path]:
    mcap = next(SAMPLE_BAG.glob("*.mcap"))
    bags = {}
    magic = tmp_path / "magic_only"
    magic.mkdir()
    (magic / "x.mcap").write_bytes(b"\x89MCAP0\r\n")
    bags["magic_only"] = magic
    middle = tmp_path / "corrupted_middle"
    middle.mkdir()
    data = bytearray(mcap.read_bytes())
    data[len(data) // 2:len(data) // 2 + 4096] = bytes(range(256)) * 16   # footer and summary intact
    (middle / "x.mcap").write_bytes(bytes(data))
    bags["corrupted_middle"] = middle
    meta = tmp_path / "binary_metadata"
    shutil.copytree(SAMPLE_BAG, meta)
    (meta / "metadata.yaml").write_bytes(bytes(range(256)))
    bags["binary_metadata"] = meta
    return bags


@pytest.mark.parametrize("case", ["magic_only", "binary_metadata"])
def test_broken_bag_is_one_line(tmp_path, case, capsys):
    bag = _broken_bags(tmp_path)[case]
    with pytest.raises(BagError) as err:
        replay(bag, progress=None)
    assert str(bag) in str(err.value)
    assert main(["replay", str(bag), "--quiet"]) == 2
    err_lines = [line for line in capsys.readouterr().err.strip().splitlines() if "error" in line]
    assert len(err_lines) == 1 and str(bag) in err_lines[0] and "Traceback" not in err_lines[0]


def test_garbage_in_the_middle_of_a_bag_skips_the_damaged_chunks_by_name(tmp_path, caplog):
    """4 KiB of garbage in the middle of a bag whose index is intact: each chunk it hits fails its CRC
    (or no longer decompresses) and is skipped with a warning naming the file and the chunk; the
    rest replays, nothing of the garbage is decoded, no traceback."""
    bag = _broken_bags(tmp_path)["corrupted_middle"]
    whole = replay(SAMPLE_BAG, progress=None).summary.inputs
    damaged = replay(bag, progress=None).summary.inputs
    assert 0 < damaged < whole
    caplog.clear()
    with caplog.at_level("WARNING"):
        assert main(["replay", str(bag), "--quiet"]) == 0
    named = [r.getMessage() for r in caplog.records if "the chunk at byte" in r.getMessage()]
    assert named and all(str(bag) in line and "skipped, not decoded" in line for line in named), caplog.text


@pytest.mark.parametrize("args, words", [
    (["solve", "--preset", "belarus_1221", "--set", "gravity=1e308"], "gravity"),
    (["solve", "--preset", "belarus_1221", "--pressure", "lift_cylinder=1e308"], "finite number"),
    (["solve", "--preset", "belarus_1221", "--stroke", "lift_cylinder=nan"], "finite number"),
    (["capacity", "--preset", "belarus_1221", "--points", "100000000"], "outside"),
    (["capacity", "--preset", "belarus_1221", "--stroke", "inf", "1"], "outside"),
    (["capacity", "--preset", "belarus_1221", "--plot", "/nonexistent/x.png"], "does not exist"),
    (["simulate", "--preset", "belarus_1221", "--rate", "1e-9"], "outside"),
    (["replay", str(SAMPLE_BAG), "--rate", "nan"], "outside"),
    (["replay", str(SAMPLE_BAG), "--out", "/nonexistent/run"], "does not exist"),
    (["calibrate", "--preset", "belarus_1221", "--data", "x.csv", "--free", "implement.mass", "--out",
      "/nonexistent/f.yaml"], "does not exist"),
])
def test_bad_argument_is_one_line_and_exit_2(args, words, capsys):
    with pytest.raises(SystemExit) as code:   # argparse's own error path
        raise SystemExit(main(args))
    assert code.value.code == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and words in err[0], err


def test_replay_with_the_wrong_mechanism_fails_saying_nothing_was_solved(capsys):
    assert main(["replay", str(REPO / "bags" / "damping_hitch_lift"), "--preset", "belarus_1221", "--quiet"]) == 1
    assert "no pose" in capsys.readouterr().err
