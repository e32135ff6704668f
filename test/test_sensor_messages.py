"""The input messages read from their CDR bytes (wire.sensor_messages) are what rclpy reads.

Oracle: rclpy's ``deserialize_message`` (Fast CDR through the C type support) of the same bytes.
Valid messages (hypothesis: any names, values incl. NaN/inf, sequences of differing lengths,
any stamp) are serialized by rclpy and must read back equal, floats bit for bit. Damaged
messages (cut short, a byte overwritten, bytes inserted) must fare the same in both readers:
both refuse, or both read the same values — our reader is no more lenient than the middleware
and refuses nothing it reads.
"""

from __future__ import annotations

import struct

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from rclpy.serialization import deserialize_message, serialize_message
from sensor_msgs.msg import FluidPressure, Imu, JointState

from linkage_monitor.wire.cdr import CdrError
from linkage_monitor.wire.sensor_messages import read_fluid_pressure, read_imu, read_joint_state

texts = st.text(max_size=12)
floats = st.floats(allow_nan=True, allow_infinity=True)
stamps = st.tuples(st.integers(-2**31, 2**31 - 1), st.integers(0, 2**32 - 1))


def _bits(values: object) -> list[bytes]:
    return [struct.pack("<d", v) for v in values]  # type: ignore[attr-defined]


def _joint_state(frame: str, stamp: tuple[int, int], names: list[str], position: list[float],
                 velocity: list[float], effort: list[float]) -> bytes:
    msg = JointState(name=names, position=position, velocity=velocity, effort=effort)
    msg.header.frame_id, (msg.header.stamp.sec, msg.header.stamp.nanosec) = frame, stamp
    return serialize_message(msg)


def _fluid_pressure(frame: str, stamp: tuple[int, int], pressure: float, variance: float) -> bytes:
    msg = FluidPressure(fluid_pressure=pressure, variance=variance)
    msg.header.frame_id, (msg.header.stamp.sec, msg.header.stamp.nanosec) = frame, stamp
    return serialize_message(msg)


def _rclpy_joint_state(data: bytes) -> tuple | None:
    try:
        m = deserialize_message(data, JointState)
    except Exception:  # noqa: BLE001 - rclpy raises RMWError (or others) for bytes it cannot read
        return None
    return (m.header.stamp.sec * 1_000_000_000 + m.header.stamp.nanosec, list(m.name), _bits(m.position),
            _bits(m.velocity))


def _ours_joint_state(data: bytes) -> tuple | None:
    try:
        r = read_joint_state(data, "/joint_states", 0)
    except CdrError:
        return None
    return r.stamp_ns, r.names, _bits(r.positions), _bits(r.velocities)


def _rclpy_fluid_pressure(data: bytes) -> tuple | None:
    try:
        m = deserialize_message(data, FluidPressure)
    except Exception:  # noqa: BLE001
        return None
    return m.header.stamp.sec * 1_000_000_000 + m.header.stamp.nanosec, _bits([m.fluid_pressure])


def _ours_fluid_pressure(data: bytes) -> tuple | None:
    try:
        r = read_fluid_pressure(data, "/pressure", 0)
    except CdrError:
        return None
    return r.stamp_ns, _bits([r.fluid_pressure])


def _imu(frame: str, stamp: tuple[int, int], values: list[float]) -> bytes:
    msg = Imu()
    msg.header.frame_id, (msg.header.stamp.sec, msg.header.stamp.nanosec) = frame, stamp
    q, w, a = msg.orientation, msg.angular_velocity, msg.linear_acceleration
    q.x, q.y, q.z, q.w, w.x, w.y, w.z, a.x, a.y, a.z = values[:10]
    msg.orientation_covariance[:] = values[10:19]
    msg.angular_velocity_covariance[:] = values[19:28]
    msg.linear_acceleration_covariance[:] = values[28:37]
    return serialize_message(msg)


def _rclpy_imu(data: bytes) -> tuple | None:
    try:
        m = deserialize_message(data, Imu)
    except Exception:  # noqa: BLE001
        return None
    return (m.header.stamp.sec * 1_000_000_000 + m.header.stamp.nanosec, m.header.frame_id,
            _bits([m.linear_acceleration.z, m.angular_velocity.y]))


