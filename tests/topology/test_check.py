"""The checker finds every invariant violation it promises, and nothing in valid solids.

Each case corrupts the tables of a valid B-rep (arrays copied with ``np.array``, modified,
``BRep(...)`` rebuilt directly — no builder involved) or builds an invalid one with the Euler
operators / ``assemble`` and ``build(check=False)``, and asserts the problem's code and entity.
A meta-test asserts that every code written in ``coons/topology/check.py`` has a case here.
Valid primitives, mesh solids and merged polygon solids are clean.
"""

from __future__ import annotations

import dataclasses
import math
import re
from pathlib import Path

import numpy as np
import pytest
import trimesh

import coons.topology.check as check_module
from coons.kernel.analytic import PlanarSurface
from coons.kernel.pcurve import Line2D, Trig2D
from coons.topology._memo import LastRecord
from coons.topology.brep import BRep
from coons.topology.builder import BRepBuilder
from coons.topology.check import CheckReport, Problem, check
from coons.topology.from_mesh import from_mesh
from coons.topology.primitives import Box, Cone, Cylinder, Sphere, Torus
from coons.topology.sew import EdgeSpec, FaceSpec, face_specs, sew_faces
from coons.errors import TopologyError

CUBE_T = [[1, 3, 0], [4, 1, 0], [0, 3, 2], [2, 4, 0], [1, 7, 3], [5, 1, 4],
          [5, 7, 1], [3, 7, 2], [6, 4, 2], [2, 7, 6], [6, 5, 4], [7, 5, 6]]
TET_P = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], float)
TET_E = [[0, 1], [1, 2], [2, 0], [0, 3], [1, 3], [2, 3]]
TET_FACES = [[[-3, -2, -1]], [[1, 5, -4]], [[2, 6, -5]], [[3, 4, -6]]]  # outward


# ============================================================================ helpers
def columns(b: BRep) -> dict:
    """Writable copies of every table of ``b`` (geometry pools as lists)."""
    out = {}
    for f in dataclasses.fields(b):
        v = getattr(b, f.name)
        out[f.name] = np.array(v) if isinstance(v, np.ndarray) else list(v)
    return out


def corrupted(b: BRep, change) -> BRep:
    cols = columns(b)
    change(cols)
    return BRep(**cols)


def cube_points(lo, hi) -> np.ndarray:
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    bits = (np.arange(8)[:, None] >> np.array([2, 1, 0])) & 1
    return lo + bits * (hi - lo)


def assemble_triangles(parts, nest: tuple[int, int] | None = None) -> BRep:
    """Unchecked B-rep of triangle shells ``[(points, triangles), ...]`` through ``assemble``."""
    b = BRepBuilder()
    for P, T in parts:
        T = np.asarray(T)
        key = {}
        edges, faces = [], []
        for tri in T:
            loop = []
            for k in range(3):
                a, c = int(tri[k]), int(tri[(k + 1) % 3])
                if (c, a) in key:
                    loop.append(-(key[(c, a)] + 1))
                else:
                    key[(a, c)] = len(edges)
                    edges.append((a, c))
                    loop.append(key[(a, c)] + 1)
            faces.append([loop])
        b.assemble(P, edges, faces)
    if nest:
        b.nest_shells(*nest)
    return b.build(check=False)


def codes(b) -> set[str]:
    return check(b).codes()


def problem(b, code: str) -> Problem:
    report = check(b)
    hits = [p for p in report.problems if p.code == code]
    assert hits, f"expected {code!r}, got {report.summary()}"
    return hits[0]


def plate_with_hole(hole_lo, hole_hi) -> BRep:
    """Unchecked polyhedral plate [0, 4]² × [0, 1] with a square through hole (quads, implicit planes)."""
    (x0, y0), (x1, y1) = hole_lo, hole_hi
    outer = [(0, 0), (4, 0), (4, 4), (0, 4)]
    inner = [(x0, y0), (x1, y0), (x1, y1), (x0, y1)]
    P = np.array([(x, y, z) for z in (0.0, 1.0) for x, y in outer + inner], float)
    # vertex ids: bottom outer 0-3, bottom inner 4-7, top outer 8-11, top inner 12-15
    edges, index = [], {}

    def ref(a, c):
        if (c, a) in index:
            return -(index[(c, a)] + 1)
        index[(a, c)] = len(edges)
        edges.append((a, c))
        return len(edges)

    def loop(vs):
        return [ref(vs[i], vs[(i + 1) % len(vs)]) for i in range(len(vs))]

    faces = [
        [loop([8, 9, 10, 11]), loop([12, 15, 14, 13])],  # top: outer ccw, hole cw seen from +z
        [loop([0, 3, 2, 1]), loop([4, 5, 6, 7])],  # bottom seen from -z
    ]
    for i in range(4):  # outer sides
        j = (i + 1) % 4
        faces.append([loop([i, j, 8 + j, 8 + i])])
    for i in range(4):  # hole sides face into the hole
        j = (i + 1) % 4
        faces.append([loop([4 + j, 4 + i, 12 + i, 12 + j])])
    b = BRepBuilder()
    b.assemble(P, edges, faces)
    return b.build(check=False)


# ============================================================================ corruption cases
def case_dangling_pointer():
    return corrupted(Box(1, 1, 1).brep, lambda c: c["edge_wing"].__setitem__((0, 1), 10**6)), "coedge", 0


def case_wing_mismatch():
    def change(c):
        c["edge_wing"][0, 0] = c["edge_wing"][0, 1]  # prev of coedge 0 := its next

    return corrupted(Box(1, 1, 1).brep, change), "coedge", None


def case_loop_mismatch():
    b = Box(1, 1, 1).brep
    other = int(b.edge_loop[0, 1])
    return corrupted(b, lambda c: c["edge_loop"].__setitem__((0, 0), other)), "coedge", None


def case_loop_not_connected():
    return corrupted(Box(1, 1, 1).brep, lambda c: c["edge_vertex"].__setitem__(0, c["edge_vertex"][0, ::-1].copy())), \
        "coedge", None


def case_loop_first_coedge():
    b = Box(1, 1, 1).brep
    return corrupted(b, lambda c: c["loop_coedge"].__setitem__(0, int(b.loop_coedge[1]))), "loop", 0


def _merge_loop_1_into_0(c, lone_vertex: int):
    """Coedges of loop 1 relabelled to loop 0; loop 1 left as a lone vertex (or empty with -1)."""
    c["edge_loop"][c["edge_loop"] == 1] = 0
    c["loop_coedge"][1] = -1
    c["loop_vertex"][1] = lone_vertex


def case_loop_split():
    return corrupted(Box(1, 1, 1).brep, lambda c: _merge_loop_1_into_0(c, 0)), "loop", 0


def case_empty_loop():
    return corrupted(Box(1, 1, 1).brep, lambda c: _merge_loop_1_into_0(c, -1)), "loop", 1


def case_seam_edge():
    """A lamina strut: mvfs + mev leaves one face whose loop runs along both sides of the edge."""
    b = BRepBuilder()
    _, _, loop, _ = b.mvfs([0, 0, 0])
    b.mev(loop, None, [1, 0, 0])
    return b.build(check=False), "edge", 0


def case_non_manifold_vertex():
    """Two tetrahedra touching at vertex 0 only."""
    T = [[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]]
    mirrored = [[a if a == 0 else a + 3 for a in t[::-1]] for t in T]  # vertices 4-6 are -1 times 1-3
    return assemble_triangles([(np.concatenate([TET_P, -TET_P[1:]]), T + mirrored)]), "vertex", 0


def case_isolated_vertex():
    def change(c):
        c["vertex_point"] = np.concatenate([c["vertex_point"], [[5.0, 5.0, 5.0]]])
        c["vertex_tol"] = np.append(c["vertex_tol"], 1e-7)
        c["vertex_coedge"] = np.append(c["vertex_coedge"], -1)

    return corrupted(Box(1, 1, 1).brep, change), "vertex", 8


