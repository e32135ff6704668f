"""The live node: joint angles and cylinder pressures in, hinge reactions, hitch state,
steerability and /diagnostics out (a thin rclpy adapter around monitor.Monitor).

Topics (defaults): `joint_states` (sensor_msgs/JointState: angles rad, cylinder lengths m),
`pressure/<sensor>` (sensor_msgs/FluidPressure, Pa), out `hinge_reactions`, `hitch_state`,
`steerability`, `/diagnostics`, and `mechanism_description` (std_msgs/String, the mechanism
YAML, transient local). Units SI; frame x forward, z up, origin at the rear wheels' ground
contact. Outputs carry the header stamp of the triggering input.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path
from typing import Any

import rclpy
import yaml
from diagnostic_msgs.msg import DiagnosticArray
from rcl_interfaces.msg import (FloatingPointRange, ParameterDescriptor, ParameterType,
                                SetParametersResult)
from rclpy.executors import ExternalShutdownException
from rclpy.node import Node
from rclpy.qos import (DurabilityPolicy, QoSProfile, ReliabilityPolicy, qos_profile_sensor_data)
from sensor_msgs.msg import FluidPressure, JointState
from std_msgs.msg import String

from linkage_monitor.ros import messages as out
from linkage_monitor.ros.diagnostics import DiagnosticGate, diagnostic_array
from linkage_monitor.monitoring.inputs import ATMOSPHERIC_PRESSURE, InputConfig
from linkage_monitor.monitoring.name_value import name_value
from linkage_monitor.mechanics import LinkageError, load_mechanism, load_preset, preset_names
from linkage_monitor.monitoring.core import ERROR, WARN, Monitor, Step
from linkage_monitor.msg import HingeReactions, HitchState, Steerability
from linkage_monitor.bag.writer import BagWriter
from linkage_monitor.viz.rerun_view import RerunView, machine_series

NODE_NAME = "linkage_monitor"
LATCHED = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE,
                     durability=DurabilityPolicy.TRANSIENT_LOCAL)
OUTPUT_QOS = QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE)
HEARTBEAT_S = 1.0  # s, /diagnostics is repeated at least this often

# name: (default, description, read_only, (min, max) for doubles)
PARAMETERS: dict[str, tuple[Any, str, bool, tuple[float, float] | None]] = {
    "mechanism": ("belarus_1221", "Preset name or path of the mechanism YAML (docs/mechanism-schema.md)",
                  True, None),
    "joint_state_topic": ("joint_states", "Input sensor_msgs/JointState topic (angles rad, cylinder lengths m)",
                          True, None),
    "joint_map": ([""], "JointState names mapped to the mechanism's measurements, as 'joint_name=measurement' "
                  "(unlisted measurements are expected under their own name)", True, None),
    "pressure_topics": ([""], "One sensor_msgs/FluidPressure topic per cylinder chamber, as "
                        "'topic=pressure_sensor'; default 'pressure/<sensor>' for every sensor; ['none']: no "
                        "pressures (the implement load is then implement_mass, the pressures predicted)", True, None),
    "pressure_absolute": (True, "FluidPressure carries absolute pressure (true, per its definition) or gauge",
                          True, None),
    "atmospheric_pressure": (ATMOSPHERIC_PRESSURE, "Pa, subtracted from absolute pressures", True,
                             (50_000.0, 110_000.0)),
    "sensor_qos": ("sensor_data", "QoS of the inputs: 'sensor_data' (best effort) or 'reliable'", True, None),
    "staleness_limit": (0.5, "s, no solve if any input is older than this relative to the triggering message",
                        False, (0.0, 3600.0)),
    "implement_mass": (-1.0, "kg, implement mass; -1 keeps the mechanism file's value; applies from the next "
                       "message", False, (-1.0, 100_000.0)),
    "tractor_mass": (-1.0, "kg, tractor operating mass without ballast; -1 keeps the file's value", False,
                     (-1.0, 100_000.0)),
    "front_ballast_mass": (-1.0, "kg, front ballast; -1 keeps the file's value", False, (-1.0, 10_000.0)),
    "ratio_min": (-1.0, "minimum share of weight on the steered axle (seed 003: 0.2); -1 keeps the file's value",
                  False, (-1.0, 1.0)),
    "record": (True, "Record every input and output to a rosbag2 MCAP bag", True, None),
    "record_dir": ("out/bags", "Directory under which each run's bag directory is created", True, None),
    "record_name": ("", "Name of this run's bag directory; empty: <mechanism>_<YYYYmmdd_HHMMSS>", True, None),
    "rerun": ("off", "Rerun logging: 'off', 'save' (to rerun_path) or 'connect' (to a running viewer)", True,
              None),
    "rerun_path": ("out/linkage_monitor.rrd", "The .rrd file written when rerun = 'save'", True, None),
}
OVERRIDES = {"implement_mass": "implement.mass", "tractor_mass": "tractor.mass",
             "front_ballast_mass": "tractor.front_ballast.mass", "ratio_min": "tractor.ratio_min"}


def _descriptor(name: str) -> ParameterDescriptor:
    default, text, read_only, bounds = PARAMETERS[name]
    desc = ParameterDescriptor(name=name, description=text, read_only=read_only)
    if bounds is not None:
        desc.floating_point_range = [FloatingPointRange(from_value=bounds[0], to_value=bounds[1], step=0.0)]
    if isinstance(default, list):
        desc.type = ParameterType.PARAMETER_STRING_ARRAY
    return desc


def _pairs(items: list[str], what: str) -> dict[str, str]:
    return dict(name_value(item, f"parameter {what}:") for item in items if item)


def load_description(spec: str):
    """A Mechanism from a preset name or a YAML path."""
    if spec in preset_names():
        return load_preset(spec)
    return load_mechanism(Path(spec))


class LinkageMonitorNode(Node):
    """Subscribes to the sensors, solves on every message, publishes results and diagnostics."""

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(NODE_NAME, **kwargs)
        for name, (default, *_rest) in PARAMETERS.items():
            self.declare_parameter(name, default, _descriptor(name))
        p = {name: self.get_parameter(name).value for name in PARAMETERS}
        mech = load_description(p["mechanism"])
        overrides = {OVERRIDES[k]: float(p[k]) for k in OVERRIDES if float(p[k]) >= 0.0}
        if overrides:
            mech = mech.with_overrides(overrides)
        config = InputConfig.default(mech)
        if list(p["pressure_topics"]) == ["none"]:
            pressure_topics = {}
        else:
            pressure_topics = _pairs(list(p["pressure_topics"]), "pressure_topics") or dict(config.pressure_topics)
        config = InputConfig(joint_map=_pairs(list(p["joint_map"]), "joint_map"), pressure_topics=pressure_topics,
                             pressure_absolute=bool(p["pressure_absolute"]),
                             atmospheric_pressure=float(p["atmospheric_pressure"]),
                             staleness_limit_s=float(p["staleness_limit"]))
        self.monitor = Monitor(mech, config)
        self.status_name = f"{NODE_NAME}: {mech.name}"
        self.diagnostic_gate = DiagnosticGate()
        self._last_diag = 0.0
        self._last_step: Step | None = None

        self.pub_hinges = self.create_publisher(HingeReactions, "hinge_reactions", OUTPUT_QOS)
        self.pub_hitch = self.create_publisher(HitchState, "hitch_state", OUTPUT_QOS)
        self.pub_steer = self.create_publisher(Steerability, "steerability", OUTPUT_QOS)
        self.pub_diag = self.create_publisher(DiagnosticArray, "/diagnostics", OUTPUT_QOS)
        self.pub_mech = self.create_publisher(String, "mechanism_description", LATCHED)
        description = yaml.safe_dump(dict(mech.raw), sort_keys=False, allow_unicode=True)
        self.pub_mech.publish(String(data=description))

        self.recorder: BagWriter | None = None
        if p["record"]:
            bag_dir = Path(p["record_dir"]) / (p["record_name"] or time.strftime(f"{mech.name}_%Y%m%d_%H%M%S"))
            self.recorder = BagWriter(bag_dir)
            self.recorder.record_mechanism(description, time.time_ns())
            self.get_logger().info(f"recording to {bag_dir}")
        self.rerun = None
        if p["rerun"] == "save":
            self.rerun = RerunView.to_file(mech, p["rerun_path"])
        elif p["rerun"] == "connect":
            self.rerun = RerunView.to_viewer(mech)
        elif p["rerun"] != "off":
            raise ValueError(f"parameter rerun = '{p['rerun']}': expected 'off', 'save' or 'connect'")

        if p["sensor_qos"] not in ("sensor_data", "reliable"):
            raise ValueError(f"parameter sensor_qos = '{p['sensor_qos']}': expected 'sensor_data' or 'reliable'")
        input_qos = qos_profile_sensor_data if p["sensor_qos"] == "sensor_data" else QoSProfile(
            depth=100, reliability=ReliabilityPolicy.RELIABLE)
        self.input_qos = input_qos
        self.joint_topic = p["joint_state_topic"]
        self.create_subscription(JointState, self.joint_topic, self.on_joint_state, input_qos)
        for topic in config.pressure_topics:
            self.create_subscription(FluidPressure, topic,
                                     lambda msg, topic=topic: self.on_pressure(topic, msg), input_qos)
        self.create_timer(HEARTBEAT_S, self.on_heartbeat)
        self.add_on_set_parameters_callback(self.on_parameters)
        self.get_logger().info(
            f"monitoring '{mech.name}': {self.joint_topic} + {', '.join(config.pressure_topics) or 'no pressures'}")

    # ---- callbacks: short, the work is in Monitor -----------------------------------------------
    def on_joint_state(self, msg: JointState) -> None:
        """Record the JointState, solve, publish."""
        stamp = out.stamp_ns(msg.header)
        self._record(self.resolve_topic_name(self.joint_topic), msg, stamp, self.input_qos)
        self._publish(self.monitor.on_joint_state(list(msg.name), list(msg.position), stamp))

    def on_pressure(self, topic: str, msg: FluidPressure) -> None:
        """Record the FluidPressure, solve, publish."""
        stamp = out.stamp_ns(msg.header)
        self._record(self.resolve_topic_name(topic), msg, stamp, self.input_qos)
        self._publish(self.monitor.on_pressure(topic, msg.fluid_pressure, stamp))

    def on_heartbeat(self) -> None:
        """Repeat the last diagnostic at least every HEARTBEAT_S (diagnostic_updater style)."""
        if self._last_step is not None and time.monotonic() - self._last_diag >= HEARTBEAT_S:
            self._publish_diagnostic(self._last_step)

    def on_parameters(self, params: list) -> SetParametersResult:
        """Apply implement mass, tractor mass, ballast, ratio_min and staleness from the next message."""
        overrides = {OVERRIDES[p.name]: float(p.value) for p in params if p.name in OVERRIDES and p.value >= 0}
        try:
            if overrides:
                self.monitor.apply_overrides(overrides)
            for p in params:
                if p.name == "staleness_limit":
                    self.monitor.set_staleness_limit(float(p.value))
        except (LinkageError, ValueError) as exc:
            return SetParametersResult(successful=False, reason=str(exc))
        return SetParametersResult(successful=True)

    # ---- outputs --------------------------------------------------------------------------------
    def _publish(self, step: Step) -> None:
        if step.outputs is not None:
            o = step.outputs
            for topic, pub, msg in (("hinge_reactions", self.pub_hinges, o.hinge_reactions),
                                    ("hitch_state", self.pub_hitch, o.hitch_state),
                                    ("steerability", self.pub_steer, o.steerability)):
                pub.publish(msg)
                self._record(self.resolve_topic_name(topic), msg, step.stamp_ns, OUTPUT_QOS)
            if self.rerun is not None:
                m = step.machine
                self.rerun.log_pose(step.stamp_ns, step.result, machine_series(m.steerability, m.lift_capacity))
        elif self.rerun is not None and step.level == ERROR:
            self.rerun.log_status(step.stamp_ns, step.message)
        if self.diagnostic_gate.due(step):
            self._publish_diagnostic(step)
        self._last_step = step
        if step.level == ERROR:
            self.get_logger().error(step.message, throttle_duration_sec=1.0)
        elif step.level == WARN:
            self.get_logger().warning(step.message, throttle_duration_sec=1.0)

    def _publish_diagnostic(self, step: Step) -> None:
        msg = diagnostic_array(step, self.status_name, self.monitor.mechanism.name)
        self.pub_diag.publish(msg)
        self._record("/diagnostics", msg, step.stamp_ns, OUTPUT_QOS)
        self._last_diag = time.monotonic()

    def _record(self, topic: str, msg: Any, stamp_ns: int, qos: QoSProfile) -> None:
        if self.recorder is not None:
            self.recorder.write(topic, msg, stamp_ns, qos=qos)

    def close(self) -> None:
        """Finish the bag and the Rerun recording."""
        if self.recorder is not None:
            self.recorder.close()
            self.get_logger().info(f"bag written: {self.recorder.directory}")
        if self.rerun is not None:
            self.rerun.close()


def main(argv: list[str] | None = None) -> int:
    """Console script `linkage_monitor_node`: run until Ctrl-C / shutdown."""
    rclpy.init(args=argv if argv is not None else sys.argv)
    node = None
    try:
        node = LinkageMonitorNode()
        rclpy.spin(node)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except (LinkageError, ValueError) as exc:
        print(f"linkage_monitor_node: {exc}", file=sys.stderr)
        return 2
    finally:
        if node is not None:
            node.close()
            node.destroy_node()
        if rclpy.ok():
            rclpy.shutdown()
    return 0


if __name__ == "__main__":
    sys.exit(main())
