"""Knot insertion, refinement and removal, degree elevation, splitting, Bézier decomposition and iso-curves.

Every operation here changes the *representation* of a B-spline curve or surface
(its knots, degree or control points) and either leaves the geometry exactly
unchanged (insertion, refinement, elevation, clamping, splitting, decomposition,
iso-curves) or moves it by less than ``tol.linear`` (knot removal).  The module does
not fit, approximate or reduce degree, and never changes a parametrisation: pieces
keep the parameters they had on the original.

Each algorithm is written once, on homogeneous control points ``Pw`` of shape
``(n, ...)`` whose axis 0 is the knot direction and whose trailing axes are a batch
(the last one holds the coordinates ``[w x, w y, (w z,) w]``).  A curve passes
``(n, d + 1)``; a surface passes ``(n_dir, n_other, d + 1)`` with the other direction
moved to axis 1, so surface operations are the curve algorithms applied to every row
of the net at once.  Python loops run over inserted or removed knots and over the
degree only.

Clamped, floating and periodic (uniform unclamped) knot vectors are accepted.
Insertion and refinement keep the knot vector's ends as they are; splitting,
segmenting, Bézier decomposition and degree elevation clamp first (same curve, same
domain, end knots of multiplicity ``p + 1``), so their results are clamped.

Parameters closer than ``tol.solver * max(1, domain length)`` to an existing knot are
taken as that knot (round-off of the caller's arithmetic, as for domain checks), so
round-off never creates spans of length 1e-16.

Sources: Boehm's insertion and its refinement form (The NURBS Book A5.1, A5.4);
knot removal (The NURBS Book A5.8, with the bound of eq. 5.30 for rational curves);
Bézier decomposition (A5.6, here by refinement); degree elevation by decomposition,
Bézier elevation (The NURBS Book §5.5) and exact removal of the extra knots
(the scheme of A5.9, Cohen–Riesenfeld–Elber §6.4 and §7.5).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from coons.errors import InvalidInputError
from coons.kernel import basis as _b
from coons.kernel._common import binomials
from coons.tolerance import Tolerance, resolve

if TYPE_CHECKING:  # pragma: no cover
    from coons.kernel.curve import NurbsCurve
    from coons.kernel.surface import NurbsSurface

__all__ = [
    "curve_insert_knot",
    "curve_refine_knots",
    "curve_remove_knot",
    "curve_remove_knots",
    "curve_elevate_degree",
    "curve_split",
    "curve_segment",
    "curve_bezier_segments",
    "curve_clamped",
    "surface_insert_knot",
    "surface_refine_knots",
    "surface_remove_knot",
    "surface_remove_knots",
    "surface_elevate_degree",
    "surface_split",
    "surface_bezier_patches",
    "surface_iso_curve",
]


# ============================================================================ array algorithms
# Every function in this block takes a knot vector U (n + p + 1,), a degree p and
# homogeneous control points Pw (n, ...) with the knot direction on axis 0, and
# returns new arrays; none validates its input (the public functions do).


def _column(v: np.ndarray, ndim: int) -> np.ndarray:
    """``v`` (k,) reshaped to broadcast along axis 0 of an array with ``ndim`` axes."""
    return v.reshape(v.shape + (1,) * (ndim - 1))


def _span(U: np.ndarray, p: int, x: float) -> int:
    """The knot span of the domain that contains ``x`` (A2.1; :func:`coons.kernel.basis.find_spans`)."""
    return int(_b.find_spans(U, p, np.asarray([x], dtype=np.float64))[0])


def _multiplicity(U: np.ndarray, x: float) -> int:
    return int(np.searchsorted(U, x, side="right") - np.searchsorted(U, x, side="left"))


def _refine(U: np.ndarray, p: int, Pw: np.ndarray, X: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Insert the sorted knots ``X`` (The NURBS Book A5.4; Boehm's insertion applied back to front).

    ``X`` must lie in the domain ``[U[p], U[n]]`` and keep every multiplicity at most
    ``p`` inside it.  Repeated values are inserted repeatedly (A5.1 is the case of a
    single repeated value).

    Parameters
    ----------
    U : (n + p + 1,) float64
    Pw : (n, ...) float64
    X : (r,) float64, sorted, r >= 1

    Returns
    -------
    Ubar : (n + p + 1 + r,) float64
    Qw : (n + r, ...) float64
    """
    n = Pw.shape[0]
    r = X.shape[0]
    a = _span(U, p, X[0])
    b = _span(U, p, X[-1]) + 1
    Q = np.empty((n + r,) + Pw.shape[1:])
    Ubar = np.empty(U.shape[0] + r)
    Q[: a - p + 1] = Pw[: a - p + 1]
    Q[b - 1 + r :] = Pw[b - 1 :]
    Ubar[: a + 1] = U[: a + 1]
    Ubar[b + p + r :] = U[b + p :]
    i = b + p - 1  # last old knot not yet placed
    k = b + p + r - 1  # last free slot of Ubar
    steps = np.arange(1, p + 1)
    for j in range(r - 1, -1, -1):
        x = X[j]
        # Old knots >= x move to the back as one block with their control points
        # (A5.4's inner while loop, done as a slice copy).
        stop = max(a, int(np.searchsorted(U, x, side="left")) - 1)
        cnt = max(i - stop, 0)
        if cnt:
            Q[k - cnt - p : k - p] = Pw[i - cnt - p : i - p]
            Ubar[k - cnt + 1 : k + 1] = U[i - cnt + 1 : i + 1]
            k -= cnt
            i -= cnt
        Q[k - p - 1] = Q[k - p]
        # A5.4's loop over l = 1..p updates Q[k-p+l-1] from itself and Q[k-p+l], which the
        # loop has not touched yet: all p updates read old values and run as one operation.
        num = Ubar[k + steps] - x
        den = Ubar[k + steps] - U[i - p + steps]
        alpha = np.divide(num, den, out=np.zeros(p), where=num != 0.0)
        alpha = _column(alpha, Q.ndim)
        Q[k - p : k] = alpha * Q[k - p : k] + (1.0 - alpha) * Q[k - p + 1 : k + 1]
        Ubar[k] = x
        k -= 1
    return Ubar, Q


