"""Every shipped parameter file starts the node, which declares its parameters with
descriptors and publishes its mechanism description (transient local, for late joiners)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest
import rclpy
import yaml
from rcl_interfaces.srv import DescribeParameters

from linkage_monitor.mechanics import preset_names
from support.ros_harness import MonitorClient, stop

CONFIG = Path(__file__).resolve().parent.parent / "config"
LAUNCH = Path(__file__).resolve().parent.parent / "launch" / "monitor.launch.py"


def test_a_config_file_per_preset():
    assert sorted(p.stem for p in CONFIG.glob("*.yaml")) == sorted(preset_names())


@pytest.mark.parametrize("preset", ["belarus_1221", "ksu1_mower_adapter"])
def test_launch_file_starts_node_with_params_and_descriptors(preset, tmp_path):
    params = yaml.safe_load((CONFIG / f"{preset}.yaml").read_text())["/linkage_monitor"]["ros__parameters"]
    params["record_dir"] = str(tmp_path)
    params_file = tmp_path / "params.yaml"
    params_file.write_text(yaml.safe_dump({"/linkage_monitor": {"ros__parameters": params}}))
    proc = subprocess.Popen([sys.executable, str(LAUNCH), "--params", str(params_file)],
                            stdout=(tmp_path / "node.log").open("w"), stderr=subprocess.STDOUT)
    rclpy.init()
    try:
        client = MonitorClient(pressure_topics=())
        assert client.spin_until(lambda: bool(client.received["mechanism_description"]), 30), \
            (tmp_path / "node.log").read_text()
        description = yaml.safe_load(client.received["mechanism_description"][0].data)
        assert description["name"] == preset
        describe = client.node.create_client(DescribeParameters, "/linkage_monitor/describe_parameters")
        assert describe.wait_for_service(timeout_sec=10)
        future = describe.call_async(DescribeParameters.Request(names=["mechanism", "staleness_limit"]))
        client.spin_until(future.done, 10)
        mech, staleness = future.result().descriptors
        assert mech.read_only and "preset" in mech.description.lower()
        assert not staleness.read_only and staleness.floating_point_range[0].to_value > 0
        client.close()
    finally:
        rclpy.shutdown()
        assert stop(proc) == 0, (tmp_path / "node.log").read_text()


@pytest.mark.parametrize("param, expect", [("mechanism:=/no/such/tractor.yaml", "cannot read the file"),
                                           ("sensor_qos:=fast", "expected one of sensor_data, reliable"),
                                           ("reliable_queue_depth:=0", "reliable_queue_depth out of range"),
                                           ("dead_centre_transmission_deg:=50.0",
                                            "dead_centre_transmission_deg out of range"),
                                           ("dead_centre_transmission_deg:=45.0000001",   # rclpy's range lets it pass
                                            "dead_centre_transmission_deg = 45.0000001: outside its range [0, 45] "
                                            "degrees"),
                                           ("stamp_tolerance:=2000000", "stamp_tolerance out of range"),   # an integer
                                           ("tractor_mass:=-0.5", "tractor_mass = -0.5: a value must be >= 0"),
                                           ("implement_mass_source:=scale",
                                            "implement_mass_source 'scale': expected one of file, estimate"),
                                           ("implement:=no_such_implement",
                                            "no_such_implement: no such implement file or bundled implement")])
def test_bad_parameter_exits_2_with_one_line_on_stderr(param, expect):
    proc = subprocess.run([sys.executable, "-m", "linkage_monitor.ros.node", "--ros-args", "-p", "record:=false",
                           "-p", param], capture_output=True, text=True, timeout=60)
    assert proc.returncode == 2
    lines = [line for line in proc.stderr.splitlines() if line.startswith("linkage_monitor_node:")]
    assert len(lines) == 1 and expect in lines[0], proc.stderr
    assert "Traceback" not in proc.stderr, proc.stderr


def test_weighing_and_uncertainty_parameters_reach_the_monitor_config():
    """The node's `implement`, `implement_mass_source` and `uncertainty` parameters set the MonitorConfig fields
    the monitor reads (at start and as a runtime change), so the node judges as `replay --uncertainty
    --implement-mass-source` does."""
    from linkage_monitor.mechanics import load_preset
    from linkage_monitor.ros.parameters import PARAMETERS, config_with, monitor_config

    params = {name: d.default for name, d in PARAMETERS.items()}
    mech = load_preset("belarus_1221")
    start = monitor_config({**params, "implement": "zhsk4v_header", "implement_mass_source": "estimate",
                            "uncertainty": True}, mech, lambda topic: "/" + topic)
    assert (start.implement, start.implement_mass_source, start.uncertainty) == ("zhsk4v_header", "estimate", True)
    default = monitor_config(params, mech, lambda topic: "/" + topic)
    assert (default.implement, default.implement_mass_source, default.uncertainty) == ("", "file", False)
    changed = config_with(default, {"uncertainty": True, "implement_mass_source": "estimate_when_confident"})
    assert (changed.uncertainty, changed.implement_mass_source) == (True, "estimate_when_confident")
