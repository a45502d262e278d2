"""Intersections of two parametric curves over given parameter ranges, in 2-D or 3-D.

:func:`intersect_curves` finds the isolated crossings and touchings of two curve pieces and the
parameter ranges where they coincide (overlaps).  It accepts the curves of coons —
:class:`~coons.kernel.pcurve.Line2D`, :class:`~coons.kernel.pcurve.Trig2D`, 2-D and 3-D
:class:`~coons.kernel.curve.NurbsCurve`, :class:`~coons.kernel.analytic.Line`,
:class:`~coons.kernel.analytic.Circle`, :class:`~coons.kernel.analytic.Ellipse` — and any object
with ``derivatives(t, order) -> shape + (order + 1, d)``.

0. **Closed forms** first: crossing lines (2-D or 3-D, least squares), a 2-D line against a
   ``Trig2D`` (``A cos t + B sin t = R`` along the line's normal) and two 2-D circles (the radical
   line; circles within ``tol.linear`` of touching meet once, at the touching point), plus the
   range ends lying within ``tol.linear`` of the other curve.  Parallel lines and all other pairs go on with the
   classic bounding-box subdivision and Newton (Sederberg & Nishita 1990; The NURBS Book §6.5):
1. **Pieces with proven boxes.**  Each curve is cut into pieces whose axis-aligned boxes
   contain the curve: for a NURBS the local control points of each (refined) knot span
   (convex hull property, The NURBS Book P4.9, positive weights); for a line the segment; for
   a conic or ``Trig2D`` the chord's box enlarged by ``h² M / 8``, where ``M`` bounds ``|C''|``
   (the linear-interpolation error bound ``|C(t) - L(t)| <= (t - a)(b - t) M / 2``).  Other
   curve types get a sampled bound (``M`` estimated on samples and doubled; not proven).
2. **Candidate pairs**: pieces whose boxes, enlarged by ``tol.linear``, overlap (one array
   comparison over all pairs).
3. **Newton** on the squared distance (full Hessian where positive definite, else damped
   Gauss–Newton; projected onto the ranges with an active set: a parameter held on a range end
   leaves the other the one-variable step) from the centre of each candidate pair and
   from every end point against the nearest sample of the other curve, all seeds at once; a
   solution whose points are within ``tol.linear`` is an intersection.  Transverse crossings
   converge quadratically, tangential touchings too (the distance's Hessian is definite
   there).  Range ends within ``tol.linear`` of the other curve are added (projected Newton
   can stall at a range end when the extended curves cross just outside it).
4. **Overlaps**: the parameter axis of the first curve is cut at its range ends and at the
   projections of the second curve's ends; an interval whose interior samples all lie within
   ``tol.linear`` of the second curve is an overlap.  Overlaps therefore end where one of the
   curves ends (the case of edges sharing a stretch between vertices); two curves that
   coincide over a stretch and then part inside both ranges give no overlap but one point.
   Solutions inside an overlap are dropped; solutions closer than ``tol.linear`` (or joined by
   a stretch within ``tol.linear`` of both curves, as around a tangential touching) are one.

A polynomial 2-D NURBS against a 2-D line (a fitted p-curve against a straight boundary edge,
the common pair when a curved face is split) replaces steps 1–3 (:func:`_nurbs_line`): the
signed distance to the line is a polynomial on each knot span, so the pieces are pruned by the
Bézier coefficients of that distance and of the foot's parameter along the line (convex hull),
and the remaining ones are solved in one variable from their middles and from the real parts of
the roots of the distance and of its derivative (companion matrices): two crossings in one piece
are both found.  Steps 4 and the end contacts are the general path's.

Speed (many small problems: face splitting intersects each p-curve with every boundary piece).
A clamped NURBS is evaluated through per-span polynomials built once per curve object and
cached weakly (:class:`_PowerForm`); its piece boxes are the Bézier hulls of equal fractions of
its spans.  Lines and conics are evaluated from their closed forms (``o + t d``,
``C + A cos t + B sin t``) without the per-call checks of the curve classes.  Feet of points
on lines and circles are closed forms; the feet of the range ends are computed once per call
and shared by the seeds, the end contacts and the overlap cuts.  Two crossing 2-D lines (the
common pair when a face with straight p-curves is split) take the same steps on Python floats
(:func:`_lines_2d`), and :func:`refine_intersections` of a few seeds on lines, conics and
polynomial NURBS (their spans' power forms, by Horner) iterates each seed on Python floats
(:func:`_newton_one`): there numpy's per-call cost on
one- and two-element arrays was most of the time.  Both agree with the array paths to
round-off (the module switch ``_FAST`` turns them and :func:`_nurbs_line` off for the tests
that compare).  Projections that only decide "within ``tol.linear``" skip the Newton of points
outside every piece box enlarged by it.

The module does not intersect a curve with itself, does not compute intersection
multiplicities, and does not find two distinct intersections closer together than the pieces
resolve (both are reported as one).
"""

from __future__ import annotations

import bisect
import math
import weakref
from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy.interpolate import BSpline

from coons.errors import InvalidInputError
from coons.kernel.analytic import Circle, Ellipse, Line
from coons.kernel.curve import NurbsCurve
from coons.kernel.pcurve import Line2D, Trig2D
from coons.tolerance import Tolerance, resolve

__all__ = ["CurveIntersections", "curve_box", "curve_boxes", "intersect_curves", "refine_intersections"]

#: Pieces per full turn of a conic: the chord box margin h² M / 8 is then below 2 % of the radius.
_CONIC_PIECES_PER_TURN = 32
#: One turn of a periodic parameter.
_TWO_PI = 2.0 * math.pi
#: Target number of pieces of a general curve (NURBS spans are refined up to about this many).
_TARGET_PIECES = 64
#: Samples along a curve used to seed projections.
_SEED_SAMPLES = 129
#: Interior fractions of an interval sampled to decide whether it is an overlap.
_OVERLAP_PROBES = np.array([0.1, 0.3, 0.5, 0.7, 0.9])
#: Newton iterations (linear convergence at tangential touchings needs a few dozen).
_NEWTON_ITERATIONS = 60
#: Newton steps without getting closer after which a seed is abandoned (not an intersection).
_STALL = 4
#: sin² of the angle between the tangents above which Newton also tries the Gauss–Newton step (a
#: solver strategy, not a geometric decision: the closer trial point is kept either way).
_TRANSVERSAL = 1e-4


@dataclass(frozen=True, eq=False)
class CurveIntersections:
    """Result of :func:`intersect_curves`.

    Attributes
    ----------
    t1, t2 : (k,) float64
        Parameters of the isolated intersections on the first and second curve, sorted by ``t1``;
        one entry per point (a point at both ends of a closed curve's range is reported once).
    points : (k, d) float64
        The intersection points (midpoint of the two curve points).
    overlaps : tuple of ((s0, s1), (u0, u1))
        Ranges where the curves coincide: ``c1([s0, s1])`` (``s0 < s1``) is ``c2([u0, u1])`` with
        ``c1(s0) = c2(u0)`` and ``c1(s1) = c2(u1)`` (``u0 > u1`` when the curves run opposite ways).
    """

    t1: np.ndarray
    t2: np.ndarray
    points: np.ndarray
    overlaps: tuple[tuple[tuple[float, float], tuple[float, float]], ...]

    def __len__(self) -> int:
        return int(self.t1.size)


# ====================================================================== curve access
def _dimension(curve: Any, what: str) -> int:
    if not callable(getattr(curve, "derivatives", None)):
        raise InvalidInputError(f"{what} must have a derivatives(t, order) method, got {type(curve).__name__}")
    if isinstance(curve, (Line2D, Trig2D)):
        return 2
    if isinstance(curve, (Line, Circle, Ellipse)):
        return 3
    if isinstance(curve, NurbsCurve):
        return curve.dimension
    return int(np.asarray(curve.derivatives(np.zeros(1), 0)).shape[-1])


def _range(r, curve: Any, what: str, t_: Tolerance) -> tuple[float, float]:
    try:
        a, b = (float(x) for x in r)
    except (TypeError, ValueError):
        raise InvalidInputError(f"{what} must be a pair of numbers (t0, t1), got {r!r}") from None
    if not (math.isfinite(a) and math.isfinite(b)) or a == b:
        raise InvalidInputError(f"{what} must be two finite, different numbers, got {r!r}")
    lo, hi = min(a, b), max(a, b)
    if isinstance(curve, NurbsCurve):
        d0, d1 = curve.domain
        slack = t_.solver * max(1.0, d1 - d0)  # round-off of the caller's parameter arithmetic (tolerance.py)
        if lo < d0 - slack or hi > d1 + slack:
            raise InvalidInputError(f"{what} = {r!r} leaves the curve's domain [{d0!r}, {d1!r}]")
        lo, hi = max(lo, d0), min(hi, d1)
    return lo, hi


def _derivs(curve: Any, t: np.ndarray, order: int) -> np.ndarray:
    """``(k, order + 1, d)`` derivatives at the parameters ``t`` (k,)."""
    lin = _linear(curve)
    if lin is not None:  # o + t d, without the per-call validation of the curve classes
        o, d = lin
        t = np.asarray(t, dtype=np.float64).reshape(-1)
        out = np.zeros((t.size, order + 1, o.size))
        out[:, 0] = o + t[:, None] * d
        if order:
            out[:, 1] = d
        return out
    if isinstance(curve, NurbsCurve):
        form = _power_form(curve)
        if form is not None:
            return form.derivatives(t, order)
    elif isinstance(curve, (Circle, Ellipse, Trig2D)):
        C, A, B = _trig_form(curve)
        t = np.asarray(t, dtype=np.float64).reshape(-1)
        c, s = np.cos(t)[:, None], np.sin(t)[:, None]
        cycle = ((c, s), (-s, c), (-c, -s), (s, -c))  # d^k/dt^k (cos t, sin t), period 4
        out = np.empty((t.size, order + 1, C.size))
        for k in range(order + 1):
            ck, sk = cycle[k % 4]
            out[:, k] = ck * A + sk * B
        out[:, 0] += C
        return out
    return np.asarray(curve.derivatives(t, order), dtype=np.float64)


_TRIG: "weakref.WeakKeyDictionary[Any, tuple[np.ndarray, np.ndarray, np.ndarray]]" = weakref.WeakKeyDictionary()


