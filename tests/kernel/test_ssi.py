"""Tests of coons.kernel.ssi: general surface–surface intersection and curve–surface intersection."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial import cKDTree

from coons.errors import InvalidInputError
from coons.kernel.analytic import (
    Circle,
    ConicalSurface,
    CylindricalSurface,
    Line,
    PlanarSurface,
    SphericalSurface,
    ToroidalSurface,
)
from coons.kernel.curve import NurbsCurve
from coons.kernel.fitting import interpolate_curve, interpolate_surface
from coons.kernel.intersect import IntersectionCurve, SurfaceIntersection
from coons.kernel.ssi import intersect_curve_surface, march_intersection
from coons.kernel.surface import NurbsSurface
from coons.tolerance import Tolerance

PI = math.pi
TOL = Tolerance()
#: Points of a fitted branch, between its samples, may exceed the measured tol slightly.
ON = 2 * TOL.linear


def _distance(surface, points):
    if isinstance(surface, NurbsSurface):
        return surface.closest_points(points).distances
    return np.abs(surface.implicit(points))


def _samples(c: IntersectionCurve, n: int = 301) -> np.ndarray:
    return c.curve.evaluate(np.linspace(c.t0, c.t1, n))


def _check_branches(result, a, b, box_a=None, box_b=None):
    """Every branch lies on both surfaces, its p-curves reproduce it and stay in the boxes."""
    assert isinstance(result, SurfaceIntersection)
    for c in result.curves:
        assert isinstance(c, IntersectionCurve)
        t = np.linspace(c.t0, c.t1, 301)
        P = c.curve.evaluate(t)
        assert _distance(a, P).max() <= ON
        assert _distance(b, P).max() <= ON
        pa, pb = c.pcurve_a.evaluate(t), c.pcurve_b.evaluate(t)
        assert np.linalg.norm(a.evaluate(pa[:, 0], pa[:, 1]) - P, axis=1).max() <= ON
        assert np.linalg.norm(b.evaluate(pb[:, 0], pb[:, 1]) - P, axis=1).max() <= ON
        assert 0.0 <= c.tol <= TOL.linear
        for box, pc in ((box_a, pa), (box_b, pb)):
            if box is not None:
                lo, hi = np.array(box)[:, 0], np.array(box)[:, 1]
                slack = 1e-9 * np.maximum(1.0, hi - lo)
                assert np.all(pc >= lo - slack) and np.all(pc <= hi + slack)


# ---------------------------------------------------------------------------- quadric pairs
CYL_Z = CylindricalSurface([0, 0, 0], [0, 0, 1], [1, 0, 0], 1.0)


def test_crossing_cylinders_of_different_radii():
    # A thin cylinder (axis x, r = 0.6) through a thick one (axis z, R = 1): one loop per side.  The
    # loops wind once around the thin cylinder, so its periodic box cuts each at its seam: one closed
    # branch per side, from the seam back to it.
    thin = CylindricalSurface([0, 0, 0], [1, 0, 0], [0, 1, 0], 0.6)
    box_a, box_b = ((PI / 2, 5 * PI / 2), (-2, 2)), ((0.5, 0.5 + 2 * PI), (-2, 2))
    r = march_intersection(CYL_Z, thin, box_a, box_b)
    assert len(r.curves) == 2
    _check_branches(r, CYL_Z, thin, box_a, box_b)
    sides = sorted(np.sign(_samples(c)[:, 0].mean()) for c in r.curves)
    assert sides == [-1.0, 1.0]
    for c in r.curves:
        P = _samples(c)
        np.testing.assert_allclose(P[0], P[-1], rtol=0, atol=TOL.linear)
        assert c.closed
        ub = c.pcurve_b.evaluate([c.t0, c.t1])[:, 0]
        np.testing.assert_allclose(sorted(ub), [0.5, 0.5 + 2 * PI], rtol=0, atol=1e-9)
        # Each loop is x = ±sqrt(1 - y²) with y² + z² = 0.36.
        np.testing.assert_allclose(np.abs(P[:, 0]), np.sqrt(1 - P[:, 1] ** 2), rtol=0, atol=ON)


def test_seams_of_both_boxes_cut_the_loops():
    thin = CylindricalSurface([0, 0, 0], [1, 0, 0], [0, 1, 0], 0.6)
    box_a, box_b = ((0, 2 * PI), (-2, 2)), ((0.5, 0.5 + 2 * PI), (-2, 2))
    r = march_intersection(CYL_Z, thin, box_a, box_b)
    _check_branches(r, CYL_Z, thin, box_a, box_b)
    # The x > 0 loop crosses the seam u_a = 0 twice and u_b = 0.5 once: 3 pieces; the x < 0 loop 1.
    assert len(r.curves) == 4
    ends = np.concatenate([c.pcurve_a.evaluate([c.t0, c.t1]) for c in r.curves])
    on_seam = np.isclose(ends[:, 0], 0.0, atol=1e-9) | np.isclose(ends[:, 0], 2 * PI, atol=1e-9)
    assert int(on_seam.sum()) == 4
    total = sum(c.curve.length() for c in r.curves)
    r2 = march_intersection(CYL_Z, thin, ((PI / 2, 5 * PI / 2), (-2, 2)), box_b)
    assert total == pytest.approx(sum(c.curve.length() for c in r2.curves), rel=1e-7)


def test_steinmetz_branches_meet_at_the_singular_points():
    # Equal radii: the intersection is two ellipses in the planes x = z and x = -z, crossing at
    # (0, ±1, 0) where the normals are parallel.  Both seams pass through (0, 1, 0), so the result
    # is exactly the 4 arcs between the two singular points.
    other = CylindricalSurface([0, 0, 0], [1, 0, 0], [0, 1, 0], 1.0)
    box_a, box_b = ((PI / 2, 5 * PI / 2), (-2, 2)), ((0, 2 * PI), (-2, 2))
    r = march_intersection(CYL_Z, other, box_a, box_b)
    assert len(r.curves) == 4
    _check_branches(r, CYL_Z, other, box_a, box_b)
    singular = np.array([[0.0, 1.0, 0.0], [0.0, -1.0, 0.0]])
    planes = []
    for c in r.curves:
        assert not c.closed
        P = _samples(c)
        ends = P[[0, -1]]
        d = np.linalg.norm(ends[:, None, :] - singular[None], axis=2)
        assert sorted(np.argmin(d, axis=1)) == [0, 1]
        assert d.min(axis=1).max() <= TOL.linear
        # Each arc lies in one of the planes x = z, x = -z.
        s = np.sign(np.median(P[:, 0] * P[:, 2]))
        np.testing.assert_allclose(P[:, 0], s * P[:, 2], rtol=0, atol=ON)
        planes.append(s)
    assert sorted(planes) == [-1.0, -1.0, 1.0, 1.0]


@pytest.mark.parametrize("angle", [PI / 2, PI / 3])
@pytest.mark.parametrize("seam", [0.0, PI / 2])
def test_equal_crossing_cylinders_are_two_exact_ellipses_cut_at_the_singular_points(angle, seam):
    # Equal radii, axes meeting at the origin at any angle: (p·Z_a)² = (p·Z_b)², so the intersection is the
    # sections of either cylinder by the bisecting planes p·(Z_a ∓ Z_b) = 0, two ellipses crossing at
    # ±R Z_a × Z_b / |Z_a × Z_b|.  intersect_surfaces gives them exactly (no marching), cut at those points
    # (where n_a × n_b flips) into arcs each running along n_a × n_b.
    from coons.kernel.analytic import Ellipse
    from coons.kernel.intersect import _normals, intersect_surfaces

    R = 1.5
    Zb = np.array([math.sin(angle), 0.0, math.cos(angle)])
    a = CylindricalSurface([0, 0, 0], [0, 0, 1], [math.cos(seam), math.sin(seam), 0], R)
    b = CylindricalSurface([0, 0, 0], Zb, [0, 1, 0], R)
    box = ((seam, seam + 2 * PI), (-6, 6))
    r = intersect_surfaces(a, b, box, ((0, 2 * PI), (-6, 6)))
    _check_branches(r, a, b, box, ((0, 2 * PI), (-6, 6)))
    assert all(isinstance(c.curve, Ellipse) for c in r.curves)
    singular = np.array([[0.0, R, 0.0], [0.0, -R, 0.0]])
    ends = np.concatenate([c.curve.evaluate([c.t0, c.t1]) for c in r.curves])
    touching = np.linalg.norm(ends[:, None] - singular[None], axis=2).min(axis=1) <= TOL.linear
    # Four arcs between the singular points; a box seam through an arc cuts it in two.
    assert int(touching.sum()) == 8 and len(r.curves) == 4 + int((~touching).sum()) // 2
    for c in r.curves:
        t = np.linspace(c.t0, c.t1, 9)[1:-1]
        D = c.curve.derivatives(t, 1)
        P, T = D[:, 0], D[:, 1]
        # Each arc lies in one bisecting plane and runs along n_a × n_b.
        off = np.abs(np.stack([P @ (np.array([0, 0, 1]) - Zb), P @ (np.array([0, 0, 1]) + Zb)])).min(axis=0)
        assert off.max() <= 1e-9
        assert np.all(np.einsum("ij,ij->i", np.cross(_normals(a, P), _normals(b, P)), T) > 0)
    length = sum(float(np.sum(np.linalg.norm(np.diff(c.curve.evaluate(np.linspace(c.t0, c.t1, 2001)), axis=0), axis=1)))
                 for c in r.curves)
    # The two ellipses: semi-axes R and R / cos(θ/2), R / sin(θ/2) (θ the angle of the axes).
    from scipy.special import ellipe

    def perimeter(major):
        return 4 * major * ellipe(1 - (R / major) ** 2)

    expected = perimeter(R / math.cos(angle / 2)) + perimeter(R / math.sin(angle / 2))
    np.testing.assert_allclose(length, expected, rtol=1e-5)


@pytest.mark.parametrize("gap", [0.0, 0.1, 0.9])
def test_nearly_equal_cylinders_with_axes_meeting_off_their_origins(gap):
    # The axes meet at (1, 2, 3), away from both origins; radii differing by a fraction of tol.linear: exact
    # ellipses up to a quarter of it (ending at the singular points or a seam), the marching beyond (whose
    # p-curve fits raised while the exact path took up to a whole tol.linear); all on both cylinders.
    from coons.kernel.analytic import Ellipse
    from coons.kernel.intersect import intersect_surfaces

    C = np.array([1.0, 2.0, 3.0])
    Za, Zb = np.array([0.0, 0.0, 1.0]), np.array([0.6, 0.0, 0.8])
    a = CylindricalSurface(C - 4 * Za, Za, [1, 0, 0], 1.5)
    b = CylindricalSurface(C + 2 * Zb, Zb, [0, 1, 0], 1.5 + gap * TOL.linear)
    boxes = ((0, 2 * PI), (-3, 11)), ((0, 2 * PI), (-8, 6))
    r = intersect_surfaces(a, b, *boxes)
    _check_branches(r, a, b, *boxes)
    exact = gap < 0.25
    assert r.curves and all(isinstance(c.curve, Ellipse) for c in r.curves) == exact
    if exact:  # (beyond, the singular points split into two near-touching loops)
        ends = np.concatenate([c.curve.evaluate([c.t0, c.t1]) for c in r.curves])
        singular = C + np.array([[0.0, 1.5, 0.0], [0.0, -1.5, 0.0]])
        touching = np.linalg.norm(ends[:, None] - singular[None], axis=2).min(axis=1) <= 10 * TOL.linear
        assert int(touching.sum()) == 8  # four arcs between the singular points (seams cut some of them)


def test_steinmetz_with_a_seam_away_from_the_singular_points():
    other = CylindricalSurface([0, 0, 0], [1, 0, 0], [0, 1, 0], 1.0)
    box_a, box_b = ((0, 2 * PI), (-2, 2)), ((0, 2 * PI), (-2, 2))
    r = march_intersection(CYL_Z, other, box_a, box_b)
    _check_branches(r, CYL_Z, other, box_a, box_b)
    # The seam u_a = 0 (x = 1) cuts the two arcs on the x > 0 side.
    assert len(r.curves) == 6
    lengths = sorted(c.curve.length() for c in r.curves)
    # Quarter and half perimeters of the ellipse with semi-axes sqrt(2) and 1.
    quarter = lengths[0]
    np.testing.assert_allclose(lengths, [quarter] * 4 + [2 * quarter] * 2, rtol=1e-6)


@pytest.mark.parametrize("swap", [False, True])
def test_viviani_curve(swap):
    # Sphere of radius R and a cylinder of radius R/2 touching the axis: Viviani's figure-eight,
    # through both poles and with a double point at (R, 0, 0).
    R = 2.0
    sphere = SphericalSurface([0, 0, 0], [0, 0, 1], [1, 0, 0], R)
    cyl = CylindricalSurface([R / 2, 0, 0], [0, 0, 1], [1, 0, 0], R / 2)
    box_c = ((0, 2 * PI), (-3, 3))
    a, b, box_a, box_b = (cyl, sphere, box_c, None) if swap else (sphere, cyl, None, box_c)
    r = march_intersection(a, b, box_a, box_b)
    assert len(r.curves) == 4
    _check_branches(r, a, b, box_a, box_b)
    ends = np.concatenate([_samples(c)[[0, -1]] for c in r.curves])
    special = np.array([[0, 0, R], [0, 0, -R], [R, 0, 0]])
    d = np.linalg.norm(ends[:, None, :] - special[None], axis=2)
    assert d.min(axis=1).max() <= TOL.linear
    np.testing.assert_array_equal(np.bincount(np.argmin(d, axis=1), minlength=3), [2, 2, 4])
    # Viviani's curve: x = R cos²θ, y = R cosθ sinθ, z = R sinθ, so x = R - z²/R.
    for c in r.curves:
        P = _samples(c)
        np.testing.assert_allclose(P[:, 0], R - P[:, 2] ** 2 / R, rtol=0, atol=ON)


def test_sphere_and_off_axis_cylinder():
    sphere = SphericalSurface([0, 0, 0], [0, 0, 1], [1, 0, 0], 2.0)
    cyl = CylindricalSurface([0.7, 0, 0], [0, 0, 1], [1, 0, 0], 0.8)
    r = march_intersection(sphere, cyl, None, ((0, 2 * PI), (-3, 3)))
    _check_branches(r, sphere, cyl)
    # Two loops (z > 0 and z < 0), each cut once by the sphere's seam (x > 0, y = 0).
    assert len(r.curves) == 2
    for c in r.curves:
        P = _samples(c)
        np.testing.assert_allclose(P[0], P[-1], rtol=0, atol=TOL.linear)
        assert c.closed
        assert abs(np.sign(P[:, 2]).sum()) == P.shape[0]


def test_torus_and_oblique_plane():
    torus = ToroidalSurface([0, 0, 0], [0, 0, 1], [1, 0, 0], 3.0, 1.0)
    plane = PlanarSurface([0, 0, 0.3], [0.3, 0.2, 1], [1, 0, 0])
    r = march_intersection(torus, plane, None, ((-6, 6), (-6, 6)))
    _check_branches(r, torus, plane, None, ((-6, 6), (-6, 6)))
    assert len(r.curves) >= 2


def test_cone_and_cylinder():
    cone = ConicalSurface([0, 0, -1], [0, 0, 1], [1, 0, 0], 0.5, 0.4)
    cyl = CylindricalSurface([0, 0, 0], [1, 0, 0.2], [0, 1, 0], 0.4)
    box_a, box_b = ((0, 2 * PI), (-1, 4)), ((0, 2 * PI), (-3, 3))
    r = march_intersection(cone, cyl, box_a, box_b)
    assert len(r.curves) >= 2
    _check_branches(r, cone, cyl, box_a, box_b)


def test_disjoint_surfaces_give_nothing():
    far = CylindricalSurface([0, 5, 0], [1, 0, 0], [0, 1, 0], 0.5)
    r = march_intersection(CYL_Z, far, ((0, 2 * PI), (-2, 2)), ((0, 2 * PI), (-2, 2)))
    assert r.curves == () and r.points.shape == (0, 3)


def test_box_cuts_a_branch_at_its_boundary():
    # Only the parts of the x < 0 loop with x = v_b in [-0.9, -0.85] are asked for (b's seam, at
    # x = -0.8, is not among them): four arcs, each from one v boundary to the other.
    thin = CylindricalSurface([0, 0, 0], [1, 0, 0], [0, 1, 0], 0.6)
    box_b = ((0, 2 * PI), (-0.9, -0.85))
    r = march_intersection(CYL_Z, thin, ((PI / 2, 5 * PI / 2), (-2, 2)), box_b)
    assert len(r.curves) == 4
    _check_branches(r, CYL_Z, thin, None, box_b)
    for c in r.curves:
        vb = sorted(c.pcurve_b.evaluate([c.t0, c.t1])[:, 1])
        np.testing.assert_allclose(vb, [-0.9, -0.85], rtol=0, atol=1e-9)


# ---------------------------------------------------------------------------- NURBS
def _bump_patch(height: float = 0.3) -> NurbsSurface:
    g = np.linspace(0.0, 1.0, 6)
    X, Y = np.meshgrid(g, g, indexing="ij")
    return interpolate_surface(np.stack([X, Y, height * np.sin(3 * X) * np.cos(2 * Y)], axis=-1), 3, 3)


@pytest.mark.parametrize("swap", [False, True])
def test_nurbs_patch_and_plane_match_sampled_truth(swap):
    patch = _bump_patch()
    plane = PlanarSurface([0, 0, 0.1], [0, 0, 1], [1, 0, 0])
    box = ((-1, 2), (-1, 2))
    a, b, box_a, box_b = (plane, patch, box, None) if swap else (patch, plane, None, box)
    r = march_intersection(a, b, box_a, box_b)
    assert len(r.curves) == 1
    _check_branches(r, a, b, box_a, box_b)
    # Truth: on each line v = const of the patch, the root of z(u, v) = 0.1 by bisection.
    vs = np.linspace(0.0, 1.0, 41)
    lo, hi = np.full(vs.shape, 0.01), np.full(vs.shape, 0.5)
    z = lambda u: patch.evaluate(u, vs)[:, 2] - 0.1  # noqa: E731
    has_root = np.sign(z(lo)) != np.sign(z(hi))
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        left = np.sign(z(mid)) == np.sign(z(lo))
        lo, hi = np.where(left, mid, lo), np.where(left, hi, mid)
    truth = patch.evaluate(0.5 * (lo + hi), vs)[has_root]
    assert truth.shape[0] > 10
    ours = _samples(r.curves[0], 20001)
    d, _ = cKDTree(ours).query(truth)
    # Dense samples of our curve are 1e-4 apart: the nearest one is within that of the truth.
    assert d.max() <= 1e-4


def test_small_closed_loop_between_two_bumps():
    g = np.linspace(-1, 1, 7)
    X, Y = np.meshgrid(g, g, indexing="ij")
    bump = np.exp(-3 * (X**2 + Y**2))
    up = interpolate_surface(np.stack([X, Y, 0.5 * bump], axis=-1), 3, 3)
    # The dip of the upper patch reaches 0.03 below the apex of the lower one: a loop of radius ~0.1.
    down = interpolate_surface(np.stack([X, Y, 0.97 - 0.5 * bump], axis=-1), 3, 3)
    r = march_intersection(up, down)
    assert len(r.curves) == 1
    c = r.curves[0]
    assert c.closed
    _check_branches(r, up, down)
    P = _samples(c)
    np.testing.assert_allclose(P[0], P[-1], rtol=0, atol=TOL.linear)
    # A loop around the apex, far smaller than the patches.
    assert 0.05 < np.linalg.norm(P[:, :2], axis=1).max() < 0.15


# ---------------------------------------------------------------------------- OCCT
def _occt_branches(surface_a, surface_b) -> tuple[list, float]:
    from OCP.GCPnts import GCPnts_AbscissaPoint
    from OCP.GeomAdaptor import GeomAdaptor_Curve
    from OCP.GeomAPI import GeomAPI_IntSS

    inter = GeomAPI_IntSS(surface_a, surface_b, 1e-7)
    assert inter.IsDone()
    curves = [inter.Line(k) for k in range(1, inter.NbLines() + 1)]
    return curves, sum(GCPnts_AbscissaPoint.Length_s(GeomAdaptor_Curve(c)) for c in curves)


def _distance_to_occt(points: np.ndarray, curves) -> np.ndarray:
    from OCP.gp import gp_Pnt
    from OCP.GeomAPI import GeomAPI_ProjectPointOnCurve

    out = np.full(points.shape[0], np.inf)
    for i, p in enumerate(points):
        for c in curves:
            proj = GeomAPI_ProjectPointOnCurve(gp_Pnt(*map(float, p)), c)
            if proj.NbPoints():
                out[i] = min(out[i], proj.LowerDistance())
    return out


def _ax3(origin, axis, x_dir):
    from OCP.gp import gp_Ax3, gp_Dir, gp_Pnt

    return gp_Ax3(gp_Pnt(*map(float, origin)), gp_Dir(*map(float, axis)), gp_Dir(*map(float, x_dir)))


@pytest.mark.occt
@pytest.mark.parametrize("case", ["cylinders", "torus_plane", "sphere_cylinder"])
def test_agreement_with_occt(case):
    from OCP.Geom import Geom_CylindricalSurface, Geom_Plane, Geom_SphericalSurface, Geom_ToroidalSurface

    if case == "cylinders":
        a = CYL_Z
        b = CylindricalSurface([0, 0, 0], [1, 0, 0], [0, 1, 0], 0.6)
        occ_a = Geom_CylindricalSurface(_ax3(a.origin, a.axis, a.x_dir), a.radius)
        occ_b = Geom_CylindricalSurface(_ax3(b.origin, b.axis, b.x_dir), b.radius)
        box_a, box_b = ((0, 2 * PI), (-2, 2)), ((0, 2 * PI), (-2, 2))
    elif case == "torus_plane":
        a = ToroidalSurface([0, 0, 0], [0, 0, 1], [1, 0, 0], 3.0, 1.0)
        b = PlanarSurface([0, 0, 0.3], [0.3, 0.2, 1], [1, 0, 0])
        occ_a = Geom_ToroidalSurface(_ax3(a.center, a.axis, a.x_dir), a.major_radius, a.minor_radius)
        occ_b = Geom_Plane(_ax3(b.origin, b.axis, b.x_dir))
        box_a, box_b = None, ((-6, 6), (-6, 6))
    else:
        a = SphericalSurface([0, 0, 0], [0, 0, 1], [1, 0, 0], 2.0)
        b = CylindricalSurface([0.7, 0, 0], [0, 0, 1], [1, 0, 0], 0.8)
        occ_a = Geom_SphericalSurface(_ax3(a.center, a.axis, a.x_dir), a.radius)
        occ_b = Geom_CylindricalSurface(_ax3(b.origin, b.axis, b.x_dir), b.radius)
        box_a, box_b = None, ((0, 2 * PI), (-3, 3))
    r = march_intersection(a, b, box_a, box_b)
    theirs, their_length = _occt_branches(occ_a, occ_b)
    # The same point set: samples of each curve set lie on the other (exact projections both ways).
    ours = np.concatenate([_samples(c, 41) for c in r.curves])
    assert _distance_to_occt(ours, theirs).max() <= 1e-6
    for c in theirs:
        ts = np.linspace(c.FirstParameter(), c.LastParameter(), 41)
        Q = np.array([[p.X(), p.Y(), p.Z()] for p in map(c.Value, ts)])
        d = np.min([c_ours.curve.closest_points(Q).distances for c_ours in r.curves], axis=0)
        assert d.max() <= 1e-6
    assert sum(c.curve.length() for c in r.curves) == pytest.approx(their_length, rel=1e-7)


# ---------------------------------------------------------------------------- curve–surface
def test_line_through_sphere():
    sphere = SphericalSurface([0, 0, 0], [0, 0, 1], [1, 0, 0], 1.0)
    t, uv, P = intersect_curve_surface(Line([-2, 0.6, 0], [1, 0, 0]), 0.0, 4.0, sphere)
    np.testing.assert_allclose(t, [1.2, 2.8], rtol=0, atol=1e-12)
    np.testing.assert_allclose(P, [[-0.8, 0.6, 0], [0.8, 0.6, 0]], rtol=0, atol=1e-12)
    np.testing.assert_allclose(sphere.evaluate(uv[:, 0], uv[:, 1]), P, rtol=0, atol=1e-12)


def test_touching_circle_and_range_limits():
    plane = PlanarSurface([0, 0, 1], [0, 0, 1], [1, 0, 0])
    circle = Circle([0, 0, 0], [0, 1, 0], [1, 0, 0], 1.0)  # touches z = 1 at t = -π/2 (y axis is -Z x X)
    t_top = float(np.arctan2(1.0, 0.0)) if circle.evaluate(PI / 2)[2] > 0 else -PI / 2
    box = ((-5, 5), (-5, 5))
    t, uv, P = intersect_curve_surface(circle, t_top - 1.0, t_top + 1.0, plane, box)
    np.testing.assert_allclose(P, [[0, 0, 1]], rtol=0, atol=1e-7)
    assert t.shape == (1,)
    # The range excludes the contact: nothing.
    t, uv, P = intersect_curve_surface(circle, t_top + 0.5, t_top + 1.0, plane, box)
    assert t.shape == (0,) and uv.shape == (0, 2) and P.shape == (0, 3)


def test_nurbs_curve_and_cylinder_in_a_box():
    cyl = CylindricalSurface([0, 0, 0], [0, 0, 1], [1, 0, 0], 1.0)
    s = np.linspace(0, 1, 12)
    curve = interpolate_curve(np.stack([3 * np.cos(5 * s) * s, 3 * np.sin(5 * s) * s, s], 1), 3)
    t, uv, P = intersect_curve_surface(curve, 0.0, 1.0, cyl, ((0, 2 * PI), (-1, 2)))
    assert t.size >= 1 and np.all(np.diff(t) > 0)
    np.testing.assert_allclose(np.hypot(P[:, 0], P[:, 1]), 1.0, rtol=0, atol=1e-9)
    np.testing.assert_allclose(curve.evaluate(t), P, rtol=0, atol=0)
    np.testing.assert_allclose(cyl.evaluate(uv[:, 0], uv[:, 1]), P, rtol=0, atol=1e-9)
    # A box that keeps only u in [0, π/2] keeps the subset there.
    t2, uv2, _ = intersect_curve_surface(curve, 0.0, 1.0, cyl, ((0, PI / 2), (-1, 2)))
    assert np.all(uv2[:, 0] <= PI / 2 + 1e-12)
    assert t2.size == int(np.sum(uv[:, 0] <= PI / 2))


def test_curve_surface_periodic_box_shift():
    cyl = CylindricalSurface([0, 0, 0], [0, 0, 1], [1, 0, 0], 1.0)
    t, uv, P = intersect_curve_surface(Line([-2, -0.5, 0.3], [1, 0, 0]), 0.0, 4.0, cyl, ((2 * PI, 4 * PI), (-1, 1)))
    assert t.size == 2
    assert np.all((uv[:, 0] >= 2 * PI) & (uv[:, 0] < 4 * PI))
    np.testing.assert_allclose(cyl.evaluate(uv[:, 0], uv[:, 1]), P, rtol=0, atol=1e-12)


@pytest.mark.parametrize("gap, count", [(0.0, 1), (0.5 * TOL.linear, 1), (1e-6, 0), (-1e-6, 2)])
def test_line_tangent_to_a_cylinder(gap, count):
    # At distance 1 + gap from the axis: touching (within tol.linear), missing, or crossing twice.
    cyl = CylindricalSurface([0, 0, 0], [0, 0, 1], [1, 0, 0], 1.0)
    t, uv, P = intersect_curve_surface(Line([1 + gap, -2, 0.3], [0, 1, 0]), 0.0, 4.0, cyl, ((0, 2 * PI), (-1, 1)))
    assert t.size == count
    if count:
        np.testing.assert_allclose(np.hypot(P[:, 0], P[:, 1]), 1.0, rtol=0, atol=TOL.linear)
        np.testing.assert_allclose(t, 2.0, rtol=0, atol=2e-3)


def test_curve_lying_in_the_surface_gives_the_ends_of_the_overlap():
    sphere = SphericalSurface([0, 0, 0], [0, 0, 1], [1, 0, 0], 1.0)
    equator = Circle([0, 0, 0], [0, 0, 1], [1, 0, 0], 1.0)
    t, uv, P = intersect_curve_surface(equator, 0.0, 1.0, sphere)
    np.testing.assert_allclose(t, [0.0, 1.0], rtol=0, atol=1e-12)
    np.testing.assert_allclose(uv, [[0.0, 0.0], [1.0, 0.0]], rtol=0, atol=1e-12)


# ---------------------------------------------------------------------------- errors
def test_unbounded_surface_needs_a_box():
    with pytest.raises(InvalidInputError, match="CylindricalSurface is unbounded, a box"):
        march_intersection(CYL_Z, CYL_Z)
    with pytest.raises(InvalidInputError, match="PlanarSurface is unbounded, a box"):
        intersect_curve_surface(Line([0, 0, 0], [1, 0, 0]), 0, 1, PlanarSurface([0, 0, 0], [0, 0, 1], [1, 0, 0]))


@pytest.mark.parametrize("box", [((0, 1),), ((1, 0), (0, 1)), ((0, math.inf), (0, 1)), "x"])
def test_malformed_box(box):
    with pytest.raises(InvalidInputError, match=r"box must be finite \(\(u0, u1\), \(v0, v1\)\)"):
        march_intersection(CYL_Z, CYL_Z, box, ((0, 1), (0, 1)))


@pytest.mark.parametrize("t0, t1", [(1.0, 1.0), (1.0, 0.0), (0.0, math.nan)])
def test_curve_surface_bad_range(t0, t1):
    with pytest.raises(InvalidInputError, match="need finite t0 < t1"):
        intersect_curve_surface(Line([0, 0, 0], [1, 0, 0]), t0, t1, CYL_Z, ((0, 1), (0, 1)))


# ---------------------------------------------------------------------------- properties
@settings(max_examples=6)
@given(
    axis=st.tuples(st.floats(-1, 1), st.floats(-1, 1), st.floats(0.2, 1)),
    offset=st.tuples(st.floats(-0.3, 0.3), st.floats(-0.3, 0.3)),
    radius=st.floats(0.3, 0.9),
)
def test_swapping_the_surfaces_gives_the_same_curves(axis, offset, radius):
    # Random crossing cylinders: a(b) and b(a) find the same branches, on both surfaces.
    z = np.array(axis) / np.linalg.norm(axis)
    x = np.cross(z, [0.3, 1.0, 0.1])
    other = CylindricalSurface([offset[0], offset[1], 0.0], z, x, radius)
    box_a, box_b = ((0, 2 * PI), (-3, 3)), ((0, 2 * PI), (-3, 3))
    r1 = march_intersection(CYL_Z, other, box_a, box_b)
    r2 = march_intersection(other, CYL_Z, box_b, box_a)
    _check_branches(r1, CYL_Z, other, box_a, box_b)
    _check_branches(r2, other, CYL_Z, box_b, box_a)
    assert len(r1.curves) == len(r2.curves)
    l1 = sum(c.curve.length() for c in r1.curves)
    l2 = sum(c.curve.length() for c in r2.curves)
    assert l1 == pytest.approx(l2, rel=1e-7, abs=1e-9)


def test_closed_nurbs_surfaces_match_their_analytic_forms():
    # The exact NURBS forms of a cylinder and a sphere (closed, with seams and poles) give the
    # same intersection as the analytic surfaces.
    cyl = CylindricalSurface([0.1, 0, 0], [0, 0.3, 1], [1, 0, 0], 0.9)
    sphere = SphericalSurface([0, 0, 0.2], [0, 0, 1], [1, 0, 0], 1.2)
    exact = march_intersection(cyl, sphere, ((0, 2 * PI), (-3, 3)), None)
    nurbs_cyl, nurbs_sphere = cyl.to_nurbs((-3, 3)), sphere.to_nurbs()
    r = march_intersection(nurbs_cyl, nurbs_sphere)
    _check_branches(r, nurbs_cyl, nurbs_sphere)
    assert sum(c.curve.length() for c in r.curves) == pytest.approx(
        sum(c.curve.length() for c in exact.curves), rel=1e-7
    )


def test_boxes_longer_than_a_period_do_not_repeat_branches():
    thin = CylindricalSurface([0, 0, 0], [1, 0, 0], [0, 1, 0], 0.6)
    eps = 1e-3
    exact = march_intersection(CYL_Z, thin, ((0, 2 * PI), (-2, 2)), ((0, 2 * PI), (-2, 2)))
    wide = march_intersection(CYL_Z, thin, ((-eps, 2 * PI + eps), (-2, 2)), ((-eps, 2 * PI + eps), (-2, 2)))
    assert len(wide.curves) == len(exact.curves)
    _check_branches(wide, CYL_Z, thin, ((0, 2 * PI), (-2, 2)), ((0, 2 * PI), (-2, 2)))
    assert sum(c.curve.length() for c in wide.curves) == pytest.approx(
        sum(c.curve.length() for c in exact.curves), rel=1e-7
    )


def test_nurbs_box_enlarged_past_the_domain_and_disjoint_box():
    patch = _bump_patch()
    plane = PlanarSurface([0, 0, 0.1], [0, 0, 1], [1, 0, 0])
    box = ((-1, 2), (-1, 2))
    exact = march_intersection(patch, plane, None, box)
    wide = march_intersection(patch, plane, ((-0.01, 1.01), (-0.01, 1.01)), box)
    assert len(wide.curves) == len(exact.curves) == 1
    assert wide.curves[0].curve.length() == pytest.approx(exact.curves[0].curve.length(), rel=1e-7)
    with pytest.raises(InvalidInputError, match=r"does not meet the NURBS domain"):
        march_intersection(patch, plane, ((2, 3), (0, 1)), box)


# ---------------------------------------------------------------------------- contacts
@pytest.mark.parametrize("swap", [False, True])
def test_sphere_touching_a_plane_is_an_isolated_point(swap):
    sphere = SphericalSurface([0.3, 0.2, 1.0], [0, 0, 1], [1, 0, 0], 1.0)
    plane = PlanarSurface([0, 0, 0], [0, 0, 1], [1, 0, 0])
    box = ((-3, 3), (-3, 3))
    a, b, box_a, box_b = (plane, sphere, box, None) if swap else (sphere, plane, None, box)
    r = march_intersection(a, b, box_a, box_b)
    assert r.curves == ()
    np.testing.assert_allclose(r.points, [[0.3, 0.2, 0.0]], rtol=0, atol=1e-9)
    uv_plane, uv_sphere = (r.uv_a, r.uv_b) if swap else (r.uv_b, r.uv_a)
    np.testing.assert_allclose(uv_plane, [[0.3, 0.2]], rtol=0, atol=1e-9)
    np.testing.assert_allclose(uv_sphere[:, 1], [-PI / 2], rtol=0, atol=1e-6)


def test_nurbs_bump_touching_a_plane_at_its_apex():
    g = np.linspace(-1, 1, 7)
    X, Y = np.meshgrid(g, g, indexing="ij")
    up = interpolate_surface(np.stack([X, Y, 0.5 * np.exp(-3 * (X**2 + Y**2))], axis=-1), 3, 3)
    apex = up.evaluate(0.5, 0.5)
    plane = PlanarSurface(apex, [0, 0, 1], [1, 0, 0])
    r = march_intersection(up, plane, None, ((-3, 3), (-3, 3)))
    assert r.curves == ()
    np.testing.assert_allclose(r.points, [apex], rtol=0, atol=1e-9)
    np.testing.assert_allclose(r.uv_a, [[0.5, 0.5]], rtol=0, atol=1e-6)


def test_tangency_along_a_curve_is_logged_not_reported(caplog):
    cyl = CylindricalSurface([0, 0, 1], [1, 0, 0], [0, 0, 1], 1.0)
    plane = PlanarSurface([0, 0, 0], [0, 0, 1], [1, 0, 0])
    with caplog.at_level("WARNING", logger="coons"):
        r = march_intersection(cyl, plane, ((0, 2 * PI), (-1, 1)), ((-3, 3), (-3, 3)))
    assert r.curves == () and r.points.shape == (0, 3)
    assert "touch along a curve" in caplog.text


# ---------------------------------------------------------------------------- regressions (random Booleans)
def _assert_ends_on_boundaries(r, a, b, box_a, box_b, extra=()):
    """The branches' union is connected: every open end lies on a box boundary, at a pole or
    apex (``extra`` points), or at an end of another branch."""
    ends = []
    for c in r.curves:
        if not c.closed:
            t = np.array([c.t0, c.t1])
            ends += [(c.curve.evaluate(t)[k], c.pcurve_a.evaluate(t)[k], c.pcurve_b.evaluate(t)[k]) for k in (0, 1)]
    P = np.array([e[0] for e in ends]).reshape(-1, 3)
    for i, (p, ua, ub) in enumerate(ends):
        on_box = any(np.any(np.abs(uv[:, None] - np.array(box)) <= 1e-7) for uv, box in ((ua, box_a), (ub, box_b)))
        d = np.linalg.norm(P - p, axis=1)
        d[i] = np.inf
        at_other = d.min(initial=np.inf) <= 1e-6
        at_extra = any(np.linalg.norm(p - q) <= 1e-6 for q in extra)
        assert on_box or at_other or at_extra, f"branch end {p.tolist()} (uv_a {ua.tolist()}, uv_b {ub.tolist()}) is loose"


def test_cone_and_sphere_branch_has_no_gap():
    """A crossing whose Newton came back with the sphere's v a turn away (5.77 for -0.52) was taken
    for a point outside the sphere's box and cut the branch (a 0.05 gap)."""
    a = ConicalSurface([2.7608287050455567, 1.599448249325841, -3.0985048923660026],
                       [-0.5995290713459612, -0.3508896509362203, 0.7193339596299532],
                       [-0.22465267926295698, 0.9364168157748223, 0.26954539661088167],
                       2.2075580506337307, -0.2816502066935166)
    b = SphericalSurface([-0.1366398597555003, 0.5124034194596274, 0.5409047355988528], [0, 0, 1], [1, 0, 0],
                         1.5516681895290736)
    box_a = ((-0.03141602653589794, 3.173008680125691), (-0.0621845290491712, 6.28062743396629))
    box_b = ((3.110176627053895, 6.314601333715484), (-1.6022123533307946, 1.6022123533307946))
    r = march_intersection(a, b, box_a, box_b)
    _check_branches(r, a, b, box_a, box_b)
    assert len(r.curves) == 2
    _assert_ends_on_boundaries(r, a, b, box_a, box_b)


