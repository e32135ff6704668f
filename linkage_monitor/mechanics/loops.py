"""The loops of a linkage from the structure of its square driving system.

A maximum matching of equations (rows) to coordinates (columns) (Hopcroft & Karp 1973), then the
strongly connected components of the graph it induces on the columns (Tarjan 1972): the diagonal
blocks of the system's block-triangular form (Dulmage & Mendelsohn 1958), one per loop. Plain
Python over a dense boolean pattern: a driving system has a few dozen rows at most, and the sparse
graph library is not worth its import at start-up.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np

_UNREACHED = 1 << 62   # the level of a row the breadth-first search has not reached


@dataclass(frozen=True)
class LoopBlock:
    """One diagonal block of a square pattern: its rows, each the row matched to the column at the
    same place in ``columns`` (ascending)."""

    rows: np.ndarray      # (k,) int64, indices into the pattern's rows
    columns: np.ndarray   # (k,) int64, indices into the pattern's columns, ascending


def row_matching(pattern: np.ndarray) -> np.ndarray:
    """A maximum matching of the rows of the boolean ``pattern`` (rows, columns) to its columns:
    the column matched to each row, −1 for a row left unmatched. Hopcroft-Karp: breadth-first
    levels from the unmatched rows, then depth-first augmenting paths along them; rows are taken in
    index order and each row's columns in ascending order, so the matching is the one
    ``scipy.sparse.csgraph.maximum_bipartite_matching(..., perm_type="column")`` returns."""
    n_rows, n_cols = pattern.shape
    columns_of = [np.flatnonzero(row).tolist() for row in pattern]
    free = n_rows   # the auxiliary row every unmatched column is matched to
    column_of = [-1] * n_rows
    row_of = [free] * n_cols
    level = [0] * (n_rows + 1)
    parent = [0] * n_rows
    while True:
        queue = [v for v in range(n_rows) if column_of[v] < 0]
        for v in range(n_rows):
            level[v] = 0 if column_of[v] < 0 else _UNREACHED
        level[free] = _UNREACHED
        for v in queue:   # the queue grows while it is read
            if level[v] < level[free]:
                for u in columns_of[v]:
                    if level[row_of[u]] == _UNREACHED:
                        level[row_of[u]] = level[v] + 1
                        queue.append(row_of[u])
        if level[free] == _UNREACHED:
            break
        for start in range(n_rows):
            if column_of[start] < 0:
                _augment(start, columns_of, column_of, row_of, level, parent, free)
    return np.array(column_of, dtype=np.int64)


def _augment(start: int, columns_of: Sequence[Sequence[int]], column_of: list[int], row_of: list[int],
             level: list[int], parent: list[int], free: int) -> None:
    """One depth-first search from the unmatched row ``start`` along rows one level deeper each step;
    the first path that reaches an unmatched column flips the matching along it (its rows are
    then left out of the other searches of this phase)."""
    stack = [start]
    while stack:
        v = stack.pop()
        for u in columns_of[v]:
            r = row_of[u]
            if level[r] != level[v] + 1:
                continue
            if r == free:
                while True:
                    level[v] = _UNREACHED
                    row_of[u] = v
                    u, column_of[v] = column_of[v], u   # v's former column is matched along the path next
                    if v == start:
                        return
                    v = parent[v]
            stack.append(r)
            parent[r] = v


def strong_components(successors: Sequence[Sequence[int]]) -> list[list[int]]:
    """The strongly connected components of a directed graph (vertex -> its successors), each
    ascending, listed by their smallest vertex (Tarjan 1972, without recursion)."""
    n = len(successors)
    order, low = [-1] * n, [0] * n
    on_stack = [False] * n
    stack: list[int] = []
    components: list[list[int]] = []
    visited = 0
    for root in range(n):
        if order[root] >= 0:
            continue
        path = [(root, 0)]   # (vertex, its next successor to look at)
        while path:
            v, next_successor = path[-1]
            if next_successor == 0:
                order[v] = low[v] = visited
                visited += 1
                stack.append(v)
                on_stack[v] = True
            if next_successor < len(successors[v]):
                path[-1] = (v, next_successor + 1)
                w = successors[v][next_successor]
                if order[w] < 0:
                    path.append((w, 0))
                elif on_stack[w]:
                    low[v] = min(low[v], order[w])
                continue
            path.pop()
            if path:
                low[path[-1][0]] = min(low[path[-1][0]], low[v])
            if low[v] == order[v]:
                component = []
                while True:
                    w = stack.pop()
                    on_stack[w] = False
                    component.append(w)
                    if w == v:
                        break
                components.append(sorted(component))
    return sorted(components)


def diagonal_blocks(pattern: np.ndarray) -> list[LoopBlock]:
    """The diagonal blocks of the block-triangular form of the square boolean ``pattern``, listed by
    their smallest column; none when the pattern is structurally singular (no perfect matching)."""
    match = row_matching(pattern)
    if np.any(match < 0):
        return []
    row_of_column = np.argsort(match)
    successors = [np.flatnonzero(pattern[row]).tolist() for row in row_of_column]
    return [LoopBlock(rows=row_of_column[columns].astype(np.int64), columns=np.array(columns, dtype=np.int64))
            for columns in strong_components(successors)]
