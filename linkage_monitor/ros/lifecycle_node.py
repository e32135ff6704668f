"""The managed linkage monitor: ``linkage_monitor_lifecycle_node``, the live node (``ros.node``) as an
``rclpy.lifecycle`` node, driven over ``/<node>/change_state`` (``ros2 lifecycle set``, a launch
file's lifecycle events, nav2's lifecycle manager). docs/lifecycle.md has the states in full.

- configure: the parameters checked, the mechanism loaded, the monitor, the output publishers
  (lifecycle publishers, silent until activate), the bag and the Rerun view built, the physics
  kernels loaded (``LinkageMonitorNode.build_monitor``). A refused parameter or an unloadable
  mechanism fails the transition (one line in the log naming the input and the reason); the node
  stays unconfigured, nothing held.
- activate: the publishers enabled, the mechanism description published (latched), the sensors
  subscribed, the heartbeat started (``LinkageMonitorNode.start_inputs``): from here on the outputs
  are the plain node's.
- deactivate: the inputs' lost samples reported, the sensors unsubscribed (nothing is queued or
  solved while inactive), the heartbeat stopped, the publishers disabled. The monitor is kept, and
  so is the bag: recording pauses (no inputs, no outputs) and goes on in the same bag at the next
  activate.
- cleanup: the bag and the Rerun recording finished, the publishers destroyed, everything configure
  built released: back to unconfigured, where every parameter (the mechanism too) may be set.
- shutdown (from any state): what the node holds released as by deactivate and cleanup; the process
  then exits (code 0), as on Ctrl-C.

The parameters are the plain node's (``ros.parameters.PARAMETERS``). Those the plain node reads only at its
start are read at configure here: settable while unconfigured, refused otherwise; the others apply at
run time as in the plain node.
"""

from __future__ import annotations

import gc
import signal
import sys
from typing import Any

from rcl_interfaces.msg import ParameterDescriptor, SetParametersResult
from rclpy.event_handler import PublisherEventCallbacks
from rclpy.lifecycle import LifecycleNode, LifecyclePublisher, LifecycleState, TransitionCallbackReturn
from rclpy.parameter import Parameter
from rclpy.qos import QoSProfile

from linkage_monitor.bag.errors import BagError
from linkage_monitor.mechanics import LinkageError
from linkage_monitor.ros.inputs import SensorTopics
from linkage_monitor.ros.node import NODE_NAME, LinkageMonitorNode, descriptor
from linkage_monitor.ros.node import main as node_main
from linkage_monitor.ros.parameters import PARAMETERS, check_bounds

EXECUTABLE = "linkage_monitor_lifecycle_node"
CONFIGURE_TIME = frozenset(name for name, d in PARAMETERS.items() if d.read_only)   # read at configure


def _managed_descriptor(name: str) -> ParameterDescriptor:
    """The plain node's descriptor; a parameter it reads only at start is settable while unconfigured."""
    desc = descriptor(PARAMETERS[name])
    if name in CONFIGURE_TIME:
        desc.read_only = False
        desc.description += " (read at configure: set it while the node is unconfigured)"
    return desc


