"""Exact geometric predicates on float64 coordinates: orientation, in-circle, segment relations.

Every function here returns the *exact* sign of a polynomial in the input coordinates,
as if the floats were real numbers: a float64 evaluation decides every entry whose
determinant is farther from zero than Shewchuk's static error bound, and the rare
ambiguous entries are recomputed exactly with Python integers (each float is a dyadic
rational ``m · 2^e``; the entry's coordinates are scaled by a common power of two, which
leaves the sign of a homogeneous polynomial unchanged).  Exact segment–segment
relations and exact intersection points (as :class:`fractions.Fraction` with their
nearest-float rounding) are built on the same filter.  The module deliberately does
not use tolerances: there is no epsilon in any decision, and it does not construct
anything beyond intersection points of two segments (arrangements and Booleans live in
:mod:`coons.booleans.planar`).

Sign conventions (Shewchuk 1997, "Adaptive precision floating-point arithmetic and fast
robust geometric predicates", Discrete Comput. Geom. 18:305–363):

``orient2d(a, b, c)``
    +1 if ``a, b, c`` turn counter-clockwise, -1 clockwise, 0 collinear.
``orient3d(a, b, c, d)``
    sign of ``det[a - d; b - d; c - d]``: +1 if ``d`` lies below the plane through
    ``a, b, c`` (below = the side from which ``a, b, c`` appear clockwise).
``incircle(a, b, c, d)``
    +1 if ``d`` lies inside the circle through the counter-clockwise ``a, b, c``, -1
    outside, 0 on it (the sign flips when ``a, b, c`` are clockwise).
``cross_sign(a0, a1, b0, b1)``
    sign of the cross product ``(a1 - a0) × (b1 - b0)``.

All predicates broadcast: points are arrays ``(..., 2)`` (``(..., 3)`` for orient3d) and
the result is an ``int8`` array of the broadcast shape without the last axis.

Underflow and overflow are handled by the filter: an entry whose float permanent is so
small that products may have lost bits to underflow, or whose evaluation overflowed,
is sent to the exact stage.
"""

from __future__ import annotations

import enum
from fractions import Fraction
from typing import Callable, NamedTuple

import numpy as np

from coons.errors import InvalidInputError

__all__ = [
    "orient2d",
    "orient3d",
    "incircle",
    "orient2d_one",
    "incircle_one",
    "cross_sign",
    "SegmentRelation",
    "classify_segments",
    "IntersectionPoints",
    "segment_intersection_points",
    "lex_less",
]

_EPS = 2.0**-53  # unit round-off of float64 (Shewchuk's epsilon)
# Shewchuk's stage-A error bounds (ccwerrboundA, o3derrboundA, iccerrboundA): |exact - float det|
# is at most bound * permanent whenever no operation underflows or overflows.
_ORIENT2D_BOUND = (3.0 + 16.0 * _EPS) * _EPS
_ORIENT3D_BOUND = (7.0 + 56.0 * _EPS) * _EPS
_INCIRCLE_BOUND = (10.0 + 96.0 * _EPS) * _EPS
# A product that underflows into the subnormal range carries an absolute error up to 2^-1075
# instead of a relative one.  With a permanent >= 2^-900 a handful of such errors stays
# below the 16·eps² · permanent slack of the bounds above, so the filter remains valid;
# smaller permanents go to the exact stage.
_UNDERFLOW_GUARD = 2.0**-900
#: Entries per block of the vectorised kernels: the float temporaries (a few hundred KB) stay in
#: cache and are recycled, instead of faulting in fresh pages for every large array.
_BLOCK = 1 << 15


