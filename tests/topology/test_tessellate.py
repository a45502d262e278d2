"""Watertight tessellation: closed and vertex-manifold meshes of every primitive (moved, mirrored,
inside out, NURBS-faced, with holes, polyhedral), the deflection bound measured against the exact
surfaces, volumes converging to the exact ones, the closed-form edge discretisation, edges with a C0
knot, the strips of revolved faces (their bound checked on worst-case triangles, their merge tiling
each strip exactly, rows asked by neighbours, fewer triangles than OCCT), the general path with chord
repairs, and every error branch.  trimesh / manifold3d acceptance is in tests/io/test_mesh_interop.py."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from hypothesis import example, given
from hypothesis import strategies as st

from coons.errors import ConvergenceError, InvalidInputError, TopologyError
from coons.kernel import conics
from coons.kernel.analytic import Circle, CylindricalSurface, Line, PlanarSurface
from coons.kernel.curve import NurbsCurve
from coons.kernel.pcurve import Line2D
from coons.tolerance import Tolerance
from coons.topology import tessellate as tess
from coons.topology.brep import BRep
from coons.topology.builder import BRepBuilder
from coons.topology.check import check
from coons.topology.mass import bounding_box, face_areas
from coons.topology.mesh import TriangleMesh
from coons.topology.primitives import Box, Cone, Cylinder, Sphere, Torus
from coons.topology.shape import Solid
from coons.topology.tessellate import edge_parameters, tessellate

PI = math.pi
#: Mesh vertices are surface evaluations: on the surface to round-off of the coordinates.
ON_SURFACE = 1e-12


# ============================================================================ fixtures
def block_with_hole(a: float = 1.0, r: float = 0.4, h: float = 1.0, *, check_it: bool = True) -> BRep:
    """A square block ``[-a, a]² × [0, h]`` with a cylindrical through hole of radius ``r``.

    Top and bottom are implicit planes with an inner loop of two half circles; the hole is two
    half-cylinder faces whose outward normal points at the axis (``face_sense = False``, loops
    clockwise in (u, v)).  Genus 1.
    """
    P = np.array([[-a, -a, 0], [a, -a, 0], [a, a, 0], [-a, a, 0], [-a, -a, h], [a, -a, h], [a, a, h], [-a, a, h],
                  [r, 0, 0], [-r, 0, 0], [r, 0, h], [-r, 0, h]], float)
    E = [(0, 1), (1, 2), (2, 3), (3, 0), (4, 5), (5, 6), (6, 7), (7, 4), (0, 4), (1, 5), (2, 6), (3, 7),
         (8, 9), (9, 8), (10, 11), (11, 10), (8, 10), (9, 11)]
    loops = [
        [[5, 6, 7, 8], [-16, -15]],  # top, hole clockwise
        [[-4, -3, -2, -1], [13, 14]],  # bottom
        [[1, 10, -5, -9]], [[2, 11, -6, -10]], [[3, 12, -7, -11]], [[4, 9, -8, -12]],
        [[-13, 17, 15, -18]],  # hole, u in [0, π]
        [[-14, 18, 16, -17]],  # hole, u in [π, 2π]
    ]
    cyl = CylindricalSurface([0, 0, 0], [0, 0, 1], [1, 0, 0], r)
    b = BRepBuilder()
    b.assemble(P, np.array(E), loops, face_surfaces=[None] * 6 + [cyl, cyl], face_senses=[True] * 6 + [False, False])
    for e, (s, t) in enumerate(E[:12]):
        d = P[t] - P[s]
        b.set_edge_curve(e, Line(P[s], d / np.linalg.norm(d)), (0.0, float(np.linalg.norm(d))))
    c0, c1 = Circle([0, 0, 0], [0, 0, 1], [1, 0, 0], r), Circle([0, 0, h], [0, 0, 1], [1, 0, 0], r)
    for e, c, rng in ((12, c0, (0, PI)), (13, c0, (PI, 2 * PI)), (14, c1, (0, PI)), (15, c1, (PI, 2 * PI))):
        b.set_edge_curve(e, c, rng)
    b.set_edge_curve(16, Line(P[8], [0, 0, 1]), (0, h))
    b.set_edge_curve(17, Line(P[9], [0, 0, 1]), (0, h))
    pcurves = {12: {6: Line2D([0, 0], [1, 0])}, 13: {7: Line2D([0, 0], [1, 0])},
               14: {6: Line2D([0, h], [1, 0])}, 15: {7: Line2D([0, h], [1, 0])},
               16: {6: Line2D([0, 0], [0, 1]), 7: Line2D([2 * PI, 0], [0, 1])},
               17: {6: Line2D([PI, 0], [0, 1]), 7: Line2D([PI, 0], [0, 1])}}
    for e, by_face in pcurves.items():
        for side in (0, 1):
            f = b.lface[b.cloop[2 * e + side]]
            if f in by_face:
                b.set_pcurve(2 * e + side, by_face[f])
    return b.build(check=check_it)


def polyhedron(points, faces) -> BRep:
    """Implicit-plane polyhedron from outward vertex loops (a face: a loop or [outer, holes...])."""
    bld = BRepBuilder()
    bld.assemble_polygons(np.asarray(points, dtype=float), faces)
    return bld.build()


def euler_block(size: float = 1.0) -> BRep:
    """mvfs, 3 mev, mef, sweep_loop: a cube of implicit planes."""
    b = BRepBuilder()
    _, _, l0, _ = b.mvfs([0, 0, 0])
    e0, _ = b.mev(l0, None, [size, 0, 0])
    e1, _ = b.mev(l0, 2 * e0, [size, size, 0])
    e2, _ = b.mev(l0, 2 * e1, [0, size, 0])
    b.mef(l0, 2 * e2, 2 * e0 + 1)
    b.sweep_loop(l0, [0, 0, size])
    return b.build()


def l_prism(h: float = 1.0) -> BRep:
    """An L-shaped prism: two non-convex L faces and six rectangles (implicit planes)."""
    L = [[0, 0], [2, 0], [2, 1], [1, 1], [1, 2], [0, 2]]
    P = [[x, y, 0] for x, y in L] + [[x, y, h] for x, y in L]
    n = len(L)
    faces = [list(range(n))[::-1], list(range(n, 2 * n))]
    faces += [[i, (i + 1) % n, n + (i + 1) % n, n + i] for i in range(n)]
    return polyhedron(P, faces)


def frame(a: float = 2.0, c: float = 1.0, h: float = 1.0) -> BRep:
    """A square frame: a block with a square through hole; top and bottom have inner loops (genus 1)."""
    sq = lambda s, z: [[-s, -s, z], [s, -s, z], [s, s, z], [-s, s, z]]  # noqa: E731
    P = sq(a, 0) + sq(a, h) + sq(c, 0) + sq(c, h)
    faces = [[[4, 5, 6, 7], [12, 15, 14, 13]], [[0, 3, 2, 1], [8, 9, 10, 11]]]
    faces += [[i, (i + 1) % 4, 4 + (i + 1) % 4, 4 + i] for i in range(4)]
    faces += [[8 + (i + 1) % 4, 8 + i, 12 + i, 12 + (i + 1) % 4] for i in range(4)]
    return polyhedron(P, faces)


def reversed_brep(b: BRep) -> BRep:
    """The shell turned inside out: loops walked backwards, senses flipped (a void's orientation)."""
    nxt, prv = b.coedge_next, b.coedge_prev
    c = np.arange(2 * b.n_edges)
    new_next, new_prev = prv[c ^ 1] ^ 1, nxt[c ^ 1] ^ 1
    wing = np.stack([new_prev[0::2], new_next[0::2], new_prev[1::2], new_next[1::2]], axis=1)
    return dataclasses.replace(b, edge_loop=b.edge_loop[:, ::-1], edge_wing=wing, edge_pcurve=b.edge_pcurve[:, ::-1],
                               loop_coedge=np.where(b.loop_coedge >= 0, b.loop_coedge ^ 1, -1), face_sense=~b.face_sense)


def nurbs_sided(b: BRep) -> BRep:
    """A cylinder or sphere whose curved faces are exact rational NURBS (``conics``), with NURBS
    iso-curve edges (same parameter as their ``Line2D`` p-curves) and 2-D NURBS p-curves on the disks."""
    surfaces, face_surface, new = list(b.surfaces), b.face_surface.copy(), {}
    for f in range(b.n_faces):
        S = b.surfaces[b.face_surface[f]]
        if isinstance(S, PlanarSurface):
            continue
        us = []
        for c in b.loop_coedges(int(b.face_loop_ids(f)[0])):
            e = int(c) >> 1
            side = int(np.flatnonzero(b.edge_face[e] == f)[0])
            us += list(b.pcurves[b.edge_pcurve[e, side]].evaluate(np.asarray(b.edge_range[e]))[:, 0])
        u_range = (min(us), max(us))
        if isinstance(S, CylindricalSurface):
            N = conics.nurbs_cylinder(S.origin, S.axis, S.radius, (-100.0, 100.0), x_dir=S.x_dir, u_range=u_range)
        else:
            N = conics.nurbs_sphere(S.center, S.axis, S.radius, x_dir=S.x_dir, u_range=u_range)
        new[f] = face_surface[f] = len(surfaces)
        surfaces.append(N)
    curves, pcurves = list(b.curves), list(b.pcurves)
    edge_curve, edge_pcurve = b.edge_curve.copy(), b.edge_pcurve.copy()
    for e in range(b.n_edges):
        if not isinstance(b.curves[b.edge_curve[e]], Circle):
            continue
        side = int(np.flatnonzero(np.isin(b.edge_face[e], list(new)))[0])
        pc = b.pcurves[b.edge_pcurve[e, side]]
        N = surfaces[new[int(b.edge_face[e, side])]]
        iso = N.iso_curve("v", float(pc.origin[1])) if pc.direction[1] == 0.0 else N.iso_curve("u", float(pc.origin[0]))
        edge_curve[e] = len(curves)
        curves.append(iso)
        other = int(b.edge_face[e, 1 - side])
        plane = b.surfaces[b.face_surface[other]]
        if isinstance(plane, PlanarSurface):
            edge_pcurve[e, 1 - side] = len(pcurves)
            pcurves.append(NurbsCurve(plane.closest_parameters(iso.control_points), iso.knots, iso.degree, iso.weights))
    return dataclasses.replace(b, surfaces=tuple(surfaces), face_surface=face_surface, curves=tuple(curves),
                               edge_curve=edge_curve, pcurves=tuple(pcurves), edge_pcurve=edge_pcurve)


PRIMITIVES = {
    "box": lambda: Box(1.0, 2.0, 3.0),
    "cylinder": lambda: Cylinder(1.0, 2.0),
    "cone": lambda: Cone(1.0, 0.0, 2.0),
    "frustum": lambda: Cone(1.0, 0.4, 1.5),
    "sphere": lambda: Sphere(1.0),
    "torus": lambda: Torus(2.0, 0.5),
}
GENUS = {"torus": 1}


def moved(s: Solid) -> Solid:
    return s.rotate((0.3, -1.0, 2.0), (1.0, 2.0, -0.5), 37.0).translate((4.0, -2.0, 1.0)).scale(2.5)


def mirrored(s: Solid) -> Solid:
    return s.mirror((1.0, 0.0, 0.0), (1.0, 1.0, 1.0))


# ============================================================================ measuring
def barycentric(k: int = 6) -> np.ndarray:
    I, J = np.meshgrid(np.arange(k + 1), np.arange(k + 1))
    keep = I + J <= k
    return np.stack([I[keep], J[keep], (k - I - J)[keep]], axis=1) / k


def surface_deviation(b: BRep, mesh: TriangleMesh) -> tuple[float, float, int]:
    """(max distance of points sampled in every triangle, max distance of the vertices, number of
    triangles whose normal opposes the outward surface normal), over faces with analytic surfaces."""
    W = barycentric()
    worst = vert = 0.0
    flipped = 0
    for f in range(b.n_faces):
        si = int(b.face_surface[f])
        if si < 0 or not hasattr(b.surfaces[si], "implicit"):
            continue
        S = b.surfaces[si]
        T = mesh.triangles[mesh.face_ids == f]
        Q = mesh.vertices[T]
        worst = max(worst, float(np.abs(S.implicit(np.einsum("sw,twj->tsj", W, Q))).max()))
        vert = max(vert, float(np.abs(S.implicit(mesh.vertices[np.unique(T)])).max()))
        n = np.cross(Q[:, 1] - Q[:, 0], Q[:, 2] - Q[:, 0])
        uv = S.closest_parameters(Q.mean(axis=1))
        outward = S.normal(uv[:, 0], uv[:, 1]) * (1.0 if b.face_sense[f] else -1.0)
        flipped += int(np.sum(np.einsum("ij,ij->i", n, outward) <= 0))
    return worst, vert, flipped


def vertex_links_are_cycles(mesh: TriangleMesh) -> bool:
    """Every used vertex's opposite edges form one cycle (a disk around it: vertex-manifold)."""
    T = mesh.triangles
    link: dict[int, dict[int, int]] = {}
    for a, b, c in T.tolist():
        for v, p, q in ((a, b, c), (b, c, a), (c, a, b)):
            d = link.setdefault(v, {})
            if p in d:
                return False
            d[p] = q
    for d in link.values():
        start = next(iter(d))
        p, n = start, 0
        while True:
            p = d.get(p)
            n += 1
            if p is None:
                return False
            if p == start:
                break
        if n != len(d):
            return False
    return True


def scale_of(b: BRep) -> float:
    box = bounding_box(b)
    return float(np.linalg.norm(box[1] - box[0]))


# ============================================================================ closed, manifold, exact
@pytest.mark.parametrize("place", ["as built", "moved", "mirrored"])
@pytest.mark.parametrize("name", list(PRIMITIVES))
def test_primitives_are_closed_manifold_and_within_deflection(name, place):
    s = {"as built": lambda x: x, "moved": moved, "mirrored": mirrored}[place](PRIMITIVES[name]())
    b = s.brep
    d = 0.01 * scale_of(b)
    m = tessellate(s, deflection=d)
    assert m.is_closed and m.boundary_edges().shape == (0, 2)
    assert m.euler_characteristic == 2 - 2 * GENUS.get(name, 0)
    assert vertex_links_are_cycles(m)
    worst, vert, flipped = surface_deviation(b, m)
    assert worst <= d, f"a triangle is {worst / d:.3f} deflections from its surface"
    assert vert <= ON_SURFACE * scale_of(b)
    assert flipped == 0
    # Every face is meshed and its triangles' area is within a deflection-sized strip of the exact area.
    areas = np.bincount(m.face_ids, weights=np.linalg.norm(m.triangle_normals, axis=1), minlength=b.n_faces)
    np.testing.assert_allclose(areas, face_areas(b), rtol=0, atol=4 * d * scale_of(b))
    # The B-rep's vertices come first, unchanged.
    np.testing.assert_array_equal(m.vertices[: b.n_vertices], b.vertex_point)
    assert np.all(m.volume > 0) and abs(m.volume - s.volume) <= d * s.area


@pytest.mark.parametrize("name", ["cylinder", "cone", "sphere", "torus"])
def test_volume_converges_to_the_exact_volume(name):
    s = PRIMITIVES[name]()
    errors = []
    for d in (1e-1, 1e-2, 1e-3):
        m = tessellate(s, deflection=d)
        err = s.volume - m.volume
        assert abs(err) <= d * s.area, (d, err)
        if name != "torus":  # convex solids: the mesh is inscribed
            assert err > 0
        errors.append(abs(err))
    assert errors[0] > errors[1] > errors[2]


def test_deflection_is_respected_at_fine_resolution():
    for s in (Sphere(2.0), Torus(2.0, 0.5), Cone(1.0, 0.3, 2.0)):
        d = 1e-3
        m = tessellate(s, deflection=d)
        worst, _, flipped = surface_deviation(s.brep, m)
        assert worst <= d and flipped == 0
        assert worst > 0.5 * d  # and not needlessly fine


def test_default_deflection_is_a_thousandth_of_the_diagonal():
    s = Sphere(3.0)
    m = tessellate(s)
    diag = scale_of(s.brep)
    worst, _, _ = surface_deviation(s.brep, m)
    assert 0.5e-3 * diag < worst <= 1e-3 * diag
    assert m.n_triangles == tessellate(s, deflection=1e-3 * diag).n_triangles


def test_angular_deflection_limits_the_chord_turning():
    s = Cylinder(1.0, 1.0)
    coarse = tessellate(s, deflection=0.5, angular_deflection=PI)
    fine = tessellate(s, deflection=0.5, angular_deflection=0.1)
    assert fine.is_closed and coarse.is_closed
    # Each half circle: ceil(π / min(θ, 2 acos(1 - d / R))) segments.
    segments = lambda theta: math.ceil(PI / min(theta, 2 * math.acos(1 - 0.5)))  # noqa: E731
    assert coarse.n_vertices == 4 + 4 * (segments(PI) - 1)
    assert fine.n_vertices == 4 + 4 * (segments(0.1) - 1)


def test_edge_discretisation_closed_forms():
    b = Cylinder(2.0, 3.0).brep
    d, a = 1e-3, 0.5
    for e in range(b.n_edges):
        t = edge_parameters(b, e, d, a)
        np.testing.assert_array_equal(t[[0, -1]], b.edge_range[e])
        c = b.curves[b.edge_curve[e]]
        if isinstance(c, Line):
            assert t.size == 2
        else:
            step = min(a, 2 * math.acos(1 - d / c.radius))
            assert t.size == math.ceil(PI / step) + 1
            np.testing.assert_allclose(np.diff(t), PI / (t.size - 1), rtol=1e-12)
            P = c.evaluate(t)
            sagitta = np.linalg.norm(c.evaluate(0.5 * (t[:-1] + t[1:])) - 0.5 * (P[:-1] + P[1:]), axis=1)
            assert sagitta.max() <= d


@given(
    kind=st.sampled_from(["cylinder", "cone", "frustum", "sphere", "torus"]),
    size=st.tuples(st.floats(0.05, 20.0), st.floats(0.05, 0.95), st.floats(0.05, 20.0)),
    relative=st.floats(1e-3, 0.5),
    angular=st.floats(0.05, PI),
    turn=st.tuples(st.floats(-1, 1), st.floats(-1, 1), st.floats(0.1, 1), st.floats(0, 360)),
)
# The coarsest meshes: an octahedron sphere whose hemispheres share both meridians (chord conflicts),
# a square prism cylinder, a four-sided cone.
@example(kind="sphere", size=(1.0, 0.5, 1.0), relative=0.5, angular=PI, turn=(0.0, 0.0, 1.0, 0.0))
@example(kind="cylinder", size=(1.0, 0.5, 1.0), relative=0.5, angular=PI, turn=(0.0, 0.0, 1.0, 0.0))
@example(kind="cone", size=(1.0, 0.5, 1.0), relative=0.5, angular=PI, turn=(0.0, 0.0, 1.0, 0.0))
@example(kind="torus", size=(1.0, 0.5, 1.0), relative=0.5, angular=PI, turn=(0.0, 0.0, 1.0, 0.0))
def test_random_primitives_and_resolutions(kind, size, relative, angular, turn):
    a, ratio, c = size
    s = {"cylinder": lambda: Cylinder(a, c), "cone": lambda: Cone(a, 0.0, c), "frustum": lambda: Cone(a, a * ratio, c),
         "sphere": lambda: Sphere(a), "torus": lambda: Torus(a, a * ratio)}[kind]()
    s = s.rotate((0, 0, 0), turn[:3], turn[3])
    b = s.brep
    d = relative * scale_of(b)
    m = tessellate(s, deflection=d, angular_deflection=angular)
    assert m.is_closed and vertex_links_are_cycles(m)
    assert m.euler_characteristic == 2 - 2 * (kind == "torus")
    worst, _, flipped = surface_deviation(b, m)
    assert worst <= d
    # Triangle normals follow the surface's once the mesh resolves the curvature (a torus whose
    # tube is a square of four chords has triangles facing away from the nearest surface normal).
    smallest_radius = a * (ratio if kind in ("frustum", "torus") else 1.0)
    if d < 0.1 * smallest_radius and angular <= 1.0:
        assert flipped == 0
    assert abs(m.volume - s.volume) <= d * s.area


# ============================================================================ special faces
def test_poles_and_apex_collapse_to_one_vertex_with_a_fan():
    for s in (Sphere(1.0), Cone(1.0, 0.0, 2.0)):
        b = s.brep
        m = tessellate(s, deflection=0.05)
        assert m.is_closed and vertex_links_are_cycles(m)
        # The pole / apex vertices appear once each; no mesh vertex duplicates them.
        for v in range(b.n_vertices):
            same = np.flatnonzero(np.all(np.abs(m.vertices - b.vertex_point[v]) < 1e-12, axis=1))
            assert same.tolist() == [v]


def test_holes_reversed_faces_and_implicit_planes_with_curved_edges():
    b = block_with_hole()
    assert check(b).ok
    exact = 4.0 - PI * 0.16
    previous = math.inf
    for d in (1e-1, 1e-2, 1e-3):
        m = tessellate(b, deflection=d)
        assert m.is_closed and vertex_links_are_cycles(m)
        assert m.euler_characteristic == 0  # genus 1
        worst, _, flipped = surface_deviation(b, m)
        assert worst <= d and flipped == 0
        err = m.volume - exact  # the inscribed hole removes less than the exact one
        assert 0 < err <= d * 2 * PI * 0.4 and err < previous
        previous = err


def test_nurbs_faces_and_nurbs_edges():
    for s, radius in ((Cylinder(1.5, 2.0), 1.5), (Sphere(1.3), 1.3)):
        b = nurbs_sided(s.brep)
        assert check(b).ok
        for d in (1e-1, 1e-2):
            m = tessellate(b, deflection=d)
            assert m.is_closed and vertex_links_are_cycles(m)
            Q = m.vertices[m.triangles]
            X = np.einsum("sw,twj->tsj", barycentric(), Q)
            planar = [isinstance(b.surfaces[b.face_surface[f]], PlanarSurface) for f in range(b.n_faces)]
            curved = ~np.array(planar)[m.face_ids]
            rho = np.hypot(X[curved][..., 0], X[curved][..., 1]) if radius == 1.5 else np.linalg.norm(X[curved], axis=-1)
            assert np.abs(rho - radius).max() <= d
            assert abs(m.volume - s.volume) <= d * s.area


def test_inside_out_shells_and_voids():
    inv = reversed_brep(Sphere(1.0).brep)
    m = tessellate(inv, deflection=0.01)
    assert m.is_closed and m.volume < 0
    np.testing.assert_allclose(-m.volume, tessellate(Sphere(1.0), deflection=0.01).volume, rtol=1e-14)


# ============================================================================ polyhedra
def test_euler_block_of_implicit_planes():
    m = tessellate(euler_block(2.0), deflection=0.1)
    assert m.n_triangles == 12 and m.is_closed and vertex_links_are_cycles(m)
    np.testing.assert_allclose(m.volume, 8.0, rtol=1e-14)


def test_non_convex_faces_and_faces_with_holes():
    for b, volume, genus in ((l_prism(), 3.0, 0), (frame(), (16.0 - 4.0), 1)):
        assert check(b).ok
        m = tessellate(b, deflection=0.1)
        assert m.is_closed and vertex_links_are_cycles(m)
        assert m.euler_characteristic == 2 - 2 * genus
        np.testing.assert_allclose(m.volume, volume, rtol=1e-14)
        np.testing.assert_allclose(m.area, face_areas(b).sum(), rtol=1e-14)
        assert m.n_vertices == b.n_vertices  # no point is added to a polyhedron


def test_mesh_derived_polyhedron_round_trips_its_triangles():
    src = tessellate(Sphere(1.0), deflection=0.02)
    T = src.triangles
    e = np.sort(np.stack([T.ravel(), T[:, [1, 2, 0]].ravel()], 1), 1)
    E, inv = np.unique(e, axis=0, return_inverse=True)
    inv = inv.reshape(-1, 3)
    sign = np.where(E[inv, 0] == T, 1, -1)
    bld = BRepBuilder()
    bld.assemble(src.vertices, E, [[r] for r in (sign * (inv + 1)).tolist()])
    b = bld.build()
    m = tessellate(b, deflection=0.02)
    assert m.is_closed
    np.testing.assert_array_equal(np.sort(np.sort(m.triangles, axis=1), axis=0), np.sort(np.sort(T, axis=1), axis=0))
    np.testing.assert_allclose(m.volume, src.volume, rtol=1e-13)
    # A house: quads and convex pentagons (fanned, vectorised) next to each other.
    P = [[0, 0, 0], [2, 0, 0], [2, 2, 0], [0, 2, 0], [0, 0, 1], [2, 0, 1], [2, 2, 1], [0, 2, 1], [1, 0, 1.5], [1, 2, 1.5]]
    faces = [[0, 3, 2, 1], [0, 1, 5, 8, 4], [2, 3, 7, 9, 6], [1, 2, 6, 5], [3, 0, 4, 7], [5, 6, 9, 8], [7, 4, 8, 9]]
    house = polyhedron(P, faces)
    assert check(house).ok
    m2 = tessellate(house, deflection=0.1)
    assert m2.n_triangles == 16 and m2.is_closed and vertex_links_are_cycles(m2)
    np.testing.assert_allclose(m2.volume, 5.0, rtol=1e-14)


# ============================================================================ errors
def test_error_branches(monkeypatch):
    with pytest.raises(InvalidInputError, match="needs a Solid or a BRep, got int"):
        tessellate(42)
    s = Sphere(1.0)
    for bad in (0.0, -1.0, math.nan, math.inf, 1e-8):
        with pytest.raises(InvalidInputError, match="deflection must be finite and greater than the linear tolerance 1e-07"):
            tessellate(s, deflection=bad)
    for bad in (0.0, -0.1, 4.0, math.nan):
        with pytest.raises(InvalidInputError, match=r"angular_deflection must lie in \(0, π\]"):
            tessellate(s, deflection=0.1, angular_deflection=bad)
    with pytest.raises(InvalidInputError, match="default deflection 1e-3 × bounding-box diagonal = 1.73e-09 is not above"):
        tessellate(Box(1e-6, 1e-6, 1e-6))
    with pytest.raises(InvalidInputError, match="is not above the linear tolerance 0.1"):
        tessellate(Box(1, 1, 1), tol=Tolerance(linear=0.1))
    # A curved face side without p-curve.
    b = Cylinder(1.0, 1.0).brep
    pc = b.edge_pcurve.copy()
    e = int(np.flatnonzero([isinstance(b.curves[c], Line) for c in b.edge_curve])[0])
    pc[e] = -1
    with pytest.raises(TopologyError, match=f"edge {e} has no p-curve in face .* CylindricalSurface"):
        tessellate(dataclasses.replace(b, edge_pcurve=pc), deflection=0.1)
    # A face whose sense contradicts its loops: they run clockwise where counter-clockwise is expected.
    cyl = Cylinder(1, 1).brep
    side = int(np.flatnonzero([isinstance(cyl.surfaces[i], CylindricalSurface) for i in cyl.face_surface])[0])
    wrong = dataclasses.replace(cyl, face_sense=np.arange(cyl.n_faces) != side)
    with pytest.raises(TopologyError, match=f"face {side}: its boundary cannot be triangulated .*contradict"):
        tessellate(wrong, deflection=0.1)
    # The final closedness check (a safety net that valid B-reps never trip): lose one triangle.
    class Lossy(tess.ConstrainedDelaunay):
        def triangles(self, **kw):
            T, idx = super().triangles(return_index=True)
            return (T[1:], idx[1:]) if kw.get("return_index") else T[1:]

    real = tess.ConstrainedDelaunay
    monkeypatch.setattr(tess, "ConstrainedDelaunay", Lossy)
    with pytest.raises(TopologyError, match=r"tessellation is not closed: \d+ directed edge\(s\) without a twin"):
        tessellate(block_with_hole(), deflection=0.1)  # top and bottom (faces with a hole) take the CDT
    monkeypatch.setattr(tess, "ConstrainedDelaunay", real)
    # A hole crossing the outer boundary of its face.
    crossing = block_with_hole(r=1.2, check_it=False)
    with pytest.raises(TopologyError, match="face 0: its boundary cannot be triangulated in parameter space: .*cross"):
        tessellate(crossing, deflection=0.1)
    # Refinement and bisection budgets (faces on NURBS surfaces take the grid + refinement path; a grid
    # 16 times too coarse for its deflection needs refinement).
    monkeypatch.setattr(tess, "MAX_REFINEMENTS", 0)
    monkeypatch.setattr(tess, "_GRID_MARGIN", 16.0)
    with pytest.raises(ConvergenceError, match="face 0: triangles still deviate more than deflection 0.01 .* 0 refinements"):
        tessellate(nurbs_sided(Sphere(1.0).brep), deflection=0.01)
    monkeypatch.setattr(tess, "_MAX_EDGE_ROUNDS", 0)
    with pytest.raises(ConvergenceError, match=r"edge 0: discretisation did not reach deflection 0.01 / angle 0.5 in 0 bisection"):
        tessellate(nurbs_sided(Cylinder(1.0, 1.0).brep), deflection=0.01)


# ============================================================================ TriangleMesh
TET_V = [[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]]
TET_T = [[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]]


def test_triangle_mesh_measures_and_closedness():
    tet = TriangleMesh(np.array(TET_V) + 5.0, TET_T, face_ids=[0, 1, 2, 3])
    np.testing.assert_allclose(tet.volume, 1 / 6, rtol=1e-13)  # translation-invariant
    np.testing.assert_allclose(tet.area, 1.5 + math.sqrt(3) / 2, rtol=1e-15)
    assert tet.is_closed and tet.boundary_edges().shape == (0, 2)
    assert tet.euler_characteristic == 2 and tet.edges_unique().shape == (6, 2)
    np.testing.assert_array_equal(tet.bounding_box(), [[5, 5, 5], [6, 6, 6]])
    assert repr(tet) == "TriangleMesh(vertices=4, triangles=4)"
    for arr in (tet.vertices, tet.triangles, tet.face_ids, tet.triangle_normals):
        assert not arr.flags.writeable
    inside_out = TriangleMesh(TET_V, np.array(TET_T)[:, ::-1])
    np.testing.assert_allclose(inside_out.volume, -1 / 6, rtol=1e-13)
    assert inside_out.is_closed
    opened = TriangleMesh(TET_V, TET_T[1:])
    assert not opened.is_closed
    assert sorted(map(tuple, opened.boundary_edges().tolist())) == [(0, 1), (1, 2), (2, 0)]
    flipped_one = TriangleMesh(TET_V, [TET_T[0][::-1]] + TET_T[1:])
    assert not flipped_one.is_closed  # every edge used twice, but one triangle disagrees
    degenerate = TriangleMesh(TET_V, TET_T + [[0, 0, 1], [0, 1, 0]])
    assert not degenerate.is_closed
    empty = TriangleMesh(np.zeros((0, 3)), np.zeros((0, 3), int))
    assert not empty.is_closed and empty.volume == 0.0 and empty.area == 0.0
    np.testing.assert_array_equal(empty.bounding_box(), np.zeros((2, 3)))


@pytest.mark.parametrize(
    "vertices, triangles, face_ids, match",
    [
        (np.zeros((4, 2)), TET_T, None, r"vertices: expected shape \(n, 3\), got \(4, 2\)"),
        (TET_V, np.array(TET_T, float), None, "integer array of shape"),
        (TET_V, [[0, 1]], None, "integer array of shape"),
        ([[0, 0, np.nan]] + TET_V[1:], TET_T, None, "NaN or inf"),
        (TET_V, [[0, 1, 4]], None, r"indices must lie in \[0, 4\), got \[0, 4\]"),
        (TET_V, TET_T, [0, 1], r"face_ids: expected 4 integers, got shape \(2,\)"),
        (TET_V, TET_T, [0.5, 1, 2, 3], "face_ids: expected 4 integers"),
    ],
)
def test_triangle_mesh_rejects_bad_arrays(vertices, triangles, face_ids, match):
    with pytest.raises(InvalidInputError, match=match):
        TriangleMesh(vertices, triangles, face_ids)


def test_boundary_points_met_twice_merge_or_raise():
    # A loop touching itself at a vertex lists it twice: one triangulation point, both segments kept.
    uv = np.array([[0, 0], [1, 0], [1, 1], [0, 0], [-1, 0], [-1, -1]], dtype=float)
    ids = np.array([7, 8, 9, 7, 10, 11])
    seg = np.stack([np.arange(6), (np.arange(6) + 1) % 6], axis=1)
    uv2, ids2, seg2 = tess._merge_touching(0, uv, ids, seg)
    assert uv2.shape == (5, 2) and ids2.tolist() == [7, 8, 9, 10, 11]
    assert seg2.tolist() == [[0, 1], [1, 2], [2, 0], [0, 3], [3, 4], [4, 0]]
    with pytest.raises(TopologyError, match=r"face 3: mesh vertices 7 and 12 sit at the same parameters \[0.0, 0.0\]"):
        tess._merge_touching(3, uv, np.array([7, 8, 9, 12, 10, 11]), seg)


# ============================================================================ C0 knots inside an edge
def kinked_prism(degree_corner: bool = True):
    """A prism on a profile whose spline has a corner inside it: degree 2, knot 0.5 of multiplicity 2 at (1, 1),
    where the tangent turns by 45° (more than the angular deflections used), closed by a line."""
    from coons.topology.profile import Profile, Segment
    from coons.topology.sweep import extrude

    P = [[0, 0], [1, 0], [1, 1], [0, 2], [-1, 1]]
    spline = NurbsCurve(np.array(P, float), [0, 0, 0, 0.5, 0.5, 1, 1, 1], 2)
    return extrude(Profile([Segment.spline(spline), Segment.line([-1, 1], [0, 0])]), 1.0), spline


@pytest.mark.parametrize("d, a", [(1e-2, 0.5), (1e-3, 0.1)])
def test_c0_knot_inside_an_edge_is_a_sample_and_the_angle_applies_within_pieces(d, a):
    s, spline = kinked_prism()
    b = s.brep
    kinked = [e for e in range(b.n_edges) if isinstance(b.curves[b.edge_curve[e]], NurbsCurve)]
    assert len(kinked) == 2  # bottom and top copies of the spline
    jump = math.radians(45.0)
    for e in kinked:
        t = edge_parameters(b, e, d, a)
        assert 0.5 in t.tolist()  # the corner is a sample
        P = b.curves[b.edge_curve[e]].evaluate(t)
        chords = np.diff(P, axis=0)
        length = np.linalg.norm(chords, axis=1)
        cos = np.einsum("ij,ij->i", chords[:-1], chords[1:]) / (length[:-1] * length[1:])
        turn = np.arccos(np.clip(cos, -1, 1))
        at_corner = np.flatnonzero(t[1:-1] == 0.5)
        smooth = np.ones(turn.size, dtype=bool)
        smooth[at_corner] = False
        assert turn[smooth].max() <= a  # the angular criterion within the smooth pieces
        assert jump - 1e-9 < turn[at_corner].max() <= jump + a  # the corner itself, plus at most one step
        tm = 0.5 * (t[:-1] + t[1:])
        sagitta = np.linalg.norm(b.curves[b.edge_curve[e]].evaluate(tm) - 0.5 * (P[:-1] + P[1:]), axis=1)
        assert sagitta.max() <= d
    m = tessellate(s, deflection=d, angular_deflection=a)
    assert m.is_closed and vertex_links_are_cycles(m) and m.euler_characteristic == 2
    for corner in ([1.0, 1.0, 0.0], [1.0, 1.0, 1.0]):  # the corner is a mesh vertex, bottom and top
        assert np.min(np.linalg.norm(m.vertices - corner, axis=1)) == 0.0
    assert abs(m.volume - s.volume) <= d * s.area
    # The side face over the spline: sampled triangle points within d of the exact (ruled) surface, i.e. their
    # (x, y) within d of the spline (distance to a dense polyline of it, chord error ~1e-11).
    from scipy.spatial import cKDTree

    side = [f for f in range(b.n_faces) if b.surfaces[b.face_surface[f]].__class__.__name__ == "NurbsSurface"]
    dense = spline.evaluate(np.linspace(0.0, 1.0, 400001))
    X = np.einsum("sw,twj->tsj", barycentric(), m.vertices[m.triangles[np.isin(m.face_ids, side)]])[..., :2]
    dist, _ = cKDTree(dense).query(X.reshape(-1, 2))
    assert dist.max() <= d * (1 + 1e-3) + 1e-5  # + half the polyline's sample spacing


# ============================================================================ strips on revolved faces
def revolved_surface(kind: str, size: tuple[float, float]):
    from coons.kernel.analytic import ConicalSurface, SphericalSurface, ToroidalSurface

    a, ratio = size
    o, z, x = [0.0, 0.0, 0.0], [0.0, 0.0, 1.0], [1.0, 0.0, 0.0]
    return {
        "cylinder": lambda: CylindricalSurface(o, z, x, a),
        "cone": lambda: ConicalSurface(o, z, x, a, -0.2 - 1.2 * ratio),
        "sphere": lambda: SphericalSurface(o, z, x, a),
        "torus": lambda: ToroidalSurface(o, z, x, a, a * ratio),
    }[kind]()


@given(
    kind=st.sampled_from(["cylinder", "cone", "sphere", "torus"]),
    size=st.tuples(st.floats(0.1, 10.0), st.floats(0.05, 0.95)),
    rows=st.tuples(st.floats(0.0, 1.0), st.floats(0.005, 1.0)),
    relative=st.floats(1e-4, 0.3),
    angular=st.floats(0.05, PI),
)
@example(kind="sphere", size=(1.0, 0.5), rows=(0.999, 0.3), relative=1e-3, angular=0.5)  # a strip at the pole
@example(kind="torus", size=(1.0, 0.9), rows=(0.5, 0.05), relative=1e-2, angular=PI)  # the top of a fat torus
def test_strip_bound_is_rigorous(kind, size, rows, relative, angular):
    """Triangles with corners on two rows and a u-span up to the bound stay within d of the surface."""
    S = revolved_surface(kind, size)
    d = relative * size[0]
    start, length = rows
    if kind == "sphere":  # latitudes; the upper row may be the pole
        va = -0.5 * PI + PI * start
        vb = min(va + length * PI / 4, 0.5 * PI)
    elif kind == "torus":
        va = 2 * PI * start
        vb = va + length * PI / 4
    elif kind == "cone":  # between the base circle (v = 0) and the apex (a row may be the apex, not both)
        apex = -S.radius / math.sin(S.semi_angle)
        va = apex * start * (1 - length)
        vb = va + length * (apex - va)
    else:
        va, vb = -size[0] * start, size[0] * length
    kind_m, rho_t, z_t, r = tess._meridian(S)
    rho, z = tess._meridian_points(S, np.array([va, vb]))
    one = np.ones(1)
    s = float(tess._strip_spans(np.array([kind_m == "circle"]), rho_t * one, z_t * one, r * one, rho[:1], z[:1],
                                rho[1:], z[1:], d, angular)[0])
    if s == 0.0:  # the meridian chord alone deviates more than d: the rows are too far apart to be a strip
        chord_mid = S.evaluate(0.0, 0.5 * (va + vb))
        assert abs(float(S.implicit(0.5 * (S.evaluate(0.0, va) + S.evaluate(0.0, vb))))) > d * (1 - 1e-9)
        assert np.all(np.isfinite(chord_mid))
        return
    assert 0 < s <= 0.5 * PI
    # Worst-case shapes: a row segment of the full span with the other row's corner anywhere over it.
    W = barycentric(8)
    for lower, upper in ((va, vb), (vb, va)):
        for frac in (0.0, 0.25, 0.5, 0.75, 1.0):
            u = np.array([0.0, s, frac * s])
            v = np.array([lower, lower, upper])
            X = np.einsum("sw,wj->sj", W, S.evaluate(u, v))
            assert np.abs(S.implicit(X)).max() <= d * (1 + 1e-9) + 1e-14 * size[0]


@st.composite
def strip_rows(draw):
    """Rows of 1-3 faces: each face 2-5 rows, each row a point (a pole, first or last row only) or keys 0 < ... < 1."""
    faces = []
    for _ in range(draw(st.integers(1, 3))):
        n_rows = draw(st.integers(2, 5))
        rows = []
        for j in range(n_rows):
            pole = j in (0, n_rows - 1) and n_rows > 2 and draw(st.booleans())
            if pole:
                rows.append(np.array([0.5]))
                continue
            k = draw(st.integers(1, 9))
            inner = np.sort(draw(st.lists(st.floats(0.01, 0.99), min_size=k - 1, max_size=k - 1, unique=True)))
            rows.append(np.concatenate([[0.0], inner, [1.0]]))
        faces.append(rows)
    return faces


@given(strip_rows())
def test_zip_strips_tiles_each_strip_exactly(faces):
    keys = [r for rows in faces for r in rows]
    row_len = np.array([r.size for r in keys])
    ids = np.arange(row_len.sum())
    per_face = np.array([len(rows) for rows in faces])
    first = np.zeros(row_len.size, bool)
    first[np.cumsum(per_face) - per_face] = True
    last = np.zeros(row_len.size, bool)
    last[np.cumsum(per_face) - 1] = True
    T, row = tess._zip_strips(row_len, ids, np.concatenate(keys), first, last)
    # Points in the (u, v) plane: row j of its face at v = j; a pole at u = 1/2.
    v = np.concatenate([np.full(r.size, float(j)) for rows in faces for j, r in enumerate(rows)])
    uv = np.stack([np.concatenate(keys), v], axis=1)
    e1, e2 = uv[T[:, 1]] - uv[T[:, 0]], uv[T[:, 2]] - uv[T[:, 0]]
    A = 0.5 * (e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0])
    assert np.all(A > 0)  # counter-clockwise, none flat
    gaps = row_len - 1
    expected = sum(int(gaps[r] + gaps[r + 1]) for r in range(row_len.size) if not last[r])
    assert T.shape[0] == expected
    # Each strip is covered once: its triangles' area is the strip's (1, or 1/2 next to a pole).
    for r in np.flatnonzero(~last):
        area = 1.0 if min(row_len[r], row_len[r + 1]) > 1 else 0.5
        np.testing.assert_allclose(A[row == r].sum(), area, rtol=1e-12)
        # Every triangle spans at most the larger segment of its two rows in u (the merge bound).
        u = np.where(np.repeat(row_len, row_len) > 1, uv[:, 0], np.nan)[T[row == r]]  # a pole has no u
        span = np.nanmax(u, axis=1) - np.nanmin(u, axis=1)
        widest = max(np.diff(keys[r]).max(initial=0.0), np.diff(keys[r + 1]).max(initial=0.0))
        assert span.max() <= widest * (1 + 1e-12)
    # Directed edges: interior segments once each way, the outline of each face once.
    d = set(zip(T.ravel().tolist(), T[:, [1, 2, 0]].ravel().tolist()))
    assert len(d) == 3 * T.shape[0]


