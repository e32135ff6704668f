"""One CAN frame as the bridge sees it, whatever it came from (a bus, a log, a can_msgs/Frame).

Stamps are ns since the epoch at µs resolution: the resolution of candump logs and of the
frames' kernel timestamps as python-can reports them in float seconds; rounding every source to
the µs gives a frame the same stamp whether it was received live, written to a log or recorded
as can_msgs/msg/Frame, so the inputs decoded from it are the same.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Iterable, Iterator, Sequence

import can
import numpy as np

from linkage_monitor.wire.cdr import check_stamp

US = 1_000
CLASSIC_BYTES = 8   # data bytes of a classic CAN frame: a FrameBlock's data columns are at least this many
BLOCK_FRAMES = 65_536   # frames per FrameBlock when frames are gathered into blocks
CAN_ERR_FLAG = 0x20000000    # linux/can.h: the identifier of an error frame carries this bit
CAN_ERR_MASK = 0x1FFFFFFF    # ... and its error class bits (linux/can/error.h) below it


@dataclass(frozen=True, slots=True)
class Frame:
    """A classic CAN frame: stamp (ns since the epoch), identifier (11 or 29 bit), flags, the
    data length code and the data bytes (``dlc`` of them for a data frame)."""

    stamp_ns: int
    arbitration_id: int
    is_extended: bool
    is_remote: bool
    is_error: bool
    dlc: int
    data: bytes


def stamp_of(seconds: float) -> int:
    """ns since the epoch of a python-can timestamp (float s), rounded to the µs; StampRangeError (a
    ValueError: the log line is refused) beyond what a ROS header stamp holds."""
    return check_stamp(round(seconds * 1e6) * US, "a stamp")


def error_frame(stamp_ns: int, can_id: int, data: bytes) -> Frame:
    """The error frame of SocketCAN identifier ``can_id`` (CAN_ERR_FLAG set): its class bits as the
    identifier and its data, as python-can's socketcan bus hands it to the live bridge."""
    return Frame(stamp_ns, can_id & CAN_ERR_MASK, False, False, True, len(data), data)


def from_message(msg: can.Message) -> Frame:
    """The Frame of a python-can message (bus or log reader)."""
    return Frame(stamp_of(msg.timestamp), int(msg.arbitration_id), bool(msg.is_extended_id),
                 bool(msg.is_remote_frame), bool(msg.is_error_frame), int(msg.dlc), bytes(msg.data))


def to_message(frame: Frame) -> can.Message:
    """The python-can message of a Frame (for python-can's log writers and buses)."""
    return can.Message(timestamp=frame.stamp_ns / 1e9, arbitration_id=frame.arbitration_id,
                       is_extended_id=frame.is_extended, is_remote_frame=frame.is_remote,
                       is_error_frame=frame.is_error, dlc=frame.dlc, data=frame.data, check=False)


@dataclass(frozen=True)
class FrameBlock:
    """Frames as columns, row k the k-th frame: what a log reader hands the decoder and the bag writer
    many at once (``Frame`` is one row).

    stamp_ns: (n,) int64, ns since the epoch; arbitration_id: (n,) int64 (11 or 29 bit); is_extended,
    is_remote, is_error: (n,) bool; dlc: (n,) int64, the data length code; length: (n,) int64, the
    number of data bytes; data: (n, w) uint8, each row's ``length`` bytes then zeros, w >= 8.
    """

    stamp_ns: np.ndarray
    arbitration_id: np.ndarray
    is_extended: np.ndarray
    is_remote: np.ndarray
    is_error: np.ndarray
    dlc: np.ndarray
    length: np.ndarray
    data: np.ndarray

    def __len__(self) -> int:
        return len(self.stamp_ns)

    def frame(self, k: int) -> Frame:
        """Row ``k`` as a Frame."""
        return Frame(int(self.stamp_ns[k]), int(self.arbitration_id[k]), bool(self.is_extended[k]),
                     bool(self.is_remote[k]), bool(self.is_error[k]), int(self.dlc[k]),
                     self.data[k, :self.length[k]].tobytes())

    def frames(self) -> Iterator[Frame]:
        """Every row as a Frame, in order."""
        return (self.frame(k) for k in range(len(self)))

    @staticmethod
    def empty(n: int, width: int = CLASSIC_BYTES) -> FrameBlock:
        """A block of ``n`` zeroed rows with ``width`` data columns, to be filled in."""
        return FrameBlock(np.zeros(n, np.int64), np.zeros(n, np.int64), np.zeros(n, bool), np.zeros(n, bool),
                          np.zeros(n, bool), np.zeros(n, np.int64), np.zeros(n, np.int64),
                          np.zeros((n, max(width, CLASSIC_BYTES)), np.uint8))

    @staticmethod
    def of(frames: Sequence[Frame]) -> FrameBlock:
        """The block of ``frames``, in order."""
        block = FrameBlock.empty(len(frames), max((len(f.data) for f in frames), default=0))
        block.fill(np.arange(len(frames)), frames)
        return block

    def fill(self, rows: np.ndarray, frames: Sequence[Frame]) -> None:
        """Write ``frames`` into ``rows`` (one row each, the data columns wide enough)."""
        if not len(frames):
            return
        self.stamp_ns[rows] = [f.stamp_ns for f in frames]
        self.arbitration_id[rows] = [f.arbitration_id for f in frames]
        self.is_extended[rows] = [f.is_extended for f in frames]
        self.is_remote[rows] = [f.is_remote for f in frames]
        self.is_error[rows] = [f.is_error for f in frames]
        self.dlc[rows] = [f.dlc for f in frames]
        self.length[rows] = [len(f.data) for f in frames]
        for row, f in zip(rows.tolist(), frames):
            self.data[row, :len(f.data)] = np.frombuffer(f.data, np.uint8)


def blocks_of(frames: Iterable[Frame], size: int = BLOCK_FRAMES) -> Iterator[FrameBlock]:
    """``frames`` gathered into blocks of ``size`` (the last one shorter), in order."""
    batch: list[Frame] = []
    for frame in frames:
        batch.append(frame)
        if len(batch) == size:
            yield FrameBlock.of(batch)
            batch = []
    if batch:
        yield FrameBlock.of(batch)
