"""NurbsCurve: evaluation against independent oracles, broadcasting, invariants and validation."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from scipy.interpolate import BSpline

from coons.errors import InvalidGeometryError, InvalidInputError
from coons.kernel.curve import NurbsCurve

from .strategies import curves, params_in

SQ2 = np.sqrt(0.5)


def quarter_circle(radius: float = 1.0) -> NurbsCurve:
    return NurbsCurve([[radius, 0, 0], [radius, radius, 0], [0, radius, 0]], [0, 0, 0, 1, 1, 1], 2, [1, SQ2, 1])


def scale_of(c: NurbsCurve) -> float:
    return float(np.abs(c.control_points).max()) + 1.0


@given(curves(rational=False))
def test_polynomial_evaluation_and_derivatives_match_scipy(c):
    rng = np.random.default_rng(0)
    u = params_in(c.domain, rng, 50)
    ref = BSpline(c.knots, c.control_points, c.degree)
    D = c.derivatives(u, c.degree)
    for k in range(c.degree + 1):
        np.testing.assert_allclose(D[:, k], ref(u, nu=k), rtol=0, atol=1e-9 * scale_of(c) * 10**k)
    np.testing.assert_allclose(c.evaluate(u), D[:, 0], rtol=0, atol=1e-12 * scale_of(c))


@given(curves(rational=True))
def test_rational_evaluation_is_projection_of_homogeneous_curve(c):
    rng = np.random.default_rng(1)
    u = params_in(c.domain, rng, 50)
    Pw = BSpline(c.knots, c.homogeneous, c.degree)(u)
    np.testing.assert_allclose(c.evaluate(u), Pw[:, :-1] / Pw[:, -1:], rtol=0, atol=1e-12 * scale_of(c))


@given(curves(max_degree=4))
def test_derivatives_match_finite_differences(c):
    rng = np.random.default_rng(2)
    a, b = c.domain
    h = 1e-6 * (b - a)
    # Stay away from knots: derivatives may jump across them.
    u = params_in((a + 2 * h, b - 2 * h), rng, 20)
    knots = np.unique(c.knots)
    u = u[np.min(np.abs(u[:, None] - knots[None, :]), axis=1) > 4 * h]
    if u.size == 0:
        return
    D = c.derivatives(u, 2)
    fd1 = (c.evaluate(u + h) - c.evaluate(u - h)) / (2 * h)
    fd2 = (c.derivatives(u + h, 1)[:, 1] - c.derivatives(u - h, 1)[:, 1]) / (2 * h)
    scale1 = np.abs(D[:, 1]).max() + scale_of(c)
    scale2 = np.abs(D[:, 2]).max() + scale_of(c)
    np.testing.assert_allclose(D[:, 1], fd1, rtol=0, atol=1e-5 * scale1)
    np.testing.assert_allclose(D[:, 2], fd2, rtol=0, atol=1e-5 * scale2)


@given(curves())
def test_convex_hull_and_affine_invariance(c):
    rng = np.random.default_rng(3)
    u = params_in(c.domain, rng, 100)
    pts = c.evaluate(u)
    lo, hi = c.bounding_box()
    eps = 1e-12 * scale_of(c)
    assert np.all(pts >= lo - eps) and np.all(pts <= hi + eps)
    if c.dimension == 3:
        A = rng.normal(size=(3, 3))
        T = np.eye(4)
        T[:3, :3] = A
        T[:3, 3] = rng.normal(size=3)
        moved = c.transformed(T).evaluate(u)
        np.testing.assert_allclose(moved, pts @ A.T + T[:3, 3], rtol=0, atol=1e-11 * scale_of(c) * np.abs(A).max())


@given(curves())
def test_reversed_and_reparametrized(c):
    rng = np.random.default_rng(4)
    a, b = c.domain
    u = params_in(c.domain, rng, 30)
    r = c.reversed()
    assert r.domain == pytest.approx(c.domain)
    np.testing.assert_allclose(r.evaluate(a + b - u), c.evaluate(u), rtol=0, atol=1e-11 * scale_of(c))
    q = c.reparametrized(-3.0, 7.0)
    assert q.domain == (-3.0, 7.0)
    np.testing.assert_allclose(q.evaluate(-3.0 + (u - a) * 10.0 / (b - a)), c.evaluate(u), rtol=0, atol=1e-10 * scale_of(c))
    assert c.is_close(c.reversed().reversed())


def test_rational_circle_is_exact():
    c = quarter_circle(2.5)
    u = np.linspace(0.0, 1.0, 1001)
    np.testing.assert_allclose(np.linalg.norm(c.evaluate(u), axis=1), 2.5, rtol=1e-15)
    # The tangent is perpendicular to the radius everywhere.
    D = c.derivatives(u, 1)
    np.testing.assert_allclose(np.einsum("ij,ij->i", D[:, 0], D[:, 1]), 0.0, atol=1e-13)
    assert c.is_rational


def test_broadcasting_shapes():
    c = quarter_circle()
    assert c.evaluate(0.5).shape == (3,)
    assert c.evaluate([0.1, 0.2]).shape == (2, 3)
    assert c.evaluate(np.zeros((4, 5))).shape == (4, 5, 3)
    assert c.derivatives(0.3, 3).shape == (4, 3)
    assert c.derivatives(np.zeros((2, 7)), 2).shape == (2, 7, 3, 3)
    assert c.evaluate(np.zeros(0)).shape == (0, 3)
    assert c(0.5).shape == (3,)


def test_arrays_are_read_only_and_values_immutable():
    c = quarter_circle()
    for arr in (c.control_points, c.knots, c.weights, c.homogeneous):
        with pytest.raises(ValueError):
            arr[0] = 1.0
    with pytest.raises(AttributeError):
        c.degree = 3  # type: ignore[misc]


def test_validation_errors():
    P = [[0, 0, 0], [1, 1, 0], [2, 0, 0]]
    with pytest.raises(InvalidGeometryError, match="expected 6 knots"):
        NurbsCurve(P, [0, 0, 1, 1, 1], 2)
    with pytest.raises(InvalidGeometryError, match="non-decreasing"):
        NurbsCurve(P, [0, 0, 0, 1, 0.5, 1], 2)
    with pytest.raises(InvalidGeometryError, match="weights must be positive"):
        NurbsCurve(P, [0, 0, 0, 1, 1, 1], 2, [1, 0, 1])
    with pytest.raises(InvalidGeometryError, match="expected weights of shape"):
        NurbsCurve(P, [0, 0, 0, 1, 1, 1], 2, [1, 1])
    with pytest.raises(InvalidGeometryError, match="not finite"):
        NurbsCurve([[0, 0, 0], [np.inf, 1, 0], [2, 0, 0]], [0, 0, 0, 1, 1, 1], 2)
    with pytest.raises(InvalidGeometryError, match="degree must be >= 1"):
        NurbsCurve(P, [0, 0, 0, 1], 0)
    with pytest.raises(InvalidGeometryError, match="degree must be an integer"):
        NurbsCurve(P, [0, 0, 0, 1, 1, 1], 2.0)
    with pytest.raises(InvalidGeometryError, match="needs at least 4 control points"):
        NurbsCurve(P, [0, 0, 0, 0, 1, 1, 1], 3)
    with pytest.raises(InvalidGeometryError, match="2 axes"):
        NurbsCurve([0, 1, 2], [0, 0, 0, 1, 1, 1], 2)
    c = NurbsCurve(P, [0, 0, 0, 1, 1, 1], 2)
    with pytest.raises(InvalidInputError, match="outside the domain"):
        c.evaluate([0.5, 1.5])
    with pytest.raises(InvalidInputError, match="order must be an integer"):
        c.derivatives(0.5, -1)
    with pytest.raises(InvalidInputError, match="start < end"):
        c.reparametrized(1.0, 1.0)
    with pytest.raises(InvalidInputError, match="affine"):
        c.transformed(np.ones((4, 4)))


@given(st.floats(0.1, 100.0), st.integers(0, 2**32 - 1))
def test_unclamped_periodic_curve_is_closed_and_smooth(radius, seed):
    rng = np.random.default_rng(seed)
    p = int(rng.integers(2, 5))
    base = rng.uniform(-radius, radius, (5, 3))
    P = np.concatenate([base, base[:p]])  # wrap p control points
    n = P.shape[0]
    U = np.arange(n + p + 1, dtype=float)
    c = NurbsCurve(P, U, p)
    a, b = c.domain
    Da, Db = c.derivatives(a, p - 1), c.derivatives(b, p - 1)
    np.testing.assert_allclose(Da, Db, rtol=0, atol=1e-10 * radius * 10**p)


@given(curves())
def test_small_batches_on_python_floats_give_the_numpy_bits(c):
    """``evaluate`` of a few points runs on Python floats (``_points_scalar``): the same operations as the
    numpy path, so the same bits, at knots, at the domain's ends and inside."""
    import coons.kernel.curve as curve_module

    lo, hi = c.domain
    U = c.knots
    u = np.concatenate([[lo, hi], U[(U >= lo) & (U <= hi)], params_in(c.domain, np.random.default_rng(3), 6)])
    fast = np.array([c.evaluate(np.array([x])) for x in u])
    old = curve_module._SCALAR_POINTS
    curve_module._SCALAR_POINTS = 0
    try:
        slow = np.array([c.evaluate(np.array([x])) for x in u])
    finally:
        curve_module._SCALAR_POINTS = old
    assert np.array_equal(fast, slow)
    assert np.array_equal(c.evaluate(u[:curve_module._SCALAR_POINTS]), slow[:curve_module._SCALAR_POINTS, 0])


