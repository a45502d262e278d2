"""Exact NURBS forms of lines, conics, surfaces of revolution and the quadrics built on them.

This module constructs exact rational B-splines: straight lines (degree 1), circular and
elliptic arcs of any sweep up to a full turn (rational quadratic segments of at most 90°
joined at double knots, The NURBS Book A7.1), single conic arcs from end points, end
tangents and a through point (A7.3) or from three control points and a weight, surfaces of
revolution (A8.1) and on them planar patches, cylinders, cones, spheres and tori.  It also
gives the exact map between the angle of a circular direction and its NURBS parameter.  It
deliberately does not approximate (no fitting, no offsets), does not trim, and does not keep
the analytic description: the analytic types with their closed forms live in
:mod:`coons.kernel.analytic`, whose ``to_nurbs`` methods call these functions.

Conventions
-----------
*Arcs.*  An arc from ``start_angle`` to ``end_angle`` (sweep ``0 < end - start <= 2π``) is
``C + r_x cos θ X + r_y sin θ Y``.  It is split into ``n = ceil(sweep / (π/2))`` equal
segments (:func:`arc_segment_count`); segment ``j`` is a rational quadratic Bézier with
weights ``(1, cos(δ/2), 1)``, ``δ = sweep / n``, joined to the next by a double knot.  By
default the NURBS domain is ``[start_angle, end_angle]`` with the knots at the segment
angles, so the NURBS parameter equals the angle at the knots; between knots it is not the
angle but follows the tangent half-angle relation of the standard weighting:

    ψ = 2 atan((2s - 1) tan(δ/4)),

where ``s ∈ [0, 1]`` is the local parameter of the segment and ``ψ ∈ [-δ/2, δ/2]`` the
angle from the segment's middle.  :func:`angle_to_nurbs_parameter` and
:func:`nurbs_parameter_to_angle` apply it (vectorised) in both directions.  The same map
holds for ellipse arcs, whose angle is the eccentric anomaly ``t`` of
``C + a cos t X + b sin t Y``.

*Surfaces of revolution.*  :func:`nurbs_revolution` puts the circular direction in ``u``
(around the axis, counter-clockwise seen from the tip of the axis direction, angle 0 where
the profile is) and the profile in ``v`` (its own parameter and knots).  Then
``Su × Sv`` points away from the axis where the profile runs in the axis direction, so the
quadrics below, whose profiles run in ``+axis`` on the side of ``x_dir``, have outward
normals, and they are parametrised like OCCT's ``Geom_CylindricalSurface``,
``Geom_ConicalSurface``, ``Geom_SphericalSurface`` and ``Geom_ToroidalSurface`` up to the
angle map above (exact at the knots; linear directions are exact everywhere).

2-D or 3-D points are accepted wherever the construction makes sense in the plane.
"""

from __future__ import annotations

import math
import numbers

import numpy as np

from coons.errors import InvalidGeometryError, InvalidInputError
from coons.kernel import basis as _b
from coons.kernel.curve import NurbsCurve
from coons.kernel.surface import NurbsSurface
from coons.tolerance import Tolerance, resolve

__all__ = [
    "perpendicular_direction",
    "orthonormal_frame",
    "arc_segment_count",
    "angle_to_nurbs_parameter",
    "nurbs_parameter_to_angle",
    "nurbs_line",
    "nurbs_arc",
    "nurbs_circle",
    "nurbs_ellipse_arc",
    "nurbs_ellipse",
    "nurbs_conic",
    "nurbs_conic_arc",
    "nurbs_revolution",
    "nurbs_plane_patch",
    "nurbs_cylinder",
    "nurbs_cone",
    "nurbs_sphere",
    "nurbs_torus",
]

TWO_PI = 2.0 * math.pi
#: Largest sweep of one rational quadratic segment: weights stay >= cos(45°) ≈ 0.707.
_MAX_SEGMENT_SWEEP = 0.5 * math.pi


# ---------------------------------------------------------------------------- validation helpers
def _vector(value, what: str, dims: tuple[int, ...] = (2, 3)) -> np.ndarray:
    """A finite float64 vector with a number of coordinates in ``dims``."""
    a = np.array(value, dtype=np.float64)
    if a.ndim != 1 or a.shape[0] not in dims:
        allowed = " or ".join(str(d) for d in dims)
        raise InvalidInputError(f"{what}: expected a vector of {allowed} coordinates, got shape {a.shape}")
    # Python floats: a few coordinates are tested faster than by a numpy reduction (hot in
    # constructors: STEP import and the Booleans build thousands of frames).
    if not all(map(math.isfinite, a.tolist())):
        raise InvalidInputError(f"{what}: coordinates must be finite, got {a.tolist()}")
    return a


def _unit(value, what: str, dims: tuple[int, ...] = (2, 3)) -> np.ndarray:
    """``value`` normalised to unit length.

    A direction carries no length scale, so any non-zero finite vector defines one; only the
    zero vector is rejected.  Dividing by the largest component first keeps huge or tiny
    vectors from overflowing or underflowing in the norm.
    """
    return np.array(_unit_tuple(value, what, dims))


def _unit_tuple(value, what: str, dims: tuple[int, ...] = (2, 3)) -> tuple[float, ...]:
    """:func:`_unit` as a tuple of Python floats (the arithmetic of a few coordinates in Python is cheaper)."""
    vals = _vector(value, what, dims).tolist()
    big = max(map(abs, vals))
    if big == 0.0:
        raise InvalidGeometryError(f"{what}: expected a non-zero direction, got {vals}")
    vals = [x / big for x in vals]
    n = math.hypot(*vals)
    return tuple(x / n for x in vals)


def _scalar(value, what: str) -> float:
    """A finite real number (not a bool or a string) as a Python float."""
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise InvalidInputError(f"{what}: expected a real number, got {value!r}")
    x = float(value)
    if not math.isfinite(x):
        raise InvalidInputError(f"{what}: expected a finite number, got {x!r}")
    return x


