"""Exact Booleans of polyhedral solids: union, difference and intersection of solids whose faces are all planar.

:func:`union`, :func:`difference` and :func:`intersection` (and the operators ``a + b``,
``a - b``, ``a & b`` of :class:`~coons.topology.shape.Solid`) combine solids bounded by planar
faces with straight edges — boxes, extrusions of polygons, meshes read with
:func:`~coons.topology.from_mesh.from_mesh` — and return a valid solid (``check`` clean,
closed, oriented, neighbouring coplanar faces merged) or raise
:class:`~coons.errors.BooleanError` naming the stage that failed.  Every combinatorial decision
is made by exact predicates on the input floats; no tolerance decides anything until the
result is sewn.  It does not handle curved faces (those raise; the B-rep Booleans are another
module), does not repair invalid or self-intersecting operands, and does not produce
non-manifold results (see below).

Notation
--------
``A``, ``B``
    The operands, each tessellated exactly (planar faces, straight edges: the triangles'
    vertices are the B-rep vertices) into a closed mesh; ``t`` is a triangle of A, ``u`` of B.
``R``
    The result, ``A ∪ B``, ``A ∩ B`` or ``A − B``.
pair ``(t, u)``
    Two triangles whose bounding boxes overlap (broad phase); the narrow phase classifies it
    as apart, meeting (crossing or touching) or coplanar.
keyed point ``(σ_A, σ_B)``
    A point common to both surfaces, named by the vertex, edge or triangle of each mesh whose
    relative interior contains it (:mod:`._mesh_arrangement`).
piece
    A triangle of the subdivided A or B; its interior lies entirely outside, inside or on the
    other surface.
patch
    A connected set of pieces of one operand, joined across piece edges that do not lie on the
    other surface; all its pieces have the same status.
status
    ``OUT`` / ``IN``: the patch lies outside / inside the other solid; ``ON_SAME`` /
    ``ON_OPPOSITE``: it lies on a coplanar part of the other surface whose outward normal points
    the same / the opposite way.

Phases (each a private function raising ``BooleanError(stage=...)`` with ids and residuals)
------------------------------------------------------------------------------------------
1. ``_meshes`` (stage ``"input"``): planar faces and straight edges are required; the first
   curved face or edge is named.  ``tessellate`` gives the exact triangle meshes with face ids
   (solids whose faces are all triangles, as ``from_mesh`` makes them, are read from their tables).
2. ``_broad_phase``: candidate pairs from :func:`._broad_phase.triangle_pairs`: a vertex cull and a
   box cull on uniform grids drop the triangles far from the other surface, then the survivors'
   overlapping boxes come from a grid (or two implicit bounding-volume hierarchies), no Python
   loop over triangles.  Then :func:`._mesh_arrangement.snap` gives both operands one common
   triangulation on every cluster of near-coplanar candidate pairs (within ``tol.linear``), so
   that their near-coincidences are exact before the exact phases (the broad phase is redone
   only when it changed the operands).
3. + 4. ``_intersect`` (stage ``"intersect"``): exact narrow phase and intersection points and
   segments (:func:`._mesh_arrangement.intersect`).
5. ``_imprint`` (stage ``"imprint"``): every triangle split along its segments; triangles crossed
   by one chain of segments (nearly all) in array time with every piece's orientation verified
   exactly, the others by a constrained triangulation that is verified exactly
   (:func:`._mesh_arrangement.imprint`).
6. ``_classify`` (stage ``"classify"``): patches are the connected components of the piece
   adjacency cut at intersection edges (``scipy.sparse.csgraph``; whole triangles are joined
   through the operand's edge table, only the pieces of split triangles are paired by sorting;
   an edge between two whole triangles is looked up among the intersection edges only when both
   its vertices lie on the other surface).
   A patch is ``ON`` when one of its pieces lies in a coplanar triangle of the other mesh (exact
   test of the piece's centroid);
   otherwise one point of the patch is classified by **ray parity**: the ray ``q + λ (1, 0, 0)``,
   ``λ > 0``, crosses the other closed surface an odd number of times exactly when ``q`` is
   inside.  Crossings are decided exactly — the ray meets a triangle when ``q``'s projection on the
   ``yz`` plane is inside the projected triangle (three ``orient2d``) and the triangle's plane lies
   ahead of ``q`` (``orient3d`` against the sign of the projected area) — and degenerate hits (the
   ray through an edge or vertex, or along a face) are resolved by *simulation of simplicity*
   (Edelsbrunner & Mücke, ACM TOG 9, 1990): ``q`` is moved to ``q + (0, ε, ε²)``, whose
   orientation signs are those of the unperturbed determinant or, when it is zero, of exact float
   differences of the triangle's coordinates, so every hit is counted on exactly one side of every
   edge and no retry is needed.  ``q`` is an original vertex of the patch that does not touch the
   other surface (float predicates with exact fallback), or else the exact rational centroid of a
   piece (integer arithmetic).
7. ``_select`` (stage ``"select"``): by the table

   ============  ==========  ============  ===================
   operation     A pieces    B pieces      coplanar pieces
   ============  ==========  ============  ===================
   union         OUT         OUT           ON_SAME, once (A's)
   intersection  IN          IN            ON_SAME, once (A's)
   difference    OUT         IN, reversed  ON_OPPOSITE (A's)
   ============  ==========  ============  ===================

8. ``_sew`` (stage ``"sew"``): exact points are rounded to the nearest floats, features below
   ``tol.linear`` are cleaned up (below; only rows holding a new point or points of both operands
   are searched), and the result is built by ``from_mesh``'s construction for clean meshes
   (:func:`~coons.topology.from_mesh._solid_from_clean_triangles`: half-edge pairing, shells as
   connected components — found on the patches, each connected, joined where they meet
   (:func:`_patch_groups`) — nested into lumps and voids, neighbouring coplanar triangles merged into
   polygon faces with holes where needed, vertices left on straight edges between two merged
   faces removed).  An empty selection gives
   :meth:`Solid.empty() <coons.topology.shape.Solid.empty>` (no lumps, volume 0, valid).
9. Check (stage ``"check"``): every edge used twice in opposite directions, every shell's volume
   of the sign its nesting requires and thicker than ``tol.linear`` on average (``|V| >
   tol.linear · A``; a thinner component — the doubly covered patch where two operands touch —
   is removed and the build retried), merged faces planar within ``tol.linear``, and the
   topological checks of :func:`~coons.topology.check.check` (pointers, loops, manifold vertices,
   Euler–Poincaré per shell); any problem raises.  The geometric checks of ``check`` have nothing
   to find on a result whose edges are the segments between its vertices.

Rounding and features below the tolerance
-----------------------------------------
The pieces are exact, but the result must be stored in floats.  Inputs whose features agree
only up to rounding — the faces of two boxes turned by the same rotation, a vertex of one
sphere mesh an ulp off an edge of another — have exact results with features of the size of
the rounding error (edges of length 1e-16, slivers, walls a rounding error apart), which floats
cannot carry and :func:`~coons.topology.from_mesh.from_mesh` (whose degenerate-triangle and
coplanarity tests use ``tol.linear``) rejects.  ``_clean`` therefore removes, with
``eps = tol.linear``: edges of length ``<= eps`` (their vertices merge, an original vertex
surviving), triangle pairs cancelling each other, and caps (height ``<= eps``: the apex is
inserted into the long edge); closed components thinner than ``eps`` (``|V| <= eps · area``)
are dropped when ``from_mesh`` refuses them.  This is the only place where a tolerance changes
geometry, by at most a few ``eps``; a result without such features is exactly the rounded exact
result.  A consequence: parts thinner than ``tol.linear`` vanish (``A − B`` for ``B`` a copy of
``A`` moved by ``1e-9`` is empty).

Degenerate inputs
-----------------
Coplanar overlapping faces, coincident edges and vertices, identical operands, solids touching
in a face, an edge or a vertex, one operand inside the other (the result keeps an inner void
shell), disjoint operands (several lumps) and empty results are all decided exactly by the
keyed points and the exact classification; none needs a tolerance or a retry.

Non-manifold results are rejected
----------------------------------
The B-rep of coons is a manifold winged-edge structure: every edge bounds exactly two faces
and every vertex has one disc of faces around it.  A result whose boundary is not a manifold —
the union of two boxes sharing only an edge or only a vertex, or a difference leaving two parts
that touch along an edge or at a vertex — therefore raises ``BooleanError(stage="sew")`` naming
the edge ("used by 4 triangles") or the vertex ("separate fans of faces"), instead of being
represented.  Intersections and differences of such touching operands are manifold and work (the
common part of two boxes sharing an edge is empty).

Status and limitations
----------------------
* Exact: every combinatorial decision, for every float input.  The result's vertices are the
  input vertices and the nearest floats to the exact new points, except where the clean-up
  above acted (features below ``tol.linear``).
* Inputs that coincide only up to rounding (rotated copies of coincident faces) give valid
  results within the tolerance of the exact answer: the snap of :mod:`._mesh_arrangement` first
  gives both operands one common triangulation on each near-coplanar cluster.  ``python
  benchmarks/hunt_rotated_grid_boxes.py --pairs 1000 --seed S`` (random rotated grid-box pairs,
  the three Booleans of each, volume against the closed form to 1e-9) finds no failure in
  28 775 Booleans (seeds 1–5 and 11–15; the snap never gave up), against 30 of the 14 365 of
  seeds 1–5 (0.21 %) with the former local snap rules, which cascaded there.  Where the snap
  does give up (features between one and a few tolerances apart, as in a sphere mesh and its
  copy turned by ``2e-7``; a cluster not near one plane) the raw operands are used, and a thin
  sheet left attached to the rest of the result makes it non-manifold, which raises (stage
  ``"sew"``) rather than return a broken solid.
* Operands must be valid closed solids; self-intersecting operands are not detected.
* Vertices left on a straight edge between two merged faces (where the tessellation's diagonals
  met the intersection curves) are removed when they lie within ``tol.linear`` of the segment
  between their neighbours (:func:`~coons.topology.from_mesh._remove_straight_vertices`).
* Speed: every phase is vectorised except the splits of the few triangles that neither a chain
  template nor the pattern of another triangle describes (Python, exact integers when the float
  filters cannot decide).  ``benchmarks/bench_booleans_mesh.py`` measures coons against
  manifold3d in the same run, the two peers' runs interleaved (``benchmarks/results/booleans_mesh.md``).
  At 1.6e5 input triangles on a 2-core machine, union / intersection / difference take about
  107 / 100 / 107 ms against manifold3d's 42 / 41 / 41 ms (2.4-2.6x; 2.7-2.9x at 1e5 by
  interpolation, 3.4-3.6x at 4e4, where fixed costs of about 11 ms weigh).  The sewing of the
  result (clean-up, half-edge pairing, tables, coplanar merging, the topological checks) is the
  largest phase, about a third of the union, then the broad phase with the snap, the narrow
  phase, imprint, classification (mostly the patch labelling, one ``connected_components`` over
  each operand's pieces) and the operands' meshes.  About 95 % of the result's half-edges get
  their twins from the operands' edge tables (:func:`_known_twins`); only the rest are paired by
  sorting, and the result's shells are found on its patches (:func:`_patch_groups`), not on its
  triangles.  The clean-up's later rounds search only the rows the previous round changed.  Row
  gathers of 2-D arrays go through ``np.take`` / ``np.compress`` (several times faster than
  ``A[idx]`` with numpy 2.4); ``A[:, [i, j]]`` and ``np.unique(..., axis=0)`` are avoided for the
  same reason (one integer key per row instead).  Much of what remains is random gathers over
  1e5-3e5 rows, bound by cache misses: a row gather (one cache line per scattered index) beats
  column gathers there, even where it loses with the arrays in cache.  A plate minus 20 × 20
  prisms (4,812 triangles) is about 8x manifold3d: its many small lumps are fixed costs.
* Bit-identical rounded points that are not joined by an edge stay distinct vertices (the exact
  points are distinct); identical input vertices of A and B are one point (keyed exactly).
* n-ary calls fold left: ``union(a, b, c) = (a ∪ b) ∪ c``.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

from coons.booleans._broad_phase import _CULL_MIN, _vertex_cull, box_pairs, triangle_boxes, triangle_pairs
from coons.booleans._mesh_arrangement import (
    Exact,
    Imprint,
    Intersections,
    Operand,
    PointTable,
    _projection,
    imprint,
    intersect,
    operand,
    snap,
)
from coons.errors import BooleanError, InvalidInputError, TopologyError
from coons.kernel._common import next_corners, used_ids
from coons.kernel.analytic import Line, PlanarSurface
from coons.kernel.predicates import orient2d, orient3d
from coons.tolerance import Tolerance, resolve
from coons.topology.shape import Solid

__all__ = ["union", "difference", "intersection", "boolean", "OUT", "IN", "ON_SAME", "ON_OPPOSITE"]

OUT, IN, ON_SAME, ON_OPPOSITE = 0, 1, 2, 3
_STATUS_NAMES = ("OUT", "IN", "ON_SAME", "ON_OPPOSITE")
#: Selection table: statuses kept from A, from B, and whether B's kept pieces are reversed.
_TABLE = {
    "union": ({OUT, ON_SAME}, {OUT}, False),
    "intersection": ({IN, ON_SAME}, {IN}, False),
    "difference": ({OUT, ON_OPPOSITE}, {IN}, True),
}


# ====================================================================== public API
def union(*solids: Solid, tol: Tolerance | None = None) -> Solid:
    """The union of polyhedral solids, ``s0 ∪ s1 ∪ ...`` (also ``a + b``).

    Parameters
    ----------
    *solids : Solid
        At least one solid whose faces are all planar with straight edges.
    tol : Tolerance, optional
        Used only to sew the result (see the module docstring).

    Returns
    -------
    Solid

    Raises
    ------
    InvalidInputError
        No solids, or an argument that is not a Solid.
    BooleanError
        ``stage="input"`` for a curved face or edge; the other stages as in the module docstring
        (a non-manifold result raises at ``"sew"``).

    Examples
    --------
    >>> from coons.topology.primitives import Box
    >>> r = union(Box(2, 2, 2), Box(2, 2, 2).translate((1, 0, 0)))
    >>> bool(np.isclose(r.volume, 12.0, rtol=1e-14)), len(r.faces())
    (True, 6)
    """
    return _fold("union", solids, tol)


def difference(a: Solid, *tools: Solid, tol: Tolerance | None = None) -> Solid:
    """``a`` minus every tool, ``a − t0 − t1 − ...`` (also ``a - b``).

    Raises
    ------
    InvalidInputError, BooleanError
        As :func:`union`.

    Examples
    --------
    >>> from coons.topology.primitives import Box
    >>> r = difference(Box(4, 4, 4), Box(2, 2, 2))   # a cube with a cubic void
    >>> bool(np.isclose(r.volume, 56.0, rtol=1e-14)), len(r.shells())
    (True, 2)
    """
    return _fold("difference", (a,) + tools, tol)


def intersection(*solids: Solid, tol: Tolerance | None = None) -> Solid:
    """The common part of polyhedral solids, ``s0 ∩ s1 ∩ ...`` (also ``a & b``).

    Raises
    ------
    InvalidInputError, BooleanError
        As :func:`union`.

    Examples
    --------
    >>> from coons.topology.primitives import Box
    >>> r = intersection(Box(2, 2, 2), Box(2, 2, 2).translate((1, 1, 1)))
    >>> bool(np.isclose(r.volume, 1.0, rtol=1e-14)), len(r.faces())
    (True, 6)
    """
    return _fold("intersection", solids, tol)


def boolean(a: Solid, b: Solid, op: str, tol: Tolerance | None = None) -> Solid:
    """One binary Boolean, ``op`` in ``{"union", "intersection", "difference"}``.

    Raises
    ------
    InvalidInputError
        An unknown ``op`` or an argument that is not a Solid.
    BooleanError
        As :func:`union`.
    """
    if op not in _TABLE:
        raise InvalidInputError(f"op must be one of {sorted(_TABLE)}, got {op!r}")
    for name, s in (("a", a), ("b", b)):
        if not isinstance(s, Solid):
            raise InvalidInputError(f"Boolean operand {name} must be a coons Solid, got {type(s).__name__}")
    return _boolean(a, b, op, resolve(tol))


def _fold(op: str, solids: tuple, tol: Tolerance | None) -> Solid:
    t = resolve(tol)
    if not solids:
        raise InvalidInputError(f"{op} needs at least one solid, got none")
    for i, s in enumerate(solids):
        if not isinstance(s, Solid):
            raise InvalidInputError(f"{op}: argument {i} must be a coons Solid, got {type(s).__name__}")
    out = solids[0]
    for s in solids[1:]:
        out = _boolean(out, s, op, t)
    return out


# ====================================================================== the pipeline
def _boolean(a: Solid, b: Solid, op: str, t: Tolerance) -> Solid:
    """Phases 1–9 for two solids (see the module docstring)."""
    A = _meshes(a, "A", t)
    B = _meshes(b, "B", t)
    if A is None or B is None:  # an empty operand
        if op == "union":
            return b if A is None else a
        if op == "intersection":
            return Solid.empty()
        return Solid.empty() if A is None else a
    I, J = _broad_phase(A, B)
    # Faces that coincide only up to rounding are made to coincide exactly (features within
    # tol.linear become one feature) before the exact phases; see _mesh_arrangement.snap.
    A, B, snapped = snap(A, B, I, J, t.linear)
    if snapped:
        I, J = _broad_phase(A, B)
    ex = Exact(A.P, B.P)
    inter = _intersect(A, B, I, J, ex)
    table = PointTable(A, B, inter, ex)
    imp_a = _imprint(A, 0, inter, table)
    imp_b = _imprint(B, 1, inter, table)
    status_a = _classify(imp_a, A, B, 0, inter, table, ex)
    status_b = _classify(imp_b, B, A, 1, inter, table, ex)
    tris = _select(op, imp_a, status_a, imp_b, status_b)
    twin = _known_twins(op, tris, imp_a, status_a, A, imp_b, status_b, B, table)
    return _sew(tris, table, t, twin, _patch_groups(op, status_a, status_b))


@dataclass
class _Classified:
    """Patches of one operand's pieces and their statuses."""

    patch: np.ndarray  # (k,) patch of each piece
    status: np.ndarray  # (n_patches,) int8
    kept: dict = field(default_factory=dict, repr=False)  # _kept's masks by selected statuses


