"""Input events taken at once give what they give one by one.

- ``Monitor.run`` / ``runs`` (the batched path: runs of events of one form accepted at once by
  ``InputTracker.accept_run``, the others one by one) against ``Monitor.step`` one event at a
  time, on a simulated lift with hostile events put in (stamps out of order, too far, ≤ 0, gaps
  past the staleness limit, NaN, readings outside their limits or a turn off, unknown and
  duplicate joint names, arrays of other lengths, unmapped topics, unreadable bytes, JointStates
  of another form): the same Step for every event (stamp, trigger, findings' codes and sentences,
  the inputs solved), the same readings at the end; also with the events handed in as
  ``InputColumns`` cut into pieces of a few Steps.
- ``wire.input_block.input_items`` (a block of recorded messages read at once) against
  ``input_event`` of each message, on generated and damaged CDR bytes: the same events.
No ROS node: the core and the wire layer (rclpy only serializes the generated messages).
"""

from __future__ import annotations

import math
import struct

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st
from rclpy.serialization import serialize_message
from sensor_msgs.msg import FluidPressure, JointState

from linkage_monitor.mechanics import load_preset
from linkage_monitor.monitoring.config import MonitorConfig
from linkage_monitor.monitoring.core import Monitor
from linkage_monitor.monitoring.events import (ConfigEvent, JointStateEvent, PressureEvent, UnreadableEvent)
from linkage_monitor.monitoring.input_columns import InputColumns
from linkage_monitor.sim.telemetry import Noise, simulate
from linkage_monitor.wire.input_block import input_items
from linkage_monitor.wire.sensor_messages import FLUID_PRESSURE, JOINT_STATE, input_event
from support.monitor_steps import step_by_step

PRESSURE_TOPIC = "/pressure/lift_cap_pressure"
NS = 1_000_000_000
SAMPLES = 48   # of the simulated lift: 96 input events
HOSTILE = ("late", "gap", "nan", "nan_rate", "outside", "turn", "unknown", "twice", "short", "zero", "far",
           "unmapped", "unreadable", "negative", "subset", "rates", "config")


def _stream() -> tuple:
    mech = load_preset("belarus_1221")
    stream = simulate(mech, "lift", rate_hz=20.0, noise=Noise(0.001, 0.0002, 2e4), seed=5,
                      start_ns=1_700_000_000_000_000_000)
    config = MonitorConfig(mechanism=mech.name, pressure_topics={PRESSURE_TOPIC: "lift_cap_pressure"},
                           pressure_absolute=False)
    return mech, config, stream


MECH, CONFIG, STREAM = _stream()


def _events(hostile: list[tuple[int, str]]) -> list:
    """The stream's events (a pressure, then a JointState per sample), each sample listed in
    ``hostile`` changed as its kind says (several kinds on one sample apply in turn)."""
    names = list(STREAM.joint_names)
    kinds: dict[int, list[str]] = {}
    for at, kind in hostile:
        kinds.setdefault(at % SAMPLES, []).append(kind)
    events: list = []
    shift = 0
    for i, stamp in enumerate(STREAM.stamps_ns[:SAMPLES].tolist()):
        positions, rates, joint_names = STREAM.joint_positions[i].tolist(), [], list(names)
        pressure, topic, receive = float(STREAM.pressure_values[i, 0]), PRESSURE_TOPIC, None
        for kind in kinds.get(i, []):
            if kind == "late":
                shift -= NS // 10
            elif kind == "gap":
                shift += NS
            elif kind == "nan" and positions:
                positions[0] = math.nan
            elif kind == "nan_rate" and positions:
                rates = [0.0] * len(positions)
                rates[-1] = math.nan
            elif kind == "outside" and names.index("lift_cylinder") < len(positions):
                positions[names.index("lift_cylinder")] = 10.0
            elif kind == "turn" and names.index("lift_arm_angle") < len(positions):
                positions[names.index("lift_arm_angle")] += 2.0 * math.pi
            elif kind == "unknown":
                joint_names, positions = joint_names + ["hitch_pin"], positions + [0.1]
            elif kind == "twice":
                joint_names, positions = joint_names + joint_names[:1], positions + positions[:1]
            elif kind == "short":
                positions = positions[:-1]
            elif kind == "zero":
                shift = -stamp
            elif kind == "far":
                receive = stamp + shift + 20 * NS
            elif kind == "unmapped":
                topic = "/pressure/elsewhere"
            elif kind == "negative":
                pressure = -2e5
            elif kind == "subset":
                joint_names, positions = joint_names[:1], positions[:1]
            elif kind == "rates":
                rates = [0.01] * len(positions)
            elif kind == "config":
                events.append(ConfigEvent(CONFIG.with_overrides({"tractor.mass": 4000.0 + i})))
        at = stamp + shift
        events.append(PressureEvent(topic, pressure, at, at if receive is None else receive))
        if "unreadable" in kinds.get(i, []):
            events.append(UnreadableEvent("joint_states", JOINT_STATE, 7, "cut short", at))
        else:
            events.append(JointStateEvent("joint_states", joint_names, positions, rates, at,
                                          at if receive is None else receive))
        if kinds.get(i, []) and "zero" in kinds[i]:
            shift = 0
    return events


