"""Tests of coons.validation.compare: exact point–triangle and point–mesh distances, Hausdorff, verdict rules."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from coons.errors import InvalidInputError
from coons.validation.cases import Case
from coons.validation.compare import (
    closest_points_on_triangles,
    compare_engines,
    hausdorff,
    judge,
    point_mesh_distance,
    sample_triangles,
)
from coons.validation.engines import EngineResult

# A unit cube [-1, 1]^3 as 12 outward triangles.
CUBE_V = np.array([[x, y, z] for x in (-1.0, 1.0) for y in (-1.0, 1.0) for z in (-1.0, 1.0)])
CUBE_T = np.array([[0, 1, 3], [0, 3, 2], [4, 6, 7], [4, 7, 5], [0, 4, 5], [0, 5, 1],
                   [2, 3, 7], [2, 7, 6], [0, 2, 6], [0, 6, 4], [1, 5, 7], [1, 7, 3]])


def cube_distance(P: np.ndarray) -> np.ndarray:
    """Closed form: distance from points to the surface of the cube [-1, 1]^3."""
    q = np.abs(P) - 1.0
    outside = np.linalg.norm(np.maximum(q, 0.0), axis=1)
    inside = -np.max(q, axis=1)
    return np.where(np.any(q > 0, axis=1), outside, inside)


def test_cube_mesh_is_closed_and_outward():
    A, B, C = (CUBE_V[CUBE_T[:, k]] for k in range(3))
    volume = np.einsum("ij,ij->i", A, np.cross(B, C)).sum() / 6.0
    np.testing.assert_allclose(volume, 8.0, rtol=1e-15)


def test_closest_points_match_a_dense_search():
    rng = np.random.default_rng(3)
    n = 150
    P, A, B, C = (rng.normal(size=(n, 3)) * s for s in (3.0, 1.0, 1.0, 1.0))
    Q = closest_points_on_triangles(P, A, B, C)
    g = np.linspace(0.0, 1.0, 161)
    u, v = np.meshgrid(g, g)
    keep = (u + v) <= 1.0
    u, v = u[keep], v[keep]
    X = A[:, None] + u[None, :, None] * (B - A)[:, None] + v[None, :, None] * (C - A)[:, None]
    dense = np.linalg.norm(X - P[:, None], axis=2).min(axis=1)
    ours = np.linalg.norm(Q - P, axis=1)
    # ours is exact: never above the dense search, and below it by at most the grid spacing
    assert np.all(ours <= dense + 1e-12)
    np.testing.assert_allclose(ours, dense, atol=0.05)
    # and Q lies on the triangle: its barycentric coordinates are in [0, 1]
    M = np.stack([B - A, C - A], axis=2)  # (n, 3, 2)
    MtM = np.einsum("nki,nkj->nij", M, M)
    bary = np.linalg.solve(MtM, np.einsum("nki,nk->ni", M, Q - A)[..., None])[..., 0]
    assert bary.min() >= -1e-9 and bary.sum(axis=1).max() <= 1 + 1e-9


def test_closest_point_regions():
    A, B, C = np.array([[0.0, 0, 0]]), np.array([[1.0, 0, 0]]), np.array([[0.0, 1, 0]])
    cases = {(-1.0, -1.0, 2.0): (0, 0, 0), (2.0, -0.5, 0.0): (1, 0, 0), (0.5, -2.0, 1.0): (0.5, 0, 0),
             (1.0, 1.0, 0.0): (0.5, 0.5, 0), (0.2, 0.2, -3.0): (0.2, 0.2, 0), (-1.0, 0.5, 0.0): (0, 0.5, 0),
             (-0.5, 3.0, 0.0): (0, 1, 0)}
    for p, q in cases.items():
        np.testing.assert_allclose(closest_points_on_triangles(np.array([p]), A, B, C)[0], q, atol=1e-15)


@given(st.lists(st.tuples(*[st.floats(-3, 3)] * 3), min_size=1, max_size=40))
def test_point_mesh_distance_is_exact_on_a_cube(points):
    P = np.array(points, dtype=float)
    # few samples on purpose: the BVH pass must make the answer exact whatever the first bound
    d = point_mesh_distance(P, CUBE_V, CUBE_T, samples=20)
    np.testing.assert_allclose(d, cube_distance(P), atol=1e-12)


def test_point_mesh_distance_errors():
    with pytest.raises(InvalidInputError, match="at least one triangle"):
        point_mesh_distance(np.zeros((1, 3)), CUBE_V, np.zeros((0, 3), np.int64))


def test_sample_triangles_lie_on_their_triangles():
    P, tri = sample_triangles(CUBE_V, CUBE_T, 500, seed=1)
    assert len(P) >= 500 + 8 + 12
    A, B, C = (CUBE_V[CUBE_T[tri, k]] for k in range(3))
    np.testing.assert_allclose(closest_points_on_triangles(P, A, B, C), P, atol=1e-14)


@pytest.mark.parametrize("delta", [0.0, 0.05, 0.3])
def test_hausdorff_of_a_shifted_cube(delta):
    h, vd = hausdorff((CUBE_V, CUBE_T), (CUBE_V + [delta, 0, 0], CUBE_T), samples=3000)
    # the vertices at x = -1 are delta from the second cube, those at x = +1 lie on its side faces
    np.testing.assert_allclose(vd, np.where(CUBE_V[:, 0] < 0, delta, 0.0), atol=1e-12)
    np.testing.assert_allclose(h, delta, atol=1e-12)


def test_hausdorff_errors():
    with pytest.raises(InvalidInputError, match="two non-empty meshes"):
        hausdorff((CUBE_V, CUBE_T), (CUBE_V, np.zeros((0, 3), np.int64)))


# ============================================================================ verdict rules
CASE = Case("synthetic", ("box", 10, 10, 10), "a synthetic case", ("planar",))
CURVED = Case("synthetic_curved", ("sphere", 5), "a synthetic curved case", ("curved",))


def result(engine: str, **kw) -> EngineResult:
    base = dict(volume=1000.0, area=600.0, bbox=[[-5.0, -5, -5], [5.0, 5, 5]], euler=2, valid=True, validity="valid",
                counts={"vertices": 8, "edges": 12, "faces": 6, "inner_loops": 0, "shells": 1, "solids": 1})
    if engine == "occt":
        base["counts"] = {**base["counts"], "seam_edges": 0, "degenerate_edges": 0}
    if engine == "manifold":
        base["tessellation_error"] = {"volume": 0.0, "area": 0.0}
    base.update(kw)
    return EngineResult(engine, **base)


def verdict(case=CASE, hd=0.0, **engines):
    res = {"coons": result("coons"), "occt": result("occt"), "manifold": result("manifold")}
    res.update(engines)
    return judge(case, res, deflection=0.017, hausdorff_distance=hd)


def test_all_agree():
    v = verdict()
    assert v.kind == "agree" and not v.is_failure and not v.reasons
    assert {m.name for m in v.measures} >= {"volume", "area", "bbox", "euler", "shells", "lumps", "faces", "V-E",
                                            "hausdorff", "empty"}


def test_coons_volume_off_by_more_than_the_tolerance_disagrees():
    v = verdict(coons=result("coons", volume=1000.1))
    assert v.kind == "disagree" and v.is_failure
    assert any("volume: coons 1000.1 vs occt 1000" in r for r in v.reasons)
    bad = [m for m in v.measures if not m.ok]
    assert {m.reference for m in bad} == {"occt", "manifold"}
    assert all(m.deviation == pytest.approx(0.1) for m in bad)
    # 1e-3 is beyond OCCT's tolerance but within manifold3d's float32 one: OCCT is blamed
    assert verdict(coons=result("coons", volume=1000.001)).kind == "reference-failed"
    # within the tolerance (1e-7 relative to L^3) it agrees
    assert verdict(coons=result("coons", volume=1000.0 + 1e-9)).kind == "agree"


def test_coons_invalid_disagrees():
    v = verdict(coons=result("coons", valid=False, validity="1 problem: open shell"))
    assert v.kind == "disagree" and "coons result is invalid: 1 problem: open shell" in v.reasons


def test_coons_euler_or_hausdorff_mismatch_disagrees():
    v = verdict(coons=result("coons", euler=0))
    assert v.kind == "disagree" and any(r.startswith("euler: coons 0 vs occt 2") for r in v.reasons)
    v = verdict(hd=0.5)  # only OCCT's mesh is compared, so no other reference can take coons's side
    assert v.kind == "disagree" and v.reasons[0].startswith("hausdorff: coons 0.5 vs occt 0")


def test_coons_raised_is_its_own_status():
    typed = verdict(coons=result("coons", status="raised", error="BooleanError: [input] curved"))
    assert typed.kind == "coons-raised" and not typed.is_failure
    bug = verdict(coons=result("coons", status="raised", error="IndexError: boom", typed_error=False))
    assert bug.kind == "coons-raised" and bug.is_failure and "a bug" in bug.reasons[0]


def test_reference_failures():
    v = verdict(occt=result("occt", status="raised", error="RuntimeError: BRepAlgoAPI failed"))
    assert v.kind == "reference-failed" and not v.is_failure
    assert v.failed_references == {"occt": "occt raised RuntimeError: BRepAlgoAPI failed"}
    v = verdict(occt=result("occt", valid=False, validity="BRepCheck_Analyzer: not valid"))
    assert v.kind == "reference-failed" and "invalid" in v.failed_references["occt"]
    v = verdict(coons=result("coons", empty=True, volume=0.0, area=0.0, bbox=None),
                occt=result("occt", empty=True, volume=0.0, area=0.0, bbox=None),
                manifold=result("manifold", volume=0.0))
    assert v.kind == "reference-failed" and "zero-volume sheet" in v.failed_references["manifold"]
    # manifold keeps a zero-thickness wall: twice the area; coons agrees with OCCT
    v = verdict(manifold=result("manifold", area=800.0))
    assert v.kind == "reference-failed" and "manifold disagrees with coons and occt: area" in v.reasons[0]


def test_both_references_against_coons_disagree():
    v = verdict(occt=result("occt", volume=900.0), manifold=result("manifold", volume=900.0))
    assert v.kind == "disagree" and v.is_failure


def test_no_healthy_reference():
    v = verdict(occt=result("occt", status="raised", error="X: y"), manifold=result("manifold", valid=False))
    assert v.kind == "reference-failed" and v.reasons[0] == "no healthy reference to judge by"


def test_closed_form_decides():
    case = Case("synthetic_expect", ("box", 10, 10, 10), "", ("planar",), expect_volume=1000.0)
    assert verdict(case).kind == "agree"
    v = verdict(case, occt=result("occt", volume=990.0))
    assert v.kind == "reference-failed" and "misses the closed form" in v.failed_references["occt"]
    v = verdict(case, coons=result("coons", volume=990.0), occt=result("occt", volume=990.0),
                manifold=result("manifold", volume=990.0))
    assert v.kind == "disagree" and "closed form" in v.reasons[0]


def test_manifold_tolerance_grows_with_the_tessellation_error():
    loose = result("manifold", volume=999.0, tessellation_error={"volume": 0.6, "area": 0.0})
    assert verdict(CURVED, manifold=loose).kind == "agree"
    tight = result("manifold", volume=999.0, tessellation_error={"volume": 0.1, "area": 0.0})
    assert verdict(CURVED, manifold=tight).kind == "reference-failed"


def test_planar_counts_are_compared_only_for_planar_cases():
    extra = result("coons", counts={"vertices": 9, "edges": 13, "faces": 6, "inner_loops": 0, "shells": 1,
                                    "solids": 1})
    assert verdict(coons=extra).kind == "agree"  # a 2-valent vertex on a straight edge: V - E unchanged
    more_faces = result("coons", counts={"vertices": 8, "edges": 13, "faces": 7, "inner_loops": 0, "shells": 1,
                                         "solids": 1})
    assert verdict(coons=more_faces).kind == "disagree"
    assert verdict(CURVED, coons=more_faces).kind == "agree"


def test_compare_engines_errors():
    with pytest.raises(InvalidInputError, match="status 'ok'"):
        compare_engines(result("coons"), result("occt", status="raised"), scale=1.0, deflection=0.01)
    with pytest.raises(InvalidInputError, match="unknown reference engine 'other'"):
        compare_engines(result("coons"), result("other"), scale=1.0, deflection=0.01)


def test_zero_area_triangles_do_not_poison_the_distance():
    from coons.validation.compare import point_mesh_distance

    V = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [2, 0, 0.0]])
    T = np.array([[0, 1, 2], [0, 1, 3]])  # the second triangle is a segment of zero area
    d = point_mesh_distance(np.array([[0.2, 0.2, 1.0], [1.5, 0.0, 1.0]]), V, T)
    np.testing.assert_allclose(d, [1.0, np.hypot(0.5, 1.0)], rtol=1e-12)
