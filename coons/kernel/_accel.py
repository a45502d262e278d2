"""Optional compiled kernels (numba) for large scattered NURBS evaluations.

This module compiles, on first use, parallel numba kernels that evaluate NURBS curves
and surfaces and their derivatives of any order at scattered parameters: span search
(The NURBS Book A2.1, by the bucket table of :func:`coons.kernel.basis.find_spans` or
by binary search), Cox–de Boor per point (A2.2 for points, A2.3 for derivatives),
contraction with the local control points (A3.2 / A3.6) and, for rational geometry,
the quotient rule on the homogeneous derivatives (A4.2 / A4.4).  They perform the same
floating-point operations in the same order as the chunked numpy path of
:mod:`coons.kernel.curve` and :mod:`coons.kernel.surface`, which stays the reference
implementation (the tests hold the two to 1e-13 relative).  It deliberately does not
hold grid evaluation (BLAS-bound, it stays in numpy), validation (callers pass
checked, clamped parameters) or any geometry the numpy path lacks.

numba is optional: coons's runtime dependencies are numpy and scipy; the ``fast``
extra (``pip install coons[fast]``) installs it.  :data:`AVAILABLE` is true when numba
can be found and the environment variable ``COONS_NO_NUMBA`` is unset or empty; numba
itself is imported only when a batch first reaches :data:`THRESHOLD` points, so
``import coons`` stays light.  The first call ever compiles the kernels (about 15–20 s
of CPU on a 2-core EPYC); numba caches the machine code in ``__pycache__`` (or, when the
package is read-only, in its user cache directory) and later processes load it in
about a second; with no writable location at all it compiles in memory in every
process.  If numba is found but fails to import or compile, a :class:`RuntimeWarning`
says why, :data:`AVAILABLE` becomes false and evaluation continues on numpy.

The kernels hold the GIL while they run (numba's ``nogil`` is off), so calls from
several Python threads are serialised and never launch parallel regions concurrently
(numba's default workqueue threading layer is not thread-safe).
"""

from __future__ import annotations

import importlib.util
import os
import warnings

import numpy as np

from coons.kernel import basis as _b
from coons.kernel._common import binomials

__all__ = ["AVAILABLE", "THRESHOLD", "curve_derivatives", "surface_derivatives"]

#: True when numba is installed and ``COONS_NO_NUMBA`` is unset or empty.
AVAILABLE: bool = importlib.util.find_spec("numba") is not None and not os.environ.get("COONS_NO_NUMBA")

#: Batches of at least this many points go to the compiled kernels (when :data:`AVAILABLE`);
#: smaller ones stay on numpy, whose per-call overhead is lower than a parallel launch.
#: Measured on the 2-core machine with the other core busy: 5,400 rational surface points with
#: first derivatives took 7.8 ms in the parallel kernel against 1.9 ms in numpy, 1e5 points
#: 15.7 ms against 14.0 ms; the kernels win clearly only on large batches on a quiet machine.
#: Module-level so tests can move it to exercise either branch.
THRESHOLD: int = 1 << 16

#: Points per parallel work item: scratch arrays are allocated once per block, not per point.
_BLOCK = 256

_kernels = None

#: Helpers inlined into the kernels at numba IR level (small, called per point).
_INLINE = ("_span_of", "_basis_into", "_triangle_into", "_ders1_into")


def _compile():
    """Import numba and build the kernels (once); ``None`` if numba fails."""
    global _kernels, AVAILABLE
    if _kernels is not None or not AVAILABLE:
        return _kernels
    try:
        _kernels = _build()
    except Exception as exc:  # numba missing a piece, incompatible numpy, LLVM failure...
        AVAILABLE = False
        warnings.warn(
            f"coons: numba is installed but its kernels are unusable ({type(exc).__name__}: {exc}); "
            "evaluating with numpy",
            RuntimeWarning,
            stacklevel=3,
        )
        return None
    return _kernels


def _span_args(knots: np.ndarray, degree: int) -> tuple:
    """Span-search data of one knot vector for the kernels (see :func:`coons.kernel.basis.span_table`).

    ``(U, last, lo, scale, cells, table, steps, ext)``; ``steps = -1`` asks for the
    binary search (clustered knots, no table).
    """
    U = np.ascontiguousarray(knots, dtype=np.float64)
    n = U.shape[0] - degree - 1
    last = int(np.searchsorted(U, U[n], side="left")) - 1
    t = _b.span_table(U, degree, last)
    if t is None:
        return U, last, 0.0, 1.0, 1.0, np.zeros(1, dtype=np.int64), -1, U
    lo, scale, cells, table, steps, ext = t
    return U, last, float(lo), float(scale), float(cells), table.astype(np.int64), int(steps), ext


