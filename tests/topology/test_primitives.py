"""Primitives: valid seamless B-reps with the stated counts, exact geometry (vertices and edges on
their surfaces, same-parameter p-curves, outward orientation), closed-form volumes, OCCT's counts
and bounding boxes, build123d's alignment, and every bad-input branch.

Volumes are integrated independently of :mod:`coons.topology.mass`: the divergence theorem
``V = (1/3) ∮ P · n dA`` over each face's parameter region (a convex polygon sampled from the
p-curves, fan-triangulated, 7-point Dunavant rule), with the outward normal ``± Su × Sv`` from
the face sense.  Disks are approximated by inscribed polygons, hence the 1e-4 relative tolerance.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from coons.errors import InvalidInputError
from coons.kernel.analytic import Circle, ConicalSurface, Line
from coons.kernel.pcurve import Line2D, Trig2D
from coons.topology.brep import BRep
from coons.topology.check import check
from coons.topology.primitives import Box, Cone, Cylinder, Sphere, Torus
from coons.topology.shape import Solid

#: Round-off allowance for exact constructions (coordinates of order 1-10).
EXACT = 1e-12
#: Inscribed-polygon error of the sampled disks in the volume quadrature.
VOLUME_RTOL = 1e-4


# ============================================================================ helpers (shared with test_transform)
def loop_uv(b: BRep, loop: int, n: int = 128) -> np.ndarray:
    """``(k, 2)`` polygon through the p-curves of a loop in loop order (pole gaps as straight segments)."""
    s = np.linspace(0.0, 1.0, n + 1)
    pts = []
    for c in b.loop_coedges(loop):
        e, side = int(c) >> 1, int(c) & 1
        t0, t1 = b.edge_range[e]
        t = t0 + (t1 - t0) * (s if side == 0 else 1.0 - s)
        pts.append(b.pcurves[int(b.edge_pcurve[e, side])].evaluate(t))
    return np.concatenate(pts)


def signed_area(P: np.ndarray) -> float:
    x, y = P[:, 0], P[:, 1]
    return 0.5 * float(np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y))


def loops_agree_with_senses(b: BRep) -> list[tuple[int, float, bool]]:
    """Faces whose outer loop is not counter-clockwise in (u, v) iff the sense is True: ``(face, area, sense)``."""
    bad = []
    for f in range(b.n_faces):
        a = signed_area(loop_uv(b, int(b.face_loop_ids(f)[0])))
        if (a > 0) != bool(b.face_sense[f]):
            bad.append((f, a, bool(b.face_sense[f])))
    return bad


_A1, _B1, _A2, _B2 = 0.059715871789770, 0.470142064105115, 0.797426985353087, 0.101286507323456
_DUNAVANT_W = np.array([0.225] + [0.132394152788506] * 3 + [0.125939180544827] * 3)
_DUNAVANT_X = np.array([[1 / 3, 1 / 3], [_A1, _B1], [_B1, _A1], [_B1, _B1], [_A2, _B2], [_B2, _A2], [_B2, _B2]])


def volume(b: BRep, n: int = 256) -> float:
    """``(1/3) Σ ∫ (P - c) · n_out dA`` with ``n_out = ±(Su × Sv)`` by the face sense (convex parameter regions).

    ``c`` is the centroid of the vertices, so the (polygonal) quadrature error does not depend on
    where the solid is and transforms with it.
    """
    origin = b.vertex_point.mean(axis=0)
    total = 0.0
    for f in range(b.n_faces):
        S = b.surfaces[int(b.face_surface[f])]
        P = loop_uv(b, int(b.face_loop_ids(f)[0]), n)
        c = P.mean(axis=0)
        A, B = P - c, np.roll(P, -1, axis=0) - c
        jac = np.abs(A[:, 0] * B[:, 1] - A[:, 1] * B[:, 0])  # twice each fan triangle's area
        U = c + _DUNAVANT_X[None, :, :1] * A[:, None, :] + _DUNAVANT_X[None, :, 1:] * B[:, None, :]
        D = S.derivatives(U[..., 0], U[..., 1], 1)
        g = np.einsum("...i,...i->...", D[..., 0, 0, :] - origin, np.cross(D[..., 1, 0, :], D[..., 0, 1, :])) / 3.0
        flux = 0.5 * float(np.sum((g @ _DUNAVANT_W) * jac))
        total += flux if b.face_sense[f] else -flux
    return total


def sampled_bounding_box(b: BRep, n: int = 101) -> np.ndarray:
    """``(2, 3)`` box of points sampled on every face (grid inside its convex parameter region) and edge."""
    pts = [b.vertex_point]
    for f in range(b.n_faces):
        S = b.surfaces[int(b.face_surface[f])]
        P = loop_uv(b, int(b.face_loop_ids(f)[0]))
        lo, hi = P.min(axis=0), P.max(axis=0)
        U, V = (g.ravel() for g in np.meshgrid(np.linspace(lo[0], hi[0], n), np.linspace(lo[1], hi[1], n)))
        E = np.roll(P, -1, axis=0) - P
        cross = E[:, None, 0] * (V[None] - P[:, None, 1]) - E[:, None, 1] * (U[None] - P[:, None, 0])
        inside = np.all(cross * np.sign(signed_area(P)) >= -1e-12, axis=0)
        pts += [S.evaluate(U[inside], V[inside]), S.evaluate(P[:, 0], P[:, 1])]
    Q = np.concatenate(pts)
    return np.stack([Q.min(axis=0), Q.max(axis=0)])


def counts(s: Solid) -> tuple[int, int, int, int]:
    b = s.brep
    return b.n_vertices, b.n_edges, b.n_faces, b.n_loops


def occt_counts(shape) -> tuple[int, int, int, int]:
    """OCCT's (vertices, edges, faces, degenerate edges), seams and degenerate edges included."""
    from OCP.BRep import BRep_Tool
    from OCP.collections import IndexedMap_TopoDS_Shape_TopTools_ShapeMapHasher as ShapeMap
    from OCP.TopAbs import TopAbs_EDGE, TopAbs_FACE, TopAbs_VERTEX
    from OCP.TopExp import TopExp
    from OCP.TopoDS import TopoDS

    maps = []
    for kind in (TopAbs_VERTEX, TopAbs_EDGE, TopAbs_FACE):
        m = ShapeMap()
        TopExp.MapShapes_s(shape.wrapped, kind, m)
        maps.append(m)
    edges = maps[1]
    degenerate = sum(BRep_Tool.Degenerated_s(TopoDS.Edge(edges.FindKey(i))) for i in range(1, edges.Extent() + 1))
    return maps[0].Extent(), maps[1].Extent(), maps[2].Extent(), degenerate


