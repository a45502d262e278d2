"""Mass properties and bounding boxes: closed forms on primitives (moved, inside out, with voids,
polyhedral, NURBS-faced), OCCT's GProp and trimesh as references, every error branch."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from coons.errors import ConvergenceError, InvalidInputError, TopologyError
from coons.kernel import conics
from coons.kernel.analytic import Circle, CylindricalSurface, Ellipse, PlanarSurface
from coons.kernel.curve import NurbsCurve
from coons.kernel.pcurve import Line2D
from coons.kernel.surface import NurbsSurface
from coons.tolerance import Tolerance
from coons.topology import mass
from coons.topology.brep import BRep
from coons.topology.builder import BRepBuilder
from coons.topology.check import check
from coons.topology.mass import MassProperties, bounding_box, face_areas, mass_properties, shell_volumes
from coons.topology.primitives import Box, Cone, Cylinder, Sphere, Torus

PI = math.pi
#: Closed forms and OCCT agree with the boundary integrals to round-off; 1e-10 is the target.
RTOL = 1e-10


# ============================================================================ helpers
def rotation(axis, angle: float) -> np.ndarray:
    a = np.asarray(axis, dtype=float)
    a = a / np.linalg.norm(a)
    K = np.array([[0, -a[2], a[1]], [a[2], 0, -a[0]], [-a[1], a[0], 0]])
    return np.eye(3) + math.sin(angle) * K + (1 - math.cos(angle)) * K @ K


def rigid(R: np.ndarray, t) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3] = R
    T[:3, 3] = t
    return T


def transformed(b: BRep, T: np.ndarray) -> BRep:
    """``b`` moved by a rigid motion ``T``: points, curves and surfaces move, p-curves stay (the
    analytic parametrisations are invariant under rigid motions)."""
    P = b.vertex_point @ T[:3, :3].T + T[:3, 3]
    return dataclasses.replace(
        b,
        vertex_point=P,
        curves=tuple(c.transformed(T) for c in b.curves),
        surfaces=tuple(s.transformed(T) for s in b.surfaces),
    )


def reversed_brep(b: BRep) -> BRep:
    """Every shell turned inside out: each loop walked backwards, each face's sense flipped.

    Coedge ``c`` of the result is coedge ``c ^ 1`` of ``b`` walked backwards, so
    ``next'(c) = prev(c ^ 1) ^ 1``; each side's p-curve moves with its face.
    """
    nxt, prv = b.coedge_next, b.coedge_prev
    c = np.arange(2 * b.n_edges)
    new_next = prv[c ^ 1] ^ 1
    new_prev = nxt[c ^ 1] ^ 1
    wing = np.stack([new_prev[0::2], new_next[0::2], new_prev[1::2], new_next[1::2]], axis=1)
    return dataclasses.replace(
        b,
        edge_loop=b.edge_loop[:, ::-1],
        edge_wing=wing,
        edge_pcurve=b.edge_pcurve[:, ::-1],
        loop_coedge=np.where(b.loop_coedge >= 0, b.loop_coedge ^ 1, -1),
        face_sense=~b.face_sense,
    )


def _shift(a: np.ndarray, k: int) -> np.ndarray:
    return np.where(a >= 0, a + k, a)


def nested(outer: BRep, void: BRep) -> BRep:
    """One solid: the shells of ``outer`` then those of ``void`` as voids of its first solid."""
    V, E, L, F, S = outer.n_vertices, outer.n_edges, outer.n_loops, outer.n_faces, outer.n_shells
    nc, ns, npc = len(outer.curves), len(outer.surfaces), len(outer.pcurves)
    cat = np.concatenate
    return BRep(
        vertex_point=cat([outer.vertex_point, void.vertex_point]),
        vertex_tol=cat([outer.vertex_tol, void.vertex_tol]),
        vertex_coedge=cat([outer.vertex_coedge, _shift(void.vertex_coedge, 2 * E)]),
        edge_vertex=cat([outer.edge_vertex, void.edge_vertex + V]),
        edge_loop=cat([outer.edge_loop, void.edge_loop + L]),
        edge_wing=cat([outer.edge_wing, void.edge_wing + 2 * E]),
        edge_curve=cat([outer.edge_curve, _shift(void.edge_curve, nc)]),
        edge_range=cat([outer.edge_range, void.edge_range]),
        edge_pcurve=cat([outer.edge_pcurve, _shift(void.edge_pcurve, npc)]),
        edge_tol=cat([outer.edge_tol, void.edge_tol]),
        loop_face=cat([outer.loop_face, void.loop_face + F]),
        loop_coedge=cat([outer.loop_coedge, _shift(void.loop_coedge, 2 * E)]),
        loop_vertex=cat([outer.loop_vertex, _shift(void.loop_vertex, V)]),
        face_surface=cat([outer.face_surface, _shift(void.face_surface, ns)]),
        face_sense=cat([outer.face_sense, void.face_sense]),
        face_shell=cat([outer.face_shell, void.face_shell + S]),
        face_loop_ptr=cat([outer.face_loop_ptr[:-1], void.face_loop_ptr + outer.face_loops.size]),
        face_loops=cat([outer.face_loops, void.face_loops + L]),
        shell_solid=cat([outer.shell_solid, np.zeros(void.n_shells, np.int64)]),
        shell_face_ptr=cat([outer.shell_face_ptr[:-1], void.shell_face_ptr + outer.shell_faces.size]),
        shell_faces=cat([outer.shell_faces, void.shell_faces + F]),
        solid_shell_ptr=np.array([0, S + void.n_shells]),
        solid_shells=np.arange(S + void.n_shells),
        surfaces=outer.surfaces + void.surfaces,
        curves=outer.curves + void.curves,
        pcurves=outer.pcurves + void.pcurves,
    )


def polyhedron(points, face_vertex_loops, *, planes: bool = False, flip=()) -> BRep:
    """A closed polyhedron from outward (counter-clockwise) vertex loops, via ``assemble``.

    A face is a vertex loop, or a list of loops (outer first, holes clockwise).

    ``planes``: explicit :class:`PlanarSurface` faces with projected ``Line2D`` p-curves instead
    of implicit planes; faces listed in ``flip`` get the reversed plane and ``sense = False``.
    """
    points = np.asarray(points, dtype=float)
    faces = [f if isinstance(f[0], list) else [f] for f in face_vertex_loops]
    bld = BRepBuilder()
    surfaces, senses = None, None
    if planes:
        surfaces, senses = [], []
        for k, face in enumerate(faces):
            P = points[face[0]]
            n = np.cross(P - P[0], np.roll(P, -1, axis=0) - P[0]).sum(axis=0)
            d = P[1] - P[0]
            s = k not in flip
            surfaces.append(PlanarSurface(P[0], n if s else -n, d))
            senses.append(s)
    bld.assemble_polygons(points, faces, face_surfaces=surfaces, face_senses=senses)
    if planes:
        # A fresh builder: its vertex ids are the indices into ``points``.
        for e, (a, b) in enumerate(bld.ev):
            for side in (0, 1):
                c = 2 * e + side
                S = surfaces[bld.lface[bld.cloop[c]]]
                ua, ub = S.closest_parameters(points[[a, b]])
                bld.set_pcurve(c, Line2D(ua, ub - ua))
    return bld.build()


CUBE = [[0, 3, 2, 1], [4, 5, 6, 7], [0, 1, 5, 4], [1, 2, 6, 5], [2, 3, 7, 6], [3, 0, 4, 7]]


def cuboid_points(a: float, b: float, c: float, origin=(0.0, 0.0, 0.0)) -> np.ndarray:
    x = np.array([[0, 0, 0], [a, 0, 0], [a, b, 0], [0, b, 0], [0, 0, c], [a, 0, c], [a, b, c], [0, b, c]], float)
    return x + np.asarray(origin, dtype=float)


def nurbs_sided(b: BRep, *, nurbs_pcurves: bool = False) -> BRep:
    """A cylinder or sphere primitive whose curved faces are exact rational NURBS.

    Each curved face gets ``to_nurbs`` of its surface over the face's ``u`` range (NURBS
    parameter == angle at the ends), its edges' circles become iso-curves of those surfaces (the
    NURBS parameter of the p-curves ``Line2D``), and the planar faces lose their p-curves
    (projected from the 3-D edges) or, with ``nurbs_pcurves``, get the exact 2-D NURBS
    projections of the iso-curves.
    """
    surfaces = list(b.surfaces)
    face_surface = b.face_surface.copy()
    new = {}
    for f in range(b.n_faces):
        S = b.surfaces[b.face_surface[f]]
        if isinstance(S, PlanarSurface):
            continue
        e0 = [int(c) >> 1 for c in b.loop_coedges(int(b.face_loop_ids(f)[0]))]
        us = []
        for e in e0:
            side = int(np.flatnonzero(b.edge_face[e] == f)[0])
            pc = b.pcurves[b.edge_pcurve[e, side]]
            us += list(pc.evaluate(np.asarray(b.edge_range[e]))[:, 0])
        u_range = (min(us), max(us))
        if isinstance(S, CylindricalSurface):
            N = conics.nurbs_cylinder(S.origin, S.axis, S.radius, (0.0, 100.0), x_dir=S.x_dir, u_range=u_range)
        else:
            N = conics.nurbs_sphere(S.center, S.axis, S.radius, x_dir=S.x_dir, u_range=u_range)
        new[f] = len(surfaces)
        face_surface[f] = len(surfaces)
        surfaces.append(N)
    curves = list(b.curves)
    pcurves = list(b.pcurves)
    edge_curve = b.edge_curve.copy()
    edge_pcurve = b.edge_pcurve.copy()
    for e in range(b.n_edges):
        if not isinstance(b.curves[b.edge_curve[e]], Circle):
            continue
        side = int(np.flatnonzero(np.isin(b.edge_face[e], list(new)))[0])
        f = int(b.edge_face[e, side])
        pc = b.pcurves[b.edge_pcurve[e, side]]
        N = surfaces[new[f]]
        if pc.direction[1] == 0.0:  # u = t: a circle at constant v
            iso = N.iso_curve("v", float(pc.origin[1]))
        else:  # v = t: a meridian at constant u
            iso = N.iso_curve("u", float(pc.origin[0]))
        edge_curve[e] = len(curves)
        curves.append(iso)
        other = 1 - side
        if isinstance(b.surfaces[b.face_surface[b.edge_face[e, other]]], PlanarSurface):
            if nurbs_pcurves:
                plane = b.surfaces[b.face_surface[b.edge_face[e, other]]]
                uv = plane.closest_parameters(iso.control_points)
                edge_pcurve[e, other] = len(pcurves)
                pcurves.append(NurbsCurve(uv, iso.knots, iso.degree, iso.weights))
            else:
                edge_pcurve[e, other] = -1
    return dataclasses.replace(b, surfaces=tuple(surfaces), face_surface=face_surface, curves=tuple(curves),
                               edge_curve=edge_curve, pcurves=tuple(pcurves), edge_pcurve=edge_pcurve)


def assert_valid(b: BRep) -> None:
    report = check(b)
    assert report.ok, report.summary()


def assert_mass(mp: MassProperties, V, A, c, I, rtol=RTOL) -> None:
    np.testing.assert_allclose(mp.volume, V, rtol=rtol)
    if A is not None:
        np.testing.assert_allclose(mp.area, A, rtol=rtol)
    np.testing.assert_allclose(mp.centroid, c, rtol=0, atol=rtol * (1 + np.abs(c).max()))
    np.testing.assert_allclose(mp.inertia, I, rtol=0, atol=rtol * np.abs(I).max())


# ============================================================================ closed forms
sizes = st.floats(0.1, 10.0)


@settings(max_examples=25)
@given(sizes, sizes, sizes)
def test_box_closed_forms(a, b, c):
    mp = Box(a, b, c, align=None).brep
    m = a * b * c
    I = m / 12 * np.diag([b * b + c * c, a * a + c * c, a * a + b * b])
    assert_mass(mass_properties(mp), m, 2 * (a * b + b * c + c * a), [a / 2, b / 2, c / 2], I)
    np.testing.assert_allclose(bounding_box(mp), [[0, 0, 0], [a, b, c]], rtol=0, atol=1e-15 * max(a, b, c))


@settings(max_examples=25)
@given(sizes, sizes)
def test_cylinder_closed_forms(r, h):
    b = Cylinder(r, h, align=None).brep
    m = PI * r * r * h
    I = np.diag([m * (3 * r * r + h * h) / 12] * 2 + [m * r * r / 2])
    assert_mass(mass_properties(b), m, 2 * PI * r * h + 2 * PI * r * r, [0, 0, h / 2], I)
    areas = np.sort(face_areas(b))
    np.testing.assert_allclose(areas, np.sort([PI * r * h, PI * r * h, PI * r * r, PI * r * r]), rtol=RTOL)
    np.testing.assert_allclose(bounding_box(b), [[-r, -r, 0], [r, r, h]], rtol=0, atol=1e-14 * max(r, h))


def frustum_reference(r0: float, r1: float, h: float):
    """Volume, area, centroid height and (I_xx, I_zz) about the centroid by exact polynomial
    integration over slices ``z ∈ [0, h]`` of radius ``ρ(z) = r0 + (r1 - r0) z / h``."""
    P = np.polynomial.Polynomial
    rho = P([r0, (r1 - r0) / h])
    z = P([0.0, 1.0])

    def integral(p):
        q = p.integ()
        return q(h) - q(0.0)

    V = PI * integral(rho**2)
    zc = PI * integral(z * rho**2) / V
    Izz = PI * integral(rho**4) / 2
    Ixx = PI * integral(rho**4 / 4 + (z - zc) ** 2 * rho**2)
    A = PI * (r0 * r0 + r1 * r1) + PI * (r0 + r1) * math.hypot(h, r1 - r0)
    return V, A, zc, Ixx, Izz


@settings(max_examples=25)
@given(st.one_of(st.just(0.0), st.floats(0.1, 5.0)), st.one_of(st.just(0.0), st.floats(0.1, 5.0)), sizes)
def test_cone_and_frustum_closed_forms(r0, r1, h):
    if abs(r0 - r1) < 1e-3:
        r1 = r0 + 1.0
    b = Cone(r0, r1, h, align=None).brep
    assert_valid(b)
    V, A, zc, Ixx, Izz = frustum_reference(r0, r1, h)
    mp = mass_properties(b)
    assert_mass(mp, V, A, [0, 0, zc], np.diag([Ixx, Ixx, Izz]))
    if r1 == 0.0:  # the cone of the textbooks: centroid at h/4, I_zz = 3/10 m r², I_xx = m (3 r²/20 + 3 h²/80)
        np.testing.assert_allclose([mp.centroid[2], mp.inertia[2, 2], mp.inertia[0, 0]],
                                   [h / 4, 0.3 * V * r0 * r0, V * (3 * r0 * r0 / 20 + 3 * h * h / 80)], rtol=RTOL)
    R = max(r0, r1)
    np.testing.assert_allclose(bounding_box(b), [[-R, -R, 0], [R, R, h]], rtol=0, atol=1e-14 * max(R, h))


@settings(max_examples=25)
@given(sizes)
def test_sphere_closed_forms(r):
    b = Sphere(r).brep
    m = 4 / 3 * PI * r**3
    assert_mass(mass_properties(b), m, 4 * PI * r * r, [0, 0, 0], np.eye(3) * 0.4 * m * r * r)
    np.testing.assert_allclose(face_areas(b), [2 * PI * r * r] * 2, rtol=RTOL)
    np.testing.assert_allclose(bounding_box(b), [[-r] * 3, [r] * 3], rtol=0, atol=1e-14 * r)


@settings(max_examples=25)
@given(sizes, st.floats(0.05, 0.95))
def test_torus_closed_forms(R, ratio):
    r = R * ratio
    b = Torus(R, r).brep
    m = 2 * PI**2 * R * r * r
    I = np.diag([m * (R * R / 2 + 5 * r * r / 8)] * 2 + [m * (R * R + 3 * r * r / 4)])
    assert_mass(mass_properties(b), m, 4 * PI**2 * R * r, [0, 0, 0], I)
    # Each quarter (upper or lower half of the tube over half a turn): ∫∫ r (R + r cos v) = π² R r.
    np.testing.assert_allclose(face_areas(b), [PI**2 * R * r] * 4, rtol=RTOL)
    np.testing.assert_allclose(bounding_box(b), [[-(R + r), -(R + r), -r], [R + r, R + r, r]], rtol=0, atol=1e-14 * R)


def test_first_and_second_moments_are_about_the_origin():
    b = Box(2, 4, 6, align=None).brep
    mp = mass_properties(b)
    c = np.array([1.0, 2.0, 3.0])
    np.testing.assert_allclose(mp.first_moments, 48 * c, rtol=RTOL)
    # ∫ x xᵀ dV = central second moments + m c cᵀ; central = m/12 diag(a², b², c²).
    M2 = 48 / 12 * np.diag([4.0, 16.0, 36.0]) + 48 * np.outer(c, c)
    np.testing.assert_allclose(mp.second_moments, M2, rtol=RTOL)
    np.testing.assert_allclose(np.sort(mp.principal_moments), np.sort(np.diag(mp.inertia)), rtol=RTOL)
    with pytest.raises(ValueError, match="read-only"):
        mp.centroid[0] = 1.0


# ============================================================================ rigid motions
PRIMITIVES = {
    "box": lambda: Box(1.0, 2.0, 3.0),
    "cylinder": lambda: Cylinder(1.5, 2.0),
    "cone": lambda: Cone(1.0, 0.0, 2.0),
    "frustum": lambda: Cone(1.0, 0.5, 2.0),
    "sphere": lambda: Sphere(1.3),
    "torus": lambda: Torus(2.0, 0.5),
}
unit_vectors = st.tuples(st.floats(-1, 1), st.floats(-1, 1), st.floats(-1, 1)).filter(lambda v: np.linalg.norm(v) > 0.1)


@pytest.mark.parametrize("name", list(PRIMITIVES))
@settings(max_examples=6)
@given(axis=unit_vectors, angle=st.floats(0, 2 * PI), shift=st.tuples(*[st.floats(-50, 50)] * 3))
def test_rigid_motion_moves_centroid_and_rotates_inertia(name, axis, angle, shift):
    b = PRIMITIVES[name]().brep
    R = rotation(axis, angle)
    moved = transformed(b, rigid(R, shift))
    assert_valid(moved)
    mp, mq = mass_properties(b), mass_properties(moved)
    assert_mass(mq, mp.volume, mp.area, R @ mp.centroid + shift, R @ mp.inertia @ R.T, rtol=1e-9)


@settings(max_examples=20)
@given(axis=unit_vectors, angle=st.floats(0, 2 * PI), shift=st.tuples(*[st.floats(-5, 5)] * 3))
def test_bounding_boxes_of_moved_curved_primitives(axis, angle, shift):
    R = rotation(axis, angle)
    T = rigid(R, shift)
    t = np.asarray(shift)
    # Sphere: the extremes are interior points of the hemispheres (or on their meridians).
    bs = bounding_box(transformed(Sphere(1.3).brep, T))
    np.testing.assert_allclose(bs, [t - 1.3, t + 1.3], rtol=0, atol=1e-13)
    # Torus about axis a: half-extent R sqrt(1 - a_i²) + r per axis.
    a = R[:, 2]
    # |e_i - a_i a| = sqrt(1 - a_i²), written without cancellation for a nearly along e_i.
    perp = np.sqrt([a[1] ** 2 + a[2] ** 2, a[0] ** 2 + a[2] ** 2, a[0] ** 2 + a[1] ** 2])
    h = 2.0 * perp + 0.5
    bt = bounding_box(transformed(Torus(2.0, 0.5).brep, T))
    np.testing.assert_allclose(bt, [t - h, t + h], rtol=0, atol=1e-13)
    # Cylinder (centred): the two end circles, r sqrt(1 - a_i²) around the end centres ± (h/2) a.
    bc = bounding_box(transformed(Cylinder(1.5, 2.0).brep, T))
    hc = 1.5 * perp + np.abs(a)
    np.testing.assert_allclose(bc, [t - hc, t + hc], rtol=0, atol=1e-13)


@pytest.mark.parametrize("name", list(PRIMITIVES))
def test_scaling_and_reflection_laws_through_solid(name):
    solid = PRIMITIVES[name]().translate((0.3, 0.2, 0.1))
    m = mass_properties(solid)
    big = solid.scale(2.5)  # volume s³, area s², inertia s⁵, centroid s c
    np.testing.assert_allclose([big.volume, big.area], [2.5**3 * m.volume, 2.5**2 * m.area], rtol=RTOL)
    np.testing.assert_allclose(big.centroid, 2.5 * m.centroid, rtol=RTOL)
    np.testing.assert_allclose(big.inertia, 2.5**5 * m.inertia, rtol=0, atol=RTOL * 2.5**5 * np.abs(m.inertia).max())
    np.testing.assert_allclose(big.bounding_box(), 2.5 * bounding_box(solid), rtol=0, atol=1e-13)
    n = np.array([1.0, 2.0, -1.0]) / math.sqrt(6.0)
    H = np.eye(3) - 2 * np.outer(n, n)
    o = np.array([0.1, 0.2, 0.3])
    mirrored = solid.mirror(o, n)  # a reflection: loops reversed, senses and parameters remapped
    assert mirrored.is_valid
    assert_mass(mass_properties(mirrored), m.volume, m.area, H @ (m.centroid - o) + o, H @ m.inertia @ H)


# ============================================================================ orientation, voids
def test_planar_faces_with_reversed_planes_give_the_same_properties():
    P = cuboid_points(1.0, 2.0, 3.0, origin=(0.5, -1.0, 2.0))
    implicit = polyhedron(P, CUBE)
    explicit = polyhedron(P, CUBE, planes=True)
    flipped = polyhedron(P, CUBE, planes=True, flip=(0, 2, 5))
    assert list(flipped.face_sense).count(False) == 3
    ref = mass_properties(Box(1.0, 2.0, 3.0, align=None).brep)
    shift = np.array([0.5, -1.0, 2.0])
    for b in (implicit, explicit, flipped):
        assert_valid(b)
        mp = mass_properties(b)
        assert_mass(mp, ref.volume, ref.area, ref.centroid + shift, ref.inertia)
        np.testing.assert_allclose(np.sort(face_areas(b)), [2, 2, 3, 3, 6, 6], rtol=RTOL)


def with_nurbs_lines(b: BRep) -> BRep:
    """Every straight edge as a degree-1 NURBS over ``[0, 1]`` (the straight edges' parameter), so
    planar faces go through Green's theorem with their ``Line2D`` p-curves instead of the
    polygon closed forms."""
    P = b.vertex_point[b.edge_vertex]
    curves = tuple(conics.nurbs_line(p, q) for p, q in P)
    return dataclasses.replace(b, curves=curves, edge_curve=np.arange(b.n_edges),
                               edge_range=np.tile([0.0, 1.0], (b.n_edges, 1)))


def test_planar_faces_through_greens_theorem_with_either_sense():
    P = cuboid_points(1.0, 2.0, 3.0, origin=(0.5, -1.0, 2.0))
    ref = mass_properties(polyhedron(P, CUBE))
    for flip in ((), (1, 2, 4)):
        b = with_nurbs_lines(polyhedron(P, CUBE, planes=True, flip=flip))
        assert_valid(b)
        assert_mass(mass_properties(b), ref.volume, ref.area, ref.centroid, ref.inertia)
        np.testing.assert_allclose(np.sort(face_areas(b)), [2, 2, 3, 3, 6, 6], rtol=RTOL)


def test_faces_with_holes_through_either_method(monkeypatch):
    # A 3 × 3 × 1 slab with a 1 × 1 square hole through it: top and bottom have an inner loop.
    P = np.concatenate([cuboid_points(3, 3, 1), cuboid_points(1, 1, 1, origin=(1, 1, 0))])
    faces = CUBE[2:] + [
        [[0, 3, 2, 1], [8, 9, 10, 11]],
        [[4, 5, 6, 7], [12, 15, 14, 13]],
        [9, 8, 12, 13], [10, 9, 13, 14], [11, 10, 14, 15], [8, 11, 15, 12],
    ]
    m_o, m_i = 9.0, 1.0
    I = np.diag([m_o * (9 + 1) - m_i * 2, m_o * (9 + 1) - m_i * 2, m_o * 18 - m_i * 2]) / 12
    monkeypatch.setattr(mass, "_CHUNK", 50)  # many chunks in the Green's-theorem path
    for b in (polyhedron(P, faces), with_nurbs_lines(polyhedron(P, faces, planes=True, flip=(4,)))):
        assert_valid(b)
        assert_mass(mass_properties(b), 8.0, 2 * 8 + 4 * 3 + 4 * 1, [1.5, 1.5, 0.5], I)
        np.testing.assert_allclose(np.sort(face_areas(b))[-2:], [8.0, 8.0], rtol=RTOL)


def test_inside_out_shells_have_negative_volume_and_check_reports_them():
    for solid in (Sphere(1.0), Cylinder(1.0, 2.0), Torus(2.0, 0.5), Cone(1.0, 0.0, 1.0)):
        b = reversed_brep(solid.brep)
        np.testing.assert_allclose(shell_volumes(b), -shell_volumes(solid.brep), rtol=RTOL)
        # Area stays positive: the sense flips together with the loop orientation.
        np.testing.assert_allclose(face_areas(b), face_areas(solid.brep), rtol=RTOL)
        report = check(b)
        assert report.codes() == {"inward-shell"}, report.summary()


def test_void_shell_subtracts():
    box = Box(4.0, 4.0, 4.0).brep
    for void_solid, V_void, I_void in (
        (Sphere(1.0), 4 / 3 * PI, 0.4 * 4 / 3 * PI * np.eye(3)),
        (Torus(1.0, 0.4), 2 * PI**2 * 0.16, 2 * PI**2 * 0.16 * np.diag([0.5 + 0.1, 0.5 + 0.1, 1 + 0.12])),
    ):
        b = nested(box, reversed_brep(void_solid.brep))
        assert_valid(b)
        vols = shell_volumes(b)
        np.testing.assert_allclose(vols, [64.0, -V_void], rtol=RTOL)
        mp = mass_properties(b)
        I_box = 64 / 12 * 32 * np.eye(3)
        assert_mass(mp, 64 - V_void, 96 + mass_properties(void_solid.brep).area, [0, 0, 0], I_box - I_void)
    # An off-centre polyhedral void moves the centroid away from it.
    outer = polyhedron(cuboid_points(4, 4, 4), CUBE)
    hole = reversed_brep(polyhedron(cuboid_points(1, 1, 1, origin=(2.5, 1.5, 1.5)), CUBE))
    b = nested(outer, hole)
    assert_valid(b)
    mp = mass_properties(b)
    np.testing.assert_allclose(mp.volume, 63.0, rtol=RTOL)
    np.testing.assert_allclose(mp.centroid, (64 * 2 - np.array([3.0, 2.0, 2.0])) / 63 * [1, 1, 1], rtol=RTOL)


# ============================================================================ polyhedra
def test_convex_polyhedron_matches_scipy_hull():
    from scipy.spatial import ConvexHull

    rng = np.random.default_rng(7)
    pts = rng.normal(size=(60, 3)) * [3.0, 1.0, 2.0] + [10.0, -20.0, 5.0]
    hull = ConvexHull(pts)
    tri = hull.simplices.copy()
    # Orient each facet outward (hull.equations: outward normals).
    n = np.cross(pts[tri[:, 1]] - pts[tri[:, 0]], pts[tri[:, 2]] - pts[tri[:, 0]])
    flip = np.einsum("ij,ij->i", n, hull.equations[:, :3]) < 0
    tri[flip] = tri[flip][:, ::-1]
    used, inv = np.unique(tri, return_inverse=True)
    b = polyhedron(pts[used], [list(map(int, t)) for t in inv.reshape(-1, 3)])
    assert_valid(b)
    mp = mass_properties(b)
    np.testing.assert_allclose(mp.volume, hull.volume, rtol=1e-12)
    np.testing.assert_allclose(mp.area, hull.area, rtol=1e-12)
    np.testing.assert_allclose(bounding_box(b), [pts[used].min(0), pts[used].max(0)], rtol=0, atol=0)


@pytest.mark.manifold
def test_polyhedron_matches_trimesh_mass_properties():
    import trimesh

    m = trimesh.creation.icosphere(subdivisions=2, radius=2.0)
    m.apply_transform(rigid(rotation([1, 2, 3], 0.7), [1.0, -2.0, 3.0]))
    m.apply_transform(np.diag([1.0, 1.5, 0.7, 1.0]))
    b = polyhedron(m.vertices, [list(map(int, f)) for f in m.faces])
    mp = mass_properties(b)
    np.testing.assert_allclose(mp.volume, m.volume, rtol=1e-12)
    np.testing.assert_allclose(mp.area, m.area, rtol=1e-12)
    np.testing.assert_allclose(mp.centroid, m.center_mass, rtol=0, atol=1e-12)
    np.testing.assert_allclose(mp.inertia, m.moment_inertia, rtol=0, atol=1e-11 * np.abs(m.moment_inertia).max())


# ============================================================================ NURBS faces, implicit planes
@pytest.mark.parametrize("nurbs_pcurves", [False, True])
def test_nurbs_cylinder_matches_closed_forms(nurbs_pcurves):
    r, h = 1.5, 2.0
    b = nurbs_sided(Cylinder(r, h, align=None).brep, nurbs_pcurves=nurbs_pcurves)
    assert_valid(b)
    m = PI * r * r * h
    I = np.diag([m * (3 * r * r + h * h) / 12] * 2 + [m * r * r / 2])
    assert_mass(mass_properties(b), m, 2 * PI * r * h + 2 * PI * r * r, [0, 0, h / 2], I)
    np.testing.assert_allclose(bounding_box(b), [[-r, -r, 0], [r, r, h]], rtol=0, atol=1e-12)


def test_nurbs_sphere_matches_closed_forms_and_moves(monkeypatch):
    monkeypatch.setattr(mass, "_CHUNK", 500)  # many chunks through the knot-split inner integral
    r = 1.3
    b = nurbs_sided(Sphere(r).brep)
    assert_valid(b)
    m = 4 / 3 * PI * r**3
    assert_mass(mass_properties(b), m, 4 * PI * r * r, [0, 0, 0], np.eye(3) * 0.4 * m * r * r)
    R = rotation([1, -2, 0.5], 1.1)
    moved = transformed(b, rigid(R, [3.0, 1.0, -2.0]))
    assert_mass(mass_properties(moved), m, 4 * PI * r * r, [3.0, 1.0, -2.0], np.eye(3) * 0.4 * m * r * r)
    # NURBS extremes come from sampling and a Newton polish: never outside, equal to round-off.
    centre = np.array([3.0, 1.0, -2.0])
    np.testing.assert_allclose(bounding_box(moved), [centre - r, centre + r], rtol=0, atol=1e-12)


def test_implicit_planes_with_curved_edges_use_projected_pcurves():
    b = Cylinder(1.5, 2.0).brep
    disks = np.flatnonzero([isinstance(b.surfaces[s], PlanarSurface) for s in b.face_surface])
    pc = b.edge_pcurve.copy()
    pc[np.isin(b.edge_face, disks)] = -1
    fs = b.face_surface.copy()
    fs[disks] = -1
    implicit = dataclasses.replace(b, face_surface=fs, edge_pcurve=pc)
    assert_valid(implicit)
    ref = mass_properties(b)
    assert_mass(mass_properties(implicit), ref.volume, ref.area, ref.centroid, ref.inertia)


# ============================================================================ curve extrema
def test_curve_extrema_match_dense_sampling():
    curves = [
        (Circle([1, 2, 3], [1, 1, 0.3], [0, 0, 1], 2.0), [(0.3, 2.9), (4.0, 7.5), (-1.0, 5.0)]),
        (Ellipse([0, -1, 2], [0.2, -1, 0.5], [1, 0, 0], 3.0, 1.0), [(0.0, 2 * PI), (2.5, 3.5)]),
        (conics.nurbs_circle([1, 0, 0], [0.3, 0.2, 1], 2.0), [(0.0, 2 * PI)]),
    ]
    for curve, ranges in curves:
        for t0, t1 in ranges:
            if isinstance(curve, NurbsCurve):
                t0, t1 = curve.domain
            t = np.linspace(t0, t1, 200001)
            P = curve.evaluate(t)
            ends = curve.evaluate(np.array([t0, t1]))
            Q = np.concatenate([ends, mass._curve_extreme_points(curve, np.array([[t0, t1]]))])
            # Exact extremes: never beyond the dense samples by more than round-off, and at least
            # as far as them (sampling error (2π/2e5)² ~ 1e-9 relative).
            assert np.all(Q.max(0) >= P.max(0) - 1e-13) and np.all(Q.max(0) <= P.max(0) + 1e-9)
            assert np.all(Q.min(0) <= P.min(0) + 1e-13) and np.all(Q.min(0) >= P.min(0) - 1e-9)


# ============================================================================ OCCT
def occt_properties(shape):
    from OCP.BRepGProp import BRepGProp
    from OCP.GProp import GProp_GProps

    vp, sp = GProp_GProps(), GProp_GProps()
    BRepGProp.VolumeProperties_s(shape.wrapped, vp)
    BRepGProp.SurfaceProperties_s(shape.wrapped, sp)
    c = vp.CentreOfMass()
    M = vp.MatrixOfInertia()
    I = np.array([[M.Value(i, j) for j in (1, 2, 3)] for i in (1, 2, 3)])
    return vp.Mass(), sp.Mass(), np.array([c.X(), c.Y(), c.Z()]), I


OCCT_CASES = {
    "box": ("Box", (1.0, 2.0, 3.0)),
    "cylinder": ("Cylinder", (1.5, 2.0)),
    "cone": ("Cone", (1.0, 0.0, 2.0)),
    "frustum": ("Cone", (1.0, 0.5, 2.0)),
    "sphere": ("Sphere", (1.3,)),
    "torus": ("Torus", (2.0, 0.5)),
}


@pytest.mark.occt
@pytest.mark.parametrize("name", list(OCCT_CASES))
def test_agrees_with_occt_gprop(name):
    import build123d as bd

    from coons.topology import primitives

    cls, args = OCCT_CASES[name]
    R = rotation([0.3, -1.0, 0.6], 0.9)
    shift = np.array([2.0, -1.0, 0.5])
    ours = transformed(getattr(primitives, cls)(*args).brep, rigid(R, shift))
    axis, angle = [0.3, -1.0, 0.6], math.degrees(0.9)
    theirs = bd.Pos(*shift) * getattr(bd, cls)(*args).rotate(bd.Axis((0, 0, 0), axis), angle)
    V, A, c, I = occt_properties(theirs)
    mp = mass_properties(ours)
    assert_mass(mp, V, A, c, I)
    bb = theirs.bounding_box(optimal=True)
    np.testing.assert_allclose(bounding_box(ours), [[bb.min.X, bb.min.Y, bb.min.Z], [bb.max.X, bb.max.Y, bb.max.Z]],
                               rtol=0, atol=1e-6)


# ============================================================================ errors
def test_error_branches():
    with pytest.raises(InvalidInputError, match="expected a BRep or a shape with a .brep, got int"):
        mass_properties(3)
    box = Box(1, 1, 1).brep
    with pytest.raises(InvalidInputError, match="expected a BRep"):
        bounding_box("box")

    class Odd:
        def derivatives(self, u, v, order=1):
            raise AssertionError("not reached")

    odd = dataclasses.replace(box, surfaces=(Odd(),) + box.surfaces[1:])
    with pytest.raises(InvalidInputError, match="cannot integrate over a Odd: supported surfaces are"):
        face_areas(odd)

    cyl = Cylinder(1.0, 1.0).brep
    side = int(np.flatnonzero([isinstance(cyl.surfaces[s], CylindricalSurface) for s in cyl.face_surface])[0])
    pc = cyl.edge_pcurve.copy()
    pc[cyl.edge_face == side] = -1
    with pytest.raises(TopologyError, match="has no p-curve; only planar faces may omit p-curves"):
        mass_properties(dataclasses.replace(cyl, edge_pcurve=pc))

    bad_pc = dataclasses.replace(cyl, pcurves=tuple(object() for _ in cyl.pcurves))
    with pytest.raises(InvalidInputError, match="cannot integrate along a object p-curve"):
        shell_volumes(bad_pc)

    # An implicit plane bounded by an unsupported curve type, and one whose boundary encloses nothing.
    disks = np.flatnonzero([isinstance(cyl.surfaces[s], PlanarSurface) for s in cyl.face_surface])
    fs = cyl.face_surface.copy()
    fs[disks] = -1
    pc = cyl.edge_pcurve.copy()
    pc[np.isin(cyl.edge_face, disks)] = -1

    class Helix:
        def derivatives(self, t, order=1):
            t = np.asarray(t, dtype=float)
            D = np.zeros(t.shape + (order + 1, 3))
            D[..., 0, :] = np.stack([np.cos(t), np.sin(t), 0 * t], -1)
            D[..., 1, :] = np.stack([-np.sin(t), np.cos(t), 0 * t], -1)
            return D

    curves = tuple(Helix() if isinstance(c, Circle) else c for c in cyl.curves)
    with pytest.raises(InvalidInputError, match="cannot integrate along a Helix edge curve"):
        mass_properties(dataclasses.replace(cyl, face_surface=fs, edge_pcurve=pc, curves=curves))
    flat = tuple(conics.nurbs_line([0, 0, 0], [1, 0, 0]) if isinstance(c, Circle) else c for c in cyl.curves)
    ranges = np.where(np.isin(cyl.edge_curve, [i for i, c in enumerate(cyl.curves) if isinstance(c, Circle)])[:, None],
                      [[0.0, 1.0]], cyl.edge_range)
    with pytest.raises(TopologyError, match="implicit face .* has zero area: its plane is undefined"):
        face_areas(dataclasses.replace(cyl, face_surface=fs, edge_pcurve=pc, curves=flat, edge_range=ranges))

    # A B-rep with no volume: one shell and its reverse in one solid.
    sphere = Sphere(1.0).brep
    with pytest.raises(TopologyError, match="encloses volume .*expected a non-zero finite volume"):
        mass_properties(nested(sphere, reversed_brep(sphere)))
    # Bounding boxes of geometry without derivatives.
    with pytest.raises(InvalidInputError, match="cannot bound a object edge curve: it has no evaluate/derivatives"):
        bounding_box(dataclasses.replace(cyl, curves=tuple(object() for _ in cyl.curves)))
    with pytest.raises(InvalidInputError, match="cannot bound a object surface: it has no evaluate/derivatives"):
        bounding_box(dataclasses.replace(sphere, surfaces=(object(),)))
    empty = dataclasses.replace(
        box, **{k: np.zeros((0,) + getattr(box, k).shape[1:], getattr(box, k).dtype)
                for k in ("vertex_point", "vertex_tol", "vertex_coedge")})
    with pytest.raises(TopologyError, match="has no vertices: its bounding box is undefined"):
        bounding_box(empty)


# ============================================================================ NURBS areas (adaptive quadrature)
XZ = ((0.0, 0.0, 0.0), (0.0, -1.0, 0.0), (1.0, 0.0, 0.0))  # the xz plane: u = x, v = z
#: Areas of NURBS faces against independent references: the adaptive quadrature asks for
#: tol.solver = 1e-12 (its error estimate is G7's, so K15 lands near round-off, measured <= 5e-16).
NURBS_AREA_RTOL = 1e-12


def quad(fn, a: float, b: float, points=()) -> float:
    """``∫_a^b fn`` by QUADPACK at 1e-13 relative (an independent reference)."""
    from scipy import integrate

    pts = [p for p in points if a < p < b]
    value, _ = integrate.quad(fn, a, b, epsabs=0.0, epsrel=1e-13, limit=400, points=pts or None)
    return value


def tensor_gauss_area(S, u_range, v_range, n: int = 40) -> float:
    """``∬ |Su × Sv|`` over a parameter rectangle: tensor Gauss–Legendre with ``n`` points per knot
    span each way (the integrand is smooth inside a span), no Green's theorem involved."""
    x, w = np.polynomial.legendre.leggauss(n)

    def nodes(knots, lo, hi):
        k = np.unique(np.concatenate([[lo, hi], knots]))
        k = k[(k >= lo) & (k <= hi)]
        a, c = k[:-1, None], k[1:, None]
        return ((a + c) / 2 + (c - a) / 2 * x).ravel(), ((c - a) / 2 * w).ravel()

    U, WU = nodes(S.knots_u, *u_range)
    V, WV = nodes(S.knots_v, *v_range)
    D = S.derivatives_grid(U, V, 1)
    return float(WU @ np.linalg.norm(np.cross(D[:, :, 1, 0], D[:, :, 0, 1]), axis=-1) @ WV)


def nurbs_face_areas(b: BRep) -> float:
    return float(sum(a for a, f in zip(face_areas(b), b.faces()) if f.surface_type == "bspline"))


def test_nurbs_face_areas_match_independent_references():
    from coons.topology.profile import Profile, Segment
    from coons.topology.sweep import extrude, loft, revolve

    # Extruded cubic spline: area = arc length × height (arc length by QUADPACK).
    spline = Segment.spline([(3, 0), (3.5, 1), (2.5, 2), (3, 3)])
    p = Profile.from_wires([Segment.line((1, 0), (3, 0)), spline, Segment.line((3, 3), (1, 3)),
                            Segment.arc_through((1, 3), (0.5, 1.5), (1, 0))], plane=XZ)
    c = next(seg for seg in p.outer if seg.kind == "spline").curve  # as resolved in the profile's plane
    length = quad(lambda t: float(np.linalg.norm(c.derivatives(np.array([t]), 1)[0, 1])), *c.domain, points=c.knots)
    s = extrude(p, 2.0)
    np.testing.assert_allclose(nurbs_face_areas(s.brep), 2.0 * length, rtol=NURBS_AREA_RTOL)
    np.testing.assert_allclose(s.volume, 2.0 * p.area, rtol=1e-14)  # volumes stay at round-off

    # Revolved spline touching the axis (NURBS faces with pole gaps): Pappus, 2π ∫ x |c'|, plus
    # the bottom disk, which the revolution makes NURBS too.
    spline = Segment.spline([(2, 0), (2.5, 1), (1.5, 2), (0, 3)])
    p = Profile.from_wires([Segment.line((0, 0), (2, 0)), spline, Segment.line((0, 3), (0, 0))], plane=XZ)
    c = next(seg for seg in p.outer if seg.kind == "spline").curve

    def pappus(t):
        D = c.derivatives(np.array([t]), 1)[0]
        return 2 * PI * D[0, 0] * float(np.linalg.norm(D[1]))

    s = revolve(p, (0, 0, 0), (0, 0, 1))
    assert {f.surface_type for f in s.faces()} == {"bspline"}
    np.testing.assert_allclose(nurbs_face_areas(s.brep), quad(pappus, *c.domain, points=c.knots) + 4 * PI,
                               rtol=NURBS_AREA_RTOL)
    V = quad(lambda t: PI * c.evaluate(np.array([t]))[0, 0] ** 2 * c.derivatives(np.array([t]), 1)[0, 1, 1],
             *c.domain, points=c.knots)
    np.testing.assert_allclose(s.volume, abs(V), rtol=1e-14)

    # Quadratic skin through three circles: r(v) = 1 - 2v + 2v², z = 2v (test_sweep), area
    # 2π ∫ r sqrt(r'² + z'²) dv.
    sections = [Profile.circle(r, plane=((0, 0, z), (0, 0, 1))) for r, z in ((1.0, 0), (0.5, 1), (1.0, 2))]
    s = loft(sections)
    ref = quad(lambda v: 2 * PI * (1 - 2 * v + 2 * v * v) * math.hypot(4 * v - 2, 2.0), 0.0, 1.0)
    np.testing.assert_allclose(nurbs_face_areas(s.brep), ref, rtol=NURBS_AREA_RTOL)

    # Square to circle (rational, no symmetry to exploit): each face against a tensor Gauss rule
    # over its parameter rectangle, converged (40 and 56 points per span agree to round-off).
    circle = Profile.from_wires([Segment.arc((0, 0), 1.0, -135, 225)], plane=((0, 0, 3), (0, 0, 1)))
    b = loft([Profile.rectangle(2, 2), circle]).brep
    areas = face_areas(b)
    for f in b.faces():
        if f.surface_type != "bspline":
            continue
        uv = np.concatenate([co.pcurve.evaluate(np.array(co.edge.range)) for co in f.coedges()])
        rng = (uv[:, 0].min(), uv[:, 0].max()), (uv[:, 1].min(), uv[:, 1].max())
        ref = tensor_gauss_area(f.surface, *rng, n=56)
        np.testing.assert_allclose(tensor_gauss_area(f.surface, *rng, n=40), ref, rtol=1e-14)
        np.testing.assert_allclose(areas[f.index], ref, rtol=NURBS_AREA_RTOL)


def test_trimmed_nurbs_face_area_with_a_hole():
    """A wavy bicubic patch (two knot spans in u) under the top cap of a plate with a hole: the
    face's outer loop crosses the knot line, its hole is a circle (Trig2D).  Reference: tensor
    Gauss over the rectangle minus polar Gauss over the disk (inside one span, so smooth)."""
    from coons.topology.profile import Profile
    from coons.topology.sweep import extrude

    b = extrude(Profile.rectangle(4, 2).with_hole(Profile.circle(0.5, center=(0.8, 0.0))), 3.0).brep
    cap = next(f for f in b.faces() if f.surface_type == "plane" and len(f.loops()) == 2 and f.surface.origin[2] > 1)
    P = cap.surface
    uv = np.concatenate([co.pcurve.evaluate(np.linspace(*co.edge.range, 9)) for co in cap.coedges()])
    (u0, v0), (u1, v1) = uv.min(axis=0), uv.max(axis=0)
    # Bicubic B-spline over [u0, u1] x [v0, v1] reproducing the plane at its Greville points, lifted
    # along the normal; the interior knot sits at u = u0 + 1 (outside the hole).
    ku = np.array([u0] * 4 + [u0 + 1.0] + [u1] * 4)
    kv = np.array([v0] * 4 + [v1] * 4)
    gu = np.array([ku[i + 1:i + 4].mean() for i in range(5)])
    gv = np.array([kv[i + 1:i + 4].mean() for i in range(4)])
    rng = np.random.default_rng(3)
    pts = P.evaluate(gu[:, None], gv[None, :]) + 0.3 * rng.standard_normal((5, 4))[..., None] * P.frame[2]
    S = NurbsSurface(pts, ku, kv, 3, 3)
    surfaces = b.surfaces + (S,)
    fs = b.face_surface.copy()
    fs[cap.index] = len(surfaces) - 1
    wavy = dataclasses.replace(b, surfaces=surfaces, face_surface=fs)
    area = face_areas(wavy)[cap.index]
    hole_u, hole_v = P.closest_parameters(np.array([0.8, 0.0, 3.0]))
    x, w = np.polynomial.legendre.leggauss(48)
    rho, wr = 0.25 * (x + 1), 0.25 * w  # [0, 0.5]
    phi, wp = PI * (x + 1), PI * w  # [0, 2π]
    U = hole_u + rho[:, None] * np.cos(phi)
    V = hole_v + rho[:, None] * np.sin(phi)
    D = S.derivatives(U, V, 1)
    J = np.linalg.norm(np.cross(D[..., 1, 0, :], D[..., 0, 1, :]), axis=-1) * rho[:, None]
    disk = float(wr @ J @ wp)
    ref = tensor_gauss_area(S, (u0, u1), (v0, v1), n=48) - disk
    assert area < tensor_gauss_area(S, (u0, u1), (v0, v1)) and area > 8.0 - PI * 0.25  # sanity: a bulging face
    np.testing.assert_allclose(area, ref, rtol=NURBS_AREA_RTOL)


def test_gauss_kronrod_and_trigonometric_rules_are_exact():
    # The embedded G7 rule is Gauss–Legendre; K15 integrates polynomials of degree 22 exactly.
    xg, wg = np.polynomial.legendre.leggauss(7)
    np.testing.assert_allclose(mass._XK[1::2], xg, rtol=0, atol=1e-15)
    np.testing.assert_allclose(mass._WG[1::2], wg, rtol=0, atol=1e-15)
    np.testing.assert_array_equal(mass._WG[0::2], 0.0)
    for k in range(23):
        np.testing.assert_allclose(mass._WK @ mass._XK**k, (1 + (-1) ** k) / (k + 1), rtol=0, atol=2e-15)
    # The 9-node rule integrates trigonometric polynomials of degree <= 4 over any interval.
    rng = np.random.default_rng(5)
    coef = rng.standard_normal(9)

    def g(t):
        return coef[0] + sum(coef[2 * k - 1] * np.cos(k * t) + coef[2 * k] * np.sin(k * t) for k in range(1, 5))

    def G(t):  # antiderivative
        terms = ((coef[2 * k - 1] * np.sin(k * t) - coef[2 * k] * np.cos(k * t)) / k for k in range(1, 5))
        return coef[0] * t + sum(terms)

    t0, t1, sign = np.array([0.3, -2.0, 1.0]), np.array([2.1, 4.5, 1.0 + 2 * PI]), np.array([1.0, -1.0, 1.0])
    _, t, w = mass._block_nodes(mass._B_TRIG_P, t0, t1, sign, np.zeros((3, 8)))
    np.testing.assert_allclose((w * g(t)).sum(axis=1), sign * (G(t1) - G(t0)), rtol=1e-14)


@pytest.mark.parametrize("make", [lambda: Sphere(1.3), lambda: Torus(2.0, 0.5), lambda: Cylinder(1.5, 2.0)],
                         ids=["sphere", "torus", "cylinder"])
def test_trigonometric_rule_and_gauss_pieces_agree(monkeypatch, make):
    """Meridians and arcs of at least ANGLE_STEP use the exact 9-node rule; forcing Gauss pieces
    on them instead gives the same properties to round-off."""
    b = make().brep
    mp = mass_properties(b)
    monkeypatch.setattr(mass, "_TRIG_RULE_MIN_SPAN", math.inf)
    gauss = dataclasses.replace(b)  # a new B-rep: nothing cached
    assert_mass(mass_properties(gauss), mp.volume, mp.area, mp.centroid, mp.inertia, rtol=1e-13)


# ============================================================================ vectorisation, cache, tolerance
def holed_plate(n: int):
    """A 200 × 200 × 10 plate with an n × n grid of r = 3 holes (the benchmark's plate for n = 10)."""
    from coons.topology.profile import Profile, Segment
    from coons.topology.sweep import extrude

    pitch = 200.0 / n
    holes = [[Segment.arc((-100 + pitch * (i + 0.5), -100 + pitch * (j + 0.5)), 3.0, 0, 360)]
             for i in range(n) for j in range(n)]
    return extrude(Profile.from_wires(Profile.rectangle(200, 200).outer, holes), 10.0)


def test_mass_properties_are_vectorised_over_faces(monkeypatch):
    """No surface or p-curve object is evaluated on analytic faces, and the closed-form integrands
    run once per quadrature block, whatever the number of faces: a plate with 100 holes (206 faces,
    1224 coedges) costs as many integrand calls as one with 4 holes."""
    from coons.kernel.analytic import PlanarSurface as Pl

    calls: dict[str, int] = {}

    def counting(owner, name):
        fn = getattr(owner, name)

        def wrapper(*a, **k):
            key = f"{getattr(owner, '__name__', '?').rsplit('.', 1)[-1]}.{name}"
            calls[key] = calls.get(key, 0) + 1
            return fn(*a, **k)

        monkeypatch.setattr(owner, name, wrapper)

    for cls in (Pl, CylindricalSurface, Line2D, mass.Trig2D):
        counting(cls, "evaluate")
        counting(cls, "derivatives")
    counting(mass, "_plane_F")
    counting(mass, "_revolved_F")
    counts = []
    for n in (2, 10):
        plate = holed_plate(n)
        calls.clear()
        mp = mass_properties(dataclasses.replace(plate.brep))  # a new B-rep: nothing cached
        np.testing.assert_allclose(mp.volume, 10.0 * (200.0**2 - n * n * PI * 9.0), rtol=1e-14)
        np.testing.assert_allclose(mp.area, 2 * (200.0**2 - n * n * PI * 9) + 10 * (800 + n * n * 2 * PI * 3),
                                   rtol=1e-14)
        counts.append(dict(calls))
    assert counts[0] == counts[1] == {"mass._plane_F": 2, "mass._revolved_F": 1}


def test_results_are_cached_per_brep_and_tolerance():
    b = Torus(2.0, 0.5).brep
    mp = mass_properties(b)
    assert mass_properties(b) is mp
    assert mass_properties(b, tol=Tolerance(solver=1e-8)) is not mp
    a = face_areas(b)
    a[0] = -1.0  # a copy: the cache is not exposed
    np.testing.assert_allclose(face_areas(b), [PI**2 * 2.0 * 0.5] * 4, rtol=RTOL)
    with pytest.raises(InvalidInputError, match="tol must be a coons.Tolerance or None, got str"):
        mass_properties(b, tol="tight")


def test_looser_tolerance_stops_earlier_within_it():
    from coons.topology.profile import Profile, Segment
    from coons.topology.sweep import revolve

    spline = Segment.spline([(2, 0), (2.5, 1), (1.5, 2), (0, 3)])
    b = revolve(Profile.from_wires([Segment.line((0, 0), (2, 0)), spline, Segment.line((0, 3), (0, 0))],
                                   plane=XZ), (0, 0, 0), (0, 0, 1)).brep
    tight = face_areas(b)
    loose = face_areas(dataclasses.replace(b), tol=Tolerance(solver=1e-6))
    np.testing.assert_allclose(loose, tight, rtol=1e-6)


def test_adaptive_quadrature_error_branches(monkeypatch):
    b = nurbs_sided(Sphere(1.0).brep)
    # Asking for round-off (tol.solver below 64 ulps is raised to it) with no bisection allowed.
    monkeypatch.setattr(mass, "MAX_BISECTIONS", 0)
    eps64 = 64 * np.finfo(float).eps
    with pytest.raises(ConvergenceError, match=r"did not reach relative accuracy 1\.4e-14 on face\(s\) \[\d") as exc:
        mass_properties(b, tol=Tolerance(solver=1e-16))
    assert exc.value.indices.size and np.all(exc.value.residuals > eps64)
    monkeypatch.setattr(mass, "MAX_BISECTIONS", 40)
    monkeypatch.setattr(mass, "_nurbs_integrand", lambda S, u, v, x0, ncols: np.full((u.size, ncols), np.nan))
    with pytest.raises(ConvergenceError, match=r"non-finite integrand on face\(s\) \[\d"):
        mass_properties(dataclasses.replace(b))


def test_circle_extremes_in_one_pass_are_the_per_curve_ones():
    """_circle_extreme_points of many arcs at once gives the points of _curve_extreme_points curve by curve."""
    from coons.booleans.solid import difference
    from coons.topology import mass
    from coons.topology.primitives import Box, Cylinder

    r = difference(Box(20, 20, 4), *[Cylinder(1.5, 10).translate((6.0 * i, 5.0 * i - 3, 0))
                                      for i in (-1, 0, 1)])
    b = r.brep
    rows = np.flatnonzero(b.edge_curve >= 0)
    circles = [k for k in rows.tolist() if type(b.curves[int(b.edge_curve[k])]).__name__ == "Circle"]
    assert len(circles) >= 6
    got = mass._circle_extreme_points([b.curves[int(b.edge_curve[k])] for k in circles], b.edge_range[circles])
    ref = np.concatenate([mass._curve_extreme_points(b.curves[int(b.edge_curve[k])], b.edge_range[[k]]) for k in circles])
    np.testing.assert_array_equal(np.sort(got.view([("x", float), ("y", float), ("z", float)]).ravel()),
                                  np.sort(ref.view([("x", float), ("y", float), ("z", float)]).ravel()))
    mass._CACHE.clear()
    lo, hi = mass.bounding_box(b)
    per_curve = [b.vertex_point] + [mass._curve_extreme_points(b.curves[int(b.edge_curve[k])], b.edge_range[[k]])
                                    for k in rows.tolist()]
    P = np.concatenate([p.reshape(-1, 3) for p in per_curve])
    np.testing.assert_array_equal(lo, P.min(axis=0))
    np.testing.assert_array_equal(hi, P.max(axis=0))


@pytest.mark.parametrize("make", [
    lambda: Box(2, 3, 4), lambda: Sphere(1.5), lambda: Torus(2.0, 0.5), lambda: Cylinder(1.0, 3.0),
    lambda: Box(4, 4, 4) - Cylinder(1.2, 6).rotate((0, 0, 0), (1, 0, 0), 30),
    lambda: Box(4, 4, 4) + Sphere(1.5).translate((2, 0.5, 0.3)),
])
def test_face_box_bounds_contain_each_face(make):
    """Every face's tessellation vertices (on the exact geometry) lie in its box, and the boxes
    together cover the exact bounding box."""
    from coons.tolerance import DEFAULT_TOLERANCE
    from coons.topology.tessellate import tessellate

    s = make()
    b = s.brep
    box = mass.face_box_bounds(b, DEFAULT_TOLERANCE)
    assert box.shape == (b.n_faces, 2, 3)
    m = tessellate(s, deflection=1e-2)
    X = m.vertices[m.triangles]  # (m, 3, 3)
    lo, hi = box[m.face_ids, 0][:, None, :], box[m.face_ids, 1][:, None, :]
    assert ((X >= lo) & (X <= hi)).all()
    exact = bounding_box(s)
    assert (box[:, 0].min(axis=0) <= exact[0]).all() and (box[:, 1].max(axis=0) >= exact[1]).all()


@pytest.mark.parametrize("make", [
    lambda: Box(4, 4, 4) - Cylinder(1.2, 6).rotate((0, 0, 0), (1, 0, 0), 30),
    lambda: Box(4, 4, 4) + Sphere(1.5).translate((2, 0.5, 0.3)),
    lambda: Sphere(2.0) - Cylinder(0.5, 6).rotate((0, 0, 0), (0, 1, 0), 20),
    lambda: Torus(2.0, 0.5),
    # (fitted intersection curves inside the box: their searches are skipped)
    lambda: Cylinder(2, 20) + Cylinder(1.5, 20, direction=(1, 0, 0)).translate((0, 0, 1)),
    lambda: Sphere(3.0) + Cylinder(1.0, 8).rotate((0, 0, 0), (1, 1, 0), 25).translate((0.5, 0, 0)),
])
def test_bounding_box_skips_only_searches_that_cannot_widen_it(make, monkeypatch):
    """Skipping the curves and surfaces whose hull lies in the box found so far gives the very box
    of the full search (and does skip searches on results with fitted intersection curves)."""
    b = make().brep
    searches = []
    real = mass._curve_extreme_points
    monkeypatch.setattr(mass, "_curve_extreme_points", lambda *a: searches.append(1) or real(*a))
    pruned = mass._bounding_box(b)
    skipping = len(searches)
    monkeypatch.setattr(mass, "_hull", lambda obj: None)
    np.testing.assert_array_equal(pruned, mass._bounding_box(b))
    full = len(searches) - skipping
    if any(isinstance(c, NurbsCurve) for c in b.curves):
        assert skipping < full



def test_pool_rows_made_together_equal_each_object_alone():
    # _pool_rows makes the rows of the objects it finds nowhere as one array and remembers them in
    # one call: each row (and code) must be the one of its object alone, in the table and in the
    # memo (read-only), objects remembered before taken from there, and objects that are not
    # values (not frozen dataclasses) never remembered.
    from coons.kernel.pcurve import Trig2D
    from coons.topology._memo import IdentityMemo

    class Loose:  # (not a value: a p-curve type the tables do not know)
        pass

    pcurves = (Line2D(np.array([0.5, -1.25]), np.array([3.0, 0.7])), Line2D(np.array([1.0, 2.0]), np.array([-2.0, 0.0])),
               Trig2D(np.array([0.1, 0.2]), np.array([1.0, 0.5]), np.array([-0.25, 2.0])), Loose())
    memo = IdentityMemo()
    first = mass._pool_rows(pcurves[:1], np.full(1, -1), mass._NO_CODE, mass._ZEROS8_2D, memo, mass._pcurve_rows)
    code, rows = mass._pool_rows(pcurves, np.full(4, -1), mass._NO_CODE, mass._ZEROS8_2D, memo, mass._pcurve_rows)
    for k, pc in enumerate(pcurves):
        kind, row = mass._pcurve_row(pc)
        assert code[k] == kind
        np.testing.assert_array_equal(rows[k], row)
        got = memo.get(pc)
        if k == 3:
            assert got is None
        else:
            assert got[0] == kind and not got[1].flags.writeable
            np.testing.assert_array_equal(got[1], row)
    np.testing.assert_array_equal(first[1][0], rows[0])
    assert len(memo) == 3


def test_pcurve_rows_by_type_equal_each_object_alone():
    # _pcurve_rows gathers the coefficients of lines and ellipses by type in array passes: every
    # shape and row must be the one _pcurve_row gives the object alone (iso-v and constant-u lines,
    # signed zeros, lines made by Line2D.many as rows of one array, a fitted
    # NURBS p-curve, a subclass and a type the tables do not know, in mixed order).
    from coons.kernel.pcurve import Trig2D

    class Loose:
        pass

    class Sub(Line2D):
        pass

    fitted = NurbsCurve(np.array([[0.0, 0.0], [1.0, 2.0], [3.0, 1.0]]), np.array([0.0, 0.0, 0.0, 1.0, 1.0, 1.0]), 2)
    pcurves = [Line2D(np.array([0.5, -1.25]), np.array([3.0, 0.7])), Line2D(np.array([1.0, 2.0]), np.array([-2.0, 0.0])),
               Line2D(np.array([1.0, 2.0]), np.array([-0.0, 5.0])),
               Trig2D(np.array([0.1, 0.2]), np.array([1.0, 0.5]), np.array([-0.25, 2.0])),
               Trig2D(np.array([0.1, 0.2]), np.array([1.0, -0.0]), np.array([-0.0, 0.5])), Loose(), fitted,
               Sub(np.array([0.0, 1.0]), np.array([0.0, 2.0]))]
    pcurves += Line2D.many(np.random.default_rng(3).normal(size=(5, 2)), np.array([[1.0, 0.0], [0.0, 1.0], [1.0, 1.0],
                                                                                   [-1.0, -0.0], [2.0, 3.0]]))
    pcurves += [Trig2D(np.array([x, 1.0]), np.array([2.0, 0.0]), np.array([0.0, x])) for x in (-0.5, 1.5)]
    shape, rows = mass._pcurve_rows(pcurves[::-1] + pcurves)
    for k, pc in enumerate(pcurves[::-1] + pcurves):
        kind, row = mass._pcurve_row(pc)
        assert shape[k] == kind, k
        assert rows[k].tobytes() == np.array(row, dtype=np.float64).tobytes(), k



def test_carried_shell_volumes_record_faces_whose_new_uses_are_values():
    # carried_shell_volumes records a face's contribution when its spec, surface and every use's
    # curve and p-curve (of its new loops, for a face extending a spec) are values, read from the
    # B-rep's pools (check._value_faces): the faces recorded must be those the test of each object
    # finds.  A box sewn with one planar face's p-curves left out (None: not a value) and a plate's
    # cut (faces carried, the top extending its spec).
    from coons.topology import _memo, check
    from coons.topology._memo import is_value
    from coons.topology.sew import EdgeSpec, FaceSpec, face_specs, sew_faces

    def expected(specs, unchanged, first):
        return [bool(u) and is_value(s) and is_value(s.surface)
                and all(is_value(e.curve) and is_value(e.pcurve) for loop in s.loops[first.get(f, 0):] for e in loop)
                for f, (s, u) in enumerate(zip(specs, unchanged))]

    _memo.clear_all()
    specs = list(face_specs(Box(2.0, 3.0, 4.0).brep))
    specs[2] = FaceSpec(specs[2].surface, specs[2].sense,
                        [[EdgeSpec(e.curve, e.t0, e.t1, None, e.tol) for e in loop] for loop in specs[2].loops])
    b = sew_faces(specs).brep
    known = check._SEWN_FROM[b]
    mass.carried_shell_volumes(b, *known, {})
    want = expected(*known, {})
    assert mass._VOLUMES_OF.last().recorded.tolist() == want and not all(want) and any(want)
    f = int(np.flatnonzero(~np.array(want))[0])
    exempt = np.zeros(b.n_loops, dtype=bool)
    exempt[b.face_loops[b.face_loop_ptr[f]:b.face_loop_ptr[f + 1]]] = True
    assert check._value_faces(b, exempt).tolist() == [True] * b.n_faces
    _memo.clear_all()
    one = Box(30.0, 30.0, 4.0) - Cylinder(1.0, 10.0).translate((4.0, 0.0, -3.0))
    two = one - Cylinder(1.0, 10.0).translate((-4.0, 0.0, -3.0))
    rec = mass._VOLUMES_OF.last()
    assert rec is mass._VOLUMES_OF.get(two.brep)
    specs, unchanged = check._SEWN_FROM[two.brep]
    assert rec.recorded.tolist() == expected(specs, unchanged, {}) and rec.recorded.all()
