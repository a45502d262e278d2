"""Global interpolation and least-squares approximation of ordered point data by B-splines.

This module fits polynomial B-spline curves through (interpolation) or near
(least squares) an ordered sequence of points, and tensor-product surfaces to a
rectangular grid of points: parametrisation (uniform, chord length, centripetal),
knot placement (averaging, and the approximation rule that puts parameters in every
span), and the banded linear systems, all vectorised over points.  It deliberately
does not fit rational curves (results have unit weights), scattered (non-grid)
surface data, local (piecewise Hermite) schemes, smoothing or fairing terms, or
parameter correction (the parameters are fixed once chosen); closest-point
distances are not used anywhere: errors are measured at the data parameters.

Sources: The NURBS Book (Piegl and Tiller, 2nd ed.) ch. 9 — eq. 9.4–9.6
(parameters), eq. 9.8 (averaged knots), A9.1 (global curve interpolation), §9.2.2
(end derivatives), A9.3/A9.4 (surface parameters and interpolation), eq. 9.63–9.69
and A9.7 (least squares with interpolated end points; the default knot placement for
least squares is eq. 9.8 on resampled parameters, see :func:`approximation_knots`,
because eq. 9.69 degenerates as the number of control points approaches the number of
points); Hager 1984 / Higham 1988 (condition estimate); Cohen–Riesenfeld–Elber,
*Geometric Modeling with Splines*, ch. 9 (interpolation, Schoenberg–Whitney).

Conventions: ``m`` data points ``Q[k]`` with parameters ``u[k]`` (strictly
increasing, ``[0, 1]`` unless given); a fitted curve has ``n`` control points,
degree ``p`` and a clamped knot vector whose domain is ``[u[0], u[-1]]``.
"""

from __future__ import annotations

import numpy as np
import scipy.linalg.lapack as _lapack
import scipy.sparse as sp

from coons.errors import ConvergenceError, InvalidInputError
from coons.kernel import basis as _b
from coons.kernel._common import as_degree, as_points
from coons.kernel.curve import NurbsCurve
from coons.kernel.surface import NurbsSurface
from coons.tolerance import Tolerance, resolve

__all__ = [
    "parametrize",
    "parametrize_grid",
    "averaged_knots",
    "approximation_knots",
    "interpolate_curve",
    "approximate_curve",
    "approximate_curve_to_tolerance",
    "interpolate_surface",
    "approximate_surface",
]

_METHODS = ("chord", "centripetal", "uniform")


# ---------------------------------------------------------------------- validation helpers
def _check_method(method: str) -> str:
    if method not in _METHODS:
        raise InvalidInputError(f"method must be one of {_METHODS}, got {method!r}")
    return method


def _check_params(params, m: int, what: str) -> np.ndarray:
    """Caller-given parameters: ``(m,)`` finite and strictly increasing."""
    u = np.array(params, dtype=np.float64)
    if u.shape != (m,):
        raise InvalidInputError(f"{what}: expected {m} parameters (one per point), got shape {u.shape}")
    if not np.all(np.isfinite(u)):
        raise InvalidInputError(f"{what}: parameters must be finite")
    bad = np.flatnonzero(np.diff(u) <= 0)
    if bad.size:
        k = int(bad[0])
        raise InvalidInputError(
            f"{what}: parameters must be strictly increasing, but params[{k + 1}] = {float(u[k + 1])!r} "
            f"<= params[{k}] = {float(u[k])!r}"
        )
    return u


def _check_count(value, what: str) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
        raise InvalidInputError(f"{what} must be an integer, got {value!r}")
    return int(value)


def _as_vector(value, d: int, what: str) -> np.ndarray:
    v = np.array(value, dtype=np.float64)
    if v.shape != (d,):
        raise InvalidInputError(f"{what}: expected a vector of shape ({d},), got shape {v.shape}")
    if not np.all(np.isfinite(v)):
        raise InvalidInputError(f"{what}: components must be finite, got {v.tolist()}")
    return v


# ---------------------------------------------------------------------- parameters and knots
def _step_lengths(dists: np.ndarray, method: str) -> np.ndarray:
    # Eq. 9.5 (chord) uses the distances, eq. 9.6 (centripetal) their square roots.
    return dists if method == "chord" else np.sqrt(dists)


