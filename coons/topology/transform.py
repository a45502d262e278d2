"""Placement of B-reps: 4×4 similarity matrices, their exact action on a B-rep, and build123d's ``Pos``/``Rot``.

:func:`translation`, :func:`rotation`, :func:`scaling` and :func:`reflection` return 4×4
affine matrices (column vectors: ``p' = M p + t``).  :func:`transform_brep` moves a whole
:class:`~coons.topology.brep.BRep` by a *similarity* (rotation, translation, uniform scale
``s``, reflection) exactly: vertices, 3-D curves and surfaces are mapped with their own
``transformed``, and because analytic types keep their natural parameters, every parameter
that depends on length is rescaled consistently — edge ranges of lines (``t → s t``),
p-curves on planes (``(u, v) → (s u, s v)``), on cylinders and cones (``v → s v``).  A
reflection reverses orientation: every loop is reversed (each edge's two sides swap) so the
result is again outward-oriented, revolved surfaces are rebuilt with a right-handed frame and
``u → 2π - u``, and face senses follow.  :class:`Location` (with :class:`Pos` and :class:`Rot`)
gives build123d's placement algebra, ``Pos(1, 2, 3) * Rot(0, 0, 90) * solid``.  Non-uniform
scaling and shear are deliberately not supported (circles would become ellipses and analytic
surfaces would change type): they raise.

Surface parameter maps (``T(S(u, v)) = S'(A (u, v) + b)``), derived from the ``transformed``
docstrings of :mod:`coons.kernel.analytic`::

    surface          rotation / scale s            reflection (det M < 0)
    plane            A = diag(s, s)                A = diag(s, s), normal flips (sense flips)
    cylinder, cone   A = diag(1, s)                A = diag(-1, s), b = (2π, 0)
    sphere, torus    A = I                         A = diag(-1, 1), b = (2π, 0)
    NURBS            A = I                         A = I, normal flips (sense flips)

Curve parameters: lines ``t → s t`` (``Line`` keeps a unit direction); circles, ellipses and
NURBS keep ``t``.  The face sense flips exactly when ``sign(det A) · sign(det M) < 0``: the
loops are reversed when ``det M < 0`` and mapped by ``A`` into the new parameter plane, so a
counter-clockwise loop stays counter-clockwise relative to the new ``Su × Sv`` iff the sense is
updated that way (``docs/brep.md``, Orientation).
"""

from __future__ import annotations

import dataclasses
import math
from numbers import Real
from typing import Any

import numpy as np

from coons.errors import InvalidInputError
from coons.kernel._common import as_transform, similarity_parts
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
from coons.kernel.surface import NurbsSurface
from coons.tolerance import Tolerance, resolve
from coons.topology.brep import BRep
from coons.topology.shape import Solid

__all__ = [
    "translation",
    "rotation",
    "scaling",
    "reflection",
    "transform_brep",
    "similarity_scale",
    "Location",
    "Pos",
    "Rot",
]

TWO_PI = 2.0 * math.pi


# ============================================================================ small helpers
def _vec3(value: Any, name: str) -> np.ndarray:
    try:
        v = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise InvalidInputError(f"{name} must be 3 finite numbers, got {value!r}") from None
    if v.shape != (3,) or not np.all(np.isfinite(v)):
        raise InvalidInputError(f"{name} must be 3 finite numbers, got {value!r}")
    return v


def _unit3(value: Any, name: str) -> np.ndarray:
    v = _vec3(value, name)
    n = float(np.linalg.norm(v))
    if n == 0.0:
        raise InvalidInputError(f"{name} must be non-zero, got {value!r}")
    return v / n


def _number(value: Any, name: str) -> float:
    numeric = not isinstance(value, bool) and isinstance(value, (Real, np.floating, np.integer))
    if not numeric or not math.isfinite(float(value)):
        raise InvalidInputError(f"{name} must be a finite number, got {value!r}")
    return float(value)


