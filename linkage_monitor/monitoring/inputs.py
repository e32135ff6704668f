"""Sensor inputs of the monitor: validation and the latest value of every input.

No rclpy: the node and the replay hand in the fields of `sensor_msgs/JointState`
(positions: rad for angle sensors, m for cylinder lengths) and `sensor_msgs/FluidPressure`
(Pa), with their header stamps in ns. Each accepted message updates the latest value of
its inputs; `inputs_at(stamp)` assembles the inputs of one solve when no input is older
than the staleness limit. Errors name the input and the reason (InputError).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Iterable, Mapping, Sequence

from linkage_monitor.mechanics import InputError, Inputs, Mechanism

ATMOSPHERIC_PRESSURE = 101325.0  # Pa, ISO 2533 standard atmosphere at sea level


class StaleInputError(InputError):
    """An input needed for a solve is missing or older than the staleness limit."""


@dataclass(frozen=True)
class InputConfig:
    """How sensor messages map onto the mechanism's measurements.

    joint_map: JointState joint name -> measurement name (an angle sensor, rad, or a measured
    cylinder, m); measurement names not in the map are expected under their own name.
    pressure_topics: topic -> pressure-sensor name (one FluidPressure topic per chamber).
    pressure_absolute: True if FluidPressure carries absolute pressure (the message's
    definition), False for gauge. staleness_limit_s: s, largest age of any input relative to
    the stamp of the triggering message.
    """

    joint_map: Mapping[str, str] = field(default_factory=dict)
    pressure_topics: Mapping[str, str] = field(default_factory=dict)
    pressure_absolute: bool = True
    atmospheric_pressure: float = ATMOSPHERIC_PRESSURE
    staleness_limit_s: float = 0.5

    @staticmethod
    def default(mech: Mechanism, prefix: str = "pressure/") -> "InputConfig":
        """Identity joint names; one topic `<prefix><sensor>` per pressure sensor."""
        return InputConfig(pressure_topics={f"{prefix}{p.name}": p.name
                                            for p in mech.measurements.pressures})


class InputTracker:
    """The latest accepted value and stamp (ns) of every input of one mechanism."""

    def __init__(self, mech: Mechanism, config: InputConfig) -> None:
        self.config = config
        self.angle_names = frozenset(a.name for a in mech.measurements.angles)
        self.cylinder_names = frozenset(mech.measurements.cylinders)
        self.pressure_names = frozenset(config.pressure_topics.values())
        known_pressures = {p.name for p in mech.measurements.pressures}
        unknown = sorted(self.pressure_names - known_pressures)
        if unknown:
            raise InputError(f"pressure sensor(s) {', '.join(unknown)} are not in the mechanism's "
                             f"measurements.pressures ({', '.join(sorted(known_pressures)) or 'none'})")
        measured = self.angle_names | self.cylinder_names
        bad_targets = sorted(set(config.joint_map.values()) - measured)
        if bad_targets:
            raise InputError(f"joint_map targets {', '.join(bad_targets)} are not measured angles or "
                             f"cylinders of the mechanism ({', '.join(sorted(measured))})")
        self._joint_to_input = {name: name for name in measured}
        self._joint_to_input.update(config.joint_map)
        self._values: dict[str, float] = {}
        self._stamps: dict[str, int] = {}

    @property
    def required(self) -> frozenset[str]:
        """Names of every input a solve needs (angles, cylinder lengths, mapped pressures)."""
        return self.angle_names | self.cylinder_names | self.pressure_names

    def update_joint_state(self, names: Sequence[str], positions: Sequence[float], stamp_ns: int) -> list[str]:
        """Accept a JointState (positions rad or m); returns the inputs it updated.

        Joints that map to no measurement are ignored unless none maps at all. Raises
        InputError for arrays of different lengths, NaN/inf or an unknown joint name.
        """
        if len(names) != len(positions):
            raise InputError(f"JointState has {len(names)} names but {len(positions)} positions: "
                             "the arrays must have the same length")
        updates: dict[str, float] = {}
        for name, value in zip(names, positions):
            target = self._joint_to_input.get(name)
            if target is None:
                continue
            value = float(value)
            if not math.isfinite(value):
                unit = "rad" if target in self.angle_names else "m"
                raise InputError(f"JointState joint '{name}' position is {value} {unit}: "
                                 "a finite value is required")
            updates[target] = value
        if not updates:
            expected = ", ".join(sorted(self._joint_to_input))
            raise InputError(f"JointState joint name(s) {', '.join(map(repr, names)) or '(none)'} are unknown: "
                             f"expected {expected} (map others with the joint_map parameter)")
        self._store(updates, stamp_ns)
        return sorted(updates)

    def update_pressure(self, topic: str, fluid_pressure: float, stamp_ns: int) -> str:
        """Accept a FluidPressure (Pa, absolute or gauge per config); returns the sensor name.

        Stores gauge pressure. Raises InputError for NaN/inf or a negative absolute pressure.
        """
        sensor = self.config.pressure_topics.get(topic)
        if sensor is None:
            raise InputError(f"FluidPressure on topic '{topic}' maps to no pressure sensor "
                             f"(pressure_topics: {', '.join(sorted(self.config.pressure_topics))})")
        value = float(fluid_pressure)
        if not math.isfinite(value):
            raise InputError(f"pressure '{sensor}' (topic '{topic}') is {value} Pa: a finite value is required")
        absolute = value if self.config.pressure_absolute else value + self.config.atmospheric_pressure
        if absolute < 0.0:
            kind = "absolute" if self.config.pressure_absolute else "gauge"
            raise InputError(f"pressure '{sensor}' (topic '{topic}') is {value:.6g} Pa {kind}: "
                             f"a negative absolute pressure ({absolute:.6g} Pa) is impossible; "
                             "check the sensor and the pressure_absolute parameter")
        gauge = absolute - self.config.atmospheric_pressure
        self._store({sensor: gauge}, stamp_ns)
        return sensor

    def inputs_at(self, stamp_ns: int) -> Inputs:
        """The inputs of a solve triggered at `stamp_ns` (ns); StaleInputError if any is missing or old."""
        limit_ns = int(self.config.staleness_limit_s * 1e9)
        missing = sorted(self.required - self._values.keys())
        stale = sorted(name for name in self.required & self._values.keys()
                       if stamp_ns - self._stamps[name] > limit_ns)
        if missing or stale:
            parts = []
            if missing:
                parts.append(f"no value yet for {', '.join(missing)}")
            if stale:
                ages = ", ".join(f"{n} ({(stamp_ns - self._stamps[n]) * 1e-9:.3f} s old)" for n in stale)
                parts.append(f"stale: {ages} > staleness limit {self.config.staleness_limit_s} s")
            raise StaleInputError("; ".join(parts))
        return Inputs(cylinders=self._pick(self.cylinder_names), angles=self._pick(self.angle_names),
                      pressures=self._pick(self.pressure_names))

    def _pick(self, names: Iterable[str]) -> dict[str, float]:
        return {name: self._values[name] for name in sorted(names)}

    def _store(self, updates: Mapping[str, float], stamp_ns: int) -> None:
        self._values.update(updates)
        self._stamps.update(dict.fromkeys(updates, int(stamp_ns)))
