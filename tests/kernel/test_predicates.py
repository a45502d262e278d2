"""Exact predicates: every sign equals the sign computed with fractions.Fraction, including the
near-degenerate inputs where plain float64 evaluation is wrong, and every error branch."""

from __future__ import annotations

from fractions import Fraction

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from coons.errors import InvalidInputError
from coons.kernel.predicates import (
    SegmentRelation,
    classify_segments,
    cross_sign,
    incircle,
    orient2d,
    orient3d,
    segment_intersection_points,
)

ULP = 2.0**-53  # one step at 0.5 (the spacing of floats in [0.5, 1) is 2^-53)


# ---------------------------------------------------------------------- references
def F(x) -> Fraction:
    return Fraction(float(x))


def sgn(v) -> int:
    return (v > 0) - (v < 0)


def ref_orient2d(a, b, c) -> int:
    ax, ay, bx, by, cx, cy = (F(v) for v in (*a, *b, *c))
    return sgn((ax - cx) * (by - cy) - (ay - cy) * (bx - cx))


def ref_cross(a0, a1, b0, b1) -> int:
    return sgn((F(a1[0]) - F(a0[0])) * (F(b1[1]) - F(b0[1])) - (F(a1[1]) - F(a0[1])) * (F(b1[0]) - F(b0[0])))


def ref_orient3d(a, b, c, d) -> int:
    rows = [[F(p[k]) - F(d[k]) for k in range(3)] for p in (a, b, c)]
    (a0, a1, a2), (b0, b1, b2), (c0, c1, c2) = rows
    return sgn(a0 * (b1 * c2 - b2 * c1) - a1 * (b0 * c2 - b2 * c0) + a2 * (b0 * c1 - b1 * c0))


def ref_incircle(a, b, c, d) -> int:
    rows = []
    for p in (a, b, c):
        x, y = F(p[0]) - F(d[0]), F(p[1]) - F(d[1])
        rows.append((x, y, x * x + y * y))
    (a0, a1, a2), (b0, b1, b2), (c0, c1, c2) = rows
    return sgn(a0 * (b1 * c2 - b2 * c1) - a1 * (b0 * c2 - b2 * c0) + a2 * (b0 * c1 - b1 * c0))


def naive_orient2d(a, b, c) -> np.ndarray:
    a, b, c = (np.asarray(x, dtype=float) for x in (a, b, c))
    return np.sign((a[..., 0] - c[..., 0]) * (b[..., 1] - c[..., 1]) - (a[..., 1] - c[..., 1]) * (b[..., 0] - c[..., 0]))


finite = st.floats(min_value=-1e6, max_value=1e6, allow_nan=False, allow_infinity=False)
point2 = st.tuples(finite, finite)


# ---------------------------------------------------------------------- orient2d
def test_orient2d_shewchuk_grid_is_exact_where_float_is_wrong():
    # Shewchuk 1997, fig. 1: a = (0.5 + i ulp, 0.5 + j ulp) against the line through (12, 12), (24, 24).
    i, j = np.meshgrid(np.arange(256), np.arange(256), indexing="ij")
    a = np.stack([0.5 + i * ULP, 0.5 + j * ULP], axis=-1)
    ours = orient2d(a, [12.0, 12.0], [24.0, 24.0])
    assert ours.shape == (256, 256) and ours.dtype == np.int8
    # Exactly, orient = 12 (a.y - a.x): the sign of j - i.
    np.testing.assert_array_equal(ours, np.sign(j - i))
    assert np.count_nonzero(naive_orient2d(a, [12.0, 12.0], [24.0, 24.0]) != np.sign(j - i)) > 1000
    for ii, jj in [(0, 0), (3, 200), (255, 254), (128, 129)]:  # spot-check the closed form against Fractions
        assert ours[ii, jj] == ref_orient2d(a[ii, jj], (12.0, 12.0), (24.0, 24.0))


@settings(max_examples=200)
@given(point2, point2, st.floats(0, 1), st.integers(-3, 3), st.integers(-3, 3))
def test_orient2d_near_collinear_matches_fraction(a, b, t, dx, dy):
    # c is a point of segment ab rounded to floats and nudged by a few ulps: nearly collinear.
    c = np.array([a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1])])
    for k, steps in enumerate((dx, dy)):
        for _ in range(abs(steps)):
            c[k] = np.nextafter(c[k], np.inf if steps > 0 else -np.inf)
    assert orient2d(a, b, c) == ref_orient2d(a, b, c)


@given(point2, point2, point2)
def test_orient2d_symmetries(a, b, c):
    s = int(orient2d(a, b, c))
    assert s == ref_orient2d(a, b, c)
    assert int(orient2d(b, c, a)) == s and int(orient2d(c, a, b)) == s  # cyclic invariance
    assert int(orient2d(b, a, c)) == -s  # antisymmetry


