"""Point membership of solids bounded by trimmed surfaces: inside (-1), on (0) or outside (+1).

:func:`classify_points` decides, for an ``(n, 3)`` batch of points, whether each lies inside,
on the boundary of, or outside a :class:`~coons.topology.shape.Solid` with any faces (planes,
cylinders, cones, spheres, tori, NURBS).  It is the membership test of the B-rep Booleans
(:mod:`coons.booleans.solid` classifies one interior point per face piece with it).  It does
not handle open or invalid B-reps and does not give distances.

Method
------
1. **Far points: winding number of the tessellation.**  The solid's watertight tessellation
   (:func:`coons.topology.tessellate.tessellate`, deflection ``d``) is a closed mesh within
   ``d`` of the exact boundary, so for a point farther than ``band = 2 d + 10 tol.linear`` from
   every face the mesh and the exact solid agree on membership.  Its generalised winding number
   ``w = Σ Ω / 4π`` is the sum of the triangles' signed solid angles by the formula of van
   Oosterom & Strackee ("The solid angle of a plane triangle", IEEE Trans. Biomed. Eng. 30,
   1983): ``tan(Ω/2) = a·(b×c) / (|a||b||c| + (a·b)|c| + (a·c)|b| + (b·c)|a|)``, vectorised over
   point–triangle pairs.  ``|w| > 1/2`` is inside.
2. **Near points: exact projection.**  For each face, the points within its (mesh) bounding box
   enlarged by ``band`` are projected exactly onto the face's surface
   (``surface.closest_parameters``; NURBS by :func:`coons.kernel.projection.surface_closest_parameters`),
   the foot's periodic parameters are shifted into the face's parameter range, and the foot is
   tested against the trim loops (crossing number against the loops' p-curves sampled into
   polygons).  A point within ``band`` of a face whose foot lies inside the trim and away from
   the trim boundary takes the side of the face's outward normal at the foot (the face with the
   smallest distance wins); a distance ``<= tol.linear`` is *on*.
3. **Points near edges.**  A foot within the polygon's measured chord error of the trim polygon
   is *ambiguous*: if the point is on the surface (``<= tol.linear``) the trim is decided exactly
   at the nearest boundary point ``q`` (the foot is in the face when it lies on the face's side
   of the edge's tangent there, ``(x − q)·(n × T) >= 0``), which makes the point *on*.  A point
   that no face claims, or that lies nearer to a surface whose foot is outside or ambiguous than
   to its claiming face, is decided at its nearest edge (searched among the edges within
   ``band`` of the points, then, for a point whose nearest edge lies farther — its foot in a hole
   of a face, far from the rim — among those within that distance): the exact distance to each edge
   curve (closed-form projections for lines, circles and ellipses,
   :func:`~coons.kernel.projection.curve_closest_parameters` otherwise) ``<= tol.linear`` is
   *on*; otherwise, when the nearest edge point ``q`` lies inside the edge's range, the *wedge
   rule* decides: with ``n_f, n_g`` the outward normals of the edge's two faces at ``q`` and
   ``r = p − q``, the edge is convex when the direction into face ``g`` points against ``n_f``;
   then ``p`` is inside iff ``r·n_f < 0`` and ``r·n_g < 0`` (concave: ``or``).  A point nearest
   to a vertex takes its claiming face's side, or else the winding number.

Deflection is a resolution: with points farther than ``band`` from the boundary decided by the
mesh and nearer ones decided by exact geometry, the answer does not depend on it except for
points within ``band`` of a vertex (limitation below).

Limitations
-----------
* Points within ``band`` of a vertex, nearer to it than to any face interior and farther than
  ``tol.linear`` from every face and edge, are decided by the winding number of the mesh
  (correct unless the point lies between the mesh and the exact surface there).
* The trim test samples curved p-curves with 65 points per edge and treats feet within 1.5 times
  the measured chord error of the polygon as ambiguous: a measured, not a proven, bound.
* The wedge rule is first order: it assumes the point is nearer to the edge than the faces'
  radii of curvature (the band is ``2 d`` with ``d`` the deflection, small against them for the
  default ``d``).
* Cost: one tessellation per solid, then ``O(n · faces)`` projections and a winding-number sum
  over the far points, each against the triangles of the shells whose box holds it (a closed
  shell's winding number is 0 outside its box), ``O(n_far · triangles)`` at worst.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from coons.errors import InvalidInputError
from coons.kernel.analytic import Circle, Ellipse, Line, PlanarSurface
from coons.tolerance import Tolerance, resolve
from coons.topology.brep import BRep

__all__ = ["classify_points", "INSIDE", "ON", "OUTSIDE", "winding_numbers"]

INSIDE, ON, OUTSIDE = -1, 0, 1

#: Samples per curved edge for the trim polygons and boundary polylines (the chord error is
#: measured and added to the ambiguity band, so this is resolution, not tolerance).
_CURVE_SAMPLES = 65
#: Point–triangle pairs held at once by the winding-number sum (memory bound, ~ 100 MB).
_CHUNK = 1 << 20


# ====================================================================== public API
def classify_points(solid, points, tol: Tolerance | None = None, *, deflection: float | None = None) -> np.ndarray:
    """Membership of points: ``-1`` inside, ``0`` on the boundary (within ``tol.linear``), ``+1`` outside.

    Parameters
    ----------
    solid : Solid or BRep
        A valid closed solid (possibly several lumps, voids).
    points : (n, 3) array_like of float
    tol : Tolerance, optional
        ``tol.linear`` is the distance below which a point is *on* the boundary.
    deflection : float, optional
        Tessellation deflection of the far-field winding-number test (default: the
        tessellator's, ``1e-3`` of the bounding-box diagonal).  Resolution only.

    Returns
    -------
    (n,) int8

    Raises
    ------
    InvalidInputError
        Not a Solid/BRep, points not of shape (n, 3) or not finite.

    Examples
    --------
    >>> from coons.topology.primitives import Sphere
    >>> classify_points(Sphere(1.0), [[0, 0, 0], [1, 0, 0], [0, 0, 2]]).tolist()
    [-1, 0, 1]
    """
    t = resolve(tol)
    P = _as_points(points)
    return Classifier(solid, t, deflection=deflection).classify(P)[0]


def winding_numbers(points: np.ndarray, triangles: np.ndarray) -> np.ndarray:
    """Generalised winding numbers ``(q,)`` of points ``(q, 3)`` w.r.t. triangle corners ``(m, 3, 3)``.

    Van Oosterom & Strackee's solid angle per triangle, summed over the mesh and divided by
    ``4π``; the work is chunked (at most ``_CHUNK`` point–triangle pairs at once).
    """
    P = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    T = np.asarray(triangles, dtype=np.float64).reshape(-1, 3, 3)
    out = np.zeros(P.shape[0])
    if T.shape[0] == 0 or P.shape[0] == 0:
        return out
    step = max(1, _CHUNK // T.shape[0])
    for s in range(0, P.shape[0], step):
        R = T[None, :, :, :] - P[s : s + step, None, None, :]  # (k, m, 3, 3)
        a, b, c = R[:, :, 0], R[:, :, 1], R[:, :, 2]
        la, lb, lc = (np.linalg.norm(x, axis=-1) for x in (a, b, c))
        num = np.einsum("kmi,kmi->km", a, np.cross(b, c))
        den = (la * lb * lc + np.einsum("kmi,kmi->km", a, b) * lc + np.einsum("kmi,kmi->km", a, c) * lb
               + np.einsum("kmi,kmi->km", b, c) * la)
        out[s : s + step] = np.arctan2(num, den).sum(axis=1) / (2.0 * np.pi)
    return out


# ====================================================================== the classifier
@dataclass
class _Face:
    """What the near-field test needs of one face."""

    surface: Any
    sign: float  # +1 when the outward normal is Su × Sv
    seg_uv: np.ndarray  # (s, 2, 2) trim polygon segments in the parameter plane
    seg_xyz: np.ndarray  # (s, 2, 3) boundary polyline in space
    chord: float  # largest measured distance between the polyline and the exact edges
    uv_band: float  # feet closer than this to the trim polygon are ambiguous
    lo: np.ndarray  # (3,) bounding box of the face (mesh), not enlarged
    hi: np.ndarray
    u0: float  # smallest u, v of the trim polygon (periodic shifts go to [u0, u0 + period))
    v0: float
    edges: np.ndarray  # edge ids of the face


class Classifier:
    """Reusable membership test of one solid (tessellation and face data built once).

    Parameters
    ----------
    solid : Solid or BRep
    tol : Tolerance
    deflection : float, optional
    mesh : TriangleMesh, optional
        The solid's tessellation at ``deflection`` (``tessellate(solid, deflection, tol=tol)``),
        when the caller already has it.  Per-face data (trim polygons, boxes) is built lazily,
        only for faces whose box is near some query point.

    Raises
    ------
    InvalidInputError
        Not a Solid or BRep.
    """

    def __init__(self, solid, tol: Tolerance | None = None, *, deflection: float | None = None, mesh=None) -> None:
        from coons.topology.tessellate import tessellate

        b = solid if isinstance(solid, BRep) else getattr(solid, "brep", None)
        if not isinstance(b, BRep):
            raise InvalidInputError(f"classify needs a Solid or BRep, got {type(solid).__name__}")
        self.b = b
        self.t = resolve(tol)
        self.empty = b.n_faces == 0
        if self.empty:
            return
        if mesh is None:
            mesh = tessellate(b, deflection=deflection, tol=self.t)
        self.tri = mesh.vertices[mesh.triangles]
        self.lo, self.hi = mesh.vertices.min(axis=0), mesh.vertices.max(axis=0)
        # The tessellator's default deflection when none is given (its documented default).
        diag = float(np.linalg.norm(np.ptp(mesh.vertices, axis=0)))
        d = float(deflection) if deflection is not None else 1e-3 * diag
        # Mesh and exact boundary are within d of each other; twice that plus a few tolerances
        # is the distance beyond which the mesh's answer is the exact one.
        self.band = 2.0 * d + 10.0 * self.t.linear
        # Per-face data is built on first use (only faces near some query point are needed);
        # their mesh boxes, enlarged by the deflection (edge samples may stick out of the mesh
        # by that much), select them.
        self._mesh = mesh
        F = b.n_faces
        lo, hi = np.full((F, 3), np.inf), np.full((F, 3), -np.inf)
        np.minimum.at(lo, mesh.face_ids, self.tri.min(axis=1))
        np.maximum.at(hi, mesh.face_ids, self.tri.max(axis=1))
        lo[~np.isfinite(lo)], hi[~np.isfinite(hi)] = -np.inf, np.inf  # a face without triangles: always near
        self._face_lo, self._face_hi = lo - d, hi + d
        self._faces: list[_Face | None] = [None] * F
        # Triangles grouped by shell, with the shells' boxes: a closed shell contributes a winding
        # number of 0 at a point outside its box, so only the shells whose box holds a point are
        # summed (a tool gathered from many disjoint solids is many small shells).
        tri_shell = np.asarray(b.face_shell, dtype=np.int64)[mesh.face_ids]
        order = np.argsort(tri_shell, kind="stable")
        self._tri_by_shell = self.tri[order]
        self._shell_ptr = np.searchsorted(tri_shell[order], np.arange(b.n_shells + 1))
        S = b.n_shells
        slo, shi = np.full((S, 3), np.inf), np.full((S, 3), -np.inf)
        np.minimum.at(slo, tri_shell, self.tri.min(axis=1))
        np.maximum.at(shi, tri_shell, self.tri.max(axis=1))
        self._shell_lo, self._shell_hi = slo, shi

    @property
    def faces(self) -> list[_Face]:
        """Per-face data of every face (built on demand)."""
        return [self.face(f) for f in range(self.b.n_faces)]

    def face(self, f: int) -> _Face:
        """Per-face data of face ``f`` (built on first use)."""
        F = self._faces[f]
        if F is None:
            F = self._faces[f] = self._face(f, self._mesh)
        return F

    # ------------------------------------------------------------------ face data
    def _face(self, f: int, mesh) -> _Face:
        b = self.b
        S = surface_of(b, f)
        uv_segs, xyz_segs, chords, uv_chords, edges = [], [], [0.0], [0.0], []
        for loop in b.face_loop_ids(f):
            ring = []  # the loop's uv polyline; consecutive p-curves may jump at a pole (docs/brep.md)
            for c in b.loop_coedges(int(loop)):
                e, side = int(c) >> 1, int(c) & 1
                edges.append(e)
                tt, X, ch = edge_samples(b, e)
                chords.append(ch)
                pi = int(b.edge_pcurve[e, side])
                tm = 0.5 * (tt[:-1] + tt[1:])
                if pi >= 0:
                    UV = np.asarray(b.pcurves[pi].evaluate(tt), dtype=np.float64)
                    UM = np.asarray(b.pcurves[pi].evaluate(tm), dtype=np.float64)
                else:
                    UV = np.asarray(S.closest_parameters(X), dtype=np.float64)
                    UM = np.asarray(S.closest_parameters(b.edge_points(e, tm)), dtype=np.float64)
                uv_chords.append(float(np.max(np.linalg.norm(UM - 0.5 * (UV[:-1] + UV[1:]), axis=1))))
                if side == 1:
                    UV = UV[::-1]
                ring.append(UV)
                xyz_segs.append(np.stack([X[:-1], X[1:]], axis=1))
            R = np.concatenate(ring)
            uv_segs.append(np.stack([R, np.roll(R, -1, axis=0)], axis=1))
        seg_uv = np.concatenate(uv_segs)
        seg_xyz = np.concatenate(xyz_segs)
        sel = mesh.face_ids == f
        V = mesh.vertices[mesh.triangles[sel]].reshape(-1, 3)
        V = np.concatenate([V, seg_xyz.reshape(-1, 3)])
        # A foot closer than this to the trim polygon may lie on either side of the exact trim:
        # the polygon's measured chord error plus rounding of the parameters' magnitude.
        uv_band = 1.5 * max(uv_chords) + 1e-12 * (1.0 + float(np.max(np.abs(seg_uv))))
        return _Face(S, 1.0 if bool(b.face_sense[f]) else -1.0, seg_uv, seg_xyz, float(max(chords)), uv_band,
                     V.min(axis=0), V.max(axis=0), float(seg_uv[..., 0].min()), float(seg_uv[..., 1].min()),
                     np.unique(np.asarray(edges, dtype=np.int64)))

    # ------------------------------------------------------------------ classification
    def classify(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Membership and, for points *on* the boundary, the outward unit normal there.

        Parameters
        ----------
        points : (n, 3) float64

        Returns
        -------
        cls : (n,) int8, -1 inside / 0 on / +1 outside
        normal : (n, 3) float64, the outward normal of the face the point lies on (NaN where
            ``cls != 0`` or the point lies on an edge or vertex)
        """
        P = _as_points(points)
        n = P.shape[0]
        cls = np.zeros(n, dtype=np.int8)
        normal = np.full((n, 3), np.nan)
        if self.empty or n == 0:
            cls[:] = OUTSIDE
            return cls, normal
        lin = self.t.linear
        best = np.full(n, np.inf)  # distance of the nearest face whose foot is clearly inside its trim
        claim_side = np.zeros(n)
        claim_normal = np.full((n, 3), np.nan)
        unclaimed = np.full(n, np.inf)  # distance to the nearest surface whose foot is outside or ambiguous
        on_face = np.zeros(n, dtype=bool)
        on_normal = np.full((n, 3), np.nan)  # normal of a face the point lies on near its trim boundary
        conflict = np.zeros(n, dtype=bool)
        plo, phi = P.min(axis=0) - self.band, P.max(axis=0) + self.band
        near = np.flatnonzero(np.all((self._face_lo <= phi) & (self._face_hi >= plo), axis=1))
        for fi in near.tolist():
            if not np.any(np.all((P >= self._face_lo[fi] - self.band) & (P <= self._face_hi[fi] + self.band), axis=1)):
                continue
            F = self.face(fi)
            idx = np.flatnonzero(np.all((P >= F.lo - self.band) & (P <= F.hi + self.band), axis=1))
            if idx.size == 0:
                continue
            Q = P[idx]
            uv = _project(F.surface, Q, self.t)
            foot = np.asarray(F.surface.evaluate(uv[:, 0], uv[:, 1]))
            nrm = F.sign * np.asarray(F.surface.normal(uv[:, 0], uv[:, 1]))
            dvec = Q - foot
            dist = np.linalg.norm(dvec, axis=1)
            s = np.einsum("ij,ij->i", dvec, nrm)
            close = dist <= self.band
            if not np.any(close):
                continue
            idx, uv, dist, s, nrm = idx[close], uv[close], dist[close], s[close], nrm[close]
            uv = _shift_periodic(F, uv)
            inside = _in_polygon(uv, F.seg_uv)
            amb = _segment_distance(uv, F.seg_uv) <= F.uv_band
            take = inside & ~amb & (dist < best[idx])
            j = idx[take]
            best[j] = dist[take]
            claim_side[j] = np.sign(s[take])
            claim_normal[j] = nrm[take]
            other = ~(inside & ~amb)
            np.minimum.at(unclaimed, idx[other], dist[other])
            # On the surface with the foot near the trim boundary: decide the trim exactly.
            maybe = amb & (dist <= lin)
            if np.any(maybe):
                k = idx[maybe]
                inn = self._inside_trim(fi, P[k] - s[maybe, None] * nrm[maybe])
                k, m = k[inn], nrm[maybe][inn]
                on_face[k] = True
                have = ~np.isnan(on_normal[k, 0])
                # A point on a sharp edge lies on faces with different normals: no single normal.
                conflict[k[have]] |= np.einsum("ij,ij->i", on_normal[k[have]], m[have]) < 1.0 - 1e-9
                on_normal[k[~have]] = m[~have]
        claimed = np.isfinite(best)
        cls[claimed] = np.where(claim_side[claimed] < 0, INSIDE, OUTSIDE)
        on = (claimed & (best <= lin)) | on_face
        cls[on] = ON
        normal[on] = np.where(np.isnan(claim_normal[on]), on_normal[on], claim_normal[on])
        normal[conflict] = np.nan
        # An edge or vertex may be nearer than the claiming face (or no face claims the point):
        # decide exactly at the nearest edge.
        todo_edge = ~on & np.isfinite(unclaimed) & (~claimed | (unclaimed < best - lin))
        decided = (claimed & ~todo_edge) | on
        if np.any(todo_edge):
            c_e, ok_e = self._edge_rule(P[todo_edge])
            k = np.flatnonzero(todo_edge)
            cls[k[ok_e]] = c_e[ok_e]
            decided[k[ok_e]] = True
            # Nearest to a vertex: the claim of a face, when there is one, else the winding number.
            rest = k[~ok_e]
            keep = claimed[rest]
            decided[rest[keep]] = True
        far = ~decided
        # Beyond the mesh's box by more than the band: outside without summing solid angles.
        outside_box = np.any((P < self.lo - self.band) | (P > self.hi + self.band), axis=1)
        cls[far & outside_box] = OUTSIDE
        far &= ~outside_box
        if np.any(far):
            w = self._winding(P[far])
            cls[far] = np.where(np.abs(w) > 0.5, INSIDE, OUTSIDE)
        return cls, normal

    def _winding(self, Q: np.ndarray) -> np.ndarray:
        """Winding numbers ``(k,)`` of the mesh at ``Q (k, 3)``, summed over the shells whose box holds each point."""
        hit = np.all((Q[:, None] >= self._shell_lo[None]) & (Q[:, None] <= self._shell_hi[None]), axis=2)  # (k, S)
        w = np.zeros(Q.shape[0])
        for sh in np.flatnonzero(np.any(hit, axis=0)).tolist():  # shells near some point (few per point)
            k = np.flatnonzero(hit[:, sh])
            w[k] += winding_numbers(Q[k], self._tri_by_shell[self._shell_ptr[sh]:self._shell_ptr[sh + 1]])
        return w

    # ------------------------------------------------------------------ edges
    def _inside_trim(self, f: int, X: np.ndarray) -> np.ndarray:
        """Whether feet ``X (k, 3)`` on face ``f``'s surface near its trim boundary lie in the face.

        At the nearest boundary point ``q`` (inside an edge's range) the foot is in the face when
        ``(X − q)·(n × T) >= −tol.linear``, ``T`` the face's direction of travel along the edge and
        ``n`` its outward normal (the face lies to the left); at a vertex, when ``|X − q| <= tol.linear``.
        """
        b, F = self.b, self.face(f)
        k = X.shape[0]
        best = np.full(k, np.inf)
        ok = np.zeros(k, dtype=bool)
        for e in F.edges.tolist():
            te, q, interior = _edge_closest(b, e, X, self.t)
            d = np.linalg.norm(X - q, axis=1)
            better = d < best
            if not np.any(better):
                continue
            best[better] = d[better]
            side = 0 if int(b.edge_face[e, 0]) == f else 1
            _, dq = edge_derivative(b, e, te[better])
            T = dq if side == 0 else -dq
            uv = _project(F.surface, q[better], self.t)
            n = F.sign * np.asarray(F.surface.normal(uv[:, 0], uv[:, 1]))
            inward = np.einsum("ij,ij->i", X[better] - q[better], np.cross(n, T))
            unit = np.linalg.norm(np.cross(n, T), axis=1)
            ok[better] = np.where(interior[better], inward >= -self.t.linear * unit, d[better] <= self.t.linear)
        return ok

    def _edge_rule(self, P: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Exact decision near edges: ``(cls, decided)`` for points ``(k, 3)`` (see the module docstring)."""
        k = P.shape[0]
        best, best_e, best_t, best_interior = self._nearest_edges(P, self.band)
        # Edges were searched within the band of the points' box only; a point whose nearest edge
        # lies farther (its foot in a hole of a face, far from the hole's rim) searches again
        # within that distance, so that no nearer edge is left out.
        far = np.flatnonzero(best > self.band)
        if far.size:
            got = self._nearest_edges(P[far], float(best[far].max()))
            best[far], best_e[far], best_t[far], best_interior[far] = got
        cls = np.zeros(k, dtype=np.int8)
        ok = best <= self.t.linear
        for e in np.unique(best_e[~ok & best_interior & (best_e >= 0)]):
            sel = np.flatnonzero(~ok & best_interior & (best_e == e))
            cls[sel] = self._wedge(int(e), P[sel], best_t[sel])
            ok[sel] = True
        return cls, ok

    def _nearest_edges(self, P: np.ndarray, reach: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """The nearest edge to each point ``(k, 3)`` among the edges that come within ``reach`` of the
        points' box: ``(distance, edge, parameter, interior)``, each ``(k,)`` (inf / -1 where none)."""
        b = self.b
        k = P.shape[0]
        best = np.full(k, np.inf)
        best_e = np.full(k, -1, dtype=np.int64)
        best_t = np.zeros(k)
        best_interior = np.zeros(k, dtype=bool)
        lo, hi = P.min(axis=0) - reach, P.max(axis=0) + reach
        for e in range(b.n_edges):
            tt, X, ch = edge_samples(b, e)
            if np.any(X.max(axis=0) + ch < lo) or np.any(X.min(axis=0) - ch > hi):
                continue
            te, q, interior = _edge_closest(b, e, P, self.t)
            d = np.linalg.norm(P - q, axis=1)
            better = d < best
            best[better], best_e[better], best_t[better] = d[better], e, te[better]
            best_interior[better] = interior[better]
        return best, best_e, best_t, best_interior

    def _wedge(self, e: int, P: np.ndarray, te: np.ndarray) -> np.ndarray:
        """The wedge rule at edge ``e`` for points ``P`` whose nearest edge points are at ``te``."""
        b = self.b
        q, dq = edge_derivative(b, e, te)
        r = P - q
        n_faces, inward = [], []
        for side in (0, 1):
            f = int(b.edge_face[e, side])
            S = self.face(f).surface
            uv = _project(S, q, self.t)
            nrm = self.face(f).sign * np.asarray(S.normal(uv[:, 0], uv[:, 1]))
            T = dq if side == 0 else -dq  # direction of travel of this side
            n_faces.append(nrm)
            inward.append(np.cross(nrm, T))  # face on the left of the travel direction
        nf, ng = n_faces
        convex = np.einsum("ij,ij->i", inward[1], nf) < 0.0
        a, c = np.einsum("ij,ij->i", r, nf) < 0.0, np.einsum("ij,ij->i", r, ng) < 0.0
        inside = np.where(convex, a & c, a | c)
        return np.where(inside, INSIDE, OUTSIDE).astype(np.int8)


# ====================================================================== geometry helpers
def surface_of(b: BRep, f: int):
    """The surface of face ``f``; the Newell plane of its vertices for an implicit plane."""
    si = int(b.face_surface[f])
    if si >= 0:
        return b.surfaces[si]
    loop0 = b.loop_coedges(int(b.face_loop_ids(f)[0]))
    V = b.vertex_point[b.coedge_origin[loop0]]
    W = np.roll(V, -1, axis=0)
    N = np.array([np.sum((V[:, 1] - W[:, 1]) * (V[:, 2] + W[:, 2])),
                  np.sum((V[:, 2] - W[:, 2]) * (V[:, 0] + W[:, 0])),
                  np.sum((V[:, 0] - W[:, 0]) * (V[:, 1] + W[:, 1]))])
    x = W[0] - V[0]
    return PlanarSurface(V.mean(axis=0), N, x - np.dot(x, N) / np.dot(N, N) * N)


def edge_samples(b: BRep, e: int) -> tuple[np.ndarray, np.ndarray, float]:
    """``(t, X, chord)``: parameters over the edge range, points, and the largest chord error measured at midpoints."""
    r0, r1 = (float(x) for x in b.edge_range[e])
    ci = int(b.edge_curve[e])
    curve = b.curves[ci] if ci >= 0 else None
    if curve is None or isinstance(curve, Line):
        tt = np.array([r0, r1])
        if curve is None:
            return tt, b.vertex_point[b.edge_vertex[e]].astype(np.float64), 0.0
        return tt, np.asarray(curve.evaluate(tt), dtype=np.float64), 0.0
    tt = np.linspace(r0, r1, _CURVE_SAMPLES)
    X = np.asarray(curve.evaluate(tt), dtype=np.float64)
    M = np.asarray(curve.evaluate(0.5 * (tt[:-1] + tt[1:])), dtype=np.float64)
    chord = float(np.max(np.linalg.norm(M - 0.5 * (X[:-1] + X[1:]), axis=1)))
    return tt, X, chord


def edge_derivative(b: BRep, e: int, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Points and first derivatives ``(k, 3)`` of edge ``e`` at parameters ``t``."""
    ci = int(b.edge_curve[e])
    if ci < 0:
        p, q = b.vertex_point[b.edge_vertex[e]]
        r0, r1 = (float(x) for x in b.edge_range[e])
        s = (t - r0) / (r1 - r0)
        return p + s[:, None] * (q - p), np.broadcast_to((q - p) / (r1 - r0), (t.size, 3)).copy()
    D = np.asarray(b.curves[ci].derivatives(t, 1))
    return D[:, 0], D[:, 1]


def _edge_closest(b: BRep, e: int, P: np.ndarray, t: Tolerance) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Nearest points of edge ``e`` (within its range) to ``P``: ``(t, q, interior)``."""
    r0, r1 = (float(x) for x in b.edge_range[e])
    ci = int(b.edge_curve[e])
    if ci < 0:
        p, q = b.vertex_point[b.edge_vertex[e]]
        d = q - p
        s = np.clip((P - p) @ d / float(d @ d), 0.0, 1.0)
        return r0 + s * (r1 - r0), p + s[:, None] * d, (s > 0.0) & (s < 1.0)
    curve = b.curves[ci]
    te = _curve_closest(curve, P, r0, t)
    interior = (te > r0) & (te < r1)
    ends = np.asarray(curve.evaluate(np.array([r0, r1])))
    d0 = np.linalg.norm(P - ends[0], axis=1)
    d1 = np.linalg.norm(P - ends[1], axis=1)
    te = np.where(interior, te, np.where(d0 <= d1, r0, r1))
    return te, np.asarray(curve.evaluate(te)), interior


def _curve_closest(curve, P: np.ndarray, r0: float, t: Tolerance) -> np.ndarray:
    """Parameters ``(k,)`` of the points of ``curve`` nearest to ``P`` (periodic ones shifted into ``[r0, r0 + 2π)``)."""
    if isinstance(curve, (Line, Circle, Ellipse)):
        te = np.asarray(curve.closest_parameters(P), dtype=np.float64).reshape(-1)
    else:
        from coons.kernel.projection import curve_closest_parameters

        te = np.asarray(curve_closest_parameters(curve, P, t), dtype=np.float64).reshape(-1)
    if isinstance(curve, (Circle, Ellipse)):
        te = r0 + np.mod(te - r0, 2.0 * math.pi)
    return te


def _project(S, Q: np.ndarray, t: Tolerance) -> np.ndarray:
    """Exact foot parameters ``(k, 2)`` of points on a surface (closed form or NURBS projection)."""
    from coons.kernel.surface import NurbsSurface

    if isinstance(S, NurbsSurface):
        from coons.kernel.projection import surface_closest_parameters

        return np.asarray(surface_closest_parameters(S, Q, t), dtype=np.float64).reshape(-1, 2)
    return np.asarray(S.closest_parameters(Q), dtype=np.float64).reshape(-1, 2)


def _shift_periodic(F: _Face, uv: np.ndarray) -> np.ndarray:
    """Move periodic parameters by whole periods into ``[u0 - ε, u0 - ε + period)`` of the face."""
    uv = uv.copy()
    S = F.surface
    for k, (periodic, period, start) in enumerate(((getattr(S, "periodic_u", False), getattr(S, "period_u", None), F.u0),
                                                    (getattr(S, "periodic_v", False), getattr(S, "period_v", None), F.v0))):
        if periodic and period:
            base = start - 1e-9 * period  # a rounding margin: a foot on the start line stays there
            uv[:, k] = base + np.mod(uv[:, k] - base, period)
    return uv


#: Below this many point–segment pairs (or with fewer than four points per row) :func:`_in_polygon`
#: tests every pair: the row sweep's Python loop over rows does not pay.
_ROW_SWEEP_PAIRS = 1 << 18
#: Up to this many point–segment pairs :func:`_in_polygon` tests them in Python floats (numpy's
#: per-call cost exceeds the arithmetic of a few points against a small face's polygon).
_SCALAR_PAIRS = 64


def _polygon_slopes(seg: np.ndarray) -> np.ndarray:
    """``dx / dy`` of polygon segments ``(s, 2, 2)`` (``dx`` where ``dy = 0``), as :func:`_in_polygon` uses them."""
    a, c = seg[:, 0], seg[:, 1]
    dy = c[:, 1] - a[:, 1]
    with np.errstate(divide="ignore", invalid="ignore"):
        return (c[:, 0] - a[:, 0]) / np.where(dy == 0, 1.0, dy)


def _in_polygon(uv: np.ndarray, seg: np.ndarray, slope: np.ndarray | None = None) -> np.ndarray:
    """Even–odd crossing test of points ``(k, 2)`` against closed polygon segments ``(s, 2, 2)``.

    A point is inside when an odd number of segments straddle its horizontal line to its right
    (crossing abscissa ``xc > x``).  Points sharing a ``y`` (the rows of a grid of candidate
    interior points) share the crossings: each distinct ``y`` is then handled once, its crossings
    sorted and each point's count found by bisection, ``O(rows · s + k log s)`` instead of the
    ``O(k · s)`` of testing every pair (a face with hundreds of holes has tens of thousands of
    segments).  The crossings and comparisons are the same floating-point operations either way.
    ``slope``: :func:`_polygon_slopes` of ``seg`` when the caller keeps them.
    """
    if uv.shape[0] == 0:
        return np.zeros(0, dtype=bool)
    a, c = seg[:, 0], seg[:, 1]
    if slope is None:
        slope = _polygon_slopes(seg)
    if uv.shape[0] * seg.shape[0] <= _SCALAR_PAIRS:  # the same comparisons and crossings in Python floats
        sides = list(zip(a[:, 0].tolist(), a[:, 1].tolist(), c[:, 1].tolist(), slope.tolist()))
        return np.array([sum(1 for ax, ay, cy, m in sides if (ay > y) != (cy > y) and x < ax + (y - ay) * m) % 2 == 1
                         for x, y in uv.tolist()], dtype=bool)
    every = uv.shape[0] * seg.shape[0] <= _ROW_SWEEP_PAIRS
    if not every:  # (the rows are only needed, and only sorted out, for the sweep)
        ys, row = np.unique(uv[:, 1], return_inverse=True)
        row = row.ravel()
        every = 4 * ys.size > uv.shape[0]
    if every:  # every pair
        out = np.empty(uv.shape[0], dtype=bool)
        step = max(1, _CHUNK // max(1, seg.shape[0]))
        for s0 in range(0, uv.shape[0], step):
            x, y = uv[s0 : s0 + step, 0:1], uv[s0 : s0 + step, 1:2]
            straddle = (a[None, :, 1] > y) != (c[None, :, 1] > y)
            xc = a[None, :, 0] + (y - a[None, :, 1]) * slope[None, :]
            out[s0 : s0 + step] = (np.count_nonzero(straddle & (x < xc), axis=1) % 2) == 1
        return out
    count = np.zeros(uv.shape[0], dtype=np.int64)
    order = np.argsort(row, kind="stable")
    ptr = np.searchsorted(row[order], np.arange(ys.size + 1))
    for r, y in enumerate(ys.tolist()):
        j = np.flatnonzero((a[:, 1] > y) != (c[:, 1] > y))
        if j.size == 0:
            continue
        xc = np.sort(a[j, 0] + (y - a[j, 1]) * slope[j])
        pts = order[ptr[r] : ptr[r + 1]]
        count[pts] = j.size - np.searchsorted(xc, uv[pts, 0], side="right")  # crossings with xc > x
    return (count % 2) == 1


def _segment_distance(Q: np.ndarray, seg: np.ndarray) -> np.ndarray:
    """Distance of points ``(k, d)`` to the nearest of segments ``(s, 2, d)``, chunked.

    Coordinate by coordinate on ``(k, s)`` arrays (the same arithmetic as on ``(k, s, d)`` ones,
    with fewer temporaries); the square root is taken of the ``k`` minima only.
    """
    out = np.full(Q.shape[0], np.inf)
    if seg.shape[0] == 0:
        return out
    a = seg[:, 0]
    d = seg[:, 1] - a
    dd = np.maximum(np.einsum("ij,ij->i", d, d), 1e-300)
    step = max(1, _CHUNK // max(1, seg.shape[0]))
    dims = range(Q.shape[1])
    for s in range(0, Q.shape[0], step):
        R = [Q[s : s + step, i, None] - a[None, :, i] for i in dims]  # (k, s) per coordinate
        lam = sum(R[i] * d[None, :, i] for i in dims) / dd
        np.clip(lam, 0.0, 1.0, out=lam)
        d2 = sum(np.square(R[i] - lam * d[None, :, i]) for i in dims)
        out[s : s + step] = np.sqrt(np.min(d2, axis=1))
    return out


def _as_points(points) -> np.ndarray:
    P = np.asarray(points, dtype=np.float64)
    if P.ndim == 1 and P.shape == (3,):
        P = P[None]
    if P.ndim != 2 or P.shape[1] != 3:
        raise InvalidInputError(f"points must have shape (n, 3), got {P.shape}")
    if not np.all(np.isfinite(P)):
        raise InvalidInputError("points must be finite")
    return P
