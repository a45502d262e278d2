"""Watertight tessellation of B-reps: every edge discretised once, every face triangulated against those points.

:func:`tessellate` turns a :class:`~coons.topology.shape.Solid` (or a
:class:`~coons.topology.brep.BRep`) into a :class:`~coons.topology.mesh.TriangleMesh` whose
triangles are oriented outward and whose every vertex lies on the exact geometry.  The mesh
is closed and edge-manifold *by construction*: the two faces of an edge use the very same
mesh vertices along it, so no stitching or vertex welding is ever done.  Chordal deviation
and normal turning are bounded by ``deflection`` and ``angular_deflection`` (as OCCT's
``BRepMesh_IncrementalMesh``; deflection is a resolution, never a tolerance).  It does not
heal invalid B-reps, smooth or decimate meshes (only edge samples are thinned, step 1), produce
quad meshes, or guarantee triangle quality beyond what the Delaunay criterion (trimmed faces)
or the strip construction (revolved faces) gives.

Algorithm (the BRepMesh idea, made watertight by construction)
--------------------------------------------------------------
0. **Plan of the revolved faces.**  A face on a cylinder, cone, sphere or torus whose single
   loop runs around the rectangle ``[u0, u1] × [v0, v1]`` of its parameter plane (straight
   p-curves along its sides, ``u1 − u0 ≤ π``; a side may collapse to a pole or apex) is
   meshed in closed form (step 3a).  Its *rows* are chosen first: the two rows of its ends
   for cylinders and cones (straight meridians), equal steps ``h`` with
   ``r_m (1 − cos(h/2)) = d / 2`` and ``h ≤ θ`` for spheres and tori (meridian circles of
   radius ``r_m``).  Between consecutive rows the largest admissible ``u``-span ``s`` of a
   triangle follows from the *strip bound* below; each row then needs ``⌈(u1 − u0) / s⌉``
   segments, which its edges, if it is a boundary row, are asked for in step 1.
1. **Edges.**  Each edge gets increasing parameters ``t`` along its 3-D curve: 2 for straight
   edges and lines; ``ceil(sweep / min(θ, 2 acos(1 − d / R)))`` equal steps for circles (never
   more than a quarter turn per chord, so that every boundary polygon has an area); for
   other curves an adaptive bisection (vectorised over all intervals of the edge) until the
   chord's midpoint deviation is at most ``d``, the turning angle between consecutive chords
   at most ``θ`` (plus the tangent jump at a C0 knot of a NURBS curve, where the curve has a
   corner), and — for p-curves that are not straight lines on non-planar faces — the
   midpoint of the straight parameter-space chord maps onto the surface within ``d`` of the
   line of the 3-D chord.  The bisection starts from (degree + 1) samples per knot span of a
   NURBS (16 per turn of an ellipse or other curve), far denser than the deflection asks for a
   curve fitted to an intersection (hundreds of spans); the samples of every bisected curve are
   then *decimated* top-down (:func:`_decimated`): a chord over
   several of them is kept when every one of their chords lies within ``d`` of it (ends'
   distance plus own midpoint deviation), none turns by more than ``θ/2`` from it, and it meets
   the bisection's own tests above (midpoint, turning, C0 knots kept, curved p-curves).  Edges
   of planned faces then take the plan's rows (meridians) or at least its segment count
   (parallels).  B-rep vertices become mesh vertices
   ``0 .. V-1``; edge samples follow.
2. **Face boundaries** (trimmed faces).  Each loop is walked in order; a coedge contributes
   its edge's samples mapped through its own p-curve (reversed for right sides).  Where
   consecutive p-curves end and start at different parameter points (a sphere's pole, a
   cone's apex: see ``docs/brep.md``; a parameter must be undetermined there
   (:func:`~coons.kernel.onsurface.singular_parameters`), else the two ends are one point) both
   points are kept and joined by a *gap segment*;
   both carry the same mesh vertex, so the one triangle on the gap degenerates and is
   dropped, which is an edge collapse of the parameter-space triangulation onto the pole.
   A loop that would get fewer than three samples (a sliver bounded by an arc and a line
   whose chords both lie within the deflection) has its longest curved edge bisected in
   step 1, once or twice, so that every face gets a triangle.
   Implicit planes (``face_surface == -1``) use coordinates in their Newell plane.
3a. **Revolved faces: strips.**  The rows are the samples of the face's left side (which
   must equal its right side's); boundary rows are the samples of the bottom and top edges
   (or the pole), interior rows get ``n_j = max(⌈Δu / s_{j−1}⌉, ⌈Δu / s_j⌉, 2)`` equal
   segments.  Consecutive rows are zipped into triangles by merging their segments in the
   order of their midpoints (the greedy contour tiling of Christiansen & Sederberg, 1978), for
   all strips of all such faces in one vectorised pass (``searchsorted``); every triangle
   then spans at most the larger segment of its two rows in ``u``.

   *Strip bound.*  Write the surface ``O + ρ(v) e(u) + z(v) Z`` and a row's meridian point
   ``m = (ρ, z)``.  A point ``x = Σ λ_i P_i`` of a triangle whose corners lie on rows ``j``
   and ``j + 1`` within a ``u``-span ``s`` has height ``Σ λ_i z_i`` and axis distance
   between ``c ρ̄`` and ``ρ̄ = Σ λ_i ρ_i`` (``c = cos(s/2)``): in its meridian half-plane it
   lies in the trapezoid spanned by the chord ``m_j m_{j+1}`` and its copy scaled towards the
   axis by ``c``.  Its distance to the surface is at most the distance of that trapezoid to the
   meridian curve: ``(1 − c) ρ_max cos α`` for a line at angle ``α`` to the axis; for a circle
   (centre ``T``, radius ``r_m``) the outer corners bound the outward distance exactly and
   ``|q − T|² ≥ D² − 2δw + δ²`` (``D ≥`` the chord's distance to ``T``, ``δ ≤ (1 − c) ρ_max``,
   ``w ≤ ρ_max − ρ_T``) the inward one.  Solving these closed forms for ``c`` gives ``s``
   (rigorous, and exact to second order: a sphere's rows get ``s ∝ 1/ρ``, fewer segments
   towards the poles).  ``s`` is also at most ``θ / |n_ρ|`` (normal turning) and π/2, and
   ``δ ≤ ℓ tan θ`` for a meridian chord of length ``ℓ`` (a long row segment beside a short
   meridian step would tilt the triangle's plane away from the surface normal).  Faces on
   equal surfaces over the same ``v``-range (the halves of a cylinder, the walls of equal
   holes) share one design.
3b. **Planar faces with one strictly convex loop** (disks) are fanned, vectorised by polygon
   size (arcs of one circle making a full turn are convex by construction; other loops are
   tested in the plane's coordinates).
3c. **Other faces: interior points.**  A grid over the face's parameter box, spaced by the
   surface's curvature: with the second fundamental form ``L, M, N`` (normal components of
   ``Suu``, ``Suv``, ``Svv``) sampled over the face,
   ``h_u = min(sqrt(8 d_u / (|L| + |M|)), θ / |n_u|)`` and likewise ``h_v`` (minima over the
   samples).  The linear interpolation error of a quadratic on a grid cell is
   ``(L h_u² + N h_v²) / 8`` at the midpoint of either diagonal, so ``d_u = d_v = d / 2`` when
   both directions are curved and ``d`` otherwise, both times a margin of 0.8 that leaves the
   grid's own triangles clear of refinement.  A direction without curvature (the rulings of a
   cylinder or cone) gets lines at the curved direction's step measured in the triangulation
   plane (square cells there) when the curved direction's metric varies by less than a factor
   2 over the face (not near a cone's apex), and none otherwise.  Grid points closer to the
   boundary than half the local boundary spacing (or half the grid spacing) are dropped.
4. **Triangulation** (step 3c faces) with the constrained Delaunay triangulator of
   :mod:`coons.topology._cdt` (which never inserts a point on a boundary segment), keeping
   the triangles left of the loops, in the plane ``(u / h_u, v / h_v)`` where the grid cells
   are unit squares (a direction without curvature is scaled by the mean ``|Su|``, ``|Sv|``).
5. **Refinement** (step 3c faces).  Each triangle's deviation is estimated from the distance
   of its centroid to the surface, times 9/8 when the triangle is acute in the metric of the
   second fundamental form, and the distances of the midpoints of its interior edges: for a
   quadratic surface the error is largest at the circumcentre of an acute triangle (the
   centroid holds at least 8/9 of it) and at the longest edge's midpoint otherwise, and on
   saddles it lies on the edges; boundary edges are bounded by step 1.  Distances are exact
   for analytic surfaces (``implicit``) and found by a few Gauss–Newton steps for others.
   Offending triangles are split at the midpoint of their longest interior edge (Rivara's
   longest-edge bisection) or at their centroid; a triangle offending through an interior
   edge whose midpoint is off the surface, while its longest edge is not, is split on that
   edge instead (else the bad edge survives in the neighbour and the rounds end in a long
   tail of single points near thin boundary features); all by Lawson insertion into the kept
   triangulation (or a new triangulation when many points come at once), at most
   :data:`MAX_REFINEMENTS` rounds.
6. **Orientation.**  When ``face_sense`` is False the parameter plane is mirrored before
   triangulating (strips: the triangles are reversed), so counter-clockwise triangles always
   map to outward normals.
7. **Chord conflicts.**  Sharing the edge samples makes every B-rep edge's mesh edges used
   once each way, but two faces that share two vertices not joined by a common edge (the
   two hemispheres of a very coarse sphere share both meridians) can both draw the chord
   between them, and a pole collapse can make one face draw a chord twice.  Such directed
   edges used twice are found in one sort; their faces get the chord midpoints as extra
   interior points and are triangulated again (at most ``_MAX_REPAIRS`` rounds; a result
   still not closed raises).  Strips never draw such chords (interior rows have at least two
   segments of their own).
8. **Crossing chords.**  Chords of two edges can cross in a face's parameter plane although
   the edges do not: a vertex of one lies within the sagitta of the other's chord (a box
   corner 0.0023 inside a cylinder's rim).  The triangulator refuses such a boundary; the
   curved edges of the crossing chords then get half their parameter step and the whole
   tessellation runs again (shared samples: both faces of an edge see its new chords), at most
   ``_MAX_CROSSING_ROUNDS`` times (each quarters the sagitta) before the crossing is reported.

*Flat NURBS faces.*  A NURBS surface whose control points lie within ``tol.linear`` of a plane
(with a control net whose cells all face one way) lies in that plane (convex-hull property, positive
weights): its faces are treated as faces of that plane (:func:`_flat_nurbs_planes`, one batched SVD
per control-grid shape), with the plane's normal along ``Su × Sv`` so that ``face_sense`` keeps its
meaning, and their boundary samples projected into the plane instead of mapped through their
p-curves.  They need no interior points: the boundary polygon, triangulated in the plane, is the
face to within ``2 tol.linear``.  A solid sewn from many bilinear patches is thus a polyhedron here.

Polygonal faces (implicit planes, planar surfaces or flat NURBS surfaces, with straight edges) skip steps 3–5:
triangles are emitted as they are and strictly convex polygons are fanned, both vectorised by
polygon size; other polygons (holes, non-convex) go through the constrained triangulator in
their plane.  A mesh-derived polyhedron therefore tessellates in numpy time.

Closedness is verified, not assumed: one sort of the edge keys ``2 (min · n + max) + [a > b]``
finds chords used twice (step 7) and checks that every edge is used exactly once each way;
a result that is not closed raises.

*Caching.*  B-reps and meshes are immutable, so :func:`tessellate` keeps its result per B-rep and
``(deflection, angular deflection, tolerance)`` (weakly: the meshes go with the B-rep).  A Boolean
tessellates its operands when it classifies by them and, when its result has a void whose vertices
all lie in the box of some face of a positive shell, the result (void nesting in
:func:`coons.topology.sew.sew_faces`; other voids are nested without a mesh); the final B-rep,
rebuilt after nesting, shares any such mesh (:func:`share_tessellations`, guarded by
:func:`coons.topology.brep.same_geometry`), so the next Boolean of a chain does not tessellate its
operand again.  Meshes are not reused per
face across different B-reps: edge sampling and chord repairs are global, and a face kept
unchanged by a Boolean is meshed again with the rest.

Speed (``benchmarks/bench_topology.py``, results in ``benchmarks/results/topology-tessellate.md``):
the strips make the revolved primitives 3× (coarse) to 60×+ (fine) faster than OCCT's
``BRepMesh_IncrementalMesh`` at equal deflection with fewer triangles; faces with holes are
bounded by Qhull in the constrained triangulator (about 10 µs per boundary point).  A cube of
6 × 13 × 13 flat bilinear NURBS faces (``benchmarks/bench_io.py``) takes about 0.05 s (it took
14 s through steps 3c–5, ~14 ms per face); curved NURBS faces still cost a few milliseconds each
(step 3c–5 per face: curvature samples, Qhull, Gauss–Newton distances).
"""

