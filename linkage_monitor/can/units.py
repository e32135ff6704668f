"""The mapped inputs' kinds and units, and a DBC signal checked against the input it feeds: the
kind of each of the mechanism's measurements (angle, cylinder, pressure), the quantity and SI unit
of each kind, a DBC unit string read as one of the mapping's units (UNITS), and InputError naming
the mapping key when a signal's factor or unit cannot feed its input as mapped.
"""

from __future__ import annotations

from typing import Any

from linkage_monitor.mechanics import InputError, Mechanism
from linkage_monitor.monitoring.findings import fmt

from .mapping import UNITS, InputMap

ANGLE, CYLINDER, PRESSURE = "angle", "cylinder", "pressure"
KIND_UNITS = {ANGLE: "angle", CYLINDER: "length", PRESSURE: "pressure"}
SI_UNIT = {ANGLE: "rad", CYLINDER: "m", PRESSURE: "Pa"}


# DBC unit spellings -> the mapping's unit names (UNITS), beside the names themselves in any case
UNIT_ALIASES = {"°": "deg", "degree": "deg", "degrees": "deg", "millimetre": "mm", "millimeter": "mm"}


def dbc_unit(text: str | None) -> tuple[str, str] | None:
    """(quantity, unit) of a DBC signal's unit string when it is one of UNITS (``kPa`` -> pressure, kPa;
    ``KPA`` too), None for an empty or other unit (``%``, ``rpm``)."""
    name = (text or "").strip()
    name = UNIT_ALIASES.get(name.lower(), name)
    for quantity, units in UNITS.items():
        for unit in units:
            if name == unit or name.lower() == unit.lower():
                return quantity, unit
    return None


def check_signal(where: str, item: InputMap, kind: str, message: Any, signal: Any) -> None:
    """InputError if the DBC signal cannot feed ``item`` as mapped: a scale of 0 (every value the
    offset), or a unit other than the mapping's: without a table, value = scale · signal + offset is
    read in the mapping's ``unit`` (SI when none), so a DBC unit of the input's quantity must be that
    unit, one of another quantity cannot be it, and any other DBC unit (``%``) needs ``unit`` written."""
    name = f"{message.name}.{signal.name}"
    if signal.scale == 0:
        raise InputError(f"{where}.signal: {name} has factor 0 in the DBC: every frame would read its offset "
                         f"({fmt(signal.offset)}); correct the signal's factor in the DBC")
    if item.table is not None:
        return   # the table maps the signal's unit to the mapping's
    declared = (signal.unit or "").strip()
    quantity = KIND_UNITS[kind]
    mapped = item.unit or SI_UNIT[kind]
    read_as = f"'{item.unit}'" if item.unit else f"{SI_UNIT[kind]} (no 'unit' given: SI)"
    found = dbc_unit(declared)
    if found is not None and found[0] != quantity:
        raise InputError(f"{where}: the DBC gives {name} in {declared} (a {found[0]}), but {item.name} is "
                         f"{'an' if kind == ANGLE else 'a'} {quantity}: map a {quantity} signal, or give a table")
    if found is not None and found[1] != mapped:
        raise InputError(f"{where}.unit: the DBC gives {name} in {declared}, the mapping reads it as {read_as}: "
                         f"write 'unit: {found[1]}' (scale and offset then in {found[1]})")
    if found is None and declared and item.unit is None:
        raise InputError(f"{where}.unit: the DBC gives {name} in '{declared}', not a unit of {quantity}: write the "
                         f"unit scale · signal + offset is in ('unit: {SI_UNIT[kind]}', ...), or give a table")


def input_kinds(mech: Mechanism) -> dict[str, str]:
    """Measurement name -> its kind (angle, cylinder, pressure) in ``mech``."""
    kinds = {a.name: ANGLE for a in mech.measurements.angles}
    kinds.update({c: CYLINDER for c in mech.measurements.cylinders})
    kinds.update({p.name: PRESSURE for p in mech.measurements.pressures})
    return kinds
