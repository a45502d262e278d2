"""Planar profiles: immutable regions bounded by one outer wire and any number of hole wires.

A :class:`Profile` is the input of the sweeps in :mod:`coons.topology.sweep`: a bounded planar
region in a plane given by a frame (origin, normal, ``x_dir``; default the XY plane), bounded by
one outer wire and zero or more hole wires.  A wire is a closed chain of :class:`Segment` s:
straight lines, circular arcs and NURBS splines lying in the plane (given in 2-D plane
coordinates, or in 3-D within ``tol.linear`` of the plane).  The constructor validates the
region and normalises it; the module does not offset, fillet, combine (Boolean) or tessellate
profiles, does not accept open wires, islands inside holes or several outer wires, and never
repairs a bad input: it raises :class:`~coons.errors.InvalidInputError` naming the offending
wire, segment index and point.

What the constructor checks, in this order (messages name the wire and the user's segment
index): finite coordinates; segments lying in the plane; segments longer than ``tol.linear``;
consecutive segments meeting within ``tol.linear`` (chains closed); no fold-back at a vertex;
non-zero enclosed area; no self-intersection or tangential touching inside a wire; holes neither
touching nor crossing the outer wire or each other; holes strictly inside the outer wire and not
inside each other.  Then it normalises: the outer wire runs counter-clockwise and holes
clockwise seen from the plane normal (segments are reversed as needed), full circles are split
into two half arcs and a wire made of one closed segment into two halves, so that every wire has
at least two vertices and no segment is closed (sweeps make no seam edges, ``docs/brep.md``).

Intersection test (sampled, like the checker; not a proof): every segment is cut into coarse
pieces (arcs at most π/8, splines four per knot span); each piece is a chord with an error bound
``e`` on the curve's distance from it (exact for lines and arcs, ``R (1 - cos(Δ/2))``; estimated
from interior samples for splines).  Candidate pairs of pieces come from a vectorised
sweep-and-prune of their boxes inflated by ``e`` (neighbouring pieces of a wire excluded); every
candidate pair whose chords are closer than ``e_a + e_b + tol.linear`` is halved on both sides,
all pairs at once, until its bound is below ``tol.linear / 2``: a pair then closer than
``tol.linear`` is a crossing or a tangential touch (the subdivision scheme of Lane–Riesenfeld
curve intersection, with chord bounds in place of convex hulls).  Containment uses the crossing
number of a test point against a polyline refined until its chord error is below half the
point's distance.

Segment parametrisations (the sweeps keep them as edge parameters): a line runs over
``t ∈ [0, L]`` with unit speed; an arc ``c + R (cos φ, sin φ)`` with ``φ = a₀ + σ t``,
``t ∈ [0, |sweep|]``, ``σ = sign(sweep)`` (counter-clockwise for positive sweeps); a spline over
its NURBS domain.
"""

from __future__ import annotations

import math
from dataclasses import InitVar, dataclass, field
from numbers import Real
from typing import Any, Sequence

import numpy as np

from coons.errors import InvalidGeometryError, InvalidInputError
from coons.kernel import conics
from coons.kernel.analytic import Circle, Line, PlanarSurface
from coons.kernel.curve import NurbsCurve
from coons.tolerance import Tolerance, resolve

__all__ = ["Segment", "Profile", "XY", "as_plane"]

TWO_PI = 2.0 * math.pi

#: Largest angle of an initial polyline piece on an arc (radians): chord error R(1 - cos(π/16)) ≈ 0.02 R.
_ARC_PIECE = math.pi / 8
#: Initial polyline pieces per knot span of a spline.
_SPLINE_PIECES = 4
#: Halvings of the pair refinement before undecided pairs count as touching (2^-60 of a piece).
_MAX_LEVELS = 60
#: Gauss–Legendre points per quadrature piece of the area and moment integrals; with pieces of at
#: most π/4 on arcs (trigonometric degree <= 3) and one per knot span on splines (polynomial
#: degree <= 3p - 1 for the moments) they are exact to round-off up to degree 10 splines.
_GAUSS = 16
_XG, _WG = np.polynomial.legendre.leggauss(_GAUSS)
#: Spline chord errors are estimated from three interior samples; the largest deviation of a
#: smooth arc-like piece from its chord is within this factor of the sampled one.
_SPLINE_ERROR_FACTOR = 1.5

#: The XY plane: origin 0, normal +z, x_dir +x.
XY = PlanarSurface(np.zeros(3), np.array([0.0, 0.0, 1.0]), np.array([1.0, 0.0, 0.0]))


