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
    "basis_first_derivatives",
    "last_span",
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
    # Models repeat a few knot vectors over and over (every patch of a sewn spline model): a
    # vector validated before is returned as the same read-only array, unchecked again.
    key = (U.tobytes(), int(degree), int(n_coefficients)) if U.size <= _VALID_KNOTS_LEN else None
    known = _VALID_KNOTS.get(key) if key is not None else None
    if known is not None:
        return known
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
    readonly(U)
    if key is not None:
        if len(_VALID_KNOTS) >= _VALID_KNOTS_MAX:
            _VALID_KNOTS.clear()  # a bound on memory, not an LRU: the common vectors come straight back
        _VALID_KNOTS[key] = U
    return U


#: Knot vectors already validated by :func:`as_knot_vector`, by (bytes, degree, count) -> read-only array.
_VALID_KNOTS: dict[tuple, np.ndarray] = {}
#: Most vectors remembered, and the longest remembered (at most 1024 × 64 × 8 bytes = 512 KB).
_VALID_KNOTS_MAX = 1024
_VALID_KNOTS_LEN = 64


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
        umin, umax = float(u.min()), float(u.max())
        if not (np.isfinite(umin) and np.isfinite(umax)):
            raise InvalidInputError(f"{what}: parameters must be finite, got NaN or inf")
        if umin < lo - slack or umax > hi + slack:
            bad = umin if umin < lo - slack else umax
            raise InvalidInputError(f"{what}: parameter {bad!r} is outside the domain [{lo!r}, {hi!r}]")
        if umin < lo or umax > hi:
            u = np.clip(u, lo, hi)
    return u


def find_spans(knots: np.ndarray, degree: int, u: np.ndarray, last: int | None = None) -> np.ndarray:
    """Knot span index of each parameter (The NURBS Book A2.1).

    The span is ``#{i : U[i] <= u} - 1`` kept inside ``[p, last]``, ``last`` being the
    last non-empty span of the domain.  Small batches use a binary search
    (``np.searchsorted``); large ones a bucket table over the domain followed by a few
    branch-free forward steps, which gives the same spans several times faster on
    random parameters (see :func:`span_table`).

    Parameters
    ----------
    knots : (n + p + 1,) float64
    u : (m,) float64, inside the domain
    last : int, optional
        :func:`last_span` of the knot vector, when the caller has it cached.

    Returns
    -------
    (m,) int64 in ``[p, n - 1]``
    """
    if last is None:
        last = last_span(knots, degree)
    u = np.asarray(u)
    if u.size >= _TABLE_MIN_POINTS:
        table = span_table(knots, degree, last)
        if table is not None and not np.isnan(u).any():
            return _table_spans(table, knots, u, last)
    spans = np.minimum(np.searchsorted(knots, u, side="right") - 1, last)
    return np.maximum(spans, degree).astype(np.int64, copy=False)


def last_span(knots: np.ndarray, degree: int) -> int:
    """Index of the last non-empty knot span of the domain ``[U[p], U[n]]``.

    With a floating knot vector ``U[n]`` may repeat above the domain, so span ``n - 1`` can
    be empty and ``u = U[n]`` belongs to the span before it.
    """
    n = knots.shape[0] - degree - 1
    return int(np.searchsorted(knots, knots[n], side="left")) - 1


#: Batches below this size use the binary search: the bucket table costs O(cells) to build.
_TABLE_MIN_POINTS = 512
#: Forward steps the bucket search may take per parameter before the binary search is cheaper.
_TABLE_MAX_STEPS = 3


def span_table(knots: np.ndarray, degree: int, last: int):
    """Bucket table for :func:`find_spans`: ``(lo, scale, cells, table, steps, ext)`` or ``None``.

    The domain ``[lo, hi]`` is cut into ``G`` equal cells (four per non-empty span).
    ``table[c]`` is the span of the left edge of cell ``c - 1``: one whole cell below
    any parameter the rounded cell index ``floor((u - lo) * G / (hi - lo))`` can put in
    cell ``c``, so the entry never exceeds the true span (the span is non-decreasing in
    ``u``).  ``steps`` bounds how many knots a parameter can lie above its entry (the
    spans three cells on, beyond any rounding of the cell index), and each step moves
    one span forward while ``U[span + 1] <= u``.  ``ext`` is ``U[:last + 2]`` followed
    by NaN so steps stop at ``last + 1`` (``u = U[n]``), which the final minimum
    maps back to ``last``.  ``None`` when clustered knots would need more than
    :data:`_TABLE_MAX_STEPS` steps.
    """
    lo, hi = float(knots[degree]), float(knots[last + 1])
    cells = 4 * max(1, int(np.count_nonzero(np.diff(knots[degree : last + 2]) > 0)))
    edges = lo + (hi - lo) / cells * (np.arange(cells + 3) - 1.0)
    f = np.clip(np.searchsorted(knots, edges, side="right") - 1, degree, last + 1)
    table = f[:cells]
    ahead = np.concatenate([f[3:cells], np.full(3, last + 1)])
    steps = int(np.max(ahead - table))
    if steps > _TABLE_MAX_STEPS:
        return None
    ext = np.append(knots[: last + 2], np.nan)  # NaN <= u is false, even for u = inf
    return lo, cells / (hi - lo), cells, table.astype(np.intp), steps, ext


