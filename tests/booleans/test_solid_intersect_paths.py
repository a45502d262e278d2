"""Phase 3 of the curved B-rep Booleans (``coons.booleans.solid._intersect``): its cheap paths give the general answers.

The clip, the cut-end tolerance, the cut-end check, the repeated-cut filter and the point-in-polygon
test each have a path in Python floats or with an early answer for the small inputs of a face crossed
by a few branches.  Each such path is compared here with the array path it stands for, on random
inputs (the same floats, or the same decision), and whole Booleans are run with the switchable paths
on and off: their cuts, links and results must be the same bit for bit.
"""

from __future__ import annotations

import hashlib
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from coons.booleans import classify as C
from coons.booleans import solid as S
from coons.kernel.analytic import Circle, Line
from coons.kernel.pcurve import Line2D
from coons.tolerance import resolve
from coons.topology.primitives import Box, Cylinder, Sphere
from coons.topology.sew import EdgeSpec

T = resolve(None)
_COORD = st.floats(-5, 5)
_POINT2 = st.tuples(_COORD, _COORD)


@settings(max_examples=80)
@given(ring=st.lists(_POINT2, min_size=1, max_size=12), points=st.lists(_POINT2, min_size=1, max_size=5),
       snap=st.booleans())
def test_point_in_polygon_in_floats_is_the_array_test(ring, points, snap):
    P = np.array(ring)
    uv = np.array(points)
    if snap:  # points and vertices on a half grid: rays through vertices, points on sides
        P, uv = np.round(P * 2) / 2, np.round(uv * 2) / 2
    seg = np.stack([P, np.roll(P, -1, axis=0)], axis=1)
    fast = C._in_polygon(uv, seg)
    with pytest.MonkeyPatch.context() as m:
        m.setattr(C, "_SCALAR_PAIRS", -1)
        slow = C._in_polygon(uv, seg)
    np.testing.assert_array_equal(fast, slow)


@settings(max_examples=80)
@given(p=st.lists(st.tuples(_COORD, _COORD, _COORD), min_size=2, max_size=6), scale=st.sampled_from([1e-6, 1.0, 1e4]))
def test_distance_is_numpys_norm_along_an_axis(p, scale):
    """``_distance`` is ``np.linalg.norm(p - q, axis=-1)`` bit for bit (numpy sums a short axis in order)."""
    P = np.array(p) * scale
    D = np.linalg.norm(P[:, None] - P[None], axis=-1)
    for i, a in enumerate(P.tolist()):
        for j, b in enumerate(P.tolist()):
            assert S._distance(a, b) == D[i, j]


def _sides(ring):
    P = np.array(ring)
    seg = np.stack([P, np.roll(P, -1, axis=0)], axis=1)
    A, E = seg[:, 0], seg[:, 1] - seg[:, 0]
    L = np.hypot(E[:, 0], E[:, 1])
    keep = L > 0.0
    return A[keep], E[keep], L[keep]


_GRID = st.integers(-5000, 5000).map(lambda k: k / 1000.0)  # (no subnormal products: no overflow in the divisions)
_GRID2 = st.tuples(_GRID, _GRID)


@settings(max_examples=150)
@given(ring=st.lists(_GRID2, min_size=3, max_size=10), p0=_GRID2, d=_GRID2.filter(lambda v: math.hypot(*v) > 1e-3),
       ends=st.tuples(st.floats(-3, 3), st.floats(0.01, 6)), snap=st.booleans())
def test_straight_crossings_in_floats_are_the_array_crossings(ring, p0, d, ends, snap):
    """``_straight_crossings`` finds the crossings of ``_straight_crossings_arrays`` and declines where it does."""
    if snap:
        ring = np.round(np.array(ring) * 2) / 2
    A, E, L = _sides(ring)
    if L.size == 0:
        return
    LL, V = L * L, np.concatenate([A, A + E])
    p0, d = np.array(p0), np.array(d)
    lo_t, hi_t = ends[0], ends[0] + ends[1]
    B = np.array([p0 + lo_t * d, p0 + hi_t * d])
    dn = math.hypot(*d)
    scale = 1.0 + max(float(np.max(np.abs(A))), float(np.max(np.abs(B))))
    margin = S._STRAIGHT_CLEARANCE * T.linear + 1e-12 * scale
    sides = list(zip(A.tolist(), E.tolist(), L.tolist(), LL.tolist()))
    fast = S._straight_crossings(sides, p0.tolist(), d.tolist(), B.tolist(), lo_t, hi_t, dn, margin,
                                 max(scale, 1.0 + float(np.max(np.abs(V)))))
    slow = S._straight_crossings_arrays(A, E, L, LL, V, p0, d, B, lo_t, hi_t, dn, margin)
    if fast is not S._UNDECIDED:
        assert fast == slow


