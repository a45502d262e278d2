"""Differential geometry of curves and surfaces, vectorised over parameters.

Curves: curvature (signed in 2-D), torsion, Frenet frames and arc length.
Surfaces: unit normals (with limits at degenerate points of the parametrisation),
the first and second fundamental forms, and Gaussian, mean and principal
curvatures with principal directions (Cohen–Riesenfeld–Elber ch. 4 and 12;
do Carmo, *Differential Geometry of Curves and Surfaces*, §1.5 and §3.2–3.3).
It deliberately does not compute curvatures of curves on surfaces (normal and
geodesic curvature), curvature extrema, offsets or derivatives of curvature.

Every function works on the duck-typed interface shared by NURBS and analytic
geometry: a curve needs ``domain`` and ``derivatives(u, order)``
(``np.shape(u) + (order + 1, d)``), a surface ``domain_u``, ``domain_v`` and
``derivatives(u, v, order)`` (``shape + (order + 1, order + 1, d)``).  Parameters
are checked against the domain here, with the caller's tolerance, so the geometry
is only ever evaluated inside it.  ``bounding_box()`` (or else samples of the
domain) gives the *size* of the geometry, the length that makes the thresholds
below dimensionless.

Thresholds (all derived from the :class:`~coons.tolerance.Tolerance`):

* a curve's speed ``|C'|`` is zero where ``|C'| · L <= tol.solver · size`` (``L``
  the domain length): at that speed the curve would cross less than the solver's
  relative accuracy of its own size over its whole domain;
* a curve is straight at ``u`` where ``κ · size <= tol.angular``: its osculating
  circle is flatter than the angular tolerance over the curve's size;
* a surface point is degenerate where ``|Su × Sv| <= tol.angular · max(|Su|, |Sv|)²``:
  the partials are parallel, or one vanishes, to within the angular tolerance;
* a surface point is umbilic where ``(k1 - k2) / 2 <= tol.angular · max(|k1|, |k2|, 1 / size)``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from coons.errors import ConvergenceError, InvalidGeometryError, InvalidInputError
from coons.kernel.basis import check_parameters
from coons.tolerance import Tolerance, resolve

__all__ = [
    "curve_curvature",
    "curve_torsion",
    "curve_frenet_frame",
    "curve_length",
    "surface_normal",
    "FundamentalForms",
    "surface_fundamental_forms",
    "SurfaceCurvatures",
    "surface_curvatures",
]

#: Gauss–Legendre nodes per interval of :func:`curve_length` beyond the degree.
_GAUSS_EXTRA = 3
#: Interval halvings allowed in :func:`curve_length` (2**-40 of a knot span).
_MAX_LENGTH_LEVELS = 40
#: Largest fraction of the way to the domain's centre at which :func:`surface_normal` looks for a
#: normal near a degenerate point whose first-order limit vanishes too.
_MAX_OFFSET = 1e-2
#: Samples per direction of a geometry without ``bounding_box`` for its size.
_SIZE_SAMPLES = 17


# ---------------------------------------------------------------------- results
@dataclass(frozen=True, eq=False)
class FundamentalForms:
    """First and second fundamental forms at a batch of parameters, each ``shape`` float64.

    ``E = Su·Su``, ``F = Su·Sv``, ``G = Sv·Sv`` and ``L = Suu·n``, ``M = Suv·n``,
    ``N = Svv·n`` with ``n`` the unit normal of :func:`surface_normal`.  Read-only.
    """

    E: np.ndarray
    F: np.ndarray
    G: np.ndarray
    L: np.ndarray
    M: np.ndarray
    N: np.ndarray

    def __post_init__(self) -> None:
        _freeze(self, ("E", "F", "G", "L", "M", "N"))


@dataclass(frozen=True, eq=False)
class SurfaceCurvatures:
    """Curvatures at a batch of parameters.

    Attributes
    ----------
    gaussian, mean, k1, k2 : shape float64
        ``K = k1 k2``, ``H = (k1 + k2) / 2``, principal curvatures with ``k1 >= k2``.
        Signed with respect to :func:`surface_normal`: a normal curvature is positive
        where the surface bends towards the normal (a sphere with outward normals
        has ``k1 = k2 = -1/R``).
    d1, d2 : shape + (3,) float64
        Unit principal directions of ``k1`` and ``k2``, tangent to the surface, with
        ``d2 = n × d1``; at umbilics ``d1`` is ``Su / |Su|``.

    Read-only.
    """

    gaussian: np.ndarray
    mean: np.ndarray
    k1: np.ndarray
    k2: np.ndarray
    d1: np.ndarray
    d2: np.ndarray

    def __post_init__(self) -> None:
        _freeze(self, ("gaussian", "mean", "k1", "k2", "d1", "d2"))


def _freeze(obj: Any, names: tuple[str, ...]) -> None:
    for name in names:
        a = np.array(getattr(obj, name), dtype=np.float64)
        a.setflags(write=False)
        object.__setattr__(obj, name, a)


# ---------------------------------------------------------------------- curves
def curve_curvature(curve, u, tol: Tolerance | None = None) -> np.ndarray:
    """Curvature of a curve (Cohen–Riesenfeld–Elber §4.2; do Carmo §1.5).

    In 3-D ``κ = |C' × C''| / |C'|³``; in 2-D the signed curvature
    ``κ = (x' y'' - y' x'') / |C'|³``, positive where the curve turns left.

    Parameters
    ----------
    curve : NurbsCurve or any curve with ``domain`` and ``derivatives(u, order)``
    u : float or array_like, inside the domain

    Returns
    -------
    np.shape(u) float64

    Raises
    ------
    InvalidInputError
        Parameters outside the domain; a curve in neither 2 nor 3 dimensions.
    InvalidGeometryError
        Where the speed ``|C'|`` vanishes (see the module docstring): the curvature
        of the parametrisation is undefined there.
    """
    t = resolve(tol)
    u, D = _curve_derivatives(curve, u, 2, t)
    d1, d2 = D[..., 1, :], D[..., 2, :]
    speed = _checked_speed(curve, u, d1, t, "curve_curvature")
    if d1.shape[-1] == 2:
        return (d1[..., 0] * d2[..., 1] - d1[..., 1] * d2[..., 0]) / speed**3
    return np.linalg.norm(np.cross(d1, d2), axis=-1) / speed**3


def curve_torsion(curve, u, tol: Tolerance | None = None) -> np.ndarray:
    """Torsion ``τ = det[C', C'', C'''] / |C' × C''|²`` of a 3-D curve (do Carmo §1.5).

    Where the curve is straight (``κ · size <= tol.angular``, see the module
    docstring) the torsion is undefined; it is returned as 0 there, the convention
    that a straight piece is planar.  Use :func:`curve_frenet_frame` to have such
    parameters raise instead.

    Parameters
    ----------
    curve : 3-D NurbsCurve or any curve with ``domain`` and ``derivatives(u, order)``
    u : float or array_like, inside the domain

    Returns
    -------
    np.shape(u) float64

    Raises
    ------
    InvalidInputError
        Parameters outside the domain; a curve that is not 3-D.
    InvalidGeometryError
        Where the speed ``|C'|`` vanishes.
    """
    t = resolve(tol)
    u, D = _curve_derivatives(curve, u, 3, t)
    if D.shape[-1] != 3:
        raise InvalidInputError(f"curve_torsion needs a 3-D curve, got dimension {D.shape[-1]}")
    d1, d2, d3 = D[..., 1, :], D[..., 2, :], D[..., 3, :]
    speed = _checked_speed(curve, u, d1, t, "curve_torsion")
    c = np.cross(d1, d2)
    cc = np.einsum("...i,...i->...", c, c)
    straight = np.sqrt(cc) / speed**3 * _size(curve) <= t.angular
    with np.errstate(divide="ignore", invalid="ignore"):
        tau = np.einsum("...i,...i->...", c, d3) / cc
    return np.where(straight, 0.0, tau)


def curve_frenet_frame(curve, u, tol: Tolerance | None = None) -> np.ndarray:
    """Frenet frames ``(T, N, B)`` of a curve (do Carmo §1.5).

    ``T = C' / |C'|``, ``B = C' × C'' / |C' × C''|``, ``N = B × T`` (towards the
    centre of curvature).  A 2-D curve is taken in the plane ``z = 0``; its ``B``
    is then ``±z``.

    Parameters
    ----------
    curve : NurbsCurve (2-D or 3-D) or any curve with ``domain`` and ``derivatives(u, order)``
    u : float or array_like, inside the domain

    Returns
    -------
    np.shape(u) + (3, 3) float64
        Rows ``T``, ``N``, ``B``: a right-handed orthonormal frame.

    Raises
    ------
    InvalidInputError
        Parameters outside the domain; a curve in neither 2 nor 3 dimensions.
    InvalidGeometryError
        Where the speed vanishes, or where the curve is straight
        (``κ · size <= tol.angular``) and the normal is undefined; the message
        names the first such parameter.
    """
    t = resolve(tol)
    u, D = _curve_derivatives(curve, u, 2, t)
    d1, d2 = D[..., 1, :], D[..., 2, :]
    speed = _checked_speed(curve, u, d1, t, "curve_frenet_frame")
    if d1.shape[-1] == 2:
        pad = [(0, 0)] * (d1.ndim - 1) + [(0, 1)]
        d1, d2 = np.pad(d1, pad), np.pad(d2, pad)
    c = np.cross(d1, d2)
    nc = np.linalg.norm(c, axis=-1)
    kappa = nc / speed**3
    straight = kappa * _size(curve) <= t.angular
    if np.any(straight):
        first = np.flatnonzero(straight.ravel())
        raise InvalidGeometryError(
            f"curve_frenet_frame: the curve is straight at u = {float(u.ravel()[first[0]])!r} "
            f"({first.size} of {straight.size} parameters; curvature {float(kappa.ravel()[first[0]]):.3g} "
            f"times size {_size(curve):.3g} <= tol.angular = {t.angular:g}): the normal is undefined"
        )
    T = d1 / speed[..., None]
    B = c / nc[..., None]
    N = np.cross(B, T)
    return np.stack([T, N, B], axis=-2)


def curve_length(curve, start: float | None = None, end: float | None = None, tol: Tolerance | None = None) -> float:
    """Arc length of a curve between two parameters (adaptive Gauss–Legendre quadrature).

    The integral of ``|C'(u)|`` is taken per knot span (the integrand is smooth
    inside a span), with ``p + 3`` Gauss–Legendre nodes per interval; an interval
    whose estimate differs from the sum over its two halves by more than its share
    ``tol.linear · (b - a) / (end - start)`` of the linear tolerance (or by more
    than ``tol.solver`` relative) is halved, all intervals of a level at once
    (Cohen–Riesenfeld–Elber §4.1; Davis & Rabinowitz, *Methods of Numerical
    Integration*, §6.2).  The error of the result is below ``tol.linear``.

    Parameters
    ----------
    curve : NurbsCurve or any curve with ``domain`` and ``derivatives(u, order)``
    start, end : float, optional
        Parameters inside the domain, ``start <= end``; default the domain ends.

    Returns
    -------
    float

    Raises
    ------
    InvalidInputError
        ``start`` or ``end`` outside the domain or not finite, or ``start > end``.
    ConvergenceError
        The error estimate did not fall below the tolerance after
        :data:`_MAX_LENGTH_LEVELS` halvings.
    """
    t = resolve(tol)
    lo, hi = (float(x) for x in curve.domain)
    a = lo if start is None else float(check_parameters(start, (lo, hi), t, what="start"))
    b = hi if end is None else float(check_parameters(end, (lo, hi), t, what="end"))
    if not (math.isfinite(a) and math.isfinite(b)):
        raise InvalidInputError(f"curve_length: an unbounded curve needs finite start and end, got [{a!r}, {b!r}]")
    if a > b:
        raise InvalidInputError(f"curve_length: start must not exceed end, got start = {a!r} > end = {b!r}")
    if a == b:
        return 0.0
    knots = getattr(curve, "knots", None)
    inner = np.unique(np.asarray(knots, dtype=np.float64)) if knots is not None else np.empty(0)
    edges = np.concatenate([[a], inner[(inner > a) & (inner < b)], [b]])
    nodes, weights = np.polynomial.legendre.leggauss(int(getattr(curve, "degree", 3)) + _GAUSS_EXTRA)
    x0, x1 = edges[:-1], edges[1:]
    total = 0.0
    for _ in range(_MAX_LENGTH_LEVELS):
        mid = 0.5 * (x0 + x1)
        q = _gauss(curve, np.concatenate([x0, x0, mid]), np.concatenate([x1, mid, x1]), nodes, weights)
        whole, halves = q[: x0.size], q[x0.size : 2 * x0.size] + q[2 * x0.size :]
        # Each interval may use its share of tol.linear, or the solver's relative accuracy.
        allowed = np.maximum(t.linear * (x1 - x0) / (b - a), t.solver * np.abs(halves))
        ok = np.abs(whole - halves) <= allowed
        total += math.fsum(halves[ok])
        x0, x1 = np.concatenate([x0[~ok], mid[~ok]]), np.concatenate([mid[~ok], x1[~ok]])
        if x0.size == 0:
            return total
    raise ConvergenceError(
        f"curve_length: {x0.size} intervals still above the tolerance after {_MAX_LENGTH_LEVELS} halvings "
        f"(first at u = {float(x0[0])!r})",
        indices=None,
        residuals=None,
    )


def _gauss(curve, x0: np.ndarray, x1: np.ndarray, nodes: np.ndarray, weights: np.ndarray) -> np.ndarray:
    """Gauss–Legendre estimates of the integral of ``|C'|`` over each ``[x0, x1]``."""
    half = 0.5 * (x1 - x0)
    u = (0.5 * (x0 + x1))[:, None] + half[:, None] * nodes
    speed = np.linalg.norm(np.asarray(curve.derivatives(u, 1), dtype=np.float64)[..., 1, :], axis=-1)
    return half * (speed @ weights)


