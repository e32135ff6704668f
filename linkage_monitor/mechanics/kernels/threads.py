"""Where a batch of poses runs: on the calling thread, or on every core (numba's thread pool)."""

from __future__ import annotations


PARALLEL_MIN = 512  # poses: smaller batches stay on the calling thread (no thread-pool wake-up)


PARALLEL_PARTS = 64  # a parallel loop's parts, each with its own work arrays (several per core: balanced)


_threads = {"allowed": False}


def allow_threads(allowed: bool = True) -> None:
    """Let batches of ≥ PARALLEL_MIN poses run on every core (numba's thread pool). Off by default:
    the live node solves one pose at a time and keeps no thread pool; the offline commands
    (replay, fleet, calibrate, capacity) turn it on."""
    _threads["allowed"] = allowed


def _parallel(n_pose: int) -> bool:
    return _threads["allowed"] and n_pose >= PARALLEL_MIN