# ============================================================================ the cases
PRIMITIVES = {
    # name: (factory, (V, E, F, L), genus, OCCT (V, E, F, degenerate), volume, surface types)
    "box": (lambda: Box(2.0, 3.0, 4.0), (8, 12, 6, 6), 0, (8, 12, 6, 0), 24.0, ["plane"] * 6),
    "cylinder": (lambda: Cylinder(1.5, 4.0), (4, 6, 4, 4), 0, (2, 3, 3, 0), math.pi * 1.5**2 * 4.0,
                 ["cylinder"] * 2 + ["plane"] * 2),
    "frustum": (lambda: Cone(2.0, 1.0, 3.0), (4, 6, 4, 4), 0, (2, 3, 3, 0), math.pi * 3.0 * (4 + 2 + 1) / 3,
                ["cone"] * 2 + ["plane"] * 2),
    "cone": (lambda: Cone(2.0, 0.0, 3.0), (3, 4, 3, 3), 0, (2, 3, 2, 1), math.pi * 4.0 * 3.0 / 3,
             ["cone"] * 2 + ["plane"]),
    "cone_apex_down": (lambda: Cone(0.0, 2.0, 3.0), (3, 4, 3, 3), 0, (2, 3, 2, 1), math.pi * 4.0 * 3.0 / 3,
                       ["cone"] * 2 + ["plane"]),
    "sphere": (lambda: Sphere(2.0), (2, 2, 2, 2), 0, (2, 3, 1, 2), 4 / 3 * math.pi * 8.0, ["sphere"] * 2),
    "torus": (lambda: Torus(3.0, 1.0), (4, 8, 4, 4), 1, (1, 2, 1, 0), 2 * math.pi**2 * 3.0, ["torus"] * 4),
}


