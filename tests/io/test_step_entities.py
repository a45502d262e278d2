"""STEP entities beyond the analytic/B-spline core: swept, offset and faceted geometry, seams on NURBS.

OCCT writes the swept solids here (``BRepPrimAPI_MakePrism`` / ``MakeRevol`` give
``Geom_SurfaceOfLinearExtrusion`` / ``Geom_SurfaceOfRevolution``, which ``STEPControl_Writer``
writes as SURFACE_OF_LINEAR_EXTRUSION / SURFACE_OF_REVOLUTION; the tests check the text).
Volumes are compared with OCCT's ``BRepGProp`` (eps 1e-10).  Areas of revolutions too; OCCT's
area integration does not converge on extrusion surfaces (68.32 / 68.70 / 68.64 for eps 1e-6 /
1e-10 / 1e-13 on the spline prism), so extrusion faces are compared with the closed form
``(v1 - v0) ∫ |Su × Sv| du`` (``|Su × Sv|`` does not depend on ``v``) integrated by scipy on
OCCT's own surface.

Hand-written files (ISO 10303-42 directly, no writer involved) cover FACETED_BREP / POLY_LOOP,
OFFSET_SURFACE of each analytic type and of a B-spline, OFFSET_CURVE_3D, seamless band faces
(a seam is inserted) and the StepError of each unsupported case; a small fuzz run feeds mutants
of these files to the reader.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from coons.errors import StepError
from coons.io.step.p21 import Ref, parse
from coons.io.step.reader import import_step, solids_from_p21
from coons.io.step.schema import StepModel
from coons.kernel import analytic as an
from coons.kernel.surface import NurbsSurface

RTOL = 1e-7


# ---------------------------------------------------------------------- OCCT-written swept solids
def _spline(points):
    from OCP.collections import Array1_gp_Pnt
    from OCP.GeomAPI import GeomAPI_PointsToBSpline
    from OCP.gp import gp_Pnt

    arr = Array1_gp_Pnt(1, len(points))
    for i, p in enumerate(points):
        arr.SetValue(i + 1, gp_Pnt(*p))
    return GeomAPI_PointsToBSpline(arr).Curve()


def _face(*edges):
    from OCP.BRepBuilderAPI import BRepBuilderAPI_MakeFace, BRepBuilderAPI_MakeWire

    w = BRepBuilderAPI_MakeWire()
    for e in edges:
        w.Add(e)
    return BRepBuilderAPI_MakeFace(w.Wire(), True).Face()


def _edge(*args):
    from OCP.BRepBuilderAPI import BRepBuilderAPI_MakeEdge
    from OCP.gp import gp_Pnt

    if len(args) == 2 and isinstance(args[0], tuple):
        return BRepBuilderAPI_MakeEdge(gp_Pnt(*args[0]), gp_Pnt(*args[1])).Edge()
    return BRepBuilderAPI_MakeEdge(*args).Edge()


def _spline_profile_face():
    return _face(_edge(_spline([(2, 0, 0), (3, 0, 1), (2.5, 0, 2), (4, 0, 3)])), _edge((4, 0, 3), (0, 0, 3)),
                 _edge((0, 0, 3), (0, 0, 0)), _edge((0, 0, 0), (2, 0, 0)))


def _ellipse_face():
    from OCP.gp import gp_Ax2, gp_Dir, gp_Elips, gp_Pnt

    return _face(_edge(gp_Elips(gp_Ax2(gp_Pnt(5, 0, 0), gp_Dir(0, 1, 0), gp_Dir(1, 0, 0)), 2.0, 1.0)))


def _skew_face():
    pts = [(1, -0.5, 0), (1, 0.5, 0), (1, 0.8, 2), (1, -0.5, 2)]
    return _face(*[_edge(pts[i], pts[(i + 1) % 4]) for i in range(4)])


def _shapes():
    from OCP.BRepPrimAPI import BRepPrimAPI_MakePrism, BRepPrimAPI_MakeRevol
    from OCP.gp import gp_Ax1, gp_Ax2, gp_Circ, gp_Dir, gp_Pnt, gp_Vec

    z = gp_Ax1(gp_Pnt(0, 0, 0), gp_Dir(0, 0, 1))
    spline_face = _face(_edge(_spline([(0, 0, 0), (3, 2, 0), (6, -1, 0), (10, 0, 0)])), _edge((10, 0, 0), (0, 0, 0)))
    disc = _face(_edge(gp_Circ(gp_Ax2(gp_Pnt(0, 0, 0), gp_Dir(0, 0, 1)), 2.0)))
    return {
        # B-spline swept along an oblique vector
        "prism-spline": (lambda: BRepPrimAPI_MakePrism(spline_face, gp_Vec(1, 2, 5)).Shape(), "SURFACE_OF_LINEAR_EXTRUSION"),
        # a circle swept obliquely: an elliptic cylinder with a seam (exact NURBS, split at the seam)
        "prism-circle": (lambda: BRepPrimAPI_MakePrism(disc, gp_Vec(1, 0.5, 3)).Shape(), "SURFACE_OF_LINEAR_EXTRUSION"),
        # B-spline profile, full turn: a closed NURBS with a seam edge, split there (stored as
        # tests/data/occt-revolution-spline.stp, read in test_revolved_spline_with_seam_stored)
        "revol-spline-360": (lambda: BRepPrimAPI_MakeRevol(_spline_profile_face(), z).Shape(), "SURFACE_OF_REVOLUTION"),
        "revol-spline-270": (lambda: BRepPrimAPI_MakeRevol(_spline_profile_face(), z, 1.5 * math.pi).Shape(),
                             "SURFACE_OF_REVOLUTION"),
        # a face in the plane x = 1 turned about Z: its slanted side is a LINE skew to the axis (a hyperboloid)
        "revol-skew-line": (lambda: BRepPrimAPI_MakeRevol(_skew_face(), z, 1.2).Shape(), "SURFACE_OF_REVOLUTION"),
        # ellipse profile: closed in both directions (two seams) / a wedge
        "revol-ellipse-360": (lambda: BRepPrimAPI_MakeRevol(_ellipse_face(), z).Shape(), "SURFACE_OF_REVOLUTION"),
        "revol-ellipse-1rad": (lambda: BRepPrimAPI_MakeRevol(_ellipse_face(), z, 1.0).Shape(), "SURFACE_OF_REVOLUTION"),
    }


def _write(shape, path) -> str:
    from OCP.STEPControl import STEPControl_AsIs, STEPControl_Writer

    w = STEPControl_Writer()
    w.Transfer(shape, STEPControl_AsIs)
    w.Write(str(path))
    return path.read_text()


def _occt_figures(shape) -> tuple[float, float]:
    """OCCT's volume, and the area with extrusion faces integrated in closed form (see the module docstring)."""
    from OCP.BRepAdaptor import BRepAdaptor_Surface
    from OCP.BRepGProp import BRepGProp
    from OCP.BRepTools import BRepTools
    from OCP.GeomAbs import GeomAbs_SurfaceType
    from OCP.gp import gp_Pnt, gp_Vec
    from OCP.GProp import GProp_GProps
    from OCP.TopAbs import TopAbs_FACE
    from OCP.TopExp import TopExp_Explorer
    from OCP.TopoDS import TopoDS
    from scipy.integrate import quad

    g = GProp_GProps()
    BRepGProp.VolumeProperties_s(shape, g, 1e-10)
    volume, area = g.Mass(), 0.0
    ex = TopExp_Explorer(shape, TopAbs_FACE)
    while ex.More():
        f = TopoDS.Face(ex.Current())
        ad = BRepAdaptor_Surface(f)
        if ad.GetType() == GeomAbs_SurfaceType.GeomAbs_SurfaceOfExtrusion:
            u0, u1, v0, v1 = BRepTools.UVBounds_s(f)
            p, su, sv = gp_Pnt(), gp_Vec(), gp_Vec()

            def density(u):
                ad.D1(u, v0, p, su, sv)
                return su.Crossed(sv).Magnitude()

            area += (v1 - v0) * quad(density, u0, u1, epsabs=1e-13, epsrel=1e-13, limit=200)[0]
        else:
            g = GProp_GProps()
            BRepGProp.SurfaceProperties_s(f, g, 1e-10)
            area += g.Mass()
        ex.Next()
    return volume, area


