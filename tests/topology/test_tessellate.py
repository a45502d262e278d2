"""Watertight tessellation: closed and vertex-manifold meshes of every primitive (moved, mirrored,
inside out, NURBS-faced, with holes, polyhedral), the deflection bound measured against the exact
surfaces, volumes converging to the exact ones, the closed-form edge discretisation, and every
error branch.  trimesh / manifold3d acceptance is in tests/io/test_mesh_interop.py."""

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
    points = np.asarray(points, dtype=float)
    edge_of: dict[tuple[int, int], int] = {}
    edges: list[tuple[int, int]] = []
    loops = []
    for face in faces:
        face = face if isinstance(face[0], list) else [face]
        refs_f = []
        for loop in face:
            refs = []
            for a, b in zip(loop, loop[1:] + loop[:1]):
                key = (min(a, b), max(a, b))
                if key not in edge_of:
                    edge_of[key] = len(edges)
                    edges.append((a, b))
                e = edge_of[key]
                refs.append(e + 1 if edges[e] == (a, b) else -(e + 1))
            refs_f.append(refs)
        loops.append(refs_f)
    bld = BRepBuilder()
    bld.assemble(points, edges, loops)
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
        tessellate(Cylinder(1, 1), deflection=0.1)
    monkeypatch.setattr(tess, "ConstrainedDelaunay", real)
    # A hole crossing the outer boundary of its face.
    crossing = block_with_hole(r=1.2, check_it=False)
    with pytest.raises(TopologyError, match="face 0: its boundary cannot be triangulated in parameter space: .*cross"):
        tessellate(crossing, deflection=0.1)
    # Refinement and bisection budgets.
    monkeypatch.setattr(tess, "MAX_REFINEMENTS", 0)
    with pytest.raises(ConvergenceError, match="face 0: triangles still deviate more than deflection 0.01 .* 0 refinements"):
        tessellate(Sphere(1.0), deflection=0.01)
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
