"""Oracle for the output messages: the three outputs of a step built field by field with rclpy's
generated message classes (how the package built them before it wrote their CDR bytes directly,
``linkage_monitor.wire.outputs.OutputEncoder``). Serialized by rclpy, they are what the encoder's
bytes must decode to (test/test_output_cdr.py).

Units SI (m, N, Pa, kg); frame x forward, z up, origin at the rear wheels' ground contact.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Mapping

from linkage_monitor.mechanics import Mechanism, Result
from linkage_monitor.monitoring.core import Monitor, Step
from linkage_monitor.msg import CylinderState, HingeReaction, HingeReactions, HitchState, Steerability
from linkage_monitor.ros.messages import header
from linkage_monitor.mechanics.budget import Budget
from linkage_monitor.wire.outputs import (HITCH_UNCERTAINTIES, STEERABILITY_UNCERTAINTIES, WEIGHING_FIELDS,
                                          hinge_status, hitch_status, steerability_reference, weighing_flags,
                                          weighing_row)


@dataclass(frozen=True)
class Outputs:
    """The three output messages of one solve."""

    hinge_reactions: HingeReactions
    hitch_state: HitchState
    steerability: Steerability


def outputs(monitor: Monitor, step: Step) -> Outputs | None:
    """The three output messages of a step with a solved pose (None without one)."""
    if step.pose is None:
        return None
    mech, result, machine = monitor.mechanism, step.pose.result, step.pose.machine
    u = _uncertainty(step.pose.budget)
    return Outputs(hinge_reactions=hinge_reactions(mech, step, result, monitor.overdetermined),
                   hitch_state=hitch_state(mech, step, result, machine.lift_capacity, monitor.estimates_load),
                   steerability=steerability(step.stamp_ns, machine.steerability, steerability_reference(mech), u,
                                             step.pose.dynamic))


def _uncertainty(budget: Budget | None):
    """The standard uncertainty (1 sigma) of a budget output by name, NaN without a budget."""
    return (lambda name: math.nan) if budget is None else budget.u_of


def hinge_reactions(mech: Mechanism, step: Step, result: Result, overdetermined: bool) -> HingeReactions:
    """HingeReactions for one solved pose: force on bodies[1] from bodies[0] at every hinge, N.

    overdetermined: more measurements than degrees of freedom (solved by least squares).
    """
    hinges = []
    u = _uncertainty(step.pose.budget if step.pose is not None else None)
    for hinge in mech.hinges:
        r = result.hinges[hinge.name]
        x, z = result.points[hinge.point]
        hinges.append(HingeReaction(name=hinge.name, on_body=r.on_body, from_body=r.from_body,
                                    fx=r.fx, fz=r.fz, magnitude=r.magnitude, fx_u=u(f"{hinge.name}.fx"),
                                    fz_u=u(f"{hinge.name}.fz"), magnitude_u=u(f"{hinge.name}.magnitude"),
                                    x=float(x), z=float(z)))
    status, text = hinge_status(step, result, overdetermined)
    return HingeReactions(header=header(step.stamp_ns), mechanism=mech.name, hinges=hinges, status=status,
                          status_text=text, equilibrium_residual=float(result.residual),
                          kinematic_residual=float(result.consistency_residual))


def hitch_state(mech: Mechanism, step: Step, result: Result, lift_capacity: Mapping[str, float],
                estimated: bool) -> HitchState:
    """HitchState: cylinder states, implement load (N, + down), lift capacities (N), reserve (-),
    the smallest transmission angle (rad, the solver's Result.transmission_angle)."""
    u = _uncertainty(step.pose.budget if step.pose is not None else None)
    cylinders = [CylinderState(name=name, length=c.length, force=c.force, force_u=u(f"{name}.force"),
                               cap_pressure_measured=c.cap_pressure_measured,
                               rod_pressure_measured=c.rod_pressure_measured,
                               cap_pressure_predicted=c.cap_pressure_predicted)
                 for name, c in result.cylinders.items()]
    hitch_point = mech.implement.hitch_point if mech.implement else None
    height = float(result.points[hitch_point][1]) if hitch_point else math.nan
    status = hitch_status(step)
    phase, sure, in_use = weighing_flags(step.weighing)
    weighed = dict(zip(WEIGHING_FIELDS, weighing_row(step.weighing) if step.weighing is not None
                       else [math.nan] * len(WEIGHING_FIELDS)))
    return HitchState(header=header(step.stamp_ns), cylinders=cylinders, implement_load=float(result.implement_load),
                      implement_load_estimated=estimated,
                      implement_cg_x=float(result.implement_cg[0]), implement_cg_z=float(result.implement_cg[1]),
                      hitch_axis_height=height,
                      lift_capacity_hitch_axis=float(lift_capacity.get("hitch_axis", math.nan)),
                      lift_capacity_610mm=float(lift_capacity.get("behind_610mm", math.nan)),
                      lift_capacity_implement_cg=float(lift_capacity.get("implement_cg", math.nan)),
                      lift_reserve=float(lift_capacity.get("reserve", math.nan)),
                      **{f: u(output) for f, output in HITCH_UNCERTAINTIES.items()}, **weighed,
                      weighing_phase=phase, weighing_confident=bool(sure), implement_mass_in_use=in_use,
                      min_transmission_angle=float(result.transmission_angle), status=status,
                      status_text=step.message)


def steerability(stamp: int, values: Mapping[str, float], ref: int, u=lambda name: math.nan,
                 dynamic=None) -> Steerability:
    """Steerability message from the machine-level values (N, m, -, kg); ref: Steerability.REFERENCE_*;
    ``u``: the standard uncertainty (1 sigma) of a budget output by name; ``dynamic``: the pose's dynamic
    front / rear axle load (N), ratio, margin (-), NaN without one."""
    fields = ("front_axle_load", "rear_axle_load", "total_weight", "wheelbase", "ratio", "ratio_unit",
              "ratio_tractor", "ratio_min", "margin", "front_ballast_needed", "max_implement_mass")
    return Steerability(header=header(stamp), reference=ref,
                        **{name: float(values.get(name, math.nan)) for name in fields},
                        **{f: u(output) for f, output in STEERABILITY_UNCERTAINTIES.items()},
                        **{name: float(dynamic[k]) if dynamic is not None else math.nan
                           for k, name in enumerate(("dynamic_front_axle_load", "dynamic_rear_axle_load",
                                                     "dynamic_ratio", "dynamic_margin"))})
