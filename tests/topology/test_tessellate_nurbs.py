"""Tessellation of solids with many NURBS faces: flat bilinear grids (the fast planar path), twisted bilinear
grids, a loft and exact rational revolved faces (the general path): closed, within the deflection, volume
converging to the exact one."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from coons.kernel.analytic import PlanarSurface
from coons.kernel.surface import NurbsSurface
from coons.topology import tessellate as tess
from coons.topology.check import check
from coons.topology.mass import face_areas
from coons.topology.primitives import Cylinder, Sphere
from coons.topology.sew import bilinear_patch_faces, sew_faces
from coons.topology.tessellate import tessellate

from .test_tessellate import barycentric, nurbs_sided, vertex_links_are_cycles

#: Gauss–Legendre nodes and weights on [0, 1]: 3 points integrate the degree-(2, 2) flux integrand exactly.
_GX, _GW = np.polynomial.legendre.leggauss(3)
GX, GW = 0.5 * (_GX + 1.0), 0.5 * _GW


def grid_patches(n: int, phi=None, swap: bool = False) -> list[np.ndarray]:
    """Control nets ``(2, 2, 3)`` of the cube [-1, 1]³ cut into n × n squares per side, corners mapped by ``phi``,
    with ``Su × Sv`` outward (inward with ``swap``)."""
    I = np.eye(3)
    g = np.linspace(-1.0, 1.0, n + 1)
    out = []
    for k in range(3):
        for s in (-1.0, 1.0):
            ea, eb = I[(k + 1) % 3], I[(k + 2) % 3]
            if (s < 0) != swap:
                ea, eb = eb, ea
            for i in range(n):
                for j in range(n):
                    cp = np.array([[s * I[k] + g[i + di] * ea + g[j + dj] * eb for dj in (0, 1)] for di in (0, 1)])
                    out.append(cp if phi is None else phi(cp))
    return out


def grid_solid(n: int, phi=None, swap: bool = False):
    """The solid of :func:`grid_patches` sewn from bilinear NURBS faces (straight edges, Line2D p-curves); with
    ``swap`` every surface points inward and the faces are reversed (``sense`` False, loops clockwise in (u, v))."""
    return sew_faces(bilinear_patch_faces(grid_patches(n, phi, swap), sense=not swap))


def bilinear_volume(patches: list[np.ndarray]) -> float:
    """Exact volume enclosed by bilinear patches with outward ``Su × Sv`` (divergence theorem, exact quadrature)."""
    P = np.stack(patches)  # (f, 2, 2, 3)
    U, V = np.meshgrid(GX, GX, indexing="ij")
    W = np.outer(GW, GW)
    u, v = U[None, :, :, None], V[None, :, :, None]
    p00, p10, p01, p11 = (P[:, a, b][:, None, None, :] for a, b in ((0, 0), (1, 0), (0, 1), (1, 1)))
    S = (1 - u) * (1 - v) * p00 + u * (1 - v) * p10 + (1 - u) * v * p01 + u * v * p11
    Su = (1 - v) * (p10 - p00) + v * (p11 - p01)
    Sv = (1 - u) * (p01 - p00) + u * (p11 - p10)
    return float(np.einsum("fabj,fabj,ab->", S, np.cross(Su, Sv), W) / 3.0)


def bilinear_distance(cp: np.ndarray, X: np.ndarray) -> np.ndarray:
    """Distance of points ``X (k, 3)`` to the bilinear patch ``cp (2, 2, 3)`` (Newton from a dense start, clamped)."""
    s = np.linspace(0.0, 1.0, 41)
    U, V = (a.ravel() for a in np.meshgrid(s, s, indexing="ij"))

    def ev(u, v):
        u, v = u[..., None], v[..., None]
        return (1 - u) * (1 - v) * cp[0, 0] + u * (1 - v) * cp[1, 0] + (1 - u) * v * cp[0, 1] + u * v * cp[1, 1]

    G = ev(U, V)
    k = np.argmin(np.linalg.norm(X[:, None] - G[None], axis=2), axis=1)
    u, v = U[k], V[k]
    for _ in range(20):
        r = ev(u, v) - X
        Su = (1 - v)[:, None] * (cp[1, 0] - cp[0, 0]) + v[:, None] * (cp[1, 1] - cp[0, 1])
        Sv = (1 - u)[:, None] * (cp[0, 1] - cp[0, 0]) + u[:, None] * (cp[1, 1] - cp[1, 0])
        J = np.stack([Su, Sv], axis=2)
        JtJ = np.einsum("kia,kib->kab", J, J)
        g = np.einsum("kia,ki->ka", J, r)
        du = np.linalg.solve(JtJ, -g[..., None])[..., 0]
        u, v = np.clip(u + du[:, 0], 0.0, 1.0), np.clip(v + du[:, 1], 0.0, 1.0)
    return np.linalg.norm(ev(u, v) - X, axis=1)


def twist(cp: np.ndarray) -> np.ndarray:
    """Move the cube's corners off its faces by a smooth field (bilinear patches become saddles)."""
    x, y, z = cp[..., 0], cp[..., 1], cp[..., 2]
    out = cp.copy()
    out[..., 0] += 0.15 * np.sin(2.0 * y) * np.cos(1.5 * z)
    out[..., 1] += 0.15 * np.sin(1.7 * z + 0.3) * np.cos(x)
    out[..., 2] += 0.15 * np.cos(1.3 * x - 0.2) * np.sin(1.9 * y)
    return out


