"""Meshes of coons solids as trimesh and manifold3d see them (watertight, winding-consistent, manifold,
same volumes), round trips, STL export of solids, OCCT's BRepMesh as a reference, and error branches."""

from __future__ import annotations

import math

import manifold3d
import numpy as np
import pytest
import trimesh

from coons.errors import InvalidInputError
from coons.io.mesh import as_triangle_mesh, mesh_from_trimesh, to_manifold, to_trimesh
from coons.io.stl import export_stl, import_stl
from coons.topology.mesh import TriangleMesh
from coons.topology.primitives import Box, Cone, Cylinder, Sphere, Torus
from coons.topology.tessellate import tessellate

pytestmark = pytest.mark.manifold

#: manifold3d stores float32 positions: volumes agree to float32 round-off of the coordinates.
FLOAT32_RTOL = 1e-5

SOLIDS = {
    "box": lambda: Box(1.0, 2.0, 3.0),
    "cylinder": lambda: Cylinder(1.0, 2.0),
    "cone": lambda: Cone(1.0, 0.0, 2.0),
    "frustum": lambda: Cone(1.0, 0.4, 1.5),
    "sphere": lambda: Sphere(1.0),
    "torus": lambda: Torus(2.0, 0.5),
    "moved torus": lambda: Torus(2.0, 0.5).rotate((1, 0, 0), (1, 1, 0), 30).translate((3, 4, 5)).scale(0.5),
    "mirrored cone": lambda: Cone(1.0, 0.0, 2.0).mirror((0, 0, 0), (1, 2, 3)),
    "moved sphere": lambda: Sphere(2.0).rotate((0, 0, 0), (0, 1, 1), 70).translate((-1, 0, 2)),
}
GENUS = {"torus": 1, "moved torus": 1}


@pytest.mark.parametrize("deflection", [1e-1, 1e-2, 1e-3])
@pytest.mark.parametrize("name", list(SOLIDS))
def test_trimesh_and_manifold3d_accept_every_primitive(name, deflection):
    s = SOLIDS[name]()
    m = tessellate(s, deflection=deflection)
    tm = to_trimesh(m)
    assert tm.is_watertight and tm.is_winding_consistent and tm.is_volume
    np.testing.assert_array_equal(tm.vertices, m.vertices)  # our order, unprocessed
    np.testing.assert_array_equal(tm.faces, m.triangles)
    np.testing.assert_allclose(tm.volume, m.volume, rtol=1e-12)
    np.testing.assert_allclose(tm.area, m.area, rtol=1e-12)
    mf = to_manifold(m)
    assert mf.status() == manifold3d.Error.NoError
    assert mf.num_tri() == m.n_triangles and mf.num_vert() == m.n_vertices
    assert mf.genus() == GENUS.get(name, 0)
    np.testing.assert_allclose(mf.volume(), m.volume, rtol=FLOAT32_RTOL)
    assert abs(m.volume - s.volume) <= deflection * s.area


def test_solids_convert_directly_with_tessellation_arguments():
    s = Sphere(1.0)
    tm = to_trimesh(s, deflection=0.05)
    assert tm.is_watertight and len(tm.faces) == tessellate(s, deflection=0.05).n_triangles
    assert np.array_equal(tm.face_attributes["face_ids"], tessellate(s, deflection=0.05).face_ids)
    mf = to_manifold(s.brep, deflection=0.05, angular_deflection=0.3)
    assert mf.num_tri() == tessellate(s, deflection=0.05, angular_deflection=0.3).n_triangles
    assert as_triangle_mesh(s, deflection=0.05).is_closed


def test_trimesh_round_trip_keeps_arrays_and_face_ids():
    m = tessellate(Torus(2.0, 0.5), deflection=0.05)
    back = mesh_from_trimesh(to_trimesh(m))
    np.testing.assert_array_equal(back.vertices, m.vertices)
    np.testing.assert_array_equal(back.triangles, m.triangles)
    np.testing.assert_array_equal(back.face_ids, m.face_ids)
    plain = mesh_from_trimesh(trimesh.creation.icosphere(subdivisions=2))
    assert plain.face_ids is None and plain.is_closed and plain.n_triangles == 320


def test_manifold_booleans_of_tessellations_behave():
    a = to_manifold(Box(2.0, 2.0, 2.0), deflection=1e-3)
    b = to_manifold(Sphere(1.2), deflection=1e-3)
    inter = a ^ b
    assert inter.status() == manifold3d.Error.NoError and inter.genus() == 0
    # Box ∩ ball of radius 1.2: the ball minus six caps of height 0.2.
    cap = math.pi * 0.2**2 * (3 * 1.2 - 0.2) / 3
    exact = 4 / 3 * math.pi * 1.2**3 - 6 * cap
    assert abs(inter.volume() - exact) < 1e-3 * 20  # deflection × (area of the pieces)


