"""Fitting: interpolation and least squares against closed forms, scipy's splines and dense solvers."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp
from hypothesis import given
from hypothesis import strategies as st
from scipy.interpolate import BSpline, make_interp_spline, make_lsq_spline

from coons.errors import ConvergenceError, InvalidGeometryError, InvalidInputError
from coons.kernel import basis as _b
from coons.kernel.curve import NurbsCurve
from coons.kernel.fitting import (
    _banded_solve,
    _inverse_norm1,
    approximate_curve,
    approximate_curve_to_tolerance,
    approximate_surface,
    approximation_knots,
    averaged_knots,
    interpolate_curve,
    interpolate_surface,
    parametrize,
    parametrize_grid,
)
from coons.tolerance import Tolerance

#: Interpolation residuals relative to the size of the data.
INTERP_RTOL = 1e-10
#: Agreement of two solvers of the same well-conditioned linear problem, relative to the data size.
SOLVER_RTOL = 1e-9

METHODS = ("chord", "centripetal", "uniform")


def walk(rng: np.random.Generator, m: int, d: int) -> np.ndarray:
    """``m`` points whose consecutive distances lie in [0.2, 2] (never near-coincident)."""
    dirs = rng.normal(size=(m - 1, d))
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    steps = dirs * rng.uniform(0.2, 2.0, (m - 1, 1))
    return np.concatenate([rng.uniform(-5, 5, (1, d)), steps]).cumsum(axis=0)


def grid(rng: np.random.Generator, m: int, n: int, d: int = 3) -> np.ndarray:
    """A perturbed regular ``m x n`` grid (rows and columns well separated)."""
    G = np.zeros((m, n, d))
    G[..., 0] = np.arange(m)[:, None]
    G[..., 1] = np.arange(n)[None, :]
    return G + rng.uniform(-0.3, 0.3, (m, n, d))


@st.composite
def point_sets(draw, min_points: int = 2, max_points: int = 14, dims=(2, 3)):
    rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
    m = draw(st.integers(min_points, max_points))
    return walk(rng, m, draw(st.sampled_from(dims)))


def scale(Q: np.ndarray) -> float:
    return float(np.abs(Q).max()) + 1.0


# ================================================================== parametrize
def test_parametrize_closed_forms():
    Q = np.array([[0.0, 0.0], [3.0, 4.0], [3.0, 8.0], [3.0, 17.0]])  # steps 5, 4, 9
    np.testing.assert_allclose(parametrize(Q, "chord"), [0, 5 / 18, 9 / 18, 1], rtol=0, atol=1e-15)
    np.testing.assert_allclose(parametrize(Q, "centripetal"), np.array([0, 5**0.5, 5**0.5 + 2, 5**0.5 + 5]) / (5**0.5 + 5), rtol=0, atol=1e-15)
    np.testing.assert_allclose(parametrize(Q, "uniform"), [0, 1 / 3, 2 / 3, 1], rtol=0, atol=1e-15)


@given(point_sets(), st.sampled_from(METHODS), st.integers(0, 2**32 - 1))
def test_parametrize_is_similarity_invariant_and_increasing(Q, method, seed):
    rng = np.random.default_rng(seed)
    u = parametrize(Q, method)
    assert u[0] == 0.0 and u[-1] == 1.0
    assert np.all(np.diff(u) > 0)
    R, _ = np.linalg.qr(rng.normal(size=(Q.shape[1], Q.shape[1])))
    moved = 3.7 * Q @ R.T + rng.normal(size=Q.shape[1])
    np.testing.assert_allclose(parametrize(moved, method), u, rtol=0, atol=1e-12)


def test_parametrize_errors():
    with pytest.raises(InvalidInputError, match=r"points 1 and 2 coincide"):
        parametrize([[0, 0], [1, 0], [1, 1e-9], [2, 0]], "chord")
    with pytest.raises(InvalidInputError, match=r"points 0 and 1 coincide"):
        parametrize([[0, 0], [0, 0], [1, 0]], "centripetal")
    # A looser tolerance makes points 1 apart coincide; uniform parameters ignore distances.
    with pytest.raises(InvalidInputError, match=r"coincide"):
        parametrize([[0, 0], [1, 0], [3, 0]], tol=Tolerance(linear=1.5))
    np.testing.assert_allclose(parametrize([[0, 0], [0, 0], [1, 0]], "uniform"), [0, 0.5, 1], rtol=0, atol=0)
    with pytest.raises(InvalidInputError, match=r"method must be one of .* got 'arc'"):
        parametrize([[0, 0], [1, 0]], "arc")
    with pytest.raises(InvalidInputError, match=r"at least 2 points, got 1"):
        parametrize([[0, 0]])
    with pytest.raises(InvalidGeometryError, match=r"expected an array with 2 axes"):
        parametrize([0, 1, 2])
    with pytest.raises(InvalidGeometryError, match=r"not finite"):
        parametrize([[0, 0], [np.nan, 1]])


def test_parametrize_grid_averages_columns_and_skips_poles():
    rng = np.random.default_rng(3)
    G = grid(rng, 5, 4)
    u, v = parametrize_grid(G, "chord")
    expected_u = np.mean([parametrize(G[:, l]) for l in range(4)], axis=0)
    expected_v = np.mean([parametrize(G[k]) for k in range(5)], axis=0)
    np.testing.assert_allclose(u, expected_u, rtol=0, atol=1e-15)
    np.testing.assert_allclose(v, expected_v, rtol=0, atol=1e-15)
    # A column collapsed to one point (a pole) carries no information and is left out.
    P = G.copy()
    P[:, 0] = P[0, 0]
    u_pole, _ = parametrize_grid(P, "centripetal")
    expected = np.mean([parametrize(P[:, l], "centripetal") for l in range(1, 4)], axis=0)
    np.testing.assert_allclose(u_pole, expected, rtol=0, atol=1e-15)
    uu, vv = parametrize_grid(G, "uniform")
    np.testing.assert_allclose(uu, np.linspace(0, 1, 5), rtol=0, atol=0)
    np.testing.assert_allclose(vv, np.linspace(0, 1, 4), rtol=0, atol=0)


def test_parametrize_grid_errors():
    G = grid(np.random.default_rng(4), 4, 3)
    G[2] = G[1]
    with pytest.raises(InvalidInputError, match=r"rows 1 and 2 coincide"):
        parametrize_grid(G)
    G = grid(np.random.default_rng(4), 4, 3)
    G[:, 2] = G[:, 1]
    with pytest.raises(InvalidInputError, match=r"columns 1 and 2 coincide"):
        parametrize_grid(G)
    with pytest.raises(InvalidInputError, match=r"at least 2 x 2 points, got 1 x 3"):
        parametrize_grid(np.zeros((1, 3, 3)))
    with pytest.raises(InvalidInputError, match=r"method must be one of"):
        parametrize_grid(G, "foo")


# ================================================================== knots
def test_averaged_knots_closed_form():
    np.testing.assert_allclose(
        averaged_knots([0.0, 0.1, 0.4, 0.6, 1.0], 3), [0, 0, 0, 0, (0.1 + 0.4 + 0.6) / 3, 1, 1, 1, 1], rtol=0, atol=1e-15
    )
    np.testing.assert_allclose(averaged_knots([0.0, 0.5, 2.0], 2), [0, 0, 0, 2, 2, 2], rtol=0, atol=0)


@given(point_sets(min_points=2), st.integers(1, 5))
def test_averaged_knots_satisfy_schoenberg_whitney(Q, p):
    u = parametrize(Q)
    if u.size < p + 1:
        return
    U = averaged_knots(u, p)
    A = _b.basis_matrix(U, p, u).toarray()
    assert np.all(np.diag(A) > 0)


def test_approximation_knots_closed_forms():
    u = np.linspace(0, 1, 10)
    # The NURBS Book eq. 9.68-9.69 with m = 10 points, n = 6, p = 3: d = 10/3.
    np.testing.assert_allclose(
        approximation_knots(u, 6, 3, placement="nurbs_book"),
        [0, 0, 0, 0, (2 / 3) * u[2] + (1 / 3) * u[3], (1 / 3) * u[5] + (2 / 3) * u[6], 1, 1, 1, 1],
        rtol=0, atol=1e-15,
    )
    rng = np.random.default_rng(5)
    w = np.sort(rng.random(12))
    # With as many control points as points the averaged placement gives the interpolation knots.
    np.testing.assert_allclose(approximation_knots(w, 12, 3), averaged_knots(w, 3), rtol=0, atol=1e-15)


def test_knot_errors():
    with pytest.raises(InvalidInputError, match=r"needs at least 4 parameters, got 3"):
        averaged_knots([0, 0.5, 1], 3)
    with pytest.raises(InvalidInputError, match=r"strictly increasing, but params\[2\] = 0.5"):
        averaged_knots([0, 0.5, 0.5, 1], 1)
    with pytest.raises(InvalidInputError, match=r"\[4, 5\], got 6"):
        approximation_knots(np.linspace(0, 1, 5), 6, 3)
    with pytest.raises(InvalidInputError, match=r"placement must be .* got 'even'"):
        approximation_knots(np.linspace(0, 1, 5), 4, 3, placement="even")
    with pytest.raises(InvalidInputError, match=r"n_control_points must be an integer, got 4.0"):
        approximation_knots(np.linspace(0, 1, 5), 4.0, 3)


# ================================================================== curve interpolation
@given(point_sets(), st.integers(1, 5), st.sampled_from(METHODS))
def test_interpolation_passes_through_points(Q, p, method):
    if Q.shape[0] < p + 1:
        return
    c = interpolate_curve(Q, p, method=method)
    u = parametrize(Q, method)
    assert c.degree == p and c.n_control_points == Q.shape[0] and not c.is_rational
    assert c.domain == (0.0, 1.0)
    np.testing.assert_allclose(c.evaluate(u), Q, rtol=0, atol=INTERP_RTOL * scale(Q))
    np.testing.assert_allclose(c.knots, averaged_knots(u, p), rtol=0, atol=0)


@given(point_sets(min_points=3), st.integers(2, 5), st.integers(0, 2**32 - 1))
def test_interpolation_with_end_tangents_matches_scipy(Q, p, seed):
    rng = np.random.default_rng(seed)
    m, d = Q.shape
    D0, D1 = rng.normal(size=d) * 5, rng.normal(size=d) * 5
    for start, end in ((D0, D1), (D0, None), (None, D1)):
        if m + (start is not None) + (end is not None) < p + 1:
            continue
        c = interpolate_curve(Q, p, start_tangent=start, end_tangent=end)
        u = parametrize(Q)
        s = scale(Q) + 5 * np.abs(np.r_[D0, D1]).max()
        np.testing.assert_allclose(c.evaluate(u), Q, rtol=0, atol=INTERP_RTOL * s)
        if start is not None:
            np.testing.assert_allclose(c.derivatives(0.0, 1)[1], start, rtol=0, atol=INTERP_RTOL * s)
        if end is not None:
            np.testing.assert_allclose(c.derivatives(1.0, 1)[1], end, rtol=0, atol=INTERP_RTOL * s)
        # scipy's interpolating spline on the same knots, with the same end conditions.
        bc = ([(1, start)] if start is not None else None, [(1, end)] if end is not None else None)
        ref = make_interp_spline(u, Q, k=p, t=c.knots, bc_type=bc)
        np.testing.assert_allclose(c.control_points, ref.c, rtol=0, atol=SOLVER_RTOL * s * 10**p)


@given(st.integers(0, 2**32 - 1), st.integers(1, 5))
def test_interpolation_reproduces_polynomials(seed, p):
    """A curve of degree <= p is in the spline space, so interpolation must return it (any parameters)."""
    rng = np.random.default_rng(seed)
    coef = rng.normal(size=(p + 1, 3))
    poly = lambda t: np.polynomial.polynomial.polyval(t, coef).T  # noqa: E731
    u = np.sort(rng.uniform(0, 1, p + 6))
    u[0], u[-1] = 0.0, 1.0
    u = np.unique(u)
    if np.min(np.diff(u)) < 1e-3:
        return
    c = interpolate_curve(poly(u), p, params=u)
    t = np.linspace(0, 1, 41)
    np.testing.assert_allclose(c.evaluate(t), poly(t), rtol=0, atol=1e-9 * (np.abs(coef).sum() + 1))


def test_degree_one_interpolation_is_the_polyline():
    Q = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 2.0], [4.0, 6.0]])
    c = interpolate_curve(Q, 1)
    np.testing.assert_allclose(c.control_points, Q, rtol=0, atol=0)
    np.testing.assert_allclose(c.knots, [0, 0, 1 / 8, 3 / 8, 1, 1], rtol=0, atol=1e-15)
    np.testing.assert_allclose(c.evaluate(0.25), [1.0, 1.0], rtol=0, atol=1e-15)


def test_interpolation_with_given_params_and_knots():
    Q = walk(np.random.default_rng(6), 7, 3)
    u = np.array([1.0, 1.5, 2.0, 3.0, 3.5, 4.5, 5.0])
    U = [1, 1, 1, 1, 2.2, 2.8, 4, 5, 5, 5, 5]
    c = interpolate_curve(Q, 3, params=u, knots=U)
    assert c.domain == (1.0, 5.0)
    np.testing.assert_allclose(c.knots, U, rtol=0, atol=0)
    np.testing.assert_allclose(c.evaluate(u), Q, rtol=0, atol=INTERP_RTOL * scale(Q))
    np.testing.assert_allclose(c.control_points, make_interp_spline(u, Q, k=3, t=U).c, rtol=0, atol=1e-10 * scale(Q))


def test_interpolation_errors():
    Q = walk(np.random.default_rng(7), 5, 2)
    with pytest.raises(InvalidInputError, match=r"degree 3 with 0 end tangent\(s\) needs at least 4 points, got 3"):
        interpolate_curve(Q[:3], 3)
    with pytest.raises(InvalidInputError, match=r"needs at least 2 points, got 1"):
        interpolate_curve(Q[:1], 2, start_tangent=[1, 0], end_tangent=[1, 0])
    with pytest.raises(InvalidInputError, match=r"end tangents need degree >= 2, got degree 1"):
        interpolate_curve(Q, 1, start_tangent=[1, 0])
    with pytest.raises(InvalidInputError, match=r"start_tangent: expected a vector of shape \(2,\), got shape \(3,\)"):
        interpolate_curve(Q, 3, start_tangent=[1, 0, 0])
    with pytest.raises(InvalidInputError, match=r"end_tangent: components must be finite"):
        interpolate_curve(Q, 3, end_tangent=[np.inf, 0])
    with pytest.raises(InvalidInputError, match=r"expected 5 parameters \(one per point\), got shape \(4,\)"):
        interpolate_curve(Q, 3, params=[0, 1, 2, 3])
    with pytest.raises(InvalidInputError, match=r"strictly increasing, but params\[2\]"):
        interpolate_curve(Q, 3, params=[0, 1, 1, 3, 4])
    with pytest.raises(InvalidInputError, match=r"parameters must be finite"):
        interpolate_curve(Q, 3, params=[0, 1, np.nan, 3, 4])
    with pytest.raises(InvalidGeometryError, match=r"expected 9 knots"):
        interpolate_curve(Q, 3, knots=[0, 0, 0, 0, 1, 1, 1, 1])
    with pytest.raises(InvalidInputError, match=r"params: parameter 1.0 is outside the domain \[0.0, 0.5\]"):
        interpolate_curve(Q, 3, knots=[0, 0, 0, 0, 0.25, 0.5, 0.5, 0.5, 0.5])
    # Interior knots crowded left: parameter 0.2 is outside the support [0, 0.15] of N_1.
    with pytest.raises(InvalidInputError, match=r"Schoenberg-Whitney condition: parameter 0.2 \(row 1\) .* function 1"):
        interpolate_curve(Q, 1, params=[0, 0.2, 0.4, 0.6, 1.0], knots=[0, 0, 0.1, 0.15, 0.3, 1, 1])
    with pytest.raises(InvalidGeometryError, match=r"degree must be >= 1, got 0"):
        interpolate_curve(Q, 0)
    with pytest.raises(InvalidInputError, match=r"method must be one of"):
        interpolate_curve(Q, 3, method="arc")
    with pytest.raises(InvalidInputError, match=r"points 1 and 2 coincide"):
        interpolate_curve(np.array([[0, 0], [1, 0], [1, 0], [2, 0]]), 2)


def test_condition_estimate_is_a_tight_lower_bound():
    """Hager's estimate of ||A^-1||_1 never exceeds the true norm and is within 10x of it."""
    import scipy.linalg.lapack as lapack

    rng = np.random.default_rng(14)
    for n, kl, ku in ((8, 1, 1), (40, 3, 3), (120, 2, 4)):
        A = sum(np.diag(rng.normal(size=n - abs(k)), k) for k in range(-kl, ku + 1))
        ab = np.zeros((2 * kl + ku + 1, n))
        i, j = np.nonzero(A)
        ab[kl + ku + i - j, j] = A[i, j]
        lu, piv, _ = lapack.dgbtrf(ab, kl, ku)
        est = _inverse_norm1(lu, piv, kl, ku)
        true = np.linalg.norm(np.linalg.inv(A), 1)
        assert true / 10 <= est <= true * (1 + 1e-10)


