"""Knot insertion, refinement and removal, degree elevation, splitting, Bézier decomposition, iso-curves.

Properties: every exact operation leaves the geometry unchanged to 1e-12 of the control
net size at random parameters; knot vectors and multiplicities come out as the theory
says; insertion and elevation agree with an independent Boehm oracle, the Bézier
closed form and OCCT; removal undoes insertion and never moves a curve or surface by
more than ``tol.linear``; every error branch raises with its message.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from coons.errors import InvalidInputError
from coons.kernel import refine
from coons.kernel.basis import periodic_uniform_knots
from coons.kernel.curve import NurbsCurve
from coons.kernel.surface import NurbsSurface
from coons.tolerance import Tolerance

from .strategies import curves, params_in, surfaces

#: "Unchanged" means agreement to this fraction of the control net size (round-off of the algorithms).
EXACT = 1e-12


def scale_of(obj) -> float:
    return float(np.abs(obj.control_points).max()) + 1.0


def dense_params(knots: np.ndarray, domain, per_span: int = 64) -> np.ndarray:
    """``per_span`` parameters in every non-empty span of ``domain`` plus its ends."""
    a, b = domain
    k = np.unique(knots[(knots >= a) & (knots <= b)])
    s = np.linspace(0.0, 1.0, per_span, endpoint=False)
    return np.append((k[:-1, None] + np.diff(k)[:, None] * s).ravel(), b)


def interior_params(c: NurbsCurve, m: int = 40, seed: int = 0) -> np.ndarray:
    """Random parameters plus the distinct knots inside the open domain.

    The right end of the domain is left out: coons.kernel.basis.find_spans picks an
    empty span there when U[n] is repeated (see test_floating_end_evaluation).
    """
    a, b = c.domain
    k = np.unique(c.knots)
    return np.concatenate([[a], params_in(c.domain, np.random.default_rng(seed), m), k[(k > a) & (k < b)]])


def assert_same_curve(a: NurbsCurve, b: NurbsCurve, u: np.ndarray, scale: float) -> None:
    np.testing.assert_allclose(a(u), b(u), rtol=0, atol=EXACT * scale)


def multiplicity(U: np.ndarray, x: float) -> int:
    return int(np.count_nonzero(U == x))


def boehm_oracle(c: NurbsCurve, u: float, times: int) -> np.ndarray:
    """Independent reference: Boehm's ``Q_i = a_i P_i + (1 - a_i) P_(i-1)`` over all ``i`` (The NURBS Book §5.2)."""
    U, Pw, p = np.array(c.knots), np.array(c.homogeneous), c.degree
    for _ in range(times):
        n = Pw.shape[0]
        lo, hi = U[: n + 1], U[p : n + p + 1]
        ratio = np.divide(u - lo, hi - lo, out=np.zeros(n + 1), where=hi > lo)
        a = np.where(hi <= u, 1.0, np.where(lo >= u, 0.0, ratio))[:, None]
        padded = np.concatenate([Pw[:1], Pw, Pw[-1:]])
        Pw = a * padded[1:] + (1.0 - a) * padded[:-1]
        U = np.sort(np.append(U, u))
    return Pw


def insertable(c: NurbsCurve, fraction: float, use_knot: bool) -> tuple[float, int]:
    """A parameter inside the domain (or an existing interior knot) and how often it can be inserted."""
    a, b = c.domain
    interior = np.unique(c.knots[(c.knots > a) & (c.knots < b)])
    if use_knot and interior.size:
        u = float(interior[int(fraction * interior.size) % interior.size])
    else:
        u = a + (b - a) * (0.05 + 0.9 * fraction)
    return u, c.degree - multiplicity(c.knots, u)


def new_knots(knots: np.ndarray, p: int, domain, fractions) -> list[float]:
    """Parameters at ``fractions`` of ``domain`` that can be inserted together (multiplicity <= p).

    Values within round-off of a knot or of each other are that knot (tested on its
    own), so they are left out here.
    """
    a, b = domain
    X: list[float] = []
    for f in fractions:
        x = a + (b - a) * f
        near = np.min(np.abs(np.append(knots, X) - x))
        if 0 < near < 1e-9 * (b - a):
            continue
        if multiplicity(knots, x) + X.count(x) < p:
            X.append(x)
    return X


def clamped_curve(rng: np.random.Generator, p: int, n: int, d: int = 3, rational: bool = True) -> NurbsCurve:
    inner = np.sort(rng.uniform(0.05, 0.95, n - p - 1))
    U = np.concatenate([np.zeros(p + 1), inner, np.ones(p + 1)])
    w = rng.uniform(0.5, 2.0, n) if rational else None
    return NurbsCurve(rng.uniform(-5, 5, (n, d)), U, p, w)


# ============================================================================ insertion and refinement


