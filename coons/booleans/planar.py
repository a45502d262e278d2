"""Exact Booleans of planar polygon sets: union, intersection, difference, symmetric difference.

This module overlays two :class:`~coons.kernel.polygon.PolygonSet` values in an exact
arrangement and reads the result off it, in 2-D and on a plane in 3-D (trim loops in a
face's parameter plane and planar faces in space use the same code).  Every
combinatorial decision — which segments meet, where they are split, the cyclic order of
edges around a vertex, which faces lie inside which operand — is made by exact
predicates (:mod:`coons.kernel.predicates`), so the combinatorial result is exact for
every float input, including shared edges, collinear overlaps, vertices on edges,
identical operands and point contacts.  The only inexactness is the final rounding of
new vertices (intersection points) to the nearest float64, at most 0.5 ulp per
coordinate (see "Rounding" below for the rare case where that rounding would break the
output).  It deliberately does not offset, snap to a grid, simplify or heal: there is no
tolerance anywhere in the 2-D code, and invalid input raises.

Notation
--------
``A``, ``B``
    The operands, read with the positive-winding rule of
    :class:`~coons.kernel.polygon.PolygonSet`: ``w_A(x)`` is the winding number of point
    ``x`` summed over A's rings, and ``x`` is in A when ``w_A(x) > 0``.
``R``
    The result region, ``op(in A, in B)`` face by face.
segment
    A directed edge of an input ring, ``p -> q``, from A or B.
vertex, edge
    Of the arrangement: input vertices and crossing points, merged when exactly equal;
    the pieces of the segments between consecutive vertices on them, merged when they
    coincide, each carrying the net count ``(c_A, c_B)`` of A and B segments along it.
half-edge ``h``, twin ``h ^ 1``, ``next[h]``
    The two directions of an edge; faces lie on the left of their half-edges and
    ``next`` walks a face boundary counter-clockwise (a component's outer boundary
    clockwise).
face node
    A cycle of ``next``: a bounded face of one connected component of the arrangement,
    or the outer boundary of a component.

Phases (each a private function): ``_segments`` → ``_intersect`` (sort-and-sweep broad
phase, exact segment relations, exact rational crossing points) → ``_imprint`` (split
segments, merge vertices and edges, exact angular order, faces) → ``_classify`` (winding
numbers of one face node per component by exact ray casting, then propagated across
edges by the counts, and checked on every edge) → ``_select`` (faces of R, boundary
half-edges with R on their left) → ``_rings`` (link boundary half-edges into rings,
split them at repeated vertices, orient them exactly, group holes with their outer ring
through the faces of R and, for components floating inside R, an exact leftward ray)
→ ``_rounding_defects`` (exact check of what rounding may have broken) → ``_assemble``.

Rounding
--------
New vertices are rounded to the nearest floats.  When inputs have features within about
an ulp of each other (typically: inputs that are themselves rounded results of earlier
Booleans, sharing lines with the other operand) that rounding can merge two vertices,
push a vertex across a nearby edge or turn a tiny ring over.  ``_rounding_defects``
checks exactly every edge at a rounded vertex; if anything broke, the rounded rings are
resolved again with the same exact overlay (positive-winding rule), which changes the
region only within about an ulp of those vertices.  One such pass has sufficed in every
case seen; after four, :class:`~coons.errors.BooleanError` (stage ``"round"``) is raised
rather than returning a broken result.

Output conventions
------------------
* Outer rings counter-clockwise, holes clockwise, no zero-area ring, every ring simple.
* Rings may share isolated vertices: two polygons touching at a point, a hole touching
  its outer ring or another hole at a point.  They never share an edge or cross.
* A vertex where the boundary runs straight on is kept if it is a vertex of A or B and
  removed if it is a new (intersection) vertex used by a single ring, so ``A ∪ A`` gives
  back ``A``'s rings and no rounded crossing point sits in the middle of a straight edge.
* Canonical order: each ring starts at its lexicographically smallest vertex, holes and
  polygons are sorted by that vertex.  An empty result is the empty PolygonSet.

Status and limitations
----------------------
* When a rounding pass was needed, the result differs from the exactly rounded one by
  slivers within about an ulp of the re-resolved vertices.
* The rounding check re-examines the edges at rounded vertices only: a ring smaller than
  an ulp that rounding moves wholesale into another face without touching an edge would
  go unnoticed (no such input is known to be constructible from float coordinates).
* Crossing points are reduced fractions of Python integers (object arrays), and the few
  ambiguous predicates run on Python integers; the rest is vectorised numpy, with Python
  loops only over the rare exact tie-breaks and over result polygons.  The broad phase is
  ``O(n log n + c)`` for ``c`` candidate pairs overlapping along the sweep axis.
* In 3-D, the projection to the plane frame rounds (about one ulp of the coordinates);
  the Boolean is exact on the projected coordinates.
"""

from __future__ import annotations

from dataclasses import dataclass
from fractions import Fraction
from functools import cmp_to_key
from typing import NamedTuple

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import breadth_first_order, connected_components

from coons.errors import BooleanError, InvalidInputError
from coons.kernel.polygon import Polygon, PolygonSet, _ccw, _self_intersection, overlapping_boxes
from coons.kernel.predicates import (
    SegmentRelation,
    _classify_flat,
    _cross_flat,
    _crossing_rationals,
    _orient2d_flat,
    _Rationals,
)
from coons.tolerance import Tolerance, resolve
from coons.topology.check import CheckReport, Problem

__all__ = [
    "OPERATIONS",
    "polygon_boolean",
    "polygon_union",
    "polygon_intersection",
    "polygon_difference",
    "polygon_symmetric_difference",
    "check_polygon_set",
    "PlaneFrame",
    "Polygon3D",
    "planar_boolean",
]

#: The operations and their tables: in R as a function of (in A, in B), on boolean arrays.
OPERATIONS = {
    "union": lambda a, b: a | b,
    "intersection": lambda a, b: a & b,
    "difference": lambda a, b: a & ~b,
    "symmetric_difference": lambda a, b: a ^ b,
}

_TWO_PI = 2.0 * np.pi
#: Re-resolutions of a rounded result before giving up (each pass only acts within about one
#: ulp of the vertices rounded by the previous one; one pass has sufficed in every case seen).
_MAX_ROUNDING_PASSES = 4


# ====================================================================== public API
def polygon_boolean(a, b, op: str) -> PolygonSet:
    """Exact Boolean of two planar polygon sets.

    Parameters
    ----------
    a, b : PolygonSet, Polygon, ring (n, 2), (outer, holes) tuple, or a sequence of those
        Coerced with :meth:`PolygonSet.coerce` (rings are validated: finite, at least 3
        distinct vertices, simple).
    op : {"union", "intersection", "difference", "symmetric_difference"}

    Returns
    -------
    PolygonSet
        Canonical (see the module docstring).  Combinatorially exact; new vertices are
        the nearest floats to the exact intersection points.

    Raises
    ------
    InvalidInputError
        Unknown ``op``; input that is not a polygon set; a ring with NaN/inf, fewer than 3
        vertices or a self-intersection (the message names the polygon, the ring and the
        segments).
    BooleanError
        An internal invariant failed (``stage`` names the phase); never expected.

    Examples
    --------
    >>> sq = [[0, 0], [2, 0], [2, 2], [0, 2]]
    >>> polygon_boolean(sq, [[1, 1], [3, 1], [3, 3], [1, 3]], "union").area
    7.0
    """
    if op not in OPERATIONS:
        raise InvalidInputError(f"op must be one of {sorted(OPERATIONS)}, got {op!r}")
    A = _coerce(a, "a")
    B = _coerce(b, "b")
    rings = _overlay(_segments(A, B), op)
    for _ in range(_MAX_ROUNDING_PASSES):
        defects = _rounding_defects(rings)
        if not defects:
            return _assemble(rings)
        rings = _overlay(_ring_segments(rings), "union")
    raise BooleanError(
        f"rounding the result still leaves defects after {_MAX_ROUNDING_PASSES} passes",
        stage="round",
        diagnostics={"defects": defects[:10]},
    )


