"""``linkage-monitor can`` (the live CAN bridge node), ``can-to-bag`` (a CAN log -> a bag for
``replay``) and ``can-calibrate`` (fit the mapping's position tables from a recorded lift).
DBC files: ``--dbc`` (repeatable) or the mapping's own ``dbc`` list; mapping: docs/can-mapping.md.
"""

from __future__ import annotations

import argparse
import shutil
import sys
from pathlib import Path
from typing import Any

import yaml

from linkage_monitor.cli.arguments import add_mechanism_group, bounded, mechanism_from_args, new_directory, output_file
from linkage_monitor.cli.main import emit
from linkage_monitor.mechanics import InputError, Mechanism, load_description
from linkage_monitor.monitoring.config import MonitorConfig

RAW_TOPIC = "/from_can_bus"


def _common(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--map", required=True, metavar="FILE", help="mapping YAML: which DBC signal feeds which "
                        "input (docs/can-mapping.md), e.g. config/can/belarus_1221.yaml")
    parser.add_argument("--dbc", action="append", default=[], metavar="FILE",
                        help="DBC file (repeatable); default: the mapping's 'dbc' list")
    add_mechanism_group(parser, required=False, default="the mapping's 'mechanism'")


def add_can_parsers(sub: Any) -> None:
    """The three CAN subcommands."""
    live = sub.add_parser("can", help="the live monitor fed from a CAN bus or /from_can_bus (ros2_socketcan)",
                          description="Run the monitor node on CAN frames: from a python-can bus (--bus "
                          "INTERFACE:CHANNEL, e.g. socketcan:can0, udp_multicast:239.74.163.2) or from "
                          "can_msgs/msg/Frame on a topic (--topic, default /from_can_bus). Publishes and records "
                          "what linkage_monitor_node does, plus the raw frames; Ctrl-C to stop. Node "
                          "parameters after --ros-args (e.g. -p record_dir:=out/bags).")
    _common(live)
    source = live.add_mutually_exclusive_group(required=True)
    source.add_argument("--bus", metavar="INTERFACE:CHANNEL", help="a python-can bus")
    source.add_argument("--topic", nargs="?", const=RAW_TOPIC, metavar="TOPIC",
                        help=f"subscribe to can_msgs/msg/Frame on TOPIC (default {RAW_TOPIC})")
    live.add_argument("--ros-args", dest="ros_args", nargs=argparse.REMAINDER, default=[],
                      help="ROS arguments for the node (parameters, remappings)")
    to_bag = sub.add_parser("can-to-bag", help="decode a CAN log into a bag for `linkage-monitor replay`",
                            description="Read a CAN log (candump .log, .asc, .blf, ... through python-can), decode "
                            "it with the DBC files and the mapping, and write a rosbag2 MCAP bag of the raw frames "
                            f"(can_msgs/msg/Frame on {RAW_TOPIC}) and the monitor's inputs, which `linkage-monitor "
                            "replay` turns into the live bridge's outputs. Prints the frame counts.")
    to_bag.add_argument("log", metavar="LOG", help="CAN log file")
    _common(to_bag)
    to_bag.add_argument("--out", required=True, metavar="DIR", type=new_directory, help="new bag directory")
    cal = sub.add_parser("can-calibrate", help="fit the mapping's position tables (hitch position -> angle, "
                         "length) from a recorded lift",
                         description="Fit each table of the mapping (signal -> measurement, monotone) from a CAN "
                         "log of a lift and the true values of the measurements during it (sensor_msgs/JointState "
                         "in a rosbag2 bag: a temporary sensor, or the simulator's truth). Prints the tables as "
                         "YAML; --out writes the mapping with them (its comments are not kept).")
    cal.add_argument("log", metavar="LOG", help="CAN log file of the lift")
    _common(cal)
    cal.add_argument("--truth", required=True, metavar="BAG", help="bag with the true values (JointState)")
    cal.add_argument("--truth-topic", default="/joint_states", metavar="TOPIC", help="its JointState topic")
    cal.add_argument("--points", type=bounded(2, 1000, integer=True), default=26, help="table points (default 26)")
    cal.add_argument("--out", type=output_file, metavar="FILE", help="write the calibrated mapping here")


