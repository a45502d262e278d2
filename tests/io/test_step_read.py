"""STEP import: corpus files and OCCT-written primitives agree with OCCT; hand-written files; schema errors."""

from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from coons.errors import StepError
from coons.io.step.p21 import Ref, parse
from coons.io.step.reader import import_step, import_step_solids, read_step_faces, solids_from_p21
from coons.io.step.schema import StepModel
from coons.kernel.analytic import Circle, ConicalSurface, Ellipse, Line, PlanarSurface
from coons.kernel.curve import NurbsCurve
from coons.kernel.surface import NurbsSurface
from tests.io.step_samples import box_mesh, polyhedron_step

DATA = Path(__file__).resolve().parents[1] / "data"

#: Relative agreement with OCCT asked by the issue for corpus files.
RTOL_CORPUS = 1e-6
#: Relative agreement with OCCT for OCCT-written primitives (exact analytic geometry on both sides).
RTOL_PRIMITIVE = 1e-9

# OCCT 8 figures (tests/data/README.md): BRepGProp with eps = 1e-10 (adaptive, converged).
CORPUS = {
    "trimesh-base_interface_AP203.step": (1257991.525627, 541917.241362, 30),
    "trimesh-base_interface_AP214.step": (1257991.525627, 541917.241362, 30),
    "trimesh-featuretype.step": (190447.659212, 34733.530109, 96),
    # 3 seam faces split in two, spindle tori (r > R) read as exact NURBS patches
    "occt-screw.step": (3788.274017, 1929.331378, 13),
}


#: The screw spends ~15 s in NURBS projection and checking (busy 2-core machine): slow suite.
CORPUS_PARAMS = [pytest.param(n, marks=pytest.mark.slow) if n == "occt-screw.step" else n for n in sorted(CORPUS)]


@pytest.mark.parametrize("name", CORPUS_PARAMS)
def test_corpus_volume_and_area_match_occt(name):
    volume, area, n_faces = CORPUS[name]
    s = import_step(DATA / name)
    assert s.check().ok
    assert s.brep.n_faces == n_faces
    np.testing.assert_allclose(s.volume, volume, rtol=RTOL_CORPUS)
    np.testing.assert_allclose(s.area, area, rtol=RTOL_CORPUS)


@pytest.mark.occt
@pytest.mark.parametrize("name", ["trimesh-featuretype.step", pytest.param("occt-screw.step", marks=pytest.mark.slow)])
def test_corpus_figures_are_occt_converged_values(name):
    """The figures above are OCCT's own, with converged integration (the corpus README lists default-precision ones)."""
    from OCP.BRepGProp import BRepGProp
    from OCP.GProp import GProp_GProps
    from OCP.STEPControl import STEPControl_Reader

    r = STEPControl_Reader()
    r.ReadFile(str(DATA / name))
    r.TransferRoots()
    g = GProp_GProps()
    BRepGProp.VolumeProperties_s(r.OneShape(), g, 1e-10)
    np.testing.assert_allclose(g.Mass(), CORPUS[name][0], rtol=1e-9)
    g = GProp_GProps()
    BRepGProp.SurfaceProperties_s(r.OneShape(), g, 1e-10)
    np.testing.assert_allclose(g.Mass(), CORPUS[name][1], rtol=1e-9)


# ---------------------------------------------------------------------- OCCT-written primitives
def _primitives():
    import build123d as bd

    return {
        "box": (bd.Box(10, 20, 30), 6, 6),
        "cylinder": (bd.Cylinder(5, 12), 3, 4),
        "cone": (bd.Cone(6, 2, 10), 3, 4),
        "cone_apex": (bd.Cone(6, 0, 10), 2, 3),
        "sphere": (bd.Sphere(7), 1, 2),
        "torus": (bd.Torus(10, 3), 1, 4),
        "box_with_hole": (bd.Box(20, 20, 10) - bd.Cylinder(4, 10), 7, 8),
        "rotated_cylinder": (bd.Rot(30, 45, 10) * bd.Pos(1, 2, 3) * bd.Cylinder(2, 5), 3, 4),
        "plate_with_25_holes": (bd.Box(50, 50, 5) - [bd.Pos(-20 + 10 * i, -20 + 10 * j, 0) * bd.Cylinder(2, 5)
                                                    for i in range(5) for j in range(5)], 31, 56),
    }