def _build123d(name: str):
    import build123d as bd

    return {
        "box": lambda: bd.Box(2.0, 3.0, 4.0),
        "cylinder": lambda: bd.Cylinder(1.5, 4.0),
        "frustum": lambda: bd.Cone(2.0, 1.0, 3.0),
        "cone": lambda: bd.Cone(2.0, 0.0, 3.0),
        "cone_apex_down": lambda: bd.Cone(0.0, 2.0, 3.0),
        "sphere": lambda: bd.Sphere(2.0),
        "torus": lambda: bd.Torus(3.0, 1.0),
    }[name]()


@pytest.fixture(scope="module", params=sorted(PRIMITIVES))
def case(request):
    name = request.param
    make, cnt, genus, occt, vol, types = PRIMITIVES[name]
    return name, make(), cnt, genus, occt, vol, types


# ============================================================================ topology
def test_counts_check_and_euler(case):
    name, s, cnt, genus, _, _, types = case
    report = check(s)
    assert report.ok, report.summary()
    assert counts(s) == cnt
    V, E, F, L = cnt
    assert V - E + F - (L - F) == 2 * (1 - genus)
    assert s.brep.n_shells == 1 and s.brep.n_solids == 1
    assert sorted(s.surface_types()) == sorted(types)
    assert all(f.sense for f in s.faces())


@pytest.mark.occt
def test_counts_differ_from_occt_only_by_seams(case):
    """OCCT closes periodic faces with seams (and poles with degenerate edges); coons splits them."""
    name, _, _, _, occt, _, _ = case
    assert occt_counts(_build123d(name)) == occt


def test_every_edge_has_two_faces_no_seams(case):
    _, s, *_ = case
    ef = s.brep.edge_face
    assert np.all(ef[:, 0] != ef[:, 1])


# ============================================================================ geometry
def test_vertices_and_edges_lie_on_their_surfaces(case):
    """Independent of the p-curves: the implicit equation of each face's surface at vertices and edge samples."""
    _, s, *_ = case
    b = s.brep
    scale = float(np.max(np.abs(b.vertex_point))) + 1.0
    for f in s.faces():
        S = f.surface
        P = np.array([v.point for v in f.vertices()])
        np.testing.assert_allclose(S.implicit(P), 0.0, atol=EXACT * scale)
        for e in f.edges():
            t = np.linspace(*e.range, 17)
            np.testing.assert_allclose(S.implicit(e.points(t)), 0.0, atol=EXACT * scale)


def test_pcurves_are_same_parameter(case):
    _, s, *_ = case
    b = s.brep
    scale = float(np.max(np.abs(b.vertex_point))) + 1.0
    for e in s.edges():
        t = np.linspace(*e.range, 33)
        P = e.points(t)
        for f in e.faces:
            uv = e.pcurve(f).evaluate(t)
            np.testing.assert_allclose(f.surface.evaluate(uv[:, 0], uv[:, 1]), P, atol=EXACT * scale)


def test_loops_are_counter_clockwise_in_parameter_space(case):
    """sense = True everywhere, so every outer loop must run counter-clockwise in (u, v)."""
    _, s, *_ = case
    assert loops_agree_with_senses(s.brep) == []


def test_volume_by_divergence_theorem(case):
    _, s, _, _, _, vol, _ = case
    np.testing.assert_allclose(volume(s.brep), vol, rtol=VOLUME_RTOL)


