"""`linkage-monitor simulate`: publish a simulated sensor stream of a mechanism (thin CLI).

The physics is in :mod:`linkage_monitor.sim.telemetry`, the publishing in
:mod:`linkage_monitor.sim.node` (imported only when the command runs, so `--help`
works without a ROS environment).
"""

from __future__ import annotations

import argparse
import sys
from typing import Sequence

from linkage_monitor.cli.arguments import add_mechanism_group, bounded, mechanism_from_args, run_with_ros_args
from linkage_monitor.cli.commands import COMMANDS
from linkage_monitor.mechanics import LinkageError
from linkage_monitor.sim.telemetry import SCENARIOS, Noise

# Default sensor noise (1 sigma): a Hall-effect rockshaft angle sensor ~0.1°, a stroke sensor
# 0.5 mm, a 0-25 MPa pressure transducer 0.2 % of full scale.
NOISE_ANGLE, NOISE_LENGTH, NOISE_PRESSURE = 0.002, 0.0005, 0.05e6   # rad, m, Pa


def add_simulate_arguments(parser: argparse.ArgumentParser) -> None:
    """Add the options of the simulate command to ``parser``."""
    add_mechanism_group(parser)
    parser.add_argument("--scenario", choices=SCENARIOS, default="lift",
                        help="driven by the lift cylinder: lift cycle, transport over bumps, field work, or "
                             "overload (steerability < 0); driven by the ground (one angle sensor and a contact, "
                             "Kotov & Krol; Naumenko et al. 2021): field_copy (shoes follow the field +-125 mm) or relief (a wheel over "
                             "Naumenko et al. 2021's relief at 0.2 then 0.4 m/s, with angle rates); default lift")
    parser.add_argument("--rate", type=bounded(0.1, 100_000.0, "Hz"), default=50.0, metavar="HZ",
                        help="samples per second, 0.1 to 100000, default 50")
    parser.add_argument("--noise-angle", type=bounded(0.0, 1.0, "rad"), default=NOISE_ANGLE, metavar="RAD",
                        help=f"angle sensor noise sigma, rad (default {NOISE_ANGLE})")
    parser.add_argument("--noise-length", type=bounded(0.0, 1.0, "m"), default=NOISE_LENGTH, metavar="M",
                        help=f"cylinder length noise sigma, m (default {NOISE_LENGTH})")
    parser.add_argument("--noise-pressure", type=bounded(0.0, 1e8, "Pa"), default=NOISE_PRESSURE, metavar="PA",
                        help=f"pressure noise sigma, Pa (default {NOISE_PRESSURE:g})")
    parser.add_argument("--duration", type=bounded(0.0, 1e6, "s", lo_open=True), default=None, metavar="S",
                        help="seconds to simulate (default: the scenario's own length)")
    parser.add_argument("--gauge", action="store_true",
                        help="publish gauge pressure (default: absolute = gauge + 101325 Pa, as FluidPressure defines)")
    parser.add_argument("--loop", action="store_true", help="repeat the scenario until Ctrl-C")
    parser.add_argument("--seed", type=bounded(0, 2**32 - 1, integer=True), default=0, help="seed of the scenario's random phases and the noise")
    parser.add_argument("--prefix", default="", help="topic prefix, e.g. 'sim/' -> sim/joint_states, "
                                                    "sim/pressure/<sensor>")


def add_simulate_parser(subparsers: argparse._SubParsersAction) -> argparse.ArgumentParser:
    """Register the ``simulate`` subcommand on ``subparsers``; returns its parser."""
    sub = subparsers.add_parser("simulate", help=COMMANDS["simulate"].help,
                                description=__doc__.splitlines()[0])
    add_simulate_arguments(sub)
    return sub


def parser() -> argparse.ArgumentParser:
    """Stand-alone parser of the simulate options (for ``python -m linkage_monitor.cli.simulate``)."""
    p = argparse.ArgumentParser(prog="linkage-monitor-simulate", description=__doc__.splitlines()[0])
    add_simulate_arguments(p)
    return p


def run_simulate(args: argparse.Namespace) -> int:
    """Run the simulate command; returns the exit code (2 for a bad mechanism or option)."""
    try:
        mech = mechanism_from_args(args)
        assert mech is not None   # the group is required
        noise = Noise(angle=args.noise_angle, length=args.noise_length, pressure=args.noise_pressure)
    except (LinkageError, ValueError) as exc:
        print(f"linkage-monitor simulate: {exc}", file=sys.stderr)
        return 2
    from linkage_monitor.sim.node import run

    try:
        return run(mech, args.scenario, args.rate, noise, args.duration, args.gauge, args.prefix, args.loop,
                   args.seed, args=getattr(args, "ros_args", None))
    except (LinkageError, ValueError) as exc:
        print(f"linkage-monitor simulate: {exc}", file=sys.stderr)
        return 2


def main(argv: Sequence[str] | None = None) -> int:
    """``python -m linkage_monitor.cli.simulate``: the options of ``linkage-monitor simulate`` plus ROS arguments."""
    return run_with_ros_args(parser(), run_simulate, argv)


if __name__ == "__main__":
    sys.exit(main())
