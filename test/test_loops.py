"""The loops of a linkage from its structure (mechanics.loops) against scipy's sparse graph
algorithms as the oracle: the same maximum matching as ``maximum_bipartite_matching`` (so every
loop block keeps its rows in the same order, and its determinant's sign, the assembly branch, is
the same), the same strongly connected components as ``connected_components``."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import connected_components, maximum_bipartite_matching

from linkage_monitor.mechanics import Solver, load_preset, preset_names
from linkage_monitor.mechanics.loops import diagonal_blocks, row_matching, strong_components


def random_patterns(count: int, seed: int) -> list[np.ndarray]:
    """Boolean patterns of 1-13 rows and columns, square for every other one, of every density;
    every third one given a perfect matching (a permuted diagonal), as a driving system has."""
    rng = np.random.default_rng(seed)
    patterns = []
    for k in range(count):
        rows, columns = (int(v) for v in rng.integers(1, 14, 2))
        columns = rows if k % 2 else columns
        pattern = rng.random((rows, columns)) < rng.uniform(0.05, 0.6)
        if k % 3 == 0 and rows == columns:
            pattern |= np.eye(rows, dtype=bool)[rng.permutation(rows)]
        patterns.append(pattern)
    return patterns


def scipy_blocks(pattern: np.ndarray) -> list[tuple[list[int], list[int]]]:
    """(columns, rows matched to them) of each diagonal block, from scipy, by smallest column."""
    match = maximum_bipartite_matching(csr_matrix(pattern.astype(np.int8)), perm_type="column")
    if np.any(match < 0):
        return []
    order = np.argsort(match)
    count, label = connected_components(csr_matrix(pattern[order].astype(np.int8)), directed=True,
                                        connection="strong")
    return sorted((np.flatnonzero(label == b).tolist(), order[label == b].tolist()) for b in range(count))


@pytest.mark.parametrize("pattern", random_patterns(600, seed=7))
def test_the_matching_is_scipys(pattern):
    expected = maximum_bipartite_matching(csr_matrix(pattern.astype(np.int8)), perm_type="column")
    np.testing.assert_array_equal(row_matching(pattern), expected)


@pytest.mark.parametrize("pattern", [p for p in random_patterns(600, seed=11) if p.shape[0] == p.shape[1]])
def test_the_blocks_are_scipys(pattern):
    blocks = [(b.columns.tolist(), b.rows.tolist()) for b in diagonal_blocks(pattern)]
    assert blocks == scipy_blocks(pattern)


def test_a_chain_of_two_dyads_gives_two_blocks_and_a_singular_pattern_none():
    """Closed form: a lower block-triangular pattern of a 2x2 and a 3x3 block (the second loop
    hangs on the first) has exactly these two blocks; a pattern with an empty column has none."""
    pattern = np.zeros((5, 5), dtype=bool)
    pattern[:2, :2] = True
    pattern[2:, 2:] = True
    pattern[3, 1] = True
    blocks = diagonal_blocks(pattern)
    assert [b.columns.tolist() for b in blocks] == [[0, 1], [2, 3, 4]]
    assert [sorted(b.rows.tolist()) for b in blocks] == [[0, 1], [2, 3, 4]]
    pattern[:, 4] = False
    assert diagonal_blocks(pattern) == []


def test_strong_components_of_a_cycle_and_a_tail():
    """Closed form: 0 -> 1 -> 2 -> 0 is one component, 3 -> 0 and 4 (alone) are their own."""
    assert strong_components([[1], [2], [0], [0], []]) == [[0, 1, 2], [3], [4]]


@pytest.mark.parametrize("preset", preset_names())
def test_each_presets_loops_are_scipys(preset):
    kin = Solver(load_preset(preset)).kin
    rows = kin.drive_rows
    q = kin.q_ref + 0.1 * np.random.default_rng(0).standard_normal(kin.n)
    pattern = kin.residual_jacobian(q[None], kin.reference.s)[1][0][rows] != 0.0
    expected = [(columns, rows[matched].tolist()) for columns, matched in scipy_blocks(pattern)]
    assert [(b.columns.tolist(), b.rows.tolist()) for b in kin._loops] == expected
    assert len(expected) >= 2   # every preset has more than one loop
