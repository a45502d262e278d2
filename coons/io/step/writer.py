"""STEP (ISO 10303-21, AP214 / AP242) export of coons solids as advanced B-reps.

:func:`export_step` writes each lump of a :class:`~coons.topology.shape.Solid` as a
``MANIFOLD_SOLID_BREP`` (a ``BREP_WITH_VOIDS`` when the lump has void shells) inside an
``ADVANCED_BREP_SHAPE_REPRESENTATION`` carried by one ``PRODUCT`` (the chain
PRODUCT → PRODUCT_DEFINITION_FORMATION → PRODUCT_DEFINITION → PRODUCT_DEFINITION_SHAPE →
SHAPE_DEFINITION_REPRESENTATION that OCCT, FreeCAD and other readers need to see a part),
in millimetres and radians, with the model tolerance as ``UNCERTAINTY_MEASURE_WITH_UNIT``.
It writes the exact geometry: planes, cylinders, cones, spheres, tori and B-spline surfaces
(rational ones as the complex ``RATIONAL_B_SPLINE_SURFACE`` entity); lines, circles, ellipses
and B-spline curves; and every p-curve as ``SURFACE_CURVE`` + ``PCURVE`` +
``DEFINITIONAL_REPRESENTATION`` (2-D line, circle, ellipse or B-spline).  It does not write
assemblies, colours, names of faces, PMI, meshes or anything read back by
:mod:`coons.io.step.reader`; it writes no seam or degenerate edge because coons has none
(readers such as OCCT add degenerate edges at poles themselves, as they do for the STEP
files OCCT writes).

Conventions (ISO 10303-42; OCCT's ``StepToGeom`` reads them the same way)
-------------------------------------------------------------------------
* Parametrisations of LINE, CIRCLE, ELLIPSE, PLANE, CYLINDRICAL_SURFACE, CONICAL_SURFACE,
  SPHERICAL_SURFACE and TOROIDAL_SURFACE are those of :mod:`coons.kernel.analytic`
  (angles from the placement's ``ref_direction``; a cone's ``radius`` is at the placement's
  origin).  STEP requires a positive cone ``semi_angle``: a coons cone with ``a < 0`` is
  written about the reversed axis with ``-a``, i.e. ``S'(u', v') = S(-u', -v')``, and its
  p-curves are mapped by ``(u, v) -> (-u, -v)``; the surface normal is unchanged.
* An ``EDGE_CURVE`` carries no parameters: the vertices bound it, and the reader projects
  them on the curve.  Straight edges without a curve (``t ∈ [0, 1]``) become a LINE of unit
  direction (parameter ``L t``) and their p-curves are re-parametrised to match.  2-D circles
  and ellipses need a right-handed placement with the major axis as reference: a
  :class:`~coons.kernel.pcurve.Trig2D` ``C + cos t A + sin t B`` is written as the ellipse of
  the same point set whose parameter is ``±t + φ`` (principal axes of ``[A B]`` by the SVD);
  readers recompute p-curve ranges by projecting the vertices (OCCT: ``ShapeFix_EdgeProjAux``).
* Faces: ``ADVANCED_FACE.same_sense`` is ``face_sense``; loops are written as stored (face on
  the left, seen from outside), so every ``FACE_BOUND`` has orientation ``.T.``; the first
  loop is the ``FACE_OUTER_BOUND``.  Faces without a surface (polyhedra) get a PLANE through
  their first vertex with the Newell normal of their outer loop.
* Each face has its own surface entity.  A sphere face is written on a placement turned about
  the axis to the face's smallest ``u`` (its p-curves moved by ``-u``): OCCT 8's reader builds
  the complementary region of a sphere face spanning ``u ∈ [π, 2π]`` and cannot read OCCT's own
  file of such a solid either (``tests/io/test_step_catalogue.py``, sphere_sphere_difference).
  P-curves of circle and ellipse edges use the base turn ``[0, 2π)`` of the edge's start, the
  parameters a reader derives from the vertices.
* Void shells are ``ORIENTED_CLOSED_SHELL(.F.)`` of a closed shell whose faces are written
  with ``same_sense`` and loop orientation inverted (the void's own outward orientation),
  as ISO 10303-42 ``brep_with_voids`` requires.

Output is deterministic: the same solid gives the same bytes (a fixed time stamp in
FILE_NAME, entities numbered in table order, reals in Python's shortest round-trip form with
the STEP decimal point and exponent, e.g. ``1.E-07``).  The file is written to a temporary
file in the destination folder and renamed into place.

References: ISO 10303-21 (clear text encoding), ISO 10303-42 (geometric and topological
representation), the CAx-IF "Recommended Practices for AP242" (units, uncertainty).
"""

