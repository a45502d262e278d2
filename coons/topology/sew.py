"""Sewing trimmed faces into a solid: vertices merged by distance, edges matched by their curves.

:func:`sew_faces` takes a closed set of trimmed faces, each a :class:`FaceSpec` (surface,
sense, loops of :class:`EdgeSpec` in loop order), and returns the checked
:class:`~coons.topology.shape.Solid` they bound.  It is the entry point of STEP import and of
the Booleans' last phase: faces arrive as independent pieces, and the topology — which ends
meet, which edges are shared — is recovered from geometry:

1. **Vertices**: the end points of all edge uses (evaluated once per face spec and per edge
   use and remembered with them, :func:`use_points`: the faces a Boolean passes through
   unchanged, and the uses a changed face keeps, are not evaluated again; the rows of the faces
   the last sewing also had are taken from its arrays in one gather, :func:`_gathered_uses`)
   are clustered with a k-d tree (``scipy.spatial.cKDTree.query_pairs``) — two ends within ``max(tol.linear, edge tolerances)``
   are one vertex; clusters are the connected components.  The vertex sits at the cluster mean
   and records the largest distance to it as its tolerance.  A use whose two ends are one vertex
   and whose midpoint lies within its tolerance of it (an edge shorter than its tolerance: two
   crossings of intersection curves that close) is collapsed into that vertex, its loop running
   on from the use before to the one after (:func:`_without_uses`; a loop or face left empty
   goes), and the ends clustered again.
2. **Loops** must close: each edge use ends at the vertex where the next one starts.
3. **Edges**: edge uses joining the same two vertices whose 3-D curves agree at their
   midpoints (the parametric midpoint of one within tolerance of the other curve, restricted to
   its range) are one edge.  Every edge must be used exactly twice, in opposite directions.
   The common case — two uses between two vertices with coincident midpoints, running opposite
   ways — is decided for all groups at once, and so are groups of four (the two halves of a
   hole, each used twice) whose every pair is certain without measuring: coincident midpoints,
   or midpoints farther apart than both curves reach from their own (a triangle-inequality bound
   for lines and circles, with a round-off margin).  Other groups go through union–find, which
   uses the same bound before measuring a distance, the sampled curve of each use computed once.
4. **Same parameter**: the first use's curve becomes the edge curve; the other use's p-curve is
   re-expressed in that parameter when its curve is a different object, through the affine
   parameter map fixed by the shared end points (verified on samples): ``Line2D``, ``Trig2D``
   (map slope ±1) and 2-D ``NurbsCurve`` p-curves are supported.
5. **Assembly**: one shell (the common case) straight from the arrays of steps 1–4
   (:func:`~coons.topology.builder.assembled_brep`, the B-rep the builder would make, without
   its per-entity lists; the edges' curves and p-curves, with their ids for the pools, are taken
   from the uses' object columns, carried from the last sewing like the others); several with
   :meth:`~coons.topology.builder.BRepBuilder.assemble`, shells nested
   (a shell enclosing negative volume becomes a void of the positive shell directly around it; a
   positive shell directly inside another positive one, or a void directly inside a void, is
   refused; which shell lies inside which is the winding number of one of its vertices, with
   respect to cones over the faces' chords when the vertex lies outside every face box, else to
   the tessellation: :mod:`coons.topology.nesting`, :func:`_nest_voids`), then ``build()``; both
   end in :func:`~coons.topology.check.check`.

:func:`face_specs` is the inverse: the face specifications of an existing B-rep (used by the
round-trip tests and by anything that re-sews modified faces).  It checks each edge once and
makes the specs with the private ``EdgeSpec._trusted`` / ``FaceSpec._trusted`` constructors
(no per-use re-validation); so does the Booleans' chord split (``solid._split_chords``) for the
pieces of a face cut by straight chords, built from validated parts.  Those constructors take only fields that validation would leave unchanged.

The module does not split or trim faces, does not close gaps larger than the tolerance, does
not reorient inconsistently oriented faces and does not merge coincident faces: any such input
raises :class:`~coons.errors.TopologyError` naming the face and edge at fault.
"""

from __future__ import annotations

import math
import operator
import weakref
from dataclasses import dataclass
from itertools import chain
from typing import Any, Sequence

import numpy as np

from coons.errors import InvalidInputError, TopologyError
from coons.kernel._common import row_groups
from coons.kernel.analytic import TWO_PI, Circle, Ellipse, Line, scalar_parameter, scalar_point
from coons.kernel.curve import NurbsCurve
from coons.kernel.onsurface import BATCHED_CURVES, evaluate_curves
from coons.kernel.pcurve import Line2D, Trig2D
from coons.tolerance import Tolerance, resolve
from coons.topology._components import components
from coons.topology._memo import (IdentityMemo, LastRecord, all_values, found_by_id, id_index, is_value,
                                  read_only as _read_only)
from coons.topology.brep import BRep
from coons.topology.builder import BRepBuilder, assembled_brep
from coons.topology.check import _SEWN_FROM, _norms
from coons.topology.shape import Solid

__all__ = ["EdgeSpec", "FaceSpec", "bilinear_patch_faces", "sew_faces", "face_specs", "sewn_unchanged",
           "sewn_unchanged_faces", "sewn_from", "remember_sewn", "read_unchanged_faces", "face_specs_many",
           "point_clusters"]

#: Parameters (fractions of an edge's range) at which two curves are compared point by point.
_PROBE = np.linspace(0.0, 1.0, 7)


@dataclass(frozen=True, eq=False)
class EdgeSpec:
    """One use of an edge by a face loop.

    Parameters
    ----------
    curve : 3-D curve with ``evaluate(t) -> shape + (3,)`` (``Line``, ``Circle``, ``NurbsCurve`` ...)
    t0, t1 : float
        Curve parameters where the use starts and ends, in the direction of travel; ``t0 > t1``
        means the loop runs against the curve's direction.
    pcurve : p-curve or None
        The curve in this face's parameter plane, same parameter as ``curve``
        (``surface(pcurve(t)) ≈ curve(t)``); None on a face without surface (implicit plane)
        or on a planar surface whose mass properties may project the 3-D curve.
    tol : float or None
        Deviation already present along this edge (for instance an intersection curve's
        fitting error); None means ``tol.linear``.

    Raises
    ------
    InvalidInputError
        A curve without ``evaluate``, non-finite or equal parameters, a negative tolerance.
    """

    curve: Any
    t0: float
    t1: float
    pcurve: Any = None
    tol: float | None = None

    def __post_init__(self) -> None:
        if not callable(getattr(self.curve, "evaluate", None)):
            raise InvalidInputError(f"EdgeSpec.curve must have an evaluate(t) method, got {type(self.curve).__name__}")
        t0, t1 = float(self.t0), float(self.t1)
        if not (math.isfinite(t0) and math.isfinite(t1)) or t0 == t1:
            raise InvalidInputError(f"EdgeSpec needs finite, different parameters t0 and t1, got ({self.t0!r}, {self.t1!r})")
        object.__setattr__(self, "t0", t0)
        object.__setattr__(self, "t1", t1)
        if self.pcurve is not None and not callable(getattr(self.pcurve, "evaluate", None)):
            raise InvalidInputError(f"EdgeSpec.pcurve must have an evaluate(t) method, got {type(self.pcurve).__name__}")
        if self.tol is not None:
            tol = float(self.tol)
            if not (math.isfinite(tol) and tol >= 0.0):
                raise InvalidInputError(f"EdgeSpec.tol must be a finite number >= 0, got {self.tol!r}")
            object.__setattr__(self, "tol", tol)

    @classmethod
    def _trusted(cls, curve: Any, t0: float, t1: float, pcurve: Any, tol: float | None) -> "EdgeSpec":
        """An EdgeSpec made without ``__post_init__``'s checks and conversions, for the kernel's
        own hot paths (a face's specs read from a B-rep, the pieces of a split face).

        Only for fields that are already what validation would make of them: ``curve`` and
        ``pcurve`` (or None) from a validated spec or a B-rep, ``t0 != t1`` finite Python floats,
        ``tol`` a finite Python float >= 0 or None.  The result then equals the validated one
        field by field; anything less trusted goes through the public constructor.
        """
        e = object.__new__(cls)
        # The frozen dataclass forbids setattr; its instance dict is the one the constructor fills.
        e.__dict__.update(curve=curve, t0=t0, t1=t1, pcurve=pcurve, tol=tol)
        return e


@dataclass(frozen=True, eq=False)
class FaceSpec:
    """A trimmed face: a surface, its sense and its loops (outer loop first).

    Parameters
    ----------
    surface : surface or None
        None for an implicit plane (the plane through the face's vertices).
    sense : bool
        True when the outward normal is ``Su × Sv``.
    loops : sequence of sequences of EdgeSpec
        Each loop in order; outer loops counter-clockwise and holes clockwise seen from
        outside (``docs/brep.md``).

    Raises
    ------
    InvalidInputError
        No loop, an empty loop, or a loop item that is not an :class:`EdgeSpec`.
    """

    surface: Any
    sense: bool
    loops: Sequence[Sequence[EdgeSpec]]

    def __post_init__(self) -> None:
        loops = tuple(tuple(loop) for loop in self.loops)
        if not loops:
            raise InvalidInputError("FaceSpec needs at least one loop, got none")
        for i, loop in enumerate(loops):
            if not loop:
                raise InvalidInputError(f"FaceSpec loop {i} is empty; a loop needs at least one EdgeSpec")
            for k, e in enumerate(loop):
                if not isinstance(e, EdgeSpec):
                    raise InvalidInputError(f"FaceSpec loop {i} item {k} must be an EdgeSpec, got {type(e).__name__}")
        object.__setattr__(self, "loops", loops)
        object.__setattr__(self, "sense", bool(self.sense))

    @classmethod
    def _trusted(cls, surface: Any, sense: bool, loops: tuple[tuple[EdgeSpec, ...], ...]) -> "FaceSpec":
        """A FaceSpec made without ``__post_init__``'s checks and conversions (see
        :meth:`EdgeSpec._trusted`): ``sense`` a bool and ``loops`` a non-empty tuple of non-empty
        tuples of :class:`EdgeSpec`, as validation would make them."""
        f = object.__new__(cls)
        f.__dict__.update(surface=surface, sense=sense, loops=loops)
        return f


# ====================================================================== sewing
#: Corners of the unit parameter square, counter-clockwise.
_UNIT_CORNERS = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])