def _ours_imu(data: bytes) -> tuple | None:
    try:
        r = read_imu(data, "/imu", 0)
    except CdrError:
        return None
    return r.stamp_ns, r.frame_id, _bits([r.specific_force_z, r.rate_y])


joint_states = st.builds(_joint_state, texts, stamps, st.lists(texts, max_size=5), st.lists(floats, max_size=5),
                         st.lists(floats, max_size=5), st.lists(floats, max_size=3))
fluid_pressures = st.builds(_fluid_pressure, texts, stamps, floats, floats)
imus = st.builds(_imu, texts, stamps, st.lists(floats, min_size=37, max_size=37))


# The check of the FluidPressure test below, for JointState: one test per type, each with its own strategy.
@settings(max_examples=400, deadline=None)
@given(joint_states)
def test_a_joint_state_reads_as_rclpy_reads_it(data):
    expected = _rclpy_joint_state(data)
    assert expected is not None
    assert _ours_joint_state(data) == expected


# The check of the JointState test above, for FluidPressure: one test per type, each with its own strategy.
@settings(max_examples=200, deadline=None)
@given(fluid_pressures)
def test_a_fluid_pressure_reads_as_rclpy_reads_it(data):
    expected = _rclpy_fluid_pressure(data)
    assert expected is not None
    assert _ours_fluid_pressure(data) == expected


# The check of the FluidPressure test above, for Imu (the fields the monitor keeps; its fixed arrays read past).
@settings(max_examples=200, deadline=None)
@given(imus)
def test_an_imu_reads_as_rclpy_reads_it(data):
    expected = _rclpy_imu(data)
    assert expected is not None
    assert _ours_imu(data) == expected


def _damaged(data: bytes, kind: int, at: int, value: int, extra: bytes) -> bytes:
    at %= len(data) + 1
    if kind == 0:
        return data[:at]                                            # cut short
    if kind == 1 and at < len(data):
        return data[:at] + bytes([value]) + data[at + 1:]            # one byte overwritten
    if kind == 2 and at + 4 <= len(data):
        return data[:at] + struct.pack("<I", value * 0x01010101 if value % 3 else value) + data[at + 4:]  # a word
    return data[:at] + extra + data[at:]                            # bytes inserted


damage = st.tuples(st.integers(0, 3), st.integers(0, 400), st.integers(0, 255), st.binary(min_size=1, max_size=9))


@pytest.mark.slow
@settings(max_examples=1500, deadline=None)
@given(joint_states, damage)
def test_a_damaged_joint_state_fares_as_in_rclpy(data, how):
    bad = _damaged(data, *how)
    assert _ours_joint_state(bad) == _rclpy_joint_state(bad)


@settings(max_examples=600, deadline=None)
@given(fluid_pressures, damage)
def test_a_damaged_fluid_pressure_fares_as_in_rclpy(data, how):
    bad = _damaged(data, *how)
    assert _ours_fluid_pressure(bad) == _rclpy_fluid_pressure(bad)


@settings(max_examples=600, deadline=None)
@given(imus, damage)
def test_a_damaged_imu_fares_as_in_rclpy(data, how):
    bad = _damaged(data, *how)
    assert _ours_imu(bad) == _rclpy_imu(bad)


@pytest.mark.parametrize("data, words", [
    (b"", "0-byte message: shorter than the 4-byte CDR header"),
    (b"\x00\x0c\x00\x00" + bytes(40), "encapsulation 000c"),
    (_joint_state("base", (1, 2), ["lift_cylinder"], [0.6], [], [])[:30], "name: 1 strings cannot fit in the 30-byte message"),
    (_joint_state("base", (1, 2), ["lift_cylinder"], [0.6], [], [])[:44], "name\\[0\\] at byte 32 runs past the end of the 44-byte message"),
])
def test_a_refusal_says_what_is_wrong(data, words):
    with pytest.raises(CdrError, match=words):
        read_joint_state(data, "/joint_states", 0)