def _cos_sin_degrees(degrees: float) -> tuple[float, float]:
    """``(cos, sin)`` of an angle in degrees, exact at multiples of 90° (so quarter turns keep
    integer coordinates integer instead of leaving 6e-17 residues)."""
    r = math.fmod(degrees, 360.0)
    quarter = r / 90.0
    if quarter == int(quarter):
        return ((1.0, 0.0), (0.0, 1.0), (-1.0, 0.0), (0.0, -1.0))[int(quarter) % 4]
    a = math.radians(r)
    return math.cos(a), math.sin(a)


def _axis_rotation(axis: np.ndarray, degrees: float) -> np.ndarray:
    """Rodrigues' rotation ``cos θ I + sin θ [k]× + (1 - cos θ) k kᵀ`` about a unit axis (right-hand rule)."""
    c, s = _cos_sin_degrees(degrees)
    k = axis
    K = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
    R = c * np.eye(3) + s * K + (1.0 - c) * np.outer(k, k)
    # Exact cos/sin and a coordinate axis give an exact matrix; keep it free of -0.0 noise.
    return R + 0.0


def _affine(M: np.ndarray, t: np.ndarray) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3] = M
    T[:3, 3] = t
    return T


# ============================================================================ matrices
def translation(offset) -> np.ndarray:
    """The translation by ``offset``, ``(4, 4)``.

    Raises
    ------
    InvalidInputError
        ``offset`` is not 3 finite numbers.
    """
    return _affine(np.eye(3), _vec3(offset, "offset"))


def rotation(origin, direction, degrees: float) -> np.ndarray:
    """The rotation by ``degrees`` about the axis through ``origin`` along ``direction``, ``(4, 4)``.

    Positive angles turn counter-clockwise seen from the tip of ``direction`` (right-hand
    rule); Rodrigues' formula, exact at multiples of 90°.

    Raises
    ------
    InvalidInputError
        Non-finite or wrongly shaped inputs, a zero direction.
    """
    o = _vec3(origin, "origin")
    R = _axis_rotation(_unit3(direction, "direction"), _number(degrees, "degrees"))
    return _affine(R, o - R @ o)


def scaling(factor: float, origin=(0.0, 0.0, 0.0)) -> np.ndarray:
    """The uniform scaling by ``factor`` about ``origin``, ``(4, 4)``.

    Raises
    ------
    InvalidInputError
        ``factor`` not a finite number > 0 (a negative factor is a point reflection: use
        :func:`reflection` and :func:`rotation`), or a bad origin.
    """
    f = _number(factor, "factor")
    if not f > 0.0:
        raise InvalidInputError(f"scaling factor must be > 0, got {factor!r}")
    o = _vec3(origin, "origin")
    return _affine(f * np.eye(3), o - f * o)


def reflection(origin, normal) -> np.ndarray:
    """The mirror in the plane through ``origin`` with ``normal`` (Householder ``I - 2 n nᵀ``), ``(4, 4)``.

    Raises
    ------
    InvalidInputError
        Non-finite or wrongly shaped inputs, a zero normal.
    """
    o = _vec3(origin, "origin")
    n = _unit3(normal, "normal")
    H = np.eye(3) - 2.0 * np.outer(n, n)
    return _affine(H, 2.0 * np.dot(n, o) * n)


def similarity_scale(matrix, tol: Tolerance | None = None) -> tuple[np.ndarray, float, bool]:
    """Split a similarity ``T = [s Q | t]`` (``Q`` orthogonal): ``(T as 4×4, s, det Q < 0)``.

    See :func:`coons.kernel._common.similarity_parts`.

    Raises
    ------
    InvalidInputError
        A matrix that is not a similarity within ``tol.angular``.
    """
    return similarity_parts(matrix, resolve(tol).angular)


# ============================================================================ geometry images
def _curve_image(curve: Any, T: np.ndarray, s: float, tol: Tolerance) -> tuple[Any, float]:
    """``(image, k)`` with ``T(curve(t)) = image(k t)``.

    Raises
    ------
    InvalidInputError
        A curve type whose parameter behaviour under similarities is unknown.
    """
    if isinstance(curve, Line):
        return curve.transformed(T), s  # unit direction: t scales with lengths
    if isinstance(curve, (Circle, Ellipse)):
        return curve.transformed(T, tol), 1.0
    if isinstance(curve, NurbsCurve):
        return curve.transformed(T), 1.0
    raise InvalidInputError(f"transform_brep: cannot transform a 3-D curve of type {type(curve).__name__}")