def _same_steps(stepped: list, batched: list) -> None:
    assert len(stepped) == len(batched)
    for one, other in zip(stepped, batched):
        assert (one.stamp_ns, one.trigger) == (other.stamp_ns, other.trigger)
        assert [(f.code, f.text) for f in one.findings] == [(f.code, f.text) for f in other.findings]
        assert one.inputs == other.inputs
        assert (one.pose is None) == (other.pose is None)


def _as_columns(events: list, size: int) -> list:
    """``events`` with every stretch of ``size`` input events of one form handed in as ``InputColumns``."""
    items: list = []
    i = 0
    while i < len(events):
        columns = None if isinstance(events[i], ConfigEvent) else InputColumns.of_events(events[i:i + size])
        if columns is None:
            items.append(events[i])
            i += 1
        else:
            columns.events = None   # as the replay's: every event given back from the columns
            items.append(columns)
            i += columns.size
    return items


@settings(max_examples=30, deadline=None)
@given(st.lists(st.tuples(st.integers(0, 10_000), st.sampled_from(HOSTILE)), max_size=12),
       st.integers(1, 9), st.integers(2, 40))
def test_events_accepted_at_once_give_the_steps_they_give_one_by_one(hostile, piece, size):
    events = _events(hostile)
    stepped = step_by_step(MECH, CONFIG, events)
    monitor = Monitor(MECH, CONFIG)
    _same_steps(stepped, monitor.run(events).steps)
    live = Monitor(MECH, CONFIG)
    for event in events:
        live.reconfigure(event.config) if isinstance(event, ConfigEvent) else live.step(event)
    assert repr(monitor.tracker.readings) == repr(live.tracker.readings)   # NaN rates alike
    assert monitor.tracker.unknown_joints == live.tracker.unknown_joints
    pieces = Monitor(MECH, CONFIG).runs(_as_columns(events, size), piece_steps=piece)
    _same_steps(stepped, [s for p in pieces for s in p.steps])


def test_a_clean_stream_is_accepted_at_once() -> None:
    """The stream without hostile events goes through ``accept_run`` (one call per window, not per event)."""
    events = _events([])
    monitor = Monitor(MECH, CONFIG)
    calls = []
    accept_run = monitor.tracker.accept_run
    monitor.tracker.accept_run = lambda run: calls.append(run.size) or accept_run(run)   # type: ignore[method-assign]
    steps = monitor.run(events).steps
    assert sum(s.pose is not None for s in steps) > 0.9 * len(events)
    assert len(calls) < len(events) / 20