def bilinear_patch_faces(nets, sense: bool = True) -> list[FaceSpec]:
    """Face specifications of bilinear NURBS patches, one per control net, bounded by their four sides.

    Each side is a :class:`~coons.kernel.analytic.Line` parametrised by length with its exact
    :class:`~coons.kernel.pcurve.Line2D` p-curve on ``[0, 1]²``.  With ``sense`` the loop runs
    counter-clockwise in ``(u, v)`` and the face normal is ``Su × Sv``; without, clockwise and
    ``-Su × Sv``.  Neighbouring patches that share corner points sew into one shell
    (:func:`sew_faces`): a quad mesh as an exact B-rep.

    Parameters
    ----------
    nets : (f, 2, 2, 3) array_like, the control points ``P[i, j]`` of each patch

    Raises
    ------
    InvalidInputError
        ``nets`` not of shape ``(f, 2, 2, 3)`` or not finite.
    """
    from coons.kernel.surface import NurbsSurface

    N = np.asarray(nets, dtype=np.float64)
    if N.ndim != 4 or N.shape[1:] != (2, 2, 3) or not np.all(np.isfinite(N)):
        raise InvalidInputError(f"bilinear_patch_faces needs finite control nets of shape (f, 2, 2, 3), got {N.shape}")
    uv = _UNIT_CORNERS if sense else _UNIT_CORNERS[[0, 3, 2, 1]]
    nxt = np.roll(uv, -1, axis=0)
    # Corners in loop order: S(u, v) of a bilinear patch at a corner of the square is that control point.
    P = N[:, uv[:, 0].astype(int), uv[:, 1].astype(int)]  # (f, 4, 3)
    D = np.roll(P, -1, axis=1) - P
    L = np.linalg.norm(D, axis=2)
    faces = []
    for cp, Pf, Df, Lf in zip(N, P, D, L):
        loop = [EdgeSpec(Line(Pf[q], Df[q]), 0.0, float(Lf[q]), Line2D(uv[q], (nxt[q] - uv[q]) / Lf[q]))
                for q in range(4)]
        faces.append(FaceSpec(NurbsSurface(cp, [0, 0, 1, 1], [0, 0, 1, 1], 1, 1), sense, [loop]))
    return faces


def sew_faces(faces: Sequence[FaceSpec], tol: Tolerance | None = None) -> Solid:
    """Sew a closed set of trimmed faces into a checked solid (see the module docstring).

    Parameters
    ----------
    faces : sequence of FaceSpec
    tol : Tolerance, optional
        ``tol.linear`` is the smallest distance at which edge ends are different vertices and
        curves different edges (edge tolerances given in the specs widen it for their edges).

    Returns
    -------
    Solid

    Raises
    ------
    InvalidInputError
        ``faces`` empty or not FaceSpecs.
    TopologyError
        A loop that does not close, an edge matching no other (open shell), more than one other
        (non-manifold), or one running the same way (inconsistent orientation), p-curves that
        cannot be made same-parameter, every face within its edges' tolerance of one vertex (the
        shell collapses to a point), a shell enclosing negative volume outside every other shell
        or directly inside another such, one enclosing positive volume directly inside another
        such (overlapping lumps), two shells too close to decide which holds the other, or any
        invariant the checker finds.

    Examples
    --------
    >>> from coons.topology.primitives import Box
    >>> box = Box(1, 2, 3)
    >>> again = sew_faces(face_specs(box)[::-1])
    >>> again.brep.n_faces, again.brep.n_edges, again.brep.n_vertices, bool(np.isclose(again.volume, 6.0))
    (6, 12, 8, True)
    """
    t = resolve(tol)
    faces = list(faces)
    if not faces:
        raise InvalidInputError("sew_faces needs at least one FaceSpec, got none")
    for i, f in enumerate(faces):
        if not isinstance(f, FaceSpec):
            raise InvalidInputError(f"faces[{i}] must be a FaceSpec, got {type(f).__name__}")
    uses = _Uses(faces, t)
    vertex, vpoint, vtol = _merge_vertices(uses, t)
    short = _degenerate_uses(uses, vertex, vpoint)
    if short.size:
        # Edges shorter than their tolerance (two crossings of intersection curves within it)
        # are collapsed into their vertex: their loops run on from the edge before to the one after.
        faces = _without_uses(faces, uses, short)
        if not faces:
            raise TopologyError(
                f"every face lies within its edges' tolerance (up to {float(uses.tol.max()):.3g}) of one vertex: "
                "the shell collapses to a point"
            )
        uses = _Uses(faces, t)
        vertex, vpoint, vtol = _merge_vertices(uses, t)
    _check_loops_close(uses, vertex, vpoint)
    pairs = _match_edges(uses, vertex, vpoint, t)
    solid = _assemble(faces, uses, vertex, vpoint, vtol, pairs, t)
    _remember_uses(solid.brep, faces, uses)
    return solid


class _Uses:
    """Flat arrays over all edge uses (coedges) in face, loop, position order.

    Gathered by :func:`_gathered_uses`: the rows of the faces the last sewing shared with this
    one (a Boolean's result sewn from its operand's faces) in one take from that sewing's
    arrays, the other faces' from the per-face tables of :func:`_face_uses` (cached per face
    spec): the faces a Boolean result carries over unchanged from its operand are not
    evaluated again.
    """

    def __init__(self, faces: list[FaceSpec], t: Tolerance) -> None:
        self.columns, self.values, self.counts = _gathered_uses(faces)
        (w, r, P, self.kind, self.frame, self.curve_id, self.own_tol, self.complete, self.spec, self.curve,
         self.pcurve, self.pcurve_id) = self.columns
        k = len(self.spec)
        self.face = np.repeat(np.arange(len(faces), dtype=np.int64), self.counts)
        self.loop, self.pos, self.loop_len = w[:, 0], w[:, 1], w[:, 2]
        self.t0, self.t1 = r[:, 0], r[:, 1]
        self.tol = np.maximum(r[:, 2], t.linear)
        self.start, self.end, self.mid = P[:, 0], P[:, 1], P[:, 2]
        # Index of the next use in the same loop.
        idx = np.arange(k)
        self.next = np.where(self.pos + 1 < self.loop_len, idx + 1, idx - self.pos)

    def name(self, i: int) -> str:
        return f"face {int(self.face[i])}, loop {int(self.loop[i])}, edge {int(self.pos[i])}"

    def __len__(self) -> int:
        return len(self.spec)


#: The columns of :class:`_FaceUses` gathered per use by :func:`_gathered_uses`, in this order.
_COLUMNS = ("where", "ranges", "points", "kind", "frame", "curve_id", "own_tol", "complete", "spec", "curve",
            "pcurve", "pcurve_id")


class _SewnUses:
    """The use columns of one sewing, for the next (:func:`_gathered_uses`): ``faces`` (held, so that
    their ids stay theirs), ``ids (F,)`` int64 their ids sorted and ``order (F,)`` the faces in that
    order; ``first, count (F,)`` each face's rows; ``values (F,)`` bool: the face's curves are all
    values (only those rows are taken again); ``columns`` (:data:`_COLUMNS`)."""

    __slots__ = ("faces", "ids", "order", "first", "count", "values", "columns")


#: The last sewing's :class:`_SewnUses`, of the B-rep it made.
_SEWN_USES = LastRecord()


def _remember_uses(b: BRep, faces: list[FaceSpec], uses: _Uses) -> None:
    """Keep the use columns of the sewing that made ``b`` for the next sewing (:func:`_gathered_uses`)."""
    rec = _SewnUses()
    rec.faces = tuple(faces)
    rec.ids, rec.order = id_index(rec.faces)
    rec.count = uses.counts
    rec.first = np.cumsum(rec.count) - rec.count
    rec.values, rec.columns = uses.values, uses.columns
    _SEWN_USES.keep(b, rec)


def _gathered_uses(faces: list[FaceSpec], names: Sequence[str] = _COLUMNS
                   ) -> tuple[list[np.ndarray], np.ndarray, np.ndarray]:
    """The columns ``names`` (of :data:`_COLUMNS`, all by default) over all uses of ``faces`` (face, loop,
    position order), read-only (the next sewing takes its rows from them, :func:`_remember_uses`), ``(F,)``
    bool: which faces' curves are all values, and ``(F,)`` int64 the uses per face.

    The faces of the last sewing (:data:`_SEWN_USES`; the very spec objects, matched by id while
    that sewing holds them) whose curves are values take their rows from its columns, all in one
    take; the others come from :func:`_face_uses`.  Either way the rows are those
    :func:`_face_uses` gives (its tables are functions of the face spec alone).  The Booleans' passes
    before sewing read their few columns of a result's faces so (the faces of its operand's sewing),
    not face by face.
    """
    n = len(faces)
    rec = _SEWN_USES.last()
    hit = np.zeros(n, dtype=bool)
    if rec is not None and n and rec.ids.size:
        df, same = found_by_id(faces, rec.ids, rec.order)
        hit = same & rec.values[df]
    miss = np.flatnonzero(~hit)
    mfaces = faces if miss.size == n else [faces[i] for i in miss.tolist()]
    mvalues = [False] * len(mfaces)
    tables = _face_uses(mfaces, mvalues) if mfaces else []
    mcount = np.array([x.where.shape[0] for x in tables], dtype=np.int64)
    if miss.size == n:  # nothing from the last sewing: the rows are the tables' in turn
        columns = [_read_only(np.concatenate([getattr(x, c) for x in tables])) for c in names]
        return columns, np.array(mvalues, dtype=bool), mcount
    count = np.empty(n, dtype=np.int64)
    count[hit] = rec.count[df[hit]]
    count[miss] = mcount
    # Each row's source among [the last sewing's rows; the missing faces' rows, in turn].
    src_first = np.empty(n, dtype=np.int64)
    src_first[hit] = rec.first[df[hit]]
    src_first[miss] = rec.columns[0].shape[0] + np.cumsum(mcount) - mcount
    src = np.repeat(src_first - (np.cumsum(count) - count), count) + np.arange(int(count.sum()))
    # (np.take along the rows: numpy's fancy index of the rows of a 2-D array costs several times more)
    columns = [_read_only(np.take(np.concatenate([rec.columns[_COLUMNS.index(c)]] + [getattr(x, c) for x in tables]),
                                  src, axis=0)) for c in names]
    values = np.ones(n, dtype=bool)
    values[miss] = mvalues
    return columns, values, count


#: Curve kinds of :class:`_FaceUses` (others are 0).
_LINE, _CIRCLE = 1, 2


class _FaceUses:
    """The edge uses of one face spec as arrays, in loop order (:func:`_face_uses`).

    ``where (k, 3)`` int64: loop, position in the loop and loop length of each use; ``ranges
    (k, 3)``: ``t0, t1`` and the use's own tolerance (``EdgeSpec.tol``, 0 for None); ``points
    (k, 3, 3)``: start, end and midpoint (the curve at ``t0``, ``t1`` and ``(t0 + t1) / 2``);
    ``kind (k,)``: the curve is a :class:`Line` (``_LINE``), a :class:`Circle` (``_CIRCLE``) or
    another curve (0); ``frame (k, 4)``: a line's origin or a circle's centre, and its radius (0
    otherwise), which :func:`_reach` bounds the curves by; ``curve_id (k,)`` int64: ``id`` of each
    use's curve (the spec holds the curve, so the id stays its own); ``own_tol (k,)``: the use's
    tolerance, NaN for None; ``complete (k,)`` bool: the use has a curve and a p-curve; ``spec,
    curve, pcurve (k,)`` object: the use (its :class:`EdgeSpec`), its curve and p-curve (None), and
    ``pcurve_id (k,)`` int64 the p-curve's ``id``: sewing gathers the uses and the B-rep's geometry
    from these columns (:func:`_gathered_uses`, :func:`_assemble`), not use by use.  All read-only.
    """

    __slots__ = ("where", "ranges", "points", "kind", "frame", "curve_id", "own_tol", "complete", "spec", "curve",
                 "pcurve", "pcurve_id")


#: Face spec -> its :class:`_FaceUses`.  A spec is immutable and so are its curves when they are
#: values (frozen dataclasses, as every curve of coons): the table never goes stale, and the
#: faces a Boolean result carries over from an operand (the same spec objects) are read once
#: for a chain of Booleans.  Entries die with their spec.
_FACE_USES = IdentityMemo()


