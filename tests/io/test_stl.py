"""STL write/read round trips, agreement with trimesh, and malformed files."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from coons.errors import InvalidInputError
from coons.io.stl import export_stl, import_stl

pytestmark = pytest.mark.manifold


def octahedron():
    V = np.array([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]], dtype=float)
    T = np.array([[0, 2, 4], [2, 1, 4], [1, 3, 4], [3, 0, 4], [2, 0, 5], [1, 2, 5], [3, 1, 5], [0, 3, 5]])
    return V, T


@pytest.mark.parametrize("binary", [True, False])
def test_round_trip_and_trimesh_agrees(tmp_path, binary):
    V, T = octahedron()
    path = export_stl((V, T), tmp_path / "o.stl", binary=binary)
    V2, T2 = import_stl(path)
    assert V2.shape == (6, 3) and T2.shape == (8, 3)
    np.testing.assert_allclose(np.sort(V2, axis=0), np.sort(V, axis=0), atol=1e-7)
    m = trimesh.load(path, file_type="stl")
    assert m.is_watertight and m.is_winding_consistent
    np.testing.assert_allclose(m.volume, 4.0 / 3.0, rtol=1e-6)
    # Orientation survives: the mesh read back has outward normals (positive volume).
    tri = V2[T2]
    vol = np.einsum("ij,ij->i", tri[:, 0], np.cross(tri[:, 1], tri[:, 2])).sum() / 6
    np.testing.assert_allclose(vol, 4.0 / 3.0, rtol=1e-6)


def test_reads_the_corpus_cube(tmp_path):
    from pathlib import Path

    path = Path(__file__).resolve().parents[1] / "data" / "trimesh-20mm-xyz-cube.stl"
    V, T = import_stl(path)
    ref = trimesh.load(path)
    assert T.shape[0] == len(ref.faces)
    tri = V[T]
    vol = np.einsum("ij,ij->i", tri[:, 0], np.cross(tri[:, 1], tri[:, 2])).sum() / 6
    np.testing.assert_allclose(vol, ref.volume, rtol=1e-9)


def test_malformed_files(tmp_path):
    bad = tmp_path / "bad.stl"
    bad.write_bytes(b"\x00" * 90)
    with pytest.raises(InvalidInputError, match="neither a binary STL"):
        import_stl(bad)
    bad.write_text("solid x\nfacet normal 0 0 1\n outer loop\n  vertex 0 0 0\n  vertex 1 0 0\n")
    with pytest.raises(InvalidInputError, match="truncated"):
        import_stl(bad)
    bad.write_text("solid x\nfacet normal 0 0 1\n outer loop\n vertex 0 0 0\n vertex 1 0 0\n endloop\nendfacet\nendsolid x\n")
    with pytest.raises(InvalidInputError, match="1 facets but 2 vertices"):
        import_stl(bad)
    bad.write_bytes(b"\xff\xfe garbage")
    with pytest.raises(InvalidInputError, match="not ASCII"):
        import_stl(bad)


def test_bad_meshes_are_refused_and_nothing_is_written(tmp_path):
    V, T = octahedron()
    target = tmp_path / "never.stl"
    with pytest.raises(InvalidInputError, match="triangle indices"):
        export_stl((V, T + 10), target)
    with pytest.raises(InvalidInputError, match=r"shape \(n, 3\)"):
        export_stl((V[:, :2], T), target)
    with pytest.raises(InvalidInputError, match="NaN"):
        export_stl((V * np.nan, T), target)
    assert list(tmp_path.iterdir()) == []
