"""Broad phase of the polyhedral Boolean: all pairs of overlapping boxes from two sets (grids and implicit BVHs).

:func:`box_pairs` returns every pair ``(i, j)`` of closed axis-aligned boxes, ``i`` from the
first set and ``j`` from the second, that share a point (touching counts);
:func:`triangle_pairs` does the same for the triangles of two meshes after culling them on
their vertices.  Large sets go through a uniform grid (the classic spatial-hash broad phase,
Ericson, "Real-Time Collision Detection", 2005, §7.1): boxes are listed in every cell they
cover, boxes sharing a cell are paired and each pair is reported only in the cell holding the
lower corner of the two boxes' overlap.  Cell indices are ``floor((x - origin) / h)``, a
monotone function of ``x``, so two closed boxes that share a point share a cell and nothing is
lost.  When boxes of very different sizes would cover too many cells, and for small sets, each
set is put in a *linear bounding-volume hierarchy*: boxes sorted by the Morton code of their centres
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

from coons.kernel._common import column_max, column_min

__all__ = ["box_pairs", "triangle_boxes", "triangle_pairs"]

#: Bits of the Morton code per axis (3 × 21 = 63 bits fit an int64).
_MORTON_BITS = 21
#: Most grid cells (bool grids of a few MB).
_MAX_CELLS = 1 << 22
#: Sets smaller than this go to the trees (a grid or a cull would not pay).
_CULL_MIN = 2048
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


def triangle_boxes(P: np.ndarray, T: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Closed boxes ``lo, hi (m, 3)`` of triangles ``T (m, 3)`` over points ``P (n, 3)`` (three gathers,
    no reduction over a middle axis; ``np.take`` row gathers are several times faster than ``P[idx]``)."""
    c0, c1, c2 = (np.take(P, T[:, k], axis=0) for k in range(3))
    return np.minimum(np.minimum(c0, c1), c2), np.maximum(np.maximum(c0, c1), c2)


def _cell_ranges(lo, hi, origin, h, dims) -> tuple[np.ndarray, np.ndarray]:
    """First and last cell ``(k, 3)`` of each box, clipped to the grid (monotone in the coordinates)."""
    top = dims - 1
    i0 = np.clip(np.floor((lo - origin) / h), 0, top).astype(np.int64)
    i1 = np.clip(np.floor((hi - origin) / h), 0, top).astype(np.int64)
    return i0, i1


def _cells(i0: np.ndarray, i1: np.ndarray, dims: np.ndarray, limit: int):
    """Every grid cell covered by each box: ``(box, flat cell)`` rows, or None above ``limit`` rows."""
    span = i1 - i0 + 1
    count = span[:, 0] * span[:, 1] * span[:, 2]
    total = int(count.sum())
    if total > limit:
        return None
    box = np.repeat(np.arange(i0.shape[0]), count)
    local = np.arange(total) - np.repeat(np.cumsum(count) - count, count)
    sz, sy = span[box, 2], span[box, 1]
    z = i0[box, 2] + local % sz
    rest = local // sz
    y = i0[box, 1] + rest % sy
    x = i0[box, 0] + rest // sy
    return box, (x * dims[1] + y) * dims[2] + z


def _grid(lo_a, hi_a, lo_b, hi_b):
    """Grid over the common part of the two sets: ``origin, h, dims`` and the boxes of each set
    meeting that part (None when it is empty)."""
    f_lo = np.maximum(column_min(lo_a), column_min(lo_b))
    f_hi = np.minimum(column_max(hi_a), column_max(hi_b))
    if np.any(f_lo > f_hi):
        return None
    in_a = (lo_a <= f_hi) & (hi_a >= f_lo)
    in_b = (lo_b <= f_hi) & (hi_b >= f_lo)
    ka = np.flatnonzero(in_a[:, 0] & in_a[:, 1] & in_a[:, 2])
    kb = np.flatnonzero(in_b[:, 0] & in_b[:, 1] & in_b[:, 2])
    if ka.size == 0 or kb.size == 0:
        return None
    # Cell size: the median of the boxes' extents (most boxes span two or three cells per axis),
    # large enough for the grid to stay below _MAX_CELLS.
    def longest(lo, hi, k):  # largest extent of each box k (columns: no reduction over rows of three)
        d = np.take(hi, k, axis=0) - np.take(lo, k, axis=0)
        return np.maximum(np.maximum(d[:, 0], d[:, 1]), d[:, 2])

    ext = np.concatenate([longest(lo_a, hi_a, ka), longest(lo_b, hi_b, kb)])
    size = f_hi - f_lo
    floor_h = (float(np.prod(np.maximum(size, size.max() * 1e-3))) / _MAX_CELLS) ** (1 / 3) * 1.01
    h = max(float(np.percentile(ext, 50)), floor_h, float(size.max()) / 4096, np.finfo(float).tiny)
    dims = np.maximum(np.ceil(size / h).astype(np.int64), 1)
    return f_lo, h, dims, ka, kb


