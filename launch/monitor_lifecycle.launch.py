"""Launch the managed linkage monitor (linkage_monitor_lifecycle_node) with a parameter file, then
configure and activate it (docs/lifecycle.md).

With launch_ros (a ROS 2 installation / colcon workspace):
    ros2 launch linkage_monitor monitor_lifecycle.launch.py params:=config/belarus_1221.yaml
Without it (the PyPI wheels have no launch/launch_ros), the same file runs the node and drives its
/linkage_monitor/change_state service itself:
    .venv/bin/python launch/monitor_lifecycle.launch.py [--params config/belarus_1221.yaml]
A transition that fails (a refused parameter, an unloadable mechanism) stops the node; the launcher
then exits 1 with one line on stderr (the node's log says why).
"""

from __future__ import annotations

import importlib.util
import signal
import subprocess
import sys
from pathlib import Path
from types import ModuleType

HERE = Path(__file__).resolve().parent
NODE_NAME = "linkage_monitor"
TRANSITION_TIMEOUT_S = 600.0   # s, a configure compiles the physics kernels when their cache is cold


def _plain_launch() -> ModuleType:
    """launch/monitor.launch.py (its parameter file default, its way of running a node)."""
    spec = importlib.util.spec_from_file_location("monitor_launch", HERE / "monitor.launch.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def generate_launch_description():  # noqa: D103  (the ros2 launch entry point)
    from launch import LaunchDescription
    from launch.actions import DeclareLaunchArgument, EmitEvent, RegisterEventHandler
    from launch.events import matches_action
    from launch.substitutions import LaunchConfiguration
    from launch_ros.actions import LifecycleNode
    from launch_ros.event_handlers import OnStateTransition
    from launch_ros.events.lifecycle import ChangeState
    from lifecycle_msgs.msg import Transition

    node = LifecycleNode(package="linkage_monitor", executable="linkage_monitor_lifecycle_node", name=NODE_NAME,
                         namespace="", parameters=[LaunchConfiguration("params")], output="screen",
                         emulate_tty=True)
    return LaunchDescription([
        DeclareLaunchArgument("params", default_value=str(_plain_launch().DEFAULT_PARAMS),
                              description="node parameter file (config/<preset>.yaml)"),
        node,
        RegisterEventHandler(OnStateTransition(target_lifecycle_node=node, goal_state="inactive", entities=[
            EmitEvent(event=ChangeState(lifecycle_node_matcher=matches_action(node),
                                        transition_id=Transition.TRANSITION_ACTIVATE))])),
        EmitEvent(event=ChangeState(lifecycle_node_matcher=matches_action(node),
                                    transition_id=Transition.TRANSITION_CONFIGURE)),
    ])


def configure_and_activate(node: subprocess.Popen) -> None:
    """Drive the node started as ``node`` through configure and activate over its change_state
    service; a failed transition stops it and ends the launcher (exit code 1, one line on stderr)."""
    import rclpy
    from lifecycle_msgs.msg import Transition
    from lifecycle_msgs.srv import ChangeState
    from rclpy.context import Context
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.signals import SignalHandlerOptions

    context = Context()
    rclpy.init(context=context, signal_handler_options=SignalHandlerOptions.NO)   # Ctrl-C stays the launcher's
    try:
        client_node = rclpy.create_node("linkage_monitor_launcher", context=context)
        change = client_node.create_client(ChangeState, f"/{NODE_NAME}/change_state")
        executor = SingleThreadedExecutor(context=context)
        executor.add_node(client_node)
        for transition, label in ((Transition.TRANSITION_CONFIGURE, "configure"),
                                  (Transition.TRANSITION_ACTIVATE, "activate")):
            failure = _transition(executor, change, node, transition)
            if failure:
                node.send_signal(signal.SIGINT)
                node.wait()
                print(f"monitor_lifecycle.launch.py: {label} of /{NODE_NAME} {failure}; the node was stopped (its "
                      "log above says why)", file=sys.stderr)
                raise SystemExit(1)
        client_node.destroy_node()
    finally:
        rclpy.shutdown(context=context)


def _transition(executor, change, node: subprocess.Popen, transition: int) -> str:
    """'' when the node took ``transition`` (asked over ``change``, answered through ``executor``),
    else what went wrong."""
    from lifecycle_msgs.msg import Transition
    from lifecycle_msgs.srv import ChangeState

    while not change.wait_for_service(timeout_sec=0.5):
        if node.poll() is not None:
            return f"did not happen: the node exited (code {node.returncode})"
    future = change.call_async(ChangeState.Request(transition=Transition(id=transition)))
    executor.spin_until_future_complete(future, timeout_sec=TRANSITION_TIMEOUT_S)
    if not future.done():
        return f"got no answer within {TRANSITION_TIMEOUT_S:.0f} s"
    return "" if future.result().success else "failed"


def main(argv: list[str] | None = None) -> int:
    """Run the managed node with a parameter file, configure and activate it, without launch_ros."""
    import argparse

    plain = _plain_launch()
    parser = argparse.ArgumentParser(description="Run linkage_monitor_lifecycle_node with a parameter file, "
                                                 "configured and active.")
    parser.add_argument("--params", type=Path, default=plain.DEFAULT_PARAMS, help="config/<preset>.yaml")
    args = parser.parse_args(argv)
    return plain.run([sys.executable, "-m", "linkage_monitor.ros.lifecycle_node", "--ros-args", "--params-file",
                      str(args.params)], started=configure_and_activate)


if __name__ == "__main__":
    sys.exit(main())
