"""The three engines of ``coons validate``: coons, OCCT (through build123d) and manifold3d, each reading a recipe.

:func:`run_coons`, :func:`run_occt` and :func:`run_manifold` build the solid a
:class:`~coons.validation.cases.Case` recipe describes and measure it into an
:class:`EngineResult`: volume, area, bounding box, topological counts, the Euler characteristic,
validity, and (on request) a triangle mesh for the Hausdorff distance and the pictures.

* **coons** builds with its own API (``coons.Box``, ``Pos``, ``Rot``, ``extrude``, ``from_mesh``,
  ``+ - &``); its validity is :func:`coons.check`.
* **OCCT** builds the same leaves with build123d (``Box``, ``Cylinder``, ``Cone``, ``Sphere``,
  ``Torus`` are centred on the origin like coons's default; ``Polygon(..., align=None)``
  keeps the given coordinates; mesh inputs are sewn triangles with coplanar faces unified),
  places them with composed ``Pos``/``Rot`` locations, and combines them with ``BRepAlgoAPI_Fuse``,
  ``Cut`` and ``Common`` followed by ``ShapeUpgrade_UnifySameDomain`` (what build123d's operators
  do, except that build123d fails on an empty result); volume and area come from ``BRepGProp``,
  the box from ``BRepBndLib::AddOptimal``, validity from ``BRepCheck_Analyzer``; its mesh comes from
  ``BRepMesh_IncrementalMesh`` written as binary STL by ``StlAPI_Writer`` and read back with
  :func:`coons.io.stl.import_stl` (vectorised, float32 coordinates as STL stores them).
* **manifold3d** combines coons's tessellations of the *operands* (placements are pushed down
  to the leaves and applied to the exact coons solids before tessellating), so its answer carries
  the operands' tessellation error; :class:`EngineResult.tessellation_error` records the volume
  and area differences between each leaf's mesh and its exact solid, from which
  :mod:`coons.validation.compare` derives its tolerance.

Count convention.  coons has no seam and no degenerate edges and splits closed faces into faces
spanning less than a period (``docs/brep.md``); OCCT has seams, degenerate edges at poles and
apexes, and whole closed faces.  Both satisfy Euler–Poincaré, and
``χ = V − E + F − R`` (``R`` the inner loops of faces, with OCCT's degenerate edges left out)
equals ``2 (shells − genus)`` in both conventions, so ``euler`` is comparable across engines
while the raw counts are reported side by side (``counts["seam_edges"]`` and
``counts["degenerate_edges"]`` say what OCCT has that coons does not).

The module imports build123d, OCP, manifold3d and trimesh only inside the functions that use
them.  It does not compare anything (that is :mod:`coons.validation.compare`).
"""

from __future__ import annotations

import math
import os
import tempfile
import time
import traceback
from dataclasses import dataclass, field
from importlib import resources
from typing import Any

import numpy as np

from coons.errors import CoonsError, InvalidInputError
from coons.validation.cases import Case

__all__ = ["EngineResult", "run_coons", "run_occt", "run_manifold", "mesh_input", "coons_solid", "occt_shape",
           "occt_counts", "occt_mesh", "ENGINES"]

ENGINES = ("coons", "occt", "manifold")


