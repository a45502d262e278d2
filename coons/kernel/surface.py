"""NURBS surfaces: an immutable tensor-product value over read-only float64 arrays.

:class:`NurbsSurface` holds control points ``(nu, nv, d)``, knot vectors in ``u``
and ``v``, degrees ``(pu, pv)`` and positive weights ``(nu, nv)``.  Scattered
evaluation (``evaluate(u, v)``, ``derivatives`` with broadcasting) gathers the
``(pu+1)(pv+1)`` control points of each parameter pair (homogeneous ones only when
the surface is rational) and contracts them with the basis values, in chunks of
contiguous 1-D arrays; batches of :data:`coons.kernel._accel.THRESHOLD` points or
more go to the optional numba kernels of :mod:`coons.kernel._accel`, which do the
same operations.  Grid evaluation (``evaluate_grid``, ``derivatives_grid``)
multiplies collocation matrices ``Bu^(k) @ Pw @ Bv^(l)T`` (The NURBS Book A3.5/A4.3
in matrix form, Cohen–Riesenfeld–Elber ch. 13).

Small batches (fewer than :data:`_SMALL` points: checking, projecting and inverting the
edges of a model a few points at a time) take a path with as few numpy calls as possible
(per-call overhead dominates there): cached last spans and net rows, first basis
derivatives in closed form (:func:`coons.kernel.basis.basis_first_derivatives`), one
gather and two einsums.  :class:`NurbsSurfaceStack` evaluates many surfaces of one
structure (degrees, knots, net shape) in one batch, each point on its own surface: the
mass properties of a model of a thousand patches then cost a few numpy passes.

Knot operations, differential geometry and projection are in
:mod:`coons.kernel.refine`, :mod:`coons.kernel.differential` and
:mod:`coons.kernel.projection`; the methods here delegate to them.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property
from typing import TYPE_CHECKING

import numpy as np
import scipy.sparse as sp

from coons.errors import InvalidGeometryError, InvalidInputError
from coons.kernel import _accel
from coons.kernel import basis as _b
from coons.kernel._common import CHUNK, as_degree, as_points, as_transform, as_weights, binomials
from coons.tolerance import Tolerance, resolve

if TYPE_CHECKING:  # pragma: no cover
    from coons.kernel.curve import NurbsCurve
    from coons.kernel.projection import ClosestPoints

__all__ = ["NurbsSurface", "NurbsSurfaceStack", "derivatives_surfaces", "evaluate_surfaces"]

#: Points per batch of the numpy scattered path.  Its temporaries are 1-D arrays of this
#: length (128 KB), small enough to stay in cache and to be recycled by the allocator rather
#: than page-faulted in afresh for every batch; 16384 measured best among 4096 … 32768.
_CHUNK = 16384
#: Grid points per block of the rational and derivative grid paths: the homogeneous block
#: and the part of the result being written stay in cache (measured among 4096 … 131072).
_GRID_BLOCK = 32768
#: Below this many points a chunk is contracted with one gather and two einsums, which
#: makes fewer numpy calls than the per-coordinate loop (per-call overhead dominates).
_SMALL = 128


def _rational_partials(A: list, binom: np.ndarray, d: int) -> list:
    """Partials of ``S = Sw[:d] / w`` from those of the homogeneous surface (The NURBS Book A4.4).

    ``S_kl = (A_kl - sum_{(i, j) != (0, 0)} C(k, i) C(l, j) w_ij S_{k-i, l-j}) / w``, each
    term subtracted in turn, the division done as one reciprocal per point.
    :mod:`coons.kernel._accel` performs the same operations in the same order.

    Parameters
    ----------
    A : nested lists ``A[k][l][c]`` of float64 arrays (any common shape), ``c < d + 1``
        (the last is the weight)
    binom : (order + 1, order + 1) binomial coefficients

    Returns
    -------
    nested lists ``S[k][l][c]``, ``c < d``
    """
    K = len(A)
    w = [[A[k][l][d] for l in range(K)] for k in range(K)]
    r = 1.0 / w[0][0]
    S: list = [[None] * K for _ in range(K)]
    for k in range(K):
        for l in range(K):
            row = []
            for c in range(d):
                t = A[k][l][c]
                fresh = False  # t is still the caller's array: do not subtract in place
                for i in range(k + 1):
                    for j in range(l + 1):
                        if i == 0 and j == 0:
                            continue
                        x = w[i][j] * S[k - i][l - j][c]
                        coef = binom[k, i] * binom[l, j]
                        if coef != 1.0:
                            x *= coef
                        if fresh:
                            t -= x
                        else:
                            t = t - x
                            fresh = True
                if fresh:
                    t *= r
                else:
                    t = t * r
                row.append(t)
            S[k][l] = row
    return S


def _contract(knots_u: np.ndarray, pu: int, knots_v: np.ndarray, pv: int, nv: int, planes, u: np.ndarray,
              v: np.ndarray, order: int, offset: np.ndarray | None, last: tuple[int, int] | None = None) -> list:
    """Mixed partials of the net given by ``planes`` at one chunk of parameters.

    Basis rows per direction (A2.2 / A2.3), then the tensor contraction of The NURBS
    Book A3.6 in two stages (v, then u), on contiguous 1-D arrays with one gather per
    control point of the local ``(pu+1) × (pv+1)`` window and coordinate; below
    :data:`_SMALL` points, one gather of all windows and two einsums instead.  ``offset``
    ``(m,)`` (or None) is added to every gathered index: the start of each point's net in
    planes that stack several nets of the same shape (:class:`NurbsSurfaceStack`); ``last``
    the cached last spans in ``u`` and ``v`` (:func:`coons.kernel.basis.last_span`).

    Returns
    -------
    A : nested lists ``A[k][l][c]`` of (m,) float64, ``k, l <= order``
    """
    lu, lv = last if last is not None else (None, None)
    su = _b.find_spans(knots_u, pu, u, lu)
    sv = _b.find_spans(knots_v, pv, v, lv)
    if order == 0:
        Nu = [_b.basis_rows(knots_u, pu, su, u)]
        Nv = [_b.basis_rows(knots_v, pv, sv, v)]
    else:
        Nu = _b.basis_derivative_rows(knots_u, pu, su, u, order)
        Nv = _b.basis_derivative_rows(knots_v, pv, sv, v, order)
    base = (su - pu) * nv + (sv - pv)
    if offset is not None:
        base += offset
    D = len(planes)
    if u.shape[0] < _SMALL:
        # Few points: one gather and two einsums cost fewer numpy calls than the
        # per-coordinate loop below (same sums, possibly different round-off).
        window = (np.arange(pu + 1)[:, None] * nv + np.arange(pv + 1))[:, :, None]
        G = np.stack(planes)[:, base + window]  # (D, pu+1, pv+1, m)
        T = np.einsum("ljm,cijm->lcim", np.asarray(Nv), G)
        A = np.einsum("kim,lcim->klcm", np.asarray(Nu), T)
    else:
        A = _contract_loop(Nu, Nv, base, planes, pu, pv, nv)
    # Orders above the degree vanish.
    zero = np.zeros(u.shape[0])
    return [
        [A[k][l] if k < len(Nu) and l < len(Nv) else [zero] * D for l in range(order + 1)]
        for k in range(order + 1)
    ]


def _contract_loop(Nu: list, Nv: list, base: np.ndarray, planes, pu: int, pv: int, nv: int) -> list:
    """``A[k][l][c] = sum_i Nu[k][i] sum_j Nv[l][j] P_c[base + i nv + j]`` on 1-D arrays (A3.6).

    The v sums first, in ``j`` order, then the u sums in ``i`` order: the operations
    the numba surface kernel repeats.
    """
    D = len(planes)
    A: list = [[[None] * D for _ in Nv] for _ in Nu]
    for i in range(pu + 1):
        G = [[P.take(idx) for P in planes] for idx in (base + (i * nv + j) for j in range(pv + 1))]
        for l, Nvl in enumerate(Nv):
            for c in range(D):
                t = Nvl[0] * G[0][c]
                for j in range(1, pv + 1):
                    t += Nvl[j] * G[j][c]
                for k, Nuk in enumerate(Nu):
                    if i == 0:
                        A[k][l][c] = Nuk[0] * t
                    else:
                        A[k][l][c] += Nuk[i] * t
    return A


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
        return bool((w != w.flat[0]).any())

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
        if u.shape == v.shape:
            return u, v
        try:
            u, v = np.broadcast_arrays(u, v)
        except ValueError as exc:
            raise InvalidInputError(f"u and v do not broadcast: shapes {u.shape} and {v.shape}") from exc
        return u, v

    @cached_property
    def _last_spans(self) -> tuple[int, int]:
        """The last non-empty knot span in ``u`` and ``v`` (:func:`coons.kernel.basis.last_span`)."""
        return _b.last_span(self.knots_u, self.degree_u), _b.last_span(self.knots_v, self.degree_v)

    @cached_property
    def _net_rows(self) -> np.ndarray:
        """The net's coordinate planes as rows ``(D, nu * nv)`` (one copy; :attr:`_planes` are its
        rows): ``P`` for a polynomial surface, ``[w P, w]`` for a rational one."""
        net = self.homogeneous if self.is_rational else self.control_points
        return np.ascontiguousarray(net.reshape(-1, net.shape[2]).T)

    def _small_derivatives(self, u: np.ndarray, v: np.ndarray, order: int) -> np.ndarray:
        """:meth:`_derivatives_flat` for fewer than :data:`_SMALL` points, ``(m, order+1, order+1, d)``.

        Per-call overhead dominates there (the edges of a model are checked and projected a few
        points at a time), so the path makes as few numpy calls as it can: spans by one binary
        search per direction (cached last span), first derivatives of the basis by
        :func:`coons.kernel.basis.basis_first_derivatives`, one gather of all ``(pu+1)(pv+1)``
        windows of the stacked net and two einsums straight into the output layout.  The same
        values as :func:`_contract` to round-off.
        """
        pu, pv = self.degree_u, self.degree_v
        lu, lv = self._last_spans
        # np.maximum/np.minimum rather than np.clip: the ufuncs skip np.clip's Python wrapper.
        su = np.maximum(np.minimum(np.searchsorted(self.knots_u, u, side="right") - 1, lu), pu)
        sv = np.maximum(np.minimum(np.searchsorted(self.knots_v, v, side="right") - 1, lv), pv)
        if order == 0:
            Nu = [_b.basis_rows(self.knots_u, pu, su, u)]
            Nv = [_b.basis_rows(self.knots_v, pv, sv, v)]
        elif order == 1:
            Nu = _b.basis_first_derivatives(self.knots_u, pu, su, u)
            Nv = _b.basis_first_derivatives(self.knots_v, pv, sv, v)
        else:
            Nu = _b.basis_derivative_rows(self.knots_u, pu, su, u, order)
            Nv = _b.basis_derivative_rows(self.knots_v, pv, sv, v, order)
        nv = self.shape[1]
        window = self._small_window
        G = self._net_rows[:, ((su - pu) * nv + (sv - pv)) + window]  # (D, pu+1, pv+1, m)
        T = np.einsum("ljm,cijm->lcim", np.asarray(Nv), G)
        A = np.einsum("kim,lcim->mklc", np.asarray(Nu), T)  # (m, ku, kv, D)
        d = self.dimension
        if self.is_rational:
            K = order + 1
            zero = np.zeros(u.shape[0])
            D = A.shape[3]
            L = [[[A[:, k, l, c] if k < A.shape[1] and l < A.shape[2] else zero for c in range(D)] for l in range(K)]
                 for k in range(K)]
            S = _rational_partials(L, binomials(order), d)
            out = np.empty((u.shape[0], K, K, d))
            for k in range(K):
                for l in range(K):
                    for c in range(d):
                        out[:, k, l, c] = S[k][l][c]
            return out
        if A.shape[1] == order + 1 and A.shape[2] == order + 1:
            return A
        # Orders above the degree vanish.
        out = np.zeros((u.shape[0], order + 1, order + 1, d))
        out[:, : A.shape[1], : A.shape[2]] = A
        return out

    @cached_property
    def _small_window(self) -> np.ndarray:
        nv = self.shape[1]
        return (np.arange(self.degree_u + 1)[:, None] * nv + np.arange(self.degree_v + 1))[:, :, None]

    @cached_property
    def _planes(self) -> tuple[np.ndarray, ...]:
        """Coordinate planes of the net the evaluation contracts, each ``(nu * nv,)`` contiguous.

        ``d`` planes of ``P`` for a polynomial surface (no weight channel, no divide),
        ``d + 1`` planes of ``[w P, w]`` for a rational one.
        """
        return tuple(self._net_rows)

    @cached_property
    def _homogeneous_planes(self) -> tuple[np.ndarray, ...]:
        H = self.homogeneous
        return tuple(np.ascontiguousarray(H[:, :, c]).ravel() for c in range(H.shape[2]))

    def _contract_chunk(self, u: np.ndarray, v: np.ndarray, order: int, planes) -> list:
        """Mixed partials of the net given by ``planes`` at one chunk of parameters (:func:`_contract`).

        Returns
        -------
        A : nested lists ``A[k][l][c]`` of (m,) float64, ``k, l <= order``
        """
        return _contract(self.knots_u, self.degree_u, self.knots_v, self.degree_v, self.shape[1], planes,
                         u, v, order, None, self._last_spans)

    def _homogeneous_derivatives(self, u: np.ndarray, v: np.ndarray, order: int) -> np.ndarray:
        """Mixed partials of the homogeneous surface, ``(m, order+1, order+1, d+1)``, flat ``u, v``.

        The numpy reference for :mod:`coons.kernel._accel` (no rational correction).
        """
        m = u.shape[0]
        planes = self._homogeneous_planes
        out = np.empty((m, order + 1, order + 1, len(planes)))
        for s in range(0, m, _CHUNK):
            A = self._contract_chunk(u[s : s + _CHUNK], v[s : s + _CHUNK], order, planes)
            for k in range(order + 1):
                for l in range(order + 1):
                    for c in range(len(planes)):
                        out[s : s + _CHUNK, k, l, c] = A[k][l][c]
        return out

    def _derivatives_flat(self, u: np.ndarray, v: np.ndarray, order: int) -> np.ndarray:
        """Cartesian mixed partials ``(m, order+1, order+1, d)`` at flat ``u, v`` inside the domain.

        Large batches go to the compiled kernel of :mod:`coons.kernel._accel` when it is
        available; otherwise numpy, in chunks of :data:`_CHUNK` points.
        """
        m = u.shape[0]
        rational = self.is_rational
        if m >= _accel.THRESHOLD and _accel.AVAILABLE:
            net = self.homogeneous if rational else self.control_points
            out = _accel.surface_derivatives(
                self.knots_u, self.degree_u, self.knots_v, self.degree_v, net, u, v, order, rational
            )
            if out is not None:
                return out
        if m < _SMALL:
            return self._small_derivatives(u, v, order)
        d = self.dimension
        planes = self._planes
        out = np.empty((m, order + 1, order + 1, d))
        binom = binomials(order)
        for s in range(0, m, _CHUNK):
            A = self._contract_chunk(u[s : s + _CHUNK], v[s : s + _CHUNK], order, planes)
            if rational:
                A = _rational_partials(A, binom, d)
            blk = out[s : s + _CHUNK]
            for k in range(order + 1):
                for l in range(order + 1):
                    for c in range(d):
                        blk[:, k, l, c] = A[k][l][c]
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
        S = self._derivatives_flat(u.ravel(), v.ravel(), 0)
        return S.reshape(shape + (self.dimension,))

    __call__ = evaluate

    def _grid_params(self, us, vs, tol: Tolerance | None) -> tuple[np.ndarray, np.ndarray]:
        t = resolve(tol)
        us = np.atleast_1d(_b.check_parameters(us, self.domain_u, t, what="u")).ravel()
        vs = np.atleast_1d(_b.check_parameters(vs, self.domain_v, t, what="v")).ravel()
        return us, vs

    def _grid_v_stage(self, vs: np.ndarray, order: int, planes: bool) -> np.ndarray:
        """First stage of grid evaluation, ``T[i, l, j, c] = sum_s N_s^(l)(vs[j]) Pw[i, s, c]``.

        Sparse collocation matrices (one per derivative order ``l``) times the net; the
        result is small (``nu × b`` points).

        Returns
        -------
        (nu, K * b * D) float64, K = order + 1, D = d (polynomial) or d + 1 (homogeneous)
            Columns ordered ``(j, l, c)``, or ``(l, c, j)`` when ``planes`` (each
            coordinate of each order contiguous over the grid row, for the quotient rule).
        """
        nu, nv = self.shape
        net = self.homogeneous if self.is_rational else self.control_points
        D = net.shape[2]
        flat = net.transpose(1, 0, 2).reshape(nv, nu * D)
        T = np.stack([
            (_b.basis_matrix(self.knots_v, self.degree_v, vs, l) @ flat).reshape(len(vs), nu, D)
            for l in range(order + 1)
        ])  # (K, b, nu, D)
        axes = (2, 0, 3, 1) if planes else (2, 1, 0, 3)
        return np.ascontiguousarray(T.transpose(axes)).reshape(nu, -1)

    def _u_basis_values(self, us: np.ndarray, order: int) -> tuple[np.ndarray, np.ndarray]:
        """Non-zero u-basis values of every grid row: columns ``(a, pu + 1)`` and ``ders (a, K, pu + 1)`` (A2.2/A2.3)."""
        p = self.degree_u
        spans = _b.find_spans(self.knots_u, p, us)
        if order == 0:
            ders = _b.basis_functions(self.knots_u, p, spans, us)[:, None, :]
        else:
            ders = _b.basis_derivatives(self.knots_u, p, spans, us, order)
        return spans[:, None] - p + np.arange(p + 1), ders

    def _u_block_matrices(self, cols: np.ndarray, ders: np.ndarray) -> list:
        """Sparse collocation matrices ``B_k[i, s] = N_s^(k)(u_i)`` of a block of rows, ``K × (rows, nu)`` CSR.

        Sparse, not dense: the product with the first-stage result then runs in scipy's
        single-threaded CSR kernel, ``p + 1`` multiply-adds per row instead of ``nu``, and
        does not depend on BLAS threads, which on a loaded 2-core machine turn many small
        GEMMs into waits for a descheduled worker (measured 20× slower).
        """
        m, p1 = cols.shape
        indptr = np.arange(0, m * p1 + 1, p1)
        indices = cols.ravel()
        shape = (m, self.shape[0])
        return [sp.csr_matrix((ders[:, k].ravel(), indices, indptr), shape=shape) for k in range(ders.shape[1])]

    def evaluate_grid(self, us, vs, tol: Tolerance | None = None) -> np.ndarray:
        """Points on the tensor grid ``us × vs``.

        Two-stage contraction ``Bu @ (Pw @ Bv^T)`` (The NURBS Book A3.5/A4.3 in matrix
        form): a sparse product in v, then, for a polynomial surface, one dense GEMM per
        large block of rows in u that writes the result in place; for a rational one a
        sparse product per block of rows small enough that the homogeneous block stays in
        cache while it is projected with one reciprocal of the weight and ``d`` products.

        Parameters
        ----------
        us : (a,) array_like
        vs : (b,) array_like

        Returns
        -------
        (a, b, d) float64

        Raises
        ------
        InvalidInputError
            Parameters outside the domain (beyond round-off) or not finite.
        """
        us, vs = self._grid_params(us, vs, tol)
        a, b = len(us), len(vs)
        nu = self.shape[0]
        d = self.dimension
        out = np.empty((a, b, d))
        if a == 0 or b == 0:
            return out
        if not self.is_rational:
            T = self._grid_v_stage(vs, 0, planes=False)
            flat = out.reshape(a, -1)
            # Bu (rows, nu) @ T (nu, b*d) writes the (rows, b, d) result contiguously; blocks
            # bound the dense Bu to a few MB.
            block = max(1, CHUNK * 16 // max(nu, b))
            for s in range(0, a, block):
                Bu = _b.basis_matrix(self.knots_u, self.degree_u, us[s : s + block]).toarray()
                np.matmul(Bu, T, out=flat[s : s + block])
            return out
        T = self._grid_v_stage(vs, 0, planes=True)
        cols, vals = self._u_basis_values(us, 0)
        # Blocks of about _GRID_BLOCK points: the homogeneous block stays in cache for the projection.
        rows = max(1, _GRID_BLOCK // b)
        for s in range(0, a, rows):
            (Bu,) = self._u_block_matrices(cols[s : s + rows], vals[s : s + rows])
            Sw = (Bu @ T).reshape(Bu.shape[0], d + 1, b)
            r = np.divide(1.0, Sw[:, d])
            for c in range(d):
                np.multiply(Sw[:, c], r, out=out[s : s + rows, :, c])
        return out

    def derivatives_grid(self, us, vs, order: int = 1, tol: Tolerance | None = None) -> np.ndarray:
        """Partial derivatives ``∂^(k+l) S / ∂u^k ∂v^l``, ``k, l <= order``, on the tensor grid ``us × vs``.

        The two-stage contraction of :meth:`evaluate_grid` with derivative collocation
        matrices (The NURBS Book A2.3 in matrix form, Cohen–Riesenfeld–Elber ch. 13):
        ``A_kl = Bu^(k) @ Pw @ Bv^(l)T``, a sparse product in v for all ``l`` at once, then
        one sparse product per ``k`` and block of rows; rational surfaces get the quotient
        rule (The NURBS Book A4.4) vectorised over each block while it is in cache.
        Equal to :meth:`derivatives` at the broadcast parameters ``(us[:, None], vs[None, :])``
        up to round-off.

        Parameters
        ----------
        us : (a,) array_like
        vs : (b,) array_like
        order : int >= 0

        Returns
        -------
        (a, b, order + 1, order + 1, d) float64
            ``[i, j, k, l, :]`` is ``∂^(k+l) S / ∂u^k ∂v^l`` at ``(us[i], vs[j])``.

        Raises
        ------
        InvalidInputError
            ``order`` not an integer >= 0; parameters outside the domain (beyond round-off)
            or not finite.
        """
        if isinstance(order, bool) or not isinstance(order, (int, np.integer)) or order < 0:
            raise InvalidInputError(f"order must be an integer >= 0, got {order!r}")
        order = int(order)
        us, vs = self._grid_params(us, vs, tol)
        a, b = len(us), len(vs)
        d = self.dimension
        K = order + 1
        out = np.empty((a, b, K, K, d))
        if a == 0 or b == 0:
            return out
        rational = self.is_rational
        T = self._grid_v_stage(vs, order, planes=rational)
        binom = binomials(order)
        # Blocks of about _GRID_BLOCK grid points: the homogeneous block and the written part
        # of ``out`` stay in cache between the K products and the quotient rule.
        cols, ders = self._u_basis_values(us, order)
        rows = max(1, _GRID_BLOCK // b)
        for s in range(0, a, rows):
            Bu = self._u_block_matrices(cols[s : s + rows], ders[s : s + rows])
            m = Bu[0].shape[0]
            blk = out[s : s + rows]
            if not rational:
                for k in range(K):
                    blk[:, :, k] = (Bu[k] @ T).reshape(m, b, K, d)
                continue
            R = [(Bu[k] @ T).reshape(m, K, d + 1, b) for k in range(K)]
            A = [[[R[k][:, l, c] for c in range(d + 1)] for l in range(K)] for k in range(K)]
            S = _rational_partials(A, binom, d)
            for k in range(K):
                for l in range(K):
                    for c in range(d):
                        blk[:, :, k, l, c] = S[k][l][c]
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
        S = self._derivatives_flat(u.ravel(), v.ravel(), order)
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


class NurbsSurfaceStack:
    """Several :class:`NurbsSurface` of one structure, evaluated together as one batch.

    Surfaces with equal degrees, knot vectors, net shape, dimension and rationality (equal
    :meth:`key`) share their basis functions at a parameter; only the control points differ.
    The stack concatenates their nets (the same coordinate planes as each surface's own
    evaluation, one after the other) so that the points of many surfaces (a model of a
    thousand bilinear patches, say) are evaluated in a few numpy passes instead of one call
    per surface: :meth:`derivatives` takes, per point, the index of its surface in the stack.
    The sums are those of :meth:`NurbsSurface.derivatives` on the numpy path (the numba
    kernel is not used), so each point agrees with its surface's own evaluation to round-off.

    Parameters
    ----------
    surfaces : sequence of NurbsSurface, non-empty, all with the same :meth:`key`

    Raises
    ------
    InvalidInputError
        An empty sequence, or surfaces of different structure.
    """

    def __init__(self, surfaces) -> None:
        surfaces = list(surfaces)
        if not surfaces or not all(isinstance(S, NurbsSurface) for S in surfaces):
            raise InvalidInputError("NurbsSurfaceStack: expected a non-empty sequence of NurbsSurface")
        k = self.key(surfaces[0])
        for i, S in enumerate(surfaces[1:], 1):
            if self.key(S) != k:
                raise InvalidInputError(
                    f"NurbsSurfaceStack: surface {i} has another structure (degrees, knots, net shape, dimension or "
                    "rationality) than surface 0"
                )
        S0 = surfaces[0]
        self.surfaces = tuple(surfaces)
        self.degree_u, self.degree_v = S0.degree_u, S0.degree_v
        self.knots_u, self.knots_v = S0.knots_u, S0.knots_v
        self.domain = S0.domain
        self.dimension = S0.dimension
        self.rational = S0.is_rational
        nu, nv = S0.shape
        self._nv, self._size = nv, nu * nv
        self._last = S0._last_spans
        self._planes = tuple(np.concatenate([S._net_rows for S in surfaces], axis=1))

    @staticmethod
    def key(S: NurbsSurface) -> tuple:
        """Structure of ``S``: surfaces with equal keys can share a :class:`NurbsSurfaceStack`."""
        return (S.degree_u, S.degree_v, S.shape, S.dimension, S.is_rational, S.knots_u.tobytes(), S.knots_v.tobytes())

    def __len__(self) -> int:
        return len(self.surfaces)

    def derivatives(self, which: np.ndarray, u: np.ndarray, v: np.ndarray, order: int = 1) -> np.ndarray:
        """Mixed partials ``(m, order+1, order+1, d)`` of surface ``which[i]`` at ``(u[i], v[i])``.

        Parameters
        ----------
        which : (m,) int, indices into the stack
        u, v : (m,) float64, inside the (common) domain: not checked or clamped (the caller's
            parameters come from its own geometry; see :meth:`NurbsSurface.derivatives` for the
            checked form)
        order : int >= 0
        """
        which = np.asarray(which, dtype=np.int64)
        u = np.asarray(u, dtype=np.float64)
        v = np.asarray(v, dtype=np.float64)
        m, d = u.shape[0], self.dimension
        out = np.empty((m, order + 1, order + 1, d))
        binom = binomials(order)
        for s in range(0, m, _CHUNK):
            sl = slice(s, s + _CHUNK)
            A = _contract(self.knots_u, self.degree_u, self.knots_v, self.degree_v, self._nv, self._planes,
                          u[sl], v[sl], order, which[sl] * self._size, self._last)
            if self.rational:
                A = _rational_partials(A, binom, d)
            blk = out[sl]
            for k in range(order + 1):
                for l in range(order + 1):
                    for c in range(d):
                        blk[:, k, l, c] = A[k][l][c]
        return out


def evaluate_surfaces(surfaces, index, u, v, tol: Tolerance | None = None) -> np.ndarray:
    """Points of many surfaces at once: ``surfaces[index[i]]`` at ``(u[i], v[i])``, ``(m, 3)``.

    :func:`derivatives_surfaces` of order 0; see there.

    Raises
    ------
    InvalidInputError
        As :func:`derivatives_surfaces`.
    """
    return derivatives_surfaces(surfaces, index, u, v, 0, tol)[:, 0, 0]


def derivatives_surfaces(surfaces, index, u, v, order: int = 1, tol: Tolerance | None = None) -> np.ndarray:
    """Partials of many surfaces at once: ``surfaces[index[i]]`` at ``(u[i], v[i])``, ``(m, order+1, order+1, 3)``.

    For callers that evaluate a few points on each of many faces (checking, tessellating or
    projecting a model's edges): the :class:`NurbsSurface` entries are grouped by structure
    (:meth:`NurbsSurfaceStack.key`) and each group is evaluated in one batch; planes and surfaces
    of revolution all together (:func:`coons.kernel.analytic.surface_derivatives`); any other
    surface type (anything with ``derivatives(u, v, order)``) is called once per distinct surface.
    Parameters are checked and clamped as :meth:`NurbsSurface.derivatives` does.

    Parameters
    ----------
    surfaces : sequence of surfaces
    index : (m,) int, into ``surfaces``
    u, v : (m,) float
    order : int >= 0

    Raises
    ------
    InvalidInputError
        An index out of range, a bad order, or parameters outside a surface's domain (beyond
        round-off) or not finite.
    """
    if not isinstance(order, (int, np.integer)) or order < 0:
        raise InvalidInputError(f"order must be an integer >= 0, got {order!r}")
    order = int(order)
    index = np.asarray(index, dtype=np.int64).ravel()
    u = np.asarray(u, dtype=np.float64).ravel()
    v = np.asarray(v, dtype=np.float64).ravel()
    m = index.size
    if u.size != m or v.size != m:
        raise InvalidInputError(f"derivatives_surfaces: index, u and v must have one size, got {m}, {u.size}, {v.size}")
    if m and (index.min() < 0 or index.max() >= len(surfaces)):
        raise InvalidInputError(f"derivatives_surfaces: surface index out of range [0, {len(surfaces)})")
    out = np.empty((m, order + 1, order + 1, 3))
    if m == 0:
        return out
    t = resolve(tol)
    # Planes and surfaces of revolution: one expression per type for all their rows.
    from coons.kernel.analytic import BATCHED_SURFACES, surface_derivatives

    ids, inverse = np.unique(index, return_inverse=True)
    batched = np.array([isinstance(surfaces[i], BATCHED_SURFACES) for i in ids.tolist()], dtype=bool)
    if batched.any():
        rows = np.flatnonzero(batched[inverse])
        out[rows] = surface_derivatives([surfaces[i] for i in ids.tolist()], u[rows], v[rows], order, inverse[rows])
        if rows.size == m:
            return out
        keep = np.flatnonzero(~batched[inverse])
    else:
        keep = np.arange(m)
    for members, sub, local in structure_groups(surfaces, index[keep]):
        rows = keep[sub]
        first = surfaces[members[0]]
        if len(members) == 1 or not isinstance(first, NurbsSurface):
            D = first.derivatives(u[rows], v[rows], order, t) if isinstance(first, NurbsSurface) \
                else first.derivatives(u[rows], v[rows], order)
            out[rows] = np.asarray(D, dtype=np.float64).reshape(-1, order + 1, order + 1, 3)
            continue
        stack = NurbsSurfaceStack([surfaces[k] for k in members])
        uu = _b.check_parameters(u[rows], stack.domain[0], t, what="u")
        vv = _b.check_parameters(v[rows], stack.domain[1], t, what="v")
        out[rows] = stack.derivatives(local, uu, vv, order)
    return out


def structure_groups(surfaces, index: np.ndarray) -> list[tuple[list[int], np.ndarray, np.ndarray]]:
    """The rows of ``index`` (into ``surfaces``) grouped by surface structure, for batched evaluation.

    Returns ``[(members, rows, local), ...]``: per group the distinct surface ids ``members`` of
    one :meth:`NurbsSurfaceStack.key` (3-D NURBS of equal degrees, knots, net shape and
    rationality; any other surface is a group of its own), the rows ``rows`` of ``index`` on
    them (in increasing order), and for each row the position ``local`` of its surface in
    ``members``.
    """
    index = np.asarray(index, dtype=np.int64).ravel()
    ids, inverse = np.unique(index, return_inverse=True)
    groups: dict = {}
    for k, si in enumerate(ids.tolist()):
        S = surfaces[si]
        key = NurbsSurfaceStack.key(S) if isinstance(S, NurbsSurface) and S.dimension == 3 else ("single", k)
        groups.setdefault(key, []).append(k)
    gid = np.empty(ids.size, dtype=np.int64)
    slot = np.empty(ids.size, dtype=np.int64)
    for g, members in enumerate(groups.values()):
        gid[members] = g
        slot[members] = np.arange(len(members))
    point_group = gid[inverse]
    order = np.argsort(point_group, kind="stable")
    bounds = np.searchsorted(point_group[order], np.arange(len(groups) + 1))
    out = []
    for g, members in enumerate(groups.values()):
        rows = order[bounds[g] : bounds[g + 1]]
        out.append(([int(ids[k]) for k in members], rows, slot[inverse[rows]]))
    return out
