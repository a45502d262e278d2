"""sew_faces and face_specs: sewing trimmed faces back into checked solids.

Round trips: every primitive (and moved, mirrored, scaled ones), a mesh solid and a merged
polygon solid with holes are taken apart with ``face_specs``, shuffled (faces and the first
edge of every loop) and sewn back: the result is clean (``check``) with the same counts,
volume and area.  Sewing recovers same-parameter p-curves when the two faces of an edge carry
their own, differently parametrised copies of the curve; nests voids; honours edge tolerances;
and refuses open, non-manifold and inconsistently oriented shells, open loops, degenerate
edges and curves that are not affine copies, naming the face and edge.
"""

from __future__ import annotations

import math
import operator
import random

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from coons.errors import InvalidInputError, TopologyError
from coons.kernel.analytic import Circle, Line
from coons.kernel.curve import NurbsCurve
from coons.kernel.pcurve import Line2D, Trig2D
from coons.topology.check import check
from coons.topology.from_mesh import from_mesh
from coons.topology.primitives import Box, Cone, Cylinder, Sphere, Torus
from coons.topology.sew import EdgeSpec, FaceSpec, _affine_pcurve, face_specs, sew_faces, sewn_from
from coons.topology.transform import Pos, Rot

#: Volumes and areas of a re-sewn solid are computed from the same geometry: round-off only.
RTOL = 1e-12

PRIMITIVES = {
    "box": lambda: Box(1, 2, 3),
    "cylinder": lambda: Cylinder(1, 2),
    "frustum": lambda: Cone(1, 0.5, 2),
    "cone": lambda: Cone(1, 0, 2),
    "cone_apex_down": lambda: Cone(0, 1, 2, direction=(1, 1, 0)),
    "sphere": lambda: Sphere(1.5),
    "torus": lambda: Torus(3, 1),
    "moved_box": lambda: Pos(1, 2, 3) * Rot(10, 20, 30) * Box(1, 2, 3),
    "tilted_cylinder": lambda: Cylinder(0.5, 3, direction=(1, 2, 3)),
    "mirrored_torus": lambda: Torus(3, 1).mirror((0, 0, 0), (1, 2, 0)),
    "scaled_sphere": lambda: Sphere(2).scale(2.5).translate((0, 0, 7)),
    "mirrored_frustum": lambda: Cone(2, 1, 1).mirror(),
}


def counts(solid):
    b = solid.brep
    return b.n_vertices, b.n_edges, b.n_faces, b.n_loops, b.n_shells, b.n_solids


def shuffled(specs: list[FaceSpec], seed: int) -> list[FaceSpec]:
    """The faces in a random order, every loop starting at a random edge."""
    rng = random.Random(seed)
    out = []
    for f in specs:
        loops = []
        for loop in f.loops:
            k = rng.randrange(len(loop))
            loops.append(list(loop[k:]) + list(loop[:k]))
        out.append(FaceSpec(f.surface, f.sense, loops))
    rng.shuffle(out)
    return out


def reversed_specs(specs: list[FaceSpec]) -> list[FaceSpec]:
    """The same faces bounding the complement: loops reversed, senses flipped."""
    return [FaceSpec(f.surface, not f.sense,
                     [[EdgeSpec(e.curve, e.t1, e.t0, e.pcurve, e.tol) for e in reversed(loop)] for loop in f.loops])
            for f in specs]


def assert_same_solid(a, b):
    assert check(b).ok
    assert counts(b) == counts(a)
    np.testing.assert_allclose(b.volume, a.volume, rtol=RTOL)
    np.testing.assert_allclose(b.area, a.area, rtol=RTOL)
    np.testing.assert_allclose(b.bounding_box(), a.bounding_box(), rtol=RTOL, atol=1e-12)


# ============================================================================ round trips
@pytest.mark.parametrize("name", sorted(PRIMITIVES))
@pytest.mark.parametrize("seed", [0, 1])
def test_primitives_round_trip(name, seed):
    solid = PRIMITIVES[name]()
    assert_same_solid(solid, sew_faces(shuffled(face_specs(solid), seed)))


@given(
    st.sampled_from(["box", "cylinder", "cone", "sphere", "torus"]),
    st.tuples(*[st.floats(-180, 180)] * 3),
    st.tuples(*[st.floats(-10, 10)] * 3),
    st.integers(0, 1000),
)
def test_placed_primitives_round_trip(name, angles, offset, seed):
    solid = Pos(*offset) * Rot(*angles) * PRIMITIVES[name]()
    assert_same_solid(solid, sew_faces(shuffled(face_specs(solid), seed)))


def test_face_specs_shares_one_curve_per_edge():
    specs = face_specs(Cylinder(1, 2))
    uses = [e for f in specs for loop in f.loops for e in loop]
    # Both uses of an edge refer to one curve object over one range (the two bottom half-circles
    # share a Circle, over [0, π] and [π, 2π]).
    edges = {(id(e.curve), min(e.t0, e.t1), max(e.t0, e.t1)) for e in uses}
    assert len(uses) == 12 and len(edges) == 6
    assert all(isinstance(e.pcurve, (Line2D, Trig2D)) for e in uses)


def test_mesh_solid_round_trip_with_lines_for_straight_edges():
    import trimesh

    mesh = from_mesh(trimesh.creation.icosphere(subdivisions=2))
    specs = face_specs(mesh)
    assert all(f.surface is None for f in specs)
    assert all(isinstance(e.curve, Line) and e.pcurve is None for f in specs for l in f.loops for e in l)
    assert_same_solid(mesh, sew_faces(shuffled(specs, 3)))


