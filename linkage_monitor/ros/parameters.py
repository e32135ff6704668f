"""The live node's parameters as one table (``PARAMETERS``), and everything read from it: the
ranges checked, the MonitorConfig built from the parameters and changed at run time, the mechanism
overrides, ``linkage_monitor_node --help`` and the README's parameter table (``tools/readme_parameters.py``
writes it, ``test/test_docs.py`` checks it). No rclpy here: the node (``ros.node``) declares them
with descriptors built from the same table.

Each parameter names what it sets: a MonitorConfig field (``config``), or a scalar of the mechanism
description as a dotted key (``override``: ``implement.mass`` kg, ...), or neither (the node's
own: QoS, recording, Rerun, markers). Units SI (Pa, s, kg, Hz, B); the dead-centre threshold in degrees.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Any, Callable, Mapping

from linkage_monitor.mechanics import Mechanism
from linkage_monitor.mechanics.constants import ATMOSPHERIC_PRESSURE
from linkage_monitor.mechanics.reduced import DEAD_CENTRE_TRANSMISSION_DEG
from linkage_monitor.monitoring.config import MonitorConfig, Topics
from linkage_monitor.monitoring.name_value import name_value
from linkage_monitor.wire.markers import DEFAULT_RATE_HZ as DEFAULT_MARKER_RATE_HZ


@dataclass(frozen=True)
class Declaration:
    """One node parameter: its name, default, unit ('' for none), description, whether it may be
    changed at run time (else it is read at start only), its range [lo, hi] (numbers; None for none),
    and what it sets: ``config``, a MonitorConfig field ('' for none), or ``override``, a dotted key
    of the mechanism description ('' for none)."""

    name: str
    default: Any
    unit: str
    description: str
    runtime: bool
    bounds: tuple[float, float] | None = None
    config: str = ""
    override: str = ""

    @property
    def read_only(self) -> bool:
        """Read at start only (the descriptor's read_only)."""
        return not self.runtime


PARAMETERS: dict[str, Declaration] = {d.name: d for d in (
    Declaration("mechanism", "belarus_1221", "", "Preset name or path of the mechanism YAML "
                "(docs/mechanism-schema.md)", False, config="mechanism"),
    Declaration("joint_state_topic", "joint_states", "", "Input sensor_msgs/JointState topic (angles rad, cylinder "
                "lengths m)", False, config="topics.joint_states"),
    Declaration("joint_map", [""], "", "JointState names mapped to the mechanism's measurements, as "
                "'joint_name=measurement' (unlisted measurements are expected under their own name)", False,
                config="joint_map"),
    Declaration("pressure_topics", [""], "", "One sensor_msgs/FluidPressure topic per cylinder chamber, as "
                "'topic=pressure_sensor'; default 'pressure/<sensor>' for every sensor; ['none']: no pressures (the "
                "implement load is then implement_mass, the pressures predicted)", False, config="pressure_topics"),
    Declaration("pressure_absolute", True, "", "FluidPressure carries absolute pressure (true, per its definition) "
                "or gauge", False, config="pressure_absolute"),
    Declaration("atmospheric_pressure", ATMOSPHERIC_PRESSURE, "Pa", "subtracted from absolute pressures", False,
                (50_000.0, 110_000.0), config="atmospheric_pressure"),
    Declaration("imu_topic", "", "", "Input sensor_msgs/Imu topic of an IMU on the tractor body (m/s², rad/s): the "
                "steerability's dynamic axle loads and margin on the road, the static ones at rest (docs/dynamics.md); "
                "'' (the default): no IMU", False, config="topics.imu"),
    Declaration("imu_frame", "imu_link", "", "the frame_id the IMU's messages carry; its axes must be the tractor "
                "body's (REP 103: x forward, y left, z up), messages in another frame are refused", False,
                config="imu_frame"),
    Declaration("imu_x", 0.0, "m", "where the IMU sits on the tractor body: ahead of the rear wheels' ground contact "
                "(over the front axle: the wheelbase; there the dynamic margin needs the least pitch acceleration, "
                "docs/dynamics.md)", False, (-20.0, 20.0), config="imu_x"),
    Declaration("sensor_qos", "sensor_data", "", "QoS of the inputs: 'sensor_data' (best effort, keep last 5) or "
                "'reliable' (keep last reliable_queue_depth)", False),
    Declaration("reliable_queue_depth", 10_000, "messages", "queued per input topic with sensor_qos 'reliable': a "
                "burst (e.g. a bag played faster than real time) waits there instead of being dropped; what does not "
                "fit is reported lost", False, (1, 1_000_000)),
    Declaration("staleness_limit", 0.5, "s", "no solve if the stamps of the inputs differ by more than this; "
                "/diagnostics goes STALE when no input has been solved for this long (steady clock, checked every "
                "second)", True, (0.0, 3600.0), config="staleness_limit_s"),
    Declaration("stamp_tolerance", 10.0, "s", "an input whose header stamp is farther than this from the node's clock "
                "is refused (ERROR)", True, (0.001, 1e6), config="stamp_tolerance_s"),
    Declaration("trusted_publishers", [""], "", "The one node to take an input topic from when two publish it, as "
                "'topic=/namespace/node' (its other publishers' messages are not used, recorded on "
                "'<topic>/refused'); an input topic without one: while two nodes publish it (both heard within "
                "staleness_limit) neither is used (sensors_disagree, naming both)", False),
    Declaration("kinetostatics", False, "", "Add inertia loads from JointState velocities and their change "
                "(Naumenko et al. 2021)", False, config="kinetostatics"),
    Declaration("dead_centre_transmission_deg", DEAD_CENTRE_TRANSMISSION_DEG, "degrees", "a pose whose smallest "
                "transmission angle along the linkage's chain of dyads is below this is a dead centre (ERROR, no "
                "outputs), except a load inferred from a pressure whose own is (published, WARN load_inference_weak "
                "on its amplification: docs/dead-centre.md); applies from the next message", True, (0.0, 45.0),
                config="dead_centre_transmission_deg"),
    Declaration("implement_mass", -1.0, "kg", "implement mass; -1 (exactly) keeps the mechanism file's value, other "
                "negatives are refused; applies from the next message", True, (-1.0, 100_000.0),
                override="implement.mass"),
    Declaration("implement", "", "", "bundled implement name or implement file path hung on the mechanism "
                "(docs/implements.md); '' keeps the mechanism file's implement; applies from the next message", True,
                config="implement"),
    Declaration("implement_mass_source", "file", "", "implement mass and cg used by the machine-level results: "
                "'file' (the mechanism or implement file's), 'estimate' (weighed while working) or "
                "'estimate_when_confident' (docs/weighing.md); applies from the next message", True,
                config="implement_mass_source"),
    Declaration("uncertainty", False, "", "carry each pose's error budget: publish every output's standard "
                "uncertainty (1 sigma, the *_u fields; NaN when off) and judge the limits on their 95 % "
                "intervals (steerability_uncertain, lift_reserve_uncertain, axle_load_uncertain; docs/accuracy.md); "
                "about 1.4x the step's time on a one-DOF linkage (its stroke tabulated), several times that where "
                "each pose's moved poses are solved (docs/accuracy.md); applies from the next message", True,
                config="uncertainty"),
    Declaration("tractor_mass", -1.0, "kg", "tractor operating mass without ballast; -1 (exactly) keeps the file's "
                "value", True, (-1.0, 100_000.0), override="tractor.mass"),
    Declaration("front_ballast_mass", -1.0, "kg", "front ballast; -1 (exactly) keeps the file's value", True,
                (-1.0, 10_000.0), override="tractor.front_ballast.mass"),
    Declaration("ratio_min", -1.0, "", "minimum share of weight on the steered axle (Popov 2009: 0.2); -1 (exactly) "
                "keeps the file's value", True, (-1.0, 1.0), override="tractor.ratio_min"),
    Declaration("record", True, "", "Record every input and output to a rosbag2 MCAP bag", False),
    Declaration("record_dir", "out/bags", "", "Directory under which each run's bag directory is created", False),
    Declaration("record_name", "", "", "Name of this run's bag directory; empty: <mechanism>_<YYYYmmdd_HHMMSS>",
                False),
    Declaration("max_bag_size", 0, "B", "the bag starts a new file once the current one has reached this size (as "
                "ros2 bag record --max-bag-size); 0: one file; below 86016 (rosbag2's smallest split size) refused at "
                "start", False, (0, 1 << 50)),
    Declaration("max_bag_duration", 0.0, "s", "the bag starts a new file once the current one spans this long (as "
                "ros2 bag record --max-bag-duration); 0: one file", False, (0.0, 1e9)),
    Declaration("rerun", "off", "", "Rerun logging: 'off', 'save' (to rerun_path) or 'connect' (to a running "
                "viewer)", False),
    Declaration("rerun_path", "out/linkage_monitor.rrd", "", "The .rrd file written when rerun = 'save'", False),
    Declaration("rerun_rate", 30.0, "Hz", "largest rate at which solved poses are logged to Rerun (the bag keeps "
                "every one)", False, (0.1, 10_000.0)),
    Declaration("marker_rate", DEFAULT_MARKER_RATE_HZ, "Hz", "largest rate at which the linkage is published as a "
                "visualization_msgs/MarkerArray on linkage_markers (frame 'linkage'); 0: not at all", False,
                (0.0, 1000.0)),
)}
SENSOR_QOS = ("sensor_data", "reliable")
RERUN_MODES = ("off", "save", "connect")
# MonitorConfig fields built by monitor_config from their parameters' text (resolved topics, NAME=VALUE entries)
STRUCTURED = frozenset({"topics.joint_states", "topics.imu", "joint_map", "pressure_topics"})
KEEP_FILE_VALUE = -1.0   # an override parameter's value that keeps the mechanism file's own value (the default)


def check_bounds(name: str, value: Any) -> None:
    """ValueError naming parameter ``name`` if ``value`` is outside its declared range. rclpy's own
    range check lets a double within a relative 1e-6 of an end pass (``45.0000001`` for 0 to 45):
    the range is the documented one, exactly."""
    d = PARAMETERS.get(name)
    if d is None or d.bounds is None or isinstance(value, bool) or not isinstance(value, (int, float)):
        return
    lo, hi = d.bounds
    if not lo <= value <= hi:   # NaN too
        unit = f" {d.unit}" if d.unit else ""
        raise ValueError(f"parameter {name} = {value!r}: outside its range [{lo:g}, {hi:g}]{unit}; give a value "
                         "inside it")


def check_choices(p: Mapping[str, Any]) -> None:
    """ValueError naming the parameter if sensor_qos or rerun is none of its choices."""
    if p["sensor_qos"] not in SENSOR_QOS:
        raise ValueError(f"parameter sensor_qos = '{p['sensor_qos']}': expected one of {', '.join(SENSOR_QOS)}")
    if p["rerun"] not in RERUN_MODES:
        raise ValueError(f"parameter rerun = '{p['rerun']}': expected one of {', '.join(RERUN_MODES)}")


def is_double(name: str) -> bool:
    """Whether parameter ``name`` is a double (an integer given for it is taken as that double)."""
    d = PARAMETERS.get(name)
    return d is not None and isinstance(d.default, float)


def override_value(name: str, value: float) -> float | None:
    """The override that parameter ``name`` (one with an ``override``) sets: its value (>= 0), or None for
    KEEP_FILE_VALUE; ValueError naming the parameter for any other value."""
    value = float(value)
    if value == KEEP_FILE_VALUE:
        return None
    if not value >= 0.0:   # NaN too
        raise ValueError(f"parameter {name} = {value}: a value must be >= 0, or exactly {KEEP_FILE_VALUE:g} to keep "
                         "the mechanism file's value")
    return value


def _typed(d: Declaration, value: Any) -> Any:
    """A scalar parameter's value as its MonitorConfig field holds it."""
    if isinstance(d.default, bool):
        return bool(value)
    if isinstance(d.default, float):
        return float(value)
    return value


def _pairs(items: list[str], what: str) -> dict[str, str]:
    return dict(name_value(item, f"parameter {what}:") for item in items if item)


def trusted_publishers(items: list[str], resolve: Callable[[str], str]) -> dict[str, str]:
    """Parameter ``trusted_publishers``: resolved topic -> the trusted node's full name (``/node`` for ``node``);
    InputError naming a malformed entry."""
    return {resolve(topic): node if node.startswith("/") else f"/{node}"
            for topic, node in _pairs(items, "trusted_publishers").items()}


def monitor_config(p: Mapping[str, Any], mech: Mechanism, resolve: Callable[[str], str]) -> MonitorConfig:
    """The MonitorConfig of the node's parameters ``p`` (topic names resolved by ``resolve``)."""
    overrides = {d.override: v for d in PARAMETERS.values()
                 if d.override and (v := override_value(d.name, p[d.name])) is not None}
    scalars = {d.config: _typed(d, p[d.name]) for d in PARAMETERS.values() if d.config and d.config not in STRUCTURED}
    if list(p["pressure_topics"]) == ["none"]:
        pressure_topics: dict[str, str] = {}
    else:
        given = _pairs(list(p["pressure_topics"]), "pressure_topics")
        pressure_topics = ({resolve(t): s for t, s in given.items()} if given
                           else {resolve(f"pressure/{s.name}"): s.name for s in mech.measurements.pressures})
    topics = Topics(joint_states=resolve(p["joint_state_topic"]), hinge_reactions=resolve("hinge_reactions"),
                    hitch_state=resolve("hitch_state"), steerability=resolve("steerability"),
                    diagnostics="/diagnostics", markers=resolve("linkage_markers"),
                    imu=resolve(p["imu_topic"]) if p["imu_topic"] else "")
    return MonitorConfig(overrides=overrides, topics=topics, joint_map=_pairs(list(p["joint_map"]), "joint_map"),
                         pressure_topics=pressure_topics, **scalars)


def config_with(config: MonitorConfig, changes: Mapping[str, Any]) -> MonitorConfig:
    """``config`` with the runtime parameters among ``changes`` (name -> value) applied; the others
    (read at start only, or not the node's) are left out. ValueError for a refused override value."""
    overrides = dict(config.overrides)
    for name, value in changes.items():
        d = PARAMETERS.get(name)
        if d is None or not d.runtime:
            continue
        if d.override:
            override = override_value(name, value)
            if override is not None:
                overrides[d.override] = override
            else:
                overrides.pop(d.override, None)
        else:
            config = replace(config, **{d.config: _typed(d, value)})
    return replace(config, overrides=overrides)


def usage_table() -> str:
    """The parameters as ``linkage_monitor_node --help`` lists them: name, default, unit, description."""
    rows = [("name", "default", "unit", "description")]
    rows += [(d.name, repr(d.default), d.unit or "-", d.description + (" (settable at run time)" if d.runtime else ""))
             for d in PARAMETERS.values()]
    widths = [max(len(row[k]) for row in rows) for k in range(3)]
    return "\n".join("  " + "  ".join(cell.ljust(w) for cell, w in zip(row, widths)) + "  " + row[3] for row in rows)


def _markdown_default(value: Any) -> str:
    if isinstance(value, bool):
        return f"`{str(value).lower()}`"
    if isinstance(value, str):
        return f"`{value}`" if value else "`''`"
    if isinstance(value, list):
        return f"`{value!r}`"
    return repr(value)


def _markdown_range(d: Declaration) -> str:
    if d.bounds is None:
        return ""
    lo, hi = d.bounds
    return f"{lo} to {hi}" if isinstance(d.default, int) else f"{lo:g} to {hi:g}"


def readme_table() -> str:
    """The README's parameter table (markdown): name, default, unit, range, runtime, description."""
    lines = ["| parameter | default | unit | range | runtime | meaning |", "|---|---|---|---|---|---|"]
    for d in PARAMETERS.values():
        meaning = d.description.replace("|", "\\|").replace("<", "\\<")   # '<sensor>' is not an HTML tag
        lines.append(f"| `{d.name}` | {_markdown_default(d.default)} | {d.unit} | {_markdown_range(d)} | "
                     f"{'yes' if d.runtime else ''} | {meaning} |")
    return "\n".join(lines)
