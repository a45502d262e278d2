"""OCCT shapes -> coons solids: walk a TopoDS shape directly into neutral faces, normalise, sew.

:func:`from_ocp` reads the faces of every solid of a ``TopoDS_Shape`` (a solid, a compound of
solids, a shell) with ``TopExp_Explorer`` and ``BRepTools_WireExplorer``; each face's surface and
each edge's curve come from ``BRepAdaptor_Surface`` / ``BRepAdaptor_Curve`` (locations applied)
and become the coons analytic type of the same parametrisation (``gp_Pln`` -> PlanarSurface,
``gp_Cylinder`` -> CylindricalSurface, ... ``gp_Lin`` -> Line, ``gp_Circ`` -> Circle,
``gp_Elips`` -> Ellipse) or a NURBS (``Geom_BSplineCurve`` / ``Geom_BSplineSurface``, periodic
ones made non-periodic; Bezier surfaces and other curves are converted exactly with
``GeomConvert``, revolution and extrusion surfaces too after trimming them to the face's
parameter box; a face turning a whole period is then a closed NURBS with a seam, split by
:mod:`coons.io._faces`).  Edge ranges are OCCT's own parameters; degenerate edges are
skipped.  The neutral faces then go through :func:`coons.io._faces.faces_to_solid` — seams split,
p-curves recomputed, faces sewn and checked — exactly as STEP import does.
:func:`from_build123d` accepts a build123d ``Solid``, ``Part`` or ``Compound``.

The module imports OCP lazily (inside the functions), so ``import coons`` never loads it.  It does
not read OCCT's p-curves or tolerances beyond the edge tolerance, and does not accept offset
surfaces or curves (OCCT can only approximate them): those raise
:class:`~coons.errors.InvalidInputError` naming the face or edge.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from coons.errors import InvalidInputError
from coons.io._faces import RawCoedge, RawEdge, RawFace, faces_to_solid
from coons.kernel import analytic as an
from coons.kernel.curve import NurbsCurve
from coons.kernel.surface import NurbsSurface
from coons.tolerance import Tolerance, resolve

__all__ = ["from_ocp", "from_build123d"]


def _xyz(p) -> np.ndarray:
    return np.array([p.X(), p.Y(), p.Z()], dtype=np.float64)


def _frame(ax) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Origin, axis ``X × Y`` and ``X`` of a gp_Ax2 / gp_Ax3 (an indirect Ax3 flips the axis, not the parametrisation)."""
    o, x, y = _xyz(ax.Location()), _xyz(ax.XDirection()), _xyz(ax.YDirection())
    return o, np.cross(x, y), x


def _bspline_curve(bc) -> NurbsCurve:
    if bc.IsPeriodic():
        bc = bc.Copy()
        bc.SetNotPeriodic()
    n = bc.NbPoles()
    P = np.array([_xyz(bc.Pole(i)) for i in range(1, n + 1)])
    W = np.array([bc.Weight(i) for i in range(1, n + 1)]) if bc.IsRational() else None
    knots = np.repeat([bc.Knot(i) for i in range(1, bc.NbKnots() + 1)],
                      [bc.Multiplicity(i) for i in range(1, bc.NbKnots() + 1)])
    return NurbsCurve(P, knots, bc.Degree(), W)


def _bspline_surface(bs) -> NurbsSurface:
    if bs.IsUPeriodic() or bs.IsVPeriodic():
        bs = bs.Copy()
        if bs.IsUPeriodic():
            bs.SetUNotPeriodic()
        if bs.IsVPeriodic():
            bs.SetVNotPeriodic()
    nu, nv = bs.NbUPoles(), bs.NbVPoles()
    P = np.array([[_xyz(bs.Pole(i, j)) for j in range(1, nv + 1)] for i in range(1, nu + 1)])
    W = None
    if bs.IsURational() or bs.IsVRational():
        W = np.array([[bs.Weight(i, j) for j in range(1, nv + 1)] for i in range(1, nu + 1)])
    ku = np.repeat([bs.UKnot(i) for i in range(1, bs.NbUKnots() + 1)],
                   [bs.UMultiplicity(i) for i in range(1, bs.NbUKnots() + 1)])
    kv = np.repeat([bs.VKnot(i) for i in range(1, bs.NbVKnots() + 1)],
                   [bs.VMultiplicity(i) for i in range(1, bs.NbVKnots() + 1)])
    return NurbsSurface(P, ku, kv, bs.UDegree(), bs.VDegree(), W)