def test_polygon_faces_with_holes_round_trip():
    import manifold3d as m3

    plate = m3.Manifold.cube([4, 4, 1]) - m3.Manifold.cube([2, 2, 3]).translate([1, 1, -1])
    m = plate.to_mesh()
    solid = from_mesh(np.asarray(m.vert_properties)[:, :3].astype(float), np.asarray(m.tri_verts), merge_coplanar=True)
    again = sew_faces(shuffled(face_specs(solid), 5))
    assert_same_solid(solid, again)
    assert sorted(len(f.loops()) for f in again.faces()) == [1] * 8 + [2] * 2


def test_vertex_ids_follow_the_input_order():
    box = Box(1, 1, 1)
    again = sew_faces(face_specs(box))
    first = face_specs(box)[0].loops[0][0]
    np.testing.assert_allclose(again.brep.vertex_point[0], first.curve.evaluate(first.t0), atol=1e-15)


# ============================================================================ same parameter
def own_copies(specs: list[FaceSpec]) -> list[FaceSpec]:
    """Give every use running against its curve its own reversed copy of the curve.

    Lines become ``Line(end, -direction)`` over ``[0, L]``; circles ``Circle(C, -normal, X, R)``
    whose angle is minus the original's; p-curves are rewritten in the new parameter
    (``Line2D`` by hand, ``Trig2D(C, A, -B)`` for ``t -> -t``).  Sewing must map them back.
    """
    out = []
    for f in specs:
        loops = []
        for loop in f.loops:
            new = []
            for e in loop:
                if e.t0 < e.t1:
                    new.append(e)
                    continue
                if isinstance(e.curve, Line):
                    start = e.curve.evaluate(e.t0)
                    curve = Line(start, -e.curve.direction)
                    pc = e.pcurve
                    if isinstance(pc, Line2D):  # old(t) with t = t0 - s
                        pc = Line2D(pc.origin + e.t0 * pc.direction, -pc.direction)
                    new.append(EdgeSpec(curve, 0.0, e.t0 - e.t1, pc, e.tol))
                elif isinstance(e.curve, Circle):
                    c = e.curve
                    curve = Circle(c.center, -c.frame[2], c.frame[0], c.radius)
                    pc = e.pcurve
                    pc = Line2D(pc.origin, -pc.direction) if isinstance(pc, Line2D) else Trig2D(pc.center, pc.a, -pc.b)
                    new.append(EdgeSpec(curve, -e.t0, -e.t1, pc, e.tol))
                else:
                    raise AssertionError(f"unexpected curve {type(e.curve).__name__}")
            loops.append(new)
        out.append(FaceSpec(f.surface, f.sense, loops))
    return out


@pytest.mark.parametrize("name", ["box", "cylinder", "frustum", "moved_box", "tilted_cylinder"])
def test_reversed_curve_copies_are_made_same_parameter(name):
    solid = PRIMITIVES[name]()
    specs = own_copies(face_specs(solid))
    uses = [e for f in specs for l in f.loops for e in l]
    along = {id(e.curve) for e in uses if e.t0 < e.t1}
    against = {id(e.curve) for e in uses if e.t0 > e.t1}
    assert not against and len(along) >= solid.brep.n_edges  # the two uses of an edge have different curves
    for seed in (0, 1):
        assert_same_solid(solid, sew_faces(shuffled(specs, seed)))


def test_affine_pcurve_closed_forms():
    t = np.linspace(-2.0, 3.0, 11)
    line = Line2D([1.0, 2.0], [0.5, -1.0])
    trig = Trig2D([1.0, -1.0], [2.0, 0.5], [-0.3, 1.0])
    nurbs = NurbsCurve([[0, 0], [1, 2], [3, 1], [4, 4]], [0, 0, 0, 0.4, 1, 1, 1], 2, [1.0, 0.8, 1.2, 1.0])
    for pc, maps in ((line, [(2.0, 0.5), (-0.25, 1.0)]), (trig, [(1.0, 0.7), (-1.0, -2.0)])):
        for a, c in maps:
            np.testing.assert_allclose(_affine_pcurve(pc, a, c).evaluate(t), pc.evaluate(a * t + c), atol=1e-14)
    for a, c in ((2.0, 0.5), (-0.5, 0.25)):
        new = _affine_pcurve(nurbs, a, c)
        s = (np.linspace(0.0, 1.0, 9) - c) / a
        np.testing.assert_allclose(new.evaluate(s), nurbs.evaluate(a * s + c), atol=1e-14)
    with pytest.raises(InvalidInputError, match=r"cannot re-parametrise a Trig2D p-curve by t -> 2 t \+ 0"):
        _affine_pcurve(trig, 2.0, 0.0)
    with pytest.raises(InvalidInputError, match="cannot re-parametrise a str p-curve"):
        _affine_pcurve("x", 1.0, 1.0)


def test_trig_pcurve_of_a_circle_edge_with_merged_ends_takes_the_unit_slope():
    """Hunt seed 20, chain 7: the two uses of a circle edge (two Circle objects of opposite turning, one
    circle) end at vertices merged within tolerance, so their ranges' lengths differ by 4e-9 and the
    parameter map's slope is -1 - 9e-9.  Two angle parametrisations of one conic differ by ±t + c exactly:
    the other use's Trig2D p-curve is re-expressed with slope -1 and the offset splitting the ends'
    disagreement (it was refused: a Trig2D re-parametrises only by slope ±1)."""
    from coons.topology.sew import _pcurve_in

    circle = Circle([0.0, 0.0, 0.0], [0.0, 0.0, 1.0], [1.0, 0.0, 0.0], 2.0)
    against = Circle([0.0, 0.0, 0.0], [0.0, 0.0, -1.0], [1.0, 0.0, 0.0], 2.0)  # against(s) = circle(-s)
    pc = Trig2D([0.3, 0.1], [1.0, 0.0], [0.0, 0.5])
    t0, t1 = 2.677945044588987, math.pi - 4.2e-9  # (t1: the end moved by the vertex merge)
    primary = EdgeSpec(circle, t0, t1)
    other = EdgeSpec(against, math.pi, 2 * math.pi - t0, pc)  # back from circle(pi) to circle(t0)
    a = (other.t0 - other.t1) / (primary.t1 - primary.t0)
    assert abs(abs(a) - 1.0) > 1e-9  # (not ±1 to round-off)
    got = _pcurve_in(primary, other, 1e-7, "edge")
    assert isinstance(got, Trig2D)
    # got(t) = pc(c - t) with c = 2 pi less half the ends' disagreement (4.2e-9)
    t = np.linspace(t0, t1, 7)
    speed = float(np.hypot(*pc.a)) + float(np.hypot(*pc.b))
    assert np.max(np.abs(got.evaluate(t) - pc.evaluate(2 * math.pi - t))) <= speed * 2.2e-9
    # ends far apart (1e-3): the unit slope leaves them apart, and the probes refuse the map
    far = EdgeSpec(against, math.pi, 2 * math.pi - t0 - 1e-3, pc)
    with pytest.raises(TopologyError, match="not affinely reparametrised"):
        _pcurve_in(primary, far, 1e-7, "edge")


