"""P-curves of 3-D curves that lie on a surface: exact forms where they exist, fitted 2-D NURBS otherwise.

:func:`pcurve_on` returns the curve ``uv(t)`` in a surface's parameter plane with the SAME parameter
as a 3-D curve lying on the surface, ``surface(uv(t)) ≈ curve(t)`` for ``t ∈ [t0, t1]``, and the
3-D deviation it measured.  Iso-curves of the analytic surfaces (lines and conics on a plane,
rulings and coaxial circles of cylinders and cones, parallels and meridians of spheres and tori)
come out exact, as :class:`~coons.kernel.pcurve.Line2D` or :class:`~coons.kernel.pcurve.Trig2D`;
every other pair gives a cubic 2-D :class:`~coons.kernel.curve.NurbsCurve` interpolating projected
samples, refined until the deviation is within ``tol.linear``.  The module deliberately does not
decide whether a curve *should* lie on a surface (a curve farther than ``tol.linear`` raises), does
not trim, and does not split a curve whose p-curve is discontinuous (a great circle through a
sphere's poles jumps by π in ``u`` there: the caller splits such a curve at the pole first).

Method (Cohen–Riesenfeld–Elber §16.2 for the projection, The NURBS Book §9.2 for the fit):

1. sample ``t`` (uniformly, plus the knots of a NURBS curve) and project the curve points with the
   closed-form ``closest_parameters`` of analytic surfaces or
   :func:`coons.kernel.projection.surface_closest_points` for NURBS;
2. where a parameter is undetermined (a sphere pole, a cone apex, a degenerate NURBS edge: moving
   it over its whole range moves the point by less than ``tol.linear``) take it from the
   neighbouring samples; unwrap periodic parameters continuously and shift them by whole periods
   so that the p-curve lies in ``box``;
3. try the exact forms: ``uv`` affine in ``t`` (:class:`Line2D`), or, for circles and ellipses,
   affine in ``(cos t, sin t)`` (:class:`Trig2D`), accepted when the 3-D deviation on check samples
   is within ``tol.linear``;
4. otherwise interpolate the samples with a cubic in the parameter ``t`` and halve every sample
   interval whose midpoint deviates by more than ``tol.linear`` (an a-posteriori error control that
   follows the curvature), until all midpoints pass;
5. on a NURBS surface, a p-curve that leaves the domain by round-off (a boundary iso-line fitted
   to ~1e-11 outside) is moved inside and its deviation measured again.

:func:`pcurves_on` does the same for the edges of one face at once, trying the cheap exact
candidate first for all of them in a few vectorised calls (a :class:`Line2D` through the
inverted end points on an open NURBS surface; the least-squares :class:`Line2D` of the projected
samples on an analytic surface), each verified on the samples before it is accepted; the rest go
through :func:`pcurve_on`.
"""

from __future__ import annotations

import logging
import math
import weakref
from typing import Any

import numpy as np

from coons.errors import CoonsError, ConvergenceError, InvalidGeometryError, InvalidInputError
from coons.kernel import projection
from coons.kernel.analytic import Circle, CylindricalSurface, Ellipse, Line
from coons.kernel.curve import NurbsCurve
from coons.kernel.fitting import interpolate_curve
from coons.kernel.pcurve import Line2D, Trig2D
from coons.kernel.surface import NurbsSurface
from coons.tolerance import Tolerance, resolve

__all__ = ["cheap_pcurves_many", "curve_derivatives", "evaluate_curves", "pcurve_on", "pcurves_on"]

_log = logging.getLogger("coons")

#: Initial uniform samples of the curve: 32 intervals keep a full circle's steps at π/16, far below
#: the half period that continuous unwrapping of an angle needs.
_INITIAL_SAMPLES = 33
#: Rounds of interval halving in the general case (each round at most doubles the samples) ...
_MAX_ROUNDS = 12
#: ... and the sample count at which it gives up (a curve that needs more is not smooth on the surface).
_MAX_SAMPLES = 1 << 14
#: Cubic p-curves (C2 interpolation); fewer samples than 4 lower the degree.
_DEGREE = 3
#: Samples along the boundary curves of a NURBS surface when testing whether it is closed.
_CLOSED_SAMPLES = 9


# ---------------------------------------------------------------------------- surface helpers
def surface_periods(surface, tol: Tolerance) -> tuple[float | None, float | None]:
    """``(period_u, period_v)`` of a surface, ``None`` in directions that are not closed.

    Analytic surfaces state their periods; a NURBS surface counts as closed in ``u`` (period: the
    domain length) when its two boundary curves ``u = u0`` and ``u = u1`` coincide within
    ``tol.linear`` at :data:`_CLOSED_SAMPLES` samples (a revolved or swept NURBS with a seam),
    likewise in ``v``.  Only unwrapping uses the NURBS periods: a NURBS is never evaluated outside
    its domain.
    """
    if not isinstance(surface, NurbsSurface):
        pu = getattr(surface, "period_u", None) if getattr(surface, "periodic_u", False) else None
        pv = getattr(surface, "period_v", None) if getattr(surface, "periodic_v", False) else None
        return pu, pv
    # Surfaces are immutable values: the answer is cached per surface object and tolerance (every
    # p-curve of a face asks it several times).
    per_surface = _PERIODS_CACHE.get(surface)
    if per_surface is None:
        per_surface = _PERIODS_CACHE.setdefault(surface, {})
    key = float(tol.linear)
    if key not in per_surface:
        per_surface[key] = _nurbs_periods(surface, tol)
    return per_surface[key]


#: ``surface -> {tol.linear: periods}`` for NURBS surfaces (weak keys: an entry dies with its surface).
_PERIODS_CACHE: "weakref.WeakKeyDictionary[NurbsSurface, dict]" = weakref.WeakKeyDictionary()


def _clamped(knots: np.ndarray, p: int) -> bool:
    k = knots.tolist()
    return all(x == k[0] for x in k[:p + 1]) and all(x == k[-1] for x in k[-p - 1:])


