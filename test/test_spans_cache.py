"""The swept spans of the input limits kept on disk (mechanics.spans_cache): read back bit for bit
as swept, swept again for any other description, sweep parameter or physics code, a malformed
entry or an unwritable directory passed over, the oldest entries removed."""

from __future__ import annotations

import copy
import json
import os
import shutil

import pytest

from linkage_monitor.mechanics import load_preset, mechanism_from_dict, preset_names
from linkage_monitor.mechanics import limits, spans_cache
from linkage_monitor.mechanics.limits import input_limits


@pytest.fixture
def cache(tmp_path, monkeypatch):
    """A fresh cache directory, no spans kept in this process, and a count of the sweeps run."""
    monkeypatch.setenv(spans_cache.CACHE_ENV, str(tmp_path))
    monkeypatch.setattr(limits, "_SPANS", {})
    sweeps = []
    sweep = limits._swept_spans

    def counted(mech):
        sweeps.append(mech.name)
        return sweep(mech)

    monkeypatch.setattr(limits, "_swept_spans", counted)
    return tmp_path / "input_spans", sweeps


def entries(directory):
    return sorted(directory.glob("*.json"))


@pytest.mark.parametrize("preset", preset_names())
def test_spans_read_back_are_the_swept_ones_bit_for_bit(cache, preset):
    directory, sweeps = cache
    mech = load_preset(preset)
    swept = input_limits(mech)
    assert sweeps == [mech.name] and len(entries(directory)) == 1
    limits._SPANS.clear()   # as in a process started again
    read = input_limits(mech)
    assert sweeps == [mech.name]   # not swept again
    assert read == swept   # Limit is a dataclass: every bound equal as a float, bit for bit
    assert all(type(limit.lo) is float and type(limit.hi) is float for limit in read.values())


def test_another_description_parameter_or_code_is_swept_again(cache, monkeypatch):
    directory, sweeps = cache
    mech = load_preset("belarus_1221")
    input_limits(mech)
    raw = copy.deepcopy(dict(mech.raw))
    point = next(iter(raw["points"]))
    raw["points"][point] = [raw["points"][point][0] + 1e-3, raw["points"][point][1]]   # one point moved 1 mm
    moved = mechanism_from_dict(raw)
    limits._SPANS.clear()
    input_limits(moved)
    assert len(sweeps) == 2
    limits._SPANS.clear()
    monkeypatch.setattr(limits, "SWEEP_POINTS", limits.SWEEP_POINTS + 10)
    input_limits(mech)
    assert len(sweeps) == 3
    limits._SPANS.clear()
    monkeypatch.setattr(spans_cache, "code_fingerprint", lambda: "the physics code changed")
    input_limits(mech)
    assert len(sweeps) == 4
    assert len(entries(directory)) == 4
    monkeypatch.undo()   # the first description, parameters and code again: read back
    monkeypatch.setenv(spans_cache.CACHE_ENV, str(directory.parent))
    monkeypatch.setattr(limits, "_SPANS", {})
    monkeypatch.setattr(limits, "_swept_spans", lambda mech: pytest.fail("swept again"))
    assert input_limits(mech)["lift_cylinder"].source == "geometry"


def test_the_fingerprint_follows_every_source_file(tmp_path):
    copied = tmp_path / "mechanics"
    shutil.copytree(spans_cache.PACKAGE, copied, ignore=shutil.ignore_patterns("__pycache__"))
    assert spans_cache.code_fingerprint(copied) == spans_cache.code_fingerprint()
    (copied / "solver.py").write_text((copied / "solver.py").read_text() + "\n# one more line\n")
    changed = spans_cache.code_fingerprint.__wrapped__(copied)
    assert changed != spans_cache.code_fingerprint()
    (copied / "kernels_added").mkdir()
    (copied / "kernels_added" / "more.py").write_text("")
    assert spans_cache.code_fingerprint.__wrapped__(copied) != changed   # a new module in a subpackage counts


@pytest.mark.parametrize("entry", ["not json", json.dumps([1.0, 2.0]), json.dumps({"lift_cylinder": [0.7, 0.5]}),
                                   json.dumps({"lift_cylinder": [0.5, float("nan")]}),
                                   json.dumps({"lift_cylinder": [0.5, 0.7], "no_such_input": [0.0, 1.0]}),
                                   json.dumps({"lift_cylinder": ["0.5", 0.7]})])
def test_a_malformed_entry_is_swept_again_and_replaced(cache, entry):
    directory, sweeps = cache
    mech = load_preset("belarus_1221")
    swept = input_limits(mech)
    [path] = entries(directory)
    path.write_text(entry)
    limits._SPANS.clear()
    assert input_limits(mech) == swept
    assert len(sweeps) == 2
    assert spans_cache.load(path.stem, ["lift_cylinder", "lift_arm_angle"]) is not None   # replaced


def test_an_unwritable_cache_is_passed_over(cache, monkeypatch, tmp_path):
    _, sweeps = cache
    blocker = tmp_path / "a_file"
    blocker.write_text("")
    monkeypatch.setenv(spans_cache.CACHE_ENV, str(blocker))   # input_spans cannot be made under a file
    mech = load_preset("belarus_1221")
    swept = input_limits(mech)
    limits._SPANS.clear()
    assert input_limits(mech) == swept
    assert len(sweeps) == 2


def test_the_oldest_entries_beyond_kept_are_removed(cache, monkeypatch):
    directory, _ = cache
    monkeypatch.setattr(spans_cache, "KEPT", 2)
    for age, key in ((300, "first"), (200, "second"), (0, "third")):
        spans_cache.store(key, {"lift_cylinder": (0.5, 0.7)})
        written = directory / f"{key}.json"
        os.utime(written, (written.stat().st_mtime - age, written.stat().st_mtime - age))
    assert [path.stem for path in entries(directory)] == ["second", "third"]
