"""The sentences of a step's findings: a failed solve's (by its status) and a solved pose's failed
checks (``checks.Check``), each worded with the pose's numbers. Units in the text: mm, N, kN, kg.
"""

from __future__ import annotations

from linkage_monitor.mechanics import Mechanism, Status
from linkage_monitor.mechanics.dynamics import DYNAMIC_FRONT, DYNAMIC_MARGIN

from .bounds import ballast_at_bound_text, uncertain_findings, weak_inference_finding
from .checks import CONSISTENCY_WARN_M, RESIDUAL_WARN_SHARE, Check
from .findings import Code, Finding, fmt
from .steps import Due, Pose, Step

FAILURE_CODE = {Status.INPUT: Code.MALFORMED_INPUT, Status.ASSEMBLY: Code.CANNOT_ASSEMBLE,
                Status.DEAD_CENTRE: Code.DEAD_CENTRE}
FAILURE_TEXT = {Code.MALFORMED_INPUT: "malformed input", Code.CANNOT_ASSEMBLE: "cannot assemble",
                Code.DEAD_CENTRE: "dead centre"}


def failed_step(due: Due, status: Status, message: str) -> Step:
    """The Step of a due solve that failed with ``status`` (INPUT, ASSEMBLY or DEAD_CENTRE) and ``message``."""
    code = FAILURE_CODE[status]
    return Step(due.stamp_ns, due.trigger, (Finding(code, f"{FAILURE_TEXT[code]}: {message}"),),
                inputs=due.inputs)


def pose_findings(checks: Check, pose: Pose, mechanism: Mechanism) -> tuple[Finding, ...]:
    """The findings of the failed ``checks`` of a solved pose of ``mechanism``, worded with its numbers."""
    result, machine = pose.result, pose.machine
    findings = []
    if Check.LIFT_OFF in checks:
        findings.append(Finding(Code.LIFT_OFF, result.message or "a ground contact lifts off"))
    if Check.SENSORS_DISAGREE in checks:
        findings.append(Finding(Code.SENSORS_DISAGREE, f"measurements disagree: kinematic residual "
                                f"{fmt(result.consistency_residual * 1e3)} mm > {fmt(CONSISTENCY_WARN_M * 1e3)} mm "
                                "(check sensor calibration)"))
    if Check.PRESSURES_DISAGREE in checks:
        findings.append(Finding(Code.PRESSURES_DISAGREE, f"equilibrium residual {fmt(result.residual)} N > "
                                f"{RESIDUAL_WARN_SHARE:.0%} of the largest force ({fmt(result.largest_force)} N): the measured "
                                "pressures disagree"))
    if Check.LOAD_INFERENCE_WEAK in checks:
        findings.append(weak_inference_finding(result, pose.budget))
    for axle, check in (("front", Check.FRONT_AXLE_LIFT_OFF), ("rear", Check.REAR_AXLE_LIFT_OFF)):
        if check in checks:
            load = machine.value(f"{axle}_axle_load")
            findings.append(Finding(Code.AXLE_LIFT_OFF, f"{axle} axle load {fmt(load / 1e3)} kN < 0: the machine "
                                    f"tips over its {'rear' if axle == 'front' else 'front'} axle (check the "
                                    "tractor, ballast and implement masses and their positions)"))
    if Check.STEERABILITY_LOW in checks:
        steer = machine.steerability
        reference = mechanism.tractor.steerability_reference if mechanism.tractor else "unit"
        findings.append(Finding(Code.STEERABILITY_LOW, f"steerability margin {steer['margin']:+.3f} < 0: the front "
                                f"axle carries {steer['ratio']:.1%} of the {reference} weight, below ratio_min "
                                f"{steer['ratio_min']:.0%}; extra front ballast needed "
                                f"{fmt(round(steer['front_ballast_needed']))} kg"
                                + (ballast_at_bound_text(pose.budget, mechanism, steer["total_weight"])
                                   if pose.budget is not None else "")))
    if Check.STEERABILITY_DYNAMIC_LOW in checks and pose.dynamic is not None:
        margin, front = pose.dynamic[DYNAMIC_MARGIN], pose.dynamic[DYNAMIC_FRONT]
        findings.append(Finding(Code.STEERABILITY_DYNAMIC_LOW, (
            f"dynamic steerability margin {margin:+.3f} < 0 (static {machine.value('margin'):+.3f}): the body's "
            f"bouncing unloads the front axle to {fmt(front / 1e3)} kN; slow down on this road or add front ballast")))
    if Check.LIFT_RESERVE_LOW in checks:
        findings.append(Finding(Code.LIFT_RESERVE_LOW, f"lift reserve {machine.value('reserve'):.2f} < 1: implement "
                                f"load {fmt(result.implement_load / 1e3)} kN exceeds the lift capacity "
                                f"{fmt(machine.value('implement_cg') / 1e3)} kN at its centre of gravity"))
    if pose.budget is not None:
        findings += uncertain_findings(checks, pose.budget, mechanism, machine.value("total_weight"))
    return tuple(findings)