def _table_spans(table, knots: np.ndarray, u: np.ndarray, last: int) -> np.ndarray:
    """Spans of ``u`` by the bucket table of :func:`span_table` (same result as the binary search)."""
    lo, scale, cells, tab, steps, ext = table
    # fmax/fmin keep +-inf inside the table; NaN never reaches here.
    x = np.fmin(np.fmax((u - lo) * scale, 0.0), cells - 1.0)
    g = tab.take(x.astype(np.intp))
    for _ in range(steps):
        g += ext.take(g + 1) <= u
    np.minimum(g, last, out=g)
    return g.astype(np.int64, copy=False)


def _knot_window(knots: np.ndarray, degree: int, spans: np.ndarray) -> np.ndarray:
    """Knots ``U[span + 1 - p .. span + p]`` of every parameter, ``(2p, m)``, one gather.

    Row ``p - j`` holds ``U[span + 1 - j]`` and row ``p - 1 + j`` holds ``U[span + j]``;
    rows are contiguous so the recursions below read unit-stride 1-D arrays.
    """
    return knots[spans + np.arange(1 - degree, degree + 1)[:, None]]


def basis_rows(knots: np.ndarray, degree: int, spans: np.ndarray, u: np.ndarray) -> list[np.ndarray]:
    """Non-zero basis functions as ``p + 1`` contiguous rows (The NURBS Book A2.2).

    The same recursion and the same floating-point operations as
    :func:`basis_functions`, laid out for the evaluation loops of curves and surfaces:
    ``rows[j]`` is ``N[span - p + j, p](u)``.

    Returns
    -------
    list of p + 1 (m,) float64 arrays
    """
    p = degree
    K = _knot_window(knots, p, spans)
    left = [u - K[p - j] for j in range(p + 1)]  # left[j] = u - U[span + 1 - j] (left[0] unused)
    right = [K[p - 1 + j] - u for j in range(p + 1)]  # right[j] = U[span + j] - u (right[0] unused)
    return triangle(left, right, p, np.ones(u.shape[0]))


def triangle(left: list, right: list, degree: int, one):
    """The triangle of The NURBS Book A2.2 from ``left[j] = u - U[span + 1 - j]`` and ``right[j] = U[span + j] - u``
    (``j = 0..p``; index 0 unused): the ``p + 1`` non-zero basis functions, starting from ``one``.

    Works on arrays (:func:`basis_rows`) and on Python floats (``NurbsCurve._points_scalar``) with the same
    operations in the same order, so both give the same bits.
    """
    N = [one]
    for j in range(1, degree + 1):
        saved = None
        nxt = []
        for r in range(j):
            temp = N[r] / (right[r + 1] + left[j - r])
            term = right[r + 1] * temp
            nxt.append(term if saved is None else saved + term)
            saved = left[j - r] * temp
        nxt.append(saved)
        N = nxt
    return N


def basis_first_derivatives(knots: np.ndarray, degree: int, spans: np.ndarray, u: np.ndarray) -> np.ndarray:
    """Non-zero basis functions and their first derivatives, ``(2, p + 1, m)`` (small batches).

    From the degree ``p - 1`` rows of :func:`basis_rows`, one more step of its recursion gives
    the degree ``p`` values (the same operations, so the same bits) and the derivative formula
    ``N'_{i,p} = p (N_{i,p-1} / (U[i+p] - U[i]) - N_{i+1,p-1} / (U[i+p+1] - U[i+1]))`` (The
    NURBS Book eq. 2.7) reuses that step's quotients: a dozen array operations in all, against
    the ``O(p²)`` of :func:`basis_derivative_rows`, whose derivatives it matches to round-off.

    Returns
    -------
    (2, p + 1, m) float64: ``[0, j]`` is ``N[span - p + j, p](u)``, ``[1, j]`` its derivative
    """
    p = degree
    m = u.shape[0]
    lower = np.asarray(basis_rows(knots, p - 1, spans, u)) if p > 1 else np.ones((1, m))
    r = np.arange(1, p + 1)[:, None]
    hi = knots[spans + r]  # U[span + 1 + j], j < p
    lo = knots[spans + (r - p)]  # U[span + 1 + j - p]
    temp = lower / (hi - lo)
    out = np.zeros((2, p + 1, m))
    N, dN = out[0], out[1]
    N[:p] = (hi - u) * temp
    N[1:] += (u - lo) * temp
    dN[1:] = temp
    dN[:p] -= temp
    dN *= p
    return out


