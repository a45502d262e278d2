"""Transforms: the 4×4 matrices, exact B-rep images under similarities (valid, vertices where the
matrix sends them, parameters rescaled consistently, outward orientation kept under reflections),
build123d's Pos/Rot placement, and every bad-input branch."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from coons.errors import InvalidInputError
from coons.kernel.analytic import Line
from coons.kernel.curve import NurbsCurve
from coons.kernel.pcurve import Line2D, Trig2D
from coons.topology.check import check
from coons.topology.primitives import Box, Cone, Cylinder, Sphere, Torus
from coons.topology.shape import Solid
from coons.topology.transform import (
    Location,
    Pos,
    Rot,
    reflection,
    rotation,
    scaling,
    similarity_scale,
    transform_brep,
    translation,
)
from tests.topology.test_primitives import VOLUME_RTOL, loops_agree_with_senses, volume

#: Round-off of one matrix product on coordinates of order 1-10.
EXACT = 1e-12

SHAPES = {
    "box": lambda: Box(2.0, 3.0, 4.0),
    "cylinder": lambda: Cylinder(1.5, 4.0),
    "frustum": lambda: Cone(2.0, 1.0, 3.0),
    "cone": lambda: Cone(2.0, 0.0, 3.0),
    "sphere": lambda: Sphere(2.0),
    "torus": lambda: Torus(3.0, 1.0),
}
_BUILT = {name: make() for name, make in SHAPES.items()}
_VOLUME = {name: volume(s.brep, 128) for name, s in _BUILT.items()}

MATRICES = {
    "identity": np.eye(4),
    "translation": translation((1.0, -2.0, 3.5)),
    "rotation": rotation((1.0, 2.0, 3.0), (1.0, -1.0, 2.0), 37.0),
    "rigid+scale": translation((3.0, -1.0, 2.0)) @ rotation((0, 0, 0), (0, 1, 1), -120.0) @ scaling(2.5),
    "shrink": scaling(0.3, origin=(1.0, 1.0, 1.0)),
    "mirror": reflection((1.0, 0.0, 0.0), (1.0, 1.0, 0.0)),
    "mirror+scale+rotation": reflection((0, 0, 0), (0, 0, 1)) @ scaling(0.3) @ rotation((0, 0, 0), (1, 2, 3), 77.0),
}


def newell_volume(solid: Solid) -> float:
    """Divergence-theorem volume of a solid with planar faces: Σ (1/6) P0 · (Pi × Pi+1) over each loop fan."""
    vol = 0.0
    for f in solid.faces():
        P = np.array([v.point for v in f.outer_loop.vertices()])
        vol += sum(np.dot(P[0], np.cross(P[i], P[i + 1])) for i in range(1, len(P) - 1)) / 6.0
    return vol


def apply(T: np.ndarray, P: np.ndarray) -> np.ndarray:
    return P @ T[:3, :3].T + T[:3, 3]


# ============================================================================ matrices
def test_translation_moves_points():
    np.testing.assert_array_equal(apply(translation((1, 2, 3)), np.zeros((1, 3))), [[1, 2, 3]])


def test_rotation_follows_the_right_hand_rule_and_fixes_its_axis():
    T = rotation((0, 0, 0), (0, 0, 1), 90)
    np.testing.assert_array_equal(apply(T, np.array([[1.0, 0, 0], [0, 1.0, 0]])), [[0, 1, 0], [-1, 0, 0]])  # exact
    T = rotation((1, 2, 3), (1, 1, 1), 50)
    axis_points = np.array([1, 2, 3]) + np.outer([-2.0, 0.0, 3.0], [1, 1, 1])
    np.testing.assert_allclose(apply(T, axis_points), axis_points, atol=EXACT)
    np.testing.assert_allclose(T[:3, :3] @ T[:3, :3].T, np.eye(3), atol=EXACT)
    assert np.linalg.det(T[:3, :3]) == pytest.approx(1.0)
    np.testing.assert_allclose(rotation((1, 2, 3), (1, 1, 1), -50) @ T, np.eye(4), atol=EXACT)


def test_scaling_about_a_point_and_reflection_are_what_they_say():
    T = scaling(2.0, origin=(1, 1, 1))
    np.testing.assert_array_equal(apply(T, np.array([[1.0, 1, 1], [2.0, 1, 1]])), [[1, 1, 1], [3, 1, 1]])
    H = reflection((1, 0, 0), (2, 0, 0))
    np.testing.assert_array_equal(apply(H, np.array([[1.0, 5, 6], [3.0, 0, 0]])), [[1, 5, 6], [-1, 0, 0]])
    np.testing.assert_allclose(H @ H, np.eye(4), atol=EXACT)
    assert np.linalg.det(H[:3, :3]) == pytest.approx(-1.0)


def test_similarity_scale_splits_the_matrix():
    T, s, reflects = similarity_scale(MATRICES["mirror+scale+rotation"])
    assert s == pytest.approx(0.3) and reflects
    assert similarity_scale(MATRICES["rigid+scale"])[1:] == (pytest.approx(2.5), False)


@pytest.mark.parametrize(
    "call, match",
    [
        (lambda: translation((1, 2)), r"offset must be 3 finite numbers, got \(1, 2\)"),
        (lambda: translation((1, 2, float("nan"))), "offset must be 3 finite numbers"),
        (lambda: rotation((0, 0, 0), (0, 0, 0), 10), "direction must be non-zero"),
        (lambda: rotation((0, 0), (0, 0, 1), 10), "origin must be 3 finite numbers"),
        (lambda: rotation((0, 0, 0), (0, 0, 1), float("inf")), "degrees must be a finite number, got inf"),
        (lambda: rotation((0, 0, 0), (0, 0, 1), "90"), "degrees must be a finite number, got '90'"),
        (lambda: scaling(0.0), r"scaling factor must be > 0, got 0.0"),
        (lambda: scaling(-2), r"scaling factor must be > 0, got -2"),
        (lambda: scaling(float("nan")), "factor must be a finite number, got nan"),
        (lambda: reflection((0, 0, 0), (0, 0, 0)), "normal must be non-zero"),
        (lambda: similarity_scale(np.diag([1.0, 2.0, 1.0, 1.0])), r"must be a similarity .* max \|M\^T M / s\^2 - I\| = 1.52"),
        (lambda: similarity_scale(np.diag([1.0, 0.0, 1.0, 1.0])), "singular"),
        (lambda: similarity_scale(np.ones((2, 2))), "transform must be 3x3 or 4x4"),
    ],
)
def test_bad_matrix_inputs_raise(call, match):
    with pytest.raises(InvalidInputError, match=match):
        call()


# ============================================================================ B-rep images
@pytest.mark.parametrize("shape", sorted(SHAPES))
@pytest.mark.parametrize("matrix", sorted(MATRICES))
def test_images_are_valid_and_placed_by_the_matrix(shape, matrix):
    T = MATRICES[matrix]
    src = _BUILT[shape].brep
    b = transform_brep(src, T)
    report = check(b)
    assert report.ok, report.summary()
    np.testing.assert_allclose(b.vertex_point, apply(T, src.vertex_point), atol=EXACT)
    # Edges (3-D curves over their new ranges) are the images of the old edges, pointwise.
    s = np.linspace(0.0, 1.0, 7)
    for e in range(src.n_edges):
        t0 = src.edge_range[e, 0] + s * (src.edge_range[e, 1] - src.edge_range[e, 0])
        t1 = b.edge_range[e, 0] + s * (b.edge_range[e, 1] - b.edge_range[e, 0])
        np.testing.assert_allclose(b.edge_points(e, t1), apply(T, src.edge_points(e, t0)), atol=EXACT * 10)
    assert loops_agree_with_senses(b) == []
    s3 = abs(np.linalg.det(T[:3, :3]))
    np.testing.assert_allclose(volume(b, 128), _VOLUME[shape] * s3, rtol=1e-9)  # same quadrature points, moved
    np.testing.assert_allclose(Solid(b).volume, _BUILT[shape].volume * s3, rtol=1e-12)  # mass properties
    assert Solid(b).volume > 0


def test_reflected_box_keeps_positive_newell_volume_and_reverses_its_loops():
    box = Box(2.0, 3.0, 4.0)
    mirrored = box.mirror((5.0, 0.0, 0.0), (1.0, 0.0, 0.0))
    assert check(mirrored).ok
    assert newell_volume(box) == pytest.approx(24.0) and newell_volume(mirrored) == pytest.approx(24.0)
    assert mirrored.volume == pytest.approx(24.0, rel=1e-12)
    np.testing.assert_allclose(mirrored.brep.bounding_box(), [[9, -1.5, -2], [11, 1.5, 2]], atol=EXACT)
    b0, b1 = box.brep, mirrored.brep
    np.testing.assert_array_equal(b1.edge_vertex, b0.edge_vertex)  # edges keep their direction ...
    np.testing.assert_array_equal(b1.edge_loop, b0.edge_loop[:, ::-1])  # ... and swap their sides
    assert list(b1.face_sense) == [False] * 6  # a mirrored plane's Su × Sv points inward


def test_reflected_revolved_faces_keep_their_sense_with_u_reversed():
    cyl = Cylinder(1.0, 2.0).mirror()
    side = [f for f in cyl.faces() if f.surface_type == "cylinder"]
    assert all(f.sense for f in side)
    for f in side:
        S = f.surface
        for e in f.edges():
            t = np.linspace(*e.range, 5)
            uv = e.pcurve(f).evaluate(t)
            assert np.all((uv[:, 0] >= -EXACT) & (uv[:, 0] <= 2 * math.pi + EXACT))  # u' = 2π - u
            np.testing.assert_allclose(S.evaluate(uv[:, 0], uv[:, 1]), e.points(t), atol=EXACT)


def test_uniform_scale_rescales_linear_parameters():
    s = 2.5
    for solid in (Box(1.0, 2.0, 3.0), Cylinder(1.0, 2.0), Cone(2.0, 1.0, 3.0)):
        b0, b1 = solid.brep, solid.scale(s).brep
        is_line = np.array([isinstance(b0.curves[c], Line) for c in b0.edge_curve])
        np.testing.assert_allclose(b1.edge_range[is_line], s * b0.edge_range[is_line], rtol=EXACT)
        np.testing.assert_array_equal(b1.edge_range[~is_line], b0.edge_range[~is_line])  # angles
        np.testing.assert_allclose(b1.edge_tol, s * b0.edge_tol)
        for f0, f1 in zip(b0.faces(), b1.faces()):
            for e0, e1 in zip(f0.edges(), f1.edges()):
                uv0 = e0.pcurve(f0).evaluate(np.asarray(e0.range))
                uv1 = e1.pcurve(f1).evaluate(np.asarray(e1.range))
                scale_uv = [s, s] if f0.surface_type == "plane" else [1.0, s]
                np.testing.assert_allclose(uv1, uv0 * scale_uv, atol=EXACT)


def test_shared_geometry_stays_shared():
    b = transform_brep(Torus(3.0, 1.0).brep, MATRICES["mirror+scale+rotation"])
    assert len(b.surfaces) == 1 and len(b.curves) == 4
    assert len(b.pcurves) == len(Torus(3.0, 1.0).brep.pcurves)


rotations = st.tuples(st.tuples(*[st.floats(-1, 1)] * 3).filter(lambda d: np.linalg.norm(d) > 0.1), st.floats(-360, 360))


@given(
    which=st.sampled_from(sorted(SHAPES)),
    rot=rotations,
    s=st.floats(0.05, 20.0),
    offset=st.tuples(*[st.floats(-100, 100)] * 3),
    mirror=st.booleans(),
)
def test_any_similarity_gives_a_valid_outward_image(which, rot, s, offset, mirror):
    T = translation(offset) @ rotation((0, 0, 0), rot[0], rot[1]) @ scaling(s)
    if mirror:
        T = reflection(offset, rot[0]) @ T
    src = _BUILT[which].brep
    b = transform_brep(src, T)
    assert check(b).ok
    scale = 100.0 + 20.0 * 10
    np.testing.assert_allclose(b.vertex_point, apply(T, src.vertex_point), atol=EXACT * scale)
    assert loops_agree_with_senses(b) == []
    np.testing.assert_allclose(volume(b, 32), volume(src, 32) * s**3, rtol=1e-9)


# ---------------------------------------------------------------------------- other geometry types
def _nurbs_box() -> Solid:
    """The box with every plane replaced by its bilinear NURBS patch and every line by a degree-1 NURBS
    (same parameters), so the NURBS branches of transform_brep run."""
    b = Box(2.0, 3.0, 4.0).brep
    surfaces = []
    for f in b.faces():
        P = np.concatenate([e.pcurve(f).evaluate(np.asarray(e.range)) for e in f.edges()])
        lo, hi = P.min(axis=0) - 1.0, P.max(axis=0) + 1.0
        surfaces.append(f.surface.to_nurbs((lo[0], hi[0]), (lo[1], hi[1])))
    curves = [b.curves[int(c)].to_nurbs(tuple(b.edge_range[e])) for e, c in enumerate(b.edge_curve)]
    nb = dataclasses.replace(b, surfaces=tuple(surfaces), face_surface=np.arange(6), curves=tuple(curves),
                             edge_curve=np.arange(12))
    assert check(nb).ok
    return Solid(nb)


@pytest.mark.parametrize("matrix", ["rigid+scale", "mirror", "mirror+scale+rotation"])
def test_nurbs_faces_and_edges_transform_exactly(matrix):
    T = MATRICES[matrix]
    src = _nurbs_box()
    b = transform_brep(src.brep, T)
    assert check(b).ok, check(b).summary()
    assert loops_agree_with_senses(b) == []
    s3 = abs(np.linalg.det(T[:3, :3]))
    np.testing.assert_allclose(volume(b), 24.0 * s3, rtol=1e-9)
    np.testing.assert_array_equal(b.edge_range, src.brep.edge_range)  # NURBS keep their parameter


def test_nurbs_pcurves_are_mapped_and_reparametrised():
    b = Box(1.0, 1.0, 1.0).brep
    pcs = tuple(NurbsCurve([pc.origin, pc.origin + pc.direction], [0, 0, 1, 1], 1) for pc in b.pcurves)
    nb = dataclasses.replace(b, pcurves=pcs, edge_range=np.tile([0.0, 1.0], (12, 1)))
    assert check(nb).ok
    out = transform_brep(nb, scaling(3.0))
    assert check(out).ok
    assert all(isinstance(pc, NurbsCurve) for pc in out.pcurves)
    np.testing.assert_array_equal(out.edge_range, 3.0 * nb.edge_range)


class _Unknown:
    def evaluate(self, *a):  # pragma: no cover - never evaluated
        raise AssertionError


def test_unknown_geometry_types_raise():
    b = Box(1.0, 1.0, 1.0).brep
    with pytest.raises(InvalidInputError, match="cannot transform a 3-D curve of type _Unknown"):
        transform_brep(dataclasses.replace(b, curves=(_Unknown(),) + b.curves[1:]), np.eye(4))
    with pytest.raises(InvalidInputError, match="cannot transform a surface of type _Unknown"):
        transform_brep(dataclasses.replace(b, surfaces=(_Unknown(),) + b.surfaces[1:]), np.eye(4))
    with pytest.raises(InvalidInputError, match="cannot transform a p-curve of type _Unknown"):
        transform_brep(dataclasses.replace(b, pcurves=(_Unknown(),) + b.pcurves[1:]), scaling(2.0))
    # A circle p-curve on a straight edge cannot follow the edge's rescaled parameter.
    trig = Trig2D([0, 0], [1, 0], [0, 1])
    with pytest.raises(InvalidInputError, match=r"Trig2D p-curve lies on an edge whose parameter scales by 2; expected 1"):
        transform_brep(dataclasses.replace(b, pcurves=(trig,) + b.pcurves[1:]), scaling(2.0))
    with pytest.raises(InvalidInputError, match="transform_brep needs a BRep, got Solid"):
        transform_brep(Box(1, 1, 1), np.eye(4))
    with pytest.raises(InvalidInputError, match="must be a similarity"):
        transform_brep(b, np.diag([1.0, 1.0, 3.0, 1.0]))


# ============================================================================ Solid methods
def test_solid_placement_methods():
    box = Box(2.0, 2.0, 2.0, align="min")
    np.testing.assert_allclose(box.translate((1, 2, 3)).brep.bounding_box(), [[1, 2, 3], [3, 4, 5]], atol=EXACT)
    np.testing.assert_allclose(box.rotate((0, 0, 0), (0, 0, 1), 90).brep.bounding_box(), [[-2, 0, 0], [0, 2, 2]],
                               atol=EXACT)
    np.testing.assert_allclose(box.scale(3.0).brep.bounding_box(), [[0, 0, 0], [6, 6, 6]], atol=EXACT)
    np.testing.assert_allclose(box.mirror().brep.bounding_box(), [[-2, 0, 0], [0, 2, 2]], atol=EXACT)
    assert all(check(s).ok for s in (box.translate((1, 2, 3)), box.rotate((1, 1, 1), (1, 2, 3), 33), box.mirror()))


# ============================================================================ Pos / Rot
def _occt_matrix(loc) -> np.ndarray:
    t = loc.wrapped.Transformation()
    M = np.eye(4)
    M[:3] = [[t.Value(i, j) for j in range(1, 5)] for i in range(1, 4)]
    return M


@pytest.mark.occt
@pytest.mark.parametrize("angles", [(10, 20, 30), (90, 0, 0), (0, 90, 45), (-33, 170, 400), (0, 0, 0)])
def test_pos_and_rot_match_build123d_locations(angles):
    import build123d as bd

    np.testing.assert_allclose(Rot(*angles).matrix, _occt_matrix(bd.Rot(*angles)), atol=EXACT)
    np.testing.assert_allclose(Pos(1, -2, 3).matrix, _occt_matrix(bd.Pos(1, -2, 3)), atol=EXACT)
    composed = Pos(1, -2, 3) * Rot(*angles)
    np.testing.assert_allclose(composed.matrix, _occt_matrix(bd.Pos(1, -2, 3) * bd.Rot(*angles)), atol=EXACT)
    np.testing.assert_allclose((Rot(*angles) * Pos(1, -2, 3)).matrix,
                               _occt_matrix(bd.Rot(*angles) * bd.Pos(1, -2, 3)), atol=EXACT)


@pytest.mark.occt
def test_placed_box_matches_build123d_vertices():
    import build123d as bd

    ours = Pos(1, 2, 3) * Rot(30, 45, 60) * Box(1, 2, 3)
    theirs = bd.Pos(1, 2, 3) * bd.Rot(30, 45, 60) * bd.Box(1, 2, 3)
    P = np.array(sorted(map(tuple, np.round(ours.brep.vertex_point, 9))))
    Q = np.array(sorted(tuple(round(c, 9) for c in (v.X, v.Y, v.Z)) for v in theirs.vertices()))
    np.testing.assert_allclose(P, Q, atol=1e-9)
    assert check(ours).ok


def test_rot_is_x_then_y_then_z_about_the_moving_axes():
    """Intrinsic XYZ: R = Rx Ry Rz on column vectors."""
    R = Rot(90, 90, 0).matrix[:3, :3]
    np.testing.assert_array_equal(R, rotation((0, 0, 0), (1, 0, 0), 90)[:3, :3] @ rotation((0, 0, 0), (0, 1, 0), 90)[:3, :3])
    np.testing.assert_array_equal(Rot(z=90).matrix, Rot((0, 0, 90)).matrix)
    np.testing.assert_array_equal(Rot(0, 0, 90).matrix[:3, :3] @ [1, 0, 0], [0, 1, 0])


def test_location_algebra():
    a, b, c = Pos(1, 2, 3), Rot(10, 20, 30), Pos(z=-5)
    np.testing.assert_allclose(((a * b) * c).matrix, (a * (b * c)).matrix, atol=EXACT)
    assert (a * b * a.inverse()).is_close(a * b * Pos(-1, -2, -3))
    assert (a * a.inverse()).is_close(Location())
    np.testing.assert_array_equal(Pos((1, 2, 3)).position, [1, 2, 3])
    box = Box(1, 1, 1)
    moved = a * b * box
    assert isinstance(moved, Solid) and check(moved).ok
    np.testing.assert_allclose(moved.brep.vertex_point, ((a * b) * box.brep).vertex_point, atol=EXACT)
    np.testing.assert_allclose((a * (b * box)).brep.vertex_point, moved.brep.vertex_point, atol=EXACT)
    assert "Pos(" in repr(a)
    with pytest.raises(TypeError):
        a * 5  # noqa: B018
    with pytest.raises(ValueError, match="read-only"):
        a.matrix[0, 0] = 2.0


@pytest.mark.parametrize(
    "call, match",
    [
        (lambda: Pos(1, 2, 3, 4), "Pos: expected at most 3 numbers, got 4"),
        (lambda: Pos(x=float("nan")), "Pos x must be a finite number, got nan"),
        (lambda: Pos(w=1), r"Pos: unexpected keyword\(s\) \['w'\]"),
        (lambda: Pos(1, x=2), "Pos: x given twice"),
        (lambda: Pos((1, 2)), r"Pos must be 3 finite numbers, got \(1, 2\)"),
        (lambda: Rot("a"), "Rot must be 3 finite numbers, got 'a'"),
        (lambda: Rot(0, float("inf"), 0), "Rot y must be a finite number, got inf"),
        (lambda: Location(np.ones((3, 4))), "transform must be 3x3 or 4x4"),
    ],
)
def test_bad_placement_inputs_raise(call, match):
    with pytest.raises(InvalidInputError, match=match):
        call()


def test_polyhedral_brep_without_geometry_transforms_and_mirrors():
    """Implicit planes and straight edges (no geometry objects): only points and, for mirrors, loops change."""
    from coons.topology.builder import BRepBuilder

    b = BRepBuilder()
    _, _, l0, _ = b.mvfs([0, 0, 0])
    e0, _ = b.mev(l0, None, [1, 0, 0])
    e1, _ = b.mev(l0, 2 * e0, [1, 1, 0])
    e2, _ = b.mev(l0, 2 * e1, [0, 1, 0])
    b.mef(l0, 2 * e2, 2 * e0 + 1)
    b.sweep_loop(l0, [0, 0, 1])
    block = Solid(b.build())
    for T in (MATRICES["rigid+scale"], MATRICES["mirror+scale+rotation"]):
        out = block.transformed(T)
        assert check(out).ok
        assert list(out.brep.face_sense) == list(block.brep.face_sense)
        np.testing.assert_array_equal(out.brep.edge_range, block.brep.edge_range)
        assert newell_volume(out) == pytest.approx(abs(np.linalg.det(T[:3, :3])), rel=1e-12)