def test_torus_and_cylinder_branch_has_no_gap():
    """A crossing where Newton jumped to another root (5.8 away, outside the cylinder's box) cut the branch."""
    a = ToroidalSurface([1.9169131567582505, 0.15337293630516013, 0.9486008904831342],
                        [0.5749974952009027, 0.5642489012675261, 0.592453422583647],
                        [0.807752697580607, -0.27640449123133204, -0.520707342735246],
                        3.9891410332725434, 0.5301274963753239)
    b = CylindricalSurface([0.9390478614972365, -0.08848912524341124, 1.3611248218073961],
                           [-0.4392647570867809, 0.5818891757444946, -0.6844351396099445],
                           [0.8983576532659425, 0.28452299204620435, -0.33466430018091886], 1.8692544891059153)
    box_a = ((-0.03141602653589794, 3.173008680125691), (-0.03141602653589794, 3.173008680125691))
    box_b = ((3.110176627053895, 6.314601333715484), (-0.03360781806320531, 3.3943796243837356))
    r = march_intersection(a, b, box_a, box_b)
    _check_branches(r, a, b, box_a, box_b)
    assert len(r.curves) == 1
    _assert_ends_on_boundaries(r, a, b, box_a, box_b)


def test_sphere_grid_beyond_the_pole_gives_no_stray_branch():
    """The sphere's box reaches past its pole (v up to 1.6022): samples there must not be folded
    into a branch outside the box (a stray branch with tol 0.22 did)."""
    a = SphericalSurface([0.8464841386067945, -0.05577507469285403, 0.13195260952388144],
                         [0.007637582623912037, -0.40215623882908813, 0.9155392000905829],
                         [0.313970335614917, -0.868301104185617, -0.3840258074972236], 3.3509554785341473)
    b = ToroidalSurface([1.80845641667185, -1.5645390141726703, -0.30647971969847115],
                        [-0.5429271816186924, -0.7233818416786101, -0.4265545528877238],
                        [-0.7685569971174963, 0.22329926740981487, 0.5995478124019609],
                        3.4509934765182555, 1.0338477832741002)
    box_a = ((-0.03141602653589794, 3.173008680125691), (-1.6022123533307946, 1.6022123533307946))
    box_b = ((3.110176627053895, 6.314601333715484), (3.110176627053895, 6.314601333715484))
    r = march_intersection(a, b, box_a, box_b)
    _check_branches(r, a, b, box_a, box_b)