@pytest.mark.occt
@pytest.mark.parametrize("name", ["prism-spline", "prism-circle", "revol-spline-270", "revol-skew-line",
                                  "revol-ellipse-360", "revol-ellipse-1rad"])
def test_swept_solids_match_occt(name, tmp_path):
    build, entity = _shapes()[name]
    shape = build()
    text = _write(shape, tmp_path / f"{name}.step")
    assert f"{entity}(" in text
    s = import_step(tmp_path / f"{name}.step")
    assert s.check().ok
    volume, area = _occt_figures(shape)
    np.testing.assert_allclose(s.volume, volume, rtol=RTOL)
    np.testing.assert_allclose(s.area, area, rtol=RTOL)


@pytest.mark.occt
def test_offset_of_revolved_spline_solid_matches_occt(tmp_path):
    """OCCT's offset (arc joins) of the spline revolution: OFFSET_SURFACE of a SURFACE_OF_REVOLUTION.

    OCCT builds the result to edge tolerances of 3e-5 mm (its intersection curves), so the
    figures agree to that accuracy (relative 2e-6 here), not to the integration's 1e-7.
    """
    from OCP.BRepOffset import BRepOffset_Skin
    from OCP.BRepOffsetAPI import BRepOffsetAPI_MakeOffsetShape
    from OCP.GeomAbs import GeomAbs_JoinType

    m = BRepOffsetAPI_MakeOffsetShape()
    m.PerformByJoin(_shapes()["revol-spline-360"][0](), 0.2, 1e-7, BRepOffset_Skin, False, False,
                    GeomAbs_JoinType.GeomAbs_Arc)
    shape = m.Shape()
    text = _write(shape, tmp_path / "offset.step")
    assert "OFFSET_SURFACE(" in text
    s = import_step(tmp_path / "offset.step")
    assert s.check().ok
    volume, area = _occt_figures(shape)
    np.testing.assert_allclose([s.volume, s.area], [volume, area], rtol=2e-6)


