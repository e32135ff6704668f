"""Every shell example of README.md and docs/*.md runs: exit code 0 (or the one the doc gives), no
traceback, and a `$ ` transcript prints what the doc shows.

The examples are read out of the markdown (`support/doc_examples.py`: fenced shell blocks and
inline `.venv/bin/` commands). Each command is classified here, by its text:
- RUNS: run as the doc writes it, or with stand-ins for what only the user has (their mechanism
  or mapping file, their CAN bus, their Dask cluster, their log and bags) named in its entry;
  a command that runs until stopped (a node, a viewer, the terminal view) is stopped with Ctrl-C
  once it has printed that it is working;
- CANNOT_RUN: why it cannot run here (the test suite itself, hardware, a ROS installation, a
  benchmark that needs the machine for minutes);
- HELD_ELSEWHERE: run by another test, named.
A command of the docs in none of them, or an entry no doc has any more, fails
`test_every_example_is_classified`: a new example is classified when it is written.

Each block runs in a directory of its own that links the checkout's files (`workdir`): what an
example writes (`out/`, `docs/`, fitted files) stays in the test's temporary directory.
"""

from __future__ import annotations

import shlex
from collections.abc import Iterator, Mapping
from contextlib import ExitStack, contextmanager
from dataclasses import dataclass, field, replace
from pathlib import Path

import pytest

from support.doc_examples import (ROOT, TRACEBACK, VENV_BIN, Command, Example, Finished, StandIn, all_examples,
                                  copy_of, dask_scheduler, directory_of, environment, link_to, output_of, run_once,
                                  run_until_ready, simulated_lift_csv, wait_for_line, workdir,
                                  x_display)

pytestmark = pytest.mark.slow

PRESET = "linkage_monitor/mechanics/presets/belarus_1221.yaml"
CAN_MAP = ("config/can/belarus_1221.yaml", "config/can/isobus_hitch.dbc")   # the mapping names the DBC beside it
CAN_LOG = "bags/can/belarus_1221_lift.log"
NODE_READY = "monitoring '"             # the node's log line once it has subscribed (ros/node.py)
CAN_READY = "CAN frames from"           # the CAN bridge's, once it listens (can/node.py)


@dataclass(frozen=True)
class Run:
    """How this test runs one command of the docs."""

    stand_ins: Mapping[str, StandIn] = field(default_factory=dict)   # a file of the user's -> how it is made
    # here (unless an earlier command of the block made it)
    arguments: Mapping[str, str] = field(default_factory=dict)   # an argument of the doc -> the one run here;
    # {bus} and {scheduler} are filled in
    ready: str | None = None   # runs until stopped: Ctrl-C once it has printed this
    exit_codes: frozenset[int] = frozenset({0})   # the exit codes that mean it worked
    needs: frozenset[str] = frozenset()   # services started for it: "display", "scheduler", "node" (a
    # belarus_1221 node), "monitor" (that node fed by the simulator)
    ros: bool = False   # starts a ROS node
    fails: str = ""   # a known fault of the software that makes it fail (reported): the example is xfail,
    # strictly, so that the fix must remove this


AS_IS = Run()
THE_NODE = Run(ready=NODE_READY, ros=True)
CAN_NODE = Run(ready=CAN_READY, ros=True)
MAPPING = {"my_tractor.yaml": copy_of(*CAN_MAP)}   # `--map my_tractor.yaml`: the user's copy of the mapping
WATCH = Run(needs=frozenset({"monitor"}), ready="linkage-monitor watch", ros=True)