from __future__ import annotations

import math
import os
import tempfile
from pathlib import Path

import numpy as np

from coons.errors import InvalidInputError, StepError
from coons.kernel.analytic import (
    Circle,
    ConicalSurface,
    CylindricalSurface,
    Ellipse,
    Line,
    PlanarSurface,
    TWO_PI,
    SphericalSurface,
    ToroidalSurface,
)
from coons.kernel.curve import NurbsCurve
from coons.kernel.pcurve import Line2D, Trig2D, _affine2
from coons.kernel.surface import NurbsSurface
from coons.tolerance import Tolerance, resolve

__all__ = ["export_step", "step_text", "SCHEMAS"]

#: The FILE_SCHEMA strings OCCT 8 writes for each supported application protocol.
SCHEMAS: dict[str, str] = {
    "AP214": "AUTOMOTIVE_DESIGN { 1 0 10303 214 1 1 1 1 }",
    "AP242": "AP242_MANAGED_MODEL_BASED_3D_ENGINEERING_MIM_LF {1 0 10303 442 1 1 4 }",
}

#: FILE_NAME time stamp: fixed so that the same solid always gives the same bytes.
_TIMESTAMP = "2000-01-01T00:00:00"


# ---------------------------------------------------------------------------- formatting
def _reals(values) -> list[str]:
    """STEP REAL tokens of a float array (shortest round-trip digits), in C order.

    ``repr`` gives the shortest string that reads back to the same double; STEP needs a
    decimal point in the mantissa and an upper-case exponent (``1e-05`` -> ``1.E-05``).
    One ``tolist`` and one ``repr`` per value: the formatting cost is Python's float repr,
    with no per-call numpy overhead (this runs for every point and direction of the file).

    Raises
    ------
    StepError
        A value is NaN or infinite.
    """
    if isinstance(values, np.ndarray) and values.dtype == np.float64:
        vals = values.ravel().tolist()
    else:
        vals = np.asarray(values, dtype=np.float64).ravel().tolist()
    out = list(map(repr, vals))
    for i, s in enumerate(out):
        if "e" in s or "n" in s:  # exponent, or 'inf' / 'nan'
            if not math.isfinite(vals[i]):
                raise StepError(f"cannot write non-finite reals, expected finite values, got {vals[i]!r}")
            m, e = s.split("e")
            out[i] = (m if "." in m else m + ".") + "E" + e
    return out


def _real(x: float) -> str:
    return _reals([x])[0]


def _string(s: str) -> str:
    """A STEP string literal (apostrophes doubled; non-ASCII replaced)."""
    return "'" + s.encode("ascii", "replace").decode("ascii").replace("'", "''") + "'"


def _ids(ids) -> str:
    return "(" + ",".join(f"#{int(i)}" for i in ids) + ")"


def _bool(b: bool) -> str:
    return ".T." if b else ".F."


class _Out:
    """Entity list: ``add`` appends one instance and returns its id (ids in order of creation)."""

    def __init__(self) -> None:
        self.lines: list[str] = []

    @property
    def next_id(self) -> int:
        return len(self.lines) + 1

    def add(self, text: str) -> int:
        self.lines.append(text)
        return len(self.lines)

    def add_many(self, texts: list[str]) -> int:
        """Append instances; returns the id of the first."""
        first = len(self.lines) + 1
        self.lines.extend(texts)
        return first

    def point(self, p) -> int:
        return self.add(f"CARTESIAN_POINT('',({','.join(_reals(p))}))")

    def points(self, P: np.ndarray) -> np.ndarray:
        """CARTESIAN_POINTs of the rows of ``P`` ``(n, d)``, one join per point; ids ``(n,)``."""
        P = np.asarray(P, dtype=np.float64)
        n, d = P.shape
        toks = _reals(P)
        first = self.add_many(
            ["CARTESIAN_POINT('',(" + ",".join(toks[d * i : d * i + d]) + "))" for i in range(n)]
        )
        return np.arange(first, first + n)

    def direction(self, d) -> int:
        return self.add(f"DIRECTION('',({','.join(_reals(d))}))")

    def axis3(self, origin, z, x) -> int:
        o = self.point(origin)
        zi = self.direction(z)
        xi = self.direction(x)
        return self.add(f"AXIS2_PLACEMENT_3D('',#{o},#{zi},#{xi})")

    def axis2(self, origin, x) -> int:
        o = self.point(origin)
        xi = self.direction(x)
        return self.add(f"AXIS2_PLACEMENT_2D('',#{o},#{xi})")

    def text(self) -> str:
        return "".join(f"#{i}={s};\n" for i, s in enumerate(self.lines, start=1))