def _meshes(s: Solid, name: str, t: Tolerance) -> Operand | None:
    """Phase 1: the exact triangle mesh of a planar-faced solid (None for an empty solid).

    Raises
    ------
    BooleanError
        (stage ``"input"``) the first face that is not planar or edge that is not straight.
    """
    b = s.brep
    if b.n_faces == 0:
        return None
    # Geometry is shared by index: test each distinct surface and curve once, then name the first user.
    used = used_ids(b.face_surface, len(b.surfaces))
    bad = [int(i) for i in used if not isinstance(b.surfaces[int(i)], PlanarSurface)]
    if bad:
        f = int(np.flatnonzero(np.isin(b.face_surface, bad))[0])
        surface = b.surfaces[int(b.face_surface[f])]
        kind = getattr(surface, "surface_type", type(surface).__name__)
        raise BooleanError(
            f"operand {name}: face {f} lies on a {kind} surface; polyhedral Booleans need planar faces "
            "(curved faces are handled by the B-rep Booleans)",
            stage="input",
            diagnostics={"operand": name, "face": f, "surface": str(kind)},
        )
    used = used_ids(b.edge_curve, len(b.curves))
    bad = [int(i) for i in used if not isinstance(b.curves[int(i)], Line)]
    if bad:
        e = int(np.flatnonzero(np.isin(b.edge_curve, bad))[0])
        raise BooleanError(
            f"operand {name}: edge {e} is a {type(b.curves[int(b.edge_curve[e])]).__name__}; polyhedral "
            "Booleans need straight edges",
            stage="input",
            diagnostics={"operand": name, "edge": e},
        )
    direct = _triangle_faces(b)
    if direct is not None:
        return operand(b.vertex_point, direct[0], np.arange(b.n_faces, dtype=np.int64), name, tables=direct[1])
    from coons.topology.tessellate import tessellate

    box = b.bounding_box()
    # Planar faces with straight edges are triangulated on their own vertices whatever the
    # deflection; any value above the tolerance will do.
    deflection = max(float(np.linalg.norm(box[1] - box[0])), 2.0 * t.linear, 1.0)
    mesh = tessellate(s, deflection=deflection, tol=t)
    return operand(np.asarray(mesh.vertices), np.asarray(mesh.triangles), np.asarray(mesh.face_ids), name)