def parametrize(points, method: str = "chord", *, tol: Tolerance | None = None) -> np.ndarray:
    """Parameters in ``[0, 1]`` for an ordered sequence of points (The NURBS Book eq. 9.4–9.6).

    Parameters
    ----------
    points : (m, d) array_like, ``m >= 2``
    method : {"chord", "centripetal", "uniform"}
        Equally spaced, proportional to the distances between consecutive points, or to
        their square roots (Lee's centripetal method).
    tol : Tolerance, optional
        Consecutive points closer than ``tol.linear`` coincide.

    Returns
    -------
    (m,) float64
        Strictly increasing, ``u[0] == 0`` and ``u[-1] == 1``.

    Raises
    ------
    InvalidInputError
        Unknown method, fewer than two points, non-finite coordinates, or (chord and
        centripetal) two consecutive points that coincide within ``tol.linear``.

    Examples
    --------
    >>> parametrize([[0, 0], [1, 0], [3, 0]]).tolist()
    [0.0, 0.3333333333333333, 1.0]
    """
    t = resolve(tol)
    _check_method(method)
    Q = as_points(points, ndim=2, what="parametrize points")
    m = Q.shape[0]
    if m < 2:
        raise InvalidInputError(f"parametrize needs at least 2 points, got {m}")
    if method == "uniform":
        return np.linspace(0.0, 1.0, m)
    dists = np.linalg.norm(np.diff(Q, axis=0), axis=1)
    close = np.flatnonzero(dists <= t.linear)
    if close.size:
        k = int(close[0])
        raise InvalidInputError(
            f"parametrize: points {k} and {k + 1} coincide "
            f"(distance {float(dists[k])!r} <= tol.linear = {t.linear!r}); "
            f"{method} parameters need distinct consecutive points"
        )
    steps = _step_lengths(dists, method)
    u = np.concatenate([[0.0], np.cumsum(steps)]) / steps.sum()
    u[-1] = 1.0
    return u


def _grid_axis_params(Q: np.ndarray, method: str, t: Tolerance, axis_name: str) -> np.ndarray:
    """Averaged parameters along axis 0 of a grid ``(m, n, d)`` (The NURBS Book A9.3).

    Columns whose points all coincide (a pole, total length <= tol.linear) carry no
    information and are left out of the average.
    """
    m = Q.shape[0]
    if method == "uniform":
        return np.linspace(0.0, 1.0, m)
    dists = np.linalg.norm(np.diff(Q, axis=0), axis=2)  # (m - 1, n)
    step_max = dists.max(axis=1)
    close = np.flatnonzero(step_max <= t.linear)
    if close.size:
        k = int(close[0])
        raise InvalidInputError(
            f"parametrize_grid: {axis_name} {k} and {k + 1} coincide (largest distance {float(step_max[k])!r} "
            f"<= tol.linear = {t.linear!r})"
        )
    steps = _step_lengths(dists, method)
    live = dists.sum(axis=0) > t.linear
    steps = steps[:, live]
    cum = np.concatenate([np.zeros((1, steps.shape[1])), np.cumsum(steps, axis=0)]) / steps.sum(axis=0)
    u = cum.mean(axis=1)
    u[0], u[-1] = 0.0, 1.0
    return u