# ---------------------------------------------------------------------------- geometry
def _knot_lists(knots) -> tuple[str, str]:
    vals, mult = np.unique(np.asarray(knots, dtype=np.float64), return_counts=True)
    return "(" + ",".join(str(int(m)) for m in mult) + ")", "(" + ",".join(_reals(vals)) + ")"


def _bspline_curve(out: _Out, c: NurbsCurve) -> int:
    pts = out.points(c.control_points)
    mult, knots = _knot_lists(c.knots)
    deg = int(c.degree)
    if c.is_rational:
        w = "(" + ",".join(_reals(c.weights)) + ")"
        return out.add(
            f"( BOUNDED_CURVE() B_SPLINE_CURVE({deg},{_ids(pts)},.UNSPECIFIED.,.F.,.F.) "
            f"B_SPLINE_CURVE_WITH_KNOTS({mult},{knots},.UNSPECIFIED.) CURVE() GEOMETRIC_REPRESENTATION_ITEM() "
            f"RATIONAL_B_SPLINE_CURVE({w}) REPRESENTATION_ITEM('') )"
        )
    return out.add(f"B_SPLINE_CURVE_WITH_KNOTS('',{deg},{_ids(pts)},.UNSPECIFIED.,.F.,.F.,{mult},{knots},.UNSPECIFIED.)")


def _bspline_surface(out: _Out, s: NurbsSurface) -> int:
    P = np.asarray(s.control_points, dtype=np.float64)
    nu, nv = P.shape[:2]
    ids = out.points(P.reshape(-1, 3)).reshape(nu, nv)
    grid = "(" + ",".join(_ids(row) for row in ids) + ")"
    mu, ku = _knot_lists(s.knots_u)
    mv, kv = _knot_lists(s.knots_v)
    du, dv = int(s.degree_u), int(s.degree_v)
    if s.is_rational:
        W = np.asarray(s.weights, dtype=np.float64)
        toks = _reals(W)
        w = "(" + ",".join("(" + ",".join(toks[i * nv : (i + 1) * nv]) + ")" for i in range(nu)) + ")"
        return out.add(
            f"( BOUNDED_SURFACE() B_SPLINE_SURFACE({du},{dv},{grid},.UNSPECIFIED.,.F.,.F.,.F.) "
            f"B_SPLINE_SURFACE_WITH_KNOTS({mu},{mv},{ku},{kv},.UNSPECIFIED.) GEOMETRIC_REPRESENTATION_ITEM() "
            f"RATIONAL_B_SPLINE_SURFACE({w}) REPRESENTATION_ITEM('') SURFACE() )"
        )
    return out.add(
        f"B_SPLINE_SURFACE_WITH_KNOTS('',{du},{dv},{grid},.UNSPECIFIED.,.F.,.F.,.F.,{mu},{mv},{ku},{kv},.UNSPECIFIED.)"
    )


def _line(out: _Out, origin, direction) -> int:
    p = out.point(origin)
    d = out.direction(direction)
    v = out.add(f"VECTOR('',#{d},1.)")
    return out.add(f"LINE('',#{p},#{v})")