def _triangle_faces(b) -> tuple[np.ndarray, tuple] | None:
    """The faces as vertex triples ``(F, 3)`` when every face is one loop of three straight edges, else None.

    Such a B-rep (a mesh read by ``from_mesh``) is its own exact triangulation: each loop runs
    counter-clockwise about the outward normal (``docs/brep.md``), so the origins of its three
    coedges are an outward triangle.  Read from the tables in array time, no tessellation.  The
    mesh's edge tables are the B-rep's (``edges`` with the smaller vertex first, ``tri_edge``,
    ``edge_tris``), also read without a sort.
    """
    if b.n_loops != b.n_faces or np.any(np.diff(b.face_loop_ptr) != 1):
        return None
    c0 = b.loop_coedge[b.face_loops]
    if np.any(c0 < 0):
        return None
    nxt = b.coedge_next
    c1 = nxt[c0]
    c2 = nxt[c1]
    if np.any(nxt[c2] != c0):
        return None
    T = np.stack([b.coedge_origin[c0], b.coedge_origin[c1], b.coedge_origin[c2]], axis=1)
    ev = b.edge_vertex
    e0, e1 = ev[:, 0], ev[:, 1]
    edges = np.stack([np.minimum(e0, e1), np.maximum(e0, e1)], axis=1)  # np.sort(axis=1) is slower on pairs
    # One loop per face: the triangle (face) of each side of an edge.
    face_of_loop = np.empty(b.n_loops, dtype=np.int64)
    face_of_loop[b.face_loops] = np.arange(b.n_faces)
    edge_tris = face_of_loop[b.edge_loop]
    tri_edge = np.stack([c0 >> 1, c1 >> 1, c2 >> 1], axis=1)
    return T, (edges, tri_edge, edge_tris)


def _broad_phase(A: Operand, B: Operand) -> tuple[np.ndarray, np.ndarray]:
    """Phase 2: candidate triangle pairs whose closed boxes overlap.

    :func:`._broad_phase.triangle_pairs` on the triangle boxes the operands already hold (it
    would compute them again: a tenth of the phase at 1e5 triangles).
    """
    if A.lo is None or B.lo is None:
        return triangle_pairs(A.P, A.T, B.P, B.T)
    ka, kb = np.arange(A.m), np.arange(B.m)
    if A.m + B.m >= _CULL_MIN:
        kept = _vertex_cull(A.P, A.T, A.lo, A.hi, B.P, B.T, B.lo, B.hi)
        if kept is not None:
            ka, kb = kept
    I, J = box_pairs(*(np.take(x, k, axis=0) for x, k in ((A.lo, ka), (A.hi, ka), (B.lo, kb), (B.hi, kb))))
    return ka[I], kb[J]


def _intersect(A: Operand, B: Operand, I: np.ndarray, J: np.ndarray, ex: Exact) -> Intersections:
    """Phases 3–4: exact narrow phase, keyed points and segments."""
    return intersect(A, B, I, J, ex)


def _imprint(X: Operand, which: int, inter: Intersections, table: PointTable) -> Imprint:
    """Phase 5: split the triangles of one operand along the other surface."""
    return imprint(X, which, inter, table)


# ====================================================================== classification
def _classify(imp: Imprint, X: Operand, Y: Operand, which: int, inter: Intersections, table: PointTable,
              ex: Exact) -> _Classified:
    """Phase 6: patches of ``X``'s pieces and their status with respect to the solid bounded by ``Y``.

    Raises
    ------
    BooleanError
        (stage ``"classify"``) a query point found on the other surface (never expected: query
        points are chosen off it).
    """
    tris = imp.tris
    k = tris.shape[0]
    touch = _touching(X, which, inter)
    n_patch, patch = _patches(imp, X, table.float.shape[0], touch)
    rep = np.empty(n_patch, dtype=np.int64)
    rep[patch[::-1]] = np.arange(k - 1, -1, -1)  # a piece of each patch (any one will do)
    status = np.full(n_patch, -1, dtype=np.int8)
    # --- ON patches: the representative piece lies in a coplanar triangle of Y.
    cop = inter.coplanar
    if cop.size:
        own, other = (cop[:, 0], cop[:, 1]) if which == 0 else (cop[:, 1], cop[:, 0])
        src = imp.source[rep]
        has = np.isin(src, own)
        if np.any(has):
            status[has] = _on_status(tris[rep[has]], src[has], own, other, cop[:, 2], Y, table)
    # --- the rest by ray parity from one point per patch.
    todo = np.flatnonzero(status < 0)
    if todo.size:
        status[todo] = _ray_status(todo, patch, tris, X, Y, which, inter, table, ex, touch)
    return _Classified(patch, status)


def _touching(X: Operand, which: int, inter: Intersections) -> np.ndarray:
    """``(n,)`` bool: the original vertices of X that lie on the other surface (named as vertices of X in a
    keyed point)."""
    codes = inter.code_a if which == 0 else inter.code_b
    touch = np.zeros(X.n, dtype=bool)
    touch[codes[(codes & 3) == 0] >> 2] = True
    return touch


