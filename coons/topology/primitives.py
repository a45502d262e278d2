"""Exact primitive solids: box, cylinder, cone, sphere and torus as checked winged-edge B-reps.

Each primitive's topology is made with the Euler operators of
:class:`~coons.topology.builder.BRepBuilder` (``mvfs``, ``mev``, ``mef``, ``sweep_loop``,
``kfmrh``, ``mekr``; Mäntylä, *An Introduction to Solid Modeling*, ch. 9–10, builds the
block, the cylinder and the torus the same way), then the exact geometry is attached: analytic
surfaces of :mod:`coons.kernel.analytic` in OCCT's parametrisation, analytic 3-D edge curves
(``Line``, ``Circle``) and same-parameter p-curves (``Line2D``, ``Trig2D``) on both faces of
every edge.  ``build()`` then runs :func:`coons.topology.check.check`, so every primitive is
returned valid or not at all.  The module does not make partial primitives (wedges, arcs of
revolution, hollow cylinders) or NURBS approximations, and it never tessellates.

Following ``docs/brep.md`` there are no seam or degenerate edges: closed surfaces are split
into faces that span half a turn (the side of a cylinder or cone: two half-cylinders
``u ∈ [0, π]`` and ``[π, 2π]``; a sphere: two hemispheres; a torus: four quarters split at
``u, v ∈ {0, π}``), and a cone's apex and a sphere's poles are vertices where the p-curve loop
jumps along the collapsed side of the parameter rectangle.  All faces have ``sense = True``
(outward normal ``= Su × Sv``), hence counter-clockwise loops in their parameter planes.

Counts (coons / OCCT, the OCCT figures including seams and degenerate edges)::

    Box       V 8  E 12  F 6      OCCT  8 / 12 / 6
    Cylinder  V 4  E 6   F 4      OCCT  2 / 3  / 3   (a seam)
    Cone      V 4  E 6   F 4      OCCT  2 / 3  / 3   (frustum; a seam)
    Cone      V 3  E 4   F 3      OCCT  2 / 3  / 2   (one radius 0; a seam, a degenerate edge)
    Sphere    V 2  E 2   F 2      OCCT  2 / 3  / 1   (a seam, two degenerate edges)
    Torus     V 4  E 8   F 4      OCCT  1 / 2  / 1   (two seams; genus 1: V - E + F = 0)

Placement follows build123d: ``align=(ax, ay, az)`` with ``"min"``, ``"center"`` or
``"max"`` per axis puts the minimum, centre or maximum of the exact bounding box at the
origin (default: centred); ``align=None`` keeps OCCT's ``BRepPrimAPI`` placement (the box's
minimum corner, the centre of the cylinder's or cone's base, the centre of the sphere or torus
at the origin).  Cylinders and cones take the direction of their axis.
"""

from __future__ import annotations

import math
from numbers import Real
from typing import Any, Sequence

import numpy as np

from coons.errors import InvalidInputError, TopologyError
from coons.kernel.analytic import (
    Circle,
    ConicalSurface,
    CylindricalSurface,
    Line,
    PlanarSurface,
    SphericalSurface,
    ToroidalSurface,
)
from coons.kernel.pcurve import Line2D, Trig2D
from coons.tolerance import Tolerance, resolve
from coons.topology.builder import BRepBuilder
from coons.topology.shape import Solid

__all__ = ["Box", "Cylinder", "Cone", "Sphere", "Torus"]

PI = math.pi
TWO_PI = 2.0 * math.pi
HALF_PI = 0.5 * math.pi
_ALIGN_NAMES = ("min", "center", "max")
_CENTER = ("center", "center", "center")
_E = np.eye(3)

#: ``u = t, v = 0``: a circle edge at the bottom of a side face (u = the circle angle).
_U_AXIS = np.array([1.0, 0.0])
#: ``u = const, v = t``: a ruling, meridian or v-circle.
_V_AXIS = np.array([0.0, 1.0])


# ============================================================================ input checks
def _positive(value: Any, name: str, tol: Tolerance) -> float:
    """``value`` as a finite float above ``tol.linear`` (smaller sizes put vertices within tolerance).

    Raises
    ------
    InvalidInputError
        Not a real number, NaN, infinite, zero, negative or not above the linear tolerance.
    """
    if isinstance(value, bool) or not isinstance(value, (Real, np.floating, np.integer)):
        raise InvalidInputError(f"{name} must be a finite number > 0, got {value!r} ({type(value).__name__})")
    x = float(value)
    if not (math.isfinite(x) and x > 0.0):
        raise InvalidInputError(f"{name} must be a finite number > 0, got {value!r}")
    _above_tolerance(x, name, tol)
    return x