def test_mass_properties_volume_is_the_closed_form(case):
    """coons.topology.mass integrates the exact faces: agreement to round-off."""
    _, s, _, _, _, vol, _ = case
    np.testing.assert_allclose(s.volume, vol, rtol=1e-12)


@pytest.mark.occt
def test_bounding_box_and_volume_match_build123d(case):
    name, s, *_ = case
    ref = _build123d(name)
    bb = ref.bounding_box()
    expected = np.array([[bb.min.X, bb.min.Y, bb.min.Z], [bb.max.X, bb.max.Y, bb.max.Z]])
    np.testing.assert_allclose(sampled_bounding_box(s.brep), expected, atol=1e-6)
    np.testing.assert_allclose(volume(s.brep), ref.volume, rtol=VOLUME_RTOL)


# ============================================================================ per-primitive structure
def test_box_edges_are_unit_speed_lines_with_lengths_as_ranges():
    s = Box(2.0, 3.0, 4.0)
    for e in s.edges():
        assert isinstance(e.curve, Line)
        a, b = (v.point for v in e.vertices)
        assert e.range[0] == 0.0
        assert e.range[1] == pytest.approx(np.linalg.norm(b - a), abs=EXACT)
        for f in e.faces:
            assert isinstance(e.pcurve(f), Line2D)
    assert sorted(round(e.range[1], 12) for e in s.edges()) == [2.0] * 4 + [3.0] * 4 + [4.0] * 4


def test_cylinder_circles_share_the_cylinder_frame_and_pcurves_are_lines():
    s = Cylinder(1.5, 4.0)
    side = next(f.surface for f in s.faces() if f.surface_type == "cylinder")
    np.testing.assert_allclose(s.brep.bounding_box()[:, 2], [-2.0, 2.0], atol=EXACT)  # centred in z
    for e in s.edges():
        if isinstance(e.curve, Circle):
            np.testing.assert_allclose(e.curve.frame, side.frame, atol=EXACT)
            assert e.range in ((0.0, math.pi), (math.pi, 2 * math.pi))
            for f in e.faces:
                pc = e.pcurve(f)
                if f.surface_type == "cylinder":  # u = t, v = const
                    assert isinstance(pc, Line2D) and pc.direction.tolist() == [1.0, 0.0]
                else:
                    assert isinstance(pc, Trig2D)
        else:  # rulings at u = 0 and u = π: u = const, v = t
            assert isinstance(e.curve, Line) and e.range == (0.0, 4.0)
            us = sorted(float(e.pcurve(f).origin[0]) for f in e.faces)
            assert us in ([0.0, 2 * math.pi], [math.pi, math.pi])
            assert all(e.pcurve(f).direction.tolist() == [0.0, 1.0] for f in e.faces)
    # The bottom disk's normal is -z: its Trig2D runs clockwise in the plane's own (u, v).
    bottom = next(f for f in s.faces() if f.surface_type == "plane" and f.surface.axis[2] < 0)
    pc = bottom.edges()[0].pcurve(bottom)
    assert pc.a[0] * pc.b[1] - pc.a[1] * pc.b[0] < 0


def test_cone_side_is_parametrised_along_the_slant():
    s = Cone(2.0, 1.0, 3.0)
    cone = next(f.surface for f in s.faces() if f.surface_type == "cone")
    assert isinstance(cone, ConicalSurface)
    slant = math.hypot(3.0, 1.0)
    assert cone.semi_angle == pytest.approx(math.atan2(-1.0, 3.0), abs=EXACT)
    rulings = [e for e in s.edges() if isinstance(e.curve, Line)]
    assert len(rulings) == 2 and all(e.range == pytest.approx((0.0, slant), abs=EXACT) for e in rulings)