def test_curves_that_are_not_affine_copies_are_refused():
    """The second use of a half-circle is a rational NURBS: same points, another parameter."""
    specs = face_specs(Cylinder(1, 2))
    f = specs[0]
    loops = [list(l) for l in f.loops]
    k = next(i for i, e in enumerate(loops[0]) if isinstance(e.curve, Circle))
    e = loops[0][k]
    lo, hi = sorted((e.t0, e.t1))
    nurbs = e.curve.to_nurbs((lo, hi))
    loops[0][k] = EdgeSpec(nurbs, e.t0, e.t1, e.pcurve, e.tol)
    specs[0] = FaceSpec(f.surface, f.sense, loops)
    # Matched geometrically (the parametric midpoints differ), then refused for same-parameter.
    with pytest.raises(TopologyError, match=r"not affinely reparametrised copies of each other \(deviation"):
        sew_faces(specs[1:] + specs[:1])


# ============================================================================ voids and tolerances
def test_spherical_void_in_a_box():
    box, ball = Box(4, 4, 4), Sphere(1).translate((0.5, 0, 0))
    solid = sew_faces(face_specs(box) + reversed_specs(face_specs(ball)))
    assert (solid.brep.n_shells, solid.brep.n_solids) == (2, 1)
    assert check(solid).ok
    np.testing.assert_allclose(solid.volume, 64 - 4 / 3 * math.pi, rtol=1e-12)


def test_void_goes_to_the_shell_around_it():
    left, right = Box(4, 4, 4).translate((-5, 0, 0)), Box(4, 4, 4).translate((5, 0, 0))
    hole = reversed_specs(face_specs(Torus(1.2, 0.5).translate((5, 0, 0))))
    solid = sew_faces(face_specs(left) + hole + face_specs(right))
    b = solid.brep
    assert (b.n_shells, b.n_solids) == (3, 2)
    lumps = {len(l.shells()): l for l in solid.lumps()}
    assert set(lumps) == {1, 2}
    centre = np.mean([v.point for s in lumps[2].shells() for f in s.faces() for v in f.vertices()], axis=0)
    assert centre[0] > 0  # the lump with the void is the right box
    np.testing.assert_allclose(solid.volume, 128 - 2 * math.pi**2 * 1.2 * 0.25, rtol=1e-12)


def test_voids_nest_in_the_smallest_shell_around_them_cones_and_mesh(monkeypatch):
    """A box with a box-shaped void holding a ball with a ball-shaped void.  The inner void's vertices
    lie in the boxes of the ball's faces (decided on the tessellation, certified by distance); the
    outer void's lie in no face box of the big box (decided by the cones over the chords)."""
    from coons.topology import tessellate as tess

    made = []
    real = tess.tessellate
    monkeypatch.setattr(tess, "tessellate", lambda *a, **k: made.append(k.get("deflection")) or real(*a, **k))
    outer, cavity = Box(10, 10, 10), Box(8, 8, 8)
    ball, bubble = Sphere(3), Sphere(1).translate((0.5, 0, 0))
    solid = sew_faces(face_specs(outer) + reversed_specs(face_specs(cavity)) + face_specs(ball)
                      + reversed_specs(face_specs(bubble)))
    b = solid.brep
    assert (b.n_shells, b.n_solids) == (4, 2)
    assert check(solid).ok
    for lump in solid.lumps():
        shells = lump.shells()
        assert len(shells) == 2
        spheres = [isinstance(f.surface, type(ball.brep.surfaces[0])) for s in shells for f in s.faces()]
        assert all(spheres) or not any(spheres)  # the bubble went to the ball, not to the big box
    np.testing.assert_allclose(solid.volume, 1000 - 512 + 4 / 3 * math.pi * (27 - 1), rtol=1e-9)
    assert len(made) == 1  # one tessellation, for the bubble; the cavity needed none


def test_a_void_in_a_face_box_but_outside_the_shell_is_refused():
    """The void lies in the corner of the ball's box: inside its faces' boxes, outside the ball."""
    specs = face_specs(Sphere(10)) + reversed_specs(face_specs(Box(1, 1, 1).translate((8, 8, 0))))
    with pytest.raises(TopologyError, match=r"shell 1 \(faces .*\) encloses volume -1 < 0 and lies inside no other "
                                            "shell: its faces are oriented inward"):
        sew_faces(specs)


def test_a_ball_in_a_cavity_is_a_lump_of_its_own():
    """A lump inside a void is valid: its outer shell lies directly inside the void, not the material."""
    solid = sew_faces(face_specs(Box(10, 10, 10)) + reversed_specs(face_specs(Box(8, 8, 8))) + face_specs(Sphere(3)))
    b = solid.brep
    assert (b.n_shells, b.n_solids) == (3, 2)
    assert check(solid).ok
    assert sorted(len(l.shells()) for l in solid.lumps()) == [1, 2]
    np.testing.assert_allclose(solid.volume, 1000 - 512 + 4 / 3 * math.pi * 27, rtol=1e-9)


