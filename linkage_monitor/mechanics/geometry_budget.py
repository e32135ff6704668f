"""Geometry tolerances in the error budget: the derivative of every output with respect to each declared
point coordinate (``error_sources.points``), tabulated once per mechanism over its stroke.

The true points differ from the file's by the declared tolerances, the same over a run; the sensors read
the true linkage and the monitor solves the file's. At fixed measured inputs, a moved point moves the
solved pose (the closure with the inputs held) and the statics. On a linkage one measured input drives
(one degree of freedom; ``driving``, the first the kinematics takes; the others, redundant, are read off
the pose it gives), the pose depends on that input alone, and at a fixed pose the outputs are affine in
the pressures: y = A(s, g) + Σ_l B_l(s, g)·p_l. So ∂y/∂g = ∂A/∂g(s) + Σ_l ∂B_l/∂g(s)·p_l, each term a
function of the driving input s alone, tabulated at STROKE_NODES points of its assemblable range
(``limits.input_limits``) by central differences of step POINT_STEP (one model of the mechanism per moved
coordinate and sign, solved batched at every node and pressure row) and interpolated linearly per step:
a table lookup. Exact for the outputs linear in the pressures (forces, loads, capacities); the others
(a hinge's magnitude, the steerability ratio and margin, the lift reserve) follow by the chain rule in
``uncertainty`` from those. test/test_geometry_budget.py holds the lookup to a direct central difference.

A linkage of more degrees of freedom has no such table: a file declaring point tolerances on one is
refused (``MechanismFileError``). Units SI (m, Pa, N); frame x forward, z up.
"""

from __future__ import annotations

import bisect
import copy
from dataclasses import dataclass
from functools import cached_property
from typing import TYPE_CHECKING

import numpy as np

from .budget import Source
from .capacity import interval_around
from .errors import MechanismFileError
from .error_sources import ErrorSources
from .inputs import Inputs
from .limits import driven_by, input_limits
from .machine import STEERABILITY_KEYS, MachineModel, MachineSeries
from .model import Mechanism
from .results import Status, angle_readings
from .schema import mechanism_from_dict
from .solver import Solver

if TYPE_CHECKING:
    from .output_table import OutputTable

POINT_STEP = 1.0e-4    # m: the central difference's step of a point coordinate (truncation O(h²): ~1e-8 relative)
PRESSURE_STEP = 1.0e6  # Pa: the pressure step of the affine part (any step: the outputs are affine in it)
STROKE_NODES = 513     # the table's nodes over the driving input's range (linear interpolation: test_geometry_budget)
AXES = ("x", "z")
TABLES_KEPT = 8        # the mechanisms whose tables this process keeps (the last used), for a monitor built again


@dataclass(frozen=True)
class _Table:
    """The derivatives of one set of given ``pressures`` (L) at the ``nodes`` (S,) of the driving input (m
    or rad): ``coefficients`` (S, 1 + L, G·n_out), per node ∂A/∂g then ∂B_l/∂g per Pa of each pressure."""

    nodes: np.ndarray
    coefficients: np.ndarray
    pressures: tuple[str, ...]

    @cached_property
    def stops(self) -> list[float]:
        """``nodes`` as a list (``bisect`` takes a scalar's place in it faster than numpy)."""
        return self.nodes.tolist()


# (description, coordinates and their order, the solver's settings) -> the tables by given pressures
_KEPT: dict[tuple, dict[tuple[str, ...], _Table]] = {}


