"""Watertight tessellation of B-reps: every edge discretised once, every face triangulated against those points.

:func:`tessellate` turns a :class:`~coons.topology.shape.Solid` (or a
:class:`~coons.topology.brep.BRep`) into a :class:`~coons.topology.mesh.TriangleMesh` whose
triangles are oriented outward and whose every vertex lies on the exact geometry.  The mesh
is closed and edge-manifold *by construction*: the two faces of an edge use the very same
mesh vertices along it, so no stitching or vertex welding is ever done.  Chordal deviation
and normal turning are bounded by ``deflection`` and ``angular_deflection`` (as OCCT's
``BRepMesh_IncrementalMesh``; deflection is a resolution, never a tolerance).  It does not
heal invalid B-reps, smooth or decimate, produce quad meshes, or guarantee triangle quality
beyond what the Delaunay criterion gives.

Algorithm (the BRepMesh idea, made watertight by construction)
--------------------------------------------------------------
1. **Edges.**  Each edge gets increasing parameters ``t`` along its 3-D curve: 2 for straight
   edges and lines; ``ceil(sweep / min(θ, 2 acos(1 − d / R)))`` equal steps for circles (never
   more than a quarter turn per chord, so that every boundary polygon has an area); for
   other curves an adaptive bisection (vectorised over all intervals of the edge) until the
   chord's midpoint deviation is at most ``d``, the turning angle between consecutive chords
   at most ``θ``, and — for p-curves that are not straight lines on non-planar faces — the
   midpoint of the straight parameter-space chord maps onto the surface within ``d`` of the
   line of the 3-D chord.  B-rep vertices become mesh vertices ``0 .. V-1``; edge samples
   follow.
2. **Face boundaries.**  Each loop is walked in order; a coedge contributes its edge's samples
   mapped through its own p-curve (reversed for right sides).  Where consecutive p-curves
   end and start at different parameter points (a sphere's pole, a cone's apex: see
   ``docs/brep.md``) both points are kept and joined by a *gap segment*; both carry the
   same mesh vertex, so the one triangle on the gap degenerates and is dropped, which is an
   edge collapse of the parameter-space triangulation onto the pole.  Implicit planes
   (``face_surface == -1``) use coordinates in their Newell plane.
3. **Interior points.**  A grid over the face's parameter box, spaced by the surface's
   curvature: with the second fundamental form ``L, M, N`` (normal components of ``Suu``,
   ``Suv``, ``Svv``) sampled over the face, ``h_u = min(sqrt(8 d_u / (|L| + |M|)), θ / |n_u|)``
   and likewise ``h_v`` (minima over the samples).  The linear interpolation error of a
   quadratic on a grid cell is ``(L h_u² + N h_v²) / 8`` at the midpoint of either diagonal,
   so ``d_u = d_v = d / 2`` when both directions are curved and ``d`` otherwise, both times
   a margin of 0.8 that leaves the grid's own triangles clear of refinement.  A direction
   without curvature gets no grid lines (planes, and the rulings of cylinders and cones, need
   none).  Grid points closer to the boundary than half the local boundary spacing (or half
   the grid spacing) are dropped.
4. **Triangulation** with the constrained Delaunay triangulator of :mod:`coons.topology._cdt`
   (which never inserts a point on a boundary segment), keeping the triangles left of the
   loops, in the plane ``(u / h_u, v / h_v)`` where the grid cells are unit squares: Delaunay
   triangles are then well shaped for the curvature, the metric that decides the deflection
   (a direction without curvature is scaled by the mean ``|Su|``, ``|Sv|`` instead).
5. **Refinement.**  Each triangle's deviation is estimated from the distance of its centroid
   to the surface, times 9/8 when the triangle is acute in the metric of the second
   fundamental form, and the distances of the midpoints of its interior edges: for a
   quadratic surface the error is largest at the circumcentre of an acute triangle (the
   centroid holds at least 8/9 of it) and at the longest edge's midpoint otherwise, and on
   saddles it lies on the edges; boundary edges are bounded by step 1.  Distances are exact
   for analytic surfaces (``implicit``) and found by a few Gauss–Newton steps for others.
   Offending triangles are split at the midpoint of their longest interior edge (Rivara's
   longest-edge bisection) or at their centroid, by Lawson insertion into the kept
   triangulation (or a new triangulation when many points come at once), at most
   :data:`MAX_REFINEMENTS` rounds.
6. **Orientation.**  When ``face_sense`` is False the parameter plane is mirrored before
   triangulating, so counter-clockwise triangles always map to outward normals.
7. **Chord conflicts.**  Sharing the edge samples makes every B-rep edge's mesh edges used
   once each way, but two faces that share two vertices not joined by a common edge (the
   two hemispheres of a very coarse sphere share both meridians) can both draw the chord
   between them, and a pole collapse can make one face draw a chord twice.  Such directed
   edges used twice are found in one sort; their faces get the chord midpoints as extra
   interior points and are triangulated again (at most ``_MAX_REPAIRS`` rounds; a result
   still not closed raises).

Polygonal faces (implicit planes or planar surfaces, with straight edges) skip steps 3–5:
triangles are emitted as they are and strictly convex polygons are fanned, both vectorised by
polygon size; other polygons (holes, non-convex) go through the constrained triangulator in
their plane.  A mesh-derived polyhedron therefore tessellates in numpy time.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from coons.errors import ConvergenceError, InvalidInputError, TopologyError
from coons.kernel.analytic import Circle, Line, PlanarSurface
from coons.kernel.pcurve import Line2D
from coons.tolerance import Tolerance, resolve
from coons.topology._cdt import ConstrainedDelaunay
from coons.topology.brep import BRep
from coons.topology.mesh import TriangleMesh

__all__ = ["tessellate", "edge_parameters", "MAX_REFINEMENTS"]

#: Re-triangulations per face in the refinement step before giving up with ConvergenceError.
MAX_REFINEMENTS = 12
#: Bisection rounds of the adaptive edge discretisation (each at most doubles the samples).
_MAX_EDGE_ROUNDS = 40
#: Largest turning angle of an edge chord whatever ``angular_deflection`` says (a half circle gets
#: at least two chords, so that every face's boundary polygon has an area).
_MAX_CHORD_TURN = 0.5 * math.pi
#: Refinement inserts its points into the kept triangulation (Lawson) when they are at most this
#: fraction of the face's points, and triangulates again from scratch (Qhull) otherwise.
_INSERT_FRACTION = 0.1
#: Rounds of chord-conflict repair (see ``_Builder.repair_conflicts``); one suffices in practice.
_MAX_REPAIRS = 4
#: Parameter samples per direction used to estimate a face's curvature (cell centres).
_CURVATURE_SAMPLES = 9
#: Relative parameter distance below which two p-curve ends are the same point (round-off of
#: the p-curve evaluation, far below any real pole gap).
_SAME_UV = 1e-10
#: Fraction of the deflection the interior grid aims at: a grid cell split by either diagonal
#: meets exactly its target in the quadratic model, so a margin keeps round-off and the
#: model's error from sending every grid triangle to refinement.
_GRID_MARGIN = 0.8


# ============================================================================ entry point
def tessellate(
    shape, deflection: float | None = None, angular_deflection: float = 0.5, tol: Tolerance | None = None
) -> TriangleMesh:
    """Closed, outward-oriented triangle mesh of a solid within a chordal deflection.

    Parameters
    ----------
    shape : Solid or BRep
    deflection : float, optional
        Largest distance between the mesh and the exact surfaces (model units); default
        ``1e-3`` times the diagonal of the exact bounding box.
    angular_deflection : float
        Largest turning angle (radians) between consecutive chords of an edge and, on
        faces, of the surface normal across a grid step (edge chords never turn more than
        π/2 whatever the value).
    tol : Tolerance, optional
        The model tolerance; ``deflection`` must exceed ``tol.linear``.

    Returns
    -------
    TriangleMesh
        ``vertices (n, 3)``: the B-rep vertices first (same order; a vertex no triangle uses,
        as a lone-vertex loop's, is left out), then edge samples, then face interior points,
        every one on the exact geometry; ``triangles (m, 3)`` oriented outward;
        ``face_ids (m,)``: the B-rep face of each triangle.

    Raises
    ------
    InvalidInputError
        Not a Solid or BRep; a deflection that is not a finite number above ``tol.linear``
        (also the default one, for a tiny solid); an angular deflection outside ``(0, π]``.
    TopologyError
        A face whose boundary cannot be triangulated (an edge side without p-curve on a
        non-planar face, crossing loops), or a result that is not closed (which a valid
        B-rep never gives).
    ConvergenceError
        Refinement did not reach the deflection within :data:`MAX_REFINEMENTS` rounds, or an
        edge's bisection within ``_MAX_EDGE_ROUNDS``.

    Examples
    --------
    >>> from coons.topology.primitives import Cylinder
    >>> mesh = tessellate(Cylinder(1.0, 2.0), deflection=1e-3)
    >>> area = 6 * np.pi  # the volume error is at most deflection × area
    >>> bool(mesh.is_closed), bool(0 < 2 * np.pi - mesh.volume <= 1e-3 * area)
    (True, True)
    """
    t = resolve(tol)
    b = _as_brep(shape)
    d = _resolve_deflection(b, deflection, t)
    a = _as_float(angular_deflection, "angular_deflection")
    if not (math.isfinite(a) and 0.0 < a <= math.pi):
        raise InvalidInputError(f"angular_deflection must lie in (0, π], got {angular_deflection!r}")
    ctx = _Builder(b, d, a, t)
    ctx.discretise_edges()
    ctx.triangulate_faces()
    for _ in range(_MAX_REPAIRS):
        if not ctx.repair_conflicts():
            break
    mesh = ctx.mesh()
    if b.n_faces and not mesh.is_closed:
        bad = mesh.boundary_edges()
        raise TopologyError(
            f"tessellation is not closed: {bad.shape[0]} directed edge(s) without a twin, e.g. {bad[:3].tolist()} "
            "(the B-rep is probably invalid; run check())"
        )
    return mesh


def _as_brep(shape) -> BRep:
    if isinstance(shape, BRep):
        return shape
    b = getattr(shape, "brep", None)
    if isinstance(b, BRep):
        return b
    raise InvalidInputError(f"tessellate needs a Solid or a BRep, got {type(shape).__name__}")


def _as_float(value, name: str) -> float:
    if isinstance(value, bool):
        raise InvalidInputError(f"{name} must be a number, got {value!r}")
    try:
        return float(value)
    except (TypeError, ValueError):
        raise InvalidInputError(f"{name} must be a number, got {value!r}") from None


def _resolve_deflection(b: BRep, deflection, t: Tolerance) -> float:
    if deflection is None:
        from coons.topology.mass import bounding_box

        box = bounding_box(b) if b.n_faces else np.zeros((2, 3))
        diag = float(np.linalg.norm(box[1] - box[0]))
        d = 1e-3 * diag
        if not d > t.linear:
            raise InvalidInputError(
                f"default deflection 1e-3 × bounding-box diagonal = {d:.3g} is not above the linear tolerance "
                f"{t.linear:g}; pass deflection="
            )
        return d
    d = _as_float(deflection, "deflection")
    if not (math.isfinite(d) and d > t.linear):
        raise InvalidInputError(
            f"deflection must be finite and greater than the linear tolerance {t.linear:g}, got {deflection!r}"
        )
    return d


# ============================================================================ edges
def edge_parameters(b: BRep, edge: int, deflection: float, angular_deflection: float) -> np.ndarray:
    """Increasing parameters ``(k,)`` along an edge, from ``edge_range[0]`` to ``edge_range[1]``.

    Closed form for straight edges, lines (both ends only) and circles (equal steps of
    ``min(θ, 2 acos(1 − d / R), π/2)``); adaptive bisection for every other curve, and for any edge
    with a curved p-curve on a non-planar face (see the module docstring).  A closed edge
    (both ends at one vertex) gets at least three segments.

    Raises
    ------
    ConvergenceError
        The bisection did not meet the criteria in ``_MAX_EDGE_ROUNDS`` rounds.
    """
    t0, t1 = (float(x) for x in b.edge_range[edge])
    ci = int(b.edge_curve[edge])
    curve = None if ci < 0 else b.curves[ci]
    closed = int(b.edge_vertex[edge, 0]) == int(b.edge_vertex[edge, 1])
    sides = _curved_sides(b, edge)
    # A chord never turns more than a quarter turn: a coarser polygon would not bound an area.
    a = min(angular_deflection, _MAX_CHORD_TURN)
    if curve is None or isinstance(curve, Line):
        t = np.array([t0, t1])
        exact = True
    elif isinstance(curve, Circle):
        R = curve.radius
        step = min(a, 2.0 * math.acos(max(1.0 - deflection / R, -1.0)))
        n = max(1, math.ceil((t1 - t0) / step * (1 - 1e-12)))
        t = np.linspace(t0, t1, n + 1)
        exact = True
    else:
        t = _initial_parameters(curve, t0, t1)
        exact = False
    if closed and t.size < 4:
        t = np.linspace(t0, t1, 4) if t.size <= 2 else np.union1d(t, 0.5 * (t[:-1] + t[1:]))
    if exact and not sides:
        return t
    return _bisect_edge(b, edge, curve, t, sides, deflection, a, check_curve=not exact)


def _curved_sides(b: BRep, edge: int) -> list[tuple[object, object]]:
    """``(pcurve, surface)`` of the sides whose straight parameter chords may leave the edge."""
    out = []
    for side in (0, 1):
        pi = int(b.edge_pcurve[edge, side])
        if pi < 0:
            continue
        pc = b.pcurves[pi]
        si = int(b.face_surface[int(b.edge_face[edge, side])])
        if si < 0:
            continue
        S = b.surfaces[si]
        if isinstance(pc, Line2D) or isinstance(S, PlanarSurface):
            continue  # straight in (u, v), or an affine (isometric) surface map
        out.append((pc, S))
    return out


def _initial_parameters(curve, t0: float, t1: float) -> np.ndarray:
    """Starting samples for the bisection: (degree + 1) per knot span of a NURBS, else 16 per full turn."""
    knots = getattr(curve, "knots", None)
    if knots is not None:
        p = int(getattr(curve, "degree", 3))
        k = np.unique(np.asarray(knots, dtype=np.float64))
        k = k[(k > t0) & (k < t1)]
        br = np.concatenate([[t0], k, [t1]])
        s = np.linspace(0.0, 1.0, p + 2)[:-1]
        t = (br[:-1, None] + (br[1:] - br[:-1])[:, None] * s).ravel()
        return np.append(t, t1)
    n = max(4, math.ceil(16 * (t1 - t0) / (2 * math.pi)))
    return np.linspace(t0, t1, n + 1)


def _edge_eval(b: BRep, edge: int, curve, t: np.ndarray) -> np.ndarray:
    if curve is None:
        return b.edge_points(edge, t)
    return curve.evaluate(t)


def _turning(a: np.ndarray, c: np.ndarray) -> np.ndarray:
    """Angles between vectors ``a`` and ``c`` (rows), 0 where either vanishes."""
    na, nc = np.linalg.norm(a, axis=-1), np.linalg.norm(c, axis=-1)
    dot = np.einsum("...i,...i->...", a, c)
    ok = (na > 0) & (nc > 0)
    cosang = np.divide(dot, na * nc, out=np.ones_like(dot), where=ok)
    return np.arccos(np.clip(cosang, -1.0, 1.0))


def _bisect_edge(b, edge, curve, t, sides, d, a, *, check_curve: bool) -> np.ndarray:
    for _ in range(_MAX_EDGE_ROUNDS):
        tm = 0.5 * (t[:-1] + t[1:])
        P = _edge_eval(b, edge, curve, t)
        Pm = _edge_eval(b, edge, curve, tm)
        bad = np.zeros(tm.shape, dtype=bool)
        if check_curve:
            bad |= np.linalg.norm(Pm - 0.5 * (P[:-1] + P[1:]), axis=1) > d
            # Turning inside each interval (half chords) and between consecutive chords.
            bad |= _turning(Pm - P[:-1], P[1:] - Pm) > a
            turn = _turning(P[1:-1] - P[:-2], P[2:] - P[1:-1]) > a
            bad[:-1] |= turn
            bad[1:] |= turn
        if sides:
            chord = P[1:] - P[:-1]
            length = np.linalg.norm(chord, axis=1, keepdims=True)
            unit = np.divide(chord, length, out=np.zeros_like(chord), where=length > 0)
        for pc, S in sides:
            # The straight (u, v) chord's midpoint must map within d of the 3-D chord's line
            # (its offset along the chord only reflects a different parametrisation).
            uv = pc.evaluate(t)
            mid = 0.5 * (uv[:-1] + uv[1:])
            w = S.evaluate(mid[:, 0], mid[:, 1]) - P[:-1]
            off = w - np.einsum("ij,ij->i", w, unit)[:, None] * unit
            bad |= np.linalg.norm(off, axis=1) > d
        if not bad.any():
            return t
        t = np.sort(np.concatenate([t, tm[bad]]))
    raise ConvergenceError(
        f"edge {edge}: discretisation did not reach deflection {d:g} / angle {a:g} in {_MAX_EDGE_ROUNDS} bisection rounds"
    )


# ============================================================================ faces
@dataclass
class _Boundary:
    """A face's boundary in its parameter plane: points, their mesh vertex ids, directed segments."""

    uv: np.ndarray  # (p, 2) unscaled parameters
    ids: np.ndarray  # (p,) mesh vertex ids
    segments: np.ndarray  # (s, 2) directed, region on the left when face_sense (or mirrored)


@dataclass
class _FaceMesh:
    """The triangulation of one face in its parameter plane."""

    T: np.ndarray  # (m, 3) local point indices, counter-clockwise in the triangulation plane
    uv: np.ndarray  # (p, 2) parameters of the local points
    ids: np.ndarray  # (p,) their mesh vertex ids
    fixed: set  # undirected local boundary segments (a, b), a < b
    extra: np.ndarray  # (q, 2) extra interior points given (chord repairs), kept for re-triangulation


class _Builder:
    """Accumulates mesh vertices and triangles while tessellating one B-rep."""

    def __init__(self, b: BRep, d: float, a: float, t: Tolerance) -> None:
        self.b, self.d, self.a, self.tol = b, d, a, t
        self.points: list[np.ndarray] = [b.vertex_point]
        self.n_points = b.n_vertices
        # Polyhedral faces triangled in bulk: (triangles (m, 3) mesh ids, faces (m,)).
        self.blocks: list[tuple[np.ndarray, np.ndarray]] = []
        # Faces triangulated one by one: their local triangulation (see _FaceMesh).
        self.faces: dict[int, _FaceMesh] = {}
        # Samples of the edges that need more than their two ends (others: the range and the vertices).
        self.edge_t: dict[int, np.ndarray] = {}
        self.edge_ids: dict[int, np.ndarray] = {}

    def point_array(self) -> np.ndarray:
        """All mesh vertices so far, ``(n, 3)`` (concatenated once, then cached)."""
        if len(self.points) > 1:
            self.points = [np.concatenate(self.points)]
        return self.points[0]

    def add_points(self, P: np.ndarray) -> np.ndarray:
        ids = np.arange(self.n_points, self.n_points + P.shape[0], dtype=np.int64)
        self.points.append(np.asarray(P, dtype=np.float64).reshape(-1, 3))
        self.n_points += P.shape[0]
        return ids

    def triangles(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """All triangles ``(m, 3)`` (mesh ids), their faces ``(m,)`` and each one's row in its face's local
        triangulation (-1: a bulk polyhedral face)."""
        Ts, Fs, Ls = [], [], []
        for T, F in self.blocks:
            keep = ~np.isin(F, list(self.faces)) if self.faces else np.ones(F.shape, dtype=bool)
            Ts.append(T[keep])
            Fs.append(F[keep])
            Ls.append(np.full(int(keep.sum()), -1, dtype=np.int64))
        for f, fm in self.faces.items():
            Ts.append(fm.ids[fm.T])
            Fs.append(np.full(fm.T.shape[0], f, dtype=np.int64))
            Ls.append(np.arange(fm.T.shape[0], dtype=np.int64))
        if not Ts:
            return np.zeros((0, 3), np.int64), np.zeros(0, np.int64), np.zeros(0, np.int64)
        return np.concatenate(Ts).reshape(-1, 3), np.concatenate(Fs), np.concatenate(Ls)

    def mesh(self) -> TriangleMesh:
        V = self.point_array()
        T, F, _ = self.triangles()
        # Drop unused points (grid points outside a face, interiors of re-triangulated faces), keeping the order.
        used = np.zeros(V.shape[0], dtype=bool)
        used[T.ravel()] = True
        remap = np.cumsum(used) - 1
        return TriangleMesh(V[used], remap[T], F)

    # ------------------------------------------------------------------ chord conflicts
    def repair_conflicts(self) -> bool:
        """Split chords that two triangles use in the same direction; returns False when there are none.

        Two faces that share two boundary vertices not joined by a shared edge (the two
        hemispheres of a coarse sphere share both meridians) can each draw the chord between
        them, and a collapsed pole gap can make a face draw one twice: the edge would be used
        by four triangles.  The offending chords get their midpoints as extra interior points
        of their faces, which are then triangulated again (boundary segments are never split).
        """
        T, F, local = self.triangles()
        if T.shape[0] == 0:
            return False
        n = np.int64(self.n_points)
        key = (T * n + T[:, [1, 2, 0]]).ravel()
        order = np.argsort(key, kind="stable")
        sk = key[order]
        dup = np.zeros(key.shape, dtype=bool)
        same = sk[1:] == sk[:-1]
        dup[order[1:][same]] = True
        dup[order[:-1][same]] = True
        if not np.any(dup):
            return False
        extra_uv: dict[int, list[np.ndarray]] = {}
        extra_xyz: dict[int, list[np.ndarray]] = {}
        V = self.point_array()
        for corner in np.flatnonzero(dup):
            t, j = divmod(int(corner), 3)
            f = int(F[t])
            if local[t] < 0:  # a bulk polyhedral face: re-triangulate it with the 3-D midpoint
                extra_xyz.setdefault(f, []).append(0.5 * (V[T[t, j]] + V[T[t, (j + 1) % 3]]))
                continue
            fm = self.faces[f]
            a, c = fm.T[local[t], j], fm.T[local[t], (j + 1) % 3]
            if (min(a, c), max(a, c)) in fm.fixed:
                continue  # a boundary segment: the chord of the other face gets split
            extra_uv.setdefault(f, []).append(0.5 * (fm.uv[a] + fm.uv[c]))
        for f in sorted(set(extra_uv) | set(extra_xyz)):
            fm = self.faces.get(f)
            uv = [fm.extra] if fm is not None else []
            uv += [np.reshape(x, (1, 2)) for x in extra_uv.get(f, [])]
            xyz = np.reshape(extra_xyz.get(f, []), (-1, 3))
            self._surface_face(f, np.unique(np.concatenate(uv + [np.zeros((0, 2))]), axis=0), xyz)
        return True

    # ------------------------------------------------------------------ step 1
    def discretise_edges(self) -> None:
        b = self.b
        # Straight edges without curved p-curves need only their ends: decided for all edges at once.
        simple = _straight_edges(b) & ~_curved_side_edges(b) & (b.edge_vertex[:, 0] != b.edge_vertex[:, 1])
        for e in np.flatnonzero(~simple):
            e = int(e)
            t = edge_parameters(b, e, self.d, self.a)
            ci = int(b.edge_curve[e])
            inner = t[1:-1]
            P = _edge_eval(b, e, None if ci < 0 else b.curves[ci], inner) if inner.size else np.zeros((0, 3))
            ids = np.concatenate([[b.edge_vertex[e, 0]], self.add_points(P), [b.edge_vertex[e, 1]]]).astype(np.int64)
            self.edge_t[e] = t
            self.edge_ids[e] = ids
        # Every boundary sample of every face is a B-rep vertex or an edge sample, all made by now.
        self.boundary_points = self.point_array()

    def samples(self, e: int) -> tuple[np.ndarray, np.ndarray]:
        """Parameters ``(k,)`` and mesh vertex ids ``(k,)`` of the samples of edge ``e``, start to end."""
        if e in self.edge_t:
            return self.edge_t[e], self.edge_ids[e]
        return self.b.edge_range[e], self.b.edge_vertex[e]

    # ------------------------------------------------------------------ steps 2-6
    def triangulate_faces(self) -> None:
        b = self.b
        faces = np.arange(b.n_faces)
        # Faces on planes (implicit or PlanarSurface) bounded by straight edges are polygons:
        # their loops, counter-clockwise seen from outside, give outward triangles directly.
        plane = np.array([isinstance(S, PlanarSurface) for S in b.surfaces] + [True], dtype=bool)[b.face_surface]
        bulk = plane & _faces_with_straight_edges(b)
        if np.any(bulk):
            self._polyhedral(faces[bulk])
        for f in faces[~bulk]:
            self._surface_face(int(f))

    # .................................................................. polyhedral faces
    def _polyhedral(self, faces: np.ndarray) -> None:
        b = self.b
        n_loops = np.diff(b.face_loop_ptr)[faces]
        single = faces[n_loops == 1]
        loops = b.face_loops[b.face_loop_ptr[single]]
        length = np.bincount(b.coedge_loop, minlength=b.n_loops)[loops]
        rest = [faces[n_loops != 1]]
        for k in np.unique(length):
            sel = length == k
            fk, lk = single[sel], loops[sel]
            ring = _rings(b, lk, int(k))  # (nf, k) vertex ids
            if k == 3:
                self.blocks.append((ring, fk))
                continue
            P = b.vertex_point[ring]
            convex = _strictly_convex(P)
            if np.any(convex):
                r = ring[convex]
                i = np.arange(1, k - 1)
                T = np.stack([np.repeat(r[:, :1], k - 2, axis=1), r[:, i], r[:, i + 1]], axis=-1).reshape(-1, 3)
                self.blocks.append((T, np.repeat(fk[convex], k - 2)))
            rest.append(fk[~convex])
        for f in np.concatenate(rest):
            self._surface_face(int(f))

    # .................................................................. general faces
    def _surface_face(self, f: int, extra_uv: np.ndarray | None = None, extra_xyz: np.ndarray | None = None) -> None:
        """Triangulate face ``f`` (steps 2-6), with optional extra interior points (parameters, or 3-D points of planes)."""
        b = self.b
        si = int(b.face_surface[f])
        if si < 0:
            S, sense = _newell_plane(b, f), True
        else:
            S, sense = b.surfaces[si], bool(b.face_sense[f])
        bd = self._boundary(f, S)
        planar = isinstance(S, PlanarSurface)
        if planar:
            steps, scale = (math.inf, math.inf), np.array([1.0, 1.0])
        else:
            lo, hi = bd.uv.min(axis=0), bd.uv.max(axis=0)
            steps = _grid_steps(S, lo, hi, self.d, self.a)
            scale = _plane_scale(S, bd.uv, steps)
        # Counter-clockwise loops in the triangulation plane: mirror u when the face is reversed.
        if not sense:
            scale = scale * np.array([-1.0, 1.0])
        X_b = bd.uv * scale
        extra = np.zeros((0, 2)) if extra_uv is None else np.asarray(extra_uv, dtype=np.float64).reshape(-1, 2)
        if extra_xyz is not None and len(extra_xyz):
            extra = np.concatenate([extra, S.closest_parameters(extra_xyz)])
        uv_in = np.zeros((0, 2)) if planar else self._grid(bd, X_b, scale, steps)
        uv_in = np.concatenate([uv_in, extra])
        cdt, T, idx, uv_all, ids_all = self._cdt(f, bd, X_b, uv_in, scale)
        if planar:
            T = T[_not_collapsed(T, ids_all, bd.uv.shape[0])]
            self._finish_ids(S, uv_all, ids_all, T)
        else:
            T, uv_all, ids_all = self._refine(f, S, bd, X_b, scale, cdt, T, idx, uv_all, ids_all)
        lo_hi = np.sort(bd.segments, axis=1)
        fixed = set(zip(lo_hi[:, 0].tolist(), lo_hi[:, 1].tolist()))
        self.faces[f] = _FaceMesh(T, uv_all, ids_all, fixed, extra)

    def _coedge_uv(self, f: int, S, c: int) -> np.ndarray:
        """Parameters ``(k, 2)`` of the samples of coedge ``c`` in face ``f``, in the coedge's direction."""
        b = self.b
        e, side = c >> 1, c & 1
        t, ids = self.samples(e)
        pi = int(b.edge_pcurve[e, side])
        if pi >= 0 and int(b.face_surface[f]) >= 0:
            uv = b.pcurves[pi].evaluate(t)
        elif isinstance(S, PlanarSurface):
            # An implicit plane (or a plane without p-curves): project the mesh vertices of the samples.
            uv = S.closest_parameters(self.boundary_points[ids])
        else:
            raise TopologyError(
                f"edge {e} has no p-curve in face {f} (surface {type(S).__name__}); cannot tessellate the face"
            )
        return uv[::-1] if side else uv

    def _boundary(self, f: int, S) -> _Boundary:
        b = self.b
        uvs, idss, segs = [], [], []
        base = 0
        for l in b.face_loop_ids(f):
            cs = b.loop_coedges(int(l))
            if cs.size == 0:
                continue  # a lone-vertex loop adds no area
            pieces = [self._coedge_uv(f, S, int(c)) for c in cs]
            ids = [self.samples(int(c) >> 1)[1][::-1] if c & 1 else self.samples(int(c) >> 1)[1] for c in cs]
            extent = float(np.ptp(np.concatenate(pieces), axis=0).max()) or 1.0
            loop_uv, loop_ids, gap = [], [], []
            for i in range(len(cs)):
                uv_i, id_i = pieces[i], ids[i]
                nxt = pieces[(i + 1) % len(cs)][0]
                loop_uv.append(uv_i[:-1])
                loop_ids.append(id_i[:-1])
                if np.linalg.norm(uv_i[-1] - nxt) > _SAME_UV * extent:
                    # A pole or apex: the loop jumps in (u, v) at one vertex; keep both ends.
                    loop_uv.append(uv_i[-1:])
                    loop_ids.append(id_i[-1:])
            luv = np.concatenate(loop_uv)
            lid = np.concatenate(loop_ids)
            k = luv.shape[0]
            uvs.append(luv)
            idss.append(lid)
            segs.append(base + np.stack([np.arange(k), (np.arange(k) + 1) % k], axis=1))
            base += k
        if not uvs:
            raise TopologyError(f"face {f} has no boundary edges")
        uv = np.concatenate(uvs)
        ids = np.concatenate(idss)
        seg = np.concatenate(segs)
        uv, ids, seg = _merge_touching(f, uv, ids, seg)
        return _Boundary(uv, ids, seg)

    def _grid(self, bd: _Boundary, X_b: np.ndarray, scale: np.ndarray, steps: tuple[float, float]) -> np.ndarray:
        """Interior candidate parameters ``(q, 2)`` (unscaled) of a curved face: the grid of ``steps`` inside the box."""
        lo, hi = bd.uv.min(axis=0), bd.uv.max(axis=0)
        lines = []
        for h, a0, a1 in ((steps[0], lo[0], hi[0]), (steps[1], lo[1], hi[1])):
            n = math.ceil((a1 - a0) / h * (1 - 1e-12)) if math.isfinite(h) and h > 0 else 1
            lines.append(np.linspace(a0, a1, n + 1)[1:-1])
        if lines[0].size == 0 or lines[1].size == 0:
            return np.zeros((0, 2))
        U, V = np.meshgrid(lines[0], lines[1], indexing="ij")
        cand = np.stack([U.ravel(), V.ravel()], axis=1)
        spacing = min(steps[0] * abs(scale[0]), steps[1] * abs(scale[1]))
        keep = _far_from_boundary(cand * scale, X_b, bd.segments, spacing)
        return cand[keep]

    def _cdt(self, f: int, bd: _Boundary, X_b: np.ndarray, uv_in: np.ndarray, scale: np.ndarray):
        """Triangulate boundary + interior points.

        Returns the triangulation (kept for insertions), its triangles (local point indices)
        with their ids in it, all parameters and all mesh ids (-1 for interior points, whose
        mesh vertices are made once the face is final).
        """
        X = np.concatenate([X_b, uv_in * scale])
        try:
            cdt = ConstrainedDelaunay(X, bd.segments)
            T, idx = cdt.triangles(return_index=True)
        except InvalidInputError as exc:
            raise TopologyError(f"face {f}: its boundary cannot be triangulated in parameter space: {exc}") from exc
        uv_all = np.concatenate([bd.uv, uv_in])
        ids_all = np.concatenate([bd.ids, np.full(uv_in.shape[0], -1, dtype=np.int64)])
        return cdt, T, idx, uv_all, ids_all

    def _finish_ids(self, S, uv_all: np.ndarray, ids_all: np.ndarray, T: np.ndarray) -> np.ndarray:
        """Allocate mesh vertices for the interior points used by ``T`` (in place on ids_all)."""
        used = np.zeros(ids_all.shape[0], dtype=bool)
        used[T.ravel()] = True
        new = np.flatnonzero(used & (ids_all < 0))
        if new.size:
            ids_all[new] = self.add_points(S.evaluate(uv_all[new, 0], uv_all[new, 1]))
        return ids_all

    def _refine(self, f, S, bd, X_b, scale, cdt, T, idx, uv_all, ids_all):
        """Step 5: insert points where triangles leave the surface by more than the deflection."""
        nb = bd.uv.shape[0]
        for _ in range(MAX_REFINEMENTS + 1):
            keep = _not_collapsed(T, ids_all, nb)
            T, idx = T[keep], idx[keep]
            P = _positions(self, S, uv_all, ids_all, nb)
            new_uv, rows = _refinement_points(S, T, uv_all, P, uv_all * scale, bd.segments, self.d)
            if new_uv.shape[0] == 0:
                self._finish_ids(S, uv_all, ids_all, T)
                return T, uv_all, ids_all
            uv_all = np.concatenate([uv_all, new_uv])
            ids_all = np.concatenate([ids_all, np.full(new_uv.shape[0], -1, dtype=np.int64)])
            inserted = False
            if new_uv.shape[0] <= _INSERT_FRACTION * uv_all.shape[0]:
                # A few points: Lawson insertion into the kept triangulation, near the triangles they refine.
                try:
                    cdt.insert(new_uv * scale, hints=idx[rows])
                    T, idx = cdt.triangles(return_index=True)
                    inserted = True
                except InvalidInputError:  # pragma: no cover - a point the walk cannot place: start afresh
                    pass
            if not inserted:
                cdt, T, idx, uv_all, ids_all = self._cdt(f, bd, X_b, uv_all[nb:], scale)
        raise ConvergenceError(
            f"face {f}: triangles still deviate more than deflection {self.d:g} from the surface after "
            f"{MAX_REFINEMENTS} refinements"
        )


# ============================================================================ helpers: polyhedral
def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Row-wise cross products of ``(..., 3)`` arrays (``np.cross`` without the axis bookkeeping that dominates small calls)."""
    return np.stack(
        [
            a[..., 1] * b[..., 2] - a[..., 2] * b[..., 1],
            a[..., 2] * b[..., 0] - a[..., 0] * b[..., 2],
            a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0],
        ],
        axis=-1,
    )


def _straight_edges(b: BRep) -> np.ndarray:
    """``(E,)`` True for straight edges (no curve, or a Line)."""
    is_line = np.array([isinstance(c, Line) for c in b.curves] + [True], dtype=bool)  # index -1: no curve
    return is_line[b.edge_curve]


def _curved_side_edges(b: BRep) -> np.ndarray:
    """``(E,)`` True for edges with a side whose p-curve is not a straight line on a non-planar surface."""
    if b.n_edges == 0:
        return np.zeros(0, dtype=bool)
    pc_straight = np.array([isinstance(p, Line2D) for p in b.pcurves] + [True], dtype=bool)
    s_plane = np.array([isinstance(S, PlanarSurface) for S in b.surfaces] + [True], dtype=bool)
    surf = b.face_surface[b.edge_face]  # (E, 2)
    return np.any(~pc_straight[b.edge_pcurve] & ~s_plane[surf], axis=1)


def _faces_with_straight_edges(b: BRep) -> np.ndarray:
    """``(F,)`` True where every edge of the face is straight (no curve or a Line)."""
    out = np.ones(b.n_faces, dtype=bool)
    if b.n_edges:
        out[b.edge_face[~_straight_edges(b)].ravel()] = False
    return out


def _rings(b: BRep, loops: np.ndarray, k: int) -> np.ndarray:
    """Origin vertices of the ``k`` coedges of each loop, in order, ``(len(loops), k)`` (vectorised walk)."""
    c = b.loop_coedge[loops].copy()
    out = np.empty((loops.size, k), dtype=np.int64)
    nxt = b.coedge_next
    org = b.coedge_origin
    for j in range(k):
        out[:, j] = org[c]
        c = nxt[c]
    return out


def _strictly_convex(P: np.ndarray) -> np.ndarray:
    """``(nf,)`` True for polygons ``P (nf, k, 3)`` that turn strictly one way about their Newell normal."""
    Q = np.roll(P, -1, axis=1)
    n = _cross(P, Q).sum(axis=1)
    e0 = Q - P
    e1 = np.roll(e0, -1, axis=1)
    turn = np.einsum("fkj,fj->fk", _cross(e0, e1), n)
    scale = np.linalg.norm(e0, axis=2) * np.roll(np.linalg.norm(e0, axis=2), -1, axis=1) * np.linalg.norm(n, axis=1)[:, None]
    # sin(turn) above 1e-9 (a corner clearly not collinear) at every vertex.
    return np.all(turn > 1e-9 * scale, axis=1)


def _newell_plane(b: BRep, f: int) -> PlanarSurface:
    """The plane of an implicit face: Newell normal (outward), through the vertex centroid."""
    P, Q = [], []
    for l in b.face_loop_ids(f):
        cs = b.loop_coedges(int(l))
        P.append(b.vertex_point[b.coedge_origin[cs]])
        Q.append(b.vertex_point[b.coedge_target[cs]])
    P, Q = np.concatenate(P), np.concatenate(Q)
    n = _cross(P, Q).sum(axis=0)
    if not np.linalg.norm(n) > 0:
        raise TopologyError(f"face {f} is an implicit plane with zero area")
    x = Q[0] - P[0]
    x = x - np.dot(x, n) / np.dot(n, n) * n
    if not np.linalg.norm(x) > 0:
        x = np.eye(3)[int(np.argmin(np.abs(n)))]
    return PlanarSurface(P.mean(axis=0), n, x)


# ============================================================================ helpers: boundaries
def _merge_touching(f: int, uv: np.ndarray, ids: np.ndarray, seg: np.ndarray):
    """Merge boundary points that coincide in (u, v) (a loop touching itself or another at a vertex).

    Raises
    ------
    TopologyError
        Two different mesh vertices at one parameter point.
    """
    extent = float(np.ptp(uv, axis=0).max()) or 1.0
    pairs = cKDTree(uv).query_pairs(_SAME_UV * extent, output_type="ndarray")
    if pairs.size == 0:
        return uv, ids, seg
    differ = ids[pairs[:, 0]] != ids[pairs[:, 1]]
    if np.any(differ):
        i, j = pairs[differ][0]
        raise TopologyError(
            f"face {f}: mesh vertices {int(ids[i])} and {int(ids[j])} sit at the same parameters {uv[i].tolist()}"
        )
    rep = np.arange(uv.shape[0])
    for i, j in sorted(map(tuple, pairs.tolist())):
        rep[max(i, j)] = rep[min(i, j)]
    keep = rep == np.arange(uv.shape[0])
    remap = np.cumsum(keep) - 1
    return uv[keep], ids[keep], remap[rep[seg]]


def _plane_scale(S, uv: np.ndarray, steps: tuple[float, float]) -> np.ndarray:
    """Scale ``(2,)`` of (u, v) in the triangulation plane.

    Where both grid steps are finite the plane is ``(u / h_u, v / h_v)``: the grid cells are
    unit squares, so Delaunay triangles are well shaped for the deflection (the curvature
    metric).  A direction without curvature takes its scale from the mean surface metric
    ``(|Su|, |Sv|)`` relative to the other; with no curvature at all, the mean metric.

    Raises
    ------
    TopologyError
        A degenerate metric (``|Su|`` or ``|Sv|`` vanishing on average over the face).
    """
    lo, hi = uv.min(axis=0), uv.max(axis=0)
    s = (np.arange(_CURVATURE_SAMPLES) + 0.5) / _CURVATURE_SAMPLES
    U, V = np.meshgrid(lo[0] + (hi[0] - lo[0]) * s, lo[1] + (hi[1] - lo[1]) * s, indexing="ij")
    D = S.derivatives(U.ravel(), V.ravel(), 1)
    su = float(np.mean(np.linalg.norm(D[:, 1, 0], axis=1)))
    sv = float(np.mean(np.linalg.norm(D[:, 0, 1], axis=1)))
    if not (su > 0 and sv > 0 and math.isfinite(su) and math.isfinite(sv)):
        raise TopologyError(
            f"surface {type(S).__name__} has a degenerate metric over the face (|Su| = {su:g}, |Sv| = {sv:g})"
        )
    hu, hv = steps
    if math.isfinite(hu) and math.isfinite(hv):
        return np.array([1.0 / hu, 1.0 / hv])
    if math.isfinite(hu):
        return np.array([1.0, sv / su]) / hu
    if math.isfinite(hv):
        return np.array([su / sv, 1.0]) / hv
    return np.array([su, sv])


def _grid_steps(S, lo: np.ndarray, hi: np.ndarray, d: float, a: float) -> tuple[float, float]:
    """Parameter steps ``(h_u, h_v)`` meeting deflection ``d`` and angle ``a`` everywhere on the box (inf: no curvature)."""
    s = (np.arange(_CURVATURE_SAMPLES) + 0.5) / _CURVATURE_SAMPLES
    us = lo[0] + (hi[0] - lo[0]) * s
    vs = lo[1] + (hi[1] - lo[1]) * s
    for attr, axis in (("knots_u", 0), ("knots_v", 1)):
        knots = getattr(S, attr, None)
        if knots is not None:  # a few samples in every knot span the box touches
            k = np.unique(np.asarray(knots))
            k = np.concatenate([[lo[axis]], k[(k > lo[axis]) & (k < hi[axis])], [hi[axis]]])
            extra = (k[:-1, None] + (k[1:] - k[:-1])[:, None] * s[None, ::2]).ravel()
            if axis == 0:
                us = np.union1d(us, extra)
            else:
                vs = np.union1d(vs, extra)
    U, V = np.meshgrid(us, vs, indexing="ij")
    D = S.derivatives(U.ravel(), V.ravel(), 2)
    Su, Sv = D[:, 1, 0], D[:, 0, 1]
    W = _cross(Su, Sv)
    w = np.linalg.norm(W, axis=1)
    ok = w > 1e-12 * np.maximum(np.linalg.norm(Su, axis=1) * np.linalg.norm(Sv, axis=1), 1e-300)
    if not np.any(ok):
        return math.inf, math.inf
    Su, Sv, W, w, D = Su[ok], Sv[ok], W[ok], w[ok], D[ok]
    n = W / w[:, None]
    L = np.abs(np.einsum("ij,ij->i", D[:, 2, 0], n))
    M = np.abs(np.einsum("ij,ij->i", D[:, 1, 1], n))
    N = np.abs(np.einsum("ij,ij->i", D[:, 0, 2], n))
    # Derivatives of the unit normal: n_u = (W_u - n (n·W_u)) / |W|.
    Wu = _cross(D[:, 2, 0], Sv) + _cross(Su, D[:, 1, 1])
    Wv = _cross(D[:, 1, 1], Sv) + _cross(Su, D[:, 0, 2])
    nu = np.linalg.norm(Wu - n * np.einsum("ij,ij->i", n, Wu)[:, None], axis=1) / w
    nv = np.linalg.norm(Wv - n * np.einsum("ij,ij->i", n, Wv)[:, None], axis=1) / w
    Lp, Np = float(np.max(L + M)), float(np.max(N + M))
    span = hi - lo
    curved_u = Lp * span[0] ** 2 / 8 > d
    curved_v = Np * span[1] ** 2 / 8 > d
    share = _GRID_MARGIN * (0.5 if (curved_u and curved_v) else 1.0)

    def step(k: np.ndarray, turn: np.ndarray, curved: bool) -> float:
        if not curved:
            return math.inf
        with np.errstate(divide="ignore"):
            h_d = np.sqrt(8.0 * share * d / k)
            h_a = a / turn
        return float(np.min(np.minimum(h_d, h_a)))

    return step(L + M, nu, curved_u), step(N + M, nv, curved_v)


def _far_from_boundary(X: np.ndarray, X_b: np.ndarray, seg: np.ndarray, spacing: float) -> np.ndarray:
    """Mask of points ``X`` at least half the local boundary spacing (and half ``spacing``) from the boundary segments."""
    A, B = X_b[seg[:, 0]], X_b[seg[:, 1]]
    length = np.linalg.norm(B - A, axis=1)
    step = 0.25 * np.minimum(length, spacing)
    step = np.where(step > 0, step, 1.0)
    counts = np.maximum(1, np.ceil(length / step).astype(np.int64))
    owner = np.repeat(np.arange(seg.shape[0]), counts)
    start = np.cumsum(counts) - counts
    frac = (np.arange(owner.size) - start[owner]) / counts[owner]
    samples = A[owner] + frac[:, None] * (B - A)[owner]
    dist, idx = cKDTree(samples).query(X)
    radius = 0.5 * np.minimum(length[owner[idx]], spacing)
    return dist >= radius


# ============================================================================ helpers: refinement
def _positions(builder: _Builder, S, uv_all: np.ndarray, ids_all: np.ndarray, nb: int) -> np.ndarray:
    """3-D points of all local points: mesh vertices on the boundary, surface points inside."""
    P = np.empty((uv_all.shape[0], 3))
    if nb:
        P[:nb] = builder.boundary_points[ids_all[:nb]]
    if uv_all.shape[0] > nb:
        P[nb:] = S.evaluate(uv_all[nb:, 0], uv_all[nb:, 1])
    return P


def _not_collapsed(T: np.ndarray, ids_all: np.ndarray, nb: int) -> np.ndarray:
    """Mask of the triangles without two corners on one mesh vertex (those on pole gaps collapse)."""
    key = np.where(np.arange(ids_all.shape[0]) < nb, ids_all, -1 - np.arange(ids_all.shape[0]))
    K = key[T]
    return (K[:, 0] != K[:, 1]) & (K[:, 1] != K[:, 2]) & (K[:, 2] != K[:, 0])


def _surface_distance(S, P: np.ndarray, uv0: np.ndarray) -> np.ndarray:
    """Distance of points ``P (k, 3)`` to the (untrimmed) surface; exact for analytic surfaces.

    Other surfaces: four damped Gauss–Newton steps from ``uv0`` inside the surface's domain;
    the distance to the point reached is an upper bound of the true distance.
    """
    if hasattr(S, "implicit"):
        return np.abs(S.implicit(P))
    uv = uv0.copy()
    (u0, u1), (v0, v1) = S.domain
    for _ in range(4):
        D = S.derivatives(uv[:, 0], uv[:, 1], 1)
        r = D[:, 0, 0] - P
        J = np.stack([D[:, 1, 0], D[:, 0, 1]], axis=2)  # (k, 3, 2)
        JtJ = np.einsum("kia,kib->kab", J, J)
        g = np.einsum("kia,ki->ka", J, r)
        lam = 1e-12 * np.trace(JtJ, axis1=1, axis2=2)[:, None, None] * np.eye(2)
        step = np.linalg.solve(JtJ + lam + 1e-300 * np.eye(2), -g[..., None])[..., 0]
        uv = uv + step
        uv[:, 0] = np.clip(uv[:, 0], u0, u1)
        uv[:, 1] = np.clip(uv[:, 1], v0, v1)
    return np.linalg.norm(S.evaluate(uv[:, 0], uv[:, 1]) - P, axis=1)


def _acute_in_hessian(S, uvT: np.ndarray, Cuv: np.ndarray) -> np.ndarray:
    """``(m,)`` True for triangles ``uvT (m, 3, 2)`` acute in the metric of ``II = [[L, M], [M, N]]`` at their centroids.

    The deviation of a linear interpolant of the height ``½ xᵀ II x`` from the surface is
    ``κ/2 (r² − |x − c|²)`` in the metric where ``II`` is ``κ I``: largest at the
    circumcentre ``c`` for acute triangles (where the centroid holds at least 8/9 of it, since
    ``|c − g| ≤ r/3``), and at the longest edge's midpoint otherwise.  Where ``II`` is
    indefinite (saddles) or singular (developable surfaces) the largest deviation lies on an
    edge, and the triangle counts as not acute.
    """
    D = S.derivatives(Cuv[:, 0], Cuv[:, 1], 2)
    W = _cross(D[:, 1, 0], D[:, 0, 1])
    w = np.linalg.norm(W, axis=1)
    n = np.divide(W, w[:, None], out=np.zeros_like(W), where=w[:, None] > 0)
    L = np.einsum("ij,ij->i", D[:, 2, 0], n)
    M = np.einsum("ij,ij->i", D[:, 1, 1], n)
    N = np.einsum("ij,ij->i", D[:, 0, 2], n)
    definite = L * N - M * M > 0
    sgn = np.sign(L)[:, None]
    a = np.roll(uvT, -1, axis=1) - uvT  # (m, 3, 2): from each corner to the next
    b = np.roll(uvT, 1, axis=1) - uvT  # to the previous
    q = sgn * (L[:, None] * a[..., 0] * b[..., 0] + M[:, None] * (a[..., 0] * b[..., 1] + a[..., 1] * b[..., 0])
               + N[:, None] * a[..., 1] * b[..., 1])
    return definite & np.all(q > 0, axis=1)


def _refinement_points(
    S, T: np.ndarray, uv: np.ndarray, P: np.ndarray, X: np.ndarray, seg: np.ndarray, d: float
) -> tuple[np.ndarray, np.ndarray]:
    """Parameters of the points to insert so that every triangle comes within ``d`` of the surface.

    Returns the parameters ``(k, 2)`` and, for each, the row of the triangle it refines ``(k,)``.
    A triangle's deviation is estimated from its centroid (times 9/8 when it is acute in the
    metric of the surface's second fundamental form) and the midpoints of its interior edges
    (see the module docstring and :func:`_acute_in_hessian`).  An offending triangle is
    split at the midpoint of its longest edge in the triangulation plane ``X`` (Rivara's
    longest-edge bisection, which never degrades the triangles), or at its centroid when that
    edge is a boundary segment (boundary samples are shared with the neighbouring face).
    """
    none = (np.zeros((0, 2)), np.zeros(0, dtype=np.int64))
    if T.shape[0] == 0:
        return none
    m = T.shape[0]
    rows = np.arange(m)
    C = P[T].mean(axis=1)
    Cuv = uv[T].mean(axis=1)
    dev = np.where(_acute_in_hessian(S, uv[T], Cuv), 9.0 / 8.0, 1.0) * _surface_distance(S, C, Cuv)
    # Edges (j, j+1) of each triangle; boundary segments are already within d (step 1).
    ea, eb = T, T[:, [1, 2, 0]]
    big = np.int64(uv.shape[0] + 1)
    und = np.minimum(ea, eb) * big + np.maximum(ea, eb)
    s_und = np.minimum(seg[:, 0], seg[:, 1]) * big + np.maximum(seg[:, 0], seg[:, 1])
    interior = ~np.isin(und, s_und)
    Muv = 0.5 * (uv[ea] + uv[eb])
    if np.any(interior):
        dev_e = np.zeros((m, 3))
        dev_e[interior] = _surface_distance(S, 0.5 * (P[ea] + P[eb])[interior], Muv[interior])
        dev = np.maximum(dev, dev_e.max(axis=1))
    bad = dev > d
    if not np.any(bad):
        return none
    length = np.linalg.norm(X[ea] - X[eb], axis=2)
    longest = np.argmax(length, axis=1)
    split = bad & interior[rows, longest]
    cent = bad & ~split
    pts, where = [Cuv[cent]], [rows[cent]]
    if np.any(split):
        keys = und[rows, longest][split]
        _, first = np.unique(keys, return_index=True)
        pts.append(Muv[rows, longest][split][first])
        where.append(rows[split][first])
    return np.concatenate(pts), np.concatenate(where)
