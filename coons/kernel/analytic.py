"""Analytic curves and surfaces with exact parameters: line, circle, ellipse, plane, cylinder, cone, sphere, torus.

Each type is a frozen value over read-only float64 arrays: an origin, a right-handed
orthonormal frame and radii (or angles).  Points, derivatives of any order and unit normals
are evaluated in closed form with numpy broadcasting, and points project onto the curve or
surface (``closest_parameters``) and get a signed distance (``implicit``) in closed form
(the ellipse, whose projection is the root of a quartic, by a bracketing bisection to full
double precision).  The parametrisations are exactly those of OCCT (``Geom_Line``,
``Geom_Circle``, ``Geom_Ellipse``, ``Geom_Plane``, ``Geom_CylindricalSurface``,
``Geom_ConicalSurface``, ``Geom_SphericalSurface``, ``Geom_ToroidalSurface``) and of the
corresponding STEP entities, so parameters exchanged with either need no conversion.  The
module deliberately does not bound, trim or intersect: each value is the whole (possibly
unbounded) curve or surface, which edges and faces bound in :mod:`coons.topology`;
intersections are in :mod:`coons.kernel.intersect`; exact NURBS forms are built by
:mod:`coons.kernel.conics` (``to_nurbs``).

Parametrisations (``X, Y, Z`` the frame; ``e(u) = cos u X + sin u Y``)::

    Line                P(t)    = O + t D                                   t ∈ ℝ
    Circle              P(t)    = C + R e(t)                                t ∈ [0, 2π) periodic
    Ellipse             P(t)    = C + a cos t X + b sin t Y   (a >= b)      t ∈ [0, 2π) periodic
    PlanarSurface       S(u, v) = O + u X + v Y      (normal Z)             u, v ∈ ℝ
    CylindricalSurface  S(u, v) = O + R e(u) + v Z                          u periodic, v ∈ ℝ
    ConicalSurface      S(u, v) = O + (R + v sin a) e(u) + v cos a Z        u periodic, v ∈ ℝ
    SphericalSurface    S(u, v) = C + R cos v e(u) + R sin v Z              u periodic, v ∈ [-π/2, π/2]
    ToroidalSurface     S(u, v) = C + (R + r cos v) e(u) + r sin v Z        u, v periodic

Normals are ``Su × Sv`` normalised, given in closed form everywhere (limits where
``Su × Sv`` vanishes): ``Z`` for the plane; outward for the cylinder, sphere and torus
(poles of the sphere: ``±Z``); away from the axis on both nappes of the cone (at the apex:
the limit from the ``R + v sin a > 0`` side).

Evaluation accepts any finite parameters (the formulas are periodic or unbounded); the
``domain_*``/``period_*`` attributes state the natural ranges that ``closest_parameters``
returns.  The NURBS parameter of a circular direction of ``to_nurbs()`` is not the angle:
it equals the angle at the knots and follows the tangent half-angle relation in between;
map points with :func:`~coons.kernel.conics.angle_to_nurbs_parameter` and
:func:`~coons.kernel.conics.nurbs_parameter_to_angle` (re-exported here).

``transformed`` takes similarities (rotation, translation, uniform scale ``s``; reflections
only where the parametrisation survives with a right-handed frame): angular parameters are
unchanged and linear ones (``t`` of a line, ``u, v`` of a plane, ``v`` of a cylinder or cone)
are multiplied by ``s``, as OCCT's ``TransformedParameter``: ``T(P(t)) = P'(s t)``.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field

import numpy as np

from coons.errors import InvalidGeometryError, InvalidInputError
from coons.kernel import conics
from coons.kernel._common import as_transform, similarity_parts
from coons.kernel.conics import angle_to_nurbs_parameter, nurbs_parameter_to_angle
from coons.kernel.curve import NurbsCurve
from coons.kernel.surface import NurbsSurface
from coons.tolerance import DEFAULT_TOLERANCE, Tolerance, resolve

__all__ = [
    "Line",
    "Circle",
    "Ellipse",
    "PlanarSurface",
    "CylindricalSurface",
    "ConicalSurface",
    "SphericalSurface",
    "ToroidalSurface",
    "BATCHED_SURFACES",
    "SCALAR_CURVES",
    "angle_to_nurbs_parameter",
    "nurbs_parameter_to_angle",
    "meridian_row",
    "scalar_parameter",
    "scalar_point",
    "surface_derivatives",
    "surface_normals",
]

TWO_PI = conics.TWO_PI
HALF_PI = 0.5 * math.pi
_INF = math.inf

# Field kinds for is_close: points and lengths compare against tol.linear, directions and
# angles against tol.angular.
_POINT = {"kind": "point"}
_DIRECTION = {"kind": "direction"}
_LENGTH = {"kind": "length"}
_ANGLE = {"kind": "angle"}

#: Bisection steps of the ellipse projection: 2^-64 · π/2 ≈ 8.5e-20 is below half the spacing
#: of doubles anywhere in [1e-3, π/2], so the bracket is resolved to double precision.
_ELLIPSE_BISECTIONS = 64


# ---------------------------------------------------------------------------- helpers
def _checked(what: str, fn, *args):
    """Run a conics validator; report its failure as an invalid ``what`` definition."""
    try:
        return fn(*args)
    except InvalidInputError as exc:
        raise InvalidGeometryError(f"{what}: {exc}") from None


def _readonly(a: np.ndarray) -> np.ndarray:
    a = np.array(a, dtype=np.float64)
    a.setflags(write=False)
    return a


def _curve_params(t) -> np.ndarray:
    t = np.asarray(t, dtype=np.float64)
    if not np.isfinite(t).all():
        raise InvalidInputError("parameters must be finite, got NaN or inf")
    return t


def _surface_params(u, v) -> tuple[np.ndarray, np.ndarray]:
    u, v = _curve_params(u), _curve_params(v)
    try:
        return tuple(np.broadcast_arrays(u, v))
    except ValueError as exc:
        raise InvalidInputError(f"u and v do not broadcast: shapes {u.shape} and {v.shape}") from exc


def _order(order) -> int:
    if isinstance(order, bool) or not isinstance(order, (int, np.integer)) or order < 0:
        raise InvalidInputError(f"order must be an integer >= 0, got {order!r}")
    return int(order)


def _points(points) -> np.ndarray:
    p = np.asarray(points, dtype=np.float64)
    if p.ndim == 0 or p.shape[-1] != 3:
        raise InvalidInputError(f"points: expected an array of shape (..., 3), got {p.shape}")
    if not np.all(np.isfinite(p)):
        raise InvalidInputError("points: coordinates must be finite, got NaN or inf")
    return p


def _angle(y, x) -> np.ndarray:
    """``atan2(y, x)`` in ``[0, 2π)``, and 0 where ``x = y = 0`` (whatever the signs of the zeros)."""
    a = np.arctan2(y, x)
    a = np.where(a < 0.0, a + TWO_PI, a)
    # -tiny + 2π rounds to 2π, which is the angle 0.
    a = np.where(a >= TWO_PI, 0.0, a)
    return np.where((x == 0.0) & (y == 0.0), 0.0, a)


def _cos_d(c: np.ndarray, s: np.ndarray, k: int) -> np.ndarray:
    """k-th derivative of cos, from cos and sin (exact signs, no phase round-off; only the one asked is negated)."""
    k %= 4
    return c if k == 0 else -s if k == 1 else -c if k == 2 else s


def _sin_d(c: np.ndarray, s: np.ndarray, k: int) -> np.ndarray:
    """k-th derivative of sin."""
    k %= 4
    return s if k == 0 else c if k == 1 else -s if k == 2 else -c


def _is_close(a, b, tol: Tolerance | None) -> bool:
    """Same type and every defining field within tolerance (``linear``: points, lengths; ``angular``: the rest)."""
    t = resolve(tol)
    if type(a) is not type(b):
        return False
    for f in dataclasses.fields(a):
        limit = t.linear if f.metadata["kind"] in ("point", "length") else t.angular
        gap = float(np.linalg.norm(np.asarray(getattr(a, f.name)) - np.asarray(getattr(b, f.name))))
        if gap > limit:
            return False
    return True


class _Framed:
    """Frame bookkeeping shared by the framed types: ``_origin`` and ``_frame`` rows ``X, Y, Z``."""

    _origin: np.ndarray
    _frame: np.ndarray

    def _init_frame(self, what: str, origin_field: str, axis_field: str, x_field: str) -> None:
        O = _readonly(_checked(what, conics._vector, getattr(self, origin_field), origin_field, (3,)))
        # Frozen values cannot take a tolerance argument: the frame is validated against the
        # default angular tolerance (an x_dir closer to the axis leaves X to round-off).
        axis, x_dir = getattr(self, axis_field), getattr(self, x_field)
        F = _readonly(_checked(what, conics.orthonormal_frame, axis, x_dir, DEFAULT_TOLERANCE))
        object.__setattr__(self, origin_field, O)
        object.__setattr__(self, axis_field, F[2])
        object.__setattr__(self, x_field, F[0])
        object.__setattr__(self, "_origin", O)
        object.__setattr__(self, "_frame", F)

    @property
    def y_dir(self) -> np.ndarray:
        """``Y = Z × X``, ``(3,)``."""
        return self._frame[1]

    @property
    def frame(self) -> np.ndarray:
        """``(3, 3)`` rows ``X, Y, Z`` (right-handed, orthonormal), read-only."""
        return self._frame

    def _local(self, points) -> np.ndarray:
        """Coordinates of ``points`` ``(..., 3)`` in the frame, ``(..., 3)``."""
        return (_points(points) - self._origin) @ self._frame.T

    def _moved_frame(self, matrix, tol: Tolerance | None, keep_handedness: bool, what: str):
        """``(origin', X', Y', Z', s)`` of the frame under a similarity.

        With ``keep_handedness`` the new axis is ``M Z / s`` and reflections raise; otherwise
        the new axis is ``X' × Y'``, which keeps ``P(t) = C + a cos t X + b sin t Y`` exact.
        """
        T, s, reflects = similarity_parts(matrix, resolve(tol).angular)
        M = T[:3, :3]
        X, Y, Z = (M @ self._frame.T).T / s
        if reflects and keep_handedness:
            raise InvalidInputError(
                f"{what}.transformed: a reflection would make the frame left-handed; the image is the same "
                "surface type with u reversed (u -> -u), build it explicitly"
            )
        return M @ self._origin + T[:3, 3], X, Y, (Z if keep_handedness else np.cross(X, Y)), s


# ---------------------------------------------------------------------------- one point
def scalar_parameter(curve: "Line | Circle", point) -> float:
    """``curve.closest_parameters`` of one point, in Python floats (a few coordinates cost less
    than a numpy call: edge matching and import ask this for thousands of single points).

    Parameters
    ----------
    curve : Line or Circle
    point : sequence of 3 floats

    Raises
    ------
    InvalidInputError
        Another curve type.
    """
    P = [float(x) for x in point]
    if type(curve) is Line:
        O, D = curve.origin.tolist(), curve.direction.tolist()
        return (P[0] - O[0]) * D[0] + (P[1] - O[1]) * D[1] + (P[2] - O[2]) * D[2]
    if type(curve) is Circle:
        C = curve.center.tolist()
        X, Y, _ = curve.frame.tolist()
        r = (P[0] - C[0], P[1] - C[1], P[2] - C[2])
        x = r[0] * X[0] + r[1] * X[1] + r[2] * X[2]
        y = r[0] * Y[0] + r[1] * Y[1] + r[2] * Y[2]
        a = math.atan2(y, x)  # as _angle: [0, 2π), 0 on the axis
        if a < 0.0:
            a += TWO_PI
        return 0.0 if a >= TWO_PI or (x == 0.0 and y == 0.0) else a
    raise InvalidInputError(f"scalar_parameter takes a Line or a Circle, got {type(curve).__name__}")


def scalar_point(curve: "Line | Circle", t: float) -> list[float]:
    """``curve.evaluate(t)`` of one parameter, in Python floats (the formula of ``evaluate``).

    Raises
    ------
    InvalidInputError
        Another curve type.
    """
    if type(curve) is Line:
        O, D = curve.origin.tolist(), curve.direction.tolist()
        return [O[k] + t * D[k] for k in range(3)]
    if type(curve) is Circle:
        C = curve.center.tolist()
        X, Y, _ = curve.frame.tolist()
        c, s = curve.radius * math.cos(t), curve.radius * math.sin(t)
        return [(c * X[k] + s * Y[k]) + C[k] for k in range(3)]
    raise InvalidInputError(f"scalar_point takes a Line or a Circle, got {type(curve).__name__}")


# ---------------------------------------------------------------------------- curves
@dataclass(frozen=True, eq=False)
class Line:
    """The line ``P(t) = O + t D``, ``D`` unit (OCCT ``Geom_Line``, STEP ``line``), ``t ∈ ℝ``.

    Parameters
    ----------
    origin : (3,) array_like
    direction : (3,) array_like, non-zero (normalised here)

    Raises
    ------
    InvalidGeometryError
        Wrong shapes, non-finite values, a zero direction.
    """

    origin: np.ndarray = field(metadata=_POINT)
    direction: np.ndarray = field(metadata=_DIRECTION)

    domain = (-_INF, _INF)
    periodic = False
    period = None

    def __post_init__(self) -> None:
        object.__setattr__(self, "origin", _readonly(_checked("Line", conics._vector, self.origin, "origin", (3,))))
        direction = _checked("Line", conics._unit, self.direction, "direction", (3,))
        object.__setattr__(self, "direction", _readonly(direction))

    def evaluate(self, t) -> np.ndarray:
        """Points, ``np.shape(t) + (3,)``.

        Raises
        ------
        InvalidInputError
            Non-finite parameters.
        """
        t = _curve_params(t)
        return self.origin + t[..., None] * self.direction

    __call__ = evaluate

    def derivatives(self, t, order: int = 1) -> np.ndarray:
        """Point and derivatives up to ``order``, ``np.shape(t) + (order + 1, 3)`` (as ``NurbsCurve.derivatives``)."""
        order = _order(order)
        t = _curve_params(t)
        out = np.zeros(t.shape + (order + 1, 3))
        out[..., 0, :] = self.origin + t[..., None] * self.direction
        if order >= 1:
            out[..., 1, :] = self.direction
        return out

    def closest_parameters(self, points) -> np.ndarray:
        """Parameters of the orthogonal projections ``(P - O)·D``, ``points.shape[:-1]``."""
        return (_points(points) - self.origin) @ self.direction

    def is_close(self, other, tol: Tolerance | None = None) -> bool:
        """Same parametrisation: origins within ``tol.linear``, directions within ``tol.angular``."""
        return _is_close(self, other, tol)

    def transformed(self, matrix, tol: Tolerance | None = None) -> "Line":
        """The image under any non-singular affine map: ``T(P(t)) = P'(|M D| t)`` (a line stays exact).

        Raises
        ------
        InvalidInputError
            A malformed or singular matrix.
        """
        T = as_transform(matrix)
        M = T[:3, :3]
        if float(np.linalg.det(M)) == 0.0:
            raise InvalidInputError("transform is singular (determinant 0)")
        return Line(M @ self.origin + T[:3, 3], M @ self.direction)

    def to_nurbs(self, t_range: tuple[float, float], tol: Tolerance | None = None) -> NurbsCurve:
        """The segment over ``t_range`` as a degree-1 NURBS with the same parameter."""
        t0, t1 = conics._interval(t_range, "Line.to_nurbs t_range")
        return conics.nurbs_line(self.evaluate(t0), self.evaluate(t1), (t0, t1), tol)


class _Conic(_Framed):
    """``P(t) = C + a cos t X + b sin t Y``, shared by circles and ellipses."""

    domain = (0.0, TWO_PI)
    periodic = True
    period = TWO_PI

    def _radii(self) -> tuple[float, float]:
        raise NotImplementedError

    def evaluate(self, t) -> np.ndarray:
        """Points, ``np.shape(t) + (3,)``.

        Raises
        ------
        InvalidInputError
            Non-finite parameters.
        """
        t = _curve_params(t)
        a, b = self._radii()
        X, Y, _ = self._frame
        return ((a * np.cos(t))[..., None] * X + (b * np.sin(t))[..., None] * Y) + self._origin

    __call__ = evaluate

    def derivatives(self, t, order: int = 1) -> np.ndarray:
        """Point and derivatives of any order in closed form, ``np.shape(t) + (order + 1, 3)``."""
        order = _order(order)
        t = _curve_params(t)
        a, b = self._radii()
        X, Y, _ = self._frame
        c, s = np.cos(t), np.sin(t)
        out = np.empty(t.shape + (order + 1, 3))
        for k in range(order + 1):
            out[..., k, :] = (a * _cos_d(c, s, k))[..., None] * X + (b * _sin_d(c, s, k))[..., None] * Y
        out[..., 0, :] += self._origin
        return out

    def is_close(self, other, tol: Tolerance | None = None) -> bool:
        """Same parametrisation: centre and radii within ``tol.linear``, axis and ``x_dir`` within ``tol.angular``."""
        return _is_close(self, other, tol)

    def to_nurbs(self, t_range: tuple[float, float] = (0.0, TWO_PI), tol: Tolerance | None = None) -> NurbsCurve:
        """Exact NURBS over ``t_range`` (sweep at most 2π), NURBS domain ``t_range``.

        The NURBS parameter equals ``t`` at the knots; in between map with
        ``angle_to_nurbs_parameter(t, *t_range)`` (see :mod:`coons.kernel.conics`).
        """
        t0, t1 = conics._interval(t_range, f"{type(self).__name__}.to_nurbs t_range")
        a, b = self._radii()
        X, Y, _ = self._frame
        return conics.nurbs_ellipse_arc(self._origin, X, Y, a, b, t0, t1, tol=tol)


@dataclass(frozen=True, eq=False)
class Circle(_Conic):
    """The circle ``P(t) = C + R (cos t X + sin t Y)`` (OCCT ``Geom_Circle``, STEP ``circle``), ``t ∈ [0, 2π)``.

    Parameters
    ----------
    center : (3,) array_like
    axis : (3,) array_like, non-zero: ``Z``, the circle turns counter-clockwise seen from its tip
    x_dir : (3,) array_like, not parallel to ``axis``: projected into the plane, where ``t = 0`` is
    radius : float > 0

    Raises
    ------
    InvalidGeometryError
        Wrong shapes, non-finite values, zero or parallel directions, non-positive radius.

    Examples
    --------
    >>> c = Circle([0, 0, 0], [0, 0, 1], [1, 0, 0], 2.0)
    >>> np.allclose(c.evaluate(np.pi / 2), [0, 2, 0], rtol=0, atol=1e-15)
    True
    """

    center: np.ndarray = field(metadata=_POINT)
    axis: np.ndarray = field(metadata=_DIRECTION)
    x_dir: np.ndarray = field(metadata=_DIRECTION)
    radius: float = field(metadata=_LENGTH)

    def __post_init__(self) -> None:
        self._init_frame("Circle", "center", "axis", "x_dir")
        object.__setattr__(self, "radius", _checked("Circle", conics._positive, self.radius, "radius"))

    @classmethod
    def many(cls, centers, frames, radii) -> list["Circle"]:
        """One circle per row of ``centers (k, 3)``, ``frames (k, 3, 3)`` (rows ``X, Y, Z``) and ``radii (k,)``.

        For the callers that build many circles at once (the Booleans' batched plane–cylinder
        sections): the frames are taken as they are, after one check in arrays that each is
        right-handed and orthonormal to ``1e3`` ulps (what an orthonormalisation's round-off
        leaves), so each circle holds read-only rows of them, as the constructor would give.

        Raises
        ------
        InvalidGeometryError
            Shapes other than ``(k, 3)``, ``(k, 3, 3)``, ``(k,)``, non-finite values, a frame that is
            not right-handed orthonormal or a non-positive radius (the first bad row is named).
        """
        C = np.array(centers, dtype=np.float64)
        F = np.array(frames, dtype=np.float64)
        R = np.array(radii, dtype=np.float64)
        k = len(C)
        if C.shape != (k, 3) or F.shape != (k, 3, 3) or R.shape != (k,):
            raise InvalidGeometryError(f"Circle.many needs (k, 3), (k, 3, 3) and (k,) arrays, got shapes "
                                       f"{C.shape}, {F.shape} and {R.shape}")
        # Orthonormal rows and Z = X × Y, to round-off (1e3 ulps is far below any tolerance).
        G = np.einsum("kij,klj->kil", F, F) - np.eye(3)
        # X × Y by np.cross's products and differences, without its axis handling (most of its cost on a
        # few frames)
        (x0, x1, x2), (y0, y1, y2) = F[:, 0].T, F[:, 1].T
        XY = np.empty((k, 3))
        XY[:, 0], XY[:, 1], XY[:, 2] = x1 * y2 - x2 * y1, x2 * y0 - x0 * y2, x0 * y1 - x1 * y0
        det = np.einsum("kj,kj->k", XY, F[:, 2])
        bad = np.flatnonzero(~np.isfinite(C).all(axis=1) | ~np.isfinite(R) | ~(R > 0.0)
                             | ~(np.abs(G).max(axis=(1, 2), initial=0.0) <= 1e3 * np.finfo(np.float64).eps)
                             | ~(np.abs(det - 1.0) <= 1e3 * np.finfo(np.float64).eps))
        if bad.size:
            i = int(bad[0])
            raise InvalidGeometryError(f"Circle.many: row {i} (center {C[i].tolist()}, frame {F[i].tolist()}, radius "
                                       f"{R[i]!r}) is not finite, not a right-handed orthonormal frame or not positive")
        C.setflags(write=False)
        F.setflags(write=False)
        out = []
        for c, f, r in zip(C, F, R.tolist()):
            circle = object.__new__(cls)
            # (the frozen dataclass forbids setattr; its instance dict is the one the constructor fills)
            circle.__dict__.update(center=c, _origin=c, axis=f[2], x_dir=f[0], _frame=f, radius=r)
            out.append(circle)
        return out

    def _radii(self) -> tuple[float, float]:
        return self.radius, self.radius

    def closest_parameters(self, points) -> np.ndarray:
        """Angle of each point's projection on the circle's plane, in ``[0, 2π)``, ``points.shape[:-1]``.

        On the axis (every circle point is equally close) the parameter is 0.
        """
        L = self._local(points)
        return _angle(L[..., 1], L[..., 0])

    def transformed(self, matrix, tol: Tolerance | None = None) -> "Circle":
        """The image under a similarity (reflections included); ``t`` is unchanged.

        Raises
        ------
        InvalidInputError
            A matrix that is malformed, singular or not a similarity.
        """
        O, X, _, Z, s = self._moved_frame(matrix, tol, False, "Circle")
        return Circle(O, Z, X, self.radius * s)


@dataclass(frozen=True, eq=False)
class Ellipse(_Conic):
    """The ellipse ``P(t) = C + a cos t X + b sin t Y``, ``a >= b`` (OCCT ``Geom_Ellipse``), ``t ∈ [0, 2π)``.

    Parameters
    ----------
    center : (3,) array_like
    axis : (3,) array_like, non-zero
    x_dir : (3,) array_like: the major axis direction (projected into the plane)
    major_radius, minor_radius : float, ``major_radius >= minor_radius > 0``

    Raises
    ------
    InvalidGeometryError
        Wrong shapes, non-finite values, zero or parallel directions, non-positive radii,
        ``minor_radius > major_radius``.
    """

    center: np.ndarray = field(metadata=_POINT)
    axis: np.ndarray = field(metadata=_DIRECTION)
    x_dir: np.ndarray = field(metadata=_DIRECTION)
    major_radius: float = field(metadata=_LENGTH)
    minor_radius: float = field(metadata=_LENGTH)

    def __post_init__(self) -> None:
        self._init_frame("Ellipse", "center", "axis", "x_dir")
        a = _checked("Ellipse", conics._positive, self.major_radius, "major_radius")
        b = _checked("Ellipse", conics._positive, self.minor_radius, "minor_radius")
        if b > a:
            raise InvalidGeometryError(f"Ellipse: minor_radius must be <= major_radius, got {b!r} > {a!r}")
        object.__setattr__(self, "major_radius", a)
        object.__setattr__(self, "minor_radius", b)

    def _radii(self) -> tuple[float, float]:
        return self.major_radius, self.minor_radius

    def closest_parameters(self, points) -> np.ndarray:
        """Parameters ``t`` in ``[0, 2π)`` of the closest ellipse points, ``points.shape[:-1]``.

        Points are projected on the ellipse's plane; the foot in the quadrant of the point is
        the unique root in ``[0, π/2]`` of ``(b² - a²) sin t cos t + a|x| sin t - b|y| cos t``
        (Eberly, "Distance from a point to an ellipse", 2013), found by 64 vectorised
        bisection steps (double precision).  At the centre (two closest points, ``±b Y``) the
        parameter is ``π/2``, or 0 when ``a == b``.
        """
        L = self._local(points)
        x, y = L[..., 0], L[..., 1]
        a, b = self.major_radius, self.minor_radius
        ax, by = a * np.abs(x), b * np.abs(y)
        k = b * b - a * a
        lo = np.zeros(x.shape)
        hi = np.full(x.shape, HALF_PI)
        for _ in range(_ELLIPSE_BISECTIONS):
            mid = 0.5 * (lo + hi)
            c, s = np.cos(mid), np.sin(mid)
            below = k * s * c + ax * s - by * c < 0.0
            lo = np.where(below, mid, lo)
            hi = np.where(below, hi, mid)
        t = 0.5 * (lo + hi)
        return _angle(np.copysign(np.sin(t), y), np.copysign(np.cos(t), x))

    def transformed(self, matrix, tol: Tolerance | None = None) -> "Ellipse":
        """The image under a similarity (reflections included); ``t`` is unchanged.

        Raises
        ------
        InvalidInputError
            A matrix that is malformed, singular or not a similarity.
        """
        O, X, _, Z, s = self._moved_frame(matrix, tol, False, "Ellipse")
        return Ellipse(O, Z, X, self.major_radius * s, self.minor_radius * s)


# ---------------------------------------------------------------------------- surfaces
@dataclass(frozen=True, eq=False)
class PlanarSurface(_Framed):
    """The plane ``S(u, v) = O + u X + v Y`` with normal ``Z = X × Y`` (OCCT ``Geom_Plane``, STEP ``plane``).

    The normal is the field ``axis`` (as for the other surfaces), so that ``normal(u, v)`` is
    the same method on every surface type.

    Parameters
    ----------
    origin : (3,) array_like
    axis : (3,) array_like, non-zero: the normal ``Z``
    x_dir : (3,) array_like, not parallel to ``axis`` (projected into the plane)

    Raises
    ------
    InvalidGeometryError
        Wrong shapes, non-finite values, zero or parallel directions.
    """

    origin: np.ndarray = field(metadata=_POINT)
    axis: np.ndarray = field(metadata=_DIRECTION)
    x_dir: np.ndarray = field(metadata=_DIRECTION)

    surface_type = "plane"  # read by topology.brep.Face.surface_type
    domain_u = (-_INF, _INF)
    domain_v = (-_INF, _INF)
    periodic_u = periodic_v = False
    period_u = period_v = None

    def __post_init__(self) -> None:
        self._init_frame("PlanarSurface", "origin", "axis", "x_dir")

    @property
    def domain(self) -> tuple[tuple[float, float], tuple[float, float]]:
        return self.domain_u, self.domain_v

    def evaluate(self, u, v) -> np.ndarray:
        """Points, ``np.broadcast_shapes(np.shape(u), np.shape(v)) + (3,)``.

        Raises
        ------
        InvalidInputError
            Non-finite or non-broadcastable parameters.
        """
        u, v = _surface_params(u, v)
        X, Y, _ = self._frame
        return self.origin + u[..., None] * X + v[..., None] * Y

    __call__ = evaluate

    def derivatives(self, u, v, order: int = 1) -> np.ndarray:
        """``shape + (order + 1, order + 1, 3)``; ``[..., k, l, :] = ∂^(k+l) S / ∂u^k ∂v^l``."""
        order = _order(order)
        u, v = _surface_params(u, v)
        out = np.zeros(u.shape + (order + 1, order + 1, 3))
        out[..., 0, 0, :] = self.evaluate(u, v)
        if order >= 1:
            out[..., 1, 0, :] = self._frame[0]
            out[..., 0, 1, :] = self._frame[1]
        return out

    def normal(self, u, v) -> np.ndarray:
        """Unit normals ``Z = Su × Sv``, ``shape + (3,)``."""
        u, v = _surface_params(u, v)
        return np.broadcast_to(self.axis, u.shape + (3,)).copy()

    def closest_parameters(self, points) -> np.ndarray:
        """``(u, v)`` of the orthogonal projections, ``points.shape[:-1] + (2,)``."""
        return self._local(points)[..., :2]

    def implicit(self, points) -> np.ndarray:
        """Signed distance ``(P - O)·Z``, positive on the normal's side, ``points.shape[:-1]``."""
        return self._local(points)[..., 2]

    def is_close(self, other, tol: Tolerance | None = None) -> bool:
        """Same parametrisation: origins within ``tol.linear``, frames within ``tol.angular``."""
        return _is_close(self, other, tol)

    def transformed(self, matrix, tol: Tolerance | None = None) -> "PlanarSurface":
        """The image under a similarity: ``T(S(u, v)) = S'(s u, s v)``.

        Reflections are accepted: the normal of the image is ``X' × Y'``.

        Raises
        ------
        InvalidInputError
            A matrix that is malformed, singular or not a similarity.
        """
        O, X, _, Z, _ = self._moved_frame(matrix, tol, False, "PlanarSurface")
        return PlanarSurface(O, Z, X)

    def to_nurbs(
        self, u_range: tuple[float, float], v_range: tuple[float, float], tol: Tolerance | None = None
    ) -> NurbsSurface:
        """The bilinear patch over ``u_range × v_range`` with the same parameters."""
        return conics.nurbs_plane_patch(self.origin, self.axis, u_range, v_range, x_dir=self.x_dir, tol=tol)