def three_face_sphere(R: float = 1.3, split: float = 0.3) -> BRep:
    """A sphere whose western hemisphere is cut along the parallel at latitude ``split``: the eastern face's
    meridians are two edges each, and its rows differ from those its neighbours ask for."""
    from coons.kernel.analytic import SphericalSurface

    S = SphericalSurface([0, 0, 0], [0, 0, 1], [1, 0, 0], R)
    south, north = S.evaluate(0.0, -0.5 * PI), S.evaluate(0.0, 0.5 * PI)
    p0, ppi = S.evaluate(0.0, split), S.evaluate(PI, split)
    P = np.array([south, north, p0, ppi])
    E = [(0, 2), (2, 1), (0, 3), (3, 1), (2, 3)]  # m0s, m0n, mpis, mpin, parallel
    loops = [[[1, 2, -4, -3]], [[5, 4, -2]], [[3, -5, -1]]]  # east, north-west, south-west
    bld = BRepBuilder()
    bld.assemble(P, np.array(E), loops, face_surfaces=[S, S, S], face_senses=[True, True, True])
    m0, mpi = Circle([0, 0, 0], [0, -1, 0], [1, 0, 0], R), Circle([0, 0, 0], [0, 1, 0], [-1, 0, 0], R)
    parallel = Circle([0, 0, R * math.sin(split)], [0, 0, 1], [1, 0, 0], R * math.cos(split))
    for e, c, rng in ((0, m0, (-0.5 * PI, split)), (1, m0, (split, 0.5 * PI)), (2, mpi, (-0.5 * PI, split)),
                      (3, mpi, (split, 0.5 * PI)), (4, parallel, (0.0, PI))):
        bld.set_edge_curve(e, c, rng)
    up = lambda u: Line2D([u, 0.0], [0.0, 1.0])  # noqa: E731
    pcurves = {0: {0: up(2 * PI), 2: up(0.0)}, 1: {0: up(2 * PI), 1: up(0.0)}, 2: {0: up(PI), 2: up(PI)},
               3: {0: up(PI), 1: up(PI)}, 4: {1: Line2D([0.0, split], [1.0, 0.0]), 2: Line2D([0.0, split], [1.0, 0.0])}}
    for e, by_face in pcurves.items():
        for side in (0, 1):
            bld.set_pcurve(2 * e + side, by_face[bld.lface[bld.cloop[2 * e + side]]])
    return bld.build()


