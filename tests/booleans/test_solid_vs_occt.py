"""Curved B-rep Booleans of coons against OCCT's on seeded random pairs of placed primitives.

The pairs (``tests/booleans/occt_cases.py``): box, cylinder, cone or frustum, sphere and torus,
every unordered combination of two kinds once (15), at random positions and random rotations,
overlapping without one bounding box containing the other, plus two nested and one disjoint pair;
each pair is combined by union, intersection and difference (54 Booleans in the default run,
90 more under ``-m slow``).  OCCT receives the same operands exactly (:func:`coons.io.ocp.to_build123d`)
and runs its own Booleans (``BRepAlgoAPI_Fuse / Common / Cut``, not build123d's ``+ & -``, whose
``ShapeUpgrade_UnifySameDomain`` pass returns wrong solids on seamless faces; see :func:`occt_reference`).
Per Boolean the tests assert

* ``check(result).ok`` for coons's result;
* volume and area equal to OCCT's to ``1e-6`` relative (OCCT's measured by
  ``BRepGProp.VolumeProperties_s`` / ``SurfaceProperties_s`` with ``eps = 1e-10``: its default
  precision is off by up to ``4e-6`` on B-spline-trimmed faces);
* the same topology after the seam rule (below);
* the two results' tessellations within ``3 × deflection`` of each other in the symmetric
  Hausdorff distance (both meshes lie within ``deflection`` of the exact surfaces, so the
  exact boundaries differ by at most ``2 × deflection`` plus sampling): a missing or spurious
  piece of surface is seen here even when it is too thin to move the volume.  Twice: coons's
  own tessellation, and coons's result converted exactly (:func:`coons.io.ocp.to_ocp`) and
  meshed by BRepMesh, which does not depend on coons's tessellator;

and per pair the algebra ``vol(A ∪ B) + vol(A ∩ B) = vol(A) + vol(B)`` and
``vol(A − B) = vol(A) − vol(A ∩ B)`` to ``1e-9`` relative (coons alone).

Topology rule.  coons has no seam and no degenerate edges (``docs/brep.md``: a cylinder is two
half-cylinder faces, a sphere two hemispheres) and merges faces only up to half a period, so face
counts differ from OCCT's by rule.  The tests compare instead, for both engines,

* the number of *distinct underlying surfaces* per surface type (faces on the same plane,
  cylinder, cone, sphere or torus — compared geometrically, to ``1e-6`` of the model size — count
  once), and
* the Euler–Poincaré invariant ``V − E + F − H = 2 (S − G)`` (``H`` inner loops, ``S`` shells,
  ``G`` genus), with OCCT's degenerate edges left out of ``E`` (a degenerate edge is a point in
  space; with it removed a face with a seam is an ordinary disk with holes), and the number of
  lumps / OCCT solids.

Failing cases are marked ``xfail(strict=True)`` in ``KNOWN_FAILURES`` with the diagnosed reason.
"""

from __future__ import annotations

import functools
import math

import numpy as np
import pytest

from coons.errors import CoonsError
from coons.topology.shape import Solid
from tests.booleans.algebra import RTOL_ALGEBRA
from tests.booleans.occt_cases import DEFAULT_PAIRS, EXTENDED_PAIRS, OPS, pair

pytestmark = pytest.mark.occt

#: Relative agreement of volume and area with OCCT.
RTOL_OCCT = 1e-6
#: Deflection of both tessellations relative to the diagonal of the operands' bounding box
#: (resolution only: it bounds the Hausdorff distance that the tests accept).
DEFLECTION = 4e-3
#: Accepted symmetric Hausdorff distance between the two tessellations, in deflections.
HAUSDORFF_FACTOR = 3.0
#: Surface samples per mesh for the Hausdorff distance.
SAMPLES = 2000

#: (pair name, op, check) -> reason; check is "coons" (raises), "volume", "topology", "hausdorff",
#: "exact-hausdorff", "algebra" or "*" (every test of that Boolean).  Filled from the runs, each
#: with its diagnosis; an empty dict means every case passes.
_OCCT_TORI = ("OCCT is wrong: its common of these two tori is empty (converted and native operands) while a "
              "2e6-point Monte Carlo of the exact implicit tori gives 11.75 ± 0.05 and coons 11.698")
