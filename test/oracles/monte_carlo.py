"""Monte Carlo oracle of the first-order error budget (``mechanics.uncertainty``): the declared sources
drawn, the perturbed readings solved, the spread of every output measured.

Per sample, each source of the pose's budget is drawn from its distribution: bias and noise normal
(σ = u), resolution uniform over one step (±√3·u), seal friction uniform over its band (±√3·u, N,
entered as the pressure that carries it). The samples are solved as one series by the same
``MachineModel`` (each from the one before); the standard deviation of each output over the samples
is the Monte Carlo standard uncertainty. SI units.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from linkage_monitor.mechanics import LinkageError, Mechanism, Solver, load_preset
from linkage_monitor.mechanics.geometry_budget import series_rows
from linkage_monitor.mechanics.machine import MachineModel, MachinePose
from linkage_monitor.mechanics.inputs import Inputs
from linkage_monitor.mechanics.budget import Budget
from linkage_monitor.mechanics.output_table import force_per_pressure
from linkage_monitor.mechanics.uncertainty import UncertaintyModel
from linkage_monitor.monitoring.core import ASSEMBLY_LIMIT_M
from linkage_monitor.sim.telemetry import simulate
from linkage_monitor.sim.true_geometry import draw_geometry

SCENARIO = {"ksu1_mower_adapter": "field_copy", "drill_coulter": "relief"}   # the simulator's; the others: "lift"
# below this share of max(1, |value|) the Monte Carlo u is negligible: an output at its extremum along the
# stroke (a lift capacity at its largest, a hinge magnitude at its smallest), where the first-order u
# tends to 0 and the spread is second order
NEGLIGIBLE = 1e-5
REFUSED_SHARE = 0.01   # above this share of refused samples the Monte Carlo spread is cut short
UNIFORM = {"resolution", "friction"}   # the parts drawn uniform (±√3·u); the others normal


@dataclass(frozen=True)
class MonteCarlo:
    """The spread of every output over ``samples`` draws: ``u`` (n_out,) the standard deviation of the
    solved samples, ``failed`` how many samples did not solve."""

    u: np.ndarray
    samples: int
    failed: int

    @property
    def truncated(self) -> bool:
        """More than REFUSED_SHARE of the samples were refused (e.g. a chamber pressure near vacuum,
        where the errors drive readings below −1 atm gauge): the spread of the rest is cut short, no
        measure of the pose's u."""
        return self.failed > REFUSED_SHARE * self.samples


def geometry_pool(um: UncertaintyModel, size: int, rng: np.random.Generator) -> list[MachineModel]:
    """``size`` models of ``um``'s mechanism with its points drawn from their tolerances (``sim.true_geometry``),
    each solved as the monitor's is: a sample takes one of them (empty without point tolerances)."""
    pool = []
    for _ in range(size if um.geometry.sources else 0):
        drawn = draw_geometry(um.mech, um.sources, rng, um.model.solver)
        assert drawn is not None
        pool.append(drawn.model)
    return pool


def monte_carlo(um: UncertaintyModel, inputs: Inputs, budget: Budget, samples: int, rng: np.random.Generator,
                pool: list[MachineModel] | None = None) -> MonteCarlo:
    """Draw the sources of ``budget`` (the first-order budget of ``inputs``) ``samples`` times, solve; the
    point coordinates (where the budget has them) by the models of ``pool`` (``geometry_pool``), sample i
    solved by model i mod len(pool), the readings held as the sensors read them."""
    readings = {kind: {name: np.full(samples, float(v)) for name, v in getattr(inputs, kind).items()}
                for kind in ("cylinders", "angles", "pressures")}
    kind_of = {name: kind for kind, group in readings.items() for name in group}
    for source in budget.sources:
        draw = (rng.uniform(-math.sqrt(3.0), math.sqrt(3.0), samples) if source.part in UNIFORM
                else rng.standard_normal(samples)) * source.u
        if source.part == "friction":
            sensor = um.friction_sensor(source.input, inputs)
            assert sensor is not None
            readings["pressures"][sensor] += draw / force_per_pressure(um.mech, sensor)
        elif source.part == "mass":
            raise ValueError("the Monte Carlo oracle does not draw the implement mass")
        elif source.part == "position":
            continue   # drawn by the pool's models
        else:
            readings[kind_of[source.input]][source.input] += draw
    if any(source.part == "position" for source in budget.sources):
        assert pool, "point tolerances need a geometry_pool"
    models = pool if pool and any(source.part == "position" for source in budget.sources) else [um.model]
    rows = np.empty((samples, len(um.table.outputs)))
    for k, model in enumerate(models):
        part = slice(k, samples, len(models))
        series = model.solve_series(*({name: v[part] for name, v in readings[kind].items()}
                                      for kind in ("cylinders", "angles", "pressures")))
        rows[part] = series_rows(um.table, model, series)
    solved = np.isfinite(rows).any(axis=1)
    return MonteCarlo(np.std(rows[solved], axis=0, ddof=1), samples, int(np.count_nonzero(~solved)))


def comparable(budget: Budget, mc: MonteCarlo) -> np.ndarray:
    """The outputs (n_out,) whose first-order u is held to the Monte Carlo one: both finite, the Monte
    Carlo u above NEGLIGIBLE of max(1, |value|)."""
    return (np.isfinite(budget.u) & np.isfinite(mc.u)
            & (mc.u > NEGLIGIBLE * np.maximum(1.0, np.abs(budget.values))))


@dataclass(frozen=True)
class SampledPoses:
    """Solved poses of a preset: its mechanism, its model and (inputs, pose) pairs."""

    mechanism: Mechanism
    model: MachineModel
    poses: list[tuple[Inputs, MachinePose]]


def sample_poses(preset: str, count: int, rng: np.random.Generator) -> SampledPoses:
    """``count`` random poses of ``preset`` that solve by the monitor's solver: samples of the simulator's
    scenario for it (its noise-free inputs at 100 Hz; a chamber at exactly 0 gauge, e.g. ttz1080's rod
    chamber at tank, is not given — the schema then takes it at tank — since its sensor's errors would
    read below vacuum in a share of the draws, which the monitor refuses; a pose the monitor refuses,
    e.g. a negative chamber pressure or a dead centre, has no budget and is passed over)."""
    mech = load_preset(preset)
    model = MachineModel(mech, Solver(mech, consistency_tol=ASSEMBLY_LIMIT_M))   # the monitor's solver
    stream = simulate(mech, SCENARIO.get(preset, "lift"), rate_hz=100.0)
    columns = stream.solver_inputs()
    poses = []
    for i in rng.permutation(len(stream)).tolist():
        inputs = Inputs(**{kind: {n: float(v[i]) for n, v in group.items()
                                  if not (kind == "pressures" and v[i] == 0.0)}   # at tank: read as tank
                           for kind, group in columns.items()})
        try:
            poses.append((inputs, model.solve(inputs)))
        except LinkageError:
            continue
        if len(poses) == count:
            return SampledPoses(mech, model, poses)
    raise ValueError(f"{preset}: fewer than {count} poses of its scenario solve")
