"""Connected components in numpy (:func:`coons.topology._components.components`): the labels of
scipy's ``connected_components`` (components numbered by their smallest node), also past the
rounds after which the graph goes to scipy."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

from coons.topology import _components
from coons.topology._components import components


def scipy_components(n: int, a: np.ndarray, b: np.ndarray) -> tuple[int, np.ndarray]:
    return connected_components(coo_matrix((np.ones(a.size), (a, b)), shape=(n, n)), directed=False)


@pytest.mark.parametrize("seed", range(5))
def test_random_graphs_match_scipy(seed):
    rng = np.random.default_rng(seed)
    for _ in range(200):
        n = int(rng.integers(1, 80))
        m = int(rng.integers(0, 2 * n))
        a, b = rng.integers(0, n, m), rng.integers(0, n, m)
        count, label = components(n, a, b)
        want_count, want = scipy_components(n, a, b)
        assert count == want_count
        np.testing.assert_array_equal(label, want)


def test_no_nodes_and_no_edges():
    assert components(0, np.empty(0, int), np.empty(0, int))[0] == 0
    count, label = components(4, np.empty(0, int), np.empty(0, int))
    assert count == 4
    np.testing.assert_array_equal(label, np.arange(4))


def test_deep_graph_falls_back_to_scipy(monkeypatch):
    # A shuffled path with its edges in random order needs several hooking rounds; with one
    # round allowed the graph goes to scipy, with the same labels.
    rng = np.random.default_rng(7)
    n = 500
    perm = rng.permutation(n)
    e = rng.permutation(n - 1)
    a, b = perm[:-1][e], perm[1:][e]
    iso = np.array([n, n + 1])  # two isolated nodes after the path
    want_count, want = scipy_components(n + 2, a, b)
    assert want_count == 3
    for rounds in (1, _components._MAX_ROUNDS):
        monkeypatch.setattr(_components, "_MAX_ROUNDS", rounds)
        count, label = components(n + 2, a, b)
        assert count == 3
        np.testing.assert_array_equal(label, want)
        assert len(set(label[iso].tolist())) == 2
