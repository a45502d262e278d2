"""STEP import: an ISO 10303-21 file -> checked coons solids.

:func:`import_step` chains the three layers: :func:`coons.io.step.p21.parse_file` (syntax),
:class:`coons.io.step.schema.StepModel` (entities -> geometry and neutral faces, units to
millimetres) and :func:`coons.io._faces.faces_to_solid` (normalisation to the coons B-rep rules,
sewing, check).  It returns every solid of the file: one :class:`~coons.topology.shape.Solid`
when the file holds exactly one, else a list (:func:`import_step_solids` always returns a list).

Everything that goes wrong is a :class:`~coons.errors.StepError` naming the entity and line:
syntax, dangling references, unsupported or malformed entities, and a B-rep that does not sew into
a valid closed solid within tolerance (the sewing's or checker's
:class:`~coons.errors.TopologyError` / :class:`~coons.errors.InvalidGeometryError` is chained as
``__cause__``).  The reader does
not heal files, does not read assemblies' placements, colours, layers or PMI, and does not use
the file's p-curves (see :mod:`coons.io.step.schema`).

Speed.  Every layer works in batches where the per-entity Python cost would dominate: the
Part 21 fast path finds, validates and defers common instances with one regular expression
each and converts them when first read (points and directions straight from their text), the
degenerate-edge tests and the cheap p-curves of all faces run as single batches
(:func:`coons.kernel.onsurface.cheap_pcurves_many`), the checker evaluates every p-curve sample
of the model at once, and the cyclic garbage collector is paused while the file is read.  On the
benchmark models (``benchmarks/bench_io.py``: a plate with 400 holes, a box of 1014 bilinear
B-spline faces) the import ran 1.17x and 1.18x faster than OCCT's (with its default healing) in
the last run on this two-core machine (1.5x and 1.2x in one on a busy machine); what is left is
spread over parsing (~0.13 s on the box), the schema's per-entity objects (~0.25 s),
normalisation (~0.15 s) and sewing with the check (~0.18 s), figures of one profiled run.
"""

from __future__ import annotations

import contextlib
import gc
import os

from coons.errors import CoonsError, StepError
from coons.tolerance import Tolerance, resolve

__all__ = ["import_step", "import_step_solids", "read_step_faces", "solids_from_p21"]


@contextlib.contextmanager
def _gc_paused():
    """Pause Python's cyclic garbage collector for the duration of a read.

    A STEP file becomes some 10^5 long-lived objects (instances, parameter tuples, geometry);
    with the collector on, every generation-2 pass walks all of them, which cost about a
    third more time on the benchmark's 1014-face box.  The reader creates no garbage cycles
    that must be freed before it returns; the collector resumes (if it was on) afterwards,
    also when the read raises.  The switch is process-wide, as ``gc.disable`` is.
    """
    was = gc.isenabled()
    gc.disable()
    try:
        yield
    finally:
        if was:
            gc.enable()


def read_step_faces(path: str | os.PathLike, tol: Tolerance | None = None):
    """The solids of a STEP file as neutral face records (:class:`coons.io.step.schema.SolidRecord`), unsewn.

    Raises
    ------
    StepError
        The file cannot be read or parsed, has no solid, or a solid's entities are malformed or
        unsupported.
    """
    from coons.io.step.p21 import parse_file
    from coons.io.step.schema import StepModel

    with _gc_paused():
        return StepModel(parse_file(path), resolve(tol)).solids()


def import_step_solids(path: str | os.PathLike, tol: Tolerance | None = None) -> list:
    """Every solid of a STEP file, in file order, as checked coons solids (lengths in millimetres).

    Parameters
    ----------
    path : str or path-like
    tol : Tolerance, optional
        The linear tolerance is raised, per solid, to the file's declared length uncertainty
        (``UNCERTAINTY_MEASURE_WITH_UNIT``) when that is larger.

    Returns
    -------
    list of Solid

    Raises
    ------
    StepError
        As :func:`read_step_faces`, or the faces do not sew into a valid closed solid within
        tolerance (the sewing or checking error is the ``__cause__``).
    """
    from coons.io.step.p21 import parse_file

    with _gc_paused():
        return solids_from_p21(parse_file(path), tol)


def solids_from_p21(file, tol: Tolerance | None = None) -> list:
    """The solids of a parsed file (:func:`coons.io.step.p21.parse`), as :func:`import_step_solids`.

    Raises
    ------
    StepError
        As :func:`import_step_solids`.
    """
    from coons.io._faces import faces_to_solid
    from coons.io.step.schema import StepModel

    t = resolve(tol)
    out = []
    for rec in StepModel(file, t).solids():
        tt = t
        if rec.uncertainty is not None and rec.uncertainty > t.linear:
            tt = Tolerance(rec.uncertainty, t.angular, t.solver)
        try:
            out.append(faces_to_solid(rec.faces, tt))
        except StepError:
            raise
        except CoonsError as exc:
            raise StepError(f"{rec.entity.name}: its faces do not form a valid solid: {type(exc).__name__}: {exc}",
                            entity_id=rec.entity.id, line=rec.entity.line) from exc
    return out


def import_step(path: str | os.PathLike, tol: Tolerance | None = None):
    """Read a STEP file: one :class:`~coons.topology.shape.Solid` if it holds one solid, else a list.

    Raises
    ------
    StepError
        As :func:`import_step_solids`.
    """
    solids = import_step_solids(path, tol)
    return solids[0] if len(solids) == 1 else solids
