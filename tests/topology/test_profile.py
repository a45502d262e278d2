"""Profiles: exact areas and centroids (closed forms), orientation normalisation, plane handling
(2-D and 3-D inputs, tilted frames, build123d-like planes, coplanar holes in other frames), the
sampled intersection and containment tests at and around the linear tolerance, and every
bad-input branch with its message.
"""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from coons.errors import InvalidInputError
from coons.kernel.analytic import Circle, Line, PlanarSurface
from coons.kernel.conics import nurbs_circle
from coons.kernel.curve import NurbsCurve
from coons.tolerance import Tolerance
from coons.topology.profile import XY, Profile, Segment, as_plane

#: Round-off allowance for exact formulas (coordinates of order 1-10).
EXACT = 1e-12
TOL = Tolerance()
XZ = ((0.0, 0.0, 0.0), (0.0, -1.0, 0.0), (1.0, 0.0, 0.0))


def shoelace(P: np.ndarray) -> float:
    x, y = P[:, 0], P[:, 1]
    return 0.5 * float(np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y))


def starts(wire, n: int = 8) -> np.ndarray:
    """Points along the wire in order (``n`` per segment), for orientation by the shoelace formula."""
    return np.concatenate([s.evaluate(np.linspace(*s.domain, n + 1)[:-1]) for s in wire])


def assert_chained(p: Profile) -> None:
    """Every wire closes exactly (lines) or within tol.linear (curves), and each resolved segment is 2-D."""
    for w in p.wires:
        for a, b in zip(w, w[1:] + w[:1]):
            assert a.dimension == 2
            assert np.linalg.norm(a.end - b.start) <= TOL.linear


# ============================================================================ constructors and areas
def test_rectangle_polygon_and_circle_areas_centroids_and_orientation():
    r = Profile.rectangle(4.0, 2.0, center=(1.0, -1.0))
    assert len(r.outer) == 4 and r.holes == ()
    np.testing.assert_allclose(r.area, 8.0, rtol=EXACT)
    np.testing.assert_allclose(r.centroid, [1.0, -1.0, 0.0], atol=EXACT)
    assert shoelace(starts(r.outer)) > 0  # counter-clockwise about +z
    np.testing.assert_array_equal(r.normal, [0.0, 0.0, 1.0])

    cw = Profile.polygon([(0, 0), (0, 3), (2, 3), (2, 0)])  # given clockwise: reversed
    np.testing.assert_allclose(cw.area, 6.0, rtol=EXACT)
    assert shoelace(starts(cw.outer)) > 0
    np.testing.assert_array_equal(cw.outer[0].start, [0.0, 0.0])  # the first vertex stays first
    closed = Profile.polygon([(0, 0), (2, 0), (2, 3), (0, 3), (0, 0)])  # a repeated first point is dropped
    assert len(closed.outer) == 4

    c = Profile.circle(1.5, center=(2.0, 1.0))
    assert [s.kind for s in c.outer] == ["arc", "arc"]  # no closed edge: two half arcs
    np.testing.assert_allclose(c.area, math.pi * 2.25, rtol=EXACT)
    np.testing.assert_allclose(c.centroid, [2.0, 1.0, 0.0], atol=EXACT)
    assert_chained(c)


def test_half_disk_centroid_and_stadium_area():
    half = Profile.from_wires([Segment.arc((0, 0), 2.0, 0, 180), Segment.line((-2, 0), (2, 0))])
    np.testing.assert_allclose(half.area, 2 * math.pi, rtol=EXACT)
    np.testing.assert_allclose(half.centroid, [0.0, 4 * 2.0 / (3 * math.pi), 0.0], atol=EXACT)


@given(st.floats(0.1, 3.0), st.floats(0.1, 5.0), st.booleans())
def test_stadium_area_closed_form(r, length, reverse):
    """Two lines and two half circles (tangent joints): A = 2 r L + π r², centroid at the middle."""
    w = [Segment.line((0, -r), (length, -r)), Segment.arc((length, 0), r, -90, 90),
         Segment.line((length, r), (0, r)), Segment.arc((0, 0), r, 90, 270)]
    if reverse:
        w = [Segment.line(s.end, s.start) if s.kind == "line" else s.reversed() for s in reversed(w)]
    p = Profile.from_wires(w)
    np.testing.assert_allclose(p.area, 2 * r * length + math.pi * r * r, rtol=EXACT)
    np.testing.assert_allclose(p.centroid, [length / 2, 0.0, 0.0], atol=EXACT * (1 + length))
    assert_chained(p)


