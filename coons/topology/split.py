"""Trimming curves to a face and splitting a trimmed face by cut edges, in its parameter plane.

:func:`clip_to_face` returns the parts of a p-curve that lie in a trimmed face (:class:`FaceSpec`),
flagging those that run along its boundary; :func:`split_face` cuts a face into the regions of
the planar arrangement formed by its loops and a set of cut edges.  Both are phases of the
Boolean pipeline (``docs/brep.md``, ``coons/booleans``): faces are clipped against the
surface–surface intersection curves, then split, then the pieces are classified and re-sewn by
:func:`coons.topology.sew.sew_faces`.

Everything happens in the face's parameter plane.  Faces without p-curves (an implicit plane,
``surface=None``, or a :class:`~coons.kernel.analytic.PlanarSurface` whose edges carry none)
use the plane's own frame — for an implicit plane the Newell plane through the loop vertices
with the frame of :func:`coons.topology.tessellate._newell_plane` — and 3-D lines, circles,
ellipses and NURBS are mapped into it exactly (the map is affine).  Reversed faces
(``sense=False``, loops clockwise in the parameter plane) are mirrored ``u -> -u`` internally,
so that every outer loop is counter-clockwise, and each parameter axis is scaled by the
largest speed of the surface along it on the boundary (``|Su|``, ``|Sv|``), so that lengths in
the working plane approximate lengths on the surface (a cylinder of radius 100 is not a
hundred times more tolerant around than along).  Sphere and cone poles, where two consecutive
p-curves of a loop end at different parameter points of one vertex, are closed by a virtual
straight segment that takes part in the arrangement but is never emitted as an edge.

Notation: a *piece* is a boundary edge use, a cut, or a virtual pole segment; *sub-pieces* are
the pieces split at their mutual intersections; *nodes* are sub-piece ends merged within the
working-plane tolerance ``eps = tol3 / σ`` (``tol3`` the largest edge tolerance and
``tol.linear``, ``σ`` the largest singular value of the scaled surface Jacobian on the
boundary, at most about 1, so that working-plane points within ``eps`` are within ``tol3`` in
space); *half-edges* are the two directions of a sub-piece.  Where the surface is slow along a
parameter (near a sphere or cone pole) a point known to ``tol3`` in space may lie many ``eps``
away in the plane: there ends within ``tol3`` in space and ``tol3 / σ_min`` in the plane (at
most ``100 eps``) are one node too, and a cut end that stops that short of a piece splits the
piece at its foot (:func:`_snap_cut_ends`).  The regions are the faces of the
arrangement, walked by turning most clockwise at every node (tangent directions, ties broken
by curvature, or, between a curve and a straight piece, by the side of the line on which the curve
lies ten ``eps`` off it: a curve in high-order contact with a straight boundary has a curvature at the
node below what its fit gets right; where a p-curve's radius of curvature at the node is below ``eps`` its tangent
there is a feature below the resolution, as at the hooked end of a branch fitted through a
point where its two surfaces touch, and the chord to a point ten ``eps`` along it serves);
counter-clockwise cycles that lie inside the original face (their boundary
pieces run forward) are outer loops, and each clockwise cycle becomes a hole of the smallest
outer cycle containing it (de Berg et al., *Computational Geometry*, ch. 2, the doubly
connected edge list).

Crossings are found between the p-curves (:func:`~coons.kernel.curve_intersect.intersect_curves`
in the working plane) and then re-solved between the 3-D curves of the two edge uses when
both have derivatives (:func:`~coons.kernel.curve_intersect.refine_intersections`): fitted
p-curves crossing at a small angle would otherwise put a shared vertex at different places
in the two faces that meet there.  A crossing whose 3-D points already coincide exactly keeps
its parameters without Newton (only a strictly closer pair would replace them), and one at a
cut's end is that end, the edge split at its foot: along a tangential touching Newton slides by
``sqrt(gap / curvature)`` off the vertex the cut's other faces have there.

Speed.  The Boolean pipeline clips every intersection branch against a face and then splits
the face: what depends on the face alone — its working plane, the working-plane p-curves of
its loop edges with their boxes, the boundary pieces and the point-in-face polylines — is
computed once per face and tolerance (:class:`_FaceData`, cached weakly on the frozen
:class:`FaceSpec`); each call takes fresh pieces for its own split parameters.  NURBS pieces are
evaluated through their span polynomials (:class:`~coons.kernel.curve_intersect._PowerForm`, built
once per curve object and shared with the curve intersections).  Box tests of
all piece pairs are one array comparison, and the arrangement's nodes are the connected
components of the merged ends by array label propagation.  On a face bounded by one convex loop of
straight pieces (the untouched faces of the primitives are their parameter rectangles) a
polynomial NURBS p-curve that nears the sides only close to its ends is clipped, and its
meetings with the sides as a cut are found, without curve–curve intersection: the control
points bound its distance to each side's line (convex hull, variation diminishing), and the
crossing is one scalar root (:func:`_convex_clip`, :func:`_convex_contacts`); a circle on a half of a
sphere primitive (a branch of sphere–sphere or plane–sphere) is clipped before that in closed form,
from the 3-D circle and the plane of the half's meridians (:func:`_hemisphere_clip`); anything else takes
the general path.  Two cuts sharing one end (consecutive pieces of a branch, branches ending at
one boundary point) are proven to meet only there when the line through the end between their
directions keeps each on its side (monotone control-point distances, :func:`_end_contact_only`):
the end contact is left to the node merge; crossing cuts, and pairs the control points do not
separate, take the general path.  Likewise a cut end within ``eps`` of a piece's end needs no snap
to that piece (:func:`_snap_cut_ends` searches no foot there), and off a cylinder the surface's reach
at the cut ends is evaluated only for a foot between ``eps`` and the widest reach.

The module does not compute intersection curves (:mod:`coons.kernel.intersect`), does not
classify pieces against another solid, does not re-sew, and does not merge faces.  Its
point-in-face test is a winding number of polylines of the loops (33 samples per curved
piece, refined 16-fold twice for probes closer than their chord error): a probe closer to a
curved boundary than the finest chord error may still be misclassified.
"""

from __future__ import annotations

import math
import weakref
from dataclasses import dataclass
from typing import Any, Sequence

import numpy as np

from coons.errors import InvalidInputError
from coons.kernel.analytic import (TWO_PI, Circle, ConicalSurface, CylindricalSurface, Ellipse, Line,
                                   PlanarSurface, SphericalSurface, ToroidalSurface)
from coons.kernel.curve import NurbsCurve
from coons.kernel.curve_intersect import (_derivs, _point1, _project, _scalar_form, curve_box, intersect_curves,
                                         refine_intersections)
from coons.kernel.pcurve import Line2D, Trig2D
from coons.tolerance import Tolerance, resolve
from coons.topology.sew import EdgeSpec, FaceSpec

__all__ = ["clip_to_face", "split_face"]

#: Polyline samples per curved sub-piece for areas and winding numbers.
_SAMPLES = 33
#: Refinement factor and levels of the polylines for points near a curved boundary.
_REFINE = 16
_REFINE_LEVELS = 2


# ====================================================================== parameter plane
@dataclass
class _Plane:
    """How a face's edges reach its (possibly mirrored) parameter plane."""

    surface: Any  # the face's surface, or the Newell PlanarSurface of an implicit plane
    project: bool  # True: p-curves are computed from the 3-D curves (implicit plane)
    M: np.ndarray  # (2, 2) diagonal map (u, v) -> working plane: axis scales, u mirrored for sense False
    eps: float  # parameter-plane tolerance
    tol3: float  # 3-D tolerance
    t: Tolerance  # tolerance object for intersect_curves in the plane
    t3: Tolerance  # the caller's tolerance (3-D)


def _newell(face: FaceSpec) -> PlanarSurface:
    """The Newell plane of a face without surface (same frame as the tessellator's)."""
    P, Q = [], []
    for loop in face.loops:
        for e in loop:
            ends = np.asarray(e.curve.evaluate(np.array([e.t0, e.t1])), dtype=np.float64)
            P.append(ends[0])
            Q.append(ends[1])
    P, Q = np.array(P), np.array(Q)
    n = np.cross(P, Q).sum(axis=0)
    if not np.linalg.norm(n) > 0:
        raise InvalidInputError("face without surface has zero Newell area; expected a planar loop enclosing area")
    x = Q[0] - P[0]
    x = x - np.dot(x, n) / np.dot(n, n) * n
    if not np.linalg.norm(x) > 0:
        x = np.eye(3)[int(np.argmin(np.abs(n)))]
    return PlanarSurface(P.mean(axis=0), n, x)


class _FaceData:
    """What a face contributes to every clip and split of it, computed once per face and tolerance.

    The surface (the Newell plane of an implicit plane), the axis scales ``M`` and ``σ``, the
    largest edge tolerance, the working-plane p-curves of the loop edges, their end points and
    proven boxes, and per working-plane tolerance ``eps`` the boundary pieces (with the virtual
    pole segments, which depend on ``eps``) and their point-in-face polylines (:class:`_Inside`).
    A face is clipped by every branch crossing it and then split by the cuts (``coons.booleans``),
    and all of this depends on the face alone: a :class:`FaceSpec` is frozen (tuples of frozen
    EdgeSpecs over geometry values), so the data stay valid as long as the face lives.
    """

    def __init__(self, face: FaceSpec, t: Tolerance) -> None:
        S = face.surface
        edges = [e for loop in face.loops for e in loop]
        project = S is None
        if S is None:
            S = _newell(face)
        elif not isinstance(S, PlanarSurface) and any(e.pcurve is None for e in edges):
            raise InvalidInputError(f"face on a {type(S).__name__} needs p-curves on every edge; some are None")
        if isinstance(S, PlanarSurface):
            scale, sigma = np.ones(2), 1.0  # the plane's frame is orthonormal
        else:
            lo_hi = np.array([[e.t0, 0.5 * (e.t0 + e.t1), e.t1] for e in edges])
            uv = np.concatenate([np.asarray(e.pcurve.evaluate(tt)) for e, tt in zip(edges, lo_hi)])
            D = np.asarray(S.derivatives(uv[:, 0], uv[:, 1], 1))
            scale = np.array([np.linalg.norm(D[:, 1, 0], axis=1).max(), np.linalg.norm(D[:, 0, 1], axis=1).max()])
            if not np.all(scale > 0):
                raise InvalidInputError(f"the surface does not move along u or v on the whole face boundary, "
                                        f"got speeds {scale.tolist()}; expected both > 0")
            J = np.stack([D[:, 1, 0] / scale[0], D[:, 0, 1] / scale[1]], axis=2)
            sigma = float(np.linalg.norm(J, ord=2, axis=(1, 2)).max())
        self.surface, self.project, self.sigma = S, project, sigma
        self.M = np.diag([scale[0] * (1.0 if face.sense else -1.0), scale[1]])
        self.tol3 = max([t.linear] + [e.tol for e in edges if e.tol is not None])
        # The loops, not the face: the cache holds its values strongly and the face only weakly.
        self.face_loops, self.t = face.loops, t
        self.loops: list[list[tuple[Any, np.ndarray, np.ndarray, np.ndarray]]] | None = None
        self.gaps: list[list[tuple[float, np.ndarray, np.ndarray]]] | None = None  # per loop edge, see pieces
        self.virtual: dict[tuple[int, int], Line2D] = {}  # (loop, edge) -> the virtual segment after the edge
        self.by_eps: dict[float, tuple[list[tuple], _Inside]] = {}
        self.convex: dict[float, tuple | None] = {}  # per eps: :func:`_convex_sides` of the boundary pieces
        self.regions: dict[tuple, _Inside] = {}  # (id(curve), a, b, loop) of the pieces -> their point-in-face test
        self.hemisphere: tuple | None = None  # :func:`_hemisphere` of the face (``()`` for none), when first asked

    def sides(self, plane: _Plane, pieces: list["_Piece"]) -> tuple[np.ndarray, np.ndarray] | None:
        """:func:`_convex_sides` of the boundary ``pieces`` (those of :meth:`pieces`), once per ``eps``."""
        if plane.eps not in self.convex:
            self.convex[plane.eps] = _convex_sides(pieces, plane)
        return self.convex[plane.eps]

    def plane(self, cuts: Sequence[EdgeSpec]) -> _Plane:
        t = self.t
        tol3 = max([self.tol3] + [e.tol for e in cuts if e.tol is not None])
        eps = tol3 / self.sigma
        return _Plane(self.surface, self.project, self.M, eps, tol3, Tolerance(eps, t.angular, t.solver), t)

    def pieces(self, plane: _Plane, fresh: bool = True) -> tuple[list["_Piece"], "_Inside"]:
        """Fresh boundary pieces (their splits are the caller's) sharing cached curves and boxes, and the
        point-in-face test of the face.  ``fresh=False``: the cached pieces themselves, for a caller that
        only reads them (:func:`clip_to_face`; a box it computes is cached on them, the same for every caller)."""
        entry = self.by_eps.get(plane.eps)
        if entry is None:
            if self.loops is None:
                loops = []  # kept only when every edge maps (a bad edge raises on every call)
                for li, loop in enumerate(self.face_loops):
                    pcs = [_pcurve(plane, e, f"loop {li} edge {k}") for k, e in enumerate(loop)]
                    loops.append([(pc, _uv(pc, e.t0), _uv(pc, e.t1), curve_box(pc, (e.t0, e.t1), plane.t))
                                  for pc, e in zip(pcs, loop)])
                self.loops = loops
            if self.gaps is None:
                # Each edge's gap to the next edge's start: its length and the virtual segment across it, the
                # same for every eps (which only decides whether the segment is a piece).
                self.gaps = [[(float(np.linalg.norm(data[(k + 1) % len(data)][1] - q)), q,
                               data[(k + 1) % len(data)][1]) for k, (_, _, q, _) in enumerate(data)]
                             for data in self.loops]
            rows = []
            for li, (loop, data, gaps) in enumerate(zip(self.face_loops, self.loops, self.gaps)):
                for k, (e, (pc, _, _, box)) in enumerate(zip(loop, data)):
                    rows.append((pc, e.t0, e.t1, "boundary", li, e, box))
                    gap, q, p = gaps[k]
                    if gap > plane.eps:
                        line = self.virtual.get((li, k))
                        if line is None:
                            line = self.virtual[(li, k)] = Line2D(q, p - q)
                        rows.append((line, 0.0, 1.0, "virtual", li, None, None))
            pieces = [_Piece(pc, a, b, kind, li, e, [], [], box) for pc, a, b, kind, li, e, box in rows]
            # The point-in-face test reads only the pieces' curves, ranges and loops: another eps with the
            # same virtual segments (the clip's and the split's) shares it, and the polylines it has built.
            key = tuple((id(pc), a, b, li) for pc, a, b, _, li, _, _ in rows)
            region = self.regions.get(key)
            if region is None:
                region = self.regions[key] = _Inside(pieces)
            entry = self.by_eps[plane.eps] = (pieces, region)
        templates, region = entry
        if not fresh:
            return templates, region
        out = [_Piece(p.pc, p.a, p.b, p.kind, p.loop, p.spec, [], [], p.box) for p in templates]
        return out, region


