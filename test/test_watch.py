"""`linkage-monitor watch`: the terminal view of a record filled by hand (every figure on an 80x24
screen, with its unit), and the command against a real node fed by `linkage-monitor simulate`:
`--once` prints what the node published, the live view in a real tmux terminal shows the node's
last output within 1 s of its publication.

Expected figures: the hand-filled record's numbers written out in the view's units (kN with two
decimals, deg with one, ratios with three), and for the live node the messages a test subscriber
received from it.
"""

from __future__ import annotations

import math
import re
import shutil
import subprocess
import sys
import time
from pathlib import Path

import pytest
import rclpy
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from rich.console import Console

from linkage_monitor.monitoring.loss import LossCounter
from linkage_monitor.msg import HingeReactions
from linkage_monitor.ros.watch import RATE_WINDOW_S, _Arrivals
from linkage_monitor.viz.terminal_view import (HingeLoad, StatusLine, TopicRate, WatchRecord, snapshot_lines,
                                               view)
from support.ros_harness import RELIABLE, MonitorClient, start_node, start_simulator, stop

WATCH = [sys.executable, "-m", "linkage_monitor.cli.main", "watch"]
TOPICS = ("/hinge_reactions", "/hitch_state", "/steerability", "/diagnostics")
BELARUS_HINGES = ("P03", "P34", "P45", "P05", "P56", "P07", "P67")   # the preset's hinges, in its order


def _loss_message() -> str:
    """The node's input-loss sentence (ros/node.py ``_report_losses``) around the real counter's summary."""
    counter = LossCounter()
    for seq in (1, 2, 6):   # 3 and 4 and 5 never arrive: a gap of 3
        counter.on_message("/joint_states", "pub", seq)
    counter.on_message("/pressure/lift_cap_pressure", "pub", 1)
    return (f"{counter.new_since_report()} input message(s) lost in the last 1 s (the monitor did not see them): "
            f"{counter.summary()}")


def _record(hinge_count: int = len(BELARUS_HINGES), output_age_s: float | None = 0.1) -> WatchRecord:
    names = BELARUS_HINGES if hinge_count == len(BELARUS_HINGES) else tuple(f"H{k}" for k in range(hinge_count))
    return WatchRecord(
        namespace="/", topics=TOPICS, mechanism="belarus_1221",
        hinges=tuple(HingeLoad(name, 10_000.0 * (k + 1) + 1_234.0, 100_000.0 + 567.0 * k)
                     for k, name in enumerate(names)),
        ratio=0.2561, ratio_min=0.2, margin=0.0561, ratio_reference="unit", lift_reserve=1.5349,
        implement_load_n=14_993.0, min_transmission_angle_rad=math.radians(26.94),
        statuses=(StatusLine("linkage_monitor: belarus_1221", "WARN", "lift reserve 0.93 below 1", "lift_reserve"),),
        loss=StatusLine("linkage_monitor: inputs", "WARN", _loss_message()), ignored=(("gps_driver: fix", 12),),
        rates=tuple(TopicRate(topic, rate, 100) for topic, rate in zip(TOPICS, (50.0, 50.0, 50.0, 1.0))),
        output_age_s=output_age_s)


# every figure of _record() as the view writes it, with its unit
FIGURES = ["11.23 kN", "71.23 kN", "peak 100.57 kN", "peak 103.40 kN", "0.256 [-]", "0.200 [-]", "+0.056 [-]",
           "1.535 [-]", "14.99 kN", "26.9 deg", "50.0 msg/s", "1.0 msg/s", "WARN", "lift reserve 0.93 below 1",
           "/joint_states: 3 lost of 3 received", "/pressure/lift_cap_pressure: 0 lost of 1 received (sequence gaps 0, middleware 0)",
           "not shown: 12 statuses (gps_driver: fix)"]


def _screen(record: WatchRecord, width: int, height: int) -> list[str]:
    console = Console(record=True, width=width, height=height, color_system=None)
    console.print(view(record, width, height))
    return console.export_text().splitlines()


@pytest.mark.parametrize("width,height", [(80, 24), (120, 40)])
def test_view_shows_every_figure_within_the_terminal(width, height):
    lines = _screen(_record(), width, height)
    text = "\n".join(lines)
    flowing = " ".join(line.strip(" │") for line in lines)   # a wrapped line read on across the break
    for figure in FIGURES:
        assert figure in flowing, f"{figure!r} not on the {width}x{height} screen:\n{text}"
    for name in BELARUS_HINGES:
        assert re.search(rf"^\W*{name} ", text, re.M), f"hinge {name} not on the screen:\n{text}"
    assert len(lines) <= height
    assert max(len(line) for line in lines) <= width
    assert "LIVE" in lines[0]


