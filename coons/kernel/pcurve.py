"""Exact curves in a surface's parameter plane (p-curves) that keep the edge's parameter.

An edge's p-curve maps the edge parameter ``t`` to ``(u, v)`` with
``surface(pcurve(t)) == curve(t)`` (same parameter).  For the analytic faces of primitives
and sweeps the p-curves are affine images of ``t`` or of ``(cos t, sin t)``:

* :class:`Line2D` — ``uv(t) = O + t D``: a line on a plane, a ruling or circle of a cylinder
  or cone (``u = t`` or ``v = t``), a meridian or parallel of a sphere or torus.
* :class:`Trig2D` — ``uv(t) = C + cos t A + sin t B``: a circle or ellipse edge on a plane,
  in any orientation and sense.

2-D :class:`~coons.kernel.curve.NurbsCurve` objects serve as p-curves for everything else.
All share ``evaluate(t) -> shape + (2,)`` and ``derivatives(t, order) -> shape + (order + 1, 2)``.
This module does not fit or project curves (see :mod:`coons.kernel.projection`).
"""

from __future__ import annotations

from dataclasses import dataclass

import math

import numpy as np

from coons.errors import InvalidGeometryError, InvalidInputError

__all__ = ["Line2D", "Trig2D"]


def _vec2(value, what: str) -> np.ndarray:
    a = np.array(value, dtype=np.float64)
    if a.shape != (2,) or not all(map(math.isfinite, a.tolist())):
        raise InvalidGeometryError(f"{what} must be 2 finite numbers, got {value!r}")
    a.setflags(write=False)
    return a


def _params(t) -> np.ndarray:
    t = np.asarray(t, dtype=np.float64)
    if t.size and not np.isfinite(t).all():
        raise InvalidInputError("p-curve parameters must be finite")
    return t


def _order(order) -> int:
    if isinstance(order, bool) or not isinstance(order, (int, np.integer)) or order < 0:
        raise InvalidInputError(f"order must be an integer >= 0, got {order!r}")
    return int(order)


def _affine2(matrix) -> tuple[np.ndarray, np.ndarray]:
    M = np.asarray(matrix, dtype=np.float64)
    if M.shape == (2, 2):
        return M, np.zeros(2)
    if M.shape == (2, 3):
        return M[:, :2], M[:, 2]
    if M.shape == (3, 3):
        return M[:2, :2], M[:2, 2]
    raise InvalidInputError(f"2-D affine map must be 2x2, 2x3 or 3x3, got shape {M.shape}")


@dataclass(frozen=True, eq=False)
class Line2D:
    """``uv(t) = origin + t * direction`` (``direction`` not normalised: it carries the speed).

    Raises
    ------
    InvalidGeometryError
        Non-finite values or a zero direction.
    """

    origin: np.ndarray
    direction: np.ndarray

    dimension = 2

    def __post_init__(self) -> None:
        object.__setattr__(self, "origin", _vec2(self.origin, "Line2D origin"))
        object.__setattr__(self, "direction", _vec2(self.direction, "Line2D direction"))
        if not np.any(self.direction):
            raise InvalidGeometryError("Line2D direction must be non-zero")

    @classmethod
    def many(cls, origins, directions) -> list["Line2D"]:
        """One line per row of ``origins`` and ``directions`` (``(k, 2)`` each), checked in one pass.

        For the callers that build thousands of p-curves at once (the STEP import): the same
        checks as the constructor, on whole arrays; each line holds read-only rows of them.

        Raises
        ------
        InvalidGeometryError
            Shapes other than ``(k, 2)``, non-finite values or a zero direction (the first bad row is named).
        """
        O = np.array(origins, dtype=np.float64)
        D = np.array(directions, dtype=np.float64)
        if O.ndim != 2 or O.shape[1:] != (2,) or D.shape != O.shape:
            raise InvalidGeometryError(f"Line2D.many needs two (k, 2) arrays, got shapes {O.shape} and {D.shape}")
        bad = np.flatnonzero(~np.isfinite(O).all(axis=1) | ~np.isfinite(D).all(axis=1) | ~D.any(axis=1))
        if bad.size:
            k = int(bad[0])
            raise InvalidGeometryError(f"Line2D.many: row {k} (origin {O[k].tolist()}, direction {D[k].tolist()}) "
                                       "is not finite or has a zero direction")
        O.setflags(write=False)
        D.setflags(write=False)
        out = []
        for o, d in zip(O, D):
            line = object.__new__(cls)
            object.__setattr__(line, "origin", o)
            object.__setattr__(line, "direction", d)
            out.append(line)
        return out

    def evaluate(self, t) -> np.ndarray:
        t = _params(t)
        return self.origin + t[..., None] * self.direction

    __call__ = evaluate

    def derivatives(self, t, order: int = 1) -> np.ndarray:
        order = _order(order)
        t = _params(t)
        out = np.zeros(t.shape + (order + 1, 2))
        out[..., 0, :] = self.evaluate(t)
        if order >= 1:
            out[..., 1, :] = self.direction
        return out

    def transformed(self, matrix) -> "Line2D":
        """The image under a 2-D affine map ``uv -> M uv + b``."""
        M, b = _affine2(matrix)
        return Line2D(M @ self.origin + b, M @ self.direction)

    def reparametrized_affine(self, scale: float, shift: float) -> "Line2D":
        """The same point set with parameter ``t' = scale * t + shift``."""
        if scale == 0 or not np.isfinite(scale) or not np.isfinite(shift):
            raise InvalidInputError(f"need a finite non-zero scale, got {scale!r}")
        d = self.direction / scale
        return Line2D(self.origin - shift * d, d)