@settings(max_examples=80)
@given(c=st.tuples(_COORD, _COORD, _COORD), r=st.floats(1e-8, 3), s0=st.floats(-7, 7),
       ds=st.sampled_from([0.0, 1e-9, 4.9e-8, 5e-8, 1e-7, 0.3, 7.0]), kind=st.sampled_from(["line", "circle"]))
def test_long_enough_in_floats_is_the_array_test(c, r, s0, ds, kind):
    curve = Line(c, [0.3, -0.4, 1.0]) if kind == "line" else Circle(c, [0.3, -0.4, 1.0], [1, 0, 0], r)
    s1 = s0 + (ds if kind == "circle" else ds * r)
    P = np.asarray(curve.evaluate(np.linspace(s0, s1, 5)))
    assert S._long_enough(curve, s0, s1, T) == bool(np.max(np.linalg.norm(P - P[0], axis=1)) > T.linear)


def _canon(x, signed: bool = True) -> str:
    """A canonical text of phase 3's output: floats in hex, arrays by their bytes, objects by their fields
    (``signed=False``: zeros without their signs)."""
    if isinstance(x, float):
        return float.hex(x if signed else x + 0.0)
    if isinstance(x, (bool, int, str, type(None))):
        return repr(x)
    if isinstance(x, np.generic):
        return _canon(x.item(), signed)
    if isinstance(x, np.ndarray):
        if not signed and x.dtype.kind == "f":
            x = x + 0.0  # (-0.0 + 0.0 is 0.0)
        return f"{x.dtype}{x.shape}" + hashlib.sha1(np.ascontiguousarray(x).tobytes()).hexdigest()
    if isinstance(x, (list, tuple)):
        return "[" + ",".join(_canon(y, signed) for y in x) + "]"
    if isinstance(x, dict):
        return "{" + ",".join(_canon(k, signed) + ":" + _canon(v, signed) for k, v in x.items()) + "}"
    fields = getattr(x, "__slots__", None) or sorted(vars(x))
    return type(x).__name__ + "(" + ",".join(f + "=" + _canon(getattr(x, f), signed) for f in fields
                                             if hasattr(x, f)) + ")"


def _phase3(a, b, signed: bool = True):
    """``_intersect``'s cuts and links of A = a, B = b (ids of curves replaced by their order)."""
    A, B = S._Operand(a, "A", T), S._Operand(b, "B", T)
    I, J = S._broad_phase(A, B)
    links: dict = {}
    cuts_a, cuts_b = S._intersect(A, B, I, J, T, links)
    return _canon([cuts_a, cuts_b, list(links.values())], signed)


CASES = {
    "box - cylinder": lambda: (Box(10, 10, 10), Cylinder(3, 20)),
    "plate - 3x3 holes": lambda: (Box(40, 40, 10), S._gathered(
        [Cylinder(2, 20).translate((-10.0 + 10 * i, -10.0 + 10 * j, 0)) for i in range(3) for j in range(3)], T)),
    "T-junction": lambda: (Cylinder(2, 20), Cylinder(1.5, 10, direction=(1, 0, 0)).translate((5, 0, 0))),
    "crossing cylinders": lambda: (Cylinder(2, 20), Cylinder(1.5, 20, direction=(1, 0, 0)).translate((0, 0, 1))),
    "sphere - sphere": lambda: (Sphere(5), Sphere(5).translate((4.0, 2.0, 0.5))),
    "tilted hole": lambda: (Box(10, 10, 4), Cylinder(1, 30, direction=(0.3, 0.2, 1.0)).translate((0.5, -0.5, 0))),
    "box - box": lambda: (Box(10, 10, 10), Box(4, 4, 20).translate((3, 1, 0))),
}


