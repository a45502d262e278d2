"""Rings and polygon sets: exact area signs, winding numbers and point location against
Fraction references, simplicity on every kind of self-contact, the sort-and-sweep broad phase
against brute force, the PolygonSet value, and every error branch."""

from __future__ import annotations

import dataclasses
from fractions import Fraction

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from coons.errors import InvalidInputError
from coons.kernel.polygon import (
    Location,
    Polygon,
    PolygonSet,
    as_ring,
    is_simple,
    normalize,
    overlapping_boxes,
    point_in_polygon,
    signed_area,
    winding_number,
)
from coons.kernel.predicates import SegmentRelation
from tests.kernel.test_predicates import ref_classify

SQUARE = np.array([[0.0, 0.0], [2.0, 0.0], [2.0, 2.0], [0.0, 2.0]])


def ref_signed_area(ring) -> Fraction:
    r = [(Fraction(float(x)), Fraction(float(y))) for x, y in ring]
    return sum(r[i][0] * r[(i + 1) % len(r)][1] - r[(i + 1) % len(r)][0] * r[i][1] for i in range(len(r))) / 2


def ref_location(p, ring) -> int:
    """Even-odd ray casting with Fractions (valid for simple rings), boundary first."""
    px, py = Fraction(float(p[0])), Fraction(float(p[1]))
    r = [(Fraction(float(x)), Fraction(float(y))) for x, y in ring]
    inside = False
    for (ax, ay), (bx, by) in zip(r, r[1:] + r[:1]):
        cross = (bx - ax) * (py - ay) - (by - ay) * (px - ax)
        if cross == 0 and min(ax, bx) <= px <= max(ax, bx) and min(ay, by) <= py <= max(ay, by):
            return Location.BOUNDARY
        if (ay > py) != (by > py) and px < ax + (py - ay) * (bx - ax) / (by - ay):
            inside = not inside
    return Location.INSIDE if inside else Location.OUTSIDE


def star(rng, n, grid=None):
    ang = np.sort(rng.uniform(0, 2 * np.pi, n))
    r = rng.uniform(1, 4, n)
    P = np.c_[r * np.cos(ang), r * np.sin(ang)]
    return np.round(P / grid) * grid if grid else P


# ---------------------------------------------------------------------- rings
def test_as_ring_drops_the_closing_vertex_and_is_read_only():
    r = as_ring(np.vstack([SQUARE, SQUARE[:1]]))
    np.testing.assert_array_equal(r, SQUARE)
    assert not r.flags.writeable
    assert np.signbit(as_ring([[-0.0, 0.0], [1.0, 0.0], [0.0, 1.0]])[0, 0]) == False  # noqa: E712  -0.0 -> 0.0


def test_signed_area_closed_forms():
    assert signed_area(SQUARE) == 4.0
    assert signed_area(SQUARE[::-1]) == -4.0
    assert signed_area([[0, 0], [3, 0], [0, 5]]) == 7.5
    n = 64
    t = np.linspace(0, 2 * np.pi, n, endpoint=False)
    np.testing.assert_allclose(signed_area(np.c_[np.cos(t), np.sin(t)]), 0.5 * n * np.sin(2 * np.pi / n), rtol=1e-14)


def test_signed_area_sign_is_exact_for_slivers():
    # Nearly collinear triangles far from the origin: the float shoelace sum is wrong there.
    X = 2.0**20
    u = np.spacing(X)
    wrong = 0
    for i in range(-20, 21):
        ring = [[X + 0.5 + i * u, X + 0.5], [X + 12.0, X + 12.0], [X + 24.0, X + 24.0]]
        exact = ref_signed_area(ring)
        a = signed_area(ring)
        assert np.sign(a) == np.sign(float(exact)) and a == float(exact)
        x = np.array(ring)
        naive = 0.5 * np.sum(x[:, 0] * np.roll(x[:, 1], -1) - np.roll(x[:, 0], -1) * x[:, 1])
        wrong += np.sign(naive) != np.sign(float(exact))
    assert wrong > 0  # the naive formula does fail here, so the test means something
    assert signed_area([[0, 0], [1, 1], [2, 2], [3, 3]]) == 0.0


