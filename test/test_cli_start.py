"""`linkage-monitor --help` and `presets` answer at once: the argparse set-up and the preset list load
neither numba, scipy, the compiled kernels nor the bag writer (each subcommand imports its own modules
when it runs; timings: bench/bench_cli_start.py)."""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
from pathlib import Path

import pytest

from linkage_monitor.cli.commands import COMMANDS
from linkage_monitor.cli.main import build_parser

HEAVY = ("numba", "scipy", "numpy", "linkage_monitor.bag", "linkage_monitor.mechanics.kernels",
         "linkage_monitor.mechanics.solver", "linkage_monitor.monitoring.core")
LOADED = """
import contextlib, io, json, sys
from linkage_monitor.cli.main import main
with contextlib.redirect_stdout(io.StringIO()):
    try:
        code = main(sys.argv[1:])
    except SystemExit as exit:   # --help
        code = exit.code
print(json.dumps({"code": code, "modules": sorted(sys.modules)}))
"""


def _loaded(*argv: str) -> tuple[int, list[str]]:
    """The exit code of ``linkage-monitor ARGV`` in a fresh interpreter and the modules it loaded."""
    run = subprocess.run([sys.executable, "-c", LOADED, *argv], capture_output=True, text=True, timeout=60, check=True)
    out = json.loads(run.stdout)
    return out["code"], out["modules"]


@pytest.mark.parametrize("argv", [["--help"], ["presets"], ["solve", "--help"]])
def test_the_answer_loads_no_heavy_module(argv) -> None:
    code, modules = _loaded(*argv)
    heavy = [m for m in modules if any(m == h or m.startswith(h + ".") for h in HEAVY)]
    if argv == ["solve", "--help"]:   # the subcommand's own options load its modules: the contrast
        assert code == 0 and "linkage_monitor.monitoring.core" in heavy
    else:
        assert code == 0 and heavy == [], heavy


def test_the_listing_is_each_subcommands_own_help() -> None:
    """The one-line helps `--help` shows without importing the subcommands (cli.commands) are the ones
    their own modules register (all imported here)."""
    sub = next(a for a in build_parser()._actions if isinstance(a, argparse._SubParsersAction))
    registered = {action.dest: action.help for action in sub._choices_actions}
    assert registered == {name: command.help for name, command in COMMANDS.items()}


def test_a_replay_that_weighs_nothing_loads_neither_student_quantile_nor_scipy_linalg() -> None:
    """scipy.special (~0.2 s to import) serves the weighing's Student factor only: a replay of a bag whose
    implement comes from its file (the bundled belarus_1221 bag) never loads it; a weighing replay does.
    The kernels' BLAS and LAPACK come without the rest of scipy.linalg (mechanics.numba_blas)."""
    bag = str(Path(__file__).resolve().parent.parent / "bags" / "belarus_1221_lift_transport")
    code, modules = _loaded("replay", bag, "--quiet")
    assert code == 0 and "scipy.special" not in modules and "scipy.linalg" not in modules
    assert "scipy.linalg.cython_blas" in modules and "scipy.linalg.cython_lapack" in modules
    code, modules = _loaded("replay", bag, "--quiet", "--implement-mass-source", "estimate")
    assert code == 0 and "scipy.special" in modules


def test_scipy_linalg_imports_after_the_kernels_took_its_blas_alone() -> None:
    """After the kernels ran on the BLAS and LAPACK loaded alone, ``import scipy.linalg`` (the calibration's
    least squares) imports the package whole, with those two modules as they are, and both still work."""
    script = """
import sys
import numpy as np
from linkage_monitor.mechanics.kernels import solve_linear
jac, rhs = np.array([[1.0, 0.0], [0.0, 2.0], [1.0, 1.0]]), np.array([1.0, 4.0, 3.0])
assert np.allclose(solve_linear(jac, rhs), [1.0, 2.0])   # least squares by jac.T @ rhs: numba's BLAS
blas = sys.modules["scipy.linalg.cython_blas"]
import scipy.linalg
from scipy.optimize import least_squares
assert sys.modules["scipy.linalg.cython_blas"] is blas
assert np.allclose(scipy.linalg.solve(np.eye(2) * 2.0, np.ones(2)), 0.5)
assert np.allclose(least_squares(lambda x: x - 3.0, np.zeros(1)).x, 3.0)
print("ok")
"""
    run = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=120, check=True)
    assert run.stdout.strip() == "ok"