def curve_derivatives(
    knots: np.ndarray, degree: int, net: np.ndarray, u: np.ndarray, order: int, rational: bool
) -> np.ndarray | None:
    """Derivatives up to ``order`` of a curve at flat parameters, or ``None`` without numba.

    Parameters
    ----------
    knots : (n + p + 1,) float64
    degree : int
    net : (n, D) float64
        Control points (``rational=False``) or homogeneous ``[w P, w]`` points.
    u : (m,) float64, inside the domain
    order : int >= 0
    rational : bool
        If true, the last coordinate of ``net`` is the weight and the result is the
        Cartesian derivatives (A4.2), ``D - 1`` coordinates; otherwise the derivatives
        of ``net`` itself (homogeneous form when ``net`` is homogeneous).

    Returns
    -------
    (m, order + 1, D - rational) float64, or None if the kernels cannot be used.
    """
    k = _compile()
    if k is None:
        return None
    net = np.ascontiguousarray(net, dtype=np.float64)
    u = np.ascontiguousarray(u, dtype=np.float64)
    out = np.empty((u.shape[0], order + 1, net.shape[1] - int(rational)))
    k.curve(*_span_args(knots, degree), int(degree), net, u, int(order), bool(rational), _binomials(order), out)
    return out


def surface_derivatives(
    knots_u: np.ndarray,
    degree_u: int,
    knots_v: np.ndarray,
    degree_v: int,
    net: np.ndarray,
    u: np.ndarray,
    v: np.ndarray,
    order: int,
    rational: bool,
) -> np.ndarray | None:
    """Mixed partials up to ``order`` in each direction at flat parameter pairs, or ``None``.

    Parameters
    ----------
    net : (nu, nv, D) float64
        Control points, or homogeneous points (see :func:`curve_derivatives`).
    u, v : (m,) float64, inside the domains

    Returns
    -------
    (m, order + 1, order + 1, D - rational) float64
        ``[:, k, l]`` is ``∂^(k+l) / ∂u^k ∂v^l`` (A4.4 when ``rational``); None if the
        kernels cannot be used.
    """
    k = _compile()
    if k is None:
        return None
    net = np.ascontiguousarray(net, dtype=np.float64)
    nv = net.shape[1]
    u = np.ascontiguousarray(u, dtype=np.float64)
    v = np.ascontiguousarray(v, dtype=np.float64)
    out = np.empty((u.shape[0], order + 1, order + 1, net.shape[2] - int(rational)))
    k.surface(
        *_span_args(knots_u, degree_u), int(degree_u), *_span_args(knots_v, degree_v), int(degree_v),
        net.reshape(-1, net.shape[2]), nv, u, v, int(order), bool(rational), _binomials(order), out,
    )
    return out


def _binomials(n: int) -> np.ndarray:
    return np.ascontiguousarray(binomials(n))


class _Kernels:
    def __init__(self, curve, surface):
        self.curve = curve
        self.surface = surface


def _build() -> _Kernels:
    """Compile (or load from numba's cache) the kernels; raises whatever numba raises.

    The kernels are the plain functions below; compiling rebinds their module names to
    numba dispatchers, so the kernels call each other compiled (the helpers inlined)
    and numba's on-disk cache, keyed by module and function, finds them again in the
    next process.
    """
    import numba as nb
    from numba import types as t

    f8, i8, b1 = t.float64, t.int64, t.boolean
    ro1, ro2 = (t.Array(f8, k, "C", readonly=True) for k in (1, 2))
    w1, w2, w3, w4 = (t.Array(f8, k, "C") for k in (1, 2, 3, 4))
    tab = t.Array(i8, 1, "C", readonly=True)
    span = (ro1, i8, f8, f8, f8, tab, i8, ro1)  # U, last, lo, scale, cells, table, steps, ext
    signatures = {  # callees first
        "_span_of": (i8(*span, i8, f8), False),
        "_basis_into": (t.void(ro1, i8, i8, f8, w1, w1, w2), False),
        "_triangle_into": (t.void(ro1, i8, i8, f8, w1, w1, w2), False),
        "_ders1_into": (t.void(ro1, i8, i8, f8, w1, w1, w2, w2), False),
        "_ders_into": (t.void(ro1, i8, i8, f8, i8, w1, w1, w2, w2, w2), False),
        "_curve_kernel": (t.void(*span, i8, ro2, ro1, i8, b1, ro2, w3), True),
        "_surface_kernel": (t.void(*span, i8, *span, i8, ro2, i8, ro1, ro1, i8, b1, ro2, w4), True),
    }
    g = globals()
    g["_prange"] = nb.prange
    for name, (sig, parallel) in signatures.items():
        fn = g[name]
        fn = getattr(fn, "py_func", fn)
        opts = dict(parallel=parallel, fastmath=False, nogil=False, boundscheck=False)
        if name in _INLINE:
            opts["inline"] = "always"
        try:
            g[name] = nb.njit(sig, cache=True, **opts)(fn)
        except RuntimeError:  # no writable cache location at all: compile in memory
            g[name] = nb.njit(sig, cache=False, **opts)(fn)
    return _Kernels(g["_curve_kernel"], g["_surface_kernel"])