@st.composite
def star_polygons(draw):
    n = draw(st.integers(3, 24))
    radii = draw(st.lists(st.floats(0.3, 2.0), min_size=n, max_size=n))
    jitter = draw(st.lists(st.floats(-0.3, 0.3), min_size=n, max_size=n))
    th = (np.arange(n) + np.array(jitter)) * 2 * np.pi / n
    return np.c_[np.array(radii) * np.cos(th), np.array(radii) * np.sin(th)]


@given(star_polygons(), st.booleans())
def test_star_shaped_polygons_are_valid_and_counter_clockwise(P, reverse):
    Q = P[::-1] if reverse else P
    p = Profile.polygon(Q)
    np.testing.assert_allclose(p.area, abs(shoelace(P)), rtol=1e-12)
    assert shoelace(starts(p.outer)) > 0


@given(star_polygons(), st.floats(-3, 3), st.floats(-3, 3), st.floats(-3, 3),
       st.lists(st.floats(-1, 1), min_size=3, max_size=3).filter(lambda v: np.linalg.norm(v) > 0.1))
def test_the_same_polygon_given_in_3d_on_a_tilted_plane(P, ox, oy, oz, normal):
    plane = as_plane(((ox, oy, oz), normal))
    X, Y, _ = plane.frame
    P3 = plane.origin + P[:, :1] * X + P[:, 1:] * Y
    p = Profile.polygon(P3, plane=plane)
    np.testing.assert_allclose(p.area, abs(shoelace(P)), rtol=1e-12)
    centroid_2d = Profile.polygon(P).centroid[:2]
    np.testing.assert_allclose(p.centroid, plane.origin + centroid_2d[0] * X + centroid_2d[1] * Y, atol=1e-12)
    np.testing.assert_allclose(p.vertices()[0][0], P3[0], atol=1e-12)  # counter-clockwise already: kept


def test_holes_are_clockwise_subtract_and_keep_their_shape():
    outer = Profile.rectangle(6.0, 4.0)
    ccw_hole = [Segment.line((1, -1), (2, -1)), Segment.line((2, -1), (2, 1)), Segment.line((2, 1), (1, -1))]
    p = outer.with_hole(ccw_hole).with_hole(Profile.circle(0.5, center=(-1.5, 0)))
    assert len(p.holes) == 2 and len(p.holes[1]) == 2
    for h in p.holes:
        assert sum(s.kind == "arc" for s in h) in (0, 2)
    assert shoelace(starts(p.holes[0])) < 0  # given counter-clockwise, stored clockwise
    np.testing.assert_allclose(p.area, 24.0 - 1.0 - math.pi * 0.25, rtol=EXACT)
    # Centroid of the region: moments of the rectangle minus those of the holes.
    m = 0.0 * 24 - (1.0 * (5.0 / 3.0)) - math.pi * 0.25 * (-1.5)
    np.testing.assert_allclose(p.centroid[0], m / p.area, rtol=1e-12)
    assert_chained(p)


def test_hole_from_a_coplanar_profile_in_another_frame():
    """The hole's plane shares the profile's plane but has another origin, x_dir and normal sense."""
    frame = as_plane(((1.0, 2.0, 0.0), (0.0, 0.0, -1.0), (0.0, 1.0, 0.0)))
    # In that frame (u along +y, v along +x since normal × x_dir = -z × y = x) the centre (0.5, -1)
    # is the world point (1 - 1, 2 + 0.5) = (0, 2.5).
    hole = Profile.from_wires([Segment.arc((0.5, -1.0), 0.4, 30, 390)], plane=frame)
    p = Profile.rectangle(4.0, 8.0).with_hole(hole)
    np.testing.assert_allclose(p.area, 32.0 - math.pi * 0.16, rtol=EXACT)
    arc = p.holes[0][0]
    np.testing.assert_allclose(arc.points[0], [0.0, 2.5], atol=EXACT)
    np.testing.assert_allclose(np.linalg.norm(arc.start - arc.points[0]), 0.4, rtol=EXACT)