_FACES: "weakref.WeakKeyDictionary[FaceSpec, dict[tuple[float, float, float], _FaceData]]" = \
    weakref.WeakKeyDictionary()


#: The fast paths on: the per-face cache, the skip of exact crossings in :func:`_in_space`, the
#: convex-face clip and contacts (:func:`_convex_clip`, :func:`_convex_contacts`), the shared-end
#: proof (:func:`_end_contact_only`), the span-polynomial evaluation (:func:`_pc_derivatives`), the skip of
#: the foot search for a cut end at a piece's end and the reach evaluated only for a foot that needs it
#: (:func:`_snap_cut_ends`), the straight pieces' directions
#: without evaluation (:meth:`_Graph._directions`), the first graph's reuse of the node labels of
#: :func:`_without_closed_virtual`, :func:`clip_to_face` reading the cached boundary pieces and
#: :func:`_space_reach`'s points of surfaces of revolution from their derivatives; tests switch them off to
#: compare with the general path.
_FAST = True


def _face_data(face: FaceSpec, t: Tolerance) -> _FaceData:
    """The cached :class:`_FaceData` of ``face`` under tolerance ``t``."""
    if not _FAST:
        return _FaceData(face, t)
    per_tol = _FACES.get(face)
    if per_tol is None:
        per_tol = _FACES[face] = {}
    key = (t.linear, t.angular, t.solver)
    data = per_tol.get(key)
    if data is None:
        data = per_tol[key] = _FaceData(face, t)
    return data


def _to_plane(curve: Any, S: PlanarSurface, what: str) -> Any:
    """The exact image of a 3-D curve under the affine map ``P -> ((P - O)·X, (P - O)·Y)``."""
    O = np.asarray(S.origin)
    F = np.asarray(S.frame)[:2]  # rows X, Y
    if isinstance(curve, Line):
        d = F @ curve.direction
        if not np.linalg.norm(d) > 0:
            raise InvalidInputError(f"{what}: line perpendicular to the face plane cannot lie in it")
        return Line2D(F @ (curve.origin - O), d)
    if isinstance(curve, (Circle, Ellipse)):
        a, b = (curve.radius, curve.radius) if isinstance(curve, Circle) else (curve.major_radius, curve.minor_radius)
        X, Y, _ = curve.frame
        try:
            return Trig2D(F @ (curve.center - O), a * (F @ X), b * (F @ Y))
        except InvalidInputError:
            raise InvalidInputError(f"{what}: conic seen edge-on from the face plane cannot lie in it") from None
    if isinstance(curve, NurbsCurve) and curve.dimension == 3:
        return NurbsCurve((curve.control_points - O) @ F.T, curve.knots, curve.degree, curve.weights)
    if isinstance(curve, (Line2D, Trig2D)) or (isinstance(curve, NurbsCurve) and curve.dimension == 2):
        return curve
    raise InvalidInputError(f"{what}: cannot map a {type(curve).__name__} into the face plane; give its p-curve")


_MAPPED: "weakref.WeakKeyDictionary[Any, dict[bytes, Any]]" = weakref.WeakKeyDictionary()


def _mapped(pc: Any, M: np.ndarray) -> Any:
    """The p-curve in the working plane: ``uv -> M uv`` (the parameter is unchanged).

    Cached per p-curve and ``M`` (curves are frozen values): a cut's p-curve is mapped when the
    branch is clipped and again when the face is split, and one mapped object keeps the caches
    of :mod:`coons.kernel.curve_intersect` (a NURBS curve's span polynomials) across the calls."""
    per = _MAPPED.get(pc) if _FAST else None
    key = M.tobytes()
    if per is not None and key in per:
        return per[key]
    if isinstance(pc, (Line2D, Trig2D)):
        out = pc.transformed(M)
    elif isinstance(pc, NurbsCurve):
        out = NurbsCurve(pc.control_points @ M.T, pc.knots, pc.degree, pc.weights)
    else:
        raise InvalidInputError(f"p-curve must be a Line2D, Trig2D or 2-D NurbsCurve, got {type(pc).__name__}")
    if _FAST:
        _MAPPED.setdefault(pc, {})[key] = out
    return out


def _pcurve(plane: _Plane, e: EdgeSpec, what: str) -> Any:
    """The 2-D curve of an edge use in the working plane (projected if planar, then mapped by ``M``)."""
    if plane.project or (e.pcurve is None and isinstance(plane.surface, PlanarSurface)):
        pc = _to_plane(e.curve, plane.surface, what)
    else:
        pc = e.pcurve
        if pc is None:
            raise InvalidInputError(f"{what} has no p-curve on the face's {type(plane.surface).__name__}")
    if not (isinstance(pc, (Line2D, Trig2D)) or (isinstance(pc, NurbsCurve) and pc.dimension == 2)):
        raise InvalidInputError(f"{what}: p-curve must be a Line2D, Trig2D or 2-D NurbsCurve, got {type(pc).__name__}")
    return _mapped(pc, plane.M)


def _uv(pc: Any, t) -> np.ndarray:
    t = np.asarray(t, dtype=np.float64)
    if _FAST and type(pc) is NurbsCurve:
        return _derivs(pc, t.reshape(-1), 0)[:, 0].reshape(t.shape + (pc.dimension,))
    return np.asarray(pc.evaluate(t), dtype=np.float64)


def _pc_derivatives(pc: Any, t: np.ndarray, order: int) -> np.ndarray:
    """``pc.derivatives(t, order)``, ``t.shape + (order + 1, 2)``; a NURBS through its cached span polynomials
    (:class:`~coons.kernel.curve_intersect._PowerForm`: the pieces of one face are evaluated many times)."""
    t = np.asarray(t, dtype=np.float64)
    if _FAST and type(pc) is NurbsCurve:
        return _derivs(pc, t.reshape(-1), order).reshape(t.shape + (order + 1, pc.dimension))
    return np.asarray(pc.derivatives(t, order), dtype=np.float64)


# ====================================================================== pieces
@dataclass
class _Piece:
    pc: Any  # 2-D curve in the working plane
    a: float  # start parameter (direction of travel)
    b: float  # end parameter
    kind: str  # "boundary", "virtual" or "cut"
    loop: int  # index of the face loop (-1 for cuts)
    spec: EdgeSpec | None  # None for virtual segments
    splits: list  # parameters where the piece is split
    dropped: list  # (lo, hi) ranges of a cut that duplicate another piece
    box: np.ndarray | None = None  # (2, 2) bounding box, computed on demand


def _box(p: "_Piece", plane: _Plane) -> np.ndarray:
    """The piece's proven bounding box ``(2, 2)``, cached on the piece.

    A polynomial NURBS piece (a cut) is boxed by its control points acting on its range (convex hull
    property, The NURBS Book §3.2): every use of the box is a conservative prefilter (box meets, then
    the exact test), and for the fitted p-curves of intersection branches, whose control polygons hug
    the curve, this box is at most a little looser than :func:`~coons.kernel.curve_intersect.curve_box`'s
    Bézier pieces, at a small part of their cost."""
    if p.box is None:
        pc = p.pc
        if _FAST and type(pc) is NurbsCurve and not pc.is_rational:
            P = _acting(pc, min(p.a, p.b), max(p.a, p.b))[1]
            p.box = np.stack([P.min(axis=0), P.max(axis=0)])
        else:
            p.box = curve_box(pc, (p.a, p.b), plane.t)
    return p.box


def _polyline(pc: Any, a: float, b: float, n: int | None = None) -> np.ndarray:
    """``(n, 2)`` samples of ``pc`` from ``a`` to ``b`` (2 for a straight line)."""
    if n is None:
        n = 2 if isinstance(pc, Line2D) else _SAMPLES
    # np.linspace(a, b, 2) is [a, b] (its first sample is a + 0 * step, its last b), without its set-up.
    return _uv(pc, np.array([a, b], dtype=np.float64) if n == 2 else np.linspace(a, b, n))


def _next(x: np.ndarray) -> np.ndarray:
    """``np.roll(x, -1, axis=0)`` without its set-up: the next element of each, cyclically."""
    return np.concatenate((x[1:], x[:1]))


def _winding(points: np.ndarray, rings: list[np.ndarray]) -> np.ndarray:
    """Winding numbers ``(m,)`` of ``points`` (m, 2) with respect to closed polylines (Sunday 2001)."""
    if not rings:
        return np.zeros(points.shape[0], dtype=np.int64)
    P = np.concatenate([r for r in rings])
    Q = np.concatenate([x for r in rings for x in (r[1:], r[:1])])  # each ring's next vertices (np.roll by -1)
    x, y = points[:, :1], points[:, 1:]
    cross = (Q[None, :, 0] - P[None, :, 0]) * (y - P[None, :, 1]) - (x - P[None, :, 0]) * (Q[None, :, 1] - P[None, :, 1])
    up = (P[None, :, 1] <= y) & (Q[None, :, 1] > y) & (cross > 0)
    down = (P[None, :, 1] > y) & (Q[None, :, 1] <= y) & (cross < 0)
    return up.sum(axis=1) - down.sum(axis=1)


def _distance(points: np.ndarray, rings: list[np.ndarray]) -> np.ndarray:
    """Distance ``(m,)`` of ``points`` (m, 2) to the closed polylines."""
    P = np.concatenate(rings)
    Q = np.concatenate([x for r in rings for x in (r[1:], r[:1])])  # each ring's next vertices (np.roll by -1)
    d = Q - P
    dd = np.maximum((d * d).sum(axis=1), np.finfo(float).tiny)
    w = points[:, None, :] - P[None]
    f = np.clip((w * d[None]).sum(axis=2) / dd[None], 0.0, 1.0)
    return np.linalg.norm(w - f[..., None] * d[None], axis=2).min(axis=1)