def _surface(face, name: str) -> tuple[Any, bool]:
    """The coons surface of a face and whether its ``Su × Sv`` is OCCT's (False: flipped).

    OCCT frames (``gp_Ax3``) may be left-handed; coons frames are right-handed with the axis
    ``X × Y``.  A plane keeps its parametrisation either way; on a cylinder, cone, sphere or torus
    an indirect frame reverses the axial (or latitude) parameter, hence OCCT's normal, and turns
    a cone's semi-angle to its negative.
    """
    from OCP.BRep import BRep_Tool
    from OCP.BRepAdaptor import BRepAdaptor_Surface
    from OCP.GeomAbs import GeomAbs_SurfaceType as S
    from OCP.GeomConvert import GeomConvert

    ad = BRepAdaptor_Surface(face, False)
    kind = ad.GetType()
    if kind == S.GeomAbs_Plane:
        o, z, x = _frame(ad.Plane().Position())
        return an.PlanarSurface(o, z, x), True
    if kind == S.GeomAbs_Cylinder:
        c = ad.Cylinder()
        o, z, x = _frame(c.Position())
        return an.CylindricalSurface(o, z, x, c.Radius()), c.Position().Direct()
    if kind == S.GeomAbs_Cone:
        c = ad.Cone()
        o, z, x = _frame(c.Position())
        direct = c.Position().Direct()
        return an.ConicalSurface(o, z, x, c.RefRadius(), c.SemiAngle() if direct else -c.SemiAngle()), direct
    if kind == S.GeomAbs_Sphere:
        c = ad.Sphere()
        o, z, x = _frame(c.Position())
        return an.SphericalSurface(o, z, x, c.Radius()), c.Position().Direct()
    if kind == S.GeomAbs_Torus:
        c = ad.Torus()
        o, z, x = _frame(c.Position())
        return an.ToroidalSurface(o, z, x, c.MajorRadius(), c.MinorRadius()), c.Position().Direct()
    if kind == S.GeomAbs_BSplineSurface:
        return _bspline_surface(ad.BSpline()), True
    if kind == S.GeomAbs_BezierSurface:
        return _bspline_surface(GeomConvert.SurfaceToBSplineSurface_s(BRep_Tool.Surface_s(face))), True
    if kind in (S.GeomAbs_SurfaceOfRevolution, S.GeomAbs_SurfaceOfExtrusion):
        # unbounded (an extrusion's v, a swept line): trimmed to the face's parameter box first,
        # which GeomConvert then makes an exact NURBS (closed when the face turns a whole period)
        from OCP.BRepTools import BRepTools
        from OCP.Geom import Geom_RectangularTrimmedSurface

        u0, u1, v0, v1 = BRepTools.UVBounds_s(face)
        trimmed = Geom_RectangularTrimmedSurface(BRep_Tool.Surface_s(face), u0, u1, v0, v1)
        return _bspline_surface(GeomConvert.SurfaceToBSplineSurface_s(trimmed)), True
    raise InvalidInputError(f"{name}: OCCT surface type {kind.name} is not supported by from_ocp")


def _curve(edge, name: str) -> Any:
    from OCP.BRepAdaptor import BRepAdaptor_Curve
    from OCP.GeomAbs import GeomAbs_CurveType as C
    from OCP.GeomConvert import GeomConvert

    ad = BRepAdaptor_Curve(edge)
    kind = ad.GetType()
    if kind == C.GeomAbs_Line:
        ln = ad.Line()
        return an.Line(_xyz(ln.Location()), _xyz(ln.Direction()))
    if kind == C.GeomAbs_Circle:
        c = ad.Circle()
        o, z, x = _frame(c.Position())
        return an.Circle(o, z, x, c.Radius())
    if kind == C.GeomAbs_Ellipse:
        c = ad.Ellipse()
        o, z, x = _frame(c.Position())
        return an.Ellipse(o, z, x, c.MajorRadius(), c.MinorRadius())
    if kind == C.GeomAbs_BSplineCurve:
        return _bspline_curve(ad.BSpline())
    if kind in (C.GeomAbs_BezierCurve, C.GeomAbs_Parabola, C.GeomAbs_Hyperbola):
        from OCP.BRep import BRep_Tool
        from OCP.Geom import Geom_TrimmedCurve

        curve = BRep_Tool.Curve_s(edge, ad.FirstParameter(), ad.LastParameter())
        trimmed = Geom_TrimmedCurve(curve, ad.FirstParameter(), ad.LastParameter())
        nc = _bspline_curve(GeomConvert.CurveToBSplineCurve_s(trimmed))
        return nc
    raise InvalidInputError(f"{name}: OCCT curve type {kind.name} is not supported by from_ocp")