@given(curves(), st.floats(0, 1), st.booleans())
def test_insert_knot_keeps_curve_and_matches_boehm(c, fraction, use_knot):
    u, room = insertable(c, fraction, use_knot)
    times = max(room, 0)
    out = c.insert_knot(u, times)
    np.testing.assert_array_equal(out.knots, np.sort(np.concatenate([c.knots, np.full(times, u)])))
    assert out.n_control_points == c.n_control_points + times
    assert out.domain == c.domain
    np.testing.assert_allclose(out.homogeneous, boehm_oracle(c, u, times), rtol=0, atol=EXACT * scale_of(c) * 3)
    assert_same_curve(out, c, interior_params(c), scale_of(c))


def test_insert_knot_zero_times_is_identity():
    c = NurbsCurve([[0, 0], [1, 1], [2, 0]], [0, 0, 0, 1, 1, 1], 2)
    assert c.insert_knot(0.5, 0) is c


def test_insert_knot_takes_round_off_as_the_knot():
    c = NurbsCurve([[0, 0], [1, 1], [2, 0], [3, 1]], [0, 0, 0, 0.5, 1, 1, 1], 2)
    out = c.insert_knot(0.5 + 1e-15)
    assert multiplicity(out.knots, 0.5) == 2
    assert out.knots.shape[0] == c.knots.shape[0] + 1


@given(curves(clamped=False, max_degree=5))
def test_insert_at_floating_domain_ends_clamps_them(c):
    p = c.degree
    assume(p > 1)  # for p = 1 the ends already have multiplicity 1 = p: nothing can be inserted
    a, b = c.domain
    out = c.insert_knot(a, p - multiplicity(c.knots, a)).insert_knot(b, p - multiplicity(c.knots, b))
    assert multiplicity(out.knots, a) == p and multiplicity(out.knots, b) == p
    assert out.domain == c.domain
    assert_same_curve(out, c, interior_params(c), scale_of(c))
    # With multiplicity p at the ends the curve passes through the control points there.
    j = int(np.searchsorted(out.knots, a, side="left"))
    np.testing.assert_allclose(out.control_points[j - 1], c(a), rtol=0, atol=EXACT * scale_of(c))


def test_floating_end_evaluation():
    U = periodic_uniform_knots(5, 3)
    c = NurbsCurve(np.random.default_rng(0).uniform(-1, 1, (5, 2)), U, 3)
    out = c.insert_knot(1.0)
    np.testing.assert_allclose(out(1.0), c(1.0), rtol=0, atol=EXACT * scale_of(c))


@given(curves(), st.lists(st.floats(0, 1), min_size=1, max_size=8))
def test_refine_knots_in_any_order_equals_insertion_one_by_one(c, fractions):
    X = new_knots(c.knots, c.degree, c.domain, fractions)
    assume(X)
    out = c.refine_knots(X)
    one_by_one = c
    for x in X:
        one_by_one = one_by_one.insert_knot(x)
    np.testing.assert_array_equal(out.knots, one_by_one.knots)
    np.testing.assert_array_equal(out.knots, np.sort(np.concatenate([c.knots, X])))
    np.testing.assert_allclose(out.homogeneous, one_by_one.homogeneous, rtol=0, atol=EXACT * scale_of(c) * 3)
    assert_same_curve(out, c, interior_params(c), scale_of(c))


def test_refine_knots_empty_is_identity():
    c = NurbsCurve([[0, 0], [1, 1], [2, 0]], [0, 0, 0, 1, 1, 1], 2)
    assert c.refine_knots([]) is c


def test_refine_knots_uniformly_converges_control_polygon_to_curve():
    # Control polygons of refined curves converge to the curve quadratically in the span
    # length (Cohen–Riesenfeld–Elber §6.5): halving the spans quarters the distance.
    c = NurbsCurve([[0, 0], [1, 2], [3, 2], [4, 0], [5, 1]], [0, 0, 0, 0.3, 0.6, 1, 1, 1], 2)
    gaps = []
    for k in (16, 32, 64):
        r = c.refine_knots(np.setdiff1d(np.linspace(0, 1, k + 1)[1:-1], c.knots))
        greville = (r.knots[1:-2] + r.knots[2:-1]) / 2
        gaps.append(np.max(np.linalg.norm(r.control_points - c(greville), axis=1)))
    assert gaps[1] < 0.3 * gaps[0] and gaps[2] < 0.3 * gaps[1]


@pytest.mark.occt
@settings(max_examples=25)
@given(st.integers(0, 2**32 - 1), st.integers(1, 5), st.integers(0, 4), st.floats(0.05, 0.95))
def test_insert_knot_matches_occt(seed, p, extra, u):
    from OCP.Geom import Geom_BSplineCurve  # noqa: F401  (real test dependency)

    c = clamped_curve(np.random.default_rng(seed), p, p + 1 + extra)
    times = p - multiplicity(c.knots, u)
    g = to_occt(c)
    g.InsertKnot(u, times)
    ref = from_occt(g)
    out = c.insert_knot(u, times)
    np.testing.assert_allclose(out.knots, ref.knots, rtol=0, atol=1e-15)
    np.testing.assert_allclose(out.control_points, ref.control_points, rtol=0, atol=EXACT * scale_of(c))
    np.testing.assert_allclose(out.weights, ref.weights, rtol=0, atol=EXACT)