from __future__ import annotations

import math
import weakref
from dataclasses import dataclass, field

import numpy as np
from scipy.spatial import cKDTree

from coons.errors import ConvergenceError, InvalidInputError, TopologyError
from coons.kernel.analytic import (
    Circle,
    ConicalSurface,
    CylindricalSurface,
    Line,
    PlanarSurface,
    SphericalSurface,
    ToroidalSurface,
)
from coons.kernel.onsurface import singular_parameters
from coons.kernel.pcurve import Line2D
from coons.kernel.polygon import proper_crossings
from coons.tolerance import Tolerance, resolve
from coons.topology._cdt import ConstrainedDelaunay
from coons.topology.brep import BRep, same_geometry
from coons.topology.mesh import TriangleMesh

__all__ = ["tessellate", "edge_parameters", "MAX_REFINEMENTS", "ANGULAR_DEFLECTION"]

#: The default angular deflection of :func:`tessellate` (radians).
ANGULAR_DEFLECTION = 0.5

#: Re-triangulations per face in the refinement step before giving up with ConvergenceError.
MAX_REFINEMENTS = 32
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
#: Fraction of the deflection refinement aims at: its deviation estimate (centroid and edge
#: midpoints in the quadratic model) is exact to second order only, and third-order terms (a cone
#: near its apex) put the true worst point of a triangle up to a few tenths of a percent above it.
_REFINE_MARGIN = 0.98
#: Fraction of the deflection the interior grid aims at: a grid cell split by either diagonal
#: meets exactly its target in the quadratic model, so a margin keeps round-off and the
#: model's error from sending every grid triangle to refinement.
_GRID_MARGIN = 0.8
#: Share of the deflection given to the meridian chords of a revolved face (the rest bounds the
#: ``u`` direction): ``β (1 − β)`` is largest, hence the triangle count smallest, at one half.
_MERIDIAN_SHARE = 0.5
#: Relative slack of the plan's comparisons of parameters that come from the same formulas by
#: different arithmetic (a p-curve evaluation against a row value, a side against its opposite).
_PLAN_RTOL = 1e-9


