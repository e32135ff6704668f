"""A recorded series of poses solved as the live node solves them, each from the one before
(``kernels.live_series``, one compiled call a part), the poses it does not take by the general path.

SI units (m, rad, N, Pa); frame x forward, z up, origin at the rear wheels' ground contact B.
"""

from __future__ import annotations

from typing import Mapping, NamedTuple

import numpy as np

from . import kernels
from .general_path import weakest_names
from .inputs import ArrayMap, InputArrays
from .programs import LiveRows, MachineProgram, fields
from .results import BatchResult
from .solver_parts import SolverParts


class SeriesPart(NamedTuple):
    """The poses of one ``Series.add``: their inputs by kind and name, which are bad, the inputs as the
    compiled call took them (s), its rows, and the cylinders whose force the layout takes as measured."""

    arrays: InputArrays
    bad: np.ndarray
    s: np.ndarray
    rows: LiveRows
    force_known: frozenset[str]


class Series:
    """A recorded series solved part by part as its inputs come (``add``), each pose from the one before
    across the parts, as ``Solver.solve_series`` solves it in one call: the same poses, bit for bit
    (``finish`` gives its answer). ``add`` may run in another thread while the caller reads the next
    inputs: the compiled call releases the GIL."""

    def __init__(self, solver: SolverParts, machine: MachineProgram) -> None:
        self._solver, self._machine = solver, machine
        reference = solver.kin.reference
        self._start = (reference.q[-1:], reference.s[-1:])   # the last pose the compiled series took
        self._parts: list[SeriesPart] = []

    def add(self, cylinders: ArrayMap, angles: ArrayMap, pressures: ArrayMap) -> None:
        """The next poses (arrays (n,), the same inputs every time), solved now."""
        part = self._part(cylinders, angles, pressures)
        taken = np.flatnonzero(part.rows.plain)
        if taken.size:
            k = int(taken[-1])
            self._start = (part.rows.q[k:k + 1], part.s[k:k + 1])
        self._parts.append(part)

    def finish(self) -> tuple[BatchResult, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """``Solver.solve_series``' answer for every pose added (once: the parts are let go)."""
        return self._joined(self._parts)

    def _part(self, cylinders: ArrayMap, angles: ArrayMap, pressures: ArrayMap) -> SeriesPart:
        """One part: its poses solved in one compiled call from the last pose the series took (q (1, n),
        s (1, n_inputs)), each from the one before."""
        solver, machine = self._solver, self._machine
        kin, checks = solver.kin, solver.checks
        n_pose, arrays = checks.arrays(cylinders, angles, pressures, {}, {})
        s = checks.matrix(arrays, n_pose, "inputs")
        bad = checks.problems(s, arrays).bad
        s = kin.wrap_angles(np.where(bad[:, None], kin.reference_inputs(), s))
        cap, rod = solver.chamber_pressures(arrays["pressures"], n_pose)
        layout = solver.statics_layout(frozenset(solver.sensors[n].cylinder for n in arrays["pressures"]))
        rows = kernels.live_rows(n_pose, kin.n, kin.m, solver.outputs_program(layout), machine)
        buffer = kernels.live_buffer(fields(rows), s, np.ascontiguousarray(np.stack([cap, rod], axis=1)))
        kernels.live_series(solver.live_programs(layout, machine), buffer, self._start[0], self._start[1],
                            solver.assembly_limit, solver.dead_centre_cond, 0, n_pose)
        return SeriesPart(arrays, bad, s, rows, layout.force_known)

    def _joined(self, parts: list[SeriesPart]) -> tuple[BatchResult, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """``solve_series``' answer from the parts, in order (the list is emptied: each row of the parts
        is let go once it is joined, so that joining takes little more memory than the rows)."""
        solver = self._solver
        mech = solver.mech

        def joined(columns: list[np.ndarray]) -> np.ndarray:
            return columns[0] if len(columns) == 1 else np.concatenate(columns)

        force_known = parts[0].force_known
        arrays = {kind: {name: joined([part.arrays[kind][name] for part in parts]) for name in parts[0].arrays[kind]}
                  for kind in ("cylinders", "angles", "pressures")}
        bad = joined([part.bad for part in parts])
        columns = [list(column) for column in zip(*(part.rows for part in parts))]
        parts.clear()
        rows_joined = []
        for k, column in enumerate(columns):
            rows_joined.append(joined(column))
            columns[k] = []
        rows = LiveRows(*rows_joined)
        n_pose = len(rows.plain)
        plain = rows.plain & ~bad
        batch = BatchResult.from_stacked(
            solver.names, {h.name: h.bodies for h in mech.hinges}, rows.point_xz, rows.q.reshape(n_pose, -1, 3),
            rows.hinge_force, rows.cylinder_values, rows.contact_values, rows.pose["implement_load"],
            rows.implement_cg, list(solver.frame_load_names), rows.frame_load_points, rows.frame_load_forces,
            rows.pose["residual"], rows.pose["consistency_residual"], rows.pose["condition"],
            rows.pose["largest_force"], rows.pose["transmission_angle"],
            weakest_names(solver.reduced[force_known], rows.pose["weakest"]), rows.pose["load_amplification"])
        general = np.flatnonzero(~plain)
        if general.size:
            def taken(group: Mapping[str, np.ndarray]) -> dict[str, np.ndarray]:
                return {n: v[general] for n, v in group.items()}
            other = solver.solve_batch(taken(arrays["cylinders"]), taken(arrays["angles"]), taken(arrays["pressures"]))
            batch.assign(general, other)
        return batch, rows.steerability, rows.capacity, rows.values, plain