@pytest.mark.parametrize("inner", [lambda: Box(2, 2, 2), lambda: Sphere(1).translate((0.5, 0, 0)),
                                   lambda: Box(1, 1, 1).translate((2, 2, 2))])
def test_a_lump_inside_a_lump_is_refused(inner):
    """Two outward shells one inside the other overlap: the inner one must be a void (cones and mesh)."""
    specs = face_specs(Box(6, 6, 6)) + face_specs(inner())
    with pytest.raises(TopologyError, match=r"shell 1 \(faces .*\) encloses volume .* > 0 and lies inside shell 0 "
                                            r"\(volume 216 > 0\): the two solids overlap"):
        sew_faces(specs)
    # Side by side they are two lumps.
    solid = sew_faces(face_specs(Box(6, 6, 6)) + face_specs(inner().translate((10, 0, 0))))
    assert (solid.brep.n_shells, solid.brep.n_solids) == (2, 2) and check(solid).ok


def test_a_void_inside_a_void_is_refused():
    specs = (face_specs(Box(10, 10, 10)) + reversed_specs(face_specs(Box(8, 8, 8)))
             + reversed_specs(face_specs(Sphere(2))))
    with pytest.raises(TopologyError, match=r"shell 2 \(faces .*\) encloses volume .* < 0 and lies directly inside "
                                            r"shell 1, another void \(volume -512\): a void must lie in solid material"):
        sew_faces(specs)


def shifted_face(spec: FaceSpec, delta, tol) -> FaceSpec:
    """A planar face moved by ``delta`` (p-curves kept: they deviate by |delta|), edges of tolerance ``tol``."""
    loops = [[EdgeSpec(Line(e.curve.origin + delta, e.curve.direction), e.t0, e.t1, e.pcurve, tol) for e in l]
             for l in spec.loops]
    return FaceSpec(spec.surface, spec.sense, loops)


def test_edge_tolerances_widen_vertex_merging():
    specs = face_specs(Box(1, 1, 1))
    gap = np.array([1e-5, 0.0, 0.0])
    with pytest.raises(TopologyError, match="matches no other edge: the shell is open there"):
        sew_faces([shifted_face(specs[0], gap, None)] + specs[1:])
    # Every edge of the shifted face carries tolerance 1e-4: its ends merge with the others'.
    solid = sew_faces([shifted_face(specs[0], gap, 1e-4)] + specs[1:])
    b = solid.brep
    assert counts(solid) == (8, 12, 6, 6, 1, 1)
    assert b.vertex_tol.max() >= 1e-5 / 2 and b.vertex_tol.max() <= 1e-5
    assert b.edge_tol.max() == 1e-4
    np.testing.assert_allclose(solid.volume, 1.0, rtol=1e-4)


# ============================================================================ refusals
def test_open_shell_names_the_face_and_edge():
    specs = face_specs(Box(1, 1, 1))
    with pytest.raises(TopologyError, match=r"face \d, loop 0, edge \d \(from \[.*\] to \[.*\]\) matches no other edge: "
                                            "the shell is open there"):
        sew_faces(specs[1:])


def test_non_manifold_edge_names_all_uses():
    specs = face_specs(Box(1, 1, 1))
    with pytest.raises(TopologyError, match=r"is shared by 3 edges \(face \d, loop 0, edge \d; .*\); a closed manifold "
                                            "shell uses each edge exactly twice"):
        sew_faces(specs + specs[:1])


def test_inconsistent_orientation_names_both_uses():
    specs = face_specs(Box(1, 1, 1))
    flipped = reversed_specs(specs[2:3])
    with pytest.raises(TopologyError, match=r"face \d, loop 0, edge \d and face \d, loop 0, edge \d .* run the same way; "
                                            r"neighbouring faces must use a shared edge in opposite directions"):
        sew_faces(specs[:2] + flipped + specs[3:])


def test_all_faces_reversed_is_an_inward_shell():
    with pytest.raises(TopologyError, match="inward-shell"):
        sew_faces(reversed_specs(face_specs(Box(1, 1, 1))))


def test_a_void_outside_every_shell_is_refused():
    specs = face_specs(Box(1, 1, 1)) + reversed_specs(face_specs(Box(1, 1, 1).translate((3, 0, 0))))
    with pytest.raises(TopologyError, match=r"shell 1 \(faces .*\) encloses volume -1 < 0 and lies inside no other "
                                            "shell: its faces are oriented inward"):
        sew_faces(specs)


def test_open_loop_is_refused_with_the_gap():
    specs = face_specs(Box(1, 1, 1))
    f = specs[0]
    loop = list(f.loops[0])
    e = loop[1]
    loop[1] = EdgeSpec(e.curve, e.t0, e.t1 - 0.25 * (e.t1 - e.t0), e.pcurve)
    specs[0] = FaceSpec(f.surface, f.sense, [loop])
    with pytest.raises(TopologyError, match=r"face 0, loop 0, edge 1 ends at .* but the next edge of the loop starts "
                                            r"at .* \(gap 0.25 > tolerance 1e-07\); loops must close"):
        sew_faces(specs)


