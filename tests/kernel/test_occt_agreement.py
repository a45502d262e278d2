"""Agreement with OCCT (through OCP): B-spline derivatives, closest points, curvatures and arc length.

The same poles, weights, distinct knots and multiplicities are handed to OCCT's
``Geom_BSplineCurve`` / ``Geom_BSplineSurface`` (clamped knot vectors only: OCCT
takes clamped or periodic ones).  Derivatives must agree to 1e-10 relative to the
size of the derivative of that order; curvatures to 1e-9 relative; closest points
are never farther than OCCT's ``GeomAPI_ProjectPointOnSurf`` answer and equal to it
on gently curved surfaces.  The number of OCP calls is kept to a few hundred.
"""

from __future__ import annotations

import numpy as np
import pytest
from OCP.collections import Array1_double, Array1_gp_Pnt, Array1_int, Array2_double, Array2_gp_Pnt
from OCP.GCPnts import GCPnts_AbscissaPoint
from OCP.Geom import Geom_BSplineCurve, Geom_BSplineSurface
from OCP.GeomAdaptor import GeomAdaptor_Curve
from OCP.GeomAPI import GeomAPI_ProjectPointOnSurf
from OCP.GeomLProp import GeomLProp_CLProps, GeomLProp_SLProps
from OCP.gp import gp_Pnt

from coons.kernel import differential as dg
from coons.kernel.curve import NurbsCurve
from coons.kernel.surface import NurbsSurface

from .strategies import random_knots

pytestmark = pytest.mark.occt

#: Derivatives: relative to the largest derivative of the same order among the samples.
DERIVATIVES = 1e-10
#: Curvatures: relative to the largest principal curvature at the point (or 1 / size).
CURVATURES = 1e-9
LINEAR = 1e-7


def _pnt(p) -> gp_Pnt:
    p = np.pad(np.asarray(p, dtype=float), (0, 3 - len(p)))
    return gp_Pnt(*p)


def _array1(values, kind):
    values = list(values)
    a = kind(1, len(values))
    for i, x in enumerate(values, start=1):
        a.SetValue(i, x)
    return a


def occt_curve(c: NurbsCurve) -> Geom_BSplineCurve:
    knots, mults = c.knot_multiplicities
    return Geom_BSplineCurve(
        _array1([_pnt(p) for p in c.control_points], Array1_gp_Pnt),
        _array1(c.weights.tolist(), Array1_double),
        _array1(knots.tolist(), Array1_double),
        _array1([int(m) for m in mults], Array1_int),
        c.degree,
        False,
    )


def occt_surface(s: NurbsSurface) -> Geom_BSplineSurface:
    nu, nv = s.shape
    poles = Array2_gp_Pnt(1, nu, 1, nv)
    weights = Array2_double(1, nu, 1, nv)
    for i in range(nu):
        for j in range(nv):
            poles.SetValue(i + 1, j + 1, _pnt(s.control_points[i, j]))
            weights.SetValue(i + 1, j + 1, float(s.weights[i, j]))
    ku, mu = np.unique(s.knots_u, return_counts=True)
    kv, mv = np.unique(s.knots_v, return_counts=True)
    return Geom_BSplineSurface(
        poles, weights,
        _array1(ku.tolist(), Array1_double), _array1(kv.tolist(), Array1_double),
        _array1([int(m) for m in mu], Array1_int), _array1([int(m) for m in mv], Array1_int),
        s.degree_u, s.degree_v, False, False,
    )


def _vec(v) -> np.ndarray:
    return np.array([v.X(), v.Y(), v.Z()])


def random_curve(seed: int, dim: int = 3, rational: bool | None = None) -> NurbsCurve:
    rng = np.random.default_rng(seed)
    p = int(rng.integers(1, 6))
    n = p + 1 + int(rng.integers(0, 6))
    is_rational = bool(rng.random() < 0.5) if rational is None else rational
    w = rng.uniform(0.3, 3.0, n) if is_rational else None
    return NurbsCurve(rng.uniform(-10, 10, (n, dim)), random_knots(rng, n, p, True), p, w)