def _trig_form(curve) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(C, A, B)`` with ``curve(t) = C + A cos t + B sin t`` for a circle, ellipse or ``Trig2D`` (cached)."""
    form = _TRIG.get(curve)
    if form is None:
        if isinstance(curve, Trig2D):
            form = (curve.center, curve.a, curve.b)
        else:  # C + a cos t X + b sin t Y
            a, b = (curve.radius, curve.radius) if isinstance(curve, Circle) else (curve.major_radius,
                                                                                   curve.minor_radius)
            form = (np.asarray(curve.center, dtype=np.float64), a * curve.frame[0], b * curve.frame[1])
        _TRIG[curve] = form
    return form


class _PowerForm:
    """A clamped NURBS curve as one polynomial per knot span, for the many small evaluations here.

    Each span ``[a, b]`` of the homogeneous curve ``[w C, w]`` is a polynomial of degree ``p``
    in ``x = (t - a) / (b - a) ∈ [0, 1]``; its power coefficients are its Taylor coefficients at
    ``a`` (one vectorised derivative evaluation of the homogeneous B-spline, by scipy's
    ``BSpline``).  Derivatives are sums of powers of ``x`` and the rational quotient rule (The
    NURBS Book eq. 4.8).  Built once
    per curve object (:func:`_power_form`): the callers (face splitting) intersect one p-curve
    with many others, and this evaluation costs a few array operations where
    ``NurbsCurve.derivatives`` costs a basis-function evaluation.  On ``[0, 1]`` the power form
    of a low-degree polynomial is well conditioned (values to a few ulps of the control points'
    magnitude).
    """

    def __init__(self, curve: NurbsCurve):
        p = curve.degree
        self.p, self.rational, self.dim = p, curve.is_rational, curve.dimension
        self.breaks = vals = curve.knot_multiplicities[0]
        # Taylor coefficients at each span's start, D^k(a) h^k / k!, of the homogeneous curve (a polynomial
        # B-spline in d + 1 coordinates; at a knot the span to its right is evaluated).
        # scipy's compiled de Boor evaluation: the same values within round-off as NurbsCurve.derivatives of
        # the homogeneous curve, at a third of the cost of its argument checks and basis rows (the p-curves of
        # a cylinder-cylinder loop have ~50 spans and are built once per Boolean).
        # (construct_fast: the curve's knots and control points are validated already; the evaluation is the same)
        hom = BSpline.construct_fast(curve.knots, curve.homogeneous, p, extrapolate=False)
        h = np.diff(vals)
        D = np.stack([hom(vals[:-1], nu=k) for k in range(p + 1)], axis=1)  # (spans, p + 1, d + 1)
        scale = np.array([1.0 / math.factorial(k) for k in range(p + 1)])[None, :] * h[:, None] ** np.arange(p + 1)
        #: (spans, p + 1, d + 1) power coefficients in the local parameter x = (t - a) / h.
        self.coef = D * scale[:, :, None]
        self._stacked: np.ndarray | None = None
        self._scalar: tuple | None = None
        self._ends: dict[bytes, np.ndarray] = {}  # t bytes -> derivatives at two parameters (see derivatives)
        self._powers = np.arange(p + 1)
        self._break_list = vals.tolist()
        self._lengths = h  # (spans,) the spans' lengths, br[i + 1] - br[i]
        self._binom = [[math.comb(k, i) for i in range(k + 1)] for k in range(p + 3)]

    def _stack(self, order: int) -> np.ndarray:
        """``(spans, k + 1, p + 1, d + 1)``, ``k >= order``: power coefficients of the x-derivatives of orders
        0..k, built once up to at least :data:`_STACKED_ORDER` (the face split reads a cut's points, tangents
        and curvatures: building the orders one call at a time built the array twice per curve)."""
        if self._stacked is None or self._stacked.shape[1] <= order:
            c = [self.coef]
            for _ in range(max(order, _STACKED_ORDER)):
                nxt = np.zeros_like(c[-1])
                nxt[:, :-1] = c[-1][:, 1:] * np.arange(1, self.p + 1)[None, :, None]
                c.append(nxt)
            self._stacked = np.stack(c, axis=1)
        return self._stacked

    def scalar(self) -> tuple | None:
        """``("poly", breaks, coef)`` for :func:`_point1` (Python floats; ``coef[span][k][j]`` the power
        coefficients of the k-th x-derivative, k <= 2, of the curve itself), None for a rational curve.

        A non-rational NURBS may have all weights equal to some ``w != 1``: the homogeneous
        coefficients are then ``w`` times the curve's, so they are divided by that constant weight.
        ``coef`` turns a span into lists when it is first read (:class:`_SpanLists`)."""
        if self.rational:
            return None
        if self._scalar is None:
            S = self._stack(2)[:, :3]
            w = float(S[0, 0, 0, -1])  # (the weight channel: the constant w, its derivatives 0)
            self._scalar = ("poly", self.breaks.tolist(), _SpanLists(S[..., :-1] / w))
        return self._scalar

    def bezier(self, lo: float, hi: float):
        """The spans meeting ``[lo, hi]``, each cut into ``per`` equal pieces (about :data:`_TARGET_PIECES` in
        all), as Bézier control points.

        The piece ``x ∈ [x0, x0 + g]`` of a span has power coefficients
        ``c'_m = g^m Σ_{k>=m} C(k, m) x0^(k-m) c_k`` and Bézier points ``P_i = Σ_{m<=i} C(i, m) / C(p, m) c'_m``.

        Returns
        -------
        span : (m,) int64, the knot span of each piece (index into ``breaks``)
        x0, x1 : (m,) float64, the piece in the span's local parameter ``x = (t - a) / h``
        a, b : (m,) float64, the piece's parameter range (not clipped to ``[lo, hi]``)
        P : (m, p + 1, d) float64, Bézier control points (rational pieces: the projected points)
        """
        br, p = self.breaks, self.p
        sel = np.flatnonzero((br[1:] > lo) & (br[:-1] < hi))
        per = max(1, math.ceil(_TARGET_PIECES / max(1, sel.size)))
        x0 = np.arange(per) / per
        g = 1.0 / per
        T = np.zeros((per, p + 1, p + 1))  # T[q, m, k]: c'_m of piece q from c_k
        Minv = np.zeros((p + 1, p + 1))
        for m in range(p + 1):
            for k in range(m, p + 1):
                T[:, m, k] = math.comb(k, m) * x0 ** (k - m) * g ** m
            for i in range(m, p + 1):
                Minv[i, m] = math.comb(i, m) / math.comb(p, m)
        B = np.einsum("im,qmk,skd->sqid", Minv, T, self.coef[sel])  # (spans, per, p + 1, d + 1)
        P = B[..., :-1] / B[..., -1:]
        h = br[sel + 1] - br[sel]
        a = (br[sel][:, None] + x0[None] * h[:, None]).ravel()
        b = (br[sel][:, None] + (x0 + g)[None] * h[:, None]).ravel()
        last = np.repeat(np.arange(per)[None] == per - 1, sel.size, axis=0).ravel()
        b = np.where(last, np.repeat(br[sel + 1], per), b)  # the last piece ends exactly at the knot
        P = P.reshape(-1, p + 1, self.dim)
        span = np.repeat(sel, per)
        xa = np.tile(x0, sel.size)
        xb = np.where(last, 1.0, xa + g)
        keep = (b > lo) & (a < hi)
        return span[keep], xa[keep], xb[keep], a[keep], b[keep], P[keep]

    def pieces(self, lo: float, hi: float, bezier: tuple):
        """The pieces of :meth:`bezier` (its answer ``bezier`` for this range), clipped to ``[lo, hi]``, with
        the boxes of their Bézier control points (convex hull property, positive weights).

        Returns
        -------
        a, b : (m,) float64; box_lo, box_hi : (m, d) float64
        """
        _, _, _, a, b, P = bezier
        return np.maximum(a, lo), np.minimum(b, hi), P.min(axis=1), P.max(axis=1)

    def derivatives(self, t: np.ndarray, order: int) -> np.ndarray:
        """``(k, order + 1, d)`` point and derivatives at ``t (k,)`` (the span to the right at a knot).

        The answer at two parameters (a piece's two ends, which several steps of the face split read at
        orders 0 to 2) is remembered per ``t`` at the highest order asked: a call asking that order or a
        lower one gets a copy of its leading rows.  The same bits as computed: each row of a derivative
        order is its own sum over the span's powers, whatever the orders computed with it (the tests
        compare)."""
        t = np.asarray(t, dtype=np.float64).ravel()
        if t.size != 2:
            return self._derivatives(t, order)
        key = t.tobytes()
        out = self._ends.get(key)
        if out is None or out.shape[1] <= order:
            out = self._ends[key] = self._derivatives(t, order)
        return out[:, : order + 1].copy()

    def _derivatives(self, t: np.ndarray, order: int) -> np.ndarray:
        """:meth:`derivatives` of flat parameters ``t`` ``(k,)``, computed."""
        br = self.breaks
        if t.size <= _FEW_POINTS:
            # The spans of a few parameters by bisection on Python floats (np.searchsorted's answer, side
            # "right", also for nan: past the end), without the array calls' set-up.
            bl, last = self._break_list, br.size - 2
            span = np.array([min(max(bisect.bisect_right(bl, x) - 1, 0), last) for x in t.tolist()], dtype=np.intp)
        else:
            span = np.minimum(np.maximum(np.searchsorted(br, t, side="right") - 1, 0), br.size - 2)
        a, h = br[span], self._lengths[span]
        x = (t - a) / h
        X = x[:, None] ** self._powers  # (k, p + 1)
        C = self._stack(order)[span, : order + 1]  # (k, order + 1, p + 1, d + 1)
        H = np.einsum("kj,kojd->kod", X, C)
        if order:
            H[:, 1:] /= (h[:, None] ** self._powers[1 : order + 1])[:, :, None]
        if not self.rational:
            return H[:, :, :-1] / H[:, :1, -1:]  # constant weight
        A, w = H[:, :, :-1], H[:, :, -1:]
        # Quotient rule C^(k) = (A^(k) - Σ_{i=1..k} C(k, i) w^(i) C^(k-i)) / w (The NURBS Book eq. 4.8).
        out = np.empty_like(A)
        for k in range(order + 1):
            v = A[:, k].copy()
            for i in range(1, k + 1):
                v -= self._binom[k][i] * w[:, i] * out[:, k - i]
            out[:, k] = v / w[:, 0]
        return out


#: Orders of x-derivatives :meth:`_PowerForm._stack` builds at least (curvature, for the face split's directions).
_STACKED_ORDER = 2
#: Up to this many parameters :meth:`_PowerForm.derivatives` finds their spans by bisection in Python.
_FEW_POINTS = 8


class _SpanLists:
    """``coef[span]`` as ``coef[span].tolist()``, converted on first use and kept.

    The Newton iterations on Python floats (:func:`_point1`) read the few spans around their roots of a
    p-curve of up to a hundred spans: converting every span up front cost more than the iterations."""

    __slots__ = ("_array", "_rows")

    def __init__(self, array: np.ndarray) -> None:
        self._array = array
        self._rows: dict[int, list] = {}

    def __getitem__(self, i: int) -> list:
        row = self._rows.get(i)
        if row is None:
            row = self._rows[i] = self._array[i].tolist()
        return row


_FORMS: "weakref.WeakKeyDictionary[NurbsCurve, _PowerForm | None]" = weakref.WeakKeyDictionary()


def _power_form(curve: NurbsCurve) -> _PowerForm | None:
    """The cached :class:`_PowerForm` of a clamped curve, None for an unclamped one."""
    form = _FORMS.get(curve, False)
    if form is False:
        U, p = curve.knots, curve.degree
        clamped = U[0] == U[p] and U[-1] == U[-p - 1]
        form = _PowerForm(curve) if clamped else None
        _FORMS[curve] = form
    return form


# ====================================================================== pieces and boxes
def _pieces(curve: Any, lo: float, hi: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Pieces of ``curve([lo, hi])`` with boxes containing them.

    Returns
    -------
    a, b : (m,) float64, piece parameter ranges (``a < b``)
    box_lo, box_hi : (m, d) float64
    """
    if isinstance(curve, (Line, Line2D)):
        P = _derivs(curve, np.array([lo, hi]), 0)[:, 0]
        return np.array([lo]), np.array([hi]), P.min(axis=0)[None], P.max(axis=0)[None]
    if isinstance(curve, NurbsCurve):
        return _nurbs_pieces(curve, lo, hi)
    if isinstance(curve, Trig2D):
        bound = float(np.linalg.norm(np.stack([curve.a, curve.b], axis=1), 2))  # max |a cos t + b sin t|
        m = max(1, math.ceil((hi - lo) * _CONIC_PIECES_PER_TURN / (2.0 * math.pi)))
    elif isinstance(curve, Circle):
        bound = float(curve.radius)
        m = max(1, math.ceil((hi - lo) * _CONIC_PIECES_PER_TURN / (2.0 * math.pi)))
    elif isinstance(curve, Ellipse):
        bound = float(curve.major_radius)
        m = max(1, math.ceil((hi - lo) * _CONIC_PIECES_PER_TURN / (2.0 * math.pi)))
    else:
        # Unknown type: the second derivative is bounded on samples only (doubled for safety).
        m = _TARGET_PIECES
        ts = np.linspace(lo, hi, 4 * m + 1)
        bound = 2.0 * float(np.linalg.norm(_derivs(curve, ts, 2)[:, 2], axis=1).max())
    t = np.linspace(lo, hi, m + 1)
    P = _derivs(curve, t, 0)[:, 0]
    h = t[1:] - t[:-1]
    margin = (h * h * bound / 8.0)[:, None]
    return t[:-1], t[1:], np.minimum(P[:-1], P[1:]) - margin, np.maximum(P[:-1], P[1:]) + margin