def test_a_hole_and_a_face_shorter_than_the_tolerance_go():
    """A hole loop of three 1e-9 edges in a box face goes (the face stays, without it); an extra face whose
    outer loop is three 1e-9 edges goes whole."""
    box = Box(1, 1, 1)
    specs = face_specs(box)
    f = specs[0]
    P = np.array([e.curve.evaluate(e.t0) for e in f.loops[0]])
    c, x, y = P.mean(axis=0), P[1] - P[0], P[2] - P[1]  # (in the face's plane)
    corners = [c, c + 1e-9 * x / np.linalg.norm(x), c + 1e-9 * y / np.linalg.norm(y)]

    def loop(points):
        return [EdgeSpec(Line(p, q - p), 0.0, float(np.linalg.norm(q - p))) for p, q in zip(points, points[1:] + points[:1])]

    specs[0] = FaceSpec(f.surface, f.sense, [list(f.loops[0]), loop(corners[::-1])])
    sliver = FaceSpec(None, True, [loop([p + [0, 0, 5] for p in corners])])
    assert len(specs[0].loops) == 2
    solid = sew_faces(specs + [sliver])
    assert counts(solid) == counts(box)
    assert check(solid).ok
    assert abs(solid.volume - 1.0) <= 1e-12


def test_a_shell_within_its_tolerance_of_a_point_is_refused():
    specs = [FaceSpec(f.surface, f.sense, [[EdgeSpec(e.curve, e.t0, e.t1, e.pcurve, 10.0) for e in l] for l in f.loops])
             for f in face_specs(Box(1, 1, 1))]
    with pytest.raises(TopologyError, match=r"every face lies within its edges' tolerance \(up to 10\) of one vertex: "
                                            "the shell collapses to a point"):
        sew_faces(specs)


def test_an_edge_shorter_than_its_tolerance_is_collapsed():
    """A tiny edge in one loop (1e-9 long, no partner), and an edge cut 3e-8 from its end in both its
    faces (a tiny edge used twice), collapse into their vertices: the box comes back."""
    box = Box(1, 1, 1)
    specs = face_specs(box)
    f = specs[0]
    e = f.loops[0][0]
    tiny = EdgeSpec(Line(e.curve.evaluate(e.t0), [0.0, 0.0, 1.0]), 0.0, 1e-9)
    specs[0] = FaceSpec(f.surface, f.sense, [[tiny] + list(f.loops[0])])
    curve = specs[1].loops[0][0].curve
    for k, g in enumerate(specs):
        loops = []
        for loop in g.loops:
            out = []
            for u in loop:
                if u.curve is curve:  # both uses: cut at the same point, 3e-8 before the end at t = max
                    cut = max(u.t0, u.t1) - 3e-8
                    out += [EdgeSpec(u.curve, u.t0, cut, u.pcurve), EdgeSpec(u.curve, cut, u.t1, u.pcurve)]
                else:
                    out.append(u)
            loops.append(out)
        specs[k] = FaceSpec(g.surface, g.sense, loops)
    assert sum(len(l) for g in specs for l in g.loops) == 24 + 1 + 2
    solid = sew_faces(specs)
    assert counts(solid) == counts(box)
    assert check(solid).ok
    assert abs(solid.volume - 1.0) <= 1e-7  # (the collapsed edges' 3e-8: within the tolerance)


class _Broken:
    def __init__(self, exc=None):
        self.exc = exc

    def evaluate(self, t):
        if self.exc:
            raise self.exc
        return np.full(np.shape(t) + (3,), np.nan)


@pytest.mark.parametrize(
    ("make", "message"),
    [
        (lambda: sew_faces([]), "sew_faces needs at least one FaceSpec, got none"),
        (lambda: sew_faces(["face"]), r"faces\[0\] must be a FaceSpec, got str"),
        (lambda: EdgeSpec("curve", 0, 1), "EdgeSpec.curve must have an evaluate"),
        (lambda: EdgeSpec(Line([0, 0, 0], [1, 0, 0]), 1, 1), "finite, different parameters"),
        (lambda: EdgeSpec(Line([0, 0, 0], [1, 0, 0]), 0, math.nan), "finite, different parameters"),
        (lambda: EdgeSpec(Line([0, 0, 0], [1, 0, 0]), 0, 1, pcurve=3), "EdgeSpec.pcurve must have an evaluate"),
        (lambda: EdgeSpec(Line([0, 0, 0], [1, 0, 0]), 0, 1, tol=-1), "EdgeSpec.tol must be a finite number >= 0"),
        (lambda: FaceSpec(None, True, []), "FaceSpec needs at least one loop"),
        (lambda: FaceSpec(None, True, [[]]), "FaceSpec loop 0 is empty"),
        (lambda: FaceSpec(None, True, [["e"]]), "FaceSpec loop 0 item 0 must be an EdgeSpec, got str"),
        (lambda: sew_faces([FaceSpec(None, True, [[EdgeSpec(_Broken(ValueError("bad t")), 0, 1)]])]),
         "face 0, loop 0, edge 0: its curve cannot be evaluated on its range: bad t"),
        (lambda: sew_faces([FaceSpec(None, True, [[EdgeSpec(_Broken(), 0, 1)]])]),
         "face 0, loop 0, edge 0: its curve evaluates to non-finite points"),
        (lambda: face_specs("box"), "face_specs needs a Solid or BRep, got str"),
    ],
)
def test_invalid_input(make, message):
    with pytest.raises(InvalidInputError, match=message):
        make()


def test_face_specs_refuses_a_lone_vertex_loop():
    from coons.topology.builder import BRepBuilder

    b = BRepBuilder()
    b.mvfs([0.0, 0.0, 0.0])
    with pytest.raises(TopologyError, match="face 0: loop 0 is a lone vertex; a FaceSpec loop needs edges"):
        face_specs(b.build(check=False))