@dataclass
class EngineResult:
    """What one engine made of one recipe.

    Attributes
    ----------
    engine : str
        ``"coons"``, ``"occt"`` or ``"manifold"``.
    status : str
        ``"ok"`` or ``"raised"`` (``error`` says what; for coons also when its result cannot be
        tessellated: ``"tessellate: ..."``).
    error : str or None
        ``"<ExceptionType>: message"``.
    typed_error : bool
        For coons: the exception was a :class:`~coons.errors.CoonsError` (a documented refusal);
        an untyped one is a bug.
    volume, area : float or None
    bbox : (2, 3) list or None
        Min and max corners; None for an empty result.
    counts : dict
        ``vertices``, ``edges``, ``faces``, ``inner_loops``, ``shells``, ``solids`` and, for OCCT,
        ``seam_edges`` and ``degenerate_edges`` (included in ``edges``).
    euler : int or None
        ``V − E + F − R`` without degenerate edges (module docstring): ``2 (shells − genus)``.
    valid : bool or None
        coons ``check(...).ok``, OCCT ``BRepCheck_Analyzer.IsValid()``, manifold ``status() == NoError``.
    validity : str
        The checker's summary.
    empty : bool
        No solid at all.
    seconds : float
        Time to build and measure (without the mesh).
    tessellation_error : dict
        manifold only: ``volume`` and ``area``, the sums over leaves of ``|mesh − exact|``.
    mesh : tuple of (n, 3) float64 and (m, 3) int64 arrays, or None
        Only when asked for; dropped before results cross process boundaries.
    """

    engine: str
    status: str = "ok"
    error: str | None = None
    typed_error: bool = True
    volume: float | None = None
    area: float | None = None
    bbox: list | None = None
    counts: dict = field(default_factory=dict)
    euler: int | None = None
    valid: bool | None = None
    validity: str = ""
    empty: bool = False
    seconds: float = 0.0
    tessellation_error: dict = field(default_factory=dict)
    mesh: Any = None

    @property
    def ok(self) -> bool:
        return self.status == "ok"

    def to_dict(self) -> dict:
        """Plain data (no mesh) for tables, JSON and process boundaries."""
        d = {k: v for k, v in self.__dict__.items() if k != "mesh"}
        return d


def _error_text(exc: BaseException) -> str:
    msg = str(exc).strip().splitlines()[0] if str(exc).strip() else ""
    return f"{type(exc).__name__}: {msg}"[:400]


# ============================================================================ mesh inputs
def mesh_input(name: str) -> tuple[np.ndarray, np.ndarray]:
    """Vertices ``(n, 3) float64`` and outward triangles ``(m, 3) int64`` of a named mesh input.

    Raises
    ------
    InvalidInputError
        An unknown name.
    """
    if name == "xyz_cube":
        from coons.io.stl import import_stl

        with resources.as_file(resources.files("coons.validation") / "data" / "xyz_cube.stl") as p:
            return import_stl(p)
    if name == "octahedron":
        V = 6.0 * np.concatenate([np.eye(3), -np.eye(3)])
        T = np.array([[0, 1, 2], [1, 3, 2], [3, 4, 2], [4, 0, 2], [1, 0, 5], [3, 1, 5], [4, 3, 5], [0, 4, 5]])
        return V, T
    if name == "icosphere":
        return _icosphere(6.0, 2)
    if name == "ring":
        return _square_ring(6.0, 3.0, 2.0)
    raise InvalidInputError(f"unknown mesh input {name!r}, expected xyz_cube, octahedron, icosphere or ring")


def _icosphere(radius: float, levels: int) -> tuple[np.ndarray, np.ndarray]:
    """An icosahedron subdivided ``levels`` times (each triangle into 4), vertices pushed onto the sphere."""
    g = (1.0 + math.sqrt(5.0)) / 2.0
    V = np.array([[-1, g, 0], [1, g, 0], [-1, -g, 0], [1, -g, 0], [0, -1, g], [0, 1, g], [0, -1, -g], [0, 1, -g],
                  [g, 0, -1], [g, 0, 1], [-g, 0, -1], [-g, 0, 1]], dtype=float)
    T = np.array([[0, 11, 5], [0, 5, 1], [0, 1, 7], [0, 7, 10], [0, 10, 11], [1, 5, 9], [5, 11, 4], [11, 10, 2],
                  [10, 7, 6], [7, 1, 8], [3, 9, 4], [3, 4, 2], [3, 2, 6], [3, 6, 8], [3, 8, 9], [4, 9, 5],
                  [2, 4, 11], [6, 2, 10], [8, 6, 7], [9, 8, 1]])
    V /= np.linalg.norm(V, axis=1, keepdims=True)
    for _ in range(levels):
        E = np.sort(np.concatenate([T[:, [0, 1]], T[:, [1, 2]], T[:, [2, 0]]]), axis=1)
        uniq, inv = np.unique(E, axis=0, return_inverse=True)
        mid = V[uniq[:, 0]] + V[uniq[:, 1]]
        mid /= np.linalg.norm(mid, axis=1, keepdims=True)
        m = len(T)
        ab, bc, ca = (len(V) + inv.ravel()[k * m:(k + 1) * m] for k in range(3))
        a, b, c = T.T
        T = np.concatenate([np.stack(x, 1) for x in ((a, ab, ca), (b, bc, ab), (c, ca, bc), (ab, bc, ca))])
        V = np.concatenate([V, mid])
    return radius * V, T


