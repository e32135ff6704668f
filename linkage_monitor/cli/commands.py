"""The subcommands of ``linkage-monitor``: name, one-line help, and the module that adds its options and
runs it. Only the module of the subcommand being run is imported (``cli.main``): ``--help`` and
``presets`` load neither numba, scipy, the kernels nor the bag writer. This module imports nothing.
"""

from __future__ import annotations

from typing import NamedTuple

EXIT_CODES = ("exit codes: 0 done (the monitor's verdict OK or WARN); 1 the monitor's verdict is ERROR "
              "(solve: on the pose; capacity: on a pose of the sweep) or replay solved no pose; 2 a bad "
              "option or input file (one line on stderr)")


class Command(NamedTuple):   # not a dataclass: importing dataclasses costs more than the whole --help
    """A subcommand. ``add``: the function of ``module`` that registers its parser on the subparsers
    (the CAN subcommands share one, which registers all three); ``run``: the function that runs it
    (Namespace -> exit code)."""

    name: str
    help: str
    module: str
    add: str
    run: str


COMMANDS = {c.name: c for c in (
    Command("presets", "list the bundled mechanisms and implement files with their description", "linkage_monitor.cli.presets",
            "add_presets_parser", "run_presets"),
    Command("solve", "solve one pose as the monitor node does: hinge reactions, cylinder forces, implement load, "
            "axle loads, the node's findings", "linkage_monitor.cli.solve", "add_solve_parser", "run_solve"),
    Command("capacity", "lift capacity (hitch axis, 610 mm, implement cg) and steerability limit over the stroke",
            "linkage_monitor.cli.capacity", "add_capacity_parser", "run_capacity"),
    Command("calibrate", "fit geometry parameters (pivots, cg, bore, mass) to measured kinematics and pressures",
            "linkage_monitor.cli.calibrate", "add_calibrate_parser", "run_calibrate"),
    Command("simulate", "publish simulated JointState + FluidPressure telemetry", "linkage_monitor.cli.simulate",
            "add_simulate_parser", "run_simulate"),
    Command("replay", "re-run the monitor offline over a recorded bag", "linkage_monitor.cli.replay",
            "add_replay_parser", "run_replay"),
    Command("weigh", "the implement's mass and cg, with their uncertainty, from a bag's lifts and lowers",
            "linkage_monitor.cli.weigh", "add_weigh_parser", "run_weigh"),
    Command("fleet", "analyse many bags on Dask: load spectra, damage-equivalent loads, margins",
            "linkage_monitor.cli.fleet", "add_fleet_parser", "run_fleet_command"),
    Command("can", "the live monitor fed from a CAN bus or /from_can_bus (ros2_socketcan)",
            "linkage_monitor.cli.can", "add_can_parsers", "run_can_command"),
    Command("can-to-bag", "decode a CAN log into a bag for `linkage-monitor replay`", "linkage_monitor.cli.can",
            "add_can_parsers", "run_can_command"),
    Command("can-calibrate", "fit the mapping's position tables (hitch position -> angle, length) from a recorded "
            "lift", "linkage_monitor.cli.can", "add_can_parsers", "run_can_command"),
    Command("watch", "live terminal view of a running monitor: hinge forces, steerability, lift reserve, "
            "diagnostics, rates", "linkage_monitor.cli.watch", "add_watch_parser", "run_watch"),
)}