def test_oblique_circle_prism_closed_form():
    """The OCCT-written oblique circular prism (stored): volume π r² h, area 2π r² + ∫|C' × V|."""
    from scipy.integrate import quad

    from tests.io.test_step_read import DATA

    s = import_step(DATA / "occt-prism-oblique-circle.stp")
    assert s.check().ok
    V = np.array([1.0, 0.5, 3.0])
    lateral = quad(lambda t: np.linalg.norm(np.cross(2.0 * np.array([-math.sin(t), math.cos(t), 0.0]), V)),
                   0.0, 2.0 * math.pi, epsabs=1e-13, epsrel=1e-13, limit=200)[0]
    np.testing.assert_allclose(s.volume, math.pi * 4.0 * 3.0, rtol=1e-9)
    np.testing.assert_allclose(s.area, 8.0 * math.pi + lateral, rtol=1e-9)


def test_revolved_spline_with_seam_stored():
    """The OCCT-written full revolution of a spline profile (stored): the closed NURBS face is split at its seam."""
    from tests.io.test_step_read import DATA

    s = import_step(DATA / "occt-revolution-spline.stp")
    assert s.check().ok
    assert s.brep.n_faces == 4  # the revolved face split in two at the seam, two planes
    # OCCT 8, BRepGProp eps 1e-10 (tests/data/README.md)
    np.testing.assert_allclose(s.volume, 71.33798183925815, rtol=RTOL)
    np.testing.assert_allclose(s.area, 151.72075766599403, rtol=RTOL)


# ---------------------------------------------------------------------- hand-written entities
_HEADER = ("ISO-10303-21;\nHEADER;\nFILE_DESCRIPTION((''),'2;1');\nFILE_NAME('t','',(''),(''),'','','');\n"
           "FILE_SCHEMA(('CONFIG_CONTROL_DESIGN'));\nENDSEC;\nDATA;\n")