def _parameters(geom, values, domain, periodic: bool, t: Tolerance, what: str) -> np.ndarray:
    """Parameters as float64, checked against ``domain`` (only for finiteness on a periodic direction)."""
    if periodic:
        values = np.asarray(values, dtype=np.float64)
        if not np.all(np.isfinite(values)):
            raise InvalidInputError(f"{what}: parameters must be finite, got NaN or inf")
        return values
    return check_parameters(values, tuple(float(x) for x in domain), t, what=what)


def _curve_derivatives(curve, u, order: int, t: Tolerance) -> tuple[np.ndarray, np.ndarray]:
    u = _parameters(curve, u, curve.domain, bool(getattr(curve, "periodic", False)), t, "u")
    D = np.asarray(curve.derivatives(u, order), dtype=np.float64)
    if D.shape[-1] not in (2, 3):
        raise InvalidInputError(f"curve differential geometry needs a 2-D or 3-D curve, got dimension {D.shape[-1]}")
    return u, D


def _checked_speed(curve, u: np.ndarray, d1: np.ndarray, t: Tolerance, where: str) -> np.ndarray:
    """``|C'|``, raising where it vanishes (see the module docstring)."""
    speed = np.linalg.norm(d1, axis=-1)
    lo, hi = (float(x) for x in curve.domain)
    length = hi - lo if math.isfinite(hi - lo) else 1.0
    zero = speed * length <= t.solver * _size(curve)
    if np.any(zero):
        first = np.flatnonzero(zero.ravel())
        raise InvalidGeometryError(
            f"{where}: the first derivative vanishes at u = {float(u.ravel()[first[0]])!r} "
            f"({first.size} of {zero.size} parameters; |C'| = {float(speed.ravel()[first[0]]):.3g}): "
            "the parametrisation is singular there"
        )
    return speed


