"""DBC signals read from many frames at once: each frame's raw value of a signal taken from its data
bytes with numpy, by the bit layout cantools parsed from the DBC (start bit, length, byte order,
signedness).

cantools stays the definition and the oracle: ``test/test_can_blocks.py`` holds these raw values
equal to ``Message.decode(..., scaling=False)`` on random frames of little- and big-endian, signed and
unsigned signals. A signal this module does not read (a float, longer than ``MAX_BITS``, in a
multiplexed message or in one longer than 8 bytes) has no ``SignalLayout``: its frames are decoded
by cantools one by one.
"""

from __future__ import annotations

from typing import Any, NamedTuple

import numpy as np

MESSAGE_BYTES = 8   # the longest message read here: its data is one 64-bit word
MAX_BITS = 52       # longer raw values are not all exact as float64


class SignalLayout(NamedTuple):
    """Where a signal's raw value lies in a message's data as a 64-bit word: ``big_endian`` says which
    reading of the 8 bytes (Motorola: byte 0 first; Intel: byte 0 last), ``shift`` how far to shift
    that word right, ``length`` its bits, ``signed`` two's complement."""

    name: str
    big_endian: bool
    shift: int
    length: int
    signed: bool


def signal_layout(message: Any, signal: Any) -> SignalLayout | None:
    """The layout of cantools ``signal`` in ``message``, or None where the frames are left to cantools."""
    if (message.is_multiplexed() or message.length > MESSAGE_BYTES or signal.conversion.is_float
            or not 0 < signal.length <= MAX_BITS):
        return None
    if signal.byte_order == "big_endian":
        msb = 8 * (signal.start // 8) + 7 - signal.start % 8   # Motorola: the start bit is the MSB (sawtooth)
        shift = 8 * MESSAGE_BYTES - msb - signal.length
        big_endian = True
    else:
        shift, big_endian = signal.start, False
    if shift < 0 or shift + signal.length > 8 * MESSAGE_BYTES:
        return None
    return SignalLayout(signal.name, big_endian, shift, signal.length, bool(signal.is_signed))


class Words(NamedTuple):
    """The data of n frames (8 bytes each, zero-padded) as 64-bit words, read both ways."""

    little: np.ndarray
    big: np.ndarray


def words(data: np.ndarray) -> Words:
    """The words of data bytes ``data`` (n, >= 8) uint8 (only the first 8 columns are read)."""
    eight = np.ascontiguousarray(data[:, :MESSAGE_BYTES])
    return Words(eight.view("<u8")[:, 0], eight.view(">u8")[:, 0])


def raw_values(w: Words, layout: SignalLayout) -> np.ndarray:
    """Each frame's raw value of the signal (n,) int64, as cantools decodes it without scaling."""
    word = w.big if layout.big_endian else w.little
    raw = ((word >> np.uint64(layout.shift)) & np.uint64((1 << layout.length) - 1)).astype(np.int64)
    if layout.signed:
        raw -= ((raw >> (layout.length - 1)) & 1) << layout.length
    return raw
