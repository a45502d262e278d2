"""Constrained Delaunay triangulation of planar point sets, and removal of the triangles outside oriented loops.

:func:`triangulate` takes points ``(n, 2)`` and *directed* constraint segments ``(k, 2)``
that form closed loops with the region to keep on their left (outer loops counter-clockwise,
holes clockwise) and returns the counter-clockwise triangles of that region.  Every input
point is a vertex of the result (or lies outside the region) and every constraint segment is
a triangle edge; no point is ever inserted, so boundary discretisations shared with other
faces stay shared.  It deliberately does not refine (no Steiner points), does not accept
constraints that cross each other or pass through another input point (those raise), and
does not merge duplicate points (they raise).

Algorithm
---------
1. Delaunay triangulation of the points plus four far corners by Qhull
   (:class:`scipy.spatial.Delaunay`); the corners make every input point interior, so
   collinear points on the hull cannot produce flat triangles, and the flat triangles that
   Qhull's triangulation of merged facets can leave are flipped away.  Points Qhull leaves
   out as near-duplicates at its precision (distinct in floating point) are then inserted by
   Lawson insertion with the exact predicates.
2. Recovery of each missing constraint by edge flips (Sloan, "A fast algorithm for
   generating constrained Delaunay triangulations", Computers & Structures 47, 1993;
   Anglada, "An improved incremental algorithm for constructing restricted Delaunay
   triangulations", Computers & Graphics 21, 1997): walk from one end of the segment to
   the other collecting the crossed edges, then flip crossed edges whose quadrilateral is
   strictly convex until none crosses.  Only missing constraints are touched; the edges
   created are then made locally Delaunay again by Lawson flips (constraints excepted).
3. Removal of the outside: triangles are labelled by connected components of the
   triangle adjacency graph cut at the constraint edges (min-label propagation in numpy for
   small triangulations, scipy.sparse.csgraph for large ones), and a
   component is kept when it lies on the left of the constraints bounding it (vectorised;
   contradicting sides raise).

The flip phase uses the exact orientation and in-circle predicates of
:mod:`coons.kernel.predicates` (Shewchuk's filtered float evaluation with an exact fallback):
the vectorised ones for batches, the scalar ``*_one`` forms inside the flip loops.
"""

from __future__ import annotations

from collections import deque

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import Delaunay, QhullError

from coons.errors import ConvergenceError, InvalidInputError
from coons.kernel import predicates
from coons.kernel.predicates import incircle_one as incircle
from coons.kernel.predicates import orient2d_one as orient2d

__all__ = ["triangulate", "ConstrainedDelaunay", "orient2d", "incircle"]



def _orient_signs(P: np.ndarray, T: np.ndarray) -> np.ndarray:
    """Exact orientation signs of triangles ``T`` over points ``P`` (:func:`coons.kernel.predicates.orient2d`)."""
    return predicates.orient2d(P[T[:, 0]], P[T[:, 1]], P[T[:, 2]]).astype(np.int64)


# ---------------------------------------------------------------------- input
def _validated(points, segments) -> tuple[np.ndarray, np.ndarray]:
    P = np.asarray(points, dtype=np.float64)
    if P.ndim != 2 or P.shape[1] != 2:
        raise InvalidInputError(f"triangulate: points must have shape (n, 2), got {P.shape}")
    if not np.all(np.isfinite(P)):
        raise InvalidInputError("triangulate: points contain NaN or inf")
    S = np.asarray(segments)
    if S.size == 0:
        S = np.zeros((0, 2), dtype=np.int64)
    if S.ndim != 2 or S.shape[1] != 2 or not np.issubdtype(S.dtype, np.integer):
        raise InvalidInputError(f"triangulate: segments must be an integer array of shape (k, 2), got {S.shape} {S.dtype}")
    S = S.astype(np.int64)
    n = P.shape[0]
    if S.size and (S.min() < 0 or S.max() >= n):
        raise InvalidInputError(f"triangulate: segment indices must lie in [0, {n}), got [{S.min()}, {S.max()}]")
    if np.any(S[:, 0] == S[:, 1]):
        i = int(np.flatnonzero(S[:, 0] == S[:, 1])[0])
        raise InvalidInputError(f"triangulate: segment {i} joins point {int(S[i, 0])} to itself")
    if n < 3:
        raise InvalidInputError(f"triangulate: need at least 3 points, got {n}")
    order = np.lexsort((P[:, 1], P[:, 0]))
    same = np.all(P[order[1:]] == P[order[:-1]], axis=1)
    if np.any(same):
        i, j = int(order[:-1][same][0]), int(order[1:][same][0])
        raise InvalidInputError(f"triangulate: points {min(i, j)} and {max(i, j)} coincide at {P[i].tolist()}")
    return P, S


