"""The constrained Delaunay triangulator: exact predicates, constraints present, holes empty, areas exact,
Delaunay where unconstrained, and every rejected input with its reason."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from coons.errors import InvalidInputError
from coons.topology._cdt import ConstrainedDelaunay, _Mesh, _remove_flat, incircle, orient2d, triangulate

AREA_RTOL = 1e-12  # sums of triangle areas against the shoelace formula (round-off only)


def signed_areas(P, T):
    a, b, c = P[T[:, 0]], P[T[:, 1]], P[T[:, 2]]
    return 0.5 * ((b - a)[:, 0] * (c - a)[:, 1] - (b - a)[:, 1] * (c - a)[:, 0])


def shoelace(P, S):
    A, B = P[S[:, 0]], P[S[:, 1]]
    return 0.5 * float(np.sum(A[:, 0] * B[:, 1] - B[:, 0] * A[:, 1]))


def loop(start, k):
    i = np.arange(k)
    return np.stack([start + i, start + (i + 1) % k], axis=1)


def directed_edges(T):
    return set(zip(T.ravel().tolist(), T[:, [1, 2, 0]].ravel().tolist()))


def assert_valid(P, S, T, area):
    """Counter-clockwise, non-degenerate, area = region area, each constraint the edge of one triangle (on its left)."""
    A = signed_areas(P, T)
    assert np.all(A > 0)
    np.testing.assert_allclose(A.sum(), area, rtol=AREA_RTOL)
    d = directed_edges(T)
    assert len(d) == 3 * T.shape[0]  # no directed edge twice: the triangles do not overlap
    for a, b in S.tolist():
        assert (a, b) in d and (b, a) not in d


# ---------------------------------------------------------------------- predicates
def test_orient2d_is_exact_where_floating_point_is_not():
    # Shewchuk's example: a = (0.5 + i ulp, 0.5) against the line through (12, 12) and (24, 24).
    # Exactly, orient(a, b, c) = 6 - 12 a.x + ... = sign(a.y - a.x), which the naive formula gets wrong.
    b, c = (12.0, 12.0), (24.0, 24.0)
    naive_wrong = 0
    for i in range(-64, 65):
        a = (0.5 + i * 2.0**-54, 0.5)
        exact = int(np.sign(a[1] - a[0]))  # Sterbenz: the subtraction is exact
        assert orient2d(a, b, c) == exact
        naive = np.sign((b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]))
        naive_wrong += int(naive != exact)
    assert naive_wrong > 0  # the filter matters on this input
    assert orient2d((0, 0), (1, 0), (0, 1)) == 1 and orient2d((0, 0), (0, 1), (1, 0)) == -1


def test_incircle_exact_on_cocircular_points():
    s = np.sqrt(0.5)
    assert incircle((1, 0), (0, 1), (-1, 0), (0, -1)) == 0
    assert incircle((1, 0), (0, 1), (-1, 0), (s, -s)) in (-1, 0, 1)  # rounded point: decided exactly, no exception
    assert incircle((1, 0), (0, 1), (-1, 0), (0, 0)) == 1
    assert incircle((1, 0), (0, 1), (-1, 0), (0, -1.0000001)) == -1


# ---------------------------------------------------------------------- regions
def test_square_with_hole_leaves_the_hole_empty():
    outer = [[0, 0], [4, 0], [4, 4], [0, 4]]
    hole = [[1, 1], [1, 3], [3, 3], [3, 1]]  # clockwise
    P = np.array(outer + hole, dtype=float)
    S = np.concatenate([loop(0, 4), loop(4, 4)])
    T = triangulate(P, S)
    assert_valid(P, S, T, 12.0)
    C = P[T].mean(axis=1)
    assert not np.any(np.all((C > 1) & (C < 3), axis=1))
    assert T.shape[0] == 8  # V - E + F: 8 points, annulus


def test_comb_non_convex_polygon():
    n = 40
    xs = np.linspace(0, 10, 2 * n)
    teeth = np.stack([xs, np.where(np.arange(2 * n) % 2 == 0, 10.0, 1.0)], axis=1)
    P = np.vstack([[[0.0, 0.0], [10.0, 0.0]], teeth[::-1]])
    S = loop(0, P.shape[0])
    T = triangulate(P, S)
    assert_valid(P, S, T, shoelace(P, S))
    assert T.shape[0] == P.shape[0] - 2  # a simple polygon without interior points


def test_collinear_boundary_points_and_interior_grid():
    side = np.linspace(0, 1, 11)[:-1]
    ring = np.concatenate([
        np.stack([side, 0 * side], 1), np.stack([1 + 0 * side, side], 1),
        np.stack([1 - side, 1 + 0 * side], 1), np.stack([0 * side, 1 - side], 1),
    ])
    g = np.linspace(0.05, 0.95, 10)
    U, V = np.meshgrid(g, g)
    P = np.vstack([ring, np.stack([U.ravel(), V.ravel()], 1)])
    S = loop(0, ring.shape[0])
    T = triangulate(P, S)
    assert_valid(P, S, T, 1.0)
    assert np.unique(T).size == P.shape[0]  # every point used
    # Delaunay away from the constraints: no point inside any triangle's circumcircle across an interior edge.
    assert _locally_delaunay(P, T, S)


def _locally_delaunay(P, T, S, rel=1e-9):
    """No unconstrained edge whose opposite point lies clearly inside the other triangle's circumcircle
    (within ``rel`` of the in-circle determinant's scale: Qhull decides near-cocircular points in floating point)."""
    fixed = {tuple(sorted(s)) for s in S.tolist()}
    where = {}
    for k, t in enumerate(T.tolist()):
        for j in range(3):
            where[(t[j], t[(j + 1) % 3])] = (k, t[(j + 2) % 3])
    for (a, b), (k, c) in where.items():
        if (b, a) in where and tuple(sorted((a, b))) not in fixed:
            d = where[(b, a)][1]
            rows = np.array([P[a] - P[d], P[b] - P[d], P[c] - P[d]])
            M = np.column_stack([rows, (rows**2).sum(axis=1)])
            scale = np.prod(np.abs(M).max(axis=0) + 1e-300)
            if np.linalg.det(M) > rel * scale and incircle(P[a], P[b], P[c], P[d]) > 0:
                return False
    return True


def test_points_outside_the_loop_are_left_out():
    P = np.array([[0, 0], [1, 0], [1, 1], [0, 1], [0.5, 0.5], [3, 3], [-2, 0.5]], dtype=float)
    T = triangulate(P, loop(0, 4))
    assert_valid(P, loop(0, 4), T, 1.0)
    assert set(np.unique(T).tolist()) == {0, 1, 2, 3, 4}


def test_missing_constraints_are_recovered_by_flips():
    # A long thin diamond whose diagonal is far from Delaunay: points close to it on both sides.
    xs = np.linspace(0.5, 9.5, 19)
    above = np.stack([xs, np.full_like(xs, 0.05)], 1)
    below = np.stack([xs, np.full_like(xs, -0.05)], 1)
    P = np.vstack([[[0.0, 0.0], [10.0, 0.0], [5.0, 5.0], [5.0, -5.0]], above, below])
    S = np.array([[0, 1]])
    T = triangulate(P, S, return_all=True)
    d = directed_edges(T)
    assert (0, 1) in d and (1, 0) in d
    assert _locally_delaunay(P, T, S)
    # The same segment as the base of a region: the triangles above it only.
    S2 = np.array([[0, 1], [1, 2], [2, 0]])
    T2 = triangulate(P, S2)
    assert_valid(P, S2, T2, 25.0)


def test_a_slit_given_both_ways_keeps_both_sides():
    P = np.array([[0, 0], [2, 0], [2, 2], [0, 2], [1, 1], [1, 1.5]], dtype=float)
    S = np.concatenate([loop(0, 4), [[4, 5], [5, 4]]])
    T = triangulate(P, S)
    assert signed_areas(P, T).sum() == pytest.approx(4.0, rel=AREA_RTOL)
    d = directed_edges(T)
    assert (4, 5) in d and (5, 4) in d


# ---------------------------------------------------------------------- random simple polygons
@st.composite
def star_polygons(draw):
    """A simple counter-clockwise polygon star-shaped about the origin, maybe a clockwise hole, and random points."""
    k = draw(st.integers(3, 40))
    gaps = np.array(draw(st.lists(st.floats(0.05, 1.0), min_size=k, max_size=k)))
    angles = np.cumsum(gaps) / gaps.sum() * 2 * np.pi
    if np.max(np.diff(np.concatenate([[angles[-1] - 2 * np.pi], angles]))) >= 0.95 * np.pi:
        angles = np.linspace(0, 2 * np.pi, k, endpoint=False)  # every turn about the origin < π: a simple polygon
    radii = np.array(draw(st.lists(st.floats(1.0, 10.0), min_size=k, max_size=k)))
    outer = np.stack([radii * np.cos(angles), radii * np.sin(angles)], 1)
    hole_k = draw(st.sampled_from([0, 0, 3, 5, 8]))
    hole = np.zeros((0, 2))
    if hole_k:
        A, B = outer, np.roll(outer, -1, axis=0)
        t = np.clip(np.einsum("ij,ij->i", -A, B - A) / np.einsum("ij,ij->i", B - A, B - A), 0, 1)
        reach = np.min(np.linalg.norm(A + t[:, None] * (B - A), axis=1))  # distance of the boundary from the origin
        a = np.linspace(0, 2 * np.pi, hole_k, endpoint=False)[::-1] + draw(st.floats(0, 1))
        hole = 0.5 * reach * np.stack([np.cos(a), np.sin(a)], 1)
    n_in = draw(st.integers(0, 30))
    inner = np.array(draw(st.lists(st.tuples(st.floats(-10, 10), st.floats(-10, 10)), min_size=n_in, max_size=n_in)))
    return outer, hole, inner.reshape(-1, 2)


@given(star_polygons())
def test_random_star_polygons_area_and_constraints(poly):
    outer, hole, inner = poly
    nb = len(outer) + len(hole)
    S = np.concatenate([loop(0, len(outer)), loop(len(outer), len(hole)) if len(hole) else np.zeros((0, 2), int)])
    boundary = np.vstack([outer, hole])
    # Interior points on a boundary segment, or within Qhull's precision of another point, are not valid input.
    A, B = boundary[S[:, 0]], boundary[S[:, 1]]
    keep = []
    for x in inner:
        t = np.clip(np.einsum("ij,ij->i", x - A, B - A) / np.einsum("ij,ij->i", B - A, B - A), 0, 1)
        if np.min(np.linalg.norm(A + t[:, None] * (B - A) - x, axis=1)) > 1e-6:
            keep.append(x)
    inner = np.unique(np.round(np.array(keep).reshape(-1, 2), 6), axis=0)  # Qhull merges near-duplicates
    P = np.vstack([boundary, inner])
    T = triangulate(P, S)
    assert_valid(P, S, T, shoelace(P, S))
    assert np.all(np.isin(np.arange(nb), T))


# ---------------------------------------------------------------------- rejected input
SQUARE = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], dtype=float)


