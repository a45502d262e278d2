"""NURBS curves: an immutable value over read-only float64 arrays.

:class:`NurbsCurve` holds control points ``(n, d)`` (``d`` = 2 for curves in a
surface's parameter space, 3 in space), a knot vector ``(n + p + 1,)``, a degree
``p >= 1`` and positive weights ``(n,)``.  Polynomial B-splines have unit weights.
Clamped, floating and periodic knot vectors are all accepted: the domain is
``[U[p], U[n]]``.

Evaluation and derivatives follow numpy broadcasting: ``evaluate(u)`` returns
``np.shape(u) + (d,)``.  Rational curves are evaluated in homogeneous coordinates and
divided at the end (The NURBS Book A4.1, A4.2), polynomial ones directly, in chunks of
points so temporaries stay small; batches of :data:`coons.kernel._accel.THRESHOLD`
points or more go to the optional numba kernels of :mod:`coons.kernel._accel`, and
points of batches up to :data:`_SCALAR_POINTS` are evaluated one by one on Python
floats (numpy's per-operation cost dominates there); both do the same operations, so
give the same bits.  :func:`spline_points` is the fast route (in-domain parameters go to scipy
without :meth:`NurbsCurve.evaluate`'s per-call checks, anything else to ``evaluate``) for callers that evaluate
polynomial curves at many in-domain parameters and accept round-off differences: scipy's compiled
de Boor evaluation (the fitted intersection curves of degree 5, where the numpy path's basis
evaluation costs several times more).

This module holds the value and its evaluation; knot insertion, refinement, removal,
degree elevation and splitting live in :mod:`coons.kernel.refine`, differential
geometry in :mod:`coons.kernel.differential`, closest points in
:mod:`coons.kernel.projection`; the methods here delegate to them.
"""

from __future__ import annotations

from bisect import bisect_right
from dataclasses import dataclass
from functools import cached_property
from typing import TYPE_CHECKING

import numpy as np
from scipy.interpolate import BSpline

from coons.errors import InvalidGeometryError, InvalidInputError
from coons.kernel import _accel
from coons.kernel import basis as _b
from coons.kernel._common import as_degree, as_points, as_transform, as_weights, binomials
from coons.tolerance import Tolerance, resolve

if TYPE_CHECKING:  # pragma: no cover
    from coons.kernel.projection import ClosestPoints

__all__ = ["NurbsCurve"]

#: Points per batch of the numpy path: its temporaries are 1-D arrays of this length
#: (128 KB), which stay in cache and are recycled by the allocator (measured, as in surface.py).
_CHUNK = 16384
#: Up to this many points, :meth:`NurbsCurve.evaluate` runs on Python floats (:meth:`NurbsCurve._points_scalar`):
#: the numpy path costs some 40 array operations on one-element arrays whatever the batch (the Booleans evaluate
#: branch curves at one or two parameters at a time), the float path about a microsecond per basis product.
_SCALAR_POINTS = 4
#: ... for curves of at most this many control points (the float path converts the whole net once).
_SCALAR_NET = 4096
#: :func:`spline_points` evaluates polynomial curves by scipy's B-spline (tests switch it off to compare).
_SCIPY_POINTS = True


