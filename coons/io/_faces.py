"""Neutral B-rep faces from other systems -> coons face specifications -> a checked coons solid.

Importers (:mod:`coons.io.step.reader`, :mod:`coons.io.from_ocp`) describe each face of a foreign
B-rep the way the foreign system stores it — a surface, a sense, loops of oriented edges whose
3-D curves are bounded by vertex parameters, possibly with seam edges, degenerate edges at poles
and vertex loops — as :class:`RawFace` records.  :func:`faces_to_solid` normalises them to the
coons B-rep rules of ``docs/brep.md`` and sews them:

1. **degenerate edges** (a curve collapsed to a point: sphere poles, cone apices) and vertex
   loops are dropped; the loop then passes through the pole vertex with a parameter gap, which
   the checker accepts;
2. **outer loop first**: when the foreign face does not say which loop is outer, it is the loop
   whose signed area in the parameter plane (oriented by the face sense) is positive and largest;
3. **p-curves** are computed with :func:`coons.kernel.onsurface.cheap_pcurves_many` (the edges of
   all faces at once through the verified cheap exact paths, the rest through ``pcurve_on``: exact ``Line2D`` /
   ``Trig2D`` for the iso-curves of analytic surfaces, fitted 2-D NURBS otherwise; the foreign
   system's own p-curves are not used), placed on the branch of the face's periodic parameters
   found from the face's boundary (the face occupies an arc of the period; the largest gap in the
   boundary's angles is where the branch is cut; when a boundary through poles leaves two
   branches, the one where the loop turns the right way); planar faces carry no p-curves (their
   mass properties project the 3-D curves);
4. faces with a **seam** (an edge used twice by one face, on an iso-line of a periodic direction
   of an analytic surface, or of a closed direction of a NURBS surface — a revolved or swept
   closed profile, whose "period" is its domain, :func:`coons.kernel.onsurface.surface_periods`)
   are unwrapped — each use of the seam on its side of the parameter box, by the direction it is
   walked — and split with :func:`coons.topology.split.split_face` along the iso-line half a
   period away (cylinders and cones in two, tori in four; a NURBS at the middle of its domain,
   along its exact iso-curve); a sphere given as one face without edges (OCCT's vertex-loop
   sphere) becomes two hemispheres; a **band without a seam** (a cylinder face bounded by its two
   circles only, as some writers leave it; a closed NURBS between two closed curves) gets one
   (:func:`_insert_seam`: the iso-line through a vertex of one loop, or a closed NURBS's domain
   start, to where it crosses the other) and is then split like the rest;
5. **imprint**: edges that splitting cut in two are cut at the same points in the neighbouring
   faces (uses of one curve object are split where other uses of it end);
6. :func:`coons.topology.sew.sew_faces` recovers the shared vertices and edges and checks.

Not handled (a :class:`~coons.errors.TopologyError` naming the face): a seamless face covering
a whole period other than a band of two winding loops (e.g. a torus face without edges).

The module does not heal: a face whose boundary is not closed, whose curves are farther from
its surface than the file's precision, or that sewing rejects raises a typed error naming the
face.  It never imports OCP.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from coons.errors import CoonsError, InvalidGeometryError, TopologyError
from coons.kernel.analytic import SCALAR_CURVES, PlanarSurface, scalar_parameter, scalar_point
from coons.kernel.curve import NurbsCurve
from coons.kernel.surface import NurbsSurface
from coons.tolerance import Tolerance, resolve
from coons.topology.sew import EdgeSpec, FaceSpec, sew_faces

__all__ = ["RawEdge", "RawCoedge", "RawFace", "edge_parameters", "face_specs_from_raw", "faces_to_solid"]

#: Samples per edge for the face's parameter branch and the loop areas (angles between samples of a
#: full circle stay below π/8, far below the half period that unwrapping needs).
_SAMPLES = 17


@dataclass(eq=False)
class RawEdge:
    """An edge of a foreign B-rep: its 3-D curve between the parameters of its two vertices.

    ``t0`` is the parameter of ``start`` and ``t1`` that of ``end``; ``t1 < t0`` when the edge runs
    against its curve.  ``tol`` is the deviation already present (vertex-to-curve distance).
    """

    curve: Any
    t0: float
    t1: float
    start: np.ndarray
    end: np.ndarray
    tol: float = 0.0
    name: str = "edge"

    @property
    def degenerate(self) -> bool:
        """The curve collapsed to a point (ends and midpoint within the edge tolerance)."""
        cached = self.__dict__.get("_degenerate")
        if cached is None:  # asked by both faces of the edge: computed once
            cached = self.__dict__["_degenerate"] = False if self.curve is None else self._collapsed()
        return cached

    def _collapsed(self) -> bool:
        P = np.asarray(self.curve.evaluate(np.array([self.t0, 0.5 * (self.t0 + self.t1), self.t1])), dtype=np.float64)
        return bool(_collapsed_rows(P[None], np.array([self.tol]))[0])


def _collapsed_rows(P: np.ndarray, tol: np.ndarray) -> np.ndarray:
    """``(k,)`` bool: edges whose start, midpoint and end ``P (k, 3, 3)`` lie within twice their
    tolerance ``tol (k,)`` of the start (the two ends may deviate in opposite directions), or within
    the round-off of the coordinates for an edge declared exact."""
    roundoff = 1e-12 * (1.0 + np.abs(P).max(axis=(1, 2)))
    return np.linalg.norm(P - P[:, :1], axis=-1).max(axis=1) <= 2.0 * np.maximum(tol, roundoff)


def _mark_degenerate(faces: list) -> None:
    """Decide :attr:`RawEdge.degenerate` for the line and circle edges of ``faces`` in one batch
    (their points in one :func:`~coons.kernel.onsurface.evaluate_curves` call); other edges are
    decided when first asked."""
    from coons.kernel.onsurface import BATCHED_CURVES, evaluate_curves

    todo = {id(c.edge): c.edge for f in faces for loop in f.loops for c in loop
            if type(c.edge.curve) in BATCHED_CURVES and "_degenerate" not in c.edge.__dict__}
    edges = list(todo.values())
    if not edges:
        return
    T = np.array([(e.t0, 0.5 * (e.t0 + e.t1), e.t1) for e in edges], dtype=np.float64)
    if not np.isfinite(T).all():
        return  # each edge reports its own bad range when asked
    flags = _collapsed_rows(evaluate_curves([e.curve for e in edges], T), np.array([e.tol for e in edges], dtype=np.float64))
    for e, flag in zip(edges, flags.tolist()):
        e.__dict__["_degenerate"] = flag


@dataclass(eq=False)
class RawCoedge:
    """A use of an edge by a face loop, ``forward`` when it runs from the edge's start to its end."""

    edge: RawEdge
    forward: bool
    pcurve: Any = None

    def reversed(self) -> "RawCoedge":
        return RawCoedge(self.edge, not self.forward, self.pcurve)

    @property
    def t_range(self) -> tuple[float, float]:
        """The curve parameters where this use starts and ends."""
        return (self.edge.t0, self.edge.t1) if self.forward else (self.edge.t1, self.edge.t0)


