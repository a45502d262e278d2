"""Disjoint unions of solids by concatenating their B-rep tables.

:func:`disjoint_union` makes one solid of solids whose bounding boxes are pairwise apart (a
plate's 100 drilling tools gathered into one operand of one Boolean).  The solids share no
point, so the union's B-rep is their B-reps side by side: every table stacked, each index
column shifted by the rows before it (vertices, edges, coedges ``2 e + side``, loops, faces,
shells, solids and the geometry tuples), ``-1`` kept as "none".  Every invariant of
:func:`~coons.topology.check.check` is per loop, edge, vertex, face, shell or solid, or about
how shells nest, and neither changes when apart shells are put side by side; so the union of
checked solids is valid by construction and is not checked again (nor sewn: the cost is a few
array copies, not vertex clustering and edge matching over all faces).  It does not decide
whether solids whose boxes meet are disjoint (that is a Boolean's job): it raises instead.
"""

from __future__ import annotations

from typing import Sequence

import numpy as np

from coons.errors import InvalidInputError
from coons.tolerance import Tolerance, resolve
from coons.topology.brep import BRep
from coons.topology.shape import Solid

__all__ = ["disjoint_union", "meeting_pair", "padded_box", "padded_boxes", "stacked"]


def disjoint_union(solids: Sequence[Solid], tol: Tolerance | None = None) -> Solid:
    """One solid made of solids whose bounding boxes are pairwise apart, their B-reps side by side.

    The result has the lumps of ``solids`` in argument order (empty solids skipped), and within
    each its vertices, edges, loops, faces, shells and geometry objects in their own order:
    face ``f`` of the ``k``-th non-empty solid is face ``f + F_0 + ... + F_{k-1}`` of the
    union, and its surface, curves and p-curves are the very same objects.  Counts and
    measures add up (volume, area, the numbers of faces, edges and vertices).

    Parameters
    ----------
    solids : sequence of Solid
        Valid solids; their exact bounding boxes, each padded by the largest of ``tol.linear``
        and its own edge and vertex tolerances, must be pairwise apart (a tolerance-sized gap
        could let later sewing merge vertices of two of them).
    tol : Tolerance, optional

    Returns
    -------
    Solid
        The solid itself when only one is non-empty, :meth:`Solid.empty` when none is.

    Raises
    ------
    InvalidInputError
        An argument that is not a Solid, or two solids whose padded boxes meet (named by their
        argument positions).

    Examples
    --------
    >>> from coons.topology.primitives import Box
    >>> u = disjoint_union([Box(1, 1, 1), Box(1, 1, 1).translate((3, 0, 0))])
    >>> u.brep.n_solids, u.brep.n_faces, bool(abs(u.volume - 2.0) < 1e-12), u.check().ok
    (2, 12, True, True)
    """
    t = resolve(tol)
    solids = list(solids)
    for i, s in enumerate(solids):
        if not isinstance(s, Solid):
            raise InvalidInputError(f"disjoint_union: argument {i} must be a coons Solid, got {type(s).__name__}")
    keep = [i for i, s in enumerate(solids) if not s.is_empty]
    if not keep:
        return Solid.empty()
    if len(keep) == 1:
        return solids[keep[0]]
    boxes = padded_boxes([solids[i] for i in keep], t)
    meet = meeting_pair(boxes)
    if meet is not None:
        i, j = keep[meet[0]], keep[meet[1]]
        raise InvalidInputError(
            f"disjoint_union: the padded bounding boxes of solids {i} ({boxes[meet[0]].tolist()}) and {j} "
            f"({boxes[meet[1]].tolist()}) meet; expected pairwise apart boxes (use a Boolean union)")
    return Solid(stacked([solids[i].brep for i in keep]))


def padded_box(s: Solid, t: Tolerance) -> np.ndarray:
    """The exact bounding box ``(2, 3)`` of a non-empty solid padded by the largest of ``t.linear``
    and its edge and vertex tolerances: solids whose padded boxes are apart share no point,
    and no vertex of one lies within a tolerance of the other."""
    b = s.brep
    pad = max(t.linear, float(np.max(b.edge_tol, initial=0.0)), float(np.max(b.vertex_tol, initial=0.0)))
    return np.asarray(s.bounding_box(), dtype=np.float64) + np.array([[-pad], [pad]])


