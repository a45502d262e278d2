"""The reference catalogue of ``coons validate``: named recipes of primitives, placements and Booleans.

A :class:`Case` is a name, a *recipe* and a few tags.  A recipe is a small tree of plain
lists, tuples, strings and numbers (so it pickles, prints and can be stored as JSON), read by
each engine of :mod:`coons.validation.engines`::

    ("box", l, w, h)            centred on the origin (build123d's and coons's default placement)
    ("cylinder", r, h)          axis +z, centred
    ("cone", r_bottom, r_top, h)
    ("sphere", r)
    ("torus", R, r)             axis +z
    ("prism", [(x, y), ...], h) a polygon in the plane z = 0 extruded by h along +z
    ("plate", w, d, h, [(cx, cy, r), ...])
                                a w × d rectangle (centred) with round holes, extruded by h along +z
    ("mesh", name)              a packaged or generated triangle mesh (:data:`MESHES`)
    ("pos", (x, y, z), node)    translation (build123d ``Pos``)
    ("rot", (ax, ay, az), node) rotation in degrees (build123d ``Rot``, intrinsic XYZ)
    ("union" | "difference" | "intersection", a, b)

The catalogue (:data:`CATALOGUE`, :func:`default_cases`) covers single primitives, generic
positions, coplanar faces, shared edges and vertices, touching in a face, an edge or a vertex,
tangent contact, coincident cylinders, nested, disjoint and identical operands, empty results and
mesh inputs.  Where the answer has a short closed form the case carries it
(``expect_volume``); these are derived in the recipe's own numbers, never copied from an engine.
The module only describes cases: it builds nothing and imports no engine.
"""

from __future__ import annotations

import fnmatch
import math
from dataclasses import dataclass, field
from typing import Any, Iterable, Sequence

from coons.errors import InvalidInputError

__all__ = ["Case", "CATALOGUE", "MESHES", "default_cases", "select_cases", "recipe_text", "is_curved"]

#: Mesh inputs a recipe may name: a packaged STL file or a generated closed mesh.
MESHES = {
    "xyz_cube": "the 20 mm calibration cube with embossed X, Y, Z letters (trimesh models, MIT; 260 triangles)",
    "octahedron": "a regular octahedron of circumradius 6 (generated)",
    "icosphere": "an icosahedron subdivided twice and pushed onto the sphere of radius 6 (generated, 320 triangles)",
    "ring": "a square ring (a polyhedral torus of genus 1): 12 × 12 outside, 6 × 6 hole, height 4 (generated)",
}

_PRIMITIVES = {"box": 3, "cylinder": 2, "cone": 3, "sphere": 1, "torus": 2, "prism": 2, "plate": 4, "mesh": 1}
_PLACEMENTS = ("pos", "rot")
_BOOLEANS = ("union", "difference", "intersection")
_CURVED = ("cylinder", "cone", "sphere", "torus", "plate")


@dataclass(frozen=True)
class Case:
    """One reference case.

    Attributes
    ----------
    name : str
        Unique, ``[a-z0-9_]``; command-line selection matches it with glob patterns.
    recipe : tuple
        The recipe tree (module docstring).
    description : str
        What the case exercises.
    tags : tuple of str
        ``"primitive"``, ``"planar"``, ``"curved"``, ``"coplanar"``, ``"touching"``, ``"tangent"``,
        ``"nested"``, ``"disjoint"``, ``"identical"``, ``"empty"``, ``"mesh"``, ``"generic"`` ...
    expect_volume : float or None
        The exact volume when it has a short closed form.
    """

    name: str
    recipe: tuple
    description: str
    tags: tuple[str, ...] = field(default_factory=tuple)
    expect_volume: float | None = None

    def __post_init__(self) -> None:
        validate_recipe(self.recipe, self.name)