def _nurbs_periods(surface: NurbsSurface, tol: Tolerance) -> tuple[float | None, float | None]:
    (u0, u1), (v0, v1) = surface.domain_u, surface.domain_v
    C = np.asarray(surface.control_points)
    if _clamped(surface.knots_u, surface.degree_u) and _clamped(surface.knots_v, surface.degree_v):
        # The corners of a clamped surface are its corner control points: boundary curves whose
        # ends already differ by more than tol.linear do not coincide (the common, open case).
        open_u = max(np.linalg.norm(C[0, 0] - C[-1, 0]), np.linalg.norm(C[0, -1] - C[-1, -1])) > tol.linear
        open_v = max(np.linalg.norm(C[0, 0] - C[0, -1]), np.linalg.norm(C[-1, 0] - C[-1, -1])) > tol.linear
        if open_u and open_v:
            return None, None
    su, sv = np.linspace(u0, u1, _CLOSED_SAMPLES), np.linspace(v0, v1, _CLOSED_SAMPLES)
    n = _CLOSED_SAMPLES
    # the four boundary curves in one evaluation: u = u0, u = u1 (along v), v = v0, v = v1 (along u)
    B = np.asarray(surface.evaluate(np.concatenate([np.full(n, u0), np.full(n, u1), su, su]),
                                    np.concatenate([sv, sv, np.full(n, v0), np.full(n, v1)]))).reshape(4, n, -1)
    gap_u = np.linalg.norm(B[0] - B[1], axis=-1).max()
    gap_v = np.linalg.norm(B[2] - B[3], axis=-1).max()
    return (u1 - u0 if gap_u <= tol.linear else None), (v1 - v0 if gap_v <= tol.linear else None)


def project_on_surface(surface, points: np.ndarray, tol: Tolerance) -> np.ndarray:
    """``(m, 2)`` parameters of the closest points of ``surface`` to ``points`` ``(m, 3)``.

    Closed form for analytic surfaces; :func:`coons.kernel.projection.surface_closest_points`
    for NURBS and anything else.
    """
    if isinstance(surface, NurbsSurface) or not hasattr(surface, "implicit"):
        return np.array(projection.surface_closest_points(surface, points, tol).parameters)
    return np.array(surface.closest_parameters(points))


def evaluate_on_surface(surface, uv: np.ndarray) -> np.ndarray:
    """``surface(uv)`` for ``uv`` ``(..., 2)``; NURBS parameters are clipped into the domain.

    Clipping is what the checks here need: a fitted p-curve that overshoots a NURBS domain by a
    little is measured at the nearest surface point, and an overshoot that matters shows up as a
    deviation.
    """
    u, v = uv[..., 0], uv[..., 1]
    if isinstance(surface, NurbsSurface):
        (u0, u1), (v0, v1) = surface.domain_u, surface.domain_v
        u, v = np.clip(u, u0, u1), np.clip(v, v0, v1)
    return np.asarray(surface.evaluate(u, v))


def _direction_lengths(surface, box, tol: Tolerance) -> tuple[float, float]:
    """The parameter range over which a parameter is free in each direction (period, box or domain)."""
    out = []
    for k, (per, dom) in enumerate(zip(surface_periods(surface, tol), (surface.domain_u, surface.domain_v))):
        if per is not None:
            out.append(float(per))
        elif box is not None and np.all(np.isfinite(box[k])):
            out.append(float(box[k][1] - box[k][0]))
        else:
            out.append(float(dom[1] - dom[0]))
    return out[0], out[1]


def singular_parameters(surface, uv: np.ndarray, box, tol: Tolerance) -> np.ndarray:
    """``(m, 2)`` bool: the parameter is undetermined at ``uv`` (sphere pole, cone apex, collapsed NURBS edge).

    A parameter is undetermined where moving it over its whole free range (period, box or domain)
    moves the surface point by less than ``tol.linear``: ``|S_u| L_u <= tol.linear``.
    """
    lu, lv = _direction_lengths(surface, box, tol)
    if isinstance(surface, CylindricalSurface):  # |S_u| = radius, |S_v| = 1 everywhere: no evaluation
        su = np.full(uv.shape[:-1], float(surface.radius))
        sv = np.ones(uv.shape[:-1])
    else:
        d = np.asarray(surface.derivatives(*_clipped(surface, uv), 1))
        su = np.linalg.norm(d[..., 1, 0, :], axis=-1)
        sv = np.linalg.norm(d[..., 0, 1, :], axis=-1)
    out = np.zeros(uv.shape, bool)
    if math.isfinite(lu):
        out[..., 0] = su * lu <= tol.linear
    if math.isfinite(lv):
        out[..., 1] = sv * lv <= tol.linear
    return out