def _size(geom) -> float:
    """Diagonal of the geometry's bounding box, or of samples of its (finite part of the) domain."""
    box = getattr(geom, "bounding_box", None)
    if callable(box):
        bb = np.asarray(box(), dtype=np.float64)
        if bb.ndim == 2 and np.all(np.isfinite(bb)):
            return float(np.linalg.norm(bb[1] - bb[0]))
    if hasattr(geom, "domain_u"):
        us, vs = _window(geom.domain_u), _window(geom.domain_v)
        P = np.asarray(geom.derivatives(us[:, None], vs[None, :], 0), dtype=np.float64)[..., 0, 0, :]
    else:
        P = np.asarray(geom.derivatives(_window(geom.domain), 0), dtype=np.float64)[..., 0, :]
    P = P.reshape(-1, P.shape[-1])
    return float(np.linalg.norm(P.max(axis=0) - P.min(axis=0)))


def _window(domain) -> np.ndarray:
    """Sample parameters of a domain; an unbounded side is cut one unit from the other (or from 0)."""
    lo, hi = (float(x) for x in domain)
    if not math.isfinite(lo) and not math.isfinite(hi):
        lo, hi = -1.0, 1.0
    elif not math.isfinite(lo):
        lo = hi - 1.0
    elif not math.isfinite(hi):
        hi = lo + 1.0
    return np.linspace(lo, hi, _SIZE_SAMPLES)