@pytest.mark.parametrize("d", [1e-1, 1e-2, 1e-3])
def test_revolved_faces_with_rows_asked_by_neighbours_and_split_sides(d):
    b = three_face_sphere()
    assert check(b).ok
    ctx = tess._Builder(b, d, 0.5, Tolerance())
    ctx.plan_revolved_faces()
    assert sorted(ctx.revolved) == [0, 1, 2]
    m = tessellate(b, deflection=d)
    assert m.is_closed and vertex_links_are_cycles(m) and m.euler_characteristic == 2
    worst, vert, flipped = surface_deviation(b, m)
    assert worst <= d and vert <= ON_SURFACE and flipped == 0
    np.testing.assert_allclose(m.volume, 4 / 3 * PI * 1.3**3, rtol=0, atol=d * 4 * PI * 1.3**2)
    # The split latitude is a row of the eastern face too (its meridian edges end there).
    east = m.vertices[np.unique(m.triangles[m.face_ids == 0])]
    assert np.any(np.abs(east[:, 2] - 1.3 * math.sin(0.3)) < 1e-12)


def test_primitives_take_the_strip_path_with_fewer_segments_towards_the_poles():
    for s in (Cylinder(1, 2), Cone(1, 0, 2), Cone(1, 0.4, 1.5), Sphere(1), Torus(2, 0.5), moved(Sphere(1)),
              mirrored(Torus(2, 0.5)), Solid(block_with_hole())):
        b = s.brep
        ctx = tess._Builder(b, 1e-3, 0.5, Tolerance())
        ctx.plan_revolved_faces()
        ctx.discretise_edges()
        ctx.triangulate_faces()
        curved = [f for f in range(b.n_faces) if not isinstance(b.surfaces[b.face_surface[f]], PlanarSurface)
                  and b.face_surface[f] >= 0]
        assert sorted(ctx.revolved) == curved and not set(curved) & set(ctx.faces)  # no curved face needed the CDT
    # A sphere's rows: fewer segments where the parallels are shorter (adaptive rings, not a u-v grid).
    m = tessellate(Sphere(1), deflection=1e-3)
    z = np.round(m.vertices[:, 2], 12)
    levels, count = np.unique(z, return_counts=True)
    near_pole = count[np.argmax(levels[:-1])]  # the last row below the north pole
    near_equator = count[np.argmin(np.abs(levels))]
    assert near_pole < near_equator / 4