# ============================================================================ flat bilinear grids
@pytest.mark.parametrize("swap", [False, True])
def test_flat_bilinear_grid_is_two_exact_triangles_per_face(swap):
    n = 4
    s = grid_solid(n, swap=swap)
    b = s.brep
    assert check(b).ok and b.n_faces == 6 * n * n
    flat, frames = tess._flat_nurbs_planes(b.surfaces, 1e-7)
    assert len(flat) == b.n_faces  # every surface recognised as a plane
    m = tessellate(s, deflection=0.05)
    assert m.is_closed and vertex_links_are_cycles(m) and m.euler_characteristic == 2
    assert m.triangles.shape[0] == 2 * b.n_faces  # no interior point: the boundary quad, split once
    assert m.vertices.shape[0] == b.n_vertices  # the grid's corners and nothing else
    assert abs(m.volume - 8.0) <= 1e-12
    # Every triangle lies in its face's plane of the cube and points outward.
    Q = m.vertices[m.triangles]
    n_t = np.cross(Q[:, 1] - Q[:, 0], Q[:, 2] - Q[:, 0])
    axis = np.argmax(np.abs(n_t), axis=1)
    rows = np.arange(Q.shape[0])
    assert np.all(np.abs(np.abs(Q[rows, :, axis]) - 1.0) <= 1e-15)
    assert np.all(n_t[rows, axis] * Q[rows, 0, axis] > 0)
    # The frames: unit normals along Su x Sv of each surface.
    for si, row in flat.items():
        S = b.surfaces[si]
        D = S.derivatives(0.5, 0.5, 1)
        w = np.cross(D[1, 0], D[0, 1])
        assert np.allclose(frames[row, 3], w / np.linalg.norm(w), atol=1e-12)
        assert np.allclose(np.cross(frames[row, 1], frames[row, 2]), frames[row, 3], atol=1e-12)


def test_many_flat_nurbs_faces_are_fast():
    """A 384-face B-spline box (``benchmarks/bench_io.py`` times the 1 014-face one: ~15 s before the planar path,
    ~0.05 s with it) in well under a second."""
    import time

    s = grid_solid(8)
    best = np.inf
    for _ in range(3):
        t0 = time.perf_counter()
        m = tessellate(s, deflection=0.05)
        best = min(best, time.perf_counter() - t0)
    assert m.is_closed and m.triangles.shape[0] == 768 and abs(m.volume - 8.0) <= 1e-12
    assert best < 0.25  # ~0.02 s at load 1; generous for a loaded 2-core machine (the general path took ~6 s)