@pytest.mark.parametrize("scale", [2.0**-1000, 2.0**-1030, 2.0**900, 2.0**1000])
def test_orient2d_exact_under_underflow_and_overflow(scale):
    # Scaling by a power of two keeps the exact sign; products underflow (to subnormals or 0)
    # or overflow (to inf), which the filter must send to the exact stage.
    rng = np.random.default_rng(7)
    base = rng.integers(-4, 5, size=(300, 3, 2)).astype(float)  # many exactly collinear triples
    base[:, 2] += rng.choice([0.0, 2.0**-40], size=(300, 2))
    expected = np.array([ref_orient2d(*t) for t in base])
    np.testing.assert_array_equal(orient2d(base[:, 0], base[:, 1], base[:, 2]), expected)
    scaled = base * scale
    np.testing.assert_array_equal(scaled / scale, base)  # the scaling is exact (subnormals included)
    np.testing.assert_array_equal(orient2d(scaled[:, 0], scaled[:, 1], scaled[:, 2]), expected)


def test_orient2d_broadcasts():
    c = np.array([[0.0, 1.0], [0.0, -1.0], [2.0, 0.0]])
    np.testing.assert_array_equal(orient2d([0.0, 0.0], [1.0, 0.0], c), [1, -1, 0])
    assert orient2d(np.zeros((4, 5, 2)), [1.0, 0.0], [0.0, 1.0]).shape == (4, 5)


# ---------------------------------------------------------------------- cross_sign, orient3d, incircle
@settings(max_examples=150)
@given(point2, point2, point2, st.integers(-2, 2))
def test_cross_sign_matches_fraction_on_near_parallel_vectors(a0, a1, b0, nudge):
    b1 = np.array([b0[0] + (a1[0] - a0[0]), b0[1] + (a1[1] - a0[1])])  # parallel up to rounding
    for _ in range(abs(nudge)):
        b1[1] = np.nextafter(b1[1], np.inf if nudge > 0 else -np.inf)
    assert cross_sign(a0, a1, b0, b1) == ref_cross(a0, a1, b0, b1)


@settings(max_examples=120)
@given(st.lists(st.tuples(finite, finite, finite), min_size=3, max_size=3), st.floats(0, 1), st.floats(0, 1))
def test_orient3d_near_coplanar_matches_fraction(abc, s, t):
    a, b, c = (np.array(p) for p in abc)
    d = a + s * (b - a) + t * (c - a)  # on the plane up to rounding
    assert orient3d(a, b, c, d) == ref_orient3d(a, b, c, d)
    assert orient3d(a, b, c, d + [0.0, 0.0, 1e-9]) == ref_orient3d(a, b, c, d + [0.0, 0.0, 1e-9])


def test_orient3d_sign_convention_and_scale_invariance():
    a, b, c = [0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]
    assert orient3d(a, b, c, [0.3, 0.3, -1.0]) == 1  # below the counter-clockwise triangle
    assert orient3d(a, b, c, [0.3, 0.3, 1.0]) == -1
    assert orient3d(a, b, c, [5.0, -7.0, 0.0]) == 0
    rng = np.random.default_rng(3)
    P = rng.integers(-3, 4, size=(200, 4, 3)).astype(float)
    expected = np.array([ref_orient3d(*p) for p in P])
    for scale in (1.0, 2.0**-1000, 2.0**700):
        Q = P * scale
        np.testing.assert_array_equal(orient3d(Q[:, 0], Q[:, 1], Q[:, 2], Q[:, 3]), expected)


@settings(max_examples=120)
@given(st.lists(st.floats(0, 2 * np.pi), min_size=4, max_size=4), st.floats(0.5, 1e3))
def test_incircle_near_cocircular_matches_fraction(angles, r):
    # Four points on a circle, rounded to floats: nearly cocircular.
    P = np.array([[r * np.cos(t), r * np.sin(t)] for t in angles])
    assert incircle(*P) == ref_incircle(*P)


def test_incircle_sign_convention_and_exact_zero():
    a, b, c = [1.0, 0.0], [0.0, 1.0], [-1.0, 0.0]
    assert incircle(a, b, c, [0.0, 0.0]) == 1
    assert incircle(a, b, c, [0.0, 2.0]) == -1
    assert incircle(a, b, c, [0.0, -1.0]) == 0
    assert incircle(c, b, a, [0.0, 0.0]) == -1  # clockwise a, b, c flips the sign
    tiny = np.array([a, b, c, [0.0, -1.0]]) * 2.0**-1060
    assert incircle(*tiny) == 0


