"""Sweeps of planar profiles into exact solids: extrusion, revolution and lofting.

:func:`extrude` translates a :class:`~coons.topology.profile.Profile` along a vector,
:func:`revolve` turns it about an axis in its plane, :func:`loft` skins a solid through two or
more profiles.  Each returns a :class:`~coons.topology.shape.Solid` whose B-rep was assembled
from its face loops (:meth:`~coons.topology.builder.BRepBuilder.assemble`: the structure the
Euler sequence ``mvfs, mev…, mef, kemr, kfmrh, sweep_loop`` would make, with Euler–Poincaré
verified by the checker) and checked by ``build()``, so it is valid or not returned at all.  The
module does not sweep along paths, does not taper or twist extrusions, does not make thin or
open (sheet) results, and does not loft holes or through points.

Geometry is exact and follows :mod:`coons.topology.primitives`: analytic surfaces of
:mod:`coons.kernel.analytic` where the swept curve allows one, exact NURBS otherwise; every edge
has its 3-D curve (``Line``, ``Circle`` or ``NurbsCurve``), created along its increasing
parameter, and same-parameter p-curves (``Line2D``, ``Trig2D`` or 2-D ``NurbsCurve``) on both
of its faces; faces have ``sense = True`` except where the surface's own normal points into the
solid (concave arcs, inward-facing walls of holes).  There are no seam and no degenerate edges
(``docs/brep.md``): a full turn is split into two half-turn faces per profile segment, and where
the profile touches the axis the loops pass through a pole vertex.

Surfaces
--------
========================  ===============================================================
extrude, perpendicular    line → ``PlanarSurface``, arc → ``CylindricalSurface``,
                          spline → NURBS ``C(u) + v V`` (``coons.kernel.construct.extrude``)
extrude, oblique          line → ``PlanarSurface``, arc and spline → NURBS extrusion
revolve                   line ∥ axis → ``CylindricalSurface``, ⟂ axis → ``PlanarSurface``,
                          oblique → ``ConicalSurface``, arc centred on the axis →
                          ``SphericalSurface``, other arcs → ``ToroidalSurface`` (ring tori),
                          splines and spindle-torus arcs → NURBS
                          (``coons.kernel.conics.nurbs_revolution``, The NURBS Book A8.1)
loft                      two NURBS halves (``coons.kernel.construct.loft``, The NURBS Book
                          §10.3, or ruled surfaces §8.4), planar end caps
========================  ===============================================================

A parallel circle (the path of a profile vertex) is shared by the faces of the two segments
meeting there.  Analytic faces use the angle as ``u`` and NURBS revolutions a rational
parameter that agrees with the angle only at the knots, so no exact p-curve joins the two:
in a revolution every run of segments between pole vertices that contains a spline (or a
spindle arc) is revolved as NURBS as a whole (:func:`revolve`).

Face counts (coons / OCCT through build123d; OCCT keeps a full circle as one edge, closes each
full turn with a seam edge per profile vertex, and lofts one face per section edge): extrusion
of an ``n``-gon with ``h`` circular holes: F ``n + 2h + 2`` / ``n + h + 2``; full revolution of a
profile with ``m`` segments off the axis: F ``2m`` / ``m`` (a half disk: a sphere of 2 / 1
faces); a partial revolution: ``m + 2`` / ``m + 2`` (circles counted as one segment by OCCT);
loft: 4 (two half faces, two caps) / 3 for circles, 6 for squares.
"""

from __future__ import annotations

import math
from numbers import Real
from typing import Any, Sequence

import numpy as np

from coons.errors import InvalidInputError, TopologyError
from coons.kernel import conics, construct
from coons.kernel.analytic import (
    Circle,
    ConicalSurface,
    CylindricalSurface,
    Line,
    PlanarSurface,
    SphericalSurface,
    ToroidalSurface,
)
from coons.kernel.curve import NurbsCurve
from coons.kernel.pcurve import Line2D, Trig2D
from coons.tolerance import Tolerance, resolve
from coons.topology.builder import BRepBuilder
from coons.topology.profile import Profile, Segment
from coons.topology.shape import Solid
from coons.topology.transform import rotation

__all__ = ["extrude", "revolve", "loft"]

PI = math.pi
TWO_PI = 2.0 * math.pi
_U_AXIS = np.array([1.0, 0.0])
_V_AXIS = np.array([0.0, 1.0])
#: Parameter samples per knot span when a spline's distance to the revolution axis is bounded.
_AXIS_SAMPLES = 64