def test_segment_geometry_and_parametrisation():
    arc = Profile.from_wires([Segment.arc((0, 0), 2.0, 0, 90), Segment.line((0, 2), (0, 0)),
                              Segment.line((0, 0), (2, 0))]).outer[0]
    assert arc.domain == (0.0, math.pi / 2)
    np.testing.assert_allclose(arc.evaluate(math.pi / 4), [math.sqrt(2), math.sqrt(2)], atol=EXACT)
    d = arc.derivatives(np.array([0.0, 0.3]), 2)
    np.testing.assert_allclose(np.linalg.norm(d[:, 1], axis=-1), 2.0, rtol=EXACT)  # unit angular speed × R
    np.testing.assert_allclose(d[:, 2], -(d[:, 0] - 0.0), atol=EXACT)  # second derivative points to the centre
    r = arc.reversed()
    np.testing.assert_allclose(r.evaluate(0.1), arc.evaluate(math.pi / 2 - 0.1), atol=EXACT)
    # to_3d: exact analytic curves with the same parameter; to_nurbs agrees at the ends and on the circle.
    plane = as_plane(((0, 0, 1), (0, 1, 1), (1, 0, 0)))
    c3, rng = arc.to_3d(plane)
    assert isinstance(c3, Circle) and rng == arc.domain
    t = np.linspace(*rng, 7)
    np.testing.assert_allclose(c3.evaluate(t), plane.evaluate(*arc.evaluate(t).T), atol=EXACT)
    nc = arc.to_nurbs(plane)
    np.testing.assert_allclose(nc.evaluate(np.array(rng)), c3.evaluate(np.array(rng)), atol=EXACT)
    np.testing.assert_allclose(np.linalg.norm(nc.evaluate(t) - plane.origin, axis=-1), 2.0, rtol=EXACT)
    line = Profile.rectangle(2, 2).outer[0]
    l3, lr = line.to_3d(plane)
    assert isinstance(l3, Line) and lr == (0.0, 2.0)
    np.testing.assert_allclose(l3.evaluate(2.0), plane.evaluate(*line.end), atol=EXACT)


def test_clockwise_arcs_and_arc_through():
    cw = Segment.arc((0, 0), 1.0, 90, 0)  # clockwise quarter
    p = Profile.from_wires([Segment.line((0, 0), (0, 1)), cw, Segment.line((1, 0), (0, 0))])
    np.testing.assert_allclose(p.area, math.pi / 4, rtol=EXACT)
    through = Profile.from_wires([Segment.arc_through((1, 0), (0, 1), (-1, 0)), Segment.line((-1, 0), (1, 0))])
    arc = through.outer[0]
    np.testing.assert_allclose(arc.points[0], [0.0, 0.0], atol=EXACT)
    np.testing.assert_allclose([arc.radius, arc.sweep], [1.0, math.pi], rtol=EXACT)
    np.testing.assert_allclose(through.area, math.pi / 2, rtol=EXACT)
    # The same half disk given clockwise (through the bottom point): reversed to counter-clockwise.
    low = Profile.from_wires([Segment.arc_through((-1, 0), (0, -1), (1, 0)), Segment.line((1, 0), (-1, 0))])
    np.testing.assert_allclose(low.area, math.pi / 2, rtol=EXACT)
    assert low.outer[0].sweep > 0 or low.outer[1].sweep > 0


def test_splines_from_points_and_curves_and_closed_ones_are_split():
    pts = np.array([(0, 0), (1, -0.5), (2, 0.2), (3, 0)])
    p = Profile.from_wires([Segment.spline(pts), Segment.line((3, 0), (3, 2)), Segment.line((3, 2), (0, 2)),
                            Segment.line((0, 2), (0, 0))])
    sp = p.outer[0]
    assert sp.kind == "spline" and sp.curve.degree == 3
    d = np.linalg.norm(sp.curve.evaluate(np.linspace(*sp.domain, 400))[:, None] - pts[None], axis=-1)
    assert np.all(d.min(axis=0) < 1e-2)  # passes through the points (sampled)
    np.testing.assert_allclose(sp.start, pts[0], atol=EXACT)
    # A closed NURBS circle as the only segment: split into two halves, area π r².
    circle = nurbs_circle([1.0, 1.0], None, 0.5)
    q = Profile.from_wires([Segment.spline(circle)])
    assert len(q.outer) == 2 and all(s.kind == "spline" for s in q.outer)
    np.testing.assert_allclose(q.area, math.pi * 0.25, rtol=1e-13)
    # A 3-D spline on a tilted plane.
    plane = as_plane(((0, 0, 0), (1, 0, 1)))
    c3 = NurbsCurve(plane.evaluate(circle.control_points[:, 0], circle.control_points[:, 1]), circle.knots,
                    circle.degree, circle.weights)
    np.testing.assert_allclose(Profile.from_wires([Segment.spline(c3)], plane=plane).area, math.pi * 0.25, rtol=1e-13)


