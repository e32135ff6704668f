"""The error budget of the ``belarus_1221`` hitch over its lift stroke as a picture (docs/accuracy.md).

    .venv/bin/python tools/accuracy_plot.py --out docs/accuracy_belarus_1221.png

The poses are the simulator's noise-free lift (``sim.telemetry``: the 15 kN header raised from the
work position to transport, its cap pressure holding it), every one judged standing (the seal
friction's whole breakaway band) with the preset's default error sources.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from linkage_monitor.mechanics import Inputs, Solver, load_preset
from linkage_monitor.mechanics.error_sources import Motion
from linkage_monitor.mechanics.machine import MachineModel
from linkage_monitor.mechanics.uncertainty import UncertaintyModel
from linkage_monitor.monitoring.core import ASSEMBLY_LIMIT_M
from linkage_monitor.sim.telemetry import simulate
from linkage_monitor.viz.budget_plot import plot_budget

PRESET = "belarus_1221"
OUTPUTS = ("implement_load", "steerability_margin", "lift_capacity.implement_cg", "P03.magnitude")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=Path("docs/accuracy_belarus_1221.png"))
    args = parser.parse_args(argv)
    mech = load_preset(PRESET)
    model = MachineModel(mech, Solver(mech, consistency_tol=ASSEMBLY_LIMIT_M))   # the monitor's solver
    um = UncertaintyModel(model)
    stream = simulate(mech, "lift", rate_hz=25.0)
    raise_phase = np.flatnonzero(stream.truth.phase == "raise")
    columns = stream.solver_inputs()
    lengths, budgets = [], []
    for i in raise_phase.tolist():
        inputs = Inputs(**{kind: {n: float(v[i]) for n, v in group.items()} for kind, group in columns.items()})
        pose = model.solve(inputs)
        budgets.append(um.budget(inputs, pose.result, pose.machine, Motion.STANDING))
        lengths.append(inputs.cylinders["lift_cylinder"])
    plot_budget(np.array(lengths), budgets, OUTPUTS, "lift cylinder length S [m]",
                f"{PRESET}: error budget over the lift stroke (15 kN header, standing, default sources)", args.out)
    print(f"wrote {args.out} ({len(budgets)} poses)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
