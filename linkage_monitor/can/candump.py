"""candump logs (``candump -L``, python-can's ``.log``) read into FrameBlocks with numpy, many lines at once.

A line is ``(SECONDS.MICROSECONDS) CHANNEL ID#DATA`` with an optional direction ``R`` / ``T`` after
it: ``(1700000000.123456) can0 18FE4D80#0102030405060708 R``. python-can's ``CanutilsLogReader`` is
the reference for what a line means (the test holds the two equal, frame for frame); lines of the
common form are read here as columns:

- the stamp: decimal seconds (1 to 10 digits, below 2^31 s) and exactly 6 decimals (µs), as candump
  and python-can write them; the frame's stamp is their value in ns, which is python-can's float
  seconds rounded to the µs (``frames.stamp_of``) for every such stamp;
- a channel of printable ASCII without spaces (not kept: a Frame has no channel);
- an identifier of 3 hex digits (11-bit) or 8 (29-bit), below 2^29 (no flag bits);
- 0 to 8 data bytes as pairs of hex digits (a classic data frame, DLC = the bytes);
- single spaces between the fields and nothing else on the line, shorter than 256 bytes.

Such lines are grouped by layout (where their fields end: few in a log) and each group is parsed as
fixed-width records, every field a range of columns.

Every other non-blank line — remote requests (``123#R``), CAN FD (``123##1...``), error frames (the
identifier's CAN_ERR_FLAG bit), other stamp formats, tabs or stray spaces — is handed to python-can's
own reader, one line at a time, in its place: the result is python-can's, but for error frames of
other classes than bus errors, which python-can reads as data frames of the class bits: they are the
error frames SocketCAN gives the live bridge (``frames.error_frame``). A line python-can cannot read
(garbage, a line cut short) is refused alone: its number and python-can's reason are kept
(``RefusedLine``), the other lines read on. Lines end at ``\\n``, ``\\r\\n`` or ``\\r`` (text mode's
universal newlines); blank lines hold no frame. A file is read in pieces of ``PIECE_BYTES`` cut at a
line end: one FrameBlock per piece.
"""

from __future__ import annotations

import io
import locale
from pathlib import Path
from typing import Iterator, NamedTuple

import can
import numpy as np
from numpy.lib.stride_tricks import as_strided

from .frames import CAN_ERR_FLAG, CLASSIC_BYTES, US, Frame, FrameBlock, error_frame, from_message

PIECE_BYTES = 4 << 20   # bytes of the file read and parsed at once (~70,000 lines of 29-bit frames)
SECONDS_DIGITS = 10     # at most this many digits before the decimal point on the fast path
FRACTION_DIGITS = 6     # exactly this many after it (µs)
ID_DIGITS = (3, 8)      # 11-bit and 29-bit identifiers
MAX_ID = 1 << 29        # identifiers at or above carry flag bits (python-can reads those lines)
MAX_SECONDS = 1 << 31   # s; beyond, python-can's float seconds lose the µs (python-can reads those lines)
DIRECTIONS = b"RrTt"    # the optional last field: received / transmitted

_NEWLINE, _SPACE, _HASH, _OPEN, _CLOSE, _DOT = (ord(c) for c in "\n #().")
_HEX = np.full(256, 255, np.uint8)      # byte -> its hex digit's value, 255 for none
for _k, _c in enumerate(b"0123456789abcdef"):
    _HEX[_c] = _HEX[bytes([_c]).upper()[0]] = _k
_DECIMAL = np.where(_HEX < 10, _HEX, 255).astype(np.uint8)   # byte -> its decimal digit's value, 255 for none
_IS_DIRECTION = np.zeros(256, bool)
_IS_DIRECTION[np.frombuffer(DIRECTIONS, np.uint8)] = True


class RefusedLine(NamedTuple):
    """A log line that holds no frame python-can can read: its number (from 1) and why."""

    number: int
    reason: str