def random_surface(seed: int, rational: bool | None = None, bumpy: bool = False) -> NurbsSurface:
    rng = np.random.default_rng(seed)
    pu, pv = (int(x) for x in rng.integers(1, 5, 2))
    nu, nv = pu + 1 + int(rng.integers(0, 4)), pv + 1 + int(rng.integers(0, 4))
    is_rational = bool(rng.random() < 0.5) if rational is None else rational
    if bumpy:  # a gently curved height field over [0, 4]^2
        g = np.stack(np.meshgrid(np.linspace(0, 4, nu), np.linspace(0, 4, nv), indexing="ij"), axis=-1)
        P = np.concatenate([g, rng.uniform(-0.5, 0.5, (nu, nv, 1))], axis=2)
        w = rng.uniform(0.7, 1.4, (nu, nv)) if is_rational else None
    else:
        P = rng.uniform(-10, 10, (nu, nv, 3))
        w = rng.uniform(0.3, 3.0, (nu, nv)) if is_rational else None
    return NurbsSurface(P, random_knots(rng, nu, pu, True), random_knots(rng, nv, pv, True), pu, pv, w)


def _agree(ours: np.ndarray, theirs: np.ndarray, rtol: float) -> None:
    """Vectors ``(m, 3)`` agree to ``rtol`` of the largest of ``theirs`` (the scale of that derivative order)."""
    scale = max(np.linalg.norm(theirs, axis=-1).max(), 1e-300)
    err = np.linalg.norm(ours - theirs, axis=-1)
    assert np.all(err <= rtol * scale), f"max error {err.max():.3g} vs allowed {rtol * scale:.3g}"


# ---------------------------------------------------------------------- derivatives
@pytest.mark.parametrize("seed", range(12))
def test_curve_derivatives_agree_with_geom_bspline_curve(seed):
    c = random_curve(seed, dim=2 + seed % 2, rational=bool(seed % 3 != 0))
    occ = occt_curve(c)
    u = np.concatenate([[c.domain[0], c.domain[1]], np.random.default_rng(seed).uniform(*c.domain, 4)])
    ours = np.pad(c.derivatives(u, 3), ((0, 0), (0, 0), (0, 3 - c.dimension)))
    points = np.array([[occ.Value(x).X(), occ.Value(x).Y(), occ.Value(x).Z()] for x in u])
    _agree(ours[:, 0], points, DERIVATIVES)
    for k in range(1, 4):
        _agree(ours[:, k], np.array([_vec(occ.DN(float(x), k)) for x in u]), DERIVATIVES)


@pytest.mark.parametrize("seed", range(8))
def test_surface_derivatives_agree_with_geom_bspline_surface(seed):
    s = random_surface(seed, rational=bool(seed % 2))
    occ = occt_surface(s)
    rng = np.random.default_rng(100 + seed)
    u = np.concatenate([[s.domain_u[0], s.domain_u[1]], rng.uniform(*s.domain_u, 3)])
    v = np.concatenate([[s.domain_v[1], s.domain_v[0]], rng.uniform(*s.domain_v, 3)])
    ours = s.derivatives(u, v, 2)
    for k, l in ((0, 0), (1, 0), (0, 1), (2, 0), (1, 1), (0, 2)):
        if k + l == 0:
            theirs = np.array([[occ.Value(a, b).X(), occ.Value(a, b).Y(), occ.Value(a, b).Z()] for a, b in zip(u, v)])
        else:
            theirs = np.array([_vec(occ.DN(float(a), float(b), k, l)) for a, b in zip(u, v)])
        _agree(ours[:, k, l], theirs, DERIVATIVES)


