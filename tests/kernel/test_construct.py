"""Constructions from curves: compatibility, extrusion, ruled surfaces, lofts and Coons patches.

Truth comes from the input curves themselves (boundaries and sections reproduced to
round-off), from closed forms (cylinders and cones of exact rational circles, planar
bilinear quads) and from reproduction properties (a Coons patch of a surface's own
boundary data returns that surface when it lies in the blending space).
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from coons.errors import InvalidInputError
from coons.kernel import refine
from coons.kernel.construct import bicubic_coons, bilinear_coons, extrude, loft, make_compatible, ruled_surface
from coons.kernel.curve import NurbsCurve
from coons.kernel.fitting import parametrize_grid
from coons.kernel.surface import NurbsSurface
from coons.tolerance import Tolerance

from .strategies import curves, random_knots

#: Reproduction of input curves by constructed surfaces, relative to the size of the control points.
REPRO_RTOL = 1e-12
T = np.linspace(0.0, 1.0, 41)


def size(*cs) -> float:
    return max(float(np.abs(c.control_points).max()) for c in cs) + 1.0


def on_unit(c: NurbsCurve, t) -> np.ndarray:
    """``c`` evaluated at the parameters of ``t`` in [0, 1] mapped affinely onto its domain."""
    a, b = c.domain
    return c.evaluate(a + np.asarray(t) * (b - a))


def circle(center, radius: float, normal_z: bool = True) -> NurbsCurve:
    """An exact circle in the plane z = center[2]: 9 control points on a square, weights 1 and sqrt(1/2)."""
    sq = [[1, 0], [1, 1], [0, 1], [-1, 1], [-1, 0], [-1, -1], [0, -1], [1, -1], [1, 0]]
    P = np.array([[x * radius, y * radius, 0.0] for x, y in sq]) + np.asarray(center, dtype=float)
    w = np.array([1, np.sqrt(0.5)] * 4 + [1])
    return NurbsCurve(P, [0, 0, 0, 0.25, 0.25, 0.5, 0.5, 0.75, 0.75, 1, 1, 1], 2, w)


def random_curve(rng, p, n, d=3, rational=False, domain=(0.0, 1.0), weights=(0.5, 2.0)) -> NurbsCurve:
    U = random_knots(rng, n, p, clamped=True)
    U = domain[0] + (domain[1] - domain[0]) * U
    w = rng.uniform(*weights, n) if rational else None
    return NurbsCurve(rng.uniform(-5, 5, (n, d)), U, p, w)


def with_ends(c: NurbsCurve, start, end) -> NurbsCurve:
    """The clamped curve ``c`` with its end points moved to ``start`` and ``end``."""
    P = np.array(c.control_points)
    P[0], P[-1] = start, end
    return NurbsCurve(P, c.knots, c.degree, c.weights)


def line(a, b) -> NurbsCurve:
    return NurbsCurve([a, b], [0, 0, 1, 1], 1)


# ================================================================== make_compatible
@settings(max_examples=40)
@given(st.lists(curves(), min_size=1, max_size=4), st.integers(0, 2))
def test_make_compatible_keeps_every_curve(cs, extra):
    top = max(c.degree for c in cs)
    out = make_compatible(cs, degree=top + extra)
    assert len(out) == len(cs)
    for c, r in zip(cs, out):
        assert r.degree == top + extra and r.domain == (0.0, 1.0)
        np.testing.assert_array_equal(r.knots, out[0].knots)
        assert r.dimension == c.dimension
        np.testing.assert_allclose(r.evaluate(T), on_unit(c, T), rtol=0, atol=REPRO_RTOL * size(c))


def test_make_compatible_merges_knots_with_their_largest_multiplicity():
    a = NurbsCurve(np.zeros((6, 2)) + np.arange(6)[:, None], [0, 0, 0, 0.5, 0.5, 0.7, 1, 1, 1], 2)
    # Knots 1.0 and 2.0 + round-off on [0, 4] map to 0.25 and 0.5 (within tol.solver).
    b = NurbsCurve(np.ones((6, 2)) + np.arange(6)[:, None], [0, 0, 0, 0, 1.0, 2.0 + 4e-15, 4, 4, 4, 4], 3)
    ca, cb = make_compatible([a, b])
    np.testing.assert_array_equal(ca.knots, [0, 0, 0, 0, 0.25, 0.5, 0.5, 0.5, 0.7, 0.7, 1, 1, 1, 1])
    np.testing.assert_array_equal(cb.knots, ca.knots)
    np.testing.assert_allclose(ca.evaluate(T), a.evaluate(T), rtol=0, atol=1e-13)
    np.testing.assert_allclose(cb.evaluate(T), b.evaluate(4 * T), rtol=0, atol=1e-13)


def test_make_compatible_errors():
    c = line([0, 0], [1, 1])
    with pytest.raises(InvalidInputError, match=r"non-empty sequence of NurbsCurve, got \[\]"):
        make_compatible([])
    with pytest.raises(InvalidInputError, match=r"non-empty sequence of NurbsCurve, got NurbsCurve"):
        make_compatible(c)
    with pytest.raises(InvalidInputError, match=r"curves\[1\] must be a NurbsCurve, got ndarray"):
        make_compatible([c, np.zeros((2, 2))])
    with pytest.raises(InvalidInputError, match=r"degree must be an integer >= .* \(2\), got 1"):
        make_compatible([c, NurbsCurve([[0, 0], [1, 2], [2, 0]], [0, 0, 0, 1, 1, 1], 2)], degree=1)
    with pytest.raises(InvalidInputError, match=r"got 2.5"):
        make_compatible([c], degree=2.5)


# ================================================================== extrude
@given(curves(dims=(3,)), st.integers(0, 2**32 - 1))
def test_extrude_is_the_curve_translated_along_v(c, seed):
    rng = np.random.default_rng(seed)
    vec = rng.uniform(-3, 3, 3)
    s = extrude(c, vec)
    assert s.domain_u == c.domain and s.domain_v == (0.0, 1.0) and (s.degree_u, s.degree_v) == (c.degree, 1)
    u = c.domain[0] + (c.domain[1] - c.domain[0]) * T
    v = rng.uniform(0, 1, T.shape)
    np.testing.assert_allclose(s.evaluate(u, v), c.evaluate(u) + v[:, None] * vec, rtol=0, atol=REPRO_RTOL * size(c))
    np.testing.assert_allclose(s.evaluate(u, 0.0), c.evaluate(u), rtol=0, atol=REPRO_RTOL * size(c))


def test_extrude_of_a_circle_is_a_cylinder():
    s = extrude(circle([1, 2, 3], 2.0), [0, 0, 5])
    u, v = np.meshgrid(T, T, indexing="ij")
    X = s.evaluate(u, v)
    np.testing.assert_allclose(np.hypot(X[..., 0] - 1, X[..., 1] - 2), 2.0, rtol=0, atol=1e-14)
    np.testing.assert_allclose(X[..., 2], 3 + 5 * v, rtol=0, atol=1e-14)


def test_extrude_errors():
    c = line([0, 0, 0], [1, 0, 0])
    with pytest.raises(InvalidInputError, match=r"vector must have shape \(3,\) like the curve, got \(2,\)"):
        extrude(c, [0, 1])
    with pytest.raises(InvalidInputError, match=r"vector must be finite"):
        extrude(c, [0, np.nan, 1])
    with pytest.raises(InvalidInputError, match=r"vector length 5e-08 is not above tol.linear = 1e-07"):
        extrude(c, [0, 5e-8, 0])
    with pytest.raises(InvalidInputError, match=r"curve must be a NurbsCurve, got list"):
        extrude([[0, 0, 0], [1, 0, 0]], [0, 0, 1])


# ================================================================== ruled surfaces
@settings(max_examples=40)
@given(curves(dims=(3,)), curves(dims=(3,)))
def test_ruled_surface_has_the_curves_as_boundaries_and_straight_rulings(a, b):
    s = ruled_surface(a, b)
    assert s.domain == ((0.0, 1.0), (0.0, 1.0)) and s.degree_v == 1
    scale = size(a, b)
    np.testing.assert_allclose(s.evaluate(T, 0.0), on_unit(a, T), rtol=0, atol=REPRO_RTOL * scale)
    np.testing.assert_allclose(s.evaluate(T, 1.0), on_unit(b, T), rtol=0, atol=REPRO_RTOL * scale)
    # Every point lies on the segment from A(u) to B(u).
    v = np.random.default_rng(0).uniform(0, 1, T.shape)
    A, B, X = on_unit(a, T), on_unit(b, T), s.evaluate(T, v)
    d = B - A
    s_along = np.einsum("ij,ij->i", X - A, d) / np.maximum(np.einsum("ij,ij->i", d, d), 1e-300)
    np.testing.assert_allclose(X, A + s_along[:, None] * d, rtol=0, atol=1e-10 * scale)
    assert np.all((s_along > -1e-9) & (s_along < 1 + 1e-9))
    if not (a.is_rational or b.is_rational):
        np.testing.assert_allclose(X, (1 - v[:, None]) * A + v[:, None] * B, rtol=0, atol=1e-11 * scale)


def test_ruled_surface_between_coaxial_circles_is_a_cylinder():
    R, h = 1.5, 4.0
    bottom = circle([0.5, -1.0, 0.0], R)
    # Same parametrisation, different representation: refined knots and a higher degree.
    top = refine.curve_elevate_degree(refine.curve_refine_knots(circle([0.5, -1.0, h], R), [0.1, 0.6, 0.6]), 1)
    s = ruled_surface(bottom, top)
    u, v = np.meshgrid(np.linspace(0, 1, 97), np.linspace(0, 1, 13), indexing="ij")
    X = s.evaluate(u, v)
    np.testing.assert_allclose(np.hypot(X[..., 0] - 0.5, X[..., 1] + 1.0), R, rtol=0, atol=1e-14)
    # Rulings are parallel to the axis.
    np.testing.assert_allclose(X[..., :2], X[:, :1, :2].repeat(13, axis=1), rtol=0, atol=1e-14)
    assert s.degree_u == 3


def test_ruled_surface_errors():
    a = line([0, 0, 0], [1, 0, 0])
    with pytest.raises(InvalidInputError, match=r"same dimension, curve_a has 3 and curve_b has 2"):
        ruled_surface(a, line([0, 0], [1, 0]))
    with pytest.raises(InvalidInputError, match=r"curve_b must be a NurbsCurve, got NoneType"):
        ruled_surface(a, None)


# ================================================================== loft
@st.composite
def sections(draw, rational: bool):
    rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
    K = draw(st.integers(2, 5))
    out = []
    for k in range(K):
        p = int(rng.integers(1, 4))
        # Weights within [0.8, 1.25]: their interpolation across sections stays positive.
        domain = (rng.uniform(-1, 0), rng.uniform(1, 2))
        c = random_curve(rng, p, int(rng.integers(p + 1, p + 5)), 3, rational, domain, weights=(0.8, 1.25))
        out.append(c.translated([0, 0, 4.0 * k]))
    return out


@settings(max_examples=40)
@given(sections(rational=False), st.data())
def test_loft_passes_through_every_section(cs, data):
    K = len(cs)
    q = data.draw(st.integers(1, K - 1))
    s = loft(cs, q)
    assert (s.degree_v, s.domain_u) == (q, (0.0, 1.0))
    v = parametrize_grid(np.stack([c.control_points for c in make_compatible(cs)]))[0]
    for k, c in enumerate(cs):
        np.testing.assert_allclose(s.evaluate(T, v[k]), on_unit(c, T), rtol=0, atol=REPRO_RTOL * size(*cs))


@settings(max_examples=30)
@given(sections(rational=True))
def test_loft_of_rational_sections_with_given_params(cs):
    K = len(cs)
    v = np.cumsum(np.r_[0.5, np.linspace(1.0, 2.0, K - 1)])
    s = loft(cs, min(2, K - 1), params=v)
    assert s.is_rational and s.domain_v == (v[0], v[-1])
    for k, c in enumerate(cs):
        np.testing.assert_allclose(s.evaluate(T, v[k]), on_unit(c, T), rtol=0, atol=REPRO_RTOL * size(*cs))


def test_loft_of_two_sections_with_degree_one_is_the_ruled_surface():
    rng = np.random.default_rng(20)
    a, b = random_curve(rng, 3, 6), random_curve(rng, 2, 5, domain=(2.0, 5.0))
    s, r = loft([a, b], 1), ruled_surface(a, b)
    u, v = np.meshgrid(T, T, indexing="ij")
    np.testing.assert_allclose(s.evaluate(u, v), r.evaluate(u, v), rtol=0, atol=1e-13 * size(a, b))


def test_loft_of_circles_is_a_cylinder_or_a_cone():
    heights = np.array([0.0, 1.0, 2.5, 3.0, 5.0])
    cyl = loft([circle([0, 0, z], 2.0) for z in heights], 3)
    cone = loft([circle([0, 0, z], 1.0 + 0.5 * z) for z in heights], 3)
    u, v = np.meshgrid(np.linspace(0, 1, 97), np.linspace(0, 1, 31), indexing="ij")
    X = cyl.evaluate(u, v)
    np.testing.assert_allclose(np.hypot(X[..., 0], X[..., 1]), 2.0, rtol=0, atol=1e-13)
    Y = cone.evaluate(u, v)
    np.testing.assert_allclose(np.hypot(Y[..., 0], Y[..., 1]), 1.0 + 0.5 * Y[..., 2], rtol=0, atol=1e-13)
    # Chord-length parameters of equally shaped sections are the normalised heights.
    np.testing.assert_allclose(cyl.evaluate(0.3, heights / 5.0)[:, 2], heights, rtol=0, atol=1e-13)


def test_loft_errors():
    a, b, c = (line([0, 0, z], [1, 0, z]) for z in (0.0, 1.0, 2.0))
    with pytest.raises(InvalidInputError, match=r"at least 2 section curves"):
        loft([a])
    with pytest.raises(InvalidInputError, match=r"curves\[1\] must be a NurbsCurve, got str"):
        loft([a, "b"])
    with pytest.raises(InvalidInputError, match=r"same dimension, curves\[0\] has 3 and curves\[2\] has 2"):
        loft([a, b, line([0, 0], [1, 0])], 2)
    with pytest.raises(InvalidInputError, match=r"degree_v must be an integer in \[1, 2\] for 3 sections, got 3"):
        loft([a, b, c])
    with pytest.raises(InvalidInputError, match=r"params must be 3 finite, strictly increasing values"):
        loft([a, b, c], 2, params=[0, 1, 1])
    with pytest.raises(InvalidInputError, match=r"cannot parametrise the sections .* rows 1 and 2 coincide"):
        loft([a, b, b], 2)
    with pytest.raises(InvalidInputError, match=r"method must be one of"):
        loft([a, b, c], 2, method="bad")
    # Middle weights swinging between 0.01 and 100 across sections overshoot below zero.
    arcs = [NurbsCurve([[0, 0, z], [1, 1, z], [2, 0, z]], [0, 0, 0, 1, 1, 1], 2, [1, w, 1])
            for z, w in zip(range(5), (0.01, 100.0, 0.01, 100.0, 0.01))]
    with pytest.raises(InvalidInputError, match=r"interpolating the section weights gives weight .* <= 0"):
        loft(arcs, 3)


# ================================================================== Coons patches
@st.composite
def boundaries(draw, d: int = 3):
    """Four random polynomial curves meeting at four random corners, on random domains."""
    rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
    P = rng.uniform(-5, 5, (2, 2, d))  # P[a, b] = S(u=a, v=b)
    out = []
    for start, end in ((P[0, 0], P[1, 0]), (P[0, 1], P[1, 1]), (P[0, 0], P[0, 1]), (P[1, 0], P[1, 1])):
        p = int(rng.integers(1, 5))
        c = random_curve(rng, p, int(rng.integers(p + 1, p + 5)), d, domain=(rng.uniform(-2, 0), rng.uniform(1, 3)))
        out.append(with_ends(c, start, end))
    return out


def assert_boundaries(s: NurbsSurface, c0, c1, d0, d1, atol: float) -> None:
    np.testing.assert_allclose(s.evaluate(T, 0.0), on_unit(c0, T), rtol=0, atol=atol)
    np.testing.assert_allclose(s.evaluate(T, 1.0), on_unit(c1, T), rtol=0, atol=atol)
    np.testing.assert_allclose(s.evaluate(0.0, T), on_unit(d0, T), rtol=0, atol=atol)
    np.testing.assert_allclose(s.evaluate(1.0, T), on_unit(d1, T), rtol=0, atol=atol)


@settings(max_examples=40)
@given(boundaries())
def test_bilinear_coons_boundaries_are_the_curves(bs):
    s = bilinear_coons(*bs)
    assert s.domain == ((0.0, 1.0), (0.0, 1.0)) and not s.is_rational
    assert s.degree_u == max(bs[0].degree, bs[1].degree) and s.degree_v == max(bs[2].degree, bs[3].degree)
    assert_boundaries(s, *bs, atol=REPRO_RTOL * size(*bs))


def test_bilinear_coons_of_a_planar_quad_is_the_planar_bilinear_patch():
    rng = np.random.default_rng(21)
    frame, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    corners2 = np.array([[[0.0, 0.0], [0.3, 2.0]], [[3.0, 0.5], [2.5, 2.8]]])  # [a, b], a convex quad
    P = corners2 @ frame[:2] + [1.0, -2.0, 0.5]
    s = bilinear_coons(line(P[0, 0], P[1, 0]), line(P[0, 1], P[1, 1]), line(P[0, 0], P[0, 1]), line(P[1, 0], P[1, 1]))
    u, v = np.meshgrid(T, T, indexing="ij")
    X = s.evaluate(u, v)
    U, V = u[..., None], v[..., None]
    bilinear = (1 - U) * (1 - V) * P[0, 0] + U * (1 - V) * P[1, 0] + (1 - U) * V * P[0, 1] + U * V * P[1, 1]
    np.testing.assert_allclose(X, bilinear, rtol=0, atol=1e-14)
    np.testing.assert_allclose((X - P[0, 0]) @ frame[2], 0.0, rtol=0, atol=1e-14)
    assert (s.degree_u, s.degree_v) == (1, 1)


def test_bilinear_coons_reproduces_the_ruled_surface_of_two_boundaries():
    rng = np.random.default_rng(22)
    a, b = random_curve(rng, 3, 7), random_curve(rng, 2, 5)
    s = bilinear_coons(a, b, line(a.evaluate(0.0), b.evaluate(0.0)), line(a.evaluate(1.0), b.evaluate(1.0)))
    u, v = np.meshgrid(T, T, indexing="ij")
    np.testing.assert_allclose(s.evaluate(u, v), ruled_surface(a, b).evaluate(u, v), rtol=0, atol=1e-13 * size(a, b))


def test_bilinear_coons_splits_small_corner_gaps():
    c0, c1, d0, d1 = line([0, 0, 0], [1, 0, 0]), line([0, 1, 0], [1, 1, 0]), line([0, 0, 0], [0, 1, 0]), line([1, 0, 0], [1, 1, 0])
    gap = 0.8e-7
    s = bilinear_coons(c0, c1, d0.translated([0, 0, gap]), d1)
    np.testing.assert_allclose(s.evaluate(0.0, 0.0), [0, 0, gap / 2], rtol=0, atol=1e-18)
    with pytest.raises(InvalidInputError, match=r"corner \(u=0, v=0\): c0 starts at \[0.0, 0.0, 0.0\] but d0 starts at .* gap"):
        bilinear_coons(c0, c1, d0.translated([0, 0, gap]), d1, tol=Tolerance(linear=1e-8))


def test_bilinear_coons_accepts_curves_polynomial_to_round_off():
    rng = np.random.default_rng(26)
    c0 = random_curve(rng, 2, 5)
    elevated = refine.curve_elevate_degree(c0, 2)  # unit weights off by an ulp at most
    assert np.max(np.abs(elevated.weights - 1.0)) < 1e-15
    c1 = random_curve(rng, 3, 4).translated([0, 0, 10])
    c1 = with_ends(c1, c0.evaluate(0.0) + [0, 0, 10], c0.evaluate(1.0) + [0, 0, 10])
    d0, d1 = line(c0.evaluate(0.0), c1.evaluate(0.0)), line(c0.evaluate(1.0), c1.evaluate(1.0))
    s = bilinear_coons(elevated, c1, d0, d1)
    assert_boundaries(s, c0, c1, d0, d1, atol=REPRO_RTOL * size(c0, c1))
    assert s.degree_u == 4


def test_bilinear_coons_errors():
    c0, c1, d0, d1 = line([0, 0, 0], [1, 0, 0]), line([0, 1, 0], [1, 1, 0]), line([0, 0, 0], [0, 1, 0]), line([1, 0, 0], [1, 1, 0])
    with pytest.raises(InvalidInputError, match=r"corner \(u=1, v=0\): c0 ends at \[1.0, 0.0, 0.0\] but d1 starts at \[1.0, 0.5, 0.0\], gap 0.5 > tol.linear = 1e-07"):
        bilinear_coons(c0, c1, d0, line([1, 0.5, 0], [1, 1, 0]))
    with pytest.raises(InvalidInputError, match=r"corner \(u=1, v=1\): c1 ends at .* but d1 ends at .* gap 0.25"):
        bilinear_coons(c0, c1, d0, line([1, 0, 0], [1, 1, 0.25]))
    with pytest.raises(InvalidInputError, match=r"corner \(u=0, v=1\): c1 starts"):
        bilinear_coons(c0, line([0, 1, 1], [1, 1, 0]), d0, d1)
    arc = NurbsCurve([[0, 0, 0], [0.5, -0.5, 0], [1, 0, 0]], [0, 0, 0, 1, 1, 1], 2, [1, 0.5, 1])
    with pytest.raises(InvalidInputError, match=r"c0: Coons patches need polynomial .* weights range from 0.5 to 1.0"):
        bilinear_coons(arc, c1, d0, d1)
    with pytest.raises(InvalidInputError, match=r"same dimension, c0 has 3 and d1 has 2"):
        bilinear_coons(c0, c1, d0, line([1, 0], [1, 1]))
    with pytest.raises(InvalidInputError, match=r"d0 must be a NurbsCurve, got tuple"):
        bilinear_coons(c0, c1, (0, 1), d1)


def surface_boundary_data(S: NurbsSurface) -> dict:
    """Boundaries and cross-boundary derivative curves of a clamped polynomial surface on [0, 1]^2."""
    P, U, V, pu, pv = S.control_points, S.knots_u, S.knots_v, S.degree_u, S.degree_v
    su0, su1 = pu / (U[pu + 1] - U[1]), pu / (U[-2] - U[-pu - 2])
    sv0, sv1 = pv / (V[pv + 1] - V[1]), pv / (V[-2] - V[-pv - 2])
    return {
        "c0": NurbsCurve(P[:, 0], U, pu), "c1": NurbsCurve(P[:, -1], U, pu),
        "d0": NurbsCurve(P[0], V, pv), "d1": NurbsCurve(P[-1], V, pv),
        "c0_cross": NurbsCurve(sv0 * (P[:, 1] - P[:, 0]), U, pu),
        "c1_cross": NurbsCurve(sv1 * (P[:, -1] - P[:, -2]), U, pu),
        "d0_cross": NurbsCurve(su0 * (P[1] - P[0]), V, pv),
        "d1_cross": NurbsCurve(su1 * (P[-1] - P[-2]), V, pv),
    }


@settings(max_examples=40)
@given(st.integers(0, 2**32 - 1), st.integers(1, 4), st.integers(1, 4), st.sets(st.sampled_from(["c0_cross", "c1_cross", "d0_cross", "d1_cross"])))
def test_bicubic_coons_interpolates_boundaries_and_given_cross_derivatives(seed, pu, pv, given_crosses):
    rng = np.random.default_rng(seed)
    nu, nv = int(rng.integers(pu + 1, pu + 4)), int(rng.integers(pv + 1, pv + 4))
    S = NurbsSurface(rng.uniform(-5, 5, (nu, nv, 3)), random_knots(rng, nu, pu, True), random_knots(rng, nv, pv, True), pu, pv)
    data = surface_boundary_data(S)
    crosses = {k: data[k] for k in given_crosses}
    s = bicubic_coons(data["c0"], data["c1"], data["d0"], data["d1"], **crosses)
    scale = size(S)
    assert_boundaries(s, data["c0"], data["c1"], data["d0"], data["d1"], atol=REPRO_RTOL * scale)
    assert (s.degree_u, s.degree_v) == (max(3, pu), max(3, pv))
    D = {k: s.derivatives(*uv, 1) for k, uv in (("c0", (T, 0.0)), ("c1", (T, 1.0)), ("d0", (0.0, T)), ("d1", (1.0, T)))}
    for k in given_crosses:
        side = k[:2]
        got = D[side][:, 0, 1] if side[0] == "c" else D[side][:, 1, 0]
        np.testing.assert_allclose(got, data[k].evaluate(T), rtol=0, atol=1e-10 * scale * max(pu, pv) * 10)


def test_bicubic_coons_reproduces_a_bicubic_surface():
    rng = np.random.default_rng(23)
    B = [0, 0, 0, 0, 1, 1, 1, 1]
    S = NurbsSurface(rng.normal(size=(4, 4, 3)), B, B, 3, 3)
    data = surface_boundary_data(S)
    s = bicubic_coons(**data)
    u, v = np.meshgrid(T, T, indexing="ij")
    np.testing.assert_allclose(s.evaluate(u, v), S.evaluate(u, v), rtol=0, atol=1e-13)


def test_bicubic_coons_without_cross_curves_has_zero_twist():
    rng = np.random.default_rng(24)
    c0, c1, d0, d1 = (random_curve(rng, 3, 6) for _ in range(4))
    c1 = with_ends(c1, d0.evaluate(1.0), d1.evaluate(1.0))
    c0 = with_ends(c0, d0.evaluate(0.0), d1.evaluate(0.0))
    s = bicubic_coons(c0, c1, d0, d1)
    assert_boundaries(s, c0, c1, d0, d1, atol=REPRO_RTOL * size(c0, c1, d0, d1))
    corners = s.derivatives(np.array([0.0, 1.0, 0.0, 1.0]), np.array([0.0, 0.0, 1.0, 1.0]), 1)
    np.testing.assert_allclose(corners[:, 1, 1], 0.0, rtol=0, atol=1e-11 * size(c0, c1, d0, d1))
    # The cross-boundary derivative along c0 is the Hermite blend of the corner tangents d0'(0), d1'(0).
    H0, H1 = 1 - 3 * T**2 + 2 * T**3, 3 * T**2 - 2 * T**3
    expected = H0[:, None] * d0.derivatives(0.0, 1)[1] + H1[:, None] * d1.derivatives(0.0, 1)[1]
    np.testing.assert_allclose(s.derivatives(T, 0.0, 1)[:, 0, 1], expected, rtol=0, atol=1e-11 * size(c0, c1, d0, d1))


def test_bicubic_coons_of_a_parallelogram_is_the_plane_patch():
    P00, a, b = np.array([1.0, 2.0, 0.0]), np.array([3.0, 1.0, 1.0]), np.array([-0.5, 2.0, 0.5])
    s = bicubic_coons(line(P00, P00 + a), line(P00 + b, P00 + a + b), line(P00, P00 + b), line(P00 + a, P00 + a + b))
    u, v = np.meshgrid(T, T, indexing="ij")
    np.testing.assert_allclose(s.evaluate(u, v), P00 + u[..., None] * a + v[..., None] * b, rtol=0, atol=1e-13)


def test_bicubic_coons_errors():
    rng = np.random.default_rng(25)
    B = [0, 0, 0, 0, 1, 1, 1, 1]
    data = surface_boundary_data(NurbsSurface(rng.normal(size=(4, 4, 3)), B, B, 3, 3))
    base = {k: data[k] for k in ("c0", "c1", "d0", "d1")}
    bad_end = data["c0_cross"].translated([0.0, 0.0, 1e-3])
    with pytest.raises(InvalidInputError, match=r"c0_cross\(0\) must equal d0'\(0\), the v-derivative at corner \(u=0, v=0\), but .* gap 0.001"):
        bicubic_coons(**base, c0_cross=bad_end)
    bad_end = data["d1_cross"].translated([1e-3, 0.0, 0.0])
    with pytest.raises(InvalidInputError, match=r"d1_cross\(0\) must equal c0'\(1\), the u-derivative at corner \(u=1, v=0\)"):
        bicubic_coons(**base, d1_cross=bad_end)
    # Same end values, different end slope: an incompatible twist at (u=0, v=0).
    P = np.array(data["d0_cross"].control_points)
    P[1] += [0.0, 0.3, 0.0]
    bent = NurbsCurve(P, B, 3)
    with pytest.raises(InvalidInputError, match=r"corner \(u=0, v=0\): the twist d0_cross'\(0\) must equal c0_cross'\(0\)"):
        bicubic_coons(**base, c0_cross=data["c0_cross"], d0_cross=bent)
    arc = NurbsCurve(data["c0_cross"].control_points, B, 3, [1, 2, 2, 1])
    with pytest.raises(InvalidInputError, match=r"c0_cross: Coons patches need polynomial"):
        bicubic_coons(**base, c0_cross=arc)
    with pytest.raises(InvalidInputError, match=r"same dimension, c0 has 3 and c1_cross has 2"):
        bicubic_coons(**base, c1_cross=line([0, 0], [1, 1]))
    with pytest.raises(InvalidInputError, match=r"d1_cross must be a NurbsCurve, got int"):
        bicubic_coons(**base, d1_cross=3)
    with pytest.raises(InvalidInputError, match=r"corner \(u=0, v=1\): c1 starts at .* but d0 ends at .* gap 1.0"):
        bicubic_coons(base["c0"], base["c1"].translated([0, 0, 1]), base["d0"], base["d1"])