def _face_uses(faces: Sequence[FaceSpec], values: list[bool] | None = None) -> list[_FaceUses]:
    """The :class:`_FaceUses` of each face, assembled from per-loop tables (:data:`_LOOP_USES`);
    the loops not cached yet gathered together (:func:`_use_rows`).  A face of many loops whose
    first loops are, use for use, those of a face cached before (:func:`_kept_uses`: a plate's top
    gaining a hole) takes that face's rows for them in one piece (a row is a function of its use
    alone, its loop number of the loops' order) and is assembled from its other loops only.

    A face or loop is cached only when all its curves are values (:func:`~coons.topology._memo.is_value`);
    ``values``, a list of ``len(faces)``, is set to which faces are.

    Raises
    ------
    InvalidInputError
        A curve that cannot be evaluated on its use's range or gives non-finite points (named by
        face, loop and edge).
    """
    out: list[_FaceUses | None] = _FACE_USES.get_many(faces)
    missing = [i for i, x in enumerate(out) if x is None]
    if values is not None:
        values[:] = [x is not None for x in out]
    if not missing:
        return out  # type: ignore[return-value]
    parts: list[list] = []
    new_spec: list[EdgeSpec] = []
    new_slots: list[tuple[int, int]] = []
    # (per new loop its face, number and length: the uses' places, only to name a bad one, made in arrays
    # below, not a tuple per use)
    new_face: list[int] = []
    new_len: list[int] = []
    # Per missing face, the number of its first loops taken from a kept face and that face's table.
    kept: dict[int, tuple[int, _FaceUses]] = {}
    for p, fi in enumerate(missing):
        got: list = []
        loops = faces[fi].loops
        n0 = 0
        if len(loops) > _PREFIX_LOOPS:  # (extending a face of _PREFIX_LOOPS or more)
            prefix = _kept_uses(faces[fi])
            if prefix is not None:
                kept[p] = prefix
                n0 = prefix[0]
        for li, loop in enumerate(loops[n0:], n0):
            c = _LOOP_USES.get(loop[0]) if loop else None
            if c is not None and len(c[0]) == len(loop) - 1 and all(map(operator.is_, c[0], loop[1:])):
                got.append(c)
                continue
            got.append(None)
            new_slots.append((p, li))
            new_face.append(fi)
            new_len.append(len(loop))
            new_spec.extend(loop)
        parts.append(got)
    if new_slots:
        n_in = np.array(new_len, dtype=np.int64)
        w = np.stack([np.repeat(np.array(new_face, dtype=np.int64), n_in),
                      np.repeat(np.array([li for _, li in new_slots], dtype=np.int64), n_in),
                      np.arange(len(new_spec)) - np.repeat(np.cumsum(n_in) - n_in, n_in), np.repeat(n_in, n_in)], axis=1)
        R = _use_rows(new_spec, w) if new_spec else np.empty((0, 17))
        # (all values, tested once per curve type, as is usual; else use by use)
        value = [True] * len(new_spec) if all_values([e.curve for e in new_spec]) else [is_value(e.curve) for e in new_spec]
        curve_id = np.array([id(e.curve) for e in new_spec], dtype=np.int64)
        own_tol = np.array([np.nan if e.tol is None else e.tol for e in new_spec], dtype=np.float64)
        complete = np.array([e.curve is not None and e.pcurve is not None for e in new_spec], dtype=bool)
        # (read-only once: their slices, each loop's rows, are read-only views)
        R, curve_id, own_tol, complete = map(_read_only, (R, curve_id, own_tol, complete))
        at = 0
        keep_keys, keep = [], []
        for p, li in new_slots:
            loop = faces[missing[p]].loops[li]
            sl = slice(at, at + len(loop))
            at += len(loop)
            c = (tuple(loop[1:]), R[sl], curve_id[sl], own_tol[sl], complete[sl], all(value[sl]))
            parts[p][li - (kept[p][0] if p in kept else 0)] = c
            if loop and c[5]:
                keep_keys.append(loop[0])
                keep.append(c)
        _LOOP_USES.set_many(keep_keys, keep)
    # All missing faces in one pass, each face's table a view of the pass's arrays (a cached face
    # keeps that pass's rows alive: a few kB per face sewn together with it).
    own = [faces[fi].loops[kept[p][0]:] if p in kept else faces[fi].loops for p, fi in enumerate(missing)]
    loops = [c for got in parts for c in got]
    per_face = np.array([len(got) for got in parts], dtype=np.int64)
    lens = np.array([c[1].shape[0] for c in loops], dtype=np.int64)
    n = int(lens.sum())
    R = np.concatenate([c[1] for c in loops]) if loops else np.empty((0, 17))
    loop_first = np.cumsum(lens) - lens
    face_first_loop = np.cumsum(per_face) - per_face
    loop_in_face = np.arange(lens.size) - np.repeat(face_first_loop, per_face)
    if kept:  # (a face's loops after its kept prefix are numbered after it)
        loop_in_face += np.repeat([kept[p][0] if p in kept else 0 for p in range(len(missing))], per_face)
    where = _read_only(np.stack([np.repeat(loop_in_face, lens), np.arange(n) - np.repeat(loop_first, lens),
                                 np.repeat(lens, lens)], axis=1))
    points = _read_only(R[:, :9].reshape(n, 3, 3))
    ranges = _read_only(R[:, 9:12].copy())
    kind = _read_only(R[:, 12].astype(np.int8))
    frame = _read_only(R[:, 13:].copy())
    curve_id = _read_only(np.concatenate([c[2] for c in loops]) if loops else np.empty(0, dtype=np.int64))
    own_tol = _read_only(np.concatenate([c[3] for c in loops]) if loops else np.empty(0))
    complete = _read_only(np.concatenate([c[4] for c in loops]) if loops else np.empty(0, dtype=bool))
    bounds = np.concatenate([[0], np.cumsum([sum(map(len, loops_p)) for loops_p in own])]).tolist()
    every = [e for loops_p in own for loop in loops_p for e in loop]  # (the rows' order)
    spec = _read_only(np.fromiter(every, dtype=object, count=n))
    curve = _read_only(np.fromiter((e.curve for e in every), dtype=object, count=n))
    pcurve = _read_only(np.fromiter((e.pcurve for e in every), dtype=object, count=n))
    pcurve_id = _read_only(np.fromiter(map(id, pcurve), dtype=np.int64, count=n))
    keep_keys, keep = [], []
    for p, fi in enumerate(missing):
        a, b = bounds[p], bounds[p + 1]
        x = _FaceUses()
        x.where, x.points, x.ranges, x.kind = where[a:b], points[a:b], ranges[a:b], kind[a:b]
        x.frame, x.curve_id, x.own_tol, x.complete = frame[a:b], curve_id[a:b], own_tol[a:b], complete[a:b]
        x.spec, x.curve, x.pcurve, x.pcurve_id = spec[a:b], curve[a:b], pcurve[a:b], pcurve_id[a:b]
        if p in kept:  # the kept face's rows first, then these
            old = kept[p][1]
            for name in _FaceUses.__slots__:
                setattr(x, name, _read_only(np.concatenate([getattr(old, name), getattr(x, name)])))
        out[fi] = x
        if all(c[5] for c in parts[p]):
            keep_keys.append(faces[fi])
            keep.append(x)
            if values is not None:
                values[fi] = True
    _FACE_USES.set_many(keep_keys, keep)
    _remember_kept_uses(keep_keys)
    return out  # type: ignore[return-value]


#: Loops from which a face's table is kept for a face that extends it by new loops (:func:`_kept_uses`),
#: and how many such faces are kept per surface (as the checker's ``_PASSED_ON``).
_PREFIX_LOOPS, _PREFIX_KEPT = 16, 4
#: Surface -> weak references to the last few face specs of :data:`_PREFIX_LOOPS` loops or more
#: on it whose :class:`_FaceUses` are cached (:data:`_FACE_USES`): a plate's top gaining a hole
#: every cut keeps the very uses of its other loops.
_KEPT_ON = IdentityMemo()


def _kept_uses(spec: FaceSpec) -> tuple[int, _FaceUses] | None:
    """``(n, table)``: the cached :class:`_FaceUses` of the face with the most loops recorded on
    ``spec``'s surface (:data:`_KEPT_ON`) whose ``n`` loops (fewer than ``spec``'s) are, use for
    use, the first loops of ``spec``; None when there is none."""
    refs = _KEPT_ON.get(spec.surface)
    if not refs:
        return None
    olds = [old for old in (ref() for ref in refs) if old is not None and 0 < len(old.loops) < len(spec.loops)]
    for old in sorted(olds, key=lambda x: -len(x.loops)):  # (the longest prefix first)
        n = len(old.loops)
        if (list(map(len, old.loops)) == list(map(len, spec.loops[:n]))
                and all(map(operator.is_, chain.from_iterable(old.loops), chain.from_iterable(spec.loops[:n])))):
            x = _FACE_USES.get(old)
            if x is not None:
                return n, x
    return None


def _remember_kept_uses(specs: list[FaceSpec]) -> None:
    """Record in :data:`_KEPT_ON` the specs of ``specs`` (whose tables :data:`_FACE_USES` holds) of
    :data:`_PREFIX_LOOPS` loops or more, on their surface (when a value)."""
    for spec in specs:
        if len(spec.loops) >= _PREFIX_LOOPS and is_value(spec.surface):
            refs = [r for r in _KEPT_ON.get(spec.surface, ()) if r() is not None][-(_PREFIX_KEPT - 1):]
            _KEPT_ON.set(spec.surface, refs + [weakref.ref(spec)])


#: First use of a loop -> ``(the other uses, rows (k, 17), curve ids, own tolerances, complete, all
#: curves values)``: the parts of :class:`_FaceUses` that do not depend on the loop's place in its
#: face (identity-checked use by use on look-up).  A plate's top gaining a hole keeps its other
#: loops.  The value holds the loop's other uses, never its key (else the entry would never die).
_LOOP_USES = IdentityMemo()


#: Edge use -> its row of :func:`_use_rows` (read-only), for the uses whose curve is a value: the
#: faces a Boolean changes (a plate's top gaining a hole) keep most of their uses.
_USE_ROWS = IdentityMemo()