def _curve3d(out: _Out, c) -> int:
    """The 3-D curve entity of a coons curve.

    Raises
    ------
    StepError
        An unsupported curve type.
    """
    if isinstance(c, Line):
        return _line(out, c.origin, c.direction)
    if isinstance(c, Circle):
        ax = out.axis3(c.center, c.axis, c.x_dir)
        return out.add(f"CIRCLE('',#{ax},{_real(c.radius)})")
    if isinstance(c, Ellipse):
        ax = out.axis3(c.center, c.axis, c.x_dir)
        return out.add(f"ELLIPSE('',#{ax},{_real(c.major_radius)},{_real(c.minor_radius)})")
    if isinstance(c, NurbsCurve):
        if c.dimension != 3:
            raise StepError(f"3-D edge curve expected, got a NurbsCurve of dimension {c.dimension}")
        return _bspline_curve(out, c)
    raise StepError(f"unsupported edge curve type {type(c).__name__}; expected Line, Circle, Ellipse or NurbsCurve")


def _surface(out: _Out, s) -> tuple[int, np.ndarray | None]:
    """The surface entity of a coons surface and the 2-D linear map of its p-curves (None: identity).

    Raises
    ------
    StepError
        An unsupported surface type.
    """
    if isinstance(s, PlanarSurface):
        return out.add(f"PLANE('',#{out.axis3(s.origin, s.axis, s.x_dir)})"), None
    if isinstance(s, CylindricalSurface):
        return out.add(f"CYLINDRICAL_SURFACE('',#{out.axis3(s.origin, s.axis, s.x_dir)},{_real(s.radius)})"), None
    if isinstance(s, ConicalSurface):
        a = float(s.semi_angle)
        if a > 0:
            ax = out.axis3(s.origin, s.axis, s.x_dir)
            return out.add(f"CONICAL_SURFACE('',#{ax},{_real(s.radius)},{_real(a)})"), None
        # STEP wants semi_angle > 0: same cone about -Z, S'(u', v') = S(-u', -v').
        ax = out.axis3(s.origin, -np.asarray(s.axis), s.x_dir)
        return out.add(f"CONICAL_SURFACE('',#{ax},{_real(s.radius)},{_real(-a)})"), -np.eye(2)
    if isinstance(s, SphericalSurface):
        return out.add(f"SPHERICAL_SURFACE('',#{out.axis3(s.center, s.axis, s.x_dir)},{_real(s.radius)})"), None
    if isinstance(s, ToroidalSurface):
        ax = out.axis3(s.center, s.axis, s.x_dir)
        return out.add(f"TOROIDAL_SURFACE('',#{ax},{_real(s.major_radius)},{_real(s.minor_radius)})"), None
    if isinstance(s, NurbsSurface):
        if s.dimension != 3:
            raise StepError(f"3-D face surface expected, got a NurbsSurface of dimension {s.dimension}")
        return _bspline_surface(out, s), None
    raise StepError(
        f"unsupported surface type {type(s).__name__}; expected PlanarSurface, CylindricalSurface, "
        "ConicalSurface, SphericalSurface, ToroidalSurface or NurbsSurface"
    )


def _face_u_min(b, f: int) -> float:
    """The smallest ``u`` of face ``f``'s p-curves (sampled at nine points per edge use)."""
    lo = math.inf
    for loop in b.face_loop_ids(f).tolist():
        for c in b.loop_coedges(loop).tolist():
            e, side = c >> 1, c & 1
            pi = int(b.edge_pcurve[e, side])
            if pi < 0:
                return 0.0
            t0, t1 = b.edge_range[e]
            lo = min(lo, float(np.min(np.asarray(b.pcurves[pi].evaluate(np.linspace(t0, t1, 9)))[:, 0])))
    return lo if math.isfinite(lo) else 0.0


