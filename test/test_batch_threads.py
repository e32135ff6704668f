"""solve_batch on numba's thread pool (the default for batches of ≥ PARALLEL_MIN poses) gives the
same numbers, bit for bit, as on the calling thread: each pose is solved by the same compiled code
whichever thread runs it."""

from __future__ import annotations

import dataclasses
import subprocess
import sys

import numpy as np
import pytest

from linkage_monitor.mechanics import Solver, kernels, load_preset, preset_names


def _fields(batch) -> dict:
    return {f.name: getattr(batch, f.name) for f in dataclasses.fields(batch)}


def _assert_identical(a, b, where: str) -> None:
    if isinstance(a, dict):
        assert a.keys() == b.keys(), where
        for key in a:
            _assert_identical(a[key], b[key], f"{where}/{key}")
    elif isinstance(a, np.ndarray):
        assert a.dtype == b.dtype and a.shape == b.shape, where
        assert a.tobytes() == b.tobytes(), where
    else:
        assert a == b, where


def test_threads_are_on_by_default():
    """In a fresh process (a test here may have turned them off, as the live node does)."""
    code = "from linkage_monitor.mechanics import kernels; print(kernels.threads_allowed())"
    assert subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout == "True\n"


@pytest.mark.parametrize("name", preset_names())
def test_threaded_batch_equals_serial(name):
    mech = load_preset(name)
    solver = Solver(mech)
    rng = np.random.default_rng(7)
    n = 2 * kernels.PARALLEL_MIN
    s_ref = solver.kin.reference_inputs()
    cylinders = {c: s_ref[k] * rng.uniform(0.9, 1.1, n) for k, c in enumerate(mech.measurements.cylinders)}
    nc = len(mech.measurements.cylinders)
    angles = {a.name: s_ref[nc + k] + rng.uniform(-0.3, 0.3, n) for k, a in enumerate(mech.measurements.angles)}
    pressures = {p.name: rng.uniform(-1e5, 2e7, n) for p in mech.measurements.pressures}
    for values in (*cylinders.values(), *angles.values(), *pressures.values()):
        values[::97] = np.nan   # some bad inputs among them
    allowed = kernels.threads_allowed()
    try:
        kernels.allow_threads(True)
        threaded = solver.solve_batch(cylinders, angles, pressures)
        kernels.allow_threads(False)
        serial = solver.solve_batch(cylinders, angles, pressures)
    finally:
        kernels.allow_threads(allowed)
    assert (threaded.status != 0).any() and (threaded.status == 0).any()   # both verdicts are compared
    _assert_identical(_fields(threaded), _fields(serial), name)