@pytest.mark.parametrize("r0, r1", [(2.0, 0.0), (0.0, 2.0)])
def test_pointed_cone_has_a_pole_gap_at_the_apex(r0, r1):
    s = Cone(r0, r1, 3.0)
    b = s.brep
    apex_z = 1.5 if r1 == 0 else -1.5
    (apex,) = [v for v in s.vertices() if abs(v.point[2] - apex_z) < EXACT]
    np.testing.assert_allclose(apex.point, [0.0, 0.0, apex_z], atol=EXACT)
    assert len(apex.edges()) == 2
    slant = math.hypot(3.0, 2.0)
    for f in (f for f in s.faces() if f.surface_type == "cone"):
        assert apex in f.vertices() and len(f.edges()) == 3
        cs = f.outer_loop.coedges()
        (into,) = [c for c in cs if c.next.origin == apex]
        t_end = into.edge.range[1] if into.forward else into.edge.range[0]
        t_start = into.next.edge.range[0] if into.next.forward else into.next.edge.range[1]
        end, start = into.pcurve.evaluate(t_end), into.next.pcurve.evaluate(t_start)
        assert end[1] == pytest.approx(start[1]) and abs(end[0] - start[0]) == pytest.approx(math.pi)
        assert abs(end[1]) == pytest.approx(slant) or end[1] == pytest.approx(0.0)
    assert check(b).ok


def test_equal_radii_make_a_cylinder():
    s = Cone(1.0, 1.0, 2.0, direction=(1, 0, 0))
    assert sorted(s.surface_types()) == ["cylinder", "cylinder", "plane", "plane"]
    np.testing.assert_allclose(volume(s.brep), 2 * math.pi, rtol=VOLUME_RTOL)


def test_sphere_meridians_have_the_latitude_as_parameter():
    s = Sphere(2.0)
    S = s.faces()[0].surface
    for e in s.edges():
        assert isinstance(e.curve, Circle) and e.range == (-math.pi / 2, math.pi / 2)
        t = np.linspace(-math.pi / 2, math.pi / 2, 9)
        u0 = float(e.pcurve(e.faces[0]).origin[0]) % (2 * math.pi)
        np.testing.assert_allclose(e.curve.evaluate(t), S.evaluate(np.full_like(t, u0), t), atol=EXACT)
    poles = sorted(v.point[2] for v in s.vertices())
    assert poles == pytest.approx([-2.0, 2.0])


def test_torus_quarters_are_the_parameter_squares():
    s = Torus(3.0, 1.0)
    boxes = set()
    for f in s.faces():
        P = loop_uv(s.brep, f.outer_loop.index)
        lo, hi = np.round(P.min(axis=0) / math.pi, 12), np.round(P.max(axis=0) / math.pi, 12)
        assert (hi - lo).tolist() == [1.0, 1.0]
        boxes.add(tuple(lo))
    assert boxes == {(0.0, 0.0), (1.0, 0.0), (0.0, 1.0), (1.0, 1.0)}
    V, E, F, _ = counts(s)
    assert V - E + F == 0


# ============================================================================ placement
@pytest.mark.parametrize(
    "align, lo, hi",
    [
        (("min", "min", "min"), [0, 0, 0], [2, 3, 4]),
        (("max", "center", "min"), [-2, -1.5, 0], [0, 1.5, 4]),
        ("max", [-2, -3, -4], [0, 0, 0]),
        (None, [0, 0, 0], [2, 3, 4]),
    ],
)
def test_box_alignment(align, lo, hi):
    np.testing.assert_allclose(Box(2, 3, 4, align=align).brep.bounding_box(), [lo, hi], atol=EXACT)


def test_align_none_is_occt_placement():
    """BRepPrimAPI places the base centre of cylinders and cones at the origin."""
    for s, top in ((Cylinder(1, 2, align=None), 2.0), (Cone(1, 0.5, 2, align=None), 2.0)):
        np.testing.assert_allclose(sampled_bounding_box(s.brep)[:, 2], [0.0, top], atol=EXACT)
    np.testing.assert_allclose(sampled_bounding_box(Sphere(1, align=None).brep), [[-1] * 3, [1] * 3], atol=EXACT)


