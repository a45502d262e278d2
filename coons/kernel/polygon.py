"""Planar polygons: rings, exact point location, simplicity, and the :class:`PolygonSet` value.

A *ring* is a closed polyline given as an ``(n, 2)`` float64 array of its ``n >= 3``
distinct vertices (the closing edge from the last vertex back to the first is implied; a
repeated first vertex at the end is accepted and removed).  This module answers questions
about rings exactly — the sign of the area, the winding number of points, whether a point
lies on the boundary, whether a ring is simple — using the exact predicates of
:mod:`coons.kernel.predicates`, and it holds :class:`Polygon` and :class:`PolygonSet`,
frozen values over read-only arrays with outer rings counter-clockwise and holes
clockwise.  It deliberately does not compute Booleans, offsets or triangulations (those
live in :mod:`coons.booleans.planar` and :mod:`coons.topology`), and it never repairs a
ring: bad input raises :class:`~coons.errors.InvalidInputError`.

The region of a :class:`PolygonSet` is the set of points whose winding number, summed
over all of its rings (outers counter-clockwise, holes clockwise), is positive.  For a
*canonical* set — polygons with disjoint interiors, each hole inside its own outer ring,
rings meeting at most in isolated shared vertices — that is the usual meaning; every
result of :mod:`coons.booleans.planar` is canonical (its checker is
:func:`coons.booleans.planar.check_polygon_set`).  Inputs that overlap are read with this
rule, so a union of overlapping polygons given as one set means what it looks like.
"""

from __future__ import annotations

import enum
import math
from dataclasses import dataclass
from typing import Iterator, NamedTuple

import numpy as np

from coons.errors import InvalidInputError
from coons.kernel.predicates import SegmentRelation, _classify_flat, _exact_integers, _orient2d_flat

__all__ = [
    "Location",
    "Winding",
    "as_ring",
    "signed_area",
    "winding_number",
    "point_in_polygon",
    "is_simple",
    "proper_crossings",
    "normalize",
    "overlapping_boxes",
    "Polygon",
    "PolygonSet",
]

_EPS = 2.0**-53  # unit round-off of float64
#: Point–edge pairs examined per batch of the winding-number kernel (a few MB of temporaries).
_PAIR_CHUNK = 1 << 20


class Location(enum.IntEnum):
    """Where a point lies with respect to a ring or polygon set (int8 codes)."""

    OUTSIDE = 0
    INSIDE = 1
    BOUNDARY = 2


class Winding(NamedTuple):
    """Winding numbers of points, with the points on the boundary marked.

    Attributes
    ----------
    number : (m,) int64
        Winding number of each point not on the boundary (0 for points on it).
    on_boundary : (m,) bool
        The point lies on an edge or is a vertex.
    """

    number: np.ndarray
    on_boundary: np.ndarray


# ---------------------------------------------------------------------- rings
def proper_crossings(a: np.ndarray, b: np.ndarray, c: np.ndarray, d: np.ndarray) -> np.ndarray:
    """``(k,)`` whether segment ``a b`` properly crosses ``c d`` (rows ``(k, 2)``): strict orientation
    signs on both sides.  Zero-length segments (repeated samples where cuts join) never cross: their
    orientation signs are 0.

    Floating-point signs, not the exact predicates of this module's ring tests: for callers that
    look for chords to refine or rings to re-test (a crossing missed by round-off is a crossing of
    segments within round-off of touching), never for a topological decision.
    """
    def orient(p, q, r):
        return np.sign((q[:, 0] - p[:, 0]) * (r[:, 1] - p[:, 1]) - (q[:, 1] - p[:, 1]) * (r[:, 0] - p[:, 0]))

    d1, d2, d3, d4 = orient(a, b, c), orient(a, b, d), orient(c, d, a), orient(c, d, b)
    return (d1 * d2 < 0) & (d3 * d4 < 0)


