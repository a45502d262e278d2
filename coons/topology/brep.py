"""The winged-edge boundary representation: immutable struct-of-arrays tables and thin views.

A :class:`BRep` stores the classic winged-edge structure of Baumgart (Cohen–Riesenfeld–
Elber ch. 19) as integer tables, one row per vertex, edge, loop, face, shell and solid,
``-1`` meaning "none".  Views (:class:`Vertex`, :class:`Edge`, :class:`Loop`,
:class:`Face`, :class:`Shell`, :class:`Lump`) are ``(brep, index)`` pairs that read the
tables; they own nothing.  A B-rep is built by :class:`coons.topology.builder.BRepBuilder`
(Euler operators), whose ``build()`` checks it, or by putting checked B-reps whose boxes are
apart side by side (:func:`coons.topology.disjoint.stacked`, valid by construction); nothing
mutates it afterwards.

Notation
--------
``e``  an edge, from ``edge_vertex[e, 0]`` (start) to ``edge_vertex[e, 1]`` (end).
``c``  a *coedge*: one side of an edge, ``c = 2 e + side``.  Side 0 (left) runs start → end
       and belongs to the loop ``edge_loop[e, 0]`` of face ``edge_face[e, 0]``; side 1 (right)
       runs end → start in loop ``edge_loop[e, 1]``.  ``c ^ 1`` is the other side (the twin).
Wings  ``edge_wing[e] = (left_prev, left_next, right_prev, right_next)``: the coedges before
       and after each side of ``e`` in its loop.  Wings are stored as coedge ids rather than
       bare edge ids so that an edge met twice by one loop (a bridge during construction) is
       never ambiguous; ``wing >> 1`` is the classic wing edge.

Invariants (checked by :func:`coons.topology.check.check`)
----------------------------------------------------------
* ``next(prev(c)) == c``; following ``next`` from a loop's first coedge returns to it, and
  every coedge of the cycle has that loop; consecutive coedges share a vertex.
* Faces are oriented outward: walking a loop with the outward normal up, the face lies to
  the left.  Outer loops run counter-clockwise, inner loops clockwise (seen from outside).
* Every edge has two sides in two different faces (closed, manifold shells; no seams).
* Euler–Poincaré: ``V − E + F − (L − F) = 2 (S − G)`` per shell.

Geometry
--------
Faces refer to a surface (``face_surface``, index into ``surfaces``; ``-1`` means the plane
through the face's vertices, used by polyhedra so a million-face mesh needs no objects);
``face_sense`` says whether the outward normal is the surface normal ``Su × Sv`` (True) or
its opposite.  Edges refer to a 3-D curve over ``edge_range`` (``-1``: the straight segment
between the vertices) and to a p-curve per side (``edge_pcurve``, index into ``pcurves``,
``-1`` for planar faces without a surface).  Each p-curve is parametrised like the 3-D curve
(same parameter): ``surface(pcurve(t)) ≈ curve(t)`` within the edge tolerance.

Closed surfaces have no seam edges in coons: the side of a cylinder, a sphere or a torus is
split into faces that each span less than a full turn, so every face's parameter region is
an ordinary planar region and every edge joins two different faces.  Where a surface
collapses to a point (a sphere's pole, a cone's apex) the face's loop runs through a vertex
at that point and its p-curves jump along the collapsed side of the parameter rectangle;
no degenerate edge is stored.  See ``docs/brep.md``.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property
from typing import Iterator

import numpy as np

from coons.errors import InvalidInputError
from coons.kernel._common import interleaved_columns

__all__ = ["BRep", "Vertex", "Edge", "Coedge", "Loop", "Face", "Shell", "Lump", "same_geometry"]


def _ro(a: np.ndarray) -> np.ndarray:
    a = np.ascontiguousarray(a)
    a.setflags(write=False)
    return a


def _csr_rows(ptr: np.ndarray, idx: np.ndarray, i: int) -> np.ndarray:
    return idx[ptr[i] : ptr[i + 1]]


@dataclass(frozen=True, eq=False)
class BRep:
    """Immutable winged-edge tables (see the module docstring for the notation and invariants).

    Shapes: ``V`` vertices, ``E`` edges, ``L`` loops, ``F`` faces, ``S`` shells, ``N`` solids.

    Attributes
    ----------
    vertex_point : (V, 3) float64
    vertex_tol : (V,) float64           deviation achieved at each vertex
    vertex_coedge : (V,) int64          one coedge leaving the vertex (-1 if isolated)
    edge_vertex : (E, 2) int64          start, end
    edge_loop : (E, 2) int64            loop of the left and right sides
    edge_wing : (E, 4) int64            left_prev, left_next, right_prev, right_next (coedge ids)
    edge_curve : (E,) int64             index into ``curves`` (-1: straight segment)
    edge_range : (E, 2) float64         curve parameters at start and end (start < end)
    edge_pcurve : (E, 2) int64          index into ``pcurves`` per side (-1: none/implicit)
    edge_tol : (E,) float64             deviation achieved along each edge
    loop_face : (L,) int64
    loop_coedge : (L,) int64            first coedge (-1 for a loop that is a lone vertex)
    loop_vertex : (L,) int64            the vertex of a lone-vertex loop, else -1
    face_surface : (F,) int64           index into ``surfaces`` (-1: plane through the vertices)
    face_sense : (F,) bool              outward normal == surface normal
    face_shell : (F,) int64
    face_loop_ptr, face_loops           CSR rows: loops of each face, the outer loop first
    shell_solid : (S,) int64
    shell_face_ptr, shell_faces         CSR rows: faces of each shell
    solid_shell_ptr, solid_shells       CSR rows: shells of each solid, the outer shell first
    surfaces, curves, pcurves : tuple   geometry values referenced by index
    """

    vertex_point: np.ndarray
    vertex_tol: np.ndarray
    vertex_coedge: np.ndarray
    edge_vertex: np.ndarray
    edge_loop: np.ndarray
    edge_wing: np.ndarray
    edge_curve: np.ndarray
    edge_range: np.ndarray
    edge_pcurve: np.ndarray
    edge_tol: np.ndarray
    loop_face: np.ndarray
    loop_coedge: np.ndarray
    loop_vertex: np.ndarray
    face_surface: np.ndarray
    face_sense: np.ndarray
    face_shell: np.ndarray
    face_loop_ptr: np.ndarray
    face_loops: np.ndarray
    shell_solid: np.ndarray
    shell_face_ptr: np.ndarray
    shell_faces: np.ndarray
    solid_shell_ptr: np.ndarray
    solid_shells: np.ndarray
    surfaces: tuple = ()
    curves: tuple = ()
    pcurves: tuple = ()

    def __post_init__(self) -> None:
        for name, dtype in _COLUMNS.items():
            arr = np.asarray(getattr(self, name), dtype=dtype)
            object.__setattr__(self, name, _ro(arr))
        for name in ("surfaces", "curves", "pcurves"):
            object.__setattr__(self, name, tuple(getattr(self, name)))

    # ---------------------------------------------------------------- sizes
    @property
    def n_vertices(self) -> int:
        return int(self.vertex_point.shape[0])

    @property
    def n_edges(self) -> int:
        return int(self.edge_vertex.shape[0])

    @property
    def n_loops(self) -> int:
        return int(self.loop_face.shape[0])

    @property
    def n_faces(self) -> int:
        return int(self.face_surface.shape[0])

    @property
    def n_shells(self) -> int:
        return int(self.shell_solid.shape[0])

    @property
    def n_solids(self) -> int:
        return int(self.solid_shell_ptr.shape[0] - 1)

    # ---------------------------------------------------------------- coedge arrays
    @cached_property
    def coedge_next(self) -> np.ndarray:
        """``(2E,)`` next coedge of each coedge in its loop."""
        return _ro(interleaved_columns(self.edge_wing, 1, 3))

    @cached_property
    def coedge_prev(self) -> np.ndarray:
        """``(2E,)`` previous coedge of each coedge in its loop."""
        return _ro(interleaved_columns(self.edge_wing, 0, 2))

    @cached_property
    def coedge_loop(self) -> np.ndarray:
        """``(2E,)`` loop of each coedge."""
        return _ro(self.edge_loop.ravel())

    @cached_property
    def coedge_origin(self) -> np.ndarray:
        """``(2E,)`` vertex each coedge starts from (start for left sides, end for right sides)."""
        return _ro(self.edge_vertex.ravel())

    @cached_property
    def coedge_target(self) -> np.ndarray:
        """``(2E,)`` vertex each coedge ends at."""
        return _ro(interleaved_columns(self.edge_vertex, 1, 0))

    @cached_property
    def coedge_face(self) -> np.ndarray:
        """``(2E,)`` face of each coedge."""
        return _ro(self.loop_face[self.coedge_loop])

    @cached_property
    def edge_face(self) -> np.ndarray:
        """``(E, 2)`` faces of the left and right sides."""
        return _ro(self.coedge_face.reshape(-1, 2))

    # ---------------------------------------------------------------- traversals
    def loop_coedges(self, loop: int) -> np.ndarray:
        """Coedges of a loop in order, O(length of the loop)."""
        first = int(self.loop_coedge[loop])
        if first < 0:
            return np.empty(0, dtype=np.int64)
        out = [first]
        nxt = self.coedge_next
        c = int(nxt[first])
        limit = 2 * self.n_edges
        while c != first:
            out.append(c)
            c = int(nxt[c])
            if len(out) > limit:
                raise InvalidInputError(f"loop {loop} does not close: its next pointers cycle elsewhere")
        return np.asarray(out, dtype=np.int64)

    def vertex_coedges(self, vertex: int) -> np.ndarray:
        """Coedges leaving a vertex, in rotation order around it, O(degree)."""
        first = int(self.vertex_coedge[vertex])
        if first < 0:
            return np.empty(0, dtype=np.int64)
        out = [first]
        nxt = self.coedge_next
        c = int(nxt[first ^ 1])
        limit = 2 * self.n_edges
        while c != first:
            out.append(c)
            c = int(nxt[c ^ 1])
            if len(out) > limit:
                raise InvalidInputError(f"the edges around vertex {vertex} do not form a cycle")
        return np.asarray(out, dtype=np.int64)

    def face_loop_ids(self, face: int) -> np.ndarray:
        return _csr_rows(self.face_loop_ptr, self.face_loops, face)

    def shell_face_ids(self, shell: int) -> np.ndarray:
        return _csr_rows(self.shell_face_ptr, self.shell_faces, shell)

    def solid_shell_ids(self, solid: int) -> np.ndarray:
        return _csr_rows(self.solid_shell_ptr, self.solid_shells, solid)

    # ---------------------------------------------------------------- geometry access
    def edge_points(self, edge: int, t) -> np.ndarray:
        """3-D points of an edge at curve parameters ``t`` (straight edges: t in [0, 1])."""
        ci = int(self.edge_curve[edge])
        if ci < 0:
            a, b = self.vertex_point[self.edge_vertex[edge]]
            t = np.asarray(t, dtype=np.float64)
            return a + t[..., None] * (b - a)
        return self.curves[ci].evaluate(t)

    def bounding_box(self) -> np.ndarray:
        """Axis-aligned box of the vertices, ``(2, 3)`` (geometry-exact boxes: see ``Shape.bounding_box``)."""
        P = self.vertex_point
        return np.stack([P.min(axis=0), P.max(axis=0)]) if P.size else np.zeros((2, 3))

    # ---------------------------------------------------------------- views
    def vertices(self) -> list["Vertex"]:
        return [Vertex(self, i) for i in range(self.n_vertices)]

    def edges(self) -> list["Edge"]:
        return [Edge(self, i) for i in range(self.n_edges)]

    def loops(self) -> list["Loop"]:
        return [Loop(self, i) for i in range(self.n_loops)]

    def faces(self) -> list["Face"]:
        return [Face(self, i) for i in range(self.n_faces)]

    def shells(self) -> list["Shell"]:
        return [Shell(self, i) for i in range(self.n_shells)]

    def lumps(self) -> list["Lump"]:
        return [Lump(self, i) for i in range(self.n_solids)]


_COLUMNS: dict[str, type] = {
    "vertex_point": np.float64,
    "vertex_tol": np.float64,
    "vertex_coedge": np.int64,
    "edge_vertex": np.int64,
    "edge_loop": np.int64,
    "edge_wing": np.int64,
    "edge_curve": np.int64,
    "edge_range": np.float64,
    "edge_pcurve": np.int64,
    "edge_tol": np.float64,
    "loop_face": np.int64,
    "loop_coedge": np.int64,
    "loop_vertex": np.int64,
    "face_surface": np.int64,
    "face_sense": np.bool_,
    "face_shell": np.int64,
    "face_loop_ptr": np.int64,
    "face_loops": np.int64,
    "shell_solid": np.int64,
    "shell_face_ptr": np.int64,
    "shell_faces": np.int64,
    "solid_shell_ptr": np.int64,
    "solid_shells": np.int64,
}


# ====================================================================== views
@dataclass(frozen=True, slots=True)
class _View:
    brep: BRep
    index: int

    def __repr__(self) -> str:
        return f"{type(self).__name__}({self.index})"

    def __eq__(self, other: object) -> bool:
        return type(other) is type(self) and other.brep is self.brep and other.index == self.index  # type: ignore[attr-defined]

    def __hash__(self) -> int:
        return hash((type(self).__name__, id(self.brep), self.index))


class Vertex(_View):
    """A vertex: a point and the tolerance achieved there."""

    __slots__ = ()

    @property
    def point(self) -> np.ndarray:
        return self.brep.vertex_point[self.index]

    @property
    def tolerance(self) -> float:
        return float(self.brep.vertex_tol[self.index])

    def edges(self) -> list["Edge"]:
        """Edges at this vertex in rotation order."""
        return [Edge(self.brep, int(c) >> 1) for c in self.brep.vertex_coedges(self.index)]

    def faces(self) -> list["Face"]:
        """Faces around this vertex in rotation order."""
        b = self.brep
        return [Face(b, int(f)) for f in b.coedge_face[b.vertex_coedges(self.index)]]


class Edge(_View):
    """An edge: two vertices, two faces (left, right), a 3-D curve and a p-curve per side."""

    __slots__ = ()

    @property
    def vertices(self) -> tuple[Vertex, Vertex]:
        s, e = self.brep.edge_vertex[self.index]
        return Vertex(self.brep, int(s)), Vertex(self.brep, int(e))

    @property
    def faces(self) -> tuple["Face", "Face"]:
        l, r = self.brep.edge_face[self.index]
        return Face(self.brep, int(l)), Face(self.brep, int(r))

    @property
    def curve(self):
        """The 3-D curve object, or None for a straight segment between the vertices."""
        ci = int(self.brep.edge_curve[self.index])
        return None if ci < 0 else self.brep.curves[ci]

    @property
    def range(self) -> tuple[float, float]:
        a, b = self.brep.edge_range[self.index]
        return float(a), float(b)

    @property
    def tolerance(self) -> float:
        return float(self.brep.edge_tol[self.index])

    def pcurve(self, face: "Face | int"):
        """The p-curve of this edge in ``face`` (None where the face is an implicit plane)."""
        f = face.index if isinstance(face, Face) else int(face)
        sides = np.flatnonzero(self.brep.edge_face[self.index] == f)
        if sides.size == 0:
            raise InvalidInputError(f"edge {self.index} does not bound face {f}")
        pi = int(self.brep.edge_pcurve[self.index, sides[0]])
        return None if pi < 0 else self.brep.pcurves[pi]

    def points(self, t) -> np.ndarray:
        return self.brep.edge_points(self.index, t)

    def coedges(self) -> tuple["Coedge", "Coedge"]:
        return Coedge(self.brep, 2 * self.index), Coedge(self.brep, 2 * self.index + 1)


class Coedge(_View):
    """One side of an edge, as used by one loop (``index = 2 * edge + side``)."""

    __slots__ = ()

    @property
    def edge(self) -> Edge:
        return Edge(self.brep, self.index >> 1)

    @property
    def forward(self) -> bool:
        """True when the loop runs along the edge's direction (left side)."""
        return (self.index & 1) == 0

    @property
    def next(self) -> "Coedge":
        return Coedge(self.brep, int(self.brep.coedge_next[self.index]))

    @property
    def previous(self) -> "Coedge":
        return Coedge(self.brep, int(self.brep.coedge_prev[self.index]))

    @property
    def twin(self) -> "Coedge":
        return Coedge(self.brep, self.index ^ 1)

    @property
    def origin(self) -> Vertex:
        return Vertex(self.brep, int(self.brep.coedge_origin[self.index]))

    @property
    def loop(self) -> "Loop":
        return Loop(self.brep, int(self.brep.coedge_loop[self.index]))

    @property
    def pcurve(self):
        pi = int(self.brep.edge_pcurve[self.index >> 1, self.index & 1])
        return None if pi < 0 else self.brep.pcurves[pi]