@pytest.mark.occt
def test_occt_written_primitives(tmp_path):
    import build123d as bd
    from OCP.BRepGProp import BRepGProp
    from OCP.GProp import GProp_GProps

    for name, (shape, occt_faces, coons_faces) in _primitives().items():
        path = tmp_path / f"{name}.step"
        bd.export_step(shape, str(path))
        g = GProp_GProps()
        BRepGProp.VolumeProperties_s(shape.wrapped, g, 1e-12)
        volume = g.Mass()
        g = GProp_GProps()
        BRepGProp.SurfaceProperties_s(shape.wrapped, g, 1e-12)
        area = g.Mass()
        s = import_step(path)
        assert s.check().ok, name
        assert len(shape.faces()) == occt_faces and s.brep.n_faces == coons_faces, name
        np.testing.assert_allclose(s.volume, volume, rtol=RTOL_PRIMITIVE, err_msg=name)
        np.testing.assert_allclose(s.area, area, rtol=RTOL_PRIMITIVE, err_msg=name)


# ---------------------------------------------------------------------- hand-written files
@pytest.mark.parametrize("unit, scale", [("mm", 1.0), ("m", 1000.0), ("inch", 25.4)])
def test_units_scale_to_millimetres(tmp_path, unit, scale):
    path = tmp_path / "box.step"
    path.write_text(polyhedron_step(*box_mesh((0, 0, 0), (1, 2, 3)), unit=unit))
    s = import_step(path)
    assert s.check().ok
    np.testing.assert_allclose(s.volume, 6.0 * scale**3, rtol=1e-12)
    np.testing.assert_allclose(s.area, 22.0 * scale**2, rtol=1e-12)


def test_brep_with_voids(tmp_path):
    path = tmp_path / "void.step"
    path.write_text(polyhedron_step(*box_mesh((0, 0, 0), (4, 4, 4)), voids=[box_mesh((1, 1, 1), (2, 3, 2))]))
    s = import_step(path)
    assert s.check().ok and len(s.shells()) == 2
    np.testing.assert_allclose(s.volume, 64.0 - 2.0, rtol=1e-12)
    np.testing.assert_allclose(s.area, 96.0 + 10.0, rtol=1e-12)


def test_several_solids_give_a_list(tmp_path):
    a = polyhedron_step(*box_mesh((0, 0, 0), (1, 1, 1)))
    b = polyhedron_step(*box_mesh((5, 0, 0), (7, 1, 1)))
    # Second file's ids shifted past the first's, then both DATA sections in one file.
    body_a = a.split("DATA;\n")[1].split("\nENDSEC;\nEND")[0]
    body_b = b.split("DATA;\n")[1].split("\nENDSEC;\nEND")[0]
    body_b = re.sub(r"#(\d+)", lambda m: f"#{int(m.group(1)) + 100000}", body_b)
    text = a.replace(body_a, body_a + "\nENDSEC;\nDATA;\n" + body_b)
    path = tmp_path / "two.step"
    path.write_text(text)
    solids = import_step(path)
    assert isinstance(solids, list) and len(solids) == 2
    np.testing.assert_allclose([s.volume for s in solids], [1.0, 2.0], rtol=1e-12)
    assert len(import_step_solids(path)) == 2
    assert len(read_step_faces(path)[1].faces) == 6


# ---------------------------------------------------------------------- schema
def model(data: str) -> StepModel:
    return StepModel(parse(f"ISO-10303-21;HEADER;ENDSEC;DATA;\n{data}\nENDSEC;END-ISO-10303-21;"))


BASE = (
    "#1=CARTESIAN_POINT('',(1.,2.,3.));\n#2=DIRECTION('',(0.,0.,2.));\n#3=DIRECTION('',(1.,0.,0.));\n"
    "#4=AXIS2_PLACEMENT_3D('',#1,#2,#3);\n#5=VECTOR('',#3,2.);\n"
)


def geometry(extra: str, kind: str, ref: int = 10):
    """Convert entity ``#ref`` with ``StepModel.curve`` or ``.surface``."""
    m = model(BASE + extra)
    return getattr(m, kind)(Ref(ref), m.file.entities[ref])