def test_branch_crossing_a_box_corner_within_one_cell_is_found():
    """A 0.2-long piece of a sphere–torus branch cuts the corner of the torus face's box between
    two grid samples outside it; without it the neighbouring faces' cuts ended 0.1 apart."""
    a = SphericalSurface([0.9567527471223962, -0.20710899696138285, -0.9444901798908854],
                         [-0.7379077027664579, -0.3845590173864419, -0.5546229208612848],
                         [-0.5240807700146016, -0.19129103885813012, 0.8299078773897014], 2.74746617060107)
    b = ToroidalSurface([0.6330717751252952, -0.03664132391536215, -0.38536310939977914],
                        [-0.15948037109074897, 0.8536666825002551, -0.4958015796926886],
                        [0.7303225867098161, -0.23589522476076613, -0.6410790608626606],
                        2.9280700556379835, 0.8287011953903672)
    box_a = ((-0.03141602653589794, 3.173008680125691), (-1.6022123533307946, 1.6022123533307946))
    box_b = ((3.110176627053895, 6.314601333715484), (3.110176627053895, 6.314601333715484))
    r = march_intersection(a, b, box_a, box_b)
    _check_branches(r, a, b, box_a, box_b)
    lengths = sorted(c.curve.length() for c in r.curves)
    assert len(lengths) == 2 and 0.1 < lengths[0] < 0.3
    _assert_ends_on_boundaries(r, a, b, box_a, box_b)


