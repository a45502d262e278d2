"""from_ocp / from_build123d: build123d primitives and Booleans keep OCCT's volume and area, and check clean."""

from __future__ import annotations

import numpy as np
import pytest

from coons.errors import InvalidInputError
from coons.topology.mass import face_areas

pytestmark = pytest.mark.occt

#: Exact analytic geometry on both sides: only round-off and OCCT's converged integration differ.
RTOL_EXACT = 1e-12
#: Shapes whose OCCT edges are fitted B-splines (intersection curves) or whose faces OCCT
#: integrates numerically: the issue's 1e-9.
RTOL_FITTED = 1e-9


def _occt_figures(shape):
    from OCP.BRepGProp import BRepGProp
    from OCP.GProp import GProp_GProps

    g = GProp_GProps()
    BRepGProp.VolumeProperties_s(shape.wrapped, g, 1e-12)
    v = g.Mass()
    g = GProp_GProps()
    BRepGProp.SurfaceProperties_s(shape.wrapped, g, 1e-12)
    return v, g.Mass()


def _shapes():
    import build123d as bd

    return {
        # name: (shape, OCCT faces, coons faces, rtol)
        "box": (bd.Box(10, 20, 30), 6, 6, RTOL_EXACT),
        "cylinder": (bd.Cylinder(5, 12), 3, 4, RTOL_EXACT),
        "cone": (bd.Cone(6, 2, 10), 3, 4, RTOL_EXACT),
        "cone_apex": (bd.Cone(6, 0, 10), 2, 3, RTOL_EXACT),
        "sphere": (bd.Sphere(7), 1, 2, RTOL_EXACT),
        "torus": (bd.Torus(10, 3), 1, 4, RTOL_EXACT),
        "wedge": (bd.Wedge(10, 5, 8, 2, 2, 8, 4), 6, 6, RTOL_EXACT),
        "placed_box": (bd.Rot(10, 20, 30) * bd.Pos(1, 2, 3) * bd.Box(3, 4, 5), 6, 6, RTOL_EXACT),
        "box_minus_cylinder": (bd.Box(20, 20, 10) - bd.Cylinder(4, 10), 7, 8, RTOL_EXACT),
        "box_plus_cylinder": (bd.Box(10, 10, 10) + bd.Pos(5, 0, 0) * bd.Cylinder(3, 14), 10, 11, RTOL_EXACT),
        "box_minus_sphere": (bd.Box(10, 10, 10) - bd.Pos(5, 5, 5) * bd.Sphere(4), 7, 7, RTOL_EXACT),
        "cylinder_plus_cylinder": (bd.Cylinder(3, 20) + bd.Rot(90, 0, 0) * bd.Cylinder(2, 20), 7, 10, RTOL_FITTED),
        "filleted_box": (bd.fillet(bd.Box(10, 10, 10).edges().group_by(bd.Axis.Z)[-1], 2), 10, 10, RTOL_FITTED),
        # mirrored shapes carry left-handed OCCT frames (gp_Ax3 indirect)
        "mirrored_cone": (bd.mirror(bd.Pos(1, 2, 3) * bd.Cone(4, 1, 6), bd.Plane.XY), 3, 4, RTOL_EXACT),
        "mirrored_torus": (bd.mirror(bd.Torus(5, 1), bd.Plane.YZ), 1, 4, RTOL_EXACT),
    }


def test_build123d_shapes_keep_volume_and_area():
    from coons.io.from_ocp import from_build123d

    for name, (shape, occt_faces, coons_faces, rtol) in _shapes().items():
        volume, area = _occt_figures(shape)
        s = from_build123d(shape)
        assert s.check().ok, name
        assert (len(shape.faces()), s.brep.n_faces) == (occt_faces, coons_faces), name
        assert np.all(face_areas(s.brep) > 0), name  # every face outward (sense and loops agree)
        np.testing.assert_allclose(s.volume, volume, rtol=rtol, err_msg=name)
        np.testing.assert_allclose(s.area, area, rtol=rtol, err_msg=name)


def test_compound_of_two_solids_gives_two_lumps_and_voids_nest():
    import build123d as bd

    from coons.io.from_ocp import from_build123d, from_ocp

    two = bd.Compound([bd.Box(1, 1, 1).solid(), bd.Pos(5, 0, 0) * bd.Sphere(1).solid()])
    s = from_build123d(two)
    assert s.check().ok and len(s.lumps()) == 2
    np.testing.assert_allclose(s.volume, 1.0 + 4.0 / 3.0 * np.pi, rtol=RTOL_EXACT)
    hollow = bd.Box(4, 4, 4) - bd.Sphere(1)  # an inner spherical void
    s = from_ocp(hollow.wrapped)
    assert s.check().ok and len(s.shells()) == 2
    np.testing.assert_allclose(s.volume, 64.0 - 4.0 / 3.0 * np.pi, rtol=RTOL_EXACT)


def test_errors():
    from OCP.TopoDS import TopoDS_Shape

    from coons.io.from_ocp import from_build123d, from_ocp

    with pytest.raises(InvalidInputError, match=r"from_ocp needs an OCP TopoDS_Shape, got int"):
        from_ocp(3)
    with pytest.raises(InvalidInputError, match=r"null TopoDS_Shape"):
        from_ocp(TopoDS_Shape())
    with pytest.raises(InvalidInputError, match=r"from_build123d needs a build123d shape \(with .wrapped\), got str"):
        from_build123d("box")


def test_offset_surface_is_refused_by_name():
    import build123d as bd
    from OCP.BRepBuilderAPI import BRepBuilderAPI_MakeFace
    from OCP.Geom import Geom_OffsetSurface, Geom_Plane
    from OCP.gp import gp_Ax3, gp_Dir, gp_Pnt

    from coons.io.from_ocp import from_build123d

    off = Geom_OffsetSurface(Geom_Plane(gp_Ax3(gp_Pnt(0, 0, 0), gp_Dir(0, 0, 1))), 1.0)
    face = BRepBuilderAPI_MakeFace(off, 0.0, 1.0, 0.0, 1.0, 1e-7).Face()
    with pytest.raises(InvalidInputError, match=r"face 0: OCCT surface type GeomAbs_OffsetSurface is not supported"):
        from_build123d(bd.Face(face))
