"""Launch the linkage_monitor node with a parameter file.

With launch_ros (a ROS 2 installation / colcon workspace):
    ros2 launch linkage_monitor monitor.launch.py params:=config/belarus_1221.yaml
Without it (the PyPI wheels have no launch/launch_ros), the same file runs the node directly:
    .venv/bin/python launch/monitor.launch.py [--params config/belarus_1221.yaml]
"""

from __future__ import annotations

import signal
import subprocess
import sys
from pathlib import Path
from typing import Callable

DEFAULT_PARAMS = Path(__file__).resolve().parent.parent / "config" / "belarus_1221.yaml"


def generate_launch_description():  # noqa: D103  (the ros2 launch entry point)
    from launch import LaunchDescription
    from launch.actions import DeclareLaunchArgument
    from launch.substitutions import LaunchConfiguration
    from launch_ros.actions import Node

    params = LaunchConfiguration("params")
    return LaunchDescription([
        DeclareLaunchArgument("params", default_value=str(DEFAULT_PARAMS),
                              description="node parameter file (config/<preset>.yaml)"),
        Node(package="linkage_monitor", executable="linkage_monitor_node", name="linkage_monitor",
             parameters=[params], output="screen", emulate_tty=True),
    ])


def _stop_with_parent() -> None:
    """In the node's process: have the kernel send SIGINT when this launcher dies, however it dies
    (a launcher killed with SIGKILL would otherwise leave the node running on the network)."""
    import ctypes

    PR_SET_PDEATHSIG = 1
    ctypes.CDLL("libc.so.6", use_errno=True).prctl(PR_SET_PDEATHSIG, signal.SIGINT)


def main(argv: list[str] | None = None) -> int:
    """Run the node with a parameter file, without launch_ros."""
    import argparse

    parser = argparse.ArgumentParser(description="Run linkage_monitor_node with a parameter file.")
    parser.add_argument("--params", type=Path, default=DEFAULT_PARAMS, help="config/<preset>.yaml")
    args = parser.parse_args(argv)
    return run([sys.executable, "-m", "linkage_monitor.ros.node", "--ros-args", "--params-file", str(args.params)])


def run(command: list[str], started: Callable[[subprocess.Popen], None] = lambda node: None) -> int:
    """Run the node's ``command`` until it ends (``started`` is called with its process once it is
    started: launch/monitor_lifecycle.launch.py configures and activates it there); its exit code."""
    # Ctrl-C and SIGTERM stop the node cleanly, also when this launcher was started with SIGINT
    # ignored (a background job of a non-interactive shell: Python then installs no handler)
    signal.signal(signal.SIGINT, signal.default_int_handler)
    signal.signal(signal.SIGTERM, signal.default_int_handler)
    node = subprocess.Popen(command, preexec_fn=_stop_with_parent if sys.platform == "linux" else None)
    try:
        started(node)
        return node.wait()
    except KeyboardInterrupt:  # pass Ctrl-C on, so the node closes its bag
        node.send_signal(signal.SIGINT)
        return node.wait()


if __name__ == "__main__":
    sys.exit(main())
