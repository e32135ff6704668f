"""The `linkage-monitor` CLI: called in-process via main([...]) and as a subprocess."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from linkage_monitor.cli.main import main
from test_mechanics_oracles import FIXTURES

HITCH = str(FIXTURES / "hitch.yaml")
PYTHON = sys.executable   # the venv of the distribution under test (.venv or .venv-kilted)


def test_solve_json_has_the_documented_keys(capsys) -> None:
    assert main(["solve", "--mechanism", HITCH, "--stroke", "lift_cylinder=0.58", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert set(out) >= {"hinges", "cylinders", "points", "implement"}
    assert set(out["hinges"]["P03"]) == {"fx", "fz", "magnitude"}
    assert out["cylinders"]["lift_cylinder"]["length"] == pytest.approx(0.58, abs=1e-9)
    # the implement weight is the configured one when no pressure is given: 1200 kg · g (fixture)
    assert out["implement"]["weight"] == pytest.approx(1200 * 9.80665)


def test_set_and_pressure_options(capsys) -> None:
    assert main(["solve", "--mechanism", HITCH, "--set", "implement.mass=1530", "--json"]) == 0
    heavy = json.loads(capsys.readouterr().out)
    assert heavy["implement"]["weight"] == pytest.approx(1530 * 9.80665)
    assert main(["solve", "--mechanism", HITCH, "--pressure", "lift_cylinder=9e6:2e5", "--json"]) == 0
    measured = json.loads(capsys.readouterr().out)
    # schema: F = p_cap·A_cap − p_rod·A_rod with bore 0.11 m, rod 0.05 m (fixture)
    import math
    a_cap = math.pi * 0.11**2 / 4
    assert measured["cylinders"]["lift_cylinder"]["force"] == pytest.approx(9e6 * a_cap - 2e5 * (a_cap - math.pi * 0.05**2 / 4))


@pytest.mark.parametrize("argv, words", [
    (["solve", "--mechanism", HITCH, "--stroke", "lift_cylinder=abc"], ["lift_cylinder", "not a number"]),
    (["solve", "--mechanism", HITCH, "--stroke", "lift_cylinder=0.9"], ["lift_cylinder", "mm"]),
    (["solve", "--mechanism", HITCH, "--stroke", "lift_cyl=0.5"], ["lift_cyl", "unknown"]),
    (["solve", "--mechanism", HITCH, "--set", "implement.mass=-3"], ["implement.mass", ">= 0"]),
    (["solve", "--mechanism", "nope.yaml"], ["nope.yaml", "cannot read"]),
    (["solve", "--preset", "nope"], ["nope", "no such preset"]),
])
def test_bad_input_exit_2_one_line(capsys, argv, words) -> None:
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and all(w in err for w in words), err


@pytest.mark.slow
def test_subprocess_presets_and_solve() -> None:
    run = subprocess.run([PYTHON, "-m", "linkage_monitor.cli", "solve", "--mechanism", HITCH], capture_output=True,
                         text=True, timeout=60)
    assert run.returncode == 0 and "lift_cylinder" in run.stdout and "P03" in run.stdout
    bad = subprocess.run([PYTHON, "-m", "linkage_monitor.cli", "solve", "--mechanism", HITCH, "--stroke", "x"],
                         capture_output=True, text=True, timeout=60)
    assert bad.returncode == 2 and bad.stderr.count("\n") == 1
    presets = subprocess.run([PYTHON, "-m", "linkage_monitor.cli", "presets"], capture_output=True, text=True, timeout=60)
    assert presets.returncode == 0
    help_text = subprocess.run([PYTHON, "-m", "linkage_monitor.cli", "solve", "--help"], capture_output=True,
                               text=True, timeout=60).stdout
    assert "--pressure" in help_text and "CYL=CAP_PA[:ROD_PA]" in help_text