def test_banded_solve_refuses_singular_systems():
    with pytest.raises(InvalidInputError, match=r"test: the linear system is singular \(zero pivot in column 1\)"):
        _banded_solve(sp.csr_matrix(np.array([[1.0, 2.0], [2.0, 4.0]])), np.ones((2, 1)), "test")
    with pytest.raises(InvalidInputError, match=r"singular to working precision \(reciprocal condition number"):
        _banded_solve(sp.csr_matrix(np.array([[1.0, 1.0], [1.0, 1.0 + 1e-17 + 2e-16]])), np.ones((2, 1)), "test")


# ================================================================== least squares
@given(point_sets(min_points=6, max_points=30), st.integers(1, 4), st.integers(0, 2**32 - 1))
def test_least_squares_matches_scipy_make_lsq_spline(Q, p, seed):
    rng = np.random.default_rng(seed)
    m = Q.shape[0]
    n = int(rng.integers(p + 1, m + 1))
    w = rng.uniform(0.5, 2.0, m)
    c = approximate_curve(Q, n, p, weights=w, interpolate_ends=False)
    u = parametrize(Q)
    np.testing.assert_allclose(c.knots, approximation_knots(u, n, p), rtol=0, atol=0)
    # scipy minimises sum (w_k r_k)^2, coons sum w_k r_k^2.
    ref = make_lsq_spline(u, Q, c.knots, k=p, w=np.sqrt(w))
    np.testing.assert_allclose(c.control_points, ref.c, rtol=0, atol=SOLVER_RTOL * scale(Q))


