"""Tests of coons.kernel.ssi on small closed loops and tangent contacts (issue 5).

Small loops: two surfaces that nearly touch and cut each other slightly meet in a loop far smaller
than a cell of the sampling grid.  Near the contact both surfaces are paraboloids, so the loop is
the ellipse ``d = ½ xᵀ (K_a - K_b) x`` (``d`` the depth of the cut, ``K`` the curvature matrices)
to relative order ``d``: its perimeter is the closed form the tests compare with.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.linalg import eigh

import coons
from coons.kernel.analytic import CylindricalSurface, PlanarSurface, SphericalSurface, ToroidalSurface
from coons.kernel.fitting import interpolate_surface
from coons.kernel.ssi import march_intersection
from coons.tolerance import Tolerance

PI = math.pi
TOL = Tolerance()
#: Points of a fitted branch, between its samples, may exceed the measured tol slightly.
ON = 2 * TOL.linear
SPHERE = SphericalSurface([0, 0, 0], [0, 0, 1], [1, 0, 0], 1.0)
CYL_BOX = ((0.0, 2 * PI), (-2.0, 2.0))


def _ellipse_perimeter(a: float, b: float) -> float:
    """Ramanujan's second approximation (relative error below 1e-9 for these aspect ratios)."""
    h = ((a - b) / (a + b)) ** 2
    return PI * (a + b) * (1 + 3 * h / (10 + math.sqrt(4 - 3 * h)))


def _grazing_cylinder(depth: float, across_seam: bool = False) -> CylindricalSurface:
    """A cylinder of radius 0.5 cutting ``depth`` into the unit sphere at (0, 1, 0) (or (1, 0, 0)).

    Near the contact the sphere is ``y = 1 - (x² + z²)/2`` and the cylinder (axis along x)
    ``y = 1 - depth + z²``: the loop is the ellipse with semi-axes ``sqrt(2 depth)`` along the
    axis and ``sqrt(2 depth / 3)`` across it.
    """
    if across_seam:  # the loop straddles the sphere's seam u = 0
        return CylindricalSurface([1.5 - depth, 0, 0], [0, 1, 0], [0, 0, 1], 0.5)
    return CylindricalSurface([0, 1.5 - depth, 0], [1, 0, 0], [0, 0, 1], 0.5)


def _on_both(r, a, b) -> None:
    for c in r.curves:
        t = np.linspace(c.t0, c.t1, 401)
        P = c.curve.evaluate(t)
        for s, pc in ((a, c.pcurve_a), (b, c.pcurve_b)):
            uv = pc.evaluate(t)
            if isinstance(s, (SphericalSurface, CylindricalSurface, PlanarSurface, ToroidalSurface)):
                assert np.abs(s.implicit(P)).max() <= ON
            assert np.linalg.norm(s.evaluate(uv[:, 0], uv[:, 1]) - P, axis=1).max() <= ON
        assert 0.0 <= c.tol <= TOL.linear


def _length(c) -> float:
    """Arc length of a branch (its parameter is chord length of its samples, a little shorter)."""
    P = c.curve.evaluate(np.linspace(c.t0, c.t1, 20001))
    return float(np.linalg.norm(np.diff(P, axis=0), axis=1).sum())


def _winds_once(P: np.ndarray, centre: np.ndarray, e1: np.ndarray, e2: np.ndarray) -> bool:
    """The closed polyline ``P`` turns once, monotonically, around ``centre`` in the plane (e1, e2)."""
    ang = np.unwrap(np.arctan2((P - centre) @ e2, (P - centre) @ e1))
    step = np.diff(ang)
    return bool((np.all(step > 0) or np.all(step < 0)) and abs(abs(ang[-1] - ang[0]) - 2 * PI) < 1e-6)


# ---------------------------------------------------------------------------- small loops
@pytest.mark.parametrize("depth", [1e-4, 1e-6])
@pytest.mark.parametrize("swap", [False, True])
def test_loop_far_smaller_than_a_grid_cell_is_found(depth, swap):
    # depth 1e-6: semi-axes 1.4e-3 and 8e-4, about 2e-4 of the sphere's parameter box.
    cyl = _grazing_cylinder(depth)
    a, b, box_a, box_b = (cyl, SPHERE, CYL_BOX, None) if swap else (SPHERE, cyl, None, CYL_BOX)
    r = march_intersection(a, b, box_a, box_b)
    assert len(r.curves) == 1 and r.points.shape == (0, 3)
    c = r.curves[0]
    assert c.closed
    _on_both(r, a, b)
    expect = _ellipse_perimeter(math.sqrt(2 * depth), math.sqrt(2 * depth / 3))
    assert _length(c) == pytest.approx(expect, rel=10 * depth + 1e-6)
    P = c.curve.evaluate(np.linspace(c.t0, c.t1, 401))
    assert _winds_once(P, np.array([0.0, 1.0, 0.0]), np.array([1.0, 0, 0]), np.array([0, 0, 1.0]))


