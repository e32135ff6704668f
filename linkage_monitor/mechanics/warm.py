"""Compile the physics kernels ahead of use (``make`` runs this after installing): numba keeps the
machine code in an on-disk cache in the ``kernels`` package, so a node or a replay started later loads
it instead of compiling (first compile about a minute here; loading a warm cache well under 2 s).
The presets' input limits are swept into their cache too (``spans_cache``).

    .venv/bin/python -m linkage_monitor.mechanics.warm
"""

from __future__ import annotations

import importlib
import pkgutil
import sys
import time
from typing import Any

import numpy as np
from numba.core.registry import CPUDispatcher

from . import kernels
from .machine import MachineModel
from .presets import load_preset, preset_names
from .errors import LinkageError
from .limits import input_limits
from .results import Status
from .inputs import Inputs
from .solver import Solver
from .uncertainty import UncertaintyModel


def compiled_kernels() -> int:
    """How many kernel signatures this process has compiled (numba's cache misses) rather than
    loaded from the on-disk cache: nonzero after a start on a cold or unwritable cache."""
    modules = [importlib.import_module(f"{kernels.__name__}.{module.name}")
               for module in pkgutil.iter_modules(kernels.__path__)]
    return sum(sum(kernel.stats.cache_misses.values()) for module in modules for kernel in vars(module).values()
               if isinstance(kernel, CPUDispatcher))


def warm_up() -> float:
    """Solve every preset once per path (single pose warm-started, small and large batches, with
    rates, lift capacity, a recorded series, the error budget) and sweep its input limits; returns the
    seconds it took."""
    started = time.perf_counter()
    allowed = kernels.threads_allowed()
    kernels.allow_threads(True)   # compile the thread-pool drivers too
    for name in preset_names():
        mech = load_preset(name)
        input_limits(mech)
        solver = Solver(mech)
        model = MachineModel(mech, solver)
        ref = {k: dict(v) for k, v in mech.reference_inputs.items()}
        result = solver.solve(Inputs(**ref))
        solved = model.solve(Inputs(**ref), previous=result)
        model.value_rows([solved.result, result], [solved.machine, model.evaluate(result)])
        UncertaintyModel(model).budget(Inputs(**ref), solved.result, solved.machine)   # from a stroke's table or moved poses
        assert result.largest_force >= 0.0
        for n_pose in (2, kernels.PARALLEL_MIN):
            arrays: dict[str, Any] = {k: {n: np.full(n_pose, v) for n, v in group.items()} for k, group in ref.items()}
            names = list(arrays.get("cylinders", {})) + list(arrays.get("angles", {}))
            rates = {n: np.zeros(n_pose) for n in names}
            batch = solver.solve_batch(**arrays, rates=rates, accelerations=rates)
            assert (batch.status < Status.INPUT).all(), f"{name}: the reference pose should solve"
            model.evaluate_batch(batch)
            assert not (batch.largest_force < 0.0).any()
            model.solve_series(arrays.get("cylinders", {}), arrays.get("angles", {}), arrays.get("pressures", {}))
        # poses out of reach: the continuation from the reference pose and the reach bisection
        far = {"cylinders": {n: 1.6 * v for n, v in ref.get("cylinders", {}).items()},
               "angles": {n: v + 2.0 for n, v in ref.get("angles", {}).items()},
               "pressures": ref.get("pressures", {})}
        far_arrays: dict[str, Any] = {k: {n: np.full(2, v) for n, v in group.items()} for k, group in far.items()}
        solver.solve_batch(**far_arrays)
        try:
            solver.solve(Inputs(**far))
        except LinkageError:
            pass
    kernels.allow_threads(allowed)
    return time.perf_counter() - started


if __name__ == "__main__":
    print(f"physics kernels ready ({warm_up():.1f} s)", file=sys.stderr)