@pytest.mark.parametrize(
    "points, segments, match",
    [
        (np.zeros((4, 3)), loop(0, 4), r"points must have shape \(n, 2\)"),
        (np.array([[0, 0], [1, 0], [np.nan, 1], [0, 1]]), loop(0, 4), "NaN or inf"),
        (SQUARE, np.array([[0, 1.5]]), "integer array of shape"),
        (SQUARE, np.array([[0, 4]]), r"indices must lie in \[0, 4\), got \[0, 4\]"),
        (SQUARE, np.array([[2, 2]]), "segment 0 joins point 2 to itself"),
        (SQUARE[:2], np.zeros((0, 2), int), "need at least 3 points, got 2"),
        (np.vstack([SQUARE, [[1, 1]]]), loop(0, 4), "points 2 and 4 coincide"),
        (np.vstack([SQUARE, [[0.5, 0]]]), loop(0, 4), r"point 4 \[0.5, 0.0\] lies on constraint segment \(0, 1\)"),
        (np.zeros((3, 2)), np.zeros((0, 2), int), "coincide"),
    ],
)
def test_invalid_input_raises(points, segments, match):
    with pytest.raises(InvalidInputError, match=match):
        triangulate(points, segments)


def test_crossing_constraints_raise():
    P = np.array([[0, 0], [2, 0], [2, 2], [0, 2], [1, -1], [1, 3], [-1, 1], [3, 1.2]], dtype=float)
    S = np.concatenate([loop(0, 4), [[4, 5], [6, 7]]])
    with pytest.raises(InvalidInputError, match="cross"):
        triangulate(P, S)


