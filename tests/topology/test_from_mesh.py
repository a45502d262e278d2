"""from_mesh: polyhedral solids from closed triangle meshes.

Properties asserted: the B-rep is clean (``check``), counts follow the mesh (F = m, E = 3m/2,
V = used distinct vertices, Euler–Poincaré with the genus), the volume equals the mesh's
signed volume (closed form; trimesh for its meshes), exact duplicates merge, voids nest by the
even–odd rule (with a warning when an orientation is healed), coplanar merging gives the
expected polygon faces (holes, genus, exact and tolerance paths, drift guard), and every
rejection names the offending edge, triangle or vertex.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest
import trimesh
from hypothesis import given
from hypothesis import strategies as st

from coons.errors import InvalidInputError, TopologyError
from coons.tolerance import Tolerance
from coons.topology.check import check
from coons.topology.from_mesh import from_mesh
from coons.topology.mesh import TriangleMesh

#: Round-off allowance for volumes summed over many triangles.
VOLUME_RTOL = 1e-12

#: Outward triangles of the cube whose vertex ``i`` has coordinate bits ``(i >> 2, i >> 1, i) & 1``
#: (trimesh.creation.box's numbering and orientation).
CUBE_T = np.array([[1, 3, 0], [4, 1, 0], [0, 3, 2], [2, 4, 0], [1, 7, 3], [5, 1, 4],
                   [5, 7, 1], [3, 7, 2], [6, 4, 2], [2, 7, 6], [6, 5, 4], [7, 5, 6]])
TET_V = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], float)
TET_T = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])


def cube(lo, hi) -> tuple[np.ndarray, np.ndarray]:
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    bits = (np.arange(8)[:, None] >> np.array([2, 1, 0])) & 1
    return lo + bits * (hi - lo), CUBE_T.copy()


def join(*parts: tuple[np.ndarray, np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    V, T, n = [], [], 0
    for v, t in parts:
        V.append(v)
        T.append(t + n)
        n += len(v)
    return np.concatenate(V), np.concatenate(T)


def reversed_mesh(part):
    v, t = part
    return v, t[:, ::-1].copy()


def counts(s):
    b = s.brep
    return b.n_vertices, b.n_edges, b.n_faces, b.n_loops, b.n_shells, b.n_solids


# ============================================================================ valid meshes
def test_tetrahedron_tables_and_volume():
    s = from_mesh(TET_V, TET_T)
    assert counts(s) == (4, 6, 4, 4, 1, 1)
    assert s.brep.face_surface.tolist() == [-1] * 4 and s.brep.edge_curve.tolist() == [-1] * 6
    np.testing.assert_allclose(s.volume, 1 / 6, rtol=VOLUME_RTOL)
    np.testing.assert_allclose(s.area, 1.5 + np.sqrt(3) / 2, rtol=VOLUME_RTOL)
    # Faces are the triangles in order: each face's loop visits the triangle's vertices cyclically.
    for f, tri in enumerate(TET_T):
        ring = [v.index for v in s.faces()[f].outer_loop.vertices()]
        k = ring.index(int(tri[0]))
        assert ring[k:] + ring[:k] == tri.tolist()


def test_icosphere_level_7_is_clean_and_matches_trimesh():
    ico = trimesh.creation.icosphere(subdivisions=7)
    s = from_mesh(ico)
    m, n = len(ico.faces), len(ico.vertices)
    assert counts(s) == (n, 3 * m // 2, m, m, 1, 1)
    assert n - 3 * m // 2 + m == 2  # Euler: a sphere
    np.testing.assert_allclose(s.volume, ico.volume, rtol=VOLUME_RTOL)
    np.testing.assert_allclose(s.area, ico.area, rtol=VOLUME_RTOL)
    np.testing.assert_array_equal(s.brep.vertex_point, ico.vertices)  # no duplicates: order kept


def test_torus_mesh_has_genus_one():
    tm = trimesh.creation.torus(major_radius=3, minor_radius=1, major_sections=40, minor_sections=20)
    s = from_mesh(tm)
    V, E, F, *_ = counts(s)
    assert V - E + F == 0
    np.testing.assert_allclose(s.volume, tm.volume, rtol=VOLUME_RTOL)
    assert check(s).ok


def test_accepts_trimesh_and_triangle_mesh_objects():
    box = trimesh.creation.box((2, 3, 4))
    a = from_mesh(box)
    b = from_mesh(TriangleMesh(box.vertices, box.faces))
    c = from_mesh(np.asarray(box.vertices).tolist(), np.asarray(box.faces).tolist())
    for s in (a, b, c):
        assert counts(s) == (8, 18, 12, 12, 1, 1)
        np.testing.assert_allclose(s.volume, 24.0, rtol=VOLUME_RTOL)


def test_exact_duplicates_merge_and_unused_vertices_are_dropped():
    V, T = cube([0, 0, 0], [1, 2, 3])
    soup = V[T].reshape(-1, 3)  # every triangle has its own three vertices
    soup = np.concatenate([[[9.0, 9.0, 9.0]], soup])  # an unused vertex first
    s = from_mesh(soup, np.arange(1, 37).reshape(12, 3))
    assert counts(s) == (8, 18, 12, 12, 1, 1)
    np.testing.assert_allclose(s.volume, 6.0, rtol=VOLUME_RTOL)
    # Vertices keep the order of their first occurrence in the input.
    first = soup[1:][np.sort(np.unique(soup[1:], axis=0, return_index=True)[1])]
    np.testing.assert_array_equal(s.brep.vertex_point, first)


def test_negative_zero_merges_with_zero():
    V, T = cube([-1, -1, -1], [0, 0, 0])
    soup = V[T].reshape(-1, 3)
    soup[soup == 0.0] = -0.0
    soup[:3][soup[:3] == -0.0] = 0.0
    s = from_mesh(soup, np.arange(36).reshape(12, 3))
    assert s.brep.n_vertices == 8


@given(
    st.floats(0.1, 10), st.floats(0.1, 10), st.floats(0.1, 10),
    st.tuples(st.floats(-100, 100), st.floats(-100, 100), st.floats(-100, 100)),
)
def test_box_volume_and_validity(a, b, c, offset):
    V, T = cube(offset, np.add(offset, (a, b, c)))
    s = from_mesh(V, T)
    np.testing.assert_allclose(s.volume, a * b * c, rtol=1e-9)
    assert check(s).ok
    m = from_mesh(V, T, merge_coplanar=True)
    assert counts(m) == (8, 12, 6, 6, 1, 1)
    np.testing.assert_allclose(m.volume, a * b * c, rtol=1e-9)


# ============================================================================ shells, voids, orientation
def test_hollow_cube_is_one_solid_with_a_void():
    s = from_mesh(*join(cube([0, 0, 0], [4, 4, 4]), reversed_mesh(cube([1, 1, 1], [3, 3, 3]))))
    b = s.brep
    assert (b.n_shells, b.n_solids) == (2, 1)
    assert b.solid_shell_ptr.tolist() == [0, 2] and b.solid_shells.tolist() == [0, 1]
    np.testing.assert_allclose(s.volume, 64 - 8, rtol=VOLUME_RTOL)


def test_misoriented_void_is_reversed_with_a_warning():
    with pytest.warns(UserWarning, match=r"reversed the triangles of 1 component\(s\) \(component ids \[1\]\)"):
        s = from_mesh(*join(cube([0, 0, 0], [4, 4, 4]), cube([1, 1, 1], [3, 3, 3])))
    np.testing.assert_allclose(s.volume, 56, rtol=VOLUME_RTOL)


def test_inward_mesh_is_reversed_with_a_warning():
    with pytest.warns(UserWarning, match="reversed"):
        s = from_mesh(TET_V, TET_T[:, ::-1])
    np.testing.assert_allclose(s.volume, 1 / 6, rtol=VOLUME_RTOL)


def test_island_in_a_void_is_a_second_lump():
    parts = join(cube([0, 0, 0], [6, 6, 6]), reversed_mesh(cube([1, 1, 1], [5, 5, 5])), cube([2, 2, 2], [4, 4, 4]))
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # already oriented by the even-odd rule: no healing
        s = from_mesh(*parts)
    b = s.brep
    assert (b.n_shells, b.n_solids) == (3, 2)
    assert [s_.index for s_ in s.lumps()[0].shells()] == [0, 1] and [s_.index for s_ in s.lumps()[1].shells()] == [2]
    np.testing.assert_allclose(s.volume, 216 - 64 + 8, rtol=VOLUME_RTOL)


def test_disjoint_components_are_separate_lumps():
    s = from_mesh(*join(cube([0, 0, 0], [1, 1, 1]), cube([2, 0, 0], [3, 2, 1])))
    assert (s.brep.n_shells, s.brep.n_solids) == (2, 2)
    np.testing.assert_allclose(s.volume, 3.0, rtol=VOLUME_RTOL)


def test_overlapping_containers_are_refused():
    parts = join(cube([0, 0, 0], [4, 4, 4]), cube([1, 1, 1], [5, 5, 5]), reversed_mesh(cube([2, 2, 2], [3, 3, 3])))
    with pytest.raises(TopologyError, match=r"component 2 lies inside components \[0, 1\] that do not nest"):
        from_mesh(*parts)


def test_flat_component_is_refused():
    V = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], float)
    with pytest.raises(TopologyError, match="component 0 .* indistinguishable from 0"):
        from_mesh(V, [[0, 1, 2], [0, 2, 1]])


# ============================================================================ coplanar merging
def test_merge_coplanar_plate_with_a_hole_exact_and_within_tolerance():
    """A 4x4x1 plate with a 2x2 square hole: top and bottom become faces with a hole (genus 1)."""
    import manifold3d as m3

    plate = m3.Manifold.cube([4, 4, 1]) - m3.Manifold.cube([2, 2, 3]).translate([1, 1, -1])
    mesh = plate.to_mesh()
    V = np.asarray(mesh.vert_properties)[:, :3].astype(np.float64)
    T = np.asarray(mesh.tri_verts).astype(np.int64)
    for scale in (1.0, 0.1):  # integer coordinates: exact predicate; scaled: within tol.linear
        s = from_mesh(V * scale, T, merge_coplanar=True)
        b = s.brep
        assert (b.n_faces, b.n_vertices, b.n_edges) == (10, 16, 24)
        loops_per_face = sorted(len(f.loops()) for f in s.faces())
        assert loops_per_face == [1] * 8 + [2] * 2
        V_, E_, F_, L_ = b.n_vertices, b.n_edges, b.n_faces, b.n_loops
        assert V_ - E_ + F_ - (L_ - F_) == 0  # 2 (1 - genus), genus 1
        np.testing.assert_allclose(s.volume, 12.0 * scale**3, rtol=VOLUME_RTOL)
        for f in s.faces():  # holes run clockwise: the inner loop's area vector opposes the outer's
            if len(f.loops()) == 2:
                areas = [np.cross(P := np.array([v.point for v in l.vertices()]), np.roll(P, -1, 0)).sum(0)
                         for l in f.loops()]
                assert np.dot(areas[0], areas[1]) < 0


def test_merge_coplanar_keeps_collinear_vertices_and_matches_unmerged_volume():
    b = trimesh.creation.box((2, 2, 2)).subdivide().subdivide()
    s = from_mesh(b, merge_coplanar=True)
    assert s.brep.n_faces == 6
    V, E, F, L = s.brep.n_vertices, s.brep.n_edges, s.brep.n_faces, s.brep.n_loops
    assert V - E + F == 2 and L == F
    np.testing.assert_allclose(s.volume, 8.0, rtol=VOLUME_RTOL)


def test_merge_coplanar_leaves_a_slightly_bent_region_triangulated():
    """Each pair of neighbours on the bent top is within tol.linear of coplanar, the region is not."""
    b = trimesh.creation.box((2, 2, 2))
    for _ in range(4):
        b = b.subdivide()
    V = b.vertices.copy()
    top = V[:, 2] == 1.0
    V[top, 2] += 2e-6 * V[top, 0] ** 2  # sagitta 2e-6 over the face, 3e-8 between neighbours
    n_top = int(np.all(top[b.faces], axis=1).sum())
    s = from_mesh(V, b.faces, merge_coplanar=True)
    assert s.brep.n_faces == 5 + n_top
    assert check(s).ok


def test_merge_coplanar_on_a_curved_mesh_changes_nothing():
    ico = trimesh.creation.icosphere(subdivisions=3)
    assert counts(from_mesh(ico, merge_coplanar=True)) == counts(from_mesh(ico))


def test_merge_coplanar_cylinder_caps():
    cyl = trimesh.creation.cylinder(radius=1, height=2, sections=64)
    s = from_mesh(cyl, merge_coplanar=True)
    # Two 64-gon caps; the side quads stay split along their diagonals only if not coplanar: they are.
    assert s.brep.n_faces == 2 + 64
    np.testing.assert_allclose(s.volume, cyl.volume, rtol=VOLUME_RTOL)


# ============================================================================ rejections
def test_open_mesh_names_the_edge():
    V, T = cube([0, 0, 0], [1, 1, 1])
    # Without triangle [1, 3, 0] the first triangle [4, 1, 0] has the open edge 1 -> 0.
    with pytest.raises(TopologyError, match=r"the mesh is open: the edge between vertices 1 \[0.0, 0.0, 1.0\] and "
                                            r"0 \[0.0, 0.0, 0.0\] is used by one triangle \(0\)"):
        from_mesh(V, T[1:])


def test_non_manifold_edge_names_the_edge_and_its_triangles():
    # Two tetrahedra glued along the edge (0, 1): it is used by four triangles.
    V = np.concatenate([TET_V, [[0.0, -1.0, 0.0], [0.0, 0.0, -1.0]]])
    T = np.concatenate([TET_T, [[0, 1, 4], [0, 5, 1], [0, 4, 5], [1, 5, 4]]])
    with pytest.raises(TopologyError, match=r"non-manifold edge: the edge between vertices 1 \[1.0, 0.0, 0.0\] and "
                                            r"0 \[0.0, 0.0, 0.0\] is used by 4 triangles \[0, 1, 4, 5\]; expected 2"):
        from_mesh(V, T)


def test_inconsistent_orientation_names_both_triangles():
    T = TET_T.copy()
    T[3] = T[3, ::-1]
    with pytest.raises(TopologyError, match=r"inconsistent orientation: triangles 0 and 3 both run the edge between "
                                            r"vertices 2 \[0.0, 1.0, 0.0\] and 1 \[1.0, 0.0, 0.0\] from vertex 2 to 1"):
        from_mesh(TET_V, T)


def test_degenerate_triangles_are_named():
    V = np.concatenate([TET_V, [[0.5, 0.0, 0.0]]])
    with pytest.raises(TopologyError, match=r"triangle 2 \(vertices \[0, 1, 4\] .*\) is degenerate: its height 0 "):
        from_mesh(V, [[0, 2, 1], [0, 4, 3], [0, 1, 4], [1, 2, 3]])
    with pytest.raises(TopologyError, match=r"triangle 1 \(vertices \[0, 1, 1\]"):
        from_mesh(TET_V, [[0, 2, 1], [0, 1, 1], [0, 3, 2], [1, 2, 3]])
    # Within tolerance of a line: the middle vertex 1e-8 off the segment.
    V[4, 1] = 1e-8
    with pytest.raises(TopologyError, match="triangle 2 .* is degenerate: its height 1e-08"):
        from_mesh(V, [[0, 2, 1], [0, 4, 3], [0, 1, 4], [1, 2, 3]])
    # A larger tolerance makes a thin but valid sliver degenerate.
    with pytest.raises(TopologyError, match=r"triangle 0 .* is not above the linear tolerance 2"):
        from_mesh(TET_V, TET_T, tol=Tolerance(linear=2.0))


def test_non_manifold_vertex_is_reported_with_its_coordinates():
    # A second, mirrored tetrahedron touching the first at vertex 0 only.
    V = np.concatenate([TET_V, -TET_V[1:]])
    T = np.concatenate([TET_T, np.array([0, 4, 5, 6])[TET_T[:, ::-1]]])
    with pytest.raises(TopologyError, match=r"non-manifold-vertex \[vertex 0\](.|\n)*vertex 0 is input vertex 0 at "
                                            r"\[0.0, 0.0, 0.0\]"):
        from_mesh(V, T)


@pytest.mark.parametrize(
    ("vertices", "triangles", "message"),
    [
        (np.zeros((4, 2)), TET_T, r"vertices must have shape \(n, 3\), got \(4, 2\)"),
        ("abc", TET_T, "vertices must be an"),
        (np.array([[0, 0, np.nan], [1, 0, 0], [0, 1, 0], [0, 0, 1]]), TET_T, r"vertex 0 is \[0.0, 0.0, nan\]"),
        (TET_V, TET_T[:, :2], r"triangles must have shape \(m, 3\), got \(4, 2\)"),
        (TET_V, np.zeros((0, 3), int), "triangles is empty"),
        (TET_V, TET_T + 0.5, "triangles must hold integer vertex indices"),
        (TET_V, TET_T + 1, r"triangle 1 has vertex indices \[1, 2, 4\]; expected indices in 0..3"),
        (object(), None, "needs vertices and triangles arrays, or one object with .vertices"),
    ],
)
def test_invalid_input(vertices, triangles, message):
    with pytest.raises(InvalidInputError, match=message):
        from_mesh(vertices, triangles)


def test_float_indices_that_are_integers_are_accepted():
    assert from_mesh(TET_V, TET_T.astype(float)).brep.n_faces == 4


def test_coplanarity_is_exact_for_integer_coordinates_and_tolerant_otherwise():
    """A box whose top corner is raised by 1: two top triangles 1 unit apart from coplanar.

    With ``tol.linear = 2`` the tolerance test merges them, the exact predicate (integer input)
    does not.
    """
    V, T = cube([0, 0, 0], [100, 100, 100])
    V[7, 2] += 1.0  # corner (100, 100, 100): the top triangles [1, 7, 3] and [5, 7, 1] fold along 1-7; sides stay flat
    tol = Tolerance(linear=2.0)
    exact = from_mesh(V, T, merge_coplanar=True, tol=tol)
    tolerant = from_mesh(V + 0.5, T, merge_coplanar=True, tol=tol)
    assert exact.brep.n_faces == 7
    assert tolerant.brep.n_faces == 6
    np.testing.assert_allclose(exact.volume, tolerant.volume, rtol=VOLUME_RTOL)


# ============================================================================ equivalence with assemble
def assembled(solid, T, nest=None):
    """The same mesh through ``BRepBuilder.assemble`` (edges and their directions taken from ``solid``)."""
    from coons.topology.builder import BRepBuilder

    ev = solid.brep.edge_vertex
    index = {(int(a), int(b)): e for e, (a, b) in enumerate(ev)}
    loops = []
    for tri in T:
        refs = []
        for k in range(3):
            a, b = int(tri[k]), int(tri[(k + 1) % 3])
            refs.append(index[(a, b)] + 1 if (a, b) in index else -(index[(b, a)] + 1))
        loops.append([refs])
    builder = BRepBuilder()
    builder.assemble(solid.brep.vertex_point, ev, loops)
    if nest:
        builder.nest_shells(*nest)
    return builder.build()


@pytest.mark.parametrize("case", ["tet", "torus", "hollow"])
def test_tables_equal_those_of_assemble(case):
    """from_mesh builds, without a Python loop, exactly the tables assemble + build make."""
    import dataclasses

    nest = None
    if case == "tet":
        V, T = TET_V, TET_T
    elif case == "torus":
        tm = trimesh.creation.torus(major_radius=2, minor_radius=0.5, major_sections=12, minor_sections=8)
        V, T = np.asarray(tm.vertices), np.asarray(tm.faces)
    else:
        V, T = join(cube([0, 0, 0], [4, 4, 4]), reversed_mesh(cube([1, 1, 1], [3, 3, 3])))
        nest = (0, 1)
    solid = from_mesh(V, T)
    ref = assembled(solid, T, nest)
    for f in dataclasses.fields(ref):
        a, b = getattr(solid.brep, f.name), getattr(ref, f.name)
        if isinstance(a, np.ndarray):
            np.testing.assert_array_equal(a, b, err_msg=f.name)
        else:
            assert len(a) == len(b) == 0, f.name


def test_a_flat_tetrahedron_is_rejected_whatever_its_rounded_volume():
    """Four nearly coplanar points (the doubly covered square left by two touching boxes, rotated):
    the float volume 3e-17 is round-off of determinants whose permanents are ~0.1, not a solid."""
    from coons.errors import TopologyError
    from coons.topology.from_mesh import from_mesh

    P = np.array([[-0.14417636, -2.70056864, -3.16151533], [-0.56570152, -3.13338301, -4.44018192],
                  [0.27186095, -2.73125141, -4.07034508], [-0.98173883, -3.10270023, -3.53135216]])
    # Put the fourth point exactly on the plane of the first three, then one ulp-scale nudge off it.
    n = np.cross(P[1] - P[0], P[2] - P[0])
    P[3] -= (P[3] - P[0]) @ n / (n @ n) * n
    P[3] += 1e-16 * n / np.linalg.norm(n)
    T = np.array([[0, 2, 1], [0, 1, 3], [1, 2, 3], [3, 2, 0]])
    with pytest.raises(TopologyError, match="indistinguishable from 0"):
        from_mesh(P, T)


def test_signed_volumes_from_the_normals_agree_with_the_determinants():
    """The three-gather form used with ``_columns`` (the Booleans' sew) against the nine-gather determinant."""
    from coons.topology import from_mesh as fm

    rng = np.random.default_rng(5)
    P = rng.normal(size=(60, 3)) * 10.0 + 3.0
    T = np.stack([rng.permutation(60)[:3] for _ in range(200)])
    v0, perm0 = fm._signed_volumes(P, T)
    v1, perm1 = fm._signed_volumes(P, T, fm._columns(P, T))
    np.testing.assert_allclose(v1, v0, rtol=1e-12, atol=1e-12 * float(np.max(perm0)))
    assert np.all(np.abs(v1 - v0) <= 64 * np.finfo(float).eps * (perm0 + perm1))
    assert np.all(perm1 >= 0)


def test_components_on_known_connected_groups_match_the_triangle_labelling():
    """``_components`` with ``groups`` (the Booleans' patches) gives the same partition as without."""
    from coons.topology import from_mesh as fm

    # Two disjoint tetrahedra: triangle groups {0, 1}, {2, 3} (connected), {4}, {5, 6, 7}.
    T = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])
    T = np.concatenate([T, T + 4])
    P = np.concatenate([np.eye(4, 3), np.eye(4, 3) + 5.0])
    a, b = fm._pair_half_edges(P, T, np.arange(8))
    plain, n_plain = fm._components(8, a // 3, b // 3)
    groups = np.array([7, 7, 2, 2, 9, 4, 4, 4])  # labels need not be consecutive
    hinted, n_hinted = fm._components(8, a // 3, b // 3, groups)
    assert n_plain == n_hinted == 2
    # the same partition (numbering may differ)
    assert len({(int(x), int(y)) for x, y in zip(plain, hinted)}) == 2


def test_components_reject_bad_groups():
    from coons.topology import from_mesh as fm

    ta, tb = np.array([0]), np.array([1])
    with pytest.raises(InvalidInputError, match=r"groups must have shape \(2,\), got \(3,\)"):
        fm._components(2, ta, tb, np.zeros(3, dtype=np.int64))
    with pytest.raises(InvalidInputError, match="groups must be labels >= 0, got -1"):
        fm._components(2, ta, tb, np.array([0, -1]))


def test_wings_are_the_stacked_coedge_pointers():
    from coons.topology.from_mesh import _wings

    rng = np.random.default_rng(9)
    prv, nxt = rng.integers(0, 50, 50), rng.integers(0, 50, 50)
    np.testing.assert_array_equal(_wings(prv, nxt), np.stack([prv[0::2], nxt[0::2], prv[1::2], nxt[1::2]], axis=1))


def test_triangle_distances_match_dense_samples():
    from coons.topology.from_mesh import _triangle_distances

    rng = np.random.default_rng(7)
    tri = rng.normal(size=(40, 3, 3))
    tri[0, 2] = tri[0, 0] + 0.5 * (tri[0, 1] - tri[0, 0])  # a degenerate (collinear) triangle
    s, t = np.meshgrid(np.linspace(0, 1, 201), np.linspace(0, 1, 201))
    keep = s + t <= 1
    s, t = s[keep], t[keep]
    for p in rng.normal(scale=2.0, size=(5, 3)):
        d = _triangle_distances(p, tri)
        X = tri[:, None, 0] + s[None, :, None] * (tri[:, None, 1] - tri[:, None, 0]) + t[None, :, None] * (
            tri[:, None, 2] - tri[:, None, 0])
        sampled = np.linalg.norm(X - p, axis=2).min(axis=1)
        assert (d <= sampled + 1e-12).all()  # never above a point of the triangle
        np.testing.assert_allclose(d, sampled, atol=0.02)  # and within the sampling's spacing of the minimum
    # Exactly: the plane's foot inside, and a vertex region.
    unit = np.array([[[0.0, 0, 0], [1, 0, 0], [0, 1, 0]]])
    np.testing.assert_allclose(_triangle_distances(np.array([0.2, 0.2, 3.0]), unit), [3.0])
    np.testing.assert_allclose(_triangle_distances(np.array([-3.0, -4.0, 0.0]), unit), [5.0])