def _positive(value, what: str) -> float:
    x = _scalar(value, what)
    if not x > 0.0:
        raise InvalidGeometryError(f"{what}: expected a positive number, got {x!r}")
    return x


def _interval(value, what: str) -> tuple[float, float]:
    """A parameter range ``(lo, hi)`` with finite ``lo < hi``."""
    try:
        lo, hi = value
    except (TypeError, ValueError) as exc:
        raise InvalidInputError(f"{what}: expected a pair (start, end), got {value!r}") from exc
    lo, hi = _scalar(lo, what), _scalar(hi, what)
    if not hi > lo:
        raise InvalidInputError(f"{what}: expected start < end, got ({lo!r}, {hi!r})")
    return lo, hi


def _sweep(start_angle, end_angle, tol: Tolerance, what: str) -> tuple[float, float, float, bool]:
    """``(start, end, sweep, full_turn)`` for an angular range with ``0 < sweep <= 2π``.

    A sweep past 2π by round-off of the caller's arithmetic (``tol.solver`` relative, the same
    slack as parameter domain checks) counts as a full turn; anything further raises.
    """
    start = _scalar(start_angle, f"{what} start_angle")
    end = _scalar(end_angle, f"{what} end_angle")
    sweep = end - start
    slack = tol.solver * TWO_PI
    if not (sweep > 0.0 and sweep <= TWO_PI + slack):
        raise InvalidGeometryError(
            f"{what}: the sweep end_angle - start_angle must be in (0, 2π], got {sweep!r} "
            f"(start {start!r}, end {end!r})"
        )
    return start, end, sweep, sweep >= TWO_PI - slack


def perpendicular_direction(axis) -> np.ndarray:
    """A unit vector perpendicular to ``axis``, chosen as OCCT's ``gp_Ax2(P, V)`` chooses its X direction.

    The coordinate of ``axis`` with the smallest magnitude is set to zero and the other two
    are swapped with one sign change, which is exactly perpendicular and never degenerate.

    Parameters
    ----------
    axis : (3,) array_like, non-zero

    Returns
    -------
    (3,) float64, unit

    Raises
    ------
    InvalidInputError
        Wrong shape or non-finite coordinates.
    InvalidGeometryError
        The zero vector.
    """
    return np.array(_perpendicular_tuple(_unit_tuple(axis, "axis", (3,))))


def _perpendicular_tuple(axis: tuple[float, float, float]) -> tuple[float, float, float]:
    a, b, c = axis
    A, B, C = abs(a), abs(b), abs(c)
    if B <= A and B <= C:
        d = (-c, 0.0, a) if A > C else (c, 0.0, -a)
    elif A <= B and A <= C:
        d = (0.0, -c, b) if B > C else (0.0, c, -b)
    else:
        d = (-b, a, 0.0) if A > B else (b, -a, 0.0)
    n = math.hypot(*d)
    return (d[0] / n, d[1] / n, d[2] / n)


def orthonormal_frame(axis, x_dir=None, tol: Tolerance | None = None) -> np.ndarray:
    """The right-handed orthonormal frame ``(X, Y, Z)`` of an axis and a reference direction.

    ``Z`` is ``axis`` normalised; ``X`` is the component of ``x_dir`` perpendicular to ``Z``,
    normalised (OCCT's ``gp_Ax2(P, N, Vx)``: ``X = (N × Vx) × N``); ``Y = Z × X``.  Without
    ``x_dir``, ``X`` is :func:`perpendicular_direction` of the axis.

    Parameters
    ----------
    axis : (3,) array_like, non-zero
    x_dir : (3,) array_like, non-zero and not parallel to ``axis``, optional
    tol : Tolerance, optional
        ``x_dir`` within ``tol.angular`` (sine of the angle) of the axis is parallel.

    Returns
    -------
    (3, 3) float64
        Rows ``X``, ``Y``, ``Z``.

    Raises
    ------
    InvalidInputError
        Wrong shapes or non-finite coordinates.
    InvalidGeometryError
        A zero vector, or ``x_dir`` parallel to the axis.
    """
    t = resolve(tol)
    Z = _unit_tuple(axis, "axis", (3,))
    if x_dir is None:
        X = _perpendicular_tuple(Z)
    else:
        x = _unit_tuple(x_dir, "x_dir", (3,))
        d = x[0] * Z[0] + x[1] * Z[1] + x[2] * Z[2]
        xp = (x[0] - d * Z[0], x[1] - d * Z[1], x[2] - d * Z[2])
        sine = math.hypot(*xp)
        if sine <= t.angular:
            raise InvalidGeometryError(
                f"x_dir {list(x)} is parallel to the axis {list(Z)}: sine of their angle {sine:.3g} "
                f"<= angular tolerance {t.angular:g}"
            )
        X = (xp[0] / sine, xp[1] / sine, xp[2] / sine)
    Y = (Z[1] * X[2] - Z[2] * X[1], Z[2] * X[0] - Z[0] * X[2], Z[0] * X[1] - Z[1] * X[0])
    return np.array((X, Y, Z))


def _plane_axes(x_axis, y_axis, dim: int, tol: Tolerance, what: str) -> tuple[np.ndarray, np.ndarray]:
    """Unit, orthogonal ``X, Y`` of dimension ``dim``; ``Y`` is re-orthogonalised exactly against ``X``."""
    X = _unit(x_axis, f"{what} x_axis", (dim,))
    Y = _unit(y_axis, f"{what} y_axis", (dim,))
    cosine = float(X @ Y)
    if abs(cosine) > tol.angular:
        raise InvalidGeometryError(
            f"{what}: x_axis and y_axis must be orthogonal, cosine of their angle is {cosine:.3g} "
            f"(angular tolerance {tol.angular:g})"
        )
    Y = Y - cosine * X
    return X, Y / np.linalg.norm(Y)