@dataclass(frozen=True, eq=False)
class Trig2D:
    """``uv(t) = center + cos(t) * a + sin(t) * b``: circles and ellipses in the parameter plane.

    Raises
    ------
    InvalidGeometryError
        Non-finite values or parallel ``a`` and ``b`` (a degenerate ellipse).
    """

    center: np.ndarray
    a: np.ndarray
    b: np.ndarray

    dimension = 2

    def __post_init__(self) -> None:
        object.__setattr__(self, "center", _vec2(self.center, "Trig2D center"))
        object.__setattr__(self, "a", _vec2(self.a, "Trig2D a"))
        object.__setattr__(self, "b", _vec2(self.b, "Trig2D b"))
        if self.a[0] * self.b[1] - self.a[1] * self.b[0] == 0.0:
            raise InvalidGeometryError("Trig2D axes a and b must not be parallel")

    @classmethod
    def many(cls, centers, a, b) -> list["Trig2D"]:
        """One curve per row of ``centers``, ``a`` and ``b`` (``(k, 2)`` each), checked in one pass
        (as :meth:`Line2D.many`).

        Raises
        ------
        InvalidGeometryError
            Shapes other than ``(k, 2)``, non-finite values or parallel ``a`` and ``b`` (the first bad row is named).
        """
        C, A, B = (np.array(x, dtype=np.float64) for x in (centers, a, b))
        if C.ndim != 2 or C.shape[1:] != (2,) or A.shape != C.shape or B.shape != C.shape:
            raise InvalidGeometryError(
                f"Trig2D.many needs three (k, 2) arrays, got shapes {C.shape}, {A.shape}, {B.shape}")
        bad = np.flatnonzero(~np.isfinite(np.concatenate([C, A, B], axis=1)).all(axis=1)
                             | (A[:, 0] * B[:, 1] - A[:, 1] * B[:, 0] == 0.0))
        if bad.size:
            k = int(bad[0])
            raise InvalidGeometryError(f"Trig2D.many: row {k} (center {C[k].tolist()}, a {A[k].tolist()}, "
                                       f"b {B[k].tolist()}) is not finite or has parallel axes")
        out = []
        for X in (C, A, B):
            X.setflags(write=False)
        for c, u, v in zip(C, A, B):
            curve = object.__new__(cls)
            object.__setattr__(curve, "center", c)
            object.__setattr__(curve, "a", u)
            object.__setattr__(curve, "b", v)
            out.append(curve)
        return out

    def evaluate(self, t) -> np.ndarray:
        t = _params(t)
        return self.center + np.cos(t)[..., None] * self.a + np.sin(t)[..., None] * self.b

    __call__ = evaluate

    def derivatives(self, t, order: int = 1) -> np.ndarray:
        order = _order(order)
        t = _params(t)
        c, s = np.cos(t)[..., None], np.sin(t)[..., None]
        out = np.empty(t.shape + (order + 1, 2))
        # d^k/dt^k (cos t, sin t) cycles with period 4.
        cycle = [(c, s), (-s, c), (-c, -s), (s, -c)]
        for k in range(order + 1):
            ck, sk = cycle[k % 4]
            out[..., k, :] = ck * self.a + sk * self.b
        out[..., 0, :] += self.center
        return out

    def transformed(self, matrix) -> "Trig2D":
        M, b = _affine2(matrix)
        return Trig2D(M @ self.center + b, M @ self.a, M @ self.b)