def parametrize_grid(points, method: str = "chord", *, tol: Tolerance | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Parameters for a grid of points: averages over rows and columns (The NURBS Book A9.3).

    Parameters
    ----------
    points : (m, n, d) array_like, ``m, n >= 2``
        ``points[k, l]`` is to sit at ``(u[k], v[l])``.
    method : {"chord", "centripetal", "uniform"}
    tol : Tolerance, optional

    Returns
    -------
    u : (m,) float64, v : (n,) float64
        Strictly increasing from 0 to 1.  ``u`` averages the chord-length (or
        centripetal) parameters of the ``n`` columns ``points[:, l]``, leaving out
        columns collapsed to a point; ``v`` likewise over the rows.

    Raises
    ------
    InvalidInputError
        Unknown method, fewer than 2 points in a direction, non-finite coordinates, or
        two consecutive rows (columns) whose points all coincide within ``tol.linear``.
    """
    t = resolve(tol)
    _check_method(method)
    Q = as_points(points, ndim=3, what="parametrize_grid points")
    if Q.shape[0] < 2 or Q.shape[1] < 2:
        raise InvalidInputError(f"parametrize_grid needs at least 2 x 2 points, got {Q.shape[0]} x {Q.shape[1]}")
    return (
        _grid_axis_params(Q, method, t, "rows"),
        _grid_axis_params(Q.transpose(1, 0, 2), method, t, "columns"),
    )


def averaged_knots(params, degree: int) -> np.ndarray:
    """Clamped knots for interpolation at ``params`` by averaging (The NURBS Book eq. 9.8).

    Each interior knot is the mean of ``degree`` consecutive parameters, which makes
    the collocation matrix satisfy the Schoenberg–Whitney condition (every parameter
    lies inside the support of its basis function).

    Parameters
    ----------
    params : (m,) array_like, strictly increasing, ``m >= degree + 1``
    degree : int >= 1

    Returns
    -------
    (m + degree + 1,) float64
        Domain ``[params[0], params[-1]]``.

    Raises
    ------
    InvalidInputError
        Bad degree, too few or non-increasing parameters.

    Examples
    --------
    >>> averaged_knots([0.0, 0.25, 0.5, 1.0], 2).tolist()
    [0.0, 0.0, 0.0, 0.375, 1.0, 1.0, 1.0]
    """
    p = as_degree(degree, what="averaged_knots")
    u = np.asarray(params, dtype=np.float64).ravel()
    u = _check_params(u, u.shape[0], "averaged_knots")
    if u.shape[0] < p + 1:
        raise InvalidInputError(f"averaged_knots: degree {p} needs at least {p + 1} parameters, got {u.shape[0]}")
    return _averaging(u, p)


def _averaging(u: np.ndarray, p: int) -> np.ndarray:
    """Eq. 9.8 on non-decreasing ``u`` (an end parameter may repeat, once per end derivative).

    Below eight terms the window sums are added left to right, which is the order of numpy's
    reduction there (``sliding_window_view(...).mean(axis=1)``, used from eight on): the same
    values, without the view's and the mean's set-up, which cost as much as the arithmetic on
    the few hundred parameters of a p-curve fit round.
    """
    n = u.shape[0]
    if n <= p + 1:
        inner = np.empty(0)
    elif p < 8:
        k = n - p - 1
        inner = u[1:1 + k].copy()
        for j in range(2, p + 1):
            inner += u[j:j + k]
        inner /= p
    else:
        inner = np.lib.stride_tricks.sliding_window_view(u[1:-1], p).mean(axis=1)
    return np.concatenate([np.full(p + 1, u[0]), inner, np.full(p + 1, u[-1])])


def approximation_knots(params, n_control_points: int, degree: int, *, placement: str = "averaged") -> np.ndarray:
    """Clamped knots for least-squares fitting at ``params`` with ``n_control_points``.

    Placements
    ----------
    ``"averaged"`` (default)
        Eq. 9.8 averaging (The NURBS Book) applied to the parameters resampled at
        ``n`` evenly spaced fractional indices ``k = j (m - 1) / (n - 1)`` (linear
        interpolation between neighbouring parameters).  For ``n = m`` these are the
        interpolation knots; the least-squares matrix stays well conditioned for every
        ``n <= m`` (condition numbers below ~100 on random data, measured).
    ``"nurbs_book"``
        The NURBS Book eq. 9.68–9.69: interior knots interpolate the parameters at
        the stride ``d = m / (n - p)``.  Sound for ``m`` well above ``n``; as ``n``
        approaches ``m``, ``d`` tends to 1, the first interior knot tends to
        ``params[0]`` and the normal equations become singular (condition numbers
        beyond 1e15 at ``n = m``, measured).

    Parameters
    ----------
    params : (m,) array_like, strictly increasing
    n_control_points : int, ``degree + 1 <= n <= m``
    degree : int >= 1
    placement : {"averaged", "nurbs_book"}

    Returns
    -------
    (n + degree + 1,) float64
        Domain ``[params[0], params[-1]]``.

    Raises
    ------
    InvalidInputError
        Bad degree or placement, non-increasing parameters, or ``n`` outside
        ``[degree + 1, m]``.
    """
    p = as_degree(degree, what="approximation_knots")
    if placement not in ("averaged", "nurbs_book"):
        raise InvalidInputError(f"placement must be 'averaged' or 'nurbs_book', got {placement!r}")
    u = np.asarray(params, dtype=np.float64).ravel()
    u = _check_params(u, u.shape[0], "approximation_knots")
    m = u.shape[0]
    n = _check_count(n_control_points, "n_control_points")
    if not p + 1 <= n <= m:
        raise InvalidInputError(
            f"approximation_knots: n_control_points must be in [degree + 1, number of points] = "
            f"[{p + 1}, {m}], got {n}"
        )
    if placement == "averaged":
        resampled = np.interp(np.linspace(0.0, m - 1.0, n), np.arange(m, dtype=np.float64), u)
        return _averaging(resampled, p)
    d = m / (n - p)
    jd = np.arange(1, n - p) * d
    i = jd.astype(np.int64)
    alpha = jd - i
    inner = (1.0 - alpha) * u[i - 1] + alpha * u[i]
    return np.concatenate([np.full(p + 1, u[0]), inner, np.full(p + 1, u[-1])])


def _user_knots(knots, p: int, n: int, u: np.ndarray, t: Tolerance, what: str) -> np.ndarray:
    U = _b.as_knot_vector(knots, p, n, what=f"{what} knots")
    _b.check_parameters(u, _b.domain_of(U, p), t, what=f"{what} params")
    return np.array(U)


# ---------------------------------------------------------------------- linear algebra
def _inverse_norm1(lu: np.ndarray, piv: np.ndarray, kl: int, ku: int) -> float:
    """Estimate ``||A^-1||_1`` from the banded LU factors (Hager 1984; Higham 1988, Algorithm 2.1).

    A few solves with ``A`` and ``A^T`` (O(n) each); LAPACK's gbcon does the same but
    its reference implementation costs O(n^2) on long bands (2 s at n = 1e5, measured).
    """
    n = lu.shape[1]
    x = np.full((n, 1), 1.0 / n)
    estimate = 0.0
    for _ in range(5):  # Hager's iteration converges in 2-3 steps; 5 is Higham's bound
        y, _ = _lapack.dgbtrs(lu, kl, ku, x, piv)
        estimate = float(np.abs(y).sum())
        z, _ = _lapack.dgbtrs(lu, kl, ku, np.where(y >= 0, 1.0, -1.0), piv, trans=1)
        j = int(np.argmax(np.abs(z)))
        if abs(z[j, 0]) <= float(z[:, 0] @ x[:, 0]):
            break
        x = np.zeros((n, 1))
        x[j] = 1.0
    return estimate


def _banded_solve(A: sp.spmatrix, rhs: np.ndarray, what: str) -> np.ndarray:
    """Solve the square banded system ``A x = rhs`` by LU with partial pivoting (LAPACK gbtrf/gbtrs).

    ``rhs`` is ``(n, k)``: all coordinates (and all rows of a grid) in one call.  The
    reciprocal condition number is estimated and a matrix singular to working
    precision is refused instead of returning noise.
    """
    C = A.tocoo()
    return _banded_solve_entries(C.row, C.col, C.data, A.shape[1], rhs, what)


def _banded_solve_entries(row: np.ndarray, col: np.ndarray, data: np.ndarray, n: int, rhs: np.ndarray,
                          what: str) -> np.ndarray:
    """:func:`_banded_solve` of the ``n × n`` matrix given by its entries (COO form, no duplicates)."""
    offsets = col - row
    kl, ku = max(0, -int(offsets.min())), max(0, int(offsets.max()))
    ab = np.zeros((2 * kl + ku + 1, n))  # LAPACK band storage with kl extra rows for the fill-in
    ab[kl + ku + row - col, col] = data
    anorm = float(np.max(np.bincount(col, np.abs(data), minlength=n)))
    lu, piv, info = _lapack.dgbtrf(ab, kl, ku)
    if info > 0:
        raise InvalidInputError(f"{what}: the linear system is singular (zero pivot in column {info - 1})")
    rcond = 1.0 / (anorm * _inverse_norm1(lu, piv, kl, ku))
    # Below machine epsilon the solution has no correct digit (scipy.linalg.solve's criterion).
    if not rcond > np.finfo(np.float64).eps:
        raise InvalidInputError(
            f"{what}: the linear system is singular to working precision (reciprocal condition number {rcond:.3e})"
        )
    x, _ = _lapack.dgbtrs(lu, kl, ku, np.asarray(rhs, dtype=np.float64), piv)
    return x


def _check_schoenberg_whitney(diag: np.ndarray, rows: np.ndarray, what: str) -> None:
    """The diagonal ``diag`` of a square collocation matrix must not vanish (Schoenberg–Whitney;
    Cohen–Riesenfeld–Elber §9.2): parameter ``k`` lies in the support of basis function ``k``."""
    bad = np.flatnonzero(diag == 0.0)
    if bad.size:
        k = int(bad[0])
        raise InvalidInputError(
            f"{what}: the knots violate the Schoenberg-Whitney condition: parameter {float(rows[k])!r} "
            f"(row {k}) is outside the support of basis function {k}"
        )


def _normal_solve(N: sp.csr_matrix, rhs: np.ndarray, w: np.ndarray, what: str, first: int = 0) -> np.ndarray:
    """Weighted least squares ``min sum_k w_k |rhs_k - (N x)_k|^2`` by the normal equations.

    ``N^T W N`` is banded (bandwidth ``p``) and positive definite when the knots leave
    enough parameters in every span (Schoenberg–Whitney for least squares).  Column
    ``j`` of ``N`` is basis function ``first + j`` (for error messages).
    """
    n = N.shape[1]
    if n == 0:
        return np.empty((0, rhs.shape[1]))
    reach = np.asarray(abs(N).sum(axis=0)).ravel()
    empty = np.flatnonzero(reach == 0.0)
    if empty.size:
        j = first + int(empty[0])
        raise InvalidInputError(
            f"{what}: no parameter lies in the support of basis function {j}; move the knots or add points"
        )
    NtW = (N.T @ sp.diags(w)).tocsr()
    return _banded_solve(NtW @ N, NtW @ rhs, what)


def _least_squares(N: sp.csr_matrix, Q: np.ndarray, w: np.ndarray, interpolate_ends: bool, what: str) -> np.ndarray:
    """Control points ``(n, k)`` of the least-squares fit of rows ``Q (m, k)`` (The NURBS Book A9.7).

    With ``interpolate_ends`` the first and last control points are the first and last
    points (clamped knots, end parameters at the domain ends) and only the inner ones
    are fitted, against ``R_k = Q_k - N_0(u_k) Q_0 - N_{n-1}(u_k) Q_{m-1}`` (eq. 9.63–9.66).
    """
    n = N.shape[1]
    if not interpolate_ends:
        return _normal_solve(N, Q, w, what)
    ends = np.stack([Q[0], Q[-1]])
    R = Q - N[:, [0, n - 1]] @ ends
    inner = _normal_solve(N[:, 1 : n - 1], R, w, what, first=1)
    return np.concatenate([Q[:1], inner, Q[-1:]])


# ---------------------------------------------------------------------- curves
def interpolate_curve(
    points,
    degree: int = 3,
    *,
    params=None,
    method: str = "chord",
    knots=None,
    start_tangent=None,
    end_tangent=None,
    tol: Tolerance | None = None,
) -> NurbsCurve:
    """The B-spline curve of ``degree`` through ``points`` (The NURBS Book A9.1, §9.2.2).

    Solves the banded collocation system ``C(u_k) = Q_k`` (plus ``C'(u_0) = D_0``
    and/or ``C'(u_{m-1}) = D_{m-1}`` when end tangents are given) for all coordinates
    at once.

    Parameters
    ----------
    points : (m, d) array_like
    degree : int >= 1 (>= 2 with end tangents)
    params : (m,) array_like, optional
        Strictly increasing parameters of the points; default from ``method``.
    method : {"chord", "centripetal", "uniform"}
        Parametrisation when ``params`` is not given (:func:`parametrize`).
    knots : (n + degree + 1,) array_like, optional
        Default: eq. 9.8 averaging of the parameters (each end with a tangent counts its
        parameter twice, as in The NURBS Book §9.2.2).  Given knots must satisfy the
        Schoenberg–Whitney condition with the parameters.
    start_tangent, end_tangent : (d,) array_like, optional
        First derivative ``dC/du`` at the ends, with respect to the curve's parameter
        (domain ``[params[0], params[-1]]``, ``[0, 1]`` by default).  A unit direction
        ``t`` is usually scaled by the total chord length to give a natural speed.
    tol : Tolerance, optional
        Used by the parametrisation (coincident points).

    Returns
    -------
    NurbsCurve
        Polynomial, clamped, ``n = m + (number of tangents)`` control points, domain
        ``[params[0], params[-1]]``.

    Raises
    ------
    InvalidInputError
        Too few points for the degree, bad parameters/knots/tangents, coincident
        consecutive points, tangents with degree 1, a singular system.

    Examples
    --------
    >>> Q = [[0, 0], [1, 1], [2, 0], [3, 1]]
    >>> c = interpolate_curve(Q, 3)
    >>> bool(np.allclose(c.evaluate(parametrize(Q)), Q, rtol=0, atol=1e-12))
    True
    """
    t = resolve(tol)
    p = as_degree(degree, what="interpolate_curve")
    _check_method(method)
    Q = as_points(points, ndim=2, what="interpolate_curve points")
    m, d = Q.shape
    D0 = None if start_tangent is None else _as_vector(start_tangent, d, "interpolate_curve start_tangent")
    D1 = None if end_tangent is None else _as_vector(end_tangent, d, "interpolate_curve end_tangent")
    n_tangents = (D0 is not None) + (D1 is not None)
    if n_tangents and p < 2:
        raise InvalidInputError(f"interpolate_curve: end tangents need degree >= 2, got degree {p}")
    n = m + n_tangents
    if m < 2 or n < p + 1:
        raise InvalidInputError(
            f"interpolate_curve: degree {p} with {n_tangents} end tangent(s) needs at least "
            f"{max(2, p + 1 - n_tangents)} points, got {m}"
        )
    u = parametrize(Q, method, tol=t) if params is None else _check_params(params, m, "interpolate_curve params")

    # Row order keeps the system banded: Q_0, D_0, Q_1 .. Q_{m-2}, D_{m-1}, Q_{m-1}
    # as (parameters, derivative order, right-hand sides) blocks.
    blocks = [
        (u[:1], 0, Q[:1]),
        (u[:1], 1, D0[None]) if D0 is not None else None,
        (u[1:-1], 0, Q[1:-1]),
        (u[-1:], 1, D1[None]) if D1 is not None else None,
        (u[-1:], 0, Q[-1:]),
    ]
    blocks = [b for b in blocks if b is not None and b[0].size]
    all_u = np.concatenate([b[0] for b in blocks])

    U = _averaging(all_u, p) if knots is None else _user_knots(knots, p, n, u, t, "interpolate_curve")
    # The collocation matrix by its entries (p + 1 per row), straight into band storage.
    vals, cols = [], []
    for uu, k, _ in blocks:
        spans = _b.find_spans(U, p, uu)
        if k == 0:
            vals.append(_b.basis_functions(U, p, spans, uu))
        else:
            vals.append(_b.basis_derivatives(U, p, spans, uu, k)[:, k, :])
        cols.append(spans[:, None] - p + np.arange(p + 1))
    V, J = np.concatenate(vals), np.concatenate(cols)
    I = np.repeat(np.arange(n), p + 1)
    diag = np.where(J == np.arange(n)[:, None], V, 0.0).sum(axis=1)
    _check_schoenberg_whitney(diag, all_u, "interpolate_curve")
    P = _banded_solve_entries(I, J.ravel(), V.ravel(), n, np.concatenate([b[2] for b in blocks]), "interpolate_curve")
    return NurbsCurve(P, U, p)


def _point_weights(weights, m: int, what: str) -> np.ndarray:
    if weights is None:
        return np.ones(m)
    w = np.array(weights, dtype=np.float64)
    if w.shape != (m,):
        raise InvalidInputError(f"{what}: expected {m} point weights, got shape {w.shape}")
    if not np.all(np.isfinite(w)) or np.any(w <= 0):
        k = int(np.flatnonzero(~(np.isfinite(w) & (w > 0)))[0])
        raise InvalidInputError(f"{what}: point weights must be finite and positive, weights[{k}] = {float(w[k])!r}")
    return w


def _fit_curve(Q, u, n, p, U, w, interpolate_ends, what) -> tuple[NurbsCurve, np.ndarray]:
    """Least-squares curve and its collocation matrix at ``u``."""
    N = _b.basis_matrix(U, p, u)
    P = _least_squares(N, Q, w, interpolate_ends, what)
    return NurbsCurve(P, U, p), N


def approximate_curve(
    points,
    n_control_points: int,
    degree: int = 3,
    *,
    params=None,
    method: str = "chord",
    knots=None,
    weights=None,
    interpolate_ends: bool = True,
    tol: Tolerance | None = None,
) -> NurbsCurve:
    """Weighted least-squares B-spline curve with ``n_control_points`` (The NURBS Book A9.7).

    Minimises ``sum_k weights[k] * |Q_k - C(u_k)|^2`` through the banded normal
    equations; by default the end points are interpolated exactly and only the inner
    control points are fitted (eq. 9.63–9.67).

    Parameters
    ----------
    points : (m, d) array_like
    n_control_points : int, ``degree + 1 <= n <= m``
    degree : int >= 1
    params : (m,) array_like, optional
        Strictly increasing; default from ``method`` (:func:`parametrize`).
    method : {"chord", "centripetal", "uniform"}
    knots : (n + degree + 1,) array_like, optional
        Default :func:`approximation_knots` (``placement="averaged"``; pass
        ``approximation_knots(params, n, p, placement="nurbs_book")`` for The NURBS
        Book eq. 9.68–9.69).  With ``interpolate_ends``
        they must be clamped with domain ``[params[0], params[-1]]``.
    weights : (m,) array_like of positive numbers, optional
        Point weights of the squared errors (not NURBS weights).
    interpolate_ends : bool
        Fix the first and last control points to the first and last points.
    tol : Tolerance, optional

    Returns
    -------
    NurbsCurve
        Polynomial (unit weights), ``n_control_points`` control points.

    Raises
    ------
    InvalidInputError
        ``n_control_points`` out of range, bad parameters/knots/weights, coincident
        consecutive points, or normal equations that are singular (some knot span has
        too few parameters).
    """
    t = resolve(tol)
    p = as_degree(degree, what="approximate_curve")
    _check_method(method)
    Q = as_points(points, ndim=2, what="approximate_curve points")
    m = Q.shape[0]
    n = _check_count(n_control_points, "approximate_curve n_control_points")
    if m < 2 or not p + 1 <= n <= m:
        raise InvalidInputError(
            f"approximate_curve: n_control_points must be in [degree + 1, number of points] = [{p + 1}, {m}], got {n}"
        )
    u = parametrize(Q, method, tol=t) if params is None else _check_params(params, m, "approximate_curve params")
    w = _point_weights(weights, m, "approximate_curve")
    if knots is None:
        U = approximation_knots(u, n, p)
    else:
        U = _user_knots(knots, p, n, u, t, "approximate_curve")
        if interpolate_ends:
            _require_clamped_at(U, p, n, u, "approximate_curve")
    return _fit_curve(Q, u, n, p, U, w, interpolate_ends, "approximate_curve")[0]


def _require_clamped_at(U: np.ndarray, p: int, n: int, u: np.ndarray, what: str) -> None:
    if not (np.all(U[: p + 1] == u[0]) and np.all(U[n:] == u[-1])):
        raise InvalidInputError(
            f"{what}: interpolate_ends needs knots clamped at the end parameters "
            f"[{float(u[0])!r}, {float(u[-1])!r}], got first knots {U[: p + 1].tolist()} "
            f"and last knots {U[n:].tolist()}"
        )


def approximate_curve_to_tolerance(
    points,
    max_error: float,
    degree: int = 3,
    *,
    params=None,
    method: str = "chord",
    max_control_points: int | None = None,
    tol: Tolerance | None = None,
) -> NurbsCurve:
    """The least-squares curve (:func:`approximate_curve`, ends interpolated) with few control points
    whose error ``max_k |C(u_k) - Q_k|`` at the data parameters is at most ``max_error``.

    The number of control points doubles from ``degree + 1`` until the error is met,
    then bisection between the last failing and the first passing count finds a small
    passing count (the error is not strictly monotone in the count, so it need not be
    the smallest).  At most ``2 log2(m) + 2`` fits.

    Parameters
    ----------
    points : (m, d) array_like
    max_error : float > 0
        Model units.
    degree : int >= 1
    params, method : as for :func:`approximate_curve`
    max_control_points : int, optional
        Upper bound on the count; default ``m`` (interpolation).
    tol : Tolerance, optional

    Returns
    -------
    NurbsCurve

    Raises
    ------
    InvalidInputError
        Bad ``max_error`` or ``max_control_points``, or as :func:`approximate_curve`.
    ConvergenceError
        Even ``max_control_points`` control points leave an error above ``max_error``;
        ``residuals`` holds the error reached.
    """
    t = resolve(tol)
    p = as_degree(degree, what="approximate_curve_to_tolerance")
    _check_method(method)
    if not (isinstance(max_error, (int, float, np.floating)) and np.isfinite(max_error) and max_error > 0):
        raise InvalidInputError(f"max_error must be a finite positive number, got {max_error!r}")
    Q = as_points(points, ndim=2, what="approximate_curve_to_tolerance points")
    m = Q.shape[0]
    if m < p + 1:
        raise InvalidInputError(f"approximate_curve_to_tolerance: degree {p} needs at least {p + 1} points, got {m}")
    cap = m if max_control_points is None else _check_count(max_control_points, "max_control_points")
    if not p + 1 <= cap <= m:
        raise InvalidInputError(
            f"max_control_points must be in [degree + 1, number of points] = [{p + 1}, {m}], got {cap}"
        )
    if params is None:
        u = parametrize(Q, method, tol=t)
    else:
        u = _check_params(params, m, "approximate_curve_to_tolerance params")
    w = np.ones(m)

    def fit(n: int) -> tuple[NurbsCurve, float]:
        c, N = _fit_curve(Q, u, n, p, approximation_knots(u, n, p), w, True, "approximate_curve_to_tolerance")
        return c, float(np.max(np.linalg.norm(N @ c.control_points - Q, axis=1)))

    failing, n = p, p + 1
    best, err = fit(n)
    while err > max_error:
        if n == cap:
            raise ConvergenceError(
                f"approximate_curve_to_tolerance: {n} control points leave a max error of {err!r} "
                f"> max_error = {max_error!r}",
                residuals=np.array([err]),
            )
        failing, n = n, min(2 * n, cap)
        best, err = fit(n)
    passing = n
    while passing - failing > 1:
        mid = (passing + failing) // 2
        c, e = fit(mid)
        if e <= max_error:
            passing, best = mid, c
        else:
            failing = mid
    return best


# ---------------------------------------------------------------------- surfaces
def _grid_setup(points, degree_u, degree_v, params_u, params_v, method, t, what):
    pu = as_degree(degree_u, what=f"{what} degree_u")
    pv = as_degree(degree_v, what=f"{what} degree_v")
    _check_method(method)
    Q = as_points(points, ndim=3, what=f"{what} points")
    m, n, _ = Q.shape
    if m < 2 or n < 2:
        raise InvalidInputError(f"{what} needs at least 2 x 2 points, got {m} x {n}")
    au = av = None
    if params_u is None or params_v is None:
        au, av = parametrize_grid(Q, method, tol=t)
    u = au if params_u is None else _check_params(params_u, m, f"{what} params_u")
    v = av if params_v is None else _check_params(params_v, n, f"{what} params_v")
    return Q, pu, pv, u, v


def interpolate_surface(
    points,
    degree_u: int = 3,
    degree_v: int = 3,
    *,
    params_u=None,
    params_v=None,
    method: str = "chord",
    tol: Tolerance | None = None,
) -> NurbsSurface:
    """The tensor-product B-spline surface through a grid of points (The NURBS Book A9.4).

    Curve interpolation through every column (one banded solve for all of them), then
    through every row of the resulting control points.

    Parameters
    ----------
    points : (m, n, d) array_like
        ``S(u[k], v[l]) = points[k, l]``; ``m >= degree_u + 1``, ``n >= degree_v + 1``.
    degree_u, degree_v : int >= 1
    params_u : (m,) array_like, optional
    params_v : (n,) array_like, optional
        Default :func:`parametrize_grid` with ``method``.
    method : {"chord", "centripetal", "uniform"}
    tol : Tolerance, optional

    Returns
    -------
    NurbsSurface
        Polynomial, ``(m, n)`` control points, knots by averaging (eq. 9.8).

    Raises
    ------
    InvalidInputError
        Too few points for the degrees, bad parameters, coincident rows or columns.
    """
    t = resolve(tol)
    Q, pu, pv, u, v = _grid_setup(points, degree_u, degree_v, params_u, params_v, method, t, "interpolate_surface")
    m, n, d = Q.shape
    if m < pu + 1 or n < pv + 1:
        raise InvalidInputError(
            f"interpolate_surface: degrees ({pu}, {pv}) need at least ({pu + 1}, {pv + 1}) points, got ({m}, {n})"
        )
    U, V = averaged_knots(u, pu), averaged_knots(v, pv)
    R = _banded_solve(_b.basis_matrix(U, pu, u), Q.reshape(m, n * d), "interpolate_surface").reshape(m, n, d)
    P = _banded_solve(_b.basis_matrix(V, pv, v), R.transpose(1, 0, 2).reshape(n, m * d), "interpolate_surface")
    return NurbsSurface(P.reshape(n, m, d).transpose(1, 0, 2), U, V, pu, pv)


def approximate_surface(
    points,
    n_u: int,
    n_v: int,
    degree_u: int = 3,
    degree_v: int = 3,
    *,
    params_u=None,
    params_v=None,
    method: str = "chord",
    interpolate_ends: bool = True,
    tol: Tolerance | None = None,
) -> NurbsSurface:
    """Least-squares tensor-product surface with ``(n_u, n_v)`` control points (The NURBS Book §9.4.3).

    Fits every column of the grid by least squares in ``u`` (A9.7, one banded
    Cholesky for all columns), then every row of those control points in ``v``.
    Without ``interpolate_ends`` this is exactly the least-squares surface of the whole
    grid (the tensor design matrix is a Kronecker product, whose pseudo-inverse is
    the product of the pseudo-inverses); with it, the four corner points are
    interpolated and each boundary is fitted with its end points fixed.

    Parameters
    ----------
    points : (m, n, d) array_like
    n_u, n_v : int, ``degree + 1 <= n_u <= m``, ``degree + 1 <= n_v <= n``
    degree_u, degree_v : int >= 1
    params_u, params_v : array_like, optional
        Default :func:`parametrize_grid` with ``method``.
    method : {"chord", "centripetal", "uniform"}
    interpolate_ends : bool
    tol : Tolerance, optional

    Returns
    -------
    NurbsSurface
        Polynomial, knots by :func:`approximation_knots` (averaged placement) in each direction.

    Raises
    ------
    InvalidInputError
        Counts out of range, bad parameters, singular normal equations.
    """
    t = resolve(tol)
    Q, pu, pv, u, v = _grid_setup(points, degree_u, degree_v, params_u, params_v, method, t, "approximate_surface")
    m, n, d = Q.shape
    nu = _check_count(n_u, "approximate_surface n_u")
    nv = _check_count(n_v, "approximate_surface n_v")
    if not (pu + 1 <= nu <= m and pv + 1 <= nv <= n):
        raise InvalidInputError(
            f"approximate_surface: (n_u, n_v) must be in [{pu + 1}, {m}] x [{pv + 1}, {n}], got ({nu}, {nv})"
        )
    U, V = approximation_knots(u, nu, pu), approximation_knots(v, nv, pv)
    what = "approximate_surface"
    R = _least_squares(_b.basis_matrix(U, pu, u), Q.reshape(m, n * d), np.ones(m), interpolate_ends, what)
    R = R.reshape(nu, n, d).transpose(1, 0, 2).reshape(n, nu * d)
    P = _least_squares(_b.basis_matrix(V, pv, v), R, np.ones(n), interpolate_ends, what)
    return NurbsSurface(P.reshape(nv, nu, d).transpose(1, 0, 2), U, V, pu, pv)