@given(point_sets(min_points=6, max_points=30), st.integers(1, 4), st.integers(0, 2**32 - 1))
def test_least_squares_with_fixed_ends_matches_dense_constrained_solution(Q, p, seed):
    rng = np.random.default_rng(seed)
    m = Q.shape[0]
    n = int(rng.integers(p + 1, m + 1))
    c = approximate_curve(Q, n, p)
    u = parametrize(Q)
    np.testing.assert_allclose(c.control_points[[0, -1]], Q[[0, -1]], rtol=0, atol=0)
    np.testing.assert_allclose(c.evaluate([0.0, 1.0]), Q[[0, -1]], rtol=0, atol=1e-14 * scale(Q))
    # Oracle: eliminate the two fixed control points and solve the rest with dense lstsq on scipy's basis.
    B = BSpline.design_matrix(u, c.knots, p).toarray()
    R = Q - B[:, [0, -1]] @ Q[[0, -1]]
    inner = np.linalg.lstsq(B[:, 1:-1], R, rcond=None)[0]
    np.testing.assert_allclose(c.control_points[1:-1], inner, rtol=0, atol=SOLVER_RTOL * scale(Q))


def test_least_squares_reproduces_a_spline_of_its_space():
    rng = np.random.default_rng(8)
    truth = NurbsCurve(rng.normal(size=(7, 3)), [0, 0, 0, 0, 0.2, 0.45, 0.7, 1, 1, 1, 1], 3)
    u = np.linspace(0, 1, 60)
    for ends in (True, False):
        c = approximate_curve(truth.evaluate(u), 7, 3, params=u, knots=truth.knots, interpolate_ends=ends)
        np.testing.assert_allclose(c.control_points, truth.control_points, rtol=0, atol=1e-12)


