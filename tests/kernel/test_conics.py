"""Exact NURBS lines, arcs, conics and surfaces of revolution (coons.kernel.conics).

Truth is closed form: constant radius of rational arcs, the conic's implicit equation, the
tangent half-angle map between angle and NURBS parameter, rotation of the profile for
surfaces of revolution, and OCCT's choice of a perpendicular X direction.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st
from OCP.GC import GC_MakeArcOfCircle
from OCP.GeomConvert import GeomConvert
from OCP.gp import gp_Ax2, gp_Circ, gp_Dir, gp_Pnt
from scipy.optimize import brentq

from coons.errors import InvalidGeometryError, InvalidInputError
from coons.kernel import conics as cn
from coons.kernel.curve import NurbsCurve

TWO_PI = 2.0 * math.pi
#: Points of exact constructions agree with closed forms to this many units of the size.
EXACT = 1e-14

angles = st.floats(-math.pi, math.pi, allow_nan=False)


def rotation(a: float, b: float, c: float) -> np.ndarray:
    """Rotation ``Rz(a) Ry(b) Rz(c)``; its columns are a right-handed orthonormal frame."""

    def rz(t):
        return np.array([[math.cos(t), -math.sin(t), 0], [math.sin(t), math.cos(t), 0], [0, 0, 1]])

    ry = np.array([[math.cos(b), 0, math.sin(b)], [0, 1, 0], [-math.sin(b), 0, math.cos(b)]])
    return rz(a) @ ry @ rz(c)


def rotate_about(points: np.ndarray, origin, axis, theta) -> np.ndarray:
    """Rodrigues rotation of ``points (..., 3)`` by ``theta (...)`` about the axis through ``origin``."""
    k = np.asarray(axis, float) / np.linalg.norm(axis)
    p = points - origin
    th = np.asarray(theta)[..., None]
    return origin + p * np.cos(th) + np.cross(k, p) * np.sin(th) + k * (p @ k)[..., None] * (1 - np.cos(th))


def wrapped(angle):
    """Angle differences reduced to (-π, π]."""
    return np.angle(np.exp(1j * np.asarray(angle)))


def knot_and_samples(curve: NurbsCurve, m: int = 101) -> np.ndarray:
    a, b = curve.domain
    return np.union1d(np.linspace(a, b, m), np.unique(curve.knots))


# ---------------------------------------------------------------------------- frames
@pytest.mark.occt
@pytest.mark.parametrize(
    "axis",
    [(0, 0, 1), (0, 0, -1), (1, 0, 0), (0, 1, 0), (0.3, 0.5, 0.8), (-0.8, 0.5, 0.3), (1, 1, 0), (1, 1, 1),
     (0.2, -0.9, 0.1), (-1, -1, 2), (1e-3, 2.0, -3.0)],
)
def test_perpendicular_direction_matches_occt_gp_ax2(axis):
    d = gp_Ax2(gp_Pnt(0, 0, 0), gp_Dir(*axis)).XDirection()
    np.testing.assert_allclose(cn.perpendicular_direction(axis), [d.X(), d.Y(), d.Z()], rtol=0, atol=1e-15)


@given(angles, angles, angles)
@settings(max_examples=40)
def test_orthonormal_frame_is_right_handed_and_projects_x_dir(a, b, c):
    R = rotation(a, b, c)
    axis, skew = 3.0 * R[:, 2], R[:, 0] + 0.7 * R[:, 2]  # x_dir with a component along the axis
    F = cn.orthonormal_frame(axis, skew)
    np.testing.assert_allclose(F @ F.T, np.eye(3), rtol=0, atol=1e-15)
    np.testing.assert_allclose(np.linalg.det(F), 1.0, rtol=0, atol=1e-15)
    np.testing.assert_allclose(F, R.T, rtol=0, atol=1e-15)
    P = cn.orthonormal_frame(axis)  # default X: perpendicular_direction
    np.testing.assert_allclose(P[0] @ P[2], 0.0, rtol=0, atol=1e-15)
    np.testing.assert_allclose(np.cross(P[0], P[1]), P[2], rtol=0, atol=1e-15)


@pytest.mark.occt
def test_orthonormal_frame_matches_occt_gp_ax2_with_x_direction():
    ax = gp_Ax2(gp_Pnt(0, 0, 0), gp_Dir(0.2, -0.4, 0.9), gp_Dir(1.0, 0.3, 0.5))
    F = cn.orthonormal_frame([0.2, -0.4, 0.9], [1.0, 0.3, 0.5])
    for row, d in zip(F, (ax.XDirection(), ax.YDirection(), ax.Direction())):
        np.testing.assert_allclose(row, [d.X(), d.Y(), d.Z()], rtol=0, atol=1e-15)


@pytest.mark.parametrize(
    "axis, x_dir, error, match",
    [
        ((0, 0, 0), (1, 0, 0), InvalidGeometryError, "non-zero direction"),
        ((0, 0, 1), (0, 0, 0), InvalidGeometryError, "non-zero direction"),
        ((0, 0, 1), (0, 0, -2), InvalidGeometryError, "parallel to the axis"),
        ((0, 1, 1), (0, 3, 3), InvalidGeometryError, "parallel to the axis"),
        ((0, 0, np.nan), (1, 0, 0), InvalidInputError, "finite"),
        ((0, 1), (1, 0, 0), InvalidInputError, "3 coordinates"),
    ],
)
def test_orthonormal_frame_rejects(axis, x_dir, error, match):
    with pytest.raises(error, match=match):
        cn.orthonormal_frame(axis, x_dir)


def test_perpendicular_direction_rejects_zero():
    with pytest.raises(InvalidGeometryError, match="non-zero direction"):
        cn.perpendicular_direction([0.0, 0.0, 0.0])


# ---------------------------------------------------------------------------- lines
def test_nurbs_line_is_linear_in_its_parameter():
    p0, p1 = np.array([1.0, -2.0, 0.5]), np.array([4.0, 2.0, -1.0])
    line = cn.nurbs_line(p0, p1, domain=(2.0, 5.0))
    t = np.linspace(2.0, 5.0, 13)
    np.testing.assert_allclose(line.evaluate(t), p0 + ((t - 2.0) / 3.0)[:, None] * (p1 - p0), rtol=0, atol=1e-15)
    assert line.degree == 1 and line.domain == (2.0, 5.0)
    np.testing.assert_allclose(cn.nurbs_line([0, 0], [3, 4]).evaluate(0.5), [1.5, 2.0], rtol=0, atol=0)


@pytest.mark.parametrize(
    "p0, p1, domain, error, match",
    [
        ((1, 2, 3), (1, 2, 3), (0, 1), InvalidGeometryError, "more than"),
        ((1, 2, 3), (1, 2), (0, 1), InvalidInputError, "3 coordinates"),
        ((1, 2, 3), (1, 2, np.inf), (0, 1), InvalidInputError, "finite"),
        ((1, 2, 3), (4, 5, 6), (1, 1), InvalidInputError, "start < end"),
        ((1, 2, 3), (4, 5, 6), (0,), InvalidInputError, "pair"),
        ((1, 2, 3, 4), (4, 5, 6, 7), (0, 1), InvalidInputError, "2 or 3 coordinates"),
    ],
)
def test_nurbs_line_rejects(p0, p1, domain, error, match):
    with pytest.raises(error, match=match):
        cn.nurbs_line(p0, p1, domain)


# ---------------------------------------------------------------------------- arcs
@given(
    start=st.floats(-7.0, 7.0),
    sweep=st.floats(1e-6, TWO_PI),
    radius=st.floats(1e-3, 1e3),
    a=angles, b=angles, c=angles,
)
@example(start=0.0, sweep=TWO_PI, radius=1.0, a=0.0, b=0.0, c=0.0)
@example(start=1.0, sweep=0.5 * math.pi, radius=2.0, a=0.3, b=0.2, c=0.1)
@example(start=-3.0, sweep=math.pi, radius=5.0, a=0.3, b=2.0, c=-1.0)
@example(start=0.5, sweep=1.5 * math.pi + 1e-9, radius=0.01, a=-2.0, b=1.0, c=3.0)
@settings(max_examples=60)
def test_arc_of_any_sweep_is_exact(start, sweep, radius, a, b, c):
    R = rotation(a, b, c)
    X, Y, Z = R[:, 0], R[:, 1], R[:, 2]
    center = np.array([1.0, -2.0, 3.0]) * radius
    end = start + sweep
    arc = cn.nurbs_arc(center, X, Y, radius, start, end)
    n = math.ceil(sweep / (0.5 * math.pi))
    assert cn.arc_segment_count(sweep) == n
    assert arc.degree == 2 and arc.n_control_points == 2 * n + 1 and arc.domain == (start, end)

    u = knot_and_samples(arc)
    rel = arc.evaluate(u) - center
    np.testing.assert_allclose(np.linalg.norm(rel, axis=-1), radius, rtol=EXACT, atol=0)
    np.testing.assert_allclose(rel @ Z, 0.0, rtol=0, atol=EXACT * radius)

    # End points and end tangents of the closed form.
    d = arc.derivatives(np.array([start, end]), 1)
    th = np.array([start, end])
    np.testing.assert_allclose(
        d[:, 0], center + radius * (np.cos(th)[:, None] * X + np.sin(th)[:, None] * Y), rtol=0, atol=EXACT * radius * 4
    )
    # Derivatives come from control point differences |P1 - P0| = R tan(δ/2) of points of size
    # |C| + R: their relative round-off is eps (|C| + R) / (R tan(δ/2)).
    delta = sweep / n
    conditioning = (1.0 + np.linalg.norm(center) / radius) / math.tan(delta / 2)
    tangent = -np.sin(th)[:, None] * X + np.cos(th)[:, None] * Y
    np.testing.assert_allclose(d[:, 1] / np.linalg.norm(d[:, 1], axis=-1, keepdims=True), tangent,
                               rtol=0, atol=1e-14 + 1e-15 * conditioning)

    # Speed of the standard weighting over the angle domain, in closed form:
    # 2 sin(δ/2)/δ at segment ends, 4 tan(δ/4)/δ at segment middles (never zero).
    speed = np.linalg.norm(arc.derivatives(u, 1)[:, 1], axis=-1) / radius
    slack = 1e-13 + 1e-15 * conditioning
    assert speed.min() >= 2.0 * math.sin(delta / 2) / delta * (1 - slack)
    assert speed.max() <= 4.0 * math.tan(delta / 4) / delta * (1 + slack)

    # The angle <-> NURBS parameter map.
    theta = start + sweep * np.linspace(0.0, 1.0, 23)
    t = cn.angle_to_nurbs_parameter(theta, start, end)
    closed = center + radius * (np.cos(theta)[:, None] * X + np.sin(theta)[:, None] * Y)
    np.testing.assert_allclose(arc.evaluate(t), closed, rtol=0, atol=4 * EXACT * radius * max(1.0, abs(start) + sweep))
    back = cn.nurbs_parameter_to_angle(t, start, end)  # a full turn maps its seam to the start
    np.testing.assert_allclose(wrapped(back - theta), 0.0, rtol=0, atol=1e-14 * (abs(start) + 7))


@pytest.mark.parametrize("center", [[0.5, -1.0], [0.5, -1.0, 2.0]])
def test_full_circle_closes_exactly_and_its_derivative_never_vanishes(center):
    normal = None if len(center) == 2 else [0.0, 1.0, 1.0]
    circle = cn.nurbs_circle(center, normal, 2.5)
    assert circle.n_control_points == 9 and circle.domain == (0.0, TWO_PI)
    assert np.array_equal(circle.control_points[0], circle.control_points[-1])
    u = np.linspace(0.0, TWO_PI, 4001)
    d = circle.derivatives(u, 1)
    np.testing.assert_allclose(np.linalg.norm(d[:, 0] - center, axis=-1), 2.5, rtol=EXACT, atol=0)
    speed = np.linalg.norm(d[:, 1], axis=-1)
    assert speed.min() >= 2.5 * 2.0 * math.sin(math.pi / 4) / (math.pi / 2) * (1 - 1e-12)
    # Same tangent on both sides of the seam.
    np.testing.assert_allclose(d[0, 1], d[-1, 1], rtol=1e-14, atol=1e-14)


def test_2d_circle_turns_counter_clockwise_from_x_axis():
    circle = cn.nurbs_circle([0.0, 0.0], None, 1.0, x_axis=[0.0, 2.0])
    d = circle.derivatives(np.linspace(0, TWO_PI, 50), 1)
    assert np.all(d[:, 0, 0] * d[:, 1, 1] - d[:, 0, 1] * d[:, 1, 0] > 0)
    np.testing.assert_allclose(circle.evaluate(0.0), [0.0, 1.0], rtol=0, atol=1e-16)


@pytest.mark.occt
@pytest.mark.parametrize("start, sweep", [(0.3, 0.01), (5.0, 1.0), (1.0, 0.5 * math.pi), (0.2, 2.7), (4.0, math.pi)])
def test_arcs_equal_occts_nurbs_conversion_where_the_span_counts_agree(start, sweep):
    # OCCT's GeomConvert (Convert_TgtThetaOver2) uses floor(1.2 sweep / π) + 1 spans, we use
    # ceil(sweep / (π/2)): the same count for sweeps up to 90° and from 150° to 180°. (OCCT
    # reduces the start of a trimmed circle into [0, 2π), so the starts here are there already.)
    R = rotation(0.3, 1.0, -0.6)
    center, radius = np.array([1.0, 2.0, -0.5]), 1.75
    circ = gp_Circ(gp_Ax2(gp_Pnt(*center), gp_Dir(*R[:, 2]), gp_Dir(*R[:, 0])), radius)
    occ = GeomConvert.CurveToBSplineCurve_s(GC_MakeArcOfCircle(circ, start, start + sweep, True).Value())
    ours = cn.nurbs_arc(center, R[:, 0], R[:, 1], radius, start, start + sweep)
    occ_knots = np.repeat([occ.Knot(i) for i in range(1, occ.NbKnots() + 1)],
                          [occ.Multiplicity(i) for i in range(1, occ.NbKnots() + 1)])
    np.testing.assert_allclose(ours.knots, occ_knots, rtol=0, atol=1e-15 * 8)
    np.testing.assert_allclose(ours.weights, [occ.Weight(i) for i in range(1, occ.NbPoles() + 1)], rtol=1e-15, atol=0)
    poles = [[p.X(), p.Y(), p.Z()] for p in (occ.Pole(i) for i in range(1, occ.NbPoles() + 1))]
    np.testing.assert_allclose(ours.control_points, poles, rtol=0, atol=1e-14)


@pytest.mark.occt
def test_3d_circle_default_x_axis_is_occts():
    normal = [0.3, -0.5, 0.8]
    circle = cn.nurbs_circle([1.0, 2.0, 3.0], normal, 2.0)
    d = gp_Ax2(gp_Pnt(0, 0, 0), gp_Dir(*normal)).XDirection()
    np.testing.assert_allclose(circle.evaluate(0.0), np.array([1.0, 2.0, 3.0]) + 2.0 * np.array([d.X(), d.Y(), d.Z()]),
                               rtol=0, atol=1e-15)


def test_angle_map_is_exact_at_knots_and_honours_domain():
    start, end = 0.25, 0.25 + 3.0
    for domain in (None, (0.0, 1.0), (-4.0, 10.0)):
        arc = cn.nurbs_arc([0, 0, 0], [1, 0, 0], [0, 1, 0], 1.0, start, end, domain=domain)
        knots = np.unique(arc.knots)
        n = len(knots) - 1
        seg_angles = start + (end - start) * np.arange(n + 1) / n
        np.testing.assert_allclose(cn.angle_to_nurbs_parameter(seg_angles, start, end, domain), knots, rtol=0, atol=1e-14)
        np.testing.assert_allclose(cn.nurbs_parameter_to_angle(knots, start, end, domain), seg_angles, rtol=0, atol=1e-14)
        theta = np.linspace(start, end, 17)
        t = cn.angle_to_nurbs_parameter(theta, start, end, domain)
        np.testing.assert_allclose(arc.evaluate(t)[:, :2], np.stack([np.cos(theta), np.sin(theta)], -1), rtol=0, atol=1e-15)


def test_angle_map_reduces_full_turns_modulo_two_pi():
    start = -1.0
    theta = np.array([-1.0 + TWO_PI, 5.0, 5.0 - 3 * TWO_PI, 0.3])
    t = cn.angle_to_nurbs_parameter(theta, start, start + TWO_PI)
    assert np.all((t >= start) & (t < start + TWO_PI))
    np.testing.assert_allclose(t[0], start, rtol=0, atol=1e-15)  # the seam maps to the domain start
    circle = cn.nurbs_arc([0, 0], [1, 0], [0, 1], 1.0, start, start + TWO_PI)
    np.testing.assert_allclose(circle.evaluate(t), np.stack([np.cos(theta), np.sin(theta)], -1), rtol=0, atol=1e-14)


@pytest.mark.parametrize(
    "call, error, match",
    [
        (lambda: cn.angle_to_nurbs_parameter(2.0, 0.0, 1.5), InvalidInputError, "outside the arc"),
        (lambda: cn.angle_to_nurbs_parameter(-0.1, 0.0, 1.5), InvalidInputError, "outside the arc"),
        (lambda: cn.angle_to_nurbs_parameter(np.nan, 0.0, 1.5), InvalidInputError, "finite"),
        (lambda: cn.angle_to_nurbs_parameter(0.5, 0.0, 1.5, (1.0, 0.0)), InvalidInputError, "start < end"),
        (lambda: cn.angle_to_nurbs_parameter(0.5, 1.5, 0.0), InvalidGeometryError, r"\(0, 2π\]"),
        (lambda: cn.nurbs_parameter_to_angle(1.6, 0.0, 1.5), InvalidInputError, "outside the domain"),
        (lambda: cn.nurbs_parameter_to_angle(0.5, 0.0, 7.0), InvalidGeometryError, r"\(0, 2π\]"),
        (lambda: cn.arc_segment_count(0.0), InvalidGeometryError, r"\(0, 2π\]"),
        (lambda: cn.arc_segment_count("x"), InvalidInputError, "real number"),
    ],
)
def test_angle_map_rejects(call, error, match):
    with pytest.raises(error, match=match):
        call()


@pytest.mark.parametrize(
    "args, kwargs, error, match",
    [
        (([0, 0, 0], [1, 0, 0], [0, 1, 0], 0.0, 0.0, 1.0), {}, InvalidGeometryError, "radius: expected a positive"),
        (([0, 0, 0], [1, 0, 0], [0, 1, 0], -1.0, 0.0, 1.0), {}, InvalidGeometryError, "radius: expected a positive"),
        (([0, 0, 0], [1, 0, 0], [0, 1, 0], 1.0, 1.0, 1.0), {}, InvalidGeometryError, r"\(0, 2π\]"),
        (([0, 0, 0], [1, 0, 0], [0, 1, 0], 1.0, 0.0, 6.3), {}, InvalidGeometryError, r"\(0, 2π\]"),
        (([0, 0, 0], [1, 0, 0], [0.1, 1, 0], 1.0, 0.0, 1.0), {}, InvalidGeometryError, "orthogonal"),
        (([0, 0, 0], [0, 0, 0], [0, 1, 0], 1.0, 0.0, 1.0), {}, InvalidGeometryError, "non-zero"),
        (([0, 0], [1, 0, 0], [0, 1, 0], 1.0, 0.0, 1.0), {}, InvalidInputError, "2 coordinates"),
        (([0, 0, 0], [1, 0, 0], [0, 1, 0], np.nan, 0.0, 1.0), {}, InvalidInputError, "finite"),
        (([0, 0, 0], [1, 0, 0], [0, 1, 0], 1.0, 0.0, np.inf), {}, InvalidInputError, "finite"),
        (([0, 0, 0], [1, 0, 0], [0, 1, 0], 1.0, 0.0, 1.0), {"domain": (2, 1)}, InvalidInputError, "start < end"),
    ],
)
def test_nurbs_arc_rejects(args, kwargs, error, match):
    with pytest.raises(error, match=match):
        cn.nurbs_arc(*args, **kwargs)


def test_arc_sweep_past_full_turn_by_round_off_is_a_full_turn():
    arc = cn.nurbs_arc([0, 0], [1, 0], [0, 1], 1.0, 0.1, 0.1 + TWO_PI * (1 + 1e-13))
    assert np.array_equal(arc.control_points[0], arc.control_points[-1])


@pytest.mark.parametrize(
    "center, normal, kwargs, error, match",
    [
        ([0, 0, 0], None, {}, InvalidInputError, "needs its normal"),
        ([0, 0], [0, 0, 1], {}, InvalidInputError, "takes no normal"),
        ([0, 0, 0], [0, 0, 1], {"x_axis": [0, 0, 5]}, InvalidGeometryError, "parallel to the axis"),
        ([0, 0], None, {"x_axis": [0, 0]}, InvalidGeometryError, "non-zero"),
    ],
)
def test_nurbs_circle_rejects(center, normal, kwargs, error, match):
    with pytest.raises(error, match=match):
        cn.nurbs_circle(center, normal, 1.0, **kwargs)
    with pytest.raises(error, match=match):
        cn.nurbs_ellipse(center, normal, 2.0, 1.0, **kwargs)


@given(start=st.floats(-4.0, 4.0), sweep=st.floats(1e-3, TWO_PI), rx=st.floats(0.1, 10.0), ry=st.floats(0.1, 10.0))
@settings(max_examples=40)
def test_ellipse_arc_lies_on_its_ellipse_with_the_eccentric_anomaly_map(start, sweep, rx, ry):
    C, X, Y = np.array([1.0, 2.0, -1.0]), np.array([0.0, 0.6, 0.8]), np.array([1.0, 0.0, 0.0])
    arc = cn.nurbs_ellipse_arc(C, X, Y, rx, ry, start, start + sweep)
    L = arc.evaluate(knot_and_samples(arc)) - C
    np.testing.assert_allclose((L @ X / rx) ** 2 + (L @ Y / ry) ** 2, 1.0, rtol=0, atol=8 * EXACT)
    t = start + sweep * np.linspace(0, 1, 19)
    closed = C + (rx * np.cos(t))[:, None] * X + (ry * np.sin(t))[:, None] * Y
    scale = max(rx, ry) * (1 + abs(start) + sweep)
    np.testing.assert_allclose(arc.evaluate(cn.angle_to_nurbs_parameter(t, start, start + sweep)), closed,
                               rtol=0, atol=4 * EXACT * scale)


def test_full_ellipse_closes_and_rejects_bad_radii():
    e = cn.nurbs_ellipse([0, 0, 0], [0, 0, 1], 3.0, 1.0, x_axis=[1, 1, 0])
    assert np.array_equal(e.control_points[0], e.control_points[-1])
    np.testing.assert_allclose(e.evaluate(0.0), [3 / math.sqrt(2), 3 / math.sqrt(2), 0], rtol=0, atol=1e-15)
    with pytest.raises(InvalidGeometryError, match="radius_y: expected a positive"):
        cn.nurbs_ellipse([0, 0, 0], [0, 0, 1], 3.0, 0.0)
    with pytest.raises(InvalidGeometryError, match="radius_x: expected a positive"):
        cn.nurbs_ellipse_arc([0, 0], [1, 0], [0, 1], -3.0, 1.0, 0.0, 1.0)


# ---------------------------------------------------------------------------- conic arcs
CONICS = {
    # name: (p0, t0, p2, t2, p, implicit equation, weight test); x is monotone along each arc
    "ellipse": (
        (3 * math.cos(0.2), math.sin(0.2)), (-3 * math.sin(0.2), math.cos(0.2)),
        (3 * math.cos(1.9), math.sin(1.9)), (-3 * math.sin(1.9), math.cos(1.9)),
        (3 * math.cos(1.0), math.sin(1.0)),
        lambda x, y: (x / 3) ** 2 + y**2 - 1, lambda w: w < 1,
    ),
    "parabola": ((-1, 1), (1, -2), (2, 4), (1, 4), (0.5, 0.25), lambda x, y: y - x**2, lambda w: abs(w - 1) < 1e-14),
    "hyperbola": ((0.5, 2), (1, -4), (2, 0.5), (1, -0.25), (1, 1), lambda x, y: x * y - 1, lambda w: w > 1),
}


@pytest.mark.parametrize("name", sorted(CONICS))
@pytest.mark.parametrize("lift", [False, True])
def test_conic_arc_lies_on_its_conic_through_its_points_with_its_tangents(name, lift):
    p0, t0, p2, t2, p, implicit, weight_ok = CONICS[name]
    p0, t0, p2, t2, p = (np.array(x, float) for x in (p0, t0, p2, t2, p))
    R = rotation(0.3, 1.1, -0.4)
    origin = np.array([1.0, -2.0, 0.5])

    def up(q, vector=False):  # embed the plane z = 0 in 3-D with a rigid motion
        return R @ np.append(q, 0.0) + (0.0 if vector else origin)

    args = (up(p0), up(t0, True), up(p2), up(t2, True), up(p)) if lift else (p0, t0, p2, t2, p)
    arc = cn.nurbs_conic_arc(*args)
    assert weight_ok(arc.weights[1])
    u = np.linspace(0.0, 1.0, 201)
    pts = arc.evaluate(u)
    flat = ((pts - origin) @ R)[:, :2] if lift else pts
    np.testing.assert_allclose(implicit(flat[:, 0], flat[:, 1]), 0.0, rtol=0, atol=1e-14 * 16)
    ends = arc.derivatives(np.array([0.0, 1.0]), 1)
    np.testing.assert_allclose(ends[:, 0], [args[0], args[2]], rtol=0, atol=1e-15)
    for d1, t in zip(ends[:, 1], (args[1], args[3])):
        np.testing.assert_allclose(d1 / np.linalg.norm(d1), t / np.linalg.norm(t), rtol=0, atol=1e-14)
    # The arc passes through p: find the parameter where the (monotone) in-plane x equals p's.
    flat_x = (lambda q: ((q - origin) @ R)[0]) if lift else (lambda q: q[0])
    u_p = brentq(lambda w: flat_x(arc.evaluate(w)) - p[0], 0.0, 1.0, xtol=1e-16, rtol=1e-15)
    np.testing.assert_allclose(arc.evaluate(u_p), args[4], rtol=0, atol=1e-13)


def test_nurbs_conic_with_cos45_weight_is_a_quarter_circle():
    quarter = cn.nurbs_conic([1, 0, 0], [1, 1, 0], [0, 1, 0], math.sqrt(0.5))
    np.testing.assert_allclose(np.linalg.norm(quarter.evaluate(np.linspace(0, 1, 50)), axis=-1), 1.0, rtol=EXACT, atol=0)
    with pytest.raises(InvalidGeometryError, match="weight: expected a positive"):
        cn.nurbs_conic([1, 0], [1, 1], [0, 1], 0.0)
    with pytest.raises(InvalidInputError, match="2 coordinates"):
        cn.nurbs_conic([1, 0], [1, 1, 0], [0, 1], 1.0)


@pytest.mark.parametrize(
    "p0, t0, p2, t2, p, error, match",
    [
        ((0, 0), (1, 0), (1, 1), (-1, 0), (0.5, 0.5), InvalidGeometryError, "parallel"),
        ((0, 0), (0, 0), (1, 1), (-1, 0), (0.5, 0.5), InvalidGeometryError, "non-zero"),
        ((0, 0, 0), (1, 0, 0), (2, 2, 1), (0, 1, 0), (1.5, 0.5, 0.2), InvalidGeometryError, "do not meet"),
        ((0, 0), (-1, 0), (2, 2), (0, 1), (1.5, 0.5), InvalidGeometryError, "towards the tangent intersection"),
        ((0, 0), (1, 0), (2, 2), (0, -1), (1.5, 0.5), InvalidGeometryError, "towards the tangent intersection"),
        ((0, 0), (1, 0), (2, 2), (0, 1), (2, 0), InvalidGeometryError, "coincides"),
        ((0, 0), (1, 0), (2, 2), (0, 1), (0.5, 1.5), InvalidGeometryError, "strictly inside"),  # beyond the chord
        ((0, 0), (1, 0), (2, 2), (0, 1), (3, -1), InvalidGeometryError, "strictly inside"),  # beyond P1
        ((0, 0), (1, 0), (2, 2), (0, 1), (1, 1), InvalidGeometryError, "strictly inside"),  # on the chord
        ((0, 0), (1, 0), (2, 2), (0, 1), (-1, -3), InvalidGeometryError, "parallel to the chord"),
        ((0, 0, 0), (1, 0, 0), (2, 2, 0), (0, 1, 0), (1.5, 0.5, 0.1), InvalidGeometryError, "do not meet"),  # off-plane
        ((0, 0), (1, 0), (2, 2, 0), (0, 1), (1.5, 0.5), InvalidInputError, "2 coordinates"),
    ],
)
def test_nurbs_conic_arc_rejects(p0, t0, p2, t2, p, error, match):
    with pytest.raises(error, match=match):
        cn.nurbs_conic_arc(p0, t0, p2, t2, p)


# ---------------------------------------------------------------------------- revolution
@given(start=st.floats(-4.0, 4.0), sweep=st.floats(1e-3, TWO_PI), a=angles, b=angles)
@example(start=0.0, sweep=TWO_PI, a=0.0, b=0.0)
@settings(max_examples=30)
def test_revolution_rotates_the_profile_by_the_mapped_angle(start, sweep, a, b):
    rng = np.random.default_rng(7)
    P = rng.uniform(-2, 2, (6, 3))
    P[2] = [0.0, 0.0, 0.5]  # a control point on the axis (the axis below is +z through the origin, then moved)
    profile = NurbsCurve(P, [0, 0, 0, 0, 0.4, 0.7, 1, 1, 1, 1], 3, rng.uniform(0.5, 2.0, 6))
    R = rotation(a, b, 0.3)
    origin = np.array([0.5, -1.0, 2.0])
    profile = profile.transformed(np.block([[R, origin[:, None]], [np.zeros((1, 3)), np.ones((1, 1))]]))
    axis = R[:, 2]
    surf = cn.nurbs_revolution(profile, origin, 2.0 * axis, start, start + sweep)
    assert surf.domain_u == (start, start + sweep) and surf.domain_v == profile.domain
    theta = start + sweep * rng.uniform(0, 1, 40)
    v = rng.uniform(0, 1, 40)
    u = cn.angle_to_nurbs_parameter(theta, start, start + sweep)
    expected = rotate_about(profile.evaluate(v), origin, axis, theta)
    np.testing.assert_allclose(surf.evaluate(u, v), expected, rtol=0, atol=1e-13 * (1 + abs(start)))
    if sweep == TWO_PI:
        assert np.array_equal(surf.control_points[0], surf.control_points[-1])


def test_revolution_rejects():
    line = cn.nurbs_line([1, 0, 0], [1, 0, 1])
    with pytest.raises(InvalidInputError, match="must be a NurbsCurve"):
        cn.nurbs_revolution([[1, 0, 0], [1, 0, 1]], [0, 0, 0], [0, 0, 1])
    with pytest.raises(InvalidGeometryError, match="must be 3-D"):
        cn.nurbs_revolution(cn.nurbs_line([1, 0], [1, 1]), [0, 0, 0], [0, 0, 1])
    with pytest.raises(InvalidGeometryError, match="non-zero direction"):
        cn.nurbs_revolution(line, [0, 0, 0], [0, 0, 0])
    with pytest.raises(InvalidGeometryError, match=r"\(0, 2π\]"):
        cn.nurbs_revolution(line, [0, 0, 0], [0, 0, 1], 0.0, 7.0)
    with pytest.raises(InvalidInputError, match="start < end"):
        cn.nurbs_revolution(line, [0, 0, 0], [0, 0, 1], domain_u=(1.0, 1.0))


# ---------------------------------------------------------------------------- quadrics
FRAME = rotation(0.4, -1.1, 2.0)
ORIGIN = np.array([1.0, -2.0, 0.5])


def _local(points):
    return (points - ORIGIN) @ FRAME


def _outward_check(surf, outward):
    """Su × Sv agrees with the closed-form outward direction ``outward(local points)`` at interior samples."""
    (u0, u1), (v0, v1) = surf.domain
    u, v = np.meshgrid(np.linspace(u0, u1, 23)[1:-1], np.linspace(v0, v1, 19)[1:-1], indexing="ij")
    d = surf.derivatives(u.ravel(), v.ravel(), 1)
    n = np.cross(d[:, 1, 0], d[:, 0, 1])
    n /= np.linalg.norm(n, axis=-1, keepdims=True)
    np.testing.assert_allclose(n @ FRAME, outward(_local(d[:, 0, 0])), rtol=0, atol=1e-12)


def _samples(surf, m=31):
    (u0, u1), (v0, v1) = surf.domain
    return _local(surf.evaluate_grid(np.linspace(u0, u1, m), np.linspace(v0, v1, m)).reshape(-1, 3))


def test_nurbs_cylinder_is_exact_with_outward_normals():
    surf = cn.nurbs_cylinder(ORIGIN, FRAME[:, 2], 2.0, (-1.0, 3.0), x_dir=FRAME[:, 0])
    L = _samples(surf)
    np.testing.assert_allclose(np.hypot(L[:, 0], L[:, 1]), 2.0, rtol=EXACT * 4, atol=0)
    assert surf.domain == ((0.0, TWO_PI), (-1.0, 3.0))
    np.testing.assert_allclose(_local(surf.evaluate(1.0, [-1.0, 0.5]))[:, 2], [-1.0, 0.5], rtol=0, atol=1e-15)
    _outward_check(surf, lambda L: np.stack([L[:, 0], L[:, 1], 0 * L[:, 2]], -1) / 2.0)


@pytest.mark.parametrize("semi_angle", [0.4, -0.4])
def test_nurbs_cone_is_exact_on_both_nappes_with_normals_away_from_the_axis(semi_angle):
    R = 1.0
    surf = cn.nurbs_cone(ORIGIN, FRAME[:, 2], R, semi_angle, (-6.0, 4.0), x_dir=FRAME[:, 0], u_range=(0.5, 4.0))
    L = _samples(surf)
    z_apex = -R / math.tan(semi_angle)
    rho = np.hypot(L[:, 0], L[:, 1])
    np.testing.assert_allclose(rho, np.abs(L[:, 2] - z_apex) * math.tan(abs(semi_angle)), rtol=0, atol=1e-13)
    a = abs(semi_angle)

    def outward(L):
        rho = np.hypot(L[:, 0], L[:, 1])
        e = np.stack([L[:, 0] / rho, L[:, 1] / rho, 0 * rho], -1)
        return math.cos(a) * e - (math.sin(a) * np.sign(L[:, 2] - z_apex))[:, None] * np.array([0, 0, 1.0])

    _outward_check(surf, outward)


def test_nurbs_sphere_is_exact_with_outward_normals():
    surf = cn.nurbs_sphere(ORIGIN, FRAME[:, 2], 3.0, x_dir=FRAME[:, 0])
    assert surf.domain == ((0.0, TWO_PI), (-0.5 * math.pi, 0.5 * math.pi))
    L = _samples(surf)
    np.testing.assert_allclose(np.linalg.norm(L, axis=-1), 3.0, rtol=EXACT * 4, atol=0)
    np.testing.assert_allclose(_local(surf.evaluate(0.0, [-0.5 * math.pi, 0.5 * math.pi])), [[0, 0, -3], [0, 0, 3]],
                               rtol=0, atol=1e-15)
    _outward_check(surf, lambda L: L / 3.0)
    cap = cn.nurbs_sphere(ORIGIN, FRAME[:, 2], 3.0, u_range=(1.0, 2.0), v_range=(0.2, 1.0))
    np.testing.assert_allclose(np.linalg.norm(_samples(cap), axis=-1), 3.0, rtol=EXACT * 4, atol=0)


def test_nurbs_torus_is_exact_with_outward_normals():
    surf = cn.nurbs_torus(ORIGIN, FRAME[:, 2], 3.0, 1.0, x_dir=FRAME[:, 0])
    L = _samples(surf)
    np.testing.assert_allclose(np.hypot(np.hypot(L[:, 0], L[:, 1]) - 3.0, L[:, 2]), 1.0, rtol=0, atol=1e-14 * 4)

    def outward(L):
        rho = np.hypot(L[:, 0], L[:, 1])
        core = np.stack([3.0 * L[:, 0] / rho, 3.0 * L[:, 1] / rho, 0 * rho], -1)
        return L - core

    _outward_check(surf, outward)


def test_nurbs_plane_patch_is_the_planar_parametrisation():
    surf = cn.nurbs_plane_patch(ORIGIN, FRAME[:, 2], (-1.0, 2.0), (0.5, 4.0), x_dir=FRAME[:, 0] + FRAME[:, 2])
    u, v = np.meshgrid(np.linspace(-1, 2, 5), np.linspace(0.5, 4, 6), indexing="ij")
    expected = ORIGIN + u[..., None] * FRAME[:, 0] + v[..., None] * FRAME[:, 1]
    np.testing.assert_allclose(surf.evaluate(u, v), expected, rtol=0, atol=1e-15 * 8)


@pytest.mark.parametrize(
    "call, error, match",
    [
        (lambda: cn.nurbs_cylinder(ORIGIN, [0, 0, 1], 0.0, (0, 1)), InvalidGeometryError, "radius: expected a positive"),
        (lambda: cn.nurbs_cylinder(ORIGIN, [0, 0, 1], 1.0, (1, 0)), InvalidInputError, "v_range: expected start < end"),
        (lambda: cn.nurbs_cylinder(ORIGIN, [0, 0, 1], 1.0, (0, 1), u_range=(0, 7)), InvalidGeometryError, r"\(0, 2π\]"),
        (lambda: cn.nurbs_cylinder(ORIGIN, [0, 0, 0], 1.0, (0, 1)), InvalidGeometryError, "non-zero"),
        (lambda: cn.nurbs_cone(ORIGIN, [0, 0, 1], -1.0, 0.3, (0, 1)), InvalidGeometryError, ">= 0"),
        (lambda: cn.nurbs_cone(ORIGIN, [0, 0, 1], 1.0, 0.0, (0, 1)), InvalidGeometryError, "0 < |a| < π/2"),
        (lambda: cn.nurbs_cone(ORIGIN, [0, 0, 1], 1.0, 1.6, (0, 1)), InvalidGeometryError, "0 < |a| < π/2"),
        (lambda: cn.nurbs_sphere(ORIGIN, [0, 0, 1], 1.0, v_range=(-2.0, 1.0)), InvalidInputError, r"\[-π/2, π/2\]"),
        (lambda: cn.nurbs_sphere(ORIGIN, [0, 0, 1], -1.0), InvalidGeometryError, "radius: expected a positive"),
        (lambda: cn.nurbs_torus(ORIGIN, [0, 0, 1], 1.0, 1.0), InvalidGeometryError, "ring torus"),
        (lambda: cn.nurbs_torus(ORIGIN, [0, 0, 1], 3.0, 0.0), InvalidGeometryError, "minor_radius: expected"),
        (lambda: cn.nurbs_torus(ORIGIN, [0, 0, 1], 3.0, 1.0, v_range=(0, 7)), InvalidGeometryError, r"\(0, 2π\]"),
        (lambda: cn.nurbs_plane_patch(ORIGIN, [0, 0, 1], x_dir=[0, 0, 1]), InvalidGeometryError, "parallel"),
        (lambda: cn.nurbs_plane_patch(ORIGIN, [0, 0, 1], (0, 0)), InvalidInputError, "start < end"),
    ],
)
def test_quadric_constructors_reject(call, error, match):
    with pytest.raises(error, match=match):
        call()