class _Inside:
    """Point-in-face classification by the winding number of polylines of the loops.

    The polylines have :data:`_SAMPLES` points per curved piece; points closer to them than
    their chord error (measured at the segment midpoints) are classified again against
    polylines refined :data:`_REFINE` times, up to :data:`_REFINE_LEVELS` times.
    """

    def __init__(self, pieces: list[_Piece]) -> None:
        self.pieces = [p for p in pieces if p.kind != "cut"]
        self.levels = [self._rings(_SAMPLES)]

    def _rings(self, n: int) -> tuple[list[np.ndarray], float]:
        loops: dict[int, list[np.ndarray]] = {}
        sag = 0.0
        for p in self.pieces:
            m = 2 if isinstance(p.pc, Line2D) else n
            # (np.linspace(a, b, 2) is [a, b], without its set-up)
            t = np.array([p.a, p.b], dtype=np.float64) if m == 2 else np.linspace(p.a, p.b, m)
            P = _uv(p.pc, t)
            if m > 2:
                mid = _uv(p.pc, 0.5 * (t[1:] + t[:-1]))
                sag = max(sag, float(np.linalg.norm(mid - 0.5 * (P[1:] + P[:-1]), axis=1).max()))
            loops.setdefault(p.loop, []).append(P[:-1])
        return [np.concatenate(v) for v in loops.values()], sag

    def winding(self, points: np.ndarray) -> np.ndarray:
        """Winding numbers ``(m,)`` of ``points`` (m, 2) with respect to the face's loops."""
        rings, sag = self.levels[0]
        w = _winding(points, rings)
        n = _SAMPLES
        for level in range(_REFINE_LEVELS):
            near = np.flatnonzero(_distance(points, rings) <= 2.0 * sag) if sag > 0 else np.zeros(0, np.int64)
            if near.size == 0:
                break
            n = (n - 1) * _REFINE + 1
            if len(self.levels) <= level + 1:
                self.levels.append(self._rings(n))
            rings, sag = self.levels[level + 1]
            w[near] = _winding(points[near], rings)
        return w

    def distance(self, points: np.ndarray) -> np.ndarray:
        """Distance ``(m,)`` of ``points`` to the finest polylines built so far."""
        return _distance(points, self.levels[-1][0])


def _in_space(plane: _Plane, c3: Any, r1, e: EdgeSpec | None, s: np.ndarray, u: np.ndarray
              ) -> tuple[np.ndarray, np.ndarray]:
    """Re-solve working-plane crossings ``(s, u)`` between ``c3`` and the edge's 3-D curve.

    The 3-D curves are often exact where p-curves are fits; at a small crossing angle a
    p-curve error ``e`` moves the crossing by ``e / sin(angle)``, enough for two faces sharing
    a vertex to disagree about it.  Crossings that converge in space within ``tol3``, closer
    than they were, take the refined parameters; the others keep theirs.

    A crossing within ``tol3`` in space of an end of ``c3``'s range ``r1`` (a cut), and of the edge,
    is that end (the node merge would join them anyway): the other faces of the cut's edge have
    their vertex at the end's point, so the edge is split at the end's foot on it.  Newton would
    move such a crossing along a tangential touching by up to ``sqrt(distance / curvature)``: a
    section tangent to a face's boundary line where it ends on it (a cylinder across another,
    tangent to the plane of its boundary lines), or the next arc of the same circle (two sections
    of one sphere–sphere circle meeting on the other sphere's boundary meridian, near a pole where
    the working plane magnifies the slide past ``eps``).
    """
    if s.size == 0 or e is None or c3 is None:
        return s, u
    if not (callable(getattr(c3, "derivatives", None)) and callable(getattr(e.curve, "derivatives", None))):
        return s, u
    try:
        P, Q = np.asarray(c3.evaluate(s)), np.asarray(e.curve.evaluate(u))
        if P.shape != Q.shape:
            return s, u  # curves of another dimension (a 2-D curve given as "3-D"): keep the plane's answer
        d0 = np.linalg.norm(P - Q, axis=-1)
        # Only a strictly closer pair replaces the plane's answer (below), so crossings whose
        # curves already meet exactly in space (d0 = 0, common for lines and circles whose
        # p-curves are exact) keep theirs without Newton: Newton runs per pair independently.
        apart = d0 > 0
        if _FAST and not apart.any():
            return s, u
        lo, hi = min(r1), max(r1)
        E = np.asarray(c3.evaluate(np.array([lo, hi])))  # (the cut's two ends)
        to_lo, to_hi = np.linalg.norm(P - E[0], axis=-1), np.linalg.norm(P - E[1], axis=-1)
        ends = np.flatnonzero((np.minimum(to_lo, to_hi) <= plane.tol3) & apart & (d0 <= plane.tol3))
        k = np.setdiff1d(np.flatnonzero(apart) if _FAST else np.arange(s.size), ends)
        s3, u3, d3 = refine_intersections(c3, r1, e.curve, (e.t0, e.t1), s[k], u[k], plane.t3)
        if ends.size:
            nearer_lo = to_lo[ends] <= to_hi[ends]
            s_end = np.where(nearer_lo, lo, hi)
            u_end, _ = _project(e.curve, (min(e.t0, e.t1), max(e.t0, e.t1)), E[np.where(nearer_lo, 0, 1)], plane.t3)
    except InvalidInputError:
        return s, u  # curves of another dimension (a 2-D curve given as "3-D"): keep the plane's answer
    # Only a strictly closer pair replaces the plane's answer: at a tangential touching Newton
    # stops anywhere along the band where the curves are within tol3, the plane's answer is exact.
    ok = (d3 <= plane.tol3) & (d3 < d0[k])
    s, u = s.copy(), u.copy()
    s[k[ok]], u[k[ok]] = s3[ok], u3[ok]
    if ends.size:
        s[ends], u[ends] = s_end, u_end  # (the foot: the closest point of the edge to the end)
    return s, u


# ====================================================================== clipping
def clip_to_face(face: FaceSpec, pcurve: Any, t0: float, t1: float, tol: Tolerance | None = None,
                 curve: Any = None) -> list[tuple[float, float, str]]:
    """The parts of ``pcurve([t0, t1])`` lying in the trimmed face.

    Parameters
    ----------
    face : FaceSpec
    pcurve : Line2D, Trig2D or 2-D NurbsCurve in the face's parameter plane; on a planar face
        (``surface`` None or a PlanarSurface without p-curves) a 3-D Line, Circle, Ellipse or
        NurbsCurve lying in the plane.
    t0, t1 : float
        The range, in the direction of interest.
    tol : Tolerance, optional
    curve : 3-D curve with ``derivatives``, optional
        The same curve in space (same parameter).  When given, crossings with the loop edges
        are re-solved between the 3-D curves (exact where the p-curves are fits), so that
        faces sharing a vertex agree on it; pass it whenever it is known.

    Returns
    -------
    list of (s0, s1, where)
        Sub-ranges in the direction ``t0 -> t1`` (``s0 -> s1`` runs the same way), ``where`` is
        ``"inside"`` or ``"boundary"`` (the piece runs along a loop edge).  Pieces outside the
        face are left out; ends are where the curve crosses or touches the loops.

    Raises
    ------
    InvalidInputError
        Equal or non-finite parameters, a p-curve of the wrong kind, a face whose edges miss
        their p-curves on a curved surface.

    Examples
    --------
    >>> from coons.kernel.analytic import PlanarSurface
    >>> sq = [Line2D([0, 0], [1, 0]), Line2D([1, 0], [0, 1]), Line2D([1, 1], [-1, 0]), Line2D([0, 1], [0, -1])]
    >>> plane = PlanarSurface([0, 0, 0], [0, 0, 1], [1, 0, 0])
    >>> edges = [EdgeSpec(Line(plane.evaluate(*p.origin), plane.evaluate(*(p.origin + p.direction)) - plane.evaluate(*p.origin)), 0, 1, p) for p in sq]
    >>> clip_to_face(FaceSpec(plane, True, [edges]), Line2D([-1, 0.5], [1, 0]), 0, 3)
    [(1.0, 2.0, 'inside')]
    """
    t = resolve(tol)
    t0, t1 = float(t0), float(t1)
    if not (math.isfinite(t0) and math.isfinite(t1)) or t0 == t1:
        raise InvalidInputError(f"clip_to_face needs finite, different t0 and t1, got ({t0!r}, {t1!r})")
    if not isinstance(face, FaceSpec):
        raise InvalidInputError(f"clip_to_face needs a FaceSpec, got {type(face).__name__}")
    data = _face_data(face, t)
    plane = data.plane([])
    planar = plane.project or isinstance(plane.surface, PlanarSurface)
    pc = _checked_pc(_to_plane(pcurve, plane.surface, "the clipped curve") if planar else pcurve, plane)
    pieces, region = data.pieces(plane, fresh=not _FAST)  # (read only here: no splits are recorded)
    lo, hi = min(t0, t1), max(t0, t1)
    if _FAST:
        sides = data.sides(plane, pieces)
        if sides is not None:
            fast = _hemisphere_clip(data, face, plane, curve, lo, hi)
            if fast is None:
                fast = _convex_clip(sides, pieces, plane, pc, lo, hi, curve)
            if fast is not None:
                return [fast] if t0 < t1 else [(fast[1], fast[0], fast[2])]
    breaks, along = [lo, hi], []
    box = curve_box(pc, (lo, hi), plane.t)
    B = np.array([_box(p, plane) for p in pieces])  # (n, 2, 2): the box tests of all pieces at once
    meet = np.all((box[0] <= B[:, 1] + plane.eps) & (B[:, 0] <= box[1] + plane.eps), axis=1)
    for k in np.flatnonzero(meet).tolist():
        p = pieces[k]
        x = intersect_curves(pc, (lo, hi), p.pc, (p.a, p.b), plane.t)
        breaks += _in_space(plane, curve, (lo, hi), p.spec, x.t1, x.t2)[0].tolist()
        for (s0, s1), _ in x.overlaps:
            breaks += [s0, s1]
            along.append((s0, s1))
    s = _distinct(pc, np.unique(breaks), plane.eps)
    a, b = s[:-1], s[1:]
    mid = 0.5 * (a + b)
    inside = region.winding(_uv(pc, mid)) != 0
    on = np.zeros(mid.size, dtype=bool)
    for s0, s1 in along:
        on |= (mid >= s0) & (mid <= s1)
    where = np.where(on, "boundary", np.where(inside, "inside", "outside"))
    out: list[list] = []
    for k in range(mid.size):
        if out and out[-1][2] == where[k]:
            out[-1][1] = float(b[k])
        else:
            out.append([float(a[k]), float(b[k]), str(where[k])])
    res = [(s0, s1, w) for s0, s1, w in out if w != "outside"]
    if t0 > t1:
        res = [(s1, s0, w) for s0, s1, w in reversed(res)]
    return res


def _checked_pc(pc: Any, plane: _Plane) -> Any:
    if not (isinstance(pc, (Line2D, Trig2D)) or (isinstance(pc, NurbsCurve) and pc.dimension == 2)):
        raise InvalidInputError(f"pcurve must be a Line2D, Trig2D or 2-D NurbsCurve, got {type(pc).__name__}")
    return _mapped(pc, plane.M)


def _distinct(pc: Any, s: np.ndarray, eps: float) -> np.ndarray:
    """Sorted parameters with those whose points are within ``eps`` of the previous kept one removed.

    The last parameter (the range end) is always kept; an interior one too close to it goes.
    """
    return _distinct_points(pc, s, eps)[0]


def _distinct_points(pc: Any, s: np.ndarray, eps: float) -> tuple[np.ndarray, np.ndarray]:
    """:func:`_distinct`, and the points ``(m, 2)`` of the kept parameters."""
    P = _uv(pc, s)
    keep = [0]
    for k in range(1, s.size - 1):
        if np.linalg.norm(P[k] - P[keep[-1]]) > eps and np.linalg.norm(P[k] - P[-1]) > eps:
            keep.append(k)
    keep.append(s.size - 1)
    keep = np.asarray(keep)
    return s[keep], P[keep]


