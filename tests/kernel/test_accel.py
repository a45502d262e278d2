"""Evaluation fast paths: the numba kernels against the numpy reference, dispatch, grid derivatives, span tables.

The numpy path of ``NurbsCurve`` / ``NurbsSurface`` is the reference implementation; the
numba kernels of :mod:`coons.kernel._accel` must reproduce it to 1e-13 relative (they do
the same operations in the same order).  ``_accel.THRESHOLD`` is moved with monkeypatch
to send a batch down either branch.  The first test that reaches a kernel compiles it
(seconds, once; numba caches the machine code in ``coons/kernel/__pycache__``).
"""

from __future__ import annotations

import os
import subprocess
import sys
import warnings

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st

from coons.errors import InvalidInputError
from coons.kernel import _accel
from coons.kernel import basis as b
from coons.kernel import curve as curve_mod
from coons.kernel import surface as surface_mod
from coons.kernel.conics import nurbs_torus
from coons.kernel.curve import NurbsCurve
from coons.kernel.surface import NurbsSurface

from .strategies import curves, params_in, random_knots, surfaces

RTOL = 1e-13  # numba against numpy: same operations, so agreement to round-off of the largest value
GRID_RTOL = 1e-12  # grid against scattered: different summation order
NEVER = 1 << 62  # a dispatch threshold no batch reaches

needs_numba = pytest.mark.skipif(
    bool(os.environ.get("COONS_NO_NUMBA")), reason="COONS_NO_NUMBA is set: the numba path is switched off"
)


def threshold(mp: pytest.MonkeyPatch, value: int) -> None:
    """Send batches of ``value`` points or more to the numba kernels (``NEVER``: none)."""
    if value != NEVER:
        assert _accel.AVAILABLE, "numba is a dev dependency (pip install -e .[dev]) but is not available"
    mp.setattr(_accel, "THRESHOLD", value)


def curve_params(c: NurbsCurve, seed: int) -> np.ndarray:
    """Random parameters, every distinct knot inside the domain and both ends."""
    lo, hi = c.domain
    knots = np.unique(c.knots)
    rng = np.random.default_rng(seed)
    return np.concatenate([params_in(c.domain, rng, 150), knots[(knots >= lo) & (knots <= hi)], [lo, hi]])