# ============================================================================ assembly
class _Assembly:
    """Vertices, edges with curves, faces with loops and p-curves: one B-rep, assembled in one go."""

    def __init__(self, tol: Tolerance) -> None:
        self.tol = tol
        self.points: list[np.ndarray] = []
        self.edges: list[tuple[int, int]] = []
        self.curves: list[tuple[Any, tuple[float, float]]] = []
        self.loops: list[list[list[int]]] = []
        self.surfaces: list[Any] = []
        self.senses: list[bool] = []
        self.side: dict[tuple[int, int], int] = {}
        self.pcurves: dict[tuple[int, int], Any] = {}

    def vertex(self, point) -> int:
        self.points.append(np.asarray(point, dtype=np.float64))
        return len(self.points) - 1

    def edge(self, a: int, b: int, curve: Any, t_range: tuple[float, float]) -> int:
        self.edges.append((a, b))
        self.curves.append((curve, (float(t_range[0]), float(t_range[1]))))
        return len(self.edges) - 1

    def face(self, surface: Any, sense: bool, loops: Sequence[Sequence[tuple[int, bool]]]) -> int:
        """A face on ``surface``; each loop lists ``(edge, forward)`` in order."""
        f = len(self.loops)
        refs = []
        for loop in loops:
            refs.append([(e + 1) if fwd else -(e + 1) for e, fwd in loop])
            for e, fwd in loop:
                if (e, f) in self.side:
                    raise TopologyError(f"internal: edge {e} used twice by face {f} (a seam)")
                self.side[(e, f)] = 0 if fwd else 1
        self.loops.append(refs)
        self.surfaces.append(surface)
        self.senses.append(bool(sense))
        return f

    def pcurve(self, edge: int, face: int, pcurve: Any) -> None:
        self.pcurves[(edge, face)] = pcurve

    def build(self) -> Solid:
        """Assemble, nest void shells in the outer shell (by the sign of their volumes), check.

        Raises
        ------
        TopologyError
            A missing p-curve, several outer shells, or an invalid result (the checker's report).
        """
        b = BRepBuilder(self.tol)
        b.assemble(np.array(self.points), np.array(self.edges, dtype=np.int64), self.loops,
                   face_surfaces=self.surfaces, face_senses=self.senses)
        for e, (curve, rng) in enumerate(self.curves):
            b.set_edge_curve(e, curve, rng)
        for (e, f), side in self.side.items():
            pc = self.pcurves.get((e, f))
            if pc is None:
                raise TopologyError(f"internal: edge {e} has no p-curve in face {f}")
            b.set_pcurve(2 * e + side, pc)
        if len(b.ssolid) > 1:
            from coons.topology.mass import shell_volumes

            vols = shell_volumes(b.build(check=False))
            outer = np.flatnonzero(vols > 0)
            if outer.size != 1:
                raise TopologyError(
                    f"internal: the sweep has {outer.size} outward shells (volumes {vols.tolist()}), expected exactly 1"
                )
            for s in np.flatnonzero(vols <= 0):
                b.nest_shells(int(outer[0]), int(s))
        return Solid(b.build())


def _on_plane(plane: PlanarSurface, curve: Any) -> Any:
    """The exact same-parameter p-curve of a 3-D curve lying in ``plane`` (the projection is affine)."""
    X, Y, _ = plane.frame
    if isinstance(curve, Line):
        return Line2D(plane.closest_parameters(curve.origin), [curve.direction @ X, curve.direction @ Y])
    if isinstance(curve, Circle):
        Xc, Yc, _ = curve.frame
        R = curve.radius
        return Trig2D(plane.closest_parameters(curve.center), [R * (Xc @ X), R * (Xc @ Y)], [R * (Yc @ X), R * (Yc @ Y)])
    if isinstance(curve, NurbsCurve):
        return NurbsCurve(plane.closest_parameters(curve.control_points), curve.knots, curve.degree, curve.weights)
    raise TopologyError(f"internal: no planar p-curve for a {type(curve).__name__}")


def _sense(surface: Any, uv: Sequence[float], outward: np.ndarray) -> bool:
    """Whether the surface normal at ``uv`` agrees with the outward direction.

    Raises
    ------
    TopologyError
        The normal is perpendicular to the outward direction there (no decision possible).
    """
    n = np.asarray(surface.normal(np.float64(uv[0]), np.float64(uv[1])), dtype=np.float64).reshape(3)
    d = float(n @ outward)
    if not abs(d) > 1e-9 * float(np.linalg.norm(outward)):  # unit normals: a cosine below 1e-9 is no decision
        raise TopologyError(f"internal: cannot orient the face on {type(surface).__name__}: normal ⟂ outward")
    return d > 0


def _translated(curve: Any, V: np.ndarray) -> Any:
    if isinstance(curve, Line):
        return Line(curve.origin + V, curve.direction)
    if isinstance(curve, Circle):
        return Circle(curve.center + V, curve.axis, curve.x_dir, curve.radius)
    return curve.translated(V)


def _tangent(curve: Any, t: float) -> np.ndarray:
    return np.asarray(curve.derivatives(np.float64(t), 1), dtype=np.float64).reshape(-1, 3)[1]


def _number(value: Any, what: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (Real, np.floating, np.integer)):
        raise InvalidInputError(f"{what} must be a finite number, got {value!r}")
    x = float(value)
    if not math.isfinite(x):
        raise InvalidInputError(f"{what} must be a finite number, got {value!r}")
    return x