# ====================================================================== convex faces
#: A p-curve is clipped to a convex face in closed form (:func:`_convex_clip`) only where its
#: control points keep this many ``eps`` off every side they do not cross, so that the curve keeps
#: at least that far off (convex hull property): ``clip_to_face`` merges and refines what lies
#: within ``eps``, so far outside that band both find the same crossings.
_CONVEX_CLEARANCE = 100.0
#: Smallest sine of the angle at which a p-curve may cross a side in :func:`_convex_clip`: at a
#: grazing crossing ``clip_to_face`` may report a touching or a stretch along the side instead.
_CONVEX_MIN_SINE = 1e-2


def _convex_sides(pieces: list[_Piece], plane: _Plane) -> tuple[np.ndarray, np.ndarray] | None:
    """``(O, N)``: each boundary piece's start ``(k, 2)`` and unit inward normal ``(k, 2)``, for a face whose
    pieces (with the virtual pole segments) are the straight sides of one convex loop; None otherwise.

    Such a face is the intersection of the sides' half-planes ``N_k · (x - O_k) >= 0``: the untouched
    faces of the primitives (a cylinder's or sphere's half, a plane's rectangle) are their parameter
    rectangles.  The loop must be counter-clockwise (outer loops are, in the working plane) and every
    side's line must keep all vertices on its left (to within ``eps``), which for a simple loop is
    convexity.
    """
    if not pieces or any(type(p.pc) is not Line2D or p.loop != 0 for p in pieces):
        return None
    o = np.array([p.pc.origin for p in pieces])
    d = np.array([p.pc.direction for p in pieces])
    a = np.array([p.a for p in pieces])[:, None]
    b = np.array([p.b for p in pieces])[:, None]
    O, E = o + a * d, o + b * d
    T = E - O
    L = np.hypot(T[:, 0], T[:, 1])
    if not np.all(L > plane.eps):
        return None
    N = np.stack([-T[:, 1], T[:, 0]], axis=1) / L[:, None]  # left of the travel: inside a counter-clockwise loop
    G = np.einsum("kj,kmj->km", N, O[None] - O[:, None])  # G[k, m]: vertex m against side k
    area = 0.5 * float(np.sum(O[:, 0] * E[:, 1] - O[:, 1] * E[:, 0]))
    if not (area > 0 and np.all(G >= -plane.eps)):
        return None
    return O, N


def _convex_clip(sides: tuple[np.ndarray, np.ndarray], pieces: list[_Piece], plane: _Plane, pc: Any, lo: float,
                 hi: float, curve: Any) -> tuple[float, float, str] | None:
    """:func:`clip_to_face` of a polynomial 2-D NURBS ``pc([lo, hi])`` (working plane) on a convex face
    (:func:`_convex_sides`) whose sides it crosses at most once near each end: ``(s0, s1, "inside")``, or
    None where that is not proven (the general clip runs).

    The signed distance ``g_k(t) = N_k · (pc(t) - O_k)`` to side ``k``'s line is a spline whose
    coefficients are those of the control points acting on ``[lo, hi]``.  Control points more than
    :data:`_CONVEX_CLEARANCE` ``eps`` inside (*deep*) must form one run; the ones before it must
    increase strictly up to ``p`` past it (and after it decrease from ``p`` before it), so that ``g_k``
    is increasing on every knot span touching the head (its derivative's coefficients are those
    differences, The NURBS Book eq. 3.4) and above the clearance on the spans of deep points only
    (convex hull).  ``g_k`` then has at most one zero in the head, where it crosses, found by
    safeguarded Newton (likewise in the tail), and the curve lies in the face exactly between the
    last crossing at the head and the first at the tail.  A crossing at a sine below
    :data:`_CONVEX_MIN_SINE` or within the clearance of another side (a corner) declines.  As in
    :func:`clip_to_face`, the crossing is re-solved between the 3-D curves (:func:`_in_space`) and a
    crossing within ``eps`` of a range end is that end.
    """
    ends = _convex_ends(sides, pc, lo, hi, plane)
    if ends is None:
        return None
    heads, tails = ends
    O, N = sides
    clear = _CONVEX_CLEARANCE * plane.eps
    C = _derivs(pc, np.array([lo, hi]), 0)[:, 0]
    head = _innermost_crossing(heads, pc, sides, C[0], lo, plane, True)
    tail = _innermost_crossing(tails, pc, sides, C[1], hi, plane, False)
    if head is None or tail is None:
        return None
    (s0, k0), (s1, k1) = head, tail
    out = []
    for s, k, e in ((s0, k0, 0), (s1, k1, 1)):
        if k >= 0:
            D = _derivs(pc, np.array([s]), 1)[0]
            speed = float(np.hypot(D[1, 0], D[1, 1]))
            if not abs(float(N[k] @ D[1])) >= _CONVEX_MIN_SINE * speed:
                return None
            others = np.delete(np.arange(N.shape[0]), k)
            if not np.all(np.einsum("kj,kj->k", N[others], D[0] - O[others]) > clear):
                return None  # near a corner: the general clip decides which side it crosses
            side = pieces[k]
            u = float((D[0] - side.pc.origin) @ side.pc.direction) / float(side.pc.direction @ side.pc.direction)
            u = min(max(u, min(side.a, side.b)), max(side.a, side.b))
            s = float(_in_space(plane, curve, (lo, hi), side.spec, np.array([s]), np.array([u]))[0][0])
            if np.linalg.norm(_uv(pc, s) - C[e]) <= plane.eps:
                s = (lo, hi)[e]  # as :func:`_distinct`: a crossing within eps of a range end is that end
        out.append(s)
    s0, s1 = out
    if not (s0 < s1) or np.linalg.norm(_uv(pc, s1) - _uv(pc, s0)) <= plane.eps:
        return None
    return float(s0), float(s1), "inside"


def _hemisphere(face: FaceSpec) -> tuple[float, ...] | None:
    """``(n, O)`` as six floats when ``face`` is a half sphere between two meridians ``u0`` and ``u0 + π`` (the
    halves of a sphere primitive): one loop of two edges whose p-curves are the lines ``u = u0`` and
    ``u = u0 + π`` from pole to pole.  The face is then the points of the sphere with ``n · (P - O) >= 0``,
    ``O`` the centre and ``n = cos u0 Y - sin u0 X`` the unit normal of the plane of the two meridians
    (``u ∈ [u0, u0 + π]`` is ``sin(u - u0) >= 0``, and ``u = atan2(y, x)`` in the sphere's frame); None for
    any other face."""
    S = face.surface
    if type(S) is not SphericalSurface or len(face.loops) != 1 or len(face.loops[0]) != 2:
        return None
    us = []
    for e in face.loops[0]:
        pc = e.pcurve
        if type(pc) is not Line2D:
            return None
        (u, v), (du, dv) = pc.origin.tolist(), pc.direction.tolist()
        if du != 0.0 or sorted((v + e.t0 * dv, v + e.t1 * dv)) != [-0.5 * math.pi, 0.5 * math.pi]:
            return None
        us.append(u)
    u0, u1 = sorted(us)
    if u1 - u0 != math.pi:
        return None
    X, Y = S._frame[0].tolist(), S._frame[1].tolist()
    c, s = math.cos(u0), math.sin(u0)
    return tuple(c * y - s * x for x, y in zip(X, Y)) + tuple(S._origin.tolist())


def _hemisphere_clip(data: _FaceData, face: FaceSpec, plane: _Plane, curve: Any, lo: float, hi: float
                     ) -> tuple[float, float, str] | None:
    """:func:`clip_to_face` of a branch whose 3-D curve is a circle on a half-sphere face (:func:`_hemisphere`), in
    closed form: ``(s0, s1, "inside")``, or None where the answer is not one such piece decided with clearance
    (the convex clip or the general path runs).

    The circle ``P(t) = C + r cos t X + r sin t Y`` lies on the sphere, and the face is the sphere's side
    ``g = n · (P - O) >= 0`` of the meridians' plane, so the branch is inside exactly where
    ``g(t) = c + a cos t + b sin t >= 0``: its zeros are ``atan2(b, a) ± acos(-c / hypot(a, b))``, polished by
    Newton on ``g``.  They are where the 3-D Newton of the general path puts the crossings with the
    meridians (the branch's crossings with the meridian circles are its crossings with their plane), up to
    round-off.  Declined: range ends or zeros within :data:`_CONVEX_CLEARANCE` ``tol3`` of each other in
    space (the general path merges ends within ``eps``), a zero at a sine below :data:`_CONVEX_MIN_SINE`, a
    zero within the clearance of the sphere's axis (the poles, the face's corners), and any answer other
    than one inside piece.
    """
    if type(curve) is not Circle:
        return None
    if data.hemisphere is None:
        data.hemisphere = _hemisphere(face) or ()
    if not data.hemisphere:
        return None
    nx, ny, nz, ox, oy, oz = data.hemisphere
    r = float(curve.radius)
    (cx, cy, cz), X, Y = curve.center.tolist(), curve.frame[0].tolist(), curve.frame[1].tolist()
    c = nx * (cx - ox) + ny * (cy - oy) + nz * (cz - oz)
    a = r * (nx * X[0] + ny * X[1] + nz * X[2])
    b = r * (nx * Y[0] + ny * Y[1] + nz * Y[2])
    amp = math.hypot(a, b)
    clear = _CONVEX_CLEARANCE * plane.tol3
    # the smallest |g'| at a zero: sqrt(amp² - c²); below the sine bound (or no zero) the clip declines
    if not amp * amp - c * c >= (_CONVEX_MIN_SINE * r) ** 2:
        return None

    def g(t: float) -> float:
        return c + a * math.cos(t) + b * math.sin(t)

    def point(t: float) -> tuple[float, float, float]:
        ct, st = r * math.cos(t), r * math.sin(t)
        return cx + ct * X[0] + st * Y[0], cy + ct * X[1] + st * Y[1], cz + ct * X[2] + st * Y[2]

    phase, half = math.atan2(b, a), math.acos(-c / amp)
    zeros = []
    for base in (phase - half, phase + half):
        t = base + TWO_PI * math.ceil((lo - base) / TWO_PI)
        while t < hi:
            for _ in range(_ZERO_STEPS):  # Newton on g from the closed form (|g'| >= the sine bound here)
                t -= g(t) / (-a * math.sin(t) + b * math.cos(t))
            zeros.append(t)
            t += TWO_PI
    ts = [lo] + sorted(zeros) + [hi]
    if not all(x < y for x, y in zip(ts, ts[1:])):
        return None
    P = [point(t) for t in ts]
    if not all(math.dist(p, q) > clear for p, q in zip(P, P[1:])):
        return None
    inside = [g(0.5 * (x + y)) > 0.0 for x, y in zip(ts, ts[1:])]  # (alternating: distinct simple zeros)
    ends = (g(lo), g(hi))
    if not (abs(ends[0]) > clear and abs(ends[1]) > clear and (ends[0] > 0) == inside[0]
            and (ends[1] > 0) == inside[-1] and all(x != y for x, y in zip(inside, inside[1:]))
            and inside.count(True) == 1):
        return None
    S = face.surface
    axis, centre = S._frame[2].tolist(), (ox, oy, oz)
    for p in P[1:-1]:
        L = [x - o for x, o in zip(p, centre)]
        h = sum(x * z for x, z in zip(L, axis))
        if not math.dist(L, [h * z for z in axis]) > clear:
            return None  # near a pole: a corner of the face in its parameter plane
    k = inside.index(True)
    return ts[k], ts[k + 1], "inside"


#: Newton steps polishing a closed-form zero in :func:`_hemisphere_clip`.
_ZERO_STEPS = 2


def _innermost_crossing(items: list[tuple[int, float]], pc: Any, sides: tuple[np.ndarray, np.ndarray], C: np.ndarray,
                        end: float, plane: _Plane, head: bool) -> tuple[float, int] | None:
    """Of the sides ``items`` (``(side, t_deep)`` of :func:`_convex_ends`) that the end ``C = pc(end)`` lies outside
    of, the crossing nearest the inside: ``(s, side)`` (``(end, -1)`` when the end is inside all of them),
    None when a root is not bracketed.  ``head``: the crossings lie in ``[end, t_deep]`` (else ``[t_deep, end]``)."""
    O, N = sides
    best, which = end, -1
    for k, t_deep in items:
        if float(N[k] @ (C - O[k])) < 0.0:
            s = _side_root(pc, N[k], O[k], *((end, t_deep) if head else (t_deep, end)), plane)
            if s is None:
                return None
            if (s > best) if head else (s < best):
                best, which = s, k
    return best, which