# ============================================================================ removal


@given(curves(), st.floats(0, 1), st.booleans())
def test_remove_knot_undoes_insertion(c, fraction, use_knot):
    u, room = insertable(c, fraction, use_knot)
    assume(room > 0)
    inserted = c.insert_knot(u, room)
    out, count = refine.curve_remove_knots(inserted, u, room)
    assert count == room
    np.testing.assert_array_equal(out.knots, c.knots)
    np.testing.assert_allclose(out.control_points, c.control_points, rtol=0, atol=1e-11 * scale_of(c))
    np.testing.assert_allclose(out.weights, c.weights, rtol=0, atol=1e-11)


@settings(max_examples=40)
@given(curves(), st.floats(0, 1), st.floats(-4, 0))
def test_remove_knot_never_moves_curve_beyond_tolerance(c, fraction, log_tol):
    a, b = c.domain
    interior = np.unique(c.knots[(c.knots > a) & (c.knots < b)])
    assume(interior.size > 0)
    u = float(interior[int(fraction * interior.size) % interior.size])
    tol = Tolerance(linear=scale_of(c) * 10.0**log_tol)
    out, count = refine.curve_remove_knots(c, u, multiplicity(c.knots, u), tol)
    assert out.knots.shape[0] == c.knots.shape[0] - count
    assert multiplicity(out.knots, u) == multiplicity(c.knots, u) - count
    us = dense_params(c.knots, c.domain)[:-1]
    assert np.max(np.linalg.norm(out(us) - c(us), axis=1)) <= tol.linear


def test_remove_knot_stops_at_the_copy_that_matters():
    # A generic cubic whose knot 0.5 (multiplicity 1) shapes the curve; one more copy
    # inserted is removable, the original one is not.
    c = NurbsCurve([[0, 0], [1, 3], [2, -1], [3, 4], [4, 0]], [0, 0, 0, 0, 0.5, 1, 1, 1, 1], 3)
    doubled = c.insert_knot(0.5)
    out, count = refine.curve_remove_knots(doubled, 0.5, 2)
    assert count == 1
    np.testing.assert_array_equal(out.knots, c.knots)
    np.testing.assert_allclose(out.control_points, c.control_points, rtol=0, atol=1e-12)
    assert c.remove_knot(0.5) is c


def test_remove_knot_refuses_a_corner():
    corner = NurbsCurve([[0, 0], [1, 0], [1, 1]], [0, 0, 0.5, 1, 1], 1)
    out, count = refine.curve_remove_knots(corner, 0.5, 1, Tolerance(linear=1e-3))
    assert count == 0 and out is corner


def test_remove_knot_of_straight_polyline_is_exact():
    line = NurbsCurve([[0, 0], [1, 1], [2, 2]], [0, 0, 0.5, 1, 1], 1)
    out, count = refine.curve_remove_knots(line, 0.5)
    assert count == 1
    np.testing.assert_array_equal(out.knots, [0, 0, 1, 1])
    np.testing.assert_allclose(out.control_points, [[0, 0], [2, 2]], rtol=0, atol=1e-15)


def test_remove_knot_with_loose_tolerance_moves_within_it():
    # x is linear in u (control abscissae at the Greville points), y a bump of height
    # 0.01 * max N_2 = 1/120 over the knots 0.4, 0.6.  Removing 0.4 flattens the bump: a
    # tolerance below its height refuses, one above it accepts and moves by the height.
    xi = [0, 0.2, 0.5, 0.8, 1]
    c = NurbsCurve(np.column_stack([xi, [0, 0, 0.01, 0, 0]]), [0, 0, 0, 0.4, 0.6, 1, 1, 1], 2)
    us = np.linspace(0, 1, 2001)
    height = np.max(c(us)[:, 1])
    tight, n_tight = refine.curve_remove_knots(c, 0.4, 1, Tolerance(linear=0.5 * height))
    loose, n_loose = refine.curve_remove_knots(c, 0.4, 1, Tolerance(linear=1e-2))
    assert n_tight == 0 and tight is c and n_loose == 1
    np.testing.assert_allclose(loose.control_points[:, 1], 0.0, rtol=0, atol=1e-15)
    deviation = np.max(np.linalg.norm(loose(us) - c(us), axis=1))
    np.testing.assert_allclose(deviation, height, rtol=1e-12)
    assert deviation <= 1e-2


@pytest.mark.occt
def test_remove_knot_matches_occt():
    from OCP.Geom import Geom_BSplineCurve  # noqa: F401

    c = clamped_curve(np.random.default_rng(7), 3, 7)
    inserted = c.insert_knot(0.55, 2)
    g = to_occt(inserted)
    index = 1 + int(np.flatnonzero(np.unique(inserted.knots) == 0.55)[0])
    assert g.RemoveKnot(index, 0, 1e-9)
    ref = from_occt(g)
    out = inserted.remove_knot(0.55, 2)
    np.testing.assert_allclose(out.knots, ref.knots, rtol=0, atol=1e-15)
    np.testing.assert_allclose(out.control_points, ref.control_points, rtol=0, atol=1e-9)
    np.testing.assert_allclose(out.control_points, c.control_points, rtol=0, atol=EXACT * scale_of(c))