_FOOTER = "ENDSEC;\nEND-ISO-10303-21;\n"


def _faceted_step(V: np.ndarray, faces: list[list[int]]) -> str:
    """A FACETED_BREP of POLY_LOOP faces (ISO 10303-42 faceted B-rep), written by hand."""
    lines, n = [], 0

    def add(text: str) -> int:
        nonlocal n
        n += 1
        lines.append(f"#{n}={text};")
        return n

    pts = [add(f"CARTESIAN_POINT('',({','.join(repr(float(c)) for c in p)}))") for p in V]
    fids = []
    for loop in faces:
        pl = add(f"POLY_LOOP('',({','.join(f'#{pts[i]}' for i in loop)}))")
        b = add(f"FACE_OUTER_BOUND('',#{pl},.T.)")
        P = V[loop]
        nrm = np.cross(P[1] - P[0], P[2] - P[0])
        nrm = nrm / np.linalg.norm(nrm)
        x = (P[1] - P[0]) / np.linalg.norm(P[1] - P[0])
        o = add(f"CARTESIAN_POINT('',({','.join(repr(float(c)) for c in P[0])}))")
        dz = add(f"DIRECTION('',({','.join(repr(float(c)) for c in nrm)}))")
        dx = add(f"DIRECTION('',({','.join(repr(float(c)) for c in x)}))")
        ax = add(f"AXIS2_PLACEMENT_3D('',#{o},#{dz},#{dx})")
        plane = add(f"PLANE('',#{ax})")
        fids.append(add(f"FACE_SURFACE('',(#{b}),#{plane},.T.)"))
    shell = add(f"CLOSED_SHELL('',({','.join(f'#{f}' for f in fids)}))")
    solid = add(f"FACETED_BREP('',#{shell})")
    u = add("( LENGTH_UNIT() NAMED_UNIT(*) SI_UNIT(.MILLI.,.METRE.) )")
    ctx = add(f"( GEOMETRIC_REPRESENTATION_CONTEXT(3) GLOBAL_UNIT_ASSIGNED_CONTEXT((#{u})) REPRESENTATION_CONTEXT('',''))")
    add(f"FACETED_BREP_SHAPE_REPRESENTATION('',(#{solid}),#{ctx})")
    return _HEADER + "\n".join(lines) + "\n" + _FOOTER


def _octahedron(a: float):
    V = np.array([[a, 0, 0], [-a, 0, 0], [0, a, 0], [0, -a, 0], [0, 0, a], [0, 0, -a]], dtype=float)
    F = [[0, 2, 4], [2, 1, 4], [1, 3, 4], [3, 0, 4], [2, 0, 5], [1, 2, 5], [3, 1, 5], [0, 3, 5]]
    return V, F


def test_faceted_brep_octahedron():
    a = 3.0
    s = solids_from_p21(parse(_faceted_step(*_octahedron(a))))[0]
    assert s.check().ok
    assert s.brep.n_faces == 8
    np.testing.assert_allclose(s.volume, 4.0 / 3.0 * a**3, rtol=1e-12)
    np.testing.assert_allclose(s.area, 8.0 * math.sqrt(3.0) / 2.0 * a**2, rtol=1e-12)


def test_faceted_brep_box_quads_share_edges():
    V = np.array([[0, 0, 0], [2, 0, 0], [2, 3, 0], [0, 3, 0], [0, 0, 4], [2, 0, 4], [2, 3, 4], [0, 3, 4]], float)
    F = [[0, 3, 2, 1], [4, 5, 6, 7], [0, 1, 5, 4], [1, 2, 6, 5], [2, 3, 7, 6], [3, 0, 4, 7]]
    s = solids_from_p21(parse(_faceted_step(V, F)))[0]
    assert s.check().ok
    np.testing.assert_allclose([s.volume, s.area], [24.0, 52.0], rtol=1e-12)