def _acting(pc: NurbsCurve, lo: float, hi: float) -> tuple[int, np.ndarray]:
    """``(i0, P)``: the index of the first control point of ``pc`` whose B-spline acts on ``[lo, hi]`` and
    those control points ``(m, dim)`` (the spline's coefficients there; The NURBS Book §2.2)."""
    U, p, P = pc.knots, pc.degree, pc.control_points
    i0 = max(int(np.searchsorted(U, lo, "right")) - 1 - p, 0)
    i1 = min(int(np.searchsorted(U, hi, "left")) - 1, P.shape[0] - 1)
    return i0, P[i0:i1 + 1]


def _rising(g: np.ndarray, J: int, p: int) -> bool:
    """Whether the spline coefficients ``g`` increase strictly up to ``p`` past index ``J``: the spline of
    degree ``p`` then increases on every knot span touching ``g[:J]`` (its derivative's coefficients are the
    differences, The NURBS Book eq. 3.4)."""
    return bool(np.all(np.diff(g[:min(J + p, g.size - 1) + 1]) > 0.0))


def _convex_ends(sides: tuple[np.ndarray, np.ndarray], pc: Any, lo: float, hi: float, plane: _Plane
                 ) -> tuple[list[tuple[int, float]], list[tuple[int, float]]] | None:
    """The sides a polynomial 2-D NURBS ``pc([lo, hi])`` comes near at its head and at its tail, on a convex face
    (:func:`_convex_sides`): ``(heads, tails)``, each a list of ``(side, t)`` with ``g_side > clearance`` from
    ``t`` on (heads) or up to ``t`` (tails) and ``g_side`` increasing before (decreasing after); None where
    the control points do not prove that shape (see :func:`_convex_clip`).

    No control point may be non-deep for two sides.  That alone does not keep the curve off a
    corner (one side's head and another's tail may share a knot span): :func:`_convex_clip` tests
    the other sides' clearance at each crossing it finds, and :func:`_convex_contacts` reads each
    side's monotone head or tail on its own.
    """
    if type(pc) is not NurbsCurve or pc.dimension != 2 or pc.is_rational:
        return None
    O, N = sides
    U, p = pc.knots, pc.degree
    i0, P = _acting(pc, lo, hi)
    if P.shape[0] < 2:
        return None
    G = np.einsum("kj,mkj->mk", N, P[:, None, :] - O[None])  # (m, k) coefficients of g_k
    clear = _CONVEX_CLEARANCE * plane.eps
    deep = G > clear
    if np.any(np.count_nonzero(~deep, axis=1) > 1):
        return None
    M = G.shape[0]
    heads, tails = [], []
    for k in np.flatnonzero(~deep.all(axis=0)).tolist():
        run = np.flatnonzero(deep[:, k])
        if run.size == 0 or run[-1] - run[0] + 1 != run.size:
            return None
        J, K = int(run[0]), int(run[-1])
        if J + p >= K + 1:
            return None  # no knot span with deep control points only
        g = G[:, k]
        if J > 0:
            if not _rising(g, J, p):
                return None
            heads.append((k, min(float(U[i0 + J + p]), hi)))
        if K < M - 1:
            if not _rising(g[::-1], M - 1 - K, p):
                return None
            tails.append((k, max(float(U[i0 + K + 1]), lo)))
    return heads, tails


def _convex_contacts(sides: tuple[np.ndarray, np.ndarray], pieces: list[_Piece], c: _Piece, plane: _Plane
                     ) -> dict[int, tuple[list[float], list[float]]] | None:
    """Where cut ``c`` (a polynomial 2-D NURBS) meets the sides of a convex face (:func:`_convex_sides`), as
    :func:`~coons.kernel.curve_intersect.intersect_curves` finds it: ``side -> (cut parameters, side
    parameters)`` for the sides it meets, None where that is not proven (the general path runs).

    By :func:`_convex_ends` the cut keeps the clearance from every side except near its ends, where its
    distance to one side grows monotonically away from the end; it meets that side only at the end, and
    only when the end lies within ``eps`` of it: the intersection is the end and its foot on the side
    (the merged end contact of ``intersect_curves``).  An end more than ``eps`` outside a side, a foot
    beyond the side's ends, or a crossing at a sine below :data:`_CONVEX_MIN_SINE` declines.
    """
    lo, hi = min(c.a, c.b), max(c.a, c.b)
    ends = _convex_ends(sides, c.pc, lo, hi, plane)
    if ends is None:
        return None
    O, N = sides
    D = _derivs(c.pc, np.array([lo, hi]), 1)
    out: dict[int, tuple[list[float], list[float]]] = {}
    for items, e in ((ends[0], 0), (ends[1], 1)):
        for k, _ in items:
            P, T = D[e, 0], D[e, 1]
            g = float(N[k] @ (P - O[k]))
            if g > plane.eps:
                continue
            if g < -plane.eps:
                return None  # the cut leaves the face: the general path and its checks see it
            if not abs(float(N[k] @ T)) >= _CONVEX_MIN_SINE * float(np.hypot(T[0], T[1])):
                return None
            side = pieces[k]
            d = side.pc.direction
            u = float((P - side.pc.origin) @ d) / float(d @ d)
            if not min(side.a, side.b) <= u <= max(side.a, side.b):
                return None
            ss, uu = out.setdefault(k, ([], []))
            ss.append((lo, hi)[e])
            uu.append(u)
    return out


def _side_root(pc: Any, n: np.ndarray, o: np.ndarray, a: float, b: float, plane: _Plane) -> float | None:
    """The zero of ``g(t) = n · (pc(t) - o)`` in ``[a, b]`` where ``g`` is increasing or decreasing with
    opposite signs at the ends: Newton kept in the bracket, bisection where a step leaves it
    (None if the signs at the ends do not differ).  One parameter at a time in Python floats
    (:func:`~coons.kernel.curve_intersect._point1` of the span polynomials, where numpy's per-call
    cost would dominate), else :func:`~coons.kernel.curve_intersect._derivs`."""
    form = _scalar_form(pc)
    nx, ny, ox, oy = float(n[0]), float(n[1]), float(o[0]), float(o[1])

    def g_at(x: float, order: int) -> tuple[float, float]:
        D = _point1(form, x, order) if form is not None else _derivs(pc, np.array([x]), order)[0].tolist()
        g = nx * (D[0][0] - ox) + ny * (D[0][1] - oy)
        return g, (nx * D[1][0] + ny * D[1][1] if order else 0.0)

    ga, gb = g_at(a, 0)[0], g_at(b, 0)[0]
    if ga == 0.0:
        return a
    if gb == 0.0:
        return b
    if (ga < 0) == (gb < 0):
        return None
    x = a + (b - a) * ga / (ga - gb)  # the secant's root
    for _ in range(60):
        g, g1 = g_at(x, 1)
        if g == 0.0:
            return x
        if (g < 0) == (ga < 0):
            a, ga = x, g
        else:
            b, gb = x, g
        x_new = x - g / g1 if g1 != 0.0 else 0.5 * (a + b)
        if not (min(a, b) < x_new < max(a, b)):
            x_new = 0.5 * (a + b)
        if abs(x_new - x) <= plane.t.solver * (1.0 + abs(x)):
            return x_new
        x = x_new
    return x


# ====================================================================== splitting
def split_face(face: FaceSpec, cuts: Sequence[EdgeSpec], tol: Tolerance | None = None) -> list[FaceSpec]:
    """Split a trimmed face by cut edges lying in it (see the module docstring).

    Parameters
    ----------
    face : FaceSpec
    cuts : sequence of EdgeSpec
        Cut edges with their p-curve on this face's surface (``pcurve`` may be None on a
        planar face: the 3-D curve is mapped into the plane).  A cut may end on the boundary,
        on another cut, or be closed; a cut piece running along a boundary edge or another cut
        is dropped (the other edge serves).
    tol : Tolerance, optional

    Returns
    -------
    list of FaceSpec
        The regions (same surface and sense), each with its outer loop first, loops oriented
        as ``docs/brep.md`` says.  Boundary edges are split where cuts meet them: the pieces
        are EdgeSpecs over sub-ranges of the same curve object with the same p-curve and
        tolerance.  Every cut piece that separates two regions is used by both, once in each
        direction; cut pieces bounding no region (trees) are dropped.

    Raises
    ------
    InvalidInputError
        Not a FaceSpec or EdgeSpecs, a cut without p-curve on a curved face, a cut leaving the
        face's region.

    Examples
    --------
    >>> from coons.topology.primitives import Box
    >>> from coons.topology.sew import face_specs
    >>> top = face_specs(Box(2, 2, 2))[0]
    >>> P = np.array([0.0, -1.0, 1.0])
    >>> halves = split_face(top, [EdgeSpec(Line(P, [0, 1, 0]), 0.0, 2.0)])
    >>> len(halves), [len(h.loops[0]) for h in halves]
    (2, [4, 4])
    """
    t = resolve(tol)
    if not isinstance(face, FaceSpec):
        raise InvalidInputError(f"split_face needs a FaceSpec, got {type(face).__name__}")
    cuts = list(cuts)
    for i, c in enumerate(cuts):
        if not isinstance(c, EdgeSpec):
            raise InvalidInputError(f"cuts[{i}] must be an EdgeSpec, got {type(c).__name__}")
    data = _face_data(face, t)
    plane = data.plane(cuts)
    pieces, region = data.pieces(plane)
    nb = len(pieces)
    for i, c in enumerate(cuts):
        pieces.append(_Piece(_pcurve(plane, c, f"cuts[{i}]"), c.t0, c.t1, "cut", -1, c, [], []))
    sides = None
    if _FAST:
        sides = data.sides(plane, pieces[:nb])
    _intersect_pieces(pieces, nb, plane, sides)
    _snap_cut_ends(pieces, nb, plane)
    sub = _sub_pieces(pieces, plane)
    _check_cuts_inside(sub, pieces, region, cuts, plane)
    sub, label = _without_closed_virtual(sub, pieces, plane)
    while True:
        graph = _Graph(sub, pieces, plane, label)
        cycles = graph.cycles()
        dangling = graph.dangling(cycles)
        if not dangling:
            break
        sub, label = [s for k, s in enumerate(sub) if k not in dangling], None
    return graph.faces(cycles, face)


def _intersect_pieces(pieces: list[_Piece], nb: int, plane: _Plane,
                      sides: tuple[np.ndarray, np.ndarray] | None = None) -> None:
    """Record mutual split parameters of cuts against every piece (boundary, virtual, earlier cuts).

    On a convex face (``sides``, :func:`_convex_sides`) a cut's meetings with the boundary come from
    :func:`_convex_contacts` where it proves them, without curve–curve intersection."""
    B = np.array([_box(p, plane) for p in pieces])  # (n, 2, 2): all pairs' box tests at once
    meet = np.all((B[:, None, 0] <= B[None, :, 1] + plane.eps) & (B[None, :, 0] <= B[:, None, 1] + plane.eps),
                  axis=2)
    for i in range(nb, len(pieces)):
        c = pieces[i]
        known = _convex_contacts(sides, pieces, c, plane) if sides is not None else None
        for j in np.flatnonzero(meet[i, :i]).tolist():
            o = pieces[j]
            if known is not None and j < nb:
                if j in known:
                    s, u = _in_space(plane, c.spec.curve, (c.a, c.b), o.spec, np.array(known[j][0]),
                                     np.array(known[j][1]))
                    c.splits += s.tolist()
                    o.splits += u.tolist()
                continue
            if j >= nb and _FAST and _end_contact_only(c, o, plane):
                continue  # their one meeting is the shared end, which the graph's node merge joins
            x = intersect_curves(c.pc, (c.a, c.b), o.pc, (o.a, o.b), plane.t)
            overlaps, touch = _touching_overlaps(x.overlaps, c.spec.curve, plane)
            s, u = _in_space(plane, c.spec.curve, (c.a, c.b), o.spec, np.concatenate([x.t1, touch[0]]),
                             np.concatenate([x.t2, touch[1]]))
            c.splits += s.tolist()
            o.splits += u.tolist()
            for (s0, s1), (u0, u1) in overlaps:
                c.splits += [s0, s1]
                o.splits += [u0, u1]
                c.dropped.append((s0, s1))


