"""Simulator -> live node -> test subscriber, over real topics in three processes.

The node solves on every input message with the latest value of every other input. What it
received is read back from its own bag (rosbags AnyReader, a reader we did not write) and the
latest-inputs state is rebuilt in message order; every output the test client received must
then carry one of the simulated stamps and equal the offline solver's values
(`Solver.solve` + `MachineModel.evaluate`) for that state. The simulated stream is recomputed
here (it is deterministic in preset, scenario, rate, seed, duration and noise) to tie each input
stamp to its sample index.
"""

from __future__ import annotations

import math
import time
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import rclpy

from linkage_monitor.mechanics.constants import ATMOSPHERIC_PRESSURE
from linkage_monitor.mechanics import Inputs, Solver, load_preset
from linkage_monitor.mechanics.machine import MachineModel
from linkage_monitor.monitoring.core import ASSEMBLY_LIMIT_M
from linkage_monitor.wire.cdr import stamp_ns
from linkage_monitor.cli.simulate import NOISE_ANGLE, NOISE_LENGTH, NOISE_PRESSURE
from linkage_monitor.sim.telemetry import Noise, SimulatedStream, simulate
from support.ros_harness import (MonitorClient, node_bag, read_bag_rosbags, settle, start_node,
                                 start_simulator, stop, wait_exit)

PRESET = "belarus_1221"
RATE = 50.0                          # Hz, the simulator's sample rate
PERIOD_NS = round(1e9 / RATE)        # ns between simulated stamps (simulate(): start + round(i·1e9/rate))
JOINT_TOPIC = "/joint_states"
PRESSURE_TOPIC = "/pressure/lift_cap_pressure"
OUTPUT_TOPICS = ("hinge_reactions", "hitch_state", "steerability")
REL = 1e-9                           # the node runs the same mechanics: only round-off may differ


def _run(tmp_path: Path, scenario: str, noise: Noise, duration: float | None) -> tuple[MonitorClient, list]:
    """Node up, simulator run to its end, outputs collected, node stopped (bag closed).

    Returns the client (with every output it received) and the node's bag as
    (topic, log time ns, message) in the bag's order."""
    record_dir = tmp_path / "bags"
    proc = start_node({"mechanism": PRESET, "record_dir": str(record_dir)}, tmp_path / "node.log")
    client = MonitorClient()
    try:
        client.wait_for_node()
        args = ["--preset", PRESET, "--scenario", scenario, "--rate", str(RATE),
                "--noise-angle", repr(noise.angle), "--noise-length", repr(noise.length),
                "--noise-pressure", repr(noise.pressure)]
        if duration is not None:
            args += ["--duration", repr(duration)]
        sim = start_simulator(args, tmp_path / "sim.log")
        deadline = time.monotonic() + (duration or 15.0) + 30.0   # s: simulation set-up + publishing
        while sim.poll() is None and time.monotonic() < deadline:
            rclpy.spin_once(client.node, timeout_sec=0.05)
        wait_exit(sim, tmp_path / "sim.log", timeout=5.0)
        settle(client, "hitch_state")
    finally:
        client.close()
        code = stop(proc)
    assert code == 0, f"node exit code {code}:\n" + (tmp_path / "node.log").read_text()
    return client, read_bag_rosbags(node_bag(record_dir))


def _stream_index(stream: SimulatedStream, bag: list) -> tuple[int, int]:
    """(index, stamp ns) of one received input in the simulated stream, found by its values.

    The simulator stamps sample i with start + i·PERIOD_NS, start = its clock at start-up; the
    node may miss the first samples (best effort, before discovery), so the index is found by
    content: the first input whose values occur in exactly one simulated sample."""
    absolute = stream.pressure_values[:, 0] + ATMOSPHERIC_PRESSURE
    for topic, _, msg in bag:
        if topic == JOINT_TOPIC:
            hits = np.flatnonzero(np.all(stream.joint_positions == np.array(msg.position), axis=1))
        elif topic == PRESSURE_TOPIC:
            hits = np.flatnonzero(absolute == msg.fluid_pressure)
        else:
            continue
        if hits.size == 1:
            return int(hits[0]), stamp_ns(msg.header)
    raise AssertionError("no input in the bag matches exactly one simulated sample")


