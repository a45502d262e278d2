"""STEP export: OCCT reads every case back as a valid solid with coons's volume, area and faces.

Truth: OCCT 8 (build123d ``import_step``, ``BRepCheck_Analyzer``, ``BRepGProp`` with an
adaptive precision of 1e-12) on the file coons writes, compared with coons's own mass
properties; plus byte-for-byte determinism, the Part 21 real format, and every error branch.
"""

from __future__ import annotations

import dataclasses
import math
import re

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

import coons
from coons import Profile
from coons.errors import InvalidInputError, StepError
from coons.io.step import export_step
from coons.io.step.writer import SCHEMAS, _reals, step_text
from coons.kernel.analytic import PlanarSurface
from coons.kernel.surface import NurbsSurface
from coons.topology.shape import Solid

#: OCCT's adaptive integration (eps 1e-12) against coons's mass properties.
RTOL_MASS = 1e-9
#: Skewed Trig2D p-curves have no same-parameter STEP form: OCCT's reader re-fits them
#: (``ShapeFix`` same-parameter approximation at its 1e-7 tolerance), measured 1.3e-7 / 4e-7.
RTOL_REFITTED = 1e-6


# ---------------------------------------------------------------------------- cases
def skewed_caps(solid: Solid) -> Solid:
    """``solid`` with every planar face's surface re-parametrised by a skew affine map.

    Each plane ``S(p, q)`` becomes the bilinear NURBS ``N(u, v) = S(M (u, v))`` with ``M``
    non-orthogonal, and its p-curves ``M⁻¹ uv(t)``: circle edges then have Trig2D p-curves
    with non-orthogonal axes of different lengths, the case STEP and OCCT have no direct form for.
    """
    b = solid.brep
    M = np.array([[1.0, 0.5], [0.0, 1.5]])
    Minv = np.linalg.inv(M)
    surfaces, pcurves, ep = list(b.surfaces), list(b.pcurves), b.edge_pcurve.copy()
    corners = np.array([-5.0, 5.0])
    for f in range(b.n_faces):
        si = int(b.face_surface[f])
        s = b.surfaces[si]
        if not isinstance(s, PlanarSurface):
            continue
        X, Y, _ = s.frame
        pq = np.einsum("ij,abj->abi", M, np.stack(np.meshgrid(corners, corners, indexing="ij"), axis=-1))
        cp = s.origin + pq[..., :1] * X + pq[..., 1:] * Y
        surfaces[si] = NurbsSurface(cp, [-5, -5, 5, 5], [-5, -5, 5, 5], 1, 1)
        for e, side in zip(*np.nonzero(b.edge_face == f)):
            pcurves.append(pcurves[ep[e, side]].transformed(Minv))
            ep[e, side] = len(pcurves) - 1
    out = Solid(dataclasses.replace(b, surfaces=tuple(surfaces), pcurves=tuple(pcurves), edge_pcurve=ep))
    assert out.check().ok
    return out


def nurbs_pcurves(solid: Solid) -> Solid:
    """``solid`` with every Line2D p-curve replaced by the same degree-1 2-D NURBS over its edge range."""
    from coons.kernel.curve import NurbsCurve
    from coons.kernel.pcurve import Line2D

    b = solid.brep
    pcurves, ep = list(b.pcurves), b.edge_pcurve.copy()
    for e, side in zip(*np.nonzero(ep >= 0)):
        pc = b.pcurves[ep[e, side]]
        if isinstance(pc, Line2D):
            t0, t1 = b.edge_range[e]
            pcurves.append(NurbsCurve(pc.evaluate(np.array([t0, t1])), [t0, t0, t1, t1], 1))
            ep[e, side] = len(pcurves) - 1
    out = Solid(dataclasses.replace(b, pcurves=tuple(pcurves), edge_pcurve=ep))
    assert out.check().ok
    return out


def _icosphere_poly():
    import trimesh

    m = trimesh.creation.icosphere(2)
    return coons.from_mesh(m.vertices, m.faces) - coons.Box(1, 1, 1)


def revolved_spline() -> Solid:
    """A full revolve of a profile with a spline side: rational NURBS faces and rational parallels."""
    from coons import Segment

    p = Profile([Segment.line((1, 0), (2, 0)), Segment.spline(np.array([(2, 0), (2.5, 1), (2, 2)])),
                 Segment.line((2, 2), (1, 2)), Segment.line((1, 2), (1, 0))])
    return coons.revolve(p, (0, 0, 0), (0, 1, 0))