# ---------------------------------------------------------------------- closest points
@pytest.mark.parametrize("seed", range(4))
def test_surface_closest_points_agree_with_geomapi_project_point_on_surf(seed):
    rng = np.random.default_rng(200 + seed)
    for bumpy in (True, False):
        s = random_surface(300 + seed, bumpy=bumpy)
        occ = occt_surface(s)
        box = s.bounding_box()
        P = rng.uniform(box[0] - 1, box[1] + 1, (8, 3))
        cp = s.closest_points(P)
        (u0, u1), (v0, v1) = s.domain_u, s.domain_v
        uv = cp.parameters
        interior = (uv[:, 0] > u0) & (uv[:, 0] < u1) & (uv[:, 1] > v0) & (uv[:, 1] < v1)
        compared = 0
        for i, p in enumerate(P):
            # OCCT lists orthogonal projections only: none exists where the answer is on the boundary.
            proj = GeomAPI_ProjectPointOnSurf(gp_Pnt(*p), occ)
            if proj.NbPoints() == 0:
                assert not interior[i]
                continue
            theirs = proj.LowerDistance()
            # Never farther than OCCT; with an interior answer on a gently curved patch, the same answer.
            assert cp.distances[i] <= theirs + LINEAR
            if bumpy and interior[i]:
                assert abs(cp.distances[i] - theirs) <= LINEAR
                a, b = proj.LowerDistanceParameters()
                np.testing.assert_allclose(cp.points[i], s.evaluate(a, b), rtol=0, atol=1e-6)
                compared += 1
        assert compared > 0 or not bumpy


# ---------------------------------------------------------------------- curvatures and length
@pytest.mark.parametrize("seed", range(6))
def test_surface_curvatures_agree_with_geomlprop(seed):
    s = random_surface(400 + seed, rational=bool(seed % 2), bumpy=bool(seed % 3 == 0))
    occ = occt_surface(s)
    rng = np.random.default_rng(500 + seed)
    u, v = rng.uniform(*s.domain_u, 4), rng.uniform(*s.domain_v, 4)
    k = dg.surface_curvatures(s, u, v)
    n = dg.surface_normal(s, u, v)
    for i in range(u.size):
        props = GeomLProp_SLProps(occ, float(u[i]), float(v[i]), 2, 1e-9)
        assert props.IsCurvatureDefined()
        scale = max(abs(props.MaxCurvature()), abs(props.MinCurvature()), 1.0 / 20.0)
        np.testing.assert_allclose(n[i], _vec(props.Normal()), rtol=0, atol=1e-10)
        np.testing.assert_allclose(k.k1[i], props.MaxCurvature(), rtol=0, atol=CURVATURES * scale)
        np.testing.assert_allclose(k.k2[i], props.MinCurvature(), rtol=0, atol=CURVATURES * scale)
        np.testing.assert_allclose(k.mean[i], props.MeanCurvature(), rtol=0, atol=CURVATURES * scale)
        np.testing.assert_allclose(k.gaussian[i], props.GaussianCurvature(), rtol=0, atol=CURVATURES * scale**2)
        if not props.IsUmbilic():
            d1, d2 = _dir(), _dir()
            props.CurvatureDirections(d1, d2)
            # Directions are defined up to sign.
            assert abs(abs(float(np.dot(k.d1[i], _vec(d1)))) - 1.0) <= 1e-7
            assert abs(abs(float(np.dot(k.d2[i], _vec(d2)))) - 1.0) <= 1e-7


def _dir():
    from OCP.gp import gp_Dir

    return gp_Dir()


@pytest.mark.parametrize("seed", range(6))
def test_curve_curvature_and_length_agree_with_occt(seed):
    c = random_curve(600 + seed, dim=3)
    occ = occt_curve(c)
    u = np.random.default_rng(700 + seed).uniform(*c.domain, 5)
    if c.degree >= 2:
        ours = dg.curve_curvature(c, u)
        theirs = np.array([GeomLProp_CLProps(occ, float(x), 2, 1e-12).Curvature() for x in u])
        np.testing.assert_allclose(ours, theirs, rtol=CURVATURES, atol=CURVATURES * theirs.max())
    length = GCPnts_AbscissaPoint.Length_s(GeomAdaptor_Curve(occ), 1e-10)
    np.testing.assert_allclose(dg.curve_length(c), length, rtol=0, atol=LINEAR)