# ============================================================================ small input helpers
def _finite_points(value: Any, what: str, count: int | None = None) -> np.ndarray:
    """``value`` as ``(k, d)`` float64 with ``d`` 2 or 3 and finite entries.

    Raises
    ------
    InvalidInputError
        Wrong shape, NaN or inf.
    """
    try:
        P = np.array(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise InvalidInputError(f"{what} must be numbers of shape (k, 2) or (k, 3), got {value!r}") from None
    if P.ndim == 1:
        P = P[None, :]
    if P.ndim != 2 or P.shape[1] not in (2, 3) or (count is not None and P.shape[0] != count):
        shape = f"({count}, 2) or ({count}, 3)" if count is not None else "(k, 2) or (k, 3)"
        raise InvalidInputError(f"{what} must have shape {shape}, got {P.shape}")
    if not np.all(np.isfinite(P)):
        raise InvalidInputError(f"{what} must be finite, got {P.tolist()}")
    return P


def _finite(value: Any, what: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (Real, np.floating, np.integer)):
        raise InvalidInputError(f"{what} must be a finite number, got {value!r}")
    x = float(value)
    if not math.isfinite(x):
        raise InvalidInputError(f"{what} must be a finite number, got {value!r}")
    return x


def _vector3(value: Any, what: str) -> np.ndarray:
    """A finite 3-vector (objects with ``to_tuple()``, e.g. build123d vectors, are read through it)."""
    if hasattr(value, "to_tuple"):
        value = value.to_tuple()
    try:
        v = np.array(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise InvalidInputError(f"{what} must be 3 finite numbers, got {value!r}") from None
    if v.shape != (3,) or not np.all(np.isfinite(v)):
        raise InvalidInputError(f"{what} must be 3 finite numbers, got {value!r}")
    return v


def as_plane(plane: Any) -> PlanarSurface:
    """The frame of a profile as a :class:`PlanarSurface` (``u, v`` along ``x_dir`` and ``normal × x_dir``).

    Parameters
    ----------
    plane : None, PlanarSurface, (origin, normal) or (origin, normal, x_dir), or an object with
        ``origin``, ``z_dir`` and ``x_dir`` attributes (build123d's ``Plane``)
        None is the XY plane.  Without ``x_dir`` the x axis is OCCT's choice for the normal
        (:func:`coons.kernel.conics.perpendicular_direction`: +x for a +z normal).

    Raises
    ------
    InvalidInputError
        Anything else, non-finite or zero vectors, ``x_dir`` parallel to the normal.
    """
    if plane is None:
        return XY
    if isinstance(plane, PlanarSurface):
        return plane
    if all(hasattr(plane, a) for a in ("origin", "z_dir", "x_dir")):
        parts = (plane.origin, plane.z_dir, plane.x_dir)
    elif isinstance(plane, (tuple, list)) and len(plane) in (2, 3):
        parts = tuple(plane)
    else:
        raise InvalidInputError(
            f"plane must be None, a PlanarSurface, (origin, normal[, x_dir]) or a build123d Plane, got {plane!r}"
        )
    origin = _vector3(parts[0], "plane origin")
    normal = _vector3(parts[1], "plane normal")
    if not np.any(normal):
        raise InvalidInputError("plane normal must be non-zero, got (0, 0, 0)")
    x_dir = _vector3(parts[2], "plane x_dir") if len(parts) == 3 else conics.perpendicular_direction(normal)
    try:
        return PlanarSurface(origin, normal, x_dir)
    except InvalidGeometryError as exc:
        raise InvalidInputError(f"plane: {exc}") from None


# ============================================================================ segments
@dataclass(frozen=True, eq=False)
class Segment:
    """One piece of a wire: a straight line, a circular arc or a NURBS spline.

    Build segments with :meth:`line`, :meth:`arc`, :meth:`arc_through` and :meth:`spline`;
    coordinates are 2-D (plane coordinates) or 3-D (then they must lie in the profile's plane,
    which :class:`Profile` checks and turns into plane coordinates).  The segments a
    :class:`Profile` holds are all 2-D and *resolved* (``kind`` is ``"line"``, ``"arc"`` or
    ``"spline"``).

    Attributes
    ----------
    kind : str
        ``"line"``, ``"arc"``, ``"spline"``; before resolution also ``"arc_through"`` and
        ``"spline_points"``.
    points : (k, d) float64
        line: start and end; arc: the centre; arc_through: start, middle, end;
        spline_points: the points to interpolate; spline: empty.
    radius : float
        Arc radius.
    start_angle, sweep : float
        Arc start angle (radians, from the plane's ``x_dir``) and signed sweep (radians,
        ``0 < |sweep| <= 2π``, positive counter-clockwise about the plane normal).
    curve : NurbsCurve or None
        The spline.
    degree : int
        Degree of the interpolating spline (``"spline_points"``).
    """

    kind: str
    points: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))
    radius: float = 0.0
    start_angle: float = 0.0
    sweep: float = 0.0
    curve: NurbsCurve | None = None
    degree: int = 3

    def __post_init__(self) -> None:
        P = np.array(self.points, dtype=np.float64)
        P.setflags(write=False)
        object.__setattr__(self, "points", P)

    # ------------------------------------------------------------ constructors
    @classmethod
    def line(cls, start, end) -> "Segment":
        """The straight segment from ``start`` to ``end`` (2-D or 3-D points).

        Raises
        ------
        InvalidInputError
            Non-finite or wrongly shaped points, or points of different dimensions.
        """
        P = _finite_points([_point(start, "line start"), _point(end, "line end")], "line points", 2)
        return cls("line", P)

    @classmethod
    def arc(cls, center, radius: float, start_deg: float, end_deg: float) -> "Segment":
        """The arc of the circle ``center + radius (cos φ, sin φ)`` from ``start_deg`` to ``end_deg``.

        Angles are in degrees, measured in the profile plane from its ``x_dir`` towards
        ``normal × x_dir``; the arc runs counter-clockwise when ``end_deg > start_deg`` and
        clockwise otherwise.  A sweep of 360° is a full circle (split into two half arcs by
        :class:`Profile`).

        Raises
        ------
        InvalidInputError
            Non-finite values, a radius <= 0, a sweep of 0 or beyond 360°.
        """
        C = _finite_points(center, "arc center", 1)
        R = _finite(radius, "arc radius")
        if not R > 0.0:
            raise InvalidInputError(f"arc radius must be > 0, got {radius!r}")
        a0 = _finite(start_deg, "arc start_deg")
        a1 = _finite(end_deg, "arc end_deg")
        sweep = a1 - a0
        # 1e-9 degrees: round-off of a caller's 360.0 arithmetic, far below any drawn arc.
        if sweep == 0.0 or abs(sweep) > 360.0 + 1e-9:
            raise InvalidInputError(
                f"arc sweep end_deg - start_deg must be non-zero and at most 360 in magnitude, got {sweep!r}"
            )
        s = math.copysign(TWO_PI, sweep) if abs(sweep) >= 360.0 else math.radians(sweep)
        return cls("arc", C, R, math.radians(a0), s)

    @classmethod
    def arc_through(cls, start, middle, end) -> "Segment":
        """The arc from ``start`` through ``middle`` to ``end`` (three distinct, non-collinear points).

        Raises
        ------
        InvalidInputError
            Non-finite or mismatched points (collinear points are reported by :class:`Profile`,
            which knows the tolerance).
        """
        P = _finite_points(
            [_point(start, "arc_through start"), _point(middle, "arc_through middle"), _point(end, "arc_through end")],
            "arc_through points", 3,
        )
        return cls("arc_through", P)

    @classmethod
    def spline(cls, curve_or_points, degree: int = 3) -> "Segment":
        """A spline: a 2-D or 3-D :class:`NurbsCurve`, or points (``(m, 2)`` or ``(m, 3)``, ``m >= 2``) to interpolate.

        Points are interpolated by a clamped B-spline of degree ``min(degree, m - 1)`` with
        chord-length parameters (:func:`coons.kernel.fitting.interpolate_curve`, The NURBS Book
        A9.1).

        Raises
        ------
        InvalidInputError
            A curve of dimension other than 2 or 3, fewer than two points, non-finite values,
            a degree < 1.
        """
        if isinstance(curve_or_points, NurbsCurve):
            if curve_or_points.dimension not in (2, 3):
                raise InvalidInputError(f"spline curve must be 2-D or 3-D, got dimension {curve_or_points.dimension}")
            return cls("spline", np.zeros((0, curve_or_points.dimension)), curve=curve_or_points)
        P = _finite_points(curve_or_points, "spline points")
        if P.shape[0] < 2:
            raise InvalidInputError(f"spline needs at least 2 points, got {P.shape[0]}")
        if isinstance(degree, bool) or not isinstance(degree, (int, np.integer)) or degree < 1:
            raise InvalidInputError(f"spline degree must be an integer >= 1, got {degree!r}")
        return cls("spline_points", P, degree=int(degree))

    # ------------------------------------------------------------ resolved (2-D) geometry
    @property
    def dimension(self) -> int:
        """2 or 3: the dimension the segment's coordinates were given in."""
        if self.curve is not None:
            return self.curve.dimension
        return int(self.points.shape[1])

    @property
    def domain(self) -> tuple[float, float]:
        """Parameter range ``(t0, t1)`` of a resolved segment (module docstring)."""
        if self.kind == "line":
            return 0.0, float(np.linalg.norm(self.points[1] - self.points[0]))
        if self.kind == "arc":
            return 0.0, abs(self.sweep)
        if self.kind == "spline":
            return self.curve.domain  # type: ignore[union-attr]
        raise InvalidInputError(f"a {self.kind!r} segment is not resolved yet: build a Profile with it")

    def evaluate(self, t) -> np.ndarray:
        """Points of a resolved segment at parameters ``t``, ``np.shape(t) + (d,)``."""
        return self.derivatives(t, 0)[..., 0, :]

    def derivatives(self, t, order: int = 1) -> np.ndarray:
        """Point and derivatives up to ``order`` (0 or 1 for lines and arcs: any), ``np.shape(t) + (order + 1, d)``."""
        t = np.asarray(t, dtype=np.float64)
        if self.kind == "line":
            p, q = self.points
            L = float(np.linalg.norm(q - p))
            d = (q - p) / L
            out = np.zeros(t.shape + (order + 1, p.shape[0]))
            out[..., 0, :] = p + t[..., None] * d
            if order >= 1:
                out[..., 1, :] = d
            return out
        if self.kind == "arc":
            c, R, sg = self.points[0], self.radius, math.copysign(1.0, self.sweep)
            phi = self.start_angle + sg * t
            cs, sn = np.cos(phi), np.sin(phi)
            out = np.empty(t.shape + (order + 1, 2))
            cyc = [(cs, sn), (-sn, cs), (-cs, -sn), (sn, -cs)]
            for k in range(order + 1):
                a, b = cyc[k % 4]
                f = R * sg**k
                out[..., k, 0] = f * a
                out[..., k, 1] = f * b
            out[..., 0, :] += c
            return out
        if self.kind == "spline":
            return self.curve.derivatives(t, order)  # type: ignore[union-attr]
        raise InvalidInputError(f"a {self.kind!r} segment is not resolved yet: build a Profile with it")

    @property
    def start(self) -> np.ndarray:
        return self.evaluate(self.domain[0])

    @property
    def end(self) -> np.ndarray:
        return self.evaluate(self.domain[1])

    def reversed(self) -> "Segment":
        """The same resolved segment traversed backwards."""
        if self.kind == "line":
            return Segment("line", self.points[::-1])
        if self.kind == "arc":
            return Segment("arc", self.points, self.radius, self.start_angle + self.sweep, -self.sweep)
        if self.kind == "spline":
            return Segment("spline", self.points, curve=self.curve.reversed())  # type: ignore[union-attr]
        raise InvalidInputError(f"a {self.kind!r} segment is not resolved yet: build a Profile with it")

    def to_nurbs(self, plane: PlanarSurface | None = None, tol: Tolerance | None = None) -> NurbsCurve:
        """The resolved segment as an exact NURBS with the same parameter at the ends (and
        everywhere for lines and splines; arcs follow :func:`~coons.kernel.conics.angle_to_nurbs_parameter`).

        In plane coordinates (2-D) by default, in 3-D on ``plane`` when given.
        """
        if self.kind == "line":
            c = conics.nurbs_line(self.points[0], self.points[1], self.domain, tol)
        elif self.kind == "arc":
            c0 = self.points[0]
            sg = math.copysign(1.0, self.sweep)
            X = np.array([math.cos(self.start_angle), math.sin(self.start_angle)])
            Y = sg * np.array([-X[1], X[0]])
            c = conics.nurbs_arc(c0, X, Y, self.radius, 0.0, abs(self.sweep), tol=tol)
        elif self.kind == "spline":
            c = self.curve  # type: ignore[assignment]
        else:
            raise InvalidInputError(f"a {self.kind!r} segment is not resolved yet: build a Profile with it")
        if plane is None:
            return c  # type: ignore[return-value]
        return NurbsCurve(_lift(plane, c.control_points), c.knots, c.degree, c.weights)  # type: ignore[union-attr]

    def to_3d(self, plane: PlanarSurface) -> tuple[Any, tuple[float, float]]:
        """The exact 3-D curve of a resolved segment on ``plane`` and its parameter range.

        Returns
        -------
        (curve, (t0, t1))
            :class:`Line` (unit speed, from the start), :class:`Circle` (axis ``± normal`` so
            that the angle increases along the arc, ``x_dir`` towards the start, range
            ``[0, |sweep|]``) or the 3-D :class:`NurbsCurve` (range its domain); in every case
            ``curve(t) == plane(segment(t))``.
        """
        if self.kind == "line":
            p, q = _lift(plane, self.points)
            return Line(p, q - p), self.domain
        if self.kind == "arc":
            C = _lift(plane, self.points)[0]
            X, Y, Z = plane.frame
            a = self.start_angle
            x_dir = math.cos(a) * X + math.sin(a) * Y
            return Circle(C, math.copysign(1.0, self.sweep) * Z, x_dir, self.radius), self.domain
        return self.to_nurbs(plane), self.domain

    def _mapped(self, A: np.ndarray, b: np.ndarray) -> "Segment":
        """The resolved segment under the 2-D isometry ``x -> A x + b`` (``A`` orthogonal)."""
        if self.kind == "line":
            return Segment("line", self.points @ A.T + b)
        if self.kind == "arc":
            d = A @ np.array([math.cos(self.start_angle), math.sin(self.start_angle)])
            det = float(np.linalg.det(A))
            return Segment("arc", self.points @ A.T + b, self.radius, math.atan2(d[1], d[0]),
                           self.sweep * math.copysign(1.0, det))
        c: NurbsCurve = self.curve  # type: ignore[assignment]
        return Segment("spline", np.zeros((0, 2)), curve=NurbsCurve(c.control_points @ A.T + b, c.knots, c.degree, c.weights))

    def __repr__(self) -> str:
        if self.kind == "line":
            return f"Segment.line({self.points[0].tolist()}, {self.points[1].tolist()})"
        if self.kind == "arc":
            a0 = math.degrees(self.start_angle)
            return f"Segment.arc({self.points[0].tolist()}, {self.radius!r}, {a0!r}, {a0 + math.degrees(self.sweep)!r})"
        return f"Segment({self.kind!r})"


