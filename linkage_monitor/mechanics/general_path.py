"""The general path of a solve: N poses as whole arrays (assembly by ``Kinematics.solve``, the
statics along the chain of dyads or as one linear system), every verdict worded — a bad input, a
pose that does not assemble, a dead centre, a contact lifting off.

SI units (m, rad, N, Pa); frame x forward, z up, origin at the rear wheels' ground contact B.
"""

from __future__ import annotations

import math

import numpy as np

from . import kernels
from .inputs import ArrayMap
from .kinematic_layout import KinematicLayout
from .kinematics import KinematicState
from .model import Mechanism
from .reduced import ReducedSolution, ReducedStatics, smallest_sine
from .results import BatchResult, Status
from .solver_parts import SolverParts
from .statics import StaticsLayout, StaticsSolution


def solve_general(solver: SolverParts, previous: KinematicState | None, cylinders: ArrayMap, angles: ArrayMap,
                  pressures: ArrayMap, rates: ArrayMap, accelerations: ArrayMap, *, reach: bool = True
                  ) -> tuple[BatchResult, KinematicState]:
    """N poses (arrays (N,), scalars broadcast) solved by ``solver``'s mechanism from ``previous`` (or
    the reference pose): the BatchResult with each pose's verdict and message, and the kinematic
    state a solve continues from. ``reach``: as ``Kinematics.solve``'s."""
    mech, kin, checks = solver.mech, solver.kin, solver.checks
    n_pose, arrays = checks.arrays(cylinders, angles, pressures, rates, accelerations)
    s = checks.matrix(arrays, n_pose, "inputs")
    problems, bad = checks.problems(s, arrays)
    s_clean = np.where(bad[:, None], kin.reference_inputs(), s)
    sensors = solver.sensors
    force_known = frozenset(sensors[n].cylinder for n in arrays["pressures"])
    reduced = solver.reduced[force_known]   # served: its transmission measure is the dead-centre verdict
    ks = kin.solve(s_clean, previous, None if reduced.served else solver.dead_centre_cond, solver.consistency_tol,
                   reach)
    status, messages = ks.status.copy(), list(ks.messages)
    for i in np.flatnonzero(bad):
        status[i], messages[i] = Status.INPUT, problems[i]
    p, rel = kin.positions(ks.q)
    accel = None
    input_rates = checks.rate_matrices(arrays, n_pose)
    if input_rates is not None:
        q_dot, q_ddot = kin.rates(ks.q, *input_rates)
        linear, _ = kin.point_rates(q_ddot, rel)
        _, centripetal = kin.point_rates(q_dot, rel)
        accel = (linear + centripetal, q_ddot[:, 2::3])
    cap_pressures, rod_pressures = solver.chamber_pressures(arrays["pressures"], n_pose)
    measured_force = kernels.measured_forces(cap_pressures, rod_pressures, solver.force_areas)
    measured_force[:, [k for k, c in enumerate(mech.cylinders) if c.name not in force_known]] = np.nan
    cap = {c.name: cap_pressures[:, k] for k, c in enumerate(mech.cylinders)}
    rod = {c.name: rod_pressures[:, k] for k, c in enumerate(mech.cylinders)}
    layout = solver.statics_layout(force_known)
    sol: StaticsSolution | ReducedSolution
    if reduced.served:   # along the chain of dyads; a dead centre where the transmission is lost
        sol = reduced.solve(p, measured_force, accel)
        sine, weakest = sol.transmission.sine, sol.transmission.weakest
        smallest = smallest_sine(sine, weakest)
        names = weakest_names(reduced, weakest)
        amplification = sol.amplification
        below = (status == Status.OK) & ~(smallest >= solver.dead_centre_sine)
        if below.any():   # (the spared poses are looked for among these only)
            below &= ~inferred_load_spared(sine, weakest, amplification, solver.dead_centre_sine)
        for i in np.flatnonzero(below):
            status[i] = Status.DEAD_CENTRE
            if np.isinf(amplification[i]):
                messages[i] = (f"dead centre at {kin.describe_inputs(s[i])}: {names[i]} passes through its pivot "
                               "(the load does no work there: its interval is unbounded, it cannot be inferred "
                               "from the measured force)")
                continue
            messages[i] = (f"dead centre at {kin.describe_inputs(s[i])}: transmission angle "
                           f"{math.degrees(math.asin(smallest[i])):.3g} deg at {names[i]} < "
                           f"{solver.dead_centre_transmission_deg:g} deg (the linkage cannot hold a load there; "
                           f"forces would be unbounded)")
        angle, statics_condition = sol.transmission.angle, np.full(n_pose, np.nan)   # arcsin(smallest)
    else:   # one linear system; a dead centre where it is near-singular
        general = sol = layout.solve(p, measured_force, accel)
        static_dead_centre_verdicts(kin, s, general.condition, solver.dead_centre_cond, status, messages)
        angle, names, statics_condition = np.full(n_pose, np.nan), [""] * n_pose, general.condition
        amplification = np.full(n_pose, np.nan)
    u = sol.unknowns
    lift_off_verdicts(mech, layout, u, status, messages)
    failed = status >= Status.INPUT
    q = np.where(failed[:, None], np.nan, ks.q)   # a copy: the state's q is where a solve continues
    if failed.any():   # no values of a failed pose (u and p are this solve's own arrays)
        u[failed], p[failed] = np.nan, np.nan
        names = np.where(failed, "", np.array(names, dtype=object)).tolist()
    batch = solver.result_layout.batch(n_pose, q, p, u, sol, layout, measured_force, cap, rod, failed)
    batch.status, batch.messages = status, messages
    # |Φ| (N,) m: np.linalg.norm's sum of squares along axis 1, without its conjugate's copy
    batch.consistency_residual = np.where(failed, np.nan, np.sqrt(np.add.reduce(ks.phi * ks.phi, axis=1)))
    batch.condition = np.fmax(statics_condition, ks.condition)
    batch.transmission_angle = np.where(failed, np.nan, angle)
    batch.weakest_transmission = names
    batch.load_amplification = np.where(failed, np.nan, amplification)
    return batch, ks