def validate_recipe(node: Any, where: str = "recipe") -> None:
    """Check the shape of a recipe tree.

    Raises
    ------
    InvalidInputError
        An unknown node kind, a wrong number of arguments, an unknown mesh name.
    """
    if not isinstance(node, (tuple, list)) or not node or not isinstance(node[0], str):
        raise InvalidInputError(f"{where}: expected a recipe node (kind, args...), got {node!r}")
    kind, args = node[0], node[1:]
    if kind in _PRIMITIVES:
        if len(args) != _PRIMITIVES[kind]:
            raise InvalidInputError(f"{where}: {kind} takes {_PRIMITIVES[kind]} arguments, got {len(args)}: {node!r}")
        if kind == "mesh" and args[0] not in MESHES:
            raise InvalidInputError(f"{where}: unknown mesh {args[0]!r}, expected one of {sorted(MESHES)}")
    elif kind in _PLACEMENTS:
        if len(args) != 2 or len(args[0]) != 3:
            raise InvalidInputError(f"{where}: {kind} takes ((x, y, z), node), got {node!r}")
        validate_recipe(args[1], where)
    elif kind in _BOOLEANS:
        if len(args) != 2:
            raise InvalidInputError(f"{where}: {kind} takes 2 operands, got {len(args)}")
        validate_recipe(args[0], where)
        validate_recipe(args[1], where)
    else:
        raise InvalidInputError(
            f"{where}: unknown recipe node {kind!r}; expected one of "
            f"{sorted(_PRIMITIVES) + list(_PLACEMENTS) + list(_BOOLEANS)}"
        )


def is_curved(node: Any) -> bool:
    """True when some leaf of the recipe has a curved face."""
    kind = node[0]
    if kind in _PRIMITIVES:
        return kind in _CURVED
    if kind in _PLACEMENTS:
        return is_curved(node[2])
    return is_curved(node[1]) or is_curved(node[2])


def recipe_text(node: Any) -> str:
    """A one-line, build123d-like rendering of a recipe (``Box(10, 10, 10) - Pos(5, 0, 0) * Cylinder(3, 12)``)."""
    kind, args = node[0], node[1:]

    def num(x: Any) -> str:
        return f"{x:g}" if isinstance(x, (int, float)) else repr(x)

    if kind == "prism":
        return f"extrude(Polygon({len(args[0])} points), {num(args[1])})"
    if kind == "plate":
        return f"extrude(Rectangle({num(args[0])}, {num(args[1])}) - {len(args[3])} holes, {num(args[2])})"
    if kind == "mesh":
        return f"Mesh({args[0]!r})"
    if kind in _PRIMITIVES:
        return f"{kind.capitalize()}({', '.join(num(a) for a in args)})"
    if kind in _PLACEMENTS:
        inner = recipe_text(args[1])
        if args[1][0] in _BOOLEANS:
            inner = f"({inner})"
        return f"{kind.capitalize()}({', '.join(num(a) for a in args[0])}) * {inner}"
    op = {"union": "+", "difference": "-", "intersection": "&"}[kind]
    parts = []
    for sub in args:
        t = recipe_text(sub)
        parts.append(f"({t})" if sub[0] in _BOOLEANS else t)
    return f"{parts[0]} {op} {parts[1]}"


# ============================================================================ the catalogue
def _box(a: float, b: float, c: float) -> tuple:
    return ("box", a, b, c)


def _pos(x: float, y: float, z: float, node: tuple) -> tuple:
    return ("pos", (x, y, z), node)


def _rot(ax: float, ay: float, az: float, node: tuple) -> tuple:
    return ("rot", (ax, ay, az), node)


B10 = _box(10, 10, 10)
_L = [(0, 0), (8, 0), (8, 3), (3, 3), (3, 7), (0, 7)]  # an L-shaped polygon (area 8*3 + 3*4 = 36)
_TRI = [(-4, -3), (5, -2), (0, 6)]