class Loop(_View):
    """A closed cycle of coedges bounding a face (the first loop of a face is its outer loop)."""

    __slots__ = ()

    @property
    def face(self) -> "Face":
        return Face(self.brep, int(self.brep.loop_face[self.index]))

    @property
    def is_outer(self) -> bool:
        return int(self.brep.face_loop_ids(int(self.brep.loop_face[self.index]))[0]) == self.index

    def coedges(self) -> list[Coedge]:
        return [Coedge(self.brep, int(c)) for c in self.brep.loop_coedges(self.index)]

    def edges(self) -> list[Edge]:
        return [Edge(self.brep, int(c) >> 1) for c in self.brep.loop_coedges(self.index)]

    def vertices(self) -> list[Vertex]:
        b = self.brep
        cs = b.loop_coedges(self.index)
        if cs.size == 0:
            return [Vertex(b, int(b.loop_vertex[self.index]))]
        return [Vertex(b, int(v)) for v in b.coedge_origin[cs]]


class Face(_View):
    """A face: a surface (with its sense) trimmed by an outer loop and any inner loops."""

    __slots__ = ()

    @property
    def surface(self):
        """The surface object, or None for an implicit plane (polyhedral face)."""
        si = int(self.brep.face_surface[self.index])
        return None if si < 0 else self.brep.surfaces[si]

    @property
    def surface_type(self) -> str:
        """``"plane"``, ``"cylinder"``, ``"cone"``, ``"sphere"``, ``"torus"``, ``"bspline"`` ..."""
        s = self.surface
        if s is None:
            return "plane"
        return getattr(s, "surface_type", "bspline")

    @property
    def sense(self) -> bool:
        return bool(self.brep.face_sense[self.index])

    @property
    def shell(self) -> "Shell":
        return Shell(self.brep, int(self.brep.face_shell[self.index]))

    def loops(self) -> list[Loop]:
        return [Loop(self.brep, int(l)) for l in self.brep.face_loop_ids(self.index)]

    @property
    def outer_loop(self) -> Loop:
        return Loop(self.brep, int(self.brep.face_loop_ids(self.index)[0]))

    def inner_loops(self) -> list[Loop]:
        return [Loop(self.brep, int(l)) for l in self.brep.face_loop_ids(self.index)[1:]]

    def coedges(self) -> Iterator[Coedge]:
        for l in self.loops():
            yield from l.coedges()

    def edges(self) -> list[Edge]:
        return [c.edge for c in self.coedges()]

    def vertices(self) -> list[Vertex]:
        seen: dict[int, None] = {}
        for l in self.loops():
            for v in l.vertices():
                seen.setdefault(v.index, None)
        return [Vertex(self.brep, i) for i in seen]

    def neighbors(self) -> list["Face"]:
        """Faces sharing an edge with this one (each once), O(number of coedges)."""
        b = self.brep
        out: dict[int, None] = {}
        for c in self.coedges():
            out.setdefault(int(b.coedge_face[c.index ^ 1]), None)
        out.pop(self.index, None)
        return [Face(b, i) for i in out]


