"""Tessellation of curved Boolean results: the OCCT agreement pairs (tests/booleans/occt_cases.py) and
hand-picked ones (a lens of two spheres, a box minus a cylinder tangent to a face, the Steinmetz solid,
a napkin ring) mesh watertight at two deflections.

Each result is built once per module (the Booleans take 0.5–5 s each) and must pass ``check``.  Its mesh
must be closed (every directed edge used once each way), vertex-manifold, of the Euler characteristic
of the B-rep (``V − E + 2F − L``, Euler–Poincaré), with every vertex on its surface (within the
tolerance the fitted intersection curves carry), every triangle within the deflection of its exact
analytic surface (sampled at 28 barycentric points per triangle), no triangle turned against its
face's outward normal, and a volume within ``deflection × area`` of the exact one.  trimesh agrees
that the meshes are watertight and winding-consistent.  The default run takes one operation per pair
(cycling union / intersection / difference) and the hand-picked cases; ``-m slow`` runs all 45 curved
results of the default pairs and the 90 of the extended draws.  Two regressions: a sliver face whose two chords coincide (box-cyl-2
union) and the refinement's slow tail near thin features (box-cyl-0 union at a fine deflection).
"""

from __future__ import annotations

import functools
import math

import numpy as np
import pytest

from coons.topology.check import check
from coons.topology.mass import bounding_box, mass_properties
from coons.topology.primitives import Box, Cylinder, Sphere
from coons.topology.shape import Solid
from coons.topology.tessellate import tessellate
from coons.topology.transform import Pos, Rot
from tests.booleans.occt_cases import DEFAULT_PAIRS, EXTENDED_PAIRS, OPS, pair
from tests.topology.test_tessellate import surface_deviation, vertex_links_are_cycles

_APPLY = {"union": lambda a, b: a + b, "intersection": lambda a, b: a & b, "difference": lambda a, b: a - b}

#: Deflections relative to the bounding-box diagonal: a coarse and a fine mesh.
RELATIVE_DEFLECTIONS = (4e-3, 1e-3)

#: Hand-picked results with their exact volumes (closed forms).
HAND_PICKED = {
    # Two spheres of radius 2 with centres 2.5 apart: V = π (4r + d)(2r − d)² / 12.
    "lens": (lambda: Sphere(2.0) & (Pos(2.5, 0, 0) * Sphere(2.0)), math.pi * 10.5 * 1.5**2 / 12),
    # A cylinder of radius 1 inside a 4-cube, tangent to its face y = 2 along a line.
    "box_minus_tangent_cylinder": (lambda: Box(4, 4, 4) - (Pos(0, 1, 0) * Cylinder(1.0, 6)), 64 - 4 * math.pi),
    # Two perpendicular cylinders of radius 1: V = 16 r³ / 3.
    "steinmetz": (lambda: Cylinder(1.0, 4) & (Rot(90, 0, 0) * Cylinder(1.0, 4)), 16 / 3),
    # The same with r = 2, length 10: its fitted curves round the singular points within their
    # tolerance through knot clusters (edge samples 1e-17 apart, turning chords there) and Qhull
    # folds a triangle of a face's boundary; the mesh (and so the three-cylinder Booleans) failed.
    "steinmetz_r2": (lambda: Cylinder(2.0, 10) & Cylinder(2.0, 10, direction=(1, 0, 0)), 16 * 8 / 3),
    # A sphere of radius 2 minus a coaxial cylinder of radius 1.2: height h = 3.2, V = π h³ / 6.
    "napkin_ring": (lambda: Sphere(2.0) - Cylinder(1.2, 6), math.pi * 3.2**3 / 6),
    # A unit box turned 30° whose corner is 0.0023 inside a cylinder's rim (the box lies inside it in
    # plan: V = 9π − 1): the rim's chords sag further than that and crossed the notch's side in the
    # cap's plane; the rim is refined until they do not (tessellate's crossing rounds).
    "notch_near_rim": (lambda: (Pos(0.5, 0.25, 1) * Cylinder(1.5, 4))
                       - (Pos(-0.25, 0.5, -1) * Rot(0, 0, 30) * Box(1, 1, 2)), 9 * math.pi - 1),
    # A sphere face with a vertex 1.2° from its pole where a fitted p-curve ends 1.6e-6 off the seam:
    # taken for a pole gap (the slow direction there makes the mismatch look long), its gap segment
    # crossed the next chord.  No closed form.
    "vertex_near_pole": (lambda: ((Pos(-0.25, -1, 1) * Cylinder(1.5, 4)) & (Pos(-0.5, -0.25, 0) * Sphere(1.0)))
                         + (Pos(1, 0, -1) * Cylinder(1.5, 4)), None),
    # A planned sphere face whose top row (from its fitted p-curves) lands 3e-8 below its seam
    # edge's end: a second mesh point at the vertex, whose short chord the next edge's crossed.
    "row_at_a_vertex": (lambda: ((Pos(-1, -0.5, 1) * Sphere(2.0)) & (Pos(0.5, 1, 0) * Cylinder(1.0, 2)))
                        + (Pos(1, 0, 1) * Sphere(1.0)), None),
}