def test_bilinear_patch_faces_sew_a_closed_solid_and_reject_bad_nets():
    """Six unit-square patches of a cube, outward and (reversed nets, sense False) inward-parametrised."""
    from coons.topology.sew import bilinear_patch_faces

    c = np.array([[x, y, z] for x in (0.0, 1.0) for y in (0.0, 1.0) for z in (0.0, 1.0)]).reshape(2, 2, 2, 3)
    # Each side as P[i, j] with Su x Sv outward.
    nets = [c[0].transpose(1, 0, 2), c[1], c[:, 0], c[:, 1].transpose(1, 0, 2),
            c[:, :, 0].transpose(1, 0, 2), c[:, :, 1]]
    for sense, N in ((True, nets), (False, [n.transpose(1, 0, 2) for n in nets])):
        s = sew_faces(bilinear_patch_faces(N, sense=sense))
        assert s.check().ok and s.brep.n_faces == 6
        np.testing.assert_allclose(s.volume, 1.0, rtol=1e-14)
    with pytest.raises(InvalidInputError, match=r"shape \(f, 2, 2, 3\)"):
        bilinear_patch_faces(np.zeros((2, 3, 2, 3)))


@given(st.integers(0, 2**32 - 1))
def test_closed_form_distances_to_arcs_and_segments_match_dense_sampling(seed):
    """The exact point-to-arc and point-to-segment distances of the edge matching: never above the
    minimum over 20001 samples, and within the samples' resolution of it."""
    from coons.topology.sew import _circle_distance, _line_distance

    rng = np.random.default_rng(seed)
    c = Circle(rng.normal(size=3), rng.normal(size=3) + 0.1, rng.normal(size=3), float(rng.uniform(0.5, 3.0)))
    lo = float(rng.uniform(-7.0, 7.0))
    hi = lo + float(rng.uniform(0.1, 2.0 * math.pi))
    p = rng.normal(size=3) * 3.0
    tt = np.linspace(lo, hi, 20001)
    d = _circle_distance(c, p, lo, hi)
    sampled = float(np.linalg.norm(c.evaluate(tt) - p, axis=-1).min())
    assert d <= sampled + 1e-12
    assert sampled - d <= 3.0 * (hi - lo) / 20000  # the curve speed is the radius (<= 3)
    L = Line(rng.normal(size=3), rng.normal(size=3) + 0.1)
    sampled = float(np.linalg.norm(L.evaluate(tt) - p, axis=-1).min())
    d = _line_distance(L, p, lo, hi)
    assert d <= sampled + 1e-12 and sampled - d <= (hi - lo) / 20000


# ---------------------------------------------------------------------- face rows and sewn_unchanged
def test_face_specs_of_chosen_rows():
    from coons.topology.sew import face_specs as fs

    c = Cylinder(1.0, 2.0)
    every = fs(c)
    some = fs(c, rows=[2, 0])
    assert len(some) == 2
    for mine, ref in zip(some, [every[2], every[0]]):
        assert mine.surface is ref.surface and mine.sense == ref.sense
        assert [[(e.curve, e.t0, e.t1, e.pcurve, e.tol) for e in loop] for loop in mine.loops] == \
               [[(e.curve, e.t0, e.t1, e.pcurve, e.tol) for e in loop] for loop in ref.loops]


def test_sewn_unchanged_recognises_exactly_the_sewn_specs():
    from coons.topology.sew import sewn_unchanged

    specs = face_specs(Cylinder(1.0, 2.0))
    s = sew_faces(specs)
    b = s.brep
    # Re-sewing the specs of a B-rep gives back its curves, p-curves, ranges and tolerances.
    assert all(sewn_unchanged(b, f, spec) for f, spec in enumerate(specs))
    assert not sewn_unchanged(b, 0, specs[1])  # another face
    f0 = specs[0]
    e = f0.loops[0][0]
    flipped = FaceSpec(f0.surface, not f0.sense, f0.loops)
    assert not sewn_unchanged(b, 0, flipped)
    for changed in (EdgeSpec(e.curve, e.t0, e.t1, e.pcurve, (e.tol or 0.0) + 1e-9),  # another tolerance
                    EdgeSpec(e.curve, e.t0, e.t1, None, e.tol),  # no p-curve
                    EdgeSpec(e.curve, e.t0, e.t1 + 1e-12, e.pcurve, e.tol)):  # another range
        other = FaceSpec(f0.surface, f0.sense, [[changed] + list(f0.loops[0][1:])] + [list(l) for l in f0.loops[1:]])
        assert not sewn_unchanged(b, 0, other)
    # A face whose surface is not given (an implicit plane) is never "unchanged".
    box = Box(1, 1, 1)
    bs = face_specs(box)
    nb = sew_faces([FaceSpec(None, sp.sense, sp.loops) for sp in bs]).brep
    assert not any(sewn_unchanged(nb, f, FaceSpec(None, sp.sense, sp.loops)) for f, sp in enumerate(bs))


def test_sewn_unchanged_faces_is_sewn_unchanged_of_each_face():
    """The bulk form answers face by face as the single one, on a part where some faces changed."""
    from coons.topology.sew import sewn_unchanged, sewn_unchanged_faces

    specs = face_specs(Cylinder(1.0, 2.0)) + face_specs(Box(1, 1, 1).translate((5.0, 0.0, 0.0)))
    b = sew_faces(specs).brep
    e = specs[1].loops[0][0]
    mixed = list(specs)
    mixed[1] = FaceSpec(specs[1].surface, specs[1].sense,
                        [[EdgeSpec(e.curve, e.t0, e.t1, e.pcurve, (e.tol or 0.0) + 1e-9)] + list(specs[1].loops[0][1:])]
                        + [list(l) for l in specs[1].loops[1:]])
    mixed[3] = specs[4]  # another face's spec in this row
    got = sewn_unchanged_faces(b, mixed)
    assert got.tolist() == [sewn_unchanged(b, f, sp) for f, sp in enumerate(mixed)]
    assert not got[1] and not got[3] and got[0] and got[2] and got[4:].all()
    assert sewn_unchanged_faces(b, [specs[2], specs[0]], rows=[2, 0]).tolist() == [True, True]


def _walked(b, specs):
    """sewn_unchanged_faces by the field-by-field walk over the B-rep (explicit rows)."""
    from coons.topology.sew import sewn_unchanged_faces

    return sewn_unchanged_faces(b, specs, rows=list(range(len(specs))))


