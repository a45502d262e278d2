"""NURBS surfaces: an immutable tensor-product value over read-only float64 arrays.

:class:`NurbsSurface` holds control points ``(nu, nv, d)``, knot vectors in ``u``
and ``v``, degrees ``(pu, pv)`` and positive weights ``(nu, nv)``.  Scattered
evaluation (``evaluate(u, v)`` with broadcasting) gathers the ``(pu+1)(pv+1)``
homogeneous control points of each parameter pair and contracts them with the
basis values, in chunks; grid evaluation (``evaluate_grid``) multiplies sparse
collocation matrices ``Bu @ Pw @ Bv^T`` (The NURBS Book A3.5/A4.3 in matrix form,
Cohen–Riesenfeld–Elber ch. 13).

Knot operations, differential geometry and projection are in
:mod:`coons.kernel.refine`, :mod:`coons.kernel.differential` and
:mod:`coons.kernel.projection`; the methods here delegate to them.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property
from typing import TYPE_CHECKING

import numpy as np

from coons.errors import InvalidGeometryError, InvalidInputError
from coons.kernel import basis as _b
from coons.kernel._common import CHUNK, as_degree, as_points, as_transform, as_weights, binomials
from coons.tolerance import Tolerance, resolve

if TYPE_CHECKING:  # pragma: no cover
    from coons.kernel.curve import NurbsCurve
    from coons.kernel.projection import ClosestPoints

__all__ = ["NurbsSurface"]


@dataclass(frozen=True, eq=False)
class NurbsSurface:
    """A (rational) tensor-product B-spline surface.

    Parameters
    ----------
    control_points : (nu, nv, d) array_like
    knots_u : (nu + pu + 1,) array_like
    knots_v : (nv + pv + 1,) array_like
    degree_u, degree_v : int >= 1
    weights : (nu, nv) array_like of positive numbers, optional

    Raises
    ------
    InvalidGeometryError
        As for :class:`~coons.kernel.curve.NurbsCurve`, in each direction.
    """

    control_points: np.ndarray
    knots_u: np.ndarray
    knots_v: np.ndarray
    degree_u: int
    degree_v: int
    weights: np.ndarray | None = None

    def __post_init__(self) -> None:
        pu = as_degree(self.degree_u, what="NurbsSurface degree_u")
        pv = as_degree(self.degree_v, what="NurbsSurface degree_v")
        P = as_points(self.control_points, ndim=3, what="NurbsSurface control_points")
        nu, nv = P.shape[:2]
        if nu < pu + 1 or nv < pv + 1:
            raise InvalidGeometryError(
                f"NurbsSurface: degrees ({pu}, {pv}) need at least ({pu + 1}, {pv + 1}) control points, got ({nu}, {nv})"
            )
        Uu = _b.as_knot_vector(self.knots_u, pu, nu, what="NurbsSurface knots_u")
        Uv = _b.as_knot_vector(self.knots_v, pv, nv, what="NurbsSurface knots_v")
        W = as_weights(self.weights, (nu, nv), what="NurbsSurface")
        object.__setattr__(self, "degree_u", pu)
        object.__setattr__(self, "degree_v", pv)
        object.__setattr__(self, "control_points", P)
        object.__setattr__(self, "knots_u", Uu)
        object.__setattr__(self, "knots_v", Uv)
        object.__setattr__(self, "weights", W)

    # ------------------------------------------------------------------ properties
    @property
    def dimension(self) -> int:
        return int(self.control_points.shape[2])

    @property
    def shape(self) -> tuple[int, int]:
        """Control net size ``(nu, nv)``."""
        return int(self.control_points.shape[0]), int(self.control_points.shape[1])

    @cached_property
    def is_rational(self) -> bool:
        w = self.weights
        return bool(np.any(w != w.flat[0]))

    @cached_property
    def domain_u(self) -> tuple[float, float]:
        return _b.domain_of(self.knots_u, self.degree_u)

    @cached_property
    def domain_v(self) -> tuple[float, float]:
        return _b.domain_of(self.knots_v, self.degree_v)

    @property
    def domain(self) -> tuple[tuple[float, float], tuple[float, float]]:
        """``((u0, u1), (v0, v1))``."""
        return self.domain_u, self.domain_v

    @cached_property
    def homogeneous(self) -> np.ndarray:
        """Homogeneous control points ``[w P, w]``, ``(nu, nv, d + 1)``, read-only."""
        W = self.weights[:, :, None]
        Pw = np.concatenate([self.control_points * W, W], axis=2)
        Pw.setflags(write=False)
        return Pw

    @classmethod
    def from_homogeneous(cls, Pw, knots_u, knots_v, degree_u: int, degree_v: int) -> "NurbsSurface":
        """Build a surface from homogeneous control points ``(nu, nv, d + 1)``."""
        Pw = np.asarray(Pw, dtype=np.float64)
        w = Pw[:, :, -1]
        if np.any(w <= 0):
            raise InvalidGeometryError(f"homogeneous weights must be positive, min is {w.min()!r}")
        return cls(Pw[:, :, :-1] / w[:, :, None], knots_u, knots_v, degree_u, degree_v, w)

    # ------------------------------------------------------------------ evaluation
    def _params(self, u, v, tol: Tolerance | None) -> tuple[np.ndarray, np.ndarray]:
        t = resolve(tol)
        u = _b.check_parameters(u, self.domain_u, t, what="u")
        v = _b.check_parameters(v, self.domain_v, t, what="v")
        try:
            u, v = np.broadcast_arrays(u, v)
        except ValueError as exc:
            raise InvalidInputError(f"u and v do not broadcast: shapes {u.shape} and {v.shape}") from exc
        return u, v

    def _homogeneous_derivatives(self, u: np.ndarray, v: np.ndarray, order: int) -> np.ndarray:
        """Mixed partials of the homogeneous surface, ``(m, order+1, order+1, d+1)``, flat ``u, v``."""
        pu, pv = self.degree_u, self.degree_v
        nv = self.shape[1]
        Pw = self.homogeneous.reshape(-1, self.dimension + 1)
        m = u.shape[0]
        out = np.empty((m, order + 1, order + 1, Pw.shape[1]))
        for s in range(0, m, CHUNK):
            uu, vv = u[s : s + CHUNK], v[s : s + CHUNK]
            su = _b.find_spans(self.knots_u, pu, uu)
            sv = _b.find_spans(self.knots_v, pv, vv)
            if order == 0:
                Nu = _b.basis_functions(self.knots_u, pu, su, uu)[:, None, :]
                Nv = _b.basis_functions(self.knots_v, pv, sv, vv)[:, None, :]
            else:
                Nu = _b.basis_derivatives(self.knots_u, pu, su, uu, order)
                Nv = _b.basis_derivatives(self.knots_v, pv, sv, vv, order)
            # One gather of the (pu+1)(pv+1) control points of every point, then contract.
            idx = ((su - pu)[:, None, None] + np.arange(pu + 1)[None, :, None]) * nv + (
                (sv - pv)[:, None, None] + np.arange(pv + 1)[None, None, :]
            )
            G = Pw[idx]  # (k, pu+1, pv+1, d+1)
            if order == 0:
                T = np.einsum("kj,kijd->kid", Nv[:, 0, :], G, optimize=False)
                out[s : s + CHUNK, 0, 0] = np.einsum("ki,kid->kd", Nu[:, 0, :], T)
            else:
                T = np.einsum("klj,kijd->klid", Nv, G)
                out[s : s + CHUNK] = np.einsum("kai,klid->kald", Nu, T)
        return out

    def evaluate(self, u, v, tol: Tolerance | None = None) -> np.ndarray:
        """Points at parameter pairs, broadcasting ``u`` against ``v``.

        Returns
        -------
        np.broadcast_shapes(np.shape(u), np.shape(v)) + (d,) float64

        Raises
        ------
        InvalidInputError
            Parameters outside the domain (beyond round-off), not finite, or not broadcastable.
        """
        u, v = self._params(u, v, tol)
        shape = u.shape
        Sw = self._homogeneous_derivatives(u.ravel(), v.ravel(), 0)[:, 0, 0, :]
        S = Sw[:, :-1] / Sw[:, -1:]
        return S.reshape(shape + (self.dimension,))

    __call__ = evaluate

    def evaluate_grid(self, us, vs, tol: Tolerance | None = None) -> np.ndarray:
        """Points on the tensor grid ``us × vs``.

        Parameters
        ----------
        us : (a,) array_like
        vs : (b,) array_like

        Returns
        -------
        (a, b, d) float64
        """
        t = resolve(tol)
        us = np.atleast_1d(_b.check_parameters(us, self.domain_u, t, what="u")).ravel()
        vs = np.atleast_1d(_b.check_parameters(vs, self.domain_v, t, what="v")).ravel()
        nu, nv = self.shape
        d = self.dimension
        rational = self.is_rational
        net = self.homogeneous if rational else self.control_points
        # v first, through a sparse collocation matrix: T[b, i, :] = sum_j Bv[b, j] P[i, j, :] (small).
        Bv = _b.basis_matrix(self.knots_v, self.degree_v, vs)
        T = (Bv @ net.transpose(1, 0, 2).reshape(nv, -1)).reshape(len(vs), nu, net.shape[2])
        T = np.ascontiguousarray(T.transpose(1, 0, 2)).reshape(nu, -1)
        # Then u as one dense GEMM per block of rows, Bu (a, nu) @ T (nu, b*d), which writes
        # the (a, b, d) result contiguously; blocks bound the dense matrix to a few MB.
        out = np.empty((len(us), len(vs), d))
        flat = out.reshape(len(us), -1)
        block = max(1, CHUNK * 16 // max(nu, len(vs)))
        for s in range(0, len(us), block):
            Bu = _b.basis_matrix(self.knots_u, self.degree_u, us[s : s + block]).toarray()
            if rational:
                Sw = (Bu @ T).reshape(Bu.shape[0], len(vs), d + 1)
                np.divide(Sw[..., :d], Sw[..., d:], out=out[s : s + block])
            else:
                np.matmul(Bu, T, out=flat[s : s + block])
        return out

    def derivatives(self, u, v, order: int = 1, tol: Tolerance | None = None) -> np.ndarray:
        """Partial derivatives ``∂^(k+l) S / ∂u^k ∂v^l`` for all ``k, l <= order`` (The NURBS Book A3.6, A4.4).

        Returns
        -------
        shape + (order + 1, order + 1, d) float64
            ``[..., k, l, :]``; ``[..., 0, 0, :]`` is the point.
        """
        if not isinstance(order, (int, np.integer)) or order < 0:
            raise InvalidInputError(f"order must be an integer >= 0, got {order!r}")
        order = int(order)
        u, v = self._params(u, v, tol)
        shape = u.shape
        A = self._homogeneous_derivatives(u.ravel(), v.ravel(), order)
        Aw, w = A[..., :-1], A[..., -1]
        S = np.empty_like(Aw)
        binom = binomials(order)
        for k in range(order + 1):
            for l in range(order + 1):
                t = Aw[:, k, l, :].copy()
                for j in range(1, l + 1):
                    t -= binom[l, j] * w[:, 0, j, None] * S[:, k, l - j, :]
                for i in range(1, k + 1):
                    t -= binom[k, i] * w[:, i, 0, None] * S[:, k - i, l, :]
                    t2 = np.zeros_like(t)
                    for j in range(1, l + 1):
                        t2 += binom[l, j] * w[:, i, j, None] * S[:, k - i, l - j, :]
                    t -= binom[k, i] * t2
                S[:, k, l, :] = t / w[:, 0, 0, None]
        return S.reshape(shape + (order + 1, order + 1, self.dimension))

    def normal(self, u, v, tol: Tolerance | None = None) -> np.ndarray:
        """Unit normals ``Su × Sv / |Su × Sv|`` (limits at degenerate points); see :mod:`coons.kernel.differential`."""
        from coons.kernel import differential

        return differential.surface_normal(self, u, v, tol)

    # ------------------------------------------------------------------ queries
    def bounding_box(self) -> np.ndarray:
        """Bounding box of the control net (contains the surface), ``(2, d)``."""
        P = self.control_points.reshape(-1, self.dimension)
        return np.stack([P.min(axis=0), P.max(axis=0)])

    def is_close(self, other: "NurbsSurface", tol: Tolerance | None = None, samples: int = 16) -> bool:
        """True if both surfaces share their domain and agree within ``tol.linear`` on a sample grid per span."""
        t = resolve(tol)
        if not isinstance(other, NurbsSurface) or other.dimension != self.dimension:
            return False
        grids = []
        for (a0, a1), (b0, b1), ka, kb in (
            (self.domain_u, other.domain_u, self.knots_u, other.knots_u),
            (self.domain_v, other.domain_v, self.knots_v, other.knots_v),
        ):
            scale = max(1.0, a1 - a0)
            if abs(a0 - b0) > t.solver * scale or abs(a1 - b1) > t.solver * scale:
                return False
            k = np.union1d(np.unique(ka), np.unique(kb))
            k = k[(k >= a0) & (k <= a1)]
            s = np.linspace(0.0, 1.0, samples, endpoint=False)
            grids.append(np.append((k[:-1, None] + np.diff(k)[:, None] * s).ravel(), a1))
        A = self.evaluate_grid(*grids)
        B = other.evaluate_grid(*grids)
        return bool(np.max(np.linalg.norm(A - B, axis=-1)) <= t.linear)

    # ------------------------------------------------------------------ new surfaces
    def transformed(self, matrix) -> "NurbsSurface":
        """The surface under an affine map (3-D surfaces)."""
        if self.dimension != 3:
            raise InvalidInputError(f"transformed needs a 3-D surface, this one has dimension {self.dimension}")
        T = as_transform(matrix)
        P = self.control_points @ T[:3, :3].T + T[:3, 3]
        return NurbsSurface(P, self.knots_u, self.knots_v, self.degree_u, self.degree_v, self.weights)

    def transposed(self) -> "NurbsSurface":
        """Swap the roles of ``u`` and ``v`` (flips the normal)."""
        return NurbsSurface(
            self.control_points.transpose(1, 0, 2),
            self.knots_v,
            self.knots_u,
            self.degree_v,
            self.degree_u,
            self.weights.T,
        )

    def reversed(self, direction: str = "u") -> "NurbsSurface":
        """Reverse the ``"u"`` or ``"v"`` direction over the same domain (flips the normal)."""
        if direction == "u":
            a, b = self.domain_u
            return NurbsSurface(
                self.control_points[::-1], (a + b) - self.knots_u[::-1], self.knots_v,
                self.degree_u, self.degree_v, self.weights[::-1],
            )
        if direction == "v":
            a, b = self.domain_v
            return NurbsSurface(
                self.control_points[:, ::-1], self.knots_u, (a + b) - self.knots_v[::-1],
                self.degree_u, self.degree_v, self.weights[:, ::-1],
            )
        raise InvalidInputError(f"direction must be 'u' or 'v', got {direction!r}")

    def reparametrized(self, domain_u: tuple[float, float], domain_v: tuple[float, float]) -> "NurbsSurface":
        """The same surface over new domains (affine maps of each knot vector)."""
        try:
            knots = [
                _b.mapped_knots(self.knots_u, self.degree_u, *domain_u),
                _b.mapped_knots(self.knots_v, self.degree_v, *domain_v),
            ]
        except InvalidInputError as exc:
            raise InvalidInputError(f"reparametrized: {exc}") from None
        return NurbsSurface(self.control_points, knots[0], knots[1], self.degree_u, self.degree_v, self.weights)

    # ------------------------------------------------------------------ delegated algorithms
    def insert_knot(self, direction: str, value: float, times: int = 1, tol: Tolerance | None = None) -> "NurbsSurface":
        """Insert a knot in the ``"u"`` or ``"v"`` direction (The NURBS Book A5.3)."""
        from coons.kernel import refine

        return refine.surface_insert_knot(self, direction, value, times, tol)

    def refine_knots(self, direction: str, new_knots, tol: Tolerance | None = None) -> "NurbsSurface":
        """Insert many knots in one direction (The NURBS Book A5.5)."""
        from coons.kernel import refine

        return refine.surface_refine_knots(self, direction, new_knots, tol)

    def remove_knot(self, direction: str, value: float, times: int = 1, tol: Tolerance | None = None) -> "NurbsSurface":
        """Remove a knot in one direction while the surface moves less than ``tol.linear``."""
        from coons.kernel import refine

        return refine.surface_remove_knot(self, direction, value, times, tol)

    def elevate_degree(self, times_u: int = 0, times_v: int = 0) -> "NurbsSurface":
        """Raise the degrees without changing the surface (The NURBS Book A5.10)."""
        from coons.kernel import refine

        return refine.surface_elevate_degree(self, times_u, times_v)

    def split(self, direction: str, value: float, tol: Tolerance | None = None) -> tuple["NurbsSurface", "NurbsSurface"]:
        """Split at an iso-parameter into two clamped surfaces."""
        from coons.kernel import refine

        return refine.surface_split(self, direction, value, tol)

    def bezier_patches(self) -> list[list["NurbsSurface"]]:
        """Decomposition into Bézier patches, ``[i][j]`` over span ``i`` in u and ``j`` in v."""
        from coons.kernel import refine

        return refine.surface_bezier_patches(self)

    def iso_curve(self, direction: str, value: float, tol: Tolerance | None = None) -> "NurbsCurve":
        """The iso-parametric curve ``u = value`` (``direction="u"``: a curve in v) or ``v = value``."""
        from coons.kernel import refine

        return refine.surface_iso_curve(self, direction, value, tol)

    def closest_parameters(self, points, tol: Tolerance | None = None) -> np.ndarray:
        """``(..., 2)`` parameters of the closest surface points; see :mod:`coons.kernel.projection`."""
        from coons.kernel import projection

        return projection.surface_closest_parameters(self, points, tol)

    def closest_points(self, points, tol: Tolerance | None = None) -> "ClosestPoints":
        from coons.kernel import projection

        return projection.surface_closest_points(self, points, tol)

    def invert(self, points, tol: Tolerance | None = None) -> np.ndarray:
        """Parameters ``(..., 2)`` of points on the surface; ``ConvergenceError`` for points off it."""
        from coons.kernel import projection

        return projection.surface_invert(self, points, tol)

    def fundamental_forms(self, u, v, tol: Tolerance | None = None):
        """First ``(E, F, G)`` and second ``(L, M, N)`` fundamental forms; see :mod:`coons.kernel.differential`."""
        from coons.kernel import differential

        return differential.surface_fundamental_forms(self, u, v, tol)

    def curvatures(self, u, v, tol: Tolerance | None = None):
        """Gaussian, mean and principal curvatures and directions; see :mod:`coons.kernel.differential`."""
        from coons.kernel import differential

        return differential.surface_curvatures(self, u, v, tol)