def _patches(imp: Imprint, X: Operand, n_ids: int, touch: np.ndarray) -> tuple[int, np.ndarray]:
    """Connected components of the pieces joined across piece edges not on the other surface.

    Whole (unsplit) triangles are joined through the operand's own edge table (no sort); only the
    pieces of split triangles and the edges around them are paired by sorting their keys.  An
    edge between two whole triangles can lie on the other surface only when both its vertices do
    (``touch (n,)`` bool, X's vertices named in a keyed point): only those edges are looked up.
    """
    tris = imp.tris
    k = tris.shape[0]
    n = np.int64(max(n_ids, 1))
    on = imp.on_edges
    on_keys = np.sort(on[:, 0] * n + on[:, 1]) if on.size else np.zeros(0, np.int64)

    def off_surface(key: np.ndarray) -> np.ndarray:
        if on_keys.size == 0:
            return np.ones(key.size, dtype=bool)
        pos = np.minimum(np.searchsorted(on_keys, key), on_keys.size - 1)
        return on_keys[pos] != key

    if imp.vid is None:  # generic: pair every piece edge by sorting
        a = tris.ravel()
        b = next_corners(tris)
        und = np.minimum(a, b) * n + np.maximum(a, b)
        order = np.argsort(und, kind="stable")
        piece = np.repeat(np.arange(k), 3)
        p1, p2 = piece[order[0::2]], piece[order[1::2]]
        link = off_surface(und[order[0::2]])
        src, dst = p1[link], p2[link]
    else:
        nw = imp.n_whole
        row = np.full(X.m, -1, dtype=np.int64)
        row[imp.source[:nw]] = np.arange(nw)
        r = row[X.edge_tris]  # (E, 2) piece rows of the two triangles of each edge (-1: split)

        def ekey(e: np.ndarray) -> np.ndarray:  # point-id keys of X's edges e
            ev = imp.vid[np.take(X.edges, e, axis=0)]
            return np.minimum(ev[:, 0], ev[:, 1]) * n + np.maximum(ev[:, 0], ev[:, 1])

        whole = (r[:, 0] >= 0) & (r[:, 1] >= 0)
        maybe = np.flatnonzero(whole & touch[X.edges[:, 0]] & touch[X.edges[:, 1]])
        whole[maybe[~off_surface(ekey(maybe))]] = False
        both = np.flatnonzero(whole)
        # The small part: the split triangles' pieces and the whole triangles next to them.
        one = np.flatnonzero((r[:, 0] >= 0) != (r[:, 1] >= 0))
        pieces = tris[nw:]
        pa, pb = pieces.ravel(), next_corners(pieces)
        keys = np.concatenate([np.minimum(pa, pb) * n + np.maximum(pa, pb), ekey(one)])
        node = np.concatenate([nw + np.repeat(np.arange(pieces.shape[0]), 3), np.maximum(r[one, 0], r[one, 1])])
        order = np.argsort(keys, kind="stable")
        ks = keys[order]
        pair = np.flatnonzero(ks[1:] == ks[:-1])
        pair = pair[off_surface(ks[pair])]
        src = np.concatenate([r[both, 0], node[order[pair]]])
        dst = np.concatenate([r[both, 1], node[order[pair + 1]]])
    g = coo_matrix((np.ones(src.size, dtype=np.int8), (src, dst)), shape=(k, k))
    n_patch, patch = connected_components(g, directed=False)
    return int(n_patch), patch.astype(np.int64)


def _centroids(tris: np.ndarray, table: PointTable) -> np.ndarray:
    """Exact centroids ``(k, 4)`` (homogeneous integers) of pieces ``tris (k, 3)``."""
    H = table.exact(tris.ravel()).reshape(-1, 3, 4)
    w0, w1, w2 = H[:, 0, 3], H[:, 1, 3], H[:, 2, 3]
    out = np.empty((tris.shape[0], 4), dtype=object)
    for c in range(3):
        out[:, c] = H[:, 0, c] * w1 * w2 + H[:, 1, c] * w0 * w2 + H[:, 2, c] * w0 * w1
    out[:, 3] = 3 * w0 * w1 * w2
    return out


def _on_status(pieces: np.ndarray, src: np.ndarray, own: np.ndarray, other: np.ndarray, same: np.ndarray,
               Y: Operand, table: PointTable) -> np.ndarray:
    """``ON_SAME`` / ``ON_OPPOSITE`` for pieces lying strictly inside a coplanar triangle of ``Y``, else -1.

    The centroid of each piece is tested against each coplanar partner of its source triangle
    in the partner's projection, exactly (homogeneous integers).
    """
    out = np.full(pieces.shape[0], -1, dtype=np.int8)
    order = np.argsort(own, kind="stable")
    own_s = own[order]
    lo = np.searchsorted(own_s, src, side="left")
    hi = np.searchsorted(own_s, src, side="right")
    cnt = hi - lo
    q = np.repeat(np.arange(pieces.shape[0]), cnt)
    idx = order[np.repeat(lo, cnt) + np.arange(cnt.sum()) - np.repeat(np.cumsum(cnt) - cnt, cnt)]
    if q.size == 0:
        return out
    cen = _centroids(pieces, table)[q]
    u = other[idx]
    axis, sgn = _projection(Y.P, Y.T, u)
    corners = table.ex.ints(Y.P[Y.T[u]])  # (k, 3, 3) integers
    r = np.arange(u.size)
    i, j = (axis + 1) % 3, (axis + 2) % 3
    cx, cy = corners[r[:, None], np.arange(3)[None, :], i[:, None]], corners[r[:, None], np.arange(3)[None, :], j[:, None]]
    px, py, w = cen[r, i], cen[r, j], cen[:, 3]
    inside = np.ones(u.size, dtype=bool)
    for e in range(3):
        ax_, ay_ = cx[:, e], cy[:, e]
        bx_, by_ = cx[:, (e + 1) % 3], cy[:, (e + 1) % 3]
        # orient2d(a, b, p) * w for p = (px, py) / w
        d = (ax_ * w - px) * (by_ * w - py) - (ay_ * w - py) * (bx_ * w - px)
        s = ((d > 0).astype(np.int8) - (d < 0).astype(np.int8)) * sgn
        inside &= s > 0
    hit = np.flatnonzero(inside)
    out[q[hit]] = np.where(same[idx[hit]] > 0, ON_SAME, ON_OPPOSITE)
    return out


def _ray_status(todo: np.ndarray, patch: np.ndarray, tris: np.ndarray, X: Operand, Y: Operand, which: int,
                inter: Intersections, table: PointTable, ex: Exact, touch: np.ndarray) -> np.ndarray:
    """``IN`` / ``OUT`` of the patches ``todo`` by exact ray parity (module docstring, phase 6);
    ``touch (n,)`` bool: X's original vertices that lie on Y."""
    nA, nB = table.nA, table.nB
    if which == 0:
        free_id = np.flatnonzero(~touch)
    else:
        free = ~touch & (inter.alias_b == nA + np.arange(nB))
        free_id = nA + np.flatnonzero(free)
    want = np.zeros(patch.max(initial=-1) + 1, dtype=bool)
    want[todo] = True
    # A free original vertex of each patch, if any.
    free_mask = np.zeros(table.float.shape[0], dtype=bool)
    free_mask[free_id] = True
    vert_of = np.full(want.size, -1, dtype=np.int64)
    # Blocks of pieces of doubling size until every patch has one: the patches are few and large, so
    # the first block nearly always serves them all (a scan of every piece only for a patch without one).
    start, step = 0, _QUERY_BLOCK
    while start < tris.shape[0]:
        stop = min(tris.shape[0], start + step)
        pb = patch[start:stop]
        wanted = want[pb]
        for c in range(3):
            V = tris[start:stop, c]
            ok = np.flatnonzero(free_mask[V] & wanted)
            vert_of[pb[ok]] = V[ok]  # any one
        if np.all(vert_of[todo] >= 0):
            break
        start, step = stop, 2 * step
    result = np.zeros(want.size, dtype=np.int8)
    with_vertex = todo[vert_of[todo] >= 0]
    if with_vertex.size:
        q = table.float[vert_of[with_vertex]]
        result[with_vertex] = _parity_float(q, Y)
    without = todo[vert_of[todo] < 0]
    if without.size:
        first = np.empty(want.size, dtype=np.int64)
        first[patch[::-1]] = np.arange(tris.shape[0] - 1, -1, -1)  # a piece of each patch
        H = _centroids(tris[first[without]], table)
        result[without] = _parity_exact(H, Y, ex)
    return np.where(result % 2 == 1, IN, OUT).astype(np.int8)[todo]


#: Pieces searched first for a query vertex of each patch (:func:`_ray_status`; the block doubles while a
#: patch has none).
_QUERY_BLOCK = 4096
#: Queries tested one by one against every triangle box; more go to the broad phase (a Python loop over
#: queries pays only for a few).
_RAY_FEW = 8
#: Candidate pairs the sweep of :func:`_ray_candidates` may list (memory: a few hundred MB at most).
_RAY_SWEEP_MAX = 1 << 24