def test_least_squares_error_decreases_with_more_control_points():
    t = np.linspace(0, 1, 300)
    Q = np.c_[np.cos(4 * t), np.sin(3 * t), t**2]
    errors = []
    for n in (5, 10, 20, 40, 80):
        c = approximate_curve(Q, n, 3)
        errors.append(np.max(np.linalg.norm(c.evaluate(parametrize(Q)) - Q, axis=1)))
    assert all(a > 2 * b for a, b in zip(errors, errors[1:])), errors
    # n = m is interpolation.
    c = approximate_curve(Q, 300, 3)
    np.testing.assert_allclose(c.evaluate(parametrize(Q)), Q, rtol=0, atol=1e-12)


def test_least_squares_errors():
    Q = walk(np.random.default_rng(9), 10, 3)
    with pytest.raises(InvalidInputError, match=r"\[4, 10\], got 11"):
        approximate_curve(Q, 11, 3)
    with pytest.raises(InvalidInputError, match=r"\[4, 10\], got 3"):
        approximate_curve(Q, 3, 3)
    with pytest.raises(InvalidInputError, match=r"n_control_points must be an integer"):
        approximate_curve(Q, "5", 3)
    with pytest.raises(InvalidInputError, match=r"expected 10 point weights, got shape \(9,\)"):
        approximate_curve(Q, 5, weights=np.ones(9))
    with pytest.raises(InvalidInputError, match=r"finite and positive, weights\[4\] = 0.0"):
        approximate_curve(Q, 5, weights=np.r_[np.ones(4), 0.0, np.ones(5)])
    u = parametrize(Q)
    floating = [-0.2, -0.1, 0.0, 0.0, 0.5, 1, 1, 1.1, 1.2]
    with pytest.raises(InvalidInputError, match=r"interpolate_ends needs knots clamped"):
        approximate_curve(Q, 5, 3, knots=floating)
    # N_2 has support [0.3, 0.34], where no parameter lies.
    gap = [0, 0.1, 0.2, 0.25, 0.5, 0.6, 0.7, 0.8, 0.9, 1.0]
    for ends in (True, False):
        with pytest.raises(InvalidInputError, match=r"no parameter lies in the support of basis function 2"):
            approximate_curve(Q, 5, 1, params=gap, knots=[0, 0, 0.3, 0.32, 0.34, 1, 1], interpolate_ends=ends)
    # The NURBS Book placement degenerates as n reaches m (first knot at params[0]).
    with pytest.raises(InvalidInputError, match=r"singular to working precision"):
        rng = np.random.default_rng(0)
        P = rng.uniform(-5, 5, (50, 3))
        approximate_curve(P, 50, 3, knots=approximation_knots(parametrize(P), 50, 3, placement="nurbs_book"))