class Lines(NamedTuple):
    """The lines of a piece: ``start`` (n,) their first byte, ``end`` (n,) their newline's position."""

    start: np.ndarray
    end: np.ndarray


class Fields(NamedTuple):
    """Where a line's fields are (byte positions, one per line): the spaces after the stamp
    (``stamp_end``) and after the channel (``channel_end``), the ``#``, the end of the data (the third
    space, or the line's end); ``shape_ok``: the line has 2 or 3 single spaces, one ``#`` and only
    printable ASCII, so the positions are its fields'."""

    stamp_end: np.ndarray
    channel_end: np.ndarray
    hash: np.ndarray
    data_end: np.ndarray
    shape_ok: np.ndarray


class Columns(NamedTuple):
    """The values of lines read on the fast path (one per line; meaningful where ``ok``): the stamp
    (ns since the epoch), identifier, whether it is 29-bit, the data bytes (n, 8) and their count."""

    ok: np.ndarray
    stamp_ns: np.ndarray
    arbitration_id: np.ndarray
    is_extended: np.ndarray
    data: np.ndarray
    length: np.ndarray


def read_candump(path: str | Path, refused: list[RefusedLine], piece_bytes: int = PIECE_BYTES) -> Iterator[FrameBlock]:
    """The frames of the candump log ``path`` in file order, a FrameBlock per piece of the file; each
    line python-can cannot read is appended to ``refused``, the rest read on."""
    with open(path, "rb") as file:
        rest, first_line = b"", 1
        while True:
            chunk = file.read(piece_bytes)
            if not chunk:
                break
            text = rest + chunk
            # the piece ends at the last line end; a last \r may be the first half of \r\n: it waits
            cut = max(text.rfind(b"\n"), text.rfind(b"\r", 0, len(text) - 1)) + 1
            rest = text[cut:]
            if cut:
                piece = _lines_with_newlines(text[:cut])
                yield parse_candump(piece, refused, first_line)
                first_line += piece.count(b"\n")
        if rest.strip():
            yield parse_candump(_lines_with_newlines(rest) + b"\n", refused, first_line)


def _lines_with_newlines(text: bytes) -> bytes:
    """``text`` with its \r\n and lone \r line ends as \n (one line end each: the lines keep their numbers)."""
    return text.replace(b"\r\n", b"\n").replace(b"\r", b"\n")


def parse_candump(piece: bytes, refused: list[RefusedLine], first_line: int = 1) -> FrameBlock:
    """The frames of whole candump lines (``piece`` ends with a newline; its first line is number
    ``first_line`` of the log), in order; the lines python-can cannot read appended to ``refused``."""
    buf = np.frombuffer(piece, np.uint8)
    lines = line_bounds(buf)
    columns = fast_columns(buf, lines, fields_of(buf, lines))
    blank = lines.start == lines.end
    slow = np.flatnonzero(~columns.ok & ~blank)
    slow_frames = []
    for k in slow.tolist():
        try:
            slow_frames.append(python_can_line(piece[lines.start[k]:lines.end[k]]))
        except (ValueError, can.CanError, IndexError, KeyError, OverflowError) as exc:
            refused.append(RefusedLine(first_line + k, f"not a CAN frame python-can reads ({type(exc).__name__}: "
                                       f"{str(exc).splitlines()[0] if str(exc) else 'no detail'})"))
            slow_frames.append(None)
    per_line = columns.ok.astype(np.int64)
    per_line[slow] = [frame is not None for frame in slow_frames]
    row = np.cumsum(per_line) - per_line            # each line's row in the block
    found = [frame for frame in slow_frames if frame is not None]
    block = FrameBlock.empty(int(per_line.sum()), max((len(f.data) for f in found), default=CLASSIC_BYTES))
    fast = np.flatnonzero(columns.ok)
    rows = row[fast]
    block.stamp_ns[rows] = columns.stamp_ns[fast]
    block.arbitration_id[rows] = columns.arbitration_id[fast]
    block.is_extended[rows] = columns.is_extended[fast]
    block.dlc[rows] = columns.length[fast]
    block.length[rows] = columns.length[fast]
    block.data[rows, :CLASSIC_BYTES] = columns.data[fast]
    block.fill(row[slow[per_line[slow] > 0]], found)
    return block