def _grid_pairs(lo_a, hi_a, lo_b, hi_b) -> tuple[np.ndarray, np.ndarray] | None:
    """All overlapping pairs from a uniform grid: boxes sharing a cell, each pair reported only in the
    cell of its overlap's lower corner (a point of both boxes, so of a cell both cover); None when the
    boxes cover too many cells."""
    empty = np.zeros(0, dtype=np.int64)
    g = _grid(lo_a, hi_a, lo_b, hi_b)
    if g is None:
        return empty, empty.copy()
    origin, h, dims, ka, kb = g
    limit = 8 * (ka.size + kb.size) + (1 << 16)
    ra = _cell_ranges(np.take(lo_a, ka, axis=0), np.take(hi_a, ka, axis=0), origin, h, dims)
    rb = _cell_ranges(np.take(lo_b, kb, axis=0), np.take(hi_b, kb, axis=0), origin, h, dims)
    ca, cb = _cells(*ra, dims, limit), _cells(*rb, dims, limit)
    if ca is None or cb is None:
        return None
    ob = np.argsort(cb[1], kind="stable")
    cell_b, box_b = cb[1][ob], cb[0][ob]
    first = np.searchsorted(cell_b, ca[1], side="left")
    count = np.searchsorted(cell_b, ca[1], side="right") - first
    total = int(count.sum())
    if total > 64 * limit:
        return None
    I = ka[np.repeat(ca[0], count)]
    J = kb[box_b[np.repeat(first, count) + np.arange(total) - np.repeat(np.cumsum(count) - count, count)]]
    cell = np.repeat(ca[1], count)
    # Overlap test and the owning cell, one axis at a time on contiguous columns.
    ok = np.ones(total, dtype=bool)
    own = np.zeros(total, dtype=np.int64)
    for ax in range(3):
        la_, ha_ = np.ascontiguousarray(lo_a[:, ax]), np.ascontiguousarray(hi_a[:, ax])
        lb_, hb_ = np.ascontiguousarray(lo_b[:, ax]), np.ascontiguousarray(hi_b[:, ax])
        x_a, x_b = la_[I], lb_[J]
        ok &= (x_a <= hb_[J]) & (x_b <= ha_[I])
        c = np.floor((np.maximum(x_a, x_b) - origin[ax]) / h)
        np.clip(c, 0, dims[ax] - 1, out=c)
        own = own * dims[ax] + c.astype(np.int64)
    keep = ok & (own == cell)
    return I[keep], J[keep]


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
    if lo_a.shape[0] + lo_b.shape[0] < _CULL_MIN:
        return _tree_pairs(lo_a, hi_a, lo_b, hi_b)
    found = _grid_pairs(lo_a, hi_a, lo_b, hi_b)
    if found is None:  # boxes of very different sizes: the trees do not depend on a cell size
        found = _tree_pairs(lo_a, hi_a, lo_b, hi_b)
    return found