_BREPMESH_CONE = ("OCCT's BRepMesh of OCCT's own result leaves the cone face by 0.175 (deflection 0.054) while "
                  "coons's mesh stays within 0.045 of the exact cone and sphere; volumes and areas agree to 1e-9")
KNOWN_FAILURES: dict[tuple[str, str, str], str] = {
    # in the extended (slow) set
    **{("tor-tor-2", op, "*"): _OCCT_TORI for op in OPS},
    **{("cone-sph-2", op, chk): _BREPMESH_CONE for op in ("union", "difference")
       for chk in ("hausdorff", "exact-hausdorff")},
    ("sph-sph-2", "difference", "exact-hausdorff"): (
        "BRepMesh at this deflection (0.04) triangulates the cut sphere face of the converted result with 42 "
        "triangles covering 17.9 of its 30.06 (BRepGProp's area of the same face); at 0.02, 0.01 and 0.005 it "
        "gives the cubic fit's triangulations (area 29.87, 29.96, 30.01).  to_ocp(result) is BRepCheck-valid "
        "with volume equal to coons's to 2e-9, and coons's own tessellation agrees with OCCT's result.  The cut "
        "face's boundary runs within about 5 degrees of the sphere's pole (latitude -1.48), where BRepMesh is weak "
        "at coarse deflection"),
}


# ====================================================================== running both engines
@functools.lru_cache(maxsize=None)
def _operands(name: str) -> tuple[Solid, Solid]:
    return pair(name).operands()


@functools.lru_cache(maxsize=None)
def _occt_operands(name: str):
    from coons.io.ocp import to_build123d

    a, b = _operands(name)
    return to_build123d(a), to_build123d(b)


@functools.lru_cache(maxsize=None)
def _coons(name: str, op: str):
    """coons's result, or the CoonsError it raised."""
    a, b = _operands(name)
    try:
        return {"union": lambda: a + b, "intersection": lambda: a & b, "difference": lambda: a - b}[op]()
    except CoonsError as exc:  # reported by the tests, never swallowed
        return exc


def _native(kind: str, sizes: tuple[float, ...], matrix):
    """The same primitive made by OCCT itself (build123d, centred like coons's) and placed by ``matrix``."""
    import build123d as bd
    from OCP.gp import gp_Trsf

    make = {"box": bd.Box, "cyl": bd.Cylinder, "cone": bd.Cone, "sph": bd.Sphere, "tor": bd.Torus}[kind]
    t = gp_Trsf()
    m = np.asarray(matrix, float)
    t.SetValues(*m[0], *m[1], *m[2])
    return bd.Location(t) * make(*sizes)


def _occt_ops(A, B) -> dict:
    """OCCT's own Booleans (``BRepAlgoAPI_Fuse/Common/Cut``) of two build123d shapes, as ``TopoDS_Shape``.

    Not build123d's ``+ & -``: those run ``ShapeUpgrade_UnifySameDomain`` afterwards, which on
    the seamless faces of converted coons solids returns wrong solids (a union of the volume of
    the difference, a torus face without wires); OCCT's Boolean itself is right on them.
    """
    from OCP.BRepAlgoAPI import BRepAlgoAPI_Common, BRepAlgoAPI_Cut, BRepAlgoAPI_Fuse

    out = {}
    for op, cls in (("union", BRepAlgoAPI_Fuse), ("intersection", BRepAlgoAPI_Common), ("difference", BRepAlgoAPI_Cut)):
        algo = cls(A.wrapped, B.wrapped)
        algo.Build()
        assert algo.IsDone(), f"OCCT's {op} failed"
        out[op] = algo.Shape()
    return out