RUNS: dict[str, Run] = {
    # README.md
    ".venv/bin/linkage-monitor presets": AS_IS,
    ".venv/bin/linkage-monitor solve --mechanism my_tractor.yaml --stroke lift_cylinder=0.6":
        Run(stand_ins={"my_tractor.yaml": copy_of(PRESET)}),
    ".venv/bin/linkage_monitor_node --ros-args --params-file config/belarus_1221.yaml": THE_NODE,
    ".venv/bin/python launch/monitor.launch.py --params config/belarus_1221.yaml": THE_NODE,
    "mkdir -p out": AS_IS,
    ".venv/bin/linkage-monitor replay bags/belarus_1221_lift_transport --out out/replayed --rrd out/replay.rrd": AS_IS,
    # the rerun launcher answers Ctrl-C with 130 (rerun_cli/__main__.py) or 0, as the viewer, which
    # gets the terminal's Ctrl-C too, quits before or after it
    # (a recording of the shortest bag stands in when the block has not written out/replay.rrd)
    ".venv/bin/rerun out/replay.rrd": Run(stand_ins={"out/replay.rrd": output_of(["mkdir", "-p", "out"], [
                                              "linkage-monitor", "replay", "bags/drill_coulter_relief", "--rrd",
                                              "out/replay.rrd", "--quiet"])},
                                          ready="replay.rrd", exit_codes=frozenset({0, 130}),
                                          needs=frozenset({"display"})),
    ".venv/bin/linkage-monitor fleet bags/ /data/tractor_bags/ --out out/fleet":
        Run(arguments={"/data/tractor_bags/": "tractor_bags/"},
            stand_ins={"tractor_bags": directory_of("bags/drill_coulter_relief")}),
    ".venv/bin/linkage-monitor fleet /shared/bags/ --out out/fleet --scheduler tcp://HOST:8786":
        Run(arguments={"/shared/bags/": "shared_bags/", "tcp://HOST:8786": "{scheduler}"},
            stand_ins={"shared_bags": directory_of("bags/drill_coulter_relief")}, needs=frozenset({"scheduler"})),
    ".venv/bin/linkage-monitor calibrate --mechanism my_tractor.yaml --data lift.mcap "
    "--free points.P05.x,points.P05.z,points.S6.x --out fitted.yaml":
        Run(stand_ins={"my_tractor.yaml": copy_of(PRESET),
                       "lift.mcap": link_to("bags/belarus_1221_lift_transport/belarus_1221_lift_transport_0.mcap")}),
    ".venv/bin/linkage-monitor can --bus socketcan:can0 --map config/can/belarus_1221.yaml":
        replace(CAN_NODE, arguments={"socketcan:can0": "virtual:{bus}"}),
    ".venv/bin/linkage-monitor can --topic --map my_tractor.yaml": replace(CAN_NODE, stand_ins=MAPPING),
    ".venv/bin/linkage-monitor can-to-bag bags/can/belarus_1221_lift.log --map config/can/belarus_1221.yaml "
    "--out out/can_bag": AS_IS,
    ".venv/bin/linkage-monitor can-calibrate LOG --map MAP --truth BAG --out fitted_map.yaml":
        Run(arguments={"LOG": CAN_LOG, "MAP": CAN_MAP[0], "BAG": "bags/can/belarus_1221_lift_truth"}),
    # docs/calibration.md: the data the example describes, simulated
    "linkage-monitor calibrate --preset belarus_1221 --data lift.csv "
    "--free points.P05.x,points.P05.z,points.S6.x,points.S6.z,implement.mass "
    "--sigma lift_arm_angle=5e-4 --sigma pressure:lift_cap_pressure=2e4 --out fitted.yaml":
        Run(stand_ins={"lift.csv": simulated_lift_csv}),
    # docs/connect-your-tractor.md: the bundled log stands in for the user's, its truth bag for their angle bag
    "linkage-monitor can-to-bag lift.log --map my_tractor.yaml --out out/lift_bag":
        Run(stand_ins={"lift.log": link_to(CAN_LOG), **MAPPING}),
    "linkage-monitor replay out/lift_bag": AS_IS,
    "linkage-monitor can-calibrate lift.log --map my_tractor.yaml --truth angle_bag --out my_tractor_calibrated.yaml":
        Run(stand_ins={"lift.log": link_to(CAN_LOG), "angle_bag": link_to("bags/can/belarus_1221_lift_truth"),
                       **MAPPING}),
    "linkage-monitor can-calibrate bags/can/belarus_1221_lift.log --map config/can/belarus_1221.yaml "
    "--truth bags/can/belarus_1221_lift_truth": AS_IS,
    "linkage-monitor can --bus socketcan:can0 --map my_tractor.yaml":
        replace(CAN_NODE, arguments={"socketcan:can0": "virtual:{bus}"}, stand_ins=MAPPING),
    "linkage-monitor can --topic --map my_tractor.yaml": replace(CAN_NODE, stand_ins=MAPPING),
    # docs/dead-centre.md, docs/performance.md
    ".venv/bin/linkage-monitor solve --preset belarus_1221 --explain": AS_IS,
    ".venv/bin/numba -s": AS_IS,
    # docs/watch.md: against a running monitor (a node fed by `linkage-monitor simulate --loop`)
    ".venv/bin/linkage-monitor watch": WATCH,
    ".venv/bin/linkage-monitor watch --namespace /tractor1": WATCH,
    ".venv/bin/linkage-monitor watch --once --timeout 10": Run(needs=frozenset({"monitor"}), ros=True),
    "linkage-monitor simulate --preset belarus_1221 --loop": Run(needs=frozenset({"node"}), ready="simulating '",
                                                                 ros=True),
    # inline commands
    "linkage-monitor --help": AS_IS,
    "linkage-monitor replay --help": AS_IS,
    "linkage-monitor capacity --preset belarus_1221 --stroke 0.515 0.715 --plot docs/capacity_belarus_1221.png": AS_IS,
    "linkage-monitor replay BAG --spectra": Run(arguments={"BAG": "bags/drill_coulter_relief"}),
    # docs/weighing.md
    ".venv/bin/linkage-monitor weigh bags/belarus_1221_lift_transport": AS_IS,
    ".venv/bin/linkage-monitor weigh bags/damping_hitch_lift --json": AS_IS,
    ".venv/bin/linkage-monitor replay bags/belarus_1221_lift_transport --implement-mass-source estimate": AS_IS,
    "linkage-monitor replay BAG --implement-mass-source estimate": Run(arguments={"BAG": "bags/damping_hitch_lift"}),
    # docs/dead-centre.md
    ".venv/bin/linkage-monitor replay bags/ttz1080_base_change_lift": AS_IS,
    # docs/lifecycle.md
    "linkage_monitor_lifecycle_node --ros-args --params-file config/belarus_1221.yaml":
        Run(ready="unconfigured: ", ros=True),
    ".venv/bin/python launch/monitor_lifecycle.launch.py --params config/belarus_1221.yaml": THE_NODE,
}

