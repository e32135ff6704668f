"""Calibration: recover a known perturbation of the belarus_1221 geometry from simulated data.

Oracle: the perturbation itself. The data come from the perturbed mechanism through the
telemetry simulator (``simulator.simulate``: lift cycle, angles + cap pressure vs. stroke with
the header's known mass); the fit starts from the unperturbed preset and must land on the
perturbed values (1 mm, 0.1 deg), through a CSV file and through a recorded bag.
"""

from __future__ import annotations

import argparse
import csv
from pathlib import Path

import numpy as np
import pytest

from linkage_monitor.cli.calibrate import add_calibrate_parser, run_calibrate
from linkage_monitor.mechanics import LinkageError, MechanismFileError, Solver, load_mechanism, load_preset
from linkage_monitor.mechanics.calibration import calibrate, parameter_value, with_parameters
from linkage_monitor.mechanics.capacity import stroke_mechanism
from linkage_monitor.bag.writer import BagWriter
from linkage_monitor.sim.telemetry import Noise, simulate

ATMOSPHERE = 101325.0  # Pa; FluidPressure carries absolute pressure
REFERENCE = "measurements.angles.lift_arm_angle.reference"
# the perturbation to recover: a few mm at the lower-link pivot and the rockshaft (lift arm pivot),
# 1 cm at the header cg, 0.5 deg on the lift-arm angle sensor's zero
PERTURBATION = {"points.P05.x": 0.003, "points.P05.z": -0.002, "points.P03.x": 0.002, "points.P03.z": 0.003,
                "points.S6.x": -0.010, "points.S6.z": 0.008, REFERENCE: np.radians(0.5)}


@pytest.fixture(scope="module")
def preset():
    return load_preset("belarus_1221")


@pytest.fixture(scope="module")
def truth(preset):
    return {k: parameter_value(preset, k) + d for k, d in PERTURBATION.items()}


@pytest.fixture(scope="module")
def stream(preset, truth):
    """One lift cycle of the perturbed hitch at 10 Hz, noise-free (126 samples, S 0.535-0.693 m)."""
    return simulate(with_parameters(preset, truth), "lift", rate_hz=10.0)


def _run(tmp_path: Path, data: Path, *extra: str) -> Path:
    parser = argparse.ArgumentParser()
    add_calibrate_parser(parser.add_subparsers(dest="command"))
    out = tmp_path / "fitted.yaml"
    args = parser.parse_args(["calibrate", "--preset", "belarus_1221", "--data", str(data),
                              "--free", ",".join(PERTURBATION), "--out", str(out), *extra])
    assert run_calibrate(args) == 0
    return out


def _assert_recovered(fitted_file: Path, truth: dict) -> None:
    fitted = load_mechanism(fitted_file)
    for key, expected in truth.items():
        tol = np.radians(0.1) if key == REFERENCE else 0.001   # the accuracy asked of a calibration: 1 mm and 0.1 deg
        assert parameter_value(fitted, key) == pytest.approx(expected, abs=tol), key


def test_csv_fit_recovers_the_perturbed_geometry(tmp_path, stream, truth, capsys):
    data = tmp_path / "lift.csv"
    with open(data, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["lift_cylinder", "lift_arm_angle", "pressure:lift_cap_pressure"])
        sim = stream.solver_inputs()
        w.writerows(zip(sim["cylinders"]["lift_cylinder"], sim["angles"]["lift_arm_angle"],
                        sim["pressures"]["lift_cap_pressure"]))
    out = _run(tmp_path, data)
    _assert_recovered(out, truth)
    assert "comments of the start file are lost" in out.read_text()
    assert "UNDETERMINED" not in capsys.readouterr().out


def test_bag_fit_recovers_the_perturbed_geometry(tmp_path, stream, truth):
    bag = tmp_path / "lift_bag"
    with BagWriter(bag) as writer:
        for i in range(len(stream)):
            stamp = int(stream.stamps_ns[i])
            writer.write("joint_states", stream.joint_state(i), stamp, log_time_ns=stamp)
            for name, msg in stream.pressures(i).items():   # absolute Pa = gauge + 101325
                writer.write(f"pressure/{name}", msg, stamp, log_time_ns=stamp + 1)
    _assert_recovered(_run(tmp_path, bag), truth)


