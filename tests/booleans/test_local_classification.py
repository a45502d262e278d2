"""Phase 5 of the curved Booleans: pieces classified locally at their cuts and by propagation.

:func:`coons.booleans.solid._classify` classifies a piece bounded by a transversal cut from the
first-order geometry at the cut (no point-in-solid query) and a face far from the other solid
from its neighbours.  These tests hold that to the point classification (one interior point per
piece against the other solid's classifier, the way every piece was classified before) on the
seeded pairs of primitives of the OCCT comparison and on hand-made cases, and check that the
common cases really take the local way.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from coons.booleans import solid as S
from coons.tolerance import resolve
from coons.topology.primitives import Box, Cylinder, Sphere, Torus
from tests.booleans.occt_cases import DEFAULT_PAIRS, EXTENDED_PAIRS


def _phases(a, b):
    """Phases 1-4 of the pipeline and both operands' pieces, as ``_boolean`` runs them."""
    t = resolve(None)
    A, B = S._Operand(a, "A", t), S._Operand(b, "B", t)
    I, J = S._broad_phase(A, B)
    links: dict = {}
    cuts_a, cuts_b = S._intersect(A, B, I, J, t, links)
    pa, pb = S._split(A, cuts_a, t), S._split(B, cuts_b, t)
    return t, A, B, I, J, links, (cuts_a, cuts_b), (pa, pb)


def _both_ways(a, b):
    """Per operand: the statuses of ``_classify`` and those of the point classification of every piece,
    and how many pieces were decided without a point."""
    t, A, B, I, J, links, cuts, pieces = _phases(a, b)
    out = []
    for side, (X, Y, idx) in enumerate(((A, B, I), (B, A, J))):
        ps = pieces[side]
        free = S._unpaired(len(X.specs), idx)
        status = S._classify(ps, X, Y, t, free=free, cuts=cuts[side], links=links, side=side)
        fast = np.full(len(ps), -1, dtype=np.int8)
        S._local_status(ps, Y, links, side, t, fast)
        S._propagate(ps, free, fast)
        dangling = S._dangling_cuts(ps, cuts[side])
        ref = S._classify_points(ps, list(range(len(ps))), X, Y, t, None, dangling)
        out.append((status, ref, int(np.count_nonzero(fast >= 0))))
    return out


@pytest.mark.parametrize("name", [p.name for p in DEFAULT_PAIRS]
                         + [pytest.param(p.name, marks=pytest.mark.slow) for p in EXTENDED_PAIRS])
def test_local_statuses_agree_with_point_classification(name):
    p = next(q for q in DEFAULT_PAIRS + EXTENDED_PAIRS if q.name == name)
    a, b = p.operands()
    for status, ref, _ in _both_ways(a, b):
        np.testing.assert_array_equal(status, ref)


def _cyl(r, h, at=(0.0, 0.0, 0.0), axis=(0.0, 0.0, 1.0)):
    return Cylinder(r, h, direction=axis).translate(at)


@pytest.mark.parametrize("case", ["box-cyl", "sphere-sphere", "cyl-cyl", "plate-holes"])
def test_transversal_cuts_need_no_point_classification(case):
    a, b = {
        "box-cyl": lambda: (Box(10, 10, 10), _cyl(3, 20)),
        "sphere-sphere": lambda: (Sphere(5), Sphere(5).translate((4.0, 2.0, 0.5))),
        "cyl-cyl": lambda: (_cyl(2, 20), _cyl(1.5, 20, (0, 0, 1), (1, 0, 0))),
        "plate-holes": lambda: (Box(40, 40, 10), S._gathered([_cyl(2, 20, (x, y, 0)) for x in (-10, 0, 10)
                                                              for y in (-10, 0, 10)], resolve(None))),
    }[case]()
    for status, ref, decided in _both_ways(a, b):
        np.testing.assert_array_equal(status, ref)
        assert decided == status.size  # every piece local or propagated: no point-in-solid query


def test_tangent_contact_falls_back_to_points():
    """A cylinder lying on a box face touches it along a line: that cut is not transversal, so the
    pieces it bounds are classified by a point (and the result is still right)."""
    box = Box(10, 10, 10)
    cyl = _cyl(2, 20, (0.0, 0.0, 7.0), (1, 0, 0))  # axis at z = 7, radius 2: tangent to the top z = 5
    out = _both_ways(box, cyl)
    for status, ref, decided in out:
        np.testing.assert_array_equal(status, ref)
    assert sum(decided for _, _, decided in out) < sum(s.size for s, _, _ in out)  # some pieces by a point
    assert (box + cyl).volume == pytest.approx(1000.0 + math.pi * 4 * 20, rel=1e-9)  # they only touch
    assert (box - cyl).volume == pytest.approx(1000.0, rel=1e-9)