@functools.lru_cache(maxsize=None)
def boolean_result(name: str, op: str) -> Solid:
    """The checked result of ``op`` on the pair ``name`` (built once per module)."""
    a, b = pair(name).operands()
    r = _APPLY[op](a, b)  # a Boolean that raises fails the test: every pair of the set must work
    report = check(r)
    assert report.ok, f"{name} {op}: the Boolean result is invalid: {report}"
    return r


@functools.lru_cache(maxsize=None)
def hand_picked(name: str) -> Solid:
    r = HAND_PICKED[name][0]()
    report = check(r)
    assert report.ok, f"{name}: the Boolean result is invalid: {report}"
    return r


def _curved(p) -> bool:
    return not (p.kind_a == "box" and p.kind_b == "box")


def _params(pairs, *, all_ops: bool, slow: bool):
    out = []
    for i, p in enumerate(q for q in pairs if _curved(q)):
        ops = OPS if all_ops else (OPS[i % len(OPS)],)
        for op in ops:
            if p.relation == "disjoint" and op == "intersection":
                continue  # empty: nothing to mesh
            marks = [pytest.mark.slow] if slow else []
            out.append(pytest.param(p.name, op, id=f"{p.name}-{op}", marks=marks))
    return out


FAST = _params(DEFAULT_PAIRS, all_ops=False, slow=False)
FAST_IDS = {p.id for p in FAST}
SLOW = [p for p in _params(DEFAULT_PAIRS, all_ops=True, slow=True) if p.id not in FAST_IDS]
SLOW += _params(EXTENDED_PAIRS, all_ops=True, slow=True)
FAST_OP = {p.values[0]: p.values[1] for p in FAST}


def assert_watertight_and_within_deflection(r: Solid, relative: float, exact_volume: float | None = None) -> None:
    b = r.brep
    box = bounding_box(b)
    diag = float(np.linalg.norm(box[1] - box[0]))
    d = relative * diag
    m = tessellate(r, deflection=d)
    # Closed and edge-manifold: every directed edge used once each way; vertex-manifold.
    assert m.is_closed and m.boundary_edges().shape == (0, 2)
    assert vertex_links_are_cycles(m)
    # Euler–Poincaré: the mesh has the B-rep's topology (V − E + F − (L − F) = 2 (S − G)).
    assert m.euler_characteristic == b.n_vertices - b.n_edges + 2 * b.n_faces - b.n_loops
    # Every face is meshed, every vertex is on its surface, every triangle within the deflection.
    assert set(np.unique(m.face_ids).tolist()) == set(range(b.n_faces))
    worst, vert, flipped = surface_deviation(b, m)
    assert worst <= d, f"a triangle is {worst / d:.3f} deflections from its surface"
    # Vertices on fitted intersection curves are within their edge tolerance of both surfaces.
    achieved = max(float(np.max(b.edge_tol, initial=0.0)), float(np.max(b.vertex_tol, initial=0.0)))
    assert vert <= achieved + 1e-12 * diag
    assert flipped == 0
    mp = mass_properties(b)
    if exact_volume is not None:
        assert mp.volume == pytest.approx(exact_volume, rel=1e-6)
    assert abs(m.volume - mp.volume) <= d * mp.area, (m.volume, mp.volume, d * mp.area)


