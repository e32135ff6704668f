"""``linkage-monitor`` command line: the subcommands of ``cli.commands``, each in its own module.

Only the module of the subcommand being run is imported (with its options): ``linkage-monitor --help``
and ``presets`` answer without loading numba, scipy, the compiled kernels or the bag writer.
SI units (m, rad, N, Pa); frame x forward, z up, origin at the rear wheels' ground contact.
"""

from __future__ import annotations

import argparse
import gc
import importlib
import os
import sys
from contextlib import contextmanager
from typing import Iterator, NoReturn, Sequence

from linkage_monitor.cli.commands import COMMANDS, EXIT_CODES, Command

BAD_INPUT_EXIT = 2   # a bad option or input file: one line on stderr (argparse's own code)
# the errors of the inputs (options, mechanism and YAML files, bags): module -> class; each module is
# loaded by the command that raises its error, so none is imported to recognise them
INPUT_ERRORS = {"linkage_monitor.mechanics.errors": "LinkageError", "linkage_monitor.bag.errors": "BagError",
                "yaml": "YAMLError"}


class _Parser(argparse.ArgumentParser):
    def error(self, message: str) -> NoReturn:  # one line on stderr, exit code 2
        self.exit(BAD_INPUT_EXIT, f"{self.prog}: error: {message}\n")


def _selected(argv: Sequence[str]) -> Command | None:
    """The subcommand ``argv`` names (its first argument that is not an option), if any."""
    first = next((a for a in argv if not a.startswith("-")), None)
    return COMMANDS.get(first) if first is not None else None


def build_parser(argv: Sequence[str] | None = None) -> argparse.ArgumentParser:
    """The argparse parser: every subcommand with its one-line help, and the options of the one ``argv``
    selects (all of them when ``argv`` is None: the subcommands' modules are imported then)."""
    parser = _Parser(prog="linkage-monitor", epilog=EXIT_CODES,
                     description="Loads in a tractor hitch linkage from cylinder strokes, joint angles and pressures "
                                 "(SI units: m, rad, N, Pa).")
    sub = parser.add_subparsers(dest="command", required=True, parser_class=_Parser)
    selected = _selected(argv) if argv is not None else None
    added: set[tuple[str, str]] = set()
    for command in COMMANDS.values():
        group = (command.module, command.add)
        if argv is None or command is selected or (selected is not None and group == (selected.module, selected.add)):
            if group not in added:
                with _collector_paused():
                    getattr(importlib.import_module(command.module), command.add)(sub)
                added.add(group)
        else:
            sub.add_parser(command.name, help=command.help)
    return parser


@contextmanager
def _collector_paused() -> Iterator[None]:
    """Python's cyclic garbage collector paused, and restored as it was after: a subcommand's imports
    (numpy, numba, the kernels) make many objects and no garbage, and the collections they set off took
    ~0.05 s of the CPU of `replay --help` (median of 8 runs on a loaded machine: 0.78 s paused, 0.83 s not)."""
    enabled = gc.isenabled()
    gc.disable()
    try:
        yield
    finally:
        if enabled:
            gc.enable()


def reader_gone() -> None:
    """Standard output's reader closed the pipe (``| head -1``): what is left to print, and the
    interpreter's last flush, go nowhere."""
    os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())


def emit(text: str) -> None:
    """Print ``text``; into a pipe its reader closed (``| head -1``), nowhere, and the command goes on
    (its exit code stays its own: ``solve``'s verdict, ``can-to-bag``'s conversion)."""
    try:
        print(text, flush=True)
    except BrokenPipeError:
        reader_gone()


def _input_error(exc: Exception) -> bool:
    """True for an error of the inputs (``INPUT_ERRORS``), reported in one line."""
    kinds = [getattr(sys.modules[m], name) for m, name in INPUT_ERRORS.items() if m in sys.modules]
    return isinstance(exc, tuple(kinds))


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command line; returns the exit code (``commands.EXIT_CODES``)."""
    argv = list(sys.argv[1:] if argv is None else argv)
    args = build_parser(argv).parse_args(argv)
    command = COMMANDS[args.command]
    module = importlib.import_module(command.module)
    try:
        return int(getattr(module, command.run)(args))
    except BrokenPipeError:   # `linkage-monitor presets | head -1`: the reader has what it wanted
        reader_gone()
        return 0
    except Exception as exc:
        if not _input_error(exc):
            raise
        print(f"linkage-monitor: error: {str(exc).splitlines()[0]}", file=sys.stderr)
        return BAD_INPUT_EXIT


if __name__ == "__main__":
    sys.exit(main())