def _check_inputs_are_simulated(stream: SimulatedStream, bag: list) -> int:
    """Every input in the bag is sample i of the stream, stamped start + i·PERIOD_NS, with its
    values (pressure absolute = gauge + 101325 Pa, as FluidPressure defines). Returns start (ns)."""
    index, stamp = _stream_index(stream, bag)
    start = stamp - index * PERIOD_NS
    inputs = [(t, m) for t, _, m in bag if t in (JOINT_TOPIC, PRESSURE_TOPIC)]
    # best effort (sensor_data, depth 5): a busy machine drops some; enough must arrive to test anything
    assert len(inputs) > 0.5 * 2 * len(stream), f"node received only {len(inputs)} of {2 * len(stream)} inputs"
    for topic, msg in inputs:
        offset = stamp_ns(msg.header) - start
        assert offset % PERIOD_NS == 0 and 0 <= offset // PERIOD_NS < len(stream), stamp_ns(msg.header)
        i = offset // PERIOD_NS
        if topic == JOINT_TOPIC:
            assert tuple(msg.name) == stream.joint_names
            assert list(msg.position) == list(stream.joint_positions[i])
        else:
            assert msg.fluid_pressure == float(stream.pressure_values[i, 0]) + ATMOSPHERIC_PRESSURE
    return start


def _used_inputs(bag: list) -> dict[str, list[tuple[int, Inputs]]]:
    """Per output topic, in order: (stamp, the latest-inputs state when the node solved it)."""
    angle, length, gauge = math.nan, math.nan, math.nan
    used: dict[str, list[tuple[int, Inputs]]] = {t: [] for t in OUTPUT_TOPICS}
    for topic, _, msg in bag:
        if topic == JOINT_TOPIC:
            values = dict(zip(msg.name, msg.position))
            angle, length = values["lift_arm_angle"], values["lift_cylinder"]
        elif topic == PRESSURE_TOPIC:
            gauge = msg.fluid_pressure - ATMOSPHERIC_PRESSURE   # node parameter pressure_absolute = true
        elif topic.lstrip("/") in used:
            state = Inputs(cylinders={"lift_cylinder": length}, angles={"lift_arm_angle": angle},
                           pressures={"lift_cap_pressure": gauge})
            used[topic.lstrip("/")].append((stamp_ns(msg.header), state))
    return used


def _close(got: float, want: float) -> bool:
    return got == pytest.approx(want, rel=REL, abs=1e-9, nan_ok=True)


def _compare(topic: str, msg: Any, expected: Any, machine: Any, mech: Any) -> list[str]:
    """Field-by-field differences (as text) between an output message and the offline values."""
    pairs: list[tuple[str, float, float]] = []
    if topic == "hinge_reactions":
        assert [h.name for h in msg.hinges] == [h.name for h in mech.hinges]
        points = {h.name: h.point for h in mech.hinges}
        for h in msg.hinges:
            ref = expected.hinges[h.name]
            x, z = expected.points[points[h.name]]
            pairs += [(f"{h.name}.{k}", getattr(h, k), v)
                      for k, v in (("fx", ref.fx), ("fz", ref.fz), ("magnitude", ref.magnitude), ("x", x), ("z", z))]
        pairs.append(("equilibrium_residual", msg.equilibrium_residual, expected.residual))
    elif topic == "hitch_state":
        cyl = msg.cylinders[0]
        ref = expected.cylinders[cyl.name]
        pairs += [("implement_load", msg.implement_load, expected.implement_load),
                  ("implement_cg_x", msg.implement_cg_x, expected.implement_cg[0]),
                  ("implement_cg_z", msg.implement_cg_z, expected.implement_cg[1]),
                  ("hitch_axis_height", msg.hitch_axis_height, expected.points[mech.implement.hitch_point][1]),
                  ("cylinder.force", cyl.force, ref.force), ("cylinder.length", cyl.length, ref.length),
                  ("cap_pressure_measured", cyl.cap_pressure_measured, ref.cap_pressure_measured),
                  ("lift_capacity_hitch_axis", msg.lift_capacity_hitch_axis, machine.lift_capacity["hitch_axis"]),
                  ("lift_capacity_610mm", msg.lift_capacity_610mm, machine.lift_capacity["behind_610mm"]),
                  ("lift_capacity_implement_cg", msg.lift_capacity_implement_cg,
                   machine.lift_capacity["implement_cg"]),
                  ("lift_reserve", msg.lift_reserve, machine.lift_capacity["reserve"])]
    else:
        pairs += [(k, getattr(msg, k), v) for k, v in machine.steerability.items()]
    return [f"{name}: node {got!r} != offline {want!r}" for name, got, want in pairs if not _close(got, want)]