@dataclass(eq=False)
class RawFace:
    """A face of a foreign B-rep.

    Attributes
    ----------
    surface : coons surface
    sense : bool
        The face's outward normal is ``Su × Sv``.
    loops : list of list of RawCoedge
        Each loop with the face on its left seen from the outward normal.
    outer : int or None
        Index of the outer loop when the source says (STEP ``FACE_OUTER_BOUND``), else None.
    poles : list of (3,) arrays
        Vertex loops (points where the surface collapses).
    name : str
        For messages (e.g. ``'#14 ADVANCED_FACE (line 20)'``).
    """

    surface: Any
    sense: bool
    loops: list
    outer: int | None = None
    poles: list = field(default_factory=list)
    name: str = "face"

    def reversed(self) -> "RawFace":
        loops = [[c.reversed() for c in loop[::-1]] for loop in self.loops]
        return RawFace(self.surface, not self.sense, loops, self.outer, list(self.poles), self.name)


# ---------------------------------------------------------------------- edge parameters
def _project_on_curve(curve: Any, points: np.ndarray, t: Tolerance) -> np.ndarray:
    if isinstance(curve, NurbsCurve):
        from coons.kernel.projection import curve_closest_parameters
        return np.asarray(curve_closest_parameters(curve, points, t), dtype=np.float64)
    return np.asarray(curve.closest_parameters(points), dtype=np.float64)


def edge_parameters(curve: Any, start, end, same_sense: bool, tol: Tolerance | None = None) -> tuple[float, float, float]:
    """Curve parameters of an edge's start and end vertices, and their distance from the curve.

    The vertices are projected on the curve (closed form for analytic curves, Newton for NURBS).
    On a periodic curve the end parameter is moved by whole periods so that the edge runs along
    (``same_sense``) or against the curve by less than one period, or exactly one period for a
    closed edge (start = end); on a closed NURBS curve a closed edge spans the whole domain.

    Returns
    -------
    t_start, t_end : float
    deviation : float
        The larger distance of a vertex from the curve point at its parameter.

    Raises
    ------
    InvalidGeometryError
        The edge runs the wrong way along a non-periodic curve, or has zero length.
    """
    t = resolve(tol)
    scalar = type(curve) in SCALAR_CURVES  # lines and circles (most edges): Python floats, no numpy calls
    if scalar:
        P = [np.asarray(start, dtype=np.float64).tolist(), np.asarray(end, dtype=np.float64).tolist()]
        ta, tb = scalar_parameter(curve, P[0]), scalar_parameter(curve, P[1])
        closed_edge = math.dist(P[0], P[1]) <= t.linear
    else:
        P = np.stack([np.asarray(start, dtype=np.float64), np.asarray(end, dtype=np.float64)])
        ta, tb = (float(x) for x in _project_on_curve(curve, P, t))
        closed_edge = float(np.linalg.norm(P[0] - P[1])) <= t.linear
    period = getattr(curve, "period", None) if getattr(curve, "periodic", False) else None
    if period is not None:
        d = (tb - ta) % period if same_sense else (ta - tb) % period
        if closed_edge or d == 0.0:
            d = period
        tb = ta + d if same_sense else ta - d
    elif closed_edge and isinstance(curve, NurbsCurve):
        d0, d1 = curve.domain
        ends = np.asarray(curve.evaluate(np.array([d0, d1])))
        if float(np.linalg.norm(ends[0] - ends[1])) > t.linear + float(np.linalg.norm(P[0] - ends[0])):
            raise InvalidGeometryError(f"a closed edge (start = end) on an open NURBS curve (ends {ends.tolist()})")
        ta, tb = (d0, d1) if same_sense else (d1, d0)
    if ta == tb or (tb > ta) != bool(same_sense):
        raise InvalidGeometryError(
            f"edge vertices project to curve parameters {ta:.9g} -> {tb:.9g}, expected "
            f"{'increasing' if same_sense else 'decreasing'} parameters (same_sense={same_sense})"
        )
    if scalar:
        return ta, tb, max(math.dist(P[0], scalar_point(curve, ta)), math.dist(P[1], scalar_point(curve, tb)))
    Q = np.asarray(curve.evaluate(np.array([ta, tb])))
    dev = float(np.max(np.linalg.norm(Q - P, axis=-1)))
    return ta, tb, dev


