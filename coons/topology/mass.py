"""Exact mass properties, face areas and bounding boxes of B-reps, by boundary integrals.

:func:`mass_properties` returns the volume, area, centroid and inertia tensor of a B-rep for
unit density; :func:`shell_volumes` the signed volume each shell encloses (what the checker
uses to verify orientation; for a B-rep sewn from face specs it sums
:func:`carried_shell_volumes`: the contributions of faces equal to a spec integrated before are
taken from then, equal up to round-off, and a planar face gaining loops adds only their paths);
:func:`face_areas` the area of every face; :func:`bounding_box`
the axis-aligned box of the exact geometry (vertices, edge curves and face surfaces; not the
control nets).  Everything is computed from the B-rep's own geometry: nothing is
tessellated, and no quantity depends on a deflection.  Results are cached per B-rep (B-reps
are immutable); the coefficient rows of each surface and p-curve are remembered per object
(they depend on it alone), so B-reps sharing geometry (a Boolean's result and its operands)
build their tables without reading every object again; the rows shared with the last sewn B-rep
tabled (else the last tabled) are taken from its tables in one gather (``_DONOR``, :func:`~coons.topology._memo.pool_positions`).  The module does not compute properties of open shells or
lower-dimensional sets (curve lengths, wire centroids), does not weight by density, and does
not repair orientation (an inside-out B-rep has negative volume).  Faces must lie on planes
(implicit or :class:`PlanarSurface`), the analytic surfaces of :mod:`coons.kernel.analytic`
or :class:`NurbsSurface`, and non-planar faces need p-curves (``Line2D``, ``Trig2D`` or 2-D
``NurbsCurve``); anything else raises rather than guesses.

Method: the classic boundary-integral mass properties (Cohen–Riesenfeld–Elber, *Geometric
Modeling with Splines*, 2001; for polyhedra Lien & Kajiya, "A symbolic method for calculating
the integral properties of arbitrary nonconvex polyhedra", 1984, and Mirtich, "Fast and
accurate computation of polyhedral mass properties", 1996):

1. *Divergence theorem.*  Each volume integral becomes a flux through the faces, with the
   rotation-covariant fields ``div(x φ) = (3 + deg φ) φ`` for a homogeneous polynomial ``φ``::

       V            = ∮ (x·n) / 3        dA
       ∫ x_a   dV   = ∮ x_a (x·n) / 4    dA
       ∫ x_a x_b dV = ∮ x_a x_b (x·n) / 5 dA

   (``x`` measured from a reference point ``x0``, the centre of the vertex box, to avoid
   cancellation far from the origin; the results are moved back exactly).
2. *Green's theorem.*  On a face ``S(u, v)`` over the trimmed region ``D``, ``n dA = σ Su × Sv
   du dv`` with ``σ = +1`` when ``face_sense`` is True, else ``-1``.  Loops as stored run
   counter-clockwise in ``(u, v)`` when ``σ = +1`` and clockwise when ``σ = -1`` (the outer
   loop is counter-clockwise seen from the outward normal ``σ Su × Sv``, and ``(u, v) ↦ S``
   preserves orientation relative to ``Su × Sv``).  Hence, walking the loops as stored,
   ``∮ F dv = σ ∬_D ∂F/∂u du dv``, and with ``F(u, v) = ∫_{u_ref}^{u} f(s, v) ds`` and
   ``f = g(S)·(Su × Sv)`` the flux is ``∬_D g·(σ Su × Sv) = ∮_stored F dv``: the face
   orientation comes out right with no explicit sign.  The area integrand ``|Su × Sv|`` has
   no orientation of its own, so the face area is ``σ ∮ F_A dv``.  ``u_ref`` is any constant
   per face: ``-ox`` on planes (the foot of ``x0``, so no term exceeds the model's size), the
   ``u`` where the face's first gathered p-curve starts on other surfaces.
3. *Boundary paths, all faces at once.*  The outer integral runs along each coedge's p-curve
   (side 0 along the edge's parameter, side 1 against it) and, on NURBS faces, along straight
   parameter-space segments wherever a coedge's p-curve ends away from where the next one starts
   (collapsed sides, ``docs/brep.md``; on analytic surfaces these gaps lie along the iso-``v``
   lines of poles and apices and add nothing); loop order plays no other part, so every coedge
   of every face is gathered in one pass.  ``Line2D`` and ``Trig2D`` p-curves (and the
   projections of lines, circles and ellipses onto planes, which are exact) are rows of one
   coefficient table, ``uv(t) = c0 + t l + cos t a + sin t b``, stacked from the B-rep's
   p-curves once and evaluated as arrays; polynomial ``NurbsCurve`` p-curves of one degree are
   evaluated as one batch (:mod:`coons.kernel._stacked`), rational ones per curve.
   Paths along which ``v`` is constant contribute nothing to ``∮ F dv`` and are skipped.
4. *Closed-form inner integrals on analytic surfaces*, all faces of a class at once (frames,
   origins and meridian coefficients stacked per face, integrands written in each face's own
   frame and the per-face sums rotated to world axes at the end; no per-face or per-surface
   call):

   * planes ``S = O + u X + v Y``: ``(x - x0)·n`` is constant, so ``F`` is a polynomial of
     degree <= 3 in ``u`` (:func:`_plane_F`);
   * surfaces of revolution ``S = O + ρ(v) e(u) + h(v) Z`` with ``ρ = α + β v + γ cos v``,
     ``h = δ v + ε sin v`` (cylinder ``(R, 0, 0, 1, 0)``, cone ``(R, sin a, 0, cos a, 0)``,
     sphere ``(0, 0, R, 0, R)``, torus ``(R, 0, r, 0, r)``): ``|Su × Sv| = |ρ| |(ρ', h')|``
     does not depend on ``u`` and ``(x - x0)·(Su × Sv)`` is a trigonometric polynomial of
     degree 1 in ``u``, so every column is a combination of ``∫ e^{imu} du``, ``m <= 3``
     (:func:`_revolved_F`, written with complex numbers).

   The outer integral uses, per block of paths (one numpy pass each): 3 Gauss–Legendre points
   (``POLY_GAUSS_ORDER``) where the integrand is a polynomial of degree <= 4 in the path
   parameter (straight p-curves on planes, rulings of cylinders and cones); an exact 9-node rule
   for trigonometric polynomials of degree <= 4 (nodes ``2πj/9`` apart, weights from the
   integrals of the Fourier basis over the path) on arcs of planes and meridians of spheres and
   tori spanning at least ``ANGLE_STEP``; and ``GAUSS_ORDER = 12`` points per piece of at most
   ``ANGLE_STEP = π/2`` of angular variation elsewhere, which integrates those trigonometric
   integrands to round-off.
5. *Adaptive quadrature on NURBS* (NURBS surfaces, and NURBS p-curves on any surface), where
   ``|Su × Sv|`` (always) and the rational integrands are not polynomials: both the outer and
   (on NURBS surfaces) the inner integral use Gauss–Kronrod G7/K15 pieces (QUADPACK's QK15,
   Piessens et al. 1983), started at one piece per knot span (the inner integral split at
   the ``u`` knots, the paths where they cross ``u`` or ``v`` knot lines and at their own
   knots) and bisected, all pieces at once, until for each face (outer) or each inner integral
   and every column ``c`` the summed estimates ``Σ |K15 - G7|`` are at most
   ``r (Σ ∫|g_c| + L^k_c Σ ∫|g_area|)`` (``r = tol.solver``, at least 64 ulps), ``L`` the
   diagonal of the vertex box and ``k_c`` the length degree of column ``c`` relative to the
   area (0 area, 1 volume, 2 first and 3 second moments; the second term is the natural
   magnitude of a column whose integrand cancels).  The error estimate is that of G7, so the
   K15 results are far more accurate:
   extruded, revolved and lofted spline faces agree with independent references to round-off
   (measured <= 5e-16, tests/topology/test_mass.py).
   Where a round of halvings no longer lowers a face's summed estimate (by ``_STALL_FACTOR``,
   for ``_STALL_ROUNDS`` rounds) the estimate is the rounding noise of the integrand (closed
   forms with cancellation on fitted p-curves), not truncation error: the face is accepted if
   that floor is within ``_ROUNDOFF_SLACK`` (1e3) times the target.
   ``ConvergenceError`` if a face needs more than ``MAX_BISECTIONS`` halvings, or stalls above that.
   Surfaces of one structure (degrees, knots, net shape: :class:`~coons.kernel.surface.NurbsSurfaceStack`)
   are integrated in one adaptive run, each point on its own face's surface, so a model of many
   small patches costs a few numpy passes per round rather than a few calls per surface; the
   convergence tests stay per face and per inner integral.
6. *Polygonal faces* (implicit planes ``face_surface = -1``, :class:`PlanarSurface` faces, or
   :class:`NurbsSurface` faces whose control net is flat to the round-off of its coordinates —
   the surface lies in the net's convex hull, so in its plane —, bounded only by straight
   edges: no curve or a :class:`Line`) use closed forms over all
   their coedges at once, whatever their sense: each coedge ``(a, b)`` of a face with
   reference vertex ``r`` spans the tetrahedron ``(x0, r, a, b)``, whose signed volume, first
   moment and second moment ``V/20 (r rᵀ + a aᵀ + b bᵀ + s sᵀ)``, ``s = r + a + b`` (Tonon,
   "Explicit exact formulas for the 3-D tetrahedron inertia tensor", 2004) sum to the solid's;
   the face's vector area is Newell's sum.  A million-triangle polyhedron costs a few numpy
   passes.  Implicit planes bounded by curved edges are integrated like planar surfaces, with
   p-curves obtained by projecting the 3-D edge curves onto the plane (exact: the projection
   is affine).

Bounding boxes: vertices; circles and ellipses at their closed-form extrema along each axis
inside the edge range; spheres and tori at their closed-form interior critical points (where
the normal is ± an axis) when those lie inside the face's parameter region; planes, cylinders
and cones have no isolated interior extrema (their critical sets are rulings, on which the
coordinate is constant up to the boundary, so the edges carry the extreme).  NURBS (and any
other) curves and surfaces: dense sampling (per knot span) followed by a Newton polish of the
best samples; every candidate is a point of the edge or face, so the box never exceeds the
exact one and matches it to round-off wherever Newton converges.  Boxes are not inflated by
edge or vertex tolerances.  A curve or surface whose proven hull (control points, a sphere's or
torus's box) lies inside the box of the candidates found so far is not searched (its extreme points
could not widen it): the intersection curves of a Boolean's result lie inside the box of its
faces.  :func:`face_box_bounds` gives looser boxes per face without any search (edge curves'
piece boxes, whole spheres and tori,
NURBS control points), proven to contain each face.
"""

from __future__ import annotations

import functools
import math
import operator
import weakref
from dataclasses import dataclass
from typing import Callable

import numpy as np

from coons.errors import ConvergenceError, InvalidInputError, TopologyError
from coons.kernel.analytic import (
    Circle,
    ConicalSurface,
    CylindricalSurface,
    Ellipse,
    Line,
    PlanarSurface,
    SphericalSurface,
    ToroidalSurface,
    meridian_row,
)
from coons.kernel.conics import perpendicular_direction
from coons.kernel.curve import NurbsCurve
from coons.kernel.pcurve import Line2D, Trig2D
from coons.kernel.surface import NurbsSurface, NurbsSurfaceStack
from coons.tolerance import Tolerance, resolve
from coons.topology._memo import IdentityMemo, LastRecord, all_values, found_by_id, id_index, is_value, pool_positions, read_only as _read_only
from coons.kernel._stacked import derivatives_many
from coons.topology.brep import BRep, same_geometry

__all__ = [
    "MassProperties",
    "mass_properties",
    "shell_volumes",
    "carried_shell_volumes",
    "face_areas",
    "bounding_box",
    "face_box_bounds",
    "GAUSS_ORDER",
    "POLY_GAUSS_ORDER",
    "ANGLE_STEP",
    "MAX_BISECTIONS",
]

#: Gauss–Legendre points per piece of a boundary path with an angular (trigonometric) integrand.
GAUSS_ORDER = 12
#: Gauss–Legendre points on paths whose integrand is a polynomial of degree <= 4 (exact to 5).
POLY_GAUSS_ORDER = 3
#: Largest angular variation per piece (radians).  12 Gauss points integrate ``e^{ikθ}`` over
#: π/2 to round-off (measured <= 2e-15 relative) for ``k <= 6``; the integrands here have
#: trigonometric degree <= 5.
ANGLE_STEP = math.pi / 2
#: Halvings of a Gauss–Kronrod piece before the adaptive quadrature gives up (ConvergenceError).
MAX_BISECTIONS = 40

_XI, _WI = np.polynomial.legendre.leggauss(GAUSS_ORDER)
_XP, _WP = np.polynomial.legendre.leggauss(POLY_GAUSS_ORDER)
_TWO_PI = 2.0 * math.pi

# Gauss–Kronrod 7/15 (QUADPACK qk15): Kronrod nodes in (0, 1], their weights, and the weights
# of the embedded 7-point Gauss rule at the odd Kronrod nodes (and 0).
_XGK = np.array([
    0.991455371120812639206854697526329, 0.949107912342758524526189684047851,
    0.864864423359769072789712788640926, 0.741531185599394439863864773280788,
    0.586087235467691130294144845693013, 0.405845151377397166906606412076961,
    0.207784955007898467600689403773245, 0.0,
])
_WGK = np.array([
    0.022935322010529224963732008058970, 0.063092092629978553290700663189204,
    0.104790010322250183839876322541518, 0.140653259715525918745189590510238,
    0.169004726639267902826583426598550, 0.190350578064785409913256402421014,
    0.204432940075298892414161999234649, 0.209482141084727828012999174891714,
])
_WG7 = np.array([0.0, 0.129484966168869693270611432679082, 0.0, 0.279705391489276667901467771423780,
                 0.0, 0.381830050505118944950369775488975, 0.0, 0.417959183673469387755102040816327])
_XK = np.concatenate([-_XGK[:-1], _XGK[::-1]])  # (15,) ascending
_WK = np.concatenate([_WGK[:-1], _WGK[::-1]])
_WG = np.concatenate([_WG7[:-1], _WG7[::-1]])
_WKG = np.stack([_WK, _WG], axis=1)  # (15, 2)
#: Initial Gauss–Kronrod pieces per knot span (or per angular piece) before any bisection: one (a
#: K15 rule is exact for polynomials of degree 22; a fitted p-curve brings tens of spans, and the
#: adaptive rounds halve whatever misses its share of the target).  Two doubled the shell-volume
#: time of curved Boolean results (crossing cylinders 21 -> 11 ms) for the same values to 1e-15.
_INITIAL_PIECES = 1
#: The adaptive quadrature stalls when a round of halvings leaves the summed error estimate above
#: this fraction of the previous round's (a jump discontinuity halves it: 0.5 is progress) ...
_STALL_FACTOR = 0.7
#: ... for this many rounds in a row; it then accepts a round-off floor of at most
#: _ROUNDOFF_SLACK times the target (relative error estimate <= 1e3 rtol = 1e-9 by default,
#: an overestimate: the noise of the G7 estimates largely cancels in the K15 sums).
_STALL_ROUNDS = 3
_ROUNDOFF_SLACK = 1e3
#: A NURBS control net whose points lie within this many ulps of their largest coordinate from
#: one plane is flat (:func:`_flat_nets`): the rounding of the coordinates of a plane's points.
_FLAT_ULPS = 64.0
#: Most pieces alive at once in one adaptive integration (memory bound; ConvergenceError beyond).
_MAX_PIECES = 1 << 20