def test_full_circle_arcs_split_and_unresolved_segments_have_no_domain():
    p = Profile.from_wires([Segment.arc((0, 0), 1.0, 45, -315)])  # a full clockwise turn
    assert len(p.outer) == 2 and all(abs(s.sweep) == pytest.approx(math.pi) for s in p.outer)
    np.testing.assert_allclose(p.area, math.pi, rtol=EXACT)
    with pytest.raises(InvalidInputError, match="'arc_through' segment is not resolved yet"):
        Segment.arc_through((0, 0), (1, 1), (2, 0)).domain
    with pytest.raises(InvalidInputError, match="'spline_points' segment is not resolved yet"):
        Segment.spline([(0, 0), (1, 1)]).evaluate(0.0)


def test_planes_tuples_planar_surfaces_and_build123d_like_objects():
    assert as_plane(None) is XY
    surf = PlanarSurface([0, 0, 1], [0, 0, 1], [0, 1, 0])
    assert as_plane(surf) is surf
    vec = lambda *v: SimpleNamespace(to_tuple=lambda: v)  # noqa: E731
    duck = SimpleNamespace(origin=vec(0.0, 0.0, 2.0), z_dir=vec(0.0, 1.0, 0.0), x_dir=vec(1.0, 0.0, 0.0))
    pl = as_plane(duck)
    np.testing.assert_allclose(pl.frame, [[1, 0, 0], [0, 0, -1], [0, 1, 0]], atol=EXACT)
    np.testing.assert_allclose(as_plane(((0, 0, 0), (0, 0, 5))).frame, np.eye(3), atol=EXACT)
    p = Profile.rectangle(2, 1, plane=duck)
    np.testing.assert_allclose(p.normal, [0, 1, 0])
    np.testing.assert_allclose(p.centroid, [0, 0, 2], atol=EXACT)


def test_flipped_is_the_same_region_seen_from_the_other_side():
    p = Profile.rectangle(3, 2, center=(1, 0)).with_hole(Profile.circle(0.5, center=(1.5, 0)))
    f = p.flipped()
    np.testing.assert_allclose(f.normal, -p.normal)
    np.testing.assert_allclose(f.area, p.area, rtol=EXACT)
    np.testing.assert_allclose(f.centroid, p.centroid, atol=EXACT)
    assert shoelace(starts(f.outer)) > 0 and shoelace(starts(f.holes[0])) < 0
    V3 = lambda q: np.sort(np.concatenate(q.vertices()).round(12), axis=0)  # noqa: E731
    np.testing.assert_allclose(V3(f), V3(p), atol=EXACT)


# ============================================================================ intersection and containment
def test_tangential_touching_is_detected_at_the_linear_tolerance():
    rect = Profile.rectangle(4.0, 2.0)
    with pytest.raises(InvalidInputError, match="the outer wire and hole 0 cross or touch"):
        rect.with_hole(Profile.circle(1.0))  # tangent to both long sides
    with pytest.raises(InvalidInputError, match="cross or touch"):
        rect.with_hole(Profile.circle(1.0 - 0.5 * TOL.linear))  # closer than tol.linear
    ok = rect.with_hole(Profile.circle(1.0 - 3 * TOL.linear))  # farther than tol.linear
    np.testing.assert_allclose(ok.area, 8 - math.pi * (1 - 3e-7) ** 2, rtol=EXACT)
    with pytest.raises(InvalidInputError, match="cross or touch"):
        rect.with_hole(Profile.polygon([(0, 1), (0.5, 0), (-0.5, 0)]))  # a vertex on the outer edge