@pytest.mark.parametrize("name", list(CASES))
def test_phase_3_is_the_same_with_the_cheap_paths_switched_off(name):
    """Cuts, their tolerances and the links are bit for bit those of the array paths, the sampled orientation,
    the complete cut-end check and the k-d tree of repeated cuts."""
    import coons.kernel.intersect as I

    a, b = CASES[name]()
    decided = {"_uniform_side": 0, "_exact_runs": 0}
    with pytest.MonkeyPatch.context() as m:
        m.setattr(S, "_BATCHED_SECTIONS", 1 << 60)  # pair by pair (the batch: the next test)
        for fn in decided:
            real = getattr(I, fn)

            def spy(*args, _real=real, _fn=fn):
                got = _real(*args)
                decided[_fn] += got is not None
                return got

            m.setattr(I, fn, spy)
        fast = _phase3(a, b)
    # The cheap paths were taken, so the comparison below tests them (crossing cylinders have no
    # exact form: marched, neither applies); box - cylinder takes both.
    if name != "crossing cylinders":
        assert sum(decided.values()) > 0
    if name == "box - cylinder":
        assert all(decided.values())
    with pytest.MonkeyPatch.context() as m:
        m.setattr(S, "_BATCHED_SECTIONS", 1 << 60)
        m.setattr(I, "_uniform_side", lambda *args: None)
        m.setattr(I, "_exact_runs", lambda *args: None)
        for switch in ("_SCALAR_SIDES", "_SCALAR_CUTS", "_SCALAR_BOXES"):
            m.setattr(S, switch, -1)
        m.setattr(C, "_SCALAR_PAIRS", -1)
        m.setattr(S, "_check_cut_ends", S._check_cut_ends_all)
        S._FACE_DATA.clear()  # (the closed-form clip's per-face data is kept with the face's)
        slow = _phase3(a, b)
    assert fast == slow


@pytest.mark.parametrize("name", list(CASES))
def test_phase_3_is_the_same_with_the_batched_pairs_switched_off(name):
    """The batched plane-cylinder pairs (sections, clips, lengths and end tolerances in array passes) give the
    cuts, tolerances and links of the pair-by-pair path bit for bit on these cases up to the signs of zeros in
    the circles' frames (their expressions are the same; the batch promises agreement only to round-off), and
    take every plane-cylinder pair of a plate."""
    import coons.kernel.intersect as I

    a, b = CASES[name]()
    taken = []
    real = I._plane_cylinder_circles

    def spy(items, tol):
        got = real(items, tol)
        taken.extend(g is not None for g in got)
        return got

    per_pair = []
    real_pieces = S._branch_pieces

    def spy_pieces(*args, **kwargs):
        per_pair.append(1)
        return real_pieces(*args, **kwargs)

    with pytest.MonkeyPatch.context() as m:
        m.setattr(I, "_plane_cylinder_circles", spy)
        m.setattr(S, "_branch_pieces", spy_pieces)
        batched = _phase3(a, b, signed=False)
    if name in ("box - cylinder", "plate - 3x3 holes"):
        assert taken and all(taken)
        assert not per_pair  # (the batched pieces did not fall back to the per-pair path)
    with pytest.MonkeyPatch.context() as m:
        m.setattr(S, "_BATCHED_SECTIONS", 1 << 60)
        S._FACE_DATA.clear()
        single = _phase3(a, b, signed=False)
    assert batched == single


