"""Edge matching in sewing: the vectorised common case (two uses with coincident midpoints) and the
cached curve samples give exactly the pairs of the general union–find path."""

from __future__ import annotations

import numpy as np

from coons.tolerance import resolve
from coons.topology import sew
from coons.topology._memo import LastRecord
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


# ---------------------------------------------------------------------- reach shortcut
import math  # noqa: E402

from hypothesis import given, settings  # noqa: E402
from hypothesis import strategies as st  # noqa: E402

from coons.kernel.analytic import Circle, Line  # noqa: E402
from coons.kernel.curve import NurbsCurve  # noqa: E402


def _uses_of(curves_ranges, t):
    """A _Uses over single-use loops (only the per-use arrays are read by the matching helpers)."""
    faces = [sew.FaceSpec(None, True, [[sew.EdgeSpec(c, a, b, None, tol)]]) for c, a, b, tol in curves_ranges]
    return sew._Uses(faces, t)


@settings(max_examples=60)
@given(
    st.lists(st.floats(0.0, 2 * math.pi), min_size=2, max_size=6),
    st.floats(1e-3, 1e3),
    st.tuples(st.floats(-1e3, 1e3), st.floats(-1e3, 1e3), st.floats(-1e3, 1e3)),
    st.floats(-1e2, 1e2),
    st.sampled_from([None, 1e-9, 1e-4, 0.5]),
)
def test_reach_shortcut_gives_the_measured_verdict(cuts, r, centre, shift, tol):
    # Arcs of one circle (and of a copy turned by ``shift``) and chords between them: every pair
    # decided by the shortcut must be decided the same way by the measurement.
    t = resolve(None)
    angles = sorted(set(cuts))
    c1 = Circle(centre, (0.0, 0.0, 1.0), (1.0, 0.0, 0.0), r)
    items = []
    for a, b in zip(angles, angles[1:]):
        if b - a > 1e-9:
            items.append((c1, a, b, tol))
            items.append((c1, b + shift * 1e-12, a, tol))  # nearly the same range, reversed
            p, q = np.asarray(c1.evaluate(a)), np.asarray(c1.evaluate(b))
            if np.linalg.norm(q - p) > 0:
                items.append((Line(p, q - p), 0.0, float(np.linalg.norm(q - p)), tol))
    items.append((Line(centre, (1.0, 0.0, 0.0)), shift, shift + r, tol))
    items.append((Line(centre, (0.0, 1.0, 0.0)), -r, r, tol))
    uses = _uses_of(items, t)
    reach = sew._reach(uses, np.arange(len(uses)))
    for i in range(len(uses)):
        for j in range(len(uses)):
            if i != j:
                assert sew._curves_agree(uses, i, j, {}, reach) == sew._curves_agree(uses, i, j, {})


def test_reach_is_unbounded_for_other_curves_and_unlisted_uses():
    t = resolve(None)
    nc = NurbsCurve(np.array([[0.0, 0, 0], [1, 1, 0], [2, 0, 0]]), [0, 0, 0, 1, 1, 1], 2)
    line = Line((0.0, 0, 0), (1.0, 0, 0))
    uses = _uses_of([(nc, 0.0, 1.0, None), (line, 0.0, 2.0, None), (line, 2.0, 0.0, None)], t)
    radius, scale = sew._reach(uses, np.array([0, 1]))
    assert math.isinf(radius[0]) and math.isinf(scale[0])  # no bound for a NURBS curve
    assert radius[1] == 1.0 and math.isfinite(scale[1])
    assert math.isinf(radius[2])  # not asked for


def test_reach_matching_equals_matching_without_it():
    # The plate-with-holes groups of four (two half circles each used twice) through the
    # union-find with and without the shortcut.
    holes = [Profile.circle(0.4 + 0.1 * i, center=(-4.0 + 2.0 * i, 0.5 * (i % 2))).outer for i in range(5)]
    solid = extrude(Profile(Profile.rectangle(12.0, 4.0).outer, holes), 2.0)
    t = resolve(None)
    uses = sew._Uses(sew.face_specs(solid.brep), t)
    vertex, _, _ = sew._merge_vertices(uses, t)
    reach = sew._reach(uses, np.arange(len(uses)))
    vs, ve = vertex[:, 0], vertex[:, 1]
    lo, hi = np.minimum(vs, ve), np.maximum(vs, ve)
    n4 = 0
    for key in sorted(set(zip(lo.tolist(), hi.tolist()))):
        group = np.flatnonzero((lo == key[0]) & (hi == key[1])).tolist()
        n4 += len(group) == 4
        assert sew._agreeing_components(uses, group, {}, reach) == sew._agreeing_components(uses, group)
    assert n4 >= 5


