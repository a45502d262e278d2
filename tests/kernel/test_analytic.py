"""Analytic curves and surfaces (coons.kernel.analytic).

Truth: OCCT's Geom_* evaluators and ElSLib/ElCLib projections at the same parameters (so we
parametrise exactly as OCCT does), finite differences for derivatives, closed-form
orientation, projection optimality against dense samples, and the exact NURBS of
``to_nurbs`` mapped through the tangent half-angle relation.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from OCP.ElCLib import ElCLib
from OCP.ElSLib import ElSLib
from OCP.Geom import (
    Geom_Circle,
    Geom_ConicalSurface,
    Geom_CylindricalSurface,
    Geom_Ellipse,
    Geom_Line,
    Geom_Plane,
    Geom_SphericalSurface,
    Geom_ToroidalSurface,
)
from OCP.GeomAPI import GeomAPI_ProjectPointOnCurve
from OCP.gp import gp_Ax1, gp_Ax2, gp_Ax3, gp_Circ, gp_Cone, gp_Cylinder, gp_Dir, gp_Lin, gp_Pln, gp_Pnt, gp_Sphere, gp_Torus

from coons.errors import InvalidGeometryError, InvalidInputError
from coons.kernel.analytic import (
    Circle,
    ConicalSurface,
    CylindricalSurface,
    Ellipse,
    Line,
    PlanarSurface,
    SphericalSurface,
    ToroidalSurface,
    angle_to_nurbs_parameter,
    nurbs_parameter_to_angle,
)
from coons.tolerance import Tolerance

TWO_PI = 2.0 * math.pi
HALF_PI = 0.5 * math.pi


def rotation(a: float, b: float, c: float) -> np.ndarray:
    def rz(t):
        return np.array([[math.cos(t), -math.sin(t), 0], [math.sin(t), math.cos(t), 0], [0, 0, 1]])

    ry = np.array([[math.cos(b), 0, math.sin(b)], [0, 1, 0], [-math.sin(b), 0, math.cos(b)]])
    return rz(a) @ ry @ rz(c)


def wrapped(angle):
    """Angle differences reduced to (-π, π]."""
    return np.angle(np.exp(1j * np.asarray(angle)))


FRAME = rotation(0.7, 2.1, -0.4)
X, Y, Z = FRAME[:, 0], FRAME[:, 1], FRAME[:, 2]
O = np.array([0.5, -1.25, 2.0])
SKEW_X = 2.0 * X + 0.3 * Z  # projected onto the plane by the constructors

CURVES = {
    "line": Line(O, 3.0 * X),
    "circle": Circle(O, Z, SKEW_X, 2.0),
    "ellipse": Ellipse(O, Z, SKEW_X, 3.0, 1.25),
}
SURFACES = {
    "plane": PlanarSurface(O, Z, SKEW_X),
    "cylinder": CylindricalSurface(O, Z, SKEW_X, 2.0),
    "cone": ConicalSurface(O, Z, SKEW_X, 1.5, 0.35),
    "cone_narrowing": ConicalSurface(O, Z, SKEW_X, 1.5, -0.35),
    "cone_apex": ConicalSurface(O, Z, SKEW_X, 0.0, 0.6),
    "sphere": SphericalSurface(O, Z, SKEW_X, 2.5),
    "torus": ToroidalSurface(O, Z, SKEW_X, 3.0, 1.0),
}


def curve_params(name: str, rng: np.random.Generator, m: int) -> np.ndarray:
    return rng.uniform(-5.0, 5.0, m) if name == "line" else rng.uniform(0.0, TWO_PI, m)


def surface_params(name: str, rng: np.random.Generator, m: int, v_span: float = 5.0) -> tuple[np.ndarray, np.ndarray]:
    u = rng.uniform(-5.0, 5.0, m) if name == "plane" else rng.uniform(0.0, TWO_PI, m)
    if name == "sphere":
        v = rng.uniform(-1.4, 1.4, m)  # away from the poles, where u is undefined
    elif name == "torus":
        v = rng.uniform(0.0, TWO_PI, m)
    else:
        v = rng.uniform(-v_span, v_span, m)
    return u, v


# ---------------------------------------------------------------------------- OCCT agreement
def occ_surface(s):
    origin = s.origin if hasattr(s, "origin") else s.center
    ax = gp_Ax3(gp_Pnt(*origin), gp_Dir(*s.axis), gp_Dir(*s.x_dir))
    if isinstance(s, PlanarSurface):
        return Geom_Plane(ax), gp_Pln(ax)
    if isinstance(s, CylindricalSurface):
        return Geom_CylindricalSurface(ax, s.radius), gp_Cylinder(ax, s.radius)
    if isinstance(s, ConicalSurface):
        return Geom_ConicalSurface(ax, s.semi_angle, s.radius), gp_Cone(ax, s.semi_angle, s.radius)
    if isinstance(s, SphericalSurface):
        return Geom_SphericalSurface(ax, s.radius), gp_Sphere(ax, s.radius)
    return Geom_ToroidalSurface(ax, s.major_radius, s.minor_radius), gp_Torus(ax, s.major_radius, s.minor_radius)


def occ_curve(c):
    if isinstance(c, Line):
        return Geom_Line(gp_Ax1(gp_Pnt(*c.origin), gp_Dir(*c.direction))), gp_Lin(gp_Pnt(*c.origin), gp_Dir(*c.direction))
    ax = gp_Ax2(gp_Pnt(*c.center), gp_Dir(*c.axis), gp_Dir(*c.x_dir))
    if isinstance(c, Circle):
        return Geom_Circle(ax, c.radius), gp_Circ(ax, c.radius)
    return Geom_Ellipse(ax, c.major_radius, c.minor_radius), None


def xyz(p) -> list[float]:
    return [p.X(), p.Y(), p.Z()]


@pytest.mark.occt
@pytest.mark.parametrize("name", sorted(SURFACES))
def test_surfaces_evaluate_and_differentiate_like_occt(name):
    s = SURFACES[name]
    geom, _ = occ_surface(s)
    rng = np.random.default_rng(1)
    u, v = surface_params(name, rng, 12)
    D = s.derivatives(u, v, 3)
    np.testing.assert_allclose(s.evaluate(u, v), D[:, 0, 0], rtol=0, atol=0)
    for i in range(len(u)):
        np.testing.assert_allclose(D[i, 0, 0], xyz(geom.Value(u[i], v[i])), rtol=0, atol=1e-14 * 8)
        for k in range(4):
            for l in range(4 - k):
                if k + l:
                    np.testing.assert_allclose(D[i, k, l], xyz(geom.DN(u[i], v[i], k, l)), rtol=0, atol=1e-14 * 8)


@pytest.mark.occt
@pytest.mark.parametrize("name", sorted(CURVES))
def test_curves_evaluate_and_differentiate_like_occt(name):
    c = CURVES[name]
    geom, _ = occ_curve(c)
    t = curve_params(name, np.random.default_rng(2), 12)
    D = c.derivatives(t, 4)
    np.testing.assert_allclose(c.evaluate(t), D[:, 0], rtol=0, atol=0)
    for i in range(len(t)):
        np.testing.assert_allclose(D[i, 0], xyz(geom.Value(t[i])), rtol=0, atol=1e-14 * 8)
        for k in range(1, 5):
            np.testing.assert_allclose(D[i, k], xyz(geom.DN(t[i], k)), rtol=0, atol=1e-14 * 8)


@pytest.mark.occt
@pytest.mark.parametrize("name", ["plane", "cylinder", "cone", "cone_narrowing", "sphere", "torus"])
def test_surface_projection_parameters_match_occt_elslib(name):
    s = SURFACES[name]
    _, prim = occ_surface(s)
    P = np.random.default_rng(3).uniform(-6.0, 6.0, (40, 3)) + O
    uv = s.closest_parameters(P)
    for p, (u, v) in zip(P, uv):
        occ_u, occ_v = ElSLib.Parameters_s(prim, gp_Pnt(*p))
        if s.periodic_u:
            np.testing.assert_allclose(wrapped(u - occ_u), 0.0, rtol=0, atol=1e-13)
        else:
            np.testing.assert_allclose(u, occ_u, rtol=0, atol=1e-13)
        if s.periodic_v:
            np.testing.assert_allclose(wrapped(v - occ_v), 0.0, rtol=0, atol=1e-13)
        else:
            np.testing.assert_allclose(v, occ_v, rtol=0, atol=1e-13)


@pytest.mark.occt
@pytest.mark.parametrize("name", sorted(CURVES))
def test_curve_projection_parameters_match_occt(name):
    c = CURVES[name]
    geom, prim = occ_curve(c)
    P = np.random.default_rng(4).uniform(-5.0, 5.0, (25, 3)) + O
    t = c.closest_parameters(P)
    for p, ti in zip(P, t):
        if prim is not None:
            expected = ElCLib.Parameter_s(prim, gp_Pnt(*p))
        else:
            expected = GeomAPI_ProjectPointOnCurve(gp_Pnt(*p), geom).LowerDistanceParameter()
        # ElCLib is closed form; OCCT projects onto ellipses iteratively (Extrema), to about 1e-9.
        atol = 1e-13 if prim is not None else 1e-9
        np.testing.assert_allclose(wrapped(ti - expected) if c.periodic else ti - expected, 0.0, rtol=0, atol=atol)


# ---------------------------------------------------------------------------- frames and validation
@pytest.mark.parametrize("obj", list(CURVES.values())[1:] + list(SURFACES.values()), ids=lambda o: type(o).__name__)
def test_frames_are_right_handed_orthonormal_and_project_x_dir(obj):
    F = obj.frame
    np.testing.assert_allclose(F @ F.T, np.eye(3), rtol=0, atol=1e-15)
    np.testing.assert_allclose(np.cross(F[0], F[1]), F[2], rtol=0, atol=1e-15)
    np.testing.assert_allclose(F, FRAME.T, rtol=0, atol=1e-15)  # SKEW_X projected back onto X
    np.testing.assert_array_equal(obj.y_dir, F[1])
    assert not F.flags.writeable and not obj.axis.flags.writeable
    with pytest.raises(dataclasses.FrozenInstanceError):
        obj.axis = Z
    with pytest.raises(ValueError, match="read-only"):
        obj.x_dir[0] = 1.0


def test_line_direction_is_normalised_and_frozen():
    line = CURVES["line"]
    np.testing.assert_allclose(line.direction, X, rtol=0, atol=2e-16)
    assert not line.origin.flags.writeable
    with pytest.raises(dataclasses.FrozenInstanceError):
        line.origin = O


BAD = [
    (lambda: Line([0, 0, 0], [0, 0, 0]), "Line: direction: expected a non-zero direction"),
    (lambda: Line([0, 0, np.nan], [0, 0, 1]), "Line: origin: coordinates must be finite"),
    (lambda: Line([0, 0], [0, 0, 1]), "Line: origin: expected a vector of 3 coordinates"),
    (lambda: Circle([0, 0, 0], [0, 0, 1], [0, 0, -3], 1.0), "Circle: x_dir .* is parallel to the axis"),
    (lambda: Circle([0, 0, 0], [0, 0, 0], [1, 0, 0], 1.0), "Circle: axis: expected a non-zero direction"),
    (lambda: Circle([0, 0, 0], [0, 0, 1], [1, 0, 0], 0.0), "Circle: radius: expected a positive number, got 0.0"),
    (lambda: Circle([0, 0, 0], [0, 0, 1], [1, 0, 0], np.inf), "Circle: radius: expected a finite number"),
    (lambda: Circle([0, 0, 0], [0, 0, 1], [1, 0, 0], "2"), "Circle: radius: expected a real number, got '2'"),
    (lambda: Circle([0, 0, 0], [0, 0, 1], [1, 0, 0], True), "Circle: radius: expected a real number"),
    (lambda: Ellipse([0, 0, 0], [0, 0, 1], [1, 0, 0], 1.0, 2.0), "minor_radius must be <= major_radius, got 2.0 > 1.0"),
    (lambda: Ellipse([0, 0, 0], [0, 0, 1], [1, 0, 0], 1.0, -1.0), "Ellipse: minor_radius: expected a positive"),
    (lambda: PlanarSurface([0, 0, 0], [0, 0, 1], [0, 0, 1]), "PlanarSurface: x_dir .* is parallel"),
    (lambda: PlanarSurface([0, 0, 0, 0], [0, 0, 1], [1, 0, 0]), "PlanarSurface: origin: expected a vector of 3"),
    (lambda: CylindricalSurface([0, 0, 0], [0, 0, 1], [1, 0, 0], -2.0), "CylindricalSurface: radius: expected a positive"),
    (lambda: ConicalSurface([0, 0, 0], [0, 0, 1], [1, 0, 0], -1.0, 0.3), "ConicalSurface: radius must be >= 0, got -1.0"),
    (lambda: ConicalSurface([0, 0, 0], [0, 0, 1], [1, 0, 0], 1.0, 0.0), r"semi_angle must satisfy 0 < \|a\| < π/2, got 0.0"),
    (lambda: ConicalSurface([0, 0, 0], [0, 0, 1], [1, 0, 0], 1.0, -HALF_PI), r"semi_angle must satisfy"),
    (lambda: ConicalSurface([0, 0, 0], [0, 0, 1], [1, 0, 0], 1.0, np.nan), "ConicalSurface: semi_angle: expected a finite"),
    (lambda: SphericalSurface([0, 0, 0], [0, 0, 1], [1, 0, 0], 0.0), "SphericalSurface: radius: expected a positive"),
    (lambda: SphericalSurface([0, 0, 0], [1, 1, 1], [2, 2, 2], 1.0), "SphericalSurface: x_dir .* is parallel"),
    (lambda: ToroidalSurface([0, 0, 0], [0, 0, 1], [1, 0, 0], 1.0, 1.0), r"ring torus\), got 1.0 >= 1.0"),
    (lambda: ToroidalSurface([0, 0, 0], [0, 0, 1], [1, 0, 0], 1.0, 2.0), r"ring torus\), got 2.0 >= 1.0"),
    (lambda: ToroidalSurface([0, 0, 0], [0, 0, 1], [1, 0, 0], 0.0, 0.5), "ToroidalSurface: major_radius: expected a positive"),
]


@pytest.mark.parametrize("make, match", BAD)
def test_constructors_reject_invalid_definitions(make, match):
    with pytest.raises(InvalidGeometryError, match=match):
        make()


@pytest.mark.parametrize("obj", list(CURVES.values()) + list(SURFACES.values()), ids=lambda o: type(o).__name__)
def test_evaluation_rejects_bad_parameters_and_points(obj):
    surface = hasattr(obj, "implicit")
    args = (lambda *a: a) if surface else (lambda *a: a[:1])
    with pytest.raises(InvalidInputError, match="finite"):
        obj.evaluate(*args(np.nan, 0.0))
    with pytest.raises(InvalidInputError, match="order must be an integer >= 0"):
        obj.derivatives(*args(0.0, 0.0), order=-1)
    with pytest.raises(InvalidInputError, match="order must be an integer >= 0"):
        obj.derivatives(*args(0.0, 0.0), order=1.5)
    with pytest.raises(InvalidInputError, match=r"expected an array of shape \(\.\.\., 3\), got \(4, 2\)"):
        obj.closest_parameters(np.zeros((4, 2)))
    with pytest.raises(InvalidInputError, match="points: coordinates must be finite"):
        obj.closest_parameters([0.0, np.inf, 0.0])
    if surface:
        with pytest.raises(InvalidInputError, match=r"do not broadcast: shapes \(2,\) and \(3,\)"):
            obj.evaluate(np.zeros(2), np.zeros(3))


# ---------------------------------------------------------------------------- evaluation
@pytest.mark.parametrize("name", sorted(SURFACES))
def test_surface_shapes_broadcast_like_nurbs_surfaces(name):
    s = SURFACES[name]
    u = np.linspace(0.1, 1.0, 4)[:, None]
    v = np.linspace(-0.5, 0.5, 3)[None, :]
    assert s.evaluate(u, v).shape == (4, 3, 3)
    assert s(0.2, 0.3).shape == (3,)
    assert s.derivatives(u, v, 2).shape == (4, 3, 3, 3, 3)
    assert s.derivatives(0.2, 0.3, 0).shape == (1, 1, 3)
    assert s.normal(u, v).shape == (4, 3, 3)
    assert s.closest_parameters(np.zeros((2, 5, 3))).shape == (2, 5, 2)
    assert s.implicit(np.zeros((2, 5, 3))).shape == (2, 5)
    np.testing.assert_array_equal(s.derivatives(u, v, 2)[..., 0, 0, :], s.evaluate(u, v))


@pytest.mark.parametrize("name", sorted(CURVES))
def test_curve_shapes_broadcast_like_nurbs_curves(name):
    c = CURVES[name]
    t = np.linspace(0.1, 1.0, 6).reshape(2, 3)
    assert c.evaluate(t).shape == (2, 3, 3) and c(0.5).shape == (3,)
    assert c.derivatives(t, 3).shape == (2, 3, 4, 3)
    assert c.closest_parameters(np.zeros((2, 5, 3))).shape == (2, 5)


@pytest.mark.parametrize("name", sorted(SURFACES))
def test_surface_derivatives_match_finite_differences(name):
    s = SURFACES[name]
    u, v = surface_params(name, np.random.default_rng(5), 20)
    h = 1e-5
    D = s.derivatives(u, v, 3)
    Du = (s.derivatives(u + h, v, 2) - s.derivatives(u - h, v, 2)) / (2 * h)
    Dv = (s.derivatives(u, v + h, 2) - s.derivatives(u, v - h, 2)) / (2 * h)
    # Central differences: truncation h^2 |D'''| / 6 plus round-off eps |P| / h.
    for k in range(3):
        for l in range(3 - k):
            np.testing.assert_allclose(Du[:, k, l], D[:, k + 1, l], rtol=0, atol=1e-8)
            np.testing.assert_allclose(Dv[:, k, l], D[:, k, l + 1], rtol=0, atol=1e-8)


@pytest.mark.parametrize("name", sorted(CURVES))
def test_curve_derivatives_match_finite_differences(name):
    c = CURVES[name]
    t = curve_params(name, np.random.default_rng(6), 20)
    h = 1e-5
    D = c.derivatives(t, 4)
    Dt = (c.derivatives(t + h, 3) - c.derivatives(t - h, 3)) / (2 * h)
    np.testing.assert_allclose(Dt, D[:, 1:], rtol=0, atol=1e-8)


@pytest.mark.parametrize("name", sorted(SURFACES))
def test_normals_are_unit_su_cross_sv_and_gradients_of_the_implicit(name):
    s = SURFACES[name]
    u, v = surface_params(name, np.random.default_rng(7), 30)
    D = s.derivatives(u, v, 1)
    n = s.normal(u, v)
    np.testing.assert_allclose(np.linalg.norm(n, axis=-1), 1.0, rtol=0, atol=1e-15)
    cross = np.cross(D[:, 1, 0], D[:, 0, 1])
    np.testing.assert_allclose(n, cross / np.linalg.norm(cross, axis=-1, keepdims=True), rtol=0, atol=1e-13)
    # The signed distance grows along the normal: orientation is outward (away from the axis for cones).
    P = D[:, 0, 0]
    np.testing.assert_allclose(s.implicit(P), 0.0, rtol=0, atol=1e-14 * 16)
    h = 1e-6
    np.testing.assert_allclose((s.implicit(P + h * n) - s.implicit(P - h * n)) / (2 * h), 1.0, rtol=0, atol=1e-7)


def test_closed_form_orientation_of_each_quadric():
    u, v = np.meshgrid(np.linspace(0, TWO_PI, 9), np.linspace(-1.5, 1.5, 7))
    radial = np.cos(u)[..., None] * X + np.sin(u)[..., None] * Y
    sphere = SURFACES["sphere"]
    np.testing.assert_allclose(sphere.normal(u, v), (sphere.evaluate(u, v) - O) / 2.5, rtol=0, atol=1e-15 * 4)
    np.testing.assert_allclose(sphere.normal([0.0, 1.0], [HALF_PI, -HALF_PI]), [Z, -Z], rtol=0, atol=1e-15)
    np.testing.assert_allclose(SURFACES["cylinder"].normal(u, v), radial, rtol=0, atol=1e-15)
    np.testing.assert_allclose(SURFACES["plane"].normal(u, v), np.broadcast_to(Z, u.shape + (3,)), rtol=0, atol=0)
    cone = SURFACES["cone"]  # apex at v = -1.5 / sin(0.35); both nappes point away from the axis
    vv = np.array([-10.0, -1.5 / math.sin(0.35), 3.0])
    n = cone.normal(0.0, vv)
    away = np.array([-X, X, X])  # past the apex, u = 0 is on the -X side of the axis
    np.testing.assert_array_less(0.0, np.einsum("ij,ij->i", n, away))


# ---------------------------------------------------------------------------- projection
@pytest.mark.parametrize("name", sorted(SURFACES))
def test_closest_parameters_invert_evaluation(name):
    s = SURFACES[name]
    u, v = surface_params(name, np.random.default_rng(8), 50)
    if name == "cone_apex":
        v = np.where(np.abs(v) < 1e-3, 1.0, v)  # at the apex u is undefined
    uv = s.closest_parameters(s.evaluate(u, v))
    du, dv = uv[:, 0] - u, uv[:, 1] - v
    np.testing.assert_allclose(wrapped(du) if s.periodic_u else du, 0.0, rtol=0, atol=1e-13)
    np.testing.assert_allclose(wrapped(dv) if s.periodic_v else dv, 0.0, rtol=0, atol=1e-13)
    (u0, u1), (v0, v1) = s.domain
    assert np.all((uv[:, 0] >= u0) & (uv[:, 0] < u1) & (uv[:, 1] >= v0) & (uv[:, 1] <= v1))


@pytest.mark.parametrize("name", sorted(CURVES))
def test_curve_closest_parameters_invert_evaluation(name):
    c = CURVES[name]
    t = curve_params(name, np.random.default_rng(9), 50)
    back = c.closest_parameters(c.evaluate(t))
    np.testing.assert_allclose(wrapped(back - t) if c.periodic else back - t, 0.0, rtol=0, atol=1e-13)


SAMPLE_V = {"plane": (-12, 12), "cylinder": (-12, 12), "cone": (-25, 25), "cone_narrowing": (-25, 25),
            "cone_apex": (-25, 25), "sphere": (-HALF_PI, HALF_PI), "torus": (0, TWO_PI)}


@pytest.mark.parametrize("name", sorted(SURFACES))
def test_closest_points_beat_dense_samples_and_match_the_implicit(name):
    s = SURFACES[name]
    P = np.random.default_rng(10).uniform(-5.0, 5.0, (20, 3)) + O
    Q = s.evaluate(*np.moveaxis(s.closest_parameters(P), -1, 0))
    d = np.linalg.norm(P - Q, axis=-1)
    np.testing.assert_allclose(np.abs(s.implicit(P)), d, rtol=0, atol=1e-13)
    np.testing.assert_allclose(np.linalg.norm(np.cross(P - Q, s.normal(*np.moveaxis(s.closest_parameters(P), -1, 0))),
                                              axis=-1), 0.0, rtol=0, atol=1e-12)
    us = np.linspace(-12, 12, 401) if name == "plane" else np.linspace(0, TWO_PI, 401)
    samples = s.evaluate(us[:, None], np.linspace(*SAMPLE_V[name], 401)[None, :]).reshape(-1, 3)
    nearest = np.min(np.linalg.norm(P[:, None, :] - samples[None, :, :], axis=-1), axis=1)
    assert np.all(d <= nearest + 1e-12)


def test_ellipse_closest_points_beat_dense_samples():
    e = CURVES["ellipse"]
    P = np.random.default_rng(11).uniform(-4.0, 4.0, (200, 3)) + O
    d = np.linalg.norm(P - e.evaluate(e.closest_parameters(P)), axis=-1)
    samples = e.evaluate(np.linspace(0, TWO_PI, 20001))
    nearest = np.min(np.linalg.norm(P[:, None, :] - samples[None, :, :], axis=-1), axis=1)
    assert np.all(d <= nearest + 1e-12)
    np.testing.assert_allclose(d, nearest, rtol=0, atol=1e-6)  # samples are 1e-3 rad apart


def test_closest_parameters_at_undefined_points():
    # An axis-aligned frame, so that the axis points below are on the axis exactly (not within round-off).
    e1, e3 = np.eye(3)[0], np.eye(3)[2]
    on_axis = O + 0.75 * e3
    circle, ellipse = Circle(O, e3, e1, 2.0), Ellipse(O, e3, e1, 3.0, 1.25)
    np.testing.assert_array_equal(circle.closest_parameters([O, on_axis]), [0.0, 0.0])
    np.testing.assert_allclose(ellipse.closest_parameters([O, on_axis]), HALF_PI, rtol=0, atol=1e-15)
    np.testing.assert_allclose(Ellipse(O, e3, e1, 2.0, 2.0).closest_parameters(O), 0.0, rtol=0, atol=1e-15)
    np.testing.assert_array_equal(CylindricalSurface(O, e3, e1, 2.0).closest_parameters(on_axis), [0.0, 0.75])
    sphere = SphericalSurface(O, e3, e1, 2.5)
    np.testing.assert_array_equal(sphere.closest_parameters([O, on_axis, O - e3]), [[0, 0], [0, HALF_PI], [0, -HALF_PI]])
    torus = ToroidalSurface(O, e3, e1, 3.0, 1.0)
    np.testing.assert_array_equal(torus.closest_parameters([on_axis, O + 3.0 * e1]), [[0.0, math.atan2(0.75, -3.0)], [0, 0]])
    cone = ConicalSurface(O, e3, e1, 1.5, 0.35)
    for p in (on_axis, cone.apex - 2.0 * e3):
        uv = cone.closest_parameters(p)
        assert uv[0] == 0.0
        np.testing.assert_allclose(np.linalg.norm(cone.evaluate(*uv) - p), abs(cone.implicit(p)), rtol=1e-14, atol=0)


def test_implicit_signs_and_closed_forms():
    P = np.array([O + 0.5 * X, O + 10 * X + Z, O - 3.0 * Z])
    np.testing.assert_allclose(SURFACES["plane"].implicit(P), [0.0, 1.0, -3.0], rtol=0, atol=1e-15 * 16)
    np.testing.assert_allclose(SURFACES["cylinder"].implicit(P), [-1.5, 8.0, -2.0], rtol=0, atol=1e-14)
    np.testing.assert_allclose(SURFACES["sphere"].implicit(P), [-2.0, math.sqrt(101) - 2.5, 0.5], rtol=0, atol=1e-14)
    np.testing.assert_allclose(SURFACES["torus"].implicit(P), [1.5, math.hypot(7.0, 1.0) - 1.0, math.hypot(3, 3) - 1],
                               rtol=0, atol=1e-14)
    apex = SURFACES["cone"].apex
    np.testing.assert_allclose(SURFACES["cone"].implicit(apex), 0.0, rtol=0, atol=1e-14)
    np.testing.assert_allclose(SURFACES["cone"].implicit(apex + 2 * Z), -2 * math.sin(0.35), rtol=0, atol=1e-14)
    np.testing.assert_allclose(SURFACES["cone"].implicit(apex - 2 * Z), -2 * math.sin(0.35), rtol=0, atol=1e-14)
    np.testing.assert_allclose(SURFACES["cone"].implicit(apex + 2 * X), 2 * math.cos(0.35), rtol=0, atol=1e-14)


# ---------------------------------------------------------------------------- transforms
def similarity(scale: float, reflect: bool = False) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3] = scale * rotation(0.3, -1.2, 2.5) @ np.diag([1.0, 1.0, -1.0 if reflect else 1.0])
    T[:3, 3] = [1.0, -2.0, 0.25]
    return T


def apply(T, P):
    return P @ T[:3, :3].T + T[:3, 3]


LINEAR_PARAMS = {"plane": (True, True), "cylinder": (False, True), "cone": (False, True), "cone_narrowing": (False, True),
                 "cone_apex": (False, True), "sphere": (False, False), "torus": (False, False)}


@given(scale=st.floats(0.1, 10.0))
@settings(max_examples=15)
def test_similarities_map_points_with_scaled_linear_parameters(scale):
    T = similarity(scale)
    rng = np.random.default_rng(12)
    for name, s in SURFACES.items():
        moved = s.transformed(T)
        assert type(moved) is type(s)
        u, v = surface_params(name, rng, 10)
        su, sv = (scale if lin else 1.0 for lin in LINEAR_PARAMS[name])
        np.testing.assert_allclose(moved.evaluate(su * u, sv * v), apply(T, s.evaluate(u, v)), rtol=0, atol=1e-13 * 10 * scale)
        np.testing.assert_allclose(moved.normal(su * u, sv * v), s.normal(u, v) @ T[:3, :3].T / scale, rtol=0, atol=1e-13)
    for name, c in CURVES.items():
        t = curve_params(name, rng, 10)
        st_ = scale if name == "line" else 1.0
        np.testing.assert_allclose(c.transformed(T).evaluate(st_ * t), apply(T, c.evaluate(t)), rtol=0, atol=1e-13 * 10 * scale)


def test_reflections_keep_curves_and_planes_exact_and_are_refused_by_revolved_surfaces():
    T = similarity(2.0, reflect=True)
    t = np.linspace(0, 6, 7)
    for name in ("circle", "ellipse"):
        moved = CURVES[name].transformed(T)
        np.testing.assert_allclose(moved.evaluate(t), apply(T, CURVES[name].evaluate(t)), rtol=0, atol=1e-13)
        np.testing.assert_allclose(np.linalg.det(moved.frame), 1.0, rtol=0, atol=1e-15)
    plane = SURFACES["plane"].transformed(T)
    np.testing.assert_allclose(plane.evaluate(2 * t, -2 * t), apply(T, SURFACES["plane"].evaluate(t, -t)), rtol=0, atol=1e-13)
    for name in ("cylinder", "cone", "sphere", "torus"):
        with pytest.raises(InvalidInputError, match="reflection would make the frame left-handed"):
            SURFACES[name].transformed(T)


@pytest.mark.parametrize("obj", list(CURVES.values())[1:] + list(SURFACES.values()), ids=lambda o: type(o).__name__)
def test_non_similarities_are_refused(obj):
    with pytest.raises(InvalidInputError, match="must be a similarity"):
        obj.transformed(np.diag([1.0, 2.0, 1.0]))
    with pytest.raises(InvalidInputError, match="singular"):
        obj.transformed(np.diag([1.0, 0.0, 1.0]))
    with pytest.raises(InvalidInputError, match="affine"):
        obj.transformed(np.ones((4, 4)))
    # Round-off of a composed rotation is a similarity; a shear above tol.angular is not.
    shear = np.eye(3)
    shear[0, 1] = 1e-6
    with pytest.raises(InvalidInputError, match="must be a similarity"):
        obj.transformed(shear, tol=Tolerance(angular=1e-9))
    assert type(obj.transformed(shear, tol=Tolerance(angular=1e-5))) is type(obj)


def test_line_stays_exact_under_any_affine_map():
    line = CURVES["line"]
    T = np.array([[1.0, 2.0, 0.0, 1.0], [0.0, 3.0, 1.0, 0.0], [0.5, 0.0, 1.0, -1.0], [0, 0, 0, 1]])
    speed = np.linalg.norm(T[:3, :3] @ line.direction)
    t = np.linspace(-3, 3, 7)
    np.testing.assert_allclose(line.transformed(T).evaluate(speed * t), apply(T, line.evaluate(t)), rtol=0, atol=1e-13)
    with pytest.raises(InvalidInputError, match="singular"):
        line.transformed(np.diag([1.0, 0.0, 1.0]))


@pytest.mark.parametrize("obj", list(CURVES.values()) + list(SURFACES.values()), ids=lambda o: type(o).__name__)
def test_is_close_compares_the_defining_parameters(obj):
    same = dataclasses.replace(obj)
    assert same is not obj and obj.is_close(same) and same.is_close(obj)
    assert not obj.is_close(Line(O, X) if not isinstance(obj, Line) else Circle(O, Z, X, 1.0))
    for f in dataclasses.fields(obj):
        value = getattr(obj, f.name)
        kind = f.metadata["kind"]
        if kind == "point":
            near, far = value + 0.5e-7 * Y, value + 3e-7 * Y
        elif kind == "length":
            near, far = value * (1 + 1e-9), value + 3e-7
        elif kind == "angle":
            near, far = value + 0.5e-9, value + 3e-9
        else:
            other = Y if abs(value @ Y) < 0.5 else X  # perpendicular: a parallel change is normalised away
            near, far = value + 0.5e-9 * other, value + 3e-9 * other
        assert obj.is_close(dataclasses.replace(obj, **{f.name: near})), f.name
        assert not obj.is_close(dataclasses.replace(obj, **{f.name: far})), f.name


# ---------------------------------------------------------------------------- exact NURBS
def nurbs_cross_normals(surf, u, v):
    d = surf.derivatives(u, v, 1)
    n = np.cross(d[:, 1, 0], d[:, 0, 1])
    return n / np.linalg.norm(n, axis=-1, keepdims=True)


TO_NURBS = {
    # name: (to_nurbs kwargs, u range, v range, u circular, v circular)
    "plane": ({"u_range": (-2.0, 3.0), "v_range": (-1.0, 4.0)}, (-2.0, 3.0), (-1.0, 4.0), False, False),
    "cylinder": ({"v_range": (-1.0, 4.0)}, (0.0, TWO_PI), (-1.0, 4.0), True, False),
    "cone": ({"v_range": (-8.0, 4.0), "u_range": (1.0, 3.0)}, (1.0, 3.0), (-8.0, 4.0), True, False),
    "cone_narrowing": ({"v_range": (-3.0, 4.0)}, (0.0, TWO_PI), (-3.0, 4.0), True, False),
    "cone_apex": ({"v_range": (0.5, 4.0)}, (0.0, TWO_PI), (0.5, 4.0), True, False),
    "sphere": ({}, (0.0, TWO_PI), (-HALF_PI, HALF_PI), True, True),
    "torus": ({"u_range": (-1.0, 2.0), "v_range": (0.5, 5.0)}, (-1.0, 2.0), (0.5, 5.0), True, True),
}


@pytest.mark.parametrize("name", sorted(TO_NURBS))
def test_to_nurbs_agrees_with_the_analytic_surface_through_the_angle_map(name):
    s = SURFACES[name]
    kwargs, ur, vr, u_circ, v_circ = TO_NURBS[name]
    surf = s.to_nurbs(**kwargs)
    assert surf.domain == (ur, vr)
    rng = np.random.default_rng(13)
    u = rng.uniform(*ur, 60)
    v = rng.uniform(vr[0] + 0.02, vr[1] - 0.02, 60)  # keep clear of the sphere's poles
    un = angle_to_nurbs_parameter(u, *ur) if u_circ else u
    vn = angle_to_nurbs_parameter(v, *vr) if v_circ else v
    scale = 10.0
    np.testing.assert_allclose(surf.evaluate(un, vn), s.evaluate(u, v), rtol=0, atol=1e-14 * scale * 4)
    np.testing.assert_allclose(nurbs_cross_normals(surf, un, vn), s.normal(u, v), rtol=0, atol=1e-12)
    # Any NURBS point lies on the analytic surface, and maps back through the inverse relation.
    un2, vn2 = rng.uniform(*surf.domain_u, 60), rng.uniform(*surf.domain_v, 60)
    P = surf.evaluate(un2, vn2)
    np.testing.assert_allclose(s.implicit(P), 0.0, rtol=0, atol=1e-14 * scale * 2)
    ua = nurbs_parameter_to_angle(un2, *ur) if u_circ else un2
    va = nurbs_parameter_to_angle(vn2, *vr) if v_circ else vn2
    np.testing.assert_allclose(s.evaluate(ua, va), P, rtol=0, atol=1e-14 * scale * 4)


@pytest.mark.parametrize("name, t_range", [("line", (-2.0, 3.0)), ("circle", (0.0, TWO_PI)), ("circle", (1.0, 2.5)),
                                           ("ellipse", (0.0, TWO_PI)), ("ellipse", (-2.0, 3.0))])
def test_curve_to_nurbs_agrees_through_the_angle_map(name, t_range):
    c = CURVES[name]
    nurbs = c.to_nurbs(t_range)
    assert nurbs.domain == t_range
    t = np.linspace(*t_range, 41)
    tn = t if name == "line" else angle_to_nurbs_parameter(t, *t_range)
    if name != "line" and t_range[1] - t_range[0] == TWO_PI:
        tn[-1] = t_range[1]  # a full turn maps its seam to the start; the end is the same point
    np.testing.assert_allclose(nurbs.evaluate(tn), c.evaluate(t), rtol=0, atol=1e-14 * 8)


def test_default_to_nurbs_are_full_turns():
    assert CURVES["circle"].to_nurbs().domain == (0.0, TWO_PI)
    assert SURFACES["torus"].to_nurbs().domain == ((0.0, TWO_PI), (0.0, TWO_PI))
    sphere = SURFACES["sphere"].to_nurbs()
    assert np.array_equal(sphere.control_points[0], sphere.control_points[-1])


@pytest.mark.parametrize(
    "call, error, match",
    [
        (lambda: CURVES["line"].to_nurbs((1.0, 1.0)), InvalidInputError, "t_range: expected start < end"),
        (lambda: CURVES["circle"].to_nurbs((0.0, 7.0)), InvalidGeometryError, r"\(0, 2π\]"),
        (lambda: CURVES["ellipse"].to_nurbs((0.0,)), InvalidInputError, "t_range: expected a pair"),
        (lambda: SURFACES["cylinder"].to_nurbs((3.0, -1.0)), InvalidInputError, "v_range: expected start < end"),
        (lambda: SURFACES["cone"].to_nurbs((0.0, 1.0), (0.0, 8.0)), InvalidGeometryError, r"\(0, 2π\]"),
        (lambda: SURFACES["sphere"].to_nurbs(v_range=(0.0, 2.0)), InvalidInputError, r"\[-π/2, π/2\]"),
        (lambda: SURFACES["plane"].to_nurbs((0.0, 1.0), (np.nan, 1.0)), InvalidInputError, "finite"),
    ],
)
def test_to_nurbs_rejects_bad_ranges(call, error, match):
    with pytest.raises(error, match=match):
        call()


@given(st.integers(0, 2**32 - 1))
def test_scalar_parameter_and_point_agree_with_the_array_methods(seed):
    """The Python-float forms used for single points (edge matching, STEP edges) give the array
    methods' values to round-off, for lines and circles."""
    from coons.errors import InvalidInputError
    from coons.kernel.analytic import Circle, Line, scalar_parameter, scalar_point

    rng = np.random.default_rng(seed)
    c = Circle(rng.normal(size=3) * 10, rng.normal(size=3) + 0.1, rng.normal(size=3), float(rng.uniform(0.1, 10)))
    L = Line(rng.normal(size=3) * 10, rng.normal(size=3) + 0.1)
    P = rng.normal(size=(4, 3)) * 10
    for curve in (c, L):
        want = curve.closest_parameters(P)
        got = np.array([scalar_parameter(curve, p) for p in P])
        np.testing.assert_allclose(got, want, rtol=0, atol=1e-12 * (1 + np.abs(want).max()))
        ts = rng.uniform(-7.0, 7.0, 5)
        np.testing.assert_allclose([scalar_point(curve, x) for x in ts], curve.evaluate(ts), rtol=0, atol=1e-12 * 100)
    assert scalar_parameter(Circle([0, 0, 0], [0, 0, 1], [1, 0, 0], 1.0), [0.0, 0.0, 2.0]) == 0.0  # on the axis
    with pytest.raises(InvalidInputError, match="Line or a Circle"):
        scalar_parameter(object(), P[0])


