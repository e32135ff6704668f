"""``linkage-monitor presets``: the bundled mechanisms with their one-line description, then the
bundled implement files (docs/implements.md) with theirs (reads their YAML files only: no solver,
no compiled kernels)."""

from __future__ import annotations

import argparse

from linkage_monitor.cli.commands import COMMANDS
from linkage_monitor.mechanics.implements import implement_description, implement_names
from linkage_monitor.mechanics.presets import preset_description, preset_names


def add_presets_parser(subparsers: argparse._SubParsersAction) -> argparse.ArgumentParser:
    """Add the ``presets`` subcommand to ``subparsers``; returns its parser."""
    return subparsers.add_parser("presets", help=COMMANDS["presets"].help)


def run_presets(args: argparse.Namespace) -> int:
    """Print one line per preset (its name and description), then one per bundled implement."""
    for name in preset_names():
        print(f"{name:<24} {preset_description(name)}")
    print("\nimplements (MonitorConfig.implement, Monitor.select_implement):")
    for name in implement_names():
        print(f"{name:<24} {implement_description(name)}")
    return 0
