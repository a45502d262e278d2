"""Surface–surface intersection: the result types, the dispatcher, and exact forms for analytic pairs.

:func:`intersect_surfaces` returns the intersection curves (each with its two p-curves on the
same parameter) and the isolated contact points of two surfaces inside two parameter boxes.
Pairs of analytic surfaces whose intersection is a set of conics are solved in closed form
here: plane–plane (line); plane–cylinder (circle, 0/1/2 rulings, ellipse); plane–cone
(circle, rulings through the apex, ellipse, and parabola/hyperbola as exact rational
quadratic arcs within the boxes); every pair of surfaces of revolution about a common axis,
planes perpendicular to that axis and spheres (symmetric about any line through their
centre) included, by intersecting their meridians in a half-plane (circles at the heights
where the meridians meet: plane–sphere, sphere–sphere, plane–torus perpendicular to its axis,
sphere–cylinder/cone/torus centred on the axis, coaxial cylinders, cones and tori); a plane
containing a torus' axis (two meridian circles); cylinders with parallel axes; cylinders
of equal radius whose axes meet (two ellipses in the bisecting planes, crossing at two singular
points where each is cut, ``_equal_cylinders``); and crossing cylinders (any radii, axes meeting
or skew) where every ruling of one crosses the other clearly (``_crossing_cylinders``: two
disjoint closed loops, each a graph ``s(θ)`` over the thinner one's angle, in closed form; the
curve and its p-curves are quintic splines fitted to them).  Every other pair (crossing cylinders
where one only partly pierces the other or nearly touches it, oblique plane–torus, non-coaxial
quadrics, NURBS surfaces) goes to the general marching method of :mod:`coons.kernel.ssi`.
This module deliberately does not march, does not resolve overlaps of coincident surfaces (it reports
``coincident=True``; the caller handles the overlap), and does not trim to faces: it clips
to the parameter boxes it is given.

Conventions
-----------
*Boxes.*  ``box = ((u0, u1), (v0, v1))``; the default is the surface's ``domain`` (infinite in
the linear directions of planes, cylinders and cones, so straight and parabolic/hyperbolic
branches need finite boxes).  Every returned branch lies in both boxes; a branch leaving a box
is cut where its p-curve crosses the box boundary.  Periodic coordinates of a p-curve are
shifted by whole periods into the box.  A box spanning a whole period or more of a periodic
coordinate has a seam at its lower bound: a branch is cut where it crosses the seam (the
p-curve must not leave the box), so a closed curve is one closed branch only where it crosses
no seam except at its start; e.g. a circle around a cylinder with box ``u ∈ [0, 2π]`` is one
closed branch from ``u = 0`` to ``u = 2π``.  Where a p-curve coordinate crosses a box bound is
found in closed form for exact coordinates and for a conic's longitude on a cylinder, sphere or
torus (where it meets the meridian half-plane, ``_conic_crossings``); other coordinates are
searched on a grid and the brackets solved by the Illinois method (``_illinois``).

*P-curves.*  A coordinate of a p-curve is exactly ``o + d t + α cos t + β sin t`` in closed form
for a line or conic in a plane and a circle coaxial with a surface of revolution (``_closed_coords``);
otherwise it is detected to be of that form by a least-squares fit on samples whose residual is
at round-off, ``tol.solver`` relative;
when both coordinates are affine in ``t`` the p-curve is a :class:`~coons.kernel.pcurve.Line2D`,
when both are trigonometric a :class:`~coons.kernel.pcurve.Trig2D`.  Otherwise (an ellipse on
a cylinder or cone, oblique circles on a sphere, conic arcs on a cone) it is a quintic 2-D
:class:`~coons.kernel.curve.NurbsCurve` interpolating the exact parameters (The NURBS Book
A9.1) on the branch's own parameter, refined until its image is within ``tol.linear / 2`` of
the curve; the plane's p-curve of a rational conic arc is exact (same weights).  Every fit starts
from the same graded samples mapped onto its range, where the collocation is one fixed matrix
(``_first_round``); the refined rounds solve theirs with scipy.  The loops of
crossing cylinders have no conic form: their 3-D curve and both p-curves are one quintic spline fitted
to the exact points and parameters at the same samples (``_loop_piece``), on the parameter ``±θ``.

*Direction.*  A transversal branch runs along ``n_a × n_b``, the cross product of the
surfaces' normals ``Su × Sv`` normalised (``a`` first).  Where ``n_a × n_b`` vanishes along a whole
branch (``tangent=True``) the rule says nothing and the direction is unspecified (deterministic
for given inputs): a caller that needs one orients the branch itself.  The normals that orient a
branch are those of ``normal(closest_parameters(P))``; for planes, cylinders and spheres they are
computed in closed form (``_normals``: the same directions to round-off, without the parameter round
trip, whose per-call cost dominated the exact pairs), with the surface's own methods on a cylinder's
axis or at a sphere's centre.  A candidate that looks the same from each of its points (a circle of
coaxial planes, cylinders and spheres; a line of planes and parallel cylinders) is oriented at one
point where the surfaces cross there at a sine well above round-off and the misalignment the exact
cases tolerate (``_uniform_side``): every sample would say the same.

*Singular points.*  A circle through a pole of a sphere is cut at the pole (the longitude
jumps there): a great circle through both poles gives two meridian branches.  A ruling
through a cone's apex is cut at the apex (the cone's ``Su × Sv`` flips there, and with it the
direction rule).  The ellipses of two equal cylinders are cut at the points where they cross
(``n_a × n_b`` vanishes there and changes sign): each arc is oriented on its own.

*Cost.*  A closed-form pair costs a few hundred microseconds, mostly numpy's per-call overhead
on a handful of values: where every p-curve coordinate is exact, the branch's window is clipped
to the boxes in Python floats (``_exact_runs``), and the measured deviation evaluates the curves
without their argument checks (``_curve_points`` and its siblings); both repeat the array
expressions value for value, so the branches are the same bit for bit (fitted p-curves are sampled
by scipy's B-spline, :func:`~coons.kernel.curve.spline_points`, to round-off).  The numeric
coordinates of a curve on a surface (their samples, unwrapping grid and box crossings) are
remembered per surface for curves equal in value (``_coords``): the several face pairs of two
surfaces (a sphere's halves against another sphere's) find one curve and differ only by their
boxes.  Many plane–cylinder pairs with the plane perpendicular to the axis (a plate against the
walls of its holes) are solved together by ``_plane_cylinder_circles`` in array passes (the Booleans' phase 3 calls
it); it takes only pairs clear of every near-tie and leaves the rest to this dispatcher.

*Tolerances.*  ``tol.linear`` decides tangency, coincidence and whether a curve passes
through a pole or apex; ``tol.angular`` decides parallel directions.  Each branch records the
largest deviation measured between its curve and its two p-curve images (round-off for exact
forms, below ``tol.linear`` for fitted p-curves).

Sources: the closed forms are classical plane sections of the natural quadrics and coaxial
pairs (Miller & Goldman, "Geometric algorithms for detecting and calculating all conic
sections in the intersection of any two natural quadric surfaces", Graphical Models and
Image Processing 57(1), 1995; the reduction of coaxial pairs to meridian intersections is
also how OCCT's ``IntAna_QuadQuadGeo`` treats them); conic arcs: The NURBS Book A7.3.
"""

from __future__ import annotations

import functools
import math
import weakref
from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy.interpolate import make_interp_spline

from coons.errors import ConvergenceError, InvalidGeometryError, InvalidInputError
from coons.kernel.analytic import (
    Circle,
    ConicalSurface,
    CylindricalSurface,
    Ellipse,
    Line,
    PlanarSurface,
    SphericalSurface,
    ToroidalSurface,
    _angle,
)
from coons.kernel._common import interval_cuts, row_norms
from coons.kernel.conics import nurbs_conic_arc, perpendicular_direction
from coons.kernel.curve import NurbsCurve, spline_points
from coons.kernel.fitting import _averaging
from coons.kernel.pcurve import Line2D, Trig2D
from coons.tolerance import Tolerance, resolve

__all__ = ["IntersectionCurve", "SurfaceIntersection", "intersect_surfaces"]

TWO_PI = 2.0 * math.pi
_EPS = float(np.finfo(np.float64).eps)
_REVOLVED = (CylindricalSurface, ConicalSurface, SphericalSurface, ToroidalSurface)
_ANALYTIC = (PlanarSurface,) + _REVOLVED

#: Samples of the least-squares detection of exact p-curve coordinates (4 unknowns; the rest
#: over-determine the fit so that a non-trigonometric coordinate cannot pass).
_FORM_SAMPLES = 24
#: Grid of the bracketing search for box crossings of coordinates that have no closed form:
#: a coordinate of a conic section changes monotonically between at most a few extrema per
#: turn, so 512 samples bracket every crossing that is not a tangency.
_SEARCH_SAMPLES = 512
#: Steps of the bracketed root solver (_illinois): bisection alone would reach the spacing of doubles
#: within 2^-64 of a bracket of at most 2π.
_ROOT_STEPS = 64
#: Surfaces of revolution whose longitude is the azimuth about the axis (closed-form crossings, _conic_crossings).
_AZIMUTHAL = (CylindricalSurface, SphericalSurface, ToroidalSurface)
#: Relative distance (to the size of the curve and its offset from the axis) below which a conic is
#: taken to reach the axis of a surface of revolution, where its longitude is ill-conditioned: the
#: closed-form crossings leave such roots to the sampled search.
_AXIS_CLEARANCE = 1e-6
#: Closed-form crossings ``cos(t - φ) = x`` with ``1 - |x|`` within this are left to the sampled search:
#: a near-tangency, whose two roots (``2 sqrt(2 * 1e-3)`` ≈ 0.09 apart, seven grid cells) the search
#: separates too, as it did before the closed form.
_GRAZE = 1e-3
#: Samples of the axis clearance's lower bound (_axis_clear).
_CLEAR_SAMPLES = 64
#: Largest number of interpolated samples for a NURBS p-curve before giving up.
_MAX_FIT_SAMPLES = 4097
#: At most this many samples are added to one interval of a p-curve fit per round.
_MAX_FIT_SPLIT = 8
#: Degree of the fitted p-curves (:func:`_fitted_pcurve`) and of the loops of crossing cylinders
#: (:func:`_loop_piece`).  The interpolation error falls with the sixth power of the spacing at degree 5
#: (the fourth at 3): a circle on a sphere in (longitude, latitude) takes about half the knot spans (49
#: where a cubic had 115), a loop piece of the crossing cylinders 20 where it had 51, and every later
#: step — clips, splits, the checker's sampling, the shell volumes — works span by span.
_FIT_DEGREE = 5
#: Samples of a fit's first round (:func:`_fit_start`), graded towards the ends by :data:`_FIT_GRADE`:
#: ``x - g sin(2πx) / 2π`` on uniform ``x`` spaces them ``1 - g`` of the uniform spacing at the ends and
#: ``1 + g`` in the middle.  An interpolating spline errs most in its end intervals (their knots have no
#: neighbour beyond), so uniform samples that met the bound inside still failed at the ends and cost
#: another round.  Only the start: the refinement guarantees the bound.
_FIT_START = 21
_FIT_GRADE = 0.5
#: Relative inset from a sphere pole where a p-curve's longitude is taken (sqrt of double eps).
_POLE_INSET = 1.5e-8
#: Offset (1/π, irrational) of sample positions within their spacing, so that samples miss the
#: round parameters where apexes, poles and seams tend to sit.
_OFFSET = 1.0 / math.pi
#: Samples on which a branch's achieved tolerance is measured.
_CHECK_SAMPLES = 65
#: Their positions as fractions of the branch's range, ends included (an irrational offset keeps the
#: interior ones off the interpolation nodes of fitted p-curves).
_CHECK_FRACTIONS = np.concatenate([[0.0], (np.arange(_CHECK_SAMPLES) + _OFFSET) / _CHECK_SAMPLES, [1.0]])
_CHECK_FRACTIONS.setflags(write=False)
#: Rows per block of :func:`_plane_cylinder_circles`' deviation pass: its (rows, samples) temporaries of
#: a few hundred kB each stay in a core's cache.
_DEVIATION_ROWS = 256


# ---------------------------------------------------------------------------- result types
@dataclass(frozen=True, eq=False)
class IntersectionCurve:
    """One branch ``curve([t0, t1])`` of the intersection of surfaces ``a`` and ``b``.

    Attributes
    ----------
    curve : Line, Circle, Ellipse or NurbsCurve
        The 3-D curve: ``evaluate(t) -> shape + (3,)``, ``derivatives(t, order)``.
    t0, t1 : float
        The branch's parameter range, ``t0 < t1``.
    pcurve_a, pcurve_b : Line2D, Trig2D or 2-D NurbsCurve
        The p-curves on ``a`` and ``b`` with the SAME parameter:
        ``a.evaluate(*pcurve_a(t).T) ≈ curve(t)``.
    closed : bool
        ``curve(t0) == curve(t1)``: a closed loop inside both boxes.
    tol : float
        The largest measured 3-D distance between ``curve(t)``, ``a(pcurve_a(t))`` and ``b(pcurve_b(t))``.
    tangent : bool
        The surfaces are tangent along this branch.

    Raises
    ------
    InvalidInputError
        ``t0 < t1`` does not hold or either is not finite.
    """

    curve: Any
    t0: float
    t1: float
    pcurve_a: Any
    pcurve_b: Any
    closed: bool
    tol: float
    tangent: bool = False

    def __post_init__(self) -> None:
        t0, t1 = float(self.t0), float(self.t1)
        if not (math.isfinite(t0) and math.isfinite(t1) and t0 < t1):
            raise InvalidInputError(f"IntersectionCurve: need finite t0 < t1, got t0={t0!r}, t1={t1!r}")
        object.__setattr__(self, "t0", t0)
        object.__setattr__(self, "t1", t1)
        object.__setattr__(self, "tol", float(self.tol))
        object.__setattr__(self, "closed", bool(self.closed))
        object.__setattr__(self, "tangent", bool(self.tangent))

    @classmethod
    def _trusted(cls, curve: Any, t0: float, t1: float, pcurve_a: Any, pcurve_b: Any, closed: bool, tol: float,
                 tangent: bool) -> "IntersectionCurve":
        """An IntersectionCurve made without ``__post_init__``'s check and conversions, for batched
        kernel paths (:func:`_plane_cylinder_circles`: a hundred branches at about 0.4 µs each).

        Only for fields that are already what ``__post_init__`` makes of them: ``t0 < t1`` finite
        Python floats (checked by the caller for the whole batch), ``tol`` a Python float, ``closed``
        and ``tangent`` bools.  The result then equals the validated one field by field.
        """
        ic = object.__new__(cls)
        # The frozen dataclass forbids setattr; its instance dict is the one the constructor fills.
        ic.__dict__.update(curve=curve, t0=t0, t1=t1, pcurve_a=pcurve_a, pcurve_b=pcurve_b, closed=closed, tol=tol,
                           tangent=tangent)
        return ic


def _rows(a, width: int, what: str) -> np.ndarray:
    arr = np.array(a, dtype=np.float64)
    if arr.size == 0:
        arr = np.zeros((0, width))
    if arr.ndim != 2 or arr.shape[1] != width:
        raise InvalidInputError(f"SurfaceIntersection.{what}: expected shape (k, {width}), got {arr.shape}")
    arr.setflags(write=False)
    return arr


@dataclass(frozen=True, eq=False)
class SurfaceIntersection:
    """The intersection of two surfaces inside the parameter boxes asked for.

    Attributes
    ----------
    curves : tuple of IntersectionCurve
    points : (k, 3) float64
        Isolated contact points (tangent touching, e.g. a sphere on a plane).
    uv_a, uv_b : (k, 2) float64
        Their parameters on ``a`` and ``b``.
    coincident : bool
        The two surfaces are the same point set; no curves are returned, the caller handles the overlap.

    Raises
    ------
    InvalidInputError
        Arrays of the wrong shapes or of different lengths.
    """

    curves: tuple
    points: np.ndarray
    uv_a: np.ndarray
    uv_b: np.ndarray
    coincident: bool = False

    def __post_init__(self) -> None:
        object.__setattr__(self, "curves", tuple(self.curves))
        object.__setattr__(self, "points", _rows(self.points, 3, "points"))
        object.__setattr__(self, "uv_a", _rows(self.uv_a, 2, "uv_a"))
        object.__setattr__(self, "uv_b", _rows(self.uv_b, 2, "uv_b"))
        k = len(self.points)
        if len(self.uv_a) != k or len(self.uv_b) != k:
            raise InvalidInputError(
                "SurfaceIntersection: points, uv_a and uv_b need equal lengths, "
                f"got {k}, {len(self.uv_a)}, {len(self.uv_b)}"
            )

    @staticmethod
    def empty(coincident: bool = False) -> "SurfaceIntersection":
        """No curves, no points."""
        return SurfaceIntersection((), np.zeros((0, 3)), np.zeros((0, 2)), np.zeros((0, 2)), coincident)


# ---------------------------------------------------------------------------- exact cases
@dataclass(frozen=True)
class _Candidate:
    """An unclipped exact branch: the whole line, circle, ellipse, conic section of a cone or loop of crossing
    cylinders (``tangent``: the surfaces touch along it).

    ``uniform``: the pair looks the same from every point of the curve (a rotation about the common
    axis carries coaxial surfaces and their circle into themselves; a translation along a line
    carries two planes, a plane and a cylinder parallel to it, or two parallel cylinders into
    themselves), up to the tolerances the exact cases accept; :func:`_oriented` may then decide the
    direction at one point (:func:`_uniform_side`).
    """

    curve: Any
    tangent: bool = False
    uniform: bool = False
    #: Points of the curve where ``n_a × n_b`` vanishes and the branches cross (two equal cylinders'
    #: ellipses): the curve is cut there and each piece oriented on its own.
    singular: tuple = ()


@dataclass(frozen=True)
class _Exact:
    """What a closed-form case found: whole curves, contact points, or coincidence."""

    candidates: tuple = ()
    points: tuple = ()
    coincident: bool = False


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v)