def _sphere_from(out: _Out, s, u_min: float) -> tuple[int, np.ndarray | None]:
    """A sphere face's SPHERICAL_SURFACE, its placement turned about the axis so that the face starts at ``u = 0``.

    OCCT's reader (OCCT 8) misplaces the p-curves of a sphere face that spans ``u ∈ [π, 2π]`` (the
    second half of a sphere cut along meridians, as coons faces are): it reads those at ``u = 2π``
    as ``u = 0`` and builds the complementary region; it cannot read its own STEP file of such a
    solid either (tests/io/test_step_catalogue.py, sphere_sphere_difference).  Faces starting at
    ``u = 0`` read correctly, so each sphere face is written on its own placement, turned by its
    smallest ``u``, with its p-curves moved by ``-u`` (the 2-D map returned).
    """
    whole = TWO_PI * round(u_min / TWO_PI)
    turn = whole if abs(u_min - whole) <= 1e-9 else u_min  # a face starting at 0 up to round-off stays put
    if turn == 0.0:
        return _surface(out, s)
    x = np.asarray(s.x_dir, dtype=np.float64)
    if turn != whole:  # whole turns move only the p-curves
        x = math.cos(turn) * x + math.sin(turn) * np.cross(np.asarray(s.axis, dtype=np.float64), x)
    sid = out.add(f"SPHERICAL_SURFACE('',#{out.axis3(s.center, s.axis, x)},{_real(s.radius)})")
    return sid, np.array([[1.0, 0.0, -turn], [0.0, 1.0, 0.0]])


def _ellipse_of(center: np.ndarray, A: np.ndarray, B: np.ndarray) -> tuple[np.ndarray, np.ndarray, float, float]:
    """Principal form of ``C + cos t A + sin t B``: ``(C, X, a, b)`` with ``X`` unit, ``a >= b``.

    The columns of ``[A B] = U diag(a, b) V^T`` (SVD): the point set is the ellipse with
    semi-axes ``a U_0``, ``b U_1``; its right-handed placement takes ``X = U_0``.
    """
    la, lb = math.hypot(A[0], A[1]), math.hypot(B[0], B[1])
    if A[0] * B[0] + A[1] * B[1] == 0.0:  # already principal (every circle of coons's planes)
        return (center, A / la, la, lb) if la >= lb else (center, B / lb, lb, la)
    U, sv, _ = np.linalg.svd(np.column_stack([A, B]))
    return center, U[:, 0], float(sv[0]), float(sv[1])


def _curve2d(out: _Out, pc, scale: float, lin: np.ndarray | None) -> int:
    """The 2-D curve entity of a p-curve after ``t -> scale t`` and ``uv -> lin uv``.

    Raises
    ------
    StepError
        An unsupported p-curve type.
    """
    if lin is not None:
        if isinstance(pc, (Line2D, Trig2D)):
            pc = pc.transformed(lin)
        elif isinstance(pc, NurbsCurve):
            M, shift = _affine2(lin)  # the p-curves' own reading of a 2-D affine map
            pc = NurbsCurve(np.asarray(pc.control_points) @ M.T + shift, pc.knots, pc.degree, pc.weights)
    if isinstance(pc, Line2D):
        d = np.asarray(pc.direction) / scale
        speed = float(np.hypot(*d))
        p = out.point(pc.origin)
        di = out.direction(d / speed)
        v = out.add(f"VECTOR('',#{di},{_real(speed)})")
        return out.add(f"LINE('',#{p},#{v})")
    if isinstance(pc, Trig2D):
        C, X, a, b = _ellipse_of(np.asarray(pc.center), np.asarray(pc.a), np.asarray(pc.b))
        ax = out.axis2(C, X)
        if math.isclose(a, b, rel_tol=1e-12):  # equal radii to round-off: a CIRCLE (an ELLIPSE would do too)
            return out.add(f"CIRCLE('',#{ax},{_real(a)})")
        return out.add(f"ELLIPSE('',#{ax},{_real(a)},{_real(b)})")
    if isinstance(pc, NurbsCurve):
        if scale != 1.0:
            lo, hi = pc.domain
            pc = pc.reparametrized(lo * scale, hi * scale)
        return _bspline_curve(out, pc)
    raise StepError(f"unsupported p-curve type {type(pc).__name__}; expected Line2D, Trig2D or a 2-D NurbsCurve")


def _period_shift(curve, t0: float) -> float:
    """The whole turns ``2πk`` that bring an edge's start ``t0`` on a circle or ellipse into ``[0, 2π)``.

    A reader knows a closed curve's edge only by its vertices, whose parameters it takes in the
    curve's base period (OCCT: ``[0, 2π)``, the end one period later if need be); the edge's
    p-curves must use the same parameters, so they are written advanced by this shift.
    """
    if type(curve) not in (Circle, Ellipse):
        return 0.0
    k = math.floor(t0 / TWO_PI)
    if t0 - k * TWO_PI > TWO_PI * (1.0 - 1e-12):  # the start of the next turn up to round-off
        k += 1
    return k * TWO_PI


