"""The `linkage-monitor` CLI: called in-process via main([...]) and as a subprocess."""

from __future__ import annotations

import json
import math
import subprocess
import sys
from pathlib import Path

import pytest

from linkage_monitor.cli.main import main
from linkage_monitor.mechanics import load_preset
from linkage_monitor.mechanics.capacity import stroke_mechanism
from linkage_monitor.mechanics.constants import ATMOSPHERIC_PRESSURE
from linkage_monitor.monitoring.config import MonitorConfig
from linkage_monitor.monitoring.core import Monitor
from linkage_monitor.monitoring.events import JointStateEvent, PressureEvent
from support.fixtures import FIXTURES

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
    a_cap = math.pi * 0.11**2 / 4
    assert measured["cylinders"]["lift_cylinder"]["force"] == pytest.approx(9e6 * a_cap - 2e5 * (a_cap - math.pi * 0.05**2 / 4))


@pytest.mark.parametrize("argv, words", [
    (["solve", "--mechanism", HITCH, "--stroke", "lift_cylinder=abc"], ["lift_cylinder", "not a number"]),
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


# ---- one verdict: the CLI says what the node's monitor says ------------------------------------------------
NODE_STAMP = 1_700_000_000_000_000_000   # ns; any stamp, the node's receive time equal to it


def _node_findings(preset: str, overrides: dict, cylinders: dict, angles: dict, pressures: dict,
                   monitor: Monitor | None = None) -> list[dict]:
    """The findings of the node's monitor on one pose: its default configuration with ``overrides`` as
    runtime parameters give them (``MonitorConfig.overrides``), the pressures as FluidPressure (absolute
    Pa) on their default topics, then one JointState (``monitor``: one that has seen the poses before)."""
    if monitor is None:
        mech = load_preset(preset)
        monitor = Monitor(mech, MonitorConfig.default(preset, mech).with_overrides(overrides))
    config = monitor.config
    topic = {sensor: t for t, sensor in config.pressure_topics.items()}
    for name, gauge in pressures.items():
        monitor.step(PressureEvent(topic[name], gauge + ATMOSPHERIC_PRESSURE, NODE_STAMP, NODE_STAMP))
    joints = {**cylinders, **angles}
    step = monitor.step(JointStateEvent("/joint_states", list(joints), list(joints.values()), [], NODE_STAMP,
                                        NODE_STAMP))
    return [{"level": f.level.name, "code": f.code.ident, "message": f.text} for f in step.findings]


BELARUS_REFERENCE = {"cylinders": {"lift_cylinder": 0.535}, "angles": {"lift_arm_angle": -2.7747},
                     "pressures": {"lift_cap_pressure": 10.132e6}}   # the preset's reference_inputs


@pytest.mark.parametrize("options, overrides, pose, level", [
    ([], {}, {}, "OK"),
    # a 1 kg tractor with 10 t of front ballast: the rear axle lifts off (rear axle load < 0)
    (["--set", "tractor.mass=1", "--set", "tractor.front_ballast.mass=10000"],
     {"tractor.mass": 1.0, "tractor.front_ballast.mass": 10000.0}, {}, "ERROR"),
    # 16 MPa in the lift cylinder: an implement load above the lift capacity at its cg, steerability low
    (["--pressure", "lift_cylinder=1.6e7"], {}, {"pressures": {"lift_cap_pressure": 1.6e7}}, "WARN"),
    # stroke and angle 0.37 rad apart: no closed linkage fits both
    (["--stroke", "lift_cylinder=0.6", "--angle", "lift_arm_angle=-2.9"], {},
     {"cylinders": {"lift_cylinder": 0.6}, "angles": {"lift_arm_angle": -2.9}}, "ERROR"),
])
def test_solve_says_what_the_node_says(capsys, options, overrides, pose, level) -> None:
    code = main(["solve", "--preset", "belarus_1221", *options, "--json"])
    out = json.loads(capsys.readouterr().out)
    inputs = {**BELARUS_REFERENCE, **pose}
    node = _node_findings("belarus_1221", overrides, inputs["cylinders"], inputs["angles"], inputs["pressures"])
    assert out["findings"] == node and out["level"] == level
    assert code == (1 if level == "ERROR" else 0)   # exit 1: the monitor's verdict is ERROR (--help's epilog)
    assert level == "OK" or node


def test_axle_lift_off_is_printed_and_exits_1(capsys) -> None:
    assert main(["solve", "--preset", "belarus_1221", "--set", "tractor.mass=1",
                 "--set", "tractor.front_ballast.mass=10000"]) == 1
    out = capsys.readouterr().out
    assert "verdict ERROR" in out and "ERROR axle_lift_off: rear axle load -" in out and "status ok" not in out


def test_out_of_range_stroke_is_the_nodes_refusal(capsys) -> None:
    assert main(["solve", "--mechanism", HITCH, "--stroke", "lift_cylinder=0.9", "--json"]) == 1
    findings = json.loads(capsys.readouterr().out)["findings"]
    assert [f["code"] for f in findings] == ["out_of_range"] and "lift_cylinder" in findings[0]["message"]


def test_capacity_says_what_the_node_says_at_every_length(capsys) -> None:
    """The sweep's poses judged by the CLI (batched, as the replay) equal the node's live steps, pose by pose;
    0.45 m is below the stroke's plausible range (0.4828 m, from the geometry): out_of_range, exit 1."""
    code = main(["capacity", "--preset", "belarus_1221", "--stroke", "0.45", "0.52", "--points", "8", "--json"])
    curve = json.loads(capsys.readouterr().out)
    sweep = stroke_mechanism(load_preset("belarus_1221"))
    monitor = Monitor(sweep, MonitorConfig.default("belarus_1221", sweep))
    node = [_node_findings("belarus_1221", {}, {"lift_cylinder": s}, {}, {}, monitor) for s in curve["length"]]
    assert curve["findings"] == node
    assert curve["findings"][0][0]["code"] == "out_of_range" and curve["verdict"] == "ERROR" and code == 1
    assert any(level == "WARN" for level in curve["level"])   # lift_reserve_low low on the stroke


# ---- solve from any sufficient set of measurements ----------------------------------------------------------
# Whether one measured input alone fixes the preset's pose (its YAML's measurements): belarus_1221 is one DOF
# measured twice (stroke and rockshaft angle), drill_coulter and ttz1080_base_change one DOF measured once,
# damping_hitch two (lift cylinder; the element's stroke closes the sub-frame), ksu1_mower_adapter three (two
# locked cylinders and the float lever).
ALONE_FIXES_THE_POSE = {
    "belarus_1221": {"lift_cylinder": True, "lift_arm_angle": True},
    "damping_hitch": {"lift_cylinder": False, "damping_element": False},
    "drill_coulter": {"upper_link_angle": True},
    "ksu1_mower_adapter": {"lift_cylinder": False, "tilt_cylinder": False, "float_lever_angle": False},
    "ttz1080_base_change": {"base_change_cylinder": True},
}


def _option(preset: str, name: str) -> str:
    return "--stroke" if name in load_preset(preset).measurements.cylinders else "--angle"


@pytest.mark.parametrize("preset, name", [(p, n) for p, names in ALONE_FIXES_THE_POSE.items() for n in names])
def test_one_measurement_at_its_reference_value(capsys, preset, name) -> None:
    """Alone at its reference value, a measurement that fixes the pose predicts the others' reference values
    (the presets' reference_inputs are consistent: to 1e-4 m / rad, the precision of belarus_1221's fitted
    angle) and the node finds nothing amiss with them; one that does not names every missing measurement."""
    mech = load_preset(preset)
    reference = {**mech.reference_inputs.get("cylinders", {}), **mech.reference_inputs.get("angles", {})}
    code = main(["solve", "--preset", preset, _option(preset, name), f"{name}={reference[name]}", "--json"])
    out, err = capsys.readouterr()
    others = [n for n in reference if n != name]
    if ALONE_FIXES_THE_POSE[preset][name]:
        result = json.loads(out)
        assert sorted(result["predicted"]) == sorted(others)
        assert result["predicted"] == pytest.approx({n: reference[n] for n in others}, abs=1e-4)
        assert code == 0 and result["level"] == "OK", result["findings"]
    else:
        assert code == 2 and err.count("\n") == 1 and name in err
        assert all(f"{_option(preset, n)} {n}=" in err for n in others), err


def test_the_readme_example_places_the_lift_arm(capsys) -> None:
    """`solve --preset belarus_1221 --stroke lift_cylinder=0.6` (README): the lift-arm angle is predicted and
    the node, given both, finds them consistent; given both at other values, it says they disagree."""
    assert main(["solve", "--preset", "belarus_1221", "--stroke", "lift_cylinder=0.6", "--json"]) == 0
    alone = json.loads(capsys.readouterr().out)
    angle = alone["predicted"]["lift_arm_angle"]
    assert alone["findings"] == [] and alone["cylinders"]["lift_cylinder"]["length"] == pytest.approx(0.6, abs=1e-9)
    assert main(["solve", "--preset", "belarus_1221", "--stroke", "lift_cylinder=0.6", "--angle",
                 f"lift_arm_angle={angle!r}", "--json"]) == 0
    both = json.loads(capsys.readouterr().out)
    magnitudes = [{n: h["magnitude"] for n, h in pose["hinges"].items()} for pose in (alone, both)]
    assert both["predicted"] == {} and magnitudes[1] == pytest.approx(magnitudes[0], rel=1e-6)
    # the rockshaft 2° off: a misfit above the node's 1.5 mm (checks.CONSISTENCY_WARN_M: 1° adds 1.8-2.6 mm)
    assert main(["solve", "--preset", "belarus_1221", "--stroke", "lift_cylinder=0.6", "--angle",
                 f"lift_arm_angle={angle + math.radians(2.0)!r}", "--json"]) == 0
    assert [f["code"] for f in json.loads(capsys.readouterr().out)["findings"]] == ["sensors_disagree"]


def test_a_missing_measurement_of_several_is_named(capsys) -> None:
    assert main(["solve", "--preset", "ksu1_mower_adapter", "--stroke", "lift_cylinder=0.4763402",
                 "--stroke", "tilt_cylinder=0.7648529"]) == 2
    err = capsys.readouterr().err
    assert "--angle float_lever_angle=RAD" in err and "--stroke" not in err.split("give also")[1], err


@pytest.mark.slow
def test_a_closed_pipe_keeps_the_verdicts_exit_code() -> None:
    """`linkage-monitor solve ... | head -0`: nothing printed, no traceback, and still exit 1 for an ERROR."""
    run = subprocess.Popen([PYTHON, "-m", "linkage_monitor.cli", "solve", "--preset", "belarus_1221", "--set",
                            "tractor.mass=1", "--set", "tractor.front_ballast.mass=10000"],
                           stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    assert run.stdout is not None
    run.stdout.close()   # the reader is gone before anything is printed
    _, err = run.communicate(timeout=120)
    assert run.returncode == 1 and "Traceback" not in err and "BrokenPipe" not in err, err
