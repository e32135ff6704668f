"""The error budget of a judged pose as ``linkage-monitor solve --uncertainty`` prints it: every output
with its standard uncertainty (1 sigma, the output's unit) and the share of u² of each declared source
(docs/accuracy.md); the 95 % interval is the value ± k·u, k the coverage factor of the output's budget
(``mechanics.coverage_factor``: 1.96 where normal sources dominate, down to 1.645 for one uniform source).
"""

from __future__ import annotations

import math

from linkage_monitor.mechanics.budget import Budget, OutputUncertainty

SHOWN_SHARE = 0.005       # the text table names the sources of at least this share of u²


def _number(x: float) -> float | None:
    """``x`` for JSON: NaN and ±inf as None."""
    return x if math.isfinite(x) else None


def budget_json(budget: Budget) -> dict:
    """``{"motions", "sources": [{name, input, part, shape, u, unit}], "outputs": {name: {value, u, k,
    half_width_95, unit, shares}}}`` (motions: force-measured cylinder -> the motion whose friction band it
    took; shape ``normal`` or ``uniform``; u a standard uncertainty, k the 95 % coverage factor and
    half_width_95 = k·u; shares of u², source name -> 0..1; NaN -> None)."""
    return {"motions": {name: motion.value for name, motion in budget.motions.items()},
            "sources": [{"name": s.name, "input": s.input, "part": s.part,
                         "shape": "uniform" if s.uniform else "normal", "u": s.u, "unit": s.unit}
                        for s in budget.sources],
            "outputs": {line.output.name: {"value": _number(line.value), "u": _number(line.u),
                                           "k": _number(line.k), "half_width_95": _number(line.half_width),
                                           "unit": line.output.unit,
                                           "shares": {k: _number(v) for k, v in line.shares.items()}}
                        for line in budget.lines()}}


def _shares_text(line: OutputUncertainty) -> str:
    """The sources of ``line`` by share, largest first (those below SHOWN_SHARE left out)."""
    if not math.isfinite(line.u):
        return "unbounded: a derivative could not be taken (the pose fails nearby)"
    ranked = sorted(((share, name) for name, share in line.shares.items() if share >= SHOWN_SHARE), reverse=True)
    return ", ".join(f"{name} {share:.0%}" for share, name in ranked) or "-"


def budget_lines(budget: Budget) -> list[str]:
    """The budget as a table: output [unit], value, u, the sources' shares."""
    friction = ", ".join(f"{name} {motion.value}" for name, motion in budget.motions.items()) or "none"
    lines = [f"uncertainty: u = standard uncertainty (1 sigma, same unit as the value); 95 % interval = value "
             f"± k u (k from the shares of normal and uniform sources); seal friction: {friction}",
             f"{'output':<32} {'value':>12} {'u':>11} {'k':>5}  sources (share of u²)"]
    for line in budget.lines():
        label = f"{line.output.name} [{line.output.unit}]"
        lines.append(f"{label:<32} {line.value:12.5g} {line.u:11.4g} {line.k:5.3f}  {_shares_text(line)}")
    lines.append("sources: " + "; ".join(f"{s.name} u = {s.u:.4g} {s.unit}" for s in budget.sources))
    return lines
