"""The wire layer's bytes are rclpy's: every message the node publishes and the recorder writes,
written by its layout parsed from the `.msg` definitions (linkage_monitor.wire), equals
``rclpy.serialization.serialize_message`` of the same message built with the generated Python
classes — on random values (hypothesis), and for the templated fast paths (outputs, markers) on
every preset's simulated lift.

How bytes are compared: rclpy's buffer is cut to the message's exact length (rosbags' decoder,
wire.definitions.exact_cdr) and must equal ours byte for byte, except the alignment padding
bytes, which rclpy leaves uninitialised (ours are zero). Where the padding is comes from our
writer; a layout that differs from rclpy's shifts the data bytes after it, which then differ.
"""

from __future__ import annotations

import importlib
import math
import struct
from typing import Any

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from rclpy.serialization import deserialize_message

from linkage_monitor.can.frame_msg import FRAME_TYPE, to_cdr
from linkage_monitor.can.frames import Frame
from linkage_monitor.mechanics import load_preset, preset_names
from linkage_monitor.monitoring.config import MonitorConfig
from linkage_monitor.monitoring.core import Monitor
from linkage_monitor.sim.telemetry import simulate
from linkage_monitor.wire.compose import STAMP, Column, Composer, Flag, encode
from linkage_monitor.wire.diagnostics import DIAGNOSTIC_ARRAY, diagnostic_array
from linkage_monitor.wire.layout import PRIMITIVES, Field, LayoutError, layout
from linkage_monitor.wire.markers import MARKER_ARRAY, LinkageMarkers
from linkage_monitor.wire.outputs import HINGE_REACTIONS, HITCH_STATE, STEERABILITY, OutputEncoder
from linkage_monitor.wire.sensor_messages import FLUID_PRESSURE, JOINT_STATE
from linkage_monitor.wire.template import Template
from oracles.markers import LinkageMarkers as OracleMarkers
from oracles.output_messages import outputs as oracle_outputs
from support.rclpy_bytes import assert_rclpy_bytes

# every message type the node publishes or the recorder writes (ros/node.py publishers, the replay's writes,
# the CAN bridge's raw frames)
WRITTEN = (HINGE_REACTIONS, HITCH_STATE, STEERABILITY, DIAGNOSTIC_ARRAY, MARKER_ARRAY, JOINT_STATE, FLUID_PRESSURE,
           "std_msgs/msg/String", FRAME_TYPE)
_TEXT = st.text(st.characters(blacklist_categories=("Cs",), blacklist_characters="\x00"), max_size=12)
_INTS = {"int8": 8, "int16": 16, "int32": 32, "int64": 64}


def _primitive(kind: str) -> st.SearchStrategy:
    if kind == "string":
        return _TEXT
    if kind == "bool":
        return st.booleans()
    if kind.startswith("float"):
        return st.floats(width=int(kind[5:]))
    if kind in _INTS:
        bits = _INTS[kind]
        return st.integers(-2**(bits - 1), 2**(bits - 1) - 1)
    return st.integers(0, 2**(8 * PRIMITIVES[kind][1]) - 1)


def _values(type_name: str, depth: int = 0) -> st.SearchStrategy:
    """Random values (field name -> value) of a ``type_name`` message, from its layout."""
    return st.fixed_dictionaries({f.name: _field(f, depth) for f in layout(type_name).fields})


def _field(f: Field, depth: int) -> st.SearchStrategy:
    one = _values(f.kind, depth + 1) if f.nested else _primitive(f.kind)
    if f.array is None:
        return one
    if f.array:
        return st.lists(one, min_size=f.array, max_size=f.array)
    return st.lists(one, max_size=3 if depth < 2 else 1)


def _message(type_name: str, values: Any) -> Any:
    """The rclpy message of ``values`` built with the generated class, field by field."""
    package, _, name = type_name.split("/")
    msg = getattr(importlib.import_module(f"{package}.msg"), name)()
    for f in layout(type_name).fields:
        value = values[f.name]
        if f.nested:
            value = [_message(f.kind, v) for v in value] if f.array is not None else _message(f.kind, value)
        elif f.kind == "byte":
            value = [bytes([v]) for v in value] if f.array is not None else bytes([value])
        setattr(msg, f.name, value)
    return msg


@pytest.mark.parametrize("type_name", WRITTEN)
def test_every_written_message_is_rclpys_on_random_values(type_name):
    """Random values of each written message type: our bytes are rclpy's (NaN, inf, any text)."""
    @settings(max_examples=60, deadline=None)
    @given(_values(type_name))
    def check(values):
        assert_rclpy_bytes(type_name, encode(type_name, values, strict=True), _message(type_name, values))
    check()