_EYE3 = np.eye(3)
_EPS = float(np.finfo(np.float64).eps)

# Integrand columns: area, volume, first moments (3), second moments xx yy zz xy xz yz.  The
# volume-only mode integrates the first two (the area column also scales the error targets).
_AREA, _VOL = 0, 1
_FIRST = slice(2, 5)
_SECOND = slice(5, 11)
_N_COLS = 11
_N_VOL_COLS = 2
_PAIRS = ((0, 0), (1, 1), (2, 2), (0, 1), (0, 2), (1, 2))
_I6 = np.array([i for i, _ in _PAIRS])
_J6 = np.array([j for _, j in _PAIRS])
#: Powers of length of each column relative to the area column.
_LENGTH_DEGREE = np.array([0, 1, 2, 2, 2, 3, 3, 3, 3, 3, 3])

# Face codes: which integrands and quadrature rules a face takes (none: a polygon or no face).
_C_NONE, _C_PLANE, _C_REV_LINEAR, _C_REV_CIRCULAR, _C_NURBS, _C_OTHER = -1, 0, 1, 2, 3, 4

#: Samples per path of the parameter-space polygon of a face (inside tests of bounding-box candidates).
_POLYGON_SAMPLES = 129
#: Integrand evaluations per batch (bounds memory: a few arrays of chunk × columns float64).
_CHUNK = 1 << 16
#: Bisection steps for knot-line crossings of p-curves: 2^-64 of a sample interval.
_BISECTIONS = 64
#: Samples per knot span (NURBS) or per curve/direction (other types) before the Newton polish
#: of bounding-box extrema, and Newton steps.
_BOX_SAMPLES_PER_SPAN = 16
_BOX_SAMPLES_GENERIC = 128
_NEWTON_STEPS = 12
_NEWTON_STARTS = 4

#: Per-B-rep results and tables (B-reps are immutable; entries go with the B-rep).
_CACHE: "weakref.WeakKeyDictionary[BRep, dict]" = weakref.WeakKeyDictionary()


# ============================================================================ results
@dataclass(frozen=True)
class MassProperties:
    """Mass properties of a solid for unit density.

    Attributes
    ----------
    volume : float
        Signed volume (positive for outward-oriented shells; voids subtract).
    area : float
        Total area of the faces.
    centroid : (3,) float64
        Centre of mass.
    inertia : (3, 3) float64
        Inertia tensor about the centroid: ``∫ (|r|² I - r rᵀ) dV`` with ``r = x - centroid``.
    first_moments : (3,) float64
        ``∫ x dV`` about the world origin (``volume * centroid``).
    second_moments : (3, 3) float64
        ``∫ x xᵀ dV`` about the world origin.
    """

    volume: float
    area: float
    centroid: np.ndarray
    inertia: np.ndarray
    first_moments: np.ndarray
    second_moments: np.ndarray

    def __post_init__(self) -> None:
        for name in ("centroid", "inertia", "first_moments", "second_moments"):
            a = np.array(getattr(self, name), dtype=np.float64)
            a.setflags(write=False)
            object.__setattr__(self, name, a)
        object.__setattr__(self, "volume", float(self.volume))
        object.__setattr__(self, "area", float(self.area))

    @classmethod
    def _trusted(cls, volume: float, area: float, *arrays: np.ndarray) -> "MassProperties":
        """Construct from fresh float64 arrays owned by the caller (made read-only, not copied)."""
        obj = object.__new__(cls)
        object.__setattr__(obj, "volume", volume)
        object.__setattr__(obj, "area", area)
        for name, a in zip(("centroid", "inertia", "first_moments", "second_moments"), arrays):
            a.setflags(write=False)
            object.__setattr__(obj, name, a)
        return obj

    @property
    def principal_moments(self) -> np.ndarray:
        """Eigenvalues of :attr:`inertia`, ascending, ``(3,)``."""
        return np.linalg.eigvalsh(self.inertia)


# ============================================================================ public API
def _as_brep(shape) -> BRep:
    if isinstance(shape, BRep):
        return shape
    b = getattr(shape, "brep", None)
    if isinstance(b, BRep):
        return b
    raise InvalidInputError(f"expected a BRep or a shape with a .brep, got {type(shape).__name__}")


def share_mass_caches(src: BRep, dst: BRep) -> None:
    """Let ``dst`` reuse the per-face integrals, tables and box computed for ``src``.

    Only for two B-reps with the same vertices, faces and geometry in the same order, differing at
    most in how shells are grouped into solids (every cached entry is a sum or table over faces).
    """
    if not same_geometry(src, dst):
        raise InvalidInputError("share_mass_caches needs B-reps with the same vertices, faces and geometry")
    got = _CACHE.get(src)
    if got:
        _cache(dst).update(got)


def _cache(b: BRep) -> dict:
    d = _CACHE.get(b)
    if d is None:
        d = _CACHE[b] = {}
    return d


def _quadrature_rtol(tol: Tolerance | None) -> float:
    # Error estimates below ~64 ulps of the integrand's magnitude are round-off, not truncation:
    # asking for less could never be met.
    return max(resolve(tol).solver, 64.0 * _EPS)


def _reference_point(b: BRep) -> tuple[np.ndarray, float]:
    """Centre of the vertex box (moments are integrated about it: no cancellation far from 0) and
    the box's diagonal (the length scale of the quadrature targets)."""
    P = b.vertex_point
    if P.size == 0:
        return np.zeros(3), 0.0
    lo, hi = P.min(axis=0), P.max(axis=0)
    d = hi - lo
    return 0.5 * (lo + hi), math.sqrt(float(d @ d))


def _columns(b: BRep, rtol: float, full: bool) -> np.ndarray:
    """Per-face integrals ``(F, 11)`` (``full``) or ``(F, 2)`` (area, volume), cached, read-only."""
    cache = _cache(b)
    cols = cache.get(("columns", rtol, True))
    if cols is None and not full:
        cols = cache.get(("columns", rtol, False))
    if cols is None:
        ref = cache.get("x0")
        if ref is None:
            ref = cache["x0"] = _reference_point(b)
        cols = _face_integrals(b, ref[0], ref[1], _N_COLS if full else _N_VOL_COLS, rtol)
        cols.setflags(write=False)
        cache[("columns", rtol, full)] = cols
    return cols


def mass_properties(brep, tol: Tolerance | None = None) -> MassProperties:
    """Volume, area, centroid and inertia of a B-rep for unit density (see the module docstring).

    Parameters
    ----------
    brep : BRep or Solid
    tol : Tolerance, optional
        ``tol.solver`` is the relative accuracy asked of the adaptive quadrature on NURBS
        (analytic faces are integrated exactly, to round-off, whatever it is).

    Returns
    -------
    MassProperties
        Cached per B-rep and tolerance.

    Raises
    ------
    InvalidInputError
        Not a B-rep; a surface or p-curve type this module cannot integrate; a bad ``tol``.
    TopologyError
        A face on a non-planar surface whose coedge has no p-curve; a B-rep enclosing zero
        volume (no centroid).
    ConvergenceError
        The adaptive quadrature of a NURBS face did not reach ``tol.solver`` (a non-finite or
        non-smooth integrand).

    Examples
    --------
    >>> from coons.topology.primitives import Box, Sphere
    >>> mp = mass_properties(Box(2, 2, 2))
    >>> bool(np.isclose(mp.volume, 8.0)), bool(np.allclose(mp.inertia, 8 * (4 + 4) / 12 * np.eye(3)))
    (True, True)
    >>> bool(np.isclose(mass_properties(Sphere(1)).inertia[0, 0], 0.4 * 4 / 3 * np.pi, rtol=1e-14))
    True
    """
    b = _as_brep(brep)
    rtol = _quadrature_rtol(tol)
    cache = _cache(b)
    mp = cache.get(("mass", rtol))
    if mp is not None:
        return mp
    cols = _columns(b, rtol, True)
    tot = cols.sum(axis=0)
    V = float(tot[_VOL])
    # The volume is a sum of face contributions, each exact to round-off: a total within a few
    # ulps of their magnitudes is indistinguishable from zero (e.g. a shell and its reverse).
    noise = 64.0 * _EPS * float(np.abs(cols[:, _VOL]).sum())
    if not math.isfinite(V) or abs(V) <= noise:
        raise TopologyError(f"the B-rep encloses volume {V!r}; expected a non-zero finite volume to locate a centroid")
    c_rel = tot[_FIRST] / V
    central = tot[_SYM9].reshape(3, 3) - (V * c_rel)[:, None] * c_rel  # ∫ r rᵀ dV about the centroid
    central = 0.5 * (central + central.T)
    centroid = cache["x0"][0] + c_rel
    mp = MassProperties._trusted(V, float(tot[_AREA]), centroid, central.trace() * _EYE3 - central, V * centroid,
                                 central + (V * centroid)[:, None] * centroid)
    cache[("mass", rtol)] = mp
    return mp


def shell_volumes(brep, tol: Tolerance | None = None) -> np.ndarray:
    """Signed volume enclosed by each shell, ``(S,)`` float64.

    Positive for shells oriented outward (outer shells), negative for shells oriented
    inward (voids).  Only the volume (and area) columns of the boundary integrals are evaluated.

    Raises
    ------
    InvalidInputError, TopologyError, ConvergenceError
        As :func:`mass_properties` (except the zero-volume case).
    """
    b = _as_brep(brep)
    cols = _columns(b, _quadrature_rtol(tol), False)
    return np.bincount(b.face_shell, weights=cols[:, _VOL], minlength=b.n_shells)[: b.n_shells]


def face_areas(brep, tol: Tolerance | None = None) -> np.ndarray:
    """Area of every face, ``(F,)`` float64 (see the module docstring for the method).

    Raises
    ------
    InvalidInputError, TopologyError, ConvergenceError
        As :func:`mass_properties` (except the zero-volume case).
    """
    b = _as_brep(brep)
    return _columns(b, _quadrature_rtol(tol), False)[:, _AREA].copy()


# ============================================================================ carried shell volumes
#: Face spec -> ``{(x0 bytes, L, rtol): volume}``: the signed volume contribution of a face equal to
#: the spec (every use keeping its curve, p-curve, range and tolerance, :func:`~coons.topology.sew.sewn_unchanged`),
#: integrated about ``x0`` with length scale ``L`` (:func:`_reference_point`) to ``rtol``.  For
#: :func:`carried_shell_volumes`, whose totals only the orientation check's sign test reads.
_FACE_VOLUMES = IdentityMemo()


class _Volumes:
    """The face contributions of the last :func:`carried_shell_volumes`: ``specs`` (held, so that their
    ids stay theirs), ``ids (F,)`` sorted and ``order (F,)`` the faces in that order, ``vol (F,)``,
    ``recorded (F,)`` bool: the face's contribution is the one in :data:`_FACE_VOLUMES` under ``key``."""

    __slots__ = ("specs", "ids", "order", "vol", "recorded", "key")


#: The last B-rep :func:`carried_shell_volumes` summed -> its :class:`_Volumes` (one entry), and a weak
#: reference to it: the next (a Boolean's result on its operand's faces) finds its carried faces'
#: contributions in one array pass.
_VOLUMES_OF = LastRecord()


def carried_shell_volumes(b: BRep, specs: tuple, unchanged: np.ndarray, extends: dict[int, tuple[int, object]],
                          tol: Tolerance | None = None) -> np.ndarray:
    """Signed volume enclosed by each shell, ``(S,)``, for the checker's orientation test: the faces
    equal to a spec whose contribution was integrated before about the same reference point take
    it from there; the others are integrated.

    ``specs`` (the face specs of ``b``, face order) and ``unchanged (F,)`` bool (the faces equal to
    them) as the sewing recorded them; ``extends``: ``{face: (n, spec)}`` for faces whose first
    ``n`` loops are, use for use, the loops of ``spec`` (a plate's top gaining a hole).  A face on a
    plane with a curved edge (its integral a sum over its boundary paths, about one plane point)
    extending a spec with a recorded contribution adds its new loops' paths to it.  A face's
    contribution is a function of its surface, sense, boundary (curves, p-curves, ranges) and, for
    a polygon, its vertices: a carried one equals the integral up to round-off and the vertices'
    tolerance, never in sign for a shell whose volume is larger than that.  So the result is for a
    sign test; :func:`shell_volumes` gives the volumes (and is what this returns when ``b``'s
    integrals are computed already, or when no face is carried: then they are computed and cached
    as there).  Contributions of faces equal to a spec whose curves are values
    are recorded (:data:`_FACE_VOLUMES`).

    Raises
    ------
    InvalidInputError, TopologyError, ConvergenceError
        As :func:`shell_volumes`.
    """
    rtol = _quadrature_rtol(tol)
    cache = _cache(b)
    if ("columns", rtol, True) in cache or ("columns", rtol, False) in cache:
        return shell_volumes(b, tol)
    ref = cache.get("x0")
    if ref is None:
        ref = cache["x0"] = _reference_point(b)
    key = (ref[0].tobytes(), ref[1], rtol)
    nf = b.n_faces
    vol = np.zeros(nf)
    have = np.zeros(nf, dtype=bool)
    rest = np.flatnonzero(unchanged)
    last = _VOLUMES_OF.last()
    if last is not None and last.key == key and rest.size and last.ids.size:
        # The specs of the last B-rep recorded, found by id in one pass (it holds them): a Boolean's
        # result carries most of its operand's faces.
        k, same = found_by_id(specs, last.ids, last.order)
        hit = unchanged & same & last.recorded[k]
        vol[hit] = last.vol[k[hit]]
        have = hit
        rest = np.flatnonzero(unchanged & ~hit)
    rows = rest.tolist()
    for f, got in zip(rows, _FACE_VOLUMES.get_many([specs[f] for f in rows])):
        if got is not None and key in got:
            vol[f] = got[key]
            have[f] = True
    carried = have.copy()
    extended = []
    new_loop = np.zeros(b.n_loops, dtype=bool)
    if extends:
        T = _tables(b)
        code = T.surface_code.take(b.face_surface)
        curved = T.curved_face
        for f, (n, old) in extends.items():
            got = _FACE_VOLUMES.get(old)
            if (not have[f] and got is not None and key in got and b.face_surface[f] >= 0
                    and code[f] == _C_PLANE and curved[f]):
                vol[f] = got[key]
                have[f] = True
                new_loop[b.face_loops[b.face_loop_ptr[f] + n:b.face_loop_ptr[f + 1]]] = True
                extended.append(f)
    need = ~have
    if not have.any():  # nothing carried: the B-rep's own integrals (cached, as shell_volumes)
        vol = _columns(b, rtol, False)[:, _VOL].copy()
    elif need.any() or extended:
        vol += _face_integrals(b, ref[0], ref[1], _N_VOL_COLS, rtol, need, new_loop)[:, _VOL]
    # Recorded for specs whose surface, curves and p-curves are values (nothing can change under
    # the record); an extended face's old loops are its old spec's, recorded under that test.
    old_loops = {f: extends[f][0] for f in extended}
    recorded = carried.copy()
    todo = np.flatnonzero(unchanged & ~carried)
    if todo.size:
        # (an unchanged face's uses hold its coedges' very curves and p-curves: read from the pools)
        from coons.topology.check import _first_loops, _value_faces

        todo = todo[_value_faces(b, _first_loops(b, old_loops) if old_loops else None)[todo]]
        todo = todo[np.array([is_value(spec) and is_value(spec.surface) for spec in map(specs.__getitem__, todo.tolist())],
                             dtype=bool)]
        made = [specs[f] for f in todo.tolist()]
        for spec, got, v in zip(made, _FACE_VOLUMES.get_many(made), vol[todo].tolist()):
            if got is None:
                _FACE_VOLUMES.set(spec, {key: v})
            else:
                got[key] = v
        recorded[todo] = True
    rec = _Volumes()
    rec.specs, rec.key, rec.vol, rec.recorded = tuple(specs), key, vol, recorded
    rec.ids, rec.order = id_index(rec.specs)
    _VOLUMES_OF.keep(b, rec)
    return np.bincount(b.face_shell, weights=vol, minlength=b.n_shells)[: b.n_shells]