# ---------------------------------------------------------------------------- arc parametrisation
def _segment_count(sweep: float) -> int:
    """The one place that decides how many segments an arc has (every function here must agree)."""
    return max(1, math.ceil(sweep / _MAX_SEGMENT_SWEEP))


def arc_segment_count(sweep: float) -> int:
    """Number of rational quadratic segments of an arc of ``sweep`` radians: ``ceil(sweep / (π/2))``, at least 1.

    OCCT's ``GeomConvert`` (``Convert_TgtThetaOver2``) uses the same knots-at-angles
    convention and weights but ``floor(1.2 sweep / π) + 1`` spans (up to 150° each); both
    rules agree, and so do the resulting NURBS, for sweeps up to 90° and from 150° to 180°.

    Raises
    ------
    InvalidGeometryError
        ``sweep`` not in ``(0, 2π]`` (beyond round-off).
    """
    _, _, s, _ = _sweep(0.0, sweep, resolve(None), "arc_segment_count")
    return _segment_count(s)


def _arc_pattern(start: float, sweep: float, full: bool) -> tuple[np.ndarray, np.ndarray, np.ndarray, int]:
    """Unit-circle control pattern of an arc (The NURBS Book A7.1, vectorised over control points).

    Returns ``(c, s, w, n)``: control point ``k`` is ``c[k] X + s[k] Y`` (relative to the
    centre, unit radius), weight ``w[k]``, for ``2n + 1`` control points of ``n`` segments.
    Odd control points are the tangent intersections, at distance ``1 / cos(δ/2)``.
    """
    n = _segment_count(sweep)
    half = sweep / (2 * n)
    k = np.arange(2 * n + 1)
    theta = start + k * half
    odd = (k % 2) == 1
    w = np.where(odd, math.cos(half), 1.0)
    f = np.where(odd, 1.0 / math.cos(half), 1.0)
    c, s = f * np.cos(theta), f * np.sin(theta)
    if full:
        # Close the curve exactly: cos/sin of start + 2π differ from those of start by round-off.
        c[-1], s[-1] = c[0], s[0]
    return c, s, w, n


def _arc_knots(domain: tuple[float, float], n: int) -> np.ndarray:
    """Clamped quadratic knots over ``domain`` with ``n - 1`` equally spaced double interior knots."""
    a, b = domain
    inner = a + (b - a) * np.arange(1, n) / n
    return np.concatenate([[a, a, a], np.repeat(inner, 2), [b, b, b]])


def angle_to_nurbs_parameter(
    angle, start_angle: float, end_angle: float, domain: tuple[float, float] | None = None, tol: Tolerance | None = None
) -> np.ndarray:
    """NURBS parameter of the point at ``angle`` on the arc built by :func:`nurbs_arc` (or any arc of this module).

    On segment ``j`` (angles ``[start + jδ, start + (j+1)δ]``) the local parameter is
    ``s = (1 + tan(ψ/2) / tan(δ/4)) / 2`` with ``ψ`` the angle from the segment's middle,
    the inverse of the tangent half-angle relation of the weighting ``(1, cos(δ/2), 1)``
    (The NURBS Book §7.3; Cohen–Riesenfeld–Elber ch. 3).

    Parameters
    ----------
    angle : float or array_like
        Angles in ``[start_angle, end_angle]`` (round-off outside is clamped).  For a full
        turn any angle is accepted and first reduced modulo 2π into
        ``[start_angle, start_angle + 2π)``, so the seam maps to the start of the domain.
    start_angle, end_angle : float
        The arc's angular range, ``0 < end - start <= 2π``.
    domain : (float, float), optional
        The arc's NURBS domain (default ``(start_angle, end_angle)``, as :func:`nurbs_arc`).

    Returns
    -------
    np.shape(angle) float64

    Raises
    ------
    InvalidInputError
        Non-finite angles, angles outside a partial arc, an invalid domain.
    InvalidGeometryError
        An invalid sweep.
    """
    t = resolve(tol)
    start, end, sweep, full = _sweep(start_angle, end_angle, t, "angle_to_nurbs_parameter")
    a, b = _interval(domain if domain is not None else (start, end), "domain")
    phi = np.asarray(angle, dtype=np.float64)
    if not np.all(np.isfinite(phi)):
        raise InvalidInputError("angle_to_nurbs_parameter: angles must be finite, got NaN or inf")
    rel = phi - start
    if full:
        rel = np.mod(rel, TWO_PI)
    elif rel.size:
        slack = t.solver * max(1.0, sweep)
        lo, hi = float(rel.min()), float(rel.max())
        if lo < -slack or hi > sweep + slack:
            bad = phi.flat[int(np.argmin(rel))] if lo < -slack else phi.flat[int(np.argmax(rel))]
            raise InvalidInputError(
                f"angle_to_nurbs_parameter: angle {float(bad)!r} is outside the arc [{start!r}, {end!r}]"
            )
        rel = np.clip(rel, 0.0, sweep)
    n = _segment_count(sweep)
    delta = sweep / n
    j = np.clip(np.floor(rel / delta), 0, n - 1)
    psi = rel - (j + 0.5) * delta
    s = 0.5 * (1.0 + np.tan(0.5 * psi) / math.tan(0.25 * delta))
    return a + (b - a) * (j + s) / n


