"""Conversion of coons solids to OCCT shapes (``TopoDS_Solid``) and build123d solids, without a file.

:func:`to_ocp` builds the OCCT B-rep directly with ``BRep_Builder``: every coons vertex,
edge, loop, face and shell becomes one ``TopoDS`` entity; surfaces and curves become the
matching ``Geom`` / ``Geom2d`` objects with the same parametrisation (:mod:`coons.kernel.analytic`
is OCCT's parametrisation, so analytic p-curves are copied exactly and stay same-parameter);
tolerances are the achieved ``edge_tol`` / ``vertex_tol`` (at least OCCT's confusion 1e-7).
:func:`to_build123d` wraps the result in ``build123d.Solid`` (``Compound`` for several lumps).
The module does not convert back (see ``coons.io.from_ocp``) and hands no geometric work to
OCCT: no ShapeFix, no sewing, no SameParameter except for the single documented case below.

Differences from coons's model that OCCT needs
----------------------------------------------
* Poles and apexes: coons loops pass through a vertex where a surface collapses and their
  p-curves jump along the collapsed side of the parameter rectangle; OCCT wants a closed
  wire in the parameter plane, so a *degenerated* edge (no 3-D curve, a straight p-curve
  across the gap, ``BRep_Builder.Degenerated``) is inserted at each such gap, as OCCT's own
  primitives have.
* Straight edges without a curve (``t ∈ [0, 1]``) get a ``Geom_Line`` of unit direction
  over ``[0, L]``; their p-curves are re-parametrised by ``t -> L t``.  Faces without a
  surface (polyhedra) get a ``Geom_Plane`` with the Newell normal and exact line p-curves.
* Orientation: a face whose outward normal is opposite to ``Su × Sv`` (``face_sense`` False)
  is built ``REVERSED`` with its loops stored reversed, so that exploring it yields coons's
  coedge orientations.  Void shells are added as coons stores them (faces pointing into the
  cavity), which is OCCT's convention for inner shells.
* A :class:`~coons.kernel.pcurve.Trig2D` p-curve whose axes are orthogonal becomes a
  ``Geom2d_Circle`` / ``Geom2d_Ellipse`` on a ``gp_Ax22d`` (direct or indirect frame) with the
  edge's own parameter.  Any other Trig2D (non-orthogonal axes, or a minor axis first) has
  no same-parameter OCCT form: it is written as the principal-axis ellipse over its own
  range and the edge is made same-parameter by ``BRepLib.SameParameter`` (which may raise
  the edge tolerance; coons's primitives and sweeps never produce this case).
"""

from __future__ import annotations

import math

import numpy as np

from coons.errors import InvalidInputError, TopologyError
from coons.kernel.analytic import (
    Circle,
    ConicalSurface,
    CylindricalSurface,
    Ellipse,
    Line,
    PlanarSurface,
    SphericalSurface,
    ToroidalSurface,
)
from coons.kernel.curve import NurbsCurve
from coons.kernel.pcurve import Line2D, Trig2D
from coons.kernel.surface import NurbsSurface
from coons.tolerance import Tolerance, resolve

__all__ = ["to_ocp", "to_build123d"]

#: OCCT's Precision::Confusion(): no OCCT tolerance may be smaller.
_OCC_CONFUSION = 1e-7


# ---------------------------------------------------------------------------- geometry
def _pnt(p):
    from OCP.gp import gp_Pnt

    return gp_Pnt(float(p[0]), float(p[1]), float(p[2]))


def _dir(d):
    from OCP.gp import gp_Dir

    return gp_Dir(float(d[0]), float(d[1]), float(d[2]))


def _ax3(origin, z, x):
    from OCP.gp import gp_Ax3

    return gp_Ax3(_pnt(origin), _dir(z), _dir(x))


def _ax2(origin, z, x):
    from OCP.gp import gp_Ax2

    return gp_Ax2(_pnt(origin), _dir(z), _dir(x))