BENCHMARK = ("a benchmark or profile: it measures for tens of seconds to an hour and needs the machine to "
             "itself (`make bench` runs every bench)")
TEST_SUITE = "runs the test suite, which holds this test"
SYNOPSIS = "a synopsis: placeholders and [optional] parts"
MENTION = "the prose names a subcommand's option, not a whole command"
ROS2_CLI = ("needs a ROS 2 installation's ros2 CLI (and launch_ros to launch): the venv's wheels have neither "
            "(test_the_venv_has_no_ros2_cli)")
CANNOT_RUN: dict[str, str] = {
    "make demo": "sets up the venv (`make setup`), which the tests run in",
    "make test": TEST_SUITE,
    "ROS_DISTRO=kilted make test": TEST_SUITE + ", in another venv",
    ".venv/bin/python -m pytest -m \"not ros\"": TEST_SUITE,
    ".venv/bin/python -m pytest test/test_paper_ttz1080.py test/test_paper_ksu1_mower.py "
    "test/test_paper_drill_coulter.py -q -p no:cacheprovider": TEST_SUITE,
    **{f"ros2 {verb}": ROS2_CLI for verb in (
        "launch linkage_monitor monitor.launch.py params:=config/belarus_1221.yaml",
        "launch linkage_monitor monitor_lifecycle.launch.py params:=config/belarus_1221.yaml",
        "lifecycle set /linkage_monitor configure", "lifecycle set /linkage_monitor activate",
        "lifecycle set /linkage_monitor deactivate", "lifecycle set /linkage_monitor cleanup",
        "param set /linkage_monitor mechanism ttz1080_base_change",
        "param set /linkage_monitor pressure_topics \"['']\"")},
    "linkage-monitor calibrate (--mechanism START.yaml | --preset NAME) --data FILE.csv|BAG "
    "--free PARAM[,PARAM...] --out FITTED.yaml [--inputs NAME[,NAME...]] [--sigma COLUMN=VALUE ...] "
    "[--bound PARAM=HALF_WIDTH ...] [--gauge-pressure]": SYNOPSIS,
    "sudo ip link set can0 up type can bitrate 250000": "needs a CAN adapter (no vcan module here either)",
    "candump can0": "needs a CAN interface and can-utils",
    "candump -L can0 > lift.log": "needs a CAN interface and can-utils (the bundled log stands in for lift.log)",
    "ssh tractor": "logs in to the tractor's PC",
    "linkage-monitor replay BAG --map fixed.yaml [--dbc ...]": SYNOPSIS,
    "linkage-monitor fleet BAG_OR_DIR... --out DIR": SYNOPSIS,
    "linkage-monitor can --topic": MENTION + " (the whole command: README.md's CAN block)",
    "linkage-monitor solve --explain": MENTION + " (the whole command, with a preset: docs/dead-centre.md)",
    "linkage-monitor replay --out": MENTION,
    "make bench 2>&1 | tee bench.log": BENCHMARK,
    **{f".venv/bin/python bench/{bench}": BENCHMARK for bench in (
        "bench_step.py", "bench_solver.py", "bench_replay.py", "bench_replay.py --long-inputs 1000000",
        "bench_node.py --quick", "bench_node_rss.py", "bench_fleet.py", "bench_can.py",
        "bench_can.py --log-only", "bench_can.py --log-only --per-frame", "bench_encode.py", "bench_memory.py",
        "bench_bag.py", "bench_spin.py", "bench_cli_start.py", "bench_weighing.py",
        "bench_weighing.py --preset belarus_1221 --runs 240 --change-runs 0 --mass 200 400",
        "bench_weighing.py --preset belarus_1221 --runs 200 --change-runs 0 --mass 200 200",
        "bench_weighing.py --preset belarus_1221 --runs 200 --change-runs 0 --mass 250 250",
        "bench_weighing.py --preset belarus_1221 --runs 200 --change-runs 0 --mass 275 275",
        "bench_weighing.py --preset belarus_1221 --runs 200 --change-runs 0 --mass 300 300",
        "bench_weighing.py --preset belarus_1221 --runs 200 --change-runs 0 --mass 350 350",
        "bench_weighing.py --preset belarus_1221 --runs 200 --change-runs 0 --mass 200 200 --pressure-noise 5e3 "
        "--pressure-gain 0.0025 --pressure-offset 5e3",
        "bench_weighing.py --preset belarus_1221 --runs 240 --change-runs 0 --mass 200 400 --pressure-noise 5e3 "
        "--pressure-gain 0.0025 --pressure-offset 5e3", "bench_uncertainty_step.py", "bench_uncertainty_mc.py",
        "bench_dynamics.py",
        "bench_uncertainty_coverage.py", "bench_replay_process.py --repeat 3", "bench_startup.py 5", "run_all.py --full", "profile_step.py",
        "profile_step.py --idle-ms 5",
        "profile_node.py --stages --rate 50")},
}