def test_self_intersections_are_reported_with_segments_and_point():
    with pytest.raises(InvalidInputError, match=r"the outer wire intersects itself: its segments \d and \d cross or touch near"):
        Profile.polygon([(0, 0), (2, 0), (2, 2), (0, 2), (0, 1), (3, 1)])
    with pytest.raises(InvalidInputError, match="intersects itself"):
        Profile.polygon([(0, 0), (2, 0), (1, 1), (2, 2), (0, 2), (1, 1)])  # two vertices touch
    with pytest.raises(InvalidInputError, match=r"its segments 0 and 3 cross or touch near \[1.5, 0.0\]"):
        Profile.polygon([(0, 0), (3, 0), (3, 1), (1.5, 0), (1, 2)])  # vertex 3 on edge 0
    figure8 = [(0, 0), (1, 1), (2, 0), (3, -1), (4, 0), (3, 1), (2, 0.0001), (1, -1), (0, -0.3)]
    with pytest.raises(InvalidInputError, match="its segment 0 crosses or touches itself near"):
        Profile.from_wires([Segment.spline(figure8), Segment.line((0, -0.3), (0, 0))])
    with pytest.raises(InvalidInputError, match="folds back on itself where segment 0 meets segment 1"):
        Profile.polygon([(0, 0), (2, 0), (1, 0), (1, 1)])
    with pytest.raises(InvalidInputError, match="encloses zero area"):
        Profile.polygon([(0, 0), (1, 1), (1, 0), (0, 1)])  # symmetric bow-tie: zero net area


def test_hole_placement_errors():
    base = Profile.rectangle(4.0, 4.0)
    with pytest.raises(InvalidInputError, match=r"hole 0 is not inside the outer wire \(its start point"):
        base.with_hole(Profile.circle(0.5, center=(5, 0)))
    with pytest.raises(InvalidInputError, match="cross or touch"):
        base.with_hole(Profile.circle(1.0, center=(1.5, 0)))  # crosses the outer wire
    with pytest.raises(InvalidInputError, match="hole 0 and hole 1 cross or touch|hole 1 and hole 0 cross or touch"):
        base.with_hole(Profile.circle(0.6, center=(-0.5, 0))).with_hole(Profile.circle(0.6, center=(0.5, 0)))
    with pytest.raises(InvalidInputError, match="hole 1 lies inside hole 0; holes must not overlap"):
        base.with_hole(Profile.circle(1.5)).with_hole(Profile.circle(0.5))
    with pytest.raises(InvalidInputError, match="hole 0 lies inside hole 1"):
        base.with_hole(Profile.circle(0.5)).with_hole(Profile.circle(1.5))


# ============================================================================ bad input
def test_wire_errors_name_the_segment():
    with pytest.raises(InvalidInputError, match=r"the outer wire is not closed: segment 1 ends at \[1.0, 1.0\] but "
                                                r"segment 2 starts at \[1.0, 1.1\] \(gap 0.1 > tol.linear = 1e-07\)"):
        Profile.from_wires([Segment.line((0, 0), (1, 0)), Segment.line((1, 0), (1, 1)), Segment.line((1, 1.1), (0, 0))])
    with pytest.raises(InvalidInputError, match="hole 0 is not closed: segment 2"):
        Profile.rectangle(4, 4).with_hole([Segment.line((0, 0), (1, 0)), Segment.line((1, 0), (1, 1)),
                                           Segment.line((1, 1), (0, 0.5))])
    with pytest.raises(InvalidInputError, match=r"segment 1 of the outer wire is not in the profile plane: point "
                                                r"\[1.0, 1.0, 0.01\] is 0.01 from it"):
        Profile.from_wires([Segment.line((0, 0, 0), (1, 0, 0)), Segment.line((1, 0, 0), (1, 1, 0.01)),
                            Segment.line((1, 1, 0.01), (0, 0, 0))])
    with pytest.raises(InvalidInputError, match="segment 0 of the outer wire is degenerate: its size 0"):
        Profile.from_wires([Segment.line((0, 0), (0, 0)), Segment.line((0, 0), (1, 1)), Segment.line((1, 1), (0, 0))])
    with pytest.raises(InvalidInputError, match="segment 0 of the outer wire: arc_through points .* are coincident or collinear"):
        Profile.from_wires([Segment.arc_through((0, 0), (1, 0), (2, 0)), Segment.line((2, 0), (0, 0))])
    with pytest.raises(InvalidInputError, match="segment 1 of the outer wire must be a Segment, got str"):
        Profile.from_wires([Segment.line((0, 0), (1, 0)), "x"])
    with pytest.raises(InvalidInputError, match="outer wire must be a sequence of Segment, got Segment"):
        Profile.from_wires(Segment.line((0, 0), (1, 1)))
    with pytest.raises(InvalidInputError, match="outer wire is empty"):
        Profile.from_wires([])
    with pytest.raises(InvalidInputError, match="holes must be a sequence of wires, got int"):
        Profile(Profile.rectangle(1, 1).outer, 3)
    with pytest.raises(InvalidInputError, match="a closed wire needs at least two segments"):
        Profile.from_wires([Segment.line((0, 0), (1, 0))])
    with pytest.raises(InvalidInputError, match="segment 0 of the outer wire: cannot interpolate the spline points"):
        Profile.from_wires([Segment.spline([(0, 0), (0, 0), (1, 1)]), Segment.line((1, 1), (0, 0))])