def nurbs_parameter_to_angle(
    u, start_angle: float, end_angle: float, domain: tuple[float, float] | None = None, tol: Tolerance | None = None
) -> np.ndarray:
    """Angle of the point at NURBS parameter ``u`` of an arc of this module: ``ψ = 2 atan((2s - 1) tan(δ/4))``.

    The inverse of :func:`angle_to_nurbs_parameter` (see there and the module docstring).

    Parameters
    ----------
    u : float or array_like, inside ``domain`` (round-off outside is clamped)
    start_angle, end_angle : float
    domain : (float, float), optional (default ``(start_angle, end_angle)``)

    Returns
    -------
    np.shape(u) float64, in ``[start_angle, end_angle]``

    Raises
    ------
    InvalidInputError
        Parameters outside the domain or not finite, an invalid domain.
    InvalidGeometryError
        An invalid sweep.
    """
    t = resolve(tol)
    start, end, sweep, _ = _sweep(start_angle, end_angle, t, "nurbs_parameter_to_angle")
    a, b = _interval(domain if domain is not None else (start, end), "domain")
    u = _b.check_parameters(u, (a, b), t)
    n = _segment_count(sweep)
    delta = sweep / n
    x = (u - a) / (b - a) * n
    j = np.clip(np.floor(x), 0, n - 1)
    s = x - j
    psi = 2.0 * np.arctan((2.0 * s - 1.0) * math.tan(0.25 * delta))
    return start + (j + 0.5) * delta + psi


# ---------------------------------------------------------------------------- curves
def nurbs_line(p0, p1, domain: tuple[float, float] = (0.0, 1.0), tol: Tolerance | None = None) -> NurbsCurve:
    """The straight segment from ``p0`` to ``p1`` as a degree-1 NURBS, linear in its parameter.

    Parameters
    ----------
    p0, p1 : (d,) array_like, d = 2 or 3
    domain : (float, float)
        ``p0`` is at ``domain[0]``, ``p1`` at ``domain[1]``.

    Returns
    -------
    NurbsCurve
        Degree 1, two control points, knots ``[a, a, b, b]``.

    Raises
    ------
    InvalidInputError
        Wrong shapes, different dimensions, non-finite values, an invalid domain.
    InvalidGeometryError
        End points closer than ``tol.linear``.
    """
    t = resolve(tol)
    P0 = _vector(p0, "nurbs_line p0")
    P1 = _vector(p1, "nurbs_line p1", (P0.shape[0],))
    a, b = _interval(domain, "nurbs_line domain")
    length = float(np.linalg.norm(P1 - P0))
    if length <= t.linear:
        raise InvalidGeometryError(
            f"nurbs_line: end points must be more than {t.linear:g} apart, got distance {length:.3g}"
        )
    return NurbsCurve(np.stack([P0, P1]), [a, a, b, b], 1)


def _elliptic_arc(
    center: np.ndarray, X: np.ndarray, Y: np.ndarray, rx: float, ry: float,
    start: float, end: float, sweep: float, full: bool, domain,
) -> NurbsCurve:
    c, s, w, n = _arc_pattern(start, sweep, full)
    P = center + (rx * c)[:, None] * X + (ry * s)[:, None] * Y
    dom = _interval(domain if domain is not None else (start, end), "domain")
    return NurbsCurve(P, _arc_knots(dom, n), 2, w)


def nurbs_ellipse_arc(
    center, x_axis, y_axis, radius_x: float, radius_y: float, start_angle: float, end_angle: float,
    *, domain: tuple[float, float] | None = None, tol: Tolerance | None = None,
) -> NurbsCurve:
    """Exact elliptic arc ``C + r_x cos t X + r_y sin t Y`` for ``t`` from ``start_angle`` to ``end_angle``.

    The affine image of :func:`nurbs_arc` (The NURBS Book A7.1 and §7.5): the same knots,
    weights and angle map (:func:`angle_to_nurbs_parameter`, with ``t`` the eccentric anomaly).

    Parameters
    ----------
    center : (d,) array_like, d = 2 or 3
    x_axis, y_axis : (d,) array_like
        Orthogonal directions (normalised here); ``y_axis`` decides the sense of rotation.
    radius_x, radius_y : float > 0
        Semi-axes along ``x_axis`` and ``y_axis`` (either may be the larger).
    start_angle, end_angle : float
        ``0 < end_angle - start_angle <= 2π``.
    domain : (float, float), optional
        NURBS domain, default ``(start_angle, end_angle)``.

    Returns
    -------
    NurbsCurve
        Degree 2, ``2n + 1`` control points for ``n`` segments of at most 90°.

    Raises
    ------
    InvalidInputError
        Wrong shapes, mismatched dimensions, non-finite values, an invalid domain.
    InvalidGeometryError
        Non-positive radii, zero or non-orthogonal axes, a sweep outside ``(0, 2π]``.
    """
    t = resolve(tol)
    C = _vector(center, "nurbs_ellipse_arc center")
    X, Y = _plane_axes(x_axis, y_axis, C.shape[0], t, "nurbs_ellipse_arc")
    rx = _positive(radius_x, "nurbs_ellipse_arc radius_x")
    ry = _positive(radius_y, "nurbs_ellipse_arc radius_y")
    return _elliptic_arc(C, X, Y, rx, ry, *_sweep(start_angle, end_angle, t, "nurbs_ellipse_arc"), domain)


