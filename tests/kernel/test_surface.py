"""NurbsSurface: evaluation against tensor-product oracles, grid vs scattered, derivatives, validation."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from scipy.interpolate import BSpline

from coons.errors import InvalidGeometryError, InvalidInputError
from coons.kernel.surface import NurbsSurface

from .strategies import params_in, surfaces


def scale_of(s: NurbsSurface) -> float:
    return float(np.abs(s.control_points).max()) + 1.0


def tensor_reference(s: NurbsSurface, u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Scattered points through scipy: contract the homogeneous net in u, then in v, per point."""
    Bu = BSpline(s.knots_u, np.eye(s.shape[0]), s.degree_u)(u)  # (m, nu)
    Bv = BSpline(s.knots_v, np.eye(s.shape[1]), s.degree_v)(v)  # (m, nv)
    Sw = np.einsum("mi,mj,ijd->md", Bu, Bv, s.homogeneous)
    return Sw[:, :-1] / Sw[:, -1:]


@given(surfaces())
def test_evaluation_matches_tensor_product_reference(s):
    rng = np.random.default_rng(0)
    u = params_in(s.domain_u, rng, 40)
    v = params_in(s.domain_v, rng, 40)
    np.testing.assert_allclose(s.evaluate(u, v), tensor_reference(s, u, v), rtol=0, atol=1e-11 * scale_of(s))


@given(surfaces())
def test_grid_equals_scattered(s):
    rng = np.random.default_rng(1)
    us = np.concatenate([params_in(s.domain_u, rng, 7), list(s.domain_u)])
    vs = np.concatenate([params_in(s.domain_v, rng, 5), list(s.domain_v)])
    G = s.evaluate_grid(us, vs)
    assert G.shape == (9, 7, 3)
    np.testing.assert_allclose(G, s.evaluate(us[:, None], vs[None, :]), rtol=0, atol=1e-12 * scale_of(s))


@given(surfaces(max_degree=3))
def test_partial_derivatives_match_finite_differences(s):
    rng = np.random.default_rng(2)
    (a, b), (c, d) = s.domain
    hu, hv = 1e-6 * (b - a), 1e-6 * (d - c)
    u = params_in((a + 2 * hu, b - 2 * hu), rng, 10)
    v = params_in((c + 2 * hv, d - 2 * hv), rng, 10)
    ku, kv = np.unique(s.knots_u), np.unique(s.knots_v)
    keep = (np.min(np.abs(u[:, None] - ku), axis=1) > 4 * hu) & (np.min(np.abs(v[:, None] - kv), axis=1) > 4 * hv)
    u, v = u[keep], v[keep]
    if u.size == 0:
        return
    D = s.derivatives(u, v, 2)
    D1u = s.derivatives(u + hu, v, 1)
    D1d = s.derivatives(u - hu, v, 1)
    D1r = s.derivatives(u, v + hv, 1)
    D1l = s.derivatives(u, v - hv, 1)
    for k, l, fd in (
        (1, 0, (D1u[:, 0, 0] - D1d[:, 0, 0]) / (2 * hu)),
        (0, 1, (D1r[:, 0, 0] - D1l[:, 0, 0]) / (2 * hv)),
        (2, 0, (D1u[:, 1, 0] - D1d[:, 1, 0]) / (2 * hu)),
        (1, 1, (D1r[:, 1, 0] - D1l[:, 1, 0]) / (2 * hv)),
        (0, 2, (D1r[:, 0, 1] - D1l[:, 0, 1]) / (2 * hv)),
    ):
        scale = np.abs(D[:, k, l]).max() + scale_of(s)
        np.testing.assert_allclose(D[:, k, l], fd, rtol=0, atol=1e-5 * scale)
    np.testing.assert_allclose(D[:, 0, 0], s.evaluate(u, v), rtol=0, atol=1e-12 * scale_of(s))