def _point(value: Any, what: str) -> np.ndarray:
    P = _finite_points(value, what, 1)
    return P[0]


def _lift(plane: PlanarSurface, uv: np.ndarray) -> np.ndarray:
    """3-D points ``(k, 3)`` of plane coordinates ``(k, 2)``."""
    uv = np.asarray(uv, dtype=np.float64)
    return plane.evaluate(uv[:, 0], uv[:, 1])


# ============================================================================ resolution into the plane
def _to_plane(plane: PlanarSurface, P: np.ndarray, tol: Tolerance, where: str) -> np.ndarray:
    """Plane coordinates ``(k, 2)`` of 2-D or 3-D points; 3-D points must lie within ``tol.linear``.

    Raises
    ------
    InvalidInputError
        A 3-D point farther than ``tol.linear`` from the plane.
    """
    if P.shape[1] == 2:
        return P.copy()
    off = np.abs(plane.implicit(P))
    k = int(np.argmax(off))
    if off[k] > tol.linear:
        raise InvalidInputError(
            f"{where} is not in the profile plane: point {P[k].tolist()} is {off[k]:.3g} from it "
            f"(tolerance {tol.linear:g})"
        )
    return plane.closest_parameters(P)


def _resolve(seg: Segment, plane: PlanarSurface, tol: Tolerance, where: str) -> Segment:
    """The segment in plane coordinates, in canonical form (line, arc or spline).

    Raises
    ------
    InvalidInputError
        Not a Segment, off the plane, collinear ``arc_through`` points, a spline that cannot be
        interpolated.
    """
    if not isinstance(seg, Segment):
        raise InvalidInputError(f"{where} must be a Segment, got {type(seg).__name__}")
    if seg.kind == "line":
        return Segment("line", _to_plane(plane, seg.points, tol, where))
    if seg.kind == "arc":
        return Segment("arc", _to_plane(plane, seg.points, tol, where), seg.radius, seg.start_angle, seg.sweep)
    if seg.kind == "arc_through":
        p, m, q = _to_plane(plane, seg.points, tol, where)
        return _circle_through(p, m, q, tol, where)
    if seg.kind == "spline":
        c = seg.curve
        if c.dimension == 3:  # type: ignore[union-attr]
            # A NURBS lies in a plane iff its control points do (convex-hull property, positive weights).
            uv = _to_plane(plane, c.control_points, tol, where)  # type: ignore[union-attr]
            c = NurbsCurve(uv, c.knots, c.degree, c.weights)  # type: ignore[union-attr]
        return Segment("spline", np.zeros((0, 2)), curve=c)
    if seg.kind == "spline_points":
        from coons.kernel.fitting import interpolate_curve

        uv = _to_plane(plane, seg.points, tol, where)
        try:
            c = interpolate_curve(uv, min(seg.degree, uv.shape[0] - 1), tol=tol)
        except InvalidInputError as exc:
            raise InvalidInputError(f"{where}: cannot interpolate the spline points ({exc})") from None
        return Segment("spline", np.zeros((0, 2)), curve=c)
    raise InvalidInputError(f"{where} has unknown kind {seg.kind!r}")


