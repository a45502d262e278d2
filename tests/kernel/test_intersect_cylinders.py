"""Closed-form loops of crossing cylinders of different radii (coons.kernel.intersect._crossing_cylinders).

Each case is checked on its own properties (points on both surfaces, p-curves reproducing the curve,
direction along n_a × n_b, pieces ending on the box bounds) and against the general marching method
on the same pair and boxes (same number of branches, Hausdorff distance within the tolerance).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from coons.kernel import intersect as ix
from coons.kernel.analytic import CylindricalSurface
from coons.kernel.curve import NurbsCurve
from coons.kernel.intersect import intersect_surfaces
from coons.kernel.ssi import march_intersection
from coons.tolerance import Tolerance

PI = math.pi
TOL = Tolerance()
#: Points of a fitted branch between its check samples may exceed its measured tol slightly.
ON = 2 * TOL.linear
CYL_Z = CylindricalSurface([0, 0, 0], [0, 0, 1], [1, 0, 0], 1.0)
THIN_X = CylindricalSurface([0, 0, 0], [1, 0, 0], [0, 1, 0], 0.6)
#: A box around both loops, cutting neither: u from a point of no loop (y < 0 side of CYL_Z, z > 0 of THIN_X).
AROUND = ((PI / 2, 5 * PI / 2), (-2, 2))


def _is_loops(a, b) -> bool:
    found = ix._crossing_cylinders(a, b, TOL)
    return found is not None and len(found.candidates) == 2


def _check(result, a, b, box_a, box_b):
    """Points on both surfaces, p-curves agreeing with the curve and in the boxes, direction n_a × n_b, ends on
    box bounds (or closed)."""
    for c in result.curves:
        assert isinstance(c.curve, NurbsCurve) and c.curve.degree == ix._FIT_DEGREE == 5
        assert isinstance(c.pcurve_a, NurbsCurve) and isinstance(c.pcurve_b, NurbsCurve)
        assert c.pcurve_a.degree == c.pcurve_b.degree == ix._FIT_DEGREE
        assert 0.0 <= c.tol <= TOL.linear
        t = np.linspace(c.t0, c.t1, 401)
        D = c.curve.derivatives(t, 1)
        P, T = D[:, 0], D[:, 1]
        assert np.abs(a.implicit(P)).max() <= ON
        assert np.abs(b.implicit(P)).max() <= ON
        pa, pb = c.pcurve_a.evaluate(t), c.pcurve_b.evaluate(t)
        assert np.linalg.norm(a.evaluate(*pa.T) - P, axis=1).max() <= ON
        assert np.linalg.norm(b.evaluate(*pb.T) - P, axis=1).max() <= ON
        slack = 1e-9
        for box, pc in ((box_a, pa), (box_b, pb)):
            lo, hi = np.array(box)[:, 0], np.array(box)[:, 1]
            assert np.all(pc >= lo - slack) and np.all(pc <= hi + slack)
        side = np.einsum("ij,ij->i", np.cross(a.normal(*pa.T), b.normal(*pb.T)), T)
        assert np.all(side > 0.0)
        ends_a, ends_b = pa[[0, -1]], pb[[0, -1]]
        if c.closed:
            np.testing.assert_allclose(P[0], P[-1], rtol=0, atol=TOL.linear)
            continue
        # Each end lies on a bound of a box (an edge of the box, or a seam of a full-period box).
        for k in (0, 1):
            on = [abs(ends[k, i] - x) <= 1e-9 for ends, box in ((ends_a, box_a), (ends_b, box_b))
                  for i in (0, 1) for x in _bounds(box, i)]
            assert any(on), (ends_a[k], ends_b[k], box_a, box_b)


def _bounds(box, i: int) -> list[float]:
    """The values where a coordinate's box cuts a branch: its bounds, and for a u box of a whole period or more
    the seams ``lo + 2πk`` inside it."""
    lo, hi = box[i]
    if i == 0 and hi - lo >= 2 * PI:
        return [lo + 2 * PI * k for k in range(int((hi - lo) // (2 * PI)) + 1)] + [hi]
    return [lo, hi]


def _hausdorff(r1, r2, n: int = 400) -> float:
    """Hausdorff distance between the point sets of two results' branches (closest points on the curves)."""
    worst = 0.0
    for x, y in ((r1, r2), (r2, r1)):
        for c in x.curves:
            P = c.curve.evaluate(np.linspace(c.t0, c.t1, n))
            d = np.full(n, np.inf)
            for other in y.curves:
                curve = other.curve.segment(other.t0, other.t1) if isinstance(other.curve, NurbsCurve) else other.curve
                d = np.minimum(d, curve.closest_points(P).distances)
            worst = max(worst, float(d.max()))
    return worst


