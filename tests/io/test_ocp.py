"""to_ocp / to_build123d: OCCT's checker accepts the shapes built directly, and measures them as coons does.

Truth: ``BRepCheck_Analyzer`` validity and ``BRepGProp`` (adaptive, eps 1e-12) volume and area
against coons's mass properties, on the same cases as the STEP writer tests; plus the
structure OCCT needs (degenerated edges only at poles and apexes, one face per coons face,
edge tolerances no looser than coons's) and every error branch.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

import coons
from coons.errors import InvalidInputError
from coons.io.ocp import to_build123d, to_ocp
from coons.topology.shape import Solid
from tests.io.test_step_write import CASES, occt_counts, occt_props
from tests.io.test_step_write import occt_edges as _edges

pytestmark = pytest.mark.occt

#: OCCT's adaptive integration (eps 1e-12) against coons's mass properties.
RTOL_MASS = 1e-9


@pytest.mark.parametrize("case", list(CASES))
def test_valid_solid_with_the_same_measures(case):
    from OCP.BRepCheck import BRepCheck_Analyzer

    s = CASES[case]()
    shape = to_ocp(s)
    assert BRepCheck_Analyzer(shape).IsValid()
    assert occt_counts(shape) == (s.brep.n_solids, s.brep.n_faces)
    v, a = occt_props(shape)
    np.testing.assert_allclose(v, s.volume, rtol=RTOL_MASS)
    np.testing.assert_allclose(a, s.area, rtol=RTOL_MASS)
    edges = _edges(shape)
    real = [e for e in edges if not e[0]]
    assert len(real) == s.brep.n_edges
    assert all(same for _, _, same in edges)


@pytest.mark.parametrize(
    ("case", "poles"),
    [("sphere", 4), ("cone apex", 2), ("cylinder", 0), ("torus", 0), ("box", 0)],
)
def test_degenerated_edges_only_where_a_surface_collapses(case, poles):
    # Sphere: 2 hemispheres x 2 poles; apex cone: the side's 2 half faces meet the apex once each.
    edges = _edges(to_ocp(CASES[case]()))
    assert sum(d for d, _, _ in edges) == poles


def test_tolerances_are_coons_achieved_values_floored_at_occt_confusion():
    s = CASES["cylinder with skewed NURBS caps"]()
    tols = [t for d, t, _ in _edges(to_ocp(s, tol=coons.Tolerance(linear=1e-6)))]
    assert min(tols) >= 1e-6
    # The skewed ellipse p-curves were made same-parameter by BRepLib within a small tolerance.
    assert max(tols) < 1e-5


def test_void_shell_is_inside_and_counts_negative():
    from OCP.BRepClass3d import BRepClass3d_SolidClassifier
    from OCP.gp import gp_Pnt
    from OCP.TopAbs import TopAbs_IN, TopAbs_OUT

    s = coons.Box(4, 4, 4) - coons.Box(1, 1, 1)
    shape = to_ocp(s)
    cls = BRepClass3d_SolidClassifier(shape)
    cls.Perform(gp_Pnt(0, 0, 0), 1e-7)
    assert cls.State() == TopAbs_OUT  # inside the void
    cls.Perform(gp_Pnt(1.5, 0, 0), 1e-7)
    assert cls.State() == TopAbs_IN
    np.testing.assert_allclose(occt_props(shape)[0], 63.0, rtol=1e-12)


def test_to_build123d_wraps_solids_and_compounds():
    import build123d as bd

    one = to_build123d(coons.Torus(3, 1))
    assert isinstance(one, bd.Solid) and one.is_valid
    np.testing.assert_allclose(one.volume, coons.Torus(3, 1).volume, rtol=1e-12)
    two = to_build123d(CASES["two lumps"]())
    assert isinstance(two, bd.Compound) and len(two.solids()) == 2
    np.testing.assert_allclose(two.volume, 3.0, rtol=1e-12)


def test_occt_booleans_accept_the_result():
    # The shapes are usable by OCCT's own algorithms: cut a coons cylinder from a coons box.
    import build123d as bd

    r = to_build123d(coons.Box(4, 4, 4)) - to_build123d(coons.Cylinder(1, 6))
    assert r.is_valid
    np.testing.assert_allclose(r.volume, 64 - np.pi * 4, rtol=1e-9)
    assert isinstance(r, (bd.Part, bd.Solid, bd.Compound))


def test_errors():
    with pytest.raises(InvalidInputError, match="to_ocp needs a coons Solid, got str"):
        to_ocp("box")
    with pytest.raises(InvalidInputError, match="non-empty solid"):
        to_ocp(Solid.empty())

    class Blob:
        pass

    b = coons.Cylinder(1, 2).brep
    with pytest.raises(InvalidInputError, match="unsupported surface Blob"):
        to_ocp(Solid(dataclasses.replace(b, surfaces=(Blob(),) + b.surfaces[1:])))
    with pytest.raises(InvalidInputError, match="unsupported edge curve Blob"):
        to_ocp(Solid(dataclasses.replace(b, curves=(Blob(),) + b.curves[1:])))
    with pytest.raises(InvalidInputError, match="unsupported p-curve Blob"):
        to_ocp(Solid(dataclasses.replace(b, pcurves=(Blob(),) + b.pcurves[1:])))