def _circle_through(p: np.ndarray, m: np.ndarray, q: np.ndarray, tol: Tolerance, where: str) -> Segment:
    """The arc from ``p`` through ``m`` to ``q`` (circumcircle; sense from the orientation of the triangle).

    Raises
    ------
    InvalidInputError
        Coincident or collinear points (the middle point within ``tol.linear`` of the chord).
    """
    chord = float(np.linalg.norm(q - p))
    a, b = m - p, q - p
    cross = float(a[0] * b[1] - a[1] * b[0])
    # The middle point's distance from the chord line: the arc's height over its chord.
    if chord <= tol.linear or float(np.linalg.norm(a)) <= tol.linear or abs(cross) / max(chord, 1e-300) <= tol.linear:
        raise InvalidInputError(
            f"{where}: arc_through points {p.tolist()}, {m.tolist()}, {q.tolist()} are coincident or collinear "
            f"(within {tol.linear:g}); expected three points on a circle"
        )
    # Circumcentre of the triangle (p, m, q) relative to p.
    aa, bb = a @ a, b @ b
    d = 2.0 * cross
    c = p + np.array([b[1] * aa - a[1] * bb, a[0] * bb - b[0] * aa]) / d
    R = float(np.mean([np.linalg.norm(p - c), np.linalg.norm(m - c), np.linalg.norm(q - c)]))
    ang = lambda x: math.atan2(x[1] - c[1], x[0] - c[0])  # noqa: E731
    a0, am, a1 = ang(p), ang(m), ang(q)
    # cross > 0: p -> m -> q turns left, the arc runs counter-clockwise.
    if cross > 0:
        sweep = (a1 - a0) % TWO_PI
    else:
        sweep = -((a0 - a1) % TWO_PI)
    return Segment("arc", c[None, :], R, a0, sweep)