def _overlay(S: _Segments, op: str) -> "_RingSet":
    """The exact phases: intersect, imprint, classify, select, and rings (rounded)."""
    if S.p.shape[0] == 0:
        return _RingSet.empty()
    arr = _imprint(S, _intersect(S))
    w = _classify(arr, S)
    sel, in_r = _select(arr, w, op)
    return _rings(arr, S, sel, in_r)


def polygon_union(a, b) -> PolygonSet:
    """A ∪ B; see :func:`polygon_boolean`."""
    return polygon_boolean(a, b, "union")


def polygon_intersection(a, b) -> PolygonSet:
    """A ∩ B; see :func:`polygon_boolean`."""
    return polygon_boolean(a, b, "intersection")


def polygon_difference(a, b) -> PolygonSet:
    """A − B; see :func:`polygon_boolean`."""
    return polygon_boolean(a, b, "difference")


def polygon_symmetric_difference(a, b) -> PolygonSet:
    """(A − B) ∪ (B − A); see :func:`polygon_boolean`."""
    return polygon_boolean(a, b, "symmetric_difference")


def _coerce(obj, name: str) -> PolygonSet:
    try:
        return PolygonSet.coerce(obj)
    except InvalidInputError as exc:
        raise InvalidInputError(f"operand {name}: {exc}") from exc


# ====================================================================== phase 0: segments
@dataclass(frozen=True)
class _Segments:
    """Directed ring edges of both operands: ``p -> q`` (n, 2) and the operand (0 = A, 1 = B)."""

    p: np.ndarray
    q: np.ndarray
    operand: np.ndarray


def _segments(A: PolygonSet, B: PolygonSet) -> _Segments:
    pa, qa = A.edges()
    pb, qb = B.edges()
    operand = np.concatenate([np.zeros(pa.shape[0], np.int64), np.ones(pb.shape[0], np.int64)])
    return _Segments(np.concatenate([pa, pb]), np.concatenate([qa, qb]), operand)


# ====================================================================== phase 1: intersect
@dataclass(frozen=True)
class _Intersections:
    """Points to split segments at.

    ``touch_seg``/``touch_src``/``touch_end``: a segment, and the endpoint (0 = p, 1 = q) of
    segment ``touch_src`` that lies strictly inside it.
    ``cross_i``/``cross_j``: properly crossing segment pairs, ``cross`` their exact common
    points (reduced fractions and their rounding).
    """

    touch_seg: np.ndarray
    touch_src: np.ndarray
    touch_end: np.ndarray
    cross_i: np.ndarray
    cross_j: np.ndarray
    cross: _Rationals


def _strictly_inside(a: np.ndarray, b: np.ndarray, r: np.ndarray) -> np.ndarray:
    """For ``r`` collinear with segment ``a, b``: is it strictly between the endpoints?
    (Lexicographic order is the order along any line; exact float comparisons.)"""

    def less(u, v):
        return (u[:, 0] < v[:, 0]) | ((u[:, 0] == v[:, 0]) & (u[:, 1] < v[:, 1]))

    return (less(a, r) & less(r, b)) | (less(b, r) & less(r, a))


def _intersect(S: _Segments) -> _Intersections:
    """Broad phase and exact narrow phase over all segment pairs with overlapping boxes."""
    p, q = S.p, S.q
    pairs = overlapping_boxes(np.minimum(p, q), np.maximum(p, q))
    i, j = pairs[:, 0], pairs[:, 1]
    rel, (o1, o2, o3, o4) = _classify_flat(p[i], q[i], p[j], q[j])
    touch_seg, touch_src, touch_end = [], [], []
    for on, host, src, end in ((o1 == 0, i, j, 0), (o2 == 0, i, j, 1), (o3 == 0, j, i, 0), (o4 == 0, j, i, 1)):
        k = np.flatnonzero(on)
        h, s = host[k], src[k]
        pt = p[s] if end == 0 else q[s]
        k = np.flatnonzero(_strictly_inside(p[h], q[h], pt))
        touch_seg.append(h[k])
        touch_src.append(s[k])
        touch_end.append(np.full(k.size, end, dtype=np.int64))
    cross = np.flatnonzero(rel == SegmentRelation.CROSSING)
    ci, cj = i[cross], j[cross]
    return _Intersections(
        np.concatenate(touch_seg),
        np.concatenate(touch_src),
        np.concatenate(touch_end),
        ci,
        cj,
        _crossing_rationals(p[ci], q[ci], p[cj], q[cj]),
    )


# ====================================================================== phase 2: imprint
@dataclass(frozen=True)
class _Arrangement:
    """The exact arrangement of the segments as a half-edge structure.

    Vertices ``0 .. n_float - 1`` are exactly their float coordinates ``xy`` (sorted
    lexicographically); vertices from ``n_float`` on are crossing points whose exact
    coordinates are ``exact[v - n_float]`` and ``xy`` their rounding.  Half-edge ``2e``
    runs ``edge_uv[e, 0] -> edge_uv[e, 1]`` (the smaller id first), ``2e + 1`` back.
    """

    xy: np.ndarray  # (nv, 2) float64
    n_float: int
    exact: list  # [(nx, dx, ny, dy)] reduced fractions of the crossing vertices
    original: np.ndarray  # (nv,) bool: a vertex of A or B
    edge_uv: np.ndarray  # (E, 2) int64
    counts: np.ndarray  # (E, 2) int64: net A and B segments along u -> v
    chain_start: np.ndarray  # (n + 1,) offsets: vertices along segment s are chain_vertex[start[s]:start[s+1]]
    chain_vertex: np.ndarray  # vertex ids in p -> q order
    chain_edge: np.ndarray  # edge from chain_vertex[k] to chain_vertex[k + 1] (-1 at a segment's last vertex)
    origin: np.ndarray  # (H,) vertex a half-edge leaves
    d0: np.ndarray  # (H, 2) float points whose difference d1 - d0 is the half-edge's direction (exact)
    d1: np.ndarray
    around: np.ndarray  # half-edges sorted by origin, then counter-clockwise
    around_start: np.ndarray  # (nv + 1,)
    n_upper: np.ndarray  # (nv,) outgoing half-edges pointing into the upper half plane [0, pi)
    next: np.ndarray  # (H,)
    face: np.ndarray  # (H,) face node left of each half-edge
    n_faces: int
    component: np.ndarray  # (nv,) connected component of each vertex
    anchor: np.ndarray  # (C,) lexicographically smallest vertex of each component (a float vertex)
    outer_face: np.ndarray  # (C,) face node of each component's outer boundary

    def exact_xy(self, v: int) -> tuple[Fraction, Fraction]:
        return _exact_xy(self.xy, self.n_float, self.exact, v)


def _exact_xy(xy: np.ndarray, n_float: int, exact: list, v: int) -> tuple[Fraction, Fraction]:
    if v < n_float:
        return Fraction(float(xy[v, 0])), Fraction(float(xy[v, 1]))
    nx, dx, ny, dy = exact[v - n_float]
    return Fraction(nx, dx), Fraction(ny, dy)


