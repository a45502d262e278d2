"""Closest points and point inversion: analytic truth, brute-force sampling, invariants and every error branch."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from coons.errors import ConvergenceError, InvalidInputError
from coons.kernel import projection
from coons.kernel.curve import NurbsCurve
from coons.kernel.projection import ClosestPoints
from coons.kernel.surface import NurbsSurface
from coons.tolerance import Tolerance

from .exact_shapes import circle, cylinder, sphere
from .strategies import curves, params_in, surfaces

TOL = Tolerance()
#: Points returned by inversion agree with the points inverted far below tol.linear
#: (the iteration stops at tol.solver relative to the geometry's size, about 1e-11 here).
ON_CURVE = 1e-9
#: Closest points off the geometry stop once the orthogonality cosine is below tol.angular:
#: their position is then exact to about tol.angular times the distance.
ALONG = 10 * TOL.angular
#: Brute-force reference: the best of 10^4 samples (100 x 100 on surfaces).
BRUTE = 10_000








def brute_force_curve(c: NurbsCurve, P: np.ndarray) -> np.ndarray:
    u = np.linspace(*c.domain, BRUTE)
    return np.min(np.linalg.norm(c.evaluate(u)[None, :, :] - P[:, None, :], axis=2), axis=1)


def brute_force_surface(s: NurbsSurface, P: np.ndarray) -> np.ndarray:
    k = int(np.sqrt(BRUTE))
    G = s.evaluate_grid(np.linspace(*s.domain_u, k), np.linspace(*s.domain_v, k)).reshape(-1, 3)
    return np.min(np.linalg.norm(G[None, :, :] - P[:, None, :], axis=2), axis=1)


def size_of(geometry) -> float:
    box = geometry.bounding_box()
    return float(np.linalg.norm(box[1] - box[0]))


# ---------------------------------------------------------------------- curves: properties
@given(curves(max_degree=4), st.integers(0, 2**32 - 1))
def test_curve_invert_returns_the_points_it_evaluated(c, seed):
    rng = np.random.default_rng(seed)
    u = params_in(c.domain, rng, 12)
    u = np.concatenate([u, c.domain])  # the ends too
    X = c.evaluate(u)
    inv = c.invert(X)
    assert inv.shape == u.shape
    assert np.all((inv >= c.domain[0]) & (inv <= c.domain[1]))
    # Parameters are not unique where the curve crosses itself: compare the points.
    np.testing.assert_allclose(c.evaluate(inv), X, rtol=0, atol=ON_CURVE * max(1.0, size_of(c)))


@given(curves(max_degree=4), st.integers(0, 2**32 - 1))
def test_curve_closest_point_is_never_beaten_by_dense_samples(c, seed):
    rng = np.random.default_rng(seed)
    box = c.bounding_box()
    P = rng.uniform(box[0] - 2, box[1] + 2, (16, c.dimension))
    cp = c.closest_points(P)
    assert np.all(cp.distances <= brute_force_curve(c, P) + TOL.linear)
    # The result is consistent: the points are the curve at the parameters, at the distances.
    np.testing.assert_allclose(cp.points, c.evaluate(cp.parameters), rtol=0, atol=1e-12 * max(1.0, size_of(c)))
    np.testing.assert_allclose(cp.distances, np.linalg.norm(cp.points - P, axis=1), rtol=1e-14, atol=0)


@given(curves(max_degree=4, clamped=True), st.integers(0, 2**32 - 1))
def test_curve_closest_point_is_orthogonal_or_at_an_end(c, seed):
    rng = np.random.default_rng(seed)
    box = c.bounding_box()
    P = rng.uniform(box[0] - 1, box[1] + 1, (10, c.dimension))
    u = c.closest_parameters(P)
    lo, hi = c.domain
    D = c.derivatives(u, 1)
    r = D[:, 0] - P
    cosine = np.abs(np.einsum("ij,ij->i", D[:, 1], r)) / (np.linalg.norm(D[:, 1], axis=1) * np.linalg.norm(r, axis=1))
    # Where the curve is only C0 (knots of multiplicity p) the minimum may sit on the kink.
    vals, counts = np.unique(c.knots, return_counts=True)
    kinks = vals[(counts >= c.degree) & (vals > lo) & (vals < hi)]
    at_kink = np.any(np.abs(u[:, None] - kinks[None, :]) <= 1e-9, axis=1) if kinks.size else np.zeros(u.shape, bool)
    at_end = (u == lo) | (u == hi)
    assert np.all(at_end | at_kink | (cosine <= 1e-6))


def test_curve_invert_on_many_points_matches_a_single_call_per_point():
    c = NurbsCurve([[0, 0, 0], [1, 2, 0], [2, -1, 1], [3, 1, 0], [4, 0, 2]], [0, 0, 0, 0, 0.5, 1, 1, 1, 1], 3)
    u = np.linspace(0, 1, 7)
    batch = c.invert(c.evaluate(u))
    single = np.array([c.invert(c.evaluate(x)) for x in u])
    np.testing.assert_allclose(batch, single, rtol=0, atol=1e-12)
    np.testing.assert_allclose(batch, u, rtol=0, atol=1e-9)


# ---------------------------------------------------------------------- curves: analytic truth
def test_circle_closest_points_are_radial():
    R = 2.0
    c = circle(R, centre=(1.0, -0.5))
    rng = np.random.default_rng(1)
    P = rng.normal(size=(400, 2)) * 3 + [1.0, -0.5]
    cp = c.closest_points(P)
    rel = P - [1.0, -0.5]
    radius = np.linalg.norm(rel, axis=1)
    np.testing.assert_allclose(cp.distances, np.abs(radius - R), rtol=0, atol=1e-12)
    np.testing.assert_allclose(cp.points, [1.0, -0.5] + R * rel / radius[:, None], rtol=0, atol=ALONG * radius.max())


def test_circle_seam_points_on_both_sides():
    R = 2.0
    c = circle(R)
    angle = np.array([-1e-9, -1e-6, 0.0, 1e-9, 1e-6, np.pi])
    for scale in (0.5, 1.0, 3.0):  # inside, on and outside the circle
        P = scale * R * np.stack([np.cos(angle), np.sin(angle)], axis=1)
        cp = c.closest_points(P)
        np.testing.assert_allclose(cp.points, R * P / np.linalg.norm(P, axis=1)[:, None], rtol=0, atol=ALONG * R)
        # On the circle the iteration stops at coincidence, tol.solver relative to the size.
        np.testing.assert_allclose(cp.distances, abs(scale - 1.0) * R, rtol=0, atol=10 * TOL.solver * R)


def test_points_beyond_the_ends_project_onto_the_ends():
    c = NurbsCurve([[0, 0], [1, 1], [2, 0]], [0, 0, 0, 1, 1, 1], 2)
    P = np.array([[-1.0, -1.0], [3.0, -1.0], [-5.0, 0.0]])
    cp = c.closest_points(P)
    np.testing.assert_array_equal(cp.parameters, [0.0, 1.0, 0.0])
    np.testing.assert_allclose(cp.distances, np.linalg.norm(P - c.evaluate(cp.parameters), axis=1), rtol=1e-15)


def test_polyline_closest_points_are_feet_or_vertices():
    # Degree 1: a polyline; kinks at every interior knot.
    V = np.array([[0.0, 0.0], [2.0, 0.0], [2.0, 2.0], [0.0, 2.0]])
    c = NurbsCurve(V, [0, 0, 1 / 3, 2 / 3, 1, 1], 1)
    P = np.array([[1.0, -1.0], [3.0, -1.0], [1.0, 1.2], [3.0, 1.0], [-1.0, 2.5]])
    expected = np.array([[1.0, 0.0], [2.0, 0.0], [1.0, 2.0], [2.0, 1.0], [0.0, 2.0]])
    cp = c.closest_points(P)
    np.testing.assert_allclose(cp.points, expected, rtol=0, atol=1e-12)


def test_distances_of_points_off_a_line_segment():
    c = NurbsCurve([[0, 0, 0], [1, 1, 1], [2, 2, 2]], [0, 0, 0, 1, 1, 1], 2)
    foot = np.array([[0.5, 0.5, 0.5], [1.5, 1.5, 1.5]])
    off = np.array([[1.0, -1.0, 0.0], [0.0, 1.0, -1.0]])  # orthogonal to the line, lengths sqrt(2)
    cp = c.closest_points(foot + off)
    np.testing.assert_allclose(cp.points, foot, rtol=0, atol=1e-12)
    np.testing.assert_allclose(cp.distances, np.sqrt(2.0), rtol=1e-14)


def test_batch_shapes_follow_the_points():
    c = circle()
    P = np.random.default_rng(0).normal(size=(2, 3, 2))
    cp = c.closest_points(P)
    assert cp.parameters.shape == (2, 3) and cp.points.shape == (2, 3, 2) and cp.distances.shape == (2, 3)
    single = c.closest_points(P[1, 2])
    assert single.parameters.shape == () and single.points.shape == (2,)
    np.testing.assert_allclose(single.points, cp.points[1, 2], rtol=0, atol=1e-14)
    assert c.closest_parameters(np.empty((0, 2))).shape == (0,)


def test_closest_points_result_is_read_only():
    cp = circle().closest_points([[3.0, 0.0]])
    assert isinstance(cp, ClosestPoints)
    for a in (cp.parameters, cp.points, cp.distances):
        with pytest.raises(ValueError, match="read-only"):
            a[...] = 0.0


# ---------------------------------------------------------------------- curves: errors
def test_curve_invert_raises_for_points_off_the_curve_with_their_indices():
    c = circle(2.0)
    P = c.evaluate(np.linspace(0, 1, 6))
    P[1] *= 1.5  # 1.0 off
    P[4] += [0.0, 1e-3]  # about 1e-3 off
    with pytest.raises(ConvergenceError, match=r"2 of 6 points are farther than tol.linear = 1e-07") as info:
        c.invert(P)
    np.testing.assert_array_equal(info.value.indices, [1, 4])
    np.testing.assert_allclose(info.value.residuals[0], 1.0, rtol=1e-12)
    assert 0.5e-3 < info.value.residuals[1] < 1.5e-3
    assert "worst is index 1 at distance 1" in str(info.value)


def test_curve_invert_tolerance_is_the_callers():
    c = circle(2.0)
    P = np.array([[2.0 + 1e-4, 0.0]])
    with pytest.raises(ConvergenceError, match="1 of 1 points"):
        c.invert(P)
    u = c.invert(P, Tolerance(linear=1e-3))  # 0 or 1: the seam
    np.testing.assert_allclose(c.evaluate(u), [[2.0, 0.0]], rtol=0, atol=1e-12)


def test_unconverged_points_raise_with_indices(monkeypatch):
    c = NurbsCurve([[0, 0], [1, 3], [2, -3], [3, 0]], [0, 0, 0, 0, 1, 1, 1, 1], 3)
    monkeypatch.setattr(projection, "MAX_ITERATIONS", 0)
    P = np.array([[1.5, 0.2], [10.0, 0.0]])  # interior minimum, then the end u = 1
    with pytest.raises(ConvergenceError, match=r"1 of 2 points did not converge within 0 Newton iterations") as info:
        c.closest_points(P)
    np.testing.assert_array_equal(info.value.indices, [0])
    assert info.value.residuals.shape == (1,) and info.value.residuals[0] > 0


@pytest.mark.parametrize(
    "points, message",
    [
        (np.zeros((4, 3)), r"points must have shape \(\.\.\., 2\) to match the geometry, got shape \(4, 3\)"),
        (np.float64(1.0), r"got shape \(\)"),
        (np.array([[0.0, np.nan]]), r"points must be finite, coordinate at index \(0, 1\) is not"),
        (np.array([[np.inf, 0.0]]), r"coordinate at index \(0, 0\)"),
    ],
)
def test_curve_bad_points_raise(points, message):
    with pytest.raises(InvalidInputError, match=message):
        projection.curve_closest_points(circle(), points)


def test_unbounded_domain_raises():
    class Ray:
        domain = (0.0, np.inf)

        def derivatives(self, u, order):
            u = np.asarray(u, dtype=float)
            out = np.zeros(u.shape + (order + 1, 2))
            out[..., 0, 0] = u
            if order >= 1:
                out[..., 1, 0] = 1.0
            return out

    with pytest.raises(InvalidInputError, match=r"bounded parameter domain, got \[0.0, inf\]"):
        projection.curve_closest_points(Ray(), [[1.0, 1.0]])


def test_duck_typed_curve_without_knots():
    class ExactCircle:
        """Angle-parametrised circle of radius 3: only ``domain`` and ``derivatives``."""

        domain = (0.0, 2 * np.pi)

        def derivatives(self, u, order):
            u = np.asarray(u, dtype=float)
            out = np.empty(u.shape + (order + 1, 2))
            for k in range(order + 1):
                out[..., k, 0] = 3.0 * np.cos(u + k * np.pi / 2)
                out[..., k, 1] = 3.0 * np.sin(u + k * np.pi / 2)
            return out

    angle = np.array([0.3, 2.0, 4.0, 6.0])
    P = 5.0 * np.stack([np.cos(angle), np.sin(angle)], axis=1)
    np.testing.assert_allclose(projection.curve_closest_parameters(ExactCircle(), P), angle, rtol=0, atol=ALONG)


# ---------------------------------------------------------------------- surfaces: properties
@given(surfaces(max_degree=4), st.integers(0, 2**32 - 1))
def test_surface_invert_returns_the_points_it_evaluated(s, seed):
    rng = np.random.default_rng(seed)
    u = np.concatenate([params_in(s.domain_u, rng, 8), s.domain_u])
    v = np.concatenate([params_in(s.domain_v, rng, 8), s.domain_v[::-1]])
    X = s.evaluate(u, v)
    uv = s.invert(X)
    assert uv.shape == (10, 2)
    np.testing.assert_allclose(s.evaluate(uv[:, 0], uv[:, 1]), X, rtol=0, atol=ON_CURVE * max(1.0, size_of(s)))


@given(surfaces(max_degree=4), st.integers(0, 2**32 - 1))
def test_surface_closest_point_is_never_beaten_by_dense_samples(s, seed):
    rng = np.random.default_rng(seed)
    box = s.bounding_box()
    P = rng.uniform(box[0] - 2, box[1] + 2, (8, 3))
    cp = s.closest_points(P)
    assert np.all(cp.distances <= brute_force_surface(s, P) + TOL.linear)
    np.testing.assert_allclose(
        cp.points, s.evaluate(cp.parameters[:, 0], cp.parameters[:, 1]), rtol=0, atol=1e-12 * max(1.0, size_of(s))
    )
    np.testing.assert_allclose(cp.distances, np.linalg.norm(cp.points - P, axis=1), rtol=1e-14, atol=0)


# ---------------------------------------------------------------------- surfaces: analytic truth
def test_sphere_closest_points_are_radial_including_poles_and_seam():
    R = 2.0
    s = sphere(R)
    rng = np.random.default_rng(2)
    P = rng.normal(size=(300, 3)) * 3
    # Near the poles, on the axis, across the seam (y ~ 0, x > 0) and on the sphere itself.
    P = np.concatenate(
        [
            P,
            [[0.1, 0.0, 4.5], [0.2, -0.01, 4.5], [-0.05, 0.03, -3.0], [0.0, 0.0, 5.0], [0.0, 0.0, -1.0]],
            [[3.0, -1e-9, 0.5], [3.0, 1e-9, -0.5], [1.0, -1e-6, 0.0]],
            R * P[:20] / np.linalg.norm(P[:20], axis=1)[:, None],
        ]
    )
    cp = s.closest_points(P)
    radius = np.linalg.norm(P, axis=1)
    np.testing.assert_allclose(cp.distances, np.abs(radius - R), rtol=0, atol=1e-11)
    np.testing.assert_allclose(cp.points, R * P / radius[:, None], rtol=0, atol=ALONG * radius.max())


def test_sphere_invert_of_its_own_points():
    s = sphere(2.0)
    rng = np.random.default_rng(3)
    u, v = rng.random(200), rng.random(200)
    u[:3], v[:3] = [0.0, 1.0, 0.3], [0.0, 1.0, 0.5]  # a pole, the other pole, the seam
    X = s.evaluate(u, v)
    uv = s.invert(X)
    np.testing.assert_allclose(s.evaluate(uv[:, 0], uv[:, 1]), X, rtol=0, atol=ON_CURVE)


def test_cylinder_closest_points_including_its_caps_edges():
    R, H = 1.5, 3.0
    s = cylinder(R, H)
    rng = np.random.default_rng(4)
    P = rng.uniform([-3, -3, -2], [3, 3, 5], (300, 3))
    cp = s.closest_points(P)
    rho = np.linalg.norm(P[:, :2], axis=1)
    z = np.clip(P[:, 2], 0.0, H)
    expected = np.column_stack([R * P[:, :2] / rho[:, None], z])
    np.testing.assert_allclose(cp.points, expected, rtol=0, atol=ALONG * 10)
    np.testing.assert_allclose(cp.parameters[:, 1], z / H, rtol=0, atol=ALONG * 10)


def test_plane_patch_boundary_and_corners():
    s = NurbsSurface([[[0, 0, 0], [0, 1, 0]], [[1, 0, 0], [1, 1, 0]]], [0, 0, 1, 1], [0, 0, 1, 1], 1, 1)
    P = np.array([[0.3, 0.6, 2.0], [2.0, 0.5, 1.0], [-1.0, -1.0, 0.5], [0.5, 3.0, -1.0], [1.5, 1.5, 0.0]])
    expected = np.array([[0.3, 0.6], [1.0, 0.5], [0.0, 0.0], [0.5, 1.0], [1.0, 1.0]])
    np.testing.assert_allclose(s.closest_parameters(P), expected, rtol=0, atol=1e-12)


def test_bilinear_patches_with_creases():
    # Degree 1 in both directions over 3 x 3 spans: C0 creases along every interior knot line.
    rng = np.random.default_rng(5)
    g = np.linspace(0, 3, 4)
    P = np.stack(np.meshgrid(g, g, indexing="ij"), axis=-1)
    P = np.concatenate([P, rng.uniform(-0.7, 0.7, (4, 4, 1))], axis=2)
    knots = [0, 0, 1 / 3, 2 / 3, 1, 1]
    s = NurbsSurface(P, knots, knots, 1, 1)
    Q = rng.uniform([-0.5, -0.5, -1.5], [3.5, 3.5, 1.5], (60, 3))
    cp = s.closest_points(Q)
    assert np.all(cp.distances <= brute_force_surface(s, Q) + TOL.linear)
    uv = rng.random((60, 2))
    X = s.evaluate(uv[:, 0], uv[:, 1])
    np.testing.assert_allclose(s.evaluate(*s.invert(X).T), X, rtol=0, atol=ON_CURVE)


def test_surface_invert_finds_a_point_behind_a_narrow_fold():
    # Minimised from a hypothesis failure: along v the distance to X has a second minimum 0.004 away
    # in space and 0.016 away in v, behind a bump of 0.003, much finer than the seed grid; the global
    # search lands on that one and inversion's local second search recovers X.
    P = np.array(
        [
            [[-4.58701659, -8.6164369, 5.45692347], [-6.37296413, -4.59729926, -2.37543315],
             [0.42525558, 1.31297104, -5.62524973], [-2.29212215, 3.27326233, -1.33118722],
             [-2.42164559, 6.26078814, -0.16287756]],
            [[8.21619275, -3.40271491, 8.40585092], [-6.94937512, -7.1893005, 4.83786736],
             [-2.37884971, -6.81744329, 7.69385129], [-4.21365641, 9.73824137, 0.8735169],
             [-8.95413607, 3.4236441, 4.17353236]],
            [[1.4763648, 6.28283276, -1.64372796], [3.77566122, 2.51455296, 9.05623858],
             [-2.42008799, 1.43983054, 9.30097609], [-0.04344071, -0.57901099, -0.98623449],
             [7.0157836, -9.8871003, -1.95893989]],
            [[-8.41185219, -9.54190897, -7.05203516], [1.53099202, -2.96250953, -0.95082135],
             [1.35602662, -7.52976539, 8.79838564], [7.72183416, 1.31135395, -4.34547039],
             [7.77513739, 4.39227158, -1.7946015]],
            [[-1.5169178, -5.86310634, 1.56133725], [-5.99164378, 2.02233912, -4.12750384],
             [-2.31699069, 9.15556357, -3.85459741], [5.25188602, -2.72194675, -6.40396424],
             [0.23861322, -6.21800269, -6.63415968]],
            [[-4.50633003, 5.22878386, 2.34459414], [9.2981377, -1.75736322, -1.71997876],
             [7.48006282, -4.77931551, -7.6745911], [6.70674341, 7.55352286, -3.90470037],
             [6.42541452, -7.78224321, 7.04304167]],
        ]
    )
    W = np.array(
        [
            [1.57105406, 0.83910513, 1.93737582, 0.344297, 2.62434122],
            [1.34724164, 1.26018627, 2.86197005, 1.42023542, 0.52244787],
            [1.989449, 1.03557301, 1.27816772, 1.37329356, 1.33994316],
            [1.65242307, 0.69018204, 2.95961982, 1.2641041, 1.56112369],
            [2.57733905, 1.91265259, 1.88593198, 1.55603363, 1.58968081],
            [0.32205405, 1.14052922, 0.96703703, 0.88381788, 0.3689589],
        ]
    )
    knots_u = [-0.09432057, 0.0, 0.16651848, 0.41865099, 0.71214966, 0.8922675, 1.0, 1.38184045]
    knots_v = [0.0, 0.0, 0.0, 0.0, 0.58034858, 1.0, 1.0, 1.0, 1.0]
    s = NurbsSurface(P, knots_u, knots_v, 1, 3, W)
    X = s.evaluate(0.05967775786797247, 0.9764312522261106)
    uv = s.invert(X[None, :])
    np.testing.assert_allclose(s.evaluate(uv[:, 0], uv[:, 1]), X[None, :], rtol=0, atol=ON_CURVE)


def test_inversion_second_search_recovers_from_a_nearby_local_answer(monkeypatch):
    # Make the global search answer a nearby wrong local point; inversion must still find the right one.
    c = NurbsCurve([[0, 0, 0], [1, 2, 0], [2, -1, 1], [3, 1, 0], [4, 0, 2]], [0, 0, 0, 0, 0.5, 1, 1, 1, 1], 3)
    s = sphere(2.0)
    curve_search, surface_search = projection.curve_closest_points, projection.surface_closest_points

    def curve_off(curve, points, tol=None):
        cp = curve_search(curve, points, tol)
        u = np.clip(cp.parameters + 0.03, *curve.domain)
        X = curve.evaluate(u)
        return ClosestPoints(u, X, np.linalg.norm(X - points, axis=-1))

    def surface_off(surface, points, tol=None):
        cp = surface_search(surface, points, tol)
        uv = np.clip(cp.parameters + [0.02, -0.03], 0.0, 1.0)
        X = surface.evaluate(uv[..., 0], uv[..., 1])
        return ClosestPoints(uv, X, np.linalg.norm(X - points, axis=-1))

    monkeypatch.setattr(projection, "curve_closest_points", curve_off)
    monkeypatch.setattr(projection, "surface_closest_points", surface_off)
    u = np.array([0.1, 0.45, 0.8])
    np.testing.assert_allclose(c.invert(c.evaluate(u)), u, rtol=0, atol=1e-9)
    uv = np.array([[0.1, 0.3], [0.6, 0.5], [0.9, 0.8]])
    X = s.evaluate(uv[:, 0], uv[:, 1])
    np.testing.assert_allclose(s.evaluate(*s.invert(X).T), X, rtol=0, atol=ON_CURVE)
    # Points really off the geometry still raise after the second search.
    with pytest.raises(ConvergenceError, match=r"curve inversion: 1 of 1 points"):
        c.invert(c.evaluate(u[:1]) + [0.0, 0.0, 0.1])


# ---------------------------------------------------------------------- surfaces: errors
def test_surface_invert_raises_for_points_off_the_surface_with_their_indices():
    s = sphere(2.0)
    X = s.evaluate(np.array([0.1, 0.4, 0.6]), np.array([0.2, 0.5, 0.7]))
    X[2] *= 1.25  # 0.5 off
    with pytest.raises(ConvergenceError, match=r"surface inversion: 1 of 3 points are farther than tol.linear") as info:
        s.invert(X)
    np.testing.assert_array_equal(info.value.indices, [2])
    np.testing.assert_allclose(info.value.residuals, [0.5], rtol=1e-12)


def test_surface_unconverged_points_raise(monkeypatch):
    s = sphere(2.0)
    monkeypatch.setattr(projection, "MAX_ITERATIONS", 0)
    with pytest.raises(ConvergenceError, match=r"surface_closest_points: \d+ of 2 points did not converge") as info:
        s.closest_points([[3.0, 0.4, 0.3], [-0.5, 2.5, 1.0]])
    assert info.value.indices.size >= 1 and info.value.residuals.shape == info.value.indices.shape


def test_surface_bad_points_raise():
    with pytest.raises(InvalidInputError, match=r"shape \(\.\.\., 3\) to match the geometry, got shape \(2, 2\)"):
        sphere().closest_points(np.zeros((2, 2)))
    with pytest.raises(InvalidInputError, match=r"points must be finite"):
        sphere().invert([[0.0, np.nan, 2.0]])


def test_surface_batch_shapes():
    s = sphere()
    P = np.random.default_rng(6).normal(size=(4, 2, 3))
    cp = s.closest_points(P)
    assert cp.parameters.shape == (4, 2, 2) and cp.points.shape == (4, 2, 3) and cp.distances.shape == (4, 2)
    assert s.closest_parameters(P[0, 0]).shape == (2,)


def test_duck_typed_surface_without_knots():
    class ExactSphere:
        """Longitude/latitude sphere of radius 2 with only ``domain_u/v`` and ``derivatives``."""

        domain_u = (0.0, 2 * np.pi)
        domain_v = (-np.pi / 2, np.pi / 2)

        def derivatives(self, u, v, order):
            u, v = np.broadcast_arrays(np.asarray(u, float), np.asarray(v, float))
            out = np.zeros(u.shape + (order + 1, order + 1, 3))
            for k in range(order + 1):
                for m in range(order + 1):
                    cu, su = np.cos(u + k * np.pi / 2), np.sin(u + k * np.pi / 2)
                    cv, sv = np.cos(v + m * np.pi / 2), np.sin(v + m * np.pi / 2)
                    out[..., k, m, 0] = 2 * cv * cu
                    out[..., k, m, 1] = 2 * cv * su
                    out[..., k, m, 2] = 2 * sv if k == 0 else 0.0
            return out

    P = np.array([[3.0, 1.0, 1.0], [-1.0, -2.0, 0.5], [0.0, 0.5, -4.0]])
    cp = projection.surface_closest_points(ExactSphere(), P)
    np.testing.assert_allclose(cp.points, 2 * P / np.linalg.norm(P, axis=1)[:, None], rtol=0, atol=ALONG * 10)
