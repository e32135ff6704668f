"""Off the caller's path: ``BagWriter.write`` queues the message (its bytes, times and topic) and returns;
a background thread writes the queue into the MCAP chunk every WRITE_PERIOD_S, in order (a live node's
callback pays a list append per message, not the MCAP writer's record building, and the thread writes tens
of messages in a row), and flushes the bag every flush_period_s. Above MAX_QUEUED queued messages ``write``
writes the queue itself (memory stays bounded, nothing is dropped)."""

from __future__ import annotations

import threading
import time
from typing import Callable

from linkage_monitor.bag.metadata import Topic

WRITE_PERIOD_S = 0.05   # s, the background thread writes the queued messages this often
MAX_QUEUED = 10_000     # messages queued at most; beyond, write() writes the queue (in order) itself


QueuedMessage = tuple[Topic, bytes, int, int]
"""A message ``BagWriter.write`` queued: (topic, CDR bytes, MCAP log time, MCAP publish time; ns since the
epoch), unpacked by these names where it is written. A tuple, not a NamedTuple: it is built in the caller's
path (a node's callback), 0.05 µs against 0.4 µs."""


class WriteQueue:
    """The messages queued and not yet written, in order. ``lock`` is held for an append or a swap only
    (the writer holds it too for the closing of the bag and the count of messages not recorded)."""

    def __init__(self) -> None:
        self.lock = threading.Lock()
        self._messages: list[QueuedMessage] = []

    def __len__(self) -> int:
        return len(self._messages)

    def append(self, message: QueuedMessage) -> bool:
        """Queue ``message`` (under ``lock``); True when MAX_QUEUED messages are queued (write them now)."""
        self._messages.append(message)
        return len(self._messages) >= MAX_QUEUED

    def take(self) -> list[QueuedMessage]:
        """Every queued message, in order, the queue left empty."""
        with self.lock:
            taken, self._messages = self._messages, []
        return taken


class WriteThread:
    """The background thread of a bag writer: ``write`` (the queue) every WRITE_PERIOD_S and ``flush`` (the
    bag to disk) every ``flush_period_s`` (s) instead, until ``closed`` is set."""

    def __init__(self, name: str, closed: threading.Event, flush_period_s: float,
                 write: Callable[[], None], flush: Callable[[], None]) -> None:
        self._closed, self._flush_period_s = closed, flush_period_s
        self._write, self._flush = write, flush
        self._thread = threading.Thread(target=self._run, name=name, daemon=True)

    def start(self) -> None:
        self._thread.start()

    def join(self) -> None:
        self._thread.join()

    def _run(self) -> None:
        next_flush = time.monotonic() + self._flush_period_s
        while not self._closed.wait(min(WRITE_PERIOD_S, self._flush_period_s)):
            if time.monotonic() >= next_flush:
                next_flush = time.monotonic() + self._flush_period_s
                self._flush()
                continue
            self._write()