def cases() -> dict:
    """name -> factory of a coons solid (shared with test_ocp.py)."""
    plate = Profile.rectangle(10, 6).with_hole(Profile.circle(1, (-2, 0))).with_hole(Profile.circle(1.5, (2.5, 0)))
    return {
        "box": lambda: coons.Box(1, 2, 3),
        "cylinder": lambda: coons.Cylinder(1, 2),
        "cone frustum": lambda: coons.Cone(1, 0.5, 2),
        "cone apex": lambda: coons.Cone(1, 0, 2),
        "sphere": lambda: coons.Sphere(1),
        "torus": lambda: coons.Torus(3, 1),
        "extrusion with holes": lambda: coons.extrude(plate, 3),
        "oblique extrusion (NURBS sides)": lambda: coons.extrude(Profile.circle(1), (0.3, 0.2, 2)),
        "revolve": lambda: coons.revolve(Profile.rectangle(1, 2, center=(2, 0)), (0, 0, 0), (0, 1, 0)),
        "partial revolve (torus)": lambda: coons.revolve(Profile.circle(0.5, center=(2, 0)), (0, 0, 0), (0, 1, 0), 90),
        "revolved spline (rational NURBS)": revolved_spline,
        "loft (NURBS faces)": lambda: coons.loft([Profile.circle(1), Profile.circle(0.5, plane=((0, 0, 2), (0, 0, 1)))]),
        "polyhedral Boolean": _icosphere_poly,
        "box with box void": lambda: coons.Box(4, 4, 4) - coons.Box(1, 1, 1),
        "revolve with torus void": lambda: coons.revolve(
            Profile.rectangle(2, 2, center=(3, 0)).with_hole(Profile.circle(0.5, (3, 0))), (0, 0, 0), (0, 1, 0)
        ),
        "moved, rotated, scaled cone": lambda: coons.Pos(1, 2, 3) * coons.Rot(10, 20, 30) * coons.Cone(1, 0.5, 2).scale(2.5),
        "cone with NURBS p-curves": lambda: nurbs_pcurves(coons.Cone(1, 0.5, 2)),
        "cylinder with skewed NURBS caps": lambda: skewed_caps(coons.Cylinder(1, 2)),
        "two lumps": lambda: coons.Box(1, 1, 1) + coons.Pos(3, 0, 0) * coons.Box(1, 2, 1),
    }


CASES = cases()


def occt_props(shape) -> tuple[float, float]:
    from OCP.BRepGProp import BRepGProp
    from OCP.GProp import GProp_GProps

    g = GProp_GProps()
    BRepGProp.VolumeProperties_s(shape, g, 1e-12)
    v = g.Mass()
    g = GProp_GProps()
    BRepGProp.SurfaceProperties_s(shape, g, 1e-12)
    return v, g.Mass()


def occt_counts(shape) -> tuple[int, int]:
    """(solids, faces) of an OCCT shape."""
    from OCP.TopAbs import TopAbs_FACE, TopAbs_SOLID
    from OCP.TopExp import TopExp_Explorer

    def count(kind):
        ex, n = TopExp_Explorer(shape, kind), 0
        while ex.More():
            n += 1
            ex.Next()
        return n

    return count(TopAbs_SOLID), count(TopAbs_FACE)


def occt_edges(shape):
    """(degenerated, tolerance, same_parameter) of each distinct edge of an OCCT shape."""
    from OCP.BRep import BRep_Tool
    from OCP.TopAbs import TopAbs_EDGE, TopAbs_FORWARD
    from OCP.TopExp import TopExp_Explorer
    from OCP.TopoDS import TopoDS

    seen, out = set(), []
    ex = TopExp_Explorer(shape, TopAbs_EDGE)
    while ex.More():
        e = TopoDS.Edge(ex.Current().Oriented(TopAbs_FORWARD))
        ex.Next()
        if hash(e) in seen:
            continue
        seen.add(hash(e))
        out.append((BRep_Tool.Degenerated_s(e), BRep_Tool.Tolerance_s(e), BRep_Tool.SameParameter_s(e)))
    return out


# ---------------------------------------------------------------------------- OCCT round trips
@pytest.mark.occt
@pytest.mark.parametrize("schema", ["AP214", "AP242"])
@pytest.mark.parametrize("case", list(CASES))
def test_occt_reads_a_valid_solid_with_the_same_measures(tmp_path, case, schema):
    import build123d as bd
    from OCP.BRepCheck import BRepCheck_Analyzer

    s = CASES[case]()
    path = export_step(s, tmp_path / "part.step", schema=schema)
    shape = bd.import_step(path).wrapped
    assert BRepCheck_Analyzer(shape).IsValid()
    n_solids, n_faces = occt_counts(shape)
    assert n_solids == s.brep.n_solids
    assert n_faces == s.brep.n_faces  # coons has no seams: OCCT keeps coons's faces, one for one
    if "skewed" not in case:
        # Consistent curves and p-curves: OCCT's reader keeps every edge at its 1e-7 confusion
        # (inconsistent ones would be re-fitted and their tolerance raised).
        assert max(t for _, t, _ in occt_edges(shape)) <= 1e-7 * (1 + 1e-9)
    v, a = occt_props(shape)
    rtol = RTOL_REFITTED if "skewed" in case else RTOL_MASS
    np.testing.assert_allclose(v, s.volume, rtol=rtol)
    np.testing.assert_allclose(a, s.area, rtol=rtol)