# ---------------------------------------------------------------------- segments
def ref_classify(p0, p1, q0, q1) -> SegmentRelation:
    """Brute-force reference with Fractions: parametrise and intersect."""
    P0, P1, Q0, Q1 = ([F(c) for c in p] for p in (p0, p1, q0, q1))
    d = [P1[0] - P0[0], P1[1] - P0[1]]
    e = [Q1[0] - Q0[0], Q1[1] - Q0[1]]
    den = d[0] * e[1] - d[1] * e[0]
    w = [Q0[0] - P0[0], Q0[1] - P0[1]]
    if d == [0, 0] or e == [0, 0]:  # a point against a segment (or a point)
        (pt, a, b) = (P0, Q0, Q1) if d == [0, 0] else (Q0, P0, P1)
        on_line = (b[0] - a[0]) * (pt[1] - a[1]) - (b[1] - a[1]) * (pt[0] - a[0]) == 0
        inside = min(a[0], b[0]) <= pt[0] <= max(a[0], b[0]) and min(a[1], b[1]) <= pt[1] <= max(a[1], b[1])
        return SegmentRelation.TOUCHING if on_line and inside else SegmentRelation.DISJOINT
    if den != 0:
        t = (w[0] * e[1] - w[1] * e[0]) / den
        u = (w[0] * d[1] - w[1] * d[0]) / den
        if not (0 <= t <= 1 and 0 <= u <= 1):
            return SegmentRelation.DISJOINT
        return SegmentRelation.CROSSING if 0 < t < 1 and 0 < u < 1 else SegmentRelation.TOUCHING
    if w[0] * d[1] - w[1] * d[0] != 0:
        return SegmentRelation.DISJOINT  # parallel, different lines
    # Collinear: project on the dominant axis of d (or of e).
    ax = 0 if (d[0] != 0 or e[0] != 0) else 1
    lo = max(min(P0[ax], P1[ax]), min(Q0[ax], Q1[ax]))
    hi = min(max(P0[ax], P1[ax]), max(Q0[ax], Q1[ax]))
    if lo > hi:
        return SegmentRelation.DISJOINT
    return SegmentRelation.OVERLAP if lo < hi else SegmentRelation.TOUCHING


grid = st.tuples(st.integers(0, 4), st.integers(0, 4)).map(lambda t: (t[0] / 2.0, t[1] / 2.0))


@settings(max_examples=300)
@given(grid, grid, grid, grid)
def test_classify_segments_on_a_coarse_grid_matches_fraction(p0, p1, q0, q1):
    # A 5x5 grid makes collinear overlaps, touching endpoints and point segments common.
    assert int(classify_segments(p0, p1, q0, q1)) == ref_classify(p0, p1, q0, q1)
    assert int(classify_segments(q0, q1, p0, p1)) == ref_classify(p0, p1, q0, q1)  # symmetric


@pytest.mark.parametrize(
    ("segments", "relation"),
    [
        (([0, 0], [2, 2], [0, 2], [2, 0]), SegmentRelation.CROSSING),
        (([0, 0], [2, 0], [1, 0], [1, 5]), SegmentRelation.TOUCHING),  # T junction
        (([0, 0], [1, 0], [1, 0], [3, 0]), SegmentRelation.TOUCHING),  # collinear, end to end
        (([0, 0], [2, 0], [1, 0], [3, 0]), SegmentRelation.OVERLAP),
        (([0, 0], [3, 0], [1, 0], [2, 0]), SegmentRelation.OVERLAP),  # one inside the other
        (([0, 0], [1, 0], [2, 0], [3, 0]), SegmentRelation.DISJOINT),  # collinear, apart
        (([0, 0], [1, 0], [0, 1], [1, 1]), SegmentRelation.DISJOINT),  # parallel
        (([1, 0], [1, 0], [0, 0], [2, 0]), SegmentRelation.TOUCHING),  # a point on a segment
        (([0, 0], [0.5 + ULP, 0.5], [0.5, 0.5], [1, 1]), SegmentRelation.DISJOINT),  # one ulp short
    ],
)
def test_classify_segments_cases(segments, relation):
    assert int(classify_segments(*segments)) == relation


@settings(max_examples=150)
@given(point2, point2, point2, point2)
def test_intersection_points_are_exact(p0, p1, q0, q1):
    rel = int(classify_segments(p0, p1, q0, q1))
    if rel not in (SegmentRelation.CROSSING, SegmentRelation.TOUCHING):
        return
    r = segment_intersection_points([p0], [p1], [q0], [q1])
    x, y = r.x[0], r.y[0]
    assert isinstance(x, Fraction) and isinstance(y, Fraction)
    for a, b in ((p0, p1), (q0, q1)):  # the exact point lies on both lines
        (ax, ay), (bx, by) = (F(a[0]), F(a[1])), (F(b[0]), F(b[1]))
        assert (bx - ax) * (y - ay) - (by - ay) * (x - ax) == 0
    assert r.rounded[0, 0] == float(x) and r.rounded[0, 1] == float(y)  # nearest float