def test_curves():
    line = geometry("#10=LINE('',#1,#5);", "curve")
    assert isinstance(line, Line) and np.allclose(line.evaluate(1.0), [2, 2, 3])
    c = geometry("#10=CIRCLE('',#4,2.5);", "curve")
    assert isinstance(c, Circle) and np.allclose(c.evaluate(math.pi / 2), [1, 4.5, 3])
    el = geometry("#10=ELLIPSE('',#4,1.,3.);", "curve")  # semi axis 2 > semi axis 1: frame turned
    assert isinstance(el, Ellipse) and el.major_radius == 3.0
    np.testing.assert_allclose(el.evaluate(0.0), [1, 5, 3], atol=1e-15)
    bs = geometry(
        "#6=CARTESIAN_POINT('',(2.,0.,0.));#7=CARTESIAN_POINT('',(2.,1.,0.));#8=CARTESIAN_POINT('',(1.,1.,0.));"
        "#10=(BOUNDED_CURVE() B_SPLINE_CURVE(2,(#6,#7,#8),.UNSPECIFIED.,.F.,.F.) "
        "B_SPLINE_CURVE_WITH_KNOTS((3,3),(0.,1.),.UNSPECIFIED.) CURVE() GEOMETRIC_REPRESENTATION_ITEM() "
        "RATIONAL_B_SPLINE_CURVE((1.,0.7071067811865476,1.)) REPRESENTATION_ITEM(''));", "curve")
    assert isinstance(bs, NurbsCurve) and bs.is_rational
    np.testing.assert_allclose(np.linalg.norm(bs.evaluate(np.linspace(0, 1, 9)) - [1, 0, 0], axis=-1), 1.0, rtol=1e-14)


def test_surfaces_and_placement_defaults():
    p = geometry("#10=PLANE('',#11);#11=AXIS2_PLACEMENT_3D('',#1,$,$);", "surface")
    assert isinstance(p, PlanarSurface) and np.allclose(p.axis, [0, 0, 1]) and np.allclose(p.x_dir, [1, 0, 0])
    cone = geometry("#10=CONICAL_SURFACE('',#4,2.,0.5);", "surface")
    assert isinstance(cone, ConicalSurface) and cone.semi_angle == 0.5
    pts = ",".join(f"(#{20 + 3 * i},#{21 + 3 * i},#{22 + 3 * i})" for i in range(3))
    defs = "".join(f"#{20 + 3 * i + j}=CARTESIAN_POINT('',({i}.,{j}.,{i * j}.));" for i in range(3) for j in range(3))
    s = geometry(defs + f"#10=B_SPLINE_SURFACE_WITH_KNOTS('',2,2,({pts}),.UNSPECIFIED.,.F.,.F.,.F.,(3,3),(3,3),"
                 "(0.,1.),(0.,1.),.UNSPECIFIED.);", "surface")
    assert isinstance(s, NurbsSurface) and s.shape == (3, 3)
    np.testing.assert_allclose(s.evaluate(0.5, 0.5), [1, 1, 1], atol=1e-15)


@pytest.mark.parametrize("extra, kind, match", [
    ("#10=HYPERBOLA('',#4,1.,1.);", "curve", r"#10, line \d+: HYPERBOLA: curve type not supported"),
    ("#10=DEGENERATE_TOROIDAL_SURFACE('',#4,1.,2.,.T.);", "surface", r"surface type not supported"),
    ("#10=CIRCLE('',#1,2.);", "curve", r"expected AXIS2_PLACEMENT_3D but #1 is CARTESIAN_POINT"),
    ("#10=CIRCLE('',#4);", "curve", r"expected at least 3 parameters, got 2"),
    ("#10=CIRCLE('',#4,-1.);", "curve", r"#10.*cannot be converted: Circle"),
    ("#10=CIRCLE('',#4,'r');", "curve", r"radius must be a finite number, got 'r'"),
    ("#10=LINE('',#99,#5);", "curve", r"reference #99 points to no entity"),
    ("#10=SURFACE_CURVE('',#11,(),.CURVE_3D.);#11=SURFACE_CURVE('',#10,(),.CURVE_3D.);", "curve",
     r"cyclic reference"),
    ("#10=LINE('',#11,#5);#11=CARTESIAN_POINT('',(1.,2.));", "curve", r"expected 3 coordinates, got 2"),
    ("#10=LINE('',#1,#11);#11=VECTOR('',#12,1.);#12=DIRECTION('',(0.,0.,0.));", "curve", r"zero direction"),
    ("#10=LINE('',#1,#11);#11=VECTOR('',#3,0.);", "curve", r"magnitude must be > 0"),
    ("#10=LINE('',#11,#5);#11=CARTESIAN_POINT('',(1.E999,0.,0.));", "curve", r"coordinate must be a finite number"),
    ("#10=B_SPLINE_CURVE_WITH_KNOTS('',2,(#1,#1,#1),.UNSPECIFIED.,.F.,.F.,(3,2),(0.,1.),.UNSPECIFIED.);",
     "curve", r"cannot be converted: NurbsCurve"),
    ("#10=B_SPLINE_CURVE_WITH_KNOTS('',2,(#1,#1,#1),.UNSPECIFIED.,.F.,.F.,(3,3),(0.,1.,2.),.UNSPECIFIED.);",
     "curve", r"2 knot multiplicities for 3 knots"),
    ("#10=B_SPLINE_CURVE_WITH_KNOTS('',500,(#1,#1),.UNSPECIFIED.,.F.,.F.,(1,1),(0.,1.),.UNSPECIFIED.);",
     "curve", r"degree must be an integer in \[1, 64\], got 500"),
    ("#10=PLANE('',#11);#11=AXIS2_PLACEMENT_3D('',#1,#3,#3);", "surface", r"ref_direction is parallel to the axis"),
])
def test_schema_errors_name_entity_and_line(extra, kind, match):
    with pytest.raises(StepError, match=match):
        geometry(extra, kind)