class _Edges:
    """One RawEdge per TopoDS edge (same TShape and location), whatever its orientation."""

    def __init__(self) -> None:
        self.table: dict[int, list[tuple[Any, RawEdge]]] = {}

    def get(self, edge) -> RawEdge:
        from OCP.BRep import BRep_Tool
        from OCP.BRepAdaptor import BRepAdaptor_Curve

        bucket = self.table.setdefault(hash(edge), [])
        for shape, raw in bucket:
            if shape.IsSame(edge):
                return raw
        name = f"edge {sum(len(b) for b in self.table.values())}"
        curve = _curve(edge, name)
        ad = BRepAdaptor_Curve(edge)
        t0, t1 = ad.FirstParameter(), ad.LastParameter()
        if isinstance(curve, NurbsCurve):
            d0, d1 = curve.domain
            t0, t1 = max(t0, d0), min(t1, d1)  # round-off past the domain of a converted curve
        P = np.asarray(curve.evaluate(np.array([t0, t1])))
        raw = RawEdge(curve, t0, t1, P[0], P[1], float(BRep_Tool.Tolerance_s(edge)), name)
        bucket.append((edge, raw))
        return raw


def _faces_of(shape, edges: _Edges) -> list[RawFace]:
    from OCP.BRep import BRep_Tool
    from OCP.BRepTools import BRepTools, BRepTools_WireExplorer
    from OCP.TopAbs import TopAbs_FACE, TopAbs_FORWARD, TopAbs_WIRE
    from OCP.TopExp import TopExp_Explorer
    from OCP.TopoDS import TopoDS

    out = []
    ex = TopExp_Explorer(shape, TopAbs_FACE)
    k = 0
    while ex.More():
        face = TopoDS.Face(ex.Current())
        name = f"face {k}"
        surface, same = _surface(face, name)
        outer_wire = BRepTools.OuterWire_s(face)
        loops, outer = [], None
        wx = TopExp_Explorer(face, TopAbs_WIRE)
        while wx.More():
            wire = TopoDS.Wire(wx.Current())
            if wire.IsSame(outer_wire):
                outer = len(loops)
            loop = []
            it = BRepTools_WireExplorer(wire, face)
            while it.More():
                e = it.Current()
                if not BRep_Tool.Degenerated_s(e):
                    loop.append(RawCoedge(edges.get(e), e.Orientation() == TopAbs_FORWARD))
                it.Next()
            if loop:
                loops.append(loop)
            wx.Next()
        out.append(RawFace(surface, (face.Orientation() == TopAbs_FORWARD) == same, loops, outer, [], name))
        ex.Next()
        k += 1
    return out


def from_ocp(shape, tol: Tolerance | None = None):
    """A coons :class:`~coons.topology.shape.Solid` from an OCCT ``TopoDS_Shape``.

    All faces of the shape (every solid of a compound) are sewn together: disjoint solids become
    lumps of one coons solid, inner shells voids.

    Parameters
    ----------
    shape : OCP.TopoDS.TopoDS_Shape
    tol : Tolerance, optional
        Raised to the largest OCCT edge tolerance when that is larger.

    Returns
    -------
    Solid

    Raises
    ------
    InvalidInputError
        Not a TopoDS_Shape, no face, an unsupported surface or curve type (offset, other).
    TopologyError, InvalidGeometryError
        The faces do not sew into a valid solid (open shell, edges off their surfaces).

    Examples
    --------
    >>> from OCP.BRepPrimAPI import BRepPrimAPI_MakeBox
    >>> s = from_ocp(BRepPrimAPI_MakeBox(1.0, 2.0, 3.0).Shape())
    >>> s.brep.n_faces, round(s.volume, 12)
    (6, 6.0)
    """
    from OCP.TopoDS import TopoDS_Shape

    if not isinstance(shape, TopoDS_Shape):
        raise InvalidInputError(f"from_ocp needs an OCP TopoDS_Shape, got {type(shape).__name__}")
    if shape.IsNull():
        raise InvalidInputError("from_ocp got a null TopoDS_Shape")
    t = resolve(tol)
    edges = _Edges()
    faces = _faces_of(shape, edges)
    if not faces:
        raise InvalidInputError(f"from_ocp: the {shape.ShapeType().name} has no face")
    worst = max((raw.tol for bucket in edges.table.values() for _, raw in bucket), default=0.0)
    if worst > t.linear:
        t = Tolerance(worst, t.angular, t.solver)
    return faces_to_solid(faces, t)


def from_build123d(obj, tol: Tolerance | None = None):
    """A coons solid from a build123d ``Solid``, ``Part``, ``Compound`` (anything with ``.wrapped``).

    Raises
    ------
    InvalidInputError
        An object without a ``wrapped`` TopoDS_Shape; otherwise as :func:`from_ocp`.
    """
    wrapped = getattr(obj, "wrapped", None)
    if wrapped is None:
        raise InvalidInputError(f"from_build123d needs a build123d shape (with .wrapped), got {type(obj).__name__}")
    return from_ocp(wrapped, tol)