@settings(max_examples=40)
@given(st.integers(0, 2**32 - 1), st.integers(3, 30))
def test_signed_area_matches_fraction_within_its_error_bound(seed, n):
    rng = np.random.default_rng(seed)
    ring = star(rng, n) * 2.0 ** int(rng.integers(-60, 60))
    exact = ref_signed_area(ring)
    a = signed_area(ring)
    assert np.sign(a) == np.sign(float(exact))
    # The documented bound: (n + 3) eps times the sum of |products| (halved for the area).
    x, y = ring[:, 0], ring[:, 1]
    bound = (n + 3) * 2.0**-53 * 0.5 * np.sum(np.abs(x * np.roll(y, -1)) + np.abs(np.roll(x, -1) * y))
    assert abs(Fraction(a) - exact) <= Fraction(bound)


def test_winding_numbers():
    pts = [[1, 1], [3, 1], [2, 0], [0, 0], [1, 2], [1, -1e-300]]
    w = winding_number(pts, SQUARE)
    np.testing.assert_array_equal(w.number, [1, 0, 0, 0, 0, 0])
    np.testing.assert_array_equal(w.on_boundary, [False, False, True, True, True, False])
    np.testing.assert_array_equal(winding_number(pts, SQUARE[::-1]).number, [-1, 0, 0, 0, 0, 0])
    # A pentagram winds twice around its centre and once around its points.
    k = np.arange(5)
    pentagram = np.c_[np.cos(np.pi / 2 + 4 * np.pi * k / 5), np.sin(np.pi / 2 + 4 * np.pi * k / 5)]
    w = winding_number([[0.0, 0.0], [0.0, 0.8], [5.0, 5.0]], pentagram)
    np.testing.assert_array_equal(w.number, [2, 1, 0])
    assert winding_number(np.zeros((3, 4, 2)), SQUARE).number.shape == (3, 4)


@settings(max_examples=40)
@given(st.integers(0, 2**32 - 1))
def test_point_in_polygon_matches_fraction_on_a_grid(seed):
    # Grid polygons and grid points: many points on edges, on vertices and level with vertices.
    rng = np.random.default_rng(seed)
    ring = star(rng, int(rng.integers(3, 12)), grid=1.0)
    if not is_simple(ring):
        return
    pts = rng.integers(-5, 6, size=(60, 2)).astype(float) / 2
    loc = point_in_polygon(pts, ring)
    assert loc.dtype == np.int8
    np.testing.assert_array_equal(loc, [ref_location(p, ring) for p in pts])


def test_point_in_polygon_one_ulp_from_an_edge():
    ring = [[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]]  # hypotenuse x + y = 1
    x = 0.3
    on = [x, 1.0 - x]  # 0.7 is rounded, so the exact point may be on either side: ask Fractions
    pts = np.array([on, [x, np.nextafter(1.0 - x, 2)], [x, np.nextafter(1.0 - x, 0)]])
    np.testing.assert_array_equal(point_in_polygon(pts, ring), [ref_location(p, ring) for p in pts])
    assert point_in_polygon([0.25, 0.75], ring) == Location.BOUNDARY  # exact: 0.25 + 0.75 == 1


@pytest.mark.parametrize(
    ("ring", "simple"),
    [
        (SQUARE, True),
        ([[0, 0], [1, 0], [2, 0], [2, 1]], True),  # a straight vertex is fine
        ([[0, 0], [2, 2], [2, 0], [0, 2]], False),  # bow tie
        ([[0, 0], [4, 0], [4, 4], [2, 0], [0, 4]], False),  # vertex on a non-adjacent edge
        ([[0, 0], [2, 0], [2, 2], [1, 0.0], [1, -1], [0, 1]], False),  # touches its own edge
        ([[0, 0], [4, 0], [2, 2], [4, 4], [0, 4], [2, 2]], False),  # repeated vertex
        ([[0, 0], [2, 0], [1, 0], [1, 1]], False),  # folds back on itself
        ([[0, 0], [1, 0], [2, 0]], False),  # zero area
        ([[0, 0], [3, 0], [3, 1], [1, 0], [0, 1]], False),  # overlaps an edge collinearly
    ],
)
def test_is_simple(ring, simple):
    assert is_simple(ring) is simple