def padded_boxes(solids: Sequence[Solid], t: Tolerance) -> np.ndarray:
    """:func:`padded_box` of each of ``solids`` (each must be non-empty, as there), ``(n, 2, 3)``, the same floats.

    A solid whose curves are all lines and circles and whose surfaces are all planes, cylinders
    and cones (a drilling tool) is bounded with the others of its kind in one array pass: its
    exact box is that of its vertices and of its circles' extreme points (the candidates
    :func:`~coons.topology.mass.bounding_box` takes for it: a line's extremes are its ends, such
    surfaces have no interior extremes), reduced per solid by exact minima and maxima.  Other
    solids are bounded one by one.  A hundred tools cost one pass instead of a hundred.
    """
    from coons.kernel.analytic import Circle, ConicalSurface, CylindricalSurface, Line, PlanarSurface
    from coons.topology.mass import circle_extremes

    flat = (PlanarSurface, CylindricalSurface, ConicalSurface)
    out = np.empty((len(solids), 2, 3))
    batch: list[int] = []
    for k, s in enumerate(solids):
        b = s.brep
        if (b.n_vertices and all(type(c) is Circle or type(c) is Line for c in b.curves)
                and all(isinstance(S, flat) for S in b.surfaces)):
            batch.append(k)
        else:
            out[k] = padded_box(s, t)
    if not batch:
        return out
    breps = [solids[k].brep for k in batch]
    n = len(breps)
    V = np.concatenate([b.vertex_point for b in breps])
    first_v = np.cumsum([0] + [b.n_vertices for b in breps[:-1]])
    lo, hi = np.minimum.reduceat(V, first_v, axis=0), np.maximum.reduceat(V, first_v, axis=0)
    # The circle arcs of all solids: their curves, rows of the stacked edge ranges and solids.
    first_e = np.cumsum([0] + [b.n_edges for b in breps[:-1]]).tolist()
    arcs, rows, owner = [], [], []
    for i, b in enumerate(breps):
        for e, c in enumerate(b.edge_curve.tolist()):
            if c >= 0 and type(b.curves[c]) is Circle:
                arcs.append(b.curves[c])
                rows.append(first_e[i] + e)
                owner.append(i)
    if arcs:
        P, k = circle_extremes(arcs, np.concatenate([b.edge_range for b in breps])[rows])
        of = np.array(owner, dtype=np.int64)[k]
        np.minimum.at(lo, of, P)
        np.maximum.at(hi, of, P)
    # The pad of padded_box: the largest of t.linear and the edge and vertex tolerances (all >= 0).
    pad = np.zeros(n)
    for name, count in (("edge_tol", "n_edges"), ("vertex_tol", "n_vertices")):
        np.maximum.at(pad, np.repeat(np.arange(n), [getattr(b, count) for b in breps]),
                      np.concatenate([getattr(b, name) for b in breps]))
    pad = np.maximum(pad, t.linear)[:, None]
    out[batch, 0] = lo + -pad
    out[batch, 1] = hi + pad
    return out


def meeting_pair(boxes: np.ndarray) -> tuple[int, int] | None:
    """The first pair ``(i, j)``, ``i < j``, of boxes ``(n, 2, 3)`` that meet (closed boxes), or None.

    Sort and sweep along x: only boxes whose x ranges overlap are compared on all axes, so a
    grid of tools costs about its size, not its square.
    """
    lo, hi = boxes[:, 0], boxes[:, 1]
    order = np.argsort(lo[:, 0], kind="stable")
    xs = lo[order, 0]
    # Box order[k] meets in x the boxes order[k + 1 : stop[k]] (their lo_x at most its hi_x).
    stop = np.searchsorted(xs, hi[order, 0], side="right")
    count = np.maximum(stop - np.arange(order.size) - 1, 0)
    if not np.any(count):
        return None
    a = np.repeat(np.arange(order.size), count)
    b = a + 1 + (np.arange(a.size) - np.repeat(np.cumsum(count) - count, count))
    i, j = order[a], order[b]
    meet = np.all((lo[i] <= hi[j]) & (lo[j] <= hi[i]), axis=1)
    if not np.any(meet):
        return None
    i, j = np.minimum(i[meet], j[meet]), np.maximum(i[meet], j[meet])
    k = np.lexsort((j, i))[0]
    return int(i[k]), int(j[k])