def _setup(args: argparse.Namespace) -> tuple[Any, Mechanism, tuple[Path, ...]]:
    from linkage_monitor.can.mapping import load_mapping

    mapping = load_mapping(args.map)
    mech = mechanism_from_args(args)
    if mech is None:
        if mapping.mechanism is None:
            raise InputError(f"mapping {args.map}: no 'mechanism': give --preset NAME or --mechanism FILE")
        mech = load_description(mapping.mechanism)
    dbc = tuple(Path(d) for d in args.dbc) or mapping.dbc
    return mapping, mech, dbc


def _mechanism_spec(args: argparse.Namespace, mapping: Any) -> str:
    return args.preset or args.mechanism or mapping.mechanism


def run_can(args: argparse.Namespace) -> int:
    """The live bridge (ros.node.main with the CAN node)."""
    from rclpy.parameter import Parameter

    from linkage_monitor.can.decoder import CanDecoder, load_databases
    from linkage_monitor.can.node import CanBridgeNode, CanSource
    from linkage_monitor.can.sources import parse_bus
    from linkage_monitor.ros.node import main as node_main

    mapping, mech, dbc = _setup(args)
    # the bus, the DBC files and the mapping checked before the node starts (and records)
    if args.bus is not None:
        parse_bus(args.bus)
    CanDecoder(load_databases(dbc), mapping, mech, MonitorConfig.default(_mechanism_spec(args, mapping), mech), "check")
    source = CanSource(mapping=mapping, dbc=dbc, bus=args.bus, topic=args.topic or RAW_TOPIC)
    overrides = [Parameter("mechanism", value=_mechanism_spec(args, mapping))]
    return node_main(["linkage-monitor", "--ros-args", *args.ros_args],
                     make_node=lambda: CanBridgeNode(source, parameter_overrides=overrides))


SHOWN_LINES = 10   # refused log lines named one by one on stderr


def run_can_to_bag(args: argparse.Namespace) -> int:
    """A CAN log -> a bag; prints the frame counts and the refusals by reason, the refused log lines on
    stderr. A log that gives no bag leaves none behind."""
    from linkage_monitor.can.candump import RefusedLine
    from linkage_monitor.can.decoder import CanDecoder, load_databases
    from linkage_monitor.can.sources import read_log_blocks
    from linkage_monitor.can.to_bag import blocks_to_bag, refusal_lines

    mapping, mech, dbc = _setup(args)
    config = MonitorConfig.default(_mechanism_spec(args, mapping), mech)
    decoder = CanDecoder(load_databases(dbc), mapping, mech, config, Path(args.log).name)
    refused: list[RefusedLine] = []
    try:
        converted = blocks_to_bag(read_log_blocks(args.log, refused), decoder, mech, config, args.out)
        if converted.counts.received == 0:
            raise InputError(f"CAN log {args.log}: no frame{_refused_text(refused)}")
    except BaseException:
        shutil.rmtree(args.out, ignore_errors=True)
        raise
    if refused:
        print(f"linkage-monitor: CAN log {args.log}: {len(refused)} line(s) refused, not converted"
              f"{_refused_text(refused)}", file=sys.stderr)
    emit("\n".join([converted.counts.summary(), *refusal_lines(converted.refusals),
                    f"bag written to {args.out}: `linkage-monitor replay {args.out}` gives the monitor's outputs"]))
    return 0


def _refused_text(refused: list[Any]) -> str:
    """``: line 4 (reason); line 3025 (reason)`` for the first SHOWN_LINES refused lines, then how many more."""
    named = "; ".join(f"line {r.number} ({r.reason})" for r in refused[:SHOWN_LINES])
    more = f"; and {len(refused) - SHOWN_LINES} more" if len(refused) > SHOWN_LINES else ""
    return f": {named}{more}" if refused else ""