def _ray_candidates(lo: np.ndarray, hi: np.ndarray, Y: Operand) -> tuple[np.ndarray, np.ndarray]:
    """Pairs (query, triangle of Y) whose boxes meet the ray boxes ``[lo, hi]``.

    Few queries (the usual case: a handful of patches) are tested against every triangle box
    directly, one query at a time over contiguous columns.  Many are swept: the ray boxes are
    (nearly) points in ``yz`` but reach across the mesh in ``x`` (a 3-D grid would put every ray in
    a whole row of cells), so the queries are sorted on ``y`` or ``z`` (the axis giving fewer
    candidates), each triangle box takes the queries of its range on that axis (two
    ``searchsorted``), and the full box overlap filters the candidates exactly.
    """
    Ylo, Yhi = (Y.lo, Y.hi) if Y.lo is not None else triangle_boxes(Y.P, Y.T)
    if lo.shape[0] > _RAY_FEW:
        best = None
        for c in (1, 2):
            order = np.argsort(lo[:, c], kind="stable")
            qs = lo[order, c]
            # A query box [lo, hi] meets [Ylo, Yhi] on axis c iff lo <= Yhi and hi >= Ylo; lo >= Ylo - width
            # is implied by the second (width: the widest query box on c), so the range is a superset.
            width = float(np.max(hi[:, c] - lo[:, c]))
            first = np.searchsorted(qs, Ylo[:, c] - width, side="left")
            count = np.searchsorted(qs, Yhi[:, c], side="right") - first
            total = int(count.sum())
            if best is None or total < best[0]:
                best = (total, order, first, count)
        total, order, first, count = best
        if total > _RAY_SWEEP_MAX:  # queries crowded on both axes: the grid bounds its own work
            return box_pairs(lo, hi, Ylo, Yhi)
        J = np.repeat(np.arange(Y.m), count)
        I = order[np.repeat(first, count) + np.arange(total) - np.repeat(np.cumsum(count) - count, count)]
        keep = np.ones(total, dtype=bool)
        for c in range(3):
            keep &= (lo[I, c] <= Yhi[J, c]) & (Ylo[J, c] <= hi[I, c])
        return I[keep], J[keep]
    cols = [(np.ascontiguousarray(Ylo[:, c]), np.ascontiguousarray(Yhi[:, c])) for c in range(3)]
    I, J = [], []
    for q in range(lo.shape[0]):
        ok = cols[0][1] >= lo[q, 0]
        ok &= cols[0][0] <= hi[q, 0]
        for c in (1, 2):
            ok &= cols[c][0] <= hi[q, c]
            ok &= cols[c][1] >= lo[q, c]
        j = np.flatnonzero(ok)
        I.append(np.full(j.size, q, dtype=np.int64))
        J.append(j)
    if not I:
        return np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64)
    return np.concatenate(I), np.concatenate(J)


def _perturbed(d: np.ndarray, az_bz: np.ndarray, by_ay: np.ndarray) -> np.ndarray:
    """Sign of ``orient2d(a, b, q + (ε, ε²))`` in the ``yz`` plane: the determinant's sign, or of
    its ε coefficient ``a_z − b_z``, or of its ε² coefficient ``b_y − a_y`` (exact float differences)."""
    return np.where(d != 0, d, np.where(az_bz != 0, np.sign(az_bz), np.sign(by_ay))).astype(np.int8)


def _parity_float(q: np.ndarray, Y: Operand) -> np.ndarray:
    """Number of crossings (mod 2) of the rays ``q + λ x̂`` (``q (k, 3)`` floats) with the surface of ``Y``."""
    big = float(Y.P[:, 0].max())
    lo = q.copy()
    hi = q.copy()
    hi[:, 0] = np.maximum(big, q[:, 0])
    I, J = _ray_candidates(lo, hi, Y)
    if I.size == 0:
        return np.zeros(q.shape[0], dtype=np.int8)
    C = np.take(Y.P, np.take(Y.T, J, axis=0), axis=0)
    Q = q[I]
    yz = C[:, :, 1:]
    qz = Q[:, 1:]
    s = []
    for e in range(3):
        a, b = yz[:, e], yz[:, (e + 1) % 3]
        d = orient2d(a, b, qz)
        s.append(_perturbed(d, a[:, 1] - b[:, 1], b[:, 0] - a[:, 0]))
    s = np.stack(s, axis=1)
    hit = np.all(s > 0, axis=1) | np.all(s < 0, axis=1)
    I, J, C, Q = I[hit], J[hit], C[hit], Q[hit]
    if I.size == 0:
        return np.zeros(q.shape[0], dtype=np.int8)
    nx = orient2d(C[:, 0, 1:], C[:, 1, 1:], C[:, 2, 1:])
    o3 = orient3d(C[:, 0], C[:, 1], C[:, 2], Q)
    _no_surface_hit(o3, I, J)
    ahead = o3 == nx
    return (np.bincount(I[ahead], minlength=q.shape[0]) % 2).astype(np.int8)


def _no_surface_hit(o3: np.ndarray, I: np.ndarray, J: np.ndarray) -> None:
    if np.any(o3 == 0):
        k = int(np.flatnonzero(o3 == 0)[0])
        raise BooleanError(
            f"classification query {int(I[k])} lies on triangle {int(J[k])} of the other operand; expected a point "
            "off its surface",
            stage="classify",
            diagnostics={"query": int(I[k]), "triangle": int(J[k])},
        )


def _parity_exact(H: np.ndarray, Y: Operand, ex: Exact) -> np.ndarray:
    """As :func:`_parity_float` for exact rational queries ``H (k, 4)`` (homogeneous integers).

    Each sign is first evaluated at the query's nearest float ``q̃`` (within ``δ = u |q̃|`` per
    coordinate of the exact ``q``): a determinant larger than its gradient times ``δ`` plus its
    own evaluation error (Shewchuk's bound) has the sign of the exact one; the rest — including
    the zeros that simulation of simplicity resolves — are evaluated with integers.
    """
    u = 2.0**-53
    qf = ex.rounded(H)
    lo = np.nextafter(qf, -np.inf)
    hi = np.nextafter(qf, np.inf)
    hi[:, 0] = np.maximum(float(Y.P[:, 0].max()), hi[:, 0])
    I, J = _ray_candidates(lo, hi, Y)
    if I.size == 0:
        return np.zeros(H.shape[0], dtype=np.int8)
    Cf = np.take(Y.P, np.take(Y.T, J, axis=0), axis=0)
    Q = qf[I]
    delta = 2.0 * u * np.abs(Q) + 1e-300  # |q - q̃| per coordinate (half an ulp, doubled)
    s = np.zeros((I.size, 3), dtype=np.int8)
    amb = np.zeros((I.size, 3), dtype=bool)
    for e in range(3):
        a, b = Cf[:, e], Cf[:, (e + 1) % 3]
        t1 = (a[:, 1] - Q[:, 1]) * (b[:, 2] - Q[:, 2])
        t2 = (a[:, 2] - Q[:, 2]) * (b[:, 1] - Q[:, 1])
        d = t1 - t2
        bound = 1.01 * (np.abs(a[:, 2] - b[:, 2]) * delta[:, 1] + np.abs(b[:, 1] - a[:, 1]) * delta[:, 2]) \
            + 8 * u * (np.abs(t1) + np.abs(t2)) + 1e-300
        s[:, e] = np.where(d > bound, 1, np.where(-d > bound, -1, 0))
        amb[:, e] = s[:, e] == 0
    rows = np.flatnonzero(amb.any(axis=1))
    if rows.size:
        C = ex.ints(Cf[rows])
        Qh = H[I[rows]]
        Y_, Z_, W = Qh[:, 1], Qh[:, 2], Qh[:, 3]
        for e in range(3):
            a, b = C[:, e], C[:, (e + 1) % 3]
            # orient2d((a_y, a_z), (b_y, b_z), (Y, Z) / W) * W^2
            d = (a[:, 1] * W - Y_) * (b[:, 2] * W - Z_) - (a[:, 2] * W - Z_) * (b[:, 1] * W - Y_)
            d = ((d > 0).astype(np.int8) - (d < 0).astype(np.int8)).astype(np.int8)
            af, bf = Cf[rows, e], Cf[rows, (e + 1) % 3]
            s[rows, e] = _perturbed(d, af[:, 2] - bf[:, 2], bf[:, 1] - af[:, 1])
    hit = np.all(s > 0, axis=1) | np.all(s < 0, axis=1)
    I, J, Cf, Q, delta = I[hit], J[hit], Cf[hit], Q[hit], delta[hit]
    if I.size == 0:
        return np.zeros(H.shape[0], dtype=np.int8)
    nx = orient2d(Cf[:, 0, 1:], Cf[:, 1, 1:], Cf[:, 2, 1:])
    # orient3d(a, b, c, q) = -n . (q - a): float value, gradient bound and evaluation error.
    ad, bd, cd = Cf[:, 0] - Q, Cf[:, 1] - Q, Cf[:, 2] - Q
    cr = np.cross(bd, cd)
    det = np.einsum("ij,ij->i", ad, cr)
    perm = np.einsum("ij,ij->i", np.abs(ad), np.abs(bd[:, [1, 2, 0]] * cd[:, [2, 0, 1]]) + np.abs(bd[:, [2, 0, 1]] * cd[:, [1, 2, 0]]))
    n = np.cross(Cf[:, 1] - Cf[:, 0], Cf[:, 2] - Cf[:, 0])
    bound = 1.01 * np.einsum("ij,ij->i", np.abs(n), delta) * (1 + 8 * u) + 16 * u * perm + 1e-300
    o3 = np.where(det > bound, 1, np.where(-det > bound, -1, 0)).astype(np.int8)
    amb = np.flatnonzero(o3 == 0)
    if amb.size:
        C = ex.ints(Cf[amb])
        Qh = H[I[amb]]
        W = Qh[:, 3]
        rr = [C[:, c] * W[:, None] - Qh[:, :3] for c in range(3)]  # (a - q) W, ...
        d3 = (rr[0][:, 0] * (rr[1][:, 1] * rr[2][:, 2] - rr[1][:, 2] * rr[2][:, 1])
              - rr[0][:, 1] * (rr[1][:, 0] * rr[2][:, 2] - rr[1][:, 2] * rr[2][:, 0])
              + rr[0][:, 2] * (rr[1][:, 0] * rr[2][:, 1] - rr[1][:, 1] * rr[2][:, 0]))
        o3[amb] = ((d3 > 0).astype(np.int8) - (d3 < 0).astype(np.int8)).astype(np.int8)
    _no_surface_hit(o3, I, J)
    ahead = o3 == nx
    return (np.bincount(I[ahead], minlength=H.shape[0]) % 2).astype(np.int8)