def as_ring(ring, *, what: str = "ring") -> np.ndarray:
    """A ring as a read-only ``(n, 2)`` float64 array.

    A last vertex equal to the first (an explicitly closed ring) is removed, and negative
    zeros become +0.0 (same value, so that equal points have equal bits).

    Raises
    ------
    InvalidInputError
        Not an ``(n, 2)`` array, NaN/inf coordinates, fewer than 3 vertices.
    """
    try:
        r = np.array(ring, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise InvalidInputError(f"{what}: expected an (n, 2) array of vertices, got {type(ring).__name__}") from exc
    if r.ndim != 2 or r.shape[1] != 2:
        raise InvalidInputError(f"{what}: expected an (n, 2) array of vertices, got shape {r.shape}")
    if not np.all(np.isfinite(r)):
        bad = int(np.argwhere(~np.isfinite(r))[0][0])
        raise InvalidInputError(f"{what}: vertex {bad} has a NaN or inf coordinate: {r[bad].tolist()}")
    if r.shape[0] >= 2 and np.array_equal(r[0], r[-1]):
        r = r[:-1]
    if r.shape[0] < 3:
        raise InvalidInputError(f"{what}: expected at least 3 distinct vertices, got {r.shape[0]}")
    r = r + 0.0  # -0.0 -> +0.0, so equal points have equal bits
    r.setflags(write=False)
    return r


def signed_area(ring) -> float:
    """Signed area of a ring (shoelace formula), positive when counter-clockwise.

    Parameters
    ----------
    ring : (n, 2) array_like

    Returns
    -------
    float
        The float64 shoelace sum, whose sign is exact: when the sum is within its
        rounding-error bound of zero it is recomputed exactly in integer arithmetic and
        returned correctly rounded (so 0.0 means zero area, except that an area below the
        smallest subnormal rounds to a zero carrying the exact sign bit, and one beyond the
        float range to an infinity).

    Raises
    ------
    InvalidInputError
        See :func:`as_ring`.

    Examples
    --------
    >>> signed_area([[0, 0], [2, 0], [2, 1], [0, 1]])
    2.0
    """
    r = as_ring(ring)
    return _signed_area(r)


def _signed_area(r: np.ndarray) -> float:
    n = r.shape[0]
    x, y = r[:, 0], r[:, 1]
    xn, yn = np.roll(x, -1), np.roll(y, -1)
    with np.errstate(all="ignore"):  # overflow and underflow fall through to the exact sum
        terms = x * yn - xn * y
        total = float(np.sum(terms))
        # Each term has relative error <= eps (product) and <= 2 eps (difference); pairwise or
        # sequential summation of n terms adds at most (n - 1) eps · sum|terms| (Higham, "Accuracy
        # and Stability of Numerical Algorithms" §4.2).  (n + 3) eps bounds the total with margin;
        # the absolute term covers products and differences that underflow (half a subnormal
        # ulp, 2^-1075, each).
        bound = (n + 3) * _EPS * float(np.sum(np.abs(x * yn) + np.abs(xn * y))) + 3 * n * 2.0**-1075
    if abs(total) > bound and np.isfinite(total):
        return 0.5 * total
    X, s = _exact_integers(r.reshape(1, -1))
    Xi = X.reshape(-1, 2)
    xs, ys = Xi[:, 0], Xi[:, 1]
    twice = int(np.sum(xs * np.roll(ys, -1) - np.roll(xs, -1) * ys))
    scale = 2 * int(s[0]) - 1  # area = twice / 2 · 2^(2 s)
    try:
        return float(twice << scale) if scale >= 0 else twice / (1 << -scale)
    except OverflowError:  # an area beyond the float range
        return math.copysign(math.inf, twice)


def _winding_edges(points: np.ndarray, p: np.ndarray, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Winding numbers of ``points`` (m, 2) about the closed edge set ``p -> q`` (n, 2), and the
    points lying on an edge.  Sunday's crossing rule with exact orientations."""
    m, n = points.shape[0], p.shape[0]
    number = np.zeros(m, dtype=np.int64)
    boundary = np.zeros(m, dtype=bool)
    if m == 0 or n == 0:
        return number, boundary
    lo, hi = np.minimum(p, q), np.maximum(p, q)
    step = max(1, _PAIR_CHUNK // n)
    for start in range(0, m, step):
        pts = points[start : start + step]
        py = pts[:, 1:2]
        up = (p[:, 1] <= py) & (q[:, 1] > py)
        down = (q[:, 1] <= py) & (p[:, 1] > py)
        inbox = (lo[:, 0] <= pts[:, 0:1]) & (pts[:, 0:1] <= hi[:, 0]) & (lo[:, 1] <= py) & (py <= hi[:, 1])
        i, e = np.nonzero(up | down | inbox)
        o = _orient2d_flat(p[e], q[e], pts[i])
        on = inbox[i, e] & (o == 0)
        contrib = np.where(up[i, e] & (o > 0), 1, 0) - np.where(down[i, e] & (o < 0), 1, 0)
        number[start : start + step] = np.bincount(i, weights=contrib, minlength=pts.shape[0]).astype(np.int64)
        boundary[start : start + step] = np.bincount(i, weights=on, minlength=pts.shape[0]) > 0
    number[boundary] = 0
    return number, boundary


def _as_points(points, what: str = "points") -> tuple[np.ndarray, tuple[int, ...]]:
    P = np.asarray(points, dtype=np.float64)
    if P.ndim == 0 or P.shape[-1] != 2:
        raise InvalidInputError(f"{what}: expected an array of shape (..., 2), got shape {P.shape}")
    if not np.all(np.isfinite(P)):
        raise InvalidInputError(f"{what}: coordinates must be finite, got NaN or inf")
    return P.reshape(-1, 2), P.shape[:-1]


def winding_number(points, ring) -> Winding:
    """Exact winding numbers of points about a ring.

    Parameters
    ----------
    points : (..., 2) array_like
    ring : (n, 2) array_like

    Returns
    -------
    Winding
        ``number`` (shape ``...``, int64) and ``on_boundary`` (shape ``...``, bool).  The
        crossing rule of Sunday ("Inclusion of a point in a polygon", 2001) with every
        left/right decision made by the exact orient2d, so no point is misclassified.

    Raises
    ------
    InvalidInputError
        Bad shapes, NaN or inf.

    Examples
    --------
    >>> w = winding_number([[1, 1], [3, 1], [2, 0]], [[0, 0], [2, 0], [2, 2], [0, 2]])
    >>> w.number.tolist(), w.on_boundary.tolist()
    ([1, 0, 0], [False, False, True])
    """
    P, shape = _as_points(points)
    r = as_ring(ring)
    number, boundary = _winding_edges(P, r, np.roll(r, -1, axis=0))
    return Winding(number.reshape(shape), boundary.reshape(shape))


def point_in_polygon(points, ring) -> np.ndarray:
    """Exact location of points with respect to a ring: OUTSIDE, INSIDE or BOUNDARY.

    Parameters
    ----------
    points : (..., 2) array_like
    ring : (n, 2) array_like
        A simple ring, either orientation (inside = non-zero winding number).

    Returns
    -------
    (...) int8
        :class:`Location` codes.

    Raises
    ------
    InvalidInputError
        Bad shapes, NaN or inf.
    """
    w = winding_number(points, ring)
    return _location(w.number != 0, w.on_boundary)


def _location(inside: np.ndarray, boundary: np.ndarray) -> np.ndarray:
    loc = np.where(inside, Location.INSIDE, Location.OUTSIDE).astype(np.int8)
    loc[boundary] = Location.BOUNDARY
    return loc


# ---------------------------------------------------------------------- broad phase
def overlapping_boxes(lo, hi, lo2=None, hi2=None) -> np.ndarray:
    """All pairs of overlapping closed axis-aligned boxes (sort and sweep, vectorised).

    Parameters
    ----------
    lo, hi : (n, 2) array_like
        Lower and upper corners.
    lo2, hi2 : (m, 2) array_like, optional
        A second set of boxes: pairs are then taken between the two sets.

    Returns
    -------
    (k, 2) int64
        Pairs ``(i, j)`` whose closed boxes share a point (touching counts): ``i < j`` within
        one set, or ``i`` into the first and ``j`` into the second set.  The sweep runs
        along the axis that yields fewer candidates; the work is ``O(n log n + c)`` for
        ``c`` candidate pairs overlapping along that axis.
    """
    lo = np.asarray(lo, dtype=np.float64).reshape(-1, 2)
    hi = np.asarray(hi, dtype=np.float64).reshape(-1, 2)
    two = lo2 is not None
    if two:
        lo2 = np.asarray(lo2, dtype=np.float64).reshape(-1, 2)
        hi2 = np.asarray(hi2, dtype=np.float64).reshape(-1, 2)
    best = None
    for axis in (0, 1):
        ranges = _sweep_ranges(lo[:, axis], hi[:, axis], lo2[:, axis] if two else None, hi2[:, axis] if two else None)
        total = sum(int((stop - start).sum()) for _, start, stop, _ in ranges)
        if best is None or total < best[0]:
            best = (total, axis, ranges)
    _total, axis, ranges = best
    other = 1 - axis
    la, ha = lo, hi
    lb, hb = (lo2, hi2) if two else (lo, hi)
    out = []
    for owner, start, stop, flip in ranges:
        for a, b in _expand(owner, start, stop):
            i, j = (b, a) if flip else (a, b)
            keep = (la[i, other] <= hb[j, other]) & (lb[j, other] <= ha[i, other])
            out.append(np.stack([i[keep], j[keep]], axis=1))
    if not out:
        return np.zeros((0, 2), dtype=np.int64)
    pairs = np.concatenate(out).astype(np.int64)
    if not two:
        pairs = np.sort(pairs, axis=1)
    return pairs


def _sweep_ranges(lo, hi, lo2, hi2):
    """Candidate ranges along one axis: (owner ids, start, stop, flipped) in sorted-order space,
    each range listing partners as original indices via the sorted order."""
    if lo2 is None:
        order = np.argsort(lo, kind="stable")
        s = lo[order]
        stop = np.searchsorted(s, hi[order], side="right")
        start = np.arange(lo.size) + 1
        return [(order, start, np.maximum(stop, start), False)]
    o1, o2 = np.argsort(lo, kind="stable"), np.argsort(lo2, kind="stable")
    s1, s2 = lo[o1], lo2[o2]
    # Type 1: lo1 <= lo2 <= hi1 (owner in the first set); type 2: lo2 < lo1 <= hi2.
    st1, sp1 = np.searchsorted(s2, s1, side="left"), np.searchsorted(s2, hi[o1], side="right")
    st2, sp2 = np.searchsorted(s1, s2, side="right"), np.searchsorted(s1, hi2[o2], side="right")
    return [((o1, o2), st1, np.maximum(sp1, st1), False), ((o2, o1), st2, np.maximum(sp2, st2), True)]


def _expand(owner, start: np.ndarray, stop: np.ndarray):
    """Yield blocks of pairs (owner index, partner index) for the ranges [start, stop)."""
    if isinstance(owner, tuple):
        own, part = owner
    else:
        own = part = owner
    counts = stop - start
    csum = np.concatenate([[0], np.cumsum(counts)])
    n = counts.size
    b0 = 0
    while b0 < n:
        # Blocks of owners bounded so the candidate arrays stay a few MB.
        b1 = int(np.searchsorted(csum, csum[b0] + _PAIR_CHUNK, side="right")) - 1
        b1 = min(max(b1, b0 + 1), n)
        c = counts[b0:b1]
        k = int(c.sum())
        if k:
            i = np.repeat(np.arange(b0, b1), c)
            j = np.repeat(start[b0:b1], c) + (np.arange(k) - np.repeat(csum[b0:b1] - csum[b0], c))
            yield own[i], part[j]
        b0 = b1


# ---------------------------------------------------------------------- simplicity
def _point_str(p: np.ndarray) -> str:
    return f"({float(p[0])!r}, {float(p[1])!r})"


def _segment_str(r: np.ndarray, i: int) -> str:
    n = r.shape[0]
    return f"segment {i} {_point_str(r[i])}-{_point_str(r[(i + 1) % n])}"


def _self_intersection(r: np.ndarray) -> str | None:
    """Why the ring ``r`` (validated by :func:`as_ring`) is not simple, or None if it is."""
    n = r.shape[0]
    # Repeated vertices: equal rows sort next to each other.
    order = np.lexsort((r[:, 1], r[:, 0]))
    same = np.all(r[order[1:]] == r[order[:-1]], axis=1)
    if same.any():
        k = int(np.flatnonzero(same)[0])
        i, j = sorted((int(order[k]), int(order[k + 1])))
        return f"vertex {i} and vertex {j} are the same point {_point_str(r[i])}"
    a, b, c = r, np.roll(r, -1, axis=0), np.roll(r, -2, axis=0)
    o = _orient2d_flat(a, b, c)
    # Collinear consecutive edges fold back when a and c lie on the same side of b.
    fold = (o == 0) & (np.sign(a[:, 0] - b[:, 0]) == np.sign(c[:, 0] - b[:, 0]))
    fold &= np.sign(a[:, 1] - b[:, 1]) == np.sign(c[:, 1] - b[:, 1])
    if fold.any():
        i = int(np.flatnonzero(fold)[0])
        return f"{_segment_str(r, i)} and {_segment_str(r, (i + 1) % n)} overlap (the ring folds back)"
    pairs = overlapping_boxes(np.minimum(a, b), np.maximum(a, b))
    i, j = pairs[:, 0], pairs[:, 1]
    nonadjacent = (j - i != 1) & ~((i == 0) & (j == n - 1))
    i, j = i[nonadjacent], j[nonadjacent]
    rel, _ = _classify_flat(a[i], b[i], a[j], b[j])
    bad = np.flatnonzero(rel != SegmentRelation.DISJOINT)
    if bad.size:
        k = bad[np.lexsort((j[bad], i[bad]))[0]]
        verb = {
            SegmentRelation.CROSSING: "crosses",
            SegmentRelation.TOUCHING: "touches",
            SegmentRelation.OVERLAP: "overlaps",
        }[SegmentRelation(int(rel[k]))]
        return f"{_segment_str(r, int(i[k]))} {verb} {_segment_str(r, int(j[k]))}"
    return None


def is_simple(ring) -> bool:
    """Whether a ring is simple: distinct vertices, and edges meeting only where consecutive
    edges share their common vertex (exact).

    Parameters
    ----------
    ring : (n, 2) array_like

    Returns
    -------
    bool
        Decided by exact segment relations over the pairs of a sort-and-sweep broad phase
        (Shamos–Hoey's question, answered with all candidate pairs rather than a sweep
        line), so a ring that touches itself at a single point is not simple.

    Raises
    ------
    InvalidInputError
        See :func:`as_ring`.

    Examples
    --------
    >>> is_simple([[0, 0], [1, 0], [1, 1], [0, 1]]), is_simple([[0, 0], [1, 1], [1, 0], [0, 1]])
    (True, False)
    """
    return _self_intersection(as_ring(ring)) is None


def _validated_ring(ring, what: str) -> np.ndarray:
    r = as_ring(ring, what=what)
    why = _self_intersection(r)
    if why is not None:
        raise InvalidInputError(f"{what} is not simple: {why}")
    return r


def _ccw(r: np.ndarray) -> bool:
    """Orientation of a simple ring: the exact turn at its lexicographically smallest vertex."""
    k = int(np.lexsort((r[:, 1], r[:, 0]))[0])
    n = r.shape[0]
    o = _orient2d_flat(r[[(k - 1) % n]], r[[k]], r[[(k + 1) % n]])
    return bool(o[0] > 0)


def _oriented(r: np.ndarray, ccw: bool) -> np.ndarray:
    if _ccw(r) == ccw:
        return r
    out = r[::-1].copy()
    out.setflags(write=False)
    return out


def normalize(outer, holes=()) -> tuple[np.ndarray, tuple[np.ndarray, ...]]:
    """Orient a polygon's rings: outer counter-clockwise, holes clockwise.

    Parameters
    ----------
    outer : (n, 2) array_like
        A simple ring.
    holes : sequence of (m_i, 2) array_like
        Simple rings.

    Returns
    -------
    outer : (n, 2) float64, read-only
    holes : tuple of (m_i, 2) float64, read-only
        The same rings, reversed where needed (orientation from the exact turn at the
        lexicographically smallest vertex, which is strictly convex in a simple ring).

    Raises
    ------
    InvalidInputError
        A ring that is not an (n, 2) finite array of at least 3 vertices, or not simple
        (the message names the ring and the offending segments).
    """
    o = _oriented(_validated_ring(outer, "outer ring"), True)
    hs = tuple(_oriented(_validated_ring(h, f"hole {k}"), False) for k, h in enumerate(holes))
    return o, hs


# ---------------------------------------------------------------------- values
def _bounds_of(rings) -> np.ndarray:
    if not rings:
        return np.full((2, 2), np.nan)
    pts = np.concatenate(rings)
    return np.stack([pts.min(axis=0), pts.max(axis=0)])


@dataclass(frozen=True, eq=False)
class Polygon:
    """One polygon: a counter-clockwise outer ring and clockwise holes.

    Parameters
    ----------
    outer : (n, 2) array_like
        A simple ring; reversed if given clockwise.
    holes : sequence of (m_i, 2) array_like
        Simple rings; reversed if given counter-clockwise.

    Raises
    ------
    InvalidInputError
        A ring with a bad shape, NaN/inf, fewer than 3 vertices, or not simple.

    Notes
    -----
    Each ring is validated alone; whether the holes lie inside the outer ring is not
    checked here (see the module docstring for how such a polygon is read).
    """

    outer: np.ndarray
    holes: tuple[np.ndarray, ...] = ()

    def __post_init__(self) -> None:
        o, hs = normalize(self.outer, self.holes)
        object.__setattr__(self, "outer", o)
        object.__setattr__(self, "holes", hs)

    @classmethod
    def _trusted(cls, outer: np.ndarray, holes: tuple[np.ndarray, ...]) -> "Polygon":
        """A polygon from rings already known to be simple and oriented (no validation)."""
        p = object.__new__(cls)
        for r in (outer, *holes):
            r.setflags(write=False)
        object.__setattr__(p, "outer", outer)
        object.__setattr__(p, "holes", tuple(holes))
        return p

    @property
    def rings(self) -> tuple[np.ndarray, ...]:
        """The outer ring followed by the holes."""
        return (self.outer, *self.holes)

    @property
    def area(self) -> float:
        """Area (outer minus holes)."""
        return float(sum(_signed_area(r) for r in self.rings))

    @property
    def bounds(self) -> np.ndarray:
        """``(2, 2)`` float64: ``[[xmin, ymin], [xmax, ymax]]``."""
        return _bounds_of([self.outer])

    def contains(self, points) -> np.ndarray:
        """Exact :class:`Location` codes (int8, shape ``...``) of points ``(..., 2)``."""
        return PolygonSet((self,)).contains(points)


def _is_ring_like(obj) -> bool:
    if isinstance(obj, (Polygon, PolygonSet)):
        return False
    try:
        a = np.asarray(obj, dtype=np.float64)
    except (TypeError, ValueError):
        return False
    return a.ndim == 2


def _is_outer_holes(obj) -> bool:
    return (
        isinstance(obj, tuple)
        and len(obj) == 2
        and _is_ring_like(obj[0])
        and isinstance(obj[1], (list, tuple))
        and all(_is_ring_like(h) for h in obj[1])
    )


def _as_polygon(obj) -> Polygon:
    if isinstance(obj, Polygon):
        return obj
    if _is_ring_like(obj):
        return Polygon(obj)
    if _is_outer_holes(obj):
        return Polygon(obj[0], tuple(obj[1]))
    raise InvalidInputError(f"expected a ring (n, 2), an (outer, holes) tuple or a Polygon, got {type(obj).__name__}")


@dataclass(frozen=True, eq=False)
class PolygonSet:
    """A set of polygons with holes: the region of the plane they cover.

    Parameters
    ----------
    polygons : sequence of Polygon

    Notes
    -----
    The region is the set of points whose total winding number over all rings is positive
    (see the module docstring).  Use :meth:`coerce` to build a set from rings and
    ``(outer, holes)`` tuples.  Results of the Booleans in :mod:`coons.booleans.planar`
    are canonical: rings start at their lexicographically smallest vertex, holes and
    polygons are sorted by it.

    Raises
    ------
    InvalidInputError
        An element that is not a :class:`Polygon`.

    Examples
    --------
    >>> s = PolygonSet.coerce(([[0, 0], [4, 0], [4, 4], [0, 4]], [[[1, 1], [1, 2], [2, 2], [2, 1]]]))
    >>> s.area
    15.0
    >>> s.contains([[0.5, 0.5], [1.5, 1.5], [4.0, 1.0]]).tolist()
    [1, 0, 2]
    """

    polygons: tuple[Polygon, ...] = ()

    def __post_init__(self) -> None:
        polys = tuple(self.polygons)
        for k, p in enumerate(polys):
            if not isinstance(p, Polygon):
                raise InvalidInputError(f"polygon {k}: expected a Polygon, got {type(p).__name__}")
        object.__setattr__(self, "polygons", polys)

    @classmethod
    def coerce(cls, obj) -> "PolygonSet":
        """A PolygonSet from a PolygonSet, a Polygon, a ring ``(n, 2)``, an ``(outer, holes)``
        tuple, or a sequence of those (an ``(k, n, 2)`` array is a sequence of rings; an empty
        sequence gives the empty set).

        Raises
        ------
        InvalidInputError
            Anything else, or a ring that is not valid (named by polygon and ring).
        """
        if isinstance(obj, PolygonSet):
            return obj
        if isinstance(obj, Polygon) or _is_ring_like(obj) or _is_outer_holes(obj):
            items = [obj]
        elif isinstance(obj, (list, tuple)) or (isinstance(obj, np.ndarray) and obj.ndim == 3):
            items = list(obj)
        else:
            items = None
        if items is not None:
            polys = []
            for k, item in enumerate(items):
                try:
                    polys.append(_as_polygon(item))
                except InvalidInputError as exc:
                    raise InvalidInputError(f"polygon {k}: {exc}") from exc
            return cls(tuple(polys))
        raise InvalidInputError(
            "expected a PolygonSet, a Polygon, a ring (n, 2), an (outer, holes) tuple or a sequence of those, "
            f"got {type(obj).__name__}"
        )

    @classmethod
    def empty(cls) -> "PolygonSet":
        """The empty set."""
        return cls(())

    def __len__(self) -> int:
        return len(self.polygons)

    def __iter__(self) -> Iterator[Polygon]:
        return iter(self.polygons)

    @property
    def is_empty(self) -> bool:
        return not self.polygons

    def rings(self) -> list[np.ndarray]:
        """Every ring, polygon by polygon (outer first, then its holes)."""
        return [r for p in self.polygons for r in p.rings]

    @property
    def n_vertices(self) -> int:
        return sum(r.shape[0] for r in self.rings())

    @property
    def area(self) -> float:
        """Sum of the polygons' areas (the region's area for a canonical set)."""
        return float(sum(p.area for p in self.polygons))

    @property
    def bounds(self) -> np.ndarray:
        """``(2, 2)`` float64 ``[[xmin, ymin], [xmax, ymax]]`` (NaN for the empty set)."""
        return _bounds_of([p.outer for p in self.polygons])

    def edges(self) -> tuple[np.ndarray, np.ndarray]:
        """Start and end points ``(e, 2)`` of every directed ring edge."""
        rings = self.rings()
        if not rings:
            z = np.zeros((0, 2))
            return z, z
        return np.concatenate(rings), np.concatenate([np.roll(r, -1, axis=0) for r in rings])

    def contains(self, points) -> np.ndarray:
        """Exact location of points in the region.

        Parameters
        ----------
        points : (..., 2) array_like

        Returns
        -------
        (...) int8
            :class:`Location` codes: BOUNDARY on any ring, else INSIDE where the total
            winding number is positive, else OUTSIDE.

        Raises
        ------
        InvalidInputError
            Bad shapes, NaN or inf.
        """
        P, shape = _as_points(points)
        p, q = self.edges()
        number, boundary = _winding_edges(P, p, q)
        return _location(number > 0, boundary).reshape(shape)
