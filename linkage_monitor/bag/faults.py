"""What a bag read could not read as recorded: ``ReadFault``s, logged and collected (``read_faults``)."""

from __future__ import annotations

import logging
from collections.abc import Iterator
from contextlib import contextmanager
from contextvars import ContextVar
from dataclasses import dataclass

log = logging.getLogger("linkage_monitor.bag.reader")
"""The bag reader's log, every reading module's (faults as warnings, recorded definitions as information)."""


@dataclass(frozen=True)
class ReadFault:
    """Part of a bag that could not be read as recorded, named: ``file``, ``kind`` ('cut_off': the file
    ends in an incomplete record; 'chunk_skipped': a chunk fails its CRC or does not read;
    'unlisted_file': a storage file metadata.yaml does not list; 'type_mismatch': a topic whose messages
    are not its declared type (sqlite3); 'no_channel': messages whose channel
    is not defined), ``offset`` (byte in the file where it starts, None when it is a whole file),
    ``messages`` (messages read before a cut, or lost in a chunk; None when not known) and ``text``,
    the sentence that says it and what follows from it."""

    file: str
    kind: str
    offset: int | None
    messages: int | None
    text: str

    def __str__(self) -> str:
        return self.text


_COLLECTED: ContextVar[list[ReadFault] | None] = ContextVar("linkage_monitor_bag_read_faults", default=None)


@contextmanager
def read_faults() -> Iterator[list[ReadFault]]:
    """Collect the ``ReadFault``s of every bag read in this context (each once, in the order found;
    a bag read several times names its faults once). Each is also logged as a warning when first found."""
    found: list[ReadFault] = []
    token = _COLLECTED.set(found)
    try:
        yield found
    finally:
        _COLLECTED.reset(token)


def report(fault: ReadFault) -> None:
    """Log ``fault`` as a warning and add it to the ``read_faults`` being collected (once)."""
    found = _COLLECTED.get()
    if found is not None:
        if fault in found:
            return
        found.append(fault)
    log.warning("%s", fault.text)