@settings(max_examples=60)
@given(st.integers(0, 2**32 - 1))
def test_is_simple_matches_pairwise_fraction_reference(seed):
    rng = np.random.default_rng(seed)
    ring = rng.integers(0, 4, size=(int(rng.integers(3, 8)), 2)).astype(float)
    if np.any(np.all(ring == np.roll(ring, -1, axis=0), axis=1)):
        return
    n = ring.shape[0]

    def meet(i, j):
        return ref_classify(ring[i], ring[(i + 1) % n], ring[j], ring[(j + 1) % n])

    ok = len({tuple(p) for p in ring.tolist()}) == n
    for i in range(n):
        for j in range(i + 1, n):
            adjacent = j == i + 1 or (i == 0 and j == n - 1)
            rel = meet(i, j)
            if (adjacent and rel == SegmentRelation.OVERLAP) or (not adjacent and rel != SegmentRelation.DISJOINT):
                ok = False
    if n == 3 and abs(ref_signed_area(ring)) == 0:
        ok = False
    assert is_simple(ring) is ok


def test_normalize_orients_rings():
    hole = [[0.5, 0.5], [1.0, 0.5], [1.0, 1.0]]  # counter-clockwise
    outer, holes = normalize(SQUARE[::-1], [hole])
    assert signed_area(outer) > 0 and signed_area(holes[0]) < 0
    np.testing.assert_array_equal(outer, SQUARE[::-1][::-1])
    assert not outer.flags.writeable and not holes[0].flags.writeable


# ---------------------------------------------------------------------- broad phase
@settings(max_examples=80)
@given(st.integers(0, 2**32 - 1), st.integers(0, 40), st.integers(0, 40))
def test_overlapping_boxes_matches_brute_force(seed, n, m):
    rng = np.random.default_rng(seed)
    lo = rng.integers(0, 10, size=(n, 2)) / 2
    hi = lo + rng.integers(0, 4, size=(n, 2)) / 2  # touching and degenerate boxes are common
    lo2 = rng.integers(0, 10, size=(m, 2)) / 2
    hi2 = lo2 + rng.integers(0, 4, size=(m, 2)) / 2

    def meets(a0, a1, b0, b1):
        return bool(np.all(np.maximum(a0, b0) <= np.minimum(a1, b1)))

    got = overlapping_boxes(lo, hi)
    want = {(i, j) for i in range(n) for j in range(i + 1, n) if meets(lo[i], hi[i], lo[j], hi[j])}
    assert got.dtype == np.int64 and len(got) == len(want) and set(map(tuple, got.tolist())) == want
    got = overlapping_boxes(lo, hi, lo2, hi2)
    want = {(i, j) for i in range(n) for j in range(m) if meets(lo[i], hi[i], lo2[j], hi2[j])}
    assert len(got) == len(want) and set(map(tuple, got.tolist())) == want


# ---------------------------------------------------------------------- values
def test_polygon_set_value():
    s = PolygonSet.coerce((SQUARE * 2, [[[1, 1], [1, 2], [2, 2], [2, 1]]]))
    assert len(s) == 1 and s.n_vertices == 8
    assert s.area == 15.0
    np.testing.assert_array_equal(s.bounds, [[0, 0], [4, 4]])
    np.testing.assert_array_equal(
        s.contains([[0.5, 0.5], [1.5, 1.5], [4.0, 1.0], [5.0, 5.0], [1.0, 1.5]]),
        [Location.INSIDE, Location.OUTSIDE, Location.BOUNDARY, Location.OUTSIDE, Location.BOUNDARY],
    )
    p = s.polygons[0]
    assert signed_area(p.outer) > 0 and signed_area(p.holes[0]) < 0  # normalised orientation
    assert not p.outer.flags.writeable
    with pytest.raises(dataclasses.FrozenInstanceError):
        p.outer = SQUARE  # type: ignore[misc]
    assert p.contains([1.5, 1.5]) == Location.OUTSIDE and p.area == 15.0
    np.testing.assert_array_equal(p.bounds, [[0, 0], [4, 4]])
    empty = PolygonSet.empty()
    assert empty.is_empty and empty.area == 0.0 and np.all(np.isnan(empty.bounds))
    np.testing.assert_array_equal(empty.contains([[0, 0]]), [Location.OUTSIDE])