@functools.lru_cache(maxsize=None)
def occt_reference(name: str) -> tuple[str, dict]:
    """OCCT's three results for a pair: ``(source, {op: TopoDS_Shape})``.

    The operands are first the coons ones converted exactly (``"converted"``); when OCCT's three
    results break its own algebra (``|vol(A∪B) + vol(A∩B) − vol(A) − vol(B)|`` or
    ``|vol(A−B) − vol(A) + vol(A∩B)|`` above ``RTOL_OCCT`` of the operands' volume) OCCT's
    native primitives at the same placement are tried (``"native"``); when both break it,
    ``("inconsistent", converted results)``: OCCT is no reference for that pair.
    """
    a, b = _operands(name)
    p = pair(name)
    sets = [("converted", _occt_operands),
            ("native", lambda n: (_native(p.kind_a, p.sizes_a, p.matrix_a), _native(p.kind_b, p.sizes_b, p.matrix_b)))]
    first = None
    for source, make in sets:
        res = _occt_ops(*make(name))
        first = first or res
        u, i, d = (occt_volume_area(res[op])[0] for op in ("union", "intersection", "difference"))
        if (abs(u + i - a.volume - b.volume) <= RTOL_OCCT * (a.volume + b.volume)
                and abs(d - a.volume + i) <= RTOL_OCCT * a.volume):
            return source, res
    return "inconsistent", first


def _occt(name: str, op: str):
    return occt_reference(name)[1][op]


def _scale(name: str) -> float:
    a, b = _operands(name)
    box = np.concatenate([a.bounding_box(), b.bounding_box()])
    return float(np.linalg.norm(box.max(axis=0) - box.min(axis=0)))


def _wrapped(shape):
    """The ``TopoDS_Shape`` of an OCCT result, or None for an empty result (null or without faces)."""
    from OCP.TopAbs import TopAbs_FACE
    from OCP.TopExp import TopExp_Explorer

    if shape is None or shape.IsNull() or not TopExp_Explorer(shape, TopAbs_FACE).More():
        return None
    return shape


def occt_volume_area(shape) -> tuple[float, float]:
    """OCCT's volume and area of a shape with ``eps = 1e-10`` (0, 0 when empty)."""
    from OCP.BRepGProp import BRepGProp
    from OCP.GProp import GProp_GProps

    w = _wrapped(shape)
    if w is None:
        return 0.0, 0.0
    pv, pa = GProp_GProps(), GProp_GProps()
    BRepGProp.VolumeProperties_s(w, pv, 1e-10)
    BRepGProp.SurfaceProperties_s(w, pa, 1e-10)
    return float(pv.Mass()), float(pa.Mass())


def _reference(name: str, op: str):
    """OCCT's result for the comparison, skipping (with the figures) a pair where OCCT breaks its own algebra."""
    source, res = occt_reference(name)
    if source == "inconsistent":
        a, b = _operands(name)
        u, i, d = (occt_volume_area(res[o])[0] for o in ("union", "intersection", "difference"))
        pytest.skip(f"OCCT is no reference on {name}: converted and native operands both break its algebra "
                    f"(union {u:.10g} + intersection {i:.10g} vs vol(A) + vol(B) {a.volume + b.volume:.10g}; "
                    f"difference {d:.10g} vs {a.volume - i:.10g})")
    return res[op]


def _result(name: str, op: str) -> Solid:
    r = _coons(name, op)
    if isinstance(r, Exception):
        pytest.fail(f"coons raised on {name} {op}: {type(r).__name__}: {r}\n{pair(name).recipe()}")
    return r


# ====================================================================== topology by the seam rule
def _canonical_direction(d: np.ndarray) -> np.ndarray:
    d = np.asarray(d, float) / np.linalg.norm(d)
    return d if d[np.argmax(np.abs(d))] > 0 else -d