# ---------------------------------------------------------------------------- kernels
# Plain Python until _build() compiles them; _prange becomes numba.prange there.
_prange = range


def _span_of(U, last, lo, scale, cells, table, steps, ext, p, x):
    """Span of ``x``, as :func:`coons.kernel.basis.find_spans` (A2.1): its bucket table, or binary search."""
    if steps >= 0:
        c = (x - lo) * scale
        if c < 0.0:
            c = 0.0
        if c > cells - 1.0:
            c = cells - 1.0
        s = table[int(c)]
        for _ in range(steps):
            if ext[s + 1] <= x:
                s += 1
    else:
        # The number of knots <= x, minus one.
        a, b = 0, U.shape[0]
        while a < b:
            mid = (a + b) >> 1
            if U[mid] <= x:
                a = mid + 1
            else:
                b = mid
        s = a - 1
        if s < p:
            s = p
    if s > last:
        s = last
    return s


def _basis_into(U, p, span, x, left, right, N):
    """A2.2 into ``N[0, :]``, in the operation order of :func:`coons.kernel.basis.basis_rows`."""
    N[0, 0] = 1.0
    for j in range(1, p + 1):
        left[j] = x - U[span + 1 - j]
        right[j] = U[span + j] - x
        saved = 0.0
        for r in range(j):
            temp = N[0, r] / (right[r + 1] + left[j - r])
            N[0, r] = saved + right[r + 1] * temp
            saved = left[j - r] * temp
        N[0, j] = saved


def _triangle_into(U, p, span, x, left, right, ndu):
    """The table of A2.3: basis functions of degrees 0..p on and above the diagonal, knot differences below."""
    ndu[0, 0] = 1.0
    for j in range(1, p + 1):
        left[j] = x - U[span + 1 - j]
        right[j] = U[span + j] - x
        saved = 0.0
        for r in range(j):
            ndu[j, r] = right[r + 1] + left[j - r]
            temp = ndu[r, j - 1] / ndu[j, r]
            ndu[r, j] = saved + right[r + 1] * temp
            saved = left[j - r] * temp
        ndu[j, j] = saved


def _ders1_into(U, p, span, x, left, right, ndu, ders):
    """A2.3 for ``order = 1`` into ``ders[:2, :]``: the general loop for k = 1, written out (same operations)."""
    _triangle_into(U, p, span, x, left, right, ndu)
    for r in range(p + 1):
        ders[0, r] = ndu[r, p]
        d = 0.0
        if r >= 1:
            d = (1.0 / ndu[p, r - 1]) * ndu[r - 1, p - 1]
        if r <= p - 1:
            d += (-1.0 / ndu[p, r]) * ndu[r, p - 1]
        ders[1, r] = d * p


