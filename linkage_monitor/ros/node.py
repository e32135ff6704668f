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

The node composes its parts: the parameters (``ros.parameters``: one table), its input source
(``ros.inputs``: the sensor subscriptions, or the CAN bridge's frames), what it publishes
(``ros.publishing``) and what it records (``ros.recording``).
"""

from __future__ import annotations

import gc
import os
import signal
import sys
import threading
import time
from pathlib import Path
from typing import Any, Callable, NamedTuple

import rclpy
from rcl_interfaces.msg import FloatingPointRange, IntegerRange, ParameterDescriptor, ParameterType, SetParametersResult
from rclpy.clock import Clock, ClockType
from rclpy.event_handler import PublisherEventCallbacks, SubscriptionEventCallbacks
from rclpy.exceptions import InvalidHandle, InvalidParameterTypeException, InvalidParameterValueException
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.qos import QoSProfile, ReliabilityPolicy, qos_profile_sensor_data
from rclpy.signals import SignalHandlerOptions

from linkage_monitor.bag.errors import BagError
from linkage_monitor.bag.step_recorder import StepRecorder
from linkage_monitor.bag.writer import BagWriter
from linkage_monitor.mechanics import LinkageError, apply_overrides, kernels, load_description
from linkage_monitor.mechanics.warm import compiled_kernels
from linkage_monitor.monitoring.config import MonitorConfig
from linkage_monitor.monitoring.core import Monitor
from linkage_monitor.monitoring.findings import Level
from linkage_monitor.monitoring.inputs import InputTracker
from linkage_monitor.monitoring.loss import LossCounter
from linkage_monitor.ros.input_events import INCOMPATIBLE_QOS, LOST, InputEvents
from linkage_monitor.ros.inputs import InputCallback, InputSource, SensorTopics
from linkage_monitor.ros.parameters import (PARAMETERS, Declaration, check_bounds, check_choices, config_with,
                                            is_double, monitor_config, usage_table)
from linkage_monitor.ros.publishers import publisher_gid
from linkage_monitor.ros.publishing import HEARTBEAT_S, OUTPUT_QOS, OutputPublisher
from linkage_monitor.ros.rcl_private import SerializedTaker
from linkage_monitor.ros.recording import ABANDONED_RERUN, Recording
from linkage_monitor.ros.spin import InputSpinner

NODE_NAME = "linkage_monitor"
STOP_POLL_S = 0.1  # s, the spin loop looks this often whether a signal asked it to stop
DRAIN_LIMIT = 200  # input messages worked off per executor callback (then timers and services run)
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


class InputQueue(NamedTuple):
    """An input subscription, the callback its messages go to and the taker that takes them with their
    publisher (``rcl_private.SerializedTaker``)."""

    subscription: Any
    callback: InputCallback
    taker: SerializedTaker


class LinkageMonitorNode(Node):
    """Takes the inputs of its ``input_source`` (default: the sensor subscriptions), solves on every
    message, publishes results and diagnostics, records them."""

    def __init__(self, input_source: InputSource | None = None, **kwargs: Any) -> None:
        super().__init__(NODE_NAME, **kwargs)
        self.input_source: InputSource = input_source if input_source is not None else SensorTopics()
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
        publishers, the recording, the physics kernels loaded: the node's start, and the configure of
        the managed node (``ros.lifecycle_node``)."""
        p = {name: self.get_parameter(name).value for name in PARAMETERS}
        # everything is validated before anything is created
        for name, value in p.items():
            check_bounds(name, value)
        check_choices(p)
        description = load_description(p["mechanism"])
        config = monitor_config(p, description, self.resolve_topic_name)
        description = self.input_source.described(description, config)
        self.monitor = Monitor(description, config)
        self.input_qos = (qos_profile_sensor_data if p["sensor_qos"] == "sensor_data" else
                          QoSProfile(depth=int(p["reliable_queue_depth"]), reliability=ReliabilityPolicy.RELIABLE))
        bag_dir = Path(p["record_dir"]) / (p["record_name"] or time.strftime(f"{description.name}_%Y%m%d_%H%M%S"))
        recorder = (StepRecorder(BagWriter(bag_dir, max_bag_size=p["max_bag_size"],
                                           max_bag_duration_s=p["max_bag_duration"]),
                                 config.topics, self.input_qos, OUTPUT_QOS)
                    if p["record"] else None)   # BagError: one line at start
        self.recording = Recording(recorder, self.publish_status, self.get_logger())
        self.loss = LossCounter()
        self._started, self._name_checked = time.monotonic(), False   # the duplicate-name check (_check_name)
        self.outputs = OutputPublisher(self.monitor, self.recording, self.output_publisher, NODE_NAME,
                                       float(p["marker_rate"]), self.get_clock(), self.get_logger())
        if recorder is not None:
            self.recording.begin(description, config, self.now())
            self.get_logger().info(f"recording to {bag_dir}")
        self.recording.open_rerun(p["rerun"], p["rerun_path"], float(p["rerun_rate"]), description,
                                  weighing=config.implement_mass_source != "file")

        # the kernels are loaded before the inputs are subscribed: a sensor sees this node once it
        # can solve, and nothing waits in its queue while numba compiles (a cold cache, the first
        # start after an install without `make`'s warm-up)
        loading, compiled = time.monotonic(), compiled_kernels()
        self.monitor.load_kernels()
        if compiled := compiled_kernels() - compiled:
            self.get_logger().warning(
                f"numba compiled {compiled} physics kernel(s) in {time.monotonic() - loading:.0f} s at this start: its "
                "on-disk cache (in linkage_monitor/mechanics/kernels/, or NUMBA_CACHE_DIR) was cold or not "
                "writable; `python -m linkage_monitor.mechanics.warm` compiles them ahead of the next start")
        self._inputs: list[InputQueue] = []
        self.input_events = InputEvents()   # taken at the heartbeat (ros/input_events.py)

    def start_inputs(self) -> None:
        """The heartbeat and the start status started, the input source started (the sensors
        subscribed): the node's start, and the activate of the managed node."""
        # on the steady clock: losses and the heartbeat are reported with use_sim_time and /clock stopped too
        steady = Clock(clock_type=ClockType.STEADY_TIME)
        self.heartbeat = self.create_timer(HEARTBEAT_S, self.on_heartbeat, clock=steady)
        # once, as soon as spinning starts (the input source has set up its inputs by then): STALE until a solve
        self._start_status = self.create_timer(0.0, self._report_start, clock=steady)
        self.input_source.start(self)

    def stop_inputs(self, when: str) -> None:
        """The inputs' losses ``when`` reported, the input subscriptions and the heartbeat ended, the
        Rerun recording flushed: the deactivate of the managed node."""
        now = self.now()
        self._take_input_events(now)
        self._report_losses(when, now)
        self.input_events.destroy()
        self._release_takers()
        for subscription in self.input_subscriptions:
            self.destroy_subscription(subscription)
        self._inputs = []
        self.destroy_timer(self.heartbeat)
        self.destroy_timer(self._start_status)
        self.recording.flush_rerun(now)

    def output_publisher(self, msg_type: type, topic: str, qos: QoSProfile) -> Any:
        """A publisher without rclpy's default event handlers (QoS / type mismatch warnings: the
        subscriber's side reports those), so that each spin of the executor waits on fewer entities."""
        return self.create_publisher(msg_type, topic, qos,
                                     event_callbacks=PublisherEventCallbacks(use_default_callbacks=False))

    def subscribe(self, msg_type: type, topic: str, callback: InputCallback) -> None:
        """An input subscription of the input source. Inputs are taken serialized (raw): the bag
        records the bytes that arrived, and the message is deserialized once, by ``callback``; each
        is counted (``monitoring.loss``: sequence gaps) first. After each input the queues are
        drained (``_drain``). The subscription's middleware events are taken at the heartbeat, not
        waited on (``ros.input_events``)."""
        def counted(data: bytes, info: dict) -> None:
            self.loss.on_message(topic, publisher_gid(info), info.get("publication_sequence_number"))
            callback(data, info)

        def take(data: bytes, info: dict) -> None:   # under rclpy's executor (main() takes inputs itself)
            self._drain([(info["received_timestamp"], counted, (data, info))])
        sub: Any = self.create_subscription(msg_type, topic, take,   # type: ignore[arg-type]  # raw: bytes
                                            self.input_qos, raw=True,
                                            event_callbacks=SubscriptionEventCallbacks(use_default_callbacks=False))
        self.input_events.watch(topic, sub)   # the loss counter's key for this topic, as for its sequence gaps
        self._inputs.append(InputQueue(sub, counted, SerializedTaker(sub)))

    @property
    def input_subscriptions(self) -> list[Any]:
        """The subscriptions of the inputs (JointState, then each pressure topic)."""
        return [queue.subscription for queue in self._inputs]

    def _release_takers(self) -> None:
        for queue in self._inputs:
            queue.taker.release()

    def take_inputs(self) -> None:
        """Work off what is waiting in the input queues (``ros.spin.InputSpinner``'s wake-up)."""
        self._drain(self._take_cycle())

    def _drain(self, cycle: list[tuple[int, InputCallback, tuple[bytes, dict]]]) -> None:
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
                    self.publish_status("internal", Level.ERROR, f"internal error while taking an input "
                                        f"({len(data)} bytes): {type(exc).__name__}: {exc}", self.now())
            taken += len(cycle)
            if taken >= DRAIN_LIMIT:
                return   # what was taken is worked off; the rest waits for the next wake-up
            cycle = self._take_cycle()

    def _take_cycle(self) -> list[tuple[int, InputCallback, tuple[bytes, dict]]]:
        """One message from each input queue that has one: (received_timestamp, callback, (bytes, info)),
        taken with its publisher (``rcl_private.SerializedTaker``: rclpy's take names it from Kilted on only)."""
        cycle = []
        for queue in self._inputs:
            try:
                message = queue.taker.take()
            except InvalidHandle:   # destroyed while shutting down: nothing more to take from it
                continue
            if message is not None:
                cycle.append((message[1]["received_timestamp"], queue.callback, message))
        return cycle

    def now(self) -> int:
        """The node's clock (``use_sim_time`` honoured), ns."""
        return self.get_clock().now().nanoseconds

    def publish_status(self, part: str, level: Level, message: str, now: int) -> None:
        """A separate DiagnosticStatus ``<node>: <part>`` (input stream, recording, internal)."""
        self.outputs.status(part, level, message, now)

    # ---- heartbeat: STALE, the last status again, losses, recording faults -----------------------------
    def _report_start(self) -> None:
        self._start_status.cancel()
        self.outputs.report_stale(self.now(), self.input_source.names())

    def on_heartbeat(self) -> None:
        """STALE when nothing was solved within the staleness limit; else repeat the last diagnostic
        at least every HEARTBEAT_S; with the input-stream and recording statuses (diagnostic_updater
        style), then the input source's own."""
        try:
            now = self.now()
            if not self.outputs.report_stale(now, self.input_source.names()):
                self.outputs.repeat_status(now)
            self._take_input_events(now)
            self._check_name(now)
            self._report_losses(f"in the last {HEARTBEAT_S:.0f} s", now)
            self.recording.heartbeat(now)
        except Exception as exc:  # noqa: BLE001
            self.get_logger().error(f"heartbeat failed: {type(exc).__name__}: {exc}", throttle_duration_sec=5.0)
        self.input_source.on_heartbeat()

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
            self.publish_status("node name", Level.WARN, text, now)

    def _take_input_events(self, now: int) -> None:
        """The middleware's events of the inputs since the last take: lost samples are counted
        (reported with the sequence gaps), a publisher whose QoS the subscription cannot match is a
        WARN naming the topic and the policy."""
        for notice in self.input_events.take():
            if notice.kind == LOST:
                self.loss.on_lost_event(notice.topic, notice.count)
            elif notice.kind == INCOMPATIBLE_QOS:
                self.publish_status("inputs", Level.WARN, f"{notice.count} publisher(s) on {notice.topic} offer a "
                                    f"QoS this node's subscription cannot match (policy: {notice.policy}): their "
                                    f"messages never arrive; check the node's sensor_qos "
                                    f"('{self.get_parameter('sensor_qos').value}') against the publisher's", now)

    def _report_losses(self, when: str, now: int) -> None:
        """A WARN ``<node>: inputs`` with the inputs newly known lost, if any (heartbeat and shutdown)."""
        new_lost = self.loss.new_since_report()
        if new_lost:
            self.publish_status("inputs", Level.WARN, f"{new_lost} input message(s) lost {when} (the monitor did "
                                f"not see them): {self.loss.summary()}", now)

    # ---- parameters: validate in on-set, apply in post-set ----------------------------------------
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

    def _config_with(self, params: list[Parameter]) -> MonitorConfig:
        return config_with(self.monitor.config, {param.name: param.value for param in params})

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
                self.recording.config(config, self.now())
                self.get_logger().info(f"configuration changed: {config.describe()}")
        except Exception as exc:  # noqa: BLE001
            self.get_logger().error(f"parameter change not applied: {type(exc).__name__}: {exc}")

    def close(self) -> None:
        """The input source closed, the inputs lost since the last heartbeat reported, the bag and
        the Rerun recording finished."""
        try:
            self.input_source.close()
        except Exception as exc:  # noqa: BLE001 - the bag is finished whatever happens here
            self.get_logger().error(f"closing the inputs failed: {type(exc).__name__}: {exc}")
        self._release_takers()
        self._inputs = []   # nothing is taken after the close
        try:
            now = self.now()
            self._take_input_events(now)
            self.input_events.destroy()
            self._report_losses("since the last report, at shutdown", now)
        except Exception as exc:  # noqa: BLE001 - the bag is finished whatever happens here
            self.get_logger().error(f"final loss report failed: {type(exc).__name__}: {exc}")
        self.recording.close()


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
    kernels.allow_threads(False)   # a pose at a time: no thread pool in the live node
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