class GeometryBudget:
    """The geometry part of the budgets of ``model``'s poses under ``sources``, for ``table``'s outputs:
    ``sources`` (a Source per toleranced point coordinate, ``{point} {axis} position``, m, normal) and
    ``derivatives`` per pose. Empty (no sources) when no point has a tolerance. The tables are kept for the
    TABLES_KEPT mechanisms last used in the process: a monitor built again for the same mechanism (a
    replay's, the coverage study's runs) does not build them again."""

    def __init__(self, model: MachineModel, sources: ErrorSources, table: "OutputTable") -> None:
        self.model, self.mech, self.table = model, model.mech, table
        self.coordinates = sources.point_coordinates(model.mech.points)
        self.sources = tuple(Source(f"{point} {AXES[axis]} position", point, "position", u, "m")
                             for point, axis, u in self.coordinates)
        self.scales = np.array([u for _, _, u in self.coordinates])
        self._tables: dict[tuple[str, ...], _Table] = {}
        self._moved: list[MachineModel] | None = None
        self.driving, self.kind = "", ""
        if self.coordinates:
            solver = model.solver
            key = (model.mech.description_key, tuple(self.coordinates), solver.dead_centre_cond,
                   solver.consistency_tol, solver.dead_centre_transmission_deg)
            self._tables = _KEPT.pop(key, self._tables)   # the last used last
            _KEPT[key] = self._tables
            while len(_KEPT) > TABLES_KEPT:
                del _KEPT[next(iter(_KEPT))]
            self.driving, self.kind = self._driving_input()
            # the table of every pressure sensor given, built now: not on a live step (~1 s for belarus_1221)
            self._table(tuple(sorted(p.name for p in self.mech.measurements.pressures)))

    def _driving_input(self) -> tuple[str, str]:
        """The measured input that drives the linkage alone, and its kind (``cylinders``, ``angles``)."""
        driving = driving_input(self.mech, self.model.solver)
        if driving is None:
            raise MechanismFileError(self.mech.file, "error_sources.points", (
                f"point tolerances are propagated on a linkage one measured input drives (one degree of freedom); "
                f"'{self.model.solver.kin.input_names[0]}' alone does not fix this one's pose"))
        return driving

    def derivatives(self, inputs: Inputs, per_pascal: str | None = None) -> np.ndarray:
        """∂y/∂g (G, n_out) per m of each toleranced coordinate at the pose of ``inputs`` (its driving input
        and pressures), the linear outputs' exact to the interpolation (the others: the chain rule's to
        apply); NaN outside the table's range. With ``per_pascal`` (a given pressure sensor): ∂B/∂g of the
        outputs' derivative B per Pa of that pressure instead (per m and Pa)."""
        given = tuple(inputs.pressures)
        table = self._tables.get(given)
        if table is None:   # kept under the order they come in as well
            table = self._tables[given] = self._table(tuple(sorted(given)))
        s = getattr(inputs, self.kind)[self.driving]
        k = bisect.bisect_left(table.stops, s) - 1
        if not 0 <= k < len(table.stops) - 1:
            return np.full((len(self.coordinates), len(self.table.outputs)), np.nan)
        w = (s - table.stops[k]) / (table.stops[k + 1] - table.stops[k])
        loads = (np.array([1.0, *(inputs.pressures[name] for name in table.pressures)]) if per_pascal is None
                 else np.array([0.0, *(float(name == per_pascal) for name in table.pressures)]))
        row = loads @ ((1.0 - w) * table.coefficients[k] + w * table.coefficients[k + 1])
        return row.reshape(len(self.coordinates), len(self.table.outputs))

    def _table(self, pressures: tuple[str, ...]) -> _Table:
        """The table of these given pressures (sorted by name), built once for them."""
        table = self._tables.get(pressures)
        if table is None:
            table = self._tables[pressures] = self._build(pressures)
        return table

    def stroke_inputs(self) -> tuple[np.ndarray, dict[str, dict[str, np.ndarray]]]:
        """The table's nodes (S,) and the measured lengths and angles there (by kind and name, (S,)): the
        driving input over its assemblable range, the others as the file's linkage reads them."""
        limit = input_limits(self.mech)[self.driving]
        grid = np.linspace(limit.lo, limit.hi, STROKE_NODES)
        ok, inputs = readings_along(self.mech, self.kind, self.driving, grid)
        # the nodes the monitor's solver takes too (on its assembly branch, no dead centre)
        ok &= self.model.solver.solve_batch(inputs["cylinders"], inputs["angles"], reach=False).status < Status.INPUT
        reference = self.mech.reference_inputs.get(self.kind, {}).get(self.driving, 0.5 * (limit.lo + limit.hi))
        span = interval_around(grid, ok, reference)   # one assembly branch, without a gap to interpolate across
        keep = (grid >= span[0]) & (grid <= span[1]) if span is not None else ok
        return grid[keep], {kind: {name: v[keep] for name, v in group.items()} for kind, group in inputs.items()}

    def _build(self, pressures: tuple[str, ...]) -> _Table:
        """∂A/∂g and ∂B_l/∂g at the nodes: each moved model solved at every node with the pressures at
        their reference (the file's, else 0) and each one PRESSURE_STEP above."""
        nodes, held = self.stroke_inputs()
        n, rows = len(nodes), len(pressures) + 1
        reference = self.mech.reference_inputs.get("pressures", {})
        base = np.array([float(reference.get(name, 0.0)) for name in pressures])
        levels = np.repeat(base[None], rows, axis=0) + PRESSURE_STEP * np.eye(rows, len(pressures), -1)
        inputs = {kind: {name: np.tile(v, rows) for name, v in group.items()} for kind, group in held.items()}
        inputs["pressures"] = {name: np.repeat(levels[:, l], n) for l, name in enumerate(pressures)}
        moved = self._moved_models()

        def solve(model: MachineModel) -> np.ndarray:
            return series_rows(self.table, model, model.solve_series(inputs["cylinders"], inputs["angles"],
                                                                     inputs["pressures"]))

        d = np.empty((len(self.coordinates), rows * n, len(self.table.outputs)))
        for g in range(len(self.coordinates)):
            up, down = solve(moved[2 * g]), solve(moved[2 * g + 1])
            with np.errstate(invalid="ignore"):   # a node a moved model does not solve (NaN) or no load (inf)
                d[g] = (up - down) / (2.0 * POINT_STEP)
        by_node = d.reshape(len(self.coordinates), rows, n, -1).transpose(2, 1, 0, 3)   # (S, rows, G, n_out)
        with np.errstate(invalid="ignore"):
            per_pascal = (by_node[:, 1:] - by_node[:, :1]) / PRESSURE_STEP
            constant = by_node[:, 0] - np.einsum("l,slgo->sgo", base, per_pascal)
        return _Table(nodes, np.concatenate([constant[:, None], per_pascal], axis=1).reshape(n, rows, -1), pressures)

    def _moved_models(self) -> list[MachineModel]:
        """The mechanism with each toleranced coordinate moved by +POINT_STEP and −POINT_STEP, in turn."""
        if self._moved is None:
            solver = self.model.solver
            self._moved = []
            for point, axis, _ in self.coordinates:
                for sign in (1.0, -1.0):
                    mech = moved_point(self.mech, point, axis, sign * POINT_STEP)
                    self._moved.append(MachineModel(mech, Solver(
                        mech, dead_centre_cond=solver.dead_centre_cond, consistency_tol=solver.consistency_tol,
                        dead_centre_transmission_deg=solver.dead_centre_transmission_deg)))
        return self._moved