def nurbs_arc(
    center, x_axis, y_axis, radius: float, start_angle: float, end_angle: float,
    *, domain: tuple[float, float] | None = None, tol: Tolerance | None = None,
) -> NurbsCurve:
    """Exact circular arc ``C + R (cos θ X + sin θ Y)``, ``start_angle <= θ <= end_angle`` (The NURBS Book A7.1).

    Any sweep ``0 < end - start <= 2π``: ``n = ceil(sweep / 90°)`` rational quadratic
    segments, weights ``(1, cos(δ/2), 1)``, joined at double knots; a full turn closes
    exactly (last control point equal to the first).  The NURBS parameter is the angle at
    the knots and follows :func:`angle_to_nurbs_parameter` in between.

    Parameters
    ----------
    center : (d,) array_like, d = 2 or 3
    x_axis, y_axis : (d,) array_like
        Orthogonal directions (normalised here); the arc turns from ``x_axis`` towards ``y_axis``.
    radius : float > 0
    start_angle, end_angle : float
    domain : (float, float), optional
        NURBS domain, default ``(start_angle, end_angle)``.
    tol : Tolerance, optional
        ``x_axis``/``y_axis`` must be orthogonal within ``tol.angular``; the sweep may exceed
        2π by ``tol.solver`` relative.

    Returns
    -------
    NurbsCurve

    Raises
    ------
    InvalidInputError
        Wrong shapes, mismatched dimensions, non-finite values, an invalid domain.
    InvalidGeometryError
        Non-positive radius, zero or non-orthogonal axes, a sweep outside ``(0, 2π]``.

    Examples
    --------
    >>> c = nurbs_arc([0, 0], [1, 0], [0, 1], 2.0, 0.0, np.pi)
    >>> bool(np.allclose(np.linalg.norm(c.evaluate(np.linspace(0, np.pi, 7)), axis=-1), 2.0, rtol=1e-15))
    True
    """
    t = resolve(tol)
    C = _vector(center, "nurbs_arc center")
    X, Y = _plane_axes(x_axis, y_axis, C.shape[0], t, "nurbs_arc")
    R = _positive(radius, "nurbs_arc radius")
    return _elliptic_arc(C, X, Y, R, R, *_sweep(start_angle, end_angle, t, "nurbs_arc"), domain)