# ============================================================================ face integrals
def _sum_by(idx: np.ndarray, vals: np.ndarray, n: int) -> np.ndarray:
    """Rows of ``vals`` ``(k, c)`` summed by ``idx`` ``(k,)`` into ``(n, c)`` (one bincount)."""
    c = vals.shape[1]
    flat = (idx[:, None] * c + np.arange(c)).ravel()
    return np.bincount(flat, weights=vals.ravel(), minlength=n * c).reshape(n, c)


def _face_integrals(b: BRep, x0: np.ndarray, L: float, ncols: int, rtol: float, faces: np.ndarray | None = None,
                    new_loop: np.ndarray | None = None) -> np.ndarray:
    """Per-face contributions ``(F, ncols)``: area, volume, first and second moments about ``x0``
    (``L``: the model's length scale, see :func:`_reference_point`).

    With ``faces`` ``(F,)`` bool, only those faces and the loops of ``new_loop`` ``(L,)`` bool
    (of planar faces with a curved edge, not in ``faces``; :func:`carried_shell_volumes`) are
    integrated, the other rows 0: the Green's-theorem sum of such a face is one term per boundary
    path, about a point of its plane, so its new loops' paths add to its old contribution.
    """
    nf = b.n_faces
    out = np.zeros((nf, ncols))
    if nf == 0:
        return out
    T = _tables(b)
    fs = b.face_surface
    # Face code of the quadrature rules: planes 0, cylinders and cones 1, spheres and tori 2
    # (γ ≠ 0: v enters trigonometrically), NURBS 3, unsupported 4; polygons become -1 (none).
    code = T.surface_code.take(fs)  # the sentinel row (face_surface = -1) is a plane
    face_has_curve = T.curved_face
    partial = None
    if faces is not None:
        partial = np.zeros(nf, dtype=bool)
        if new_loop is not None:
            partial[b.loop_face[new_loop]] = True
    if T.has_planes:
        # Planar faces (implicit, PlanarSurface or a flat NURBS net) bounded only by straight
        # edges are polygons: closed forms from their vertices, whatever the face's sense.
        poly = ((code == _C_PLANE) | ((code == _C_NURBS) & T.flat_nurbs.take(fs))) & ~face_has_curve
        if faces is not None:
            poly &= faces
        if poly.any():
            _polyhedral_integrals(b, poly, x0, ncols, out)
            code[poly] = _C_NONE
    if faces is not None:
        code[~(faces | partial)] = _C_NONE
    counts = np.bincount(code + 1, minlength=_C_OTHER + 2)  # none, plane, cyl/cone, sphere/torus, NURBS, other
    if counts[_C_OTHER + 1]:
        S = b.surfaces[int(fs[(code == _C_OTHER).nonzero()[0][0]])]
        raise InvalidInputError(
            f"cannot integrate over a {type(S).__name__}: supported surfaces are PlanarSurface, CylindricalSurface, "
            "ConicalSurface, SphericalSurface, ToroidalSurface and NurbsSurface"
        )
    green = code >= 0
    if not green.any():  # polygons only
        return out
    rows = T.surface_rows.take(fs, axis=0)
    origin, frame, par = rows[:, 0:3], rows[:, 3:12].reshape(-1, 3, 3), rows[:, 12:17]
    if T.implicit_curved:
        for f in ((fs < 0) & face_has_curve & green).nonzero()[0]:
            P = _implicit_plane(b, int(f))
            origin[f], frame[f] = P.origin, P.frame
    n_nurbs = counts[_C_NURBS + 1]
    nurbs = code == _C_NURBS if n_nurbs else None
    paths, uref = _gather_paths(b, green, code, origin, frame, nurbs)
    if partial is not None and partial.any():
        paths = _new_loop_paths(b, paths, green, partial, new_loop)
    scale = L ** _LENGTH_DEGREE[:ncols]
    o = (frame @ (origin - x0)[:, :, None])[:, :, 0]
    G, Gc = _face_geometry(o, par, np.where(code == _C_PLANE, -o[:, 0], uref),
                           bool(counts[_C_REV_LINEAR + 1] or counts[_C_REV_CIRCULAR + 1]))
    local = np.zeros((nf, ncols))
    if _analytic_integrals(paths, G, Gc, code, ncols, rtol, scale, local):
        out += _to_world(local, frame)
    if n_nurbs:
        _nurbs_integrals(b, paths, nurbs, uref, x0, ncols, rtol, scale, out)
    out[green & ~b.face_sense, _AREA] *= -1.0
    return out


def _new_loop_paths(b: BRep, paths: _Paths, green: np.ndarray, partial: np.ndarray, new_loop: np.ndarray) -> _Paths:
    """``paths`` (:func:`_gather_paths` of the faces ``green``) without the paths of the old loops
    of the faces ``partial`` ``(F,)`` bool: of those, only the paths of the loops ``new_loop`` are kept.
    The coedge paths come first, in the coedge order of :func:`_gather_paths`; gap paths (of NURBS
    faces only, never partial) after them."""
    sel = green.take(b.coedge_face).nonzero()[0]
    keep = np.ones(paths.face.size, dtype=bool)
    keep[: sel.size] = ~partial.take(b.coedge_face.take(sel)) | new_loop.take(b.coedge_loop.take(sel))
    at = np.cumsum(keep) - 1
    return _Paths(paths.face[keep], paths.t0[keep], paths.t1[keep], paths.sign[keep], paths.shape[keep],
                  paths.coef[keep], {int(at[p]): c for p, c in paths.curves.items() if keep[p]}, paths.block[keep])


def _polyhedral_integrals(b: BRep, poly: np.ndarray, x0: np.ndarray, ncols: int, out: np.ndarray) -> None:
    """Closed-form contributions of the polygonal faces in ``poly`` (planar, straight edges).

    Coedges that start or end at their face's reference vertex span flat tetrahedra and are
    skipped, so a triangle costs one tetrahedron.  Coordinates are handled as separate
    contiguous component arrays (gathers and products stay in cache-friendly 1-D passes).
    """
    nf = b.n_faces
    # Reference vertex of each face: the start of its first loop.
    has_loop = b.face_loop_ptr[1:] > b.face_loop_ptr[:-1]
    first_loop = b.face_loops[np.minimum(b.face_loop_ptr[:-1], max(b.face_loops.size - 1, 0))]
    lc = b.loop_coedge[first_loop]
    ref_v = np.where(lc >= 0, b.coedge_origin[np.maximum(lc, 0)], b.loop_vertex[first_loop])
    cf = b.coedge_face
    c = np.flatnonzero(poly[cf] & has_loop[cf])
    f = cf[c]
    rv, av, qv = ref_v[f], b.coedge_origin[c], b.coedge_target[c]
    keep = (av != rv) & (qv != rv)
    f, rv, av, qv = f[keep], rv[keep], av[keep], qv[keep]
    if f.size == 0:
        return
    X = [np.ascontiguousarray(b.vertex_point[:, k] - x0[k]) for k in range(3)]
    r = [x[rv] for x in X]
    a = [x[av] for x in X]
    q = [x[qv] for x in X]
    # a × q, then the signed volume r·(a × q)/6 of the tetrahedron (x0, r, a, q).
    aq = [a[1] * q[2] - a[2] * q[1], a[2] * q[0] - a[0] * q[2], a[0] * q[1] - a[1] * q[0]]
    vt = (r[0] * aq[0] + r[1] * aq[1] + r[2] * aq[2]) / 6.0
    out[:, _VOL] += np.bincount(f, weights=vt, minlength=nf)
    # Vector area: Σ ½ (a - r) × (q - r) over the fan of each loop (Newell).
    d = [a[k] - r[k] for k in range(3)]
    e = [q[k] - r[k] for k in range(3)]
    A = np.stack([
        np.bincount(f, weights=d[1] * e[2] - d[2] * e[1], minlength=nf),
        np.bincount(f, weights=d[2] * e[0] - d[0] * e[2], minlength=nf),
        np.bincount(f, weights=d[0] * e[1] - d[1] * e[0], minlength=nf),
    ], axis=1)
    out[:, _AREA] += np.where(poly, 0.5 * np.linalg.norm(A, axis=1), 0.0)
    if ncols <= _N_VOL_COLS:
        return
    s = [r[k] + a[k] + q[k] for k in range(3)]
    for k in range(3):
        out[:, 2 + k] += np.bincount(f, weights=vt * s[k], minlength=nf) / 4.0
    v20 = vt / 20.0
    for k, (i, j) in enumerate(_PAIRS):
        m = r[i] * r[j] + a[i] * a[j] + q[i] * q[j] + s[i] * s[j]
        out[:, 5 + k] += np.bincount(f, weights=v20 * m, minlength=nf)


# ---------------------------------------------------------------------------- tables
# Shapes of boundary paths, as far as the quadrature rules care: v constant (no contribution),
# straight with u constant, straight otherwise, trigonometric, a curve (NURBS), unsupported, none.
_P_ISO_V, _P_CONST_U, _P_LINE, _P_TRIG, _P_CURVE, _P_BAD, _P_MISSING = range(7)


@dataclass(frozen=True)
class _Tables:
    """The geometry of a B-rep as rows, built once per B-rep (one Python pass over its objects).

    Surfaces (one more row, last, for implicit planes): face code (``_C_*``) and a row of origin
    (3), frame (9: rows X, Y, Z) and the meridian ``(α, β, γ, δ, ε)`` of ``ρ = α + β v + γ cos v``,
    ``h = δ v + ε sin v`` for surfaces of revolution (module docstring).  Edges: whether the 3-D
    curve is not a line; faces: whether one of their edges is (not polygons).  P-curves (one more row, last, for "none"): shape and the coefficients
    of ``uv(t) = c0 + t l + cos t a + sin t b`` (columns ``c0, l, a, b``).
    """

    surface_code: np.ndarray  # (S + 1,) int8
    surface_rows: np.ndarray  # (S + 1, 17)
    flat_nurbs: np.ndarray  # (S + 1,) bool: a NURBS surface lying in a plane (_flat_nets)
    has_planes: bool  # some face is (or may be) planar
    curved_edge: np.ndarray  # (E,) bool
    curved_face: np.ndarray  # (F,) bool: a face with a curved edge
    implicit_curved: bool  # some implicit plane (face_surface = -1) has a curved edge
    pcurve_shape: np.ndarray  # (P + 1,) int8
    pcurve_coef: np.ndarray  # (P + 1, 8)


def _tables(b: BRep) -> _Tables:
    cache = _cache(b)
    T = cache.get("tables")
    if T is not None:
        return T
    from coons.topology.check import _SEWN_FROM

    donor = D = None
    for ref in _DONOR:  # the last sewn B-rep tabled first (a Boolean's operand, for its result)
        d = ref() if ref is not None else None
        D = _CACHE.get(d, {}).get("tables") if d is not None and d is not b else None
        if D is not None:
            donor = d
            break
    if D is not None:
        code, rows = _pool_rows(b.surfaces, pool_positions(b, donor, "surfaces"), D.surface_code, D.surface_rows,
                                _SURFACE_ROWS, _surface_rows)
        shape, coef = _pool_rows(b.pcurves, pool_positions(b, donor, "pcurves"), D.pcurve_shape, D.pcurve_coef,
                                 _PCURVE_ROWS, _pcurve_rows)
    else:
        none = np.full(len(b.surfaces), -1, dtype=np.int64)
        code, rows = _pool_rows(b.surfaces, none, _NO_CODE, _IMPLICIT_PLANE_ROW_2D, _SURFACE_ROWS, _surface_rows)
        none = np.full(len(b.pcurves), -1, dtype=np.int64)
        shape, coef = _pool_rows(b.pcurves, none, _NO_CODE, _ZEROS8_2D, _PCURVE_ROWS, _pcurve_rows)
    code = np.append(code, np.int8(_C_PLANE))
    rows = np.concatenate([rows, _IMPLICIT_PLANE_ROW_2D])
    # (classified as _classify_shapes does)
    shape = np.append(shape, np.int8(_P_MISSING))
    coef = np.concatenate([coef, _ZEROS8_2D])
    curved = np.array([not isinstance(c, Line) for c in b.curves] + [False]).take(b.edge_curve)
    fs = b.face_surface
    implicit = fs.size > 0 and int(fs.min()) < 0
    flat = np.zeros(code.size, dtype=bool)
    nurbs = (code[:-1] == _C_NURBS).nonzero()[0]
    if nurbs.size:
        flat[nurbs] = _flat_nets([b.surfaces[i].control_points for i in nurbs])
    has_planes = implicit or bool((code[:-1] == _C_PLANE).any()) or bool(flat.any())
    curved_face = np.zeros(fs.size, dtype=bool)
    curved_face[b.coedge_face.reshape(-1, 2)[curved].ravel()] = True
    implicit_curved = implicit and bool((fs[curved_face] < 0).any())
    T = cache["tables"] = _Tables(code, rows, flat, has_planes, curved, _read_only(curved_face), implicit_curved,
                                  shape, coef)
    ref = weakref.ref(b)
    _DONOR[:] = [ref if b in _SEWN_FROM else _DONOR[0], ref]
    return T


def pcurve_table(b: BRep) -> np.ndarray:
    """The p-curve coefficient rows of ``b``'s mass tables, ``(P + 1, 8)`` (never written): row ``i`` of
    ``b.pcurves[i]`` a :class:`Line2D` is its origin and direction, of a :class:`Trig2D` its centre
    (columns 0:2) and axes ``a``, ``b`` (4:6, 6:8), the very floats of the p-curve (the checker
    samples them from here)."""
    return _tables(b).pcurve_coef