def _joint_state_padded(frame: str, names: list[str], fill: int) -> bytes:
    """A JointState's CDR (wire.compose) with every byte of alignment padding ``fill``, as a writer that
    leaves its padding uninitialised may send it: one position per name, no velocities or efforts."""
    from linkage_monitor.wire.compose import Composer
    from linkage_monitor.wire.sensor_messages import JOINT_STATE

    composer = Composer().message(JOINT_STATE, {"header": {"stamp": {"sec": 1, "nanosec": 2}, "frame_id": frame},
                                                "name": names, "position": [0.5] * len(names)})
    data = bytearray(composer.data)
    for start, end in composer.writer.padding:
        data[start:end] = bytes([fill]) * (end - start)
    return bytes(data)


@settings(max_examples=400, deadline=None)
@given(st.lists(texts, max_size=5), texts, texts, st.integers(0, 255), st.integers(0, 255), damage)
def test_joint_names_read_after_the_same_names_read_as_rclpy_reads_them(names, frame, other_frame, fill, other_fill,
                                                                       how):
    """A JointState whose names (their bytes) are those of the JointState read before, at another offset (another
    frame_id), other bytes in the padding, whole or damaged: read as rclpy reads it."""
    first = _joint_state_padded(frame, names, fill)
    assert _ours_joint_state(first) == _rclpy_joint_state(first) is not None
    second = _joint_state_padded(other_frame, names, other_fill)
    assert _ours_joint_state(second) == _rclpy_joint_state(second) is not None
    assert _ours_joint_state(first) == _rclpy_joint_state(first)
    bad = _damaged(second, *how)
    assert _ours_joint_state(bad) == _rclpy_joint_state(bad)


@settings(max_examples=300, deadline=None)
@given(texts, st.lists(texts, min_size=1, max_size=4), st.data())
def test_messages_of_one_shape_read_one_after_another_as_rclpy_reads_them(frame, names, data):
    """JointStates and FluidPressures of one frame_id, joint names and sequence lengths, whose numbers
    differ (the later ones read by the shape the first left, ``wire.read.Shape``), and copies with
    one byte overwritten or a word replaced (the same size, another shape where the byte is not a
    number): each read as rclpy reads it."""
    n, m = len(names), data.draw(st.integers(0, 3))
    for _ in range(4):
        joints = _joint_state(frame, data.draw(stamps), names, data.draw(st.lists(floats, min_size=n, max_size=n)),
                              data.draw(st.lists(floats, min_size=n, max_size=n)), [1.0] * m)
        pressure = _fluid_pressure(frame, data.draw(stamps), data.draw(floats), data.draw(floats))
        for message, ours, theirs in ((joints, _ours_joint_state, _rclpy_joint_state),
                                      (pressure, _ours_fluid_pressure, _rclpy_fluid_pressure)):
            assert ours(message) == theirs(message) is not None
            kind, at, value = data.draw(st.integers(1, 2)), data.draw(st.integers(0, 400)), data.draw(st.integers(0, 255))
            bad = _damaged(message, kind, at, value, b"")
            assert ours(bad) == theirs(bad)


def test_a_refusal_is_the_same_after_the_names_were_read_whole():
    """A JointState cut in its names is refused as when it is the first read, after the whole of it was read."""
    whole = _joint_state("base", (1, 2), ["lift_cylinder", "top_link"], [0.6, 0.1], [], [])
    refusals = []
    for _ in range(2):
        with pytest.raises(CdrError) as refused:
            read_joint_state(whole[:56], "/joint_states", 0)
        refusals.append(str(refused.value))
        assert read_joint_state(whole, "/joint_states", 0).names == ["lift_cylinder", "top_link"]
    assert refusals[0] == refusals[1] and "name[1]" in refusals[0], refusals


def test_every_joint_state_of_the_bundled_bag_reads_as_rclpy_reads_it():
    """The bundled bag's JointStates (one after the other, the same names every time, the recording
    node's padding bytes) read as rclpy reads them."""
    from pathlib import Path

    from linkage_monitor.bag.reader import read_bag_raw

    bag = Path(__file__).resolve().parents[1] / "bags" / "belarus_1221_lift_transport"
    recorded = [raw.data for raw in read_bag_raw(bag, topics=["/joint_states"])]
    assert len(recorded) > 1000
    assert [_ours_joint_state(data) for data in recorded] == [_rclpy_joint_state(data) for data in recorded]
