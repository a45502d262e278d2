"""Triangle meshes as values: vertex and triangle arrays with the measures and closedness tests a tessellation needs.

:class:`TriangleMesh` is the output of :func:`coons.topology.tessellate.tessellate` and the
exchange value of :mod:`coons.io.mesh` (trimesh, manifold3d) and :mod:`coons.io.stl`: a
frozen dataclass over read-only arrays, with the signed volume and the area by vectorised
closed forms and the combinatorial closedness test (:attr:`TriangleMesh.is_closed`,
:meth:`TriangleMesh.boundary_edges`).  It deliberately does not repair, merge, simplify or
Boolean anything, and imports no mesh library.

Notation: ``n`` vertices, ``m`` triangles; a triangle ``(a, b, c)`` has the directed edges
``a → b``, ``b → c``, ``c → a`` and the normal ``(b − a) × (c − a)`` (right-hand rule).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np

from coons.errors import InvalidInputError

__all__ = ["TriangleMesh"]


def _ro(a: np.ndarray) -> np.ndarray:
    a = np.array(a, copy=True)
    a.setflags(write=False)
    return a


@dataclass(frozen=True, eq=False)
class TriangleMesh:
    """An indexed triangle mesh (immutable).

    Parameters
    ----------
    vertices : (n, 3) array_like of float
    triangles : (m, 3) array_like of int, indices into ``vertices``
    face_ids : (m,) array_like of int, optional
        The B-rep face each triangle came from (``-1`` where unknown).

    Raises
    ------
    InvalidInputError
        Wrong shapes, non-finite vertices, triangle indices out of range or a
        ``face_ids`` length different from the triangle count.

    Examples
    --------
    >>> tet = TriangleMesh([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]],
    ...                    [[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])
    >>> bool(tet.is_closed), bool(np.isclose(tet.volume, 1 / 6, rtol=1e-15))
    (True, True)
    """

    vertices: np.ndarray
    triangles: np.ndarray
    face_ids: np.ndarray | None = None

    def __post_init__(self) -> None:
        V = np.asarray(self.vertices, dtype=np.float64)
        T = np.asarray(self.triangles)
        if V.ndim != 2 or V.shape[1] != 3:
            raise InvalidInputError(f"TriangleMesh vertices: expected shape (n, 3), got {V.shape}")
        if T.size == 0:
            T = T.reshape(0, 3).astype(np.int64)
        if T.ndim != 2 or T.shape[1] != 3 or not np.issubdtype(T.dtype, np.integer):
            raise InvalidInputError(
                f"TriangleMesh triangles: expected an integer array of shape (m, 3), got {T.shape} {T.dtype}"
            )
        if not np.all(np.isfinite(V)):
            raise InvalidInputError("TriangleMesh vertices contain NaN or inf")
        if T.size and (T.min() < 0 or T.max() >= V.shape[0]):
            raise InvalidInputError(
                f"TriangleMesh triangle indices must lie in [0, {V.shape[0]}), got [{T.min()}, {T.max()}]"
            )
        object.__setattr__(self, "vertices", _ro(V))
        object.__setattr__(self, "triangles", _ro(T.astype(np.int64)))
        if self.face_ids is not None:
            F = np.asarray(self.face_ids)
            if F.shape != (T.shape[0],) or (F.size and not np.issubdtype(F.dtype, np.integer)):
                raise InvalidInputError(
                    f"TriangleMesh face_ids: expected {T.shape[0]} integers, got shape {F.shape} {F.dtype}"
                )
            object.__setattr__(self, "face_ids", _ro(F.astype(np.int64)))

    def __repr__(self) -> str:
        return f"TriangleMesh(vertices={self.n_vertices}, triangles={self.n_triangles})"

    # ------------------------------------------------------------------ sizes
    @property
    def n_vertices(self) -> int:
        return int(self.vertices.shape[0])

    @property
    def n_triangles(self) -> int:
        return int(self.triangles.shape[0])

    # ------------------------------------------------------------------ measures
    @cached_property
    def _corners(self) -> np.ndarray:
        """``(m, 3, 3)`` corner coordinates, centred on the vertex centroid to limit round-off."""
        V = self.vertices
        c = V.mean(axis=0) if V.shape[0] else np.zeros(3)
        return (V - c)[self.triangles]

    @cached_property
    def triangle_normals(self) -> np.ndarray:
        """``(m, 3)`` area vectors ``(b − a) × (c − a) / 2`` (length = triangle area), read-only."""
        P = self._corners
        return _ro(0.5 * np.cross(P[:, 1] - P[:, 0], P[:, 2] - P[:, 0]))

    @cached_property
    def volume(self) -> float:
        """Signed enclosed volume ``Σ a · (b × c) / 6`` (divergence theorem); positive for outward-oriented closed meshes.

        Computed about the vertex centroid, which leaves the result of a closed mesh unchanged
        and keeps the terms small.  Meaningless for meshes that are not closed.
        """
        P = self._corners
        return float(np.einsum("ij,ij->", P[:, 0], np.cross(P[:, 1], P[:, 2])) / 6.0)

    @cached_property
    def area(self) -> float:
        """Total triangle area."""
        return float(np.linalg.norm(self.triangle_normals, axis=1).sum())

    def bounding_box(self) -> np.ndarray:
        """``(2, 3)`` min and max corners of the vertices (zeros for an empty mesh)."""
        V = self.vertices
        return np.stack([V.min(axis=0), V.max(axis=0)]) if V.shape[0] else np.zeros((2, 3))

    # ------------------------------------------------------------------ combinatorics
    @cached_property
    def _directed(self) -> tuple[np.ndarray, np.ndarray]:
        """Directed edge keys ``a · n + b`` of every triangle edge (``(3m,)``) and their reverses."""
        T = self.triangles
        a = T.ravel()
        b = T[:, [1, 2, 0]].ravel()
        n = np.int64(max(self.n_vertices, 1))
        return a * n + b, b * n + a

    @cached_property
    def is_closed(self) -> bool:
        """Every undirected edge is used by exactly two triangles, in opposite directions.

        Equivalently: no directed edge occurs twice and every directed edge's reverse occurs.
        This is the watertight, consistently oriented, edge-manifold condition (vertex links
        are not examined).  An empty mesh is not closed.
        """
        if self.n_triangles == 0:
            return False
        key, rev = self._directed
        s = np.sort(key)
        if np.any(s[1:] == s[:-1]):
            return False
        T = self.triangles
        if np.any((T[:, 0] == T[:, 1]) | (T[:, 1] == T[:, 2]) | (T[:, 2] == T[:, 0])):
            return False
        return bool(np.all(np.isin(rev, s, assume_unique=True)))

    def boundary_edges(self) -> np.ndarray:
        """Directed edges ``(a, b)`` whose reverse ``(b, a)`` is used by no triangle, ``(k, 2)`` int64.

        Empty for a closed mesh; a directed edge used twice (a non-manifold or inconsistently
        oriented edge) is listed each time its reverse is missing.
        """
        key, rev = self._directed
        missing = ~np.isin(rev, key)
        T = self.triangles
        a = T.ravel()[missing]
        b = T[:, [1, 2, 0]].ravel()[missing]
        return np.stack([a, b], axis=1).astype(np.int64)

    def edges_unique(self) -> np.ndarray:
        """Undirected edges ``(a, b)`` with ``a < b``, each once, ``(k, 2)`` int64."""
        T = self.triangles
        e = np.sort(np.stack([T.ravel(), T[:, [1, 2, 0]].ravel()], axis=1), axis=1)
        return np.unique(e, axis=0) if e.size else e.reshape(0, 2)

    @property
    def euler_characteristic(self) -> int:
        """``V − E + F`` over the vertices used by triangles (2 for a closed sphere-like mesh)."""
        used = np.unique(self.triangles) if self.n_triangles else np.empty(0, np.int64)
        return int(used.size - self.edges_unique().shape[0] + self.n_triangles)
