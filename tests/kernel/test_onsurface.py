"""Tests of coons.kernel.onsurface: p-curves of curves lying on surfaces."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from coons.errors import ConvergenceError, InvalidGeometryError, InvalidInputError
from coons.kernel.analytic import (
    Circle,
    ConicalSurface,
    CylindricalSurface,
    Ellipse,
    Line,
    PlanarSurface,
    SphericalSurface,
    ToroidalSurface,
)
from coons.kernel.curve import NurbsCurve
from coons.kernel.fitting import interpolate_curve, interpolate_surface
from coons.kernel.onsurface import pcurve_on, pcurves_on
from coons.kernel.pcurve import Line2D, Trig2D
from coons.tolerance import Tolerance

PI = math.pi
TOL = Tolerance()
#: Exact forms reproduce the curve to round-off of coordinates of size ~10.
EXACT = 1e-13


def _on(surface, pcurve, t):
    uv = pcurve.evaluate(t)
    return surface.evaluate(uv[..., 0], uv[..., 1])


def _check(surface, curve, t0, t1, pcurve, dev, bound):
    """The p-curve reproduces the curve within ``bound`` on dense samples, and ``dev`` says so."""
    t = np.linspace(t0, t1, 401)
    err = np.linalg.norm(_on(surface, pcurve, t) - curve.evaluate(t), axis=-1)
    assert err.max() <= bound
    assert 0.0 <= dev <= bound


# ---------------------------------------------------------------------------- exact forms
PLANE = PlanarSurface([1, 2, 3], [1, 1, 1], [1, 0, 0])


@pytest.mark.parametrize(
    "curve, t0, t1, kind",
    [
        (Line([1, 2, 3], [1, -1, 0]), -2.0, 5.0, Line2D),
        (Line([3, 2, 1], [0, 1, -1]), 10.0, 11.0, Line2D),
        (Circle([1, 2, 3], [1, 1, 1], [0, 1, -1], 2.0), 0.0, 2 * PI, Trig2D),
        (Circle([2, 2, 2], [-1, -1, -1], [0, 1, -1], 0.5), 1.0, 3.0, Trig2D),
        (Ellipse([1, 2, 3], [-1, -1, -1], [0, 1, -1], 2.0, 1.0), 1.0, 4.0, Trig2D),
    ],
)
def test_plane_lines_and_conics_are_exact(curve, t0, t1, kind):
    pc, dev = pcurve_on(PLANE, curve, t0, t1)
    assert isinstance(pc, kind)
    _check(PLANE, curve, t0, t1, pc, dev, EXACT)


def test_plane_circle_pcurve_is_a_circle_of_the_same_radius():
    # The plane's parameters are an isometry: the Trig2D axes are orthogonal, of length R.
    pc, _ = pcurve_on(PLANE, Circle([1, 2, 3], [1, 1, 1], [0, 1, -1], 2.0), 0.0, 2 * PI)
    np.testing.assert_allclose(np.linalg.norm(pc.a), 2.0, rtol=0, atol=EXACT)
    np.testing.assert_allclose(np.linalg.norm(pc.b), 2.0, rtol=0, atol=EXACT)
    np.testing.assert_allclose(pc.a @ pc.b, 0.0, rtol=0, atol=EXACT)
    np.testing.assert_allclose(pc.center, [0.0, 0.0], rtol=0, atol=EXACT)


CYL = CylindricalSurface([0, 0, 0], [0, 0, 1], [1, 0, 0], 2.0)


def test_cylinder_ruling_is_a_v_line():
    pc, dev = pcurve_on(CYL, Line([0, 2, 0], [0, 0, -1]), -1.0, 3.0)
    assert isinstance(pc, Line2D)
    np.testing.assert_allclose(pc.direction, [0.0, -1.0], rtol=0, atol=EXACT)
    np.testing.assert_allclose(pc.origin, [PI / 2, 0.0], rtol=0, atol=EXACT)
    _check(CYL, Line([0, 2, 0], [0, 0, -1]), -1.0, 3.0, pc, dev, EXACT)


def test_cylinder_coaxial_circle_reversed_sense():
    # The circle's axis is -Z: u decreases with t.
    circle = Circle([0, 0, 1], [0, 0, -1], [0, 1, 0], 2.0)
    pc, dev = pcurve_on(CYL, circle, 0.0, 2 * PI)
    assert isinstance(pc, Line2D)
    np.testing.assert_allclose(pc.direction, [-1.0, 0.0], rtol=0, atol=EXACT)
    np.testing.assert_allclose(pc.origin[1], 1.0, rtol=0, atol=EXACT)
    _check(CYL, circle, 0.0, 2 * PI, pc, dev, EXACT)


def test_cone_ruling_and_parallel():
    cone = ConicalSurface([0, 0, 0], [0, 0, 1], [1, 0, 0], 1.0, 0.3)
    v = 2.0
    circle = Circle([0, 0, v * math.cos(0.3)], [0, 0, 1], [1, 0, 0], 1 + v * math.sin(0.3))
    pc, dev = pcurve_on(cone, circle, 0.0, 2 * PI)
    assert isinstance(pc, Line2D)
    np.testing.assert_allclose(pc.direction, [1.0, 0.0], rtol=0, atol=EXACT)
    np.testing.assert_allclose(pc.origin, [0.0, v], rtol=0, atol=EXACT)
    _check(cone, circle, 0.0, 2 * PI, pc, dev, EXACT)
    p0, p1 = cone.evaluate(0.7, -1.0), cone.evaluate(0.7, 2.0)
    ruling = Line(p0, p1 - p0)
    pc, dev = pcurve_on(cone, ruling, 0.0, 3.0)
    assert isinstance(pc, Line2D)
    # The cone's v is arc length along the ruling, as is the line's t.
    np.testing.assert_allclose(pc.direction, [0.0, 1.0], rtol=0, atol=EXACT)
    np.testing.assert_allclose(pc.origin, [0.7, -1.0], rtol=0, atol=EXACT)
    _check(cone, ruling, 0.0, 3.0, pc, dev, EXACT)


SPHERE = SphericalSurface([0, 0, 0], [0, 0, 1], [1, 0, 0], 2.0)


def test_sphere_parallel():
    circle = Circle([0, 0, 1], [0, 0, 1], [1, 0, 0], math.sqrt(3))
    pc, dev = pcurve_on(SPHERE, circle, 0.0, 2 * PI)
    assert isinstance(pc, Line2D)
    np.testing.assert_allclose(pc.origin, [0.0, PI / 6], rtol=0, atol=EXACT)
    np.testing.assert_allclose(pc.direction, [1.0, 0.0], rtol=0, atol=EXACT)
    _check(SPHERE, circle, 0.0, 2 * PI, pc, dev, EXACT)


@pytest.mark.parametrize("t0, t1", [(0.0, PI / 2), (-PI / 2, PI / 2), (-PI / 2, 0.0)])
def test_sphere_meridian_to_the_poles_is_a_v_line(t0, t1):
    # At the pole u is undetermined: it must follow the meridian (u = 0), not the projection's choice.
    meridian = Circle([0, 0, 0], [0, -1, 0], [1, 0, 0], 2.0)
    pc, dev = pcurve_on(SPHERE, meridian, t0, t1)
    assert isinstance(pc, Line2D)
    np.testing.assert_allclose(pc.origin, [0.0, 0.0], rtol=0, atol=EXACT)
    np.testing.assert_allclose(pc.direction, [0.0, 1.0], rtol=0, atol=EXACT)
    _check(SPHERE, meridian, t0, t1, pc, dev, EXACT)


def test_sphere_meridian_on_the_far_side_has_u_pi():
    meridian = Circle([0, 0, 0], [0, 1, 0], [-1, 0, 0], 2.0)  # x = -2 cos t, z = 2 sin t
    pc, dev = pcurve_on(SPHERE, meridian, 0.0, PI / 2)
    assert isinstance(pc, Line2D)
    np.testing.assert_allclose(pc.origin, [PI, 0.0], rtol=0, atol=EXACT)
    np.testing.assert_allclose(pc.direction, [0.0, 1.0], rtol=0, atol=EXACT)


def test_torus_parallel_and_meridian():
    torus = ToroidalSurface([0, 0, 0], [0, 0, 1], [1, 0, 0], 3.0, 1.0)
    top = Circle([0, 0, 1], [0, 0, 1], [1, 0, 0], 3.0)
    pc, dev = pcurve_on(torus, top, 0.0, 2 * PI)
    assert isinstance(pc, Line2D)
    np.testing.assert_allclose(pc.origin, [0.0, PI / 2], rtol=0, atol=EXACT)
    _check(torus, top, 0.0, 2 * PI, pc, dev, EXACT)
    meridian = Circle([3, 0, 0], [0, -1, 0], [1, 0, 0], 1.0)
    pc, dev = pcurve_on(torus, meridian, 0.0, 2 * PI)
    assert isinstance(pc, Line2D)
    np.testing.assert_allclose(pc.direction, [0.0, 1.0], rtol=0, atol=EXACT)
    _check(torus, meridian, 0.0, 2 * PI, pc, dev, EXACT)


# ---------------------------------------------------------------------------- periodic parameters
def test_seam_crossing_is_unwrapped():
    # A ruling-free arc crossing u = 0: u must run continuously through 0 (not jump by 2π).
    circle = Circle([0, 0, 0.5], [0, 0, 1], [1, 0, 0], 2.0)
    pc, dev = pcurve_on(CYL, circle, -1.0, 1.0)
    u = pc.evaluate(np.linspace(-1.0, 1.0, 50))[:, 0]
    assert np.all(np.diff(u) > 0)
    assert u[-1] - u[0] == pytest.approx(2.0, abs=EXACT)


@pytest.mark.parametrize("box_u, expected_start", [((PI, 2 * PI), PI), ((3 * PI, 4 * PI), 3 * PI), ((-PI, 0), -PI)])
def test_box_shifts_by_whole_periods(box_u, expected_start):
    circle = Circle([0, 0, 0.5], [0, 0, 1], [1, 0, 0], 2.0)
    pc, _ = pcurve_on(CYL, circle, PI, 2 * PI, box=(box_u, (-1.0, 1.0)))
    np.testing.assert_allclose(pc.evaluate([PI, 2 * PI])[:, 0], [expected_start, expected_start + PI], atol=EXACT)


def test_box_shift_of_a_fitted_pcurve():
    n = np.array([1.0, 1.0, 1.0]) / math.sqrt(3)
    circle = Circle(n, n, [1, -1, 0], math.sqrt(3))  # an oblique small circle: no exact form
    pc0, _ = pcurve_on(SPHERE, circle, 0.0, 2 * PI)
    pc1, _ = pcurve_on(SPHERE, circle, 0.0, 2 * PI, box=((2 * PI, 4 * PI), (-PI / 2, PI / 2)))
    t = np.linspace(0.0, 2 * PI, 33)
    d = pc1.evaluate(t) - pc0.evaluate(t)
    # The same p-curve up to a whole number of periods in u.
    k = np.round(d[:, 0] / (2 * PI))
    np.testing.assert_allclose(d[:, 0], k * 2 * PI, rtol=0, atol=1e-9)
    np.testing.assert_allclose(d[:, 1], 0.0, rtol=0, atol=1e-9)
    u = pc1.evaluate(t)[:, 0]
    assert 2 * PI <= 0.5 * (u.min() + u.max()) <= 4 * PI


# ---------------------------------------------------------------------------- fitted p-curves
@settings(max_examples=12)
@given(
    tilt=st.floats(0.2, 1.2),
    linear=st.sampled_from([1e-7, 1e-5]),
)
def test_oblique_plane_cylinder_ellipse_within_tolerance(tilt, linear):
    # The section of the cylinder x² + y² = 4 by the plane z = tan(tilt) x: u = t, v = 2 tan(tilt) cos t.
    tol = Tolerance(linear=linear)
    a = 2.0 / math.cos(tilt)
    normal = np.array([-math.sin(tilt), 0.0, math.cos(tilt)])
    ellipse = Ellipse([0, 0, 0], normal, [math.cos(tilt), 0, math.sin(tilt)], a, 2.0)
    pc, dev = pcurve_on(CYL, ellipse, 0.0, 2 * PI, tol=tol)
    assert isinstance(pc, NurbsCurve)
    assert pc.domain == pytest.approx((0.0, 2 * PI), abs=0)
    t = np.linspace(0.0, 2 * PI, 997)
    err = np.linalg.norm(_on(CYL, pc, t) - ellipse.evaluate(t), axis=-1)
    # Check samples are midpoints; the dense error may exceed them by the interpolant's wiggle.
    assert err.max() <= 2 * linear
    assert dev <= linear
    # A 3-D error e moves u by e / R = e / 2 and v by e.
    np.testing.assert_allclose(pc.evaluate(t)[:, 0], t, rtol=0, atol=linear)
    np.testing.assert_allclose(pc.evaluate(t)[:, 1], 2 * math.tan(tilt) * np.cos(t), rtol=0, atol=2 * linear)


def _bump():
    g = np.linspace(0.0, 1.0, 6)
    X, Y = np.meshgrid(g, g, indexing="ij")
    return interpolate_surface(np.stack([X, Y, 0.3 * np.sin(3 * X) * np.cos(2 * Y)], axis=-1), 3, 3)


def test_nurbs_surface_curve_recovers_the_parameter_path():
    surface = _bump()
    t = np.linspace(0.0, 1.0, 200)
    uv = np.stack([0.1 + 0.8 * t, 0.2 + 0.5 * t**2], axis=1)
    curve = interpolate_curve(surface.evaluate(uv[:, 0], uv[:, 1]), 3, params=t)
    pc, dev = pcurve_on(surface, curve, 0.0, 1.0)
    assert dev <= TOL.linear
    _check(surface, curve, 0.0, 1.0, pc, dev, 2 * TOL.linear)
    np.testing.assert_allclose(pc.evaluate(t), uv, rtol=0, atol=1e-6)


def test_nurbs_iso_curve_is_exact():
    surface = _bump()
    iso = surface.iso_curve("u", 0.4)
    pc, dev = pcurve_on(surface, iso, *iso.domain)
    assert isinstance(pc, Line2D)
    np.testing.assert_allclose(pc.origin, [0.4, 0.0], rtol=0, atol=EXACT)
    np.testing.assert_allclose(pc.direction, [0.0, 1.0], rtol=0, atol=EXACT)


def test_closed_nurbs_sphere_seam_and_pole():
    # The exact NURBS sphere: the meridian u = 0 is its seam (points project to u = 0 or u = 2π)
    # and reaches the degenerate pole edge.
    nurbs = SPHERE.to_nurbs()
    meridian = Circle([0, 0, 0], [0, -1, 0], [1, 0, 0], 2.0)
    pc, dev = pcurve_on(nurbs, meridian, 0.1, PI / 2)
    assert dev <= TOL.linear
    u = pc.evaluate(np.linspace(0.1, PI / 2, 50))[:, 0]
    assert np.ptp(u) <= 1e-9
    _check(nurbs, meridian, 0.1, PI / 2, pc, dev, 2 * TOL.linear)


# ---------------------------------------------------------------------------- errors
def test_curve_off_the_surface_raises_with_distance():
    with pytest.raises(InvalidGeometryError, match=r"not on the SphericalSurface: distance 0\.1"):
        pcurve_on(SPHERE, Circle([0, 0, 0], [0, -1, 0], [1, 0, 0], 2.1), 0.0, 1.0)


def test_discontinuous_pcurve_raises():
    # A meridian across the north pole: u jumps by π there.
    with pytest.raises(ConvergenceError, match="is the p-curve continuous") as info:
        pcurve_on(SPHERE, Circle([0, 0, 0], [0, -1, 0], [1, 0, 0], 2.0), 0.0, PI)
    assert info.value.residuals[0] > TOL.linear


@pytest.mark.parametrize("t0, t1", [(1.0, 1.0), (2.0, 1.0), (0.0, math.inf), (math.nan, 1.0)])
def test_bad_range_raises(t0, t1):
    with pytest.raises(InvalidInputError, match="need finite t0 < t1"):
        pcurve_on(CYL, Line([0, 2, 0], [0, 0, 1]), t0, t1)


def test_non_numeric_range_raises():
    with pytest.raises(InvalidInputError, match="must be numbers"):
        pcurve_on(CYL, Line([0, 2, 0], [0, 0, 1]), "a", 1.0)


@pytest.mark.parametrize("box", [((0, 1),), ((1, 0), (0, 1)), "x", ((0, math.nan), (0, 1))])
def test_bad_box_raises(box):
    with pytest.raises(InvalidInputError, match=r"box must be \(\(u0, u1\), \(v0, v1\)\)"):
        pcurve_on(CYL, Line([0, 2, 0], [0, 0, 1]), 0.0, 1.0, box=box)


def test_two_dimensional_curve_raises():
    curve2d = NurbsCurve([[0.0, 0.0], [1.0, 1.0]], [0, 0, 1, 1], 1)
    with pytest.raises(InvalidInputError, match="curve must be 3-D, got points of dimension 2"):
        pcurve_on(CYL, curve2d, 0.0, 1.0)


def test_object_without_evaluate_raises():
    with pytest.raises(InvalidInputError, match="need evaluate"):
        pcurve_on(object(), Line([0, 2, 0], [0, 0, 1]), 0.0, 1.0)


# ---------------------------------------------------------------------------- batches (pcurves_on)
def _bilinear(z11=0.0):
    from coons.kernel.surface import NurbsSurface

    cp = np.array([[[0.0, 0.0, 0.0], [0.0, 2.0, 0.0]], [[3.0, 0.0, 0.0], [3.0, 2.0, z11]]])
    return NurbsSurface(cp, [0, 0, 1, 1], [0, 0, 1, 1], 1, 1)


def test_pcurves_on_bilinear_boundary_lines_are_exact_iso_lines():
    # The four boundary edges of a bilinear patch (a B-spline box face): cheap path, Line2D whose
    # constant coordinate is exactly the domain boundary, same parameter as the 3-D line.
    S = _bilinear(0.5)
    P = S.evaluate(np.array([0.0, 1.0, 1.0, 0.0]), np.array([0.0, 0.0, 1.0, 1.0]))
    items = []
    for q in range(4):
        a, b = P[q], P[(q + 1) % 4]
        L = float(np.linalg.norm(b - a))
        items.append((Line(a, b - a), 0.0, L))
    out = pcurves_on(S, items)
    iso = [(1, 0.0), (0, 1.0), (1, 1.0), (0, 0.0)]  # (constant coordinate, value) per edge
    for (curve, t0, t1), (pc, dev), (k, value) in zip(items, out, iso):
        assert isinstance(pc, Line2D)
        assert pc.origin[k] == value and pc.direction[k] == 0.0
        _check(S, curve, t0, t1, pc, dev, 1e-12)  # the boundary of a bilinear patch is straight
        ref, _ = pcurve_on(S, curve, t0, t1)
        np.testing.assert_allclose(pc.evaluate(np.linspace(t0, t1, 9)), ref.evaluate(np.linspace(t0, t1, 9)),
                                   rtol=0, atol=1e-9)


def test_pcurves_on_matches_pcurve_on_for_every_kind():
    # NURBS: an iso-curve (cheap path), a curved parameter path (general path); cylinder: a ruling,
    # a coaxial circle (cheap path), an oblique ellipse (general path, Trig2D); with a box.
    surface = _bump()
    t = np.linspace(0.0, 1.0, 200)
    path = interpolate_curve(surface.evaluate(0.1 + 0.8 * t, 0.2 + 0.5 * t**2), 3, params=t)
    iso = surface.iso_curve("u", 0.4)
    cases = [
        (surface, [(iso, *iso.domain), (path, 0.0, 1.0)], None),
        (CYL, [(Line([0, 2, 0], [0, 0, -1]), -1.0, 3.0), (Circle([0, 0, 1], [0, 0, -1], [1, 0, 0], 2.0), 0.5, 5.0),
               (Ellipse([0, 0, 0], [0, -math.sin(0.3), math.cos(0.3)], [0, math.cos(0.3), math.sin(0.3)], 2.0 / math.cos(0.3), 2.0),
                0.0, 2.0)],
         ((4 * PI, 6 * PI), (-10.0, 10.0))),
    ]
    for S, items, box in cases:
        got = pcurves_on(S, items, box)
        for (curve, t0, t1), (pc, dev) in zip(items, got):
            ref, ref_dev = pcurve_on(S, curve, t0, t1, box)
            assert type(pc) is type(ref)
            s = np.linspace(t0, t1, 33)
            np.testing.assert_allclose(pc.evaluate(s), ref.evaluate(s), rtol=0, atol=1e-9)
            _check(S, curve, t0, t1, pc, dev, 2 * TOL.linear)
    cheap = pcurves_on(CYL, cases[1][1], cases[1][2], general=False)
    assert isinstance(cheap[0][0], Line2D) and isinstance(cheap[1][0], Line2D) and cheap[2] is None
    assert 4 * PI <= cheap[1][0].evaluate(0.5)[0] <= 6 * PI  # shifted into the box by whole periods


def test_pcurves_on_errors_are_pcurve_on_errors():
    with pytest.raises(InvalidGeometryError, match=r"not on the SphericalSurface: distance 0\.1"):
        pcurves_on(SPHERE, [(Circle([0, 0, 0], [0, -1, 0], [1, 0, 0], 2.1), 0.0, 1.0)])
    with pytest.raises(InvalidGeometryError, match=r"not on the NurbsSurface"):
        pcurves_on(_bilinear(), [(Line([0, 0, 1], [1, 0, 0]), 0.0, 1.0)])
    with pytest.raises(InvalidInputError, match="need finite t0 < t1"):
        pcurves_on(CYL, [(Line([0, 2, 0], [0, 0, 1]), 1.0, 1.0)])


def test_pcurve_on_nurbs_boundary_stays_in_the_domain():
    # A p-curve along a domain boundary must not leave the domain by round-off (the checker's
    # NURBS evaluation refuses that): moved inside, deviation measured again.
    from coons.kernel.onsurface import _into_domain

    S = _bilinear()
    curve = Line([0.0, 0.0, 0.0], [0.0, 1.0, 0.0])
    over = Line2D([-2e-11, 0.0], [1e-12, 0.5])
    pc, dev = _into_domain(S, curve, over, 0.0, 0.0, 2.0, TOL)
    assert pc.origin[0] == 0.0 and pc.direction[0] == 0.0 and dev <= 1e-10
    far = Line2D([-1e-3, 0.0], [0.0, 0.5])  # not round-off: left for the checks to report
    assert _into_domain(S, curve, far, 0.0, 0.0, 2.0, TOL)[0] is far
    nc = NurbsCurve(np.array([[-3e-11, 0.0], [1e-12, 0.5], [0.0, 1.0 + 4e-11]]), [0, 0, 0, 2, 2, 2], 2)
    pc, dev = _into_domain(S, curve, nc, 0.0, 0.0, 2.0, TOL)
    assert pc.control_points.min() >= 0.0 and pc.control_points.max() <= 1.0 and dev <= 1e-9


def test_closed_nurbs_with_an_unbounded_box_is_finite():
    # An infinite box says nothing: a closed NURBS is unwrapped towards its domain (no NaN).
    nurbs = SPHERE.to_nurbs()
    meridian = Circle([0, 0, 0], [0, -1, 0], [1, 0, 0], 2.0)
    inf = ((-math.inf, math.inf), (-math.inf, math.inf))
    pc, dev = pcurve_on(nurbs, meridian, 0.1, PI / 2, inf)
    ref, _ = pcurve_on(nurbs, meridian, 0.1, PI / 2)
    s = np.linspace(0.1, PI / 2, 20)
    assert np.all(np.isfinite(pc.evaluate(s)))
    np.testing.assert_allclose(pc.evaluate(s), ref.evaluate(s), rtol=0, atol=1e-12)
    _check(nurbs, meridian, 0.1, PI / 2, pc, dev, 2 * TOL.linear)


@given(st.integers(0, 2**32 - 1))
def test_unwrap_rows_is_numpy_unwrap_with_a_period_per_row(seed):
    from coons.kernel.onsurface import _unwrap_rows

    rng = np.random.default_rng(seed)
    col = rng.uniform(-20.0, 20.0, (12, 30))
    col[:, 5] = col[:, 4] + math.pi  # a jump of exactly half of 2π: numpy's tie rule
    per = rng.choice([2.0 * math.pi, 1.0, 3.0], 12)
    want = np.stack([np.unwrap(col[i], period=per[i]) for i in range(12)])
    np.testing.assert_array_equal(_unwrap_rows(col, per), want)


def test_cheap_pcurves_many_over_mixed_structures_matches_one_surface_at_a_time():
    # Bilinear patches (one structure, seeded as one batch) and a bicubic bump (another), with the
    # bump's iso-curve and boundary lines: the batch gives each request what pcurves_on gives it alone.
    from coons.kernel.onsurface import cheap_pcurves_many

    patches = [_bilinear(z) for z in (0.0, 0.5, -0.7)]
    requests = []
    for S in patches:
        P = S.evaluate(np.array([0.0, 1.0, 1.0, 0.0]), np.array([0.0, 0.0, 1.0, 1.0]))
        requests.append((S, [(Line(P[q], P[(q + 1) % 4] - P[q]), 0.0, float(np.linalg.norm(P[(q + 1) % 4] - P[q])))
                             for q in range(4)], None))
    bump = _bump()
    iso = bump.iso_curve("v", 0.3)
    requests.insert(1, (bump, [(iso, *iso.domain)], None))
    got = cheap_pcurves_many(requests)
    for (S, items, box), out in zip(requests, got):
        alone = pcurves_on(S, items, box, general=False)
        assert len(out) == len(alone) == len(items)
        for (curve, t0, t1), (pc, dev), (ref, ref_dev) in zip(items, out, alone):
            assert isinstance(pc, Line2D)
            s = np.linspace(t0, t1, 17)
            np.testing.assert_allclose(pc.evaluate(s), ref.evaluate(s), rtol=0, atol=1e-12)
            _check(S, curve, t0, t1, pc, dev, 2 * TOL.linear)


def test_line2d_many_is_the_constructor_row_by_row():
    O = np.array([[0.0, 1.0], [2.5, -3.0]])
    D = np.array([[1.0, 0.0], [0.5, 0.25]])
    lines = Line2D.many(O, D)
    for o, d, ln in zip(O, D, lines):
        ref = Line2D(o, d)
        np.testing.assert_array_equal(ln.evaluate([0.0, 2.0]), ref.evaluate([0.0, 2.0]))
        assert not ln.origin.flags.writeable and not ln.direction.flags.writeable
    O[0, 0] = 99.0  # the lines hold copies
    assert lines[0].origin[0] == 0.0
    assert Line2D.many(np.empty((0, 2)), np.empty((0, 2))) == []
    with pytest.raises(InvalidGeometryError, match="row 1"):
        Line2D.many(O, [[1.0, 0.0], [0.0, 0.0]])
    with pytest.raises(InvalidGeometryError, match="row 0"):
        Line2D.many([[math.nan, 0.0]], [[1.0, 0.0]])
    with pytest.raises(InvalidGeometryError, match="shapes"):
        Line2D.many(np.zeros((2, 3)), np.zeros((2, 3)))


# ====================================================================== batched curve evaluation
def test_curve_derivatives_are_each_curves_own():
    """curve_derivatives (lines, circles, Line2D and Trig2D in one expression per type, others one by
    one) gives each curve's own derivatives; the points of lines, circles and straight and
    trigonometric p-curves are their own bit for bit (the Booleans' passes compare them exactly)."""
    from coons.kernel.onsurface import curve_derivatives, evaluate_curves

    rng = np.random.default_rng(3)
    space = []
    for _ in range(4):
        o, d, x = rng.normal(size=3), rng.normal(size=3), rng.normal(size=3)
        space += [Line(o, d), Circle(o, d, x, rng.uniform(0.5, 3.0)), Ellipse(o, d, x, 3.0, rng.uniform(0.5, 2.5))]
    space.append(NurbsCurve([[0, 0, 0], [1, 3, 1], [2, -3, 0], [3, 1, 2]], [0, 0, 0, 0, 1, 1, 1, 1], 3))
    plane = [Line2D(rng.normal(size=2), rng.normal(size=2)), Trig2D([0.3, -0.2], [2.0, 0.5], [-0.3, 1.0]),
             NurbsCurve([[0, 0], [1, 3], [2, -3], [3, 1]], [0, 0, 0, 0, 1, 1, 1, 1], 3)]
    for curves in (space, plane, space[2:]):  # (the last batch starts with a curve called one by one)
        T = rng.uniform(0.0, 1.0, (len(curves), 5))
        D = curve_derivatives(curves, T, 3)
        assert D.shape == (len(curves), 5, 4, 3 if curves is not plane else 2)
        for c, t, got in zip(curves, T, D):
            np.testing.assert_allclose(got, c.derivatives(t, 3), rtol=0, atol=1e-12)
    T = rng.uniform(-5.0, 5.0, (len(space) - 1, 7))
    X = evaluate_curves(space[:-1], T)
    for c, t, got in zip(space[:-1], T, X):
        if isinstance(c, (Line, Circle)):
            assert np.array_equal(got, c.evaluate(t))
    T = rng.uniform(-5.0, 5.0, (2, 7))
    for c, t, got in zip(plane[:2], T, curve_derivatives(plane[:2], T, 0)[:, :, 0]):
        assert np.array_equal(got, c.evaluate(t))
    with pytest.raises(InvalidInputError, match="is not 3-D"):
        curve_derivatives([space[0], plane[1]], np.zeros((2, 1)), 1)
    with pytest.raises(InvalidInputError, match="one row of parameters per curve"):
        curve_derivatives(space[:1], np.zeros((2, 3)))
    with pytest.raises(InvalidInputError, match="finite"):
        curve_derivatives(plane, np.full((3, 1), np.nan))


@pytest.mark.parametrize("order", [0, 1, 2, 5])
def test_curve_derivatives_by_coordinate_is_the_broadcast_form(monkeypatch, order):
    """Large batches are evaluated coordinate by coordinate, small ones broadcast over ``(k, n, d)``:
    the same floats bit for bit, for every batched type, in batches of one type and mixed."""
    from coons.kernel import onsurface

    rng = np.random.default_rng(11)
    space, plane = [], []
    for _ in range(6):
        o, d, x = rng.normal(size=3), rng.normal(size=3), rng.normal(size=3)
        space += [Line(o, d), Circle(o, d, x, rng.uniform(0.5, 3.0))]
        plane += [Line2D(rng.normal(size=2), rng.normal(size=2)),
                  Trig2D(rng.normal(size=2), [2.0, rng.uniform(-1, 1)], [rng.uniform(-1, 1), 1.5])]
    for curves in (space, space[1::2], plane, plane[1::2], space[:5]):
        T = rng.uniform(-7.0, 7.0, (len(curves), 9))
        monkeypatch.setattr(onsurface, "_COORDINATE_POINTS", 1 << 30)
        broadcast = onsurface.curve_derivatives(curves, T, order)
        monkeypatch.setattr(onsurface, "_COORDINATE_POINTS", 1)
        by_coordinate = onsurface.curve_derivatives(curves, T, order)
        assert np.array_equal(broadcast, by_coordinate)
        for c, t, got in zip(curves, T, broadcast):  # (and each curve's own points, bit for bit)
            assert np.array_equal(got[:, 0], c.evaluate(t))


def test_trig2d_many_is_the_constructor_row_by_row():
    from coons.kernel.pcurve import Trig2D

    C = np.array([[0.0, 1.0], [2.5, -3.0]])
    A = np.array([[1.0, 0.0], [0.5, 0.25]])
    B = np.array([[0.0, 2.0], [-0.25, 0.5]])
    curves = Trig2D.many(C, A, B)
    t = np.array([0.0, 0.7, 2.0])
    for c, a, b, tr in zip(C, A, B, curves):
        np.testing.assert_array_equal(tr.evaluate(t), Trig2D(c, a, b).evaluate(t))
        assert not (tr.center.flags.writeable or tr.a.flags.writeable or tr.b.flags.writeable)
    C[0, 0] = 99.0  # the curves hold copies
    assert curves[0].center[0] == 0.0
    assert Trig2D.many(np.empty((0, 2)), np.empty((0, 2)), np.empty((0, 2))) == []
    with pytest.raises(InvalidGeometryError, match="row 1 .* parallel axes"):
        Trig2D.many(C, A, [[0.0, 2.0], [1.0, 0.5]])
    with pytest.raises(InvalidGeometryError, match="row 0"):
        Trig2D.many([[math.nan, 0.0]], [[1.0, 0.0]], [[0.0, 1.0]])
    with pytest.raises(InvalidGeometryError, match="shapes"):
        Trig2D.many(np.zeros((2, 3)), np.zeros((2, 3)), np.zeros((2, 3)))


def test_circle_many_is_the_constructor_row_by_row():
    from coons.kernel.analytic import Circle
    from coons.kernel.conics import orthonormal_frame

    C = np.array([[0.0, 1.0, 2.0], [2.5, -3.0, 0.5]])
    F = np.array([orthonormal_frame([0, 0, 1], [1, 0, 0]), orthonormal_frame([0.3, -0.4, 1.0], [1, 0, 0])])
    R = np.array([1.5, 0.25])
    circles = Circle.many(C, F, R)
    t = np.array([0.0, 0.7, 4.0])
    for c, f, r, ci in zip(C, F, R, circles):
        ref = Circle(c, f[2], f[0], r)
        np.testing.assert_allclose(ci.evaluate(t), ref.evaluate(t), rtol=0, atol=1e-15)
        np.testing.assert_allclose(ci.frame, ref.frame, rtol=0, atol=1e-16)
        assert ci.radius == r and not ci.frame.flags.writeable and not ci.center.flags.writeable
    assert Circle.many(np.empty((0, 3)), np.empty((0, 3, 3)), np.empty(0)) == []
    with pytest.raises(InvalidGeometryError, match="row 1 .* not positive"):
        Circle.many(C, F, [1.0, 0.0])
    with pytest.raises(InvalidGeometryError, match="row 0"):
        Circle.many(C, np.array([F[0][[1, 0, 2]], F[1]]), R)  # left-handed
    with pytest.raises(InvalidGeometryError, match="row 1"):
        Circle.many(C, np.array([F[0], 2.0 * F[1]]), R)  # not unit
    with pytest.raises(InvalidGeometryError, match="shapes"):
        Circle.many(C, F[:, :2], R)