def test_flatness_detection_rejects_curved_folded_and_out_of_tolerance_nets():
    base = np.array([[[0.0, 0.0, 0.0], [0.0, 1.0, 0.0]], [[1.0, 0.0, 0.0], [1.0, 1.0, 0.0]]])
    flat = NurbsSurface(base, [0, 0, 1, 1], [0, 0, 1, 1], 1, 1)
    lifted = base.copy()
    lifted[1, 1, 2] = 1e-6  # a twisted quad beyond the tolerance 1e-7
    tiny = base.copy()
    tiny[1, 1, 2] = 1e-8  # within it
    # A bow tie: P00 (0,0), P10 (1,0), P01 (1,1), P11 (0,1): the diagonals are parallel, the cell has no side.
    folded = np.array([[[0.0, 0.0, 0.0], [1.0, 1.0, 0.0]], [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]])
    rev = base[:, ::-1]  # Su x Sv = -z
    # A planar bicubic-by-linear net whose cells all agree, a rational one too.
    cubic = np.stack([np.stack([[x, y, 0.0] for y in (0.0, 1.0)]) for x in (0.0, 0.3, 0.7, 1.0)])
    surfaces = [
        flat,
        NurbsSurface(lifted, [0, 0, 1, 1], [0, 0, 1, 1], 1, 1),
        NurbsSurface(tiny, [0, 0, 1, 1], [0, 0, 1, 1], 1, 1),
        NurbsSurface(folded, [0, 0, 1, 1], [0, 0, 1, 1], 1, 1),
        NurbsSurface(rev, [0, 0, 1, 1], [0, 0, 1, 1], 1, 1),
        NurbsSurface(cubic, [0, 0, 0, 0, 1, 1, 1, 1], [0, 0, 1, 1], 3, 1, weights=np.array([[1, 1], [2, 2], [0.5, 0.5], [1, 1]])),
        PlanarSurface([0, 0, 0], [0, 0, 1], [1, 0, 0]),
    ]
    got, frames = tess._flat_nurbs_planes(surfaces, 1e-7)
    assert sorted(got) == [0, 2, 4, 5]
    assert np.allclose(frames[got[0], 3], [0, 0, 1]) and np.allclose(frames[got[4], 3], [0, 0, -1])
    assert np.allclose(frames[got[5], 3], [0, 0, 1])
    assert tess._flat_nurbs_planes([], 1e-7)[1].shape == (0, 4, 3)


# ============================================================================ curved NURBS faces (general path)
@pytest.mark.parametrize("swap", [False, True])
def test_twisted_bilinear_grid_is_closed_within_deflection_and_converges(swap):
    n = 2
    patches = grid_patches(n, twist)
    exact = bilinear_volume(patches)
    assert abs(bilinear_volume(grid_patches(n)) - 8.0) <= 1e-13  # the exact volume formula on the cube
    s = grid_solid(n, twist, swap=swap)
    b = s.brep
    assert check(b).ok
    assert not tess._flat_nurbs_planes(b.surfaces, 1e-7)[0]  # no face takes the planar path
    area = float(face_areas(b).sum())
    for d in (0.03, 0.01):
        m = tessellate(s, deflection=d)
        assert m.is_closed and vertex_links_are_cycles(m) and m.euler_characteristic == 2
        # Sampled triangle points within d of their face's patch.
        X = np.einsum("sw,twj->tsj", barycentric(4), m.vertices[m.triangles])
        worst = 0.0
        for f in range(b.n_faces):
            cp = b.surfaces[b.face_surface[f]].control_points
            pts = X[m.face_ids == f].reshape(-1, 3)
            worst = max(worst, float(bilinear_distance(cp, pts).max()))
        assert worst <= d * (1 + 1e-6)
        # Saddles: the signed errors of the patches partly cancel, so only the bound (which shrinks with d) holds.
        assert abs(m.volume - exact) <= d * area


@settings(max_examples=12)
@given(amp=st.floats(0.0, 0.3), freq=st.floats(0.5, 2.0), d=st.floats(0.005, 0.2), swap=st.booleans())
def test_random_bilinear_boxes_are_closed_and_within_deflection(amp, freq, d, swap):
    """Cubes of six bilinear faces with corners moved at random (flat or twisted faces, either sense)."""
    def phi(cp):
        out = cp.copy()
        out[..., 0] += amp * np.sin(freq * cp[..., 1] + 0.3) * np.cos(freq * cp[..., 2])
        out[..., 1] += amp * np.sin(freq * cp[..., 2] - 0.7) * np.cos(freq * cp[..., 0])
        out[..., 2] += amp * np.sin(freq * cp[..., 0] + 1.1) * np.cos(freq * cp[..., 1])
        return out

    s = grid_solid(1, phi, swap=swap)
    b = s.brep
    m = tessellate(s, deflection=d)
    assert m.is_closed and vertex_links_are_cycles(m) and m.euler_characteristic == 2
    X = np.einsum("sw,twj->tsj", barycentric(4), m.vertices[m.triangles])
    for f in range(b.n_faces):
        cp = b.surfaces[b.face_surface[f]].control_points
        assert bilinear_distance(cp, X[m.face_ids == f].reshape(-1, 3)).max() <= d * (1 + 1e-6)
    exact = bilinear_volume(grid_patches(1, phi))
    assert abs(m.volume - exact) <= d * float(face_areas(b).sum())