def test_file_without_solid_and_bad_units():
    with pytest.raises(StepError, match=r"the file contains no solid"):
        model(BASE).solids()
    text = polyhedron_step(*box_mesh((0, 0, 0), (1, 1, 1))).replace("SI_UNIT(.MILLI.,.METRE.)", "SI_UNIT(.MILLI.,.GRAM.)")
    with pytest.raises(StepError, match=r"length unit must be based on .METRE., got .GRAM."):
        solids_from_p21(parse(text))
    text = polyhedron_step(*box_mesh((0, 0, 0), (1, 1, 1))).replace("SI_UNIT(.MILLI.,.METRE.)", "SI_UNIT(.SUPER.,.METRE.)")
    with pytest.raises(StepError, match=r"unknown SI prefix .SUPER."):
        solids_from_p21(parse(text))


def test_open_shell_is_a_step_error_with_the_sewing_cause():
    V, F = box_mesh((0, 0, 0), (1, 1, 1))
    text = polyhedron_step(V, F[:-1])
    with pytest.raises(StepError, match=r"MANIFOLD_SOLID_BREP: its faces do not form a valid solid: TopologyError: "
                                        r".*the shell is open") as info:
        solids_from_p21(parse(text))
    assert type(info.value.__cause__).__name__ == "TopologyError"


def test_edge_running_the_wrong_way_is_named():
    text = polyhedron_step(*box_mesh((0, 0, 0), (1, 1, 1)))
    first = text.index("EDGE_CURVE(")
    end = text.index(";", first)
    text = text[:end].replace(",.T.)", ",.F.)") + text[end:] if text[end - 5:end] == ",.T.)" else text
    text = text[:first] + text[first:end].replace(".T.)", ".F.)") + text[end:]
    with pytest.raises(StepError, match=r"EDGE_CURVE: edge vertices project to curve parameters .* expected decreasing"):
        solids_from_p21(parse(text))


# ---------------------------------------------------------------------- round trips and properties
def test_round_trip_through_the_coons_writer(tmp_path):
    from coons.io.step.writer import export_step
    from coons.topology.primitives import Box, Cone, Cylinder, Sphere, Torus

    for shape in (Box(1, 2, 3), Cylinder(2, 5), Sphere(3), Torus(5, 1), Cone(3, 1, 4), Cone(3, 0, 4)):
        path = tmp_path / "rt.step"
        export_step(shape, path)
        back = import_step(path)
        assert back.check().ok
        assert (back.brep.n_faces, back.brep.n_edges, back.brep.n_vertices) == (
            shape.brep.n_faces, shape.brep.n_edges, shape.brep.n_vertices)
        np.testing.assert_allclose(back.volume, shape.volume, rtol=1e-12)
        np.testing.assert_allclose(back.area, shape.area, rtol=1e-12)


@given(st.tuples(*[st.floats(0.1, 100.0)] * 3), st.tuples(*[st.floats(-1e3, 1e3)] * 3),
       st.sampled_from([("mm", 1.0), ("m", 1000.0), ("inch", 25.4)]))
