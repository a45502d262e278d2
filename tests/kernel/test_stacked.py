"""Batched evaluation of polynomial NURBS curves (coons.kernel._stacked) against NurbsCurve itself."""

import numpy as np
import pytest

from coons.errors import InvalidInputError
from coons.kernel.analytic import Line
from coons.kernel.curve import NurbsCurve
from coons.kernel._stacked import derivatives_many, stacked_derivatives


def _curve(rng, n, p, d, lo=0.0, hi=1.0, weights=False, repeat=False):
    inner = np.sort(rng.uniform(lo, hi, n - p - 1))
    if repeat and p >= 2 and inner.size >= 2:
        inner[1] = inner[0]  # a double interior knot
    knots = np.concatenate([[lo] * (p + 1), inner, [hi] * (p + 1)])
    w = rng.uniform(0.5, 2.0, n) if weights else None
    return NurbsCurve(rng.normal(size=(n, d)), knots, p, w)


@pytest.mark.parametrize("order", [0, 1, 2])
def test_stacked_is_bitwise_the_curves_own_evaluation(order):
    rng = np.random.default_rng(7)
    for p in (1, 2, 3, 5):
        curves = [_curve(rng, n, p, 2, lo, hi, repeat=k % 2 == 0)
                  for k, (n, lo, hi) in enumerate([(p + 1, 0.0, 1.0), (p + 8, -2.0, 3.0), (p + 30, 5.0, 5.5)])]
        # Random parameters, the domain ends and the interior knots themselves.
        params = [np.concatenate([rng.uniform(*c.domain, 50 + 700 * k), list(c.domain), c.knots[p:-p]])
                  for k, c in enumerate(curves)]
        D = stacked_derivatives(curves, params, order)
        at = 0
        for c, u in zip(curves, params):
            ref = c.derivatives(u, order)
            np.testing.assert_array_equal(D[:, at : at + u.size], np.moveaxis(ref, 1, 0))
            at += u.size


def test_derivatives_many_mixes_kinds_and_checks_parameters():
    rng = np.random.default_rng(3)
    curves = [_curve(rng, 9, 3, 3), _curve(rng, 6, 2, 3, weights=True), Line([0, 0, 0], [1, 2, 3]),
              _curve(rng, 12, 3, 3), _curve(rng, 7, 2, 2), _curve(rng, 8, 3, 2)]  # (degree 3 in 2-D and 3-D)
    params = [rng.uniform(0.0, 1.0, 40) for _ in curves]
    for c, u, D in zip(curves, params, derivatives_many(curves, params, 1)):
        np.testing.assert_array_equal(D, np.moveaxis(c.derivatives(u, 1), 1, 0))
    for c, u, D in zip(curves, params, derivatives_many(curves, params, 0)):
        np.testing.assert_array_equal(D[0], c.evaluate(u))
    with pytest.raises(InvalidInputError):
        derivatives_many(curves[:1], [np.array([0.5, 1.5])], 0)