def test_local_sign_follows_the_operation():
    """Union, intersection and difference of a torus and a sphere crossing its tube: the locally
    classified result satisfies vol(A ∪ B) + vol(A ∩ B) = vol(A) + vol(B) and vol(A − B) = vol(A) − vol(A ∩ B)."""
    a, b = Torus(3, 1), Sphere(1.5).translate((3.0, 0.0, 0.8))
    u, i, d = a + b, a & b, a - b
    # (the torus–sphere branches are marched and fitted: the 1e-7)
    assert u.volume + i.volume == pytest.approx(a.volume + b.volume, rel=1e-7)
    assert d.volume == pytest.approx(a.volume - i.volume, rel=1e-7)
    for status, ref, decided in _both_ways(a, b):
        np.testing.assert_array_equal(status, ref)
        assert decided > 0


def test_local_tests_on_a_face_of_many_loops_look_only_at_nearby_loops(monkeypatch):
    """On a plate face with more than _LOOPS_BOXED hole loops, the clearance test reads only the loops
    whose box comes near a point: the same answers as testing every segment of the face."""
    plate = Box(60, 60, 10)
    for x in (-20.0, -10.0, 0.0, 10.0, 20.0):
        for y in (-10.0, 10.0):
            plate = plate - Cylinder(2, 20).translate((x, y, 0))
    calls = []
    real = S._local_tests
    monkeypatch.setattr(S, "_local_tests", lambda cand, Y, t: calls.append((cand, Y, t)) or real(cand, Y, t))
    # (a hole 0.1 from the one at (0, -10): the clearance test near their loops rejects candidates)
    S.difference(plate, Cylinder(2, 20).translate((0.0, -5.9, 0.0)), method="brep")
    # (Y: the other operand of every candidate, or a list of each one's: both operands in one pass)
    busy = [c for c in calls if any(len((c[1][i] if isinstance(c[1], list) else c[1]).specs[k[4]].loops)
                                    > S._LOOPS_BOXED for i, k in enumerate(c[0]))]
    assert busy
    boxed = S._LOOPS_BOXED
    rejected = 0
    for cand, Y, t in calls:
        fast = real(cand, Y, t)
        monkeypatch.setattr(S, "_LOOPS_BOXED", 1 << 60)
        every = real(cand, Y, t)
        monkeypatch.setattr(S, "_LOOPS_BOXED", boxed)
        np.testing.assert_array_equal(fast[0], every[0])
        np.testing.assert_array_equal(fast[1], every[1])
        rejected += int((~every[0]).sum())
    assert rejected > 0  # the case the loop boxes must not lose is reached


def _eager_local_status(pieces, Y, links, side, t, status, cut=None):
    """The local way as it ran before its candidates were found round by round: every candidate of every
    piece first, then rounds of each undecided piece's next candidate (the reference of the test below)."""
    cand = []
    for k, (f, spec) in enumerate(pieces):
        if cut is not None and f not in cut:
            continue
        for loop in spec.loops:
            for e in loop:
                lo, hi = min(e.t0, e.t1), max(e.t0, e.t1)
                for ln in links.get(id(e.curve), ()):
                    a, b = max(lo, ln.s0), min(hi, ln.s1)
                    if ln.faces[side] == f and b > a:
                        cand.append((k, spec, e, 0.5 * (a + b), ln.faces[1 - side], ln.pcurves[1 - side]))
    of_piece: dict = {}
    for i, c in enumerate(cand):
        of_piece.setdefault(c[0], []).append(i)
    r = 0
    while True:
        rows = [got[r] for k, got in of_piece.items() if r < len(got) and status[k] < 0]
        if not rows:
            return len(cand)
        sub = [cand[i] for i in rows]
        ok, cos = S._local_tests(sub, Y, t)
        for c, good, x in zip(sub, ok.tolist(), cos.tolist()):
            if good and status[c[0]] < 0:
                status[c[0]] = S.IN if x < 0 else S.OUT
        r += 1