def test_remember_sewn_records_specs_and_the_walked_mask():
    """remember_sewn (for B-reps assembled without sewing) records the specs and the walk's mask,
    which sewn_from and sewn_unchanged_faces then answer from; one spec per face or it refuses."""
    from coons.errors import InvalidInputError
    from coons.topology.sew import remember_sewn, sewn_unchanged_faces

    specs = face_specs(Cylinder(1.0, 2.0))
    b = sew_faces(specs).brep
    changed = list(specs)
    e = specs[0].loops[0][0]
    changed[0] = FaceSpec(specs[0].surface, specs[0].sense,
                          [[EdgeSpec(e.curve, e.t0, e.t1, e.pcurve, (e.tol or 0.0) + 1e-9)] + list(specs[0].loops[0][1:])]
                          + [list(l) for l in specs[0].loops[1:]])
    remember_sewn(b, changed)
    assert all(x is y for x, y in zip(sewn_from(b), changed, strict=True))
    assert sewn_unchanged_faces(b, changed).tolist() == _walked(b, changed).tolist() == [False] + [True] * (len(specs) - 1)
    with pytest.raises(InvalidInputError, match="one spec per face"):
        remember_sewn(b, changed[1:])
    assert all(x is y for x, y in zip(sewn_from(b), changed, strict=True))  # (a refused record leaves the old one)


def test_sewing_knows_which_faces_it_left_unchanged():
    """The mask sew_faces works out in arrays while sewing equals the walk over the built B-rep:
    on specs sewn as they are, on specs whose shared uses disagree (a wider tolerance on one side,
    a range differing in the last place, a curve object of its own), and on Boolean results
    (split, merged and fused faces)."""
    from coons.topology.sew import _SEWN_FROM, sewn_unchanged_faces

    def agree(specs):
        b = sew_faces(specs).brep
        mask = _SEWN_FROM[b][1]
        assert mask.tolist() == _walked(b, specs).tolist()
        assert sewn_unchanged_faces(b, specs).tolist() == mask.tolist()  # answered from the record
        return mask

    cyl = face_specs(Cylinder(1.0, 2.0))
    specs = cyl + face_specs(Box(1, 1, 1).translate((5.0, 0.0, 0.0)))
    assert agree(specs).all()
    i = len(cyl)  # a box face: its first use lies on a Line
    e = specs[i].loops[0][0]
    assert isinstance(e.curve, Line)
    for changed in (EdgeSpec(e.curve, e.t0, e.t1, e.pcurve, (e.tol or 0.0) + 1e-9),
                    EdgeSpec(e.curve, e.t0, np.nextafter(e.t1, np.inf), e.pcurve, e.tol),
                    EdgeSpec(Line(e.curve.origin, e.curve.direction), e.t0, e.t1, e.pcurve, e.tol)):
        mixed = list(specs)
        mixed[i] = FaceSpec(specs[i].surface, specs[i].sense,
                            [[changed] + list(specs[i].loops[0][1:])] + [list(l) for l in specs[i].loops[1:]])
        mask = agree(mixed)
        assert not mask.all() and mask[:len(cyl)].all()
    # A face without a surface (an implicit plane) is never unchanged, in the record as in the walk.
    implicit = list(specs)
    implicit[i] = FaceSpec(None, specs[i].sense, [list(l) for l in specs[i].loops])
    assert not agree(implicit)[i]
    # Boolean results: the specs they were sewn from.
    from coons.booleans import solid as S

    plate = Box(40, 40, 10)
    for k, at in enumerate([(-10.0, -10.0, 0.0), (10.0, -10.0, 0.0), (0.0, 10.0, 0.0)]):
        plate = plate - Cylinder(2.0, 20.0).translate(at)
    results = [plate, Box(10, 10, 10) - Cylinder(3.0, 20.0),
               S.union(Box(2, 2, 2), Box(2, 2, 2).translate((1.0, 1.0, 0.0)), method="brep"),
               S.union(Box(2, 2, 2), Box(2, 2, 2).translate((2.0, 0.0, 0.0)), method="brep"),
               Cylinder(2.0, 20.0) + Cylinder(1.5, 10.0, direction=(1, 0, 0)).translate((5.0, 0.0, 0.0))]
    for r in results:
        specs = sewn_from(r.brep)
        assert _SEWN_FROM[r.brep][1].tolist() == _walked(r.brep, specs).tolist()


def test_use_tables_are_assembled_from_cached_loops():
    """A face gaining a loop reads its other loops' use tables from the per-loop cache, and the
    assembled table is the one computed from scratch (positions, rows, ids, tolerances)."""
    from coons.topology import _memo
    from coons.topology.sew import _LOOP_USES, _face_uses

    plate = Box(40, 40, 4)
    for at in [(-10.0, -10.0, 0.0), (10.0, 10.0, 0.0)]:
        plate = plate - Cylinder(1.0, 10.0).translate(at)
    top = max(face_specs(plate), key=lambda sp: len(sp.loops))
    _face_uses([top])
    cached = [_LOOP_USES.get(loop[0]) for loop in top.loops]
    assert all(c is not None for c in cached)
    grown = FaceSpec(top.surface, top.sense, [list(l) for l in top.loops] + [list(top.loops[1])])
    got = _face_uses([grown])[0]
    assert all(_LOOP_USES.get(loop[0]) is c for loop, c in zip(top.loops, cached))  # not recomputed
    _memo.clear_all()  # from scratch
    fresh = _face_uses([FaceSpec(top.surface, top.sense, [list(l) for l in grown.loops])])[0]
    for f in ("where", "ranges", "points", "kind", "frame", "curve_id", "own_tol", "complete"):
        assert np.array_equal(getattr(got, f), getattr(fresh, f), equal_nan=getattr(got, f).dtype.kind == "f"), f
    assert got.where[-len(top.loops[1]):, 0].tolist() == [len(top.loops)] * len(top.loops[1])