def _pool_rows(objs: tuple, pos: np.ndarray, donor_code: np.ndarray, donor_rows: np.ndarray, memo: IdentityMemo,
               rows_of: Callable) -> tuple[np.ndarray, np.ndarray]:
    """The codes ``(n,)`` int8 and rows ``(n, w)`` of :class:`_Tables` for the geometry objects
    ``objs`` of a B-rep's pool (its surfaces or p-curves): those at positions ``pos >= 0`` of a
    donor's pool (:func:`~coons.topology._memo.pool_positions`) gathered from the donor's table
    in one take, the others from :data:`_SURFACE_ROWS` / :data:`_PCURVE_ROWS` or ``rows_of``
    (a list of objects -> their codes ``(m,)`` and rows ``(m, w)``).  A row is a function of its
    object alone, so it does not matter which table it is read from.  The rows made are one array
    (each object's row a read-only view of it), remembered in one call (a Boolean of a hundred
    tools brings a thousand new p-curves)."""
    code = donor_code.take(pos)  # (-1, absent from the donor, reads the sentinel and is overwritten)
    rows = donor_rows.take(pos, axis=0)
    miss = np.flatnonzero(pos < 0)
    if miss.size:
        need = [objs[i] for i in miss.tolist()]
        got = memo.get_many(need)
        old = [k for k, g in enumerate(got) if g is not None]
        if old:
            code[miss[old]] = [got[k][0] for k in old]
            rows[miss[old]] = np.concatenate([got[k][1] for k in old]).reshape(len(old), -1)
        if len(old) < len(need):
            new = [k for k, g in enumerate(got) if g is None]
            made = [need[k] for k in new]
            kinds, R = rows_of(made)
            R = _read_only(R)
            code[miss[new]] = kinds
            rows[miss[new]] = R
            kinds = kinds.tolist()
            if not all_values(made):
                keep = [k for k, o in enumerate(made) if is_value(o)]
                made, kinds, R = [made[k] for k in keep], [kinds[k] for k in keep], _read_only(R[keep])
            memo.set_many(made, zip(kinds, R))
    return code, rows


#: The last sewn B-rep (``check._SEWN_FROM``) whose :class:`_Tables` were built and the last B-rep
#: whose tables were built (weak references): the next B-rep's tables (a Boolean's result, most of
#: whose surfaces and p-curves are its operand's) take the rows of the objects they share from the
#: first of them alive in one gather (:func:`_pool_rows`); a tool tabled since the operand does not
#: displace it.  They hold nothing once ``_CACHE`` forgets those B-reps.
_DONOR: list = [None, None]


def _surface_row(S) -> tuple[int, list[float]]:
    """The face code and the row of :class:`_Tables` of one surface (a function of the surface alone)."""
    if isinstance(S, PlanarSurface):
        return _C_PLANE, S.origin.tolist() + S.frame.ravel().tolist() + [0.0, 0.0, 0.0, 0.0, 0.0]
    p = meridian_row(S)  # (cylinder, cone: ρ, h linear in v; sphere, torus: circular)
    if p is None:
        return (_C_NURBS if isinstance(S, NurbsSurface) else _C_OTHER), _NO_SURFACE_ROW
    k = _C_REV_LINEAR if isinstance(S, (CylindricalSurface, ConicalSurface)) else _C_REV_CIRCULAR
    org = S.origin if k == _C_REV_LINEAR else S.center
    return k, org.tolist() + S.frame.ravel().tolist() + list(p)


def _pcurve_row(pc) -> tuple[int, list[float]]:
    """The shape and the coefficient row of :class:`_Tables` of one p-curve (a function of the p-curve alone)."""
    if isinstance(pc, Line2D):
        du, dv = pc.direction.tolist()
        return (_P_ISO_V if dv == 0.0 else _P_CONST_U if du == 0.0 else _P_LINE), pc.origin.tolist() + [du, dv] + _ZEROS4
    if isinstance(pc, Trig2D):
        a, bb = pc.a.tolist(), pc.b.tolist()
        return (_P_ISO_V if a[1] == 0.0 and bb[1] == 0.0 else _P_TRIG), pc.center.tolist() + _ZEROS2 + a + bb
    return (_P_CURVE if isinstance(pc, NurbsCurve) and pc.dimension == 2 else _P_BAD), _ZEROS8


def _surface_rows(surfaces: list) -> tuple[np.ndarray, np.ndarray]:
    """:func:`_surface_row` of each surface: codes ``(m,)`` int8 and rows ``(m, 17)``."""
    kinds, R = zip(*map(_surface_row, surfaces))
    return np.array(kinds, dtype=np.int8), np.array(R, dtype=np.float64)


def _pcurve_rows(pcurves: list) -> tuple[np.ndarray, np.ndarray]:
    """:func:`_pcurve_row` of each p-curve: shapes ``(m,)`` int8 and rows ``(m, 8)``, the same values;
    the :class:`Line2D` and :class:`Trig2D` p-curves (the fitted ones aside, all of a Boolean's new
    p-curves) by one array pass per type over their gathered coefficients."""
    m = len(pcurves)
    shape = np.empty(m, dtype=np.int8)
    R = np.zeros((m, 8))
    kind = np.fromiter(map(id, map(type, pcurves)), dtype=np.int64, count=m)  # (exact types: no subclass)
    line = np.flatnonzero(kind == id(Line2D))
    if line.size:
        some = [pcurves[i] for i in line.tolist()]
        R[line, 0:2] = _rows_of(some, "origin")
        R[line, 2:4] = D = _rows_of(some, "direction")
        shape[line] = np.where(D[:, 1] == 0.0, _P_ISO_V, np.where(D[:, 0] == 0.0, _P_CONST_U, _P_LINE))
    trig = np.flatnonzero(kind == id(Trig2D))
    if trig.size:
        some = [pcurves[i] for i in trig.tolist()]
        R[trig, 0:2] = _rows_of(some, "center")
        R[trig, 4:6] = A = _rows_of(some, "a")
        R[trig, 6:8] = B = _rows_of(some, "b")
        shape[trig] = np.where((A[:, 1] == 0.0) & (B[:, 1] == 0.0), _P_ISO_V, _P_TRIG)
    for i in np.flatnonzero((kind != id(Line2D)) & (kind != id(Trig2D))).tolist():  # (any other type)
        shape[i], R[i] = _pcurve_row(pcurves[i])
    return shape, R


def _rows_of(objs: list, name: str) -> np.ndarray:
    """The 2-vector attribute ``name`` of the p-curves ``objs``, stacked ``(m, 2)``: their bytes joined
    (the constructors of :class:`Line2D` and :class:`Trig2D` make each a contiguous float64 array of
    its own or a row of one; several times faster than ``np.array`` of the list)."""
    return np.frombuffer(b"".join(map(operator.attrgetter(name), objs)), dtype=np.float64).reshape(-1, 2)


#: Surface -> :func:`_surface_row`, p-curve -> :func:`_pcurve_row` (code and row as a read-only
#: array): the per-object rows of :class:`_Tables`, which a B-rep sewn from the faces of another
#: (a Boolean's result) shares with it.  Rows are never modified.
_SURFACE_ROWS = IdentityMemo()
_PCURVE_ROWS = IdentityMemo()


def _flat_nets(nets: list) -> np.ndarray:
    """Whether each control net ``(nu, nv, 3)`` lies in one plane to the round-off of its coordinates.

    A NURBS surface lies in the convex hull of its control points (positive weights), so a flat
    net makes a planar surface, whose faces bounded by straight edges are polygons
    (:func:`_polyhedral_integrals`, exact).  Nets of one size are tested together: the smallest
    singular value of the centred points bounds every point's distance from their best plane;
    it must be within ``_FLAT_ULPS`` ulps of the largest coordinate (coordinates are only
    known to that: such a net is the rounded image of a plane).
    """
    out = np.zeros(len(nets), dtype=bool)
    by_size: dict[tuple, list[int]] = {}
    for i, P in enumerate(nets):
        if P.shape[-1] == 3:
            by_size.setdefault(P.shape, []).append(i)
    for rows in by_size.values():
        P = np.stack([nets[i] for i in rows]).reshape(len(rows), -1, 3)
        Q = P - P.mean(axis=1, keepdims=True)
        smallest = np.linalg.svd(Q, compute_uv=False)[:, -1]
        scale = np.abs(P).max(axis=(1, 2))
        out[rows] = smallest <= _FLAT_ULPS * _EPS * scale
    return out


_ZEROS2, _ZEROS4, _ZEROS8 = [0.0] * 2, [0.0] * 4, [0.0] * 8
_NO_SURFACE_ROW = [0.0] * 17
_NO_CODE = np.zeros(1, dtype=np.int8)  # a donor of one sentinel row, for the tables built without one
_ZEROS8_2D = _read_only(np.zeros((1, 8)))
_IMPLICIT_PLANE_ROW = [0.0] * 3 + np.eye(3).ravel().tolist() + [0.0] * 5
_IMPLICIT_PLANE_ROW_2D = _read_only(np.array([_IMPLICIT_PLANE_ROW]))


def _classify_shapes(shape: np.ndarray, coef: np.ndarray) -> None:
    """Refine ``_P_LINE`` and ``_P_TRIG`` rows of ``shape`` by their coefficients (in place)."""
    iso_v = (coef[:, 3::2] == 0.0).all(axis=1)  # l_v = a_v = b_v = 0
    simple = shape <= _P_TRIG
    shape[simple & (shape == _P_LINE) & (coef[:, 2] == 0.0)] = _P_CONST_U
    shape[simple & iso_v] = _P_ISO_V


# ---------------------------------------------------------------------------- paths
# Blocks of boundary paths by quadrature (the face code of _face_integrals × the path shape).
_B_SKIP, _B_POLY_P, _B_TRIG_P, _B_GAUSS_P, _B_POLY_R, _B_TRIG_R, _B_GAUSS_R, _B_ADAPT, _B_NURBS = range(9)
_BLOCKS = np.array([
    # iso-v    const-u     line        trig        curve
    [_B_SKIP, _B_SKIP, _B_SKIP, _B_SKIP, _B_SKIP],  # no integration (-1)
    [_B_SKIP, _B_POLY_P, _B_POLY_P, _B_TRIG_P, _B_ADAPT],  # plane
    [_B_SKIP, _B_POLY_R, _B_GAUSS_R, _B_GAUSS_R, _B_ADAPT],  # cylinder, cone
    [_B_SKIP, _B_TRIG_R, _B_GAUSS_R, _B_GAUSS_R, _B_ADAPT],  # sphere, torus
    [_B_SKIP, _B_NURBS, _B_NURBS, _B_NURBS, _B_NURBS],  # NURBS
], dtype=np.int8)


#: Shortest angular span (ω (t1 - t0)) integrated by the exact 9-node trigonometric rule; shorter
#: arcs and meridians use Gauss nodes on the path (the rule's nodes spread over a full period).
_TRIG_RULE_MIN_SPAN = ANGLE_STEP
_TRIG_BLOCK = np.zeros(_B_NURBS + 1, dtype=bool)
_TRIG_BLOCK[[_B_TRIG_P, _B_TRIG_R]] = True