def run_can_calibrate(args: argparse.Namespace) -> int:
    """Fit the tables; print them (YAML) with their fit, write the calibrated mapping with --out."""
    import numpy as np

    from linkage_monitor.bag.columns import JointStateColumns
    from linkage_monitor.bag.reader import read_inputs
    from linkage_monitor.can.calibrate import fit_tables
    from linkage_monitor.can.decoder import load_databases
    from linkage_monitor.can.mapping import UNITS
    from linkage_monitor.can.sources import read_log
    from linkage_monitor.can.units import KIND_UNITS, SI_UNIT, input_kinds

    mapping, mech, dbc = _setup(args)
    columns = read_inputs(args.truth).get(args.truth_topic)
    if not isinstance(columns, JointStateColumns):
        raise InputError(f"bag {args.truth} holds no sensor_msgs/JointState on {args.truth_topic}")
    kinds = input_kinds(mech)
    truth = {}
    for item in mapping.inputs:
        if item.table is None or item.name not in columns.names:
            continue
        kind = kinds.get(item.name)
        if kind is None:
            raise InputError(f"mapping {args.map}: inputs.{item.name}: not a measurement of '{mech.name}'")
        factor = UNITS[KIND_UNITS[kind]][item.unit or SI_UNIT[kind]]
        values = columns.position[:, columns.names.index(item.name)]
        keep = np.isfinite(values)
        truth[item.name] = (columns.stamp_ns[keep], values[keep] / factor)
    fitted = fit_tables(mapping, load_databases(dbc), read_log(args.log), truth, int(args.points))
    tables = {f.input.name: {"signal": list(f.table.signal), "value": list(f.table.value)} for f in fitted}
    for f in fitted:
        print(f"# {f.input.name}: {f.samples} frames of {f.input.message}.{f.input.signal}, {len(f.table.signal)} "
              f"points over {f.table.span()}, largest error against the truth {f.max_error:.3g} "
              f"{f.input.unit or SI_UNIT[kinds[f.input.name]]}")
    print(yaml.safe_dump({"inputs": {name: {"table": t} for name, t in tables.items()}}, sort_keys=False))
    if args.out:
        data = yaml.safe_load(Path(args.map).read_text(encoding="utf-8"))
        for name, table in tables.items():
            data["inputs"][name]["table"] = table
        args.out.write_text(yaml.safe_dump(data, sort_keys=False), encoding="utf-8")
        print(f"calibrated mapping written to {args.out}")
    return 0


def add_redecode_arguments(replay: argparse.ArgumentParser) -> None:
    """``replay --map [--dbc]``: decode the bag's raw CAN frames again before replaying."""
    group = replay.add_argument_group("CAN", "decode the raw frames the bag recorded again, with a corrected DBC or "
                                      "mapping, instead of the inputs decoded when it was recorded")
    group.add_argument("--map", metavar="FILE", help="mapping YAML (docs/can-mapping.md)")
    group.add_argument("--dbc", action="append", default=[], metavar="FILE",
                       help="DBC file (repeatable); default: the mapping's 'dbc' list")
    group.add_argument("--raw-topic", default=RAW_TOPIC, metavar="TOPIC",
                       help=f"the bag's can_msgs/msg/Frame topic (default {RAW_TOPIC})")


def redecoded(args: argparse.Namespace, work: Path) -> Path:
    """The bag of ``args.bag``'s raw frames decoded again (``--map``/``--dbc``) under ``work``, with the
    mechanism and configuration the bag recorded (or given); prints the frame counts."""
    from linkage_monitor.can.decoder import CanDecoder, load_databases
    from linkage_monitor.can.mapping import load_mapping
    from linkage_monitor.can.sources import read_bag_frames
    from linkage_monitor.can.to_bag import can_to_bag, refusal_lines
    from linkage_monitor.offline.replay import recording_in_bag

    mapping = load_mapping(args.map)
    recorded = recording_in_bag(Path(args.bag))
    mech = mechanism_from_args(args) or recorded.description
    if mech is None:
        raise InputError(f"bag {args.bag} holds no mechanism description: give --preset NAME or --mechanism FILE")
    config = recorded.config or MonitorConfig.default(mech.name, mech)
    decoder = CanDecoder(load_databases(tuple(Path(d) for d in args.dbc) or mapping.dbc), mapping, mech, config,
                         args.raw_topic)
    bag = work / "redecoded"
    converted = can_to_bag(read_bag_frames(args.bag, args.raw_topic), decoder, mech, config, bag, args.raw_topic)
    emit("\n".join([f"decoded again with {args.map}: {converted.counts.summary()}",
                    *refusal_lines(converted.refusals)]))
    return bag


COMMANDS = {"can": run_can, "can-to-bag": run_can_to_bag, "can-calibrate": run_can_calibrate}


def run_can_command(args: argparse.Namespace) -> int:
    """Run one of the CAN subcommands."""
    return COMMANDS[args.command](args)