def test_contradicting_orientation_raises():
    outer = [[0, 0], [4, 0], [4, 4], [0, 4]]
    hole_ccw = [[1, 1], [3, 1], [3, 3], [1, 3]]  # should be clockwise
    P = np.array(outer + hole_ccw, dtype=float)
    with pytest.raises(InvalidInputError, match="contradict each other"):
        triangulate(P, np.concatenate([loop(0, 4), loop(4, 4)]))


def test_no_segments_gives_no_region():
    assert triangulate(SQUARE, np.zeros((0, 2), int)).shape == (0, 3)
    assert triangulate(SQUARE, np.zeros((0, 2), int), return_all=True).shape == (2, 3)


def test_flat_triangles_are_flipped_away():
    # (b, a, c) is flat (c halfway along a b) and shares a b with (a, b, d): flipping a b to c d.
    P = np.array([[0, 0], [2, 0], [1, 0], [1, 1]], dtype=float)  # a, b, c, d
    T = np.array([[1, 0, 2], [0, 1, 3]])
    N = np.array([[-1, -1, 1], [-1, -1, 0]])
    mesh = _Mesh(P, T, N)
    _remove_flat(mesh, np.array([0]))
    T2, N2 = mesh.arrays()
    assert np.all(signed_areas(P, T2) > 0)
    assert sorted(map(sorted, T2.tolist())) == [[0, 2, 3], [1, 2, 3]]
    assert sorted(N2.ravel().tolist()) == [-1, -1, -1, -1, 0, 1]
    lonely = _Mesh(P[[0, 2, 1]], np.array([[0, 1, 2]]), np.array([[-1, -1, -1]]))
    with pytest.raises(InvalidInputError, match="a flat triangle lies on the hull"):
        _remove_flat(lonely, np.array([0]))