#: Ranges per curve whose pieces and seed samples are kept (a cut meets every piece of a face over one range).
_RANGES_KEPT = 8


def _memo(curve: Any, key: tuple, make):
    """``make()`` remembered per curve object (weakly) and ``key``, the last :data:`_RANGES_KEPT` keys.

    The callers intersect one curve over one range with many others (face splitting: a cut
    against every piece of the face); its pieces and seed samples depend on the curve and the
    range only.  Curves are frozen values, so the stored arrays stay valid (they are read-only)."""
    try:
        per = _MEMO.get(curve)
    except TypeError:  # not weak-referenceable or not hashable: no memo
        return make()
    if per is None:
        per = {}
        try:
            _MEMO[curve] = per
        except TypeError:
            return make()
    out = per.get(key)
    if out is None:
        out = make()
        for a in (out if isinstance(out, tuple) else (out,)):
            a.setflags(write=False)
        if len(per) >= _RANGES_KEPT:
            per.pop(next(iter(per)))
        per[key] = out
    return out


_MEMO: "weakref.WeakKeyDictionary[Any, dict]" = weakref.WeakKeyDictionary()


def _seed_samples(curve: Any, r: tuple[float, float]) -> tuple[np.ndarray, np.ndarray]:
    """``(ts, points)``: :data:`_SEED_SAMPLES` parameters over ``r`` and the curve's points there (remembered)."""
    def make():
        ts = np.linspace(r[0], r[1], _SEED_SAMPLES)
        return ts, _derivs(curve, ts, 0)[:, 0]
    return _memo(curve, ("seeds", r[0], r[1]), make)


def _bezier(curve: NurbsCurve, form: _PowerForm, lo: float, hi: float) -> tuple:
    """:meth:`_PowerForm.bezier` of ``curve`` over ``[lo, hi]`` (remembered)."""
    return _memo(curve, ("bezier", lo, hi), lambda: form.bezier(lo, hi))


def _nurbs_pieces(curve: NurbsCurve, lo: float, hi: float):
    """Knot spans of ``curve`` over ``[lo, hi]`` cut into about :data:`_TARGET_PIECES` pieces, each boxed by
    its Bézier control points (of the cached :class:`_PowerForm`; a refined copy's B-spline control
    points for an unclamped curve)."""
    form = _power_form(curve)
    if form is not None:
        return _memo(curve, ("pieces", lo, hi), lambda: form.pieces(lo, hi, _bezier(curve, form, lo, hi)))
    U, p = curve.knots, curve.degree
    vals = np.unique(U[p : U.size - p])
    spans = np.stack([vals[:-1], vals[1:]], axis=1)
    spans = spans[(spans[:, 1] > lo) & (spans[:, 0] < hi)]
    per = max(1, math.ceil(_TARGET_PIECES / max(1, spans.shape[0])))
    if per > 1:
        f = np.arange(1, per) / per
        new = (spans[:, :1] + f[None] * (spans[:, 1:] - spans[:, :1])).ravel()
        curve = curve.refine_knots(new)
        U = curve.knots
    P = curve.control_points
    starts = np.flatnonzero(U[:-1] < U[1:])
    starts = starts[(starts >= p) & (starts < P.shape[0])]
    a, b = U[starts], U[starts + 1]
    keep = (b > lo) & (a < hi)
    starts, a, b = starts[keep], a[keep], b[keep]
    idx = starts[:, None] - p + np.arange(p + 1)[None]  # control points acting on each span
    local = P[idx]
    return np.maximum(a, lo), np.minimum(b, hi), local.min(axis=1), local.max(axis=1)


def curve_box(curve: Any, t_range, tol: Tolerance | None = None) -> np.ndarray:
    """An axis-aligned box containing ``curve(t_range)``, ``(2, d)`` rows ``lo, hi``.

    The union of the piece boxes of step 1 of the module docstring (proven for NURBS with
    positive weights, lines, conics and ``Trig2D``).  A broad phase for callers that
    intersect many curve pairs.

    Raises
    ------
    InvalidInputError
        As :func:`intersect_curves` for one curve and range.
    """
    t_ = resolve(tol)
    _dimension(curve, "curve")
    r = _range(t_range, curve, "t_range", t_)
    if isinstance(curve, (Circle, Ellipse, Trig2D)):
        return _trig_box(curve, *r)
    _, _, lo, hi = _pieces(curve, *r)
    return np.stack([lo.min(axis=0), hi.max(axis=0)])


def curve_boxes(curves: list, lo, hi, tol: Tolerance | None = None) -> np.ndarray:
    """:func:`curve_box` of many curves at once: ``(n, 2, d)``, rows ``lo, hi`` of each curve over its range.

    Lines and arcs (circles, ellipses, ``Trig2D``) are boxed together by array formulas
    (:func:`_trig_boxes`); other curves one by one by :func:`curve_box`.  All curves must have
    dimension ``d``.

    Parameters
    ----------
    curves : list of n curves
    lo, hi : (n,) array_like, the parameter ranges (either order)

    Raises
    ------
    InvalidInputError
        As :func:`curve_box`; curves of different dimensions.
    """
    t_ = resolve(tol)
    a, b = np.asarray(lo, dtype=np.float64).reshape(-1), np.asarray(hi, dtype=np.float64).reshape(-1)
    n = len(curves)
    if a.size != n or b.size != n:
        raise InvalidInputError(f"curve_boxes needs one range per curve: {n} curves, {a.size} and {b.size} ends")
    if n == 0:
        return np.zeros((0, 2, 0))
    if not (np.all(np.isfinite(a)) and np.all(np.isfinite(b)) and np.all(a != b)):
        k = int(np.flatnonzero(~(np.isfinite(a) & np.isfinite(b) & (a != b)))[0])
        raise InvalidInputError(f"range {k} must be two finite, different numbers, got ({a[k]!r}, {b[k]!r})")
    a, b = np.minimum(a, b), np.maximum(a, b)
    # (by exact type where the type alone gives the dimension and the kind: an operand brings hundreds of edges)
    types = set(map(type, curves))
    dims = {_dimension(c, "curve") for c in curves} if not types <= _KNOWN_DIMENSION.keys() \
        else {_KNOWN_DIMENSION[kind] for kind in types}
    if len(dims) != 1:
        raise InvalidInputError(f"curve_boxes needs curves of one dimension, got {sorted(dims)}")
    d = dims.pop()
    out = np.empty((n, 2, d))
    lines, arcs, other = [], [], []
    for k, c in enumerate(curves):
        kind = lines if isinstance(c, (Line, Line2D)) else arcs if isinstance(c, (Circle, Ellipse, Trig2D)) else other
        kind.append(k)
    if lines:
        O = np.array([curves[k].origin for k in lines], dtype=np.float64)
        D = np.array([curves[k].direction for k in lines], dtype=np.float64)
        P0, P1 = O + a[lines, None] * D, O + b[lines, None] * D
        out[lines, 0], out[lines, 1] = np.minimum(P0, P1), np.maximum(P0, P1)
    if arcs:
        # Circles' forms in one pass (_trig_form's products, the same floats; the edges of a hundred tools are
        # hundreds of circles), other arcs' by _trig_form.
        cs = [curves[k] for k in arcs]
        if all(type(c) is Circle for c in cs):
            R = np.array([c.radius for c in cs], dtype=np.float64)[:, None]
            F = np.array([c._frame for c in cs], dtype=np.float64)
            C, A, B = np.array([c.center for c in cs], dtype=np.float64), R * F[:, 0], R * F[:, 1]
        else:
            forms = [_trig_form(curves[k]) for k in arcs]
            C, A, B = (np.array([f[i] for f in forms], dtype=np.float64) for i in range(3))
        out[arcs] = _trig_boxes(C, A, B, a[arcs], b[arcs])
    for k in other:
        out[k] = curve_box(curves[k], (a[k], b[k]), t_)
    return out


#: The dimension :func:`_dimension` gives a curve of each of these exact types.
_KNOWN_DIMENSION = {Line: 3, Circle: 3, Ellipse: 3, Line2D: 2, Trig2D: 2}


def _trig_box(curve: Any, lo: float, hi: float) -> np.ndarray:
    """The exact box ``(2, d)`` of one arc ``C + A cos t + B sin t``, ``t ∈ [lo, hi]``: :func:`_trig_boxes`'s
    formula on Python floats (one arc at a time from ``curve_box``, where numpy's per-call cost would be
    most of the time: about 3 µs against 20; a test compares the two)."""
    C, A, B = _trig_form(curve)
    c0, s0, c1, s1 = math.cos(lo), math.sin(lo), math.cos(hi), math.sin(hi)
    box = np.empty((2, C.size))
    for k, (ck, ak, bk) in enumerate(zip(C.tolist(), A.tolist(), B.tolist())):
        e0, e1 = ck + ak * c0 + bk * s0, ck + ak * c1 + bk * s1
        amp, peak = math.hypot(ak, bk), math.atan2(bk, ak)
        top = peak + _TWO_PI * math.ceil((lo - peak) / _TWO_PI)  # the first maximum at or after lo
        bottom = peak + math.pi + _TWO_PI * math.ceil((lo - peak - math.pi) / _TWO_PI)
        box[0, k] = ck - amp if bottom <= hi else min(e0, e1)
        box[1, k] = ck + amp if top <= hi else max(e0, e1)
    return box