def basis_derivative_rows(
    knots: np.ndarray, degree: int, spans: np.ndarray, u: np.ndarray, order: int
) -> list[list[np.ndarray]]:
    """Basis functions and derivatives as contiguous rows (The NURBS Book A2.3).

    The same recursion and floating-point operations as :func:`basis_derivatives`;
    ``rows[k][j]`` is the k-th derivative of ``N[span - p + j, p]``.  Only orders
    ``k <= min(order, p)`` are returned (higher derivatives vanish).

    Returns
    -------
    list of min(order, p) + 1 lists of p + 1 (m,) float64 arrays
    """
    if order < 0:
        raise InvalidInputError(f"derivative order must be >= 0, got {order}")
    p = degree
    n = min(order, p)
    K = _knot_window(knots, p, spans)
    left = [u - K[p - j] for j in range(p + 1)]
    right = [K[p - 1 + j] - u for j in range(p + 1)]
    # ndu[j][r]: basis functions of degree j on and above the diagonal, knot differences below.
    ndu: list[list] = [[None] * (p + 1) for _ in range(p + 1)]
    ndu[0][0] = np.ones(u.shape[0])
    for j in range(1, p + 1):
        saved = None
        for r in range(j):
            ndu[j][r] = right[r + 1] + left[j - r]
            temp = ndu[r][j - 1] / ndu[j][r]
            term = right[r + 1] * temp
            ndu[r][j] = term if saved is None else saved + term
            saved = left[j - r] * temp
        ndu[j][j] = saved
    ders = [[ndu[r][p] for r in range(p + 1)]] + [[None] * (p + 1) for _ in range(n)]
    for r in range(p + 1):
        s1, s2 = 0, 1
        # Python floats until a coefficient becomes an array: a[s][j] is 0 unless written.
        a = [[1.0] + [0.0] * p, [0.0] * (p + 1)]
        for k in range(1, n + 1):
            d = None
            rk, pk = r - k, p - k
            if r >= k:
                a[s2][0] = a[s1][0] / ndu[pk + 1][rk]
                d = a[s2][0] * ndu[rk][pk]
            j1 = 1 if rk >= -1 else -rk
            j2 = k - 1 if r - 1 <= pk else p - r
            for j in range(j1, j2 + 1):
                a[s2][j] = (a[s1][j] - a[s1][j - 1]) / ndu[pk + 1][rk + j]
                term = a[s2][j] * ndu[rk + j][pk]
                d = term if d is None else d + term
            if r <= pk:
                a[s2][k] = -a[s1][k - 1] / ndu[pk + 1][r]
                term = a[s2][k] * ndu[r][pk]
                d = term if d is None else d + term
            ders[k][r] = np.zeros(u.shape[0]) if d is None else d
            s1, s2 = s2, s1
    factor = float(p)
    for k in range(1, n + 1):
        ders[k] = [row * factor for row in ders[k]]
        factor *= p - k
    return ders


def basis_functions(knots: np.ndarray, degree: int, spans: np.ndarray, u: np.ndarray) -> np.ndarray:
    """Non-zero basis functions ``N[span-p .. span, p](u)`` (The NURBS Book A2.2).

    Returns
    -------
    (m, p + 1) float64
    """
    rows = basis_rows(knots, degree, spans, np.asarray(u, dtype=np.float64))
    return np.stack(rows, axis=1)


def basis_derivatives(knots: np.ndarray, degree: int, spans: np.ndarray, u: np.ndarray, order: int) -> np.ndarray:
    """Basis functions and their derivatives up to ``order`` (The NURBS Book A2.3).

    Returns
    -------
    (m, order + 1, p + 1) float64
        ``ders[:, k, j]`` is the k-th derivative of ``N[span - p + j, p]``; rows above
        ``p`` are zero.
    """
    rows = basis_derivative_rows(knots, degree, spans, np.asarray(u, dtype=np.float64), order)
    m = np.shape(u)[0]
    ders = np.zeros((m, order + 1, degree + 1))
    for k, row in enumerate(rows):
        ders[:, k, :] = np.stack(row, axis=1)
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