def _key(kind: str, **g) -> tuple[str, np.ndarray]:
    """A surface's type and a vector of numbers that identifies it as a point set."""
    if kind == "plane":
        n = _canonical_direction(g["normal"])
        return kind, np.concatenate([n, [n @ g["origin"]]])
    if kind == "cylinder":
        a = _canonical_direction(g["axis"])
        p = g["origin"] - (g["origin"] @ a) * a
        return kind, np.concatenate([a, p, [g["radius"]]])
    if kind == "cone":
        a = np.asarray(g["axis"], float) * math.copysign(1.0, g["semi_angle"])  # towards the opening
        return kind, np.concatenate([a, g["apex"], [abs(g["semi_angle"])]])
    if kind == "sphere":
        return kind, np.concatenate([g["center"], [g["radius"]]])
    if kind == "torus":
        a = _canonical_direction(g["axis"])
        return kind, np.concatenate([a, g["center"], [g["major"], g["minor"]]])
    raise AssertionError(f"unexpected surface type {kind!r}")


def _coons_key(face) -> tuple[str, np.ndarray]:
    S = face.surface
    if S is None:  # an implicit plane (polyhedral face): its Newell plane
        P = np.array([v.point for v in face.outer_loop.vertices()])
        n = np.cross(P - P.mean(axis=0), np.roll(P, -1, axis=0) - P.mean(axis=0)).sum(axis=0)
        return _key("plane", normal=n, origin=P.mean(axis=0))
    kind = getattr(S, "surface_type", "bspline")
    if kind == "plane":
        return _key(kind, normal=S.axis, origin=S.origin)
    if kind == "cylinder":
        return _key(kind, axis=S.axis, origin=S.origin, radius=S.radius)
    if kind == "cone":
        return _key(kind, axis=S.axis, apex=S.apex, semi_angle=S.semi_angle)
    if kind == "sphere":
        return _key(kind, center=S.center, radius=S.radius)
    if kind == "torus":
        return _key(kind, axis=S.axis, center=S.center, major=S.major_radius, minor=S.minor_radius)
    raise AssertionError(f"unexpected surface type {kind!r} in a Boolean of primitives")


def _occt_key(face) -> tuple[str, np.ndarray]:
    from OCP.BRepAdaptor import BRepAdaptor_Surface
    from OCP.GeomAbs import GeomAbs_Cone, GeomAbs_Cylinder, GeomAbs_Plane, GeomAbs_Sphere, GeomAbs_Torus

    s = BRepAdaptor_Surface(face)
    t = s.GetType()

    def xyz(p):
        return np.array([p.X(), p.Y(), p.Z()])

    if t == GeomAbs_Plane:
        ax = s.Plane().Position()
        return _key("plane", normal=xyz(ax.Direction()), origin=xyz(ax.Location()))
    if t == GeomAbs_Cylinder:
        c = s.Cylinder()
        return _key("cylinder", axis=xyz(c.Axis().Direction()), origin=xyz(c.Location()), radius=c.Radius())
    if t == GeomAbs_Cone:
        c = s.Cone()
        return _key("cone", axis=xyz(c.Axis().Direction()), apex=xyz(c.Apex()), semi_angle=c.SemiAngle())
    if t == GeomAbs_Sphere:
        c = s.Sphere()
        return _key("sphere", center=xyz(c.Location()), radius=c.Radius())
    if t == GeomAbs_Torus:
        c = s.Torus()
        return _key("torus", axis=xyz(c.Axis().Direction()), center=xyz(c.Location()), major=c.MajorRadius(),
                    minor=c.MinorRadius())
    raise AssertionError(f"OCCT returned a face of GeomAbs type {t} in a Boolean of primitives")


def distinct_surfaces(keys: list[tuple[str, np.ndarray]], tol: float) -> dict[str, int]:
    """Number of geometrically distinct surfaces per type (greedy clustering within ``tol``; loops over faces)."""
    reps: dict[str, list[np.ndarray]] = {}
    for kind, k in keys:
        group = reps.setdefault(kind, [])
        if not any(np.max(np.abs(k - r)) <= tol for r in group):
            group.append(k)
    return {kind: len(v) for kind, v in sorted(reps.items())}


def coons_topology(r: Solid, tol: float) -> dict:
    b = r.brep
    V, E, F, L = b.n_vertices, b.n_edges, b.n_faces, b.n_loops
    return {"surfaces": distinct_surfaces([_coons_key(f) for f in r.faces()], tol),
            "euler_poincare": V - E + F - (L - F), "lumps": len(r.lumps())}