def _clipped(surface, uv: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    u, v = uv[..., 0], uv[..., 1]
    if isinstance(surface, NurbsSurface):
        (u0, u1), (v0, v1) = surface.domain_u, surface.domain_v
        u, v = np.clip(u, u0, u1), np.clip(v, v0, v1)
    return u, v


def continuous_parameters(surface, t: np.ndarray, uv: np.ndarray, box, tol: Tolerance) -> np.ndarray:
    """Make sampled parameters ``uv`` ``(m, 2)`` (ordered by ``t``) a continuous path, shifted into ``box``.

    Undetermined parameters (:func:`singular_parameters`) are interpolated in ``t`` from the
    others; periodic ones are unwrapped (steps below half a period) and shifted by whole periods
    so that the middle of their range is nearest the middle of ``box``.
    """
    uv = np.array(uv, dtype=np.float64)
    free = singular_parameters(surface, uv, box, tol)
    if isinstance(surface, NurbsSurface):
        # A closed NURBS is unwrapped towards its domain where the box says nothing (None or an
        # infinite side): its p-curves must stay where the surface can be evaluated.
        dom = surface.domain
        box = dom if box is None else tuple(
            tuple(box[k]) if np.all(np.isfinite(box[k])) else dom[k] for k in range(2))
    for k, per in enumerate(surface_periods(surface, tol)):
        good = ~free[:, k]
        if not np.any(good):
            continue
        col = uv[good, k]
        if per is not None:
            col = np.unwrap(col, period=per)
        uv[good, k] = col
        if not np.all(good):
            uv[~good, k] = np.interp(t[~good], t[good], col)
        if per is not None and box is not None and np.all(np.isfinite(box[k])):
            mid = 0.5 * (float(box[k][0]) + float(box[k][1]))
            have = 0.5 * (float(uv[:, k].min()) + float(uv[:, k].max()))
            uv[:, k] += per * round((mid - have) / per)
    return uv


def _check_box(box) -> tuple[tuple[float, float], tuple[float, float]] | None:
    if box is None:
        return None
    try:
        b = np.asarray(box, dtype=np.float64)
    except (TypeError, ValueError):
        b = None
    if b is None or b.shape != (2, 2) or np.any(np.isnan(b)) or np.any(b[:, 0] > b[:, 1]):
        raise InvalidInputError(f"box must be ((u0, u1), (v0, v1)) with u0 <= u1, v0 <= v1, got {box!r}")
    return (float(b[0, 0]), float(b[0, 1])), (float(b[1, 0]), float(b[1, 1]))


# ---------------------------------------------------------------------------- public
def pcurve_on(surface, curve, t0: float, t1: float, box=None, tol: Tolerance | None = None) -> tuple[Any, float]:
    """The p-curve of ``curve([t0, t1])`` on ``surface``, in the same parameter, and its 3-D deviation.

    Parameters
    ----------
    surface : PlanarSurface, CylindricalSurface, ConicalSurface, SphericalSurface, ToroidalSurface or NurbsSurface
    curve : Line, Circle, Ellipse or 3-D NurbsCurve
        Lying on ``surface`` within ``tol.linear`` over ``[t0, t1]``.
    t0, t1 : float, ``t0 < t1``
    box : ((u0, u1), (v0, v1)), optional
        Periodic parameters of the p-curve are shifted by whole periods towards this box (the
        middle of the p-curve's range nearest the middle of the box).
    tol : Tolerance, optional

    Returns
    -------
    pcurve : Line2D, Trig2D or 2-D NurbsCurve
        ``surface.evaluate(*pcurve(t).T) ≈ curve(t)``; a NURBS p-curve has domain ``[t0, t1]``.
    deviation : float
        The largest ``|surface(pcurve(t)) - curve(t)|`` measured (at the samples and between them).

    Raises
    ------
    InvalidInputError
        ``t0 >= t1`` or not finite, a malformed ``box``, a curve or surface without the needed methods.
    InvalidGeometryError
        The curve is farther than ``tol.linear`` from the surface (the message names the distance
        and where).
    ConvergenceError
        The fitted p-curve cannot reach ``tol.linear`` (a p-curve that is not continuous, e.g. a
        curve through a sphere pole across it); ``residuals`` holds the deviation reached.

    Examples
    --------
    >>> from coons.kernel.analytic import CylindricalSurface, Circle
    >>> cyl = CylindricalSurface([0, 0, 0], [0, 0, 1], [1, 0, 0], 2.0)
    >>> pc, dev = pcurve_on(cyl, Circle([0, 0, 1], [0, 0, 1], [1, 0, 0], 2.0), 0.0, np.pi)
    >>> type(pc).__name__, bool(np.allclose(pc(0.5), [0.5, 1.0], rtol=0, atol=1e-12))
    ('Line2D', True)
    """
    t = resolve(tol)
    try:
        a, b = float(t0), float(t1)
    except (TypeError, ValueError):
        raise InvalidInputError(f"pcurve_on: t0, t1 must be numbers, got {t0!r}, {t1!r}") from None
    if not (math.isfinite(a) and math.isfinite(b) and a < b):
        raise InvalidInputError(f"pcurve_on: need finite t0 < t1, got t0={a!r}, t1={b!r}")
    bx = _check_box(box)
    for name in ("evaluate", "derivatives"):
        if not hasattr(surface, name) or not hasattr(curve, name):
            raise InvalidInputError(
                f"pcurve_on: surface and curve need {name}(), got {type(surface).__name__}, {type(curve).__name__}"
            )

    ts = np.linspace(a, b, _INITIAL_SAMPLES)
    if isinstance(curve, NurbsCurve):
        inner = curve.knots[(curve.knots > a) & (curve.knots < b)]
        ts = np.unique(np.concatenate([ts, inner]))
    P = np.asarray(curve.evaluate(ts))
    if P.shape[-1] != 3:
        raise InvalidInputError(f"pcurve_on: curve must be 3-D, got points of dimension {P.shape[-1]}")
    uv = continuous_parameters(surface, ts, project_on_surface(surface, P, t), bx, t)
    _check_on(surface, ts, P, uv, t)

    exact = _exact_form(surface, curve, ts, uv, t)
    pc, dev = exact if exact is not None else _fitted(surface, curve, ts, P, uv, bx, t)
    return _into_domain(surface, curve, pc, dev, a, b, t)


# ---------------------------------------------------------------------------- internals
def _check_on(surface, ts: np.ndarray, P: np.ndarray, uv: np.ndarray, t: Tolerance) -> None:
    dist = np.linalg.norm(evaluate_on_surface(surface, uv) - P, axis=-1)
    k = int(np.argmax(dist))
    if dist[k] > t.linear:
        raise InvalidGeometryError(
            f"pcurve_on: the curve is not on the {type(surface).__name__}: distance {float(dist[k])!r} "
            f"> tol.linear = {t.linear!r} at t = {float(ts[k])!r}"
        )


def _midpoints(ts: np.ndarray) -> np.ndarray:
    return 0.5 * (ts[:-1] + ts[1:])


def _deviation(surface, curve, pcurve, ts: np.ndarray) -> np.ndarray:
    uv = np.asarray(pcurve.evaluate(ts))
    return np.linalg.norm(evaluate_on_surface(surface, uv) - np.asarray(curve.evaluate(ts)), axis=-1)


def _snap_small(coef: np.ndarray, reach: float, scale: float, t: Tolerance) -> np.ndarray:
    """Zero the coefficients whose whole contribution ``|c| reach`` is round-off of the parameters' size."""
    coef = coef.copy()
    coef[np.abs(coef) * reach <= t.solver * scale] = 0.0
    return coef


def _exact_form(surface, curve, ts: np.ndarray, uv: np.ndarray, t: Tolerance):
    """A Line2D (uv affine in t) or, for conics, a Trig2D (affine in cos t, sin t), if within tolerance."""
    check = np.concatenate([ts, _midpoints(ts)])
    scale = max(1.0, float(np.max(np.abs(uv))))
    reach = float(ts[-1] - ts[0])
    tm = 0.5 * (float(ts[0]) + float(ts[-1]))
    s = ts - tm
    candidates = []
    coef, *_ = np.linalg.lstsq(np.stack([np.ones_like(s), s], axis=1), uv, rcond=None)
    d = _snap_small(coef[1], reach, scale, t)
    candidates.append(lambda: Line2D(coef[0] - tm * d, d))
    if isinstance(curve, (Circle, Ellipse)):
        A = np.stack([np.ones_like(ts), np.cos(ts), np.sin(ts)], axis=1)
        tc, *_ = np.linalg.lstsq(A, uv, rcond=None)
        # cos and sin are at most 1: a coefficient's reach is its own size.
        ca, cb = _snap_small(tc[1], 1.0, scale, t), _snap_small(tc[2], 1.0, scale, t)
        candidates.append(lambda: Trig2D(tc[0], ca, cb))
    for make in candidates:
        try:
            pc = make()
        except InvalidGeometryError:
            continue
        dev = float(np.max(_deviation(surface, curve, pc, check)))
        if dev <= t.linear:
            return pc, dev
    return None


def _fitted(surface, curve, ts, P, uv, box, t: Tolerance) -> tuple[NurbsCurve, float]:
    """Interpolate, then halve the intervals whose midpoints deviate, until every midpoint passes."""
    periods = surface_periods(surface, t)
    dev_samples = np.linalg.norm(evaluate_on_surface(surface, uv) - P, axis=-1)
    for _ in range(_MAX_ROUNDS):
        pc = interpolate_curve(uv, min(_DEGREE, ts.size - 1), params=ts, tol=t)
        mids = _midpoints(ts)
        dev_mid = _deviation(surface, curve, pc, mids)
        bad = dev_mid > t.linear
        if not np.any(bad):
            return pc, float(max(dev_mid.max(), dev_samples.max()))
        if ts.size + int(bad.sum()) > _MAX_SAMPLES:
            break
        new_t = mids[bad]
        new_P = np.asarray(curve.evaluate(new_t))
        guess = np.asarray(pc.evaluate(new_t))
        new_uv = project_on_surface(surface, new_P, t)
        free = singular_parameters(surface, new_uv, box, t)
        for k, per in enumerate(periods):
            if per is not None:
                new_uv[:, k] += per * np.round((guess[:, k] - new_uv[:, k]) / per)
            new_uv[free[:, k], k] = guess[free[:, k], k]
        _check_on(surface, new_t, new_P, new_uv, t)
        order = np.argsort(np.concatenate([ts, new_t]), kind="stable")
        ts = np.concatenate([ts, new_t])[order]
        uv = np.concatenate([uv, new_uv])[order]
        P = np.concatenate([P, new_P])[order]
        dev_samples = np.linalg.norm(evaluate_on_surface(surface, uv) - P, axis=-1)
    worst = float(dev_mid.max())
    raise ConvergenceError(
        f"pcurve_on: the fitted p-curve deviates by {worst!r} > tol.linear = {t.linear!r} after "
        f"{ts.size} samples (is the p-curve continuous on [{float(ts[0])!r}, {float(ts[-1])!r}]?)",
        residuals=np.array([worst]),
    )


# ---------------------------------------------------------------------------- domain clamping
#: A p-curve on a NURBS surface leaving the domain by less than this fraction of the domain length
#: is moved inside (round-off of a fit or a projection along a domain boundary, ~1e-11 in practice).
#: The deviation is measured again after the move, so the slack decides nothing about accuracy.
_DOMAIN_SLACK = 1e-6


def _into_domain(surface, curve, pc, dev: float, a: float, b: float, t: Tolerance) -> tuple[Any, float]:
    """Move a p-curve on a NURBS surface that leaves the domain by round-off back into it.

    NURBS evaluation refuses parameters outside the domain (beyond ``tol.solver``), so a p-curve
    along a domain boundary that overshoots it by ~1e-11 would make every later evaluation fail.
    A :class:`Line2D` within the slack of a boundary gets that boundary as its constant
    coordinate, one that overshoots by less than the slack is shifted inside; a NURBS p-curve's
    control points are clipped (the curve stays in their convex hull).  Larger overshoots are left
    alone for the caller's checks to report.  When anything moved the deviation is measured again.
    """
    if not isinstance(surface, NurbsSurface) or pc is None:
        return pc, dev
    doms = surface.domain
    new = pc
    if isinstance(pc, Line2D):
        E = np.asarray(pc.evaluate(np.array([a, b])))
        o, d = pc.origin.copy(), pc.direction.copy()
        changed = False
        for k, (d0, d1) in enumerate(doms):
            eps = _DOMAIN_SLACK * (d1 - d0)
            lo, hi = float(E[:, k].min()), float(E[:, k].max())
            if lo < d0 - eps or hi > d1 + eps:
                continue  # a real overshoot: not round-off
            snapped = False
            for bound in (d0, d1):
                if max(abs(lo - bound), abs(hi - bound)) <= eps and (lo != bound or hi != bound):
                    o[k], d[k] = bound, 0.0
                    changed = snapped = True
                    break
            if not snapped and (lo < d0 or hi > d1):
                o[k] += max(d0 - lo, 0.0) - max(hi - d1, 0.0)
                changed = True
        if changed and np.any(d):
            new = Line2D(o, d)
    elif isinstance(pc, NurbsCurve):
        P = pc.control_points.copy()
        for k, (d0, d1) in enumerate(doms):
            eps = _DOMAIN_SLACK * (d1 - d0)
            if P[:, k].min() >= d0 - eps and P[:, k].max() <= d1 + eps:
                P[:, k] = np.clip(P[:, k], d0, d1)
        if np.any(P != pc.control_points):
            new = NurbsCurve(P, pc.knots, pc.degree, pc.weights)
    if new is pc:
        return pc, dev
    ts = np.linspace(a, b, 2 * _INITIAL_SAMPLES - 1)
    return new, max(dev, float(np.max(_deviation(surface, curve, new, ts))))


# ---------------------------------------------------------------------------- batches
#: Newton steps of the batched point inversion (quadratic convergence from a grid seed: a point
#: on the surface is found to round-off in 3-5 steps; more is a sign of a bad seed, and the
#: candidate built from it simply fails verification).
_NEWTON_STEPS = 8


#: Point–control-point pairs held at once by the seeding of :func:`_invert_nurbs_many`.
_SEED_PAIRS = 1 << 18


def _invert_nurbs_many(surfaces: list, which: np.ndarray, P: np.ndarray, t: Tolerance) -> tuple[np.ndarray, np.ndarray]:
    """Parameters of points ``P`` ``(m, 3)`` on NURBS surfaces ``surfaces[which[i]]``: nearest control point, then Gauss–Newton.

    The seed of each point is the Greville abscissa pair of its nearest control point (the
    parameter a control point "belongs to"; exact at the corners of a clamped surface), then the
    local inversion of The NURBS Book §6.1 (eq. 6.6, first-order form), vectorised over the
    points of all surfaces (one :func:`~coons.kernel.surface.derivatives_surfaces` call per
    step: surfaces of one structure are evaluated as one batch), parameters clipped to each
    point's domain at every step.  No global guarantee: callers verify what they build from
    the result.

    Returns
    -------
    uv : (m, 2) float64
    speed : (m, 2) float64
        ``|S_u|, |S_v|`` at the last Newton iterate (for detecting undetermined parameters).
    """
    from coons.kernel.surface import derivatives_surfaces, structure_groups

    def greville(knots, p, n):
        idx = np.arange(n)[:, None] + np.arange(1, p + 1)[None, :]
        return np.asarray(knots, dtype=np.float64)[idx].mean(axis=1)

    which = np.asarray(which, dtype=np.int64)
    m = P.shape[0]
    uv = np.empty((m, 2))
    lo, hi = np.empty((m, 2)), np.empty((m, 2))
    speed = np.zeros((m, 2))
    for members, rows, local in structure_groups(surfaces, which):
        # surfaces of one structure share knots, hence Greville abscissae: their seeds are one batch
        # (the points' own nets gathered, nearest control point by squared distance)
        S0 = surfaces[members[0]]
        (u0, u1), (v0, v1) = S0.domain
        C = np.stack([np.asarray(surfaces[k].control_points, dtype=np.float64) for k in members])
        nu, nv = C.shape[1:3]
        gu = np.clip(greville(S0.knots_u, S0.degree_u, nu), u0, u1)
        gv = np.clip(greville(S0.knots_v, S0.degree_v, nv), v0, v1)
        G = C.reshape(len(members), nu * nv, -1)
        idx = np.empty(rows.size, dtype=np.int64)
        step = max(1, _SEED_PAIRS // (nu * nv))
        for s0 in range(0, rows.size, step):  # bounded memory for large nets
            sl = slice(s0, s0 + step)
            diff = G[local[sl]] - P[rows[sl]][:, None, :]
            idx[sl] = np.argmin(np.einsum("mcj,mcj->mc", diff, diff), axis=1)
        uv[rows, 0], uv[rows, 1] = gu[idx // nv], gv[idx % nv]
        lo[rows], hi[rows] = (u0, v0), (u1, v1)
    todo = np.arange(m)
    for _ in range(_NEWTON_STEPS):
        if todo.size == 0:
            break
        x = uv[todo]
        D = derivatives_surfaces(surfaces, which[todo], x[:, 0], x[:, 1], 1)
        r = P[todo] - D[:, 0, 0]
        Su, Sv = D[:, 1, 0], D[:, 0, 1]
        speed[todo] = np.stack([np.linalg.norm(Su, axis=-1), np.linalg.norm(Sv, axis=-1)], axis=1)
        a, bb, c = np.einsum("mj,mj->m", Su, Su), np.einsum("mj,mj->m", Su, Sv), np.einsum("mj,mj->m", Sv, Sv)
        g0, g1 = np.einsum("mj,mj->m", Su, r), np.einsum("mj,mj->m", Sv, r)
        det = a * c - bb * bb
        ok = det > 1e-300  # a singular Jacobian (pole, collapsed edge): no step; verification decides
        safe = np.where(ok, det, 1.0)
        step = np.where(ok[:, None], np.stack([(c * g0 - bb * g1) / safe, (a * g1 - bb * g0) / safe], axis=1), 0.0)
        l, h = lo[todo], hi[todo]
        new = np.clip(x + step, l, h)
        moved = np.abs(new - x)
        uv[todo] = new
        # a surface's points are done together (as when each surface was inverted alone): the
        # speeds of their last step are those at uv to round-off
        still = np.any(moved > t.solver * np.maximum(1.0, h - l), axis=1)
        todo = todo[np.isin(which[todo], np.unique(which[todo[still]]))]
    return uv, speed


def pcurves_on(surface, items, box=None, tol: Tolerance | None = None, general: bool = True) -> list:
    """:func:`pcurve_on` for several curves on one surface: ``[(pcurve, deviation), ...]`` per item.

    ``items`` is a sequence of ``(curve, t0, t1)``.  On an analytic surface the ``2 × 33 - 1``
    samples of all items are projected in one closed-form call, unwrapped and shifted towards
    ``box`` as in :func:`continuous_parameters`, and the least-squares :class:`Line2D` of each item
    is accepted when it is within ``tol.linear`` at every sample (no sample at a pole or apex).
    On an open (not closed) NURBS surface the
    cheap exact candidate is tried first for all items at once: the curve's end points are
    inverted (:func:`_invert_nurbs_many`) and the :class:`Line2D` through their parameters is accepted
    when ``surface(line(t))`` is within ``tol.linear`` of ``curve(t)`` at the same
    ``2 × 33 - 1`` check samples as :func:`pcurve_on`'s exact forms, and neither end sits where a
    parameter is undetermined.  Everything else (and every item on other surfaces) goes through
    :func:`pcurve_on`, whose result and errors are returned / raised unchanged; with
    ``general=False`` those items are ``None`` instead (for callers with their own fallback).

    Raises
    ------
    InvalidInputError, InvalidGeometryError, ConvergenceError
        As :func:`pcurve_on` for the first item that takes the general path and fails.
    """
    t = resolve(tol)
    items = list(items)
    out = cheap_pcurves_many([(surface, items, box)], t)[0]
    if not general:
        return out
    return [r if r is not None else pcurve_on(surface, c, a, b, box, t) for r, (c, a, b) in zip(out, items)]


def cheap_pcurves_many(requests, tol: Tolerance | None = None) -> list[list]:
    """The cheap exact paths of :func:`pcurves_on` (``general=False``) for many faces at once.

    ``requests`` is a sequence of ``(surface, items, box)`` as the arguments of
    :func:`pcurves_on`; the result holds, per request, ``[(pcurve, deviation) or None, ...]``
    per item.  The items on open NURBS surfaces of all requests are inverted and verified
    together (one batch per Newton step for all surfaces, see :func:`_invert_nurbs_many`), and
    so are those on analytic surfaces (:func:`_cheap_analytic_many`: three closed-form calls per
    surface, the rest over all items).  Raises only for a malformed ``box``
    (``InvalidInputError``); what the cheap paths cannot decide is None.
    """
    t = resolve(tol)
    outs, nurbs, analytic = [], [], []
    for surface, items, box in requests:
        items = list(items)
        out: list = [None] * len(items)
        outs.append(out)
        if items and isinstance(surface, NurbsSurface):
            if surface.dimension == 3 and surface_periods(surface, t) == (None, None):
                nurbs.append((surface, items, None, out))
        elif items and hasattr(surface, "implicit") and hasattr(surface, "closest_parameters"):
            analytic.append((surface, items, _check_box(box), out))
    if nurbs:
        _cheap_lines_many(nurbs, t)
    if analytic:
        _cheap_analytic_many(analytic, t)
    return outs


def _cheap_lines_many(requests: list, t: Tolerance) -> None:
    """Fill ``out[i]`` with ``(Line2D, deviation)`` for the items whose p-curve is affine in ``t``, for many
    ``(surface, items, box, out)`` on open NURBS surfaces (``box`` unused: the domain bounds the lines).

    The curves are sampled per request; the inversion of the end points and the verification
    of the candidate lines run over the items of all requests together (surfaces of one
    structure evaluated as one batch), so a model of a thousand small patches costs a few
    batched passes rather than a thousand small ones.
    """
    from coons.kernel.surface import evaluate_surfaces

    got = _gathered(requests)
    if got is None:
        return
    owners, first, counts, ab, ts, X = got
    surfaces = [requests[r][0] for r in owners]
    item_surface = np.repeat(np.arange(len(owners)), counts)
    ends = X[:, [0, -1]].reshape(-1, 3)
    uv, speed = _invert_nurbs_many(surfaces, np.repeat(item_surface, 2), ends, t)
    uv, speed = uv.reshape(-1, 2, 2), speed.reshape(-1, 2, 2)
    dom = np.array([[S.domain[0][0], S.domain[0][1], S.domain[1][0], S.domain[1][1]] for S in surfaces])[item_surface]
    u0, u1, v0, v1 = dom.T
    lengths = np.stack([u1 - u0, v1 - v0], axis=1)
    # both ends must fix both parameters (not a pole or collapsed edge: see singular_parameters)
    determined = np.all(speed * lengths[:, None, :] > t.linear, axis=(1, 2))
    span = ab[:, 1] - ab[:, 0]
    d = (uv[:, 1] - uv[:, 0]) / span[:, None]
    scale = np.maximum(1.0, np.abs(uv).max(axis=(1, 2)))
    d[np.abs(d) * span[:, None] <= t.solver * scale[:, None]] = 0.0  # an iso-line: its constant parameter is exact
    o = uv[:, 0] - ab[:, :1] * d
    Q = o[:, None, :] + ts[..., None] * d[:, None, :]
    n = ts.shape[1]
    Qc = np.stack([np.clip(Q[..., 0], u0[:, None], u1[:, None]), np.clip(Q[..., 1], v0[:, None], v1[:, None])], axis=-1)
    img = evaluate_surfaces(surfaces, np.repeat(item_surface, n), Qc[..., 0].ravel(), Qc[..., 1].ravel()).reshape(X.shape)
    dev = np.linalg.norm(img - X, axis=-1).max(axis=1)
    E = Q[:, [0, -1]]
    inside = np.all((E[..., 0] >= u0[:, None]) & (E[..., 0] <= u1[:, None])
                    & (E[..., 1] >= v0[:, None]) & (E[..., 1] <= v1[:, None]), axis=1)
    good = np.flatnonzero(determined & (dev <= t.linear) & np.any(d != 0.0, axis=1))
    for i, pc in zip(good.tolist(), Line2D.many(o[good], d[good])):
        g = int(item_surface[i])
        surface, items, _, out = requests[owners[g]]
        j = int(i - first[g])
        c, a, b = items[j]
        out[j] = (pc, float(dev[i])) if inside[i] else _into_domain(surface, c, pc, float(dev[i]), float(a), float(b), t)


def _gathered(requests: list):
    """The samples of every item of ``(surface, items, box, out)`` requests, concatenated.

    Returns ``(owners, first, counts, ab, ts, X)``: the requests whose curves could be sampled
    (:func:`_samples`), the first row and number of rows of each, and the rows of all of them; or
    None when no request could be.
    """
    counts = np.array([len(items) for _, items, _, _ in requests], dtype=np.int64)
    whole = _samples([it for _, items, _, _ in requests for it in items]) if counts.all() else None
    if whole is not None:  # the common case: every curve of every request could be sampled, in one call
        first = np.concatenate([[0], np.cumsum(counts)[:-1]])
        return (list(range(len(requests))), first, counts, *whole)
    got, owners = [], []
    for r, (_, items, _, _) in enumerate(requests):
        g = _samples(items)
        if g is not None:
            got.append(g)
            owners.append(r)
    if not got:
        return None
    counts = np.array([g[0].shape[0] for g in got])
    first = np.concatenate([[0], np.cumsum(counts)[:-1]])
    return (owners, first, counts, *(np.concatenate([g[i] for g in got]) for i in range(3)))


def _samples(items: list) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
    """``(ab (k, 2), ts (k, n), X (k, n, 3))``: ranges, uniform parameters and curve points, or None."""
    n = 2 * _INITIAL_SAMPLES - 1
    s = np.linspace(0.0, 1.0, n)
    try:
        ab = np.array([(float(a), float(b)) for _, a, b in items])
    except (TypeError, ValueError):
        return None
    if not (np.all(np.isfinite(ab)) and np.all(ab[:, 0] < ab[:, 1])):
        return None  # pcurve_on reports malformed ranges
    ts = ab[:, :1] + s[None, :] * (ab[:, 1:] - ab[:, :1])
    ts[:, -1] = ab[:, 1]
    try:
        X = evaluate_curves([c for c, _, _ in items], ts)
    except (AttributeError, TypeError, ValueError, CoonsError):
        return None  # pcurve_on reports unusable curves
    return ab, ts, X


#: Types :func:`curve_derivatives` batches: 1 line, 2 circle, 3 straight and 4 trigonometric p-curve,
#: and the dimension of each kind.
_BATCHED_KIND = {Line: 1, Circle: 2, Line2D: 3, Trig2D: 4}
_BATCHED_DIM = {1: 3, 2: 3, 3: 2, 4: 2}


#: Curve types :func:`evaluate_curves` evaluates as one array expression each (most edges of a model).
BATCHED_CURVES = tuple(kind for kind, code in _BATCHED_KIND.items() if _BATCHED_DIM[code] == 3)


def evaluate_curves(curves: list, T: np.ndarray) -> np.ndarray:
    """Points of many 3-D curves at once: ``curves[k]`` at the parameters ``T[k]``, ``(k, n, 3)``.

    Lines and circles (most edges of a model) are evaluated in one expression each, with the
    formulas of their own ``evaluate``; any other curve is called once (:func:`curve_derivatives`).

    Raises
    ------
    InvalidInputError
        Not one row of parameters per curve, non-finite parameters, or a curve whose points are not 3-D.
    """
    return curve_derivatives(curves, T, 0, 3)[..., 0, :]


#: Points (curves × parameters) of one curve type from which :func:`curve_derivatives` evaluates coordinate by
#: coordinate: ``(k, n)`` arrays, where numpy walks the ``(k, n, 3)`` form's short inner axis slowly (the
#: one-call plate's batches of thousands: a quarter faster); below it the broadcast form, which makes a third
#: of the numpy calls (crossing near 300–500 points here).  Both are the same expressions per coordinate.
_COORDINATE_POINTS = 512


def curve_derivatives(curves: list, T: np.ndarray, order: int = 1, dimension: int | None = None) -> np.ndarray:
    """Points and derivatives of many curves at once: ``curves[k]`` at the parameters ``T[k]``,
    ``(k, n, order + 1, d)``.

    Lines and circles in space and straight and trigonometric p-curves (``Line2D``, ``Trig2D``)
    are evaluated in one expression per type with the formulas of their own ``derivatives``
    (coordinate by coordinate from :data:`_COORDINATE_POINTS` points of a type on);
    polynomial NURBS curves of one degree together (:func:`coons.kernel._stacked.derivatives_many`);
    any other curve is called once.  ``d`` is ``dimension``, or the first curve's.

    Raises
    ------
    InvalidInputError
        Not one row of parameters per curve, non-finite parameters, or a curve of another dimension.
    """
    T = np.asarray(T, dtype=np.float64)
    k = len(curves)
    if k == 0 and T.size == 0:  # (no curves: no points, whatever the empty T's shape)
        return np.empty((0, T.shape[1] if T.ndim == 2 else 0, order + 1, dimension or 0))
    if T.ndim != 2 or T.shape[0] != k:
        raise InvalidInputError(f"curve_derivatives needs one row of parameters per curve: {k} curves, T {T.shape}")
    if not np.isfinite(T).all():
        raise InvalidInputError("parameters must be finite, got NaN or inf")
    groups: dict[int, list[int]] = {}  # (Python lists: the batches are often a handful of curves)
    for i, c in enumerate(curves):
        groups.setdefault(_BATCHED_KIND.get(type(c), 0), []).append(i)
    if dimension is None:  # (k >= 1 here)
        first = _BATCHED_KIND.get(type(curves[0]), 0)
        dimension = _BATCHED_DIM[first] if first else int(np.asarray(curves[0].derivatives(T[0][:1], 0)).shape[-1])
    X = np.empty(T.shape + (order + 1, dimension))
    for code, d in _BATCHED_DIM.items():
        rows = groups.get(code)
        if rows is None:
            continue
        if d != dimension:
            raise InvalidInputError(f"curve {rows[0]} ({type(curves[rows[0]]).__name__}) is not {dimension}-D")
        if len(rows) == k:  # (all of one type: written in place)
            members, t, Y = curves, T, X
        else:  # (written into its own block, scattered once)
            members, t = [curves[i] for i in rows], T[rows]
            Y = np.empty(t.shape + (order + 1, d))
        _batched_derivatives(code, members, t, Y, t.size >= _COORDINATE_POINTS)
        if Y is not X:
            X[rows] = Y
    rest = groups.get(0)
    if rest:
        # (polynomial NURBS of one degree as one batch, the same bits as their own derivatives)
        from coons.kernel._stacked import derivatives_many

        for i, D in zip(rest, derivatives_many([curves[i] for i in rest], [T[i] for i in rest], order)):
            if D.shape[-1] != dimension:
                raise InvalidInputError(f"curve {i} ({type(curves[i]).__name__}) is not {dimension}-D")
            X[i] = np.moveaxis(D, 0, 1).reshape(X[i].shape)
    return X


def _batched_derivatives(code: int, members: list, t: np.ndarray, Y: np.ndarray, by_coordinate: bool) -> None:
    """Write the points and derivatives of ``members`` (all of kind ``code`` of :data:`_BATCHED_KIND`) at ``t (m, n)``
    into ``Y (m, n, order + 1, d)``: the expressions of their own ``derivatives``, per coordinate on ``(m, n)``
    arrays (``by_coordinate``) or broadcast over ``(m, n, d)``; the same floats either way."""
    order = Y.shape[2] - 1
    if code in (1, 3):  # O + t D
        O = np.array([c.origin for c in members])
        D = np.array([c.direction for c in members])
        if by_coordinate:
            for i in range(Y.shape[3]):
                Y[:, :, 0, i] = O[:, i, None] + t * D[:, i, None]
        else:
            Y[:, :, 0] = O[:, None, :] + t[..., None] * D[:, None, :]
        if order >= 1:
            Y[:, :, 1] = D[:, None, :]
            if order >= 2:
                Y[:, :, 2:] = 0.0
        return
    if code == 2:  # O + (R cos t) X + (R sin t) Y
        F = np.array([c.frame for c in members])
        R = np.array([float(c.radius) for c in members])[:, None]
        O, A, B = np.array([c.center for c in members]), F[:, 0], F[:, 1]
        c, s = np.cos(t), np.sin(t)
        c, s = R * c, R * s  # (R (d^j/dt^j cos t) is ± R cos t or ± R sin t: the same products, negated)
    else:  # C + cos t a + sin t b
        O = np.array([c.center for c in members])
        A = np.array([c.a for c in members])
        B = np.array([c.b for c in members])
        c, s = np.cos(t), np.sin(t)
    # d^j/dt^j (cos t, sin t), period 4, negated only where an order needs it
    cycle = [(c, s)]
    if order >= 1:
        cycle.append((-s, c))
    if order >= 2:
        cycle += [(-c, -s), (s, -c)]
    if by_coordinate:
        for j in range(order + 1):
            cj, sj = cycle[j % 4]
            for i in range(Y.shape[3]):
                if j == 0 and code == 2:
                    Y[:, :, 0, i] = (cj * A[:, i, None] + sj * B[:, i, None]) + O[:, i, None]
                elif j == 0:  # (Trig2D.evaluate's order of sums: the same points bit for bit)
                    Y[:, :, 0, i] = (O[:, i, None] + cj * A[:, i, None]) + sj * B[:, i, None]
                else:
                    Y[:, :, j, i] = cj * A[:, i, None] + sj * B[:, i, None]
        return
    A, B, O = A[:, None, :], B[:, None, :], O[:, None, :]
    for j in range(order + 1):
        cj, sj = cycle[j % 4]
        cj, sj = cj[..., None], sj[..., None]
        if j == 0 and code == 2:
            Y[:, :, 0] = (cj * A + sj * B) + O
        elif j == 0:  # (Trig2D.evaluate's order of sums: the same points bit for bit)
            Y[:, :, 0] = (O + cj * A) + sj * B
        else:
            Y[:, :, j] = cj * A + sj * B


def _cheap_analytic_many(requests: list, t: Tolerance) -> None:
    """Fill ``out[i]`` with ``(Line2D, deviation)`` for the items whose p-curve on an analytic surface is affine in ``t``.

    ``requests`` holds ``(surface, items, box, out)``.  Per surface the samples are projected
    (closed form), tested for undetermined parameters and the candidate lines evaluated, one
    call each; unwrapping, the shift towards ``box``, the least-squares lines and the
    deviations run over the items of all requests at once.
    """
    got = _gathered(requests)
    if got is None:
        return
    owners, first, counts, ab, ts, X = got
    k, n = ts.shape
    uv = np.empty((k, n, 2))
    free = np.empty((k, n, 2), dtype=bool)
    period = np.full((k, 2), np.nan)
    mid = np.full((k, 2), np.nan)  # the box's middle where it is finite
    for g, r in enumerate(owners):
        surface, _, box, _ = requests[r]
        sl = slice(int(first[g]), int(first[g] + counts[g]))
        q = np.asarray(surface.closest_parameters(X[sl].reshape(-1, 3)), dtype=np.float64)
        free[sl] = singular_parameters(surface, q, box, t).reshape(-1, n, 2)
        uv[sl] = q.reshape(-1, n, 2)
        for j, per in enumerate(surface_periods(surface, t)):
            if per is not None:
                period[sl, j] = per
                if box is not None and np.all(np.isfinite(box[j])):
                    mid[sl, j] = 0.5 * (box[j][0] + box[j][1])
    for j in range(2):
        rows = np.flatnonzero(np.isfinite(period[:, j]))
        if rows.size == 0:
            continue
        per = period[rows, j]
        col = _unwrap_rows(uv[rows, :, j], per)
        m = mid[rows, j]
        shift = np.isfinite(m)
        have = 0.5 * (col.min(axis=1) + col.max(axis=1))
        col = col + np.where(shift, per * np.round((np.where(shift, m, 0.0) - have) / per), 0.0)[:, None]
        uv[rows, :, j] = col
    # least-squares line in t per item (closed form of _exact_form's lstsq)
    tm = 0.5 * (ab[:, 0] + ab[:, 1])
    sc = ts - tm[:, None]
    mean = uv.mean(axis=1)
    d = np.einsum("kn,knj->kj", sc, uv - mean[:, None, :]) / np.einsum("kn,kn->k", sc, sc)[:, None]
    reach = ab[:, 1] - ab[:, 0]
    scale = np.maximum(1.0, np.abs(uv).max(axis=(1, 2)))
    d[np.abs(d) * reach[:, None] <= t.solver * scale[:, None]] = 0.0  # as _snap_small
    o = mean - tm[:, None] * d
    Q = o[:, None, :] + ts[..., None] * d[:, None, :]
    S = np.empty_like(X)
    for g, r in enumerate(owners):
        sl = slice(int(first[g]), int(first[g] + counts[g]))
        S[sl] = np.asarray(requests[r][0].evaluate(Q[sl, :, 0].ravel(), Q[sl, :, 1].ravel())).reshape(-1, n, 3)
    dev = np.linalg.norm(S - X, axis=-1).max(axis=1)
    good = ~free.any(axis=(1, 2)) & (dev <= t.linear) & np.any(d != 0.0, axis=1)
    owner = np.repeat(np.arange(len(owners)), counts)
    idx = np.flatnonzero(good)
    for i, pc in zip(idx.tolist(), Line2D.many(o[idx], d[idx])):
        g = int(owner[i])
        requests[owners[g]][3][int(i - first[g])] = (pc, float(dev[i]))


def _unwrap_rows(col: np.ndarray, period: np.ndarray) -> np.ndarray:
    """``np.unwrap(col, period=p, axis=1)`` with its own period ``p`` per row (numpy's algorithm)."""
    dd = np.diff(col, axis=1)
    half = (period / 2.0)[:, None]
    p = period[:, None]
    ddmod = np.mod(dd + half, p) - half
    ddmod = np.where((ddmod == -half) & (dd > 0), half, ddmod)
    correct = np.where(np.abs(dd) < half, 0.0, ddmod - dd)
    out = col.copy()
    out[:, 1:] += np.cumsum(correct, axis=1)
    return out