def test_a_corrupt_neighbour_table_raises_instead_of_walking_forever():
    # Two triangles around vertex 0 that name each other as the next one counter-clockwise while
    # neither holds the edge asked for, and the walk's start is not in their cycle: before the
    # bound, triangle_with_edge turned around vertex 0 forever (as on Qhull's folded output).
    from coons.errors import ConvergenceError

    P = np.array([[0, 0], [1, 0], [0, 1], [-1, 0], [0, -1]], dtype=float)
    T = np.array([[0, 1, 2], [0, 2, 3], [0, 3, 4]])
    N = np.array([[-1, 2, -1], [-1, 2, -1], [-1, 1, -1]])  # 1 and 2 point at each other; 0 enters the loop
    mesh = _Mesh(P, T, N)
    mesh.vt[0] = 0
    with pytest.raises(ConvergenceError, match="do not close a fan"):
        mesh.triangle_with_edge(0, 4)  # no edge 0 -> 4 leaves vertex 0 in these triangles


# ---------------------------------------------------------------------- incremental insertion
@given(star_polygons(), st.integers(0, 2**31 - 1))
def test_insertion_gives_the_same_triangulation_as_building_at_once(poly, seed):
    outer, hole, _ = poly
    S = np.concatenate([loop(0, len(outer)), loop(len(outer), len(hole)) if len(hole) else np.zeros((0, 2), int)])
    boundary = np.vstack([outer, hole])
    rng = np.random.default_rng(seed)
    lo, hi = outer.min(axis=0), outer.max(axis=0)
    cand = rng.uniform(lo, hi, size=(100, 2))
    region = triangulate(np.vstack([boundary, cand]), S)  # keeps the candidates inside the region
    used = np.unique(region)
    inner = cand[used[used >= len(boundary)] - len(boundary)][:25]
    cdt = ConstrainedDelaunay(boundary, S)
    T0, ids = cdt.triangles(return_index=True)
    new = cdt.insert(inner, hints=np.full(len(inner), ids[0]))
    np.testing.assert_array_equal(new, len(boundary) + np.arange(len(inner)))
    P = np.vstack([boundary, inner])
    T = cdt.triangles()
    assert_valid(P, S, T, shoelace(P, S))
    assert _locally_delaunay(P, T, S)
    # Euler: a region with h holes, b boundary and i interior points has b + 2 i - 2 + 2 h triangles.
    assert T.shape[0] == len(boundary) + 2 * len(inner) - 2 + 2 * (len(hole) > 0) == triangulate(P, S).shape[0]