# ---------------------------------------------------------------------- faces
def _periods(surface: Any, t: Tolerance) -> tuple[float | None, float | None]:
    """Periods of the surface's parameters; a closed NURBS direction has its domain length as period.

    (:func:`coons.kernel.onsurface.surface_periods`: a NURBS whose boundary curves ``u = u0`` and
    ``u = u1`` coincide, e.g. a revolved or extruded closed profile, is closed in ``u``.)
    """
    from coons.kernel.onsurface import surface_periods

    return surface_periods(surface, t)


def _period_start(surface: Any, k: int) -> float:
    """Where parameter ``k``'s period is counted from: the domain start of a NURBS, 0 for analytic surfaces."""
    if isinstance(surface, NurbsSurface):
        return float(surface.domain[k][0])
    return 0.0


def _face_box(face: RawFace, loops: list, t: Tolerance, fixed: dict | None = None):
    """The face's parameter box ``((u0, u1), (v0, v1))``; infinite in non-periodic directions.

    In a periodic direction with a seam the box starts at the seam (``fixed[k]``); otherwise the
    boundary's sampled angles occupy part of the circle and the branch is cut in the middle of
    the largest gap.  Seam uses are left out of the sampling.

    Raises
    ------
    TopologyError
        The boundary covers the whole period without a seam (a seamless full-period face).
    """
    from coons.kernel.onsurface import project_on_surface, singular_parameters

    if isinstance(face.surface, NurbsSurface):
        # A NURBS is never evaluated outside its domain: pcurve_on unwraps a closed one towards its
        # domain when the box says nothing, and an open one needs no box.
        return ((-math.inf, math.inf), (-math.inf, math.inf))
    fixed = fixed or {}
    periods = _periods(face.surface, t)
    if all(per is None or k in fixed for k, per in enumerate(periods)):
        # nothing to choose (a plane, or every period fixed by a seam): no samples needed
        return tuple((fixed[k], fixed[k] + per) if per is not None else (-math.inf, math.inf)
                     for k, per in enumerate(periods))
    X = _coedge_samples([c for loop in loops for c in loop], _SAMPLES).reshape(-1, 3)
    uv = project_on_surface(face.surface, X, t)
    free = singular_parameters(face.surface, uv, None, t)
    box = []
    for k, per in enumerate(periods):
        col = uv[~free[:, k], k]
        if per is None:
            box.append((-math.inf, math.inf))
            continue
        if k in fixed:
            box.append((fixed[k], fixed[k] + per))
            continue
        if col.size == 0:
            box.append((0.0, per))
            continue
        a = np.sort(np.mod(col, per))
        gaps = np.diff(np.concatenate([a, [a[0] + per]]))
        g = int(np.argmax(gaps))
        # adjacent samples of one edge are < period / 16 apart: a largest gap below that means full coverage
        if gaps[g] <= per / (_SAMPLES - 1) * 1.01:
            raise _FullPeriod(
                f"{face.name}: its boundary covers the whole period of the surface's "
                f"{'uv'[k]} parameter without a seam edge", k
            )
        lo = float(a[(g + 1) % a.size])
        box.append((lo, lo + per - float(gaps[g])))
    return box[0], box[1]


class _FullPeriod(TopologyError):
    """A face whose boundary covers the whole period of parameter ``k`` without a seam edge."""

    def __init__(self, message: str, k: int) -> None:
        super().__init__(message)
        self.k = k


def _winding_loops(face: RawFace, loops: list, k: int, per: float, t: Tolerance) -> tuple[list[int], list]:
    """Indices of the loops winding once around the period of parameter ``k``, and every loop's
    parameter-``k`` samples per coedge (``_SAMPLES`` each)."""
    from coons.kernel.onsurface import project_on_surface

    winding, samples = [], []
    for i, loop in enumerate(loops):
        X = [np.asarray(c.edge.curve.evaluate(np.linspace(*c.t_range, _SAMPLES))) for c in loop]
        uv = [project_on_surface(face.surface, x, t)[:, k] for x in X]
        steps = np.diff(np.concatenate(uv))
        if abs(float(np.sum(np.remainder(steps + 0.5 * per, per) - 0.5 * per))) > 0.5 * per:
            winding.append(i)
        samples.append(uv)
    return winding, samples


