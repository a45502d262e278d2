"""STEP entities -> coons geometry and neutral topology records (AP203 / AP214 / AP242 B-rep subset).

:class:`StepModel` interprets a parsed :class:`~coons.io.step.p21.P21File`: it finds the solids
(``MANIFOLD_SOLID_BREP``, ``BREP_WITH_VOIDS``, ``FACETED_BREP``, the closed shells of a
``SHELL_BASED_SURFACE_MODEL``) through the shape representations that hold them, reads their units
(``LENGTH_UNIT`` as an ``SI_UNIT`` with prefix or a ``CONVERSION_BASED_UNIT`` such as the inch;
``PLANE_ANGLE_UNIT`` radian or degree) and converts geometry to coons values in millimetres and
radians:

=====================================  ==============================================================
STEP                                    coons
=====================================  ==============================================================
CARTESIAN_POINT, DIRECTION, VECTOR      ``(3,)`` arrays
AXIS2_PLACEMENT_3D                      origin, axis, x direction (ISO 10303-42 ``build_axes`` defaults)
LINE, CIRCLE, ELLIPSE                   :class:`~coons.kernel.analytic.Line`, ``Circle``, ``Ellipse``
B_SPLINE_CURVE_WITH_KNOTS (+ rational)  :class:`~coons.kernel.curve.NurbsCurve`
BEZIER_CURVE, POLYLINE                  ``NurbsCurve``
TRIMMED_CURVE, SURFACE_CURVE,           their basis / 3-D curve (edges are bounded by their vertices)
SEAM_CURVE, INTERSECTION_CURVE
OFFSET_CURVE_3D of a LINE / of a        ``Line`` / ``Circle`` (exact; OCCT's convention: offset along
CIRCLE about ref_direction              ``T × ref_direction``)
PLANE, CYLINDRICAL_, CONICAL_,          ``PlanarSurface``, ``CylindricalSurface``, ``ConicalSurface``,
SPHERICAL_, TOROIDAL_SURFACE            ``SphericalSurface``, ``ToroidalSurface``
B_SPLINE_SURFACE_WITH_KNOTS (+ rat.)    :class:`~coons.kernel.surface.NurbsSurface`
SURFACE_OF_LINEAR_EXTRUSION             a plane (LINE swept), a cylinder (CIRCLE along its axis), else
                                        an exact ``NurbsSurface`` per face (conics made exact NURBS)
SURFACE_OF_REVOLUTION                   a cylinder (LINE parallel to the axis), else an exact
                                        ``NurbsSurface`` per face (:func:`coons.kernel.conics.nurbs_revolution`
                                        of a B-spline, a segment of a LINE, or a CIRCLE / ELLIPSE in a
                                        plane through the axis that does not meet it)
OFFSET_SURFACE                          the same analytic type for planes, cylinders, cones, spheres
                                        and tori (exact); the same sweep of a fitted offset curve for
                                        swept surfaces; a fitted bicubic ``NurbsSurface`` for B-splines
TOROIDAL_SURFACE with r >= R (spindle)  exact ``NurbsSurface`` per face, seams outside the face
=====================================  ==============================================================

**Per-face surfaces.**  A NURBS patch is bounded and not periodic, but swept surfaces are unbounded
(a line swept) or closed (a conic swept, a full revolution) in the file.  Such surfaces are made
one patch per face from the face's boundary (:meth:`StepModel._swept_face`): the patch's extent
covers the boundary with margin, and its seam in each closed direction is the face's seam edge
when it has one (the face is then split there by :mod:`coons.io._faces`), else the middle of the
largest gap of the boundary's angles.  Where the result is an analytic surface whose ``Su × Sv``
is opposite to the file's, the face's sense is flipped instead (``_Flipped``).

**Offsets are approximations where they must be.**  The offset of a B-spline (and of a swept
B-spline or conic) is not a NURBS: it is interpolated per knot span with cubic pieces joined C0
(the offset is only C1 where its basis is C2), samples doubled until the mid-sample error is within
the tolerance raised to the file's length uncertainty; a fit that cannot get there within
``_OFFSET_GRID`` samples raises a :class:`~coons.errors.StepError` naming the face.

**Faceted B-reps.**  ``POLY_LOOP`` bounds (of ``FACE_SURFACE``\\ s in a ``FACETED_BREP``, or of
advanced faces) become straight edges, one per pair of points shared by the facets using it.

Topology (``ADVANCED_FACE``/``FACE_SURFACE``, ``FACE_(OUTER_)BOUND``, ``EDGE_LOOP``,
``VERTEX_LOOP``, ``POLY_LOOP``, ``ORIENTED_EDGE``, ``EDGE_CURVE``, ``VERTEX_POINT``, the shells)
becomes the neutral records of :mod:`coons.io._faces` (:class:`~coons.io._faces.RawFace`), which
turn into a coons solid there.  Edge parameters are found by projecting the vertex points on the
edge curve (closed form for analytic curves, :func:`coons.kernel.projection.curve_closest_parameters`
for NURBS), so the file's curve parametrisation (e.g. a ``VECTOR`` magnitude) never matters.

Deliberately not done: the file's ``PCURVE``\\ s are not read (p-curves are recomputed from the
3-D geometry by :func:`coons.kernel.onsurface.pcurve_on`, which is exact for iso-curves).  Not
read (a :class:`~coons.errors.StepError` naming the entity when a solid needs them):
``RECTANGULAR_TRIMMED_SURFACE``, ``CURVE_BOUNDED_SURFACE``, ``DEGENERATE_TOROIDAL_SURFACE``,
hyperbolas and parabolas, offset curves other than the exact cases above, revolutions of conics
meeting the axis or out of a meridian plane, offset faces reaching past their B-spline basis's
domain (OCCT extrapolates the basis there).  Assembly placements
(``REPRESENTATION_RELATIONSHIP_WITH_TRANSFORMATION`` with an ``ITEM_DEFINED_TRANSFORMATION``) are
applied: a solid appears once per path from its representation to a root representation.
Unknown entity types elsewhere in the file are ignored.

Reference: ISO 10303-42 (geometric and topological representation), ISO 10303-41 (units).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from coons.errors import CoonsError, StepError
from coons.io._faces import RawCoedge, RawEdge, RawFace
from coons.io.step.p21 import Entity, Enum, P21File, Ref, Typed
from coons.kernel import analytic as an
from coons.kernel.curve import NurbsCurve
from coons.kernel.surface import NurbsSurface
from coons.tolerance import Tolerance, resolve

__all__ = ["StepModel", "SolidRecord"]

#: Largest sample grid (points) for fitting the offset of a B-spline surface: ~1 s of evaluation.
_OFFSET_GRID = 1 << 18

_SI_PREFIX = {
    "EXA": 1e18, "PETA": 1e15, "TERA": 1e12, "GIGA": 1e9, "MEGA": 1e6, "KILO": 1e3, "HECTO": 1e2, "DECA": 1e1,
    "DECI": 1e-1, "CENTI": 1e-2, "MILLI": 1e-3, "MICRO": 1e-6, "NANO": 1e-9, "PICO": 1e-12, "FEMTO": 1e-15,
    "ATTO": 1e-18,
}


def _piecewise_cubic(Q: np.ndarray, breaks: np.ndarray, m: int, tol: Tolerance) -> tuple[np.ndarray, np.ndarray]:
    """Cubic interpolation of the rows of ``Q`` (``m + 1`` uniform samples per span of ``breaks``), span by span.

    Each span is interpolated on its own (The NURBS Book A9.1) and the pieces are joined with
    knots of full multiplicity at the breaks (C0): an offset is only C1 where its basis is C2,
    which one smooth interpolant across the break would smear into the neighbouring spans.

    Parameters
    ----------
    Q : ((len(breaks) - 1) * m + 1, d) samples at ``linspace`` of each span, shared ends
    breaks : (k,) increasing

    Returns
    -------
    control points (n, d), knots (n + 4,)
    """
    from coons.kernel.fitting import interpolate_curve

    pts, knots = [], [np.full(4, breaks[0])]
    for k, (a, b) in enumerate(zip(breaks[:-1], breaks[1:])):
        c = interpolate_curve(Q[k * m:(k + 1) * m + 1], 3, params=np.linspace(a, b, m + 1), tol=tol)
        pts.append(c.control_points if k == 0 else c.control_points[1:])
        knots.append(np.concatenate([c.knots[4:-4], np.full(3, b)]))
    knots.append([breaks[-1]])
    return np.concatenate(pts), np.concatenate(knots)


def _span_samples(breaks: np.ndarray, m: int) -> np.ndarray:
    """``m + 1`` uniform samples per span of ``breaks``, the shared ends once."""
    return np.concatenate([np.linspace(a, b, m + 1)[:-1] for a, b in zip(breaks[:-1], breaks[1:])] + [breaks[-1:]])


def _de_casteljau_parts(Pw: np.ndarray, s: float) -> tuple[np.ndarray, np.ndarray]:
    """Control points of one Bézier polynomial on ``[0, s]`` and on ``[s, 1]`` (local parameter; ``s``
    may lie outside ``[0, 1]``: extrapolation).  The NURBS Book A5.6's subdivision, in homogeneous
    coordinates; the loop runs over the degree."""
    left, right = [Pw[0]], [Pw[-1]]
    Q = Pw
    for _ in range(Pw.shape[0] - 1):
        Q = (1.0 - s) * Q[:-1] + s * Q[1:]
        left.append(Q[0])
        right.append(Q[-1])
    return np.array(left), np.array(right[::-1])


def _extended(C: NurbsCurve, frac: float) -> NurbsCurve:
    """``C`` continued past both ends by ``frac`` of its domain, its end pieces' polynomials extrapolated.

    As OCCT evaluates a B-spline outside its range: an offset face may reach a little past its
    basis curve's end (the intersection with a neighbour lies beyond it).  The pieces are joined
    with knots of multiplicity ``p`` (the curve is unchanged inside the old domain).
    """
    p = C.degree
    segs = C.bezier_segments()
    (a, b) = C.domain
    delta = frac * (b - a)
    pieces, breaks = [], []
    for k, sg in enumerate(segs):
        Pw = np.asarray(sg.homogeneous)
        s0, s1 = sg.domain
        if k == len(segs) - 1:
            Pw = _de_casteljau_parts(Pw, (s1 + delta - s0) / (s1 - s0))[0]
            s1 = s1 + delta
        if k == 0:
            Pw = _de_casteljau_parts(Pw, -delta / (s1 - s0))[1]
            s0 = s0 - delta
        pieces.append(Pw if k == 0 else Pw[1:])
        breaks.append((s0, s1))
    knots = np.concatenate([np.full(p + 1, breaks[0][0])] + [np.full(p, s1) for _, s1 in breaks[:-1]]
                           + [np.full(p + 1, breaks[-1][1])])
    return NurbsCurve.from_homogeneous(np.concatenate(pieces), knots, p)


@dataclass(frozen=True)
class _SpindleTorus:
    """A torus with ``minor_radius >= major_radius``, made an exact NURBS per face."""

    o: np.ndarray
    z: np.ndarray
    x: np.ndarray
    R: float
    r: float


@dataclass(frozen=True)
class _Swept:
    """A SURFACE_OF_LINEAR_EXTRUSION (``vector``) or SURFACE_OF_REVOLUTION (``o``, ``z``) made a NURBS per face.

    Both are unbounded (a LINE swept) or closed (a conic swept) in the file; a NURBS patch is
    bounded and not periodic, so its extent and seams are chosen from the face's boundary
    (:meth:`StepModel._swept_face`).
    """

    curve: Any
    vector: np.ndarray | None = None
    o: np.ndarray | None = None
    z: np.ndarray | None = None


@dataclass(frozen=True)
class _Offset:
    """An OFFSET_SURFACE of a :class:`_Swept` surface: made a NURBS per face, then offset."""

    basis: Any
    distance: float


@dataclass(frozen=True)
class _Flipped:
    """An analytic surface whose ``Su × Sv`` is opposite to the file surface's: the face's sense flips."""

    surface: Any


@dataclass
class SolidRecord:
    """One solid of the file: its entity and the neutral faces of each shell (outer shell first).

    ``shells[k]`` is ``(faces, flipped)``: a shell used with orientation ``.F.`` (a void of a
    ``BREP_WITH_VOIDS``) has its faces already reversed in ``faces``.
    """

    entity: Entity
    faces: list[RawFace]
    length_unit: float  # millimetres per file length unit
    uncertainty: float | None  # the representation's length uncertainty, in mm


class StepModel:
    """Interpretation of a parsed STEP file (see the module docstring).

    Parameters
    ----------
    file : P21File
    tol : Tolerance, optional

    Raises
    ------
    StepError
        From the methods, naming the entity (id, type, line) that cannot be read.
    """

    def __init__(self, file: P21File, tol: Tolerance | None = None) -> None:
        self.file = file
        self.tol = resolve(tol)
        self._memo: dict[tuple, Any] = {}
        self._busy: set[tuple] = set()
        self._parents: dict | None = None  # entities being converted: a reference back to one is a cycle
        self.L = 1.0  # mm per file length unit (set per representation)
        self.A = 1.0  # radians per file angle unit
        self.M = np.eye(3)  # rotation of the current assembly placement ...
        self.b = np.zeros(3)  # ... and its translation (mm)
        self._xf = 0  # key of the current placement in the memo
        self._xf_count = 0
        self.unc: float | None = None  # the current representation's length uncertainty (mm)

    # ------------------------------------------------------------------ helpers
    def ent(self, ref: Any, referrer: Entity, *types: str) -> Entity:
        """Resolve ``ref`` and check its type is one of ``types`` (any when empty)."""
        e = self.file.get(ref, referrer)
        if types and not any(e.has_type(t) for t in types):
            raise StepError(f"expected {' or '.join(types)} but #{e.id} is {e.name} (line {e.line})",
                            entity_id=referrer.id, line=referrer.line)
        return e

    @staticmethod
    def fail(e: Entity, message: str) -> StepError:
        return StepError(f"{e.name}: {message}", entity_id=e.id, line=e.line)

    def params(self, e: Entity, n: int, part: str | None = None) -> tuple:
        """The parameters of ``e`` (or of its partial type ``part``), at least ``n`` of them."""
        if part is not None and e.parts is not None:
            p = e.parts.get(part)
            if p is None:
                raise self.fail(e, f"complex instance lacks the partial type {part}")
        else:
            p = e.params
        if len(p) < n:
            raise self.fail(e, f"expected at least {n} parameters, got {len(p)}")
        return p

    def number(self, x: Any, e: Entity, what: str) -> float:
        if isinstance(x, Typed) and len(x.params) == 1:
            x = x.params[0]
        if isinstance(x, bool) or not isinstance(x, (int, float)) or not math.isfinite(float(x)):
            raise self.fail(e, f"{what} must be a finite number, got {x!r}")
        return float(x)

    def integer(self, x: Any, e: Entity, what: str, low: int = 0, high: int = 10**6) -> int:
        if isinstance(x, bool) or not isinstance(x, int) or not low <= x <= high:
            raise self.fail(e, f"{what} must be an integer in [{low}, {high}], got {x!r}")
        return int(x)

    def logical(self, x: Any, e: Entity, what: str) -> bool:
        if not isinstance(x, bool):
            raise self.fail(e, f"{what} must be .T. or .F., got {x!r}")
        return x

    def seq(self, x: Any, e: Entity, what: str, min_len: int = 1) -> tuple:
        if not isinstance(x, tuple) or len(x) < min_len:
            raise self.fail(e, f"{what} must be a list of at least {min_len} items, got {x!r}"[:300])
        return x

    def _memoised(self, kind: str, ref: Any, referrer: Entity, build) -> Any:
        key = (kind, ref.id if isinstance(ref, Ref) else None, self.L, self.A, self._xf)
        if key[1] is not None and key in self._memo:
            return self._memo[key]
        e = self.file.get(ref, referrer)
        if key in self._busy:
            raise self.fail(e, f"cyclic reference: #{e.id} refers back to itself through #{referrer.id}")
        self._busy.add(key)
        try:
            value = build(e)
        except StepError:
            raise
        except (CoonsError, ValueError, TypeError, ArithmeticError, IndexError) as exc:
            raise self.fail(e, f"cannot be converted: {exc}") from None
        finally:
            self._busy.discard(key)
        self._memo[key] = value
        return value

    # ------------------------------------------------------------------ points and placements
    def _numbers(self, e: Entity, dim: int, what: str, item: str) -> list[float] | tuple[float, ...]:
        """The ``dim`` finite numbers of a point's or direction's list (its second parameter)."""
        c = e.real_triple() if dim == 3 else None  # the common form, read without building params
        if c is not None and all(map(math.isfinite, c)):
            return c
        c = self.seq(self.params(e, 2)[1], e, what)  # (the general path names what is wrong)
        if len(c) != dim:
            raise self.fail(e, f"expected {dim} {what}, got {len(c)}")
        return [self.number(x, e, item) for x in c]

    def point(self, ref: Any, referrer: Entity, dim: int = 3) -> np.ndarray:
        def build(e: Entity) -> np.ndarray:
            if e.name == "VERTEX_POINT":
                return self.point(self.params(e, 2)[1], e, dim)
            if not e.has_type("CARTESIAN_POINT"):
                raise self.fail(e, "expected CARTESIAN_POINT")
            c = self._numbers(e, dim, "coordinates", "coordinate")
            with np.errstate(over="ignore", invalid="ignore"):
                P = np.array(c, dtype=np.float64) * self.L
                if dim == 3 and self._xf:
                    P = self.M @ P + self.b
            if not np.isfinite(P).all():
                raise self.fail(e, f"coordinates overflow in millimetres ({self.L:g} mm per unit)")
            return P
        return self._memoised(f"point{dim}", ref, referrer, build)

    def direction(self, ref: Any, referrer: Entity, dim: int = 3) -> np.ndarray:
        def build(e: Entity) -> np.ndarray:
            if not e.has_type("DIRECTION"):
                raise self.fail(e, "expected DIRECTION")
            d = self._numbers(e, dim, "direction ratios", "direction ratio")
            big = max(map(abs, d))
            if big > 0.0:  # scaled first: huge ratios must not overflow the norm
                d = [x / big for x in d]
            n = math.hypot(*d)
            if not n > 0.0:
                raise self.fail(e, "zero direction")
            u = np.array([x / n for x in d])
            return self.M @ u if dim == 3 and self._xf else u
        return self._memoised(f"dir{dim}", ref, referrer, build)

    def vector(self, ref: Any, referrer: Entity) -> np.ndarray:
        e = self.ent(ref, referrer, "VECTOR")
        p = self.params(e, 3)
        mag = self.number(p[2], e, "magnitude")
        if not (mag > 0.0 and math.isfinite(mag * self.L)):
            raise self.fail(e, f"magnitude must be > 0 and finite in millimetres, got {mag!r}")
        return self.direction(p[1], e) * mag * self.L

    def placement(self, ref: Any, referrer: Entity) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(origin, z, x)`` of an AXIS2_PLACEMENT_3D with the ISO 10303-42 defaults."""
        e = self.ent(ref, referrer, "AXIS2_PLACEMENT_3D")
        p = self.params(e, 2)
        o = self.point(p[1], e)
        z = np.array([0.0, 0.0, 1.0]) if len(p) < 3 or p[2] is None else self.direction(p[2], e)
        if len(p) < 4 or p[3] is None:
            ref_dir = np.array([1.0, 0.0, 0.0]) if abs(z[0]) < 1.0 - 1e-12 else np.array([0.0, 0.0, 1.0])
        else:
            ref_dir = self.direction(p[3], e)
        rz = float(ref_dir @ z)
        x = ref_dir - rz * z
        n = math.hypot(*x.tolist())
        if not n > self.tol.angular:
            raise self.fail(e, "ref_direction is parallel to the axis")
        return o, z, x / n

    # ------------------------------------------------------------------ curves
    def curve(self, ref: Any, referrer: Entity) -> Any:
        """The 3-D coons curve of a STEP curve entity."""
        return self._memoised("curve", ref, referrer, self._curve)

    def _curve(self, e: Entity) -> Any:
        n = e.name
        if n == "LINE":
            p = self.params(e, 3)
            return an.Line(self.point(p[1], e), self.vector(p[2], e))
        if n == "CIRCLE":
            p = self.params(e, 3)
            o, z, x = self.placement(p[1], e)
            return an.Circle(o, z, x, self.number(p[2], e, "radius") * self.L)
        if n == "ELLIPSE":
            p = self.params(e, 4)
            o, z, x = self.placement(p[1], e)
            a, b = self.number(p[2], e, "semi_axis_1") * self.L, self.number(p[3], e, "semi_axis_2") * self.L
            if a < b:  # coons wants the major axis first: turn the frame by 90 degrees
                x, a, b = np.cross(z, x), b, a
            return an.Ellipse(o, z, x, a, b)
        if n in ("SURFACE_CURVE", "SEAM_CURVE", "INTERSECTION_CURVE", "BOUNDED_SURFACE_CURVE"):
            return self.curve(self.params(e, 2)[1], e)
        if n == "TRIMMED_CURVE":
            return self.curve(self.params(e, 2)[1], e)
        if n == "OFFSET_CURVE_3D":
            p = self.params(e, 5)
            return self._offset_curve(self.curve(p[1], e), self.number(p[2], e, "distance") * self.L,
                                      self.direction(p[4], e), e)
        if n == "POLYLINE":
            pts = self.seq(self.params(e, 2)[1], e, "points", 2)
            P = np.array([self.point(r, e) for r in pts])
            m = P.shape[0]
            return NurbsCurve(P, np.concatenate([[0.0], np.arange(m, dtype=float), [m - 1.0]]), 1)
        if e.has_type("B_SPLINE_CURVE_WITH_KNOTS") or e.name == "BEZIER_CURVE" or e.has_type("BEZIER_CURVE"):
            return self._bspline_curve(e)
        raise self.fail(e, "curve type not supported by the coons STEP reader")

    def _offset_curve(self, C: Any, d: float, V: np.ndarray, e: Entity) -> Any:
        """``C + d (T × V) / |T × V|`` (``T`` the tangent, ``V`` the reference direction, as OCCT's
        ``Geom_OffsetCurve``): exact for a line and for a circle in a plane square to ``V``."""
        if isinstance(C, an.Line):
            n = np.cross(C.direction, V)
            if not np.linalg.norm(n) > self.tol.angular:
                raise self.fail(e, "ref_direction is parallel to the line")
            return an.Line(C.origin + d * n / np.linalg.norm(n), C.direction)
        if isinstance(C, an.Circle):
            c = float(np.dot(C.axis, V))
            if 1.0 - abs(c) <= self.tol.angular:
                r = C.radius + (d if c > 0.0 else -d)  # (Z × r) × Z = r: outwards when V is the axis
                if not r > self.tol.linear:
                    raise self.fail(e, f"the offset by {d:.9g} shrinks the circle to radius {r:.9g}")
                return an.Circle(C.center, C.axis, C.x_dir, r)
        raise self.fail(e, f"the offset of a {type(C).__name__} (other than a line, or a circle about "
                        "ref_direction) is not supported")

    def _bspline_curve(self, e: Entity) -> NurbsCurve:
        if e.parts is None:
            p = self.params(e, 6)
            deg, pts = p[1], p[2]
            rest = p[6:] if e.name == "B_SPLINE_CURVE_WITH_KNOTS" else None
            weights = None
        else:
            b = self.params(e, 5, "B_SPLINE_CURVE")
            deg, pts = b[0], b[1]
            rest = e.parts.get("B_SPLINE_CURVE_WITH_KNOTS")
            w = e.parts.get("RATIONAL_B_SPLINE_CURVE")
            weights = None if w is None else [self.number(x, e, "weight") for x in self.seq(w[0] if w else None, e, "weights")]
        p_ = self.integer(deg, e, "degree", 1, 64)
        P = np.array([self.point(r, e) for r in self.seq(pts, e, "control points", 2)])
        if rest is None:  # Bezier: one span
            knots = np.concatenate([np.zeros(p_ + 1), np.ones(p_ + 1)])
        else:
            if len(rest) < 2:
                raise self.fail(e, "B_SPLINE_CURVE_WITH_KNOTS needs knot_multiplicities and knots")
            knots = self._knots(rest[0], rest[1], e)
        if weights is not None and len(weights) != P.shape[0]:
            raise self.fail(e, f"{len(weights)} weights for {P.shape[0]} control points")
        return NurbsCurve(P, knots, p_, weights)

    def _knots(self, mults: Any, values: Any, e: Entity) -> np.ndarray:
        m = [self.integer(x, e, "knot multiplicity", 1, 64) for x in self.seq(mults, e, "knot multiplicities")]
        k = [self.number(x, e, "knot") for x in self.seq(values, e, "knots")]
        if len(m) != len(k):
            raise self.fail(e, f"{len(m)} knot multiplicities for {len(k)} knots")
        return np.repeat(np.asarray(k), m)

    # ------------------------------------------------------------------ surfaces
    def surface(self, ref: Any, referrer: Entity) -> Any:
        return self._memoised("surface", ref, referrer, self._surface)

    def _surface(self, e: Entity) -> Any:
        n = e.name
        if n == "PLANE":
            o, z, x = self.placement(self.params(e, 2)[1], e)
            return an.PlanarSurface(o, z, x)
        if n == "CYLINDRICAL_SURFACE":
            p = self.params(e, 3)
            o, z, x = self.placement(p[1], e)
            return an.CylindricalSurface(o, z, x, self.number(p[2], e, "radius") * self.L)
        if n == "CONICAL_SURFACE":
            p = self.params(e, 4)
            o, z, x = self.placement(p[1], e)
            return an.ConicalSurface(o, z, x, self.number(p[2], e, "radius") * self.L,
                                     self.number(p[3], e, "semi_angle") * self.A)
        if n == "SPHERICAL_SURFACE":
            p = self.params(e, 3)
            o, z, x = self.placement(p[1], e)
            return an.SphericalSurface(o, z, x, self.number(p[2], e, "radius") * self.L)
        if n == "TOROIDAL_SURFACE":
            p = self.params(e, 4)
            o, z, x = self.placement(p[1], e)
            R, r = self.number(p[2], e, "major_radius") * self.L, self.number(p[3], e, "minor_radius") * self.L
            if 0.0 < R and r >= R:
                return _SpindleTorus(o, z, x, R, r)  # made a NURBS per face (see _spindle_torus)
            return an.ToroidalSurface(o, z, x, R, r)
        if e.has_type("B_SPLINE_SURFACE_WITH_KNOTS"):
            return self._bspline_surface(e)
        if n == "SURFACE_OF_REVOLUTION":
            p = self.params(e, 3)
            ax = self.ent(p[2], e, "AXIS1_PLACEMENT")
            ap = self.params(ax, 2)
            z = np.array([0.0, 0.0, 1.0]) if len(ap) < 3 or ap[2] is None else self.direction(ap[2], ax)
            return self._revolution(self.curve(p[1], e), self.point(ap[1], ax), z, e)
        if n == "SURFACE_OF_LINEAR_EXTRUSION":
            p = self.params(e, 3)
            return self._extrusion(self.curve(p[1], e), self.vector(p[2], e), e)
        if n == "OFFSET_SURFACE":
            p = self.params(e, 3)
            return self._offset_surface(self.surface(p[1], e), self.number(p[2], e, "distance") * self.L, e)
        raise self.fail(e, "surface type not supported by the coons STEP reader")

    def _offset_surface(self, S: Any, d: float, e: Entity) -> Any:
        """``S + d N`` (``N`` the unit normal ``Su × Sv``): the same analytic type, or a fitted NURBS.

        Planes move along their normal, cylinders, spheres and the tube of a torus change radius,
        a cone (normal ``cos a r - sin a z``) moves its apex along the axis and changes radius:
        all exact.  The offset of a B-spline surface is not a B-spline: it is interpolated
        (bicubic, The NURBS Book A9.4) on a grid in the basis's parameters, refined until the
        offset points between the grid points are within ``tol.linear`` of the fit (the
        reader's tolerance, raised to the file's uncertainty), else StepError.
        """
        if d == 0.0:
            return S
        if isinstance(S, _Flipped):  # the file's normal is the opposite of the analytic one
            out = self._offset_surface(S.surface, -d, e)
            return out if isinstance(out, _Offset) else _Flipped(out)
        if isinstance(S, _SpindleTorus):  # the tube's radius changes, as for a torus
            r = S.r + d
            if not r > self.tol.linear:
                raise self.fail(e, f"the offset by {d:.9g} turns the torus inside out (minor radius {r:.9g})")
            return _SpindleTorus(S.o, S.z, S.x, S.R, r) if r >= S.R else an.ToroidalSurface(S.o, S.z, S.x, S.R, r)
        if isinstance(S, _Swept):
            return _Offset(S, d)
        if isinstance(S, an.PlanarSurface):
            return an.PlanarSurface(S.origin + d * S.axis, S.axis, S.x_dir)
        radius = {an.CylindricalSurface: "radius", an.SphericalSurface: "radius", an.ToroidalSurface: "minor_radius"}
        if type(S) in radius:
            r = getattr(S, radius[type(S)]) + d
            if not r > self.tol.linear:
                raise self.fail(e, f"the offset by {d:.9g} turns the {type(S).__name__} inside out (radius {r:.9g})")
            if isinstance(S, an.CylindricalSurface):
                return an.CylindricalSurface(S.origin, S.axis, S.x_dir, r)
            if isinstance(S, an.SphericalSurface):
                return an.SphericalSurface(S.center, S.axis, S.x_dir, r)
            if r >= S.major_radius:
                return _SpindleTorus(S.center, S.axis, S.x_dir, S.major_radius, r)
            return an.ToroidalSurface(S.center, S.axis, S.x_dir, S.major_radius, r)
        if isinstance(S, an.ConicalSurface):
            a = S.semi_angle
            r = S.radius + d * math.cos(a)
            if not r >= 0.0:
                raise self.fail(e, f"the offset by {d:.9g} moves the cone's reference circle past the apex")
            return an.ConicalSurface(S.origin - d * math.sin(a) * S.axis, S.axis, S.x_dir, r, a)
        if isinstance(S, NurbsSurface):
            return self._offset_nurbs(S, d, e)
        raise self.fail(e, f"the offset of a {type(S).__name__} is not supported")

    def _offset_nurbs(self, S: NurbsSurface, d: float, e: Entity) -> NurbsSurface:
        """A bicubic fit of ``S + d N`` over ``S``'s domain, within the tolerance (see :meth:`_offset_surface`).

        Raises
        ------
        StepError
            ``S`` has no normal somewhere (a collapsed boundary), or the fit misses the tolerance
            with :data:`_OFFSET_GRID` samples.
        """
        ku, kv = np.unique(S.knots_u), np.unique(S.knots_v)

        def offset(us: np.ndarray, vs: np.ndarray) -> np.ndarray:
            D = np.asarray(S.derivatives_grid(us, vs, 1))  # (nu, nv, 2, 2, 3)
            N = np.cross(D[..., 1, 0, :], D[..., 0, 1, :])
            n = np.linalg.norm(N, axis=-1, keepdims=True)
            if not np.all(n > 0.0):
                raise self.fail(e, "the basis surface has no normal at some points (degenerate edge): offset not supported")
            return D[..., 0, 0, :] + d * N / n

        # per knot span (_piecewise_cubic), in u then v (The NURBS Book A9.4 order)
        lim = max(self.tol.linear, self.unc or 0.0)  # the file's uncertainty when it is coarser
        mu = mv = 4  # samples per knot span, doubled in the direction whose mid-points miss
        dev = math.inf
        while (len(ku) - 1) * mu * (len(kv) - 1) * mv <= _OFFSET_GRID:
            us, vs = _span_samples(ku, mu), _span_samples(kv, mv)
            Q = offset(us, vs)
            nu, nv = Q.shape[:2]
            R, KU = _piecewise_cubic(Q.reshape(nu, nv * 3), ku, mu, self.tol)
            P, KV = _piecewise_cubic(R.reshape(-1, nv, 3).transpose(1, 0, 2).reshape(nv, -1), kv, mv, self.tol)
            fit = NurbsSurface(P.reshape(P.shape[0], -1, 3).transpose(1, 0, 2), KU, KV, 3, 3)
            um, vm = 0.5 * (us[1:] + us[:-1]), 0.5 * (vs[1:] + vs[:-1])
            du = float(np.max(np.linalg.norm(np.asarray(fit.evaluate_grid(um, vs)) - offset(um, vs), axis=-1)))
            dv = float(np.max(np.linalg.norm(np.asarray(fit.evaluate_grid(us, vm)) - offset(us, vm), axis=-1)))
            dc = float(np.max(np.linalg.norm(np.asarray(fit.evaluate_grid(um, vm)) - offset(um, vm), axis=-1)))
            dev = max(du, dv, dc)
            if dev <= lim:
                return fit
            if du >= dv:
                mu *= 2
            if dv >= du or dc > max(du, dv):
                mv *= 2
        raise self.fail(e, f"the offset of the B-spline surface cannot be fitted within {lim:.3g} mm "
                        f"(reached {dev:.3g})")

    def _open_extended(self, C: NurbsCurve) -> NurbsCurve:
        """An open curve continued past its ends (:func:`_extended`) by a tenth of its domain, a closed one as is.

        The face of an offset of a swept open curve may reach past the curve's ends (OCCT extrapolates
        there); a tenth of the domain is far more than such a face needs, small enough for the
        extrapolated polynomial to stay tame.
        """
        ends = np.asarray(C.evaluate(np.array(C.domain)))
        if float(np.linalg.norm(ends[1] - ends[0])) <= self.tol.linear:
            return C
        return _extended(C, 0.1)

    def _offset_fit(self, C: NurbsCurve, normal, d: float, e: Entity) -> NurbsCurve:
        """A cubic fit of ``C(t) + d n(t)``, ``n = normal(C, C') / |normal(C, C')|``, within the tolerance.

        The offset of a swept surface is the same sweep of an offset curve (the normal of an
        extrusion does not depend on ``v``; that of a revolution turns with ``u``), so only this
        curve is approximated: per knot span (:func:`_piecewise_cubic`), samples doubled until the
        mid-points are within the tolerance (raised to the file's uncertainty).

        Raises
        ------
        StepError
            The normal vanishes (the profile meets the axis), or no fit within ``_OFFSET_GRID`` samples.
        """
        lim = max(self.tol.linear, self.unc or 0.0)
        breaks = np.unique(C.knots[C.degree:C.knots.size - C.degree])

        def offset(ts: np.ndarray) -> np.ndarray:
            D = np.asarray(C.derivatives(ts, 1))
            N = normal(D[:, 0], D[:, 1])
            n = np.linalg.norm(N, axis=-1, keepdims=True)
            if not np.all(n > 0.0):
                raise self.fail(e, "the swept surface has no normal at some points: its offset is not supported")
            return D[:, 0] + d * N / n

        m, dev = 8, math.inf
        while (breaks.size - 1) * m <= _OFFSET_GRID:
            ts = _span_samples(breaks, m)
            P, knots = _piecewise_cubic(offset(ts), breaks, m, self.tol)
            fit = NurbsCurve(P, knots, 3)
            mid = 0.5 * (ts[1:] + ts[:-1])
            dev = float(np.max(np.linalg.norm(np.asarray(fit.evaluate(mid)) - offset(mid), axis=-1)))
            if dev <= lim:
                return fit
            m *= 2
        raise self.fail(e, f"the offset of the swept curve cannot be fitted within {lim:.3g} mm (reached {dev:.3g})")

    def _extrusion(self, curve: Any, V: np.ndarray, e: Entity) -> Any:
        """``S(u, v) = C(u) + v V``: a plane for a line, a cylinder for a circle swept along its axis, else per face."""
        Vn = V / np.linalg.norm(V)
        if isinstance(curve, an.Line):
            n = np.cross(curve.direction, Vn)
            if not np.linalg.norm(n) > self.tol.angular:
                raise self.fail(e, "a line extruded along itself (degenerate surface)")
            return an.PlanarSurface(curve.origin, n, curve.direction)  # Su × Sv = D × V
        if isinstance(curve, (an.Circle, an.Ellipse)):
            c = float(np.dot(Vn, curve.axis))
            if not abs(c) > self.tol.angular:
                raise self.fail(e, "a conic extruded in its own plane (degenerate surface)")
            if isinstance(curve, an.Circle) and 1.0 - abs(c) <= self.tol.angular:
                # Su × Sv = (Z × r) × V points outwards when V runs along the circle's axis
                cyl = an.CylindricalSurface(curve.center, curve.axis, curve.x_dir, curve.radius)
                return cyl if c > 0.0 else _Flipped(cyl)
        elif not isinstance(curve, NurbsCurve):
            raise self.fail(e, f"cannot extrude a {type(curve).__name__}")
        return _Swept(curve, vector=V)

    def _revolution(self, curve: Any, o: np.ndarray, z: np.ndarray, e: Entity) -> Any:
        """``S(u, v)``: ``C(v)`` turned by ``u`` about the axis; a cylinder for a parallel line, else per face."""
        if isinstance(curve, an.Line):
            c = float(np.dot(curve.direction, z))
            if 1.0 - abs(c) <= self.tol.angular:
                w = curve.origin - o
                r = w - np.dot(w, z) * z
                rho = float(np.linalg.norm(r))
                if not rho > self.tol.linear:
                    raise self.fail(e, "a line revolved about itself (degenerate surface)")
                # Su × Sv = (Z × r) × D points outwards when the line runs along Z
                cyl = an.CylindricalSurface(o, z, r / rho, rho)
                return cyl if c > 0.0 else _Flipped(cyl)
        elif isinstance(curve, (an.Circle, an.Ellipse)):
            if abs(float(np.dot(curve.axis, z))) > self.tol.angular:
                raise self.fail(e, "a conic profile whose plane does not contain the axis of revolution is not supported")
            a, b = curve._radii()
            w = curve.center - o
            r = w - np.dot(w, z) * z
            reach = math.hypot(a * np.dot(curve.x_dir, r), b * np.dot(curve.y_dir, r)) / max(np.linalg.norm(r), 1e-300)
            if not np.linalg.norm(r) - reach > self.tol.linear:
                raise self.fail(e, "a conic profile meeting the axis of revolution is not supported")
        elif not isinstance(curve, NurbsCurve):
            raise self.fail(e, f"cannot revolve a {type(curve).__name__}")
        return _Swept(curve, o=o, z=z)

    def _cut(self, ang: np.ndarray, seam: list, e: Entity, what: str, band: bool = False) -> float:
        """Where a NURBS patch's seam goes in an angle: on the face's seam edge, else in the boundary's largest gap.

        ``ang`` holds the boundary samples' angles, ``seam`` the angle samples of each edge the face
        uses twice.  A seam edge at a constant angle is the face's cut; otherwise the face covers
        an arc and the cut is the middle of the largest gap between the samples.  A face covering
        the whole turn without a seam edge (a band between two closed curves) is cut at its first
        vertex ``ang[0]`` when ``band`` (:mod:`coons.io._faces` inserts the seam there), else refused.
        """
        for s in seam:
            d = np.angle(np.exp(1j * (s - s[0])))
            if np.ptp(d) <= 1e-9:  # an iso-line of this angle (round-off only)
                return float(s[0])
        a = np.sort(np.mod(ang, 2.0 * math.pi))
        gaps = np.diff(np.concatenate([a, [a[0] + 2.0 * math.pi]]))
        g = int(np.argmax(gaps))
        if gaps[g] <= 2.0 * math.pi / 16 * 1.01:  # 17 samples per edge: steps below 2π/16
            if band:
                return float(ang[0])
            raise self.fail(e, f"a face covering a whole turn in {what} without a seam edge is not supported")
        return float(a[g] + 0.5 * gaps[g])

    def _swept_face(self, sw: _Swept, loops: list, e: Entity, offset: float = 0.0) -> NurbsSurface:
        """The exact NURBS of an extrusion or revolution covering one face (The NURBS Book §8.3, A8.1).

        Extrusion ``C(u) + v V``: a conic becomes its exact NURBS starting at the cut angle
        (:meth:`_cut`); ``v`` spans the boundary's range (closed form ``(X - c)·n / (V·n)`` for a
        conic, a hull bound from the control points for a B-spline), padded.  Revolution of a
        profile ``C(v)`` about ``(o, z)``: a line profile becomes a segment over the boundary's
        range (from the height, or the radius for a line square to the axis), a conic in a plane
        through the axis its NURBS from the cut angle of the boundary points turned into that
        plane; :func:`coons.kernel.conics.nurbs_revolution` then starts at the cut angle about
        the axis.  ``Su × Sv`` is the file's normal in both.  With ``offset`` ``d`` the face lies
        on the offset surface ``S + d N``: the same sweep of the offset curve (:meth:`_offset_fit`),
        its extent widened by ``|d|`` where it is found from the boundary.
        """
        from coons.kernel.conics import nurbs_line, nurbs_revolution
        from coons.kernel.construct import extrude

        count: dict[int, int] = {}
        for loop in loops:
            for c in loop:
                count[id(c.edge)] = count.get(id(c.edge), 0) + 1
        samples, seams = [], []
        for loop in loops:
            for c in loop:
                X = np.asarray(c.edge.curve.evaluate(np.linspace(*c.t_range, 17)))
                samples.append(X)
                if count[id(c.edge)] == 2:
                    seams.append(len(samples) - 1)
        if not samples:
            raise self.fail(e, "a face on a swept surface needs edges")
        X = np.concatenate(samples)
        split = np.cumsum([len(s) for s in samples])[:-1]
        per_edge = lambda a: [np.split(a, split)[k] for k in seams]  # noqa: E731 - angle samples of the seam edges
        C = sw.curve
        margin = abs(offset)
        pad = 0.1  # the surface reaches a tenth of the face's extent past it: boundary curves bulge between samples
        if sw.vector is not None:
            V = sw.vector
            base = C
            if not isinstance(C, NurbsCurve):
                n = C.axis
                vs = (X - C.center) @ n / float(np.dot(V, n))
                ang = C.closest_parameters(X - np.outer(vs, V))
                cut = self._cut(ang, per_edge(ang), e, "the swept conic's angle", True)
                base = C.to_nurbs((cut, cut + 2.0 * math.pi), tol=self.tol)
            if offset:  # the normal C' × V does not depend on v
                base = self._offset_fit(self._open_extended(base), lambda P, dP: np.cross(dP, V), offset, e)
            # X = C(u) + v V with C(u) in the hull of the control points: v is bounded by the hull's
            # extent along V (exact bounds are not needed, the patch only has to contain the face)
            Vh = V / float(np.dot(V, V))
            h, hc = X @ Vh, base.control_points @ Vh
            v0, v1 = float(h.min() - hc.max()), float(h.max() - hc.min())
            span = max(v1 - v0, self.tol.linear)
            v0, v1 = v0 - pad * span, v1 + pad * span
            shifted = NurbsCurve(base.control_points + v0 * V, base.knots, base.degree, base.weights)
            return extrude(shifted, (v1 - v0) * V, tol=self.tol)
        o, z = sw.o, sw.z
        D = X - o
        hgt = D @ z
        R = D - np.outer(hgt, z)
        rho = np.linalg.norm(R, axis=1)
        if isinstance(C, an.Line):
            d, w = C.direction, C.origin - o
            dz = float(np.dot(d, z))
            if abs(dz) > self.tol.angular:
                vs = (hgt - float(np.dot(w, z))) / dz
                slack = margin / abs(dz)
            else:  # square to the axis: |w_r + v d| = rho, both roots (rho widened by the margin)
                wr = w - np.dot(w, z) * z
                q = float(np.dot(wr, d))
                root = np.sqrt(np.maximum(q * q - float(np.dot(wr, wr)) + (rho + margin) ** 2, 0.0))
                vs = np.concatenate([-q - root, -q + root])
                slack = margin
            v0, v1 = float(vs.min()), float(vs.max())
            span = max(v1 - v0, self.tol.linear)
            v0, v1 = v0 - pad * span - slack, v1 + pad * span + slack
            profile = nurbs_line(C.evaluate(np.array(v0)), C.evaluate(np.array(v1)), (v0, v1), tol=self.tol)
            r0 = np.asarray(C.evaluate(np.array([v0, v1])))
        elif isinstance(C, NurbsCurve):
            profile = C
            r0 = C.control_points
        else:
            wr = C.center - o
            wr = wr - np.dot(wr, z) * z
            rh = wr / np.linalg.norm(wr)
            Xp = o + np.outer(hgt, z) + np.outer(rho, rh)  # the boundary turned into the profile's half-plane
            ang = C.closest_parameters(Xp)
            cut = self._cut(ang, per_edge(ang), e, "the profile conic's angle", True)
            profile = C.to_nurbs((cut, cut + 2.0 * math.pi), tol=self.tol)
            r0 = C.center[None]
        if offset:  # the normal at angle 0, (Z × (C - o)) × C', turns with the profile
            profile = self._offset_fit(self._open_extended(profile), lambda P, dP: np.cross(np.cross(z, P - o), dP),
                                       offset, e)
            r0 = profile.control_points
        # the profile's own half-plane is angle 0 of nurbs_revolution
        rr = r0 - o - np.outer((r0 - o) @ z, z)
        k = int(np.argmax(np.linalg.norm(rr, axis=1)))
        if not np.linalg.norm(rr[k]) > self.tol.linear:
            raise self.fail(e, "the swept curve lies on the axis of revolution")
        xh = rr[k] / np.linalg.norm(rr[k])
        ua = np.arctan2(D @ np.cross(z, xh), D @ xh)
        cut = self._cut(ua, per_edge(ua), e, "the angle about the axis", True)
        if abs(math.remainder(cut, 2.0 * math.pi)) <= 1e-12:
            cut = 0.0  # the profile itself (OCCT's seam): no rounding of the control net
        return nurbs_revolution(profile, o, z, cut, cut + 2.0 * math.pi, tol=self.tol)

    def _spindle_torus(self, st: "_SpindleTorus", loops: list, e: Entity) -> NurbsSurface:
        """A spindle torus (``r >= R``, which the analytic type excludes) as an exact NURBS for one face.

        The meridian circle ``C + (R + r cos v) X + r sin v Z`` revolved about ``Z`` (The NURBS
        Book A8.1 via :func:`coons.kernel.conics.nurbs_revolution`), with ``Su × Sv`` pointing away
        from the axis on the outer equator as the torus's normal.  A NURBS patch is not periodic:
        both its seams are put in the largest gaps of the face boundary's torus angles ``(u, v)``
        (each boundary point's own branch: the apple part where ``R + r cos v > 0``, the lemon
        part on the other side of the axis), so the face lies inside the patch.

        Raises
        ------
        StepError
            The face's boundary covers a whole turn in ``u`` or ``v``.
        """
        from coons.kernel.conics import nurbs_circle, nurbs_revolution

        y = np.cross(st.z, st.x)
        pts = [np.asarray(c.edge.curve.evaluate(np.linspace(*c.t_range, 17))) for loop in loops for c in loop]
        if not pts:
            raise self.fail(e, "a face on a spindle torus needs edges")
        D = np.concatenate(pts) - st.o
        h = D @ st.z
        px, py = D @ st.x, D @ y
        rho = np.hypot(px, py)
        ua = np.arctan2(py, px)
        apple = np.abs((rho - st.R) ** 2 + h**2 - st.r**2) <= np.abs((rho + st.R) ** 2 + h**2 - st.r**2)
        u = np.where(apple, ua, ua + math.pi)
        v = np.where(apple, np.arctan2(h, rho - st.R), np.arctan2(h, -rho - st.R))
        us, vs = self._cut(u, [], e, "u on a spindle torus"), self._cut(v, [], e, "v on a spindle torus")
        xv = math.cos(vs) * st.x + math.sin(vs) * st.z
        profile = nurbs_circle(st.o + st.R * st.x, np.cross(st.x, st.z), st.r, x_axis=xv, tol=self.tol)
        return nurbs_revolution(profile, st.o, st.z, us, us + 2.0 * math.pi, tol=self.tol)

    def _bspline_surface(self, e: Entity) -> NurbsSurface:
        if e.parts is None:
            p = self.params(e, 13)
            du, dv, rows, rest = p[1], p[2], p[3], p[8:]
            weights = None
        else:
            b = self.params(e, 7, "B_SPLINE_SURFACE")
            du, dv, rows = b[0], b[1], b[2]
            rest = self.params(e, 4, "B_SPLINE_SURFACE_WITH_KNOTS")
            w = e.parts.get("RATIONAL_B_SPLINE_SURFACE")
            weights = None
            if w is not None:
                wr = self.seq(w[0] if w else None, e, "weights")
                weights = np.array([[self.number(x, e, "weight") for x in self.seq(r, e, "weight row")] for r in wr])
        pu, pv = self.integer(du, e, "u_degree", 1, 64), self.integer(dv, e, "v_degree", 1, 64)
        rows = self.seq(rows, e, "control points", 2)
        grid = [[self.point(r, e) for r in self.seq(row, e, "control point row", 2)] for row in rows]
        if len({len(r) for r in grid}) != 1:
            raise self.fail(e, "control point rows of different lengths")
        P = np.array(grid)
        if weights is not None and weights.shape != P.shape[:2]:
            raise self.fail(e, f"weights of shape {weights.shape} for control points {P.shape[:2]}")
        ku = self._knots(rest[0], rest[2], e)
        kv = self._knots(rest[1], rest[3], e)
        return NurbsSurface(P, ku, kv, pu, pv, weights)

    # ------------------------------------------------------------------ units
    def units_of(self, context_ref: Any, referrer: Entity) -> tuple[float, float, float | None]:
        """``(mm per length unit, radians per angle unit, uncertainty in mm)`` of a representation context."""
        ctx = self.file.get(context_ref, referrer)
        L, A, unc = 1.0, 1.0, None
        assigned = ctx.parts.get("GLOBAL_UNIT_ASSIGNED_CONTEXT") if ctx.parts else None
        if assigned:
            for r in self.seq(assigned[0], ctx, "units"):
                u = self.file.get(r, ctx)
                if u.has_type("LENGTH_UNIT"):
                    L = self._unit_factor(u, "length")
                elif u.has_type("PLANE_ANGLE_UNIT"):
                    A = self._unit_factor(u, "angle")
        unc_part = ctx.parts.get("GLOBAL_UNCERTAINTY_ASSIGNED_CONTEXT") if ctx.parts else None
        if unc_part:
            for r in self.seq(unc_part[0], ctx, "uncertainties"):
                m = self.file.get(r, ctx)
                if m.has_type("UNCERTAINTY_MEASURE_WITH_UNIT") and m.parts is None and len(m.params) >= 2:
                    try:
                        val = self.number(m.params[0], m, "uncertainty")
                        unit = self.file.get(m.params[1], m)
                        if unit.has_type("LENGTH_UNIT"):
                            unc = abs(val) * self._unit_factor(unit, "length")
                    except StepError:
                        unc = None
        return L, A, unc

    def _unit_factor(self, u: Entity, kind: str, depth: int = 0) -> float:
        """Millimetres (length) or radians (angle) per unit."""
        if depth > 8:
            raise self.fail(u, "unit conversion chain longer than 8")
        if u.parts is not None and "SI_UNIT" in u.parts:
            si = u.parts["SI_UNIT"]
            if len(si) < 2 or not isinstance(si[1], Enum):
                raise self.fail(u, f"SI_UNIT needs (prefix, name), got {si!r}")
            prefix = 1.0
            if isinstance(si[0], Enum):
                if si[0].name not in _SI_PREFIX:
                    raise self.fail(u, f"unknown SI prefix .{si[0].name}.")
                prefix = _SI_PREFIX[si[0].name]
            name = si[1].name
            if kind == "length":
                if name != "METRE":
                    raise self.fail(u, f"length unit must be based on .METRE., got .{name}.")
                return prefix * 1000.0
            if name == "RADIAN":
                return prefix
            if name == "STERADIAN":
                raise self.fail(u, "plane angle unit .STERADIAN.")
            raise self.fail(u, f"plane angle unit must be based on .RADIAN., got .{name}.")
        if u.parts is not None and "CONVERSION_BASED_UNIT" in u.parts:
            cb = u.parts["CONVERSION_BASED_UNIT"]
            if len(cb) < 2:
                raise self.fail(u, "CONVERSION_BASED_UNIT needs (name, conversion_factor)")
            m = self.file.get(cb[1], u)
            mp = m.parts.get("MEASURE_WITH_UNIT") if m.parts else m.params
            if m.parts is None and len(mp) >= 2:
                val, unit = mp[0], mp[1]
            elif mp is not None and len(mp) >= 2:
                val, unit = mp[0], mp[1]
            else:
                raise self.fail(m, "a measure with unit needs (value, unit)")
            return self.number(val, m, "conversion factor") * self._unit_factor(self.file.get(unit, m), kind, depth + 1)
        raise self.fail(u, f"{kind} unit of an unsupported kind")

    # ------------------------------------------------------------------ solids
    def solids(self) -> list[SolidRecord]:
        """Every solid of the file, in entity order, with its faces as neutral records.

        Raises
        ------
        StepError
            The file has no solid, or a solid cannot be read (naming the entity).
        """
        self._parents = None
        owner_ctx: dict[int, tuple[Entity, Any]] = {}
        for rep in self.file:
            if rep.parts is None and rep.name.endswith("SHAPE_REPRESENTATION") and len(rep.params) >= 3:
                items = rep.params[1]
                if isinstance(items, tuple):
                    for r in items:
                        if isinstance(r, Ref):
                            owner_ctx.setdefault(r.id, (rep, rep.params[2]))
        out = []
        bodies = [e for e in self.file if e.name in ("MANIFOLD_SOLID_BREP", "BREP_WITH_VOIDS", "FACETED_BREP")]
        shells_models = [e for e in self.file if e.name == "SHELL_BASED_SURFACE_MODEL"]
        for e in sorted(bodies + shells_models, key=lambda x: x.id):
            L, A, unc = 1.0, 1.0, None
            places = [np.eye(4)]
            if e.id in owner_ctx:
                rep, ctx = owner_ctx[e.id]
                L, A, unc = self.units_of(ctx, rep)
                self.L, self.A, self._xf = L, A, 0
                self.M, self.b = np.eye(3), np.zeros(3)
                places = self._instances(rep)
            for k, T in enumerate(places):
                self.L, self.A, self.unc = L, A, unc
                identity = bool(np.allclose(T, np.eye(4), rtol=0.0, atol=1e-15))
                self.M, self.b = T[:3, :3], T[:3, 3]
                self._xf_count += 1
                self._xf = 0 if identity else self._xf_count  # a fresh memo key per placement
                out.extend(self._solid_records(e, L, unc))
        if not out:
            raise StepError("the file contains no solid (MANIFOLD_SOLID_BREP, BREP_WITH_VOIDS, FACETED_BREP or closed shell of a "
                            "SHELL_BASED_SURFACE_MODEL)")
        return out

    def _frame(self, ref: Any, referrer: Entity) -> np.ndarray:
        """4x4 matrix of an AXIS2_PLACEMENT_3D (local -> global), in the file's units scaled to mm."""
        o, z, x = self.placement(ref, referrer)
        T = np.eye(4)
        T[:3, 0], T[:3, 1], T[:3, 2], T[:3, 3] = x, np.cross(z, x), z, o
        return T

    def _instances(self, rep: Entity) -> list[np.ndarray]:
        """The placements (4x4, child -> root) of a representation through the assembly structure.

        ``REPRESENTATION_RELATIONSHIP_WITH_TRANSFORMATION`` with an ``ITEM_DEFINED_TRANSFORMATION``
        maps ``rep_1`` into ``rep_2`` by ``frame(item_2) frame(item_1)^-1`` (ISO 10303-43; as OCCT);
        relationships without transformation are identities.  Every path to a root is one instance.
        """
        if self._parents is None:
            self._parents = {}
            for e in self.file:
                if not e.has_type("REPRESENTATION_RELATIONSHIP"):
                    continue
                rr = e.parts["REPRESENTATION_RELATIONSHIP"] if e.parts else e.params
                if len(rr) < 4 or not isinstance(rr[2], Ref) or not isinstance(rr[3], Ref):
                    continue
                xf = None
                if e.has_type("REPRESENTATION_RELATIONSHIP_WITH_TRANSFORMATION"):
                    p = e.parts["REPRESENTATION_RELATIONSHIP_WITH_TRANSFORMATION"] if e.parts else e.params[4:]
                    xf = self.file.get(p[0], e) if p else None
                    if xf is None or xf.name != "ITEM_DEFINED_TRANSFORMATION":
                        raise self.fail(e, "only ITEM_DEFINED_TRANSFORMATION placements are supported")
                    xf = (xf, e)
                self._parents.setdefault(rr[2].id, []).append((rr[3].id, xf))
        out: list[np.ndarray] = []
        stack = [(rep.id, np.eye(4), frozenset([rep.id]))]
        while stack:
            rid, T, seen = stack.pop()
            ups = [(pid, xf) for pid, xf in self._parents.get(rid, []) if pid not in seen]
            if not ups:
                out.append(T)
                if len(out) > 10000:
                    raise self.fail(rep, "more than 10000 placed instances")
                continue
            for pid, xf in ups:
                if xf is None:
                    stack.append((pid, T, seen | {pid}))
                    continue
                t, rel = xf
                tp = self.params(t, 4)
                with np.errstate(all="ignore"):
                    step = self._frame(tp[3], t) @ np.linalg.inv(self._frame(tp[2], t))
                if not np.all(np.isfinite(step)):
                    raise self.fail(t, "singular placement")
                stack.append((pid, step @ T, seen | {pid}))
        return out

    def _solid_records(self, e: Entity, L: float, unc: float | None) -> list[SolidRecord]:
        if e.name == "SHELL_BASED_SURFACE_MODEL":
            out = []
            for r in self.seq(self.params(e, 2)[1], e, "shells"):
                sh = self.file.get(r, e)
                if sh.name in ("CLOSED_SHELL", "ORIENTED_CLOSED_SHELL"):
                    out.append(SolidRecord(sh, self.shell_faces(r, e), L, unc))
            return out
        p = self.params(e, 2)
        faces = self.shell_faces(p[1], e)
        if e.name == "BREP_WITH_VOIDS":
            for r in self.seq(self.params(e, 3)[2], e, "voids"):
                faces += self.shell_faces(r, e)
        return [SolidRecord(e, faces, L, unc)]

    def shell_faces(self, ref: Any, referrer: Entity) -> list[RawFace]:
        sh = self.ent(ref, referrer, "CLOSED_SHELL", "OPEN_SHELL", "ORIENTED_CLOSED_SHELL", "ORIENTED_OPEN_SHELL")
        flip = False
        for _ in range(8):
            if not sh.name.startswith("ORIENTED_"):
                break
            p = self.params(sh, 4)
            flip ^= not self.logical(p[3], sh, "orientation")
            sh = self.ent(p[2], sh, "CLOSED_SHELL", "OPEN_SHELL", "ORIENTED_CLOSED_SHELL", "ORIENTED_OPEN_SHELL")
        else:
            raise self.fail(sh, "oriented shells nested deeper than 8 (cyclic?)")
        faces = [self.face(r, sh) for r in self.seq(self.params(sh, 2)[1], sh, "faces")]
        return [f.reversed() for f in faces] if flip else faces

    # ------------------------------------------------------------------ topology
    def face(self, ref: Any, referrer: Entity, depth: int = 0) -> RawFace:
        e = self.ent(ref, referrer, "ADVANCED_FACE", "FACE_SURFACE", "ORIENTED_FACE")
        if e.name == "ORIENTED_FACE":
            if depth > 8:
                raise self.fail(e, "oriented faces nested deeper than 8 (cyclic?)")
            p = self.params(e, 4)
            f = self.face(p[2], e, depth + 1)
            return f if self.logical(p[3], e, "orientation") else f.reversed()
        p = self.params(e, 4)
        surface = self.surface(p[2], e)
        same = self.logical(p[3], e, "same_sense")
        loops: list[list[RawCoedge]] = []
        poles: list[np.ndarray] = []
        outer: int | None = None
        for r in self.seq(p[1], e, "bounds"):
            b = self.ent(r, e, "FACE_BOUND", "FACE_OUTER_BOUND")
            bp = self.params(b, 3)
            orient = self.logical(bp[2], b, "orientation")
            lp = self.ent(bp[1], b, "EDGE_LOOP", "VERTEX_LOOP", "POLY_LOOP")
            if lp.name == "VERTEX_LOOP":
                poles.append(self.point(self.params(lp, 2)[1], lp))
                continue
            if lp.name == "POLY_LOOP":
                coedges = self.poly_loop(lp)
            else:
                coedges = [self.oriented_edge(x, lp) for x in self.seq(self.params(lp, 2)[1], lp, "edges")]
            if not orient:
                coedges = [c.reversed() for c in coedges[::-1]]
            if b.name == "FACE_OUTER_BOUND":
                if outer is not None:
                    raise self.fail(e, "more than one FACE_OUTER_BOUND")
                outer = len(loops)
            loops.append(coedges)
        if isinstance(surface, _Flipped):
            surface, same = surface.surface, not same
        elif isinstance(surface, (_SpindleTorus, _Swept, _Offset)):
            what = "spindle torus" if isinstance(surface, _SpindleTorus) else "swept or offset surface"
            try:
                if isinstance(surface, _SpindleTorus):
                    surface = self._spindle_torus(surface, loops, e)
                elif isinstance(surface, _Swept):
                    surface = self._swept_face(surface, loops, e)
                else:
                    surface = self._swept_face(surface.basis, loops, e, surface.distance)
            except StepError:
                raise
            except (CoonsError, ValueError, ArithmeticError) as exc:
                raise self.fail(e, f"its {what} cannot be converted: {exc}") from None
        return RawFace(surface, same, loops, outer, poles, f"#{e.id} {e.name} (line {e.line})")

    def poly_loop(self, lp: Entity) -> list[RawCoedge]:
        """The straight edges of a POLY_LOOP (faceted B-reps), shared by the faces through the same two points.

        One :class:`~coons.io._faces.RawEdge` per pair of CARTESIAN_POINT entities (and placement),
        a ``Line`` from the point of lower id to the other, so that neighbouring facets use the
        same edge as an EDGE_CURVE would be used.
        """
        refs = self.seq(self.params(lp, 2)[1], lp, "polygon", 3)
        ids = []
        for r in refs:
            if not isinstance(r, Ref):
                raise self.fail(lp, f"polygon points must be references, got {r!r}")
            self.point(r, lp)
            ids.append(r.id)
        out = []
        for a, b in zip(ids, ids[1:] + ids[:1]):
            if a == b:
                raise self.fail(lp, f"the polygon repeats point #{a} consecutively")
            key = ("poly", min(a, b), max(a, b), self.L, self._xf)
            edge = self._memo.get(key)
            if edge is None:
                P, Q = self.point(Ref(min(a, b)), lp), self.point(Ref(max(a, b)), lp)
                L = float(np.linalg.norm(Q - P))
                if not L > self.tol.linear:
                    raise self.fail(lp, f"polygon side #{a} -> #{b} is shorter than the tolerance ({L:.3g} mm)")
                edge = self._memo[key] = RawEdge(an.Line(P, Q - P), 0.0, L, P, Q, 0.0,
                                                 f"#{lp.id} POLY_LOOP side #{min(a, b)}-#{max(a, b)} (line {lp.line})")
            out.append(RawCoedge(edge, a < b))
        return out

    def oriented_edge(self, ref: Any, referrer: Entity) -> RawCoedge:
        e = self.ent(ref, referrer, "ORIENTED_EDGE")
        p = self.params(e, 5)
        edge = self.edge(p[3], e)
        return RawCoedge(edge, self.logical(p[4], e, "orientation"))

    def edge(self, ref: Any, referrer: Entity) -> RawEdge:
        def build(e: Entity) -> RawEdge:
            if e.name == "ORIENTED_EDGE":  # an oriented edge's edge element may itself be oriented
                raise self.fail(e, "nested ORIENTED_EDGE as edge element is not supported")
            if e.name != "EDGE_CURVE":
                raise self.fail(e, "expected EDGE_CURVE")
            p = self.params(e, 5)
            a = self.point(p[1], e)
            b = self.point(p[2], e)
            curve = self.curve(p[3], e)
            same = self.logical(p[4], e, "same_sense")
            from coons.io._faces import edge_parameters
            try:
                t0, t1, dev = edge_parameters(curve, a, b, same, self.tol)
            except CoonsError as exc:
                raise self.fail(e, str(exc)) from None
            return RawEdge(curve, t0, t1, a, b, dev, f"#{e.id} EDGE_CURVE (line {e.line})")
        return self._memoised("edge", ref, referrer, build)