def test_intersection_points_known_values():
    r = segment_intersection_points(
        [[0, 0], [0, 0], [0, 0]], [[1, 1], [3, 0], [2, 0]], [[0, 1], [1, 0], [1, 0]], [[3, 0], [1, 1], [1, 3]]
    )
    assert list(zip(r.x, r.y)) == [
        (Fraction(3, 4), Fraction(3, 4)),
        (Fraction(1), Fraction(0)),
        (Fraction(1), Fraction(0)),
    ]
    # 1/3 is not a float: the rounding is the nearest one.
    r = segment_intersection_points([[0, 0]], [[1, 0]], [[1 / 3, -1]], [[1 / 3, 1]])
    assert r.x[0] == Fraction(1 / 3) and r.rounded[0, 0] == 1 / 3
    r = segment_intersection_points([[0, 0]], [[3, 3]], [[0, 1]], [[1, 0]])
    assert r.x[0] == Fraction(1, 2)
    r = segment_intersection_points([[0, 0]], [[3, 0]], [[1, -1]], [[2, 2]])
    assert r.x[0] == Fraction(4, 3) and r.rounded[0, 0] == 4 / 3


# ---------------------------------------------------------------------- errors
def test_errors_name_the_problem():
    with pytest.raises(InvalidInputError, match=r"a: expected points of shape \(\.\.\., 2\), got shape \(3,\)"):
        orient2d([0, 0, 0], [1, 0], [0, 1])
    with pytest.raises(InvalidInputError, match=r"d: expected points of shape \(\.\.\., 3\), got shape \(2,\)"):
        orient3d([0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0])
    with pytest.raises(InvalidInputError, match="c: coordinates must be finite"):
        orient2d([0, 0], [1, 0], [np.nan, 1])
    with pytest.raises(InvalidInputError, match="b: coordinates must be finite"):
        incircle([0, 0], [np.inf, 0], [0, 1], [1, 1])
    with pytest.raises(InvalidInputError, match=r"do not broadcast: shapes \(2, 2\), \(3, 2\)"):
        cross_sign(np.zeros((2, 2)), np.zeros((3, 2)), [0, 0], [1, 1])
    with pytest.raises(InvalidInputError, match="pair 1: expected segments meeting in one point .* got OVERLAP"):
        segment_intersection_points([[0, 0], [0, 0]], [[1, 1], [2, 0]], [[0, 1], [1, 0]], [[1, 0], [3, 0]])
    with pytest.raises(InvalidInputError, match="pair 0: .* got DISJOINT"):
        segment_intersection_points([[0, 0]], [[1, 0]], [[0, 1]], [[1, 1]])
    with pytest.raises(InvalidInputError, match=r"expected \(k, 2\) arrays of segment endpoints"):
        segment_intersection_points([0, 0], [1, 1], [0, 1], [1, 0])


def test_scalar_forms_equal_the_vectorised_predicates_near_degeneracy():
    """orient2d_one / incircle_one (used one at a time in the CDT's flip loops) give the same exact signs."""
    from coons.kernel.predicates import incircle, incircle_one, orient2d, orient2d_one

    e = 2.0**-53
    k = np.arange(-16, 17)
    A = np.stack(np.meshgrid(0.5 + k * e, 0.5 + k * e, indexing="ij"), axis=-1).reshape(-1, 2)
    B, C = np.array([12.0, 12.0]), np.array([24.0, 24.0])
    vec = orient2d(A, B, C)
    assert set(vec.tolist()) == {-1, 0, 1}
    assert [orient2d_one(a, B, C) for a in A] == vec.tolist()
    # Points on and next to the unit circle through three exact points.
    a, b, c = np.array([1.0, 0.0]), np.array([0.0, 1.0]), np.array([-1.0, 0.0])
    D = np.stack([np.zeros_like(k, dtype=float), -1.0 + k * e], axis=1)
    vec = incircle(a, b, c, D)
    assert set(vec.tolist()) == {-1, 0, 1}
    assert [incircle_one(a, b, c, d) for d in D] == vec.tolist()


def test_finite_check_survives_an_overflowing_sum_and_catches_nan_and_inf():
    """The finiteness test sums the coordinates first: a finite input whose sum overflows still passes,
    and a NaN or inf anywhere still raises."""
    import warnings

    from coons.errors import InvalidInputError
    from coons.kernel.predicates import orient2d

    big = np.array([[1e308, 1e308], [1e308, -1e308], [1e308, 1e308]])
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        orient2d(big[0], big[1], big[2])  # no overflow warning, no error
    for bad in (np.nan, np.inf, -np.inf):
        a = np.zeros((4, 2))
        a[2, 1] = bad
        with pytest.raises(InvalidInputError, match="coordinates must be finite"):
            orient2d(a, np.ones((4, 2)), np.zeros((4, 2)))