def _cut_loop(face: RawFace, loop: list, samples: list, k: int, a: float, per: float, t: Tolerance) -> tuple[list, np.ndarray]:
    """The winding ``loop`` rotated to start where it crosses the iso-line ``k = a`` (the crossing
    coedge cut there, its own edge object: the imprint step cuts the neighbour's use), and that point.

    The crossing is where the wrapped offset ``k - a`` changes sign between samples (not at the
    wrap-around jump of ±per/2), refined by bisection on the coedge's curve parameter.
    """
    from coons.kernel.onsurface import project_on_surface

    S = face.surface
    for j, (c, u) in enumerate(zip(loop, samples)):
        d = np.remainder(u - a + 0.5 * per, per) - 0.5 * per
        if abs(d[0]) <= 1e-12 * per:  # a vertex on the line (round-off of the projection)
            P = np.asarray(c.edge.curve.evaluate(np.array([c.t_range[0]])))[0]
            return loop[j:] + loop[:j], P
        cross = np.nonzero((np.sign(d[:-1]) != np.sign(d[1:])) & (np.abs(d[:-1] - d[1:]) < 0.5 * per))[0]
        if not cross.size:
            continue
        ts = np.linspace(*c.t_range, _SAMPLES)
        lo, hi, dlo = float(ts[cross[0]]), float(ts[cross[0] + 1]), float(d[cross[0]])
        for _ in range(60):  # bisection to round-off of the curve parameter (2^-60 of a sample step)
            mid = 0.5 * (lo + hi)
            um = project_on_surface(S, np.asarray(c.edge.curve.evaluate(np.array([mid]))), t)[0, k]
            dm = math.remainder(float(um) - a, per)
            if (dm < 0.0) == (dlo < 0.0):
                lo, dlo = mid, dm
            else:
                hi = mid
        tc = 0.5 * (lo + hi)
        s0, s1 = c.t_range
        E = np.asarray(c.edge.curve.evaluate(np.array([s0, tc, s1])))
        # a crossing within the tolerance of a vertex is that vertex (no sliver edge): a vertex on the
        # seam line of a closed NURBS may project to the far side of the domain by round-off
        if float(np.linalg.norm(E[1] - E[0])) <= t.linear:
            return loop[j:] + loop[:j], E[0]
        if float(np.linalg.norm(E[1] - E[2])) <= t.linear:
            return loop[j + 1:] + loop[:j + 1], E[2]
        e0 = RawEdge(c.edge.curve, s0, tc, E[0], E[1], c.edge.tol, c.edge.name)
        e1 = RawEdge(c.edge.curve, tc, s1, E[1], E[2], c.edge.tol, c.edge.name)
        return [RawCoedge(e1, True)] + loop[j + 1:] + loop[:j] + [RawCoedge(e0, True)], E[1]
    raise TopologyError(f"{face.name}: the inserted seam {'uv'[k]} = {a:.9g} does not cross one of its loops")


def _insert_seam(face: RawFace, loops: list, k: int, per: float, t: Tolerance, a: float | None = None) -> tuple[list, RawEdge]:
    """Join the two loops of a seamless band face by a seam edge along an iso-line of parameter ``k``.

    The band's two loops each wind once around the period (a cylinder, cone or sphere zone
    between two circles, a closed NURBS between two closed curves); loops that do not wind
    (holes) are kept.  The seam is the iso-curve ``k = a`` (:func:`_iso_cut`, exact and
    same-parameter), by default through the first vertex ``P1`` of the first winding loop (a
    NURBS gives its domain start: it is not periodic); it meets the loops at ``P1`` and ``P2``
    (:func:`_cut_loop`).  The new outer loop is ``loop1 (from P1), seam P1 -> P2, loop2 (from
    P2), seam P2 -> P1``: the face as a seam face, split like the others.

    Raises
    ------
    TopologyError
        Not exactly two winding loops, or the seam line does not cross a loop.
    """
    from coons.kernel.onsurface import project_on_surface

    S = face.surface
    bands, samples = _winding_loops(face, loops, k, per, t)
    if len(bands) != 2:
        raise TopologyError(f"{face.name}: covers the whole period of its {'uv'[k]} parameter without a seam edge "
                            f"and has {len(bands)} loops winding around it (only bands of two are supported)")
    if a is None:
        first = loops[bands[0]][0]
        P = np.asarray(first.edge.curve.evaluate(np.array([first.t_range[0]])))
        a = float(project_on_surface(S, P, t)[0, k])
    first, P1 = _cut_loop(face, loops[bands[0]], samples[bands[0]], k, a, per, t)
    second, P2 = _cut_loop(face, loops[bands[1]], samples[bands[1]], k, a, per, t)
    uv = project_on_surface(S, np.stack([P1, P2]), t)
    curve, _ = _iso_cut(S, k, a)
    seam = RawEdge(curve, float(uv[0, 1 - k]), float(uv[1, 1 - k]), P1, P2, 0.0, f"seam inserted at {'uv'[k]} = {a:.9g}")
    joined = first + [RawCoedge(seam, True)] + second + [RawCoedge(seam, False)]
    return [joined] + [lp for i, lp in enumerate(loops) if i not in bands], seam


def _shifted(pc: Any, du: float, dv: float) -> Any:
    """The p-curve translated by ``(du, dv)`` in the parameter plane (exact for every type)."""
    from coons.kernel.pcurve import Line2D, Trig2D

    d = np.array([du, dv])
    if not np.any(d):
        return pc
    if isinstance(pc, Line2D):
        return Line2D(pc.origin + d, pc.direction)
    if isinstance(pc, Trig2D):
        return Trig2D(pc.center + d, pc.a, pc.b)
    if isinstance(pc, NurbsCurve):
        return NurbsCurve(pc.control_points + d, pc.knots, pc.degree, pc.weights)
    raise InvalidGeometryError(f"cannot translate a {type(pc).__name__} p-curve")