def _surface_image(
    surface: Any, T: np.ndarray, s: float, reflects: bool, tol: Tolerance
) -> tuple[Any, np.ndarray, np.ndarray]:
    """``(image, A, b)`` with ``T(S(u, v)) = image(A (u, v) + b)``.

    Reflections of revolved surfaces are rebuilt with the right-handed frame ``X' = Q X``,
    ``Z' = Q Z`` (so ``Y' = -Q Y``): then ``Q e(u) = e'(-u)`` and the parameter map is
    ``u' = 2π - u`` (kept in ``[0, 2π]`` for faces within one turn).

    Raises
    ------
    InvalidInputError
        A surface type whose parameter behaviour under similarities is unknown.
    """
    I = np.eye(2)
    zero = np.zeros(2)
    if isinstance(surface, PlanarSurface):
        return surface.transformed(T, tol), s * I, zero
    if isinstance(surface, NurbsSurface):
        return surface.transformed(T), I, zero
    revolved = (CylindricalSurface, ConicalSurface, SphericalSurface, ToroidalSurface)
    if not isinstance(surface, revolved):
        raise InvalidInputError(f"transform_brep: cannot transform a surface of type {type(surface).__name__}")
    linear_v = isinstance(surface, (CylindricalSurface, ConicalSurface))
    v_scale = s if linear_v else 1.0
    if not reflects:
        return surface.transformed(T, tol), np.diag([1.0, v_scale]), zero
    M = T[:3, :3]
    X, _, Z = surface.frame
    centre = surface.center if isinstance(surface, (SphericalSurface, ToroidalSurface)) else surface.origin
    O = M @ centre + T[:3, 3]
    Xn, Zn = M @ X / s, M @ Z / s
    if isinstance(surface, CylindricalSurface):
        image = CylindricalSurface(O, Zn, Xn, surface.radius * s)
    elif isinstance(surface, ConicalSurface):
        image = ConicalSurface(O, Zn, Xn, surface.radius * s, surface.semi_angle)
    elif isinstance(surface, SphericalSurface):
        image = SphericalSurface(O, Zn, Xn, surface.radius * s)
    else:
        image = ToroidalSurface(O, Zn, Xn, surface.major_radius * s, surface.minor_radius * s)
    return image, np.diag([-1.0, v_scale]), np.array([TWO_PI, 0.0])


def _pcurve_image(pc: Any, A: np.ndarray, b: np.ndarray, k: float) -> Any:
    """The p-curve ``t' -> A pc(t' / k) + b`` (new surface parameters, new edge parameter ``t' = k t``).

    Raises
    ------
    InvalidInputError
        A ``Trig2D`` on an edge whose parameter scales (not representable), or an unknown type.
    """
    if k == 1.0 and np.array_equal(A, np.eye(2)) and not np.any(b):
        return pc
    if isinstance(pc, Line2D):
        return Line2D(A @ pc.origin + b, (A @ pc.direction) / k)
    if isinstance(pc, Trig2D):
        if k != 1.0:
            raise InvalidInputError(
                f"transform_brep: a Trig2D p-curve lies on an edge whose parameter scales by {k:g}; expected 1"
            )
        return Trig2D(A @ pc.center + b, A @ pc.a, A @ pc.b)
    if isinstance(pc, NurbsCurve) and pc.dimension == 2:
        return NurbsCurve(pc.control_points @ A.T + b, pc.knots * k, pc.degree, pc.weights)
    raise InvalidInputError(f"transform_brep: cannot transform a p-curve of type {type(pc).__name__}")


