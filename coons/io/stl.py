"""STL read and write (binary and ASCII), vectorised.

Writes triangle meshes given as ``(vertices (n, 3), triangles (m, 3))`` or any object
with ``vertices`` and ``triangles`` arrays (a coons mesh), and solids (tessellated first by
:func:`coons.topology.tessellate.tessellate`).  Files are written to a
temporary file in the destination folder and renamed into place, so a failure never
leaves a half-written file.  Reading merges bit-identical vertices, which rebuilds
the connectivity that STL's triangle soup loses; it does not heal near-coincident
vertices, repair orientation, or accept anything but well-formed files.
"""

from __future__ import annotations

import os
import re
import tempfile
from pathlib import Path

import numpy as np

from coons.errors import InvalidInputError

__all__ = ["export_stl", "import_stl", "mesh_arrays"]

_BINARY_DTYPE = np.dtype(
    [("normal", "<f4", (3,)), ("v", "<f4", (3, 3)), ("attr", "<u2")]
)


def mesh_arrays(mesh) -> tuple[np.ndarray, np.ndarray]:
    """``(vertices (n, 3) float64, triangles (m, 3) int64)`` of a mesh-like input.

    Raises
    ------
    InvalidInputError
        Wrong shapes, non-finite vertices or triangle indices out of range.
    """
    if isinstance(mesh, tuple) and len(mesh) == 2:
        V, T = mesh
    elif hasattr(mesh, "vertices") and (hasattr(mesh, "triangles") or hasattr(mesh, "faces")):
        V = mesh.vertices
        T = mesh.triangles if hasattr(mesh, "triangles") else mesh.faces
    else:
        raise InvalidInputError(f"expected (vertices, triangles) or a mesh object, got {type(mesh).__name__}")
    V = np.asarray(V, dtype=np.float64)
    T = np.asarray(T)
    if V.ndim != 2 or V.shape[1] != 3:
        raise InvalidInputError(f"vertices must have shape (n, 3), got {V.shape}")
    if T.ndim != 2 or T.shape[1] != 3 or not np.issubdtype(T.dtype, np.integer):
        raise InvalidInputError(f"triangles must be an integer array of shape (m, 3), got {T.shape} {T.dtype}")
    if not np.all(np.isfinite(V)):
        raise InvalidInputError("vertices contain NaN or inf")
    if T.size and (T.min() < 0 or T.max() >= V.shape[0]):
        raise InvalidInputError(f"triangle indices must lie in [0, {V.shape[0]}), got [{T.min()}, {T.max()}]")
    return V, T.astype(np.int64, copy=False)


def _facet_normals(tri: np.ndarray) -> np.ndarray:
    n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    length = np.linalg.norm(n, axis=1, keepdims=True)
    return np.divide(n, length, out=np.zeros_like(n), where=length > 0)


def _atomic_write(path: Path, data: bytes) -> None:
    path = Path(path)
    fd, tmp = tempfile.mkstemp(prefix=".tmp-", suffix=path.suffix, dir=path.parent or ".")
    try:
        with os.fdopen(fd, "wb") as fh:
            fh.write(data)
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise


