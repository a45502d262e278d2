"""Polyhedral solids from closed triangle meshes, with the winged-edge tables built in array time.

:func:`from_mesh` turns a closed, manifold, consistently oriented triangle mesh into a
:class:`~coons.topology.shape.Solid` whose faces are implicit planes (``face_surface = -1``)
and whose edges are straight segments (``edge_curve = -1``).  The winged-edge tables are
computed directly with numpy — directed half-edges from the triangles, twins by sorting the
``(min, max)`` vertex pairs, ``next``/``prev`` inside each triangle, shells as the connected
components of the triangle adjacency (``scipy.sparse.csgraph``) — instead of looping
:meth:`~coons.topology.builder.BRepBuilder.assemble` over the triangles.  The tables are
identical to those ``assemble`` + ``build`` make (a test compares them column by column), and
:func:`~coons.topology.check.check` then verifies every invariant, Euler–Poincaré included, as
``build`` would.  A million triangles take about 1 s for the tables and 1.5 s for the check on
a busy 2-core machine.

With ``merge_coplanar=True`` neighbouring coplanar triangles are merged into polygon faces
(with holes where a flat region surrounds another one) before checking.

The module does **not** repair meshes.  Open meshes, non-manifold edges, inconsistently
oriented neighbours and degenerate triangles raise :class:`~coons.errors.TopologyError`
naming the first offender (by the caller's vertex and triangle indices, with coordinates);
non-manifold vertices and every other invariant are reported by the checker.  Near-duplicate
vertices are the caller's business.  Three things are normalised, documented here:

* vertices with bit-identical coordinates are merged (``-0.0 == 0.0``), and vertices no
  triangle uses are dropped (they bound nothing);
* a whole component (shell) whose orientation disagrees with its nesting is reversed with a
  :class:`UserWarning`: components nested inside an odd number of others are voids and must
  enclose negative volume, all others positive (the even–odd rule of STL solids);
* with ``merge_coplanar``, a flat region whose vertices turn out to be more than
  ``tol.linear`` off its best plane is left as triangles.

Self-intersecting meshes (two shells crossing, a fold-over inside one shell) are not detected.

Speed notes for successors: row gathers of 2-D arrays use ``np.take(A, idx, axis=0)`` and
``np.compress(mask, A, axis=0)`` — with numpy 2.4 advanced indexing ``A[idx]`` of an ``(n, 3)``
array is 4 to 40 times slower at 1e5 rows (1-D gathers ``x[idx]`` are not affected); half-edges
are paired by one value sort of keys with their position packed below (:func:`_stable_sort`),
not by a stable argsort.  The construction for the polyhedral Booleans
(:func:`_solid_from_clean_triangles`, with the twins and the connected groups (patches) the
Booleans already know) is about two fifths of a Boolean at 1e5 triangles (some 60 ms of the
~146 ms union of ``benchmarks/bench_booleans_mesh.py``, best of interleaved runs on a shared
2-core machine), about a quarter of it in :func:`~coons.topology.check.check`.  Avoid
``T[:, [1, 2, 0]].ravel()`` and ``A[:, [i, j]].ravel()`` (strided copies, use
:func:`~coons.kernel._common.next_corners`, ``prev_corners``, ``interleaved_columns``),
``np.unique`` / ``np.isin`` where a scatter into a mask gives the answer (``used_ids``) and
axis-0 reductions of ``(n, 3)`` arrays (use ``column_min`` / ``column_max``): all are 10-40 times
slower at 1e5 rows.
"""

from __future__ import annotations

import warnings

import numpy as np

from coons.errors import InvalidInputError, TopologyError
from coons.kernel._common import column_max, column_min, interleaved_columns, next_corners, prev_corners, used_ids
from coons.tolerance import Tolerance, resolve
from coons.topology.brep import BRep
from coons.topology.shape import Solid

__all__ = ["from_mesh"]

#: Largest |coordinate| for which the exact coplanarity predicate is used: coordinate differences
#: are integers below 2**16, a triangle normal's components (differences of two products) below
#: 2**33, and its dot product with a difference below 3 * 2**49 < 2**53 — every intermediate of the
#: orientation determinant is an integer held exactly in float64.
_EXACT_COORD_LIMIT = 2.0**15