# ================================================================== least squares to a tolerance
def test_approximation_to_tolerance_meets_it_with_few_control_points():
    t = np.linspace(0, 1, 400)
    Q = np.c_[np.cos(5 * t), np.sin(3 * t), t]
    u = parametrize(Q)
    counts = []
    for e in (1e-2, 1e-4, 1e-6):
        c = approximate_curve_to_tolerance(Q, e)
        err = np.max(np.linalg.norm(c.evaluate(u) - Q, axis=1))
        assert err <= e
        np.testing.assert_allclose(c.evaluate([0.0, 1.0]), Q[[0, -1]], rtol=0, atol=1e-14)
        counts.append(c.n_control_points)
        # One fewer control point does not meet the tolerance (bisection found the threshold).
        smaller = approximate_curve(Q, c.n_control_points - 1, 3)
        assert np.max(np.linalg.norm(smaller.evaluate(u) - Q, axis=1)) > e
    assert counts[0] < counts[1] < counts[2] < 150, counts


def test_approximation_to_tolerance_errors():
    Q = walk(np.random.default_rng(10), 30, 3)
    with pytest.raises(ConvergenceError, match=r"8 control points leave a max error of .* > max_error = 1e-06") as info:
        approximate_curve_to_tolerance(Q, 1e-6, max_control_points=8)
    assert info.value.residuals.shape == (1,) and info.value.residuals[0] > 1e-6
    with pytest.raises(ConvergenceError, match=r"30 control points leave"):
        approximate_curve_to_tolerance(Q, 1e-300)
    for bad in (0.0, -1.0, np.nan, "1"):
        with pytest.raises(InvalidInputError, match=r"max_error must be a finite positive number"):
            approximate_curve_to_tolerance(Q, bad)
    with pytest.raises(InvalidInputError, match=r"max_control_points must be in .* = \[4, 30\], got 31"):
        approximate_curve_to_tolerance(Q, 1e-3, max_control_points=31)
    with pytest.raises(InvalidInputError, match=r"degree 3 needs at least 4 points, got 3"):
        approximate_curve_to_tolerance(Q[:3], 1e-3)