def test_coerce_forms():
    tri = [[0, 0], [1, 0], [0, 1]]
    assert len(PolygonSet.coerce(tri)) == 1
    assert len(PolygonSet.coerce([tri, SQUARE + 5])) == 2  # a list of rings
    assert len(PolygonSet.coerce(np.stack([SQUARE, SQUARE + 5]))) == 2  # a (k, n, 2) array
    assert len(PolygonSet.coerce([(SQUARE, []), Polygon(tri)])) == 2
    assert len(PolygonSet.coerce([])) == 0
    s = PolygonSet.coerce(tri)
    assert PolygonSet.coerce(s) is s
    # Overlapping polygons in one set mean their union (positive winding).
    both = PolygonSet.coerce([SQUARE, SQUARE + 1])
    np.testing.assert_array_equal(both.contains([[1.5, 1.5], [2.5, 2.5], [0.5, 2.5]]), [1, 1, 0])


def test_errors_name_the_ring_and_segment():
    with pytest.raises(InvalidInputError, match=r"polygon 0: outer ring is not simple: segment 0 \(0.0, 0.0\)-\(2.0, 2.0\) crosses segment 2"):
        PolygonSet.coerce([[0, 0], [2, 2], [2, 0], [0, 2]])
    with pytest.raises(InvalidInputError, match=r"polygon 1: hole 0 is not simple: vertex 1 and vertex 3 are the same point"):
        PolygonSet.coerce([SQUARE, (SQUARE * 4, [[[1, 1], [2, 2], [3, 1], [2, 2]]])])
    with pytest.raises(InvalidInputError, match=r"outer ring: vertex 1 has a NaN or inf coordinate: \[1.0, nan\]"):
        Polygon([[0, 0], [1, np.nan], [1, 1]])
    with pytest.raises(InvalidInputError, match="expected at least 3 distinct vertices, got 2"):
        as_ring([[0, 0], [1, 1], [0, 0]])
    with pytest.raises(InvalidInputError, match=r"expected an \(n, 2\) array of vertices, got shape \(4, 3\)"):
        as_ring(np.zeros((4, 3)))
    with pytest.raises(InvalidInputError, match=r"expected an \(n, 2\) array of vertices, got list"):
        as_ring([[0, 0], [1]])
    with pytest.raises(InvalidInputError, match="polygon 1: expected a ring .* got str"):
        PolygonSet.coerce([SQUARE, "square"])
    with pytest.raises(InvalidInputError, match="expected a PolygonSet, a Polygon, .* got int"):
        PolygonSet.coerce(3)
    with pytest.raises(InvalidInputError, match="polygon 0: expected a Polygon, got tuple"):
        PolygonSet(((SQUARE, []),))
    with pytest.raises(InvalidInputError, match=r"points: expected an array of shape \(\.\.\., 2\)"):
        winding_number([1, 2, 3], SQUARE)
    with pytest.raises(InvalidInputError, match="points: coordinates must be finite"):
        PolygonSet.coerce(SQUARE).contains([np.nan, 0])


def test_proper_crossings_are_strict():
    """A proper crossing only: touching at an end (T), a shared end, a collinear overlap and a zero-length
    segment on either side do not cross."""
    from coons.kernel.polygon import proper_crossings

    S = np.array  # rows: a, b, c, d
    cases = [
        ([0, 0], [2, 2], [0, 2], [2, 0], True),    # the diagonals of a square
        ([0, 0], [2, 0], [1, 0], [1, 1], False),   # T: c on ab
        ([0, 0], [1, 1], [1, 1], [2, 0], False),   # shared end
        ([0, 0], [2, 0], [1, 0], [3, 0], False),   # collinear overlap
        ([1, 1], [1, 1], [0, 2], [2, 0], False),   # zero-length ab on the other diagonal
        ([0, 2], [2, 0], [1, 1], [1, 1], False),   # zero-length cd on it
    ]
    a, b, c, d = (S([row[k] for row in cases], dtype=float) for k in range(4))
    want = [row[4] for row in cases]
    assert proper_crossings(a, b, c, d).tolist() == want
    assert proper_crossings(c, d, a, b).tolist() == want