def _square_ring(outer: float, inner: float, half_height: float) -> tuple[np.ndarray, np.ndarray]:
    """A square annulus extruded: outer half-width ``outer``, hole half-width ``inner``, ``z ∈ [-h, h]``."""
    sq = np.array([[1, -1], [1, 1], [-1, 1], [-1, -1]], dtype=float)  # counter-clockwise
    rings = [outer * sq, inner * sq]
    V = np.array([[*p, z] for z in (-half_height, half_height) for r in rings for p in r])
    ob, ib, ot, it = (np.arange(4) + 4 * k for k in range(4))  # outer/inner, bottom/top
    n1 = np.roll(np.arange(4), -1)
    tris = []
    for k in range(4):
        j = n1[k]
        tris += [[ot[k], ot[j], it[j]], [ot[k], it[j], it[k]]]  # top, normal +z
        tris += [[ob[k], ib[j], ob[j]], [ob[k], ib[k], ib[j]]]  # bottom, normal -z
        tris += [[ob[k], ob[j], ot[j]], [ob[k], ot[j], ot[k]]]  # outer wall, outward
        tris += [[ib[k], it[j], ib[j]], [ib[k], it[k], it[j]]]  # hole wall, towards the axis
    return V, np.array(tris, dtype=np.int64)


# ============================================================================ coons
def _coons_leaf(node: tuple):
    import coons

    kind, args = node[0], node[1:]
    if kind == "box":
        return coons.Box(*args)
    if kind == "cylinder":
        return coons.Cylinder(*args)
    if kind == "cone":
        return coons.Cone(*args)
    if kind == "sphere":
        return coons.Sphere(*args)
    if kind == "torus":
        return coons.Torus(*args)
    if kind == "prism":
        return coons.extrude(coons.Profile.polygon([tuple(p) for p in args[0]]), args[1])
    if kind == "plate":
        w, d, h, holes = args
        prof = coons.Profile.rectangle(w, d)
        for cx, cy, r in holes:
            prof = prof.with_hole(coons.Profile.circle(r, center=(cx, cy)))
        return coons.extrude(prof, h)
    if kind == "mesh":
        V, T = mesh_input(args[0])
        return coons.from_mesh(V, T, merge_coplanar=True)
    raise InvalidInputError(f"unknown recipe leaf {kind!r}")


def _placement(node: tuple):
    import coons

    return coons.Pos(*node[1]) if node[0] == "pos" else coons.Rot(*node[1])


def coons_solid(node: tuple):
    """The coons :class:`~coons.topology.shape.Solid` of a recipe.

    Raises
    ------
    CoonsError
        Whatever coons raises (``BooleanError(stage="input")`` for curved Booleans today).
    """
    kind = node[0]
    if kind in ("pos", "rot"):
        return _placement(node) * coons_solid(node[2])
    if kind in ("union", "difference", "intersection"):
        a, b = coons_solid(node[1]), coons_solid(node[2])
        return a + b if kind == "union" else a - b if kind == "difference" else a & b
    return _coons_leaf(node)