def test_poly_loop_repeated_point_is_step_error():
    V, F = _octahedron(1.0)
    F[0] = [0, 2, 4, 4]
    with pytest.raises(StepError, match="POLY_LOOP"):
        solids_from_p21(parse(_faceted_step(V, F)))


def _surface_of(text_entities: str, target: int):
    m = StepModel(parse(_HEADER + text_entities + "\n" + _FOOTER))
    return m, m.surface(Ref(target), next(x for x in m.file if x.id == target))


_FRAME = ("#1=CARTESIAN_POINT('',(1.,2.,3.));\n#2=DIRECTION('',(0.,0.6,0.8));\n#3=DIRECTION('',(1.,0.,0.));\n"
          "#4=AXIS2_PLACEMENT_3D('',#1,#2,#3);\n")


@pytest.mark.parametrize("basis, check", [
    ("PLANE('',#4)", lambda S: isinstance(S, an.PlanarSurface)),
    ("CYLINDRICAL_SURFACE('',#4,2.)", lambda S: isinstance(S, an.CylindricalSurface) and abs(S.radius - 2.5) < 1e-15),
    ("CONICAL_SURFACE('',#4,2.,0.4)", lambda S: isinstance(S, an.ConicalSurface)),
    ("SPHERICAL_SURFACE('',#4,2.)", lambda S: isinstance(S, an.SphericalSurface) and abs(S.radius - 2.5) < 1e-15),
    ("TOROIDAL_SURFACE('',#4,4.,1.)", lambda S: isinstance(S, an.ToroidalSurface)),
])
def test_offset_of_analytic_surfaces_is_exact(basis, check):
    """OFFSET_SURFACE of planes, cylinders, cones, spheres, tori: S + d N lies on the converted surface."""
    d = 0.5
    m, S = _surface_of(_FRAME + f"#5={basis};\n#6=OFFSET_SURFACE('',#5,{d},.F.);", 6)
    B = m.surface(Ref(5), next(x for x in m.file if x.id == 6))
    assert check(S)
    u, v = np.meshgrid(np.linspace(0.1, 1.2, 5), np.linspace(-0.3, 0.4, 5))
    P = np.asarray(B.evaluate(u, v)) + d * np.asarray(B.normal(u, v))
    Q = np.asarray(S.evaluate(*np.moveaxis(np.asarray(S.closest_parameters(P)), -1, 0)))
    np.testing.assert_allclose(Q, P, atol=1e-12)
    # the offset keeps the basis's normal direction
    n = np.asarray(S.normal(*np.moveaxis(np.asarray(S.closest_parameters(P)), -1, 0)))
    assert np.all(np.sum(n * np.asarray(B.normal(u, v)), axis=-1) > 1.0 - 1e-12)


def test_offset_of_bspline_surface_is_fitted_within_tolerance():
    pts = "\n".join(f"#{10 + 3 * i + j}=CARTESIAN_POINT('',({i}.,{j}.,{(i - 1) ** 2 * 0.5 + j * j * 0.3}));"
                    for i in range(3) for j in range(3))
    grid = ",".join("(" + ",".join(f"#{10 + 3 * i + j}" for j in range(3)) + ")" for i in range(3))
    text = (pts + f"\n#30=B_SPLINE_SURFACE_WITH_KNOTS('',2,2,({grid}),.UNSPECIFIED.,.F.,.F.,.F.,(3,3),(3,3),"
            "(0.,1.),(0.,1.),.UNSPECIFIED.);\n#31=OFFSET_SURFACE('',#30,-0.4,.F.);")
    m, S = _surface_of(text, 31)
    B = m.surface(Ref(30), next(x for x in m.file if x.id == 31))
    assert isinstance(S, NurbsSurface)
    u, v = np.meshgrid(np.linspace(0, 1, 23), np.linspace(0, 1, 19))
    P = np.asarray(B.evaluate(u, v)) - 0.4 * np.asarray(B.normal(u, v))
    assert np.max(np.linalg.norm(np.asarray(S.evaluate(u, v)) - P, axis=-1)) <= m.tol.linear