def triangle_pairs(P_a: np.ndarray, T_a: np.ndarray, P_b: np.ndarray, T_b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Pairs of triangles of two meshes whose closed boxes overlap: :func:`box_pairs` after a vertex cull.

    The cull works on vertices, which are half as many as triangles and fall in one cell each:
    with a cell size ``h`` at least every triangle's box extent, two triangles whose boxes share
    a point ``x`` have all their vertices within one cell of ``x``'s cell on each axis, so within
    two cells of each other.  The cells of B's vertices, dilated by two cells per axis, therefore
    contain a vertex of every triangle of A that can meet B (and the other way round).  A second
    pass marks the (at most eight) cells each surviving box covers and keeps the boxes covering a
    cell of the other set.  Only the survivors — a band around the intersection curve — reach
    :func:`box_pairs`.

    Parameters
    ----------
    P_a, P_b : (n, 3) float64 vertices; T_a, T_b : (m, 3) int64 triangles.

    Returns
    -------
    I, J : (k,) int64, as :func:`box_pairs` for the triangles' boxes.
    """
    lo_a, hi_a = triangle_boxes(P_a, T_a)
    lo_b, hi_b = triangle_boxes(P_b, T_b)
    ka = np.arange(T_a.shape[0])
    kb = np.arange(T_b.shape[0])
    if T_a.shape[0] + T_b.shape[0] >= _CULL_MIN:
        kept = _vertex_cull(P_a, T_a, lo_a, hi_a, P_b, T_b, lo_b, hi_b)
        if kept is not None:
            ka, kb = kept
    I, J = box_pairs(lo_a[ka], hi_a[ka], lo_b[kb], hi_b[kb])
    return ka[I], kb[J]


def _vertex_cull(P_a, T_a, lo_a, hi_a, P_b, T_b, lo_b, hi_b):
    """Triangles of each mesh with a vertex within two cells of the other mesh's vertices (see
    :func:`triangle_pairs`), or None when the grid would be too coarse to pay."""
    f_lo = np.maximum(column_min(P_a), column_min(P_b))
    f_hi = np.minimum(column_max(P_a), column_max(P_b))
    ext = max(float((hi_a - lo_a).max()), float((hi_b - lo_b).max()))
    size = f_hi - f_lo
    if np.any(size < -2 * ext):  # the meshes' boxes (widened by a triangle) do not meet
        return np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64)
    # Cells: at least the largest triangle extent (the argument above), few enough for a small grid.
    origin = f_lo - 2 * ext
    size = np.maximum(size + 4 * ext, 0.0)
    floor_h = (float(np.prod(np.maximum(size, size.max() * 1e-3))) / _MAX_CELLS) ** (1 / 3) * 1.01
    h = max(1.01 * ext, floor_h, np.finfo(float).tiny)  # 1 %: rounding of the cell index stays below a cell
    dims = np.maximum(np.ceil(size / h).astype(np.int64) + 1, 1)
    if int(dims.max()) < 8:
        return None
    n_cells = int(np.prod(dims))

    def cells(P):
        c = np.floor((P - origin) * (1.0 / h))  # monotone; out-of-grid vertices clip to the border
        np.clip(c, 0, dims - 1, out=c)
        c = c.astype(np.int64)
        return (c[:, 0] * dims[1] + c[:, 1]) * dims[2] + c[:, 2]

    def dilated(flat):
        occ = np.zeros(n_cells, dtype=bool)
        occ[flat] = True
        g = occ.reshape(tuple(int(d) for d in dims))
        for ax in range(3):  # separable dilation by two cells (the grid is padded by its border)
            for _ in range(2):
                up = [slice(None)] * 3
                dn = [slice(None)] * 3
                up[ax], dn[ax] = slice(1, None), slice(None, -1)
                d = g.copy()
                d[tuple(dn)] |= g[tuple(up)]
                d[tuple(up)] |= g[tuple(dn)]
                g = d
        return g.reshape(-1)

    cell_a, cell_b = cells(P_a), cells(P_b)
    near_a = dilated(cell_b)[cell_a]
    near_b = dilated(cell_a)[cell_b]
    ka = np.flatnonzero(near_a[T_a[:, 0]] | near_a[T_a[:, 1]] | near_a[T_a[:, 2]])
    kb = np.flatnonzero(near_b[T_b[:, 0]] | near_b[T_b[:, 1]] | near_b[T_b[:, 2]])
    # Second, tighter pass on the survivors: the cells each box covers (at most two per axis since
    # h exceeds every extent, so its eight corner cells are all of them) against the other set's.
    corners = []
    for k, lo, hi in ((ka, lo_a, hi_a), (kb, lo_b, hi_b)):
        lo_k, hi_k = np.take(lo, k, axis=0), np.take(hi, k, axis=0)  # np.take: faster than lo[k]
        c0 = np.clip(np.floor((lo_k - origin) * (1.0 / h)), 0, dims - 1).astype(np.int64)  # clipping is
        c1 = np.clip(np.floor((hi_k - origin) * (1.0 / h)), 0, dims - 1).astype(np.int64)  # monotone too
        flat = []
        for x in (c0[:, 0], c1[:, 0]):
            for y in (c0[:, 1], c1[:, 1]):
                xy = (x * dims[1] + y) * dims[2]
                flat.extend((xy + c0[:, 2], xy + c1[:, 2]))
        corners.append(flat)
    occ = [np.zeros(n_cells, dtype=bool), np.zeros(n_cells, dtype=bool)]
    for flat, o in zip(corners, occ):
        for f in flat:
            o[f] = True
    kept = []
    for k, flat, other in ((ka, corners[0], occ[1]), (kb, corners[1], occ[0])):
        hit = other[flat[0]]
        for f in flat[1:]:
            hit |= other[f]
        kept.append(k[hit])
    return kept[0], kept[1]


def _tree_pairs(lo_a, hi_a, lo_b, hi_b) -> tuple[np.ndarray, np.ndarray]:
    """All overlapping pairs by the simultaneous descent of the two trees (module docstring)."""
    empty = np.zeros(0, dtype=np.int64)
    frame_lo = np.minimum(column_min(lo_a), column_min(lo_b))
    frame_hi = np.maximum(column_max(hi_a), column_max(hi_b))
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
