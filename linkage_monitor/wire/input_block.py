"""A block of recorded input messages read at once: the replay's way in.

The messages (JointState, FluidPressure: their topics, type names, CDR bytes and receive times)
are read by type and size at once (``read.read_block``, by the shape of the message of that type
and size read before) into ``monitoring.input_columns.InputColumns``: runs of messages of one
form, the values ``sensor_messages.input_event`` reads from each (test_input_block.py holds the
two readings equal). A message that does not have the shape (another joint list, a text of
another length, damaged bytes, an XCDR2 payload), or a JointState of another form than the
run's, ends the run: it is read alone by ``input_event`` (and the shape it leaves serves the
next block). Units as in the messages: rad or m, rad/s or m/s, Pa; times ns.
"""

from __future__ import annotations

from typing import Sequence

import numpy as np

from linkage_monitor.monitoring.events import InputEvent
from linkage_monitor.monitoring.input_columns import InputColumns

from .cdr import CdrError, is_xcdr1
from .read import read_block, read_message
from .sensor_messages import FLUID_PRESSURE, JOINT_STATE, input_event


def input_items(topics: Sequence[str], type_names: Sequence[str], datas: Sequence[bytes],
                receive_ns: Sequence[int]) -> list[InputColumns | InputEvent]:
    """The input messages given (parallel sequences, in order) as runs of columns and single events,
    in their order: every message once."""
    n = len(datas)
    groups: dict[tuple[str, str, int], list[int]] = {}
    for i, (topic, type_name, data) in enumerate(zip(topics, type_names, datas)):
        groups.setdefault((topic, type_name, len(data)), []).append(i)
    form = np.full(n, -1, np.intp)     # per message: its group's number when it reads at once, else -1
    place = np.zeros(n, np.intp)       # its row in its group
    stamps = np.zeros(n, np.int64)
    read: list[dict] = []
    for (_, type_name, _), at in groups.items():
        values = _group(type_name, [datas[i] for i in at])
        if values is None:
            continue
        index = np.array(at, np.intp)
        form[index[values["fits"]]] = len(read)
        place[index] = np.arange(len(at))
        stamps[index] = values["header.stamp"]
        read.append(values)
    receive = np.array(receive_ns, np.int64)
    items: list[InputColumns | InputEvent] = []
    start, joint = 0, -1
    for i, g in enumerate(form.tolist()):
        if g < 0 or (type_names[i] == JOINT_STATE and joint not in (-1, g)):   # the run ends before it
            if i > start:
                items.append(_columns(topics, type_names, read, form, place, stamps, receive, start, i, joint))
            start, joint = i, -1
        if g < 0:
            items.append(input_event(type_names[i], datas[i], topics[i], int(receive_ns[i])))
            start = i + 1
        elif type_names[i] == JOINT_STATE:
            joint = g
    if n > start:
        items.append(_columns(topics, type_names, read, form, place, stamps, receive, start, n, joint))
    return items


def _group(type_name: str, datas: list[bytes]) -> dict | None:
    """The columns of messages of one type and size (with ``fits``), None when they are not read at
    once (no shape, or not a form the columns hold)."""
    if len(datas[0]) >= 4 and not is_xcdr1(datas[0]):
        return None   # XCDR2: read by rclpy, one by one
    block = read_block(type_name, datas)
    if block is None:
        try:
            read_message(type_name, datas[0])   # leaves its shape (little-endian CDR)
        except CdrError:
            return None
        block = read_block(type_name, datas)
        if block is None:
            return None
    values = block.values
    if type_name == JOINT_STATE:
        names = values["name"]
        positions, velocities = values["position"], values["velocity"]
        positions = positions if isinstance(positions, np.ndarray) else np.zeros((len(datas), len(positions)))
        if isinstance(velocities, np.ndarray):
            given = velocities
        elif len(velocities) == 0:
            given = None
        else:
            return None
        if positions.shape[1] != len(names) or (given is not None and given.shape[1] != len(names)):
            return None
        return {"fits": block.fits, "header.stamp": values["header.stamp"], "names": tuple(names),
                "positions": positions, "velocities": given}
    if type_name == FLUID_PRESSURE:
        return {"fits": block.fits, "header.stamp": values["header.stamp"], "pressure": values["fluid_pressure"]}
    return None


def _columns(topics: Sequence[str], type_names: Sequence[str], read: list[dict], form: np.ndarray,
             place: np.ndarray, stamps: np.ndarray, receive: np.ndarray, start: int, end: int,
             joint: int) -> InputColumns:
    """The messages start..end-1 (each read at once, the JointStates of group ``joint``) as columns."""
    span = range(start, end)
    joint_at = [i - start for i in span if type_names[i] == JOINT_STATE]
    pressure_at: dict[str, list[int]] = {}
    for i in span:
        if type_names[i] == FLUID_PRESSURE:
            pressure_at.setdefault(topics[i], []).append(i - start)
    columns = InputColumns(list(topics[start:end]), stamps[start:end], receive[start:end])
    if joint_at:
        rows = place[np.array(joint_at, np.intp) + start]
        values = read[joint]
        columns.joint_topic, columns.names = topics[joint_at[0] + start], values["names"]
        columns.joint_at, columns.positions = np.array(joint_at, np.intp), values["positions"][rows]
        columns.velocities = values["velocities"][rows] if values["velocities"] is not None else None
    for topic, at in pressure_at.items():
        index = np.array(at, np.intp) + start
        columns.pressure_at[topic] = index - start
        columns.pressures[topic] = np.array([read[int(form[i])]["pressure"][int(place[i])] for i in index.tolist()])
    return columns
