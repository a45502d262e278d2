"""Exact intersection and imprinting of two closed triangle meshes (phases 3–5 of the polyhedral Boolean).

Given two closed, oriented triangle meshes ``A`` and ``B`` with float64 vertices and the
candidate triangle pairs of the broad phase, this module finds every point where the two
surfaces meet, exactly, and splits every triangle of each mesh along the curves where the
other surface crosses or touches it, so that both meshes are subdivided consistently: every
intersection segment is an edge of both subdivided meshes, and the two triangles on each side
of an edge are split at the same points.  It does not classify or select pieces, and it does
not round anything except the 2-D coordinates handed to the triangulator (whose output is then
verified exactly).  See :mod:`coons.booleans.polyhedral` for the pipeline around it.

Notation
--------
``t``, ``u``
    A triangle of A, a triangle of B; a *pair* ``(t, u)`` is a candidate of the broad phase.
simplex ``σ``
    A vertex, an edge or a triangle of one mesh, encoded as ``code = 4 index + dim``
    (``dim`` 0, 1, 2).
key ``(σ_A, σ_B)``
    Every point common to both surfaces lies in the relative interior of exactly one simplex of
    A and one of B; the pair of those simplices names the point *symbolically*.  Points are
    identified by their keys, never by comparing coordinates: two tests that find the same
    point (the crossing of edge ``e`` of A with triangle ``u`` of B, found from both triangles
    of ``e``) produce the same key.  Which relative interior a point lies in is decided by
    exact predicates on the input floats, so keys are canonical.
global id
    Vertex ``v`` of A is ``v``, vertex ``w`` of B is ``nA + w`` (or the A vertex it coincides
    with), and new points (keys with no vertex in them) follow from ``nA + nB``.

Exactness
---------
All decisions use exact predicates on the input floats (:func:`coons.kernel.predicates.orient3d`,
``orient2d``, ``classify_segments``: Shewchuk's float filters with an exact fallback).  New
points are edge–plane crossings ``p + dp / (dp − dq) (q − p)`` (``dp``, ``dq`` the exact
orientation determinants of the edge ends against the plane) or crossings of two coplanar
edges, stored as homogeneous integer coordinates ``(X, Y, Z, W)`` over the common power-of-two
scale of all input coordinates (every float is ``m 2^e``), so they are exact rationals.
Splitting a triangle projects its points onto the coordinate plane that drops the dominant
axis of its normal (exact: a coordinate is dropped).  A triangle crossed by one chain of
segments (two points on two of its edges, a few interior points between them: nearly every
split triangle of two fine meshes) is split in array time by a fixed template — a fan of the
one-corner side, a triangle and two fans on the two-corner side (:func:`_chain_pieces`) — and
kept when every piece is counter-clockwise for the exact points.  The others are grouped by the
pattern of their split problem (points per edge, interior points, chords between local indices:
:func:`_patterns`); a group's first triangle is split as below and its triangulation, in local
indices, is kept for each other member whose pieces are all counter-clockwise for that member's
exact points (the prism sides of a perforated plate: thousands of triangles, a few patterns).
The remaining triangles with few points (at most ``_SMALL_SPLIT``) are split by incremental
insertion and edge flips whose every orientation test is exact (a float filter on the rounded
coordinates with a rounding-aware error bound, integer determinants when it cannot decide);
triangles with many
points go to the constrained Delaunay triangulator of :mod:`coons.topology._cdt` on the nearest
floats, whose output is verified exactly and, should rounding have made it invalid (features
within an ulp of each other), replaced by the exact incremental split.  Every split is
verified: each piece counter-clockwise for the *exact* points, piece counts, the boundary of
each triangle's pieces equal to its subdivided boundary, every segment an edge, and the pieces
of the whole mesh closed around the splits.  By the degree argument (a triangulated disc whose
triangles are all positively oriented and whose boundary maps onto a simple polygon covers its
inside exactly once) this proves the splits exact.

Why the constraints inside one triangle never cross
---------------------------------------------------
The segments imprinted on ``t`` are pieces of ``t ∩ B``.  B is an embedded closed surface, so
two of its triangles meet only along a shared edge or vertex and the pieces meet only at their
end points: the constraint graph in ``t`` is a planar straight-line graph whose vertices are the
keyed points.  This is why a constrained triangulation suffices and no planar arrangement has to
be computed per triangle (the 2-D arrangement of :mod:`coons.booleans.planar` computes crossings
of float segments; here the segment ends are exact rationals and their crossings are known).

Snapping near-coincidences (:func:`snap`, before everything above)
-------------------------------------------------------------------
Exact predicates on rounded inputs see faces that coincide only up to rounding (two boxes
sharing a face, turned by the same rotation) as hinged at angles of ``1e-16`` or crossing each
other, and the exact result then has cracks of the size of the rounding error; one touching the
boundary makes the result non-manifold (an edge of four triangles), which no clean-up of the
rounded result repairs.  The tolerance model says such faces are one face, so :func:`snap`
first gives both meshes one common triangulation on every cluster of candidate pairs that are
coplanar within ``tol.linear``: B's vertex takes A's coordinates where they are within the
tolerance, an edge of A and one of B passing within the tolerance meet at one new float point,
every edge of the cluster runs through the points of the other mesh within the tolerance of it
(snap rounding), and one constrained Delaunay triangulation of all those points and edge chains,
in the coordinate plane that drops the dominant axis of the cluster's normal, gives each
triangle of either mesh the triangles of the region its chains enclose.  Where the faces
overlap, both meshes then have the same triangles on bit-identical points, and the exact
predicates find them coplanar; a neighbouring triangle whose edge gained points is triangulated
again inside its own boundary, so each mesh stays closed.  Nothing moves by more than the
tolerance (checked), and every decision *after* the snap is exact on the snapped floats.  Local
rules (a point inserted into each mesh with spokes to the opposite corners, round after round)
can cascade into ever closer crossings where the diagonals of both tessellations meet; one
triangulation per cluster does not, and a second pass finds nothing.  Should a cluster not be
near one plane, a point lie within the tolerance of a vertex it was not merged with, or a new
triangle be lower than the tolerance, the raw operands are used.  This is the float-input
counterpart of manifold's symbolic perturbation: manifold perturbs coplanar faces consistently
and removes the resulting slivers afterwards; here coplanarity within the tolerance is made
exact first.  Inputs without near-coplanar candidate pairs cost one float plane-distance test
per pair.

Limitations
-----------
* :func:`snap` gives up (the raw operands, the reason logged) where features lie between one
  and a few tolerances apart — a point within the tolerance of an edge's end, or chains that do
  not enclose one region each (snap rounding with discs, unlike Hobby's grid, does not
  guarantee that), as for a sphere mesh and its copy turned by ``2e-7`` — or a cluster is not
  near one plane; the exact arrangement of the raw inputs may then leave features the sew
  stage refuses.  It never gave up in 28 775 Booleans of rotated grid-box pairs
  (``benchmarks/hunt_rotated_grid_boxes.py``, seeds 1–5 and 11–15, no failure), where the
  former local rules failed 30 of 14 365.
* A cluster is triangulated as a whole (Qhull, then constraint recovery by flips in Python):
  a large coplanar overlap costs one constrained Delaunay triangulation of all its triangles
  (the top of a plate with 20 × 20 holes against a box on it, 8000 triangles: about 0.5 s of
  snap, of 3.7 s for the Boolean).
* Self-intersecting inputs are not detected (their constraints may cross, which raises
  ``BooleanError`` at stage ``"imprint"``).
* Triangles crossed by one chain of segments (two edge points, up to ``_CHAIN_MAX`` interior
  points: nearly all of them for two fine meshes) are split in array time by fixed templates
  whose pieces are verified exactly; the others loop over the triangles in Python (Python
  integers for the rare exact decisions).
"""

from __future__ import annotations

import logging
from dataclasses import dataclass
from fractions import Fraction
from functools import lru_cache

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

from coons.errors import BooleanError, ConvergenceError, InvalidInputError
from coons.kernel._common import next_corners, row_pointers, sorted_contains
from coons.kernel.predicates import SegmentRelation, classify_segments, orient2d, orient3d
from coons.topology._cdt import triangulate

__all__ = ["Operand", "operand", "snap", "Exact", "Intersections", "intersect", "Imprint", "imprint"]

_log = logging.getLogger("coons")
_EPS = 2.0**-53
#: Points per chunk of the vectorised predicate calls (bounds the temporaries).
_CHUNK = 1 << 18


# ====================================================================== operands
@dataclass(frozen=True)
class Operand:
    """One operand as a closed triangle mesh with its edge tables.

    Attributes
    ----------
    P : (n, 3) float64          vertices
    T : (m, 3) int64            triangles, counter-clockwise seen from outside
    face : (m,) int64           B-rep face of each triangle (for diagnostics)
    edges : (E, 2) int64        undirected edges, smaller vertex first
    tri_edge : (m, 3) int64     edge ``k`` of triangle ``t`` joins ``T[t, k]`` and ``T[t, (k + 1) % 3]``
    edge_tris : (E, 2) int64    the two triangles of each edge
    lo, hi : (m, 3) float64     closed bounding box of each triangle
    """

    P: np.ndarray
    T: np.ndarray
    face: np.ndarray
    edges: np.ndarray
    tri_edge: np.ndarray
    edge_tris: np.ndarray
    lo: np.ndarray | None = None
    hi: np.ndarray | None = None

    @property
    def n(self) -> int:
        return int(self.P.shape[0])

    @property
    def m(self) -> int:
        return int(self.T.shape[0])

    @property
    def n_edges(self) -> int:
        return int(self.edges.shape[0])