# ============================================================================ B-rep
def transform_brep(brep: BRep, matrix, tol: Tolerance | None = None) -> BRep:
    """The image of a B-rep under a similarity, with the same topology (entity ``i`` maps to ``i``).

    Parameters
    ----------
    brep : BRep
    matrix : (4, 4) or (3, 3) array_like
        A similarity: rotation, translation, uniform scale, reflection (any combination).
    tol : Tolerance, optional
        ``tol.angular`` bounds how far ``matrix`` may be from a similarity.

    Returns
    -------
    BRep
        Vertices, curves and surfaces moved; line edge ranges and p-curves reparametrised
        (see the module docstring); vertex and edge tolerances times ``s``; for reflections
        every loop reversed and face senses updated, so outer shells still enclose positive
        volume.  The result is not re-checked (call :func:`coons.topology.check.check`).

    Raises
    ------
    InvalidInputError
        ``brep`` is not a BRep; the matrix is malformed or not a similarity; geometry of a
        type this function cannot map.
    """
    if not isinstance(brep, BRep):
        raise InvalidInputError(f"transform_brep needs a BRep, got {type(brep).__name__}")
    t = resolve(tol)
    T, s, reflects = similarity_scale(matrix, t)
    M, off = T[:3, :3], T[:3, 3]

    curves, k_curve = [], np.ones(len(brep.curves))
    for i, c in enumerate(brep.curves):
        image, k_curve[i] = _curve_image(c, T, s, t)
        curves.append(image)
    k_edge = np.where(brep.edge_curve >= 0, k_curve[np.maximum(brep.edge_curve, 0)] if len(curves) else 1.0, 1.0)

    surfaces, maps = [], []
    for S in brep.surfaces:
        image, A, b = _surface_image(S, T, s, reflects, t)
        surfaces.append(image)
        maps.append((A, b))

    # P-curves: one image per (p-curve, surface, edge scale); shared objects stay shared.
    pcurves: list[Any] = []
    cache: dict[tuple[int, int, float], int] = {}
    new_pc = np.full(brep.edge_pcurve.shape, -1, dtype=np.int64)
    face_of = brep.edge_face
    for e, side in zip(*np.nonzero(brep.edge_pcurve >= 0)):
        p = int(brep.edge_pcurve[e, side])
        si = int(brep.face_surface[face_of[e, side]])
        k = float(k_edge[e])
        key = (p, si, k)
        if key not in cache:
            A, b = maps[si] if si >= 0 else (s * np.eye(2), np.zeros(2))
            pcurves.append(_pcurve_image(brep.pcurves[p], A, b, k))
            cache[key] = len(pcurves) - 1
        new_pc[e, side] = cache[key]

    sense = brep.face_sense.copy()
    if len(surfaces):
        has = brep.face_surface >= 0
        flip = np.array([(np.linalg.det(A) < 0) != reflects for A, _ in maps], dtype=bool)
        sense[has] ^= flip[brep.face_surface[has]]

    changes: dict[str, Any] = dict(
        vertex_point=brep.vertex_point @ M.T + off,
        vertex_tol=brep.vertex_tol * s,
        edge_range=brep.edge_range * k_edge[:, None],
        edge_pcurve=new_pc,
        edge_tol=brep.edge_tol * s,
        face_sense=sense,
        surfaces=tuple(surfaces),
        curves=tuple(curves),
        pcurves=tuple(pcurves),
    )
    if reflects:
        changes.update(_reversed_loops(brep))
        changes["edge_pcurve"] = new_pc[:, ::-1]
    return dataclasses.replace(brep, **changes)


def _reversed_loops(brep: BRep) -> dict[str, np.ndarray]:
    """Tables with every loop traversed backwards: each edge keeps its vertices, its sides swap.

    The coedge that runs along edge ``e`` in loop ``L`` changes side (``c -> c ^ 1``); in the
    reversed cycle ``next`` and ``prev`` swap: ``next'(c ^ 1) = prev(c) ^ 1``.
    """
    nc = 2 * brep.n_edges
    twin = np.arange(nc) ^ 1
    nxt = brep.coedge_prev[twin] ^ 1
    prv = brep.coedge_next[twin] ^ 1
    loop = brep.coedge_loop[twin]
    wing = np.stack([prv[0::2], nxt[0::2], prv[1::2], nxt[1::2]], axis=1) if nc else np.zeros((0, 4), np.int64)
    first = brep.loop_coedge
    return {
        "edge_loop": loop.reshape(-1, 2),
        "edge_wing": wing,
        "loop_coedge": np.where(first >= 0, first ^ 1, first),
    }


