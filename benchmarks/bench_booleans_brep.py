"""B-rep Boolean benchmark: coons against OCCT (build123d) on solids bounded by quadrics.

Cases, each run by both peers in the same process on operands made beforehand:

* ``box − cylinder``: a 10 mm cube minus a through cylinder of radius 3;
* ``sphere ∪ sphere``: two spheres of radius 5, centres 4.5 mm apart (off-axis);
* ``T-junction``: a cylinder (r 2, length 20) united with a perpendicular one (r 1.5) that ends
  on its axis;
* ``crossing cylinders``: two perpendicular cylinders of radii 2 and 1.5 crossing each other;
* ``plate − 10×10 holes``: a 110 × 110 × 10 plate minus 100 cylinders, once as one call with
  all tools (OCCT: ``cut`` with a list of tools; coons: ``difference(plate, *tools)``, which
  gathers the disjoint tools into one operand and runs one pass) and once as 100 sequential
  cuts; ``plate − 20×20 holes``: the same with 400 cylinders on a 210 × 210 plate, one call;
* ``chain of 20``: a box to which 20 cylinders and spheres are alternately added and removed.

``COONS_BENCH_CASES`` (comma-separated, case-insensitive substrings of the case names, e.g.
``box,sphere``) restricts a run to the matching cases; the plate and chain rows take most of the
time.

Both peers are called as a user calls them: coons ``a - b`` (which returns a checked solid with
faces on one surface merged), build123d ``a - b`` (BRepAlgoAPI plus its default clean-up by
``ShapeUpgrade_UnifySameDomain``).  Before a time is reported the two volumes must agree to
1e-6 relative; otherwise the row is marked and ``run.py`` exits 1.  The module measures and
asserts nothing about speed.
"""

from __future__ import annotations

import cProfile
import io
import math
import os
import pstats
import time

import numpy as np

from _harness import Report, markdown_table, register

AGREE_RTOL = 1e-6


def _best(fn, reps: int, budget: float = 20.0):
    best, out = math.inf, None
    start = time.perf_counter()
    for _ in range(reps):
        t0 = time.perf_counter()
        out = fn()
        best = min(best, time.perf_counter() - t0)
        if time.perf_counter() - start > budget:
            break
    return best, out


def _cases():
    """name -> (coons thunk, occt thunk, reps); operands are built here, outside the timings."""
    import build123d as bd

    import coons

    def both(make):
        """(coons operand, build123d operand) made by the same recipe."""
        return make(coons), make(bd)

    def cyl(lib, r, h, at=(0, 0, 0), axis="z"):
        if lib is coons:
            d = {"x": (1, 0, 0), "y": (0, 1, 0), "z": (0, 0, 1)}[axis]
            return coons.Cylinder(r, h, direction=d).translate(at)
        rot = {"x": bd.Rot(0, 90, 0), "y": bd.Rot(90, 0, 0), "z": bd.Rot(0, 0, 0)}[axis]
        return bd.Pos(*at) * rot * bd.Cylinder(r, h)

    def sphere(lib, r, at=(0, 0, 0)):
        return coons.Sphere(r).translate(at) if lib is coons else bd.Pos(*at) * bd.Sphere(r)

    def box(lib, x, y, z, at=(0, 0, 0)):
        return coons.Box(x, y, z).translate(at) if lib is coons else bd.Pos(*at) * bd.Box(x, y, z)

    out = {}
    (cb, ob), (cc, oc) = both(lambda L: box(L, 10, 10, 10)), both(lambda L: cyl(L, 3, 20))
    out["box − cylinder"] = (lambda: cb - cc, lambda: ob - oc, 5)
    (c1, o1), (c2, o2) = both(lambda L: sphere(L, 5)), both(lambda L: sphere(L, 5, (4.0, 2.0, 0.5)))
    out["sphere ∪ sphere"] = (lambda: c1 + c2, lambda: o1 + o2, 5)
    (t1, u1), (t2, u2) = both(lambda L: cyl(L, 2, 20)), both(lambda L: cyl(L, 1.5, 10, (5, 0, 0), "x"))
    out["T-junction"] = (lambda: t1 + t2, lambda: u1 + u2, 5)
    (x1, y1), (x2, y2) = both(lambda L: cyl(L, 2, 20)), both(lambda L: cyl(L, 1.5, 20, (0, 0, 1), "x"))
    out["crossing cylinders"] = (lambda: x1 + x2, lambda: y1 + y2, 5)

    centres = [(-45.0 + 10 * i, -45.0 + 10 * j, 0.0) for i in range(10) for j in range(10)]
    cplate, oplate = box(coons, 110, 110, 10), box(bd, 110, 110, 10)
    ctools = [cyl(coons, 2, 20, c) for c in centres]
    otools = [cyl(bd, 2, 20, c) for c in centres]

    def coons_seq():
        s = cplate
        for t in ctools:
            s = s - t
        return s

    def occt_seq():
        s = oplate
        for t in otools:
            s = s - t
        return s

    out["plate − 10×10 holes, one call"] = (lambda: coons.difference(cplate, *ctools), lambda: oplate.cut(*otools), 1)
    out["plate − 10×10 holes, sequential"] = (coons_seq, occt_seq, 1)
    centres20 = [(-95.0 + 10 * i, -95.0 + 10 * j, 0.0) for i in range(20) for j in range(20)]
    cplate20, oplate20 = box(coons, 210, 210, 10), box(bd, 210, 210, 10)
    ctools20 = [cyl(coons, 2, 20, c) for c in centres20]
    otools20 = [cyl(bd, 2, 20, c) for c in centres20]
    out["plate − 20×20 holes, one call"] = (lambda: coons.difference(cplate20, *ctools20),
                                            lambda: oplate20.cut(*otools20), 1)

    rng = np.random.default_rng(20)
    steps = []
    for k in range(20):
        at = tuple(rng.uniform(-4, 4, 3))
        steps.append(("-" if k % 2 else "+", k % 4 < 2, at))

    def chain(L):
        s = box(L, 10, 10, 10)
        for op, use_cyl, at in steps:
            tool = cyl(L, 1.2, 14, at, "xyz"[int(abs(at[0] * 10)) % 3]) if use_cyl else sphere(L, 1.5, at)
            s = s - tool if op == "-" else s + tool
        return s

    out["chain of 20 Booleans"] = (lambda: chain(coons), lambda: chain(bd), 1)
    return out