# ================================================================== surfaces
@given(st.integers(0, 2**32 - 1), st.integers(1, 4), st.integers(1, 4), st.sampled_from(METHODS))
def test_surface_interpolation_passes_through_grid(seed, pu, pv, method):
    rng = np.random.default_rng(seed)
    m, n = int(rng.integers(pu + 1, pu + 6)), int(rng.integers(pv + 1, pv + 6))
    G = grid(rng, m, n)
    s = interpolate_surface(G, pu, pv, method=method)
    u, v = parametrize_grid(G, method)
    assert s.shape == (m, n) and (s.degree_u, s.degree_v) == (pu, pv)
    np.testing.assert_allclose(s.evaluate_grid(u, v), G, rtol=0, atol=INTERP_RTOL * scale(G))
    np.testing.assert_allclose(s.knots_u, averaged_knots(u, pu), rtol=0, atol=0)
    np.testing.assert_allclose(s.knots_v, averaged_knots(v, pv), rtol=0, atol=0)


def test_surface_interpolation_reproduces_polynomial_surfaces():
    rng = np.random.default_rng(11)
    C = rng.normal(size=(3, 4, 3))  # degree 2 in u, 3 in v
    f = lambda a, b: np.einsum("ijd,...i,...j->...d", C, a[..., None] ** np.arange(3), b[..., None] ** np.arange(4))  # noqa: E731
    u = np.r_[0, np.sort(rng.uniform(0.1, 0.9, 4)), 1]
    v = np.linspace(0, 1, 7) ** 1.5
    uu, vv = np.meshgrid(u, v, indexing="ij")
    s = interpolate_surface(f(uu, vv), 2, 3, params_u=u, params_v=v)
    a, b = np.meshgrid(np.linspace(0, 1, 9), np.linspace(0, 1, 11), indexing="ij")
    np.testing.assert_allclose(s.evaluate(a, b), f(a, b), rtol=0, atol=1e-10)