def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``a × b`` of arrays ``(..., 3)`` (the same products and differences as ``np.cross``, without its
    axis handling, which costs more than the arithmetic on the few vectors here)."""
    a0, a1, a2 = a[..., 0], a[..., 1], a[..., 2]
    b0, b1, b2 = b[..., 0], b[..., 1], b[..., 2]
    out = np.empty(np.broadcast_shapes(a.shape, b.shape))
    out[..., 0] = a1 * b2 - a2 * b1
    out[..., 1] = a2 * b0 - a0 * b2
    out[..., 2] = a0 * b1 - a1 * b0
    return out


def _sine(d1: np.ndarray, d2: np.ndarray) -> float:
    """|sin| of the angle between two unit directions (Python floats: numpy's per-call cost exceeds the
    arithmetic on one pair of 3-vectors)."""
    a0, a1, a2 = d1.tolist()
    b0, b1, b2 = d2.tolist()
    return math.hypot(a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0)


def _off_axis(point: np.ndarray, origin: np.ndarray, axis: np.ndarray) -> float:
    """Distance from ``point`` to the line ``origin + s axis`` (``axis`` unit), in Python floats."""
    w0, w1, w2 = (point - origin).tolist()
    z0, z1, z2 = axis.tolist()
    h = w0 * z0 + w1 * z1 + w2 * z2
    return math.hypot(w0 - h * z0, w1 - h * z1, w2 - h * z2)


def _plane_plane(a: PlanarSurface, b: PlanarSurface, tol: Tolerance) -> _Exact:
    d = np.cross(a.axis, b.axis)
    h = float((b.origin - a.origin) @ a.axis)
    if np.linalg.norm(d) <= tol.angular:
        return _Exact(coincident=abs(h) <= tol.linear)
    # The line point closest to a's origin: n_a·x = n_a·O_a, n_b·x = n_b·O_b, d·x = d·O_a.
    M = np.stack([a.axis, b.axis, d])
    rhs = np.array([a.axis @ a.origin, b.axis @ b.origin, d @ a.origin])
    return _Exact((_Candidate(Line(np.linalg.solve(M, rhs), d), uniform=True),))


def _plane_cylinder(p: PlanarSurface, c: CylindricalSurface, tol: Tolerance) -> _Exact | None:
    n, Z, O, R = p.axis, c.axis, c.origin, c.radius
    cos = float(n @ Z)
    if abs(cos) <= tol.angular:  # axis parallel to the plane: rulings
        delta = float((O - p.origin) @ n)  # signed height of the axis over the plane
        if abs(delta) > R + tol.linear:
            return _Exact()
        foot = O - delta * n
        if abs(abs(delta) - R) <= tol.linear:
            return _Exact((_Candidate(Line(foot, Z), tangent=True),))
        w = _unit(np.cross(Z, n))
        half = math.sqrt(R * R - delta * delta)
        return _Exact(tuple(_Candidate(Line(foot + sgn * half * w, Z), uniform=True) for sgn in (1.0, -1.0)))
    sine = _sine(n, Z)
    if sine <= tol.angular:
        return None  # perpendicular: the coaxial (meridian) case gives the circle
    # Oblique: the ellipse centred where the axis meets the plane, minor radius R across the
    # axis, major radius R / |cos| along the plane's steepest direction.
    C = O + (float((p.origin - O) @ n) / cos) * Z
    # R / |cos| - R in a form without cancellation (and without |cos| rounding above 1, which made
    # the major radius fall below the minor one a little past the angular tolerance).
    c = min(abs(cos), 1.0)
    excess = R * sine * sine / (c * (1.0 + c))
    if excess <= tol.solver * R:
        # The semi-axes agree to the relative accuracy asked of solvers: a near-circular ellipse is
        # stored as its circle of radius R about C in the plane (within ``excess`` of the ellipse and
        # of the cylinder).  (The crash near perpendicular planes was the major radius computed below
        # the minor one; the cancellation-free ``excess`` above is what fixed it.)
        return _Exact((_Candidate(Circle(C, n, perpendicular_direction(n), R)),))
    w = _unit(np.cross(Z, n))
    m = np.cross(n, w)
    return _Exact((_Candidate(Ellipse(C, n, m, R + excess, R)),))


def _plane_cone(p: PlanarSurface, k: ConicalSurface, tol: Tolerance) -> _Exact | None:
    n, Z, A = p.axis, k.axis, k.apex
    alpha = abs(k.semi_angle)
    if _sine(n, Z) <= tol.angular:
        return None  # perpendicular to the axis: the coaxial case gives the circle
    D = float((p.origin - A) @ n)  # signed distance of the plane from the apex
    X, Y = k.frame[0], k.frame[1]
    # A generator direction is g(u) = sin α e(u) + cos α s Z (s = sign of the cone's semi-angle
    # as seen from Z: its radius grows along s Z); n·g(u) = sin α ρ_n cos(u - φ) + cos α s n_z.
    s = 1.0 if k.semi_angle > 0.0 else -1.0
    nx, ny, nz = float(n @ X), float(n @ Y), float(n @ Z)
    rho_n = math.hypot(nx, ny)
    phi = math.atan2(ny, nx)

    def g(u: float) -> np.ndarray:
        return math.sin(alpha) * (math.cos(u) * X + math.sin(u) * Y) + math.cos(alpha) * s * Z

    # c = cos(u - φ) of the generators parallel to the plane.
    c = -math.cos(alpha) * s * nz / (math.sin(alpha) * rho_n)
    if abs(D) <= tol.linear:  # through the apex: rulings
        if abs(c) > 1.0 + tol.angular:
            return _Exact(points=(A,))
        if abs(abs(c) - 1.0) <= tol.angular:
            u = phi if c > 0 else phi + math.pi
            return _Exact((_Candidate(Line(A, g(u)), tangent=True),))
        half = math.acos(c)
        return _Exact((_Candidate(Line(A, g(phi + half))), _Candidate(Line(A, g(phi - half)))))
    if abs(c) <= 1.0 + tol.angular:
        # Generators parallel to the plane: a parabola (|c| = 1) or hyperbola, unbounded; the
        # boxes bound it (see _ConeSection).
        section = _ConeSection(A, X, Y, s * Z, alpha, n, D, phi, math.sin(alpha) * rho_n, math.cos(alpha) * s * nz,
                               max(-1.0, min(1.0, c)), k)
        return _Exact((_Candidate(section),))
    # Ellipse: its major axis lies in the principal plane (spanned by Z and n), between the
    # points where the generators u = φ and u = φ + π meet the plane (s = D / n·g).
    P1 = A + (D / float(n @ g(phi))) * g(phi)
    P2 = A + (D / float(n @ g(phi + math.pi))) * g(phi + math.pi)
    C = 0.5 * (P1 + P2)
    major = 0.5 * float(np.linalg.norm(P2 - P1))
    m = _unit(P2 - P1)
    # C + y w (w ⟂ principal plane, so ⟂ Z) is on the cone where ρ² = (h tan α)².
    h = float((C - A) @ Z)
    radial = float(np.linalg.norm(C - A - h * Z))
    minor = math.sqrt(max((h * math.tan(alpha)) ** 2 - radial**2, 0.0))
    if minor > major:  # round-off of a nearly circular section
        m, major, minor = np.cross(n, m), minor, major
    return _Exact((_Candidate(Ellipse(C, n, m, major, minor)),))


class _ConeSection:
    """A parabola or hyperbola cut from a cone by a plane, parametrised by the generator angle ``u``.

    ``P(u) = A + λ(u) g(u)`` with ``g(u) = sin α e(u) + cos α Z`` (the generator through the
    apex ``A``) and ``λ(u) = D / (k cos(u - φ) + m)``, ``D`` the plane's distance from the apex.
    Only used to locate the in-box pieces; each piece becomes an exact rational quadratic arc
    (The NURBS Book A7.3) through its ends and middle.
    """

    def __init__(self, A, X, Y, Z, alpha, n, D, phi, k, m, c, cone):
        self.A, self.X, self.Y, self.Z, self.alpha = A, X, Y, Z, alpha
        self.n, self.D, self.phi, self.k, self.m, self.c, self.cone = n, D, phi, k, m, c, cone

    def _g(self, u: np.ndarray, order: int) -> np.ndarray:
        c, s = np.cos(u)[..., None], np.sin(u)[..., None]
        e = (c * self.X + s * self.Y, -s * self.X + c * self.Y)[order]
        return math.sin(self.alpha) * e + (math.cos(self.alpha) * self.Z if order == 0 else 0.0)

    def evaluate(self, u) -> np.ndarray:
        u = np.asarray(u, dtype=np.float64)
        lam = self.D / (self.k * np.cos(u - self.phi) + self.m)
        return self.A + lam[..., None] * self._g(u, 0)

    def tangent(self, u: float) -> np.ndarray:
        den = self.k * math.cos(u - self.phi) + self.m
        lam = self.D / den
        dlam = self.D * self.k * math.sin(u - self.phi) / (den * den)
        return dlam * self._g(np.array(u), 0) + lam * self._g(np.array(u), 1)

    def windows(self, v_box: tuple[float, float]) -> list[tuple[float, float]]:
        """Angle intervals of the branches, limited to twice the box's reach along the generators.

        Raises
        ------
        InvalidInputError
            An infinite ``v`` box on the cone (the section is unbounded).
        """
        v0, v1 = v_box
        if not (math.isfinite(v0) and math.isfinite(v1)):
            raise InvalidInputError(
                f"intersect_surfaces: the cone's box v {v_box!r} must be finite for a parabolic or hyperbolic section"
            )
        cone = self.cone
        v_apex = -cone.radius / math.sin(cone.semi_angle)
        reach = 2.0 * max(abs(v0 - v_apex), abs(v1 - v_apex))  # twice: the in-box part lies strictly inside
        gap = abs(self.D) / (self.k * reach)
        out = []
        c1 = self.c + gap  # one branch: cos(u - φ) >= c1
        if c1 < 1.0:
            h = math.acos(max(c1, -1.0))
            out.append((self.phi - h, self.phi + h))
        c2 = self.c - gap  # the other: cos(u - φ) <= c2
        if c2 > -1.0:
            h = math.acos(min(c2, 1.0))
            out.append((self.phi + h, self.phi + TWO_PI - h))
        return out


def _plane_torus_meridians(p: PlanarSurface, t: ToroidalSurface, tol: Tolerance) -> _Exact | None:
    """A plane containing the torus' axis: the two meridian circles."""
    n, Z, C = p.axis, t.axis, t.center
    if abs(float(n @ Z)) > tol.angular or abs(float((C - p.origin) @ n)) > tol.linear:
        return None
    m = _unit(np.cross(Z, n))
    R, r = t.major_radius, t.minor_radius
    return _Exact(tuple(_Candidate(Circle(C + sgn * R * m, n, m, r)) for sgn in (1.0, -1.0)))


def _parallel_cylinders(a: CylindricalSurface, b: CylindricalSurface, tol: Tolerance) -> _Exact | None:
    Z = a.axis
    if _sine(Z, b.axis) > tol.angular:
        return None  # crossing axes: the general method
    w = b.origin - a.origin
    w = w - (w @ Z) * Z
    d = float(np.linalg.norm(w))
    if d <= tol.linear:
        return None  # coaxial: the meridian case
    R1, R2 = a.radius, b.radius
    if d > R1 + R2 + tol.linear or d < abs(R1 - R2) - tol.linear:
        return _Exact()
    e = w / d
    x = (d * d + R1 * R1 - R2 * R2) / (2.0 * d)  # along e from a's axis (radical line)
    if abs(d - (R1 + R2)) <= tol.linear or abs(d - abs(R1 - R2)) <= tol.linear:
        x = R1 if abs(d - (R1 + R2)) <= tol.linear or R1 > R2 else -R1
        return _Exact((_Candidate(Line(a.origin + x * e, Z), tangent=True),))
    y = math.sqrt(max(R1 * R1 - x * x, 0.0))
    f = np.cross(Z, e)
    return _Exact(tuple(_Candidate(Line(a.origin + x * e + sgn * y * f, Z), uniform=True) for sgn in (1.0, -1.0)))


#: Largest radius difference plus axis distance, in ``tol.linear``, that :func:`_equal_cylinders` takes as
#: equal cylinders with meeting axes (a quarter: the fitted p-curves on ``b`` get half of ``tol.linear``).
_EQUAL_CYLINDERS_GAP = 0.25


def _equal_cylinders(a: CylindricalSurface, b: CylindricalSurface, tol: Tolerance) -> _Exact | None:
    """Two cylinders of equal radius whose axes cross: two ellipses, crossing at two singular points.

    With the origin where the axes ``Z_a``, ``Z_b`` meet, ``|p|² - (p·Z_a)² = R² = |p|² - (p·Z_b)²``
    gives ``(p·Z_a)² = (p·Z_b)²``: the intersection is the union of the plane sections of cylinder
    ``a`` by the bisecting planes ``p·(Z_a ∓ Z_b) = 0`` (ellipses, exact), which cross at the two
    points ``±R (Z_a × Z_b)/|Z_a × Z_b|`` where the surfaces touch (one of the degenerate pairs of
    Miller & Goldman whose intersection is two conics).  None (the general method) when the axes are
    parallel, or when the radii's difference plus the axes' distance exceeds
    :data:`_EQUAL_CYLINDERS_GAP` ``tol.linear``: the ellipses lie on ``a`` and within that gap of ``b``,
    and ``b``'s p-curves are fitted to half of ``tol.linear``.
    """
    Za, Zb, R = a.axis, b.axis, a.radius
    k = np.cross(Za, Zb)
    sk = float(np.linalg.norm(k))
    if sk <= tol.angular:
        return None
    k = k / sk
    w = b.origin - a.origin
    if abs(a.radius - b.radius) + abs(float(w @ k)) > _EQUAL_CYLINDERS_GAP * tol.linear:
        return None  # different radii or skew axes
    # Where the axes meet: a.origin + s Za = b.origin + r Zb (in the plane of both axes).
    c = float(Za @ Zb)
    s_ = (float(w @ Za) - c * float(w @ Zb)) / (1.0 - c * c)
    C = a.origin + s_ * Za
    singular = (C + R * k, C - R * k)
    out = []
    for n in (Za - Zb, Za + Zb):
        n = n / float(np.linalg.norm(n))
        found = _plane_cylinder(PlanarSurface(C, n, perpendicular_direction(n)), a, tol)
        if found is None or len(found.candidates) != 1:
            return None
        out.append(_Candidate(found.candidates[0].curve, singular=singular))
    return _Exact(tuple(out))


#: Least half-chord, as a fraction of the other cylinder's radius ``R``, that every ruling of one cylinder must
#: cut from the other (seen along its axis) for :func:`_crossing_cylinders` to take the pair in closed form;
#: to report no intersection every ruling must miss it with ``ρ² - R²`` at least the same squared (``ρ`` the
#: ruling's distance from the axis).  The loops' curvature grows as the half-chord shrinks (at zero they
#: touch: a tangency, or one loop turning back); closer pairs are marched as before.
_LOOP_CHORD = 0.1
#: Least sine of the angle between the axes for :func:`_crossing_cylinders` (about 3°): as the axes turn
#: parallel the loops stretch along them as ``1 / sin`` and their fits need ever more samples; such pairs
#: are marched as before.
_LOOP_MIN_SINE = 0.05
#: Least half-chord margin (``_LOOP_CHORD`` times the radius), in ``tol.linear``, for :func:`_cylinder_loops`: the
#: margin must clear the tolerance widely.
_LOOP_MARGIN_TOLS = 1e2
#: Samples of the discriminant over a turn in :func:`_cylinder_loops` (its minimum and maximum are then
#: bounded by the sample extremes widened by the interpolation error bound of its second derivative).
_LOOP_DISC_SAMPLES = 64


class _CylinderLoop:
    """One closed loop of two cylinders with non-parallel axes, a graph over the angle of cylinder ``g``.

    On ``g``, ``P(θ, s) = O_g + R_g (cos θ X_g + sin θ Y_g) + s Z_g`` lies on cylinder ``h`` (radius
    ``R_h``, axis ``Z_h`` through ``O_h``) iff ``|z|² s² + 2 B s + C = 0`` with ``q(θ)`` the part of
    ``P(θ, 0) - O_h`` across ``Z_h``, ``z`` that of ``Z_g``, ``B = q·z`` and ``C = |q|² - R_h²``.  Where the
    discriminant ``D(θ) = B² - |z|² C`` stays positive the roots ``s(θ) = (-B + r √D) / |z|²`` (``r = ±1``,
    one loop each) are smooth and ``2π``-periodic: the loop is ``P(θ, s(θ))``, in closed form with its
    derivative.  The parameter is ``t = σ θ`` (``σ = ±1``: :meth:`reversed` flips it).
    """

    __slots__ = ("g", "h", "root", "sense", "_c", "_x", "_y", "_z", "_zz", "_rh2")

    def __init__(self, g: CylindricalSurface, h: CylindricalSurface, root: float, sense: float = 1.0) -> None:
        self.g, self.h, self.root, self.sense = g, h, float(root), float(sense)
        Zh = h._frame[2]

        def across(v: np.ndarray) -> np.ndarray:
            return v - (v @ Zh) * Zh

        X, Y, Z = g._frame
        self._c = across(g._origin - h._origin)
        self._x, self._y, self._z = across(g.radius * X), across(g.radius * Y), across(Z)
        self._zz = float(self._z @ self._z)
        self._rh2 = h.radius * h.radius

    def reversed(self) -> "_CylinderLoop":
        """The same loop run the other way (``t -> -t``)."""
        return _CylinderLoop(self.g, self.h, self.root, -self.sense)

    def graph(self, t, slopes: bool = True) -> tuple[np.ndarray, np.ndarray, np.ndarray | None, np.ndarray]:
        """``(θ, s, ds/dθ, D)`` at parameters ``t`` (each of ``t``'s shape); ``ds/dθ`` None unless ``slopes``."""
        theta = self.sense * np.asarray(t, dtype=np.float64)
        c, s = np.cos(theta), np.sin(theta)
        q = self._c + c[..., None] * self._x + s[..., None] * self._y
        dq = s[..., None] * -self._x + c[..., None] * self._y
        B, dB = q @ self._z, dq @ self._z
        C, dC = np.add.reduce(q * q, axis=-1) - self._rh2, 2.0 * np.add.reduce(q * dq, axis=-1)
        D = B * B - self._zz * C
        root = np.sqrt(np.maximum(D, 0.0))
        sv = (-B + self.root * root) / self._zz
        if not slopes:
            return theta, sv, None, D
        dsv = (-dB + self.root * (B * dB - 0.5 * self._zz * dC) / root) / self._zz
        return theta, sv, dsv, D

    def evaluate(self, t) -> np.ndarray:
        """The loop's points ``t.shape + (3,)``."""
        theta, sv, _, _ = self.graph(t, slopes=False)
        return _surface_points(self.g, theta, sv)

    def derivatives(self, t, order: int = 1) -> np.ndarray:
        """Points and first derivatives ``t.shape + (2, 3)`` (``order`` 1 only)."""
        if order != 1:
            raise InvalidInputError(f"_CylinderLoop.derivatives: order 1 only, got {order}")
        theta, sv, dsv, _ = self.graph(t)
        X, Y, Z = self.g._frame
        P = _surface_points(self.g, theta, sv)
        dP = self.sense * (self.g.radius * (np.cos(theta)[..., None] * Y - np.sin(theta)[..., None] * X)
                           + dsv[..., None] * Z)
        return np.stack([P, dP], axis=-2)