def test_loop_across_the_seam_comes_back_in_pieces_that_close():
    depth = 1e-5
    cyl = _grazing_cylinder(depth, across_seam=True)
    r = march_intersection(SPHERE, cyl, None, CYL_BOX)
    assert len(r.curves) >= 1
    _on_both(r, SPHERE, cyl)
    total = sum(_length(c) for c in r.curves)
    expect = _ellipse_perimeter(math.sqrt(2 * depth), math.sqrt(2 * depth / 3))
    assert total == pytest.approx(expect, rel=1e-4)
    ends = np.array([c.curve.evaluate(np.array([c.t0, c.t1])) for c in r.curves if not c.closed]).reshape(-1, 3)
    for i, p in enumerate(ends):
        d = np.linalg.norm(ends - p, axis=1)
        d[i] = np.inf
        assert d.min() <= 1e-7, "a piece of the loop ends loose"


def test_loop_about_one_grid_cell_across_is_traced_without_folding():
    # A half-sphere face box as the Boolean passes it: the loop spans about one cell and the main
    # grid sees only three or four crossings of it.
    depth = 1e-3
    cyl = _grazing_cylinder(depth)
    r = march_intersection(SPHERE, cyl, ((-0.031, 3.173), (-1.602, 1.602)), CYL_BOX)
    assert len(r.curves) == 1 and r.curves[0].closed
    c = r.curves[0]
    _on_both(r, SPHERE, cyl)
    expect = _ellipse_perimeter(math.sqrt(2 * depth), math.sqrt(2 * depth / 3))
    assert _length(c) == pytest.approx(expect, rel=5e-3)
    P = c.curve.evaluate(np.linspace(c.t0, c.t1, 401))
    assert _winds_once(P, np.array([0.0, 1.0, 0.0]), np.array([1.0, 0, 0]), np.array([0, 0, 1.0]))


def test_surfaces_that_nearly_touch_without_cutting_give_nothing():
    r = march_intersection(SPHERE, _grazing_cylinder(-1e-5), None, CYL_BOX)
    assert r.curves == () and r.points.shape == (0, 3)


def _bump():
    g = np.linspace(-1, 1, 7)
    X, Y = np.meshgrid(g, g, indexing="ij")
    return interpolate_surface(np.stack([X, Y, 0.5 * np.exp(-3 * (X**2 + Y**2))], axis=-1), 3, 3)


@pytest.mark.parametrize("depth", [1e-5, 1e-6])
def test_nurbs_bump_crossing_a_plane_in_a_tiny_loop(depth):
    up = _bump()
    d = up.derivatives(0.5, 0.5, 2)
    apex = d[0, 0]
    plane = PlanarSurface(apex - [0, 0, depth], [0, 0, 1], [1, 0, 0])
    r = march_intersection(up, plane, None, ((-3, 3), (-3, 3)))
    assert len(r.curves) == 1 and r.curves[0].closed
    c = r.curves[0]
    _on_both(r, up, plane)
    # The loop is ½ wᵀ L w = depth in the parameters w, L the second fundamental form (the apex is
    # a maximum of z, normal e_z); its semi-axes in space come from L relative to the metric M.
    J = np.stack([d[1, 0], d[0, 1]], axis=1)
    M = J.T @ J
    L = -np.array([[d[2, 0, 2], d[1, 1, 2]], [d[1, 1, 2], d[0, 2, 2]]])
    lam = eigh(L, M, eigvals_only=True)
    semi = np.sqrt(2 * depth / lam)
    assert _length(c) == pytest.approx(_ellipse_perimeter(*semi), rel=1e-3)
    P = c.curve.evaluate(np.linspace(c.t0, c.t1, 401))
    assert _winds_once(P, apex, np.array([1.0, 0, 0]), np.array([0, 1.0, 0]))


@pytest.mark.parametrize("depth, rot", [
    (1e-3, (0, 0, 0)),
    (1e-4, (0, 0, 0)),
    # The loop straddles the boundary of the two half-sphere faces: an arc dips into one face's box
    # for about a cell and lost its end crossings (the cut ended inside the face).
    (0.0012580670925064247, (183.41851734774338, 183.91999840795188, 271.09087477278405)),
    # The main grid broke the loop into two chains of three and four crossings (a saddle cell):
    # one loop must come back, not the loop and a stray copy.
    (0.002575694213158854, (224.5293821182146, 218.47816368360532, 349.40115472774454)),
    # The extremum of f lies just outside one half-sphere face's box, its loop reaching in.
    (0.0019392910944116594, (193.3815064370768, 295.29640926645976, 99.33777272346248)),
])
def test_boolean_cut_by_a_tiny_loop_removes_the_lens(depth, rot):
    sphere = coons.Sphere(1.0)
    cyl = coons.Rot(*rot) * (coons.Pos(0, 1.5 - depth, 0) * coons.Rot(0, 90, 0) * coons.Cylinder(0.5, 4))
    R = sphere - cyl
    assert R.check().ok
    # The lens between the paraboloids: π depth² / √3 to relative order depth; the volume
    # integration's 1e-12 relative error on the sphere is below 3e-4 of the lens at depth 1e-4.
    removed = 4 / 3 * PI - R.volume
    assert removed == pytest.approx(PI * depth**2 / math.sqrt(3), rel=1e-3)