@pytest.mark.occt
def test_occt_sees_a_part_with_units_and_the_schema(tmp_path):
    from OCP.IFSelect import IFSelect_RetDone
    from OCP.STEPControl import STEPControl_Reader

    path = export_step(coons.Sphere(2), tmp_path / "s.step", schema="AP242", name="ball")
    r = STEPControl_Reader()
    assert r.ReadFile(str(path)) == IFSelect_RetDone
    assert r.NbRootsForTransfer() == 1  # one product, one root shape
    r.TransferRoots()
    v, _ = occt_props(r.OneShape())
    np.testing.assert_allclose(v, 4 / 3 * math.pi * 8, rtol=RTOL_MASS)  # millimetres, not metres
    text = path.read_text()
    assert SCHEMAS["AP242"] in text and "SI_UNIT(.MILLI.,.METRE.)" in text and "PRODUCT('ball'" in text


# ---------------------------------------------------------------------------- file content
def test_same_solid_same_bytes(tmp_path):
    a = export_step(coons.Torus(3, 1), tmp_path / "a.step").read_bytes()
    b = export_step(coons.Torus(3, 1), tmp_path / "b.step").read_bytes()
    assert a == b
    assert step_text(coons.Torus(3, 1)).encode() == a


def test_entities_written_for_each_geometry_type():
    text = step_text(coons.Cone(1, 0.5, 2)) + step_text(CASES["loft (NURBS faces)"]())
    for name in ("CONICAL_SURFACE", "PLANE", "CIRCLE", "LINE", "B_SPLINE_SURFACE_WITH_KNOTS",
                 "B_SPLINE_CURVE_WITH_KNOTS", "SURFACE_CURVE", "PCURVE", "DEFINITIONAL_REPRESENTATION",
                 "ADVANCED_FACE", "FACE_OUTER_BOUND", "EDGE_LOOP", "ORIENTED_EDGE", "EDGE_CURVE",
                 "VERTEX_POINT", "MANIFOLD_SOLID_BREP", "CLOSED_SHELL", "UNCERTAINTY_MEASURE_WITH_UNIT"):
        assert f"{name}(" in text, name
    void = step_text(coons.Box(4, 4, 4) - coons.Box(1, 1, 1))
    assert "BREP_WITH_VOIDS(" in void and "ORIENTED_CLOSED_SHELL(" in void and "MANIFOLD_SOLID_BREP(" not in void
    # coons's sphere/torus: exact analytic surfaces, not NURBS
    text = step_text(coons.Sphere(1)) + step_text(coons.Torus(3, 1))
    assert "SPHERICAL_SURFACE(" in text and "TOROIDAL_SURFACE(" in text and "B_SPLINE" not in text


def test_cone_semi_angle_is_positive_in_the_file():
    s = coons.Cone(1, 0.5, 2)
    assert s.brep.surfaces[[type(x).__name__ for x in s.brep.surfaces].index("ConicalSurface")].semi_angle < 0
    angles = re.findall(r"CONICAL_SURFACE\('',#\d+,[^,]+,([^)]+)\)", step_text(s))
    assert angles  # one surface entity per face
    np.testing.assert_allclose([float(a) for a in angles], math.atan(0.25), rtol=1e-15)


def test_rational_surfaces_and_curves_are_complex_entities():
    text = step_text(revolved_spline())
    assert "( BOUNDED_SURFACE() B_SPLINE_SURFACE(" in text and "RATIONAL_B_SPLINE_SURFACE(((" in text
    assert "( BOUNDED_CURVE() B_SPLINE_CURVE(" in text and "RATIONAL_B_SPLINE_CURVE((" in text


def test_uncertainty_comes_from_tol():
    text = step_text(coons.Box(1, 1, 1), tol=coons.Tolerance(linear=1e-5))
    assert "LENGTH_MEASURE(1.E-05)" in text


def test_reals_are_shortest_round_trip_with_a_decimal_point():
    vals = [0.0, -0.0, 1.0, 1e-05, 1.5e16, -2.5e-300, 0.1, 1 / 3, 123456789.0]
    toks = _reals(vals)
    assert toks[:5] == ["0.0", "-0.0", "1.0", "1.E-05", "1.5E+16"]
    assert all(re.fullmatch(r"-?\d+\.\d*(E[+-]\d+)?", t) for t in toks)
    assert [float(t) for t in toks] == vals  # bit-exact


