"""Broad phase of the polyhedral Boolean: all pairs of overlapping boxes from two sets, by two implicit BVHs.

:func:`box_pairs` returns every pair ``(i, j)`` of closed axis-aligned boxes, ``i`` from the
first set and ``j`` from the second, that share a point (touching counts).  Each set is put
in a *linear bounding-volume hierarchy*: boxes sorted by the Morton code of their centres
(Karras, "Maximizing parallelism in the construction of BVHs, octrees, and k-d trees", HPG
2012, uses the same order), padded to a power of two with empty boxes, and the complete binary
tree over that order stored level by level (node ``i`` of level ``L`` covers sorted positions
``[i 2^L, (i + 1) 2^L)``).  The two trees are traversed simultaneously, one level at a time, on
arrays of node pairs: each step replaces every surviving pair by its child pairs and keeps
those whose boxes overlap.  The work is ``O(n log n)`` for the sorts plus the surviving node
pairs of every level, ``O((n + k) log n)`` at worst for ``k`` overlapping leaf pairs; nothing
loops over boxes in Python.  Unlike a sort-and-sweep along one axis, the cost does not
depend on how many boxes overlap along a single axis (two surfaces crossing along a long
curve overlap along every axis).

The module decides nothing exactly: boxes are compared with ``<=`` on floats, so callers pass
closed boxes of float vertices (which contain the exact geometry).  It does not test the
objects inside the boxes.
"""

from __future__ import annotations

import numpy as np

__all__ = ["box_pairs"]

#: Bits of the Morton code per axis (3 × 21 = 63 bits fit an int64).
_MORTON_BITS = 21
#: Node pairs processed at once while descending (bounds the temporaries to some tens of MB).
_CHUNK = 1 << 21


def _spread(x: np.ndarray) -> np.ndarray:
    """Insert two zero bits between the low 21 bits of ``x`` (uint64), for 3-D Morton codes."""
    x = x.astype(np.uint64) & np.uint64(0x1FFFFF)
    x = (x | (x << np.uint64(32))) & np.uint64(0x1F00000000FFFF)
    x = (x | (x << np.uint64(16))) & np.uint64(0x1F0000FF0000FF)
    x = (x | (x << np.uint64(8))) & np.uint64(0x100F00F00F00F00F)
    x = (x | (x << np.uint64(4))) & np.uint64(0x10C30C30C30C30C3)
    x = (x | (x << np.uint64(2))) & np.uint64(0x1249249249249249)
    return x


def _morton_order(lo: np.ndarray, hi: np.ndarray, frame_lo: np.ndarray, frame_hi: np.ndarray) -> np.ndarray:
    """Permutation sorting boxes by the Morton code of their centres in the common frame."""
    c = 0.5 * (lo + hi)
    span = np.where(frame_hi > frame_lo, frame_hi - frame_lo, 1.0)
    q = np.clip((c - frame_lo) / span, 0.0, 1.0) * ((1 << _MORTON_BITS) - 1)
    q = q.astype(np.uint64)
    code = _spread(q[:, 0]) | (_spread(q[:, 1]) << np.uint64(1)) | (_spread(q[:, 2]) << np.uint64(2))
    return np.argsort(code, kind="stable")


class _Tree:
    """Complete binary tree of boxes over the Morton order: ``lo[L], hi[L]`` per level, leaves at level 0."""

    def __init__(self, lo: np.ndarray, hi: np.ndarray, frame_lo: np.ndarray, frame_hi: np.ndarray) -> None:
        n = lo.shape[0]
        self.order = _morton_order(lo, hi, frame_lo, frame_hi)
        size = 1 << max(0, int(np.ceil(np.log2(max(n, 1)))))
        L0 = np.full((size, 3), np.inf)
        H0 = np.full((size, 3), -np.inf)  # padding: empty boxes overlap nothing
        L0[:n] = lo[self.order]
        H0[:n] = hi[self.order]
        self.lo, self.hi = [L0], [H0]
        while self.lo[-1].shape[0] > 1:
            l, h = self.lo[-1], self.hi[-1]
            self.lo.append(np.minimum(l[0::2], l[1::2]))
            self.hi.append(np.maximum(h[0::2], h[1::2]))
        self.top = len(self.lo) - 1