@pytest.mark.occt
def test_alignment_matches_build123d():
    import build123d as bd

    A = bd.Align
    for ours, theirs in (
        (Box(2, 3, 4, align=("min", "center", "max")), bd.Box(2, 3, 4, align=(A.MIN, A.CENTER, A.MAX))),
        (Cylinder(1, 2, align=("max", "min", "min")), bd.Cylinder(1, 2, align=(A.MAX, A.MIN, A.MIN))),
        (Cone(1, 0.5, 2, align=(A.MIN, A.MAX, A.CENTER)), bd.Cone(1, 0.5, 2, align=(A.MIN, A.MAX, A.CENTER))),
        (Sphere(1.5, align="min"), bd.Sphere(1.5, align=(A.MIN, A.MIN, A.MIN))),
        (Torus(3, 1, align=("center", "max", "min")), bd.Torus(3, 1, align=(A.CENTER, A.MAX, A.MIN))),
    ):
        bb = theirs.bounding_box()
        expected = np.array([[bb.min.X, bb.min.Y, bb.min.Z], [bb.max.X, bb.max.Y, bb.max.Z]])
        np.testing.assert_allclose(sampled_bounding_box(ours.brep), expected, atol=1e-6)


@pytest.mark.occt
def test_direction_matches_an_occt_cylinder_on_that_axis():
    import build123d as bd

    d = np.array([1.0, -2.0, 0.5])
    ours = Cylinder(1.0, 3.0, direction=d, align=None)
    ref = bd.Solid.make_cylinder(1.0, 3.0, bd.Plane(origin=(0, 0, 0), z_dir=tuple(d)))
    bb = ref.bounding_box()
    expected = np.array([[bb.min.X, bb.min.Y, bb.min.Z], [bb.max.X, bb.max.Y, bb.max.Z]])
    np.testing.assert_allclose(sampled_bounding_box(ours.brep, n=201), expected, atol=2e-4)  # grid resolution
    np.testing.assert_allclose(volume(ours.brep), ref.volume, rtol=VOLUME_RTOL)


directions = st.tuples(*[st.floats(-1, 1)] * 3).filter(lambda d: np.linalg.norm(d) > 0.1)
sizes = st.floats(0.1, 10.0)


@given(r=sizes, h=sizes, d=directions)
def test_cylinder_any_direction_is_valid_with_exact_volume(r, h, d):
    s = Cylinder(r, h, direction=d)
    assert check(s).ok
    np.testing.assert_allclose(volume(s.brep, 64), math.pi * r * r * h, rtol=2e-3)
    axis = np.asarray(d) / np.linalg.norm(d)
    tops = [v.point for v in s.vertices()]
    heights = sorted(np.round(np.asarray(tops) @ axis / h, 9))
    assert heights == pytest.approx([-0.5, -0.5, 0.5, 0.5], abs=1e-9)  # centred bounding box, symmetric


cone_radii = st.one_of(st.just(0.0), st.floats(0.01, 5.0))


@given(r0=cone_radii, r1=cone_radii, h=sizes, d=directions)
def test_cone_any_radii_and_direction_is_valid_with_exact_volume(r0, r1, h, d):
    if r0 == r1 == 0.0:
        r0 = 1.0
    s = Cone(r0, r1, h, direction=d)
    assert check(s).ok
    assert loops_agree_with_senses(s.brep) == []
    np.testing.assert_allclose(volume(s.brep, 64), math.pi * h * (r0 * r0 + r0 * r1 + r1 * r1) / 3, rtol=2e-3)


@given(R=sizes, ratio=st.floats(0.01, 0.99), L=sizes, W=sizes)
def test_sphere_torus_box_any_size_are_valid(R, ratio, L, W):
    for s in (Sphere(R), Torus(R, ratio * R), Box(L, W, R)):
        assert check(s).ok


# ============================================================================ bad input
BAD_SIZES = [0, -1.0, float("nan"), float("inf"), -float("inf"), "2", None, True, [1.0]]