# ====================================================================== selection and sewing
def _select(op: str, imp_a: Imprint, ca: _Classified, imp_b: Imprint, cb: _Classified) -> np.ndarray:
    """Phase 7: the result's triangles (global ids), by the selection table of the module docstring."""
    keep_a, keep_b, reverse_b = _TABLE[op]
    sa = ca.status[ca.patch]
    sb = cb.status[cb.patch]
    if np.any(sa < 0) or np.any(sb < 0):
        raise BooleanError("a patch was left unclassified", stage="select",
                           diagnostics={"unclassified_a": int((sa < 0).sum()), "unclassified_b": int((sb < 0).sum())})
    # np.compress / np.take: row selections several times faster than boolean or integer indexing.
    ta = np.compress(_kept(ca, keep_a), imp_a.tris, axis=0)
    tb = np.compress(_kept(cb, keep_b), imp_b.tris, axis=0)
    if reverse_b:
        tb = tb[:, ::-1]
    return np.concatenate([ta, tb])


def _known_twins(op: str, tris: np.ndarray, imp_a: Imprint, ca: _Classified, A: Operand, imp_b: Imprint,
                 cb: _Classified, B: Operand, table: PointTable) -> np.ndarray:
    """``(3 k,)`` int64: the twin of each half-edge of :func:`_select`'s triangles ``tris (k, 3)`` where the operands'
    edge tables already know it, else -1 (half-edge ``3 r + j`` runs from ``tris[r, j]`` to
    ``tris[r, (j + 1) % 3]``).

    An edge of an operand between two whole (unsplit) triangles that are both selected is an edge
    of the result with these two half-edges, read from ``edge_tris`` / ``tri_edge`` without a sort.
    No other selected half-edge can join the same two points: a piece or whole triangle of the same
    (valid, manifold) operand with both points as vertices would be a third triangle on that
    edge, and a triangle of the other operand uses both ids only if both are used by both
    operands — such edges are left to the sort (-1) so that :func:`_pair_half_edges` still finds
    an edge used more than twice.  Every other half-edge (pieces, the rims of split regions) is -1.
    """
    keep_a, keep_b, reverse_b = _TABLE[op]
    parts = []
    for imp, c, X, keep, rev in ((imp_a, ca, A, keep_a, False), (imp_b, cb, B, keep_b, reverse_b)):
        sel = np.flatnonzero(_kept(c, keep))
        parts.append((sel, int(np.searchsorted(sel, imp.n_whole)), imp, X, rev))
    k_a = parts[0][0].size
    k = k_a + parts[1][0].size
    if k != tris.shape[0]:
        raise BooleanError(f"internal: {tris.shape[0]} selected triangles, the statuses keep {k}", stage="select")
    twin = np.full(3 * k, -1, dtype=np.int64)
    # Corner j of a kept row holds the half-edge of the source triangle's edge k (j = k, or
    # (1 - k) % 3 for B's triangles reversed by the difference: (v2, v1, v0) runs v1 -> v2 second).
    # Each kept whole triangle writes its half-edge into its side of the operand edge (side 0 when
    # it is edge_tris[e, 0]); edges with both sides written are pairs.
    for (sel, n_ws, imp, X, rev), row0 in zip(parts, (0, k_a)):
        if n_ws == 0:
            continue
        src = imp.source[sel[:n_ws]]  # the whole triangles kept, as rows row0 + i
        e = np.take(X.tri_edge, src, axis=0).ravel()  # (3 w,) the edge of each corner
        side = (X.edge_tris[:, 0][e].reshape(n_ws, 3) != src[:, None]).ravel()  # broadcast: no np.repeat
        # Half-edge 3 (row0 + i) + j of corner k = j: an arange, with corners 0 and 1 swapped when reversed.
        hid = np.arange(3 * row0, 3 * (row0 + n_ws), dtype=np.int64)
        if rev:
            hid += np.tile(np.array([1, -1, 0], dtype=np.int64), n_ws)
        he = np.full(2 * X.n_edges, -1, dtype=np.int64)
        he[2 * e + side] = hid
        h0, h1 = he[0::2], he[1::2]
        both = np.flatnonzero((h0 >= 0) & (h1 >= 0))
        h0, h1 = h0[both], h1[both]
        twin[h0], twin[h1] = h1, h0
    # Edges whose two points are both used by both operands' rows go to the sort.
    n_ids = table.float.shape[0]
    used_a, used_b = np.zeros(n_ids, dtype=bool), np.zeros(n_ids, dtype=bool)
    used_a[tris[:k_a].ravel()] = True
    used_b[tris[k_a:].ravel()] = True
    shared = used_a & used_b
    if np.any(shared):
        org, dst = tris.ravel(), next_corners(tris)
        twin[shared[org] & shared[dst]] = -1
    return twin


def _patch_groups(op: str, ca: _Classified, cb: _Classified) -> np.ndarray:
    """``(k,)`` int64: the patch of each of :func:`_select`'s triangles (B's patches numbered after A's).

    A patch is connected through piece edges off the other surface, and both pieces of such an edge
    have the patch's status, so are both selected: the triangles of one patch are connected in the
    result, which lets the sew find the result's shells on the patches (a handful) instead of on
    every triangle (:func:`coons.topology.from_mesh._components`).
    """
    keep_a, keep_b, _ = _TABLE[op]
    n_a = int(ca.status.size)
    return np.concatenate([np.compress(_kept(ca, keep_a), ca.patch), n_a + np.compress(_kept(cb, keep_b), cb.patch)])


def _kept(c: _Classified, keep: set) -> np.ndarray:
    """``(k,)`` bool: the pieces whose patch status is in ``keep`` (a lookup table over the four statuses);
    computed once per selection (select, the known twins and the patch groups all ask)."""
    key = frozenset(keep)
    mask = c.kept.get(key)
    if mask is None:
        table = np.zeros(len(_STATUS_NAMES), dtype=bool)
        table[list(keep)] = True
        mask = c.kept[key] = table[c.status][c.patch]
    return mask