def _knots(knots):
    from OCP.collections import Array1_double, Array1_int

    vals, mult = np.unique(np.asarray(knots, dtype=np.float64), return_counts=True)
    K = Array1_double(1, len(vals))
    M = Array1_int(1, len(vals))
    for i, (v, m) in enumerate(zip(vals.tolist(), mult.tolist()), start=1):
        K.SetValue(i, v)
        M.SetValue(i, int(m))
    return K, M


def _weights1(w):
    from OCP.collections import Array1_double

    W = Array1_double(1, len(w))
    for i, x in enumerate(np.asarray(w, dtype=np.float64).tolist(), start=1):
        W.SetValue(i, x)
    return W


def _bspline_curve3d(c: NurbsCurve):
    from OCP.collections import Array1_gp_Pnt
    from OCP.Geom import Geom_BSplineCurve

    P = np.asarray(c.control_points, dtype=np.float64)
    poles = Array1_gp_Pnt(1, len(P))
    for i, p in enumerate(P.tolist(), start=1):
        poles.SetValue(i, _pnt(p))
    K, M = _knots(c.knots)
    if c.is_rational:
        return Geom_BSplineCurve(poles, _weights1(c.weights), K, M, int(c.degree))
    return Geom_BSplineCurve(poles, K, M, int(c.degree))


def _bspline_curve2d(c: NurbsCurve):
    from OCP.collections import Array1_gp_Pnt2d
    from OCP.Geom2d import Geom2d_BSplineCurve
    from OCP.gp import gp_Pnt2d

    P = np.asarray(c.control_points, dtype=np.float64)
    poles = Array1_gp_Pnt2d(1, len(P))
    for i, p in enumerate(P.tolist(), start=1):
        poles.SetValue(i, gp_Pnt2d(p[0], p[1]))
    K, M = _knots(c.knots)
    if c.is_rational:
        return Geom2d_BSplineCurve(poles, _weights1(c.weights), K, M, int(c.degree))
    return Geom2d_BSplineCurve(poles, K, M, int(c.degree))


def _curve3d(c):
    """``Geom_Curve`` of a coons 3-D curve (same parametrisation).

    Raises
    ------
    InvalidInputError
        An unsupported curve type.
    """
    from OCP.Geom import Geom_Circle, Geom_Ellipse, Geom_Line

    if isinstance(c, Line):
        return Geom_Line(_pnt(c.origin), _dir(c.direction))
    if isinstance(c, Circle):
        return Geom_Circle(_ax2(c.center, c.axis, c.x_dir), float(c.radius))
    if isinstance(c, Ellipse):
        return Geom_Ellipse(_ax2(c.center, c.axis, c.x_dir), float(c.major_radius), float(c.minor_radius))
    if isinstance(c, NurbsCurve) and c.dimension == 3:
        return _bspline_curve3d(c)
    raise InvalidInputError(f"to_ocp: unsupported edge curve {type(c).__name__}; expected Line, Circle, Ellipse or 3-D NurbsCurve")


