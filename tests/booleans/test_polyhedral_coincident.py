"""Polyhedral Booleans of solids whose faces coincide only up to rounding (issue 4).

The same rigid motion applied to two boxes that share a face, an edge or part of a face leaves
the shared features an ulp apart; the exact arrangement of the rounded inputs then sees hinges
and crossings of the size of the rounding error, and its exact result can have a crack touching
the boundary (an edge of four triangles).  :func:`coons.booleans._mesh_arrangement.snap` makes
the near-coincidences of near-coplanar triangles exact before the exact phases.  Here: the
snap's own invariants (closed meshes, surfaces moved by at most the tolerance, shared faces
triangulated identically, nothing done to inputs without near-coincidences), and end-to-end
regressions from a hunt over random rotations of grid boxes (cases that raised at sew or returned
an invalid solid before the snap)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

import coons.booleans.polyhedral as poly
from coons.booleans._mesh_arrangement import operand, snap
from coons.booleans._broad_phase import triangle_pairs
from coons.tolerance import Tolerance
from coons.topology.primitives import Box
from coons.topology.shape import Solid

EPS = Tolerance().linear
ROTATED_RTOL = 1e-9  # rotated inputs against closed forms: rounded vertices, moves below the tolerance


def box(lo, hi) -> Solid:
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    return Box(*(hi - lo)).translate((lo + hi) / 2)


def motion(quat, shift) -> np.ndarray:
    M = np.eye(4)
    M[:3, :3] = Rotation.from_quat(quat).as_matrix()
    M[:3, 3] = shift
    return M


def grid_pair(g1, g2, q, t):
    """Two grid boxes ``g = (lo, size)`` moved by the same rigid motion, and their closed-form volumes."""
    l1, h1 = np.array(g1[:3], float), np.add(g1[:3], g1[3:]).astype(float)
    l2, h2 = np.array(g2[:3], float), np.add(g2[:3], g2[3:]).astype(float)
    d = np.minimum(h1, h2) - np.maximum(l1, l2)
    vi = float(np.prod(d)) if np.all(d >= 0) else 0.0
    va, vb = float(np.prod(h1 - l1)), float(np.prod(h2 - l2))
    M = motion(q, t)
    vols = {"intersection": vi, "difference": va - vi, "union": va + vb - vi}
    return box(l1, h1).transformed(M), box(l2, h2).transformed(M), vols


def meshes(a: Solid, b: Solid):
    t = Tolerance()
    return poly._meshes(a, "A", t), poly._meshes(b, "B", t)


def signed_volume(X) -> float:
    C = X.P[X.T]
    return float(np.einsum("ij,ij->i", C[:, 0], np.cross(C[:, 1], C[:, 2])).sum() / 6.0)


def distance_to_surface(Q: np.ndarray, X) -> np.ndarray:
    """Distance of points ``Q (k, 3)`` to the triangles of ``X`` (brute force over all pairs; small meshes)."""
    A, B, C = (X.P[X.T[:, i]][None] for i in range(3))
    q = Q[:, None]
    # closest point on each triangle (Ericson, Real-Time Collision Detection 5.1.5), vectorised over pairs
    ab, ac, ap = B - A, C - A, q - A
    d1, d2 = np.einsum("...j,...j", ab, ap), np.einsum("...j,...j", ac, ap)
    bp, cp = q - B, q - C
    d3, d4 = np.einsum("...j,...j", ab, bp), np.einsum("...j,...j", ac, bp)
    d5, d6 = np.einsum("...j,...j", ab, cp), np.einsum("...j,...j", ac, cp)
    va, vb, vc = d3 * d6 - d5 * d4, d5 * d2 - d1 * d6, d1 * d4 - d3 * d2
    with np.errstate(invalid="ignore", divide="ignore"):
        den = va + vb + vc
        v, w = vb / den, vc / den
        P = A + v[..., None] * ab + w[..., None] * ac
        cands = [P]
        for U, V in ((A, B), (B, C), (C, A)):
            uv = V - U
            s = np.clip(np.einsum("...j,...j", q - U, uv) / np.einsum("...j,...j", uv, uv), 0, 1)
            cands.append(U + s[..., None] * uv)
    inside = (va >= 0) & (vb >= 0) & (vc >= 0)
    dist = np.stack([np.linalg.norm(c - q, axis=-1) for c in cands])
    dist[0] = np.where(inside, dist[0], np.inf)
    return dist.min(axis=0).min(axis=1)


# ---------------------------------------------------------------------- the snap itself
SHARED_FACE = ([1, 3, 1, 2, 3, 3], [1, 0, 2, 2, 3, 2],
               [0.08245371109486843, -0.44621759190925836, -0.6786959824497463, 0.9398508264322651],
               [0.03213717109575742, -0.7682687750584594, 0.24697951107500082])


def test_snap_triangulates_a_shared_face_identically_and_moves_nothing_beyond_the_tolerance():
    """B's face y = 3 is a sub-rectangle of A's face y = 3 (touching three of its edges); after the
    snap the triangles of both on the shared part are the same triples of bit-identical points."""
    g1, g2, q, t = SHARED_FACE
    a, b, _ = grid_pair(g1, g2, q, t)
    A, B = meshes(a, b)
    I, J = triangle_pairs(A.P, A.T, B.P, B.T)
    A2, B2, changed = snap(A, B, I, J, EPS)
    assert changed
    for X, X2 in ((A, A2), (B, B2)):
        operand(X2.P, X2.T, X2.face, "X")  # closed: every edge used by exactly two triangles (else raises)
        assert distance_to_surface(X2.P, X).max() <= EPS
        np.testing.assert_allclose(signed_volume(X2), signed_volume(X), rtol=0, atol=EPS * 100)
    # The shared part: B's face at y = 3 in the unmoved frame, x in [1, 3], z in [2, 4].
    M = motion(q, t)

    def shared(X):
        local = (X.P - M[:3, 3]) @ M[:3, :3]
        on = np.abs(local[:, 1] - 3) < 1e-9
        inside = on & (local[:, 2] > 2 - 1e-9)
        keep = np.all(inside[X.T], axis=1)
        return {frozenset(map(tuple, X.P[tri].tolist())) for tri in X.T[keep]}

    sa, sb = shared(A2), shared(B2)
    assert sa and sa == sb


def test_snap_leaves_inputs_without_near_coincidences_alone():
    rng = np.random.default_rng(3)
    a = box([-1, -1, -1], [1, 1, 1]).transformed(motion(rng.normal(size=4), [0.1, 0.2, 0.3]))
    b = box([-1, -1, -1], [1, 1, 1]).transformed(motion(rng.normal(size=4), [0.7, 0.5, 0.4]))
    A, B = meshes(a, b)
    I, J = triangle_pairs(A.P, A.T, B.P, B.T)
    assert I.size
    A2, B2, changed = snap(A, B, I, J, EPS)
    assert not changed and A2 is A and B2 is B


# ---------------------------------------------------------------------- regressions from the hunt
# (g1, g2, quaternion, shift, operation): each raised "not a manifold" at sew or returned a solid
# failing check before the snap (hunt: /tmp/R/hunt.py, seed 1).
REGRESSIONS = [
    SHARED_FACE + ("union",),
    ([1, 0, 1, 2, 2, 3], [0, 2, 3, 2, 3, 1],
     [-0.0971574549496812, 0.6581934548561186, 0.46037273794575917, 0.03826647530037719],
     [-0.6330099808061196, -0.5242581331070562, 0.40752851048368455], "intersection"),
    ([3, 0, 0, 3, 3, 1], [3, 2, 0, 2, 1, 3],
     [0.31799629916204797, -0.8934262119721763, 0.16437751192532746, 0.24782326144339328],
     [0.17350403933070724, 0.9806002143760695, 0.2273027069026572], "difference"),
    ([1, 1, 0, 1, 1, 3], [1, 0, 3, 2, 2, 2],
     [0.8553779479718049, -0.6775445920527823, 0.7718282759385762, -0.6546912318120952],
     [0.1804791893623543, -0.9906635871224467, 0.6899829574045395], "union"),
    ([1, 0, 0, 3, 1, 3], [1, 1, 2, 1, 1, 1],
     [0.841309939856322, 0.015239738911713596, -0.15746617267681806, 0.3162846234852388],
     [-0.06986197856202359, -0.809849697714041, -0.24211948618410228], "intersection"),
    ([1, 1, 2, 2, 1, 3], [1, 1, 1, 1, 1, 1],
     [-0.7356461681010071, -0.38984969478325304, -0.18445088553019806, 0.5450569115372192],
     [0.373369443422676, 0.073460684809171, -0.24628241246953708], "union"),
    # Boxes touching in a face: the intersection used to come back as the doubly covered touching
    # square (a flat tetrahedron of volume 3e-17 that passed the round-off test of from_mesh).
    ([3, 2, 2, 3, 2, 3], [1, 1, 0, 3, 1, 3],
     [0.9942776443266228, 0.11906511254254037, -0.6428864095588331, 0.2190815556544452],
     [-0.4254064126470216, 0.025878112441974244, -0.08135335261403909], "intersection"),
]


@pytest.mark.parametrize("g1, g2, q, t, op", REGRESSIONS)
def test_rotated_coincidences_found_by_the_hunt_give_valid_solids(g1, g2, q, t, op):
    a, b, vols = grid_pair(g1, g2, q, t)
    r = poly.boolean(a, b, op)
    report = r.check()
    assert report.ok, report.summary()
    scale = sum(vols.values())
    np.testing.assert_allclose(r.volume if not r.is_empty else 0.0, vols[op], rtol=0, atol=ROTATED_RTOL * scale)


def test_coplanar_faces_side_by_side_without_a_common_point():
    """Coplanar caps whose boxes overlap but which share no point (the intersect phase used to index
    an empty point table); found by the prism hunt."""
    from coons.topology.profile import Profile
    from coons.topology.sweep import extrude

    a = extrude(Profile.polygon([(0, 0), (3, 0), (0, 3)]), 1.0)
    b = extrude(Profile.polygon([(3, 3), (2, 3), (3, 2)]), 1.0)
    np.testing.assert_allclose((a + b).volume, 5.0, rtol=1e-12)
    assert (a & b).is_empty
    np.testing.assert_allclose((a - b).volume, 4.5, rtol=1e-12)
    for r in (a + b, a - b):
        assert r.check().ok


def test_a_fixed_batch_of_rotated_grid_boxes_all_succeed():
    """30 random rotated grid-box pairs (three Booleans each): every result whose exact counterpart
    is a manifold must come out valid and within the tolerance of the closed form; only the union
    of boxes touching along an edge or at a corner may be refused.  (Before the snap about 3 % of
    such Booleans raised or returned an invalid solid; the hunt over 1000 pairs leaves about
    0.4 %, where the snap does not settle — none of them in this batch.)"""
    from coons.errors import BooleanError

    rng = np.random.default_rng(1)
    for _ in range(30):
        q = rng.uniform(-1, 1, 4)
        while np.linalg.norm(q) < 0.1:
            q = rng.uniform(-1, 1, 4)
        t = rng.uniform(-1, 1, 3)
        g1 = np.r_[rng.integers(0, 4, 3), rng.integers(1, 4, 3)]
        g2 = np.r_[rng.integers(0, 4, 3), rng.integers(1, 4, 3)]
        a, b, vols = grid_pair(g1, g2, q, t)
        d = np.minimum(g1[:3] + g1[3:], g2[:3] + g2[3:]) - np.maximum(g1[:3], g2[:3])
        touch_only = bool(np.all(d >= 0) and np.sum(d == 0) >= 2)
        for op, v in vols.items():
            try:
                r = poly.boolean(a, b, op)
            except BooleanError as exc:
                assert op == "union" and touch_only and "not a manifold" in str(exc), (g1, g2, op, str(exc))
                continue
            assert r.check().ok, (g1, g2, op)
            vol = 0.0 if r.is_empty else r.volume
            np.testing.assert_allclose(vol, v, rtol=0, atol=ROTATED_RTOL * sum(vols.values()),
                                       err_msg=str((g1, g2, op)))
