"""The crash-safe MCAP file: after every write it ends in a valid MCAP tail (DataEnd + Footer, no
summary), so a process killed at any point leaves a file that footer-reading readers (rosbags, mcap
SeekingReader, Rerun) open; an I/O error cuts it back to where the write began."""

from __future__ import annotations

import os
from pathlib import Path

from linkage_monitor.bag.mcap_records import TAIL


class TailedFile:
    """Unbuffered file that ends in a valid MCAP tail after every write.

    Each write is followed by `TAIL`, and the position moves back before it, so the next
    write overwrites it. `tell()` is the logical end; `close()` truncates the last tail.
    """

    def __init__(self, path: Path) -> None:
        self._file = open(path, "xb", buffering=0)  # noqa: SIM115 (closed in close())
        self._tail = False

    def enable_tail(self) -> None:
        self._tail = True

    def write(self, data: bytes | memoryview) -> int:
        """Write all of ``data`` (then the tail); on an I/O error (ENOSPC, EIO) the file is cut back
        to where this write began and ends in the tail again, so it stays readable, and the error
        is raised."""
        start = self._file.tell()
        try:
            view = memoryview(data)
            while view:
                view = view[self._file.write(view):]
            if self._tail:
                self._write_tail()
        except OSError:
            self._rollback(start)
            raise
        return len(data)

    def _write_tail(self) -> None:
        view = memoryview(TAIL)
        while view:
            view = view[self._file.write(view):]
        self._file.seek(-len(TAIL), os.SEEK_CUR)

    def _rollback(self, position: int) -> None:
        """Cut the file back to ``position`` and end it in the tail again (best effort: the cut frees
        the space the tail needs)."""
        try:
            self._file.truncate(position)
            self._file.seek(position)
            if self._tail:
                self._write_tail()
        except OSError:
            pass

    def tell(self) -> int:
        return self._file.tell()

    def flush(self) -> None:
        """Nothing buffered in-process; data written is in the OS page cache."""

    def fsync(self) -> None:
        os.fsync(self._file.fileno())

    def close(self, keep_tail: bool = False) -> None:
        """Close; ``keep_tail``: leave the file ending in the tail (after an I/O error, when the
        MCAP writer cannot finish its summary)."""
        try:
            if not keep_tail:
                self._file.truncate(self._file.tell())
        finally:
            self._file.close()
