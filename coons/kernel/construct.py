"""Surfaces built from curves: extrusion, ruled surfaces, lofts (skinning) and Coons patches.

Every construction here returns an exact NURBS surface whose boundary (or section)
curves are the input curves, reparametrised to ``[0, 1]``: the curves are first made
compatible (:func:`make_compatible`: common degree by degree elevation, common
knot vector by knot refinement, both from :mod:`coons.kernel.refine`), then their
control points are combined.  The module deliberately does not approximate (no
fitting of sections or boundaries, no tolerance-driven knot removal afterwards), does
not build Gordon surfaces from curve networks, does not sweep along paths, and does
not make Coons patches from rational boundaries (a sum of rational patches with
different denominators is not a NURBS patch with the same control structure).

Conventions: a surface made from curves runs ``u`` along the curves and ``v`` across
them.  Linear and Hermite blending functions are expressed exactly in the common
spline space by passing a small "blend curve" (its coordinates are the blending
functions) through :func:`make_compatible` with the boundary curves.

Sources: The NURBS Book (Piegl and Tiller, 2nd ed.) §8.3 (general cylinder), §8.4
(ruled surface), §10.3 (skinning, eq. 10.8 for the section parameters), §10.6
(Coons surfaces as Boolean sums); Cohen–Riesenfeld–Elber, *Geometric Modeling with
Splines*, §14 (bilinearly and bicubically blended Coons patches); Farin, *Curves and
Surfaces for CAGD*, ch. 22 (Coons patches, twist compatibility).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from coons.errors import InvalidGeometryError, InvalidInputError
from coons.kernel import refine
from coons.kernel.curve import NurbsCurve
from coons.kernel.fitting import interpolate_curve, parametrize_grid
from coons.kernel.surface import NurbsSurface
from coons.tolerance import Tolerance, resolve

__all__ = [
    "make_compatible",
    "extrude",
    "ruled_surface",
    "loft",
    "bilinear_coons",
    "bicubic_coons",
]

#: Linear blends (1 - t, t) as a degree-1 curve on [0, 1] whose coordinates are the blending functions.
_LINEAR_BLENDS = NurbsCurve([[1.0, 0.0], [0.0, 1.0]], [0.0, 0.0, 1.0, 1.0], 1)

#: Cubic Hermite blends (H0, H1, H2, H3) on [0, 1] as a cubic Bézier curve in 4-D:
#: H0 = 1 - 3t² + 2t³, H1 = 3t² - 2t³ (values at 0 and 1), H2 = t(1 - t)², H3 = -t²(1 - t)
#: (first derivatives at 0 and 1); row k holds the k-th Bernstein coefficients of all four.
_HERMITE_BLENDS = NurbsCurve(
    [[1.0, 0.0, 0.0, 0.0], [1.0, 0.0, 1.0 / 3.0, 0.0], [0.0, 1.0, 0.0, -1.0 / 3.0], [0.0, 1.0, 0.0, 0.0]],
    [0.0, 0.0, 0.0, 0.0, 1.0, 1.0, 1.0, 1.0],
    3,
)


# ---------------------------------------------------------------------- helpers
def _check_curve(c, what: str) -> NurbsCurve:
    if not isinstance(c, NurbsCurve):
        raise InvalidInputError(f"{what} must be a NurbsCurve, got {type(c).__name__}")
    return c


def _check_same_dimension(curves: Sequence[NurbsCurve], names: Sequence[str], what: str) -> int:
    d = curves[0].dimension
    for c, name in zip(curves, names):
        if c.dimension != d:
            raise InvalidInputError(
                f"{what}: all curves must have the same dimension, {names[0]} has {d} and {name} has {c.dimension}"
            )
    return d


def _unit_domain(c: NurbsCurve) -> NurbsCurve:
    """The same curve over ``[0, 1]``.

    ``(U - a) / (b - a)`` maps ``a`` to 0 and ``b`` to 1 exactly and keeps the knots
    non-decreasing (correctly rounded subtraction and division are monotone), which a
    multiplication by ``1 / (b - a)`` does not guarantee.
    """
    a, b = c.domain
    if (a, b) == (0.0, 1.0):
        return c
    return NurbsCurve(c.control_points, (c.knots - a) / (b - a), c.degree, c.weights)


def _snap_to(values: np.ndarray, representatives: np.ndarray, slack: float) -> np.ndarray:
    """Each value replaced by the representative within ``slack`` of it (there is exactly one)."""
    idx = np.clip(np.searchsorted(representatives, values), 1, representatives.size - 1)
    lo, hi = representatives[idx - 1], representatives[idx]
    return np.where(np.abs(values - lo) <= np.abs(hi - values), lo, hi)


def make_compatible(
    curves: Sequence[NurbsCurve], *, degree: int | None = None, tol: Tolerance | None = None
) -> list[NurbsCurve]:
    """The same curves with one degree, one knot vector and the domain ``[0, 1]`` (The NURBS Book §10.3).

    Each curve is clamped (:func:`coons.kernel.refine.curve_clamped`), mapped affinely
    to ``[0, 1]``, raised to the common degree
    (:func:`coons.kernel.refine.curve_elevate_degree`), and given the union of all
    knot vectors — every distinct knot with its largest multiplicity over the curves —
    by knot refinement (:func:`coons.kernel.refine.curve_refine_knots`).  None of these
    steps changes a curve's points: ``result[i](t) == curves[i](a_i + t (b_i - a_i))``.

    Knots of different curves closer than ``tol.solver`` (round-off on the unit domain,
    as in :mod:`coons.kernel.refine`) are taken as the same knot, so round-off in the
    reparametrisation never creates spans of length 1e-16.

    Parameters
    ----------
    curves : sequence of NurbsCurve, at least one; dimensions and weights may differ
    degree : int, optional
        Common degree, at least the largest degree of the curves (default: that largest degree).
    tol : Tolerance, optional

    Returns
    -------
    list of NurbsCurve
        Same length and order as ``curves``; clamped, equal ``degree`` and equal ``knots``
        arrays, domain ``(0.0, 1.0)``; rational curves stay rational.

    Raises
    ------
    InvalidInputError
        An empty sequence, an item that is not a NurbsCurve, or ``degree`` below the
        largest degree of the curves.

    Examples
    --------
    >>> a = NurbsCurve([[0, 0], [1, 0]], [0, 0, 1, 1], 1)
    >>> b = NurbsCurve([[0, 1], [1, 2], [2, 1]], [0, 0, 0, 2, 2, 2], 2)
    >>> ca, cb = make_compatible([a, b])
    >>> (ca.degree, cb.degree, ca.knots.tolist() == cb.knots.tolist())
    (2, 2, True)
    """
    t = resolve(tol)
    if isinstance(curves, NurbsCurve) or not isinstance(curves, Sequence) or len(curves) == 0:
        raise InvalidInputError(f"make_compatible needs a non-empty sequence of NurbsCurve, got {curves!r}")
    cs = [_check_curve(c, f"make_compatible: curves[{i}]") for i, c in enumerate(curves)]
    top = max(c.degree for c in cs)
    if degree is None:
        p = top
    elif isinstance(degree, bool) or not isinstance(degree, (int, np.integer)) or degree < top:
        raise InvalidInputError(
            f"make_compatible: degree must be an integer >= the largest degree of the curves ({top}), got {degree!r}"
        )
    else:
        p = int(degree)
    cs = [refine.curve_elevate_degree(_unit_domain(refine.curve_clamped(c)), p - c.degree) for c in cs]

    # Distinct knots over all curves, with values closer than round-off merged (first one wins).
    slack = t.solver  # the unit domain's round-off (tol.solver * max(1, length 1))
    values = np.unique(np.concatenate([c.knots for c in cs]))
    reps = values[np.concatenate([[True], np.diff(values) > slack])]
    snapped = []
    for c in cs:
        U = _snap_to(c.knots, reps, slack) if reps.size > 1 else c.knots
        snapped.append(c if np.array_equal(U, c.knots) else NurbsCurve(c.control_points, U, p, c.weights))
    counts = np.stack(
        [np.searchsorted(c.knots, reps, "right") - np.searchsorted(c.knots, reps, "left") for c in snapped]
    )
    target = counts.max(axis=0)
    merged = np.repeat(reps, target)
    out = []
    for c, own in zip(snapped, counts):
        missing = np.repeat(reps, target - own)
        r = refine.curve_refine_knots(c, missing, t) if missing.size else c
        if not np.array_equal(r.knots, merged):
            raise InvalidGeometryError(
                f"make_compatible: knot refinement returned knots {r.knots.tolist()}, expected {merged.tolist()}"
            )
        out.append(r)
    return out


def _polynomial_check(c: NurbsCurve, t: Tolerance, what: str) -> None:
    """Refuse rational curves; weights equal to within ``tol.solver`` (relative) count as polynomial.

    Knot refinement and degree elevation of a polynomial curve leave its unit weights
    off by an ulp or so; such a curve is polynomial to round-off and its Cartesian
    control points are used.
    """
    w = c.weights
    if float(w.max() - w.min()) > t.solver * float(w.max()):
        raise InvalidInputError(
            f"{what}: Coons patches need polynomial (non-rational) curves, but the weights range from "
            f"{float(w.min())!r} to {float(w.max())!r}"
        )


def _ends(c: NurbsCurve, order: int) -> np.ndarray:
    """Point and derivatives at both ends of a curve on ``[0, 1]``, ``(2, order + 1, d)``."""
    return c.derivatives(np.array([0.0, 1.0]), order)


# ---------------------------------------------------------------------- extrusion and ruled surfaces
def extrude(curve: NurbsCurve, vector, *, tol: Tolerance | None = None) -> NurbsSurface:
    """The general cylinder ``S(u, v) = C(u) + v * vector`` (The NURBS Book §8.3).

    Parameters
    ----------
    curve : NurbsCurve of dimension ``d`` (3 for a surface in space)
    vector : (d,) array_like, longer than ``tol.linear``
    tol : Tolerance, optional

    Returns
    -------
    NurbsSurface
        ``u`` is the curve's parameter (its knots, degree and domain are kept), ``v`` in
        ``[0, 1]`` with degree 1; control points ``(n, 2, d)``, weights ``(n, 2)``
        copied from the curve, so rational curves give exact rational surfaces.

    Raises
    ------
    InvalidInputError
        ``curve`` not a NurbsCurve, ``vector`` of the wrong shape, not finite or shorter
        than ``tol.linear``.
    """
    t = resolve(tol)
    c = _check_curve(curve, "extrude: curve")
    d = c.dimension
    vec = np.array(vector, dtype=np.float64)
    if vec.shape != (d,):
        raise InvalidInputError(f"extrude: vector must have shape ({d},) like the curve, got {vec.shape}")
    if not np.all(np.isfinite(vec)):
        raise InvalidInputError(f"extrude: vector must be finite, got {vec.tolist()}")
    length = float(np.linalg.norm(vec))
    if length <= t.linear:
        raise InvalidInputError(f"extrude: vector length {length!r} is not above tol.linear = {t.linear!r}")
    P = np.stack([c.control_points, c.control_points + vec], axis=1)
    W = np.repeat(c.weights[:, None], 2, axis=1)
    return NurbsSurface(P, c.knots, [0.0, 0.0, 1.0, 1.0], c.degree, 1, W)


def ruled_surface(curve_a: NurbsCurve, curve_b: NurbsCurve, *, tol: Tolerance | None = None) -> NurbsSurface:
    """The ruled surface between two curves (The NURBS Book §8.4).

    The curves are made compatible (:func:`make_compatible`), then joined control point
    to control point by degree-1 segments in ``v``; in homogeneous coordinates
    ``S^w(u, v) = (1 - v) A^w(u) + v B^w(u)``, so each ruling is the straight segment
    from ``A(u)`` to ``B(u)`` (traversed non-uniformly when the weights differ).

    Parameters
    ----------
    curve_a, curve_b : NurbsCurve of the same dimension
    tol : Tolerance, optional

    Returns
    -------
    NurbsSurface
        Domain ``[0, 1]²``; ``S(u, 0) = A(u)`` and ``S(u, 1) = B(u)`` with both curves
        reparametrised to ``[0, 1]``.

    Raises
    ------
    InvalidInputError
        Not NurbsCurves, or different dimensions.
    """
    t = resolve(tol)
    a = _check_curve(curve_a, "ruled_surface: curve_a")
    b = _check_curve(curve_b, "ruled_surface: curve_b")
    _check_same_dimension([a, b], ["curve_a", "curve_b"], "ruled_surface")
    a, b = make_compatible([a, b], tol=t)
    P = np.stack([a.control_points, b.control_points], axis=1)
    W = np.stack([a.weights, b.weights], axis=1)
    return NurbsSurface(P, a.knots, [0.0, 0.0, 1.0, 1.0], a.degree, 1, W)


# ---------------------------------------------------------------------- lofting
def loft(
    curves: Sequence[NurbsCurve],
    degree_v: int = 3,
    *,
    params=None,
    method: str = "chord",
    tol: Tolerance | None = None,
) -> NurbsSurface:
    """The surface through a sequence of section curves: skinning (The NURBS Book §10.3).

    The sections are made compatible (:func:`make_compatible`); then, for every index
    ``i``, the homogeneous control points ``P^w_{k,i}`` of the sections ``k`` are
    interpolated across the sections by a curve of degree ``degree_v``
    (:func:`coons.kernel.fitting.interpolate_curve`, all ``i`` in one banded solve).
    Interpolating in homogeneous space makes ``S^w(u, v_k) = C_k^w(u)``, so the surface
    contains every section exactly, rational ones included.

    Parameters
    ----------
    curves : sequence of K >= 2 NurbsCurve of one dimension
    degree_v : int, ``1 <= degree_v <= K - 1``
    params : (K,) array_like, optional
        Strictly increasing ``v`` of the sections; default: eq. 10.8, the ``method``
        parameters of every column of compatible control points, averaged
        (:func:`coons.kernel.fitting.parametrize_grid`), in ``[0, 1]``.
    method : {"chord", "centripetal", "uniform"}
    tol : Tolerance, optional

    Returns
    -------
    NurbsSurface
        ``u`` along the sections (domain ``[0, 1]``, their common knots and degree),
        ``v`` across them (averaged knots, eq. 9.8); ``S(u, params[k]) = curves[k](u)``
        after reparametrising the sections to ``[0, 1]``.

    Raises
    ------
    InvalidInputError
        Fewer than two sections, items that are not NurbsCurves, different dimensions,
        ``degree_v`` out of range, bad ``params``, two consecutive sections whose control
        points coincide (default parameters), or interpolated weights that are not
        positive (rational sections whose weights vary too much across the sections).
    """
    t = resolve(tol)
    if isinstance(curves, NurbsCurve) or not isinstance(curves, Sequence) or len(curves) < 2:
        raise InvalidInputError(f"loft needs a sequence of at least 2 section curves, got {curves!r}")
    cs = [_check_curve(c, f"loft: curves[{k}]") for k, c in enumerate(curves)]
    K = len(cs)
    _check_same_dimension(cs, [f"curves[{k}]" for k in range(K)], "loft")
    if isinstance(degree_v, bool) or not isinstance(degree_v, (int, np.integer)) or not 1 <= degree_v <= K - 1:
        raise InvalidInputError(
            f"loft: degree_v must be an integer in [1, {K - 1}] for {K} sections, got {degree_v!r}"
        )
    cs = make_compatible(cs, tol=t)
    Pw = np.stack([c.homogeneous for c in cs])  # (K, n, d + 1)
    n, d1 = Pw.shape[1], Pw.shape[2]
    if params is None:
        try:
            v = parametrize_grid(np.stack([c.control_points for c in cs]), method, tol=t)[0]
        except InvalidInputError as exc:
            raise InvalidInputError(f"loft: cannot parametrise the sections ({exc})") from exc
    else:
        v = np.array(params, dtype=np.float64)
        if v.shape != (K,) or not np.all(np.isfinite(v)) or np.any(np.diff(v) <= 0):
            raise InvalidInputError(
                f"loft: params must be {K} finite, strictly increasing values, got {np.asarray(params).tolist()!r}"
            )
    across = interpolate_curve(Pw.reshape(K, n * d1), degree_v, params=v, tol=t)
    net = across.control_points.reshape(K, n, d1).transpose(1, 0, 2)
    if np.any(net[:, :, -1] <= 0):
        i, k = (int(x) for x in np.argwhere(net[:, :, -1] <= 0)[0])
        raise InvalidInputError(
            f"loft: interpolating the section weights gives weight {float(net[i, k, -1])!r} <= 0 at control point "
            f"({i}, {k}); the sections' weights vary too much for degree_v = {degree_v}"
        )
    return NurbsSurface.from_homogeneous(net, cs[0].knots, across.knots, cs[0].degree, degree_v)


# ---------------------------------------------------------------------- Coons patches
def _corner_points(c, d, t: Tolerance, what: str) -> np.ndarray:
    """Corner points ``T[a, b] = S(u=a, v=b)`` as the midpoints of the two curves meeting there.

    Raises when the curves miss each other by more than ``tol.linear``.
    """
    T = np.empty((2, 2, c[0].dimension))
    for a in (0, 1):
        for b in (0, 1):
            from_c = c[b].evaluate(c[b].domain[a])
            from_d = d[a].evaluate(d[a].domain[b])
            gap = float(np.linalg.norm(from_c - from_d))
            if gap > t.linear:
                ends = ("start", "end")
                raise InvalidInputError(
                    f"{what}: corner (u={a}, v={b}): c{b} {ends[a]}s at {from_c.tolist()} but d{a} {ends[b]}s at "
                    f"{from_d.tolist()}, gap {gap!r} > tol.linear = {t.linear!r}"
                )
            T[a, b] = 0.5 * (from_c + from_d)
    return T


def _boolean_sum(C, D, hU, hV, M) -> np.ndarray:
    """Control net of ``sum_k C_k(u) h_k(v) + sum_k h_k(u) D_k(v) - sum_ab h_a(u) h_b(v) M_ab``.

    ``C (k, nu, d)`` and ``D (k, nv, d)`` are curve coefficients, ``hU (nu, k)`` and
    ``hV (nv, k)`` blending-function coefficients in the same spline spaces, ``M (k, k, d)``
    the corner data; products of coefficients are exact in the tensor-product space.
    """
    return (
        np.einsum("kid,jk->ijd", C, hV)
        + np.einsum("ik,kjd->ijd", hU, D)
        - np.einsum("ia,jb,abd->ijd", hU, hV, M)
    )


def bilinear_coons(
    c0: NurbsCurve, c1: NurbsCurve, d0: NurbsCurve, d1: NurbsCurve, *, tol: Tolerance | None = None
) -> NurbsSurface:
    """The bilinearly blended Coons patch of four boundary curves.

    Cohen–Riesenfeld–Elber §14; The NURBS Book §10.6.

    ``S = R_c + R_d - B``: the ruled surface between ``c0`` and ``c1`` (in ``v``), plus
    the ruled surface between ``d0`` and ``d1`` (in ``u``), minus the bilinear patch of
    the four corners.  Built exactly as one NURBS surface: the ``c`` curves are made
    compatible in ``u`` and the ``d`` curves in ``v`` (:func:`make_compatible`), and
    the linear blends ``1 - t, t`` are written in those spline spaces.

    The patch domain is ``[0, 1]²`` and every curve is reparametrised to ``[0, 1]``:
    ``S(u, 0) = c0(u)``, ``S(u, 1) = c1(u)``, ``S(0, v) = d0(v)``, ``S(1, v) = d1(v)``.
    The curves must meet at the corners: ``c0`` starts where ``d0`` starts, ``c0`` ends
    where ``d1`` starts, ``c1`` starts where ``d0`` ends, ``c1`` ends where ``d1``
    ends.  Corner gaps up to ``tol.linear`` are split in the middle (each boundary is
    then reproduced to within half the gap).

    Parameters
    ----------
    c0, c1, d0, d1 : polynomial NurbsCurve of one dimension
    tol : Tolerance, optional

    Returns
    -------
    NurbsSurface
        Polynomial; degree in ``u`` the largest of ``c0, c1`` (at least 1), in ``v``
        that of ``d0, d1``.

    Raises
    ------
    InvalidInputError
        Not NurbsCurves, different dimensions, rational curves, or a corner gap above
        ``tol.linear`` (the message names the corner and the gap).
    """
    t = resolve(tol)
    names = ("c0", "c1", "d0", "d1")
    cs = [_check_curve(x, f"bilinear_coons: {name}") for x, name in zip((c0, c1, d0, d1), names)]
    _check_same_dimension(cs, names, "bilinear_coons")
    for x, name in zip(cs, names):
        _polynomial_check(x, t, f"bilinear_coons: {name}")
    cu = make_compatible([cs[0], cs[1], _LINEAR_BLENDS], tol=t)
    dv = make_compatible([cs[2], cs[3], _LINEAR_BLENDS], tol=t)
    T = _corner_points(cu[:2], dv[:2], t, "bilinear_coons")
    P = _boolean_sum(
        np.stack([cu[0].control_points, cu[1].control_points]),
        np.stack([dv[0].control_points, dv[1].control_points]),
        cu[2].control_points,
        dv[2].control_points,
        T,
    )
    return NurbsSurface(P, cu[0].knots, dv[0].knots, cu[0].degree, dv[0].degree)


def bicubic_coons(
    c0: NurbsCurve,
    c1: NurbsCurve,
    d0: NurbsCurve,
    d1: NurbsCurve,
    *,
    c0_cross: NurbsCurve | None = None,
    c1_cross: NurbsCurve | None = None,
    d0_cross: NurbsCurve | None = None,
    d1_cross: NurbsCurve | None = None,
    tol: Tolerance | None = None,
) -> NurbsSurface:
    """The bicubically (Hermite) blended Coons patch (Cohen–Riesenfeld–Elber §14; Farin ch. 22).

    ``S = L_c + L_d - T`` with cubic Hermite blends ``H0, H1`` (values) and ``H2, H3``
    (derivatives)::

        L_c(u, v) = c0(u) H0(v) + c1(u) H1(v) + c0_cross(u) H2(v) + c1_cross(u) H3(v)
        L_d(u, v) = d0(v) H0(u) + d1(v) H1(u) + d0_cross(v) H2(u) + d1_cross(v) H3(u)

    and ``T`` the tensor Hermite patch of the corner points, corner tangents and corner
    twists.  The patch interpolates the four boundaries and the four cross-boundary
    derivatives.  The domain is ``[0, 1]²`` and every curve is reparametrised to
    ``[0, 1]``; boundaries as in :func:`bilinear_coons`.

    Cross-boundary derivatives
        ``c0_cross(u) = ∂S/∂v (u, 0)``, ``c1_cross(u) = ∂S/∂v (u, 1)``,
        ``d0_cross(v) = ∂S/∂u (0, v)``, ``d1_cross(v) = ∂S/∂u (1, v)``, with respect to
        the unit parameters.  Each is optional.  A missing one is the cubic Hermite
        blend of the two corner tangents of the transversal boundaries and the twists
        of its corners (e.g. ``c0_cross`` from ``d0'(0)``, ``d1'(0)``); a corner twist
        ``∂²S/∂u∂v`` is the derivative of a given cross curve there, else zero.  With
        no cross curves at all every twist is zero and ``L_c`` reduces to
        ``c0 H0(v) + c1 H1(v)`` plus the Hermite interpolant of the corner tangents:
        the classical zero-twist bicubically blended Coons patch.

    Compatibility (checked within ``tol.linear``)
        Corner points as in :func:`bilinear_coons`; a given cross curve must start and
        end with the corner tangents of the transversal boundaries
        (``c0_cross(0) = d0'(0)``, ``c0_cross(1) = d1'(0)``, ...); two given cross curves
        meeting at a corner must have the same twist there
        (``c0_cross'(0) = d0_cross'(0)``, ...).  A derivative mismatch ``δ`` on the unit
        parameter interval moves Hermite-blended points by at most ``4δ/27``
        (``max |H2| = 4/27``), so ``tol.linear`` bounds derivative gaps too.

    Parameters
    ----------
    c0, c1, d0, d1 : polynomial NurbsCurve of one dimension
    c0_cross, c1_cross, d0_cross, d1_cross : polynomial NurbsCurve of the same dimension, optional
    tol : Tolerance, optional

    Returns
    -------
    NurbsSurface
        Polynomial, degree ``max(3, degrees of c0, c1 and the c crosses)`` in ``u`` and
        likewise in ``v``.

    Raises
    ------
    InvalidInputError
        Not NurbsCurves, different dimensions, rational curves, or a corner, tangent
        or twist mismatch above ``tol.linear`` (the message names the corner and the gap).
    """
    t = resolve(tol)
    what = "bicubic_coons"
    curves = {k: _check_curve(x, f"{what}: {k}") for k, x in (("c0", c0), ("c1", c1), ("d0", d0), ("d1", d1))}
    crosses = (("c0_cross", c0_cross), ("c1_cross", c1_cross), ("d0_cross", d0_cross), ("d1_cross", d1_cross))
    curves.update((k, _check_curve(x, f"{what}: {k}")) for k, x in crosses if x is not None)
    _check_same_dimension(list(curves.values()), list(curves), what)
    for k, x in curves.items():
        _polynomial_check(x, t, f"{what}: {k}")
    dim = c0.dimension

    # Boundaries and given cross curves in the common spaces, blends written in them too.
    u_names = [k for k in ("c0", "c1", "c0_cross", "c1_cross") if k in curves]
    v_names = [k for k in ("d0", "d1", "d0_cross", "d1_cross") if k in curves]
    pu = max(3, *(curves[k].degree for k in u_names))
    pv = max(3, *(curves[k].degree for k in v_names))
    U_list = make_compatible([curves[k] for k in u_names] + [_HERMITE_BLENDS], degree=pu, tol=t)
    V_list = make_compatible([curves[k] for k in v_names] + [_HERMITE_BLENDS], degree=pv, tol=t)
    cu = dict(zip(u_names, U_list[:-1]))
    dv = dict(zip(v_names, V_list[:-1]))
    hU, hV = U_list[-1].control_points, V_list[-1].control_points  # (nu, 4), (nv, 4)

    T = _corner_points([cu["c0"], cu["c1"]], [dv["d0"], dv["d1"]], t, what)
    c_ends = [_ends(cu[f"c{b}"], 1) for b in (0, 1)]  # [b][a, order]
    d_ends = [_ends(dv[f"d{a}"], 1) for a in (0, 1)]  # [a][b, order]
    Su = np.array([[c_ends[b][a, 1] for b in (0, 1)] for a in (0, 1)])  # Su[a, b] at (u=a, v=b)
    Sv = np.array([[d_ends[a][b, 1] for b in (0, 1)] for a in (0, 1)])

    # Given cross curves must start and end on the transversal tangents; their end slopes are twists.
    twist = np.zeros((2, 2, dim))
    twist_from = [[None, None], [None, None]]
    for b in (0, 1):
        name = f"c{b}_cross"
        if name in cu:
            e = _ends(cu[name], 1)
            for a in (0, 1):
                statement = f"{name}({a}) must equal d{a}'({b}), the v-derivative at corner (u={a}, v={b})"
                _check_gap(e[a, 0], Sv[a, b], t, what, statement)
                twist[a, b], twist_from[a][b] = e[a, 1], name
    for a in (0, 1):
        name = f"d{a}_cross"
        if name in dv:
            e = _ends(dv[name], 1)
            for b in (0, 1):
                statement = f"{name}({b}) must equal c{b}'({a}), the u-derivative at corner (u={a}, v={b})"
                _check_gap(e[b, 0], Su[a, b], t, what, statement)
                if twist_from[a][b] is not None:
                    statement = f"corner (u={a}, v={b}): the twist {name}'({b}) must equal {twist_from[a][b]}'({a})"
                    _check_gap(e[b, 1], twist[a, b], t, what, statement)
                else:
                    twist[a, b] = e[b, 1]

    # Missing cross curves: cubic Hermite interpolants of the corner tangents (values) and twists (slopes).
    def cross(space: dict, name: str, h: np.ndarray, values: np.ndarray, slopes: np.ndarray) -> np.ndarray:
        if name in space:
            return space[name].control_points
        return h @ np.concatenate([values, slopes])

    C = np.stack([
        cu["c0"].control_points,
        cu["c1"].control_points,
        cross(cu, "c0_cross", hU, Sv[:, 0], twist[:, 0]),
        cross(cu, "c1_cross", hU, Sv[:, 1], twist[:, 1]),
    ])
    D = np.stack([
        dv["d0"].control_points,
        dv["d1"].control_points,
        cross(dv, "d0_cross", hV, Su[0], twist[0]),
        cross(dv, "d1_cross", hV, Su[1], twist[1]),
    ])
    # M[a', b']: rows (S at u=0, S at u=1, S_u at u=0, S_u at u=1), columns likewise in v.
    M = np.empty((4, 4, dim))
    M[:2, :2], M[:2, 2:], M[2:, :2], M[2:, 2:] = T, Sv, Su, twist
    P = _boolean_sum(C, D, hU, hV, M)
    return NurbsSurface(P, U_list[0].knots, V_list[0].knots, pu, pv)


def _check_gap(x: np.ndarray, y: np.ndarray, t: Tolerance, what: str, statement: str) -> None:
    gap = float(np.linalg.norm(x - y))
    if gap > t.linear:
        raise InvalidInputError(
            f"{what}: {statement}, but they are {x.tolist()} and {y.tolist()}, "
            f"gap {gap!r} > tol.linear = {t.linear!r}"
        )