# ============================================================================ degree elevation


@given(curves(), st.integers(0, 3))
def test_elevate_degree_keeps_curve_and_raises_multiplicities(c, times):
    out = c.elevate_degree(times)
    if times == 0:
        assert out is c
        return
    clamped = c.clamped()
    vals, mults = np.unique(clamped.knots, return_counts=True)
    assert out.degree == c.degree + times
    np.testing.assert_array_equal(out.knots, np.repeat(vals, mults + times))
    assert out.n_control_points == clamped.n_control_points + times * (vals.size - 1)
    assert out.domain == c.domain
    assert_same_curve(out, c, interior_params(c), scale_of(c))
    np.testing.assert_allclose(out(c.domain[1]), clamped(c.domain[1]), rtol=0, atol=EXACT * scale_of(c))


@given(st.integers(0, 2**32 - 1), st.integers(1, 6))
def test_elevate_bezier_matches_closed_form(seed, p):
    rng = np.random.default_rng(seed)
    P = rng.uniform(-5, 5, (p + 1, 3))
    c = NurbsCurve(P, np.repeat([0.0, 1.0], p + 1), p)
    i = np.arange(p + 2)[:, None] / (p + 1)
    padded_prev = np.concatenate([P[:1], P])  # P_(i-1), the first one unused (weight 0)
    padded_this = np.concatenate([P, P[-1:]])  # P_i, the last one unused (weight 0)
    expected = i * padded_prev + (1 - i) * padded_this  # The NURBS Book §5.5 with t = 1
    np.testing.assert_allclose(c.elevate_degree().control_points, expected, rtol=0, atol=1e-13)


def test_elevated_quarter_circle_keeps_its_radius():
    s = np.sqrt(0.5)
    arc = NurbsCurve([[1, 0], [1, 1], [0, 1]], [0, 0, 0, 1, 1, 1], 2, [1, s, 1])
    up = arc.elevate_degree(2)
    assert up.is_rational and up.degree == 4
    np.testing.assert_allclose(np.linalg.norm(up(np.linspace(0, 1, 101)), axis=1), 1.0, rtol=0, atol=1e-14)


@pytest.mark.occt
@settings(max_examples=25)
@given(st.integers(0, 2**32 - 1), st.integers(1, 5), st.integers(0, 4), st.integers(1, 3))
def test_elevate_degree_matches_occt(seed, p, extra, times):
    from OCP.Geom import Geom_BSplineCurve  # noqa: F401

    c = clamped_curve(np.random.default_rng(seed), p, p + 1 + extra)
    g = to_occt(c)
    g.IncreaseDegree(p + times)
    ref = from_occt(g)
    out = c.elevate_degree(times)
    np.testing.assert_allclose(out.knots, ref.knots, rtol=0, atol=1e-15)
    np.testing.assert_allclose(out.control_points, ref.control_points, rtol=0, atol=1e-11 * scale_of(c))
    np.testing.assert_allclose(out.weights, ref.weights, rtol=0, atol=1e-11)


@given(curves(), st.floats(0.05, 0.95), st.integers(1, 2))
def test_elevate_then_remove_round_trip(c, fraction, times):
    # Elevating a curve with an extra knot gives that knot multiplicity 1 + times; removing
    # all its copies yields the elevation of the original curve, coefficient by coefficient.
    a, b = c.domain
    u = a + (b - a) * fraction
    assume(multiplicity(c.knots, u) == 0)
    with_knot = c.insert_knot(u).elevate_degree(times)
    assert multiplicity(with_knot.knots, u) == 1 + times
    out, count = refine.curve_remove_knots(with_knot, u, 1 + times)
    assert count == 1 + times
    ref = c.elevate_degree(times)
    np.testing.assert_array_equal(out.knots, ref.knots)
    np.testing.assert_allclose(out.control_points, ref.control_points, rtol=0, atol=1e-10 * scale_of(c))


# ============================================================================ clamping, splits, segments, Bézier pieces


@given(curves())
def test_clamped_keeps_curve_and_clamps_ends(c):
    out = c.clamped()
    p = c.degree
    a, b = c.domain
    assert out.domain == c.domain
    np.testing.assert_array_equal(out.knots[: p + 1], np.full(p + 1, a))
    np.testing.assert_array_equal(out.knots[-p - 1 :], np.full(p + 1, b))
    assert_same_curve(out, c, interior_params(c), scale_of(c))
    np.testing.assert_allclose(out.control_points[0], c(a), rtol=0, atol=EXACT * scale_of(c))
    assert out.clamped() is out