def driving_input(mech: Mechanism, solver: Solver) -> tuple[str, str] | None:
    """The name and kind (``cylinders``, ``angles``) of the measured input that drives ``mech``'s linkage
    alone (the first ``solver`` takes), None when it does not fix the pose alone (more than one DOF)."""
    name = solver.kin.input_names[0]
    kind = "cylinders" if name in mech.measurements.cylinders else "angles"
    if driven_by(mech, kind, _entry(mech, kind, name)) is None or input_limits(mech)[name].source != "geometry":
        return None
    return name, kind


def with_point_tolerance(mech: Mechanism, tolerance: float) -> Mechanism:
    """``mech`` whose file declares ``tolerance`` (m, 1 sigma) for every coordinate of the points it does
    not list (``error_sources.point_tolerance``)."""
    raw = copy.deepcopy(dict(mech.raw))
    raw["error_sources"] = {**(raw.get("error_sources") or {}), "point_tolerance": tolerance}
    return mechanism_from_dict(raw, file=mech.file)


def readings_along(mech: Mechanism, kind: str, name: str, values: np.ndarray
                   ) -> tuple[np.ndarray, dict[str, dict[str, np.ndarray]]]:
    """The measured lengths and angles of ``mech``'s linkage (by kind and name, (N,), m or rad) with its
    input ``name`` of ``kind`` (``cylinders``, ``angles``), which drives it alone, at ``values`` (N,),
    and where they solve (N,) bool (``limits.driven_by``'s solver, batched)."""
    solver = driven_by(mech, kind, _entry(mech, kind, name))
    assert solver is not None
    batch = (solver.solve_batch(cylinders={name: values}) if kind == "cylinders"
             else solver.solve_batch(angles={name: values}))
    angles = angle_readings(mech, batch)
    inputs = {"cylinders": {c: batch.cylinder_length[c] for c in mech.measurements.cylinders},
              "angles": {a.name: angles[a.name] for a in mech.measurements.angles}}
    inputs[kind][name] = np.asarray(values, dtype=float)
    return batch.status < Status.INPUT, inputs


def _entry(mech: Mechanism, kind: str, name: str) -> object:
    """The file's entry of the measured input ``name`` of ``kind`` (``limits.driven_by`` takes it)."""
    if kind == "cylinders":
        return name
    return next(raw for a, raw in zip(mech.measurements.angles, mech.raw["measurements"].get("angles") or [])
                if a.name == name)


def moved_point(mech: Mechanism, point: str, axis: int, step: float) -> Mechanism:
    """``mech`` with coordinate ``axis`` (0 = x, 1 = z) of ``point`` moved by ``step`` (m), read again from
    its description (what names the point moves with it: an implement's cg, a body's)."""
    raw = copy.deepcopy(dict(mech.raw))
    moved = [float(v) for v in mech.points[point]]
    moved[axis] += step
    raw["points"][point] = moved
    return mechanism_from_dict(raw, file=mech.file)


def series_rows(table: "OutputTable", model: MachineModel, series: MachineSeries) -> np.ndarray:
    """The outputs (N, n_out) of ``table`` at the poses of ``series`` (``model.solve_series``: as the live
    node solves them, each from the one before; NaN where a pose failed)."""
    batch, machine = series.batch, series.machine
    names = model.solver.names
    n = len(batch)
    hinge_force = (np.stack([batch.hinge_force[h] for h, _, _ in names.hinges], axis=1) if names.hinges
                   else np.zeros((n, 0, 2)))
    cylinder_force = (np.stack([batch.cylinder_force[c] for c in names.cylinders], axis=1) if names.cylinders
                      else np.zeros((n, 0)))
    steer = (np.stack([machine.steerability[k] for k in STEERABILITY_KEYS], axis=1) if machine.steerability
             else np.zeros((n, 0)))
    capacity = (np.stack([machine.lift_capacity[k] for k in model.capacity_keys], axis=1) if machine.lift_capacity
                else np.zeros((n, 0)))
    rows = table.rows(hinge_force, cylinder_force, batch.implement_load, steer, capacity)
    rows[batch.status >= Status.INPUT] = np.nan
    return rows