def _volume(shape) -> float:
    """coons's exact volume, or OCCT's computed with a 1e-10 relative error bound.

    OCCT's default ``GProp`` precision (what build123d's ``volume`` uses) is off by up to 4e-6
    relative on Booleans of crossing cylinders, whose faces are trimmed by B-spline curves; with
    ``Eps = 1e-10`` its figures converge to the closed forms, and coons's agree with them to 1e-11.
    """
    if not hasattr(shape, "wrapped"):
        return float(shape.volume)
    from OCP.BRepGProp import BRepGProp
    from OCP.GProp import GProp_GProps

    props = GProp_GProps()
    BRepGProp.VolumeProperties_s(shape.wrapped, props, 1e-10)
    return float(props.Mass())


@register("booleans_brep", "B-rep Booleans of quadric solids against OCCT (build123d)", versions=("build123d",))
def run() -> Report:
    import coons  # noqa: F401  (registers the operators)

    rows, failed, profile_case = [], False, None
    only = [w.strip().lower() for w in os.environ.get("COONS_BENCH_CASES", "").split(",") if w.strip()]
    for name, (cfn, ofn, reps) in _cases().items():
        if only and not any(w in name.lower() for w in only):
            continue
        try:
            tc, rc = _best(cfn, reps)
        except Exception as exc:  # a failing case is a row of the report, not a crash of the run
            rows.append([name, f"raised {type(exc).__name__}", "", "", ""])
            failed = True
            continue
        to, ro = _best(ofn, reps)
        vc, vo = _volume(rc), _volume(ro)
        agree = abs(vc - vo) <= AGREE_RTOL * abs(vo)
        failed |= not agree
        rows.append([name, f"{tc * 1e3:.1f}", f"{to * 1e3:.1f}", f"{tc / to:.2f}" if agree else "volumes differ",
                     f"{len(rc.faces())} / {len(ro.faces())}"])
        if name == "box − cylinder":
            profile_case = cfn
    table = markdown_table(["case", "coons ms", "OCCT ms", "coons / OCCT", "faces coons / OCCT"], rows)
    sections = [table]
    if profile_case is not None:
        pr = cProfile.Profile()
        pr.enable()
        profile_case()
        pr.disable()
        s = io.StringIO()
        pstats.Stats(pr, stream=s).sort_stats("cumulative").print_stats(18)
        sections.append("Profile of one `box − cylinder` (cumulative):\n\n```\n" + s.getvalue().strip() + "\n```")
    return Report("B-rep Booleans: coons against OCCT", sections, failed=failed)
