"""Where a batch of poses runs: on the calling thread, or on every core (numba's thread pool)."""

from __future__ import annotations


# poses: smaller batches stay on the calling thread (no thread-pool wake-up). A batch's kinematics
# (belarus_1221, 2 cores, the second idle) take 0.6 of their one-thread time on 2 threads at 64
# poses, half from 256 on; with the other core busy a wake-up can wait for the scheduler (ms): the
# threshold keeps that rare
PARALLEL_MIN = 512


PARALLEL_PARTS = 64  # a parallel loop's parts, each with its own work arrays (several per core: balanced)


_threads = {"allowed": True}


def allow_threads(allowed: bool = True) -> None:
    """Whether batches of ≥ PARALLEL_MIN poses run on every core (numba's thread pool). On by default
    (``Solver.solve_batch``, the offline commands); the live node turns it off (it solves a pose at a
    time and keeps no thread pool), and so do a fleet's workers (one process per core already)."""
    _threads["allowed"] = allowed


def threads_allowed() -> bool:
    """Whether batches of ≥ PARALLEL_MIN poses run on every core (``allow_threads``)."""
    return _threads["allowed"]


def _parallel(n_pose: int) -> bool:
    return _threads["allowed"] and n_pose >= PARALLEL_MIN