# ---------------------------------------------------------------------- the mutable triangulation
class _Mesh:
    """Triangles (counter-clockwise) with neighbours ``N[t][j]`` opposite vertex ``T[t][j]`` (-1: none)."""

    def __init__(self, P: np.ndarray, T: np.ndarray, N: np.ndarray) -> None:
        self.P = P
        self.n_points = P.shape[0]
        self.T: list[list[int]] = T.tolist()
        self.N: list[list[int]] = N.tolist()
        vt = np.full(P.shape[0], -1, dtype=np.int64)
        vt[T.ravel()] = np.repeat(np.arange(T.shape[0]), 3)
        self.vt: list[int] = vt.tolist()

    def add_point(self, p: np.ndarray) -> int:
        """Append a point (no triangle yet); returns its index."""
        if self.n_points == self.P.shape[0]:  # grow geometrically
            grown = np.empty((2 * self.P.shape[0], 2))
            grown[: self.n_points] = self.P[: self.n_points]
            self.P = grown
        self.P[self.n_points] = p
        self.vt.append(-1)
        self.n_points += 1
        return self.n_points - 1

    def locate(self, p: int, t: int) -> tuple[int, int]:
        """``(t, j)``: the triangle containing point ``p`` and -1, or the local index of the vertex opposite
        the edge ``p`` lies on (visibility walk from ``t``, Devillers–Pion–Teillaud 2002; a full search
        if the walk stalls).

        Raises
        ------
        InvalidInputError
            The point coincides with a vertex or lies outside the triangulation.
        """
        T, N, P = self.T, self.N, self.P
        for _ in range(4 * len(T) + 10):
            tri = T[t]
            zero = -1
            moved = False
            for j in range(3):
                a, b = tri[(j + 1) % 3], tri[(j + 2) % 3]
                o = orient2d(P[a], P[b], P[p])
                if o < 0:
                    t = N[t][j]
                    if t < 0:
                        raise InvalidInputError(f"triangulate: point {P[p].tolist()} lies outside the triangulation")
                    moved = True
                    break
                if o == 0:
                    if zero >= 0:
                        raise InvalidInputError(f"triangulate: point {P[p].tolist()} coincides with a vertex")
                    zero = j
            if not moved:
                return t, zero
        raise ConvergenceError(f"triangulate: locating point {P[p].tolist()} did not finish")  # pragma: no cover

    def insert_point(self, p: int, hint: int, fixed: set[tuple[int, int]]) -> None:
        """Insert point ``p`` (already added) by splitting its triangle (or edge) and Lawson flips (constraints never flip).

        Raises
        ------
        InvalidInputError
            The point lies on a constraint segment, on a vertex or outside the triangulation.
        """
        T, N = self.T, self.N
        t, j = self.locate(p, hint)
        if j < 0:  # inside t = (a, b, c): three triangles around p
            a, b, c = T[t]
            na, nb, nc = N[t]
            t1, t2 = len(T), len(T) + 1
            T[t] = [a, b, p]
            N[t] = [t1, t2, nc]
            T.append([b, c, p])
            N.append([t2, t, na])
            T.append([c, a, p])
            N.append([t, t1, nb])
            if na >= 0:
                N[na][N[na].index(t)] = t1
            if nb >= 0:
                N[nb][N[nb].index(t)] = t2
            vt = self.vt
            vt[a] = vt[b] = vt[p] = t
            vt[c] = t1
            self.legalize([(a, b), (b, c), (c, a)], fixed)
            return
        # On the edge u -> w of t1 = (u, w, s1), shared with t2 = (w, u, s2): four triangles around p.
        t1 = t
        u, w, s1 = T[t1][(j + 1) % 3], T[t1][(j + 2) % 3], T[t1][j]
        if (min(u, w), max(u, w)) in fixed:
            raise InvalidInputError(
                f"triangulate: point {self.P[p].tolist()} lies on constraint segment ({min(u, w)}, {max(u, w)})"
            )
        A = N[t1][(j + 1) % 3]  # across (w, s1)
        B = N[t1][(j + 2) % 3]  # across (s1, u)
        t2 = N[t1][j]
        if t2 < 0:  # pragma: no cover - the far corners keep every input point off the hull
            raise InvalidInputError(f"triangulate: point {self.P[p].tolist()} lies on the hull")
        k = T[t2].index(w)  # t2 = (w, u, s2) from w
        s2 = T[t2][(k + 2) % 3]
        C = N[t2][(k + 0) % 3]  # opposite w: across (u, s2)
        D = N[t2][(k + 1) % 3]  # opposite u: across (s2, w)
        t3, t4 = len(T), len(T) + 1
        T[t1] = [u, p, s1]
        N[t1] = [t3, B, t4]
        T.append([p, w, s1])
        N.append([A, t1, t2])
        T[t2] = [w, p, s2]
        N[t2] = [t4, D, t3]
        T.append([p, u, s2])
        N.append([C, t2, t1])
        if A >= 0:
            N[A][N[A].index(t1)] = t3
        if C >= 0:
            N[C][N[C].index(t2)] = t4
        vt = self.vt
        vt[u] = vt[s1] = vt[p] = t1
        vt[w] = t3
        vt[s2] = t2
        self.legalize([(w, s1), (s1, u), (u, s2), (s2, w)], fixed)

    def orient(self, a: int, b: int, c: int) -> int:
        P = self.P
        return orient2d(P[a], P[b], P[c])

    def points(self) -> np.ndarray:
        return self.P[: self.n_points]

    def triangle_with_edge(self, a: int, b: int) -> tuple[int, int]:
        """``(t, j)``: the triangle holding the directed edge ``a → b`` and its third vertex's local index (-1, -1: none)."""
        T, N = self.T, self.N
        start = t = self.vt[a]
        # Counter-clockwise around a (across the edge from a to the vertex before it), then, if
        # a hull vertex stops the turn, clockwise from the start.  A fan has fewer triangles than
        # the mesh: a longer walk means the neighbour table is corrupt, which must raise, not hang.
        for step in (1, 2):
            for _ in range(len(T) + 1):
                tri = T[t]
                i = tri.index(a)
                if tri[(i + 1) % 3] == b:
                    return t, (i + 2) % 3
                t = N[t][(i + step) % 3]
                if t == start:
                    return -1, -1
                if t < 0:
                    break
            else:
                raise ConvergenceError(f"triangulate: the triangles around vertex {a} do not close a fan "
                                       "(inconsistent neighbour table)")
            t = start
        return -1, -1

    def _present(self, u: int, w: int) -> bool:
        return self.triangle_with_edge(u, w)[0] >= 0 or self.triangle_with_edge(w, u)[0] >= 0

    def flip(self, t1: int, j1: int) -> tuple[int, int]:
        """Flip the edge of ``t1`` opposite its local vertex ``j1``; returns the new diagonal ``(s1, s2)``."""
        T, N = self.T, self.N
        s1 = T[t1][j1]
        p = T[t1][(j1 + 1) % 3]
        q = T[t1][(j1 + 2) % 3]
        t2 = N[t1][j1]
        tri2 = T[t2]
        j2 = tri2.index(next(v for v in tri2 if v != p and v != q))
        s2 = tri2[j2]
        n_a = N[t1][(j1 + 1) % 3]  # across (q, s1)
        n_b = N[t1][(j1 + 2) % 3]  # across (s1, p)
        # t2 = (s2, q, p) in counter-clockwise order starting at s2 (it holds the edge q -> p).
        m_a = N[t2][(j2 + 1) % 3]  # opposite q: across (p, s2)
        m_b = N[t2][(j2 + 2) % 3]  # opposite p: across (s2, q)
        T[t1] = [p, s2, s1]
        N[t1] = [t2, n_b, m_a]
        T[t2] = [s2, q, s1]
        N[t2] = [n_a, t1, m_b]
        if n_a >= 0:
            N[n_a][N[n_a].index(t1)] = t2
        if m_a >= 0:
            N[m_a][N[m_a].index(t2)] = t1
        vt = self.vt
        vt[p] = t1
        vt[s2] = t1
        vt[s1] = t1
        vt[q] = t2
        return s1, s2

    def crossed_edges(self, a: int, b: int) -> list[tuple[int, int]]:
        """Edges crossed by the open segment ``a b``, each as (left, right) of the directed line ``a → b``.

        Raises
        ------
        InvalidInputError
            An input point lies on the open segment.
        """
        T, N, P = self.T, self.N, self.P
        start = t = self.vt[a]
        while True:
            tri = T[t]
            i = tri.index(a)
            p, q = tri[(i + 1) % 3], tri[(i + 2) % 3]
            o1 = self.orient(a, p, b)
            o2 = self.orient(a, q, b)
            if o1 > 0 and o2 < 0:
                break
            for w, o in ((p, o1), (q, o2)):
                if o == 0 and np.dot(P[w] - P[a], P[b] - P[a]) > 0:
                    raise InvalidInputError(
                        f"triangulate: point {w} {P[w].tolist()} lies on constraint segment ({a}, {b})"
                    )
            t = N[t][(i + 1) % 3]
            if t < 0 or t == start:
                raise InvalidInputError(f"triangulate: cannot leave point {a} towards point {b}")
        left, right = q, p
        out = [(left, right)]
        t = N[t][i]
        while True:
            tri = T[t]
            r = next(v for v in tri if v != left and v != right)
            if r == b:
                return out
            o = self.orient(a, b, r)
            if o == 0:
                raise InvalidInputError(f"triangulate: point {r} {P[r].tolist()} lies on constraint segment ({a}, {b})")
            if o > 0:
                nxt = N[t][tri.index(left)]
                left = r
            else:
                nxt = N[t][tri.index(right)]
                right = r
            out.append((left, right))
            t = nxt
            if t < 0:
                raise InvalidInputError(f"triangulate: constraint segment ({a}, {b}) leaves the triangulation")

    def insert_segment(self, a: int, b: int, created: list[tuple[int, int]], fixed: set[tuple[int, int]]) -> None:
        """Make ``a b`` an edge by flips (Sloan 1993); appends the other edges created to ``created``.

        Raises
        ------
        InvalidInputError
            The segment crosses a constraint already in place (``fixed`` holds all of them).
        """
        crossed = self.crossed_edges(a, b)
        for u, w in crossed:
            if (min(u, w), max(u, w)) in fixed:
                P = self.P
                raise InvalidInputError(
                    f"triangulate: constraint segments ({a}, {b}) and ({u}, {w}) cross "
                    f"({P[a].tolist()}-{P[b].tolist()} and {P[u].tolist()}-{P[w].tolist()})"
                )
        queue = deque(crossed)
        limit = 50 * (len(queue) + 4) ** 2
        steps = 0
        while queue:
            steps += 1
            if steps > limit:
                raise ConvergenceError(f"triangulate: recovering segment ({a}, {b}) did not finish after {limit} flips")
            u, w = queue.popleft()
            t1, j1 = self.triangle_with_edge(u, w)
            if t1 < 0:
                t1, j1 = self.triangle_with_edge(w, u)
                u, w = w, u
            if t1 < 0:  # pragma: no cover - queued edges exist until flipped
                raise InvalidInputError(f"triangulate: lost edge ({u}, {w}) while recovering segment ({a}, {b})")
            s1 = self.T[t1][j1]
            t2 = self.N[t1][j1]
            s2 = next(v for v in self.T[t2] if v != u and v != w)
            # Strictly convex quadrilateral u, s2, w, s1: u and w strictly on both sides of s1 s2.
            if self.orient(s1, s2, u) * self.orient(s1, s2, w) >= 0:
                queue.append((u, w))
                continue
            self.flip(t1, j1)
            if {s1, s2} == {a, b}:
                continue
            if self.orient(a, b, s1) * self.orient(a, b, s2) < 0:
                queue.append((s1, s2))
            else:
                created.append((s1, s2))

    def legalize(self, edges: list[tuple[int, int]], fixed: set[tuple[int, int]]) -> None:
        """Lawson flips until the given edges (and those they touch) are locally Delaunay; ``fixed`` edges never flip."""
        P = self.P
        stack = list(edges)
        limit = 100 * (len(stack) + 10) ** 2
        steps = 0
        while stack:
            steps += 1
            if steps > limit:
                raise ConvergenceError(f"triangulate: Lawson flips did not finish after {limit} steps")
            u, w = stack.pop()
            if (min(u, w), max(u, w)) in fixed:
                continue
            t1, j1 = self.triangle_with_edge(u, w)
            if t1 < 0:
                continue
            t2 = self.N[t1][j1]
            if t2 < 0:
                continue
            s1 = self.T[t1][j1]
            s2 = next(v for v in self.T[t2] if v != u and v != w)
            if incircle(P[u], P[w], P[s1], P[s2]) > 0:
                self.flip(t1, j1)
                stack += [(u, s2), (s2, w), (w, s1), (s1, u)]

    def arrays(self) -> tuple[np.ndarray, np.ndarray]:
        return np.asarray(self.T, dtype=np.int64).reshape(-1, 3), np.asarray(self.N, dtype=np.int64).reshape(-1, 3)