def inferred_load_spared(sine: np.ndarray, weakest: np.ndarray, amplification: np.ndarray, dead_centre_sine: float
                         ) -> np.ndarray:
    """Where (N,) a pose whose transmission measure is below the dead-centre's is no dead centre: its
    weakest measure is the free load's (the last column of ``sine`` (N, S + 1)), inferred from a
    measured cylinder force with a finite ``amplification`` (N,), and every step's own measure (links,
    cylinders: what holds the load) is at or above ``dead_centre_sine``. The linkage holds the load
    there; what is weak is inferring it from the pressure (a WARN on the amplification, published with
    its uncertainty; docs/dead-centre.md)."""
    n_steps = sine.shape[1] - 1
    steps = sine[:, :n_steps]
    with np.errstate(invalid="ignore"):
        steps_hold = np.all(np.isnan(steps) | (steps >= dead_centre_sine), axis=1)
    return (weakest == n_steps) & np.isfinite(amplification) & steps_hold


def static_dead_centre_verdicts(kin: KinematicLayout, s: np.ndarray, condition: np.ndarray, limit: float,
                                status: np.ndarray, messages: list[str]) -> None:
    """Status DEAD_CENTRE and its message, in place, for each pose still OK (inputs s (N, n_inputs))
    whose equilibrium matrix's condition number (N,) is above ``limit``."""
    for i in np.flatnonzero((status == Status.OK) & ~(condition <= limit)):
        status[i] = Status.DEAD_CENTRE
        messages[i] = (f"static dead centre at {kin.describe_inputs(s[i])}: equilibrium matrix condition "
                       f"number {condition[i]:.3g} > {limit:.3g} (a member is aligned with a hinge; forces "
                       f"would be unbounded)")


def lift_off_verdicts(mech: Mechanism, layout: StaticsLayout, u: np.ndarray, status: np.ndarray,
                      messages: list[str]) -> None:
    """Status LIFT_OFF and its message, in place, for each pose still OK where a contact's normal
    force (N, from the unknowns u (N, n_unknowns) in ``layout``) would pull."""
    for contact in mech.contacts:
        normal = u[:, layout.contact_col[contact.name]]
        for i in np.flatnonzero((status == Status.OK) & (normal < 0.0)):
            status[i] = Status.LIFT_OFF
            messages[i] = f"contact '{contact.name}' lifts off: its normal force would be {normal[i]:.1f} N (pulling)"


def weakest_names(reduced: ReducedStatics, weakest: np.ndarray) -> list[str]:
    """The name of each pose's weakest transmission measure (``ReducedStatics.measure_names``; '' for −1)."""
    names = np.array([*reduced.measure_names, ""], dtype=object)   # index −1: ''
    return names[weakest].tolist()