def _above_tolerance(x: float, name: str, tol: Tolerance) -> None:
    if not x > tol.linear:
        raise InvalidInputError(
            f"{name} must be larger than the linear tolerance {tol.linear:g} (or the shape degenerates), got {x!r}"
        )


def _non_negative(value: Any, name: str, tol: Tolerance) -> float:
    """``value`` as a finite float that is 0 (a cone's apex) or above ``tol.linear``.

    Raises
    ------
    InvalidInputError
        Not a real number, NaN, infinite, negative, or in ``(0, tol.linear]``.
    """
    if isinstance(value, bool) or not isinstance(value, (Real, np.floating, np.integer)):
        raise InvalidInputError(f"{name} must be a finite number >= 0, got {value!r} ({type(value).__name__})")
    x = float(value)
    if not (math.isfinite(x) and x >= 0.0):
        raise InvalidInputError(f"{name} must be a finite number >= 0, got {value!r}")
    if x > 0.0:
        _above_tolerance(x, name, tol)
    return x


def _alignment(align: Any) -> tuple[str, str, str] | None:
    """Normalise ``align``: None, one name for all axes, or three names (``"min"|"center"|"max"``).

    Objects with a ``name`` attribute (build123d's ``Align.MIN`` ...) are read by that name.

    Raises
    ------
    InvalidInputError
        Anything else, naming the offending entry.
    """
    if align is None:
        return None

    def one(a: Any, where: str) -> str:
        name = getattr(a, "name", a)
        if isinstance(name, str) and name.lower() in _ALIGN_NAMES:
            return name.lower()
        raise InvalidInputError(f"align{where} must be one of 'min', 'center', 'max', got {a!r}")

    if isinstance(align, str) or hasattr(align, "name"):
        a = one(align, "")
        return (a, a, a)
    try:
        items = list(align)
    except TypeError:
        raise InvalidInputError(
            f"align must be None, a name or 3 names ('min', 'center', 'max'), got {align!r}"
        ) from None
    if len(items) != 3:
        raise InvalidInputError(f"align needs one entry per axis (3), got {len(items)}: {align!r}")
    return tuple(one(a, f"[{i}]") for i, a in enumerate(items))  # type: ignore[return-value]


def _direction(direction: Any) -> np.ndarray:
    """A non-zero finite 3-vector, normalised.

    Raises
    ------
    InvalidInputError
        Wrong shape, NaN/inf or zero length.
    """
    try:
        d = np.asarray(direction, dtype=np.float64)
    except (TypeError, ValueError):
        raise InvalidInputError(f"direction must be 3 finite numbers, got {direction!r}") from None
    if d.shape != (3,) or not np.all(np.isfinite(d)):
        raise InvalidInputError(f"direction must be 3 finite numbers, got {direction!r}")
    n = float(np.linalg.norm(d))
    if n == 0.0:
        raise InvalidInputError(f"direction must be non-zero, got {direction!r}")
    return d / n