def _use_rows(spec: list[EdgeSpec], w: np.ndarray) -> np.ndarray:
    """Per use, the row ``(17,)``: start, end and midpoint (9, the curve at ``t0``, ``t1`` and
    ``(t0 + t1) / 2``), ``t0, t1`` and the use's own tolerance (0 for None), its curve kind and
    frame (:class:`_FaceUses`).  Remembered per use (:data:`_USE_ROWS`); the others computed
    together: lines and circles (most edges) in one batch
    (:func:`~coons.kernel.onsurface.evaluate_curves`, their own formulas element by element), each
    distinct curve and range once (:func:`_distinct_ranges`: the two uses of an edge, one per face,
    run over one range opposite ways round, and their rows differ only in the order of the ends);
    any other curve in one evaluation per distinct curve object.  ``w (k, 4)``: face, loop,
    position and loop length of each use, to name a bad one.

    Raises
    ------
    InvalidInputError
        A curve that cannot be evaluated on its use's range or gives non-finite points.
    """
    k = len(spec)
    got = _USE_ROWS.get_many(spec)
    need = [i for i, g in enumerate(got) if g is None]
    out = np.empty((k, 17))
    have = np.ones(k, dtype=bool)
    have[need] = False
    if have.any():
        out[have] = np.concatenate([g for g in got if g is not None]).reshape(-1, 17)
    if not need:
        return out
    sub = [spec[i] for i in need]
    curves = [e.curve for e in sub]
    wn = w[need]
    n = len(sub)
    # (a column at a time: numpy reads a list of tuples slowly)
    t0 = np.fromiter((e.t0 for e in sub), dtype=np.float64, count=n)
    t1 = np.fromiter((e.t1 for e in sub), dtype=np.float64, count=n)
    ranges = np.stack([t0, t1, np.fromiter((e.tol or 0.0 for e in sub), dtype=np.float64, count=n)], axis=1)

    def name(i: int) -> str:
        return f"face {int(wn[i, 0])}, loop {int(wn[i, 1])}, edge {int(wn[i, 2])}"

    P = np.empty((n, 3, 3))
    kind = np.zeros(n)
    frame = np.zeros((n, 4))
    simple = np.fromiter((type(c) in BATCHED_CURVES for c in curves), dtype=bool, count=n)
    rs = np.flatnonzero(simple)
    if rs.size:
        rep, of, forward = _distinct_ranges(np.fromiter(map(id, curves), dtype=np.int64, count=n)[rs], t0[rs], t1[rs])
        reps = [curves[i] for i in rs[rep].tolist()]
        kind[rs], frame[rs] = (x[of] for x in _curve_frames(reps))
        # (each distinct range from its lower end: a use's own ends are those parameters, bit for bit)
        lo, hi = np.where(forward, t0[rs], t1[rs])[rep], np.where(forward, t1[rs], t0[rs])[rep]
        tt = np.stack([lo, hi, 0.5 * (lo + hi)], axis=1)
        Q = evaluate_curves(reps, tt) if np.isfinite(tt).all() else None
        if Q is not None and np.isfinite(Q).all():
            # (a use running down its range takes the upper end first)
            P[rs] = Q[of[:, None], np.where(forward[:, None], [0, 1, 2], [1, 0, 2])]
        else:  # the per-curve path below names the use whose curve or range is bad
            simple[:] = False
    groups: dict[int, list[int]] = {}
    for i in np.flatnonzero(~simple).tolist():
        groups.setdefault(id(sub[i].curve), []).append(i)
    for rows in groups.values():
        r = np.asarray(rows)
        curve = sub[rows[0]].curve
        tt = np.concatenate([t0[r], t1[r], 0.5 * (t0[r] + t1[r])])
        try:
            Q = np.asarray(curve.evaluate(tt), dtype=np.float64).reshape(3, r.size, 3)
        except (ValueError, TypeError, ArithmeticError) as exc:
            raise InvalidInputError(f"{name(rows[0])}: its curve cannot be evaluated on its range: {exc}") from None
        if not np.all(np.isfinite(Q)):
            raise InvalidInputError(f"{name(rows[0])}: its curve evaluates to non-finite points")
        P[r] = Q.transpose(1, 0, 2)
    new = np.concatenate([P.reshape(n, 9), ranges, kind[:, None], frame], axis=1)
    out[need] = new
    # (``new`` made read-only in place: its rows are read-only views; a kept row holds the batch, 136 bytes a use)
    rows = list(_read_only(new))
    if all_values(curves):  # (tested once per curve type)
        _USE_ROWS.set_many(sub, rows)
    else:
        keep = [i for i, c in enumerate(curves) if is_value(c)]
        _USE_ROWS.set_many([sub[i] for i in keep], [rows[i] for i in keep])
    return out


