"""`NAME=VALUE` entries of command-line options and node parameters (`--stroke lift_cylinder=0.6`,
`joint_map: ['rockshaft=lift_arm_angle']`)."""

from __future__ import annotations

import math

from linkage_monitor.mechanics import InputError
from linkage_monitor.mechanics.schema_values import MAX_MAGNITUDE


def name_value(text: str, option: str) -> tuple[str, str]:
    """(name, value) of one `NAME=VALUE` entry of `option`, both stripped; InputError if malformed."""
    name, sep, value = text.partition("=")
    name, value = name.strip(), value.strip()
    if not sep or not name or not value:
        raise InputError(f"{option} {text!r}: expected NAME=VALUE")
    return name, value


def number(text: str, option: str, name: str) -> float:
    """The float of `text`, the value of `name` in `option`; InputError if it is not a number."""
    try:
        value = float(text)
    except ValueError:
        raise InputError(f"{option} {name}={text}: {text!r} is not a number") from None
    if not math.isfinite(value) or abs(value) > MAX_MAGNITUDE:
        raise InputError(f"{option} {name}={text}: a finite number of magnitude <= {MAX_MAGNITUDE:.0e} is needed")
    return value
