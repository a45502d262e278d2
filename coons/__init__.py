"""coons: a solid modeling kernel in Python.

The names most scripts need, build123d-style::

    import coons
    part = coons.Box(10, 10, 10) - coons.Box(3, 3, 20)       # polyhedral Booleans (+, -, &)
    placed = coons.Pos(0, 0, 5) * coons.Rot(0, 45, 0) * coons.Torus(4, 1)
    print(placed.volume, placed.area, coons.check(placed).ok)

Layers: :mod:`coons.kernel` (geometry), :mod:`coons.topology` (B-rep), :mod:`coons.booleans`,
:mod:`coons.io` (files and interop), :mod:`coons.validation`.  Importing coons imports no
reference engine (OCCT, manifold3d, trimesh).
"""

from coons.errors import (
    BooleanError,
    CoonsError,
    ConvergenceError,
    InvalidGeometryError,
    InvalidInputError,
    StepError,
    TopologyError,
)
from coons.tolerance import DEFAULT_TOLERANCE, Tolerance
from coons.topology.check import check
from coons.topology.from_mesh import from_mesh
from coons.topology.primitives import Box, Cone, Cylinder, Sphere, Torus
from coons.topology.shape import Solid
from coons.topology.profile import Profile, Segment
from coons.topology.sweep import extrude, loft, revolve
from coons.topology.tessellate import tessellate
from coons.topology.transform import Location, Pos, Rot
from coons.io.step import export_step, import_step
from coons.io.stl import export_stl, import_stl
from coons.booleans import difference, intersection, union  # also registers Solid's + - &

__version__ = "0.1.0"

__all__ = [
    "Box",
    "Cylinder",
    "Cone",
    "Sphere",
    "Torus",
    "Solid",
    "Location",
    "Pos",
    "Rot",
    "check",
    "Profile",
    "Segment",
    "extrude",
    "revolve",
    "loft",
    "from_mesh",
    "tessellate",
    "union",
    "difference",
    "intersection",
    "export_stl",
    "export_step",
    "import_step",
    "import_stl",
    "Tolerance",
    "DEFAULT_TOLERANCE",
    "CoonsError",
    "InvalidInputError",
    "InvalidGeometryError",
    "ConvergenceError",
    "TopologyError",
    "BooleanError",
    "StepError",
]
