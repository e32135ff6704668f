"""Fit the mapping's position tables from a recorded lift whose true values are known.

The log gives each table's signal (e.g. the ISOBUS rear hitch position, %) frame by frame; the
truth gives the measurement it stands for (sensor_msgs/JointState in a rosbag2 bag: a temporary
angle sensor during the calibration lift, or the simulator's ground truth). Each frame is paired
with the truth interpolated linearly at the frame's stamp (frames outside the truth's time span
are left out) and the table fitted by ``position_table.fit_table``.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Any, Iterable

import numpy as np
from cantools.database import Database

from linkage_monitor.mechanics import InputError

from .frames import Frame
from .j1939 import Raw, classify, pgn
from .mapping import CanMapping, InputMap
from .position_table import PositionTable, TableError, fit_table


@dataclass(frozen=True)
class FittedTable:
    """One fitted table: the input, the table, the samples used and the largest error of the table
    against the truth on them (in the measurement's unit as the mapping gives it)."""

    input: InputMap
    table: PositionTable
    samples: int
    max_error: float


def signal_series(frames: Iterable[Frame], db: Database, inputs: list[InputMap]) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """input name -> (stamps ns, physical signal values) of its signal in ``frames``; frames with the
    signal 'not available' / 'error' or of another length than the DBC's are left out."""
    wanted: dict[int, tuple[Any, list[InputMap]]] = {}
    for item in inputs:
        message = db.get_message_by_name(item.message)
        wanted.setdefault(pgn(message.frame_id) if message.is_extended_frame else message.frame_id, (message, []))[1].append(item)
    series: dict[str, tuple[list[int], list[float]]] = {item.name: ([], []) for item in inputs}
    for frame in frames:
        if frame.is_error or frame.is_remote:
            continue
        key = pgn(frame.arbitration_id) if frame.is_extended else frame.arbitration_id
        entry = wanted.get(key)
        if entry is None or len(frame.data) != entry[0].length:
            continue
        message, items = entry
        raw = message.decode(frame.data, decode_choices=False, scaling=False)
        for item in items:
            signal = message.get_signal_by_name(item.signal)
            value = int(raw[signal.name])
            if not signal.is_signed and classify(value, signal.length) is not Raw.VALUE:
                continue
            stamps, values = series[item.name]
            stamps.append(frame.stamp_ns)
            values.append(value * signal.scale + signal.offset)
    return {name: (np.array(s, dtype=np.int64), np.array(v, dtype=float)) for name, (s, v) in series.items()}


def fit_tables(mapping: CanMapping, db: Database, frames: Iterable[Frame],
               truth: dict[str, tuple[np.ndarray, np.ndarray]], points: int = 26) -> list[FittedTable]:
    """The fitted table of every input of ``mapping`` that has one. truth: measurement name ->
    (stamps ns, values in the mapping's unit for that input). InputError naming what is missing."""
    inputs = [item for item in mapping.inputs if item.table is not None]
    if not inputs:
        raise InputError(f"mapping {mapping.source}: no input has a table to calibrate")
    missing = [item.name for item in inputs if item.name not in truth]
    if missing:
        raise InputError(f"the truth holds no {', '.join(missing)}: record the calibration lift with those joints")
    series = signal_series(frames, db, inputs)
    fitted = []
    for item in inputs:
        stamps, signal = series[item.name]
        truth_stamps, truth_values = truth[item.name]
        order = np.argsort(truth_stamps, kind="stable")
        truth_stamps, truth_values = truth_stamps[order], truth_values[order]
        inside = (stamps >= truth_stamps[0]) & (stamps <= truth_stamps[-1]) if truth_stamps.size else stamps < 0
        if not inside.any():
            raise InputError(f"no frame of {item.message}.{item.signal} lies within the truth's time span for "
                             f"{item.name}: are the log and the truth of the same lift?")
        # stamps relative to the first truth stamp: float64 keeps ns exactly over the lift
        base = truth_stamps[0]
        value = np.interp((stamps[inside] - base).astype(float), (truth_stamps - base).astype(float), truth_values)
        try:
            table = fit_table(signal[inside], value, points)
        except TableError as exc:
            raise InputError(f"inputs.{item.name}: {exc}") from None
        errors = np.abs(np.interp(signal[inside], table.signal, table.value) - value)
        fitted.append(FittedTable(replace(item, table=table), table, int(inside.sum()), float(errors.max())))
    return fitted