def test_branch_passing_next_to_a_sphere_pole_keeps_its_p_curve_in_the_domain():
    """The branch passes 0.012 from the sphere's south pole (a Boolean's chain of 20 solids): Newton's
    refinement points went over the pole (latitude < -π/2) and turns away in longitude; the p-curve
    jumped between them and the branch came back with tol 0.17."""
    cyl = CylindricalSurface([-4.540198973164249, 2.506442686317463, -3.9602271003246567], [1, 0, 0], [0, 1, 0], 1.2)
    sphere = SphericalSurface([1.0697481342871509, 1.5793852479522137, -3.2370476147348457], [0, 0, 1], [1, 0, 0], 1.5)
    box_a = ((-0.041897055921502654, 4.231591988467847), (-0.09540208973164256, 9.635601062895898))
    box_b = ((-0.03141602653589794, 3.173008680125691), (-PI / 2, PI / 2))
    r = march_intersection(cyl, sphere, box_a, box_b)
    assert len(r.curves) >= 1
    _check_branches(r, cyl, sphere, box_a, box_b)
    south = sphere.center - 1.5 * np.array([0, 0, 1.0])
    near_pole = min(np.linalg.norm(_samples(c) - south, axis=1).min() for c in r.curves)
    assert near_pole < 0.02