@pytest.mark.parametrize("count", [11, 20])
def test_view_of_many_hinges_fits_80x24(count):
    """damping_hitch has 11 hinges (one column), a mechanism of 20 takes two: each is on the 80x24
    screen with its force."""
    lines = _screen(_record(hinge_count=count), 80, 24)
    text = "\n".join(lines)
    for k in range(count):
        assert f"H{k} " in text and f"{(10_000.0 * (k + 1) + 1_234.0) / 1e3:.2f} kN" in text, text
    assert len(lines) <= 24 and max(len(line) for line in lines) <= 80


def test_stale_and_waiting_said_plainly():
    assert "STALE: no output for 3.5 s" in _screen(_record(output_age_s=3.5), 80, 24)[0]
    waiting = _screen(WatchRecord(namespace="/", topics=TOPICS), 80, 24)
    assert "WAITING: no output yet" in waiting[0]
    assert "waiting for /hinge_reactions, /hitch_state, /steerability, /diagnostics" in "\n".join(waiting)


def test_snapshot_has_one_figure_per_line():
    lines = snapshot_lines(_record())
    assert "hinge P03 |F| 11.23 kN (peak 100.00 kN)" in lines
    assert "steerability margin +0.056 [-]" in lines
    assert "min transmission angle 26.9 deg" in lines
    assert "received /diagnostics 1.0 msg/s" in lines
    assert "  /joint_states: 3 lost of 3 received (sequence gaps 3, middleware 0)" in lines


def test_received_rate_of_a_steady_stream_and_of_a_burst():
    """A 50 Hz stream over 3 s rates 50 msg/s over the last 2 s (RATE_WINDOW_S); two messages taken
    0.4 us apart after a silence rate as two messages over the window, not as 1 / 0.4 us; a topic first
    heard 1 s ago is rated over that 1 s."""
    steady = _Arrivals()
    for k in range(150):
        steady.arrived(1000.0 + k / 50)
    assert steady.rate(1000.0 + 149 / 50) == pytest.approx(50.0, abs=1.0)
    burst = _Arrivals()
    burst.arrived(900.0)   # heard long before
    burst.arrived(1000.0)
    burst.arrived(1000.0000004)
    assert burst.rate(1000.5) == 2 / RATE_WINDOW_S
    late = _Arrivals()
    for k in range(10):
        late.arrived(1000.0 + k / 10)
    assert late.rate(1001.0) == pytest.approx(10.0)


# ---- against a real node fed by the simulator -------------------------------------------------------------

@pytest.fixture(scope="module")
def monitor(ros, tmp_path_factory):
    """A belarus_1221 node (not recording) fed by `linkage-monitor simulate --loop`, and a test
    subscriber of its outputs in this process: yields (client, tmp directory, simulator process)."""
    tmp = tmp_path_factory.mktemp("watch")
    proc = start_node({"mechanism": "belarus_1221", "record": False}, tmp / "node.log")
    sim = start_simulator(["--preset", "belarus_1221", "--loop"], tmp / "sim.log")   # it waits for the node
    client = MonitorClient()
    try:
        client.wait_for_node()
        assert client.spin_until(lambda: bool(client.received["hinge_reactions"]), 30), (tmp / "sim.log").read_text()
        yield client, tmp, sim
    finally:
        stop(sim)
        client.close()
        code = stop(proc)
        assert code == 0, (tmp / "node.log").read_text()


def _hinge_figures(client: MonitorClient) -> dict[str, set[str]]:
    """Each hinge's |F| in every HingeReactions the client received, as the view writes it (kN)."""
    figures: dict[str, set[str]] = {}
    for msg in client.received["hinge_reactions"]:
        for h in msg.hinges:
            figures.setdefault(h.name, set()).add(f"{h.magnitude / 1e3:.2f} kN")
    return figures