def test_loft_is_closed_within_deflection_and_converges():
    from coons.topology.profile import Profile
    from coons.topology.sweep import loft

    s = loft([Profile.circle(1.0), Profile.circle(0.6, plane=((0, 0, 1.5), (0, 0, 1))),
              Profile.circle(0.9, plane=((0, 0, 3.0), (0, 0, 1)))])
    b = s.brep
    assert check(b).ok
    side = [f for f in range(b.n_faces) if isinstance(b.surfaces[b.face_surface[f]], NurbsSurface)]
    assert side
    exact = s.volume
    errors = []
    for d in (0.02, 0.004):
        m = tessellate(s, deflection=d)
        assert m.is_closed and vertex_links_are_cycles(m)
        # Side triangles: sampled points within d of the side surfaces (closest points on the NURBS).
        for f in side:
            S = b.surfaces[b.face_surface[f]]
            X = np.einsum("sw,twj->tsj", barycentric(3), m.vertices[m.triangles[m.face_ids == f]]).reshape(-1, 3)
            uv = S.closest_parameters(X)
            assert np.linalg.norm(S.evaluate(uv[:, 0], uv[:, 1]) - X, axis=1).max() <= d * (1 + 1e-6)
        err = abs(m.volume - exact)
        assert err <= d * s.area
        errors.append(err)
    assert errors[1] < errors[0]


@pytest.mark.parametrize("make,radius", [(lambda: Cylinder(1.5, 2.0), 1.5), (lambda: Sphere(1.3), 1.3)])
def test_rational_revolved_faces_volume_converges(make, radius):
    s = make()
    b = nurbs_sided(s.brep)
    errors = []
    for d in (5e-2, 5e-3, 5e-4):
        m = tessellate(b, deflection=d)
        assert m.is_closed
        # Every vertex on the exact surfaces; volume inside the deflection band.
        V = m.vertices
        rho = np.hypot(V[:, 0], V[:, 1]) if radius == 1.5 else np.linalg.norm(V, axis=1)
        on_side = np.abs(rho - radius) <= 1e-9
        assert on_side.sum() > 0
        err = s.volume - m.volume
        assert 0 <= err <= d * s.area  # inscribed: every vertex on a convex solid's surface
        errors.append(err)
    assert errors[2] < errors[1] < errors[0]
    assert errors[2] <= 0.02 * errors[0] * 1.5  # roughly linear in d (chordal error): two decades, ~1/100


# ============================================================================ the triangulator's component labels
def test_small_components_match_scipy_and_fall_back_on_long_strips():
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components
    from scipy.spatial import Delaunay

    from coons.topology import _cdt

    rng = np.random.default_rng(7)
    for _ in range(20):
        P = rng.random((int(rng.integers(4, 120)), 2))
        dl = Delaunay(P)
        N = dl.neighbors.astype(np.int64)
        link = (N >= 0) & (rng.random(N.shape) < 0.6)
        # Cut symmetrically: a link holds only if it holds from both sides.
        m = N.shape[0]
        back = np.zeros_like(link)
        for t, j in zip(*np.nonzero(N >= 0)):
            back[t, j] = link[N[t, j], list(N[N[t, j]]).index(t)]
        link &= back
        got = _cdt._small_components(N, link)
        assert got is not None
        tri = np.repeat(np.arange(m), 3).reshape(m, 3)
        want = connected_components(coo_matrix((np.ones(int(link.sum())), (tri[link], N[link])), shape=(m, m)),
                                    directed=False)
        assert got[0] == want[0]
        # Same partition: labels correspond one to one.
        pairs = set(zip(got[1].tolist(), want[1].tolist()))
        assert len(pairs) == got[0]
    # A chain of 400 triangles: one component after ~log2(400) rounds of pointer jumping; None when the rounds run out.
    m = 400
    N = np.full((m, 3), -1, dtype=np.int64)
    N[1:, 0] = np.arange(m - 1)
    N[:-1, 1] = np.arange(1, m)
    got = _cdt._small_components(N, N >= 0)
    assert got[0] == 1 and not got[1].any()
    old = _cdt._PROPAGATION_ROUNDS
    try:
        _cdt._PROPAGATION_ROUNDS = 2
        assert _cdt._small_components(N, N >= 0) is None
    finally:
        _cdt._PROPAGATION_ROUNDS = old
    # The triangulator gives the same triangles either way (a square with a hole, many points).
    k = 40
    t = np.linspace(0, 2 * np.pi, k, endpoint=False)
    outer = np.stack([np.cos(t), np.sin(t)], axis=1)
    inner = 0.4 * outer[::-1]
    pts = np.concatenate([outer, inner, 0.7 * np.stack([np.cos(t + 0.1), np.sin(t + 0.1)], axis=1)])
    seg = np.concatenate([np.stack([np.arange(k), (np.arange(k) + 1) % k], 1),
                          k + np.stack([np.arange(k), (np.arange(k) + 1) % k], 1)])
    T1 = _cdt.triangulate(pts, seg)
    for name, value in (("_SMALL_COMPONENTS", -1), ("_PROPAGATION_ROUNDS", 1)):  # scipy; propagation giving up
        old = getattr(_cdt, name)
        try:
            setattr(_cdt, name, value)
            T2 = _cdt.triangulate(pts, seg)
        finally:
            setattr(_cdt, name, old)
        assert np.array_equal(T1, T2)
    # n boundary and i interior points around h holes: n + 2 i + 2 h - 2 triangles.
    assert T1.shape[0] == 2 * k + 2 * k + 2 - 2