def test_singular_point_search_abandons_a_transversal_crossing_quickly(monkeypatch):
    """A seed on a transversal crossing (a sphere cut by a plane at a small angle: the normals' sine is
    below the candidate filter) is no singular point: Gauss–Newton stalls at a positive residual and
    the row is dropped after _SINGULAR_PATIENCE stalled steps instead of running all iterations."""
    from coons.kernel import ssi

    sphere = SphericalSurface([0, 0, 0], [0, 0, 1], [1, 0, 0], 1.0)
    plane = PlanarSurface([0, 0, 0.9], [0, 0, 1], [1, 0, 0])
    lat = math.asin(0.9)
    u = np.linspace(0.1, 6.0, 7)
    r = math.cos(lat)
    x0 = np.stack([u, np.full_like(u, lat), r * np.cos(u), r * np.sin(u)], axis=1)
    calls = []
    frame = ssi._frame
    monkeypatch.setattr(ssi, "_frame", lambda s, a, b: (calls.append(1), frame(s, a, b))[1])
    assert ssi._singular_points(sphere, plane, x0, TOL).shape == (0, 4)
    # Each step evaluates the residual 9 times (2 frames each); all iterations would be 60 steps.
    assert len(calls) <= 2 * 9 * (ssi._SINGULAR_PATIENCE + 3) + 2


