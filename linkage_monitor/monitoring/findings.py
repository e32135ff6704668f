"""The monitor's error model: a level per step and structured findings, never parsed text.

A finding is one reason why a step is not OK: a code (what kind of fault or limit, fixed
level), and a sentence naming the input and the reason with the numbers (≤ 6 significant
digits). The node turns findings into one diagnostic_msgs/DiagnosticStatus per step; the
replay counts them by code.
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import Enum, IntEnum


class Level(IntEnum):
    """diagnostic_msgs/DiagnosticStatus levels."""

    OK = 0
    WARN = 1
    ERROR = 2
    STALE = 3   # the monitor has solved nothing for its staleness limit (``monitoring.freshness``)


class Code(Enum):
    """Kinds of findings; the value is (stable identifier, level)."""

    # the input message itself (nothing from it is used)
    MALFORMED_INPUT = ("malformed_input", Level.ERROR)      # NaN/inf, array lengths differ
    UNKNOWN_INPUT = ("unknown_input", Level.ERROR)          # no joint name / topic maps to a measurement
    DUPLICATE_JOINT = ("duplicate_joint", Level.ERROR)      # a joint name twice in one JointState
    OUT_OF_RANGE = ("out_of_range", Level.ERROR)            # outside the plausibility limits of the mechanism
    BAD_STAMP = ("bad_stamp", Level.ERROR)                  # zero, negative or far from the monitor's clock
    OUT_OF_ORDER = ("out_of_order", Level.WARN)             # stamped before the reading in use: not applied
    # the inputs of a solve
    NO_VALUE_YET = ("no_value_yet", Level.WARN)             # an input has not arrived yet
    STALE_INPUT = ("stale_input", Level.WARN)               # an input is older than the staleness limit
    # the solver's verdict
    CANNOT_ASSEMBLE = ("cannot_assemble", Level.ERROR)      # or only off the reference assembly branch
    DEAD_CENTRE = ("dead_centre", Level.ERROR)
    LIFT_OFF = ("lift_off", Level.WARN)                     # a ground contact would pull
    SENSORS_DISAGREE = ("sensors_disagree", Level.WARN)     # redundant kinematic inputs disagree
    PRESSURES_DISAGREE = ("pressures_disagree", Level.WARN)  # redundant forces disagree (equilibrium residual)
    LOAD_INFERENCE_WEAK = ("load_inference_weak", Level.WARN)  # a load inferred from a pressure, amplified
    # machine-level limits
    AXLE_LIFT_OFF = ("axle_lift_off", Level.ERROR)          # an axle's ground load < 0: the machine tips over
    STEERABILITY_LOW = ("steerability_low", Level.WARN)     # steerability margin < 0
    # the dynamic steerability margin < 0 while the static one is not: the front axle unloads on a bump (an IMU)
    STEERABILITY_DYNAMIC_LOW = ("steerability_dynamic_low", Level.WARN)
    LIFT_RESERVE_LOW = ("lift_reserve_low", Level.WARN)     # lift reserve < 1
    IMPLEMENT_CHANGED = ("implement_changed", Level.WARN)   # the weighing found a new load: the mass in use is stale
    # the 95 % interval of a value that clears its limit reaches across it (monitoring.bounds)
    AXLE_LOAD_UNCERTAIN = ("axle_load_uncertain", Level.WARN)
    STEERABILITY_UNCERTAIN = ("steerability_uncertain", Level.WARN)
    LIFT_RESERVE_UNCERTAIN = ("lift_reserve_uncertain", Level.WARN)
    # the monitor itself
    INTERNAL_ERROR = ("internal_error", Level.ERROR)        # a bug: reported, the monitor goes on
    NOT_SOLVING = ("not_solving", Level.STALE)             # no input solved for the staleness limit (live node)
    INPUTS_LOST = ("inputs_lost", Level.WARN)               # inputs dropped before the monitor saw them (a WARN
                                                            # on /diagnostics, as the node reports lost inputs)

    @property
    def ident(self) -> str:
        """Stable lower-case identifier (diagnostic key-values, replay summaries)."""
        return self.value[0]

    @property
    def level(self) -> Level:
        """The level a finding of this code gives its step."""
        return self.value[1]


@dataclass(frozen=True)
class Finding:
    """One reason a step is not OK: its code and a sentence naming the input and the reason."""

    code: Code
    text: str

    @property
    def level(self) -> Level:
        return self.code.level


def fmt(value: float) -> str:
    """A number for a message: ≤ 6 significant digits (``1e+308``, ``0.535``, ``-2.7747``)."""
    return f"{value:.6g}"
