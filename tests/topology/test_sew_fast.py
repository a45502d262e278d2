"""Edge matching in sewing: the vectorised common case (two uses with coincident midpoints) and the
cached curve samples give exactly the pairs of the general union–find path."""

from __future__ import annotations

import numpy as np

from coons.tolerance import resolve
from coons.topology import sew
from coons.topology.profile import Profile
from coons.topology.sweep import extrude


def general_pairs(uses, vertex) -> np.ndarray:
    """The pairs of :func:`sew._match_edges` by the general path alone, every group through union–find."""
    vs, ve = vertex[:, 0], vertex[:, 1]
    lo, hi = np.minimum(vs, ve), np.maximum(vs, ve)
    pairs = []
    for key in sorted(set(zip(lo.tolist(), hi.tolist()))):
        group = np.flatnonzero((lo == key[0]) & (hi == key[1])).tolist()
        for comp in sew._agreeing_components(uses, group):
            sew._require_pair(uses, comp, vertex)
            pairs.append(comp)
    out = np.asarray(pairs, dtype=np.int64).reshape(-1, 2)
    return out[np.argsort(out[:, 0], kind="stable")]


def test_fast_matching_equals_the_general_path():
    # Holes as two half-cylinders: their circles are two arcs between the same two vertices (groups
    # of four uses, the sampled path); the straight edges are groups of two (the vectorised path).
    holes = [Profile.circle(1.0, center=(-3.0 + 3.0 * i, 0.0)).outer for i in range(3)]
    solid = extrude(Profile(Profile.rectangle(12.0, 4.0).outer, holes), 2.0)
    t = resolve(None)
    specs = sew.face_specs(solid.brep)
    uses = sew._Uses(specs, t)
    vertex, vpoint, _ = sew._merge_vertices(uses, t)
    got = sew._match_edges(uses, vertex, vpoint, t)
    np.testing.assert_array_equal(got, general_pairs(uses, vertex))
    sizes = np.bincount(np.unique(np.sort(vertex, axis=1), axis=0, return_inverse=True)[1].ravel())
    assert {2, 4} <= set(sizes.tolist())  # both paths were taken
    resewn = sew.sew_faces(specs, t)
    assert resewn.brep.n_edges == solid.brep.n_edges
    np.testing.assert_allclose(resewn.volume, solid.volume, rtol=1e-14)