def test_surface_interpolation_errors():
    G = grid(np.random.default_rng(12), 4, 5)
    with pytest.raises(InvalidInputError, match=r"degrees \(4, 2\) need at least \(5, 3\) points, got \(4, 5\)"):
        interpolate_surface(G, 4, 2)
    with pytest.raises(InvalidInputError, match=r"params_u: expected 4 parameters"):
        interpolate_surface(G, 2, 2, params_u=[0, 1])
    with pytest.raises(InvalidInputError, match=r"params_v: parameters must be strictly increasing"):
        interpolate_surface(G, 2, 2, params_v=[0, 1, 1, 2, 3])
    with pytest.raises(InvalidInputError, match=r"at least 2 x 2 points, got 4 x 1"):
        interpolate_surface(G[:, :1], 1, 1)
    with pytest.raises(InvalidGeometryError, match=r"degree_v: degree must be >= 1, got 0"):
        interpolate_surface(G, 2, 0)
    with pytest.raises(InvalidGeometryError, match=r"expected an array with 3 axes"):
        interpolate_surface(G[0], 2, 2)


@given(st.integers(0, 2**32 - 1), st.integers(1, 3), st.integers(1, 3))
def test_surface_least_squares_is_the_tensor_least_squares(seed, pu, pv):
    rng = np.random.default_rng(seed)
    m, n = int(rng.integers(pu + 2, 12)), int(rng.integers(pv + 2, 12))
    nu, nv = int(rng.integers(pu + 1, m + 1)), int(rng.integers(pv + 1, n + 1))
    G = grid(rng, m, n)
    s = approximate_surface(G, nu, nv, pu, pv, interpolate_ends=False)
    u, v = parametrize_grid(G)
    # Oracle: one dense least-squares problem on the Kronecker design matrix.
    K = np.kron(BSpline.design_matrix(u, s.knots_u, pu).toarray(), BSpline.design_matrix(v, s.knots_v, pv).toarray())
    ref = np.linalg.lstsq(K, G.reshape(m * n, 3), rcond=None)[0].reshape(nu, nv, 3)
    np.testing.assert_allclose(s.control_points, ref, rtol=0, atol=SOLVER_RTOL * scale(G))
    # With the ends interpolated, the corners are exact.
    e = approximate_surface(G, nu, nv, pu, pv)
    corners = np.array([[G[0, 0], G[0, -1]], [G[-1, 0], G[-1, -1]]])
    np.testing.assert_allclose(e.evaluate_grid([0.0, 1.0], [0.0, 1.0]), corners, rtol=0, atol=1e-13 * scale(G))


