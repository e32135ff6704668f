"""The live node: joint angles and cylinder pressures in, hinge reactions, hitch state,
steerability and /diagnostics out — a thin rclpy driver of monitoring.core.Monitor.

Topics (defaults, relative to the node's namespace): `joint_states` (sensor_msgs/JointState:
angles rad, cylinder lengths m, velocities rad/s, m/s), `pressure/<sensor>`
(sensor_msgs/FluidPressure, Pa), out `hinge_reactions`, `hitch_state`, `steerability`,
`/diagnostics`, `mechanism_description` (std_msgs/String, the mechanism YAML, transient local),
`linkage_markers` (visualization_msgs/MarkerArray, frame `linkage`: the x-z plane at y = 0, m;
at `marker_rate`).
Units SI; frame x forward, z up, origin at the rear wheels' ground contact (REP 103). Outputs
carry the header stamp of the triggering input; receive times come from the node's clock
(`use_sim_time` is honoured).
"""

from __future__ import annotations

import gc
import os
import signal
import sys
import threading
import time
from pathlib import Path
from typing import Any, Callable

import rclpy
from diagnostic_msgs.msg import DiagnosticArray
from rcl_interfaces.msg import FloatingPointRange, IntegerRange, ParameterDescriptor, ParameterType, SetParametersResult
from rclpy.clock import Clock, ClockType
from rclpy.event_handler import PublisherEventCallbacks, SubscriptionEventCallbacks
from rclpy.exceptions import InvalidHandle, InvalidParameterTypeException, InvalidParameterValueException
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy, qos_profile_sensor_data
from rclpy.signals import SignalHandlerOptions
from sensor_msgs.msg import FluidPressure, JointState
from std_msgs.msg import String
from visualization_msgs.msg import MarkerArray

from linkage_monitor.bag.step_recorder import StepRecorder, mechanism_yaml
from linkage_monitor.bag.writer import BagError, BagWriter
from linkage_monitor.mechanics import LinkageError, apply_overrides, load_description
from linkage_monitor.mechanics.warm import compiled_kernels
from linkage_monitor.monitoring.config import MonitorConfig
from linkage_monitor.monitoring.core import Monitor, Step
from linkage_monitor.monitoring.findings import Level
from linkage_monitor.monitoring.freshness import Freshness
from linkage_monitor.monitoring.inputs import InputTracker
from linkage_monitor.monitoring.loss import LossCounter
from linkage_monitor.msg import HingeReactions, HitchState, Steerability
from linkage_monitor.ros.input_events import INCOMPATIBLE_QOS, LOST, InputEvents
from linkage_monitor.ros.parameters import (PARAMETERS, Declaration, check_bounds, check_choices, config_with,
                                            is_double, monitor_config, usage_table)
from linkage_monitor.ros.spin import InputSpinner
from linkage_monitor.wire.diagnostics import status_array
from linkage_monitor.wire.markers import DisplayGate
from linkage_monitor.wire.outputs import OutputEncoder
from linkage_monitor.wire.sensor_messages import FLUID_PRESSURE, JOINT_STATE, input_event
from linkage_monitor.wire.step_messages import StepMessenger

NODE_NAME = "linkage_monitor"
LATCHED = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL)
OUTPUT_QOS = QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE)   # a drained burst publishes in a row
HEARTBEAT_S = 1.0  # s, /diagnostics is repeated at least this often
STOP_POLL_S = 0.1  # s, the spin loop looks this often whether a signal asked it to stop
DRAIN_LIMIT = 200  # input messages worked off per executor callback (then timers and services run)
ABANDONED_RERUN: list[Any] = []   # Rerun views whose sink failed (LinkageMonitorNode._rerun_failed)
NAME_CHECK_S = 10.0  # s, how long after its start the node looks for another node of its name


def descriptor(d: Declaration) -> ParameterDescriptor:
    """The ParameterDescriptor of parameter ``d``: its unit and description, read-only, range, type."""
    text = f"{d.unit}, {d.description}" if d.unit else d.description
    desc = ParameterDescriptor(name=d.name, description=text, read_only=d.read_only)
    if d.bounds is not None and isinstance(d.default, int):
        desc.integer_range = [IntegerRange(from_value=int(d.bounds[0]), to_value=int(d.bounds[1]), step=1)]
    elif d.bounds is not None:
        desc.floating_point_range = [FloatingPointRange(from_value=d.bounds[0], to_value=d.bounds[1], step=0.0)]
    if isinstance(d.default, list):
        desc.type = ParameterType.PARAMETER_STRING_ARRAY
    return desc