@pytest.mark.parametrize("bad", BAD_SIZES, ids=repr)
def test_bad_sizes_raise_with_the_value(bad):
    match = r"must be a finite number > 0, got " + __import__("re").escape(repr(bad))
    calls = [
        lambda: Box(bad, 1, 1), lambda: Box(1, bad, 1), lambda: Box(1, 1, bad),
        lambda: Cylinder(bad, 1), lambda: Cylinder(1, bad),
        lambda: Cone(1, 0.5, bad),
        lambda: Sphere(bad),
        lambda: Torus(bad, 1), lambda: Torus(3, bad),
    ]
    for call in calls:
        with pytest.raises(InvalidInputError, match=match):
            call()


@pytest.mark.parametrize("bad", [-1.0, float("nan"), float("inf"), "1", None], ids=repr)
def test_bad_cone_radii_raise(bad):
    match = r"must be a finite number >= 0, got " + __import__("re").escape(repr(bad))
    with pytest.raises(InvalidInputError, match="bottom_radius " + match):
        Cone(bad, 1, 1)
    with pytest.raises(InvalidInputError, match="top_radius " + match):
        Cone(1, bad, 1)


def test_sizes_not_above_the_tolerance_raise():
    with pytest.raises(InvalidInputError, match=r"width must be larger than the linear tolerance 1e-07 .* got 1e-08"):
        Box(1, 1e-8, 1)
    with pytest.raises(InvalidInputError, match=r"top_radius must be larger than the linear tolerance"):
        Cone(1, 1e-9, 1)
    with pytest.raises(InvalidInputError, match=r"inner equator's radius\) must be larger than the linear tolerance"):
        Torus(1, 1 - 1e-9)
    assert sorted(Cone(1, 1 + 1e-8, 2).surface_types()) == ["cylinder", "cylinder", "plane", "plane"]


def test_cone_with_both_radii_zero_raises():
    with pytest.raises(InvalidInputError, match="at least one radius must be > 0"):
        Cone(0, 0.0, 1)


@pytest.mark.parametrize("minor", [3.0, 4.0])
def test_torus_minor_not_below_major_raises(minor):
    with pytest.raises(InvalidInputError, match=rf"minor_radius must be < major_radius .* got {minor!r} >= 3"):
        Torus(3, minor)


@pytest.mark.parametrize(
    "align, match",
    [
        ("middle", r"align must be one of 'min', 'center', 'max', got 'middle'"),
        (("min", "center"), r"align needs one entry per axis \(3\), got 2"),
        (("min", "center", "top"), r"align\[2\] must be one of .* got 'top'"),
        (("min", 0, "max"), r"align\[1\] must be one of .* got 0"),
        (5, r"align must be None, a name or 3 names .* got 5"),
    ],
)
def test_bad_align_raises(align, match):
    for make in (lambda: Box(1, 1, 1, align=align), lambda: Cylinder(1, 1, align=align), lambda: Sphere(1, align=align),
                 lambda: Torus(2, 1, align=align), lambda: Cone(1, 0, 1, align=align)):
        with pytest.raises(InvalidInputError, match=match):
            make()


@pytest.mark.parametrize(
    "direction, match",
    [((0, 0, 0), "direction must be non-zero"), ((1, 2), "direction must be 3 finite numbers"),
     ((float("nan"), 0, 1), "direction must be 3 finite numbers"), ("up", "direction must be 3 finite numbers")],
)
def test_bad_direction_raises(direction, match):
    with pytest.raises(InvalidInputError, match=match):
        Cylinder(1, 1, direction=direction)
    with pytest.raises(InvalidInputError, match=match):
        Cone(1, 0.5, 1, direction=direction)


def test_align_accepts_enum_like_names():
    class Align:
        def __init__(self, name):
            self.name = name

    a = Box(2, 2, 2, align=(Align("MIN"), Align("CENTER"), Align("MAX")))
    np.testing.assert_allclose(a.brep.bounding_box(), [[0, -1, -2], [2, 1, 0]], atol=EXACT)