def test_convexity_tests_agree_and_reject_stars_and_collinear_corners():
    rng = np.random.default_rng(3)
    X, Y = np.array([[1.0, 0, 0]]), np.array([[0, 1.0, 0]])
    for k in (3, 4, 7, 40):
        ang = np.sort(rng.uniform(0, 2 * PI, k))
        P = np.stack([np.cos(ang), np.sin(ang), np.zeros(k)], axis=1)[None]
        assert tess._strictly_convex(P)[0] and tess._convex_in_plane(P, X, Y, np.ones(1))[0]
        assert tess._strictly_convex(P[:, ::-1])[0]  # about its own Newell normal
        assert not tess._convex_in_plane(P[:, ::-1], X, Y, np.ones(1))[0]  # clockwise where counter-clockwise is due
        assert tess._convex_in_plane(P[:, ::-1], X, Y, -np.ones(1))[0]
    star = np.array([[math.cos(4 * PI * i / 5), math.sin(4 * PI * i / 5), 0.0] for i in range(5)])[None]
    square_with_midpoint = np.array([[0, 0, 0], [1, 0, 0], [2, 0, 0], [2, 2, 0], [0, 2, 0]], float)[None]
    dart = np.array([[0, 0, 0], [2, 0, 0], [1, 0.5, 0], [1, 2, 0]], float)[None]
    for P in (star, square_with_midpoint, dart):
        assert not tess._strictly_convex(P)[0]
        assert not tess._convex_in_plane(P, X, Y, np.ones(1))[0]