def _unique_rows(X: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Unique rows of a float (m, 2) array in lexicographic order, and the inverse map."""
    order = np.lexsort((X[:, 1], X[:, 0]))
    Xs = X[order]
    new = np.ones(X.shape[0], dtype=bool)
    new[1:] = np.any(Xs[1:] != Xs[:-1], axis=1)
    ids = np.cumsum(new) - 1
    inverse = np.empty(X.shape[0], dtype=np.int64)
    inverse[order] = ids
    return Xs[new], inverse


def _vertices(S: _Segments, I: _Intersections):
    """Merge exactly equal points: floats by their bits (crossing points that are floats
    included), the other crossing points by their reduced fractions."""
    n = S.p.shape[0]
    c = I.cross
    rounded = c.rounded
    # A crossing point is a float iff its reduced fractions are those of its rounding.
    columns = (rounded[:, 0].tolist(), rounded[:, 1].tolist(), c.nx.tolist(), c.dx.tolist(), c.ny.tolist(), c.dy.tolist())
    representable = np.array(
        [rx.as_integer_ratio() == (a, b) and ry.as_integer_ratio() == (d, e) for rx, ry, a, b, d, e in zip(*columns)],
        dtype=bool,
    )
    rep = np.flatnonzero(representable)
    pts = np.concatenate([S.p, S.q, rounded[rep]]) + 0.0
    xy_float, inverse = _unique_rows(pts)
    n_float = xy_float.shape[0]
    original = np.zeros(n_float, dtype=bool)
    original[inverse[: 2 * n]] = True
    vid_p, vid_q = inverse[:n], inverse[n : 2 * n]
    cross_vid = np.empty(rounded.shape[0], dtype=np.int64)
    cross_vid[rep] = inverse[2 * n :]
    keys: dict = {}
    exact = []
    rest = np.flatnonzero(~representable)
    for k, key in zip(
        rest.tolist(), zip(c.nx[rest].tolist(), c.dx[rest].tolist(), c.ny[rest].tolist(), c.dy[rest].tolist())
    ):
        v = keys.get(key)
        if v is None:
            v = keys[key] = n_float + len(exact)
            exact.append((k, key))
        cross_vid[k] = v
    xy = np.concatenate([xy_float, rounded[[k for k, _ in exact]].reshape(-1, 2)])
    original = np.concatenate([original, np.zeros(len(exact), dtype=bool)])
    touch_vid = np.where(I.touch_end == 0, vid_p[I.touch_src], vid_q[I.touch_src])
    return xy, n_float, [key for _, key in exact], original, vid_p, vid_q, cross_vid, touch_vid


def _imprint(S: _Segments, I: _Intersections) -> _Arrangement:
    """Split segments at their points, merge vertices and edges, order edges around vertices."""
    n = S.p.shape[0]
    xy, n_float, exact, original, vid_p, vid_q, cross_vid, touch_vid = _vertices(S, I)
    nv = xy.shape[0]

    def exact_xy(v: int) -> tuple[Fraction, Fraction]:
        return _exact_xy(xy, n_float, exact, v)

    # --- chains: the vertices on each segment, in p -> q order
    seg = np.concatenate([np.arange(n), np.arange(n), I.touch_seg, I.cross_i, I.cross_j]).astype(np.int64)
    vid = np.concatenate([vid_p, vid_q, touch_vid, cross_vid, cross_vid]).astype(np.int64)
    uniq = np.unique(seg * nv + vid)
    seg, vid = uniq // nv, uniq % nv
    axis = np.where(S.p[:, 0] != S.q[:, 0], 0, 1)
    sense = np.where(S.q[np.arange(n), axis] > S.p[np.arange(n), axis], 1.0, -1.0)
    # Rounding is monotone, so the rounded coordinate orders the points along a segment
    # except between distinct points that round alike: those ties are ordered exactly.
    key = xy[vid, axis[seg]] * sense[seg]
    order = np.lexsort((key, seg))
    seg, vid, key = seg[order], vid[order], key[order]
    tie = (seg[1:] == seg[:-1]) & (key[1:] == key[:-1])
    if tie.any():
        for start, stop in _runs(tie):
            s = int(seg[start])
            ax, sg = int(axis[s]), int(sense[s])
            block = sorted(vid[start:stop].tolist(), key=lambda v: exact_xy(v)[ax] * sg)
            vid[start:stop] = block
    chain_start = np.searchsorted(seg, np.arange(n + 1))

    # --- edges: consecutive chain vertices, merged when they coincide
    inner = np.flatnonzero(seg[1:] == seg[:-1])
    a, b = vid[inner], vid[inner + 1]
    sub_seg = seg[inner]
    u, v = np.minimum(a, b), np.maximum(a, b)
    sgn = np.where(a < b, 1, -1)
    ekey, first, inv = np.unique(u * nv + v, return_index=True, return_inverse=True)
    E = ekey.shape[0]
    edge_uv = np.stack([ekey // nv, ekey % nv], axis=1)
    counts = np.zeros((E, 2), dtype=np.int64)
    np.add.at(counts, (inv, S.operand[sub_seg]), sgn)
    chain_edge = np.full(seg.shape[0], -1, dtype=np.int64)
    chain_edge[inner] = inv

    # --- half-edges and their exact directions (from the supporting input segment)
    rep_seg, rep_fwd = sub_seg[first], sgn[first] == 1
    H = 2 * E
    origin = edge_uv.reshape(-1).copy()
    fwd = np.empty(H, dtype=bool)
    fwd[0::2], fwd[1::2] = rep_fwd, ~rep_fwd
    hseg = np.repeat(rep_seg, 2)
    d0 = np.where(fwd[:, None], S.p[hseg], S.q[hseg])
    d1 = np.where(fwd[:, None], S.q[hseg], S.p[hseg])

    # --- rotation system: outgoing half-edges counter-clockwise around each vertex
    upper = (d1[:, 1] > d0[:, 1]) | ((d1[:, 1] == d0[:, 1]) & (d1[:, 0] > d0[:, 0]))
    half = np.where(upper, 0, 1)
    ang = np.arctan2(d1[:, 1] - d0[:, 1], d1[:, 0] - d0[:, 0])
    ang = np.where(ang < 0, ang + _TWO_PI, ang)  # an estimate: the order is verified exactly below
    around = np.lexsort((ang, half, origin))
    around = _verify_rotation(around, origin, half, d0, d1)
    deg = np.bincount(origin, minlength=nv)
    around_start = np.concatenate([[0], np.cumsum(deg)])
    n_upper = np.bincount(origin[upper], minlength=nv)
    rank = np.empty(H, dtype=np.int64)
    rank[around] = np.arange(H) - around_start[origin[around]]
    twin = np.arange(H) ^ 1
    vt = origin[twin]
    nxt = around[around_start[vt] + (rank[twin] - 1) % deg[vt]]

    # --- faces (cycles of next) and components
    n_faces, face = connected_components(coo_matrix((np.ones(H), (np.arange(H), nxt)), shape=(H, H)), directed=False)
    _n_comp, component = connected_components(
        coo_matrix((np.ones(E), (edge_uv[:, 0], edge_uv[:, 1])), shape=(nv, nv)), directed=False
    )
    used = deg > 0
    comps = np.unique(component[used])
    anchor = np.full(component.max() + 1, nv, dtype=np.int64)
    fv = np.flatnonzero(used[:n_float])
    np.minimum.at(anchor, component[fv], fv)
    anchor = anchor[comps]
    if np.any(anchor >= n_float):
        raise BooleanError("a component has no input vertex", stage="imprint", diagnostics={"components": comps})
    # At the lexicographically smallest vertex every edge points into (-pi/2, pi/2]; the
    # outer face is left of the last edge in the upper half plane (or of the last edge).
    pos = np.where(n_upper[anchor] > 0, n_upper[anchor] - 1, deg[anchor] - 1)
    outer_face = face[around[around_start[anchor] + pos]]
    comp_index = np.full(component.max() + 1, -1, dtype=np.int64)
    comp_index[comps] = np.arange(comps.size)
    component = np.where(used, comp_index[component], -1)

    arr = _Arrangement(
        xy=xy, n_float=n_float, exact=exact, original=original, edge_uv=edge_uv, counts=counts,
        chain_start=chain_start, chain_vertex=vid, chain_edge=chain_edge, origin=origin, d0=d0, d1=d1,
        around=around, around_start=around_start, n_upper=n_upper, next=nxt, face=face, n_faces=int(n_faces),
        component=component, anchor=anchor, outer_face=outer_face,
    )  # fmt: skip
    _check_half_edges(arr)
    return arr


def _runs(tie: np.ndarray) -> list[tuple[int, int]]:
    """[start, stop) runs of elements joined by ``tie[k]`` (element k ties with k + 1)."""
    d = np.diff(np.concatenate([[0], tie.astype(np.int8), [0]]))
    return list(zip(np.flatnonzero(d == 1).tolist(), (np.flatnonzero(d == -1) + 1).tolist()))


def _verify_rotation(around, origin, half, d0, d1) -> np.ndarray:
    """Check the estimated angular order with exact cross products; re-sort vertices where it fails.

    Within one half plane, ``a`` precedes ``b`` counter-clockwise iff ``cross(a, b) > 0``, a
    strict total order (two edges from one vertex never point the same way).
    """
    a, b = around[:-1], around[1:]
    same = (origin[a] == origin[b]) & (half[a] == half[b])
    k = np.flatnonzero(same)
    cs = _cross_flat(d0[a[k]], d1[a[k]], d0[b[k]], d1[b[k]])
    if np.any(cs == 0):
        bad = int(a[k[np.flatnonzero(cs == 0)[0]]])
        raise BooleanError(
            "two edges leave a vertex in the same direction", stage="imprint", diagnostics={"half_edge": bad}
        )
    wrong = k[cs < 0]
    if wrong.size == 0:
        return around
    around = around.copy()
    starts = np.searchsorted(origin[around], origin[around[wrong]], side="left")
    stops = np.searchsorted(origin[around], origin[around[wrong]], side="right")

    def cmp(h: int, g: int) -> int:
        if half[h] != half[g]:
            return -1 if half[h] < half[g] else 1
        return -int(_cross_flat(d0[[h]], d1[[h]], d0[[g]], d1[[g]])[0])

    for start, stop in sorted(set(zip(starts.tolist(), stops.tolist()))):
        around[start:stop] = sorted(around[start:stop].tolist(), key=cmp_to_key(cmp))
    return _verify_rotation(around, origin, half, d0, d1)  # now in order: verified, never re-sorted


def _check_half_edges(arr: _Arrangement) -> None:
    """Invariants of the half-edge structure: next is a permutation that starts where the previous ends."""
    H = arr.origin.shape[0]
    if H and not np.array_equal(np.sort(arr.next), np.arange(H)):
        raise BooleanError("next is not a permutation of the half-edges", stage="imprint")
    head = arr.origin[np.arange(H) ^ 1]
    if not np.array_equal(arr.origin[arr.next], head):
        bad = int(np.flatnonzero(arr.origin[arr.next] != head)[0])
        raise BooleanError("next does not continue at the head vertex", stage="imprint", diagnostics={"half_edge": bad})


# ====================================================================== phase 3: classify
def _classify(arr: _Arrangement, S: _Segments) -> np.ndarray:
    """Winding numbers ``(w_A, w_B)`` of every face node, shape (F, 2) int64.

    Each component's outer face node is seeded with the exact winding numbers of a point
    just left of its anchor vertex; crossing half-edge ``h`` from its face to its twin's
    changes the winding numbers by ``-counts``.  The potentials are propagated along a
    breadth-first spanning tree (pointer jumping, vectorised) and then checked on every
    edge, so an inconsistent arrangement cannot go unnoticed.
    """
    F = arr.n_faces
    C = arr.anchor.shape[0]
    seeds = _ray_windings(arr.xy[arr.anchor], S)
    H = arr.origin.shape[0]
    h = np.arange(H)
    c = np.where((h % 2 == 0)[:, None], arr.counts[h // 2], -arr.counts[h // 2])
    src = np.concatenate([arr.face, np.full(C, F)])
    dst = np.concatenate([arr.face[h ^ 1], arr.outer_face])
    inc = np.concatenate([-c, seeds])
    w = _potentials(F + 1, src, dst, inc, root=F)[:F]
    if not np.array_equal(w[arr.face[h ^ 1]] - w[arr.face], -c) or not np.array_equal(w[arr.outer_face], seeds):
        bad = np.flatnonzero(np.any(w[arr.face[h ^ 1]] - w[arr.face] != -c, axis=1))
        raise BooleanError(
            "winding numbers are inconsistent across edges",
            stage="classify",
            diagnostics={"half_edges": bad[:10].tolist()},
        )
    return w


def _ray_candidates(points: np.ndarray, S: _Segments) -> tuple[np.ndarray, np.ndarray]:
    """Pairs (point i, segment s) where ``s`` crosses the leftward ray from ``points[i]``
    perturbed to ``v + (-eps, +delta)`` (infinitesimals ``0 < delta << eps``), exactly.

    A segment crosses when it straddles ``y = v_y + delta`` (exactly one end strictly above
    ``v_y``) and passes strictly left of ``v`` (exact orient2d).  A segment through ``v``
    itself never counts: ``v`` is the leftmost vertex of its component, so such a segment
    leaves ``v`` to the right or straight up.
    """
    if points.shape[0] == 0 or S.p.shape[0] == 0:
        return np.zeros(0, np.int64), np.zeros(0, np.int64)
    ray_lo = np.stack([np.full(points.shape[0], -np.inf), points[:, 1]], axis=1)
    pairs = overlapping_boxes(ray_lo, points, np.minimum(S.p, S.q), np.maximum(S.p, S.q))
    i, s = pairs[:, 0], pairs[:, 1]
    vy = points[i, 1]
    k = np.flatnonzero((S.p[s, 1] > vy) != (S.q[s, 1] > vy))
    i, s = i[k], s[k]
    up = (S.p[s, 1] < S.q[s, 1])[:, None]
    lo, hi = np.where(up, S.p[s], S.q[s]), np.where(up, S.q[s], S.p[s])
    k = np.flatnonzero(_orient2d_flat(lo, hi, points[i]) < 0)
    return i[k], s[k]


def _ray_windings(points: np.ndarray, S: _Segments) -> np.ndarray:
    """Exact winding numbers (w_A, w_B), shape (C, 2), of the points just left of ``points``
    (see :func:`_ray_candidates`); a downward segment crossing the ray counts +1."""
    i, s = _ray_candidates(points, S)
    down = np.where(S.p[s, 1] > S.q[s, 1], 1, -1)
    flat = np.bincount(i * 2 + S.operand[s], weights=down, minlength=2 * points.shape[0])
    return flat.reshape(-1, 2).astype(np.int64)


def _potentials(N: int, src: np.ndarray, dst: np.ndarray, inc: np.ndarray, root: int) -> np.ndarray:
    """Node values ``w`` with ``w[dst] - w[src] = inc`` on a spanning tree from ``root`` (w[root] = 0)."""
    graph = coo_matrix((np.ones(src.shape[0]), (src, dst)), shape=(N, N)).tocsr()
    order, pred = breadth_first_order(graph, root, directed=False, return_predecessors=True)
    if order.shape[0] != N:
        raise BooleanError(
            "face nodes unreachable from the seeds",
            stage="classify",
            diagnostics={"reached": int(order.shape[0]), "nodes": N},
        )
    # Increment along each tree edge pred[x] -> x: look it up among both directions.
    keys = np.concatenate([src * N + dst, dst * N + src])
    vals = np.concatenate([inc, -inc])
    o = np.argsort(keys, kind="stable")
    keys, vals = keys[o], vals[o]
    nodes = np.arange(N)
    parent = np.where(nodes == root, root, pred)
    acc = np.zeros((N, inc.shape[1]), dtype=np.int64)
    nonroot = nodes != root
    acc[nonroot] = vals[np.searchsorted(keys, parent[nonroot] * N + nodes[nonroot])]
    # Pointer jumping: acc[x] = w[x] - w[anc[x]]; halve the distance to the root each round.
    anc = parent
    while np.any(anc != root):
        acc = acc + acc[anc]
        anc = anc[anc]
    return acc


# ====================================================================== phase 4: select
def _select(arr: _Arrangement, w: np.ndarray, op: str) -> tuple[np.ndarray, np.ndarray]:
    """Face nodes in R, and the half-edges with R on their left and not on their right."""
    in_r = OPERATIONS[op](w[:, 0] > 0, w[:, 1] > 0)
    H = arr.origin.shape[0]
    h = np.arange(H)
    sel = in_r[arr.face] & ~in_r[arr.face[h ^ 1]]
    return sel, in_r


# ====================================================================== phase 5: rings
@dataclass(frozen=True)
class _RingSet:
    """Result rings before assembly, as flat arrays: ring ``k`` is rows
    ``offsets[k]:offsets[k + 1]`` of ``xy`` (rounded coordinates), ``vid`` (arrangement vertex
    ids) and ``rounded`` (the vertex is a crossing point that is not a float); ``ccw`` and
    ``group`` (polygon) per ring."""

    xy: np.ndarray
    vid: np.ndarray
    rounded: np.ndarray
    offsets: np.ndarray
    ccw: np.ndarray
    group: np.ndarray

    @classmethod
    def empty(cls) -> "_RingSet":
        return cls(
            np.zeros((0, 2)), np.zeros(0, np.int64), np.zeros(0, bool), np.zeros(1, np.int64),
            np.zeros(0, bool), np.zeros(0, np.int64),
        )  # fmt: skip

    @property
    def n_rings(self) -> int:
        return self.offsets.shape[0] - 1

    def ring_of(self) -> np.ndarray:
        """(m,) ring index of every row."""
        return np.repeat(np.arange(self.n_rings), np.diff(self.offsets))

    def next_row(self) -> np.ndarray:
        """(m,) row of the next vertex around the same ring."""
        ring = self.ring_of()
        k = np.arange(self.xy.shape[0])
        return np.where(k + 1 == self.offsets[ring + 1], self.offsets[ring], k + 1)


def _rings(arr: _Arrangement, S: _Segments, sel: np.ndarray, in_r: np.ndarray) -> _RingSet:
    """Link the boundary half-edges into simple rings, orient them, attach holes, round."""
    hs = np.flatnonzero(sel)
    if hs.size == 0:
        return _RingSet.empty()
    # Successor: turn clockwise around the head vertex through faces of R until a boundary
    # half-edge; this keeps each angular sector of R at a vertex on its own ring.
    succ = arr.next[hs]
    pending = ~sel[succ]
    while pending.any():
        succ[pending] = arr.next[succ[pending] ^ 1]
        pending[pending] = ~sel[succ[pending]]
    index = np.full(arr.origin.shape[0], -1, dtype=np.int64)
    index[hs] = np.arange(hs.size)
    order, sizes = _cycles(index[succ])
    order, sizes = _split_at_repeated_vertices(arr.origin[hs], order, sizes)
    hh = hs[order]
    offsets = np.concatenate([[0], np.cumsum(sizes)])
    loop = np.repeat(np.arange(sizes.size), sizes)
    k = np.arange(hh.size)
    prev = hh[np.where(k == offsets[loop], offsets[loop + 1] - 1, k - 1)]
    v = arr.origin[hh]
    ccw = _loops_ccw(arr, v, prev, hh, loop, offsets)
    piece_face = arr.face[hh[offsets[:-1]]]
    # Straight-through new vertices used by one ring only are dropped (see the module docstring).
    straight = _cross_flat(arr.d0[prev], arr.d1[prev], arr.d0[hh], arr.d1[hh]) == 0
    sel_out = np.bincount(arr.origin[hs], minlength=arr.xy.shape[0])
    keep = ~(straight & ~arr.original[v] & (sel_out[v] == 1))
    v = v[keep]
    offsets = np.concatenate([[0], np.cumsum(np.bincount(loop[keep], minlength=sizes.size))])
    group = _groups(arr, S, in_r, piece_face)
    return _RingSet(arr.xy[v], v, v >= arr.n_float, offsets, ccw, group)


def _cycles(succ: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The cycles of a permutation: elements cycle by cycle, each from its smallest element
    in successor order (list ranking by pointer jumping), and the cycle sizes."""
    m = succ.shape[0]
    _n, label = connected_components(coo_matrix((np.ones(m), (np.arange(m), succ)), shape=(m, m)), directed=False)
    start = np.full(label.max() + 1, m, dtype=np.int64)
    np.minimum.at(start, label, np.arange(m))
    # Cut each cycle before its start; dist = steps to the cut.
    tail = succ == start[label]
    nxt = np.where(tail, np.arange(m), succ)
    dist = np.where(tail, 0, 1)
    while np.any(nxt != nxt[nxt]):
        dist = dist + dist[nxt]
        nxt = nxt[nxt]
    order = np.lexsort((-dist, label))
    return order, np.bincount(label)


def _split_at_repeated_vertices(
    vertex: np.ndarray, order: np.ndarray, sizes: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Split closed walks that visit a vertex twice into simple loops that touch there.

    ``vertex[order]`` are the walks' vertices, walk by walk.  Each second visit closes the
    loop walked since the first (a stack), which pairs the visits in their angular order
    around the vertex, so the loops touch without crossing.
    """
    loop = np.repeat(np.arange(sizes.size), sizes)
    key = loop * (int(vertex.max()) + 1) + vertex[order]
    ks = np.sort(key)
    dup = np.unique(ks[1:][ks[1:] == ks[:-1]] // (int(vertex.max()) + 1))
    if dup.size == 0:
        return order, sizes
    offsets = np.concatenate([[0], np.cumsum(sizes)])
    pieces = []
    split = set(dup.tolist())
    for w in range(sizes.size):
        walk = order[offsets[w] : offsets[w + 1]]
        if w not in split:
            pieces.append(walk)
            continue
        stack: list[int] = []
        where: dict[int, int] = {}
        for e, vert in zip(walk.tolist(), vertex[walk].tolist()):
            if vert in where:
                cut = where[vert]
                piece = stack[cut:]
                del stack[cut:]
                for ee in piece:
                    where.pop(int(vertex[ee]), None)
                pieces.append(np.array(piece, dtype=np.int64))
            where[vert] = len(stack)
            stack.append(e)
        pieces.append(np.array(stack, dtype=np.int64))
    return np.concatenate(pieces), np.array([p.size for p in pieces], dtype=np.int64)


def _lexmin_rows(xy: np.ndarray, loop: np.ndarray, offsets: np.ndarray) -> np.ndarray:
    """Row of the lexicographically smallest point of each loop (by the float coordinates)."""
    order = np.lexsort((xy[:, 1], xy[:, 0], loop))
    return order[offsets[:-1]]


def _loops_ccw(arr: _Arrangement, v, prev, hh, loop, offsets) -> np.ndarray:
    """Orientation of simple loops: the exact turn at each loop's lexicographically smallest
    vertex, which is strictly convex (an extreme vertex of a simple polygon)."""
    xy = arr.xy[v]
    k = _lexmin_rows(xy, loop, offsets)
    # Rounding is monotone, so the exact minimum has the minimal rounded x; the rounded order
    # can only be wrong among several rounded-x ties that include a crossing point.
    tie = xy[:, 0] == xy[k[loop], 0]
    n_tie = np.bincount(loop[tie], minlength=offsets.size - 1)
    n_new = np.bincount(loop[tie & (v >= arr.n_float)], minlength=offsets.size - 1)
    for L in np.flatnonzero((n_tie > 1) & (n_new > 0)).tolist():
        rows = offsets[L] + np.flatnonzero(tie[offsets[L] : offsets[L + 1]])
        k[L] = min(rows.tolist(), key=lambda r: arr.exact_xy(int(v[r])))
    turn = _cross_flat(arr.d0[prev[k]], arr.d1[prev[k]], arr.d0[hh[k]], arr.d1[hh[k]])
    if np.any(turn == 0):
        raise BooleanError("a result ring is degenerate at its extreme vertex", stage="select")
    return turn > 0


def _groups(arr: _Arrangement, S: _Segments, in_r: np.ndarray, piece_face: np.ndarray) -> np.ndarray:
    """Polygon id of each loop: loops whose left faces are joined through R belong together.

    Face nodes of R joined across edges with R on both sides form pieces.  A component lying
    inside a face of R contributes a piece joined to that face only geometrically: its
    anchor shoots a ray to the left, and the first edge hit bounds the enclosing face.
    """
    H = arr.origin.shape[0]
    h = np.arange(H)
    F = arr.n_faces
    inner = in_r[arr.face] & in_r[arr.face[h ^ 1]]
    src, dst = [arr.face[inner]], [arr.face[h[inner] ^ 1]]
    floating = np.flatnonzero(in_r[arr.outer_face])
    if floating.size:
        hits = _shoot_left(arr, S, arr.anchor[floating])
        if np.any(hits < 0):
            c = int(floating[np.flatnonzero(hits < 0)[0]])
            raise BooleanError(
                "a component inside R has nothing to its left", stage="select", diagnostics={"component": c}
            )
        src.append(arr.outer_face[floating])
        dst.append(arr.face[hits])
    src, dst = np.concatenate(src), np.concatenate(dst)
    _n, label = connected_components(coo_matrix((np.ones(src.size), (src, dst)), shape=(F, F)), directed=False)
    return label[piece_face]


def _shoot_left(arr: _Arrangement, S: _Segments, anchors: np.ndarray) -> np.ndarray:
    """For each anchor vertex, the half-edge, pointing down, of the first edge met by its
    leftward ray (see :func:`_ray_candidates`); -1 if none.

    The nearest crossing has the largest abscissa at ``y = v_y`` (ties: the largest
    ``dx/dy``, the abscissa at ``v_y + delta``).  A float estimate with a rounding-error bound
    keeps the candidates that can be the nearest; those are compared exactly (Fractions).
    """
    points = arr.xy[anchors]
    C = anchors.shape[0]
    out = np.full(C, -1, dtype=np.int64)
    i, s = _ray_candidates(points, S)
    if i.size == 0:
        return out
    up = (S.p[s, 1] < S.q[s, 1])[:, None]
    lo, hi = np.where(up, S.p[s], S.q[s]), np.where(up, S.q[s], S.p[s])
    with np.errstate(all="ignore"):
        x = lo[:, 0] + (points[i, 1] - lo[:, 1]) * ((hi[:, 0] - lo[:, 0]) / (hi[:, 1] - lo[:, 1]))
        # Five rounded operations on terms bounded by |x0| + |x1| (0 <= t < 1): 16 eps of that
        # bounds the error with margin; the tiny absolute term covers underflow.
        err = 16.0 * 2.0**-53 * (np.abs(lo[:, 0]) + np.abs(hi[:, 0])) + 2.0**-1060
        err = np.where(np.isfinite(x) & np.isfinite(err), err, np.inf)
        x = np.where(np.isfinite(x), x, 0.0)
        floor = np.full(C, -np.inf)
        np.maximum.at(floor, i, x - err)
        keep = np.flatnonzero(x + err >= floor[i])
    i, s, lo, hi = i[keep], s[keep], lo[keep], hi[keep]
    order = np.argsort(i, kind="stable")
    i, s, lo, hi = i[order], s[order], lo[order], hi[order]
    bounds = np.searchsorted(i, np.arange(C + 1))
    for c in np.flatnonzero(np.diff(bounds) > 0).tolist():
        a, b = bounds[c], bounds[c + 1]
        Y = Fraction(float(points[c, 1]))
        if b - a == 1:
            best = a
        else:

            def key(k: int) -> tuple[Fraction, Fraction]:
                x0, y0 = Fraction(float(lo[k, 0])), Fraction(float(lo[k, 1]))
                x1, y1 = Fraction(float(hi[k, 0])), Fraction(float(hi[k, 1]))
                slope = (x1 - x0) / (y1 - y0)
                return (x0 + (Y - y0) * slope, slope)

            best = max(range(a, b), key=key)
        out[c] = _straddling_half_edge(arr, int(s[best]), Y)
    return out


def _straddling_half_edge(arr: _Arrangement, s: int, Y: Fraction) -> int:
    """The downward half-edge of the piece of segment ``s`` that straddles ``y = Y + delta``."""
    a, b = arr.chain_start[s], arr.chain_start[s + 1]
    chain = arr.chain_vertex[a:b]
    vy = float(Y)
    above = np.array(
        [arr.xy[v, 1] > vy if v < arr.n_float else arr.exact_xy(v)[1] > Y for v in chain.tolist()], dtype=bool
    )
    k = int(np.flatnonzero(above[1:] != above[:-1])[0])
    e = int(arr.chain_edge[a + k])
    top = int(chain[k] if above[k] else chain[k + 1])
    return 2 * e if arr.edge_uv[e, 0] == top else 2 * e + 1


# ====================================================================== phase 6: round
def _rounding_defects(rs: _RingSet) -> list[str]:
    """What rounding the new vertices broke, checked exactly where it can have broken something.

    Vertices that were rounded (crossing points that are not floats) may now coincide with
    another vertex, their edges may cross, overlap or touch other edges, or a tiny ring may
    have turned over.  Pairs of edges that touch no rounded vertex are exactly as in the
    arrangement and are not re-examined.
    """
    if not rs.rounded.any():
        return []
    out = []
    V, vid, moved = rs.xy, rs.vid, rs.rounded
    # (a) distinct vertices that round to the same float point
    _u, inv = _unique_rows(V)
    base = int(vid.max()) + 1
    key = np.unique(inv * base + vid)  # distinct (point, vertex) combinations
    n_ids = np.bincount(key // base)
    clash = (n_ids[inv] > 1) & moved
    if clash.any():
        out.append(f"vertices merged by rounding at {V[np.flatnonzero(clash)[0]].tolist()}")
    # (b) edges at a rounded vertex against every edge whose box meets theirs
    nxt = rs.next_row()
    p, q = V, V[nxt]
    lo, hi = np.minimum(p, q), np.maximum(p, q)
    m = np.flatnonzero(moved | moved[nxt])
    pairs = overlapping_boxes(lo[m], hi[m], lo, hi)
    i, j = m[pairs[:, 0]], pairs[:, 1]
    keep = i != j
    i, j = i[keep], j[keep]
    rel, _ = _classify_flat(p[i], q[i], p[j], q[j])
    share = (vid[i] == vid[j]) | (vid[i] == vid[nxt[j]]) | (vid[nxt[i]] == vid[j]) | (vid[nxt[i]] == vid[nxt[j]])
    bad = (rel == SegmentRelation.CROSSING) | (rel == SegmentRelation.OVERLAP)
    bad |= (rel == SegmentRelation.TOUCHING) & ~share
    if bad.any():
        b = int(np.flatnonzero(bad)[0])
        out.append(f"edges {p[i[b]].tolist()}-{q[i[b]].tolist()} and {p[j[b]].tolist()}-{q[j[b]].tolist()} meet")
    # (c) a ring with rounded vertices that turned over (rings are simple here)
    if not out:
        ring = rs.ring_of()
        k = _lexmin_rows(V, ring, rs.offsets)
        prv = np.empty_like(nxt)
        prv[nxt] = np.arange(nxt.size)
        turn = _orient2d_flat(V[prv[k]], V[k], V[nxt[k]])
        has_moved = np.bincount(ring[moved], minlength=rs.n_rings) > 0
        flipped = has_moved & ((turn > 0) != rs.ccw)
        if flipped.any():
            out.append(f"a ring turned over when rounded, at {V[k[np.flatnonzero(flipped)[0]]].tolist()}")
    return out


def _ring_segments(rs: _RingSet) -> _Segments:
    """The rounded rings as segments of one operand, zero-length edges left out."""
    p, q = rs.xy, rs.xy[rs.next_row()]
    keep = np.any(p != q, axis=1)
    return _Segments(p[keep], q[keep], np.zeros(int(keep.sum()), dtype=np.int64))


# ====================================================================== assembly
def _assemble(rs: _RingSet) -> PolygonSet:
    """Canonical PolygonSet: one counter-clockwise outer per group, its clockwise holes, each
    ring starting at its lexicographically smallest vertex, holes and polygons sorted by it."""
    L = rs.n_rings
    if L == 0:
        return PolygonSet.empty()
    sizes = np.diff(rs.offsets)
    ring = rs.ring_of()
    first = _lexmin_rows(rs.xy, ring, rs.offsets)
    rot = rs.offsets[ring] + (np.arange(ring.size) - rs.offsets[ring] + (first[ring] - rs.offsets[ring])) % sizes[ring]
    xy = rs.xy[rot]
    n_outer = np.bincount(rs.group[rs.ccw], minlength=int(rs.group.max()) + 1)
    groups = np.unique(rs.group)
    if np.any(n_outer[groups] != 1):
        g = int(groups[np.flatnonzero(n_outer[groups] != 1)[0]])
        raise BooleanError(
            f"a polygon of the result has {int(n_outer[g])} outer rings, expected 1",
            stage="select",
            diagnostics={"group": g, "rings": np.flatnonzero(rs.group == g).tolist()},
        )
    # Sort key of a ring: its first two vertices (rings touching at their first vertex differ
    # in the second, since they share no edge).  Polygons by their outer ring's key; in each,
    # the outer ring first, then the holes by theirs.
    ring_key = np.concatenate([xy[rs.offsets[:-1]], xy[rs.offsets[:-1] + 1]], axis=1)
    outer_key = np.zeros((int(rs.group.max()) + 1, 4))
    outer_key[rs.group[rs.ccw]] = ring_key[rs.ccw]
    pk = outer_key[rs.group]
    order = np.lexsort((*ring_key.T[::-1], ~rs.ccw, rs.group, *pk.T[::-1]))
    rings = np.split(xy, rs.offsets[1:-1])
    for r in rings:
        r.setflags(write=False)
    polys = []
    gs = rs.group[order]
    cut = np.flatnonzero(np.diff(gs)) + 1
    for block in np.split(order, cut):
        polys.append(Polygon._trusted(rings[block[0]], tuple(rings[k] for k in block[1:].tolist())))
    return PolygonSet(tuple(polys))


def _rotate_to_min(r: np.ndarray) -> np.ndarray:
    k = int(np.lexsort((r[:, 1], r[:, 0]))[0])
    out = np.ascontiguousarray(np.roll(r, -k, axis=0))
    out.setflags(write=False)
    return out


# ====================================================================== checker
def check_polygon_set(polygons) -> CheckReport:
    """Check that a polygon set is canonical: what every Boolean result promises.

    Parameters
    ----------
    polygons : PolygonSet or anything :meth:`PolygonSet.coerce` accepts

    Returns
    -------
    CheckReport
        Problems with codes ``ring_not_simple``, ``ring_orientation`` (outer not
        counter-clockwise or hole not clockwise), ``overlap`` (a face covered twice),
        ``hole_outside`` (negative winding: a hole not inside its outer ring),
        ``shared_edge`` (an edge with the region on both sides or on neither, e.g. two
        polygons sharing an edge), ``vertex_on_edge`` (a ring vertex in the interior of
        another ring's edge), ``grouping`` (a hole attached to the wrong outer ring);
        entity ``"ring"`` (index into :meth:`PolygonSet.rings`), ``"face"``, ``"edge"`` or
        ``"polygon"``.
    """
    ps = PolygonSet.coerce(polygons)
    out: list[Problem] = []
    k = 0
    for pi, poly in enumerate(ps.polygons):
        for ri, r in enumerate(poly.rings):
            why = _self_intersection(r) if r.shape[0] >= 3 else "fewer than 3 vertices"
            if why is not None:
                out.append(Problem("ring_not_simple", "ring", k, f"polygon {pi} ring {ri}: {why}"))
            elif _ccw(r) != (ri == 0):
                want = "counter-clockwise" if ri == 0 else "clockwise"
                out.append(Problem("ring_orientation", "ring", k, f"polygon {pi} ring {ri}: expected {want}"))
            k += 1
    if out or ps.is_empty:
        return CheckReport(tuple(out), {"polygons": len(ps), "rings": k})
    S = _segments(ps, PolygonSet.empty())
    arr = _imprint(S, _intersect(S))
    w = _classify(arr, S)[:, 0]
    n_split = np.diff(arr.chain_start)
    for s_ in np.flatnonzero(n_split > 2).tolist():
        out.append(
            Problem(
                "vertex_on_edge", "edge", s_,
                f"ring edge {S.p[s_].tolist()}-{S.q[s_].tolist()} has {int(n_split[s_]) - 2} vertices of other "
                "rings in its interior (touching rings must share vertices)",
            )
        )  # fmt: skip
    for f in np.flatnonzero(w > 1).tolist():
        out.append(Problem("overlap", "face", f, f"a face has winding number {int(w[f])}, expected 0 or 1"))
    for f in np.flatnonzero(w < 0).tolist():
        out.append(Problem("hole_outside", "face", f, f"a face has winding number {int(w[f])}, expected 0 or 1"))
    for e in np.flatnonzero(np.abs(arr.counts[:, 0]) != 1).tolist():
        u, v = arr.edge_uv[e]
        out.append(
            Problem(
                "shared_edge", "edge", e,
                f"edge {arr.xy[u].tolist()}-{arr.xy[v].tolist()} is traversed with net count "
                f"{int(arr.counts[e, 0])}, expected +-1",
            )
        )  # fmt: skip
    if not out:
        canon = polygon_boolean(ps, PolygonSet.empty(), "union")
        mine = sorted(_polygon_signature(p) for p in ps.polygons)
        theirs = sorted(_polygon_signature(p) for p in canon.polygons)
        if mine != theirs:
            out.append(Problem("grouping", "polygon", 0, "holes are not attached to the outer rings that enclose them"))
    return CheckReport(tuple(out), {"polygons": len(ps), "rings": k})


def _polygon_signature(p: Polygon) -> tuple:
    return (
        _rotate_to_min(p.outer).tobytes(),
        tuple(sorted(_rotate_to_min(h).tobytes() for h in p.holes)),
    )


# ====================================================================== 3-D
@dataclass(frozen=True)
class PlaneFrame:
    """An orthonormal frame of a plane: ``origin`` and unit ``x_dir``, ``y_dir``, ``normal``
    (right-handed); local coordinates ``(x, y)`` map to ``origin + x x_dir + y y_dir``."""

    origin: np.ndarray
    x_dir: np.ndarray
    y_dir: np.ndarray
    normal: np.ndarray

    @classmethod
    def from_normal(cls, origin, normal, x_dir=None) -> "PlaneFrame":
        """A frame at ``origin`` with the given ``normal``.

        ``x_dir`` (optional) is projected into the plane; by default it is the projection
        of the world axis least aligned with the normal (so the frame depends only on the
        plane, not on the operands).

        Raises
        ------
        InvalidInputError
            Non-finite or zero vectors, or an ``x_dir`` parallel to the normal.
        """
        o = _vec3(origin, "plane_origin")
        n = _vec3(normal, "plane_normal")
        norm = float(np.linalg.norm(n))
        if norm == 0.0:
            raise InvalidInputError("plane_normal must be a non-zero vector, got [0, 0, 0]")
        n = n / norm
        if x_dir is None:
            x = np.eye(3)[int(np.argmin(np.abs(n)))]
        else:
            x = _vec3(x_dir, "x_dir")
        x = x - np.dot(x, n) * n
        xn = float(np.linalg.norm(x))
        if xn == 0.0:
            raise InvalidInputError(
                f"x_dir must not be parallel to the normal {n.tolist()}, got {np.asarray(x_dir).tolist()}"
            )
        x = x / xn
        y = np.cross(n, x)
        for a in (o, x, y, n):
            a.setflags(write=False)
        return cls(o, x, y, n)

    def to_local(self, points: np.ndarray) -> np.ndarray:
        """``(..., 3)`` -> ``(..., 2)`` plane coordinates."""
        d = np.asarray(points, dtype=np.float64) - self.origin
        return np.stack([d @ self.x_dir, d @ self.y_dir], axis=-1)

    def to_global(self, uv: np.ndarray) -> np.ndarray:
        """``(..., 2)`` plane coordinates -> ``(..., 3)`` points."""
        uv = np.asarray(uv, dtype=np.float64)
        return self.origin + uv[..., :1] * self.x_dir + uv[..., 1:2] * self.y_dir


class Polygon3D(NamedTuple):
    """A planar polygon in space: ``outer`` (n, 3) counter-clockwise about the plane normal,
    ``holes`` clockwise."""

    outer: np.ndarray
    holes: tuple[np.ndarray, ...]


def _vec3(v, what: str) -> np.ndarray:
    a = np.array(v, dtype=np.float64)
    if a.shape != (3,) or not np.all(np.isfinite(a)):
        raise InvalidInputError(f"{what} must be a finite 3-vector, got {v!r}")
    return a


def _rings_3d(obj, what: str) -> list[tuple[np.ndarray, list[np.ndarray]]]:
    """Parse a ring (n, 3), an (outer, holes) tuple, or a sequence of those."""

    def ring_like(x) -> bool:
        try:
            a = np.asarray(x, dtype=np.float64)
        except (TypeError, ValueError):
            return False
        return a.ndim == 2

    if isinstance(obj, Polygon3D):
        return [(np.asarray(obj.outer, np.float64), [np.asarray(h, np.float64) for h in obj.holes])]
    if ring_like(obj):
        return [(np.asarray(obj, np.float64), [])]
    if isinstance(obj, tuple) and len(obj) == 2 and ring_like(obj[0]) and isinstance(obj[1], (list, tuple)):
        if all(ring_like(h) for h in obj[1]):
            return [(np.asarray(obj[0], np.float64), [np.asarray(h, np.float64) for h in obj[1]])]
    if isinstance(obj, (list, tuple)):
        out = []
        for k, item in enumerate(obj):
            out.extend(_rings_3d(item, f"{what} polygon {k}"))
        return out
    raise InvalidInputError(
        f"{what}: expected a ring (n, 3), an (outer, holes) tuple or a sequence of those, got {type(obj).__name__}"
    )


def _to_plane(obj, frame: PlaneFrame, t: Tolerance, what: str) -> PolygonSet:
    polys = []
    for k, (outer, holes) in enumerate(_rings_3d(obj, what)):
        for r in (outer, *holes):
            if r.ndim != 2 or r.shape[1] != 3:
                raise InvalidInputError(f"{what} polygon {k}: expected rings of shape (n, 3), got {r.shape}")
            if not np.all(np.isfinite(r)):
                raise InvalidInputError(f"{what} polygon {k}: coordinates must be finite, got NaN or inf")
            dist = np.abs((r - frame.origin) @ frame.normal)
            if dist.size and float(dist.max()) > t.linear:
                raise InvalidInputError(
                    f"{what} polygon {k}: a vertex lies {float(dist.max())!r} from the plane, "
                    f"expected at most tol.linear = {t.linear!r}"
                )
        polys.append((frame.to_local(outer), [frame.to_local(h) for h in holes]))
    return _coerce(polys, what)


def planar_boolean(
    a3d, b3d, plane_origin, plane_normal, op: str, *, x_dir=None, tol: Tolerance | None = None
) -> list[Polygon3D]:
    """Exact Boolean of polygons lying on one plane in 3-D.

    Parameters
    ----------
    a3d, b3d : ring (n, 3), (outer, holes) tuple, Polygon3D, or a sequence of those
    plane_origin, plane_normal : (3,) array_like
    op : {"union", "intersection", "difference", "symmetric_difference"}
    x_dir : (3,) array_like, optional
        The frame's x direction (see :meth:`PlaneFrame.from_normal`).
    tol : Tolerance, optional
        Every vertex must lie within ``tol.linear`` of the plane.

    Returns
    -------
    list of Polygon3D
        The result mapped back to space: outers counter-clockwise seen from the side the
        normal points to.  The 2-D Boolean is exact on the projected coordinates; the
        projection and the map back each round to about one ulp of the coordinates.

    Raises
    ------
    InvalidInputError
        Bad vectors or shapes, NaN/inf, a vertex off the plane by more than
        ``tol.linear``, a ring that is not simple once projected, an unknown ``op``.
    """
    t = resolve(tol)
    if op not in OPERATIONS:
        raise InvalidInputError(f"op must be one of {sorted(OPERATIONS)}, got {op!r}")
    frame = PlaneFrame.from_normal(plane_origin, plane_normal, x_dir)
    A = _to_plane(a3d, frame, t, "operand a")
    B = _to_plane(b3d, frame, t, "operand b")
    result = polygon_boolean(A, B, op)
    return [
        Polygon3D(frame.to_global(p.outer), tuple(frame.to_global(h) for h in p.holes)) for p in result.polygons
    ]