@dataclass(frozen=True, eq=False)
class NurbsCurve:
    """A (rational) B-spline curve of any degree in 2 or more dimensions.

    Parameters
    ----------
    control_points : (n, d) array_like
    knots : (n + p + 1,) array_like, non-decreasing
    degree : int >= 1
    weights : (n,) array_like of positive numbers, optional (default: all ones)

    Raises
    ------
    InvalidGeometryError
        Degree < 1, fewer than ``p + 1`` control points, wrong knot count,
        decreasing knots, non-positive or non-finite weights, NaN/inf coordinates.

    Examples
    --------
    >>> c = NurbsCurve([[0, 0, 0], [1, 1, 0], [2, 0, 0]], [0, 0, 0, 1, 1, 1], 2)
    >>> c.evaluate(0.5).tolist()
    [1.0, 0.5, 0.0]
    """

    control_points: np.ndarray
    knots: np.ndarray
    degree: int
    weights: np.ndarray | None = None

    def __post_init__(self) -> None:
        p = as_degree(self.degree, what="NurbsCurve")
        P = as_points(self.control_points, ndim=2, what="NurbsCurve control_points")
        n = P.shape[0]
        if n < p + 1:
            raise InvalidGeometryError(f"NurbsCurve: degree {p} needs at least {p + 1} control points, got {n}")
        U = _b.as_knot_vector(self.knots, p, n, what="NurbsCurve knots")
        W = as_weights(self.weights, (n,), what="NurbsCurve")
        object.__setattr__(self, "degree", p)
        object.__setattr__(self, "control_points", P)
        object.__setattr__(self, "knots", U)
        object.__setattr__(self, "weights", W)

    # ------------------------------------------------------------------ properties
    @property
    def dimension(self) -> int:
        """Number of coordinates ``d`` of the control points."""
        return int(self.control_points.shape[1])

    @property
    def n_control_points(self) -> int:
        return int(self.control_points.shape[0])

    @cached_property
    def is_rational(self) -> bool:
        """True when the weights are not all equal (the curve is then not polynomial)."""
        w = self.weights
        return bool(np.any(w != w[0]))

    @cached_property
    def domain(self) -> tuple[float, float]:
        """Parametric domain ``(U[p], U[n])``."""
        return _b.domain_of(self.knots, self.degree)

    @cached_property
    def homogeneous(self) -> np.ndarray:
        """Control points in homogeneous form ``[w P, w]``, shape ``(n, d + 1)``, read-only."""
        Pw = np.concatenate([self.control_points * self.weights[:, None], self.weights[:, None]], axis=1)
        Pw.setflags(write=False)
        return Pw

    @classmethod
    def from_homogeneous(cls, Pw: np.ndarray, knots, degree: int) -> "NurbsCurve":
        """Build a curve from homogeneous control points ``(n, d + 1)``.

        Raises
        ------
        InvalidGeometryError
            Non-positive last coordinate (weight).
        """
        Pw = np.asarray(Pw, dtype=np.float64)
        w = Pw[:, -1]
        if np.any(w <= 0):
            raise InvalidGeometryError(f"homogeneous weights must be positive, min is {w.min()!r}")
        return cls(Pw[:, :-1] / w[:, None], knots, degree, w)

    @cached_property
    def knot_multiplicities(self) -> tuple[np.ndarray, np.ndarray]:
        """Distinct knots and their multiplicities, ``((k,), (k,))``."""
        vals, counts = np.unique(self.knots, return_counts=True)
        return vals, counts

    # ------------------------------------------------------------------ evaluation
    def _params(self, u, tol: Tolerance | None) -> np.ndarray:
        return _b.check_parameters(u, self.domain, resolve(tol))

    @cached_property
    def _planes(self) -> tuple[np.ndarray, ...]:
        """Coordinate columns of the net the evaluation contracts, each ``(n,)`` contiguous.

        ``d`` columns of ``P`` for a polynomial curve (no weight channel, no divide),
        ``d + 1`` columns of ``[w P, w]`` for a rational one.
        """
        net = self.homogeneous if self.is_rational else self.control_points
        return tuple(np.ascontiguousarray(net[:, c]) for c in range(net.shape[1]))

    @cached_property
    def _homogeneous_planes(self) -> tuple[np.ndarray, ...]:
        return tuple(np.ascontiguousarray(self.homogeneous[:, c]) for c in range(self.homogeneous.shape[1]))

    def _contract_chunk(self, u: np.ndarray, order: int, planes) -> list:
        """Derivatives of the net given by ``planes`` at one chunk of parameters (The NURBS Book A3.2).

        Basis rows (A2.2 / A2.3) contracted with one gather per control point of the
        local window and coordinate, on contiguous 1-D arrays.

        Returns
        -------
        A : nested lists ``A[k][c]`` of (m,) float64, ``k <= order``
        """
        p = self.degree
        spans = _b.find_spans(self.knots, p, u)
        if order == 0:
            N = [_b.basis_rows(self.knots, p, spans, u)]
        else:
            N = _b.basis_derivative_rows(self.knots, p, spans, u, order)
        base = spans - p
        A: list = [[None] * len(planes) for _ in N]
        for j in range(p + 1):
            idx = base + j if j else base
            for c, P in enumerate(planes):
                g = P.take(idx)
                for k, Nk in enumerate(N):
                    if j == 0:
                        A[k][c] = Nk[0] * g
                    else:
                        A[k][c] += Nk[j] * g
        zero = np.zeros(u.shape[0])  # derivatives above the degree vanish
        return A + [[zero] * len(planes) for _ in range(order + 1 - len(N))]

    @cached_property
    def _bspline(self) -> BSpline:
        """scipy's B-spline of a polynomial curve (same knots, control points and degree), for :func:`spline_points`."""
        return BSpline.construct_fast(self.knots, self.control_points, self.degree)

    def _homogeneous_derivatives(self, u: np.ndarray, order: int) -> np.ndarray:
        """Derivatives of the homogeneous curve, ``(m, order + 1, d + 1)``, for flat ``u``.

        The numpy reference for :mod:`coons.kernel._accel` (no rational correction).
        """
        m = u.shape[0]
        planes = self._homogeneous_planes
        out = np.empty((m, order + 1, len(planes)))
        for s in range(0, m, _CHUNK):
            A = self._contract_chunk(u[s : s + _CHUNK], order, planes)
            for k in range(order + 1):
                for c in range(len(planes)):
                    out[s : s + _CHUNK, k, c] = A[k][c]
        return out

    @cached_property
    def _scalar_net(self) -> tuple[list[float], int, list[list[float]]]:
        """``(knots, last span, net rows)`` as Python floats for :meth:`_points_scalar`."""
        net = self.homogeneous if self.is_rational else self.control_points
        return self.knots.tolist(), _b.last_span(self.knots, self.degree), net.tolist()

    def _points_scalar(self, u: np.ndarray) -> np.ndarray:
        """Points ``(m, 1, d)`` at flat ``u`` inside the domain, one parameter at a time on Python floats.

        The same floating-point operations in the same order as the numpy path (:func:`~coons.kernel.basis.find_spans`'
        binary search, :func:`~coons.kernel.basis.basis_rows`' recursion, :meth:`_contract_chunk`'s sums, one
        reciprocal of the weight), each correctly rounded in both, so the same bits; a test compares them.
        """
        U, last, net = self._scalar_net
        p, d, rational = self.degree, self.dimension, self.is_rational
        out = []
        for x in u.tolist():
            span = max(min(bisect_right(U, x) - 1, last), p)
            left = [0.0] + [x - U[span + 1 - j] for j in range(1, p + 1)]
            right = [0.0] + [U[span + j] - x for j in range(1, p + 1)]
            N = _b.triangle(left, right, p, 1.0)
            base = span - p
            acc = [N[0] * g for g in net[base]]
            for j in range(1, p + 1):
                Nj = N[j]
                acc = [a + Nj * g for a, g in zip(acc, net[base + j])]
            if rational:
                r = 1.0 / acc[d]
                acc = [acc[c] * r for c in range(d)]
            out.append(acc)
        return np.array(out, dtype=np.float64).reshape(u.shape[0], 1, d)

    def _derivatives_flat(self, u: np.ndarray, order: int) -> np.ndarray:
        """Cartesian derivatives ``(m, order + 1, d)`` at flat ``u`` inside the domain.

        Large batches go to the compiled kernel of :mod:`coons.kernel._accel` when it is
        available; points of a small batch (:data:`_SCALAR_POINTS`) to :meth:`_points_scalar`;
        otherwise numpy, in chunks of :data:`_CHUNK` points, with the quotient rule of The
        NURBS Book A4.2 for rational curves.
        """
        m = u.shape[0]
        if order == 0 and 0 < m <= _SCALAR_POINTS and self.control_points.shape[0] <= _SCALAR_NET:
            return self._points_scalar(u)  # (the spans chosen are non-empty: no zero divisor)
        rational = self.is_rational
        if m >= _accel.THRESHOLD and _accel.AVAILABLE:
            net = self.homogeneous if rational else self.control_points
            out = _accel.curve_derivatives(self.knots, self.degree, net, u, order, rational)
            if out is not None:
                return out
        d = self.dimension
        planes = self._planes
        out = np.empty((m, order + 1, d))
        binom = binomials(order)
        for s in range(0, m, _CHUNK):
            A = self._contract_chunk(u[s : s + _CHUNK], order, planes)
            if rational:
                # A4.2: C^(k) = (A^(k) - sum_i C(k, i) w^(i) C^(k-i)) / w, one reciprocal per
                # point; coons.kernel._accel does the same operations in the same order.
                w = [A[k][d] for k in range(order + 1)]
                r = 1.0 / w[0]
                for k in range(order + 1):
                    for c in range(d):
                        t = A[k][c]
                        for i in range(1, k + 1):
                            x = w[i] * A[k - i][c]  # A[k - i] already holds Cartesian derivatives
                            if binom[k, i] != 1.0:
                                x *= binom[k, i]
                            t = t - x
                        A[k][c] = t * r
            blk = out[s : s + _CHUNK]
            for k in range(order + 1):
                for c in range(d):
                    blk[:, k, c] = A[k][c]
        return out

    def evaluate(self, u, tol: Tolerance | None = None) -> np.ndarray:
        """Points of the curve.

        Parameters
        ----------
        u : float or array_like, inside :attr:`domain`

        Returns
        -------
        np.shape(u) + (d,) float64

        Raises
        ------
        InvalidInputError
            Parameters outside the domain (beyond round-off) or not finite.
        """
        u = self._params(u, tol)
        shape = u.shape
        C = self._derivatives_flat(u.ravel(), 0)
        return C.reshape(shape + (self.dimension,))

    __call__ = evaluate

    def derivatives(self, u, order: int = 1, tol: Tolerance | None = None) -> np.ndarray:
        """Point and derivatives up to ``order`` (The NURBS Book A3.2 and A4.2).

        Returns
        -------
        np.shape(u) + (order + 1, d) float64
            ``[..., k, :]`` is the k-th derivative; ``[..., 0, :]`` the point.
        """
        if not isinstance(order, (int, np.integer)) or order < 0:
            raise InvalidInputError(f"order must be an integer >= 0, got {order!r}")
        u = self._params(u, tol)
        shape = u.shape
        C = self._derivatives_flat(u.ravel(), int(order))
        return C.reshape(shape + (order + 1, self.dimension))

    def tangent(self, u, tol: Tolerance | None = None) -> np.ndarray:
        """Unit tangent vectors, ``np.shape(u) + (d,)``.

        Raises
        ------
        InvalidGeometryError
            Where the first derivative vanishes (a singular point of the parametrisation).
        """
        d1 = self.derivatives(u, 1, tol)[..., 1, :]
        norm = np.linalg.norm(d1, axis=-1, keepdims=True)
        if np.any(norm == 0):
            raise InvalidGeometryError("tangent undefined: the first derivative vanishes")
        return d1 / norm

    # ------------------------------------------------------------------ queries
    def bounding_box(self) -> np.ndarray:
        """Bounding box of the control polygon (contains the curve), ``(2, d)``: min row, max row."""
        P = self.control_points
        return np.stack([P.min(axis=0), P.max(axis=0)])

    def is_close(self, other: "NurbsCurve", tol: Tolerance | None = None, samples: int = 64) -> bool:
        """True if both curves have the same domain and their points agree within ``tol.linear``.

        Compared at ``samples`` parameters per knot span of both curves (a sampled test,
        not a proof).
        """
        t = resolve(tol)
        if not isinstance(other, NurbsCurve) or other.dimension != self.dimension:
            return False
        a0, a1 = self.domain
        b0, b1 = other.domain
        scale = max(1.0, a1 - a0)
        if abs(a0 - b0) > t.solver * scale or abs(a1 - b1) > t.solver * scale:
            return False
        knots = np.union1d(np.unique(self.knots), np.unique(other.knots))
        knots = knots[(knots >= a0) & (knots <= a1)]
        s = np.linspace(0.0, 1.0, samples, endpoint=False)
        u = (knots[:-1, None] + np.diff(knots)[:, None] * s).ravel()
        u = np.append(u, a1)
        return bool(np.max(np.linalg.norm(self.evaluate(u) - other.evaluate(u), axis=-1)) <= t.linear)

    # ------------------------------------------------------------------ new curves
    def reversed(self) -> "NurbsCurve":
        """The same point set traversed backwards over the same domain: ``c.reversed()(a + b - u) == c(u)``."""
        a, b = self.domain
        U = (a + b) - self.knots[::-1]
        return NurbsCurve(self.control_points[::-1], U, self.degree, self.weights[::-1])

    def reparametrized(self, start: float, end: float) -> "NurbsCurve":
        """The same curve over the domain ``[start, end]`` (affine map of the knots).

        Raises
        ------
        InvalidInputError
            ``end <= start`` or non-finite bounds.
        """
        try:
            U = _b.mapped_knots(self.knots, self.degree, start, end)
        except InvalidInputError as exc:
            raise InvalidInputError(f"reparametrized: {exc}") from None
        return NurbsCurve(self.control_points, U, self.degree, self.weights)

    def transformed(self, matrix) -> "NurbsCurve":
        """The curve under an affine map (4×4 or 3×3 matrix); NURBS are affinely invariant.

        Only for 3-D curves.
        """
        if self.dimension != 3:
            raise InvalidInputError(f"transformed needs a 3-D curve, this one has dimension {self.dimension}")
        T = as_transform(matrix)
        P = self.control_points @ T[:3, :3].T + T[:3, 3]
        return NurbsCurve(P, self.knots, self.degree, self.weights)

    def translated(self, offset) -> "NurbsCurve":
        """The curve moved by ``offset`` ``(d,)``."""
        off = np.asarray(offset, dtype=np.float64)
        if off.shape != (self.dimension,):
            raise InvalidInputError(f"offset must have shape ({self.dimension},), got {off.shape}")
        return NurbsCurve(self.control_points + off, self.knots, self.degree, self.weights)

    # ------------------------------------------------------------------ delegated algorithms
    def insert_knot(self, u: float, times: int = 1, tol: Tolerance | None = None) -> "NurbsCurve":
        """Insert ``u`` ``times`` times (Boehm; The NURBS Book A5.1). See :mod:`coons.kernel.refine`."""
        from coons.kernel import refine

        return refine.curve_insert_knot(self, u, times, tol)

    def refine_knots(self, new_knots, tol: Tolerance | None = None) -> "NurbsCurve":
        """Insert many knots at once (Oslo / The NURBS Book A5.4). See :mod:`coons.kernel.refine`."""
        from coons.kernel import refine

        return refine.curve_refine_knots(self, new_knots, tol)

    def remove_knot(self, u: float, times: int = 1, tol: Tolerance | None = None) -> "NurbsCurve":
        """Remove ``u`` up to ``times`` times while the curve moves less than ``tol.linear`` (A5.8)."""
        from coons.kernel import refine

        return refine.curve_remove_knot(self, u, times, tol)

    def elevate_degree(self, times: int = 1) -> "NurbsCurve":
        """Raise the degree by ``times`` without changing the curve (The NURBS Book A5.9)."""
        from coons.kernel import refine

        return refine.curve_elevate_degree(self, times)

    def split(self, u: float, tol: Tolerance | None = None) -> tuple["NurbsCurve", "NurbsCurve"]:
        """Two clamped curves over ``[a, u]`` and ``[u, b]`` (subdivision by knot insertion)."""
        from coons.kernel import refine

        return refine.curve_split(self, u, tol)

    def segment(self, start: float, end: float, tol: Tolerance | None = None) -> "NurbsCurve":
        """The piece of the curve over ``[start, end]`` as a clamped curve."""
        from coons.kernel import refine

        return refine.curve_segment(self, start, end, tol)

    def bezier_segments(self) -> list["NurbsCurve"]:
        """Decomposition into Bézier pieces, one per non-empty knot span (The NURBS Book A5.6)."""
        from coons.kernel import refine

        return refine.curve_bezier_segments(self)

    def clamped(self) -> "NurbsCurve":
        """The same curve over the same domain with clamped end knots (multiplicity p + 1)."""
        from coons.kernel import refine

        return refine.curve_clamped(self)

    def closest_parameters(self, points, tol: Tolerance | None = None) -> np.ndarray:
        """Parameters of the closest curve points to ``points`` ``(..., d)``; see :mod:`coons.kernel.projection`."""
        from coons.kernel import projection

        return projection.curve_closest_parameters(self, points, tol)

    def closest_points(self, points, tol: Tolerance | None = None) -> "ClosestPoints":
        """Closest points, parameters and distances; see :mod:`coons.kernel.projection`."""
        from coons.kernel import projection

        return projection.curve_closest_points(self, points, tol)

    def invert(self, points, tol: Tolerance | None = None) -> np.ndarray:
        """Parameters of points that lie on the curve; raises ``ConvergenceError`` for points off it."""
        from coons.kernel import projection

        return projection.curve_invert(self, points, tol)

    def curvature(self, u, tol: Tolerance | None = None) -> np.ndarray:
        """Curvature ``|C' x C''| / |C'|^3``, ``np.shape(u)``; see :mod:`coons.kernel.differential`."""
        from coons.kernel import differential

        return differential.curve_curvature(self, u, tol)

    def torsion(self, u, tol: Tolerance | None = None) -> np.ndarray:
        """Torsion, ``np.shape(u)`` (3-D curves)."""
        from coons.kernel import differential

        return differential.curve_torsion(self, u, tol)

    def frenet_frame(self, u, tol: Tolerance | None = None) -> np.ndarray:
        """Frenet frame ``(T, N, B)`` as ``np.shape(u) + (3, 3)`` (rows T, N, B)."""
        from coons.kernel import differential

        return differential.curve_frenet_frame(self, u, tol)

    def length(self, start: float | None = None, end: float | None = None, tol: Tolerance | None = None) -> float:
        """Arc length over ``[start, end]`` (default: the domain) by Gauss–Legendre quadrature per span."""
        from coons.kernel import differential

        return differential.curve_length(self, start, end, tol)


def spline_points(curve, u: np.ndarray) -> np.ndarray:
    """``curve.evaluate(u)`` at a flat array ``u`` ``(m,)``, to round-off: ``(m, d)``.

    A polynomial :class:`NurbsCurve` at more than :data:`_SCALAR_POINTS` parameters, all inside its domain,
    goes to scipy's compiled de Boor evaluation (``BSpline``, built once per curve and kept on it), which
    costs a fraction of the numpy path's basis evaluation at degree 5 (the fitted intersection curves);
    the points agree with :meth:`NurbsCurve.evaluate`'s to round-off, not bit for bit.  Anything else
    (rational curves, other types, few points, parameters outside the domain or not finite) goes to the
    curve's own ``evaluate``, with its checks and errors.
    """
    if (_SCIPY_POINTS and type(curve) is NurbsCurve and u.shape[0] > _SCALAR_POINTS
            and not curve.is_rational):
        lo, hi = curve.domain
        if lo <= u.min() and u.max() <= hi:  # (False for NaN)
            return curve._bspline(u)
    return curve.evaluate(u)