def test_a_field_without_a_value_is_its_definition_default():
    """Fields left out take the `.msg` defaults, as the generated classes do (geometry_msgs/Quaternion
    w = 1 in its definition), and strict composing names the missing field."""
    from visualization_msgs.msg import Marker, MarkerArray

    data = encode(MARKER_ARRAY, {"markers": [{"text": "abc"}, {}]})
    assert_rclpy_bytes(MARKER_ARRAY, data, MarkerArray(markers=[Marker(text="abc"), Marker()]))
    assert deserialize_message(data, MarkerArray).markers[0].pose.orientation.w == 1.0
    with pytest.raises(LayoutError, match="HitchState.cylinders"):
        encode(HITCH_STATE, {"header": {"stamp": 0, "frame_id": ""}}, strict=True)
    with pytest.raises(LayoutError, match="no field"):
        encode(STEERABILITY, {"not_a_field": 1.0})


@settings(max_examples=200, deadline=None)
@given(st.integers(-2**31 * 10**9, 2**31 * 10**9 - 1), st.integers(0, 2**32 - 1), st.booleans(), st.booleans(),
       st.booleans(), st.integers(0, 8), st.binary(max_size=8), _TEXT)
def test_the_can_bridge_frames_are_their_layouts(stamp, ident, extended, remote, error, dlc, data, frame_id):
    """can/frame_msg.to_cdr (a struct per can_msgs/Frame) writes the bytes of the message's layout."""
    frame = Frame(stamp, ident, extended, remote, error, dlc, data)
    assert to_cdr(frame, frame_id) == encode(FRAME_TYPE, {
        "header": {"stamp": stamp, "frame_id": frame_id}, "id": ident, "is_rtr": remote, "is_extended": extended,
        "is_error": error, "dlc": dlc, "data": (data + bytes(8))[:8]}, strict=True)


@settings(max_examples=100, deadline=None)
@given(st.integers(1, 6).flatmap(lambda n: st.tuples(
    st.lists(st.lists(st.floats(width=64), min_size=3, max_size=3), min_size=n, max_size=n),
    st.lists(st.integers(-2**31 * 10**9, 2**31 * 10**9 - 1), min_size=n, max_size=n),
    st.lists(st.integers(0, 255), min_size=n, max_size=n))))
def test_rows_filled_at_once_as_one_by_one(rows):
    """``Template.fill_rows`` (N messages) gives each row ``Template.fill`` of it: stamps before
    1970 and to the end of int32 seconds, any floats (NaN, inf), any flag bytes; a stamp beyond
    int32 seconds is refused by both."""
    values, stamps, flags = rows
    template = Template.of(Composer(strict=True).message(STEERABILITY, {
        "header": {"stamp": STAMP, "frame_id": "odd length"}, "reference": Flag(0),
        **{f.name: Column(k % 3) for k, f in enumerate(layout(STEERABILITY).fields) if f.kind == "float64"}}))
    assert len(template.slots) == len(layout(STEERABILITY).fields) - 2   # all but header and reference
    source = np.array(values)
    filled = template.fill_rows(np.array(stamps, dtype=np.int64), source[:, template.columns],
                                np.array(flags, np.uint8)[:, None])
    assert [row.tobytes() for row in filled] == [bytes(template.fill(t, v[template.columns], (f,)))
                                                for t, v, f in zip(stamps, source, flags)]
    for beyond in (2**31 * 10**9, -2**31 * 10**9 - 1):
        with pytest.raises(struct.error):
            template.fill(beyond, source[0, template.columns])
        with pytest.raises(struct.error):
            template.fill_rows(np.array([*stamps, beyond], dtype=np.int64), np.vstack([source, source[:1]])[:, template.columns])


@settings(max_examples=200, deadline=None)
@given(st.lists(st.floats(width=64), min_size=1, max_size=9), st.integers(0, 2**31 - 1),
       st.integers(0, 999_999_999), _TEXT, st.integers(0, 255))