def _delaunay(P: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Qhull's Delaunay triangulation of ``P`` plus four far corners, made counter-clockwise.

    Returns
    -------
    Q : (n + 4, 2) the points and the corners
    T, N : (m, 3) triangles and neighbours (``N[t, j]`` opposite ``T[t, j]``)
    flat : (f,) indices of zero-area triangles (Qhull's triangulated merged facets)
    dropped : (k,) indices of the points Qhull left out as near-duplicates at its precision
        (distinct in floating point: the caller inserts them with the exact predicates)

    Raises
    ------
    InvalidInputError
        Qhull fails.
    """
    lo, hi = P.min(axis=0), P.max(axis=0)
    size = float(np.max(hi - lo))
    if size == 0.0:
        raise InvalidInputError("triangulate: all points coincide")
    c = 0.5 * (lo + hi)
    r = 4.0 * size  # far enough that every input point is strictly interior
    corners = c + r * np.array([[-1.0, -1.0], [1.0, -1.0], [1.0, 1.0], [-1.0, 1.0]])
    Q = np.vstack([P, corners])
    n = P.shape[0]
    # scipy lists 2-D simplices counter-clockwise, so a clockwise one by the exact predicate is a
    # triangle Qhull folded over at its precision (boundary samples 1e-8 of the domain apart on a
    # nearly straight stretch): its output is then no triangulation.  The vertices of folded
    # triangles are left out and Qhull runs again on the rest; the left-out points join those Qhull
    # dropped itself, which the caller inserts with the exact predicates.
    keep = np.ones(n + 4, dtype=bool)
    for _ in range(_QHULL_RETRIES):
        idx = np.flatnonzero(keep)
        try:
            d = Delaunay(Q[idx])
        except QhullError as exc:  # pragma: no cover - Qhull rejects only degenerate input
            raise InvalidInputError(f"triangulate: Qhull failed: {exc}") from None
        T = idx[d.simplices.astype(np.int64)]
        s = _orient_signs(Q, T)
        if not np.any(s < 0):
            break
        folded = np.unique(T[s < 0])
        keep[folded[folded < n]] = False
    else:
        return (Q,) + _exact_delaunay(Q) + (np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64))
    N = d.neighbors.astype(np.int64)
    qhull_dropped = idx[d.coplanar[:, 0]] if d.coplanar.size else np.zeros(0, dtype=np.int64)
    dropped = np.union1d(qhull_dropped.astype(np.int64), np.flatnonzero(~keep))
    return Q, T, N, np.flatnonzero(s == 0), dropped


#: Qhull runs, each without the vertices of the triangles it folded the time before, before the
#: triangulation is built by exact incremental insertion alone.
_QHULL_RETRIES = 4


def _exact_delaunay(Q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Delaunay triangles and neighbours ``(m, 3)`` of ``Q`` (points, then the four far corners of
    :func:`_delaunay` counter-clockwise) by Lawson's incremental insertion with the exact predicates.

    The last resort when Qhull keeps folding triangles; Python-level work per point (and a seeded
    random order, whose expected number of flips per point is constant), so it is kept for rare inputs.
    """
    n = Q.shape[0] - 4
    c = n + np.arange(4)
    T = np.array([[c[0], c[1], c[2]], [c[0], c[2], c[3]]], dtype=np.int64)
    N = np.array([[-1, 1, -1], [-1, -1, 0]], dtype=np.int64)
    mesh = _Mesh(Q, T, N)
    order = np.random.default_rng(0).permutation(n)
    hint = 0
    fixed: set[tuple[int, int]] = set()
    for p in order.tolist():
        mesh.insert_point(p, hint, fixed)
        hint = mesh.vt[p]
    return mesh.arrays()


def _remove_flat(mesh: _Mesh, flat: np.ndarray) -> None:
    """Flip away zero-area triangles (Qhull's triangulated merged facets): flip each one's longest edge.

    A flat triangle ``(a, c, b)`` with ``c`` between ``a`` and ``b`` shares ``a b`` with a
    proper triangle ``(b, a, d)``; flipping ``a b`` to ``c d`` leaves two proper triangles.

    Raises
    ------
    InvalidInputError
        A flat triangle that cannot be removed.
    """
    P = mesh.P
    todo = deque(int(t) for t in flat)
    guard = 0
    while todo:
        guard += 1
        if guard > 100 * (len(flat) + 10):
            raise InvalidInputError("triangulate: cannot remove the flat triangles of Qhull's output")
        t = todo.popleft()
        tri = mesh.T[t]
        if orient2d(P[tri[0]], P[tri[1]], P[tri[2]]) != 0:
            continue
        lengths = [float(np.sum((P[tri[(j + 1) % 3]] - P[tri[(j + 2) % 3]]) ** 2)) for j in range(3)]
        j = int(np.argmax(lengths))
        t2 = mesh.N[t][j]
        if t2 < 0:
            raise InvalidInputError("triangulate: a flat triangle lies on the hull")
        mesh.flip(t, j)
        for tt in (t, t2):
            a, b, c = mesh.T[tt]
            if orient2d(P[a], P[b], P[c]) <= 0:
                todo.append(tt)


# ---------------------------------------------------------------------- public
class ConstrainedDelaunay:
    """A constrained Delaunay triangulation kept for refinement by point insertion.

    Built like :func:`triangulate` (same parameters, same exceptions); :meth:`insert` adds
    interior points one by one (Lawson's incremental insertion: split the containing triangle
    or edge, then flip until locally Delaunay, constraints never flipped), which costs far less
    than triangulating again when a few points are added.  Inserted points take the indices
    ``n, n + 1, ...`` after the ``n`` initial points.
    """

    def __init__(self, points, segments) -> None:
        P, S = _validated(points, segments)
        n = P.shape[0]
        self.n, self.S = n, S
        Q, T, N, flat, dropped = _delaunay(P)
        m_all = np.int64(n + 4)
        s_lo, s_hi = np.minimum(S[:, 0], S[:, 1]), np.maximum(S[:, 0], S[:, 1])
        self.fixed: set[tuple[int, int]] = set(zip(s_lo.tolist(), s_hi.tolist()))
        missing = np.zeros(0, dtype=np.int64)
        if S.shape[0]:
            # Constraints already present in either direction (undirected keys).
            e_lo = np.minimum(T, T[:, [1, 2, 0]]).ravel()
            e_hi = np.maximum(T, T[:, [1, 2, 0]]).ravel()
            missing = np.flatnonzero(~np.isin(s_lo * m_all + s_hi, e_lo * m_all + e_hi))
        self._mesh: _Mesh | None = None
        self._Q, self._T, self._N = Q, T, N
        if dropped.size:
            # Qhull's precision merged them with a neighbour; they are distinct points, placed by Lawson
            # insertion with the exact predicates (which raise for a point on a vertex or a constraint).
            mesh = self._mutable()
            if flat.size:
                _remove_flat(mesh, flat)
                flat = np.zeros(0, dtype=np.int64)
            for p in dropped.tolist():
                mesh.insert_point(p, 0, self.fixed)
            T, _ = mesh.arrays()
            e_lo = np.minimum(T, T[:, [1, 2, 0]]).ravel()
            e_hi = np.maximum(T, T[:, [1, 2, 0]]).ravel()
            missing = np.flatnonzero(~np.isin(s_lo * m_all + s_hi, e_lo * m_all + e_hi))
        if flat.size or missing.size:
            mesh = self._mutable()
            if flat.size:
                _remove_flat(mesh, flat)
            created: list[tuple[int, int]] = []
            for i in missing:
                a, b = int(S[i, 0]), int(S[i, 1])
                if mesh._present(a, b):
                    continue  # recovered as a side effect of an earlier segment
                mesh.insert_segment(a, b, created, self.fixed)
            if created:
                mesh.legalize(created, self.fixed)

    def _mutable(self) -> _Mesh:
        if self._mesh is None:
            self._mesh = _Mesh(self._Q, self._T, self._N)
        return self._mesh

    def _arrays(self) -> tuple[np.ndarray, np.ndarray, int]:
        if self._mesh is None:
            return self._T, self._N, self._Q.shape[0]
        T, N = self._mesh.arrays()
        return T, N, self._mesh.n_points

    def triangles(self, *, return_all: bool = False, return_index: bool = False):
        """Counter-clockwise triangles ``(m, 3)`` of the region left of the constraints (see :func:`triangulate`).

        With ``return_index`` also their ``(m,)`` ids in the triangulation, the hints :meth:`insert` takes.
        """
        T, N, n_all = self._arrays()
        n = self.n
        corner = (T >= n) & (T < n + 4)
        if return_all:
            keep = ~np.any(corner, axis=1)
        elif self.S.shape[0] == 0:
            keep = np.zeros(T.shape[0], dtype=bool)
        else:
            keep = _inside(T, N, self.S, n, n_all)
        idx = np.flatnonzero(keep)
        out = T[idx]
        out = np.where(out >= n + 4, out - 4, out)  # inserted points follow the input points
        return (out, idx) if return_index else out

    def insert(self, points, hints=None) -> np.ndarray:
        """Insert interior points ``(k, 2)``; ``hints (k,)``: triangle ids near each (from ``triangles(return_index=True)``).

        Returns
        -------
        (k,) int64: the indices of the new points.

        Raises
        ------
        InvalidInputError
            A point outside the triangulation, on a vertex or on a constraint segment.
        """
        X = np.asarray(points, dtype=np.float64).reshape(-1, 2)
        if not np.all(np.isfinite(X)):
            raise InvalidInputError("triangulate: inserted points contain NaN or inf")
        mesh = self._mutable()
        h = np.zeros(X.shape[0], dtype=np.int64) if hints is None else np.asarray(hints, dtype=np.int64)
        out = np.empty(X.shape[0], dtype=np.int64)
        for i in range(X.shape[0]):
            p = mesh.add_point(X[i])
            try:
                mesh.insert_point(p, int(h[i]) if 0 <= h[i] < len(mesh.T) else 0, self.fixed)
            except InvalidInputError:
                mesh.n_points -= 1  # nothing was linked yet: forget the point
                mesh.vt.pop()
                raise
            out[i] = p - 4
        return out


def triangulate(points, segments, *, return_all: bool = False) -> np.ndarray:
    """Constrained Delaunay triangulation of the region on the left of oriented constraint loops.

    Parameters
    ----------
    points : (n, 2) array_like of float
        Distinct points.
    segments : (k, 2) array_like of int
        Directed constraint segments ``(a, b)`` (indices into ``points``) forming closed
        loops that keep the region on their left: outer boundaries counter-clockwise, holes
        clockwise.  Points not on a segment are interior points; those outside every loop
        are simply left out.
    return_all : bool
        Return every triangle of the constrained triangulation whose corners are input
        points instead (no removal; needs no loops).  Near the convex hull a sliver whose
        circumcircle reaches the far corners of step 1 may be missing.

    Returns
    -------
    (m, 3) int64
        Counter-clockwise triangles; every segment is an edge of exactly one of them (of
        two with ``return_all``).

    Raises
    ------
    InvalidInputError
        Malformed arrays, coincident points (exactly equal: near-duplicates are inserted), a
        segment through another point, crossing segments, or loops whose sides contradict
        (the same region both left and right of constraints).
    ConvergenceError
        The flip loops exceed their (quadratic) step bounds, which valid input never does.

    Examples
    --------
    >>> square_with_centre = [[0, 0], [1, 0], [1, 1], [0, 1], [0.5, 0.5]]
    >>> triangulate(square_with_centre, [[0, 1], [1, 2], [2, 3], [3, 0]]).shape
    (4, 3)
    """
    return ConstrainedDelaunay(points, segments).triangles(return_all=return_all)


#: Triangulations up to this many triangles label their components by min-label propagation in numpy
#: (:func:`_small_components`), which costs far less than building a sparse graph for scipy.
_SMALL_COMPONENTS = 4096
#: Rounds of min-label propagation before handing over to scipy (a long thin mesh has a large diameter).
_PROPAGATION_ROUNDS = 48


def _small_components(N: np.ndarray, link: np.ndarray) -> tuple[int, np.ndarray] | None:
    """Connected components ``(count, label (m,))`` of triangles joined across the edges where ``link (m, 3)`` holds
    (``N (m, 3)`` the neighbours), or None when :data:`_PROPAGATION_ROUNDS` rounds do not settle.

    Min-label propagation with pointer jumping: every label is the index of a triangle of the same
    component and never above its own index, so a fixed point (labels equal across every link) gives
    each component its smallest index (Shiloach & Vishkin's hooking and shortcutting, synchronously).
    """
    m = N.shape[0]
    nb = np.where(link, N, np.arange(m)[:, None])
    label = np.arange(m)
    for _ in range(_PROPAGATION_ROUNDS):
        new = np.minimum(label, label[nb].min(axis=1))
        new = new[new]
        if np.array_equal(new, label):
            roots, label = np.unique(label, return_inverse=True)
            return roots.size, label
        label = new
    return None


def _inside(T: np.ndarray, N: np.ndarray, S: np.ndarray, n: int, n_all: int) -> np.ndarray:
    """Mask of the triangles left of the constraints: components of the adjacency cut at constraints, seeded by sides.

    ``n`` input points, then the four far corners, then inserted points (``n_all`` in all).
    """
    m = T.shape[0]
    big = np.int64(n_all)
    # Edge opposite local vertex j is (T[j+1], T[j+2]).
    ea = T[:, [1, 2, 0]]
    eb = T[:, [2, 0, 1]]
    und = np.minimum(ea, eb) * big + np.maximum(ea, eb)
    s_und = np.minimum(S[:, 0], S[:, 1]) * big + np.maximum(S[:, 0], S[:, 1])
    cut = np.isin(und, s_und)
    tri = np.repeat(np.arange(m), 3).reshape(m, 3)
    link = (~cut) & (N >= 0)
    found = _small_components(N, link) if m <= _SMALL_COMPONENTS else None
    if found is None:
        g = coo_matrix((np.ones(int(link.sum())), (tri[link], N[link])), shape=(m, m))
        found = connected_components(g, directed=False)
    n_comp, label = found
    # Directed triangle edges a -> b (counter-clockwise): the triangle lies on the left of a -> b.
    d_key = (ea * big + eb).ravel()
    d_tri = tri.ravel()
    order = np.argsort(d_key)
    d_key, d_tri = d_key[order], d_tri[order]

    def tri_of(keys: np.ndarray) -> np.ndarray:
        pos = np.searchsorted(d_key, keys)
        pos = np.minimum(pos, d_key.size - 1)
        found = d_key[pos] == keys
        if not np.all(found):  # pragma: no cover - every constraint is an edge after recovery
            k = int(np.flatnonzero(~found)[0])
            raise InvalidInputError(f"triangulate: constraint segment {S[k].tolist()} is not an edge of the triangulation")
        return d_tri[pos]

    fwd = S[:, 0] * big + S[:, 1]
    rev = S[:, 1] * big + S[:, 0]
    left = tri_of(fwd)
    # A segment given in both directions (a slit) has the region on both sides.
    one_way = ~np.isin(rev, fwd)
    right = tri_of(rev[one_way])
    inside = np.zeros(n_comp, dtype=bool)
    outside = np.zeros(n_comp, dtype=bool)
    inside[label[left]] = True
    outside[label[right]] = True
    # Triangles touching the far corners are outside whatever the loops say.
    outside[label[np.any((T >= n) & (T < n + 4), axis=1)]] = True
    both = np.flatnonzero(inside & outside)
    if both.size:
        c = int(both[0])
        bad = np.flatnonzero(label[left] == c)
        raise InvalidInputError(
            "triangulate: the constraint loops contradict each other (a region is both left and right of them: "
            f"crossing loops or inconsistent orientation), e.g. near segment {S[bad[0]].tolist() if bad.size else '?'}"
        )
    return inside[label]
