"""Exact rational NURBS circles, spheres and cylinders built by hand, shared by the kernel tests.

They are written out from the standard 9-point circle (weights 1, sqrt(2)/2 alternating) rather
than taken from :mod:`coons.kernel.conics`, so the tests of projection and differential geometry
do not depend on the code paths of the constructions they check against.
"""

from __future__ import annotations

import numpy as np

from coons.kernel.curve import NurbsCurve
from coons.kernel.surface import NurbsSurface

SQ2 = np.sqrt(0.5)
_SQUARE = np.array([[1, 0], [1, 1], [0, 1], [-1, 1], [-1, 0], [-1, -1], [0, -1], [1, -1], [1, 0]], float)
_KNOTS = [0, 0, 0, 0.25, 0.25, 0.5, 0.5, 0.75, 0.75, 1, 1, 1]
_WEIGHTS = np.array([1, SQ2, 1, SQ2, 1, SQ2, 1, SQ2, 1])


def circle(radius: float = 2.0, dim: int = 2, centre=None) -> NurbsCurve:
    """Full rational quadratic circle, counter-clockwise from (R, 0) in the xy plane, domain [0, 1]."""
    P = radius * _SQUARE
    if centre is not None:
        P = P + np.asarray(centre, dtype=float)
    return NurbsCurve(np.pad(P, ((0, 0), (0, dim - 2))), _KNOTS, 2, _WEIGHTS)


def sphere(radius: float = 2.0) -> NurbsSurface:
    """Rational biquadratic sphere: u the full circle of longitude, v from the south to the north pole."""
    meridian = np.array([[0, -1], [1, -1], [1, 0], [1, 1], [0, 1]], float)
    w_v = np.array([1, SQ2, 1, SQ2, 1])
    P = np.empty((9, 5, 3))
    P[..., 0] = radius * _SQUARE[:, None, 0] * meridian[None, :, 0]
    P[..., 1] = radius * _SQUARE[:, None, 1] * meridian[None, :, 0]
    P[..., 2] = radius * meridian[None, :, 1]
    return NurbsSurface(P, _KNOTS, [0, 0, 0, 0.5, 0.5, 1, 1, 1], 2, 2, _WEIGHTS[:, None] * w_v[None, :])


def cylinder(radius: float = 1.5, height: float = 3.0) -> NurbsSurface:
    """Rational cylinder: u around the z axis, v along it from 0 to ``height``."""
    c = circle(radius)
    P = np.empty((9, 2, 3))
    P[:, :, :2] = c.control_points[:, None, :]
    P[:, 0, 2], P[:, 1, 2] = 0.0, height
    return NurbsSurface(P, c.knots, [0, 0, 1, 1], 2, 1, np.repeat(c.weights[:, None], 2, axis=1))