@pytest.mark.parametrize("degree", [3, 5])
@pytest.mark.parametrize("dim", [2, 3])
def test_spline_points_of_polynomial_curves_by_scipy_agree_with_evaluate(degree, dim, monkeypatch):
    """``spline_points`` takes scipy's B-spline for a polynomial curve at many in-domain parameters (the spline is
    kept on the curve) with evaluate's points to round-off; otherwise, or switched off, it is ``evaluate``."""
    import coons.kernel.curve as C

    rng = np.random.default_rng(7 * degree + dim)
    n = 3 * degree
    inner = np.sort(rng.uniform(0.5, 3.0, n - degree - 1))
    U = np.concatenate([[0.5] * (degree + 1), inner, [3.0] * (degree + 1)])
    P = rng.uniform(-4.0, 4.0, (n, dim))
    curve = NurbsCurve(P, U, degree)
    u = np.concatenate([[0.5, 3.0], inner, rng.uniform(0.5, 3.0, 61)])
    got = C.spline_points(curve, u)
    assert "_bspline" in curve.__dict__  # (the scipy path was taken)
    np.testing.assert_allclose(got, curve.evaluate(u), rtol=0, atol=1e-13 * np.abs(P).max())
    # Few points, a rational curve, parameters outside the domain or not finite: evaluate, bit for bit or its error.
    fresh = NurbsCurve(P, U, degree)
    np.testing.assert_array_equal(C.spline_points(fresh, u[:C._SCALAR_POINTS]), fresh.evaluate(u[:C._SCALAR_POINTS]))
    rational = NurbsCurve(P, U, degree, rng.uniform(0.5, 2.0, n))
    np.testing.assert_array_equal(C.spline_points(rational, u), rational.evaluate(u))
    for bad in (np.linspace(0.0, 3.0, 10), np.linspace(0.5, 3.5, 10), np.r_[np.linspace(0.5, 3.0, 9), np.nan]):
        with pytest.raises(InvalidInputError):
            C.spline_points(fresh, bad)
    assert "_bspline" not in fresh.__dict__ and "_bspline" not in rational.__dict__
    monkeypatch.setattr(C, "_SCIPY_POINTS", False)
    np.testing.assert_array_equal(C.spline_points(fresh, u), fresh.evaluate(u))
    assert "_bspline" not in fresh.__dict__