def _vector(value: Any, what: str) -> np.ndarray:
    try:
        v = np.array(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise InvalidInputError(f"{what} must be 3 finite numbers, got {value!r}") from None
    if v.shape != (3,) or not np.all(np.isfinite(v)):
        raise InvalidInputError(f"{what} must be 3 finite numbers, got {value!r}")
    return v


def _profile(profile: Any, what: str) -> Profile:
    if not isinstance(profile, Profile):
        raise InvalidInputError(f"{what} must be a Profile, got {type(profile).__name__}")
    return profile


# ============================================================================ extrude
def extrude(profile: Profile, amount, *, tol: Tolerance | None = None) -> Solid:
    """The solid swept by ``profile`` translated along a vector (a prism or general cylinder).

    Faces: the profile itself (outward normal against the extrusion), its translate, and one
    side face per segment of every wire (module docstring for the surfaces): holes give inner
    loops on both caps and side walls facing into the hole.  Vertices: two per profile vertex;
    edges: the bottom and top copies of every segment and one straight strut per vertex.
    When the vector is within ``tol.linear`` (over its whole length) of the normal, it is
    snapped onto it and arcs give cylinders.

    Parameters
    ----------
    profile : Profile
    amount : float or (3,) array_like
        A distance along the profile normal (negative: the other way) or a vector.
    tol : Tolerance, optional

    Returns
    -------
    Solid
        Volume ``area × |V·n|`` (Cavalieri).

    Raises
    ------
    InvalidInputError
        Not a Profile; a NaN/inf amount; a zero distance or vector (not above ``tol.linear``);
        a vector lying in the profile plane (its height ``|V·n|`` not above ``tol.linear``).

    Examples
    --------
    >>> from coons.topology.profile import Profile
    >>> s = extrude(Profile.rectangle(4, 2).with_hole(Profile.circle(0.5)), 3.0)
    >>> bool(abs(s.volume - (8 - math.pi / 4) * 3) < 1e-12), len(s.faces())
    (True, 8)
    """
    t = resolve(tol)
    p = _profile(profile, "extrude: profile")
    N = p.normal
    if isinstance(amount, (Real, np.floating, np.integer)) and not isinstance(amount, bool):
        d = _number(amount, "extrude: distance")
        if not abs(d) > t.linear:
            raise InvalidInputError(f"extrude: distance must be non-zero (above tol.linear = {t.linear:g}), got {d!r}")
        V = d * N
    else:
        V = _vector(amount, "extrude: vector")
        length = float(np.linalg.norm(V))
        if not length > t.linear:
            raise InvalidInputError(f"extrude: vector must be non-zero (longer than tol.linear = {t.linear:g}), got {V.tolist()}")
    h = float(V @ N)
    if not abs(h) > t.linear:
        raise InvalidInputError(
            f"extrude: vector {V.tolist()} lies in the profile plane (its height along the normal {N.tolist()} is {h:.3g})"
        )
    if h < 0.0:
        p, N, h = p.flipped(), -N, -h
    perpendicular = float(np.linalg.norm(V - h * N)) <= t.linear
    if perpendicular:
        V = h * N
    return _extrude(p, V, perpendicular, t)


def _extrude(p: Profile, V: np.ndarray, perpendicular: bool, t: Tolerance) -> Solid:
    """Extrusion along ``V`` with ``V · normal > 0`` (the profile faces the extrusion)."""
    plane = p.plane
    O, (X, _, N) = plane.origin, plane.frame
    length = float(np.linalg.norm(V))
    unit = V / length
    asm = _Assembly(t)
    bottom = PlanarSurface(O, -N, X)  # outward: against the extrusion
    top = PlanarSurface(O + V, N, X)
    bottom_loops, top_loops, cap_edges = [], [], []
    for wire in p.wires:
        n = len(wire)
        P = p.plane.evaluate(*np.array([s.start for s in wire]).T)
        vb = [asm.vertex(x) for x in P]
        vt = [asm.vertex(x + V) for x in P]
        struts = [asm.edge(vb[k], vt[k], Line(P[k], V), (0.0, length)) for k in range(n)]
        bots, tops = [], []
        for k, seg in enumerate(wire):
            curve, rng = seg.to_3d(plane)
            if seg.kind != "line" and not (seg.kind == "arc" and perpendicular):
                curve = seg.to_nurbs(plane, t)
                rng = curve.domain
            e_b = asm.edge(vb[k], vb[(k + 1) % n], curve, rng)
            e_t = asm.edge(vt[k], vt[(k + 1) % n], _translated(curve, V), rng)
            s0, s1 = struts[k], struts[(k + 1) % n]
            t0, t1 = rng
            tm = 0.5 * (t0 + t1)
            outward = np.cross(_tangent(curve, tm), V)
            if isinstance(curve, Line):
                S = PlanarSurface(curve.origin, outward, curve.direction)
                pcs = {e: _on_plane(S, c) for e, c in ((e_b, curve), (e_t, _translated(curve, V)),
                                                     (s0, Line(P[k], V)), (s1, Line(P[(k + 1) % n], V)))}
                uv_mid = S.closest_parameters(curve.evaluate(tm))
            elif isinstance(curve, Circle):
                S = CylindricalSurface(curve.center, curve.axis, curve.x_dir, curve.radius)
                sg = float(curve.axis @ unit)  # ±1: v runs along ±V
                pcs = {e_b: Line2D([0.0, 0.0], _U_AXIS), e_t: Line2D([0.0, sg * length], _U_AXIS),
                       s0: Line2D([t0, 0.0], [0.0, sg]), s1: Line2D([t1, 0.0], [0.0, sg])}
                uv_mid = (tm, 0.5 * sg * length)
            else:
                S = construct.extrude(curve, V, tol=t)
                pcs = {e_b: Line2D([0.0, 0.0], _U_AXIS), e_t: Line2D([0.0, 1.0], _U_AXIS),
                       s0: Line2D([t0, 0.0], [0.0, 1.0 / length]), s1: Line2D([t1, 0.0], [0.0, 1.0 / length])}
                uv_mid = (tm, 0.5)
            f = asm.face(S, _sense(S, uv_mid, outward), [[(e_b, True), (s1, True), (e_t, False), (s0, False)]])
            for e, pc in pcs.items():
                asm.pcurve(e, f, pc)
            bots.append(e_b)
            tops.append(e_t)
        bottom_loops.append([(e, False) for e in reversed(bots)])
        top_loops.append([(e, True) for e in tops])
        cap_edges.append((bots, tops))
    fb = asm.face(bottom, True, bottom_loops)
    ft = asm.face(top, True, top_loops)
    for bots, tops in cap_edges:
        for e in bots:
            asm.pcurve(e, fb, _on_plane(bottom, asm.curves[e][0]))
        for e in tops:
            asm.pcurve(e, ft, _on_plane(top, asm.curves[e][0]))
    return asm.build()


# ============================================================================ revolve
class _Meridian:
    """One profile segment seen by the revolution: its kind, 3-D curve at θ = 0 and surface data.

    ``kind``: ``"axis"`` (on the axis: collapses), ``"cylinder"``, ``"plane"``, ``"cone"``,
    ``"sphere"``, ``"torus"`` or ``"nurbs"``.  Analytic non-planar kinds use ``u = θ`` and
    ``v(t) = v0 + dv t`` along the segment's parameter ``t``.
    """

    def __init__(self, seg: Segment, plane: PlanarSurface) -> None:
        self.seg = seg
        self.plane = plane
        self.curve, self.range = seg.to_3d(plane)
        self.kind = ""
        self.surface: Any = None
        self.v0 = 0.0
        self.dv = 1.0
        self.nurbs_surfaces: dict[tuple[float, float], Any] = {}

    def v(self, t: float) -> float:
        return self.v0 + self.dv * t


def _axis_extent(seg: Segment, plane: PlanarSurface, Oa: np.ndarray, W: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Signed distances along ``W`` from the axis line: ``(at the two ends (2,), at interior candidates (k,))``.

    Interior candidates are exact for lines (none) and arcs (the arc's extremes ``s_c ± R``
    where they fall strictly inside its angle range); for splines they are samples
    (``_AXIS_SAMPLES`` per knot span, ends excluded), so a spline is checked, not proven.
    """
    t0, t1 = seg.domain
    ends = plane.evaluate(*seg.evaluate(np.array([t0, t1])).T)
    s_end = (ends - Oa) @ W
    if seg.kind == "line":
        return s_end, np.empty(0)
    X, Y, _ = plane.frame
    if seg.kind == "arc":
        C = plane.evaluate(*seg.points[0])
        beta = math.atan2(float(W @ Y), float(W @ X))
        sc = float((C - Oa) @ W)
        sg = math.copysign(1.0, seg.sweep)
        inner = []
        for phi, val in ((beta, sc + seg.radius), (beta + PI, sc - seg.radius)):
            tt = ((phi - seg.start_angle) * sg) % TWO_PI  # the arc parameter where its angle is phi
            if 0.0 < tt < abs(seg.sweep):
                inner.append(val)
        return s_end, np.array(inner)
    k = np.unique(seg.curve.knots)  # type: ignore[union-attr]
    k = k[(k >= t0) & (k <= t1)]
    f = np.linspace(0.0, 1.0, _AXIS_SAMPLES + 1)[1:]
    tt = (k[:-1, None] + np.diff(k)[:, None] * f).ravel()[:-1]
    return s_end, (plane.evaluate(*seg.evaluate(tt).T) - Oa) @ W


def revolve(profile: Profile, axis_origin, axis_direction, degrees: float = 360.0, *,
            tol: Tolerance | None = None) -> Solid:
    """The solid swept by ``profile`` turning about an axis lying in its plane.

    The angle runs counter-clockwise seen from the tip of ``axis_direction`` (right-hand rule),
    starting at the profile.  The profile may touch the axis along whole segments, which
    collapse (no face; their end vertices become poles; in a partial turn they are the edge
    where the two end caps meet), and at vertices (poles); it must not cross the axis or touch
    it inside a segment.  A full turn gives two half-turn faces per segment off the axis; a
    partial turn one face per segment and two planar end caps (copies of the profile).  Holes
    give void shells (full turn) or inner loops of the caps (partial).  Faces on analytic
    surfaces where possible (module docstring); every run of segments between poles that
    contains a spline, or an arc whose circle would revolve into a spindle torus, is revolved
    as exact NURBS (``nurbs_revolution``), so that the parallels between its faces are the
    same rational arcs.  The axis is snapped into the plane (within ``tol.linear`` and
    ``tol.angular``) and vertices within ``tol.linear`` of it onto it.

    Parameters
    ----------
    profile : Profile
    axis_origin, axis_direction : (3,) array_like
    degrees : float, in ``(0, 360]``
    tol : Tolerance, optional

    Returns
    -------
    Solid
        Volume ``θ · ρ̄ · area`` (Pappus), ``ρ̄`` the distance of the profile's centroid from
        the axis.

    Raises
    ------
    InvalidInputError
        Not a Profile; NaN/inf or zero axis; an axis not in the profile plane (origin farther
        than ``tol.linear``, direction not within ``tol.angular`` of it); ``degrees`` outside
        ``(0, 360]``; a profile crossing the axis (naming the segment), touching it inside a
        segment, or (full turn) touching it at a vertex between two segments off the axis
        (the solid would be pinched there: not a manifold).

    Examples
    --------
    >>> from coons.topology.profile import Profile
    >>> tube = revolve(Profile.rectangle(1, 2, center=(2.5, 0), plane=((0, 0, 0), (0, -1, 0), (1, 0, 0))),
    ...                (0, 0, 0), (0, 0, 1))
    >>> bool(abs(tube.volume - math.pi * (3**2 - 2**2) * 2) < 1e-12), len(tube.faces())
    (True, 8)
    """
    t = resolve(tol)
    p = _profile(profile, "revolve: profile")
    Oa = _vector(axis_origin, "revolve: axis_origin")
    A = _vector(axis_direction, "revolve: axis_direction")
    if not np.any(A):
        raise InvalidInputError("revolve: axis_direction must be non-zero, got (0, 0, 0)")
    A = A / np.linalg.norm(A)
    deg = _number(degrees, "revolve: degrees")
    if not 0.0 < deg <= 360.0:
        raise InvalidInputError(f"revolve: degrees must be in (0, 360], got {degrees!r}")
    N = p.normal
    off = float(p.plane.implicit(Oa))
    if abs(off) > t.linear or abs(float(A @ N)) > t.angular:
        raise InvalidInputError(
            f"revolve: the axis must lie in the profile plane: its origin is {off:.3g} from the plane and its "
            f"direction makes cosine {float(A @ N):.3g} with the normal {N.tolist()}"
        )
    Oa = Oa - off * N
    A = A - (A @ N) * N
    A /= np.linalg.norm(A)
    W = np.cross(A, N)

    # Which side of the axis: every point of the profile on one side (touching allowed).
    extents = [[_axis_extent(s, p.plane, Oa, W) for s in w] for w in p.wires]
    values = np.concatenate([np.concatenate(e) for w in extents for e in w])
    side = 1.0 if values.max() >= -values.min() else -1.0
    for wi, w in enumerate(extents):
        for k, e in enumerate(w):
            worst = float(np.min(side * np.concatenate(e)))
            if worst < -t.linear:
                raise InvalidInputError(
                    f"revolve: the profile crosses the axis: segment {k} of {_wire(wi)} reaches {-worst:.3g} beyond "
                    "it (the profile must lie on one side, touching at most)"
                )
    Xr = side * W
    Yr = np.cross(A, Xr)
    flipped = float(Yr @ N) < 0.0
    if flipped:
        p = p.flipped()
    full = deg >= 360.0
    theta = [0.0, PI] if full else [0.0, math.radians(deg)]
    spans = [(0, 1, 0.0, PI), (1, 0, PI, TWO_PI)] if full else [(0, 1, 0.0, theta[1])]
    rot = [np.eye(4), rotation(Oa, A, 180.0 if full else deg)]
    return _revolve(p, Oa, A, Xr, Yr, full, theta, spans, rot, flipped, t)


def _wire(wi: int) -> str:
    return "the outer wire" if wi == 0 else f"hole {wi - 1}"


def _classify(m: _Meridian, Oa: np.ndarray, A: np.ndarray, Xr: np.ndarray, t: Tolerance, where: str,
              s_ends: np.ndarray, s_inner: np.ndarray) -> None:
    """Set the meridian's kind and analytic surface (or ``"nurbs"``)."""
    seg = m.seg
    rho = lambda P: float((P - Oa) @ Xr)  # noqa: E731
    z = lambda P: float((P - Oa) @ A)  # noqa: E731
    t0, t1 = m.range
    P0, P1 = m.curve.evaluate(np.array([t0, t1]))
    if seg.kind == "line":
        if np.all(np.abs(s_ends) <= t.linear):
            m.kind = "axis"
            return
        D = m.curve.direction
        r0, z0 = rho(P0), z(P0)
        if abs(rho(P1) - r0) <= t.linear:
            m.kind, m.surface, m.v0, m.dv = "cylinder", CylindricalSurface(Oa, A, Xr, r0), z0, float(D @ A)
        elif abs(z(P1) - z0) <= t.linear:
            m.kind = "plane"
            m.surface = PlanarSurface(Oa + z0 * A, math.copysign(1.0, float(D @ Xr)) * A, Xr)
        else:
            dr, dz = float(D @ Xr), float(D @ A)
            sg = math.copysign(1.0, dz)
            m.kind = "cone"
            m.surface = ConicalSurface(Oa + z0 * A, A, Xr, max(r0, 0.0), math.atan2(sg * dr, sg * dz))
            m.v0, m.dv = 0.0, sg
        return
    if s_inner.size and float(s_inner.min()) <= t.linear:
        raise InvalidInputError(
            f"revolve: {where} touches the axis at an interior point (distance {max(float(s_inner.min()), 0.0):.3g}); "
            "split the segment there so that the touching point is a vertex"
        )
    if seg.kind == "arc":
        c = m.curve.center
        rc, zc, r = rho(c), z(c), m.curve.radius
        C = Oa + zc * A
        R0 = P0 - c
        psi0 = math.atan2(float(R0 @ A), float(R0 @ Xr))
        d0 = _tangent(m.curve, t0)
        dpsi = math.copysign(1.0, float(d0 @ (-math.sin(psi0) * Xr + math.cos(psi0) * A)))
        if abs(rc) <= t.linear:
            m.kind, m.surface = "sphere", SphericalSurface(C, A, Xr, r)
        elif rc - r > t.linear:
            m.kind, m.surface = "torus", ToroidalSurface(C, A, Xr, rc, r)
        else:
            m.kind = "nurbs"
            return
        m.v0, m.dv = psi0 - dpsi * t0, dpsi
        return
    m.kind = "nurbs"


def _revolve(p: Profile, Oa, A, Xr, Yr, full: bool, theta, spans, rot, flipped: bool, t: Tolerance) -> Solid:
    asm = _Assembly(t)
    plane = p.plane
    cap_loops: list[list[list[tuple[int, bool]]]] = [[], []]
    cap_edges: list[list[int]] = [[], []]
    for wi, wire in enumerate(p.wires):
        n = len(wire)
        # Segment k of a flipped profile is segment n - 1 - k of the caller's profile.
        name = lambda k: f"segment {(n - 1 - k) % n if flipped else k % n} of {_wire(wi)}"  # noqa: E731
        ms = [_Meridian(s, plane) for s in wire]
        pole = []
        for k, m in enumerate(ms):
            s_ends, s_inner = _axis_extent(m.seg, plane, Oa, Xr)
            pole.append(abs(float(s_ends[0])) <= t.linear)
            _classify(m, Oa, A, Xr, t, name(k), s_ends, s_inner)
        for k, m in enumerate(ms):
            if m.kind == "axis":
                pole[k] = pole[(k + 1) % n] = True
        # A run of segments joined at off-axis vertices shares its parallels: NURBS spreads over it.
        changed = True
        while changed:
            changed = False
            for k in range(n):
                a, b = ms[k - 1], ms[k]
                if not pole[k] and (a.kind == "nurbs") != (b.kind == "nurbs"):
                    for m in (a, b):
                        m.kind = "nurbs"
                    changed = True
        if full:
            for k in range(n):
                if pole[k] and ms[k - 1].kind != "axis" and ms[k].kind != "axis":
                    a, b = sorted((name(k - 1), name(k)))
                    raise InvalidInputError(
                        f"revolve: the profile touches the axis at the vertex where {a} and {b} "
                        f"meet ({ms[k].curve.evaluate(ms[k].range[0]).tolist()}) without running along it: a full "
                        "turn would pinch the solid to a point there (not a manifold); revolve less than 360 degrees "
                        "or give the profile a segment along the axis"
                    )
        for m in ms:
            if m.kind == "nurbs":
                m.curve = m.seg.to_nurbs(plane, t)
                m.range = m.curve.domain
        # Vertices: one per pole, one per boundary angle elsewhere.
        V: list[list[int]] = []
        for k in range(n):
            P = ms[k].curve.evaluate(ms[k].range[0])
            used = not full or ms[k - 1].kind != "axis" or ms[k].kind != "axis"
            if pole[k]:
                Pk = Oa + float((P - Oa) @ A) * A
                v = asm.vertex(Pk) if used else -1
                V.append([v] * len(theta))
            else:
                V.append([asm.vertex(R[:3, :3] @ P + R[:3, 3]) for R in rot])
        # NURBS surfaces per span.
        for m in ms:
            if m.kind == "nurbs":
                for (_, _, a, b) in spans:
                    m.nurbs_surfaces[(a, b)] = conics.nurbs_revolution(m.curve, Oa, A, a, b, tol=t)
        # Meridian edges per boundary angle; axis edges (partial turns only).
        mer: list[list[int]] = []
        for k, m in enumerate(ms):
            if m.kind == "axis":
                if full:
                    mer.append([-1] * len(theta))
                else:
                    P, Q = asm.points[V[k][0]], asm.points[V[(k + 1) % n][0]]
                    e = asm.edge(V[k][0], V[(k + 1) % n][0], Line(P, Q - P), (0.0, float(np.linalg.norm(Q - P))))
                    mer.append([e] * len(theta))
                continue
            row = []
            for j, R in enumerate(rot):
                c = m.curve if j == 0 else m.curve.transformed(R)
                row.append(asm.edge(V[k][j], V[(k + 1) % n][j], c, m.range))
            mer.append(row)
        # Parallels per off-axis vertex and span.
        par: list[dict[int, int]] = []
        for k in range(n):
            row: dict[int, int] = {}
            if not pole[k]:
                P = ms[k].curve.evaluate(ms[k].range[0])
                for si, (ja, jb, a, b) in enumerate(spans):
                    if ms[k].kind == "nurbs":
                        c = ms[k].nurbs_surfaces[(a, b)].iso_curve("v", ms[k].range[0])
                    else:
                        c = Circle(Oa + float((P - Oa) @ A) * A, A, Xr, float((P - Oa) @ Xr))
                    row[si] = asm.edge(V[k][ja], V[k][jb], c, (a, b))
            par.append(row)
        # Side faces.
        for k, m in enumerate(ms):
            if m.kind == "axis":
                continue
            t0, t1 = m.range
            tm = 0.5 * (t0 + t1)
            for si, (ja, jb, a, b) in enumerate(spans):
                loop = [(mer[k][ja], True)]
                if not pole[(k + 1) % n]:
                    loop.append((par[(k + 1) % n][si], True))
                loop.append((mer[k][jb], False))
                if not pole[k]:
                    loop.append((par[k][si], False))
                S = m.nurbs_surfaces[(a, b)] if m.kind == "nurbs" else m.surface
                Ra = rot[ja]
                Pm = Ra[:3, :3] @ m.curve.evaluate(tm) + Ra[:3, 3]
                outward = Ra[:3, :3] @ np.cross(_tangent(m.curve, tm), Yr)
                if m.kind == "nurbs":
                    uv = (a, tm)
                elif m.kind == "plane":
                    uv = tuple(S.closest_parameters(Pm))
                else:
                    uv = (a, m.v(tm))
                f = asm.face(S, _sense(S, uv, outward), [loop])
                pcs: dict[int, Any] = {}
                if m.kind == "plane":
                    for e, _ in loop:
                        pcs[e] = _on_plane(S, asm.curves[e][0])
                elif m.kind == "nurbs":
                    pcs[mer[k][ja]] = Line2D([a, 0.0], _V_AXIS)
                    pcs[mer[k][jb]] = Line2D([b, 0.0], _V_AXIS)
                    if not pole[k]:
                        pcs[par[k][si]] = Line2D([0.0, t0], _U_AXIS)
                    if not pole[(k + 1) % n]:
                        pcs[par[(k + 1) % n][si]] = Line2D([0.0, t1], _U_AXIS)
                else:
                    pcs[mer[k][ja]] = Line2D([a, m.v0], [0.0, m.dv])
                    pcs[mer[k][jb]] = Line2D([b, m.v0], [0.0, m.dv])
                    if not pole[k]:
                        pcs[par[k][si]] = Line2D([0.0, m.v(t0)], _U_AXIS)
                    if not pole[(k + 1) % n]:
                        pcs[par[(k + 1) % n][si]] = Line2D([0.0, m.v(t1)], _U_AXIS)
                for e, pc in pcs.items():
                    asm.pcurve(e, f, pc)
        if not full:
            cap_loops[0].append([(mer[k][0], False) for k in reversed(range(n))])
            cap_loops[1].append([(mer[k][1], True) for k in range(n)])
            cap_edges[0] += [mer[k][0] for k in range(n)]
            cap_edges[1] += [mer[k][1] for k in range(n)]
    if not full:
        Ra = rot[1][:3, :3]
        caps = [PlanarSurface(Oa, -Yr, Xr), PlanarSurface(Oa, Ra @ Yr, Ra @ Xr)]
        for j in (0, 1):
            f = asm.face(caps[j], True, cap_loops[j])
            for e in cap_edges[j]:
                asm.pcurve(e, f, _on_plane(caps[j], asm.curves[e][0]))
    return asm.build()


# ============================================================================ loft
def _closed_nurbs(wire: Sequence[Segment], plane: PlanarSurface, t: Tolerance) -> tuple[NurbsCurve, np.ndarray]:
    """One closed 3-D NURBS through the wire's segments, on ``[0, 1]`` by arc-length fractions,
    and the parameters of the joints ``(n + 1,)`` (0 and 1 included).

    Each segment's exact NURBS is clamped, raised to the common degree (The NURBS Book A5.9) and
    mapped onto its share of ``[0, 1]`` (its length over the wire's); joints become knots of
    multiplicity ``p`` (C0), and each segment's weights are scaled (which leaves a rational
    curve unchanged) so that it starts with the weight its predecessor ends with.
    """
    from coons.kernel import refine

    cs = [s.to_nurbs(plane, t) for s in wire]
    p = max(c.degree for c in cs)
    cs = [refine.curve_elevate_degree(refine.curve_clamped(c), p - c.degree) for c in cs]
    lengths = np.array([c.length() for c in cs])
    cuts = np.concatenate([[0.0], np.cumsum(lengths) / lengths.sum()])
    cuts[-1] = 1.0
    P, W, U = [], [], [np.zeros(p + 1)]
    prev = 1.0
    for k, c in enumerate(cs):
        a, b = c.domain
        knots = cuts[k] + (c.knots - a) / (b - a) * (cuts[k + 1] - cuts[k])
        w = c.weights * (prev / c.weights[0])
        first = 0 if k == 0 else 1  # the joint's control point is the previous segment's last
        P.append(c.control_points[first:])
        W.append(w[first:])
        U.append(knots[p + 1 : knots.size - (p + 1)])
        U.append(np.full(p, cuts[k + 1]) if k < len(cs) - 1 else np.ones(p + 1))
        prev = float(w[-1])
    return NurbsCurve(np.concatenate(P), np.concatenate(U), p, np.concatenate(W)), cuts


def _section_parameters(grid: np.ndarray, t: Tolerance) -> np.ndarray:
    """Section parameters ``(K,)`` in ``[0, 1]``: chord lengths across the sections of every column
    of control points ``grid (K, n, 3)``, averaged (The NURBS Book eq. 10.8 / A9.3)."""
    d = np.linalg.norm(np.diff(grid, axis=0), axis=2)  # (K - 1, n)
    step = d.max(axis=1)
    if np.any(step <= t.linear):
        k = int(np.flatnonzero(step <= t.linear)[0])
        raise InvalidInputError(f"loft: sections {k} and {k + 1} coincide (within tol.linear = {t.linear:g})")
    live = d.sum(axis=0) > t.linear
    cum = np.concatenate([np.zeros((1, int(live.sum()))), np.cumsum(d[:, live], axis=0)]) / d[:, live].sum(axis=0)
    v = cum.mean(axis=1)
    v[0], v[-1] = 0.0, 1.0
    return v


def loft(profiles: Sequence[Profile], ruled: bool = False, *, tol: Tolerance | None = None) -> Solid:
    """The solid skinned through two or more profiles (outer wires only).

    Each section's outer wire becomes one closed NURBS (segments at their arc-length share of
    ``[0, 1]``, starting at the wire's first vertex) split at ``0.5`` into two halves; the
    halves are made compatible across the sections
    (:func:`coons.kernel.construct.make_compatible`) and skinned
    (:func:`coons.kernel.construct.loft`, degree ``min(3, K - 1)`` across ``K`` sections, or
    degree 1 when ``ruled``: :func:`~coons.kernel.construct.ruled_surface` for two sections)
    with one set of section parameters (chord length averaged over both halves), so the two
    side faces share their rails exactly.  The first and last sections are planar caps with
    NURBS p-curves.  F 4 (two side faces, two caps); the caps' edges are the half curves cut
    at every joint of the section's segments, so a corner is a vertex and never lies inside an
    edge (two circles: V 4, E 6; two squares: V 8, E 10).  Sections correspond by their first
    vertices and by arc length: start them at matching points to avoid a twist.

    Parameters
    ----------
    profiles : sequence of K >= 2 Profile
        Consecutive sections must be oriented alike (``normal_k · normal_{k+1} > 0``); the loft
        runs from the first to the last (either way along the normals).
    ruled : bool
    tol : Tolerance, optional

    Returns
    -------
    Solid

    Raises
    ------
    InvalidInputError
        Fewer than two sections, items that are not Profiles, sections with holes, sections
        with opposite orientations, a second section in the plane of the first, rational
        sections whose end weights would make the two halves' rails differ, and the errors of
        :func:`coons.kernel.construct.loft`.

    Examples
    --------
    >>> from coons.topology.profile import Profile
    >>> c = loft([Profile.circle(1.0), Profile.circle(1.0, plane=((0, 0, 2), (0, 0, 1)))])
    >>> bool(abs(c.volume - 2 * math.pi) < 1e-10), len(c.faces())
    (True, 4)
    """
    t = resolve(tol)
    if isinstance(profiles, Profile) or not isinstance(profiles, Sequence) or len(profiles) < 2:
        n = 1 if isinstance(profiles, Profile) else (len(profiles) if isinstance(profiles, Sequence) else 0)
        raise InvalidInputError(f"loft needs a sequence of at least 2 profiles, got {n}")
    ps = [_profile(q, f"loft: section {k}") for k, q in enumerate(profiles)]
    for k, q in enumerate(ps):
        if q.holes:
            raise InvalidInputError(f"loft: section {k} has {len(q.holes)} hole(s); loft uses outer wires only")
    for k in range(len(ps) - 1):
        if not float(ps[k].normal @ ps[k + 1].normal) > 0.0:
            raise InvalidInputError(
                f"loft: sections {k} and {k + 1} have opposite orientations (normals {ps[k].normal.tolist()} and "
                f"{ps[k + 1].normal.tolist()}); give every section the same orientation"
            )
    h = float((ps[1].centroid - ps[0].centroid) @ ps[0].normal)
    if not abs(h) > t.linear:
        raise InvalidInputError(
            f"loft: section 1 does not advance from section 0 along its normal (height {h:.3g}); sections must be "
            "stacked, not side by side in one plane"
        )
    if h < 0.0:
        ps = [q.flipped() for q in ps]
    K = len(ps)
    closed = [_closed_nurbs(q.outer, q.plane, t) for q in ps]
    halves = [c.split(0.5, t) for c, _ in closed]
    A = construct.make_compatible([hv[0] for hv in halves], tol=t)
    B = construct.make_compatible([hv[1] for hv in halves], tol=t)
    ratio = np.array([b.weights[-1] / a.weights[0] for a, b in zip(A, B)])
    if float(np.ptp(ratio)) > t.solver * float(np.max(ratio)):
        raise InvalidInputError(
            "loft: the sections' closed curves have end weights that differ by different factors "
            f"({ratio.tolist()}); rational splines must start and end with equal weight ratios"
        )
    v = _section_parameters(np.concatenate([np.stack([c.control_points for c in A]),
                                            np.stack([c.control_points for c in B])], axis=1), t)
    degree_v = 1 if ruled else min(3, K - 1)
    if ruled and K == 2:
        SA, SB = construct.ruled_surface(A[0], A[1], tol=t), construct.ruled_surface(B[0], B[1], tol=t)
    else:
        SA = construct.loft(A, degree_v, params=v, tol=t)
        SB = construct.loft(B, degree_v, params=v, tol=t)
        v0, v1 = SA.domain_v
        if (v0, v1) != (0.0, 1.0):  # pragma: no cover - construct.loft returns [0, 1]
            raise TopologyError(f"internal: loft v-domain {(v0, v1)}")

    asm = _Assembly(t)
    caps = [PlanarSurface(ps[0].plane.origin, -ps[0].normal, ps[0].plane.frame[0]),
            PlanarSurface(ps[-1].plane.origin, ps[-1].normal, ps[-1].plane.frame[0])]
    # Section edges: the half curves cut at the joints of the section's segments (a kink is a
    # vertex, never inside an edge); half A runs over 2c, half B over 2c - 1 of the closed parameter c.
    ends = []
    for sec, (ca, cb) in ((0, (A[0], B[0])), (K - 1, (A[-1], B[-1]))):
        cuts = closed[sec][1]
        inner = cuts[(cuts > 0.0) & (cuts < 1.0)]
        # Joints closer than round-off to the split point are the split point.
        ta = [0.0] + [2.0 * c for c in inner if 2.0 * c < 1.0 - t.solver] + [1.0]
        tb = [0.0] + [2.0 * c - 1.0 for c in inner if 2.0 * c - 1.0 > t.solver] + [1.0]
        va = [asm.vertex(ca.evaluate(x)) for x in ta[:-1]]
        vb = [asm.vertex(cb.evaluate(x)) for x in tb[:-1]]
        ring = va + vb  # start vertex first, the split vertex at len(va)
        ea = [asm.edge(ring[i], ring[i + 1], ca, (ta[i], ta[i + 1])) for i in range(len(va))]
        eb = [asm.edge(ring[len(va) + i], ring[(len(va) + i + 1) % len(ring)], cb, (tb[i], tb[i + 1]))
              for i in range(len(vb))]
        ends.append((ring[0], ring[len(va)], ea, eb))
    (s0, m0, ea0, eb0), (s1, m1, ea1, eb1) = ends
    rail_s = asm.edge(s0, s1, SA.iso_curve("u", 0.0), (0.0, 1.0))
    rail_m = asm.edge(m0, m1, SA.iso_curve("u", 1.0), (0.0, 1.0))
    for S, e0, e1, r_start, r_end in ((SA, ea0, ea1, rail_s, rail_m), (SB, eb0, eb1, rail_m, rail_s)):
        c0, (u0, u1) = asm.curves[e0[0]]
        um = 0.5 * (u0 + u1)
        outward = np.cross(_tangent(c0, um), ps[0].normal)
        loop = [(e, True) for e in e0] + [(r_end, True)] + [(e, False) for e in reversed(e1)] + [(r_start, False)]
        f = asm.face(S, _sense(S, (um, 0.0), outward), [loop])
        for e in e0:
            asm.pcurve(e, f, Line2D([0.0, 0.0], _U_AXIS))
        for e in e1:
            asm.pcurve(e, f, Line2D([0.0, 1.0], _U_AXIS))
        asm.pcurve(r_start, f, Line2D([0.0, 0.0], _V_AXIS))
        asm.pcurve(r_end, f, Line2D([1.0, 0.0], _V_AXIS))
    f0 = asm.face(caps[0], True, [[(e, False) for e in reversed(ea0 + eb0)]])
    f1 = asm.face(caps[1], True, [[(e, True) for e in ea1 + eb1]])
    for f, cap, es in ((f0, caps[0], ea0 + eb0), (f1, caps[1], ea1 + eb1)):
        for e in es:
            asm.pcurve(e, f, _on_plane(cap, asm.curves[e][0]))
    return asm.build()