@settings(max_examples=30)
@given(
    kind=st.sampled_from(["cylinder", "cone", "sphere", "torus"]),
    axis=st.tuples(*[st.floats(-1, 1)] * 3).filter(lambda a: np.linalg.norm(a) > 0.2),
    seed=st.integers(0, 2**16),
)
def test_frame_of_a_surface_of_revolution_is_its_derivatives_bit_for_bit(kind, axis, seed):
    """The marching's own points and partials of analytic surfaces of revolution equal ``derivatives(u, v, 1)``."""
    from coons.kernel.analytic import ConicalSurface, CylindricalSurface, SphericalSurface, ToroidalSurface
    from coons.kernel.ssi import _frame

    rng = np.random.default_rng(seed)
    z = np.array(axis) / np.linalg.norm(axis)
    x = np.cross(z, [1.0, 0.0, 0.0]) if abs(z[0]) < 0.9 else np.cross(z, [0.0, 1.0, 0.0])
    o = rng.uniform(-5, 5, 3)
    s = {"cylinder": lambda: CylindricalSurface(o, z, x, 1.7), "cone": lambda: ConicalSurface(o, z, x, 1.1, -0.3),
         "sphere": lambda: SphericalSurface(o, z, x, 2.3), "torus": lambda: ToroidalSurface(o, z, x, 3.0, 0.7)}[kind]()
    u, v = rng.uniform(-7, 7, 40), rng.uniform(-1.5, 1.5, 40)
    d = s.derivatives(u, v, 1)
    for got, want in zip(_frame(s, u, v), (d[:, 0, 0], d[:, 1, 0], d[:, 0, 1])):
        assert np.array_equal(got, want)