@pytest.mark.ros
@pytest.mark.slow
def test_once_prints_what_the_node_published(monitor):
    client, _, _ = monitor
    from linkage_monitor.ros.watch import CODES_KEY
    from linkage_monitor.wire.diagnostics import CODES_KEY as NODE_CODES_KEY

    assert CODES_KEY == NODE_CODES_KEY
    watch = subprocess.run([*WATCH, "--once", "--timeout", "20"], capture_output=True, text=True, timeout=40)
    stdout, stderr = watch.stdout, watch.stderr
    client.spin_until(lambda: False, 0.5)   # the last outputs the watch may have seen
    assert watch.returncode == 0, stderr
    lines = stdout.splitlines()
    figures = _hinge_figures(client)
    for name in BELARUS_HINGES:
        line = next(line for line in lines if line.startswith(f"hinge {name} "))
        value = re.search(r"\|F\| (\S+ kN)", line)
        assert value and value.group(1) in figures[name], f"{line!r}: not a |F| the node published"
    ratio_min = {f"{m.ratio_min:.3f} [-]" for m in client.received["steerability"]}
    assert next(line for line in lines if line.startswith("ratio min ")).removeprefix("ratio min ") in ratio_min
    assert any(re.match(r"diagnostics (OK|WARN|ERROR|STALE) linkage_monitor: belarus_1221: .", line)
               for line in lines), stdout


@pytest.mark.ros
@pytest.mark.slow
def test_once_without_a_monitor_names_the_topics_and_exits_1():
    watch = subprocess.run([*WATCH, "--once", "--timeout", "1", "--namespace", "/no_tractor"], capture_output=True,
                           text=True, timeout=30)
    assert watch.returncode == 1 and watch.stdout == ""
    assert len(watch.stderr.splitlines()) == 1
    for topic in ("/no_tractor/hinge_reactions", "/no_tractor/hitch_state", "/no_tractor/steerability", "/diagnostics"):
        assert topic in watch.stderr


def _tmux(*args: str) -> str:
    return subprocess.run(["tmux", "-L", "linkage_monitor_watch_test", *args], check=True, capture_output=True,
                          text=True).stdout


def _capture() -> str:
    """The watch's screen as tmux holds it, whole: a capture taken while the view redraws (a box seen
    twice, the title line not first) is taken again, up to 20 times 20 ms apart."""
    for _ in range(20):
        screen = _tmux("capture-pane", "-p", "-t", "watch")
        titles = re.findall(r"╭─ ([^─]+) ─", screen)
        if screen.startswith("linkage-monitor watch") and len(titles) == len(set(titles)):
            return screen
        time.sleep(0.02)
    return screen


def _screen_forces(screen: str) -> tuple[str, ...] | None:
    """Each hinge's |F| on a captured screen, as written there (None if one is missing)."""
    found = [re.search(rf"{name} +(\d+\.\d\d kN)", screen) for name in BELARUS_HINGES]
    return tuple(m.group(1) for m in found if m) if all(found) else None


def _forces(msg: HingeReactions) -> tuple[str, ...]:
    return tuple(f"{h.magnitude / 1e3:.2f} kN" for h in msg.hinges)


SKEW_S = 0.2      # s: how much later than the view this process may stamp a message's receipt
IGNORED = re.compile(r"/diagnostics of other nodes, not shown: \d+ statuses \(gps_driver: fix\)")
STARVED_S = 0.5   # s: a gap of the node's outputs this long (25 of its 50 Hz) is a stall of the whole machine


def _steady(arrivals: list[tuple[int, HingeReactions]], at: int) -> bool:
    """Whether the outputs received in the 2 s before ``at`` (ns) came without a gap above STARVED_S."""
    times = [at - 2_000_000_000] + [t for t, _ in arrivals if at - 2_000_000_000 <= t <= at] + [at]
    return max(b - a for a, b in zip(times, times[1:])) <= STARVED_S * 1e9