HELD_ELSEWHERE: dict[str, str] = {   # command -> the test that runs it
    ".venv/bin/python tools/belarus_tables.py --out docs/belarus-1221-tables.md": "test/test_paper_belarus_1221.py",
    ".venv/bin/python tools/transmission_sweep.py": "test/test_reduced_coordinates.py",
}

EXAMPLES = all_examples()


def test_every_example_is_classified() -> None:
    found = {command.text for example in EXAMPLES for command in example.commands}
    where = {command.text: example.where for example in EXAMPLES for command in example.commands}
    classified = RUNS.keys() | CANNOT_RUN.keys() | HELD_ELSEWHERE.keys()
    assert not RUNS.keys() & CANNOT_RUN.keys() and not (RUNS.keys() | CANNOT_RUN.keys()) & HELD_ELSEWHERE.keys()
    new = sorted(f"{where[text]}: {text}" for text in found - classified)
    assert not new, "classify these examples in RUNS, CANNOT_RUN or HELD_ELSEWHERE:\n" + "\n".join(new)
    gone = sorted(classified - found)
    assert not gone, "no doc has these examples any more; remove them:\n" + "\n".join(gone)


def test_examples_held_elsewhere_are_run_there() -> None:
    for command, test in HELD_ELSEWHERE.items():
        script = next(word for word in command.split() if word.endswith(".py"))
        assert Path(script).name in (ROOT / test).read_text(), f"{test} does not run {script}"