#: (pair, op, relative deflection) known to fail, with the diagnosed reason (strict: a fix shows as XPASS).
#: Empty: the box-cone-0 cases (a fitted p-curve end taken for a pole gap; a triangle 1.0004
#: deflections off a cone) were fixed by summing both edges' tolerances and refining to 0.98 d.
KNOWN_FAILURES: dict[tuple[str, str, float], str] = {}


def _with_known_failures(cases, relatives):
    out = []
    for c in cases:
        name, op = c.values
        for rel in relatives:
            why = KNOWN_FAILURES.get((name, op, rel))
            marks = list(c.marks) + ([pytest.mark.xfail(strict=True, reason=why)] if why else [])
            out.append(pytest.param(name, op, rel, marks=marks, id=f"{c.id}-{rel}"))
    return out


@pytest.mark.parametrize(("name", "op", "relative"), _with_known_failures(FAST + SLOW, RELATIVE_DEFLECTIONS))
def test_occt_pair_results_tessellate_watertight_within_deflection(name, op, relative):
    assert_watertight_and_within_deflection(boolean_result(name, op), relative)


@pytest.mark.parametrize("relative", RELATIVE_DEFLECTIONS)
@pytest.mark.parametrize("name", list(HAND_PICKED))
def test_hand_picked_results_tessellate_watertight_within_deflection(name, relative):
    assert_watertight_and_within_deflection(hand_picked(name), relative, HAND_PICKED[name][1])


@pytest.mark.manifold
def test_trimesh_sees_watertight_winding_consistent_meshes():
    import trimesh

    for r in [hand_picked("steinmetz"), hand_picked("lens"), boolean_result("cyl-cyl-0", FAST_OP["cyl-cyl-0"])]:
        box = bounding_box(r.brep)
        m = tessellate(r, deflection=RELATIVE_DEFLECTIONS[0] * float(np.linalg.norm(box[1] - box[0])))
        tm = trimesh.Trimesh(m.vertices, m.triangles, process=False)
        assert tm.is_watertight and tm.is_winding_consistent and tm.is_volume
        assert tm.volume == pytest.approx(m.volume, rel=1e-12)



def test_sliver_face_whose_chords_coincide_still_gets_a_triangle():
    """box-cyl-2 union has a planar sliver bounded by a line and an arc whose one chord is within the
    deflection: its loop would be two points; the arc is bisected so that the face is meshed."""
    r = boolean_result("box-cyl-2", "union")
    b = r.brep
    two = [lp for lp in range(b.n_loops) if len(b.loop_coedges(lp)) == 2]
    assert two, "the sliver face is gone: pick another reproducer"
    assert_watertight_and_within_deflection(r, 4e-3)


def test_refinement_converges_near_thin_features_at_a_fine_deflection():
    """box-cyl-0 union at deflection 0.002 (1.7e-4 of its diagonal) used to stop after 12 refinement rounds
    with a tail of one or two points per round beside a boundary; splitting the offending edge converges."""
    r = boolean_result("box-cyl-0", "union")
    m = tessellate(r, deflection=0.002)
    assert m.is_closed
    worst, _, flipped = surface_deviation(r.brep, m)
    assert worst <= 0.002 and flipped == 0


@pytest.mark.parametrize("eps", [1e-13, 1e-15])
def test_points_qhull_drops_as_near_duplicates_are_inserted_exactly(eps):
    """Qhull leaves out a point within its precision of another (``coplanar``); the triangulator inserts it
    with the exact predicates instead of raising, so every input point is a vertex of the result."""
    from scipy.spatial import Delaunay

    from coons.topology._cdt import triangulate

    P = np.array([[0, 0], [1, 0], [1, 1], [0, 1], [0.5, 0.5], [0.5 + eps, 0.5 + 0.3 * eps]])
    corners = np.array([[-4.0, -4.0], [4.0, -4.0], [4.0, 4.0], [-4.0, 4.0]])
    assert Delaunay(np.vstack([P, corners])).coplanar.shape[0] == 1  # Qhull does drop it
    T = triangulate(P, np.array([[0, 1], [1, 2], [2, 3], [3, 0]]))
    assert sorted(np.unique(T).tolist()) == list(range(6))
    a, b = P[T[:, 1]] - P[T[:, 0]], P[T[:, 2]] - P[T[:, 0]]
    area = 0.5 * (a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0])
    assert np.all(area > 0) and abs(area.sum() - 1.0) < 1e-15