@given(surfaces())
def test_convex_hull_transposed_reversed(s):
    rng = np.random.default_rng(3)
    u = params_in(s.domain_u, rng, 30)
    v = params_in(s.domain_v, rng, 30)
    pts = s.evaluate(u, v)
    lo, hi = s.bounding_box()
    eps = 1e-12 * scale_of(s)
    assert np.all(pts >= lo - eps) and np.all(pts <= hi + eps)
    np.testing.assert_allclose(s.transposed().evaluate(v, u), pts, rtol=0, atol=1e-12 * scale_of(s))
    (a, b), (c, d) = s.domain
    np.testing.assert_allclose(s.reversed("u").evaluate(a + b - u, v), pts, rtol=0, atol=1e-11 * scale_of(s))
    np.testing.assert_allclose(s.reversed("v").evaluate(u, c + d - v), pts, rtol=0, atol=1e-11 * scale_of(s))
    r = s.reparametrized((0.0, 2.0), (5.0, 6.0))
    np.testing.assert_allclose(
        r.evaluate(2.0 * (u - a) / (b - a), 5.0 + (v - c) / (d - c)), pts, rtol=0, atol=1e-10 * scale_of(s)
    )
    assert s.is_close(s.transposed().transposed())
    shift = np.eye(4)
    shift[2, 3] = 1e-5
    assert not s.is_close(s.transformed(shift))
    assert not s.is_close(s.reparametrized((0.0, 9.0), (0.0, 9.0)))


def test_broadcasting_shapes():
    s = NurbsSurface(np.random.default_rng(0).random((3, 4, 3)), [0, 0, 0, 1, 1, 1], [0, 0, 0, 0.5, 1, 1, 1], 2, 2)
    assert s.evaluate(0.5, 0.5).shape == (3,)
    assert s.evaluate([0.1, 0.2], 0.3).shape == (2, 3)
    assert s.evaluate(np.zeros((4, 1)), np.zeros((1, 6))).shape == (4, 6, 3)
    assert s.derivatives(0.5, 0.5, 2).shape == (3, 3, 3)
    assert s.derivatives(np.zeros(5), np.zeros(5), 1).shape == (5, 2, 2, 3)
    assert s.evaluate_grid([0.0, 1.0], [0.0, 0.5, 1.0]).shape == (2, 3, 3)
    with pytest.raises(InvalidInputError, match="do not broadcast"):
        s.evaluate(np.zeros(3), np.zeros(4))


def test_validation_errors():
    P = np.zeros((3, 3, 3))
    K = [0, 0, 0, 1, 1, 1]
    with pytest.raises(InvalidGeometryError, match="knots_u: expected 6 knots"):
        NurbsSurface(P, [0, 0, 1, 1, 1], K, 2, 2)
    with pytest.raises(InvalidGeometryError, match="knots_v: knots must be non-decreasing"):
        NurbsSurface(P, K, [0, 0, 0, 1, 0.5, 1], 2, 2)
    with pytest.raises(InvalidGeometryError, match=r"expected weights of shape \(3, 3\)"):
        NurbsSurface(P, K, K, 2, 2, np.ones(3))
    with pytest.raises(InvalidGeometryError, match="weights must be positive"):
        NurbsSurface(P, K, K, 2, 2, -np.ones((3, 3)))
    with pytest.raises(InvalidGeometryError, match="3 axes"):
        NurbsSurface(np.zeros((3, 3)), K, K, 2, 2)
    with pytest.raises(InvalidGeometryError, match=r"need at least \(3, 4\) control points"):
        NurbsSurface(P, K, [0, 0, 0, 0, 1, 1, 1], 2, 3)
    s = NurbsSurface(P, K, K, 2, 2)
    with pytest.raises(InvalidInputError, match="v: parameter"):
        s.evaluate(0.5, -0.5)
    with pytest.raises(InvalidInputError, match="direction must be 'u' or 'v'"):
        s.reversed("w")