class LinkageMonitorLifecycleNode(LinkageMonitorNode, LifecycleNode):
    """The live node with the lifecycle's states: unconfigured, inactive, active, finalized."""

    def __init__(self, **kwargs: Any) -> None:
        LifecycleNode.__init__(self, NODE_NAME, **kwargs)   # not the plain node's start: configure builds it
        self.input_source = SensorTopics()
        self._doubles_as_declared()
        for name, declaration in PARAMETERS.items():
            self.declare_parameter(name, declaration.default, _managed_descriptor(name))
        self._inputs = []   # the spin loop asks for the input subscriptions before any configure
        self._configured = self._active = False
        self._unconfigured = set(vars(self)) | {"_unconfigured"}   # what configure adds, cleanup releases
        self.add_pre_set_parameters_callback(self.as_declared_types)
        self.add_on_set_parameters_callback(self.validate_managed)
        self.add_post_set_parameters_callback(self.apply_managed)
        self.get_logger().info(f"unconfigured: configure and activate over /{NODE_NAME}/change_state "
                               f"(ros2 lifecycle set {self.get_fully_qualified_name()} configure)")

    # ---- parameters: configure-time ones only while unconfigured ----------------------------------
    def validate_managed(self, params: list[Parameter]) -> SetParametersResult:
        """Unconfigured: every parameter within its range (the rest is checked at configure).
        Configured: a parameter read at configure is refused (naming what to do), the others are
        validated as the plain node validates them."""
        if not self._configured:
            try:
                for param in params:
                    check_bounds(param.name, param.value)
            except ValueError as exc:
                return SetParametersResult(successful=False, reason=str(exc))
            return SetParametersResult(successful=True)
        fixed = sorted(p.name for p in params if p.name in CONFIGURE_TIME)
        if fixed:
            return SetParametersResult(successful=False, reason=(
                f"parameter(s) {', '.join(fixed)} are read at configure: deactivate and clean up "
                f"{self.get_fully_qualified_name()} first, set them, then configure and activate it again"))
        return self.validate_parameters(params)

    def apply_managed(self, params: list[Parameter]) -> None:
        """Configured: applied as by the plain node (from the next message on, recorded in the bag)."""
        if self._configured:
            self.apply_parameters(params)

    def output_publisher(self, msg_type: type, topic: str, qos: QoSProfile) -> Any:
        """The outputs' publishers are lifecycle publishers: silent unless the node is active."""
        return self.create_lifecycle_publisher(msg_type, topic, qos,
                                               event_callbacks=PublisherEventCallbacks(use_default_callbacks=False))

    # ---- transitions ------------------------------------------------------------------------------
    def on_configure(self, state: LifecycleState) -> TransitionCallbackReturn:
        """Build the monitor from the parameters; a refused one fails the transition (logged)."""
        try:
            self.build_monitor()
        except (LinkageError, ValueError, BagError) as exc:
            self.get_logger().error(f"configure failed: {str(exc).splitlines()[0]}; set the parameter right and "
                                    "configure again")
            self._release()
            return TransitionCallbackReturn.FAILURE
        except Exception as exc:  # noqa: BLE001 - e.g. the Rerun file not writable: nothing is kept half-built
            reason = str(exc).splitlines()[0] if str(exc) else ""
            self.get_logger().error(f"configure failed: {type(exc).__name__}: {reason}")
            self._release()
            return TransitionCallbackReturn.FAILURE
        self._configured = True
        gc.freeze()   # what configure built is left out of every later collection (cleanup unfreezes)
        config = self.monitor.config
        self.get_logger().info(f"configured '{self.monitor.description.name}': {config.topics.joint_states} + "
                               f"{', '.join(config.pressure_topics) or 'no pressures'}; activate to monitor")
        return super().on_configure(state)

    def on_activate(self, state: LifecycleState) -> TransitionCallbackReturn:
        """Enable the publishers, publish the mechanism, subscribe the sensors, start the heartbeat."""
        result = super().on_activate(state)
        self.outputs.publish_description()
        self.start_inputs()
        self._active = True
        self.get_logger().info(f"active: monitoring '{self.monitor.description.name}'")
        return result

    def on_deactivate(self, state: LifecycleState) -> TransitionCallbackReturn:
        """Report the inputs' losses, unsubscribe, stop the heartbeat, disable the publishers."""
        self._stop_inputs()
        self.get_logger().info("inactive: the sensors unsubscribed, nothing solved or published")
        return super().on_deactivate(state)

    def on_cleanup(self, state: LifecycleState) -> TransitionCallbackReturn:
        """Finish the bag and the Rerun recording, release everything configure built."""
        self._release()
        self.get_logger().info("unconfigured: every parameter may be set, then configure")
        return super().on_cleanup(state)

    def on_shutdown(self, state: LifecycleState) -> TransitionCallbackReturn:
        """Release what the node holds (from any state), then end the process as Ctrl-C does."""
        self.close()
        signal.raise_signal(signal.SIGINT)   # ros.node.main's stop flag: it stops once this transition is answered
        return super().on_shutdown(state)

    def on_error(self, state: LifecycleState) -> TransitionCallbackReturn:
        """A transition raised: release what the node holds; it is unconfigured again."""
        self.get_logger().error(f"a transition from '{state.label}' failed; the node is unconfigured again")
        self.close()
        return super().on_error(state)

    def close(self) -> None:
        """What the node holds released, whatever its state (shutdown, Ctrl-C, SIGTERM)."""
        if self._active:
            self._stop_inputs()
        if self._configured:
            self._release()

    def _stop_inputs(self) -> None:
        self.stop_inputs("since the last report, at deactivate")
        self._active = False

    def _release(self) -> None:
        """The bag and the Rerun recording finished (``LinkageMonitorNode.close``), the publishers
        destroyed, every attribute configure added dropped."""
        if hasattr(self, "input_events"):   # built whole (build_monitor's last attribute)
            LinkageMonitorNode.close(self)
        elif (recording := getattr(self, "recording", None)) is not None:   # configure failed after opening the bag
            recording.close_bag()
        for publisher in [p for p in self.publishers if isinstance(p, LifecyclePublisher)]:
            self.destroy_lifecycle_publisher(publisher)
        for name in set(vars(self)) - self._unconfigured:
            delattr(self, name)
        self._configured = False
        gc.unfreeze()


def usage() -> str:
    """``linkage_monitor_lifecycle_node --help``."""
    return (f"usage: {EXECUTABLE} [-h] [--ros-args -p NAME:=VALUE ... | --params-file FILE ...]\n\n"
            "The linkage monitor as a managed (lifecycle) node: it starts unconfigured; configure, activate,\n"
            "deactivate, cleanup and shutdown over /linkage_monitor/change_state (ros2 lifecycle set), or\n"
            "launch/monitor_lifecycle.launch.py (docs/lifecycle.md). Once active its topics and outputs are\n"
            "linkage_monitor_node's; so are its parameters (linkage_monitor_node --help), those read at its\n"
            "start read at each configure here.")


def main(argv: list[str] | None = None) -> int:
    """Console script ``linkage_monitor_lifecycle_node``: ``ros.node.main``'s spin loop, signals and
    exit codes around the managed node."""
    args = argv if argv is not None else sys.argv
    own = args[1:args.index("--ros-args")] if "--ros-args" in args else args[1:]
    if "--help" in own or "-h" in own:
        print(usage())
        return 0
    return node_main(args, make_node=LinkageMonitorLifecycleNode)


if __name__ == "__main__":
    sys.exit(main())