def test_branch_through_a_sphere_pole_ends_at_the_limit_longitude():
    """A cylinder of the sphere's radius whose wall holds the sphere's axis cuts it along a curve
    through both poles, arriving tangent to the x axis (Viviani-like: ``y = (z² - R²) / 2R``), so its
    longitude tends to π and 2π there.  The pole's own longitude is undetermined; it was copied from
    the first coarse sample next to it (0.034 off), and the refined p-curve then ran along the pole
    over its last 2e-5 of length (a Boolean's face split found it overlapping the pole segment)."""
    R = 1.5
    sph = SphericalSurface([0, 0, 0], [0, 0, 1], [1, 0, 0], R)
    cyl = CylindricalSurface([0, -R, 0], [0, 0, 1], [1, 0, 0], R)
    r = march_intersection(sph, cyl, ((PI, 2 * PI), (-PI / 2, PI / 2)), ((0, 2 * PI), (-1, 2)))
    limits = []
    for c in r.curves:
        for end, inward in ((c.t0, c.t1), (c.t1, c.t0)):
            u, v = c.pcurve_a.evaluate(np.array([end]))[0]
            if abs(abs(v) - PI / 2) > 1e-9:
                continue
            limits.append(u)
            assert abs(u - PI * round(u / PI)) <= 1e-4, u
            # the last thousandth of the branch moves away from the limit monotonically (no run along the pole)
            s = end + np.linspace(0.0, 1e-3, 41) * (inward - end)
            du = np.abs(c.pcurve_a.evaluate(s)[:, 0] - PI * round(u / PI))
            assert np.all(np.diff(du) >= -1e-9) and du[-1] <= 1e-3 * c.t1 / R
    assert sorted(round(u / PI) for u in limits) == [1, 2]