def case_shell_mismatch():
    b = assemble_triangles([(TET_P, [[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]]),
                            (TET_P + 5.0, [[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])])

    def change(c):
        c["face_shell"][4] = 0  # a face of the second tetrahedron claimed by the first shell
        c["shell_face_ptr"] = np.array([0, 5, 8])
        c["shell_faces"] = np.array([0, 1, 2, 3, 4, 5, 6, 7])

    return corrupted(b, change), "edge", None


def case_euler_poincare():
    b = assemble_triangles([(TET_P, [[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]]),
                            (TET_P + 5.0, [[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])])

    def change(c):  # both tetrahedra in one shell: V - E + F = 4 is not 2 (1 - G)
        c["face_shell"][:] = 0
        c["shell_solid"] = np.array([0])
        c["shell_face_ptr"] = np.array([0, 8])
        c["shell_faces"] = np.arange(8)
        c["solid_shell_ptr"] = np.array([0, 1])
        c["solid_shells"] = np.array([0])

    return corrupted(b, change), "shell", 0


def case_vertex_off_edge():
    return corrupted(Box(1, 1, 1).brep, lambda c: c["vertex_point"].__setitem__((0, 0), c["vertex_point"][0, 0] + 1e-3)), \
        "edge", None


def case_pcurve_deviation():
    b = Box(1, 1, 1).brep
    k = int(b.edge_pcurve[0, 0])

    def change(c):
        pc = c["pcurves"][k]
        c["pcurves"][k] = Line2D(pc.origin + [0.0, 0.01], pc.direction)

    return corrupted(b, change), "edge", 0


def case_pcurve_loop_open():
    """A cylinder's bottom half-circle p-curve shifted by 2π in u: the same 3-D points, an open uv loop."""
    b = Cylinder(1, 2).brep
    k = next(i for i, pc in enumerate(b.pcurves)
             if isinstance(pc, Line2D) and np.allclose(pc.origin, 0) and np.allclose(pc.direction, [1, 0]))

    def change(c):
        c["pcurves"][k] = Line2D([2 * math.pi, 0.0], [1.0, 0.0])

    bad = corrupted(b, change)
    assert "pcurve-deviation" not in codes(bad)
    return bad, "coedge", None


def case_non_planar_face():
    s = from_mesh(cube_points([0, 0, 0], [1, 1, 1]), CUBE_T, merge_coplanar=True)
    return corrupted(s.brep, lambda c: c["vertex_point"].__setitem__((7, 2), 1.001)), "face", None


def case_self_intersecting_trim():
    return plate_with_hole((3, 1), (5, 2)), "face", 0


def case_inward_shell():
    """A sphere turned inside out: every loop reversed (the sides of each edge swap, with their
    p-curves), every sense flipped — consistent, but enclosing negative volume."""
    b = Sphere(1).brep

    def change(c):
        twin = np.arange(2 * b.n_edges) ^ 1
        nxt, prv = b.coedge_prev[twin] ^ 1, b.coedge_next[twin] ^ 1  # the reversed cycles
        c["edge_loop"] = c["edge_loop"][:, ::-1].copy()
        c["edge_wing"] = np.stack([prv[0::2], nxt[0::2], prv[1::2], nxt[1::2]], axis=1)
        c["edge_pcurve"] = c["edge_pcurve"][:, ::-1].copy()
        c["loop_coedge"] = c["loop_coedge"] ^ 1
        c["face_sense"] = ~c["face_sense"]

    bad = corrupted(b, change)
    assert codes(bad) == {"inward-shell"}
    return bad, "shell", 0


def case_face_orientation():
    """One half-cylinder face's sense flipped: its loops now run clockwise about its outward normal."""
    b = Cylinder(1, 2).brep
    f = next(i for i in range(b.n_faces) if b.surfaces[int(b.face_surface[i])].surface_type == "cylinder")

    def change(c):
        c["face_sense"] = c["face_sense"].copy()
        c["face_sense"][f] = not c["face_sense"][f]

    return corrupted(b, change), "face", f


def case_outward_void():
    outer, inner = cube_points([0, 0, 0], [4, 4, 4]), cube_points([1, 1, 1], [3, 3, 3])
    return assemble_triangles([(outer, CUBE_T), (inner, CUBE_T)], nest=(0, 1)), "shell", 1


def case_nested_solids():
    """A cube inside a cube, both outward and each its own solid: the solids overlap."""
    outer, inner = cube_points([0, 0, 0], [4, 4, 4]), cube_points([1, 1, 1], [3, 3, 3])
    return assemble_triangles([(outer, CUBE_T), (inner, CUBE_T)]), "shell", 1


def case_void_outside():
    """An inward cube made a void of a cube it lies beside, not inside."""
    outer, void = cube_points([0, 0, 0], [4, 4, 4]), cube_points([5, 1, 1], [7, 3, 3])
    return assemble_triangles([(outer, CUBE_T), (void, [t[::-1] for t in CUBE_T])], nest=(0, 1)), "shell", 1


def case_shells_touch():
    """A slab spanning a cube wall to wall: every vertex of the slab lies on the cube's sides, so on
    which side of the cube it lies is not proven."""
    outer, slab = cube_points([0, 0, 0], [4, 4, 4]), cube_points([0, 0, 1], [4, 4, 3])
    return assemble_triangles([(outer, CUBE_T), (slab, CUBE_T)]), "brep", 0


class _OpaquePcurve:
    """A correct p-curve of a type the mass integrator does not know."""

    def __init__(self, pc):
        self.pc = pc

    def evaluate(self, t):
        return self.pc.evaluate(t)

    def derivatives(self, t, order=1):
        return self.pc.derivatives(t, order)


def case_orientation_unchecked():
    b = Cylinder(1, 2).brep  # its faces are integrated along their p-curves

    def change(c):
        c["pcurves"][0] = _OpaquePcurve(c["pcurves"][0])

    return corrupted(b, change), "brep", 0


CASES = {
    "dangling-pointer": case_dangling_pointer,
    "wing-mismatch": case_wing_mismatch,
    "loop-mismatch": case_loop_mismatch,
    "loop-not-connected": case_loop_not_connected,
    "loop-first-coedge": case_loop_first_coedge,
    "loop-split": case_loop_split,
    "empty-loop": case_empty_loop,
    "seam-edge": case_seam_edge,
    "non-manifold-vertex": case_non_manifold_vertex,
    "isolated-vertex": case_isolated_vertex,
    "shell-mismatch": case_shell_mismatch,
    "euler-poincare": case_euler_poincare,
    "vertex-off-edge": case_vertex_off_edge,
    "pcurve-deviation": case_pcurve_deviation,
    "pcurve-loop-open": case_pcurve_loop_open,
    "non-planar-face": case_non_planar_face,
    "self-intersecting-trim": case_self_intersecting_trim,
    "inward-shell": case_inward_shell,
    "outward-void": case_outward_void,
    "face-orientation": case_face_orientation,
    "orientation-unchecked": case_orientation_unchecked,
    "nested-solids": case_nested_solids,
    "void-outside": case_void_outside,
    "shells-touch": case_shells_touch,
}


@pytest.mark.parametrize("code", sorted(CASES))
def test_each_violation_is_found(code):
    brep, entity, index = CASES[code]()
    p = problem(brep, code)
    assert p.entity == entity
    if index is not None:
        assert p.index == index
    assert str(p).startswith(f"{code} [{entity} {p.index}]: ")
    assert not check(brep).ok


def test_every_code_of_the_checker_has_a_case():
    source = Path(check_module.__file__).read_text()
    written = set(re.findall(r'Problem\(\s*"([a-z-]+)"', source))
    assert written == set(CASES)


# ============================================================================ details of some checks
def test_topology_only_skips_the_geometric_checks():
    brep, _, _ = case_vertex_off_edge()
    assert check(brep, geometry=False).ok
    brep, _, _ = case_self_intersecting_trim()
    assert check(brep, geometry=False).ok


def test_pointer_problems_stop_before_the_other_checks():
    brep, _, _ = case_dangling_pointer()
    assert codes(brep) == {"dangling-pointer"}


def test_geometric_problems_suppress_the_orientation_check():
    brep, _, _ = case_vertex_off_edge()
    assert "inward-shell" not in codes(brep) and "outward-void" not in codes(brep)


def test_euler_message_gives_the_counts():
    brep, _, _ = case_euler_poincare()
    assert "V - E + F - (L - F) = 4 (V=8, E=12, F=8, L=8) is not 2(1 - G)" in problem(brep, "euler-poincare").message


def test_trim_crossing_is_located():
    p = problem(plate_with_hole((3, 1), (5, 2)), "self-intersecting-trim")
    assert re.search(r"edge \d+ of loop \d+ crosses edge \d+ of loop \d+ near \[", p.message)
    # Both the top (face 0) and the bottom (face 1) have the hole crossing their outer loop.
    report = check(plate_with_hole((3, 1), (5, 2)))
    assert {q.index for q in report.problems if q.code == "self-intersecting-trim"} == {0, 1}


def test_hole_inside_and_hole_touching_the_boundary_are_not_crossings():
    assert check(plate_with_hole((1, 1), (2, 3))).ok
    # Hole edges lying on the outer boundary (x = 4) touch it without crossing.
    assert "self-intersecting-trim" not in codes(plate_with_hole((3, 1), (4, 2)))


def test_crossing_trims_with_surfaces_and_pcurves_are_found():
    """The plate's faces on PlanarSurfaces with Line2D p-curves: the check samples p-curves in (u, v)."""
    def planar(specs):
        out = []
        for f in specs:
            P = np.array([e.curve.evaluate(e.t0) for e in f.loops[0]])
            n = np.cross(P - P[0], np.roll(P, -1, 0) - P[0]).sum(0)
            x = P[1] - P[0]
            S = PlanarSurface(P[0], n, x - np.dot(x, n) / np.dot(n, n) * n)
            X, Y = S.frame[0], S.frame[1]
            loops = [[EdgeSpec(e.curve, e.t0, e.t1,
                               Line2D(S.closest_parameters(e.curve.origin),
                                      [np.dot(e.curve.direction, X), np.dot(e.curve.direction, Y)]))
                      for e in loop] for loop in f.loops]
            out.append(FaceSpec(S, True, loops))
        return out

    good = sew_faces(planar(face_specs(plate_with_hole((1, 1), (2, 3)))))
    assert check(good).ok and good.brep.surfaces
    with pytest.raises(TopologyError, match=r"self-intersecting-trim \[face \d+\]"):
        sew_faces(planar(face_specs(plate_with_hole((3, 1), (5, 2)))))


def disc_with_hole(gap: float) -> list[FaceSpec]:
    """Face specs of a disc of radius 2 and height 1 with a round hole of radius 0.5 whose rim
    comes within ``gap`` of the disc's rim (negative: the hole crosses it), towards the angle
    π/16 where the disc's 9-sample polyline cuts the corner deepest (sagitta 0.038)."""
    R, r, th = 2.0, 0.5, math.pi / 16
    d = R - r - gap
    outer = face_specs(Cylinder(R, 1.0))
    inner = face_specs(Cylinder(r, 1.0).translate((d * math.cos(th), d * math.sin(th), 0.0)))

    def holed(face, hole):
        S = face.surface
        F = np.asarray(S.frame)[:2]
        uses = []
        for e in reversed(hole.loops[0]):
            X, Y, _ = e.curve.frame
            pc = Trig2D(F @ (e.curve.center - S.origin), e.curve.radius * (F @ X), e.curve.radius * (F @ Y))
            uses.append(EdgeSpec(e.curve, e.t1, e.t0, pc, e.tol))
        return FaceSpec(S, face.sense, [face.loops[0], uses])

    walls = [FaceSpec(f.surface, not f.sense, [[EdgeSpec(e.curve, e.t1, e.t0, e.pcurve, e.tol)
                                                 for e in reversed(f.loops[0])]]) for f in inner[2:]]
    return [holed(outer[0], inner[0]), holed(outer[1], inner[1])] + outer[2:] + walls


def test_hole_grazing_a_curved_rim_is_not_a_crossing(monkeypatch):
    """A hole 0.01 inside the rim: the coarse chords cross (the sagitta is 0.038), the curves do not."""
    solid = sew_faces(disc_with_hole(0.01))
    assert check(solid).ok
    assert math.isclose(solid.volume, math.pi * (4.0 - 0.25), rel_tol=1e-12)
    # Without the refinement the coarse polylines report the false crossing (the case is a real test).
    monkeypatch.setattr(check_module, "_REFINE_LEVELS", 0)
    monkeypatch.setattr(check_module, "_DENSE_ENDS", np.empty(0))
    assert {p.index for p in check(solid).problems if p.code == "self-intersecting-trim"} == {0, 1}


def test_hole_crossing_a_curved_rim_is_found():
    with pytest.raises(TopologyError, match=r"self-intersecting-trim \[face 0\]: edge \d+ of loop \d+ crosses"):
        sew_faces(disc_with_hole(-0.02))


def test_report_api():
    report = check(Box(1, 2, 3))
    assert isinstance(report, CheckReport) and report.ok and bool(report) and report.summary() == "valid"
    assert report.counts == {"vertices": 8, "edges": 12, "loops": 6, "faces": 6, "shells": 1, "solids": 1}
    bad = check(case_wing_mismatch()[0])
    assert not bad and "wing-mismatch" in bad.summary()
    many = CheckReport(tuple(Problem("x", "edge", i, "m") for i in range(25)))
    assert many.summary(limit=3).endswith("... and 22 more")


# ============================================================================ valid shapes are clean
@pytest.mark.parametrize(
    "make",
    [
        lambda: Box(1, 2, 3),
        lambda: Cylinder(1, 2),
        lambda: Cone(1, 0.5, 2),
        lambda: Cone(1, 0, 2),
        lambda: Sphere(1),
        lambda: Torus(3, 1),
        lambda: Torus(3, 1).mirror(),
        lambda: from_mesh(trimesh.creation.icosphere(subdivisions=4)),
        lambda: from_mesh(trimesh.creation.torus(major_radius=3, minor_radius=1), merge_coplanar=True),
        lambda: from_mesh(trimesh.creation.cylinder(radius=1, height=2, sections=32), merge_coplanar=True),
    ],
)
def test_valid_shapes_are_clean(make):
    report = check(make())
    assert report.ok, report.summary()


def test_implicit_faces_with_curved_edges_are_sampled():
    """A cylinder whose disks are implicit planes (no surface, no p-curves) bounded by circle arcs."""
    specs = face_specs(Cylinder(1, 2))
    implicit = [FaceSpec(None, True, [[EdgeSpec(e.curve, e.t0, e.t1, None, e.tol) for e in l] for l in f.loops])
                if isinstance(f.surface, PlanarSurface) else f for f in specs]
    solid = sew_faces(implicit)
    assert (solid.brep.face_surface < 0).sum() == 2
    assert check(solid).ok
    np.testing.assert_allclose(solid.volume, 2 * math.pi, rtol=1e-9)
    # The trim polyline of a disk in its Newell plane: two arcs of 9 samples, each shared end kept once.
    from coons.topology.check import _face_segments
    from coons.tolerance import DEFAULT_TOLERANCE

    f = int(np.flatnonzero(solid.brep.face_surface < 0)[0])
    A, B, face, nxt, coedge, eps = _face_segments(solid.brep, f, 9, DEFAULT_TOLERANCE)
    assert A.shape == (16, 2) and np.all(face == f) and np.all(eps == DEFAULT_TOLERANCE.linear)
    np.testing.assert_allclose(np.linalg.norm(A - A.mean(axis=0), axis=1), 1.0, rtol=1e-12)  # on the unit circle


def test_cycle_lengths_of_random_permutations():
    """Pointer doubling against the components of the permutation graph (scipy)."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    rng = np.random.default_rng(7)
    for n in (1, 2, 3, 17, 1000):
        for _ in range(5):
            p = rng.permutation(n)
            g = coo_matrix((np.ones(n), (np.arange(n), p)), shape=(n, n))
            _, label = connected_components(g, directed=True, connection="weak")
            np.testing.assert_array_equal(check_module._cycle_lengths(p), np.bincount(label)[label])


def test_cycle_lengths_at_starts_agree_with_pointer_doubling():
    """The bounded walks (and their pointer-doubling tail for long cycles) against _cycle_lengths."""
    rng = np.random.default_rng(11)
    for sizes in ([3] * 40, [1, 2, 3, 5, 8, 13, 40, 200], list(rng.integers(1, 30, 60))):
        group = np.repeat(np.arange(len(sizes)), sizes)
        n = group.size
        perm = np.empty(n, dtype=np.int64)
        ptr = np.concatenate([[0], np.cumsum(sizes)])
        for g in range(len(sizes)):  # a random permutation inside each group (often several cycles)
            perm[ptr[g] : ptr[g + 1]] = ptr[g] + rng.permutation(sizes[g])
        order = rng.permutation(n)  # scatter the groups over the ids
        inv = np.empty(n, dtype=np.int64)
        inv[order] = np.arange(n)
        perm, group = inv[perm[order]], group[order]
        start = rng.integers(0, n, 50)
        expected = np.bincount(group)[group[start]]
        np.testing.assert_array_equal(check_module._cycle_lengths_at(perm, start, group, expected),
                                      check_module._cycle_lengths(perm)[start])


def test_cycle_lengths_at_flags_a_group_that_perm_leaves():
    """A permutation that does not keep the groups (never expected from the checked tables) still gets
    true lengths for cycles closing within the walk, and the whole-permutation doubling for the rest."""
    n = 40
    perm = np.roll(np.arange(n), 1)  # one cycle of 40 through two groups of 20
    group = np.repeat([0, 1], 20)
    out = check_module._cycle_lengths_at(perm, np.array([0, 25]), group, np.array([40, 40]))
    np.testing.assert_array_equal(out, [40, 40])
    out = check_module._cycle_lengths_at(perm, np.array([0]), group, np.array([20]))
    assert out[0] != 20  # the group of 20 does not hold the cycle: reported as a mismatch


def test_batched_edge_samples_equal_per_curve_evaluation():
    # Lines and circles are sampled in one array expression; the points must be the very floats
    # of each curve's own evaluate (as the per-curve loop produced them).
    from coons.topology.check import _edge_samples
    from coons.topology.profile import Profile
    from coons.topology.sweep import extrude

    holes = [Profile.circle(0.3 + 0.1 * i, center=(-3.0 + 1.5 * i, 0.2 * i)).outer for i in range(4)]
    shapes = [extrude(Profile(Profile.rectangle(9.0, 4.0).outer, holes), 2.0), Sphere(2.0), Torus(3.0, 1.0),
              Cylinder(1.0, 2.0), Cone(1.0, 0.5, 2.0)]
    for shape in shapes:
        b = shape.brep
        for samples in (2, 7, 16):
            T, P = _edge_samples(b, samples)
            for e in range(b.n_edges):
                ci = int(b.edge_curve[e])
                if ci >= 0:
                    np.testing.assert_array_equal(P[e], b.curves[ci].evaluate(T[e]))


def test_bulk_assemble_equals_per_vertex_assemble(monkeypatch):
    # BRepBuilder.assemble adds the vertices, edges and coedge links in bulk; forcing the per-vertex
    # and per-coedge paths must give the same tables row for row.
    import coons.topology.builder as builder_module

    shape = sew_faces(face_specs(Box(1, 2, 3)) + face_specs(Sphere(0.3).translate((3, 0, 0)).brep))  # two lumps
    def tables():
        specs = face_specs(shape)
        return sew_faces(specs).brep
    fast = tables()

    class Shim:  # numpy as the builder module sees it, refusing the bulk path's finiteness test
        def __getattr__(self, name):
            return getattr(np, name)

        @staticmethod
        def isfinite(x, *a, **k):
            out = np.isfinite(x, *a, **k)
            return np.zeros_like(out) if np.ndim(x) == 2 and np.shape(x)[-1] == 3 else out

    monkeypatch.setattr(builder_module, "np", Shim())
    monkeypatch.setattr(BRepBuilder, "_assemble_loops_bulk", lambda *a, **k: None)  # loops one coedge at a time
    slow = tables()
    monkeypatch.undo()
    import dataclasses as dc

    for fld in dc.fields(fast):
        a, b = getattr(fast, fld.name), getattr(slow, fld.name)
        if isinstance(a, np.ndarray):
            np.testing.assert_array_equal(a, b, err_msg=fld.name)
    assert fast.n_shells == 2


# ============================================================================ remembered measurements
def _shifted_curve(b: BRep, offset: float, tol: float) -> BRep:
    """``b`` with the 3-D line of edge 0 moved by ``offset`` across itself and that edge's tolerance ``tol``."""
    from coons.kernel.analytic import Line

    cols = columns(b)
    line = cols["curves"][int(cols["edge_curve"][0])]
    assert isinstance(line, Line)
    across = np.cross(line.direction, [0.3, 0.5, 0.7])
    cols["curves"].append(Line(line.origin + offset * across / np.linalg.norm(across), line.direction))
    cols["edge_curve"][0] = len(cols["curves"]) - 1
    cols["edge_tol"][0] = tol
    return BRep(**cols)


def test_geometry_check_remembers_measurements_not_verdicts():
    """A coedge measured before (same curve, p-curve, surface and range: a face a Boolean passes
    through unchanged) takes its measurements from the memo, never its verdict: a later B-rep with
    the same geometry and a smaller edge tolerance is still reported."""
    from coons.topology import _memo
    from coons.topology.check import _SAME_PARAMETER, _check_geometry
    from coons.tolerance import DEFAULT_TOLERANCE as T

    _memo.clear_all()
    loose = _shifted_curve(Box(1, 2, 3).brep, 1e-4, 1e-3)
    assert check(loose).ok
    assert len(_SAME_PARAMETER) == len(loose.pcurves)  # every coedge measured and remembered
    tight = dataclasses.replace(loose, edge_tol=np.where(np.arange(loose.n_edges) == 0, 1e-6, loose.edge_tol))
    warm = _check_geometry(tight, T, 9, out := [])
    assert {p.code for p in out} == {"vertex-off-edge", "pcurve-deviation"} and {p.index for p in out} == {0}
    _memo.clear_all()
    cold = _check_geometry(tight, T, 9, out_cold := [])
    assert [str(p) for p in out] == [str(p) for p in out_cold]
    for name in ("coedge", "uv", "speed", "line", "pos"):
        np.testing.assert_array_equal(getattr(warm, name), getattr(cold, name), err_msg=name)


@pytest.mark.parametrize("make", [lambda: Cylinder(1.0, 2.0), lambda: Sphere(1.5), lambda: Torus(3.0, 1.0),
                                  lambda: Cone(1.0, 0.5, 2.0)])
def test_geometry_check_with_remembered_measurements_equals_a_cold_check(make):
    """Half the coedges remembered (a B-rep measured before and one moved vertex apart), the other
    half measured: the same table and problems as a cold check, and a moved vertex is still found."""
    from coons.topology import _memo
    from coons.topology.check import _check_geometry
    from coons.tolerance import DEFAULT_TOLERANCE as T

    b = make().brep
    _memo.clear_all()
    assert check(b).ok
    moved = corrupted(b, lambda c: c["vertex_point"].__setitem__(0, c["vertex_point"][0] + 1e-3))
    warm = _check_geometry(moved, T, 9, out := [])
    _memo.clear_all()
    cold = _check_geometry(moved, T, 9, out_cold := [])
    assert [str(p) for p in out] == [str(p) for p in out_cold] and "vertex-off-edge" in {p.code for p in out}
    for name in ("coedge", "uv", "speed", "line", "pos"):
        np.testing.assert_array_equal(getattr(warm, name), getattr(cold, name), err_msg=name)


def test_identity_memo_forgets_dead_objects_and_takes_only_values():
    from coons.topology._memo import IdentityMemo, clear_all, is_value

    memo = IdentityMemo()
    line = Line2D([0.0, 0.0], [1.0, 0.0])
    memo.set(line, 1)
    assert memo.get(line) == 1 and memo.get_many([line, Line2D([0.0, 0.0], [1.0, 0.0])]) == [1, None]
    assert memo.setdefault(line, lambda: 2) == 1
    del line
    import gc

    gc.collect()
    assert len(memo) == 0  # the entry died with its p-curve
    assert is_value(Line2D([0.0, 0.0], [1.0, 0.0])) and not is_value([1.0])
    with pytest.raises(TypeError, match="immutable values"):
        memo.set([1.0], 3)
    other = Line2D([0.0, 1.0], [1.0, 0.0])
    memo.set(other, 4)
    clear_all()
    assert memo.get(other) is None


def test_last_record_keeps_one_record_of_a_living_object():
    import gc

    from coons.topology._memo import clear_all

    rec = LastRecord()
    a, b = Line2D([0.0, 0.0], [1.0, 0.0]), Line2D([0.0, 1.0], [1.0, 0.0])
    assert rec.last() is None
    rec.keep(a, "of a")
    assert rec.last() == "of a" and rec.get(a) == "of a"
    rec.keep(b, "of b")  # one record: a's is gone
    assert rec.last() == "of b" and rec.get(a) is None and len(rec) == 1
    del b
    gc.collect()
    assert rec.last() is None and len(rec) == 0  # died with its object
    rec.keep(a, "again")
    clear_all()
    assert rec.last() is None
    with pytest.raises(TypeError, match="immutable values"):
        rec.keep([1.0], "list")


def test_segment_pairs_are_the_sweep_pairs_of_loops_that_can_meet():
    """The loop-aware broad phase of the trim check: the pairs of the plain sweep whose loops are one
    or have overlapping boxes, in the sweep's order (so the first crossing of each face is the same)."""
    from coons.topology.check import _cycle_labels, _segment_pairs, _sweep_pairs

    rng = np.random.default_rng(7)
    for trial in range(30):
        A, nxt, face = [], [], []
        n = 0
        for f in range(int(rng.integers(1, 4))):
            for _ in range(int(rng.integers(1, 6))):  # loops: jittered polygons of random size and place
                m = int(rng.integers(3, 12))
                c = rng.uniform(-5, 5, 2)
                r = rng.uniform(0.2, 3.0)
                ang = np.sort(rng.uniform(0, 2 * np.pi, m))
                A.append(c + r * np.stack([np.cos(ang), np.sin(ang)], axis=1) + rng.normal(0, 0.3, (m, 2)))
                nxt.append(n + (np.arange(m) + 1) % m)
                face.append(np.full(m, f))
                n += m
        A, nxt, face = np.concatenate(A), np.concatenate(nxt), np.concatenate(face)
        B = A[nxt]
        i, j = _sweep_pairs(A, B, face)
        ring = _cycle_labels(nxt)
        lo, hi = np.minimum(A, B), np.maximum(A, B)
        rlo = {r: lo[ring == r].min(axis=0) for r in np.unique(ring)}
        rhi = {r: hi[ring == r].max(axis=0) for r in np.unique(ring)}
        meet = np.array([ring[a] == ring[b] or bool(np.all(np.maximum(rlo[ring[a]], rlo[ring[b]])
                                                            <= np.minimum(rhi[ring[a]], rhi[ring[b]])))
                         for a, b in zip(i.tolist(), j.tolist())], dtype=bool)
        gi, gj = _segment_pairs(A, B, face, nxt, chunk=int(rng.integers(1, 50)))
        np.testing.assert_array_equal(gi, i[meet])
        np.testing.assert_array_equal(gj, j[meet])


def test_plate_with_many_holes_checks_clean_and_finds_a_crossing_hole():
    """Many loops in one face (the trim check's loop-aware broad phase): clean, and a hole moved onto
    its neighbour is found."""
    from coons.topology.profile import Profile
    from coons.topology.sweep import extrude

    holes = [Profile.circle(0.6, center=(-4.0 + 2.0 * i, -4.0 + 2.0 * k)).outer for i in range(5) for k in range(5)]
    ok = extrude(Profile(Profile.rectangle(12.0, 12.0).outer, holes), 1.0)
    assert check(ok).ok
    b = ok.brep
    cap = int(np.argmax(np.diff(b.face_loop_ptr)))  # a cap: the face with all the holes
    hole = int(b.face_loops[b.face_loop_ptr[cap] + 8])

    def move_hole(c):  # the p-curves of one hole of the cap, 1.0 towards its neighbour (radius 0.6)
        for co in b.loop_coedges(hole).tolist():
            e, side = co >> 1, co & 1
            pc = c["pcurves"][int(c["edge_pcurve"][e, side])]
            shift = np.array([1.0, 0.0])
            moved = Trig2D(pc.center + shift, pc.a, pc.b) if isinstance(pc, Trig2D) else Line2D(pc.origin + shift, pc.direction)
            c["pcurves"].append(moved)
            c["edge_pcurve"][e, side] = len(c["pcurves"]) - 1

    assert "self-intersecting-trim" in codes(corrupted(b, move_hole))


def test_value_faces_are_the_faces_whose_uses_are_all_values():
    # _remember_trims records a face only when its curves and p-curves are values (what the record
    # depends on cannot change); _value_faces reads that from the pools, per coedge.
    from coons.topology.check import _value_faces

    class Opaque:  # not a frozen dataclass: not a value
        def evaluate(self, t):
            return t

    b = (Box(4, 4, 2) - Cylinder(1.0, 5.0)).brep
    assert _value_faces(b).all()
    k = int(b.edge_pcurve[0, 1])
    pcurves = list(b.pcurves)
    pcurves[k] = Opaque()
    c = dataclasses.replace(b, pcurves=tuple(pcurves))
    e, side = np.nonzero(c.edge_pcurve == k)
    expect = np.ones(c.n_faces, dtype=bool)
    expect[c.edge_face[e, side]] = False
    np.testing.assert_array_equal(_value_faces(c), expect)
    assert not expect.all()
    no_curve = dataclasses.replace(b, edge_curve=np.where(np.arange(b.n_edges) == 0, -1, b.edge_curve))
    assert not _value_faces(no_curve)[b.edge_face[0]].any()


def test_trim_checks_of_faces_that_passed_before_are_not_repeated(monkeypatch):
    """A face sewn unchanged from a spec whose face passed the trim checks in an earlier clean
    check (same tolerance and samples) is not checked again; any other face is: a new spec, a
    face the sewing changed (a wider tolerance on a shared edge), another tolerance or samples."""
    from coons.tolerance import Tolerance
    from coons.topology.check import _SEWN_FROM

    seen: list[set[int]] = []
    real = check_module._sampled_rings

    def spy(b, cross_faces, sense_faces, *args):
        seen.append(set(cross_faces.tolist()) | set(sense_faces.tolist()))
        return real(b, cross_faces, sense_faces, *args)

    monkeypatch.setattr(check_module, "_sampled_rings", spy)
    specs = face_specs(Cylinder(1.0, 2.0)) + face_specs(Box(1, 1, 1).translate((5.0, 0.0, 0.0)))
    F = len(specs)
    first = sew_faces(specs).brep
    assert seen[-1] == set(range(F))  # nothing passed before
    again = sew_faces(specs).brep
    assert _SEWN_FROM[again][1].all()
    assert seen[-1] == set()  # every face passed in the first check
    assert check(again).ok and seen[-1] == set()
    assert check(again, samples=17).ok and seen[-1] == set(range(F))  # other samples: checked
    assert check(again, Tolerance(linear=2e-7)).ok and seen[-1] == set(range(F))  # other tolerance
    # A wider tolerance on one use: its face is a new spec (whose use keeps its own tolerance, the
    # edge's), and the face across the edge is no longer unchanged (its use's tolerance is not).
    i = len(face_specs(Cylinder(1.0, 2.0)))
    e = specs[i].loops[0][0]
    mixed = list(specs)
    mixed[i] = FaceSpec(specs[i].surface, specs[i].sense,
                        [[EdgeSpec(e.curve, e.t0, e.t1, e.pcurve, (e.tol or 0.0) + 1e-6)] + list(specs[i].loops[0][1:])])
    third = sew_faces(mixed).brep
    changed = set(np.flatnonzero(~_SEWN_FROM[third][1]).tolist())
    assert len(changed) == 1 and i not in changed
    assert seen[-1] == changed | {i}
    # A B-rep not made by sewing is checked whole.
    assert check(first).ok and seen[-1] == set()  # (first was sewn: its record stands)
    assert check(Cylinder(1.0, 2.0)).ok and len(seen[-1]) == 4


def _rings_segments(centres, n=12, r=0.3):
    """Closed polygons (one ring each) around ``centres`` as the segment arrays of the trim checks."""
    A, B, nxt, face = [], [], [], []
    k = 0
    for cx, cy in centres:
        a = np.linspace(0.0, 2 * np.pi, n, endpoint=False)
        P = np.stack([cx + r * np.cos(a), cy + r * np.sin(a)], axis=1)
        A.append(P)
        B.append(np.roll(P, -1, axis=0))
        nxt.append(k + (np.arange(n) + 1) % n)
        face.append(np.zeros(n, dtype=np.int64))
        k += n
    return np.concatenate(A), np.concatenate(B), np.concatenate(face), np.concatenate(nxt)


@pytest.mark.parametrize("grid", [(2, 2), (4, 12)])  # the sweep over the face, and loop by loop
def test_segment_pairs_leave_out_exactly_the_pairs_of_old_loops(grid):
    from coons.topology.check import _segment_pairs

    rng = np.random.default_rng(3)
    nx, ny = grid
    centres = [(i + 0.2 * rng.random(), 0.5 * j + 0.2 * rng.random()) for i in range(nx) for j in range(ny)]
    centres.append(centres[0])  # a ring on top of another: its segments cross that one's
    A, B, face, nxt = _rings_segments(centres)
    ring = np.repeat(np.arange(len(centres)), 12)
    old = ring < len(centres) // 2
    i0, j0 = _segment_pairs(A, B, face, nxt)
    i1, j1 = _segment_pairs(A, B, face, nxt, old=old)
    full = set(zip(i0.tolist(), j0.tolist()))
    assert set(zip(i1.tolist(), j1.tolist())) == {(i, j) for i, j in full if not (old[i] and old[j])}
    assert len(full) > len(set(zip(i1.tolist(), j1.tolist())))  # some pairs were left out


@pytest.mark.parametrize("seed", range(6))
def test_old_loops_far_from_the_new_ones_are_dropped_without_losing_a_crossing(seed):
    # _near_new_loops drops the old loops whose widened box misses the new segments of their
    # face: the faces with a crossing between an old and a new loop (or two new ones) are the
    # same as with every loop, and only loops that cannot meet a new one are dropped.
    import types

    from coons.topology.check import _crossings, _near_new_loops

    rng = np.random.default_rng(seed)
    centres = [(i + 0.2 * rng.random(), 0.8 * j + 0.2 * rng.random()) for i in range(5) for j in range(4)]
    k = len(centres)
    new_at = [tuple(rng.random(2) * (4.0, 2.4)) for _ in range(2)]  # may cross some old rings, or not
    A, B, face, nxt = _rings_segments(centres + new_at)
    face = np.repeat(np.arange(len(centres) + 2) % 2, 12)  # two faces, loops alternating between them
    loop = np.repeat(np.arange(len(centres) + 2), 12)
    b = types.SimpleNamespace(coedge_loop=loop, n_faces=2, n_loops=len(centres) + 2,
                              loop_face=np.arange(len(centres) + 2) % 2)
    coedge = np.arange(A.shape[0])
    eps = np.full(A.shape[0], 1e-9)
    part = (A, B, face, nxt, coedge, eps)
    old_loop = np.arange(len(centres) + 2) < k
    near = _near_new_loops(b, part, old_loop)
    assert near[0].shape[0] < A.shape[0]  # far rings dropped
    kept = np.unique(loop[near[4]])
    assert set(range(k, k + 2)) <= set(kept.tolist())  # the new loops stay whole
    np.testing.assert_array_equal(np.bincount(loop[near[4]])[kept], 12)  # loops dropped whole, rings closed
    np.testing.assert_array_equal(loop[near[4]][near[3]], loop[near[4]])
    full = _crossings([part], old_loop[loop])
    assert set(_crossings([near], old_loop[loop]).keys()) == set(full.keys())
    lo, hi = np.minimum(A, B), np.maximum(A, B)
    for lp in set(range(k)) - set(kept.tolist()):  # a dropped loop's box misses its face's new loops
        mine, theirs = loop == lp, (loop >= k) & (face == face[loop == lp][0])
        apart = (lo[mine].min(axis=0) > hi[theirs].max(axis=0)) | (hi[mine].max(axis=0) < lo[theirs].min(axis=0))
        assert apart.any()


def test_a_face_gaining_loops_has_only_its_new_loops_tested(monkeypatch):
    """Sequential cuts into a plate: once its top and bottom faces passed with 16 or more loops, a
    cut tests only the pairs involving the new hole (the rest were tested in the spec it extends),
    and the results stay valid with the exact volume."""
    from coons.topology.primitives import Cylinder as Cyl

    calls = []
    segments, tested = [], []
    real = check_module._crossings

    def spy(parts, old_coedge=None):
        calls.append(None if old_coedge is None else int(old_coedge.sum()))
        segments.append(sum(p[0].shape[0] for p in parts))
        return real(parts, old_coedge)

    monkeypatch.setattr(check_module, "_crossings", spy)
    plate = Box(60, 50, 4)
    holes = [(-25.0 + 10 * i, -20.0 + 10 * j, 0.0) for i in range(6) for j in range(5)]
    for k, at in enumerate(holes):
        tool = Cyl(1.0, 10.0).translate(at)
        calls.clear()
        segments.clear()
        plate = plate - tool
        assert len(calls) == 1  # the result's check
        tested.append(segments[0])
        # After k cuts the top has k + 1 loops: from _PREFIX_LOOPS on it is recorded, and the
        # next cut extends it.
        if k >= check_module._PREFIX_LOOPS:
            assert calls[0] is not None and calls[0] > 0  # old loops' coedges left out
        if k < check_module._PREFIX_LOOPS - 1:
            assert calls[0] is None
    # The old holes far from the new one are not even passed to the pair search (_near_new_loops):
    # the segments tested stop growing with the holes.
    assert tested[-1] < tested[check_module._PREFIX_LOOPS - 2] / 4
    assert check(plate).ok
    assert math.isclose(plate.volume, 60 * 50 * 4 - len(holes) * math.pi * 4, rel_tol=1e-12)


def test_faces_passed_found_through_the_last_clean_check_equal_the_per_spec_look_up(monkeypatch):
    """_trims_passed finds the specs the last clean check recorded in one array pass
    (_PASSED_FACES); the faces passed and extended are those of looking every spec up."""
    from coons.topology.primitives import Cylinder as Cyl

    real = check_module._trims_passed
    memo = check_module._TRIMS_PASSED
    real_get_many = memo.get_many
    compared, looked_up = [], []

    def get_many(objs):
        objs = list(objs)
        looked_up.append(len(objs))
        return real_get_many(objs)

    def spy(b, known, t, samples, found=None):
        looked_up.clear()
        passed, extends = real(b, known, t, samples, found)
        fast = looked_up[0]
        kept = check_module._PASSED_FACES
        check_module._PASSED_FACES = LastRecord()  # no record: every spec looked up
        try:
            again, extends_again = real(b, known, t, samples)
        finally:
            check_module._PASSED_FACES = kept
        np.testing.assert_array_equal(passed, again)
        assert extends == extends_again
        compared.append((int(passed.sum()), fast, looked_up[1]))
        return passed, extends

    monkeypatch.setattr(check_module, "_trims_passed", spy)
    monkeypatch.setattr(memo, "get_many", get_many)
    plate = Box(60, 50, 4)
    for k in range(20):
        plate = plate - Cyl(1.0, 10.0).translate((-25.0 + 10 * (k % 6), -20.0 + 10 * (k // 6), 0.0))
    assert len(compared) >= 20
    n_passed, fast, slow = compared[-1]
    assert n_passed > 10 and fast < slow / 4  # most faces passed before, found without a look-up each
    # The same B-rep checked again: its own record is the last one, and serves as well.
    assert check(plate).ok
    again, fast, slow = compared[-1]
    assert len(compared) >= 21 and again >= n_passed and fast < slow / 4
    assert check(plate).ok


def test_coedges_of_faces_that_passed_before_are_not_measured_again(monkeypatch):
    """The same-parameter comparisons of a face that passed as the same spec are not repeated
    (only its edges' ends are compared with the vertices again); a new face's coedges are."""
    measured = []
    real = check_module._cached_samples

    def spy(b, pi, *args):
        measured.append(int(pi.size))
        return real(b, pi, *args)

    monkeypatch.setattr(check_module, "_cached_samples", spy)
    specs = face_specs(Cylinder(1.0, 2.0)) + face_specs(Box(1, 1, 1).translate((5.0, 0.0, 0.0)))
    sew_faces(specs)
    first = measured[-1]
    again = sew_faces(specs)
    assert first > 0 and measured[-1] == 0
    assert check(again).ok and measured[-1] == 0
    assert check(again, samples=17).ok and measured[-1] == first  # another key: measured whole


def _spy_cached_samples(monkeypatch) -> list:
    """Record ``(coedges asked, coedges found)`` of every ``_cached_samples`` call of the check."""
    found = []
    real = check_module._cached_samples

    def spy(b, pi, *args):
        idx, H = real(b, pi, *args)
        found.append((int(pi.size), int(idx.size)))
        return idx, H

    monkeypatch.setattr(check_module, "_cached_samples", spy)
    return found


def test_measurements_carried_from_the_last_checked_brep_equal_a_cold_check(monkeypatch):
    """A Boolean's result takes the same-parameter rows of the coedges it shares with the B-rep
    checked last (its operand) in one gather (``_MEASURED``): the same table and problems as a cold
    check, with most rows found there."""
    from coons.topology import _memo
    from coons.topology.check import _check_geometry
    from coons.tolerance import DEFAULT_TOLERANCE as T

    _memo.clear_all()
    one = Box(20.0, 20.0, 4.0) - Cylinder(1.0, 10.0).translate((4.0, 0.0, -3.0))
    two = one - Cylinder(1.0, 10.0).translate((-4.0, 0.0, -3.0))
    _check_geometry(one.brep, T, 9, [])  # one is the B-rep measured last, every coedge of it
    found = _spy_cached_samples(monkeypatch)
    check_module._SAME_PARAMETER.clear()  # only the carried rows remain
    edges = np.flatnonzero(two.brep.edge_curve >= 0)
    evaluated = []
    real_samples = check_module._edge_samples
    monkeypatch.setattr(check_module, "_edge_samples",
                        lambda b, n, e: (evaluated.append(e.size), real_samples(b, n, e))[1])
    ends = check_module._edge_ends(two.brep, edges)  # the curve ends, most carried
    assert 0 < sum(evaluated) < edges.size  # the new hole's edges are evaluated, the others carried
    np.testing.assert_array_equal(ends, real_samples(two.brep, 2, edges)[1])
    warm = _check_geometry(two.brep, T, 9, out := [])
    n, hits = found[-1]
    assert 0 < hits < n  # the new hole's coedges are measured
    _memo.clear_all()
    cold = _check_geometry(two.brep, T, 9, out_cold := [])
    assert found[-1][1] == 0
    assert out == out_cold == []
    for name in ("coedge", "uv", "speed", "line", "pos"):
        np.testing.assert_array_equal(getattr(warm, name), getattr(cold, name), err_msg=name)


def test_a_check_with_one_sample_does_not_poison_the_next_check():
    # One sample is the curve's start only: the ends recorded by such a check must not stand for the
    # curve ends of the next B-rep checked (a Boolean's result sharing its edges).
    from coons.topology import _memo

    _memo.clear_all()
    one = Box(20.0, 20.0, 4.0) - Cylinder(1.0, 10.0).translate((4.0, 0.0, -3.0))
    two = one - Cylinder(1.0, 10.0).translate((-4.0, 0.0, -3.0))
    assert check(one).ok
    check(one, samples=1)
    warm = check(two)
    _memo.clear_all()
    cold = check(two)
    assert cold.ok and warm.ok, [p.message for p in warm.problems]


def test_mass_tables_gathered_from_the_operand_equal_cold_ones():
    from coons.topology import _memo, mass

    _memo.clear_all()
    one = Box(20.0, 20.0, 4.0) - Cylinder(1.0, 10.0).translate((4.0, 0.0, -3.0))
    two = one - Cylinder(1.0, 10.0).translate((-4.0, 0.0, -3.0))
    _memo.clear_all()  # (the Boolean tabled its result while checking it)
    mass._CACHE.clear()
    mass._DONOR[:] = [None, None]
    mass._tables(one.brep)
    assert mass._DONOR[1]() is one.brep  # the last tabled: the donor of the next
    shared = [int((mass.pool_positions(two.brep, one.brep, name) >= 0).sum()) for name in ("surfaces", "pcurves")]
    assert min(shared) > 0
    # Only the gather from one's tables can supply the shared rows now (the per-object memos are empty).
    mass._SURFACE_ROWS.clear()
    mass._PCURVE_ROWS.clear()
    made = {"surfaces": 0, "pcurves": 0}
    real_s, real_p = mass._surface_rows, mass._pcurve_rows

    def surface_rows(objs):
        made["surfaces"] += len(objs)
        return real_s(objs)

    def pcurve_rows(objs):
        made["pcurves"] += len(objs)
        return real_p(objs)

    mass._surface_rows, mass._pcurve_rows = surface_rows, pcurve_rows
    try:
        warm = mass._tables(two.brep)
    finally:
        mass._surface_rows, mass._pcurve_rows = real_s, real_p
    for name, k in zip(("surfaces", "pcurves"), shared):
        assert made[name] <= len(getattr(two.brep, name)) - k, name
    _memo.clear_all()
    mass._CACHE.clear()
    mass._DONOR[:] = [None, None]
    cold = mass._tables(two.brep)
    assert warm is not cold
    for name in ("surface_code", "surface_rows", "flat_nurbs", "has_planes", "curved_edge", "curved_face",
                 "implicit_curved", "pcurve_shape", "pcurve_coef"):
        np.testing.assert_array_equal(getattr(warm, name), getattr(cold, name), err_msg=name)


def test_pool_positions_match_objects_by_identity_and_skip_non_values():
    from coons.topology._memo import pool_positions

    @dataclasses.dataclass(frozen=True, eq=False)
    class Pools:
        curves: tuple

    class Mutable:
        pass

    a, b, c, m = Line2D((0.0, 0.0), (1.0, 0.0)), Line2D((0.0, 0.0), (1.0, 0.0)), Line2D((1.0, 0.0), (0.0, 1.0)), Mutable()
    donor = Pools((c, m, a))
    new = Pools((a, b, m, c))  # b equals a but is another object; m is not a value
    np.testing.assert_array_equal(pool_positions(new, donor, "curves"), [2, -1, -1, 0])
    assert pool_positions(new, Pools(()), "curves").tolist() == [-1, -1, -1, -1]


def _cap_with_holes(n_holes: int, moved: bool = False):
    """An extruded plate with ``n_holes`` holes of radius 0.6 on a 2.0 grid (the last one moved 1.0
    onto its neighbour when ``moved``), and its cap (the face with the holes)."""
    from coons.topology.profile import Profile
    from coons.topology.sweep import extrude

    centres = [(-4.0 + 2.0 * i, -4.0 + 2.0 * k) for i in range(5) for k in range(5)][:n_holes]
    holes = [Profile.circle(0.6, center=c).outer for c in centres]
    b = extrude(Profile(Profile.rectangle(12.0, 12.0).outer, holes), 1.0).brep
    cap = int(np.argmax(np.diff(b.face_loop_ptr)))
    if moved:
        hole = int(b.face_loops[b.face_loop_ptr[cap + 1] - 1])  # the last loop: the last hole

        def move(c):
            for co in b.loop_coedges(hole).tolist():
                e, side = co >> 1, co & 1
                pc = c["pcurves"][int(c["edge_pcurve"][e, side])]
                shift = np.array([-1.0, 0.0]) if b.surfaces[int(b.face_surface[cap])].frame[0, 0] > 0 else np.array([1.0, 0.0])
                moved_pc = (Trig2D(pc.center + shift, pc.a, pc.b) if isinstance(pc, Trig2D)
                            else Line2D(pc.origin + shift, pc.direction))
                c["pcurves"].append(moved_pc)
                c["edge_pcurve"][e, side] = len(c["pcurves"]) - 1

        b = corrupted(b, move)
    return b, cap


def test_rings_of_a_face_extending_a_passed_one_give_the_segments_and_orientation_of_all_its_rings():
    """_sampled_rings with ``partial``: the old loops come from their recorded sums (area, scale,
    stretch, loop boxes), only the old loops near the new ones are made into rings; after
    _near_new_loops the segments are those of the rings of all loops, the orientation sums agree
    (the area to round-off), and a new loop crossing an old one is found."""
    from coons.tolerance import resolve

    t = resolve(None)
    old_b, old_cap = _cap_with_holes(24)
    sums_old: dict = {}
    table = check_module._check_geometry(old_b, t, 9, [])
    check_module._sampled_rings(old_b, np.array([old_cap]), np.empty(0, dtype=np.int64), table, 9, t, [],
                                None, sums_old)
    n = int(np.diff(old_b.face_loop_ptr)[old_cap])
    rec = sums_old[old_cap]
    assert rec.lo.shape == rec.hi.shape == (n, 2)
    for moved in (False, True):
        b, cap = _cap_with_holes(25, moved)
        assert int(np.diff(b.face_loop_ptr)[cap]) == n + 1
        out_full, out_part = [], []
        full_table = check_module._check_geometry(b, t, 9, [])
        full = check_module._sampled_rings(b, np.array([cap]), np.empty(0, dtype=np.int64), full_table, 9, t,
                                           out_full, None, sums_full := {})
        partial = {cap: (n, rec)}
        part_table = check_module._check_geometry(b, t, 9, [], None, partial)
        in_cap = b.coedge_loop[part_table.coedge]
        assert set(in_cap[b.loop_face[in_cap] == cap].tolist()) == {int(b.face_loops[b.face_loop_ptr[cap + 1] - 1])}
        part = check_module._sampled_rings(b, np.array([cap]), np.empty(0, dtype=np.int64), part_table, 9, t,
                                           out_part, partial, sums_part := {})
        assert part[0].shape[0] < full[0].shape[0] / 4
        assert out_full == out_part == []
        a, p = sums_full[cap], sums_part[cap]
        assert (a.scale, a.stretch) == (p.scale, p.stretch)
        np.testing.assert_allclose(p.area, a.area, rtol=1e-12)
        np.testing.assert_array_equal(p.lo, a.lo)
        np.testing.assert_array_equal(p.hi, a.hi)
        old_loop = np.zeros(b.n_loops, dtype=bool)
        old_loop[b.face_loops[b.face_loop_ptr[cap]:b.face_loop_ptr[cap] + n]] = True
        near_full = check_module._near_new_loops(b, full, old_loop)
        near_part = check_module._near_new_loops(b, part, old_loop)

        def rows(s):
            A, B, face, nxt, coedge, eps = s
            r = np.concatenate([A, B, face[:, None], coedge[:, None], eps[:, None]], axis=1)
            return r[np.lexsort(r.T[::-1])]

        np.testing.assert_array_equal(rows(near_part), rows(near_full))
        hits = check_module._crossings([near_part], old_loop[b.coedge_loop])
        assert (cap in hits) == moved
        assert hits.keys() == check_module._crossings([near_full], old_loop[b.coedge_loop]).keys()


def test_a_face_extending_a_passed_one_is_checked_as_a_whole_would_be(monkeypatch):
    """Sequential cuts into a plate: from the cut after the top and bottom passed with 16 or more
    loops, their old loops are neither measured nor made into rings (the recorded sums stand in),
    and the check reports and records what the whole check does: nothing, the same sums."""
    from coons.topology.primitives import Cylinder as Cyl

    taken, measured = [], []
    real_rings, real_geometry = check_module._sampled_rings, check_module._check_geometry

    def geometry(b, t, samples, out, passed=None, partial=None):
        table = real_geometry(b, t, samples, out, passed, partial)
        measured.append(table.coedge.size)
        return table

    def rings(b, cross, sense, table, samples, t, out, partial=None, sums=None):
        seg = real_rings(b, cross, sense, table, samples, t, out, partial, sums)
        taken.append(sorted(partial or ()))
        if partial:  # the whole rings, on a whole table, give the same sums and no more problems
            whole, mine = {}, []
            real_rings(b, cross, sense, real_geometry(b, t, samples, [], None), samples, t, mine, None, whole)
            assert mine == [] and out == []
            for f in partial:
                assert (whole[f].scale, whole[f].stretch) == (sums[f].scale, sums[f].stretch)
                np.testing.assert_allclose(sums[f].area, whole[f].area, rtol=1e-12)
                np.testing.assert_array_equal(sums[f].lo, whole[f].lo)
                np.testing.assert_array_equal(sums[f].hi, whole[f].hi)
        return seg

    monkeypatch.setattr(check_module, "_sampled_rings", rings)
    monkeypatch.setattr(check_module, "_check_geometry", geometry)
    plate = Box(60, 50, 4)
    holes = [(-25.0 + 10 * i, -20.0 + 10 * j, 0.0) for i in range(6) for j in range(4)]
    sizes = []
    for k, at in enumerate(holes):
        taken.clear()
        measured.clear()
        plate = plate - Cyl(1.0, 10.0).translate(at)
        sizes.append(measured[-1])
        if k >= check_module._PREFIX_LOOPS:
            assert len(taken[-1]) == 2  # top and bottom
    # (after k cuts the top has k + 1 loops: recorded from cut _PREFIX_LOOPS - 1 on, extended after)
    assert sizes[-1] < sizes[check_module._PREFIX_LOOPS - 2] / 4
    assert check(plate).ok
    assert math.isclose(plate.volume, 60 * 50 * 4 - len(holes) * math.pi * 4, rel_tol=1e-12)


def test_carried_shell_volumes_equal_the_integrated_ones_and_integrate_only_what_changed(monkeypatch):
    """The orientation check of a sewn B-rep sums face contributions carried from earlier checks
    (mass.carried_shell_volumes): along a chain of cuts they equal the volumes integrated whole (to
    round-off), and a late cut integrates only its new faces and the new loops of the faces gaining
    a hole (the plate's top and bottom)."""
    from coons.topology import mass
    from coons.topology.primitives import Cylinder as Cyl

    real, real_part = mass.carried_shell_volumes, mass._face_integrals
    compared, integrated = [], []

    def carried(b, specs, unchanged, extends, tol=None):
        vols = real(b, specs, unchanged, extends, tol)
        ref = mass._reference_point(b)
        whole = np.bincount(b.face_shell, weights=mass._face_integrals(b, ref[0], ref[1], 2, mass._quadrature_rtol(tol))[:, 1],
                            minlength=b.n_shells)
        np.testing.assert_allclose(vols, whole, rtol=1e-12)
        compared.append(len(extends))
        return vols

    def part(b, x0, L, ncols, rtol, faces=None, new_loop=None):
        if faces is not None:
            integrated.append((int(faces.sum()), int(new_loop.sum())))
        return real_part(b, x0, L, ncols, rtol, faces, new_loop)

    monkeypatch.setattr(mass, "carried_shell_volumes", carried)
    monkeypatch.setattr(mass, "_face_integrals", part)
    plate = Box(60, 50, 4)
    for k in range(20):
        integrated.clear()
        plate = plate - Cyl(1.0, 10.0).translate((-25.0 + 10 * (k % 6), -20.0 + 10 * (k // 6), 0.0))
    assert len(compared) >= 20 and compared[-1] == 2  # the top and bottom extend their specs
    assert integrated[-1] == (2, 2)  # the hole's two half cylinders, one new loop in the top and the bottom
    assert check(plate).ok
    assert math.isclose(plate.volume, 60 * 50 * 4 - 20 * math.pi * 4, rel_tol=1e-12)


def test_an_inside_out_shell_of_carried_faces_is_still_found(monkeypatch):
    """The walls of a box drilled along x, y and z (the very specs whose volume contributions its
    check recorded) closed by caps on the box's faces bound the drilled-out cross from outside: an
    inward shell with the same vertex box, so the walls' recorded contributions (negative about
    the centre, as the cross's outward ones are positive) are carried, and only the caps are
    integrated.  Their sign decides: with it ignored the shell would look outward."""
    from coons.kernel.analytic import CylindricalSurface, PlanarSurface
    from coons.topology import mass

    def drill(axis):
        return Cylinder(1.0, 12.0, direction={"x": (1, 0, 0), "y": (0, 1, 0), "z": (0, 0, 1)}[axis])

    specs = face_specs((Box(10, 10, 10) - drill("x") - drill("y") - drill("z")).brep)
    assert check(sew_faces(specs).brep).ok  # records the faces' contributions
    walls = [s for s in specs if isinstance(s.surface, CylindricalSurface)]
    # The holes of the box's faces, the same edge specs used the same way, as faces whose normal
    # points into the box (the hole loop runs clockwise about the box face's outward normal).
    caps = [FaceSpec(s.surface, not s.sense, [loop]) for s in specs if isinstance(s.surface, PlanarSurface)
            for loop in s.loops[1:]]
    assert len(walls) == 12 and len(caps) == 6
    real_carried, real_integrals = mass.carried_shell_volumes, mass._face_integrals
    unchanged, integrated = [], []

    def carried(b, sp, unch, extends, tol=None):
        unchanged.append(int(np.count_nonzero(unch)))
        return real_carried(b, sp, unch, extends, tol)

    def integrals(b, x0, L, ncols, rtol, faces=None, new_loop=None):
        integrated.append(b.n_faces if faces is None else int(np.count_nonzero(faces)))
        return real_integrals(b, x0, L, ncols, rtol, faces, new_loop)

    monkeypatch.setattr(mass, "carried_shell_volumes", carried)
    monkeypatch.setattr(mass, "_face_integrals", integrals)
    with pytest.raises(TopologyError, match="inward-shell"):
        sew_faces(walls + caps)
    assert unchanged == [len(walls) + len(caps)]  # every face equal to its spec
    assert integrated == [len(caps)]  # the walls' contributions carried, the caps' integrated


def test_the_nesting_found_at_one_tolerance_is_not_served_at_another():
    """A box with a void 0.005 inside its walls: nested at the default tolerance (sewing finds and shares
    it); at a tolerance of 0.01 the void lies within the band of the walls (the shells touch), and at
    0.02 no mesh is fine enough to decide: both are reported, not served from sewing's answer or raised."""
    from coons.tolerance import Tolerance

    void = [FaceSpec(f.surface, not f.sense, [[EdgeSpec(e.curve, e.t1, e.t0, e.pcurve, e.tol) for e in reversed(loop)]
                                              for loop in f.loops]) for f in face_specs(Box(9.99, 9.99, 9.99))]
    solid = sew_faces(face_specs(Box(10, 10, 10)) + void)
    assert (solid.brep.n_shells, solid.brep.n_solids) == (2, 1)
    assert check(solid).ok
    for linear in (0.01, 0.02):
        report = check(solid, tol=Tolerance(linear))
        assert "shells-touch" in report.codes(), (linear, report.summary())
        assert "not decided" in str([p for p in report.problems if p.code == "shells-touch"][0])
    assert check(solid).ok  # (and the default's answer is still the default's)


def test_measurements_remembered_per_pcurve_equal_a_cold_check(monkeypatch):
    """The same-parameter rows remembered per p-curve (``_SAME_PARAMETER``, written for all coedges
    of a check in one pass) are found for every coedge of a B-rep with the same geometry when no
    B-rep's array record is there to carry them, and give the cold check's table; p-curves shared
    by several coedges keep one entry per curve, surface and range."""
    from coons.topology import _memo
    from coons.topology.check import _SAME_PARAMETER, _check_geometry
    from coons.tolerance import DEFAULT_TOLERANCE as T

    _memo.clear_all()
    shape = Box(20.0, 20.0, 4.0) - Cylinder(1.0, 10.0).translate((4.0, 0.0, -3.0))
    cold = _check_geometry(shape.brep, T, 9, out_cold := [])
    assert len(_SAME_PARAMETER) > 0
    for entries in _SAME_PARAMETER._data.values():
        for h in entries[1].values():
            assert not h[2].flags.writeable
    found = _spy_cached_samples(monkeypatch)
    check_module._MEASURED.clear()  # only the per-p-curve memo remains
    check_module._LAST_MEASURED[:] = [None, None]
    copy = dataclasses.replace(shape.brep)
    warm = _check_geometry(copy, T, 9, out := [])
    n, hits = found[-1]
    assert hits == n
    assert out == out_cold
    for name in ("coedge", "uv", "speed", "line", "pos"):
        np.testing.assert_array_equal(getattr(warm, name), getattr(cold, name), err_msg=name)


@pytest.mark.parametrize("make", [
    lambda: Box(20.0, 20.0, 4.0) - Cylinder(1.0, 10.0).translate((4.0, 0.0, -3.0)),
    lambda: Sphere(5.0) + Sphere(5.0).translate((4.0, 2.0, 0.5)),
    lambda: Cone(3.0, 1.0, 6.0) - Torus(4.0, 1.0),
])
def test_geometry_check_of_analytic_surfaces_equals_the_grouped_path(make, monkeypatch):
    """Where every surface measured is a plane or of revolution, _check_geometry evaluates them by
    ``analytic.surface_derivatives`` directly; ``derivatives_surfaces`` (which groups the rows by
    surface first) must give the very same table and problems."""
    from coons.topology import _memo
    from coons.topology.check import _check_geometry
    from coons.tolerance import DEFAULT_TOLERANCE as T

    shape = make()
    _memo.clear_all()
    check_module._MEASURED.clear()
    fast = _check_geometry(shape.brep, T, 9, out_fast := [])
    _memo.clear_all()
    check_module._MEASURED.clear()
    monkeypatch.setattr(check_module, "BATCHED_SURFACES", ())  # (no surface qualifies: the grouped path)
    general = _check_geometry(shape.brep, T, 9, out_general := [])
    assert [str(p) for p in out_fast] == [str(p) for p in out_general]
    for name in ("coedge", "uv", "speed", "line", "pos"):
        np.testing.assert_array_equal(getattr(fast, name), getattr(general, name), err_msg=name)


def test_pcurve_samples_from_the_mass_tables_equal_each_pcurve_evaluated():
    # The checker samples lines and ellipses from the coefficient rows of the mass tables (the
    # p-curves' own floats): every sample must be the bits of the p-curve's own evaluate, for the
    # lines and ellipses of a plate minus cylinders and of the union of two spheres.
    from coons.booleans.solid import difference, union

    plate = difference(Box(30.0, 30.0, 4.0), *[Cylinder(1.0, 10.0).translate((x, y, -3.0))
                                              for x in (-6.0, 6.0) for y in (-6.0, 6.0)])
    blob = union(Sphere(2.0), Sphere(2.0).translate((1.5, 0.5, 0.25)))
    for b in (plate.brep, blob.brep):
        which = np.array([i for i, pc in enumerate(b.pcurves) if isinstance(pc, (Line2D, Trig2D))])[::-1].repeat(2)
        T = np.random.default_rng(5).uniform(-1.0, 4.0, size=(which.size, 9))
        uv, line = check_module._pcurves_at(b, which, T)
        for k, i in enumerate(which.tolist()):
            pc = b.pcurves[i]
            assert line[k] == isinstance(pc, Line2D)
            assert uv[k].tobytes() == pc.evaluate(T[k]).tobytes(), (k, type(pc).__name__)