def from_mesh(
    vertices,
    triangles=None,
    *,
    merge_coplanar: bool = False,
    tol: Tolerance | None = None,
) -> Solid:
    """A polyhedral solid bounded by a closed triangle mesh.

    Parameters
    ----------
    vertices : (n, 3) array_like of float, or a mesh object
        Vertex positions.  An object with ``.vertices`` and ``.faces`` arrays (a
        ``trimesh.Trimesh``) or ``.vertices`` and ``.triangles`` (a
        :class:`~coons.topology.mesh.TriangleMesh`) may be passed instead, with ``triangles``
        omitted.
    triangles : (m, 3) array_like of int
        Vertex indices of each triangle, counter-clockwise seen from outside (right-hand
        rule: the normal ``(b - a) × (c - a)`` points out of the solid).
    merge_coplanar : bool
        Merge neighbouring coplanar triangles into polygon faces (see :func:`_merge_coplanar`
        for the coplanarity test: exact for integer coordinates below 2**15, else within
        ``tol.linear``).
    tol : Tolerance, optional
        ``tol.linear`` decides degenerate triangles (height not above it), coplanarity of
        non-integer inputs, and becomes the vertex and edge tolerance of the result.

    Returns
    -------
    Solid
        One lump per outer shell; shells nested at odd depth are voids of the shell around them.
        Faces are numbered like the triangles (without ``merge_coplanar``); vertices keep the
        order of their first occurrence in ``vertices``.

    Raises
    ------
    InvalidInputError
        Wrong shapes, non-finite coordinates, non-integer or out-of-range indices, no triangles.
    TopologyError
        A degenerate triangle, an open mesh (an edge used by one triangle), a non-manifold
        edge (used by more than two), two neighbours running their shared edge the same way,
        a component enclosing no volume, components that contain each other, or any
        invariant the checker finds (non-manifold vertices, for instance).

    Warns
    -----
    UserWarning
        When a component was reversed to agree with its nesting (see the module docstring).

    Examples
    --------
    >>> tet = from_mesh([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]],
    ...                 [[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])
    >>> tet.brep.n_faces, tet.brep.n_edges, tet.brep.n_vertices, bool(np.isclose(tet.volume, 1 / 6))
    (4, 6, 4, True)
    """
    t = resolve(tol)
    P, T = _as_arrays(vertices, triangles)
    P, T, orig = _merge_identical(P, T)
    _reject_degenerate(P, T, orig, t)
    a, b = _pair_half_edges(P, T, orig)
    labels, n_comp = _components(T.shape[0], a // 3, b // 3)
    depth, parent = _nesting(P, T, labels, n_comp)
    flip = _orientation(P, T, labels, n_comp, depth)
    if np.any(flip):
        flipped = np.flatnonzero(flip)
        warnings.warn(
            f"from_mesh: reversed the triangles of {flipped.size} component(s) (component ids "
            f"{flipped[:10].tolist()}{' ...' if flipped.size > 10 else ''}) so that outer shells enclose "
            "positive and voids negative volume",
            UserWarning,
            stacklevel=2,
        )
        rev = flip[labels]
        T = T.copy()
        T[rev] = T[rev][:, [0, 2, 1]]
        a, b = _pair_half_edges(P, T, orig)
    cols = _tables(P, T, a, b, labels, n_comp, depth, parent, t)
    if merge_coplanar:
        cols = _merge_coplanar(cols, P, T, a, b, t)
    brep = BRep(**cols)
    from coons.topology.check import check

    report = check(brep, t)
    if not report.ok:
        lines = [str(p) for p in report.problems[:20]]
        for p in report.problems[:20]:
            if p.entity == "vertex" and p.index < orig.size:
                lines.append(f"  vertex {p.index} is input vertex {int(orig[p.index])} at {P[p.index].tolist()}")
        raise TopologyError("from_mesh: the mesh does not bound a valid solid:\n" + "\n".join(lines))
    return Solid(brep)


def _solid_from_clean_triangles(P: np.ndarray, T: np.ndarray, t: Tolerance, *, merge_coplanar: bool = True,
                                straighten: bool = False, no_sheets: bool = False,
                                twin: np.ndarray | None = None, groups: np.ndarray | None = None) -> Solid:
    """:func:`from_mesh` for callers that guarantee their mesh is clean (the polyhedral Booleans).

    Preconditions, not re-verified: ``P (n, 3)`` finite float64 with every vertex used by ``T``;
    ``T (m, 3)`` int64 indices into ``P`` with no degenerate triangle (height above
    ``t.linear``).  Skipping :func:`from_mesh`'s input normalisation (bit-identical vertices are
    **not** merged: distinct vertices stay distinct) and degenerate-triangle test, it runs the same
    construction and verifies what the construction could get wrong: every edge used twice in
    opposite directions (raises as :func:`from_mesh`), nesting, the orientation of every
    component (a component that would need reversing raises instead of being reversed), planar
    merged regions, and the topological checks of :func:`~coons.topology.check.check`
    (pointers, loops, manifold vertices, Euler–Poincaré per shell).  The geometric checks of
    ``check`` are not run: every edge is the straight segment between its vertices (nothing can
    deviate), merged faces are verified planar within ``t.linear`` here, and shell orientation is
    the volume test above.  ``straighten`` (with ``merge_coplanar``) also removes the vertices
    left on straight boundaries between merged faces (:func:`_remove_straight_vertices`).
    ``no_sheets`` also rejects components thinner than ``t.linear`` on average (``|volume| <=
    t.linear · area``: two facing triangulations of one patch left by touching operands).
    ``twin (3 m,)`` int64, optional: the twin of each half-edge where the caller knows it, -1
    elsewhere (:func:`_pair_known_half_edges`: the known pairs are verified, the others sorted).
    ``groups (m,)`` int64, optional: labels ``>= 0`` such that the triangles sharing a label are
    connected through shared edges (the caller's guarantee: the polyhedral Booleans pass the patch of
    each piece); the components are then those of the small graph of labels joined by an edge
    (:func:`_components`), instead of a labelling of every triangle.

    Raises
    ------
    TopologyError
        As :func:`from_mesh`; "encloses volume of the wrong sign" for a component whose
        orientation disagrees with its nesting.
    """
    orig = np.arange(P.shape[0])
    dst = next_corners(T)  # the end of each half-edge, computed once for the pairing and the merge
    a, b = _pair_half_edges(P, T, orig, dst=dst) if twin is None else _pair_known_half_edges(P, T, twin, dst)
    labels, n_comp = _components(T.shape[0], a // 3, b // 3, groups)
    depth, parent = _nesting(P, T, labels, n_comp)
    columns = _columns(P, T)
    flip = _orientation(P, T, labels, n_comp, depth, thin=t.linear if no_sheets else 0.0, columns=columns)
    if np.any(flip):
        k = int(np.flatnonzero(flip)[0])
        raise TopologyError(
            f"component {k} encloses volume of the wrong sign for its nesting depth {int(depth[k])} "
            f"(outer shells must enclose positive and voids negative volume); {int(flip.sum())} such component(s)"
        )
    if merge_coplanar:
        # _merge_coplanar needs only these columns of the triangle tables; the full tables are made
        # only when nothing merges.
        org = T.ravel()
        h0 = np.where(org[a] < dst[a], a, b)
        shell_solid, solid_ptr, solid_shells = _solids(n_comp, depth, parent)
        few = dict(edge_vertex=np.stack([org[h0], dst[h0]], axis=1), face_shell=labels, shell_solid=shell_solid,
                   solid_shell_ptr=solid_ptr, solid_shells=solid_shells)
        cols = _merge_coplanar(few, P, T, a, b, t, straighten=straighten, columns=columns, dst=dst)
        if cols is few:
            cols = _tables(P, T, a, b, labels, n_comp, depth, parent, t)
    else:
        cols = _tables(P, T, a, b, labels, n_comp, depth, parent, t)
    brep = BRep(**cols)
    from coons.topology.check import check

    report = check(brep, t, geometry=False)
    if not report.ok:
        raise TopologyError("from_mesh: the mesh does not bound a valid solid:\n" + report.summary(20))
    return Solid(brep)


# ====================================================================== input
def _as_arrays(vertices, triangles) -> tuple[np.ndarray, np.ndarray]:
    """Validated ``(n, 3) float64`` vertices and ``(m, 3) int64`` triangles.

    Raises
    ------
    InvalidInputError
        See :func:`from_mesh`.
    """
    if triangles is None:
        V = getattr(vertices, "vertices", None)
        F = getattr(vertices, "faces", None)
        if F is None:
            F = getattr(vertices, "triangles", None)
        if V is None or F is None:
            raise InvalidInputError(
                "from_mesh needs vertices and triangles arrays, or one object with .vertices and "
                f".faces (or .triangles); got {type(vertices).__name__} without triangles"
            )
        vertices, triangles = V, F
    try:
        P = np.array(vertices, dtype=np.float64)
    except (TypeError, ValueError):
        raise InvalidInputError(f"vertices must be an (n, 3) array of numbers, got {type(vertices).__name__}") from None
    if P.ndim != 2 or P.shape[1] != 3:
        raise InvalidInputError(f"vertices must have shape (n, 3), got {P.shape}")
    if not np.all(np.isfinite(P)):
        i = int(np.flatnonzero(~np.all(np.isfinite(P), axis=1))[0])
        raise InvalidInputError(f"vertices must be finite; vertex {i} is {P[i].tolist()}")
    Ti = np.asarray(triangles)
    if Ti.ndim != 2 or Ti.shape[1] != 3:
        raise InvalidInputError(f"triangles must have shape (m, 3), got {Ti.shape}")
    if Ti.shape[0] == 0:
        raise InvalidInputError("triangles is empty; a solid needs at least 4 triangles")
    if Ti.dtype.kind not in "iu":
        if Ti.dtype.kind != "f" or not np.all(Ti == np.round(Ti)):
            raise InvalidInputError(f"triangles must hold integer vertex indices, got dtype {Ti.dtype}")
    T = Ti.astype(np.int64)
    bad = np.flatnonzero(np.any((T < 0) | (T >= P.shape[0]), axis=1))
    if bad.size:
        i = int(bad[0])
        raise InvalidInputError(
            f"triangle {i} has vertex indices {T[i].tolist()}; expected indices in 0..{P.shape[0] - 1}"
        )
    return P, T


def _merge_identical(P: np.ndarray, T: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Merge bit-identical vertices and drop unused ones.

    Returns
    -------
    P : (n', 3) float64, the kept vertices in the order of their first occurrence
    T : (m, 3) int64, remapped triangles
    orig : (n',) int64, the caller's index of each kept vertex (its first occurrence)
    """
    P = P + 0.0  # -0.0 becomes 0.0: identical coordinates compare equal bitwise and numerically
    n = P.shape[0]
    order = np.lexsort((P[:, 2], P[:, 1], P[:, 0]))
    Ps = np.take(P, order, axis=0)  # np.take: row gathers several times faster than P[order]
    new = np.ones(n, dtype=bool)
    new[1:] = np.any(Ps[1:] != Ps[:-1], axis=1)
    starts = np.flatnonzero(new)
    group = np.empty(n, dtype=np.int64)
    group[order] = np.cumsum(new) - 1
    rep = np.minimum.reduceat(order, starts)  # first occurrence of each distinct point
    used = np.zeros(starts.size, dtype=bool)
    used[group[T]] = True
    keep = np.flatnonzero(used)
    keep = keep[np.argsort(rep[keep], kind="stable")]
    new_id = np.full(starts.size, -1, dtype=np.int64)
    new_id[keep] = np.arange(keep.size)
    orig = rep[keep]
    return np.take(P, orig, axis=0), new_id[group[T]], orig


def _reject_degenerate(P: np.ndarray, T: np.ndarray, orig: np.ndarray, t: Tolerance) -> None:
    """Raise on the first triangle whose height is not above ``t.linear`` (zero area within tolerance).

    The height ``2 area / longest side`` is the distance of the farthest vertex from the line
    through the other two: at most ``t.linear`` means the three points are collinear within
    the tolerance (and a repeated vertex gives 0).
    """
    A, B, C = (np.take(P, T[:, k], axis=0) for k in range(3))
    area2 = np.linalg.norm(np.cross(B - A, C - A), axis=1)
    longest = np.sqrt(np.max(np.stack([((B - A) ** 2).sum(1), ((C - B) ** 2).sum(1), ((A - C) ** 2).sum(1)]), axis=0))
    height = np.divide(area2, longest, out=np.zeros_like(area2), where=longest > 0)
    bad = np.flatnonzero(height <= t.linear)
    if bad.size:
        i = int(bad[0])
        raise TopologyError(
            f"triangle {i} (vertices {orig[T[i]].tolist()} at {P[T[i]].tolist()}) is degenerate: its height "
            f"{height[i]:.3g} is not above the linear tolerance {t.linear:g}"
        )


# ====================================================================== half-edges
def _pair_half_edges(P: np.ndarray, T: np.ndarray, orig: np.ndarray,
                     subset: np.ndarray | None = None, dst: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Twin half-edges: half-edge ``h = 3 t + k`` runs from ``T[t, k]`` to ``T[t, (k + 1) % 3]``.

    ``subset``, optional: increasing half-edge ids to pair among themselves (every other half-edge
    is left out).  ``dst``, optional: ``next_corners(T)`` when the caller has it.

    Half-edges are sorted by their undirected key ``min · n + max`` (stable, :func:`_stable_sort`, so each group
    lists its half-edges in triangle order); every group must hold exactly two half-edges
    running in opposite directions.

    Returns
    -------
    a, b : (E,) int64, the two half-edges of each edge, ``a < b``, edges sorted by key.

    Raises
    ------
    TopologyError
        For the bad edge met first in triangle order: used once (open mesh), more than twice
        (non-manifold), or twice in the same direction (inconsistent orientation).
    """
    n = P.shape[0]
    org = T.ravel()
    dst = next_corners(T) if dst is None else dst
    if subset is None:
        key = np.minimum(org, dst) * n + np.maximum(org, dst)
        order, ks = _stable_sort(key)
    else:
        o, d = org[subset], dst[subset]
        order, ks = _stable_sort(np.minimum(o, d) * n + np.maximum(o, d))
        order = subset[order]  # subset is increasing: the order stays stable
    if ks.size == 0:
        return np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64)
    start = np.flatnonzero(np.concatenate([[True], ks[1:] != ks[:-1]]))
    count = np.diff(np.append(start, ks.size))
    a = order[start]
    b = order[np.minimum(start + 1, ks.size - 1)]
    bad = (count != 2) | (org[a] == org[b])
    if np.any(bad):
        g = np.flatnonzero(bad)
        g = int(g[np.argmin(a[g])])
        h = order[start[g] : start[g] + count[g]]
        tri = (h // 3).tolist()
        v0, v1 = int(org[h[0]]), int(dst[h[0]])
        where = (
            f"the edge between vertices {int(orig[v0])} {P[v0].tolist()} and {int(orig[v1])} {P[v1].tolist()}"
        )
        if count[g] == 1:
            raise TopologyError(
                f"the mesh is open: {where} is used by one triangle ({tri[0]}); a closed mesh uses every edge twice"
            )
        if count[g] > 2:
            raise TopologyError(
                f"non-manifold edge: {where} is used by {int(count[g])} triangles {tri}; expected 2"
            )
        raise TopologyError(
            f"inconsistent orientation: triangles {tri[0]} and {tri[1]} both run {where} from vertex "
            f"{int(orig[v0])} to {int(orig[v1])}; neighbours must run a shared edge in opposite directions"
        )
    return a, b


def _pair_known_half_edges(P: np.ndarray, T: np.ndarray, twin: np.ndarray,
                           dst: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """:func:`_pair_half_edges` when the caller knows most twins: ``twin (3 m,)`` int64, -1 where unknown.

    The known pairs are verified in array time — an involution without fixed points whose pairs
    run between the same two vertices in opposite directions — and the unknown half-edges are
    paired by sorting, with :func:`_pair_half_edges`'s checks and messages.  That no known pair
    shares its two vertices with another edge is the caller's guarantee (the polyhedral Booleans:
    :func:`coons.booleans.polyhedral._known_twins`).

    Returns
    -------
    a, b : (E,) int64, the two half-edges of each edge, ``a < b``, edges in increasing ``a``.

    Raises
    ------
    TopologyError
        As :func:`_pair_half_edges`; a known pair that is not a pair of opposite half-edges.
    """
    org = T.ravel()
    dst = next_corners(T) if dst is None else dst  # optional: the caller's next_corners(T)
    h = np.flatnonzero(twin >= 0)
    g = twin[h]
    # dst[g] == org[h] needs no test of its own: twin[g] == h for every h makes g one of the h, and
    # the test org[twin[g]] == dst[g] at g is that one.  twin and org side by side: one row gather
    # (one cache line) per scattered g instead of two.
    TO = np.empty((twin.size, 2), dtype=np.int64)
    TO[:, 0] = twin
    TO[:, 1] = org
    R = np.take(TO, g, axis=0)
    bad = (g == h) | (R[:, 0] != h) | (R[:, 1] != dst[h])
    if np.any(bad):
        i = int(h[np.argmax(bad)])
        raise TopologyError(
            f"internal: half-edge {i} (triangle {i // 3}) was given twin {int(twin[i])}, which does not run the "
            "same edge the other way"
        )
    a1, b1 = _pair_half_edges(P, T, np.arange(P.shape[0]), subset=np.flatnonzero(twin < 0), dst=dst)
    full = twin.copy()
    full[a1], full[b1] = b1, a1
    a = np.flatnonzero(full > np.arange(full.size))
    return a, full[a]


def _stable_sort(key: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``order = argsort(key, stable)`` and ``key[order]`` for non-negative int64 keys.

    When ``max(key) · 2**bits(size)`` fits in int64 the position is packed below the key's bits and one plain
    value sort does the work: several times faster than a stable argsort (a merge sort on
    int64), and the packed position breaks ties in input order, so the result is the stable one.
    """
    k = key.size
    if k == 0:
        return np.zeros(0, dtype=np.int64), key
    bits = k.bit_length()
    if int(key.max()) < 2 ** (62 - bits):
        packed = np.sort((key << bits) | np.arange(k, dtype=np.int64))
        return packed & ((1 << bits) - 1), packed >> bits
    order = np.argsort(key, kind="stable")
    return order, key[order]


def _components(m: int, ta: np.ndarray, tb: np.ndarray, groups: np.ndarray | None = None) -> tuple[np.ndarray, int]:
    """Connected components of the triangle adjacency (triangles ``ta[i]``, ``tb[i]`` share an edge).

    ``groups (m,)`` int64, optional: labels ``>= 0`` of sets of triangles known to be connected
    (see :func:`_solid_from_clean_triangles`).  The components are then found on the labels joined
    by the edges between two labels (a few, where a Boolean's patches meet), one gather per edge
    end instead of a graph of every triangle; components are numbered in the order of their
    smallest label, not of their first triangle.
    """
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    if groups is None:
        g = coo_matrix((np.ones(ta.size, dtype=np.int8), (ta, tb)), shape=(m, m)).tocsr()
        n_comp, labels = connected_components(g, directed=False)
        return labels.astype(np.int64), int(n_comp)
    if groups.shape != (m,):
        raise InvalidInputError(f"groups must have shape ({m},), got {groups.shape}")
    if m == 0:
        return np.zeros(0, dtype=np.int64), 0
    if int(groups.min()) < 0:
        raise InvalidInputError(f"groups must be labels >= 0, got {int(groups.min())}")
    n_g = int(groups.max()) + 1
    used = used_ids(groups, n_g)
    local = np.full(n_g, -1, dtype=np.int64)
    local[used] = np.arange(used.size)
    gl = local[groups]
    ga, gb = gl[ta], gl[tb]
    cross = ga != gb
    g = coo_matrix((np.ones(int(cross.sum()), dtype=np.int8), (ga[cross], gb[cross])), shape=(used.size, used.size))
    n_comp, lab = connected_components(g, directed=False)
    return lab.astype(np.int64)[gl], int(n_comp)


# ====================================================================== orientation and nesting
def _columns(P: np.ndarray, T: np.ndarray) -> tuple[list, tuple, list]:
    """Coordinate columns ``X[k] (n,)``, corner columns ``(t0, t1, t2)`` of ``T`` and the unnormalised
    triangle normals ``N[k] = ((P[t1] - P[t0]) × (P[t2] - P[t0]))[k] (m,)``, gathered once for the
    orientation test and the coplanar merge (contiguous 1-D gathers: no ``(m, 3)`` temporaries)."""
    X = [np.ascontiguousarray(P[:, k]) for k in range(3)]
    t0, t1, t2 = (np.ascontiguousarray(T[:, k]) for k in range(3))
    e1 = [x[t1] - x[t0] for x in X]
    e2 = [x[t2] - x[t0] for x in X]
    N = [e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2], e1[0] * e2[1] - e1[1] * e2[0]]
    return X, (t0, t1, t2), N


def _signed_volumes(P: np.ndarray, T: np.ndarray, columns: tuple | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Signed volume of each triangle's tetrahedron with the centre of the vertex box, and the bound
    of its round-off: the permanent of the products summed (the sum of their magnitudes), to which
    the rounding error of the float value is proportional whatever the value is (a flat tetrahedron
    has a tiny value and a large permanent).

    Without ``columns`` the value is the determinant of the three centred corners ``a, b, c`` and
    the bound its permanent (six products).  With ``columns`` (:func:`_columns` of ``P, T``, which
    holds the normals ``N = (b - a) × (c - a)``) it is the same determinant evaluated as
    ``(a - x0) · N`` and the bound that expression's permanent: three gathers instead of nine.
    """
    x0 = 0.5 * (column_min(P) + column_max(P))
    if columns is not None:
        X, (t0, _, _), N = columns
        A = [X[k][t0] - x0[k] for k in range(3)]
        v = (A[0] * N[0] + A[1] * N[1] + A[2] * N[2]) / 6.0
        perm = (np.abs(A[0]) * np.abs(N[0]) + np.abs(A[1]) * np.abs(N[1]) + np.abs(A[2]) * np.abs(N[2])) / 6.0
        return v, perm
    X = [np.ascontiguousarray(P[:, k]) for k in range(3)]
    t0, t1, t2 = (np.ascontiguousarray(T[:, k]) for k in range(3))
    Q = [X[k] - x0[k] for k in range(3)]  # columns: no (m, 3) temporaries
    ax, ay, az = (q[t0] for q in Q)
    bx, by, bz = (q[t1] for q in Q)
    cx, cy, cz = (q[t2] for q in Q)
    v = (ax * (by * cz - bz * cy) + ay * (bz * cx - bx * cz) + az * (bx * cy - by * cx)) / 6.0
    perm = (np.abs(ax) * (np.abs(by * cz) + np.abs(bz * cy)) + np.abs(ay) * (np.abs(bz * cx) + np.abs(bx * cz))
            + np.abs(az) * (np.abs(bx * cy) + np.abs(by * cx))) / 6.0
    return v, perm


def _orientation(P: np.ndarray, T: np.ndarray, labels: np.ndarray, n_comp: int, depth: np.ndarray,
                 thin: float = 0.0, columns: tuple | None = None) -> np.ndarray:
    """Components to reverse: the sign of the enclosed volume must be ``(-1) ** depth``.

    ``columns``: :func:`_columns` of ``P, T`` when the caller has them (the triangle areas of the
    ``thin`` test are half the lengths of its normals).

    Raises
    ------
    TopologyError
        A component whose volume is indistinguishable from zero (round-off of its terms), or with
        ``thin > 0`` one whose mean thickness ``|volume| / area`` is at most ``thin``.
    """
    if thin > 0.0 and columns is None:
        columns = _columns(P, T)
    v, av = _signed_volumes(P, T, columns)
    vol = np.bincount(labels, weights=v, minlength=n_comp)
    if thin > 0.0:
        N = columns[2]
        area = np.bincount(labels, weights=0.5 * np.sqrt(N[0] * N[0] + N[1] * N[1] + N[2] * N[2]), minlength=n_comp)
        sheet = np.flatnonzero(np.abs(vol) <= thin * area)
        if sheet.size:
            k = int(sheet[0])
            raise TopologyError(
                f"component {k} encloses volume {vol[k]:.3g} over area {area[k]:.3g}: thinner than the tolerance "
                f"{thin:g} (expected a component bounding a solid)"
            )
    # Each term is a float determinant whose error is a few ulps of its permanent: a total within
    # that of the summed permanents is indistinguishable from zero (a flat, doubly covered
    # component, e.g. the sheet left by two faces that touch, whose terms are all tiny).
    noise = 64.0 * np.finfo(np.float64).eps * np.bincount(labels, weights=av, minlength=n_comp)
    flat = np.flatnonzero(np.abs(vol) <= noise)
    if flat.size:
        k = int(flat[0])
        tri = np.flatnonzero(labels == k)
        raise TopologyError(
            f"component {k} (triangles {tri[:8].tolist()}{' ...' if tri.size > 8 else ''}) encloses volume "
            f"{vol[k]:.3g}, indistinguishable from 0; expected a component bounding a solid"
        )
    expected = np.where(depth % 2 == 0, 1.0, -1.0)
    return np.sign(vol) != expected


def _nesting(P: np.ndarray, T: np.ndarray, labels: np.ndarray, n_comp: int) -> tuple[np.ndarray, np.ndarray]:
    """Nesting depth of each component and its immediate container (-1 for depth 0).

    Component ``i`` is inside ``j`` when ``i``'s box lies in ``j``'s and the generalised winding
    number of a vertex of ``i`` with respect to ``j`` is ±1 (Van Oosterom & Strackee, *The solid
    angle of a plane triangle*, IEEE Trans. Biomed. Eng. 30, 1983; Jacobson et al., *Robust
    inside-outside segmentation using generalized winding numbers*, SIGGRAPH 2013).  Components
    are assumed not to cross each other (not checked).

    Raises
    ------
    TopologyError
        Two components each containing the other's probe vertex, or a nesting that is not a tree.
    """
    depth = np.zeros(n_comp, dtype=np.int64)
    parent = np.full(n_comp, -1, dtype=np.int64)
    if n_comp == 1:
        return depth, parent
    order = np.argsort(labels, kind="stable")
    ptr = np.concatenate([[0], np.cumsum(np.bincount(labels, minlength=n_comp))])
    corners = np.take(P, np.take(T, order, axis=0), axis=0)  # (m, 3, 3) in component order
    lo = np.minimum.reduceat(corners.min(axis=1), ptr[:-1])
    hi = np.maximum.reduceat(corners.max(axis=1), ptr[:-1])
    probe = P[T[order[ptr[:-1]], 0]]  # a vertex of each component
    # Candidate pairs (i in j): boxes nested.  A sweep along x lists the i whose lower x lies in
    # j's x range (sorted lower bounds and searchsorted), then the full containment filters them.
    by_lo = np.argsort(lo[:, 0], kind="stable")
    first = np.searchsorted(lo[by_lo, 0], lo[:, 0], side="left")
    count = np.searchsorted(lo[by_lo, 0], hi[:, 0], side="right") - first
    J = np.repeat(np.arange(n_comp), count)
    I = by_lo[np.repeat(first, count) + np.arange(J.size) - np.repeat(np.cumsum(count) - count, count)]
    nested = (I != J) & np.all(lo[I] >= lo[J], axis=1) & np.all(hi[I] <= hi[J], axis=1)
    I, J = I[nested], J[nested]
    inside_pairs: list[tuple[np.ndarray, int]] = []
    cuts = np.flatnonzero(np.diff(J)) + 1  # J is sorted (np.repeat of an arange): one group per container
    for cand, j in zip(np.split(I, cuts), J[np.concatenate([[0], cuts])] if J.size else []):
        j = int(j)
        w = _winding_numbers(probe[cand], corners[ptr[j] : ptr[j + 1]])
        inside = cand[np.abs(w) > 0.5]  # |w| is 1 inside a closed shell and 0 outside
        if inside.size:
            inside_pairs.append((inside, j))
    if not inside_pairs:
        return depth, parent
    inner = np.concatenate([p[0] for p in inside_pairs])
    outer = np.concatenate([np.full(p[0].size, p[1]) for p in inside_pairs])
    depth = np.bincount(inner, minlength=n_comp).astype(np.int64)
    immediate = depth[outer] == depth[inner] - 1
    parent[inner[immediate]] = outer[immediate]
    lost = np.flatnonzero((depth > 0) & (parent < 0))
    if lost.size:
        k = int(lost[0])
        raise TopologyError(
            f"component {k} lies inside components {np.unique(outer[inner == k]).tolist()} that do not nest "
            "(components overlap or contain each other); expected disjoint or nested shells"
        )
    return depth, parent


def _winding_numbers(points: np.ndarray, tri: np.ndarray, chunk: int = 1 << 19) -> np.ndarray:
    """Generalised winding numbers ``(q,)`` of points ``(q, 3)`` w.r.t. triangles ``(m, 3, 3)``.

    ``Ω = 2 atan2(a·(b×c), |a||b||c| + (a·b)|c| + (a·c)|b| + (b·c)|a|)`` per triangle with
    ``a, b, c`` the corners relative to the point; ``w = ΣΩ / 4π``.  Work is chunked so that at
    most ``chunk`` point–triangle pairs are held at once.
    """
    out = np.zeros(points.shape[0])
    step = max(1, chunk // max(1, tri.shape[0]))
    for s in range(0, points.shape[0], step):
        q = points[s : s + step, None, None, :]
        R = tri[None, :, :, :] - q  # (k, m, 3, 3)
        a, b, c = R[:, :, 0], R[:, :, 1], R[:, :, 2]
        la, lb, lc = (np.linalg.norm(x, axis=-1) for x in (a, b, c))
        num = np.einsum("kmi,kmi->km", a, np.cross(b, c))
        den = (la * lb * lc + np.einsum("kmi,kmi->km", a, b) * lc + np.einsum("kmi,kmi->km", a, c) * lb
               + np.einsum("kmi,kmi->km", b, c) * la)
        out[s : s + step] = 2.0 * np.arctan2(num, den).sum(axis=1) / (4.0 * np.pi)
    return out


def _triangle_distances(point: np.ndarray, tri: np.ndarray) -> np.ndarray:
    """Distances ``(m,)`` from one point ``(3,)`` to triangles ``(m, 3, 3)``: the plane's foot when it
    lies inside the triangle, else the nearest of the three sides, so that a degenerate (collinear)
    triangle is its sides (cf. Ericson 2005, §5.1.5, whose Voronoi-region form
    :func:`coons.validation.compare.closest_points_on_triangles` gives the points but assumes a
    proper triangle).  For :mod:`coons.topology.nesting`'s distance certificate."""
    a, b, c = tri[:, 0], tri[:, 1], tri[:, 2]
    n = np.cross(b - a, c - a)
    nn = np.einsum("ij,ij->i", n, n)
    w = point - a
    h = np.divide(np.einsum("ij,ij->i", w, n), nn, out=np.zeros(len(tri)), where=nn > 0)
    foot = point - h[:, None] * n
    # The foot is inside when it lies left of (or on) every side, seen along n.
    inside = nn > 0
    for p, q in ((a, b), (b, c), (c, a)):
        inside &= np.einsum("ij,ij->i", np.cross(q - p, foot - p), n) >= 0
    best = np.where(inside, np.abs(h) * np.sqrt(nn), np.inf)
    for p, q in ((a, b), (b, c), (c, a)):
        e = q - p
        ee = np.einsum("ij,ij->i", e, e)
        s = np.clip(np.divide(np.einsum("ij,ij->i", point - p, e), ee, out=np.zeros(len(tri)), where=ee > 0), 0, 1)
        best = np.minimum(best, np.linalg.norm(point - p - s[:, None] * e, axis=1))
    return best


# ====================================================================== tables
def _tables(
    P: np.ndarray,
    T: np.ndarray,
    a: np.ndarray,
    b: np.ndarray,
    labels: np.ndarray,
    n_comp: int,
    depth: np.ndarray,
    parent: np.ndarray,
    t: Tolerance,
) -> dict[str, np.ndarray]:
    """The :class:`BRep` columns of the triangle mesh, one face and loop per triangle.

    Equivalent to ``BRepBuilder.assemble`` with each edge oriented from its smaller to its
    larger vertex id and one face of one loop per triangle, followed by ``nest_shells`` for the
    voids and ``build``'s compaction — the same tables, made without a Python loop.  The left
    side (coedge ``2 e``) of edge ``e`` is the half-edge running from its smaller vertex.
    """
    m, n = T.shape[0], P.shape[0]
    E = a.size
    org = T.ravel()
    dst = next_corners(T)
    a_fwd = org[a] < dst[a]
    h0 = np.where(a_fwd, a, b)  # runs start -> end (left side)
    h1 = np.where(a_fwd, b, a)
    coedge_of = np.empty(3 * m, dtype=np.int64)
    coedge_of[h0] = 2 * np.arange(E)
    coedge_of[h1] = 2 * np.arange(E) + 1
    h = np.arange(3 * m)
    base = h - h % 3
    nxt = np.empty(2 * E, dtype=np.int64)
    prv = np.empty(2 * E, dtype=np.int64)
    nxt[coedge_of] = coedge_of[base + (h % 3 + 1) % 3]
    prv[coedge_of] = coedge_of[base + (h % 3 + 2) % 3]
    cloop = np.empty(2 * E, dtype=np.int64)
    cloop[coedge_of] = h // 3
    edge_vertex = np.stack([org[h0], dst[h0]], axis=1)
    # The smallest coedge leaving each vertex (coedge c starts at edge_vertex.ravel()[c]), as assemble picks it.
    vertex_coedge = np.full(n, 2 * E, dtype=np.int64)
    np.minimum.at(vertex_coedge, edge_vertex.ravel(), np.arange(2 * E))
    shell_solid, solid_ptr, solid_shells = _solids(n_comp, depth, parent)
    face_order = np.argsort(labels, kind="stable")
    return dict(
        vertex_point=P,
        vertex_tol=np.full(n, t.linear),
        vertex_coedge=vertex_coedge,
        edge_vertex=edge_vertex,
        edge_loop=cloop.reshape(E, 2),
        edge_wing=_wings(prv, nxt),
        edge_curve=np.full(E, -1, dtype=np.int64),
        edge_range=_unit_ranges(E),
        edge_pcurve=np.full((E, 2), -1, dtype=np.int64),
        edge_tol=np.full(E, t.linear),
        loop_face=np.arange(m, dtype=np.int64),
        loop_coedge=coedge_of[3 * np.arange(m)],
        loop_vertex=np.full(m, -1, dtype=np.int64),
        face_surface=np.full(m, -1, dtype=np.int64),
        face_sense=np.ones(m, dtype=bool),
        face_shell=labels,
        face_loop_ptr=np.arange(m + 1, dtype=np.int64),
        face_loops=np.arange(m, dtype=np.int64),
        shell_solid=shell_solid,
        shell_face_ptr=np.concatenate([[0], np.cumsum(np.bincount(labels, minlength=n_comp))]),
        shell_faces=face_order,
        solid_shell_ptr=solid_ptr,
        solid_shells=solid_shells,
    )


def _wings(prv: np.ndarray, nxt: np.ndarray) -> np.ndarray:
    """``edge_wing (E, 4)`` = ``[prev, next]`` of the left then the right side, from the coedge arrays
    ``prv, nxt (2 E,)``: two strided copies (``np.stack`` of four strided slices is slower)."""
    E = prv.size // 2
    W = np.empty((E, 2, 2), dtype=np.int64)
    W[:, :, 0] = prv.reshape(E, 2)
    W[:, :, 1] = nxt.reshape(E, 2)
    return W.reshape(E, 4)


def _unit_ranges(E: int) -> np.ndarray:
    """``(E, 2)`` rows ``[0, 1]`` (``np.tile`` is several times slower at a million rows)."""
    r = np.empty((E, 2))
    r[:, 0] = 0.0
    r[:, 1] = 1.0
    return r


def _solids(n_comp: int, depth: np.ndarray, parent: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``shell_solid`` and the solid → shells CSR rows (outer shell first) from the nesting."""
    outer = np.flatnonzero(depth % 2 == 0)
    solid_of = np.full(n_comp, -1, dtype=np.int64)
    solid_of[outer] = np.arange(outer.size)
    voids = np.flatnonzero(depth % 2 == 1)
    solid_of[voids] = solid_of[parent[voids]]
    # Outer shell first in each solid row: sort by (solid, is_void, shell id).
    is_void = (depth % 2 == 1).astype(np.int64)
    order = np.lexsort((np.arange(n_comp), is_void, solid_of))
    ptr = np.concatenate([[0], np.cumsum(np.bincount(solid_of, minlength=outer.size))])
    return solid_of, ptr, order.astype(np.int64)


# ====================================================================== coplanar merging
def _merge_coplanar(
    cols: dict[str, np.ndarray], P: np.ndarray, T: np.ndarray, a: np.ndarray, b: np.ndarray, t: Tolerance,
    straighten: bool = False, columns: tuple | None = None, dst: np.ndarray | None = None,
) -> dict[str, np.ndarray]:
    """Merge neighbouring coplanar triangles into polygon faces (outer loop first, then holes).

    ``columns``: :func:`_columns` of ``P, T`` and ``dst``: ``next_corners(T)``, when the caller has them.

    Coplanarity of the two triangles on an edge is decided **exactly** when every coordinate
    is an integer of magnitude below 2**15 (the orientation determinant of one triangle and
    the other's far vertex is then computed without rounding, see ``_EXACT_COORD_LIMIT``, and
    must be 0), and otherwise **within tolerance**: each far vertex lies within ``t.linear``
    of the other triangle's plane.  In both cases the normals must point the same way (a
    folded-flat fin is not merged).  Chains of within-tolerance merges can drift, so each
    merged region is verified afterwards: a region whose vertices are more than ``t.linear``
    from its Newell plane stays triangulated.

    Edges between two triangles of one region are removed; the remaining edges of a region
    are linked into loops by turning around each vertex inside the region (vectorised
    pointer following, one step per interior edge met); the loop with positive area about
    the region's normal is the outer loop, the others are holes.  Vertices left without an
    edge (inside a flat region) are removed and everything is renumbered.
    """
    m = T.shape[0]
    org = T.ravel()
    dst = next_corners(T) if dst is None else dst
    ta, tb = a // 3, b // 3
    opposite = prev_corners(T)  # the vertex of each half-edge's triangle opposite it
    far_a, far_b = opposite[a], opposite[b]
    # Column arrays: gathers of contiguous 1-D columns, no (E, 3) temporaries.
    X, (t0, t1, t2), Nc = _columns(P, T) if columns is None else columns

    P0 = np.take(P, t0, axis=0)  # the first corner of each triangle, a point of its plane

    def dot_far(n: list, tri: np.ndarray, far: np.ndarray) -> np.ndarray:
        # Row gathers (a cache line per scattered vertex) instead of column gathers of X; the same
        # products and sums as n[k][tri] * (X[k][far] - X[k][t0[tri]]).
        F = np.take(P, far, axis=0)
        Q = np.take(P0, tri, axis=0)
        return n[0][tri] * (F[:, 0] - Q[:, 0]) + n[1][tri] * (F[:, 1] - Q[:, 1]) + n[2][tri] * (F[:, 2] - Q[:, 2])

    if np.all(P == np.round(P)) and np.max(np.abs(P), initial=0.0) < _EXACT_COORD_LIMIT:
        coplanar = dot_far(Nc, ta, far_b) == 0.0
        c = np.flatnonzero(coplanar)
        coplanar[c] = Nc[0][ta[c]] * Nc[0][tb[c]] + Nc[1][ta[c]] * Nc[1][tb[c]] + Nc[2][ta[c]] * Nc[2][tb[c]] > 0
    else:
        nrm = np.sqrt(Nc[0] * Nc[0] + Nc[1] * Nc[1] + Nc[2] * Nc[2])
        U = [x / nrm for x in Nc]
        coplanar = np.abs(dot_far(U, ta, far_b)) <= t.linear  # one side first, the rest on the survivors
        c = np.flatnonzero(coplanar)
        coplanar[c] = (np.abs(dot_far(U, tb[c], far_a[c])) <= t.linear) & (
            U[0][ta[c]] * U[0][tb[c]] + U[1][ta[c]] * U[1][tb[c]] + U[2][ta[c]] * U[2][tb[c]] > 0)
    if not np.any(coplanar):
        return cols
    # Only triangles with a coplanar edge take part in regions; every other triangle stays a face of
    # its own, its loop its three half-edges (most triangles of a curved mesh: the work below is on
    # the region triangles only).
    in_reg = np.zeros(m, dtype=bool)
    in_reg[ta[coplanar]] = True
    in_reg[tb[coplanar]] = True
    rt = np.flatnonzero(in_reg)  # region triangles, increasing
    local = np.full(m, -1, dtype=np.int64)
    local[rt] = np.arange(rt.size)
    region, n_reg = _components(rt.size, local[ta[coplanar]], local[tb[coplanar]])
    # Verify each region's planarity against its Newell plane (guards against drift).
    Nr = np.stack([n[rt] for n in Nc], axis=1)  # region triangles only (1-D gathers)
    normal = np.stack([np.bincount(region, weights=Nr[:, k], minlength=n_reg) for k in range(3)], axis=1)
    unit = normal / np.linalg.norm(normal, axis=1)[:, None]
    size = np.bincount(region, minlength=n_reg)
    r3 = np.repeat(region, 3)
    Pr = np.take(P, np.take(T, rt, axis=0).ravel(), axis=0)
    cen = np.stack([np.bincount(r3, weights=Pr[:, k], minlength=n_reg) for k in range(3)], axis=1) / (3 * size)[:, None]
    off = np.abs(np.einsum("ij,ij->i", Pr - np.take(cen, r3, axis=0), np.take(unit, r3, axis=0)))
    dev = np.zeros(n_reg)
    np.maximum.at(dev, r3, off)
    bent = dev > t.linear
    if np.any(bent):  # split bent regions back into single triangles
        tri_bent = bent[region]
        region = region.copy()
        region[tri_bent] = n_reg + np.arange(int(tri_bent.sum()))
        _, region = np.unique(region, return_inverse=True)
        n_reg = int(region.max()) + 1
    size = np.bincount(region, minlength=n_reg)
    # Faces: the triangles outside regions in order, then the regions; face_of per triangle.
    single = np.flatnonzero(~in_reg)
    n_single = single.size
    face_of = np.empty(m, dtype=np.int64)
    face_of[single] = np.arange(n_single)
    face_of[rt] = n_single + region
    n_faces = n_single + n_reg
    interior = face_of[ta] == face_of[tb]
    if not np.any(interior):
        return cols
    twin = np.empty(3 * m, dtype=np.int64)
    twin[a], twin[b] = b, a
    # Region half-edges (the three of each region triangle, in triangle order).
    hr = (3 * rt[:, None] + np.arange(3)).ravel()
    inner_r = face_of[hr // 3] == face_of[twin[hr] // 3]
    inner_h = np.zeros(3 * m, dtype=bool)
    inner_h[hr] = inner_r
    # Next boundary half-edge after h (ending at v): g = next(h); while g is interior: g = next(twin(g)).
    nxt_of = lambda h: h - h % 3 + (h % 3 + 1) % 3  # noqa: E731
    kr = hr[~inner_r]  # boundary half-edges of regions
    g = nxt_of(kr)
    todo = np.flatnonzero(inner_h[g])
    while todo.size:
        g[todo] = nxt_of(twin[g[todo]])
        todo = todo[inner_h[g[todo]]]
    # Region loops: cycles of the permutation h -> g on the region boundary half-edges.
    perm = np.searchsorted(kr, g)  # kr is increasing and holds every g: positions without a (3 m,) table
    if kr.size and np.any(kr[np.minimum(perm, kr.size - 1)] != g):
        raise TopologyError("internal: a merged region's boundary walk left the region's boundary half-edges")
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    k = kr.size
    n_rloops, rloop_of = connected_components(
        coo_matrix((np.ones(k, dtype=np.int8), (np.arange(k), perm)), shape=(k, k)), directed=True, connection="weak"
    )
    rloop_of = rloop_of.astype(np.int64)
    rloop_face = np.empty(n_rloops, dtype=np.int64)
    rloop_face[rloop_of] = face_of[kr // 3]
    # Orientation of each loop about its region's normal: Newell vector · normal (unnormalised).
    normal = np.stack([np.bincount(region, weights=Nr[:, c], minlength=n_reg) for c in range(3)], axis=1)
    cr = np.cross(np.take(P, org[kr], axis=0), np.take(P, dst[kr], axis=0))
    area_vec = np.stack([np.bincount(rloop_of, weights=cr[:, c], minlength=n_rloops) for c in range(3)], axis=1)
    signed = np.einsum("ij,ij->i", area_vec, np.take(normal, rloop_face - n_single, axis=0))
    # Loops: one per single triangle (its face id), then the region loops by face, outer loop
    # (largest signed area) first.
    rloop_order = np.lexsort((-signed, rloop_face))
    rloop_rank = np.empty(n_rloops, dtype=np.int64)
    rloop_rank[rloop_order] = n_single + np.arange(n_rloops)
    reg_loops = np.bincount(rloop_face - n_single, minlength=n_reg)
    # One loop per single face: its pointers are an arange, the regions' follow.
    face_loop_ptr = np.concatenate([np.arange(n_single + 1, dtype=np.int64), n_single + np.cumsum(reg_loops)])
    outer = rloop_order[face_loop_ptr[n_single:-1] - n_single]
    if np.any(signed[outer] <= 0):
        r = int(np.flatnonzero(signed[outer] <= 0)[0])
        raise TopologyError(f"internal: merged flat region {r} has no counter-clockwise outer loop")
    # Edges that stay, renumbered; their sides keep the side numbering of the triangle tables.
    E_old = a.size
    keep_e = np.flatnonzero(~interior)
    e_new = np.full(E_old, -1, dtype=np.int64)
    e_new[keep_e] = np.arange(keep_e.size)
    # The new coedge of every half-edge of a kept edge (side 0 runs from edge_vertex[e, 0]).
    ev = cols["edge_vertex"]
    fwd = (org[a] == ev[:, 0]).astype(np.int64)
    C = np.empty(3 * m, dtype=np.int64)
    C[a] = 2 * e_new + 1 - fwd
    C[b] = 2 * e_new + fwd
    E = keep_e.size
    nxt = np.empty(2 * E, dtype=np.int64)
    cloop = np.empty(2 * E, dtype=np.int64)
    loop_first = np.empty(n_single + n_rloops, dtype=np.int64)
    # Single triangles: their three coedges in a cycle, loop = face = their rank.
    Cs = np.take(C.reshape(m, 3), single, axis=0)
    flat = Cs.ravel()  # one scatter of each column over all three corners (contiguous rows)
    nxt[flat] = next_corners(Cs)
    cloop[flat] = np.repeat(np.arange(n_single), 3)
    loop_first[:n_single] = Cs[:, 0]
    # Region loops.
    ck = C[kr]
    nxt[ck] = C[g]
    cloop[ck] = rloop_rank[rloop_of]
    loop_first[rloop_rank[rloop_of]] = ck
    prv = np.empty(2 * E, dtype=np.int64)
    prv[nxt] = np.arange(2 * E)
    loop_face = np.concatenate([np.arange(n_single, dtype=np.int64), n_single + np.repeat(np.arange(n_reg), reg_loops)])
    # Vertices that still have an edge, renumbered.
    edge_vertex = np.take(ev, keep_e, axis=0)
    used = np.zeros(P.shape[0], dtype=bool)
    used[edge_vertex.ravel()] = True
    n_used = int(used.sum())
    v_new = np.full(P.shape[0], -1, dtype=np.int64)
    v_new[used] = np.arange(n_used)
    edge_vertex = v_new[edge_vertex]
    # A coedge leaving each vertex (coedge 2e starts at v_start, 2e + 1 at v_end): the smallest one,
    # written in decreasing order so that it is the last write.
    vertex_coedge = np.empty(n_used, dtype=np.int64)
    vertex_coedge[edge_vertex.ravel()[::-1]] = np.arange(2 * E - 1, -1, -1)
    # Faces are regions, shells follow the old face shells of their triangles.
    face_shell = np.empty(n_faces, dtype=np.int64)
    face_shell[face_of] = cols["face_shell"]
    n_shell = cols["shell_solid"].size
    n_loops = n_single + n_rloops
    merged = dict(
        cols,
        vertex_point=np.compress(used, P, axis=0),
        vertex_tol=np.full(n_used, t.linear),
        vertex_coedge=vertex_coedge,
        edge_vertex=edge_vertex,
        edge_loop=cloop.reshape(E, 2),
        edge_wing=_wings(prv, nxt),
        edge_curve=np.full(E, -1, dtype=np.int64),  # the constant columns of _tables
        edge_range=_unit_ranges(E),
        edge_pcurve=np.full((E, 2), -1, dtype=np.int64),
        edge_tol=np.full(E, t.linear),
        loop_face=loop_face,
        loop_coedge=loop_first,
        loop_vertex=np.full(n_loops, -1, dtype=np.int64),
        face_surface=np.full(n_faces, -1, dtype=np.int64),
        face_sense=np.ones(n_faces, dtype=bool),
        face_shell=face_shell,
        face_loop_ptr=face_loop_ptr,
        face_loops=np.arange(n_loops, dtype=np.int64),
        shell_face_ptr=np.concatenate([[0], np.cumsum(np.bincount(face_shell, minlength=n_shell))]),
        shell_faces=np.argsort(face_shell, kind="stable"),
    )
    return _remove_straight_vertices(merged, t) if straighten else merged


#: Rounds of straight-vertex removal (each removes an independent set; chains shrink by at least one).
_MAX_STRAIGHT_ROUNDS = 64


def _remove_straight_vertices(cols: dict[str, np.ndarray], t: Tolerance) -> dict[str, np.ndarray]:
    """Remove vertices where exactly two edges meet in a straight line (after coplanar merging).

    Merging coplanar triangles leaves, on the boundary between two merged faces, the vertices where
    the triangulation's edges met that boundary: a vertex with two edges only, both faces on
    either side of both.  Such a vertex lies on the line where the two planes meet, so its two
    edges are collinear; it is removed (its two edges become one: Euler's ``kev`` in the winged
    edge tables) when it lies within ``t.linear`` of the segment between its neighbours and
    strictly between them.  Each round removes, vectorised, a set of straight vertices no two of
    which are adjacent or share a neighbour (each the smallest id around its neighbours), so
    their pointer updates touch disjoint coedges; at least one vertex goes per round.  Tables are
    renumbered at the end.
    """
    P = cols["vertex_point"]
    n_v = P.shape[0]
    # Removing v (edges u-v, v-w become u-w) leaves every other vertex's degree unchanged: the
    # candidates are the degree-2 vertices of the input, and each round works on them only (its
    # cost is proportional to the candidates, not to the tables).
    cand = np.flatnonzero(np.bincount(cols["edge_vertex"].ravel(), minlength=n_v) == 2)
    if cand.size == 0:
        return cols  # no vertex with two edges (most results: nothing to copy)
    ev = cols["edge_vertex"].copy()
    wing = cols["edge_wing"]
    nxt = interleaved_columns(wing, 1, 3)  # new arrays, written below
    prv = interleaved_columns(wing, 0, 2)
    E = ev.shape[0]
    org = ev.ravel()  # a view: org[c] is the origin of coedge c, org[c ^ 1] its target
    vertex_coedge = cols["vertex_coedge"]
    # Removed coedges point at the coedge that replaces them (first coedges of loops and vertices are
    # redirected once at the end); chains of replacements are followed.
    redirect = np.arange(2 * E)
    removed: list[np.ndarray] = []

    def resolve(c: np.ndarray) -> np.ndarray:
        while True:
            r = redirect[c]
            if np.array_equal(r, c):
                return c
            c = r

    v_alive = np.ones(n_v, dtype=bool)
    e_alive = np.ones(E, dtype=bool)
    for _ in range(_MAX_STRAIGHT_ROUNDS):
        v = cand[v_alive[cand]]
        if v.size == 0:
            break
        c_out = resolve(vertex_coedge[v])
        c_in = prv[c_out]
        u, w = org[c_in], org[c_out ^ 1]
        ok = ((c_out >> 1) != (c_in >> 1)) & (u != w) & (nxt[c_out ^ 1] == (c_in ^ 1)) & (org[c_in ^ 1] == v)
        Pu = np.take(P, u, axis=0)
        d = np.take(P, w, axis=0) - Pu
        q = np.take(P, v, axis=0) - Pu
        L2 = np.einsum("ij,ij->i", d, d)
        along = np.einsum("ij,ij->i", q, d)
        off = np.linalg.norm(np.cross(d, q), axis=1)
        ok &= (off <= t.linear * np.sqrt(L2)) & (along > 0) & (along < L2)
        if not np.any(ok):
            break
        # An independent set: no two removed vertices adjacent or sharing a neighbour (their pointer
        # updates then touch disjoint coedges); the smallest id wins.  Local ids over the vertices
        # involved keep the round's arrays small.
        ids, inv = np.unique(np.concatenate([v, u, w]), return_inverse=True)
        lv, lu, lw = inv[: v.size], inv[v.size : 2 * v.size], inv[2 * v.size :]
        straight = np.zeros(ids.size, dtype=bool)
        straight[lv[ok]] = True
        first = np.full(ids.size, n_v, dtype=np.int64)
        np.minimum.at(first, np.concatenate([lu[ok], lw[ok]]), np.concatenate([v[ok], v[ok]]))
        keep = ok & (first[lu] == v) & (first[lw] == v) & (~straight[lu] | (v < u)) & (~straight[lw] | (v < w))
        v, c_out, c_in, u, w = v[keep], c_out[keep], c_in[keep], u[keep], w[keep]
        o_in, o_out = c_in ^ 1, c_out ^ 1
        # Loop of c_in: c_in now runs on to w.  Other loop: the twin of c_in now starts at w.
        after = nxt[c_out]
        before = prv[o_out]
        e_in = c_in >> 1
        ev[e_in, 1 - (c_in & 1)] = w  # c_in's target: the end of a left side, the start of a right side
        nxt[c_in] = after
        prv[after] = c_in
        prv[o_in] = before
        nxt[before] = o_in
        redirect[c_out] = c_in
        redirect[o_out] = o_in
        removed.append(np.concatenate([c_out, o_out]))
        e_alive[c_out >> 1] = False
        v_alive[v] = False
    if v_alive.all():
        return cols
    gone = np.concatenate(removed)
    redirect[gone] = resolve(redirect[gone])
    loop_coedge = redirect[cols["loop_coedge"]]
    vertex_coedge = redirect[vertex_coedge]
    # Renumber edges and vertices.
    e_new = np.cumsum(e_alive) - 1
    v_new = np.cumsum(v_alive) - 1
    keep_e = np.flatnonzero(e_alive)
    cmap = lambda c: 2 * e_new[c >> 1] + (c & 1)  # noqa: E731
    nxt2, prv2 = np.take(nxt.reshape(E, 2), keep_e, axis=0), np.take(prv.reshape(E, 2), keep_e, axis=0)
    out = dict(cols)
    out.update(
        vertex_point=np.compress(v_alive, P, axis=0),
        vertex_tol=cols["vertex_tol"][v_alive],
        vertex_coedge=cmap(vertex_coedge[v_alive]),
        edge_vertex=v_new[np.take(ev, keep_e, axis=0)],
        edge_loop=np.take(cols["edge_loop"], keep_e, axis=0),
        edge_wing=np.stack([cmap(prv2[:, 0]), cmap(nxt2[:, 0]), cmap(prv2[:, 1]), cmap(nxt2[:, 1])], axis=1),
        edge_curve=cols["edge_curve"][keep_e],
        edge_range=np.take(cols["edge_range"], keep_e, axis=0),
        edge_pcurve=np.take(cols["edge_pcurve"], keep_e, axis=0),
        edge_tol=cols["edge_tol"][keep_e],
        loop_coedge=cmap(loop_coedge),
    )
    return out