def test_offset_curves_of_line_and_circle_are_exact():
    """OFFSET_CURVE_3D: C + d (T × V)/|T × V| (OCCT's Geom_OffsetCurve convention)."""
    text = (_FRAME.replace("(0.,0.6,0.8)", "(0.,0.,1.)") +
            "#5=CIRCLE('',#4,2.);\n#6=DIRECTION('',(0.,0.,1.));\n#7=OFFSET_CURVE_3D('',#5,0.5,.F.,#6);\n"
            "#8=DIRECTION('',(1.,0.,0.));\n#9=VECTOR('',#8,1.);\n#10=LINE('',#1,#9);\n"
            "#11=OFFSET_CURVE_3D('',#10,0.5,.F.,#6);\n#12=DIRECTION('',(0.,0.,-1.));\n"
            "#13=OFFSET_CURVE_3D('',#5,0.5,.F.,#12);")
    m = StepModel(parse(_HEADER + text + "\n" + _FOOTER))
    e = next(iter(m.file))
    c = m.curve(Ref(7), e)
    assert isinstance(c, an.Circle) and c.radius == 2.5
    assert m.curve(Ref(13), e).radius == 1.5
    ln = m.curve(Ref(11), e)
    np.testing.assert_allclose(ln.origin, [1.0, 1.5, 3.0], atol=1e-15)  # T × V = x × z = -y


def test_unsupported_swept_profile_names_entity():
    """A circle profile crossing the axis of revolution (a spindle/sphere-like sweep) is refused by name."""
    text = (_FRAME.replace("(0.,0.6,0.8)", "(0.,1.,0.)") + "#5=CIRCLE('',#4,5.);\n#6=CARTESIAN_POINT('',(0.,0.,0.));\n"
            "#7=DIRECTION('',(0.,0.,1.));\n#8=AXIS1_PLACEMENT('',#6,#7);\n#9=SURFACE_OF_REVOLUTION('',#5,#8);")
    m = StepModel(parse(_HEADER + text + "\n" + _FOOTER))
    with pytest.raises(StepError, match="#9.*SURFACE_OF_REVOLUTION.*meeting the axis"):
        m.surface(Ref(9), next(iter(m.file)))


def _seamless_cylinder_step(r: float, h: float, top_angle: float, top_radius: float | None = None) -> str:
    """A cylinder whose side face is bounded by its two circles only (or, with ``top_radius``, a
    frustum whose side is a SURFACE_OF_REVOLUTION of a slanted LINE: a closed NURBS per face).

    Some writers leave out the seam edge; the top circle's vertex is at ``top_angle`` so that the
    inserted seam has to cut it.
    """
    rt = r if top_radius is None else top_radius
    ca, sa = math.cos(top_angle), math.sin(top_angle)
    side = (f"CYLINDRICAL_SURFACE('',#4,{float(r)})" if top_radius is None else
            f"SURFACE_OF_REVOLUTION('',#53,#54);\n#50=CARTESIAN_POINT('',({float(r)},0.,0.));\n"
            f"#51=DIRECTION('',({float(rt - r)},0.,{float(h)}));\n#52=VECTOR('',#51,1.);\n#53=LINE('',#50,#52);\n"
            "#54=AXIS1_PLACEMENT('',#1,#2)")
    text = f"""#1=CARTESIAN_POINT('',(0.,0.,0.));
#2=DIRECTION('',(0.,0.,1.));
#3=DIRECTION('',(1.,0.,0.));
#4=AXIS2_PLACEMENT_3D('',#1,#2,#3);
#5=CARTESIAN_POINT('',(0.,0.,{float(h)}));
#6=DIRECTION('',({ca},{sa},0.));
#7=AXIS2_PLACEMENT_3D('',#5,#2,#6);
#10=CIRCLE('',#4,{float(r)});
#11=CIRCLE('',#7,{float(rt)});
#12=CARTESIAN_POINT('',({float(r)},0.,0.));
#13=CARTESIAN_POINT('',({rt * ca},{rt * sa},{float(h)}));
#14=VERTEX_POINT('',#12);
#15=VERTEX_POINT('',#13);
#16=EDGE_CURVE('',#14,#14,#10,.T.);
#17=EDGE_CURVE('',#15,#15,#11,.T.);
#20=ORIENTED_EDGE('',*,*,#16,.T.);
#21=ORIENTED_EDGE('',*,*,#17,.F.);
#22=EDGE_LOOP('',(#20));
#23=EDGE_LOOP('',(#21));
#24=FACE_BOUND('',#22,.T.);
#25=FACE_BOUND('',#23,.T.);
#26={side};
#27=ADVANCED_FACE('',(#24,#25),#26,.T.);
#30=ORIENTED_EDGE('',*,*,#16,.F.);
#31=EDGE_LOOP('',(#30));
#32=FACE_OUTER_BOUND('',#31,.T.);
#33=PLANE('',#4);
#34=ADVANCED_FACE('',(#32),#33,.F.);
#35=ORIENTED_EDGE('',*,*,#17,.T.);
#36=EDGE_LOOP('',(#35));
#37=FACE_OUTER_BOUND('',#36,.T.);
#38=PLANE('',#7);
#39=ADVANCED_FACE('',(#37),#38,.T.);
#40=CLOSED_SHELL('',(#27,#34,#39));
#41=MANIFOLD_SOLID_BREP('',#40);
#42=( LENGTH_UNIT() NAMED_UNIT(*) SI_UNIT(.MILLI.,.METRE.) );
#43=( GEOMETRIC_REPRESENTATION_CONTEXT(3) GLOBAL_UNIT_ASSIGNED_CONTEXT((#42)) REPRESENTATION_CONTEXT('',''));
#44=ADVANCED_BREP_SHAPE_REPRESENTATION('',(#41),#43);"""
    return _HEADER + text + "\n" + _FOOTER


