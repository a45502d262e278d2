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
   follows the curvature), until all midpoints pass.
"""

from __future__ import annotations

import logging
import math
from typing import Any

import numpy as np

from coons.errors import ConvergenceError, InvalidGeometryError, InvalidInputError
from coons.kernel import projection
from coons.kernel.analytic import Circle, Ellipse
from coons.kernel.curve import NurbsCurve
from coons.kernel.fitting import interpolate_curve
from coons.kernel.pcurve import Line2D, Trig2D
from coons.kernel.surface import NurbsSurface
from coons.tolerance import Tolerance, resolve

__all__ = ["pcurve_on"]

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
    (u0, u1), (v0, v1) = surface.domain_u, surface.domain_v
    su, sv = np.linspace(u0, u1, _CLOSED_SAMPLES), np.linspace(v0, v1, _CLOSED_SAMPLES)
    gap_u = np.linalg.norm(surface.evaluate(u0, sv) - surface.evaluate(u1, sv), axis=-1).max()
    gap_v = np.linalg.norm(surface.evaluate(su, v0) - surface.evaluate(su, v1), axis=-1).max()
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
    if box is None and isinstance(surface, NurbsSurface):
        box = surface.domain
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
        if per is not None and box is not None:
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
    if exact is not None:
        return exact
    return _fitted(surface, curve, ts, P, uv, bx, t)


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