def _touching_overlaps(overlaps: list, c3: Any, plane: _Plane) -> tuple[list, tuple[np.ndarray, np.ndarray]]:
    """The overlaps of a cut with a piece that run farther than ``tol3`` in space, and the middles
    ``(s, u)`` of the others, which are touchings.

    Two cuts continuing one another (the arcs of one sphere–sphere circle on either side of the other
    sphere's boundary meridian) lie within tolerance of each other over a stretch about their shared
    end, which :func:`~coons.kernel.curve_intersect.intersect_curves` reports as an overlap; near a pole
    the working plane magnifies that stretch past ``eps``, and taken for an overlap it left a sliver of
    one cut beside the dropped stretch of the other.  Without a 3-D curve every overlap stays one.
    """
    if not overlaps or c3 is None or not callable(getattr(c3, "evaluate", None)):
        return overlaps, (np.zeros(0), np.zeros(0))
    S = np.array([[s0, 0.5 * (s0 + s1), s1] for (s0, s1), _ in overlaps])
    P = np.asarray(c3.evaluate(S.ravel())).reshape(S.shape + (-1,))
    reach = np.linalg.norm(np.diff(P, axis=1), axis=2).sum(axis=1)  # (the two chords' length)
    short = reach <= plane.tol3
    mids = np.array([[0.5 * (s0 + s1), 0.5 * (u0 + u1)] for (s0, s1), (u0, u1) in overlaps]).reshape(-1, 2)
    return ([ov for ov, k in zip(overlaps, short.tolist()) if not k],
            (mids[short, 0], mids[short, 1]))


#: Smallest sine of half the angle between two cuts leaving a shared end for :func:`_end_contact_only`
#: (60 degrees between them): a narrower wedge takes the general path, whose end-contact merging
#: decides touchings along a near-tangent approach.
_END_MIN_SINE = 0.5


def _end_contact_only(c: _Piece, o: _Piece, plane: _Plane) -> bool:
    """Whether cut pieces ``c`` and ``o`` (polynomial 2-D NURBS) are proven to meet only within about ``eps``
    of one shared end, where :func:`~coons.kernel.curve_intersect.intersect_curves` would report just
    that end contact (a split at a range end, or within ``eps`` of it, which :func:`_distinct_points`
    drops, and a node that :func:`_node_pairs` merges).

    Consecutive pieces of one branch and branches ending at one boundary point share an end ``E``
    (within ``eps``) and leave it in different directions ``u_c``, ``u_o``.  With ``n`` along
    ``u_c - u_o`` and ``M`` the middle of the two ends, ``g(t) = n · (pc(t) - M)`` is a spline whose
    coefficients are the control points' acting on the piece.  As in :func:`_convex_ends`, coefficients
    increasing strictly away from the end up to ``p`` past the last one within :data:`_CONVEX_CLEARANCE`
    ``eps`` make ``g`` increase on every knot span touching that head (its derivative's coefficients
    are their differences, The NURBS Book eq. 3.4) and exceed the clearance beyond it (convex hull);
    with ``g`` oriented to grow into ``c`` and to fall into ``o``, ``c`` lies in ``g >= h`` and ``o`` in
    ``g <= -h`` (``h = n · (E_c - E_o) / 2``, ``|h| <= eps / 2``).
    For ``h >= 0`` they share at most the end itself; for ``h < 0`` only points in the band
    ``|g| <= -h``, which the check of ``g`` one ``eps`` (of arc) from each end confines to within
    about ``eps`` of the ends.  Rational curves, two shared ends, a wedge narrower than
    :data:`_END_MIN_SINE` or coefficients without that shape return False (the general path runs).
    """
    pcs = (c.pc, o.pc)
    if any(type(pc) is not NurbsCurve or pc.dimension != 2 or pc.is_rational for pc in pcs):
        return False
    eps = plane.eps
    rc, ro = (c.a, c.b), (o.a, o.b)
    Dc, Do = _derivs(c.pc, np.array(rc), 1), _derivs(o.pc, np.array(ro), 1)
    d = np.linalg.norm(Dc[:, None, 0] - Do[None, :, 0], axis=2)  # (2, 2) distances between the ends
    near = np.argwhere(d <= eps)
    if near.shape[0] != 1:
        return False
    ic, io = (int(k) for k in near[0])
    # Tangents leaving the shared end into each piece (the parameter runs away from the end or towards it).
    sign_c = 1.0 if rc[ic] == min(rc) else -1.0
    sign_o = 1.0 if ro[io] == min(ro) else -1.0
    tc, to = sign_c * Dc[ic, 1], sign_o * Do[io, 1]
    lc, lo_ = float(np.hypot(*tc)), float(np.hypot(*to))
    if not (lc > 0.0 and lo_ > 0.0):
        return False
    n = tc / lc - to / lo_
    ln = float(np.hypot(*n))
    if not ln > 0.0:
        return False
    n = n / ln
    if not float(n @ tc) >= _END_MIN_SINE * lc:
        return False
    Ec, Eo = Dc[ic, 0], Do[io, 0]
    M = 0.5 * (Ec + Eo)
    h = 0.5 * float(n @ (Ec - Eo))
    clear = _CONVEX_CLEARANCE * eps  # > eps / 2 >= |h|: deep control points are off the band
    for pc, r, e, sign, E, speed, nn in ((c.pc, rc, ic, sign_c, Ec, lc, n), (o.pc, ro, io, sign_o, Eo, lo_, -n)):
        lo, hi = min(r), max(r)
        G = (_acting(pc, lo, hi)[1] - M) @ nn  # coefficients of g (oriented to grow into this piece) on [lo, hi]
        if sign < 0.0:
            G = G[::-1]  # from the shared end on
        # Past the last control point within the clearance g stays above it (convex hull); up to p past it the
        # coefficients must increase strictly, so that g increases on every span touching the head.
        shallow = np.flatnonzero(G <= clear)
        if not _rising(G, int(shallow[-1]) + 1 if shallow.size else 0, pc.degree):
            return False
        if h < 0.0:
            # g <= -h only up to about eps of arc from the end: the band holds no point farther off.
            t = min(max(r[e] + sign * eps / speed, lo), hi)
            X = _uv(pc, t)
            if not (float(nn @ (X - M)) > -h and float(np.hypot(*(X - E))) <= 2.0 * eps):
                return False
    return True


@dataclass
class _Sub:
    piece: int
    a: float  # in the piece's direction of travel
    b: float
    uv: np.ndarray  # (n, 2) polyline from a to b
    artificial_mid: bool = False  # b's node was made up to split a closed piece


def _sub_pieces(pieces: list[_Piece], plane: _Plane) -> list[_Sub]:
    out = []
    for k, p in enumerate(pieces):
        lo, hi = min(p.a, p.b), max(p.a, p.b)
        # (without splits np.unique(np.clip([lo, hi])) is [lo, hi]: the pieces have lo < hi)
        s = (np.unique(np.clip(np.asarray([lo, hi] + p.splits, dtype=np.float64), lo, hi)) if p.splits
             else np.array([lo, hi], dtype=np.float64))
        s, P = _distinct_points(p.pc, s, plane.eps)
        if p.a > p.b:
            s, P = s[::-1], P[::-1]
        # A straight piece's sub-piece polylines are its two end points, evaluated already (pointwise).
        line = isinstance(p.pc, Line2D)
        for i, (a, b) in enumerate(zip(s[:-1], s[1:])):
            m = 0.5 * (a + b)
            if any(r0 <= m <= r1 for r0, r1 in p.dropped):
                continue
            poly = P[i:i + 2] if line else _polyline(p.pc, a, b)
            if np.linalg.norm(poly[-1] - poly[0]) <= plane.eps:
                if np.linalg.norm(np.diff(poly, axis=0), axis=1).sum() <= plane.eps:
                    continue  # degenerate sub-piece: a point
                # A closed sub-piece (a circle): split at its middle so that the graph has no loops.
                out.append(_Sub(k, float(a), float(m), _polyline(p.pc, a, m), artificial_mid=True))
                out.append(_Sub(k, float(m), float(b), _polyline(p.pc, m, b)))
                continue
            out.append(_Sub(k, float(a), float(b), poly))
    return out