class LinkageMonitorNode(Node):
    """Subscribes to the sensors, solves on every message, publishes results and diagnostics.

    A driver that brings its own inputs (the CAN bridge, ``linkage_monitor.can.node``) subclasses
    it with ``subscribes_sensors = False`` and hands its decoded inputs to ``_record_input`` /
    ``monitor`` / ``_publish`` as the sensor callbacks do.
    """

    subscribes_sensors = True

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(NODE_NAME, **kwargs)
        self._doubles_as_declared()
        for d in PARAMETERS.values():
            self.declare_parameter(d.name, d.default, descriptor(d))
        self.build_monitor()
        self.start_inputs()
        self.add_pre_set_parameters_callback(self.as_declared_types)
        self.add_on_set_parameters_callback(self.validate_parameters)
        self.add_post_set_parameters_callback(self.apply_parameters)
        gc.freeze()   # what start-up built (modules, kernels, layouts) is left out of every later collection
        config = self.monitor.config
        self.get_logger().info(f"monitoring '{self.monitor.description.name}': {config.topics.joint_states} + "
                               f"{', '.join(config.pressure_topics) or 'no pressures'}")

    def build_monitor(self) -> None:
        """The monitor of the node's parameters (every one checked before anything is created), its
        publishers, the recorder, the Rerun view, the physics kernels loaded: the node's start, and
        the configure of the managed node (``ros.lifecycle_node``)."""
        p = {name: self.get_parameter(name).value for name in PARAMETERS}
        # everything is validated before anything is created
        for name, value in p.items():
            check_bounds(name, value)
        check_choices(p)
        description = load_description(p["mechanism"])
        config = monitor_config(p, description, self.resolve_topic_name)
        self.monitor = Monitor(description, config)
        self.encoder = OutputEncoder()
        self.input_qos = (qos_profile_sensor_data if p["sensor_qos"] == "sensor_data" else
                          QoSProfile(depth=int(p["reliable_queue_depth"]), reliability=ReliabilityPolicy.RELIABLE))
        bag_dir = Path(p["record_dir"]) / (p["record_name"] or time.strftime(f"{description.name}_%Y%m%d_%H%M%S"))
        self.recorder = (StepRecorder(BagWriter(bag_dir, max_bag_size=p["max_bag_size"],
                                                max_bag_duration_s=p["max_bag_duration"]),
                                      config.topics, self.input_qos, OUTPUT_QOS)
                         if p["record"] else None)   # BagError: one line at start

        self.messenger = StepMessenger(description, f"{NODE_NAME}: {description.name}", float(p["marker_rate"]))
        self.loss = LossCounter()
        self._reported: Step | None = None   # the last step the gate let through: what the heartbeat repeats
        self.freshness = Freshness()   # STALE on /diagnostics when nothing was solved for staleness_limit
        self._stale = True   # the last status the heartbeat sent was STALE: the next step is reported
        self._last_heartbeat = 0.0
        self._started, self._name_checked = time.monotonic(), False   # the duplicate-name check (_check_name)
        self._recording_reported = False
        self._pending_params: dict[str, Any] = {}
        self.pub_hinges = self._publisher(HingeReactions, config.topics.hinge_reactions, OUTPUT_QOS)
        self.pub_hitch = self._publisher(HitchState, config.topics.hitch_state, OUTPUT_QOS)
        self.pub_steer = self._publisher(Steerability, config.topics.steerability, OUTPUT_QOS)
        self.pub_diag = self._publisher(DiagnosticArray, config.topics.diagnostics, OUTPUT_QOS)
        self.pub_mech = self._publisher(String, "mechanism_description", LATCHED)
        self.pub_mech.publish(String(data=mechanism_yaml(description)))
        if self.recorder is not None:
            self.recorder.begin(description, config, self._now())
            self.get_logger().info(f"recording to {bag_dir}")

        self.pub_markers = self._publisher(MarkerArray, config.topics.markers, OUTPUT_QOS)
        self.rerun = None
        self._rerun_target = p["rerun_path"] if p["rerun"] == "save" else "(viewer)"
        self.rerun_gate = DisplayGate(float(p["rerun_rate"]))
        if p["rerun"] != "off":
            from linkage_monitor.viz.rerun_view import RerunView
            self.rerun = (RerunView.to_file(description, p["rerun_path"]) if p["rerun"] == "save"
                          else RerunView.to_viewer(description))

        # the kernels are loaded before the inputs are subscribed: a sensor sees this node once it
        # can solve, and nothing waits in its queue while numba compiles (a cold cache, the first
        # start after an install without `make`'s warm-up)
        loading, compiled = time.monotonic(), compiled_kernels()
        self.monitor.load_kernels()
        if compiled := compiled_kernels() - compiled:
            self.get_logger().warning(
                f"numba compiled {compiled} physics kernel(s) in {time.monotonic() - loading:.0f} s at this start: its "
                "on-disk cache (beside linkage_monitor/mechanics/kernels.py, or NUMBA_CACHE_DIR) was cold or not "
                "writable; `python -m linkage_monitor.mechanics.warm` compiles them ahead of the next start")
        self._inputs: list[tuple[Any, Callable[[bytes, dict], None]]] = []   # (subscription, its callback)
        self.input_events = InputEvents()   # taken at the heartbeat (ros/input_events.py)

    def start_inputs(self) -> None:
        """The sensors subscribed (unless the driver brings its own inputs), the heartbeat and the
        start status started: the node's start, and the activate of the managed node."""
        config = self.monitor.config
        if self.subscribes_sensors:
            self._subscribe(JointState, config.topics.joint_states, self._input_callback(config.topics.joint_states,
                                                                                          JOINT_STATE))
            for topic in config.pressure_topics:
                self._subscribe(FluidPressure, topic, self._input_callback(topic, FLUID_PRESSURE))
        # on the steady clock: losses and the heartbeat are reported with use_sim_time and /clock stopped too
        steady = Clock(clock_type=ClockType.STEADY_TIME)
        self.heartbeat = self.create_timer(HEARTBEAT_S, self.on_heartbeat, clock=steady)
        # once, as soon as spinning starts (a subclass has set up its own inputs by then): STALE until a solve
        self._start_status = self.create_timer(0.0, self._report_start, clock=steady)

    def _input_callback(self, topic: str, type_name: str) -> Callable[[bytes, dict], None]:
        def callback(data: bytes, info: dict) -> None:
            self.on_input(topic, type_name, data, info)
        return callback

    def _publisher(self, msg_type: type, topic: str, qos: QoSProfile) -> Any:
        """A publisher without rclpy's default event handlers (QoS / type mismatch warnings: the
        subscriber's side reports those), so that each spin of the executor waits on fewer entities."""
        return self.create_publisher(msg_type, topic, qos,
                                     event_callbacks=PublisherEventCallbacks(use_default_callbacks=False))

    def _subscribe(self, msg_type: type, topic: str, callback: Callable[[bytes, Any], None]) -> None:
        """Inputs are taken serialized (raw): the bag records the bytes that arrived, and the
        message is deserialized once, here. After each input the queues are drained (``_drain``).
        The subscription's middleware events are taken at the heartbeat, not waited on
        (``ros.input_events``)."""
        def take(data: bytes, info: dict) -> None:   # under rclpy's executor (main() takes inputs itself)
            self._drain([(info["received_timestamp"], callback, (data, info))])
        sub: Any = self.create_subscription(msg_type, topic, take,   # type: ignore[arg-type]  # raw: bytes
                                            self.input_qos, raw=True,
                                            event_callbacks=SubscriptionEventCallbacks(use_default_callbacks=False))
        self.input_events.watch(topic, sub)   # the loss counter's key for this topic, as for its sequence gaps
        self._inputs.append((sub, callback))

    @property
    def input_subscriptions(self) -> list[Any]:
        """The subscriptions of the inputs (JointState, then each pressure topic)."""
        return [sub for sub, _ in self._inputs]

    def take_inputs(self) -> None:
        """Work off what is waiting in the input queues (``ros.spin.InputSpinner``'s wake-up)."""
        self._drain(self._take_cycle())

    def _drain(self, cycle: list[tuple[int, Callable[[bytes, dict], None], tuple[bytes, dict]]]) -> None:
        """Work off the ``cycle`` of messages taken, then what is already waiting in the input
        queues, before returning: a burst is worked off without one wake-up of the spin loop per
        message. Like rclpy's executor, one message per queue per cycle (each cycle's few in
        arrival order, received_timestamp), so the topics advance together as they would through
        the executor; at most DRAIN_LIMIT messages, so timers (heartbeat) and parameter services run."""
        taken = 0
        while cycle:
            for _, callback, (data, info) in sorted(cycle, key=lambda c: c[0]):
                try:
                    callback(data, info)
                except Exception as exc:  # noqa: BLE001 - callbacks guard themselves; the others go on
                    self._publish_status("internal", Level.ERROR, f"internal error while taking an input "
                                         f"({len(data)} bytes): {type(exc).__name__}: {exc}", self._now())
            taken += len(cycle)
            if taken >= DRAIN_LIMIT:
                return   # what was taken is worked off; the rest waits for the next wake-up
            cycle = self._take_cycle()

    def _take_cycle(self) -> list[tuple[int, Callable[[bytes, dict], None], tuple[bytes, dict]]]:
        """One message from each input queue that has one: (received_timestamp, callback, (bytes, info))."""
        cycle = []
        for sub, callback in self._inputs:
            try:
                with sub.handle:   # as rclpy's executor takes a message (Executor._take_subscription)
                    message = sub.handle.take_message(sub.msg_type, sub.raw)
            except InvalidHandle:   # destroyed while shutting down: nothing more to take from it
                continue
            if message is not None:
                cycle.append((message[1]["received_timestamp"], callback, message))
        return cycle

    def _now(self) -> int:
        return self.get_clock().now().nanoseconds

    # ---- callbacks: record first, then the core; never raise -------------------------------------
    def on_input(self, topic: str, type_name: str, data: bytes, info: dict) -> None:
        """An input message's CDR bytes (``type_name``) arrived on ``topic``: read them into an input
        event (``wire.sensor_messages``; bytes that are not the type: an UnreadableEvent, an ERROR step
        saying why), record the bytes as they came, solve, publish."""
        now = self._now()
        self.loss.on_message(topic, _publisher_id(info), info.get("publication_sequence_number"))
        event = input_event(type_name, data, topic, now)
        self._record_input(topic, type_name, data, event.stamp_ns, now)
        try:
            self._publish(self.monitor.step(event), now)
        except Exception as exc:  # noqa: BLE001 - the adapter boundary: report and go on
            self.get_logger().error(f"internal error on {topic}: {type(exc).__name__}: {exc}",
                                    throttle_duration_sec=1.0)
            self._publish_status("internal", Level.ERROR, f"internal error while publishing the results of "
                                 f"{topic}: {type(exc).__name__}: {exc}", now)

    def input_sources(self) -> list[str]:
        """Where the node takes its inputs from: the topics of its input subscriptions."""
        return [sub.topic_name for sub, _ in self._inputs]

    def _report_start(self) -> None:
        self._start_status.cancel()
        self._report_stale(self._now())

    def _report_stale(self, now: int) -> bool:
        """The monitor's status STALE (``monitoring.freshness``) if nothing was solved within the
        staleness limit: stamped ``now``, published, not recorded (the replay solves what the bag
        holds, whenever); whether it was."""
        finding = self.freshness.stale(time.monotonic(), self.monitor.config.staleness_limit_s, self.input_sources())
        self._stale = finding is not None
        if finding is not None:
            self._send_diagnostic(self.messenger.diagnostic(Step(now, ", ".join(self.input_sources()), (finding,)),
                                                            now))
        return self._stale

    def on_heartbeat(self) -> None:
        """STALE when nothing was solved within the staleness limit; else repeat the last diagnostic
        at least every HEARTBEAT_S; with the input-stream and recording statuses (diagnostic_updater
        style)."""
        try:
            now = self._now()
            stale = self._report_stale(now)
            if not stale and self._reported is not None and time.monotonic() - self._last_heartbeat >= HEARTBEAT_S:
                # the last reported status again (diagnostic_updater style); the bag holds it once already
                self._send_diagnostic(self.messenger.diagnostic(self._reported, now))
            self._take_input_events(now)
            self._check_name(now)
            self._report_losses(f"in the last {HEARTBEAT_S:.0f} s", now)
            recorder_error = self.recorder.writer.error if self.recorder is not None else None
            if recorder_error:
                self._publish_status("recording", Level.ERROR, f"recording failed: {recorder_error}; solving and "
                                     "publishing go on", now)
            self._flush_rerun(now)
        except Exception as exc:  # noqa: BLE001
            self.get_logger().error(f"heartbeat failed: {type(exc).__name__}: {exc}", throttle_duration_sec=5.0)

    def _check_name(self, now: int) -> None:
        """During the first NAME_CHECK_S of the node, whether another node of the graph has its name: two
        monitors on the same topics solve and record every input twice. A WARN ``<node>: node name``
        (and the log), once."""
        if self._name_checked or time.monotonic() - self._started > NAME_CHECK_S:
            return
        me = (self.get_name(), self.get_namespace())
        if self.get_node_names_and_namespaces().count(me) > 1:
            self._name_checked = True
            full = f"{me[1].rstrip('/')}/{me[0]}"
            text = (f"another node is named {full}: two monitors on the same topics solve, publish and record "
                    f"every input twice; stop one, or give it its own name (--ros-args -r __node:=NAME)")
            self.get_logger().warn(text)
            self._publish_status("node name", Level.WARN, text, now)

    def _take_input_events(self, now: int) -> None:
        """The middleware's events of the inputs since the last take: lost samples are counted
        (reported with the sequence gaps), a publisher whose QoS the subscription cannot match is a
        WARN naming the topic and the policy."""
        for notice in self.input_events.take():
            if notice.kind == LOST:
                self.loss.on_lost_event(notice.topic, notice.count)
            elif notice.kind == INCOMPATIBLE_QOS:
                self._publish_status("inputs", Level.WARN, f"{notice.count} publisher(s) on {notice.topic} offer a "
                                     f"QoS this node's subscription cannot match (policy: {notice.policy}): their "
                                     f"messages never arrive; check the node's sensor_qos "
                                     f"('{self.get_parameter('sensor_qos').value}') against the publisher's", now)

    def _report_losses(self, when: str, now: int) -> None:
        """A WARN ``<node>: inputs`` with the inputs newly known lost, if any (heartbeat and shutdown)."""
        new_lost = self.loss.new_since_report()
        if new_lost:
            self._publish_status("inputs", Level.WARN, f"{new_lost} input message(s) lost {when} (the monitor did "
                                 f"not see them): {self.loss.summary()}", now)

    # ---- parameters: validate in on-set, apply in post-set ----------------------------------------
    def _config_with(self, params: list[Parameter]) -> MonitorConfig:
        return config_with(self.monitor.config, {param.name: param.value for param in params})

    @staticmethod
    def as_declared_types(params: list[Parameter]) -> list[Parameter]:
        """An integer given for a double parameter taken as that double (``implement_mass 2000``)."""
        return [Parameter(p.name, Parameter.Type.DOUBLE, float(p.value))
                if p.type_ == Parameter.Type.INTEGER and is_double(p.name) else p for p in params]

    def _doubles_as_declared(self) -> None:
        """At start too (``-p implement_mass:=1500``, a parameter file's ``1500``), as at run time
        (``as_declared_types``): rclpy declares a parameter with the override's value as given, and
        an integer for a double is refused there, before any callback runs."""
        overrides = self._parameter_overrides   # rclpy's: the command line's and the parameter files' values
        for param in self.as_declared_types(list(overrides.values())):
            overrides[param.name] = param

    def validate_parameters(self, params: list[Parameter]) -> SetParametersResult:
        """Accept a change only if the mechanism with it is valid (nothing is applied here)."""
        try:
            for param in params:
                check_bounds(param.name, param.value)
            config = self._config_with(params)
            mech = apply_overrides(self.monitor.description, dict(config.overrides))
            InputTracker(mech, config)
        except (LinkageError, ValueError) as exc:
            return SetParametersResult(successful=False, reason=str(exc))
        return SetParametersResult(successful=True)

    def apply_parameters(self, params: list[Parameter]) -> None:
        """Apply a validated change from the next message on, and record it in the bag."""
        try:
            config = self._config_with(params)
            if config != self.monitor.config:
                self.monitor.reconfigure(config)
                if self.recorder is not None:
                    self.recorder.config(config, self._now())
                self.get_logger().info(f"configuration changed: {config.describe()}")
        except Exception as exc:  # noqa: BLE001
            self.get_logger().error(f"parameter change not applied: {type(exc).__name__}: {exc}")

    # ---- outputs ----------------------------------------------------------------------------------
    def _publish(self, step: Step, now: int) -> None:
        """Publish and record what ``step`` sends (``wire.step_messages``), log it to Rerun."""
        messages = self.messenger.messages(step, self.encoder.outputs(self.monitor, step), now)
        out = messages.outputs
        if out is not None:   # serialized: published and recorded as they are
            self.pub_hinges.publish(out.hinge_reactions)
            self.pub_hitch.publish(out.hitch_state)
            self.pub_steer.publish(out.steerability)
        if messages.markers is not None:
            self.pub_markers.publish(messages.markers)
        if step.pose is not None:
            self.freshness.solved(time.monotonic())
        if messages.diagnostic is not None:
            self._reported = step
            self._send_diagnostic(messages.diagnostic)
        elif self._stale:   # the STALE the heartbeat sent is replaced at once (not recorded: the gate did not pass it)
            self._reported = step
            self._send_diagnostic(self.messenger.diagnostic(step, now))
        self._stale = False
        if self.recorder is not None:
            self.recorder.step(messages, now)
        if self.rerun is not None:
            try:
                self._log_rerun(step)
            except Exception as exc:  # noqa: BLE001 - a failed Rerun sink must not stop the monitor
                self._rerun_failed(exc, now)
        if step.level == Level.ERROR:
            self.get_logger().error(step.message, throttle_duration_sec=1.0)
        elif step.level == Level.WARN:
            self.get_logger().warning(step.message, throttle_duration_sec=1.0)

    def _flush_rerun(self, now: int) -> None:
        """The Rerun recording written out (every heartbeat: a power cut loses at most about a second
        of it); a failed sink (its disk full) is an ERROR ``<node>: recording`` naming the file, the
        Rerun logging stops, solving, publishing and the bag go on."""
        if self.rerun is None:
            return
        try:
            self.rerun.flush()
        except Exception as exc:  # noqa: BLE001 - rerun raises RuntimeError (and others) for a failed sink
            self._rerun_failed(exc, now)

    def _rerun_failed(self, exc: Exception, now: int) -> None:
        reason = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        # a failed file sink can be neither flushed, closed nor dropped: each waits forever for its
        # writer (rerun-sdk 0.41), so it is kept, never touched again, and main() exits past it
        ABANDONED_RERUN.append(self.rerun)
        text = (f"Rerun recording {self._rerun_target} failed: {reason} (disk full, or too slow?); the Rerun logging stops, "
                "solving, publishing and the bag go on")
        self.rerun = None
        self.get_logger().error(text)
        self._publish_status("recording", Level.ERROR, text, now)

    def _log_rerun(self, step: Step) -> None:
        """Solved poses at most at rerun_rate; every ERROR's text."""
        from linkage_monitor.viz.rerun_view import machine_series

        assert self.rerun is not None
        if step.pose is not None:
            if self.rerun_gate.due(step.stamp_ns):
                m, result = step.pose.machine, step.pose.result
                self.rerun.log_pose(step.stamp_ns, result, machine_series(
                    m.steerability, m.lift_capacity, result.transmission_angle,
                    self.monitor.config.dead_centre_transmission_deg))
        elif step.level == Level.ERROR:
            self.rerun.log_status(step.stamp_ns, step.message)

    def _send_diagnostic(self, diagnostic: bytes) -> None:
        """Publish a step's DiagnosticArray; the heartbeat repeats the last one HEARTBEAT_S after."""
        self.pub_diag.publish(diagnostic)
        self._last_heartbeat = time.monotonic()

    def _publish_status(self, part: str, level: Level, message: str, now: int) -> None:
        """A separate DiagnosticStatus ``<node>: <part>`` (input stream, recording, internal)."""
        msg = status_array(self.get_clock().now().nanoseconds, level, f"{NODE_NAME}: {part}", message,
                           self.monitor.mechanism.name, {"part": part})
        if part != "recording" and self.recorder is not None:
            self.recorder.status(msg, now, now)
        self.pub_diag.publish(msg)

    def _record_input(self, topic: str, type_name: str, data: bytes, stamp_ns: int, now: int) -> None:
        """Record an input's CDR bytes as they came (``StepRecorder.input``); a recording fault is an
        ERROR ``<node>: recording`` and the monitoring goes on."""
        if self.recorder is None:
            return
        try:
            self.recorder.input(topic, type_name, data, stamp_ns, now)
        except Exception as exc:  # noqa: BLE001 - a recording fault must not stop the monitoring
            self._publish_status("recording", Level.ERROR, f"recording failed for {topic}: {type(exc).__name__}: "
                                 f"{exc}; solving and publishing go on", now)

    def close(self) -> None:
        """Report the inputs lost since the last heartbeat, finish the bag and the Rerun recording."""
        try:
            now = self._now()
            self._take_input_events(now)
            self.input_events.destroy()
            self._report_losses("since the last report, at shutdown", now)
        except Exception as exc:  # noqa: BLE001 - the bag is finished whatever happens here
            self.get_logger().error(f"final loss report failed: {type(exc).__name__}: {exc}")
        if self.recorder is not None:
            self.recorder.writer.close()
            writer = self.recorder.writer
            (self.get_logger().info if writer.error is None else self.get_logger().error)(writer.outcome)
        if self.rerun is not None:
            try:
                self.rerun.close()
            except Exception as exc:  # noqa: BLE001 - one line, no traceback: the disk may be full
                self.get_logger().error(f"Rerun recording {self._rerun_target} not finished: "
                                        f"{str(exc).splitlines()[0] if str(exc) else type(exc).__name__}")


