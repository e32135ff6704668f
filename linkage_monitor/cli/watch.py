"""`linkage-monitor watch`: a live terminal view of a running monitor, from its output topics.

For a terminal reached over SSH: each hinge's force against its peak, steerability ratio and
margin, lift reserve, the smallest transmission angle, the monitor's latest /diagnostics, the
received rates and the monitor's input losses (``docs/watch.md``). ``--once`` prints one plain
snapshot for scripts. rclpy and rich are imported only when the command runs (``--help`` needs
neither).
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from typing import TYPE_CHECKING, Sequence

from linkage_monitor.cli.arguments import bounded, run_with_ros_args
from linkage_monitor.cli.commands import COMMANDS

if TYPE_CHECKING:
    from rclpy.executors import Executor

    from linkage_monitor.ros.watch import OutputWatch

PROG = "linkage-monitor watch"
NO_OUTPUT_EXIT = 1   # --once: nothing (or not every topic) arrived within --timeout


def add_watch_arguments(parser: argparse.ArgumentParser) -> None:
    """Add the options of the watch command to ``parser``."""
    parser.add_argument("--namespace", default="/", metavar="NS",
                        help="the monitor node's namespace (its topics NS/hinge_reactions, NS/hitch_state, "
                             "NS/steerability; /diagnostics is global); default /")
    parser.add_argument("--once", action="store_true",
                        help="wait for one message on every watched topic, print one plain snapshot and exit 0 "
                             "(exit 1 after --timeout if one never arrives)")
    parser.add_argument("--timeout", type=bounded(0.0, 3600.0, "s", lo_open=True), default=10.0, metavar="S",
                        help="--once: seconds to wait for the outputs, default 10")
    parser.add_argument("--stale-after", type=bounded(0.0, 3600.0, "s", lo_open=True), default=2.0, metavar="S",
                        help="the view says STALE when no output arrived for this long, s (default 2)")
    parser.add_argument("--refresh", type=bounded(0.1, 30.0, "Hz"), default=4.0, metavar="HZ",
                        help="screen updates per second, 0.1 to 30, default 4")


def add_watch_parser(subparsers: argparse._SubParsersAction) -> argparse.ArgumentParser:
    """Register the ``watch`` subcommand on ``subparsers``; returns its parser."""
    sub = subparsers.add_parser("watch", help=COMMANDS["watch"].help, description=__doc__.splitlines()[0])
    add_watch_arguments(sub)
    return sub


def parser() -> argparse.ArgumentParser:
    """Stand-alone parser of the watch options (for ``python -m linkage_monitor.cli.watch``)."""
    p = argparse.ArgumentParser(prog=PROG, description=__doc__.splitlines()[0])
    add_watch_arguments(p)
    return p


def run_watch(args: argparse.Namespace) -> int:
    """Run the watch command until Ctrl-C (``--once``: one snapshot); returns the exit code (1: --once
    saw no output within --timeout, 2: a bad namespace)."""
    import rclpy
    from rclpy.exceptions import InvalidNamespaceException
    from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
    from rclpy.validate_namespace import validate_namespace

    from linkage_monitor.ros.watch import OutputWatch

    namespace = args.namespace if args.namespace.startswith("/") else "/" + args.namespace
    try:
        validate_namespace(namespace)
    except InvalidNamespaceException as exc:
        print(f"{PROG}: --namespace {args.namespace}: {str(exc).splitlines()[0].rstrip(':')}; give a ROS namespace "
              "such as /tractor1", file=sys.stderr)
        return 2
    rclpy.init(args=getattr(args, "ros_args", None))
    node = rclpy.create_node(f"linkage_monitor_watch_{os.getpid()}", namespace=namespace,
                             start_parameter_services=False)
    executor = SingleThreadedExecutor()
    executor.add_node(node)
    watch = OutputWatch(node, args.stale_after)
    try:
        return _once(watch, executor, args.timeout) if args.once else _live(watch, executor, args.refresh)
    except (KeyboardInterrupt, ExternalShutdownException):   # Ctrl-C
        return 0
    finally:
        executor.shutdown()
        node.destroy_node()
        rclpy.try_shutdown()


def _once(watch: OutputWatch, executor: Executor, timeout_s: float) -> int:
    """Spin until every watched topic has delivered (or ``timeout_s`` passes); print the snapshot."""
    from linkage_monitor.viz.terminal_view import snapshot_lines

    end = time.monotonic() + timeout_s
    while watch.missing() and time.monotonic() < end:
        executor.spin_once(timeout_sec=min(0.1, max(0.0, end - time.monotonic())))
        watch.drain()
    if missing := watch.missing():
        print(f"{PROG}: nothing arrived on {', '.join(missing)} within {timeout_s:g} s (waited on "
              f"{', '.join(watch.topics.values())}, ROS_DOMAIN_ID {os.environ.get('ROS_DOMAIN_ID', '0')}): is the "
              "monitor running, in this namespace (--namespace) and domain?", file=sys.stderr)
        return NO_OUTPUT_EXIT
    print("\n".join(snapshot_lines(watch.record())))
    return 0


def _live(watch: OutputWatch, executor: Executor, refresh_hz: float) -> int:
    """Draw the view on the terminal's alternate screen ``refresh_hz`` times a second until Ctrl-C;
    the messages are taken in between (at each wake-up, all that wait)."""
    from rich.console import Console
    from rich.live import Live

    from linkage_monitor.viz.terminal_view import view

    console = Console()
    period, draw_at = 1.0 / refresh_hz, 0.0
    with Live(console=console, screen=True, auto_refresh=False) as live:
        while True:
            now = time.monotonic()
            if now >= draw_at:
                width, height = console.size
                live.update(view(watch.record(), width, height), refresh=True)
                draw_at = now + period
            executor.spin_once(timeout_sec=max(0.0, draw_at - time.monotonic()))
            watch.drain()


def main(argv: Sequence[str] | None = None) -> int:
    """``python -m linkage_monitor.cli.watch``: the options of ``linkage-monitor watch`` plus ROS arguments."""
    return run_with_ros_args(parser(), run_watch, argv)


if __name__ == "__main__":
    sys.exit(main())