def test_cut_ends_found_on_the_boundary_need_no_check():
    """``_end_tolerance`` reports for each end a bound on its distance to the face's boundary that the complete
    check measures below: the ends of a box − cylinder cut on the cylinder lie on its seam and rims."""
    A, B = S._Operand(Box(10, 10, 10), "A", T), S._Operand(Cylinder(3, 20), "B", T)
    I, J = S._broad_phase(A, B)
    checked = []
    real = S._check_cut_ends_all

    def spy(X, f, cuts, Y, t):
        checked.append((X.name, f))
        return real(X, f, cuts, Y, t)

    with pytest.MonkeyPatch.context() as m:
        m.setattr(S, "_check_cut_ends_all", spy)
        cuts_a, cuts_b = S._intersect(A, B, I, J, T, {})
    assert not checked  # every end met another or was found on the boundary
    # The bound holds: each end of each cut on B's faces is within the complete check's reach.
    for f, cuts in cuts_b.items():
        for c in cuts:
            near = [[math.inf, math.inf], [math.inf, math.inf]]
            face_a = next(i for i in cuts_a if any(e.curve is c.curve for e in cuts_a[i]))
            S._end_tolerance(c, (c.t0, c.t1), (A.edge_boxes(face_a), B.edge_boxes(f)), T, near)
            P = np.asarray(c.curve.evaluate(np.array([c.t0, c.t1])))
            for p, bound in zip(P, near[1]):
                if not math.isfinite(bound):
                    continue
                best = min(float(np.linalg.norm(np.asarray(e.curve.evaluate(
                    np.clip(C._curve_closest(e.curve, p[None], min(e.t0, e.t1), T), min(e.t0, e.t1), max(e.t0, e.t1))
                )).reshape(3) - p)) for loop in B.specs[f].loops for e in loop)
                assert best <= bound


@settings(max_examples=40)
@given(n=st.integers(2, 6), gap=st.sampled_from([0.0, 1e-8, 3e-7, 1.0]), seed=st.integers(0, 2**16))
def test_apart_cuts_are_those_the_tree_pairs_none_of(n, gap, seed):
    """``_unique_cuts``'s early answer (no two midpoints near) is the k-d tree's: the same cuts, none repeated."""
    rng = np.random.default_rng(seed)
    cuts = []
    for k in range(n):
        o = rng.normal(size=3) if k == 0 or gap >= 1.0 else cuts[0].curve.origin + gap * rng.normal(size=3)
        cuts.append(EdgeSpec(Line(o, [1.0, 0.0, 0.0]), -1.0, 1.0, Line2D([0.0, 0.0], [1.0, 0.0]), None))
    repeated_fast: set = set()
    fast = S._unique_cuts(cuts, T, repeated_fast)
    repeated_slow: set = set()
    with pytest.MonkeyPatch.context() as m:
        m.setattr(S, "_SCALAR_CUTS", -1)
        slow = S._unique_cuts(cuts, T, repeated_slow)
    assert [id(c) for c in fast] == [id(c) for c in slow]
    assert repeated_fast == repeated_slow


def test_batched_straight_clips_are_the_single_ones():
    """``_clip_straight_many`` (break points, pieces and runs in arrays, the pieces' midpoints by ``_in_faces``)
    returns ``_clip_straight``'s clip for every branch, bit for bit, and declines where it declines: random
    straight p-curves, both ways round, across faces of a plate with square holes (several crossings each) and
    of a cylinder (a periodic surface, where an empty clip is left to the general path)."""
    from types import SimpleNamespace

    plate = Box(20, 20, 4)
    for x, y in ((-5.0, -5.0), (5.0, -5.0), (-5.0, 5.0), (5.0, 5.0)):
        plate = plate - Box(3, 3, 10).translate((x, y, 0.0))
    rng = np.random.default_rng(7)
    for solid in (plate, Cylinder(3, 10)):
        X = S._Operand(solid, "A", T)
        faces = [f for f in range(len(X.specs)) if S._straight_data(X, f, T) is not None]
        assert faces
        fs, pcs, brs = [], [], []
        for f in faces:
            (u0, u1), (v0, v1) = X.uv_box[f]
            for _ in range(40):
                o = rng.uniform([u0, v0], [u1, v1])
                d = rng.normal(size=2)
                if rng.random() < 0.3:  # along a parameter direction: through rows of hole sides
                    d[rng.integers(2)] = 0.0
                span = 2.0 * max(u1 - u0, v1 - v0) / float(np.hypot(*d))
                a, b = sorted(rng.uniform(-span, span, 2).tolist())
                if rng.random() < 0.5:
                    a, b = b, a
                fs.append(f)
                pcs.append(Line2D(o, d))
                brs.append(SimpleNamespace(t0=a, t1=b))
        many = S._clip_straight_many(X, fs, pcs, brs, T)
        single = [S._clip_straight(X, f, p, c.t0, c.t1, T) for f, p, c in zip(fs, pcs, brs)]
        assert many == single
        if solid is plate:  # (some branches leave and re-enter a face)
            assert sum(r is not None and len(r) > 1 for r in single) > 10