def test_segment_and_constructor_errors():
    with pytest.raises(InvalidInputError, match="polygon points must be finite"):
        Profile.polygon([(0, 0), (1, 0), (np.nan, 1)])
    with pytest.raises(InvalidInputError, match="polygon needs at least 3 points, got 2"):
        Profile.polygon([(0, 0), (1, 0)])
    with pytest.raises(InvalidInputError, match=r"polygon points must have shape \(k, 2\) or \(k, 3\)"):
        Profile.polygon(np.zeros((4, 4)))
    with pytest.raises(InvalidInputError, match="rectangle sizes must be > 0"):
        Profile.rectangle(0.0, 1.0)
    with pytest.raises(InvalidInputError, match="width must be a finite number"):
        Profile.rectangle(math.inf, 1.0)
    with pytest.raises(InvalidInputError, match="arc radius must be > 0, got -1"):
        Profile.circle(-1)
    with pytest.raises(InvalidInputError, match="arc radius must be a finite number"):
        Segment.arc((0, 0), "r", 0, 90)
    with pytest.raises(InvalidInputError, match="arc sweep end_deg - start_deg must be non-zero and at most 360"):
        Segment.arc((0, 0), 1, 10, 10)
    with pytest.raises(InvalidInputError, match="at most 360 in magnitude, got 400.0"):
        Segment.arc((0, 0), 1, 0, 400)
    with pytest.raises(InvalidInputError, match=r"arc center must have shape \(1, 2\) or \(1, 3\)"):
        Segment.arc((0, 0, 0, 0), 1, 0, 90)
    with pytest.raises(InvalidInputError, match="line points must be numbers"):
        Segment.line((0, 0), (1, 1, 1))
    with pytest.raises(InvalidInputError, match="line end must be finite"):
        Segment.line((0, 0), (1, np.inf))
    with pytest.raises(InvalidInputError, match="arc_through middle must have shape"):
        Segment.arc_through((0, 0), (1,), (2, 0))
    with pytest.raises(InvalidInputError, match="spline needs at least 2 points, got 1"):
        Segment.spline([(0, 0)])
    with pytest.raises(InvalidInputError, match="spline degree must be an integer >= 1, got 0"):
        Segment.spline([(0, 0), (1, 1)], degree=0)
    with pytest.raises(InvalidInputError, match="spline curve must be 2-D or 3-D, got dimension 4"):
        Segment.spline(NurbsCurve(np.zeros((2, 4)) + [[0, 0, 0, 0], [1, 1, 1, 1]], [0, 0, 1, 1], 1))


def test_plane_and_with_hole_errors():
    with pytest.raises(InvalidInputError, match="plane must be None, a PlanarSurface, .* got 'xy'"):
        Profile.rectangle(1, 1, plane="xy")
    with pytest.raises(InvalidInputError, match=r"plane normal must be non-zero, got \(0, 0, 0\)"):
        Profile.rectangle(1, 1, plane=((0, 0, 0), (0, 0, 0)))
    with pytest.raises(InvalidInputError, match="plane origin must be 3 finite numbers"):
        Profile.rectangle(1, 1, plane=((0, 0), (0, 0, 1)))
    with pytest.raises(InvalidInputError, match="plane: PlanarSurface: x_dir .* is parallel to the axis"):
        Profile.rectangle(1, 1, plane=((0, 0, 0), (0, 0, 1), (0, 0, 2)))
    with pytest.raises(InvalidInputError, match="with_hole: the hole profile has 1 hole"):
        Profile.rectangle(4, 4).with_hole(Profile.rectangle(1, 1).with_hole(Profile.circle(0.1)))
    with pytest.raises(InvalidInputError, match="with_hole: the hole's plane is not the profile's plane"):
        Profile.rectangle(4, 4).with_hole(Profile.circle(1, plane=((0, 0, 1), (0, 0, 1))))
    with pytest.raises(InvalidInputError, match="with_hole: the hole's plane is not the profile's plane"):
        Profile.rectangle(4, 4).with_hole(Profile.circle(1, plane=((0, 0, 0), (0, 1, 1))))