def _surface(s):
    """``Geom_Surface`` of a coons surface (same parametrisation).

    Raises
    ------
    InvalidInputError
        An unsupported surface type.
    """
    from OCP.Geom import (
        Geom_BSplineSurface,
        Geom_ConicalSurface,
        Geom_CylindricalSurface,
        Geom_Plane,
        Geom_SphericalSurface,
        Geom_ToroidalSurface,
    )

    if isinstance(s, PlanarSurface):
        return Geom_Plane(_ax3(s.origin, s.axis, s.x_dir))
    if isinstance(s, CylindricalSurface):
        return Geom_CylindricalSurface(_ax3(s.origin, s.axis, s.x_dir), float(s.radius))
    if isinstance(s, ConicalSurface):
        return Geom_ConicalSurface(_ax3(s.origin, s.axis, s.x_dir), float(s.semi_angle), float(s.radius))
    if isinstance(s, SphericalSurface):
        return Geom_SphericalSurface(_ax3(s.center, s.axis, s.x_dir), float(s.radius))
    if isinstance(s, ToroidalSurface):
        return Geom_ToroidalSurface(_ax3(s.center, s.axis, s.x_dir), float(s.major_radius), float(s.minor_radius))
    if isinstance(s, NurbsSurface) and s.dimension == 3:
        from OCP.collections import Array2_double, Array2_gp_Pnt

        P = np.asarray(s.control_points, dtype=np.float64)
        nu, nv = P.shape[:2]
        poles = Array2_gp_Pnt(1, nu, 1, nv)
        for i in range(nu):
            for j in range(nv):
                poles.SetValue(i + 1, j + 1, _pnt(P[i, j]))
        Ku, Mu = _knots(s.knots_u)
        Kv, Mv = _knots(s.knots_v)
        du, dv = int(s.degree_u), int(s.degree_v)
        if s.is_rational:
            W = np.asarray(s.weights, dtype=np.float64)
            Wa = Array2_double(1, nu, 1, nv)
            for i in range(nu):
                for j in range(nv):
                    Wa.SetValue(i + 1, j + 1, float(W[i, j]))
            return Geom_BSplineSurface(poles, Wa, Ku, Kv, Mu, Mv, du, dv)
        return Geom_BSplineSurface(poles, Ku, Kv, Mu, Mv, du, dv)
    raise InvalidInputError(
        f"to_ocp: unsupported surface {type(s).__name__}; expected PlanarSurface, CylindricalSurface, "
        "ConicalSurface, SphericalSurface, ToroidalSurface or 3-D NurbsSurface"
    )


def _curve2d(pc, scale: float, t0: float, t1: float):
    """``(Geom2d_Curve, same_parameter)`` of a p-curve after ``t -> scale t``, for the edge range ``[t0, t1]`` (scaled).

    Raises
    ------
    InvalidInputError
        An unsupported p-curve type.
    """
    from OCP.Geom2d import Geom2d_Circle, Geom2d_Ellipse, Geom2d_Line
    from OCP.gp import gp_Ax22d, gp_Dir2d, gp_Pnt2d

    if isinstance(pc, Line2D):
        d = np.asarray(pc.direction) / scale
        speed = float(np.hypot(d[0], d[1]))
        o = np.asarray(pc.origin)
        if speed == 1.0:
            return Geom2d_Line(gp_Pnt2d(o[0], o[1]), gp_Dir2d(d[0], d[1])), True
        # A Geom2d_Line runs at unit speed: a degree-1 B-spline over the edge range keeps the parameter.
        return _bspline_curve2d(NurbsCurve(np.array([o + t0 * d, o + t1 * d]), [t0, t0, t1, t1], 1)), True
    if isinstance(pc, Trig2D):
        C, A, B = (np.asarray(x, dtype=np.float64) for x in (pc.center, pc.a, pc.b))
        la, lb = float(np.hypot(*A)), float(np.hypot(*B))
        # Orthogonal axes, the first one major, within a few ulps (the round-off of rotating an
        # exact circle's frame): an exact circle/ellipse on a (possibly indirect) frame.  On a
        # straight edge (scale != 1) the parameter is L t, which no conic has: fall through.
        if scale == 1.0 and abs(A @ B) <= 1e-14 * la * lb and la >= lb * (1 - 1e-14):
            ax = gp_Ax22d(gp_Pnt2d(C[0], C[1]), gp_Dir2d(A[0], A[1]), gp_Dir2d(B[0], B[1]))
            if math.isclose(la, lb, rel_tol=1e-14):  # equal radii to round-off: a circle (an ellipse would do too)
                return Geom2d_Circle(ax, la), True
            return Geom2d_Ellipse(ax, la, lb), True
        U, sv, _ = np.linalg.svd(np.column_stack([A, B]))
        if np.linalg.det(U) < 0:  # a direct frame: the ellipse runs counter-clockwise (to_ocp reverses if needed)
            U[:, 1] *= -1.0
        ax = gp_Ax22d(gp_Pnt2d(C[0], C[1]), gp_Dir2d(U[0, 0], U[1, 0]), gp_Dir2d(U[0, 1], U[1, 1]))
        return Geom2d_Ellipse(ax, float(sv[0]), float(sv[1])), False
    if isinstance(pc, NurbsCurve) and pc.dimension == 2:
        if scale != 1.0:
            lo, hi = pc.domain
            pc = pc.reparametrized(lo * scale, hi * scale)
        return _bspline_curve2d(pc), True
    raise InvalidInputError(f"to_ocp: unsupported p-curve {type(pc).__name__}; expected Line2D, Trig2D or 2-D NurbsCurve")