# ============================================================================ placement algebra
class Location:
    """A placement: a 4×4 similarity applied with ``*`` (build123d's ``Location``).

    ``Location * Location`` composes (the right one applies first), ``Location * Solid`` and
    ``Location * BRep`` move the shape.

    Parameters
    ----------
    matrix : (4, 4) array_like, optional (identity)

    Raises
    ------
    InvalidInputError
        A malformed or non-affine matrix.
    """

    __slots__ = ("_matrix",)

    def __init__(self, matrix=None) -> None:
        T = np.eye(4) if matrix is None else as_transform(matrix).copy()
        T.setflags(write=False)
        self._matrix = T

    @property
    def matrix(self) -> np.ndarray:
        """``(4, 4)`` read-only."""
        return self._matrix

    @property
    def position(self) -> np.ndarray:
        """Where the origin goes, ``(3,)``."""
        return self._matrix[:3, 3].copy()

    def inverse(self) -> "Location":
        return Location(np.linalg.inv(self._matrix))

    def is_close(self, other: "Location", tol: Tolerance | None = None) -> bool:
        """Same placement: linear parts within ``tol.angular``, translations within ``tol.linear``."""
        t = resolve(tol)
        d = self._matrix - other.matrix
        return bool(np.max(np.abs(d[:3, :3])) <= t.angular and np.max(np.abs(d[:3, 3])) <= t.linear)

    def __mul__(self, other: Any):
        if isinstance(other, Location):
            return Location(self._matrix @ other.matrix)
        if isinstance(other, BRep):
            return transform_brep(other, self._matrix)
        if isinstance(other, Solid):
            return other.transformed(self._matrix)
        return NotImplemented

    def __repr__(self) -> str:
        return f"{type(self).__name__}({self._matrix[:3].round(12).tolist()})"


def _three(args: tuple, kwargs: dict, what: str) -> np.ndarray:
    """``(x, y, z)`` from ``(x, y, z)``, ``((x, y, z),)`` or keywords ``x=, y=, z=``."""
    unknown = set(kwargs) - {"x", "y", "z"}
    if unknown:
        raise InvalidInputError(f"{what}: unexpected keyword(s) {sorted(unknown)}; use x, y, z")
    if len(args) == 1 and not isinstance(args[0], (Real, np.floating, np.integer)) and not kwargs:
        return _vec3(args[0], what)
    if len(args) > 3:
        raise InvalidInputError(f"{what}: expected at most 3 numbers, got {len(args)}")
    vals = list(args) + [0.0] * (3 - len(args))
    for i, name in enumerate("xyz"):
        if name in kwargs:
            if i < len(args):
                raise InvalidInputError(f"{what}: {name} given twice")
            vals[i] = kwargs[name]
    return np.array([_number(v, f"{what} {n}") for v, n in zip(vals, "xyz")])


class Pos(Location):
    """The translation to ``(x, y, z)`` (build123d's ``Pos``): ``Pos(1, 2, 3)``, ``Pos((1, 2, 3))``, ``Pos(z=5)``.

    Raises
    ------
    InvalidInputError
        Non-finite or too many values, unknown keywords.
    """

    __slots__ = ()

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(translation(_three(args, kwargs, "Pos")))


class Rot(Location):
    """The rotation by Euler angles in degrees (build123d's ``Rot``, ordering ``Intrinsic.XYZ``).

    About ``x``, then about the rotated ``y``, then about the twice-rotated ``z``:
    ``R = Rx(x) Ry(y) Rz(z)`` acting on column vectors (the same matrix as extrinsic
    rotations about the fixed ``z``, then ``y``, then ``x``).  ``Rot(0, 0, 90)``,
    ``Rot((0, 0, 90))``, ``Rot(z=90)``.

    Raises
    ------
    InvalidInputError
        Non-finite or too many values, unknown keywords.
    """

    __slots__ = ()

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        ax, ay, az = _three(args, kwargs, "Rot")
        X, Y, Z = np.eye(3)
        R = _axis_rotation(X, ax) @ _axis_rotation(Y, ay) @ _axis_rotation(Z, az)
        super().__init__(_affine(R, np.zeros(3)))