def surface_params(s: NurbsSurface, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """Random pairs plus every pair of knots/ends of the two domains."""
    rng = np.random.default_rng(seed)
    grid = []
    for (lo, hi), U in ((s.domain_u, s.knots_u), (s.domain_v, s.knots_v)):
        k = np.unique(U)
        grid.append(np.concatenate([k[(k >= lo) & (k <= hi)], [lo, hi]]))
    ku, kv = np.meshgrid(*grid, indexing="ij")
    u = np.concatenate([params_in(s.domain_u, rng, 150), ku.ravel()])
    v = np.concatenate([params_in(s.domain_v, rng, 150), kv.ravel()])
    return u, v


def assert_close_per_order(actual: np.ndarray, expected: np.ndarray, axes: tuple[int, ...], rtol: float) -> None:
    """Agreement to ``rtol`` times the largest magnitude of each derivative order (slices over ``axes``)."""
    assert actual.shape == expected.shape
    scale = np.abs(expected).max(axis=tuple(i for i in range(expected.ndim) if i not in axes), keepdims=True)
    excess = np.abs(actual - expected) / (rtol * np.maximum(scale, 1.0))
    assert np.all(excess <= 1.0), f"error {excess.max():.3g} x the allowed {rtol:g} of the largest value"


# ---------------------------------------------------------------------------- numba == numpy
@needs_numba
@settings(max_examples=40)
@given(curves(max_degree=5), st.integers(0, 4))
def test_curve_kernel_equals_numpy_path(c, order):
    u = curve_params(c, order)
    # The homogeneous form (no quotient rule) against the numpy reference.
    H = _accel.curve_derivatives(c.knots, c.degree, c.homogeneous, u, order, False)
    assert_close_per_order(H, c._homogeneous_derivatives(u, order), (1, 2), RTOL)
    # The public results through both dispatch branches.
    with pytest.MonkeyPatch.context() as mp:
        threshold(mp, 1)
        fast, fast_pts = c.derivatives(u, order), c.evaluate(u)
        threshold(mp, NEVER)
        ref, ref_pts = c.derivatives(u, order), c.evaluate(u)
    assert_close_per_order(fast, ref, (1,), RTOL)
    assert_close_per_order(fast_pts, ref_pts, (), RTOL)


@needs_numba
@settings(max_examples=40)
@given(surfaces(max_degree=5), st.integers(0, 3))
def test_surface_kernel_equals_numpy_path(s, order):
    u, v = surface_params(s, order)
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(surface_mod, "_SMALL", 0)  # the per-coordinate numpy loop the kernel mirrors
        H = _accel.surface_derivatives(
            s.knots_u, s.degree_u, s.knots_v, s.degree_v, s.homogeneous, u, v, order, False
        )
        assert_close_per_order(H, s._homogeneous_derivatives(u, v, order), (1, 2, 3), RTOL)
        threshold(mp, 1)
        fast, fast_pts = s.derivatives(u, v, order), s.evaluate(u, v)
        threshold(mp, NEVER)
        ref, ref_pts = s.derivatives(u, v, order), s.evaluate(u, v)
    assert_close_per_order(fast, ref, (1, 2), RTOL)
    assert_close_per_order(fast_pts, ref_pts, (), RTOL)


@needs_numba
def test_kernels_accept_read_only_strided_and_broadcast_parameters(monkeypatch):
    s = nurbs_torus([0, 0, 0], [0, 0, 1], 3, 1)
    rng = np.random.default_rng(3)
    u = rng.uniform(*s.domain_u, 2 * 5000)[::2]  # strided
    v = np.broadcast_to(np.float64(s.domain_v[1] / 3), u.shape)  # read-only, zero strides
    c = NurbsCurve(rng.uniform(-5, 5, (7, 3)), [0, 0, 0, 0.2, 0.5, 0.5, 0.9, 1, 1, 1], 2, rng.uniform(0.5, 2, 7))
    w = rng.random(5000)
    w.setflags(write=False)
    threshold(monkeypatch, 1)
    fast = s.derivatives(u, v, 2), c.derivatives(w, 3)
    threshold(monkeypatch, NEVER)
    assert_close_per_order(fast[0], s.derivatives(u, v, 2), (1, 2), RTOL)
    assert_close_per_order(fast[1], c.derivatives(w, 3), (1,), RTOL)


# ---------------------------------------------------------------------------- dispatch
@needs_numba
def test_dispatch_threshold_selects_the_branch(monkeypatch):
    assert _accel.AVAILABLE
    calls = []
    real_curve, real_surface = _accel.curve_derivatives, _accel.surface_derivatives

    def spy(real, name):
        def wrapped(*args):
            calls.append((name, args[-3].shape[0]))  # the (last) parameter array
            return real(*args)

        return wrapped

    monkeypatch.setattr(_accel, "curve_derivatives", spy(real_curve, "curve"))
    monkeypatch.setattr(_accel, "surface_derivatives", spy(real_surface, "surface"))
    monkeypatch.setattr(_accel, "THRESHOLD", 100)
    s = nurbs_torus([0, 0, 0], [0, 0, 1], 3, 1)
    c = s.iso_curve("v", 1.0)
    rng = np.random.default_rng(4)
    u = rng.uniform(*s.domain_u, 100)
    v = rng.uniform(*s.domain_v, 100)

    small = s.evaluate(u[:99], v[:99]), c.derivatives(u[:99], 2)
    assert calls == []  # 99 < THRESHOLD: numpy
    large = s.evaluate(u, v), c.derivatives(u, 2)
    assert calls == [("surface", 100), ("curve", 100)]  # 100 >= THRESHOLD: numba
    np.testing.assert_allclose(large[0][:99], small[0], rtol=0, atol=RTOL * 4)
    np.testing.assert_allclose(large[1][:99], small[1], rtol=RTOL, atol=RTOL * np.abs(small[1]).max())


@needs_numba
def test_kernels_from_several_python_threads(monkeypatch):
    """Concurrent callers are serialised by the GIL: same results, no aborted parallel launch."""
    import threading

    threshold(monkeypatch, 1)
    s = nurbs_torus([0, 0, 0], [0, 0, 1], 3, 1)
    u = np.random.default_rng(5).uniform(*s.domain_u, 20_000)
    ref = s.derivatives(u, u[::-1], 1)
    same = []

    def work():
        same.extend(np.array_equal(s.derivatives(u, u[::-1], 1), ref) for _ in range(5))

    threads = [threading.Thread(target=work) for _ in range(4)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert same == [True] * 20


def test_numpy_path_when_numba_is_off(monkeypatch):
    """With AVAILABLE false no kernel is called, whatever the batch size."""
    monkeypatch.setattr(_accel, "AVAILABLE", False)
    monkeypatch.setattr(_accel, "THRESHOLD", 1)

    def boom(*args):  # pragma: no cover - reaching it is the failure
        raise AssertionError("kernel called although AVAILABLE is False")

    monkeypatch.setattr(_accel, "_compile", boom)
    s = nurbs_torus([0, 0, 0], [0, 0, 1], 3, 1)
    u = np.linspace(*s.domain_u, 5000)
    P = s.evaluate(u, u[::-1])
    rho = np.hypot(P[:, 0], P[:, 1])
    np.testing.assert_allclose(np.hypot(rho - 3, P[:, 2]), 1.0, rtol=0, atol=1e-14)


def test_broken_numba_warns_and_falls_back_to_numpy(monkeypatch):
    monkeypatch.setattr(_accel, "AVAILABLE", True)
    monkeypatch.setattr(_accel, "_kernels", None)
    monkeypatch.setattr(_accel, "THRESHOLD", 1)

    def broken():
        raise ImportError("numba needs a numpy it does not have")

    monkeypatch.setattr(_accel, "_build", broken)
    c = NurbsCurve([[0, 0], [1, 2], [3, 1]], [0, 0, 0, 1, 1, 1], 2, [1, 0.5, 2])
    u = np.linspace(0, 1, 50)
    with pytest.warns(RuntimeWarning, match="numba is installed but its kernels are unusable.*ImportError"):
        got = c.derivatives(u, 1)
    assert _accel.AVAILABLE is False
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # warned once, then quietly numpy
        again = c.derivatives(u, 1)
    monkeypatch.setattr(_accel, "THRESHOLD", NEVER)
    np.testing.assert_array_equal(got, c.derivatives(u, 1))
    np.testing.assert_array_equal(again, got)


def _run(code: str, **env) -> str:
    full = {k: v for k, v in os.environ.items() if k != "COONS_NO_NUMBA"}
    full.update(env)
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=full, check=True)
    return out.stdout.strip()


def test_coons_no_numba_is_honoured_and_import_stays_light():
    code = (
        "import sys, numpy as np, coons, coons.kernel\n"
        "from coons.kernel import _accel\n"
        "from coons.kernel.conics import nurbs_torus\n"
        "print(_accel.AVAILABLE, 'numba' in sys.modules)\n"
        "s = nurbs_torus([0, 0, 0], [0, 0, 1], 3, 1)\n"
        "u = np.linspace(*s.domain_u, _accel.THRESHOLD)\n"
        "s.derivatives(u, u, 1)\n"
        "print('numba' in sys.modules)\n"
    )
    assert _run(code, COONS_NO_NUMBA="1").split() == ["False", "False", "False"]
    if not os.environ.get("COONS_NO_NUMBA"):
        # Without the variable numba is found, yet imported only by the first large batch.
        assert _run(code).split() == ["True", "False", "True"]


# ---------------------------------------------------------------------------- numpy paths
@settings(max_examples=30)
@given(surfaces(max_degree=4), st.integers(0, 2))
def test_surface_numpy_small_and_chunked_paths_agree(s, order):
    u, v = surface_params(s, 10 + order)
    with pytest.MonkeyPatch.context() as mp:
        threshold(mp, NEVER)
        mp.setattr(surface_mod, "_SMALL", 0)  # the per-coordinate loop, one chunk
        ref = s.derivatives(u, v, order)
        mp.setattr(surface_mod, "_SMALL", 1 << 30)  # one gather + einsum for every chunk
        small = s.derivatives(u, v, order)
        mp.setattr(surface_mod, "_SMALL", 0)
        mp.setattr(surface_mod, "_CHUNK", 7)  # many chunks and a ragged last one
        chunked = s.derivatives(u, v, order)
    assert_close_per_order(small, ref, (1, 2), 1e-12)
    assert_close_per_order(chunked, ref, (1, 2), 1e-13)


@settings(max_examples=30)
@given(curves(max_degree=5), st.integers(0, 3))
def test_curve_numpy_chunks_do_not_change_values(c, order):
    u = curve_params(c, 20 + order)
    with pytest.MonkeyPatch.context() as mp:
        threshold(mp, NEVER)
        ref = c.derivatives(u, order)
        mp.setattr(curve_mod, "_CHUNK", 5)  # many chunks and a ragged last one
        np.testing.assert_array_equal(c.derivatives(u, order), ref)


def test_rational_quotient_rule_on_the_circle():
    """A rational quadratic quarter circle: |C| = 1, C' ⟂ C, and C'' · C = -|C'|^2 (from |C|^2 = 1)."""
    s2 = np.sqrt(0.5)
    c = NurbsCurve([[1, 0], [1, 1], [0, 1]], [0, 0, 0, 1, 1, 1], 2, [1, s2, 1])
    u = np.linspace(0, 1, 300)
    D = c.derivatives(u, 2)
    C, d1, d2 = D[:, 0], D[:, 1], D[:, 2]
    np.testing.assert_allclose(np.linalg.norm(C, axis=1), 1.0, rtol=0, atol=1e-15)
    np.testing.assert_allclose(np.einsum("md,md->m", C, d1), 0.0, rtol=0, atol=1e-14)
    np.testing.assert_allclose(np.einsum("md,md->m", C, d2), -np.einsum("md,md->m", d1, d1), rtol=1e-13, atol=0)


# ---------------------------------------------------------------------------- grids
@settings(max_examples=40)
@given(surfaces(max_degree=4), st.integers(0, 3))
def test_derivatives_grid_equals_scattered_derivatives(s, order):
    rng = np.random.default_rng(order)
    us = np.concatenate([params_in(s.domain_u, rng, 6), list(s.domain_u), np.unique(s.knots_u)[1:-1]])
    vs = np.concatenate([params_in(s.domain_v, rng, 5), list(s.domain_v)])
    us = np.clip(us, *s.domain_u)
    G = s.derivatives_grid(us, vs, order)
    assert G.shape == (us.size, vs.size, order + 1, order + 1, 3)
    assert_close_per_order(G, s.derivatives(us[:, None], vs[None, :], order), (2, 3), GRID_RTOL)


@pytest.mark.parametrize("block", [1, 40, 1 << 20])  # one row, 3 rows (ragged), all rows per block
def test_grid_blocks_do_not_change_values(monkeypatch, block):
    s = nurbs_torus([0, 0, 0], [0, 0, 1], 3, 1)
    us, vs = np.linspace(*s.domain_u, 23), np.linspace(*s.domain_v, 11)
    ref_pts, ref_d = s.evaluate_grid(us, vs), s.derivatives_grid(us, vs, 2)
    monkeypatch.setattr(surface_mod, "_GRID_BLOCK", block)
    np.testing.assert_allclose(s.evaluate_grid(us, vs), ref_pts, rtol=0, atol=1e-14 * 4)
    assert_close_per_order(s.derivatives_grid(us, vs, 2), ref_d, (2, 3), 1e-14)  # GEMM blocking: ulps


def test_torus_grid_points_and_partials_are_exact():
    """Exact torus R = 3, r = 1 about z: points on it, first partials tangent to it (analytic normal)."""
    s = nurbs_torus([0, 0, 0], [0, 0, 1], 3, 1)
    us, vs = np.linspace(*s.domain_u, 101), np.linspace(*s.domain_v, 67)
    P = s.evaluate_grid(us, vs)
    D = s.derivatives_grid(us, vs, 1)
    np.testing.assert_allclose(D[:, :, 0, 0], s.derivatives_grid(us, vs, 0)[:, :, 0, 0], rtol=0, atol=1e-15 * 4)
    np.testing.assert_allclose(D[:, :, 0, 0], P, rtol=0, atol=1e-14)
    rho = np.hypot(P[..., 0], P[..., 1])
    np.testing.assert_allclose(np.hypot(rho - 3, P[..., 2]), 1.0, rtol=0, atol=1e-14)
    # Normal of the torus at P: from the tube centre (3 cos, 3 sin, 0) to P.
    centre = np.stack([3 * P[..., 0] / rho, 3 * P[..., 1] / rho, np.zeros_like(rho)], axis=-1)
    n = P - centre
    for k, l in ((1, 0), (0, 1)):
        T = D[:, :, k, l]
        cos = np.einsum("abd,abd->ab", T, n) / np.linalg.norm(T, axis=-1)
        np.testing.assert_allclose(cos, 0.0, rtol=0, atol=1e-13)
    # Central differences of the grid points in u agree with the u partials away from knots.
    h = 1e-6
    mid = np.linspace(0.3, 0.45, 5)
    fd = (s.evaluate_grid(mid + h, vs) - s.evaluate_grid(mid - h, vs)) / (2 * h)
    np.testing.assert_allclose(s.derivatives_grid(mid, vs, 1)[:, :, 1, 0], fd, rtol=0, atol=1e-7)


def test_derivatives_grid_errors_and_empty_grids():
    s = nurbs_torus([0, 0, 0], [0, 0, 1], 3, 1)
    with pytest.raises(InvalidInputError, match="order must be an integer >= 0, got -1"):
        s.derivatives_grid([0.1], [0.1], -1)
    with pytest.raises(InvalidInputError, match="order must be an integer >= 0, got 1.0"):
        s.derivatives_grid([0.1], [0.1], 1.0)
    with pytest.raises(InvalidInputError, match="order must be an integer >= 0, got True"):
        s.derivatives_grid([0.1], [0.1], True)
    with pytest.raises(InvalidInputError, match=r"u: parameter 7.0 is outside the domain"):
        s.derivatives_grid([7.0], [0.1])
    with pytest.raises(InvalidInputError, match=r"v: parameters must be finite"):
        s.derivatives_grid([0.1], [np.nan])
    assert s.derivatives_grid([], [0.1, 0.2], 2).shape == (0, 2, 3, 3, 3)
    assert s.evaluate_grid([0.1], []).shape == (1, 0, 3)


# ---------------------------------------------------------------------------- span search
def binary_search_spans(U: np.ndarray, p: int, u: np.ndarray) -> np.ndarray:
    n = U.size - p - 1
    last = int(np.searchsorted(U, U[n], side="left")) - 1
    return np.maximum(np.minimum(np.searchsorted(U, u, side="right") - 1, last), p)


@st.composite
def span_setups(draw):
    rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
    p = draw(st.integers(1, 6))
    n = draw(st.integers(p + 1, p + 40))
    U = random_knots(rng, n, p, draw(st.booleans())) * draw(st.sampled_from([1.0, 1e-3, 7e4])) + draw(
        st.sampled_from([0.0, -3.0, 1e3])
    )
    return b.as_knot_vector(U, p, n), p


@settings(max_examples=200)
@given(span_setups())
@example((b.as_knot_vector([0, 0, 0, 0.5, 0.5, 1, 1, 1], 2, 5), 2))
@example((b.as_knot_vector(np.r_[0, 0, np.linspace(0.5, 0.5001, 9), 1, 1], 1, 11), 1))  # clustered: no table
def test_bucket_span_search_equals_binary_search(setup):
    U, p = setup
    lo, hi = b.domain_of(U, p)
    rng = np.random.default_rng(0)
    u = np.concatenate([
        lo + (hi - lo) * rng.random(b._TABLE_MIN_POINTS),
        U, np.nextafter(U, np.inf), np.nextafter(U, -np.inf),
        [lo, hi, lo - 1.0, hi + 1.0, np.inf, -np.inf],
    ])
    spans = b.find_spans(U, p, u)
    assert spans.dtype == np.int64
    np.testing.assert_array_equal(spans, binary_search_spans(U, p, u))


def test_span_table_is_built_or_declined_as_documented():
    U = b.clamped_uniform_knots(20, 3)
    last = U.size - 3 - 2
    table = b.span_table(U, 3, last)
    assert table is not None and table[4] <= b._TABLE_MAX_STEPS
    clustered = b.as_knot_vector(np.r_[0, 0, np.linspace(0.5, 0.5001, 9), 1, 1], 1, 11)
    assert b.span_table(clustered, 1, 10) is None  # nine knots in one cell: binary search instead
    # NaN parameters take the binary search (NaN sorts last: the last span), not the table.
    u = np.full(b._TABLE_MIN_POINTS, 0.5)
    u[3] = np.nan
    np.testing.assert_array_equal(b.find_spans(U, 3, u), binary_search_spans(U, 3, u))