@pytest.mark.parametrize("top_angle", [0.0, 1.0])
def test_seamless_cylinder_band_gets_a_seam(top_angle):
    r, h = 2.0, 5.0
    s = solids_from_p21(parse(_seamless_cylinder_step(r, h, top_angle)))[0]
    assert s.check().ok
    np.testing.assert_allclose(s.volume, math.pi * r * r * h, rtol=1e-12)
    np.testing.assert_allclose(s.area, 2.0 * math.pi * r * h + 2.0 * math.pi * r * r, rtol=1e-12)


# ---------------------------------------------------------------------- fuzzing the new entities
def test_corrupted_entity_files_give_step_error_only():
    """Mutants (tests/io/test_step_fuzz.mutate) of the files above: the OCCT files and the revolved
    band through parser and schema (the per-face NURBS conversion of swept surfaces runs there), the
    faceted and seamless cylinder through the whole reader: a StepError or valid results, nothing else."""
    import random

    from tests.io.test_step_fuzz import mutate
    from tests.io.test_step_read import DATA

    bases = [(DATA / "occt-revolution-spline.stp").read_bytes(), (DATA / "occt-prism-oblique-circle.stp").read_bytes(),
             _faceted_step(*_octahedron(2.0)).encode(), _seamless_cylinder_step(2.0, 5.0, 1.0).encode(),
             _seamless_cylinder_step(2.0, 3.0, 2.0, 1.0).encode()]
    rng = random.Random(6)
    bad = []
    for i in range(240):
        data, what = mutate(bases[i % len(bases)], rng)
        try:
            if i % len(bases) in (2, 3):  # small hand-written files: the whole reader (faces, seams, sewing, check)
                assert all(s.check().ok for s in solids_from_p21(parse(data)))
            else:
                StepModel(parse(data)).solids()
        except StepError as exc:
            assert str(exc)
        except Exception as exc:  # noqa: BLE001 - anything else is the failure this test looks for
            bad.append((i, what, f"{type(exc).__name__}: {exc}"[:200]))
    assert not bad, bad[:5]