def _iso_cut(surface: Any, k: int, c: float) -> tuple[Any, Any]:
    """The iso-curve ``u = c`` (``k = 0``) or ``v = c`` (``k = 1``) of an analytic surface, same-parameter.

    Returns the 3-D curve and its p-curve; the curve parameter is the free surface parameter
    (``v`` along ``u = c``), so ``surface(pcurve(s)) = curve(s)`` exactly.
    """
    from coons.kernel.analytic import Circle, ConicalSurface, CylindricalSurface, Line, SphericalSurface, ToroidalSurface
    from coons.kernel.pcurve import Line2D

    if isinstance(surface, NurbsSurface):  # the iso-curve keeps the surface's other parameter
        return surface.iso_curve("uv"[k], c), (Line2D([c, 0.0], [0.0, 1.0]) if k == 0 else Line2D([0.0, c], [1.0, 0.0]))
    X, Z = surface.x_dir, surface.axis
    Y = np.cross(Z, X)
    e = math.cos(c) * X + math.sin(c) * Y
    if k == 0:
        pc = Line2D([c, 0.0], [0.0, 1.0])
        if isinstance(surface, CylindricalSurface):
            return Line(surface.origin + surface.radius * e, Z), pc
        if isinstance(surface, ConicalSurface):
            a = surface.semi_angle
            return Line(surface.origin + surface.radius * e, math.sin(a) * e + math.cos(a) * Z), pc
        if isinstance(surface, SphericalSurface):
            return Circle(surface.center, np.cross(e, Z), e, surface.radius), pc
        if isinstance(surface, ToroidalSurface):
            return Circle(surface.center + surface.major_radius * e, np.cross(e, Z), e, surface.minor_radius), pc
    elif isinstance(surface, ToroidalSurface):
        R, r = surface.major_radius, surface.minor_radius
        return Circle(surface.center + r * math.sin(c) * Z, Z, X, R + r * math.cos(c)), Line2D([0.0, c], [1.0, 0.0])
    raise TopologyError(f"cannot split a {type(surface).__name__} along its {'uv'[k]} seam")


def _coedge_samples(coedges: list, n: int) -> np.ndarray:
    """``(k, n, 3)`` points of each coedge's curve at ``n`` uniform parameters in its direction of use."""
    from coons.kernel.onsurface import evaluate_curves

    s = np.linspace(0.0, 1.0, n)
    r = np.array([c.t_range for c in coedges], dtype=np.float64).reshape(-1, 2)
    T = r[:, :1] + (r[:, 1:] - r[:, :1]) * s  # np.linspace(a, b, n) per coedge, to round-off
    T[:, 0], T[:, -1] = r[:, 0], r[:, 1]
    return evaluate_curves([c.edge.curve for c in coedges], T)


def _loop_area(face: RawFace, loop: list, pcs: list, t: Tolerance) -> float:
    """Signed area of a loop in the parameter plane (shoelace over sampled p-curves)."""
    if all(pc is None for pc in pcs):  # planar face: the plane's own coordinates of the 3-D points
        X = _coedge_samples(loop, _SAMPLES)[:, :-1].reshape(-1, 3)
        P = np.asarray(face.surface.closest_parameters(X))
    else:  # faces on other surfaces have a p-curve on every edge
        P = np.concatenate([np.asarray(pc.evaluate(np.linspace(*c.t_range, _SAMPLES)[:-1])) for c, pc in zip(loop, pcs)])
    x, y = P[:, 0], P[:, 1]
    return 0.5 * float(np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y))


def _pcurve(face: RawFace, c: RawCoedge, box, t: Tolerance) -> tuple[Any, float]:
    """The p-curve of a coedge on the face's surface branch, and its deviation."""
    from coons.kernel.onsurface import pcurve_on

    if isinstance(face.surface, PlanarSurface):
        return None, 0.0
    lo, hi = sorted(c.t_range)
    try:
        return pcurve_on(face.surface, c.edge.curve, lo, hi, box, t)
    except InvalidGeometryError:
        pass
    # The curve lies off the surface by more than tol.linear (file precision): measure by how much
    # and accept up to the edge's own vertex deviation or 1e3 tol.linear, recording it.
    from coons.kernel.onsurface import evaluate_on_surface, project_on_surface

    X = np.asarray(c.edge.curve.evaluate(np.linspace(lo, hi, 33)))
    d = float(np.max(np.linalg.norm(evaluate_on_surface(face.surface, project_on_surface(face.surface, X, t)) - X, axis=-1)))
    limit = max(1e3 * t.linear, 4.0 * c.edge.tol)  # a file written to ~1e-4 mm is accepted; more is a bad file
    if not d <= limit:
        raise InvalidGeometryError(f"{face.name}: edge {c.edge.name} lies {d:.3g} from the face's surface "
                                   f"(more than the accepted {limit:.3g})")
    loose = Tolerance(max(2.0 * d, t.linear), t.angular, t.solver)
    return pcurve_on(face.surface, c.edge.curve, lo, hi, box, loose)


def _sphere_halves(face: RawFace, t: Tolerance) -> list[FaceSpec]:
    """A whole sphere (a face bounded only by vertex loops) as two hemispheres split along meridians."""
    from coons.kernel.analytic import SphericalSurface
    from coons.kernel.pcurve import Line2D

    S = face.surface
    if not isinstance(S, SphericalSurface):
        raise TopologyError(f"{face.name}: a face without edges on a {type(S).__name__} is not supported "
                            "(only whole spheres)")
    m0, p0 = _iso_cut(S, 0, 0.0)
    m1, p1 = _iso_cut(S, 0, math.pi)
    h = 0.5 * math.pi
    up = lambda curve, pc: EdgeSpec(curve, -h, h, pc)  # noqa: E731 - south pole -> north pole
    down = lambda curve, pc: EdgeSpec(curve, h, -h, pc)  # noqa: E731
    halves = [[up(m1, p1), down(m0, p0)], [up(m0, _shifted(p0, 2.0 * math.pi, 0.0)), down(m1, p1)]]
    if not face.sense:  # clockwise in the parameter plane: every loop reversed
        halves = [[EdgeSpec(e.curve, e.t1, e.t0, e.pcurve) for e in loop[::-1]] for loop in halves]
    return [FaceSpec(S, face.sense, [loop]) for loop in halves]