@pytest.mark.parametrize("case", ["plate-holes", "tangent"])
def test_local_candidates_found_round_by_round_as_all_at_once(monkeypatch, case):
    """_local_status reads each piece's candidates only as far as its rounds go (_piece_candidates): the
    same rounds, each testing the same candidates in the same order, and the same statuses as gathering
    every candidate first; on a plate drilled by many tools it reads fewer candidates than there are."""
    a, b = {
        "plate-holes": lambda: (Box(40, 40, 10), S._gathered([_cyl(2, 20, (x, y, 0)) for x in (-10, 0, 10)
                                                              for y in (-10, 0, 10)], resolve(None))),
        "tangent": lambda: (Box(10, 10, 10), _cyl(2, 20, (0.0, 0.0, 7.0), (1, 0, 0))),
    }[case]()
    t, A, B, I, J, links, cuts, pieces = _phases(a, b)
    batches, read = [], [0]
    real_tests, real_cand = S._local_tests, S._piece_candidates

    def spy_tests(cand, Y, tol):
        batches[-1].append([(c[0], id(c[2]), c[3], c[4]) for c in cand])
        return real_tests(cand, Y, tol)

    def spy_cand(*args):
        for c in real_cand(*args):
            read[0] += 1
            yield c

    monkeypatch.setattr(S, "_local_tests", spy_tests)
    monkeypatch.setattr(S, "_piece_candidates", spy_cand)
    total = 0
    for side, (X, Y) in enumerate(((A, B), (B, A))):
        lazy, eager = (np.full(len(pieces[side]), -1, dtype=np.int8) for _ in range(2))
        batches.append([])
        S._local_status(pieces[side], Y, links, side, t, lazy, cut=cuts[side])
        batches.append([])
        total += _eager_local_status(pieces[side], Y, links, side, t, eager, cut=cuts[side])
        np.testing.assert_array_equal(lazy, eager)
        assert batches[-2] == batches[-1]
    assert any(batches) and read[0] <= total
    if case == "plate-holes":
        assert read[0] < total  # (the plate's face with nine hole circles needs one of them)


@pytest.mark.parametrize("case", ["box-cylinder", "plate-holes", "tangent", "spheres"])
def test_local_way_of_both_operands_in_one_pass_as_each_alone(monkeypatch, case):
    """_local_both tests both operands' rounds together (one _local_tests pass per round, each candidate
    with its own other operand): the same statuses as _local_status one operand at a time, in fewer passes."""
    a, b = {
        "box-cylinder": lambda: (Box(10, 10, 10), _cyl(3, 20)),
        "plate-holes": lambda: (Box(40, 40, 10), S._gathered([_cyl(2, 20, (x, y, 0)) for x in (-10, 0, 10)
                                                              for y in (-10, 0, 10)], resolve(None))),
        "tangent": lambda: (Box(10, 10, 10), _cyl(2, 20, (0.0, 0.0, 7.0), (1, 0, 0))),
        "spheres": lambda: (Sphere(5), Sphere(5).translate((4.0, 2.0, 0.5))),
    }[case]()
    t, A, B, I, J, links, cuts, pieces = _phases(a, b)
    passes = []
    real = S._local_tests
    monkeypatch.setattr(S, "_local_tests", lambda cand, Y, tol: passes.append(len(cand)) or real(cand, Y, tol))
    both = S._local_both(pieces[0], pieces[1], A, B, cuts[0], cuts[1], links, t)
    joint = len(passes)
    alone = []
    for side, Y in enumerate((B, A)):
        status = np.full(len(pieces[side]), -1, dtype=np.int8)
        S._local_status(pieces[side], Y, links, side, t, status, cut=cuts[side])
        alone.append(status)
    assert sum(passes[joint:]) == sum(passes[:joint])  # the same candidates
    assert joint <= len(passes) - joint
    if case != "tangent":  # (there only B's pieces have a transversal cut)
        assert joint < len(passes) - joint  # fewer passes
    for got, ref in zip(both, alone):
        np.testing.assert_array_equal(got, ref)
    if case != "tangent":  # (there the candidates fail the test: near tangency, decided by points)
        assert all((ref >= 0).any() for ref in alone)


def test_local_status_leaves_pieces_decided_before_untouched(monkeypatch):
    """_local_status tests only the pieces still undecided when it is called (its caller may have decided
    some: the pieces of faces far from the other solid are OUT): such a piece keeps its status and none
    of its candidates is tested; every other piece gets the status of a run from scratch."""
    a, b = Box(40, 40, 10), S._gathered([_cyl(2, 20, (x, y, 0)) for x in (-10, 0, 10) for y in (-10, 0, 10)],
                                        resolve(None))
    t, A, B, I, J, links, cuts, pieces = _phases(a, b)
    for side, Y in enumerate((B, A)):
        fresh = np.full(len(pieces[side]), -1, dtype=np.int8)
        S._local_status(pieces[side], Y, links, side, t, fresh, cut=cuts[side])
        decided = np.flatnonzero(fresh >= 0)[::2]
        assert decided.size
        preset = np.full(len(pieces[side]), -1, dtype=np.int8)
        preset[decided] = S.ON_SAME  # (a status the local way never gives)
        tested = []
        real = S._local_tests
        with monkeypatch.context() as m:
            m.setattr(S, "_local_tests", lambda cand, Y, tol: tested.extend(c[0] for c in cand) or real(cand, Y, tol))
            S._local_status(pieces[side], Y, links, side, t, preset, cut=cuts[side])
        assert tested and not set(tested) & set(decided.tolist())
        assert (preset[decided] == S.ON_SAME).all()
        rest = np.ones(len(pieces[side]), dtype=bool)
        rest[decided] = False
        np.testing.assert_array_equal(preset[rest], fresh[rest])