def _newell_plane(P: np.ndarray):
    from coons.io.step.writer import _newell_plane as newell

    return newell(P)


# ---------------------------------------------------------------------------- topology
def to_ocp(solid, tol: Tolerance | None = None):
    """The OCCT B-rep of a coons solid, built directly with ``BRep_Builder``.

    Parameters
    ----------
    solid : Solid
        A non-empty coons solid.
    tol : Tolerance, optional
        ``tol.linear`` is the least tolerance given to OCCT vertices and edges (with OCCT's
        confusion 1e-7); each gets ``max(achieved coons tolerance, tol.linear, 1e-7)``.

    Returns
    -------
    OCP.TopoDS.TopoDS_Solid
        For one lump; for several lumps a ``TopoDS_Compound`` of one solid per lump.

    Raises
    ------
    InvalidInputError
        Not a Solid, the empty solid, geometry of a type OCCT conversion does not support, or a
        lone-vertex loop (OCCT faces have none).
    TopologyError
        A pole gap whose end points cannot be joined by a degenerated edge.
    """
    from OCP.BRep import BRep_Builder
    from OCP.BRepLib import BRepLib
    from OCP.Geom2d import Geom2d_Line
    from OCP.gp import gp_Dir2d, gp_Pnt2d
    from OCP.TopAbs import TopAbs_FORWARD, TopAbs_REVERSED
    from OCP.TopoDS import TopoDS_Compound, TopoDS_Edge, TopoDS_Face, TopoDS_Shell, TopoDS_Solid, TopoDS_Vertex, TopoDS_Wire

    from coons.topology.shape import Solid

    if not isinstance(solid, Solid):
        raise InvalidInputError(f"to_ocp needs a coons Solid, got {type(solid).__name__}")
    if solid.is_empty:
        raise InvalidInputError("to_ocp needs a non-empty solid, got the empty solid (0 faces)")
    t = resolve(tol)
    floor = max(t.linear, _OCC_CONFUSION)
    b = solid.brep
    B = BRep_Builder()

    etol = np.maximum(b.edge_tol, floor)
    vtol = np.maximum(b.vertex_tol, floor)
    np.maximum.at(vtol, b.edge_vertex[:, 0], etol)
    np.maximum.at(vtol, b.edge_vertex[:, 1], etol)

    verts = []
    for i, p in enumerate(b.vertex_point.tolist()):
        v = TopoDS_Vertex()
        B.MakeVertex(v, _pnt(p), float(vtol[i]))
        verts.append(v)

    # Faces first (edges attach their p-curves to them).  Each face gets its own Geom surface
    # even when coons shares one: OCCT keys p-curves by (surface, location), and an edge with
    # p-curves on two faces of one surface handle would become a seam of both.
    faces, face_plane = [], {}
    for f in range(b.n_faces):
        si = int(b.face_surface[f])
        if si >= 0:
            g = _surface(b.surfaces[si])
        else:
            from OCP.Geom import Geom_Plane

            cs = b.loop_coedges(int(b.face_loop_ids(f)[0]))
            o, n, x = _newell_plane(b.vertex_point[b.coedge_origin[cs]])
            g = Geom_Plane(_ax3(o, n, x))
            face_plane[f] = (o, np.cross(n, x), x)
        F = TopoDS_Face()
        B.MakeFace(F, g, floor)
        faces.append(F)

    # Edges: 3-D curve, range, vertices, p-curves.
    curve_cache: dict[int, object] = {}
    edges = []
    end_uv = np.full((b.n_edges, 2, 2, 2), np.nan)  # [edge, side, start/end (edge direction), uv]
    edge_face = b.edge_face
    for e in range(b.n_edges):
        E = TopoDS_Edge()
        ci = int(b.edge_curve[e])
        v0, v1 = (int(x) for x in b.edge_vertex[e])
        scale = 1.0
        if ci >= 0:
            if ci not in curve_cache:
                curve_cache[ci] = _curve3d(b.curves[ci])
            t0, t1 = (float(x) for x in b.edge_range[e])
            B.MakeEdge(E, curve_cache[ci], float(etol[e]))
        else:
            from OCP.Geom import Geom_Line

            a_, b_ = b.vertex_point[[v0, v1]]
            scale = float(np.linalg.norm(b_ - a_))
            if scale == 0.0:
                raise InvalidInputError(f"to_ocp: straight edge {e} has coincident end points")
            t0, t1 = 0.0, scale
            B.MakeEdge(E, Geom_Line(_pnt(a_), _dir((b_ - a_) / scale)), float(etol[e]))
        B.Add(E, verts[v0].Oriented(TopAbs_FORWARD))
        B.Add(E, verts[v1].Oriented(TopAbs_REVERSED))
        B.Range(E, t0, t1)
        fix_same_parameter = False
        for side in (0, 1):
            f = int(edge_face[e, side])
            pi = int(b.edge_pcurve[e, side])
            if pi >= 0:
                pc = b.pcurves[pi]
                c2, same = _curve2d(pc, scale, t0, t1)
                tt = np.array([t0, t1]) / scale
                end_uv[e, side] = pc.evaluate(tt)
                if same:
                    B.UpdateEdge(E, c2, faces[f], float(etol[e]))
                else:
                    # Own range of the principal-axis ellipse: project the end points on it.
                    from OCP.Geom2dAPI import Geom2dAPI_ProjectPointOnCurve

                    uv = end_uv[e, side]
                    s0 = Geom2dAPI_ProjectPointOnCurve(gp_Pnt2d(*uv[0]), c2).LowerDistanceParameter()
                    s1 = Geom2dAPI_ProjectPointOnCurve(gp_Pnt2d(*uv[1]), c2).LowerDistanceParameter()
                    a2, b2 = np.asarray(pc.a), np.asarray(pc.b)
                    d = float(np.sign(a2[0] * b2[1] - a2[1] * b2[0]))
                    if d > 0 and s1 <= s0:
                        s1 += 2 * math.pi
                    if d < 0:
                        c2 = c2.Reversed()
                        s0, s1 = c2.ReversedParameter(s0), c2.ReversedParameter(s1)
                        if s1 <= s0:
                            s1 += 2 * math.pi
                    B.UpdateEdge(E, c2, faces[f], float(etol[e]))
                    B.Range(E, faces[f], s0, s1)
                    fix_same_parameter = True
            elif f in face_plane and ci < 0:
                o, y, x = face_plane[f]
                P = b.vertex_point[[v0, v1]] - o
                uv = np.stack([P @ x, P @ y], axis=1)
                d = (uv[1] - uv[0]) / scale
                end_uv[e, side] = uv
                line = Geom2d_Line(gp_Pnt2d(uv[0, 0], uv[0, 1]), gp_Dir2d(d[0], d[1]))
                if abs(float(np.hypot(*d)) - 1.0) > 1e-12:
                    line = _bspline_curve2d(NurbsCurve(uv, [0.0, 0.0, scale, scale], 1))
                B.UpdateEdge(E, line, faces[f], float(etol[e]))
        if fix_same_parameter:
            B.SameRange(E, False)
            B.SameParameter(E, False)
            BRepLib.SameParameter_s(E, float(etol[e]))
            from OCP.BRep import BRep_Tool

            if BRep_Tool.Tolerance_s(E) < etol[e]:  # SameParameter sets the achieved value; keep coons's floor
                B.UpdateEdge(E, float(etol[e]))
        edges.append(E)

    # Wires (with degenerated edges across pole gaps), faces.
    for f in range(b.n_faces):
        F = faces[f]
        sense = bool(b.face_sense[f]) if b.face_surface[f] >= 0 else True
        for loop in b.face_loop_ids(f).tolist():
            cs = b.loop_coedges(int(loop))
            if cs.size == 0:
                raise InvalidInputError(f"to_ocp: face {f} has a lone-vertex loop {loop}; OCCT faces have no vertex loops")
            W = TopoDS_Wire()
            B.MakeWire(W)
            seq = []  # (shape, forward) in coons loop order
            n = len(cs)
            for k in range(n):
                c = int(cs[k])
                e, side = c >> 1, c & 1
                seq.append((edges[e], side == 0))
                # p-curve end of this coedge and start of the next, in the loop's direction
                nxt = int(cs[(k + 1) % n])
                uv_end = end_uv[e, side, 1 - side]
                uv_next = end_uv[nxt >> 1, nxt & 1, nxt & 1]
                if np.all(np.isfinite(uv_end)) and np.all(np.isfinite(uv_next)):
                    gap = float(np.hypot(*(uv_next - uv_end)))
                    if gap > 1e-9 * (1.0 + float(np.abs(uv_end).max())):
                        vtx = int(b.coedge_target[c])
                        seq.append((_degenerated(B, verts[vtx], uv_end, uv_next, F, float(vtol[vtx]), f), True))
            if not sense:
                seq = [(s, not fw) for s, fw in reversed(seq)]
            for s, fw in seq:
                B.Add(W, s.Oriented(TopAbs_FORWARD if fw else TopAbs_REVERSED))
            W.Closed(True)
            B.Add(F, W)
        if not sense:
            faces[f] = F.Oriented(TopAbs_REVERSED)

    lumps = []
    for lump in range(b.n_solids):
        S = TopoDS_Solid()
        B.MakeSolid(S)
        for sh in b.solid_shell_ids(lump).tolist():
            Sh = TopoDS_Shell()
            B.MakeShell(Sh)
            for f in b.shell_face_ids(sh).tolist():
                B.Add(Sh, faces[f])
            Sh.Closed(True)
            B.Add(S, Sh)
        lumps.append(S)
    if len(lumps) == 1:
        return lumps[0]
    comp = TopoDS_Compound()
    B.MakeCompound(comp)
    for S in lumps:
        B.Add(comp, S)
    return comp