def _trig_boxes(C: np.ndarray, A: np.ndarray, B: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """The exact boxes ``(n, 2, d)`` of the arcs ``C + A cos t + B sin t``, ``t ∈ [lo, hi]`` (rows ``(n, d)``).

    Coordinate ``k`` peaks at ``C_k + hypot(A_k, B_k)`` where ``t = atan2(B_k, A_k)`` (mod 2π) and
    bottoms out ``π`` later; an extremum inside the range replaces the end points' value.
    """
    lo, hi = lo[:, None], hi[:, None]
    e0 = C + A * np.cos(lo) + B * np.sin(lo)
    e1 = C + A * np.cos(hi) + B * np.sin(hi)
    amp, peak = np.hypot(A, B), np.arctan2(B, A)
    top = peak + _TWO_PI * np.ceil((lo - peak) / _TWO_PI)  # the first maximum at or after lo
    bottom = peak + math.pi + _TWO_PI * np.ceil((lo - peak - math.pi) / _TWO_PI)
    return np.stack([np.where(bottom <= hi, C - amp, np.minimum(e0, e1)),
                     np.where(top <= hi, C + amp, np.maximum(e0, e1))], axis=1)


def refine_intersections(c1: Any, range1, c2: Any, range2, t1, t2, tol: Tolerance | None = None
                         ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Newton-polish approximate intersections ``(t1, t2)`` of two curves within their ranges.

    Used to re-solve in space crossings found between p-curves in a parameter plane: the
    3-D curves are often exact (lines, circles, ellipses) where the p-curves are fits, and a
    crossing at a small angle turns a p-curve error ``e`` into ``e / sin(angle)`` along the
    curves.  Same Newton as :func:`intersect_curves` (step 3).

    Parameters
    ----------
    c1, c2 : curves with ``derivatives``; range1, range2 : (float, float)
    t1, t2 : (k,) array_like, the starting parameters

    Returns
    -------
    t1, t2 : (k,) float64, refined parameters (inside the ranges)
    dist : (k,) float64, ``|c1(t1) - c2(t2)|`` reached (the caller decides what it accepts)

    Raises
    ------
    InvalidInputError
        As :func:`intersect_curves`, or ``t1`` and ``t2`` of different sizes.
    """
    t_ = resolve(tol)
    d1, d2 = _dimension(c1, "c1"), _dimension(c2, "c2")
    if d1 != d2:
        raise InvalidInputError(f"refine_intersections needs curves of one dimension, got {d1}-D and {d2}-D")
    r1, r2 = _range(range1, c1, "range1", t_), _range(range2, c2, "range2", t_)
    s = np.asarray(t1, dtype=np.float64).ravel()
    t = np.asarray(t2, dtype=np.float64).ravel()
    if s.shape != t.shape:
        raise InvalidInputError(f"t1 and t2 must have the same size, got {s.size} and {t.size}")
    if s.size == 0:
        return s, t, np.zeros(0)
    s, t = _clamp(s, r1), _clamp(t, r2)
    if _FAST and s.size <= _SCALAR_SEEDS:
        f1, f2 = _scalar_form(c1), _scalar_form(c2)
        if f1 is not None and f2 is not None:
            out = np.array([_newton_one(f1, r1, f2, r2, a, b, t_) for a, b in zip(s.tolist(), t.tolist())])
            return out[:, 0].copy(), out[:, 1].copy(), out[:, 2].copy()
    return _newton_pairs(c1, r1, c2, r2, s, t, t_)


#: Up to this many seeds (points), :func:`refine_intersections` of lines, conics and polynomial NURBS
#: iterates each on Python floats, and :func:`_project` projects each alone.
_SCALAR_SEEDS = 4


def _scalar_form(curve: Any) -> tuple | None:
    """``("line", o, d)``, ``("trig", C, A, B)`` or, for a clamped polynomial NURBS, ``("poly", breaks, coef)``
    (:meth:`_PowerForm.scalar`: the breaks as a list of floats, the coefficients as span-indexed lists,
    :class:`_SpanLists`) for :func:`_point1`, None for other curves."""
    lin = _linear(curve)
    if lin is not None:
        return ("line", lin[0].tolist(), lin[1].tolist())
    if isinstance(curve, (Circle, Ellipse, Trig2D)):
        C, A, B = _trig_form(curve)
        return ("trig", C.tolist(), A.tolist(), B.tolist())
    if isinstance(curve, NurbsCurve):
        form = _power_form(curve)
        return None if form is None else form.scalar()
    return None


def _point1(form: tuple, t: float, order: int) -> list[list[float]]:
    """Point and derivatives up to ``order`` at one parameter, as :func:`_derivs` (lists of floats)."""
    if form[0] == "line":
        o, d = form[1], form[2]
        out = [[oi + t * di for oi, di in zip(o, d)]]
        if order:
            out.append(list(d))
        if order > 1:
            out.append([0.0] * len(d))
        return out
    if form[0] == "poly":
        # The span's polynomials in x = (t - a) / h by Horner, as _PowerForm.derivatives by power sums
        # (the span to the right at a knot; the coefficients are divided by the constant weight).
        br, coef = form[1], form[2]
        i = min(max(bisect.bisect_right(br, t) - 1, 0), len(br) - 2)
        a, h = br[i], br[i + 1] - br[i]
        x = (t - a) / h
        out = []
        for k in range(order + 1):
            rows = coef[i][k]
            acc = list(rows[-1])
            for row in rows[-2::-1]:
                acc = [v * x + c for v, c in zip(acc, row)]
            if k:
                hk = h ** k
                acc = [v / hk for v in acc]
            out.append(acc)
        return out
    C, A, B = form[1], form[2], form[3]
    c, s = math.cos(t), math.sin(t)
    # d^k/dt^k (cos t, sin t) = (c, s), (-s, c), (-c, -s) for k <= 2 (the callers' orders), each sum
    # (c_k a + s_k b), then + C for the point, in that order.
    out = [[c * a + s * b + ci for a, b, ci in zip(A, B, C)]]
    if order:
        out.append([-s * a + c * b for a, b in zip(A, B)])
    if order > 1:
        out.append([-c * a + -s * b for a, b in zip(A, B)])
    if order > 2:
        cycle = ((c, s), (-s, c), (-c, -s), (s, -c))  # period 4
        out += [[cycle[k % 4][0] * a + cycle[k % 4][1] * b for a, b in zip(A, B)] for k in range(3, order + 1)]
    return out


def _dot(a: list[float], b: list[float]) -> float:
    out = 0.0
    for x, y in zip(a, b):
        out += x * y
    return out


def _gap1(f1: tuple, s: float, f2: tuple, t: float) -> list[float]:
    return [a - b for a, b in zip(_point1(f1, s, 0)[0], _point1(f2, t, 0)[0])]


def _step1(s, t, m11, m12, m22, g1, g2, r1, r2) -> tuple[float, float]:
    """:func:`_step2` for one seed on Python floats."""
    dm = m11 * m22 - m12 * m12
    if abs(dm) > 0:
        st, tt = (m12 * g2 - m22 * g1) / dm, (m12 * g1 - m11 * g2) / dm
        if math.isfinite(st) and math.isfinite(tt):
            fix_s = (s <= r1[0] and st < 0) or (s >= r1[1] and st > 0)
            fix_t = (t <= r2[0] and tt < 0) or (t >= r2[1] and tt > 0)
            if fix_s and fix_t:
                st = tt = 0.0
            elif fix_s:
                st, tt = 0.0, (-g2 / m22 if m22 > 0 else 0.0)
            elif fix_t:
                st, tt = (-g1 / m11 if m11 > 0 else 0.0), 0.0
            s, t = s + st, t + tt
    return min(max(s, r1[0]), r1[1]), min(max(t, r2[0]), r2[1])


def _newton_one(f1: tuple, r1, f2: tuple, r2, s: float, t: float, t_: Tolerance) -> tuple[float, float, float]:
    """:func:`_newton_pairs` for one seed of two lines, conics or polynomial NURBS (:func:`_scalar_form`) on
    Python floats (same steps and stops):
    numpy's per-call cost on one-row arrays is most of the array version's time for a few seeds."""
    best, stalled = math.inf, 0
    tiny = np.finfo(float).tiny
    g = None
    for _ in range(_NEWTON_ITERATIONS):
        A, B = _point1(f1, s, 2), _point1(f2, t, 2)
        r = [a - b for a, b in zip(A[0], B[0])]
        dist = math.sqrt(_dot(r, r))
        stalled = 0 if dist < best else stalled + 1
        best = min(best, dist)
        j11, j12, j22 = _dot(A[1], A[1]), -_dot(A[1], B[1]), _dot(B[1], B[1])
        g1, g2 = _dot(A[1], r), -_dot(B[1], r)
        h11, h22 = j11 + _dot(r, A[2]), j22 - _dot(r, B[2])
        det = h11 * h22 - j12 * j12
        pd = det > t_.solver * (abs(h11 * h22) + j12 * j12) and h11 > 0
        lam = t_.solver * (j11 + j22) + tiny
        s_new, t_new = _step1(s, t, h11 if pd else j11 + lam, j12, h22 if pd else j22 + lam, g1, g2, r1, r2)
        g = None  # the gap at (s_new, t_new) where it is known
        if pd and j11 * j22 - j12 * j12 > _TRANSVERSAL * j11 * j22:
            sg, tg = _step1(s, t, j11, j12, j22, g1, g2, r1, r2)
            rh, rg = _gap1(f1, s_new, f2, t_new), _gap1(f1, sg, f2, tg)
            g = rh
            if _dot(rg, rg) < _dot(rh, rh):
                s_new, t_new, g = sg, tg, rg
        moved = abs(s_new - s) + abs(t_new - t)
        s, t = s_new, t_new
        if moved <= t_.solver * (1.0 + abs(s_new) + abs(t_new)) or stalled >= _STALL:
            break
    if g is None:
        g = _gap1(f1, s, f2, t)
    return s, t, math.sqrt(_dot(g, g))


# ====================================================================== Newton
def _clamp(x: np.ndarray, r: tuple[float, float]) -> np.ndarray:
    """``x`` clipped to ``[r0, r1]`` (``np.clip``'s dispatch costs more than this on small arrays)."""
    return np.minimum(np.maximum(x, r[0]), r[1])


def _newton_pairs(c1, r1, c2, r2, s, t, t_: Tolerance):
    """Newton on ``f(s, t) = |c1(s) - c2(t)|² / 2``, kept in the ranges (projected steps, :func:`_step2`).

    The full Hessian ``JᵀJ + diag(r·c1'', -r·c2'')`` is used where it is positive definite —
    quadratic convergence at crossings, at closest approaches and at tangential touchings (where
    ``JᵀJ`` alone is singular) — and Gauss–Newton with Levenberg damping elsewhere (The NURBS
    Book §6.1, generalised to two curves).  Where the tangents also make an angle (sin² above
    :data:`_TRANSVERSAL`) the Gauss–Newton step is tried too and the closer of the two points
    kept: from a far seed the Hessian's ``r·c''`` terms can overshoot a crossing.

    Returns
    -------
    s, t : (k,) parameters reached; dist : (k,) ``|c1(s) - c2(t)|``
    """
    s, t = s.astype(np.float64).copy(), t.astype(np.float64).copy()
    best = np.full(s.size, np.inf)
    stalled = np.zeros(s.size, dtype=np.int64)
    act = np.arange(s.size)
    tiny = np.finfo(float).tiny
    for _ in range(_NEWTON_ITERATIONS):
        if act.size == 0:
            break
        sa, ta = s[act], t[act]
        A, B = _derivs(c1, sa, 2), _derivs(c2, ta, 2)
        r = A[:, 0] - B[:, 0]
        dist = np.sqrt(np.einsum("kd,kd->k", r, r))
        # A seed that has not come closer for a few steps sits at a positive local minimum of
        # the distance (often on a range end): it is no intersection, stop iterating it.
        better = dist < best[act]
        best[act] = np.minimum(best[act], dist)
        stalled[act] = np.where(better, 0, stalled[act] + 1)
        # J = [c1', -c2'] (d, 2); JᵀJ and g = Jᵀr entry by entry (2x2 per seed).
        j11 = np.einsum("kd,kd->k", A[:, 1], A[:, 1])
        j12 = -np.einsum("kd,kd->k", A[:, 1], B[:, 1])
        j22 = np.einsum("kd,kd->k", B[:, 1], B[:, 1])
        g1 = np.einsum("kd,kd->k", A[:, 1], r)
        g2 = -np.einsum("kd,kd->k", B[:, 1], r)
        h11 = j11 + np.einsum("kd,kd->k", r, A[:, 2])
        h22 = j22 - np.einsum("kd,kd->k", r, B[:, 2])
        det = h11 * h22 - j12 * j12
        # Definite and not singular to round-off (coincident curves give a singular Hessian).
        scale = np.abs(h11 * h22) + j12 * j12
        pd = (det > t_.solver * scale) & (h11 > 0)
        # Damping proportional to the scale of JᵀJ keeps parallel tangents solvable.
        lam = t_.solver * (j11 + j22) + tiny
        s_new, t_new = _step2(sa, ta, np.where(pd, h11, j11 + lam), j12, np.where(pd, h22, j22 + lam), g1, g2, r1, r2)
        # Where the tangents make an angle, the Gauss–Newton step (Newton on c1(s) = c2(t)) is
        # quadratic at a crossing and unaffected by the r·c'' terms, which can throw a far seed
        # (|r| large) out of the range; at a positive minimum (curves that miss) the full
        # Hessian is the right model.  Both are tried where they differ; the closer point wins.
        two = pd & (j11 * j22 - j12 * j12 > _TRANSVERSAL * j11 * j22)
        if np.any(two):
            k = np.flatnonzero(two)
            sg, tg = _step2(sa[k], ta[k], j11[k], j12[k], j22[k], g1[k], g2[k], r1, r2)
            # Both trial points of each curve in one evaluation (pointwise: the same values as two).
            P1 = _derivs(c1, np.concatenate([s_new[k], sg]), 0)[:, 0]
            P2 = _derivs(c2, np.concatenate([t_new[k], tg]), 0)[:, 0]
            rh, rg = P1[: k.size] - P2[: k.size], P1[k.size :] - P2[k.size :]
            use = np.einsum("kd,kd->k", rg, rg) < np.einsum("kd,kd->k", rh, rh)
            s_new[k[use]], t_new[k[use]] = sg[use], tg[use]
        moved = np.abs(s_new - sa) + np.abs(t_new - ta)
        s[act], t[act] = s_new, t_new
        done = (moved <= t_.solver * (1.0 + np.abs(s_new) + np.abs(t_new))) | (stalled[act] >= _STALL)
        act = act[~done]
    d = np.linalg.norm(_derivs(c1, s, 0)[:, 0] - _derivs(c2, t, 0)[:, 0], axis=1)
    return s, t, d


def _step2(s, t, m11, m12, m22, g1, g2, r1, r2):
    """The step ``-M⁻¹ g`` of the symmetric 2x2 systems ``M = [[m11, m12], [m12, m22]]`` from ``(s, t)``,
    projected on the ranges; a singular or non-finite system takes no step.

    Projected Newton with an active set (Bertsekas 1982): a parameter on a range end that the
    step would push out stays there and the other takes the step of the one-variable problem
    (``-g2 / m22`` or ``-g1 / m11``).  Clipping the joint step instead moves the free parameter
    by the wrong amount, and seeds converging to a range end (cuts meeting at their end points)
    then crawl there linearly.
    """
    dm = m11 * m22 - m12 * m12
    ok = np.abs(dm) > 0
    dm = np.where(ok, dm, 1.0)
    st = (m12 * g2 - m22 * g1) / dm
    tt = (m12 * g1 - m11 * g2) / dm
    ok &= np.isfinite(st) & np.isfinite(tt)
    st, tt = np.where(ok, st, 0.0), np.where(ok, tt, 0.0)
    fix_s = ((s <= r1[0]) & (st < 0)) | ((s >= r1[1]) & (st > 0))
    fix_t = ((t <= r2[0]) & (tt < 0)) | ((t >= r2[1]) & (tt > 0))
    if np.any(fix_s | fix_t):
        only_s, only_t = fix_s & ~fix_t, fix_t & ~fix_s
        tt = np.where(only_s, np.where(m22 > 0, -g2 / np.where(m22 > 0, m22, 1.0), 0.0), tt)
        st = np.where(only_t, np.where(m11 > 0, -g1 / np.where(m11 > 0, m11, 1.0), 0.0), st)
        st = np.where(fix_s, 0.0, st)
        tt = np.where(fix_t, 0.0, tt)
    return _clamp(s + st, r1), _clamp(t + tt, r2)


def _circle_frame(curve: Any, t_: Tolerance) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
    """``(C, A, B)`` with ``curve(t) = C + A cos t + B sin t``, ``A ⊥ B``, ``|A| = |B|``, for a circle, else None.

    A :class:`Circle` always; a :class:`Trig2D` whose axes are orthogonal and of equal length to
    ``tol.solver`` relative (then the closed-form foot below is off by at most that, relative to
    the radius, far below ``tol.linear``).
    """
    if isinstance(curve, Circle):
        return _trig_form(curve)
    if isinstance(curve, Trig2D):
        A, B = curve.a, curve.b
        aa, bb = float(A @ A), float(B @ B)
        if abs(float(A @ B)) <= t_.solver * math.sqrt(aa * bb) and abs(aa - bb) <= t_.solver * max(aa, bb):
            return curve.center, A, B
    return None


def _project(curve, r, X: np.ndarray, t_: Tolerance, near: float | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Closest parameters on ``curve(r)`` of the points ``X`` (k, d) and the distances (k,).

    Lines and circles in closed form: the foot on the line clipped to the range; the polar angle
    about a circle's centre, taken in the range or replaced by the nearer range end.  Other
    curves: seeded at the nearest of :data:`_SEED_SAMPLES` samples, then Newton on
    ``(C - X)·C' = 0`` clipped to the range (The NURBS Book §6.1); up to :data:`_SCALAR_SEEDS` points
    (the range ends of :func:`_end_feet`, the midpoint probes of the overlap tests) on Python floats,
    each alone (:func:`_project_one`).

    ``near``: the caller only compares the distances with it.  A point of a clamped NURBS's
    projection outside every piece box (step 1) enlarged by ``near`` is then farther than ``near``
    from the curve: it gets the distance ``inf`` (and the parameter ``r[0]``) without Newton.
    """
    lin = _linear(curve)
    if lin is not None:
        o, d = lin
        t = np.clip(((X - o) @ d) / float(d @ d), *r)
        return t, np.linalg.norm(o + t[:, None] * d - X, axis=1)
    circle = _circle_frame(curve, t_)
    if circle is not None:
        C, A, B = circle
        W = X - C
        base = np.arctan2(W @ B, W @ A)  # the foot on the whole circle (any angle on the centre)
        inner = base + _TWO_PI * np.ceil((r[0] - base) / _TWO_PI)
        inner = np.clip(np.where(inner <= r[1], inner, r[0]), *r)
        cand = np.stack([inner, np.full_like(inner, r[0]), np.full_like(inner, r[1])], axis=1)  # (k, 3)
        dist = np.linalg.norm(_derivs(curve, cand.ravel(), 0)[:, 0].reshape(cand.shape + (-1,)) - X[:, None], axis=2)
        pick = np.argmin(dist, axis=1)
        rows = np.arange(X.shape[0])
        return cand[rows, pick], dist[rows, pick]
    if near is not None and isinstance(curve, NurbsCurve) and _power_form(curve) is not None:
        _, _, lo, hi = _nurbs_pieces(curve, *r)
        inside = np.any(np.all((X[:, None] >= lo[None] - near) & (X[:, None] <= hi[None] + near), axis=2), axis=1)
        if not np.all(inside):
            t = np.full(X.shape[0], r[0])
            dist = np.full(X.shape[0], np.inf)
            k = np.flatnonzero(inside)
            if k.size:
                t[k], dist[k] = _project(curve, r, X[k], t_)
            return t, dist
    ts, S = _seed_samples(curve, r)
    d2 = ((X[:, None, :] - S[None]) ** 2).sum(axis=2)
    t = ts[np.argmin(d2, axis=1)]
    form = _scalar_form(curve) if _FAST and X.shape[0] <= _SCALAR_SEEDS else None
    if form is not None:  # a few points (range ends): each on Python floats, as refine_intersections
        out = np.array([_project_one(form, r, x, t0, t_) for x, t0 in zip(X.tolist(), t.tolist())]).reshape(-1, 2)
        return out[:, 0].copy(), out[:, 1].copy()
    for _ in range(_NEWTON_ITERATIONS):
        D = _derivs(curve, t, 2)
        diff = D[:, 0] - X
        f = (diff * D[:, 1]).sum(axis=1)
        df = (D[:, 1] * D[:, 1]).sum(axis=1) + (diff * D[:, 2]).sum(axis=1)
        ok = df > 0
        step = np.where(ok, -f / np.where(ok, df, 1.0), 0.0)
        t_new = _clamp(t + step, r)
        done = np.abs(t_new - t) <= t_.solver * (1.0 + np.abs(t))
        t = t_new
        if np.all(done):
            break
    dist = np.linalg.norm(_derivs(curve, t, 0)[:, 0] - X, axis=1)
    return t, dist


def _project_one(form: tuple, r, x: list[float], t: float, t_: Tolerance) -> tuple[float, float]:
    """The Newton of :func:`_project` for one point ``x`` from the seed ``t`` on Python floats (the same steps; the
    array version stops when every point's step is small, this one when its own is): ``(t, distance)``."""
    for _ in range(_NEWTON_ITERATIONS):
        D = _point1(form, t, 2)
        diff = [a - b for a, b in zip(D[0], x)]
        f = _dot(diff, D[1])
        df = _dot(D[1], D[1]) + _dot(diff, D[2])
        t_new = min(max(t + (-f / df if df > 0 else 0.0), r[0]), r[1])
        done = abs(t_new - t) <= t_.solver * (1.0 + abs(t))
        t = t_new
        if done:
            break
    g = [a - b for a, b in zip(_point1(form, t, 0)[0], x)]
    return t, math.sqrt(_dot(g, g))


# ====================================================================== public
def intersect_curves(c1: Any, range1, c2: Any, range2, tol: Tolerance | None = None) -> CurveIntersections:
    """Isolated intersections and overlaps of ``c1(range1)`` and ``c2(range2)`` (see the module docstring).

    Parameters
    ----------
    c1, c2 : curves of the same dimension (2 or 3) with ``derivatives(t, order)``
    range1, range2 : (float, float)
        Parameter ranges, either order; NURBS ranges must lie in the domain.
    tol : Tolerance, optional
        Points closer than ``tol.linear`` (in the curves' space) are one point.

    Returns
    -------
    CurveIntersections

    Raises
    ------
    InvalidInputError
        A curve without ``derivatives``, curves of different dimensions, a malformed range
        or a NURBS range outside the domain.

    Examples
    --------
    >>> x = intersect_curves(Line2D([0, 0], [1, 1]), (0, 2), Line2D([0, 1], [1, -1]), (0, 2))
    >>> x.points.round(12).tolist(), x.t1.round(12).tolist(), x.overlaps
    ([[0.5, 0.5]], [0.5], ())
    """
    t_ = resolve(tol)
    d1, d2 = _dimension(c1, "c1"), _dimension(c2, "c2")
    if d1 != d2:
        raise InvalidInputError(f"intersect_curves needs curves of one dimension, got {d1}-D and {d2}-D")
    r1, r2 = _range(range1, c1, "range1", t_), _range(range2, c2, "range2", t_)
    if _FAST and isinstance(c1, Line2D) and isinstance(c2, Line2D):
        fast = _lines_2d(c1, r1, c2, r2, t_)
        if fast is not None:
            return fast
    eps = t_.linear
    exact = _exact(c1, r1, c2, r2, t_)
    feet = _end_feet(c1, r1, c2, r2, t_)
    if exact is not None:
        return _with_end_contacts(exact, c1, r1, c2, r2, t_, feet)

    line_pair = _nurbs_line(c1, r1, c2, r2, t_) if _FAST else None
    if line_pair is not None:
        s, t, dist = line_pair
    else:
        # 1-2. Pieces, boxes and candidate pairs.
        a1, b1, lo1, hi1 = _pieces(c1, *r1)
        a2, b2, lo2, hi2 = _pieces(c2, *r2)
        hit = np.all((lo1[:, None] <= hi2[None] + eps) & (lo2[None] <= hi1[:, None] + eps), axis=2)
        i, j = np.nonzero(hit)
        seeds_s = [0.5 * (a1[i] + b1[i])]
        seeds_t = [0.5 * (a2[j] + b2[j])]
        # End points against the other curve: cuts ending on an edge converge from here.
        ends1, ends2 = np.array(r1), np.array(r2)
        t_of_1, _, s_of_2, _ = feet
        seeds_s += [ends1, s_of_2]
        seeds_t += [t_of_1, ends2]

        # 3. Newton on every seed.
        s, t, dist = _newton_pairs(c1, r1, c2, r2, np.concatenate(seeds_s), np.concatenate(seeds_t), t_)
    good = dist <= eps
    s, t, dist = s[good], t[good], dist[good]

    # 4. Overlaps, then de-duplication of the isolated solutions.
    overlaps = _overlaps(c1, r1, c2, r2, t_, eps, feet)
    if overlaps and s.size:
        keep = np.ones(s.size, dtype=bool)
        speed = np.linalg.norm(_derivs(c1, s, 1)[:, 1], axis=1)
        slack = eps / np.maximum(speed, np.finfo(float).tiny)
        for (s0, s1), _ in overlaps:
            keep &= ~((s >= s0 - slack) & (s <= s1 + slack))
        s, t, dist = s[keep], t[keep], dist[keep]
    s, t = _deduplicate(c1, r1, c2, r2, s, t, dist, eps, t_)
    # Projected Newton can stall at a range end whose point is within eps of the other curve
    # while the unconstrained solution lies outside the range: add those contacts directly.
    return _with_end_contacts(_result(c1, c2, s, t), c1, r1, c2, r2, t_, feet, tuple(overlaps))


# ====================================================================== closed forms
#: Scalar fast paths on (tests switch them off to compare with the general path).
_FAST = True


def _lines_2d(c1: Line2D, r1, c2: Line2D, r2, t_: Tolerance) -> CurveIntersections | None:
    """:func:`intersect_curves` of two crossing 2-D lines in scalar arithmetic, None for parallel lines.

    The same steps as the general path for a pair of lines — the closed-form crossing of
    :func:`_exact`, the feet of the range ends (:func:`_end_feet`) and their merging with the
    crossing (:func:`_with_end_contacts`) — on Python floats: face splitting intersects many
    short segments, and numpy's per-call cost on two-element arrays is most of the general
    path's time.  The answers agree with it to round-off (sums of two products may be fused
    differently); tests compare the two.
    """
    eps = t_.linear
    (ox1, oy1), (dx1, dy1) = c1.origin.tolist(), c1.direction.tolist()
    (ox2, oy2), (dx2, dy2) = c2.origin.tolist(), c2.direction.tolist()
    q1, q2 = dx1 * dx1 + dy1 * dy1, dx2 * dx2 + dy2 * dy2
    n1, n2 = math.sqrt(q1), math.sqrt(q2)
    cr = dx1 * dy2 - dy1 * dx2
    sin2 = cr * cr
    if sin2 <= (t_.angular * n1 * n2) ** 2:
        return None  # parallel to the angular tolerance: the general path reports overlaps
    a0, a1 = r1
    b0, b1 = r2
    # The crossing (_exact): closest points of the lines, Cramer with det = |d1 × d2|².
    wx, wy = ox2 - ox1, oy2 - oy1
    a12 = dx1 * dx2 + dy1 * dy2
    w1, w2 = wx * dx1 + wy * dy1, wx * dx2 + wy * dy2
    s = (w1 * n2 * n2 - w2 * a12) / sin2
    t = (w1 * a12 - w2 * n1 * n1) / sin2
    ok = a0 - eps / n1 <= s <= a1 + eps / n1 and b0 - eps / n2 <= t <= b1 + eps / n2
    s, t = min(max(s, a0), a1), min(max(t, b0), b1)
    cands = []  # (s, t, kind): kind 1 an end of c1, 2 an end of c2, 0 the crossing
    ex, ey = ox1 + s * dx1 - ox2 - t * dx2, oy1 + s * dy1 - oy2 - t * dy2
    if ok and math.sqrt(ex * ex + ey * ey) <= eps:
        crossing = [(s, t)]
    else:
        crossing = []

    def foot(x, y, ox, oy, dx, dy, q, lo, hi):
        u = min(max(((x - ox) * dx + (y - oy) * dy) / q, lo), hi)
        fx, fy = ox + u * dx - x, oy + u * dy - y
        return u, math.sqrt(fx * fx + fy * fy)

    # Range ends within eps of the other line (_end_feet, _with_end_contacts), c1's ends first.
    for e in (a0, a1):
        u, d = foot(ox1 + e * dx1, oy1 + e * dy1, ox2, oy2, dx2, dy2, q2, b0, b1)
        if d <= eps:
            cands.append((e, u, 1))
    for e in (b0, b1):
        u, d = foot(ox2 + e * dx2, oy2 + e * dy2, ox1, oy1, dx1, dy1, q1, a0, a1)
        if d <= eps:
            cands.append((u, e, 2))
    if cands:
        cands += [(s_, t_2, 0) for s_, t_2 in crossing]
        n = len(cands)
        label = list(range(n))
        for i in range(n):
            for j in range(i + 1, n):
                si, ti, _ = cands[i]
                sj, tj, _ = cands[j]
                gx, gy = (ox1 + si * dx1) - (ox1 + sj * dx1), (oy1 + si * dy1) - (oy1 + sj * dy1)
                same = math.sqrt(gx * gx + gy * gy) <= eps
                if not same:  # joined by a stretch within eps of both lines
                    sm, tm = 0.5 * (si + sj), 0.5 * (ti + tj)
                    same = (foot(ox1 + sm * dx1, oy1 + sm * dy1, ox2, oy2, dx2, dy2, q2, b0, b1)[1] <= eps
                            and foot(ox2 + tm * dx2, oy2 + tm * dy2, ox1, oy1, dx1, dy1, q1, a0, a1)[1] <= eps)
                if same:
                    lo_, hi_ = min(label[i], label[j]), max(label[i], label[j])
                    label = [lo_ if g == hi_ else g for g in label]
        pairs = []
        for g in sorted(set(label)):
            m = [k for k in range(n) if label[k] == g]
            k1 = [k for k in m if cands[k][2] == 1]
            k2 = [k for k in m if cands[k][2] == 2]
            pairs.append((cands[k1[0] if k1 else m[0]][0], cands[k2[0] if k2 else m[0]][1]))
    else:
        pairs = crossing
    pairs.sort(key=lambda st: st[0])  # stable, as _result's argsort
    S = np.array([st[0] for st in pairs], dtype=np.float64)
    T = np.array([st[1] for st in pairs], dtype=np.float64)
    P = np.array([[0.5 * ((ox1 + a * dx1) + (ox2 + b * dx2)), 0.5 * ((oy1 + a * dy1) + (oy2 + b * dy2))]
                  for a, b in pairs], dtype=np.float64).reshape(-1, 2)
    return CurveIntersections(S, T, P, ())


def _nurbs_line(c1, r1, c2, r2, t_: Tolerance) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
    """Steps 1-3 for a polynomial 2-D NURBS against a 2-D line (either order): ``(s, t, dist)`` of the
    solutions, as :func:`_newton_pairs` returns them, or None for other pairs.

    Along the line's unit normal ``n`` the signed distance ``f(t) = n·(C(t) - o)`` of the curve is a
    polynomial on each knot span, and on each piece of :meth:`_PowerForm.bezier` its Bézier
    coefficients are ``n·(P_i - o)`` (the foot's parameter along the line likewise): a piece whose
    coefficients keep off ``[-eps, eps]``, or whose feet all keep off the line's range, meets no
    point of the segment within ``eps`` (convex hull property).  On the remaining pieces, Newton on
    ``f² / 2`` in one variable (full second derivative where positive: crossings and tangential
    touchings alike; the Newton step on ``f`` tried too, the smaller ``|f|`` kept, as in
    :func:`_newton_pairs`), on the span's power coefficients, all pieces at once and kept in their
    piece (a root in a neighbour is that neighbour's).  Each piece is seeded at its middle and at the
    real parts of the roots of ``f`` and ``f'`` inside it (:func:`_root_seeds`).  The solutions' distance is then measured between the curves (the
    foot clipped to the line's range), so the steps after this one see what the general path gives.
    """
    swap = isinstance(c1, Line2D)
    curve, rc, line, rl = (c2, r2, c1, r1) if swap else (c1, r1, c2, r2)
    if not (isinstance(line, Line2D) and isinstance(curve, NurbsCurve) and curve.dimension == 2):
        return None
    form = _power_form(curve)
    if form is None or form.rational:
        return None
    eps = t_.linear
    lo, hi = rc
    span, xa, xb, a, b, P = _bezier(curve, form, lo, hi)
    (ox, oy), (dx, dy) = line.origin.tolist(), line.direction.tolist()
    q = dx * dx + dy * dy
    nd = math.sqrt(q)
    nx, ny = -dy / nd, dx / nd
    F = (P[..., 0] - ox) * nx + (P[..., 1] - oy) * ny  # (m, p + 1) Bézier coefficients of f
    G = ((P[..., 0] - ox) * dx + (P[..., 1] - oy) * dy) / q  # and of the foot's parameter on the line
    reach = eps / nd
    # The pieces' boxes against the segment's (as the general path pairs pieces) prune what the
    # line's own frame leaves, where the segment is short across the curve.
    _, _, box_lo, box_hi = _nurbs_pieces(curve, lo, hi)
    ends = np.array([[ox + rl[0] * dx, oy + rl[0] * dy], [ox + rl[1] * dx, oy + rl[1] * dy]])
    seg_lo, seg_hi = ends.min(axis=0) - eps, ends.max(axis=0) + eps
    cand = np.flatnonzero((F.min(axis=1) <= eps) & (F.max(axis=1) >= -eps)
                          & (G.min(axis=1) <= rl[1] + reach) & (G.max(axis=1) >= rl[0] - reach)
                          & np.all((box_lo <= seg_hi) & (box_hi >= seg_lo), axis=1))
    if cand.size == 0:
        return np.zeros(0), np.zeros(0), np.zeros(0)
    # f(x) on each candidate's span: power coefficients of n·(A - o w) / w with the constant weight w.
    C = form.coef[span[cand]]  # (k, p + 1, 3)
    fc = (C[..., 0] * nx + C[..., 1] * ny - (ox * nx + oy * ny) * C[..., 2]) / C[:, :1, 2]
    p = form.p
    pw = np.arange(p + 1)
    # Seeds: the piece's middle, and the real parts of the roots of f and of f' in the piece (two
    # crossings in one piece, or the extremum of a touching or near-touching).
    row_f, x_f = _root_seeds(fc, xa[cand], xb[cand])
    row_d, x_d = _root_seeds(fc[:, 1:] * pw[1:], xa[cand], xb[cand])
    rows = np.concatenate([np.arange(cand.size), row_f, row_d])
    k = cand[rows]
    c0 = fc[rows]
    lo_x, hi_x = xa[k], xb[k]
    x = np.concatenate([0.5 * (xa[cand] + xb[cand]), x_f, x_d])
    c1_ = c0[:, 1:] * pw[1:]  # f'
    c2_ = c1_[:, 1:] * pw[1:p]  # f''

    def f_at(idx, xx):
        return np.einsum("kj,kj->k", c0[idx], xx[:, None] ** pw)

    act = np.arange(k.size)
    best = np.full(k.size, np.inf)
    stalled = np.zeros(k.size, dtype=np.int64)
    for _ in range(_NEWTON_ITERATIONS):
        if act.size == 0:
            break
        xs = x[act]
        X = xs[:, None] ** pw
        f = np.einsum("kj,kj->k", c0[act], X)
        f1 = np.einsum("kj,kj->k", c1_[act], X[:, :p])
        f2 = np.einsum("kj,kj->k", c2_[act], X[:, : p - 1]) if p > 1 else np.zeros(act.size)
        af = np.abs(f)
        better = af < best[act]
        best[act] = np.minimum(best[act], af)
        stalled[act] = np.where(better, 0, stalled[act] + 1)
        h = f1 * f1 + f * f2
        pd = h > 0
        step = np.where(pd, -f * f1 / np.where(pd, h, 1.0), 0.0)
        lo_a, hi_a = lo_x[act], hi_x[act]
        x_new = np.minimum(np.maximum(xs + step, lo_a), hi_a)
        gn = f1 != 0
        if np.any(gn):
            g = np.flatnonzero(gn)
            xg = np.minimum(np.maximum(xs[g] - f[g] / f1[g], lo_a[g]), hi_a[g])
            use = np.abs(f_at(act[g], xg)) < np.abs(f_at(act[g], x_new[g]))
            x_new[g[use]] = xg[use]
        moved = np.abs(x_new - xs)
        x[act] = x_new
        done = (moved <= t_.solver * (1.0 + np.abs(x_new))) | (stalled[act] >= _STALL)
        act = act[~done]
    br = form.breaks
    h_span = br[span[k] + 1] - br[span[k]]
    tc = np.minimum(np.maximum(br[span[k]] + x * h_span, lo), hi)
    Pc = form.derivatives(tc, 0)[:, 0]
    sl = np.minimum(np.maximum(((Pc[:, 0] - ox) * dx + (Pc[:, 1] - oy) * dy) / q, rl[0]), rl[1])
    dist = np.hypot(Pc[:, 0] - (ox + sl * dx), Pc[:, 1] - (oy + sl * dy))
    return (sl, tc, dist) if swap else (tc, sl, dist)


def _root_seeds(coef: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Real parts lying in ``[lo, hi]`` of the roots of the polynomials ``Σ_m coef[:, m] x^m`` (k, q + 1), as
    ``(row, x)``: eigenvalues of the companion matrices, all rows in one call.

    Seeds only (Newton polishes them), so a row whose leading coefficient is below ``1e-12`` of its
    largest (a lower-degree polynomial, where the companion matrix would overflow) gives none.
    """
    q = coef.shape[1] - 1
    if q < 1 or coef.shape[0] == 0:
        return np.zeros(0, dtype=np.int64), np.zeros(0)
    lead = coef[:, q]
    ok = np.flatnonzero(np.abs(lead) > 1e-12 * np.abs(coef).max(axis=1))
    if ok.size == 0:
        return np.zeros(0, dtype=np.int64), np.zeros(0)
    M = np.zeros((ok.size, q, q))
    M[:, np.arange(1, q), np.arange(q - 1)] = 1.0
    M[:, :, q - 1] = -coef[ok, :q] / lead[ok, None]
    x = np.linalg.eigvals(M).real  # (ok, q)
    inside = (x >= lo[ok, None]) & (x <= hi[ok, None])
    r, j = np.nonzero(inside)
    return ok[r], x[r, j]


def _linear(c: Any) -> tuple[np.ndarray, np.ndarray] | None:
    """``(origin, direction)`` of a straight curve ``O + t D``, else None."""
    if isinstance(c, Line2D):
        return c.origin, c.direction
    if isinstance(c, Line):
        return c.origin, c.direction
    return None


def _result(c1, c2, s: np.ndarray, t: np.ndarray) -> CurveIntersections:
    order = np.argsort(s, kind="stable")
    s, t = s[order], t[order]
    d = _dimension(c1, "c1")
    P = 0.5 * (_derivs(c1, s, 0)[:, 0] + _derivs(c2, t, 0)[:, 0]) if s.size else np.zeros((0, d))
    return CurveIntersections(s, t, P.reshape(-1, d), ())


def _in_range(x: np.ndarray, r: tuple[float, float], slack: np.ndarray | float) -> np.ndarray:
    return (x >= r[0] - slack) & (x <= r[1] + slack)


def _exact(c1, r1, c2, r2, t_: Tolerance) -> CurveIntersections | None:
    """Closed forms: crossing lines (Cramer / least squares), a 2-D line against a ``Trig2D``, two 2-D circles.

    Returns None when no closed form applies (parallel lines go to the general path, which
    reports their overlaps).  Parameters within ``tol.linear`` of a range end (in length) are
    snapped to it; points farther than ``tol.linear`` apart are no intersection.
    """
    eps = t_.linear
    L1, L2 = _linear(c1), _linear(c2)
    if L1 is not None and L2 is not None:
        (o1, d1), (o2, d2) = L1, L2
        n1, n2 = float(np.linalg.norm(d1)), float(np.linalg.norm(d2))
        # |d1 × d2| is accurate to round-off where a determinant of dot products is not.
        cr = d1[0] * d2[1] - d1[1] * d2[0] if d1.size == 2 else np.cross(d1, d2)
        sin2 = float(np.sum(np.square(cr)))
        if sin2 <= (t_.angular * n1 * n2) ** 2:
            return None  # parallel to the angular tolerance
        # Closest points of the two lines (least squares; Cramer with det = |d1 × d2|²).
        w = o2 - o1
        a12 = float(d1 @ d2)
        s = (float(w @ d1) * n2 * n2 - float(w @ d2) * a12) / sin2
        t = (float(w @ d1) * a12 - float(w @ d2) * n1 * n1) / sin2
        ok = _in_range(np.array([s]), r1, eps / n1)[0] and _in_range(np.array([t]), r2, eps / n2)[0]
        s, t = float(np.clip(s, *r1)), float(np.clip(t, *r2))
        if not ok or np.linalg.norm(o1 + s * d1 - o2 - t * d2) > eps:
            return _result(c1, c2, np.zeros(0), np.zeros(0))
        return _result(c1, c2, np.array([s]), np.array([t]))
    if L1 is not None and isinstance(c2, Trig2D) and isinstance(c1, Line2D):
        return _line_trig(c1, r1, c2, r2, t_, swap=False)
    if L2 is not None and isinstance(c1, Trig2D) and isinstance(c2, Line2D):
        return _line_trig(c2, r2, c1, r1, t_, swap=True)
    if isinstance(c1, Trig2D) and isinstance(c2, Trig2D):
        f1, f2 = _circle_frame(c1, t_), _circle_frame(c2, t_)
        if f1 is not None and f2 is not None:
            return _circle_circle(c1, r1, f1, c2, r2, f2, t_)
    return None


def _circle_circle(c1: Trig2D, r1, f1: tuple, c2: Trig2D, r2, f2: tuple, t_: Tolerance) -> CurveIntersections | None:
    """Two 2-D circles (:func:`_circle_frame`): their crossings from the radical line, or their touching point.

    With centres ``C1, C2`` at distance ``d`` along ``u`` and radii ``ρ1, ρ2``, the crossings lie at
    ``C1 + a u ± h v`` (``a = (ρ1² - ρ2² + d²) / 2d``, ``h² = ρ1² - a²``).  Circles within ``tol.linear`` of
    touching (``d`` within it of ``ρ1 + ρ2`` or of ``|ρ1 - ρ2|``) stay within it of each other between their
    two crossings: they touch once, at ``C1 ± ρ1 u``, exactly where tangent circles meet (Newton on the
    squared distance stops about ``sqrt(eps / Δκ)`` along them from it: a node of a face split 1e-6 away
    from the vertex the other faces have).  Concentric circles of one radius: None (the general path
    reports the overlap).  As :func:`_line_trig`: every representative of a parameter within its range
    (and within ``tol.linear`` of it, snapped), points farther apart than ``tol.linear`` dropped.
    """
    eps = t_.linear
    (C1, A1, B1), (C2, A2, B2) = f1, f2
    rho1, rho2 = math.sqrt(float(A1 @ A1)), math.sqrt(float(A2 @ A2))
    w = np.asarray(C2, dtype=np.float64) - C1
    d = math.hypot(float(w[0]), float(w[1]))
    if d <= eps:
        if abs(rho1 - rho2) <= eps:
            return None
        return _result(c1, c2, np.zeros(0), np.zeros(0))
    u = w / d
    if abs(d - (rho1 + rho2)) <= eps or abs(d - abs(rho1 - rho2)) <= eps:
        # (externally, or internally with circle 1 the larger: towards C2; internally the smaller: away)
        sign = -1.0 if abs(d - (rho1 + rho2)) > eps and rho1 < rho2 else 1.0
        P = (C1 + sign * rho1 * u)[None]
    elif d > rho1 + rho2 or d < abs(rho1 - rho2):
        return _result(c1, c2, np.zeros(0), np.zeros(0))
    else:
        a = (rho1 * rho1 - rho2 * rho2 + d * d) / (2.0 * d)
        h = math.sqrt(max(rho1 * rho1 - a * a, 0.0))
        v = np.array([-u[1], u[0]])
        P = np.stack([C1 + a * u + h * v, C1 + a * u - h * v])

    def angles(C, A, B, r):
        # every representative of each point's angle about C inside the range (a range may exceed one period)
        X = P - C
        base = np.arctan2(X @ B, X @ A)
        k0 = np.floor((r[0] - base) / (2 * math.pi))
        return base[:, None] + 2 * math.pi * (k0[:, None] + np.arange(3))

    t1, t2 = angles(C1, A1, B1, r1), angles(C2, A2, B2, r2)
    s_out, t_out = [], []
    for k in range(P.shape[0]):
        for s in t1[k][_in_range(t1[k], r1, eps / rho1)].tolist():
            for t in t2[k][_in_range(t2[k], r2, eps / rho2)].tolist():
                s_out.append(min(max(s, r1[0]), r1[1]))
                t_out.append(min(max(t, r2[0]), r2[1]))
    s, t = np.array(s_out), np.array(t_out)
    if s.size:
        close = np.linalg.norm(c1.evaluate(s) - c2.evaluate(t), axis=1) <= eps
        s, t = s[close], t[close]
    s, t = _first_per_point(c1, s, t, eps)  # (range ends one period apart give one point twice)
    return _result(c1, c2, s, t)


def _line_trig(line: Line2D, rl, trig: Trig2D, rt, t_: Tolerance, swap: bool) -> CurveIntersections:
    """A 2-D line against ``C + a cos t + b sin t``: ``A cos t + B sin t = R`` along the normal."""
    eps = t_.linear
    o, d = line.origin, line.direction
    nd = float(np.linalg.norm(d))
    n = np.array([-d[1], d[0]]) / nd
    A, B, R = float(n @ trig.a), float(n @ trig.b), float(n @ (o - trig.center))
    rho = math.hypot(A, B)
    if abs(R) > rho + eps:
        t = np.zeros(0)
    else:
        phi = math.atan2(B, A)
        if abs(R) >= rho - eps:
            # Within eps of the line over the whole stretch between the two roots: a touching,
            # at the extremum of the distance (acos near ±1 would split it by sqrt(eps)).
            base = np.array([phi if R >= 0 else phi + math.pi])
        else:
            half = math.acos(R / rho)
            base = np.array([phi - half, phi + half])
        # Every representative of each root inside the range (a range may exceed one period).
        k0 = np.floor((rt[0] - base) / (2 * math.pi))
        t = np.concatenate([b + 2 * math.pi * np.arange(k, k + 3) for b, k in zip(base, k0)])
        speed = np.linalg.norm(trig.derivatives(t, 1)[:, 1], axis=1)
        slack = eps / np.maximum(speed, np.finfo(float).tiny)
        t = np.clip(t[_in_range(t, rt, slack)], *rt)
    P = trig.evaluate(t)
    s = (P - o) @ d / (nd * nd)
    keep = _in_range(s, rl, eps / nd)
    s, t = np.clip(s[keep], *rl), t[keep]
    close = np.linalg.norm(line.evaluate(s) - trig.evaluate(t), axis=1) <= eps
    s, t = s[close], t[close]
    t, s = _first_per_point(trig, t, s, eps)  # (a double root, a tangency, or range ends one period apart)
    return _result(trig, line, t, s) if swap else _result(line, trig, s, t)


def _first_per_point(curve, u: np.ndarray, w: np.ndarray, eps: float) -> tuple[np.ndarray, np.ndarray]:
    """The solutions ``u`` on ``curve`` (with their parameters ``w`` on the other curve) in ascending ``u``,
    each dropped whose point lies within ``eps`` of an earlier one's: one per point of a closed form that
    gives a touching twice or a point at both ends of a range a period long."""
    if u.size < 2:
        return u, w
    order = np.argsort(u, kind="stable")
    u, w = u[order], w[order]
    P = curve.evaluate(u)
    far = np.linalg.norm(P[:, None] - P[None], axis=2) > eps
    first = np.array([k == 0 or bool(np.all(far[k, :k])) for k in range(u.size)])
    return u[first], w[first]


def _end_feet(c1, r1, c2, r2, t_: Tolerance) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Feet of each curve's range ends on the other: ``(t of c1's ends on c2, distances, s of c2's ends on c1,
    distances)``, each (2,); computed once per call (seeds, end contacts and overlap cuts use them)."""
    t_of_1, d1 = _project(c2, r2, _derivs(c1, np.array(r1), 0)[:, 0], t_)
    s_of_2, d2 = _project(c1, r1, _derivs(c2, np.array(r2), 0)[:, 0], t_)
    return t_of_1, d1, s_of_2, d2


def _with_end_contacts(x: CurveIntersections, c1, r1, c2, r2, t_: Tolerance, feet, overlaps=()) -> CurveIntersections:
    """Add the range ends lying within ``tol.linear`` of the other curve, merged with nearby solutions.

    A slanted segment ending just short of (or past) another curve meets it, within the
    tolerance, at its end point, while the exact crossing of the extended curves lies outside
    the range.  Candidates (ends of ``c1``, ends of ``c2``, crossings) joined by stretches of
    both curves within ``tol.linear`` of each other are one intersection: curves accurate to
    ``eps`` crossing at a small angle place the crossing up to ``eps / sin(angle)`` from where
    an edge ends.  A merged intersection takes each curve's range end when one of its members
    is that end (so that edges ending at one vertex are split exactly at their ends).
    """
    eps = t_.linear
    e1, e2 = np.array(r1), np.array(r2)
    t_of_1, d1, s_of_2, d2 = feet
    s = np.concatenate([e1[d1 <= eps], s_of_2[d2 <= eps]])
    t = np.concatenate([t_of_1[d1 <= eps], e2[d2 <= eps]])
    kind = np.concatenate([np.full(int(np.sum(d1 <= eps)), 1), np.full(int(np.sum(d2 <= eps)), 2)])
    if overlaps and s.size:  # ends of an overlap are not isolated points
        slack = eps / np.maximum(np.linalg.norm(_derivs(c1, s, 1)[:, 1], axis=1), np.finfo(float).tiny)
        keep = np.ones(s.size, dtype=bool)
        for (s0, s1), _ in overlaps:
            keep &= (s < s0 - slack) | (s > s1 + slack)
        s, t, kind = s[keep], t[keep], kind[keep]
    if s.size == 0:
        return x if not overlaps else CurveIntersections(x.t1, x.t2, x.points, tuple(overlaps))
    s, t = np.concatenate([s, x.t1]), np.concatenate([t, x.t2])
    kind = np.concatenate([kind, np.zeros(x.t1.size, dtype=np.int64)])
    n = s.size
    I, J = np.triu_indices(n, 1)
    P = _derivs(c1, s, 0)[:, 0]
    same = np.linalg.norm(P[I] - P[J], axis=1) <= eps
    far = np.flatnonzero(~same)
    if far.size:  # a coincident stretch between them joins candidates that are not near (each pair alone)
        I2, J2 = I[far], J[far]
        _, m1 = _project(c2, r2, _derivs(c1, 0.5 * (s[I2] + s[J2]), 0)[:, 0], t_, eps)
        _, m2 = _project(c1, r1, _derivs(c2, 0.5 * (t[I2] + t[J2]), 0)[:, 0], t_, eps)
        same[far] = (m1 <= eps) & (m2 <= eps)
    label = np.arange(n)
    for i, j in zip(I[same], J[same]):  # union-find over a handful of candidates
        a, b = label[i], label[j]
        label[label == max(a, b)] = min(a, b)
    out_s, out_t = [], []
    for g in np.unique(label):
        m = np.flatnonzero(label == g)
        k1, k2 = m[kind[m] == 1], m[kind[m] == 2]
        out_s.append(s[k1[0]] if k1.size else s[m[0]])
        out_t.append(t[k2[0]] if k2.size else t[m[0]])
    out = _result(c1, c2, np.array(out_s), np.array(out_t))
    return CurveIntersections(out.t1, out.t2, out.points, tuple(overlaps))


def _deduplicate(c1, r1, c2, r2, s, t, dist, eps, t_):
    """One solution per intersection: cluster by point distance or by a coincident stretch between."""
    if s.size == 0:
        return s, t
    order = np.argsort(s, kind="stable")
    s, t, dist = s[order], t[order], dist[order]
    P = _derivs(c1, s, 0)[:, 0]
    # Neighbours in s join when their points are within eps or the midpoint between them on c1
    # is within eps of c2 (a tangential touching spreads Newton's solutions along a band).
    near = np.linalg.norm(P[1:] - P[:-1], axis=1) <= eps
    if s.size > 1:
        mid = 0.5 * (s[1:] + s[:-1])
        _, dm = _project(c2, r2, _derivs(c1, mid, 0)[:, 0], t_, eps)
        near |= dm <= eps
    group = np.concatenate([[0], np.cumsum(~near)])
    # Representative: the member with the smallest distance.
    rank = np.lexsort((dist, group))
    first = np.concatenate([[True], group[rank][1:] != group[rank][:-1]])
    best = np.sort(rank[first])
    # Groups at one point but not adjacent in s (both ends of a closed range): keep the first.
    Q = P[best]
    far = np.linalg.norm(Q[:, None] - Q[None], axis=2) > eps
    keep = np.array([k == 0 or bool(np.all(far[k, :k])) for k in range(best.size)])
    best = best[keep]
    return s[best], t[best]


def _overlaps(c1, r1, c2, r2, t_: Tolerance, eps: float, feet):
    """Maximal ranges of ``c1`` within ``eps`` of ``c2`` (see the module docstring, step 4)."""
    _, _, s_e, d_e = feet
    cuts = np.unique(np.concatenate([np.array(r1), s_e[d_e <= eps]]))
    if cuts.size < 2:
        return []
    a, b = cuts[:-1], cuts[1:]
    probe = a[:, None] + _OVERLAP_PROBES[None] * (b - a)[:, None]
    _, dp = _project(c2, r2, _derivs(c1, probe.ravel(), 0)[:, 0], t_, eps)
    on = np.all(dp.reshape(probe.shape) <= eps, axis=1)
    # An interval shorter than eps (between solutions clustered around a touching) is a point.
    path = np.concatenate([a[:, None], probe, b[:, None]], axis=1)
    Q = _derivs(c1, path.ravel(), 0)[:, 0].reshape(path.shape + (-1,))
    on &= np.linalg.norm(Q[:, 1:] - Q[:, :-1], axis=2).sum(axis=1) > eps
    out = []
    k = 0
    while k < on.size:
        if not on[k]:
            k += 1
            continue
        m = k
        while m + 1 < on.size and on[m + 1]:
            m += 1
        out.append((float(a[k]), float(b[m])))
        k = m + 1
    if not out:
        return []
    ends = np.array(out)
    u, _ = _project(c2, r2, _derivs(c1, ends.ravel(), 0)[:, 0], t_)
    u = u.reshape(-1, 2)
    return [((s0, s1), (float(u0), float(u1))) for (s0, s1), (u0, u1) in zip(out, u)]