def _frame(rng) -> tuple[np.ndarray, np.ndarray]:
    z = rng.normal(size=3)
    z /= np.linalg.norm(z)
    x = np.cross(z, rng.normal(size=3))
    return z, x / np.linalg.norm(x)


def _random_pair(rng):
    """A thick cylinder and a thinner one crossing it at a random angle and offset (its rulings may or may not all
    cross the thick one)."""
    za, xa = _frame(rng)
    a = CylindricalSurface(rng.uniform(-1, 1, 3), za, xa, rng.uniform(0.8, 1.6))
    zb, xb = _frame(rng)
    while abs(float(zb @ za)) > math.cos(math.radians(15)):
        zb, xb = _frame(rng)
    rb = a.radius * rng.uniform(0.2, 0.85)
    offset = rng.uniform(-1, 1) * (a.radius - rb) * np.cross(za, zb) / np.linalg.norm(np.cross(za, zb))
    ob = a.origin + offset + rng.uniform(-1, 1) * za + rng.uniform(-1, 1) * zb
    b = CylindricalSurface(ob, zb, xb, rb)
    return (a, b) if rng.uniform() < 0.5 else (b, a)


def _random_box(rng, s, height: float):
    """A face-like box: half a turn (padded), a whole turn, or a whole turn and a little more."""
    u0 = rng.uniform(-PI, PI)
    width = rng.choice([PI + 0.06, 2 * PI, 2 * PI + 0.01])
    h = float((s.origin - CYL_Z.origin) @ s.axis)
    v0 = -h - height * rng.uniform(0.2, 1.0)
    return (u0, u0 + width), (v0, v0 + 2 * height)


def _seeded_cases():
    rng = np.random.default_rng(20261206)
    cases = []
    while len(cases) < 14:
        a, b = _random_pair(rng)
        if not _is_loops(a, b):
            continue
        cases.append((a, b, _random_box(rng, a, 3.0), _random_box(rng, b, 3.0)))
    return cases


@pytest.mark.parametrize("case", range(14))
def test_random_crossing_cylinders_agree_with_marching(case):
    a, b, box_a, box_b = _seeded_cases()[case]
    r = intersect_surfaces(a, b, box_a, box_b)
    m = march_intersection(a, b, box_a, box_b, TOL)
    _check(r, a, b, box_a, box_b)
    assert len(r.curves) == len(m.curves)
    assert sorted(c.closed for c in r.curves) == sorted(c.closed for c in m.curves)
    if r.curves:
        assert _hausdorff(r, m) <= 2 * ON
    assert sum(c.curve.length(c.t0, c.t1) for c in r.curves) == pytest.approx(
        sum(c.curve.length(c.t0, c.t1) for c in m.curves), rel=1e-7, abs=1e-9)
    # Swapping the surfaces: the same branches, reversed (n_b × n_a), p-curves swapped.
    s = intersect_surfaces(b, a, box_b, box_a)
    _check(s, b, a, box_b, box_a)
    assert len(s.curves) == len(r.curves)
    if r.curves:
        assert _hausdorff(r, s) <= 2 * ON
    assert sum(c.curve.length(c.t0, c.t1) for c in s.curves) == pytest.approx(
        sum(c.curve.length(c.t0, c.t1) for c in r.curves), rel=1e-7, abs=1e-9)


def test_thin_cylinder_through_a_thick_one_gives_two_closed_loops():
    # Every ruling of the thin cylinder crosses the thick one: one loop per side, x = ±sqrt(1 - y²).
    assert _is_loops(CYL_Z, THIN_X)
    box_a, box_b = ((PI / 2, 5 * PI / 2), (-2, 2)), ((0.5, 0.5 + 2 * PI), (-2, 2))
    r = intersect_surfaces(CYL_Z, THIN_X, box_a, box_b)
    _check(r, CYL_Z, THIN_X, box_a, box_b)
    assert len(r.curves) == 2 and all(c.closed for c in r.curves)
    sides = []
    for c in r.curves:
        P = c.curve.evaluate(np.linspace(c.t0, c.t1, 301))
        np.testing.assert_allclose(np.abs(P[:, 0]), np.sqrt(1 - P[:, 1] ** 2), rtol=0, atol=ON)
        np.testing.assert_allclose(P[:, 1] ** 2 + P[:, 2] ** 2, 0.36, rtol=0, atol=ON)
        sides.append(np.sign(P[:, 0].mean()))
        # The thin cylinder's seam u = 0.5 is where each loop starts and ends.
        np.testing.assert_allclose(sorted(c.pcurve_b.evaluate([c.t0, c.t1])[:, 0]), [0.5, 0.5 + 2 * PI], atol=1e-12)
    assert sorted(sides) == [-1.0, 1.0]