# ====================================================================== many surfaces at once
def test_surface_derivatives_and_normals_of_many_are_each_surfaces_own():
    """surface_derivatives / surface_normals (planes and surfaces of revolution in one expression
    per type, others one call each) give each surface's own partials and normals, at sphere poles
    and a cone's apex too (the normal's limit); meridian_row is each _meridian's form."""
    from coons.kernel.analytic import meridian_row, surface_derivatives, surface_normals
    from coons.kernel.surface import NurbsSurface

    rng = np.random.default_rng(11)
    surfaces = []
    for _ in range(3):
        o, a, x = rng.normal(size=3), rng.normal(size=3), rng.normal(size=3)
        surfaces += [PlanarSurface(o, a, x), CylindricalSurface(o, a, x, 1.5), ConicalSurface(o, a, x, 1.2, 0.4),
                     SphericalSurface(o, a, x, 2.0), ToroidalSurface(o, a, x, 3.0, 1.0)]
    grid = np.stack(np.meshgrid(np.linspace(0, 1, 4), np.linspace(0, 1, 4), indexing="ij"), axis=-1)
    surfaces.append(NurbsSurface(np.concatenate([grid, rng.normal(size=(4, 4, 1))], axis=-1),
                                 [0, 0, 0, 0, 1, 1, 1, 1], [0, 0, 0, 0, 1, 1, 1, 1], 3, 3))
    u, v = rng.uniform(0.0, 1.0, len(surfaces)), rng.uniform(0.0, 1.0, len(surfaces))
    u[3], v[3] = 0.7, math.pi / 2  # a sphere's pole
    u[2], v[2] = 0.3, -1.2 / math.sin(0.4)  # the cone's apex
    D, N = surface_derivatives(surfaces, u, v, 3), surface_normals(surfaces, u, v)
    for S, a, b, d, n in zip(surfaces, u, v, D, N):
        np.testing.assert_allclose(d, S.derivatives(a, b, 3), rtol=0, atol=1e-12)
        np.testing.assert_allclose(n, S.normal(a, b), rtol=0, atol=1e-12)
        row = meridian_row(S)
        if row is not None:
            vs = rng.uniform(-1.0, 1.0, 5)
            al, be, ga, de, ep = row
            rho, h = S._meridian(vs, 0)
            np.testing.assert_allclose(rho[0], al + be * vs + ga * np.cos(vs), rtol=0, atol=1e-12)
            np.testing.assert_allclose(h[0], de * vs + ep * np.sin(vs), rtol=0, atol=1e-12)
    index = rng.integers(0, len(surfaces), 40)  # (rows naming their surface)
    ui, vi = rng.uniform(0.0, 1.0, 40), rng.uniform(0.0, 1.0, 40)
    D, N = surface_derivatives(surfaces, ui, vi, 2, index), surface_normals(surfaces, ui, vi, index)
    for i, a, b, d, n in zip(index.tolist(), ui, vi, D, N):
        np.testing.assert_allclose(d, surfaces[i].derivatives(a, b, 2), rtol=0, atol=1e-12)
        np.testing.assert_allclose(n, surfaces[i].normal(a, b), rtol=0, atol=1e-12)
    with pytest.raises(InvalidInputError, match="out of range"):
        surface_normals(surfaces, [0.0], [0.0], [len(surfaces)])
    with pytest.raises(InvalidInputError, match="one \\(u, v\\) per surface"):
        surface_derivatives(surfaces, u[:-1], v)
    with pytest.raises(InvalidInputError, match="finite"):
        surface_normals(surfaces[:1], [np.nan], [0.0])
