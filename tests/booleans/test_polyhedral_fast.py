"""The fast paths of the polyhedral Boolean agree with the general ones: the grid-culled broad phase with
brute force, the array-time chain splits with the per-triangle exact splits, the adjacency-based
patches with the sorted ones, the row-restricted clean-up with the full one, and from_mesh's fast path
for clean meshes with from_mesh itself (tables, volumes and its error branches)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import coons
import coons.booleans._broad_phase as bp
import coons.booleans._mesh_arrangement as arrangement
import coons.booleans.polyhedral as poly
from coons.errors import TopologyError
from coons.topology.from_mesh import _solid_from_clean_triangles, from_mesh

VOL_RTOL = 1e-12  # the same exact pieces, summed in another order


def _brute(lo_a, hi_a, lo_b, hi_b) -> np.ndarray:
    """Sorted keys ``i * m + j`` of the overlapping pairs, by brute force."""
    ok = np.all(lo_a[:, None, :] <= hi_b[None, :, :], axis=2) & np.all(lo_b[None, :, :] <= hi_a[:, None, :], axis=2)
    i, j = np.nonzero(ok)
    return np.sort(i * lo_b.shape[0] + j)


def _keys(I, J, m) -> np.ndarray:
    return np.sort(I * m + J)


def _icospheres(level: int, offset=(0.3, 0.2, 0.1)):
    import trimesh

    s = trimesh.creation.icosphere(subdivisions=level)
    V, F = np.asarray(s.vertices), np.asarray(s.faces)
    return (V, F), (V + np.asarray(offset), F)


# ---------------------------------------------------------------------- broad phase
@settings(max_examples=8)
@given(st.integers(0, 2**32 - 1), st.integers(1050, 1600), st.sampled_from([0.01, 0.05, 0.15]))
def test_triangle_pairs_match_brute_force(seed, n, size):
    """Random triangle soups large enough for the cull and the grid, on integer-snapped coordinates
    (so that many boxes touch exactly): the pairs are exactly the brute-force overlapping pairs."""
    rng = np.random.default_rng(seed)
    P_a = np.round(rng.random((n, 3)) * 64) / 64
    P_b = np.round(rng.random((n, 3)) * 64) / 64 + 0.25
    T_a = np.sort(rng.integers(0, n, (n, 3)), axis=1)
    T_b = np.sort(rng.integers(0, n, (n, 3)), axis=1)
    # Shrink the triangles towards their first vertex so that they are small (a real mesh).
    P_a = np.concatenate([P_a, P_a + size * (rng.random((n, 3)) - 0.5)])
    P_b = np.concatenate([P_b, P_b + size * (rng.random((n, 3)) - 0.5)])
    T_a[:, 1:] += n * (T_a[:, 1:] != T_a[:, :1])
    T_b[:, 1:] += n * (T_b[:, 1:] != T_b[:, :1])
    I, J = bp.triangle_pairs(P_a, T_a, P_b, T_b)
    lo_a, hi_a = bp.triangle_boxes(P_a, T_a)
    lo_b, hi_b = bp.triangle_boxes(P_b, T_b)
    want = _brute(lo_a, hi_a, lo_b, hi_b)
    assert np.array_equal(_keys(I, J, T_b.shape[0]), want)  # every pair, once
    # box_pairs alone (the grid path) agrees too
    I2, J2 = bp.box_pairs(lo_a, hi_a, lo_b, hi_b)
    assert np.array_equal(_keys(I2, J2, T_b.shape[0]), want)


def test_box_pairs_with_one_huge_box_falls_back_to_the_trees():
    rng = np.random.default_rng(7)
    lo_a = rng.random((1500, 3))
    hi_a = lo_a + 0.01
    lo_b = rng.random((1500, 3))
    hi_b = lo_b + 0.01
    lo_b[0], hi_b[0] = -1.0, 2.0  # covers every cell of a fine grid
    assert bp._grid_pairs(lo_a, hi_a, lo_b, hi_b) is None
    I, J = bp.box_pairs(lo_a, hi_a, lo_b, hi_b)
    assert np.array_equal(_keys(I, J, 1500), _brute(lo_a, hi_a, lo_b, hi_b))
    assert np.count_nonzero(J == 0) == 1500


def test_triangle_pairs_of_far_apart_meshes_is_empty():
    (V, F), _ = _icospheres(3)
    I, J = bp.triangle_pairs(V, F, V + 10.0, F)
    assert I.size == 0 and J.size == 0


# ---------------------------------------------------------------------- imprint
def _arrangement(a, b):
    t = coons.DEFAULT_TOLERANCE
    A, B = poly._meshes(a, "A", t), poly._meshes(b, "B", t)
    ex = arrangement.Exact(A.P, B.P)
    I, J = poly._broad_phase(A, B)
    inter = poly._intersect(A, B, I, J, ex)
    table = arrangement.PointTable(A, B, inter, ex)
    return A, B, inter, table, ex


def _area(P, T):
    return 0.5 * np.linalg.norm(np.cross(P[T[:, 1]] - P[T[:, 0]], P[T[:, 2]] - P[T[:, 0]]), axis=1)


def test_chain_splits_partition_their_triangles():
    (V, F), (W, G) = _icospheres(3)
    A, B, inter, table, _ = _arrangement(from_mesh(V, F), from_mesh(W, G))
    for X, which in ((A, 0), (B, 1)):
        imp = poly._imprint(X, which, inter, table)
        area = np.bincount(imp.source, weights=_area(table.float, imp.tris), minlength=X.m)
        np.testing.assert_allclose(area, _area(X.P, X.T), rtol=1e-9)
        # most split triangles went through the array-time chain split
        aff = np.flatnonzero(np.bincount(imp.source, minlength=X.m) > 1)
        done, G_, src = arrangement._chain_pieces(
            *_chain_args(X, which, inter, table, aff))
        assert done.mean() > 0.9 and np.array_equal(np.unique(src), aff[done])


def _chain_args(X, which, inter, table, aff):
    """The arguments imprint passes to _chain_pieces, recomputed for a test."""
    vid = np.arange(X.n) if which == 0 else inter.alias_b
    T = vid[X.T]
    codes = inter.code_a if which == 0 else inter.code_b
    dim, idx = codes & 3, codes >> 2
    on_edge, inside = np.flatnonzero(dim == 1), np.flatnonzero(dim == 2)
    e_of, ep = idx[on_edge], inter.gid[on_edge]
    order = arrangement._sort_on_edges(X, e_of, ep, table)
    e_ptr = np.searchsorted(e_of[order], np.arange(X.n_edges + 1))
    t_of, ip = idx[inside], inter.gid[inside]
    io = np.argsort(t_of, kind="stable")
    t_ptr = np.searchsorted(t_of[io], np.arange(X.m + 1))
    seg = inter.seg_a if which == 0 else inter.seg_b
    seg = seg[np.argsort(seg[:, 0], kind="stable")]
    s_ptr = np.searchsorted(seg[:, 0], np.arange(X.m + 1))
    axis, sgn = arrangement._projection(X.P, X.T, aff)
    return aff, axis, sgn, T, X, e_ptr, ep[order], t_ptr, ip[io], seg, s_ptr, table


def test_chain_split_failures_fall_back_to_exact_splits(monkeypatch):
    """Every chain candidate rejected by the exact verification: the per-triangle splits take over
    and the Boolean is unchanged."""
    (V, F), (W, G) = _icospheres(2)
    a, b = from_mesh(V, F), from_mesh(W, G)
    want = {op: poly.boolean(a, b, op) for op in ("union", "intersection", "difference")}
    flag = {"on": False}
    real_orient, real_chain = arrangement._orient_projected, arrangement._chain_pieces

    def orient(F_, ids, table, axis, flip):
        if flag["on"]:
            return -np.ones(ids.shape[0], dtype=np.int8)
        return real_orient(F_, ids, table, axis, flip)

    def chain(*args):
        flag["on"] = True
        try:
            out = real_chain(*args)
        finally:
            flag["on"] = False
        assert not out[0].any()
        return out

    monkeypatch.setattr(arrangement, "_orient_projected", orient)
    monkeypatch.setattr(arrangement, "_chain_pieces", chain)
    for op, r in want.items():
        got = poly.boolean(a, b, op)
        assert got.check().ok
        np.testing.assert_allclose(got.volume, r.volume, rtol=VOL_RTOL)
        assert got.brep.n_faces == r.brep.n_faces


def test_chain_templates_are_splits_for_every_configuration():
    for k in range(arrangement._CHAIN_MAX + 1):
        for x in range(5):
            for y in range(x + 1, 5):
                corners = [i for i in range(5) if i not in (x, y)]
                if y - x == 1 and x + 1 not in corners:
                    continue
                # x and y on different edges: a corner lies between them both ways round
                if not any(x < c < y for c in corners) or all(x < c < y for c in corners):
                    continue
                for tp in arrangement._chain_templates(k, x, y):
                    assert tp.shape == (2 * k + 3, 3)
                    assert set(np.unique(tp).tolist()) == set(range(5 + k))


# ---------------------------------------------------------------------- classification and clean-up
@settings(max_examples=10)
@given(st.integers(0, 2**32 - 1), st.integers(9, 400))
def test_ray_candidates_sweep_matches_brute_force(seed, q):
    """Many ray boxes (the sweep on y or z) give the pairs of the brute-force box test; some queries sit
    exactly on triangle box faces (vertex coordinates), some are widened by an ulp as the exact queries are."""
    rng = np.random.default_rng(seed)
    (V, F), _ = _icospheres(2)
    Y = arrangement.operand(V, F, np.arange(F.shape[0]), "B")
    pts = rng.uniform(-1.2, 1.2, (q, 3))
    on = rng.random(q) < 0.3
    pts[on] = V[rng.integers(0, V.shape[0], int(on.sum()))]  # on box faces in every coordinate
    lo, hi = pts.copy(), pts.copy()
    wide = rng.random(q) < 0.5
    lo[wide], hi[wide] = np.nextafter(pts[wide], -np.inf), np.nextafter(pts[wide], np.inf)
    hi[:, 0] = np.maximum(float(V[:, 0].max()), hi[:, 0])
    assert q > poly._RAY_FEW
    I, J = poly._ray_candidates(lo, hi, Y)
    assert np.array_equal(np.sort(I * Y.m + J), _brute(lo, hi, Y.lo, Y.hi))
    I1, J1 = poly._ray_candidates(lo[:3], hi[:3], Y)  # the per-query loop
    assert np.array_equal(np.sort(I1 * Y.m + J1), _brute(lo[:3], hi[:3], Y.lo, Y.hi))


def test_ray_candidates_fall_back_to_the_grid_when_the_sweep_is_crowded(monkeypatch):
    (V, F), _ = _icospheres(2)
    Y = arrangement.operand(V, F, np.arange(F.shape[0]), "B")
    pts = np.random.default_rng(5).uniform(-1, 1, (50, 3))
    lo, hi = pts.copy(), pts.copy()
    hi[:, 0] = float(V[:, 0].max())
    want = _brute(lo, hi, Y.lo, Y.hi)
    monkeypatch.setattr(poly, "_RAY_SWEEP_MAX", 0)
    I, J = poly._ray_candidates(lo, hi, Y)
    assert want.size and np.array_equal(np.sort(I * Y.m + J), want)


def test_packed_stable_sort_equals_stable_argsort():
    from coons.topology.from_mesh import _stable_sort

    rng = np.random.default_rng(7)
    for key in (rng.integers(0, 40, 5000), rng.integers(0, 2**40, 3000), rng.integers(0, 2**61, 300),
                np.zeros(0, np.int64), np.array([5])):
        order, ks = _stable_sort(key)
        want = np.argsort(key, kind="stable")
        assert np.array_equal(order, want) and np.array_equal(ks, key[want])


def test_adjacency_patches_equal_sorted_patches():
    a = poly.union(coons.Box(2, 2, 2), coons.Box(2, 2, 2).translate((1, 1, 1)))  # polygon faces
    (V, F), _ = _icospheres(2)
    b = from_mesh(V * 1.3 + np.array([0.9, 0.3, 0.2]), F)  # crosses both boxes' faces
    # touching boxes: whole triangles of each meet across edges lying on the other's face
    c, d = coons.Box(2, 2, 2), coons.Box(2, 3, 2).translate((2, -0.5, 0))
    for x, y in ((a, b), (b, a), (c, d), (d, c)):
        A, B, inter, table, _ = _arrangement(x, y)
        for X, which in ((A, 0), (B, 1)):
            imp = poly._imprint(X, which, inter, table)
            touch = poly._touching(X, which, inter)
            n1, p1 = poly._patches(imp, X, table.float.shape[0], touch)
            n2, p2 = poly._patches(dataclasses.replace(imp, vid=None), X, table.float.shape[0], touch)
            assert n1 == n2 >= 2
            # the same partition: the labels map one to one
            pairs = np.unique(np.stack([p1, p2], axis=1), axis=0)
            assert pairs.shape[0] == n1


def test_clean_on_active_rows_equals_full_clean():
    # a short edge (1e-9) among active rows; the inactive rows are far away and untouched
    P = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1e-9, 0, 0], [5, 5, 5], [6, 5, 5], [5, 6, 5]], float)
    T = np.array([[0, 1, 2], [3, 1, 2], [4, 5, 6]])
    original = np.array([1, 1, 1, 0, 1, 1, 1], bool)
    full = poly._clean(P, T, original, 1e-7)
    part = poly._clean(P, T, original, 1e-7, np.array([True, True, False]))
    assert np.array_equal(np.sort(full, axis=0), np.sort(part, axis=0))
    # nothing active: returned unchanged without a search
    assert np.array_equal(poly._clean(P, T, original, 1e-7, np.zeros(3, bool)), T)


# ---------------------------------------------------------------------- from_mesh fast path
def test_fast_path_equals_from_mesh():
    import trimesh

    t = coons.DEFAULT_TOLERANCE
    for mesh in (trimesh.creation.icosphere(subdivisions=3), trimesh.creation.box(extents=(1, 2, 3)),
                 trimesh.creation.cylinder(radius=1, height=2, sections=24)):
        V, F = np.asarray(mesh.vertices), np.asarray(mesh.faces)
        for merge in (True, False):
            fast = _solid_from_clean_triangles(V, F, t, merge_coplanar=merge)
            ref = from_mesh(V, F, merge_coplanar=merge)
            assert ref.check().ok and fast.check().ok
            b, r = fast.brep, ref.brep
            assert (b.n_vertices, b.n_edges, b.n_faces, b.n_loops) == (r.n_vertices, r.n_edges, r.n_faces, r.n_loops)
            np.testing.assert_allclose(fast.volume, ref.volume, rtol=VOL_RTOL)


def test_fast_path_errors():
    t = coons.DEFAULT_TOLERANCE
    P = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], float)
    with pytest.raises(TopologyError, match="wrong sign"):
        _solid_from_clean_triangles(P, np.array([[0, 1, 2], [0, 3, 1], [0, 2, 3], [1, 3, 2]]), t)
    with pytest.raises(TopologyError, match="open"):
        _solid_from_clean_triangles(P, np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2]]), t)
    # a pinched vertex: the topological checks run
    Q = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1], [-1, 0, 0], [0, -1, 0], [0, 0, -1]], float)
    T = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3], [0, 4, 5], [0, 6, 4], [0, 5, 6], [4, 6, 5]])
    with pytest.raises(TopologyError, match="non-manifold-vertex"):
        _solid_from_clean_triangles(Q, T, t)


# ---------------------------------------------------------------------- straight vertices
@pytest.mark.parametrize("shift, counts", [
    ((1, 0, 0), {"union": (8, 12, 6), "intersection": (8, 12, 6), "difference": (8, 12, 6)}),
    ((0.3, 0.2, 0), None),
])
def test_vertices_on_straight_edges_are_removed(shift, counts):
    """Boxes sharing face planes: the merged faces keep no vertex in the middle of a straight edge
    (every vertex has three or more edges), the volumes are exact and the results check clean."""
    a = coons.Box(2, 2, 2)
    b = coons.Box(1, 1, 3).translate(shift) if counts is None else coons.Box(2, 2, 2).translate(shift)
    va, vb = a.volume, b.volume
    vi = poly.boolean(a, b, "intersection").volume
    for op, want in (("union", va + vb - vi), ("intersection", vi), ("difference", va - vi)):
        r = poly.boolean(a, b, op)
        br = r.brep
        assert r.check().ok
        np.testing.assert_allclose(r.volume, want, rtol=VOL_RTOL)
        assert np.bincount(br.edge_vertex.ravel()).min() >= 3
        if counts is not None:
            assert (br.n_vertices, br.n_edges, br.n_faces) == counts[op]


@pytest.mark.parametrize("shuffle", [False, True])
def test_straight_vertex_chains_are_removed_from_a_subdivided_cube(shuffle):
    """A cube whose faces are 16 x 16 grids: merging leaves chains of 15 straight vertices on every edge,
    removed over several rounds (independent sets), whatever the vertex numbering: 8 vertices, 12
    edges, 6 faces, volume 1, check clean."""
    import trimesh

    m = trimesh.creation.box(extents=(1, 1, 1))
    for _ in range(4):
        m = m.subdivide()
    V, F = np.asarray(m.vertices), np.asarray(m.faces)
    if shuffle:
        perm = np.random.default_rng(3).permutation(V.shape[0])
        V, F = V[perm], np.argsort(perm)[F]
    r = _solid_from_clean_triangles(V, F, coons.DEFAULT_TOLERANCE, merge_coplanar=True, straighten=True)
    assert (r.brep.n_vertices, r.brep.n_edges, r.brep.n_faces) == (8, 12, 6)
    np.testing.assert_allclose(r.volume, 1.0, rtol=VOL_RTOL)
    assert r.check().ok


def test_straight_vertex_removal_keeps_bent_corners():
    """A vertex with two edges that is not on the segment between its neighbours stays (here: none are
    removed from an L-shaped prism whose every vertex is a corner)."""
    from coons.topology.from_mesh import _remove_straight_vertices

    l_shape = poly.union(coons.Box(2, 1, 1).translate((1, 0.5, 0.5)), coons.Box(1, 2, 1).translate((0.5, 1, 0.5)))
    cols = {k: getattr(l_shape.brep, k) for k in l_shape.brep.__dataclass_fields__}
    assert _remove_straight_vertices(cols, coons.DEFAULT_TOLERANCE) is cols
    assert l_shape.brep.n_vertices == 12 and l_shape.check().ok


def test_bad_chain_candidates_in_the_per_triangle_loop_are_redone_exactly(monkeypatch):
    """The per-triangle loop's predicate-free candidates (:func:`_chain_split`) that fail the vectorised
    verification are split again by the exact incremental split: here every candidate is turned
    inside out, and the Booleans are unchanged."""
    (V, F), (W, G) = _icospheres(2)
    a, b = from_mesh(V, F), from_mesh(W, G)
    want = {op: poly.boolean(a, b, op) for op in ("union", "difference")}
    real_split = arrangement._chain_split
    calls = {"bad": 0}

    def none_done(aff, *args):
        return np.zeros(aff.size, dtype=bool), np.zeros((0, 3), np.int64), np.zeros(0, np.int64)

    def inside_out(*args):
        tri = real_split(*args)
        if tri is not None:
            calls["bad"] += 1
            tri = tri[:, ::-1].copy()
        return tri

    monkeypatch.setattr(arrangement, "_chain_pieces", none_done)
    monkeypatch.setattr(arrangement, "_chain_split", inside_out)
    for op, r in want.items():
        got = poly.boolean(a, b, op)
        assert got.check().ok
        np.testing.assert_allclose(got.volume, r.volume, rtol=VOL_RTOL)
    assert calls["bad"] > 0


# ---------------------------------------------------------------------- pattern splits
def _plate_minus_prisms(n: int, rotation=None):
    """A plate minus one tool of ``n × n`` square prisms through it, optionally turned as a whole."""
    import trimesh

    plate = trimesh.creation.box(extents=(n + 2.0, n + 2.0, 1.0))
    cube = trimesh.creation.box(extents=(0.5, 0.5, 3.0))
    Vs, Fs = [], []
    for i in range(n):
        for j in range(n):
            Vs.append(np.asarray(cube.vertices) + [i - (n - 1) / 2, j - (n - 1) / 2, 0.0])
            Fs.append(np.asarray(cube.faces) + 8 * (i * n + j))
    PV, TV = np.asarray(plate.vertices), np.concatenate(Vs)
    if rotation is not None:
        PV, TV = PV @ rotation.T, TV @ rotation.T
    return from_mesh(PV, np.asarray(plate.faces)), from_mesh(TV, np.concatenate(Fs))


def _no_patterns(rest, *args):
    return rest, []


@pytest.mark.parametrize("turned", [False, True])
def test_pattern_splits_equal_per_triangle_splits(monkeypatch, turned):
    """The prism sides of a perforated plate, each cut by the plate's two faces, are split by the
    pattern of one of them (vectorised); the result equals the one-by-one splits and the closed
    form, also turned by a rotation (then the sides' exact points differ from pattern to member)."""
    from scipy.spatial.transform import Rotation

    n = 6
    R = Rotation.from_rotvec([0.3, -0.2, 0.5]).as_matrix() if turned else None
    plate, tool = _plate_minus_prisms(n, R)
    real = arrangement._patterns
    seen = {"members": 0}

    def spy(*args):
        reps, groups = real(*args)
        seen["members"] += sum(g[1].size for g in groups)
        return reps, groups

    monkeypatch.setattr(arrangement, "_patterns", spy)
    got = plate - tool
    assert seen["members"] >= 4 * n * n  # most of the 8 n² side triangles
    monkeypatch.setattr(arrangement, "_patterns", _no_patterns)
    want = plate - tool
    for r in (got, want):
        assert r.check().ok
        np.testing.assert_allclose(r.volume, (n + 2.0) ** 2 - 0.25 * n * n, rtol=1e-12)
    assert got.brep.n_faces == want.brep.n_faces == 2 + 4 + 4 * n * n
    np.testing.assert_allclose(got.area, want.area, rtol=VOL_RTOL)


def test_pattern_failures_fall_back_to_per_triangle_splits(monkeypatch):
    """A pattern whose pieces are not counter-clockwise for a member's exact points leaves that member
    to the one-by-one split: here every member is refused, and the Boolean is unchanged."""
    plate, tool = _plate_minus_prisms(4)
    want = plate - tool
    real_apply, real_ccw = arrangement._apply_patterns, arrangement._ccw_rows
    flag = {"on": False, "again": 0}

    def ccw(G, prow, axis, sgn, table):
        good = real_ccw(G, prow, axis, sgn, table)
        return np.zeros_like(good) if flag["on"] else good

    def apply(*args):
        flag["on"] = True
        try:
            G, src, again = real_apply(*args)
        finally:
            flag["on"] = False
        assert G.shape[0] == 0 and again.size > 0
        flag["again"] += again.size
        return G, src, again

    monkeypatch.setattr(arrangement, "_ccw_rows", ccw)
    monkeypatch.setattr(arrangement, "_apply_patterns", apply)
    got = plate - tool
    assert flag["again"] > 0 and got.check().ok
    np.testing.assert_allclose(got.volume, want.volume, rtol=VOL_RTOL)
    assert got.brep.n_faces == want.brep.n_faces


@pytest.mark.parametrize("case", ["spheres", "turned plate"])
def test_clean_searching_changed_rows_leaves_no_feature_anywhere(monkeypatch, case):
    """Each round of the clean-up searches only the rows the previous round changed; what it returns
    has no short edge, cancelling pair or cap in any row (a full search changes nothing)."""
    from scipy.spatial.transform import Rotation

    if case == "spheres":  # level 5: intersection points within 1e-16 of sphere vertices
        (V, F), (W, G) = _icospheres(5)
        a, b = from_mesh(V, F), from_mesh(W, G)
    else:
        a, b = _plate_minus_prisms(6, Rotation.from_rotvec([0.3, -0.2, 0.5]).as_matrix())
    real = poly._clean
    seen = []

    def spy(P, T, original, eps, active=None):
        out = real(P, T, original, eps, active)
        seen.append((P, T, out, original, eps))
        return out

    monkeypatch.setattr(poly, "_clean", spy)
    r = a - b if case != "spheres" else a + b
    assert r.check().ok and seen
    for P, T, out, original, eps in seen:
        assert out is not T  # the clean-up had features to remove
        assert real(P, out, original, eps) is out
