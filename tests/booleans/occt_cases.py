"""Seeded pairs of placed primitives for comparing coons's curved Booleans with OCCT's.

Each :class:`Pair` is two primitives of coons (box, cylinder, cone or frustum, sphere, torus) with
their sizes and a 4×4 placement (a random rotation from ``scipy.spatial.transform.Rotation`` and a
translation), drawn from a ``numpy.random.default_rng`` seeded by the pair's index, so a pair is
reproduced from its name alone (``pair("cyl-sph-0").operands()``).  Draws whose bounding boxes do
not overlap, or where one box contains the other, are rejected and redrawn: every kept pair
really intersects.  A few nested and disjoint pairs are added on purpose.  The module does not
run any Boolean and imports no reference engine: the same operands go to OCCT through
:func:`coons.io.ocp.to_build123d` (exact geometry, no second placement to get wrong).

``DEFAULT_PAIRS`` (one pair per unordered kind combination, 15, plus nested and disjoint) is
the fast set; ``EXTENDED_PAIRS`` adds more draws per combination for ``pytest -m slow``.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import numpy as np

from coons.topology.primitives import Box, Cone, Cylinder, Sphere, Torus
from coons.topology.shape import Solid

__all__ = ["KINDS", "Pair", "pair", "DEFAULT_PAIRS", "EXTENDED_PAIRS", "OPS"]

KINDS = ("box", "cyl", "cone", "sph", "tor")
OPS = ("union", "intersection", "difference")
#: Largest number of redraws of one pair before giving up (a bug in the generator, not in coons).
_MAX_DRAWS = 200


def _sizes(kind: str, rng: np.random.Generator) -> tuple[float, ...]:
    """Primitive sizes of about 3..8 model units (so that pairs overlap for offsets of 0.5..3)."""
    if kind == "box":
        return tuple(float(x) for x in rng.uniform(3.0, 7.0, 3))
    if kind == "cyl":
        return (float(rng.uniform(1.5, 3.0)), float(rng.uniform(4.0, 8.0)))
    if kind == "cone":
        r0 = float(rng.uniform(1.5, 3.0))
        # One cone in three is pointed (an apex vertex), the others frustums.
        r1 = 0.0 if rng.random() < 1.0 / 3.0 else float(rng.uniform(0.5, r0 - 0.5))
        return (r0, r1, float(rng.uniform(4.0, 8.0)))
    if kind == "sph":
        return (float(rng.uniform(2.0, 3.5)),)
    if kind == "tor":
        return (float(rng.uniform(2.5, 3.5)), float(rng.uniform(0.7, 1.2)))
    raise ValueError(f"unknown kind {kind!r}, expected one of {KINDS}")


def build_primitive(kind: str, sizes: tuple[float, ...]) -> Solid:
    """The coons primitive (centred on the origin, axis +z) of ``kind`` with ``sizes``."""
    if kind == "box":
        return Box(*sizes)
    if kind == "cyl":
        return Cylinder(*sizes)
    if kind == "cone":
        return Cone(*sizes)
    if kind == "sph":
        return Sphere(*sizes)
    if kind == "tor":
        return Torus(*sizes)
    raise ValueError(f"unknown kind {kind!r}, expected one of {KINDS}")


def _placement(rng: np.random.Generator, centre: np.ndarray) -> np.ndarray:
    from scipy.spatial.transform import Rotation

    m = np.eye(4)
    m[:3, :3] = Rotation.random(random_state=rng).as_matrix()
    m[:3, 3] = centre
    return m


@dataclass(frozen=True)
class Pair:
    """Two placed primitives.  ``matrix_*`` are 4×4 rigid motions applied to the centred primitive."""

    name: str
    kind_a: str
    sizes_a: tuple[float, ...]
    matrix_a: tuple[tuple[float, ...], ...]
    kind_b: str
    sizes_b: tuple[float, ...]
    matrix_b: tuple[tuple[float, ...], ...]
    relation: str = "overlap"  # "overlap", "nested" (B inside A) or "disjoint"

    def operands(self) -> tuple[Solid, Solid]:
        """The two coons solids."""
        a = build_primitive(self.kind_a, self.sizes_a).transformed(np.array(self.matrix_a))
        b = build_primitive(self.kind_b, self.sizes_b).transformed(np.array(self.matrix_b))
        return a, b

    def recipe(self) -> str:
        """A reproducer in Python (coons names), for failure reports."""
        np_a = np.array2string(np.array(self.matrix_a), separator=", ", precision=17, max_line_width=200)
        np_b = np.array2string(np.array(self.matrix_b), separator=", ", precision=17, max_line_width=200)
        return (f"a = build_primitive({self.kind_a!r}, {self.sizes_a!r}).transformed(np.array({np_a}))\n"
                f"b = build_primitive({self.kind_b!r}, {self.sizes_b!r}).transformed(np.array({np_b}))")


def _as_tuple(m: np.ndarray) -> tuple[tuple[float, ...], ...]:
    return tuple(tuple(float(x) for x in row) for row in m)


def _boxes_relation(a: Solid, b: Solid) -> str:
    ba, bb = a.bounding_box(), b.bounding_box()
    if np.any(ba[1] < bb[0]) or np.any(bb[1] < ba[0]):
        return "disjoint"
    a_in_b = np.all(ba[0] >= bb[0]) and np.all(ba[1] <= bb[1])
    b_in_a = np.all(bb[0] >= ba[0]) and np.all(bb[1] <= ba[1])
    return "nested" if a_in_b or b_in_a else "overlap"


def draw_pair(kind_a: str, kind_b: str, index: int, seed: int = 2026) -> Pair:
    """The ``index``-th overlapping pair of ``kind_a`` and ``kind_b`` (seeded, reproducible).

    A is centred in ``[-1, 1]³``, B at an offset of length ``0.5..3`` in a random direction; both
    get a random rotation.  Draws whose bounding boxes do not overlap or nest are redrawn.
    """
    key = (KINDS.index(kind_a), KINDS.index(kind_b), index)
    rng = np.random.default_rng([seed, *key])
    for _ in range(_MAX_DRAWS):
        sa, sb = _sizes(kind_a, rng), _sizes(kind_b, rng)
        ca = rng.uniform(-1.0, 1.0, 3)
        d = rng.normal(size=3)
        cb = ca + rng.uniform(0.5, 3.0) * d / np.linalg.norm(d)
        ma, mb = _placement(rng, ca), _placement(rng, cb)
        p = Pair(f"{kind_a}-{kind_b}-{index}", kind_a, sa, _as_tuple(ma), kind_b, sb, _as_tuple(mb))
        if _boxes_relation(*p.operands()) == "overlap":
            return p
    raise RuntimeError(f"no overlapping draw of {kind_a}/{kind_b} #{index} in {_MAX_DRAWS} tries")


def _special_pairs() -> list[Pair]:
    """Nested (a small sphere and a small tilted cylinder inside a box) and disjoint pairs, on purpose."""
    rng = np.random.default_rng([2026, 99])
    box = (8.0, 7.0, 6.0)
    out = [
        Pair("box-sph-nested", "box", box, _as_tuple(_placement(rng, np.array([0.3, -0.2, 0.1]))),
             "sph", (1.5,), _as_tuple(_placement(rng, np.array([0.5, 0.2, -0.1]))), "nested"),
        Pair("box-cyl-nested", "box", box, _as_tuple(np.eye(4)),
             "cyl", (1.0, 2.5), _as_tuple(_placement(rng, np.array([-0.5, 0.5, 0.2]))), "nested"),
        Pair("sph-tor-disjoint", "sph", (2.0,), _as_tuple(_placement(rng, np.array([0.0, 0.0, 0.0]))),
             "tor", (3.0, 1.0), _as_tuple(_placement(rng, np.array([9.0, 1.0, -1.0]))), "disjoint"),
    ]
    for p in out:
        got = _boxes_relation(*p.operands())
        if (p.relation == "disjoint") != (got == "disjoint"):
            raise RuntimeError(f"special pair {p.name}: expected {p.relation}, the boxes are {got}")
    return out


def _combinations() -> list[tuple[str, str]]:
    return list(itertools.combinations_with_replacement(KINDS, 2))


DEFAULT_PAIRS: list[Pair] = [draw_pair(a, b, 0) for a, b in _combinations()] + _special_pairs()
EXTENDED_PAIRS: list[Pair] = [draw_pair(a, b, i) for i in (1, 2) for a, b in _combinations()]
_BY_NAME = {p.name: p for p in DEFAULT_PAIRS + EXTENDED_PAIRS}


def pair(name: str) -> Pair:
    """The pair called ``name`` (``"cyl-sph-0"``) from either set."""
    try:
        return _BY_NAME[name]
    except KeyError:
        raise KeyError(f"no pair {name!r}; known: {sorted(_BY_NAME)}") from None
