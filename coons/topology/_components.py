"""Connected components of small undirected graphs given as node pairs, in numpy.

The sewing's vertex clusters and the builder's shells are components of graphs whose
components are small (a vertex's few coincident ends) or shallow (faces around shared edges),
where scipy's sparse ``connected_components`` costs mostly its set-up (a COO and a CSR matrix,
their index checks: about a hundred microseconds per call, several calls per Boolean).
:func:`components` hooks roots and compresses paths with array operations instead; a graph
needing many rounds goes to scipy.
"""

from __future__ import annotations

import numpy as np

__all__ = ["components"]

#: Hooking rounds before the graph is handed to scipy: every round merges at least two trees, so a
#: path of many components could take many rounds; the graphs here settle in two or three.
_MAX_ROUNDS = 8


def components(n: int, a: np.ndarray, b: np.ndarray) -> tuple[int, np.ndarray]:
    """Connected components of ``n`` nodes joined by the edges ``(a[k], b[k])``.

    Returns ``(count, label)`` as ``scipy.sparse.csgraph.connected_components(..., directed=False)``
    does: ``label (n,)`` int numbers the components ``0 .. count - 1`` in the order of their
    smallest node.

    Each round hooks, for every edge whose ends have different roots, the larger root under the
    smaller (``np.minimum.at``: parents only decrease, ``parent[x] <= x``, so there are no
    cycles), then jumps pointers until every node points at its root.  A round that hooks
    nothing leaves every edge inside one tree: the trees are the components, and each root is
    its component's smallest node.
    """
    a = np.asarray(a, dtype=np.int64).ravel()
    b = np.asarray(b, dtype=np.int64).ravel()
    parent = np.arange(n, dtype=np.int64)
    for _ in range(_MAX_ROUNDS):
        pa, pb = parent[a], parent[b]
        diff = pa != pb
        if not diff.any():
            roots, label = np.unique(parent, return_inverse=True)
            return int(roots.size), label.reshape(n)
        np.minimum.at(parent, np.maximum(pa[diff], pb[diff]), np.minimum(pa[diff], pb[diff]))
        while True:
            up = parent[parent]
            if np.array_equal(up, parent):
                break
            parent = up
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    count, label = connected_components(coo_matrix((np.ones(a.size, np.int8), (a, b)), shape=(n, n)),
                                        directed=False)
    return int(count), label
