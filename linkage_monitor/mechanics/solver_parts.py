"""What the solve paths (``general_path``, ``live_path``, ``series``) take of a solver: its mechanism's
parts built once and the few of its methods they call, as a Protocol that ``solver.Solver`` meets
(structurally: the type checker holds it to it), so the paths need not import the solver that uses them.

SI units (m, rad, N, Pa); frame x forward, z up, origin at the rear wheels' ground contact B.
"""

from __future__ import annotations

from typing import Mapping, Protocol

import numpy as np

from .inputs import ArrayMap, InputChecks
from .kinematics import Kinematics
from .model import Mechanism, PressureSensor
from .programs import LivePrograms, MachineProgram, OutputsProgram
from .reduced import ReducedStatics
from .result_layout import ResultLayout
from .results import BatchResult, ResultNames
from .statics import StaticsLayout


class SolverParts(Protocol):
    """A solver's parts as the solve paths use them (``solver.Solver`` documents each).

    dead_centre_cond: condition number above which a pose is a dead centre on the general path;
    dead_centre_transmission_deg: degrees, and dead_centre_sine its sine, the smallest transmission
    angle below which a pose is a dead centre on the reduced path; consistency_tol: m, largest
    constraint residual accepted when more inputs than degrees of freedom are measured;
    assembly_limit: m, largest constraint residual of an assembled pose; force_areas (2, C) m²:
    count·cap area and count·rod area of each cylinder; cylinder_index: each cylinder's index in
    ``mech.cylinders``; sensors: the pressure sensors by name; reduced: the reduced-coordinate
    statics of each set of cylinders whose force is measured.
    """

    mech: Mechanism
    kin: Kinematics
    checks: InputChecks
    reduced: dict[frozenset[str], ReducedStatics]
    result_layout: ResultLayout
    frame_load_names: list[str]
    names: ResultNames
    sensors: dict[str, PressureSensor]
    force_areas: np.ndarray
    cylinder_index: dict[str, int]
    dead_centre_cond: float
    dead_centre_transmission_deg: float
    dead_centre_sine: float
    consistency_tol: float
    assembly_limit: float

    def statics_layout(self, force_known: frozenset[str]) -> StaticsLayout:
        """The equilibrium layout with the forces of these cylinders measured."""
        ...

    def chamber_pressures(self, pressures: Mapping[str, np.ndarray], n_pose: int) -> tuple[np.ndarray, np.ndarray]:
        """The cap and rod gauge pressures (N, C) Pa of every cylinder; NaN where a chamber is not measured."""
        ...

    def solve_batch(self, cylinders: ArrayMap | None = None, angles: ArrayMap | None = None,
                    pressures: ArrayMap | None = None, rates: ArrayMap | None = None,
                    accelerations: ArrayMap | None = None, *, reach: bool = True) -> BatchResult:
        """N poses (arrays (N,)) solved by the general path from the reference pose."""
        ...

    def outputs_program(self, layout: StaticsLayout) -> OutputsProgram:
        """What ``kernels.live_series`` needs, beyond the layout's own program, for poses solved with ``layout``."""
        ...

    def live_programs(self, layout: StaticsLayout, machine: MachineProgram) -> LivePrograms:
        """The ``LivePrograms`` ``kernels.live_series`` takes for ``layout`` and the machine program ``machine``."""
        ...