def test_seams_of_both_boxes_cut_the_loops():
    box_a, box_b = ((0, 2 * PI), (-2, 2)), ((0.5, 0.5 + 2 * PI), (-2, 2))
    r = intersect_surfaces(CYL_Z, THIN_X, box_a, box_b)
    _check(r, CYL_Z, THIN_X, box_a, box_b)
    # The x > 0 loop crosses the seam u_a = 0 twice and u_b = 0.5 once: 3 pieces; the x < 0 loop 1.
    m = march_intersection(CYL_Z, THIN_X, box_a, box_b, TOL)
    assert len(r.curves) == len(m.curves) == 4
    ends = np.concatenate([c.pcurve_a.evaluate([c.t0, c.t1]) for c in r.curves])
    on_seam = np.isclose(ends[:, 0], 0.0, atol=1e-9) | np.isclose(ends[:, 0], 2 * PI, atol=1e-9)
    assert int(on_seam.sum()) == 4
    assert _hausdorff(r, m) <= 2 * ON


def test_half_cylinder_faces_of_a_t_junction():
    # The Boolean's boxes: half-turn faces padded by 1 %, the branch cut where either half ends.
    thick = CylindricalSurface([0, 0, -10], [0, 0, 1], [1, 0, 0], 2.0)
    thin = CylindricalSurface([0, 0, 0], [1, 0, 0], [0, 1, 0], 1.5)
    pad = 0.01 * PI
    halves = [(-pad, PI + pad), (PI - pad, 2 * PI + pad)]
    total = 0.0
    for ua in halves:
        for ub in halves:
            box_a, box_b = (ua, (-0.2, 20.2)), (ub, (-0.1, 10.1))
            r = intersect_surfaces(thick, thin, box_a, box_b)
            _check(r, thick, thin, box_a, box_b)
            m = march_intersection(thick, thin, box_a, box_b, TOL)
            assert len(r.curves) == len(m.curves) == 1
            assert _hausdorff(r, m) <= 2 * ON
            total += r.curves[0].curve.length(r.curves[0].t0, r.curves[0].t1)
    # The four pieces overlap by the padding; the loop x = sqrt(4 - y²), y² + z² = 2.25 is longer than
    # the circle of the thin cylinder.
    assert total > 2 * PI * 1.5


@pytest.mark.parametrize("ratio", [0.995, 0.999, 1.0 - 1e-9])
def test_near_tangency_falls_back_to_marching(ratio):
    # Axes crossing at right angles, radii almost equal: the loops come together (their discriminant's
    # minimum nears 0), so _crossing_cylinders declines; the last pair is within _equal_cylinders' gap
    # (two ellipses), the others are marched as before.
    near = CylindricalSurface([0, 0, 0], [1, 0, 0], [0, 1, 0], ratio)
    assert ix._crossing_cylinders(CYL_Z, near, TOL) is None
    assert (ix._equal_cylinders(CYL_Z, near, TOL) is not None) == (ratio > 1.0 - 1e-8)


@pytest.mark.parametrize("offset", [0.5, 0.9, 1.2])
def test_partial_piercing_falls_back_to_marching(offset):
    # The thin cylinder's axis is offset so that some of its rulings miss the thick one and some cross it
    # (and no ruling of the thick one crosses the thin one everywhere): one loop that turns back in θ.
    thin = CylindricalSurface([0, offset, 0], [1, 0, 0], [0, 1, 0], 0.6)
    assert ix._crossing_cylinders(CYL_Z, thin, TOL) is None
    box = ((0, 2 * PI), (-3, 3))
    r = intersect_surfaces(CYL_Z, thin, box, box)
    m = march_intersection(CYL_Z, thin, box, box, TOL)
    assert len(r.curves) == len(m.curves)
    for c, d in zip(r.curves, m.curves):  # the same marched branches
        np.testing.assert_array_equal(c.curve.control_points, d.curve.control_points)