def _degenerated(B, vertex, uv0: np.ndarray, uv1: np.ndarray, face, tol: float, f: int):
    """A degenerated edge at ``vertex`` whose p-curve runs straight from ``uv0`` to ``uv1`` on ``face``."""
    from OCP.Geom2d import Geom2d_Line
    from OCP.gp import gp_Dir2d, gp_Pnt2d
    from OCP.TopAbs import TopAbs_FORWARD, TopAbs_REVERSED
    from OCP.TopoDS import TopoDS_Edge

    d = np.asarray(uv1) - np.asarray(uv0)
    length = float(np.hypot(*d))
    if not length > 0:
        raise TopologyError(f"to_ocp: face {f}: pole gap of zero length at {uv0.tolist()}")
    E = TopoDS_Edge()
    B.MakeEdge(E)
    B.UpdateEdge(E, Geom2d_Line(gp_Pnt2d(uv0[0], uv0[1]), gp_Dir2d(d[0] / length, d[1] / length)), face, tol)
    B.Add(E, vertex.Oriented(TopAbs_FORWARD))
    B.Add(E, vertex.Oriented(TopAbs_REVERSED))
    B.Range(E, 0.0, length)
    B.Degenerated(E, True)
    return E


def to_build123d(solid, tol: Tolerance | None = None):
    """The solid as a ``build123d.Solid`` (a ``build123d.Compound`` of solids for several lumps).

    Raises
    ------
    InvalidInputError
        As :func:`to_ocp`.
    """
    import build123d as bd

    shape = to_ocp(solid, tol)
    from OCP.TopoDS import TopoDS_Solid

    return bd.Solid(shape) if isinstance(shape, TopoDS_Solid) else bd.Compound(shape)