# ---------------------------------------------------------------------------- tangent points
TORUS = ToroidalSurface([0, 0, 0], [0, 0, 1], [1, 0, 0], 6.0, 2.0)
TORUS_BOX = ((0.0, 2 * PI), (0.0, 2 * PI))
PLANE_BOX = ((-10.0, 10.0), (-10.0, 10.0))


def _tangent_plane(u: float, v: float) -> tuple[PlanarSurface, np.ndarray]:
    p = TORUS.evaluate(u, v)
    n = TORUS.normal(u, v)
    x = np.cross(n, [0.3, 0.1, 0.9])
    return PlanarSurface(p, n, x / np.linalg.norm(x)), p


@pytest.mark.parametrize("u, v", [(0.0, 0.0), (1.2, 0.4), (4.0, -1.1), (5.5, 1.2)])
def test_plane_tangent_to_the_outer_tube_touches_at_one_point(u, v):
    plane, p = _tangent_plane(u, v)
    r = march_intersection(TORUS, plane, TORUS_BOX, PLANE_BOX)
    assert r.curves == ()
    np.testing.assert_allclose(r.points, [p], rtol=0, atol=1e-7)


# (1.181, 2.011) and (6.079, 3.607): the chains turned a cell away from the crossing and were not
# split there; (0.091, 4.243): a chain beyond G's seam was split at the point's image there.
@pytest.mark.parametrize("u, v", [(PI, PI), (1.181, 2.011), (6.079, 3.607), (0.091, 4.243), (2.5, 3.9)])
def test_plane_tangent_to_the_inner_tube_gives_four_branches_ending_at_the_point(u, v):
    plane, p = _tangent_plane(u, v)
    r = march_intersection(TORUS, plane, TORUS_BOX, PLANE_BOX)
    assert r.points.shape == (0, 3)
    _on_both(r, TORUS, plane)
    ends, params = [], []
    for c in r.curves:
        assert c.t1 - c.t0 > 1e-2, "a spurious short branch"
        if not c.closed:
            t = np.array([c.t0, c.t1])
            ends.append(c.curve.evaluate(t))
            params.append(np.concatenate([c.pcurve_a.evaluate(t), c.pcurve_b.evaluate(t)], axis=1))
    ends, params = np.concatenate(ends), np.concatenate(params)
    at_p = np.linalg.norm(ends - p, axis=1) <= 1e-7
    assert int(at_p.sum()) == 4
    # Every other end is on the torus box (its seams) or the plane's box.
    box = np.array(TORUS_BOX + PLANE_BOX)
    on_box = np.any(np.abs(params[:, :, None] - box[None]).reshape(len(params), -1) <= 1e-7, axis=1)
    assert np.all(at_p | on_box)
    # The p-curves stay in the torus box (no piece ends at the point's image a period away).
    for c in r.curves:
        uv = c.pcurve_a.evaluate(np.linspace(c.t0, c.t1, 101))
        assert np.all((uv >= -1e-9) & (uv <= 2 * PI + 1e-9))


def test_torus_and_the_faces_of_a_box_tangent_to_its_tube():
    """coons.validation.cases torus_minus_box: x = 8 touches the tube at (8, 0, 0); x = 4 cuts the
    lemniscate whose double point (4, 0, 0) is a saddle contact."""
    outer = PlanarSurface([8, -10, -4], [1, 0, 0], [0, 1, 0])
    r = march_intersection(TORUS, outer, TORUS_BOX, ((-0.2, 20.2), (-0.08, 8.08)))
    assert r.curves == ()
    np.testing.assert_allclose(r.points, [[8, 0, 0]], rtol=0, atol=1e-7)
    inner = PlanarSurface([4, 10, -4], [-1, 0, 0], [0, -1, 0])
    r = march_intersection(TORUS, inner, TORUS_BOX, ((-0.2, 20.2), (-0.08, 8.08)))
    _on_both(r, TORUS, inner)
    ends = np.concatenate([c.curve.evaluate(np.array([c.t0, c.t1])) for c in r.curves if not c.closed])
    assert int((np.linalg.norm(ends - [4, 0, 0], axis=1) <= 1e-7).sum()) == 4
    # The lemniscate (ρ - 6)² + z² = 4 in x = 4: its length by quadrature of the same curve.
    total = sum(_length(c) for c in r.curves)
    # Parametrised by the tube angle w: ρ = 6 + 2 cos w, z = 2 sin w, y = sqrt(ρ² - 16), w ∈ (−π, π).
    w = np.linspace(-PI, PI, 400001)
    rho, z = 6 + 2 * np.cos(w), 2 * np.sin(w)
    y = np.sqrt(np.maximum(rho**2 - 16, 0.0))
    half = np.sum(np.hypot(np.diff(y), np.diff(z)))
    assert total == pytest.approx(2 * half, rel=1e-6)