def _ders_into(U, p, span, x, order, left, right, ndu, a, ders):
    """A2.3 into ``ders[:order + 1, :]`` (rows above ``min(order, p)`` zero).

    The operation order of :func:`coons.kernel.basis.basis_derivative_rows`.
    """
    n = min(order, p)
    _triangle_into(U, p, span, x, left, right, ndu)
    for r in range(p + 1):
        ders[0, r] = ndu[r, p]
    for k in range(n + 1, order + 1):
        for r in range(p + 1):
            ders[k, r] = 0.0
    for r in range(p + 1):
        s1, s2 = 0, 1
        for j in range(p + 1):
            a[0, j] = 0.0
            a[1, j] = 0.0
        a[0, 0] = 1.0
        for k in range(1, n + 1):
            d = 0.0
            rk, pk = r - k, p - k
            if r >= k:
                a[s2, 0] = a[s1, 0] / ndu[pk + 1, rk]
                d = a[s2, 0] * ndu[rk, pk]
            j1 = 1 if rk >= -1 else -rk
            j2 = k - 1 if r - 1 <= pk else p - r
            for j in range(j1, j2 + 1):
                a[s2, j] = (a[s1, j] - a[s1, j - 1]) / ndu[pk + 1, rk + j]
                d += a[s2, j] * ndu[rk + j, pk]
            if r <= pk:
                a[s2, k] = -a[s1, k - 1] / ndu[pk + 1, r]
                d += a[s2, k] * ndu[r, pk]
            ders[k, r] = d
            s1, s2 = s2, s1
    factor = float(p)
    for k in range(1, n + 1):
        for r in range(p + 1):
            ders[k, r] *= factor
        factor *= p - k


