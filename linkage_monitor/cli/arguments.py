"""Command-line arguments checked before any work starts: numbers finite and in range, output
paths writable, the one `--preset NAME | --mechanism FILE` group. A bad value is one line on
stderr and exit code 2 (argparse's own error path), never a traceback or a hang."""

from __future__ import annotations

import argparse
import math
import os
import sys
from pathlib import Path
from typing import TYPE_CHECKING, Callable, Sequence

if TYPE_CHECKING:   # the mechanics (numba: seconds) are loaded by the commands that read a mechanism
    from linkage_monitor.mechanics import Mechanism


def bounded(lo: float, hi: float, unit: str = "", integer: bool = False, lo_open: bool = False
           ) -> Callable[[str], float]:
    """An argparse type: a finite number in [lo, hi] (lo excluded when ``lo_open``)."""
    def parse(text: str) -> float:
        try:
            value = int(text) if integer else float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{text!r} is not {'an integer' if integer else 'a number'}") from None
        if not math.isfinite(value) or value > hi or value < lo or (lo_open and value == lo):
            bound = f"{'(' if lo_open else '['}{lo:g}, {hi:g}]"
            raise argparse.ArgumentTypeError(f"{text} is outside {bound}{' ' + unit if unit else ''}")
        return value
    return parse


def output_file(text: str) -> Path:
    """An argparse type: a file path whose directory exists and is writable."""
    path = Path(text)
    parent = path.parent if str(path.parent) else Path(".")
    if path.is_dir():
        raise argparse.ArgumentTypeError(f"{text} is a directory: give a file name")
    if not parent.is_dir():
        raise argparse.ArgumentTypeError(f"directory {parent} does not exist: create it first")
    if not os.access(parent, os.W_OK):
        raise argparse.ArgumentTypeError(f"directory {parent} is not writable")
    return path


def new_directory(text: str) -> Path:
    """An argparse type: a directory to create (it must not exist; its parent must be writable)."""
    path = Path(text)
    if path.exists():
        raise argparse.ArgumentTypeError(f"{text} already exists: give a new directory")
    output_file(text)
    return path


def add_mechanism_group(parser: argparse.ArgumentParser, required: bool = True, default: str = "") -> None:
    """The ``--preset NAME | --mechanism FILE`` pair (one of them, ``required`` or not)."""
    group = parser.add_mutually_exclusive_group(required=required)
    group.add_argument("--preset", metavar="NAME", help="bundled mechanism (see `linkage-monitor presets`)"
                       + (f"; default: {default}" if default else ""))
    group.add_argument("--mechanism", metavar="FILE", help="mechanism YAML (docs/mechanism-schema.md)"
                       + (f"; default: {default}" if default else ""))


def add_recorded_bag(parser: argparse.ArgumentParser) -> None:
    """The positional ``BAG`` (a rosbag2 bag: its directory or one file) and the ``--preset NAME |
    --mechanism FILE`` pair, whose default is the mechanism the bag recorded."""
    parser.add_argument("bag", metavar="BAG",
                        help="bag directory (metadata.yaml + .mcap or .db3 files) or one .mcap / .db3 file")
    add_mechanism_group(parser, required=False, default="the one recorded in the bag")


def mechanism_from_args(args: argparse.Namespace) -> Mechanism | None:
    """The mechanism the ``--preset/--mechanism`` group names (None when neither was given)."""
    from linkage_monitor.mechanics import load_mechanism, load_preset

    if getattr(args, "preset", None):
        return load_preset(args.preset)
    if getattr(args, "mechanism", None):
        return load_mechanism(args.mechanism)
    return None


def run_with_ros_args(parser: argparse.ArgumentParser, run: Callable[[argparse.Namespace], int],
                      argv: Sequence[str] | None = None) -> int:
    """``python -m linkage_monitor.cli.<command>``: ``parser``'s options, and ROS's arguments after
    ``--ros-args`` (remappings, parameters) kept whole in ``args.ros_args`` for ``rclpy.init``."""
    from rclpy.utilities import remove_ros_args

    every = list(sys.argv if argv is None else argv)
    args = parser.parse_args(remove_ros_args(every)[1:])
    args.ros_args = every
    return run(args)