# ---------------------------------------------------------------------- surfaces
def surface_normal(surface, u, v, tol: Tolerance | None = None) -> np.ndarray:
    """Unit normals ``Su × Sv / |Su × Sv|`` of a 3-D surface, with limits at degenerate points.

    Where the point is degenerate (``|Su × Sv| <= tol.angular · max(|Su|, |Sv|)²``,
    e.g. a sphere's pole or a collapsed edge) the normal is the limit of
    ``Su × Sv`` approached from inside the domain, along the direction
    ``δ = (δu, δv)`` towards the domain's centre: to first order
    ``Su × Sv (u + s δu, v + s δv) ≈ s [δu (Suu × Sv + Su × Suv) + δv (Suv × Sv + Su × Svv)]``
    (Cohen–Riesenfeld–Elber §12.1).  Should that vanish too (a higher-order
    degeneracy), the normal is that at the parameter a fraction ``h`` of the way
    towards the centre, ``h = sqrt(tol.solver)`` growing tenfold up to
    :data:`_MAX_OFFSET` until ``Su × Sv`` rises above the threshold: an
    approximation of the limit, good to ``O(h)`` on a smooth surface.  At a genuine singularity
    (a cone's apex) the result is the limit along ``δ``.  Never NaN.

    Parameters
    ----------
    surface : NurbsSurface or any surface with ``domain_u``, ``domain_v`` and ``derivatives(u, v, order)``
    u, v : float or array_like, broadcasting against each other

    Returns
    -------
    np.broadcast_shapes(np.shape(u), np.shape(v)) + (3,) float64

    Raises
    ------
    InvalidInputError
        Parameters outside the domain or not broadcastable; a surface that is not 3-D.
    InvalidGeometryError
        Where no normal exists even at the offset parameter (the surface collapses
        to a point or a curve there); the message names the first such parameter.
    """
    t = resolve(tol)
    u, v, D = _surface_derivatives(surface, u, v, 1, t)
    shape = u.shape
    n = _normals(surface, u.ravel(), v.ravel(), D.reshape(-1, 2, 2, 3), t)
    return n.reshape(shape + (3,))