def test_clamped_periodic_curve_is_closed():
    p, n = 3, 8
    rng = np.random.default_rng(3)
    P = rng.uniform(-1, 1, (n - p, 2))
    P = np.concatenate([P, P[:p]])  # periodic: the first p points repeated
    c = NurbsCurve(P, periodic_uniform_knots(n, p), p)
    out = c.clamped()
    np.testing.assert_allclose(out.control_points[0], out.control_points[-1], rtol=0, atol=1e-14)
    assert_same_curve(out, c, np.linspace(0, 1, 50, endpoint=False), scale_of(c))


@given(curves(), st.floats(0.01, 0.99), st.booleans())
def test_split_pieces_reproduce_the_curve(c, fraction, use_knot):
    a, b = c.domain
    u, _ = insertable(c, fraction, use_knot)
    left, right = c.split(u)
    p = c.degree
    assert left.domain == (a, u) and right.domain == (u, b)
    for piece in (left, right):
        lo, hi = piece.domain
        np.testing.assert_array_equal(piece.knots[: p + 1], np.full(p + 1, lo))
        np.testing.assert_array_equal(piece.knots[-p - 1 :], np.full(p + 1, hi))
        t = np.linspace(lo, hi, 41)[:-1]
        np.testing.assert_allclose(piece(t), c(t), rtol=0, atol=EXACT * scale_of(c))
    np.testing.assert_allclose(left.control_points[-1], right.control_points[0], rtol=0, atol=0)
    np.testing.assert_allclose(right.control_points[0], c(u), rtol=0, atol=EXACT * scale_of(c))


@given(curves(), st.floats(0, 1), st.floats(0, 1))
def test_segment_is_the_curve_between_its_bounds(c, f0, f1):
    a, b = c.domain
    start, end = sorted((a + (b - a) * f0, a + (b - a) * f1))
    assume(end - start >= 1e-6 * (b - a))
    seg = c.segment(start, end)
    # Bounds within round-off of the domain ends are those ends.
    np.testing.assert_allclose(seg.domain, (start, end), rtol=0, atol=1e-12 * (b - a))
    t = np.linspace(start, end, 40, endpoint=False)
    np.testing.assert_allclose(seg(t), c(t), rtol=0, atol=EXACT * scale_of(c))
    np.testing.assert_allclose(seg.control_points[0], c(seg.domain[0]), rtol=0, atol=EXACT * scale_of(c))
    np.testing.assert_allclose(seg.control_points[-1], c(seg.domain[1]), rtol=0, atol=EXACT * scale_of(c))


@given(curves())
def test_bezier_segments_cover_every_span(c):
    p = c.degree
    a, b = c.domain
    breaks = np.unique(c.knots[(c.knots >= a) & (c.knots <= b)])
    pieces = c.bezier_segments()
    assert len(pieces) == breaks.size - 1
    for i, piece in enumerate(pieces):
        np.testing.assert_array_equal(piece.knots, np.repeat(breaks[i : i + 2], p + 1))
        assert piece.n_control_points == p + 1
        t = np.linspace(breaks[i], breaks[i + 1], 17)[:-1]
        np.testing.assert_allclose(piece(t), c(t), rtol=0, atol=EXACT * scale_of(c))
    for left, right in zip(pieces, pieces[1:]):
        np.testing.assert_allclose(left.control_points[-1], right.control_points[0], rtol=0, atol=EXACT * scale_of(c))


# ============================================================================ surfaces