def test_the_venv_has_no_ros2_cli() -> None:
    """`ros2 launch` stays in CANNOT_RUN only while the venv has no ros2 command."""
    assert not (VENV_BIN / "ros2").exists()


@contextmanager
def _monitor(base: Path, simulated: bool) -> Iterator[None]:
    """A belarus_1221 node (not recording), ``simulated``: fed by `linkage-monitor simulate --loop`."""
    from support.ros_harness import start_node, start_simulator, stop

    node = start_node({"mechanism": "belarus_1221", "record": False}, base / "monitor.log")
    simulator = start_simulator(["--preset", "belarus_1221", "--loop"], base / "simulator.log") if simulated else None
    try:
        wait_for_line(base / "monitor.log", NODE_READY, node)
        yield
    finally:
        if simulator is not None:
            stop(simulator)
        stop(node)


def _services(example: Example, base: Path, stack: ExitStack) -> dict[str, str]:
    """Start what the example's commands need; the values filled into their arguments."""
    needs = set().union(*(RUNS[c.text].needs for c in example.commands if c.text in RUNS))
    values = {"bus": f"doc-example-{base.name}"}
    if "display" in needs:
        values["DISPLAY"] = stack.enter_context(x_display())
    if "scheduler" in needs:
        values["scheduler"] = stack.enter_context(dask_scheduler())
    if "monitor" in needs or "node" in needs:
        stack.enter_context(_monitor(base, simulated="monitor" in needs))
    return values


def _argv(command: Command, run: Run, values: dict[str, str]) -> list[str]:
    """The command's arguments with the stand-ins put in."""
    return [run.arguments.get(word, word).format(**values) for word in shlex.split(command.text)]


def _check_transcript(command: Command, run: Run, finished: Finished) -> None:
    """The output a `$ ` transcript shows: the same lines when the command runs as written; with stand-in
    data, the same lines by their first word (labels, parameter names)."""
    printed = finished.output.splitlines()
    if not (run.stand_ins or run.arguments):
        assert printed[:len(command.output)] == list(command.output), finished.output
    else:
        labels = [line.split()[0] for line in command.output]
        assert [line.split()[0] for line in printed[:len(labels)]] == labels, finished.output


def _runnable(example: Example) -> bool:
    return any(c.text in RUNS for c in example.commands)


def _marks(example: Example) -> list[pytest.MarkDecorator]:
    """`ros` on an example that starts a node; xfail on one a known fault makes fail."""
    runs = [RUNS[c.text] for c in example.commands if c.text in RUNS]
    faults = "; ".join(run.fails for run in runs if run.fails)
    return ([pytest.mark.ros] if any(run.ros for run in runs) else []) + \
        ([pytest.mark.xfail(strict=True, reason=faults)] if faults else [])


@pytest.mark.parametrize("example", [pytest.param(e, id=e.where, marks=_marks(e)) for e in EXAMPLES if _runnable(e)])
def test_example_runs(example: Example, tmp_path: Path) -> None:
    work = workdir(tmp_path)
    with ExitStack() as stack:
        values = _services(example, tmp_path, stack)
        env = environment(tmp_path, **({"DISPLAY": values["DISPLAY"]} if "DISPLAY" in values else {}))
        for command in example.commands:
            if command.text in CANNOT_RUN or command.text in HELD_ELSEWHERE:
                continue
            assert command.text in RUNS, f"{example.where}: {command.text!r} is not classified (see the first test)"
            run = RUNS[command.text]
            for name, make in run.stand_ins.items():
                if not (work / name).exists():
                    make(work / name, work)
            argv = _argv(command, run, values)
            finished = run_until_ready(argv, work, env, run.ready) if run.ready is not None else run_once(argv, work, env)
            said = f"{example.where}: {command.text}\n{finished.output}"
            assert finished.code in run.exit_codes, f"exit code {finished.code}, not {sorted(run.exit_codes)}: {said}"
            assert TRACEBACK not in finished.output, said
            if command.output:
                _check_transcript(command, run, finished)