@settings(max_examples=15)
def test_hand_written_boxes_any_size_place_and_unit(size, corner, unit):
    lo = np.asarray(corner)
    hi = lo + np.asarray(size)
    s = solids_from_p21(parse(polyhedron_step(*box_mesh(lo, hi), unit=unit[0])))[0]
    k = unit[1]
    np.testing.assert_allclose(s.volume, np.prod(size) * k**3, rtol=1e-12)
    np.testing.assert_allclose(s.bounding_box(), np.array([lo, hi]) * k, rtol=1e-12, atol=1e-9 * k)


def _bspline_box(n: int):
    """The cube [-1, 1]³, each side an n × n grid of bilinear NURBS faces (benchmarks/bench_io.py)."""
    from tests.topology.test_tessellate_nurbs import grid_solid

    return grid_solid(n)


def test_nurbs_faces_get_exact_boundary_pcurves(tmp_path):
    # Every edge of a bilinear NURBS face is a boundary iso-line: the reader's p-curves are Line2D
    # with the constant coordinate exactly 0 or 1 (never outside the domain), same parameter.
    from coons.io.step.writer import export_step
    from coons.kernel.pcurve import Line2D

    shape = _bspline_box(2)
    export_step(shape, tmp_path / "bbox.step")
    back = import_step(tmp_path / "bbox.step")
    assert back.check().ok and back.brep.n_faces == 24
    np.testing.assert_allclose(back.volume, 8.0, rtol=1e-12)
    np.testing.assert_allclose(back.area, 24.0, rtol=1e-12)
    pcs = [pc for pc in back.brep.pcurves if pc is not None]
    assert len(pcs) == 2 * back.brep.n_edges and all(isinstance(pc, Line2D) for pc in pcs)
    for pc in pcs:
        k = int(np.flatnonzero(pc.direction == 0.0)[0])
        assert pc.origin[k] in (0.0, 1.0)


def test_reading_pauses_the_garbage_collector_and_restores_it(tmp_path, monkeypatch):
    import gc

    from coons.io.step import export_step, reader
    from coons.topology.primitives import Box

    bad = tmp_path / "bad.step"
    bad.write_text("ISO-10303-21;\nHEADER;\nENDSEC;\nDATA;\n#1=CARTESIAN_POINT('',(0.,0.,0.));\n")  # truncated
    assert gc.isenabled()
    with pytest.raises(StepError):
        reader.import_step(bad)
    assert gc.isenabled()  # restored after an error
    gc.disable()
    try:
        with pytest.raises(StepError):
            reader.import_step(bad)
        assert not gc.isenabled()  # left as found
    finally:
        gc.enable()
    good = tmp_path / "box.step"
    export_step(Box(1, 2, 3), good)
    seen = []
    real = reader.solids_from_p21

    def spy(*args, **kwargs):
        seen.append(gc.isenabled())
        return real(*args, **kwargs)

    monkeypatch.setattr(reader, "solids_from_p21", spy)
    assert reader.import_step(good).volume == pytest.approx(6.0)
    assert seen == [False] and gc.isenabled()


def test_batched_degenerate_edges_decide_as_one_at_a_time():
    # _mark_degenerate (lines and circles in one batch) gives every edge the flag its own
    # RawEdge.degenerate computes: collapsed lines and arcs within 2 tol, exact points, long edges.
    from coons.io._faces import RawCoedge, RawEdge, RawFace, _mark_degenerate
    from coons.kernel.analytic import Circle, Line, PlanarSurface

    rng = np.random.default_rng(3)
    edges = []
    for _ in range(200):
        tol = float(rng.choice([0.0, 1e-7, 1e-3]))
        span = float(rng.choice([0.0, 1e-9, 1e-7, 1.5e-3, 1.0]))
        a = float(rng.uniform(-5, 5))
        if rng.random() < 0.5:
            curve = Line(rng.uniform(-100, 100, 3), rng.normal(size=3))
        else:
            curve = Circle(rng.uniform(-100, 100, 3), rng.normal(size=3), rng.normal(size=3), float(rng.uniform(1e-3, 50)))
        P = np.asarray(curve.evaluate(np.array([a, a + span])))
        edges.append(RawEdge(curve, a, a + span, P[0], P[1], tol))
    face = RawFace(PlanarSurface([0, 0, 0], [0, 0, 1], [1, 0, 0]), True, [[RawCoedge(e, True) for e in edges]])
    _mark_degenerate([face])
    batched = [e.__dict__.pop("_degenerate") for e in edges]
    alone = [e.degenerate for e in edges]
    assert batched == alone and any(alone) and not all(alone)
