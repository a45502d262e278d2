"""disjoint_union: solids with pairwise apart boxes put side by side in one B-rep.

The union of valid apart solids is valid (``check`` clean) without sewing; its counts (vertices,
edges, loops, faces, shells, lumps) and measures (volume, area) are the sums of the parts'; each
part's faces keep their geometry objects, row for row; it agrees with sewing all the faces
together; and boxes that meet (or come within a tolerance) are refused, naming the two solids.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from coons.errors import InvalidInputError
from coons.topology.check import check
from coons.topology.disjoint import disjoint_union, meeting_pair, padded_box, padded_boxes, stacked
from coons.topology.primitives import Box, Cone, Cylinder, Sphere, Torus
from coons.topology.sew import face_specs, sew_faces
from coons.topology.shape import Solid
from coons.topology.transform import Pos, Rot

#: Volumes and areas of the union are sums of the same per-face integrals: round-off only.
RTOL = 1e-12


def counts(solid):
    b = solid.brep
    return np.array([b.n_vertices, b.n_edges, b.n_loops, b.n_faces, b.n_shells, b.n_solids])


def parts():
    """Solids of every kind, a hollow one (a void shell) among them, placed on a line 10 apart."""
    hollow = Box(4, 4, 4) - Sphere(1.5)
    solids = [Box(1, 2, 3), Cylinder(1, 2), Cone(1, 0.5, 2), Sphere(1.5), Torus(3, 1),
              Pos(0, 0, 0) * Rot(10, 20, 30) * Box(1, 2, 3), hollow]
    return [s.translate((10.0 * k, 0.0, 0.0)) for k, s in enumerate(solids)]


def test_union_is_valid_and_adds_up():
    ps = parts()
    u = disjoint_union(ps)
    assert check(u.brep).ok
    np.testing.assert_array_equal(counts(u), sum(counts(p) for p in ps))
    np.testing.assert_allclose(u.volume, sum(p.volume for p in ps), rtol=RTOL)
    np.testing.assert_allclose(u.area, sum(p.area for p in ps), rtol=RTOL)
    assert u.brep.n_shells == len(ps) + 1  # the hollow box's void stays its own shell


def test_faces_keep_their_geometry_in_order():
    ps = parts()
    u = disjoint_union(ps)
    specs = face_specs(u)
    f = 0
    for p in ps:
        for spec, own in zip(specs[f:f + p.brep.n_faces], face_specs(p)):
            assert spec.surface is own.surface and spec.sense == own.sense
            for loop, own_loop in zip(spec.loops, own.loops, strict=True):
                for e, o in zip(loop, own_loop, strict=True):
                    assert (e.t0, e.t1, e.tol) == (o.t0, o.t1, o.tol)
                    assert e.pcurve is o.pcurve
        f += p.brep.n_faces
    assert f == u.brep.n_faces


def test_agrees_with_sewing():
    ps = parts()[:5]
    u = disjoint_union(ps)
    sewn = sew_faces([spec for p in ps for spec in face_specs(p)])
    np.testing.assert_array_equal(counts(u), counts(sewn))
    np.testing.assert_allclose(u.volume, sewn.volume, rtol=RTOL)


def test_empty_and_single():
    box = Box(1, 1, 1)
    assert disjoint_union([Solid.empty(), box, Solid.empty()]) is box
    assert disjoint_union([]).is_empty
    assert disjoint_union([Solid.empty()]).is_empty
    assert stacked([box.brep]) is box.brep


def test_meeting_boxes_are_refused():
    a = Box(1, 1, 1)
    with pytest.raises(InvalidInputError, match=r"solids 0 .* and 2 .* meet"):
        disjoint_union([a, a.translate((5, 0, 0)), a.translate((0.5, 0.5, 0.5))])
    # A gap below the tolerance counts as meeting (sewing could merge their vertices).
    with pytest.raises(InvalidInputError, match="meet"):
        disjoint_union([a, a.translate((1.0 + 1e-9, 0, 0))])
    with pytest.raises(InvalidInputError, match="argument 1 must be a coons Solid"):
        disjoint_union([a, "box"])


@given(st.lists(st.tuples(st.floats(-50, 50), st.floats(-50, 50), st.floats(-50, 50), st.floats(0.1, 5),
                          st.floats(0.1, 5), st.floats(0.1, 5)), min_size=2, max_size=12))
def test_meeting_pair_is_the_first_of_all_pairs(spec):
    """The sweep finds the first meeting pair that testing every pair finds."""
    c = np.array([s[:3] for s in spec])
    h = np.array([s[3:] for s in spec])
    boxes = np.stack([c - h, c + h], axis=1)
    n = len(spec)
    every = [(i, j) for i in range(n) for j in range(i + 1, n)
             if np.all((boxes[i, 0] <= boxes[j, 1]) & (boxes[j, 0] <= boxes[i, 1]))]
    assert meeting_pair(boxes) == (every[0] if every else None)


def test_padded_boxes_are_padded_box_one_by_one(monkeypatch):
    """The batch of line-and-circle solids (tools, tilted and cut ones among them) and the
    one-by-one path for the others give padded_box's very floats; only the others go one by one."""
    from coons.topology import disjoint
    from coons.tolerance import resolve

    t = resolve(None)
    tools = [Cylinder(1.0 + 0.1 * k, 3.0 + k).translate((5.0 * k, 0.3 * k, -0.7 * k)) for k in range(6)]
    tilted = Pos(1, 2, 3) * Rot(10, 20, 30) * Cylinder(1, 2)
    notched = Box(4, 4, 4) - Cylinder(1, 10).translate((2, 0, 0))  # arcs that are not half circles
    solids = parts() + tools + [tilted, Cone(1, 0.5, 2).translate((0, 40, 0)), notched]
    one_by_one = []
    monkeypatch.setattr(disjoint, "padded_box", lambda s, t: one_by_one.append(s) or padded_box(s, t))
    got = padded_boxes(solids, t)
    batched = tools + [tilted, solids[-2], notched]
    assert one_by_one and not any(s is u for s in one_by_one for u in batched)
    np.testing.assert_array_equal(got, np.stack([padded_box(s, t) for s in solids]))


def test_grid_of_cylinders():
    tools = [Cylinder(2, 20).translate((10.0 * i, 10.0 * j, 0.0)) for i in range(6) for j in range(6)]
    u = disjoint_union(tools)
    assert check(u.brep).ok
    assert u.brep.n_solids == 36
    np.testing.assert_allclose(u.volume, 36 * np.pi * 4 * 20, rtol=RTOL)