def _frame(z: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Right-handed orthonormal ``(X, Y, Z)`` with ``Z = z``; ``X`` is the world axis least aligned
    with ``z`` made perpendicular to it (so ``z = +Z`` gives the world frame)."""
    k = int(np.argmin(np.abs(z)))  # first of equals: x before y before z
    x = _E[k] - np.dot(_E[k], z) * z
    x /= np.linalg.norm(x)
    return x, np.cross(z, x), z


def _align_offset(box: np.ndarray, align: tuple[str, str, str] | None) -> np.ndarray:
    """Translation that puts the bounding box ``(2, 3)`` where ``align`` says, ``(3,)``."""
    if align is None:
        return np.zeros(3)
    pick = {"min": box[0], "center": 0.5 * (box[0] + box[1]), "max": box[1]}
    return -np.array([pick[a][i] for i, a in enumerate(align)])


def _circle_box(center: np.ndarray, radius: float, axis: np.ndarray) -> np.ndarray:
    """Exact bounding box ``(2, 3)`` of a circle: half-extent ``r sqrt(1 - axis_i²)`` per axis.

    Written as ``r sqrt(axis_j² + axis_k²)``, which keeps full precision when the axis is
    nearly along a coordinate axis (``1 - axis_i²`` cancels there).
    """
    a2 = axis * axis
    h = radius * np.sqrt(a2.sum() - a2)
    return np.stack([center - h, center + h])


def _union_box(*boxes: np.ndarray) -> np.ndarray:
    b = np.stack(boxes)
    return np.stack([b[:, 0].min(axis=0), b[:, 1].max(axis=0)])


# ============================================================================ geometry helpers
def _face_of(b: BRepBuilder, coedge: int) -> int:
    return b.lface[b.cloop[coedge]]


def _attach_edge(b: BRepBuilder, edge: int, curve: Any, t_range: tuple[float, float], pcurves: dict[int, Any]) -> None:
    """Attach the 3-D curve and, on each side, the p-curve given for that side's face.

    Raises
    ------
    TopologyError
        A side lies in a face with no p-curve given (the Euler construction differs from the plan).
    """
    b.set_edge_curve(edge, curve, t_range)
    for side in (0, 1):
        f = _face_of(b, 2 * edge + side)
        if f not in pcurves:
            raise TopologyError(
                f"internal: edge {edge} side {side} lies in face {f}, expected one of {sorted(pcurves)}"
            )
        b.set_pcurve(2 * edge + side, pcurves[f])


def _line_on_plane(plane: PlanarSurface, line: Line) -> Line2D:
    """The p-curve of a line lying in a plane, same parameter: ``uv(t) = uv(O) + t (D·X, D·Y)``."""
    X, Y, _ = plane.frame
    return Line2D(plane.closest_parameters(line.origin), [np.dot(line.direction, X), np.dot(line.direction, Y)])


def _circle_on_plane(plane: PlanarSurface, circle: Circle) -> Trig2D:
    """The p-curve of a circle lying in a plane, same parameter.

    ``uv(t) = uv(C) + cos t R (X_c)_uv + sin t R (Y_c)_uv``, ``(·)_uv`` the plane coordinates.
    """
    X, Y, _ = plane.frame
    Xc, Yc, _ = circle.frame
    R = circle.radius
    return Trig2D(
        plane.closest_parameters(circle.center),
        [R * np.dot(Xc, X), R * np.dot(Xc, Y)],
        [R * np.dot(Yc, X), R * np.dot(Yc, Y)],
    )


# ============================================================================ Box
def Box(length: float, width: float, height: float, *, align: Any = _CENTER, tol: Tolerance | None = None) -> Solid:
    """An axis-parallel box of ``length × width × height`` (x, y, z).

    Six :class:`PlanarSurface` faces whose normals point outward (``sense = True``), twelve
    :class:`Line` edges parametrised by arc length from their start vertex (range
    ``[0, edge length]``) with :class:`Line2D` p-curves on both faces, eight vertices.  Built
    as Mäntylä's block: a square lamina (``mvfs``, three ``mev``, ``mef``) swept up
    (``sweep_loop``).

    Parameters
    ----------
    length, width, height : float > 0
    align : None, str or 3 of ``"min"``, ``"center"``, ``"max"``
        Per axis, which part of the box sits at the origin (build123d's ``Align``); None puts
        the minimum corner at the origin (OCCT's ``BRepPrimAPI_MakeBox``).
    tol : Tolerance, optional

    Returns
    -------
    Solid

    Raises
    ------
    InvalidInputError
        A size that is not a finite number above ``tol.linear``; an invalid ``align``.

    Examples
    --------
    >>> box = Box(2, 3, 4)
    >>> [len(box.faces()), len(box.edges()), len(box.vertices())]
    [6, 12, 8]
    >>> box.brep.bounding_box().tolist()
    [[-1.0, -1.5, -2.0], [1.0, 1.5, 2.0]]
    """
    t = resolve(tol)
    L, W, H = _positive(length, "length", t), _positive(width, "width", t), _positive(height, "height", t)
    al = _alignment(align)
    o = _align_offset(np.array([[0.0, 0.0, 0.0], [L, W, H]]), al)
    X, Y, Z = _E
    b = BRepBuilder(t)
    # A counter-clockwise (seen from +z) square lamina: the loop l_top faces up, the other down.
    _, f_top, l_top, _ = b.mvfs(o)
    e0, _ = b.mev(l_top, None, o + L * X)
    e1, _ = b.mev(l_top, 2 * e0, o + L * X + W * Y)
    e2, _ = b.mev(l_top, 2 * e1, o + W * Y)
    _, f_bottom, _ = b.mef(l_top, 2 * e2, 2 * e0 + 1)
    sweep = b.sweep_loop(l_top, H * Z)

    planes = {f_top: PlanarSurface(o + H * Z, Z, X), f_bottom: PlanarSurface(o, -Z, X)}
    for c, f in zip(sweep["coedges"], sweep["faces"]):
        p, q = b.vpoint[b.origin(c)], b.vpoint[b.target(c)]
        d = (q - p) / np.linalg.norm(q - p)
        # The bottom coedges run counter-clockwise seen from +z, so d × z points out of the box.
        planes[f] = PlanarSurface(p, np.cross(d, Z), d)
    for f, plane in planes.items():
        b.set_face_surface(f, plane, True)
    for e, (vs, ve) in enumerate(b.ev):
        p, q = b.vpoint[vs], b.vpoint[ve]
        line = Line(p, q - p)
        pcs = {f: _line_on_plane(planes[f], line) for f in (_face_of(b, 2 * e), _face_of(b, 2 * e + 1))}
        _attach_edge(b, e, line, (0.0, float(np.linalg.norm(q - p))), pcs)
    return Solid(b.build())


# ============================================================================ surfaces of revolution
def _revolved(
    b: BRepBuilder,
    O: np.ndarray,
    frame: tuple[np.ndarray, np.ndarray, np.ndarray],
    r0: float,
    r1: float,
    h: float,
    side: CylindricalSurface | ConicalSurface,
    v_top: float,
) -> None:
    """Cylinder-like topology (V 4, E 6, F 4): base disk of radius ``r0`` at ``O``, lid of radius
    ``r1`` at ``O + h Z``, two half-side faces on ``side``.

    ``side`` must satisfy ``side(u, 0) = O + r0 e(u)``, ``side(u, v_top) = O + h Z + r1 e(u)``
    with ``|Sv| = 1`` (``v`` is arc length along the rulings), which holds for the cylinder
    and for OCCT's cone with ``O`` on its reference circle.

    Euler construction: ``mvfs(b0)``, ``mev`` to ``b1`` (bottom arc A, ``u ∈ [0, π]``), ``mef``
    back to ``b0`` (arc B, ``u ∈ [π, 2π]``) makes a two-face disk lamina whose up-facing loop
    is swept along ``h Z`` (the rulings at ``u = π`` and ``u = 0``, the lid arcs B and A, the
    side faces on arcs B and A).
    """
    X, Y, Z = frame
    top = O + h * Z
    bot0, bot1, top0, top1 = O + r0 * X, O - r0 * X, top + r1 * X, top - r1 * X

    _, f_lid, l_lid, _ = b.mvfs(bot0)
    e_bot_a, _ = b.mev(l_lid, None, bot1)  # bot0 -> bot1
    e_bot_b, f_base, _ = b.mef(l_lid, 2 * e_bot_a, 2 * e_bot_a + 1)  # bot1 -> bot0
    sweep = b.sweep_loop(l_lid, h * Z)
    e_rul_pi, e_rul_0 = sweep["struts"]  # bot1 -> top1, bot0 -> top0
    e_top_b, e_top_a = sweep["lids"]  # top1 -> top0, top0 -> top1
    f_side_b, f_side_a = sweep["faces"]  # u in [π, 2π], u in [0, π]
    b.set_vertex(b.ev[e_rul_0][1], top0)
    b.set_vertex(b.ev[e_rul_pi][1], top1)

    base = PlanarSurface(O, -Z, X)  # normal -Z: outward under the base
    lid = PlanarSurface(top, Z, X)
    for f, s in ((f_base, base), (f_lid, lid), (f_side_a, side), (f_side_b, side)):
        b.set_face_surface(f, s, True)

    c_bot = Circle(O, Z, X, r0)  # angle == the side's u
    c_top = Circle(top, Z, X, r1)
    on_base, on_lid = _circle_on_plane(base, c_bot), _circle_on_plane(lid, c_top)
    bottom_uv = Line2D([0.0, 0.0], _U_AXIS)
    top_uv = Line2D([0.0, v_top], _U_AXIS)
    _attach_edge(b, e_bot_a, c_bot, (0.0, PI), {f_side_a: bottom_uv, f_base: on_base})
    _attach_edge(b, e_bot_b, c_bot, (PI, TWO_PI), {f_side_b: bottom_uv, f_base: on_base})
    _attach_edge(b, e_top_a, c_top, (0.0, PI), {f_side_a: top_uv, f_lid: on_lid})
    _attach_edge(b, e_top_b, c_top, (PI, TWO_PI), {f_side_b: top_uv, f_lid: on_lid})
    # Rulings: the line from the bottom point along Sv (unit), so t == v.
    sv = side.derivatives(np.array([0.0, PI]), np.zeros(2), 1)[:, 0, 1, :]
    _attach_edge(b, e_rul_0, Line(bot0, sv[0]), (0.0, v_top),
                 {f_side_a: Line2D([0.0, 0.0], _V_AXIS), f_side_b: Line2D([TWO_PI, 0.0], _V_AXIS)})
    pi_uv = Line2D([PI, 0.0], _V_AXIS)
    _attach_edge(b, e_rul_pi, Line(bot1, sv[1]), (0.0, v_top), {f_side_a: pi_uv, f_side_b: pi_uv})


def _pointed_cone(
    b: BRepBuilder, O: np.ndarray, frame: tuple[np.ndarray, np.ndarray, np.ndarray], r0: float, h: float
) -> None:
    """Cone with base radius ``r0`` at ``O`` and apex at ``O + h Z`` (V 3, E 4, F 3).

    Euler construction: the disk lamina as in :func:`_revolved`, then ``mev`` from ``b0`` to
    the apex (ruling at ``u = 0``) and ``mef`` from ``b1`` to the apex (ruling at ``u = π``)
    splitting the up-facing face into the two half-cones.  Each half-cone's p-curve loop jumps
    from ``(π, L)`` to ``(0, L)`` (or ``(2π, L)`` to ``(π, L)``) at the apex, ``L`` the slant
    height, where the surface collapses to the apex.
    """
    X, Y, Z = frame
    slant = math.hypot(h, r0)
    side = ConicalSurface(O, Z, X, r0, math.atan2(-r0, h))
    bot0, bot1, apex = O + r0 * X, O - r0 * X, O + h * Z

    _, f_side_a, l_up, _ = b.mvfs(bot0)
    e_bot_a, _ = b.mev(l_up, None, bot1)  # bot0 -> bot1
    e_bot_b, f_base, _ = b.mef(l_up, 2 * e_bot_a, 2 * e_bot_a + 1)  # bot1 -> bot0
    e_rul_0, _ = b.mev(l_up, 2 * e_bot_b, apex)  # bot0 -> apex
    e_rul_pi, f_side_b, _ = b.mef(l_up, 2 * e_bot_a, 2 * e_rul_0)  # bot1 -> apex

    base = PlanarSurface(O, -Z, X)
    b.set_face_surface(f_base, base, True)
    b.set_face_surface(f_side_a, side, True)
    b.set_face_surface(f_side_b, side, True)
    c_bot = Circle(O, Z, X, r0)
    on_base = _circle_on_plane(base, c_bot)
    bottom_uv = Line2D([0.0, 0.0], _U_AXIS)
    _attach_edge(b, e_bot_a, c_bot, (0.0, PI), {f_side_a: bottom_uv, f_base: on_base})
    _attach_edge(b, e_bot_b, c_bot, (PI, TWO_PI), {f_side_b: bottom_uv, f_base: on_base})
    sv = side.derivatives(np.array([0.0, PI]), np.zeros(2), 1)[:, 0, 1, :]
    _attach_edge(b, e_rul_0, Line(bot0, sv[0]), (0.0, slant),
                 {f_side_a: Line2D([0.0, 0.0], _V_AXIS), f_side_b: Line2D([TWO_PI, 0.0], _V_AXIS)})
    pi_uv = Line2D([PI, 0.0], _V_AXIS)
    _attach_edge(b, e_rul_pi, Line(bot1, sv[1]), (0.0, slant), {f_side_a: pi_uv, f_side_b: pi_uv})


def Cylinder(
    radius: float,
    height: float,
    *,
    align: Any = _CENTER,
    direction: Sequence[float] = (0.0, 0.0, 1.0),
    tol: Tolerance | None = None,
) -> Solid:
    """A right circular cylinder without seam: two half-cylinder faces and two disks.

    The side is one :class:`CylindricalSurface` (axis ``direction``, ``v = 0`` at the base,
    ``x_dir`` where ``u = 0``) shared by the faces ``u ∈ [0, π]`` and ``u ∈ [π, 2π]``; the
    base and the lid are :class:`PlanarSurface` disks with outward normals.  Vertices sit at
    ``u = 0`` and ``u = π`` on both circles; the four half-circle edges are :class:`Circle`
    arcs in the cylinder's frame (circle angle == ``u``, ranges ``[0, π]`` and ``[π, 2π]``),
    the two rulings :class:`Line` edges with ``t == v``.  P-curves: ``Line2D`` on the side
    faces, ``Trig2D`` on the disks.  V 4, E 6, F 4 (OCCT: 2, 3, 3 with a seam).

    Parameters
    ----------
    radius, height : float > 0
    align : None, str or 3 of ``"min"``, ``"center"``, ``"max"``
        Bounding-box alignment per axis (default centred, so ``z ∈ [-h/2, h/2]`` for the
        default direction); None puts the centre of the base at the origin.
    direction : (3,) array_like
        The axis, from the base to the lid.
    tol : Tolerance, optional

    Returns
    -------
    Solid

    Raises
    ------
    InvalidInputError
        A size that is not a finite number above ``tol.linear``, a zero or non-finite direction,
        an invalid align.
    """
    t = resolve(tol)
    r, h = _positive(radius, "radius", t), _positive(height, "height", t)
    al, Z = _alignment(align), _direction(direction)
    frame = _frame(Z)
    o = _align_offset(_union_box(_circle_box(np.zeros(3), r, Z), _circle_box(h * Z, r, Z)), al)
    b = BRepBuilder(t)
    _revolved(b, o, frame, r, r, h, CylindricalSurface(o, Z, frame[0], r), h)
    return Solid(b.build())


def Cone(
    bottom_radius: float,
    top_radius: float,
    height: float,
    *,
    align: Any = _CENTER,
    direction: Sequence[float] = (0.0, 0.0, 1.0),
    tol: Tolerance | None = None,
) -> Solid:
    """A right circular cone or frustum without seam.

    The side is one :class:`ConicalSurface` in OCCT's parametrisation (reference circle = the
    base, ``v`` along the slant: ``v = L = sqrt(h² + (r1 - r0)²)`` at the top, semi-angle
    ``atan((r1 - r0) / h)``, negative when narrowing) split into ``u ∈ [0, π]`` and
    ``[π, 2π]``.  With both radii > 0 the topology is the cylinder's (V 4, E 6, F 4; OCCT 2, 3, 3).
    When one radius is 0 that end is an apex vertex where the two rulings of each half meet;
    there is no disk there (V 3, E 4, F 3; OCCT 2, 3, 2 with a seam and a degenerate edge).
    Equal radii (within ``tol.linear``) make a cylinder, which is what is built (:func:`Cylinder`,
    cylindrical side).

    Parameters
    ----------
    bottom_radius, top_radius : float >= 0, not both 0
    height : float > 0
    align : None, str or 3 of ``"min"``, ``"center"``, ``"max"``
        Bounding-box alignment per axis (default centred); None puts the centre of the base
        at the origin.
    direction : (3,) array_like
        The axis, from the bottom to the top.
    tol : Tolerance, optional

    Returns
    -------
    Solid

    Raises
    ------
    InvalidInputError
        Negative, NaN or infinite radii, a radius in ``(0, tol.linear]``, both radii 0, a
        height that is not a finite number above ``tol.linear``, a zero or non-finite
        direction, an invalid align.
    """
    t = resolve(tol)
    r0 = _non_negative(bottom_radius, "bottom_radius", t)
    r1 = _non_negative(top_radius, "top_radius", t)
    h = _positive(height, "height", t)
    if r0 == 0.0 and r1 == 0.0:
        raise InvalidInputError("Cone: at least one radius must be > 0, got bottom_radius = top_radius = 0")
    al, Z = _alignment(align), _direction(direction)
    if abs(r0 - r1) <= t.linear:  # the cone would deviate from this cylinder by less than tol.linear
        return Cylinder(r0, h, align=al, direction=Z, tol=t)
    frame = _frame(Z)
    boxes = [_circle_box(np.zeros(3), r0, Z) if r0 > 0 else np.zeros((2, 3)),
             _circle_box(h * Z, r1, Z) if r1 > 0 else np.stack([h * Z, h * Z])]
    o = _align_offset(_union_box(*boxes), al)
    b = BRepBuilder(t)
    if r1 == 0.0:
        _pointed_cone(b, o, frame, r0, h)
    elif r0 == 0.0:
        # The same solid seen from the other end: base (radius r1) at the top, apex at o.
        X, _, _ = frame
        _pointed_cone(b, o + h * Z, (X, np.cross(-Z, X), -Z), r1, h)
    else:
        side = ConicalSurface(o, Z, frame[0], r0, math.atan2(r1 - r0, h))
        _revolved(b, o, frame, r0, r1, h, side, math.hypot(h, r1 - r0))
    return Solid(b.build())


def Sphere(radius: float, *, align: Any = _CENTER, tol: Tolerance | None = None) -> Solid:
    """A sphere as two hemispheres split along the meridian plane ``y = 0`` (through the centre).

    One :class:`SphericalSurface` (axis +z, ``x_dir`` +x) bounds the faces ``u ∈ [0, π]`` and
    ``u ∈ [π, 2π]``; the two vertices are the poles and the two edges the meridians ``u = 0``
    and ``u = π``, :class:`Circle` curves framed so that their angle is the sphere's latitude
    ``v`` (range ``[-π/2, π/2]``, from the south pole to the north pole).  Each hemisphere's
    p-curve loop jumps along ``v = ±π/2`` at the poles.  V 2, E 2, F 2 (OCCT: 2, 3, 1).

    Parameters
    ----------
    radius : float > 0
    align : None, str or 3 of ``"min"``, ``"center"``, ``"max"``
        Bounding-box alignment per axis (default and None: centred).
    tol : Tolerance, optional

    Returns
    -------
    Solid

    Raises
    ------
    InvalidInputError
        A radius that is not a finite number above ``tol.linear``, an invalid align.
    """
    t = resolve(tol)
    R = _positive(radius, "radius", t)
    al = _alignment(align)
    C = _align_offset(np.array([[-R, -R, -R], [R, R, R]]), al)
    X, Y, Z = _E
    b = BRepBuilder(t)
    _, f_west, l0, _ = b.mvfs(C - R * Z)
    e_m0, _ = b.mev(l0, None, C + R * Z)  # south -> north, u = 0
    e_mpi, f_east, _ = b.mef(l0, 2 * e_m0 + 1, 2 * e_m0)  # south -> north, u = π
    # f_west holds meridian π forwards and meridian 0 backwards: u in [0, π]; f_east: [π, 2π].
    S = SphericalSurface(C, Z, X, R)
    b.set_face_surface(f_west, S, True)
    b.set_face_surface(f_east, S, True)
    # Circle frames (X_c, Y_c = Z): circle(t) == S(u, t) for u = 0 and u = π.
    _attach_edge(b, e_m0, Circle(C, -Y, X, R), (-HALF_PI, HALF_PI),
                 {f_west: Line2D([0.0, 0.0], _V_AXIS), f_east: Line2D([TWO_PI, 0.0], _V_AXIS)})
    pi_uv = Line2D([PI, 0.0], _V_AXIS)
    _attach_edge(b, e_mpi, Circle(C, Y, -X, R), (-HALF_PI, HALF_PI), {f_west: pi_uv, f_east: pi_uv})
    return Solid(b.build())


def Torus(major_radius: float, minor_radius: float, *, align: Any = _CENTER, tol: Tolerance | None = None) -> Solid:
    """A ring torus about +z as four quarter faces split at ``u ∈ {0, π}`` and ``v ∈ {0, π}``.

    One :class:`ToroidalSurface` (axis +z, ``x_dir`` +x) bounds the faces
    ``[iπ, (i+1)π] × [jπ, (j+1)π]``.  Vertices at ``(u, v) ∈ {0, π}²`` (outer and inner
    equator on the ``xz`` plane); edges: four half-parallels (:class:`Circle` about the axis,
    angle == ``u``) on the outer (``v = 0``) and inner (``v = π``) equators and four
    half-meridians (:class:`Circle` in the planes ``u = 0`` and ``u = π``, angle == ``v``).
    All p-curves are ``Line2D``.  V 4, E 8, F 4, genus 1 (OCCT: 1, 2, 1 with two seams).

    Euler construction: a tube from ``u = 0`` to ``u = π`` with a cap at each end (``mvfs``,
    ``mev``, ``mef`` make the meridian lamina at ``u = 0``; two ``mev`` the half-equators to
    ``u = π``; two ``mef`` the meridian arcs there, closing the quarters ``Q00`` and ``Q01`` and
    the cap at ``u = π``), then ``kfmrh`` turns the cap at ``u = 0`` into a ring of the cap at
    ``u = π`` (genus 1), ``mekr`` joins the two rings along the outer equator and ``mef``
    splits the face along the inner one into ``Q10`` and ``Q11``.  Every edge is made in the
    direction of its increasing parameter.

    Parameters
    ----------
    major_radius : float > 0
    minor_radius : float, ``0 < minor_radius < major_radius``
    align : None, str or 3 of ``"min"``, ``"center"``, ``"max"``
        Bounding-box alignment per axis (default and None: centred).
    tol : Tolerance, optional

    Returns
    -------
    Solid

    Raises
    ------
    InvalidInputError
        Radii that are not finite numbers above ``tol.linear``, ``minor_radius >= major_radius``
        or an inner radius ``major - minor`` not above ``tol.linear``, an invalid align.
    """
    t = resolve(tol)
    R, r = _positive(major_radius, "major_radius", t), _positive(minor_radius, "minor_radius", t)
    if not r < R:
        raise InvalidInputError(
            f"Torus: minor_radius must be < major_radius (a ring torus), got {minor_radius!r} >= {major_radius!r}"
        )
    _above_tolerance(R - r, "major_radius - minor_radius (the inner equator's radius)", t)
    al = _alignment(align)
    C = _align_offset(np.array([[-(R + r), -(R + r), -r], [R + r, R + r, r]]), al)
    X, Y, Z = _E
    S = ToroidalSurface(C, Z, X, R, r)
    p00, p0pi, ppi0, ppipi = S.evaluate(np.array([0.0, 0.0, PI, PI]), np.array([0.0, PI, 0.0, PI]))

    b = BRepBuilder(t)
    # Names: m = meridian (u const), p = parallel (v const); 0 / pi the constant; a / b the half.
    v00, f_cap0, l_cap0, _ = b.mvfs(p00)
    e_m0a, v0pi = b.mev(l_cap0, None, p0pi)  # v00 -> v0pi
    e_m0b, f_q00, l_q00 = b.mef(l_cap0, 2 * e_m0a, 2 * e_m0a + 1)  # v0pi -> v00
    e_p0a, vpi0 = b.mev(l_q00, b.coedge_ending_at(l_q00, v00), ppi0)  # v00 -> vpi0
    e_ppa, vpipi = b.mev(l_q00, b.coedge_ending_at(l_q00, v0pi), ppipi)  # v0pi -> vpipi
    e_mpia, f_q01, l_q01 = b.mef(l_q00, 2 * e_p0a, 2 * e_ppa)  # vpi0 -> vpipi
    e_mpib, f_cap, l_cap = b.mef(l_q01, 2 * e_ppa, 2 * e_mpia + 1)  # vpipi -> vpi0
    b.kfmrh(f_cap0, f_cap)
    e_p0b = b.mekr(l_cap, b.coedge_ending_at(l_cap, vpi0), l_cap0, b.coedge_ending_at(l_cap0, v00))
    e_ppb, f_q10, _ = b.mef(l_cap, b.coedge_ending_at(l_cap, vpipi), b.coedge_ending_at(l_cap, v0pi))
    f_q11 = f_cap

    for f in (f_q00, f_q10, f_q01, f_q11):
        b.set_face_surface(f, S, True)
    outer, inner = Circle(C, Z, X, R + r), Circle(C, Z, X, R - r)
    m0, mpi = Circle(C + R * X, -Y, X, r), Circle(C - R * X, Y, -X, r)  # angle == v at u = 0, π
    v0_uv, v2pi_uv, vpi_uv = (Line2D([0.0, v], _U_AXIS) for v in (0.0, TWO_PI, PI))
    u0_uv, u2pi_uv, upi_uv = (Line2D([u, 0.0], _V_AXIS) for u in (0.0, TWO_PI, PI))
    _attach_edge(b, e_m0a, m0, (0.0, PI), {f_q00: u0_uv, f_q10: u2pi_uv})
    _attach_edge(b, e_m0b, m0, (PI, TWO_PI), {f_q01: u0_uv, f_q11: u2pi_uv})
    _attach_edge(b, e_mpia, mpi, (0.0, PI), {f_q00: upi_uv, f_q10: upi_uv})
    _attach_edge(b, e_mpib, mpi, (PI, TWO_PI), {f_q01: upi_uv, f_q11: upi_uv})
    _attach_edge(b, e_p0a, outer, (0.0, PI), {f_q00: v0_uv, f_q01: v2pi_uv})
    _attach_edge(b, e_p0b, outer, (PI, TWO_PI), {f_q10: v0_uv, f_q11: v2pi_uv})
    _attach_edge(b, e_ppa, inner, (0.0, PI), {f_q00: vpi_uv, f_q01: vpi_uv})
    _attach_edge(b, e_ppb, inner, (PI, TWO_PI), {f_q10: vpi_uv, f_q11: vpi_uv})
    return Solid(b.build())