def test_edge_pairing_agrees_with_triangle_mesh_closedness():
    cases = [TET_T, [TET_T[0][::-1]] + TET_T[1:], TET_T[1:], TET_T + [[0, 0, 1], [0, 1, 0]], TET_T + TET_T]
    for T in cases:
        T = np.array(T)
        repeated, closed = tess._edge_pairing(T, 4)
        assert closed == TriangleMesh(TET_V, T).is_closed
        key = (T * 4 + T[:, [1, 2, 0]]).ravel()
        assert repeated == (np.unique(key).size < key.size) or closed
    assert tess._edge_pairing(np.zeros((0, 3), int), 4) == (False, False)


@pytest.mark.occt
def test_fewer_triangles_than_occt_at_equal_deflection_and_within_it():
    """OCCT's BRepMesh on the same primitives (OCCT placement: base / centre at the origin) meshes more triangles
    at the same deflection and angle; coons stays within the deflection (OCCT's sphere does not: ~2 d at 1e-3)."""
    from OCP.BRep import BRep_Tool
    from OCP.BRepMesh import BRepMesh_IncrementalMesh
    from OCP.BRepPrimAPI import (BRepPrimAPI_MakeCone, BRepPrimAPI_MakeCylinder, BRepPrimAPI_MakeSphere,
                                 BRepPrimAPI_MakeTorus)
    from OCP.TopAbs import TopAbs_FACE
    from OCP.TopExp import TopExp_Explorer
    from OCP.TopLoc import TopLoc_Location
    from OCP.TopoDS import TopoDS

    def occt_triangles(shape, d):
        BRepMesh_IncrementalMesh(shape, d, False, 0.5, False)
        n, ex = 0, TopExp_Explorer(shape, TopAbs_FACE)
        while ex.More():
            n += BRep_Tool.Triangulation_s(TopoDS.Face(ex.Current()), TopLoc_Location()).NbTriangles()
            ex.Next()
        return n

    pairs = [(Cylinder(1, 2), lambda: BRepPrimAPI_MakeCylinder(1, 2).Shape()),
             (Cone(1, 0, 2), lambda: BRepPrimAPI_MakeCone(1, 0, 2).Shape()),
             (Sphere(1), lambda: BRepPrimAPI_MakeSphere(1).Shape()),
             (Torus(2, 0.5), lambda: BRepPrimAPI_MakeTorus(2, 0.5).Shape())]
    for s, occt in pairs:
        for d in (1e-2, 1e-3):
            m = tessellate(s, deflection=d)
            assert m.n_triangles < occt_triangles(occt(), d)
            assert surface_deviation(s.brep, m)[0] <= d


