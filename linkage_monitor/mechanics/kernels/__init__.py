"""Compiled per-pose physics (numba): loop closure, assembly branch, equilibrium, lift capacity.

The one numeric path of the solver. Every function works on plain arrays that describe the
mechanism (built once by :class:`~..kinematics.Kinematics` and :class:`~..statics.StaticsLayout`)
and loops over poses in compiled code, so a single pose costs microseconds, not the ~150
numpy calls of the array formulation that the tests keep as their oracle
(``test/oracles/numpy_solver/``). Compiled once, cached on disk (``cache=True``; ``numba_cache``).

Conventions (as in kinematics.py / statics.py): q holds (x, z, θ) per moving body (m, m, rad;
x forward, z up); an attachment is a point fixed on a body, at ``ref`` (m) from the body's
origin in the reference pose, or at ``ref`` in the frame when its body is the ground (−1).
Rows of the loop-closure system: 2 per hinge (x, z gap, m), 1 per measured cylinder (length
error, m), 1 per measured angle (error · lc, m). Equilibrium rows: ΣFx, ΣFz, ΣM/lc per body.

The modules, each one job: ``threads`` (where a batch runs), ``linalg`` (small dense linear
algebra), ``closure`` (positions, Φ and ∂Φ/∂q), ``dyads`` (the pose along the chain of dyads),
``assembly`` (Newton, the branch, a batch's kinematics), ``equilibrium`` (the general statics),
``reduced`` (the statics along the chain, transmission), ``capacity`` (lift capacity),
``steerability`` (axle loads), ``coverage`` (an error budget's coverage factors), ``budget`` (an error
budget's chain rule and its tabulated pose), ``rows`` (a pose's published numbers), ``live`` (the live pose
in one call). The names other modules use are importable from the package.
"""

from __future__ import annotations

from ..numba_blas import load_alone
from ..numba_cache import ensure_writable, stamp_by_package

stamp_by_package()   # before the kernels are defined: how numba stamps them,
ensure_writable()    # and where it can keep them
load_alone()         # the BLAS and LAPACK they call, without the rest of scipy.linalg

from .assembly import (assembled, assembled_batch, condition, loop_signs, newton,  # noqa: E402
                       newton_batch, solve_poses)
from .budget import (MOTION_LIFTING, MOTION_LOWERING, MOTION_STANDING, NODE_EMPTY, NODE_FAILED,  # noqa: E402
                     NODE_FILLED, NOT_TABULATED, BudgetProgram, OutputLayout, PoseTable, SourceColumns,
                     budget_program, chain_rule, output_rows, pose_coordinate, tabulated_budget)
from .capacity import lift_capacity  # noqa: E402
from .coverage import coverage_factors  # noqa: E402
from .closure import positions, positions_batch, residual_jacobian, residual_jacobian_batch  # noqa: E402
from .dyads import chain_fit, chain_pose  # noqa: E402
from .equilibrium import equilibrium_matrix, solve_statics  # noqa: E402
from .linalg import closed_step, det_sign, factor_and_condition, gram, lu_factor, lu_solve, solve_linear  # noqa: E402
from .live import NO_MACHINE, live_buffer, live_programs, live_rows, live_series  # noqa: E402
from .reduced import (smallest_sine, smallest_sines, solve_reduced_statics,  # noqa: E402
                      step_transmission, transmission_batch, transmission_pose)
from .rows import (BatchOutputs, batch_outputs, frame_loads, largest_force, measured_force,  # noqa: E402
                   measured_forces, pack_row, pack_rows)
from .steerability import (N_STEERABILITY, STEERABILITY_COLUMNS, STEERABILITY_PARAMETERS,  # noqa: E402
                           steerability_pose, steerability_rows)
from .threads import PARALLEL_MIN, PARALLEL_PARTS, allow_threads, threads_allowed  # noqa: E402

__all__ = ["BatchOutputs", "BudgetProgram", "MOTION_LIFTING", "MOTION_LOWERING", "MOTION_STANDING", "NODE_EMPTY",
           "NODE_FAILED", "NODE_FILLED", "NOT_TABULATED", "NO_MACHINE", "N_STEERABILITY", "OutputLayout", "PARALLEL_MIN", "PARALLEL_PARTS",
           "PoseTable", "STEERABILITY_COLUMNS", "STEERABILITY_PARAMETERS", "SourceColumns", "allow_threads",
           "assembled", "assembled_batch", "batch_outputs", "budget_program", "chain_fit", "chain_rule", "chain_pose", "closed_step", "condition", "coverage_factors", "det_sign",
           "equilibrium_matrix", "factor_and_condition", "frame_loads", "gram", "largest_force", "lift_capacity",
           "live_buffer", "live_programs", "live_rows", "live_series", "loop_signs", "lu_factor", "lu_solve",
           "measured_force", "measured_forces", "newton", "newton_batch", "output_rows", "pack_row", "pack_rows", "positions",
           "pose_coordinate", "positions_batch", "residual_jacobian", "residual_jacobian_batch", "smallest_sine", "smallest_sines",
           "solve_linear", "solve_poses", "solve_reduced_statics", "solve_statics", "steerability_pose",
           "steerability_rows", "step_transmission", "tabulated_budget", "threads_allowed", "transmission_batch", "transmission_pose"]
