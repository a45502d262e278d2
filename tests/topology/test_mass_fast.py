"""Batched NURBS evaluation and the fast paths of mass properties: surface stacks, the small-batch
evaluation path, first basis derivatives, flat NURBS faces as polygons, and sewn models of many
bilinear patches (the STEP-import benchmark's "B-spline box") against closed forms and independent
tensor-product Gauss references."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from coons.errors import InvalidInputError
from coons.kernel import basis as _b
from coons.kernel.surface import _SMALL, NurbsSurface, NurbsSurfaceStack
from coons.topology import mass
from coons.topology.check import check
from coons.topology.mass import face_areas, mass_properties
from coons.topology.sew import bilinear_patch_faces, sew_faces

from .test_tessellate_nurbs import grid_patches

RNG_SEED = 20261122


# ============================================================================ helpers
def random_surfaces(rng, count: int, pu: int, pv: int, nu: int, nv: int, rational: bool) -> list[NurbsSurface]:
    """``count`` surfaces sharing degrees, clamped knot vectors and net shape, random nets (and weights)."""
    ku = np.concatenate([np.zeros(pu + 1), np.sort(rng.random(nu - pu - 1)), np.ones(pu + 1)])
    kv = np.concatenate([np.zeros(pv + 1), np.sort(rng.random(nv - pv - 1)), np.ones(pv + 1)])
    out = []
    for _ in range(count):
        w = rng.uniform(0.5, 2.0, (nu, nv)) if rational else None
        out.append(NurbsSurface(rng.normal(size=(nu, nv, 3)), ku, kv, pu, pv, w))
    return out


def patch_box(n: int, bump: float = 0.0):
    """The cube [-1, 1]³, each side an ``n × n`` grid of bilinear NURBS faces, sewn into a solid.

    With ``bump`` the grid points of each side move along its outward normal by
    ``bump (1 - a²)(1 - b²)`` (``a, b`` the side's coordinates): shared grid points stay shared
    (the solid is still closed) and the patches become non-planar hyperbolic paraboloids with
    straight edges.
    """

    def bumped(cp):
        # The side of a point is its coordinate of magnitude 1 (on an edge of the cube the bump is 0).
        k = np.argmax(np.abs(cp), axis=-1)[..., None]
        f = 1.0 - cp * cp
        np.put_along_axis(f, k, 1.0, axis=-1)  # (1 - a²)(1 - b²) over the side's own coordinates
        out = np.zeros_like(cp)
        np.put_along_axis(out, k, np.sign(np.take_along_axis(cp, k, axis=-1)), axis=-1)
        return cp + bump * f.prod(axis=-1, keepdims=True) * out

    return sew_faces(bilinear_patch_faces(grid_patches(n, bumped if bump else None)))


def tensor_gauss(b, n: int = 8) -> tuple[float, float]:
    """Volume and area of a solid of untrimmed NURBS faces by an ``n × n`` Gauss rule per face
    (``(S · (Su × Sv)) / 3`` is a polynomial of degree <= 2 in ``u`` and ``v`` on a bilinear patch:
    exact from ``n = 2``; the area's square root converges fast on these smooth patches)."""
    x, w = np.polynomial.legendre.leggauss(n)
    t, W = 0.5 * (x + 1.0), 0.5 * w
    U, V = np.meshgrid(t, t, indexing="ij")
    WW = np.outer(W, W)
    vol = area = 0.0
    for f in range(b.n_faces):
        S = b.surfaces[int(b.face_surface[f])]
        D = S.derivatives(U, V, 1)
        N = np.cross(D[..., 1, 0, :], D[..., 0, 1, :])
        sign = 1.0 if b.face_sense[f] else -1.0
        vol += sign * float(np.sum(WW * np.einsum("...i,...i->...", D[..., 0, 0, :], N))) / 3.0
        area += float(np.sum(WW * np.linalg.norm(N, axis=-1)))
    return vol, area


# ============================================================================ kernel: stacks and small batches
@pytest.mark.parametrize("rational", [False, True])
@pytest.mark.parametrize("degrees", [(1, 1), (2, 3), (3, 2)])
def test_stack_matches_each_surface(rational, degrees):
    rng = np.random.default_rng(RNG_SEED)
    pu, pv = degrees
    surfaces = random_surfaces(rng, 5, pu, pv, pu + 3, pv + 2, rational)
    stack = NurbsSurfaceStack(surfaces)
    m = 3 * _SMALL  # both evaluation paths of the chunks below and above _SMALL
    which, u, v = rng.integers(0, 5, m), rng.random(m), rng.random(m)
    u[:3], v[:3] = [0.0, 1.0, 0.5], [1.0, 0.0, 0.5]
    for order in (0, 1, 2):
        got = stack.derivatives(which, u, v, order)
        assert got.shape == (m, order + 1, order + 1, 3)
        for i, S in enumerate(surfaces):
            sel = which == i
            ref = S.derivatives(u[sel], v[sel], order)
            np.testing.assert_allclose(got[sel], ref, rtol=1e-12, atol=1e-12 * np.abs(ref).max())


def test_stack_rejects_mixed_structures():
    rng = np.random.default_rng(RNG_SEED)
    a = random_surfaces(rng, 1, 2, 2, 4, 4, False)[0]
    b = random_surfaces(rng, 1, 2, 2, 4, 4, False)[0]  # other interior knots
    c = random_surfaces(rng, 1, 2, 2, 4, 4, True)[0]
    assert NurbsSurfaceStack.key(a) != NurbsSurfaceStack.key(b)
    with pytest.raises(InvalidInputError, match="surface 1 has another structure"):
        NurbsSurfaceStack([a, b])
    with pytest.raises(InvalidInputError, match="surface 1 has another structure"):
        NurbsSurfaceStack([a, dataclasses.replace(a, weights=c.weights)])
    with pytest.raises(InvalidInputError, match="non-empty"):
        NurbsSurfaceStack([])


@pytest.mark.parametrize("rational", [False, True])
@pytest.mark.parametrize("degrees", [(1, 1), (1, 3), (3, 2)])
def test_small_batches_match_large_batches(rational, degrees):
    """The small-batch path (fewer than _SMALL points) and the chunked path agree at the same points."""
    rng = np.random.default_rng(RNG_SEED + 1)
    pu, pv = degrees
    S = random_surfaces(rng, 1, pu, pv, pu + 4, pv + 3, rational)[0]
    m = 2 * _SMALL
    u, v = rng.random(m), rng.random(m)
    u[:4], v[:4] = [0.0, 1.0, 0.0, 1.0], [0.0, 0.0, 1.0, 1.0]
    for order in (0, 1, 2, 4):
        large = S.derivatives(u, v, order)
        small = np.concatenate([S.derivatives(u[s : s + 7], v[s : s + 7], order) for s in range(0, m, 7)])
        np.testing.assert_allclose(small, large, rtol=1e-12, atol=1e-12 * np.abs(large).max())
        if not rational and order > max(pu, pv):  # a polynomial's partials above its degree vanish
            assert np.all(small[:, pu + 1 :] == 0.0) and np.all(small[:, :, pv + 1 :] == 0.0)
    np.testing.assert_allclose(S.evaluate(u[:9], v[:9]), S.evaluate(u, v)[:9], rtol=1e-13, atol=1e-13)


@pytest.mark.parametrize("p", [1, 2, 3, 5])
def test_basis_first_derivatives_match_a23(p):
    rng = np.random.default_rng(RNG_SEED + p)
    n = p + 5
    U = np.concatenate([np.zeros(p + 1), np.sort(rng.random(n - p - 1)), np.ones(p + 1)])
    U[p + 2] = U[p + 1]  # a double interior knot
    u = np.concatenate([rng.random(40), [0.0, 1.0, U[p + 1]]])
    spans = _b.find_spans(U, p, u)
    got = _b.basis_first_derivatives(U, p, spans, u)
    ref = np.asarray(_b.basis_derivative_rows(U, p, spans, u, 1))
    np.testing.assert_array_equal(got[0], np.asarray(_b.basis_rows(U, p, spans, u)))
    np.testing.assert_allclose(got[1], ref[1], rtol=1e-13, atol=1e-13 * np.abs(ref[1]).max())
    np.testing.assert_allclose(got[0].sum(axis=0), 1.0, rtol=1e-14)  # partition of unity
    np.testing.assert_allclose(got[1].sum(axis=0), 0.0, atol=1e-12 * np.abs(ref[1]).max())


# ============================================================================ mass: flat nets and batched faces
def test_flat_nets_are_recognised_to_round_off():
    rng = np.random.default_rng(RNG_SEED + 7)
    Q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    grid = np.stack(np.meshgrid(np.linspace(0, 3, 4), np.linspace(-1, 2, 5), indexing="ij"), axis=-1)
    flat = np.concatenate([grid + 0.1 * rng.normal(size=grid.shape), np.zeros((4, 5, 1))], axis=-1) @ Q.T + [1e3, 0, 0]
    bent = flat.copy()
    bent[2, 3] += 1e-9 * Q[:, 2]  # one point 1e-9 off the plane: far above the coordinates' round-off
    assert mass._flat_nets([flat, bent, flat[:2, :2]]).tolist() == [True, False, True]


def test_flat_bilinear_box_is_integrated_as_polygons(monkeypatch):
    solid = patch_box(3)
    b = solid.brep
    assert check(b).ok
    calls = []
    real = NurbsSurfaceStack.derivatives
    monkeypatch.setattr(NurbsSurfaceStack, "derivatives", lambda self, *a: calls.append(1) or real(self, *a))
    mp = mass_properties(b)
    assert calls == []  # the flat patches never reach the adaptive quadrature
    np.testing.assert_allclose(mp.volume, 8.0, rtol=1e-14)
    np.testing.assert_allclose(mp.area, 24.0, rtol=1e-14)
    np.testing.assert_allclose(mp.centroid, 0.0, atol=1e-14)
    np.testing.assert_allclose(mp.inertia, 8.0 * 8.0 / 12.0 * np.eye(3), rtol=0, atol=1e-13)
    np.testing.assert_allclose(face_areas(b), 24.0 / b.n_faces, rtol=1e-13)
    # The same faces through Green's theorem and the adaptive quadrature (flatness test disabled).
    monkeypatch.setattr(mass, "_FLAT_ULPS", -1.0)
    adaptive = mass_properties(dataclasses.replace(b))
    assert calls
    np.testing.assert_allclose(adaptive.volume, mp.volume, rtol=1e-13)
    np.testing.assert_allclose(adaptive.area, mp.area, rtol=1e-13)
    np.testing.assert_allclose(adaptive.inertia, mp.inertia, rtol=0, atol=1e-12)


def test_bumpy_bilinear_box_matches_tensor_gauss_and_batches_its_faces(monkeypatch):
    """Non-planar bilinear patches go through the adaptive quadrature, all faces of one structure
    in one batch: the results match an independent tensor Gauss rule, match a run with one batch
    per surface, and the number of batched evaluations stays far below the number of faces."""
    counts, results = [], []
    real = NurbsSurfaceStack.derivatives
    calls = []
    monkeypatch.setattr(NurbsSurfaceStack, "derivatives", lambda self, *a: calls.append(len(self)) or real(self, *a))
    for n in (2, 4):
        solid = patch_box(n, bump=0.3)
        b = solid.brep
        assert check(b).ok
        assert not mass._tables(b).flat_nurbs[:-1].any()
        calls.clear()
        mp = mass_properties(dataclasses.replace(b))
        counts.append(len(calls))
        assert set(calls) == {b.n_faces}  # one stack holding every face's surface
        vol, area = tensor_gauss(b, 12)
        np.testing.assert_allclose(mp.volume, vol, rtol=1e-12)
        np.testing.assert_allclose(mp.area, area, rtol=1e-10)
        assert mp.volume > 8.0
        results.append((b, mp))
    # A few batches (one per adaptive round and chunk of points), not a few calls per face.
    assert counts[1] <= 2 * counts[0] and counts[1] < results[1][0].n_faces / 10
    # One batch per surface (a key unique to each surface) gives the same integrals.
    b, mp = results[0]
    key = NurbsSurfaceStack.key
    monkeypatch.setattr(NurbsSurfaceStack, "key", staticmethod(lambda S: key(S) + (id(S),)))
    calls.clear()
    single = mass_properties(dataclasses.replace(b))
    assert set(calls) == {1}
    np.testing.assert_allclose(single.volume, mp.volume, rtol=1e-14)
    np.testing.assert_allclose(single.area, mp.area, rtol=1e-14)
    np.testing.assert_allclose(single.inertia, mp.inertia, rtol=0, atol=1e-14 * np.abs(mp.inertia).max())


def test_evaluate_surfaces_matches_each_surface():
    from coons.kernel.analytic import CylindricalSurface
    from coons.kernel.surface import evaluate_surfaces

    rng = np.random.default_rng(RNG_SEED + 3)
    surfaces = (random_surfaces(rng, 4, 1, 1, 2, 2, False) + random_surfaces(rng, 3, 2, 3, 4, 5, True)
                + [CylindricalSurface((0.0, 0.0, 0.0), (0.0, 0.0, 1.0), (1.0, 0.0, 0.0), 2.0)] + random_surfaces(rng, 1, 3, 1, 5, 3, False))
    m = 400
    index = rng.integers(0, len(surfaces), m)
    u, v = rng.random(m), rng.random(m)
    got = evaluate_surfaces(surfaces, index, u, v)
    for i, S in enumerate(surfaces):
        sel = index == i
        np.testing.assert_allclose(got[sel], S.evaluate(u[sel], v[sel]), rtol=1e-13, atol=1e-13)
    with pytest.raises(InvalidInputError, match="outside the domain"):
        evaluate_surfaces(surfaces, [0, 1], [0.5, 1.5], [0.5, 0.5])
    with pytest.raises(InvalidInputError, match="out of range"):
        evaluate_surfaces(surfaces, [len(surfaces)], [0.5], [0.5])
    assert evaluate_surfaces(surfaces, [], [], []).shape == (0, 3)


def test_validated_knot_vectors_are_shared_and_bad_ones_still_raise():
    from coons.errors import InvalidGeometryError

    a = _b.as_knot_vector([0, 0, 0, 0.5, 1, 1, 1], 2, 4)
    b = _b.as_knot_vector(np.array([0.0, 0, 0, 0.5, 1, 1, 1]), 2, 4)
    assert a is b and not a.flags.writeable
    # The same values validated for another degree: a double knot exceeds degree 1.
    double = [0, 0, 0, 0.5, 0.5, 1, 1, 1]
    with pytest.raises(InvalidGeometryError, match="multiplicity 2"):
        _b.as_knot_vector(double, 1, 6)
    _b.as_knot_vector(double, 2, 5)
    with pytest.raises(InvalidGeometryError, match="multiplicity 2"):
        _b.as_knot_vector(double, 1, 6)  # valid for degree 2 is not valid for degree 1
    with pytest.raises(InvalidGeometryError, match="non-decreasing"):
        _b.as_knot_vector([0, 0, 1, 0.5, 1, 1], 1, 4)
    long = np.concatenate([[0.0], np.linspace(0, 1, 100), [1.0]])
    assert _b.as_knot_vector(long, 1, 100) is not _b.as_knot_vector(long, 1, 100)  # long vectors are not kept