@pytest.mark.parametrize("name", ["cylinder", "cone", "sphere", "torus"])
def test_general_path_on_analytic_faces_without_strips(name, monkeypatch):
    """Trimmed faces of revolved surfaces take the grid + Delaunay + refinement path; with the strip plan off the
    primitives go that way too and stay closed and within the deflection."""
    monkeypatch.setattr(tess._Builder, "plan_revolved_faces", lambda self: None)
    s = PRIMITIVES[name]()
    for d in (1e-1, 1e-2):
        m = tessellate(s, deflection=d)
        assert m.is_closed and vertex_links_are_cycles(m)
        worst, _, flipped = surface_deviation(s.brep, m)
        assert worst <= d and flipped == 0


def test_chord_conflicts_are_repaired(monkeypatch):
    """The two hemispheres of an octahedron-coarse sphere meshed by the general path both draw the pole-to-pole
    chord: the conflict is found in the edge sort and repaired by splitting the chord in each face."""
    monkeypatch.setattr(tess._Builder, "plan_revolved_faces", lambda self: None)
    repairs = []
    real = tess._Builder.repair_conflicts
    monkeypatch.setattr(tess._Builder, "repair_conflicts", lambda self, *a: repairs.append(1) or real(self, *a))
    s = Sphere(1.0)
    m = tessellate(s, deflection=0.5 * scale_of(s.brep), angular_deflection=PI)
    assert repairs and m.is_closed and vertex_links_are_cycles(m) and m.euler_characteristic == 2