def test_template_and_its_tail_are_rclpys(values, sec, nanosec, text, flag):
    """A HitchState template (every float64 field a Column, from the layout), filled with any floats,
    stamps and flag bytes, its status text written after it, is rclpy's message of those values."""
    fields = layout(HITCH_STATE).fields
    columns = iter(range(1000))

    def placeholders(type_name: str, skip: str) -> dict[str, Any]:
        return {f.name: Column(next(columns)) if f.kind == "float64" else Flag(0) if f.name == "status" else True
                for f in layout(type_name).fields
                if f.name != skip and not f.nested and f.kind != "string"}

    cylinders = [{"name": f"cyl{'x' * k}", **placeholders("linkage_monitor/msg/CylinderState", "")}
                 for k in range(len(values))]
    base = Template.of(Composer(strict=True).message(HITCH_STATE, {
        "header": {"stamp": STAMP, "frame_id": "base_footprint"}, "cylinders": cylinders,
        **placeholders(HITCH_STATE, "status_text")}, stop="status_text"))
    template = base.extended(lambda c: c.message(HITCH_STATE, {"status_text": text}, start="status_text"))
    numbers = [values[k % len(values)] for k in range(len(template.slots))]
    data = bytes(template.fill(sec * 1_000_000_000 + nanosec, np.array(numbers), (flag,)))
    msg = deserialize_message(data, _message_class(HITCH_STATE))
    assert (msg.header.stamp.sec, msg.header.stamp.nanosec, msg.status, msg.status_text) == (sec, nanosec, flag, text)
    assert msg.implement_load_estimated is True
    got = [getattr(c, f.name) for c in msg.cylinders for f in layout("linkage_monitor/msg/CylinderState").fields
           if f.kind == "float64"]
    got += [getattr(msg, f.name) for f in fields if f.kind == "float64"]
    assert struct.pack(f"<{len(got)}d", *got) == struct.pack(f"<{len(numbers)}d", *numbers)
    assert_rclpy_bytes(HITCH_STATE, data, msg)


def _message_class(type_name: str) -> type:
    package, _, name = type_name.split("/")
    return getattr(importlib.import_module(f"{package}.msg"), name)


def _lift_steps(preset: str) -> tuple[Monitor, list]:
    mech = load_preset(preset)
    stream = simulate(mech, "lift", rate_hz=20.0, start_ns=1_700_000_000_000_000_000)
    topics = {f"/pressure/{name}": name for name in stream.pressure_names}
    monitor = Monitor(mech, MonitorConfig(mechanism=mech.name, pressure_topics=topics, pressure_absolute=False,
                                          staleness_limit_s=3600.0, stamp_tolerance_s=1e9))
    steps = []
    for i, stamp in enumerate(stream.stamps_ns.tolist()[:40]):
        for topic, name in topics.items():
            monitor.on_pressure(topic, float(stream.pressure_values[i, stream.pressure_names.index(name)]), stamp, stamp)
        steps.append(monitor.on_joint_state(list(stream.joint_names), stream.joint_positions[i].tolist(), [], stamp,
                                            stamp))
    return monitor, steps


def _simulated(name: str) -> bool:
    """Whether the simulator drives ``name``'s lift (an implement, the pose fixed by the cylinder lengths)."""
    try:
        simulate(load_preset(name), "lift", rate_hz=1.0)
    except ValueError:
        return False
    return True


SIMULATED = [n for n in preset_names() if _simulated(n)]


@pytest.mark.parametrize("preset", SIMULATED)
def test_outputs_markers_and_diagnostics_are_rclpys(preset):
    """Each preset's simulated lift: the three outputs (OutputEncoder, templates), the MarkerArray
    (LinkageMarkers, spliced labels) and the DiagnosticArray are rclpy's serialization of the
    oracles' messages (test/oracles: built field by field with the generated classes)."""
    monitor, steps = _lift_steps(preset)
    encoder, markers, oracle_markers = OutputEncoder(), LinkageMarkers(monitor.mechanism), OracleMarkers(monitor.mechanism)
    solved = 0
    for step in steps:
        ours, theirs = encoder.outputs(monitor, step), oracle_outputs(monitor, step)
        assert (ours is None) == (theirs is None)
        data = diagnostic_array(step, "linkage_monitor", monitor.mechanism.name, 0)
        assert_rclpy_bytes(DIAGNOSTIC_ARRAY, data, deserialize_message(data, _message_class(DIAGNOSTIC_ARRAY)))
        if ours is None:
            continue
        solved += 1
        for type_name, name in ((HINGE_REACTIONS, "hinge_reactions"), (HITCH_STATE, "hitch_state"),
                                (STEERABILITY, "steerability")):
            assert_rclpy_bytes(type_name, getattr(ours, name), getattr(theirs, name))
        assert_rclpy_bytes(MARKER_ARRAY, markers.markers(step.stamp_ns, step.pose.result),
                           oracle_markers.markers(step.stamp_ns, step.pose.result))
    assert solved, "no step of the lift solved: nothing compared"
    assert not math.isnan(markers.force_scale or math.nan)
