"""Fixed byte layouts filled per message: the fast path of the messages whose layout is fixed for a
mechanism (names and counts do not change between poses).

A ``Template`` is a message written once by its layout (``wire.compose``) with placeholders: the
header stamp, ``Column`` float64 slots, ``Flag`` uint8 slots. Each message is a copy with those
filled in (an array assignment), instead of building an rclpy message field by field and
serializing it. What may vary in length (a status text) is written after the fixed part
(``extended``: the rest of the message from a named field on).
"""

from __future__ import annotations

import struct
from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from .cdr import ENCAPSULATION, check_stamp, stamp_fields
from .compose import Composer

_STAMP = struct.Struct("<iI")
_NS = 1_000_000_000


@dataclass(frozen=True)
class Template:
    """The fixed part of a message: its bytes with the stamp and float64 slots to fill.

    ``slots``: the float64 slots in message order, as indices of 8-byte words from the payload start
    (every float64 is 8-aligned there); ``columns``: the source column of each slot (the
    ``Column`` placeholders' indices); ``flags``: byte offsets of uint8 slots, in ``Flag`` order.
    """

    data: bytes
    slots: np.ndarray
    columns: np.ndarray
    flags: tuple[int, ...] = ()
    # what ``fill`` writes each message in: a copy of ``data`` and its float64 words
    _buffer: bytearray = field(init=False, repr=False, compare=False)
    _words: np.ndarray = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        buffer = bytearray(self.data)
        object.__setattr__(self, "_buffer", buffer)
        object.__setattr__(self, "_words", np.frombuffer(buffer, dtype="<f8", offset=len(ENCAPSULATION),
                                                         count=(len(buffer) - len(ENCAPSULATION)) // 8))

    @staticmethod
    def of(composer: Composer) -> "Template":
        """Freeze what ``composer`` wrote: a message whose first field is a std_msgs/Header with the
        ``STAMP`` placeholder, float64 ``Column`` and uint8 ``Flag`` placeholders after it."""
        if composer.stamps != [len(ENCAPSULATION)]:
            raise ValueError("a template's one stamp placeholder must be its header's, the first field")
        base = len(ENCAPSULATION)
        offsets = [offset for offset, _ in composer.columns]
        return Template(bytes(composer.data), np.array([(o - base) // 8 for o in offsets], dtype=np.intp),
                        np.array([column for _, column in composer.columns], dtype=np.intp),
                        tuple(offset for offset, _ in sorted(composer.flags, key=lambda f: f[1])))

    def extended(self, write: Callable[[Composer], object]) -> "Template":
        """This template followed by what ``write`` writes with a Composer on a copy of its bytes (a
        tail whose layout depends on, say, a status text); its Column placeholders are slots after these."""
        composer = Composer(bytearray(self.data), strict=True)
        composer.stamps.append(len(ENCAPSULATION))
        write(composer)
        tail = Template.of(composer)
        return Template(tail.data, np.concatenate([self.slots, tail.slots]),
                        np.concatenate([self.columns, tail.columns]), self.flags + tail.flags)

    def fill_rows(self, stamps_ns: np.ndarray, values: np.ndarray, flags: np.ndarray | None = None) -> np.ndarray:
        """N messages at once: ``fill`` of each row, as an (N, len(data)) uint8 array. ``stamps_ns``
        (N,) int64 ns since the epoch (struct.error beyond int32 seconds, as ``fill``), ``values``
        (N, len(slots)) in slot order, ``flags`` (N, k) uint8 of the first k flags (None, and those after
        k: the template's)."""
        n, size = len(stamps_ns), len(self.data)
        rows = np.empty((n, size), dtype=np.uint8)
        rows[:] = np.frombuffer(self.data, dtype=np.uint8)
        sec, nanosec = np.divmod(np.asarray(stamps_ns, dtype=np.int64), _NS)   # floor, as stamp_fields
        if n:
            check_stamp(int(np.min(stamps_ns)), "a header stamp")
            check_stamp(int(np.max(stamps_ns)), "a header stamp")
        base = len(ENCAPSULATION)
        rows[:, base:base + 4] = sec.astype("<i4").view(np.uint8).reshape(n, 4)
        rows[:, base + 4:base + 8] = nanosec.astype("<u4").view(np.uint8).reshape(n, 4)
        words = rows[:, base:base + 8 * ((size - base) // 8)].view("<f8")   # every float64 is 8-aligned there
        words[:, self.slots] = values
        if flags is not None:
            for k, offset in enumerate(self.flags[:flags.shape[1]]):
                rows[:, offset] = flags[:, k]
        return rows

    def fill(self, stamp_ns: int, values: "np.ndarray | list[float]", flags: tuple[int, ...] = ()) -> bytes:
        """The message with the header stamp (ns since the epoch; struct.error beyond int32 seconds),
        the float64 ``values`` in slot order and the uint8 ``flags`` written in (the template's own
        for those not given). Written in the template's one buffer, then copied out: one thread
        fills a template at a time (the node's executor, the replay)."""
        buffer = self._buffer
        _STAMP.pack_into(buffer, len(ENCAPSULATION), *stamp_fields(stamp_ns))
        self._words[self.slots] = values
        for k, offset in enumerate(self.flags):
            buffer[offset] = flags[k] if k < len(flags) else self.data[offset]
        return bytes(buffer)