def _publisher_id(info: dict) -> object:
    gid = info.get("publisher_gid")
    return tuple(gid["data"]) if isinstance(gid, dict) and "data" in gid else None


def usage() -> str:
    """``linkage_monitor_node --help``: how to run the node and its parameters (name, default, unit,
    description: ``ros.parameters.PARAMETERS``, what the node declares)."""
    return ("usage: linkage_monitor_node [-h] [--ros-args -p NAME:=VALUE ... | --params-file FILE ...]\n\n"
            "The live linkage monitor: sensor_msgs/JointState and FluidPressure in; hinge reactions, hitch state,\n"
            "steerability and /diagnostics out (ros/node.py's docstring has the topics). Parameters:\n\n"
            + usage_table())


def main(argv: list[str] | None = None, make_node: Callable[[], LinkageMonitorNode] = LinkageMonitorNode) -> int:
    """Console script `linkage_monitor_node`: run until Ctrl-C / SIGTERM / shutdown. ``make_node``
    builds the node (the CAN bridge passes its own; errors of its inputs end the start as the
    node's own do: one line on stderr, exit code 2).

    A signal only asks the spin loop to stop (rclpy's own handlers are off): it never lands as an
    exception in the middle of a callback, e.g. half-way through writing a message into the bag's
    chunk, so the bag is always finished whole.
    """
    args = argv if argv is not None else sys.argv
    own = args[1:args.index("--ros-args")] if "--ros-args" in args else args[1:]   # before ROS's arguments
    if "--help" in own or "-h" in own:
        print(usage())
        return 0
    rclpy.init(args=args, signal_handler_options=SignalHandlerOptions.NO)
    stopping = threading.Event()
    for signum in (signal.SIGINT, signal.SIGTERM):
        signal.signal(signum, lambda *_: stopping.set())
    node = None
    try:
        node = make_node()
        executor = SingleThreadedExecutor()
        executor.add_node(node)
        spinner = InputSpinner(node, executor, lambda: node.input_subscriptions, node.take_inputs)
        while not stopping.is_set() and rclpy.ok():
            spinner.spin_once(STOP_POLL_S)
    except ExternalShutdownException:   # rclpy shut down from elsewhere
        pass
    except (LinkageError, ValueError, BagError, InvalidParameterValueException, InvalidParameterTypeException) as exc:
        print(f"linkage_monitor_node: {str(exc).splitlines()[0]}", file=sys.stderr)
        return 2
    finally:
        if node is not None:
            node.close()
            node.destroy_node()
        if rclpy.ok():
            rclpy.shutdown()
        # the run is over: a second Ctrl-C (a launcher forwarding the terminal's) while the interpreter
        # exits, where Python restores the default handlers it replaced, would end it with -SIGINT
        for signum in (signal.SIGINT, signal.SIGTERM):
            signal.signal(signum, signal.SIG_IGN)
    if ABANDONED_RERUN:   # the bag is finished; a failed Rerun sink would hang the interpreter's exit
        sys.stdout.flush()
        sys.stderr.flush()
        os._exit(0)
    return 0


if __name__ == "__main__":
    sys.exit(main())