def _advanced(pc, shift: float):
    """The p-curve ``t -> pc(t + shift)`` (a Trig2D is unchanged by whole turns)."""
    if shift == 0.0 or isinstance(pc, Trig2D):
        return pc
    if isinstance(pc, Line2D):
        return Line2D(np.asarray(pc.origin) + shift * np.asarray(pc.direction), pc.direction)
    if isinstance(pc, NurbsCurve):
        lo, hi = pc.domain
        return pc.reparametrized(lo - shift, hi - shift)
    return pc  # _curve2d reports the unsupported type


def _newell_plane(P: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(origin, normal, x_dir)`` of the plane of a closed polygon ``P (n, 3)`` (Newell's normal)."""
    Q = np.roll(P, -1, axis=0)
    n = np.array(
        [
            np.sum((P[:, 1] - Q[:, 1]) * (P[:, 2] + Q[:, 2])),
            np.sum((P[:, 2] - Q[:, 2]) * (P[:, 0] + Q[:, 0])),
            np.sum((P[:, 0] - Q[:, 0]) * (P[:, 1] + Q[:, 1])),
        ]
    )
    length = float(np.linalg.norm(n))
    if length == 0.0:
        raise StepError(f"a polygonal face of {len(P)} vertices has no area (zero Newell normal); cannot write its plane")
    n = n / length
    e = np.zeros(3)
    e[int(np.argmin(np.abs(n)))] = 1.0
    x = e - n * (e @ n)
    return P[0], n, x / np.linalg.norm(x)


# ---------------------------------------------------------------------------- main
def step_text(shape, *, schema: str = "AP214", tol: Tolerance | None = None, name: str | None = None) -> str:
    """The ISO 10303-21 text of a solid (what :func:`export_step` writes).

    Parameters and errors as :func:`export_step`.
    """
    from coons.topology.shape import Solid

    if not isinstance(shape, Solid):
        raise InvalidInputError(f"export_step needs a coons Solid, got {type(shape).__name__}")
    if shape.is_empty:
        raise InvalidInputError("export_step needs a non-empty solid, got the empty solid (0 faces)")
    if schema not in SCHEMAS:
        raise InvalidInputError(f"schema must be one of {sorted(SCHEMAS)}, got {schema!r}")
    t = resolve(tol)
    name = "coons" if name is None else str(name)
    b = shape.brep
    out = _Out()

    # -- product chain (AP214 / AP242 "part")
    if schema == "AP214":
        app = out.add("APPLICATION_CONTEXT('core data for automotive mechanical design processes')")
        out.add(f"APPLICATION_PROTOCOL_DEFINITION('international standard','automotive_design',2000,#{app})")
    else:
        app = out.add("APPLICATION_CONTEXT('Managed model based 3d engineering')")
        out.add(
            "APPLICATION_PROTOCOL_DEFINITION('international standard',"
            f"'ap242_managed_model_based_3d_engineering',2013,#{app})"
        )
    pctx = out.add(f"PRODUCT_CONTEXT('',#{app},'mechanical')")
    prod = out.add(f"PRODUCT({_string(name)},{_string(name)},'',(#{pctx}))")
    out.add(f"PRODUCT_RELATED_PRODUCT_CATEGORY('part',$,(#{prod}))")
    form = out.add(f"PRODUCT_DEFINITION_FORMATION('','',#{prod})")
    pdctx = out.add(f"PRODUCT_DEFINITION_CONTEXT('part definition',#{app},'design')")
    pdef = out.add(f"PRODUCT_DEFINITION('design','',#{form},#{pdctx})")
    pds = out.add(f"PRODUCT_DEFINITION_SHAPE('','',#{pdef})")
    sdr_at = out.add("")  # SHAPE_DEFINITION_REPRESENTATION, filled once the representation id is known
    # -- units and uncertainty
    mm = out.add("( LENGTH_UNIT() NAMED_UNIT(*) SI_UNIT(.MILLI.,.METRE.) )")
    rad = out.add("( NAMED_UNIT(*) PLANE_ANGLE_UNIT() SI_UNIT($,.RADIAN.) )")
    sr = out.add("( NAMED_UNIT(*) SI_UNIT($,.STERADIAN.) SOLID_ANGLE_UNIT() )")
    unc = out.add(
        f"UNCERTAINTY_MEASURE_WITH_UNIT(LENGTH_MEASURE({_real(t.linear)}),#{mm},"
        "'distance_accuracy_value','confusion accuracy')"
    )
    ctx3 = out.add(
        f"( GEOMETRIC_REPRESENTATION_CONTEXT(3) GLOBAL_UNCERTAINTY_ASSIGNED_CONTEXT((#{unc})) "
        f"GLOBAL_UNIT_ASSIGNED_CONTEXT((#{mm},#{rad},#{sr})) "
        "REPRESENTATION_CONTEXT('Context #1','3D Context with UNIT and UNCERTAINTY') )"
    )
    ctx2 = out.add(
        "( GEOMETRIC_REPRESENTATION_CONTEXT(2) PARAMETRIC_REPRESENTATION_CONTEXT() "
        "REPRESENTATION_CONTEXT('2D SPACE','') )"
    )
    world = out.axis3((0.0, 0.0, 0.0), (0.0, 0.0, 1.0), (1.0, 0.0, 0.0))

    # -- vertices: one CARTESIAN_POINT and one VERTEX_POINT per vertex, generated in bulk
    pts = out.points(b.vertex_point)
    vfirst = out.add_many([f"VERTEX_POINT('',#{p})" for p in pts.tolist()])
    vid = np.arange(vfirst, vfirst + b.n_vertices)

    # -- surfaces, one entity per face (also where faces share a coons surface: the halves of a
    # sphere or cylinder; a sphere face gets its own turned placement, _sphere_from), and planes
    # of polyhedral faces.
    face_surf = np.zeros(b.n_faces, dtype=np.int64)
    face_lin: list[np.ndarray | None] = [None] * b.n_faces
    for f in range(b.n_faces):
        si = int(b.face_surface[f])
        if si >= 0:
            S = b.surfaces[si]
            if isinstance(S, SphericalSurface):
                face_surf[f], face_lin[f] = _sphere_from(out, S, _face_u_min(b, f))
            else:
                face_surf[f], face_lin[f] = _surface(out, S)
        else:
            loop = int(b.face_loop_ids(f)[0])
            cs = b.loop_coedges(loop)
            if cs.size < 3:
                raise StepError(f"face {f} has no surface and an outer loop of {cs.size} edges; expected >= 3")
            o, n, x = _newell_plane(b.vertex_point[b.coedge_origin[cs]])
            face_surf[f] = out.add(f"PLANE('',#{out.axis3(o, n, x)})")

    # -- edges: 3-D curve (shared curves once), p-curves, EDGE_CURVE
    curve_cache: dict[int, int] = {}
    edge_id = np.zeros(b.n_edges, dtype=np.int64)
    face_of = b.edge_face
    P = b.vertex_point
    for e in range(b.n_edges):
        ci = int(b.edge_curve[e])
        scale = 1.0
        if ci >= 0:
            if ci not in curve_cache:
                curve_cache[ci] = _curve3d(out, b.curves[ci])
            cid = curve_cache[ci]
        else:
            a_, b_ = P[b.edge_vertex[e]]
            d = b_ - a_
            scale = float(np.linalg.norm(d))
            if scale == 0.0:
                raise StepError(f"straight edge {e} has coincident end points; expected a positive length")
            cid = _line(out, a_, d / scale)
        shift = _period_shift(b.curves[ci], float(b.edge_range[e, 0])) if ci >= 0 else 0.0
        pcs = []
        for side in (0, 1):
            pi = int(b.edge_pcurve[e, side])
            if pi < 0:
                continue
            f = int(face_of[e, side])
            c2 = _curve2d(out, _advanced(b.pcurves[pi], shift), scale, face_lin[f])
            rep = out.add(f"DEFINITIONAL_REPRESENTATION('',(#{c2}),#{ctx2})")
            pcs.append(out.add(f"PCURVE('',#{face_surf[f]},#{rep})"))
        if pcs:
            cid = out.add(f"SURFACE_CURVE('',#{cid},{_ids(pcs)},.PCURVE_S1.)")
        v0, v1 = b.edge_vertex[e]
        edge_id[e] = out.add(f"EDGE_CURVE('',#{vid[v0]},#{vid[v1]},#{cid},.T.)")

    # -- faces, written once per orientation needed (voids use the reversed orientation)
    def write_face(f: int, flip: bool) -> int:
        bounds = []
        for k, loop in enumerate(b.face_loop_ids(f)):
            cs = b.loop_coedges(int(loop))
            if cs.size == 0:
                lp = out.add(f"VERTEX_LOOP('',#{vid[int(b.loop_vertex[loop])]})")
            else:
                oe = [
                    out.add(f"ORIENTED_EDGE('',*,*,#{edge_id[c >> 1]},{_bool((c & 1) == 0)})")
                    for c in cs.tolist()
                ]
                lp = out.add(f"EDGE_LOOP('',{_ids(oe)})")
            kind = "FACE_OUTER_BOUND" if k == 0 else "FACE_BOUND"
            bounds.append(out.add(f"{kind}('',#{lp},{_bool(not flip)})"))
        sense = bool(b.face_sense[f]) if b.face_surface[f] >= 0 else True
        return out.add(f"ADVANCED_FACE('',{_ids(bounds)},#{face_surf[f]},{_bool(sense != flip)})")

    items = [world]
    for lump in range(b.n_solids):
        shells = b.solid_shell_ids(lump)
        outer = None
        voids = []
        for k, sh in enumerate(shells.tolist()):
            faces = [write_face(int(f), k > 0) for f in b.shell_face_ids(sh)]
            cs = out.add(f"CLOSED_SHELL('',{_ids(faces)})")
            if k == 0:
                outer = cs
            else:
                voids.append(out.add(f"ORIENTED_CLOSED_SHELL('',*,#{cs},.F.)"))
        if voids:
            items.append(out.add(f"BREP_WITH_VOIDS('',#{outer},{_ids(voids)})"))
        else:
            items.append(out.add(f"MANIFOLD_SOLID_BREP('',#{outer})"))
    rep = out.add(f"ADVANCED_BREP_SHAPE_REPRESENTATION({_string(name)},{_ids(items)},#{ctx3})")
    out.lines[sdr_at - 1] = f"SHAPE_DEFINITION_REPRESENTATION(#{pds},#{rep})"

    header = (
        "ISO-10303-21;\nHEADER;\n"
        "FILE_DESCRIPTION(('coons solid model'),'2;1');\n"
        f"FILE_NAME({_string(name)},'{_TIMESTAMP}',(''),(''),'coons STEP writer','coons','');\n"
        f"FILE_SCHEMA(('{SCHEMAS[schema]}'));\n"
        "ENDSEC;\nDATA;\n"
    )
    return header + out.text() + "ENDSEC;\nEND-ISO-10303-21;\n"


def export_step(shape, path, *, schema: str = "AP214", tol: Tolerance | None = None, name: str | None = None) -> Path:
    """Write a solid as a STEP file (ISO 10303-21, AP214 or AP242 advanced B-rep).

    Parameters
    ----------
    shape : Solid
        A non-empty coons solid (every lump, with its voids, becomes one solid B-rep).
    path : str or os.PathLike
        Destination; written to a temporary file in the same folder, then renamed into place.
    schema : {"AP214", "AP242"}
        The application protocol named in FILE_SCHEMA (the entities written are the same).
    tol : Tolerance, optional
        ``tol.linear`` is written as the model's length uncertainty (default 1e-7 mm).
    name : str, optional
        Product and representation name (default ``"coons"``).

    Returns
    -------
    Path
        The path written.

    Raises
    ------
    InvalidInputError
        ``shape`` is not a Solid, or is empty; unknown ``schema``.
    StepError
        A surface, curve or p-curve type STEP export does not support, or non-finite geometry.
    """
    text = step_text(shape, schema=schema, tol=tol, name=name)
    path = Path(os.fspath(path))
    fd, tmp = tempfile.mkstemp(prefix=".tmp-", suffix=path.suffix, dir=path.parent if str(path.parent) else ".")
    try:
        with os.fdopen(fd, "wb") as fh:
            fh.write(text.encode("ascii"))
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise
    return path