def _catalogue() -> list[Case]:
    c: list[Case] = []

    def add(name: str, recipe: tuple, description: str, tags: Sequence[str], expect: float | None = None) -> None:
        c.append(Case(name, recipe, description, tuple(tags), expect))

    pi = math.pi
    # ---- single solids: exact measures of coons's primitives, sweeps and meshes against OCCT's
    add("box", B10, "a centred 10 mm cube", ["primitive", "planar"], 1000.0)
    add("box_rotated", _rot(17, 23, 31, _box(8, 5, 3)), "a box rotated about three axes", ["primitive", "planar"],
        120.0)
    add("cylinder", ("cylinder", 3, 10), "a cylinder: OCCT has a seam, coons two half-cylinder faces",
        ["primitive", "curved"], pi * 9 * 10)
    add("cylinder_rotated", _pos(1, 2, 3, _rot(30, 45, 0, ("cylinder", 2, 7))), "a placed, tilted cylinder",
        ["primitive", "curved"], pi * 4 * 7)
    add("cone_frustum", ("cone", 4, 2, 6), "a frustum of a cone", ["primitive", "curved"],
        pi * 6 / 3 * (16 + 8 + 4))
    add("cone_pointed", ("cone", 4, 0, 6), "a pointed cone: an apex vertex (OCCT: a degenerate edge)",
        ["primitive", "curved"], pi * 16 * 6 / 3)
    add("sphere", ("sphere", 5), "a sphere: two hemispheres in coons; one face, a seam and two poles in OCCT",
        ["primitive", "curved"], 4 / 3 * pi * 125)
    add("torus", ("torus", 6, 2), "a ring torus (genus 1)", ["primitive", "curved"], 2 * pi**2 * 6 * 4)
    add("prism_l", ("prism", _L, 4), "an extruded L-shaped polygon", ["primitive", "planar"], 36.0 * 4)
    add("plate_holes", ("plate", 16, 10, 2, [(-4, 0, 1.5), (4, 0, 1.5)]), "an extruded plate with two round holes",
        ["primitive", "curved"], (160 - 2 * pi * 2.25) * 2)
    add("mesh_xyz_cube", ("mesh", "xyz_cube"), MESHES["xyz_cube"], ["primitive", "planar", "mesh"])
    add("mesh_octahedron", ("mesh", "octahedron"), MESHES["octahedron"], ["primitive", "planar", "mesh"],
        4 / 3 * 6**3)
    add("mesh_icosphere", ("mesh", "icosphere"), MESHES["icosphere"], ["primitive", "planar", "mesh"])
    add("mesh_ring", ("mesh", "ring"), MESHES["ring"], ["primitive", "planar", "mesh"], (144 - 36) * 4)

    # ---- two boxes, generic position
    gen = _pos(3.3, 2.7, 1.9, B10)
    ov = 6.7 * 7.3 * 8.1
    add("box_box_generic_union", ("union", B10, gen), "two cubes overlapping in general position",
        ["planar", "generic"], 2000 - ov)
    add("box_box_generic_difference", ("difference", B10, gen), "a cube minus a cube in general position",
        ["planar", "generic"], 1000 - ov)
    add("box_box_generic_intersection", ("intersection", B10, gen), "the common part of two cubes",
        ["planar", "generic"], ov)
    rot = _rot(17, 23, 31, _box(8, 8, 8))
    add("box_box_rotated_union", ("union", B10, rot), "a cube and a rotated cube, all faces crossing",
        ["planar", "generic"])
    add("box_box_rotated_difference", ("difference", B10, rot), "a cube minus a rotated cube", ["planar", "generic"])
    add("box_box_rotated_intersection", ("intersection", B10, rot), "a cube and a rotated cube, common part",
        ["planar", "generic"])
    # ---- coplanar faces: same top and bottom planes
    cop = _pos(4, 3, 0, B10)
    add("box_box_coplanar_union", ("union", B10, cop), "two cubes sharing their top and bottom planes",
        ["planar", "coplanar"], 2000 - 6 * 7 * 10)
    add("box_box_coplanar_difference", ("difference", B10, cop), "cube minus a cube sharing two planes",
        ["planar", "coplanar"], 1000 - 6 * 7 * 10)
    add("box_box_coplanar_intersection", ("intersection", B10, cop), "common part of cubes sharing two planes",
        ["planar", "coplanar"], 6 * 7 * 10)
    # ---- touching in a face, an edge, a vertex
    face = _pos(10, 0, 0, B10)
    add("box_box_face_union", ("union", B10, face), "two cubes sharing a whole face: one 20 × 10 × 10 box",
        ["planar", "touching"], 2000.0)
    add("box_box_face_difference", ("difference", B10, face), "a cube minus its face neighbour: unchanged",
        ["planar", "touching"], 1000.0)
    add("box_box_face_intersection", ("intersection", B10, face), "cubes touching in a face: empty",
        ["planar", "touching", "empty"], 0.0)
    add("box_box_partial_face_union", ("union", B10, _pos(10, 4, 3, _box(10, 6, 6))),
        "a box against part of a cube's face", ["planar", "touching"], 1000 + 360)
    edge = _pos(10, 10, 0, B10)
    add("box_box_edge_union", ("union", B10, edge), "cubes sharing an edge (a non-manifold edge in the union)",
        ["planar", "touching"], 2000.0)
    add("box_box_edge_intersection", ("intersection", B10, edge), "cubes touching along an edge: empty",
        ["planar", "touching", "empty"], 0.0)
    vert = _pos(10, 10, 10, B10)
    add("box_box_vertex_union", ("union", B10, vert), "cubes sharing a vertex (a non-manifold vertex)",
        ["planar", "touching"], 2000.0)
    add("box_box_vertex_difference", ("difference", B10, vert), "a cube minus a cube touching it at a vertex",
        ["planar", "touching"], 1000.0)
    # ---- identical operands
    add("box_box_identical_union", ("union", B10, B10), "a cube with itself", ["planar", "identical"], 1000.0)
    add("box_box_identical_difference", ("difference", B10, B10), "a cube minus itself: empty",
        ["planar", "identical", "empty"], 0.0)
    add("box_box_identical_intersection", ("intersection", B10, B10), "a cube and itself", ["planar", "identical"],
        1000.0)
    # ---- nested and disjoint
    small = _box(4, 4, 4)
    add("box_nested_union", ("union", B10, small), "a cube around a small cube", ["planar", "nested"], 1000.0)
    add("box_nested_difference", ("difference", B10, small), "a cube with an inner void (two shells)",
        ["planar", "nested"], 1000 - 64)
    add("box_nested_intersection", ("intersection", B10, small), "the small cube inside", ["planar", "nested"], 64.0)
    add("box_pocket", ("difference", B10, _pos(0, 0, 3, _box(4, 4, 4))), "a square pocket open at the top face",
        ["planar", "nested", "coplanar"], 1000 - 64)
    far = _pos(20, 5, -3, _box(6, 6, 6))
    add("box_disjoint_union", ("union", B10, far), "two disjoint boxes: two lumps", ["planar", "disjoint"], 1216.0)
    add("box_disjoint_difference", ("difference", B10, far), "a cube minus a far box: unchanged",
        ["planar", "disjoint"], 1000.0)
    add("box_disjoint_intersection", ("intersection", B10, far), "disjoint boxes: empty",
        ["planar", "disjoint", "empty"], 0.0)
    # ---- through holes, chains and assemblies
    add("box_through_slot", ("difference", B10, _box(4, 20, 4)), "a square tunnel through a cube (genus 1)",
        ["planar", "generic"], 1000 - 160)
    add("box_cross_union", ("union", ("union", _box(20, 4, 4), _box(4, 20, 4)), _box(4, 4, 20)),
        "three orthogonal bars", ["planar", "coplanar"], 3 * 320 - 2 * 64)
    add("box_staircase",
        ("union", ("union", _box(12, 4, 2), _pos(0, 0, 2, _box(8, 4, 2))), _pos(0, 0, 4, _box(4, 4, 2))),
        "three stacked steps sharing faces", ["planar", "touching", "coplanar"], 96 + 64 + 32)
    add("box_nested_chain", ("intersection", ("difference", B10, _pos(3, 3, 3, B10)), _pos(-2, -2, -2, B10)),
        "(A - B) & C", ["planar", "generic"])
    add("box_frame", ("difference", _box(12, 12, 4), ("union", _box(8, 8, 6), _pos(0, 0, 1, _box(16, 2, 2)))),
        "a frame with a notch: a nested Boolean whose operand is a Boolean", ["planar", "generic"])
    add("box_rotated_45_union", ("union", B10, _pos(0, 0, 5, _rot(0, 0, 45, _box(10, 10, 4)))),
        "a cube and a box turned 45° whose bottom lies in the cube's top plane", ["planar", "coplanar"])
    add("prism_l_minus_box", ("difference", ("prism", _L, 4), _pos(2, 2, 2, _box(2, 8, 2))), "an L prism with a slot",
        ["planar", "generic"])
    add("prism_triangle_and_box", ("intersection", ("prism", _TRI, 6), _rot(0, 10, 20, _box(7, 7, 7))),
        "a triangular prism and a tilted box", ["planar", "generic"])
    # ---- mesh inputs
    add("mesh_octahedron_and_box", ("intersection", ("mesh", "octahedron"), _pos(2, 2, 2, B10)),
        "an octahedron (mesh) cut by a cube", ["planar", "mesh", "generic"])
    add("mesh_icosphere_minus_box", ("difference", ("mesh", "icosphere"), _pos(4, 4, 4, B10)),
        "a faceted sphere (mesh) with a corner cut away", ["planar", "mesh", "generic"])
    add("mesh_xyz_cube_minus_box", ("difference", ("mesh", "xyz_cube"), _pos(-38, 5, -21, _box(8, 30, 8))),
        "the calibration cube with a square tunnel", ["planar", "mesh", "generic"])
    add("mesh_xyz_cube_union_box", ("union", ("mesh", "xyz_cube"), _pos(-30, 5, -21, B10)),
        "the calibration cube and a box overlapping its lettered face", ["planar", "mesh", "generic"])
    add("mesh_ring_and_box", ("union", ("mesh", "ring"), _pos(0, 0, 2, _box(4, 4, 8))),
        "a ring (genus 1) with a post through its hole, not touching", ["planar", "mesh", "disjoint"],
        432 + 128)

    # ---- curved operands (coons's curved Booleans are in progress: they raise BooleanError today)
    add("box_minus_cylinder", ("difference", B10, ("cylinder", 3, 12)), "a round through hole",
        ["curved", "generic"], 1000 - pi * 9 * 10)
    add("box_union_cylinder", ("union", B10, _pos(4, 2, 3, _rot(20, 0, 0, ("cylinder", 2, 12)))),
        "a tilted cylinder crossing a cube's faces", ["curved", "generic"])
    add("box_and_sphere", ("intersection", B10, _pos(3, 2, 1, ("sphere", 6))), "a sphere clipped by a cube",
        ["curved", "generic"])
    add("box_cylinder_tangent", ("union", B10, _pos(0, 0, 8, _rot(90, 0, 0, ("cylinder", 3, 6)))),
        "a cylinder lying on a cube's top face (tangent along a line)", ["curved", "tangent", "touching"],
        1000 + pi * 9 * 6)
    add("box_sphere_tangent", ("union", B10, _pos(0, 0, 9, ("sphere", 4))),
        "a sphere resting on a cube (tangent at a point)",
        ["curved", "tangent", "touching"], 1000 + 4 / 3 * pi * 64)
    add("cylinder_coaxial_union", ("union", ("cylinder", 3, 10), _pos(0, 0, 6, ("cylinder", 3, 10))),
        "coincident cylinders on one axis, overlapping heights", ["curved", "coplanar"], pi * 9 * 16)
    add("cylinder_coaxial_difference", ("difference", ("cylinder", 4, 10), ("cylinder", 2, 12)),
        "a tube: coaxial cylinders", ["curved", "nested"], pi * 12 * 10)
    add("cylinder_steinmetz", ("intersection", ("cylinder", 3, 12), _rot(90, 0, 0, ("cylinder", 3, 12))),
        "two perpendicular cylinders (Steinmetz solid)", ["curved", "generic"], 16 / 3 * 27)
    add("sphere_sphere_difference", ("difference", ("sphere", 5), _pos(4, 1, 2, ("sphere", 4))),
        "a sphere with a spherical bite", ["curved", "generic"])
    add("sphere_identical_union", ("union", ("sphere", 5), ("sphere", 5)), "a sphere with itself",
        ["curved", "identical"], 4 / 3 * pi * 125)
    add("torus_minus_box", ("difference", ("torus", 6, 2), _pos(6, 0, 0, _box(4, 20, 8))), "a torus cut open by a box",
        ["curved", "generic"])
    add("cone_union_cylinder", ("union", ("cone", 4, 1, 6), _pos(0, 0, 4, ("cylinder", 1, 6))),
        "a cone and a coaxial cylinder (meeting along a circle)", ["curved", "generic"])
    add("plate_union_box", ("union", ("plate", 16, 10, 2, [(-4, 0, 1.5), (4, 0, 1.5)]), _pos(0, 0, 3, _box(4, 4, 2))),
        "a boss on a plate with holes (coplanar contact)", ["curved", "touching", "coplanar"],
        (160 - 2 * pi * 2.25) * 2 + 32)
    add("box_sphere_void", ("difference", _box(12, 12, 12), ("sphere", 4)), "a cube with a spherical void",
        ["curved", "nested"], 1728 - 4 / 3 * pi * 64)
    add("box_sphere_disjoint_union", ("union", B10, _pos(15, 0, 0, ("sphere", 3))),
        "a cube and a far sphere: two lumps",
        ["curved", "disjoint"], 1000 + 4 / 3 * pi * 27)
    add("box_sphere_empty_intersection", ("intersection", B10, _pos(15, 0, 0, ("sphere", 3))),
        "a cube and a far sphere: empty", ["curved", "disjoint", "empty"], 0.0)
    return c