def test_use_tables_of_a_face_extending_a_kept_face_are_those_from_scratch():
    """A face of many loops whose first loops are, use for use, those of a face whose table is
    cached takes that table's rows for them (sewn._kept_uses) and only computes its new loops; every
    column is the one computed from scratch, and a bad use of a new loop is named by its place in
    the whole face."""
    from coons.topology import _memo
    from coons.topology import sew

    plate = Box(40, 40, 4)
    for at in [(-10.0, -10.0, 0.0), (10.0, 10.0, 0.0)]:
        plate = plate - Cylinder(1.0, 10.0).translate(at)
    top = max(face_specs(plate), key=lambda sp: len(sp.loops))
    many = FaceSpec(top.surface, top.sense, [list(l) for l in top.loops] + [list(top.loops[1])] * sew._PREFIX_LOOPS)
    base = sew._face_uses([many])[0]
    grown = FaceSpec(top.surface, top.sense, [list(l) for l in many.loops] + [list(top.loops[2])])
    n, kept = sew._kept_uses(grown)
    assert n == len(many.loops) and kept is base
    got = sew._face_uses([grown])[0]
    _memo.clear_all()  # from scratch
    assert sew._kept_uses(grown) is None
    fresh = sew._face_uses([FaceSpec(top.surface, top.sense, [list(l) for l in grown.loops])])[0]
    for f in sew._FaceUses.__slots__:
        a, b = getattr(got, f), getattr(fresh, f)
        if a.dtype == object:
            assert all(map(operator.is_, a, b)) and a.shape == b.shape, f
        else:
            assert np.array_equal(a, b, equal_nan=a.dtype.kind == "f"), f
        assert not a.flags.writeable, f
    assert got.where[-len(top.loops[2]):, 0].tolist() == [len(many.loops)] * len(top.loops[2])
    sew._face_uses([many])  # kept again
    wrong = FaceSpec(top.surface, top.sense, [list(l) for l in many.loops] + [[EdgeSpec(_Broken(), 0, 1)]])
    with pytest.raises(InvalidInputError, match=f"face 0, loop {len(many.loops)}, edge 0: its curve evaluates to non-finite"):
        sew._face_uses([wrong])


def test_per_loop_memos_die_with_their_loops():
    """The per-loop tables of sewing and of the Boolean pipeline hold a loop's other uses, not its
    first (their key): once the specs are gone the entries are gone."""
    import gc

    from coons.booleans import solid as S
    from coons.tolerance import resolve
    from coons.topology.sew import _LOOP_USES, _face_uses

    gc.collect()
    before = len(_LOOP_USES), len(S._LOOP_DATA)
    specs = face_specs(Cylinder(1.0, 2.0).translate((3.0, 0.0, 0.0)))
    _face_uses(specs)
    for spec in specs:
        S._face_data(spec, resolve(None))
    assert len(_LOOP_USES) > before[0] and len(S._LOOP_DATA) > before[1]
    del specs, spec
    gc.collect()
    assert (len(_LOOP_USES), len(S._LOOP_DATA)) == before


def test_a_void_touching_another_shell_raises_a_topology_error_and_keeps_no_fine_mesh(monkeypatch):
    """A void whose vertices all lie within about 1e-6 of the ball's surface (the tolerance band of the
    mesh test, whatever the deflection) raises TopologyError, not an error of the tessellator, and
    a small void near the wall but clear of it needs finer meshes, which are not cached with the
    result; a larger one near the wall takes its farthest vertex as the probe and needs none."""
    from coons.topology import tessellate as tess

    r = 0.01
    corner = r - 3e-7
    box = Box(5e-7, 5e-7, 5e-7).translate((corner / math.sqrt(3) - 2.5e-7,) * 3)
    # The box's far corner lies on the diagonal at |corner| from the centre: 3e-7 inside the sphere,
    # and every vertex within about 1e-6 of it.
    with pytest.raises(TopologyError, match="the shells touch"):
        sew_faces(face_specs(Sphere(r)) + reversed_specs(face_specs(box)))
    from coons.tolerance import resolve

    tess._MESHES.clear()  # (a cache: only this test's meshes below)
    made = []
    real = tess._tessellate
    monkeypatch.setattr(tess, "_tessellate", lambda b, d, *a: made.append(d) or real(b, d, *a))
    ball = Sphere(10)
    # A 0.01 cube whose far corner is 0.005 from the wall: every vertex within the default mesh's band.
    cube = Box(0.01, 0.01, 0.01).translate((9.995 / math.sqrt(3) - 0.005,) * 3)
    solid = sew_faces(face_specs(ball) + reversed_specs(face_specs(cube)))
    assert check(solid).ok and (solid.brep.n_shells, solid.brep.n_solids) == (2, 1)
    np.testing.assert_allclose(solid.volume, 4 / 3 * math.pi * 1000 - 1e-6, rtol=1e-9)
    default = tess._resolve_deflection(solid.brep, None, resolve(None))
    assert min(made) < default / 4  # the nesting refined the mesh ...
    assert all(key[0] >= default for m in tess._MESHES.values() for key in m)  # ... and cached no finer one
    made.clear()
    cube = Box(1, 1, 1).translate((9.995 / math.sqrt(3) - 0.5,) * 3)  # far corner 0.005 from the wall
    solid = sew_faces(face_specs(ball) + reversed_specs(face_specs(cube)))
    assert check(solid).ok and (solid.brep.n_shells, solid.brep.n_solids) == (2, 1)
    np.testing.assert_allclose(solid.volume, 4 / 3 * math.pi * 1000 - 1, rtol=1e-9)
    assert min(made) >= default  # (another corner of the cube is far from the wall: no finer mesh)