def _distinct_ranges(curve_id: np.ndarray, t0: np.ndarray, t1: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The distinct (curve, range) of uses ``(k,)`` (curve ids and ends), whichever way round a use runs:
    ``rep (g,)`` one use of each, ``of (k,)`` each use's, and ``forward (k,)`` whether a use's range is
    ``t0 <= t1``; two uses share one when their curves are one object and their ends the same floats bit
    for bit (``0.0`` and ``-0.0`` apart: a row holds the use's own ends; the ends grouped as int64)."""
    forward = t0 <= t1
    rep, of = row_groups(curve_id, np.where(forward, t0, t1).view(np.int64), np.where(forward, t1, t0).view(np.int64))
    return rep, of, forward


def _curve_frames(curves: list) -> tuple[np.ndarray, np.ndarray]:
    """The curve kind ``(k,)`` and frame ``(k, 4)`` columns of :class:`_FaceUses` of each of ``curves``: a
    line's origin, a circle's centre and radius, zeros for another curve."""
    k = len(curves)
    kind = np.fromiter((_LINE if type(c) is Line else _CIRCLE if type(c) is Circle else 0 for c in curves),
                       dtype=np.float64, count=k)
    frame = np.zeros((k, 4))
    for code, attr in ((_LINE, "origin"), (_CIRCLE, "center")):
        rows = np.flatnonzero(kind == code)
        if rows.size:
            frame[rows, :3] = [getattr(curves[i], attr) for i in rows.tolist()]
            if code == _CIRCLE:
                frame[rows, 3] = [float(curves[i].radius) for i in rows.tolist()]
    return kind, frame


def use_points(faces: Sequence[FaceSpec]) -> np.ndarray:
    """Start, end and midpoint ``(k, 3, 3)`` of every edge use of ``faces`` in face, loop, position
    order, as :func:`sew_faces` sees them (cached per face spec, see :func:`_face_uses`)."""
    tables = _face_uses(faces)
    return np.concatenate([x.points for x in tables]) if tables else np.empty((0, 3, 3))


def point_clusters(X: np.ndarray, tol: np.ndarray, rank: np.ndarray | None = None) -> np.ndarray:
    """Cluster labels ``(n,)`` of points ``X (n, 3)``: the connected components of the pairs of points
    within ``max(tol_i, tol_j)`` of each other, numbered in the order of their first point by
    ``rank (n,)`` (default: the points' order).

    Points at exactly the same place (the ends of the uses of one curve object meeting there:
    most of them) are one point to the pair search (:func:`_close_pairs`), with the largest of
    their tolerances (two points are within ``max(tol_i, tol_j)`` of some pair of their copies
    exactly when within the larger of those two maxima), so the labels are those of the
    components of all the points.
    Sewing's vertices and the Booleans' T-junction and fuse passes cluster with it.
    """
    n = X.shape[0]
    if n == 0:
        return np.empty(0, dtype=np.int64)
    order = np.lexsort((X[:, 2], X[:, 1], X[:, 0]))
    Xs = X[order]
    ne = Xs[1:] != Xs[:-1]
    distinct = np.concatenate([[True], ne[:, 0] | ne[:, 1] | ne[:, 2]])  # (columns or-ed: numpy reduces a short axis row by row)
    at = np.flatnonzero(distinct)
    point_of = np.empty(n, dtype=np.int64)
    point_of[order] = np.cumsum(distinct) - 1
    U = Xs[at]
    utol = np.maximum.reduceat(np.asarray(tol, dtype=np.float64)[order], at)
    pairs = _close_pairs(U, float(utol.max()))
    if pairs.size:
        d = np.linalg.norm(U[pairs[:, 0]] - U[pairs[:, 1]], axis=1)
        pairs = pairs[d <= np.maximum(utol[pairs[:, 0]], utol[pairs[:, 1]])]
    m = U.shape[0]
    nc, label = components(m, pairs[:, 0], pairs[:, 1])
    # Each component's first rank: the least rank of each distinct point (its copies are consecutive in
    # ``order``, one reduceat), then the least over the component's distinct points (a minimum in any
    # order; a fifth of the points to ``np.minimum.at``, several times a reduceat's cost per element).
    first = np.full(nc, n, dtype=np.int64)
    np.minimum.at(first, label, np.minimum.reduceat((np.arange(n) if rank is None else np.asarray(rank))[order], at))
    out = np.empty(nc, dtype=np.int64)
    out[np.argsort(first, kind="stable")] = np.arange(nc)
    return out[label[point_of]]


#: Candidate pairs per point up to which :func:`_close_pairs` sweeps along x (beyond: a k-d tree).
_SWEEP_PAIRS = 16


def _close_pairs(U: np.ndarray, r: float) -> np.ndarray:
    """Pairs ``(p, 2)`` int64 ``[i, j]``, ``i < j``, of the distinct points ``U (m, 3)`` (sorted by x,
    as :func:`point_clusters` sorts them), among which are all pairs within ``r`` of each other (the
    caller keeps those within their tolerance).

    A sweep along x: each point against the points after it up to ``x + 2r`` (a bound that the
    rounding of ``x + 2r`` cannot bring below any ``x_j <= x + r``), kept when ``|dy|`` and ``|dz|``
    are at most ``2r`` too.  A model's vertices share coordinates (a grid of holes: whole columns
    of vertices on one x, all on one of two z), on which the k-d tree's rectangles do not separate
    and its pair search walks several hundred thousand instructions for a few hundred points;
    along x only points on one x meet.  Where more than ``_SWEEP_PAIRS`` pairs per point would be
    tried, or a coordinate is not finite, ``scipy``'s ``cKDTree.query_pairs`` answers (its pairs
    within ``r``, which the caller filters the same way)."""
    m = U.shape[0]
    x = U[:, 0]
    count = np.searchsorted(x, x + 2.0 * r, side="right") - np.arange(1, m + 1)
    total = int(count.sum())
    if total > _SWEEP_PAIRS * m or not np.isfinite(U).all():
        from scipy.spatial import cKDTree

        return cKDTree(U).query_pairs(r=r, output_type="ndarray")
    i = np.repeat(np.arange(m), count)
    j = np.arange(total) - np.repeat(np.cumsum(count) - count - np.arange(1, m + 1), count)
    y, z = U[:, 1].copy(), U[:, 2].copy()
    near = ((np.abs(y.take(j) - np.repeat(y, count)) <= 2.0 * r)
            & (np.abs(z.take(j) - np.repeat(z, count)) <= 2.0 * r))
    return np.stack([i[near], j[near]], axis=1)


def _merge_vertices(uses: _Uses, t: Tolerance) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Cluster the use ends into vertices.

    Returns
    -------
    vertex : (k, 2) int64, start and end vertex of each use
    points : (V, 3) float64, cluster means
    tols : (V,) float64, ``max(tol.linear, largest distance of a member from the mean)``
    """
    k = len(uses)
    X = np.concatenate([uses.start, uses.end])
    ptol = np.concatenate([uses.tol, uses.tol])
    # Vertex ids follow the input order: the start of use i before its end.
    label = point_clusters(X, ptol, rank=np.concatenate([np.arange(k) * 2, np.arange(k) * 2 + 1]))
    nv = int(label.max()) + 1 if label.size else 0
    count = np.bincount(label, minlength=nv)
    # Per coordinate (bincount adds in index order, as np.add.at did: the same sums, a fifth of the
    # time; so is the distance, written out: numpy's norm over a short axis runs row by row).
    mean = np.stack([np.bincount(label, weights=X[:, i], minlength=nv) for i in range(3)], axis=1)
    mean /= count[:, None]
    d = X - mean[label]
    spread = np.zeros(nv)
    np.maximum.at(spread, label, _norms(d))
    return np.stack([label[:k], label[k:]], axis=1), mean, np.maximum(spread, t.linear)


def _degenerate_uses(uses: _Uses, vertex: np.ndarray, vpoint: np.ndarray) -> np.ndarray:
    """Indices of the uses whose ends are one vertex and whose midpoint lies within their tolerance
    of it: edges shorter than their tolerance (a closed curve's midpoint lies far from its ends)."""
    closed = np.flatnonzero(vertex[:, 0] == vertex[:, 1])
    if closed.size == 0:
        return closed
    gap = _norms(uses.mid[closed] - vpoint[vertex[closed, 0]])
    return closed[gap <= uses.tol[closed]]


def _without_uses(faces: list[FaceSpec], uses: _Uses, drop: np.ndarray) -> list[FaceSpec]:
    """The faces with the uses ``drop`` (indices into ``uses``) taken out of their loops; a loop left
    empty goes, and a face whose outer loop goes goes with its holes (all of it lies within the
    tolerance of one vertex)."""
    gone = np.zeros(len(uses), dtype=bool)
    gone[drop] = True
    first = np.cumsum(uses.counts) - uses.counts
    out = []
    for f, (face, start) in enumerate(zip(faces, first.tolist())):
        if not gone[start : start + uses.counts[f]].any():
            out.append(face)
            continue
        loops, i = [], start
        for k, loop in enumerate(face.loops):
            kept = tuple(e for j, e in enumerate(loop) if not gone[i + j])
            i += len(loop)
            if not kept and k == 0:
                break
            if kept:
                loops.append(kept)
        else:
            out.append(FaceSpec._trusted(face.surface, face.sense, tuple(loops)))
    return out


def _check_loops_close(uses: _Uses, vertex: np.ndarray, vpoint: np.ndarray) -> None:
    """Each use must end at the vertex where the next use of its loop starts.

    Raises
    ------
    TopologyError
        Naming the first use whose end is not the next use's start, with the gap.
    """
    bad = np.flatnonzero(vertex[:, 1] != vertex[uses.next, 0])
    if bad.size:
        i = int(bad[0])
        j = int(uses.next[i])
        gap = float(np.linalg.norm(uses.end[i] - uses.start[j]))
        raise TopologyError(
            f"{uses.name(i)} ends at {uses.end[i].tolist()} but the next edge of the loop starts at "
            f"{uses.start[j].tolist()} (gap {gap:.3g} > tolerance {max(uses.tol[i], uses.tol[j]):.3g}); loops must close"
        )


def _match_edges(uses: _Uses, vertex: np.ndarray, vpoint: np.ndarray, t: Tolerance) -> np.ndarray:
    """Pair the uses into edges: ``(E, 2)`` use indices, the first use of each pair first.

    Uses are grouped by their unordered vertex pair; inside a group, two uses are one edge when
    their curves agree at the midpoints (:func:`_curves_agree`).

    Raises
    ------
    TopologyError
        An unmatched use (open shell), a use matched more than once (non-manifold) or a pair
        running the same way (inconsistent orientation).
    """
    vs, ve = vertex[:, 0], vertex[:, 1]
    closed = vs == ve  # (closed curves: sew_faces collapsed the uses shorter than their tolerance)
    lo, hi = np.minimum(vs, ve), np.maximum(vs, ve)
    # The uses by (lo, hi), ties in use order: one stable sort of one integer key (not a lexsort of three).
    key = lo * (int(hi.max()) + 1) + hi
    order = np.argsort(key, kind="stable")
    key = key[order]
    start = np.flatnonzero(np.concatenate([[True], key[1:] != key[:-1]]))
    stop = np.append(start[1:], key.size)
    # The common case at once: two uses between two distinct vertices, running opposite ways,
    # with coincident midpoints (one curve shared by both faces) are one edge, exactly as the
    # general path below would find; every other group goes through it.
    two = (stop - start) == 2
    i2, j2 = order[start[two]], order[start[two] + 1]
    D = uses.mid[i2] - uses.mid[j2]
    fast = ((_norms(D) <= np.maximum(uses.tol[i2], uses.tol[j2]))
            & ~closed[i2] & (vs[i2] == ve[j2]))
    pairs = [np.stack([i2[fast], j2[fast]], axis=1)]
    samples: dict = {}  # first-round samples of _distance_to_curve, shared by the uses of one curve
    slow = np.ones(start.size, dtype=bool)
    slow[two.nonzero()[0][fast]] = False
    group_of = np.cumsum(np.concatenate([[True], key[1:] != key[:-1]])) - 1  # group of each sorted use
    reach = _reach(uses, order[slow[group_of]]) if slow.any() else None
    four = np.flatnonzero(slow & ((stop - start) == 4))
    if four.size:
        got, done = _match_fours(uses, vertex, closed, order[start[four, None] + np.arange(4)], reach)
        pairs.append(got)
        slow[four[done]] = False
    if slow.any():  # (the general path's bounds as Python floats, read pair by pair)
        reach = reach[0].tolist(), reach[1].tolist()
    for s, e in zip(start[slow], stop[slow]):
        group = [int(x) for x in order[s:e]]
        for comp in _agreeing_components(uses, group, samples, reach):
            _require_pair(uses, comp, vertex)
            pairs.append(np.asarray([comp], dtype=np.int64))
    out = np.concatenate(pairs).astype(np.int64, copy=False).reshape(-1, 2)
    return out[np.argsort(out[:, 0], kind="stable")]


#: The three ways of pairing four uses, as index pairs into a group of four (ascending use index).
_MATCHINGS = np.array([[[0, 1], [2, 3]], [[0, 2], [1, 3]], [[0, 3], [1, 2]]])


def _match_fours(uses: _Uses, vertex: np.ndarray, closed: np.ndarray, G: np.ndarray,
                 reach: tuple[np.ndarray, np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """Groups of four uses (two edges between the same two vertices, as the halves of a hole) at once.

    A group is decided here only when every pair's verdict of :func:`_curves_agree` is certain
    without measuring: the pairs of one of the three matchings have midpoints within
    ``(1 - 1e-12)`` of their tolerance (coincident, True whichever way the norm is rounded), and
    the four other pairs are beyond reach (the bound of :func:`_curves_agree` with its margin,
    False).  The union–find then yields exactly that matching; each pair must also pass
    :func:`_require_pair` (distinct end vertices, opposite directions).  Every other group is
    left to the general path.

    Parameters
    ----------
    G : (n, 4) int64, the uses of each group in ascending order

    Returns
    -------
    pairs : (m, 2) int64, the edges of the decided groups
    done : (n,) bool, which groups were decided
    """
    radius, scale = reach
    a = G[:, [0, 0, 0, 1, 1, 2]]  # the six pairs of a group, numbered as in ``col``
    b = G[:, [1, 2, 3, 2, 3, 3]]
    thr = np.maximum(uses.tol[a], uses.tol[b])
    D = uses.mid[a] - uses.mid[b]
    # (the sum over the short last axis written out: numpy reduces it row by row, here the same
    # floats, left to right, several times faster)
    d = _norms(D)
    # A few ulps separate this norm from np.linalg.norm's: 1e-12 relative keeps both on one side.
    same = d <= thr * (1.0 - 1e-12)
    apart = (d > thr * (1.0 + 1e-12)) & (d - np.minimum(radius[a], radius[b]) > thr + 1e-9 * (1.0 + scale[a] + scale[b]))
    col = {(0, 1): 0, (0, 2): 1, (0, 3): 2, (1, 2): 3, (1, 3): 4, (2, 3): 5}
    done = np.zeros(G.shape[0], dtype=bool)
    which = np.full(G.shape[0], -1)
    for m, ((p, q), (r, s)) in enumerate(_MATCHINGS.tolist()):
        inside = [col[(p, q)], col[(r, s)]]
        outside = [c for c in range(6) if c not in inside]
        ok = same[:, inside[0]] & same[:, inside[1]]
        for c in outside:
            ok &= apart[:, c]
        which[ok] = m
        done |= ok
    rows = np.flatnonzero(done)
    M = _MATCHINGS[which[rows]]  # (k, 2, 2) positions in the group
    P = np.take_along_axis(G[rows][:, None, :], M, axis=2)  # (k, 2, 2) use indices, first < second
    i, j = P[..., 0], P[..., 1]
    good = ~closed[i] & (vertex[i, 0] == vertex[j, 1])
    ok = good.all(axis=1)
    done[rows[~ok]] = False  # _require_pair raises there: the general path names the fault
    return P[ok].reshape(-1, 2), done


def _reach(uses: _Uses, rows: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """For the uses ``rows``, a bound on how far each curve strays from its midpoint, and the size of its numbers.

    ``radius[i]`` bounds the distance from ``uses.mid[i]`` to every point of the use's curve over
    its range: half the range for a (unit-speed) line, ``min(r · range / 2, 2 r)`` for a circle
    (arc length from the midpoint to an end, and the diameter); ``inf`` for any other curve and
    any use not in ``rows`` (no bound, the distance is then always measured).  ``scale[i]`` is
    the magnitude of the coordinates and parameters that went into the use's points, for a
    round-off margin.  Arrays ``(len(uses),)``.
    """
    k = len(uses)
    radius = np.full(k, math.inf)
    scale = np.full(k, math.inf)
    rows = np.asarray(rows, dtype=np.int64)
    kind = uses.kind[rows]
    half = 0.5 * np.abs(uses.t1[rows] - uses.t0[rows])
    base = _abs_max3(uses.mid[rows]) + np.maximum(np.abs(uses.t0[rows]), np.abs(uses.t1[rows]))
    for code in (_LINE, _CIRCLE):
        sel = np.flatnonzero(kind == code)
        if not sel.size:
            continue
        r = rows[sel]
        if code == _LINE:
            radius[r] = half[sel]
            scale[r] = base[sel] + _abs_max3(uses.frame[r, :3])
        else:
            R = uses.frame[r, 3]
            radius[r] = np.minimum(R * half[sel], 2.0 * R)
            scale[r] = base[sel] + _abs_max3(uses.frame[r, :3]) + R
    return radius, scale


def _abs_max3(X: np.ndarray) -> np.ndarray:
    """``np.abs(X).max(axis=1)`` of ``X (n, 3)``, column by column (a reduction over the short axis
    runs row by row; a maximum is exact either way)."""
    A = np.abs(X)
    return np.maximum(np.maximum(A[:, 0], A[:, 1]), A[:, 2])


def _agreeing_components(uses: _Uses, group: list[int], samples: dict | None = None,
                         reach: tuple[list[float], list[float]] | None = None) -> list[list[int]]:
    """Partition uses joining the same vertices into sets whose curves agree (union–find).

    ``samples`` caches the first sampling round of :func:`_distance_to_curve` per curve and range;
    ``reach`` (:func:`_reach`) lets :func:`_curves_agree` reject far-apart curves without measuring.
    """
    parent = list(range(len(group)))

    def find(a: int) -> int:
        while parent[a] != a:
            parent[a] = parent[parent[a]]
            a = parent[a]
        return a

    for x in range(len(group)):
        for y in range(x + 1, len(group)):
            if find(x) != find(y) and _curves_agree(uses, group[x], group[y], samples, reach):
                parent[find(x)] = find(y)
    comps: dict[int, list[int]] = {}
    for x in range(len(group)):
        comps.setdefault(find(x), []).append(group[x])
    return sorted(comps.values(), key=lambda c: c[0])


def _curves_agree(uses: _Uses, i: int, j: int, samples: dict | None = None,
                  reach: tuple[list[float], list[float]] | None = None) -> bool:
    """Whether uses ``i`` and ``j`` lie on one curve: each midpoint within tolerance of the other curve.

    With ``reach`` (:func:`_reach`), midpoints farther apart than both curves can reach from
    their own midpoints plus the tolerance are decided without measuring: by the triangle
    inequality ``dist(mid_i, curve_j) >= |mid_i - mid_j| - radius_j`` (and the same with i, j
    swapped), so when that bound exceeds ``thr`` by more than any round-off of the measured
    distance could, the measurement would have said False too.
    """
    thr = max(uses.tol[i], uses.tol[j])
    d = np.linalg.norm(uses.mid[i] - uses.mid[j])
    if d <= thr:
        return True  # same parametric midpoint (the common case: a shared curve object)
    if reach is not None:
        radius, scale = reach
        # 1e-9 relative to the numbers involved is far above the few ulps of round-off in the
        # measured distance (closed forms of lines and circles), so the shortcut never decides
        # a case the measurement would decide the other way.
        margin = 1e-9 * (1.0 + scale[i] + scale[j])
        if float(d) - min(radius[i], radius[j]) > thr + margin:
            return False
    return (_distance_to_curve(uses.mid[i], uses.spec[j], stop=thr, samples=samples) <= thr
            and _distance_to_curve(uses.mid[j], uses.spec[i], stop=thr, samples=samples) <= thr)


def _distance_to_curve(p: np.ndarray, spec: EdgeSpec, n: int = 33, rounds: int = 8, stop: float | None = None,
                       samples: dict | None = None) -> float:
    """Distance from ``p`` to ``spec.curve`` over its range: dense samples, then zooming on the nearest.

    Each round samples ``n`` parameters and shrinks the bracket around the nearest sample to two
    sample steps, so the parameter error falls by ``(n - 1) / 2`` per round.  The distance error
    is quadratic in it near a minimum off the curve but linear for a point on the curve (the
    nearest sample is up to half a step away along it), so 8 rounds bring the step to
    ``range · 16⁻⁸ / 32 ≈ 7e-12 range``, below any tolerance.  Only evaluation is needed, so any
    curve type works.  With ``stop``, a point farther from the first samples than ``stop`` plus
    the largest sample spacing returns that first estimate at once (only "is it within stop"
    matters to the caller).  ``samples``, a dict, caches the first round's samples and spacing
    per curve object and range (the uses of one edge share both; a group of uses between two
    vertices probes each curve several times).  Lines and circles take their closed forms
    instead (:data:`_EXACT_DISTANCE`: the projection clamped to the range; the split halves of
    every hole's circles in a plate meet at the same two vertices, so sewing asks this often).
    """
    lo, hi = min(spec.t0, spec.t1), max(spec.t0, spec.t1)
    exact = _EXACT_DISTANCE.get(type(spec.curve))
    if exact is not None:
        return exact(spec.curve, np.asarray(p, dtype=np.float64), lo, hi)
    best = math.inf
    for r in range(rounds):
        key = (id(spec.curve), lo, hi, n) if r == 0 and samples is not None else None
        hit = samples.get(key) if key is not None else None
        if hit is None:
            tt = np.linspace(lo, hi, n)
            X = np.asarray(spec.curve.evaluate(tt))
            gap = None
        else:
            X, gap = hit
        d = np.sqrt(np.square(X - p).sum(axis=-1))
        k = int(d.argmin())
        best = min(best, float(d[k]))
        if r == 0 and stop is not None:
            # Farther from every sample than the sample spacing allows the curve to come back
            # (the same resolution assumption as the zoom itself): no closer than ``stop``.
            if gap is None:
                gap = float(np.max(np.linalg.norm(np.diff(X, axis=0), axis=-1), initial=0.0))
            if key is not None and hit is None:
                samples[key] = (X, gap)  # the uses keep their curves alive while the dict lives: ids stay unique
            if best - gap > stop:
                return best
        step = (hi - lo) / (n - 1)
        tk = lo + k * step if k < n - 1 else hi  # tt[k] of np.linspace(lo, hi, n)
        lo, hi = max(lo, tk - step), min(hi, tk + step)
    return best


def _line_distance(curve: Line, p: np.ndarray, lo: float, hi: float) -> float:
    """Distance from ``p`` to the segment ``curve([lo, hi])`` (the projection clamped to the range)."""
    P = p.tolist()
    return math.dist(P, scalar_point(curve, min(max(scalar_parameter(curve, P), lo), hi)))


def _circle_distance(curve: Circle, p: np.ndarray, lo: float, hi: float) -> float:
    """Distance from ``p`` to the arc ``curve([lo, hi])``: at the projection's angle when the arc holds it, else at an end.

    The distance to the points of a circle falls monotonically from the angle opposite the
    projection to the projection's angle, so on an arc it is least at that angle or at an end.
    """
    P = p.tolist()
    ts = [lo, hi]
    a = scalar_parameter(curve, P)
    if (a - lo) % TWO_PI <= hi - lo:
        ts.append(lo + (a - lo) % TWO_PI)
    return min(math.dist(P, scalar_point(curve, t)) for t in ts)


#: Curves whose distance from a point has a closed form (the sampled zoom serves the others).
_EXACT_DISTANCE = {Line: _line_distance, Circle: _circle_distance}


def _require_pair(uses: _Uses, comp: list[int], vertex: np.ndarray) -> None:
    """A matched set of uses must be two uses running opposite ways.

    Raises
    ------
    TopologyError
        Open shell (one use), non-manifold edge (three or more), inconsistent orientation.
    """
    i = comp[0]
    if len(comp) == 2 and vertex[i, 0] != vertex[i, 1] and vertex[i, 0] == vertex[comp[1], 1]:
        return  # the common case, without formatting the message below
    where = f"(from {uses.start[i].tolist()} to {uses.end[i].tolist()})"
    if len(comp) == 1:
        raise TopologyError(f"{uses.name(i)} {where} matches no other edge: the shell is open there")
    if len(comp) > 2:
        raise TopologyError(
            f"{uses.name(i)} {where} is shared by {len(comp)} edges ({'; '.join(uses.name(j) for j in comp)}); "
            "a closed manifold shell uses each edge exactly twice"
        )
    j = comp[1]
    if vertex[i, 0] != vertex[i, 1]:
        opposite = vertex[i, 0] == vertex[j, 1]
    else:  # a closed edge: compare the directions of travel at the midpoints
        opposite = float(np.dot(_travel(uses.spec[i]), _travel(uses.spec[j]))) < 0.0
    if not opposite:
        raise TopologyError(
            f"{uses.name(i)} and {uses.name(j)} {where} run the same way; neighbouring faces must use a shared "
            "edge in opposite directions (inconsistent orientation)"
        )


def _travel(spec: EdgeSpec) -> np.ndarray:
    """Direction of travel at the midpoint of a use (central difference of the curve)."""
    h = 1e-4 * (spec.t1 - spec.t0)  # a small fraction of the range: only the sign of the dot matters
    m = 0.5 * (spec.t0 + spec.t1)
    P = np.asarray(spec.curve.evaluate(np.array([m - h, m + h])))
    return P[1] - P[0]


# ====================================================================== same parameter
def _pcurve_in(primary: EdgeSpec, other: EdgeSpec, thr: float, what: str) -> Any:
    """``other.pcurve`` re-expressed in ``primary``'s curve parameter.

    Raises
    ------
    TopologyError
        The curves are not related by an affine parameter map within ``thr``, or the p-curve
        type cannot be re-parametrised.
    """
    pc = other.pcurve
    # other runs opposite to primary: other.t1 <-> primary.t0 and other.t0 <-> primary.t1.
    a = (other.t0 - other.t1) / (primary.t1 - primary.t0)
    c = other.t1 - a * primary.t0
    if isinstance(primary.curve, (Circle, Ellipse)) and isinstance(other.curve, (Circle, Ellipse)):
        # Two angle parametrisations of one conic differ by t -> ±t + c exactly: a slope off ±1 comes
        # from range ends merged into vertices within tolerance (each computed on its own face).  The
        # slope is ±1 and the offset splits the ends' disagreement; the probes below still decide.
        a = math.copysign(1.0, a)
        c = 0.5 * ((other.t1 - a * primary.t0) + (other.t0 - a * primary.t1))
    if other.curve is primary.curve:
        # One curve object: its parameter is already common to both uses.  Their ranges may differ
        # slightly where a vertex merged ends computed on different faces; that must not turn the
        # identity into an affine map.
        return pc
    tp = primary.t0 + (primary.t1 - primary.t0) * _PROBE
    dev = np.max(np.linalg.norm(np.asarray(primary.curve.evaluate(tp)) - np.asarray(other.curve.evaluate(a * tp + c)), axis=-1))
    if not dev <= thr:
        raise TopologyError(
            f"{what}: the two faces' curves of this edge are not affinely reparametrised copies of each other "
            f"(deviation {dev:.3g} > {thr:.3g}); their p-curves cannot be made same-parameter"
        )
    if pc is None or (a == 1.0 and c == 0.0):
        return pc
    try:
        return _affine_pcurve(pc, a, c)
    except InvalidInputError as exc:
        raise TopologyError(f"{what}: {exc}") from None


def _affine_pcurve(pc: Any, a: float, c: float) -> Any:
    """The p-curve ``t -> pc(a t + c)``.

    Raises
    ------
    InvalidInputError
        A type other than Line2D, Trig2D (only for ``|a| = 1``) and 2-D NurbsCurve.
    """
    if isinstance(pc, Line2D):
        return Line2D(pc.origin + c * pc.direction, a * pc.direction)
    if isinstance(pc, Trig2D) and abs(abs(a) - 1.0) <= 1e-12:
        a = math.copysign(1.0, a)  # the slope comes from float parameter ranges: ±1 up to rounding
        # cos(a t + c) = cos c cos t - a sin c sin t and sin(a t + c) = sin c cos t + a cos c sin t for a = ±1.
        cc, sc = math.cos(c), math.sin(c)
        return Trig2D(pc.center, cc * pc.a + sc * pc.b, a * (cc * pc.b - sc * pc.a))
    if isinstance(pc, NurbsCurve):
        d0, d1 = pc.domain
        if a < 0:  # pc(a t + c) = R(d0 + d1 - a t - c) with R the reversed curve
            pc, a, c = pc.reversed(), -a, d0 + d1 - c
        return pc.reparametrized((d0 - c) / a, (d1 - c) / a)
    raise InvalidInputError(
        f"cannot re-parametrise a {type(pc).__name__} p-curve by t -> {a:.6g} t + {c:.6g} (supported: Line2D, "
        "Trig2D with slope ±1, NurbsCurve)"
    )


# ====================================================================== assembly
def _assemble(
    faces: list[FaceSpec],
    uses: _Uses,
    vertex: np.ndarray,
    vpoint: np.ndarray,
    vtol: np.ndarray,
    pairs: np.ndarray,
    t: Tolerance,
) -> Solid:
    """Build the B-rep and attach the geometry (:func:`~coons.topology.builder.assembled_brep` for
    one shell, else ``BRepBuilder.assemble`` and void nesting); also which faces are unchanged
    (:func:`_unchanged_faces`)."""
    k = len(uses)
    E = pairs.shape[0]
    primary, other = pairs[:, 0], pairs[:, 1]
    fwd = uses.t0[primary] < uses.t1[primary]  # the primary use runs along its curve: it is the left side
    edge_start = np.where(fwd, vertex[primary, 0], vertex[primary, 1])
    edge_end = np.where(fwd, vertex[primary, 1], vertex[primary, 0])
    left = np.where(fwd, primary, other)
    edge_of = np.empty(k, dtype=np.int64)
    edge_of[primary] = np.arange(E)
    edge_of[other] = np.arange(E)
    is_left = np.zeros(k, dtype=bool)
    is_left[left] = True
    ref = np.where(is_left, edge_of + 1, -(edge_of + 1))
    edges = np.stack([edge_start, edge_end], axis=1)
    spec = uses.spec
    thr = np.maximum(uses.tol[primary], uses.tol[other])
    # The geometry in takes from the uses' object columns, with the objects' ids (the pools).
    curves = uses.curve[primary]
    ranges = np.stack([np.minimum(uses.t0[primary], uses.t1[primary]),
                       np.maximum(uses.t0[primary], uses.t1[primary])], axis=1)
    # The primary use's p-curve, then the other's, edge by edge (the pool order of one call each).
    # One curve object: _pcurve_in returns the p-curve as it is (checked first there too).
    # (uses.curve_id holds id(use.curve) of live uses: equal ids are the same object)
    pcs = np.empty(2 * E, dtype=object)
    pcs[0::2] = uses.pcurve[primary]
    pcs[1::2] = uses.pcurve[other]
    pc_ids = np.empty(2 * E, dtype=np.int64)
    pc_ids[0::2] = uses.pcurve_id[primary]
    pc_ids[1::2] = uses.pcurve_id[other]
    thr_l = thr.tolist()
    for e in np.flatnonzero(uses.curve_id[primary] != uses.curve_id[other]).tolist():
        pc = _pcurve_in(spec[int(primary[e])], spec[int(other[e])], thr_l[e],
                        f"{uses.name(int(other[e]))} (shared with {uses.name(int(primary[e]))})")
        pcs[2 * e + 1] = pc  # (pcs holds it: its id stays its own)
        pc_ids[2 * e + 1] = id(pc)
    side_p = np.where(fwd, 0, 1)
    pc_coedges = np.stack([2 * np.arange(E) + side_p, 2 * np.arange(E) + 1 - side_p], axis=1).ravel()
    # Which faces equal their spec, recorded before the check: it skips the checks of those whose
    # spec passed before (check._TRIMS_PASSED), and the next Boolean on the result reads its
    # unchanged faces from the record (sewn_unchanged_faces).
    unchanged = _unchanged_faces(faces, uses, primary, other, thr)
    surfaces = [f.surface for f in faces]
    senses = [f.sense for f in faces]
    # One shell (the common case) in array passes; several (which may nest) through the builder.
    first_use = uses.pos == 0
    brep = assembled_brep(vpoint, vtol, edges, ref, uses.loop_len[first_use],
                          np.bincount(uses.face[first_use], minlength=len(faces)), surfaces, senses, curves,
                          ranges, thr, pc_coedges, pcs, t, sewn_from=(tuple(faces), unchanged),
                          curve_ids=uses.curve_id[primary], pcurve_ids=pc_ids)
    if brep is not None:
        return Solid(brep)
    refs = ref.tolist()
    face_loops: list[list[list[int]]] = []
    i = 0
    for f in faces:
        loops = []
        for loop in f.loops:
            loops.append(refs[i : i + len(loop)])
            i += len(loop)
        face_loops.append(loops)
    b = BRepBuilder(t)
    b.assemble(vpoint, edges, face_loops, face_surfaces=surfaces, face_senses=senses)
    b.set_vertex_tols(np.arange(vtol.shape[0]), vtol)
    b.set_edge_curves(np.arange(E), curves.tolist(), ranges, thr)
    b.set_pcurves(pc_coedges, pcs.tolist())
    pre = _nest_voids(b, t) if len(b.ssolid) > 1 else None
    return Solid(b.build(caches_from=pre, sewn_from=(tuple(faces), unchanged)))


def _unchanged_faces(faces: list[FaceSpec], uses: "_Uses", primary: np.ndarray, other: np.ndarray,
                     thr: np.ndarray) -> np.ndarray:
    """``(F,)`` bool: the faces that :func:`sewn_unchanged` would find unchanged in the B-rep
    :func:`_assemble` builds (every use keeps its curve, p-curve, range and tolerance).

    An edge takes the primary use's curve, p-curve and range, the other use's p-curve when both
    share the curve object, and the larger tolerance ``thr``; so the primary use is unchanged
    when its own tolerance is ``thr``, and the other when it also shares the curve and runs over
    the same range the other way.  A use without a curve or p-curve, or a face without a
    surface, never is.  All in arrays
    over the uses' tables (:class:`_FaceUses`: curve ids, own tolerances).
    """
    k = len(uses)
    ok = np.zeros(k, dtype=bool)
    own, has = uses.own_tol, uses.complete
    shared = uses.curve_id[primary] == uses.curve_id[other]
    ok[primary] = has[primary] & (own[primary] == thr)
    ok[other] = (has[other] & shared & (own[other] == thr)
                 & (uses.t0[other] == uses.t1[primary]) & (uses.t1[other] == uses.t0[primary]))
    out = np.array([f.surface is not None for f in faces], dtype=bool)  # (an implicit plane never is)
    return out & (np.bincount(uses.face[~ok], minlength=len(faces)) == 0)


def _nest_voids(b: BRepBuilder, t: Tolerance) -> BRep:
    """Make every shell enclosing negative volume a void of the shell around it, and refuse a
    shell enclosing positive volume inside another such (two lumps overlapping).

    Which shell lies inside which is :func:`coons.topology.nesting.shell_parents` (winding numbers
    of one vertex, from cones over the faces' chords where the vertex lies outside every face box
    of the other shell, else from the default mesh with a distance certificate).  Returns the
    B-rep built before nesting, whose shell volumes, default mesh and nesting the final build
    shares (the next Boolean on the result tessellates it with the same default).

    Raises
    ------
    TopologyError
        A negative shell inside no shell (its faces are oriented inward) or directly inside another
        negative one; a positive shell directly inside another positive one; two shells touching
        (every vertex of one within the mesh band of the other at the finest deflection tried).
    """
    from coons.topology.mass import shell_volumes
    from coons.topology.nesting import shell_parents

    brep = b.build(check=False)
    vol = shell_volumes(brep)
    parents = shell_parents(brep, t, vol)
    for s in range(brep.n_shells):
        p = int(parents[s])
        faces = brep.shell_face_ids(s)[:8].tolist()
        if vol[s] < 0:
            if p < 0:
                raise TopologyError(
                    f"shell {s} (faces {faces}) encloses volume {vol[s]:.6g} < 0 and lies inside no other shell: "
                    "its faces are oriented inward (expected outward normals)"
                )
            if vol[p] < 0:
                raise TopologyError(
                    f"shell {s} (faces {faces}) encloses volume {vol[s]:.6g} < 0 and lies directly inside shell {p}, "
                    f"another void (volume {vol[p]:.6g}): a void must lie in solid material"
                )
            b.nest_shells(p, s)
        elif p >= 0 and vol[p] > 0:
            raise TopologyError(
                f"shell {s} (faces {faces}) encloses volume {vol[s]:.6g} > 0 and lies inside shell {p} (volume "
                f"{vol[p]:.6g} > 0): the two solids overlap (a shell inside solid material must be a void, "
                "oriented inward)"
            )
    return brep


# ====================================================================== B-rep -> specs
def face_specs(shape, rows=None) -> list[FaceSpec]:
    """The :class:`FaceSpec` of every face of a B-rep, in face order (inverse of :func:`sew_faces`).

    Straight edges without a curve get one shared :class:`~coons.kernel.analytic.Line` per edge
    (parametrised by arc length; p-curves re-expressed accordingly).  Both uses of an edge
    refer to the same curve object (among the faces of one call).

    Parameters
    ----------
    shape : Solid or BRep
    rows : sequence of int, optional
        Only these faces, in this order (default: all).

    Returns
    -------
    list of FaceSpec

    Raises
    ------
    InvalidInputError
        Not a B-rep or Solid.
    TopologyError
        A loop that is a lone vertex (no edge to describe it).
    """
    b = shape if isinstance(shape, BRep) else getattr(shape, "brep", None)
    if not isinstance(b, BRep):
        raise InvalidInputError(f"face_specs needs a Solid or BRep, got {type(shape).__name__}")
    if rows is None:
        rows = range(b.n_faces)
        # The whole B-rep: its columns read as Python lists once (reading one numpy scalar costs
        # several list reads; for a few rows of a large B-rep the arrays are read in place).
        e_curve, e_range, e_pcurve, e_tol = (b.edge_curve.tolist(), b.edge_range.tolist(),
                                             b.edge_pcurve.tolist(), b.edge_tol.tolist())
        nxt, l_first, f_ptr, f_loops = (b.coedge_next.tolist(), b.loop_coedge.tolist(),
                                        b.face_loop_ptr.tolist(), b.face_loops.tolist())
        f_surface, f_sense = b.face_surface.tolist(), b.face_sense.tolist()
    else:
        e_curve, e_range, e_pcurve, e_tol = b.edge_curve, b.edge_range, b.edge_pcurve, b.edge_tol
        nxt, l_first, f_ptr, f_loops = b.coedge_next, b.loop_coedge, b.face_loop_ptr, b.face_loops
        f_surface, f_sense = b.face_surface, b.face_sense
    curves: dict[int, tuple[Any, float, float, float, float, float]] = {}

    def edge_curve(e: int) -> tuple[Any, float, float, float, float, float]:
        """(curve, start, end, a, c, tol): the curve over [start, end], the map t_old = a t + c
        and the edge's tolerance, checked as :class:`EdgeSpec` would check them (once per edge,
        so that both uses can be made by ``EdgeSpec._trusted``)."""
        got = curves.get(e)
        if got is None:
            ci = int(e_curve[e])
            r0, r1 = (float(x) for x in e_range[e])
            if ci >= 0:
                got = (b.curves[ci], r0, r1, 1.0, 0.0)
            else:
                p, q = b.vertex_point[b.edge_vertex[e]]
                length = float(np.linalg.norm(q - p))
                got = (Line(p, q - p), 0.0, length, (r1 - r0) / length, r0)
            tol = float(e_tol[e])
            # The checks of EdgeSpec.__post_init__, which the trusted constructor skips, in place; on a
            # failure the constructor itself raises its message.
            if not (callable(getattr(got[0], "evaluate", None)) and math.isfinite(got[1]) and math.isfinite(got[2])
                    and got[1] != got[2] and math.isfinite(tol) and tol >= 0.0):
                EdgeSpec(got[0], got[1], got[2], None, tol)
            got = curves[e] = got + (tol,)
        return got

    limit = 2 * b.n_edges
    out = []
    for f in rows:
        f = int(f)
        si = int(f_surface[f])
        loops = []
        for loop in f_loops[int(f_ptr[f]):int(f_ptr[f + 1])]:
            loop = int(loop)
            first = int(l_first[loop])
            if first < 0:
                raise TopologyError(f"face {f}: loop {loop} is a lone vertex; a FaceSpec loop needs edges")
            specs = []
            c = first
            while True:
                e, side = c >> 1, c & 1
                curve, s0, s1, a, cc, tol = edge_curve(e)
                pi = int(e_pcurve[e][side])
                pc = None if pi < 0 else b.pcurves[pi]
                if pc is not None:
                    if not callable(getattr(pc, "evaluate", None)):
                        raise InvalidInputError(
                            f"EdgeSpec.pcurve must have an evaluate(t) method, got {type(pc).__name__}")
                    if a != 1.0 or cc != 0.0:
                        pc = _affine_pcurve(pc, a, cc)
                t0, t1 = (s0, s1) if side == 0 else (s1, s0)
                specs.append(EdgeSpec._trusted(curve, t0, t1, pc, tol))
                c = int(nxt[c])
                if c == first:
                    break
                if len(specs) > limit:
                    raise InvalidInputError(f"loop {loop} does not close: its next pointers cycle elsewhere")
            loops.append(tuple(specs))
        if not loops:
            raise InvalidInputError("FaceSpec needs at least one loop, got none")
        # Trusted: every field checked above as EdgeSpec and FaceSpec check them.
        out.append(FaceSpec._trusted(None if si < 0 else b.surfaces[si], bool(f_sense[f]), tuple(loops)))
    return out


#: The tables :func:`face_specs` reads to walk a B-rep's faces (with the pools' objects, all it reads when
#: every edge has a curve; ``coedge_next`` is made from ``edge_wing``).
_WALKED = ("edge_curve", "edge_range", "edge_pcurve", "edge_tol", "edge_wing", "loop_coedge", "face_loop_ptr",
           "face_loops", "face_surface", "face_sense")


def face_specs_many(breps: Sequence[BRep]) -> list[list[FaceSpec]]:
    """:func:`face_specs` of each B-rep, the walk done once per distinct set of tables.

    A B-rep whose walked tables (:data:`_WALKED`, byte for byte) and pool sizes equal an earlier
    one's (the tools of a drilling pattern: one primitive placed again and again) takes that one's
    walk with its own surfaces, curves and p-curves put in: the same specs :func:`face_specs` makes,
    field by field.  Only when every edge of the earlier one has a curve (otherwise
    :func:`face_specs` makes new lines) and its pools hold distinct objects; the checks
    :func:`face_specs` makes of each curve and p-curve object are made of the new ones.

    Parameters
    ----------
    breps : sequence of BRep

    Returns
    -------
    list of list of FaceSpec
        One list per B-rep, in face order.
    """
    plans: dict[tuple, tuple | None] = {}
    out = []
    for b in breps:
        tables = [getattr(b, name) for name in _WALKED]
        key = (tuple(a.tobytes() for a in tables), tuple((a.dtype.str, a.shape) for a in tables),
               len(b.surfaces), len(b.curves), len(b.pcurves))
        plan = plans.get(key, _MISSING_PLAN)
        if plan is None:
            out.append(face_specs(b))
            continue
        if plan is _MISSING_PLAN:
            specs = face_specs(b)
            plans[key] = _walk_plan(b, specs)
            out.append(specs)
            continue
        out.append(_planned_specs(b, *plan))
    return out


_MISSING_PLAN = object()


def _walk_plan(b: BRep, specs: list[FaceSpec]) -> tuple | None:
    """``(faces, curve rows, p-curve rows)``: ``specs`` (:func:`face_specs` of ``b``) as pool positions,
    per face ``(surface position or -1, sense, loops of (curve position, t0, t1, p-curve position
    or -1, tol))``, and the positions of the curves and p-curves it uses; None when the specs are
    not all pool objects (a new line for an edge without curve) or a pool repeats an object (a
    position would not say which one)."""
    where = []
    for pool in (b.surfaces, b.curves, b.pcurves):
        at = {id(x): i for i, x in enumerate(pool)}
        if len(at) != len(pool):
            return None
        where.append(at)
    surf, curv, pcur = where
    faces = []
    try:
        for spec in specs:
            loops = tuple(tuple((curv[id(e.curve)], e.t0, e.t1, -1 if e.pcurve is None else pcur[id(e.pcurve)], e.tol)
                                for e in loop) for loop in spec.loops)
            faces.append((-1 if spec.surface is None else surf[id(spec.surface)], spec.sense, loops))
    except KeyError:
        return None
    used_c = sorted({u[0] for f in faces for loop in f[2] for u in loop})
    used_p = sorted({u[3] for f in faces for loop in f[2] for u in loop if u[3] >= 0})
    return tuple(faces), used_c, used_p


def _planned_specs(b: BRep, faces: tuple, used_c: list[int], used_p: list[int]) -> list[FaceSpec]:
    """The face specs of ``b`` from another B-rep's :func:`_walk_plan` over the same tables, with the
    checks :func:`face_specs` makes of each curve and p-curve object."""
    S, C, P = b.surfaces, b.curves, b.pcurves
    for i in used_c:
        if not callable(getattr(C[i], "evaluate", None)):
            raise InvalidInputError(f"EdgeSpec.curve must have an evaluate(t) method, got {type(C[i]).__name__}")
    for i in used_p:
        if not callable(getattr(P[i], "evaluate", None)):
            raise InvalidInputError(f"EdgeSpec.pcurve must have an evaluate(t) method, got {type(P[i]).__name__}")
    make = EdgeSpec._trusted
    return [FaceSpec._trusted(None if si < 0 else S[si], sense,
                              tuple(tuple(make(C[ci], t0, t1, None if pi < 0 else P[pi], tol)
                                          for ci, t0, t1, pi, tol in loop) for loop in loops))
            for si, sense, loops in faces]


def sewn_unchanged(b: BRep, f: int, spec: FaceSpec) -> bool:
    """Whether face ``f`` of ``b`` is exactly ``spec``: ``face_specs(b, [f])[0]`` would equal it field by field.

    True when the face's surface and every edge use's curve and p-curve are the very objects of
    ``spec`` (no p-curve missing), with the same sense, loops in the same order, and parameter
    ranges and tolerances equal as floats.  The Booleans use it to carry an operand face's
    per-face data over to a result that was sewn from it (:func:`sew_faces` may have re-expressed
    a p-curve or widened a tolerance, then this is False).
    """
    return bool(sewn_unchanged_faces(b, [spec], rows=[f])[0])


def sewn_from(b: BRep) -> tuple[FaceSpec, ...] | None:
    """The face specs (in face order, a tuple: the record cannot be edited through it) B-rep ``b``
    was sewn from, when it was (:func:`sew_faces`, or recorded by :func:`remember_sewn`); None
    otherwise."""
    known = _SEWN_FROM.get(b)
    return None if known is None else known[0]


def remember_sewn(b: BRep, specs: Sequence[FaceSpec], unchanged: np.ndarray | None = None) -> None:
    """Record that B-rep ``b``'s faces are made from ``specs`` (face order), as :func:`sew_faces`
    records it while building: which faces equal their spec is ``unchanged (F,)`` bool when the
    caller knows it (it must be :func:`sewn_unchanged_faces` of ``b`` and ``specs``: see
    :func:`read_unchanged_faces`; it is not verified, and later served as the record's answer),
    else found by walking the B-rep.  For a B-rep assembled without
    sewing (a disjoint union of solids on their own geometry objects)."""
    specs = tuple(specs)
    if len(specs) != b.n_faces:
        raise InvalidInputError(f"remember_sewn needs one spec per face: {len(specs)} specs, {b.n_faces} faces")
    if unchanged is None:
        unchanged = sewn_unchanged_faces(b, specs)
    else:
        unchanged = np.array(unchanged, dtype=bool)
        if unchanged.shape != (b.n_faces,):
            raise InvalidInputError(f"remember_sewn needs one unchanged flag per face: shape {unchanged.shape}, "
                                    f"{b.n_faces} faces")
    _SEWN_FROM.pop(b, None)
    _SEWN_FROM[b] = (specs, unchanged)


def read_unchanged_faces(b: BRep) -> np.ndarray:
    """``(F,)`` bool: :func:`sewn_unchanged_faces` of ``b`` and ``face_specs(b)``, without the walk.

    :func:`face_specs` gives a face exactly as ``b`` holds it (the very surface, curves and
    p-curves, its ranges and tolerances as floats) unless the face has no surface or one of its
    uses has no p-curve or no curve (a straight edge without one gets a new :class:`Line`, its
    p-curves re-expressed), which are the faces the walk finds changed.  A disjoint union of a
    hundred tools is recorded from its members' face specs (``booleans.solid._gathered``) by two
    array passes instead of a walk over every use.
    """
    ok = b.face_surface >= 0
    # (a use in no loop, edge_loop -1, belongs to no face)
    bad = (b.edge_loop >= 0) & ~((b.edge_curve >= 0)[:, None] & (b.edge_pcurve >= 0))
    ok[b.loop_face[b.edge_loop[bad]]] = False
    return ok


def sewn_unchanged_faces(b: BRep, specs: Sequence[FaceSpec], rows: Sequence[int] | None = None) -> np.ndarray:
    """:func:`sewn_unchanged` of many faces at once: ``(n,)`` bool for face ``rows[i]`` (default ``i``) and ``specs[i]``.

    One walk over the loops' coedges in plain Python lists and one array comparison of the
    uses' curve and p-curve objects, ranges and tolerances (a large part carried from Boolean
    to Boolean costs microseconds per face, not a loop of array lookups per use).
    """
    if rows is None:
        known = _SEWN_FROM.get(b)
        if known is not None and len(known[0]) == len(specs) == b.n_faces and all(
                x is y for x, y in zip(known[0], specs)):
            return known[1].copy()
    rows = list(range(len(specs))) if rows is None else [int(r) for r in rows]
    out = np.zeros(len(rows), dtype=bool)
    face_surface, face_sense = b.face_surface.tolist(), b.face_sense.tolist()
    ptr, face_loops, first = b.face_loop_ptr.tolist(), b.face_loops.tolist(), b.loop_coedge.tolist()
    nxt = b.coedge_next.tolist()
    cand, coedges, uses, owner = [], [], [], []
    for i, (f, spec) in enumerate(zip(rows, specs)):
        si = face_surface[f]
        if si < 0 or b.surfaces[si] is not spec.surface or bool(face_sense[f]) != spec.sense:
            continue
        loops = face_loops[ptr[f]:ptr[f + 1]]
        if len(loops) != len(spec.loops):
            continue
        cs: list[int] = []
        good = True
        for loop, ls in zip(loops, spec.loops):
            c0 = first[loop]
            n0 = len(cs)
            if c0 >= 0:
                c = c0
                while True:
                    cs.append(c)
                    c = nxt[c]
                    if c == c0 or len(cs) - n0 > len(ls):
                        break
            if len(cs) - n0 != len(ls):
                good = False
                break
        if not good:
            continue
        cand.append(i)
        coedges += cs
        uses += [e for loop in spec.loops for e in loop]
        owner += [len(cand) - 1] * len(cs)
    if not cand:
        return out
    c = np.asarray(coedges, dtype=np.int64)
    k, side = c >> 1, c & 1
    ci, pi = b.edge_curve[k], b.edge_pcurve[k, side]
    curve_ids = np.array([id(x) for x in b.curves] + [0], dtype=np.int64)
    pcurve_ids = np.array([id(x) for x in b.pcurves] + [0], dtype=np.int64)
    same = (ci >= 0) & (pi >= 0)
    same &= curve_ids[np.where(ci >= 0, ci, -1)] == np.array([id(e.curve) for e in uses], dtype=np.int64)
    same &= pcurve_ids[np.where(pi >= 0, pi, -1)] == np.array([0 if e.pcurve is None else id(e.pcurve) for e in uses],
                                                                 dtype=np.int64)
    r0, r1 = b.edge_range[k, 0], b.edge_range[k, 1]
    t0 = np.array([e.t0 for e in uses], dtype=np.float64)
    t1 = np.array([e.t1 for e in uses], dtype=np.float64)
    same &= (t0 == np.where(side == 0, r0, r1)) & (t1 == np.where(side == 0, r1, r0))
    same &= np.array([np.nan if e.tol is None else e.tol for e in uses], dtype=np.float64) == b.edge_tol[k]
    good_face = np.ones(len(cand), dtype=bool)
    np.logical_and.at(good_face, np.asarray(owner, dtype=np.int64), same)
    out[np.asarray(cand, dtype=np.int64)] = good_face
    return out
