"""The user-facing solid: an immutable value wrapping a checked :class:`BRep`.

:class:`Solid` is what ``coons.Box(...)``, ``coons.Cylinder(...)``, sweeps and Booleans
return.  It may hold several lumps (disjoint solids) and voids.  Queries return views
(``faces()``, ``edges()``, ``vertices()``, ``shells()``, ``lumps()``); measures
(``volume``, ``area``, ``centroid``, ``inertia``) are computed on the exact B-rep by
:mod:`coons.topology.mass` and cached; placement returns new solids
(``translate``, ``rotate``, ``scale``, ``mirror``, ``Pos(...) * solid``, ``Rot(...) * solid``).
:meth:`Solid.empty` is the solid with no lumps (the result of an empty Boolean): valid, volume
and area 0; it has no centroid, inertia or bounding box.

The Boolean operators ``+``, ``-`` and ``&`` are implemented by :mod:`coons.booleans`,
which registers itself here when imported (``import coons`` does); the topology layer
never imports the Boolean layer.
"""

from __future__ import annotations

from functools import cached_property
from typing import Any, Callable

import numpy as np

from coons.errors import CoonsError, InvalidInputError
from coons.topology.brep import BRep, Edge, Face, Lump, Shell, Vertex

__all__ = ["Solid", "register_boolean"]

_BOOLEAN: dict[str, Callable[..., "Solid"]] = {}


def register_boolean(name: str, fn: Callable[..., "Solid"]) -> None:
    """Install the implementation of ``"union"``, ``"difference"`` or ``"intersection"`` (used by coons.booleans)."""
    if name not in ("union", "difference", "intersection"):
        raise InvalidInputError(f"unknown Boolean operation {name!r}")
    _BOOLEAN[name] = fn


def _boolean(name: str, a: "Solid", b: Any) -> "Solid":
    if not isinstance(b, Solid):
        return NotImplemented  # type: ignore[return-value]
    fn = _BOOLEAN.get(name)
    if fn is None:
        raise CoonsError(f"Boolean {name} is not available: import coons (or coons.booleans) first")
    return fn(a, b)


def _empty_brep() -> BRep:
    """A B-rep with zero rows in every table."""
    from coons.topology.brep import _COLUMNS

    shapes = {"vertex_point": (0, 3), "edge_vertex": (0, 2), "edge_loop": (0, 2), "edge_wing": (0, 4),
              "edge_range": (0, 2), "edge_pcurve": (0, 2)}
    cols = {name: np.zeros(shapes.get(name, (0,)), dtype=dt) for name, dt in _COLUMNS.items()}
    for ptr in ("face_loop_ptr", "shell_face_ptr", "solid_shell_ptr"):
        cols[ptr] = np.zeros(1, dtype=np.int64)
    return BRep(**cols)


class Solid:
    """A solid (one or more lumps) bounded by a valid winged-edge B-rep.

    Parameters
    ----------
    brep : BRep
        An already checked B-rep (as returned by ``BRepBuilder.build()``).
    """

    __slots__ = ("brep", "__dict__")

    def __init__(self, brep: BRep) -> None:
        if not isinstance(brep, BRep):
            raise InvalidInputError(f"Solid needs a BRep, got {type(brep).__name__}")
        self.brep = brep

    @classmethod
    def empty(cls) -> "Solid":
        """The empty solid: a B-rep with no rows (no lumps, faces, edges or vertices).

        It is valid (``check`` finds nothing to object to), its ``volume`` and ``area`` are 0.0, and
        ``centroid``, ``inertia`` and ``bounding_box`` raise ``TopologyError`` (an empty set has
        neither a centroid nor a box).
        """
        return cls(_empty_brep())

    @property
    def is_empty(self) -> bool:
        """True for the solid with no lumps."""
        return self.brep.n_faces == 0

    def __repr__(self) -> str:
        b = self.brep
        return f"Solid(lumps={b.n_solids}, faces={b.n_faces}, edges={b.n_edges}, vertices={b.n_vertices})"

    # ------------------------------------------------------------ topology queries
    def faces(self) -> list[Face]:
        return self.brep.faces()

    def edges(self) -> list[Edge]:
        return self.brep.edges()

    def vertices(self) -> list[Vertex]:
        return self.brep.vertices()

    def shells(self) -> list[Shell]:
        return self.brep.shells()

    def lumps(self) -> list[Lump]:
        return self.brep.lumps()

    def surface_types(self) -> list[str]:
        """Surface type of each face (``"plane"``, ``"cylinder"``, ...), in face order."""
        return [f.surface_type for f in self.faces()]

    # ------------------------------------------------------------ validity
    def check(self, tol=None):
        """Full validity report (:func:`coons.topology.check.check`)."""
        from coons.topology.check import check

        return check(self.brep, tol)

    @property
    def is_valid(self) -> bool:
        return self.check().ok

    # ------------------------------------------------------------ measures
    @cached_property
    def _mass(self):
        from coons.topology.mass import mass_properties

        return mass_properties(self.brep)

    @property
    def volume(self) -> float:
        return 0.0 if self.is_empty else self._mass.volume

    @property
    def area(self) -> float:
        return 0.0 if self.is_empty else self._mass.area

    @property
    def centroid(self) -> np.ndarray:
        return self._mass.centroid

    @property
    def inertia(self) -> np.ndarray:
        """Inertia tensor about the centroid for unit density, ``(3, 3)``."""
        return self._mass.inertia

    def bounding_box(self) -> np.ndarray:
        """Axis-aligned bounding box ``(2, 3)`` (min row, max row) of the exact geometry."""
        from coons.topology.mass import bounding_box

        return bounding_box(self.brep)

    # ------------------------------------------------------------ placement
    def transformed(self, matrix) -> "Solid":
        """A copy moved by a 4×4 similarity transform (rotation, translation, uniform scale, reflection)."""
        from coons.topology.transform import transform_brep

        return Solid(transform_brep(self.brep, matrix))

    def translate(self, offset) -> "Solid":
        from coons.topology.transform import translation

        return self.transformed(translation(offset))

    def rotate(self, origin, direction, degrees: float) -> "Solid":
        from coons.topology.transform import rotation

        return self.transformed(rotation(origin, direction, degrees))

    def scale(self, factor: float) -> "Solid":
        from coons.topology.transform import scaling

        return self.transformed(scaling(factor))

    def mirror(self, origin=(0.0, 0.0, 0.0), normal=(1.0, 0.0, 0.0)) -> "Solid":
        from coons.topology.transform import reflection

        return self.transformed(reflection(origin, normal))

    # ------------------------------------------------------------ Booleans
    def __add__(self, other: Any) -> "Solid":
        return _boolean("union", self, other)

    def __sub__(self, other: Any) -> "Solid":
        return _boolean("difference", self, other)

    def __and__(self, other: Any) -> "Solid":
        return _boolean("intersection", self, other)