def test_reach_shortcut_spares_the_measurements_of_hole_halves(monkeypatch):
    holes = [Profile.circle(0.5, center=(-3.0 + 3.0 * i, 0.0)).outer for i in range(3)]
    solid = extrude(Profile(Profile.rectangle(12.0, 4.0).outer, holes), 2.0)
    t = resolve(None)
    specs = sew.face_specs(solid.brep)
    calls = []
    real = sew._distance_to_curve
    monkeypatch.setattr(sew, "_distance_to_curve", lambda *a, **k: calls.append(1) or real(*a, **k))
    uses = sew._Uses(specs, t)
    vertex, vpoint, _ = sew._merge_vertices(uses, t)
    got = sew._match_edges(uses, vertex, vpoint, t)
    assert not calls  # every pair of different half circles was told apart by the bound
    np.testing.assert_array_equal(got, general_pairs(uses, vertex))
    assert calls  # the general path measures them


# ---------------------------------------------------------------------- groups of four at once
import pytest  # noqa: E402

from coons.errors import TopologyError  # noqa: E402


def _holed_plate(radii, xs, ys):
    holes = [Profile.circle(r, center=(x, y)).outer for r, x, y in zip(radii, xs, ys)]
    return extrude(Profile(Profile.rectangle(40.0, 40.0).outer, holes), 2.0)