def test_batched_cuts_are_what_the_validating_constructor_makes():
    """The cuts of the batched plane-cylinder pairs, made by ``EdgeSpec._trusted``, have the fields the validating
    constructor would give them: Python floats, a finite non-empty range, a finite tolerance >= 0."""
    a, b = CASES["plate - 3x3 holes"]()
    A, B = S._Operand(a, "A", T), S._Operand(b, "B", T)
    I, J = S._broad_phase(A, B)
    cuts_a, cuts_b = S._intersect(A, B, I, J, T, {})
    cuts = [e for cuts in (cuts_a, cuts_b) for es in cuts.values() for e in es]
    assert len(cuts) == 72  # (9 holes' two walls, each cut by the plate's top and bottom: a cut on each operand)
    for e in cuts:
        assert type(e.t0) is float and type(e.t1) is float and type(e.tol) is float
        assert vars(EdgeSpec(e.curve, e.t0, e.t1, e.pcurve, e.tol)) == vars(e)  # (EdgeSpec compares by identity)


def test_open_cut_ends_in_arrays_are_the_per_cut_ones():
    """``_open_cut_ends`` of many cuts on lines and circles (ends, gaps and thresholds in arrays) gives the ends
    and thresholds of the per-cut path bit for bit, closed cuts and near ties included."""
    rng = np.random.default_rng(11)
    cuts = []
    for k in range(60):
        centre, axis = rng.uniform(-50, 50, 3), rng.normal(size=3)
        x = np.cross(axis, rng.normal(size=3))
        tol = [None, 0.0, 3e-7, 1e-5][k % 4]
        lim = max(T.linear, tol or 0.0)
        if k % 3 == 0:
            t0 = rng.uniform(-5, 5)
            # (a chord at the threshold within round-off: the near-tie branch; or plainly open)
            cuts.append(EdgeSpec(Line(centre, axis / np.linalg.norm(axis)), t0,
                                 t0 + (lim if k % 2 else rng.uniform(0.1, 9.0)), None, tol))
        else:
            t0 = rng.uniform(-7, 7)
            closed = k % 5 == 0
            cuts.append(EdgeSpec(Circle(centre, axis, x, rng.uniform(0.1, 5)), t0,
                                 t0 + (2.0 * math.pi if closed else rng.uniform(0.1, 6.0)), None, tol))
    assert len(cuts) > S._SCALAR_ENDS
    fast = S._open_cut_ends(cuts, T)
    with pytest.MonkeyPatch.context() as m:
        m.setattr(S, "_SCALAR_ENDS", 1 << 60)  # (every cut by the per-cut path)
        slow = S._open_cut_ends(cuts, T)
    assert fast == slow
    assert 0 < len(fast[0]) < 2 * len(cuts)  # (some cuts closed)


def test_batched_edge_boxes_are_each_faces():
    """``_Operand.fill_edge_boxes`` of many faces gives each face the uses, boxes and tolerances of its own
    computation, on faces of one loop and of many (a plate with holes)."""
    plate = Box(40, 40, 10) - Cylinder(2, 20).translate((5, 5, 0)) - Cylinder(2, 20).translate((-5, -5, 0))
    for solid in (plate, Cylinder(3, 10)):
        X = S._Operand(solid, "A", T)
        faces = list(range(len(X.specs)))
        for f in faces:
            X._data[f].edge_boxes = None
        X.fill_edge_boxes(faces)
        many = [X._data[f].edge_boxes for f in faces]
        assert any(len(X.specs[f].loops) > 1 for f in faces) or solid is not plate
        for f, got in zip(faces, many):
            X._data[f].edge_boxes = None
            one = X.edge_boxes(f)
            assert got[0] == one[0] and all(map(np.array_equal, got[1:], one[1:]))
            assert not any(a.flags.writeable for a in got[1:])


