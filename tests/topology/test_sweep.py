"""Sweeps: every result passes check(); volumes and areas against closed forms (prism, tube,
cylinder, cone, sphere, torus, Pappus for any revolved profile, Cavalieri for oblique prisms,
frusta for lofts) to 1e-10 relative; against OCCT's GProp (build123d extrude / revolve / loft of
the same profile, edges built from the same exact curves) to 1e-8 relative on curved profiles;
face counts stated and compared with OCCT's; watertight tessellations; every bad-input branch.

Face counts differ from OCCT's only by seams (``docs/brep.md``): OCCT closes a full turn with one
seam per profile vertex and keeps a full circle as one edge, coons splits a full turn into two
half-turn faces per segment and a circle into two half arcs.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from coons.errors import InvalidInputError
from coons.kernel.analytic import PlanarSurface
from coons.kernel.curve import NurbsCurve
from coons.topology.check import check
from coons.topology.mass import face_areas
from coons.topology.profile import Profile, Segment
from coons.topology.shape import Solid
from coons.topology.sweep import extrude, loft, revolve
from coons.topology.tessellate import tessellate

#: Closed forms: exact integrals of exact geometry, so round-off only (mass integrates analytic
#: faces to ~1e-15 and rational NURBS faces to ~1e-13 relative).
RTOL = 1e-10
#: Areas of NURBS faces: coons.topology.mass integrates |Su x Sv| (not polynomial) with a fixed
#: Gauss rule per knot span, measured 2.4e-8 relative on the extruded spline face below (the
#: exact length by adaptive quadrature); volumes have polynomial integrands and stay at RTOL.
NURBS_AREA_RTOL = 1e-7
#: Acceptance criterion against OCCT's GProp on curved profiles.
OCCT_RTOL = 1e-8
#: OCCT integrates the area of B-spline faces only to ~1e-7 relative (its default GProp
#: precision); analytic faces agree to round-off.
OCCT_AREA_RTOL = 1e-6
XZ = ((0.0, 0.0, 0.0), (0.0, -1.0, 0.0), (1.0, 0.0, 0.0))  # the xz plane: u = x, v = z
ORIGIN, Z = (0.0, 0.0, 0.0), (0.0, 0.0, 1.0)


def valid(s: Solid) -> Solid:
    report = check(s)
    assert report.ok, report.summary()
    return s


def counts(s: Solid) -> tuple[int, int, int]:
    b = s.brep
    return b.n_vertices, b.n_edges, b.n_faces


def pappus(p: Profile, degrees: float, origin=ORIGIN, axis=Z) -> float:
    """Volume swept by a region turning about an axis: angle × (centroid's distance) × area."""
    A = np.asarray(axis, float) / np.linalg.norm(axis)
    d = p.centroid - np.asarray(origin, float)
    return math.radians(degrees) * float(np.linalg.norm(d - (d @ A) * A)) * p.area


def perimeter(p: Profile) -> float:
    total = 0.0
    for w in p.wires:
        for s in w:
            total += s.curve.length() if s.kind == "spline" else (s.radius * abs(s.sweep) if s.kind == "arc" else s.domain[1])
    return total


def spline_profile() -> Profile:
    """Lines, a cubic spline and an arc in the xz plane, off the z axis."""
    return Profile.from_wires([Segment.line((1, 0), (3, 0)), Segment.spline([(3, 0), (3.5, 1), (2.5, 2), (3, 3)]),
                               Segment.line((3, 3), (1, 3)), Segment.arc_through((1, 3), (0.5, 1.5), (1, 0))], plane=XZ)


# ============================================================================ extrude
def test_extruded_rectangle_with_circular_hole_closed_forms_and_topology():
    w, h, r, d = 4.0, 2.0, 0.5, 3.0
    s = valid(extrude(Profile.rectangle(w, h).with_hole(Profile.circle(r)), d))
    np.testing.assert_allclose(s.volume, (w * h - math.pi * r * r) * d, rtol=RTOL)
    np.testing.assert_allclose(s.area, 2 * (w * h - math.pi * r * r) + 2 * (w + h) * d + 2 * math.pi * r * d, rtol=RTOL)
    # 2 caps, 4 planes, 2 half cylinders (OCCT: 7, one cylinder with a seam); genus 1: V - E + F - (L - F) = 0.
    assert counts(s) == (12, 18, 8) and s.brep.n_loops == 10
    assert sorted(s.surface_types()) == ["cylinder"] * 2 + ["plane"] * 6
    assert [f.sense for f in s.faces() if f.surface_type == "cylinder"] == [False, False]  # walls face the hole
    np.testing.assert_allclose(s.bounding_box(), [[-2, -1, 0], [2, 1, 3]], atol=1e-12)
    down = valid(extrude(Profile.rectangle(w, h).with_hole(Profile.circle(r)), -d))
    np.testing.assert_allclose(down.volume, s.volume, rtol=RTOL)
    np.testing.assert_allclose(down.bounding_box(), [[-2, -1, -3], [2, 1, 0]], atol=1e-12)


def test_extrusion_of_arcs_splines_and_lines():
    p = spline_profile()
    s = valid(extrude(p, 2.0))
    np.testing.assert_allclose(s.volume, p.area * 2.0, rtol=RTOL)
    np.testing.assert_allclose(s.area, 2 * p.area + perimeter(p) * 2.0, rtol=NURBS_AREA_RTOL)
    assert sorted(s.surface_types()) == ["bspline", "cylinder"] + ["plane"] * 4
    box = s.bounding_box()
    np.testing.assert_allclose(box[:, 1], [-2.0, 0.0], atol=1e-12)  # the xz plane's normal is -y


@settings(max_examples=25)
@given(st.floats(-2, 2), st.floats(-2, 2), st.floats(0.3, 3), st.booleans())
def test_oblique_extrusions_keep_cavalieris_volume(vx, vy, vz, down):
    p = Profile.rectangle(3, 2).with_hole(Profile.circle(0.4, center=(0.5, 0)))
    V = np.array([vx, vy, -vz if down else vz])
    s = valid(extrude(p, V))
    np.testing.assert_allclose(s.volume, p.area * vz, rtol=RTOL)
    oblique = math.hypot(vx, vy) > 1e-7
    assert s.surface_types().count("bspline") == (2 if oblique else 0)
    assert s.surface_types().count("cylinder") == (0 if oblique else 2)


def test_extrusion_in_a_tilted_plane_and_bounding_box():
    plane = ((1.0, 2.0, 3.0), (1.0, 1.0, 1.0))
    p = Profile.circle(1.0, plane=plane)
    s = valid(extrude(p, 2.0))
    np.testing.assert_allclose(s.volume, 2 * math.pi, rtol=RTOL)
    n = np.ones(3) / math.sqrt(3)
    top = s.bounding_box().mean(axis=0)
    np.testing.assert_allclose(top, np.array([1.0, 2.0, 3.0]) + n, atol=1e-9)


# ============================================================================ revolve
def test_revolved_rectangles_tube_and_cylinder():
    R1, R2, H = 2.0, 3.0, 2.0
    tube = valid(revolve(Profile.rectangle(R2 - R1, H, center=(2.5, 0), plane=XZ), ORIGIN, Z))
    np.testing.assert_allclose(tube.volume, math.pi * (R2**2 - R1**2) * H, rtol=RTOL)
    np.testing.assert_allclose(tube.area, 2 * math.pi * (R2**2 - R1**2) + 2 * math.pi * H * (R1 + R2), rtol=RTOL)
    assert counts(tube) == (8, 16, 8)  # genus 1; OCCT: 4 faces, each with a seam
    assert sorted(tube.surface_types()) == ["cylinder"] * 4 + ["plane"] * 4
    cyl = valid(revolve(Profile.rectangle(1.0, H, center=(0.5, 0), plane=XZ), ORIGIN, Z))
    np.testing.assert_allclose(cyl.volume, math.pi * H, rtol=RTOL)
    np.testing.assert_allclose(cyl.area, 2 * math.pi + 2 * math.pi * H, rtol=RTOL)
    # The segment on the axis collapses; its ends are poles: V 2 + 2 x 2, F 3 segments x 2 halves.
    assert counts(cyl) == (6, 10, 6)


def test_revolved_half_disk_is_a_sphere_and_circle_a_torus():
    R = 1.5
    half = Profile.from_wires([Segment.arc((0, 0), R, -90, 90), Segment.line((0, R), (0, -R))], plane=XZ)
    sph = valid(revolve(half, ORIGIN, Z))
    np.testing.assert_allclose(sph.volume, 4 / 3 * math.pi * R**3, rtol=RTOL)
    np.testing.assert_allclose(sph.area, 4 * math.pi * R**2, rtol=RTOL)
    assert counts(sph) == (2, 2, 2) and sph.surface_types() == ["sphere"] * 2  # the Sphere primitive's topology
    Rt, r = 2.0, 0.5
    tor = valid(revolve(Profile.circle(r, center=(Rt, 0), plane=XZ), ORIGIN, Z))
    np.testing.assert_allclose(tor.volume, 2 * math.pi**2 * Rt * r * r, rtol=RTOL)
    np.testing.assert_allclose(tor.area, 4 * math.pi**2 * Rt * r, rtol=RTOL)
    assert counts(tor) == (4, 8, 4) and tor.surface_types() == ["torus"] * 4  # the Torus primitive's topology


def test_revolved_triangle_is_a_cone_and_axis_sense():
    R, H = 1.0, 2.0
    tri = Profile.polygon([(0, 0), (R, 0), (0, H)], plane=XZ)
    cone = valid(revolve(tri, ORIGIN, Z))
    np.testing.assert_allclose(cone.volume, math.pi * R * R * H / 3, rtol=RTOL)
    np.testing.assert_allclose(cone.area, math.pi * R * R + math.pi * R * math.hypot(R, H), rtol=RTOL)
    assert sorted(cone.surface_types()) == ["cone", "cone", "plane", "plane"]
    # A quarter turn counter-clockwise about +z sweeps from +x into +y; about -z into -y.
    q_pos = valid(revolve(tri, ORIGIN, Z, 90))
    q_neg = valid(revolve(tri, ORIGIN, (0, 0, -1), 90))
    np.testing.assert_allclose(q_pos.bounding_box(), [[0, 0, 0], [1, 1, 2]], atol=1e-12)
    np.testing.assert_allclose(q_neg.bounding_box(), [[0, -1, 0], [1, 0, 2]], atol=1e-12)
    # The same profile on the other side of the axis.
    mirrored = valid(revolve(Profile.polygon([(0, 0), (-R, 0), (0, H)], plane=XZ), ORIGIN, Z))
    np.testing.assert_allclose(mirrored.volume, cone.volume, rtol=RTOL)


def bulged_profile() -> Profile:
    """Touches the axis along a segment; an arc off the axis (torus), lines (disks, cylinder)."""
    return Profile.from_wires([Segment.line((0, 0), (2, 0)), Segment.arc((2, 1), 1.0, -90, 90),
                               Segment.line((2, 2), (0, 2)), Segment.line((0, 2), (0, 0))], plane=XZ)


@settings(max_examples=25)
@given(st.floats(1.0, 359.0))
def test_partial_revolutions_scale_linearly(degrees):
    p = bulged_profile()
    full = revolve(p, ORIGIN, Z)
    part = valid(revolve(p, ORIGIN, Z, degrees))
    f = degrees / 360.0
    np.testing.assert_allclose(full.volume, pappus(p, 360.0), rtol=RTOL)
    np.testing.assert_allclose(part.volume, f * full.volume, rtol=RTOL)
    np.testing.assert_allclose(part.area, f * full.area + 2 * p.area, rtol=RTOL)
    # One face per segment off the axis, two caps; the axis segment is the edge where the caps meet.
    assert counts(part)[2] == 3 + 2 and counts(full)[2] == 2 * 3
    caps = [a for a, f_ in zip(face_areas(part), part.faces()) if isinstance(f_.surface, PlanarSurface)
            and abs(abs(f_.surface.axis[2]) - 1.0) > 1e-9]
    np.testing.assert_allclose(caps, [p.area, p.area], rtol=RTOL)


def test_revolved_profile_with_hole_full_turn_has_a_void_and_partial_turn_caps_with_holes():
    ring = Profile.rectangle(2, 2, center=(3, 0), plane=XZ).with_hole(Profile.circle(0.5, center=(3, 0), plane=XZ))
    full = valid(revolve(ring, ORIGIN, Z))
    np.testing.assert_allclose(full.volume, pappus(ring, 360), rtol=RTOL)
    assert full.brep.n_solids == 1 and full.brep.n_shells == 2  # the torus-shaped void
    part = valid(revolve(ring, ORIGIN, Z, 90))
    np.testing.assert_allclose(part.volume, pappus(ring, 90), rtol=RTOL)
    assert part.brep.n_shells == 1 and part.brep.n_loops == part.brep.n_faces + 2  # a hole in each cap
    c_shape = Profile.polygon([(0, 0), (2, 0), (2, 3), (0, 3), (0, 2), (1, 2), (1, 1), (0, 1)], plane=XZ)
    chamber = valid(revolve(c_shape, ORIGIN, Z))  # the notch touching the axis becomes a closed cavity
    np.testing.assert_allclose(chamber.volume, pappus(c_shape, 360), rtol=RTOL)
    assert chamber.brep.n_shells == 2


def test_splines_revolve_as_nurbs_over_their_run_of_segments():
    p = spline_profile()
    s = valid(revolve(p, ORIGIN, Z))
    np.testing.assert_allclose(s.volume, pappus(p, 360), rtol=RTOL)
    assert s.surface_types() == ["bspline"] * 8  # no pole: the spline's run is the whole wire
    # Poles separate an analytic run (disks, cylinder) from the spline's run.
    mixed = Profile.from_wires([Segment.line((0, 0), (2, 0)), Segment.line((2, 0), (2, 3)), Segment.line((2, 3), (0, 3)),
                                Segment.line((0, 3), (0, 2)), Segment.spline([(0, 2), (1, 1.5), (0, 1)]),
                                Segment.line((0, 1), (0, 0))], plane=XZ)
    m = valid(revolve(mixed, ORIGIN, Z))
    np.testing.assert_allclose(m.volume, pappus(mixed, 360), rtol=RTOL)
    assert sorted(m.surface_types()) == ["bspline"] * 2 + ["cylinder"] * 2 + ["plane"] * 4
    m90 = valid(revolve(mixed, ORIGIN, Z, 120))
    np.testing.assert_allclose(m90.volume, pappus(mixed, 120), rtol=RTOL)


def test_spindle_arcs_and_vertices_on_the_axis():
    rc, r = 0.5, 1.0
    zc = math.sqrt(r * r - rc * rc)
    spindle = Profile.from_wires([Segment.arc_through((0, -zc), (rc + r, 0), (0, zc)), Segment.line((0, zc), (0, -zc))],
                                 plane=XZ)
    s = valid(revolve(spindle, ORIGIN, Z))
    np.testing.assert_allclose(s.volume, pappus(spindle, 360), rtol=RTOL)
    assert s.surface_types() == ["bspline"] * 2  # a spindle torus has no ToroidalSurface: exact NURBS
    tri = Profile.polygon([(0, 0), (2, 0), (1, 1)], plane=XZ)  # touches the axis at a vertex only
    wedge = valid(revolve(tri, ORIGIN, Z, 90))
    np.testing.assert_allclose(wedge.volume, pappus(tri, 90), rtol=RTOL)
    with pytest.raises(InvalidInputError, match="a full turn would pinch the solid to a point there"):
        revolve(tri, ORIGIN, Z)


# ============================================================================ loft
def test_loft_of_equal_circles_is_a_cylinder_and_of_scaled_circles_a_frustum():
    c = valid(loft([Profile.circle(1.0), Profile.circle(1.0, plane=((0, 0, 2), Z))]))
    np.testing.assert_allclose(c.volume, 2 * math.pi, rtol=RTOL)
    np.testing.assert_allclose(c.area, 2 * math.pi + 4 * math.pi, rtol=RTOL)
    assert counts(c) == (4, 6, 4)  # OCCT's ThruSections: 3 faces, one seam
    sections = [Profile.circle(1.0 - 0.25 * k, plane=((0, 0, k), Z)) for k in range(3)]
    f = valid(loft(sections))
    np.testing.assert_allclose(f.volume, math.pi * 2 / 3 * (1 + 0.5 + 0.25), rtol=RTOL)


def test_ruled_and_smooth_lofts_through_three_circles():
    sections = [Profile.circle(r, plane=((0, 0, z), Z)) for r, z in ((1.0, 0), (0.5, 1), (1.0, 2))]
    ruled = valid(loft(sections, ruled=True))
    np.testing.assert_allclose(ruled.volume, 2 * math.pi / 3 * (1 + 0.5 + 0.25), rtol=RTOL)
    # Quadratic skinning: by symmetry the sections sit at v = 0, 1/2, 1, so r(v) = 1 - 2v + 2v²,
    # z = 2v and V = 2π ∫ r² dv = 14π/15.
    smooth = valid(loft(sections))
    np.testing.assert_allclose(smooth.volume, 14 * math.pi / 15, rtol=RTOL)


def test_loft_through_tilted_sections_of_different_kinds():
    n1 = np.array([1.0, 0.0, 1.0]) / math.sqrt(2)
    sections = [Profile.circle(1.0), Profile.circle(0.8, plane=((1, 0, 3), n1)),
                Profile.rectangle(1, 1, plane=((3, 0, 4), (1, 0, 0.2))), Profile.circle(0.5, plane=((5, 0, 4.5), (1, 0, 0)))]
    s = valid(loft(sections))
    assert counts(s) == (4, 6, 4) and s.volume > 0
    caps = sorted(a for a, f in zip(face_areas(s), s.faces()) if f.surface_type == "plane")
    np.testing.assert_allclose(caps, [math.pi * 0.25, math.pi], rtol=RTOL)


def test_ruled_square_frustum_and_sections_given_upside_down():
    h = 3.0
    down = ((0, 0, 0), (0, 0, -1))  # normals against the stacking direction: flipped internally
    sq = [Profile.rectangle(2, 2, plane=(down[0], down[1])), Profile.rectangle(1, 1, plane=((0, 0, h), down[1]))]
    s = valid(loft(sq, ruled=True))
    np.testing.assert_allclose(s.volume, h / 3 * (4 + 1 + 2), rtol=RTOL)
    assert counts(s) == (8, 10, 4)  # a vertex at every corner of both caps
    # Sections correspond by their start vertices and arc-length: start the circle towards the
    # square's first corner (-1, -1) for an untwisted loft, whose volume lies between the cylinder's
    # and the prism's; started at angle 0 the loft twists by 135 degrees and pinches.
    circle = Profile.from_wires([Segment.arc((0, 0), 1.0, -135, 225)], plane=((0, 0, h), Z))
    square_to_circle = valid(loft([Profile.rectangle(2, 2), circle]))
    caps = sorted(a for a, f in zip(face_areas(square_to_circle), square_to_circle.faces()) if f.surface_type == "plane")
    np.testing.assert_allclose(caps, [math.pi, 4.0], rtol=RTOL)
    assert 4.0 * h > square_to_circle.volume > math.pi * h
    twisted = valid(loft([Profile.rectangle(2, 2), Profile.circle(1.0, plane=((0, 0, h), Z))]))
    assert twisted.volume < square_to_circle.volume


# ============================================================================ tessellation
@pytest.mark.parametrize("make", [
    lambda: extrude(Profile.rectangle(4, 2).with_hole(Profile.circle(0.5)), (1.0, 0.5, 3.0)),
    lambda: extrude(spline_profile(), 1.0),
    lambda: revolve(bulged_profile(), ORIGIN, Z, 120),
    lambda: revolve(Profile.from_wires([Segment.line((0, 0), (2, 0)), Segment.spline([(2, 0), (2.5, 1), (1.5, 2), (0, 3)]),
                                        Segment.line((0, 3), (0, 0))], plane=XZ), ORIGIN, Z),
    lambda: loft([Profile.rectangle(2, 2), Profile.circle(1.0, plane=((0, 0, 2), Z))], ruled=True),
], ids=["oblique-extrusion", "spline-extrusion", "partial-revolution", "spline-revolution-with-poles", "loft"])
def test_tessellations_are_watertight(make):
    s = make()
    mesh = tessellate(s, deflection=0.01)
    assert mesh.is_closed
    b = s.brep
    assert mesh.euler_characteristic == b.n_vertices - b.n_edges + b.n_faces - (b.n_loops - b.n_faces)
    # Chordal deflection 0.01 on a solid of size ~3 bounds the volume error by ~area x 0.01.
    assert abs(mesh.volume - s.volume) <= 0.01 * s.area


# ============================================================================ bad input
def test_extrude_errors():
    p = Profile.rectangle(2, 2, center=(2, 0), plane=XZ)
    with pytest.raises(InvalidInputError, match="extrude: profile must be a Profile, got str"):
        extrude("p", 1.0)
    with pytest.raises(InvalidInputError, match=r"extrude: distance must be non-zero \(above tol.linear = 1e-07\), got 0.0"):
        extrude(p, 0.0)
    with pytest.raises(InvalidInputError, match="extrude: distance must be a finite number, got nan"):
        extrude(p, float("nan"))
    with pytest.raises(InvalidInputError, match=r"extrude: vector must be non-zero .* got \[0.0, 0.0, 0.0\]"):
        extrude(p, (0, 0, 0))
    with pytest.raises(InvalidInputError, match="extrude: vector must be 3 finite numbers"):
        extrude(p, (np.nan, 0, 0))
    with pytest.raises(InvalidInputError, match="extrude: vector must be 3 finite numbers"):
        extrude(p, (1, 2))
    with pytest.raises(InvalidInputError, match=r"extrude: vector \[1.0, 0.0, 2.0\] lies in the profile plane"):
        extrude(p, (1, 0, 2))


def test_revolve_errors():
    p = Profile.rectangle(2, 2, center=(2, 0), plane=XZ)
    with pytest.raises(InvalidInputError, match="revolve: profile must be a Profile, got NoneType"):
        revolve(None, ORIGIN, Z)
    for bad in (0, -10, 360.5, float("nan")):
        with pytest.raises(InvalidInputError, match="revolve: degrees must be"):
            revolve(p, ORIGIN, Z, bad)
    with pytest.raises(InvalidInputError, match=r"revolve: axis_direction must be non-zero, got \(0, 0, 0\)"):
        revolve(p, ORIGIN, (0, 0, 0))
    with pytest.raises(InvalidInputError, match="revolve: axis_origin must be 3 finite numbers"):
        revolve(p, (0, np.inf, 0), Z)
    with pytest.raises(InvalidInputError, match="revolve: the axis must lie in the profile plane: its origin is -1 from"):
        revolve(p, (0, 1, 0), Z)
    with pytest.raises(InvalidInputError, match="revolve: the axis must lie in the profile plane: .* cosine -0.707"):
        revolve(p, ORIGIN, (0, 1, 1))
    with pytest.raises(InvalidInputError, match=r"revolve: the profile crosses the axis: segment 0 of the outer wire "
                                                r"reaches 1 beyond it"):
        revolve(p, (2, 0, 0), Z)
    with pytest.raises(InvalidInputError, match="revolve: segment 0 of the outer wire touches the axis at an interior point"):
        revolve(Profile.from_wires([Segment.arc((1, 0), 1, 90, 270), Segment.line((1, -1), (1, 1))], plane=XZ), ORIGIN, Z)
    with pytest.raises(InvalidInputError, match="the profile touches the axis at the vertex where segment 0 of the outer "
                                                "wire and segment 1 of the outer wire meet"):
        revolve(Profile.circle(1, center=(1, 0), plane=XZ), ORIGIN, Z)


def test_loft_errors():
    c0 = Profile.circle(1)
    with pytest.raises(InvalidInputError, match="loft needs a sequence of at least 2 profiles, got 1"):
        loft([c0])
    with pytest.raises(InvalidInputError, match="loft needs a sequence of at least 2 profiles, got 1"):
        loft(c0)
    with pytest.raises(InvalidInputError, match="loft: section 1 must be a Profile, got str"):
        loft([c0, "x"])
    with pytest.raises(InvalidInputError, match=r"loft: section 0 has 1 hole\(s\); loft uses outer wires only"):
        loft([Profile.rectangle(3, 3).with_hole(c0), Profile.circle(1, plane=((0, 0, 1), Z))])
    with pytest.raises(InvalidInputError, match="loft: sections 0 and 1 have opposite orientations"):
        loft([c0, Profile.circle(1, plane=((0, 0, 1), (0, 0, -1)))])
    with pytest.raises(InvalidInputError, match="loft: section 1 does not advance from section 0 along its normal"):
        loft([c0, Profile.circle(1, center=(5, 0))])
    with pytest.raises(InvalidInputError, match="loft: sections 1 and 2 coincide"):
        loft([c0, Profile.circle(1, plane=((0, 0, 1), Z)), Profile.circle(1, plane=((0, 0, 1), Z))])
    # A rational spline starting with weight 2 and ending with weight 1, lofted to a polygon: the two
    # halves' rails would interpolate differently weighted copies of the same points.
    rational = NurbsCurve([[1, 0], [1, 1], [0, 1]], [0, 0, 0, 1, 1, 1], 2, [2.0, 1.0, 1.0])
    quarter = [Segment.spline(rational), Segment.line((0, 1), (0, 0)), Segment.line((0, 0), (1, 0))]
    with pytest.raises(InvalidInputError, match=r"end weights that differ by different factors \(\[0.5, 1.0\]\)"):
        loft([Profile.from_wires(quarter), Profile.polygon([(1, 0), (1, 1), (0, 1), (0, 0)], plane=((0, 0, 1), Z))])
    same = valid(loft([Profile.from_wires(quarter), Profile.from_wires(quarter, plane=((0, 0, 1), Z))]))
    np.testing.assert_allclose(same.volume, math.pi / 4, rtol=RTOL)  # equal factors: a quarter cylinder


# ============================================================================ OCCT
def _occt_edge(seg: Segment, plane):
    import build123d as bd
    from OCP.BRepBuilderAPI import BRepBuilderAPI_MakeEdge
    from OCP.collections import Array1_double, Array1_gp_Pnt, Array1_int
    from OCP.Geom import Geom_BSplineCurve
    from OCP.gp import gp_Pnt

    if seg.kind == "line":
        return bd.Edge.make_line(*(tuple(x) for x in plane.evaluate(*seg.points.T)))
    if seg.kind == "arc":
        t0, t1 = seg.domain
        P = plane.evaluate(*seg.evaluate(np.array([t0, 0.5 * (t0 + t1), t1])).T)
        return bd.Edge.make_three_point_arc(*(tuple(x) for x in P))
    c = seg.to_nurbs(plane)
    k, m = c.knot_multiplicities

    def arr(values, kind):
        a = kind(1, len(values))
        for i, x in enumerate(values, 1):
            a.SetValue(i, x)
        return a

    g = Geom_BSplineCurve(arr([gp_Pnt(*x) for x in c.control_points], Array1_gp_Pnt), arr(c.weights.tolist(), Array1_double),
                          arr(k.tolist(), Array1_double), arr([int(x) for x in m], Array1_int), c.degree, False)
    return bd.Edge(BRepBuilderAPI_MakeEdge(g).Edge())


def occt_face(p: Profile):
    """The same region in OCCT: one edge per segment, from the same exact curves (full circles whole)."""
    import build123d as bd

    def wire(w):
        if len(w) == 2 and all(s.kind == "arc" for s in w) and abs(abs(w[0].sweep) + abs(w[1].sweep) - 2 * math.pi) < 1e-12:
            C = p.plane.evaluate(*w[0].points[0])
            return bd.Wire([bd.Edge.make_circle(w[0].radius, bd.Plane(tuple(C), z_dir=tuple(p.normal)))])
        return bd.Wire([_occt_edge(s, p.plane) for s in w])

    return bd.Face(wire(p.outer), [wire(h) for h in p.holes])


def occt_properties(shape) -> tuple[float, float]:
    from OCP.BRepGProp import BRepGProp
    from OCP.GProp import GProp_GProps

    vp, sp = GProp_GProps(), GProp_GProps()
    BRepGProp.VolumeProperties_s(shape.wrapped, vp)
    BRepGProp.SurfaceProperties_s(shape.wrapped, sp)
    return vp.Mass(), sp.Mass()


def _occt_cases():
    import build123d as bd

    z = bd.Axis((0, 0, 0), (0, 0, 1))
    hole = Profile.rectangle(4, 2).with_hole(Profile.circle(0.5))
    sp = spline_profile()
    ring = Profile.rectangle(2, 2, center=(3, 0), plane=XZ).with_hole(Profile.circle(0.5, center=(3, 0), plane=XZ))
    half = Profile.from_wires([Segment.arc((0, 0), 1.5, -90, 90), Segment.line((0, 1.5), (0, -1.5))], plane=XZ)
    V = (1.0, 0.5, 3.0)
    circles = [Profile.circle(1.0), Profile.circle(1.0, plane=((0, 0, 2), Z))]
    squares = [Profile.rectangle(2, 2), Profile.rectangle(1, 1, plane=((0, 0, 3), Z))]
    # name: (ours, OCCT, our face count, OCCT face count, spline faces present)
    return {
        "extrude-hole": (extrude(hole, 3.0), bd.extrude(occt_face(hole), 3.0, clean=False), 8, 7, False),
        "extrude-oblique": (extrude(hole, V), bd.extrude(occt_face(hole), float(np.linalg.norm(V)), dir=V, clean=False),
                            8, 7, True),
        "extrude-spline": (extrude(sp, 2.0), bd.extrude(occt_face(sp), 2.0, dir=(0, -1, 0), clean=False), 6, 6, True),
        "revolve-spline": (revolve(sp, ORIGIN, Z), bd.revolve(occt_face(sp), z, 360, clean=False), 8, 4, True),
        "revolve-spline-120": (revolve(sp, ORIGIN, Z, 120), bd.revolve(occt_face(sp), z, 120, clean=False), 6, 6, True),
        "revolve-ring": (revolve(ring, ORIGIN, Z), bd.revolve(occt_face(ring), z, 360, clean=False), 12, 5, False),
        "revolve-ring-90": (revolve(ring, ORIGIN, Z, 90), bd.revolve(occt_face(ring), z, 90, clean=False), 8, 7, False),
        "revolve-sphere": (revolve(half, ORIGIN, Z), bd.revolve(occt_face(half), z, 360, clean=False), 2, 1, False),
        "loft-cylinder": (loft(circles), bd.loft([occt_face(c) for c in circles], clean=False), 4, 3, True),
        "loft-frustum": (loft(squares, ruled=True), bd.loft([occt_face(c) for c in squares], ruled=True, clean=False),
                         4, 6, False),
    }


@pytest.mark.occt
def test_volumes_areas_and_face_counts_agree_with_occt():
    for name, (ours, theirs, n_ours, n_occt, nurbs) in _occt_cases().items():
        valid(ours)
        V, A = occt_properties(theirs)
        np.testing.assert_allclose(ours.volume, V, rtol=OCCT_RTOL, err_msg=name)
        np.testing.assert_allclose(ours.area, A, rtol=OCCT_AREA_RTOL if nurbs else RTOL, err_msg=name)
        assert (len(ours.faces()), len(theirs.faces())) == (n_ours, n_occt), name