def _curve_kernel(U, last, lo, scale, cells, table, steps, ext, p, net, u, order, rational, binom, out):
    """Curve derivatives ``out (m, order + 1, d)`` at ``u (m,)``: A2.1, A2.2/A2.3, A3.2, A4.2."""
    m = u.shape[0]
    D = net.shape[1]
    d = D - 1 if rational else D
    K = order + 1
    for b in _prange((m + _BLOCK - 1) // _BLOCK):
        left = np.empty(p + 1)
        right = np.empty(p + 1)
        ndu = np.empty((p + 1, p + 1))
        a = np.empty((2, p + 1))
        N = np.zeros((K, p + 1))
        A = np.empty((K, D))
        for q in range(b * _BLOCK, min(m, (b + 1) * _BLOCK)):
            x = u[q]
            span = _span_of(U, last, lo, scale, cells, table, steps, ext, p, x)
            if order == 0:
                _basis_into(U, p, span, x, left, right, N)
            elif order == 1:
                _ders1_into(U, p, span, x, left, right, ndu, N)
            else:
                _ders_into(U, p, span, x, order, left, right, ndu, a, N)
            for k in range(K):
                for c in range(D):
                    acc = N[k, 0] * net[span - p, c]
                    for j in range(1, p + 1):
                        acc += N[k, j] * net[span - p + j, c]
                    A[k, c] = acc
            if not rational:
                for k in range(K):
                    for c in range(D):
                        out[q, k, c] = A[k, c]
                continue
            # A4.2, in the operations of coons.kernel.curve's numpy path.
            r = 1.0 / A[0, d]
            for k in range(K):
                for c in range(d):
                    v = A[k, c]
                    for i in range(1, k + 1):
                        x = A[i, d] * out[q, k - i, c]
                        if binom[k, i] != 1.0:
                            x *= binom[k, i]
                        v = v - x
                    out[q, k, c] = v * r


def _surface_kernel(
    Uu, last_u, lo_u, scale_u, cells_u, table_u, steps_u, ext_u, pu,
    Uv, last_v, lo_v, scale_v, cells_v, table_v, steps_v, ext_v, pv,
    net, nv, u, v, order, rational, binom, out,
):
    """Surface partials ``out (m, K, K, d)`` at ``(u, v)``: A2.1, A2.2/A2.3, A3.6, A4.4.

    ``net`` is the control net flattened to ``(nu * nv, D)``.  Points (``order = 0``)
    with ``D <= 4`` contract in scalar accumulators (registers, not scratch memory).
    """
    m = u.shape[0]
    D = net.shape[1]
    d = D - 1 if rational else D
    K = order + 1
    KD = K * D
    for b in _prange((m + _BLOCK - 1) // _BLOCK):
        pm = max(pu, pv)
        left = np.empty(pm + 1)
        right = np.empty(pm + 1)
        ndu = np.empty((pm + 1, pm + 1))
        a = np.empty((2, pm + 1))
        Nu = np.zeros((K, pu + 1))
        Nv = np.zeros((K, pv + 1))
        T = np.empty(KD)
        A = np.empty(K * KD)  # A[(k K + l) D + c]: homogeneous partial (k, l), coordinate c
        S = np.empty(K * KD)  # Cartesian partials, S[(k K + l) d + c]
        for q in range(b * _BLOCK, min(m, (b + 1) * _BLOCK)):
            x, y = u[q], v[q]
            su = _span_of(Uu, last_u, lo_u, scale_u, cells_u, table_u, steps_u, ext_u, pu, x)
            sv = _span_of(Uv, last_v, lo_v, scale_v, cells_v, table_v, steps_v, ext_v, pv, y)
            base = (su - pu) * nv + (sv - pv)
            if order == 0 and D <= 4:
                _basis_into(Uu, pu, su, x, left, right, Nu)
                _basis_into(Uv, pv, sv, y, left, right, Nv)
                # Two stages in the numpy path's order: v first, then u.
                a0 = a1 = a2 = a3 = 0.0
                for i in range(pu + 1):
                    row = base + i * nv
                    w = Nv[0, 0]
                    t0 = w * net[row, 0]
                    t1 = w * net[row, 1]
                    t2 = w * net[row, 2] if D > 2 else 0.0
                    t3 = w * net[row, 3] if D > 3 else 0.0
                    for j in range(1, pv + 1):
                        w = Nv[0, j]
                        t0 += w * net[row + j, 0]
                        t1 += w * net[row + j, 1]
                        if D > 2:
                            t2 += w * net[row + j, 2]
                        if D > 3:
                            t3 += w * net[row + j, 3]
                    w = Nu[0, i]
                    if i == 0:
                        a0, a1, a2, a3 = w * t0, w * t1, w * t2, w * t3
                    else:
                        a0 += w * t0
                        a1 += w * t1
                        a2 += w * t2
                        a3 += w * t3
                A[0] = a0
                A[1] = a1
                if D > 2:
                    A[2] = a2
                if D > 3:
                    A[3] = a3
            else:
                if order == 0:
                    _basis_into(Uu, pu, su, x, left, right, Nu)
                    _basis_into(Uv, pv, sv, y, left, right, Nv)
                elif order == 1:
                    _ders1_into(Uu, pu, su, x, left, right, ndu, Nu)
                    _ders1_into(Uv, pv, sv, y, left, right, ndu, Nv)
                else:
                    _ders_into(Uu, pu, su, x, order, left, right, ndu, a, Nu)
                    _ders_into(Uv, pv, sv, y, order, left, right, ndu, a, Nv)
                for i in range(pu + 1):
                    row = base + i * nv
                    for l in range(K):
                        for c in range(D):
                            tv = Nv[l, 0] * net[row, c]
                            for j in range(1, pv + 1):
                                tv += Nv[l, j] * net[row + j, c]
                            T[l * D + c] = tv
                    for k in range(K):
                        w = Nu[k, i]
                        off = k * KD
                        if i == 0:
                            for e in range(KD):
                                A[off + e] = w * T[e]
                        else:
                            for e in range(KD):
                                A[off + e] += w * T[e]
            if not rational:
                for k in range(K):
                    for l in range(K):
                        for c in range(D):
                            out[q, k, l, c] = A[(k * K + l) * D + c]
                continue
            # A4.4, in the operations of coons.kernel.surface._rational_partials (orders 0
            # and 1 written out: the general loop below costs ten times more per point).
            r = 1.0 / A[d]
            if order == 0:
                for c in range(d):
                    out[q, 0, 0, c] = A[c] * r
                continue
            if order == 1:
                w01, w10, w11 = A[D + d], A[2 * D + d], A[3 * D + d]
                for c in range(d):
                    s00 = A[c] * r
                    s01 = (A[D + c] - w01 * s00) * r
                    s10 = (A[2 * D + c] - w10 * s00) * r
                    out[q, 0, 0, c] = s00
                    out[q, 0, 1, c] = s01
                    out[q, 1, 0, c] = s10
                    out[q, 1, 1, c] = (((A[3 * D + c] - w01 * s10) - w10 * s01) - w11 * s00) * r
                continue
            for k in range(K):
                for l in range(K):
                    for c in range(d):
                        tt = A[(k * K + l) * D + c]
                        for i in range(k + 1):
                            for j in range(l + 1):
                                if i == 0 and j == 0:
                                    continue
                                term = A[(i * K + j) * D + d] * S[((k - i) * K + l - j) * d + c]
                                coef = binom[k, i] * binom[l, j]
                                if coef != 1.0:
                                    term *= coef
                                tt = tt - term
                        tt *= r
                        S[(k * K + l) * d + c] = tt
                        out[q, k, l, c] = tt
