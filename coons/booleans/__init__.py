"""coons.booleans: Boolean operations.

The planar layer (:mod:`.planar`) computes exact union, intersection, difference and
symmetric difference of polygon sets in 2-D and on a plane in 3-D, from an exact
arrangement of the operands' edges; trim loops and planar faces share it.  The polyhedral
layer (:mod:`.polyhedral`) computes exact ``union``, ``difference`` and ``intersection`` of
solids whose faces are all planar.  The B-rep layer (:mod:`.solid`) combines solids bounded by
any trimmed surfaces through surface–surface intersection, face splitting, classification and
sewing, and hands all-planar pairs to the polyhedral layer; its ``union``, ``difference`` and
``intersection`` are registered here as the ``+``, ``-`` and ``&`` operators of
:class:`~coons.topology.shape.Solid` (importing :mod:`coons` imports this package).  This package imports the kernel
and topology, never a reference engine.
"""

from coons.booleans.planar import (
    OPERATIONS,
    PlaneFrame,
    Polygon3D,
    check_polygon_set,
    planar_boolean,
    polygon_boolean,
    polygon_difference,
    polygon_intersection,
    polygon_symmetric_difference,
    polygon_union,
)
from coons.booleans.solid import difference, intersection, union
from coons.topology.shape import register_boolean

register_boolean("union", union)
register_boolean("difference", difference)
register_boolean("intersection", intersection)

__all__ = [
    "union",
    "difference",
    "intersection",
    "OPERATIONS",
    "PlaneFrame",
    "Polygon3D",
    "check_polygon_set",
    "planar_boolean",
    "polygon_boolean",
    "polygon_difference",
    "polygon_intersection",
    "polygon_symmetric_difference",
    "polygon_union",
]