def _face_spec(face: RawFace, t: Tolerance):
    """Normalise one face (steps 1-4 of the module docstring): a generator, driven by :func:`face_specs_from_raw`.

    Each time it needs the cheap p-curves of a face's edges it yields the request
    ``(surface, items, box)`` of :func:`coons.kernel.onsurface.cheap_pcurves_many` and is sent
    the answer, so that the requests of all faces are answered in one batch; it returns the
    face's :class:`FaceSpec` list.
    """
    loops = []
    for loop in face.loops:
        kept = [c for c in loop if not c.edge.degenerate]
        if kept:
            loops.append(kept)
    if not loops:
        if face.poles or not face.loops:
            return _sphere_halves(face, t)
        raise TopologyError(f"{face.name}: no loop with a non-degenerate edge")
    count: dict[int, int] = {}
    for loop in loops:
        for c in loop:
            count[id(c.edge)] = count.get(id(c.edge), 0) + 1
    seam_ids = {k for k, n in count.items() if n == 2}
    if any(n > 2 for n in count.values()):
        raise TopologyError(f"{face.name}: an edge is used more than twice by the face")
    periods = _periods(face.surface, t)
    fixed: dict[int, float] = {}
    if seam_ids:
        fixed = _seam_values(face, loops, seam_ids, periods, t)
    inserted: tuple[int, float | None] | None = None
    if not seam_ids and isinstance(face.surface, NurbsSurface):
        # a NURBS has no full-period test in _face_box (its box is the domain): loops winding
        # around a closed direction need a seam at the domain start
        for k, per in enumerate(periods):
            if per is not None and _winding_loops(face, loops, k, per, t)[0]:
                inserted = (k, _period_start(face.surface, k))
                break
    try:
        box = None if inserted else _face_box(face, loops, t, fixed)
    except _FullPeriod as full:
        if seam_ids:
            raise
        inserted = (full.k, None)
    if inserted:
        # a band without a seam edge (a cylinder between two circles): insert the seam, then as above
        k, a = inserted
        loops, seam = _insert_seam(face, loops, k, periods[k], t, a)
        face = RawFace(face.surface, face.sense, loops, None, face.poles, face.name)
        seam_ids = {id(seam)}
        fixed = _seam_values(face, loops, seam_ids, periods, t)
        box = _face_box(face, loops, t, fixed)
    specs, pcs_all = yield from _loop_specs(face, loops, box, seam_ids, fixed, periods, t)
    if len(loops) == 1 and not fixed and not isinstance(face.surface, (PlanarSurface, NurbsSurface)):
        # A boundary through poles (two meridians of a sphere) leaves the branch ambiguous: the
        # face is on the branch where its loop turns the right way (counter-clockwise in the
        # parameter plane when sense, the pole gaps closed by straight segments).
        sign = 1.0 if face.sense else -1.0
        if sign * _loop_area(face, loops[0], pcs_all[0], t) < 0.0:
            other = tuple((hi, lo + per) if per is not None else (lo, hi) for (lo, hi), per in zip(box, periods))
            specs2, pcs2 = yield from _loop_specs(face, loops, other, seam_ids, fixed, periods, t)
            if sign * _loop_area(face, loops[0], pcs2[0], t) > 0.0:
                specs, pcs_all = specs2, pcs2
    if len(specs) > 1:
        if face.outer is not None:
            first = face.outer
        else:
            sign = 1.0 if face.sense else -1.0
            areas = np.array([sign * _loop_area(face, lp, pc, t) for lp, pc in zip(loops, pcs_all)])
            first = int(np.argmax(areas))
        specs = [specs[first]] + specs[:first] + specs[first + 1:]
    spec = FaceSpec(face.surface, face.sense, specs)
    if not fixed:
        return [spec]
    return _split_at_half_period(face, spec, fixed, periods, box, t)


def _loop_specs(face: RawFace, loops: list, box, seam_ids: set, fixed: dict, periods, t: Tolerance):
    """EdgeSpecs (with p-curves on the branch ``box``) and the p-curves of every loop (a generator, as :func:`_face_spec`).

    The p-curves of the cheap exact paths are asked for all coedges at once (one yielded
    request); the coedges they leave take the general path (:func:`_pcurve`).  Planar faces
    carry no p-curves.
    """
    specs, pcs_all = [], []
    cheap: dict = {}
    if not isinstance(face.surface, PlanarSurface):
        coedges = [c for loop in loops for c in loop]
        out = yield (face.surface, [(c.edge.curve, *sorted(c.t_range)) for c in coedges], box)
        cheap = {id(c): r for c, r in zip(coedges, out) if r is not None}
    for loop in loops:
        pcs, es = [], []
        for c in loop:
            try:
                pc, dev = cheap[id(c)] if id(c) in cheap else _pcurve(face, c, box, t)
                if id(c.edge) in seam_ids:
                    pc = _seam_branch(face, c, pc, fixed, periods)
            except CoonsError as exc:
                raise type(exc)(f"{face.name}, edge {c.edge.name}: {exc}") from None
            a, b = c.t_range
            # twice the larger of the vertex-to-curve and p-curve deviations: both ends of a
            # vertex cluster may sit that far on opposite sides
            es.append(EdgeSpec(c.edge.curve, a, b, pc, max(c.edge.tol, dev, t.linear) * 2.0))
            pcs.append(pc)
        specs.append(es)
        pcs_all.append(pcs)
    return specs, pcs_all