# ============================================================================ caching
def test_meshes_are_cached_per_brep_and_arguments():
    """The same B-rep and arguments give the same (immutable) mesh object, equal to a fresh tessellation."""
    s = Cylinder(1.0, 2.0)
    m1 = tessellate(s)
    assert tessellate(s) is m1 and tessellate(s.brep) is m1
    m2 = tessellate(s, deflection=1e-2)
    assert m2 is not m1 and m2.triangles.shape[0] < m1.triangles.shape[0]
    fresh = tess._tessellate(s.brep, 1e-3 * float(np.linalg.norm(np.ptp(bounding_box(s.brep), axis=0))), 0.5,
                             Tolerance())
    np.testing.assert_array_equal(fresh.triangles, m1.triangles)
    np.testing.assert_array_equal(fresh.vertices, m1.vertices)


def test_a_boolean_result_with_a_void_reuses_the_mesh_of_its_void_nesting():
    """Sewing a shell and a void tessellates them to nest the void when its vertices lie in the boxes
    of the outer shell's faces (here the faces of a ball); the final B-rep shares that mesh (and the
    face integrals), so the next Boolean on the result does not tessellate it again.  A void in no
    face box (a ball in a box) is nested without a mesh."""
    r = Box(10, 10, 10) - Sphere(2.0)
    assert r.brep.n_shells == 2
    assert not tess._MESHES.get(r.brep)
    outer, inner = Sphere(10.0), Sphere(2.0).translate((0.5, 0.3, 0.2))
    r = outer - inner  # the small ball becomes a void
    assert r.brep.n_shells == 2
    cached = tess._MESHES.get(r.brep)
    assert cached, "the void nesting's mesh was not shared with the result"
    mesh = tessellate(r)
    assert any(mesh is m for m in cached.values())
    key = next(iter(k for k, m in cached.items() if m is mesh))
    fresh = tess._tessellate(r.brep, *key)
    np.testing.assert_array_equal(fresh.triangles, mesh.triangles)
    assert abs(mesh.volume - r.volume) <= key[0] * r.area  # within deflection × area


