"""Differential geometry: closed forms (circle, sphere, cylinder), Frenet–Serret against finite
differences, classical formulas and Euler's theorem on random surfaces, and every error branch."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from coons.errors import InvalidGeometryError, InvalidInputError
from coons.kernel import differential as dg
from coons.kernel.curve import NurbsCurve
from coons.kernel.surface import NurbsSurface
from coons.tolerance import Tolerance

from .exact_shapes import circle, cylinder, sphere
from .strategies import curves, params_in, surfaces

TOL = Tolerance()
#: Closed forms evaluated from exact rational NURBS: round-off only.
EXACT = 1e-12
#: Central differences with step H: error O(H^2) relative to the derivatives' scale.
H = 1e-5
FD = 1e-6








def helix_like(turns: float = 1.5, radius: float = 1.0, pitch: float = 0.8) -> NurbsCurve:
    """A cubic B-spline through points of a helix (not a helix: compare with its own derivatives)."""
    t = np.linspace(0.0, 2 * np.pi * turns, 14)
    P = np.column_stack([radius * np.cos(t), radius * np.sin(t), pitch * t / (2 * np.pi)])
    inner = np.linspace(0, 1, P.shape[0] - 2)[1:-1]
    return NurbsCurve(P, np.concatenate([[0] * 4, inner, [1] * 4]), 3)


def inner_params(domain, rng, m, margin=1e-3):
    lo, hi = domain
    return lo + margin + (hi - lo - 2 * margin) * rng.random(m)


# ---------------------------------------------------------------------- curvature and torsion: closed forms
def test_circle_curvature_is_one_over_radius_and_signed_in_2d():
    u = np.linspace(0, 1, 41)
    for R in (0.5, 2.0, 30.0):
        np.testing.assert_allclose(dg.curve_curvature(circle(R), u), 1 / R, rtol=EXACT)
        np.testing.assert_allclose(dg.curve_curvature(circle(R).reversed(), u), -1 / R, rtol=EXACT)
        np.testing.assert_allclose(dg.curve_curvature(circle(R, dim=3), u), 1 / R, rtol=EXACT)


def test_circle_torsion_is_zero_and_its_frame_points_to_the_centre():
    c = circle(2.0, dim=3)
    u = np.linspace(0, 1, 17)
    np.testing.assert_allclose(dg.curve_torsion(c, u), 0.0, atol=EXACT)
    F = dg.curve_frenet_frame(c, u)
    X = c.evaluate(u)
    np.testing.assert_allclose(F[:, 1], -X / 2.0, atol=EXACT)  # N towards the centre
    np.testing.assert_allclose(F[:, 2], np.broadcast_to([0, 0, 1], X.shape), atol=EXACT)  # counter-clockwise
    # The 2-D circle gives the same frame in the plane z = 0.
    np.testing.assert_allclose(dg.curve_frenet_frame(circle(2.0), u), F, atol=EXACT)


def test_tilted_circle_torsion_zero_curvature_constant():
    rng = np.random.default_rng(0)
    Q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    c = circle(3.0, dim=3).transformed(Q)
    u = rng.random(30)
    np.testing.assert_allclose(dg.curve_curvature(c, u), 1 / 3.0, rtol=1e-11)
    np.testing.assert_allclose(dg.curve_torsion(c, u), 0.0, atol=1e-11)


def test_helix_like_curvature_and_torsion_match_frenet_serret_differences():
    c = helix_like()
    u = np.linspace(0.05, 0.95, 19)
    F, Fp, Fm = dg.curve_frenet_frame(c, u), dg.curve_frenet_frame(c, u + H), dg.curve_frenet_frame(c, u - H)
    speed = np.linalg.norm(c.derivatives(u, 1)[:, 1], axis=1)
    dT = (Fp[:, 0] - Fm[:, 0]) / (2 * H)
    dB = (Fp[:, 2] - Fm[:, 2]) / (2 * H)
    N = F[:, 1]
    # T' = |C'| κ N and B' = -|C'| τ N.
    np.testing.assert_allclose(np.einsum("ij,ij->i", dT, N) / speed, dg.curve_curvature(c, u), rtol=FD)
    np.testing.assert_allclose(-np.einsum("ij,ij->i", dB, N) / speed, dg.curve_torsion(c, u), rtol=FD, atol=FD)
    # And the curve does twist like the right-handed helix it follows.
    assert np.all(dg.curve_torsion(c, u) > 0)


@given(curves(dims=(3,), max_degree=4, clamped=True), st.integers(0, 2**32 - 1))
def test_frenet_frame_is_orthonormal_right_handed_and_matches_curvature(c, seed):
    rng = np.random.default_rng(seed)
    u = params_in(c.domain, rng, 8)
    try:
        F = dg.curve_frenet_frame(c, u)
    except InvalidGeometryError:
        return  # a straight or singular piece: covered by its own tests
    np.testing.assert_allclose(np.einsum("...ij,...kj->...ik", F, F), np.broadcast_to(np.eye(3), F.shape), atol=1e-12)
    np.testing.assert_allclose(np.linalg.det(F), 1.0, atol=1e-12)
    D = c.derivatives(u, 2)
    np.testing.assert_allclose(F[:, 0], D[:, 1] / np.linalg.norm(D[:, 1], axis=1)[:, None], atol=1e-12)
    # C'' = (|C'|^2 κ) N + (d|C'|/du) T: its N component is the curvature times the speed squared.
    kappa = dg.curve_curvature(c, u)
    speed2 = np.einsum("ij,ij->i", D[:, 1], D[:, 1])
    np.testing.assert_allclose(np.einsum("ij,ij->i", D[:, 2], F[:, 1]), speed2 * kappa, rtol=1e-9, atol=1e-9)
    assert np.all(np.abs(np.einsum("ij,ij->i", D[:, 2], F[:, 2])) <= 1e-9 * (1 + np.linalg.norm(D[:, 2], axis=1)))


def test_signed_curvature_of_an_s_curve_changes_sign():
    c = NurbsCurve([[0, 0], [1, 1], [2, 0], [3, -1], [4, 0]], [0, 0, 0, 0, 0.5, 1, 1, 1, 1], 3)
    k = dg.curve_curvature(c, np.array([0.1, 0.9]))
    assert k[0] < 0 < k[1]  # turns right first, then left
    D = c.derivatives(np.array([0.1, 0.9]), 2)
    cross = D[:, 1, 0] * D[:, 2, 1] - D[:, 1, 1] * D[:, 2, 0]
    np.testing.assert_allclose(k, cross / np.linalg.norm(D[:, 1], axis=1) ** 3, rtol=1e-14)


def test_straight_line_curvature_torsion_and_frame():
    line = NurbsCurve([[0, 0, 0], [1, 2, 3], [3, 6, 9]], [0, 0, 0, 1, 1, 1], 2)  # non-uniform speed
    u = np.array([0.2, 0.5, 0.7])
    np.testing.assert_allclose(dg.curve_curvature(line, u), 0.0, atol=1e-15)
    np.testing.assert_array_equal(dg.curve_torsion(line, u), 0.0)  # documented convention
    with pytest.raises(InvalidGeometryError, match=r"the curve is straight at u = 0\.2 \(3 of 3 parameters"):
        dg.curve_frenet_frame(line, u)


def test_frame_raises_at_the_inflection_only():
    c = NurbsCurve([[0, 0, 0], [1, 1, 0], [2, 0, 0], [3, -1, 0], [4, 0, 0]], [0, 0, 0, 0, 0.5, 1, 1, 1, 1], 3)
    dg.curve_frenet_frame(c, [0.1, 0.9])
    with pytest.raises(InvalidGeometryError, match=r"straight at u = 0\.5 \(1 of 3 parameters"):
        dg.curve_frenet_frame(c, [0.1, 0.5, 0.9])  # the symmetric S bends neither way at 0.5


def test_zero_speed_raises():
    # Repeated first control points: C'(0) = 0.
    c = NurbsCurve([[0, 0, 0], [0, 0, 0], [1, 1, 0], [2, 0, 1]], [0, 0, 0, 0, 1, 1, 1, 1], 3)
    for fn in (dg.curve_curvature, dg.curve_torsion, dg.curve_frenet_frame):
        with pytest.raises(InvalidGeometryError, match=r"first derivative vanishes at u = 0\.0 \(1 of 2 parameters"):
            fn(c, [0.0, 0.5])
    assert np.isfinite(dg.curve_curvature(c, 0.5))


def test_curve_errors():
    with pytest.raises(InvalidInputError, match=r"curve_torsion needs a 3-D curve, got dimension 2"):
        dg.curve_torsion(circle(), 0.5)
    with pytest.raises(InvalidInputError, match=r"u: parameter 1\.5 is outside the domain \[0\.0, 1\.0\]"):
        dg.curve_curvature(circle(), [0.5, 1.5])
    c4 = NurbsCurve(np.eye(4)[:3], [0, 0, 0, 1, 1, 1], 2)
    with pytest.raises(InvalidInputError, match=r"needs a 2-D or 3-D curve, got dimension 4"):
        dg.curve_curvature(c4, 0.5)


def test_curvature_broadcasts_over_parameter_shapes():
    c = helix_like()
    u = np.linspace(0.1, 0.9, 6).reshape(2, 3)
    assert dg.curve_curvature(c, u).shape == (2, 3)
    assert dg.curve_torsion(c, u).shape == (2, 3)
    assert dg.curve_frenet_frame(c, u).shape == (2, 3, 3, 3)
    assert dg.curve_curvature(c, 0.3).shape == ()
    np.testing.assert_allclose(dg.curve_curvature(c, u).ravel(), dg.curve_curvature(c, u.ravel()), rtol=0, atol=0)


# ---------------------------------------------------------------------- arc length
def test_circle_length():
    for R in (0.3, 2.0, 50.0):
        np.testing.assert_allclose(dg.curve_length(circle(R)), 2 * np.pi * R, rtol=0, atol=TOL.linear)
        np.testing.assert_allclose(dg.curve_length(circle(R), 0.0, 0.25), np.pi * R / 2, rtol=0, atol=TOL.linear)


def test_line_length_and_empty_range():
    line = NurbsCurve([[0, 0, 0], [1, 2, 2], [3, 6, 6]], [0, 0, 0, 1, 1, 1], 2)
    np.testing.assert_allclose(dg.curve_length(line), 9.0, rtol=1e-14)
    assert dg.curve_length(line, 0.4, 0.4) == 0.0


@given(curves(max_degree=4), st.integers(0, 2**32 - 1))
def test_length_is_additive_and_invariant(c, seed):
    rng = np.random.default_rng(seed)
    a, m, b = np.sort(params_in(c.domain, rng, 3))
    whole = dg.curve_length(c, a, b)
    np.testing.assert_allclose(dg.curve_length(c, a, m) + dg.curve_length(c, m, b), whole, rtol=0, atol=2 * TOL.linear)
    lo, hi = c.domain
    reverse = dg.curve_length(c.reversed(), lo + hi - b, lo + hi - a)
    np.testing.assert_allclose(reverse, whole, rtol=0, atol=2 * TOL.linear)
    # Never shorter than the chord, and within the dense polyline's length (which is shorter).
    # Kinks (knots) are polyline vertices, so the polyline is exact for degree 1 and O(h^2) short otherwise.
    knots = np.unique(c.knots)
    X = c.evaluate(np.union1d(np.linspace(a, b, 4001), knots[(knots > a) & (knots < b)]))
    polyline = np.sum(np.linalg.norm(np.diff(X, axis=0), axis=1))
    assert np.linalg.norm(X[-1] - X[0]) <= whole + TOL.linear
    assert polyline <= whole + TOL.linear
    assert whole <= polyline * (1 + 1e-4) + TOL.linear


def test_length_errors():
    c = circle()
    with pytest.raises(InvalidInputError, match=r"start must not exceed end, got start = 0\.6 > end = 0\.2"):
        dg.curve_length(c, 0.6, 0.2)
    with pytest.raises(InvalidInputError, match=r"end: parameter 2\.0 is outside the domain"):
        dg.curve_length(c, 0.0, 2.0)

    class Ray:
        domain = (0.0, np.inf)

    with pytest.raises(InvalidInputError, match=r"an unbounded curve needs finite start and end, got \[0\.0, inf\]"):
        dg.curve_length(Ray())


# ---------------------------------------------------------------------- surfaces: closed forms
def test_sphere_normals_curvatures_and_umbilic_directions():
    R = 2.0
    s = sphere(R)
    rng = np.random.default_rng(1)
    u, v = rng.random(50), inner_params((0, 1), rng, 50)
    X = s.evaluate(u, v)
    np.testing.assert_allclose(dg.surface_normal(s, u, v), X / R, atol=EXACT)  # outward
    k = dg.surface_curvatures(s, u, v)
    np.testing.assert_allclose(k.gaussian, 1 / R**2, rtol=1e-10)
    np.testing.assert_allclose(k.mean, -1 / R, rtol=1e-10)  # bends away from the outward normal
    np.testing.assert_allclose(k.k1, -1 / R, rtol=1e-10)
    np.testing.assert_allclose(k.k2, -1 / R, rtol=1e-10)
    # Every point is umbilic: d1 follows Su.
    Su = s.derivatives(u, v, 1)[:, 1, 0]
    np.testing.assert_allclose(k.d1, Su / np.linalg.norm(Su, axis=1)[:, None], atol=EXACT)
    np.testing.assert_allclose(k.d2, np.cross(X / R, k.d1), atol=EXACT)


def test_sphere_pole_normals_are_the_limits():
    s = sphere(2.0)
    u = np.array([0.0, 0.3, 0.77, 1.0])
    np.testing.assert_allclose(dg.surface_normal(s, u, 0.0), np.broadcast_to([0, 0, -1.0], (4, 3)), atol=EXACT)
    np.testing.assert_allclose(dg.surface_normal(s, u, 1.0), np.broadcast_to([0, 0, 1.0], (4, 3)), atol=EXACT)
    ff = dg.surface_fundamental_forms(s, 0.3, 1.0)
    assert float(ff.E) == pytest.approx(0.0, abs=1e-20) and float(ff.F) == pytest.approx(0.0, abs=1e-20)
    assert float(ff.N) < 0  # second form with the limit normal: the meridian bends away from it
    with pytest.raises(InvalidGeometryError, match=r"degenerate parametrisation at \(u, v\) = \(0\.3, 1\.0\)"):
        dg.surface_curvatures(s, [0.3, 0.3], [0.5, 1.0])


def test_cylinder_curvatures_and_principal_directions():
    R = 1.5
    s = cylinder(R)
    rng = np.random.default_rng(2)
    u, v = rng.random(40), rng.random(40)
    k = dg.surface_curvatures(s, u, v)
    np.testing.assert_allclose(k.gaussian, 0.0, atol=1e-12)
    np.testing.assert_allclose(k.mean, -1 / (2 * R), rtol=1e-10)
    np.testing.assert_allclose(k.k1, 0.0, atol=1e-12)
    np.testing.assert_allclose(k.k2, -1 / R, rtol=1e-10)
    np.testing.assert_allclose(np.abs(k.d1[:, 2]), 1.0, atol=1e-12)  # along the axis (straight rulings)
    X = s.evaluate(u, v)
    tangential = np.cross([0, 0, 1.0], X * [1, 1, 0]) / R
    np.testing.assert_allclose(np.abs(np.einsum("ij,ij->i", k.d2, tangential)), 1.0, atol=1e-12)


@given(surfaces(max_degree=3), st.integers(0, 2**32 - 1))
def test_curvatures_agree_with_classical_formulas_and_euler(s, seed):
    rng = np.random.default_rng(seed)
    u, v = inner_params(s.domain_u, rng, 10), inner_params(s.domain_v, rng, 10)
    D = s.derivatives(u, v, 1)
    Su, Sv = D[:, 1, 0], D[:, 0, 1]
    keep = np.linalg.norm(np.cross(Su, Sv), axis=1) > 1e-6 * np.maximum(
        np.einsum("ij,ij->i", Su, Su), np.einsum("ij,ij->i", Sv, Sv)
    )
    u, v, Su, Sv = u[keep], v[keep], Su[keep], Sv[keep]
    if u.size == 0:
        return
    n = dg.surface_normal(s, u, v)
    np.testing.assert_allclose(np.linalg.norm(n, axis=1), 1.0, rtol=1e-14)
    assert np.all(np.abs(np.einsum("ij,ij->i", n, Su)) <= 1e-10 * np.linalg.norm(Su, axis=1))
    assert np.all(np.abs(np.einsum("ij,ij->i", n, Sv)) <= 1e-10 * np.linalg.norm(Sv, axis=1))
    f = dg.surface_fundamental_forms(s, u, v)
    k = dg.surface_curvatures(s, u, v)
    den = f.E * f.G - f.F**2
    scale = np.abs(k.k1) + np.abs(k.k2)
    assert _close(k.gaussian, (f.L * f.N - f.M**2) / den, 1e-9 * scale**2)
    assert _close(k.mean, (f.E * f.N - 2 * f.F * f.M + f.G * f.L) / (2 * den), 1e-9 * scale)
    assert np.all(k.k1 >= k.k2)
    # Principal directions: unit, orthogonal, tangent; normal curvature along them is k1, k2 (Euler).
    for d, kk in ((k.d1, k.k1), (k.d2, k.k2)):
        np.testing.assert_allclose(np.linalg.norm(d, axis=1), 1.0, rtol=1e-12)
        assert np.all(np.abs(np.einsum("ij,ij->i", d, n)) <= 1e-10)
        a, b = _tangent_coordinates(d, Su, Sv)
        kn = (f.L * a * a + 2 * f.M * a * b + f.N * b * b) / (f.E * a * a + 2 * f.F * a * b + f.G * b * b)
        assert _close(kn, kk, 1e-9 * scale)
    np.testing.assert_allclose(np.einsum("ij,ij->i", k.d1, k.d2), 0.0, atol=1e-12)
    # Any other tangent direction has a normal curvature between k2 and k1.
    a, b = rng.normal(size=(2, u.size))
    kn = (f.L * a * a + 2 * f.M * a * b + f.N * b * b) / (f.E * a * a + 2 * f.F * a * b + f.G * b * b)
    assert np.all((kn <= k.k1 + 1e-9 * scale) & (kn >= k.k2 - 1e-9 * scale))


def _close(actual, expected, atol) -> bool:
    """``|actual - expected| <= atol`` element-wise, with ``atol`` an array (relative to each point's curvatures)."""
    return bool(np.all(np.abs(actual - expected) <= atol))


def _tangent_coordinates(d, Su, Sv):
    """``(a, b)`` with ``d = a Su + b Sv`` for tangent vectors ``d`` (normal equations of the 3x2 system)."""
    E, F, G = (np.einsum("ij,ij->i", x, y) for x, y in ((Su, Su), (Su, Sv), (Sv, Sv)))
    p, q = np.einsum("ij,ij->i", d, Su), np.einsum("ij,ij->i", d, Sv)
    det = E * G - F * F
    return (G * p - F * q) / det, (E * q - F * p) / det


def test_normal_matches_finite_differences_of_the_surface():
    s = NurbsSurface(
        np.random.default_rng(3).normal(size=(4, 5, 3)), [0, 0, 0, 0.5, 1, 1, 1], [0, 0, 0, 0, 0.4, 1, 1, 1, 1], 2, 3,
        np.random.default_rng(4).uniform(0.5, 2, (4, 5)),
    )
    u, v = np.array([0.2, 0.55, 0.8]), np.array([0.3, 0.45, 0.9])  # away from knots: smooth differences
    Su = (s.evaluate(u + H, v) - s.evaluate(u - H, v)) / (2 * H)
    Sv = (s.evaluate(u, v + H) - s.evaluate(u, v - H)) / (2 * H)
    c = np.cross(Su, Sv)
    np.testing.assert_allclose(dg.surface_normal(s, u, v), c / np.linalg.norm(c, axis=1)[:, None], atol=FD)


def test_higher_order_degenerate_edge_uses_the_offset_normal():
    # Two collapsed rows at u = 0 (degree 2): Sv and Suv vanish there, so does the first-order limit.
    rng = np.random.default_rng(5)
    P = rng.normal(size=(4, 3, 3))
    P[0] = [0.0, 0.0, 0.0]
    P[1] = [1.0, 0.0, 0.0]
    s = NurbsSurface(P, [0, 0, 0, 0.5, 1, 1, 1], [0, 0, 0, 1, 1, 1], 2, 2)
    v = np.array([0.1, 0.5, 0.9])
    n0 = dg.surface_normal(s, 0.0, v)
    assert np.all(np.isfinite(n0))
    np.testing.assert_allclose(np.linalg.norm(n0, axis=1), 1.0, rtol=1e-14)
    # An approximation of the limit to O(offset), the offset about sqrt(tol.angular) here (Sv ~ u^2):
    # it agrees with the ordinary normal at u = 1e-3 to O(1e-3).
    np.testing.assert_allclose(n0, dg.surface_normal(s, 1e-3, v), atol=1e-2)


def test_collapsed_surface_raises_on_normal():
    s = NurbsSurface(np.ones((3, 3, 3)), [0, 0, 0, 1, 1, 1], [0, 0, 0, 1, 1, 1], 2, 2)
    with pytest.raises(InvalidGeometryError, match=r"no normal at \(u, v\) = \(0\.25, 0\.5\) \(1 of 1 parameters\)"):
        dg.surface_normal(s, 0.25, 0.5)


def test_surface_errors_and_broadcasting():
    s = sphere()
    assert dg.surface_normal(s, np.linspace(0, 1, 3)[:, None], np.linspace(0.1, 0.9, 4)).shape == (3, 4, 3)
    k = dg.surface_curvatures(s, 0.3, np.array([0.2, 0.4]))
    assert k.gaussian.shape == (2,) and k.d1.shape == (2, 3)
    with pytest.raises(ValueError, match="read-only"):
        k.k1[0] = 1.0
    with pytest.raises(InvalidInputError, match=r"u and v do not broadcast: shapes \(2,\) and \(3,\)"):
        dg.surface_normal(s, [0.1, 0.2], [0.1, 0.2, 0.3])
    with pytest.raises(InvalidInputError, match=r"v: parameter -0\.5 is outside the domain"):
        dg.surface_fundamental_forms(s, 0.1, -0.5)
    flat = NurbsSurface(np.zeros((2, 2, 2)) + [[[0, 0], [0, 1]], [[1, 0], [1, 1]]], [0, 0, 1, 1], [0, 0, 1, 1], 1, 1)
    with pytest.raises(InvalidInputError, match=r"needs a 3-D surface, got dimension 2"):
        dg.surface_normal(flat, 0.5, 0.5)


def test_duck_typed_analytic_surface():
    class Torus:
        """Angle-parametrised torus (R = 3, r = 1), only ``domain_u/v`` and ``derivatives``."""

        domain_u = domain_v = (0.0, 2 * np.pi)

        def derivatives(self, u, v, order):
            u, v = np.broadcast_arrays(np.asarray(u, float), np.asarray(v, float))
            out = np.zeros(u.shape + (order + 1, order + 1, 3))
            for k in range(order + 1):
                cu, su = np.cos(u + k * np.pi / 2), np.sin(u + k * np.pi / 2)
                for m in range(order + 1):
                    cv, sv = np.cos(v + m * np.pi / 2), np.sin(v + m * np.pi / 2)
                    radial = 3.0 + cv if m == 0 else cv
                    out[..., k, m, 0] = radial * cu
                    out[..., k, m, 1] = radial * su
                    out[..., k, m, 2] = sv if k == 0 else 0.0
            return out

    v = np.array([0.0, np.pi / 2, np.pi])
    k = dg.surface_curvatures(Torus(), 0.4, v)
    # Gaussian curvature of a torus: cos v / (r (R + r cos v)).
    np.testing.assert_allclose(k.gaussian, np.cos(v) / (3.0 + np.cos(v)), atol=1e-12)


def test_curve_and_surface_methods_delegate_here():
    c, s = helix_like(), sphere()
    u = np.array([0.2, 0.6])
    np.testing.assert_array_equal(c.curvature(u), dg.curve_curvature(c, u))
    np.testing.assert_array_equal(c.torsion(u), dg.curve_torsion(c, u))
    np.testing.assert_array_equal(c.frenet_frame(u), dg.curve_frenet_frame(c, u))
    assert c.length(0.2, 0.6) == dg.curve_length(c, 0.2, 0.6)
    np.testing.assert_array_equal(s.normal(u, u), dg.surface_normal(s, u, u))
    np.testing.assert_array_equal(s.fundamental_forms(u, u).N, dg.surface_fundamental_forms(s, u, u).N)
    np.testing.assert_array_equal(s.curvatures(u, u).d1, dg.surface_curvatures(s, u, u).d1)
