"""The shell examples of README.md and docs/*.md, read out of the markdown, and what running one
needs: a working directory beside the checkout, a long-running command stopped as Ctrl-C stops
it, a headless X display, a Dask scheduler, stand-in files for the user's own ones.

An example is a fenced block (```sh, ```bash, ```shell, ```console, or a bare ``` block that is a
`$ ` transcript or whose every line is a command, a program's name first) or an inline span that
starts with `.venv/bin/` and has an argument, or with `linkage-monitor` and has an option. In a block, `\\` continuations are joined and a trailing `# comment` dropped; a block
with `$ ` prompts is a transcript: its commands are the prompted lines, the lines after one are
the output the doc shows for it.
"""

from __future__ import annotations

import fcntl
import os
import pty
import re
import shutil
import signal
import struct
import subprocess
import sys
import termios
import threading
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
# the venv running the tests: `.venv` (Jazzy) as the docs write it, or `.venv-kilted` under
# ROS_DISTRO=kilted, which the examples' `.venv` stands for in their working directory
VENV = Path(sys.prefix)
VENV_BIN = VENV / "bin"
DOCS = (ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md")))
SHELL_LANGUAGES = {"sh", "bash", "shell", "console"}
COMMAND_START = re.compile(r"(\$ |\.venv/bin/|linkage-monitor(\s|$)|linkage_monitor_\w+|python3? |make |ros2 |colcon |"
                           r"rosdep |candump |sudo |ssh |cd |mkdir |[A-Z_]+=\S+ )")
FENCE = re.compile(r"^\s*```(\S*)\s*$")
INLINE = re.compile(r"`(\.venv/bin/[^`]*\s[^`]*|linkage-monitor [^`]*(?<=\s)-[^`]*)`")
COMMENT = re.compile(r"(^|\s)#.*$")
TRACEBACK = "Traceback (most recent call last)"
# the checkout's entries an example may name; the working directory links them (read only: no
# example that runs writes under them) and has its own `docs/` and `out/`
NOT_LINKED = {".git", "build", "out", "docs", "log", "install", ".venv"}


@dataclass(frozen=True)
class Command:
    """One command of a doc: continuation lines joined, the `$ ` prompt and a trailing comment
    dropped, whitespace collapsed; ``output``: the lines a transcript shows after it."""

    text: str
    output: tuple[str, ...] = ()


@dataclass(frozen=True)
class Example:
    """A shell block (or an inline command) of a doc: commands run in order in one directory."""

    doc: str
    line: int   # 1-based line of the block's first command or of the inline span
    commands: tuple[Command, ...]

    @property
    def where(self) -> str:
        return f"{self.doc}:{self.line}"


def _text(line: str) -> str:
    return " ".join(COMMENT.sub("", line).split())


def _joined(lines: list[str]) -> list[str]:
    """The block's lines with `\\` continuations joined."""
    out: list[str] = []
    pending = ""
    for line in lines:
        if line.rstrip().endswith("\\"):
            pending += line.rstrip()[:-1] + " "
        else:
            out.append(pending + line)
            pending = ""
    return out + ([pending] if pending else [])


def _commands(lines: list[str]) -> tuple[Command, ...]:
    lines = [line for line in _joined(lines) if line.strip()]
    if not any(line.startswith("$ ") for line in lines):
        return tuple(Command(_text(line)) for line in lines if not line.lstrip().startswith("#"))
    commands: list[Command] = []
    for line in lines:
        if line.startswith("$ "):
            commands.append(Command(_text(line[2:])))
        elif commands:
            commands[-1] = Command(commands[-1].text, (*commands[-1].output, line.rstrip()))
    return tuple(commands)


def _is_shell(language: str, body: list[str]) -> bool:
    """A block tagged as shell, or a bare block that is a `$ ` transcript or holds commands only
    (not a directory tree, a table, a screen or a message that starts with a program's name)."""
    lines = [line for line in _joined(body) if line.strip()]
    if language in SHELL_LANGUAGES:
        return True
    return language == "" and bool(lines) and (lines[0].startswith("$ ")
                                                or all(COMMAND_START.match(line) for line in lines))


def examples_of(doc: Path) -> list[Example]:
    """Every shell block and inline `.venv/bin/` command of ``doc``, in the order they appear."""
    name = doc.relative_to(ROOT).as_posix()
    lines = doc.read_text(encoding="utf-8").splitlines()
    found: list[Example] = []
    prose = list(lines)   # the doc with its fenced blocks blanked out (line numbers kept)
    i = 0
    while i < len(lines):
        fence = FENCE.match(lines[i])
        if fence is None:
            i += 1
            continue
        end = next((j for j in range(i + 1, len(lines)) if lines[j].strip().startswith("```")), len(lines))
        body = lines[i + 1:end]
        if _is_shell(fence.group(1), body):
            found.append(Example(name, i + 2, _commands(body)))
        prose[i:end + 1] = [""] * (min(end, len(lines) - 1) + 1 - i)
        i = end + 1
    text = "\n".join(prose)
    for span in INLINE.finditer(text):
        found.append(Example(name, text.count("\n", 0, span.start()) + 1, (Command(" ".join(span.group(1).split())),)))
    return sorted(found, key=lambda e: e.line)


def all_examples() -> list[Example]:
    """The examples of README.md and every docs/*.md."""
    return [example for doc in DOCS for example in examples_of(doc)]


def workdir(base: Path) -> Path:
    """A directory to run examples in, as the checkout looks to a user: its entries linked (read
    only), `.venv` the venv running the tests, its own empty `docs/` and no `out/`; a private HOME beside it (the viewer and Dask
    write there)."""
    work = base / "work"
    work.mkdir()
    for entry in ROOT.iterdir():
        if entry.name not in NOT_LINKED:
            (work / entry.name).symlink_to(entry)
    (work / "docs").mkdir()
    (work / ".venv").symlink_to(VENV)
    (base / "home").mkdir(mode=0o700)
    return work


def environment(base: Path, **extra: str) -> dict[str, str]:
    """The process environment of an example: the venv's programs first on PATH (as `linkage-monitor`
    and `python` are after activating it), HOME in ``base``."""
    home = str(base / "home")
    return dict(os.environ, PATH=f"{VENV_BIN}{os.pathsep}{os.environ.get('PATH', '')}", HOME=home,
                XDG_RUNTIME_DIR=home, XDG_CONFIG_HOME=f"{home}/.config", XDG_DATA_HOME=f"{home}/.local/share",
                **extra)


@dataclass(frozen=True)
class Finished:
    """A command's exit code and what it printed (stdout and stderr, interleaved)."""

    code: int
    output: str


def run_once(argv: list[str], work: Path, env: dict[str, str], timeout: float = 120.0) -> Finished:
    """Run a command that ends by itself."""
    done = subprocess.run(argv, cwd=work, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                          timeout=timeout)
    return Finished(done.returncode, done.stdout)


def run_until_ready(argv: list[str], work: Path, env: dict[str, str], ready: str, linger: float = 1.0,
                    timeout: float = 60.0) -> Finished:
    """Start a command that runs until stopped, in a terminal of 100x30 characters (a pseudo-terminal:
    what draws a screen draws it), wait until it prints ``ready``, let it run ``linger`` s more, then
    press Ctrl-C (SIGINT to its process group, as the terminal sends it)."""
    main_fd, child_fd = pty.openpty()
    fcntl.ioctl(child_fd, termios.TIOCSWINSZ, struct.pack("HHHH", 30, 100, 0, 0))
    proc = subprocess.Popen(argv, cwd=work, env=dict(env, TERM="xterm-256color"), stdin=child_fd, stdout=child_fd,
                            stderr=child_fd, start_new_session=True)
    os.close(child_fd)
    printed = bytearray()

    def read() -> None:
        try:
            while chunk := os.read(main_fd, 65536):
                printed.extend(chunk)
        except OSError:   # EIO: the terminal's last writer has exited
            pass

    reader = threading.Thread(target=read, daemon=True)
    reader.start()
    end = time.monotonic() + timeout
    try:
        while ready.encode() not in printed:
            if proc.poll() is not None or time.monotonic() > end:
                reader.join(timeout=5.0)
                why = f"exited with code {proc.returncode}" if proc.poll() is not None else f"not within {timeout} s"
                raise AssertionError(f"{argv} did not print {ready!r} ({why}); it printed:\n"
                                     f"{printed.decode(errors='replace')}")
            time.sleep(0.1)
        time.sleep(linger)
        os.killpg(proc.pid, signal.SIGINT)
        code = proc.wait(timeout=20.0)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()
        reader.join(timeout=5.0)
        os.close(main_fd)
    return Finished(code, printed.decode(errors="replace"))


def wait_for_line(log: Path, text: str, proc: subprocess.Popen, timeout: float = 60.0) -> None:
    """Wait until the process ``proc`` writing ``log`` has written ``text`` there."""
    end = time.monotonic() + timeout
    while not (log.exists() and text in log.read_text(errors="replace")):
        assert proc.poll() is None and time.monotonic() < end, \
            f"{proc.args!r} did not write {text!r} (exit code {proc.poll()}):\n{log.read_text(errors='replace')}"
        time.sleep(0.1)


@contextmanager
def x_display() -> Iterator[str]:
    """A headless X server (Xvfb, on a free display number): yields its DISPLAY."""
    server = subprocess.Popen(["Xvfb", "-displayfd", "1", "-screen", "0", "1280x800x24", "-nolisten", "tcp"],
                              stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True)
    try:
        assert server.stdout is not None
        number = server.stdout.readline().strip()
        assert number.isdigit(), f"Xvfb gave no display number (exit code {server.poll()})"
        yield f":{number}"
    finally:
        server.terminate()
        server.wait(timeout=10.0)


@contextmanager
def dask_scheduler() -> Iterator[str]:
    """A running Dask cluster: a scheduler on TCP and one worker thread in this process (a worker
    process would import the package anew, seconds more): yields the scheduler's address."""
    from dask.distributed import LocalCluster

    with LocalCluster(n_workers=1, threads_per_worker=1, processes=False, protocol="tcp",
                      dashboard_address=None) as cluster:
        yield cluster.scheduler_address


# stand-ins: how a file the doc takes as the user's own is made in the working directory

StandIn = Callable[[Path, Path], None]   # (the file to make, the working directory)


def link_to(source: str) -> StandIn:
    """The checkout's file or directory ``source`` (relative), linked."""
    return lambda path, work: path.symlink_to(ROOT / source)


def copy_of(*sources: str) -> StandIn:
    """A copy of the checkout's file ``sources[0]``; further ``sources`` copied beside it (the
    files it names relative to itself)."""
    def make(path: Path, work: Path) -> None:
        shutil.copyfile(ROOT / sources[0], path)
        for other in sources[1:]:
            shutil.copyfile(ROOT / other, path.parent / Path(other).name)
    return make


def directory_of(*sources: str) -> StandIn:
    """A directory holding copies of the checkout's bag directories ``sources``."""
    def make(path: Path, work: Path) -> None:
        path.mkdir(parents=True)
        for source in sources:
            shutil.copytree(ROOT / source, path / Path(source).name)
    return make


def output_of(*argvs: list[str]) -> StandIn:
    """What commands (those of another doc example) write, run in the working directory."""
    def make(path: Path, work: Path) -> None:
        for argv in argvs:
            done = run_once(argv, work, environment(work.parent))
            assert done.code == 0, f"{argv} (making {path.name}) exited {done.code}:\n{done.output}"
    return make


def simulated_lift_csv(path: Path, work: Path) -> None:
    """The data of docs/calibration.md's example: one lift cycle of belarus_1221 at 10 Hz with the
    lower-link pivot P05 moved by (+3, -2) mm and the header cg S6 10 mm further back, angle noise
    0.5 mrad, pressure noise 20 kPa; columns lift_cylinder (m), lift_arm_angle (rad),
    pressure:lift_cap_pressure (Pa gauge)."""
    import csv

    from linkage_monitor.mechanics import load_preset
    from linkage_monitor.mechanics.calibration import parameter_value, with_parameters
    from linkage_monitor.sim.telemetry import Noise, simulate

    preset = load_preset("belarus_1221")
    moved = {"points.P05.x": 0.003, "points.P05.z": -0.002, "points.S6.x": -0.010}
    truth = with_parameters(preset, {key: parameter_value(preset, key) + d for key, d in moved.items()})
    inputs = simulate(truth, "lift", rate_hz=10.0, noise=Noise(angle=5e-4, pressure=2e4)).solver_inputs()
    with open(path, "w", newline="") as f:
        writer = csv.writer(f)
        writer.writerow(["lift_cylinder", "lift_arm_angle", "pressure:lift_cap_pressure"])
        writer.writerows(zip(inputs["cylinders"]["lift_cylinder"], inputs["angles"]["lift_arm_angle"],
                             inputs["pressures"]["lift_cap_pressure"]))
