"""coons.kernel: pure geometry on numpy and scipy.

NURBS curves and surfaces (:class:`NurbsCurve`, :class:`NurbsSurface`) with vectorised
evaluation and derivatives; knot insertion, refinement, removal, degree elevation,
splitting and Bézier decomposition (:mod:`.refine`); exact conics and quadrics as NURBS
(:mod:`.conics`); analytic curves and surfaces with OCCT's parametrisations
(:mod:`.analytic`); constructions (:mod:`.construct`); interpolation and least squares
(:mod:`.fitting`); closest points (:mod:`.projection`); differential geometry
(:mod:`.differential`); p-curve types (:mod:`.pcurve`); exact orientation predicates
(:mod:`.predicates`) and polygon rings (:mod:`.polygon`).

The analytic types are named as STEP names them (``PlanarSurface``, ``CylindricalSurface``,
``ConicalSurface``, ``SphericalSurface``, ``ToroidalSurface``) because ``coons.Cylinder`` etc. are
the solids and build123d's ``Plane`` is a coordinate frame.  The kernel imports nothing of
coons's topology, Booleans or I/O, and never a reference engine.
"""

from coons.kernel import conics, construct, differential, fitting, polygon, predicates, projection, refine
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
from coons.kernel.polygon import Polygon, PolygonSet
from coons.kernel.projection import ClosestPoints
from coons.kernel.surface import NurbsSurface

__all__ = [
    "NurbsCurve",
    "NurbsSurface",
    "Line",
    "Circle",
    "Ellipse",
    "PlanarSurface",
    "CylindricalSurface",
    "ConicalSurface",
    "SphericalSurface",
    "ToroidalSurface",
    "Line2D",
    "Trig2D",
    "ClosestPoints",
    "Polygon",
    "PolygonSet",
    "conics",
    "construct",
    "differential",
    "fitting",
    "polygon",
    "predicates",
    "projection",
    "refine",
]