def _circle_axes(center, normal, x_axis, tol: Tolerance, what: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    C = _vector(center, f"{what} center")
    if C.shape[0] == 2:
        if normal is not None:
            raise InvalidInputError(f"{what}: a 2-D {what.split('_')[-1]} takes no normal, got {normal!r}")
        X = _unit(x_axis if x_axis is not None else (1.0, 0.0), f"{what} x_axis", (2,))
        return C, X, np.array([-X[1], X[0]])
    if normal is None:
        raise InvalidInputError(f"{what}: a 3-D {what.split('_')[-1]} needs its normal (the axis)")
    X, Y, _ = orthonormal_frame(normal, x_axis, tol)
    return C, X, Y


def nurbs_circle(
    center, normal, radius: float, *, x_axis=None, domain: tuple[float, float] = (0.0, TWO_PI),
    tol: Tolerance | None = None,
) -> NurbsCurve:
    """Exact full circle ``C + R (cos θ X + sin θ Y)``, ``θ ∈ [0, 2π]``: four 90° rational quadratic segments.

    Parameters
    ----------
    center : (d,) array_like, d = 2 or 3
    normal : (3,) array_like or None
        The axis ``Z`` of a 3-D circle (counter-clockwise seen from its tip); must be ``None``
        for a 2-D circle, which turns counter-clockwise.
    radius : float > 0
    x_axis : array_like, optional
        Where ``θ = 0`` is: projected into the circle's plane (3-D), default
        :func:`perpendicular_direction` of the normal (3-D) or ``(1, 0)`` (2-D).
    domain : (float, float)
        NURBS domain, default ``(0, 2π)``.

    Returns
    -------
    NurbsCurve
        9 control points, closed exactly.

    Raises
    ------
    InvalidInputError
        A normal given in 2-D or missing in 3-D, wrong shapes, non-finite values.
    InvalidGeometryError
        Non-positive radius, zero normal, ``x_axis`` parallel to the normal.
    """
    t = resolve(tol)
    C, X, Y = _circle_axes(center, normal, x_axis, t, "nurbs_circle")
    R = _positive(radius, "nurbs_circle radius")
    return _elliptic_arc(C, X, Y, R, R, 0.0, TWO_PI, TWO_PI, True, domain)


def nurbs_ellipse(
    center, normal, radius_x: float, radius_y: float, *, x_axis=None,
    domain: tuple[float, float] = (0.0, TWO_PI), tol: Tolerance | None = None,
) -> NurbsCurve:
    """Exact full ellipse ``C + r_x cos t X + r_y sin t Y``, ``t ∈ [0, 2π]`` (axes as :func:`nurbs_circle`).

    Raises
    ------
    InvalidInputError, InvalidGeometryError
        As :func:`nurbs_circle`, for each radius.
    """
    t = resolve(tol)
    C, X, Y = _circle_axes(center, normal, x_axis, t, "nurbs_ellipse")
    rx = _positive(radius_x, "nurbs_ellipse radius_x")
    ry = _positive(radius_y, "nurbs_ellipse radius_y")
    return _elliptic_arc(C, X, Y, rx, ry, 0.0, TWO_PI, TWO_PI, True, domain)


def nurbs_conic(p0, p1, p2, weight: float) -> NurbsCurve:
    """The rational quadratic Bézier arc with control points ``p0, p1, p2`` and weights ``(1, weight, 1)``.

    It is an arc of an ellipse for ``weight < 1``, a parabola for ``weight == 1`` and a
    hyperbola for ``weight > 1`` (The NURBS Book §7.2; Cohen–Riesenfeld–Elber ch. 3), tangent to
    ``p1 - p0`` at ``p0`` and to ``p2 - p1`` at ``p2``.

    Parameters
    ----------
    p0, p1, p2 : (d,) array_like, d = 2 or 3
    weight : float > 0

    Returns
    -------
    NurbsCurve
        Domain ``[0, 1]``.

    Raises
    ------
    InvalidInputError
        Wrong shapes, mismatched dimensions, non-finite values.
    InvalidGeometryError
        A non-positive weight.
    """
    P0 = _vector(p0, "nurbs_conic p0")
    P1 = _vector(p1, "nurbs_conic p1", (P0.shape[0],))
    P2 = _vector(p2, "nurbs_conic p2", (P0.shape[0],))
    w = _positive(weight, "nurbs_conic weight")
    return NurbsCurve(np.stack([P0, P1, P2]), [0.0, 0.0, 0.0, 1.0, 1.0, 1.0], 2, [1.0, w, 1.0])


def _intersect_lines(A, U, B, V, tol: Tolerance, what: str) -> tuple[float, float, np.ndarray]:
    """``(s, r, point)`` with ``A + s U ≈ B + r V`` (least squares; the two lines must meet within ``tol.linear``)."""
    M = np.stack([U, -V], axis=1)
    (s, r), *_ = np.linalg.lstsq(M, B - A, rcond=None)
    Pa, Pb = A + s * U, B + r * V
    gap = float(np.linalg.norm(Pa - Pb))
    if gap > tol.linear:
        raise InvalidGeometryError(
            f"{what}: the lines do not meet, they pass {gap:.3g} apart (linear tolerance {tol.linear:g})"
        )
    return float(s), float(r), 0.5 * (Pa + Pb)


def nurbs_conic_arc(p0, t0, p2, t2, p, tol: Tolerance | None = None) -> NurbsCurve:
    """A rational quadratic conic arc from ``p0`` to ``p2`` with end tangents ``t0``, ``t2``, through ``p``.

    The middle control point ``P1`` is where the tangent lines meet; the line from ``P1``
    through ``p`` meets the chord at ``Q = (1 - α) p0 + α p2``, which fixes the parameter of
    ``p`` to ``u = a / (1 + a)``, ``a = sqrt(α / (1 - α))``, and the ratio
    ``r = |p - Q| / |P1 - Q|`` fixes the weight ``w = r ((1-u)² + u²) / (2u(1-u)(1 - r))``.
    The weight decides the type: ellipse (``w < 1``), parabola (``w = 1``), hyperbola (``w > 1``).
    The NURBS Book A7.3 (MakeOneArc), which also allows parallel tangents through an infinite
    middle control point (``w = 0``); here weights stay positive and that case raises.

    Parameters
    ----------
    p0, p2 : (d,) array_like, d = 2 or 3
        End points.
    t0, t2 : (d,) array_like
        Tangent directions at ``p0`` and ``p2`` in the direction of travel (normalised here).
    p : (d,) array_like
        A point of the arc, strictly inside the triangle ``p0, P1, p2``.
    tol : Tolerance, optional
        Lines must meet within ``tol.linear``; tangents within ``tol.angular`` are parallel.

    Returns
    -------
    NurbsCurve
        Degree 2, control points ``[p0, P1, p2]``, weights ``[1, w, 1]``, domain ``[0, 1]``.

    Raises
    ------
    InvalidInputError
        Wrong shapes, mismatched dimensions, non-finite values.
    InvalidGeometryError
        Parallel end tangents (the middle control point would be at infinity: split the arc),
        tangent lines that do not meet, tangents pointing away from their intersection, or
        ``p`` not strictly inside the triangle (off its plane, beyond ``P1`` or the chord).
    """
    t = resolve(tol)
    P0 = _vector(p0, "nurbs_conic_arc p0")
    d = (P0.shape[0],)
    P2 = _vector(p2, "nurbs_conic_arc p2", d)
    P = _vector(p, "nurbs_conic_arc p", d)
    T0 = _unit(t0, "nurbs_conic_arc t0", d)
    T2 = _unit(t2, "nurbs_conic_arc t2", d)
    sine = abs(T0[0] * T2[1] - T0[1] * T2[0]) if d[0] == 2 else float(np.linalg.norm(np.cross(T0, T2)))
    if sine <= t.angular:
        raise InvalidGeometryError(
            f"nurbs_conic_arc: end tangents {T0.tolist()} and {T2.tolist()} are parallel (sine {sine:.3g}); "
            "the middle control point would be at infinity, split the arc in two"
        )
    s, r, P1 = _intersect_lines(P0, T0, P2, T2, t, "nurbs_conic_arc tangent lines")
    if not (s > 0.0 and r < 0.0):
        raise InvalidGeometryError(
            "nurbs_conic_arc: t0 must point from p0 towards the tangent intersection and t2 from it towards p2, "
            f"got offsets {s:.6g} along t0 (expected > 0) and {r:.6g} along t2 (expected < 0)"
        )
    chord = P2 - P0
    ray = P - P1
    if float(np.linalg.norm(ray)) <= t.linear:
        raise InvalidGeometryError("nurbs_conic_arc: p coincides with the tangent intersection (infinite weight)")
    ray_sine = float(np.linalg.norm(ray - (ray @ chord) / (chord @ chord) * chord)) / float(np.linalg.norm(ray))
    if ray_sine <= t.angular:
        raise InvalidGeometryError(
            "nurbs_conic_arc: p must lie inside the triangle p0, P1, p2, the line P1 p is parallel to the chord"
        )
    lam, alpha, Q = _intersect_lines(P1, ray, P0, chord, t, "nurbs_conic_arc p and the chord")
    if not (0.0 < alpha < 1.0 and lam > 1.0):
        raise InvalidGeometryError(
            "nurbs_conic_arc: p must lie strictly inside the triangle p0, P1, p2; "
            f"its ray from P1 meets the chord at fraction {alpha:.6g} (expected in (0, 1)) "
            f"with p at ratio {1.0 / lam:.6g} of the way from P1 (expected in (0, 1))"
        )
    ratio = 1.0 - 1.0 / lam  # |p - Q| / |P1 - Q|
    a = math.sqrt(alpha / (1.0 - alpha))
    u = a / (1.0 + a)
    w = ratio * ((1.0 - u) ** 2 + u**2) / (2.0 * u * (1.0 - u) * (1.0 - ratio))
    return NurbsCurve(np.stack([P0, P1, P2]), [0.0, 0.0, 0.0, 1.0, 1.0, 1.0], 2, [1.0, w, 1.0])


# ---------------------------------------------------------------------------- surfaces
def nurbs_revolution(
    profile: NurbsCurve, axis_origin, axis_direction, start_angle: float = 0.0, end_angle: float = TWO_PI,
    *, domain_u: tuple[float, float] | None = None, tol: Tolerance | None = None,
) -> NurbsSurface:
    """The exact surface swept by ``profile`` turning about an axis (The NURBS Book A8.1, vectorised).

    ``u`` runs around the axis (the arc direction, counter-clockwise seen from the tip of
    ``axis_direction``; angle 0 is the profile itself), ``v`` along the profile with its own
    knots and degree.  Each control point ``P_j`` (weight ``w_j``) sweeps the arc
    ``O_j + cos θ D_j + sin θ (Z × D_j)``, ``D_j`` its offset from the axis point ``O_j``
    below it; the net is the tensor product with the arc pattern of :func:`nurbs_arc`
    (weights ``w_arc_k w_j``).  Works for any 3-D profile, including points on the axis.
    Normals ``Su × Sv`` point away from the axis where the profile runs along ``+Z``.

    Parameters
    ----------
    profile : NurbsCurve, 3-D
    axis_origin : (3,) array_like
    axis_direction : (3,) array_like, non-zero
    start_angle, end_angle : float
        ``0 < end - start <= 2π``.
    domain_u : (float, float), optional
        NURBS domain in ``u``, default ``(start_angle, end_angle)``; the angle map is
        :func:`angle_to_nurbs_parameter`.

    Returns
    -------
    NurbsSurface
        Degrees ``(2, profile.degree)``, control net ``(2n + 1, m, 3)``.

    Raises
    ------
    InvalidInputError
        ``profile`` not a NurbsCurve, wrong shapes, non-finite values.
    InvalidGeometryError
        A profile that is not 3-D, a zero axis, a sweep outside ``(0, 2π]``.
    """
    t = resolve(tol)
    if not isinstance(profile, NurbsCurve):
        raise InvalidInputError(f"nurbs_revolution: profile must be a NurbsCurve, got {type(profile).__name__}")
    if profile.dimension != 3:
        raise InvalidGeometryError(f"nurbs_revolution: profile must be 3-D, got dimension {profile.dimension}")
    O = _vector(axis_origin, "nurbs_revolution axis_origin", (3,))
    Z = _unit(axis_direction, "nurbs_revolution axis_direction", (3,))
    start, end, sweep, full = _sweep(start_angle, end_angle, t, "nurbs_revolution")
    c, s, w_arc, n = _arc_pattern(start, sweep, full)
    D = profile.control_points - O
    along = D @ Z
    Oj = O + along[:, None] * Z
    Rj = D - along[:, None] * Z  # radial offsets, zero for control points on the axis
    Tj = np.cross(Z, Rj)
    Q = Oj[None] + c[:, None, None] * Rj[None] + s[:, None, None] * Tj[None]
    W = w_arc[:, None] * profile.weights[None, :]
    dom = _interval(domain_u if domain_u is not None else (start, end), "domain_u")
    return NurbsSurface(Q, _arc_knots(dom, n), profile.knots, 2, profile.degree, W)


def nurbs_plane_patch(
    origin, normal, u_range: tuple[float, float] = (0.0, 1.0), v_range: tuple[float, float] = (0.0, 1.0),
    *, x_dir=None, tol: Tolerance | None = None,
) -> NurbsSurface:
    """Bilinear patch ``O + u X + v Y`` over ``u_range × v_range`` (``X, Y, normal`` right-handed).

    The parametrisation of :class:`~coons.kernel.analytic.PlanarSurface` (OCCT ``Geom_Plane``),
    exact in both parameters.  ``x_dir`` (projected into the plane) defaults to
    :func:`perpendicular_direction` of the normal, as for every builder below.

    Raises
    ------
    InvalidInputError
        Wrong shapes, non-finite values, invalid ranges.
    InvalidGeometryError
        A zero normal, ``x_dir`` parallel to the normal.
    """
    t = resolve(tol)
    O = _vector(origin, "nurbs_plane_patch origin", (3,))
    X, Y, _ = orthonormal_frame(normal, x_dir, t)
    u0, u1 = _interval(u_range, "nurbs_plane_patch u_range")
    v0, v1 = _interval(v_range, "nurbs_plane_patch v_range")
    uu = np.array([u0, u1])[:, None, None]
    vv = np.array([v0, v1])[None, :, None]
    P = O + uu * X + vv * Y
    return NurbsSurface(P, [u0, u0, u1, u1], [v0, v0, v1, v1], 1, 1)


def nurbs_cylinder(
    origin, axis, radius: float, v_range: tuple[float, float],
    *, x_dir=None, u_range: tuple[float, float] = (0.0, TWO_PI), tol: Tolerance | None = None,
) -> NurbsSurface:
    """Exact cylinder ``O + R (cos u X + sin u Y) + v Z`` (OCCT ``Geom_CylindricalSurface``), normals outward.

    ``u`` is the NURBS arc parameter (:func:`angle_to_nurbs_parameter` of the angle over
    ``u_range``), ``v`` is exact.  ``x_dir=None`` takes :func:`perpendicular_direction`.

    Raises
    ------
    InvalidInputError
        Wrong shapes, non-finite values, invalid ranges.
    InvalidGeometryError
        Non-positive radius, zero axis, ``x_dir`` parallel to the axis, an angular range outside ``(0, 2π]``.
    """
    t = resolve(tol)
    O = _vector(origin, "nurbs_cylinder origin", (3,))
    X, _, Z = orthonormal_frame(axis, x_dir, t)
    R = _positive(radius, "nurbs_cylinder radius")
    v0, v1 = _interval(v_range, "nurbs_cylinder v_range")
    u0, u1 = _interval(u_range, "nurbs_cylinder u_range")
    profile = nurbs_line(O + R * X + v0 * Z, O + R * X + v1 * Z, (v0, v1), t)
    return nurbs_revolution(profile, O, Z, u0, u1, tol=t)


def nurbs_cone(
    origin, axis, radius: float, semi_angle: float, v_range: tuple[float, float],
    *, x_dir=None, u_range: tuple[float, float] = (0.0, TWO_PI), tol: Tolerance | None = None,
) -> NurbsSurface:
    """Exact cone ``O + (R + v sin a)(cos u X + sin u Y) + v cos a Z`` (OCCT ``Geom_ConicalSurface``).

    ``R >= 0`` is the radius at ``v = 0``, ``0 < |a| < π/2``.  Normals point away from the axis
    (on both nappes, should ``v_range`` cross the apex).  ``u`` follows the angle map, ``v`` is exact.

    Raises
    ------
    InvalidInputError
        Wrong shapes, non-finite values, invalid ranges.
    InvalidGeometryError
        Negative radius, semi-angle not in ``0 < |a| < π/2``, zero axis, parallel ``x_dir``,
        an angular range outside ``(0, 2π]``.
    """
    t = resolve(tol)
    O = _vector(origin, "nurbs_cone origin", (3,))
    X, _, Z = orthonormal_frame(axis, x_dir, t)
    R = _scalar(radius, "nurbs_cone radius")
    if R < 0.0:
        raise InvalidGeometryError(f"nurbs_cone radius: expected a number >= 0, got {R!r}")
    a = _scalar(semi_angle, "nurbs_cone semi_angle")
    if not 0.0 < abs(a) < 0.5 * math.pi:
        raise InvalidGeometryError(f"nurbs_cone semi_angle: expected 0 < |a| < π/2, got {a!r}")
    v0, v1 = _interval(v_range, "nurbs_cone v_range")
    u0, u1 = _interval(u_range, "nurbs_cone u_range")
    sa, ca = math.sin(a), math.cos(a)
    ends = [O + (R + v * sa) * X + v * ca * Z for v in (v0, v1)]
    profile = nurbs_line(ends[0], ends[1], (v0, v1), t)
    return nurbs_revolution(profile, O, Z, u0, u1, tol=t)


def nurbs_sphere(
    center, axis, radius: float, *, x_dir=None, u_range: tuple[float, float] = (0.0, TWO_PI),
    v_range: tuple[float, float] = (-0.5 * math.pi, 0.5 * math.pi), tol: Tolerance | None = None,
) -> NurbsSurface:
    """Exact sphere ``C + R cos v (cos u X + sin u Y) + R sin v Z`` (OCCT ``Geom_SphericalSurface``), normals outward.

    The profile is the meridian arc in the ``X, Z`` half-plane from latitude ``v_range[0]``
    to ``v_range[1]``; both directions follow the angle map.  Poles are collapsed rows of the
    control net (the first ``u`` derivative vanishes there).

    Raises
    ------
    InvalidInputError
        Wrong shapes, non-finite values, invalid ranges, latitudes outside ``[-π/2, π/2]``.
    InvalidGeometryError
        Non-positive radius, zero axis, parallel ``x_dir``, an angular range outside ``(0, 2π]``.
    """
    t = resolve(tol)
    C = _vector(center, "nurbs_sphere center", (3,))
    X, _, Z = orthonormal_frame(axis, x_dir, t)
    R = _positive(radius, "nurbs_sphere radius")
    u0, u1 = _interval(u_range, "nurbs_sphere u_range")
    v0, v1 = _interval(v_range, "nurbs_sphere v_range")
    pole = 0.5 * math.pi * (1.0 + t.solver)  # round-off slack of the caller's π/2
    if v0 < -pole or v1 > pole:
        raise InvalidInputError(f"nurbs_sphere v_range: latitudes must lie in [-π/2, π/2], got ({v0!r}, {v1!r})")
    profile = _elliptic_arc(C, X, Z, R, R, v0, v1, v1 - v0, False, None)
    return nurbs_revolution(profile, C, Z, u0, u1, tol=t)


def nurbs_torus(
    center, axis, major_radius: float, minor_radius: float, *, x_dir=None,
    u_range: tuple[float, float] = (0.0, TWO_PI), v_range: tuple[float, float] = (0.0, TWO_PI),
    tol: Tolerance | None = None,
) -> NurbsSurface:
    """Exact torus ``C + (R + r cos v)(cos u X + sin u Y) + r sin v Z`` (OCCT ``Geom_ToroidalSurface``).

    The profile is the tube circle arc in the ``X, Z`` half-plane centred at ``C + R X``;
    both directions follow the angle map; normals point outward.  Only ring tori (``0 < r < R``).

    Raises
    ------
    InvalidInputError
        Wrong shapes, non-finite values, invalid ranges.
    InvalidGeometryError
        Non-positive radii, ``minor_radius >= major_radius``, zero axis, parallel ``x_dir``,
        angular ranges outside ``(0, 2π]``.
    """
    t = resolve(tol)
    C = _vector(center, "nurbs_torus center", (3,))
    X, _, Z = orthonormal_frame(axis, x_dir, t)
    R = _positive(major_radius, "nurbs_torus major_radius")
    r = _positive(minor_radius, "nurbs_torus minor_radius")
    if not r < R:
        raise InvalidGeometryError(
            f"nurbs_torus: minor_radius must be < major_radius (ring torus), got {r!r} >= {R!r}"
        )
    u0, u1 = _interval(u_range, "nurbs_torus u_range")
    v0, v1 = _interval(v_range, "nurbs_torus v_range")
    profile = _elliptic_arc(C + R * X, X, Z, r, r, *_sweep(v0, v1, t, "nurbs_torus v_range"), None)
    return nurbs_revolution(profile, C, Z, u0, u1, tol=t)