def test_disjoint_crossing_cylinders_give_nothing():
    far = CylindricalSurface([0, 3, 0], [1, 0, 0], [0, 1, 0], 0.6)
    found = ix._crossing_cylinders(CYL_Z, far, TOL)
    assert found is not None and not found.candidates
    assert intersect_surfaces(CYL_Z, far, ((0, 2 * PI), (-3, 3)), ((0, 2 * PI), (-3, 3))).curves == ()


def test_nearly_touching_disjoint_cylinders_fall_back_to_marching():
    near = CylindricalSurface([0, 1.6 + 1e-4, 0], [1, 0, 0], [0, 1, 0], 0.6)
    assert ix._crossing_cylinders(CYL_Z, near, TOL) is None


def test_skew_axes_and_the_larger_cylinder_second():
    # A thin cylinder along (1, 0.3, 0.2) off the thick one's axis, given first: the roles swap inside.
    thin = CylindricalSurface([0.1, 0.2, 0.3], [1, 0.3, 0.2], [0, 0.2, -0.3], 0.4)
    assert _is_loops(thin, CYL_Z)
    box_a, box_b = ((0, 2 * PI), (-5, 5)), ((1.0, 1.0 + PI), (-2, 2))
    r = intersect_surfaces(thin, CYL_Z, box_a, box_b)
    _check(r, thin, CYL_Z, box_a, box_b)
    m = march_intersection(thin, CYL_Z, box_a, box_b, TOL)
    assert len(r.curves) == len(m.curves)
    assert _hausdorff(r, m) <= 2 * ON


def test_loop_derivative_matches_finite_differences():
    thin = CylindricalSurface([0.1, 0.2, 0.3], [1, 0.3, 0.2], [0, 0.2, -0.3], 0.4)
    for root in (1.0, -1.0):
        for loop in (ix._CylinderLoop(thin, CYL_Z, root), ix._CylinderLoop(thin, CYL_Z, root).reversed()):
            t = np.linspace(-4, 4, 33)
            D = loop.derivatives(t, 1)
            h = 1e-6
            fd = (loop.evaluate(t + h) - loop.evaluate(t - h)) / (2 * h)
            np.testing.assert_allclose(D[:, 1], fd, rtol=0, atol=1e-8)
            np.testing.assert_allclose(np.abs(CYL_Z.implicit(D[:, 0])), 0.0, atol=1e-14)
            np.testing.assert_allclose(np.abs(thin.implicit(D[:, 0])), 0.0, atol=1e-14)


@pytest.mark.parametrize("box_a, box_b, pieces, closed", [
    # The domains (u in [0, 2π], v unbounded): CYL_Z's seam u = 0 cuts the x > 0 loop twice.
    (None, None, 4, 1),
    (((-math.inf, math.inf), (-2, 2)), ((-math.inf, math.inf), (-math.inf, math.inf)), 2, 2),
])
def test_unbounded_boxes(box_a, box_b, pieces, closed):
    r = intersect_surfaces(CYL_Z, THIN_X, box_a, box_b)
    assert len(r.curves) == pieces and sum(c.closed for c in r.curves) == closed
    assert sum(c.curve.length(c.t0, c.t1) for c in r.curves) == pytest.approx(
        sum(c.curve.length(c.t0, c.t1) for c in intersect_surfaces(CYL_Z, THIN_X, AROUND, AROUND).curves), rel=1e-7)
    for c in r.curves:
        P = c.curve.evaluate(np.linspace(c.t0, c.t1, 301))
        np.testing.assert_allclose(np.abs(P[:, 0]), np.sqrt(1 - P[:, 1] ** 2), rtol=0, atol=ON)
        if c.closed:
            np.testing.assert_allclose(P[0], P[-1], rtol=0, atol=TOL.linear)
        pa, pb = c.pcurve_a.evaluate(np.linspace(c.t0, c.t1, 301)), c.pcurve_b.evaluate(np.linspace(c.t0, c.t1, 301))
        assert np.linalg.norm(CYL_Z.evaluate(*pa.T) - P, axis=1).max() <= ON
        assert np.linalg.norm(THIN_X.evaluate(*pb.T) - P, axis=1).max() <= ON


def test_nearly_parallel_axes_fall_back_to_marching():
    # 2° between the axes: the loops would stretch over ~30 radii along them; left to marching.
    angle = math.radians(2.0)
    thin = CylindricalSurface([0, 0, 0], [math.sin(angle), 0, math.cos(angle)], [0, 1, 0], 0.3)
    assert ix._crossing_cylinders(CYL_Z, thin, TOL) is None