def _check_cuts_inside(sub: list[_Sub], pieces: list[_Piece], region: _Inside, cuts, plane: _Plane) -> None:
    """Every cut sub-piece must lie in the face: its midpoint's winding number is not 0 or it is on the boundary."""
    idx = [k for k, s in enumerate(sub) if pieces[s.piece].kind == "cut"]
    if not idx:
        return
    mids = np.array([sub[k].uv[sub[k].uv.shape[0] // 2] if sub[k].uv.shape[0] > 2
                     else 0.5 * (sub[k].uv[0] + sub[k].uv[1]) for k in idx])
    w = region.winding(mids)
    # A piece within eps of the boundary (a cut overshooting its end point by less than the
    # tolerance) is on it, not outside: it becomes a dangling piece and is dropped.
    bad = np.flatnonzero((w == 0) & (region.distance(mids) > plane.eps))
    if bad.size:
        s = sub[idx[int(bad[0])]]
        ci = s.piece - (len(pieces) - len(cuts))
        raise InvalidInputError(
            f"cuts[{ci}] leaves the face: its part over parameters [{s.a:.6g}, {s.b:.6g}] lies outside the face's "
            f"loops (winding number 0, expected ±1); cuts must lie in the face"
        )


#: Largest factor by which a node merge may exceed ``eps`` in the working plane where the surface
#: is slow along a parameter (near a pole); beyond it ends stay apart even if close in space.
_SLOW_MERGE = 100.0


#: The surfaces of revolution (kernel.analytic), whose ``derivatives(u, v)[..., 0, 0]`` are ``evaluate(u, v)``.
_REVOLVED = (CylindricalSurface, ConicalSurface, SphericalSurface, ToroidalSurface)

#: The surfaces on which :func:`_snap_cut_ends` evaluates the reach of all cut ends first: a cylinder's
#: ``σ_min`` is ``σ`` everywhere, so the reach test skips most ends there (11 of 12 on the benchmark's
#: crossing cylinders; fewer on some random pairs), before any box or foot.
_REACH_FIRST = (CylindricalSurface,)


def _space_reach(plane: _Plane, X: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """3-D points ``(m, 3)`` of working-plane points ``X`` (m, 2) on a curved face, and how far
    ``(m,)`` in the plane a point found to ``tol3`` in space may lie from them: ``tol3 / σ_min``
    (σ_min the smallest singular value of the scaled Jacobian there), at most
    :data:`_SLOW_MERGE` ``eps``."""
    Minv = np.diag(1.0 / np.diag(plane.M))
    uv = X @ Minv.T
    S = plane.surface
    D = np.asarray(S.derivatives(uv[:, 0], uv[:, 1], 1), dtype=np.float64)
    if _FAST and type(S) in _REVOLVED:
        P = D[:, 0, 0]  # (a surface of revolution's derivatives give evaluate's points bit for bit: the same sums)
    else:
        P = np.asarray(S.evaluate(uv[:, 0], uv[:, 1]), dtype=np.float64).reshape(-1, 3)
    J = np.stack([D[:, 1, 0] * Minv[0, 0], D[:, 0, 1] * Minv[1, 1]], axis=2)  # (m, 3, 2)
    smin = np.linalg.svd(J, compute_uv=False)[:, -1]
    reach = np.minimum(_SLOW_MERGE * plane.eps, plane.tol3 / np.maximum(smin, np.finfo(float).tiny))
    return P, reach


def _foot(pc: Any, a: float, b: float, q: np.ndarray, samples: dict | None = None) -> tuple[float, float]:
    """The parameter in ``[min(a, b), max(a, b)]`` of the point of ``pc`` nearest ``q`` (2,), and the distance.

    On a :class:`Line2D` in closed form; otherwise dense samples, then Newton on ``(pc(s) - q) · pc'(s) = 0`` (a few
    steps, kept in the range).  ``samples`` keeps the dense samples per curve and range for the next end near the same piece."""
    lo, hi = min(a, b), max(a, b)
    if type(pc) is Line2D:  # the projection on the line, clamped to the range (what Newton converges to)
        o, d = pc.origin, pc.direction
        x = min(max(float((q - o) @ d) / float(d @ d), lo), hi)
        return x, float(np.linalg.norm(_uv(pc, x) - q))
    key = (id(pc), lo, hi)
    if samples is not None and key in samples:
        s, S = samples[key]
    else:
        s = np.linspace(lo, hi, 257)
        S = _uv(pc, s)
        if samples is not None:
            samples[key] = (s, S)
    k = int(np.argmin(np.linalg.norm(S - q, axis=1)))
    x = float(s[k])
    for _ in range(8):
        D = _pc_derivatives(pc, np.array([x]), 2)[0]
        r = D[0] - q
        g, h = float(r @ D[1]), float(D[1] @ D[1] + r @ D[2])
        if not h > 0:
            break
        x_new = min(max(x - g / h, lo), hi)
        if x_new == x:
            break  # a fixed point: the remaining steps would repeat this one
        x = x_new
    return x, float(np.linalg.norm(_uv(pc, x) - q))


def _snap_cut_ends(pieces: list[_Piece], nb: int, plane: _Plane) -> None:
    """Split pieces where a cut ends on them within ``tol3`` in space but beyond ``eps`` in the plane.

    Near a pole the surface is slow along ``u``: a cut ending on a meridian, computed to
    ``tol3`` in space, may stop short of it by many ``eps`` in the working plane, so that
    :func:`intersect_curves` finds no crossing there.  The foot of the end on the piece becomes a
    split (and :func:`_node_pairs` merges the end with it).

    An end is examined only if its reach (:func:`_space_reach`) exceeds ``eps``.  On a cylinder
    (:data:`_REACH_FIRST`) ``σ_min`` is ``σ`` everywhere, so that test skips most ends there:
    the reach of all ends comes first, in one evaluation.  Elsewhere (a sphere's ``σ_min < σ`` off
    its widest latitude) it skips none, and the reach matters only for a foot between ``eps`` and
    the widest reach :data:`_SLOW_MERGE` ``eps``: with the fast paths on, the pieces are searched
    within the widest reach and the reach is evaluated (for all ends at once) at the first such
    foot; the tests of the true reach then follow, so the splits are the same."""
    if plane.project or isinstance(plane.surface, PlanarSurface) or nb == len(pieces):
        return
    # The ends of all cuts at once (the surface is evaluated point by point either way).
    ends_all = np.concatenate([_uv(c.pc, np.array([c.a, c.b])) for c in pieces[nb:]])
    P_all = reach_all = None
    if not _FAST or type(plane.surface) in _REACH_FIRST:
        P_all, reach_all = _space_reach(plane, ends_all)
    widest = _SLOW_MERGE * plane.eps  # _space_reach's bound on every reach
    samples: dict = {}  # dense samples of the pieces, per curve and range (pieces live through the call)
    piece_ends: dict[int, np.ndarray] = {}  # (2, 2) end points of the pieces examined, cuts' from ends_all
    B = None  # (n, 2, 2) the pieces' boxes, for the box tests of all pieces against one end at once
    for i in range(nb, len(pieces)):
        for k in (2 * (i - nb), 2 * (i - nb) + 1):
            q = ends_all[k]
            true_r = reach_all is not None  # (else r is the widest reach until a foot needs the true one)
            r = reach_all[k] if true_r else widest
            if not r > plane.eps:
                continue
            if B is None:
                B = np.array([_box(o, plane) for o in pieces])
            # (the end's box [q - r, q + r] against every piece's, with no margin)
            meet = np.all((q - r <= B[:, 1]) & (B[:, 0] <= q + r), axis=1)
            for j in np.flatnonzero(meet).tolist():
                o = pieces[j]
                if j == i:
                    continue
                if _FAST:
                    # An end of the piece within eps of q bounds the true foot's distance by eps: no split (the
                    # test below), and the node merge joins the two ends.  Consecutive cuts of one branch,
                    # and branches ending at one point, skip the dense search of the foot.
                    E = piece_ends.get(j)
                    if E is None:
                        E = piece_ends[j] = (ends_all[2 * (j - nb):2 * (j - nb) + 2] if j >= nb
                                             else _uv(o.pc, np.array([o.a, o.b])))
                    dq = E - q
                    if float(np.min(dq[:, 0] * dq[:, 0] + dq[:, 1] * dq[:, 1])) <= plane.eps * plane.eps:
                        continue
                s, d = _foot(o.pc, o.a, o.b, q, samples)
                if not plane.eps < d <= r:
                    continue
                if reach_all is None:
                    P_all, reach_all = _space_reach(plane, ends_all)
                if not true_r:
                    # The tests of the end's true reach, which the widest one passed: the general path's
                    # (its box test follows from d <= r for a proven box; kept for the same order of tests).
                    true_r, r = True, reach_all[k]
                    if not r > plane.eps:
                        break
                    meet = np.all((q - r <= B[:, 1]) & (B[:, 0] <= q + r), axis=1)
                if not (meet[j] and d <= r):
                    continue
                Ps, _ = _space_reach(plane, _uv(o.pc, s)[None])
                if np.linalg.norm(Ps[0] - P_all[k]) <= plane.tol3:
                    o.splits.append(s)


def _node_pairs(X: np.ndarray, plane: _Plane) -> np.ndarray:
    """Pairs ``(p, 2)`` of sub-piece ends ``X`` (m, 2) that are one node.

    Ends within ``eps`` in the working plane always are.  Where the surface moves slowly along
    a parameter (near a sphere or cone pole) a point found to ``tol3`` in space may be
    ``tol3 / σ_min`` away in the working plane (σ_min the smallest singular value of the scaled
    Jacobian there): two fitted p-curves ending at one 3-D vertex then miss each other by more
    than ``eps``.  Such ends are merged when they are within ``tol3`` in space and within
    ``tol3 / σ_min`` (at most :data:`_SLOW_MERGE` ``eps``) in the plane, so that distinct
    parameter points of a pole, far apart in the plane, never merge.
    """
    from scipy.spatial import cKDTree

    tree = cKDTree(X)
    pairs = tree.query_pairs(r=plane.eps, output_type="ndarray")
    if plane.project or isinstance(plane.surface, PlanarSurface):
        return pairs  # the working plane is the plane itself: distances are 3-D distances
    wide = tree.query_pairs(r=_SLOW_MERGE * plane.eps, output_type="ndarray")
    if wide.shape[0] == pairs.shape[0]:
        return pairs
    P, reach = _space_reach(plane, X)
    i, j = wide[:, 0], wide[:, 1]
    d2 = np.linalg.norm(X[i] - X[j], axis=1)
    d3 = np.linalg.norm(P[i] - P[j], axis=1)
    ok = (d2 <= plane.eps) | ((d3 <= plane.tol3) & (d2 <= np.minimum(reach[i], reach[j])))
    return wide[ok]


def _components(m: int, pairs: np.ndarray) -> np.ndarray:
    """Connected components ``(m,)`` of ``m`` nodes joined by ``pairs`` (p, 2): each node's label is the
    smallest node of its component.

    Minimum-label propagation with pointer jumping; labels only decrease (``label[x] <= x``
    throughout), so it stops, and at the fixed point the two ends of every pair agree.  The
    graphs here have a few dozen nodes, where scipy's sparse ``connected_components`` costs
    mostly its set-up.
    """
    label = np.arange(m)
    if len(pairs) == 0:
        return label
    i, j = pairs[:, 0], pairs[:, 1]
    while True:
        new = label.copy()
        low = np.minimum(label[i], label[j])
        np.minimum.at(new, i, low)
        np.minimum.at(new, j, low)
        new = new[new]
        if np.array_equal(new, label):
            return label
        label = new


def _without_closed_virtual(sub: list["_Sub"], pieces: list[_Piece], plane: _Plane
                            ) -> tuple[list["_Sub"], np.ndarray | None]:
    """The sub-pieces without the virtual segments whose two ends are one node of the arrangement, and
    their :func:`_node_labels` where they were computed for sub-pieces that all stay (None otherwise), for
    the first :class:`_Graph` to reuse.

    A virtual segment closes the gap between two p-curve ends of one vertex; near a pole, where the
    node merge reaches further (see the module docstring), the two ends can be merged after all.
    The segment would then be a loop at the node whose direction (of a gap of round-off size)
    misorders the turn there: the walk joins the regions on both sides of the node (a sphere face
    with a vertex 3° from its pole, split by a latitude cut, came back as one region)."""
    virtual = [k for k, s in enumerate(sub) if pieces[s.piece].kind == "virtual"]
    if not virtual:
        return sub, None
    n = len(sub)
    label = _node_labels(sub, plane)
    closed = {k for k in virtual if label[k] == label[n + k]}
    return ([s for k, s in enumerate(sub) if k not in closed], None) if closed else (sub, label)


def _node_labels(sub: list["_Sub"], plane: _Plane) -> np.ndarray:
    """``(2 n,)`` the node of each sub-piece's start (first n) and end (last n): their ends merged within
    the working-plane tolerance (:func:`_node_pairs`, :func:`_components`)."""
    n = len(sub)
    X = np.concatenate([np.array([s.uv[0] for s in sub]), np.array([s.uv[-1] for s in sub])]).reshape(-1, 2)
    return _components(2 * n, _node_pairs(X, plane) if n else np.zeros((0, 2), int))


#: Distance along a half-edge, in eps, from which its direction is taken where the p-curve turns within eps of
#: the node (:meth:`_Graph._coarse_direction`): far enough that a sub-eps hook tilts the chord by at most about
#: a tenth of a radian, near enough that a real curvature bends it by ``5 eps κ``.
_COARSE = 10.0
#: Parameter fractions ``2^-k`` (k up to this) tried for that point: 2^-52 of a sub-piece is below rounding.
_COARSE_HALVINGS = 52


class _Graph:
    """The planar arrangement of the sub-pieces: nodes, half-edges sorted around nodes, cycles."""

    def __init__(self, sub: list[_Sub], pieces: list[_Piece], plane: _Plane, label: np.ndarray | None = None
                 ) -> None:
        """``label``: the :func:`_node_labels` of ``sub`` when the caller has them (computed here otherwise)."""
        self.sub, self.pieces, self.plane = sub, pieces, plane
        n = len(sub)
        if label is None or not _FAST:
            label = _node_labels(sub, plane)
        elif len(label) != 2 * n:  # (labels of the wrong length: another set of sub-pieces, a caller's bug)
            raise AssertionError(f"_Graph given {len(label)} node labels for {n} sub-pieces")
        # Half-edge 2k runs sub k forward (node n0 -> n1), 2k + 1 backward.
        self.origin = np.empty(2 * n, dtype=np.int64)
        self.origin[0::2], self.origin[1::2] = label[:n], label[n:]
        self.artificial = {int(label[n + k]) for k, s in enumerate(sub) if s.artificial_mid}
        self.degree = np.bincount(self.origin, minlength=int(label.max()) + 1 if n else 0)
        angle, kappa = self._directions()
        nxt = np.empty(2 * n, dtype=np.int64)
        order = np.lexsort((angle, self.origin))
        starts = np.flatnonzero(np.concatenate([[True], self.origin[order][1:] != self.origin[order][:-1]]))
        stops = np.append(starts[1:], order.size)
        size = stops - starts
        # A node with one or two half-edges leaving needs no order: each arrives and leaves by the other
        # (or turns back), whatever the directions; the loop below gives the same for them.
        one, two = starts[size == 1], starts[size == 2]
        nxt[order[one] ^ 1] = order[one]
        nxt[order[two] ^ 1], nxt[order[two + 1] ^ 1] = order[two + 1], order[two]
        for a, b in zip(starts[size > 2].tolist(), stops[size > 2].tolist()) if n else zip(starts, stops):
            ring = order[a:b]
            # Directions just above -π are ties with those just below π: move them past π.
            thr = self._tie(float(np.abs(kappa[ring]).max()))
            ang = np.where(angle[ring] <= -math.pi + thr, angle[ring] + 2 * math.pi, angle[ring])
            ring = self._break_ties(list(ring[np.argsort(ang, kind="stable")]), ang, ring, kappa)
            m = len(ring)
            for q, h in enumerate(ring):
                # Arriving through twin(h) = h ^ 1 at this node, leave by the next clockwise of h.
                nxt[h ^ 1] = ring[(q - 1) % m]
        self.next = nxt

    def _directions(self) -> tuple[np.ndarray, np.ndarray]:
        """Tangent angle and signed curvature of every half-edge at its origin, ``(2n,)`` each.

        One derivative evaluation per piece (at the ends of all its sub-pieces); at a
        stationary point of a p-curve the polyline's first chord gives the direction.
        """
        n = len(self.sub)
        D1, D2 = np.empty((2 * n, 2)), np.empty((2 * n, 2))
        ab_all = np.array([[s.a, s.b] for s in self.sub]).reshape(n, 2)
        sign_all = np.where(ab_all[:, 1] > ab_all[:, 0], 1.0, -1.0)[:, None]
        by_piece: dict[int, list[int]] = {}
        straight: list[int] = []
        for k, s in enumerate(self.sub):
            if _FAST and type(self.pieces[s.piece].pc) is Line2D:
                straight.append(k)
            else:
                by_piece.setdefault(s.piece, []).append(k)
        if straight:
            # A straight piece's derivatives are its direction and 0 everywhere (Line2D.derivatives' values),
            # without the evaluation of its points, which this does not read: all straight sub-pieces at once.
            ks = np.asarray(straight)
            d = np.array([self.pieces[self.sub[k].piece].pc.direction for k in straight])
            D1[2 * ks], D1[2 * ks + 1] = sign_all[ks] * d, -sign_all[ks] * d
            D2[2 * ks] = D2[2 * ks + 1] = 0.0
        for p, ks in by_piece.items():
            ks = np.asarray(ks)
            ab, sign = ab_all[ks], sign_all[ks]
            pc = self.pieces[p].pc
            D = _pc_derivatives(pc, ab, 2)  # (m, 2, 3, 2)
            # Forward half-edge leaves a along the travel, backward leaves b against it.
            D1[2 * ks], D2[2 * ks] = sign * D[:, 0, 1], D[:, 0, 2]
            D1[2 * ks + 1], D2[2 * ks + 1] = -sign * D[:, 1, 1], D[:, 1, 2]
        speed = np.linalg.norm(D1, axis=1)
        for h in np.flatnonzero(~(speed > 0)):
            uv = self.sub[h >> 1].uv
            poly = uv if h % 2 == 0 else uv[::-1]
            D1[h] = poly[1] - poly[0]
        speed = np.linalg.norm(D1, axis=1)
        kappa = (D1[:, 0] * D2[:, 1] - D1[:, 1] * D2[:, 0]) / speed**3
        # A radius of curvature below eps at a node: the p-curve turns within the arrangement's resolution
        # there, and its derivatives are not the direction it leaves in (a branch fitted through a point
        # where its two surfaces touch hooks over 1e-8 at the end, its tangent along the boundary it meets
        # at 35 degrees).  Such half-edges take the chord to the point a few eps along and the curvature there.
        for h in np.flatnonzero(np.abs(kappa) * self.plane.eps > 1.0).tolist():
            D1[h], kappa[h] = self._coarse_direction(h)
        angle = np.arctan2(D1[:, 1], D1[:, 0])
        return angle, kappa

    def _coarse_direction(self, h: int) -> tuple[np.ndarray, float]:
        """Direction and signed curvature of half-edge ``h`` seen from about :data:`_COARSE` eps along it.

        The chord from its origin to the first of the points at parameter fractions ``2^-k`` of its
        sub-piece, nearest first, that lies that far off (half-way on a shorter sub-piece: the speed
        may vanish at a hook, so the fraction is searched, not derived from the length), and the
        curvature there."""
        s = self.sub[h >> 1]
        t0, t1 = (s.a, s.b) if h % 2 == 0 else (s.b, s.a)
        origin = s.uv[0] if h % 2 == 0 else s.uv[-1]
        t = t0 + np.ldexp(1.0, -np.arange(_COARSE_HALVINGS, 0, -1)) * (t1 - t0)
        D = _pc_derivatives(self.pieces[s.piece].pc, t, 2)  # (k, 3, 2)
        far = np.flatnonzero(np.linalg.norm(D[:, 0] - origin, axis=1) >= _COARSE * self.plane.eps)
        d = D[int(far[0]) if far.size else -1]
        chord = d[0] - origin
        d1 = d[1] if t1 > t0 else -d[1]  # along the travel away from the origin
        speed = float(np.hypot(*d1))
        if not (np.hypot(*chord) > 0.0 and speed > 0.0):
            return d1, 0.0
        return chord, float((d1[0] * d[2][1] - d1[1] * d[2][0]) / speed**3)

    def _tie(self, kappa: float) -> float:
        """Two tangent directions closer than this are one (see :meth:`_break_ties`)."""
        return math.sqrt(self.plane.eps * kappa) + self.plane.t.angular

    def _break_ties(self, ring: list[int], ang: np.ndarray, ids: np.ndarray, kappa: np.ndarray) -> list[int]:
        """Order half-edges leaving in the same direction by curvature (left-turning ones later).

        ``ang[i]`` is the direction of half-edge ``ids[i]``.  Two directions within
        ``sqrt(eps · |κ|) + tol.angular`` are the same: a touching node found to ``eps`` sits
        ``sqrt(eps / |κ|)`` along the curves, turning them by that much.
        """
        angle = dict(zip(ids.tolist(), ang.tolist()))
        out = list(ring)
        # (each swap by curvatures alone removes one inversion of them, so at most m(m - 1)/2 passes change
        # anything; the side of a line replaces a curvature pair by pair, which could cycle: the bound ends it)
        passes = len(out) * (len(out) - 1) // 2 + 1
        changed = True
        while changed and passes:
            changed = False
            passes -= 1
            for q in range(len(out) - 1):
                h, g = out[q], out[q + 1]
                thr = self._tie(max(abs(kappa[h]), abs(kappa[g])))
                if abs(angle[g] - angle[h]) <= thr and self._turn(g, h, kappa) < self._turn(h, g, kappa):
                    out[q], out[q + 1] = g, h
                    changed = True
        return out

    def _straight(self, h: int) -> bool:
        return type(self.pieces[self.sub[h >> 1].piece].pc) is Line2D

    def _turn(self, h: int, other: int, kappa: np.ndarray) -> float:
        """The curvature by which half-edge ``h`` is ordered against ``other`` leaving its node in the same
        direction: its own, or, when ``other`` is straight and ``h`` is not, the side of ``other``'s line on
        which ``h`` lies where it first leaves it by more than :data:`_COARSE` eps (``±1``: left, right).

        A curve in contact of high order with a straight boundary (a section osculating a sphere's bounding
        meridian: ``u ≈ v⁴ / 16``) has a curvature near the node far below what a fitted p-curve gets right,
        and its sign may be the wrong one; the side at a distance is exact."""
        k = float(kappa[h])
        if not self._straight(other) or self._straight(h):
            return k
        side = self._side_of_line(h, other)
        return k if side == 0.0 else side

    def _side_of_line(self, h: int, line: int) -> float:
        """``+1`` / ``-1`` where half-edge ``h`` first lies more than :data:`_COARSE` eps to the left / right
        of straight half-edge ``line`` leaving the same node (points at parameter fractions ``2^-k`` of
        ``h``'s sub-piece, nearest first), ``0.0`` where it never does."""
        s, sl = self.sub[h >> 1], self.sub[line >> 1]
        t0, t1 = (s.a, s.b) if h % 2 == 0 else (s.b, s.a)
        origin = sl.uv[0] if line % 2 == 0 else sl.uv[-1]
        d = np.asarray(self.pieces[sl.piece].pc.direction, dtype=np.float64)
        d = d if (sl.b > sl.a) == (line % 2 == 0) else -d
        t = t0 + np.ldexp(1.0, -np.arange(_COARSE_HALVINGS, -1, -1)) * (t1 - t0)
        Q = _pc_derivatives(self.pieces[s.piece].pc, t, 0)[:, 0] - origin
        n = (d[0] * Q[:, 1] - d[1] * Q[:, 0]) / math.hypot(*d)
        off = np.flatnonzero(np.abs(n) > _COARSE * self.plane.eps)
        return float(np.sign(n[off[0]])) if off.size else 0.0

    def cycles(self) -> list[list[int]]:
        seen = np.zeros(self.next.size, dtype=bool)
        out = []
        for h0 in range(self.next.size):
            if seen[h0]:
                continue
            cyc, h = [], h0
            while not seen[h]:
                seen[h] = True
                cyc.append(h)
                h = int(self.next[h])
            out.append(cyc)
        return out

    def dangling(self, cycles: list[list[int]]) -> set[int]:
        """Sub-pieces whose two half-edges lie in one cycle (trees, bridges): cuts only."""
        out = set()
        for cyc in cycles:
            s = set(cyc)
            for h in cyc:
                k = h >> 1
                if (h ^ 1) in s and self.pieces[self.sub[k].piece].kind == "cut":
                    out.add(k)
        return out

    def polygon(self, cyc: list[int]) -> np.ndarray:
        return np.concatenate([(self.sub[h >> 1].uv if h % 2 == 0 else self.sub[h >> 1].uv[::-1])[:-1] for h in cyc])

    def faces(self, cycles: list[list[int]], face: FaceSpec) -> list[FaceSpec]:
        polys = [self.polygon(c) for c in cycles]
        area = np.array([0.5 * float(np.sum(p[:, 0] * _next(p[:, 1]) - _next(p[:, 0]) * p[:, 1]))
                         for p in polys])
        # A cycle running a boundary piece backward bounds the outside of the original face (the face is on
        # the left of its boundary pieces run forward): never a piece, nor a hole of one (a piece's holes run
        # the face's inner loops forward, or cuts only), though its probe may fall inside a piece where a cut
        # touches the boundary tangentially (a loop inside the face touching its outer loop at a point).
        outside = [any(self.pieces[self.sub[h >> 1].piece].kind != "cut" and h % 2 == 1 for h in cyc)
                   for cyc in cycles]
        outer = [ci for ci in range(len(cycles)) if area[ci] > 0 and not outside[ci]]
        holes: dict[int, list[int]] = {ci: [] for ci in outer}
        for ci, cyc in enumerate(cycles):
            if area[ci] >= 0 or outside[ci]:
                continue
            mine = {h >> 1 for h in cyc}
            probe = polys[ci][:1] if polys[ci].shape[0] < 2 else 0.5 * (polys[ci][:1] + polys[ci][1:2])
            best, best_area = None, math.inf
            for co in outer:
                if mine & {h >> 1 for h in cycles[co]}:
                    continue
                if _winding(probe, [polys[co]])[0] != 0 and area[co] < best_area:
                    best, best_area = co, area[co]
            if best is not None:
                holes[best].append(ci)
        out = []
        for co in outer:
            loops = [self._loop(cycles[co])] + [self._loop(cycles[h]) for h in holes[co]]
            loops = [lp for lp in loops if lp]
            out.append(FaceSpec(face.surface, face.sense, loops))
        return out

    def _loop(self, cyc: list[int]) -> list[EdgeSpec]:
        """EdgeSpecs of a cycle: virtual segments left out, and consecutive sub-pieces of one
        piece joined through nodes where nothing else meets (the middle of a closed piece, the
        foot of a dropped dangling cut) so that boundary edges are split only where cuts end."""
        items = []
        for h in cyc:
            s = self.sub[h >> 1]
            p = self.pieces[s.piece]
            if p.kind != "virtual":
                a, b = (s.a, s.b) if h % 2 == 0 else (s.b, s.a)
                items.append((p, a, b, int(self.origin[h])))
        if not items:
            return []

        def joins(prev, cur) -> bool:
            return prev[0] is cur[0] and prev[2] == cur[1] and self.degree[cur[3]] == 2

        m = len(items)
        start = next((q for q in range(m) if not joins(items[q - 1], items[q])), None)
        if start is None:  # one closed piece all round: start where its parameter starts
            start = next((q for q in range(m) if items[q][3] not in self.artificial), 0)
        items = items[start:] + items[:start]
        out: list[list] = []
        for it in items:
            if out and joins((out[-1][0], None, out[-1][2]), it):
                out[-1][2] = it[2]
            else:
                out.append([it[0], it[1], it[2]])
        # The pieces' specs are validated and a sub-piece's ends are Python floats: the trusted constructor
        # where they are finite and distinct (else the public one, which raises as before).
        return [EdgeSpec._trusted(p.spec.curve, a, b, p.spec.pcurve, p.spec.tol)
                if a != b and math.isfinite(a) and math.isfinite(b) else EdgeSpec(p.spec.curve, a, b, p.spec.pcurve,
                                                                                   p.spec.tol)
                for p, a, b in out]