def _seam_values(face: RawFace, loops: list, seam_ids: set, periods, t: Tolerance) -> dict[int, float]:
    """For each direction with a seam, the seam's parameter value (in ``[0, period)``).

    Raises
    ------
    TopologyError
        A seam that is not an iso-curve of a periodic direction, or two seams in one direction.
    """
    from coons.kernel.onsurface import pcurve_on

    fixed: dict[int, float] = {}
    done = set()
    for loop in loops:
        for c in loop:
            if id(c.edge) not in seam_ids or id(c.edge) in done:
                continue
            done.add(id(c.edge))
            lo, hi = sorted(c.t_range)
            pc, _ = pcurve_on(face.surface, c.edge.curve, lo, hi, None, Tolerance(max(t.linear, 2.0 * c.edge.tol), t.angular, t.solver))
            E = np.asarray(pc.evaluate(np.linspace(lo, hi, 5)))
            span = np.ptp(E, axis=0)
            k = int(np.argmin(span))
            per = periods[k]
            if per is None or not span[k] <= 1e-9 * per:  # an iso-line: its constant parameter varies by round-off only
                raise TopologyError(f"{face.name}: seam edge {c.edge.name} is not an iso-curve of a periodic parameter "
                                    f"of the {type(face.surface).__name__}")
            base = _period_start(face.surface, k)
            value = float(np.mod(E[0, k] - base, per))
            if per - value <= 1e-9 * per:  # the far side of the period (a NURBS seam at u1) is its start
                value = 0.0
            value += base
            if k in fixed and abs(math.remainder(fixed[k] - value, per)) > 1e-9 * per:
                raise TopologyError(f"{face.name}: two seams in the {'uv'[k]} direction "
                                    f"({fixed[k]:.9g} and {value:.9g})")
            fixed[k] = value
    return fixed


def _seam_branch(face: RawFace, c: RawCoedge, pc: Any, fixed: dict, periods) -> Any:
    """Put one use of a seam edge on its side of the face's unwrapped parameter box.

    With the face on the left (counter-clockwise outer loop when ``sense``): the side
    ``u = u_s + P`` is walked towards ``+v`` and ``u = u_s`` towards ``-v``; the side ``v = v_s``
    towards ``+u`` and ``v = v_s + P`` towards ``-u``.
    """
    lo, hi = sorted(c.t_range)
    E = np.asarray(pc.evaluate(np.linspace(lo, hi, 5)))
    span = np.ptp(E, axis=0)
    k = int(np.argmin(span))
    per = periods[k]
    travel = (E[-1, 1 - k] - E[0, 1 - k]) * (1.0 if c.t_range[1] > c.t_range[0] else -1.0)
    travel *= 1.0 if face.sense else -1.0
    far = travel > 0 if k == 0 else travel < 0
    target = fixed[k] + (per if far else 0.0)
    d = [0.0, 0.0]
    d[k] = target - float(E[0, k])
    d[k] = per * round(d[k] / per)  # whole periods only: the seam's value is kept exactly
    return _shifted(pc, *d)


def _split_at_half_period(face: RawFace, spec: FaceSpec, fixed: dict, periods, box, t: Tolerance) -> list[FaceSpec]:
    """Split an unwrapped seam face along the iso-lines half a period from its seams (``split_face``)."""
    from coons.kernel.analytic import SphericalSurface
    from coons.topology.split import clip_to_face, split_face

    cuts = []
    for k, value in sorted(fixed.items()):
        c = value + 0.5 * periods[k]
        curve, pc = _iso_cut(face.surface, k, c)
        other = 1 - k
        lo, hi = box[other]
        if not (math.isfinite(lo) and math.isfinite(hi)):
            lo, hi = _extent(spec, other)
            pad = 1e-3 * (hi - lo)  # reach past the boundary so that clipping finds the crossings
            lo, hi = lo - pad, hi + pad
        if isinstance(face.surface, SphericalSurface):  # a meridian ends at the poles
            lo, hi = max(lo, -0.5 * math.pi), min(hi, 0.5 * math.pi)
        if isinstance(face.surface, NurbsSurface):  # a NURBS is not evaluated outside its domain
            d0, d1 = face.surface.domain[other]
            lo, hi = max(lo, d0), min(hi, d1)
        band = _band_range(spec, fixed, other)
        if band is not None:
            cuts.append(EdgeSpec(curve, band[0], band[1], pc))
            continue
        try:
            parts = clip_to_face(spec, pc, lo, hi, t)
        except CoonsError as exc:
            raise TopologyError(f"{face.name}: clipping the seam split line {'uv'[k]} = {c:.9g}: {exc}") from None
        for s0, s1, where in parts:
            if where == "inside":
                cuts.append(EdgeSpec(curve, s0, s1, pc))
    if not cuts:
        raise TopologyError(f"{face.name}: the split line half a period from the seam misses the face")
    try:
        return split_face(spec, cuts, t)
    except CoonsError as exc:
        raise TopologyError(f"{face.name}: splitting the seam face failed: {exc}") from None