def surface_fundamental_forms(surface, u, v, tol: Tolerance | None = None) -> FundamentalForms:
    """First and second fundamental forms ``E, F, G, L, M, N`` (do Carmo §2.5, §3.3).

    Parameters
    ----------
    surface : NurbsSurface or any surface with ``domain_u``, ``domain_v`` and ``derivatives(u, v, order)``
    u, v : float or array_like, broadcasting against each other

    Returns
    -------
    FundamentalForms
        Six arrays of shape ``np.broadcast_shapes(np.shape(u), np.shape(v))``; the
        second form uses the normal of :func:`surface_normal` (limits at degenerate points).

    Raises
    ------
    InvalidInputError, InvalidGeometryError
        As :func:`surface_normal`.
    """
    t = resolve(tol)
    u, v, D = _surface_derivatives(surface, u, v, 2, t)
    shape = u.shape
    Df = D.reshape(-1, 3, 3, 3)
    n = _normals(surface, u.ravel(), v.ravel(), Df, t)
    Su, Sv = Df[:, 1, 0], Df[:, 0, 1]
    forms = [
        _dot(Su, Su), _dot(Su, Sv), _dot(Sv, Sv),
        _dot(Df[:, 2, 0], n), _dot(Df[:, 1, 1], n), _dot(Df[:, 0, 2], n),
    ]
    return FundamentalForms(*(f.reshape(shape) for f in forms))