def test_insertion_on_an_edge_and_rejected_insertions():
    P = np.array([[0, 0], [2, 0], [2, 2], [0, 2]], dtype=float)
    cdt = ConstrainedDelaunay(P, loop(0, 4))
    T, ids = cdt.triangles(return_index=True)
    diag = [e for e in ((0, 2), (1, 3)) if set(e) <= set(T[0].tolist())][0]
    mid = P[list(diag)].mean(axis=0)
    assert cdt.insert([mid], hints=[ids[0]]).tolist() == [4]
    T2 = cdt.triangles()
    assert T2.shape == (4, 3) and np.all(T2.max(axis=1) == 4)  # the centre joined to every corner
    assert_valid(np.vstack([P, mid]), loop(0, 4), T2, 4.0)
    with pytest.raises(InvalidInputError, match="coincides with a vertex"):
        cdt.insert([[2.0, 2.0]])
    with pytest.raises(InvalidInputError, match=r"lies on constraint segment \(0, 1\)"):
        cdt.insert([[0.5, 0.0]])
    with pytest.raises(InvalidInputError, match="NaN or inf"):
        cdt.insert([[np.nan, 0.0]])


# ---------------------------------------------------------------------- Qhull folds at its precision
@pytest.mark.parametrize("retries", [4, 0])
def test_qhull_folds_are_left_to_the_exact_insertion(monkeypatch, retries):
    # The boundary of a Steinmetz-solid face in its scaled parameter plane (tests/data/README.md):
    # samples ~1e-7 apart on a nearly straight stretch, where Qhull's Delaunay comes back with a
    # triangle that is clockwise by the exact predicate (folded over a neighbour).  Before the
    # repair the incremental insertion then walked around a vertex forever.  The vertices of folded
    # triangles are left out of Qhull's run and inserted exactly (retries > 0), or, once the
    # retries are spent, the whole triangulation is built by exact insertion (retries = 0).
    from pathlib import Path

    from scipy.spatial import Delaunay

    from coons.topology import _cdt

    data = np.load(Path(__file__).parents[1] / "data" / "cdt-steinmetz-face.npz")
    P, S = data["points"], data["segments"].astype(np.int64)
    monkeypatch.setattr(_cdt, "_QHULL_RETRIES", retries)
    Q, T, N, flat, dropped = _cdt._delaunay(P)
    # The input is a hard one: Qhull's own triangulation of the same points has a folded triangle.
    assert np.any(_cdt._orient_signs(Q, Delaunay(Q).simplices.astype(np.int64)) < 0)
    assert np.all(_cdt._orient_signs(Q, T) > 0)
    assert len(directed_edges(T)) == 3 * T.shape[0]  # a triangulation of what it holds
    held = np.zeros(Q.shape[0], dtype=bool)
    held[T.ravel()] = True
    np.testing.assert_array_equal(np.flatnonzero(~held), dropped)  # the rest is left to the caller
    assert (dropped.size > 0) == (retries > 0)
    T2 = triangulate(P, S)
    assert_valid(P, S, T2, shoelace(P, S))


@given(st.integers(0, 2**31 - 1), st.integers(3, 60))
def test_exact_delaunay_fallback_is_delaunay(seed, n):
    from coons.topology._cdt import _exact_delaunay

    rng = np.random.default_rng(seed)
    P = rng.uniform(-5, 5, size=(n, 2))
    lo, hi = P.min(axis=0), P.max(axis=0)
    c, r = 0.5 * (lo + hi), 4.0 * float(np.max(hi - lo))
    Q = np.vstack([P, c + r * np.array([[-1.0, -1.0], [1.0, -1.0], [1.0, 1.0], [-1.0, 1.0]])])
    T, N = _exact_delaunay(Q)
    # Every point used, a triangulation of the corners' square (Euler: n + 4 points on a 4-gon hull).
    assert set(np.unique(T).tolist()) == set(range(n + 4))
    assert T.shape[0] == 2 * (n + 4) - 2 - 4
    assert_valid(Q, np.zeros((0, 2), np.int64), T, 4.0 * r * r)
    assert _locally_delaunay(Q, T, np.zeros((0, 2), np.int64))
    # Neighbours: N[t, j] shares the edge opposite T[t, j].
    for t in range(T.shape[0]):
        for j in range(3):
            u = N[t, j]
            if u >= 0:
                assert {int(T[t, (j + 1) % 3]), int(T[t, (j + 2) % 3])} <= set(T[u].tolist())