def _band_range(spec: FaceSpec, fixed: dict, other: int) -> tuple[float, float] | None:
    """The exact range of the split line on a band face, or None when clipping is needed.

    A band is one loop whose edges are the seam uses and iso-lines ``other = const`` (a
    cylinder or cone between two circles, the common case): the split line then runs from the
    lowest to the highest of those constants.  Anything else goes through ``clip_to_face``.
    """
    if len(spec.loops) != 1 or len(fixed) != 1:
        return None
    k = 1 - other
    levels = []
    for e in spec.loops[0]:
        E = np.asarray(e.pcurve.evaluate(np.linspace(e.t0, e.t1, 5)))
        span = np.ptp(E, axis=0)
        scale = max(1.0, float(np.abs(E).max()))
        # an iso-line varies by round-off only (as in _seam_values): exact ones (Line2D) by nothing,
        # fitted ones (a circle's p-curve on a revolved NURBS) by the fit's round-off
        if span[other] <= 1e-9 * scale:
            levels.append(float(E[0, other]))
        elif span[k] > 1e-9 * scale:
            return None
    if len(levels) < 2:
        return None
    lo, hi = min(levels), max(levels)
    return (lo, hi) if hi > lo else None


def _extent(spec: FaceSpec, k: int) -> tuple[float, float]:
    """Range of parameter ``k`` over the face's p-curves."""
    vals = []
    for loop in spec.loops:
        for e in loop:
            vals.append(np.asarray(e.pcurve.evaluate(np.linspace(e.t0, e.t1, _SAMPLES)))[:, k])
    v = np.concatenate(vals)
    return float(v.min()), float(v.max())


def _imprint(specs: list[FaceSpec], t: Tolerance) -> list[FaceSpec]:
    """Split edge uses at the ends of other uses of the same curve object that fall inside them.

    Splitting a seam face cuts its boundary edges (say a full circle) in two; the neighbouring
    face still uses the whole edge.  Every use of a curve is split at the parameters where other
    uses of that curve start or end (modulo the period for periodic curves), so that sewing sees
    the same edges on both sides.
    """
    by_curve: dict[int, list[float]] = {}
    for f in specs:
        for loop in f.loops:
            for e in loop:
                by_curve.setdefault(id(e.curve), []).extend((e.t0, e.t1))
    out = []
    changed = False
    for f in specs:
        loops = []
        for loop in f.loops:
            new = []
            for e in loop:
                cuts = _inner_params(e, by_curve[id(e.curve)], t)
                if not cuts:
                    new.append(e)
                    continue
                changed = True
                ts = [e.t0] + cuts + [e.t1]
                new.extend(EdgeSpec(e.curve, a, b, e.pcurve, e.tol) for a, b in zip(ts[:-1], ts[1:]))
            loops.append(new)
        out.append(FaceSpec(f.surface, f.sense, loops) if changed else f)
    return out


def _inner_params(e: EdgeSpec, params: list[float], t: Tolerance) -> list[float]:
    """Parameters of ``params`` strictly inside ``e``'s range, in the direction of travel."""
    lo, hi = min(e.t0, e.t1), max(e.t0, e.t1)
    per = getattr(e.curve, "period", None) if getattr(e.curve, "periodic", False) else None
    p = np.asarray(params, dtype=np.float64)
    if per is not None:
        p = lo + np.mod(p - lo, per)
    # a split point closer than round-off to an end is that end (the parameters come from one curve)
    eps = 1e-9 * max(1.0, hi - lo)
    inner = np.unique(p[(p > lo + eps) & (p < hi - eps)])
    if inner.size > 1:
        inner = inner[np.concatenate([[True], np.diff(inner) > eps])]
    vals = inner.tolist()
    return vals if e.t1 > e.t0 else vals[::-1]


def face_specs_from_raw(faces: list[RawFace], tol: Tolerance | None = None) -> list[FaceSpec]:
    """Normalise neutral faces to coons :class:`~coons.topology.sew.FaceSpec`\\ s (steps 1-4 of the module docstring).

    Raises
    ------
    TopologyError
        A face with no non-degenerate loop, a seam or full-period face that cannot be split.
    InvalidGeometryError
        An edge lying off its face's surface by more than the accepted precision.
    """
    t = resolve(tol)
    from coons.kernel.onsurface import cheap_pcurves_many

    # Every face runs as a generator up to its request for cheap p-curves; the requests of all
    # faces are answered in one batch (a thousand small faces cost a few batched passes), and the
    # faces go on to their next request or their result.
    _mark_degenerate(faces)
    steps = [_face_spec(f, t) for f in faces]
    results: list = [None] * len(faces)
    pending: dict[int, tuple] = {}

    def advance(i: int, value) -> None:
        try:
            pending[i] = steps[i].send(value)
        except StopIteration as done:
            results[i] = done.value

    for i in range(len(faces)):
        advance(i, None)
    while pending:
        asked = sorted(pending)
        answers = cheap_pcurves_many([pending.pop(i) for i in asked], t)
        for i, answer in zip(asked, answers):
            advance(i, answer)
    out: list[FaceSpec] = [spec for pieces in results for spec in pieces]
    split = any(len(pieces) > 1 for pieces in results)
    return _imprint(out, t) if split else out


def faces_to_solid(faces: list[RawFace], tol: Tolerance | None = None):
    """Normalise and sew neutral faces into a checked :class:`~coons.topology.shape.Solid`.

    Raises
    ------
    TopologyError, InvalidGeometryError
        As :func:`face_specs_from_raw` and :func:`coons.topology.sew.sew_faces`.
    """
    t = resolve(tol)
    return sew_faces(face_specs_from_raw(faces, t), t)