def test_apart_groups_in_arrays_are_the_pairwise_test():
    """``_apart_many`` (every pair of a group's midpoints at once, groups by size; a few groups in Python floats)
    answers, group by group, the pairwise test: no two midpoints within twice the group's widest cut tolerance."""
    rng = np.random.default_rng(13)
    groups = []
    for k in range(120):
        size = int(rng.integers(1, 7))
        base = rng.uniform(-9, 9, 3)
        g = []
        for i in range(size):
            # (near-repeats at about the threshold in some groups; far apart in others)
            o = base + (rng.choice([1e-7, 2e-7, 1.0]) if k % 2 else 5.0) * rng.normal(size=3)
            c = Circle(o, rng.normal(size=3), rng.normal(size=3), 1.0) if i % 2 else Line(o, [1.0, 0.0, 0.0])
            g.append(EdgeSpec(c, -0.5, 0.5, None, [None, 1e-7, 2e-7][(k + i) % 3]))
        groups.append(g)
    got = S._apart_many(groups, T)
    assert len(groups) > S._SCALAR_GROUPS
    with pytest.MonkeyPatch.context() as m:
        m.setattr(S, "_SCALAR_GROUPS", 1 << 60)
        assert S._apart_many(groups, T) == got  # (the Python floats' path for a few faces)
    expect = []
    for g in groups:
        r = 2.0 * max(max(T.linear, c.tol or 0.0) for c in g)
        m = [np.asarray(c.curve.evaluate(np.array([0.5 * (c.t0 + c.t1)]))).reshape(3).tolist() for c in g]
        expect.append(all(S._distance(p, q) > r for i, p in enumerate(m) for q in m[:i]))
    assert got == expect
    assert 0 < sum(got) < len(got)


def test_straight_data_of_many_faces_keeps_each_faces_sides():
    """``_prefill_straight`` of many faces at once gives each face its own sides' starts then ends ``V``
    (rows of one array for all faces), as stacked from that face's sides alone."""
    plate = Box(20, 20, 4)
    for x, y in ((-5.0, -5.0), (5.0, 5.0)):
        plate = plate - Box(3, 3, 10).translate((x, y, 0.0))
    for solid in (plate, Cylinder(3, 10)):
        X = S._Operand(solid, "A", T)
        for d in X._data:
            d.straight = None
        S._prefill_straight(X, list(range(len(X.specs))), T)
        data = [d.straight for d in X._data if d.straight]
        assert len(data) > 1
        for sp, A, E, L, LL, V, largest, sides, size in data:
            np.testing.assert_array_equal(V, np.concatenate([A, A + E]))
            assert not V.flags.writeable
            assert sides == list(zip(A.tolist(), E.tolist(), L.tolist(), LL.tolist()))


def test_phase_3_on_a_face_of_many_loops_reads_only_the_near_loops():
    """On a plate's face of more than ``_LOOPS_BOXED`` loops, the clear test, the point-in-face test and the end
    tolerances read only the loops whose boxes come near (``_near_loop_segments``, ``_near_loop_edges``): the
    cuts, tolerances and links are bit for bit those of every loop read, for a hole clear of the others, one
    passing within 0.2 of a hole, one cutting into a hole (cut ends on its edges) and a wide one across two holes."""
    plate = Box(60, 60, 10)
    for i in range(3):
        for j in range(3):
            plate = plate - Cylinder(2, 20).translate((-20.0 + 20 * i, -20.0 + 20 * j, 0.0))
    assert max(len(f.loops) for f in S._operand_specs(plate, "A", T)) > S._LOOPS_BOXED
    tools = [Cylinder(2, 20).translate((10.0, 10.0, 0.0)), Cylinder(2, 20).translate((4.2, 0.0, 0.0)),
             Cylinder(2, 20).translate((3.0, 0.0, 0.0)), Cylinder(9, 20).translate((10.0, 0.0, 0.0))]
    for tool in tools:
        taken = {"_near_loop_segments": 0, "_near_loop_edges": 0}
        with pytest.MonkeyPatch.context() as m:
            for fn in taken:
                real = getattr(S, fn)

                def spy(*args, _real=real, _fn=fn):
                    got = _real(*args)
                    taken[_fn] += not isinstance(got, slice)
                    return got

                m.setattr(S, fn, spy)
            S._FACE_DATA.clear()
            local = _phase3(plate, tool)
        assert taken["_near_loop_edges"] or taken["_near_loop_segments"]
        with pytest.MonkeyPatch.context() as m:
            m.setattr(S, "_LOOPS_BOXED", 1 << 60)  # (every loop of every face)
            S._FACE_DATA.clear()
            every = _phase3(plate, tool)
        assert local == every