@pytest.mark.ros
@pytest.mark.slow
@pytest.mark.skipif(shutil.which("tmux") is None, reason="tmux is not installed (Debian package tmux)")
def test_live_view_in_tmux_shows_outputs_within_1_s(monitor):
    """While the simulator runs, every screen captured shows the forces of a HingeReactions that
    arrived here (DDS receive time) no earlier than the newest one that had arrived 1 s before the
    capture; once the simulator has stopped, the screen shows the node's last outputs, and STALE
    3 s later. Another node's status on /diagnostics is counted and named, not shown."""
    client, tmp, sim = monitor
    arrivals: list[tuple[int, HingeReactions]] = []   # (receive time ns, message)
    client.node.create_subscription(HingeReactions, "hinge_reactions",
                                    lambda msg, info: arrivals.append((info["received_timestamp"], msg)), RELIABLE)
    # another node's status on /diagnostics, about 4 a second: counted and named, not shown as the monitor's
    other = client.node.create_publisher(DiagnosticArray, "/diagnostics", RELIABLE)
    _tmux("new", "-d", "-s", "watch", "-x", "80", "-y", "24", " ".join(WATCH) + f" 2> {tmp / 'watch.err'}")
    captures: list[tuple[int, str]] = []   # (capture time ns, screen)
    try:
        # up to 30 s: captures go on 2 s after the first LIVE one, and until the other node's status has been
        # counted (its publisher and the watch find each other over DDS discovery, slow on a loaded machine)
        started, end, live_until = time.monotonic(), time.monotonic() + 30, math.inf
        while time.monotonic() < end and not (time.monotonic() > live_until and IGNORED.search(captures[-1][1])):
            other.publish(DiagnosticArray(status=[DiagnosticStatus(level=DiagnosticStatus.ERROR, name="gps_driver: fix",
                                                                   message="no fix")]))
            client.spin_until(lambda: False, 0.2)
            captures.append((time.time_ns(), _capture()))
            if "LIVE" in captures[-1][1] and live_until == math.inf:
                live_until = time.monotonic() + 2.0
        assert stop(sim) == 0, (tmp / "sim.log").read_text()
        client.spin_until(lambda: False, 1.0)   # the last outputs arrive here and on the screen
        final = _capture()
        time.sleep(2.0)   # 3 s after the last output: more than --stale-after's default 2 s
        stale = _capture()
    finally:
        _tmux("kill-server")
    print(final)   # what the user sees (pytest -s)
    live = [(at, screen) for at, screen in captures if "LIVE" in screen.splitlines()[0]]
    assert len(live) >= 3, (f"the view said LIVE in fewer than 3 of {len(captures)} captures in "
                            f"{time.monotonic() - started:.1f} s:\n" + "\n".join(s for _, s in captures[-2:]))
    # a capture is judged where the node published steadily over the 2 s before it (no gap of its outputs
    # above STARVED_S here): on a starved machine the simulator, the node and the view stall together,
    # and no view can show what was not published in time
    steady = [(at, screen) for at, screen in live if _steady(arrivals, at)]
    assert len(steady) >= 3, f"the node published steadily before fewer than 3 of {len(live)} LIVE captures"
    for at, screen in steady:
        shown = _screen_forces(screen)
        # the view's process may take a message before this one stamps its own receipt of it: an arrival
        # up to SKEW_S after the capture counts as the one shown
        received = [t for t, msg in arrivals if t <= at + SKEW_S * 1e9 and _forces(msg) == shown]
        due = [t for t, _ in arrivals if t <= at - 1_000_000_000]   # arrived 1 s or more before the capture
        assert received and (not due or max(received) >= max(due)), (
            f"the screen shows forces {shown} received {(at - max(received, default=0)) / 1e9:.2f} s before the "
            f"capture, a newer output {(at - max(due)) / 1e9:.2f} s before it:\n{screen}")
    lines = final.splitlines()
    assert len(lines) <= 24 and max(len(line) for line in lines) <= 80
    assert _screen_forces(final) == _forces(client.received["hinge_reactions"][-1]), final
    last_steer, last_hitch = client.received["steerability"][-1], client.received["hitch_state"][-1]
    assert f"{last_steer.ratio:.3f} [-]" in final and f"{last_steer.margin:+.3f} [-]" in final, final
    assert f"{last_hitch.lift_reserve:.3f} [-]" in final, final
    assert IGNORED.search(final), final
    assert "no fix" not in final, final
    assert f"{math.degrees(last_hitch.min_transmission_angle):.1f} deg" in final, final
    assert "STALE: no output for" in stale.splitlines()[0], f"not STALE 3 s after the last output:\n{stale}"


@pytest.mark.slow
@pytest.mark.parametrize("namespace,reason", [("bad ns!", "alphanumerics"), ("/a//b", "repeated '/'")])
def test_bad_namespace_is_one_line_and_exit_2(namespace, reason):
    watch = subprocess.run([*WATCH, "--namespace", namespace, "--once"], capture_output=True, text=True, timeout=30)
    assert watch.returncode == 2 and watch.stdout == ""
    assert len(watch.stderr.splitlines()) == 1, watch.stderr
    assert f"--namespace {namespace}: " in watch.stderr and reason in watch.stderr, watch.stderr