CATALOGUE: tuple[Case, ...] = tuple(_catalogue())
_BY_NAME = {case.name: case for case in CATALOGUE}
assert len(_BY_NAME) == len(CATALOGUE), "case names must be unique"


def default_cases() -> list[Case]:
    """The whole catalogue, in its order."""
    return list(CATALOGUE)


def select_cases(patterns: Iterable[str] | None = None, cases: Sequence[Case] | None = None) -> list[Case]:
    """The cases whose names match any of the glob ``patterns`` (all cases when none is given).

    Parameters
    ----------
    patterns : iterable of str, optional
        Names or ``fnmatch`` patterns (``"box_box_*"``, ``"*sphere*"``).
    cases : sequence of Case, optional
        The set to select from (default: :data:`CATALOGUE`).

    Returns
    -------
    list of Case
        In catalogue order, each once.

    Raises
    ------
    InvalidInputError
        A pattern that matches no case (its name and a few known names in the message).
    """
    pool = list(CATALOGUE if cases is None else cases)
    pats = list(patterns or [])
    if not pats:
        return pool
    chosen: set[str] = set()
    for p in pats:
        hits = [c.name for c in pool if fnmatch.fnmatchcase(c.name, p)]
        if not hits:
            sample = ", ".join(c.name for c in pool[:5])
            raise InvalidInputError(f"no case matches {p!r} (expected a name or glob of {len(pool)} cases: "
                                    f"{sample}, ...; see `coons validate --list`)")
        chosen.update(hits)
    return [c for c in pool if c.name in chosen]