def surface_curvatures(surface, u, v, tol: Tolerance | None = None) -> SurfaceCurvatures:
    """Gaussian, mean and principal curvatures and principal directions (do Carmo §3.2–3.3).

    The principal curvatures solve the generalised 2×2 eigenproblem
    ``II x = k I x``.  It is reduced in closed form to a symmetric one by the
    Cholesky factor of ``I`` — the orthonormal tangent frame ``e1 = Su / |Su|``,
    ``e2 = n × e1``, in which ``Su = a e1`` and ``Sv = α e1 + β e2`` — giving the
    shape operator ``W = [[w11, w12], [w12, w22]]``; then ``k = H ± sqrt(((w11 -
    w22) / 2)² + w12²)``, free of cancellation, and the direction of ``k1`` is at
    the angle ``θ = atan2(2 w12, w11 - w22) / 2`` from ``e1``
    (Cohen–Riesenfeld–Elber §12.2).  At umbilics (see the module docstring)
    ``θ = 0``: ``d1`` is aligned with ``Su``.

    Parameters
    ----------
    surface : NurbsSurface or any surface with ``domain_u``, ``domain_v`` and ``derivatives(u, v, order)``
    u, v : float or array_like, broadcasting against each other

    Returns
    -------
    SurfaceCurvatures
        ``gaussian, mean, k1, k2`` of shape ``np.broadcast_shapes(np.shape(u),
        np.shape(v))``, ``d1, d2`` of that shape + ``(3,)``.

    Raises
    ------
    InvalidInputError
        Parameters outside the domain or not broadcastable; a surface that is not 3-D.
    InvalidGeometryError
        At degenerate points (a pole, a collapsed edge, parallel partials), where
        the first fundamental form is singular and the curvatures of this
        parametrisation are undefined; the message names the first such parameter.
    """
    t = resolve(tol)
    u, v, D = _surface_derivatives(surface, u, v, 2, t)
    shape = u.shape
    Df = D.reshape(-1, 3, 3, 3)
    Su, Sv = Df[:, 1, 0], Df[:, 0, 1]
    c = np.cross(Su, Sv)
    nc = np.linalg.norm(c, axis=-1)
    degenerate = _degenerate(Su, Sv, nc, t)
    if np.any(degenerate):
        first = np.flatnonzero(degenerate)
        raise InvalidGeometryError(
            f"surface_curvatures: degenerate parametrisation at (u, v) = ({float(u.ravel()[first[0]])!r}, "
            f"{float(v.ravel()[first[0]])!r}) ({first.size} of {degenerate.size} parameters; |Su x Sv| = "
            f"{float(nc[first[0]]):.3g}): the first fundamental form is singular there"
        )
    n = c / nc[:, None]
    L, M, N = _dot(Df[:, 2, 0], n), _dot(Df[:, 1, 1], n), _dot(Df[:, 0, 2], n)
    a = np.linalg.norm(Su, axis=-1)
    e1 = Su / a[:, None]
    e2 = np.cross(n, e1)
    alpha = _dot(Sv, e1)
    beta = nc / a  # = Sv · e2 > 0
    w11 = L / (a * a)
    w12 = (M * a - L * alpha) / (a * a * beta)
    w22 = (L * alpha * alpha - 2.0 * M * alpha * a + N * a * a) / (a * a * beta * beta)
    H = 0.5 * (w11 + w22)
    half_gap = np.hypot(0.5 * (w11 - w22), w12)
    k1, k2 = H + half_gap, H - half_gap
    K = w11 * w22 - w12 * w12
    flat = 1.0 / max(_size(surface), t.linear)  # curvatures below this are flat over the surface's size
    umbilic = half_gap <= t.angular * np.maximum(np.maximum(np.abs(k1), np.abs(k2)), flat)
    theta = np.where(umbilic, 0.0, 0.5 * np.arctan2(2.0 * w12, w11 - w22))
    cos, sin = np.cos(theta)[:, None], np.sin(theta)[:, None]
    d1 = cos * e1 + sin * e2
    d2 = cos * e2 - sin * e1
    return SurfaceCurvatures(
        K.reshape(shape), H.reshape(shape), k1.reshape(shape), k2.reshape(shape),
        d1.reshape(shape + (3,)), d2.reshape(shape + (3,)),
    )


def _dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.einsum("...i,...i->...", a, b)


def _surface_derivatives(surface, u, v, order: int, t: Tolerance) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    u = _parameters(surface, u, surface.domain_u, bool(getattr(surface, "periodic_u", False)), t, "u")
    v = _parameters(surface, v, surface.domain_v, bool(getattr(surface, "periodic_v", False)), t, "v")
    try:
        u, v = np.broadcast_arrays(u, v)
    except ValueError as exc:
        raise InvalidInputError(f"u and v do not broadcast: shapes {np.shape(u)} and {np.shape(v)}") from exc
    D = np.asarray(surface.derivatives(u, v, order), dtype=np.float64)
    if D.shape[-1] != 3:
        raise InvalidInputError(f"surface differential geometry needs a 3-D surface, got dimension {D.shape[-1]}")
    return u, v, D