def run_coons(case: Case, deflection: float | None = None, mesh: bool = False) -> tuple[EngineResult, Any]:
    """Build and measure the case with coons.

    Returns
    -------
    (EngineResult, Solid or None)
        The result (``status="raised"`` on an exception, with ``typed_error``) and the solid.
    """
    res = EngineResult("coons")
    t0 = time.perf_counter()
    try:
        solid = coons_solid(case.recipe)
        b = solid.brep
        res.empty = bool(solid.is_empty)
        res.volume, res.area = float(solid.volume), float(solid.area)
        res.bbox = None if res.empty else np.asarray(solid.bounding_box(), float).tolist()
        n_loops = int(b.n_loops)
        res.counts = {"vertices": int(b.n_vertices), "edges": int(b.n_edges), "faces": int(b.n_faces),
                      "inner_loops": n_loops - int(b.n_faces), "shells": int(b.n_shells), "solids": int(b.n_solids)}
        c = res.counts
        res.euler = c["vertices"] - c["edges"] + c["faces"] - c["inner_loops"]
        report = solid.check()
        res.valid = bool(report.ok)
        res.validity = "valid" if report.ok else report.summary(limit=5)
    except Exception as exc:  # noqa: BLE001 - every failure is recorded, typed or not
        res.status, res.error = "raised", _error_text(exc)
        res.typed_error = isinstance(exc, CoonsError)
        if not res.typed_error:
            res.validity = traceback.format_exc(limit=6)[-2000:]
        res.seconds = time.perf_counter() - t0
        return res, None
    res.seconds = time.perf_counter() - t0
    if mesh and not res.empty:
        from coons.topology.tessellate import tessellate

        try:
            m = tessellate(solid, deflection=deflection)
        except Exception as exc:  # noqa: BLE001 - a solid coons cannot mesh is a coons failure, recorded
            res.status, res.error = "raised", f"tessellate: {_error_text(exc)}"
            res.typed_error = isinstance(exc, CoonsError)
            return res, solid
        res.mesh = (np.asarray(m.vertices, float), np.asarray(m.triangles, np.int64))
    return res, solid


# ============================================================================ OCCT (build123d)
def _occt_leaf(node: tuple):
    import build123d as bd

    kind, args = node[0], node[1:]
    if kind == "box":
        return bd.Box(*args)
    if kind == "cylinder":
        return bd.Cylinder(*args)
    if kind == "cone":
        return bd.Cone(*args)
    if kind == "sphere":
        return bd.Sphere(*args)
    if kind == "torus":
        return bd.Torus(*args)
    if kind == "prism":
        return bd.extrude(bd.Polygon(*[tuple(p) for p in args[0]], align=None), args[1])
    if kind == "plate":
        w, d, h, holes = args
        sk = bd.Rectangle(w, d)
        for cx, cy, r in holes:
            sk = sk - bd.Pos(cx, cy) * bd.Circle(r)
        return bd.extrude(sk, h)
    raise InvalidInputError(f"unknown recipe leaf {kind!r}")


def _occt_mesh_solid(V: np.ndarray, T: np.ndarray):
    """An OCCT solid (``TopoDS_Shape``) bounded by the triangles, sewn, with coplanar neighbours unified.

    A Python loop over triangles: building a reference input once per case, not a hot path.
    """
    from OCP.BRepBuilderAPI import (
        BRepBuilderAPI_MakeFace,
        BRepBuilderAPI_MakePolygon,
        BRepBuilderAPI_MakeSolid,
        BRepBuilderAPI_Sewing,
    )
    from OCP.gp import gp_Pnt
    from OCP.ShapeUpgrade import ShapeUpgrade_UnifySameDomain
    from OCP.TopAbs import TopAbs_SHELL
    from OCP.TopoDS import TopoDS

    sew = BRepBuilderAPI_Sewing(1e-6)
    pts = [gp_Pnt(*map(float, p)) for p in V]
    for a, b, c in T:
        poly = BRepBuilderAPI_MakePolygon(pts[a], pts[b], pts[c], True)
        sew.Add(BRepBuilderAPI_MakeFace(poly.Wire(), True).Face())
    sew.Perform()
    maker = BRepBuilderAPI_MakeSolid()
    for shell in _sub_shapes(sew.SewedShape(), TopAbs_SHELL):
        maker.Add(TopoDS.Shell(shell))
    unify = ShapeUpgrade_UnifySameDomain(maker.Solid(), True, True, True)
    unify.Build()
    return unify.Shape()


def _sub_shapes(shape, kind) -> list:
    """The distinct sub-shapes of one type (``TopExp::MapShapes``)."""
    from OCP.collections import IndexedMap_TopoDS_Shape_TopTools_ShapeMapHasher
    from OCP.TopExp import TopExp

    m = IndexedMap_TopoDS_Shape_TopTools_ShapeMapHasher()
    TopExp.MapShapes_s(shape, kind, m)
    return [m.FindKey(i) for i in range(1, m.Extent() + 1)]


