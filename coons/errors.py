"""Typed exceptions of coons.

Every failure in coons raises one of these, with a message that names what was
expected and what was found.  Nothing returns ``None`` or ``False`` to signal a
failure, nothing is silently clamped or dropped.

Hierarchy::

    CoonsError
    ├── InvalidInputError (ValueError)      bad arguments from the caller
    │   └── InvalidGeometryError            a curve/surface definition that is not valid
    ├── ConvergenceError (ArithmeticError)  an iterative solver did not converge
    ├── TopologyError                       a B-rep that breaks an invariant
    ├── BooleanError                        a Boolean stage failed (``.stage``, ``.diagnostics``)
    └── StepError                           a STEP file that cannot be read (``.entity_id``, ``.line``)
"""

from __future__ import annotations

from typing import Any

__all__ = [
    "CoonsError",
    "InvalidInputError",
    "InvalidGeometryError",
    "ConvergenceError",
    "TopologyError",
    "BooleanError",
    "StepError",
]


class CoonsError(Exception):
    """Base class of every exception raised by coons."""


class InvalidInputError(CoonsError, ValueError):
    """An argument has the wrong shape, type or value."""


class InvalidGeometryError(InvalidInputError):
    """A curve or surface definition is not valid (knots, weights, degree, coordinates)."""


class ConvergenceError(CoonsError, ArithmeticError):
    """An iterative solver did not reach its tolerance.

    Attributes
    ----------
    indices : numpy array or None
        Indices (into the caller's batch) of the items that failed, when the call was batched.
    residuals : numpy array or None
        The residual reached by each failed item.
    """

    def __init__(self, message: str, *, indices: Any = None, residuals: Any = None) -> None:
        super().__init__(message)
        self.indices = indices
        self.residuals = residuals


class TopologyError(CoonsError):
    """A boundary representation breaks one of its invariants."""


class BooleanError(CoonsError):
    """A Boolean operation failed.

    Attributes
    ----------
    stage : str
        The phase that failed (``"broad_phase"``, ``"intersect"``, ``"imprint"``,
        ``"classify"``, ``"select"``, ``"sew"``, ``"check"``).
    diagnostics : dict
        Face/edge ids, residuals and anything else that locates the failure.
    """

    def __init__(self, message: str, *, stage: str, diagnostics: dict[str, Any] | None = None) -> None:
        super().__init__(f"[{stage}] {message}")
        self.stage = stage
        self.diagnostics = dict(diagnostics or {})


class StepError(CoonsError):
    """A STEP (ISO 10303-21) file cannot be read or written.

    Attributes
    ----------
    entity_id : int or None
        The ``#id`` of the offending entity, when known.
    line : int or None
        The 1-based line of the file where the problem was found, when known.
    """

    def __init__(self, message: str, *, entity_id: int | None = None, line: int | None = None) -> None:
        where = []
        if entity_id is not None:
            where.append(f"#{entity_id}")
        if line is not None:
            where.append(f"line {line}")
        prefix = f"{', '.join(where)}: " if where else ""
        super().__init__(prefix + message)
        self.entity_id = entity_id
        self.line = line
