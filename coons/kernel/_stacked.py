"""Several polynomial NURBS curves evaluated as one batch.

The checks and the mass integrals evaluate the fitted curves of a Boolean (intersection curves
and their p-curves: a few dozen small polynomial B-splines, degree 5 for the fits) one object at
a time, and at a few hundred points each the fixed cost of a call (span search, basis recursion,
contraction, some thirty numpy calls) dominates.  :func:`stacked_derivatives` concatenates the
knot vectors and the nets of curves of one degree and evaluates them together: one span search
per curve, then one basis evaluation and one contraction for all points.  A span's knot window
``U[span + 1 - p .. span + p]`` stays inside its own curve's knots, so the basis recursion
(The NURBS Book A2.2 / A2.3) reads the same knots, and does the same floating-point operations
in the same order, as :meth:`NurbsCurve.derivatives` (its numpy path) point by point: the
results are the same bits.  Rational curves are not handled here (their quotient rule is the
curve's own business); callers evaluate them one by one.
"""

from __future__ import annotations

import numpy as np

from coons.kernel import basis as _b
from coons.kernel.curve import NurbsCurve
from coons.tolerance import resolve


def stackable(curve) -> bool:
    """True when ``curve`` is a polynomial :class:`NurbsCurve` (what :func:`stacked_derivatives` takes)."""
    return type(curve) is NurbsCurve and not curve.is_rational


def stacked_derivatives(curves: list, params: list, order: int) -> np.ndarray:
    """Points and derivatives up to ``order`` of polynomial :class:`NurbsCurve` s of one degree and
    dimension, ``curves[i]`` at ``params[i]`` (flat, inside its domain: the caller checks), concatenated.

    Returns
    -------
    (order + 1, m, d) float64, ``m`` the total number of parameters; ``[k]`` the k-th derivatives.
    """
    p = curves[0].degree
    sizes = [x.size for x in params]
    knots = np.concatenate([c.knots for c in curves])
    net = np.concatenate([c.control_points for c in curves])
    k_off = np.repeat(np.cumsum([0] + [c.knots.size for c in curves[:-1]]), sizes)
    n_off = np.repeat(np.cumsum([0] + [c.control_points.shape[0] for c in curves[:-1]]), sizes)
    u = np.concatenate(params)
    local = np.concatenate([_b.find_spans(c.knots, p, x) for c, x in zip(curves, params)])
    if order == 0:
        N = [_b.basis_rows(knots, p, local + k_off, u)]
    else:
        N = _b.basis_derivative_rows(knots, p, local + k_off, u, order)
    base = local - p + n_off
    out = np.zeros((order + 1, u.size, net.shape[1]))  # derivatives above the degree vanish
    for c in range(net.shape[1]):
        P = np.ascontiguousarray(net[:, c])
        g = [P.take(base + j) for j in range(p + 1)]
        for k, Nk in enumerate(N):
            A = Nk[0] * g[0]
            for j in range(1, p + 1):
                A += Nk[j] * g[j]
            out[k, :, c] = A
    return out


def derivatives_many(curves: list, params: list, order: int) -> list[np.ndarray]:
    """``curves[i]`` and its derivatives up to ``order`` at ``params[i]`` (flat), each ``(order + 1, n_i, d)``:
    :meth:`~coons.kernel.curve.NurbsCurve.derivatives` of every curve, with its parameter check
    (beyond round-off outside the domain raises ``InvalidInputError``), the polynomial NURBS ones of
    one degree and dimension evaluated together (:func:`stacked_derivatives`), any other curve on its own."""
    out: list = [None] * len(curves)
    groups: dict[tuple[int, int], list[int]] = {}
    checked = list(params)
    for i, c in enumerate(curves):
        if stackable(c):
            checked[i] = _b.check_parameters(params[i], c.domain, resolve(None))
            groups.setdefault((c.degree, c.dimension), []).append(i)
        elif order == 0:
            out[i] = c.evaluate(params[i])[None]
        else:
            out[i] = np.moveaxis(c.derivatives(params[i], order), 1, 0)
    for members in groups.values():
        D = stacked_derivatives([curves[i] for i in members], [checked[i] for i in members], order)
        ends = np.cumsum([0] + [checked[i].size for i in members])
        for i, a, z in zip(members, ends[:-1], ends[1:]):
            out[i] = D[:, a:z]
    return out