def test_extrapolated_end_parameters_stay_in_the_box():
    """An undetermined end parameter extrapolated past its box's edge (the limit longitude on a seam
    corner, missed to second order) is kept on the edge; a determined one is left alone."""
    from coons.kernel.ssi import _extrapolated_ends

    # samples along a straight chord of equal steps: the u of sample 0 extrapolates to -0.1
    X = np.array([[9.0, 0.5, 0.0, 0.0], [0.1, 0.5, 0.1, 0.0], [0.3, 0.5, 0.2, 0.0], [0.5, 0.5, 0.3, 0.0]])
    P = np.array([[0.0, 0, 0], [1.0, 0, 0], [2.0, 0, 0], [3.0, 0, 0]])
    free = np.zeros((2, 4), bool)
    free[0, 0] = True
    box = np.array([[0.0, -1.0, -5.0, -5.0], [2 * np.pi, 1.0, 5.0, 5.0]])
    np.testing.assert_allclose(_extrapolated_ends(X, P, free)[0], [-0.1, 0.5, 0.0, 0.0], atol=1e-15)
    np.testing.assert_allclose(_extrapolated_ends(X, P, free, box)[0], [0.0, 0.5, 0.0, 0.0], atol=1e-15)
    # inside the box: unchanged by it
    box[0, 0] = -1.0
    np.testing.assert_allclose(_extrapolated_ends(X, P, free, box)[0], [-0.1, 0.5, 0.0, 0.0], atol=1e-15)


@pytest.mark.parametrize("half", [0, 1])
def test_singular_point_a_cell_inside_the_grid_box_ends_the_branch_on_its_own_arm(half):
    """A sphere of radius 2 internally tangent to a cylinder of radius 1.5 at ``u = 0``, ``v = 0``: the section
    on the wall is ``v = ±√3 |sin(u / 2)|``, a double point there.  A half face's box (one cell wider, as a
    Boolean asks) holds the point a cell from its edge; the grid joined the arm inside ``[π, 2π]`` (or
    ``[0, π]``) to the arm beyond it in the point's cell and the chain ended at the box edge.  The branch
    now ends at the point coming along its own arm, and the arm beyond is a piece from the point."""
    cyl = CylindricalSurface([0.5, -1, -1], [0, 0, 1], [1, 0, 0], 1.5)
    sphere = SphericalSurface([0, -1, -1], [0, 0, 1], [1, 0, 0], 2.0)
    pad = 0.01 * PI
    u0 = PI * (1 - half)
    box_a = ((u0 - pad, u0 + PI + pad), (-0.02, 2.02))
    r = march_intersection(cyl, sphere, box_a, ((u0 - pad, u0 + PI + pad), (-PI / 2, PI / 2)))
    point = np.array([2.0, -1.0, -1.0])
    main = [c for c in r.curves if c.curve.length() > 1.0]
    assert len(main) == 1
    c = main[0]
    t = np.linspace(c.t0, c.t1, 2001)
    uv = c.pcurve_a.evaluate(t)
    ends = c.curve.evaluate(np.array([c.t0, c.t1]))
    assert np.linalg.norm(ends - point, axis=1).min() <= TOL.linear
    # On the arm inside the half face, up to the point (was: up to 0.032 beyond it in u and back).
    assert np.all(uv[:, 0] <= 2 * PI + 1e-9) if half == 0 else np.all(uv[:, 0] >= -1e-9)
    np.testing.assert_allclose(uv[:, 1], math.sqrt(3) * np.abs(np.sin(uv[:, 0] / 2)), rtol=0, atol=ON)
    beyond = [c for c in r.curves if c.curve.length() <= 1.0]
    assert len(beyond) == 1
    ends = beyond[0].curve.evaluate(np.array([beyond[0].t0, beyond[0].t1]))
    assert np.linalg.norm(ends - point, axis=1).min() <= TOL.linear