# ============================================================================ pieces (polylines with error bounds)
@dataclass
class _Pieces:
    """Chords of the segments of some wires: segment ``seg``, parameters ``[ta, tb]``, wire, ring position.

    Segment data are held as arrays by kind (lines and arcs evaluate all pieces at once; only
    splines are evaluated segment by segment).
    """

    segs: list  # resolved segments, global index
    seg: np.ndarray
    ta: np.ndarray
    tb: np.ndarray
    wire: np.ndarray
    pos: np.ndarray
    ring: np.ndarray  # number of pieces in the piece's wire

    def __post_init__(self) -> None:
        n = len(self.segs)
        self.kind = np.array([{"line": 0, "arc": 1}.get(S.kind, 2) for S in self.segs], dtype=np.int64)
        self.p0 = np.zeros((n, 2))
        self.dir = np.zeros((n, 2))
        self.radius = np.zeros(n)
        self.a0 = np.zeros(n)
        self.sg = np.ones(n)
        for i, S in enumerate(self.segs):
            if S.kind == "line":
                p, q = S.points
                self.p0[i], self.dir[i] = p, (q - p) / np.linalg.norm(q - p)
            elif S.kind == "arc":
                self.p0[i], self.radius[i], self.a0[i] = S.points[0], S.radius, S.start_angle
                self.sg[i] = math.copysign(1.0, S.sweep)

    def _points(self, seg: np.ndarray, t: np.ndarray) -> np.ndarray:
        out = np.empty((seg.size, 2))
        k = self.kind[seg]
        m = k == 0
        out[m] = self.p0[seg[m]] + t[m, None] * self.dir[seg[m]]
        m = k == 1
        phi = self.a0[seg[m]] + self.sg[seg[m]] * t[m]
        out[m] = self.p0[seg[m]] + self.radius[seg[m], None] * np.stack([np.cos(phi), np.sin(phi)], axis=1)
        for s in np.unique(seg[k == 2]):
            m = seg == s
            out[m] = self.segs[int(s)].evaluate(t[m])
        return out

    def chords(self, seg: np.ndarray, ta: np.ndarray, tb: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """End points ``(n, 2)`` and error bounds ``(n,)`` of chords over ``[ta, tb]`` of ``seg``."""
        A, B = self._points(seg, ta), self._points(seg, tb)
        k = self.kind[seg]
        E = np.where(k == 1, self.radius[seg] * (1.0 - np.cos(0.5 * np.abs(tb - ta))), 0.0)
        for s in np.unique(seg[k == 2]):
            m = seg == s
            a, b = ta[m], tb[m]
            T = a[:, None] + (b - a)[:, None] * np.array([0.25, 0.5, 0.75])
            Q = self.segs[int(s)].evaluate(T)  # (k, 3, 2)
            E[m] = _SPLINE_ERROR_FACTOR * np.max(_point_segment_distance(Q, A[m][:, None, :], B[m][:, None, :]), axis=1)
        return A, B, E


def _initial_breaks(S: Segment) -> np.ndarray:
    t0, t1 = S.domain
    if S.kind == "line":
        return np.array([t0, t1])
    if S.kind == "arc":
        n = max(1, math.ceil(abs(S.sweep) / _ARC_PIECE))
        return np.linspace(t0, t1, n + 1)
    k = np.unique(S.curve.knots)  # type: ignore[union-attr]
    k = k[(k >= t0) & (k <= t1)]
    f = np.linspace(0.0, 1.0, _SPLINE_PIECES + 1)[:-1]
    return np.append((k[:-1, None] + np.diff(k)[:, None] * f).ravel(), t1)


def _pieces(wires: Sequence[Sequence[Segment]]) -> _Pieces:
    segs, seg, ta, tb, wire, pos, ring = [], [], [], [], [], [], []
    for w, segments in enumerate(wires):
        start = len(seg)
        for S in segments:
            br = _initial_breaks(S)
            n = br.size - 1
            seg += [len(segs)] * n
            segs.append(S)
            ta += br[:-1].tolist()
            tb += br[1:].tolist()
        n_w = len(seg) - start
        wire += [w] * n_w
        pos += list(range(n_w))
        ring += [n_w] * n_w
    return _Pieces(segs, *(np.asarray(a) for a in (seg, ta, tb)), *(np.asarray(a, dtype=np.int64) for a in (wire, pos, ring)))


def _point_segment_distance(P: np.ndarray, A: np.ndarray, B: np.ndarray) -> np.ndarray:
    """Distance from points ``P`` to segments ``[A, B]`` (broadcast), ``(...,)``."""
    d = B - A
    dd = np.einsum("...i,...i->...", d, d)
    s = np.einsum("...i,...i->...", P - A, d) / np.where(dd > 0.0, dd, 1.0)
    s = np.clip(s, 0.0, 1.0)
    return np.linalg.norm(P - (A + s[..., None] * d), axis=-1)


def _orient(a: np.ndarray, b: np.ndarray, c: np.ndarray) -> np.ndarray:
    return (b[..., 0] - a[..., 0]) * (c[..., 1] - a[..., 1]) - (b[..., 1] - a[..., 1]) * (c[..., 0] - a[..., 0])


def _segment_distance(A0, A1, B0, B1) -> np.ndarray:
    """Distance between 2-D segments ``[A0, A1]`` and ``[B0, B1]``, ``(n,)`` (0 when they properly cross)."""
    d = np.minimum.reduce([
        _point_segment_distance(A0, B0, B1), _point_segment_distance(A1, B0, B1),
        _point_segment_distance(B0, A0, A1), _point_segment_distance(B1, A0, A1),
    ])
    cross = (_orient(A0, A1, B0) * _orient(A0, A1, B1) < 0.0) & (_orient(B0, B1, A0) * _orient(B0, B1, A1) < 0.0)
    return np.where(cross, 0.0, d)


def _candidate_pairs(lo: np.ndarray, hi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Index pairs ``i < j`` (in sorted order) of boxes ``[lo, hi]`` ``(n, 2)`` that overlap: sweep and prune on x."""
    order = np.argsort(lo[:, 0], kind="stable")
    xs = lo[order, 0]
    stop = np.searchsorted(xs, hi[order, 0], side="right")
    first = np.arange(order.size) + 1
    counts = np.maximum(stop - first, 0)
    i = np.repeat(np.arange(order.size), counts)
    offsets = np.arange(counts.sum()) - np.repeat(np.cumsum(counts) - counts, counts)
    j = np.repeat(first, counts) + offsets
    a, b = order[i], order[j]
    keep = (lo[a, 1] <= hi[b, 1]) & (lo[b, 1] <= hi[a, 1])
    return a[keep], b[keep]


def _first_contact(P: _Pieces, tol: Tolerance) -> tuple[int, int, np.ndarray] | None:
    """The first pair of segments found within ``tol.linear`` of each other (neighbours excluded).

    Returns ``(segment_a, segment_b, point)`` with global segment indices, or None.
    """
    A, B, E = P.chords(P.seg, P.ta, P.tb)
    pad = E[:, None] + 0.5 * tol.linear
    lo, hi = np.minimum(A, B) - pad, np.maximum(A, B) + pad
    i, j = _candidate_pairs(lo, hi)
    same = P.wire[i] == P.wire[j]
    gap = np.mod(P.pos[j] - P.pos[i], P.ring[i])
    neighbour = same & ((gap == 1) | (gap == P.ring[i] - 1))
    i, j = i[~neighbour], j[~neighbour]
    sa, a0, a1 = P.seg[i], P.ta[i], P.tb[i]
    sb, b0, b1 = P.seg[j], P.ta[j], P.tb[j]
    for _ in range(_MAX_LEVELS):
        if sa.size == 0:
            return None
        A0, A1, ea = P.chords(sa, a0, a1)
        B0, B1, eb = P.chords(sb, b0, b1)
        d = _segment_distance(A0, A1, B0, B1)
        keep = d <= ea + eb + tol.linear
        fine = (ea + eb) <= 0.5 * tol.linear
        hit = np.flatnonzero(keep & fine & (d <= tol.linear))
        if hit.size:
            k = int(hit[0])
            return int(sa[k]), int(sb[k]), 0.5 * (A0[k] + A1[k])
        go = keep & ~fine
        sa, a0, a1, sb, b0, b1, ea, eb = (x[go] for x in (sa, a0, a1, sb, b0, b1, ea, eb))
        # Halve each side whose chord is not exact (lines stay whole).
        am, bm = 0.5 * (a0 + a1), 0.5 * (b0 + b1)
        split_a, split_b = ea > 0.0, eb > 0.0
        ka = np.where(split_a, 2, 1)
        kb = np.where(split_b, 2, 1)
        n = ka * kb
        idx = np.repeat(np.arange(sa.size), n)
        r = np.arange(n.sum()) - np.repeat(np.cumsum(n) - n, n)
        ia = np.where(split_a[idx], r // kb[idx], 0)
        ib = np.where(split_b[idx], r % kb[idx], 0)
        na0 = np.where(split_a[idx] & (ia == 1), am[idx], a0[idx])
        na1 = np.where(split_a[idx] & (ia == 0), am[idx], a1[idx])
        nb0 = np.where(split_b[idx] & (ib == 1), bm[idx], b0[idx])
        nb1 = np.where(split_b[idx] & (ib == 0), bm[idx], b1[idx])
        sa, sb = sa[idx], sb[idx]
        a0, a1, b0, b1 = na0, na1, nb0, nb1
    if sa.size:  # undecided after _MAX_LEVELS halvings: the curves are within round-off of each other
        A0, A1, _ = P.chords(sa[:1], a0[:1], a1[:1])
        return int(sa[0]), int(sb[0]), 0.5 * (A0[0] + A1[0])
    return None


def _polyline(segments: Sequence[Segment], max_error: float) -> np.ndarray:
    """Closed polyline ``(k, 2)`` (last point omitted) of a wire, chord error below ``max_error``."""
    P = _pieces([segments])
    seg, ta, tb = P.seg, P.ta, P.tb
    for _ in range(_MAX_LEVELS):
        _, _, E = P.chords(seg, ta, tb)
        big = E > max_error
        if not big.any():
            break
        mid = 0.5 * (ta + tb)
        rep = np.where(big, 2, 1)
        first = np.cumsum(rep) - rep
        n = int(rep.sum())
        nseg, nta, ntb = np.empty(n, np.int64), np.empty(n), np.empty(n)
        nseg[first], nta[first], ntb[first] = seg, ta, np.where(big, mid, tb)
        second = first[big] + 1
        nseg[second], nta[second], ntb[second] = seg[big], mid[big], tb[big]
        seg, ta, tb = nseg, nta, ntb
    A, _, _ = P.chords(seg, ta, tb)
    return A


def _crossing_number(q: np.ndarray, ring: np.ndarray) -> bool:
    """Point ``q`` inside the closed polyline ``ring`` (even–odd rule)."""
    a, b = ring, np.roll(ring, -1, axis=0)
    up = (a[:, 1] <= q[1]) != (b[:, 1] <= q[1])
    with np.errstate(divide="ignore", invalid="ignore"):
        x = a[:, 0] + (q[1] - a[:, 1]) * (b[:, 0] - a[:, 0]) / (b[:, 1] - a[:, 1])
    return bool(np.count_nonzero(up & (x > q[0])) % 2)


def _inside(q: np.ndarray, segments: Sequence[Segment], tol: Tolerance) -> bool:
    """Whether ``q`` (farther than ``tol.linear`` from the wire) is inside the wire."""
    P = _pieces([segments])
    A, B, E = P.chords(P.seg, P.ta, P.tb)
    err = float(E.max(initial=0.0))
    for _ in range(_MAX_LEVELS):
        ring = _polyline(segments, err) if err > 0.0 else A
        d = float(np.min(_point_segment_distance(q, ring, np.roll(ring, -1, axis=0))))
        if err <= 0.5 * d or err <= 0.25 * tol.linear:
            return _crossing_number(q, ring)
        err = 0.25 * d
    return _crossing_number(q, ring)


# ============================================================================ integrals
def _moments(segments: Sequence[Segment]) -> np.ndarray:
    """``(A, Sx, Sy, L)``: signed area, first moments ``∬ x``, ``∬ y`` (Green) and length of a closed wire.

    ``A = ½∮(x dy − y dx)``, ``∬x = ½∮x² dy``, ``∬y = −½∮y² dx``: closed forms for lines,
    Gauss–Legendre per piece elsewhere (arcs cut into pieces of at most π/4, splines per knot
    span), exact to round-off.
    """
    out = np.zeros(4)
    lines = np.array([S.points for S in segments if S.kind == "line"]).reshape(-1, 2, 2)
    if lines.size:
        (x0, y0), (x1, y1) = lines[:, 0].T, lines[:, 1].T
        out += [
            0.5 * np.sum(x0 * y1 - x1 * y0),
            np.sum((y1 - y0) * (x0 * x0 + x0 * x1 + x1 * x1)) / 6.0,
            -np.sum((x1 - x0) * (y0 * y0 + y0 * y1 + y1 * y1)) / 6.0,
            np.sum(np.hypot(x1 - x0, y1 - y0)),
        ]
    for S in segments:
        if S.kind == "line":
            continue
        br = _quadrature_breaks(S)
        lo, hi = br[:-1], br[1:]
        h = 0.5 * (hi - lo)
        t = (lo[:, None] + h[:, None] * (_XG + 1.0)).ravel()
        w = (h[:, None] * _WG).ravel()
        D = S.derivatives(t, 1)
        x, y, dx, dy = D[:, 0, 0], D[:, 0, 1], D[:, 1, 0], D[:, 1, 1]
        out += [
            0.5 * np.sum(w * (x * dy - y * dx)),
            0.5 * np.sum(w * x * x * dy),
            -0.5 * np.sum(w * y * y * dx),
            np.sum(w * np.hypot(dx, dy)),
        ]
    return out


def _quadrature_breaks(S: Segment) -> np.ndarray:
    """Pieces on which Gauss–Legendre integrates the Green integrands of a segment to round-off."""
    t0, t1 = S.domain
    if S.kind == "arc":
        return np.linspace(t0, t1, max(1, math.ceil(abs(S.sweep) / (math.pi / 4))) + 1)
    if S.kind == "spline":
        k = np.unique(S.curve.knots)  # type: ignore[union-attr]
        return k[(k >= t0) & (k <= t1)]
    return np.array([t0, t1])


def _reverse_wire(wire: Sequence[Segment]) -> tuple[Segment, ...]:
    return tuple(s.reversed() for s in reversed(wire))


# ============================================================================ the profile
def _split(S: Segment) -> tuple[Segment, Segment]:
    """Two halves of a resolved arc or spline (a full circle, or the only segment of a wire)."""
    if S.kind == "arc":
        h = 0.5 * S.sweep
        return (Segment("arc", S.points, S.radius, S.start_angle, h), Segment("arc", S.points, S.radius, S.start_angle + h, h))
    if S.kind == "spline":
        a, b = S.domain
        c0, c1 = S.curve.split(0.5 * (a + b))  # type: ignore[union-attr]
        return Segment("spline", S.points, curve=c0), Segment("spline", S.points, curve=c1)
    raise InvalidInputError("a closed wire needs at least two segments; a single line cannot close")


def _wire_name(w: int) -> str:
    return "the outer wire" if w == 0 else f"hole {w - 1}"


@dataclass(frozen=True, eq=False)
class Profile:
    """A planar region: one outer wire and any number of hole wires in a plane (module docstring).

    Parameters
    ----------
    outer : sequence of Segment
        A closed chain: each segment starts where the previous one ends (within ``tol.linear``)
        and the last ends where the first starts.
    holes : sequence of sequences of Segment
    plane : see :func:`as_plane`; default the XY plane
    tol : Tolerance, optional

    Attributes
    ----------
    outer : tuple of Segment
        Resolved 2-D segments, counter-clockwise seen from the plane normal.
    holes : tuple of tuples of Segment
        Clockwise.
    plane : PlanarSurface
    tol : Tolerance

    Raises
    ------
    InvalidInputError
        Any check of the module docstring failing, with the wire, the segment index (as given)
        and the point.

    Examples
    --------
    >>> p = Profile.rectangle(4, 2).with_hole(Profile.circle(0.5))
    >>> bool(abs(p.area - (8 - math.pi * 0.25)) < 1e-12), len(p.outer), len(p.holes[0])
    (True, 4, 2)
    """

    outer: tuple
    holes: tuple = ()
    plane: Any = None
    tol: Any = None
    _trusted: InitVar[bool] = False

    def __post_init__(self, _trusted: bool) -> None:
        t = resolve(self.tol)
        object.__setattr__(self, "tol", t)
        object.__setattr__(self, "plane", as_plane(self.plane))
        if _trusted:
            object.__setattr__(self, "outer", tuple(self.outer))
            object.__setattr__(self, "holes", tuple(tuple(h) for h in self.holes))
            return
        wires = _as_wires(self.outer, self.holes)
        resolved = [_prepare_wire(w, i, self.plane, t) for i, w in enumerate(wires)]
        wire_segs = [r[0] for r in resolved]
        index_maps = [r[1] for r in resolved]
        # Orientation: outer counter-clockwise (positive area), holes clockwise.
        for w in range(len(wire_segs)):
            A, _, _, L = _moments(wire_segs[w])
            if not abs(A) > t.linear * L:
                raise InvalidInputError(
                    f"{_wire_name(w)} encloses zero area ({A:.3g} for a length of {L:.3g}; it must exceed "
                    f"tol.linear x length = {t.linear * L:.3g})"
                )
            if (A > 0) != (w == 0):
                wire_segs[w] = _reverse_wire(wire_segs[w])
                index_maps[w] = index_maps[w][::-1]
        _check_intersections(wire_segs, index_maps, t)
        _check_nesting(wire_segs, t)
        object.__setattr__(self, "outer", wire_segs[0])
        object.__setattr__(self, "holes", tuple(wire_segs[1:]))

    # ------------------------------------------------------------ constructors
    @classmethod
    def from_wires(cls, outer: Sequence[Segment], holes: Sequence[Sequence[Segment]] = (), plane: Any = None,
                   tol: Tolerance | None = None) -> "Profile":
        """The profile bounded by ``outer`` with ``holes`` (see the class docstring)."""
        return cls(outer, holes, plane, tol)

    @classmethod
    def polygon(cls, points, plane: Any = None, tol: Tolerance | None = None) -> "Profile":
        """The polygon through ``points`` ``(k, 2)`` or ``(k, 3)``, ``k >= 3`` (a repeated first point at the end is dropped).

        Raises
        ------
        InvalidInputError
            Fewer than 3 distinct points, non-finite coordinates, and the checks of the class.
        """
        P = _finite_points(points, "polygon points")
        if P.shape[0] >= 2 and np.array_equal(P[0], P[-1]):
            P = P[:-1]
        if P.shape[0] < 3:
            raise InvalidInputError(f"polygon needs at least 3 points, got {P.shape[0]}")
        return cls([Segment.line(P[i], P[(i + 1) % len(P)]) for i in range(len(P))], (), plane, tol)

    @classmethod
    def rectangle(cls, width: float, height: float, center=(0.0, 0.0), plane: Any = None,
                  tol: Tolerance | None = None) -> "Profile":
        """The axis-parallel (in plane coordinates) rectangle ``width × height`` centred at ``center``.

        Raises
        ------
        InvalidInputError
            Sizes that are not finite and > 0, a bad centre, and the checks of the class.
        """
        w, h = _finite(width, "width"), _finite(height, "height")
        if not (w > 0 and h > 0):
            raise InvalidInputError(f"rectangle sizes must be > 0, got width={width!r}, height={height!r}")
        c = _finite_points(center, "rectangle center", 1)[0][:2]
        d = np.array([[-w, -h], [w, -h], [w, h], [-w, h]]) * 0.5 + c
        return cls.polygon(d, plane, tol)

    @classmethod
    def circle(cls, radius: float, center=(0.0, 0.0), plane: Any = None, tol: Tolerance | None = None) -> "Profile":
        """The disk of ``radius`` about ``center`` (plane coordinates): two half arcs from angle 0.

        Raises
        ------
        InvalidInputError
            A radius that is not finite and > 0, a bad centre.
        """
        return cls([Segment.arc(center, radius, 0.0, 360.0)], (), plane, tol)

    def with_hole(self, hole) -> "Profile":
        """This profile with one more hole: a wire (sequence of Segment) or a coplanar :class:`Profile` without holes.

        Raises
        ------
        InvalidInputError
            A profile with holes of its own, a profile in another plane, and the checks of the class.
        """
        if isinstance(hole, Profile):
            if hole.holes:
                raise InvalidInputError(
                    f"with_hole: the hole profile has {len(hole.holes)} hole(s) of its own; an island inside a hole "
                    "is a separate profile"
                )
            A, b = _plane_map(hole.plane, self.plane, self.tol)
            wire = tuple(s._mapped(A, b) for s in hole.outer)
        else:
            wire = tuple(hole)
        return Profile(self.outer, self.holes + (wire,), self.plane, self.tol)

    # ------------------------------------------------------------ queries
    @property
    def wires(self) -> tuple[tuple[Segment, ...], ...]:
        """The outer wire followed by the holes."""
        return (self.outer,) + self.holes

    @property
    def normal(self) -> np.ndarray:
        """The plane normal ``(3,)``: the outer wire runs counter-clockwise about it."""
        return self.plane.axis

    @property
    def area(self) -> float:
        """Area of the region (outer area minus the holes')."""
        return float(sum(_moments(w)[0] for w in self.wires))

    @property
    def centroid(self) -> np.ndarray:
        """Centroid of the region in 3-D, ``(3,)`` (Green's theorem, exact to round-off)."""
        m = np.sum([_moments(w)[:3] for w in self.wires], axis=0)
        return self.plane.evaluate(m[1] / m[0], m[2] / m[0])

    def vertices(self) -> list[np.ndarray]:
        """Per wire, the 3-D start points of its segments, ``(k, 3)``."""
        return [_lift(self.plane, np.array([s.start for s in w])) for w in self.wires]

    def flipped(self) -> "Profile":
        """The same region described in the plane with the opposite normal (``v -> -v``), wires re-oriented."""
        X, Y, Z = self.plane.frame
        plane = PlanarSurface(self.plane.origin, -Z, X)
        A = np.diag([1.0, -1.0])
        b = np.zeros(2)
        wires = [_reverse_wire([s._mapped(A, b) for s in w]) for w in self.wires]
        return Profile(wires[0], tuple(wires[1:]), plane, self.tol, True)

    def __repr__(self) -> str:
        return f"Profile(segments={len(self.outer)}, holes={len(self.holes)}, area={self.area:.6g})"


def _plane_map(src: PlanarSurface, dst: PlanarSurface, tol: Tolerance) -> tuple[np.ndarray, np.ndarray]:
    """The 2-D isometry ``uv_dst = A uv_src + b`` between coplanar frames.

    Raises
    ------
    InvalidInputError
        The planes are not the same plane (normals not parallel within ``tol.angular``, or the
        source origin farther than ``tol.linear`` from the destination plane).
    """
    sine = float(np.linalg.norm(np.cross(src.axis, dst.axis)))
    off = abs(float(dst.implicit(src.origin)))
    if sine > tol.angular or off > tol.linear:
        raise InvalidInputError(
            f"with_hole: the hole's plane is not the profile's plane (normals {src.axis.tolist()} and "
            f"{dst.axis.tolist()}, origin {off:.3g} off the plane)"
        )
    Xs, Ys, _ = src.frame
    Xd, Yd, _ = dst.frame
    A = np.array([[Xs @ Xd, Ys @ Xd], [Xs @ Yd, Ys @ Yd]])
    b = dst.closest_parameters(src.origin)
    return A, b


def _as_wires(outer: Any, holes: Any) -> list[list[Segment]]:
    def wire(w: Any, what: str) -> list[Segment]:
        if isinstance(w, Segment) or not isinstance(w, Sequence) or isinstance(w, str):
            raise InvalidInputError(f"{what} must be a sequence of Segment, got {type(w).__name__}")
        if len(w) == 0:
            raise InvalidInputError(f"{what} is empty")
        return list(w)

    if isinstance(holes, Sequence) and not isinstance(holes, str):
        hole_list = list(holes)
    else:
        raise InvalidInputError(f"holes must be a sequence of wires, got {type(holes).__name__}")
    return [wire(outer, "outer wire")] + [wire(h, f"hole {k}") for k, h in enumerate(hole_list)]


def _prepare_wire(segments: list[Segment], w: int, plane: PlanarSurface, t: Tolerance) -> tuple[tuple[Segment, ...], list[int]]:
    """Resolve, split full circles and single closed segments, check lengths, closure and fold-backs.

    Returns the resolved segments and, for each, the index of the user's segment it comes from.
    """
    name = _wire_name(w)
    out: list[Segment] = []
    index: list[int] = []
    for i, s in enumerate(segments):
        r = _resolve(s, plane, t, f"segment {i} of {name}")
        t0, t1 = r.domain
        size = (t1 - t0) if r.kind != "arc" else r.radius * abs(r.sweep)
        if r.kind == "spline":
            Q = r.curve.control_points  # type: ignore[union-attr]
            size = float(np.max(np.linalg.norm(Q - Q[0], axis=1)))
        if not size > t.linear:
            raise InvalidInputError(
                f"segment {i} of {name} is degenerate: its size {size:.3g} is not above tol.linear = {t.linear:g}"
            )
        if r.kind == "arc" and abs(r.sweep) >= TWO_PI - t.solver * TWO_PI:
            out += list(_split(Segment("arc", r.points, r.radius, r.start_angle, math.copysign(TWO_PI, r.sweep))))
            index += [i, i]
        else:
            out.append(r)
            index.append(i)
    if len(out) == 1:
        out = list(_split(out[0]))
        index = index * 2
    n = len(out)
    for k in range(n):
        a, b = out[k], out[(k + 1) % n]
        gap = float(np.linalg.norm(a.end - b.start))
        if gap > t.linear:
            raise InvalidInputError(
                f"{name} is not closed: segment {index[k]} ends at {a.end.tolist()} but segment "
                f"{index[(k + 1) % n]} starts at {b.start.tolist()} (gap {gap:.3g} > tol.linear = {t.linear:g})"
            )
    # Shared vertices: a curve's end point where a curve meets a line, so that lines (rebuilt
    # between their vertices) join their neighbours exactly; curves keep their own end points,
    # which are within tol.linear of the vertex.
    vert = [out[k].start if (out[k].kind != "line" or out[k - 1].kind == "line") else out[k - 1].end for k in range(n)]
    for k in range(n):
        if out[k].kind == "line":
            out[k] = Segment("line", np.stack([vert[k], vert[(k + 1) % n]]))
    for k in range(n):
        a, b = out[k], out[(k + 1) % n]
        da = a.derivatives(a.domain[1], 1)[1]
        db = b.derivatives(b.domain[0], 1)[1]
        na, nb = float(np.linalg.norm(da)), float(np.linalg.norm(db))
        if na > 0 and nb > 0:
            cos = float(da @ db) / (na * nb)
            sine = abs(float(da[0] * db[1] - da[1] * db[0])) / (na * nb)
            if cos < 0 and sine <= t.angular:
                raise InvalidInputError(
                    f"{name} folds back on itself where segment {index[k]} meets segment {index[(k + 1) % n]} "
                    f"at {b.start.tolist()} (the tangents are opposite)"
                )
    return tuple(out), index


def _check_intersections(wires: list[tuple[Segment, ...]], index_maps: list[list[int]], t: Tolerance) -> None:
    """Raise when two segments of the profile cross or touch (neighbours in a wire excepted)."""
    P = _pieces(wires)
    hit = _first_contact(P, t)
    if hit is None:
        return
    sa, sb, point = hit
    owner = np.repeat(np.arange(len(wires)), [len(w) for w in wires])
    first = np.concatenate([[0], np.cumsum([len(w) for w in wires])])
    wa, wb = int(owner[sa]), int(owner[sb])
    ia, ib = index_maps[wa][sa - first[wa]], index_maps[wb][sb - first[wb]]
    at = f"near {np.round(point, 12).tolist()}"
    if wa == wb:
        what = f"its segment {ia} crosses or touches itself" if ia == ib else f"its segments {ia} and {ib} cross or touch"
        raise InvalidInputError(f"{_wire_name(wa)} intersects itself: {what} {at}")
    raise InvalidInputError(
        f"{_wire_name(wa)} and {_wire_name(wb)} cross or touch: segment {ia} of {_wire_name(wa)} meets segment "
        f"{ib} of {_wire_name(wb)} {at}"
    )


def _check_nesting(wires: list[tuple[Segment, ...]], t: Tolerance) -> None:
    """Holes strictly inside the outer wire and not inside each other (no wire touches another here)."""
    for h in range(1, len(wires)):
        q = wires[h][0].start
        if not _inside(q, wires[0], t):
            raise InvalidInputError(f"hole {h - 1} is not inside the outer wire (its start point {q.tolist()} is outside)")
    if len(wires) < 3:
        return
    # A hole's start point can only lie inside another hole if it lies inside that hole's
    # bounding box, and the box test is one array operation for all pairs: only the pairs it
    # keeps need the exact inside test (a grid of holes keeps none).
    lo, hi = _wire_boxes(wires[1:], t)
    q = np.array([w[0].start for w in wires[1:]])
    maybe = np.all((q[:, None, :] >= lo[None, :, :]) & (q[:, None, :] <= hi[None, :, :]), axis=2)
    np.fill_diagonal(maybe, False)
    for h, g in zip(*np.nonzero(maybe)):
        if _inside(q[h], wires[g + 1], t):
            raise InvalidInputError(f"hole {h} lies inside hole {g}; holes must not overlap")


def _wire_boxes(wires: Sequence[Sequence[Segment]], t: Tolerance) -> tuple[np.ndarray, np.ndarray]:
    """Boxes ``(lo, hi)``, each ``(k, 2)``, that contain each wire: its chords widened by their error bound."""
    lo, hi = [], []
    for w in wires:
        P = _pieces([w])
        A, B, E = P.chords(P.seg, P.ta, P.tb)
        pts = np.concatenate([A, B])
        margin = float(E.max(initial=0.0)) + t.linear
        lo.append(pts.min(axis=0) - margin)
        hi.append(pts.max(axis=0) + margin)
    return np.array(lo), np.array(hi)