def operand(P: np.ndarray, T: np.ndarray, face: np.ndarray, name: str, tables=None) -> Operand:
    """Edge tables of a closed triangle mesh.

    ``tables``, optional: ``(edges, tri_edge, edge_tris)`` known from a B-rep (each triangle a
    face of three edges), which spares the sort that derives them.

    Raises
    ------
    BooleanError
        (stage ``"input"``) an edge not used by exactly two triangles.
    """
    from coons.booleans._broad_phase import triangle_boxes

    P = np.ascontiguousarray(P, dtype=np.float64)
    T = np.ascontiguousarray(T, dtype=np.int64)
    lo, hi = triangle_boxes(P, T)
    if tables is not None:
        edges, tri_edge, edge_tris = tables
        return Operand(P, T, np.asarray(face, dtype=np.int64), edges, tri_edge, edge_tris, lo, hi)
    n, m = P.shape[0], T.shape[0]
    a = T.ravel()
    b = next_corners(T)
    key = np.minimum(a, b) * np.int64(n) + np.maximum(a, b)
    uniq, inv, count = np.unique(key, return_inverse=True, return_counts=True)
    if np.any(count != 2):
        e = int(np.flatnonzero(count != 2)[0])
        raise BooleanError(
            f"operand {name}: the tessellation edge between vertices {int(uniq[e] // n)} and {int(uniq[e] % n)} "
            f"is used by {int(count[e])} triangles; expected a closed manifold mesh (2)",
            stage="input",
            diagnostics={"operand": name, "edge": (int(uniq[e] // n), int(uniq[e] % n))},
        )
    edges = np.stack([uniq // n, uniq % n], axis=1)
    inv = inv.reshape(-1)
    order = np.argsort(inv, kind="stable")
    edge_tris = (order // 3).reshape(-1, 2)
    return Operand(P, T, np.asarray(face, dtype=np.int64), edges, inv.reshape(m, 3), edge_tris, lo, hi)


# ====================================================================== exact numbers
class Exact:
    """Float coordinates as Python integers over one power-of-two scale shared by both operands.

    Every finite float is ``M 2^E`` with an integer ``M``; with ``s`` the smallest ``E`` over all
    input coordinates, ``x = X 2^s`` for the integer ``X = M 2^(E - s)``.  Homogeneous points
    ``(X, Y, Z, W)`` then stand for ``(X / W, Y / W, Z / W) 2^s``.
    """

    def __init__(self, *coordinate_arrays: np.ndarray) -> None:
        values = np.concatenate([np.asarray(c, dtype=np.float64).ravel() for c in coordinate_arrays])
        mant, expo = np.frexp(values)
        nz = mant != 0
        self.s = int((expo[nz] - 53).min()) if np.any(nz) else 0
        self.scale = 2.0**self.s

    def ints(self, P: np.ndarray) -> np.ndarray:
        """``(..., 3)`` floats as an object array of Python ints on the common scale."""
        P = np.asarray(P, dtype=np.float64)
        mant, expo = np.frexp(P)
        M = (mant * 2.0**53).astype(np.int64)
        shift = np.where(M == 0, 0, expo.astype(np.int64) - 53 - self.s)
        return M.astype(object) << shift.astype(object)

    def homogeneous(self, P: np.ndarray) -> np.ndarray:
        """``(k, 3)`` floats as ``(k, 4)`` homogeneous integer points (``W = 1``)."""
        X = self.ints(np.asarray(P, dtype=np.float64).reshape(-1, 3))
        return np.concatenate([X, np.ones((X.shape[0], 1), dtype=object)], axis=1)

    def rounded(self, H: np.ndarray) -> np.ndarray:
        """Nearest floats ``(k, 3)`` of homogeneous points ``(k, 4)`` (correctly rounded division)."""
        if H.shape[0] == 0:
            return np.zeros((0, 3))
        # Put the scale into the integers before the one division: int / int is correctly rounded in
        # Python (no intermediate float that could overflow or lose bits).
        W = H[:, 3] << max(-self.s, 0)
        out = np.empty((H.shape[0], 3))
        for k in range(3):
            out[:, k] = ((H[:, k] << max(self.s, 0)) / W).astype(np.float64)
        return out


def _det3(ax, ay, az, bx, by, bz, cx, cy, cz):
    """Determinant of the rows ``a, b, c`` (works on object arrays of ints)."""
    return ax * (by * cz - bz * cy) - ay * (bx * cz - bz * cx) + az * (bx * cy - by * cx)


def _sign(x: np.ndarray) -> np.ndarray:
    return ((x > 0).astype(np.int8) - (x < 0).astype(np.int8)).astype(np.int8)


# ====================================================================== predicates on simplices
def _projection(P: np.ndarray, T: np.ndarray, tris: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Dropped axis and orientation sign of each triangle's projection.

    The dropped axis is the largest component of the float normal; the kept axes are the two
    following it cyclically, so the projected orientation has the sign of that normal
    component, computed exactly with ``orient2d``.

    Returns
    -------
    axis : (k,) int64
    sign : (k,) int8, +1 or -1

    Raises
    ------
    BooleanError
        (stage ``"intersect"``) a triangle whose projection is flat (a degenerate triangle).
    """
    C = P[T[tris]]
    n = np.cross(C[:, 1] - C[:, 0], C[:, 2] - C[:, 0])
    axis = np.argmax(np.abs(n), axis=1).astype(np.int64)
    Q = _project(C, axis)
    sign = orient2d(Q[:, 0], Q[:, 1], Q[:, 2]) if tris.size else np.zeros(0, np.int8)
    if np.any(sign == 0):
        k = int(np.flatnonzero(sign == 0)[0])
        raise BooleanError(
            f"triangle {int(tris[k])} is degenerate (its corners {C[k].tolist()} are collinear)",
            stage="intersect",
            diagnostics={"triangle": int(tris[k])},
        )
    return axis, sign


def _project(X: np.ndarray, axis: np.ndarray) -> np.ndarray:
    """Points ``X (k, p, 3)`` projected to ``(k, p, 2)`` by dropping ``axis (k,)``, keeping the two
    following axes in cyclic order (so projected orientations have the sign of the dropped normal
    component)."""
    r = np.arange(X.shape[0])[:, None]
    c = np.arange(X.shape[1])[None, :]
    i = ((axis + 1) % 3)[:, None]
    j = ((axis + 2) % 3)[:, None]
    return np.stack([X[r, c, i], X[r, c, j]], axis=-1)


def _locate(o: np.ndarray) -> np.ndarray:
    """Location code from three signs ``o (k, 3)`` measured against edges ``j = (c_j, c_{j+1})``
    so that the inside is positive on every edge (or negative on every edge, for lines).

    Returns ``(k,)`` int8: -1 outside, 0–2 at corner ``c_i``, 3–5 on edge ``j = code − 3``,
    6 inside, 7 every sign zero (a degenerate configuration).
    """
    pos = np.all(o >= 0, axis=1)
    neg = np.all(o <= 0, axis=1)
    zero = o == 0
    nz = zero.sum(axis=1)
    code = np.full(o.shape[0], -1, dtype=np.int8)
    inside = (pos | neg)
    code[inside & (nz == 0)] = 6
    one = inside & (nz == 1)
    code[one] = 3 + np.argmax(zero[one], axis=1)
    two = inside & (nz == 2)
    # zeros on edges j and j+1 meet at corner j+1: the corner is the one after the nonzero edge's end,
    # i.e. corner (nonzero + 2) % 3.
    code[two] = (np.argmin(zero[two], axis=1) + 2) % 3
    code[nz == 3] = 7
    return code


def _in_triangles(Pv: np.ndarray, C: np.ndarray, axis: np.ndarray, sgn: np.ndarray) -> np.ndarray:
    """Location of coplanar points in closed triangles (see :func:`_locate`), in the triangles' projection.

    Pv : (k, 3) points on the triangles' planes; C : (k, 3, 3) corners.
    """
    Q = _project(np.concatenate([C, Pv[:, None, :]], axis=1), axis)
    c, p = Q[:, :3], Q[:, 3]
    o = np.stack([orient2d(c[:, j], c[:, (j + 1) % 3], p) for j in range(3)], axis=1) * sgn[:, None]
    return _locate(o)


def _line_through_triangles(p: np.ndarray, q: np.ndarray, C: np.ndarray) -> np.ndarray:
    """Location where lines ``p q`` (crossing the triangles' planes) meet triangles ``C``: signs of
    ``orient3d(p, q, c_j, c_{j+1})`` (Plücker side products), see :func:`_locate`."""
    o = np.stack([orient3d(p, q, C[:, j], C[:, (j + 1) % 3]) for j in range(3)], axis=1)
    return _locate(o)


# ====================================================================== intersections
@dataclass
class Intersections:
    """Exact intersection of the two surfaces.

    Attributes
    ----------
    n_points : int                   keyed points
    code_a, code_b : (k,) int64      the simplex codes of each point's key
    gid : (k,) int64                 global id of each point
    new_h : (q, 4) object            homogeneous integer coordinates of the new points (gid ``nA + nB + i``)
    new_float : (q, 3) float64       their nearest floats
    alias_b : (nB,) int64            global id of each B vertex (itself, or the A vertex it coincides with)
    seg_a : (s, 3) int64             segments imprinted on A: triangle of A, global ids of the two ends
    seg_b : (s', 3) int64            segments imprinted on B: triangle of B, ends
    coplanar : (c, 3) int64          coplanar pairs: triangle of A, triangle of B, +1 same / -1 opposite normals
    """

    code_a: np.ndarray
    code_b: np.ndarray
    gid: np.ndarray
    new_h: np.ndarray
    new_float: np.ndarray
    alias_b: np.ndarray
    seg_a: np.ndarray
    seg_b: np.ndarray
    coplanar: np.ndarray

    @property
    def n_points(self) -> int:
        return int(self.code_a.size)


class _Records:
    """Candidate points found by the tests: keys and constructions, deduplicated at the end."""

    def __init__(self) -> None:
        self.parts: list[tuple[np.ndarray, ...]] = []
        self.count = 0

    def add(self, code_a, code_b, kind, i0, i1, i2) -> np.ndarray:
        """Append records; return their record ids."""
        k = np.asarray(code_a).size
        ids = np.arange(self.count, self.count + k, dtype=np.int64)
        self.count += k
        self.parts.append(tuple(np.asarray(x, dtype=np.int64).reshape(-1) * np.ones(k, dtype=np.int64)
                                for x in (code_a, code_b, kind, i0, i1, i2)))
        return ids

    def columns(self) -> tuple[np.ndarray, ...]:
        if not self.parts:
            return tuple(np.zeros(0, dtype=np.int64) for _ in range(6))
        return tuple(np.concatenate([p[c] for p in self.parts]) for c in range(6))


# Kinds of construction of a point.
_VERTEX_A, _VERTEX_B, _EDGE_A_PLANE_B, _EDGE_B_PLANE_A, _EDGE_EDGE = range(5)


def _code(index: np.ndarray, dim) -> np.ndarray:
    return 4 * np.asarray(index, dtype=np.int64) + dim


def _loc_code(loc: np.ndarray, X: Operand, tris: np.ndarray) -> np.ndarray:
    """Simplex codes of locations (from :func:`_locate`) in triangles ``tris`` of ``X``."""
    out = np.full(loc.size, -1, dtype=np.int64)
    corner = loc <= 2
    out[corner] = _code(X.T[tris[corner], loc[corner].astype(np.int64)], 0)
    edge = (loc >= 3) & (loc <= 5)
    out[edge] = _code(X.tri_edge[tris[edge], loc[edge].astype(np.int64) - 3], 1)
    inside = loc == 6
    out[inside] = _code(tris[inside], 2)
    return out


def intersect(A: Operand, B: Operand, I: np.ndarray, J: np.ndarray, ex: Exact) -> Intersections:
    """Exact intersection points and segments of the candidate pairs ``(I[p], J[p])`` (phase 3–4).

    Each pair is classified by the six exact orientations of one triangle's corners against
    the other's plane (separated, crossing/touching, coplanar).  Surviving pairs run the
    point tests — a corner on the other triangle's plane against that triangle, an edge crossing
    the other plane against the triangle (Plücker signs), an edge lying in the other plane
    against that triangle's edges (exact segment relations) — each once per distinct
    (simplex, triangle) combination.  The points found by a pair's tests are its intersection:
    a non-coplanar pair meets in at most two distinct keyed points, joined by a segment
    imprinted on both triangles; a coplanar pair imprints the part of each edge of one triangle
    lying in the other.

    Raises
    ------
    BooleanError
        (stage ``"intersect"``) a non-coplanar pair meeting in more than two keyed points, or a
        degenerate triangle; never expected for valid inputs.
    """
    nA, nB = A.n, B.n
    # np.take row gathers (several times faster than A.T[I], A.P[tA] with numpy 2.4)
    tA, tB = np.take(A.T, I, axis=0), np.take(B.T, J, axis=0)
    CA = np.take(A.P, tA.ravel(), axis=0).reshape(-1, 3, 3)
    CB = np.take(B.P, tB.ravel(), axis=0).reshape(-1, 3, 3)
    k = I.size
    sA = np.zeros((k, 3), dtype=np.int8)
    sB = np.zeros((k, 3), dtype=np.int8)
    for s in range(0, k, _CHUNK):
        sl = slice(s, s + _CHUNK)
        sA[sl] = orient3d(CB[sl, None, 0], CB[sl, None, 1], CB[sl, None, 2], CA[sl])
        sB[sl] = orient3d(CA[sl, None, 0], CA[sl, None, 1], CA[sl, None, 2], CB[sl])
    apart = (np.all(sA > 0, 1) | np.all(sA < 0, 1) | np.all(sB > 0, 1) | np.all(sB < 0, 1))
    live = np.flatnonzero(~apart)
    I, J = I[live], J[live]
    tA, tB, CA, CB, sA, sB = (np.take(x, live, axis=0) for x in (tA, tB, CA, CB, sA, sB))
    k = I.size
    copl = np.all(sA == 0, axis=1)
    rec = _Records()
    slots = np.full((k, 21), -1, dtype=np.int64)  # record id per test slot (see below)

    # Projections of the triangles that take part in 2-D tests.
    need_b = np.unique(J[np.any(sA == 0, axis=1)])
    need_a = np.unique(I[np.any(sB == 0, axis=1)])
    axis_b = np.zeros(B.m, dtype=np.int64)
    sgn_b = np.zeros(B.m, dtype=np.int8)
    axis_a = np.zeros(A.m, dtype=np.int64)
    sgn_a = np.zeros(A.m, dtype=np.int8)
    if need_b.size:
        axis_b[need_b], sgn_b[need_b] = _projection(B.P, B.T, need_b)
    if need_a.size:
        axis_a[need_a], sgn_a[need_a] = _projection(A.P, A.T, need_a)

    # --- slots 0-2 and 3-5: corners on the other plane, located in the other triangle.
    for X, Y, s, tX, tris_x, tris_y, axis_y, sgn_y, base, side in (
        (A, B, sA, tA, I, J, axis_b, sgn_b, 0, 0),
        (B, A, sB, tB, J, I, axis_a, sgn_a, 3, 1),
    ):
        pp, kk = np.nonzero(s == 0)
        if pp.size == 0:
            continue
        v = tX[pp, kk]
        u = tris_y[pp]
        key = v * np.int64(Y.m) + u
        uk, first, inv = np.unique(key, return_index=True, return_inverse=True)
        vu, uu = v[first], u[first]
        loc = _in_triangles(X.P[vu], Y.P[Y.T[uu]], axis_y[uu], sgn_y[uu])
        hit = loc >= 0
        if np.any(loc == 7):
            raise BooleanError("a degenerate triangle in a point location test", stage="intersect",
                               diagnostics={"operand": "AB"[1 - side], "triangle": int(uu[np.argmax(loc == 7)])})
        rid = np.full(uk.size, -1, dtype=np.int64)
        cy = _loc_code(loc[hit], Y, uu[hit])
        cx = _code(vu[hit], 0)
        if side == 0:
            rid[hit] = rec.add(cx, cy, _VERTEX_A, vu[hit], 0, 0)
        else:
            rid[hit] = rec.add(cy, cx, _VERTEX_B, vu[hit], 0, 0)
        slots[pp, base + kk] = rid[inv.reshape(-1)]

    # --- slots 6-8 and 9-11: edges crossing the other plane (ends strictly on both sides).
    for X, Y, s, tris_x, tris_y, base, side in ((A, B, sA, I, J, 6, 0), (B, A, sB, J, I, 9, 1)):
        cross = s * s[:, [1, 2, 0]] < 0
        pp, kk = np.nonzero(cross)
        if pp.size == 0:
            continue
        e = X.tri_edge[tris_x[pp], kk]
        u = tris_y[pp]
        key = e * np.int64(Y.m) + u
        uk, first, inv = np.unique(key, return_index=True, return_inverse=True)
        eu, uu = e[first], u[first]
        p, q = X.P[X.edges[eu, 0]], X.P[X.edges[eu, 1]]
        loc = _line_through_triangles(p, q, Y.P[Y.T[uu]])
        if np.any(loc == 7):
            raise BooleanError("an edge crossing a plane lies in it (inconsistent predicates)", stage="intersect",
                               diagnostics={"operand": "AB"[side], "edge": int(eu[np.argmax(loc == 7)])})
        hit = loc >= 0
        rid = np.full(uk.size, -1, dtype=np.int64)
        cy = _loc_code(loc[hit], Y, uu[hit])
        cx = _code(eu[hit], 1)
        if side == 0:
            rid[hit] = rec.add(cx, cy, _EDGE_A_PLANE_B, eu[hit], uu[hit], 0)
        else:
            rid[hit] = rec.add(cy, cx, _EDGE_B_PLANE_A, eu[hit], uu[hit], 0)
        slots[pp, base + kk] = rid[inv.reshape(-1)]

    # --- slots 12-20: an edge of t lying in u's plane against the edges of u (proper crossings),
    # or an edge of u lying in t's plane against the edges of t when t's edge does not lie in u's plane.
    for X, Y, s, s_other, tris_x, tris_y, axis_y, side in (
        (A, B, sA, sB, I, J, axis_b, 0),
        (B, A, sB, sA, J, I, axis_a, 1),
    ):
        inplane = (s == 0) & (s[:, [1, 2, 0]] == 0)
        pp, kk = np.nonzero(inplane)
        if pp.size == 0:
            continue
        e = X.tri_edge[tris_x[pp], kk]
        u = tris_y[pp]
        key = e * np.int64(Y.m) + u
        uk, first, inv = np.unique(key, return_index=True, return_inverse=True)
        eu, uu = e[first], u[first]
        ends = np.stack([X.P[X.edges[eu, 0]], X.P[X.edges[eu, 1]]], axis=1)
        C = Y.P[Y.T[uu]]
        Q = _project(np.concatenate([ends, C], axis=1), axis_y[uu])
        inv = inv.reshape(-1)
        for j in range(3):
            rel = classify_segments(Q[:, 0], Q[:, 1], Q[:, 2 + j], Q[:, 2 + (j + 1) % 3])
            hit = rel == SegmentRelation.CROSSING
            rid = np.full(uk.size, -1, dtype=np.int64)
            f = Y.tri_edge[uu[hit], j]
            if side == 0:
                rid[hit] = rec.add(_code(eu[hit], 1), _code(f, 1), _EDGE_EDGE, eu[hit], f, axis_y[uu[hit]])
                slots[pp, 12 + 3 * kk + j] = rid[inv]
            else:
                rid[hit] = rec.add(_code(f, 1), _code(eu[hit], 1), _EDGE_EDGE, f, eu[hit], axis_y[uu[hit]])
                # slot of (edge j of t, edge kk of u); only where t's edge j is not itself in u's plane
                # (then the A-side loop above found the same crossing).
                other_in = (s_other[pp, j] == 0) & (s_other[pp, (j + 1) % 3] == 0)
                ok = ~other_in
                slots[pp[ok], 12 + 3 * j + kk[ok]] = rid[inv][ok]

    # --- deduplicate the records into keyed points.
    code_a, code_b, kind, i0, i1, i2 = rec.columns()
    NB = np.int64(4 * max(B.n, B.n_edges, B.m) + 4)
    key = code_a * NB + code_b
    uk, first, rec_point = np.unique(key, return_index=True, return_inverse=True)
    rec_point = rec_point.reshape(-1)
    code_a, code_b, kind, i0, i1, i2 = (x[first] for x in (code_a, code_b, kind, i0, i1, i2))
    npts = uk.size
    dim_a, dim_b = code_a & 3, code_b & 3
    gid = np.empty(npts, dtype=np.int64)
    va = dim_a == 0
    gid[va] = code_a[va] >> 2
    vb = (~va) & (dim_b == 0)
    gid[vb] = nA + (code_b[vb] >> 2)
    new = ~(va | vb)
    gid[new] = nA + nB + np.arange(int(new.sum()))
    alias_b = nA + np.arange(nB, dtype=np.int64)
    both = va & (dim_b == 0)
    alias_b[code_b[both] >> 2] = code_a[both] >> 2
    new_idx = np.flatnonzero(new)
    new_h = _construct(A, B, ex, kind[new_idx], i0[new_idx], i1[new_idx], i2[new_idx])
    new_float = ex.rounded(new_h)

    # --- per pair: the distinct points of its tests.
    pslot = np.where(slots >= 0, rec_point[np.maximum(slots, 0)], -1) if rec_point.size else np.full_like(slots, -1)
    seg_a, seg_b = [], []
    nc = ~copl
    if np.any(nc):
        ends, cnt = _two_distinct(pslot[nc])
        if np.any(cnt > 2):
            r = int(np.flatnonzero(cnt > 2)[0])
            p = int(np.flatnonzero(nc)[r])
            raise BooleanError(
                f"triangle {int(I[p])} of A (face {int(A.face[I[p]])}) and triangle {int(J[p])} of B (face "
                f"{int(B.face[J[p]])}) meet in {int(cnt[r])} distinct points; expected at most 2",
                stage="intersect",
                diagnostics={"triangle_a": int(I[p]), "triangle_b": int(J[p]), "points": int(cnt[r])},
            )
        two = cnt == 2
        pa, pb = gid[ends[two, 0]], gid[ends[two, 1]]
        seg_a.append(np.stack([I[nc][two], pa, pb], axis=1))
        seg_b.append(np.stack([J[nc][two], pa, pb], axis=1))
    coplanar = np.zeros((0, 3), dtype=np.int64)
    if np.any(copl):
        cp = np.flatnonzero(copl)
        pc = pslot[cp]
        if code_a.size:
            ca = np.where(pc >= 0, code_a[np.maximum(pc, 0)], -1)
            cb = np.where(pc >= 0, code_b[np.maximum(pc, 0)], -1)
        else:  # coplanar pairs but no common point at all (coplanar faces side by side, apart)
            ca = cb = np.full_like(pc, -1)
        for X, tris, own_codes, target, seg in ((B, J[cp], cb, I[cp], seg_a), (A, I[cp], ca, J[cp], seg_b)):
            # Edge j of the X triangle, clipped to the other triangle: points whose X simplex lies on it.
            for j in range(3):
                e = _code(X.tri_edge[tris, j], 1)[:, None]
                v0 = _code(X.T[tris, j], 0)[:, None]
                v1 = _code(X.T[tris, (j + 1) % 3], 0)[:, None]
                on = (own_codes == e) | (own_codes == v0) | (own_codes == v1)
                ends, cnt = _two_distinct(np.where(on, pc, -1))
                if np.any(cnt > 2):
                    raise BooleanError("a clipped coplanar edge has more than two ends", stage="intersect",
                                       diagnostics={"pair": int(cp[int(np.argmax(cnt > 2))])})
                two = cnt == 2
                seg.append(np.stack([target[two], gid[ends[two, 0]], gid[ends[two, 1]]], axis=1))
        # Same or opposite orientation: t's corners projected along u's axis against u's sign.
        ax = axis_b[J[cp]]
        Q = _project(A.P[A.T[I[cp]]], ax)
        st = orient2d(Q[:, 0], Q[:, 1], Q[:, 2])
        coplanar = np.stack([I[cp], J[cp], (st * sgn_b[J[cp]]).astype(np.int64)], axis=1)
    cat = lambda L: np.concatenate(L) if L else np.zeros((0, 3), dtype=np.int64)  # noqa: E731
    # Canonical ids (B vertices coinciding with A vertices) in the segments.
    seg_a, seg_b = cat(seg_a), cat(seg_b)
    for S in (seg_a, seg_b):
        for c in (1, 2):
            b_ids = (S[:, c] >= nA) & (S[:, c] < nA + nB)
            S[b_ids, c] = alias_b[S[b_ids, c] - nA]
    gid_c = gid.copy()
    bv = (gid_c >= nA) & (gid_c < nA + nB)
    gid_c[bv] = alias_b[gid_c[bv] - nA]
    return Intersections(code_a, code_b, gid_c, new_h, new_float, alias_b, seg_a, seg_b, coplanar)


def _two_distinct(S: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Rows of point ids (-1: none): the smallest and largest id and the number of distinct ids."""
    if S.shape[0] == 0:
        return np.zeros((0, 2), dtype=np.int64), np.zeros(0, dtype=np.int64)
    Ss = np.sort(S, axis=1)
    valid = Ss >= 0
    new = valid.copy()
    new[:, 1:] &= Ss[:, 1:] != Ss[:, :-1]
    cnt = new.sum(axis=1)
    lo = np.where(valid, Ss, np.iinfo(np.int64).max).min(axis=1)
    hi = Ss[:, -1]
    return np.stack([lo, hi], axis=1), cnt


def _construct(A: Operand, B: Operand, ex: Exact, kind, i0, i1, i2) -> np.ndarray:
    """Homogeneous integer coordinates ``(k, 4)`` of new points from their constructions."""
    out = np.empty((kind.size, 4), dtype=object)
    for kd, X, Y in ((_EDGE_A_PLANE_B, A, B), (_EDGE_B_PLANE_A, B, A)):
        sel = np.flatnonzero(kind == kd)
        if sel.size == 0:
            continue
        e, u = i0[sel], i1[sel]
        p = ex.ints(X.P[X.edges[e, 0]])
        q = ex.ints(X.P[X.edges[e, 1]])
        C = ex.ints(Y.P[Y.T[u]])
        c0 = C[:, 0]
        d1, d2 = C[:, 1] - c0, C[:, 2] - c0
        dp = _det3(*d1.T, *d2.T, *(p - c0).T)
        dq = _det3(*d1.T, *d2.T, *(q - c0).T)
        W = dp - dq
        H = p * W[:, None] + (q - p) * dp[:, None]
        neg = W < 0
        H[neg] = -H[neg]
        W[neg] = -W[neg]
        out[sel, :3] = H
        out[sel, 3] = W
    sel = np.flatnonzero(kind == _EDGE_EDGE)
    if sel.size:
        e, f, ax = i0[sel], i1[sel], i2[sel]
        p = ex.ints(A.P[A.edges[e, 0]])
        q = ex.ints(A.P[A.edges[e, 1]])
        a = ex.ints(B.P[B.edges[f, 0]])
        b = ex.ints(B.P[B.edges[f, 1]])
        r = np.arange(sel.size)
        i, j = (ax + 1) % 3, (ax + 2) % 3
        d, g, ap = q - p, b - a, a - p
        den = d[r, i] * g[r, j] - d[r, j] * g[r, i]
        num = ap[r, i] * g[r, j] - ap[r, j] * g[r, i]
        H = p * den[:, None] + d * num[:, None]
        neg = den < 0
        H[neg] = -H[neg]
        den[neg] = -den[neg]
        out[sel, :3] = H
        out[sel, 3] = den
    if np.any(out[:, 3] == None):  # noqa: E711  (object array: unset rows)
        raise BooleanError("internal: a new point without construction", stage="intersect")
    return out


# ====================================================================== imprint
@dataclass
class Imprint:
    """One operand split along the other surface.

    Attributes
    ----------
    tris : (k, 3) int64        pieces as global point ids, counter-clockwise seen from outside
    source : (k,) int64        triangle of the operand each piece comes from
    on_edges : (s, 2) int64    undirected piece edges (smaller id first) lying on the other surface
    n_whole : int              the first ``n_whole`` pieces are whole (unsplit) triangles, in order
    vid : (n,) int64, optional global id of each vertex of the operand
    """

    tris: np.ndarray
    source: np.ndarray
    on_edges: np.ndarray
    n_whole: int = 0
    vid: np.ndarray | None = None


class PointTable:
    """Float and exact coordinates of every global id (A vertices, B vertices, new points)."""

    def __init__(self, A: Operand, B: Operand, X: Intersections, ex: Exact) -> None:
        self.nA, self.nB = A.n, B.n
        self.float = np.concatenate([A.P, B.P, X.new_float]) if X.new_float.size else np.concatenate([A.P, B.P])
        self.new_h = X.new_h
        self.ex = ex

    @property
    def is_float(self) -> np.ndarray:
        """``(N,)`` bool: the point is exactly its float coordinates (input vertices, and new points
        whose rational coordinates happen to be floats)."""
        cached = getattr(self, "_is_float", None)
        if cached is not None:
            return cached
        out = np.ones(self.float.shape[0], dtype=bool)
        H = self.new_h
        if H.shape[0]:
            F = self.float[self.nA + self.nB :]
            mant, expo = np.frexp(F)
            M = (mant * 2.0**53).astype(np.int64).astype(object)
            E = expo.astype(np.int64) - 53 - self.ex.s  # F = M 2^(E + s); the point is X / W 2^s
            up = np.maximum(E, 0).astype(object)
            down = np.maximum(-E, 0).astype(object)
            W = H[:, 3:4]
            same = (H[:, :3] << down) == (M * W) << up
            out[self.nA + self.nB :] = np.all(same, axis=1)
        self._is_float = out
        return out

    def exact(self, ids: np.ndarray) -> np.ndarray:
        """Homogeneous integer coordinates ``(k, 4)`` of global ids."""
        ids = np.asarray(ids, dtype=np.int64).reshape(-1)
        out = np.empty((ids.size, 4), dtype=object)
        old = ids < self.nA + self.nB
        if np.any(old):
            out[old] = self.ex.homogeneous(self.float[ids[old]])
        if np.any(~old):
            out[~old] = self.new_h[ids[~old] - self.nA - self.nB]
        return out


def _orient_projected_exact(H: np.ndarray, axis: int) -> np.ndarray:
    """Exact orientation signs of triangles of homogeneous points ``H (k, 3, 4)`` projected along ``axis``."""
    i, j = (axis + 1) % 3, (axis + 2) % 3
    x, y, w = H[:, :, i], H[:, :, j], H[:, :, 3]
    d = (x[:, 0] * (y[:, 1] * w[:, 2] - y[:, 2] * w[:, 1]) - y[:, 0] * (x[:, 1] * w[:, 2] - x[:, 2] * w[:, 1])
         + w[:, 0] * (x[:, 1] * y[:, 2] - x[:, 2] * y[:, 1]))
    return _sign(d)


def _orient_projected(F: np.ndarray, ids: np.ndarray, table: PointTable, axis: int, flip: int) -> np.ndarray:
    """Exact orientation signs ``(k,)`` of triangles ``ids (k, 3)`` projected along ``axis`` (times ``flip``).

    Float filter on the rounded coordinates ``F (k, 3, 3)``: each coordinate is within a relative
    2^-53 of the exact one, so the determinant moves by at most ``3 u M (sum of |differences|)``
    plus second-order and evaluation terms (``M`` the largest coordinate magnitude); a
    determinant beyond twice that bound has its float sign; the others are decided with integers.
    """
    i, j = (axis + 1) % 3, (axis + 2) % 3
    a, b, c = F[:, 0], F[:, 1], F[:, 2]
    acx, acy = a[:, i] - c[:, i], a[:, j] - c[:, j]
    bcx, bcy = b[:, i] - c[:, i], b[:, j] - c[:, j]
    left, right = acx * bcy, acy * bcx
    det = left - right
    M = np.max(np.abs(F[:, :, [i, j]]).reshape(F.shape[0], -1), axis=1)
    u = _EPS
    bound = 2.0 * (3 * u * M * (np.abs(acx) + np.abs(acy) + np.abs(bcx) + np.abs(bcy)) + 18 * u * u * M * M
                   + 3 * u * (np.abs(left) + np.abs(right))) + 1e-300
    sign = np.where(det > bound, 1, np.where(-det > bound, -1, 0)).astype(np.int8)
    amb = np.flatnonzero(sign == 0)
    if amb.size:
        H = table.exact(ids[amb].ravel()).reshape(amb.size, 3, 4)
        sign[amb] = _orient_projected_exact(H, axis)
    return sign * flip


def imprint(X: Operand, which: int, inter: Intersections, table: PointTable) -> Imprint:
    """Split the triangles of one operand along its imprinted segments (phase 5).

    Parameters
    ----------
    X : Operand
    which : 0 for A, 1 for B
    inter : Intersections
    table : PointTable

    Returns
    -------
    Imprint

    Raises
    ------
    BooleanError
        (stage ``"imprint"``) a triangle the float triangulation cannot split (features within an
        ulp of each other), a split that fails the exact verification, a segment that is not an
        edge of the pieces, or pieces that do not close up (each piece edge used twice).
    """
    nA, nB = table.nA, table.nB
    off = 0 if which == 0 else nA
    if which == 0:
        vid = np.arange(X.n, dtype=np.int64)
    else:
        vid = inter.alias_b.copy()
    T = vid[X.T]
    codes = inter.code_a if which == 0 else inter.code_b
    dim = codes & 3
    idx = codes >> 2
    seg = inter.seg_a if which == 0 else inter.seg_b
    # Points on edges and inside triangles of X.
    on_edge = np.flatnonzero(dim == 1)
    inside = np.flatnonzero(dim == 2)
    e_of = idx[on_edge]
    ep_gid = inter.gid[on_edge]
    t_of = idx[inside]
    ip_gid = inter.gid[inside]
    affected = np.zeros(X.m, dtype=bool)
    if e_of.size:
        affected[X.edge_tris[e_of].ravel()] = True
    affected[t_of] = True
    # Points of each edge sorted along it (float order of the dominant coordinate, exact on ties).
    order = _sort_on_edges(X, e_of, ep_gid, table)
    e_sorted, g_sorted = e_of[order], ep_gid[order]
    e_ptr = row_pointers(e_sorted, X.n_edges)
    i_order = np.argsort(t_of, kind="stable")
    t_sorted, gi_sorted = t_of[i_order], ip_gid[i_order]
    t_ptr = row_pointers(t_sorted, X.m)
    # Segments per triangle.
    s_order = np.argsort(seg[:, 0], kind="stable")
    seg = seg[s_order]
    s_ptr = row_pointers(seg[:, 0], X.m)
    aff = np.flatnonzero(affected)
    axis, sgn = _projection(X.P, X.T, aff) if aff.size else (np.zeros(0, np.int64), np.zeros(0, np.int8))
    whole = np.flatnonzero(~affected)
    pieces, sources = [np.take(T, whole, axis=0)], [whole]
    done, G_chain, src_chain = _chain_pieces(aff, axis, sgn, T, X, e_ptr, g_sorted, t_ptr, gi_sorted, seg, s_ptr,
                                             table)
    if G_chain.size:
        pieces.append(G_chain)
        sources.append(src_chain)
    # Triangles of one pattern (points per edge, interior points, chords) take the split of the first
    # of them where it is valid for theirs (vectorised); the others are split one by one.
    rest = np.flatnonzero(~done)
    reps, groups = _patterns(rest, aff, T, X, e_ptr, g_sorted, t_ptr, gi_sorted, seg, s_ptr)
    ctx = (aff, axis, sgn, T, X, e_ptr, g_sorted, t_ptr, gi_sorted, seg, s_ptr, table, which)
    splits = _split_each(reps, *ctx)
    if groups:
        G_pat, src_pat, again = _apply_patterns(groups, splits, aff, axis, sgn, table)
        pieces.append(G_pat)
        sources.append(src_pat)
        splits += _split_each(again, *ctx)
    for t, tri, ids in splits:
        pieces.append(ids[tri])
        sources.append(np.full(tri.shape[0], t, dtype=np.int64))
    tris = np.concatenate(pieces)
    source = np.concatenate(sources)
    if seg.size:  # distinct undirected segments, smaller id first, in order (one int key: unique(axis=0) is slow)
        n_ids = np.int64(table.float.shape[0])
        key = np.unique(np.minimum(seg[:, 1], seg[:, 2]) * n_ids + np.maximum(seg[:, 1], seg[:, 2]))
        on = np.stack([key // n_ids, key % n_ids], axis=1)
    else:
        on = np.zeros((0, 2), dtype=np.int64)
    # Closedness can only fail around split triangles: check their pieces, their neighbours and
    # the triangles carrying segments.
    near = affected.copy()
    if aff.size:
        near[X.edge_tris[X.tri_edge[aff]].ravel()] = True
    if seg.size:
        near[seg[:, 0]] = True
    _verify_closed(np.compress(near[source], tris, axis=0), on, which,
                   boundary_ok=near[X.edge_tris[:, 0]] != near[X.edge_tris[:, 1]], X=X, vid=vid)
    return Imprint(tris, source, on, int(X.m - aff.size), vid)


def _split_each(rows, aff, axis, sgn, T, X, e_ptr, g_sorted, t_ptr, gi_sorted, seg, s_ptr, table, which) -> list:
    """Split the triangles ``aff[rows]`` one by one (the loop of :func:`imprint` for the triangles no
    template split): exact incremental splits for few points, the constrained Delaunay triangulator
    (verified exactly) for many.

    Returns
    -------
    list of ``(t, tri, ids)``: triangle, ``(k, 3)`` local indices of its pieces into ``ids``, global ids.
    """
    out: list = []
    small: list = []
    redo: dict = {}  # entries of small split by _chain_split: the arguments of the exact split
    is_float = table.is_float
    for r in np.asarray(rows, dtype=np.int64).tolist():
        t = int(aff[r])
        ax, sg = int(axis[r]), int(sgn[r])
        loop = []
        len_e = []
        for kk in range(3):
            v = int(T[t, kk])
            loop.append(v)
            e = int(X.tri_edge[t, kk])
            pts = g_sorted[e_ptr[e] : e_ptr[e + 1]].tolist()
            if X.edges[e, 0] != X.T[t, kk]:
                pts = pts[::-1]
            loop.extend(pts)
            len_e.append(len(pts))
        interior = gi_sorted[t_ptr[t] : t_ptr[t + 1]].tolist()
        ids = loop + interior
        local = {g: i for i, g in enumerate(ids)}
        if len(local) != len(ids):
            raise BooleanError(f"triangle {t} lists a point twice", stage="imprint",
                               diagnostics={"operand": "AB"[which], "triangle": t})
        tv = [int(T[t, 0]), int(T[t, 1]), int(T[t, 2])]
        edges_of = {}  # global id -> set of local edge slots of t containing it
        for kk in range(3):
            edges_of.setdefault(tv[kk], set()).update({kk, (kk + 2) % 3})
        for kk in range(3):
            e = int(X.tri_edge[t, kk])
            for g in g_sorted[e_ptr[e] : e_ptr[e + 1]].tolist():
                edges_of.setdefault(g, set()).add(kk)
        nb = len(loop)
        cons = [(i, (i + 1) % nb) for i in range(nb)]
        chords = []
        for p, q in seg[s_ptr[t] : s_ptr[t + 1], 1:].tolist():
            if edges_of.get(p, set()) & edges_of.get(q, set()):
                continue  # along the boundary of t
            if p not in local or q not in local:
                raise BooleanError(f"segment end {p if p not in local else q} is not a point of triangle {t}",
                                   stage="imprint", diagnostics={"operand": "AB"[which], "triangle": t})
            chords.append((local[p], local[q]))
        chords = sorted(set(tuple(sorted(c)) for c in chords))
        for a, b in chords:
            cons.append((a, b))
            cons.append((b, a))
        F3 = table.float[ids]
        ids_arr = np.asarray(ids, dtype=np.int64)
        i, j = (ax + 1) % 3, (ax + 2) % 3
        P2 = F3[:, [i, j]] if sg > 0 else F3[:, [j, i]]
        corners = [0, 1 + len_e[0], 2 + len_e[0] + len_e[1]]
        exact_h = _LazyExact(table, ids_arr, i, j, sg)
        if len(ids) <= _SMALL_SPLIT:
            # Boxes of the exact points: the rounded coordinates widened by their possible rounding error.
            slack = 2.0 * _EPS * np.abs(P2) + 1e-300
            boxes = np.concatenate([P2 - slack, P2 + slack], axis=1)
            sides = [0] * len(ids)
            pos = 0
            for kk in range(3):  # corner kk lies on edges kk and kk - 1, edge points on their edge
                sides[pos] |= (1 << kk) | (1 << ((kk + 2) % 3))
                for q in range(pos + 1, pos + 1 + len_e[kk]):
                    sides[q] = 1 << kk
                pos += 1 + len_e[kk]
            args = (len(ids), nb, corners, chords, _filtered_orient(P2, exact_h, is_float[ids_arr].tolist(), sides),
                    _failer(which, t), boxes)
            tri = _chain_split(len(ids), nb, corners, chords, P2)
            if tri is None:
                tri = _split_incremental(*args)
            else:
                redo[len(small)] = args
            small.append((t, tri, ids_arr, nb, ax, sg, loop))
            continue  # pieces appended after the vectorised verification
        else:
            try:
                tri = triangulate(P2, np.asarray(cons, dtype=np.int64))
                _verify_split(tri, nb, len(ids), chords, F3, ids_arr, table, ax, sg, which, t)
            except (InvalidInputError, BooleanError):
                # Features within an ulp of each other: split with exact arithmetic instead.
                tri = _split_incremental(len(ids), nb, corners, chords, _exact_orient(exact_h()), _failer(which, t))
                _verify_split(tri, nb, len(ids), chords, F3, ids_arr, table, ax, sg, which, t)
        out.append((t, tri, ids_arr))
    if small:
        bad = _verify_small(small, table, which, strict=not redo)
        if bad.size:
            # A candidate of _chain_split that is not a valid split: split those exactly (Python).
            for r in bad.tolist():
                if r not in redo:
                    _verify_small([small[r]], table, which)  # raises with the reason
                t_, _, ids_, nb_, ax_, sg_, loop_ = small[r]
                small[r] = (t_, _split_incremental(*redo[r]), ids_, nb_, ax_, sg_, loop_)
            _verify_small([small[r] for r in bad.tolist()], table, which)
        out.extend((t_, tri_, ids_) for t_, tri_, ids_, *_rest in small)
    return out


def _verify_split(tri, nb, n_ids, chords, F3, ids, table, ax, sg, which, t) -> None:
    """Exact checks of a triangle's split (module docstring): orientation, boundary, constraints."""
    fail = None
    if tri.shape[0] != nb + 2 * (n_ids - nb) - 2:
        fail = f"{tri.shape[0]} pieces for {nb} boundary and {n_ids - nb} interior points"
    else:
        s = _orient_projected(F3[tri], ids[tri], table, ax, sg)
        if np.any(s <= 0):
            fail = f"piece {tri[int(np.argmax(s <= 0))].tolist()} is not counter-clockwise for the exact points"
        else:
            # Directed piece edges as one integer each (sets of tuples are slow for big splits).
            n = np.int64(n_ids)
            a, b = tri.ravel().astype(np.int64), next_corners(tri).astype(np.int64)
            d = a * n + b
            dk = np.sort(d)
            boundary = np.sort(d[~sorted_contains(dk, b * n + a)])
            loop = np.arange(nb, dtype=np.int64)
            want = np.sort(loop * n + np.roll(loop, -1))
            ch = np.asarray(chords, dtype=np.int64).reshape(-1, 2)
            if boundary.shape != want.shape or not np.array_equal(boundary, want):
                fail = "the pieces' boundary is not the subdivided triangle boundary"
            elif not np.all(sorted_contains(dk, ch[:, 0] * n + ch[:, 1])
                            | sorted_contains(dk, ch[:, 1] * n + ch[:, 0])):
                fail = "a constraint segment is not an edge of the pieces"
    if fail:
        raise BooleanError(f"split of triangle {t} of {'AB'[which]} fails exact verification: {fail}",
                           stage="imprint", diagnostics={"operand": "AB"[which], "triangle": t})


def _verify_closed(tris: np.ndarray, on: np.ndarray, which: int, boundary_ok: np.ndarray, X: Operand,
                   vid: np.ndarray) -> None:
    """Every piece edge of a closed neighbourhood is used once each way, and every on-edge is a piece edge.

    ``tris`` are the pieces of the triangles near the splits; directed edges without a reverse are
    allowed only on original edges leaving the neighbourhood (``boundary_ok`` per edge of ``X``).
    """
    if tris.shape[0] == 0:
        return
    a = tris.ravel()
    b = next_corners(tris)
    n = np.int64(max(int(tris.max()) + 1, int(vid.max(initial=0)) + 1, 1))
    d = a * n + b
    ds = np.sort(d)
    dupl = ds[1:] == ds[:-1]
    missing = ~sorted_contains(ds, b * n + a)
    if np.any(missing):
        ev = vid[X.edges[boundary_ok]]
        ok_keys = np.sort(np.concatenate([ev[:, 0] * n + ev[:, 1], ev[:, 1] * n + ev[:, 0]]))
        missing[missing] = ~sorted_contains(ok_keys, d[missing])
    if np.any(dupl) or np.any(missing):
        g = int(ds[1:][dupl][0]) if np.any(dupl) else int(d[np.argmax(missing)])
        raise BooleanError(
            f"the pieces of {'AB'[which]} do not close up at the edge between points {g // n} and {g % n}",
            stage="imprint", diagnostics={"operand": "AB"[which], "edge": (int(g // n), int(g % n))},
        )
    if on.size:
        k = on[:, 0] * n + on[:, 1]
        und = np.minimum(a, b) * n + np.maximum(a, b)
        miss = ~sorted_contains(np.sort(und), k)
        if np.any(miss):
            p, q = on[int(np.argmax(miss))]
            raise BooleanError(
                f"the intersection segment between points {int(p)} and {int(q)} is not an edge of the pieces of "
                f"{'AB'[which]}", stage="imprint", diagnostics={"operand": "AB"[which], "segment": (int(p), int(q))},
            )


def _sort_on_edges(X: Operand, e_of: np.ndarray, gids: np.ndarray, table: PointTable) -> np.ndarray:
    """Order of points (on edges ``e_of``) by edge, then by position from the edge's start."""
    if e_of.size == 0:
        return np.zeros(0, dtype=np.int64)
    p = X.P[X.edges[e_of, 0]]
    q = X.P[X.edges[e_of, 1]]
    d = q - p
    ax = np.argmax(np.abs(d), axis=1)
    r = np.arange(e_of.size)
    sgn = np.sign(d[r, ax])
    coord = table.float[gids, ax] * sgn
    order = np.lexsort((coord, e_of))
    # Exact tie-break where two distinct points of an edge round to the same coordinate.
    es, cs = e_of[order], coord[order]
    tie = np.flatnonzero((es[1:] == es[:-1]) & (cs[1:] == cs[:-1]))
    if tie.size:
        order = order.copy()
        for start in _runs(tie):
            lo, hi = start
            block = order[lo : hi + 1]
            H = table.exact(gids[block])
            axb = int(ax[block[0]])
            sb = int(sgn[block[0]])
            keys = [Fraction(int(h[axb]), int(h[3])) * sb for h in H]
            order[lo : hi + 1] = block[np.argsort(np.array(keys, dtype=object), kind="stable")]
    return order


def _runs(tie: np.ndarray) -> list[tuple[int, int]]:
    """Maximal runs ``[lo, hi]`` of positions joined by ties ``tie`` (position i ties with i + 1)."""
    out = []
    start = prev = int(tie[0])
    for x in tie[1:].tolist():
        if x != prev + 1:
            out.append((start, prev + 1))
            start = x
        prev = x
    out.append((start, prev + 1))
    return out


# ====================================================================== exact fallback split
#: Triangles with at most this many points are split by :func:`_split_incremental` (filtered exact
#: predicates, Python); larger ones by the constrained Delaunay triangulator on floats.
_SMALL_SPLIT = 24


class _LazyExact:
    """The exact projected homogeneous points of one triangle's split, computed on first use."""

    def __init__(self, table: "PointTable", ids: np.ndarray, i: int, j: int, sg: int) -> None:
        self.table, self.ids, self.i, self.j, self.sg = table, ids, i, j, sg
        self.H: list | None = None

    def __call__(self) -> list:
        if self.H is None:
            H = self.table.exact(self.ids)
            H2 = H[:, [self.i, self.j, 3]] if self.sg > 0 else H[:, [self.j, self.i, 3]]
            self.H = [tuple(int(v) for v in row) for row in H2.tolist()]
        return self.H


def _orient_h(H: list, a: int, b: int, c: int) -> int:
    """Exact orientation of 2-D homogeneous integer points ``H[a], H[b], H[c]`` (``w > 0``)."""
    xa, ya, wa = H[a]
    xb, yb, wb = H[b]
    xc, yc, wc = H[c]
    d = xa * (yb * wc - yc * wb) - ya * (xb * wc - xc * wb) + wa * (xb * yc - xc * yb)
    return (d > 0) - (d < 0)


def _exact_orient(H: list):
    return lambda a, b, c: _orient_h(H, a, b, c)


def _filtered_orient(P2: np.ndarray, exact: _LazyExact, is_float: list, sides: list | None = None):
    """Orientation of rounded points with the rounding-aware float filter of :func:`_orient_projected`,
    exact integers when it cannot decide.  Between points that are exactly their floats
    (``is_float``) a float difference is zero only for equal coordinates, so a determinant whose
    products each have a zero factor is certified zero without integers (collinear points along
    an axis, the usual case on the boundary of a split).  ``sides[i]`` (a bit mask of the triangle
    edges point ``i`` lies on) answers collinear triples on one edge combinatorially."""
    F = [tuple(r) for r in P2.tolist()]
    u = _EPS

    def orient(a: int, b: int, c: int) -> int:
        if sides is not None and sides[a] & sides[b] & sides[c]:
            return 0  # three points of one edge of the triangle
        ax, ay = F[a]
        bx, by = F[b]
        cx, cy = F[c]
        acx, acy, bcx, bcy = ax - cx, ay - cy, bx - cx, by - cy
        left, right = acx * bcy, acy * bcx
        d = left - right
        M = max(abs(ax), abs(ay), abs(bx), abs(by), abs(cx), abs(cy))
        bound = 2.0 * (3 * u * M * (abs(acx) + abs(acy) + abs(bcx) + abs(bcy)) + 18 * u * u * M * M
                       + 3 * u * (abs(left) + abs(right))) + 1e-300
        if d > bound:
            return 1
        if -d > bound:
            return -1
        if (is_float[a] and is_float[b] and is_float[c] and (acx == 0 or bcy == 0) and (acy == 0 or bcx == 0)):
            return 0
        return _orient_h(exact(), a, b, c)

    return orient


def _failer(which: int, t: int):
    def fail(msg: str):
        raise BooleanError(f"split of triangle {t} of {'AB'[which]}: {msg}", stage="imprint",
                           diagnostics={"operand": "AB"[which], "triangle": t})

    return fail


def _split_incremental(n: int, nb: int, corners: list, chords: list, orient, fail,
                       boxes: np.ndarray | None = None) -> np.ndarray:
    """Triangulate a triangle's points with exact orientation tests (incremental insertion and flips).

    Points ``0 .. nb-1`` are the counter-clockwise boundary loop (the triangle's ``corners`` and
    the points of its edges), ``nb .. n-1`` interior points; ``chords`` are the constraint
    segments between them.  Boundary points split the triangle on its edges, interior points
    split the triangle (or the two triangles) containing them, and each chord is recovered by
    flipping the edges crossing it (Sloan, "A fast algorithm for generating constrained Delaunay
    triangulations", 1993), every decision by ``orient(a, b, c)`` (exact).  Valid input
    (non-crossing chords through no other point) always succeeds; otherwise ``fail`` raises.

    ``boxes (n, 4)``, optional: a box ``(xmin, ymin, xmax, ymax)`` around each exact point; two
    segments whose boxes are disjoint are not tested for crossing (a conservative prefilter).

    Returns
    -------
    (k, 3) int64 local indices, counter-clockwise.
    """
    tris: dict[int, tuple[int, int, int]] = {}
    owner: dict[tuple[int, int], int] = {}
    counter = 0

    def add(a: int, b: int, c: int) -> None:
        nonlocal counter
        tris[counter] = (a, b, c)
        owner[(a, b)] = owner[(b, c)] = owner[(c, a)] = counter
        counter += 1

    def remove(k: int) -> tuple[int, int, int]:
        a, b, c = tris.pop(k)
        for e in ((a, b), (b, c), (c, a)):
            if owner.get(e) == k:
                del owner[e]
        return a, b, c

    c0, c1, c2 = corners
    add(c0, c1, c2)
    for ca, cb in ((c0, c1), (c1, c2), (c2, nb)):
        prev, end = ca, cb % nb
        for p in range(ca + 1, cb):
            k = owner.get((prev, end))
            if k is None:
                fail(f"boundary edge ({prev}, {end}) missing")
            a, b, c = remove(k)
            while a != prev:
                a, b, c = b, c, a
            add(prev, p, c)
            add(p, end, c)
            prev = p
    for p in range(nb, n):
        for k, (a, b, c) in list(tris.items()):
            o0 = orient(a, b, p)
            if o0 < 0:
                continue
            o1 = orient(b, c, p)
            if o1 < 0:
                continue
            o2 = orient(c, a, p)
            if o2 < 0:
                continue
            zeros = [z for z, o in enumerate((o0, o1, o2)) if o == 0]
            if not zeros:
                remove(k)
                add(a, b, p)
                add(b, c, p)
                add(c, a, p)
            elif len(zeros) == 1:
                u, v, w = ((a, b, c), (b, c, a), (c, a, b))[zeros[0]]
                k2 = owner.get((v, u))
                if k2 is None:
                    fail(f"interior point {p} lies on the boundary")
                x = [q for q in tris[k2] if q != u and q != v][0]
                remove(k)
                remove(k2)
                add(u, p, w)
                add(p, v, w)
                add(v, p, x)
                add(p, u, x)
            else:
                fail(f"interior point {p} coincides with a vertex")
            break
        else:
            fail(f"interior point {p} lies outside the triangle")
    fixed = {(min(a, b), max(a, b)) for a, b in chords}

    if boxes is not None:
        B = boxes.tolist()

        def apart(a: int, b: int, p: int, q: int) -> bool:
            ba, bb, bp, bq = B[a], B[b], B[p], B[q]
            return (max(ba[2], bb[2]) < min(bp[0], bq[0]) or max(bp[2], bq[2]) < min(ba[0], bb[0])
                    or max(ba[3], bb[3]) < min(bp[1], bq[1]) or max(bp[3], bq[3]) < min(ba[1], bb[1]))
    else:
        def apart(a: int, b: int, p: int, q: int) -> bool:
            return False

    def crosses(a: int, b: int, p: int, q: int) -> bool:
        if apart(a, b, p, q):
            return False
        return orient(p, q, a) * orient(p, q, b) < 0 and orient(a, b, p) * orient(a, b, q) < 0

    def crossed_edges(p: int, q: int) -> list[tuple[int, int]]:
        """Edges crossed by the segment p q, by walking from p (one orientation per step)."""
        start = None
        for a, b, c in tris.values():
            if p not in (a, b, c):
                continue
            while a != p:
                a, b, c = b, c, a
            if orient(p, b, q) > 0 and orient(p, c, q) < 0:
                start = (b, c)
                break
        if start is None:
            fail(f"chord ({p}, {q}) leaves no triangle around {p}")
        x, y = start  # x right of p -> q, y left of it
        out = [start]
        for _ in range(len(tris) + 1):
            k = owner.get((y, x))
            if k is None:
                fail(f"chord ({p}, {q}) leaves the triangle")
            z = [v for v in tris[k] if v != x and v != y][0]
            if z == q:
                return out
            side = orient(p, q, z)
            if side == 0:
                fail(f"chord ({p}, {q}) passes through point {z}")
            if side > 0:
                y = z
            else:
                x = z
            out.append((x, y))
        fail(f"chord ({p}, {q}) walk does not end")
        return out

    for p, q in chords:
        if (p, q) in owner or (q, p) in owner:
            continue
        queue = [(min(a, b), max(a, b)) for a, b in crossed_edges(p, q)]
        if any(e in fixed for e in queue):
            fail(f"chord ({p}, {q}) crosses another constraint")
        steps = 0
        limit = 4 * (len(queue) + 1) ** 2 + 16
        while queue:
            steps += 1
            if steps > limit:
                fail(f"chord ({p}, {q}) not recovered after {limit} flips")
            a, b = queue.pop(0)
            k1, k2 = owner.get((a, b)), owner.get((b, a))
            if k1 is None or k2 is None:
                continue
            c = [x for x in tris[k1] if x != a and x != b][0]
            d = [x for x in tris[k2] if x != a and x != b][0]
            if orient(c, d, a) * orient(c, d, b) < 0:
                remove(k1)
                remove(k2)
                add(a, d, c)
                add(d, b, c)
                if crosses(c, d, p, q):
                    queue.append((min(c, d), max(c, d)))
            else:
                queue.append((a, b))
        if (p, q) not in owner and (q, p) not in owner:
            fail(f"chord ({p}, {q}) could not be recovered")
    return np.asarray(list(tris.values()), dtype=np.int64).reshape(-1, 3)


#: Most interior points of a triangle split by :func:`_chain_pieces` (larger chains take the Python path).
_CHAIN_MAX = 4


@lru_cache(maxsize=None)
def _chain_templates(k: int, x: int, y: int) -> tuple[np.ndarray, ...]:
    """Local triangles of the chain split (see :func:`_chain_pieces`) for ``k`` interior points and edge
    points at loop positions ``x < y`` (corners at the other three of the five positions): one
    template ``(2 k + 3, 3)`` per choice of the split vertex of the two-corner polygon.  Local ids:
    ``0..4`` the boundary loop, ``5 + i`` the ``i``-th interior point along the chain from ``x``."""
    inner = [5 + i for i in range(k)]
    polys = []
    for start, stop, seq in ((x, y, [y] + inner[::-1] + [x]), (y, x, [x] + inner + [y])):
        cs = [(start + i) % 5 for i in range(1, (stop - start) % 5)]
        polys.append((cs, seq))
    one = [p for p in polys if len(p[0]) == 1][0]
    two = [p for p in polys if len(p[0]) == 2][0]
    fan = [(one[0][0], one[1][i], one[1][i + 1]) for i in range(len(one[1]) - 1)]
    (c1, c2), seq = two
    out = []
    for j in range(len(seq)):
        tri = fan + [(c1, c2, seq[j])]
        tri += [(c2, seq[i], seq[i + 1]) for i in range(j)]
        tri += [(c1, seq[i], seq[i + 1]) for i in range(j, len(seq) - 1)]
        tri = np.asarray(tri, dtype=np.int64)
        tri.flags.writeable = False  # cached: shared by every call
        # The template must be a disc whose boundary is the loop (combinatorial, checked once).
        d = {(int(a), int(b)) for a, b in tri[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2)}
        boundary = {(a, b) for a, b in d if (b, a) not in d}
        if boundary != {(i, (i + 1) % 5) for i in range(5)} or len(d) != 3 * tri.shape[0]:  # pragma: no cover
            raise BooleanError("internal: a chain template is not a split of the triangle", stage="imprint")
        out.append(tri)
    return tuple(out)


@lru_cache(maxsize=None)
def _chain_template_stack(k: int, x: int, y: int) -> np.ndarray:
    """The templates of :func:`_chain_templates` as one read-only ``(templates, 2 k + 3, 3)`` array."""
    TP = np.stack(_chain_templates(k, x, y))
    TP.flags.writeable = False
    return TP


def _chain_pieces(aff, axis, sgn, T, X, e_ptr, g_sorted, t_ptr, gi_sorted, seg, s_ptr, table):
    """Split, in array time, the triangles crossed by one chain of segments (nearly all of them).

    A triangle qualifies when exactly two of its edges carry one point each, it holds ``k <=
    _CHAIN_MAX`` interior points and ``k + 1`` segments that form one chain from one edge point
    through every interior point to the other (walked on arrays, one step per chain vertex).  The
    chain cuts the triangle into a polygon with one corner, fanned from it, and one with two
    corners ``c1, c2``, split into the triangle ``(c1, c2, s)`` and fans from ``c2`` and ``c1`` on
    either side of a chain vertex ``s`` (:func:`_chain_templates`; ``s`` maximises the smallest
    float orientation).  Every piece is then verified counter-clockwise for the exact points
    (:func:`_orient_projected`); with the templates' boundary (the subdivided triangle) this
    proves the split (degree argument, module docstring).  Triangles that do not qualify or fail
    the verification are left to the per-triangle splits.

    Returns
    -------
    done : (len(aff),) bool        the triangles split here
    G : (p, 3) int64               their pieces, global ids
    source : (p,) int64            the triangle of each piece
    """
    q = aff.size
    done = np.zeros(q, dtype=bool)
    empty = (done, np.zeros((0, 3), dtype=np.int64), np.zeros(0, dtype=np.int64))
    if q == 0:
        return empty
    E = X.tri_edge[aff]
    cnt = e_ptr[E + 1] - e_ptr[E]
    k = t_ptr[aff + 1] - t_ptr[aff]
    ns = s_ptr[aff + 1] - s_ptr[aff]
    c = np.flatnonzero((cnt.sum(axis=1) == 2) & (cnt.max(axis=1) == 1) & (ns == k + 1) & (k <= _CHAIN_MAX))
    if c.size == 0:
        return empty
    E, cnt, k, ns, t = E[c], cnt[c], k[c], ns[c], aff[c]
    r = np.arange(c.size)
    # The boundary loop: corner 0, its edge's point, corner 1, ..., as global ids at five positions.
    L = np.empty((c.size, 5), dtype=np.int64)
    pos = np.zeros(c.size, dtype=np.int64)
    ep_pos = []
    for kk in range(3):
        L[r, pos] = T[t, kk]
        has = cnt[:, kk] == 1
        L[r[has], pos[has] + 1] = g_sorted[e_ptr[E[has, kk]]]
        ep_pos.append(np.where(has, pos + 1, -1))
        pos = pos + 1 + cnt[:, kk]
    ep_pos = np.sort(np.stack(ep_pos, axis=1), axis=1)[:, 1:]  # the two edge point positions, x < y
    xp, yp = ep_pos[:, 0], ep_pos[:, 1]
    K = _CHAIN_MAX
    # Segments (padded with -2, which no id or sentinel equals).
    S = np.full((c.size, K + 1, 2), -2, dtype=np.int64)
    for j in range(K + 1):
        has = ns > j
        S[has, j] = seg[s_ptr[t[has]] + j, 1:]
    inner_set = np.full((c.size, K), -3, dtype=np.int64)
    for j in range(K):
        has = k > j
        inner_set[has, j] = gi_sorted[t_ptr[t[has]] + j]
    # Walk the chain from x.
    ok = np.ones(c.size, dtype=bool)
    cur = L[r, xp]
    prev = np.full(c.size, -5, dtype=np.int64)
    chain = np.full((c.size, K), -4, dtype=np.int64)
    for step in range(K + 1):
        live = step <= k
        m0 = (S[:, :, 0] == cur[:, None]) & (S[:, :, 1] != prev[:, None])
        m1 = (S[:, :, 1] == cur[:, None]) & (S[:, :, 0] != prev[:, None])
        hits = m0.sum(axis=1) + m1.sum(axis=1)
        ok &= ~live | (hits == 1)
        nxt = np.where(m0.any(axis=1), S[r, np.argmax(m0, axis=1), 1], S[r, np.argmax(m1, axis=1), 0])
        prev = np.where(live, cur, prev)
        cur = np.where(live, nxt, cur)
        if step < K:
            inner_step = live & (step < k)
            chain[inner_step, step] = cur[inner_step]
            # each chain vertex is one of the triangle's interior points
            ok &= ~inner_step | np.any(inner_set == cur[:, None], axis=1)
    ok &= cur == L[r, yp]
    for i in range(K):  # distinct chain vertices
        for j in range(i + 1, K):
            ok &= ~((i < k) & (j < k) & (chain[:, i] == chain[:, j]))
    GID = np.concatenate([L, chain], axis=1)  # local ids 0..4 loop, 5.. chain
    # Projected float coordinates for choosing the split vertex.
    ax, sg = axis[c], sgn[c]
    Fl = table.float[np.maximum(GID, 0)]
    i_ax, j_ax = (ax + 1) % 3, (ax + 2) % 3
    U = np.where((sg > 0)[:, None], Fl[r[:, None], np.arange(GID.shape[1])[None, :], i_ax[:, None]],
                 Fl[r[:, None], np.arange(GID.shape[1])[None, :], j_ax[:, None]])
    V = np.where((sg > 0)[:, None], Fl[r[:, None], np.arange(GID.shape[1])[None, :], j_ax[:, None]],
                 Fl[r[:, None], np.arange(GID.shape[1])[None, :], i_ax[:, None]])
    out_G, out_s, out_rows = [], [], []
    # The distinct (k, xp, yp) in lexicographic order, by one integer key (unique(axis=0) is slow).
    base = np.int64(max(int(k.max(initial=0)), int(xp.max(initial=0)), int(yp.max(initial=0))) + 1)
    key = (k.astype(np.int64) * base + xp) * base + yp
    keys = np.unique(key[ok])
    for kk_, x_, y_ in zip((keys // (base * base)).tolist(), (keys // base % base).tolist(), (keys % base).tolist()):
        rows = np.flatnonzero(ok & (key == (kk_ * base + x_) * base + y_))
        TP = _chain_template_stack(kk_, x_, y_)  # (templates, pieces, 3)
        Ur, Vr = U[rows], V[rows]
        ia, ib, ic = TP[..., 0], TP[..., 1], TP[..., 2]
        uc, vc = Ur[:, ic], Vr[:, ic]
        o = (Ur[:, ia] - uc) * (Vr[:, ib] - vc) - (Vr[:, ia] - vc) * (Ur[:, ib] - uc)  # (rows, templates, pieces)
        choice = np.argmax(o.min(axis=2), axis=1)
        p = TP.shape[1]
        out_G.append(GID[rows[:, None, None], TP[choice]].reshape(-1, 3))
        out_s.append(np.repeat(t[rows], p))
        out_rows.append(np.repeat(rows, p))
    if not out_G:
        return empty
    G = np.concatenate(out_G)
    src = np.concatenate(out_s)
    prow = np.concatenate(out_rows)
    good = _ccw_rows(G, prow, ax, sg, table) & ok
    keep = good[prow]
    done[c[good]] = True
    return done, G[keep], src[keep]


def _ccw_rows(G: np.ndarray, prow: np.ndarray, axis: np.ndarray, sgn: np.ndarray, table: "PointTable") -> np.ndarray:
    """Which rows have all their pieces counter-clockwise for the exact points (vectorised).

    ``G (p, 3)`` pieces as global ids, ``prow (p,)`` the row of each piece, ``axis``, ``sgn``
    ``(rows,)`` each row's projection (:func:`_projection`).  Returns ``(rows,)`` bool.
    """
    pax, psg = axis[prow], sgn[prow]
    good = np.ones(axis.size, dtype=bool)
    Fp = table.float[G]
    for a_ in range(3):
        for s_ in (-1, 1):
            sel = np.flatnonzero((pax == a_) & (psg == s_))
            if sel.size:
                o = _orient_projected(Fp[sel], G[sel], table, a_, s_)
                good[prow[sel[o <= 0]]] = False
    return good


#: Segments a triangle may carry to be split by the pattern of another (:func:`_patterns`).
_PATTERN_SEGMENTS = 16


def _patterns(rest, aff, T, X, e_ptr, g_sorted, t_ptr, gi_sorted, seg, s_ptr) -> tuple[np.ndarray, list]:
    """Group the triangles ``aff[rest]`` by the pattern of their split, in array time.

    A triangle's split is a triangulation of its local points — corner 0, the points of edge 0 in
    order, corner 1, ..., then the interior points — constrained by its chords (segments not along
    one of its edges).  Two triangles with the same points per edge, the same number of interior
    points and the same chords between local indices have the same combinatorial problem, and
    one's triangulation in local indices is the other's whenever its pieces are counter-clockwise
    for the other's exact points (its boundary is the subdivided triangle by construction: the
    degree argument of the module docstring).  The many prism sides of a perforated plate, each
    cut by the plate's two faces, are a few patterns.

    Returns
    -------
    reps : (r,) int64
        Rows of ``aff`` to split one by one: each group's first triangle and the triangles in no
        group (alone in their pattern, too many points or segments, or points the loop cannot
        name: the per-triangle split reports those).
    groups : list of ``(rep, members, ids, rep_ids)``
        The representative's row, the other rows ``(m,)``, their local points as global ids
        ``(m, n)`` and the representative's ``(n,)``.
    """
    t = aff[rest]
    E = X.tri_edge[t]
    cnt = e_ptr[E + 1] - e_ptr[E]
    k = t_ptr[t + 1] - t_ptr[t]
    ns = s_ptr[t + 1] - s_ptr[t]
    n = 3 + cnt.sum(axis=1) + k
    c = np.flatnonzero((n <= _SMALL_SPLIT) & (ns <= _PATTERN_SEGMENTS))
    if c.size < 2:
        return rest, []
    t, E, cnt, k, ns, n = t[c], E[c], cnt[c], k[c], ns[c], n[c]
    m, N = c.size, int(n.max())
    r = np.arange(m)
    ID = np.full((m, N), -1, dtype=np.int64)
    side = np.zeros((m, N), dtype=np.int64)  # bit kk: on edge kk of the triangle
    pos = np.zeros(m, dtype=np.int64)
    for kk in range(3):
        ID[r, pos] = T[t, kk]
        side[r, pos] = (1 << kk) | (1 << ((kk + 2) % 3))
        fwd = X.edges[E[:, kk], 0] == X.T[t, kk]
        for j in range(int(cnt[:, kk].max())):
            h = np.flatnonzero(cnt[:, kk] > j)
            jj = np.where(fwd[h], j, cnt[h, kk] - 1 - j)
            ID[h, pos[h] + 1 + j] = g_sorted[e_ptr[E[h, kk]] + jj]
            side[h, pos[h] + 1 + j] = 1 << kk
        pos = pos + 1 + cnt[:, kk]
    for j in range(int(k.max())):
        h = np.flatnonzero(k > j)
        ID[h, pos[h] + j] = gi_sorted[t_ptr[t[h]] + j]
    srt = np.sort(ID, axis=1)
    ok = ~np.any((srt[:, 1:] == srt[:, :-1]) & (srt[:, 1:] >= 0), axis=1)
    S = max(int(ns.max()), 1)
    ends = np.full((m, S, 2), -2, dtype=np.int64)
    for j in range(S):
        h = np.flatnonzero(ns > j)
        ends[h, j] = seg[s_ptr[t[h]] + j, 1:]
    match = ID[:, None, None, :] == ends[:, :, :, None]
    real = np.arange(S)[None, :] < ns[:, None]
    ok &= np.all(match.any(axis=3) | ~real[:, :, None], axis=(1, 2))
    loc = np.argmax(match, axis=3)
    on = np.take_along_axis(side, loc.reshape(m, -1), axis=1).reshape(m, S, 2)
    chord = real & ((on[:, :, 0] & on[:, :, 1]) == 0)
    big = N * N
    code = np.where(chord, loc.min(axis=2) * N + loc.max(axis=2), big)
    code = np.sort(code, axis=1)
    code[:, 1:][code[:, 1:] == code[:, :-1]] = big
    code = np.sort(code, axis=1)
    key = np.concatenate([cnt, k[:, None], code], axis=1)
    sel = np.flatnonzero(ok)
    if sel.size < 2:
        return rest, []
    _, inv, count = np.unique(key[sel], axis=0, return_inverse=True, return_counts=True)
    inv = inv.ravel()
    grouped = count[inv] >= 2
    order = np.argsort(inv, kind="stable")
    groups = []
    for g in np.flatnonzero(count >= 2).tolist():
        rows = sel[order[np.searchsorted(inv[order], g) : np.searchsorted(inv[order], g, side="right")]]
        rep, members = rows[0], rows[1:]
        groups.append((int(rest[c[rep]]), rest[c[members]], ID[members, : int(n[rep])], ID[rep, : int(n[rep])]))
    alone = np.ones(rest.size, dtype=bool)
    alone[c[sel[grouped]]] = False
    reps = np.concatenate([rest[alone], np.array([g[0] for g in groups], dtype=np.int64)])
    return reps, groups


def _apply_patterns(groups: list, splits: list, aff, axis, sgn, table) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Each group's members split by their representative's triangulation, kept where exact.

    Returns
    -------
    G : (p, 3) int64       the pieces of the members it splits, global ids
    source : (p,) int64    the triangle of each piece
    again : (q,) int64     rows of ``aff`` whose pieces were not all counter-clockwise
    """
    by_t = {t: (tri, ids) for t, tri, ids in splits}
    Gs, rows = [], []
    for rep, members, ids, want in groups:
        tri, rep_ids = by_t[int(aff[rep])]
        # The boundary argument needs the representative's points in the order the pattern named them.
        if not np.array_equal(rep_ids, want):  # pragma: no cover - one layout of the local points
            raise BooleanError(f"internal: triangle {int(aff[rep])}'s split points are not in its pattern's order",
                               stage="imprint")
        Gs.append(ids[:, tri].reshape(-1, 3))
        rows.append(np.repeat(members, tri.shape[0]))
    G, prow = np.concatenate(Gs), np.concatenate(rows)
    good = _ccw_rows(G, prow, axis, sgn, table)
    keep = good[prow]
    members = np.concatenate([g[1] for g in groups])
    return G[keep], aff[prow[keep]], members[~good[members]]


def _chain_split(n: int, nb: int, corners: list, chords: list, P2: np.ndarray) -> np.ndarray | None:
    """A candidate split, without predicates, of a triangle crossed by one chain of chords.

    The common case (nearly every split triangle of two fine meshes): two boundary points ``x``,
    ``y`` on different edges joined by a chain of chords through all the interior points.  The
    chain cuts the triangle into two polygons ``[x, corners..., y, chain back to x]`` with one or
    two corners; one corner is fanned, two corners get the triangle ``(c1, c2, s)`` and fans from
    ``c2`` and ``c1`` on either side of the chain vertex ``s`` (chosen by float orientations).
    Nothing here is decided exactly: the caller verifies the pieces exactly
    (:func:`_verify_small`) and splits the triangle with :func:`_split_incremental` when the
    candidate is not valid.

    Returns
    -------
    (n - 2 + n - nb, 3) int64 local indices, or None when the triangle is not such a case.
    """
    k = n - nb
    if nb != 5 or len(chords) != k + 1:
        return None
    edge_pts = [i for i in range(5) if i not in corners]
    adj: dict[int, list[int]] = {}
    for a, b in chords:
        adj.setdefault(a, []).append(b)
        adj.setdefault(b, []).append(a)
    x, y = edge_pts
    if len(adj.get(x, ())) != 1 or len(adj.get(y, ())) != 1 or y - x == 1 and x + 1 not in corners:
        return None
    chain = [x]
    prev = -1
    while True:
        nbrs = adj[chain[-1]]
        nxt_ = [v for v in nbrs if v != prev]
        if len(nbrs) > 2 or len(nxt_) != 1:
            return None
        prev = chain[-1]
        chain.append(nxt_[0])
        if chain[-1] == y or len(chain) > k + 2:
            break
    if chain[-1] != y or len(chain) != k + 2:
        return None
    inner = chain[1:-1]
    if any(v < nb for v in inner):
        return None
    F = P2.tolist()

    def orient(a: int, b: int, c: int) -> float:
        return (F[a][0] - F[c][0]) * (F[b][1] - F[c][1]) - (F[a][1] - F[c][1]) * (F[b][0] - F[c][0])

    out: list[tuple[int, int, int]] = []
    # Polygon 1: x, corners after x up to y, y, then the chain back; polygon 2: y, corners up to x, x, chain.
    for start, stop, seq in ((x, y, [y] + inner[::-1] + [x]), (y, x, [x] + inner + [y])):
        cs = [(start + i) % 5 for i in range(1, (stop - start) % 5)]
        if len(cs) == 1:
            out.extend((cs[0], seq[i], seq[i + 1]) for i in range(len(seq) - 1))
        elif len(cs) == 2:
            c1, c2 = cs
            best, best_j = -np.inf, 0
            for j in range(len(seq)):
                cand = [orient(c1, c2, seq[j])]
                cand += [orient(c2, seq[i], seq[i + 1]) for i in range(j)]
                cand += [orient(c1, seq[i], seq[i + 1]) for i in range(j, len(seq) - 1)]
                worst = min(cand)
                if worst > best:
                    best, best_j = worst, j
            j = best_j
            out.append((c1, c2, seq[j]))
            out.extend((c2, seq[i], seq[i + 1]) for i in range(j))
            out.extend((c1, seq[i], seq[i + 1]) for i in range(j, len(seq) - 1))
        else:
            return None
    return np.asarray(out, dtype=np.int64)


def _verify_small(small: list, table: "PointTable", which: int, strict: bool = True) -> np.ndarray:
    """The checks of :func:`_verify_split` for many splits at once (vectorised): exact orientation of
    every piece, piece counts, and the boundary of each triangle's pieces.

    ``strict``: raise on the first failure; otherwise return the entries that fail, ``(k,)`` int64.
    """
    src = np.concatenate([np.full(tri.shape[0], r, dtype=np.int64) for r, (_, tri, *_rest) in enumerate(small)])
    G = np.concatenate([ids[tri] for (_, tri, ids, *_rest) in small])
    n_ids = np.array([ids.size for (_, _, ids, *_rest) in small])
    nb = np.array([s[3] for s in small])
    failed = np.zeros(len(small), dtype=bool)
    got = np.bincount(src, minlength=len(small))
    bad = np.flatnonzero(got != 2 * n_ids - nb - 2)
    if bad.size and strict:
        t = small[int(bad[0])][0]
        raise BooleanError(f"split of triangle {t} of {'AB'[which]}: {int(got[bad[0]])} pieces, expected "
                           f"{int(2 * n_ids[bad[0]] - nb[bad[0]] - 2)}", stage="imprint",
                           diagnostics={"operand": "AB"[which], "triangle": t})
    failed[bad] = True
    axes = np.array([s[4] for s in small])[src]
    sgns = np.array([s[5] for s in small])[src]
    F = table.float[G]
    for ax in range(3):
        for sg in (-1, 1):
            sel = np.flatnonzero((axes == ax) & (sgns == sg))
            if sel.size == 0:
                continue
            o = _orient_projected(F[sel], G[sel], table, ax, sg)
            if np.any(o <= 0):
                if strict:
                    r = int(src[sel[int(np.argmax(o <= 0))]])
                    t = small[r][0]
                    raise BooleanError(f"split of triangle {t} of {'AB'[which]}: a piece is not counter-clockwise "
                                       "for the exact points", stage="imprint",
                                       diagnostics={"operand": "AB"[which], "triangle": t})
                failed[src[sel[o <= 0]]] = True
    # Boundary of each split: directed piece edges whose reverse (same split) is absent, against the loop.
    a = G.ravel()
    b = next_corners(G)
    s3 = np.repeat(src, 3)
    N = np.int64(max(int(G.max()) + 1, 1))
    if len(small) * int(N) * int(N) >= 2**62:  # pragma: no cover - beyond a billion points
        raise BooleanError("too many points to verify the splits", stage="imprint")
    key = (s3 * N + a) * N + b
    rev = (s3 * N + b) * N + a
    boundary = np.sort(key[~np.isin(rev, key)])
    loops = np.concatenate([np.asarray(x[6], dtype=np.int64) for x in small])
    nxt = np.concatenate([np.roll(np.asarray(x[6], dtype=np.int64), -1) for x in small])
    owner = np.repeat(np.arange(len(small), dtype=np.int64), [len(x[6]) for x in small])
    want = np.sort((owner * N + loops) * N + nxt)
    if boundary.shape != want.shape or not np.array_equal(boundary, want):
        if strict:
            raise BooleanError(f"the splits of {'AB'[which]} do not have the subdivided triangle boundaries",
                               stage="imprint", diagnostics={"operand": "AB"[which]})
        failed[boundary[~np.isin(boundary, want)] // (N * N)] = True
        failed[want[~np.isin(want, boundary)] // (N * N)] = True
    return np.flatnonzero(failed)


# ====================================================================== snapping near-coincidences
#: Passes of :func:`snap` before it gives up and leaves the operands as they are.  One pass makes
#: every cluster it touches agree; a second one normally finds nothing (it only acts when the first
#: one's new points, or a cluster's inserted points on a neighbouring cluster's edges, are themselves
#: near-coincidences).
_SNAP_PASSES = 4
#: Edges whose directions make ``sin² θ`` below this are parallel for the crossing search: the
#: crossing of two segments at angle ``θ`` is computed with an error of about ``ulp / sin θ``
#: (``1e-10`` of the edge length here, far below any tolerance); parallel overlapping edges are
#: found by the vertex–edge search instead.
_PARALLEL_SIN2 = 1e-12
#: A cluster is projected on the coordinate plane that drops the dominant axis of one of its
#: normals; every triangle's normal must keep at least this share of its length on that axis
#: (a unit normal's largest component is at least 1/√3 ≈ 0.58, and the triangles of a cluster are
#: parallel up to the tolerance over their size), else the cluster is not one plane.
_PROJECTION_SHARE = 0.5


def snap(A: Operand, B: Operand, I: np.ndarray, J: np.ndarray, eps: float) -> tuple[Operand, Operand, bool]:
    """Make the near-coincidences of near-coplanar triangles exact coincidences, moving nothing by more than ``eps``.

    Faces that coincide only up to rounding (two boxes sharing a face, turned by the same
    rotation) are *not* coplanar for the exact predicates: the triangles of A and of B on the
    shared face are hinged at angles of ``1e-16`` or cross each other, and the exact result has
    cracks and slivers of the size of the rounding error, some of them touching its boundary
    (an edge of four triangles), which no clean-up of the rounded result can repair.  Within
    the tolerance those faces are one face, so before the exact arrangement the triangles of
    both meshes on such a face are replaced by **one common triangulation**:

    1. *Clusters.*  The candidate pairs coplanar within ``eps`` (every corner of one triangle
       within ``eps`` of the other's plane) are the links of a graph on the triangles of A and
       B; its connected components are the clusters (a shared face and the triangles of both
       meshes on it).
    2. *Points.*  A vertex of B within ``eps`` of a vertex of A becomes that vertex (it takes
       the A vertex's coordinates, bit for bit).  Two cluster edges, one of each mesh, passing
       within ``eps`` of each other at interior points (farther than ``eps`` from their ends)
       give one new point, the nearest point on A's edge.
    3. *Edge chains.*  Every edge of a cluster triangle passes through every point of the
       other mesh (vertex or new point) within ``eps`` of its interior, in order along it
       (snap rounding with discs of radius ``eps`` as the hot pixels: Hobby, "Practical segment
       intersection with finite precision output", CGTA 13, 1999).  A point within ``eps`` of
       an edge's end that is not that end gives up (a feature below the tolerance).
    4. *Common triangulation.*  Each cluster where step 2 or 3 found something, or where a
       point of one mesh lies inside a triangle of the other, is projected on the coordinate
       plane dropping the dominant axis of its normal (exact: a coordinate is dropped) and
       triangulated once, by the constrained Delaunay triangulation
       (:class:`coons.topology._cdt.ConstrainedDelaunay`) of all its points with all its edge
       chains as constraints.  A triangle of A takes the triangles of the region its three
       chains enclose (the connected component of the triangulation cut at A's chains on the
       left of its boundary, found combinatorially and checked: one region per triangle, closed,
       not on both sides of its boundary), and so does each triangle of B.  Where the faces
       overlap both meshes therefore take the *same* triangles on bit-identical points, so the
       exact predicates find them coplanar and the ``ON`` classification applies.
    5. *Neighbours.*  A triangle outside the re-triangulated clusters whose edge gained points
       (the side face of a box next to its shared face) is triangulated again inside its own
       boundary, so that the mesh stays closed.

    The passes repeat (new points of one cluster may lie on the edges of another) until one
    finds nothing, at most ``_SNAP_PASSES`` times.  Every vertex of a new triangle lies within
    ``eps`` of the plane of the triangle it replaces (checked), and each mesh stays closed.
    The decisions here are float tests against ``eps``; they choose the *input* of the exact
    arrangement, whose decisions stay exact.  Local insertions (a point into each mesh per
    round, spokes to the opposite corners: the rules this replaces) can cascade, the spokes of
    one mesh crossing the other's edges at new points ever closer to a corner; the common
    triangulation has no spokes (where the meshes overlap, every new edge is an edge of both),
    so a second pass normally finds nothing.

    Should the passes not settle, a step above give up, or a new triangle be of height at most
    ``eps``, the operands are returned unchanged (the exact arrangement then works on the raw
    inputs, as it always can); the reason is logged on ``logging.getLogger("coons")`` (debug).

    Parameters
    ----------
    A, B : Operand
    I, J : (k,) int64
        Candidate triangle pairs of the broad phase for ``A``, ``B``.
    eps : float
        The linear tolerance.

    Returns
    -------
    (A, B, changed): the snapped operands, and whether anything changed (the candidate pairs
    must then be recomputed).
    """
    from coons.booleans._broad_phase import triangle_pairs

    PA, TA, FA = A.P, A.T, A.face
    PB, TB, FB = B.P, B.T, B.face
    freshA = np.zeros(TA.shape[0], dtype=bool)
    freshB = np.zeros(TB.shape[0], dtype=bool)
    changed = False
    try:
        for _ in range(_SNAP_PASSES):
            I, J = _near_coplanar(PA, TA, PB, TB, I, J, eps)
            if I.size == 0:
                break
            step = _snap_pass(PA, TA, FA, freshA, PB, TB, FB, freshB, I, J, eps)
            if step is None:
                break
            PA, TA, FA, freshA, PB, TB, FB, freshB = step
            changed = True
            I, J = triangle_pairs(PA, TA, PB, TB)
        else:
            raise BooleanError(f"the near-coincidences did not settle in {_SNAP_PASSES} passes", stage="snap")
        if not changed:
            return A, B, False
        out = []
        for P, T, F, fresh, name in ((PA, TA, FA, freshA, "A"), (PB, TB, FB, freshB, "B")):
            C = P[T[fresh]]
            longest = np.linalg.norm(C - C[:, [1, 2, 0]], axis=2).max(axis=1)
            area2 = np.linalg.norm(np.cross(C[:, 1] - C[:, 0], C[:, 2] - C[:, 0]), axis=1)
            low = area2 <= eps * longest
            if np.any(low):  # a new triangle of height <= eps: a feature below the tolerance
                raise BooleanError(f"operand {name}: {int(low.sum())} new triangles of height <= {eps:g}",
                                   stage="snap", diagnostics={"operand": name})
            used, inv = np.unique(T, return_inverse=True)
            out.append(operand(P[used], inv.reshape(-1, 3), F, name))
    except BooleanError as exc:  # not snapped: the raw inputs, whose exact arrangement always exists
        _log.debug("snap: operands left as they are: %s", exc)
        return A, B, False
    return out[0], out[1], True


def _near_coplanar(PA, TA, PB, TB, I, J, eps) -> tuple[np.ndarray, np.ndarray]:
    """The candidate pairs ``(I, J)`` whose triangles are coplanar within ``eps`` (float test, either way round)."""
    # np.take row gathers: several times faster than PA[TA[I]] (numpy 2.4)
    CA = np.take(PA, np.take(TA, I, axis=0).ravel(), axis=0).reshape(-1, 3, 3)
    CB = np.take(PB, np.take(TB, J, axis=0).ravel(), axis=0).reshape(-1, 3, 3)
    keep = np.zeros(I.size, dtype=bool)
    for C, D in ((CA, CB), (CB, CA)):
        n = np.cross(C[:, 1] - C[:, 0], C[:, 2] - C[:, 0])
        with np.errstate(invalid="ignore", divide="ignore"):
            n /= np.linalg.norm(n, axis=1)[:, None]
            R = D - C[:, :1]  # the three products summed explicitly: einsum("ikj,ij->ik") is slower here
            h = np.abs(R[:, :, 0] * n[:, None, 0] + R[:, :, 1] * n[:, None, 1] + R[:, :, 2] * n[:, None, 2]).max(axis=1)
        keep |= h <= eps
    return I[keep], J[keep]


def _unique_edges(E: np.ndarray, n) -> np.ndarray:
    """The distinct undirected edges ``(k, 2)`` (smaller id first, sorted) of triangles ``(m, 3)`` or of
    edges ``(m, 2)`` over ids below ``n`` (one integer key per edge: far faster than ``unique(axis=0)``)."""
    if E.shape[1] == 3:
        E = np.stack([E, E[:, [1, 2, 0]]], axis=2).reshape(-1, 2)
    n = np.int64(n)
    key = np.unique(np.minimum(E[:, 0], E[:, 1]) * n + np.maximum(E[:, 0], E[:, 1]))
    return np.stack([key // n, key % n], axis=1)


def _snap_pass(PA, TA, FA, freshA, PB, TB, FB, freshB, I, J, eps):
    """One pass of :func:`snap` over the near-coplanar pairs ``(I, J)``: the new operand arrays, or None
    when there is nothing to snap.  Raises ``BooleanError(stage="snap")`` where it gives up.

    Points are named by *global ids*: vertex ``v`` of A is ``v``, vertex ``w`` of B is ``nA + w``
    (or the A vertex it is merged with), the new points of the edge crossings follow from
    ``nA + nB``; ``G`` holds their coordinates.
    """
    from coons.booleans._broad_phase import box_pairs

    nA, nB, mA, mB = PA.shape[0], PB.shape[0], TA.shape[0], TB.shape[0]
    # 1. B vertices onto A vertices (the cluster vertices of both, paired by boxes of half-width eps).
    ua, ub = np.unique(TA[I]), np.unique(TB[J])
    i, j = box_pairs(PA[ua] - eps, PA[ua] + eps, PB[ub], PB[ub])
    d = np.linalg.norm(PA[ua[i]] - PB[ub[j]], axis=1)
    near = d <= eps
    va, vb, d = ua[i[near]], ub[j[near]], d[near]
    if np.unique(va).size != va.size or np.unique(vb).size != vb.size:
        raise BooleanError("a vertex lies within the tolerance of two vertices of the other operand", stage="snap")
    gidB = nA + np.arange(nB)
    gidB[vb] = va
    moved = d > 0
    if np.any(moved):
        PB = PB.copy()
        PB[vb[moved]] = PA[va[moved]]
        moved_v = np.zeros(nB, dtype=bool)
        moved_v[vb[moved]] = True
        freshB = freshB | np.any(moved_v[TB], axis=1)
    G = np.concatenate([PA, PB])
    # 2. Crossings of a cluster edge of A and one of B within eps of each other, away from their ends.
    EA, EB = _unique_edges(TA[I], nA), _unique_edges(TB[J], nB)
    a0, a1, b0, b1 = PA[EA[:, 0]], PA[EA[:, 1]], PB[EB[:, 0]], PB[EB[:, 1]]
    i, j = box_pairs(np.minimum(a0, a1) - eps, np.maximum(a0, a1) + eps, np.minimum(b0, b1), np.maximum(b0, b1))
    X = _edge_crossings(a0[i], a1[i], b0[j], b1[j], eps)
    G = np.concatenate([G, X])
    NG = np.int64(G.shape[0])
    in_b = np.zeros(G.shape[0], dtype=bool)
    in_b[gidB] = True
    in_a = np.zeros(G.shape[0], dtype=bool)
    in_a[:nA] = True
    TBg = gidB[TB]
    # 3. Edge chains: every cluster edge through the points of the other mesh within eps of it (an A
    # edge and a B edge with the same ends share one chain: the union of both searches).
    Q = np.unique(np.concatenate([ua, gidB[ub], nA + nB + np.arange(X.shape[0])]))
    edges = (EA, _unique_edges(gidB[EB], NG))
    found = []
    for name, Eg, own in (("A", edges[0], in_a), ("B", edges[1], in_b)):
        e, q, s = _edge_hits(G, Eg, Q[~own[Q]], eps, name)
        found.append(np.stack([Eg[e, 0] * NG + Eg[e, 1], q], axis=1) if e.size else np.zeros((0, 2), np.int64))
    found = np.concatenate(found)
    found = found[np.lexsort((found[:, 1], found[:, 0]))]  # by edge key, then point
    hits = found[np.r_[True, np.any(found[1:] != found[:-1], axis=1)]] if found.size else found
    chains = {}
    keys, start = np.unique(hits[:, 0], return_index=True)
    for key, pts in zip(keys.tolist(), np.split(hits[:, 1], start[1:])):  # the edges that gained points: few
        a, b = divmod(key, int(NG))
        ab = G[b] - G[a]
        pts = pts[np.argsort((G[pts] - G[a]) @ ab, kind="stable")]
        gaps = np.linalg.norm(np.diff(G[np.concatenate([[a], pts, [b]])], axis=0), axis=1)
        if np.any(gaps <= eps):
            raise BooleanError("two points within the tolerance of each other on one edge", stage="snap",
                               diagnostics={"edge": (a, b), "gap": float(gaps.min())})
        chains[key] = pts
    keys = np.fromiter(chains, dtype=np.int64, count=len(chains))
    hit_edges = [Eg[np.isin(Eg[:, 0] * NG + Eg[:, 1], keys)] for Eg in edges]
    # 4. Points of the other mesh inside a cluster triangle (not on its edges).
    inner = [_inner_hits(G, TA, I, Q[~in_a[Q]], eps), _inner_hits(G, TBg, J, Q[~in_b[Q]], eps)]
    # Clusters: components of the near-coplanar pairs on the triangles of A (0..mA-1) and B (mA..).
    links = coo_matrix((np.ones(I.size), (I, mA + J)), shape=(mA + mB, mA + mB))
    _, label = connected_components(links, directed=False)
    member = np.zeros(mA + mB, dtype=bool)
    member[I] = True
    member[mA + J] = True
    work = np.zeros(mA + mB, dtype=bool)
    touched = []  # triangles with an edge that gained points, per mesh
    for which, (T, hit) in enumerate(((TA, hit_edges[0]), (TBg, hit_edges[1]))):
        t = _triangles_of_edges(T, hit, NG)
        touched.append(t)
        work[which * mA + t] = True
        work[which * mA + inner[which]] = True
    work &= member
    work_clusters = np.unique(label[work])
    if work_clusters.size == 0:
        if not np.any(moved):
            return None
        return PA, TA, FA, freshA, PB, TB, FB, freshB
    # 5. One common triangulation per cluster with work, then the neighbours whose edges gained points.
    in_work = np.isin(label, work_clusters) & member
    new = [[], []]  # per mesh: (source triangle of each (k,), (k, 3) global-id triangles)
    order = np.argsort(label[in_work], kind="stable")
    nodes = np.flatnonzero(in_work)[order]
    bounds = np.flatnonzero(np.diff(label[nodes])) + 1
    for group in np.split(nodes, bounds):
        ta, tb = group[group < mA], group[group >= mA] - mA
        for which, src, tris in _common_triangulation(G, TA, ta, TBg, tb, chains, NG):
            new[which].append((src, tris))
    for which, T in enumerate((TA, TBg)):
        rest = np.setdiff1d(touched[which], np.flatnonzero(in_work[which * mA: which * mA + T.shape[0]]))
        for t in rest.tolist():
            tris = _retriangulated(G, T[t], chains, NG)
            new[which].append((np.full(tris.shape[0], t), tris))
    return _assembled(G, nA, nB, gidB, (PA, TA, FA, freshA), (PB, TB, FB, freshB), new, eps)


def _edge_crossings(p0, p1, q0, q1, eps) -> np.ndarray:
    """Points ``(k, 3)`` where edges ``p0 p1`` (of A) and ``q0 q1`` (of B) pass within ``eps`` of each other
    at interior points farther than ``eps`` from all four ends: the nearest point on A's edge."""
    d1, d2 = p1 - p0, q1 - q0
    r = p0 - q0
    aa, cc_, bb = (np.einsum("ij,ij->i", x, y) for x, y in ((d1, d1), (d2, d2), (d1, d2)))
    c, f = np.einsum("ij,ij->i", d1, r), np.einsum("ij,ij->i", d2, r)
    den = aa * cc_ - bb * bb
    ok = den > _PARALLEL_SIN2 * aa * cc_
    with np.errstate(invalid="ignore", divide="ignore"):
        s = np.where(ok, (bb * f - c * cc_) / den, -1.0)
        t = np.where(ok, (aa * f - bb * c) / den, -1.0)
    X = p0 + s[:, None] * d1
    Y = q0 + t[:, None] * d2
    ok &= (s > 0) & (s < 1) & (t > 0) & (t < 1) & (np.linalg.norm(X - Y, axis=1) <= eps)
    for end in (p0, p1, q0, q1):
        ok &= np.linalg.norm(X - end, axis=1) > eps
    return X[ok]


def _edge_hits(G, E, cand, eps, name):
    """The points ``cand`` (global ids) within ``eps`` of the interior of edges ``E (k, 2)``: ``(edge row, id,
    parameter)``.  Raises for a point within ``eps`` of an edge's end (it should have been that end)."""
    from coons.booleans._broad_phase import box_pairs

    a, b = G[E[:, 0]], G[E[:, 1]]
    e, k = box_pairs(np.minimum(a, b) - eps, np.maximum(a, b) + eps, G[cand], G[cand])
    q = cand[k]
    a, b, x = a[e], b[e], G[q]
    ab = b - a
    with np.errstate(invalid="ignore", divide="ignore"):  # a zero-length edge gives NaN: no match
        s = np.einsum("ij,ij->i", x - a, ab) / np.einsum("ij,ij->i", ab, ab)
    hit = (s > 0) & (s < 1) & (np.linalg.norm(a + s[:, None] * ab - x, axis=1) <= eps)
    end = hit & ((np.linalg.norm(x - a, axis=1) <= eps) | (np.linalg.norm(x - b, axis=1) <= eps))
    if np.any(end):
        w = int(np.flatnonzero(end)[0])
        raise BooleanError(f"operand {name}: a point of the other operand lies within the tolerance of the end of "
                           f"an edge without being that end", stage="snap",
                           diagnostics={"edge": E[e[w]].tolist(), "point": x[w].tolist()})
    return e[hit], q[hit], s[hit]


def _inner_hits(G, T, tris, cand, eps) -> np.ndarray:
    """The triangles ``tris`` (rows of ``T``, global ids) with one of the points ``cand`` within ``eps`` of
    their plane and farther than ``eps`` inside each of their edges."""
    from coons.booleans._broad_phase import box_pairs

    tris = np.unique(tris)
    C = G[T[tris]]
    t, k = box_pairs(C.min(axis=1) - eps, C.max(axis=1) + eps, G[cand], G[cand])
    C, q = C[t], G[cand[k]]
    n = np.cross(C[:, 1] - C[:, 0], C[:, 2] - C[:, 0])
    with np.errstate(invalid="ignore", divide="ignore"):  # degenerate triangles give NaN: no match
        n /= np.linalg.norm(n, axis=1)[:, None]
        ok = np.abs(np.einsum("ij,ij->i", q - C[:, 0], n)) <= eps
        for j in range(3):
            side = np.cross(n, C[:, (j + 1) % 3] - C[:, j])
            side /= np.linalg.norm(side, axis=1)[:, None]
            ok &= np.einsum("ij,ij->i", q - C[:, j], side) > eps
    return np.unique(tris[t[ok]])


def _triangles_of_edges(T: np.ndarray, E: np.ndarray, NG) -> np.ndarray:
    """Rows of ``T`` with one of the undirected edges ``E (k, 2)`` (smaller id first)."""
    if E.shape[0] == 0:
        return np.zeros(0, dtype=np.int64)
    S = np.sort(np.stack([T, T[:, [1, 2, 0]]], axis=2), axis=2)
    key = S[:, :, 0] * NG + S[:, :, 1]
    return np.flatnonzero(np.isin(key, E[:, 0] * NG + E[:, 1]).any(axis=1))


def _chain(a: int, b: int, chains: dict, NG) -> list[int]:
    """The points from ``a`` to ``b`` along the edge ``ab`` (its ends included)."""
    if a < b:
        pts = chains.get(a * NG + b)
        return [a, b] if pts is None else [a, *pts.tolist(), b]
    pts = chains.get(b * NG + a)
    return [a, b] if pts is None else [a, *pts[::-1].tolist(), b]


def _boundary_chains(tri: np.ndarray, chains: dict, NG) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The closed boundary of each triangle ``tri (k, 3)`` through the points its edges gained, in array time.

    Returns ``(owner, tail, head)``: one directed segment per row, in each triangle's order (its
    corners, each followed by the points of ``chains`` on the edge to the next corner), ``owner``
    its triangle.  ``chains`` maps ``min · NG + max`` of an edge to its inner points from the
    smaller end (:func:`_chain` for one edge).
    """
    k = tri.shape[0]
    a, b = tri.ravel(), next_corners(tri)  # the directed edges, triangle by triangle
    if not chains:
        return np.repeat(np.arange(k), 3), a, b
    keys = np.array(sorted(chains), dtype=np.int64)
    vals = [np.asarray(chains[int(x)], dtype=np.int64) for x in keys.tolist()]
    ptr = np.concatenate([[0], np.cumsum([v.size for v in vals], dtype=np.int64)])
    flat = np.concatenate(vals) if vals else np.zeros(0, dtype=np.int64)
    ek = np.minimum(a, b) * NG + np.maximum(a, b)
    pos = np.searchsorted(keys, ek)
    found = pos < keys.size
    found[found] = keys[pos[found]] == ek[found]
    pos = np.where(found, pos, 0)
    count = np.where(found, ptr[pos + 1] - ptr[pos], 0)
    n_out = 1 + count  # the tail corner, then the edge's inner points
    e = np.repeat(np.arange(ek.size), n_out)
    j = np.arange(e.size) - np.repeat(np.cumsum(n_out) - n_out, n_out)
    tail = a[e]
    m = np.flatnonzero(j > 0)  # inner points, in the edge's direction
    em, jm = e[m], j[m]
    tail[m] = flat[np.where(a[em] < b[em], ptr[pos[em]] + jm - 1, ptr[pos[em]] + count[em] - jm)]
    owner = e // 3
    per = np.bincount(owner, minlength=k)
    first = np.cumsum(per) - per
    nxt = np.arange(1, e.size + 1)
    nxt[first + per - 1] = first
    return owner, tail, tail[nxt]


def _frame(C: np.ndarray) -> tuple[int, np.ndarray]:
    """Dominant axis of the normals of triangles ``C (k, 3, 3)`` and each triangle's orientation sign in the
    projection dropping it (coordinates ``axis + 1, axis + 2`` cyclically: counter-clockwise when the
    normal's ``axis`` component is positive).  Raises when the triangles are not near one plane."""
    n = np.cross(C[:, 1] - C[:, 0], C[:, 2] - C[:, 0])
    length = np.linalg.norm(n, axis=1)
    axis = int(np.argmax(np.abs(n[int(np.argmax(length))])))
    if np.any(np.abs(n[:, axis]) < _PROJECTION_SHARE * length) or np.any(length == 0):
        raise BooleanError("a cluster of near-coplanar triangles is not near one plane", stage="snap")
    return axis, np.sign(n[:, axis]).astype(np.int64)


def _common_triangulation(G, TA, ta, TB, tb, chains, NG):
    """One constrained Delaunay triangulation of a cluster (A triangles ``ta``, B triangles ``tb``, rows of
    ``TA``, ``TB`` in global ids); yields ``(which, source triangle of each (k,), triangles (k, 3))`` per
    mesh: each triangle of the cluster replaced by the triangles of the region its edge chains enclose."""
    from coons.topology._cdt import ConstrainedDelaunay

    tri = np.concatenate([TA[ta], TB[tb]])
    axis, sign = _frame(G[tri])
    # The directed boundary chain of every triangle, counter-clockwise in the projection.
    owner, tail, head = _boundary_chains(np.where((sign > 0)[:, None], tri, tri[:, ::-1]), chains, NG)
    ids, inv = np.unique(np.concatenate([tail, head]), return_inverse=True)
    tail, head = inv[:tail.size], inv[tail.size:]
    n = np.int64(ids.size)
    segs = np.unique(np.minimum(tail, head) * n + np.maximum(tail, head))
    P2 = G[ids][:, [(axis + 1) % 3, (axis + 2) % 3]]
    try:
        T2 = ConstrainedDelaunay(P2, np.stack([segs // n, segs % n], axis=1)).triangles(return_all=True)
    except (InvalidInputError, ConvergenceError) as exc:
        raise BooleanError(f"the common triangulation of a cluster failed: {exc}", stage="snap") from exc
    m2 = T2.shape[0]
    half = (T2 * n + T2[:, [1, 2, 0]]).ravel()  # directed half-edges a -> b, the triangle on their left
    order = np.argsort(half)
    sh = half[order]

    def left_of(keys):
        pos = np.minimum(np.searchsorted(sh, keys), sh.size - 1)
        return np.where(sh[pos] == keys, order[pos] // 3, -1)

    nbr = left_of((T2[:, [1, 2, 0]] * n + T2).ravel())  # the triangle across each half-edge, -1 on the hull
    und = (np.minimum(T2, T2[:, [1, 2, 0]]) * n + np.maximum(T2, T2[:, [1, 2, 0]])).ravel()
    half_tri = np.repeat(np.arange(m2), 3)
    for which, rows in ((0, np.arange(ta.size)), (1, ta.size + np.arange(tb.size))):
        if rows.size == 0:
            continue
        mine = np.isin(owner, rows)
        o, a, b = owner[mine], tail[mine], head[mine]
        # Regions: components of the triangulation cut at this mesh's chains; each triangle's region lies
        # on the left of its directed chains, and must be one closed region, never on both sides of them.
        cut = np.isin(und, np.minimum(a, b) * n + np.maximum(a, b))
        link = ~cut & (nbr >= 0)
        g = coo_matrix((np.ones(int(link.sum())), (half_tri[link], nbr[link])), shape=(m2, m2))
        _, comp = connected_components(g, directed=False)
        leaks = np.zeros(m2, dtype=bool)
        leaks[comp[half_tri[~cut & (nbr < 0)]]] = True
        left, right = left_of(a * n + b), left_of(b * n + a)
        region = np.full(tri.shape[0], -1, dtype=np.int64)
        if np.all(left >= 0):
            region[o] = comp[left]  # any one: all are checked against it below
        c = region[o]
        bad = ((left < 0) | (comp[left] != c) | leaks[c] | ((right >= 0) & (comp[right] == c)))
        regions = region[rows]
        if np.any(bad) or np.unique(regions).size != rows.size:
            raise BooleanError("the edge chains of a triangle do not enclose one region of the common triangulation "
                               "of its cluster", stage="snap", diagnostics={"operand": "AB"[which]})
        of_region = np.full(m2, -1, dtype=np.int64)
        of_region[regions] = rows
        r = of_region[comp]
        take = np.flatnonzero(r >= 0)
        out = ids[T2[take]]
        flip = sign[r[take]] < 0
        out[flip] = out[flip][:, ::-1]
        src = (ta if which == 0 else tb)[r[take] - (0 if which == 0 else ta.size)]
        yield which, src, out


def _retriangulated(G, corners, chains, NG) -> np.ndarray:
    """Triangles ``(k, 3)`` (global ids, the orientation of ``corners``) of one triangle whose edges gained points."""
    c = corners.tolist()
    loop = []
    for k in range(3):
        loop += _chain(c[k], c[(k + 1) % 3], chains, NG)[:-1]
    axis, sign = _frame(G[np.asarray(c)][None])
    if sign[0] < 0:
        loop = loop[::-1]
    ids = np.asarray(loop)
    P2 = G[ids][:, [(axis + 1) % 3, (axis + 2) % 3]]
    segs = np.stack([np.arange(ids.size), np.roll(np.arange(ids.size), -1)], axis=1)
    try:
        T2 = triangulate(P2, segs)
    except (InvalidInputError, ConvergenceError) as exc:
        raise BooleanError(f"a triangle whose edges gained points cannot be re-triangulated: {exc}",
                           stage="snap") from exc
    out = ids[T2]
    return out[:, ::-1] if sign[0] < 0 else out


def _assembled(G, nA, nB, gidB, a, b, new, eps):
    """The operand arrays after a pass: the replaced triangles removed, the new ones appended (their new
    points appended to each mesh's vertices).  Raises when a new vertex lies farther than ``eps`` from the
    plane of the triangle it replaces."""
    out = []
    for which, (P, T, F, fresh) in enumerate((a, b)):
        items = new[which]
        if not items:
            out += [P, T, F, fresh]
            continue
        src = np.concatenate([s for s, _ in items])
        tris = np.concatenate([t for _, t in items])
        Tg = T if which == 0 else gidB[T]
        C = G[Tg[src]]
        nrm = np.cross(C[:, 1] - C[:, 0], C[:, 2] - C[:, 0])
        nrm /= np.linalg.norm(nrm, axis=1)[:, None]
        off = np.abs(np.einsum("ikj,ij->ik", G[tris] - C[:, :1], nrm)).max()
        if not off <= eps:
            raise BooleanError(f"operand {'AB'[which]}: a snapped vertex lies {off:.3g} off the surface "
                               f"(tolerance {eps:g})", stage="snap")
        local = np.full(G.shape[0], -1, dtype=np.int64)
        if which == 0:
            local[:nA] = np.arange(nA)
        else:
            local[gidB] = np.arange(nB)
        extra = np.unique(tris[local[tris] < 0])
        local[extra] = P.shape[0] + np.arange(extra.size)
        keep = np.ones(T.shape[0], dtype=bool)
        keep[src] = False
        out += [np.concatenate([P, G[extra]]), np.concatenate([T[keep], local[tris]]),
                np.concatenate([F[keep], F[src]]), np.concatenate([fresh[keep], np.ones(tris.shape[0], dtype=bool)])]
    return tuple(out)
