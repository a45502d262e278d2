"""Hypothesis strategies for random B-spline curves and surfaces, shared by the kernel tests."""

from __future__ import annotations

import numpy as np
from hypothesis import strategies as st

from coons.kernel.curve import NurbsCurve
from coons.kernel.surface import NurbsSurface


def random_knots(rng: np.random.Generator, n: int, p: int, clamped: bool) -> np.ndarray:
    """A valid knot vector for ``n`` coefficients of degree ``p`` with random interior knots,
    occasionally repeated (multiplicity up to ``p``)."""
    inner = np.sort(rng.random(n - p - 1)) if n > p + 1 else np.empty(0)
    if inner.size > 1 and p >= 2 and rng.random() < 0.3:
        k = int(rng.integers(0, inner.size - 1))
        reps = int(rng.integers(1, p))
        inner[k + 1 : k + 1 + reps] = inner[k]
        inner = np.sort(inner)
    if clamped:
        return np.concatenate([np.zeros(p + 1), inner, np.ones(p + 1)])
    # Floating ends: p knots below 0 and above 1 with the domain [0, 1].
    lo = -np.sort(rng.random(p))[::-1] * 0.5
    hi = 1.0 + np.sort(rng.random(p)) * 0.5
    return np.concatenate([lo, [0.0], inner, [1.0], hi])


@st.composite
def curves(draw, dims=(2, 3), max_degree: int = 5, rational=None, clamped=None):
    seed = draw(st.integers(0, 2**32 - 1))
    rng = np.random.default_rng(seed)
    p = draw(st.integers(1, max_degree))
    n = draw(st.integers(p + 1, p + 8))
    d = draw(st.sampled_from(dims))
    is_clamped = draw(st.booleans()) if clamped is None else clamped
    is_rational = draw(st.booleans()) if rational is None else rational
    U = random_knots(rng, n, p, is_clamped)
    P = rng.uniform(-10, 10, (n, d))
    w = rng.uniform(0.3, 3.0, n) if is_rational else None
    return NurbsCurve(P, U, p, w)


@st.composite
def surfaces(draw, max_degree: int = 4, rational=None):
    seed = draw(st.integers(0, 2**32 - 1))
    rng = np.random.default_rng(seed)
    pu = draw(st.integers(1, max_degree))
    pv = draw(st.integers(1, max_degree))
    nu = draw(st.integers(pu + 1, pu + 5))
    nv = draw(st.integers(pv + 1, pv + 5))
    is_rational = draw(st.booleans()) if rational is None else rational
    Uu = random_knots(rng, nu, pu, draw(st.booleans()))
    Uv = random_knots(rng, nv, pv, draw(st.booleans()))
    P = rng.uniform(-10, 10, (nu, nv, 3))
    w = rng.uniform(0.3, 3.0, (nu, nv)) if is_rational else None
    return NurbsSurface(P, Uu, Uv, pu, pv, w)


def params_in(domain, rng: np.random.Generator, m: int) -> np.ndarray:
    a, b = domain
    return a + (b - a) * rng.random(m)