def test_surface_least_squares_converges_on_smooth_data():
    a, b = np.meshgrid(np.linspace(0, 1, 40), np.linspace(0, 1, 30), indexing="ij")
    G = np.stack([a, b, np.sin(3 * a) * np.cos(2 * b)], axis=-1)
    u, v = parametrize_grid(G)
    errors = [
        np.abs(approximate_surface(G, k, k, 3, 3).evaluate_grid(u, v) - G).max() for k in (5, 10, 20)
    ]
    assert errors[0] > 4 * errors[1] > 16 * errors[2], errors
    full = approximate_surface(G, 40, 30, 3, 3)
    np.testing.assert_allclose(full.evaluate_grid(u, v), G, rtol=0, atol=1e-12)


def test_surface_least_squares_errors():
    G = grid(np.random.default_rng(13), 6, 5)
    with pytest.raises(InvalidInputError, match=r"\(n_u, n_v\) must be in \[4, 6\] x \[3, 5\], got \(7, 4\)"):
        approximate_surface(G, 7, 4, 3, 2)
    with pytest.raises(InvalidInputError, match=r"n_v must be an integer"):
        approximate_surface(G, 5, 4.5, 3, 2)


@given(t=st.lists(st.floats(-1e3, 1e3), min_size=2, max_size=60), p=st.integers(1, 9))
def test_averaged_knots_are_the_window_means(t, p):
    """Eq. 9.8's window sums (added in order below eight terms) equal numpy's sliding-window means value for value."""
    from coons.kernel.fitting import _averaging

    u = np.sort(np.array(t))
    windows = np.lib.stride_tricks.sliding_window_view(u[1:-1], p) if u.size > p + 1 else np.empty((0, p))
    expected = np.concatenate([np.full(p + 1, u[0]), windows.mean(axis=1), np.full(p + 1, u[-1])])
    assert np.array_equal(_averaging(u, p), expected)