def test_lift_outputs_carry_simulated_stamps_and_equal_offline_solver(ros, tmp_path):
    noise = Noise(angle=NOISE_ANGLE, length=NOISE_LENGTH, pressure=NOISE_PRESSURE)   # the CLI's default noise
    client, bag = _run(tmp_path, "lift", noise, duration=None)
    mech = load_preset(PRESET)
    stream = simulate(mech, "lift", RATE, noise=noise, seed=0)
    _check_inputs_are_simulated(stream, bag)
    input_stamps = {stamp_ns(m.header) for t, _, m in bag if t in (JOINT_TOPIC, PRESSURE_TOPIC)}
    used = _used_inputs(bag)
    solver = Solver(mech, consistency_tol=ASSEMBLY_LIMIT_M)   # the node's setting: noisy redundant sensors
    machine = MachineModel(mech, solver)
    offline: dict[tuple, tuple] = {}
    for topic in OUTPUT_TOPICS:
        received = client.received[topic]
        # the node solves the first message only once both inputs are known: about one solve per input
        assert len(received) >= len(input_stamps), (topic, len(received), len(input_stamps))
        assert [stamp_ns(m.header) for m in received] == [s for s, _ in used[topic]], \
            f"{topic}: the client's messages are not the ones in the node's bag"
        for msg, (stamp, state) in zip(received, used[topic]):
            assert stamp in input_stamps
            key = (state.cylinders["lift_cylinder"], state.angles["lift_arm_angle"],
                   state.pressures["lift_cap_pressure"])
            if key not in offline:
                result = solver.solve(state)
                offline[key] = (result, machine.evaluate(result))
            errors = _compare(topic, msg, *offline[key], mech)
            assert not errors, f"{topic} at stamp {stamp}: " + "; ".join(errors)
    # the cycle was really driven through: the lift arm moved over the raise (Popov 2009: 3.5-3.8 s lift)
    heights = [m.hitch_axis_height for m in client.received["hitch_state"]]
    assert max(heights) - min(heights) > 0.2


def test_overload_first_margin_warning_at_first_negative_margin_sample(ros, tmp_path):
    noise = Noise()   # zero noise: the node sees the model values, so its margin crosses where the truth does
    duration = 8.0    # s; belarus_1221 crosses at t = 7.04 s (simulator docstring)
    client, bag = _run(tmp_path, "overload", noise, duration=duration)
    stream = simulate(load_preset(PRESET), "overload", RATE, duration_s=duration, noise=noise, seed=0)
    k = stream.truth.overload_index
    assert k is not None and stream.truth.steerability_margin[k - 1] >= 0.0 > stream.truth.steerability_margin[k]
    start = _check_inputs_are_simulated(stream, bag)
    crossing = start + k * PERIOD_NS
    received = {stamp_ns(m.header) for t, _, m in bag if t == PRESSURE_TOPIC}
    assert crossing in received, "the node did not receive the crossing sample's pressure (best effort drop)"
    warnings = [(stamp_ns(m.header), s.message) for m in client.received["diagnostics"] for s in m.status
                if s.level == b"\x01" and "steerability margin" in s.message]
    assert warnings, "no steerability WARN on /diagnostics"
    assert warnings[0][0] == crossing, (
        f"first steerability WARN at sample {(warnings[0][0] - start) / PERIOD_NS}, truth {k}: {warnings[0][1]}")
    # and the steerability output agrees: non-negative margin before the crossing, negative from it
    margins = [(stamp_ns(m.header), m.margin) for m in client.received["steerability"]]
    assert all(margin >= 0.0 for stamp, margin in margins if stamp < crossing)
    assert any(stamp == crossing and margin < 0.0 for stamp, margin in margins)