def _remove_once(U: np.ndarray, p: int, Pw: np.ndarray, x: float) -> tuple[np.ndarray, np.ndarray, float]:
    """Remove one copy of the interior knot ``x`` (The NURBS Book A5.8, one pass).

    With ``r`` the index of the last copy of ``x`` and ``s`` its multiplicity, the
    removed curve's control points ``Q[r-p .. r-s-1]`` satisfy the ``m + 1 = p - s + 1``
    insertion equations ``Pw[i] = a_i Q[i] + (1 - a_i) Q[i - 1]``, ``i = r-p .. r-s``,
    with ``Q[r-p-1] = Pw[r-p-1]`` and ``Q[r-s] = Pw[r-s+1]`` fixed.  As in A5.8 the
    unknowns come from a sweep from the left (``Q[i]`` from equation ``i``) up to some
    point and a sweep from the right beyond it, and the one equation left unused
    measures the error.  A5.8 always leaves the middle equation; here both sweeps are
    run to the end and, for every row of the batch, the unused equation with the
    smallest residual is chosen.  Re-inserting ``x`` reproduces ``Pw`` to round-off on
    every used equation whatever the sweeps amplified, so this residual is the
    deviation, and minimising it keeps exact removals (degree elevation) at round-off
    also next to very short spans.

    Returns
    -------
    U' : (len(U) - 1,) float64
    Qw : (n - 1, ...) float64
    error : float
        Bound on ``|Cw(u) - C'w(u)|`` of the homogeneous curves (max over the batch):
        the residual of the unused equation, which multiplies one basis function of
        the original knot vector (non-negative, at most one).
    """
    r = int(np.searchsorted(U, x, side="right")) - 1
    s = r - int(np.searchsorted(U, x, side="left")) + 1
    first, last = r - p, r - s
    m = last - first  # unknowns Q[first .. last-1]
    P = Pw[first - 1 : last + 2]  # P[t] = Pw[first - 1 + t], t = 0 .. m + 2
    eqs = np.arange(first, last + 1)
    alpha = (x - U[eqs]) / (U[eqs + p + 1] - U[eqs])  # in (0, 1): U[eqs] < x < U[eqs + p + 1]
    # Position t of L and R holds Q[first - 1 + t]; 0 and m + 1 are the fixed neighbours.
    L = np.empty((m + 2,) + Pw.shape[1:])
    R = np.empty_like(L)
    L[0], R[m + 1] = P[0], P[m + 2]
    for t in range(1, m + 1):  # equation first + t - 1 gives Q at position t
        L[t] = (P[t] - (1.0 - alpha[t - 1]) * L[t - 1]) / alpha[t - 1]
    for t in range(m, 0, -1):  # equation first + t gives Q at position t
        R[t] = (P[t + 1] - alpha[t] * R[t + 1]) / (1.0 - alpha[t])
    # Leaving equation first + c unused keeps L at positions 1..c and R at c+1..m.
    a = _column(alpha, Pw.ndim)
    resid = P[1 : m + 2] - (a * R[1 : m + 2] + (1.0 - a) * L[0 : m + 1])  # (m + 1, ...)
    norms = np.linalg.norm(resid, axis=-1)
    norms = np.where(np.isfinite(norms), norms, np.inf)
    c = np.argmin(norms, axis=0)  # per batch row
    t = _column(np.arange(1, m + 1), Pw.ndim - 1)
    keep_left = (t <= c[None])[..., None]
    unknowns = np.where(keep_left, L[1 : m + 1], R[1 : m + 1])
    err = float(np.max(np.min(norms, axis=0)))
    Q = np.concatenate([Pw[:first], unknowns, Pw[last + 1 :]])
    return np.delete(U, r), Q, err