def occt_topology(shape, tol: float) -> dict:
    from OCP.TopAbs import TopAbs_FACE, TopAbs_SOLID
    from OCP.TopoDS import TopoDS

    from coons.validation.engines import _sub_shapes, occt_counts

    w = _wrapped(shape)
    if w is None:
        return {"surfaces": {}, "euler_poincare": 0, "lumps": 0}
    c = occt_counts(w)
    ep = c["vertices"] - (c["edges"] - c["degenerate_edges"]) + c["faces"] - c["inner_loops"]
    keys = [_occt_key(TopoDS.Face(f)) for f in _sub_shapes(w, TopAbs_FACE)]
    return {"surfaces": distinct_surfaces(keys, tol), "euler_poincare": ep,
            "lumps": len(_sub_shapes(w, TopAbs_SOLID))}


# ====================================================================== the tests
def _params(pairs, checks):
    out = []
    for p in pairs:
        for op in OPS:
            marks = []
            for chk in (*checks, "coons", "*"):
                reason = KNOWN_FAILURES.get((p.name, op, chk))
                if reason:
                    marks = [pytest.mark.xfail(strict=True, reason=reason)]
                    break
            out.append(pytest.param(p.name, op, id=f"{p.name}-{op}", marks=marks))
    return out


def _slow(params):
    return [pytest.param(*p.values, id=p.id, marks=[*p.marks, pytest.mark.slow]) for p in params]


def _both(checks):
    return _params(DEFAULT_PAIRS, checks) + _slow(_params(EXTENDED_PAIRS, checks))


@pytest.mark.parametrize(("name", "op"), _both(("volume",)))
def test_volume_and_area_agree_with_occt(name, op):
    r = _result(name, op)
    rep = r.check()
    assert rep.ok, [str(p) for p in rep.problems]
    a, b = _operands(name)
    v, s = occt_volume_area(_reference(name, op))
    floor = 1e-12 * (a.volume + b.volume)  # an empty result: both zero up to round-off
    np.testing.assert_allclose(r.volume, v, rtol=RTOL_OCCT, atol=floor, err_msg=f"{name} {op} volume")
    np.testing.assert_allclose(r.area, s, rtol=RTOL_OCCT, atol=floor, err_msg=f"{name} {op} area")


@pytest.mark.parametrize(("name", "op"), _both(("topology",)))
def test_topology_agrees_with_occt_after_the_seam_rule(name, op):
    r = _result(name, op)
    tol = 1e-6 * _scale(name)
    ours, theirs = coons_topology(r, tol), occt_topology(_reference(name, op), tol)
    assert ours == theirs, f"{name} {op}: coons {ours} vs OCCT {theirs}"


