"""Point membership of curved solids (coons.booleans.classify): closed-form implicit tests of primitives
on random points, points 1e-6 from curved walls, rims and box edges (decided exactly, not by the mesh),
points on faces / edges / poles, several lumps and voids, and every error branch."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from coons.booleans.classify import INSIDE, ON, OUTSIDE, Classifier, classify_points, winding_numbers
from coons.errors import InvalidInputError
from coons.tolerance import Tolerance
from coons.topology.primitives import Box, Cone, Cylinder, Sphere, Torus

LIN = 1e-7


def _expected(signed_distance: np.ndarray) -> np.ndarray:
    """-1 / 0 / +1 from an exact signed distance (negative inside), ``on`` within 1e-7."""
    return np.where(np.abs(signed_distance) <= LIN, ON, np.where(signed_distance < 0, INSIDE, OUTSIDE))


def _sd_box(P, h=5.0):
    q = np.abs(P) - h
    return np.linalg.norm(np.maximum(q, 0.0), axis=1) + np.minimum(q.max(axis=1), 0.0)


def _sd_cylinder(P, r=3.0, h=10.0):
    q = np.stack([np.hypot(P[:, 0], P[:, 1]) - r, np.abs(P[:, 2]) - h], axis=1)
    return np.linalg.norm(np.maximum(q, 0.0), axis=1) + np.minimum(q.max(axis=1), 0.0)


def _sd_sphere(P, r=5.0):
    return np.linalg.norm(P, axis=1) - r


def _sd_torus(P, R=5.0, r=1.0):
    return np.hypot(np.hypot(P[:, 0], P[:, 1]) - R, P[:, 2]) - r


# ---------------------------------------------------------------------- random points, closed forms
@pytest.mark.parametrize("make, sd", [
    (lambda: Sphere(5.0), _sd_sphere),
    (lambda: Cylinder(3.0, 20.0), _sd_cylinder),
    (lambda: Box(10, 10, 10), _sd_box),
    (lambda: Torus(5.0, 1.0), _sd_torus),
])
def test_agrees_with_implicit_test_on_random_points(make, sd):
    solid = make()
    bb = solid.bounding_box()
    P = np.random.default_rng(0).uniform(bb[0] - 1.0, bb[1] + 1.0, (10_000, 3))
    got = classify_points(solid, P)
    np.testing.assert_array_equal(got, _expected(sd(P)))
    assert got.dtype == np.int8
    assert 0 < np.count_nonzero(got == INSIDE) < P.shape[0]


def test_cone_apex_and_base():
    cone = Cone(3.0, 0.0, 6.0, align=None)  # base at z = 0, apex at z = 6
    P = np.array([[0, 0, 3.0], [0, 0, 6.0], [0, 0, 6 + 1e-6], [0, 0, 6 - 1e-6], [1.5, 0, 3.0],
                  [1.5 + 1e-6, 0, 3.0], [0, 0, 0], [0, 0, -1e-6]])
    np.testing.assert_array_equal(classify_points(cone, P), [INSIDE, ON, OUTSIDE, INSIDE, ON, OUTSIDE, ON, OUTSIDE])


# ---------------------------------------------------------------------- near the boundary: exact decisions
def test_points_a_micron_from_the_sphere_are_decided_exactly():
    rng = np.random.default_rng(1)
    u = rng.normal(size=(2000, 3))
    u /= np.linalg.norm(u, axis=1)[:, None]
    sphere = Sphere(5.0)
    c = Classifier(sphere)
    assert c.band > 1e-3  # the mesh alone could not decide these points
    for eps, want in ((1e-6, OUTSIDE), (-1e-6, INSIDE), (0.0, ON), (5e-8, ON), (-5e-8, ON)):
        np.testing.assert_array_equal(c.classify(u * (5.0 + eps))[0], want, err_msg=str(eps))
    # Poles and the meridian seam edges of the two hemispheres.
    P = np.array([[0, 0, 5.0], [0, 0, 5 + 1e-6], [0, 0, -5 + 1e-6], [0, 5.0, 0], [0, 5 + 1e-6, 0], [0, -5 + 1e-6, 0]])
    np.testing.assert_array_equal(c.classify(P)[0], [ON, OUTSIDE, INSIDE, ON, OUTSIDE, INSIDE])


def test_points_near_the_cylinder_rim_use_the_wedge_rule():
    rng = np.random.default_rng(2)
    th, ph = rng.uniform(0, 2 * np.pi, 3000), rng.uniform(0, 2 * np.pi, 3000)
    rim = np.stack([3 * np.cos(th), 3 * np.sin(th), np.full_like(th, 10.0)], axis=1)
    d = np.stack([np.cos(ph) * np.cos(th), np.cos(ph) * np.sin(th), np.sin(ph)], axis=1)
    cyl = Cylinder(3.0, 20.0)
    for r in (1e-6, 1e-9, 1e-3):
        P = rim + r * d
        np.testing.assert_array_equal(classify_points(cyl, P), _expected(_sd_cylinder(P)), err_msg=str(r))


def test_points_in_the_plane_of_a_face_with_a_hole_are_decided_by_the_nearest_edge():
    # A disc with a square hole where a post rises through it: points in the disc's plane inside the
    # hole lie on the disc's surface but off the face, far from every edge (the nearest, the hole's
    # rim, lies 0.1–0.5 away: well beyond the band in which edges were first searched).
    part = Cylinder(2.0, 2.0) + Box(1.0, 1.0, 4.0).translate((0, 0, 1))
    rng = np.random.default_rng(7)
    P = np.column_stack([rng.uniform(-0.4, 0.4, (300, 2)), np.full(300, 1.0)])
    P = np.concatenate([P, P + [0, 0, 1e-3], P - [0, 0, 1e-3]])
    np.testing.assert_array_equal(classify_points(part, P), np.full(P.shape[0], INSIDE))
    # and beside the post above the disc, outside
    Q = np.column_stack([rng.uniform(0.6, 1.2, (300, 2)) * rng.choice([-1, 1], (300, 2)), np.full(300, 1.2)])
    np.testing.assert_array_equal(classify_points(part, Q), np.full(300, OUTSIDE))


def test_points_near_box_edges_and_corners():
    rng = np.random.default_rng(3)
    n = 4000
    P = rng.uniform(-5, 5, (n, 3))
    k = rng.integers(0, 3, n)
    P[np.arange(n), k] = 5 + rng.uniform(-1e-5, 1e-5, n)
    P[np.arange(n), (k + 1) % 3] = -5 + rng.uniform(-1e-5, 1e-5, n)
    corners = np.array([[5, 5, 5]]) + rng.uniform(-1e-5, 1e-5, (500, 3))
    P = np.concatenate([P, corners])
    np.testing.assert_array_equal(classify_points(Box(10, 10, 10), P), _expected(_sd_box(P)))


def test_on_points_report_the_outward_normal():
    c = Classifier(Cylinder(3.0, 20.0))
    cls, n = c.classify(np.array([[0, 3.0, 0], [0, 0, 10.0], [0, 0, 0], [3.0, 0, 10.0], [3.0, 0, 0]]))
    np.testing.assert_array_equal(cls, [ON, ON, INSIDE, ON, ON])
    np.testing.assert_allclose(n[0], [0, 1, 0], atol=1e-15)
    np.testing.assert_allclose(n[1], [0, 0, 1], atol=1e-15)
    # Not on the boundary, or on the sharp rim: no normal; on the smooth ruling between the two
    # half-cylinders: the common normal.
    assert np.all(np.isnan(n[2])) and np.all(np.isnan(n[3]))
    np.testing.assert_allclose(n[4], [1, 0, 0], atol=1e-12)


def test_several_lumps_and_a_void():
    from coons.booleans.solid import difference, union

    two = union(Sphere(1.0), Sphere(1.0).translate((5, 0, 0)))
    P = np.array([[0, 0, 0], [5, 0, 0], [2.5, 0, 0], [1.0, 0, 0], [6 + 1e-6, 0, 0]])
    np.testing.assert_array_equal(classify_points(two, P), [INSIDE, INSIDE, OUTSIDE, ON, OUTSIDE])
    hollow = difference(Box(10, 10, 10), Sphere(2.0))
    P = np.array([[0, 0, 0], [3, 0, 0], [2.0, 0, 0], [0, 0, 2 - 1e-6], [0, 0, 2 + 1e-6], [9, 0, 0]])
    np.testing.assert_array_equal(classify_points(hollow, P), [OUTSIDE, INSIDE, ON, OUTSIDE, INSIDE, OUTSIDE])


def test_winding_by_shell_equals_the_whole_mesh_sum():
    """Skipping closed shells whose box misses a point changes its winding number by round-off only."""
    from coons.booleans.solid import difference, union

    rng = np.random.default_rng(5)
    lumps = union(Sphere(1.0), Box(1, 1, 1).translate((4, 0, 0)), Sphere(0.5).translate((0, 4, 0)))
    hollow = difference(Box(10, 10, 10), Sphere(2.0))
    for solid in (lumps, hollow):
        c = Classifier(solid)
        Q = rng.uniform(c.lo - 1.0, c.hi + 1.0, (400, 3))
        np.testing.assert_allclose(c._winding(Q), winding_numbers(Q, c.tri), rtol=0, atol=1e-9)


def test_tolerance_sets_the_on_band():
    P = np.array([[0, 0, 5 + 1e-5]])
    assert classify_points(Sphere(5.0), P).tolist() == [OUTSIDE]
    assert classify_points(Sphere(5.0), P, Tolerance(linear=1e-4)).tolist() == [ON]


def test_empty_solid_and_empty_batch():
    from coons.topology.shape import Solid

    assert classify_points(Solid.empty(), [[0, 0, 0]]).tolist() == [OUTSIDE]
    assert classify_points(Sphere(1.0), np.zeros((0, 3))).shape == (0,)


def test_winding_numbers_of_a_tetrahedron():
    T = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1.0]])
    tris = T[np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])]
    w = winding_numbers(np.array([[0.1, 0.1, 0.1], [2, 2, 2]]), tris)
    np.testing.assert_allclose(w, [1.0, 0.0], atol=1e-12)


# ---------------------------------------------------------------------- errors
def test_errors():
    with pytest.raises(InvalidInputError, match=r"points must have shape \(n, 3\), got \(2, 2\)"):
        classify_points(Sphere(1.0), np.zeros((2, 2)))
    with pytest.raises(InvalidInputError, match="points must be finite"):
        classify_points(Sphere(1.0), [[np.nan, 0, 0]])
    with pytest.raises(InvalidInputError, match="classify needs a Solid or BRep, got str"):
        classify_points("sphere", [[0, 0, 0]])
    with pytest.raises(InvalidInputError, match="tol must be a coons.Tolerance"):
        classify_points(Sphere(1.0), [[0, 0, 0]], tol=1e-3)


def test_classifier_builds_face_data_only_near_the_queries_and_reuses_a_mesh():
    from coons.booleans.classify import Classifier
    from coons.topology.primitives import Box
    from coons.topology.tessellate import tessellate

    box = Box(10, 10, 10)
    mesh = tessellate(box)
    c = Classifier(box, mesh=mesh)
    assert all(f is None for f in c._faces)
    P = np.array([[0.0, 0.0, 4.9999], [0.0, 0.0, 0.0], [0.0, 0.0, 5.0]])  # near the top face only
    cls, _ = c.classify(P)
    assert cls.tolist() == [-1, -1, 0]
    built = [f is not None for f in c._faces]
    assert 1 <= sum(built) < 6
    again, _ = Classifier(box).classify(P)  # its own tessellation: the same answers
    assert again.tolist() == cls.tolist()
    assert len(c.faces) == 6 and all(f is not None for f in c._faces)


def _in_polygon_pairs(uv, seg):
    """The even-odd test on every point-segment pair (the reference of the row sweep)."""
    a, c = seg[:, 0], seg[:, 1]
    x, y = uv[:, 0:1], uv[:, 1:2]
    straddle = (a[None, :, 1] > y) != (c[None, :, 1] > y)
    dy = c[:, 1] - a[:, 1]
    with np.errstate(divide="ignore", invalid="ignore"):
        xc = a[None, :, 0] + (y - a[None, :, 1]) * ((c[:, 0] - a[:, 0]) / np.where(dy == 0, 1.0, dy))[None, :]
    return (np.count_nonzero(straddle & (x < xc), axis=1) % 2) == 1


@settings(max_examples=30, deadline=None)
@given(st.integers(0, 2**32 - 1), st.integers(1, 40), st.booleans(), st.booleans())
def test_in_polygon_row_sweep_equals_every_pair(seed, holes, grid, sweep):
    """Points on shared rows (a grid of candidates) take the row sweep; it gives the answers of the
    pair-by-pair test exactly, on a square with many polygonal holes (some on the grid's rows and
    vertices: axis-aligned squares on grid values)."""
    import coons.booleans.classify as C

    rng = np.random.default_rng(seed)
    rings = [np.array([[0.0, 0.0], [10.0, 0.0], [10.0, 10.0], [0.0, 10.0]])]
    for _ in range(holes):
        c = rng.uniform(1, 9, 2)
        if rng.random() < 0.3:  # on grid values: vertices and horizontal edges on the rows
            c = np.round(c * 4) / 4
            r = 0.25
            rings.append(c + r * np.array([[-1, -1], [-1, 1], [1, 1], [1, -1]], float))
        else:
            k = int(rng.integers(3, 40))
            ang = np.sort(rng.uniform(0, 2 * np.pi, k))[::-1]
            rings.append(c + rng.uniform(0.05, 0.6) * np.stack([np.cos(ang), np.sin(ang)], 1))
    seg = np.concatenate([np.stack([R, np.roll(R, -1, axis=0)], axis=1) for R in rings])
    if grid:
        g = np.arange(41) / 4.0
        uv = np.stack(np.meshgrid(g, g, indexing="ij"), -1).reshape(-1, 2)
    else:
        uv = rng.uniform(-1, 11, (500, 2))
    old = C._ROW_SWEEP_PAIRS
    C._ROW_SWEEP_PAIRS = 0 if sweep else old  # the sweep also for small problems
    try:
        got = C._in_polygon(uv, seg)
    finally:
        C._ROW_SWEEP_PAIRS = old
    np.testing.assert_array_equal(got, _in_polygon_pairs(uv, seg))