@pytest.mark.parametrize("delta", [3e-8, 1e-7, 1e-6, 1e-5])
@pytest.mark.parametrize("seed", range(1, 7))  # (draws that are two loops)
@pytest.mark.parametrize("row, peak", [(3, True), (3, False), (0, True), (0, False)])
def test_a_box_bound_just_inside_a_turn_between_grid_points_cuts_the_loop(row, peak, seed, delta):
    # A coordinate of the loop turns (row 3: the thin cylinder's axial coordinate; row 0: the thick one's
    # angle) in the middle of a cell of the crossing search's grid, and the box stops delta short of the
    # turn: both ends of that cell are inside the box, yet the loop leaves it (the turn is located and the
    # cell bracketed on both sides of it, _loop_turns).
    rng = np.random.default_rng(seed)
    Z = rng.normal(size=3)
    Z /= np.linalg.norm(Z)
    X = np.cross(Z, rng.normal(size=3))
    X /= np.linalg.norm(X)
    O, r = rng.normal(size=3) * 0.3, rng.uniform(0.2, 0.9)
    loop = ix._crossing_cylinders(CYL_Z, CylindricalSurface(O, Z, X, r), TOL).candidates[0].curve
    t = np.linspace(0.0, 2 * PI, 200001)
    _, G, _ = ix._loop_coordinates(loop, t, False)
    f = np.unwrap(G[row]) if row == 0 else G[row]
    i = int(np.argmax(f) if peak else np.argmin(f))
    # Turn the thin cylinder's frame so that the turn's angle is half a grid cell.
    phi = float(loop.graph(t[i:i + 1], slopes=False)[0][0]) - PI / ix._SEARCH_SAMPLES
    g = CylindricalSurface(O, Z, math.cos(phi) * X + math.sin(phi) * np.cross(Z, X), r)
    bound = float(f[i]) - delta if peak else float(f[i]) + delta
    span = (float(f.min()) - 0.5, bound) if peak else (bound, float(f.max()) + 0.5)
    box_a, box_b = ((0.0, 2 * PI), (-10.0, 10.0)), ((0.0, 2 * PI), (-10.0, 10.0))
    if row == 3:
        box_b = (box_b[0], span)
    else:
        box_a = (span, box_a[1])
    result = intersect_surfaces(CYL_Z, g, box_a, box_b, TOL)
    assert result.curves
    _check(result, CYL_Z, g, box_a, box_b)
    for c in result.curves:  # (densely: the excursion is a few thousandths of a turn wide)
        pc = (c.pcurve_b if row == 3 else c.pcurve_a).evaluate(np.linspace(c.t0, c.t1, 40001))[:, 1 if row == 3 else 0]
        assert pc.max() <= span[1] + 1e-12 and pc.min() >= span[0] - 1e-12


@pytest.mark.parametrize("case", range(14))
def test_fit_deviation_measured_on_the_splines_matches_the_curves(case, monkeypatch):
    """``_finished`` measures a fitted loop piece by scipy's B-spline (``spline_points``, ``_SCIPY_POINTS``): the
    same branches and the same deviation, to round-off, as measured by ``NurbsCurve.evaluate``."""
    import coons.kernel.curve as C

    a, b, box_a, box_b = _seeded_cases()[case]
    calls = []
    finished = ix._finished

    def spy(curve, s0, s1, pcurves, *args):
        out = finished(curve, s0, s1, pcurves, *args)
        # (the fits are new: _finished sampled all three by scipy's spline, kept on each curve)
        calls.append(all("_bspline" in c.__dict__ for c in (curve, *pcurves)))
        return out

    monkeypatch.setattr(ix, "_finished", spy)
    fast = intersect_surfaces(a, b, box_a, box_b)
    assert calls and all(calls)  # every loop piece took the spline path
    monkeypatch.setattr(C, "_SCIPY_POINTS", False)
    slow = intersect_surfaces(a, b, box_a, box_b)
    assert len(fast.curves) == len(slow.curves)
    for f, s in zip(fast.curves, slow.curves):
        assert (f.t0, f.t1, f.closed) == (s.t0, s.t1, s.closed)
        np.testing.assert_array_equal(f.curve.control_points, s.curve.control_points)
        assert f.tol == pytest.approx(s.tol, rel=1e-9, abs=1e-15)
