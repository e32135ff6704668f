"""SAE J1939 conventions the decoder needs: a frame's parameter group number and source address, and the
'error indicator' / 'not available' ranges of a parameter's raw value (J1939-71, ISO 11783-7)."""

from __future__ import annotations

from enum import Enum
from typing import TypeVar

import numpy as np

# socketcan error frames (linux/can/error.h): class bits in the identifier
CAN_ERR_BUSOFF = 0x40

_Ident = TypeVar("_Ident", int, np.ndarray)


class Raw(Enum):
    """What a parameter's raw value says: a value, an error indicator or not available."""

    VALUE = "value"
    ERROR = "error indicator"
    NOT_AVAILABLE = "not available"


def pgn(arbitration_id: int) -> int:
    """The parameter group number of a 29-bit identifier (PDU1: the destination byte is not part of it)."""
    pf = (arbitration_id >> 16) & 0xFF
    ps = (arbitration_id >> 8) & 0xFF
    page = (arbitration_id >> 24) & 0x3
    return (page << 16) | (pf << 8) | (ps if pf >= 240 else 0)


def source_address(ident: _Ident) -> _Ident:
    """The J1939 source address of a 29-bit identifier (its low byte; also of an array of them)."""
    return ident & 0xFF


def classify(raw: int, length: int) -> Raw:
    """The J1939 meaning of an unsigned raw value of ``length`` bits. 2 bits: 2 error, 3 not
    available; 4 bits: 0xE, 0xF; whole bytes: the top byte 0xFE error, 0xFF not available
    (1 byte: 0xFE, 0xFF; 2 bytes: 0xFE00-0xFEFF, 0xFF00-0xFFFF; ...). Other lengths carry no
    such ranges (VALUE)."""
    if length in (2, 4):
        top = (1 << length) - 1
        return Raw.NOT_AVAILABLE if raw == top else Raw.ERROR if raw == top - 1 else Raw.VALUE
    if length % 8 or length == 0:
        return Raw.VALUE
    top_byte = raw >> (length - 8)
    return Raw.NOT_AVAILABLE if top_byte == 0xFF else Raw.ERROR if top_byte == 0xFE else Raw.VALUE


def is_value(raw: np.ndarray, length: int) -> np.ndarray:
    """Where unsigned raw values ``raw`` (n,) of ``length`` bits are values: ``classify`` of each is VALUE."""
    if length in (2, 4):
        return raw < (1 << length) - 2
    if length % 8 or length == 0:
        return np.ones(raw.shape, bool)
    return (raw >> (length - 8)) < 0xFE