def occt_shape(node: tuple, loc=None):
    """The OCCT ``TopoDS_Shape`` of a recipe.

    Primitives and sweeps come from build123d; placements are composed and applied to the
    leaves (the same solids as placing the results); Booleans call ``BRepAlgoAPI_Fuse``, ``Cut``,
    ``Common`` directly, then ``ShapeUpgrade_UnifySameDomain`` as build123d's ``clean()`` does
    (build123d's operators fail with an ``AssertionError`` on an empty result).

    Raises
    ------
    RuntimeError
        A Boolean that is not done (``IsDone()`` False).
    """
    import build123d as bd

    kind = node[0]
    if kind in ("pos", "rot"):
        here = bd.Pos(*node[1]) if kind == "pos" else bd.Rot(*node[1])
        return occt_shape(node[2], here if loc is None else loc * here)
    if kind in ("union", "difference", "intersection"):
        from OCP.BRepAlgoAPI import BRepAlgoAPI_Common, BRepAlgoAPI_Cut, BRepAlgoAPI_Fuse
        from OCP.ShapeUpgrade import ShapeUpgrade_UnifySameDomain

        a, b = occt_shape(node[1], loc), occt_shape(node[2], loc)
        op = {"union": BRepAlgoAPI_Fuse, "difference": BRepAlgoAPI_Cut, "intersection": BRepAlgoAPI_Common}[kind]
        algo = op(a, b)
        if not algo.IsDone():
            raise RuntimeError(f"BRepAlgoAPI {kind} failed (IsDone() is False)")
        unify = ShapeUpgrade_UnifySameDomain(algo.Shape(), True, True, True)
        unify.Build()
        return unify.Shape()
    if kind == "mesh":
        shape = bd.Solid(_occt_mesh_solid(*mesh_input(node[1])))
    else:
        shape = _occt_leaf(node)
    return (shape if loc is None else loc * shape).wrapped


def occt_counts(wrapped) -> dict:
    """Vertices, edges (with seams and degenerate edges counted apart), faces, inner wires, shells and solids.

    Loops run over faces and edges (cold).
    """
    from OCP.BRep import BRep_Tool
    from OCP.TopAbs import TopAbs_EDGE, TopAbs_FACE, TopAbs_SHELL, TopAbs_SOLID, TopAbs_VERTEX, TopAbs_WIRE
    from OCP.TopoDS import TopoDS

    faces = _sub_shapes(wrapped, TopAbs_FACE)
    edges = _sub_shapes(wrapped, TopAbs_EDGE)
    degenerate = sum(1 for e in edges if BRep_Tool.Degenerated_s(TopoDS.Edge(e)))
    seams = []
    inner = 0
    for f in faces:
        face = TopoDS.Face(f)
        inner += len(_sub_shapes(f, TopAbs_WIRE)) - 1
        for e in _sub_shapes(f, TopAbs_EDGE):
            if BRep_Tool.IsClosed_s(TopoDS.Edge(e), face) and not any(e.IsSame(s) for s in seams):
                seams.append(e)
    return {"vertices": len(_sub_shapes(wrapped, TopAbs_VERTEX)), "edges": len(edges), "faces": len(faces),
            "inner_loops": inner, "shells": len(_sub_shapes(wrapped, TopAbs_SHELL)),
            "solids": len(_sub_shapes(wrapped, TopAbs_SOLID)), "seam_edges": len(seams),
            "degenerate_edges": degenerate}


def occt_mesh(wrapped, deflection: float, angular: float = 0.5) -> tuple[np.ndarray, np.ndarray]:
    """OCCT's ``BRepMesh_IncrementalMesh`` of a shape, through a binary STL (float32 coordinates).

    Raises
    ------
    RuntimeError
        The STL writer failed.
    """
    from OCP.BRepMesh import BRepMesh_IncrementalMesh
    from OCP.StlAPI import StlAPI_Writer

    from coons.io.stl import import_stl

    BRepMesh_IncrementalMesh(wrapped, deflection, False, angular, True)
    fd, name = tempfile.mkstemp(suffix=".stl")
    os.close(fd)
    try:
        w = StlAPI_Writer()
        w.ASCIIMode = False
        if not w.Write(wrapped, name):
            raise RuntimeError(f"StlAPI_Writer failed on {name}")
        return import_stl(name)
    finally:
        os.unlink(name)