def test_noisy_fit_is_within_its_reported_uncertainty(preset, truth):
    """With sensor noise (0.5 mrad, 20 kPa) the error of each parameter is within 4 reported sigmas."""
    noisy = simulate(with_parameters(preset, truth), "lift", rate_hz=10.0, noise=Noise(angle=5e-4, pressure=2e4), seed=3)
    sim = noisy.solver_inputs()
    data = {"lift_cylinder": sim["cylinders"]["lift_cylinder"], "lift_arm_angle": sim["angles"]["lift_arm_angle"],
            "pressure:lift_cap_pressure": sim["pressures"]["lift_cap_pressure"]}
    res = calibrate(preset, data, list(PERTURBATION),
                    sigma={"lift_arm_angle": 5e-4, "pressure:lift_cap_pressure": 2e4})
    for p, value, sigma in zip(res.parameters, res.values, res.uncertainty):
        assert 0.0 < sigma and abs(value - truth[p.key]) <= 4.0 * sigma, p.key
    assert res.rms["lift_arm_angle"] == pytest.approx(5e-4, rel=0.3)   # residual = the injected noise
    assert res.rms["pressure:lift_cap_pressure"] == pytest.approx(2e4, rel=0.3)


def test_mass_and_bore_are_reported_undetermined(preset):
    """Virtual work: count·p·A_cap·dS = m·g·dz_S6, so pressures fix only m / bore²; P05 stays determined."""
    heavier = with_parameters(preset, {"implement.mass": 1600.0, "points.P05.x": -0.222})
    sim = simulate(heavier, "lift", rate_hz=10.0).solver_inputs()
    data = {"lift_cylinder": sim["cylinders"]["lift_cylinder"],
            "pressure:lift_cap_pressure": sim["pressures"]["lift_cap_pressure"]}
    res = calibrate(preset, data, ["points.P05.x", "implement.mass", "cylinders.lift_cylinder.bore"])
    assert res.undetermined == ["implement.mass", "cylinders.lift_cylinder.bore"]


def test_point_height_columns_fix_the_lower_link_pivot(preset):
    """x:P56 / z:P56 (hitch axis) over the stroke recover a 3 mm / -2 mm shift of the lower-link pivot P05."""
    truth = {"points.P05.x": -0.222, "points.P05.z": 0.486}
    moved = stroke_mechanism(with_parameters(preset, truth))
    s = np.linspace(0.52, 0.71, 20)
    p56 = Solver(moved).solve_batch(cylinders={"lift_cylinder": s}).points["P56"]
    res = calibrate(preset, {"lift_cylinder": s, "x:P56": p56[:, 0], "z:P56": p56[:, 1]}, list(truth))
    assert res.values == pytest.approx(list(truth.values()), abs=1e-4)
    assert res.undetermined == []


@pytest.mark.parametrize("key, words", [
    ("points.P05", "name one coordinate"),
    ("implement.cg.x", "points.S6.x"),
    ("points.P99.x", "'P99' is not set"),
    ("cylinders.lift_cyl.bore", "no item named 'lift_cyl'"),
])
def test_bad_parameter_keys_say_what_to_write(preset, key, words):
    with pytest.raises(MechanismFileError, match=words):
        parameter_value(preset, key)


def test_invalid_parameter_value_is_rejected_by_the_schema(preset):
    with pytest.raises(MechanismFileError, match="bore"):
        with_parameters(preset, {"cylinders.lift_cylinder.bore": -0.08})


@pytest.mark.parametrize("rows, words", [
    ("lift_cylinder,z:P99\n0.55,0.4\n", "data column 'z:P99' is not understood"),
    ("lift_cylinder,lift_arm_angle\n0.55,abc\n", "row 2, column 'lift_arm_angle'"),
    ("lift_cylinder\n0.55\n", "add a measured column"),
])
def test_bad_data_is_a_linkage_error_naming_the_problem(tmp_path, rows, words):
    """cli.main turns a LinkageError into exit code 2 and one line on stderr."""
    data = tmp_path / "bad.csv"
    data.write_text(rows)
    with pytest.raises(LinkageError, match=words):
        _run(tmp_path, data)


def test_missing_data_file_is_a_linkage_error(tmp_path):
    with pytest.raises(LinkageError, match="cannot read"):
        _run(tmp_path, tmp_path / "nothing.csv")