def _crossing_cylinders(a: CylindricalSurface, b: CylindricalSurface, tol: Tolerance) -> _Exact | None:
    """Cylinders with non-parallel axes where every ruling of one crosses the other clearly: two closed loops.

    Tries each cylinder as the graph cylinder of :class:`_CylinderLoop`: its discriminant bounded
    above ``0`` on the whole turn gives the two loops (one cylinder passes right through the other), bounded
    below ``0`` gives nothing (no ruling meets the other cylinder); None (the general method) when neither
    role decides (the discriminant changes sign: one loop turning back in ``θ``; or comes within the margin
    of :data:`_LOOP_CHORD`: near tangency).
    """
    for g, h in ((b, a), (a, b)):
        found = _cylinder_loops(g, h, tol)
        if found is not None:
            return found
    return None


def _cylinder_loops(g: CylindricalSurface, h: CylindricalSurface, tol: Tolerance) -> _Exact | None:
    """The two loops of ``g`` through ``h`` (:class:`_CylinderLoop`), nothing, or None (see :func:`_crossing_cylinders`).

    ``D(θ) / |z|²`` is the squared half-chord ``R_h² - ρ²`` that the ruling at ``θ`` (at distance ``ρ`` from
    ``h``'s axis in projection along it) cuts from ``h``.  It is a trigonometric polynomial of degree 2 in
    ``θ``: its extremes lie within ``M h² / 8`` of the extremes of samples spaced ``h`` apart, with ``M`` the
    sum of its harmonics' amplitudes times their squared orders, which bounds ``|D''|``.
    """
    loop = _CylinderLoop(g, h, 1.0)
    zz = loop._zz
    if zz < _LOOP_MIN_SINE * _LOOP_MIN_SINE:
        return None  # (nearly) parallel axes: _parallel_cylinders, _coaxial or marching
    margin = _LOOP_CHORD * h.radius
    if margin <= _LOOP_MARGIN_TOLS * tol.linear:  # (a hair-thin cylinder)
        return None
    theta = np.arange(_LOOP_DISC_SAMPLES) * (TWO_PI / _LOOP_DISC_SAMPLES)
    D = loop.graph(theta, slopes=False)[3] / zz
    # The harmonics of D / |z|² from the samples (exact for a trigonometric polynomial of degree 2).
    spectrum = np.abs(np.fft.rfft(D)) * (2.0 / _LOOP_DISC_SAMPLES)
    bound = (spectrum[1] + 4.0 * spectrum[2]) * (TWO_PI / _LOOP_DISC_SAMPLES) ** 2 / 8.0
    lo, hi = float(D.min()) - bound, float(D.max()) + bound
    if lo >= margin * margin:
        return _Exact((_Candidate(loop), _Candidate(_CylinderLoop(g, h, -1.0))))
    if hi <= -margin * margin:
        return _Exact()
    return None


def _loop_coordinates(loop: _CylinderLoop, t: np.ndarray, g_first: bool,
                      slopes: bool = False) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
    """``(P (k, 3), coordinates (4, k), their derivatives (4, k) or None)`` of the loop at parameters ``t`` ``(k,)``:
    ``(u_a, v_a, u_b, v_b)``, where the graph cylinder's are ``(θ, s(θ))`` and the other's angle is in
    ``[-π, π]``, unwrapped by the caller; the derivatives (by ``t``) only when ``slopes``."""
    theta, sv, dsv, _ = loop.graph(t, slopes)
    c, s = np.cos(theta), np.sin(theta)
    X, Y, Z = loop.g._frame
    P = (loop.g.radius * (c[:, None] * X + s[:, None] * Y) + sv[:, None] * Z) + loop.g._origin
    L = (P - loop.h._origin) @ loop.h._frame.T
    on_h, on_g = (np.arctan2(L[:, 1], L[:, 0]), L[:, 2]), (theta, sv)
    G = np.stack(on_g + on_h if g_first else on_h + on_g)
    if not slopes:
        return P, G, None
    dP = loop.sense * (loop.g.radius * (c[:, None] * Y - s[:, None] * X) + dsv[:, None] * Z)
    dL = dP @ loop.h._frame.T
    d_h = ((L[:, 0] * dL[:, 1] - L[:, 1] * dL[:, 0]) / (L[:, 0] ** 2 + L[:, 1] ** 2), dL[:, 2])
    d_g = (np.full(theta.shape, loop.sense), loop.sense * dsv)
    return P, G, np.stack(d_g + d_h if g_first else d_h + d_g)


def _loop_roots(loop: _CylinderLoop, g_first: bool, rows: np.ndarray, targets: np.ndarray, ref: np.ndarray,
                lo: np.ndarray, hi: np.ndarray, glo: np.ndarray, ghi: np.ndarray) -> np.ndarray:
    """Where coordinate ``rows[i]`` of the loop equals ``targets[i]`` in the bracket ``[lo[i], hi[i]]`` (values ``glo``,
    ``ghi`` of opposite signs, nonzero), all at once: Newton's method on the closed-form coordinates and their
    derivatives, kept in the shrinking brackets (a step leaving its bracket is replaced by the midpoint).

    A root is done when its value is exactly zero, its Newton step or its bracket is within four ulps of
    ``max(1, |t|)`` (the parameter's round-off), or after :data:`_ROOT_STEPS` steps.  The angle of the
    cylinder that is not the graph is unwrapped against ``ref``, its value at the bracket's grid point.
    """
    lo, hi, glo = lo.copy(), hi.copy(), glo.copy()
    x = lo - glo * (hi - lo) / (ghi - glo)  # the secant start
    x = np.where((x > lo) & (x < hi), x, 0.5 * (lo + hi))
    out = x.copy()
    h_row = 2 if g_first else 0
    act = np.arange(x.size)
    for _ in range(_ROOT_STEPS):
        if act.size == 0:
            break
        xa, r = x[act], rows[act]
        _, G, dG = _loop_coordinates(loop, xa, g_first, slopes=True)
        k = np.arange(act.size)
        v, dv = G[r, k], dG[r, k]
        v = np.where(r == h_row, v + TWO_PI * np.round((ref[act] - v) / TWO_PI), v)
        g = v - targets[act]
        out[act] = xa
        left = np.signbit(g) != np.signbit(glo[act])  # the root lies in [lo, x]
        hi[act] = np.where(left, xa, hi[act])
        lo[act] = np.where(left, lo[act], xa)
        glo[act] = np.where(left, glo[act], g)
        with np.errstate(divide="ignore", invalid="ignore"):
            step = g / dv
        nx = xa - step
        ulps = 4.0 * _EPS * np.maximum(1.0, np.abs(xa))
        # A Newton step within the parameter's round-off ends the search even where it leaves the bracket
        # (the value's sign is noise there; bisecting would crawl to the bracket's width).
        done = (g == 0.0) | (np.abs(step) <= ulps) | (hi[act] - lo[act] <= ulps)
        x[act] = np.where(np.isfinite(nx) & (nx > lo[act]) & (nx < hi[act]), nx, 0.5 * (lo[act] + hi[act]))
        act = act[~done]
    return out


def _loop_branches(loop: _CylinderLoop, a, b, box_a, box_b, tol: Tolerance) -> list[IntersectionCurve]:
    """The pieces of a loop of two cylinders (:class:`_CylinderLoop`) inside both boxes, running along ``n_a × n_b``.

    The same clipping as :func:`_branches` on the closed-form coordinates: a turn starting where the graph
    cylinder's angle is at its box's lower bound; breakpoints where a coordinate crosses a box bound (a seam
    for a box of a whole period or more), bracketed on a grid of :data:`_SEARCH_SAMPLES` intervals (each
    coordinate changes monotonically between a few extrema per turn; a turn inside a cell that can reach a
    bound is located by :func:`_loop_turns` and the cell bracketed on both sides of it) and solved together
    by :func:`_loop_roots`; runs of in-box intervals (:func:`_runs`), each fitted by :func:`_loop_piece`.  The
    other cylinder's angle stays within an arc shorter than π along a loop (the loop lies on one side
    of the plane through that cylinder's axis across the graph cylinder's axis), so it is unwrapped
    against one reference value.
    """
    g_first = loop.g is a
    boxes = (box_a, box_b)
    bounds = [box_a[0], box_a[1], box_b[0], box_b[1]]
    periodic = [True, False, True, False]
    slack = tol.solver * max(1.0, *(abs(x) for box in boxes for r in box for x in r if math.isfinite(x)))
    # Direction: (n_a × n_b)·T keeps its sign along the loop (the surfaces cross at every point of it).
    D = loop.derivatives(_TURN_SAMPLES, 1)
    side = np.einsum("ij,ij->i", _cross(_normals(a, D[:, 0]), _normals(b, D[:, 0])), D[:, 1])
    if side[int(np.argmax(np.abs(side)))] < 0.0:
        loop = loop.reversed()
    lo_g = (box_a if g_first else box_b)[0][0]
    lo_g = lo_g if math.isfinite(lo_g) else 0.0
    w0 = lo_g if loop.sense > 0.0 else -(lo_g + TWO_PI)
    w1 = w0 + TWO_PI
    grid = np.linspace(w0, w1, _SEARCH_SAMPLES + 1)
    _, F, dF = _loop_coordinates(loop, grid, g_first, slopes=True)
    h_row = 2 if g_first else 0
    F[h_row] = np.unwrap(F[h_row], period=TWO_PI)
    # Brackets [lo, hi] with values of opposite signs (coordinate, target, reference value) of every
    # bound crossing, then all roots at once.
    br_rows, br_targets, br_refs, br_lo, br_hi, br_glo, br_ghi, seam_rows = [], [], [], [], [], [], [], []
    exact, exact_seams = [], []  # crossings at grid points (the window's ends among them)
    seam_at_start = False
    for k, ((lo, hi), per) in enumerate(zip(bounds, periodic)):
        seam = per and hi - lo >= TWO_PI and math.isfinite(lo)
        if seam:
            seam_at_start |= bool(_inside(F[k, :1], lo, lo, True, slack)[0])
        # (widened by how far the coordinate can move past its grid values inside a cell: _loop_turns)
        reach = 2.0 * float(grid[1] - grid[0]) * float(np.max(np.abs(dF[k])))
        f_lo, f_hi = float(F[k].min()) - reach, float(F[k].max()) + reach
        wanted = [t for bound in ((lo,) if seam else (lo, hi)) if math.isfinite(bound)
                  for t in _target_values(per, bound, f_lo, f_hi)]
        if wanted:
            turns = _loop_turns(loop, g_first, k, grid, F[k], dF[k], np.array(wanted))
        for target in wanted:
            g = F[k] - target
            (exact_seams if seam else exact).append(grid[g == 0.0])
            # (a bracket with a zero end would make regula falsi crawl towards it)
            j = np.flatnonzero((np.signbit(g[:-1]) != np.signbit(g[1:])) & (g[:-1] != 0.0) & (g[1:] != 0.0))
            lo_t, hi_t, glo, ghi = [grid[j]], [grid[j + 1]], [g[j]], [g[j + 1]]
            refs = [F[k, j]]
            # A turn of the coordinate inside a cell whose ends are on one side of the target may
            # still reach past it: such a cell is two brackets, either side of the turn.
            c, ts, Fs = turns
            if c.size:
                gs, g0, g1 = Fs - target, g[c], g[c + 1]
                past = ((np.signbit(gs) != np.signbit(g0)) & (np.signbit(g0) == np.signbit(g1))
                        & (gs != 0.0) & (g0 != 0.0) & (g1 != 0.0))
                c, ts, gs, g0, g1 = c[past], ts[past], gs[past], g0[past], g1[past]
                lo_t += [grid[c], ts]
                hi_t += [ts, grid[c + 1]]
                glo += [g0, gs]
                ghi += [gs, g1]
                refs += [F[k, c], F[k, c]]
            n = sum(x.size for x in lo_t)
            br_lo += lo_t
            br_hi += hi_t
            br_glo += glo
            br_ghi += ghi
            br_refs += refs
            br_rows += [k] * n
            br_targets += [target] * n
            seam_rows += [seam] * n
    roots, seam_roots = np.concatenate([np.zeros(0)] + exact), np.concatenate([np.zeros(0)] + exact_seams)
    if br_rows:
        rows_, targets_ = np.array(br_rows), np.array(br_targets)
        found = _loop_roots(loop, g_first, rows_, targets_, np.concatenate(br_refs), np.concatenate(br_lo),
                            np.concatenate(br_hi), np.concatenate(br_glo), np.concatenate(br_ghi))
        is_seam = np.array(seam_rows)
        roots, seam_roots = np.concatenate([roots, found[~is_seam]]), np.concatenate([seam_roots, found[is_seam]])
    br = np.unique(np.concatenate([[w0, w1], roots, seam_roots]))
    br = br[np.concatenate([[True], np.diff(br) > slack])]
    br[-1] = w1
    hard = np.min(np.abs(seam_roots[:, None] - br[None, :]), axis=0, initial=np.inf) <= slack
    _, M, _ = _loop_coordinates(loop, 0.5 * (br[:-1] + br[1:]), g_first)
    ok = np.ones(M.shape[1], dtype=bool)
    for k, ((lo, hi), per) in enumerate(zip(bounds, periodic)):
        ok &= _inside(M[k], lo, hi, per, slack)
    out = []
    for s0, s1 in _runs(br, ok, hard, not seam_at_start):
        if s1 - s0 > slack:
            out.append(_loop_piece(loop, s0, s1, a, b, boxes, g_first, slack, s1 - s0 >= TWO_PI - slack, tol))
    return out


#: Bisection steps locating a turn of a loop coordinate inside a grid cell (:func:`_loop_turns`): a cell of
#: ``2π / 512`` halved 44 times is below 1e-15.
_TURN_STEPS = 44


