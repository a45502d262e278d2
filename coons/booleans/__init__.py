"""coons.booleans: Boolean operations.

The planar layer (:mod:`.planar`) computes exact union, intersection, difference and
symmetric difference of polygon sets in 2-D and on a plane in 3-D, from an exact
arrangement of the operands' edges; trim loops and planar faces share it.  Polyhedral and
B-rep Booleans build on it.  This package imports the kernel and topology, never a
reference engine.
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

__all__ = [
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