def test_sharing_needs_the_same_geometry():
    from coons.topology.mass import share_mass_caches

    a, b = Box(1, 1, 1), Box(1, 1, 2)
    with pytest.raises(InvalidInputError, match="same vertices, faces and geometry"):
        tess.share_tessellations(a.brep, b.brep)
    with pytest.raises(InvalidInputError, match="same vertices, faces and geometry"):
        share_mass_caches(a.brep, b.brep)


def test_cached_bounding_box_cannot_be_corrupted_by_the_caller():
    s = Sphere(1.0)
    box = bounding_box(s.brep)
    box[:] = 0.0
    np.testing.assert_allclose(bounding_box(s.brep), [[-1, -1, -1], [1, 1, 1]], atol=1e-12)


# ============================================================================ curves with many knot spans
def many_span_prism(spans: int = 200):
    """A prism over a cubic B-spline through ``spans + 3`` points of a half circle of radius 1 (a curve
    with many knot spans, as a fitted intersection curve), closed by a straight segment."""
    from coons.topology.profile import Profile, Segment
    from coons.topology.sweep import extrude

    theta = np.linspace(0.0, PI, spans + 3)
    knots = np.concatenate([[0.0] * 3, np.linspace(0.0, 1.0, spans + 1), [1.0] * 3])
    spline = NurbsCurve(np.stack([np.cos(theta), np.sin(theta)], axis=1), knots, 3)
    return extrude(Profile([Segment.spline(spline), Segment.line([-1, 0], [1, 0])]), 1.0), spline


@pytest.mark.parametrize("d, a", [(1e-2, 0.5), (1e-3, 0.5), (1e-3, 0.05)])
def test_many_knot_spans_are_decimated_within_the_deflection_and_angle(d, a):
    s, spline = many_span_prism()
    b = s.brep
    edges = [e for e in range(b.n_edges) if isinstance(b.curves[b.edge_curve[e]], NurbsCurve)]
    assert len(edges) == 2
    for e in edges:
        c = b.curves[b.edge_curve[e]]
        t = edge_parameters(b, e, d, a)
        np.testing.assert_array_equal(t[[0, -1]], b.edge_range[e])
        P = c.evaluate(t)
        # Far fewer than the (degree + 1) per span the bisection starts from: about what a circle of
        # radius 1 needs (equal steps of min(θ, 2 acos(1 - d))), at most twice that (halving).
        need = math.ceil(PI / min(a, 2 * math.acos(1 - d)))
        assert t.size - 1 <= 2 * need
        # Deflection: a dense sampling of the exact curve lies within d of the polyline, and
        # the midpoint test of the bisection holds for every chord.
        tm = 0.5 * (t[:-1] + t[1:])
        assert np.linalg.norm(c.evaluate(tm) - 0.5 * (P[:-1] + P[1:]), axis=1).max() <= d
        dense = np.linspace(t[0], t[-1], 20001)
        X = c.evaluate(dense)
        k = np.clip(np.searchsorted(t, dense, side="right") - 1, 0, t.size - 2)
        A, B = P[k], P[k + 1]
        u = np.clip(np.einsum("ij,ij->i", X - A, B - A) / np.einsum("ij,ij->i", B - A, B - A), 0, 1)
        assert np.linalg.norm(X - A - u[:, None] * (B - A), axis=1).max() <= d * (1 + 1e-3)
        # Angle: consecutive chords turn by at most θ.
        ch = np.diff(P, axis=0)
        cos = np.einsum("ij,ij->i", ch[:-1], ch[1:]) / np.linalg.norm(ch[:-1], axis=1) / np.linalg.norm(ch[1:], axis=1)
        assert np.arccos(np.clip(cos, -1, 1)).max() <= a
    m = tessellate(s, deflection=d, angular_deflection=a)
    assert m.is_closed and vertex_links_are_cycles(m) and m.euler_characteristic == 2
    assert abs(m.volume - s.volume) <= d * s.area