# ============================================================================ entry point
def tessellate(
    shape, deflection: float | None = None, angular_deflection: float = ANGULAR_DEFLECTION, tol: Tolerance | None = None
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
        faces, of the surface normal across a grid step or row segment (edge chords never
        turn more than π/2 whatever the value).
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
    meshes = _MESHES.get(b)
    if meshes is None:
        meshes = _MESHES[b] = {}
    key = (d, a, t)
    if key not in meshes:
        meshes[key] = _tessellate(b, d, a, t)
    return meshes[key]


#: Meshes per B-rep and ``(deflection, angular deflection, tolerance)``: B-reps and meshes are
#: immutable, and a Boolean tessellates its operands, which are often the results of the previous
#: Boolean, tessellated there already (void nesting) — see :func:`share_tessellations`.
_MESHES: "weakref.WeakKeyDictionary[BRep, dict]" = weakref.WeakKeyDictionary()


def share_tessellations(src: BRep, dst: BRep) -> None:
    """Let ``dst`` reuse the meshes computed for ``src``.

    Only for two B-reps with the same vertices, faces and geometry in the same order, differing at
    most in how shells are grouped into solids (a B-rep rebuilt after nesting its voids): the mesh
    of each face, and so of the whole, is then the same.
    """
    if not same_geometry(src, dst):
        raise InvalidInputError("share_tessellations needs B-reps with the same vertices, faces and geometry")
    meshes = _MESHES.get(src)
    if meshes:
        _MESHES.setdefault(dst, {}).update(meshes)


#: Rounds of :func:`_tessellate` that refine the chords of curved edges crossing another edge's in a
#: face's parameter plane (each round quarters their sagitta) before the crossing is reported.
_MAX_CROSSING_ROUNDS = 6


class _Crossing(Exception):
    """Internal: boundary chords of a face cross; ``edges`` are the curved edges to refine."""

    def __init__(self, edges: set[int], error: TopologyError) -> None:
        super().__init__(str(error))
        self.edges, self.error = edges, error


def _tessellate(b: BRep, d: float, a: float, t: Tolerance) -> TriangleMesh:
    """:func:`tessellate` with resolved arguments, uncached.

    Chords of two edges can cross in a face's parameter plane although the edges do not: a
    vertex of one within the sagitta of the other's chord (a box corner 0.0023 inside a
    cylinder's rim, whose chords sag further).  The curved edges of crossing chords then get
    chords of half the parameter step, and the whole tessellation runs again (the samples of
    an edge are shared by its two faces, so both see the finer chords).
    """
    refine: dict[int, int] = {}
    for r in range(_MAX_CROSSING_ROUNDS + 1):
        try:
            return _tessellate_once(b, d, a, t, refine)
        except _Crossing as exc:
            if not exc.edges or r == _MAX_CROSSING_ROUNDS:
                raise exc.error from exc.error.__cause__
            for e in exc.edges:
                refine[e] = refine.get(e, 0) + 1
    raise AssertionError("unreachable")  # (the last round returns or raises)


def _tessellate_once(b: BRep, d: float, a: float, t: Tolerance, refine: dict[int, int]) -> TriangleMesh:
    """One run of :func:`_tessellate`; ``refine``: edge -> how many times to halve its parameter steps."""
    ctx = _Builder(b, d, a, t, refine)
    ctx.plan_revolved_faces()
    ctx.discretise_edges()
    ctx.triangulate_faces()
    T, F = ctx.triangles()
    repeated, closed = _edge_pairing(T, ctx.n_points)
    for _ in range(_MAX_REPAIRS):
        if not repeated:
            break
        ctx.repair_conflicts(*ctx.triangles(local=True))
        T, F = ctx.triangles()
        repeated, closed = _edge_pairing(T, ctx.n_points)
    mesh = ctx.mesh(T, F)
    if b.n_faces and not closed:
        bad = mesh.boundary_edges()
        raise TopologyError(
            f"tessellation is not closed: {bad.shape[0]} directed edge(s) without a twin, e.g. {bad[:3].tolist()} "
            "(the B-rep is probably invalid; run check())"
        )
    return mesh


def _edge_pairing(T: np.ndarray, n: int) -> tuple[bool, bool]:
    """``(repeated, closed)`` for triangles ``T (m, 3)`` over ``n`` points, from one sort.

    ``repeated``: some directed edge is used twice (a chord conflict).  ``closed``: every
    undirected edge is used exactly twice, once each way, by non-degenerate triangles — the
    condition of :attr:`TriangleMesh.is_closed`.  The key ``2 (min · n + max) + [a > b]``
    sorts the two uses of an edge next to each other, the forward one first.
    """
    if T.shape[0] == 0:
        return False, False
    a = T.ravel()
    c = T[:, [1, 2, 0]].ravel()
    key = np.sort(2 * (np.minimum(a, c) * np.int64(n) + np.maximum(a, c)) + (a > c))
    first, second = key[0::2], key[1::2]
    if key.size % 2 == 0 and (second - first == 1).all() and not (first & 1).any():
        return False, True  # (a directed edge used twice would break the pattern)
    return bool((key[1:] == key[:-1]).any()), False


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
    (both ends at one vertex) gets at least three segments.  At an interior knot of a NURBS
    curve whose multiplicity reaches the degree (a C0 knot: the curve may have a corner there)
    the knot is a sample and the turning allowed between its two chords grows by the jump of
    the tangent direction, so the angular criterion applies within the smooth pieces.  The
    bisection's samples (of a NURBS from (degree + 1) per knot span) are then thinned to the
    chords that still meet every criterion (:func:`_decimated`).  This
    is the curve's own discretisation: :func:`tessellate` may add samples where the faces of
    the edge ask for them (step 0 of the module docstring).

    Raises
    ------
    ConvergenceError
        The bisection did not meet the criteria in ``_MAX_EDGE_ROUNDS`` rounds.
    """
    t0, t1 = b.edge_range[edge].tolist()
    ci = int(b.edge_curve[edge])
    closed = int(b.edge_vertex[edge, 0]) == int(b.edge_vertex[edge, 1])
    return _edge_params(b, edge, deflection, angular_deflection, bool(_curved_sides(b, edge)), t0, t1,
                        None if ci < 0 else b.curves[ci], closed)


def _edge_params(b: BRep, edge: int, deflection: float, angular_deflection: float, curved_sides: bool, t0: float,
                 t1: float, curve, closed: bool) -> np.ndarray:
    """:func:`edge_parameters` with the edge's range, curve, closedness and curved-p-curve flag known."""
    # A chord never turns more than a quarter turn: a coarser polygon would not bound an area.
    a = min(angular_deflection, _MAX_CHORD_TURN)
    if curve is None or isinstance(curve, Line):
        t = np.array([t0, t1])
        exact = True
    elif isinstance(curve, Circle):
        R = curve.radius
        step = min(a, 2.0 * math.acos(max(1.0 - deflection / R, -1.0)))
        t = _linspace(t0, t1, max(1, math.ceil((t1 - t0) / step * (1 - 1e-12))))
        exact = True
    else:
        t = _initial_parameters(curve, t0, t1)
        exact = False
    if closed and t.size < 4:
        t = _linspace(t0, t1, 3) if t.size <= 2 else np.union1d(t, 0.5 * (t[:-1] + t[1:]))
    if exact and not curved_sides:
        return t
    return _bisect_edge(b, edge, curve, t, _curved_sides(b, edge), deflection, a, check_curve=not exact, closed=closed)


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
    """Starting samples for the bisection: (degree + 1) per knot span of a NURBS (knots included), else 16 per full turn."""
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


def _c0_knots(curve, t0: float, t1: float) -> tuple[np.ndarray, np.ndarray]:
    """Interior knots ``(k,)`` of a NURBS curve whose multiplicity reaches its degree, and the angle ``(k,)``
    between the curve's one-sided tangents there (0 where it is tangent-continuous after all, as at the
    double knots of an exact rational circle)."""
    none = (np.zeros(0), np.zeros(0))
    knots = getattr(curve, "knots", None)
    if knots is None:
        return none
    p = int(getattr(curve, "degree", 0))
    k, mult = np.unique(np.asarray(knots, dtype=np.float64), return_counts=True)
    k = k[(mult >= p) & (k > t0) & (k < t1)]
    if k.size == 0:
        return none
    # One-sided tangents: derivatives just before and just after the knot; the offset is far below
    # any knot span (the domain is finite), so the tangents differ from the limits by round-off only.
    eps = 1e-9 * (t1 - t0)
    D = curve.derivatives(np.concatenate([k - eps, k + eps]), 1)[:, 1, :]
    jump = _turning(D[: k.size], D[k.size :])
    return k, jump


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


def _bisect_edge(b, edge, curve, t, sides, d, a, *, check_curve: bool, closed: bool) -> np.ndarray:
    breaks, jumps = _c0_knots(curve, float(t[0]), float(t[-1])) if check_curve else (np.zeros(0), np.zeros(0))
    if breaks.size:
        t = np.union1d(t, breaks)  # the initial samples hold every knot already; this keeps it so
    # The curve is known only within the edge's tolerance: its direction over a chord no longer
    # than that is noise (a fitted intersection curve rounds a crossing's corner within it, as at
    # the singular points of the Steinmetz solid), so such chords are never tested for turning.
    known = max(float(b.edge_tol[edge]), 0.0)
    for _ in range(_MAX_EDGE_ROUNDS):
        tm = 0.5 * (t[:-1] + t[1:])
        P = _edge_eval(b, edge, curve, t)
        Pm = _edge_eval(b, edge, curve, tm)
        bad = np.zeros(tm.shape, dtype=bool)
        if check_curve:
            bad |= np.linalg.norm(Pm - 0.5 * (P[:-1] + P[1:]), axis=1) > d
            # Turning inside each interval (half chords) and between consecutive chords; at a C0 knot
            # (always a sample, never inside an interval) the chords may turn by the corner's angle more.
            resolved = np.linalg.norm(P[1:] - P[:-1], axis=1) > known
            bad |= (_turning(Pm - P[:-1], P[1:] - Pm) > a) & resolved
            allowed = np.full(t.size - 2, a)
            if breaks.size:
                at = np.searchsorted(t[1:-1], breaks)
                allowed[at] += jumps
            turn = (_turning(P[1:-1] - P[:-2], P[2:] - P[1:-1]) > allowed) & resolved[:-1] & resolved[1:]
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
            if check_curve and t.size > 3:
                dev = np.linalg.norm(Pm - 0.5 * (P[:-1] + P[1:]), axis=1)
                keep = _decimated(b, edge, curve, t, P, dev, sides, d, a, known, breaks, jumps, closed)
                t, P = t[keep], P[keep]
            return _resolved_samples(t, P, known)
        t = np.sort(np.concatenate([t, tm[bad]]))
    raise ConvergenceError(
        f"edge {edge}: discretisation did not reach deflection {d:g} / angle {a:g} in {_MAX_EDGE_ROUNDS} bisection rounds"
    )


def _decimated(b, edge, curve, t: np.ndarray, P: np.ndarray, dev: np.ndarray, sides, d: float, a: float,
               known: float, breaks: np.ndarray, jumps: np.ndarray, closed: bool) -> np.ndarray:
    """Indices ``(k,)`` of a sub-sequence of the bisection's samples ``t (n,)`` (points ``P (n, 3)``) whose
    chords still meet every criterion of step 1, with both ends, the C0 knots and, for a closed edge,
    three segments at least.

    The bisection starts from (degree + 1) samples per knot span, which for a curve fitted to an
    intersection within ``tol.linear`` (hundreds of spans) is far denser than the deflection asks.
    A chord over the dense samples ``i < k < j`` is kept when (1) every dense chord between its ends
    lies within ``d`` of it, measured as the larger distance of its ends to the coarse chord plus
    its own midpoint deviation ``dev (n - 1,)`` (the curve lies within ``dev`` of the dense chord as
    far as the bisection's midpoint test tells, and the dense chord within its ends' distance of the
    coarse one); (2) every dense chord longer than ``known`` deviates in direction by at most ``θ/2``
    from it (the tangent turns by at most ``θ`` along it); (3) the tests of the bisection hold for
    the coarse chord itself: midpoint deviation, turning of its half chords and against its
    neighbours (plus the corner's angle at a C0 knot), and the curved-p-curve side criterion.
    Chords that fail are split at their middle dense sample, all at once, until none fails; dense
    chords passed the bisection, so this ends within ``log2 n`` rounds (top-down, as Douglas–Peucker
    1973 with the bisection's criteria as the test).
    """
    n = t.size
    keep = np.zeros(n, dtype=bool)
    keep[[0, -1]] = True
    jump_at = np.zeros(n)
    if breaks.size:
        at = np.searchsorted(t, breaks)  # every break is a sample (the bisection kept it so)
        keep[at] = True
        jump_at[at] = jumps
    if closed:
        keep[[n // 3, (2 * n) // 3]] = True
    chord = P[1:] - P[:-1]
    clen = np.linalg.norm(chord, axis=1)
    resolved = clen > known
    uvs = [np.asarray(pc.evaluate(t), dtype=np.float64) for pc, _ in sides]
    point = np.arange(n)
    while True:
        idx = np.flatnonzero(keep)
        lo, hi = idx[:-1], idx[1:]
        multi = hi - lo > 1
        if not multi.any():
            return idx
        A, B = P[lo], P[hi]
        AB = B - A
        L = np.linalg.norm(AB, axis=1)
        unit = np.divide(AB, L[:, None], out=np.zeros_like(AB), where=L[:, None] > 0)
        # (1) and (2), per dense sample and chord against the coarse chord that holds it.
        owner = np.minimum(np.searchsorted(idx, point, side="right") - 1, lo.size - 1)
        w = P - A[owner]
        s = np.clip(np.einsum("ij,ij->i", w, unit[owner]), 0.0, L[owner])
        dist = np.linalg.norm(w - s[:, None] * unit[owner], axis=1)
        co = owner[:-1]
        worst = np.maximum(dist[:-1], np.where(keep[1:], 0.0, dist[1:])) + dev
        turned = _turning(chord, AB[co]) > 0.5 * a
        fail = (worst > d) | (turned & resolved & (L[co] > known))
        bad = np.bincount(co, weights=fail, minlength=lo.size) > 0
        # (3) the bisection's own tests on the coarse chords.
        j = np.flatnonzero(multi)
        tm = 0.5 * (t[lo[j]] + t[hi[j]])
        Pm = _edge_eval(b, edge, curve, tm)
        bad[j] |= np.linalg.norm(Pm - 0.5 * (A[j] + B[j]), axis=1) > d
        bad[j] |= (_turning(Pm - A[j], B[j] - Pm) > a) & (L[j] > known)
        turn = (_turning(AB[:-1], AB[1:]) > a + jump_at[lo[1:]]) & (L[:-1] > known) & (L[1:] > known)
        bad[:-1] |= turn
        bad[1:] |= turn
        for (_, S), uv in zip(sides, uvs):
            mid = 0.5 * (uv[lo[j]] + uv[hi[j]])
            w = S.evaluate(mid[:, 0], mid[:, 1]) - A[j]
            off = w - np.einsum("ij,ij->i", w, unit[j])[:, None] * unit[j]
            bad[j] |= np.linalg.norm(off, axis=1) > d
        bad &= multi
        if not bad.any():
            return idx
        keep[(lo[bad] + hi[bad]) // 2] = True


def _resolved_samples(t: np.ndarray, P: np.ndarray, known: float) -> np.ndarray:
    """Samples ``t (k,)`` (points ``P (k, 3)``) without the interior ones within ``known`` of the last kept sample
    or of the end: points the edge's tolerance cannot tell apart would become mesh vertices at one place
    (a knot cluster of a fitted curve at a crossing gives samples 1e-17 apart).  Both ends are kept."""
    step = np.linalg.norm(P[1:] - P[:-1], axis=1)
    if t.size <= 2 or not np.any(step <= known):
        return t
    keep = [0]
    for i in range(1, t.size - 1):  # cold: only edges with sub-tolerance chords get here
        if np.linalg.norm(P[i] - P[keep[-1]]) > known and np.linalg.norm(P[-1] - P[i]) > known:
            keep.append(i)
    keep.append(t.size - 1)
    return t[np.asarray(keep)]


def _linspace(t0: float, t1: float, n: int) -> np.ndarray:
    """``n + 1`` equal steps from ``t0`` to ``t1`` (both exact), cheaper than ``np.linspace`` for small ``n``."""
    t = t0 + (t1 - t0) / n * np.arange(n + 1.0)
    t[-1] = t1
    return t


def _union_samples(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Sorted union of two sample sets over the same range, merging values within round-off of each other."""
    t = np.union1d(x, y)
    if t.size > 2:
        keep = np.ones(t.size, dtype=bool)
        keep[1:] = np.diff(t) > _PLAN_RTOL * (t[-1] - t[0])
        keep[-1] = True
        keep[-2] &= t[-1] - t[-2] > _PLAN_RTOL * (t[-1] - t[0])  # the exact end wins over a near copy
        t = t[keep]
    return t


def _subdivided(t: np.ndarray, gap: float) -> np.ndarray:
    """``t`` with every interval longer than ``gap`` split into equal parts no longer than it (vectorised)."""
    g = np.diff(t)
    k = np.maximum(1, np.ceil(g / gap * (1 - 1e-12)).astype(np.int64))
    if (k == 1).all():
        return t
    owner = np.repeat(np.arange(g.size), k)
    j = np.arange(owner.size) - np.repeat(np.cumsum(k) - k, k)
    return np.append(t[:-1][owner] + g[owner] * j / k[owner], t[-1])


# ============================================================================ revolved faces (strips)
_REVOLVED = (CylindricalSurface, ConicalSurface, SphericalSurface, ToroidalSurface)


def _meridian(S) -> tuple[str, float, float, float]:
    """``(kind, ρ_T, z_T, r)`` of a revolved surface's meridian in its half-plane ``(ρ, z)``.

    ``"circle"``: centre ``(ρ_T, z_T)``, radius ``r`` (sphere, torus).  ``"line"``: ``r`` is
    ``|cos α|``, ``α`` the angle between the line and the axis (cylinder 1, cone ``cos a``).
    """
    if isinstance(S, SphericalSurface):
        return "circle", 0.0, 0.0, float(S.radius)
    if isinstance(S, ToroidalSurface):
        return "circle", float(S.major_radius), 0.0, float(S.minor_radius)
    if isinstance(S, ConicalSurface):
        return "line", 0.0, 0.0, abs(math.cos(S.semi_angle))
    return "line", 0.0, 0.0, 1.0


def _meridian_key(S) -> tuple:
    """What a revolved surface's meridian depends on (equal keys: equal meridians, whatever the placement)."""
    if isinstance(S, CylindricalSurface):
        return "cylinder", float(S.radius)
    if isinstance(S, ConicalSurface):
        return "cone", float(S.radius), float(S.semi_angle)
    if isinstance(S, SphericalSurface):
        return "sphere", float(S.radius)
    return "torus", float(S.major_radius), float(S.minor_radius)


def _meridian_rho(S, v: float) -> float:
    """Axis distance ``ρ(v)`` of a revolved surface at one ``v`` (scalar :func:`_meridian_points`)."""
    if isinstance(S, CylindricalSurface):
        return float(S.radius)
    if isinstance(S, ConicalSurface):
        return S.radius + v * math.sin(S.semi_angle)
    if isinstance(S, SphericalSurface):
        return S.radius * math.cos(v)
    return S.major_radius + S.minor_radius * math.cos(v)


def _meridian_points(S, v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Axis distance ``ρ(v)`` and height ``z(v)`` of the surface's points at ``v`` (OCCT parametrisations)."""
    if isinstance(S, CylindricalSurface):
        return np.full(v.shape, float(S.radius)), v
    if isinstance(S, ConicalSurface):
        sa, ca = math.sin(S.semi_angle), math.cos(S.semi_angle)
        return S.radius + v * sa, v * ca
    if isinstance(S, SphericalSurface):
        return S.radius * np.cos(v), S.radius * np.sin(v)
    return S.major_radius + S.minor_radius * np.cos(v), S.minor_radius * np.sin(v)


def _strip_spans(circle: np.ndarray, rho_t: np.ndarray, z_t: np.ndarray, r: np.ndarray, ra: np.ndarray,
                 za: np.ndarray, rb: np.ndarray, zb: np.ndarray, d: float, a: float) -> np.ndarray:
    """Largest ``u``-span ``(m,)`` of a triangle in each of ``m`` strips between rows with meridian points
    ``(ra, za)`` and ``(rb, zb)``; per strip the meridian is a circle (``circle``; centre ``(rho_t, z_t)``,
    radius ``r``) or a line (``r = |cos α|``), as :func:`_meridian` gives.

    The strip bound of the module docstring (step 3a), solved for ``c = cos(s/2)`` in closed
    form: ``1 − c ≤ δ / ρ`` for the largest admissible inward shift ``δ`` of the chord, then
    ``s = 4 asin(sqrt((1 − c) / 2))`` (stable for small ``1 − c``), capped by the normal
    turning ``θ / |n_ρ|``, by the tilt of a triangle's plane (``δ ≤ ℓ tan θ`` for a meridian
    chord of length ``ℓ``: a long row segment next to a short meridian step would make a
    triangle face away from the surface) and by π/2.  0 marks a strip whose meridian chord
    alone leaves the surface by more than ``d`` (rows too far apart).
    """
    rmax = np.maximum(ra, rb)
    if not circle.any():  # cylinders and cones only
        with np.errstate(divide="ignore"):  # ρ_max = 0 (both rows at an apex, never in a face): no bound
            lim = d / (r * rmax)  # the distance of (c ρ, z) to the line is (1 - c) ρ |cos α|
            if a < 0.5 * math.pi:  # the tilt bound, as below
                lim = np.minimum(lim, np.hypot(rb - ra, zb - za) * math.tan(a) / rmax)
        s = 4.0 * np.arcsin(np.sqrt(np.minimum(lim, 2.0) * 0.5))
        return np.minimum(np.minimum(s, a / r), _MAX_CHORD_TURN)
    big = rmax > 0
    safe = np.where(big, rmax, 1.0)
    half_chord2 = 0.25 * ((rb - ra) ** 2 + (zb - za) ** 2)
    # Inward: |q - T|^2 >= D^2 - 2 δ w + δ^2 >= (r - d)^2, K = D^2 - (r - d)^2 written without cancellation;
    # vacuous where r <= d.
    K = d * (2.0 * r - d) - half_chord2
    inward = circle & (r > d)
    infeasible = inward & (K < 0)
    w = rmax - rho_t
    tight = inward & (w > 0) & (w * w > K) & ~infeasible
    root = np.sqrt(np.where(tight, w * w - K, 1.0))
    delta_in = np.where(tight, K / np.where(tight, w + root, 1.0), np.inf)
    # Outward, exactly at the trapezoid's inner corners: δ_k^2 - 2 δ_k w_k <= E.
    E = d * (2.0 * r + d)
    lim = delta_in / safe
    for rk in (ra, rb):
        wk = rk - rho_t
        root = np.sqrt(wk * wk + E)
        delta_out = np.where(wk >= 0, wk + root, E / (root - wk))
        lim = np.minimum(lim, np.where(rk > 0, delta_out / np.where(rk > 0, rk, 1.0), np.inf))
    n_rho = np.minimum(np.maximum(np.abs(ra - rho_t), np.abs(rb - rho_t)) / r, 1.0)
    n_rho = np.where((za - z_t) * (zb - z_t) <= 0, 1.0, n_rho)  # the strip passes the meridian's widest point
    # Mixed batches: straight meridians as in the branch above.
    lim = np.where(circle, lim, d / (r * safe))
    n_rho = np.where(circle, n_rho, r)
    if a < 0.5 * math.pi:
        # A triangle's plane holds a row chord, pulled in by δ = (1 - c) ρ, and a corner one meridian
        # chord ℓ away: it tilts from the surface normal by atan(δ / ℓ), kept within θ.
        lim = np.minimum(lim, np.hypot(rb - ra, zb - za) * math.tan(a) / safe)
    lim = np.where(big, lim, np.inf)
    s = 4.0 * np.arcsin(np.sqrt(np.minimum(lim, 2.0) * 0.5))
    s = np.minimum(s, a / np.where(n_rho > 0, n_rho, a / _MAX_CHORD_TURN))
    s = np.minimum(s, _MAX_CHORD_TURN)
    return np.where(infeasible, 0.0, s)


def _meridian_rows(S, kind: str, r: float, v0: float, v1: float, d: float, a: float) -> np.ndarray:
    """Designed rows ``v`` of a revolved face: its ends for straight meridians, equal steps for circles
    (meridian chord deviation ``_MERIDIAN_SHARE · d``, turning ``θ``, at most π/2)."""
    if kind == "line":
        return np.array([v0, v1])
    h = 4.0 * math.asin(min(1.0, math.sqrt(_MERIDIAN_SHARE * d / (2.0 * r))))
    h = min(h, a, _MAX_CHORD_TURN)
    return _linspace(v0, v1, max(1, math.ceil((v1 - v0) / h * (1 - 1e-12))))


@dataclass
class _Revolved:
    """The plan of a face meshed by strips (step 0): its rectangle, sides and designed rows."""

    face: int
    S: object
    flip: bool  # face_sense False: the strip triangles (counter-clockwise in (u, v)) are reversed
    u0: float
    u1: float
    v0: float
    v1: float
    sides: dict  # "bottom" | "right" | "top" | "left" -> list of coedges
    line: dict  # coedge -> (u, v) origin and direction of its Line2D p-curve, 4 floats
    kind: str
    rho_t: float
    z_t: float
    r: float
    rows: np.ndarray  # designed v of the rows
    spans: np.ndarray  # designed largest u-span per strip


@dataclass
class _Proposal:
    """What the planned faces ask of an edge: explicit samples (meridians) and largest gaps (parallels), in ``t``."""

    samples: list = field(default_factory=list)
    gaps: list = field(default_factory=list)


def _zip_strips(row_len: np.ndarray, ids: np.ndarray, keys: np.ndarray, first: np.ndarray,
                last: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Triangles ``(m, 3)`` (counter-clockwise in (u, v)) and the row of each ``(m,)`` joining consecutive rows.

    Rows are stored one after the other (``row_len (R,)`` points each, ``ids`` and ``keys``
    (normalised ``u`` in [0, 1], increasing within a row) per point); ``first``/``last (R,)``
    mark the first and last row of each face (no strip across faces).  The segments of the
    lower row (A) and upper row (B) of a strip are merged in the order of their midpoint keys:
    an A segment ``(a_k, a_{k+1})`` makes the triangle ``(a_k, a_{k+1}, b_j)`` with ``b_j`` the
    B point reached so far, a B segment ``(b_j, b_{j+1})`` the triangle ``(a_i, b_{j+1}, b_j)``.
    Both sides of every comparison use the same floating-point keys ``strip + mid``, so the two
    views of the merge agree and the strip is tiled exactly once.
    """
    R = row_len.size
    ptr = np.zeros(R + 1, dtype=np.int64)
    np.cumsum(row_len, out=ptr[1:])
    n = ids.size
    row_of = np.repeat(np.arange(R), row_len)
    is_end = np.zeros(n, dtype=bool)
    is_end[ptr[1:] - 1] = True
    gp = np.flatnonzero(~is_end)  # left point of each segment
    g_row = row_of[gp]
    mid = 0.5 * (keys[gp] + keys[gp + 1])
    # A segments (rows that are not a face's last) in strip = their row; B segments in strip = row - 1.
    ia = np.flatnonzero(~last[g_row])
    ib = np.flatnonzero(~first[g_row])
    sa = g_row[ia]
    sb = g_row[ib] - 1
    KA = sa + mid[ia]
    KB = sb + mid[ib]
    a_start = np.searchsorted(KA, np.arange(R), side="left")
    b_start = np.searchsorted(KB, np.arange(R), side="left")
    j = np.searchsorted(KB, KA, side="left") - b_start[sa]  # B segments before each A segment
    i = np.searchsorted(KA, KB, side="right") - a_start[sb]  # A segments before (or tied with) each B segment
    pa = gp[ia]
    pb = gp[ib]
    TA = np.stack([ids[pa], ids[pa + 1], ids[ptr[sa + 1] + j]], axis=1)
    TB = np.stack([ids[ptr[sb] + i], ids[pb + 1], ids[pb]], axis=1)
    return np.concatenate([TA, TB]), np.concatenate([sa, sb])


# ============================================================================ faces (general path)
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

    def __init__(self, b: BRep, d: float, a: float, t: Tolerance, refine: dict[int, int] | None = None) -> None:
        self.b, self.d, self.a, self.tol = b, d, a, t
        self.points: list[np.ndarray] = [b.vertex_point]
        self.n_points = b.n_vertices
        # Faces triangled in bulk (polyhedral, strips, fans): (triangles (m, 3) mesh ids, faces (m,)).
        self.blocks: list[tuple[np.ndarray, np.ndarray]] = []
        # Faces triangulated one by one: their local triangulation (see _FaceMesh).
        self.faces: dict[int, _FaceMesh] = {}
        # Samples of the edges that need more than their two ends (others: the range and the vertices).
        self.edge_t: dict[int, np.ndarray] = {}
        self.edge_ids: dict[int, np.ndarray] = {}
        self.straight = _straight_edges(b)  # (E,) no curve or a Line
        # Step 0: revolved faces meshed by strips, and what they ask of their edges.
        self.revolved: dict[int, _Revolved] = {}
        self.proposals: dict[int, _Proposal] = {}
        # NURBS surfaces that are planes within the linear tolerance: surface index -> row of ``flat_frames``
        # (origin, x_dir, y_dir, normal along Su x Sv), made into PlanarSurface values only where needed.
        self.flat, self.flat_frames = _flat_nurbs_planes(b.surfaces, t.linear)
        self._flat_planes: dict[int, PlanarSurface] = {}
        # Edges whose parameter steps are halved this many times (chords crossing, see _tessellate).
        self.refine: dict[int, int] = refine or {}

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

    def triangles(self, local: bool = False) -> tuple:
        """All triangles ``(m, 3)`` (mesh ids) and their faces ``(m,)``; with ``local`` also each one's row in its
        face's local triangulation ``(m,)`` (-1: a face triangled in bulk)."""
        Ts, Fs, Ls = [], [], []
        for T, F in self.blocks:
            if self.faces:  # a face re-triangulated one by one (chord repair) replaces its bulk triangles
                keep = ~np.isin(F, list(self.faces))
                T, F = T[keep], F[keep]
            Ts.append(T)
            Fs.append(F)
            if local:
                Ls.append(np.full(F.size, -1, dtype=np.int64))
        for f, fm in self.faces.items():
            Ts.append(fm.ids[fm.T])
            Fs.append(np.full(fm.T.shape[0], f, dtype=np.int64))
            if local:
                Ls.append(np.arange(fm.T.shape[0], dtype=np.int64))
        if not Ts:
            T, F, L = np.zeros((0, 3), np.int64), np.zeros(0, np.int64), np.zeros(0, np.int64)
        elif len(Ts) == 1:
            T, F, L = Ts[0].reshape(-1, 3), Fs[0], Ls[0] if local else None
        else:
            T, F, L = np.concatenate(Ts).reshape(-1, 3), np.concatenate(Fs), np.concatenate(Ls) if local else None
        return (T, F, L) if local else (T, F)

    def mesh(self, T: np.ndarray, F: np.ndarray) -> TriangleMesh:
        """The mesh of triangles ``T`` (mesh ids) with faces ``F``, without the points no triangle uses."""
        V = self.point_array()
        if not self.faces and T.shape[0] and self.b.loop_vertex.max(initial=-1) < 0:
            # Strips, fans and polygons use every point they are given (a lone-vertex loop's vertex, or the grid
            # points of a face triangulated one by one, may be left out: see below).
            return TriangleMesh(V, T, F)
        # Drop unused points (grid points outside a face, interiors of re-triangulated faces), keeping the order.
        used = np.zeros(V.shape[0], dtype=bool)
        used[T.ravel()] = True
        if used.all():
            return TriangleMesh(V, T, F)
        remap = np.cumsum(used) - 1
        return TriangleMesh(V[used], remap[T], F)

    # ------------------------------------------------------------------ chord conflicts
    def repair_conflicts(self, T: np.ndarray, F: np.ndarray, local: np.ndarray) -> None:
        """Split chords that two of the triangles ``T`` (faces ``F``, rows ``local`` in their face's triangulation) use
        in the same direction.

        Two faces that share two boundary vertices not joined by a shared edge (the two
        hemispheres of a coarse sphere share both meridians) can each draw the chord between
        them, and a collapsed pole gap can make a face draw one twice: the edge would be used
        by four triangles.  The offending chords get their midpoints as extra interior points
        of their faces, which are then triangulated again (boundary segments are never split).
        """
        n = np.int64(self.n_points)
        key = (T * n + T[:, [1, 2, 0]]).ravel()
        order = np.argsort(key, kind="stable")
        sk = key[order]
        same = sk[1:] == sk[:-1]
        dup = np.zeros(key.shape, dtype=bool)
        dup[order[1:][same]] = True
        dup[order[:-1][same]] = True
        extra_uv: dict[int, list[np.ndarray]] = {}
        extra_xyz: dict[int, list[np.ndarray]] = {}
        V = self.point_array()
        boundary = None
        for corner in np.flatnonzero(dup):
            t, j = divmod(int(corner), 3)
            f = int(F[t])
            if local[t] < 0:  # a face triangled in bulk: re-triangulate it with the 3-D midpoint
                a, c = int(T[t, j]), int(T[t, (j + 1) % 3])
                if boundary is None:
                    boundary = self._edge_chords()
                if (min(a, c), max(a, c)) in boundary:
                    # (its midpoint would be an interior point on the face's own boundary, exactly so
                    # where the edge is a straight line of the parameter plane: a tangent ruling)
                    continue
                extra_xyz.setdefault(f, []).append(0.5 * (V[a] + V[c]))
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

    def _edge_chords(self) -> set[tuple[int, int]]:
        """The chords ``(min, max)`` between consecutive mesh vertices of every edge (its discretisation;
        an edge without one runs straight between its two vertices, whose mesh ids are theirs)."""
        ids = [x for x in self.edge_ids.values() if x.size > 1]
        plain = np.setdiff1d(np.arange(self.b.n_edges), np.fromiter(self.edge_ids, dtype=np.int64))
        ids.append(self.b.edge_vertex[plain].T.copy() if plain.size else np.zeros((2, 0), np.int64))
        lo = np.concatenate([np.minimum(x[:-1], x[1:]).ravel() for x in ids])
        hi = np.concatenate([np.maximum(x[:-1], x[1:]).ravel() for x in ids])
        return set(zip(lo.tolist(), hi.tolist()))

    # ------------------------------------------------------------------ step 0
    def plan_revolved_faces(self) -> None:
        """Find the faces meshed by strips, design their rows and record what they ask of their edges."""
        b = self.b
        if not any(isinstance(S, _REVOLVED) for S in b.surfaces):
            return
        kinds = [isinstance(S, _REVOLVED) for S in b.surfaces]
        fs, ptr = b.face_surface.tolist(), b.face_loop_ptr.tolist()
        candidates = [f for f in range(b.n_faces) if fs[f] >= 0 and kinds[fs[f]] and ptr[f + 1] - ptr[f] == 1]
        if not candidates:
            return
        # Python lists of the few columns the scalar planning reads (cheaper than numpy scalars).
        tables = (b.coedge_next.tolist(), b.loop_coedge.tolist(), b.face_loops.tolist(), ptr, b.edge_pcurve.tolist(),
                  b.edge_range.tolist(), b.face_sense.tolist(), fs)
        plans = [p for p in (self._plan(f, tables) for f in candidates) if p is not None]
        if not plans:
            return
        # Faces on equal surfaces (up to placement) over the same v-range share their design (the two halves of a
        # cylinder, the hemispheres, the walls of equal holes): the strip spans once per design.
        design: dict[tuple, np.ndarray] = {}
        for plan in plans:
            key = (_meridian_key(plan.S), plan.v0, plan.v1)
            sp = design.get(key)
            if sp is None and plan.kind == "line":  # one strip: the bound in scalar arithmetic
                ra, rb = _meridian_rho(plan.S, plan.v0), _meridian_rho(plan.S, plan.v1)
                rmax = max(ra, rb)
                lim = self.d / (plan.r * rmax)
                if self.a < 0.5 * math.pi:
                    lim = min(lim, math.hypot(rb - ra, plan.r * (plan.v1 - plan.v0)) * math.tan(self.a) / rmax)
                sp = design[key] = np.array([min(4.0 * math.asin(math.sqrt(min(lim, 2.0) * 0.5)), self.a / plan.r,
                                                 _MAX_CHORD_TURN)])
            elif sp is None:
                rho, z = _meridian_points(plan.S, plan.rows)
                m = rho.size - 1
                sp = design[key] = _strip_spans(np.full(m, plan.kind == "circle"), np.full(m, plan.rho_t),
                                                np.full(m, plan.z_t), np.full(m, plan.r), rho[:-1], z[:-1], rho[1:],
                                                z[1:], self.d, self.a)
                if not (sp > 0).all():
                    sp = design[key] = np.zeros(0)
            if sp.size == 0:
                continue
            plan.spans = sp
            self.revolved[plan.face] = plan
            for name, s in (("bottom", float(sp[0])), ("top", float(sp[-1]))):
                for c in plan.sides[name]:
                    self.proposals.setdefault(c >> 1, _Proposal()).gaps.append(s / abs(plan.line[c][2]))
            if plan.kind == "circle":
                for c in plan.sides["left"] + plan.sides["right"]:
                    e = c >> 1
                    t0, t1 = b.edge_range[e].tolist()
                    t = (plan.rows - plan.line[c][1]) / plan.line[c][3]
                    slack = _PLAN_RTOL * (t1 - t0)
                    t = np.sort(t[(t > t0 + slack) & (t < t1 - slack)])
                    self.proposals.setdefault(e, _Proposal()).samples.append(np.concatenate([[t0], t, [t1]]))

    def _plan(self, f: int, tables: tuple) -> _Revolved | None:
        """The strip plan of face ``f`` (rows designed, spans not yet), or None when the face is not a rectangle
        of a revolved surface (step 0).  Scalar Python over the B-rep columns ``tables`` as lists (see
        :meth:`plan_revolved_faces`): a face has a handful of coedges."""
        b = self.b
        nxt, loop_coedge, face_loops, ptr, edge_pcurve, edge_range, face_sense, fs = tables
        S = b.surfaces[fs[f]]
        c = first = loop_coedge[face_loops[ptr[f]]]
        cs = []
        while True:
            cs.append(c)
            c = nxt[c]
            if c == first or len(cs) > 64:  # a longer loop is no rectangle's boundary
                break
        if len(cs) < 2 or c != first:
            return None
        pis = [edge_pcurve[c >> 1][c & 1] for c in cs]
        if min(pis) < 0:
            return None
        pcs = [b.pcurves[p] for p in pis]
        if any(type(p) is not Line2D for p in pcs):
            return None
        geo = []  # per coedge: (horizontal, start u, start v, travel u, travel v, length in (u, v))
        for c, pc in zip(cs, pcs):
            t0, t1 = edge_range[c >> 1]
            ox, oy = pc.origin.tolist()
            dx, dy = pc.direction.tolist()
            if abs(dy) <= 1e-14 * abs(dx):
                horizontal = True
            elif abs(dx) <= 1e-14 * abs(dy):
                horizontal = False
            else:
                return None
            sgn = -1.0 if c & 1 else 1.0
            geo.append((horizontal, ox + t0 * dx, oy + t0 * dy, ox + t1 * dx, oy + t1 * dy, sgn * dx, sgn * dy,
                        abs(t1 - t0) * abs(dx if horizontal else dy), ox, oy, dx, dy))
        us = [g[1] for g in geo] + [g[3] for g in geo]
        vs = [g[2] for g in geo] + [g[4] for g in geo]
        u0, u1, v0, v1 = min(us), max(us), min(vs), max(vs)
        du, dv = u1 - u0, v1 - v0
        if not (du > 0 and dv > 0 and du <= math.pi * (1 + _PLAN_RTOL)):
            return None
        sides: dict[str, list[int]] = {"bottom": [], "right": [], "top": [], "left": []}
        length = dict.fromkeys(sides, 0.0)
        ccw = cw = True
        eu, ev = _PLAN_RTOL * du, _PLAN_RTOL * dv
        for c, (horizontal, su, sv, _, _, tu, tv, ell, *_) in zip(cs, geo):
            # Counter-clockwise: bottom +u, right +v, top -u, left -v.
            if horizontal and abs(sv - v0) <= ev:
                name, fwd = "bottom", tu > 0
            elif horizontal and abs(sv - v1) <= ev:
                name, fwd = "top", tu < 0
            elif not horizontal and abs(su - u0) <= eu:
                name, fwd = "left", tv < 0
            elif not horizontal and abs(su - u1) <= eu:
                name, fwd = "right", tv > 0
            else:
                return None
            sides[name].append(c)
            length[name] += ell
            ccw &= fwd
            cw &= not fwd
        sense = face_sense[f]
        if ccw == cw or ccw != sense or not (sides["left"] and sides["right"]):
            return None  # not a rectangle's boundary, or loops contradicting the sense (the general path reports it)
        kind, rho_t, z_t, r = _meridian(S)
        rho = [_meridian_rho(S, v0), _meridian_rho(S, v1)]
        scale = max(abs(rho[0]), abs(rho[1]), r if kind == "circle" else 0.0, 1e-300)
        # The sides cover the rectangle once (their lengths add up); a missing bottom or top is a pole.
        for name, full, pole in (("bottom", du, rho[0]), ("top", du, rho[1]), ("left", dv, None), ("right", dv, None)):
            if not sides[name] and pole is not None:
                if abs(pole) > _PLAN_RTOL * scale:
                    return None
            elif abs(length[name] - full) > _PLAN_RTOL * full:
                return None
        if kind == "line" and min(rho) < -_PLAN_RTOL * scale:
            return None  # a cone face across its apex
        if isinstance(S, SphericalSurface) and max(-v0, v1) > 0.5 * math.pi * (1 + 1e-12):
            return None
        rows = _meridian_rows(S, kind, r, v0, v1, self.d, self.a)
        line = {c: (g[8], g[9], g[10], g[11]) for c, g in zip(cs, geo)}
        return _Revolved(f, S, not sense, u0, u1, v0, v1, sides, line, kind, rho_t, z_t, r, rows, np.zeros(0))

    # ------------------------------------------------------------------ step 1
    def discretise_edges(self) -> None:
        b = self.b
        # Straight edges without curved p-curves need only their ends: decided for all edges at once.
        curved = _curved_side_edges(b).tolist()
        ec, er, ev = b.edge_curve.tolist(), b.edge_range.tolist(), b.edge_vertex.tolist()
        straight = self.straight.tolist()
        todo = [e for e in range(b.n_edges)
                if not straight[e] or curved[e] or ev[e][0] == ev[e][1] or e in self.proposals or e in self.refine]
        if not todo:  # a polyhedron: the B-rep vertices are all the boundary points
            self.boundary_points = self.point_array()
            return
        curves = b.curves
        ts = [self._edge_samples(e, curved[e], *er[e], None if ec[e] < 0 else curves[ec[e]], ev[e][0] == ev[e][1])
              for e in todo]
        self._at_least_a_triangle(todo, ts)
        # Circle samples are evaluated for all circle edges at once, as Circle.evaluate would (same operations).
        rows: dict[int, int] = {}  # curve index -> row of the frames array
        circles, which = [], []
        for k, e in enumerate(todo):
            if ts[k].size > 2 and ec[e] >= 0 and isinstance(curves[ec[e]], Circle):
                circles.append(k)
                which.append(rows.setdefault(ec[e], len(rows)))
        first: dict[int, int] = {}
        if circles:
            count = [ts[k].size - 2 for k in circles]
            frames = np.empty((len(rows), 10))
            for i, ci in enumerate(rows):
                c = curves[ci]
                frames[i, 0] = c.radius
                frames[i, 1:4] = c.center
                frames[i, 4:7] = c.x_dir
                frames[i, 7:10] = c.y_dir
            F = frames[np.repeat(which, count)] if len(rows) > 1 else frames
            t = np.concatenate([ts[k][1:-1] for k in circles])
            P = ((F[:, 0] * np.cos(t))[:, None] * F[:, 4:7] + (F[:, 0] * np.sin(t))[:, None] * F[:, 7:10]) + F[:, 1:4]
            start = self.n_points
            self.add_points(P)
            for k, n in zip(circles, count):
                first[k] = start
                start += n
        for k, (e, t) in enumerate(zip(todo, ts)):
            n = t.size - 2
            if k in first:
                s0 = first[k]
            elif n > 0:
                s0 = self.n_points
                self.add_points(_edge_eval(b, e, self._curve(e), t[1:-1]))
            ids = np.arange(s0 - 1, s0 + n + 1) if n > 0 else np.empty(2, dtype=np.int64)
            ids[0], ids[-1] = ev[e]
            self.edge_t[e] = t
            self.edge_ids[e] = ids
        # Every boundary sample of every face is a B-rep vertex or an edge sample, all made by now.
        self.boundary_points = self.point_array()

    def _at_least_a_triangle(self, todo: list[int], ts: list[np.ndarray]) -> None:
        """Bisect curved edges of loops that would have fewer than three boundary samples (in place).

        A sliver face bounded by an arc and a line (or two curved edges) whose chords are within the
        deflection gets only their two end points: a polygon without area.  Halving the longest (in
        parameter) curved edge of such a loop, once or twice, gives it a triangle; the samples stay
        shared with the edge's other face.
        """
        b = self.b
        nseg = np.ones(b.n_edges, dtype=np.int64)
        nseg[todo] = [t.size - 1 for t in ts]
        count = np.bincount(b.edge_loop.ravel(), weights=np.repeat(nseg, 2), minlength=b.n_loops)
        thin = np.nonzero((count < 3) & (b.loop_coedge >= 0))[0]
        if thin.size == 0:
            return
        where = {e: k for k, e in enumerate(todo)}
        for lp in thin.tolist():
            edges = [e for e in np.unique(np.nonzero(b.edge_loop == lp)[0]).tolist() if e in where]
            for _ in range(3 - int(count[lp])):
                if not edges:
                    break  # only straight edges: an invalid loop, which the triangulator reports
                # A curved edge first: bisecting a straight one would only add a collinear point.
                pick = [e for e in edges if not self.straight[e]] or edges
                k = where[max(pick, key=lambda e: np.diff(ts[where[e]]).max())]
                t = ts[k]
                i = int(np.argmax(np.diff(t)))
                ts[k] = np.insert(t, i + 1, 0.5 * (t[i] + t[i + 1]))

    def _curve(self, e: int):
        ci = int(self.b.edge_curve[e])
        return None if ci < 0 else self.b.curves[ci]

    def _edge_samples(self, e: int, curved_sides: bool, t0: float, t1: float, curve, closed: bool) -> np.ndarray:
        """Parameters of edge ``e`` (range ``t0, t1``, ``curve``): its own discretisation, merged with what its
        planned faces ask."""
        base = _edge_params(self.b, e, self.d, self.a, curved_sides, t0, t1, curve, closed)
        halve = self.refine.get(e, 0)
        if halve:
            base = _subdivided(base, float(np.diff(base).max()) / 2**halve)
        prop = self.proposals.get(e)
        if prop is None:
            return base
        closed_form = (curve is None or isinstance(curve, (Line, Circle))) and not curved_sides
        t = base
        if prop.samples:
            want = prop.samples[0]
            for other in prop.samples[1:]:
                if other.shape != want.shape or not np.allclose(other, want, rtol=0, atol=_PLAN_RTOL * abs(t1 - t0)):
                    want = _union_samples(want, other)
            finer = np.diff(want).max() <= np.diff(base).max() * (1 + _PLAN_RTOL)
            t = want if (closed_form and finer) else _union_samples(want, base)
        if prop.gaps:
            gap = min(prop.gaps)
            if closed_form and not prop.samples:
                n = max(base.size - 1, math.ceil((t1 - t0) / gap * (1 - 1e-12)))
                t = base if n == base.size - 1 else _linspace(t0, t1, n)
            else:
                t = _subdivided(t, gap)
        return self._off_the_ends(e, curve, t) if prop.samples else t

    def _off_the_ends(self, e: int, curve, t: np.ndarray) -> np.ndarray:
        """``t`` without the interior samples within ten tolerances of the edge's end vertices.

        A planned face's row lands there when the face's box (from its fitted p-curves) ends a
        hair off the edge's end: a second mesh point at the vertex, and the chord of the next edge,
        leaving the vertex from a p-curve end as far off, can cross the short chord between them.
        (Both sides of a plan must then agree again; where they do not, the face takes the general path.)
        """
        b = self.b
        reach = 10.0 * max(self.tol.linear, float(b.edge_tol[e]))
        V = b.vertex_point[b.edge_vertex[e]]
        while t.size > 2:
            P = np.asarray(_edge_eval(b, e, curve, t[[1, -2]]), dtype=np.float64).reshape(2, 3)
            near = np.linalg.norm(P - V, axis=1) <= reach
            if not near.any():
                break
            t = np.delete(t, [k for k, n in zip((1, t.size - 2), near.tolist()) if n])
        return t

    def samples(self, e: int) -> tuple[np.ndarray, np.ndarray]:
        """Parameters ``(k,)`` and mesh vertex ids ``(k,)`` of the samples of edge ``e``, start to end."""
        if e in self.edge_t:
            return self.edge_t[e], self.edge_ids[e]
        return self.b.edge_range[e], self.b.edge_vertex[e]

    # ------------------------------------------------------------------ steps 2-6
    def triangulate_faces(self) -> None:
        b = self.b
        # Faces on planes (implicit or PlanarSurface) bounded by straight edges are polygons:
        # their loops, counter-clockwise seen from outside, give outward triangles directly.
        plane_s = [isinstance(S, PlanarSurface) or i in self.flat for i, S in enumerate(b.surfaces)] + [True]
        fs = b.face_surface.tolist()
        plane = [plane_s[s] for s in fs]
        curved = set(b.edge_face[~self.straight].ravel().tolist()) if not self.straight.all() else set()
        bulk = [p and f not in curved for f, p in enumerate(plane)]
        if all(bulk):  # a polyhedron
            self._polyhedral(np.arange(b.n_faces))
            return
        if any(bulk):
            self._polyhedral(np.flatnonzero(bulk))
        rest = self._strips([self.revolved[f] for f in sorted(self.revolved)]) if self.revolved else []
        rest += [f for f, k in enumerate(bulk) if not k and f not in self.revolved]
        ptr = b.face_loop_ptr.tolist()
        fans = [f for f in rest if plane[f] and ptr[f + 1] - ptr[f] == 1]
        if fans:
            left = set(self._convex_fans(fans))
            rest = [f for f in rest if f in left or not (plane[f] and ptr[f + 1] - ptr[f] == 1)]
        for f in rest:
            self._surface_face(int(f))

    # .................................................................. step 3a: strips
    def _side(self, plan: _Revolved, name: str, axis: int, scale: float = 1.0,
              shift: float = 0.0) -> tuple[np.ndarray, np.ndarray] | None:
        """``(x - shift) * scale`` for the parameters ``x`` (``axis`` 0: u, 1: v) of the samples along one side of a
        planned face, increasing, and their mesh ids; None if they do not increase strictly."""
        cs = plan.sides[name]
        if len(cs) == 1:  # the usual case: one edge, a straight p-curve, monotone in t
            t, ids = self.samples(cs[0] >> 1)
            o, dx = plan.line[cs[0]][axis], plan.line[cs[0]][2 + axis]
            x = t * (dx * scale) + (o - shift) * scale
            return (x, ids) if dx > 0 else (x[::-1], ids[::-1])
        xs, idss = [], []
        for c in cs:
            t, idx = self.samples(c >> 1)
            o, dx = plan.line[c][axis], plan.line[c][2 + axis]
            xs.append(t * (dx * scale) + (o - shift) * scale)
            idss.append(idx)
        x, i = np.concatenate(xs), np.concatenate(idss)
        order = np.argsort(x, kind="stable")
        x, i = x[order], i[order]
        keep = np.ones(x.size, dtype=bool)
        keep[1:] = i[1:] != i[:-1]  # the shared end of two edges along the side
        x, i = x[keep], i[keep]
        if (x[1:] <= x[:-1]).any():
            return None
        return x, i

    def _rows(self, plan: _Revolved) -> tuple[list, list, list] | None:
        """Rows of a planned face from the actual edge samples, bottom to top: the mesh ids and the keys (u normalised
        to [0, 1]) of their points, as arrays each holding one row or, in the middle, all interior rows, and the
        lengths of the rows; None to fall back to the general path."""
        du, dv = plan.u1 - plan.u0, plan.v1 - plan.v0
        left, right = self._side(plan, "left", 1), self._side(plan, "right", 1)
        if left is None or right is None:
            return None
        (VL, IL), (VR, IR) = left, right
        if VL.size != VR.size or (VL.size > 2 and np.abs(VL - VR).max() > _PLAN_RTOL * dv):
            return None
        ends = []
        for name, k in (("bottom", 0), ("top", -1)):
            if plan.sides[name]:
                side = self._side(plan, name, 0, 1.0 / du, plan.u0)
                if side is None or side[1][0] != IL[k] or side[1][-1] != IR[k]:
                    return None
                ends.append(side)
            else:  # a pole: one mesh vertex, the end of both meridians
                if IL[k] != IR[k]:
                    return None
                ends.append((np.array([0.5]), IL[:1] if k == 0 else IL[-1:]))
        if VL.size == plan.rows.size and (VL.size == 2 or np.abs(VL - plan.rows).max() <= _PLAN_RTOL * dv):
            s, V = plan.spans, plan.rows  # the rows as designed (to round-off)
        else:  # the edges were sampled otherwise (a neighbour asked for more): bound the actual strips
            V = 0.5 * (VL + VR)
            rho, z = _meridian_points(plan.S, V)
            m = V.size - 1
            one = np.ones(m)
            s = _strip_spans(np.full(m, plan.kind == "circle"), plan.rho_t * one, plan.z_t * one, plan.r * one,
                             rho[:-1], z[:-1], rho[1:], z[1:], self.d, self.a)
            if not (s > 0).all():
                return None
        (kb, ib), (kt, it) = ends
        if (kb.size > 1 and (kb[1:] - kb[:-1]).max() * du > s[0] * (1 + _PLAN_RTOL)) or (
            kt.size > 1 and (kt[1:] - kt[:-1]).max() * du > s[-1] * (1 + _PLAN_RTOL)
        ):
            return None
        if V.size == 2:  # one strip: the two boundary rows
            return [ib, it], [kb, kt], [ib.size, it.size]
        need = np.ceil(du / s * (1 - 1e-12)).astype(np.int64)
        n_int = np.maximum(np.maximum(need[:-1], need[1:]), 2)  # interior rows 1 .. m-1
        L = n_int + 1
        total = int(L.sum())
        starts = np.cumsum(L) - L
        n_rep = np.repeat(n_int, L)
        pos = np.arange(total) - np.repeat(starts, L)
        keys = pos / n_rep
        ids = np.empty(total, dtype=np.int64)
        inner = (pos > 0) & (pos < n_rep)
        ids[starts] = IL[1:-1]
        ids[starts + n_int] = IR[1:-1]
        row = np.repeat(np.arange(n_int.size), n_int - 1)
        ids[inner] = self.add_points(plan.S.evaluate(plan.u0 + du * keys[inner], V[1:-1][row]))
        return [ib, ids, it], [kb, keys, kt], [ib.size, *L.tolist(), it.size]

    def _strips(self, plans: list[_Revolved]) -> list[int]:
        """Mesh the planned faces by strips, all at once; returns the faces that fall back to the general path.

        A face of one strip whose two rows have the same points in ``u`` (a cylinder's or a frustum's
        side, a hole's wall) is cut into quads split along one diagonal, which is what the merge gives
        for equal keys, written in closed form; all other strips go through :func:`_zip_strips`.
        """
        ids, keys, lens, fallback, faces, flips, n_rows = [], [], [], [], [], [], []
        quads, quad_faces, quad_flips = [], [], []
        for plan in plans:
            rows = self._rows(plan)
            if rows is None:
                fallback.append(plan.face)
                continue
            if len(rows[2]) == 2 and rows[2][0] == rows[2][1] and rows[2][0] > 1 and \
                    np.abs(rows[1][0] - rows[1][1]).max() <= _PLAN_RTOL:
                quads.append(np.stack(rows[0]))
                quad_faces.append(plan.face)
                quad_flips.append(plan.flip)
                continue
            ids += rows[0]
            keys += rows[1]
            lens += rows[2]
            faces.append(plan.face)
            flips.append(plan.flip)
            n_rows.append(len(rows[2]))
        if quads:
            self._quad_strips(quads, quad_faces, quad_flips)
        if not faces:
            return fallback
        row_len = np.array(lens, dtype=np.int64)
        per_face = np.array(n_rows)
        row_face = np.repeat(np.array(faces, dtype=np.int64), per_face)
        ends = np.cumsum(per_face)
        first = np.zeros(row_len.size, dtype=bool)
        first[ends - per_face] = True
        last = np.zeros(row_len.size, dtype=bool)
        last[ends - 1] = True
        T, row = _zip_strips(row_len, np.concatenate(ids), np.concatenate(keys), first, last)
        if any(flips):
            flip = np.repeat(np.array(flips), per_face)[row]
            T[flip] = T[flip][:, [0, 2, 1]]
        self.blocks.append((T, row_face[row]))
        return fallback

    def _quad_strips(self, rows: list[np.ndarray], faces: list[int], flips: list[bool]) -> None:
        """Triangles of one-strip faces whose rows ``(2, k)`` (bottom, top ids) match point for point: each quad
        ``a_i a_{i+1} b_{i+1} b_i`` gives ``(a_i, a_{i+1}, b_i)`` and ``(a_{i+1}, b_{i+1}, b_i)``."""
        size = [r.shape[1] for r in rows]
        for k in sorted(set(size)):
            sel = [i for i, n in enumerate(size) if n == k]
            R = np.stack([rows[i] for i in sel]) if len(sel) > 1 else rows[sel[0]][None]
            A, B = R[:, 0], R[:, 1]
            T = np.empty((len(sel), k - 1, 2, 3), dtype=np.int64)
            T[:, :, 0, 0] = A[:, :-1]
            T[:, :, 0, 1] = T[:, :, 1, 0] = A[:, 1:]
            T[:, :, 0, 2] = T[:, :, 1, 2] = B[:, :-1]
            T[:, :, 1, 1] = B[:, 1:]
            T = T.reshape(-1, 3)
            fl = [flips[i] for i in sel]
            if any(fl):
                flip = np.repeat(np.array(fl), 2 * (k - 1))
                T[flip] = T[flip][:, [0, 2, 1]]
            self.blocks.append((T, np.repeat(np.array([faces[i] for i in sel], dtype=np.int64), 2 * (k - 1))))

    # .................................................................. step 3b: convex planar faces
    def _convex_fans(self, faces: list[int]) -> list[int]:
        """Fan the planar faces whose one loop is a strictly convex polygon (vectorised by polygon size);
        returns the others."""
        b = self.b
        nxt, first_coedge = b.coedge_next.tolist(), b.loop_coedge[b.face_loops[b.face_loop_ptr[faces]]].tolist()
        ec, er = b.edge_curve.tolist(), b.edge_range.tolist()
        rings, disk = [], []
        for c0 in first_coedge:
            parts, cs, c = [], [], c0
            while True:
                ids = self.samples(c >> 1)[1]
                parts.append(ids[:0:-1] if c & 1 else ids[:-1])
                cs.append(c)
                c = nxt[c]
                if c == c0:
                    break
            rings.append(parts[0] if len(parts) == 1 else np.concatenate(parts))
            # Arcs of one circle making a full turn: their samples are an inscribed polygon, convex by construction.
            ci = [ec[c >> 1] for c in cs]
            disk.append(ci[0] >= 0 and ci.count(ci[0]) == len(ci) and isinstance(b.curves[ci[0]], Circle)
                        and abs(sum(abs(er[c >> 1][1] - er[c >> 1][0]) for c in cs) - 2.0 * math.pi) <= 1e-9)
        size = [r.size for r in rings]
        rest = []
        for k in sorted(set(size)):
            sel = [i for i, n in enumerate(size) if n == k]
            fk = [faces[i] for i in sel]
            if k < 3:
                rest += fk
                continue
            ring = np.stack([rings[i] for i in sel])
            si = b.face_surface[fk]
            if all(disk[i] for i in sel):
                convex = np.ones(len(sel), dtype=bool)
            elif si.min() >= 0:  # PlanarSurface faces: the test in the plane's own coordinates
                sign = np.where(b.face_sense[fk], 1.0, -1.0)
                convex = _convex_in_plane(self.boundary_points[ring], *self._plane_frames(si), sign)
            else:
                convex = _strictly_convex(self.boundary_points[ring])
            ok = convex.tolist()
            if all(ok):
                self.blocks.append((_fan(ring), np.repeat(np.array(fk, dtype=np.int64), k - 2)))
            elif any(ok):
                self.blocks.append((_fan(ring[convex]), np.repeat(np.array(fk, dtype=np.int64)[convex], k - 2)))
            rest += [f for f, yes in zip(fk, ok) if not yes]
        return rest

    def _plane_frames(self, surfaces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``x_dir`` and ``y_dir`` ``(n, 3)`` of the planar surfaces ``surfaces (n,)`` (indices)."""
        flat, surf = self.flat, self.b.surfaces
        if flat and all(i in flat for i in surfaces.tolist()):
            rows = [flat[i] for i in surfaces.tolist()]
            return self.flat_frames[rows, 1], self.flat_frames[rows, 2]
        S = [self.flat_plane(i) if i in flat else surf[i] for i in surfaces.tolist()]
        return np.array([x.x_dir for x in S]), np.array([x.y_dir for x in S])

    def flat_plane(self, si: int) -> PlanarSurface:
        """The plane of the flat NURBS surface ``si`` (see :func:`_flat_nurbs_planes`), made once."""
        S = self._flat_planes.get(si)
        if S is None:
            o, x, _, n = self.flat_frames[self.flat[si]]
            S = self._flat_planes[si] = PlanarSurface(o, n, x)
        return S

    # .................................................................. polyhedral faces
    def _polyhedral(self, faces: np.ndarray) -> None:
        b = self.b
        if b.n_loops == b.n_faces:  # one loop per face (the usual polyhedron)
            single, rest = faces, []
            loops = b.face_loops[faces]
        else:
            n_loops = b.face_loop_ptr[faces + 1] - b.face_loop_ptr[faces]
            one = n_loops == 1
            single = faces[one]
            loops = b.face_loops[b.face_loop_ptr[single]]
            rest = [faces[~one]]
        length = np.bincount(b.coedge_loop, minlength=b.n_loops)[loops]
        lo, hi = (int(length.min()), int(length.max())) if single.size else (0, -1)
        for k in [lo] if lo == hi else np.unique(length).tolist():
            fk, lk = (single, loops) if lo == hi else (single[length == k], loops[length == k])
            ring = _rings(b, lk, k)  # (nf, k) vertex ids
            if k == 3:
                self.blocks.append((ring, fk))
                continue
            P = b.vertex_point[ring]
            si = b.face_surface[fk]
            if si.min() >= 0:  # PlanarSurface faces: the test in the planes' own coordinates
                convex = _convex_in_plane(P, *self._plane_frames(si), np.where(b.face_sense[fk], 1.0, -1.0))
            else:
                convex = _strictly_convex(P)
            if convex.all():
                r = ring
            else:
                r = ring[convex]
                rest.append(fk[~convex])
                fk = fk[convex]
            if r.shape[0]:
                self.blocks.append((_fan(r), np.repeat(fk, k - 2)))
        for f in np.concatenate(rest).tolist() if rest else []:
            self._surface_face(f)

    # .................................................................. general faces
    def _surface_face(self, f: int, extra_uv: np.ndarray | None = None, extra_xyz: np.ndarray | None = None) -> None:
        """Triangulate face ``f`` (steps 2-6), with optional extra interior points (parameters, or 3-D points of planes)."""
        b = self.b
        si = int(b.face_surface[f])
        if si < 0:
            S, sense = _newell_plane(b, f), True
        else:
            S, sense = self.flat_plane(si) if si in self.flat else b.surfaces[si], bool(b.face_sense[f])
        bd = self._boundary(f, S)
        planar = isinstance(S, PlanarSurface)
        if planar:
            steps, scale = (math.inf, math.inf), np.array([1.0, 1.0])
        else:
            lo, hi = bd.uv.min(axis=0), bd.uv.max(axis=0)
            steps, metric = _grid_steps(S, lo, hi, self.d, self.a)
            scale = _plane_scale(S, bd.uv, steps, metric)
        # Counter-clockwise loops in the triangulation plane: mirror u when the face is reversed.
        if not sense:
            scale = scale * np.array([-1.0, 1.0])
        X_b = bd.uv * scale
        extra = np.zeros((0, 2)) if extra_uv is None else np.asarray(extra_uv, dtype=np.float64).reshape(-1, 2)
        if extra_xyz is not None and len(extra_xyz):
            extra = np.concatenate([extra, S.closest_parameters(extra_xyz)])
        uv_in = np.zeros((0, 2)) if planar else self._grid(S, bd, X_b, scale, steps)
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
        si = int(b.face_surface[f])
        if pi >= 0 and si >= 0 and si not in self.flat:
            uv = b.pcurves[pi].evaluate(t)
        elif isinstance(S, PlanarSurface):
            # An implicit plane, a plane without p-curves or a flat NURBS surface (whose p-curves live in its own
            # parameters, not the plane's): project the mesh vertices of the samples.
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
                if np.linalg.norm(uv_i[-1] - nxt) > _SAME_UV * extent and self._pole_gap(
                        S, int(cs[i]), int(cs[(i + 1) % len(cs)]), uv_i[-1], nxt):
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

    def _pole_gap(self, S, c: int, c_next: int, p: np.ndarray, q: np.ndarray) -> bool:
        """Whether the parameter jump from ``p`` (end of coedge ``c``) to ``q`` (start of ``c_next``) is a pole or apex.

        Two p-curves meeting at one vertex end at slightly different parameters when they are
        fitted (each within its edge tolerance); at a pole they end far apart along the collapsed
        side.  The jump measured with the surface's largest first derivative at ``p`` tells them
        apart: a fitting mismatch maps to at most the sum of the two edges' tolerances in space
        (each end may be off by its own), a pole's jump (``|Su| = 0`` but ``|Sv|`` of the order of
        the radius) to much more.
        """
        D = S.derivatives(p[0], p[1], 1)
        stretch = max(float(np.linalg.norm(D[1, 0])), float(np.linalg.norm(D[0, 1])))
        et = self.b.edge_tol
        allowed = max(self.tol.linear, float(et[c >> 1]) + float(et[c_next >> 1]))
        if not float(np.linalg.norm(p - q)) * stretch > allowed:
            return False
        # Near but not at a pole (a vertex 1° from it) the slow direction makes a fitting mismatch
        # look long: it is a pole only where a parameter is undetermined (moving it over its whole
        # range moves the point by less than the tolerance); else the two ends are one point and a
        # gap segment there may cross the next chord.
        return bool(singular_parameters(S, np.stack([p, q]), None, self.tol).any())

    def _grid(self, S, bd: _Boundary, X_b: np.ndarray, scale: np.ndarray, steps: tuple[float, float]) -> np.ndarray:
        """Interior candidate parameters ``(q, 2)`` (unscaled) of a curved face: the grid of ``steps`` inside the box."""
        lo, hi = bd.uv.min(axis=0), bd.uv.max(axis=0)
        lines = []
        for h, a0, a1 in ((steps[0], lo[0], hi[0]), (steps[1], lo[1], hi[1])):
            n = math.ceil((a1 - a0) / h * (1 - 1e-12)) if math.isfinite(h) and h > 0 else 1
            lines.append(np.linspace(a0, a1, n + 1)[1:-1])
        if (lines[0].size == 0) != (lines[1].size == 0) and _even_metric(S, lo, hi, 1 if lines[0].size == 0 else 0):
            # One curved direction (cylinders, cones away from the apex): lines of the other direction at the
            # same step in the triangulation plane (unit squares there, see _plane_scale), instead of none at all.
            k = 0 if lines[0].size == 0 else 1
            h = 1.0 / abs(scale[k])
            n = math.ceil((hi[k] - lo[k]) / h * (1 - 1e-12))
            lines[k] = np.linspace(lo[k], hi[k], n + 1)[1:-1]
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
            error = TopologyError(f"face {f}: its boundary cannot be triangulated in parameter space: {exc}")
            error.__cause__ = exc
            raise _Crossing(self._crossing_edges(X_b, bd), error) from exc
        uv_all = np.concatenate([bd.uv, uv_in])
        ids_all = np.concatenate([bd.ids, np.full(uv_in.shape[0], -1, dtype=np.int64)])
        return cdt, T, idx, uv_all, ids_all

    def _crossing_edges(self, X: np.ndarray, bd: _Boundary) -> set[int]:
        """The curved edges (not sides of planned faces) with a boundary chord properly crossing another chord
        of the face (points ``X (p, 2)`` in the triangulation plane); empty when no such edge.

        A chord between two samples of one edge is that edge's; a chord between two B-rep vertices is
        every edge joining them.  Cold: only a face that failed to triangulate gets here.
        """
        seg = bd.segments
        a, c = X[seg[:, 0]], X[seg[:, 1]]
        i, j = np.triu_indices(seg.shape[0], 1)
        cross = proper_crossings(a[i], c[i], a[j], c[j])
        hit = np.unique(np.concatenate([i[cross], j[cross]]))
        if hit.size == 0:
            return set()
        on_face = set(bd.ids.tolist())
        owner: dict[int, int] = {}
        for e, ids in self.edge_ids.items():
            for i in ids[1:-1].tolist():
                if i in on_face:
                    owner[i] = e
        ends: dict[tuple[int, int], list[int]] = {}
        for e, (v0, v1) in enumerate(self.b.edge_vertex.tolist()):
            ends.setdefault((min(v0, v1), max(v0, v1)), []).append(e)
        out: set[int] = set()
        for k in hit.tolist():
            i, j = (int(x) for x in bd.ids[seg[k]])
            if i in owner or j in owner:
                out.add(owner.get(i, owner.get(j)))
            else:
                out.update(ends.get((min(i, j), max(i, j)), []))
        planned = {e for e, prop in self.proposals.items() if prop.samples}
        return {e for e in out if not self.straight[e] and e not in planned}

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
_LEVI_CIVITA = np.zeros((3, 3, 3))
_LEVI_CIVITA[0, 1, 2] = _LEVI_CIVITA[1, 2, 0] = _LEVI_CIVITA[2, 0, 1] = 1.0
_LEVI_CIVITA[0, 2, 1] = _LEVI_CIVITA[2, 1, 0] = _LEVI_CIVITA[1, 0, 2] = -1.0


def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Row-wise cross products of ``(..., 3)`` arrays (``np.cross`` without the axis bookkeeping that dominates
    small calls): one einsum with the Levi-Civita symbol for small arrays, the explicit formula for large ones."""
    if a.size <= 768 and b.size <= 768:
        return np.einsum("ijk,...j,...k->...i", _LEVI_CIVITA, a, b)
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
    if b.n_edges == 0 or all(isinstance(S, PlanarSurface) for S in b.surfaces):
        return np.zeros(b.n_edges, dtype=bool)
    if all(isinstance(p, Line2D) for p in b.pcurves):
        return np.zeros(b.n_edges, dtype=bool)
    pc_straight = np.array([isinstance(p, Line2D) for p in b.pcurves] + [True], dtype=bool)
    s_plane = np.array([isinstance(S, PlanarSurface) for S in b.surfaces] + [True], dtype=bool)
    surf = b.face_surface[b.edge_face]  # (E, 2)
    return np.any(~pc_straight[b.edge_pcurve] & ~s_plane[surf], axis=1)


def _fan(ring: np.ndarray) -> np.ndarray:
    """Fan triangles ``(nf (k - 2), 3)`` of polygons ``ring (nf, k)`` (ids in order) from their first corner."""
    nf, k = ring.shape
    T = np.empty((nf, k - 2, 3), dtype=ring.dtype)
    T[:, :, 0] = ring[:, :1]
    T[:, :, 1] = ring[:, 1:-1]
    T[:, :, 2] = ring[:, 2:]
    return T.reshape(-1, 3)


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
    """``(nf,)`` True for polygons ``P (nf, k, 3)`` that turn strictly one way about their Newell normal, once.

    Every corner must turn left by more than 1e-9 radians (a corner clearly not collinear) and
    the turns must add up to one full turn, which excludes star polygons.
    """
    k = P.shape[1]
    nxt = np.arange(1, k + 1) % k
    Q = P[:, nxt]
    n = _cross(P, Q).sum(axis=1)
    e0 = Q - P
    e1 = e0[:, nxt]
    nn = np.sqrt(np.einsum("fj,fj->f", n, n))[:, None]
    with np.errstate(divide="ignore", invalid="ignore"):  # a polygon without area: NaN turns, not convex
        turn = np.einsum("fkj,fj->fk", _cross(e0, e1), n) / nn  # |e0| |e1| sin(turn)
    dot = np.einsum("fkj,fkj->fk", e0, e1)  # |e0| |e1| cos(turn)
    ok = turn > 1e-9 * np.hypot(turn, dot)
    total = np.arctan2(turn, dot).sum(axis=1)  # 2π for a convex polygon, 4π for a pentagram
    return ok.all(axis=1) & (total < 3.0 * math.pi)


def _convex_in_plane(P: np.ndarray, X: np.ndarray, Y: np.ndarray, sign: np.ndarray) -> np.ndarray:
    """:func:`_strictly_convex` for polygons ``P (nf, k, 3)`` lying in known planes with directions ``X, Y (nf, 3)``;
    ``sign (nf,)`` is +1 where the polygon should turn counter-clockwise in ``(X, Y)`` and -1 where clockwise (the
    face's sense).  Two dimensions make it cheaper; turns need edge vectors only, so no origin."""
    k = P.shape[1]
    nxt = np.arange(1, k + 1) % k
    E = P[:, nxt] - P
    eu = np.einsum("fkj,fj->fk", E, X)
    ev = np.einsum("fkj,fj->fk", E, Y)
    fu, fv = eu[:, nxt], ev[:, nxt]
    turn = sign[:, None] * (eu * fv - ev * fu)  # |e0| |e1| sin(turn)
    dot = eu * fu + ev * fv
    ok = (turn > 1e-9 * np.hypot(turn, dot)).all(axis=1)
    if k < 5:  # k left turns, each below π, add up to less than 4π: one full turn
        return ok
    return ok & (np.arctan2(turn, dot).sum(axis=1) < 3.0 * math.pi)  # 2π for a convex polygon, 4π for a pentagram


def _flat_nurbs_planes(surfaces: list, eps: float) -> tuple[dict[int, int], np.ndarray]:
    """The NURBS surfaces of ``surfaces`` that are planes within ``eps``: index -> row of the frames ``(g, 4, 3)``
    (origin, ``x_dir``, ``y_dir``, normal ``x_dir × y_dir`` along ``Su × Sv``; unit vectors).

    A NURBS surface with positive weights lies in the convex hull of its control points, so
    control points within ``eps`` of a plane put the whole surface there, and a face on it whose
    boundary polygon is triangulated in that plane deviates from it by at most ``2 eps`` (the
    boundary samples lie on the surface; the triangles and the surface both lie in the slab).  The
    plane's normal follows the control net: the cross products of every cell's diagonals
    ``(P₁₁ − P₀₀) × (P₀₁ − P₁₀)`` must all point to one side of the plane (a net folding over
    itself is left to the general path), which is taken as the side of ``Su × Sv`` (exact for
    bilinear patches, whose diagonal product is twice the mean of ``Su × Sv``; for higher degrees
    the control net's orientation, which a regular surface shares).  Vectorised over surfaces with
    the same control grid shape (one batched SVD per shape).
    """
    groups: dict[tuple, list[int]] = {}
    for i, S in enumerate(surfaces):
        cp = getattr(S, "control_points", None)
        if cp is not None and hasattr(S, "knots_u") and cp.ndim == 3 and cp.shape[2] == 3:
            groups.setdefault(cp.shape, []).append(i)
    out: dict[int, int] = {}
    frames = []
    for idx in groups.values():
        P = np.stack([surfaces[i].control_points for i in idx])  # (g, nu, nv, 3)
        c = P.mean(axis=(1, 2))
        Q = (P - c[:, None, None]).reshape(len(idx), -1, 3)
        _, sv, vt = np.linalg.svd(Q, full_matrices=False)
        n = vt[:, 2]
        dist = np.abs(np.einsum("gkj,gj->gk", Q, n)).max(axis=1)
        cells = _cross(P[:, 1:, 1:] - P[:, :-1, :-1], P[:, :-1, 1:] - P[:, 1:, :-1])  # (g, nu-1, nv-1, 3)
        side = np.einsum("gabj,gj->gab", cells, n).reshape(len(idx), -1)
        pos, neg = (side > 0).all(axis=1), (side < 0).all(axis=1)
        ok = (dist <= eps) & (pos | neg) & (sv[:, 1] > 0)
        keep = np.flatnonzero(ok)
        if keep.size == 0:
            continue
        n = np.where(neg[:, None], -n, n)[keep]
        x = vt[keep, 0]
        F = np.stack([c[keep], x, _cross(n, x), n], axis=1)
        for k in keep.tolist():
            out[idx[k]] = len(out)
        frames.append(F)
    return out, np.concatenate(frames) if frames else np.zeros((0, 4, 3))


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


def _plane_scale(S, uv: np.ndarray, steps: tuple[float, float],
                 metric: tuple[float, float] | None = None) -> np.ndarray:
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
    if metric is None:
        lo, hi = uv.min(axis=0), uv.max(axis=0)
        s = (np.arange(_CURVATURE_SAMPLES) + 0.5) / _CURVATURE_SAMPLES
        U, V = np.meshgrid(lo[0] + (hi[0] - lo[0]) * s, lo[1] + (hi[1] - lo[1]) * s, indexing="ij")
        metric = _mean_metric(S.derivatives(U.ravel(), V.ravel(), 1))
    su, sv = metric
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


def _mean_metric(D: np.ndarray) -> tuple[float, float]:
    """Mean ``|Su|`` and ``|Sv|`` over derivatives ``D (k, ≥2, ≥2, 3)``."""
    return float(np.mean(np.linalg.norm(D[:, 1, 0], axis=1))), float(np.mean(np.linalg.norm(D[:, 0, 1], axis=1)))


def _grid_steps(S, lo: np.ndarray, hi: np.ndarray, d: float,
                a: float) -> tuple[tuple[float, float], tuple[float, float]]:
    """Parameter steps ``(h_u, h_v)`` meeting deflection ``d`` and angle ``a`` everywhere on the box (inf: no curvature),
    and the mean metric ``(|Su|, |Sv|)`` over the cell centres of the box (for :func:`_plane_scale`)."""
    s = (np.arange(_CURVATURE_SAMPLES) + 0.5) / _CURVATURE_SAMPLES
    us0 = us = lo[0] + (hi[0] - lo[0]) * s
    vs0 = vs = lo[1] + (hi[1] - lo[1]) * s
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
    # The cell centres are among the samples (knot samples are only added): the metric of _plane_scale.
    centres = (np.isin(us, us0)[:, None] & np.isin(vs, vs0)[None, :]).ravel()
    metric = _mean_metric(D if centres.all() else D[centres])
    Su, Sv = D[:, 1, 0], D[:, 0, 1]
    W = _cross(Su, Sv)
    w = np.linalg.norm(W, axis=1)
    ok = w > 1e-12 * np.maximum(np.linalg.norm(Su, axis=1) * np.linalg.norm(Sv, axis=1), 1e-300)
    if not np.any(ok):
        return (math.inf, math.inf), metric
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

    return (step(L + M, nu, curved_u), step(N + M, nv, curved_v)), metric


def _even_metric(S, lo: np.ndarray, hi: np.ndarray, curved: int) -> bool:
    """True when the metric ``|S_curved|`` of the curved direction varies by less than a factor 2 over the box.

    Then a grid of equal steps is isotropic enough everywhere; near a cone's apex (``|Su| → 0``) it is not,
    and the face is left to the refinement (step 5) as before.
    """
    u = np.array([lo[0], hi[0], lo[0], hi[0], 0.5 * (lo[0] + hi[0])])
    v = np.array([lo[1], lo[1], hi[1], hi[1], 0.5 * (lo[1] + hi[1])])
    D = S.derivatives(u, v, 1)
    g = np.linalg.norm(D[:, 1, 0] if curved == 0 else D[:, 0, 1], axis=1)
    return bool(g.min() > 0.5 * g.max())


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


def _surface_distance(S, P: np.ndarray, uv0: np.ndarray, D0: np.ndarray | None = None) -> np.ndarray:
    """Distance of points ``P (k, 3)`` to the (untrimmed) surface; exact for analytic surfaces.

    Other surfaces: at most four damped Gauss–Newton steps from ``uv0`` inside the surface's
    domain (fewer once every step is below round-off of the domain: the iteration has arrived);
    the distance to the point reached is an upper bound of the true distance (when the iteration
    stops early, the distance to the point the last step started from: a surface point as well,
    so still an upper bound, and within round-off of the next).  ``D0``: the surface derivatives
    ``(k, ≥2, ≥2, 3)`` at ``uv0`` when the caller has them (the first step then evaluates nothing).
    """
    if hasattr(S, "implicit"):
        return np.abs(S.implicit(P))
    uv = uv0.copy()
    (u0, u1), (v0, v1) = S.domain
    # A step this small relative to the domain moves the point by round-off only.
    still = 1e-13 * max(u1 - u0, v1 - v0)
    for i in range(4):
        D = D0 if (i == 0 and D0 is not None) else S.derivatives(uv[:, 0], uv[:, 1], 1)
        r = D[:, 0, 0] - P
        J = np.stack([D[:, 1, 0], D[:, 0, 1]], axis=2)  # (k, 3, 2)
        JtJ = np.einsum("kia,kib->kab", J, J)
        g = np.einsum("kia,ki->ka", J, r)
        lam = 1e-12 * np.trace(JtJ, axis1=1, axis2=2)[:, None, None] * np.eye(2)
        step = np.linalg.solve(JtJ + lam + 1e-300 * np.eye(2), -g[..., None])[..., 0]
        uv = uv + step
        uv[:, 0] = np.clip(uv[:, 0], u0, u1)
        uv[:, 1] = np.clip(uv[:, 1], v0, v1)
        if not np.abs(step).max(initial=0.0) > still:
            return np.linalg.norm(r, axis=1)  # the distance to S(uv before the step), D[:, 0, 0]
    return np.linalg.norm(S.evaluate(uv[:, 0], uv[:, 1]) - P, axis=1)


def _acute_in_hessian(S, uvT: np.ndarray, Cuv: np.ndarray, D: np.ndarray | None = None) -> np.ndarray:
    """``(m,)`` True for triangles ``uvT (m, 3, 2)`` acute in the metric of ``II = [[L, M], [M, N]]`` at their centroids.

    The deviation of a linear interpolant of the height ``½ xᵀ II x`` from the surface is
    ``κ/2 (r² − |x − c|²)`` in the metric where ``II`` is ``κ I``: largest at the
    circumcentre ``c`` for acute triangles (where the centroid holds at least 8/9 of it, since
    ``|c − g| ≤ r/3``), and at the longest edge's midpoint otherwise.  Where ``II`` is
    indefinite (saddles) or singular (developable surfaces) the largest deviation lies on an
    edge, and the triangle counts as not acute.  ``D``: the second-order derivatives ``(m, 3, 3, 3)`` at
    ``Cuv`` when the caller has them.
    """
    if D is None:
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
    edge is a boundary segment (boundary samples are shared with the neighbouring face).  When
    the triangle offends through an interior edge's midpoint and the longest edge does not,
    the worst such edge is split instead (the tail of slow rounds near thin features).
    """
    none = (np.zeros((0, 2)), np.zeros(0, dtype=np.int64))
    if T.shape[0] == 0:
        return none
    m = T.shape[0]
    rows = np.arange(m)
    C = P[T].mean(axis=1)
    Cuv = uv[T].mean(axis=1)
    # Edges (j, j+1) of each triangle; boundary segments are already within d (step 1).
    ea, eb = T, T[:, [1, 2, 0]]
    big = np.int64(uv.shape[0] + 1)
    und = np.minimum(ea, eb) * big + np.maximum(ea, eb)
    s_und = np.minimum(seg[:, 0], seg[:, 1]) * big + np.maximum(seg[:, 0], seg[:, 1])
    interior = ~np.isin(und, s_und)
    Muv = 0.5 * (uv[ea] + uv[eb])
    # Centroids and interior edge midpoints in one (pointwise) distance computation: one surface
    # evaluation setup per Gauss-Newton step instead of two.
    uv0 = np.concatenate([Cuv, Muv[interior]])
    # Non-analytic surfaces: the second derivatives at all starting points serve both the acuteness test
    # (centroids) and the first Gauss-Newton step.
    D = None if hasattr(S, "implicit") else S.derivatives(uv0[:, 0], uv0[:, 1], 2)
    dist = _surface_distance(S, np.concatenate([C, 0.5 * (P[ea] + P[eb])[interior]]), uv0, D)
    dev = np.where(_acute_in_hessian(S, uv[T], Cuv, None if D is None else D[:m]), 9.0 / 8.0, 1.0) * dist[:m]
    if np.any(interior):
        dev_e = np.zeros((m, 3))
        dev_e[interior] = dist[m:]
        dev = np.maximum(dev, dev_e.max(axis=1))
    bad = dev > _REFINE_MARGIN * d
    if not np.any(bad):
        return none
    length = np.linalg.norm(X[ea] - X[eb], axis=2)
    longest = np.argmax(length, axis=1)
    if np.any(interior):
        # A triangle bad through one of its interior edges (the chord's midpoint is off the surface by
        # more than d) is split on that edge when the longest edge is within d: bisecting a good edge
        # would leave the bad one in a neighbour, a slow tail of rounds near thin boundary features.
        worst = np.argmax(dev_e, axis=1)  # boundary edges have dev_e 0
        edge_bad = dev_e[rows, worst] > d
        longest = np.where(edge_bad & (dev_e[rows, longest] <= d), worst, longest)
    split = bad & interior[rows, longest]
    cent = bad & ~split
    pts, where = [Cuv[cent]], [rows[cent]]
    if np.any(split):
        keys = und[rows, longest][split]
        _, first = np.unique(keys, return_index=True)
        pts.append(Muv[rows, longest][split][first])
        where.append(rows[split][first])
    return np.concatenate(pts), np.concatenate(where)