def _without_slivers(V: np.ndarray, T: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The mesh without zero-area triangles (BRepMesh emits a few; the point–triangle distance of
    :mod:`coons.validation.compare` returns NaN on them).  They cover no surface, so nothing is lost."""
    A, B, C = V[T[:, 0]], V[T[:, 1]], V[T[:, 2]]
    return V, T[np.linalg.norm(np.cross(B - A, C - A), axis=1) > 0.0]


def _hausdorff_to_occt(name: str, op: str, mesh_of_ours) -> None:
    from coons.validation.compare import hausdorff
    from coons.validation.engines import occt_mesh

    r = _result(name, op)
    w = _wrapped(_reference(name, op))
    if r.is_empty or w is None:
        assert r.is_empty and w is None, f"{name} {op}: coons empty {r.is_empty}, OCCT empty {w is None}"
        return
    d = DEFLECTION * _scale(name)
    h, _ = hausdorff(_without_slivers(*mesh_of_ours(r, d)), _without_slivers(*occt_mesh(w, d)), samples=SAMPLES)
    assert h <= HAUSDORFF_FACTOR * d, f"{name} {op}: Hausdorff {h:.3g} > {HAUSDORFF_FACTOR} × deflection {d:.3g}"


@pytest.mark.parametrize(("name", "op"), _both(("hausdorff",)))
def test_tessellation_agrees_with_occt_within_the_deflection(name, op):
    """coons's own tessellation of its result against OCCT's BRepMesh of OCCT's result."""
    from coons.topology.tessellate import tessellate

    def ours(r, d):
        m = tessellate(r, deflection=d)
        return m.vertices, m.triangles

    _hausdorff_to_occt(name, op, ours)


@pytest.mark.parametrize(("name", "op"), _both(("exact-hausdorff",)))
def test_exact_result_agrees_with_occt_within_the_deflection(name, op):
    """coons's result converted exactly to OCCT (to_ocp) and meshed by BRepMesh, against OCCT's result.

    Independent of coons's tessellator: it shows the result's trimmed surfaces are OCCT's.
    """
    from coons.io.ocp import to_ocp
    from coons.validation.engines import occt_mesh

    _hausdorff_to_occt(name, op, lambda r, d: occt_mesh(to_ocp(r), d))


def _pairs_params(pairs):
    out = []
    for p in pairs:
        reasons = [KNOWN_FAILURES.get((p.name, op, c)) for op in OPS for c in ("algebra", "coons")]
        reason = next((x for x in reasons if x), None)
        marks = [pytest.mark.xfail(strict=True, reason=reason)] if reason else []
        out.append(pytest.param(p.name, id=p.name, marks=marks))
    return out


@pytest.mark.parametrize("name", _pairs_params(DEFAULT_PAIRS)
                         + [pytest.param(*p.values, id=p.id, marks=[*p.marks, pytest.mark.slow])
                            for p in _pairs_params(EXTENDED_PAIRS)])
def test_algebra_identities(name):
    a, b = _operands(name)
    u, i, d = (_result(name, op) for op in ("union", "intersection", "difference"))
    np.testing.assert_allclose(u.volume + i.volume, a.volume + b.volume, rtol=RTOL_ALGEBRA)
    np.testing.assert_allclose(d.volume, a.volume - i.volume, rtol=RTOL_ALGEBRA, atol=RTOL_ALGEBRA * a.volume)


# ====================================================================== the harness itself
@pytest.mark.parametrize("kind", ["box", "cyl", "cone", "sph", "tor"])
def test_seam_rule_holds_on_the_primitives(kind):
    """The topology rule is blind to seams: coons's and OCCT's own primitives compare equal under it
    although their face counts differ (cylinder 4 vs 3, sphere 2 vs 1, torus 4 vs 1)."""
    from coons.validation.engines import _sub_shapes
    from OCP.TopAbs import TopAbs_FACE
    from tests.booleans.occt_cases import build_primitive

    sizes = {"box": (3.0, 4.0, 5.0), "cyl": (2.0, 5.0), "cone": (2.0, 0.0, 5.0), "sph": (2.0,), "tor": (3.0, 1.0)}[kind]
    ours = build_primitive(kind, sizes)
    theirs = _native(kind, sizes, np.eye(4)).wrapped
    assert coons_topology(ours, 1e-9) == occt_topology(theirs, 1e-9)
    genus = 1 if kind == "tor" else 0
    assert coons_topology(ours, 1e-9)["euler_poincare"] == 2 * (1 - genus)
    n_faces = {"box": (6, 6), "cyl": (4, 3), "cone": (3, 2), "sph": (2, 1), "tor": (4, 1)}[kind]
    assert (len(ours.faces()), len(_sub_shapes(theirs, TopAbs_FACE))) == n_faces


def test_pairs_are_reproducible_and_related_as_stated():
    from tests.booleans.occt_cases import _boxes_relation, draw_pair

    assert len(DEFAULT_PAIRS) * len(OPS) >= 48
    again = draw_pair("cyl", "sph", 0)
    assert again == pair("cyl-sph-0")
    for p in DEFAULT_PAIRS:
        assert _boxes_relation(*_operands(p.name)) == {"overlap": "overlap", "nested": "nested",
                                                       "disjoint": "disjoint"}[p.relation], p.name
    with pytest.raises(KeyError, match="no pair 'nope'"):
        pair("nope")