@given(st.lists(st.floats(allow_nan=False, allow_infinity=False), min_size=1, max_size=20))
def test_any_finite_real_round_trips_in_step_grammar(vals):
    toks = _reals(vals)
    assert all(re.fullmatch(r"-?\d+\.\d*(E[+-]\d+)?", t) for t in toks)
    assert [float(t) for t in toks] == vals


def test_names_are_escaped():
    text = step_text(coons.Box(1, 1, 1), name="Bob's part")
    assert "PRODUCT('Bob''s part','Bob''s part'," in text


def test_polyhedral_faces_get_newell_planes():
    s = _icosphere_poly()
    assert (s.brep.face_surface < 0).any()
    text = step_text(s)
    assert text.count("ADVANCED_FACE(") == s.brep.n_faces
    assert text.count("PLANE(") == s.brep.n_faces


# ---------------------------------------------------------------------------- errors
def test_not_a_solid(tmp_path):
    with pytest.raises(InvalidInputError, match="needs a coons Solid, got Box"):
        export_step(type("Box", (), {})(), tmp_path / "x.step")


def test_empty_solid(tmp_path):
    with pytest.raises(InvalidInputError, match="non-empty solid"):
        export_step(Solid.empty(), tmp_path / "x.step")
    assert not list(tmp_path.iterdir())


def test_unknown_schema(tmp_path):
    with pytest.raises(InvalidInputError, match=r"schema must be one of \['AP214', 'AP242'\], got 'AP203'"):
        export_step(coons.Box(1, 1, 1), tmp_path / "x.step", schema="AP203")


class _Blob:
    """Geometry of a type STEP export does not know."""

    def evaluate(self, *a):  # pragma: no cover - never called
        raise AssertionError


def test_unsupported_surface_curve_and_pcurve(tmp_path):
    b = coons.Cylinder(1, 2).brep
    bad = Solid(dataclasses.replace(b, surfaces=(_Blob(),) + b.surfaces[1:]))
    with pytest.raises(StepError, match="unsupported surface type _Blob"):
        export_step(bad, tmp_path / "x.step")
    bad = Solid(dataclasses.replace(b, curves=(_Blob(),) + b.curves[1:]))
    with pytest.raises(StepError, match="unsupported edge curve type _Blob"):
        export_step(bad, tmp_path / "x.step")
    bad = Solid(dataclasses.replace(b, pcurves=(_Blob(),) + b.pcurves[1:]))
    with pytest.raises(StepError, match="unsupported p-curve type _Blob"):
        export_step(bad, tmp_path / "x.step")
    assert not list(tmp_path.iterdir())  # nothing written, no temporary left


def test_non_finite_geometry():
    with pytest.raises(StepError, match="non-finite reals"):
        _reals([1.0, math.nan])


def test_write_failure_leaves_nothing(tmp_path):
    with pytest.raises(FileNotFoundError):
        export_step(coons.Box(1, 1, 1), tmp_path / "missing" / "x.step")
    assert not list(tmp_path.iterdir())


def test_pcurves_of_closed_curves_are_written_in_the_base_turn():
    # An edge on a circle whose range starts a turn or more away from [0, 2pi) keeps its points:
    # its p-curves are advanced by the whole turns, so that they use the parameters a reader
    # derives from the vertices.
    from coons.io.step.writer import _advanced, _period_shift
    from coons.kernel.analytic import Circle, Line as Line3
    from coons.kernel.curve import NurbsCurve
    from coons.kernel.pcurve import Line2D, Trig2D

    circle = Circle([0, 0, 0], [0, 0, 1], [1, 0, 0], 2.0)
    for t0, turns in [(6.4781, 1), (9.2299, 1), (-1.5708, -1), (0.2, 0), (2 * math.pi - 1e-14, 1), (-4 * math.pi, -2)]:
        shift = _period_shift(circle, t0)
        assert shift == pytest.approx(2 * math.pi * turns)
        assert -1e-12 <= t0 - shift < 2 * math.pi  # a start within round-off of 2pi counts as 0
    assert _period_shift(Line3([0, 0, 0], [1, 0, 0]), 9.0) == 0.0
    shift = 2 * math.pi
    t = np.linspace(6.5, 9.2, 7)
    line = Line2D([0.3, -1.0], [0.0, 1.0])
    nurbs = NurbsCurve(np.array([[0.0, 0.0], [1.0, 2.0], [3.0, 1.0]]), [6.5, 6.5, 6.5, 9.2, 9.2, 9.2], 2)
    trig = Trig2D([1.0, 2.0], [0.5, 0.0], [0.0, 0.5])
    for pc in (line, nurbs, trig):
        np.testing.assert_allclose(_advanced(pc, shift).evaluate(t - shift), pc.evaluate(t), rtol=0, atol=1e-12)