def _sew(tris: np.ndarray, table: PointTable, t: Tolerance, twin: np.ndarray | None = None,
         groups: np.ndarray | None = None) -> Solid:
    """Phases 8–9: round, clean features below the tolerance, check the result is manifold, build and check it.

    ``twin (3 k,)``, optional: the half-edge twins :func:`_known_twins` read from the operands (-1
    where unknown); used when the clean-up leaves the triangles unchanged, so that only the other
    half-edges are paired by sorting.  ``groups (k,)``, optional: the patch of each triangle
    (:func:`_patch_groups`), used under the same condition to find the result's shells.

    Raises
    ------
    BooleanError
        (stage ``"sew"``) a non-manifold result, or a clean-up that does not converge; (stage
        ``"check"``) a result the checker rejects.
    """
    if tris.shape[0] == 0:
        return Solid.empty()
    nA, nB = table.nA, table.nB
    # Rows made only of one operand's original vertices are input triangles (whole, or a piece
    # that is a whole triangle): nothing below the tolerance can start there (see _clean).
    lo_all = (tris[:, 0] < nA) & (tris[:, 1] < nA) & (tris[:, 2] < nA)
    inb = (tris >= nA) & (tris < nA + nB)
    active = ~(lo_all | (inb[:, 0] & inb[:, 1] & inb[:, 2]))
    used, T = _compact(tris, table.float.shape[0])
    P = np.take(table.float, used, axis=0)
    original = used < nA + nB
    T_raw = T
    T = _clean(P, T, original, t.linear, active)
    if T is not T_raw:  # the clean-up changed the triangles: their twins and shells are found again
        twin = groups = None
    if T.shape[0] == 0:
        return Solid.empty()
    if T is not T_raw:  # points the clean-up left unused are dropped (unchanged T uses every point)
        used, T = _compact(T, P.shape[0])
        P = np.take(P, used, axis=0)
    try:
        return _build(P, T, t, twin, groups)
    except BooleanError:
        # Diagnose: a non-manifold result gets a clear message; a closed component thinner than the
        # tolerance (two facing triangulations of one flat patch) is removed and the build retried.
        T2 = _drop_thin_components(P, T, t.linear)
        if T2.shape[0] == T.shape[0]:
            _manifold(T, P)
            raise
        if T2.shape[0] == 0:
            return Solid.empty()
        used, T2 = np.unique(T2, return_inverse=True)
        P, T = P[used], T2.reshape(-1, 3)
        try:
            return _build(P, T, t)
        except BooleanError:
            _manifold(T, P)
            raise


def _compact(T: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray]:
    """The ids ``T`` uses (increasing) and ``T`` renumbered onto them (``np.unique`` without a sort)."""
    mask = np.zeros(n, dtype=bool)
    mask[T.ravel()] = True
    used = np.flatnonzero(mask)
    new = np.zeros(n, dtype=np.int64)
    new[used] = np.arange(used.size)
    return used, new[T]


def _build(P: np.ndarray, T: np.ndarray, t: Tolerance, twin: np.ndarray | None = None,
           groups: np.ndarray | None = None) -> Solid:
    """The checked solid of the cleaned result mesh (``from_mesh``'s construction with coplanar merging,
    through its fast path for clean meshes); errors become ``BooleanError`` (stage ``"sew"`` or ``"check"``)."""
    from coons.topology.from_mesh import _solid_from_clean_triangles

    try:
        return _solid_from_clean_triangles(P, T, t, merge_coplanar=True, straighten=True, no_sheets=True, twin=twin,
                                           groups=groups)
    except TopologyError as exc:
        msg = str(exc)
        if "wrong sign" in msg:
            raise BooleanError(f"the selected pieces are inconsistently oriented: {msg}", stage="sew") from None
        stage = "check" if "does not bound a valid solid" in msg else "sew"
        raise BooleanError(msg, stage=stage, diagnostics={"triangles": int(T.shape[0])}) from None


#: Rounds of the clean-up before giving up (each round removes every short edge and cap it finds).
_MAX_CLEAN_ROUNDS = 32


def _clean(P: np.ndarray, T: np.ndarray, original: np.ndarray, eps: float,
           active: np.ndarray | None = None) -> np.ndarray:
    """Remove the features of the rounded result that lie below the tolerance ``eps``.

    Near-coincident inputs (faces that agree only up to rounding, a vertex an ulp off an
    edge) give exact results with features far below the tolerance — edges of length 1e-16,
    slivers, walls a rounding error apart — that floats cannot carry and ``from_mesh`` rejects.
    Each round, vectorised:

    1. *short edges*: the vertices joined by edges of length at most ``eps`` (identical rounded
       coordinates included) are merged into one, an original input vertex when the cluster has
       one (connected components); triangles with a repeated vertex disappear;
    2. *cancelling pairs*: two triangles on the same three vertices with opposite orientations
       (a wall and its twin) are both removed;
    3. *caps*: a triangle whose height over its longest edge is at most ``eps`` has its apex
       inserted into that edge — the cap is removed and the triangle on the other side of the
       edge is split at the apex (an edge split), which keeps the mesh closed.

    Geometry moves by at most ``eps`` per operation (cluster diameters are checked against a few
    ``eps``).  Results without such features are returned unchanged.

    ``active (k,)`` bool, optional: the rows where a feature can start (the others are input
    triangles between original vertices of one operand: their edges and heights are the valid
    input's, and a cancelling twin of one would lie on the other operand's surface, classified
    ``ON`` and not selected).  Each later round searches only the rows the previous one changed or
    made (a feature appears only where a vertex moved or a cap was split; a cancelling partner is
    looked for among the rows on the searched rows' vertices), so the clean-up costs in proportion
    to the features, not to the mesh.  (Closed components thinner than the tolerance are removed
    by :func:`_drop_thin_components` when ``from_mesh`` rejects the result.)

    Returns
    -------
    (k, 3) int64: the cleaned triangles (ids into ``P``).

    Raises
    ------
    BooleanError
        (stage ``"sew"``) a cluster wider than ``4 eps`` or no convergence in ``_MAX_CLEAN_ROUNDS``.
    """
    n = P.shape[0]
    # ``act``: the rows searched this round; ``fresh``: the rows this round changes or makes, the only
    # ones where a feature can appear next round (merging moves only rows with a merged vertex,
    # cancelling removes rows, a cap split makes two new rows).
    act = np.ones(T.shape[0], dtype=bool) if active is None else np.asarray(active, dtype=bool).copy()
    for _ in range(_MAX_CLEAN_ROUNDS):
        changed = False
        fresh = np.zeros(T.shape[0], dtype=bool)
        # 1. short edges and identical points.
        rows = np.flatnonzero(act)
        Ts = np.take(T, rows, axis=0)
        a = Ts.ravel()
        b = next_corners(Ts)
        L = np.linalg.norm(np.take(P, a, axis=0) - np.take(P, b, axis=0), axis=1)
        short = L <= eps
        if np.any(short):
            src, dst = a[short], b[short]
            g = coo_matrix((np.ones(src.size, dtype=np.int8), (src, dst)), shape=(n, n))
            _, comp = connected_components(g, directed=False)
            # representative: an original vertex if any, else the smallest id
            rank = np.where(original, 0, 1) * np.int64(n) + np.arange(n)
            best = np.full(comp.max() + 1, np.iinfo(np.int64).max)
            np.minimum.at(best, comp, rank)
            rep = best[comp] % np.int64(n)
            moved = np.linalg.norm(P - P[rep], axis=1)
            if np.any(moved > 4 * eps):
                v = int(np.argmax(moved))
                raise BooleanError(
                    f"clean-up: a cluster of vertices closer than the tolerance {eps:g} spans {moved[v]:.3g} "
                    f"(vertex at {P[v].tolist()}); expected at most {4 * eps:g}",
                    stage="sew", diagnostics={"vertex": P[v].tolist(), "moved": float(moved[v])},
                )
            T_old, T = T, rep[T]
            keep = (T[:, 0] != T[:, 1]) & (T[:, 1] != T[:, 2]) & (T[:, 2] != T[:, 0])
            # A merge must not turn a surviving triangle over (a fold the checker would not see).
            touched = np.any(T != T_old, axis=1)
            fold = keep & touched
            if np.any(fold):
                C0, C1 = P[T_old[fold]], P[T[fold]]
                n0 = np.cross(C0[:, 1] - C0[:, 0], C0[:, 2] - C0[:, 0])
                n1 = np.cross(C1[:, 1] - C1[:, 0], C1[:, 2] - C1[:, 0])
                L = np.max(np.linalg.norm(C1 - C1[:, [1, 2, 0]], axis=2), axis=1)
                tall = np.linalg.norm(n1, axis=1) > eps * L  # height above eps: not a cap to be removed
                flipped = np.einsum("ij,ij->i", n0, n1) < 0
                if np.any(flipped & tall):
                    k = int(np.flatnonzero(fold)[np.argmax(flipped & tall)])
                    raise BooleanError(
                        f"clean-up: merging vertices closer than {eps:g} would turn over the triangle at "
                        f"{P[T[k]].tolist()}", stage="sew", diagnostics={"triangle": P[T[k]].tolist()},
                    )
            T, act, fresh = T[keep], (act | touched)[keep], touched[keep]
            changed = True
        # 2. cancelling pairs: among the searched rows and the rows on their vertices only (a partner
        # has the same three vertices).
        if T.shape[0] and np.any(act):
            near = _rows_on(T, np.flatnonzero(act), 3)
            sub = np.take(T, near, axis=0)
            S = np.sort(sub, axis=1)
            key = (S[:, 0] * np.int64(n) + S[:, 1]) * np.int64(n) + S[:, 2]
            _, inv, cnt = np.unique(key, return_inverse=True, return_counts=True)
            if np.any(cnt > 1):
                # parity of the rotation from the sorted triple: even permutations are one orientation
                even = ((sub[:, 0] == S[:, 0]) & (sub[:, 1] == S[:, 1])) | (
                    (sub[:, 1] == S[:, 0]) & (sub[:, 2] == S[:, 1])) | ((sub[:, 2] == S[:, 0]) & (sub[:, 0] == S[:, 1]))
                plus = np.bincount(inv, weights=even.astype(float), minlength=cnt.size)
                drop_pairs = np.minimum(plus, cnt - plus)
                # remove min(plus, minus) of each orientation per key
                keep = np.ones(T.shape[0], dtype=bool)
                for kk in np.flatnonzero(drop_pairs > 0).tolist():
                    r = np.flatnonzero(inv == kk)
                    m = int(drop_pairs[kk])
                    keep[near[r[even[r]][:m]]] = False
                    keep[near[r[~even[r]][:m]]] = False
                if not np.all(keep):
                    T, act, fresh = T[keep], act[keep], fresh[keep]
                    changed = True
        # 3. caps.
        rows = np.flatnonzero(act)
        if rows.size:
            C = np.take(P, np.take(T, rows, axis=0), axis=0)
            e = np.stack([C[:, 1] - C[:, 0], C[:, 2] - C[:, 1], C[:, 0] - C[:, 2]], axis=1)
            el = np.linalg.norm(e, axis=2)
            longest = np.argmax(el, axis=1)
            area2 = np.linalg.norm(np.cross(C[:, 1] - C[:, 0], C[:, 2] - C[:, 0]), axis=1)
            height = area2 / np.maximum(el[np.arange(rows.size), longest], np.finfo(float).tiny)
            caps = np.flatnonzero(height <= eps)
            if caps.size:
                fresh[rows[caps]] = True  # caps left for the next round (one split per neighbour per round)
                T, keep = _split_caps(T, rows[caps], longest[caps])
                if keep is not None:
                    made = T.shape[0] - int(keep.sum())
                    fresh = np.concatenate([fresh[keep], np.ones(made, dtype=bool)])
                changed = True  # a cap that cannot be split (an open edge) ends in the convergence error
        if not changed:
            return T
        act = fresh
    raise BooleanError(
        f"clean-up of features below the tolerance {eps:g} did not converge in {_MAX_CLEAN_ROUNDS} rounds",
        stage="sew", diagnostics={"triangles": int(T.shape[0])},
    )