@pytest.mark.parametrize("top_angle", [0.0, 2.0])
def test_seamless_revolution_band_gets_a_seam(top_angle):
    """A frustum whose side (a revolved LINE, read as a closed NURBS) is bounded by two circles only."""
    r0, r1, h = 2.0, 1.0, 3.0
    s = solids_from_p21(parse(_seamless_cylinder_step(r0, h, top_angle, r1)))[0]
    assert s.check().ok
    np.testing.assert_allclose(s.volume, math.pi * h / 3.0 * (r0 * r0 + r0 * r1 + r1 * r1), rtol=1e-9)
    side = math.pi * (r0 + r1) * math.hypot(r0 - r1, h)
    np.testing.assert_allclose(s.area, side + math.pi * (r0 * r0 + r1 * r1), rtol=1e-9)


@pytest.mark.occt
@pytest.mark.parametrize("name", ["prism-circle", "revol-spline-360"])
def test_from_ocp_reads_swept_faces_with_seams(name):
    """from_ocp makes the swept surfaces exact NURBS (trimmed to the face first: an extrusion is
    unbounded); the full-turn ones are closed NURBS split at their seam like STEP's."""
    from coons.io.from_ocp import from_ocp

    shape = _shapes()[name][0]()
    s = from_ocp(shape)
    assert s.check().ok
    volume, area = _occt_figures(shape)
    np.testing.assert_allclose([s.volume, s.area], [volume, area], rtol=RTOL)


@pytest.mark.parametrize("entities, target, kind, message", [
    ("#5=ELLIPSE('',#4,3.,1.);\n#6=OFFSET_CURVE_3D('',#5,0.5,.F.,#2);", 6, "curve",
     r"#6, line \d+: OFFSET_CURVE_3D: the offset of a Ellipse"),
    ("#5=CYLINDRICAL_SURFACE('',#4,2.);\n#6=OFFSET_SURFACE('',#5,-3.,.F.);", 6, "surface",
     r"#6, line \d+: OFFSET_SURFACE: the offset by -3 turns the CylindricalSurface inside out"),
    ("#5=VECTOR('',#2,1.);\n#6=LINE('',#1,#5);\n#7=SURFACE_OF_LINEAR_EXTRUSION('',#6,#5);", 7, "surface",
     r"#7, line \d+: SURFACE_OF_LINEAR_EXTRUSION: a line extruded along itself"),
    ("#5=CIRCLE('',#4,1.);\n#6=AXIS1_PLACEMENT('',#1,#2);\n#7=SURFACE_OF_REVOLUTION('',#5,#6);", 7, "surface",
     r"#7, line \d+: SURFACE_OF_REVOLUTION: a conic profile whose plane does not contain the axis"),
    ("#5=HYPERBOLA('',#4,1.,1.);\n#6=VECTOR('',#2,1.);\n#7=SURFACE_OF_LINEAR_EXTRUSION('',#5,#6);", 7, "surface",
     r"#5, line \d+: HYPERBOLA: curve type not supported"),
])
def test_unsupported_cases_name_the_entity(entities, target, kind, message):
    m = StepModel(parse(_HEADER + _FRAME + entities + "\n" + _FOOTER))
    e = next(iter(m.file))
    with pytest.raises(StepError, match=message):
        (m.surface if kind == "surface" else m.curve)(Ref(target), e)


def test_extended_curve_is_the_same_polynomial_continued():
    """The B-spline continued past its ends (for offset faces reaching past their basis): unchanged
    inside, and the end pieces' polynomials continued (derivatives up to the degree agree at the old ends)."""
    from coons.io.step.schema import _extended
    from coons.kernel.curve import NurbsCurve

    rng = np.random.default_rng(3)
    c = NurbsCurve(rng.random((6, 3)), [0, 0, 0, 0, 0.3, 0.6, 1, 1, 1, 1.0], 3, weights=rng.random(6) + 0.5)
    x = _extended(c, 0.1)
    assert x.domain == pytest.approx((-0.1, 1.1), abs=1e-15)
    t = np.linspace(0.0, 1.0, 101)
    np.testing.assert_allclose(x.evaluate(t), c.evaluate(t), atol=1e-14)
    ends = np.array([0.0, 1.0])
    np.testing.assert_allclose(x.derivatives(ends, 3), c.derivatives(ends, 3), rtol=1e-10, atol=1e-10)