def _loop_turns(loop: _CylinderLoop, g_first: bool, k: int, grid: np.ndarray, f: np.ndarray,
                df: np.ndarray, targets: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(cells, t*, f(t*))``: the grid cells where coordinate ``k`` of the loop (values ``f``, derivatives ``df`` on
    ``grid``; the other cylinder's angle unwrapped) turns and might, between grid points, pass one of
    ``targets`` that neither end reaches, with the turn ``t*`` (where the derivative changes sign, by
    bisection on its sign) and the coordinate there.

    A cell qualifies when the derivative changes sign across it and a target lies beyond both ends'
    values, on the turn's side, by at most ``h (|f'_0| + |f'_1|)`` (the coordinate moves from an end by at
    most about ``h max |f'|`` before it turns, ``f'`` being nearly linear across a cell); only those are
    located: usually none, since a bound rarely lies that close to an extreme.  Turning exactly at a grid
    point needs nothing (the grid value is the extreme).  Two turns inside one cell (the derivative of one
    sign at both ends) are not seen: with 512 cells a turn that tight needs a loop near tangency, which
    :func:`_cylinder_loops` leaves to marching.
    """
    d0, d1 = df[:-1], df[1:]
    c = np.flatnonzero((np.signbit(d0) != np.signbit(d1)) & (d0 != 0.0) & (d1 != 0.0))
    if c.size == 0:
        return c, np.zeros(0), np.zeros(0)
    h = grid[c + 1] - grid[c]
    reach = h * (np.abs(d0[c]) + np.abs(d1[c]))
    # A maximum (f' from + to -) can rise above both ends by at most the reach, a minimum fall below.
    high, low = np.maximum(f[c], f[c + 1]), np.minimum(f[c], f[c + 1])
    peak = ~np.signbit(d0[c])
    T = targets[None, :]
    near = np.where(peak, np.any((T > high[:, None]) & (T <= (high + reach)[:, None]), axis=1),
                    np.any((T < low[:, None]) & (T >= (low - reach)[:, None]), axis=1))
    c, peak = c[near], peak[near]
    if c.size == 0:
        return c, np.zeros(0), np.zeros(0)
    lo, hi = grid[c].copy(), grid[c + 1].copy()
    for _ in range(_TURN_STEPS):
        mid = 0.5 * (lo + hi)
        _, _, dG = _loop_coordinates(loop, mid, g_first, slopes=True)
        rising = ~np.signbit(dG[k])
        left = rising == peak  # still rising to a peak (falling to a trough): the turn lies right of mid
        lo, hi = np.where(left, mid, lo), np.where(left, hi, mid)
    ts = 0.5 * (lo + hi)
    _, G, _ = _loop_coordinates(loop, ts, g_first)
    fs = G[k]
    if k == (2 if g_first else 0):  # the other cylinder's angle: on the grid's unwrapped turn
        fs = fs + TWO_PI * np.round((f[c] - fs) / TWO_PI)
    return c, ts, fs


def _loop_piece(loop: _CylinderLoop, s0: float, s1: float, a, b, boxes, g_first: bool, slack: float, closed: bool,
                tol: Tolerance) -> IntersectionCurve:
    """The piece ``[s0, s1]`` of a loop of two cylinders: its 3-D curve and both p-curves fitted together.

    One spline of degree :data:`_FIT_DEGREE` interpolates the exact points and both surfaces' parameters
    (shifted into the boxes as :func:`_shift` does) at the same samples (The NURBS Book A9.1, averaged
    knots eq. 9.8, as :func:`_fitted_pcurve`, from the same first samples, :func:`_fit_start`),
    refined the same way until, at the quarter points of every interval, the curve and the images of both
    p-curves are within ``tol.linear / 2`` of the exact point (evaluations only: no projection).  The graph
    cylinder's angle is affine in the parameter, which the spline reproduces.  The samples of one fit serve
    all three curves, so they share their knots.
    """
    tm = 0.5 * (s0 + s1)
    _, mid, _ = _loop_coordinates(loop, np.array([tm]), g_first)
    mid = mid[:, 0]
    h_row = 2 if g_first else 0
    shift = np.zeros(4)
    for k in (0, 2):
        lo = boxes[k // 2][0][0]
        if math.isfinite(lo):
            shift[k] = TWO_PI * math.ceil((lo - slack - mid[k]) / TWO_PI)
    ref = mid[h_row]

    def f(t: np.ndarray) -> np.ndarray:
        P, G, _ = _loop_coordinates(loop, t, g_first)
        G[h_row] = ref + np.remainder(G[h_row] - ref + math.pi, TWO_PI) - math.pi
        return np.concatenate([P, (G + shift[:, None]).T], axis=1)

    t = _fit_start(s0, s1)
    Q = f(t)
    bound = 0.5 * tol.linear
    worst = math.inf
    while len(t) <= _MAX_FIT_SAMPLES:
        F, ctrl, knots = _fit_round(t, Q)
        tq = _quarter_points(t)
        E = loop.evaluate(tq)
        C = F[:, :3]
        Pa = _surface_points(a, F[:, 3], F[:, 4])
        Pb = _surface_points(b, F[:, 5], F[:, 6])
        off = np.stack([np.add.reduce(d * d, axis=-1) for d in (C - E, Pa - E, Pb - E)])
        e = np.sqrt(np.max(off.max(axis=0).reshape(-1, 3), axis=1))
        bad = np.flatnonzero(e > bound)
        if bad.size == 0:
            gaps = np.concatenate([Pa - C, Pb - C, Pa - Pb])
            fit_dev = math.sqrt(float(np.max(np.add.reduce(gaps * gaps, axis=-1))))
            p = _FIT_DEGREE
            pcurves = [NurbsCurve(ctrl[:, 3:5], knots, p), NurbsCurve(ctrl[:, 5:7], knots, p)]
            return _finished(NurbsCurve(ctrl[:, :3], knots, p), s0, s1, pcurves, fit_dev, a, b, closed, False)
        worst = float(e.max())
        count = np.clip(np.ceil((e[bad] / bound) ** (1.0 / (_FIT_DEGREE + 1))) - 1.0, 1,
                        _MAX_FIT_SPLIT).astype(np.int64)
        owner, j = interval_cuts(bad, count)
        new = t[owner] + j * (t[owner + 1] - t[owner])
        order = np.argsort(np.concatenate([t, new]), kind="stable")
        t, Q = np.concatenate([t, new])[order], np.concatenate([Q, f(new)])[order]
    raise ConvergenceError(
        f"cylinder loop fit: deviation {worst:.3g} above {bound:.3g} with {_MAX_FIT_SAMPLES} samples",
        residuals=np.array([worst]),
    )


# Meridians in the half-plane (ρ >= 0, z) about a common axis: ("line", point, direction) and
# ("circle", centre, radius), all 2-D.
def _axis_of(s) -> tuple[np.ndarray, np.ndarray] | None:
    """The symmetry axis ``(point, unit direction)`` of a surface of revolution; ``None`` for a sphere (any line
    through its centre)."""
    if isinstance(s, SphericalSurface):
        return None
    return s._origin, s.axis


def _meridian(s, A: np.ndarray, Z: np.ndarray) -> list[tuple]:
    """The meridian of ``s`` about the axis ``A + z Z`` (``s`` known to be symmetric about it)."""
    if isinstance(s, PlanarSurface):
        return [("line", np.array([0.0, float((s.origin - A) @ Z)]), np.array([1.0, 0.0]))]
    z0 = float((s._origin - A) @ Z)
    if isinstance(s, SphericalSurface):
        return [("circle", np.array([0.0, z0]), s.radius)]
    if isinstance(s, ToroidalSurface):
        return [("circle", np.array([s.major_radius, z0]), s.minor_radius)]
    sgn = 1.0 if float(s.axis @ Z) > 0.0 else -1.0
    if isinstance(s, CylindricalSurface):
        return [("line", np.array([s.radius, z0]), np.array([0.0, 1.0]))]
    # Cone: ρ = R + v sin a, z = z0 + sgn v cos a, and its mirror image (the far nappe).
    sa, ca = math.sin(s.semi_angle), math.cos(s.semi_angle)
    return [
        ("line", np.array([s.radius, z0]), np.array([sa, sgn * ca])),
        ("line", np.array([-s.radius, z0]), np.array([-sa, sgn * ca])),
    ]


def _unit_meridian(U: np.ndarray) -> np.ndarray:
    """``_unit(U)`` of a 2-D direction; a unit axis direction (a plane's or cylinder's meridian) as it is,
    which is what the division by its norm, exactly 1, gives."""
    u0, u1 = U.tolist()
    if (u0 == 0.0 and abs(u1) == 1.0) or (u1 == 0.0 and abs(u0) == 1.0):
        return U
    return _unit(U)


def _meet(p, q, tol: Tolerance) -> tuple[list[tuple[np.ndarray, bool]], bool]:
    """Intersections ``[(point (2,), tangent)]`` of two meridian pieces, and whether they coincide.

    Mirrored for many plane–cylinder pairs at once by :func:`_plane_cylinder_circles`: keep the two in step.
    """
    if p[0] == "circle" and q[0] == "line":
        p, q = q, p
    if p[0] == "line" and q[0] == "line":
        (_, P, U), (_, Q, V) = p, q
        U, V = _unit_meridian(U), _unit_meridian(V)
        cross = U[0] * V[1] - U[1] * V[0]
        w = Q - P
        if abs(cross) <= tol.angular:
            return [], abs(U[0] * w[1] - U[1] * w[0]) <= tol.linear
        s = (w[0] * V[1] - w[1] * V[0]) / cross
        return [(P + s * U, False)], False
    if p[0] == "line":
        (_, P, U), (_, c, r) = p, q
        U = _unit(U)
        foot = P + float((c - P) @ U) * U
        dist = float(np.linalg.norm(c - foot))
        if dist > r + tol.linear:
            return [], False
        if abs(dist - r) <= tol.linear:
            return [(foot, True)], False
        half = math.sqrt(r * r - dist * dist)
        return [(foot + half * U, False), (foot - half * U, False)], False
    (_, c1, r1), (_, c2, r2) = p, q
    w = c2 - c1
    d = float(np.linalg.norm(w))
    if d <= tol.linear:
        return [], abs(r1 - r2) <= tol.linear
    if d > r1 + r2 + tol.linear or d < abs(r1 - r2) - tol.linear:
        return [], False
    e = w / d
    x = (d * d + r1 * r1 - r2 * r2) / (2.0 * d)
    if abs(d - (r1 + r2)) <= tol.linear or abs(d - abs(r1 - r2)) <= tol.linear:
        return [(c1 + x * e, True)], False
    y = math.sqrt(max(r1 * r1 - x * x, 0.0))
    f = np.array([-e[1], e[0]])
    return [(c1 + x * e + y * f, False), (c1 + x * e - y * f, False)], False


def _common_axis(a, b, tol: Tolerance) -> tuple[np.ndarray, np.ndarray] | None:
    """An axis about which both surfaces are symmetric, or ``None``."""
    if isinstance(a, PlanarSurface) and isinstance(b, PlanarSurface):
        return None
    if isinstance(b, PlanarSurface):
        a, b = b, a
    if isinstance(a, PlanarSurface):
        ax = _axis_of(b)
        if ax is None:
            return b.center, a.axis
        return (ax[0], ax[1]) if _sine(a.axis, ax[1]) <= tol.angular else None
    ax_a, ax_b = _axis_of(a), _axis_of(b)
    if ax_a is None and ax_b is None:
        w = b.center - a.center
        d = float(np.linalg.norm(w))
        return (a.center, w / d) if d > tol.linear else (a.center, a.axis)
    if ax_a is None:
        ax_a, ax_b, a, b = ax_b, ax_a, b, a
    if ax_b is None:
        return ax_a if _off_axis(b.center, *ax_a) <= tol.linear else None
    if _sine(ax_a[1], ax_b[1]) > tol.angular or _off_axis(ax_b[0], *ax_a) > tol.linear:
        return None
    return ax_a


def _coaxial(a, b, tol: Tolerance) -> _Exact | None:
    """Surfaces of revolution (or planes, spheres) about one axis: circles where the meridians meet.

    Mirrored for many plane–cylinder pairs at once by :func:`_plane_cylinder_circles`: keep the two in step.
    """
    axis = _common_axis(a, b, tol)
    if axis is None:
        return None
    A, Z = axis
    X = perpendicular_direction(Z)
    found: list[tuple[np.ndarray, bool]] = []
    for p in _meridian(a, A, Z):
        for q in _meridian(b, A, Z):
            pts, same = _meet(p, q, tol)
            if same:
                return _Exact(coincident=True)
            found += pts
    candidates, points, seen = [], [], []
    for (rho, z), tangent in found:
        if rho < -tol.linear or any(abs(z - z2) <= tol.linear and abs(rho - r2) <= tol.linear for z2, r2 in seen):
            continue  # the mirror half-plane, or the same circle met twice (a cone's nappes at the apex)
        seen.append((z, rho))
        if rho <= tol.linear:
            points.append(A + z * Z)
        else:
            candidates.append(_Candidate(Circle(A + z * Z, Z, X, rho), tangent, uniform=True))
    return _Exact(tuple(candidates), tuple(points))


def _exact(a, b, tol: Tolerance) -> _Exact | None:
    """The closed-form case for the pair, or ``None`` when it has none."""
    if not (isinstance(a, _ANALYTIC) and isinstance(b, _ANALYTIC)):
        return None
    if isinstance(b, PlanarSurface) and not isinstance(a, PlanarSurface):
        a, b = b, a  # the cases below take the plane first; the branches do not depend on the order
    if isinstance(a, PlanarSurface):
        if isinstance(b, PlanarSurface):
            return _plane_plane(a, b, tol)
        if isinstance(b, CylindricalSurface) and (found := _plane_cylinder(a, b, tol)) is not None:
            return found
        if isinstance(b, ConicalSurface) and (found := _plane_cone(a, b, tol)) is not None:
            return found
        if isinstance(b, ToroidalSurface) and (found := _plane_torus_meridians(a, b, tol)) is not None:
            return found
    if isinstance(a, CylindricalSurface) and isinstance(b, CylindricalSurface):
        if (found := _parallel_cylinders(a, b, tol)) is not None:
            return found
        if (found := _equal_cylinders(a, b, tol)) is not None:
            return found
        if (found := _crossing_cylinders(a, b, tol)) is not None:
            return found
    return _coaxial(a, b, tol)


# ---------------------------------------------------------------------------- p-curves and clipping
def _reversed(curve):
    """The same point set run the other way (``t -> -t``)."""
    if isinstance(curve, Line):
        return Line(curve.origin, -curve.direction)
    if isinstance(curve, Circle):
        return Circle(curve.center, -curve.axis, curve.x_dir, curve.radius)
    return Ellipse(curve.center, -curve.axis, curve.x_dir, curve.major_radius, curve.minor_radius)


def _frozen(a: np.ndarray) -> np.ndarray:
    a.setflags(write=False)
    return a


# Parameters spread over a curve (irrational offsets keep off apexes and poles placed at round values);
# computed once: they depend only on whether the curve is a line.
# Any spread does along a line: n_a × n_b keeps its side along it (apexes are handled per piece).
_LINE_SAMPLES = _frozen((np.arange(_FORM_SAMPLES) - (_FORM_SAMPLES - 1) / 2.0 + _OFFSET) * 0.25)
_TURN_SAMPLES = _frozen((np.arange(_FORM_SAMPLES) + _OFFSET) * (TWO_PI / _FORM_SAMPLES))


def _sample_parameters(curve) -> np.ndarray:
    """Parameters spread over a curve (read-only, shared)."""
    return _LINE_SAMPLES if isinstance(curve, Line) else _TURN_SAMPLES


def _oriented(cand: _Candidate, a, b, tol: Tolerance) -> Any:
    """The candidate's curve, reversed if needed so that it runs along ``n_a × n_b`` (transversal branches)."""
    if cand.tangent or cand.singular:
        return cand.curve  # (a curve with singular points is oriented window by window in _branches)
    if cand.uniform:
        along = _uniform_side(cand.curve, a, b, tol)
        if along is not None:
            return cand.curve if along else _reversed(cand.curve)
    t = _sample_parameters(cand.curve)
    D = cand.curve.derivatives(t, 1)
    P, T = D[:, 0], D[:, 1]
    na = _normals(a, P)
    nb = _normals(b, P)
    cross = _cross(na, nb)
    strength = np.linalg.norm(cross, axis=-1)
    i = int(np.argmax(strength))  # the most transversal sample decides (poles and apexes give bad normals)
    return cand.curve if float(cross[i] @ T[i]) >= 0.0 else _reversed(cand.curve)


#: Least sine of the angle between the surfaces at which :func:`_uniform_side` decides a uniform
#: candidate's direction from one point (below it, the sampled rule of :func:`_oriented` runs).
_UNIFORM_MIN_SINE = 1e-6
#: Factor on the tolerances and round-off that bound how much ``(n_a × n_b)·T`` may vary along a
#: uniform candidate (:func:`_uniform_side`); generous: the variation is a small multiple of them.
_UNIFORM_SLACK = 1e3


def _uniform_side(curve, a, b, tol: Tolerance) -> bool | None:
    """Whether a uniform candidate's curve runs along ``n_a × n_b``, decided at its first sample, or None.

    Along a uniform candidate (see :class:`_Candidate`) ``(n_a × n_b)·T`` is one value ``κ`` at every
    sample of :func:`_oriented`, up to round-off and to the small misalignment the exact cases
    tolerate (``tol.angular`` between axes, ``tol.linear`` off an axis, over the smallest radius
    ``r`` involved).  Where ``|κ| / |T|`` (the sine of the angle between the surfaces) exceeds
    :data:`_UNIFORM_MIN_SINE` plus :data:`_UNIFORM_SLACK` times those bounds, every sample has
    the sign of the value at the first one, so the sampled rule (the most transversal sample
    decides) gives this same answer.  Planes, cylinders and spheres only (their normals in
    Python floats); None for other surfaces, points on a cylinder's axis or a sphere's centre, and
    near-tangent pairs: the caller samples.

    Mirrored for many plane–cylinder pairs at once by :func:`_plane_cylinder_circles`: keep the two in step.
    """
    if isinstance(curve, Circle):
        X, Y, _ = curve._frame.tolist()
        C, R = curve._origin.tolist(), curve.radius
        c, s = math.cos(_TURN_SAMPLES[0]), math.sin(_TURN_SAMPLES[0])
        P = [C[k] + R * (c * X[k] + s * Y[k]) for k in range(3)]
        T = [R * (c * Y[k] - s * X[k]) for k in range(3)]
        r = R
    elif isinstance(curve, Line):
        O, D = curve.origin.tolist(), curve.direction.tolist()
        t = float(_LINE_SAMPLES[0])
        P = [O[k] + t * D[k] for k in range(3)]
        T, r = D, math.inf
    else:
        return None
    scale = 1.0 + max(map(abs, P))
    n = []
    for surf in (a, b):
        if isinstance(surf, PlanarSurface):
            n.append(surf._frame[2].tolist())
            continue
        if not isinstance(surf, (CylindricalSurface, SphericalSurface)):
            return None
        O = surf._origin.tolist()
        w = [P[k] - O[k] for k in range(3)]
        if isinstance(surf, CylindricalSurface):
            Z = surf._frame[2].tolist()
            h = w[0] * Z[0] + w[1] * Z[1] + w[2] * Z[2]
            w = [w[k] - h * Z[k] for k in range(3)]
        size = math.hypot(*w)
        if size == 0.0:
            return None
        n.append([x / size for x in w])
        r = min(r, surf.radius)
        scale = max(scale, 1.0 + max(map(abs, O)))
    (a0, a1, a2), (b0, b1, b2) = n
    value = (a1 * b2 - a2 * b1) * T[0] + (a2 * b0 - a0 * b2) * T[1] + (a0 * b1 - a1 * b0) * T[2]
    bound = _UNIFORM_MIN_SINE + _UNIFORM_SLACK * (tol.angular + (tol.linear + _EPS * scale) / r)
    if abs(value) <= bound * math.hypot(*T):
        return None
    return value > 0.0


def _normals(s, P: np.ndarray) -> np.ndarray:
    """``s.normal`` at the closest parameters of points ``P (k, 3)``, ``(k, 3)``.

    Planes, cylinders and spheres in closed form (the same directions up to round-off, without
    the parameter round trip, whose per-call cost dominates on the few points here): a plane's
    normal is its axis, a cylinder's the outward unit radial ``e(u)`` of the point, a sphere's
    the outward unit ``(P - C) / |P - C|``.  A point on the cylinder's axis or at the sphere's
    centre (where the radial direction is undefined and ``closest_parameters`` picks a
    convention) goes through the surface's own methods.
    """
    if isinstance(s, PlanarSurface):
        return np.broadcast_to(s._frame[2], P.shape)
    if isinstance(s, CylindricalSurface):
        L = (P - s._origin) @ s._frame[:2].T
        rho = np.hypot(L[:, 0], L[:, 1])
        if np.all(rho > 0.0):
            return (L / rho[:, None]) @ s._frame[:2]
    elif isinstance(s, SphericalSurface):
        w = P - s._origin
        r = np.linalg.norm(w, axis=-1)
        if np.all(r > 0.0):
            return w / r[:, None]
    return s.normal(*s.closest_parameters(P).T)


def _pole_parameters(curve, s, tol: Tolerance) -> list[float]:
    """Parameters of ``curve`` (a circle) at the poles of the sphere ``s``."""
    if not (isinstance(s, SphericalSurface) and isinstance(curve, Circle)):
        return []
    out = []
    for sgn in (1.0, -1.0):
        P = s.center + sgn * s.radius * s.axis
        w = P - curve.center
        if abs(float(w @ curve.axis)) <= tol.linear and abs(float(np.linalg.norm(w)) - curve.radius) <= tol.linear:
            out.append(float(curve.closest_parameters(P)) % TWO_PI)
    return out


def _form_parameters(window: tuple[float, float]) -> np.ndarray:
    """The :data:`_FORM_SAMPLES` parameters on which a coordinate's form is fitted (off the window ends by
    ``_OFFSET / _FORM_SAMPLES`` of it, far more than the pole inset, so no clipping applies to them); read-only."""
    return _form_basis(float(window[0]), float(window[1]))[0]


@functools.lru_cache(maxsize=256)
def _form_basis(w0: float, w1: float) -> tuple[np.ndarray, np.ndarray]:
    """``(t, basis)``: the form parameters of the window ``[w0, w1]`` and the basis ``(1, t, cos t, sin t)``
    ``(_FORM_SAMPLES, 4)`` on them, both read-only.  Cached: every circle not cut at a pole has the window
    ``[0, 2π]``, and the same window serves both surfaces of a pair."""
    t = w0 + (w1 - w0) * (np.arange(_FORM_SAMPLES) + _OFFSET) / _FORM_SAMPLES
    return _frozen(t), _frozen(np.stack([np.ones_like(t), t, np.cos(t), np.sin(t)], axis=-1))


def _coords(surface, curve, window: tuple[float, float], full: bool, tol: Tolerance) -> list["_Coord"]:
    """Both coordinates ``[u, v]`` of the p-curve of ``curve`` on ``surface``, from one projection of the samples
    (or in closed form, :func:`_closed_coords`).

    Numeric coordinates are remembered per surface for curves equal in value (:data:`_COORDS`): the
    faces of one surface meet the faces of another in several pairs (a sphere's two halves against
    another sphere's), each pair finds the same exact curve, and its coordinates differ only by the
    boxes, which the coordinates do not depend on."""
    closed = _closed_coords(surface, curve, window, full, tol)
    if closed is not None:
        return closed
    key = _curve_key(curve)
    per = None
    if key is not None:
        key = (key, float(window[0]), float(window[1]), bool(full), tol.linear, tol.angular, tol.solver)
        try:
            per = _COORDS.get(surface)
            if per is None:
                per = _COORDS[surface] = {}
        except TypeError:  # not weak-referenceable or not hashable: no memo
            per = None
        states = per.get(key) if per is not None else None
        if states is not None:
            return [_Coord.restored(surface, curve, state) for state in states]
    uv = np.asarray(_projected(surface, curve, _form_parameters(window)), dtype=np.float64)
    out = [_Coord(surface, curve, i, window, full, tol, samples=uv[..., i]) for i in (0, 1)]
    if per is not None:
        if len(per) >= _COORDS_PER_SURFACE:
            del per[next(iter(per))]  # the oldest: a long-lived surface met by many curves keeps the latest
        per[key] = [c.state() for c in out]
    return out


#: Surface -> ``{(curve key, window, full, tolerance): states}``: the :meth:`_Coord.state` of both numeric
#: coordinates of a curve on that surface (:func:`_coords`), found again for a curve equal in value
#: (:func:`_curve_key`).  The states hold arrays and numbers, never the surface or the curve: an entry
#: dies with its surface.
_COORDS: "weakref.WeakKeyDictionary[Any, dict]" = weakref.WeakKeyDictionary()
#: Most curves remembered per surface in :data:`_COORDS` (two reference grids of ~4 kB each per curve).
_COORDS_PER_SURFACE = 32


def _curve_key(curve) -> bytes | None:
    """The bytes of what a line, circle or ellipse evaluates from (its type, origin or centre, frame or
    direction, radii): equal keys, the same points at every parameter; None for other curves."""
    kind = type(curve)
    if kind is Circle or kind is Ellipse:
        parts = (curve._origin, curve._frame, np.array(curve._radii(), dtype=np.float64))
    elif kind is Line:
        parts = (curve.origin, curve.direction)
    else:
        return None
    return kind.__name__.encode() + b"".join(np.ascontiguousarray(x, dtype=np.float64).tobytes() for x in parts)


def _closed_coords(surface, curve, window: tuple[float, float], full: bool, tol: Tolerance) -> list["_Coord"] | None:
    """The two exact coordinates of the p-curve in closed form where the pair has one, else None.

    * A line, circle or ellipse in a plane: the plane's parameters are the affine map
      ``(P - O)·X, (P - O)·Y``, so a line gives ``o + d t`` and a conic ``C + a cos t X_c + b sin t Y_c``
      gives ``o + α cos t + β sin t`` with ``o = (C - O)·X``, ``α = a X_c·X``, ``β = b Y_c·X`` (and ``Y``).
    * A circle coaxial with a surface of revolution (its axis along ``±Z`` and its centre on the
      axis, within ``tol.solver`` relative: the round-off of the exact constructions, below what
      the sample fit of :class:`_Coord` calls exact): the longitude is ``u(t₀) ± (t - t₀)`` (``+``
      when the circle's axis is ``Z``: both angles are measured in right-handed frames about it)
      and the other parameter is constant, ``v(t₀)``, with ``u(t₀), v(t₀)`` the projection of
      the first form sample ``t₀`` (where the fit's unwrapping starts).

    The coefficients are then treated as the fit's are: those below ``tol.solver`` of the
    coordinates' size become 0, a closed curve's slope is rounded to whole turns.

    Mirrored for many plane–cylinder pairs at once by :func:`_plane_cylinder_circles`: keep the two in step.
    """
    t = _form_parameters(window)
    if isinstance(surface, PlanarSurface):
        if not isinstance(curve, (Line, Circle, Ellipse)):
            return None
        F, O = surface._frame[:2], surface._origin
        if isinstance(curve, Line):
            o, d = F @ (curve.origin - O), F @ curve.direction
            coef = np.array([[o[0], d[0], 0.0, 0.0], [o[1], d[1], 0.0, 0.0]])
        else:
            ra, rb = curve._radii()
            X, Y, _ = curve._frame
            o, al, be = F @ (curve._origin - O), ra * (F @ X), rb * (F @ Y)
            coef = np.array([[o[0], 0.0, al[0], be[0]], [o[1], 0.0, al[1], be[1]]])
    elif isinstance(surface, _REVOLVED) and isinstance(curve, Circle):
        Z, Zc = surface.axis, curve._frame[2]
        if _sine(Zc, Z) > tol.solver:
            return None
        if _off_axis(curve._origin, surface._origin, Z) > tol.solver * curve.radius:
            return None
        sgn = 1.0 if float(Zc @ Z) > 0.0 else -1.0
        u0, v0 = _first_parameters(surface, curve, t[:1])
        t0 = float(t[0])
        coef = np.array([[u0 - sgn * t0, sgn, 0.0, 0.0], [v0, 0.0, 0.0, 0.0]])
        # The sizes as the basis product below gives them: its only inexact operation is the
        # one rounding of u0 - sgn t0 + sgn t (the products by 0, 1 and ±1 are exact).
        o = u0 - sgn * t0
        sizes = [max(abs(o + sgn * x) for x in t.tolist()), abs(v0)]
    else:
        return None
    if isinstance(surface, PlanarSurface):
        basis = _form_basis(float(window[0]), float(window[1]))[1]
        # Both coordinates' sizes on the samples in one product.
        sizes = np.max(np.abs(basis @ coef.T), axis=0).tolist()
    out = []
    for i, row in enumerate(coef.tolist()):  # four Python floats: cheaper than numpy on so few
        scale = max(1.0, sizes[i], abs(window[0]), abs(window[1]))
        small = tol.solver * scale
        c = [0.0 if abs(x) <= small else x for x in row]
        if full and abs(c[1] - round(c[1])) <= small:
            c[1] = float(round(c[1]))
        out.append(_Coord.exact_form(surface, curve, i, window, full, np.array(c)))
    return out


def _projected(surface, curve, t: np.ndarray) -> np.ndarray:
    """``surface.closest_parameters(curve.evaluate(t))`` for finite ``t`` ``(k,)``: ``(k, 2)``.

    A line, circle or ellipse on a sphere or cylinder by the same expressions as those methods (the curve's
    points of :func:`_curve_points`, the local coordinates by the same product, ``_angle``, and the sphere's
    ``arctan2(z, ρ)``) without their argument checks, which cost as much as the arithmetic on the few dozen
    points of a numeric coordinate's samples; other pairs through their methods.  It mirrors
    ``analytic._Revolved._polar`` and the surfaces' ``closest_parameters``: keep them in step (a test compares
    them bit for bit).
    """
    kind = type(surface)
    if (kind is SphericalSurface or kind is CylindricalSurface) and type(curve) in (Line, Circle, Ellipse):
        L = (_curve_points(curve, t) - surface._origin) @ surface._frame.T
        x, y, z = L[..., 0], L[..., 1], L[..., 2]
        phi = _angle(y, x)
        return np.stack([phi, np.arctan2(z, np.hypot(x, y)) if kind is SphericalSurface else z], axis=-1)
    return surface.closest_parameters(curve.evaluate(t))


def _first_parameters(surface, curve, t: np.ndarray) -> tuple[float, float]:
    """``surface.closest_parameters(curve.evaluate(t))`` of one parameter ``t`` ``(1,)`` as two floats.

    On a cylinder, the same operations as its ``closest_parameters`` (the local coordinates by the
    same product, then the angle of ``_angle`` in Python floats around numpy's ``arctan2``) without
    its argument checks and array bookkeeping; other surfaces through their method.

    Mirrored for many plane–cylinder pairs at once by :func:`_plane_cylinder_circles`: keep the two in step.
    """
    P = _curve_points(curve, t)
    if type(surface) is not CylindricalSurface:
        return tuple(float(x) for x in np.asarray(surface.closest_parameters(P))[0])
    x, y, z = ((P - surface._origin) @ surface._frame.T)[0].tolist()
    u = float(np.arctan2(y, x))
    if u < 0.0:
        u += TWO_PI
    if u >= TWO_PI or (x == 0.0 and y == 0.0):  # -tiny + 2π rounds to 2π; 0 on the axis
        u = 0.0
    return u, z


class _Coord:
    """One coordinate of a p-curve as a function of the branch parameter.

    Exact: ``f(t) = o + d t + α cos t + β sin t``.  Otherwise numeric: the surface's
    ``closest_parameters`` of the curve point, unwrapped (periodic coordinates) along a
    reference grid over ``window`` (extended by whole turns for a closed curve).
    """

    def __init__(self, surface, curve, index: int, window: tuple[float, float], full: bool, tol: Tolerance,
                 samples: np.ndarray | None = None):
        self.surface, self.curve, self.index, self.window, self.full = surface, curve, index, window, full
        self.tol = tol
        self.periodic = bool(surface.periodic_u if index == 0 else surface.periodic_v)
        is_line = isinstance(curve, Line)
        w0, w1 = window
        t = _form_parameters(window)
        g = self._raw(t) if samples is None else samples
        if self.periodic:
            g = np.unwrap(g, period=TWO_PI)
        basis = np.stack([np.ones_like(t), t] + ([] if is_line else [np.cos(t), np.sin(t)]), axis=-1)
        coef, *_ = np.linalg.lstsq(basis, g, rcond=None)
        # Parameters of exact points come back with round-off ~1e-15 relative; tol.solver (the
        # relative accuracy asked of solvers and parametric checks) separates that from a
        # coordinate of another form.
        scale = max(1.0, float(np.max(np.abs(g))), abs(w0), abs(w1))
        small = tol.solver * scale
        self.exact = float(np.max(np.abs(basis @ coef - g))) <= small
        coef = np.where(np.abs(coef) <= small, 0.0, coef)
        if self.exact and full and abs(coef[1] - round(coef[1])) <= small:
            coef[1] = round(coef[1])  # a closed curve winds a whole number of times
        self.coef = np.concatenate([coef, np.zeros(4 - len(coef))])
        self.turns = 0
        if not self.exact and self.periodic:
            # The reference that unwraps a periodic coordinate in __call__ (a non-periodic one needs none).
            n = _SEARCH_SAMPLES
            self.grid = _frozen(np.linspace(w0, w1, n + 1))
            self.ref = _frozen(np.unwrap(self._raw(self.grid), period=TWO_PI))
            self.turns = round((self.ref[-1] - self.ref[0]) / TWO_PI) if full else 0
        _frozen(self.coef)
        self._crossed: dict[tuple[float, float, float], np.ndarray] = {}  # crossings of a numeric coordinate

    def state(self) -> dict:
        """What the coordinate computed from its surface and curve (all but those two objects), for
        :meth:`restored`; the crossings found so far and later are shared with the restored copies."""
        return {k: v for k, v in self.__dict__.items() if k not in ("surface", "curve")}

    @classmethod
    def restored(cls, surface, curve, state: dict) -> "_Coord":
        """The coordinate of :meth:`state` on ``surface`` along ``curve`` (equal in value to the curve it was
        computed for)."""
        self = object.__new__(cls)
        self.__dict__.update(state)
        self.surface, self.curve = surface, curve
        return self

    @classmethod
    def exact_form(cls, surface, curve, index: int, window: tuple[float, float], full: bool,
                   coef: np.ndarray) -> "_Coord":
        """The coordinate known in closed form: ``coef = (o, d, α, β)`` (4,)."""
        self = object.__new__(cls)
        self.surface, self.curve, self.index, self.window, self.full = surface, curve, index, window, full
        self.periodic = bool(surface.periodic_u if index == 0 else surface.periodic_v)
        self.exact = True
        self.coef = np.asarray(coef, dtype=np.float64)
        self._crossed = None  # (closed-form crossings are not remembered)
        return self

    def _raw(self, t: np.ndarray) -> np.ndarray:
        return _projected(self.surface, self.curve, self._inset(t))[..., self.index]

    def _inset(self, t: np.ndarray) -> np.ndarray:
        """The parameters where :meth:`_raw` projects the curve: ``t`` itself, but on a periodic coordinate whose
        window is cut at sphere poles, where the longitude is undefined, clipped a relative sqrt(eps) inside
        the window (the limit to ~1e-8; the 3-D point does not depend on it there, and the local coordinates
        near the pole keep ~8 significant digits)."""
        if self.periodic and not self.full:
            w0, w1 = self.window
            inset = _POLE_INSET * (w1 - w0)
            return np.clip(t, w0 + inset, w1 - inset)
        return t

    @property
    def affine(self) -> bool:
        return self.exact and self.coef[2] == 0.0 and self.coef[3] == 0.0

    @property
    def trigonometric(self) -> bool:
        return self.exact and self.coef[1] == 0.0

    def __call__(self, t) -> np.ndarray:
        t = np.asarray(t, dtype=np.float64)
        if self.exact:
            o, d, al, be = self.coef
            return o + d * t + al * np.cos(t) + be * np.sin(t)
        return self._unwrapped(t, self._raw(t))

    def _unwrapped(self, t: np.ndarray, raw: np.ndarray) -> np.ndarray:
        """A numeric coordinate's value at ``t`` from its :meth:`_raw` projection ``raw`` there."""
        if not self.periodic:
            return raw
        w0 = self.window[0]
        turn = np.floor((t - w0) / TWO_PI) if self.full else np.zeros_like(t)
        ref = np.interp(t - turn * TWO_PI, self.grid, self.ref) + turn * TWO_PI * self.turns
        return raw + TWO_PI * np.round((ref - raw) / TWO_PI)

    def values(self, t: list[float]) -> list[float]:
        """An exact coordinate at parameters ``t`` as a list: ``self(t)`` value for value (the terms of zero
        coefficients left out, which changes at most the sign of a zero result)."""
        o, d, al, be = self.coef.tolist()
        if al == 0.0 and be == 0.0:
            return [o + d * x for x in t]
        arr = np.array(t, dtype=np.float64)
        return [o + d * x + al * c + be * s for x, c, s in zip(t, np.cos(arr).tolist(), np.sin(arr).tolist())]

    def crossings(self, bound: float, t0: float, t1: float) -> np.ndarray:
        """Parameters in ``(t0, t1)`` where the coordinate equals ``bound`` (modulo 2π if periodic)."""
        if not math.isfinite(bound):
            return np.zeros(0)
        o, d, al, be = self.coef
        if self.exact and al == 0.0 and be == 0.0:
            if d == 0.0:
                return np.zeros(0)
            f0, f1 = sorted((o + d * t0, o + d * t1))
            targets = self._targets(bound, f0, f1)
            return (targets - o) / d
        if self.exact and d == 0.0:
            r, phi = math.hypot(al, be), math.atan2(be, al)
            targets = self._targets(bound, o - r, o + r)
            if targets.size == 0:
                return np.zeros(0)  # the bound lies beyond the coordinate's range
            c = np.clip((targets - o) / r, -1.0, 1.0)
            base = np.concatenate([phi + np.arccos(c), phi - np.arccos(c)])
            k0, k1 = math.floor((t0 - phi) / TWO_PI) - 1, math.ceil((t1 - phi) / TWO_PI) + 1
            out = (base[:, None] + TWO_PI * np.arange(k0, k1 + 1)[None, :]).ravel()
            return np.unique(out[(out > t0) & (out < t1)])
        memo = self._crossed
        key = (bound, t0, t1)
        if memo is not None and key in memo:
            return memo[key]
        found = _conic_crossings(self, bound, t0, t1)
        found = self._searched_crossings(bound, t0, t1) if found is None else found
        if memo is not None:
            memo[key] = _frozen(found)
        return found

    def _searched_crossings(self, bound: float, t0: float, t1: float) -> np.ndarray:
        """:meth:`crossings` of a coordinate without a closed form: bracket sign changes on a grid of
        :data:`_SEARCH_SAMPLES`, then solve all brackets at once (:func:`_illinois`)."""
        grid = np.linspace(t0, t1, _SEARCH_SAMPLES + 1)
        f = self(grid)
        targets = self._targets(bound, float(f.min()), float(f.max()))
        if targets.size == 0:
            return np.zeros(0)
        g = f[None, :] - targets[:, None]
        i, j = np.nonzero(np.signbit(g[:, :-1]) != np.signbit(g[:, 1:]))
        # The grid's own values and signs: re-evaluating at one point may round the other way.
        return _illinois(lambda t, k: self(t) - targets[i[k]], grid[j], grid[j + 1], g[i, j], g[i, j + 1])

    def _targets(self, bound: float, f0: float, f1: float) -> np.ndarray:
        """``bound + 2πk`` within ``[f0, f1]`` (only ``bound`` if not periodic), :func:`_target_values`."""
        return np.array(_target_values(self.periodic, bound, f0, f1), dtype=np.float64)


def _conic_crossings(c: _Coord, bound: float, t0: float, t1: float) -> np.ndarray | None:
    """``c.crossings(bound, t0, t1)`` of a conic's non-exact coordinate on a surface of revolution in closed
    form, or None where it has none (then the sampled search decides).

    With ``P(t) = C + a cos t X_c + b sin t Y_c`` and the surface's frame ``X, Y, Z`` at ``O``:

    * The longitude of a cylinder, sphere or torus is the azimuth of ``P - O`` about ``Z`` (a cone's
      is not: a point nearer the other nappe gets the azimuth + π).  It is ``u0`` (mod 2π) where
      ``P`` lies in the meridian half-plane: ``(P - O)·n = 0`` with ``n = -sin u0 X + cos u0 Y``,
      i.e. ``A cos t + B sin t = -k`` with ``A = a X_c·n``, ``B = b Y_c·n``, ``k = (C - O)·n``, so
      ``t = φ ± arccos(-k / r)``, ``φ = atan2(B, A)``, ``r = hypot(A, B)``; the roots on the other
      half-plane, ``(P - O)·e < 0`` with ``e = cos u0 X + sin u0 Y``, are dropped.
    * A sphere's latitude reaches ``±π/2`` only on the axis: no crossing where the curve keeps
      clear of it (``_axis_clear``); a bound beyond ``±π/2`` is never reached.

    None where the answer is ill-conditioned, for the sampled search to decide as before: a
    near-tangency (``|k| / r`` within :data:`_GRAZE` of 1: two close roots the grid may not
    separate), a root within :data:`_AXIS_CLEARANCE` of the axis (a circle through a pole: the
    longitude jumps there), a meridian plane containing the curve (``r`` at round-off), any other
    bound of a latitude, and a root whose coordinate value does not come back to ``bound``
    (mod 2π) within ``tol.solver``.  The roots are ordered as the sampled search orders them:
    by the whole turn of their (unwrapped) value, then by ``t``.  Unlike the search, a root exactly at
    ``t0`` or ``t1`` is left out: the callers break the window at its ends anyway.
    """
    surface, curve = c.surface, c.curve
    if c.exact or not isinstance(curve, (Circle, Ellipse)) or not isinstance(surface, _AZIMUTHAL):
        return None
    O = surface._origin
    X, Y, Z = surface._frame
    ra, rb = curve._radii()
    Xc, Yc, _ = curve._frame
    C = curve._origin - O
    scale = math.sqrt(float(C @ C)) + ra
    if c.index == 1:
        if type(surface) is not SphericalSurface:
            return None
        if abs(bound) > 0.5 * math.pi:
            return np.zeros(0)
        if abs(bound) == 0.5 * math.pi and _axis_clear(C, ra * Xc, rb * Yc, Z, scale):
            return np.zeros(0)
        return None
    cu, su = math.cos(bound), math.sin(bound)
    n, e = cu * Y - su * X, cu * X + su * Y
    k, A, B = float(C @ n), ra * float(Xc @ n), rb * float(Yc @ n)
    r = math.hypot(A, B)
    if r <= _AXIS_CLEARANCE * scale:
        return None
    x = -k / r
    if abs(x) >= 1.0:
        return np.zeros(0) if abs(x) >= 1.0 + _GRAZE else None
    if 1.0 - abs(x) <= _GRAZE:
        return None
    phi, h = math.atan2(B, A), math.acos(x)
    lo, hi = math.floor((t0 - phi) / TWO_PI) - 1, math.ceil((t1 - phi) / TWO_PI) + 1
    t = np.array([phi + s * h + TWO_PI * j for j in range(lo, hi + 1) for s in (-1.0, 1.0)])
    t = t[(t > t0) & (t < t1)]
    if t.size == 0:
        return t
    P = _curve_points(curve, t) - O
    side = P @ e
    if np.any(np.abs(side) <= _AXIS_CLEARANCE * scale):
        return None
    t = t[side > 0.0]
    if t.size == 0:
        return t
    # The coordinate's own values at the roots: the whole turn of each (the order of the sampled
    # search), and a check that the closed form found what the search would.
    f = c(t)
    turn = np.round((f - bound) / TWO_PI)
    if np.any(np.abs(f - bound - TWO_PI * turn) > c.tol.solver * max(1.0, abs(bound), *np.abs(f))):
        return None
    return t[np.lexsort((t, turn))]


def _axis_clear(C: np.ndarray, a: np.ndarray, b: np.ndarray, Z: np.ndarray, scale: float) -> bool:
    """Whether ``P(t) = C + a cos t + b sin t`` (relative to a point of the axis ``Z``) keeps a distance above
    ``_AXIS_CLEARANCE * scale`` from the axis: the squared distance ``q(t) = |P⊥|²`` is the trigonometric
    polynomial ``k0 + k1 cos t + k2 sin t + k3 cos 2t + k4 sin 2t`` (``P⊥`` the part normal to ``Z``); its
    minimum is at least its minimum on :data:`_CLEAR_SAMPLES` samples less the bound ``|q'| ≤ |k1| + |k2| +
    2 |k3| + 2 |k4|`` times half their spacing."""
    C, a, b = C - (C @ Z) * Z, a - (a @ Z) * Z, b - (b @ Z) * Z
    aa, bb = float(a @ a), float(b @ b)
    k = np.array([float(C @ C) + 0.5 * (aa + bb), 2.0 * float(C @ a), 2.0 * float(C @ b), 0.5 * (aa - bb),
                  float(a @ b)])
    t = np.arange(_CLEAR_SAMPLES) * (TWO_PI / _CLEAR_SAMPLES)
    q = k[0] + k[1] * np.cos(t) + k[2] * np.sin(t) + k[3] * np.cos(2.0 * t) + k[4] * np.sin(2.0 * t)
    slope = abs(k[1]) + abs(k[2]) + 2.0 * (abs(k[3]) + abs(k[4]))
    low = float(q.min()) - slope * math.pi / _CLEAR_SAMPLES
    # The products above round at ~eps * scale²: far below the clearance asked.
    return low > (_AXIS_CLEARANCE * scale) ** 2


def _illinois(fn, lo: np.ndarray, hi: np.ndarray, glo: np.ndarray, ghi: np.ndarray) -> np.ndarray:
    """Roots of ``fn(t, k)`` (the function of bracket ``k`` at ``t``) in the brackets ``[lo, hi]``, all at once.

    The Illinois variant of regula falsi (Dowell & Jarratt 1971): superlinear, and the root stays
    bracketed (a false-position point outside its bracket, or not finite, is replaced by the
    midpoint).  A bracket is done when its value is exactly zero or its width is within four
    ulps of its ends; at most :data:`_ROOT_STEPS` steps (what bisection to the spacing of doubles
    needs).  Where a bracket is done by width the midpoint is returned, else the last point.
    """
    lo, hi, glo, ghi = (np.array(x, dtype=np.float64) for x in (lo, hi, glo, ghi))
    out = 0.5 * (lo + hi)
    side = np.zeros(lo.shape, dtype=np.int8)  # which end moved last: -1 lo, 1 hi
    act = np.arange(lo.size)
    for _ in range(_ROOT_STEPS):
        width = hi[act] - lo[act]
        done = width <= 4.0 * _EPS * np.maximum(np.abs(lo[act]), np.abs(hi[act]))
        out[act[done]] = 0.5 * (lo[act[done]] + hi[act[done]])
        act = act[~done]
        if act.size == 0:
            break
        a, b, ga, gb = lo[act], hi[act], glo[act], ghi[act]
        with np.errstate(divide="ignore", invalid="ignore"):
            x = (a * gb - b * ga) / (gb - ga)
        x = np.where(np.isfinite(x) & (x > a) & (x < b), x, 0.5 * (a + b))
        gx = np.asarray(fn(x, act), dtype=np.float64)
        out[act] = x
        zero = gx == 0.0
        left = (np.signbit(gx) != np.signbit(ga)) & ~zero  # the root lies in [a, x]: x becomes hi
        right = ~left & ~zero
        # Illinois: an end kept twice in a row has its value halved, so the next point moves past it.
        glo[act] = np.where(left & (side[act] == 1), 0.5 * ga, np.where(right, gx, ga))
        ghi[act] = np.where(right & (side[act] == -1), 0.5 * gb, np.where(left, gx, gb))
        hi[act] = np.where(left, x, b)
        lo[act] = np.where(right, x, a)
        side[act] = np.where(left, 1, np.where(right, -1, 0))
        act = act[~zero]
    return out


def _inside(values: np.ndarray, lo: float, hi: float, periodic: bool, slack: float) -> np.ndarray:
    """Whether coordinate values lie in ``[lo, hi]`` (modulo 2π for a periodic coordinate)."""
    if periodic:
        if hi - lo >= TWO_PI:
            return np.ones(np.shape(values), dtype=bool)
        values = lo + np.mod(values - lo + slack, TWO_PI) - slack
    return (values >= lo - slack) & (values <= hi + slack)


def _shift(coord: _Coord, t_mid: float, lo: float, hi: float, slack: float) -> float:
    """The multiple of 2π that moves a periodic coordinate's branch into ``[lo, hi]``.

    Mirrored for many plane–cylinder pairs at once by :func:`_plane_cylinder_circles`, and for the cylinder
    loops by :func:`_loop_piece`: keep the three in step.
    """
    if not coord.periodic or not math.isfinite(lo):
        return 0.0
    value = coord.values([t_mid])[0] if coord.exact else float(coord(t_mid))
    return TWO_PI * math.ceil((lo - slack - value) / TWO_PI)


def _public_pcurve(cu: _Coord, cv: _Coord, s0: float, s1: float, du: float, dv: float, surface, curve,
                   tol: Tolerance):
    """``(p-curve, deviation)`` over ``[s0, s1]`` with periodic shifts ``du, dv``: Line2D or Trig2D (deviation 0:
    measured later with the branch), or a fitted 2-D NURBS and its measured deviation."""
    if cu.exact and cv.exact:  # (the coefficients as Python floats: the same values, cheaper to pack)
        (ou, su, au, bu), (ov, sv, av, bv) = cu.coef.tolist(), cv.coef.tolist()
        if au == 0.0 and bu == 0.0 and av == 0.0 and bv == 0.0:
            return Line2D([ou + du, ov + dv], [su, sv]), 0.0
        if su == 0.0 and sv == 0.0 and au * bv - av * bu != 0.0:
            return Trig2D([ou + du, ov + dv], [au, av], [bu, bv]), 0.0
    return _fitted_pcurve(lambda t: _pair_values(cu, cv, t) + np.array([du, dv]), s0, s1, surface, curve, tol,
                          pointwise=True)


def _pair_values(cu: _Coord, cv: _Coord, t: np.ndarray) -> np.ndarray:
    """``np.stack([cu(t), cv(t)], axis=-1)`` ``(n, 2)`` of the two coordinates of one p-curve, value for value; where
    both are numeric and project the curve at the same parameters, from one projection (the fits' rounds
    evaluate both at every new sample)."""
    t = np.asarray(t, dtype=np.float64)
    if not (cu.exact or cv.exact) and (cu.index, cv.index) == (0, 1) and cu.surface is cv.surface \
            and cu.curve is cv.curve:
        tu, tv = cu._inset(t), cv._inset(t)
        if tu is tv or np.array_equal(tu, tv):
            raw = _projected(cu.surface, cu.curve, tu)
            return np.stack([cu._unwrapped(t, raw[..., 0]), cv._unwrapped(t, raw[..., 1])], axis=-1)
    return np.stack([cu(t), cv(t)], axis=-1)


def _fit_start(s0: float, s1: float) -> np.ndarray:
    """The first round's samples ``(_FIT_START,)`` of a fit over ``[s0, s1]``, graded towards the ends
    (:data:`_FIT_GRADE`), ``s0`` and ``s1`` exactly."""
    x = np.linspace(0.0, 1.0, _FIT_START)
    t = s0 + (s1 - s0) * (x - _FIT_GRADE * np.sin(TWO_PI * x) / TWO_PI)
    t[-1] = s1  # (sin 2π is not 0 in floating point)
    return t


#: The quarter points of every interval between samples, where a fit round measures its error.
_QUARTERS = _frozen(np.array([0.25, 0.5, 0.75]))
#: The first round of a fit takes its interpolating spline from :func:`_first_round` (True), not from scipy's
#: ``make_interp_spline``; tests switch it off to compare.
_FAST_FIRST = True


def _quarter_points(t: np.ndarray) -> np.ndarray:
    """``(3 (n - 1),)``: the quarter points of the intervals between the samples ``t`` (n,), interval by interval."""
    return (t[:-1, None] + _QUARTERS[None, :] * np.diff(t)[:, None]).ravel()


@functools.lru_cache(maxsize=8)
def _first_round(n: int, p: int, grade: float) -> tuple[np.ndarray, np.ndarray]:
    """``(inverse, at_quarters)``: the maps ``(n, n)`` and ``(3 (n - 1), n)`` from the values of a fit's first
    round at the samples of :func:`_fit_start` (``n`` of them, degree ``p``, grading ``grade``) to the control
    points of the interpolating spline and to its values at the quarter points (:func:`_quarter_points`).

    The samples and the averaged knots (The NURBS Book eq. 9.8) of every range ``[s0, s1]`` are the images
    of those of ``[0, 1]`` under ``x -> s0 + (s1 - s0) x``, and B-spline basis functions are invariant
    under that map: the collocation matrix and the basis at the quarter points are the same for every
    first round (to the round-off of the mapped parameters).  Two small products replace scipy's banded
    solve and evaluation, whose set-up cost was most of a round on the few samples of a first round.
    The collocation matrix is totally positive and well conditioned (condition number about 13 for the
    module's constants): the inverse loses nothing that the bound ``tol.linear / 2`` could see.  Cached
    per ``(n, p, grade)``: tests change the module's constants.
    """
    from scipy.interpolate import BSpline

    x = np.linspace(0.0, 1.0, n)  # (the samples of _fit_start on [0, 1])
    x = x - grade * np.sin(TWO_PI * x) / TWO_PI
    x[-1] = 1.0
    knots = _averaging(x, p)
    A = BSpline.design_matrix(x, knots, p).toarray()
    inverse = np.linalg.solve(A, np.eye(n))
    E = BSpline.design_matrix(_quarter_points(x), knots, p).toarray()
    return _frozen(inverse), _frozen(E @ inverse)


def _fit_round(t: np.ndarray, Q: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(at_quarters, control points, knots)`` of the spline of degree :data:`_FIT_DEGREE` interpolating ``Q``
    ``(n, d)`` at ``t`` (n,) on the averaged knots (The NURBS Book A9.1, eq. 9.8): its values ``(3 (n - 1), d)``
    at :func:`_quarter_points`.  ``t`` of :data:`_FIT_START` samples is :func:`_fit_start`'s (the first
    round: later rounds only add samples), solved by the matrices of :func:`_first_round`; otherwise
    scipy's banded collocation (``make_interp_spline``)."""
    knots = _averaging(t, _FIT_DEGREE)
    if _FAST_FIRST and t.size == _FIT_START:
        inverse, at_quarters = _first_round(_FIT_START, _FIT_DEGREE, _FIT_GRADE)
        return at_quarters @ Q, inverse @ Q, knots
    spline = make_interp_spline(t, Q, k=_FIT_DEGREE, t=knots)
    return spline(_quarter_points(t)), spline.c, spline.t


def _fitted_pcurve(f, s0: float, s1: float, surface, curve, tol: Tolerance, pointwise: bool = False):
    """``(p-curve, deviation)``: interpolation of the exact parameters ``f(t)`` by a spline of degree
    :data:`_FIT_DEGREE` ``p`` (The NURBS Book A9.1 with the averaged knots of eq. 9.8, solved by
    :func:`_fit_round`: the fixed matrices of :func:`_first_round`, then scipy's banded collocation of
    ``make_interp_spline``) from the graded samples of :func:`_fit_start`, refined
    adaptively: every interval whose image on
    ``surface`` misses ``curve`` by ``e`` more than ``b = tol.linear / 2`` at its quarter points is cut into
    ``ceil((e / b)^(1/(p+1)))`` equal parts (at least two, at most ``_MAX_FIT_SPLIT + 1``) by new samples, until
    none misses: the error of the interpolant falls with the ``p + 1``-th power of the spacing, so one round
    usually brings an interval within ``b`` where halving took several (each round refits and re-measures
    every interval).

    The rounds work on the arrays of :func:`_fit_round` and evaluate without argument checks
    (``_surface_points``, ``_curve_points``); only the accepted fit becomes a :class:`NurbsCurve`: on the few hundred
    samples of a fit, the checks and the per-call costs of ``interpolate_curve`` and
    ``NurbsCurve.evaluate`` were most of the time.

    ``pointwise``: ``f``'s value at a parameter does not depend on the other parameters passed
    with it (a :class:`_Coord` pair), so each round evaluates only the new samples; otherwise
    (an unwrapping over the whole array) every round evaluates all of them.

    Raises
    ------
    ConvergenceError
        Still off after growing to :data:`_MAX_FIT_SAMPLES` samples.
    """
    t = _fit_start(s0, s1)
    Q = f(t)
    worst = math.inf
    bound = 0.5 * tol.linear  # half: the other half of tol.linear is the other surface's
    while len(t) <= _MAX_FIT_SAMPLES:
        # Averaged knots (The NURBS Book eq. 9.8, as interpolate_curve), one collocation solve (_fit_round).
        uv, ctrl, knots = _fit_round(t, Q)
        tm = _quarter_points(t)
        gap = _surface_points(surface, uv[:, 0], uv[:, 1]) - _curve_points(curve, tm)
        e = np.sqrt(np.max(np.add.reduce(gap * gap, axis=-1).reshape(-1, 3), axis=1))
        worst = float(e.max())
        bad = np.flatnonzero(e > bound)
        if bad.size == 0:
            return NurbsCurve(ctrl, knots, _FIT_DEGREE), worst
        count = np.clip(np.ceil((e[bad] / bound) ** (1.0 / (_FIT_DEGREE + 1))) - 1.0, 1,
                        _MAX_FIT_SPLIT).astype(np.int64)
        owner, j = interval_cuts(bad, count)
        new = t[owner] + j * (t[owner + 1] - t[owner])
        if pointwise:
            order = np.argsort(np.concatenate([t, new]), kind="stable")
            t, Q = np.concatenate([t, new])[order], np.concatenate([Q, f(new)])[order]
        else:
            t = np.sort(np.concatenate([t, new]))
            Q = f(t)
    raise ConvergenceError(
        f"p-curve fit: deviation {worst:.3g} above {0.5 * tol.linear:.3g} with {_MAX_FIT_SAMPLES} samples",
        residuals=np.array([worst]),
    )


def _branches(cand: _Candidate, a, b, box_a, box_b, tol: Tolerance) -> list[IntersectionCurve]:
    """Clip one exact curve to both boxes and return its in-box pieces with their p-curves."""
    if isinstance(cand.curve, _CylinderLoop):
        return _loop_branches(cand.curve, a, b, box_a, box_b, tol)
    section = isinstance(cand.curve, _ConeSection)
    curve = cand.curve if section else _oriented(cand, a, b, tol)
    surfaces, boxes = (a, b), (box_a, box_b)
    # Slack of the parametric box tests: the relative round-off allowed by tol.solver.
    slack = tol.solver * max(1.0, *(abs(x) for box in boxes for r in box for x in r if math.isfinite(x)))
    if isinstance(curve, Line):
        windows, full = [(-1.0, 1.0)], False
    elif section:
        windows, full = curve.windows(box_a[1] if a is curve.cone else box_b[1]), False
    else:
        cuts = _pole_parameters(curve, a, tol) + _pole_parameters(curve, b, tol)
        cuts += [float(curve.closest_parameters(P)) % TWO_PI for P in cand.singular]
        cuts = sorted(set(cuts))
        if cuts:
            ends = cuts + [cuts[0] + TWO_PI]
            windows, full = list(zip(ends[:-1], ends[1:])), False
        else:
            windows, full = [(0.0, TWO_PI)], True
    out = []
    oriented = curve
    for window in windows:
        curve = oriented
        if cand.singular and not cand.tangent and _against(curve, 0.5 * (window[0] + window[1]), a, b):
            # n_a × n_b changes sign at the singular points: this piece runs the other way (t -> -t).
            curve, window = _reversed(curve), (-window[1], -window[0])
        coords = [_coords(s, curve, window, full, tol) for s in surfaces]
        pairs = [(c, box[i]) for cs, box in zip(coords, boxes) for i, c in enumerate(cs)]
        if isinstance(curve, Line):
            t0, t1 = -math.inf, math.inf
            for c, (lo, hi) in pairs:
                o, d = c.coef[0], c.coef[1]
                if d == 0.0:
                    if not _inside(np.array(o), lo, hi, c.periodic, slack):
                        t0, t1 = math.inf, -math.inf
                    continue
                r0, r1 = sorted(((lo - o) / d, (hi - o) / d))
                t0, t1 = max(t0, r0), min(t1, r1)
            if not (math.isfinite(t0) and math.isfinite(t1)) and t0 < t1:
                raise InvalidInputError(
                    f"intersect_surfaces: the line through {curve.origin.tolist()} along {curve.direction.tolist()} "
                    "is not bounded by the boxes; give finite boxes for planes, cylinders and cones"
                )
            pieces = [(t0, t1)] if t1 - t0 > slack else []
            # Su × Sv of a cone flips at its apex: a ruling through it is two branches, each
            # oriented on its own.
            apexes = [
                float((k.apex - curve.origin) @ curve.direction)
                for k in surfaces
                if isinstance(k, ConicalSurface) and _off_axis(k.apex, curve.origin, curve.direction) <= tol.linear
            ]
            for ta in apexes:
                pieces = [q for s0, s1 in pieces for q in (((s0, ta), (ta, s1)) if s0 < ta < s1 else ((s0, s1),))]
            if not cand.tangent:
                flipped = [p for p in pieces if _against(curve, 0.5 * (p[0] + p[1]), a, b)]
                if flipped:
                    rev = _reversed(curve)
                    rev_coords = [_coords(s, rev, window, full, tol) for s in surfaces]
                    for s0, s1 in flipped:
                        out.append(_piece(rev, rev_coords, -s1, -s0, a, b, boxes, slack, False, cand.tangent, tol))
                    pieces = [p for p in pieces if p not in flipped]
        else:
            w0, w1 = window
            if full:
                w0 = _start(pairs, slack)
                w1 = w0 + TWO_PI
            pieces = _exact_runs(pairs, w0, w1, full, slack)
        if not isinstance(curve, Line) and pieces is None:
            # A coordinate with a box of a whole period or more must not cross the box's lower
            # bound inside a branch (the p-curve would leave the box): its crossings are seams.
            breaks, seams = [np.array([w0, w1])], [np.zeros(0)]
            seam_at_start = False
            for c, (lo, hi) in pairs:
                if c.periodic and hi - lo >= TWO_PI:
                    seams.append(c.crossings(lo, w0, w1))
                    seam_at_start |= bool(_inside(c(np.array([w0])), lo, lo, True, slack)[0])
                else:
                    breaks += [c.crossings(lo, w0, w1), c.crossings(hi, w0, w1)]
            seam = np.concatenate(seams)
            br = np.unique(np.concatenate(breaks + [seam]))
            # One crossing found twice (from both sides of a grid point, or a seam that is also a
            # box bound) differs by round-off: keep the first of breakpoints closer than the slack.
            br = br[np.concatenate([[True], np.diff(br) > slack])]
            br[-1] = w1
            hard = np.min(np.abs(seam[:, None] - br[None, :]), axis=0, initial=np.inf) <= slack
            mid = 0.5 * (br[:-1] + br[1:])
            ok = np.ones(mid.shape, dtype=bool)
            for c, (lo, hi) in pairs:
                ok &= _inside(c(mid), lo, hi, c.periodic, slack)
            pieces = _runs(br, ok, hard, full and not seam_at_start)
        for s0, s1 in pieces:
            if s1 - s0 > slack and section:
                out.append(_conic_piece(curve, s0, s1, a, b, boxes, tol))
            elif s1 - s0 > slack:
                closed = full and s1 - s0 >= TWO_PI - slack
                out.append(_piece(curve, coords, s0, s1, a, b, boxes, slack, closed, cand.tangent, tol))
    return out


def _exact_runs(pairs, w0: float, w1: float, full: bool, slack: float) -> list[tuple[float, float]] | None:
    """The in-box runs of ``[w0, w1]`` when every coordinate is exact, in Python floats; None otherwise.

    The same operations as the array path of :func:`_branches` (breakpoints at the box crossings
    and seams, merged within the slack, tested at their midpoints), one value at a time: on the
    few values of a conic's window numpy's per-call cost exceeds the arithmetic.  None also where
    a breakpoint is zero or not finite (numpy's sort may order ``-0.0`` and ``0.0`` either way)
    or a crossing has no scalar form (:func:`_exact_crossings`): the array path decides then.

    Mirrored for many plane–cylinder pairs at once by :func:`_plane_cylinder_circles`: keep the two in step.
    """
    if not all(c.exact for c, _ in pairs):
        return None
    breaks, seam = [w0, w1], []
    seam_at_start = False
    for c, (lo, hi) in pairs:
        if c.periodic and hi - lo >= TWO_PI:
            found = _exact_crossings(c, lo, w0, w1)
            if found is None:
                return None
            seam += found
            seam_at_start |= _inside_value(c.values([w0])[0], lo, lo, True, slack)
        else:
            for bound in (lo, hi):
                found = _exact_crossings(c, bound, w0, w1)
                if found is None:
                    return None
                breaks += found
    values = breaks + seam
    if 0.0 in values or not all(map(math.isfinite, values)):
        return None
    br = sorted(set(values))
    br = [br[0]] + [br[i] for i in range(1, len(br)) if br[i] - br[i - 1] > slack]
    br[-1] = w1
    hard = [min((abs(x - b) for x in seam), default=math.inf) <= slack for b in br]
    mid = [0.5 * (x + y) for x, y in zip(br[:-1], br[1:])]
    ok = [True] * len(mid)
    for c, (lo, hi) in pairs:
        ok = [k and _inside_value(v, lo, hi, c.periodic, slack) for k, v in zip(ok, c.values(mid))]
    return _runs(br, ok, hard, full and not seam_at_start)


def _exact_crossings(c: "_Coord", bound: float, t0: float, t1: float) -> list[float] | None:
    """``c.crossings(bound, t0, t1)`` of an exact coordinate as a list, by the same operations one value at a
    time (numpy's ``arccos`` kept: its results differ from ``math.acos`` in the last bit); None where
    its result could hold a zero (see :func:`_exact_runs`)."""
    if not math.isfinite(bound):
        return []
    o, d, al, be = c.coef.tolist()
    if al == 0.0 and be == 0.0:
        if d == 0.0:
            return []
        f0, f1 = sorted((o + d * t0, o + d * t1))
        return [(x - o) / d for x in _target_values(c.periodic, bound, f0, f1)]
    if d != 0.0:
        return None
    r, phi = math.hypot(al, be), math.atan2(be, al)
    targets = _target_values(c.periodic, bound, o - r, o + r)
    if not targets:
        return []
    acos = [float(np.arccos(min(max((x - o) / r, -1.0), 1.0))) for x in targets]
    base = [phi + x for x in acos] + [phi - x for x in acos]
    k0, k1 = math.floor((t0 - phi) / TWO_PI) - 1, math.ceil((t1 - phi) / TWO_PI) + 1
    out = [x for x in (b + TWO_PI * k for b in base for k in range(k0, k1 + 1)) if t0 < x < t1]
    if 0.0 in out:
        return None
    return sorted(set(out))


def _target_values(periodic: bool, bound: float, f0: float, f1: float) -> list[float]:
    """``bound + 2πk`` within ``[f0, f1]`` (only ``bound`` if not periodic), as a list (``_Coord._targets``)."""
    if not periodic:
        return [bound] if f0 <= bound <= f1 else []
    return [bound + TWO_PI * k for k in range(math.ceil((f0 - bound) / TWO_PI), math.floor((f1 - bound) / TWO_PI) + 1)]


def _inside_value(value: float, lo: float, hi: float, periodic: bool, slack: float) -> bool:
    """:func:`_inside` of one value (Python's ``%`` is numpy's ``mod``: both take ``fmod`` and add the divisor to a
    remainder of the other sign)."""
    if periodic:
        if hi - lo >= TWO_PI:
            return True
        value = lo + (value - lo + slack) % TWO_PI - slack
    return lo - slack <= value <= hi + slack


def _against(curve, t: float, a, b) -> bool:
    """Whether the curve runs against ``n_a × n_b`` at ``t``."""
    D = curve.derivatives(np.array([t]), 1)[0]
    P = D[0][None]
    na = _normals(a, P)[0]
    nb = _normals(b, P)[0]
    return float(_cross(na, nb) @ D[1]) < 0.0


def _piece(curve, coords, s0, s1, a, b, boxes, slack, closed: bool, tangent: bool, tol: Tolerance):
    """The branch ``curve([s0, s1])`` with its p-curves shifted into the boxes."""
    tm = 0.5 * (s0 + s1)
    pcurves = []
    for s, box, (cu, cv) in zip((a, b), boxes, coords):
        du = _shift(cu, tm, *box[0], slack)
        dv = _shift(cv, tm, *box[1], slack)
        pcurves.append(_public_pcurve(cu, cv, s0, s1, du, dv, s, curve, tol))
    fit_dev = max(dev for _, dev in pcurves)
    return _finished(curve, s0, s1, [pc for pc, _ in pcurves], fit_dev, a, b, closed, tangent)


def _conic_piece(section: _ConeSection, s0: float, s1: float, a, b, boxes, tol: Tolerance) -> IntersectionCurve:
    """The piece ``u ∈ [s0, s1]`` of a parabola or hyperbola as one rational quadratic arc (The NURBS Book A7.3:
    a branch turns by less than π, so its end tangents meet), running along ``n_a × n_b``, with the plane's
    p-curve exact (the plane's parameters are affine: the control points' parameters, same weights) and the
    cone's fitted."""
    P0, P2 = section.evaluate(np.array([s0, s1]))
    arc = nurbs_conic_arc(P0, section.tangent(s0), P2, section.tangent(s1), section.evaluate(0.5 * (s0 + s1)), tol)
    if _against(arc, 0.5, a, b):
        arc = arc.reversed()
    pcurves, fit_dev = [], 0.0
    for s, box in zip((a, b), boxes):
        if isinstance(s, PlanarSurface):
            uv = s.closest_parameters(arc.control_points)
            pcurves.append(NurbsCurve(uv, arc.knots, arc.degree, arc.weights))
            continue

        def f(t, s=s, box=box):
            uv = np.array(s.closest_parameters(arc.evaluate(t)), dtype=np.float64)
            uv[:, 0] = np.unwrap(uv[:, 0], period=TWO_PI)
            mid = uv[len(uv) // 2, 0]
            lo = box[0][0]
            uv[:, 0] += TWO_PI * math.ceil((lo - mid) / TWO_PI) if math.isfinite(lo) else 0.0
            return uv

        fitted, dev = _fitted_pcurve(f, 0.0, 1.0, s, arc, tol)
        pcurves.append(fitted)
        fit_dev = max(fit_dev, dev)
    return _finished(arc, 0.0, 1.0, pcurves, fit_dev, a, b, False, False)


def _start(pairs, slack: float) -> float:
    """Start of the turn of a closed curve: where a winding periodic coordinate is at its box's lower bound
    (a seam first: a loop that starts on the seam it crosses can stay one closed branch).

    Mirrored for many plane–cylinder pairs at once by :func:`_plane_cylinder_circles`: keep the two in step.
    """
    for c, (lo, hi) in sorted(pairs, key=lambda pair: pair[1][1] - pair[1][0] < TWO_PI):
        if not c.periodic or not math.isfinite(lo):
            continue
        if c.exact and c.coef[1] != 0.0:
            return float((lo - c.coef[0]) / c.coef[1] if c.coef[1] > 0 else (lo + TWO_PI - c.coef[0]) / c.coef[1])
        if not c.exact and c.turns != 0:
            roots = c.crossings(lo, 0.0, TWO_PI)
            if roots.size:
                return float(roots[0])
    return 0.0


def _runs(br: np.ndarray, ok: np.ndarray, hard: np.ndarray, wrap: bool) -> list[tuple[float, float]]:
    """Maximal runs of in-box intervals between breakpoints ``br``, split at ``hard`` breakpoints (seams), and
    joined across the window's ends when ``wrap`` (a closed curve whose window start is no seam)."""
    runs, start = [], None
    for i, inside in enumerate(ok):
        if start is not None and (not inside or hard[i]):
            runs.append([float(start), float(br[i])])
            start = None
        if inside and start is None:
            start = br[i]
    if start is not None:
        runs.append([float(start), float(br[-1])])
    if wrap and len(runs) > 1 and runs[0][0] == br[0] and runs[-1][1] == br[-1]:
        first = runs.pop(0)
        runs[-1][1] = first[1] + TWO_PI
    return [tuple(r) for r in runs]


def _finished(curve, s0, s1, pcurves, fit_dev: float, a, b, closed: bool, tangent: bool) -> IntersectionCurve:
    """The branch with its measured deviation (the fits' own, and on samples between their nodes).

    Fitted (polynomial NURBS) curves are sampled by :func:`~coons.kernel.curve.spline_points`
    (``_curve_points``, ``_pcurve_points``): the same points to round-off.

    Mirrored for many plane–cylinder pairs at once by :func:`_plane_cylinder_circles`: keep the two in step.
    """
    # An irrational offset keeps the samples off the interpolation nodes of fitted p-curves.
    t = s0 + (s1 - s0) * _CHECK_FRACTIONS
    if math.isfinite(s0) and math.isfinite(s1):  # (else evaluate raises its own error)
        trig = (np.cos(t), np.sin(t))
        P = _curve_points(curve, t, trig)
        Pa = _surface_points(a, *_pcurve_points(pcurves[0], t, trig).T)
        Pb = _surface_points(b, *_pcurve_points(pcurves[1], t, trig).T)
    else:
        P = curve.evaluate(t)
        Pa = a.evaluate(*pcurves[0].evaluate(t).T)
        Pb = b.evaluate(*pcurves[1].evaluate(t).T)
    # The three pairwise distances in one reduction (the largest norm is the root of the largest
    # squared norm: sqrt is monotone and correctly rounded, so this equals the max of the norms).
    gaps = np.concatenate([Pa - P, Pb - P, Pa - Pb])
    dev = max(math.sqrt(float(np.max(np.add.reduce(gaps * gaps, axis=-1)))), fit_dev)
    return IntersectionCurve(curve, s0, s1, pcurves[0], pcurves[1], closed, dev, tangent)


# The three evaluations below are those of the types' ``evaluate`` methods, expression for expression
# (so bit for bit: tests/kernel/test_intersect.py compares them), without their argument checks:
# ``_finished`` passes finite parameter arrays, and the checks cost more than the arithmetic on its
# few samples.  ``trig`` is ``(cos t, sin t)`` when the caller has them.  Other types go to
# ``spline_points``: a polynomial NURBS at many parameters by scipy's B-spline (round-off, not bits).
def _curve_points(curve, t: np.ndarray, trig=None) -> np.ndarray:
    """``curve.evaluate(t)`` for finite ``t`` ``(k,)``: ``(k, 3)``."""
    kind = type(curve)
    if kind is Line:
        return curve.origin + t[..., None] * curve.direction
    if kind is Circle or kind is Ellipse:
        c, s = trig if trig is not None else (np.cos(t), np.sin(t))
        ra, rb = curve._radii()
        X, Y, _ = curve._frame
        return ((ra * c)[..., None] * X + (rb * s)[..., None] * Y) + curve._origin
    return spline_points(curve, t)


def _curve_tangents(curve, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``curve.derivatives(t, 1)`` for finite ``t`` ``(k,)`` as points and first derivatives, ``(k, 3)`` each."""
    kind = type(curve)
    if kind is Line:
        return curve.origin + t[..., None] * curve.direction, np.broadcast_to(curve.direction, t.shape + (3,))
    if kind is Circle or kind is Ellipse:
        c, s = np.cos(t), np.sin(t)
        ra, rb = curve._radii()
        X, Y, _ = curve._frame
        return (((ra * c)[..., None] * X + (rb * s)[..., None] * Y) + curve._origin,
                (ra * -s)[..., None] * X + (rb * c)[..., None] * Y)
    D = np.asarray(curve.derivatives(t, 1), dtype=np.float64)
    return D[..., 0, :], D[..., 1, :]


def _pcurve_points(pcurve, t: np.ndarray, trig=None) -> np.ndarray:
    """``pcurve.evaluate(t)`` for finite ``t`` ``(k,)``: ``(k, 2)``."""
    kind = type(pcurve)
    if kind is Line2D:
        return pcurve.origin + t[..., None] * pcurve.direction
    if kind is Trig2D:
        c, s = trig if trig is not None else (np.cos(t), np.sin(t))
        return pcurve.center + c[..., None] * pcurve.a + s[..., None] * pcurve.b
    return spline_points(pcurve, t)


def _surface_points(surface, u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """``surface.evaluate(u, v)`` for finite ``u, v`` of one shape ``(k,)``: ``(k, 3)``."""
    kind = type(surface)
    if kind is PlanarSurface:
        X, Y, _ = surface._frame
        return surface.origin + u[..., None] * X + v[..., None] * Y
    if kind in _REVOLVED:
        X, Y, Z = surface._frame
        e = np.cos(u)[..., None] * X + np.sin(u)[..., None] * Y
        if kind is CylindricalSurface:  # its meridian: ρ = R (the same products as by an array of R), h = v
            return (surface.radius * e + v[..., None] * Z) + surface._origin
        rho, h = surface._meridian(v, 0)
        return (rho[0][..., None] * e + h[0][..., None] * Z) + surface._origin
    return surface.evaluate(u, v)


# ---------------------------------------------------------------------------- batched sections
#: Margin, in slacks (``tol.solver`` of the boxes' size), by which every decision of the batched
#: plane–cylinder sections must clear its threshold; closer pairs take the general path, where the
#: round-off of the per-pair expressions (which the batch does not repeat bit for bit) decides.
_BATCH_MARGIN = 1e3


def _plane_cylinder_circles(items: list[tuple], tol: Tolerance) -> list[list[IntersectionCurve] | None]:
    """The branches of many plane–cylinder pairs whose plane is perpendicular to the cylinder's axis, in array passes.

    ``items``: ``(a, b, box_a, box_b)`` as :func:`intersect_surfaces` takes them, one surface of
    each pair a :class:`PlanarSurface` and the other a :class:`CylindricalSurface` (exact types).
    The section is the circle about the axis at the plane's height (the coaxial case of
    :func:`_coaxial`); the per-pair steps of :func:`_branches` are done for all pairs at once:
    the direction along ``n_a × n_b`` (:func:`_uniform_side`'s one-point rule), both p-curves in
    closed form (:func:`_closed_coords`: a :class:`Trig2D` on the plane, a :class:`Line2D`
    ``u = u₀ ± t, v = h`` on the cylinder), the window starting at the cylinder box's lower
    ``u`` bound (:func:`_start`), the one run of it inside the boxes and the measured deviation
    (:func:`_finished`), with the same expressions, so that the branches agree with the general
    path's to round-off.  The batch covers only the plain case: a cylinder box spanning less than
    a period, a circle whose plane coordinates stay inside or outside the plane's box and whose
    height is inside or outside the cylinder's ``v`` range, each by a margin of
    ``_BATCH_MARGIN`` slacks, and a pair the one-point direction rule decides.  Every other pair
    (oblique, parallel, a circle crossing the plane box, a near-tie) gets ``None``: the caller
    runs :func:`intersect_surfaces` on it.

    Returns
    -------
    list
        Per pair, its branches (one arc or none) or ``None``.
    """
    K = len(items)
    out: list[list[IntersectionCurve] | None] = [None] * K
    if K == 0:
        return out
    first = np.array([type(it[0]) is PlanarSurface for it in items])
    planes = [it[0] if f else it[1] for it, f in zip(items, first.tolist())]
    cyls = [it[1] if f else it[0] for it, f in zip(items, first.tolist())]

    def gathered(objs, *attrs):  # one stack per distinct surface object, then indexed per pair
        index: dict[int, int] = {}
        rows = [index.setdefault(id(o), len(index)) for o in objs]
        uniq = list({id(o): o for o in objs}.values())
        return [np.array([getattr(o, a) for o in uniq], dtype=np.float64)[rows] for a in attrs]

    Op, Fp = gathered(planes, "_origin", "_frame")
    Oc, Fc, R = gathered(cyls, "_origin", "_frame", "radius")
    # (K, 2, 2, 2): box_a, box_b; from one flat list of their numbers (numpy reads nested tuples slowly)
    boxes = np.array([x for it in items for box in it[2:4] for side in box for x in side],
                     dtype=np.float64).reshape(K, 2, 2, 2)
    PB = np.where(first[:, None, None], boxes[:, 0], boxes[:, 1])
    CB = np.where(first[:, None, None], boxes[:, 1], boxes[:, 0])
    fin = np.where(np.isfinite(boxes), np.abs(boxes), 0.0).reshape(K, -1)
    slack = tol.solver * np.maximum(1.0, fin.max(axis=1))
    m = _BATCH_MARGIN * slack
    N, Z = Fp[:, 2], Fc[:, 2]
    # The coaxial case of _plane_cylinder and _common_axis (sine <= tol.angular) and a circle, not a
    # contact point (radius > tol.linear), each with a factor 2 of margin: a pair near either threshold
    # is decided by the per-pair expressions.
    ok = row_norms(_cross(N, Z)) <= 0.5 * tol.angular
    ok &= R > 2.0 * tol.linear
    # The circle (_coaxial): centre on the axis at the plane's height, X perpendicular_direction(Z).
    h = np.einsum("kj,kj->k", Op - Oc, Z)
    C = Oc + h[:, None] * Z
    X = _perpendicular_rows(Z)
    Y = _cross(Z, X)
    # Direction (_uniform_side at the first turn sample): reversed circles have axis -Z, the same X.
    ts = float(_TURN_SAMPLES[0])
    c, s = math.cos(ts), math.sin(ts)
    P = C + R[:, None] * (c * X + s * Y)
    T = R[:, None] * (c * Y - s * X)
    w = P - Oc
    w = w - np.einsum("kj,kj->k", w, Z)[:, None] * Z
    nc = w / row_norms(w)[:, None]
    fl = first[:, None]
    value = np.einsum("kj,kj->k", _cross(np.where(fl, N, nc), np.where(fl, nc, N)), T)
    scale = np.maximum(1.0 + np.abs(P).max(axis=1), 1.0 + np.abs(Oc).max(axis=1))
    bound = _UNIFORM_MIN_SINE + _UNIFORM_SLACK * (tol.angular + (tol.linear + _EPS * scale) / R)
    ok &= np.abs(value) > 2.0 * bound * row_norms(T)  # (a factor 2 of margin, as above)
    sg = np.where(value > 0.0, 1.0, -1.0)
    Y = sg[:, None] * Y
    Z = sg[:, None] * Z
    # The plane's p-curve (_closed_coords): o + α cos t + β sin t per coordinate, tiny terms dropped.
    F2 = Fp[:, :2]
    tf, basis = _form_basis(0.0, TWO_PI)
    coef = np.zeros((K, 2, 4))
    coef[:, :, 0] = np.einsum("kij,kj->ki", F2, C - Op)
    coef[:, :, 2] = R[:, None] * np.einsum("kij,kj->ki", F2, X)
    coef[:, :, 3] = R[:, None] * np.einsum("kij,kj->ki", F2, Y)
    sizes = np.abs(np.einsum("sj,kij->kis", basis, coef)).max(axis=2)
    coef[np.abs(coef) <= (tol.solver * np.maximum(sizes, TWO_PI))[:, :, None]] = 0.0
    o, al, be = coef[:, :, 0], coef[:, :, 2], coef[:, :, 3]
    ok &= al[:, 0] * be[:, 1] - al[:, 1] * be[:, 0] != 0.0
    # The cylinder's (_closed_coords, _first_parameters): u = u0 - sg t0 + sg t, v = v0.
    t0 = float(tf[0])
    L = np.einsum("kij,kj->ki", Fc, C + R[:, None] * (math.cos(t0) * X + math.sin(t0) * Y) - Oc)
    u0 = np.arctan2(L[:, 1], L[:, 0])
    u0 = np.where(u0 < 0.0, u0 + TWO_PI, u0)
    u0 = np.where((u0 >= TWO_PI) | ((L[:, 0] == 0.0) & (L[:, 1] == 0.0)), 0.0, u0)
    ou, ov = u0 - sg * t0, L[:, 2]
    size_u = np.abs(ou[:, None] + sg[:, None] * tf[None]).max(axis=1)
    ou = np.where(np.abs(ou) <= tol.solver * np.maximum(size_u, TWO_PI), 0.0, ou)
    ov = np.where(np.abs(ov) <= tol.solver * np.maximum(np.abs(ov), TWO_PI), 0.0, ov)
    # Boxes: the cylinder's u range less than a period; every other coordinate clearly in or out.
    (lo_u, hi_u), (lo_v, hi_v) = CB[:, 0].T, CB[:, 1].T
    span = hi_u - lo_u
    ok &= np.isfinite(lo_u) & np.isfinite(hi_u) & (span > m) & (span < TWO_PI - m)
    inside = (ov >= lo_v - slack + m) & (ov <= hi_v + slack - m)
    outside = (ov < lo_v - slack - m) | (ov > hi_v + slack + m)
    r = np.hypot(al, be)
    for i in (0, 1):
        lo, hi = PB[:, i, 0], PB[:, i, 1]
        inside &= (o[:, i] - r[:, i] > lo + m) & (o[:, i] + r[:, i] < hi - m)
        outside |= (o[:, i] + r[:, i] < lo - slack - m) | (o[:, i] - r[:, i] > hi + slack + m)
    ok &= inside | outside
    # The window starts where u is at its lower bound (_start); the run ends where it crosses the upper one.
    w0 = np.where(sg > 0.0, (lo_u - ou) / sg, (lo_u + TWO_PI - ou) / sg)
    w1 = w0 + TWO_PI
    cross_hi = (hi_u - ou) / sg
    s0 = np.where(sg > 0.0, w0, cross_hi)
    s1 = np.where(sg > 0.0, cross_hi, w1)
    tm = 0.5 * (s0 + s1)
    du = TWO_PI * np.ceil((lo_u - slack - (ou + sg * tm)) / TWO_PI)  # (_shift)
    for k in np.flatnonzero(ok & outside).tolist():
        out[k] = []
    todo = np.flatnonzero(ok & ~outside)
    if todo.size == 0:
        return out
    # The deviation (_finished) of all branches at once.
    C, X, Y, Z, R, o, al, be = C[todo], X[todo], Y[todo], Z[todo], R[todo], o[todo], al[todo], be[todo]
    s0, s1, ou, ov, sg = s0[todo], s1[todo], ou[todo] + du[todo], ov[todo] + 0.0, sg[todo]  # (the shifts: _piece)
    Fpt, Opt, Fct, Oct = Fp[todo], Op[todo], Fc[todo], Oc[todo]
    dev = np.empty(todo.size)
    # In blocks of rows, whose dozen (rows, samples) temporaries stay in the cache (a quarter faster than
    # all rows at once on a 20x20 plate's 1600 pairs).
    for b in range(0, todo.size, _DEVIATION_ROWS):
        r = slice(b, b + _DEVIATION_ROWS)
        t = s0[r, None] + (s1[r] - s0[r])[:, None] * _CHECK_FRACTIONS[None]
        cs, sn = np.cos(t), np.sin(t)
        Rc, Rs = R[r, None] * cs, R[r, None] * sn
        # The uv points on both surfaces, then the 3-d points coordinate by coordinate: (k, samples) arrays
        # rather than (k, samples, 3), whose length-3 inner axis numpy walks slowly; the same expressions, in
        # the same order, so the deviation is bit-identical to the per-pair one.
        uv = [(o[r, i, None] + cs * al[r, i, None]) + sn * be[r, i, None] for i in (0, 1)]
        u = ou[r, None] + sg[r, None] * t
        cu, su = np.cos(u), np.sin(u)
        d_pk = d_ck = d_pc = 0.0
        for j in range(3):
            pk = (Rc * X[r, j, None] + Rs * Y[r, j, None]) + C[r, j, None]
            pp = (Opt[r, j, None] + uv[0] * Fpt[r, 0, j, None]) + uv[1] * Fpt[r, 1, j, None]
            e = cu * Fct[r, 0, j, None] + su * Fct[r, 1, j, None]
            pc = (R[r, None] * e + ov[r, None] * Fct[r, 2, j, None]) + Oct[r, j, None]  # (the cylinder's radius)
            d_pk, d_ck, d_pc = d_pk + (pp - pk) ** 2, d_ck + (pc - pk) ** 2, d_pc + (pp - pc) ** 2
        # (the largest squared gap, then its root: sqrt is monotone and correctly rounded)
        dev[r] = np.sqrt(np.maximum(np.maximum(d_pk, d_ck), d_pc).max(axis=1))
    circles = Circle.many(C, np.stack([X, Y, Z], axis=1), R)
    on_plane = Trig2D.many(o, al, be)
    on_cylinder = Line2D.many(np.stack([ou, ov], axis=1), np.stack([sg, np.zeros_like(sg)], axis=1))
    # The constructor's check (finite t0 < t1) for all branches at once; then each is built as the constructor
    # would leave it (Python floats and bools), without its per-object conversions.  A branch failing the
    # check goes through the constructor, which raises.
    make = IntersectionCurve._trusted if bool(np.all(np.isfinite(s0) & np.isfinite(s1) & (s0 < s1))) \
        else IntersectionCurve
    for k, circle, pp, pc, a, b, d, f in zip(todo.tolist(), circles, on_plane, on_cylinder, s0.tolist(), s1.tolist(),
                                             dev.tolist(), first[todo].tolist()):
        out[k] = [make(circle, a, b, pp if f else pc, pc if f else pp, False, d, False)]
    return out


def _perpendicular_rows(Z: np.ndarray) -> np.ndarray:
    """:func:`~coons.kernel.conics.perpendicular_direction` of unit rows ``Z (k, 3)``, ``(k, 3)``: the coordinate of
    least magnitude set to zero, the other two swapped with one sign change, normalised."""
    a, b, c = Z.T
    A, B, Cm = np.abs(Z).T
    zero = np.zeros_like(a)
    by_y = (B <= A) & (B <= Cm)
    by_x = ~by_y & (A <= B) & (A <= Cm)
    # The six candidates (rows of one table), each row's by index: one gather, not nested selections.
    which = np.where(by_y, np.where(A > Cm, 0, 1), np.where(by_x, np.where(B > Cm, 2, 3), np.where(A > B, 4, 5)))
    na, nb, nc = -a, -b, -c
    table = np.array([[nc, zero, a], [c, zero, na], [zero, nc, b], [zero, c, nb], [nb, a, zero], [b, na, zero]])
    d = table[which, :, np.arange(a.size)]
    return d / row_norms(d)[:, None]


# ---------------------------------------------------------------------------- dispatcher
def _box(surface, box, what: str) -> tuple[tuple[float, float], tuple[float, float]]:
    if box is None:
        box = surface.domain
    try:
        (u0, u1), (v0, v1) = box
        u0, u1, v0, v1 = float(u0), float(u1), float(v0), float(v1)
    except (TypeError, ValueError):
        raise InvalidInputError(f"{what}: expected ((u0, u1), (v0, v1)), got {box!r}") from None
    if any(math.isnan(x) for x in (u0, u1, v0, v1)) or not (u0 < u1 and v0 < v1):
        raise InvalidInputError(f"{what}: need u0 < u1 and v0 < v1, got (({u0}, {u1}), ({v0}, {v1}))")
    return (u0, u1), (v0, v1)


def _contact_points(points, a, b, box_a, box_b, tol: Tolerance):
    """Parameters of isolated contact points on both surfaces, shifted into the boxes; those outside dropped as
    lying outside the region asked for."""
    if not points:
        return np.zeros((0, 3)), np.zeros((0, 2)), np.zeros((0, 2))
    P = np.array(points, dtype=np.float64)
    uvs, keep = [], np.ones(len(P), dtype=bool)
    slack = tol.solver * max(1.0, *(abs(x) for box in (box_a, box_b) for r in box for x in r if math.isfinite(x)))
    for s, box in ((a, box_a), (b, box_b)):
        uv = np.array(s.closest_parameters(P), dtype=np.float64).reshape(-1, 2)
        for i, periodic in enumerate((s.periodic_u, s.periodic_v)):
            lo, hi = box[i]
            if periodic and math.isfinite(lo):
                uv[:, i] += TWO_PI * np.ceil((lo - slack - uv[:, i]) / TWO_PI)
            keep &= (uv[:, i] >= lo - slack) & (uv[:, i] <= hi + slack)
        uvs.append(uv)
    return P[keep], uvs[0][keep], uvs[1][keep]


def intersect_surfaces(a, b, box_a=None, box_b=None, tol: Tolerance | None = None) -> SurfaceIntersection:
    """The intersection curves and isolated contact points of surfaces ``a`` and ``b`` within two parameter boxes.

    Analytic pairs whose intersection is a set of conics, and crossing cylinders whose intersection
    is two separate loops, are solved in closed form (see the module docstring for the list and the
    conventions on boxes, p-curves and direction); every other pair goes to
    :func:`coons.kernel.ssi.march_intersection`.

    Parameters
    ----------
    a, b : PlanarSurface, CylindricalSurface, ConicalSurface, SphericalSurface, ToroidalSurface or NurbsSurface
    box_a, box_b : ((u0, u1), (v0, v1)), optional
        The parameter boxes the caller cares about (default: the surface's domain; planes,
        cylinders and cones need finite boxes where a straight branch runs).
    tol : Tolerance, optional
        ``linear`` decides tangency and coincidence of positions, ``angular`` of directions.

    Returns
    -------
    SurfaceIntersection
        Branches inside both boxes, each running along ``n_a × n_b`` unless tangent; contact
        points ``(k, 3)`` with ``uv_a, uv_b (k, 2)``; ``coincident=True`` (and nothing else)
        when the surfaces are the same point set.

    Raises
    ------
    InvalidInputError
        Malformed boxes, or a straight, parabolic or hyperbolic branch not bounded by the boxes.
    InvalidGeometryError
        The pair needs the general method and :mod:`coons.kernel.ssi` is not available.
    ConvergenceError
        A fitted p-curve does not reach ``tol.linear / 2`` with 4097 samples.

    Examples
    --------
    >>> from coons.kernel.analytic import PlanarSurface, SphericalSurface
    >>> plane = PlanarSurface([0, 0, 0.6], [0, 0, 1], [1, 0, 0])
    >>> sphere = SphericalSurface([0, 0, 0], [0, 0, 1], [1, 0, 0], 1.0)
    >>> cut = intersect_surfaces(plane, sphere, box_a=((-2, 2), (-2, 2)))
    >>> c = cut.curves[0]
    >>> bool(c.closed and abs(c.curve.radius - 0.8) < 1e-15)
    True
    """
    t = resolve(tol)
    box_a = _box(a, box_a, "box_a")
    box_b = _box(b, box_b, "box_b")
    found = _exact(a, b, t)
    if found is None:
        try:
            from coons.kernel.ssi import march_intersection
        except ModuleNotFoundError as exc:
            if exc.name != "coons.kernel.ssi":
                raise  # a broken general method must not pass for a missing one
            raise InvalidGeometryError(
                f"no intersection method for {type(a).__name__} and {type(b).__name__} yet "
                "(the general method coons.kernel.ssi is not available)"
            ) from None
        return march_intersection(a, b, box_a, box_b, t)
    if found.coincident:
        return SurfaceIntersection.empty(coincident=True)
    curves = [br for cand in found.candidates for br in _branches(cand, a, b, box_a, box_b, t)]
    P, uv_a, uv_b = _contact_points(found.points, a, b, box_a, box_b, t)
    return SurfaceIntersection(tuple(curves), P, uv_a, uv_b)
