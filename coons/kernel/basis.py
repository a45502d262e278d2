"""B-spline basis functions and knot vectors, vectorised over many parameters.

Formulas only: knot-vector validation, span search, basis functions and their
derivatives (Cox–de Boor recursion in the triangular form of The NURBS Book A2.2
and A2.3; Cohen–Riesenfeld–Elber ch. 6), and sparse basis matrices for grids.
Every function takes arrays of parameters and loops in Python only over the
degree and the derivative order, never over parameters.

Conventions: a B-spline of degree ``p`` with ``n`` coefficients has a knot vector
``U`` of length ``n + p + 1``; its domain is ``[U[p], U[n]]``, which covers clamped
(end knots of multiplicity ``p + 1``), floating and periodic (uniform, unclamped)
knot vectors alike.  Spans are the indices ``i`` in ``[p, n - 1]`` with
``U[i] <= u < U[i + 1]``, the last non-empty span being closed on the right.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from coons.errors import InvalidGeometryError, InvalidInputError
from coons.tolerance import Tolerance

__all__ = [
    "as_knot_vector",
    "domain_of",
    "check_parameters",
    "find_spans",
    "basis_functions",
    "basis_derivatives",
    "basis_matrix",
    "mapped_knots",
    "clamped_uniform_knots",
    "periodic_uniform_knots",
]


def readonly(a: np.ndarray) -> np.ndarray:
    """Return ``a`` marked read-only (in place) for use inside frozen geometry values."""
    a.setflags(write=False)
    return a


def as_knot_vector(knots, degree: int, n_coefficients: int, *, what: str = "knots") -> np.ndarray:
    """Validate and return a knot vector as a read-only float64 array.

    Parameters
    ----------
    knots : (n + p + 1,) array_like
    degree : int, >= 1
    n_coefficients : int
        Number of control points ``n`` the knots go with.

    Raises
    ------
    InvalidGeometryError
        Wrong length, NaN/inf, decreasing values, an empty domain, or a knot inside
        the domain whose multiplicity exceeds ``degree`` (the curve would be
        discontinuous there).
    """
    if not isinstance(degree, (int, np.integer)) or degree < 1:
        raise InvalidGeometryError(f"degree must be an integer >= 1, got {degree!r}")
    U = np.array(knots, dtype=np.float64).ravel()
    expected = n_coefficients + degree + 1
    if U.shape[0] != expected:
        raise InvalidGeometryError(
            f"{what}: expected {expected} knots for {n_coefficients} control points of degree {degree} "
            f"(n + p + 1), got {U.shape[0]}"
        )
    if not np.all(np.isfinite(U)):
        bad = int(np.flatnonzero(~np.isfinite(U))[0])
        raise InvalidGeometryError(f"{what}: knot {bad} is not finite ({U[bad]!r})")
    dec = np.flatnonzero(np.diff(U) < 0)
    if dec.size:
        i = int(dec[0])
        raise InvalidGeometryError(
            f"{what}: knots must be non-decreasing, but knot {i + 1} = {U[i + 1]!r} < knot {i} = {U[i]!r}"
        )
    lo, hi = U[degree], U[n_coefficients]
    if not hi > lo:
        raise InvalidGeometryError(f"{what}: empty domain [U[p], U[n]] = [{lo!r}, {hi!r}]")
    # Inside the open domain a knot of multiplicity > p would make the curve discontinuous.
    interior = U[degree + 1 : n_coefficients]
    if interior.size:
        vals, counts = np.unique(interior, return_counts=True)
        too_many = counts > degree
        if np.any(too_many):
            j = int(np.flatnonzero(too_many)[0])
            raise InvalidGeometryError(
                f"{what}: interior knot {vals[j]!r} has multiplicity {counts[j]}, at most degree = {degree} allowed"
            )
    return readonly(U)


def domain_of(knots: np.ndarray, degree: int) -> tuple[float, float]:
    """The parametric domain ``(U[p], U[n])`` of a knot vector."""
    n = knots.shape[0] - degree - 1
    return float(knots[degree]), float(knots[n])


def check_parameters(u, domain: tuple[float, float], tol: Tolerance, *, what: str = "u") -> np.ndarray:
    """Return ``u`` as float64, clamped into ``domain`` when within round-off of it.

    Round-off is ``tol.solver * max(1, domain length)``; parameters further outside
    raise rather than being clamped silently.

    Raises
    ------
    InvalidInputError
        NaN/inf parameters, or parameters outside the domain by more than round-off.
    """
    u = np.asarray(u, dtype=np.float64)
    lo, hi = domain
    slack = tol.solver * max(1.0, hi - lo)
    if u.size:
        umin, umax = float(np.min(u)), float(np.max(u))
        if not (np.isfinite(umin) and np.isfinite(umax)):
            raise InvalidInputError(f"{what}: parameters must be finite, got NaN or inf")
        if umin < lo - slack or umax > hi + slack:
            bad = umin if umin < lo - slack else umax
            raise InvalidInputError(f"{what}: parameter {bad!r} is outside the domain [{lo!r}, {hi!r}]")
        if umin < lo or umax > hi:
            u = np.clip(u, lo, hi)
    return u


def find_spans(knots: np.ndarray, degree: int, u: np.ndarray) -> np.ndarray:
    """Knot span index of each parameter (The NURBS Book A2.1, by binary search).

    Parameters
    ----------
    knots : (n + p + 1,) float64
    u : (m,) float64, inside the domain

    Returns
    -------
    (m,) int64 in ``[p, n - 1]``
    """
    n = knots.shape[0] - degree - 1
    # The last non-empty span: with a floating knot vector U[n] may repeat above the
    # domain, so span n - 1 can be empty and u = U[n] belongs to the span before it.
    last = int(np.searchsorted(knots, knots[n], side="left")) - 1
    spans = np.minimum(np.searchsorted(knots, u, side="right") - 1, last)
    return np.maximum(spans, degree).astype(np.int64, copy=False)


def basis_functions(knots: np.ndarray, degree: int, spans: np.ndarray, u: np.ndarray) -> np.ndarray:
    """Non-zero basis functions ``N[span-p .. span, p](u)`` (The NURBS Book A2.2).

    Returns
    -------
    (m, p + 1) float64
    """
    m = u.shape[0]
    p = degree
    N = np.zeros((m, p + 1))
    N[:, 0] = 1.0
    left = np.empty((m, p + 1))
    right = np.empty((m, p + 1))
    for j in range(1, p + 1):
        left[:, j] = u - knots[spans + 1 - j]
        right[:, j] = knots[spans + j] - u
        saved = np.zeros(m)
        for r in range(j):
            temp = N[:, r] / (right[:, r + 1] + left[:, j - r])
            N[:, r] = saved + right[:, r + 1] * temp
            saved = left[:, j - r] * temp
        N[:, j] = saved
    return N


def basis_derivatives(knots: np.ndarray, degree: int, spans: np.ndarray, u: np.ndarray, order: int) -> np.ndarray:
    """Basis functions and their derivatives up to ``order`` (The NURBS Book A2.3).

    Returns
    -------
    (m, order + 1, p + 1) float64
        ``ders[:, k, j]`` is the k-th derivative of ``N[span - p + j, p]``; rows above
        ``p`` are zero.
    """
    if order < 0:
        raise InvalidInputError(f"derivative order must be >= 0, got {order}")
    m = u.shape[0]
    p = degree
    n = min(order, p)
    ndu = np.zeros((m, p + 1, p + 1))
    ndu[:, 0, 0] = 1.0
    left = np.empty((m, p + 1))
    right = np.empty((m, p + 1))
    for j in range(1, p + 1):
        left[:, j] = u - knots[spans + 1 - j]
        right[:, j] = knots[spans + j] - u
        saved = np.zeros(m)
        for r in range(j):
            ndu[:, j, r] = right[:, r + 1] + left[:, j - r]
            temp = ndu[:, r, j - 1] / ndu[:, j, r]
            ndu[:, r, j] = saved + right[:, r + 1] * temp
            saved = left[:, j - r] * temp
        ndu[:, j, j] = saved
    ders = np.zeros((m, order + 1, p + 1))
    ders[:, 0, :] = ndu[:, :, p]
    a = np.zeros((m, 2, p + 1))
    for r in range(p + 1):
        s1, s2 = 0, 1
        a[:] = 0.0
        a[:, 0, 0] = 1.0
        for k in range(1, n + 1):
            d = np.zeros(m)
            rk, pk = r - k, p - k
            if r >= k:
                a[:, s2, 0] = a[:, s1, 0] / ndu[:, pk + 1, rk]
                d = a[:, s2, 0] * ndu[:, rk, pk]
            j1 = 1 if rk >= -1 else -rk
            j2 = k - 1 if r - 1 <= pk else p - r
            for j in range(j1, j2 + 1):
                a[:, s2, j] = (a[:, s1, j] - a[:, s1, j - 1]) / ndu[:, pk + 1, rk + j]
                d = d + a[:, s2, j] * ndu[:, rk + j, pk]
            if r <= pk:
                a[:, s2, k] = -a[:, s1, k - 1] / ndu[:, pk + 1, r]
                d = d + a[:, s2, k] * ndu[:, r, pk]
            ders[:, k, r] = d
            s1, s2 = s2, s1
    factor = float(p)
    for k in range(1, n + 1):
        ders[:, k, :] *= factor
        factor *= p - k
    return ders


def basis_matrix(knots: np.ndarray, degree: int, u: np.ndarray, order: int = 0) -> sp.csr_matrix:
    """Sparse collocation matrix ``B[i, j] = d^order N_j(u_i) / du^order``.

    Returns
    -------
    (m, n) scipy.sparse.csr_matrix with ``p + 1`` stored entries per row.
    """
    n = knots.shape[0] - degree - 1
    m = u.shape[0]
    spans = find_spans(knots, degree, u)
    if order == 0:
        vals = basis_functions(knots, degree, spans, u)
    else:
        vals = basis_derivatives(knots, degree, spans, u, order)[:, order, :]
    cols = spans[:, None] - degree + np.arange(degree + 1)
    indptr = np.arange(0, m * (degree + 1) + 1, degree + 1)
    return sp.csr_matrix((vals.ravel(), cols.ravel(), indptr), shape=(m, n))


def mapped_knots(knots: np.ndarray, degree: int, start: float, end: float) -> np.ndarray:
    """The knot vector moved affinely so its domain becomes ``[start, end]``.

    The domain ends land exactly on ``start`` and ``end`` and the result stays
    non-decreasing despite round-off.

    Raises
    ------
    InvalidInputError
        ``end <= start`` or non-finite bounds.
    """
    if not (np.isfinite(start) and np.isfinite(end) and end > start):
        raise InvalidInputError(f"need finite start < end, got [{start!r}, {end!r}]")
    a, b = domain_of(knots, degree)
    s = (knots - a) / (b - a)
    U = start + s * (end - start)
    U[s == 0.0] = start
    U[s == 1.0] = end
    return np.maximum.accumulate(U)


def clamped_uniform_knots(n_coefficients: int, degree: int, domain: tuple[float, float] = (0.0, 1.0)) -> np.ndarray:
    """Clamped knot vector with uniformly spaced interior knots.

    Raises
    ------
    InvalidGeometryError
        ``n_coefficients < degree + 1``.
    """
    if n_coefficients < degree + 1:
        raise InvalidGeometryError(
            f"a degree-{degree} B-spline needs at least {degree + 1} control points, got {n_coefficients}"
        )
    lo, hi = domain
    inner = np.linspace(lo, hi, n_coefficients - degree + 1)
    return np.concatenate([np.full(degree, lo), inner, np.full(degree, hi)])


def periodic_uniform_knots(n_coefficients: int, degree: int, domain: tuple[float, float] = (0.0, 1.0)) -> np.ndarray:
    """Uniform unclamped knot vector whose domain ``[U[p], U[n]]`` is ``domain``.

    With the first ``degree`` control points repeated at the end, the B-spline is a
    closed, ``C^(p-1)`` periodic curve.
    """
    if n_coefficients < degree + 1:
        raise InvalidGeometryError(
            f"a degree-{degree} B-spline needs at least {degree + 1} control points, got {n_coefficients}"
        )
    lo, hi = domain
    h = (hi - lo) / (n_coefficients - degree)
    return lo + h * (np.arange(n_coefficients + degree + 1) - degree)
