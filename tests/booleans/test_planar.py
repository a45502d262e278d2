"""Planar Booleans: every degenerate case with its exact area and rings, the Boolean algebra's
laws on random polygons (integer grids full of collinear points, floats, holes), exact scale and
mirror covariance, agreement with shapely, validity of every result, the 3-D wrapper, the
checker's problem codes, and every error branch."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import shapely
from hypothesis import given, settings
from hypothesis import strategies as st
from shapely.geometry import MultiPolygon
from shapely.geometry import Polygon as ShapelyPolygon

import coons.booleans.planar as planar
from coons.booleans import (
    OPERATIONS,
    PlaneFrame,
    check_polygon_set,
    planar_boolean,
    polygon_boolean,
    polygon_difference,
    polygon_intersection,
    polygon_symmetric_difference,
    polygon_union,
)
from coons.errors import BooleanError, InvalidInputError
from coons.kernel.polygon import Polygon, PolygonSet, is_simple, signed_area

AREA_RTOL = 1e-12  # area identities: sums of shoelace areas of rounded vertices
SHAPELY_RTOL = 1e-9  # symmetric-difference area against shapely, relative to the result's area
OPS = sorted(OPERATIONS)


# ---------------------------------------------------------------------- helpers
def sq(x0, y0, x1, y1):
    return [[x0, y0], [x1, y0], [x1, y1], [x0, y1]]


def rings_of(ps: PolygonSet) -> list:
    """Exact, hashable description of a canonical set: outer and holes per polygon, in order."""
    return [(p.outer.tolist(), [h.tolist() for h in p.holes]) for p in ps.polygons]


def canonical(ps: PolygonSet) -> list:
    """Rings up to orientation and starting vertex, as a sorted list (for mirrored sets)."""

    def ring_key(r):
        r = np.asarray(r)
        if signed_area(r) < 0:
            r = r[::-1]
        k = int(np.lexsort((r[:, 1], r[:, 0]))[0])
        return tuple(map(tuple, np.roll(r, -k, axis=0).tolist()))

    return sorted((ring_key(p.outer), tuple(sorted(ring_key(h) for h in p.holes))) for p in ps.polygons)


def assert_valid(ps: PolygonSet) -> None:
    """What every result promises: simple rings, outers CCW, holes CW, canonical (the checker)."""
    for p in ps.polygons:
        assert is_simple(p.outer) and signed_area(p.outer) > 0
        for h in p.holes:
            assert is_simple(h) and signed_area(h) < 0
    report = check_polygon_set(ps)
    assert report.ok, report.summary()


def to_shapely(ps: PolygonSet) -> MultiPolygon:
    return MultiPolygon([ShapelyPolygon(p.outer, list(p.holes)) for p in ps.polygons])


def from_shapely(g) -> PolygonSet:
    geoms = [g] if g.geom_type == "Polygon" else list(g.geoms)
    return PolygonSet.coerce(
        [(np.array(p.exterior.coords), [np.array(h.coords) for h in p.interiors]) for p in geoms if not p.is_empty]
    )


def densified(ring: np.ndarray) -> np.ndarray:
    """The ring with every lattice point on its integer edges inserted: collinear vertices."""
    out = []
    for p, q in zip(ring, np.roll(ring, -1, axis=0)):
        d = q - p
        g = np.gcd(int(abs(d[0])), int(abs(d[1]))) if np.all(np.round(ring) == ring) else 1
        out.extend(p + np.outer(np.arange(max(g, 1)), d / max(g, 1)))
    return np.array(out)


def random_set(rng: np.random.Generator, kind: str) -> PolygonSet:
    """Random canonical polygon sets (built with shapely, so they are independent of coons).

    grid: unions of triangles and rectangles on a 5x5 integer grid, full of collinear edges,
    shared vertices and holes, half of them with every lattice point on their edges made a
    vertex; their crossing points are rounded floats, so a second Boolean meets inputs with
    features an ulp apart.  float: star polygons with float vertices and a star-shaped hole.
    """
    while True:
        if kind == "grid":
            parts = []
            for _ in range(int(rng.integers(1, 5))):
                if rng.random() < 0.5:
                    x0, y0 = rng.integers(0, 4, 2)
                    w, h = rng.integers(1, 3, 2)
                    parts.append(shapely.box(x0, y0, x0 + w, y0 + h))
                else:
                    t = ShapelyPolygon(rng.integers(0, 5, (3, 2)).astype(float))
                    if t.area > 0:
                        parts.append(t)
            g = shapely.unary_union(parts) if parts else None
        else:
            c = rng.uniform(-1, 1, 2)
            n = int(rng.integers(3, 14))
            ang = np.sort(rng.uniform(0, 2 * np.pi, n))
            outer = c + rng.uniform(1.0, 3.0, n)[:, None] * np.c_[np.cos(ang), np.sin(ang)]
            g = ShapelyPolygon(outer)
            if g.is_valid and rng.random() < 0.6:
                m = int(rng.integers(3, 8))
                a2 = np.sort(rng.uniform(0, 2 * np.pi, m))
                hole = ShapelyPolygon(c + rng.uniform(0.2, 0.7, m)[:, None] * np.c_[np.cos(a2), np.sin(a2)])
                if hole.is_valid:
                    g = g.difference(hole)
        if g is not None and g.is_valid and g.area > 0:
            ps = from_shapely(g)
            if kind == "grid" and rng.random() < 0.5:
                ps = PolygonSet.coerce(
                    [(densified(p.outer), [densified(h) for h in p.holes]) for p in ps.polygons]
                )
            return ps


sets = st.tuples(st.integers(0, 2**32 - 1), st.sampled_from(["grid", "float"])).map(
    lambda t: random_set(np.random.default_rng(t[0]), t[1])
)


# ---------------------------------------------------------------------- degenerate cases
def test_partial_overlap_closed_form():
    a, b = sq(0, 0, 2, 2), sq(1, 1, 3, 3)
    u = polygon_union(a, b)
    assert rings_of(u) == [([[0, 0], [2, 0], [2, 1], [3, 1], [3, 3], [1, 3], [1, 2], [0, 2]], [])]
    assert rings_of(polygon_intersection(a, b)) == [([[1, 1], [2, 1], [2, 2], [1, 2]], [])]
    assert polygon_difference(a, b).area == 3.0
    x = polygon_symmetric_difference(a, b)
    # The two L shapes touch at (1, 2) and (2, 1): two polygons sharing vertices, not one.
    assert len(x) == 2 and x.area == 6.0
    assert_valid(x)


def test_shared_edge():
    a, b = sq(0, 0, 1, 1), sq(1, 0, 2, 1)
    u = polygon_union(a, b)
    # (1, 0) and (1, 1) are vertices of the inputs: kept where the boundary runs straight on.
    assert rings_of(u) == [([[0, 0], [1, 0], [2, 0], [2, 1], [1, 1], [0, 1]], [])]
    assert polygon_intersection(a, b).is_empty  # a common edge has no area
    assert rings_of(polygon_difference(a, b)) == rings_of(polygon_union(a, []))
    assert rings_of(polygon_symmetric_difference(a, b)) == rings_of(u)  # the edge is not a boundary


def test_collinear_partial_overlap_of_edges():
    a, b = sq(0, 0, 2, 1), sq(1, 1, 3, 2)
    u = polygon_union(a, b)
    assert len(u) == 1 and u.area == 4.0 and len(u.polygons[0].outer) == 8
    assert polygon_intersection(a, b).is_empty
    assert polygon_difference(a, b).area == 2.0
    assert_valid(u)


def test_vertex_touching_an_edge_from_outside():
    a, tri = sq(0, 0, 2, 2), [[1, 2], [2, 3], [0, 3]]  # apex on the top edge
    u = polygon_union(a, tri)
    assert len(u) == 2 and u.area == 5.0  # two polygons touching at (1, 2)
    assert [1.0, 2.0] in u.polygons[0].outer.tolist() and [1.0, 2.0] in u.polygons[1].outer.tolist()
    assert polygon_intersection(a, tri).is_empty
    assert polygon_difference(a, tri).area == 4.0
    assert_valid(u)


def test_hole_touching_the_outer_ring_at_a_vertex():
    a, tri = sq(0, 0, 4, 4), [[0, 2], [2, 1], [2, 3]]  # inside, one vertex on the left edge
    d = polygon_difference(a, tri)
    assert len(d) == 1 and len(d.polygons[0].holes) == 1 and d.area == 14.0
    p = d.polygons[0]
    assert [0.0, 2.0] in p.outer.tolist() and [0.0, 2.0] in p.holes[0].tolist()
    assert_valid(d)
    u = polygon_union(a, tri)
    assert u.area == 16.0 and len(u.polygons[0].outer) == 5  # (0, 2) kept: a vertex of B
    assert rings_of(polygon_intersection(a, tri)) == rings_of(polygon_union(tri, []))


def test_polygons_starting_at_the_same_vertex_keep_their_holes():
    # Both results start at their lexicographically smallest vertex (0, 0); the hole must stay
    # with the polygon it is in (regression: sorting by the first vertex alone mixed them up).
    upper, upper_hole = [[0, 0], [8, 2], [2, 8]], [[2, 2], [3, 2], [2, 3]]
    lower, lower_hole = [[0, 0], [2, -8], [8, -2]], [[2, -2], [3, -2], [2, -3]]
    for a, b, holes in [((upper, [upper_hole]), lower, [0, 1]), (upper, (lower, [lower_hole]), [1, 0])]:
        for op in ("union", "symmetric_difference"):
            r = polygon_boolean(a, b, op)
            assert [len(p.holes) for p in r.polygons] == holes
            assert r.polygons[0].outer.tolist()[:2] == [[0, 0], [2, -8]]
            assert r.area == 30 - 0.5 + 30
            assert_valid(r)


def test_holes_touching_each_other_at_a_point():
    d = polygon_difference(sq(0, 0, 4, 4), [[[1, 1], [2, 1], [2, 2]], [[2, 2], [3, 2], [3, 3]]])
    assert len(d) == 1 and len(d.polygons[0].holes) == 2 and d.area == 15.0
    assert_valid(d)


def test_identical_operands():
    a = PolygonSet.coerce((sq(0, 0, 4, 4), [sq(1, 1, 2, 2)]))
    for op in ("union", "intersection"):
        assert rings_of(polygon_boolean(a, a, op)) == rings_of(polygon_union(a, []))
    assert polygon_difference(a, a).is_empty and polygon_symmetric_difference(a, a).is_empty


def test_one_inside_the_other():
    big, small = sq(0, 0, 4, 4), sq(1, 1, 2, 2)
    assert rings_of(polygon_union(big, small)) == rings_of(polygon_union(big, []))
    assert rings_of(polygon_intersection(big, small)) == rings_of(polygon_union(small, []))
    d = polygon_difference(big, small)
    assert len(d) == 1 and len(d.polygons[0].holes) == 1 and d.area == 15.0
    assert polygon_difference(small, big).is_empty
    assert rings_of(polygon_symmetric_difference(big, small)) == rings_of(d)
    # An island inside the hole of another polygon stays a polygon of its own.
    island = polygon_union(d, sq(1.25, 1.25, 1.75, 1.75))
    assert len(island) == 2 and island.area == 15.25
    assert_valid(island)


def test_touching_at_a_point():
    a, b = sq(0, 0, 1, 1), sq(1, 1, 2, 2)
    u = polygon_union(a, b)
    assert len(u) == 2 and u.area == 2.0
    assert polygon_intersection(a, b).is_empty
    assert rings_of(polygon_symmetric_difference(a, b)) == rings_of(u)
    assert_valid(u)


def test_checkerboard():
    a = [sq(0, 0, 1, 1), sq(1, 1, 2, 2)]
    b = [sq(1, 0, 2, 1), sq(0, 1, 1, 2)]
    u = polygon_union(a, b)
    assert rings_of(u) == [([[0, 0], [1, 0], [2, 0], [2, 1], [2, 2], [1, 2], [0, 2], [0, 1]], [])]
    assert polygon_intersection(a, b).is_empty
    assert rings_of(polygon_symmetric_difference(a, b)) == rings_of(u)
    # Overlapping polygons inside one operand are read as their union.
    assert polygon_union([sq(0, 0, 2, 2), sq(1, 1, 3, 3)], []).area == 7.0


def test_zero_area_slivers_never_appear():
    a = sq(0, 0, 2, 1)
    halves = [sq(0, 0, 1, 1), sq(1, 0, 2, 1)]  # cover a exactly, meeting along x = 1
    assert polygon_difference(a, halves).is_empty
    assert polygon_difference(halves, a).is_empty
    assert polygon_symmetric_difference(a, halves).is_empty
    i = polygon_intersection(a, halves)
    assert len(i) == 1 and i.area == 2.0
    # A sliver of positive area, one subnormal high, is kept exactly.
    tiny = 2.0**-1074
    s = polygon_difference(sq(0, 0, 1, 1), [[0, tiny], [1, tiny], [1, 1], [0, 1]])
    assert len(s) == 1 and s.area == tiny
    assert_valid(s)


def test_empty_operands_and_results():
    a = sq(0, 0, 1, 1)
    assert rings_of(polygon_union(a, [])) == [([[0, 0], [1, 0], [1, 1], [0, 1]], [])]
    assert rings_of(polygon_union([], a)) == rings_of(polygon_union(a, []))
    for op in OPS:
        assert polygon_boolean([], [], op).is_empty
    assert polygon_intersection(a, []).is_empty
    assert polygon_difference([], a).is_empty
    assert polygon_intersection(a, sq(5, 5, 6, 6)).is_empty  # disjoint


def test_many_collinear_vertices_and_overlapping_edges():
    comb = [[0, 0], [1, 0], [2, 0], [3, 0], [4, 0], [4, 1], [3, 1], [3, 2], [2, 2], [2, 1], [1, 1], [1, 2], [0, 2]]
    bar = [[0, 1], [4, 1], [4, 3], [0, 3]]
    u = polygon_union(comb, bar)
    assert u.area == 6 + 8 - 2 and len(u) == 1  # comb 6, bar 8, teeth 2
    assert polygon_intersection(comb, bar).area == 2.0
    assert polygon_difference(comb, bar).area == 4.0
    assert_valid(u)


def test_rounded_inputs_need_and_get_a_rounding_pass():
    # a has a vertex 4/3 rounded to a float (it is the union of two triangles); b's edge passes
    # through the exact point (4/3, 1), so exact crossings land within an ulp of a's vertex.
    a = polygon_union([[1, 0], [2, 1], [0, 1]], [[1, 0], [2, 3], [1, 2]])
    assert [4 / 3, 1.0] in a.polygons[0].outer.tolist()
    b = [[2, 0], [0, 3], [1, 0]]
    sa, sb = to_shapely(a), to_shapely(PolygonSet.coerce(b))
    for op in OPS:
        first = planar._overlay(planar._segments(a, PolygonSet.coerce(b)), op)
        assert planar._rounding_defects(first)  # plain rounding would break this result
        r = polygon_boolean(a, b, op)
        assert_valid(r)
        ref = getattr(sa, op)(sb)
        assert to_shapely(r).symmetric_difference(ref).area <= SHAPELY_RTOL * ref.area


# ---------------------------------------------------------------------- laws of the algebra
@settings(max_examples=100)
@given(sets, sets)
def test_area_identities_and_validity(a, b):
    u, i, d, x = (polygon_boolean(a, b, op) for op in ("union", "intersection", "difference", "symmetric_difference"))
    for r in (u, i, d, x):
        assert_valid(r)
    scale = a.area + b.area
    np.testing.assert_allclose(u.area + i.area, a.area + b.area, rtol=AREA_RTOL)
    np.testing.assert_allclose(d.area, a.area - i.area, rtol=0, atol=AREA_RTOL * scale)
    np.testing.assert_allclose(x.area, u.area - i.area, rtol=0, atol=AREA_RTOL * scale)


@settings(max_examples=60)
@given(sets, sets)
def test_commutative_and_idempotent(a, b):
    for op in ("union", "intersection", "symmetric_difference"):
        assert rings_of(polygon_boolean(a, b, op)) == rings_of(polygon_boolean(b, a, op))
    canon = polygon_union(a, [])
    assert rings_of(polygon_union(a, a)) == rings_of(canon)
    assert rings_of(polygon_intersection(a, a)) == rings_of(canon)
    assert polygon_symmetric_difference(a, canon).is_empty  # A ∪ ∅ is A as a region
    assert polygon_difference(a, a).is_empty
    assert polygon_intersection(a, []).is_empty


@settings(max_examples=20)
@given(sets, sets, st.sampled_from([-500, -60, 40, 700]))
def test_exact_under_power_of_two_scaling_and_mirroring(a, b, k):
    def scaled(ps, s):
        return PolygonSet.coerce([(p.outer * s, [h * s for h in p.holes]) for p in ps.polygons])

    def mirrored(ps):
        flip = np.array([-1.0, 1.0])
        return PolygonSet.coerce([(p.outer * flip, [h * flip for h in p.holes]) for p in ps.polygons])

    for op in OPS:
        r = polygon_boolean(a, b, op)
        # Scaling by 2^k is exact and so is every decision: the results are the same bits.
        assert rings_of(polygon_boolean(scaled(a, 2.0**k), scaled(b, 2.0**k), op)) == rings_of(scaled(r, 2.0**k))
        assert canonical(polygon_boolean(mirrored(a), mirrored(b), op)) == canonical(mirrored(r))


def test_agreement_with_shapely_on_random_polygons_with_holes():
    rng = np.random.default_rng(20240601)
    for k in range(300):
        kind = ("grid", "float")[k % 2]
        a, b = random_set(rng, kind), random_set(rng, kind)
        sa, sb = to_shapely(a), to_shapely(b)
        if k % 10 == 0:
            # Overlapping polygons in one operand: read as their union (positive winding).
            extra = random_set(rng, kind)
            a = PolygonSet(a.polygons + extra.polygons)
            sa = shapely.unary_union([sa, to_shapely(extra)])
        for op in OPS:
            r = polygon_boolean(a, b, op)
            for p in r.polygons:
                assert is_simple(p.outer) and signed_area(p.outer) > 0
                assert all(is_simple(h) and signed_area(h) < 0 for h in p.holes)
            ref = getattr(sa, op)(sb)
            mine = to_shapely(r)
            assert mine.is_valid
            np.testing.assert_allclose(r.area, ref.area, rtol=SHAPELY_RTOL, atol=SHAPELY_RTOL)
            assert mine.symmetric_difference(ref).area <= SHAPELY_RTOL * max(ref.area, 1.0), (k, op)


def test_many_components_and_nested_islands():
    plate = sq(0, 0, 21, 21)
    holes = [sq(i + 0.25, j + 0.25, i + 0.75, j + 0.75) for i in range(1, 20) for j in range(1, 20)]
    d = polygon_difference(plate, holes)
    assert len(d) == 1 and len(d.polygons[0].holes) == 361 and d.area == 441 - 361 * 0.25
    islands = [sq(i + 0.375, j + 0.375, i + 0.625, j + 0.625) for i in range(1, 20) for j in range(1, 20)]
    u = polygon_union(d, islands)
    assert len(u) == 362 and u.area == d.area + 361 * 0.0625
    assert_valid(u)
    assert rings_of(polygon_union(d, holes)) == rings_of(polygon_union(plate, []))


# ---------------------------------------------------------------------- 3-D
def newell_normal(ring: np.ndarray) -> np.ndarray:
    """Twice the vector area of a planar ring (Newell's method)."""
    return 0.5 * np.cross(ring, np.roll(ring, -1, axis=0)).sum(axis=0)


def test_planar_boolean_on_a_horizontal_plane_matches_2d():
    lift = [np.c_[np.array(r, dtype=float), np.ones(4)] for r in (sq(0, 0, 2, 2), sq(1, 1, 3, 3))]
    for op in OPS:
        res = planar_boolean(lift[0], lift[1], [0, 0, 1], [0, 0, 1], op)
        flat = polygon_boolean(sq(0, 0, 2, 2), sq(1, 1, 3, 3), op)
        assert len(res) == len(flat)
        for p3, p2 in zip(res, flat.polygons):
            np.testing.assert_array_equal(p3.outer[:, :2], p2.outer)
            np.testing.assert_array_equal(p3.outer[:, 2], 1.0)


def test_planar_boolean_on_a_tilted_plane():
    rng = np.random.default_rng(5)
    Q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    origin = np.array([3.0, -2.0, 7.0])
    n = Q[:, 2]

    def place(ring):
        r = np.asarray(ring, dtype=float)
        return origin + r[:, :1] * Q[:, 0] + r[:, 1:2] * Q[:, 1]

    a = (place(sq(0, 0, 4, 4)), [place(sq(1, 1, 2, 2))])
    b = place([[3, 3], [5, 3], [5, 5], [3, 5]])[::-1]  # clockwise as given: orientation is not input
    for op, area in [("union", 15 + 4 - 1), ("intersection", 1), ("difference", 14), ("symmetric_difference", 17)]:
        res = planar_boolean(a, b, origin, n, op)
        total = 0.0
        for p in res:
            for k, ring in enumerate((p.outer, *p.holes)):
                assert np.max(np.abs((ring - origin) @ n)) < 1e-13  # on the plane
                vec = newell_normal(ring)
                assert np.dot(vec, n) * (1 if k == 0 else -1) > 0  # outer CCW about n, holes CW
                total += np.dot(vec, n)
        np.testing.assert_allclose(total, area, rtol=1e-12)
    f = PlaneFrame.from_normal(origin, n)
    np.testing.assert_allclose(f.to_local(f.to_global([[1.5, -2.0]])), [[1.5, -2.0]], atol=1e-15)
    np.testing.assert_allclose([f.x_dir @ f.y_dir, f.x_dir @ f.normal, np.cross(f.x_dir, f.y_dir) @ f.normal], [0, 0, 1], atol=1e-15)


def test_planar_boolean_errors():
    a = np.c_[np.array(sq(0, 0, 1, 1), dtype=float), np.zeros(4)]
    off = a.copy()
    off[2, 2] = 1e-3
    with pytest.raises(InvalidInputError, match=r"operand a polygon 0: a vertex lies 0.001 from the plane, expected at most tol.linear = 1e-07"):
        planar_boolean(off, a, [0, 0, 0], [0, 0, 1], "union")
    with pytest.raises(InvalidInputError, match=r"plane_normal must be a non-zero vector"):
        planar_boolean(a, a, [0, 0, 0], [0, 0, 0], "union")
    with pytest.raises(InvalidInputError, match=r"plane_origin must be a finite 3-vector"):
        planar_boolean(a, a, [0, 0], [0, 0, 1], "union")
    with pytest.raises(InvalidInputError, match=r"x_dir must not be parallel to the normal"):
        planar_boolean(a, a, [0, 0, 0], [0, 0, 1], "union", x_dir=[0, 0, 2])
    with pytest.raises(InvalidInputError, match=r"operand b polygon 0: expected rings of shape \(n, 3\)"):
        planar_boolean(a, np.zeros((4, 2)), [0, 0, 0], [0, 0, 1], "union")
    with pytest.raises(InvalidInputError, match="operand b polygon 0: coordinates must be finite"):
        planar_boolean(a, np.full((4, 3), np.nan), [0, 0, 0], [0, 0, 1], "union")
    with pytest.raises(InvalidInputError, match="operand b: expected a ring .* got str"):
        planar_boolean(a, "b", [0, 0, 0], [0, 0, 1], "union")
    with pytest.raises(InvalidInputError, match="op must be one of"):
        planar_boolean(a, a, [0, 0, 0], [0, 0, 1], "unite")
    bow = np.c_[np.array([[0, 0], [1, 1], [1, 0], [0, 1]], dtype=float), np.zeros(4)]
    with pytest.raises(InvalidInputError, match="operand a: polygon 0: outer ring is not simple"):
        planar_boolean(bow, a, [0, 0, 0], [0, 0, 1], "union")


# ---------------------------------------------------------------------- errors and invariants
def test_input_errors():
    with pytest.raises(InvalidInputError, match=r"operand b: polygon 0: outer ring is not simple: segment 0 \(0.0, 0.0\)-\(1.0, 1.0\) crosses segment 2"):
        polygon_union(sq(0, 0, 1, 1), [[0, 0], [1, 1], [1, 0], [0, 1]])
    with pytest.raises(InvalidInputError, match=r"operand a: polygon 1: hole 0: vertex 2 has a NaN or inf coordinate"):
        polygon_intersection([sq(5, 5, 6, 6), (sq(0, 0, 4, 4), [[[1, 1], [2, 1], [np.nan, 2]]])], [])
    with pytest.raises(InvalidInputError, match=r"op must be one of \['difference', 'intersection', 'symmetric_difference', 'union'\], got 'xor'"):
        polygon_boolean(sq(0, 0, 1, 1), sq(0, 0, 1, 1), "xor")
    with pytest.raises(InvalidInputError, match="operand a: expected a PolygonSet"):
        polygon_difference(None, [])


def test_rounding_that_cannot_be_repaired_raises(monkeypatch):
    monkeypatch.setattr(planar, "_rounding_defects", lambda rs: ["a defect"])
    with pytest.raises(BooleanError, match=r"\[round\] rounding the result still leaves defects after 4 passes") as e:
        polygon_union(sq(0, 0, 2, 2), sq(1, 1, 3, 3))
    assert e.value.stage == "round" and e.value.diagnostics == {"defects": ["a defect"]}


def test_internal_invariants_are_checked():
    a, b = PolygonSet.coerce(sq(0, 0, 2, 2)), PolygonSet.coerce(sq(1, 1, 3, 3))
    S = planar._segments(a, b)
    arr = planar._imprint(S, planar._intersect(S))
    counts = arr.counts.copy()
    counts[0, 0] += 1  # one edge out of balance: the counts around its vertices no longer sum to 0
    bad = dataclasses.replace(arr, counts=counts)
    with pytest.raises(BooleanError, match=r"\[classify\] winding numbers are inconsistent across edges"):
        planar._classify(bad, S)
    nxt = arr.next.copy()
    nxt[[0, 1]] = nxt[[1, 0]]
    with pytest.raises(BooleanError, match=r"\[imprint\] next does not continue at the head vertex"):
        planar._check_half_edges(dataclasses.replace(arr, next=nxt))
    with pytest.raises(BooleanError, match=r"\[imprint\] next is not a permutation"):
        planar._check_half_edges(dataclasses.replace(arr, next=np.zeros_like(arr.next)))
    d0, d1 = np.zeros((2, 2)), np.ones((2, 2))
    with pytest.raises(BooleanError, match=r"\[imprint\] two edges leave a vertex in the same direction"):
        planar._verify_rotation(np.arange(2), np.zeros(2, np.int64), np.zeros(2, np.int64), d0, d1)
    rs = planar._overlay(planar._segments(PolygonSet.coerce([sq(0, 0, 1, 1), sq(2, 2, 3, 3)]), PolygonSet.empty()), "union")
    with pytest.raises(BooleanError, match=r"\[select\] a polygon of the result has 2 outer rings, expected 1"):
        planar._assemble(dataclasses.replace(rs, group=np.zeros_like(rs.group)))


def test_floating_component_without_enclosing_edge_raises(monkeypatch):
    monkeypatch.setattr(planar, "_shoot_left", lambda arr, S, anchors: np.full(len(anchors), -1))
    with pytest.raises(BooleanError, match=r"\[select\] a component inside R has nothing to its left"):
        polygon_difference(sq(0, 0, 4, 4), sq(1, 1, 2, 2))


# ---------------------------------------------------------------------- checker
@pytest.mark.parametrize(
    ("polygons", "code"),
    [
        ([sq(0, 0, 2, 2), sq(1, 1, 3, 3)], "overlap"),
        ([sq(0, 0, 1, 1), sq(1, 0, 2, 1)], "shared_edge"),
        ([sq(0, 0, 2, 2), [[2, 1], [3, 0], [3, 2]]], "vertex_on_edge"),
        ([(sq(0, 0, 1, 1), [sq(5, 5, 6, 6)])], "hole_outside"),
        ([(sq(0, 0, 4, 4), []), (sq(10, 0, 14, 4), [sq(1, 1, 2, 2)])], "grouping"),
    ],
)
def test_checker_codes(polygons, code):
    report = check_polygon_set(polygons)
    assert code in report.codes(), report.summary()


def test_checker_on_rings_that_bypass_validation():
    bow = np.array([[0.0, 0.0], [1.0, 1.0], [1.0, 0.0], [0.0, 1.0]])
    cw = np.array(sq(0, 0, 1, 1), dtype=float)[::-1].copy()
    report = check_polygon_set(PolygonSet((Polygon._trusted(bow, ()), Polygon._trusted(cw, ()))))
    assert report.codes() == {"ring_not_simple", "ring_orientation"}
    assert "polygon 0 ring 0: segment 0" in report.summary()
    assert check_polygon_set(polygon_union(sq(0, 0, 2, 2), sq(1, 1, 3, 3))).ok