# ============================================================================ planes written as flat NURBS
def planes_as_flat_nurbs(b, margin: float = 0.5, every: int = 1):
    """``b`` with every PlanarSurface ``O + u X + v Y`` replaced by the bilinear NURBS over a box around its faces'
    parameters, ``(s, t) -> O + (u0 + s w) X + (v0 + t h) Y`` (same normal, same sense), and the p-curves on those
    faces mapped by ``(u, v) -> ((u - u0) / w, (v - v0) / h)``."""
    import dataclasses

    surfaces, pcurves = list(b.surfaces), list(b.pcurves)
    edge_pcurve = b.edge_pcurve.copy()
    for si, S in enumerate(b.surfaces):
        if not isinstance(S, PlanarSurface) or si % every:
            continue
        faces = np.flatnonzero(b.face_surface == si)
        uv = np.concatenate([pcurves[p].evaluate(np.linspace(*b.edge_range[e], 17))
                             for e in range(b.n_edges) for side in (0, 1)
                             if b.edge_face[e, side] in faces and (p := b.edge_pcurve[e, side]) >= 0])
        lo, hi = uv.min(axis=0) - margin, uv.max(axis=0) + margin
        w, h = hi - lo
        cp = np.array([[S.origin + (lo[0] + i * w) * S.x_dir + (lo[1] + j * h) * S.y_dir for j in (0, 1)]
                       for i in (0, 1)])
        surfaces[si] = NurbsSurface(cp, [0, 0, 1, 1], [0, 0, 1, 1], 1, 1)
        M = np.array([[1 / w, 0, -lo[0] / w], [0, 1 / h, -lo[1] / h]])
        for e in range(b.n_edges):
            for side in (0, 1):
                if b.edge_face[e, side] in faces and b.edge_pcurve[e, side] >= 0:
                    edge_pcurve[e, side] = len(pcurves)
                    pcurves.append(pcurves[b.edge_pcurve[e, side]].transformed(M))
    return dataclasses.replace(b, surfaces=tuple(surfaces), pcurves=tuple(pcurves), edge_pcurve=edge_pcurve)


@pytest.mark.parametrize("d", [0.05, 0.002])
def test_planes_written_as_flat_nurbs_tessellate_like_the_planes(d):
    """Disks (fans), faces with holes (the triangulator, boundary projected into the plane) and rectangles: the
    flat-NURBS versions give closed meshes with the same vertices, triangle counts and volume as the planes."""
    from coons.topology.profile import Profile
    from coons.topology.sweep import extrude

    solids = [Cylinder(1.0, 2.0),
              extrude(Profile(Profile.rectangle(4.0, 3.0).outer, [Profile.circle(0.8, center=(0.5, 0.2)).outer]), 1.5)]
    for s, every in [(x, k) for x in solids for k in (1, 2)]:
        b = s.brep
        n = planes_as_flat_nurbs(b, every=every)
        assert check(n).ok
        planes = [i for i, S in enumerate(b.surfaces) if isinstance(S, PlanarSurface) and i % every == 0]
        assert sorted(tess._flat_nurbs_planes(n.surfaces, 1e-7)[0]) == planes
        m0, m1 = tessellate(b, deflection=d), tessellate(n, deflection=d)
        assert m1.is_closed and vertex_links_are_cycles(m1)
        assert np.array_equal(m0.vertices, m1.vertices)
        assert np.array_equal(np.bincount(m0.face_ids), np.bincount(m1.face_ids))
        assert abs(m1.volume - m0.volume) <= 1e-12 * s.volume
        assert abs(m1.volume - s.volume) <= d * s.area
