"""The monitor's configuration as one typed, recordable value (no rclpy).

Everything that decides what the monitor computes from its inputs lives here: the mechanism
(as given: preset name or file, plus scalar overrides such as the implement mass), how sensor
messages map onto the mechanism's measurements, the pressure convention, the time limits and
the topic names. The node builds it from its parameters, records it in its bag (YAML text on
CONFIG_TOPIC, a new copy at every runtime parameter change), and the replay rebuilds the same
monitor from the recorded copies. Units SI (Pa, s, kg); the dead-centre threshold in degrees.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field, fields, replace
from typing import Any, Mapping

import yaml

from linkage_monitor.mechanics import InputError, Mechanism
from linkage_monitor.mechanics.constants import ATMOSPHERIC_PRESSURE
from linkage_monitor.mechanics.reduced import DEAD_CENTRE_TRANSMISSION_DEG

CONFIG_TOPIC = "/linkage_monitor/config"
"""Topic (std_msgs/String, YAML of a MonitorConfig) on which the node records its configuration."""

IMPLEMENT_MASS_SOURCES = ("file", "estimate", "estimate_when_confident")   # MonitorConfig.implement_mass_source


@dataclass(frozen=True)
class Topics:
    """Resolved (absolute) names of the monitor's input and output topics."""

    joint_states: str = "/joint_states"
    hinge_reactions: str = "/hinge_reactions"
    hitch_state: str = "/hitch_state"
    steerability: str = "/steerability"
    diagnostics: str = "/diagnostics"
    markers: str = "/linkage_markers"
    imu: str = ""   # the tractor body's sensor_msgs/Imu; '': none


@dataclass(frozen=True)
class MonitorConfig:
    """How the monitor turns sensor messages into results.

    mechanism: preset name or YAML path as given (for the record; the description itself is
    recorded beside it). overrides: dotted key -> value applied to the description
    (``implement.mass`` kg, ``tractor.mass`` kg, ``tractor.front_ballast.mass`` kg,
    ``tractor.ratio_min`` -). joint_map: JointState joint name -> measurement name (angle rad,
    cylinder length m); unlisted measurements are expected under their own name.
    pressure_topics: resolved FluidPressure topic -> pressure-sensor name. pressure_absolute:
    FluidPressure carries absolute pressure (its definition) or gauge. atmospheric_pressure: Pa.
    staleness_limit_s: s, largest age of any input at a solve. stamp_tolerance_s: s, largest
    distance of a header stamp from the monitor's clock. kinetostatics: use JointState
    velocities (and their differences) for inertia loads (Naumenko et al. 2021). dead_centre_transmission_deg:
    degrees, a pose whose smallest transmission angle along the linkage's chain of dyads is below
    this is a dead centre (``Solver(dead_centre_transmission_deg=)``). uncertainty: every solved pose
    carries the error budget of the mechanism's declared error sources (``mechanics.uncertainty``),
    and the machine-level limits are judged on their 95 % intervals (``monitoring.bounds``).
    implement: a bundled implement's name or an implement file's path (``mechanics.implements``)
    hung on the mechanism; '' keeps the mechanism file's. implement_mass_source: where the
    machine-level results take the implement's mass and cg from, ``file`` (the default),
    ``estimate`` or ``estimate_when_confident`` (the weighing estimator, which runs only then:
    ``monitoring.implement_mass``). imu_frame: the frame_id the IMU's messages must carry (its axes
    the tractor body's, REP 103); imu_x: m, where it sits on the body, ahead of the rear wheels'
    ground contact (``mechanics.dynamics``; with ``topics.imu``).
    """

    mechanism: str
    overrides: Mapping[str, float] = field(default_factory=dict)
    topics: Topics = field(default_factory=Topics)
    joint_map: Mapping[str, str] = field(default_factory=dict)
    pressure_topics: Mapping[str, str] = field(default_factory=dict)
    pressure_absolute: bool = True
    atmospheric_pressure: float = ATMOSPHERIC_PRESSURE
    staleness_limit_s: float = 0.5
    stamp_tolerance_s: float = 10.0
    kinetostatics: bool = False
    dead_centre_transmission_deg: float = DEAD_CENTRE_TRANSMISSION_DEG
    uncertainty: bool = False
    implement: str = ""
    implement_mass_source: str = "file"
    imu_frame: str = "imu_link"
    imu_x: float = 0.0

    def __post_init__(self) -> None:
        if self.implement_mass_source not in IMPLEMENT_MASS_SOURCES:
            raise InputError(f"implement_mass_source '{self.implement_mass_source}': expected one of "
                             f"{', '.join(IMPLEMENT_MASS_SOURCES)}")

    @staticmethod
    def default(spec: str, mech: Mechanism, namespace: str = "/") -> MonitorConfig:
        """Identity joint names, one topic ``<namespace>pressure/<sensor>`` per pressure sensor."""
        ns = namespace.rstrip("/") + "/"
        return MonitorConfig(mechanism=spec, pressure_topics={f"{ns}pressure/{p.name}": p.name
                                                              for p in mech.measurements.pressures})

    def with_overrides(self, overrides: Mapping[str, float]) -> MonitorConfig:
        """A copy with these dotted-key overrides added (later values win)."""
        return replace(self, overrides={**self.overrides, **overrides})

    def to_yaml(self) -> str:
        """The configuration as YAML text (what the bag records)."""
        data = asdict(self)
        data["overrides"] = dict(self.overrides)
        return yaml.safe_dump(data, sort_keys=False)

    @staticmethod
    def from_yaml(text: str, source: str = "recorded configuration") -> MonitorConfig:
        """Parse ``to_yaml`` output; InputError naming ``source`` if it is not one."""
        try:
            data = yaml.safe_load(text)
            known = {f.name for f in fields(MonitorConfig)}
            unknown = sorted(set(data) - known)
            if unknown:
                raise InputError(f"{source}: unknown key(s) {', '.join(unknown)}")
            data["topics"] = Topics(**data.get("topics", {}))
            return MonitorConfig(**data)
        except (yaml.YAMLError, TypeError, AttributeError) as exc:
            raise InputError(f"{source}: not a monitor configuration ({exc})") from exc

    def describe(self) -> dict[str, Any]:
        """Short key-values for logs: what differs from the defaults."""
        base = MonitorConfig(self.mechanism)
        return {f.name: getattr(self, f.name) for f in fields(self) if getattr(self, f.name) != getattr(base, f.name)}