def _degenerate(Su: np.ndarray, Sv: np.ndarray, nc: np.ndarray, t: Tolerance) -> np.ndarray:
    """Partials parallel, or one vanishing, to within the angular tolerance."""
    ref = np.maximum(_dot(Su, Su), _dot(Sv, Sv))
    return nc <= t.angular * ref


def _normals(surface, u: np.ndarray, v: np.ndarray, D: np.ndarray, t: Tolerance) -> np.ndarray:
    """Unit normals ``(m, 3)`` from flat parameters ``(m,)`` and derivatives ``(m, >=2, >=2, 3)``."""
    Su, Sv = D[:, 1, 0], D[:, 0, 1]
    c = np.cross(Su, Sv)
    nc = np.linalg.norm(c, axis=-1)
    bad = _degenerate(Su, Sv, nc, t)
    n = np.divide(c, nc[:, None], out=np.zeros_like(c), where=~bad[:, None])
    if not np.any(bad):
        return n
    idx = np.flatnonzero(bad)
    uu, vv = u[idx], v[idx]
    (ulo, uhi), (vlo, vhi) = ((float(a), float(b)) for a, b in (surface.domain_u, surface.domain_v))
    du, dv = _towards_centre(uu, vv, (ulo, uhi), (vlo, vhi))
    D2 = np.asarray(surface.derivatives(uu, vv, 2), dtype=np.float64)
    Su, Sv, Suu, Suv, Svv = D2[:, 1, 0], D2[:, 0, 1], D2[:, 2, 0], D2[:, 1, 1], D2[:, 0, 2]
    lim = du[:, None] * (np.cross(Suu, Sv) + np.cross(Su, Suv)) + dv[:, None] * (np.cross(Suv, Sv) + np.cross(Su, Svv))
    nl = np.linalg.norm(lim, axis=-1)
    norm = np.linalg.norm
    ref = np.abs(du) * (norm(Suu, axis=-1) * norm(Sv, axis=-1) + norm(Su, axis=-1) * norm(Suv, axis=-1)) + np.abs(
        dv
    ) * (norm(Suv, axis=-1) * norm(Sv, axis=-1) + norm(Su, axis=-1) * norm(Svv, axis=-1))
    # The first-order limit is trusted where it is not itself round-off of its terms.
    ok = nl > t.angular * ref
    n[idx[ok]] = lim[ok] / nl[ok, None]
    rest, d_u, d_v = idx[~ok], du[~ok], dv[~ok]
    h = math.sqrt(t.solver)
    while rest.size:
        # The normal a fraction h of the way to the centre, h growing tenfold until Su × Sv rises
        # above the threshold (a degeneracy of order k needs h ~ tol.angular ** (1 / k)).
        Do = np.asarray(surface.derivatives(u[rest] + h * d_u, v[rest] + h * d_v, 1), dtype=np.float64)
        Su, Sv = Do[:, 1, 0], Do[:, 0, 1]
        c = np.cross(Su, Sv)
        nc = np.linalg.norm(c, axis=-1)
        still = _degenerate(Su, Sv, nc, t)
        n[rest[~still]] = c[~still] / nc[~still, None]
        rest, d_u, d_v = rest[still], d_u[still], d_v[still]
        if rest.size and h >= _MAX_OFFSET:
            raise InvalidGeometryError(
                f"surface_normal: no normal at (u, v) = ({float(u[rest[0]])!r}, {float(v[rest[0]])!r}) "
                f"({rest.size} of {u.size} parameters): the surface collapses to a point or a curve there"
            )
        h *= 10.0
    return n


def _towards_centre(u: np.ndarray, v: np.ndarray, dom_u, dom_v) -> tuple[np.ndarray, np.ndarray]:
    """Parameter direction from ``(u, v)`` towards the domain's centre (of its unit window where unbounded).

    At the centre itself the direction is towards the upper corner of the window.
    """
    wu, wv = _window(dom_u), _window(dom_v)
    du = 0.5 * (wu[0] + wu[-1]) - u
    dv = 0.5 * (wv[0] + wv[-1]) - v
    at_centre = (du == 0) & (dv == 0)
    du = np.where(at_centre, 0.5 * (wu[-1] - wu[0]), du)
    dv = np.where(at_centre, 0.5 * (wv[-1] - wv[0]), dv)
    return du, dv