def run_occt(case: Case, deflection: float | None = None, mesh: bool = False) -> EngineResult:
    """Build and measure the case with OCCT (any exception is recorded as ``status="raised"``, not raised)."""
    res = EngineResult("occt")
    t0 = time.perf_counter()
    try:
        from OCP.BRepCheck import BRepCheck_Analyzer

        w = occt_shape(case.recipe)
        res.counts = occt_counts(w)
        c = res.counts
        res.empty = c["solids"] == 0
        res.volume = res.area = 0.0
        if not res.empty:
            from OCP.Bnd import Bnd_Box
            from OCP.BRepBndLib import BRepBndLib
            from OCP.BRepGProp import BRepGProp
            from OCP.GProp import GProp_GProps

            props = GProp_GProps()
            BRepGProp.VolumeProperties_s(w, props)
            res.volume = float(props.Mass())
            props = GProp_GProps()
            BRepGProp.SurfaceProperties_s(w, props)
            res.area = float(props.Mass())
            box = Bnd_Box()
            BRepBndLib.AddOptimal_s(w, box, False, False)
            res.bbox = [list(box.CornerMin().Coord()), list(box.CornerMax().Coord())]
        res.euler = c["vertices"] - (c["edges"] - c["degenerate_edges"]) + c["faces"] - c["inner_loops"]
        res.valid = bool(BRepCheck_Analyzer(w).IsValid())
        res.validity = "valid" if res.valid else "BRepCheck_Analyzer: not valid"
        res.seconds = time.perf_counter() - t0
    except Exception as exc:  # noqa: BLE001 - a reference failure is a result
        res.status, res.error = "raised", _error_text(exc)
        res.seconds = time.perf_counter() - t0
        return res
    if mesh and not res.empty:
        try:
            res.mesh = occt_mesh(w, deflection)
        except Exception as exc:  # noqa: BLE001 - no Hausdorff distance then; the measures stand
            res.validity += f"; no mesh ({_error_text(exc)})"
    return res


# ============================================================================ manifold3d
def _manifold_tree(node: tuple, M: np.ndarray, deflection: float | None, err: dict):
    import manifold3d

    from coons.io.mesh import to_manifold
    from coons.topology.tessellate import tessellate

    kind = node[0]
    if kind in ("pos", "rot"):
        return _manifold_tree(node[2], M @ _placement(node).matrix, deflection, err)
    if kind in ("union", "difference", "intersection"):
        a = _manifold_tree(node[1], M, deflection, err)
        b = _manifold_tree(node[2], M, deflection, err)
        op = {"union": manifold3d.OpType.Add, "difference": manifold3d.OpType.Subtract,
              "intersection": manifold3d.OpType.Intersect}[kind]
        return manifold3d.Manifold.batch_boolean([a, b], op)
    solid = _coons_leaf(node)
    if not np.allclose(M, np.eye(4)):
        solid = solid.transformed(M)
    tm = tessellate(solid, deflection=deflection)
    err["volume"] += abs(tm.volume - solid.volume)
    err["area"] += abs(tm.area - solid.area)
    return to_manifold(tm)


def run_manifold(case: Case, deflection: float | None = None) -> EngineResult:
    """Combine coons's tessellations of the operands with manifold3d (any exception is recorded)."""
    res = EngineResult("manifold")
    t0 = time.perf_counter()
    try:
        import manifold3d

        err = {"volume": 0.0, "area": 0.0}
        m = _manifold_tree(case.recipe, np.eye(4), deflection, err)
        res.tessellation_error = err
        res.empty = bool(m.is_empty())
        res.volume, res.area = float(m.volume()), float(m.surface_area())
        if not res.empty:
            bb = m.bounding_box()
            res.bbox = [list(bb[:3]), list(bb[3:])]
        parts = m.decompose()
        res.counts = {"vertices": int(m.num_vert()), "edges": int(m.num_edge()), "faces": int(m.num_tri()),
                      "inner_loops": 0, "shells": len(parts), "solids": len(parts)}
        res.euler = 0 if res.empty else 2 - 2 * int(m.genus())
        status = m.status()
        res.valid = status == manifold3d.Error.NoError
        res.validity = f"status {status.name}"
    except Exception as exc:  # noqa: BLE001
        res.status, res.error = "raised", _error_text(exc)
    res.seconds = time.perf_counter() - t0
    return res