def _clamp_start(U: np.ndarray, p: int, Pw: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Clamp the start of the knot vector at ``a = U[p]`` without changing the curve on its domain.

    Insert ``a`` until its multiplicity is ``p``; the run of copies then starts at some
    ``j >= 1`` and ``C(a) = Pw[j - 1]``.  The curve on ``[a, ...)`` depends only on
    ``Pw[j - 1:]`` and ``U[j:]`` (the first knot only shapes the first span, which lies
    left of ``a``), so ``[a] * (p + 1) + U[j + p:]`` with ``Pw[j - 1:]`` is the clamped
    form.  A run longer than ``p`` (already clamped, or degenerate with basis functions
    that vanish on the domain) keeps its last ``p + 1`` copies.
    """
    a = U[p]
    s = _multiplicity(U, a)
    if s < p:
        U, Pw = _refine(U, p, Pw, np.full(p - s, a))
        s = p
    j = int(np.searchsorted(U, a, side="left"))
    if j == 0 and s == p + 1:
        return U, Pw
    Uc = np.concatenate([np.full(p + 1, a), U[j + s :]])
    return Uc, Pw[j + s - p - 1 :]


def _clamp(U: np.ndarray, p: int, Pw: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Both ends clamped (end knots of multiplicity ``p + 1``), same curve over the same domain."""
    U, Pw = _clamp_start(U, p, Pw)
    # The end is the start of the mirrored knot vector.
    Ur, Pr = _clamp_start(-U[::-1], p, Pw[::-1])
    return -Ur[::-1], Pr[::-1]


def _is_clamped(U: np.ndarray, p: int) -> bool:
    a, b = U[p], U[-p - 1]
    return bool(U[0] == a and U[-1] == b and _multiplicity(U, a) == p + 1 and _multiplicity(U, b) == p + 1)


def _split(
    U: np.ndarray, p: int, Pw: np.ndarray, x: float
) -> tuple[tuple[np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray]]:
    """Split at the interior parameter ``x`` (subdivision by insertion to multiplicity ``p``).

    Returns the pieces over ``[U[p], x]`` and ``[x, U[n]]`` as ``(U, Pw)`` pairs; the
    cut ends are clamped, the outer ends are as in ``U``.
    """
    s = _multiplicity(U, x)
    if s < p:
        U, Pw = _refine(U, p, Pw, np.full(p - s, x))
    j = int(np.searchsorted(U, x, side="left"))  # copies of x at j .. j + p - 1, C(x) = Pw[j - 1]
    left = (np.concatenate([U[: j + p], [x]]), Pw[:j])
    right = (np.concatenate([[x], U[j:]]), Pw[j - 1 :])
    return left, right


def _bezier_net(U: np.ndarray, p: int, Pw: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Bézier control points of every non-empty span of a clamped B-spline (A5.6, by refinement).

    Returns
    -------
    breaks : (k + 1,) float64
        Distinct knots; segment ``i`` runs over ``[breaks[i], breaks[i + 1]]``.
    B : (k, p + 1, ...) float64
        Homogeneous Bézier control points of each segment.
    """
    breaks, counts = np.unique(U, return_counts=True)
    X = np.repeat(breaks[1:-1], p - counts[1:-1])
    if X.size:
        U, Pw = _refine(U, p, Pw, X)
    k = breaks.shape[0] - 1
    idx = (np.arange(k) * p)[:, None] + np.arange(p + 1)
    return breaks, Pw[idx]


def _bezier_elevation_matrix(p: int, t: int) -> np.ndarray:
    """``E`` (p + t + 1, p + 1) with ``Q = E @ P`` the Bézier control points raised from degree p to p + t.

    ``E[i, j] = C(p, j) C(t, i - j) / C(p + t, i)`` (The NURBS Book §5.5).
    """
    C = binomials(p + t)
    i = np.arange(p + t + 1)[:, None]
    j = np.arange(p + 1)[None, :]
    k = i - j
    ok = (k >= 0) & (k <= t)
    kk = np.clip(k, 0, t)
    return np.where(ok, C[p, j] * C[t, kk] / C[p + t, i], 0.0)


def _elevate(U: np.ndarray, p: int, Pw: np.ndarray, t: int) -> tuple[np.ndarray, np.ndarray]:
    """Raise the degree from ``p`` to ``p + t`` without changing the curve (scheme of The NURBS Book A5.9).

    Decompose into Bézier segments, raise each in closed form (one matrix product for
    all segments and batch rows), then remove the extra copies of every interior
    knot: a knot of multiplicity ``m`` in degree ``p`` (continuity ``C^(p-m)``) ends with
    multiplicity ``m + t``, the same continuity in degree ``p + t``.  Those removals are
    exact, so their residuals are not checked.  The result is clamped.

    Returns
    -------
    U' : knot vector of degree ``p + t``
    Qw : (n', ...) float64
    """
    U, Pw = _clamp(U, p, Pw)
    _, counts = np.unique(U, return_counts=True)
    breaks, B = _bezier_net(U, p, Pw)
    q = p + t
    E = _bezier_elevation_matrix(p, t)
    EB = np.moveaxis(np.tensordot(E, B, axes=([1], [1])), 0, 1)  # (k, q + 1, ...)
    Q = np.concatenate([EB[0], EB[1:, 1:].reshape((-1,) + EB.shape[2:])])
    k = breaks.shape[0] - 1
    Uq = np.repeat(breaks, np.concatenate([[q + 1], np.full(k - 1, q), [q + 1]]).astype(np.int64))
    # Right to left, so removals never shift the indices of knots still to be processed.
    for i in range(k - 1, 0, -1):
        for _ in range(p - int(counts[i])):
            Uq, Q, _err = _remove_once(Uq, q, Q, breaks[i])
    return Uq, Q


def _contract(U: np.ndarray, p: int, Pw: np.ndarray, x: float) -> np.ndarray:
    """``sum_i N_i,p(x) Pw[i]``: the point (or, for a batch, the row) at parameter ``x``, shape ``Pw.shape[1:]``."""
    span = _span(U, p, x)
    N = _b.basis_functions(U, p, np.array([span]), np.array([x]))[0]
    return np.tensordot(N, Pw[span - p : span + 1], axes=([0], [0]))


# ============================================================================ validation helpers


def _count(value, what: str) -> int:
    """A repeat count as a Python int >= 0."""
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
        raise InvalidInputError(f"{what} must be an integer >= 0, got {value!r}")
    if value < 0:
        raise InvalidInputError(f"{what} must be an integer >= 0, got {value}")
    return int(value)


def _round_off(domain: tuple[float, float], tol: Tolerance) -> float:
    # The caller's parameter arithmetic is trusted to tol.solver relative to the domain
    # (the same slack as coons.kernel.basis.check_parameters).
    return tol.solver * max(1.0, domain[1] - domain[0])


def _scalar_parameter(value, domain: tuple[float, float], tol: Tolerance, what: str) -> float:
    """A finite scalar inside ``domain`` (round-off outside is clamped by check_parameters)."""
    try:
        u = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise InvalidInputError(f"{what} must be a real number, got {value!r}") from exc
    if u.shape != ():
        raise InvalidInputError(f"{what} must be a single real number, got shape {u.shape}")
    return float(_b.check_parameters(u, domain, tol, what=what))


def _snap(U: np.ndarray, X: np.ndarray, slack: float) -> np.ndarray:
    """Sorted ``X``, values within ``slack`` of a knot of ``U`` (or of a smaller value of ``X``) made equal to it."""
    X = np.sort(X)
    nearest = np.clip(np.searchsorted(U, X), 1, U.shape[0] - 1)
    lo, hi = U[nearest - 1], U[nearest]
    X = np.where(np.abs(X - lo) <= slack, lo, np.where(np.abs(hi - X) <= slack, hi, X))
    # Values of X within slack of the previous one join its group (first value wins).
    starts = np.concatenate([[True], np.diff(X) > slack])
    return X[np.flatnonzero(starts)[np.cumsum(starts) - 1]]


def _knots_to_insert(U: np.ndarray, p: int, values, tol: Tolerance, what: str) -> np.ndarray:
    """Validated, snapped, sorted knots to insert; raises if a multiplicity would exceed ``p``."""
    try:
        X = np.asarray(values, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise InvalidInputError(f"{what}: expected real numbers, got {values!r}") from exc
    if X.ndim > 1:
        raise InvalidInputError(f"{what}: expected a scalar or a 1-D array of knots, got shape {X.shape}")
    X = np.atleast_1d(X)
    domain = _b.domain_of(U, p)
    X = _b.check_parameters(X, domain, tol, what=what)
    if X.size == 0:
        return X
    X = _snap(U, X, _round_off(domain, tol))
    vals, added = np.unique(X, return_counts=True)
    existing = np.searchsorted(U, vals, side="right") - np.searchsorted(U, vals, side="left")
    bad = np.flatnonzero(existing + added > p)
    if bad.size:
        i = int(bad[0])
        raise InvalidInputError(
            f"{what}: knot {float(vals[i])!r} would have multiplicity {int(existing[i] + added[i])} "
            f"(existing {int(existing[i])} + inserted {int(added[i])}), at most the degree {p} allowed"
        )
    return X


def _interior_knot(U: np.ndarray, p: int, value, tol: Tolerance, what: str) -> tuple[float, int, int]:
    """The interior knot that ``value`` names (within round-off), its last index and multiplicity."""
    domain = _b.domain_of(U, p)
    u = _scalar_parameter(value, domain, tol, what)
    interior = np.unique(U[(U > domain[0]) & (U < domain[1])])
    if interior.size:
        k = int(np.argmin(np.abs(interior - u)))
        if abs(interior[k] - u) <= _round_off(domain, tol):
            x = float(interior[k])
            r = int(np.searchsorted(U, x, side="right")) - 1
            return x, r, _multiplicity(U, x)
    listed = np.array2string(interior[:10], separator=", ") + (" ..." if interior.size > 10 else "")
    raise InvalidInputError(f"{what}: {u!r} is not an interior knot; interior knots are {listed}")


def _inside(value, domain: tuple[float, float], tol: Tolerance, what: str) -> float:
    """A parameter strictly inside ``domain``, farther than round-off from both ends."""
    u = _scalar_parameter(value, domain, tol, what)
    slack = _round_off(domain, tol)
    if not (domain[0] + slack < u < domain[1] - slack):
        raise InvalidInputError(
            f"{what}: {u!r} must lie strictly inside the domain [{domain[0]!r}, {domain[1]!r}] "
            f"(farther than {slack:.3g} from its ends)"
        )
    return u


def _axis(direction) -> int:
    if direction == "u":
        return 0
    if direction == "v":
        return 1
    raise InvalidInputError(f"direction must be 'u' or 'v', got {direction!r}")


def _homogeneous_budget(P: np.ndarray, w: np.ndarray, linear: float) -> float:
    """Homogeneous error that keeps the Euclidean error below ``linear``.

    With equal weights ``w0`` the homogeneous curve is ``w0 C``, so ``w0 * linear``;
    otherwise ``linear * w_min / (1 + |P|_max)`` (The NURBS Book eq. 5.30).
    """
    if np.all(w == w.flat[0]):
        return linear * float(w.flat[0])
    return linear * float(w.min()) / (1.0 + float(np.max(np.linalg.norm(P, axis=-1))))


def _removal_sequence(
    U: np.ndarray, p: int, Pw: np.ndarray, x: float, times: int, budget: float
) -> list[tuple[np.ndarray, np.ndarray]]:
    """``[(U, Pw), after one removal, after two, ...]`` while the summed error bounds stay within ``budget``.

    Each single removal moves the homogeneous curve by at most its error bound, so the
    sum bounds the distance to the original.  A removal that would make a weight
    non-positive ends the sequence.
    """
    seq = [(U, Pw)]
    total = 0.0
    for _ in range(times):
        U1, Q1, err = _remove_once(seq[-1][0], p, seq[-1][1], x)
        total += err
        if total > budget or np.min(Q1[..., -1]) <= 0.0:
            break
        seq.append((U1, Q1))
    return seq


def _removal_samples(U: np.ndarray, p: int, r: int, s: int, times: int) -> np.ndarray:
    """Parameters covering every span where removing ``times`` copies of ``U[r]`` can move the curve.

    Each removal changes the curve only on the supports of the basis functions around
    the knot, which reach from ``U[r - p - times]`` to ``U[r - s + p + 1 + times]`` in the
    original indices; one more knot is taken on each side.  The sampling density
    (``4 (p + 1)`` points per span) resolves a degree-``p`` deviation; it is a check, not a proof.
    """
    n = U.shape[0] - p - 1
    lo = max(p, r - p - times - 1)
    hi = min(n, r - s + p + times + 2)
    knots = np.unique(U[lo : hi + 1])
    frac = np.linspace(0.0, 1.0, 4 * (p + 1), endpoint=False)
    return np.append((knots[:-1, None] + np.diff(knots)[:, None] * frac).ravel(), knots[-1])


def _grid_samples(U: np.ndarray, p: int) -> np.ndarray:
    """``2 (p + 1)`` parameters per non-empty span of the domain, plus its end."""
    a, b = _b.domain_of(U, p)
    knots = np.unique(U[(U >= a) & (U <= b)])
    frac = np.linspace(0.0, 1.0, 2 * (p + 1), endpoint=False)
    return np.append((knots[:-1, None] + np.diff(knots)[:, None] * frac).ravel(), b)


# ============================================================================ curves


def _exact_weights(Pw: np.ndarray, source) -> np.ndarray:
    """``Pw`` with its weights restored exactly when ``source`` is polynomial.

    Insertion, elevation and splitting form convex combinations of the weights, so equal
    weights stay equal in exact arithmetic; in floating point they drift by an ulp, which
    would make a polynomial result look rational.  The points are divided by the computed
    weights first, so the geometry is untouched.
    """
    if source.is_rational:
        return Pw
    Pw = np.array(Pw, dtype=np.float64)
    w0 = float(source.weights.flat[0])
    Pw[..., :-1] *= w0 / Pw[..., -1:]
    Pw[..., -1] = w0
    return Pw


def _curve(Pw: np.ndarray, U: np.ndarray, p: int, source) -> "NurbsCurve":
    """A curve from homogeneous points; ``source`` (the input curve or surface) decides rationality."""
    from coons.kernel.curve import NurbsCurve

    return NurbsCurve.from_homogeneous(_exact_weights(Pw, source), U, p)


def curve_insert_knot(curve: "NurbsCurve", u: float, times: int = 1, tol: Tolerance | None = None) -> "NurbsCurve":
    """Insert the knot ``u`` ``times`` times; the curve is unchanged (Boehm; The NURBS Book A5.1).

    Parameters
    ----------
    curve : NurbsCurve with ``n`` control points
    u : float, inside the domain (a value within round-off of a knot is that knot)
    times : int >= 0; ``0`` returns ``curve`` itself

    Returns
    -------
    NurbsCurve with ``n + times`` control points and the same domain.

    Raises
    ------
    InvalidInputError
        ``u`` not finite or outside the domain; ``times`` negative or not an integer;
        the multiplicity of ``u`` would exceed the degree (e.g. at a clamped end).
    """
    t = resolve(tol)
    times = _count(times, "insert_knot: times")
    u = _scalar_parameter(u, curve.domain, t, "insert_knot: u")
    if times == 0:
        return curve
    return curve_refine_knots(curve, np.full(times, u), t)


def curve_refine_knots(curve: "NurbsCurve", new_knots, tol: Tolerance | None = None) -> "NurbsCurve":
    """Insert many knots at once, in any order; the curve is unchanged (The NURBS Book A5.4).

    Parameters
    ----------
    new_knots : (r,) array_like inside the domain, repeats allowed

    Returns
    -------
    NurbsCurve with ``n + r`` control points; ``curve`` itself when ``r == 0``.

    Raises
    ------
    InvalidInputError
        Knots not finite or outside the domain, or a multiplicity that would exceed the degree.
    """
    t = resolve(tol)
    p = curve.degree
    X = _knots_to_insert(curve.knots, p, new_knots, t, "refine_knots")
    if X.size == 0:
        return curve
    U, Q = _refine(curve.knots, p, curve.homogeneous, X)
    return _curve(Q, U, p, curve)


def curve_remove_knots(
    curve: "NurbsCurve", u: float, times: int = 1, tol: Tolerance | None = None
) -> tuple["NurbsCurve", int]:
    """Remove the interior knot ``u`` up to ``times`` times without moving the curve by more than ``tol.linear``.

    Runs single removals (The NURBS Book A5.8) while the summed homogeneous error
    bounds stay below the budget of eq. 5.30, then checks the result against the
    original by sampling every span it may have moved; if the check fails it falls
    back to fewer removals.  Fewer than ``times`` removals is a normal outcome, not an
    error: the count says how many were made.

    Parameters
    ----------
    u : float, an interior knot (within round-off)
    times : int, ``0 <= times <=`` multiplicity of ``u``

    Returns
    -------
    (NurbsCurve, int)
        The curve with ``k`` copies of ``u`` removed, and ``k``; ``(curve, 0)`` when no
        removal keeps the curve within ``tol.linear``.

    Raises
    ------
    InvalidInputError
        ``u`` is not an interior knot, or ``times`` is negative, not an integer or
        larger than the multiplicity of ``u``.
    """
    t = resolve(tol)
    times = _count(times, "remove_knot: times")
    p = curve.degree
    x, r, s = _interior_knot(curve.knots, p, u, t, "remove_knot: u")
    if times > s:
        raise InvalidInputError(f"remove_knot: times must be at most the multiplicity {s} of knot {x!r}, got {times}")
    if times == 0:
        return curve, 0
    budget = _homogeneous_budget(curve.control_points, curve.weights, t.linear)
    seq = _removal_sequence(curve.knots, p, curve.homogeneous, x, times, budget)
    if len(seq) == 1:
        return curve, 0
    us = _removal_samples(curve.knots, p, r, s, times)
    ref = curve.evaluate(us)
    for k in range(len(seq) - 1, 0, -1):
        cand = _curve(seq[k][1], seq[k][0], p, curve)
        if float(np.max(np.linalg.norm(cand.evaluate(us) - ref, axis=-1))) <= t.linear:
            return cand, k
    return curve, 0


def curve_remove_knot(curve: "NurbsCurve", u: float, times: int = 1, tol: Tolerance | None = None) -> "NurbsCurve":
    """:func:`curve_remove_knots` without the count: the curve with as many copies removed as the tolerance allows."""
    return curve_remove_knots(curve, u, times, tol)[0]


def curve_elevate_degree(curve: "NurbsCurve", times: int = 1) -> "NurbsCurve":
    """Raise the degree by ``times`` without changing the curve (The NURBS Book A5.9, by decomposition).

    Each distinct knot of multiplicity ``m`` (after clamping) gets multiplicity ``m + times``;
    the result is clamped, over the same domain.

    Returns
    -------
    NurbsCurve of degree ``p + times``; ``curve`` itself when ``times == 0``.

    Raises
    ------
    InvalidInputError
        ``times`` negative or not an integer.
    """
    times = _count(times, "elevate_degree: times")
    if times == 0:
        return curve
    U, Q = _elevate(curve.knots, curve.degree, curve.homogeneous, times)
    return _curve(Q, U, curve.degree + times, curve)


def curve_clamped(curve: "NurbsCurve") -> "NurbsCurve":
    """The same curve over the same domain with end knots of multiplicity ``p + 1``; ``curve`` itself if already so.

    Floating and periodic knot vectors are clamped by inserting the domain ends up to
    multiplicity ``p`` (The NURBS Book A5.1) and dropping the knots and control points
    outside the domain.
    """
    if _is_clamped(curve.knots, curve.degree):
        return curve
    U, Q = _clamp(curve.knots, curve.degree, curve.homogeneous)
    return _curve(Q, U, curve.degree, curve)


def curve_split(curve: "NurbsCurve", u: float, tol: Tolerance | None = None) -> tuple["NurbsCurve", "NurbsCurve"]:
    """Two clamped curves over ``[a, u]`` and ``[u, b]`` that together are ``curve`` (subdivision by insertion).

    Raises
    ------
    InvalidInputError
        ``u`` not strictly inside the domain (by more than round-off).
    """
    t = resolve(tol)
    u = _inside(u, curve.domain, t, "split: u")
    p = curve.degree
    U, Pw = _clamp(curve.knots, p, curve.homogeneous)
    x = float(_snap(U, np.array([u]), _round_off(curve.domain, t))[0])
    (U1, P1), (U2, P2) = _split(U, p, Pw, x)
    return _curve(P1, U1, p, curve), _curve(P2, U2, p, curve)


def curve_segment(curve: "NurbsCurve", start: float, end: float, tol: Tolerance | None = None) -> "NurbsCurve":
    """The piece of ``curve`` over ``[start, end]``, clamped, with the original parameters.

    Raises
    ------
    InvalidInputError
        ``start`` or ``end`` outside the domain, or ``end - start`` not larger than round-off.
    """
    t = resolve(tol)
    dom = curve.domain
    a = _scalar_parameter(start, dom, t, "segment: start")
    b = _scalar_parameter(end, dom, t, "segment: end")
    slack = _round_off(dom, t)
    if not b - a > slack:
        raise InvalidInputError(f"segment: need start < end (by more than {slack:.3g}), got [{a!r}, {b!r}]")
    p = curve.degree
    U, Pw = _clamp(curve.knots, p, curve.homogeneous)
    if b < dom[1] - slack:
        x = float(_snap(U, np.array([b]), slack)[0])
        (U, Pw), _ = _split(U, p, Pw, x)
    if a > dom[0] + slack:
        x = float(_snap(U, np.array([a]), slack)[0])
        _, (U, Pw) = _split(U, p, Pw, x)
    return _curve(Pw, U, p, curve)


def curve_bezier_segments(curve: "NurbsCurve") -> list["NurbsCurve"]:
    """Bézier pieces, one per non-empty knot span, each with knots ``[a]*(p+1) + [b]*(p+1)`` (The NURBS Book A5.6).

    Returns
    -------
    list of NurbsCurve, in parameter order; piece ``i`` equals ``curve`` on its span.
    """
    p = curve.degree
    U, Pw = _clamp(curve.knots, p, curve.homogeneous)
    breaks, B = _bezier_net(U, p, Pw)
    return [
        _curve(B[i], np.repeat(breaks[i : i + 2], p + 1), p, curve) for i in range(B.shape[0])
    ]


# ============================================================================ surfaces
# The surface versions move the chosen direction to axis 0 of the homogeneous net,
# run the curve algorithm with the other direction as a batch axis, and move it back.


def _net(surface: "NurbsSurface", axis: int) -> tuple[np.ndarray, int, np.ndarray]:
    U = surface.knots_u if axis == 0 else surface.knots_v
    p = surface.degree_u if axis == 0 else surface.degree_v
    return U, p, np.moveaxis(surface.homogeneous, axis, 0)


def _surface(surface: "NurbsSurface", axis: int, U: np.ndarray, p: int, Pw: np.ndarray) -> "NurbsSurface":
    """The surface with direction ``axis`` replaced by ``(U, p)`` and the net ``Pw`` (axis first)."""
    from coons.kernel.surface import NurbsSurface

    Pw = _exact_weights(np.moveaxis(Pw, 0, axis), surface)
    if axis == 0:
        return NurbsSurface.from_homogeneous(Pw, U, surface.knots_v, p, surface.degree_v)
    return NurbsSurface.from_homogeneous(Pw, surface.knots_u, U, surface.degree_u, p)


def surface_insert_knot(
    surface: "NurbsSurface", direction: str, value: float, times: int = 1, tol: Tolerance | None = None
) -> "NurbsSurface":
    """Insert ``value`` ``times`` times into the ``"u"`` or ``"v"`` knot vector (The NURBS Book A5.3).

    Raises
    ------
    InvalidInputError
        Bad ``direction``; otherwise as :func:`curve_insert_knot`.
    """
    t = resolve(tol)
    axis = _axis(direction)
    U, p, _ = _net(surface, axis)
    times = _count(times, "insert_knot: times")
    u = _scalar_parameter(value, _b.domain_of(U, p), t, f"insert_knot: {direction}")
    if times == 0:
        return surface
    return surface_refine_knots(surface, direction, np.full(times, u), t)


def surface_refine_knots(
    surface: "NurbsSurface", direction: str, new_knots, tol: Tolerance | None = None
) -> "NurbsSurface":
    """Insert many knots into one direction at once (The NURBS Book A5.5: A5.4 on every row of the net).

    Raises
    ------
    InvalidInputError
        Bad ``direction``; otherwise as :func:`curve_refine_knots`.
    """
    t = resolve(tol)
    axis = _axis(direction)
    U, p, Pw = _net(surface, axis)
    X = _knots_to_insert(U, p, new_knots, t, f"refine_knots ({direction})")
    if X.size == 0:
        return surface
    U, Q = _refine(U, p, Pw, X)
    return _surface(surface, axis, U, p, Q)


def surface_remove_knots(
    surface: "NurbsSurface", direction: str, value: float, times: int = 1, tol: Tolerance | None = None
) -> tuple["NurbsSurface", int]:
    """Remove a knot of one direction up to ``times`` times, moving the surface by at most ``tol.linear``.

    As :func:`curve_remove_knots` with every row of the net removed at once (The NURBS
    Book A5.8 and §5.4); the sampled check covers the affected spans of ``direction``
    times the whole other direction.

    Returns
    -------
    (NurbsSurface, int)
    """
    t = resolve(tol)
    axis = _axis(direction)
    U, p, Pw = _net(surface, axis)
    times = _count(times, "remove_knot: times")
    x, r, s = _interior_knot(U, p, value, t, f"remove_knot: {direction}")
    if times > s:
        raise InvalidInputError(f"remove_knot: times must be at most the multiplicity {s} of knot {x!r}, got {times}")
    if times == 0:
        return surface, 0
    budget = _homogeneous_budget(surface.control_points, surface.weights, t.linear)
    seq = _removal_sequence(U, p, Pw, x, times, budget)
    if len(seq) == 1:
        return surface, 0
    along = _removal_samples(U, p, r, s, times)
    if axis == 0:
        grid = (along, _grid_samples(surface.knots_v, surface.degree_v))
    else:
        grid = (_grid_samples(surface.knots_u, surface.degree_u), along)
    ref = surface.evaluate_grid(*grid)
    for k in range(len(seq) - 1, 0, -1):
        cand = _surface(surface, axis, seq[k][0], p, seq[k][1])
        if float(np.max(np.linalg.norm(cand.evaluate_grid(*grid) - ref, axis=-1))) <= t.linear:
            return cand, k
    return surface, 0


def surface_remove_knot(
    surface: "NurbsSurface", direction: str, value: float, times: int = 1, tol: Tolerance | None = None
) -> "NurbsSurface":
    """:func:`surface_remove_knots` without the count."""
    return surface_remove_knots(surface, direction, value, times, tol)[0]


def surface_elevate_degree(surface: "NurbsSurface", times_u: int = 0, times_v: int = 0) -> "NurbsSurface":
    """Raise the degrees by ``times_u`` and ``times_v`` without changing the surface (The NURBS Book A5.10).

    A direction that is elevated comes out clamped; one with ``times == 0`` is untouched.

    Raises
    ------
    InvalidInputError
        A count negative or not an integer.
    """
    counts = (_count(times_u, "elevate_degree: times_u"), _count(times_v, "elevate_degree: times_v"))
    out = surface
    for axis, times in enumerate(counts):
        if times:
            U, p, Pw = _net(out, axis)
            U, Q = _elevate(U, p, Pw, times)
            out = _surface(out, axis, U, p + times, Q)
    return out


def surface_split(
    surface: "NurbsSurface", direction: str, value: float, tol: Tolerance | None = None
) -> tuple["NurbsSurface", "NurbsSurface"]:
    """Split along the iso-line ``direction = value`` into two surfaces, clamped in ``direction``.

    Returns
    -------
    (NurbsSurface, NurbsSurface)
        The pieces over ``[a, value]`` and ``[value, b]`` of ``direction``.

    Raises
    ------
    InvalidInputError
        Bad ``direction``; ``value`` not strictly inside the domain.
    """
    t = resolve(tol)
    axis = _axis(direction)
    U, p, Pw = _net(surface, axis)
    dom = _b.domain_of(U, p)
    x = _inside(value, dom, t, f"split: {direction}")
    U, Pw = _clamp(U, p, Pw)
    x = float(_snap(U, np.array([x]), _round_off(dom, t))[0])
    (U1, P1), (U2, P2) = _split(U, p, Pw, x)
    return _surface(surface, axis, U1, p, P1), _surface(surface, axis, U2, p, P2)


def surface_bezier_patches(surface: "NurbsSurface") -> list[list["NurbsSurface"]]:
    """Bézier patches ``[i][j]`` over span ``i`` in u and span ``j`` in v (The NURBS Book A5.7).

    Each patch has knots ``[a]*(pu+1) + [b]*(pu+1)`` and ``[c]*(pv+1) + [d]*(pv+1)``.
    """
    from coons.kernel.surface import NurbsSurface

    pu, pv = surface.degree_u, surface.degree_v
    Uu, Pw = _clamp(surface.knots_u, pu, surface.homogeneous)
    bu, Bu = _bezier_net(Uu, pu, Pw)  # (ku, pu+1, nv, d+1)
    Uv, Pv = _clamp(surface.knots_v, pv, np.moveaxis(Bu, 2, 0))  # (nv, ku, pu+1, d+1)
    bv, Bv = _bezier_net(Uv, pv, Pv)  # (kv, pv+1, ku, pu+1, d+1)
    patches = Bv.transpose(2, 0, 3, 1, 4)  # (ku, kv, pu+1, pv+1, d+1)
    return [
        [
            NurbsSurface.from_homogeneous(
                _exact_weights(patches[i, j], surface), np.repeat(bu[i : i + 2], pu + 1), np.repeat(bv[j : j + 2], pv + 1), pu, pv
            )
            for j in range(patches.shape[1])
        ]
        for i in range(patches.shape[0])
    ]


def surface_iso_curve(
    surface: "NurbsSurface", direction: str, value: float, tol: Tolerance | None = None
) -> "NurbsCurve":
    """The iso-parametric curve ``direction = value``, exact (rational surfaces give rational curves).

    ``direction="u"`` fixes ``u = value`` and returns the curve in ``v`` (knots
    ``knots_v``, degree ``degree_v``); ``"v"`` the converse.  Its homogeneous control
    points are the net contracted with the basis functions at ``value`` (The NURBS
    Book §4.5 and eq. 4.16).

    Raises
    ------
    InvalidInputError
        Bad ``direction``; ``value`` not finite or outside the domain.
    """
    t = resolve(tol)
    axis = _axis(direction)
    U, p, Pw = _net(surface, axis)
    x = _scalar_parameter(value, _b.domain_of(U, p), t, f"iso_curve: {direction}")
    Cw = _contract(U, p, Pw, x)
    if axis == 0:
        return _curve(Cw, surface.knots_v, surface.degree_v, surface)
    return _curve(Cw, surface.knots_u, surface.degree_u, surface)