class Shell(_View):
    """A connected closed set of faces."""

    __slots__ = ()

    def faces(self) -> list[Face]:
        return [Face(self.brep, int(f)) for f in self.brep.shell_face_ids(self.index)]

    @property
    def lump(self) -> "Lump":
        return Lump(self.brep, int(self.brep.shell_solid[self.index]))


class Lump(_View):
    """One solid of the B-rep: an outer shell and any void shells."""

    __slots__ = ()

    def shells(self) -> list[Shell]:
        return [Shell(self.brep, int(s)) for s in self.brep.solid_shell_ids(self.index)]

    def faces(self) -> list[Face]:
        return [f for s in self.shells() for f in s.faces()]


def same_geometry(src: BRep, dst: BRep) -> bool:
    """Whether two B-reps have the same vertices, faces, edges and geometry objects, row for row.

    True for a B-rep and its rebuild after regrouping shells into solids (void nesting): what is
    computed per face or vertex of one (meshes, integrals, boxes) then holds for the other.
    """
    return (src.n_faces == dst.n_faces and src.n_vertices == dst.n_vertices and src.n_edges == dst.n_edges
            and np.array_equal(src.vertex_point, dst.vertex_point)
            and np.array_equal(src.face_surface, dst.face_surface) and np.array_equal(src.face_sense, dst.face_sense)
            and np.array_equal(src.edge_vertex, dst.edge_vertex) and np.array_equal(src.edge_range, dst.edge_range)
            and np.array_equal(src.edge_curve, dst.edge_curve) and np.array_equal(src.edge_pcurve, dst.edge_pcurve)
            and np.array_equal(src.face_loop_ptr, dst.face_loop_ptr) and np.array_equal(src.face_loops, dst.face_loops)
            and np.array_equal(src.loop_coedge, dst.loop_coedge)
            and len(src.pcurves) == len(dst.pcurves) and all(x is y for x, y in zip(src.pcurves, dst.pcurves))
            and len(src.surfaces) == len(dst.surfaces) and all(x is y for x, y in zip(src.surfaces, dst.surfaces))
            and len(src.curves) == len(dst.curves) and all(x is y for x, y in zip(src.curves, dst.curves)))