@dataclass(frozen=True, eq=False)
class _Paths:
    """Boundary paths in parameter space, one row each: the coedges of the gathered faces, then
    the straight gaps between consecutive coedges whose p-curves do not meet.

    Path ``p`` is ``uv(t)`` for ``t`` from ``t0`` to ``t1`` walked in direction ``sign``;
    ``uv(t) = c0 + t l + cos t a + sin t b`` from ``coef`` for straight and trigonometric
    paths; for curves ``curves[p] = (curve, d0, d1)``: a 2-D curve evaluated at ``t`` clipped
    into ``[d0, d1]``.  ``block`` is the quadrature block (``_B_*``).
    """

    face: np.ndarray  # (m,) int64
    t0: np.ndarray  # (m,)
    t1: np.ndarray  # (m,)
    sign: np.ndarray  # (m,) ±1.0
    shape: np.ndarray  # (m,) int8
    coef: np.ndarray  # (m, 8)
    curves: dict
    block: np.ndarray  # (m,) int8

    def evaluate(self, pid: np.ndarray, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``uv`` and ``duv/dt`` of paths ``pid`` ``(n,)`` at ``t`` ``(n,)``, each ``(n, 2)``."""
        on_curve = self.shape.take(pid) == _P_CURVE if self.curves else None
        if on_curve is None or not on_curve.any():
            return self._table(pid, t)
        # The table's rows only where they are used (the adaptive block's paths are mostly curves).
        uv, duv = np.empty((pid.size, 2)), np.empty((pid.size, 2))
        rows = (~on_curve).nonzero()[0]
        if rows.size:
            uv[rows], duv[rows] = self._table(pid.take(rows), t.take(rows))
        # The rows of each curve path in their order, from one stable sort (a mask per path cost a pass
        # over all rows each).
        rows = on_curve.nonzero()[0]
        rows = rows.take(np.argsort(pid.take(rows), kind="stable"))
        ids = pid.take(rows)
        # One batch for the polynomial NURBS p-curves (the fitted ones) of one degree.
        groups = np.split(rows, (ids[1:] != ids[:-1]).nonzero()[0] + 1)
        entries = [self.curves[int(pid[r[0]])] for r in groups]
        D = derivatives_many([c for c, _, _ in entries],
                             [np.clip(t.take(r), d0, d1) for r, (_, d0, d1) in zip(groups, entries)], 1)
        for r, Dr in zip(groups, D):
            uv[r], duv[r] = Dr[0], Dr[1]
        return uv, duv

    def _table(self, pid: np.ndarray, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`evaluate` of table paths (straight and trigonometric) ``pid`` ``(n,)`` at ``t`` ``(n,)``."""
        C = self.coef.take(pid, axis=0)
        c, s = np.cos(t)[:, None], np.sin(t)[:, None]
        uv = C[:, 0:2] + t[:, None] * C[:, 2:4] + c * C[:, 4:6] + s * C[:, 6:8]
        duv = C[:, 2:4] + c * C[:, 6:8] - s * C[:, 4:6]
        return uv, duv

    def breaks(self, p: int) -> np.ndarray:
        """Interior breakpoints of path ``p``: the knots of its curve inside ``(t0, t1)``."""
        if self.shape[p] != _P_CURVE:
            return np.empty(0)
        return _interior_knots(np.asarray(self.curves[p][0].knots), float(self.t0[p]), float(self.t1[p]))


def _gather_paths(b: BRep, need: np.ndarray, code: np.ndarray, origin, frame,
                  gaps: np.ndarray | None) -> tuple[_Paths, np.ndarray]:
    """The boundary paths of the faces in ``need`` ``(F,)``, with their quadrature blocks from the
    face ``code`` ``(F,)`` (planes 0, ...; ``_face_integrals``), and ``u_ref`` per face ``(F,)``.

    Coedges without a p-curve on planar faces (code 0) get the projection of their 3-D edge onto
    the face's plane (``origin``, ``frame`` per face).  Gap segments are added for the faces in
    ``gaps`` ``(F,)`` only (None: none): an analytic surface collapses only along iso-``v`` lines
    (sphere poles, cone apices), so the gaps of analytic faces add nothing to ``∮ F dv``.

    Raises
    ------
    InvalidInputError
        A p-curve of an unsupported type, or a 3-D curve that cannot be projected.
    TopologyError
        A coedge without a p-curve on a face that is not planar.
    """
    cf = b.coedge_face
    sel = need.take(cf).nonzero()[0]
    e, side, f = sel >> 1, sel & 1, cf.take(sel)
    rng = b.edge_range.take(e, axis=0)
    t0, t1 = rng[:, 0], rng[:, 1]
    pi = b.edge_pcurve.ravel().take(sel)  # coedge c = 2 e + side
    T = _tables(b)
    shape, coef = T.pcurve_shape.take(pi), T.pcurve_coef.take(pi, axis=0)
    curves = {}
    if sel.size and shape.max() >= _P_CURVE:
        for i in (shape == _P_BAD).nonzero()[0][:1]:
            raise InvalidInputError(
                f"cannot integrate along a {type(b.pcurves[pi[i]]).__name__} p-curve (edge {e[i]}, face {f[i]}): "
                "supported are Line2D, Trig2D and 2-D NurbsCurve"
            )
        for i in (shape == _P_CURVE).nonzero()[0]:
            pc = b.pcurves[pi[i]]
            curves[int(i)] = (pc, *pc.domain)
        missing = (shape == _P_MISSING).nonzero()[0]
        for i in missing:
            fi = int(f[i])
            if code[fi] != 0:
                S = b.surfaces[int(b.face_surface[fi])]
                raise TopologyError(
                    f"coedge {sel[i]} (edge {e[i]}) of face {fi} on a {type(S).__name__} has no p-curve; only planar "
                    "faces may omit p-curves"
                )
            shape[i], coef[i], curve = _projected(b, int(e[i]), origin[fi], frame[fi])
            if curve is not None:
                curves[int(i)] = (curve, *curve.domain)
        if missing.size:
            _classify_shapes(shape, coef)
    sign = 1.0 - 2.0 * side
    block = _BLOCKS[code.take(f) + 1, shape]
    # Arcs and meridians spanning less than ANGLE_STEP keep Gauss nodes on the path
    # (_analytic_integrals): their trigonometric block becomes the Gauss block after it.
    omega = np.where(shape == _P_TRIG, 1.0, np.abs(coef[:, 3]))  # angular speed of a trigonometric rule
    block += _TRIG_BLOCK.take(block) & (omega * (t1 - t0) < _TRIG_RULE_MIN_SPAN)
    paths = _Paths(f, t0, t1, sign, shape, coef, curves, block)
    # u_ref: u where the face's first gathered path starts (t0); planes use their own (-ox).
    first = np.zeros(b.n_faces, dtype=np.int64)
    first[f[::-1]] = np.arange(sel.size)[::-1]
    uref = np.zeros(b.n_faces)
    if sel.size and code.max() > 0:
        C, tt = coef.take(first, axis=0), t0.take(first)
        uref = C[:, 0] + tt * C[:, 2] + np.cos(tt) * C[:, 4] + np.sin(tt) * C[:, 6]
        if curves:
            cf_ = (shape.take(first) == _P_CURVE).nonzero()[0]
            if cf_.size:
                uref[cf_] = paths.evaluate(first[cf_], tt[cf_])[0][:, 0]
    if gaps is not None:
        paths = _with_gaps(b, paths, sel, gaps.take(f).nonzero()[0])
    return paths, uref


def _with_gaps(b: BRep, paths: _Paths, sel: np.ndarray, sub: np.ndarray) -> _Paths:
    """``paths`` plus a straight segment wherever path ``i`` in ``sub`` (a coedge ``sel[i]``) ends
    away from where the next coedge's path starts by more than the round-off of evaluating the two
    (a mismatch within it is no gap: its segment would add a round-off-sized term)."""
    pos = np.full(2 * b.n_edges, -1, dtype=np.int64)
    pos[sel] = np.arange(sel.size)
    nxt = pos.take(b.coedge_next.take(sel.take(sub)))
    both = np.concatenate([sub, nxt])
    fwd = paths.sign.take(both) > 0
    ta = np.where(fwd, paths.t0.take(both), paths.t1.take(both))  # start in the walking direction
    tb = np.where(fwd, paths.t1.take(both), paths.t0.take(both))
    k = sub.size
    end = paths.evaluate(sub, tb[:k])[0]
    start = paths.evaluate(nxt, ta[k:])[0]
    A = np.abs(paths.coef.take(both, axis=0))
    mag = A[:, 0:2] + A[:, 4:6] + A[:, 6:8] + A[:, 2:4] * np.maximum(np.abs(ta), np.abs(tb))[:, None]
    diff = start - end
    bound = 16.0 * _EPS * (mag[:k] + mag[k:] + np.abs(start) + np.abs(end))
    gap = (np.abs(diff) > bound).any(axis=1).nonzero()[0]
    if gap.size == 0:
        return paths
    gc = np.zeros((gap.size, 8))
    gc[:, 0:2] = end[gap]
    gc[:, 2:4] = diff[gap]
    gf = paths.face.take(sub.take(gap))
    one = np.ones(gap.size)
    gshape = np.where(diff[gap, 1] == 0.0, _P_ISO_V, np.where(diff[gap, 0] == 0.0, _P_CONST_U, _P_LINE)).astype(np.int8)
    gblock = np.where(gshape == _P_ISO_V, _B_SKIP, _B_NURBS).astype(np.int8)  # gaps only matter on NURBS
    cat = np.concatenate
    return _Paths(cat([paths.face, gf]), cat([paths.t0, 0.0 * one]), cat([paths.t1, one]), cat([paths.sign, one]),
                  cat([paths.shape, gshape]), cat([paths.coef, gc]), paths.curves, cat([paths.block, gblock]))


def _projected(b: BRep, e: int, O: np.ndarray, frame: np.ndarray) -> tuple[int, np.ndarray, object]:
    """The exact p-curve of edge ``e`` on the plane ``(O, frame)``: shape, coefficients, 2-D curve or None.

    Raises
    ------
    InvalidInputError
        An edge curve other than a line, circle, ellipse or NURBS curve.
    """
    J = frame[:2].T  # (3, 2): uv = (P - O) @ J
    ci = int(b.edge_curve[e])
    t0, t1 = (float(x) for x in b.edge_range[e])
    c8 = np.zeros(8)
    if ci < 0:
        a, q = b.vertex_point[b.edge_vertex[e]]
        d = (q - a) / (t1 - t0)
        c8[0:2], c8[2:4] = (a - t0 * d - O) @ J, d @ J
        return _P_LINE, c8, None
    curve = b.curves[ci]
    if isinstance(curve, Line):
        c8[0:2], c8[2:4] = (curve.origin - O) @ J, curve.direction @ J
        return _P_LINE, c8, None
    if isinstance(curve, (Circle, Ellipse)):
        ra, rb = (curve.radius, curve.radius) if isinstance(curve, Circle) else (curve.major_radius, curve.minor_radius)
        c8[0:2], c8[4:6], c8[6:8] = (curve.center - O) @ J, ra * curve.frame[0] @ J, rb * curve.frame[1] @ J
        return _P_TRIG, c8, None
    if isinstance(curve, NurbsCurve):
        return _P_CURVE, c8, NurbsCurve((curve.control_points - O) @ J, curve.knots, curve.degree, curve.weights)
    raise InvalidInputError(
        f"cannot integrate along a {type(curve).__name__} edge curve (edge {e}) projected onto a plane: supported "
        "are Line, Circle, Ellipse and NurbsCurve"
    )


# ---------------------------------------------------------------------------- analytic faces
# Per-face geometry of the closed-form integrands, one column per face so that a block of nodes
# gathers it with one take: real rows ``(12, F)`` — the surface origin minus x0 in the face's
# frame (ox, oy, oz), u_ref, the meridian speed |(ρ', h')| (constant on every supported surface of
# revolution) and the meridian coefficients (α, β, γ, δ, ε) — and complex rows ``(6, F)``:
# z = ox + i oy, its conjugate, z², |z|², and e^{i m u_ref} for m = 1, 2, 3.
_OX, _OY, _OZ, _UR, _SPEED, _PAR = 0, 1, 2, 3, 4, 5
_Z, _ZC, _ZZ, _ZABS2, _ER1, _ER2, _ER3 = range(7)


def _face_geometry(o: np.ndarray, par: np.ndarray, uref: np.ndarray, revolved: bool) -> tuple[np.ndarray, np.ndarray]:
    """Per-face rows (see above) from ``o`` ``(F, 3)``, ``par`` ``(F, 5)``, ``uref`` ``(F,)``; the
    complex rows only when some face is a surface of revolution (``revolved``)."""
    # Cylinders and cones have γ = ε = 0 and a unit (sin a, cos a); spheres and tori β = δ = 0, γ = ε.
    speed = np.hypot(par[:, 1], par[:, 3]) + par[:, 2]
    G = np.concatenate([o.T, uref[None], speed[None], par.T])
    if not revolved:
        return G, None
    Gc = np.empty((7, uref.size), dtype=np.complex128)
    z = Gc[_Z] = o[:, 0] + 1j * o[:, 1]
    Gc[_ZC] = z.conj()
    Gc[_ZZ] = z * z
    Gc[_ZABS2] = z * Gc[_ZC]
    er = Gc[_ER1] = np.exp(1j * uref)
    Gc[_ER2] = er * er
    Gc[_ER3] = Gc[_ER2] * er
    return G, Gc


def _plane_F(R: np.ndarray, u: np.ndarray, v: np.ndarray, ncols: int) -> np.ndarray:
    """``F(u, v) = ∫_{u_ref}^{u} f(s, v) ds`` on planes, in the face's frame, ``(n, ncols)``.

    ``R`` holds the face rows of each node ``(10, n)``; ``u, v`` are ``(n,)``.  On planes
    ``u_ref = -ox``, so that ``x - x0 = (s - u_ref, oy + v, oz)`` and ``(x - x0)·n = oz``
    (``n = X × Y = Z``); with ``d = u - u_ref`` and ``b = oy + v``::

        F_area = d,  F_vol = oz d / 3,  F_first = oz/4 (d²/2, b d, oz d),
        F_second = oz/5 (d³/3, b² d, oz² d, b d²/2, oz d²/2, b oz d).
    """
    out = np.empty((u.size, ncols))
    oz = R[_OZ]
    d = u - R[_UR]
    out[:, _AREA] = d
    ozd = oz * d
    out[:, _VOL] = ozd / 3.0
    if ncols > _N_VOL_COLS:
        b = R[_OY] + v
        h = 0.5 * d * d
        bd = b * d
        q5 = 0.2 * oz
        out[:, 2] = 0.25 * oz * h
        out[:, 3] = 0.25 * oz * bd
        out[:, 4] = 0.25 * oz * ozd
        out[:, 5] = q5 * h * d / 1.5
        out[:, 6] = q5 * b * bd
        out[:, 7] = q5 * oz * ozd
        out[:, 8] = q5 * b * h
        out[:, 9] = q5 * oz * h
        out[:, 10] = q5 * b * ozd
    return out


def _revolved_F(R: np.ndarray, Rc: np.ndarray, u: np.ndarray, v: np.ndarray, ncols: int,
                meridian: int = 0) -> np.ndarray:
    """``F(u, v) = ∫_{u_ref}^{u} f(s, v) ds`` on surfaces of revolution, in the face's frame, in
    closed form, ``(n, ncols)`` (``R``, ``Rc``: the real and complex face rows of each node).

    ``x - x0 = (ox + ρ cos s, oy + ρ sin s, oz + h)`` and ``Su × Sv = ρ (h' e - ρ' Z)``.  With
    ``z = ox + i oy``, ``(x - x0)_x + i (x - x0)_y = z + ρ e^{is}`` and ``(x - x0)·(Su × Sv) = w0 +
    (k/2)(z̄ e^{is} + z e^{-is})``, ``k = ρ h'``, ``w0 = ρ (ρ h' - ρ' (oz + h))``; the area integrand
    ``|ρ| |(ρ', h')|`` is constant in ``s``.  Every column then follows from ``E_m = ∫ e^{ims} ds``
    over ``[u_ref, u]`` (``m = 1, 2, 3``)::

        W  = ∫ w = w0 d + k Re(z̄ E1),   G1 = ∫ e^{is} w = w0 E1 + k/2 (z̄ E2 + z d),
        G2 = ∫ e^{2is} w = w0 E2 + k/2 (z̄ E3 + z E1),
        ∫ (x + i y) w = z W + ρ G1,   ∫ (x² + y²) w = (|z|² + ρ²) W + 2ρ Re(z̄ G1),
        ∫ (x + i y)² w = z² W + 2 z ρ G1 + ρ² G2  (= ∫ (x² - y²) w + 2i ∫ x y w).

    ``meridian``: 0 any surface of revolution; 1 cylinders and cones only (``γ = ε = 0``: the
    meridian is straight); 2 spheres and tori only (``β = δ = 0``, ``γ = ε``: a circle), where
    ``ρ`` stands for ``|ρ|`` (its analytic continuation, ``ρ >= 0`` on every sphere and torus
    face), as the exact trigonometric rule needs.
    """
    if meridian == 1:
        be, de = R[_PAR + 1], R[_PAR + 3]
        rho = R[_PAR] + be * v
        pz = R[_OZ] + de * v  # oz + h
        k = rho * de  # ρ h'
        w0 = rho * (k - be * pz)
    else:
        cv, sv = np.cos(v), np.sin(v)
        ga = R[_PAR + 2]
        if meridian == 2:
            rho = R[_PAR] + ga * cv
            gs = ga * sv
            pz = R[_OZ] + gs
            k = rho * ga * cv
            w0 = rho * (k + gs * pz)
        else:
            be, de, ep = R[_PAR + 1], R[_PAR + 3], R[_PAR + 4]
            rho = R[_PAR] + be * v + ga * cv
            pz = R[_OZ] + de * v + ep * sv
            k = rho * (de + ep * cv)
            w0 = rho * (k - (be - ga * sv) * pz)
    zc = Rc[_ZC]
    d = u - R[_UR]
    eu = np.exp(1j * u)
    E1 = (Rc[_ER1] - eu) * 1j
    W = w0 * d + k * (zc * E1).real
    out = np.empty((u.size, ncols))
    out[:, _AREA] = d * (rho if meridian == 2 else np.abs(rho)) * R[_SPEED]
    out[:, _VOL] = W / 3.0
    if ncols > _N_VOL_COLS:
        z = Rc[_Z]
        eu2 = eu * eu
        E2 = (Rc[_ER2] - eu2) * 0.5j
        E3 = (Rc[_ER3] - eu2 * eu) * (1j / 3.0)
        kh = 0.5 * k
        G1 = w0 * E1 + kh * (zc * E2 + z * d)
        G2 = w0 * E2 + kh * (zc * E3 + z * E1)
        F1 = (z * W + rho * G1).view(np.float64).reshape(-1, 2)  # ∫ (x, y) w
        rr = rho * rho
        S = (Rc[_ZABS2].real + rr) * W + 2.0 * rho * (zc * G1).real
        Q = (Rc[_ZZ] * W + (2.0 * rho) * z * G1 + rr * G2).view(np.float64).reshape(-1, 2)
        pzW = pz * W
        out[:, 2:4] = 0.25 * F1
        out[:, 4] = 0.25 * pzW
        out[:, 5] = 0.1 * (S + Q[:, 0])
        out[:, 6] = 0.1 * (S - Q[:, 0])
        out[:, 7] = 0.2 * pz * pzW
        out[:, 8] = 0.1 * Q[:, 1]
        out[:, 9:11] = (0.2 * pz)[:, None] * F1
    return out


def _analytic_F(G: np.ndarray, Gc: np.ndarray, code: np.ndarray, f: np.ndarray, u: np.ndarray, v: np.ndarray,
                ncols: int) -> np.ndarray:
    """``F(u, v)`` ``(n, ncols)`` for nodes on faces ``f`` ``(n,)`` that are planes or surfaces of revolution."""
    plane = code.take(f) == 0
    if u.size and (plane.all() or not plane.any()):
        # Faces of one kind (the curved paths of most Booleans lie on revolved faces): no gathers.
        R = G.take(f, axis=1)
        return _plane_F(R, u, v, ncols) if plane[0] else _revolved_F(R, Gc.take(f, axis=1), u, v, ncols)
    out = np.empty((u.size, ncols))
    for sel, is_plane in ((plane.nonzero()[0], True), ((~plane).nonzero()[0], False)):
        if sel.size:
            fs = f[sel]
            R = G.take(fs, axis=1)
            out[sel] = (_plane_F(R, u[sel], v[sel], ncols) if is_plane
                        else _revolved_F(R, Gc.take(fs, axis=1), u[sel], v[sel], ncols))
    return out


def _to_world(local: np.ndarray, frame: np.ndarray) -> np.ndarray:
    """Per-face columns ``(F, ncols)`` integrated in the faces' frames ``(F, 3, 3)``, in world axes."""
    if local.shape[1] <= _N_VOL_COLS:
        return local
    out = local.copy()
    out[:, _FIRST] = (local[:, None, _FIRST] @ frame)[:, 0]
    M = local[:, _SYM9].reshape(-1, 3, 3)
    out[:, _SECOND] = (frame.transpose(0, 2, 1) @ M @ frame).reshape(-1, 9)[:, _UPPER6]
    return out


#: Columns of the second moments as a row-major 3 × 3 matrix, and the matrix entries of the columns.
_SYM9 = np.array([5, 8, 9, 8, 6, 10, 9, 10, 7])
_UPPER6 = np.array([0, 4, 8, 1, 2, 5])


# Exact rule for trigonometric polynomials of degree <= 4 in θ = ω t over any interval: nodes at
# θ_0 + 2πj/9; weights from the integrals of (1, cos kφ, sin kφ), k <= 4, over [0, Δθ] and the
# inverse of the (orthogonal) Fourier matrix.
_TRIG_RULE_NODES = 9
_PHI9 = _TWO_PI * np.arange(_TRIG_RULE_NODES) / _TRIG_RULE_NODES
_K1234 = np.arange(1.0, 5.0)
_INV_IK = 1.0 / (1j * _K1234)
_E9 = np.stack([np.ones(_TRIG_RULE_NODES)] + [f(k * _PHI9) for k in _K1234 for f in (np.cos, np.sin)], axis=1)
_E9_INV = _E9.T * np.array([1.0] + [2.0] * 8)[:, None] / _TRIG_RULE_NODES


def _block_nodes(block: int, t0, t1, sign, C) -> tuple[np.ndarray | None, np.ndarray, np.ndarray]:
    """Nodes ``t`` and signed weights ``w`` ``(r, q)`` of the paths ``(t0, t1, sign)`` ``(k,)`` with
    coefficients ``C`` ``(k, 8)`` in a fixed-rule block, and the path of each of the ``r`` rows
    (None: row ``i`` is path ``i``; the Gauss blocks cut a path into pieces of ``ANGLE_STEP``)."""
    if block in (_B_TRIG_P, _B_TRIG_R):
        dth = t1 - t0
        if block == _B_TRIG_R:
            omega = np.abs(C[:, 3])
            dth = dth * omega
        # I = [Δθ, ∫ cos kφ, ∫ sin kφ (k = 1..4)] over [0, Δθ]; ∫ e^{ikφ} = (e^{ikΔθ} - 1) / (ik).
        I = np.empty((t0.size, _TRIG_RULE_NODES))
        I[:, 0] = dth
        I[:, 1:] = ((np.exp(1j * dth[:, None] * _K1234) - 1.0) * _INV_IK).view(np.float64)
        if block == _B_TRIG_P:
            return None, t0[:, None] + _PHI9, (I @ _E9_INV) * sign[:, None]
        return None, t0[:, None] + _PHI9 / omega[:, None], (I @ _E9_INV) * (sign / omega)[:, None]
    rows = None
    if block in (_B_POLY_P, _B_POLY_R):
        x, w = _XP, _WP
    else:
        x, w = _XI, _WI
        # Angular variation: t of arcs, u on surfaces of revolution, v on spheres and tori (all
        # of the latter are in _B_GAUSS_R only when not a meridian).
        amp_u = np.abs(C[:, 2]) + np.hypot(C[:, 4], C[:, 6])
        amp_v = np.abs(C[:, 3]) + np.hypot(C[:, 5], C[:, 7])
        trig = (C[:, 4:8] != 0.0).any(axis=1)
        ang = (t1 - t0) * np.maximum(trig, (amp_u if block == _B_GAUSS_R else 0.0) + amp_v * (block == _B_GAUSS_R))
        # The 1e-9 only absorbs round-off in piece counts: a span of exactly ANGLE_STEP is one piece.
        pieces = np.maximum(1, np.ceil(ang / ANGLE_STEP - 1e-9)).astype(np.int64)
        if pieces.max() > 1:
            starts = np.cumsum(pieces) - pieces
            j = np.arange(int(pieces.sum())) - np.repeat(starts, pieces)
            rows = np.repeat(np.arange(t0.size), pieces)
            dt = np.repeat((t1 - t0) / pieces, pieces)
            t0, sign = np.repeat(t0, pieces) + j * dt, np.repeat(sign, pieces)
            t1 = t0 + dt
    h = 0.5 * (t1 - t0)
    return rows, (t0 + h)[:, None] + h[:, None] * x, (h * sign)[:, None] * w


#: Coefficient columns (b_v, a_v) and signs: dv/dt of a trigonometric path is (cos t, sin t) @ (b_v, -a_v).
_B_MINUS_A = np.array([7, 5])
_SIGNS_B_MINUS_A = np.array([1.0, -1.0])
#: Meridian specialisation of _revolved_F per block: rulings of cylinders and cones, meridians
#: of spheres and tori, anything.
_MERIDIAN = {_B_POLY_R: 1, _B_TRIG_R: 2, _B_GAUSS_R: 0}


def _analytic_integrals(paths: _Paths, G: np.ndarray, Gc: np.ndarray, code: np.ndarray, ncols: int, rtol: float,
                        scale: np.ndarray, out: np.ndarray) -> bool:
    """Green's-theorem contributions of every face on a plane or a surface of revolution into
    ``out`` (in the faces' frames); False when there is none.

    Straight and trigonometric paths use fixed rules, one block ``(rows, nodes)`` each:
    ``_B_POLY_*`` (3 Gauss points) where the integrand is a polynomial of degree <= 4 in ``t``
    (straight paths on planes, rulings of cylinders and cones); ``_B_TRIG_*`` (exact for
    trigonometric degree <= 4 in ``ω t``) on arcs of planes (``ω = 1``) and meridians of spheres
    and tori (``ω = |dv/dt|``) spanning at least ``ANGLE_STEP`` (shorter ones would put nodes far
    from the path, where the integrand may be much larger); ``_B_GAUSS_*`` (12 points per
    ``ANGLE_STEP`` of angular variation) for the rest.  NURBS p-curves are adaptive (``_B_ADAPT``).
    """
    counts = np.bincount(paths.block, minlength=_B_NURBS + 1)
    if not counts[_B_POLY_P:_B_NURBS].any():
        return False
    nf = out.shape[0]
    pf, C = paths.face, paths.coef
    for blk in counts[_B_POLY_P:_B_ADAPT].nonzero()[0] + _B_POLY_P:
        p = (paths.block == blk).nonzero()[0]
        Cp = C.take(p, axis=0)
        rows, t, w = _block_nodes(blk, paths.t0.take(p), paths.t1.take(p), paths.sign.take(p), Cp)
        if rows is not None:
            p, Cp = p.take(rows), Cp.take(rows, axis=0)
        r, q = t.shape
        on_rev = blk >= _B_POLY_R
        if blk == _B_POLY_P or blk == _B_POLY_R or blk == _B_TRIG_R:
            # Straight paths; on surfaces of revolution u is constant along them.
            u = Cp[:, 0].repeat(q) if on_rev else (Cp[:, 0:1] + t * Cp[:, 2:3]).ravel()
            v = (Cp[:, 1:2] + t * Cp[:, 3:4]).ravel()
            g = w * Cp[:, 3:4]
        else:
            # uv = c0 + t l + (cos t, sin t) @ [a; b], duv/dt = l + (cos t, sin t) @ [b; -a].
            cs = np.exp(1j * t).view(np.float64).reshape(r, q, 2)
            uv = cs @ Cp[:, 4:8].reshape(r, 2, 2)
            dv = cs @ (Cp[:, _B_MINUS_A] * _SIGNS_B_MINUS_A)[:, :, None]
            if blk == _B_GAUSS_R:
                uv += t[:, :, None] * Cp[:, None, 2:4]
            u = (uv[..., 0] + Cp[:, 0:1]).ravel()
            v = (uv[..., 1] + Cp[:, 1:2]).ravel()
            g = w * (dv[..., 0] + Cp[:, 3:4])
        f = pf.take(p)
        fn = f.repeat(q)
        step = max(1, _CHUNK // q)
        for s0 in range(0, r, step):
            sr, sn = slice(s0, s0 + step), slice(s0 * q, (s0 + step) * q)
            R = G.take(fn[sn], axis=1)
            if on_rev:
                vals = _revolved_F(R, Gc.take(fn[sn], axis=1), u[sn], v[sn], ncols, _MERIDIAN[blk])
            else:
                vals = _plane_F(R, u[sn], v[sn], ncols)
            # Σ over each row's nodes of g F, then into the rows' faces.
            np.add.at(out, f[sr], (g[sr, None, :] @ vals.reshape(-1, q, ncols))[:, 0])
    if counts[_B_ADAPT]:
        curved = (paths.block == _B_ADAPT).nonzero()[0]
        item, lo, hi = _initial_pieces(paths, curved, [paths.breaks(int(p)) for p in curved])

        def integrand(it: np.ndarray, t: np.ndarray) -> np.ndarray:
            uv, duv = paths.evaluate(it, t)
            return _analytic_F(G, Gc, code, pf[it], uv[:, 0], uv[:, 1], ncols) * (duv[:, 1] * paths.sign[it])[:, None]

        out += _adaptive(item, lo, hi, pf[item], nf, integrand, ncols, rtol, scale, np.arange(nf))
    return True


# ---------------------------------------------------------------------------- NURBS faces
def _initial_pieces(paths: _Paths, pids: np.ndarray, breaks: list) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Gauss–Kronrod pieces of paths ``pids``: cut at ``breaks`` (per path), then ``_INITIAL_PIECES`` each."""
    item, lo, hi = [], [], []
    sub = np.linspace(0.0, 1.0, _INITIAL_PIECES + 1)
    for p, br in zip(pids, breaks):
        t0, t1 = float(paths.t0[p]), float(paths.t1[p])
        bp = np.unique(np.concatenate([[t0, t1], np.asarray(br, dtype=np.float64)]))
        bp = bp[(bp >= t0) & (bp <= t1)]
        a, c = bp[:-1], bp[1:]
        edges = a[:, None] + (c - a)[:, None] * sub
        lo.append(edges[:, :-1].ravel())
        hi.append(edges[:, 1:].ravel())
        item.append(np.full(lo[-1].size, p))
    return np.concatenate(item), np.concatenate(lo), np.concatenate(hi)


def _nurbs_integrals(b: BRep, paths: _Paths, nurbs: np.ndarray, uref: np.ndarray, x0: np.ndarray, ncols: int,
                     rtol: float, scale: np.ndarray, out: np.ndarray) -> None:
    """Contributions of the faces on NURBS surfaces (``nurbs`` ``(F,)``): adaptive outer and inner
    integrals, per group of surfaces of one structure.

    Surfaces sharing degrees, knots and net shape (:meth:`NurbsSurfaceStack.key`: the patches of a
    sewn spline model, say) are integrated as one batch, each point evaluated on its own face's
    surface: the convergence test stays per face (outer) and per inner integral, so the results
    are those of one batch per surface; only the number of numpy calls drops.
    """
    nf = out.shape[0]
    pf = paths.face
    fs = b.face_surface
    on_nurbs = paths.block == _B_NURBS
    groups: dict[tuple, list[int]] = {}
    for si in np.unique(fs[nurbs]):
        groups.setdefault(NurbsSurfaceStack.key(b.surfaces[int(si)]), []).append(int(si))
    slot = np.zeros(len(b.surfaces) + 1, dtype=np.int64)  # surface -> index in its stack (-1 reads the last)
    for members in groups.values():
        stack = NurbsSurfaceStack([b.surfaces[si] for si in members])
        slot[members] = np.arange(len(members))
        (u0, u1), (v0, v1) = stack.domain
        ku, kv = _interior_knots(stack.knots_u, u0, u1), _interior_knots(stack.knots_v, v0, v1)
        pids = (on_nurbs & np.isin(fs.take(pf), members)).nonzero()[0]
        if pids.size == 0:
            continue
        breaks = []
        for p in pids:
            br = list(paths.breaks(int(p)))
            t0, t1 = float(paths.t0[p]), float(paths.t1[p])
            if paths.shape[p] == _P_TRIG:
                n = max(1, math.ceil((t1 - t0) / ANGLE_STEP - 1e-9))  # as in _block_nodes
                br += list(np.linspace(t0, t1, n + 1)[1:-1])
            if ku.size or kv.size:
                n = 64 * (1 + len(br))
                br += _crossings(paths, int(p), ku, 0, n) + _crossings(paths, int(p), kv, 1, n)
            breaks.append(br)
        item, lo, hi = _initial_pieces(paths, pids, breaks)
        ur = np.clip(uref, u0, u1)
        face_slot = slot.take(fs)

        def integrand(it: np.ndarray, t: np.ndarray, stack=stack, ku=ku, dom=((u0, u1), (v0, v1))) -> np.ndarray:
            uv, duv = paths.evaluate(it, t)
            u = np.clip(uv[:, 0], *dom[0])
            v = np.clip(uv[:, 1], *dom[1])
            f = pf.take(it)
            F = _nurbs_F(stack, face_slot.take(f), ku, x0, ncols, rtol, scale, u, v, ur.take(f), f)
            return F * (duv[:, 1] * paths.sign.take(it))[:, None]

        out += _adaptive(item, lo, hi, pf[item], nf, integrand, ncols, rtol, scale, np.arange(nf))


def _nurbs_F(stack: NurbsSurfaceStack, which: np.ndarray, ku: np.ndarray, x0: np.ndarray, ncols: int, rtol: float,
             scale: np.ndarray, u: np.ndarray, v: np.ndarray, uref: np.ndarray, face: np.ndarray) -> np.ndarray:
    """``F(u, v) = ∫_{u_ref}^{u} f(s, v) ds`` on surface ``which`` of ``stack``, ``(n, ncols)``:
    adaptive G7/K15 over ``[u_ref, u]`` cut at the interior ``u`` knots ``ku``, each integral to ``rtol``."""
    n = u.size
    lo, hi = np.minimum(uref, u), np.maximum(uref, u)
    bounds = np.concatenate([[-np.inf], ku, [np.inf]])
    a = np.clip(bounds[:-1][None, :], lo[:, None], hi[:, None])
    c = np.clip(bounds[1:][None, :], lo[:, None], hi[:, None])
    node, span = np.nonzero(c > a)
    a, c = a[node, span], c[node, span]
    sub = np.linspace(0.0, 1.0, _INITIAL_PIECES + 1)
    edges = a[:, None] + (c - a)[:, None] * sub
    node = np.repeat(node, _INITIAL_PIECES)

    def integrand(it: np.ndarray, s: np.ndarray) -> np.ndarray:
        return _nurbs_integrand(functools.partial(stack.derivatives, which.take(it)), s, v.take(it), x0, ncols)

    F = _adaptive(node, edges[:, :-1].ravel(), edges[:, 1:].ravel(), node, n, integrand, ncols, rtol, scale, face)
    return F * np.where(u >= uref, 1.0, -1.0)[:, None]


def _nurbs_integrand(derivatives: Callable, u: np.ndarray, v: np.ndarray, x0: np.ndarray, ncols: int) -> np.ndarray:
    """``f(u, v)`` columns ``(n, ncols)`` of the module docstring from ``derivatives(u, v, 1)``
    (first partials ``(n, 2, 2, 3)``, as :meth:`NurbsSurface.derivatives`)."""
    D = derivatives(u, v, 1)
    P = D[:, 0, 0, :] - x0
    N = np.cross(D[:, 1, 0, :], D[:, 0, 1, :])
    w = np.einsum("ni,ni->n", P, N)
    out = np.empty((u.size, ncols))
    out[:, _AREA] = np.linalg.norm(N, axis=-1)
    out[:, _VOL] = w / 3.0
    if ncols > _N_VOL_COLS:
        out[:, _FIRST] = P * (w / 4.0)[:, None]
        out[:, _SECOND] = P[:, _I6] * P[:, _J6] * (w / 5.0)[:, None]
    return out


# ---------------------------------------------------------------------------- adaptive quadrature
def _gk15(item: np.ndarray, lo: np.ndarray, hi: np.ndarray, fn: Callable, ncols: int):
    """K15 integrals, ``|K15 - G7|`` error estimates and K15 integrals of ``|fn|`` over the
    pieces ``[lo, hi]``, each ``(m, ncols)``."""
    m = item.size
    half, mid = 0.5 * (hi - lo), 0.5 * (hi + lo)
    t = (mid[:, None] + half[:, None] * _XK).ravel()
    it = np.repeat(item, _XK.size)
    vals = np.empty((t.size, ncols))
    for s0 in range(0, t.size, _CHUNK):
        s = slice(s0, s0 + _CHUNK)
        vals[s] = fn(it[s], t[s])
    vals = vals.reshape(m, _XK.size, ncols)
    R = np.einsum("mkc,kj->mjc", vals, _WKG) * half[:, None, None]
    A = np.einsum("mkc,k->mc", np.abs(vals), _WK) * half[:, None]
    return R[:, 0], np.abs(R[:, 0] - R[:, 1]), A


def _adaptive(item, lo, hi, owner, n_owners: int, fn: Callable, ncols: int, rtol: float, scale: np.ndarray,
              owner_face: np.ndarray) -> np.ndarray:
    """``Σ ∫_lo^hi fn(item, t) dt`` per owner, ``(n_owners, ncols)``, by vectorised adaptive G7/K15.

    Every round evaluates all new pieces at once.  An owner is done when, for every column
    ``c``, ``Σ |K15 - G7| <= rtol (Σ ∫|f_c| + scale_c Σ ∫|f_area|)`` over its pieces (the module
    docstring); otherwise its pieces whose error exceeds their share of that target are halved.

    Raises
    ------
    ConvergenceError
        Non-finite integrands, or an owner not done after ``MAX_BISECTIONS`` rounds (the error
        names the faces, ``owner_face[owner]``).
    """
    total = np.zeros((n_owners, ncols))
    if item.size == 0:
        return total
    K, E, A = _gk15(item, lo, hi, fn, ncols)
    last = np.full(n_owners, np.inf)  # previous round's error / target, per owner
    stall = np.zeros(n_owners, dtype=np.int64)
    for depth in range(MAX_BISECTIONS + 1):
        if not np.all(np.isfinite(K)):
            bad = np.unique(owner_face[owner[~np.all(np.isfinite(K), axis=1)]])
            raise ConvergenceError(f"mass properties: non-finite integrand on face(s) {bad.tolist()}", indices=bad)
        E_o, A_o = _sum_by(owner, E, n_owners), _sum_by(owner, A, n_owners)
        target = rtol * (A_o + A_o[:, :1] * scale)
        with np.errstate(divide="ignore", invalid="ignore"):
            ratio_o = np.max(np.where(E_o > 0, E_o / target, 0.0), axis=1)
        # Round-off floor: where halving every piece no longer lowers the summed estimate (a
        # smooth integrand's drops 2^-15 per halving, a kink's 1/4, a jump's 1/2), the estimate
        # is the rounding noise of the integrand, not its truncation error.  The owner is done
        # once that has held for _STALL_ROUNDS rounds and the noise is below _ROUNDOFF_SLACK targets.
        stall = np.where(ratio_o > _STALL_FACTOR * last, stall + 1, 0)
        last = ratio_o
        done_o = np.all(E_o <= target, axis=1) | ((stall >= _STALL_ROUNDS) & (ratio_o <= _ROUNDOFF_SLACK))
        done = done_o[owner]
        if done.all():
            return total + _sum_by(owner, K, n_owners)
        if depth == MAX_BISECTIONS or (~done).sum() > _MAX_PIECES:
            failed = np.flatnonzero(~done_o)
            ratio = np.max(E_o[failed] / np.where(target[failed] > 0, target[failed], 1.0), axis=1) * rtol
            faces = np.unique(owner_face[failed])
            raise ConvergenceError(
                f"mass properties: the adaptive quadrature did not reach relative accuracy {rtol:.1e} on face(s) "
                f"{faces.tolist()[:10]} after {depth} bisections ({int((~done).sum())} pieces); estimated relative "
                f"error {ratio.max():.1e}",
                indices=faces, residuals=ratio,
            )
        if done.any():
            total += _sum_by(owner[done], K[done], n_owners)
            keep = ~done
            item, lo, hi, owner, K, E, A = item[keep], lo[keep], hi[keep], owner[keep], K[keep], E[keep], A[keep]
        n_o = np.bincount(owner, minlength=n_owners)
        split = np.any(E > (target / np.maximum(n_o, 1)[:, None])[owner], axis=1)
        s, k = np.flatnonzero(split), ~split
        mid = 0.5 * (lo[s] + hi[s])
        n_item, n_lo, n_hi, n_owner = (np.concatenate([item[s], item[s]]), np.concatenate([lo[s], mid]),
                                       np.concatenate([mid, hi[s]]), np.concatenate([owner[s], owner[s]]))
        K2, E2, A2 = _gk15(n_item, n_lo, n_hi, fn, ncols)
        item, lo, hi, owner = (np.concatenate([x[k], y]) for x, y in ((item, n_item), (lo, n_lo), (hi, n_hi),
                                                                       (owner, n_owner)))
        K, E, A = (np.concatenate([x[k], y]) for x, y in ((K, K2), (E, E2), (A, A2)))
    raise AssertionError("unreachable")  # pragma: no cover


# ---------------------------------------------------------------------------- helpers
def _interior_knots(knots: np.ndarray, lo: float, hi: float) -> np.ndarray:
    # Knot vectors are sorted: the distinct values without np.unique's sort (called per path).
    k = knots[(knots > lo) & (knots < hi)]
    return k[np.concatenate([[True], k[1:] != k[:-1]])] if k.size else k


def _crossings(paths: _Paths, p: int, values: np.ndarray, comp: int, n: int) -> list[float]:
    """Parameters ``t`` in ``(t0, t1)`` where ``uv(t)[comp]`` of path ``p`` crosses one of ``values``
    (knot lines).

    Sign changes between ``n`` samples are refined by vectorised bisection; a path lying along a
    knot line (exactly) has nothing to split.
    """
    if values.size == 0:
        return []
    t = np.linspace(paths.t0[p], paths.t1[p], n)

    def coord(t: np.ndarray) -> np.ndarray:
        return paths.evaluate(np.full(t.size, p), t)[0][:, comp]

    x = coord(t)
    g = x[None, :] - values[:, None]  # (K, n)
    along = np.all(g == 0.0, axis=1)
    values, g = values[~along], g[~along]
    out = [float(t[1 + j]) for _, j in np.argwhere(g[:, 1:-1] == 0.0)]
    ki, ji = np.nonzero(g[:, :-1] * g[:, 1:] < 0.0)
    if ki.size:
        lo, hi = t[ji].copy(), t[ji + 1].copy()
        glo, target = g[ki, ji], values[ki]
        for _ in range(_BISECTIONS):
            mid = 0.5 * (lo + hi)
            same = np.sign(coord(mid) - target) == np.sign(glo)
            lo = np.where(same, mid, lo)
            hi = np.where(same, hi, mid)
        out += [float(x) for x in 0.5 * (lo + hi)]
    return out


# ---------------------------------------------------------------------------- implicit planes
def _implicit_plane(b: BRep, f: int) -> PlanarSurface:
    """The plane of an implicit face with curved edges: Newell normal of its sampled boundary."""
    pts, nxt_pts = [], []
    s = np.linspace(0.0, 1.0, 17)[:-1]
    for loop in b.face_loop_ids(f):
        ring = []
        for c in b.loop_coedges(int(loop)):
            e, side = int(c) >> 1, int(c) & 1
            t0, t1 = b.edge_range[e]
            t = t0 + (t1 - t0) * (s if side == 0 else 1.0 - s)
            ring.append(_edge_points(b, e, t))
        if ring:
            R = np.concatenate(ring)
            pts.append(R)
            nxt_pts.append(np.roll(R, -1, axis=0))
    P, Q = np.concatenate(pts), np.concatenate(nxt_pts)
    n = np.cross(P - P[0], Q - P[0]).sum(axis=0)
    if not np.linalg.norm(n) > 0.0:
        raise TopologyError(f"implicit face {f} has zero area: its plane is undefined")
    return PlanarSurface(P[0], n, perpendicular_direction(n))


def _edge_points(b: BRep, e: int, t: np.ndarray) -> np.ndarray:
    """3-D points of edge ``e`` at curve parameters ``t`` (straight edges: affine over the range)."""
    return _edge_derivs(b, e, t)[0]


def _edge_derivs(b: BRep, e: int, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Points and first derivatives of edge ``e`` at ``t``, each ``(k, 3)``."""
    t = np.asarray(t, dtype=np.float64)
    ci = int(b.edge_curve[e])
    t0, t1 = b.edge_range[e]
    if ci < 0:
        a, q = b.vertex_point[b.edge_vertex[e]]
        d = (q - a) / (t1 - t0)
        return a + (t - t0)[:, None] * d, np.broadcast_to(d, (t.size, 3))
    D = b.curves[ci].derivatives(t, 1)
    return D[:, 0], D[:, 1]


# ============================================================================ bounding box
def bounding_box(brep) -> np.ndarray:
    """Axis-aligned bounding box of the exact geometry, ``(2, 3)``: min row, max row.

    Candidates are the vertices, the extrema of every edge curve inside its range and the
    interior extrema of every face surface inside its trimmed region (module docstring).

    Raises
    ------
    InvalidInputError
        Not a B-rep.
    TopologyError
        A B-rep without vertices (nothing to bound), or a non-planar face whose coedge has no
        p-curve.
    """
    b = _as_brep(brep)
    if b.n_vertices == 0:
        raise TopologyError("the B-rep has no vertices: its bounding box is undefined")
    cache = _cache(b)
    box = cache.get("box")
    if box is None:
        box = cache["box"] = _bounding_box(b)
        box.setflags(write=False)
    return box.copy()


def _bounding_box(b: BRep) -> np.ndarray:
    """:func:`bounding_box`, uncached.

    Cheap candidates first (vertices, circle extrema), then the searches, each skipped when a
    proven hull of its curve or surface (:func:`_hull`) already lies in the box found so far: its
    extreme points, all in the hull, could not widen it (up to the round-off of an evaluation).
    The intersection curves of a Boolean's result lie inside the box of its faces, and searching
    them by sampling and Newton steps was most of the cost of the tessellator's default deflection.

    :func:`~coons.topology.disjoint.padded_boxes` mirrors these candidates for B-reps of lines and
    circles on planes, cylinders and cones (vertices and circle extrema only): keep the two in step.
    """
    lo = b.vertex_point.min(axis=0)
    hi = b.vertex_point.max(axis=0)

    def grow(P: np.ndarray) -> None:
        nonlocal lo, hi
        P = P.reshape(-1, 3)
        if P.size:
            lo, hi = np.minimum(lo, P.min(axis=0)), np.maximum(hi, P.max(axis=0))

    def inside(obj) -> bool:
        hull = _hull(obj)
        return hull is not None and bool((hull[0] >= lo).all() and (hull[1] <= hi).all())

    # Edges grouped by curve (ascending rows within a curve); circles (every hole of a plate has
    # two) all in one array pass, the other curves one by one.
    curved = np.flatnonzero(b.edge_curve >= 0)
    order = curved[np.argsort(b.edge_curve[curved], kind="stable")]
    cut = np.flatnonzero(np.diff(b.edge_curve[order])) + 1
    circles, others = [], []
    for rows in np.split(order, cut) if order.size else []:
        curve = b.curves[int(b.edge_curve[rows[0]])]
        (circles if type(curve) is Circle else others).append(rows)
    if circles:
        rows = np.concatenate(circles)
        grow(_circle_extreme_points([b.curves[int(c)] for c in b.edge_curve[rows]], b.edge_range[rows]))
    # Planes, cylinders and cones have no isolated interior extrema; every other face is searched.
    flat = (PlanarSurface, CylindricalSurface, ConicalSurface)
    search = np.array([not isinstance(S, flat) and not inside(S) for S in b.surfaces] + [False])[b.face_surface]
    if search.any():
        # Code 3 (not planar): every searched coedge needs a p-curve; all faces get their gaps.
        paths = _gather_paths(b, search, np.full(b.n_faces, 3), None, None, search)[0]
        for f in np.flatnonzero(search):
            grow(_surface_extreme_points(paths, int(f), b.surfaces[int(b.face_surface[f])]))
    for rows in others:
        curve = b.curves[int(b.edge_curve[rows[0]])]
        if not inside(curve):
            grow(_curve_extreme_points(curve, b.edge_range[rows]))
    return np.stack([lo, hi])


def _hull(obj) -> tuple[np.ndarray, np.ndarray] | None:
    """A box ``(lo, hi)`` containing the whole curve or surface ``obj`` (NURBS: its control points, by the
    convex hull property with positive weights; spheres and tori: closed form), None for other types."""
    if isinstance(obj, (NurbsCurve, NurbsSurface)):
        if obj.dimension != 3:
            return None
        lo, hi = obj.bounding_box()  # (the control points' box)
        return lo, hi
    if isinstance(obj, SphericalSurface):
        r = float(obj.radius)
    elif isinstance(obj, ToroidalSurface):
        r = float(obj.major_radius + obj.minor_radius)
    else:
        return None
    c = np.asarray(obj.center, dtype=np.float64)
    return c - r, c + r


def face_box_bounds(brep, tol: Tolerance | None = None) -> np.ndarray:
    """Boxes ``(F, 2, 3)`` (rows ``lo, hi``) proven to contain each face, without searching for extrema.

    Cheaper and looser than :func:`bounding_box` face by face: the union of the face's edge
    boxes (:func:`coons.kernel.curve_intersect.curve_boxes`: exact for lines and arcs, the union of
    the pieces' control-point boxes for NURBS curves; the end points for edges without a curve),
    padded by the largest tolerance of the face's edges and their vertices and ``t.linear`` (the
    boundary of the face's parameter region maps within the edge tolerances of its edges; a gap
    at a pole maps to a vertex).  A coordinate on a plane, cylinder or cone has no interior extremum that is not
    also reached on the boundary (it is affine along each ruling); a sphere or torus adds the
    box of the whole surface, a NURBS surface its control points' box (convex hull property,
    positive weights).  Infinite for a face whose curve or surface type is not handled.

    Raises
    ------
    InvalidInputError
        Not a BRep or Solid.
    """
    from coons.kernel.curve_intersect import curve_box, curve_boxes

    b, t = _as_brep(brep), resolve(tol)
    F = b.n_faces
    E = b.n_edges
    elo, ehi = np.full((E, 3), np.inf), np.full((E, 3), -np.inf)
    ends = b.vertex_point[b.edge_vertex]  # (E, 2, 3)
    elo[:], ehi[:] = ends.min(axis=1), ends.max(axis=1)
    curved = [e for e, ci in enumerate(b.edge_curve.tolist()) if ci >= 0]
    if curved:
        curves = [b.curves[int(b.edge_curve[e])] for e in curved]
        R = b.edge_range[curved]
        try:
            boxes = curve_boxes(curves, R[:, 0], R[:, 1])
        except InvalidInputError:  # (one by one: a curve that cannot be boxed leaves its faces unknown)
            boxes = np.empty((len(curved), 2, 3))
            for k, (c, r) in enumerate(zip(curves, R.tolist())):
                try:
                    boxes[k] = curve_box(c, r)
                except InvalidInputError:
                    boxes[k] = [[-np.inf] * 3, [np.inf] * 3]
        elo[curved] = np.minimum(elo[curved], boxes[:, 0])
        ehi[curved] = np.maximum(ehi[curved], boxes[:, 1])
    lo, hi = np.full((F, 3), np.inf), np.full((F, 3), -np.inf)
    ef = b.edge_face  # (E, 2)
    for side in (0, 1):
        np.minimum.at(lo, ef[:, side], elo)
        np.maximum.at(hi, ef[:, side], ehi)
    # An edge's points lie within its tolerance of its curve, and its ends within their vertices'.
    etol = np.maximum(b.edge_tol, b.vertex_tol[b.edge_vertex].max(axis=1)) if E else np.zeros(0)
    pad = np.zeros(F)
    for side in (0, 1):
        np.maximum.at(pad, ef[:, side], etol)
    pad += t.linear
    unknown = (lo > hi).any(axis=1)  # a face without edges
    lo[unknown], hi[unknown] = -np.inf, np.inf
    flat = (PlanarSurface, CylindricalSurface, ConicalSurface)
    hulls: dict[int, tuple | None] = {}  # (per surface, not per face)
    for f, si in enumerate(b.face_surface.tolist()):
        S = None if si < 0 else b.surfaces[si]
        if S is None or isinstance(S, flat):
            continue
        if si not in hulls:
            hulls[si] = _hull(S)
        h = hulls[si]
        if h is None:  # a surface type without a proven whole box
            lo[f], hi[f] = -np.inf, np.inf
        else:
            lo[f], hi[f] = np.minimum(lo[f], h[0]), np.maximum(hi[f], h[1])
    return np.stack([lo - pad[:, None], hi + pad[:, None]], axis=1)


def _curve_extreme_points(curve, ranges: np.ndarray) -> np.ndarray:
    """Points of ``curve`` where a coordinate is extreme inside each of ``ranges`` ``(k, 2)``."""
    if isinstance(curve, Line):
        return np.empty((0, 3))
    if isinstance(curve, (Circle, Ellipse)):
        a, bb = (curve.radius, curve.radius) if isinstance(curve, Circle) else (curve.major_radius, curve.minor_radius)
        X, Y = curve.frame[0], curve.frame[1]
        # x_i(t) = C_i + a X_i cos t + b Y_i sin t is extreme at t* = atan2(b Y_i, a X_i) and t* + π.
        ts = np.arctan2(bb * Y, a * X)
        ts = np.concatenate([ts, ts + math.pi])[None, :]  # (1, 6)
        t0, t1 = ranges[:, :1], ranges[:, 1:]
        first = ts + _TWO_PI * np.ceil((t0 - ts) / _TWO_PI)
        cand = np.stack([first, first + _TWO_PI], axis=-1)  # (k, 6, 2)
        inside = (cand >= t0[:, :, None]) & (cand <= t1[:, :, None])
        return curve.evaluate(cand[inside])
    return _generic_curve_extremes(curve, ranges)


def _circle_extreme_points(curves: list, ranges: np.ndarray) -> np.ndarray:
    """:func:`_curve_extreme_points` of many circle arcs at once: ``curves[k]`` over ``ranges[k]`` ``(k, 2)``.

    Element by element the same expressions as :func:`_curve_extreme_points` and
    ``Circle.evaluate``, so the same points (in another order).
    """
    return circle_extremes(curves, ranges)[0]


def circle_extremes(curves: list, ranges: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """:func:`_circle_extreme_points` and the arc of each point: ``(points (m, 3), arcs (m,) int64)``,
    ``arcs`` ascending (for per-B-rep reductions over the arcs of many B-reps, ``disjoint.padded_boxes``)."""
    R = np.array([c.radius for c in curves], dtype=np.float64)[:, None]
    F = np.array([c.frame for c in curves])  # (k, 3, 3)
    O = np.array([c.center for c in curves])
    X, Y = F[:, 0], F[:, 1]
    ts = np.arctan2(R * Y, R * X)
    ts = np.concatenate([ts, ts + math.pi], axis=1)  # (k, 6)
    t0, t1 = ranges[:, :1], ranges[:, 1:]
    first = ts + _TWO_PI * np.ceil((t0 - ts) / _TWO_PI)
    cand = np.stack([first, first + _TWO_PI], axis=-1)  # (k, 6, 2)
    inside = (cand >= t0[:, :, None]) & (cand <= t1[:, :, None])
    k = np.nonzero(inside)[0]
    t = cand[inside]
    return ((R[k, 0] * np.cos(t))[:, None] * X[k] + (R[k, 0] * np.sin(t))[:, None] * Y[k]) + O[k], k


def _span_samples(lo: float, hi: float, knots, generic: int) -> np.ndarray:
    """Parameters in ``[lo, hi]``: ``_BOX_SAMPLES_PER_SPAN`` per knot span, or ``generic`` evenly."""
    if knots is None:
        return np.linspace(lo, hi, generic)
    k = np.unique(np.concatenate([[lo, hi], _interior_knots(np.asarray(knots), lo, hi)]))
    spans = [np.linspace(a, c, _BOX_SAMPLES_PER_SPAN + 1)[:-1] for a, c in zip(k[:-1], k[1:])]
    return np.concatenate(spans + [[hi]])


def _generic_curve_extremes(curve, ranges: np.ndarray) -> np.ndarray:
    """Sampling per knot span plus a Newton polish of ``x_i'(t) = 0`` from the best samples.

    Raises
    ------
    InvalidInputError
        A curve without ``evaluate`` and ``derivatives``.
    """
    if not (hasattr(curve, "evaluate") and hasattr(curve, "derivatives")):
        raise InvalidInputError(f"cannot bound a {type(curve).__name__} edge curve: it has no evaluate/derivatives")
    out = []
    knots = getattr(curve, "knots", None)
    for t0, t1 in ranges:
        t = _span_samples(t0, t1, knots, _BOX_SAMPLES_GENERIC)
        P = curve.evaluate(t)
        out.append(P)
        h = float(np.max(np.diff(t)))
        starts = []
        for i in range(3):
            order = np.argsort(P[:, i])
            starts += [t[order[:_NEWTON_STARTS]], t[order[-_NEWTON_STARTS:]]]
        T = np.concatenate(starts)
        axis = np.repeat(np.arange(3), 2 * _NEWTON_STARTS)
        lo_b, hi_b = np.maximum(T - h, t0), np.minimum(T + h, t1)
        for _ in range(_NEWTON_STEPS):
            D = curve.derivatives(T, 2)
            g1 = D[np.arange(T.size), 1, axis]
            g2 = D[np.arange(T.size), 2, axis]
            step = np.divide(g1, g2, out=np.zeros_like(g1), where=g2 != 0.0)
            T = np.clip(T - step, lo_b, hi_b)
        out.append(curve.evaluate(T))
    return np.concatenate(out) if out else np.empty((0, 3))


def _face_polygon(paths: _Paths, f: int) -> tuple[np.ndarray, np.ndarray]:
    """The parameter-space boundary of face ``f`` as segments ``(A, B)``, each ``(n, 2)``: every
    path sampled densely (the paths join end to end, gaps included, so the segments close)."""
    p = np.flatnonzero(paths.face == f)
    if p.size == 0:
        return np.empty((0, 2)), np.empty((0, 2))
    s = np.linspace(0.0, 1.0, _POLYGON_SAMPLES)
    t = paths.t0[p, None] + (paths.t1[p] - paths.t0[p])[:, None] * s
    uv = paths.evaluate(np.repeat(p, s.size), t.ravel())[0].reshape(p.size, s.size, 2)
    return uv[:, :-1].reshape(-1, 2), uv[:, 1:].reshape(-1, 2)


def _inside(seg: tuple[np.ndarray, np.ndarray], pts: np.ndarray) -> np.ndarray:
    """Even–odd test of ``pts`` ``(k, 2)`` against closed boundary segments ``seg = (A, B)``."""
    A, B = seg
    if A.shape[0] < 3 or pts.shape[0] == 0:
        return np.zeros(pts.shape[0], dtype=bool)
    x, y = pts[:, 0][:, None], pts[:, 1][:, None]
    straddle = (A[None, :, 1] > y) != (B[None, :, 1] > y)
    with np.errstate(divide="ignore", invalid="ignore"):
        xc = A[None, :, 0] + (y - A[None, :, 1]) * (B[None, :, 0] - A[None, :, 0]) / (B[None, :, 1] - A[None, :, 1])
    return (np.count_nonzero(straddle & (x < xc), axis=1) % 2) == 1


def _wrap_into(values: np.ndarray, lo: float, period: float) -> np.ndarray:
    return lo + np.mod(values - lo, period)


def _surface_extreme_points(paths: _Paths, f: int, S) -> np.ndarray:
    """Interior critical points of each coordinate on face ``f`` (inside its trimmed region)."""
    poly = _face_polygon(paths, f)
    if poly[0].shape[0] < 3:
        return np.empty((0, 3))
    u_lo, v_lo = poly[0].min(axis=0)
    if isinstance(S, (SphericalSurface, ToroidalSurface)):
        F = S.frame  # rows X, Y, Z; column i: the axis e_i in frame coordinates
        cx, cy, cz = F[0], F[1], F[2]
        phi = np.arctan2(cy, cx)
        h = np.hypot(cx, cy)
        if isinstance(S, SphericalSurface):
            # ±e_i: u = φ, v = atan2(z, h) and u = φ + π, v = -atan2(z, h).
            lat = np.arctan2(cz, h)
            u = np.concatenate([phi, phi + math.pi])
            v = np.concatenate([lat, -lat])
        else:
            # u ∈ {φ, φ + π} (w = ±h), then v = atan2(z_i, w) and v + π.
            u = np.concatenate([phi, phi, phi + math.pi, phi + math.pi])
            w = np.concatenate([h, h, -h, -h])
            v = np.arctan2(np.tile(cz, 4), w) + np.repeat([0.0, math.pi, 0.0, math.pi], 3)
            v = _wrap_into(v, v_lo, _TWO_PI)
        u = _wrap_into(u, u_lo, _TWO_PI)
        uv = np.stack([u, v], axis=1)
        uv = uv[_inside(poly, uv)]
        return S.evaluate(uv[:, 0], uv[:, 1]) if uv.size else np.empty((0, 3))
    return _generic_surface_extremes(S, poly)


def _generic_surface_extremes(S, poly: tuple[np.ndarray, np.ndarray]) -> np.ndarray:
    """Grid samples inside the region plus a Newton polish of ``∇ x_i = 0`` from the best ones.

    Raises
    ------
    InvalidInputError
        A surface without ``evaluate`` and ``derivatives``.
    """
    if not (hasattr(S, "evaluate") and hasattr(S, "derivatives")):
        raise InvalidInputError(f"cannot bound a {type(S).__name__} surface: it has no evaluate/derivatives")
    (u0, v0), (u1, v1) = poly[0].min(axis=0), poly[0].max(axis=0)

    us = _span_samples(u0, u1, getattr(S, "knots_u", None), _BOX_SAMPLES_GENERIC // 2)
    vs = _span_samples(v0, v1, getattr(S, "knots_v", None), _BOX_SAMPLES_GENERIC // 2)
    UU, VV = np.meshgrid(us, vs, indexing="ij")
    G = np.stack([UU.ravel(), VV.ravel()], axis=1)
    G = G[_inside(poly, G)]
    if G.shape[0] == 0:
        return np.empty((0, 3))
    P = S.evaluate(G[:, 0], G[:, 1])
    starts, axis = [], []
    for i in range(3):
        order = np.argsort(P[:, i])
        for sel in (order[:_NEWTON_STARTS], order[-_NEWTON_STARTS:]):
            starts.append(G[sel])
            axis.append(np.full(sel.size, i))
    X = np.concatenate(starts)
    ax = np.concatenate(axis)
    idx = np.arange(X.shape[0])
    for _ in range(_NEWTON_STEPS):
        D = S.derivatives(X[:, 0], X[:, 1], 2)
        gu, gv = D[idx, 1, 0, ax], D[idx, 0, 1, ax]
        huu, huv, hvv = D[idx, 2, 0, ax], D[idx, 1, 1, ax], D[idx, 0, 2, ax]
        det = huu * hvv - huv * huv
        ok = det != 0.0
        du = np.divide(hvv * gu - huv * gv, det, out=np.zeros_like(gu), where=ok)
        dv = np.divide(huu * gv - huv * gu, det, out=np.zeros_like(gv), where=ok)
        X = np.stack([np.clip(X[:, 0] - du, u0, u1), np.clip(X[:, 1] - dv, v0, v1)], axis=1)
    X = X[_inside(poly, X)]
    Q = S.evaluate(X[:, 0], X[:, 1]) if X.size else np.empty((0, 3))
    return np.concatenate([P, Q])