def line_bounds(buf: np.ndarray) -> Lines:
    """Start and newline of every line of ``buf`` (which ends with a newline)."""
    end = np.flatnonzero(buf == _NEWLINE)
    start = np.empty_like(end)
    start[:1] = 0
    start[1:] = end[:-1] + 1
    return Lines(start, end)


def _per_line(positions: np.ndarray, lines: Lines) -> tuple[np.ndarray, np.ndarray]:
    """For byte ``positions`` (sorted): how many fall in each line, and the index of each line's first."""
    count = np.bincount(np.searchsorted(lines.end, positions), minlength=len(lines.end))
    return count, np.cumsum(count) - count


def _nth(positions: np.ndarray, k: np.ndarray) -> np.ndarray:
    """``positions[k]``, k clipped to the array (lines where the k-th is not theirs are not shape_ok)."""
    if not len(positions):
        return np.zeros_like(k)
    return positions[np.minimum(k, len(positions) - 1)]


def fields_of(buf: np.ndarray, lines: Lines) -> Fields:
    """The field positions of every line (meaningful where ``shape_ok``)."""
    spaces = np.flatnonzero(buf == _SPACE)
    hashes = np.flatnonzero(buf == _HASH)
    odd = np.flatnonzero((buf < 0x21) | (buf > 0x7E))
    odd = odd[(buf[odd] != _SPACE) & (buf[odd] != _NEWLINE)]   # tabs, control bytes, non-ASCII
    n_spaces, first_space = _per_line(spaces, lines)
    n_hashes, first_hash = _per_line(hashes, lines)
    n_odd, _ = _per_line(odd, lines)
    shape_ok = ((n_spaces == 2) | (n_spaces == 3)) & (n_hashes == 1) & (n_odd == 0)
    return Fields(stamp_end=_nth(spaces, first_space), channel_end=_nth(spaces, first_space + 1),
                  hash=_nth(hashes, first_hash),
                  data_end=np.where(n_spaces == 3, _nth(spaces, first_space + 2), lines.end), shape_ok=shape_ok)


class Layout(NamedTuple):
    """Where a line's fields end, counted from its first byte: the spaces after the stamp and after the
    channel, the ``#``, the end of the data, the line's length. Lines of one layout are fixed-width
    records: each field is a range of columns."""

    stamp_end: int
    channel_end: int
    hash: int
    data_end: int
    length: int

    @staticmethod
    def key(f: Fields, lines: Lines, rows: np.ndarray) -> np.ndarray:
        """The layout of lines ``rows`` (shorter than 256 bytes) as one int64 each (a byte per field)."""
        key = np.zeros(len(rows), np.int64)
        for position in (f.stamp_end, f.channel_end, f.hash, f.data_end, lines.end):
            key = (key << 8) | (position[rows] - lines.start[rows])
        return key

    @staticmethod
    def of_key(key: int) -> Layout:
        return Layout(*((key >> shift) & 0xFF for shift in (32, 24, 16, 8, 0)))

    def fits(self) -> bool:
        """Whether lines of this layout can be of the common form: 1 to SECONDS_DIGITS digits and 6
        decimals in the stamp, a channel, a 3 or 8 digit identifier, 0 to 8 data bytes, maybe a direction."""
        data_digits = self.data_end - self.hash - 1
        return (1 <= self.stamp_end - FRACTION_DIGITS - 3 <= SECONDS_DIGITS and self.channel_end > self.stamp_end + 1
                and self.hash - self.channel_end - 1 in ID_DIGITS and data_digits % 2 == 0
                and 0 <= data_digits <= 2 * CLASSIC_BYTES and self.length in (self.data_end, self.data_end + 2))


