"""The one tolerance model of coons.

A :class:`Tolerance` is a frozen value with three numbers:

``linear``
    Two points closer than this (model units) are the same point.  Edge and vertex
    tolerances recorded on shapes start from it.
``angular``
    Two directions closer than this (radians) are parallel.
``solver``
    Relative accuracy asked of iterative solvers (Newton, fitting) and of the
    parametric domain checks: a parameter may lie outside its knot span domain by at
    most ``solver * max(1, domain length)`` (round-off of the caller's arithmetic) and
    is then clamped; anything further raises.

Public functions take ``tol: Tolerance | None = None`` and resolve it once with
:func:`resolve`; private functions take a resolved ``Tolerance``.  Derived
thresholds are computed from these three values where they are used, with a comment
saying why.  Tessellation deflection is a resolution, not a tolerance, and never
decides topology.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from coons.errors import InvalidInputError

__all__ = ["Tolerance", "DEFAULT_TOLERANCE", "resolve"]


@dataclass(frozen=True, slots=True)
class Tolerance:
    """Linear, angular and solver tolerances (see the module docstring).

    Raises
    ------
    InvalidInputError
        If a value is not a finite positive number.
    """

    linear: float = 1e-7
    angular: float = 1e-9
    solver: float = 1e-12

    def __post_init__(self) -> None:
        for name in ("linear", "angular", "solver"):
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
                raise InvalidInputError(f"Tolerance.{name} must be a finite positive number, got {value!r}")

    def scaled(self, factor: float) -> "Tolerance":
        """The same tolerance with ``linear`` multiplied by ``factor`` (for a model scaled by it)."""
        return Tolerance(self.linear * factor, self.angular, self.solver)


#: Default tolerance: 1e-7 model units, 1e-9 rad, solver 1e-12 (OCCT's Precision::Confusion is 1e-7).
DEFAULT_TOLERANCE = Tolerance()


def resolve(tol: Tolerance | None) -> Tolerance:
    """Return ``tol`` or the default tolerance.

    Raises
    ------
    InvalidInputError
        If ``tol`` is neither ``None`` nor a :class:`Tolerance`.
    """
    if tol is None:
        return DEFAULT_TOLERANCE
    if not isinstance(tol, Tolerance):
        raise InvalidInputError(f"tol must be a coons.Tolerance or None, got {type(tol).__name__}")
    return tol