def test_stl_export_of_solids(tmp_path):
    s = Cylinder(1.0, 2.0)
    path = export_stl(s, tmp_path / "c.stl")
    V, T = import_stl(path)
    m = tessellate(s)  # the default deflection
    assert T.shape == m.triangles.shape
    back = TriangleMesh(V, T)
    assert back.is_closed
    np.testing.assert_allclose(back.volume, m.volume, rtol=1e-6)  # float32 coordinates in binary STL
    loaded = trimesh.load(path, file_type="stl")
    assert loaded.is_watertight and loaded.is_winding_consistent
    coarse = export_stl(s.brep, tmp_path / "coarse.stl", deflection=0.1, binary=False)
    assert import_stl(coarse)[1].shape[0] == tessellate(s, deflection=0.1).n_triangles
    with pytest.raises(InvalidInputError, match="deflection applies to solids only"):
        export_stl(m, tmp_path / "m.stl", deflection=0.1)


def test_error_branches():
    m = tessellate(Box(1, 1, 1), deflection=0.1)
    with pytest.raises(InvalidInputError, match="expected a Solid, BRep or TriangleMesh, got str"):
        to_trimesh("box")
    with pytest.raises(InvalidInputError, match=r"tessellation arguments \['deflection'\] were given with an already"):
        to_manifold(m, deflection=0.1)
    open_mesh = TriangleMesh(m.vertices, m.triangles[1:])
    with pytest.raises(InvalidInputError, match="manifold3d rejected the mesh: status NotManifold"):
        to_manifold(open_mesh)
    with pytest.raises(InvalidInputError, match="expected a trimesh.Trimesh .* got int"):
        mesh_from_trimesh(3)


# ---------------------------------------------------------------------- OCCT's BRepMesh as a reference
def occt_mesh_volume(shape, deflection: float) -> tuple[float, int]:
    """Volume and triangle count of OCCT's BRepMesh_IncrementalMesh of a build123d solid."""
    from OCP.BRep import BRep_Tool
    from OCP.BRepMesh import BRepMesh_IncrementalMesh
    from OCP.BRepTools import BRepTools
    from OCP.TopAbs import TopAbs_FACE, TopAbs_REVERSED
    from OCP.TopExp import TopExp_Explorer
    from OCP.TopLoc import TopLoc_Location
    from OCP.TopoDS import TopoDS

    w = shape.wrapped
    BRepTools.Clean_s(w)
    BRepMesh_IncrementalMesh(w, deflection, False, 0.5, False)
    vol, count = 0.0, 0
    ex = TopExp_Explorer(w, TopAbs_FACE)
    while ex.More():
        face = TopoDS.Face(ex.Current())
        loc = TopLoc_Location()
        tri = BRep_Tool.Triangulation_s(face, loc)
        P = np.array([[tri.Node(i).X(), tri.Node(i).Y(), tri.Node(i).Z()] for i in range(1, tri.NbNodes() + 1)])
        T = np.array([tri.Triangle(i).Get() for i in range(1, tri.NbTriangles() + 1)]) - 1
        if face.Orientation() == TopAbs_REVERSED:
            T = T[:, ::-1]
        vol += float(np.einsum("ij,ij->", P[T[:, 0]], np.cross(P[T[:, 1]], P[T[:, 2]]))) / 6.0
        count += T.shape[0]
        ex.Next()
    return vol, count


@pytest.mark.occt
@pytest.mark.parametrize("name", ["cylinder", "cone", "sphere", "torus"])
def test_volumes_within_deflection_like_occt_brepmesh(name):
    import build123d as bd

    ours = SOLIDS[name]()
    ref = {"cylinder": lambda: bd.Cylinder(1.0, 2.0), "cone": lambda: bd.Cone(1.0, 0.0, 2.0),
           "sphere": lambda: bd.Sphere(1.0), "torus": lambda: bd.Torus(2.0, 0.5)}[name]()
    d = 1e-3
    m = tessellate(ours, deflection=d)
    occt_volume, occt_count = occt_mesh_volume(ref, d)
    exact = ref.volume
    np.testing.assert_allclose(ours.volume, exact, rtol=1e-12)
    # Both inscribed meshes lose volume of the order of deflection × area; ours never more than the bound.
    assert 0 < exact - m.volume <= d * ours.area
    assert 0 < exact - occt_volume <= 2 * d * ours.area
    assert m.n_triangles > 0 and occt_count > 0