# ---- recorded bytes read at once ----------------------------------------------------------------
def _joint_state(frame: str, stamp: int, names: list[str], position: list[float], velocity: list[float]) -> bytes:
    msg = JointState(name=names, position=position, velocity=velocity)
    msg.header.frame_id, msg.header.stamp.sec, msg.header.stamp.nanosec = frame, stamp // NS, stamp % NS
    return serialize_message(msg)


def _fluid_pressure(frame: str, stamp: int, pressure: float) -> bytes:
    msg = FluidPressure(fluid_pressure=pressure, variance=0.0)
    msg.header.frame_id, msg.header.stamp.sec, msg.header.stamp.nanosec = frame, stamp // NS, stamp % NS
    return serialize_message(msg)


def _bits(values) -> list[bytes]:
    return [struct.pack("<d", v) for v in values]


def _key(event) -> tuple:
    """What an event says, floats by their bits (NaN payloads too)."""
    if isinstance(event, JointStateEvent):
        return ("joint", event.topic, list(event.names), _bits(event.positions), _bits(event.velocities),
                event.stamp_ns, event.receive_ns)
    if isinstance(event, PressureEvent):
        return ("pressure", event.topic, _bits([event.fluid_pressure]), event.stamp_ns, event.receive_ns)
    return ("unreadable", event.topic, event.type_name, event.size, event.reason, event.receive_ns)


values = st.floats(allow_nan=True, allow_infinity=True)
message = st.one_of(
    st.tuples(st.just("joint"), st.sampled_from(["", "base_link"]), st.sampled_from([["a", "b"], ["a", "b", "c"]]),
              st.lists(values, min_size=3, max_size=3), st.booleans(), st.integers(0, 3), st.binary(max_size=2)),
    st.tuples(st.just("pressure"), st.sampled_from(["", "p"]), values, st.sampled_from(["/p1", "/p2"]),
              st.integers(0, 3), st.binary(max_size=2)))


@settings(max_examples=200, deadline=None)
@given(st.lists(st.tuples(message, st.integers(0, 2**40)), max_size=40))
def test_a_block_of_messages_reads_as_each_message_alone(messages):
    topics, types, datas, receive = [], [], [], []
    for k, (m, stamp) in enumerate(messages):
        if m[0] == "joint":
            _, frame, names, position, given_rates, damage, extra = m
            data = _joint_state(frame, stamp, names, position[:len(names)], position[:len(names)] if given_rates else [])
            topic, type_name = "/joint_states", JOINT_STATE
        else:
            _, frame, pressure, topic, damage, extra = m
            data, type_name = _fluid_pressure(frame, stamp, pressure), FLUID_PRESSURE
        if damage == 1:
            data = data[:len(data) - 3]   # cut short
        elif damage == 2:
            data = data + extra           # bytes after it
        topics.append(topic)
        types.append(type_name)
        datas.append(data)
        receive.append(stamp + k)
    items = input_items(topics, types, datas, receive)
    alone = [input_event(t, d, topic, r) for topic, t, d, r in zip(topics, types, datas, receive)]
    expanded = []
    for item in items:
        expanded += [item.event(i) for i in range(item.size)] if isinstance(item, InputColumns) else [item]
    assert [_key(e) for e in expanded] == [_key(e) for e in alone]


def test_messages_of_one_form_are_read_as_one_run_of_columns() -> None:
    stamps = [1_700_000_000 * NS + k * NS // 50 for k in range(60)]
    datas = [_joint_state("base_link", s, ["a", "b"], [0.1 * k, 0.2], []) if k % 2 else _fluid_pressure("", s, 1e5 + k)
             for k, s in enumerate(stamps)]
    types = [FLUID_PRESSURE if k % 2 == 0 else JOINT_STATE for k in range(60)]
    topics = ["/p1" if k % 2 == 0 else "/joint_states" for k in range(60)]
    items = input_items(topics, types, datas, stamps)
    assert len(items) == 1 and items[0].size == 60 and items[0].names == ("a", "b")