# ---------------------------------------------------------------------- exact stage
def _exact_integers(values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Each row of ``values`` as Python integers scaled by a common power of two.

    Parameters
    ----------
    values : (m, k) float64, finite

    Returns
    -------
    X : (m, k) object array of int
    s : (m,) int64
        ``values[i, j] == X[i, j] * 2**s[i]`` exactly.
    """
    mant, expo = np.frexp(values)
    M = (mant * 2.0**53).astype(np.int64)  # exact: a float64 significand has 53 bits
    E = expo.astype(np.int64) - 53
    zero = M == 0
    big = np.iinfo(np.int64).max
    s = np.where(zero, big, E).min(axis=1)
    s = np.where(s == big, 0, s)
    shift = np.where(zero, 0, E - s[:, None])
    return M.astype(object) << shift.astype(object), s


def _exact_signs(poly: Callable[..., np.ndarray], columns: np.ndarray) -> np.ndarray:
    """Exact signs of a homogeneous polynomial of the columns, row by row (int8)."""
    if columns.shape[0] == 0:
        return np.zeros(0, dtype=np.int8)
    X, _ = _exact_integers(columns)
    det = poly(*X.T)
    return (det > 0).astype(np.int8) - (det < 0).astype(np.int8)


def _filtered(
    det: np.ndarray, permanent: np.ndarray, bound: float, exact_zero: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """Signs certified by the float filter, and the mask of entries it cannot certify.

    ``exact_zero`` marks entries known to be exactly zero (every product has an exactly
    zero factor); they are certified with sign 0 instead of going to the exact stage.
    """
    err = bound * permanent
    sign = (det > err).astype(np.int8) - (-det > err).astype(np.int8)
    # NaN/inf (overflow) compare False above and land in the ambiguous set too.
    ambiguous = (sign == 0) | (permanent < _UNDERFLOW_GUARD) | ~np.isfinite(permanent)
    if exact_zero is not None:
        ambiguous &= ~exact_zero
    sign[ambiguous] = 0
    return sign, ambiguous


# ---------------------------------------------------------------------- polynomials
# The exact stage evaluates these on object arrays of Python ints; the float stage spells
# them out with its partial products, which it needs for the permanent.
def _orient2d_poly(ax, ay, bx, by, cx, cy):
    return (ax - cx) * (by - cy) - (ay - cy) * (bx - cx)


def _cross_poly(a0x, a0y, a1x, a1y, b0x, b0y, b1x, b1y):
    return (a1x - a0x) * (b1y - b0y) - (a1y - a0y) * (b1x - b0x)


def _orient3d_poly(ax, ay, az, bx, by, bz, cx, cy, cz, dx, dy, dz):
    adx, ady, adz = ax - dx, ay - dy, az - dz
    bdx, bdy, bdz = bx - dx, by - dy, bz - dz
    cdx, cdy, cdz = cx - dx, cy - dy, cz - dz
    return adz * (bdx * cdy - cdx * bdy) + bdz * (cdx * ady - adx * cdy) + cdz * (adx * bdy - bdx * ady)


def _incircle_poly(ax, ay, bx, by, cx, cy, dx, dy):
    adx, ady = ax - dx, ay - dy
    bdx, bdy = bx - dx, by - dy
    cdx, cdy = cx - dx, cy - dy
    return (
        (adx * adx + ady * ady) * (bdx * cdy - cdx * bdy)
        + (bdx * bdx + bdy * bdy) * (cdx * ady - adx * cdy)
        + (cdx * cdx + cdy * cdy) * (adx * bdy - bdx * ady)
    )


# ---------------------------------------------------------------------- flat kernels
def _blocked(kernel: Callable[..., np.ndarray], *arrays: np.ndarray) -> np.ndarray:
    m = arrays[0].shape[0]
    if m <= _BLOCK:
        return kernel(*arrays)
    out = np.empty(m, dtype=np.int8)
    for start in range(0, m, _BLOCK):
        out[start : start + _BLOCK] = kernel(*(x[start : start + _BLOCK] for x in arrays))
    return out


def _orient2d_flat(a: np.ndarray, b: np.ndarray, c: np.ndarray) -> np.ndarray:
    """orient2d on (m, 2) float arrays, no validation (Shewchuk 1997, orient2d stage A + exact)."""
    return _blocked(_orient2d_block, a, b, c)


def _orient2d_block(a: np.ndarray, b: np.ndarray, c: np.ndarray) -> np.ndarray:
    with np.errstate(all="ignore"):  # overflow and underflow are caught by the filter
        acx, acy = a[:, 0] - c[:, 0], a[:, 1] - c[:, 1]
        bcx, bcy = b[:, 0] - c[:, 0], b[:, 1] - c[:, 1]
        left, right = acx * bcy, acy * bcx
        # A float difference is 0 only if the operands are equal, so a zero factor is exact.
        zero = ((acx == 0) | (bcy == 0)) & ((acy == 0) | (bcx == 0))
        sign, amb = _filtered(left - right, np.abs(left) + np.abs(right), _ORIENT2D_BOUND, zero)
    if amb.any():
        idx = np.flatnonzero(amb)
        sign[idx] = _exact_signs(_orient2d_poly, np.concatenate([a[idx], b[idx], c[idx]], axis=1))
    return sign


def _cross_flat(a0: np.ndarray, a1: np.ndarray, b0: np.ndarray, b1: np.ndarray) -> np.ndarray:
    """cross_sign on (m, 2) float arrays, no validation (same structure and bound as orient2d)."""
    return _blocked(_cross_block, a0, a1, b0, b1)


def _cross_block(a0: np.ndarray, a1: np.ndarray, b0: np.ndarray, b1: np.ndarray) -> np.ndarray:
    with np.errstate(all="ignore"):  # overflow and underflow are caught by the filter
        dax, day = a1[:, 0] - a0[:, 0], a1[:, 1] - a0[:, 1]
        dbx, dby = b1[:, 0] - b0[:, 0], b1[:, 1] - b0[:, 1]
        left, right = dax * dby, day * dbx
        zero = ((dax == 0) | (dby == 0)) & ((day == 0) | (dbx == 0))  # exact zeros, as in orient2d
        sign, amb = _filtered(left - right, np.abs(left) + np.abs(right), _ORIENT2D_BOUND, zero)
    if amb.any():
        idx = np.flatnonzero(amb)
        cols = np.concatenate([a0[idx], a1[idx], b0[idx], b1[idx]], axis=1)
        sign[idx] = _exact_signs(_cross_poly, cols)
    return sign


# ---------------------------------------------------------------------- public predicates
def _broadcast_points(points: tuple, dim: int, names: str) -> tuple[tuple[int, ...], list[np.ndarray]]:
    arrays = [np.asarray(p, dtype=np.float64) for p in points]
    for name, arr in zip(names, arrays):
        if arr.ndim == 0 or arr.shape[-1] != dim:
            raise InvalidInputError(f"{name}: expected points of shape (..., {dim}), got shape {arr.shape}")
        # A NaN or inf makes the sum non-finite; only then (or when a finite sum overflows) is every
        # coordinate tested (one reduction instead of a boolean temporary per array).
        with np.errstate(over="ignore", invalid="ignore"):
            total = np.add.reduce(arr, axis=None)
        if not np.isfinite(total) and not np.all(np.isfinite(arr)):
            raise InvalidInputError(f"{name}: coordinates must be finite, got NaN or inf")
    shape0 = arrays[0].shape
    if any(a.shape != shape0 for a in arrays[1:]):
        try:
            arrays = np.broadcast_arrays(*arrays)
        except ValueError as exc:
            shapes = ", ".join(str(a.shape) for a in arrays)
            raise InvalidInputError(f"point arrays do not broadcast: shapes {shapes}") from exc
    shape = arrays[0].shape[:-1]
    return shape, [a if a.ndim == 2 else a.reshape(-1, dim) for a in arrays]


def orient2d(a, b, c) -> np.ndarray:
    """Exact orientation of the triangles ``(a, b, c)``.

    Parameters
    ----------
    a, b, c : (..., 2) array_like, broadcasting

    Returns
    -------
    (...) int8
        +1 counter-clockwise, -1 clockwise, 0 collinear; exact for every float input
        (Shewchuk 1997: float filter with ccwerrboundA, exact integer fallback).

    Raises
    ------
    InvalidInputError
        A last axis other than 2, NaN or inf coordinates, shapes that do not broadcast.

    Examples
    --------
    >>> int(orient2d([0.0, 0.0], [1.0, 0.0], [0.0, 1.0]))
    1
    >>> e = 2.0**-53   # naive float evaluation says 0 here
    >>> int(orient2d([0.5 + e, 0.5], [12.0, 12.0], [24.0, 24.0]))
    -1
    """
    shape, (A, B, C) = _broadcast_points((a, b, c), 2, "abc")
    return _orient2d_flat(A, B, C).reshape(shape)


def cross_sign(a0, a1, b0, b1) -> np.ndarray:
    """Exact sign of the cross product ``(a1 - a0) × (b1 - b0)`` of two difference vectors.

    Parameters
    ----------
    a0, a1, b0, b1 : (..., 2) array_like, broadcasting

    Returns
    -------
    (...) int8
        +1 if ``b1 - b0`` points counter-clockwise of ``a1 - a0``, -1 clockwise, 0 parallel
        (or a zero vector).  Same float filter as orient2d (the polynomial has the same
        structure: two products of rounded differences), exact fallback.

    Raises
    ------
    InvalidInputError
        A last axis other than 2, NaN or inf coordinates, shapes that do not broadcast.
    """
    shape, (A0, A1, B0, B1) = _broadcast_points((a0, a1, b0, b1), 2, ("a0", "a1", "b0", "b1"))
    return _cross_flat(A0, A1, B0, B1).reshape(shape)


def orient3d(a, b, c, d) -> np.ndarray:
    """Exact sign of ``det[a - d; b - d; c - d]`` (Shewchuk 1997, orient3d).

    Parameters
    ----------
    a, b, c, d : (..., 3) array_like, broadcasting

    Returns
    -------
    (...) int8
        +1 if ``d`` lies below the plane through ``a, b, c`` (seen from above, ``a, b, c``
        are counter-clockwise), -1 above, 0 coplanar.

    Raises
    ------
    InvalidInputError
        A last axis other than 3, NaN or inf coordinates, shapes that do not broadcast.

    Examples
    --------
    >>> int(orient3d([0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, -1]))
    1
    """
    shape, (A, B, C, D) = _broadcast_points((a, b, c, d), 3, "abcd")
    with np.errstate(all="ignore"):  # overflow and underflow are caught by the filter
        sign, amb = _orient3d_filter(A, B, C, D)
    if amb.any():
        idx = np.flatnonzero(amb)
        sign[idx] = _exact_signs(_orient3d_poly, np.concatenate([A[idx], B[idx], C[idx], D[idx]], axis=1))
    return sign.reshape(shape)


def _orient3d_filter(A, B, C, D):
    ad, bd, cd = A - D, B - D, C - D
    bdxcdy, cdxbdy = bd[:, 0] * cd[:, 1], cd[:, 0] * bd[:, 1]
    cdxady, adxcdy = cd[:, 0] * ad[:, 1], ad[:, 0] * cd[:, 1]
    adxbdy, bdxady = ad[:, 0] * bd[:, 1], bd[:, 0] * ad[:, 1]
    det = ad[:, 2] * (bdxcdy - cdxbdy) + bd[:, 2] * (cdxady - adxcdy) + cd[:, 2] * (adxbdy - bdxady)
    permanent = (
        (np.abs(bdxcdy) + np.abs(cdxbdy)) * np.abs(ad[:, 2])
        + (np.abs(cdxady) + np.abs(adxcdy)) * np.abs(bd[:, 2])
        + (np.abs(adxbdy) + np.abs(bdxady)) * np.abs(cd[:, 2])
    )
    return _filtered(det, permanent, _ORIENT3D_BOUND)


def incircle(a, b, c, d) -> np.ndarray:
    """Exact in-circle test (Shewchuk 1997, incircle).

    Parameters
    ----------
    a, b, c, d : (..., 2) array_like, broadcasting

    Returns
    -------
    (...) int8
        +1 if ``d`` lies inside the circle through ``a, b, c`` when those are
        counter-clockwise (outside when clockwise), -1 on the other side, 0 cocircular.

    Raises
    ------
    InvalidInputError
        A last axis other than 2, NaN or inf coordinates, shapes that do not broadcast.

    Examples
    --------
    >>> int(incircle([1, 0], [0, 1], [-1, 0], [0, -1]))
    0
    """
    shape, (A, B, C, D) = _broadcast_points((a, b, c, d), 2, "abcd")
    with np.errstate(all="ignore"):  # overflow and underflow are caught by the filter
        sign, amb = _incircle_filter(A, B, C, D)
    if amb.any():
        idx = np.flatnonzero(amb)
        sign[idx] = _exact_signs(_incircle_poly, np.concatenate([A[idx], B[idx], C[idx], D[idx]], axis=1))
    return sign.reshape(shape)


def _incircle_filter(A, B, C, D):
    ad, bd, cd = A - D, B - D, C - D
    bdxcdy, cdxbdy = bd[:, 0] * cd[:, 1], cd[:, 0] * bd[:, 1]
    cdxady, adxcdy = cd[:, 0] * ad[:, 1], ad[:, 0] * cd[:, 1]
    adxbdy, bdxady = ad[:, 0] * bd[:, 1], bd[:, 0] * ad[:, 1]
    alift = ad[:, 0] * ad[:, 0] + ad[:, 1] * ad[:, 1]
    blift = bd[:, 0] * bd[:, 0] + bd[:, 1] * bd[:, 1]
    clift = cd[:, 0] * cd[:, 0] + cd[:, 1] * cd[:, 1]
    det = alift * (bdxcdy - cdxbdy) + blift * (cdxady - adxcdy) + clift * (adxbdy - bdxady)
    permanent = (
        (np.abs(bdxcdy) + np.abs(cdxbdy)) * alift
        + (np.abs(cdxady) + np.abs(adxcdy)) * blift
        + (np.abs(adxbdy) + np.abs(bdxady)) * clift
    )
    return _filtered(det, permanent, _INCIRCLE_BOUND)


# ---------------------------------------------------------------------- segments
class SegmentRelation(enum.IntEnum):
    """How two closed segments meet (codes returned by :func:`classify_segments`)."""

    DISJOINT = 0  #: no common point
    CROSSING = 1  #: one common point, interior to both segments
    TOUCHING = 2  #: one common point, an endpoint of at least one segment
    OVERLAP = 3  #: collinear, sharing a sub-segment of positive length


def lex_less(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``a < b`` in lexicographic (x, then y) order, exactly, row by row.

    Parameters
    ----------
    a, b : (..., 2) float64

    Returns
    -------
    (...) bool
    """
    return (a[..., 0] < b[..., 0]) | ((a[..., 0] == b[..., 0]) & (a[..., 1] < b[..., 1]))


def _on_closed_segment(p0: np.ndarray, p1: np.ndarray, r: np.ndarray) -> np.ndarray:
    """For ``r`` collinear with ``p0, p1`` (exactly): does it lie on the closed segment?"""
    lo = np.where(lex_less(p1, p0)[:, None], p1, p0)
    hi = np.where(lex_less(p1, p0)[:, None], p0, p1)
    return ~lex_less(r, lo) & ~lex_less(hi, r)


def _classify_flat(p0, p1, q0, q1) -> tuple[np.ndarray, np.ndarray]:
    """Relations of (m, 2) segment pairs and the four orientations (4, m)."""
    m = p0.shape[0]
    if m > _BLOCK:
        rel = np.empty(m, dtype=np.int8)
        o = np.empty((4, m), dtype=np.int8)
        for start in range(0, m, _BLOCK):
            sl = slice(start, start + _BLOCK)
            rel[sl], o[:, sl] = _classify_flat(p0[sl], p1[sl], q0[sl], q1[sl])
        return rel, o
    o = _orient2d_flat(
        np.concatenate([p0, p0, q0, q0]), np.concatenate([p1, p1, q1, q1]), np.concatenate([q0, q1, p0, p1])
    ).reshape(4, m)
    o1, o2, o3, o4 = o
    rel = np.full(m, SegmentRelation.TOUCHING, dtype=np.int8)
    separated = (o1 * o2 > 0) | (o3 * o4 > 0)
    crossing = (o1 * o2 < 0) & (o3 * o4 < 0)
    collinear = (o1 == 0) & (o2 == 0) & (o3 == 0) & (o4 == 0)
    rel[separated] = SegmentRelation.DISJOINT
    rel[crossing] = SegmentRelation.CROSSING
    if collinear.any():
        i = np.flatnonzero(collinear)
        a0, a1, b0, b1 = p0[i], p1[i], q0[i], q1[i]
        swap_a, swap_b = lex_less(a1, a0)[:, None], lex_less(b1, b0)[:, None]
        alo, ahi = np.where(swap_a, a1, a0), np.where(swap_a, a0, a1)
        blo, bhi = np.where(swap_b, b1, b0), np.where(swap_b, b0, b1)
        lo = np.where(lex_less(alo, blo)[:, None], blo, alo)  # the larger of the two starts
        hi = np.where(lex_less(ahi, bhi)[:, None], ahi, bhi)  # the smaller of the two ends
        r = np.where(
            lex_less(lo, hi),
            SegmentRelation.OVERLAP,
            np.where(lex_less(hi, lo), SegmentRelation.DISJOINT, SegmentRelation.TOUCHING),
        )
        rel[i] = r
    return rel, o


def _segment_arrays(p0, p1, q0, q1) -> tuple[tuple[int, ...], list[np.ndarray]]:
    return _broadcast_points((p0, p1, q0, q1), 2, ("p0", "p1", "q0", "q1"))


def classify_segments(p0, p1, q0, q1) -> np.ndarray:
    """Exact relation of the closed segments ``[p0, p1]`` and ``[q0, q1]``.

    Parameters
    ----------
    p0, p1, q0, q1 : (..., 2) array_like, broadcasting
        Segment endpoints; a segment may be a single point (``p0 == p1``).

    Returns
    -------
    (...) int8
        :class:`SegmentRelation` codes: DISJOINT, CROSSING (a single point interior to
        both), TOUCHING (a single common point that is an endpoint of one of them, collinear
        segments meeting end to end included), OVERLAP (collinear with a common piece of
        positive length).  Decided by four exact orientations and exact coordinate
        comparisons (Cormen et al., "Introduction to Algorithms" §33.1, with Shewchuk's
        exact orient2d).

    Raises
    ------
    InvalidInputError
        Bad shapes, NaN or inf.

    Examples
    --------
    >>> int(classify_segments([0, 0], [2, 2], [0, 2], [2, 0])) == SegmentRelation.CROSSING
    True
    >>> int(classify_segments([0, 0], [2, 0], [1, 0], [3, 0])) == SegmentRelation.OVERLAP
    True
    """
    shape, (P0, P1, Q0, Q1) = _segment_arrays(p0, p1, q0, q1)
    rel, _ = _classify_flat(P0, P1, Q0, Q1)
    return rel.reshape(shape)


class IntersectionPoints(NamedTuple):
    """Exact intersection points and their rounding.

    Attributes
    ----------
    x, y : (k,) object arrays of fractions.Fraction
        The exact coordinates.
    rounded : (k, 2) float64
        The nearest float64 to each coordinate (round half to even): at most 0.5 ulp away.
    """

    x: np.ndarray
    y: np.ndarray
    rounded: np.ndarray


class _Rationals(NamedTuple):
    """Exact points as reduced fractions ``(nx / dx, ny / dy)`` (object arrays of int, ``d > 0``)
    with their nearest floats ``rounded`` (k, 2)."""

    nx: np.ndarray
    dx: np.ndarray
    ny: np.ndarray
    dy: np.ndarray
    rounded: np.ndarray


def _crossing_rationals(p0, p1, q0, q1) -> _Rationals:
    """Exact common points of (m, 2) segment pairs on non-parallel lines (crossing or touching):
    ``p0 + t (p1 - p0)`` with ``t = ((q0 - p0) × e) / (d × e)``, ``d = p1 - p0``, ``e = q1 - q0``,
    in integer arithmetic on the pair's common power-of-two scale, then reduced."""
    m = p0.shape[0]
    if m == 0:
        z = np.zeros(0, dtype=object)
        return _Rationals(z, z, z, z, np.zeros((0, 2)))
    X, s = _exact_integers(np.concatenate([p0, p1, q0, q1], axis=1))
    P0x, P0y, P1x, P1y, Q0x, Q0y, Q1x, Q1y = X.T
    dx, dy = P1x - P0x, P1y - P0y
    ex, ey = Q1x - Q0x, Q1y - Q0y
    den = dx * ey - dy * ex
    tnum = (Q0x - P0x) * ey - (Q0y - P0y) * ex
    # x = 2^s (P0x den + tnum dx) / den: make den positive, then put 2^|s| on the numerator
    # (s >= 0) or on the denominator (s < 0).
    sign = np.where(den < 0, -1, 1).astype(object)
    nx = (P0x * den + tnum * dx) * sign
    ny = (P0y * den + tnum * dy) * sign
    den = den * sign
    up = np.maximum(s, 0).astype(object)
    down = np.maximum(-s, 0).astype(object)
    nx, ny, den = nx << up, ny << up, den << down
    gx, gy = np.gcd(nx, den), np.gcd(ny, den)
    nx, dxr = nx // gx, den // gx
    ny, dyr = ny // gy, den // gy
    rounded = np.stack([(nx / dxr).astype(np.float64), (ny / dyr).astype(np.float64)], axis=1)
    return _Rationals(nx, dxr, ny, dyr, rounded)


def _crossing_fractions(p0, p1, q0, q1) -> tuple[list[Fraction], list[Fraction]]:
    """The points of :func:`_crossing_rationals` as Fractions."""
    r = _crossing_rationals(p0, p1, q0, q1)
    fx = [Fraction(a, b) for a, b in zip(r.nx.tolist(), r.dx.tolist())]
    fy = [Fraction(a, b) for a, b in zip(r.ny.tolist(), r.dy.tolist())]
    return fx, fy


def segment_intersection_points(p0, p1, q0, q1) -> IntersectionPoints:
    """The exact common point of segment pairs that meet in exactly one point.

    Parameters
    ----------
    p0, p1, q0, q1 : (k, 2) array_like
        Segment pairs whose relation is CROSSING or TOUCHING.

    Returns
    -------
    IntersectionPoints
        Exact rational coordinates (:class:`fractions.Fraction`) and their nearest floats.
        A crossing point is ``p0 + t (p1 - p0)`` evaluated in integer arithmetic; a touching
        point is the endpoint that lies on the other segment.

    Raises
    ------
    InvalidInputError
        Bad shapes, NaN or inf, or a pair that is DISJOINT or OVERLAPs (named by index).

    Examples
    --------
    >>> r = segment_intersection_points([[0, 0]], [[1, 1]], [[0, 1]], [[3, 0]])
    >>> (r.x[0], r.y[0])
    (Fraction(3, 4), Fraction(3, 4))
    """
    shape, (P0, P1, Q0, Q1) = _segment_arrays(p0, p1, q0, q1)
    if len(shape) != 1:
        raise InvalidInputError(f"expected (k, 2) arrays of segment endpoints, got broadcast shape {shape + (2,)}")
    rel, o = _classify_flat(P0, P1, Q0, Q1)
    bad = np.flatnonzero((rel != SegmentRelation.CROSSING) & (rel != SegmentRelation.TOUCHING))
    if bad.size:
        i = int(bad[0])
        raise InvalidInputError(
            f"pair {i}: expected segments meeting in one point (CROSSING or TOUCHING), "
            f"got {SegmentRelation(int(rel[i])).name}"
        )
    k = P0.shape[0]
    x = np.empty(k, dtype=object)
    y = np.empty(k, dtype=object)
    cross = np.flatnonzero(rel == SegmentRelation.CROSSING)
    fx, fy = _crossing_fractions(P0[cross], P1[cross], Q0[cross], Q1[cross])
    x[cross], y[cross] = fx, fy  # (lists assigned element-wise into the object arrays)
    touch = np.flatnonzero(rel == SegmentRelation.TOUCHING)
    if touch.size:
        o1, o2, o3, o4 = o[:, touch]
        a0, a1, b0, b1 = P0[touch], P1[touch], Q0[touch], Q1[touch]
        # The common point is an endpoint lying on the other (closed) segment.
        cand = [
            (b0, (o1 == 0) & _on_closed_segment(a0, a1, b0)),
            (b1, (o2 == 0) & _on_closed_segment(a0, a1, b1)),
            (a0, (o3 == 0) & _on_closed_segment(b0, b1, a0)),
            (a1, (o4 == 0) & _on_closed_segment(b0, b1, a1)),
        ]
        point = np.empty((touch.size, 2))
        done = np.zeros(touch.size, dtype=bool)
        for pts, ok in reversed(cand):
            point[ok] = pts[ok]
            done |= ok
        x[touch] = [Fraction(v) for v in point[:, 0].tolist()]
        y[touch] = [Fraction(v) for v in point[:, 1].tolist()]
    rounded = np.array([[float(a), float(b)] for a, b in zip(x.tolist(), y.tolist())], dtype=np.float64).reshape(k, 2)
    return IntersectionPoints(x, y, rounded)


def orient2d_one(a, b, c) -> int:
    """:func:`orient2d` of one triangle, as a Python int (no array overhead: for loops that test one at a time).

    Parameters
    ----------
    a, b, c : (2,) sequences of float
    """
    ax, ay = float(a[0]), float(a[1])
    bx, by = float(b[0]), float(b[1])
    cx, cy = float(c[0]), float(c[1])
    left = (ax - cx) * (by - cy)
    right = (ay - cy) * (bx - cx)
    det = left - right
    bound = _ORIENT2D_BOUND * (abs(left) + abs(right))
    if det > bound:
        return 1
    if -det > bound:
        return -1
    A = [Fraction(x) for x in (ax, ay, bx, by, cx, cy)]
    d = (A[0] - A[4]) * (A[3] - A[5]) - (A[1] - A[5]) * (A[2] - A[4])
    return (d > 0) - (d < 0)


def incircle_one(a, b, c, d) -> int:
    """:func:`incircle` of one configuration, as a Python int (no array overhead: for loops that test one at a time)."""
    adx, ady = float(a[0]) - float(d[0]), float(a[1]) - float(d[1])
    bdx, bdy = float(b[0]) - float(d[0]), float(b[1]) - float(d[1])
    cdx, cdy = float(c[0]) - float(d[0]), float(c[1]) - float(d[1])
    alift = adx * adx + ady * ady
    blift = bdx * bdx + bdy * bdy
    clift = cdx * cdx + cdy * cdy
    bc, cb = bdx * cdy, cdx * bdy
    ca, ac = cdx * ady, adx * cdy
    ab, ba = adx * bdy, bdx * ady
    det = alift * (bc - cb) + blift * (ca - ac) + clift * (ab - ba)
    perm = (abs(bc) + abs(cb)) * alift + (abs(ca) + abs(ac)) * blift + (abs(ab) + abs(ba)) * clift
    bound = _INCIRCLE_BOUND * perm
    if det > bound:
        return 1
    if -det > bound:
        return -1
    F = [Fraction(float(x)) for x in (a[0], a[1], b[0], b[1], c[0], c[1], d[0], d[1])]
    adx, ady = F[0] - F[6], F[1] - F[7]
    bdx, bdy = F[2] - F[6], F[3] - F[7]
    cdx, cdy = F[4] - F[6], F[5] - F[7]
    det = (
        (adx * adx + ady * ady) * (bdx * cdy - cdx * bdy)
        + (bdx * bdx + bdy * bdy) * (cdx * ady - adx * cdy)
        + (cdx * cdx + cdy * cdy) * (adx * bdy - bdx * ady)
    )
    return (det > 0) - (det < 0)