def _drop_thin_components(P: np.ndarray, T: np.ndarray, eps: float) -> np.ndarray:
    """Remove the edge-connected components of ``T`` whose ``|volume| <= eps · area`` (sheets below the tolerance)."""
    if T.shape[0] == 0:
        return T
    m = T.shape[0]
    n = np.int64(T.max() + 1)
    a = T.ravel()
    b = next_corners(T)
    und = np.minimum(a, b) * n + np.maximum(a, b)
    order = np.argsort(und, kind="stable")
    same = und[order[1:]] == und[order[:-1]]
    t1, t2 = order[:-1][same] // 3, order[1:][same] // 3
    g = coo_matrix((np.ones(t1.size, dtype=np.int8), (t1, t2)), shape=(m, m))
    k, comp = connected_components(g, directed=False)
    C = P[T] - P[T].reshape(-1, 3).mean(axis=0)
    vol = np.bincount(comp, weights=np.einsum("ij,ij->i", C[:, 0], np.cross(C[:, 1], C[:, 2])) / 6.0, minlength=k)
    area = np.bincount(comp, weights=0.5 * np.linalg.norm(np.cross(C[:, 1] - C[:, 0], C[:, 2] - C[:, 0]), axis=1),
                       minlength=k)
    thin = np.abs(vol) <= eps * area
    return T[~thin[comp]] if np.any(thin) else T


def _rows_on(T: np.ndarray, rows: np.ndarray, at_least: int) -> np.ndarray:
    """The rows of ``T (m, 3)`` with at least ``at_least`` vertices among those of ``T[rows]``, increasing."""
    on = np.zeros(int(T.max()) + 1, dtype=bool)
    on[np.take(T, rows, axis=0).ravel()] = True
    return np.flatnonzero((on[T[:, 0]].astype(np.int8) + on[T[:, 1]] + on[T[:, 2]]) >= at_least)


def _split_caps(T: np.ndarray, caps: np.ndarray, longest: np.ndarray) -> tuple[np.ndarray, np.ndarray | None]:
    """Insert each cap's apex into its longest edge (one cap per edge and per neighbour each round).

    Returns the new triangles — the kept rows of ``T`` in order, then two per split cap — and the
    kept-row mask ``(len(T),)``, or ``T`` and None when no cap could be split.
    """
    n = np.int64(T.max() + 1)
    # The triangle across a cap's edge holds two of the cap's vertices: only such rows are searched.
    near = _rows_on(T, caps, 2)
    Tn = np.take(T, near, axis=0)
    dkey = Tn.ravel() * n + next_corners(Tn)
    order = np.argsort(dkey)
    sk = dkey[order]
    keep = np.ones(T.shape[0], dtype=bool)
    new = []
    busy = np.zeros(T.shape[0], dtype=bool)
    for c, k in zip(caps.tolist(), longest.tolist()):
        if busy[c]:
            continue
        u, v, w = int(T[c, k]), int(T[c, (k + 1) % 3]), int(T[c, (k + 2) % 3])  # edge u -> v, apex w
        pos = np.searchsorted(sk, v * n + u)
        if pos >= sk.size or sk[pos] != v * n + u:
            continue  # an open edge: left for the manifold check to report
        nb = int(near[order[pos] // 3])
        if busy[nb] or nb == c:
            continue
        x = [q for q in T[nb].tolist() if q not in (u, v)]
        if len(x) != 1 or x[0] == w:
            continue
        x = x[0]
        busy[c] = busy[nb] = True
        keep[c] = keep[nb] = False
        new.append((v, w, x))
        new.append((w, u, x))
    if not new:
        return T, None
    return np.concatenate([T[keep], np.asarray(new, dtype=np.int64)]), keep


def _manifold(T: np.ndarray, P: np.ndarray) -> None:
    """Raise unless the result triangles ``T`` over points ``P`` form an oriented 2-manifold.

    Every undirected edge must be used twice, once each way, and the triangles around every
    vertex must form a single fan: corners are joined across the edges at their vertex
    (``scipy.sparse.csgraph``) and a vertex whose corners fall into two components is pinched.

    Raises
    ------
    BooleanError
        (stage ``"sew"``) naming the offending edge or vertex with its coordinates.
    """
    n = np.int64(P.shape[0])
    m = T.shape[0]
    a = T.ravel()
    b = next_corners(T)
    und = np.minimum(a, b) * n + np.maximum(a, b)
    order = np.argsort(und, kind="stable")
    us = und[order]
    start = np.flatnonzero(np.concatenate([[True], us[1:] != us[:-1]]))
    cnt = np.diff(np.append(start, us.size))
    if np.any(cnt != 2):
        k = int(np.flatnonzero(cnt != 2)[0])
        p, q = P[us[start[k]] // n], P[us[start[k]] % n]
        raise BooleanError(
            f"the result is not a manifold: the edge from {p.tolist()} to {q.tolist()} is used by {int(cnt[k])} "
            "triangles (solids touching along an edge); coons solids are manifold (expected 2)",
            stage="sew", diagnostics={"edge": (p.tolist(), q.tolist()), "triangles": int(cnt[k])},
        )
    h0, h1 = order[0::2], order[1::2]
    if np.any(a[h0] == a[h1]):
        k = int(np.flatnonzero(a[h0] == a[h1])[0])
        raise BooleanError(
            f"the selected pieces are inconsistently oriented at the edge from {P[a[h0[k]]].tolist()} to "
            f"{P[b[h0[k]]].tolist()}", stage="sew", diagnostics={"edge": (int(a[h0[k]]), int(b[h0[k]]))},
        )
    # Corner 3t + k sits at T[t, k]; half-edge h = 3t + k starts there and its twin ends there.
    nxt = lambda h: h - h % 3 + (h % 3 + 1) % 3  # noqa: E731
    src = np.concatenate([h0, h1])
    dst = nxt(np.concatenate([h1, h0]))
    g = coo_matrix((np.ones(src.size, dtype=np.int8), (src, dst)), shape=(3 * m, 3 * m))
    _, comp = connected_components(g, directed=False)
    pairs = np.unique(np.stack([a, comp], axis=1), axis=0)
    fans = np.bincount(pairs[:, 0], minlength=P.shape[0])
    if np.any(fans > 1):
        v = int(np.flatnonzero(fans > 1)[0])
        raise BooleanError(
            f"the result is not a manifold: {int(fans[v])} separate fans of faces meet at the vertex {P[v].tolist()} "
            "(solids touching at a vertex); coons solids are manifold (expected 1)",
            stage="sew", diagnostics={"vertex": P[v].tolist(), "fans": int(fans[v])},
        )