def _digits(columns: np.ndarray, table: np.ndarray, base: int) -> tuple[np.ndarray, np.ndarray]:
    """The numbers written in ``columns`` (n, w) bytes, digit values by ``table`` (255: not a digit), and
    whether each is all digits."""
    values = table[columns]
    weights = base ** np.arange(columns.shape[1] - 1, -1, -1, dtype=np.int64)
    return values.astype(np.int64) @ weights, np.all(values < base, axis=1)


def _parse_layout(rows: np.ndarray, layout: Layout) -> tuple[np.ndarray, Columns]:
    """Lines of one layout (``rows``: (n, length) bytes): which are of the common form, and their values."""
    dot = layout.stamp_end - FRACTION_DIGITS - 2
    seconds, seconds_ok = _digits(rows[:, 1:dot], _DECIMAL, 10)
    micros, micros_ok = _digits(rows[:, dot + 1:layout.stamp_end - 1], _DECIMAL, 10)
    ident, ident_ok = _digits(rows[:, layout.channel_end + 1:layout.hash], _HEX, 16)
    nibbles = _HEX[rows[:, layout.hash + 1:layout.data_end]]
    ok = ((rows[:, 0] == _OPEN) & (rows[:, dot] == _DOT) & (rows[:, layout.stamp_end - 1] == _CLOSE)
          & seconds_ok & micros_ok & (seconds < MAX_SECONDS) & ident_ok & (ident < MAX_ID) & np.all(nibbles < 16, axis=1))
    if layout.length > layout.data_end:
        ok &= _IS_DIRECTION[rows[:, layout.data_end + 1]]
    n, count = len(rows), nibbles.shape[1] // 2
    data = np.zeros((n, CLASSIC_BYTES), np.uint8)
    data[:, :count] = nibbles[:, 0::2] * 16 + nibbles[:, 1::2]
    return ok, Columns(ok, (seconds * 1_000_000 + micros) * US, ident,
                       np.full(n, layout.hash - layout.channel_end - 1 > ID_DIGITS[0]), data, np.full(n, count))


def fast_columns(buf: np.ndarray, lines: Lines, f: Fields) -> Columns:
    """The stamp, identifier and data of every line of the common form (``ok``); others are not ok. Lines
    are parsed by layout (few in a log): each layout's lines gathered as fixed-width rows."""
    n = len(lines.start)
    out = Columns(np.zeros(n, bool), np.zeros(n, np.int64), np.zeros(n, np.int64), np.zeros(n, bool),
                  np.zeros((n, CLASSIC_BYTES), np.uint8), np.zeros(n, np.int64))
    candidates = np.flatnonzero(f.shape_ok & (lines.end - lines.start < 256) & (f.stamp_end > lines.start)
                                & (f.channel_end > f.stamp_end) & (f.hash > f.channel_end))
    keys, inverse = np.unique(Layout.key(f, lines, candidates), return_inverse=True)
    for k, key in enumerate(keys.tolist()):
        layout = Layout.of_key(key)
        if not layout.fits():
            continue
        mine = candidates[inverse.ravel() == k]
        starting_at = as_strided(buf, shape=(len(buf) - layout.length + 1, layout.length), strides=(1, 1))
        ok, values = _parse_layout(starting_at[lines.start[mine]], layout)
        for column, value in zip(out, values):
            column[mine[ok]] = value[ok]
    return out


def python_can_line(line: bytes) -> Frame | None:
    """The frame python-can's candump reader reads from one line (None for a line without one); its
    error for a line it cannot read. An identifier with CAN_ERR_FLAG is an error frame of its class
    (python-can reads only bus errors as such)."""
    text = line.decode(locale.getpreferredencoding(False))
    reader = can.CanutilsLogReader(io.StringIO(text))
    try:
        for msg in reader:
            frame = from_message(msg)
            can_id = int(text.split()[2].split("#", 1)[0], 16)
            if can_id & CAN_ERR_FLAG and not frame.is_error:
                return error_frame(frame.stamp_ns, can_id, frame.data)
            return frame
        return None
    finally:
        reader.stop()