def _overlap(la: np.ndarray, ha: np.ndarray, lb: np.ndarray, hb: np.ndarray) -> np.ndarray:
    return np.all(la <= hb, axis=1) & np.all(lb <= ha, axis=1)


def box_pairs(lo_a, hi_a, lo_b, hi_b) -> tuple[np.ndarray, np.ndarray]:
    """Pairs of overlapping closed boxes between two sets.

    Parameters
    ----------
    lo_a, hi_a : (n, 3) array_like of float
        Lower and upper corners of the first set.
    lo_b, hi_b : (m, 3) array_like of float
        Lower and upper corners of the second set.

    Returns
    -------
    I : (k,) int64
        Indices into the first set.
    J : (k,) int64
        Indices into the second set; box ``I[p]`` and box ``J[p]`` share a point.  Pairs are
        unique, in no particular order.

    Examples
    --------
    >>> I, J = box_pairs([[0, 0, 0], [5, 5, 5]], [[1, 1, 1], [6, 6, 6]], [[1, 1, 1]], [[2, 2, 2]])
    >>> I.tolist(), J.tolist()
    ([0], [0])
    """
    lo_a = np.asarray(lo_a, dtype=np.float64).reshape(-1, 3)
    hi_a = np.asarray(hi_a, dtype=np.float64).reshape(-1, 3)
    lo_b = np.asarray(lo_b, dtype=np.float64).reshape(-1, 3)
    hi_b = np.asarray(hi_b, dtype=np.float64).reshape(-1, 3)
    empty = np.zeros(0, dtype=np.int64)
    if lo_a.shape[0] == 0 or lo_b.shape[0] == 0:
        return empty, empty.copy()
    frame_lo = np.minimum(lo_a.min(axis=0), lo_b.min(axis=0))
    frame_hi = np.maximum(hi_a.max(axis=0), hi_b.max(axis=0))
    A = _Tree(lo_a, hi_a, frame_lo, frame_hi)
    B = _Tree(lo_b, hi_b, frame_lo, frame_hi)
    la, lb = A.top, B.top
    pa = np.zeros(1, dtype=np.int64)
    pb = np.zeros(1, dtype=np.int64)
    keep = _overlap(A.lo[la][pa], A.hi[la][pa], B.lo[lb][pb], B.hi[lb][pb])
    pa, pb = pa[keep], pb[keep]
    while (la > 0 or lb > 0) and pa.size:
        down_a = la > 0 and la >= lb
        down_b = lb > 0 and lb >= la
        if down_a:
            la -= 1
        if down_b:
            lb -= 1
        parts_a, parts_b = [], []
        for s in range(0, pa.size, _CHUNK):
            ca, cb = pa[s : s + _CHUNK], pb[s : s + _CHUNK]
            if down_a and down_b:
                ca = (2 * ca[:, None] + np.array([0, 0, 1, 1])).ravel()
                cb = (2 * cb[:, None] + np.array([0, 1, 0, 1])).ravel()
            elif down_a:
                ca = (2 * ca[:, None] + np.array([0, 1])).ravel()
                cb = np.repeat(cb, 2)
            else:
                ca = np.repeat(ca, 2)
                cb = (2 * cb[:, None] + np.array([0, 1])).ravel()
            ok = _overlap(A.lo[la][ca], A.hi[la][ca], B.lo[lb][cb], B.hi[lb][cb])
            parts_a.append(ca[ok])
            parts_b.append(cb[ok])
        pa = np.concatenate(parts_a)
        pb = np.concatenate(parts_b)
    if la > 0 or lb > 0:
        return empty, empty.copy()
    return A.order[pa].astype(np.int64), B.order[pb].astype(np.int64)
