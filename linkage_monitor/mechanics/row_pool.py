"""Rows for the live poses of one configuration, allocated in blocks and handed out one pose at a
time (``RowPool.take``): allocating the rows per pose took as long as solving the pose."""

from __future__ import annotations

import threading
from typing import Callable, NamedTuple

import numpy as np

from . import kernels
from .programs import LiveBuffer, LiveRows, fields


class RowBlock(NamedTuple):
    """Rows of SIZE live poses (``RowPool``): ``rows`` a ``LiveRows``, the inputs it solves them
    from, s (SIZE, n_inputs) and pressures (SIZE, 2, C) Pa, all in ``buffer`` (as
    ``kernels.live_series`` takes them)."""

    rows: LiveRows
    s: np.ndarray
    pressures: np.ndarray
    buffer: LiveBuffer


class RowPool:
    """Rows for the live poses of one configuration, handed out one pose at a time (``take``). A
    Result holds views of its pose's rows, so a row is never handed out twice: when a block's rows
    are all taken, a new block is allocated (the old one lives on with the Results that hold it)."""

    SIZE = 64

    def __init__(self, allocate: Callable[[int], LiveRows], n_inputs: int, n_cylinders: int) -> None:
        self._allocate, self._n_inputs, self._n_cylinders = allocate, n_inputs, n_cylinders
        self._lock = threading.Lock()   # one row per caller, from several threads too
        self._block, self._next = self._new_block(self.SIZE), 0

    def take(self) -> tuple[RowBlock, int]:
        """The block and index of the next free row."""
        return self.take_rows(1)

    def take_rows(self, count: int) -> tuple[RowBlock, int]:
        """The block and index of the first of ``count`` free rows in a row (a block of their own when
        they are more than SIZE)."""
        if count > self.SIZE:
            return self._new_block(count), 0
        with self._lock:
            if self._next + count > self.SIZE:
                self._block, self._next = self._new_block(self.SIZE), 0
            self._next += count
            return self._block, self._next - count

    def _new_block(self, size: int) -> RowBlock:
        rows = self._allocate(size)
        s, pressures = np.empty((size, self._n_inputs)), np.empty((size, 2, self._n_cylinders))
        return RowBlock(rows, s, pressures, kernels.live_buffer(fields(rows), s, pressures))