def export_stl(mesh, path, *, binary: bool = True, name: str = "coons", deflection: float | None = None) -> Path:
    """Write a triangle mesh, or a solid tessellated by :func:`coons.topology.tessellate.tessellate`, as STL.

    Parameters
    ----------
    mesh : (vertices, triangles), mesh-like, Solid or BRep
    path : str or Path
    binary : bool
        Binary (default, float32 as the format requires) or ASCII (``%.9e``, float64 precision kept to 10 digits).
    deflection : float, optional
        For a Solid or BRep: the tessellation's deflection (default: ``tessellate``'s,
        1e-3 of the bounding-box diagonal).  Not allowed with a mesh.

    Returns
    -------
    Path of the written file.

    Raises
    ------
    InvalidInputError
        Invalid mesh arrays, a name with a newline, or ``deflection`` given with a mesh.
    """
    from coons.topology.brep import BRep

    if isinstance(mesh, BRep) or isinstance(getattr(mesh, "brep", None), BRep):
        from coons.topology.tessellate import tessellate

        mesh = tessellate(mesh, deflection=deflection)
    elif deflection is not None:
        raise InvalidInputError("deflection applies to solids only; the mesh is already tessellated")
    V, T = mesh_arrays(mesh)
    tri = V[T]
    normals = _facet_normals(tri)
    path = Path(path)
    if binary:
        rec = np.zeros(T.shape[0], dtype=_BINARY_DTYPE)
        rec["normal"] = normals
        rec["v"] = tri
        header = f"binary STL written by {name}".encode("ascii", "replace")[:80].ljust(80, b" ")
        data = header + np.uint32(T.shape[0]).tobytes() + rec.tobytes()
    else:
        if "\n" in name:
            raise InvalidInputError("solid name must be a single line")
        block = np.concatenate([normals[:, None, :], tri], axis=1).reshape(-1, 12)
        fmt = (
            "facet normal %.9e %.9e %.9e\n outer loop\n"
            "  vertex %.9e %.9e %.9e\n  vertex %.9e %.9e %.9e\n  vertex %.9e %.9e %.9e\n"
            " endloop\nendfacet\n"
        )
        # One formatting call over the flat array (no Python loop over triangles).
        body = (fmt * block.shape[0]) % tuple(block.ravel().tolist())
        data = f"solid {name}\n{body}endsolid {name}\n".encode("ascii")
    _atomic_write(path, data)
    return path


_FLOAT = r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?|[-+]?(?:nan|inf)"
_VERTEX_RE = re.compile(rf"vertex\s+({_FLOAT})\s+({_FLOAT})\s+({_FLOAT})", re.IGNORECASE)


def import_stl(path) -> tuple[np.ndarray, np.ndarray]:
    """Read an STL file (binary or ASCII) into merged ``(vertices (n, 3), triangles (m, 3))``.

    Vertices with identical coordinates are merged; degenerate input is returned as is
    (validity is the solid builder's business).

    Raises
    ------
    InvalidInputError
        A truncated or malformed file, or non-finite coordinates.
    """
    data = Path(path).read_bytes()
    is_binary = False
    if len(data) >= 84:
        count = int(np.frombuffer(data[80:84], dtype="<u4")[0])
        is_binary = len(data) == 84 + 50 * count
    if is_binary:
        rec = np.frombuffer(data, dtype=_BINARY_DTYPE, count=count, offset=84)
        soup = rec["v"].astype(np.float64).reshape(-1, 3)
    else:
        try:
            text = data.decode("ascii")
        except UnicodeDecodeError as exc:
            raise InvalidInputError(f"{path}: not a binary STL (size mismatch) and not ASCII text ({exc})") from exc
        if not text.lstrip().lower().startswith("solid"):
            raise InvalidInputError(
                f"{path}: neither a binary STL (size {len(data)} does not match 84 + 50 * triangle count) nor ASCII STL"
            )
        if not re.search(r"endsolid", text, re.IGNORECASE):
            raise InvalidInputError(f"{path}: ASCII STL is truncated (no 'endsolid')")
        coords = _VERTEX_RE.findall(text)
        facets = len(re.findall(r"\bfacet\b", text, re.IGNORECASE))
        if len(coords) != 3 * facets:
            raise InvalidInputError(f"{path}: {facets} facets but {len(coords)} vertices (expected {3 * facets})")
        soup = np.array(coords, dtype=np.float64).reshape(-1, 3)
    if not np.all(np.isfinite(soup)):
        raise InvalidInputError(f"{path}: vertex coordinates contain NaN or inf")
    V, inverse = np.unique(soup, axis=0, return_inverse=True)
    return V, inverse.reshape(-1, 3).astype(np.int64)