def surface_params(s: NurbsSurface, m: int = 30, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    return params_in(s.domain_u, rng, m), params_in(s.domain_v, rng, m)


def assert_same_surface(a: NurbsSurface, b: NurbsSurface, scale: float) -> None:
    u, v = surface_params(b)
    np.testing.assert_allclose(a(u, v), b(u, v), rtol=0, atol=EXACT * scale)


@given(surfaces(), st.sampled_from("uv"), st.lists(st.floats(0.02, 0.98), min_size=1, max_size=4))
def test_surface_refine_equals_curve_refine_of_every_row(s, direction, fractions):
    knots, p = (s.knots_u, s.degree_u) if direction == "u" else (s.knots_v, s.degree_v)
    X = new_knots(knots, p, s.domain_u if direction == "u" else s.domain_v, fractions)
    assume(X)
    out = s.refine_knots(direction, X)
    assert_same_surface(out, s, scale_of(s))
    # The net refined as a batch equals each row refined as a curve.
    net = s.homogeneous if direction == "u" else s.homogeneous.transpose(1, 0, 2)
    got = out.homogeneous if direction == "u" else out.homogeneous.transpose(1, 0, 2)
    for j in range(net.shape[1]):
        row = NurbsCurve.from_homogeneous(net[:, j], knots, p).refine_knots(X)
        np.testing.assert_allclose(got[:, j], row.homogeneous, rtol=0, atol=EXACT * scale_of(s) * 3)
    single = s.insert_knot(direction, X[0])
    assert_same_surface(single, s, scale_of(s))


@given(surfaces(), st.sampled_from("uv"), st.floats(0.05, 0.95))
def test_surface_remove_knot_undoes_insertion(s, direction, fraction):
    knots, p = (s.knots_u, s.degree_u) if direction == "u" else (s.knots_v, s.degree_v)
    lo, hi = s.domain_u if direction == "u" else s.domain_v
    x = lo + (hi - lo) * fraction
    room = p - multiplicity(knots, x)
    assume(room > 0)
    out, count = refine.surface_remove_knots(s.insert_knot(direction, x, room), direction, x, room)
    assert count == room
    np.testing.assert_array_equal(out.knots_u, s.knots_u)
    np.testing.assert_array_equal(out.knots_v, s.knots_v)
    np.testing.assert_allclose(out.control_points, s.control_points, rtol=0, atol=1e-11 * scale_of(s))


@settings(max_examples=30)
@given(surfaces(), st.sampled_from("uv"), st.floats(0, 1), st.floats(-3, 0))
def test_surface_remove_knot_never_moves_beyond_tolerance(s, direction, fraction, log_tol):
    knots, p = (s.knots_u, s.degree_u) if direction == "u" else (s.knots_v, s.degree_v)
    lo, hi = s.domain_u if direction == "u" else s.domain_v
    interior = np.unique(knots[(knots > lo) & (knots < hi)])
    assume(interior.size > 0)
    x = float(interior[int(fraction * interior.size) % interior.size])
    tol = Tolerance(linear=scale_of(s) * 10.0**log_tol)
    out, count = refine.surface_remove_knots(s, direction, x, multiplicity(knots, x), tol)
    us = dense_params(s.knots_u, s.domain_u, 16)[:-1]
    vs = dense_params(s.knots_v, s.domain_v, 16)[:-1]
    assert np.max(np.linalg.norm(out.evaluate_grid(us, vs) - s.evaluate_grid(us, vs), axis=-1)) <= tol.linear
    assert s.remove_knot(direction, x, 0) is s


@settings(max_examples=30)
@given(surfaces(), st.integers(0, 2), st.integers(0, 2))
def test_surface_elevate_degree_keeps_surface(s, tu, tv):
    out = s.elevate_degree(tu, tv)
    assert (out.degree_u, out.degree_v) == (s.degree_u + tu, s.degree_v + tv)
    assert out.domain == s.domain
    assert_same_surface(out, s, scale_of(s))
    if tu == 0:
        np.testing.assert_array_equal(out.knots_u, s.knots_u)
    else:
        vals, mults = np.unique(refine._clamp(s.knots_u, s.degree_u, s.homogeneous)[0], return_counts=True)
        np.testing.assert_array_equal(out.knots_u, np.repeat(vals, mults + tu))


@given(surfaces(), st.sampled_from("uv"), st.floats(0.02, 0.98))
def test_surface_split_pieces_reproduce_the_surface(s, direction, fraction):
    lo, hi = s.domain_u if direction == "u" else s.domain_v
    x = lo + (hi - lo) * fraction
    first, second = s.split(direction, x)
    u, v = surface_params(s, 60)
    along = u if direction == "u" else v
    for piece, mask in ((first, along <= x), (second, along >= x)):
        np.testing.assert_allclose(piece(u[mask], v[mask]), s(u[mask], v[mask]), rtol=0, atol=EXACT * scale_of(s))
    if direction == "u":
        assert first.domain_u == (lo, x) and second.domain_u == (x, hi) and first.domain_v == s.domain_v
        np.testing.assert_allclose(first.control_points[-1], second.control_points[0], rtol=0, atol=0)
    else:
        assert first.domain_v == (lo, x) and second.domain_v == (x, hi) and first.domain_u == s.domain_u
        np.testing.assert_allclose(first.control_points[:, -1], second.control_points[:, 0], rtol=0, atol=0)


@settings(max_examples=30)
@given(surfaces())
def test_surface_bezier_patches_cover_every_span(s):
    pu, pv = s.degree_u, s.degree_v
    bu = np.unique(s.knots_u[(s.knots_u >= s.domain_u[0]) & (s.knots_u <= s.domain_u[1])])
    bv = np.unique(s.knots_v[(s.knots_v >= s.domain_v[0]) & (s.knots_v <= s.domain_v[1])])
    patches = s.bezier_patches()
    assert len(patches) == bu.size - 1 and all(len(row) == bv.size - 1 for row in patches)
    rng = np.random.default_rng(0)
    for i, row in enumerate(patches):
        for j, patch in enumerate(row):
            np.testing.assert_array_equal(patch.knots_u, np.repeat(bu[i : i + 2], pu + 1))
            np.testing.assert_array_equal(patch.knots_v, np.repeat(bv[j : j + 2], pv + 1))
            u = params_in(patch.domain_u, rng, 6)
            v = params_in(patch.domain_v, rng, 6)
            np.testing.assert_allclose(patch(u, v), s(u, v), rtol=0, atol=EXACT * scale_of(s))


@given(surfaces(), st.sampled_from("uv"), st.floats(0, 1))
def test_iso_curve_agrees_with_surface(s, direction, fraction):
    lo, hi = s.domain_u if direction == "u" else s.domain_v
    x = lo + (hi - lo) * fraction
    c = s.iso_curve(direction, x)
    rng = np.random.default_rng(1)
    if direction == "u":
        t = params_in(s.domain_v, rng, 40)
        expected = s(np.full_like(t, x), t)
        assert c.degree == s.degree_v
        np.testing.assert_array_equal(c.knots, s.knots_v)
    else:
        t = params_in(s.domain_u, rng, 40)
        expected = s(t, np.full_like(t, x))
        assert c.degree == s.degree_u
        np.testing.assert_array_equal(c.knots, s.knots_u)
    np.testing.assert_allclose(c(t), expected, rtol=0, atol=EXACT * scale_of(s))


def test_iso_curve_of_cylinder_is_a_circle():
    # A quarter cylinder of radius 2 (rational in u, linear in v): u-iso-curves are
    # lines, v-iso-curves quarter circles that keep their weights.
    s2 = np.sqrt(0.5)
    ring = np.array([[2, 0], [2, 2], [0, 2]])
    P = np.stack([np.column_stack([ring, np.full(3, z)]) for z in (0.0, 3.0)], axis=1)  # (3, 2, 3)
    w = np.array([[1, 1], [s2, s2], [1, 1]])
    s = NurbsSurface(P, [0, 0, 0, 1, 1, 1], [0, 0, 1, 1], 2, 1, w)
    circle = s.iso_curve("v", 0.4)
    assert circle.is_rational
    np.testing.assert_allclose(circle.weights, w[:, 0], rtol=0, atol=1e-15)
    pts = circle(np.linspace(0, 1, 33))
    np.testing.assert_allclose(np.linalg.norm(pts[:, :2], axis=1), 2.0, rtol=0, atol=1e-14)
    np.testing.assert_allclose(pts[:, 2], 1.2, rtol=0, atol=1e-14)
    line = s.iso_curve("u", 0.5)
    np.testing.assert_allclose(line([0.0, 1.0]), s([0.5, 0.5], [0.0, 1.0]), rtol=0, atol=1e-14)


# ============================================================================ errors


@pytest.fixture
def cubic() -> NurbsCurve:
    return NurbsCurve(
        [[0, 0], [1, 2], [2, -1], [3, 3], [4, 0]], [0, 0, 0, 0, 0.5, 1, 1, 1, 1], 3
    )


@pytest.fixture
def patch() -> NurbsSurface:
    P = np.random.default_rng(0).uniform(-1, 1, (4, 3, 3))
    return NurbsSurface(P, [0, 0, 0, 0.5, 1, 1, 1], [0, 0, 1, 2, 2], 2, 1)


def test_insert_knot_errors(cubic):
    with pytest.raises(InvalidInputError, match=r"outside the domain"):
        cubic.insert_knot(1.5)
    with pytest.raises(InvalidInputError, match=r"knot 0\.5 would have multiplicity 4 .* at most the degree 3"):
        cubic.insert_knot(0.5, 3)
    with pytest.raises(InvalidInputError, match=r"knot 0\.0 would have multiplicity 5"):
        cubic.insert_knot(0.0)
    with pytest.raises(InvalidInputError, match=r"times must be an integer >= 0, got -1"):
        cubic.insert_knot(0.3, -1)
    with pytest.raises(InvalidInputError, match=r"times must be an integer >= 0, got 1\.5"):
        cubic.insert_knot(0.3, 1.5)
    with pytest.raises(InvalidInputError, match=r"times must be an integer >= 0, got True"):
        cubic.insert_knot(0.3, True)
    with pytest.raises(InvalidInputError, match=r"must be finite"):
        cubic.insert_knot(float("nan"))
    with pytest.raises(InvalidInputError, match=r"single real number, got shape \(2,\)"):
        cubic.insert_knot([0.2, 0.3])
    with pytest.raises(InvalidInputError, match=r"must be a real number, got 'a'"):
        cubic.insert_knot("a")


def test_refine_knots_errors(cubic):
    with pytest.raises(InvalidInputError, match=r"refine_knots: parameter -0\.5 is outside the domain"):
        cubic.refine_knots([0.2, -0.5])
    with pytest.raises(InvalidInputError, match=r"knot 0\.2 would have multiplicity 4 \(existing 0 \+ inserted 4\)"):
        cubic.refine_knots([0.2, 0.7, 0.2, 0.2, 0.2])
    with pytest.raises(InvalidInputError, match=r"1-D array of knots, got shape \(2, 2\)"):
        cubic.refine_knots([[0.2, 0.3], [0.4, 0.6]])
    with pytest.raises(InvalidInputError, match=r"expected real numbers"):
        cubic.refine_knots(["x"])


def test_remove_knot_errors(cubic):
    with pytest.raises(InvalidInputError, match=r"0\.3 is not an interior knot; interior knots are \[0\.5\]"):
        cubic.remove_knot(0.3)
    with pytest.raises(InvalidInputError, match=r"0\.0 is not an interior knot"):
        cubic.remove_knot(0.0)
    with pytest.raises(InvalidInputError, match=r"times must be at most the multiplicity 1 of knot 0\.5, got 2"):
        cubic.remove_knot(0.5, 2)
    with pytest.raises(InvalidInputError, match=r"times must be an integer >= 0, got -2"):
        cubic.remove_knot(0.5, -2)
    with pytest.raises(InvalidInputError, match=r"outside the domain"):
        cubic.remove_knot(2.0)
    assert refine.curve_remove_knots(cubic, 0.5, 0) == (cubic, 0)


def test_elevate_split_segment_errors(cubic):
    with pytest.raises(InvalidInputError, match=r"elevate_degree: times must be an integer >= 0, got -1"):
        cubic.elevate_degree(-1)
    with pytest.raises(InvalidInputError, match=r"got 2\.0"):
        cubic.elevate_degree(2.0)
    with pytest.raises(InvalidInputError, match=r"split: u: 0\.0 must lie strictly inside the domain \[0\.0, 1\.0\]"):
        cubic.split(0.0)
    with pytest.raises(InvalidInputError, match=r"strictly inside"):
        cubic.split(1.0 - 1e-14)
    with pytest.raises(InvalidInputError, match=r"outside the domain"):
        cubic.split(1.5)
    with pytest.raises(InvalidInputError, match=r"segment: need start < end .* got \[0\.6, 0\.4\]"):
        cubic.segment(0.6, 0.4)
    with pytest.raises(InvalidInputError, match=r"segment: end: parameter 2\.0 is outside the domain"):
        cubic.segment(0.2, 2.0)


def test_surface_errors(patch):
    for call in (
        lambda: patch.insert_knot("w", 0.5),
        lambda: patch.refine_knots("x", [0.5]),
        lambda: patch.remove_knot("uv", 0.5),
        lambda: patch.split("U", 0.5),
        lambda: patch.iso_curve(0, 0.5),
    ):
        with pytest.raises(InvalidInputError, match=r"direction must be 'u' or 'v'"):
            call()
    with pytest.raises(InvalidInputError, match=r"iso_curve: v: parameter 3\.0 is outside the domain \[0\.0, 2\.0\]"):
        patch.iso_curve("v", 3.0)
    with pytest.raises(InvalidInputError, match=r"knot 1\.0 would have multiplicity 2 .* at most the degree 1"):
        patch.insert_knot("v", 1.0)
    with pytest.raises(InvalidInputError, match=r"split: v: 2\.0 must lie strictly inside"):
        patch.split("v", 2.0)
    with pytest.raises(InvalidInputError, match=r"elevate_degree: times_v must be an integer >= 0, got -1"):
        patch.elevate_degree(1, -1)
    with pytest.raises(InvalidInputError, match=r"remove_knot: u: 0\.25 is not an interior knot"):
        patch.remove_knot("u", 0.25)
    assert patch.elevate_degree(0, 0) is patch
    assert patch.insert_knot("u", 0.3, 0) is patch


# ============================================================================ OCCT conversion (tests only)


def to_occt(c: NurbsCurve):
    from OCP.collections import Array1_double, Array1_gp_Pnt, Array1_int
    from OCP.Geom import Geom_BSplineCurve
    from OCP.gp import gp_Pnt

    n = c.n_control_points
    poles, weights = Array1_gp_Pnt(1, n), Array1_double(1, n)
    for i, (x, y, z) in enumerate(c.control_points):
        poles.SetValue(i + 1, gp_Pnt(float(x), float(y), float(z)))
        weights.SetValue(i + 1, float(c.weights[i]))
    vals, mults = np.unique(c.knots, return_counts=True)
    K, M = Array1_double(1, vals.size), Array1_int(1, vals.size)
    for i, (k, m) in enumerate(zip(vals, mults)):
        K.SetValue(i + 1, float(k))
        M.SetValue(i + 1, int(m))
    return Geom_BSplineCurve(poles, weights, K, M, c.degree)


def from_occt(g) -> NurbsCurve:
    n = g.NbPoles()
    P = np.array([[g.Pole(i).X(), g.Pole(i).Y(), g.Pole(i).Z()] for i in range(1, n + 1)])
    w = np.array([g.Weight(i) for i in range(1, n + 1)])
    seq = g.KnotSequence()
    U = np.array([seq.Value(i) for i in range(seq.Lower(), seq.Upper() + 1)])
    return NurbsCurve(P, U, g.Degree(), w)


@given(curves(rational=False))
def test_polynomial_curves_stay_polynomial(c):
    """Refinement, elevation and splitting of a polynomial curve keep unit weights exactly."""
    a, b = c.domain
    m = 0.5 * (a + b)
    outs = [c.elevate_degree(1), c.insert_knot(m), *c.split(m), *c.bezier_segments(), c.clamped()]
    for out in outs:
        assert not out.is_rational
        np.testing.assert_array_equal(out.weights, c.weights[0])