class _Revolved(_Framed):
    """Surfaces ``S(u, v) = O + ρ(v) e(u) + h(v) Z``: cylinder, cone, sphere, torus.

    ``∂^(k+l) S / ∂u^k ∂v^l = ρ^(l)(v) e^(k)(u) + [k = 0] h^(l)(v) Z`` (+ ``O`` for ``k = l = 0``),
    and ``Su × Sv = ρ (h' e - ρ' Z)``.
    """

    domain_u = (0.0, TWO_PI)
    periodic_u = True
    period_u = TWO_PI

    @property
    def domain(self) -> tuple[tuple[float, float], tuple[float, float]]:
        return self.domain_u, self.domain_v  # type: ignore[attr-defined]

    def _meridian(self, v: np.ndarray, order: int) -> tuple[list[np.ndarray], list[np.ndarray]]:
        """``ρ^(l)(v)`` and ``h^(l)(v)`` for ``l <= order``, each of ``v``'s shape."""
        raise NotImplementedError

    def evaluate(self, u, v) -> np.ndarray:
        """Points, ``np.broadcast_shapes(np.shape(u), np.shape(v)) + (3,)``.

        Raises
        ------
        InvalidInputError
            Non-finite or non-broadcastable parameters.
        """
        u, v = _surface_params(u, v)
        rho, h = self._meridian(v, 0)
        X, Y, Z = self._frame
        e = np.cos(u)[..., None] * X + np.sin(u)[..., None] * Y
        # Same order of sums as derivatives(), so both give bit-identical points.
        return (rho[0][..., None] * e + h[0][..., None] * Z) + self._origin

    __call__ = evaluate

    def derivatives(self, u, v, order: int = 1) -> np.ndarray:
        """All partials up to ``order`` in closed form, ``shape + (order + 1, order + 1, 3)``.

        ``[..., k, l, :] = ∂^(k+l) S / ∂u^k ∂v^l`` (the layout of ``NurbsSurface.derivatives``).
        """
        order = _order(order)
        u, v = _surface_params(u, v)
        rho, h = self._meridian(v, order)
        X, Y, Z = self._frame
        c, s = np.cos(u), np.sin(u)
        # e^(k)(u) for every k, times ρ^(l)(v) for every l, in one broadcast product (the same
        # element-wise arithmetic as a loop over k and l).
        E = np.stack([_cos_d(c, s, k)[..., None] * X + _sin_d(c, s, k)[..., None] * Y for k in range(order + 1)],
                     axis=-2)  # shape + (order + 1, 3)
        out = E[..., :, None, :] * np.stack(rho, axis=-1)[..., None, :, None]
        out[..., 0, :, :] += np.stack(h, axis=-1)[..., None] * Z
        out[..., 0, 0, :] += self._origin
        return out

    def normal(self, u, v) -> np.ndarray:
        """Unit normals ``sign(ρ) (h' e - ρ' Z) / |(ρ', h')|`` (= ``Su × Sv`` normalised), ``shape + (3,)``.

        Where ``ρ = 0`` (sphere poles, cone apex) the limit from the ``ρ > 0`` side.
        """
        u, v = _surface_params(u, v)
        rho, h = self._meridian(v, 1)
        X, Y, Z = self._frame
        e = np.cos(u)[..., None] * X + np.sin(u)[..., None] * Y
        sign = np.where(rho[0] < 0.0, -1.0, 1.0) / np.hypot(rho[1], h[1])
        return (sign * h[1])[..., None] * e - (sign * rho[1])[..., None] * Z

    def is_close(self, other, tol: Tolerance | None = None) -> bool:
        """Same parametrisation: points and lengths within ``tol.linear``, directions, angles within ``tol.angular``."""
        return _is_close(self, other, tol)

    def _polar(self, points) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(φ, ρ, z)``: angle in ``[0, 2π)`` (0 on the axis), distance to the axis, height along it.

        ``coons.kernel.intersect._projected`` repeats these expressions without the checks: keep them in step."""
        L = self._local(points)
        return _angle(L[..., 1], L[..., 0]), np.hypot(L[..., 0], L[..., 1]), L[..., 2]


@dataclass(frozen=True, eq=False)
class CylindricalSurface(_Revolved):
    """The cylinder ``S(u, v) = O + R (cos u X + sin u Y) + v Z`` (OCCT ``Geom_CylindricalSurface``), normals outward.

    Parameters
    ----------
    origin : (3,) array_like, a point of the axis (``v = 0``)
    axis : (3,) array_like, non-zero
    x_dir : (3,) array_like, not parallel to ``axis``: where ``u = 0`` is
    radius : float > 0

    Raises
    ------
    InvalidGeometryError
        Wrong shapes, non-finite values, zero or parallel directions, non-positive radius.
    """

    origin: np.ndarray = field(metadata=_POINT)
    axis: np.ndarray = field(metadata=_DIRECTION)
    x_dir: np.ndarray = field(metadata=_DIRECTION)
    radius: float = field(metadata=_LENGTH)

    surface_type = "cylinder"  # read by topology.brep.Face.surface_type
    domain_v = (-_INF, _INF)
    periodic_v = False
    period_v = None

    def __post_init__(self) -> None:
        self._init_frame("CylindricalSurface", "origin", "axis", "x_dir")
        object.__setattr__(self, "radius", _checked("CylindricalSurface", conics._positive, self.radius, "radius"))

    def _meridian(self, v, order):
        zero = np.zeros(v.shape)
        rho = [np.full(v.shape, self.radius)] + [zero] * order
        h = [v, np.ones(v.shape)][: order + 1] + [zero] * max(0, order - 1)
        return rho, h

    def closest_parameters(self, points) -> np.ndarray:
        """``(u, v)``, ``u`` in ``[0, 2π)``, ``points.shape[:-1] + (2,)``; on the axis ``u = 0``."""
        phi, _, z = self._polar(points)
        return np.stack([phi, z], axis=-1)

    def implicit(self, points) -> np.ndarray:
        """Signed distance: distance to the axis minus ``R`` (positive outside), ``points.shape[:-1]``."""
        _, rho, _ = self._polar(points)
        return rho - self.radius

    def transformed(self, matrix, tol: Tolerance | None = None) -> "CylindricalSurface":
        """The image under a rotation, translation and uniform scale ``s``: ``T(S(u, v)) = S'(u, s v)``.

        Raises
        ------
        InvalidInputError
            A malformed or non-similarity matrix, or a reflection.
        """
        O, X, _, Z, s = self._moved_frame(matrix, tol, True, "CylindricalSurface")
        return CylindricalSurface(O, Z, X, self.radius * s)

    def to_nurbs(
        self, v_range: tuple[float, float], u_range: tuple[float, float] = (0.0, TWO_PI), tol: Tolerance | None = None
    ) -> NurbsSurface:
        """Exact NURBS over ``u_range × v_range``: ``v`` exact, ``u`` via ``angle_to_nurbs_parameter(u, *u_range)``."""
        return conics.nurbs_cylinder(
            self.origin, self.axis, self.radius, v_range, x_dir=self.x_dir, u_range=u_range, tol=tol
        )


@dataclass(frozen=True, eq=False)
class ConicalSurface(_Revolved):
    """The cone ``S(u, v) = O + (R + v sin a)(cos u X + sin u Y) + v cos a Z`` (OCCT ``Geom_ConicalSurface``).

    ``R >= 0`` is the radius at ``v = 0`` (STEP allows 0: apex at the origin), ``0 < |a| < π/2``.
    ``v`` runs over both nappes: past the apex ``v_apex = -R / sin a`` the points are on the
    opposite side of the axis.  Normals point away from the axis on both nappes.

    Parameters
    ----------
    origin : (3,) array_like, centre of the reference circle (``v = 0``)
    axis : (3,) array_like, non-zero
    x_dir : (3,) array_like, not parallel to ``axis``
    radius : float >= 0
    semi_angle : float, ``0 < |semi_angle| < π/2`` (negative: the cone narrows along ``+Z``)

    Raises
    ------
    InvalidGeometryError
        Wrong shapes, non-finite values, zero or parallel directions, negative radius,
        semi-angle out of range.
    """

    origin: np.ndarray = field(metadata=_POINT)
    axis: np.ndarray = field(metadata=_DIRECTION)
    x_dir: np.ndarray = field(metadata=_DIRECTION)
    radius: float = field(metadata=_LENGTH)
    semi_angle: float = field(metadata=_ANGLE)

    surface_type = "cone"  # read by topology.brep.Face.surface_type
    domain_v = (-_INF, _INF)
    periodic_v = False
    period_v = None

    def __post_init__(self) -> None:
        self._init_frame("ConicalSurface", "origin", "axis", "x_dir")
        R = _checked("ConicalSurface", conics._scalar, self.radius, "radius")
        if R < 0.0:
            raise InvalidGeometryError(f"ConicalSurface: radius must be >= 0, got {R!r}")
        a = _checked("ConicalSurface", conics._scalar, self.semi_angle, "semi_angle")
        if not 0.0 < abs(a) < HALF_PI:
            raise InvalidGeometryError(f"ConicalSurface: semi_angle must satisfy 0 < |a| < π/2, got {a!r}")
        object.__setattr__(self, "radius", R)
        object.__setattr__(self, "semi_angle", a)

    @property
    def apex(self) -> np.ndarray:
        """The apex ``O - (R / tan a) Z``, ``(3,)``."""
        return self._origin - (self.radius / math.tan(self.semi_angle)) * self.axis

    def _meridian(self, v, order):
        sa, ca = math.sin(self.semi_angle), math.cos(self.semi_angle)
        zero = np.zeros(v.shape)
        rho = [self.radius + v * sa, np.full(v.shape, sa)][: order + 1] + [zero] * max(0, order - 1)
        h = [v * ca, np.full(v.shape, ca)][: order + 1] + [zero] * max(0, order - 1)
        return rho, h

    def closest_parameters(self, points) -> np.ndarray:
        """``(u, v)`` of the closest point on the double cone, ``points.shape[:-1] + (2,)``.

        In the meridian plane of the point the cone is two lines through the apex, ``u = φ``
        and ``u = φ + π``; the nearer one wins (OCCT's ``ElSLib::ConeParameters`` makes the same
        choice), and ``v`` is the foot on it.  On the axis ``u = 0``.
        """
        phi, rho, z = self._polar(points)
        sa, ca = math.sin(self.semi_angle), math.cos(self.semi_angle)
        R = self.radius
        near = np.abs((rho - R) * ca - z * sa)
        far = np.abs((-rho - R) * ca - z * sa)
        other = far < near
        u = np.where(other, phi + math.pi, phi)
        u = np.where(u >= TWO_PI, u - TWO_PI, u)
        v = (np.where(other, -rho, rho) - R) * sa + z * ca
        return np.stack([u, v], axis=-1)

    def implicit(self, points) -> np.ndarray:
        """Signed distance to the double cone, ``ρ cos|a| - |z - z_apex| sin|a|`` (positive outside).

        Returns ``points.shape[:-1]``.
        """
        _, rho, z = self._polar(points)
        a = abs(self.semi_angle)
        z_apex = -self.radius / math.tan(self.semi_angle)
        return rho * math.cos(a) - np.abs(z - z_apex) * math.sin(a)

    def transformed(self, matrix, tol: Tolerance | None = None) -> "ConicalSurface":
        """The image under a rotation, translation and uniform scale ``s``: ``T(S(u, v)) = S'(u, s v)``.

        Raises
        ------
        InvalidInputError
            A malformed or non-similarity matrix, or a reflection.
        """
        O, X, _, Z, s = self._moved_frame(matrix, tol, True, "ConicalSurface")
        return ConicalSurface(O, Z, X, self.radius * s, self.semi_angle)

    def to_nurbs(
        self, v_range: tuple[float, float], u_range: tuple[float, float] = (0.0, TWO_PI), tol: Tolerance | None = None
    ) -> NurbsSurface:
        """Exact NURBS over ``u_range × v_range``: ``v`` exact, ``u`` via ``angle_to_nurbs_parameter(u, *u_range)``."""
        return conics.nurbs_cone(
            self.origin, self.axis, self.radius, self.semi_angle, v_range, x_dir=self.x_dir, u_range=u_range, tol=tol
        )


@dataclass(frozen=True, eq=False)
class SphericalSurface(_Revolved):
    """The sphere ``S(u, v) = C + R cos v (cos u X + sin u Y) + R sin v Z`` (OCCT ``Geom_SphericalSurface``).

    ``u`` is the longitude, ``v ∈ [-π/2, π/2]`` the latitude; ``Su × Sv = R² cos v n``, so the
    normals point outward (at the poles: ``±Z``).

    Parameters
    ----------
    center : (3,) array_like
    axis : (3,) array_like, non-zero (towards the north pole)
    x_dir : (3,) array_like, not parallel to ``axis``
    radius : float > 0

    Raises
    ------
    InvalidGeometryError
        Wrong shapes, non-finite values, zero or parallel directions, non-positive radius.
    """

    center: np.ndarray = field(metadata=_POINT)
    axis: np.ndarray = field(metadata=_DIRECTION)
    x_dir: np.ndarray = field(metadata=_DIRECTION)
    radius: float = field(metadata=_LENGTH)

    surface_type = "sphere"  # read by topology.brep.Face.surface_type
    domain_v = (-HALF_PI, HALF_PI)
    periodic_v = False
    period_v = None

    def __post_init__(self) -> None:
        self._init_frame("SphericalSurface", "center", "axis", "x_dir")
        object.__setattr__(self, "radius", _checked("SphericalSurface", conics._positive, self.radius, "radius"))

    def _meridian(self, v, order):
        c, s = np.cos(v), np.sin(v)
        R = self.radius
        return [R * _cos_d(c, s, l) for l in range(order + 1)], [R * _sin_d(c, s, l) for l in range(order + 1)]

    def closest_parameters(self, points) -> np.ndarray:
        """``(u, v)`` with ``u ∈ [0, 2π)``, ``v ∈ [-π/2, π/2]``, ``points.shape[:-1] + (2,)``.

        On the axis ``u = 0`` (and ``v = ±π/2``); at the centre (every point equally close)
        ``(0, 0)`` (OCCT's ``ElSLib`` gives ``(0, -π/2)`` there).
        """
        phi, rho, z = self._polar(points)
        return np.stack([phi, np.arctan2(z, rho)], axis=-1)

    def implicit(self, points) -> np.ndarray:
        """Signed distance ``|P - C| - R`` (positive outside), ``points.shape[:-1]``."""
        return np.linalg.norm(_points(points) - self._origin, axis=-1) - self.radius

    def transformed(self, matrix, tol: Tolerance | None = None) -> "SphericalSurface":
        """The image under a rotation, translation and uniform scale: ``T(S(u, v)) = S'(u, v)``.

        Raises
        ------
        InvalidInputError
            A malformed or non-similarity matrix, or a reflection.
        """
        O, X, _, Z, s = self._moved_frame(matrix, tol, True, "SphericalSurface")
        return SphericalSurface(O, Z, X, self.radius * s)

    def to_nurbs(
        self, u_range: tuple[float, float] = (0.0, TWO_PI), v_range: tuple[float, float] = (-HALF_PI, HALF_PI),
        tol: Tolerance | None = None,
    ) -> NurbsSurface:
        """Exact NURBS over ``u_range × v_range``; both directions via ``angle_to_nurbs_parameter``."""
        return conics.nurbs_sphere(
            self.center, self.axis, self.radius, x_dir=self.x_dir, u_range=u_range, v_range=v_range, tol=tol
        )


@dataclass(frozen=True, eq=False)
class ToroidalSurface(_Revolved):
    """The torus ``S(u, v) = C + (R + r cos v)(cos u X + sin u Y) + r sin v Z`` (OCCT ``Geom_ToroidalSurface``).

    Ring tori only (``0 < r < R``: no spindle or horn tori); normals point outward.

    Parameters
    ----------
    center : (3,) array_like
    axis : (3,) array_like, non-zero
    x_dir : (3,) array_like, not parallel to ``axis``
    major_radius : float > 0, ``R``
    minor_radius : float, ``0 < r < R``

    Raises
    ------
    InvalidGeometryError
        Wrong shapes, non-finite values, zero or parallel directions, non-positive radii,
        ``minor_radius >= major_radius``.
    """

    center: np.ndarray = field(metadata=_POINT)
    axis: np.ndarray = field(metadata=_DIRECTION)
    x_dir: np.ndarray = field(metadata=_DIRECTION)
    major_radius: float = field(metadata=_LENGTH)
    minor_radius: float = field(metadata=_LENGTH)

    surface_type = "torus"  # read by topology.brep.Face.surface_type
    domain_v = (0.0, TWO_PI)
    periodic_v = True
    period_v = TWO_PI

    def __post_init__(self) -> None:
        self._init_frame("ToroidalSurface", "center", "axis", "x_dir")
        R = _checked("ToroidalSurface", conics._positive, self.major_radius, "major_radius")
        r = _checked("ToroidalSurface", conics._positive, self.minor_radius, "minor_radius")
        if not r < R:
            raise InvalidGeometryError(
                f"ToroidalSurface: minor_radius must be < major_radius (ring torus), got {r!r} >= {R!r}"
            )
        object.__setattr__(self, "major_radius", R)
        object.__setattr__(self, "minor_radius", r)

    def _meridian(self, v, order):
        c, s = np.cos(v), np.sin(v)
        R, r = self.major_radius, self.minor_radius
        rho = [r * _cos_d(c, s, l) for l in range(order + 1)]
        rho[0] = rho[0] + R
        return rho, [r * _sin_d(c, s, l) for l in range(order + 1)]

    def closest_parameters(self, points) -> np.ndarray:
        """``(u, v)`` both in ``[0, 2π)``, ``points.shape[:-1] + (2,)``.

        On the axis ``u = 0``; on the core circle (``ρ = R``, ``z = 0``, every tube point
        equally close) ``v = 0``.
        """
        phi, rho, z = self._polar(points)
        return np.stack([phi, _angle(z, rho - self.major_radius)], axis=-1)

    def implicit(self, points) -> np.ndarray:
        """Signed distance ``sqrt((ρ - R)² + z²) - r`` (positive outside the tube), ``points.shape[:-1]``."""
        _, rho, z = self._polar(points)
        return np.hypot(rho - self.major_radius, z) - self.minor_radius

    def transformed(self, matrix, tol: Tolerance | None = None) -> "ToroidalSurface":
        """The image under a rotation, translation and uniform scale: ``T(S(u, v)) = S'(u, v)``.

        Raises
        ------
        InvalidInputError
            A malformed or non-similarity matrix, or a reflection.
        """
        O, X, _, Z, s = self._moved_frame(matrix, tol, True, "ToroidalSurface")
        return ToroidalSurface(O, Z, X, self.major_radius * s, self.minor_radius * s)

    def to_nurbs(
        self, u_range: tuple[float, float] = (0.0, TWO_PI), v_range: tuple[float, float] = (0.0, TWO_PI),
        tol: Tolerance | None = None,
    ) -> NurbsSurface:
        """Exact NURBS over ``u_range × v_range``; both directions via ``angle_to_nurbs_parameter``."""
        return conics.nurbs_torus(
            self.center, self.axis, self.major_radius, self.minor_radius,
            x_dir=self.x_dir, u_range=u_range, v_range=v_range, tol=tol,
        )


#: The curve types :func:`scalar_parameter` and :func:`scalar_point` serve.
SCALAR_CURVES = (Line, Circle)


# ---------------------------------------------------------------------------- many surfaces at once
def meridian_row(S) -> tuple[float, float, float, float, float] | None:
    """``(α, β, γ, δ, ε)`` of a surface of revolution's meridian ``ρ(v) = α + β v + γ cos v``,
    ``h(v) = δ v + ε sin v`` (cylinder, cone, sphere, torus; the forms of their ``_meridian``), else None."""
    if isinstance(S, CylindricalSurface):
        return S.radius, 0.0, 0.0, 1.0, 0.0
    if isinstance(S, ConicalSurface):
        return S.radius, math.sin(S.semi_angle), 0.0, math.cos(S.semi_angle), 0.0
    if isinstance(S, SphericalSurface):
        return 0.0, 0.0, S.radius, 0.0, S.radius
    if isinstance(S, ToroidalSurface):
        return S.major_radius, 0.0, S.minor_radius, 0.0, S.minor_radius
    return None


#: Surface types :func:`surface_derivatives` and :func:`surface_normals` evaluate in one expression per type.
BATCHED_SURFACES = (PlanarSurface, CylindricalSurface, ConicalSurface, SphericalSurface, ToroidalSurface)


def _batch(surfaces: list, u, v, what: str, index=None, gather: bool = True) -> tuple[np.ndarray, ...]:
    """The checked parameters ``u, v (k,)``, ``kind (k,)`` (1 plane, 2 surface of revolution, 0 other),
    origins ``(k, 3)``, frames ``(k, 3, 3)``, meridian rows ``(k, 5)`` (zeros where they do not apply),
    the surface of each row ``(k,)`` and the distinct surfaces it indexes (``surfaces`` itself when
    ``index`` is given; else one per distinct object of ``surfaces``).  Without ``gather``, ``kind``,
    the origins, frames and meridian rows are those of the distinct surfaces, ``(n, ...)``, for the
    caller to take by ``index``.

    Raises
    ------
    InvalidInputError
        Non-finite parameters, not one ``(u, v)`` per row, or an index out of range.
    """
    u, v = (np.asarray(x, dtype=np.float64).reshape(-1) for x in (u, v))
    if index is None:  # one surface per row, often the same object many times: each distinct one once
        slot: dict[int, int] = {}
        index = np.array([slot.setdefault(id(S), len(slot)) for S in surfaces], dtype=np.int64)
        surfaces = list({id(S): S for S in surfaces}.values())
    else:
        index = np.asarray(index, dtype=np.int64).reshape(-1)
    n = len(surfaces)
    k = index.size
    if u.size != k or v.size != k:
        raise InvalidInputError(f"{what} needs one (u, v) per surface: {k} surfaces, {u.size}, {v.size}")
    if k and (index.min() < 0 or index.max() >= n):
        raise InvalidInputError(f"{what}: surface index out of range [0, {n})")
    if not (np.isfinite(u).all() and np.isfinite(v).all()):
        raise InvalidInputError("parameters must be finite, got NaN or inf")
    kind = np.zeros(n, dtype=np.int64)
    O, F, M = np.zeros((n, 3)), np.zeros((n, 3, 3)), np.zeros((n, 5))
    for i, S in enumerate(surfaces):
        if isinstance(S, PlanarSurface):
            kind[i], O[i], F[i] = 1, S._origin, S._frame
        elif isinstance(S, _Revolved):
            row = meridian_row(S)
            if row is not None:
                kind[i], O[i], F[i], M[i] = 2, S._origin, S._frame, row
    if gather and (k != n or not np.array_equal(index, np.arange(n))):
        kind, O, F, M = kind[index], O[index], F[index], M[index]
    return u, v, kind, O, F, M, index, surfaces


def _each_other(kind: np.ndarray, index: np.ndarray) -> list[np.ndarray]:
    """The rows of the surfaces :func:`_batch` does not handle (``kind`` 0), grouped by surface."""
    rows = np.flatnonzero(kind == 0)
    groups: dict[int, list[int]] = {}
    for r, i in zip(rows.tolist(), index[rows].tolist()):
        groups.setdefault(i, []).append(r)
    return [np.asarray(g) for g in groups.values()]


def _meridian_many(M: np.ndarray, v: np.ndarray, order: int) -> tuple[list[np.ndarray], list[np.ndarray]]:
    """``ρ^(l)(v)`` and ``h^(l)(v)``, ``l <= order``, for meridian rows ``M (k, 5)`` and ``v (k,)``."""
    c, s = np.cos(v), np.sin(v)
    a, b, g, d, e = M.T
    rho = [g * _cos_d(c, s, l) for l in range(order + 1)]
    h = [e * _sin_d(c, s, l) for l in range(order + 1)]
    rho[0] = rho[0] + (a + b * v)
    h[0] = h[0] + d * v
    if order >= 1:
        rho[1] = rho[1] + b
        h[1] = h[1] + d
    return rho, h


def surface_derivatives(surfaces: list, u, v, order: int = 1, index=None) -> np.ndarray:
    """Partials of many surfaces, ``surfaces[i]`` (``surfaces[index[i]]`` when ``index (k,)`` is given)
    at ``(u[i], v[i])``: ``(k, order + 1, order + 1, 3)``, ``[i, a, b] = ∂^(a+b) S_i / ∂u^a ∂v^b`` (the
    layout of ``derivatives``).

    Planes and surfaces of revolution (cylinders, cones, spheres, tori: one meridian form,
    :func:`meridian_row`) are evaluated in one expression each; any other surface is called once.

    Raises
    ------
    InvalidInputError
        Non-finite parameters, not one ``(u, v)`` per row, or an index out of range.
    """
    order = _order(order)
    u, v, kind, O, F, M, index, surfaces = _batch(surfaces, u, v, "surface_derivatives", index, gather=False)
    # Each row's origin, frame and meridian row taken straight from its surface's (not gathered
    # for every row first and then again for the rows of each type: a check of a 20×20 plate
    # evaluates 43 000 rows).
    out = np.zeros((index.size, order + 1, order + 1, 3))
    kind = kind[index]
    p = np.flatnonzero(kind == 1)
    if p.size:
        i = index[p]
        X, Y = F[i, 0], F[i, 1]
        out[p, 0, 0] = O[i] + u[p, None] * X + v[p, None] * Y
        if order >= 1:
            out[p, 1, 0], out[p, 0, 1] = X, Y
    r = np.flatnonzero(kind == 2)
    if r.size:
        i = index[r]
        X, Y, Z = F[i, 0], F[i, 1], F[i, 2]
        c, s = np.cos(u[r])[:, None], np.sin(u[r])[:, None]
        rho, h = _meridian_many(M[i], v[r], order)
        for a in range(order + 1):
            E = _cos_d(c, s, a) * X + _sin_d(c, s, a) * Y
            for b in range(order + 1):
                out[r, a, b] = E * rho[b][:, None]
        for b in range(order + 1):
            out[r, 0, b] += h[b][:, None] * Z
        out[r, 0, 0] += O[i]
    for r in _each_other(kind, index):  # one call per surface
        D = surfaces[index[r[0]]].derivatives(u[r], v[r], order)
        out[r] = np.asarray(D, dtype=np.float64).reshape(out[r].shape)
    return out


def surface_normals(surfaces: list, u, v, index=None) -> np.ndarray:
    """Unit normals of many surfaces, ``surfaces[i]`` (or ``surfaces[index[i]]``) at ``(u[i], v[i])``:
    ``(k, 3)``, as their ``normal`` gives them (a surface of revolution's limit at ``ρ = 0``
    included); planes and surfaces of revolution in one expression each (:func:`surface_derivatives`).

    Raises
    ------
    InvalidInputError
        As :func:`surface_derivatives`.
    """
    u, v, kind, O, F, M, index, surfaces = _batch(surfaces, u, v, "surface_normals", index)
    out = np.empty((index.size, 3))
    out[kind == 1] = F[kind == 1, 2]
    r = np.flatnonzero(kind == 2)
    if r.size:
        c, s = np.cos(u[r])[:, None], np.sin(u[r])[:, None]
        e = c * F[r, 0] + s * F[r, 1]
        rho, h = _meridian_many(M[r], v[r], 1)
        sign = np.where(rho[0] < 0.0, -1.0, 1.0) / np.hypot(rho[1], h[1])
        out[r] = (sign * h[1])[:, None] * e - (sign * rho[1])[:, None] * F[r, 2]
    for r in _each_other(kind, index):  # one call per surface
        out[r] = np.asarray(surfaces[index[r[0]]].normal(u[r], v[r]), dtype=np.float64).reshape(r.size, 3)
    return out