@settings(max_examples=25, deadline=None)
@given(st.lists(st.tuples(st.floats(0.05, 1.4), st.floats(-0.5, 0.5), st.floats(-0.5, 0.5)), min_size=1, max_size=8))
def test_groups_of_four_match_as_the_general_path(holes):
    # Hole i sits in its own 4 x 4 cell, at most 0.5 off its centre: radii below 1.5 never overlap.
    radii = [h[0] for h in holes]
    xs = [-16.0 + 4.0 * (i % 8) + h[1] for i, h in enumerate(holes)]
    ys = [-16.0 + 4.0 * (i // 8) + h[2] for i, h in enumerate(holes)]
    solid = _holed_plate(radii, xs, ys)
    t = resolve(None)
    uses = sew._Uses(sew.face_specs(solid.brep), t)
    vertex, vpoint, _ = sew._merge_vertices(uses, t)
    np.testing.assert_array_equal(sew._match_edges(uses, vertex, vpoint, t), general_pairs(uses, vertex))


def test_groups_of_four_with_a_wrong_way_use_raise_the_general_message(monkeypatch):
    solid = _holed_plate([0.5, 0.7], [-5.0, 5.0], [0.0, 1.0])
    specs = sew.face_specs(solid.brep)
    # Reverse every loop of the first face that holds a circle: a hole half then runs the same way
    # as its twin (inconsistent orientation inside a group of four).
    for k, f in enumerate(specs):
        if any(type(e.curve).__name__ == "Circle" for loop in f.loops for e in loop):
            loops = [[sew.EdgeSpec(e.curve, e.t1, e.t0, e.pcurve, e.tol) for e in reversed(loop)] for loop in f.loops]
            specs[k] = sew.FaceSpec(f.surface, not f.sense, loops)
            break
    with pytest.raises(TopologyError) as fast:
        sew.sew_faces(specs)
    monkeypatch.setattr(sew, "_match_fours", lambda uses, vertex, closed, G, reach: (
        np.empty((0, 2), np.int64), np.zeros(G.shape[0], bool)))
    with pytest.raises(TopologyError) as general:
        sew.sew_faces(specs)
    assert str(fast.value) == str(general.value)


def test_boolean_results_have_the_tables_of_the_old_paths(monkeypatch):
    # A plate minus cylinders (sewing with hole halves in groups of four) and sphere + sphere:
    # the B-rep tables with every new shortcut of sewing and assembly disabled are the same.
    import dataclasses

    import coons
    from coons.topology.builder import BRepBuilder

    def cases():
        plate = coons.Box(12, 12, 2)
        tools = [coons.Cylinder(0.5 + 0.1 * i, 4).translate((-4.0 + 4.0 * (i % 3), -4.0 + 4.0 * (i // 3), 0.0))
                 for i in range(6)]
        return [coons.difference(plate, *tools), (plate - tools[0]) - tools[4],
                coons.Sphere(5) + coons.Sphere(5).translate((4.0, 2.0, 0.5))]

    fast = cases()
    k = lambda uses, rows: (np.full(len(uses), math.inf), np.full(len(uses), math.inf))  # noqa: E731
    monkeypatch.setattr(sew, "_reach", k)
    monkeypatch.setattr(sew, "_match_fours", lambda uses, vertex, closed, G, reach: (
        np.empty((0, 2), np.int64), np.zeros(G.shape[0], bool)))
    monkeypatch.setattr(BRepBuilder, "_assemble_loops_bulk", lambda *a, **kw: None)
    monkeypatch.setattr(sew, "assembled_brep", lambda *a, **kw: None)
    old = cases()
    for a, b in zip(fast, old):
        for fld in dataclasses.fields(a.brep):
            x, y = getattr(a.brep, fld.name), getattr(b.brep, fld.name)
            if isinstance(x, np.ndarray):
                np.testing.assert_array_equal(x, y, err_msg=fld.name)
        assert a.brep.n_faces == b.brep.n_faces and np.isclose(a.volume, b.volume, rtol=1e-12, atol=0.0)


# ---------------------------------------------------------------------- per-face use tables
class _Wrapped:
    """A curve that is not a value (not a frozen dataclass): what is computed from it is not remembered."""

    def __init__(self, curve):
        self.curve = curve

    def evaluate(self, t):
        return self.curve.evaluate(t)


def test_face_use_tables_are_the_uses_points_and_are_remembered_per_face_spec():
    from coons.topology import _memo
    from coons.topology.primitives import Box, Cylinder, Sphere

    _memo.clear_all()
    specs = sew.face_specs(Cylinder(1.0, 2.0).brep) + sew.face_specs(Sphere(0.5).brep)
    first = sew._face_uses(specs)
    again = sew._face_uses(specs)
    assert all(x is y for x, y in zip(first, again))  # remembered, not recomputed
    for f, x in zip(specs, first):
        uses = [e for loop in f.loops for e in loop]
        assert x.where.tolist() == [[li, pi, len(loop)] for li, loop in enumerate(f.loops) for pi in range(len(loop))]
        np.testing.assert_array_equal(x.ranges, [[e.t0, e.t1, e.tol or 0.0] for e in uses])
        for e, P in zip(uses, x.points):
            np.testing.assert_array_equal(P, e.curve.evaluate(np.array([e.t0, e.t1, 0.5 * (e.t0 + e.t1)])))
    box = sew.face_specs(Box(1, 2, 3).brep)
    odd = sew.FaceSpec(box[0].surface, box[0].sense,
                       [[sew.EdgeSpec(_Wrapped(e.curve), e.t0, e.t1, e.pcurve, e.tol) for e in box[0].loops[0]]])
    x, y = sew._face_uses([odd]), sew._face_uses([odd])
    assert x[0] is not y[0]  # not a value: computed each time
    np.testing.assert_array_equal(x[0].points, sew._face_uses([box[0]])[0].points)
    resewn = sew.sew_faces([odd] + box[1:])
    np.testing.assert_allclose(resewn.volume, 6.0, rtol=1e-14)


@settings(max_examples=40)
@given(st.lists(st.tuples(st.integers(0, 5), st.integers(0, 5), st.floats(0.0, 2e-3)), min_size=1, max_size=30),
       st.integers(0, 2**31 - 1))
def test_merge_vertices_clusters_as_all_pairs_do(ends, seed):
    """Vertices of use ends: connected components of ends within the larger of their two tolerances,
    numbered by first appearance (ends at one exact point are clustered once)."""
    rng = np.random.default_rng(seed)
    grid = np.array([(a, b, 0.0) for a, b, _ in ends]) * 1e-3  # many exact repeats, some within tolerance
    k = len(ends)
    start = grid + (rng.random((k, 1)) < 0.3) * rng.normal(0, 5e-4, (k, 3))
    end = start[rng.permutation(k)]
    tol = np.maximum([tl for _, _, tl in ends], 1e-7)

    class Uses:  # only the arrays _merge_vertices reads
        def __len__(self):
            return k

    uses = Uses()
    uses.start, uses.end, uses.tol = start, end, tol
    t = resolve(None)
    vertex, points, tols = sew._merge_vertices(uses, t)
    X = np.concatenate([start, end])
    ptol = np.concatenate([tol, tol])
    n = X.shape[0]
    near = np.linalg.norm(X[:, None] - X[None], axis=-1) <= np.maximum(ptol[:, None], ptol[None])
    label = np.arange(n)
    for _ in range(n):  # transitive closure by repeated min over neighbours
        label = np.array([label[near[i]].min() for i in range(n)])
    order = np.concatenate([np.arange(k) * 2, np.arange(k) * 2 + 1])
    first = {}
    for pos in np.argsort(order, kind="stable"):
        first.setdefault(int(label[pos]), len(first))
    expect = np.array([first[int(x)] for x in label])
    np.testing.assert_array_equal(vertex, np.stack([expect[:k], expect[k:]], axis=1))
    assert points.shape == (len(first), 3) and np.all(tols >= t.linear)


# ---------------------------------------------------------------- trusted spec constructors
from coons import Box, Cylinder, Sphere, Torus  # noqa: E402
from coons.errors import InvalidInputError  # noqa: E402


def _fields(spec: sew.FaceSpec) -> tuple:
    return (spec.surface, spec.sense, tuple(tuple((e.curve, e.t0, e.t1, e.pcurve, e.tol) for e in loop)
                                            for loop in spec.loops))


def test_trusted_specs_equal_the_validated_ones_field_by_field():
    """face_specs builds its specs without re-validation: they equal what the validating
    constructors make of the same fields (types included), on the whole B-rep and on rows."""
    for shape in (Box(1, 2, 3), Cylinder(2, 5), Sphere(3), Torus(5, 1), Box(10, 10, 10) - Cylinder(3, 20)):
        specs = sew.face_specs(shape)
        for spec in specs:
            again = sew.FaceSpec(spec.surface, spec.sense,
                                 [[sew.EdgeSpec(e.curve, e.t0, e.t1, e.pcurve, e.tol) for e in loop]
                                  for loop in spec.loops])
            got, want = _fields(spec), _fields(again)
            assert got[0] is want[0] and got[1] == want[1] and type(got[1]) is bool and type(spec.loops) is tuple
            for a, b in zip(got[2], want[2], strict=True):
                for x, y in zip(a, b, strict=True):
                    assert x[0] is y[0] and x[3] is y[3]
                    assert [type(v) for v in x[1:3] + x[4:]] == [type(v) for v in y[1:3] + y[4:]]
                    assert x[1:3] + x[4:] == y[1:3] + y[4:]
        # A subset of rows reads the arrays in place and gives the same fields (straight edges
        # without a curve get a fresh Line per call, so compare curves by type and parameters).
        rows = list(range(shape.brep.n_faces))[::-1]
        for a, b in zip(sew.face_specs(shape, rows=rows), [specs[r] for r in rows], strict=True):
            assert a.surface is b.surface and a.sense == b.sense
            for la, lb in zip(a.loops, b.loops, strict=True):
                def key(loop):
                    return [(e.t0, e.t1, e.tol, type(e.curve)) for e in loop]

                assert key(la) == key(lb)


def test_face_specs_still_rejects_a_degenerate_edge_range():
    import dataclasses

    b = Cylinder(1, 2).brep
    r = b.edge_range.copy()
    r[0, 1] = r[0, 0]
    bad = dataclasses.replace(b, edge_range=r)
    with pytest.raises(InvalidInputError, match="finite, different parameters"):
        sew.face_specs(bad)


@pytest.mark.parametrize("bad", [-1e-9, math.nan, math.inf])
def test_face_specs_still_rejects_a_bad_edge_tolerance(bad):
    """face_specs checks each edge in place of EdgeSpec's constructor; a failure raises the constructor's message."""
    import dataclasses

    b = Cylinder(1, 2).brep
    tol = b.edge_tol.copy()
    tol[1] = bad
    with pytest.raises(InvalidInputError, match="EdgeSpec.tol must be a finite number >= 0"):
        sew.face_specs(dataclasses.replace(b, edge_tol=tol))


def _brep_tables(b) -> dict:
    """Every table of a B-rep, and its pools as object identities (pool order included)."""
    out = {k: np.asarray(v) for k, v in vars(b).items() if isinstance(v, np.ndarray)}
    for pool in ("surfaces", "curves", "pcurves"):
        out[pool] = np.array([id(x) for x in getattr(b, pool)], dtype=np.int64)
    return out


def test_bulk_assembly_equals_the_per_coedge_path(monkeypatch):
    # Sewing builds a one-shell B-rep from arrays (builder.assembled_brep); the builder, which it
    # falls back to, assembles its faces, loops and coedges in array passes
    # (BRepBuilder._assemble_loops_bulk, the faces in bulk too); the per-coedge assembly must
    # build the very same B-rep as both.
    from coons.topology import builder

    holes = [Profile.circle(0.5, center=(-4.0 + 1.5 * i, 0.0)).outer for i in range(6)]
    solid = extrude(Profile(Profile.rectangle(12.0, 4.0).outer, holes), 2.0)
    specs = sew.face_specs(solid.brep)
    direct = sew.sew_faces(specs).brep
    direct_tables = _brep_tables(direct)
    monkeypatch.setattr(sew, "assembled_brep", lambda *a, **kw: None)
    taken = []
    bulk = builder.BRepBuilder._assemble_loops_bulk

    def spy(self, *args):
        taken.append(bulk(self, *args))
        return taken[-1]

    monkeypatch.setattr(builder.BRepBuilder, "_assemble_loops_bulk", spy)
    fast = _brep_tables(sew.sew_faces(specs).brep)
    assert len(taken) == 1 and taken[0] == list(range(len(specs)))  # the bulk path, every face

    class PerCoedge(builder.BRepBuilder):
        def _assemble_loops_bulk(self, *args):
            return None

    monkeypatch.setattr(sew, "BRepBuilder", PerCoedge)
    slow_brep = sew.sew_faces(specs).brep
    slow = _brep_tables(slow_brep)
    assert fast.keys() == slow.keys() == direct_tables.keys()
    for k in fast:
        np.testing.assert_array_equal(fast[k], slow[k], err_msg=k)
        np.testing.assert_array_equal(direct_tables[k], slow[k], err_msg=k)  # pools as identities too



def test_pooled_is_the_builders_pool_order():
    # builder._pooled (an empty pool filled in array passes) gives the pool and indices of
    # pooling the objects one by one: first-seen order by identity, None as -1.
    from coons.topology import builder

    objs = [object() for _ in range(5)]
    rng = np.random.default_rng(7)
    for _ in range(20):
        seq = [None if k == 5 else objs[k] for k in rng.integers(0, 6, size=int(rng.integers(0, 12))).tolist()]
        b = builder.BRepBuilder()
        one = [b._pool("curves", x) for x in seq]
        pool, idx, ids, order = builder._pooled(seq)
        assert idx.tolist() == one and [id(x) for x in pool] == [id(x) for x in b.curves]
        # the pool's ids and their stable sorting order (what _memo.seed_pool_ids is given)
        assert ids.dtype == np.uint64 and ids.tolist() == [id(x) for x in pool]
        np.testing.assert_array_equal(order, np.argsort(ids, kind="stable"))
        b2 = builder.BRepBuilder()
        assert b2._pool_many("curves", seq) == one and [id(x) for x in b2.curves] == [id(x) for x in b.curves]
        assert b2._pool_many("curves", seq) == one  # (a pool with entries)


def test_several_shells_are_assembled_by_the_builder(monkeypatch):
    # Two disjoint boxes are two shells (which sewing may nest): the array path declines and the
    # builder assembles them, as before.
    import coons
    from coons.topology import builder

    specs = sew.face_specs(coons.Box(1, 1, 1)) + sew.face_specs(coons.Box(1, 1, 1).translate((3, 0, 0)))
    answers = []
    direct = builder.assembled_brep

    def spy(*a, **kw):
        answers.append(direct(*a, **kw))
        return answers[-1]

    monkeypatch.setattr(sew, "assembled_brep", spy)
    b = sew.sew_faces(specs).brep
    assert answers == [None] and b.n_shells == 2 and b.n_solids == 2
    assert sew.sew_faces(sew.face_specs(coons.Box(1, 2, 3))).brep.n_shells == 1 and answers[-1] is not None


def _uses_columns(u) -> dict:
    cols = {c: np.asarray(x) for c, x in zip(sew._COLUMNS, u.columns)}
    for c in ("spec", "curve", "pcurve"):  # object columns: the very objects (their ids)
        assert cols[c].dtype == object and not cols[c].flags.writeable
        cols[c] = np.array([id(e) for e in cols[c]], dtype=np.int64)
        cols[c].setflags(write=False)
    assert cols["spec"].tolist() == [id(e) for e in u.spec]
    assert cols["curve"].tolist() == [id(e.curve) for e in u.spec] == cols["curve_id"].tolist()
    assert cols["pcurve"].tolist() == [id(e.pcurve) for e in u.spec] == cols["pcurve_id"].tolist()
    cols["values"] = np.asarray(u.values)
    for name in ("face", "loop", "pos", "loop_len", "t0", "t1", "tol", "start", "end", "mid", "next"):
        cols[name] = np.asarray(getattr(u, name))
    return cols


def test_uses_gathered_from_the_last_sewing_equal_the_per_face_tables(monkeypatch):
    # The faces of the last sewing take their use rows from its columns in one take
    # (_gathered_uses); the arrays equal those built from the per-face tables, and only the
    # faces it did not have, or whose curves are not values, go through _face_uses.
    t = resolve(None)
    box = sew.face_specs(Box(1, 2, 3).brep)
    odd = sew.FaceSpec(box[0].surface, box[0].sense,
                       [[sew.EdgeSpec(_Wrapped(e.curve), e.t0, e.t1, e.pcurve, e.tol) for e in box[0].loops[0]]])
    first = [odd] + box[1:]
    kept = sew.sew_faces(first)  # the last sewing (kept alive: its record lives with it)
    others = sew.face_specs(Cylinder(1.0, 2.0).translate((5.0, 0.0, 0.0)).brep)
    faces = [others[0], first[3], odd, first[1]] + others[1:] + [first[5], first[2]]
    asked = []
    real = sew._face_uses

    def spy(fs, values=None):
        asked.append([id(f) for f in fs])
        return real(fs, values)

    monkeypatch.setattr(sew, "_face_uses", spy)
    fast = _uses_columns(sew._Uses(faces, t))
    assert sorted(asked[-1]) == sorted(id(f) for f in [odd] + others)  # the rest from the record
    monkeypatch.setattr(sew, "_SEWN_USES", LastRecord())  # no record: every face from its table
    slow = _uses_columns(sew._Uses(faces, t))
    assert len(asked[-1]) == len(faces)
    assert fast.keys() == slow.keys()
    for k in fast:
        assert fast[k].dtype == slow[k].dtype, k
        np.testing.assert_array_equal(fast[k], slow[k], err_msg=k)
    assert not fast["values"][2] and fast["values"][[0, 1, 3]].all()
    # The columns become the next sewing's source rows (_SEWN_USES): read-only on either path.
    for cols in (fast, slow):
        assert not any(cols[c].flags.writeable for c in sew._COLUMNS)
    assert kept.brep.n_faces == 6



def test_seeded_pool_ids_are_the_computed_ones():
    # assembled_brep hands _memo the ids its pools were sorted by (seed_pool_ids); the tables
    # _pool_ids gives from a seed equal those it computes from the pool, values only.
    import dataclasses

    from coons import Box, Cylinder
    from coons.topology import _memo, builder

    b = (Box(10, 10, 10) - Cylinder(3, 20).translate((0, 0, -5))).brep
    # (seeds not read yet, and tables already read from them)
    seeded = {**(_memo._POOL_SEEDS.get(b) or {}), **(_memo._POOL_IDS.get(b) or {})}
    assert all(k in seeded for k in ("surfaces", "curves", "pcurves"))
    for name in ("surfaces", "curves", "pcurves"):
        got = _memo._pool_ids(b, name)
        del _memo._POOL_IDS.get(b)[name]
        again = _memo._pool_ids(b, name)  # computed from the pool
        pool, _, ids, order = builder._pooled(getattr(b, name))
        assert [id(x) for x in pool] == [id(x) for x in getattr(b, name)]
        del _memo._POOL_IDS.get(b)[name]
        _memo.seed_pool_ids(b, name, ids, order)
        for x, y, z in zip(got, again, _memo._pool_ids(b, name)):
            np.testing.assert_array_equal(x, y)
            np.testing.assert_array_equal(x, z)

    # A pool with objects that are not values: the seed is filtered as the pool would be.
    @dataclasses.dataclass
    class Mutable:
        x: int

    @dataclasses.dataclass(frozen=True)
    class Holder:
        probe: tuple

    values = list(b.curves[:4])
    objs = [Mutable(k) if k % 2 else values[k // 2] for k in range(8)]
    pool, _, ids, order = builder._pooled(objs + objs[::-1])
    seeded_holder, plain_holder = Holder(tuple(pool)), Holder(tuple(pool))
    _memo.seed_pool_ids(seeded_holder, "probe", ids, order)
    got, again = _memo._pool_ids(seeded_holder, "probe"), _memo._pool_ids(plain_holder, "probe")
    assert got[1].size == 4
    for x, y in zip(got, again):
        np.testing.assert_array_equal(x, y)


# ---------------------------------------------------------------------- face_specs of many B-reps
def _same_specs(got: list, want: list, fresh_lines: bool = False) -> None:
    """Field by field; with ``fresh_lines``, curves made anew (Lines of curve-less edges) by type and parameters."""
    assert len(got) == len(want)
    for a, b in zip(got, want, strict=True):
        fa, fb = _fields(a), _fields(b)
        assert fa[0] is fb[0] and fa[1] is fb[1]
        for la, lb in zip(fa[2], fb[2], strict=True):
            for x, y in zip(la, lb, strict=True):
                if fresh_lines and isinstance(x[0], Line):
                    assert type(x[0]) is type(y[0]) and np.array_equal(x[0].origin, y[0].origin)
                else:
                    assert x[0] is y[0]
                assert x[3] is y[3] and x[1:3] + x[4:] == y[1:3] + y[4:]
                assert [type(v) for v in x[1:3] + x[4:]] == [type(v) for v in y[1:3] + y[4:]]


def test_face_specs_many_equals_face_specs_and_walks_a_repeated_primitive_once(monkeypatch):
    import trimesh

    from coons.topology.from_mesh import from_mesh

    mesh = from_mesh(trimesh.creation.box())  # (edges without curves: a new Line per edge and call)
    holes = [Cylinder(2, 20).translate((10.0 * i, 3.0 * i, 0)) for i in range(5)]
    shapes = holes[:2] + [Box(1, 2, 3), Sphere(3), mesh, Torus(5, 1)] + holes[2:] + [
        Box(10, 10, 10) - Cylinder(3, 20), Cylinder(2.5, 20), mesh, Box(4, 5, 6)]
    want = [sew.face_specs(s) for s in shapes]
    walks = []
    real = sew.face_specs
    monkeypatch.setattr(sew, "face_specs", lambda b, rows=None: walks.append(b) or real(b, rows))
    got = sew.face_specs_many([s.brep for s in shapes])
    for g, w, s in zip(got, want, shapes, strict=True):
        _same_specs(g, w, fresh_lines=s is mesh)
    # One walk per distinct set of tables (the five holes, the two boxes of other sizes ... apart);
    # the mesh's plan is refused (its lines are new per call), so it is walked both times.
    walked = [id(b) for b in walks]
    assert walked.count(id(holes[0].brep)) == 1 and all(id(h.brep) not in walked for h in holes[1:])
    assert walked.count(id(mesh.brep)) == 2 and len(walks) == len(shapes) - 4


def test_face_specs_many_checks_the_curves_it_puts_in():
    import dataclasses

    a, b = Cylinder(1, 2), Cylinder(1, 2).translate((5, 0, 0))
    bad = dataclasses.replace(b.brep, curves=(object(),) + tuple(b.brep.curves[1:]))
    with pytest.raises(InvalidInputError, match="evaluate"):
        sew.face_specs(bad)
    with pytest.raises(InvalidInputError, match="evaluate"):
        sew.face_specs_many([a.brep, bad])


def test_face_specs_many_refuses_a_plan_from_a_pool_holding_one_object_twice():
    """A first B-rep whose curve pool holds one object at two positions cannot lend its walk to a second
    with the same tables and distinct objects (both uses would take one of them)."""
    import dataclasses

    first, second = Cylinder(1, 2).brep, Cylinder(1, 2).brep  # (the same tables, distinct objects)
    assert first.curves[0] is not second.curves[0]
    c = first.curves
    twice = dataclasses.replace(first, curves=(c[0], c[0], *c[2:]))
    got = sew.face_specs_many([twice, second])
    _same_specs(got[1], sew.face_specs(second))
    assert any(e.curve is second.curves[1] for f in got[1] for l in f.loops for e in l)


def test_read_unchanged_faces_is_the_walk_over_face_specs():
    import trimesh

    from coons.topology.disjoint import stacked
    from coons.topology.from_mesh import from_mesh

    import dataclasses

    mesh = from_mesh(trimesh.creation.icosphere(subdivisions=1))
    cut = Box(10, 10, 10) - Cylinder(3, 20)
    box = Box(1, 2, 3).brep
    # One edge without its curve, one use without its p-curve: only their faces change.
    no_curve, no_pcurve = box.edge_curve.copy(), box.edge_pcurve.copy()
    no_curve[0] = -1
    no_pcurve[5, 1] = -1
    holed = [dataclasses.replace(box, edge_curve=no_curve), dataclasses.replace(box, edge_pcurve=no_pcurve)]
    for h in holed:
        assert 0 < sew.read_unchanged_faces(h).sum() < h.n_faces
    for b in (Box(1, 2, 3).brep, Cylinder(2, 5).brep, Sphere(3).brep, Torus(5, 1).brep, mesh.brep, cut.brep,
              stacked([Cylinder(1, 4).brep, mesh.translate((9, 0, 0)).brep, cut.translate((0, 30, 0)).brep]), *holed):
        want = sew.sewn_unchanged_faces(b, sew.face_specs(b), rows=range(b.n_faces))  # (the walk itself)
        got = sew.read_unchanged_faces(b)
        assert got.dtype == bool and np.array_equal(got, want)
    assert not sew.read_unchanged_faces(mesh.brep).any() and sew.read_unchanged_faces(cut.brep).all()


def test_remember_sewn_takes_known_flags_of_the_right_shape():
    from coons.topology.check import _SEWN_FROM
    from coons.topology.disjoint import stacked

    b = stacked([Cylinder(1, 4).brep, Cylinder(1, 4).translate((5, 0, 0)).brep])
    specs = sew.face_specs(b)
    sew.remember_sewn(b, specs, sew.read_unchanged_faces(b))
    assert sew.sewn_from(b) == tuple(specs) and _SEWN_FROM[b][1].all()
    with pytest.raises(InvalidInputError, match="flag"):
        sew.remember_sewn(b, specs, np.ones(b.n_faces - 1, dtype=bool))


def test_set_many_is_set_of_each():
    import gc

    from coons.topology._memo import IdentityMemo

    uses = [sew.EdgeSpec(Line(np.zeros(3), np.ones(3)), 0.0, float(k + 1)) for k in range(5)]
    one, many = IdentityMemo(), IdentityMemo()
    for e, v in zip(uses + uses[:1], list(range(5)) + ["last"]):
        one.set(e, v)
    many.set_many(uses + uses[:1], list(range(5)) + ["last"])
    assert [one.get(e) for e in uses] == [many.get(e) for e in uses] == ["last", 1, 2, 3, 4] and len(many) == 5
    with pytest.raises(TypeError, match="immutable"):
        many.set_many([uses[0], object()], [0, 1])
    del e, uses[3:]
    gc.collect()
    assert len(many) == 3  # (entries die with their objects)


def test_use_rows_evaluate_each_edge_once_and_equal_each_uses_own_row(monkeypatch):
    """_use_rows evaluates each distinct (curve, range) once for the uses of both ways round (a cut plate's
    edges, each used by two faces); every row equals, bit for bit, the row of its use computed alone, and
    uses whose ends differ only in the sign of a zero are not taken for one another."""
    from coons import Box, Cylinder, difference
    from coons.kernel import onsurface
    from coons.kernel.analytic import Circle, Line
    from coons.kernel.curve import NurbsCurve
    from coons.topology._memo import IdentityMemo

    plate = difference(Box(30, 30, 5), *[Cylinder(1.5, 10).translate((8.0 * i, 0, 0)) for i in (-1, 0, 1)])
    uses = [e for spec in sew.face_specs(plate.brep) for loop in spec.loops for e in loop]
    line = Line(np.zeros(3), np.array([1.0, 2.0, 0.0]))
    circle = Circle(np.array([1.0, 0, 0]), np.array([0, 0, 1.0]), np.array([1.0, 0, 0]), 2.0)
    nurbs = NurbsCurve(np.array([[0, 0, 0], [1, 2, 0], [3, 1, 1.0]]), [0, 0, 0, 1, 1, 1], 2)
    uses += [sew.EdgeSpec(line, 0.0, 1.5), sew.EdgeSpec(line, 1.5, 0.0, tol=1e-5), sew.EdgeSpec(circle, -0.0, 1.0),
             sew.EdgeSpec(circle, 1.0, 0.0), sew.EdgeSpec(circle, 2.0, 0.5), sew.EdgeSpec(nurbs, 0.9, 0.2)]
    w = np.zeros((len(uses), 4), dtype=np.int64)
    evaluated = []
    real = onsurface.curve_derivatives

    def spy(curves, T, *rest):
        evaluated.append(len(curves))
        return real(curves, T, *rest)

    monkeypatch.setattr(sew, "_USE_ROWS", IdentityMemo())
    monkeypatch.setattr(onsurface, "curve_derivatives", spy)
    rows = sew._use_rows(uses, w)
    simple = [e for e in uses if type(e.curve) in (Line, Circle)]
    # (one evaluation of the lines and circles, a row per distinct curve and ends, bit for bit)
    assert evaluated == [len({(id(e.curve), *(x.hex() for x in sorted((e.t0, e.t1)))) for e in simple})]
    assert evaluated[0] <= len(simple) // 2 + 4  # (the plate's edges: one evaluation for two uses)
    for i, e in enumerate(uses):
        monkeypatch.setattr(sew, "_USE_ROWS", IdentityMemo())
        alone = sew._use_rows([e], w[i:i + 1])
        np.testing.assert_array_equal(rows[i], alone[0])
        assert rows[i].tobytes() == alone[0].tobytes()  # (the sign of a zero too)


# ---------------------------------------------------------------------- vertex clusters
@pytest.mark.parametrize("seed", range(6))
def test_point_clusters_by_the_sweep_equal_those_by_the_kd_tree(seed, monkeypatch):
    """point_clusters finds its close pairs by a sweep along x (``_close_pairs``) unless too many pairs
    would be tried; the k-d tree path (``_SWEEP_PAIRS`` -1 forces it) must give the same labels, on
    points sharing whole coordinates (a grid, one z) with copies moved by about their tolerance."""
    rng = np.random.default_rng(seed)
    runs = []
    clouds = []
    for _ in range(40):
        n = int(rng.integers(1, 300))
        P = rng.integers(0, 5, (n, 3)).astype(float) * rng.choice([1.0, 2e-7])
        P[:, 0] = rng.integers(0, max(n // 4, 1), n)  # (about four points per x: the sweep's case)
        P[:, 2] *= rng.integers(0, 2)  # (one z for all, half of the clouds)
        P += (rng.random((n, 3)) < 0.3) * rng.normal(0.0, 1e-7, (n, 3))
        P = P * rng.choice([1.0, 1e3]) + rng.choice([0.0, 123.0])
        tol = rng.choice([1e-7, 2e-7, 5e-8], n) * rng.choice([1.0, 1e3])
        rank = rng.permutation(n) if n % 2 else None
        clouds.append((P, tol, rank))
    kd = []
    from scipy.spatial import cKDTree

    class Counted(cKDTree):
        def __init__(self, *a, **k):
            kd.append(1)
            super().__init__(*a, **k)

    monkeypatch.setattr("scipy.spatial.cKDTree", Counted)
    for sweep in (True, False):
        if not sweep:
            monkeypatch.setattr(sew, "_SWEEP_PAIRS", -1)
        runs.append([sew.point_clusters(P, tol, rank) for P, tol, rank in clouds])
        if sweep:
            assert len(kd) < len(clouds) // 2  # (most clouds swept)
    assert len(kd) >= len(clouds)  # (and then none)
    for a, b in zip(*runs):
        np.testing.assert_array_equal(a, b)
    assert any(np.unique(a).size < a.size for a in runs[0])  # (some points did merge)