def stacked(breps: Sequence[BRep]) -> BRep:
    """The B-reps' tables side by side (see the module docstring); no check that they are apart.

    Parameters
    ----------
    breps : sequence of BRep
        At least one.

    Returns
    -------
    BRep
        Rows of ``breps[k]`` follow those of ``breps[:k]`` in every table; geometry tuples are
        concatenated (the same objects), index columns shifted, ``-1`` kept.
    """
    if not breps:
        raise InvalidInputError("stacked needs at least one BRep, got none")
    if len(breps) == 1:
        return breps[0]
    sizes = np.array([[b.n_vertices, b.n_edges, b.n_loops, b.n_faces, b.n_shells, b.n_solids,
                       len(b.surfaces), len(b.curves), len(b.pcurves)] for b in breps], dtype=np.int64)
    # Offsets of each B-rep's rows (and geometry indices), per kind.
    off = np.concatenate([np.zeros((1, sizes.shape[1]), dtype=np.int64), np.cumsum(sizes, axis=0)[:-1]])
    V, E, L, F, S, N, SU, CU, PC = range(9)

    def column(name: str, kind: int | None, scale: int = 1) -> np.ndarray:
        parts = [getattr(b, name) for b in breps]
        out = np.concatenate(parts)
        if kind is None:
            return out
        # Each part's offset, repeated over its rows; "none" (-1) stays -1.
        shift = np.repeat(scale * off[:, kind], [p.shape[0] for p in parts])
        if out.ndim > 1:
            shift = shift[:, None]
        return np.where(out >= 0, out + shift, out)

    def csr(ptr_name: str, idx_name: str, kind: int) -> tuple[np.ndarray, np.ndarray]:
        ptrs = [getattr(b, ptr_name) for b in breps]
        starts = np.cumsum([0] + [int(p[-1]) for p in ptrs[:-1]])
        ptr = np.concatenate([ptrs[0]] + [p[1:] + s for p, s in zip(ptrs[1:], starts[1:])])
        return ptr, column(idx_name, kind)

    face_loop_ptr, face_loops = csr("face_loop_ptr", "face_loops", L)
    shell_face_ptr, shell_faces = csr("shell_face_ptr", "shell_faces", F)
    solid_shell_ptr, solid_shells = csr("solid_shell_ptr", "solid_shells", S)
    # Each table with the kind of index it holds (None: not an index) and the scale of that
    # index (coedges are 2 e + side).
    kinds = {"vertex_point": (None, 1), "vertex_tol": (None, 1), "vertex_coedge": (E, 2), "edge_vertex": (V, 1),
             "edge_loop": (L, 1), "edge_wing": (E, 2), "edge_curve": (CU, 1), "edge_range": (None, 1),
             "edge_pcurve": (PC, 1), "edge_tol": (None, 1), "loop_face": (F, 1), "loop_coedge": (E, 2),
             "loop_vertex": (V, 1), "face_surface": (SU, 1), "face_sense": (None, 1), "face_shell": (S, 1),
             "shell_solid": (N, 1)}
    return BRep(
        **{name: column(name, kind, scale) for name, (kind, scale) in kinds.items()},
        face_loop_ptr=face_loop_ptr,
        face_loops=face_loops,
        shell_face_ptr=shell_face_ptr,
        shell_faces=shell_faces,
        solid_shell_ptr=solid_shell_ptr,
        solid_shells=solid_shells,
        surfaces=tuple(x for b in breps for x in b.surfaces),
        curves=tuple(x for b in breps for x in b.curves),
        pcurves=tuple(x for b in breps for x in b.pcurves),
    )
