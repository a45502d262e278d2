"""Comparison of engine results and the verdict of a case: measures, tolerances, Hausdorff distance.

:func:`compare_engines` lines up what coons found against one reference engine — volume, area,
bounding box, emptiness, the Euler characteristic ``χ = V − E + F − R`` (convention-free, see
:mod:`coons.validation.engines`), shell and lump counts and, for results bounded only by planes,
the face count and ``V − E`` — each a :class:`Measure` with its tolerance.  :func:`hausdorff`
measures the symmetric Hausdorff distance between two triangle meshes, and :func:`judge` turns it
all into a :class:`Verdict`:

``agree``
    coons is valid and agrees with every healthy reference (and with the closed form, if any).
``disagree``
    coons is invalid, misses the closed form, or disagrees with every healthy reference
    (the measures say which and by how much).  The only verdict that makes ``coons validate``
    fail, together with an untyped exception from coons (a bug, not a refusal).
``coons-raised``
    coons raised (``BooleanError`` for Booleans it does not do yet): its own status, not "wrong".
``reference-failed``
    coons agrees with a healthy reference but another reference raised, is invalid, misses the
    closed form or disagrees with both (manifold3d's zero-thickness walls and sheets, OCCT's
    invalid results): worth reporting, not a coons failure.

Tolerances (:class:`Tolerances`) scale with the size ``L`` of the case (the largest
bounding-box diagonal among the engines).  coons and OCCT are both exact B-rep engines:
volumes agree within ``1e-7 max(|V|, L³)``, areas within ``1e-6 max(|A|, L²)``, boxes within
``1e-6 L``, counts exactly.
manifold3d works on coons's float32 tessellations of the operands, so its volume and area
tolerances are twice the leaves' own tessellation errors (``EngineResult.tessellation_error``)
plus float32 round-off, its box tolerance two deflections, and the meshes of coons and OCCT are
compared by a Hausdorff distance within ``hausdorff_factor × deflection``.  That distance is
sampled (the largest exact point–mesh distance over some thousands of area-weighted samples,
the vertices and the centroids of each mesh), so it is a lower bound of the true one; it is a
coarse check of shape and placement, the volumes and areas are the sharp ones.

The module does not build or run anything; it is pure numpy/scipy on the engines' figures.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field

import numpy as np

from coons.errors import InvalidInputError

__all__ = [
    "Measure",
    "Verdict",
    "Tolerances",
    "VERDICTS",
    "compare_engines",
    "judge",
    "hausdorff",
    "point_mesh_distance",
    "sample_triangles",
    "closest_points_on_triangles",
    "case_scale",
]

VERDICTS = ("agree", "disagree", "coons-raised", "reference-failed", "timeout", "crashed")


@dataclass(frozen=True)
class Tolerances:
    """Comparison tolerances (module docstring).

    Attributes
    ----------
    volume_rtol, area_rtol : float
        Between exact engines, relative to ``max(|x|, L³)`` and ``max(|x|, L²)``: OCCT's volumes of
        quadric Booleans agree with closed forms to 1e-9..1e-11 and its areas to 1e-4 only on
        trimmed B-spline faces (``/work/shared/REFERENCES.md``); analytic faces do far better.
    bbox_rtol : float
        Box corners, relative to ``L`` (OCCT's optimal boxes carry the shape's 1e-7 tolerance).
    float32_rtol : float
        manifold3d stores float32 positions: ~6e-8 per coordinate, accumulated in sums.
    tessellation_factor : float
        manifold3d's volume/area tolerance in units of the leaves' own tessellation errors
        (a Boolean of meshes differs from the exact Boolean by at most the operands' differences,
        the factor leaves room for cut triangles).
    hausdorff_factor : float
        Largest Hausdorff distance between coons's and OCCT's meshes in deflections: each mesh lies
        within one deflection of the exact surface, OCCT's ``BRepMesh`` only approximately.
    """

    volume_rtol: float = 1e-7
    area_rtol: float = 1e-6
    bbox_rtol: float = 1e-6
    float32_rtol: float = 1e-5
    tessellation_factor: float = 2.0
    hausdorff_factor: float = 4.0


DEFAULT_TOLERANCES = Tolerances()


@dataclass
class Measure:
    """One figure of coons against one reference (or a closed form).

    ``deviation`` and ``tolerance`` are absolute; ``ok`` is ``deviation <= tolerance``.
    """

    name: str
    reference: str
    coons: object
    other: object
    deviation: float
    tolerance: float
    ok: bool

    def describe(self) -> str:
        def fmt(x: object) -> str:
            if isinstance(x, float):
                return f"{x:.10g}"
            if isinstance(x, list):
                return "[" + ", ".join(fmt(v) for v in x) + "]"
            return str(x)

        return (f"{self.name}: coons {fmt(self.coons)} vs {self.reference} {fmt(self.other)} "
                f"(deviation {self.deviation:.3g} > tolerance {self.tolerance:.3g})")


@dataclass
class Verdict:
    """The outcome of a case: ``kind`` (one of :data:`VERDICTS`), reasons, and every measure taken."""

    kind: str
    reasons: list[str] = field(default_factory=list)
    measures: list[Measure] = field(default_factory=list)
    failed_references: dict[str, str] = field(default_factory=dict)
    coons_bug: bool = False

    @property
    def is_failure(self) -> bool:
        """True when coons is wrong, invalid, or raised an untyped exception (the CLI exits non-zero)."""
        return self.kind == "disagree" or self.coons_bug

    def to_dict(self) -> dict:
        return asdict(self)


# ============================================================================ figures
def _get(r, name):
    return r[name] if isinstance(r, dict) else getattr(r, name)


def case_scale(*results) -> float:
    """``L``: the largest bounding-box diagonal among the results (1.0 when all are empty)."""
    diags = []
    for r in results:
        if r is not None and _get(r, "status") == "ok" and _get(r, "bbox") is not None:
            b = np.asarray(_get(r, "bbox"), float)
            diags.append(float(np.linalg.norm(b[1] - b[0])))
    return max(diags) if diags and max(diags) > 0 else 1.0


def _measure(name: str, ref: str, a, b, tol: float) -> Measure:
    if isinstance(a, (list, tuple)) or isinstance(b, (list, tuple)):
        dev = float(np.max(np.abs(np.asarray(a, float) - np.asarray(b, float))))
    elif isinstance(a, bool) or isinstance(b, bool) or isinstance(a, int) and isinstance(b, int):
        dev = float(abs(int(a) - int(b)))
    else:
        dev = abs(float(a) - float(b))
    return Measure(name, ref, a, b, dev, tol, bool(dev <= tol))


def _planar_only(res) -> bool:
    c = _get(res, "counts")
    return c.get("seam_edges", 0) == 0 and c.get("degenerate_edges", 0) == 0 and _get(res, "engine") == "occt"


def compare_engines(coons, ref, *, scale: float, deflection: float, planar: bool = False,
                    tolerances: Tolerances = DEFAULT_TOLERANCES) -> list[Measure]:
    """Measures of coons against one reference engine.

    Parameters
    ----------
    coons, ref : EngineResult or its ``to_dict()``
        Both with ``status == "ok"``.
    scale : float
        ``L`` (:func:`case_scale`).
    deflection : float
        The tessellation deflection used for manifold3d's operands.
    planar : bool
        The case's solids are all bounded by planes (then faces and ``V − E`` are compared with OCCT:
        coons may keep 2-valent vertices on straight edges, each adding one vertex and one edge).

    Returns
    -------
    list of Measure

    Raises
    ------
    InvalidInputError
        A result that is not ``ok``, or an unknown engine.
    """
    t = tolerances
    name = _get(ref, "engine")
    for r in (coons, ref):
        if _get(r, "status") != "ok":
            raise InvalidInputError(f"compare_engines needs results with status 'ok', got {_get(r, 'engine')}: "
                                    f"{_get(r, 'status')}")
    L = scale
    out: list[Measure] = [_measure("empty", name, bool(_get(coons, "empty")), bool(_get(ref, "empty")), 0.0)]
    vc, vr = float(_get(coons, "volume")), float(_get(ref, "volume"))
    ac, ar = float(_get(coons, "area")), float(_get(ref, "area"))
    if name == "occt":
        vtol = t.volume_rtol * max(abs(vr), L**3)
        atol = t.area_rtol * max(abs(ar), L**2)
        btol = t.bbox_rtol * L
    elif name == "manifold":
        err = _get(ref, "tessellation_error") or {}
        vtol = t.tessellation_factor * err.get("volume", 0.0) + t.float32_rtol * max(abs(vr), L**3 * 1e-3)
        atol = t.tessellation_factor * err.get("area", 0.0) + t.float32_rtol * max(abs(ar), L**2 * 1e-3)
        btol = 2.0 * deflection + t.float32_rtol * L
    else:
        raise InvalidInputError(f"unknown reference engine {name!r}, expected 'occt' or 'manifold'")
    out.append(_measure("volume", name, vc, vr, vtol))
    out.append(_measure("area", name, ac, ar, atol))
    bc, br = _get(coons, "bbox"), _get(ref, "bbox")
    if bc is not None and br is not None:
        out.append(_measure("bbox", name, bc, br, btol))
    if not _get(coons, "empty") and not _get(ref, "empty"):
        out.append(_measure("euler", name, int(_get(coons, "euler")), int(_get(ref, "euler")), 0.0))
    cc, cr = _get(coons, "counts"), _get(ref, "counts")
    if name == "occt":
        out.append(_measure("shells", name, cc["shells"], cr["shells"], 0.0))
        out.append(_measure("lumps", name, cc["solids"], cr["solids"], 0.0))
        if planar and _planar_only(ref):
            out.append(_measure("faces", name, cc["faces"], cr["faces"], 0.0))
            out.append(_measure("V-E", name, cc["vertices"] - cc["edges"], cr["vertices"] - cr["edges"], 0.0))
    return out


# ============================================================================ Hausdorff distance
def sample_triangles(V, T, n: int, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """About ``n`` points on a triangle mesh, area-weighted, plus every vertex and centroid.

    Parameters
    ----------
    V : (nv, 3) float64
    T : (m, 3) int64
    n : int
        Random points spread by area (stratified: ``ceil(n · area_i / area)`` per triangle).

    Returns
    -------
    points : (k, 3) float64
    triangle : (k,) int64
        The triangle each point lies on (a vertex: one of its triangles).
    """
    V = np.asarray(V, float)
    T = np.asarray(T, np.int64)
    A, B, C = V[T[:, 0]], V[T[:, 1]], V[T[:, 2]]
    area = 0.5 * np.linalg.norm(np.cross(B - A, C - A), axis=1)
    total = float(area.sum())
    per = np.zeros(len(T), np.int64) if total <= 0 else np.ceil(n * area / total).astype(np.int64)
    tri = np.repeat(np.arange(len(T)), per)
    rng = np.random.default_rng(seed)
    r1, r2 = rng.random(len(tri)), rng.random(len(tri))
    flip = r1 + r2 > 1.0
    r1[flip], r2[flip] = 1.0 - r1[flip], 1.0 - r2[flip]
    P = A[tri] + r1[:, None] * (B - A)[tri] + r2[:, None] * (C - A)[tri]
    vt = np.zeros(len(V), np.int64)
    vt[T.ravel()] = np.repeat(np.arange(len(T)), 3)
    used = np.zeros(len(V), bool)
    used[T.ravel()] = True
    pts = np.concatenate([P, V[used], (A + B + C) / 3.0])
    tris = np.concatenate([tri, vt[used], np.arange(len(T))])
    return pts, tris


def closest_points_on_triangles(P, A, B, C) -> np.ndarray:
    """The point of triangle ``(A_i, B_i, C_i)`` closest to ``P_i``, for all ``i`` at once.

    Ericson, *Real-Time Collision Detection* (2005), §5.1.5 ``ClosestPtPointTriangle``: the
    Voronoi regions of the vertices, edges and face, decided from six dot products, vectorised
    with masks.

    Parameters
    ----------
    P, A, B, C : (k, 3) float64

    Returns
    -------
    (k, 3) float64
    """
    P, A, B, C = (np.asarray(x, float) for x in (P, A, B, C))
    ab, ac, ap = B - A, C - A, P - A
    d1, d2 = np.einsum("ij,ij->i", ab, ap), np.einsum("ij,ij->i", ac, ap)
    bp = P - B
    d3, d4 = np.einsum("ij,ij->i", ab, bp), np.einsum("ij,ij->i", ac, bp)
    cp = P - C
    d5, d6 = np.einsum("ij,ij->i", ab, cp), np.einsum("ij,ij->i", ac, cp)
    va, vb, vc = d3 * d6 - d5 * d4, d5 * d2 - d1 * d6, d1 * d4 - d3 * d2
    with np.errstate(divide="ignore", invalid="ignore"):
        denom = va + vb + vc
        v = np.where(denom != 0, vb / denom, 0.0)
        w = np.where(denom != 0, vc / denom, 0.0)
        out = A + v[:, None] * ab + w[:, None] * ac  # the face region
        # Ericson tests A, B, AB, C, AC, BC, face and returns at the first hit: assign in reverse order
        m_bc = (va <= 0) & (d4 - d3 >= 0) & (d5 - d6 >= 0)
        t_bc = np.clip((d4 - d3) / ((d4 - d3) + (d5 - d6)), 0.0, 1.0)
        out = np.where(m_bc[:, None], B + t_bc[:, None] * (C - B), out)
        m_ac = (vb <= 0) & (d2 >= 0) & (d6 <= 0)
        t_ac = np.clip(d2 / (d2 - d6), 0.0, 1.0)
        out = np.where(m_ac[:, None], A + t_ac[:, None] * ac, out)
        out = np.where(((d6 >= 0) & (d5 <= d6))[:, None], C, out)
        m_ab = (vc <= 0) & (d1 >= 0) & (d3 <= 0)
        t_ab = np.clip(d1 / (d1 - d3), 0.0, 1.0)
        out = np.where(m_ab[:, None], A + t_ab[:, None] * ab, out)
    out = np.where(((d3 >= 0) & (d4 <= d3))[:, None], B, out)
    out = np.where(((d1 <= 0) & (d2 <= 0))[:, None], A, out)
    return out


def point_mesh_distance(P, V, T, *, samples: int = 20000, k: int = 4, seed: int = 0) -> np.ndarray:
    """Exact distance from each point to a triangle mesh.

    Two vectorised passes.  An upper bound ``u_i``: the mesh is sampled
    (:func:`sample_triangles`), a ``scipy.spatial.cKDTree`` of the samples gives each point its
    ``k`` nearest samples, and the exact distance to their triangles is taken.  Then every triangle
    whose bounding box meets the cube ``P_i ± u_i`` (:func:`coons.booleans._broad_phase.box_pairs`,
    a linear BVH) is a candidate, which includes the closest triangle, and the exact point–triangle
    distance (:func:`closest_points_on_triangles`) to the nearest candidate is returned.

    Parameters
    ----------
    P : (p, 3) float64
    V : (n, 3) float64, T : (m, 3) int64
        The target mesh (at least one triangle).

    Returns
    -------
    (p,) float64

    Raises
    ------
    InvalidInputError
        An empty target mesh.
    """
    from scipy.spatial import cKDTree

    from coons.booleans._broad_phase import box_pairs

    P = np.asarray(P, float).reshape(-1, 3)
    V, T = np.asarray(V, float), np.asarray(T, np.int64)
    if len(T) == 0:
        raise InvalidInputError("point_mesh_distance needs a target mesh with at least one triangle, got none")
    if len(P) == 0:
        return np.zeros(0)
    # Zero-area triangles (BRepMesh emits some) have no interior: their points lie on edges of their
    # neighbours, and the point–triangle formula would divide by zero on them.
    area2 = np.linalg.norm(np.cross(V[T[:, 1]] - V[T[:, 0]], V[T[:, 2]] - V[T[:, 0]]), axis=1)
    if np.any(area2 > 0):
        T = T[area2 > 0]
    S, tri = sample_triangles(V, T, samples, seed)
    kk = min(k, len(S))
    _, idx = cKDTree(S).query(P, k=kk)
    cand = tri[np.asarray(idx).reshape(len(P), kk)]
    u = _distances(np.repeat(P, kk, axis=0), V, T, cand.ravel()).reshape(len(P), kk).min(axis=1)
    tri_pts = V[T]
    i, j = box_pairs(P - u[:, None], P + u[:, None], tri_pts.min(axis=1), tri_pts.max(axis=1))
    d = u.copy()
    np.minimum.at(d, i, _distances(P[i], V, T, j))
    return d


def _distances(P: np.ndarray, V: np.ndarray, T: np.ndarray, tri: np.ndarray) -> np.ndarray:
    """``|P_i − closest point of triangle tri_i|`` for all ``i``."""
    Q = closest_points_on_triangles(P, V[T[tri, 0]], V[T[tri, 1]], V[T[tri, 2]])
    return np.linalg.norm(Q - P, axis=1)


def hausdorff(mesh_a, mesh_b, *, samples: int = 20000, seed: int = 0) -> tuple[float, np.ndarray]:
    """Symmetric Hausdorff distance between two triangle meshes, and the distance of ``a``'s vertices to ``b``.

    Both surfaces are sampled (about ``samples`` points each, plus vertices and centroids) and each
    sample's distance to the other mesh is :func:`point_mesh_distance`; the result is the largest.

    Parameters
    ----------
    mesh_a, mesh_b : tuple of ``(V (n, 3) float64, T (m, 3) int64)``

    Returns
    -------
    distance : float
    vertex_distance : (n_a,) float64
        For a colour map of ``a``.

    Raises
    ------
    InvalidInputError
        An empty mesh.
    """
    Va, Ta = (np.asarray(x) for x in mesh_a)
    Vb, Tb = (np.asarray(x) for x in mesh_b)
    if len(Ta) == 0 or len(Tb) == 0:
        raise InvalidInputError(f"hausdorff needs two non-empty meshes, got {len(Ta)} and {len(Tb)} triangles")
    Sa, _ = sample_triangles(Va, Ta, samples, seed)
    Sb, _ = sample_triangles(Vb, Tb, samples, seed + 1)
    dab = point_mesh_distance(Sa, Vb, Tb, samples=samples, seed=seed + 2)
    dba = point_mesh_distance(Sb, Va, Ta, samples=samples, seed=seed + 3)
    vd = point_mesh_distance(Va, Vb, Tb, samples=samples, seed=seed + 2)
    return float(max(dab.max(), dba.max())), vd


# ============================================================================ verdict
def judge(case, results: dict, *, deflection: float, hausdorff_distance: float | None = None,
          tolerances: Tolerances = DEFAULT_TOLERANCES) -> Verdict:
    """The verdict of one case from its engine results (module docstring for the rules).

    Parameters
    ----------
    case : Case
        For ``expect_volume`` and whether its recipe is all planar.
    results : dict
        ``{"coons": ..., "occt": ..., "manifold": ...}`` (EngineResult or dict); a missing or None
        reference counts as not run.
    deflection : float
        The tessellation deflection of the case.
    hausdorff_distance : float, optional
        Between coons's and OCCT's meshes, when both are non-empty.

    Returns
    -------
    Verdict
    """
    from coons.validation.cases import is_curved

    t = tolerances
    c = results["coons"]
    refs = {k: results.get(k) for k in ("occt", "manifold") if results.get(k) is not None}
    L = case_scale(c, *refs.values())
    expect = case.expect_volume
    etol = t.volume_rtol * max(abs(expect or 0.0), L**3)
    failed: dict[str, str] = {}
    for name, r in refs.items():
        if _get(r, "status") != "ok":
            failed[name] = f"{name} raised {_get(r, 'error')}"
        elif not _get(r, "valid"):
            failed[name] = f"{name} result is invalid ({_get(r, 'validity')})"
        elif not _get(r, "empty") and abs(float(_get(r, "volume"))) <= t.volume_rtol * L**3:
            # manifold3d keeps zero-thickness sheets where solids touch; a solid has volume
            failed[name] = (f"{name} result is a zero-volume sheet (volume {_get(r, 'volume'):.3g}, "
                            f"area {_get(r, 'area'):.6g}), not a solid")
        elif expect is not None:
            tol = etol
            if name == "manifold":
                err = _get(r, "tessellation_error") or {}
                tol = t.tessellation_factor * err.get("volume", 0.0) + t.float32_rtol * max(abs(expect), L**3 * 1e-3)
            if abs(float(_get(r, "volume")) - expect) > tol:
                failed[name] = f"{name} volume {_get(r, 'volume'):.10g} misses the closed form {expect:.10g}"
    if _get(c, "status") != "ok":
        bug = not _get(c, "typed_error")
        reasons = [f"coons raised {_get(c, 'error')}" + (" (an untyped exception: a bug)" if bug else "")]
        return Verdict("coons-raised", reasons + list(failed.values()), [], failed, coons_bug=bug)

    measures: list[Measure] = []
    if expect is not None:
        measures.append(_measure("volume", "closed form", float(_get(c, "volume")), float(expect), etol))
    planar = not is_curved(case.recipe)
    by_ref: dict[str, list[Measure]] = {}
    for name, r in refs.items():
        if _get(r, "status") == "ok":
            ms = compare_engines(c, r, scale=L, deflection=deflection, planar=planar, tolerances=t)
            if name == "occt" and hausdorff_distance is not None:
                ms.append(_measure("hausdorff", name, float(hausdorff_distance), 0.0,
                                   t.hausdorff_factor * deflection + t.float32_rtol * L))
            by_ref[name] = ms
            measures += ms
    coons_bad = []
    if not _get(c, "valid"):
        coons_bad.append(f"coons result is invalid: {_get(c, 'validity')}")
    if expect is not None and not measures[0].ok:
        coons_bad.append(measures[0].describe())
    healthy = [n for n in refs if n not in failed]
    if coons_bad:
        reasons = coons_bad + [m.describe() for n in healthy for m in by_ref.get(n, []) if not m.ok]
        return Verdict("disagree", reasons + list(failed.values()), measures, failed)
    if not healthy:
        reason = "no healthy reference to judge by" if refs else "no reference engine was run"
        return Verdict("reference-failed" if refs else "agree", [reason] + list(failed.values()), measures, failed)
    # A reference is blamed for a measure only when another healthy reference took the same measure and
    # agrees with coons on it; a measure no other reference can judge (Hausdorff, OCCT's counts) counts
    # against coons.
    against_coons: list[Measure] = []
    blamed: dict[str, list[Measure]] = {}
    for n in healthy:
        for m in by_ref.get(n, []):
            if m.ok:
                continue
            backers = [o for o in healthy if o != n and any(x.name == m.name and x.ok for x in by_ref.get(o, []))]
            if backers:
                blamed.setdefault(n, []).append(m)
            else:
                against_coons.append(m)
    if against_coons:
        return Verdict("disagree", [m.describe() for m in against_coons] + list(failed.values()), measures, failed)
    for n, ms in blamed.items():
        others = ", ".join(o for o in healthy if o != n)
        failed[n] = f"{n} disagrees with coons and {others}: " + "; ".join(m.describe() for m in ms)
    return Verdict("reference-failed" if failed else "agree", list(failed.values()), measures, failed)


def relative(a: float, b: float) -> float:
    """``|a − b| / max(|a|, |b|)`` (0 when both are 0)."""
    s = max(abs(a), abs(b))
    return 0.0 if s == 0 else abs(a - b) / s if math.isfinite(s) else math.inf
