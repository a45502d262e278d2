"""The validity checker of B-reps: every invariant the structure promises, as a report.

:func:`check` returns a :class:`CheckReport` listing every problem found (never just the
first): pointer consistency of the winged-edge tables, closed loops, manifold edges with two
different faces and opposite senses, manifold vertices, Euler–Poincaré per shell, vertices
on their edges, p-curves agreeing with 3-D curves, loops closed in parameter space, planar
polyhedral faces, self-intersecting trim loops, faces lying on the left of their loops
(the sign of their parameter-plane area agrees with ``face_sense``), outward orientation of shells (outer
shells enclose positive volume, voids negative), and the nesting of shells (every void directly inside its
solid's outer shell, no outer shell inside another solid's material:
:func:`~coons.topology.nesting.shell_parents`).  It does not repair anything.

Geometric checks sample each edge at a fixed number of parameters (``samples``); a sampled
check can miss a deviation between samples, so tolerances are verified, not proven.  What the
same-parameter check measures along a coedge (the p-curve samples, the surface's speed there,
the largest distance from the 3-D curve, the curve's end points) depends only on its curve,
p-curve, surface, edge range and ``samples``, all immutable values: it is remembered per those
(``_SAME_PARAMETER``, weakly keyed by the p-curve) and compared against the coedge's own edge
and vertex tolerances every time, so a B-rep sharing most of its geometry with one checked
before (a Boolean's result and its operand) samples only its new coedges.  The rows and curve
ends of the last sewn B-rep measured (and of the last B-rep measured) are also kept as arrays
(``_MEASURED``): a Boolean's result, checked after its operand, finds those of the coedges and
edges it shares with it in one array pass, by the positions of their objects in the operand's
pools (``_memo.pool_positions``).  Likewise the trim
checks of a face (its loops crossing, their sense against ``face_sense``) are a function of its
surface, sense, p-curves and ranges, the tolerance and ``samples`` alone: a B-rep sewn from face
specs (:func:`~coons.topology.sew.sewn_unchanged` faces, recorded in :data:`_SEWN_FROM` by the
sewing, or for a B-rep assembled without sewing by :func:`~coons.topology.sew.remember_sewn`, which
finds the unchanged faces by walking the B-rep) skips them for a face whose spec passed them in
an earlier clean check (``_TRIMS_PASSED``; the specs the last clean check of a sewn B-rep recorded
are found by id in one array pass, ``_PASSED_FACES``), as a plate's untouched faces do from cut to cut, and
with them the same-parameter comparisons of its
coedges (the deviation measured then, against the same edge tolerance: an unchanged face's uses
keep theirs; faces whose loop closure was judged against a vertex are never recorded); the
ends of every edge are still compared with its vertices.  A face on a plane or cylinder whose loops extend,
use for use, those of a spec that passed tests only the pairs of segments involving its new loops
(a plate's top gaining a hole; ``_PASSED_ON``), and of its old loops only those whose box meets
the new ones' (``_near_new_loops``).  When the spec it extends was recorded with its face's
orientation sums and loop boxes (``_PASSED_SUMS``: total signed parameter-plane area, largest ring
box and speed, one box per loop), its old loops are not measured again either (their deviation and
closure are the spec's, as for a passed face) nor made into rings: the face's area is the recorded
one plus the new loops', and only the old loops whose recorded box meets the new rings' box are
sampled (from the earlier measurements, ``_coedge_samples``) for the crossing search.  Every other
check, topological and geometric
(vertices on edges, edge tolerances, orientation), runs on the whole model; the shell volumes of
a sewn B-rep are summed from face contributions, those of faces equal to a spec integrated before
carried (:func:`~coons.topology.mass.carried_shell_volumes`, for the sign test).  The
p-curve samples of the whole model are evaluated in one batch (lines and ellipses in array
time, surfaces of one NURBS structure together through
:func:`~coons.kernel.surface.derivatives_surfaces`, a model of planes and surfaces of revolution
alone by :func:`~coons.kernel.analytic.surface_derivatives`) and shared by the trim checks, whose rings,
orientation areas and segments are built for all faces on surfaces at once: the checker costs a
few array passes, not a few numpy calls per coedge.
"""

from __future__ import annotations

import functools
import operator
import weakref
from itertools import chain, repeat
from dataclasses import dataclass, field

import numpy as np

from coons.errors import CoonsError, InvalidInputError, TopologyError
from coons.kernel.analytic import BATCHED_SURFACES, CylindricalSurface, Line, PlanarSurface, surface_derivatives
from coons.kernel.onsurface import BATCHED_CURVES, evaluate_curves
from coons.kernel.pcurve import Line2D, Trig2D
from coons.kernel.surface import derivatives_surfaces
from coons.tolerance import Tolerance, resolve
from coons.topology._memo import IdentityMemo, LastRecord, all_values, found_by_id, id_index, is_value, pool_positions, pool_values, read_only as _read_only
from coons.kernel._common import row_norms as _norms
from coons.kernel._stacked import derivatives_many
from coons.topology.brep import BRep

__all__ = ["CheckReport", "Problem", "check"]

_ENDS = np.array([0.0, 1.0])  # sample parameters of a straight segment: its two ends
#: Refinement factor and levels of the trim polylines of faces whose coarse polylines cross: two
#: levels take 9 samples per edge to 2049, the sagitta of a chord down by 16^4 (a half circle of
#: radius 1: from 0.02 to 3e-7).
_REFINE = 16
_REFINE_LEVELS = 2
#: Fractions of an edge's range, falling by 2^(1/4) from 1/2 to 2^-30, at which the last refinement of
#: :func:`_check_trims` samples curved edges towards both ends besides the uniform fractions.  At a vertex
#: where edges of curvatures ``κa > κb`` leave tangent to each other, the chord of the flatter one over
#: ``[s, 2^(1/4) s]`` sags by ``κb (0.19 s)² / 8``, less than their gap ``(κa - κb) s² / 2`` there while
#: ``κa > 1.01 κb``; below 2^-30 of an edge the gaps are far below a tolerance.
_DENSE_ENDS = np.exp2(-np.arange(4, 121) / 4.0)


@dataclass(frozen=True)
class Problem:
    """One violated invariant: a short code, the entity kind and index, and a message."""

    code: str
    entity: str
    index: int
    message: str

    def __str__(self) -> str:
        return f"{self.code} [{self.entity} {self.index}]: {self.message}"


@dataclass(frozen=True)
class CheckReport:
    """Problems found by :func:`check`; ``ok`` when there are none."""

    problems: tuple[Problem, ...] = field(default_factory=tuple)
    counts: dict = field(default_factory=dict)

    @property
    def ok(self) -> bool:
        return not self.problems

    def __bool__(self) -> bool:
        return self.ok

    def codes(self) -> set[str]:
        return {p.code for p in self.problems}

    def summary(self, limit: int = 20) -> str:
        lines = [str(p) for p in self.problems[:limit]]
        if len(self.problems) > limit:
            lines.append(f"... and {len(self.problems) - limit} more")
        return "\n".join(lines) if lines else "valid"


def check(shape, tol: Tolerance | None = None, *, samples: int = 9, geometry: bool = True) -> CheckReport:
    """Check every invariant of a B-rep (or of anything with a ``.brep``).

    Parameters
    ----------
    shape : BRep or Shape
    tol : Tolerance, optional
    samples : int
        Parameters per edge for the geometric checks.
    geometry : bool
        Also run the geometric checks (topology only when False).

    Returns
    -------
    CheckReport
    """
    t = resolve(tol)
    b: BRep = shape if isinstance(shape, BRep) else shape.brep
    problems: list[Problem] = []
    _check_pointers(b, problems)
    topo_ok = not problems
    if topo_ok:
        _check_manifold(b, problems)
        _check_euler(b, problems)
    if geometry and topo_ok:
        known = _SEWN_FROM.get(b)
        found: dict = {}
        passed, extends = _trims_passed(b, known, t, samples, found) if known is not None else (None, None)
        partial = _partial_faces(b, extends, found, t, samples)
        table = _check_geometry(b, t, samples, problems, passed, partial)
        sums = _check_trims(b, t, samples, problems, table, passed, extends, partial)
        if not problems:
            _check_orientation(b, t, problems, known, {f: (n, found[f]) for f, n in (extends or {}).items()})
        if not problems and b.n_shells > 1:
            _check_nesting(b, t, problems)
        if not problems and known is not None:
            _remember_passed(b, known, passed | _remember_trims(b, known, passed, t, samples, table.gapped, sums),
                             t, samples)
    counts = {"vertices": b.n_vertices, "edges": b.n_edges, "loops": b.n_loops, "faces": b.n_faces,
              "shells": b.n_shells, "solids": b.n_solids}
    return CheckReport(tuple(problems), counts)


# ---------------------------------------------------------------------- topology
def _check_pointers(b: BRep, out: list[Problem]) -> None:
    nc = 2 * b.n_edges
    nxt, prv, loop = b.coedge_next, b.coedge_prev, b.coedge_loop
    if nc == 0:
        return
    for name, arr, hi in (("next", nxt, nc), ("prev", prv, nc), ("loop", loop, b.n_loops)):
        bad = np.flatnonzero(arr.view(np.uint64) >= hi)  # negative ids wrap to huge: one comparison
        for c in bad[:10]:
            out.append(Problem("dangling-pointer", "coedge", int(c), f"{name} pointer {int(arr[c])} is out of range"))
    if out:
        return
    bad = np.flatnonzero(nxt[prv] != np.arange(nc))
    for c in bad[:10]:
        out.append(Problem("wing-mismatch", "coedge", int(c), "next(prev(c)) != c"))
    bad = np.flatnonzero(loop[nxt] != loop)
    for c in bad[:10]:
        out.append(Problem("loop-mismatch", "coedge", int(c), f"next coedge lies in loop {int(loop[nxt[c]])}, not {int(loop[c])}"))
    bad = np.flatnonzero(b.coedge_origin[nxt] != b.coedge_target)
    for c in bad[:10]:
        out.append(Problem("loop-not-connected", "coedge", int(c),
                           f"ends at vertex {int(b.coedge_target[c])} but the next coedge starts at {int(b.coedge_origin[nxt[c]])}"))
    first = b.loop_coedge
    has = first >= 0
    bad = np.flatnonzero(has & (loop[np.where(has, first, 0)] != np.arange(b.n_loops)))
    for l in bad[:10]:
        out.append(Problem("loop-first-coedge", "loop", int(l), "its first coedge belongs to another loop"))
    # Every loop is a single cycle: count coedges per loop against the cycle length.
    if not out:
        per_loop = np.bincount(loop, minlength=b.n_loops)
        with_coedge = np.flatnonzero(has)
        cyc_len = np.zeros(b.n_loops, dtype=np.int64)
        cyc_len[with_coedge] = _cycle_lengths_at(nxt, first[with_coedge], loop, per_loop[with_coedge])
        bad = np.flatnonzero(has & (cyc_len != per_loop))
        for l in bad[:10]:
            out.append(Problem("loop-split", "loop", int(l), "its coedges form more than one cycle"))
        empty = np.flatnonzero(~has & (b.loop_vertex < 0))
        for l in empty[:10]:
            out.append(Problem("empty-loop", "loop", int(l), "no coedge and no vertex"))


def _cycle_lengths(perm: np.ndarray) -> np.ndarray:
    """Length of the cycle of the permutation ``perm`` through each element (pointer doubling,
    :func:`_cycle_labels`).  About 2–3 times faster than labelling the components of the
    permutation graph with scipy (the polyhedral Booleans check every result)."""
    label = _cycle_labels(perm)
    return np.bincount(label, minlength=label.size)[label]


def _cycle_labels(perm: np.ndarray) -> np.ndarray:
    """The least element of the cycle of the permutation ``perm`` through each element (pointer doubling).

    ``label`` holds the minimum over the window ``i, σ(i), …, σ^(2^r − 1)(i)``; each round doubles
    the window (``label = min(label, label[σ^(2^r)])``, ``σ^(2^(r+1)) = σ^(2^r) ∘ σ^(2^r)``).  When a
    round changes nothing the labels are stable for every later round (``label[σ^(2^(r+1))(i)] =
    label[σ^(2^r)(σ^(2^r)(i))] = label[i]``), so they already are the minima of whole cycles;
    ``⌈log2(longest cycle)⌉ + 1`` rounds at most.
    """
    n = perm.shape[0]
    label = np.arange(n)
    p = np.asarray(perm)
    while True:
        lp = label[p]
        if np.array_equal(lp, label):
            break
        np.minimum(label, lp, out=label)
        p = p[p]
    return label


#: Steps walked along every cycle by :func:`_cycle_lengths_at` before the long ones go to pointer doubling.
_WALK = 12


def _cycle_lengths_at(perm: np.ndarray, start: np.ndarray, group: np.ndarray, expected: np.ndarray) -> np.ndarray:
    """Length ``(k,)`` of the cycle of the permutation ``perm`` through each element of ``start (k,)``.

    ``group (n,)``: a label that ``perm`` preserves (``group[perm] == group``, the caller's checked
    invariant: loops for ``next``, origin vertices for the rotation about a vertex), and
    ``expected (k,)`` the size of the group of each start (a cycle is at most that long).  The cycles
    are walked together, one gather per step, for :data:`_WALK` steps — enough for the triangles and
    vertex fans of meshes, a few array passes over the starts instead of :func:`_cycle_lengths`'s
    log-many passes over every element; the cycles still open are measured by :func:`_cycle_lengths`
    on the elements of their groups only.  Equal to ``_cycle_lengths(perm)[start]``.
    """
    k = start.size
    out = np.zeros(k, dtype=np.int64)
    rows = np.arange(k)
    first = np.asarray(start, dtype=np.int64)
    cur = perm[first]
    for steps in range(1, _WALK + 1):
        done = cur == first
        out[rows[done]] = steps
        if np.all(done):
            return out
        # a cycle longer than its group cannot close: stop walking it (the caller reports it)
        keep = ~done & (expected[rows] > steps)
        rows, first, cur = rows[keep], first[keep], cur[keep]
        if rows.size == 0:
            return out
        cur = perm[cur]
    open_rows = rows
    in_open = np.zeros(int(group.max(initial=-1)) + 1, dtype=bool)
    in_open[group[first]] = True
    elems = np.flatnonzero(in_open[group])
    local = np.full(perm.size, -1, dtype=np.int64)
    local[elems] = np.arange(elems.size)
    sub = local[perm[elems]]
    if np.any(sub < 0):  # perm does not preserve the groups after all: measure on every element
        out[open_rows] = _cycle_lengths(perm)[first]
    else:
        out[open_rows] = _cycle_lengths(sub)[local[first]]
    return out


def _check_manifold(b: BRep, out: list[Problem]) -> None:
    ef = b.edge_face
    same = np.flatnonzero(ef[:, 0] == ef[:, 1])
    for e in same[:10]:
        out.append(Problem("seam-edge", "edge", int(e), f"both sides lie in face {int(ef[e, 0])}"))
    # Manifold vertices: the rotation around each vertex visits every coedge leaving it.
    nc = 2 * b.n_edges
    if nc:
        rot = b.coedge_next[np.arange(nc) ^ 1]  # next outgoing coedge around the origin vertex
        v = b.coedge_origin
        degree = np.bincount(v, minlength=b.n_vertices)
        # rot permutes the coedges leaving each vertex (their twins end there, and the pointer checks
        # made every next coedge start where its predecessor ends): the vertex is manifold when the
        # cycle through any one of them visits all.
        start = np.empty(b.n_vertices, dtype=np.int64)
        start[v] = np.arange(nc)
        used = np.flatnonzero(degree > 0)
        fan = _cycle_lengths_at(rot, start[used], v, degree[used])
        bad = used[fan != degree[used]]
        for vi in bad[:10]:
            out.append(Problem("non-manifold-vertex", "vertex", int(vi),
                               f"{int(degree[vi])} edges leave it but they form several fans"))
    lv = b.loop_vertex[(b.loop_vertex >= 0) & (b.loop_vertex < b.n_vertices)]
    in_loop = np.zeros(b.n_vertices, dtype=bool)  # np.isin(arange, loop_vertex) by a scatter (no sort)
    in_loop[lv] = True
    isolated = np.flatnonzero((b.vertex_coedge < 0) & ~in_loop)
    for vi in isolated[:10]:
        out.append(Problem("isolated-vertex", "vertex", int(vi), "not used by any edge or loop"))
    # Shells must be closed: every edge's two faces in the same shell.
    fs = b.face_shell[ef]
    bad = np.flatnonzero(fs[:, 0] != fs[:, 1])
    for e in bad[:10]:
        out.append(Problem("shell-mismatch", "edge", int(e), f"joins shells {int(fs[e, 0])} and {int(fs[e, 1])}"))


def _check_euler(b: BRep, out: list[Problem]) -> None:
    """Per shell: V - E + F - (L - F) = 2 (1 - G) with an integer genus G >= 0."""
    ns = b.n_shells
    if ns == 0:
        return
    shell_of_face = b.face_shell
    F = np.bincount(shell_of_face, minlength=ns)
    L = np.bincount(shell_of_face[b.loop_face], minlength=ns)
    edge_shell = shell_of_face[b.edge_face[:, 0]]
    E = np.bincount(edge_shell, minlength=ns)
    has_lv = b.loop_vertex >= 0
    vs = np.concatenate([b.edge_vertex[:, 0], b.edge_vertex[:, 1], b.loop_vertex[has_lv]])
    ss = np.concatenate([edge_shell, edge_shell, shell_of_face[b.loop_face[has_lv]]])
    # Distinct (vertex, shell) pairs.  Nearly always every vertex lies in one shell: scatter a shell
    # of each vertex and count the vertices whose pairs all agree with it (no sort); only the pairs
    # of vertices seen in several shells are sorted (a 1-D key: np.unique is many times slower).
    shell_of = np.full(b.n_vertices, -1, dtype=np.int64)
    shell_of[vs] = ss
    mixed = np.zeros(b.n_vertices, dtype=bool)
    mixed[vs[shell_of[vs] != ss]] = True
    single = (shell_of >= 0) & ~mixed
    V = np.bincount(shell_of[single], minlength=ns)
    if np.any(mixed):
        sel = mixed[vs]
        key = np.sort(vs[sel] * ns + ss[sel])
        distinct = key[np.concatenate([[True], key[1:] != key[:-1]])]
        V = V + np.bincount(distinct % ns, minlength=ns)
    chi = V - E + F - (L - F)
    for s in range(ns):
        if chi[s] % 2 or chi[s] > 2:
            out.append(Problem("euler-poincare", "shell", s,
                               f"V - E + F - (L - F) = {int(chi[s])} (V={V[s]}, E={E[s]}, F={F[s]}, L={L[s]}) is not 2(1 - G)"))


# ---------------------------------------------------------------------- geometry
@functools.lru_cache(maxsize=16)
def _unit_samples(samples: int) -> np.ndarray:
    """``np.linspace(0.0, 1.0, samples)``, read-only, made once per count (the check asks it a few times a
    B-rep; numpy's set-up costs more than the few values)."""
    s = np.linspace(0.0, 1.0, samples)
    s.setflags(write=False)
    return s


def _edge_samples(b: BRep, samples: int, edges: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Parameters ``(k, samples)`` and 3-D points ``(k, samples, 3)`` along the given edges (default: all)."""
    edges = np.arange(b.n_edges) if edges is None else np.asarray(edges, dtype=np.int64)
    s = _unit_samples(samples)
    r = b.edge_range[edges]
    T = r[:, :1] + (r[:, 1:] - r[:, :1]) * s
    P = np.empty(T.shape + (3,))
    curve = b.edge_curve[edges]
    straight = curve < 0
    if np.any(straight):
        a = b.vertex_point[b.edge_vertex[edges[straight], 0]]
        c = b.vertex_point[b.edge_vertex[edges[straight], 1]]
        P[straight] = a[:, None, :] + s[None, :, None] * (c - a)[:, None, :]
    # Lines and circles (most curves of a model) in one array expression for all their edges,
    # with the formulas of their own ``evaluate`` (the same floats); any other curve once per object.
    curved = np.flatnonzero(~straight)
    batched = np.array([type(b.curves[int(ci)]) in BATCHED_CURVES for ci in curve[curved].tolist()], dtype=bool)
    rows = curved[batched]
    if rows.size and np.isfinite(T[rows]).all():
        P[rows] = evaluate_curves([b.curves[int(ci)] for ci in curve[rows].tolist()], T[rows])
        curved = curved[~batched]
    if not curved.size:
        return T, P
    # (one stable sort groups the rows by curve, as mass._Paths.evaluate: not a mask per curve)
    curved = curved[np.argsort(curve[curved], kind="stable")]
    ids, starts = np.unique(curve[curved], return_index=True)
    groups = np.split(curved, starts[1:])
    for rows, D in zip(groups, derivatives_many([b.curves[int(ci)] for ci in ids], [T[r].ravel() for r in groups], 0)):
        P[rows] = D[0].reshape(rows.size, samples, 3)
    return T, P


@dataclass(frozen=True)
class _PcurveSamples:
    """The p-curve of every coedge that has one (except those of faces that passed before,
    :func:`_trims_passed`: their ``pos`` is -1 as for a coedge without one), sampled at the edge's
    check parameters.

    Row ``k`` is coedge ``coedge[k]``: ``uv[k]`` its p-curve at the ``samples`` parameters of its
    edge (in the edge's direction, whichever side the coedge is), ``speed[k]`` ``max(|Su|, |Sv|)``
    there, ``line[k]`` whether the p-curve is a :class:`Line2D`; ``pos[c]`` is the row of coedge
    ``c`` or -1.  Built once per check: the geometric and the trim checks share it.  ``gapped``:
    the faces with a p-curve gap between coedges that was judged in 3-D against a vertex (their
    checks depend on more than the face itself: they are never recorded as passed).
    """

    coedge: np.ndarray
    uv: np.ndarray
    speed: np.ndarray
    line: np.ndarray
    pos: np.ndarray
    gapped: frozenset = frozenset()


def _pcurves_at(b: BRep, which: np.ndarray, T: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``b.pcurves[which[k]]`` at the parameters ``T[k]``, ``(k, n, 2)``, lines and ellipses in array time
    from the coefficient rows of the mass tables (:func:`~coons.topology.mass.pcurve_table`: the
    p-curves' own origin and direction, centre and axes, gathered once per B-rep and shared with
    the orientation check's shell volumes); and whether each is a :class:`Line2D`, ``(k,)``."""
    from coons.topology.mass import pcurve_table

    pcurves = b.pcurves
    out = np.empty(T.shape + (2,))
    which = np.asarray(which, dtype=np.int64)
    ids, inv = np.unique(which, return_inverse=True)
    kind = np.array([0 if isinstance(pcurves[i], Line2D) else 1 if isinstance(pcurves[i], Trig2D) else 2
                     for i in ids.tolist()], dtype=np.int64)
    k = kind[inv.reshape(-1)] if ids.size else np.empty(0, dtype=np.int64)
    coef = pcurve_table(b) if (k < 2).any() else None
    rows = np.flatnonzero(k == 0)
    if rows.size:
        C = coef.take(which[rows], axis=0)
        out[rows] = C[:, None, 0:2] + T[rows][..., None] * C[:, None, 2:4]
    rows = np.flatnonzero(k == 1)
    if rows.size:
        C = coef.take(which[rows], axis=0)
        tt = T[rows][..., None]
        out[rows] = C[:, None, 0:2] + np.cos(tt) * C[:, None, 4:6] + np.sin(tt) * C[:, None, 6:8]
    rows = np.flatnonzero(k == 2)
    if rows.size:
        for r, D in zip(rows, derivatives_many([pcurves[int(i)] for i in which[rows]], [T[r] for r in rows], 0)):
            out[r] = D[0]
    return out, k == 0


def _packed(uv: np.ndarray, speed: np.ndarray, dev: np.ndarray, ends: np.ndarray, line: np.ndarray) -> np.ndarray:
    """Rows ``(m, 3 samples + 8)`` holding ``uv (m, samples, 2)``, ``speed (m, samples)``, ``dev (m,)``,
    ``ends (m, 2, 3)`` and ``line (m,)`` (as 0 or 1)."""
    m = dev.shape[0]
    return np.concatenate([uv.reshape(m, 2 * uv.shape[1]), speed, dev[:, None], ends.reshape(m, 6), line[:, None]],
                          axis=1)


def _unpacked(R: np.ndarray, samples: int) -> tuple[np.ndarray, ...]:
    """``uv, speed, dev, ends, line`` of rows made by :func:`_packed`."""
    m, S = R.shape[0], samples
    return (R[:, : 2 * S].reshape(m, S, 2), R[:, 2 * S : 3 * S], R[:, 3 * S], R[:, 3 * S + 1 : 3 * S + 7].reshape(m, 2, 3),
            R[:, 3 * S + 7] != 0.0)


#: P-curve -> ``{(id(curve), id(surface), t0, t1, samples): (curve, surface, rows, k)}``: what the
#: same-parameter check measured along coedges with that p-curve, row ``rows[k]`` (:func:`_packed`:
#: the p-curve at the check parameters, ``max(|Su|, |Sv|)`` there, the largest distance between
#: ``surface(uv)`` and the curve, the curve at the first and last parameter, and whether the p-curve
#: is a :class:`Line2D`) of the read-only rows of one check (held whole, as a view of them would
#: hold them: an entry costs a tuple, no object or view of its own).  Every measurement is a
#: function of the p-curve, the 3-D curve, the surface, the edge range and the number of samples
#: alone, all immutable values: a coedge of a later B-rep with the same five (a face a Boolean
#: passes through unchanged keeps its curve, p-curve and surface objects) has the same
#: measurements, which are compared against its own edge and vertex tolerances again.  Entries die
#: with their p-curve; the curve and surface are held by the entry (their ids stay theirs).
_SAME_PARAMETER = IdentityMemo()


def _first_loops(b: BRep, first: dict[int, int]) -> np.ndarray:
    """``(n_loops,)`` bool: the first ``n`` loops of each face ``f`` of ``first`` (``{f: n}``), the loops a
    face extending an earlier spec shares with it."""
    out = np.zeros(b.n_loops, dtype=bool)
    for f, n in first.items():
        out[b.face_loops[b.face_loop_ptr[f]:b.face_loop_ptr[f] + n]] = True
    return out


def _check_geometry(b: BRep, t: Tolerance, samples: int, out: list[Problem],
                    passed: np.ndarray | None = None,
                    partial: dict[int, tuple[int, "_FaceSums"]] | None = None) -> _PcurveSamples:
    # Only edges with a 3-D curve or a p-curve on a surface are sampled: a straight edge without
    # p-curves is the segment between its vertices, nothing about it can deviate.
    has_pc = (b.edge_pcurve >= 0) & (b.face_surface[b.edge_face] >= 0)  # (E, 2)
    if passed is not None:
        # The coedges of faces that passed every check before as the very same spec
        # (:func:`_trims_passed`): their p-curve deviation is the one measured then against the
        # same edge tolerance (an unchanged face's uses keep theirs), and their loops closed
        # then; only their edges' ends are compared with the vertices again, below.
        has_pc &= ~passed[b.edge_face]
    if partial:
        # Likewise the old loops of a face extending a spec that passed (:func:`_partial_faces`):
        # their uses are the spec's, with their own tolerances as edge tolerances then and now.
        old_loop = _first_loops(b, {f: n for f, (n, _) in partial.items()})
        has_pc &= ~old_loop[b.edge_loop]
    rows = np.flatnonzero((b.edge_curve >= 0) | has_pc.any(axis=1))
    # p-curves: surface(pcurve(t)) == curve(t) within the edge tolerance, every p-curve sample of
    # the model in one batch (surfaces of one structure evaluated together).  A coedge whose
    # curve, p-curve, surface and range were measured before (by the check of an earlier B-rep
    # that shares them: the faces a Boolean passes through unchanged) takes those measurements
    # (:data:`_SAME_PARAMETER`); only the others are sampled.
    rr, side = np.nonzero(has_pc[rows])
    e = rows[rr]
    pi = b.edge_pcurve[e, side]
    f = b.edge_face[e, side]
    n = rr.size
    si = b.face_surface[f]
    ci = b.edge_curve[e]
    hit, H = _cached_samples(b, pi, ci, si, e, samples)
    miss = np.ones(n, dtype=bool)
    miss[hit] = False
    miss = np.flatnonzero(miss)
    uv_h, speed_h, dev_h, ends_h, line_h = _unpacked(H, samples)
    # Edges with a coedge to measure are sampled; those with all coedges measured before take
    # their ends from the record; the others (no p-curve on a surface, or all on faces that
    # passed before) only need their ends: the same first and last parameters and points
    # whatever the number of samples.
    full = np.zeros(rows.size, dtype=bool)
    full[rr[miss]] = True
    sub = np.flatnonzero(full)
    coedged = np.zeros(rows.size, dtype=bool)
    coedged[rr] = True
    ends_only = np.flatnonzero(~coedged)
    Ts, Ps = _edge_samples(b, samples, rows[sub])
    at = np.full(rows.size, -1, dtype=np.int64)
    at[sub] = np.arange(sub.size)
    ends_pts = np.empty((rows.size, 2, 3))
    ends_pts[rr[hit]] = ends_h  # (both uses of an edge measure the same curve over the same range)
    ends_pts[sub] = Ps[:, [0, -1]]
    if ends_only.size:
        ends_pts[ends_only] = _edge_ends(b, rows[ends_only])
    ev = b.edge_vertex[rows]
    ends = b.vertex_point[ev]  # (k, 2, 3)
    allow = b.edge_tol[rows, None] + b.vertex_tol[ev] + t.linear
    gap = _norms(ends_pts - ends)
    bad = np.argwhere(gap > allow)
    for r, k in bad[:10]:
        out.append(Problem("vertex-off-edge", "edge", int(rows[r]),
                           f"its {'start' if k == 0 else 'end'} is {gap[r, k]:.3g} from vertex {int(ev[r, k])} "
                           f"(allowed {allow[r, k]:.3g})"))
    uv = np.empty((n, samples, 2))
    speed = np.empty((n, samples))
    dev = np.empty(n)
    line = np.empty(n, dtype=bool)
    uv[hit], speed[hit], dev[hit], line[hit] = uv_h, speed_h, dev_h, line_h
    if miss.size:
        Tm, Pm = Ts[at[rr[miss]]], Ps[at[rr[miss]]]
        uv_m, line_m = _pcurves_at(b, pi[miss], Tm)
        u_m, v_m = uv_m[..., 0].ravel(), uv_m[..., 1].ravel()
        ids, inv = np.unique(si[miss], return_inverse=True)
        used = [b.surfaces[s] for s in ids.tolist()]
        if all(isinstance(S, BATCHED_SURFACES) for S in used):
            # Planes and surfaces of revolution only (a plate and its holes): their one expression per
            # type straight away on the surfaces measured, the same rows as derivatives_surfaces gives
            # it after grouping them by surface (a sort of every sample's surface index).
            D = surface_derivatives(used, u_m, v_m, 1, np.repeat(inv.reshape(-1), samples))
        else:
            D = derivatives_surfaces(b.surfaces, np.repeat(si[miss], samples), u_m, v_m, 1)
        D = D.reshape(miss.size, samples, 2, 2, 3)
        dev_m = _norms(D[:, :, 0, 0] - Pm).max(axis=1)
        speed_m = np.maximum(_norms(D[:, :, 1, 0]), _norms(D[:, :, 0, 1]))
        uv[miss], speed[miss], dev[miss], line[miss] = uv_m, speed_m, dev_m, line_m
        _remember_samples(b, miss, pi, ci, si, e, samples, _packed(uv_m, speed_m, dev_m, Pm[:, [0, -1]], line_m))
    if rows.size:
        _remember_measured(b, pi, ci, si, e, samples, _packed(uv, speed, dev, ends_pts[rr], line), rows, ends_pts)
    for k in np.flatnonzero(dev > b.edge_tol[e] + t.linear):
        out.append(Problem("pcurve-deviation", "edge", int(e[k]),
                           f"p-curve in face {int(f[k])} is {dev[k]:.3g} from the 3-D curve (edge tolerance "
                           f"{b.edge_tol[e[k]]:.3g})"))
    coedge = 2 * e + side
    pos = np.full(2 * b.n_edges, -1, dtype=np.int64)
    pos[coedge] = np.arange(n)
    # Coedge start/end in parameter space (the right side runs backwards).
    fwd = (side == 0)[:, None]
    start = np.where(fwd, uv[:, 0], uv[:, -1])
    end = np.where(fwd, uv[:, -1], uv[:, 0])
    # Loops closed in parameter space, allowing a jump along a collapsed side (a pole).
    # Equal up to the round-off of evaluating two p-curves at their end parameters: closed.
    # Anything larger is decided in 3-D below (a gap is allowed only where its whole segment
    # maps onto the vertex, as at a pole), so no parameter-space length threshold is guessed.
    j = pos[b.coedge_next[coedge]]
    i = np.flatnonzero(j >= 0)
    j = j[i]
    e_i = end[i]
    far = _norms(e_i - start[j]) > t.solver * (1.0 + np.maximum(np.abs(e_i[:, 0]), np.abs(e_i[:, 1])))
    table = _PcurveSamples(coedge, uv, speed, line, pos,
                           frozenset(b.coedge_face[coedge[i[far]]].tolist()) if far.any() else frozenset())
    if far.any():
        # The gaps' segments (m, samples, 2), each surface evaluated once on all of its gaps (the surfaces'
        # expressions are point by point: the same points as one segment at a time).
        ks, kns = i[far], j[far]
        c_far = coedge[ks]
        s_far = b.face_surface[b.coedge_face[c_far]]
        seg = end[ks][:, None, :] + _unit_samples(samples)[None, :, None] * (start[kns] - end[ks])[:, None, :]
        img = np.empty(seg.shape[:2] + (3,))
        for si_ in np.unique(s_far).tolist():
            sel = s_far == si_
            uv_sel = seg[sel].reshape(-1, 2)
            img[sel] = np.asarray(b.surfaces[si_].evaluate(uv_sel[:, 0], uv_sel[:, 1])).reshape(-1, samples, 3)
        target = b.coedge_target[c_far]
        gap = np.max(_norms(img - b.vertex_point[target][:, None, :]), axis=1)
        for k, kn, c, g, limit in zip(ks.tolist(), kns.tolist(), c_far.tolist(), gap.tolist(),
                                      (b.vertex_tol[target] + t.linear).tolist()):
            if g > limit:
                fc = int(b.coedge_face[c])
                out.append(Problem("pcurve-loop-open", "coedge", c,
                                   f"in face {fc} the p-curve ends at {end[k].round(9).tolist()} but the next starts "
                                   f"at {start[kn].round(9).tolist()}"))
    # Polyhedral faces: vertices on one plane.
    # A face with at most three coedges has at most three vertices, always on one plane.
    n_coedges = np.bincount(b.coedge_face, minlength=b.n_faces)
    implicit = np.flatnonzero((b.face_surface < 0) & (n_coedges > 3))
    if implicit.size:
        from coons.topology.polyhedral import face_plane_deviation

        dev = face_plane_deviation(b, implicit)
        for f, d in zip(implicit[dev > t.linear][:10], dev[dev > t.linear][:10]):
            out.append(Problem("non-planar-face", "face", int(f), f"vertices are up to {d:.3g} off the face's plane"))
    return table


def _cached_samples(b: BRep, pi: np.ndarray, ci: np.ndarray, si: np.ndarray, e: np.ndarray,
                    samples: int) -> tuple[np.ndarray, np.ndarray]:
    """The coedges (p-curve ``pi``, curve ``ci``, surface ``si``, edge ``e``) measured before:
    their positions ``(h,)`` and their rows ``(h, 3 samples + 8)`` (:func:`_packed`).

    First those measured in the donor B-rep (:func:`_donor`: a Boolean's operand for its
    result), found for all coedges at once by their objects' positions in that B-rep's pools
    (:func:`~coons.topology._memo.pool_positions`, values only) and their edge range; then the
    others in :data:`_SAME_PARAMETER`, coedge by coedge.  Both hold the same measurements (of the
    same five immutable values).
    """
    n = pi.size
    width = 3 * samples + 8
    H = np.empty((n, width))
    found = np.zeros(n, dtype=bool)
    r = b.edge_range[e]
    donor, rec = _donor(b) if n else (None, None)
    if rec is not None and rec.samples == samples and rec.key.size:
        # A position of -1 (index -1 reads the appended -1): not in the donor, or not a value.
        pp = np.append(pool_positions(b, donor, "pcurves"), -1)[pi]
        cp = np.append(pool_positions(b, donor, "curves"), -1)[ci]
        sp = np.append(pool_positions(b, donor, "surfaces"), -1)[si]
        ok = (ci >= 0) & (pp >= 0) & (cp >= 0) & (sp >= 0)
        key = (pp * rec.n_curves + cp) * rec.n_surfaces + sp
        found, j = _lookup(rec.key, rec.r0, rec.r1, key, r, ok)
        H[found] = rec.rows[j[found]]
    if len(_SAME_PARAMETER) and not found.all():
        pcurves, curves, surfaces = b.pcurves, b.curves, b.surfaces
        rest = np.flatnonzero(~found & (ci >= 0))
        got = _SAME_PARAMETER.get_many([pcurves[p] for p in pi[rest].tolist()])
        for k, entries, c, s, r0, r1 in zip(rest.tolist(), got, ci[rest].tolist(), si[rest].tolist(),
                                            r[rest, 0].tolist(), r[rest, 1].tolist()):
            if entries is None:
                continue
            curve, surface = curves[c], surfaces[s]
            h = entries.get((id(curve), id(surface), r0, r1, samples))
            if h is not None and h[0] is curve and h[1] is surface:
                found[k] = True
                H[k] = h[2][h[3]]
    idx = np.flatnonzero(found)
    return idx, H[idx]


class _Measured:
    """What :func:`_check_geometry` measured on one B-rep, for the next check (:func:`_cached_samples`,
    :func:`_edge_ends`).  Coedges that have a curve: ``key (m,)`` int64 ``(pcurve · n_curves +
    curve) · n_surfaces + surface`` (positions in the B-rep's pools), sorted; ``r0, r1 (m,)`` the
    edge range; ``rows (m, 3 samples + 8)`` (:func:`_packed`).  Edges that have a curve:
    ``edge_key (k,)`` the curve's position, sorted; ``edge_r0, edge_r1 (k,)``; ``ends (k, 2, 3)``
    the curve at the ends of the range."""

    __slots__ = ("samples", "n_curves", "n_surfaces", "key", "r0", "r1", "rows", "edge_key", "edge_r0", "edge_r1",
                 "ends")


def _remember_measured(b: BRep, pi: np.ndarray, ci: np.ndarray, si: np.ndarray, e: np.ndarray, samples: int,
                       R: np.ndarray, edges: np.ndarray, ends: np.ndarray) -> None:
    """Record the rows ``R`` of the coedges of :func:`_check_geometry` and the curve ends ``ends (k, 2,
    3)`` of its ``edges`` as :data:`_MEASURED` of ``b`` (the only entry: the next B-rep checked
    reads it)."""
    rec = _Measured()
    has = np.flatnonzero(ci >= 0)
    rec.samples, rec.n_curves, rec.n_surfaces = samples, len(b.curves), len(b.surfaces)
    key = (pi[has] * rec.n_curves + ci[has]) * rec.n_surfaces + si[has]
    o = np.argsort(key, kind="stable")
    rec.key = key[o]
    r = b.edge_range[e[has[o]]]
    rec.r0, rec.r1 = r[:, 0].copy(), r[:, 1].copy()
    rec.rows = R[has[o]]
    ec = b.edge_curve[edges]
    has = np.flatnonzero(ec >= 0)
    o = has[np.argsort(ec[has], kind="stable")]
    rec.edge_key = ec[o]
    r = b.edge_range[edges[o]]
    rec.edge_r0, rec.edge_r1 = r[:, 0].copy(), r[:, 1].copy()
    rec.ends = ends[o]
    # Kept: b, and the last sewn B-rep measured (b itself when it is sewn).
    ref = weakref.ref(b)
    sewn = _LAST_MEASURED[0]() if _LAST_MEASURED[0] is not None and b not in _SEWN_FROM else None
    kept = _MEASURED.get(sewn) if sewn is not None else None
    _MEASURED.clear()
    _MEASURED.set(b, rec)
    if kept is not None:
        _MEASURED.set(sewn, kept)
    first = ref if b in _SEWN_FROM else (_LAST_MEASURED[0] if kept is not None else None)
    _LAST_MEASURED[:] = [first, ref]


def _donor(b: BRep) -> tuple[BRep | None, "_Measured | None"]:
    """The B-rep whose measurements ``b`` reads, with its :class:`_Measured`: the last sewn B-rep
    measured (a Boolean's operand, for its result: a tool made and checked since, such as a cylinder
    built and moved for the cut, does not displace it), else the last B-rep measured."""
    for ref in _LAST_MEASURED:
        donor = ref() if ref is not None else None
        if donor is not None and donor is not b:
            rec = _MEASURED.get(donor)
            if rec is not None:
                return donor, rec
    return None, None


#: Entries with one key (the arcs of one circle, the coedges of one p-curve) compared per look-up;
#: a range found among none of them is measured again.
_SAME_KEY = 4


def _lookup(keys: np.ndarray, r0: np.ndarray, r1: np.ndarray, key: np.ndarray, r: np.ndarray,
            valid: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Where ``(key, r[:, 0], r[:, 1])`` occurs among the entries ``(keys, r0, r1)`` (``keys`` sorted):
    ``(found (n,) bool, index (n,))`` for the queries with ``valid``; ranges compared exactly."""
    found = np.zeros(key.size, dtype=bool)
    at = np.zeros(key.size, dtype=np.int64)
    j = np.searchsorted(keys, key)
    last = keys.size - 1
    for step in range(_SAME_KEY):
        k = np.minimum(j + step, last)
        hit = valid & ~found & (keys[k] == key) & (r0[k] == r[:, 0]) & (r1[k] == r[:, 1])
        at[hit] = k[hit]
        found |= hit
    return found, at


def _edge_ends(b: BRep, edges: np.ndarray) -> np.ndarray:
    """The edges' curves (their chords where they have none) at the ends of their ranges, ``(k, 2, 3)``:
    those of edges with the same curve and range in the donor B-rep (:func:`_donor`, measured with
    at least two samples) gathered in one pass, the others evaluated (:func:`_edge_samples`).  The curve's end points are
    a function of the curve and the range alone."""
    donor, rec = _donor(b)
    if rec is None or rec.samples < 2 or not rec.edge_key.size:  # (one sample is the start point only)
        return _edge_samples(b, 2, edges)[1]
    ci = b.edge_curve[edges]
    key = np.append(pool_positions(b, donor, "curves"), -1)[ci]
    ok, j = _lookup(rec.edge_key, rec.edge_r0, rec.edge_r1, key, b.edge_range[edges], (ci >= 0) & (key >= 0))
    out = np.empty((edges.size, 2, 3))
    out[ok] = rec.ends[j[ok]]
    miss = np.flatnonzero(~ok)
    if miss.size:
        out[miss] = _edge_samples(b, 2, edges[miss])[1]
    return out


#: The last B-rep measured and the last sewn one (``_SEWN_FROM``) -> their :class:`_Measured` (at
#: most these two entries), and weak references to those two B-reps (sewn first): a Boolean's
#: result takes the measurements of the coedges it shares with its operand from there in one
#: gather (:func:`_donor`, :func:`_cached_samples`, :func:`_edge_ends`).
_MEASURED = IdentityMemo()
_LAST_MEASURED: list = [None, None]


def _remember_samples(b: BRep, rows: np.ndarray, pi: np.ndarray, ci: np.ndarray, si: np.ndarray, e: np.ndarray,
                      samples: int, R: np.ndarray) -> None:
    """Store the measurements ``R`` (:func:`_packed`, in the order of ``rows``) of the coedges
    ``rows`` (of the arrays of :func:`_check_geometry`) whose curve, p-curve and surface are values.

    One pass over the coedges: the rows are kept as one read-only copy that every entry indexes,
    the keys and entries are made by ``zip`` in C, the p-curves new to :data:`_SAME_PARAMETER` are
    given their entries in one call (a Boolean's result brings a thousand new coedges)."""
    has = np.flatnonzero(ci[rows] >= 0)
    sel = rows[has]
    P = [b.pcurves[p] for p in pi[sel].tolist()]
    C = [b.curves[c] for c in ci[sel].tolist()]
    S = [b.surfaces[s] for s in si[sel].tolist()]
    held = _read_only(R[has])
    r = b.edge_range[e[sel]]
    keys = zip(map(id, C), map(id, S), r[:, 0].tolist(), r[:, 1].tolist(), repeat(samples))
    todo = zip(P, keys, zip(C, S, repeat(held), range(len(P))), _SAME_PARAMETER.get_many(P))
    objs = P + C + S
    if not all_values(objs):
        todo = [t for t in todo if is_value(t[0]) and is_value(t[2][0]) and is_value(t[2][1])]
    fresh: dict[int, tuple] = {}  # id(p-curve) -> (p-curve, its new entry)
    for pcurve, key, entry, entries in todo:
        if entries is None:
            new = fresh.get(id(pcurve))
            if new is None:
                new = fresh[id(pcurve)] = (pcurve, {})
            entries = new[1]
        entries[key] = entry
    if fresh:
        _SAME_PARAMETER.set_many([pc for pc, _ in fresh.values()], [entries for _, entries in fresh.values()])


# ---------------------------------------------------------------------- trims
#: B-rep made by :func:`~coons.topology.sew.sew_faces` (or recorded by
#: :func:`~coons.topology.sew.remember_sewn`) -> (its face specs in face order, a tuple; ``(F,)`` bool:
#: the faces equal to their spec, :func:`~coons.topology.sew.sewn_unchanged`).  Read through
#: :func:`~coons.topology.sew.sewn_from`.
_SEWN_FROM: "weakref.WeakKeyDictionary[BRep, tuple[tuple, np.ndarray]]" = weakref.WeakKeyDictionary()
#: Face spec -> the :func:`_trims_key` values with which a B-rep face equal to it passed the trim
#: checks (in a check that found no problem at all).
_TRIMS_PASSED = IdentityMemo()
#: Surface -> weak references to the last few specs with many loops on it that passed the trim
#: checks: a face that extends one of them by new loops (a plate's top gaining a hole) has only
#: the pairs involving its new loops tested (:func:`_trims_passed`).
_PASSED_ON = IdentityMemo()
#: Spec recorded in :data:`_PASSED_ON` -> ``{trims key: _FaceSums}``: its face's total signed
#: parameter-plane area, largest ring box and speed, and loop boxes as :func:`_sampled_rings` found
#: them in the clean check that recorded it.  A face extending the spec takes them for its old
#: loops instead of measuring them and making their rings again (:func:`_partial_faces`).
_PASSED_SUMS = IdentityMemo()
#: Loops from which a face is worth recording in :data:`_PASSED_ON`, and how many are kept per surface.
_PREFIX_LOOPS, _PREFIX_KEPT = 16, 4


def _trims_passed(b: BRep, known: tuple[list, np.ndarray], t: Tolerance,
                  samples: int, found: dict | None = None) -> tuple[np.ndarray, dict[int, int]]:
    """``(F,)`` bool: faces equal to a spec that passed the trim checks with ``t`` and ``samples``;
    and ``{face: n}`` for faces equal to a spec whose first ``n`` loops are, use for use, the
    loops of a spec that passed (same surface and sense, a plane or a cylinder, whose parameter
    scale, and so the crossing threshold, does not depend on where the loops lie).  ``found``, when
    given, receives ``{face: that spec}``."""
    specs, unchanged = known
    key = _trims_key(t, samples)
    passed = np.zeros(len(specs), dtype=bool)
    rest = np.flatnonzero(unchanged)
    rec = _PASSED_FACES.last()
    if rec is not None and rec.key == key and rest.size and rec.ids.size:
        # The specs the last clean check recorded: found by id in one pass (it holds them).  What
        # it says is of the spec objects (each marked one is in _TRIMS_PASSED under ``key``), not
        # of the B-rep checked then: it holds for any B-rep on them, ``b`` itself checked again too.
        k, same = found_by_id(specs, rec.ids, rec.order)
        passed = unchanged & same & rec.passed[k]
        rest = np.flatnonzero(unchanged & ~passed)
    got = _TRIMS_PASSED.get_many([specs[i] for i in rest.tolist()])
    passed[rest] = np.fromiter((g is not None and key in g for g in got), dtype=bool, count=rest.size)
    extends: dict[int, int] = {}
    if len(_PASSED_ON):
        n_loops = np.diff(b.face_loop_ptr)
        sizes = None
        for f in np.flatnonzero(unchanged & ~passed & (n_loops >= _PREFIX_LOOPS)).tolist():
            spec = specs[f]
            if type(spec.surface) not in (PlanarSurface, CylindricalSurface):
                continue
            best = 0
            olds = [old for old in (ref() for ref in _PASSED_ON.get(spec.surface, ()))
                    if old is not None and old.sense == spec.sense and 0 < len(old.loops) < len(spec.loops)
                    and key in (_TRIMS_PASSED.get(old) or ())]
            # The longest prefix wins: try the specs from the most loops down, stop at the first match.
            for old in sorted(olds, key=lambda x: -len(x.loops)):
                n = len(old.loops)
                if (list(map(len, old.loops)) == list(map(len, spec.loops[:n]))
                        and all(map(operator.is_, chain.from_iterable(old.loops),
                                    chain.from_iterable(spec.loops[:n])))):
                    best = n
                    break
            if best:
                # The B-rep keeps the spec's loop order (its coedge counts agree loop by loop).
                if sizes is None:
                    cl = b.coedge_loop
                    sizes = np.bincount(cl[cl >= 0], minlength=b.n_loops)
                loops = b.face_loops[b.face_loop_ptr[f]:b.face_loop_ptr[f + 1]]
                if sizes[loops].tolist() == [len(loop) for loop in spec.loops]:
                    extends[f] = best
                    if found is not None:
                        found[f] = old
    return passed, extends


class _Passed:
    """The faces of one clean check recorded in :data:`_TRIMS_PASSED` (:func:`_remember_passed`):
    ``specs`` (held, so that their ids stay theirs), ``ids (F,)`` int64 sorted and ``order (F,)``
    the faces in that order, ``passed (F,)`` bool, and the :func:`_trims_key` ``key``."""

    __slots__ = ("specs", "ids", "order", "passed", "key")


#: The last sewn B-rep whose check found nothing -> its :class:`_Passed` (one entry), and a weak
#: reference to that B-rep: the next check (a Boolean's result on its operand's faces) finds
#: which of its specs passed in one array pass, not one look-up per face (:func:`_trims_passed`).
_PASSED_FACES = LastRecord()


def _remember_passed(b: BRep, known: tuple[list, np.ndarray], passed: np.ndarray, t: Tolerance,
                     samples: int) -> None:
    """Keep which faces of ``b`` (its specs ``known[0]``) are recorded as passed, for the next check."""
    rec = _Passed()
    rec.specs = tuple(known[0])
    rec.ids, rec.order = id_index(rec.specs)
    rec.passed = passed.copy()
    rec.key = _trims_key(t, samples)
    _PASSED_FACES.keep(b, rec)


def _remember_trims(b: BRep, known: tuple[list, np.ndarray], passed: np.ndarray, t: Tolerance, samples: int,
                    gapped: frozenset = frozenset(), sums: dict | None = None) -> np.ndarray:
    """Record that the unchanged faces' specs of ``b`` passed the checks (the check found nothing),
    except the faces whose loop closure was judged against a vertex (``gapped``), and those whose
    spec, surface, curves or p-curves are not all values (what the record depends on could change
    under it); ``(F,)`` bool, the faces recorded.  An unchanged face's uses hold the very curves
    and p-curves of its coedges in ``b``: their being values is read from the pools
    (:func:`_value_faces`).  A spec recorded in :data:`_PASSED_ON` also keeps its face's orientation
    sums from ``sums`` (:func:`_sampled_rings`) in :data:`_PASSED_SUMS`."""
    specs, unchanged = known
    key = _trims_key(t, samples)
    todo = np.flatnonzero(unchanged & ~passed).tolist()
    values = _value_faces(b) if todo else None
    recorded = np.zeros(len(specs), dtype=bool)
    for f in todo:
        spec = specs[f]
        if f not in gapped and values[f] and is_value(spec) and is_value(spec.surface):
            _TRIMS_PASSED.setdefault(spec, set).add(key)
            recorded[f] = True
            if (len(spec.loops) >= _PREFIX_LOOPS and type(spec.surface) in (PlanarSurface, CylindricalSurface)
                    and is_value(spec.surface)):
                refs = [r for r in _PASSED_ON.get(spec.surface, ()) if r() is not None][-(_PREFIX_KEPT - 1):]
                _PASSED_ON.set(spec.surface, refs + [weakref.ref(spec)])
                if sums is not None and f in sums:
                    _PASSED_SUMS.setdefault(spec, dict)[key] = sums[f]
    return recorded


def _value_faces(b: BRep, exempt: np.ndarray | None = None) -> np.ndarray:
    """``(F,)`` bool: every coedge of the face has a curve and a p-curve, both values
    (:func:`~coons.topology._memo.pool_values`); the coedges of the loops ``exempt`` ``(L,)`` bool
    (if given) are not asked."""
    cv = np.append(pool_values(b, "curves"), False)  # (index -1, none, reads False)
    pv = np.append(pool_values(b, "pcurves"), False)
    ok = np.repeat(cv[b.edge_curve], 2) & pv[b.edge_pcurve.ravel()]
    if exempt is not None:
        ok |= exempt[b.coedge_loop]
    out = np.ones(b.n_faces, dtype=bool)
    out[b.coedge_face[~ok]] = False
    return out


def _trims_key(t: Tolerance, samples: int) -> tuple:
    """What a face's trim checks depend on besides the face: the tolerance, the samples and the refinement."""
    return t, samples, _REFINE, _REFINE_LEVELS


def _instances(objs: tuple, cls: type) -> np.ndarray:
    """``(n + 1,)`` bool: which of ``objs`` are ``cls`` instances, and True last (read at index -1: none)."""
    n = len(objs)
    out = np.ones(n + 1, dtype=bool)
    out[:n] = np.fromiter(map(isinstance, objs, repeat(cls)), dtype=bool, count=n)  # (no Python-level loop)
    return out


def _partial_faces(b: BRep, extends: dict[int, int] | None, found: dict, t: Tolerance,
                   samples: int) -> dict[int, tuple[int, "_FaceSums"]]:
    """``{face: (n, sums)}``: the faces of ``extends`` (``{face: n}``, :func:`_trims_passed`) whose
    spec extends one (``found``: ``{face: that spec}``) with :class:`_FaceSums` recorded under this
    check's key (:data:`_PASSED_SUMS`).  Their first ``n`` loops are, use for use, the loops of a
    face that passed every check, in the face they are now too (an unchanged face's uses keep their
    curves, p-curves, ranges and tolerances, which its edges take): their p-curves' deviation and
    closure are those measured then, their crossings with each other and their orientation were
    judged then.  The check measures and rings only their new loops (and old ones near them)."""
    out: dict[int, tuple[int, _FaceSums]] = {}
    if not extends:
        return out
    key = _trims_key(t, samples)
    for f, n in extends.items():
        got = _PASSED_SUMS.get(found[f]) if f in found else None
        x = got.get(key) if got is not None else None
        if x is not None and x.lo.shape[0] == n and b.face_surface[f] >= 0:
            out[f] = (n, x)
    return out


def _check_trims(b: BRep, t: Tolerance, samples: int, out: list[Problem], table: _PcurveSamples,
                 passed: np.ndarray | None = None, extends: dict[int, int] | None = None,
                 partial: dict[int, tuple[int, "_FaceSums"]] | None = None) -> dict[int, "_FaceSums"]:
    """Self-intersecting trim loops: two segments of a face's boundary polylines crossing properly.

    Every loop of a face is turned into a closed polyline in the face's parameter plane (its
    p-curves sampled at ``samples`` parameters, straight p-curves at their ends, the jump at a
    pole as one segment); implicit planar faces use their vertices (and sampled curved edges)
    projected on the face's Newell plane.  All segment pairs of all loops of a face are tested
    for a *proper* crossing (each segment's ends strictly on opposite sides of the other's
    line), neighbours in a loop excluded, after a sweep-and-prune broad phase along ``u``
    (all faces at once).  "Strictly" means farther than a parameter-space tolerance: ``tol.linear``
    for implicit planes, ``tol.linear / max(|Su|, |Sv|)`` over the loop's samples on surfaces
    (a parameter step that maps to less than ``tol.linear`` in space is touching, not crossing).
    Touching loops and shared vertices are therefore accepted.  The polylines are samples:
    chords cut the corners of curved edges by their sagitta, so loops closer than that (a hole
    grazing a circular rim) cross as polylines but not as curves.  Faces with crossings are
    therefore sampled again :data:`_REFINE` times finer, up to :data:`_REFINE_LEVELS` times, then
    once more with samples falling towards the edges' ends (:data:`_DENSE_ENDS`: where two edges
    leave a vertex tangent to each other, a chord from the vertex cuts into the other edge at any
    uniform spacing), and only crossings that persist are reported (a real crossing persists at
    every level).  A
    crossing of the true curves that the coarse chords miss is not found.  Planar faces made of
    one loop of at most three straight edges cannot self-intersect and are skipped, and so are
    the faces of ``passed`` (``(F,)`` bool, :func:`_trims_passed`), for crossings and orientation;
    in a face of ``extends`` (``{face: n}``) two segments of its first ``n`` loops are not tested
    against each other (they were, in the spec it extends); of the faces of ``partial``
    (:func:`_partial_faces`) the old loops far from the new ones are not even made into rings
    (:func:`_sampled_rings`).  Returns the :class:`_FaceSums` of the faces with many loops.
    """
    sums: dict[int, _FaceSums] = {}
    if b.n_faces == 0 or b.n_edges == 0:
        return sums
    parts: list[tuple[np.ndarray, ...]] = []
    # Index -1 (no curve: a straight segment; no p-curve) reads the appended True.
    straight_curve = _instances(b.curves, Line)[b.edge_curve]
    straight_pc = _instances(b.pcurves, Line2D)[b.edge_pcurve]  # (E, 2)
    implicit = b.face_surface < 0
    cf = b.coedge_face
    straight_c = np.where(implicit[cf], np.repeat(straight_curve, 2), straight_pc.ravel())
    all_straight = np.ones(b.n_faces, dtype=bool)
    all_straight[cf[~straight_c]] = False
    n_loops = np.diff(b.face_loop_ptr)
    n_coedges = np.bincount(cf, minlength=b.n_faces)
    # At most three straight edges in one loop cannot cross each other — unless the loop also jumps
    # across a collapsed side in parameter space, which only non-planar surfaces have.
    flat = _instances(b.surfaces, PlanarSurface)[b.face_surface]
    simple = (n_loops == 1) & (n_coedges <= 3) & all_straight & flat
    vec_faces = implicit & all_straight & ~simple
    if np.any(vec_faces):
        parts.append(_implicit_segments(b, vec_faces, t))
    on_surface = b.face_surface >= 0
    todo = on_surface if passed is None else on_surface & ~passed  # (implicit planes never pass before)
    # Faces on surfaces: rings from the p-curve samples of the geometric check, all faces at once
    # (orientation of every one, segments of those that can cross); implicit planes face by face.
    seg = _sampled_rings(b, np.flatnonzero(todo & ~simple), np.flatnonzero(todo & simple),
                         table, samples, t, out, partial, sums)
    if seg is not None:
        parts.append(seg)
    for f in np.flatnonzero(~simple & ~vec_faces & ~on_surface):
        seg = _face_segments(b, int(f), samples, t)
        if seg is not None:
            parts.append(seg)
    if not parts:
        return sums
    old_loop = None
    if extends:
        old_loop = _first_loops(b, extends)
        parts = [_near_new_loops(b, p, old_loop) for p in parts]
    hits = _crossings(parts, None if old_loop is None else old_loop[b.coedge_loop])
    # Chords of curved edges cut corners by their sagitta: loops closer than that (an ellipse hole
    # grazing a circular rim) cross as polylines but not as curves.  Faces with crossings are
    # sampled again, _REFINE times finer per level; only crossings that persist are reported.
    n = samples
    for _ in range(_REFINE_LEVELS):
        if not hits:
            break
        n = (n - 1) * _REFINE + 1
        finer = [_face_segments(b, f, n, t) for f in sorted(hits)]
        hits = _crossings([p for p in finer if p is not None])
    # Where two edges of a face leave a vertex tangent to each other (a loop touching itself or another
    # loop there: a hole internally tangent to a rim, the crescent between them), the chord from the
    # vertex along the flatter edge cuts into the other edge by a fixed fraction of its length at any
    # uniform spacing; chords falling geometrically towards the ends leave the two curves apart.
    if hits:
        finer = [_face_segments(b, f, n, t, dense_ends=True) for f in sorted(hits)]
        hits = _crossings([p for p in finer if p is not None])
    for f in sorted(hits)[:10]:
        ci, cj, x = hits[f]
        out.append(Problem("self-intersecting-trim", "face", f,
                           f"edge {ci >> 1} of loop {int(b.coedge_loop[ci])} crosses edge {cj >> 1} of loop "
                           f"{int(b.coedge_loop[cj])} near {np.round(x, 9).tolist()} in the face's parameter plane"))
    return sums


def _near_new_loops(b: BRep, part: tuple[np.ndarray, ...], old_loop: np.ndarray) -> tuple[np.ndarray, ...]:
    """The segments ``part`` (of :func:`_face_segments`' form) without the loops of ``old_loop``
    (``(L,)`` bool, loops tested against each other before) whose box, widened by the crossing
    threshold ``eps``, misses the box of their face's new segments (widened alike).

    Two old segments are never tested, and an old segment crosses another properly only where
    the two meet, inside both boxes: a loop whose widened box misses its face's new segments has
    no pair left to test (a plate's top gaining a hole keeps its rim and the holes next to the
    new one).  Loops are dropped whole, so the rings (``next``) stay closed, renumbered.
    """
    A, B, face, nxt, coedge, eps = part
    loop = b.coedge_loop[coedge]
    old = old_loop[loop]
    if not old.any():
        return part
    lo = np.minimum(A, B) - eps[:, None]
    hi = np.maximum(A, B) + eps[:, None]
    # Boxes per run of one loop (the rings come loop by loop), then per loop and per face.
    starts = np.flatnonzero(np.concatenate([[True], loop[1:] != loop[:-1]]))
    rlo, rhi = np.minimum.reduceat(lo, starts, axis=0), np.maximum.reduceat(hi, starts, axis=0)
    rl = loop[starts]
    llo = np.full((b.n_loops, 2), np.inf)
    lhi = np.full((b.n_loops, 2), -np.inf)
    np.minimum.at(llo, rl, rlo)  # (a loop in several runs: the union of their boxes)
    np.maximum.at(lhi, rl, rhi)
    lf = b.loop_face
    new = ~old_loop[rl]
    flo = np.full((b.n_faces, 2), np.inf)
    fhi = np.full((b.n_faces, 2), -np.inf)
    np.minimum.at(flo, lf[rl[new]], rlo[new])
    np.maximum.at(fhi, lf[rl[new]], rhi[new])
    near = ~old_loop | ((llo <= fhi[lf]).all(axis=1) & (flo[lf] <= lhi).all(axis=1))
    keep = np.flatnonzero(near[loop])
    if keep.size == A.shape[0]:
        return part
    at = np.full(A.shape[0], -1, dtype=np.int64)
    at[keep] = np.arange(keep.size)
    return A[keep], B[keep], face[keep], at[nxt[keep]], coedge[keep], eps[keep]


def _loop_ranks(b: BRep) -> np.ndarray:
    """Position of every coedge in its loop, counted from the loop's first coedge (list ranking by pointer jumping)."""
    nc = 2 * b.n_edges
    first = np.zeros(nc, dtype=bool)
    has = b.loop_coedge >= 0
    first[b.loop_coedge[has]] = True
    rank = np.where(first, 0, 1)
    jump = b.coedge_prev.copy()
    done = first.copy()
    # Every loop is one cycle holding its first coedge (checked before): each round doubles the
    # reach, so ceil(log2(nc)) + 1 rounds finish.
    for _ in range(max(1, nc).bit_length() + 1):
        if done.all():
            break
        todo = np.flatnonzero(~done)
        nxt = jump[todo]
        rank[todo] += rank[nxt]
        done[todo] = done[nxt]
        jump[todo] = jump[nxt]
    return rank


def _ring_successors(ring: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Rings as contiguous runs of equal labels ``ring (m,)``: the first index of each run, and each
    point's successor in its ring (the last point's is the run's first)."""
    m = ring.shape[0]
    starts = np.flatnonzero(np.concatenate([[True], ring[1:] != ring[:-1]]))
    nxt = np.arange(1, m + 1)
    nxt[np.append(starts[1:], m) - 1] = starts
    return starts, nxt


class _FaceSums:
    """What the trim checks found of one face with many loops (:func:`_sampled_rings`), kept with its
    spec for a face that extends it (:data:`_PASSED_SUMS`): ``area`` its loops' total signed
    parameter-plane area, ``scale`` the largest product of a ring's box sides, ``stretch`` the
    largest speed ``max(|Su|, |Sv|)`` at its ring points, ``lo, hi (L, 2)`` each loop's box of all
    its p-curve samples, in the face's loop order."""

    __slots__ = ("area", "scale", "stretch", "lo", "hi")


def _loop_boxes(b: BRep, c: np.ndarray, uv: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The loops of the coedges ``c`` (sorted) and each one's box ``lo, hi (l, 2)`` of the samples
    ``uv (n, samples, 2)`` of its coedges in ``c``."""
    # (samples, n, 2), contiguous: a reduction over the outer axis runs elementwise (over a short
    # inner axis numpy runs row by row, about 40 times slower here)
    U = np.ascontiguousarray(uv.transpose(1, 0, 2))
    cl = b.coedge_loop[c]
    o = np.argsort(cl, kind="stable")
    first = np.flatnonzero(np.concatenate([[True], cl[o][1:] != cl[o][:-1]]))
    return (cl[o][first], np.minimum.reduceat(U.min(axis=0)[o], first, axis=0),
            np.maximum.reduceat(U.max(axis=0)[o], first, axis=0))


def _coedge_samples(b: BRep, c: np.ndarray, samples: int) -> tuple[np.ndarray, np.ndarray]:
    """The p-curve samples of the coedges ``c`` (each with a p-curve on a surface), as
    :func:`_check_geometry` takes them: ``uv (n, samples, 2)``, ``line (n,)``; from the
    measurements of an earlier check where there are some (:func:`_cached_samples`), else
    evaluated.  Nothing is compared with a tolerance here (for coedges checked before)."""
    e, side = c >> 1, c & 1
    pi = b.edge_pcurve[e, side]
    si = b.face_surface[b.edge_face[e, side]]
    hit, H = _cached_samples(b, pi, b.edge_curve[e], si, e, samples)
    uv = np.empty((c.size, samples, 2))
    line = np.empty(c.size, dtype=bool)
    uv_h, _, _, _, line_h = _unpacked(H, samples)
    uv[hit], line[hit] = uv_h, line_h
    miss = np.ones(c.size, dtype=bool)
    miss[hit] = False
    miss = np.flatnonzero(miss)
    if miss.size:
        T, _ = _edge_samples(b, samples, e[miss])
        uv[miss], line[miss] = _pcurves_at(b, pi[miss], T)
    return uv, line


def _ring_points(b: BRep, c: np.ndarray, k: np.ndarray, uv: np.ndarray, line: np.ndarray, samples: int,
                 ranks: np.ndarray, speed: np.ndarray | None = None) -> tuple[np.ndarray, ...]:
    """The rings of the loops of the coedges ``c`` (each loop whole; coedge ``c[i]`` sampled in row
    ``k[i]`` of ``uv, line`` and ``speed``, :class:`_PcurveSamples`' columns): points ``(m, 2)`` loop
    by loop in loop order (both ends of a :class:`Line2D`, every sample of other p-curves, reversed
    on the right side), and per point its coedge, loop, face and speed (None without ``speed``).
    ``ranks``: :func:`_loop_ranks`."""
    o = np.lexsort((ranks[c], b.coedge_loop[c]))  # loops of one face are contiguous: a face owns its loops
    c, k = c[o], k[o]
    loop = b.coedge_loop[c]
    S = samples
    npts = np.where(line[k], 2, S)
    rep = np.repeat(np.arange(c.size), npts)
    local = np.arange(rep.size) - np.repeat(np.cumsum(npts) - npts, npts)
    sidx = np.where(line[k][rep], local * (S - 1), local)
    sidx = np.where((c[rep] & 1) == 1, S - 1 - sidx, sidx)  # the right side runs backwards
    kr = k[rep]
    owner = c[rep]
    return uv[kr, sidx], owner, loop[rep], b.coedge_face[owner], None if speed is None else speed[kr, sidx]


def _sampled_rings(b: BRep, cross_faces: np.ndarray, sense_faces: np.ndarray, table: _PcurveSamples, samples: int,
                   t: Tolerance, out: list[Problem], partial: dict[int, tuple[int, _FaceSums]] | None = None,
                   sums: dict[int, _FaceSums] | None = None) -> tuple[np.ndarray, ...] | None:
    """:func:`_face_rings` and :func:`_face_segments` for many faces on surfaces at once, and their orientation.

    Every loop of ``cross_faces`` and ``sense_faces`` becomes its ring of p-curve samples (both
    ends of a :class:`Line2D`, every sample of other p-curves, reversed on the right side) taken
    from ``table``; faces with a coedge without p-curve are skipped, as there.  The orientation of
    every face is checked (appending to ``out``); the segments of ``cross_faces`` are returned in
    the form of :func:`_face_segments` (one part for all of them), or None when there are none.

    Orientation: with ``face_sense`` True (outward normal ``Su × Sv``) the outer loop runs
    counter-clockwise in the parameter plane and holes clockwise, so the loops' total signed area
    (shoelace over the rings) is positive; with False it is negative.  A face whose loops run the
    other way has its material on the wrong side: the shell's volume can still come out right when
    another face compensates, so the sign is checked per face.  Areas within the sampling's
    resolution of zero (``1e-9`` of the largest ring's parameter box) are not judged.

    ``partial``: ``{face: (n, sums)}`` for faces whose first ``n`` loops are, use for use, those of
    a spec that passed the trim checks (:func:`_trims_passed`'s ``extends``) with its
    :class:`_FaceSums`; ``table`` need not hold those loops' coedges (:func:`check` leaves them
    out).  Their area is the recorded one plus the new loops', their scale and stretch the larger
    of the recorded and the new loops' (a maximum over a union: the very floats of all the rings;
    the area, a sum in another order, may differ in its last bits, which only a sign decides).  Of
    their old loops, only those whose recorded box, widened by the crossing threshold, meets the
    widened box of the face's new ring points become rings, for the crossing search: a superset
    of those :func:`_near_new_loops` then keeps (its boxes are of the segments left after dropping
    repeats), their samples from :func:`_coedge_samples`.  ``sums``, when given, receives the
    :class:`_FaceSums` of the judged faces of :data:`_PREFIX_LOOPS` loops or more (what
    :func:`_remember_trims` records).
    """
    faces = np.concatenate([cross_faces, sense_faces]).astype(np.int64)
    if faces.size == 0 or b.n_edges == 0:
        return None
    want = np.zeros(b.n_faces, dtype=bool)
    want[faces] = True
    c = np.flatnonzero(want[b.coedge_face])
    ptr = b.face_loop_ptr
    if partial:
        old_loop = _first_loops(b, {f: n for f, (n, _) in partial.items()})
        c = c[~old_loop[b.coedge_loop[c]]]
    missing = np.zeros(b.n_faces, dtype=bool)
    missing[b.coedge_face[c[table.pos[c] < 0]]] = True
    c = c[~missing[b.coedge_face[c]]]
    if c.size == 0:
        return None
    ranks = _loop_ranks(b)
    pts, owner, ring, face, speed = _ring_points(b, c, table.pos[c], table.uv, table.line, samples, ranks, table.speed)
    m = pts.shape[0]
    starts, nxt = _ring_successors(ring)
    ring_id = np.repeat(np.arange(starts.size), np.diff(np.append(starts, m)))
    # Orientation: the shoelace area of each ring (relative to its first point), summed per face.
    x = pts - pts[starts][ring_id]
    area = 0.5 * np.bincount(face, weights=x[:, 0] * x[nxt, 1] - x[nxt, 0] * x[:, 1], minlength=b.n_faces)
    ptp = np.maximum.reduceat(pts, starts, axis=0) - np.minimum.reduceat(pts, starts, axis=0)
    scale = np.zeros(b.n_faces)
    np.maximum.at(scale, face[starts], ptp[:, 0] * ptp[:, 1])
    stretch = np.zeros(b.n_faces)
    np.maximum.at(stretch, face, speed)
    judged = np.zeros(b.n_faces, dtype=bool)
    judged[face] = True
    done = [f for f in partial if judged[f]] if partial else []
    for f in done:
        old = partial[f][1]
        area[f] += old.area
        scale[f] = max(scale[f], old.scale)
        stretch[f] = max(stretch[f], old.stretch)
    wrong = judged & (np.abs(area) > 1e-9 * scale) & ((area > 0) != b.face_sense.astype(bool))
    for f in np.flatnonzero(wrong):
        out.append(Problem("face-orientation", "face", int(f),
                           f"its loops enclose signed area {area[f]:.6g} in the parameter plane but face_sense is "
                           f"{bool(b.face_sense[f])} (the face lies on the wrong side of its boundary)"))
    if sums is not None:
        many = np.flatnonzero(judged & (np.diff(ptr) >= _PREFIX_LOOPS))
        if many.size:
            wanted = np.zeros(b.n_faces, dtype=bool)
            wanted[many] = True
            mc = c[wanted[b.coedge_face[c]]]
            loops, lo, hi = _loop_boxes(b, mc, table.uv[table.pos[mc]])
            at = np.full(b.n_loops, -1, dtype=np.int64)
            at[loops] = np.arange(loops.size)
            for f in many.tolist():
                fl = at[b.face_loops[ptr[f]:ptr[f + 1]]]
                x = _FaceSums()
                x.area, x.scale, x.stretch = float(area[f]), float(scale[f]), float(stretch[f])
                n = partial[f][0] if f in done else 0
                fl = fl[n:]
                x.lo, x.hi = lo[fl], hi[fl]
                if n:
                    old = partial[f][1]
                    x.lo, x.hi = np.concatenate([old.lo, x.lo]), np.concatenate([old.hi, x.hi])
                x.lo.setflags(write=False)
                x.hi.setflags(write=False)
                sums[f] = x
    # Segments of the faces tested for crossings, consecutive repeats (closer than eps) dropped.
    eps_face = np.where(stretch > 0, t.linear / np.where(stretch > 0, stretch, 1.0), t.linear)
    crossing = np.zeros(b.n_faces, dtype=bool)
    crossing[cross_faces] = True
    near = [f for f in done if crossing[f]]
    if near:
        # The old loops near the new ones, as _near_new_loops tests them, term for term, on boxes
        # that can only be larger: it keeps no loop that this drops.
        keep_loop = np.zeros(b.n_loops, dtype=bool)
        for f in near:
            n, old = partial[f]
            mine = pts[face == f]
            e = eps_face[f]
            flo, fhi = mine.min(axis=0) - e, mine.max(axis=0) + e
            meet = (old.lo - e <= fhi) & (flo <= old.hi + e)
            keep_loop[b.face_loops[ptr[f]:ptr[f] + n][meet[:, 0] & meet[:, 1]]] = True
        c_near = np.flatnonzero(keep_loop[b.coedge_loop])
        if c_near.size:
            uv2, line2 = _coedge_samples(b, c_near, samples)
            P2 = _ring_points(b, c_near, np.arange(c_near.size), uv2, line2, samples, ranks)
            pts, owner, ring, face = (np.concatenate([u, v]) for u, v in zip((pts, owner, ring, face), P2[:4]))
            m = pts.shape[0]
            starts, nxt = _ring_successors(ring)
            ring_id = np.repeat(np.arange(starts.size), np.diff(np.append(starts, m)))
    prv = np.empty(m, dtype=np.int64)
    prv[nxt] = np.arange(m)
    keep = crossing[face] & (_norms(pts - pts[prv]) > eps_face[face])
    idx = np.flatnonzero(keep)
    if idx.size == 0:
        return None
    _, nxt2 = _ring_successors(ring_id[idx])
    A = pts[idx]
    return A, A[nxt2], face[idx], nxt2, owner[idx], eps_face[face[idx]]


def _crossings(parts: list[tuple[np.ndarray, ...]],
               old_coedge: np.ndarray | None = None) -> dict[int, tuple[int, int, np.ndarray]]:
    """Faces whose boundary segments cross properly: face -> (coedge, coedge, crossing point).

    ``parts`` are segment sets of :func:`_face_segments` / :func:`_implicit_segments`
    (``A, B, face, next, coedge, eps``); each face is reported once, with its first crossing.
    ``old_coedge (2E,)`` bool: two segments of such coedges are not tested against each other.
    """
    offsets = np.cumsum([0] + [p[0].shape[0] for p in parts[:-1]])
    A = np.concatenate([p[0] for p in parts])
    B = np.concatenate([p[1] for p in parts])
    face = np.concatenate([p[2] for p in parts])
    nxt = np.concatenate([p[3] + o for p, o in zip(parts, offsets)])
    coedge = np.concatenate([p[4] for p in parts])
    eps = np.concatenate([p[5] for p in parts])
    i, j = _segment_pairs(A, B, face, nxt, old=None if old_coedge is None else old_coedge[coedge])
    if i.size == 0:
        return {}
    keep = (nxt[i] != j) & (nxt[j] != i)
    i, j = i[keep], j[keep]
    di, dj = B[i] - A[i], B[j] - A[j]
    li, lj = _norms(di), _norms(dj)
    ok = (li > 0) & (lj > 0)
    i, j, di, dj, li, lj = i[ok], j[ok], di[ok], dj[ok], li[ok], lj[ok]

    def side(d, l, o, p):  # signed distance of p from the line through o along d
        q = p - o
        return (d[:, 0] * q[:, 1] - d[:, 1] * q[:, 0]) / l

    e = eps[i]
    s1, s2 = side(di, li, A[i], A[j]), side(di, li, A[i], B[j])
    s3, s4 = side(dj, lj, A[j], A[i]), side(dj, lj, A[j], B[i])
    cross = (((s1 > e) & (s2 < -e)) | ((s1 < -e) & (s2 > e))) & (((s3 > e) & (s4 < -e)) | ((s3 < -e) & (s4 > e)))
    hits = np.flatnonzero(cross)
    if hits.size == 0:
        return {}
    _, first = np.unique(face[i[hits]], return_index=True)
    found: dict[int, tuple[int, int, np.ndarray]] = {}
    for k in hits[first]:  # one per face
        w = s1[k] / (s1[k] - s2[k])
        found[int(face[i[k]])] = (int(coedge[i[k]]), int(coedge[j[k]]), A[j[k]] + w * (B[j[k]] - A[j[k]]))
    return found


def _implicit_segments(b: BRep, faces: np.ndarray, t: Tolerance) -> tuple[np.ndarray, ...]:
    """One segment per coedge of implicit planar faces with straight edges, projected on each face's Newell plane."""
    from coons.topology.polyhedral import newell_normals

    c = np.flatnonzero(faces[b.coedge_face])
    f = b.coedge_face[c]
    P0, P1 = b.vertex_point[b.coedge_origin[c]], b.vertex_point[b.coedge_target[c]]
    ids, local = np.unique(f, return_inverse=True)
    N = newell_normals(P0, P1, local, ids.size)
    norm = np.linalg.norm(N, axis=1)
    N = np.divide(N, norm[:, None], out=np.zeros_like(N), where=norm[:, None] > 0)
    k = np.argmin(np.abs(N), axis=1)
    X = np.cross(N, np.eye(3)[k])
    X /= np.maximum(np.linalg.norm(X, axis=1), np.finfo(float).tiny)[:, None]
    Y = np.cross(N, X)
    ref = np.zeros((ids.size, 3))
    ref[local] = P0  # any vertex of the face: coordinates relative to it keep precision
    Xl, Yl, Rl = X[local], Y[local], ref[local]
    A = np.stack([np.einsum("ij,ij->i", P0 - Rl, Xl), np.einsum("ij,ij->i", P0 - Rl, Yl)], axis=1)
    B = np.stack([np.einsum("ij,ij->i", P1 - Rl, Xl), np.einsum("ij,ij->i", P1 - Rl, Yl)], axis=1)
    pos = np.full(2 * b.n_edges, -1, dtype=np.int64)
    pos[c] = np.arange(c.size)
    return A, B, f, pos[b.coedge_next[c]], c, np.full(c.size, t.linear)


def _face_rings(b: BRep, f: int, samples: int, dense_ends: bool = False
                ) -> tuple[list[np.ndarray], list[np.ndarray]] | None:
    """Each loop of a face as a closed polyline (its p-curves sampled; 3-D points on implicit planes).

    ``dense_ends``: curved edges are sampled, besides ``samples`` uniform fractions of their
    range, at fractions falling geometrically towards both ends (:data:`_DENSE_ENDS`).
    Returns ``(rings, owners)``: per loop a ``(m, 2)`` (or ``(m, 3)``) ring and the coedge of each
    point; None when a coedge of a face on a surface has no p-curve (nothing to sample).
    """
    si = int(b.face_surface[f])
    s = _unit_samples(samples)
    if dense_ends:
        g = _DENSE_ENDS[_DENSE_ENDS < s[1]]
        s = np.unique(np.concatenate([s, g, 1.0 - g]))
    rings, owners = [], []
    for loop in b.face_loop_ids(f):
        pts, own = [], []
        for c in b.loop_coedges(int(loop)):
            e, sd = int(c) >> 1, int(c) & 1
            t0, t1 = b.edge_range[e]
            if si >= 0:
                pi = int(b.edge_pcurve[e, sd])
                if pi < 0:
                    return None
                pc = b.pcurves[pi]
                u = _ENDS if isinstance(pc, Line2D) else s
                w = u if sd == 0 else 1.0 - u  # the right side runs backwards
                pts.append(pc.evaluate(t0 + (t1 - t0) * w))
            else:
                ci = int(b.edge_curve[e])
                u = _ENDS if ci < 0 or isinstance(b.curves[ci], Line) else s
                w = u if sd == 0 else 1.0 - u
                # Straight edges without a curve are parametrised over [0, 1] by edge_points.
                pts.append(b.edge_points(e, w if ci < 0 else t0 + (t1 - t0) * w))
            own.append(np.full(u.size, int(c)))
        if pts:
            rings.append(np.concatenate(pts))
            owners.append(np.concatenate(own))
    if not rings:
        return None
    return rings, owners


def _face_segments(b: BRep, f: int, samples: int, t: Tolerance, dense_ends: bool = False
                   ) -> tuple[np.ndarray, ...] | None:
    """Boundary polylines of one face in its parameter plane (or Newell plane), as segments.

    For implicit planar faces and for sampling again finer where crossings were found (the
    first pass of faces on surfaces is :func:`_sampled_rings`; ``dense_ends``: see
    :func:`_face_rings`).  Returns None when a coedge of a face on a surface has no p-curve
    (nothing to sample).
    """
    si = int(b.face_surface[f])
    found = _face_rings(b, f, samples, dense_ends)
    if found is None:
        return None
    rings, owners = found
    if si < 0:  # project the 3-D rings on the Newell plane of the face
        allp = np.concatenate(rings)
        nxtp = np.concatenate([np.roll(r, -1, axis=0) for r in rings])
        N = np.cross(allp - allp[0], nxtp - allp[0]).sum(axis=0)
        N /= max(float(np.linalg.norm(N)), np.finfo(float).tiny)
        X = np.cross(N, np.eye(3)[int(np.argmin(np.abs(N)))])
        X /= np.linalg.norm(X)
        Y = np.cross(N, X)
        rings = [np.stack([(r - allp[0]) @ X, (r - allp[0]) @ Y], axis=1) for r in rings]
        eps = t.linear
    else:
        allp = np.concatenate(rings)
        try:
            D = b.surfaces[si].derivatives(allp[:, 0], allp[:, 1], 1)
            stretch = float(max(np.linalg.norm(D[:, 1, 0], axis=-1).max(), np.linalg.norm(D[:, 0, 1], axis=-1).max()))
        except CoonsError:  # samples outside a NURBS domain: fall back to the linear tolerance itself
            stretch = 1.0
        # A parameter step below t.linear / stretch moves the point by less than t.linear in space.
        eps = t.linear / stretch if stretch > 0 else t.linear
    A, B, nxt, cc = [], [], [], []
    n = 0
    for r, o in zip(rings, owners):
        # Drop consecutive repeats (shared ends, closing points within round-off): closer than eps
        # they are one point for the crossing test anyway.
        keep = np.linalg.norm(r - np.roll(r, 1, axis=0), axis=1) > eps
        if not np.any(keep):
            continue
        r, o = r[keep], o[keep]
        m = r.shape[0]
        A.append(r)
        B.append(np.roll(r, -1, axis=0))
        nxt.append(n + (np.arange(m) + 1) % m)
        cc.append(o)
        n += m
    if n == 0:
        return None
    return (np.concatenate(A), np.concatenate(B), np.full(n, f, dtype=np.int64), np.concatenate(nxt),
            np.concatenate(cc), np.full(n, eps))


def _sweep_pairs(A: np.ndarray, B: np.ndarray, face: np.ndarray, chunk: int = 1 << 22,
                 keys: tuple[np.ndarray, ...] | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Pairs of segments of one face whose boxes overlap (sweep and prune along ``u``).

    Each face's ``u`` is mapped monotonically into ``[face, face + 1)`` so that one sort and one
    ``searchsorted`` serve all faces at once; a monotone map keeps ``lo_j <= hi_i`` as a
    (possibly larger) candidate set, never a smaller one.  Pairs ``(i, j)`` come with ``i``
    before ``j`` in the sweep order, ordered by ``i``'s position, then ``j``'s.  ``keys``:
    :func:`_sweep_keys` of the segments when the caller has them.
    """
    lo = np.minimum(A, B)
    hi = np.maximum(A, B)
    g_lo, g_hi, order = _sweep_keys(lo, hi, face) if keys is None else keys
    count = _sweep_counts(g_lo, g_hi, order)
    I, J = [np.empty(0, dtype=np.int64)], [np.empty(0, dtype=np.int64)]
    start = 0
    while start < order.size:
        # Grow the block while the number of candidate pairs stays within ``chunk``.
        csum = np.cumsum(count[start:])
        stop = start + max(1, int(np.searchsorted(csum, chunk, side="right")))
        cnt = count[start:stop]
        p = np.repeat(np.arange(start, stop), cnt)
        off = np.arange(p.size) - np.repeat(np.cumsum(cnt) - cnt, cnt)
        q = p + 1 + off
        i, j = order[p], order[q]
        v_ok = (np.maximum(lo[i, 1], lo[j, 1]) <= np.minimum(hi[i, 1], hi[j, 1])) & (face[i] == face[j])
        I.append(i[v_ok])
        J.append(j[v_ok])
        start = stop
    return np.concatenate(I), np.concatenate(J)


def _sweep_keys(lo: np.ndarray, hi: np.ndarray, group: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The sweep coordinates of boxes ``lo, hi (n, 2)``: ``u`` of each group mapped monotonically into
    ``[group, group + 1/2)`` (``g_lo, g_hi``), and the boxes in sweep order (``g_lo`` ascending, stable)."""
    ids, local = np.unique(group, return_inverse=True)
    fmin = np.full(ids.size, np.inf)
    fmax = np.full(ids.size, -np.inf)
    np.minimum.at(fmin, local, lo[:, 0])
    np.maximum.at(fmax, local, hi[:, 0])
    span = np.maximum(fmax - fmin, np.finfo(float).tiny) * 2.0  # factor 2: normalised values stay below 1/2
    g_lo = local + (lo[:, 0] - fmin[local]) / span[local]
    g_hi = local + (hi[:, 0] - fmin[local]) / span[local]
    return g_lo, g_hi, np.argsort(g_lo, kind="stable")


def _sweep_counts(g_lo: np.ndarray, g_hi: np.ndarray, order: np.ndarray) -> np.ndarray:
    """Per position of the sweep order, the number of later boxes it is paired with before the ``v`` test."""
    end = np.searchsorted(g_lo[order], g_hi[order], side="right")
    return np.maximum(end - np.arange(order.size) - 1, 0)


#: Candidate pairs per segment of the sweep over whole faces above which :func:`_segment_pairs`
#: sweeps loop by loop instead (the loop-by-loop passes cost a few more array calls).
_LOOP_SWEEP_RATIO = 16


def _segment_pairs(A: np.ndarray, B: np.ndarray, face: np.ndarray, nxt: np.ndarray,
                   chunk: int = 1 << 22, old: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """The pairs of :func:`_sweep_pairs` whose rings (the cycles of ``nxt``: the loops) are one or have
    overlapping boxes, in the same order.

    Two segments of different loops can only cross where the loops' boxes overlap.  A face with
    many holes (a plate after many cuts) has every segment overlap, along ``u``, all the holes of
    its column: sweeping the whole face costs segments times holes per column, while sweeping
    each loop, and the segments of each pair of loops whose boxes overlap, costs about the
    segments.  That is done when the sweep over faces would test more than
    :data:`_LOOP_SWEEP_RATIO` candidates per segment.  Every pair whose boxes overlap is found
    either way, so the crossings found, and the first crossing of each face in pair order, are
    those of :func:`_sweep_pairs`.  ``old (n,)`` bool: pairs of two such segments are left out
    (loops whose segments were tested against each other before; a loop is all old or all new).
    """
    lo, hi = np.minimum(A, B), np.maximum(A, B)
    keys = _sweep_keys(lo, hi, face)
    if nxt.size == 0 or nxt.min() < 0 or _sweep_counts(*keys).sum() <= _LOOP_SWEEP_RATIO * A.shape[0]:
        i, j = _sweep_pairs(A, B, face, chunk, keys)
        if old is not None:
            keep = ~(old[i] & old[j])
            i, j = i[keep], j[keep]
        return i, j
    ring = _cycle_labels(nxt)
    members = np.argsort(ring, kind="stable")  # the segments ring by ring
    starts = np.flatnonzero(np.concatenate([[True], ring[members[1:]] != ring[members[:-1]]]))
    cnt = np.diff(np.append(starts, members.size))
    rinv = np.empty(ring.size, dtype=np.int64)
    rinv[members] = np.repeat(np.arange(starts.size), cnt)
    rlo = np.minimum.reduceat(lo[members], starts, axis=0)
    rhi = np.maximum.reduceat(hi[members], starts, axis=0)
    if old is None:
        parts = [_sweep_pairs(A, B, rinv, chunk)]  # within each loop
    else:
        fresh = np.flatnonzero(~old)  # within each loop not tested before
        fi, fj = _sweep_pairs(A[fresh], B[fresh], rinv[fresh], chunk)
        parts = [(fresh[fi], fresh[fj])]
    RI, RJ = _sweep_pairs(rlo, rhi, face[members[starts]], chunk)  # loops of one face with overlapping boxes
    if old is not None:
        ring_old = old[members[starts]]
        keep = ~(ring_old[RI] & ring_old[RJ])
        RI, RJ = RI[keep], RJ[keep]
    if RI.size:
        sizes = cnt[RI] + cnt[RJ]
        grp = np.repeat(np.arange(RI.size), sizes)
        k = np.arange(grp.size) - np.repeat(np.cumsum(sizes) - sizes, sizes)
        a = cnt[RI][grp]
        seg = members[np.where(k < a, starts[RI][grp] + k, starts[RJ][grp] + k - a)]
        i, j = _sweep_pairs(A[seg], B[seg], grp, chunk)  # the segments of each loop pair together
        i, j = seg[i], seg[j]
        cross = rinv[i] != rinv[j]
        parts.append((i[cross], j[cross]))
    i = np.concatenate([p[0] for p in parts])
    j = np.concatenate([p[1] for p in parts])
    # The pairs as the sweep over faces takes them: its orientation, its test and its order.
    g_lo, g_hi, order = keys
    rank = np.empty(order.size, dtype=np.int64)
    rank[order] = np.arange(order.size)
    swap = rank[i] > rank[j]
    i, j = np.where(swap, j, i), np.where(swap, i, j)
    keep = ((g_lo[j] <= g_hi[i]) & (np.maximum(lo[i, 1], lo[j, 1]) <= np.minimum(hi[i, 1], hi[j, 1]))
            & (face[i] == face[j]))
    i, j = i[keep], j[keep]
    o = np.lexsort((rank[j], rank[i]))
    return i[o], j[o]


def _outer_shells(b: BRep) -> np.ndarray:
    """``(n_solids,)`` int64: each solid's outer shell (the other shells are voids)."""
    return np.asarray(b.solid_shells, dtype=np.int64)[np.asarray(b.solid_shell_ptr[:-1], dtype=np.int64)]


def _check_nesting(b: BRep, t: Tolerance, out: list[Problem]) -> None:
    """Every void lies directly inside its solid's outer shell, and no outer shell inside another
    solid's material (:func:`coons.topology.nesting.shell_parents`: winding numbers proven on cones
    or a certified mesh).  Runs after the orientation check has passed (outer shells positive,
    voids negative)."""
    from coons.topology.nesting import shell_parents

    try:
        parents = shell_parents(b, t)
    except (TopologyError, InvalidInputError) as exc:  # (touching, or no mesh fine enough at this tolerance)
        out.append(Problem("shells-touch", "brep", 0, f"which shell lies inside which is not decided: {exc}"))
        return
    outer_of = _outer_shells(b)
    outer = np.zeros(b.n_shells, dtype=bool)
    outer[outer_of] = True
    solid = np.asarray(b.shell_solid, dtype=np.int64)
    for s in range(b.n_shells):
        p = int(parents[s])
        if outer[s] and p >= 0 and outer[p]:
            out.append(Problem("nested-solids", "shell", s,
                               f"outer shell of solid {solid[s]} lies inside the outer shell {p} of solid {solid[p]} "
                               "(overlapping solids; a shell inside material must be a void)"))
        elif not outer[s] and p != outer_of[solid[s]]:
            where = "inside no shell" if p < 0 else f"directly inside shell {p}"
            out.append(Problem("void-outside", "shell", s,
                               f"void of solid {solid[s]} lies {where}, not directly inside its solid's outer shell "
                               f"{outer_of[solid[s]]}"))


def _check_orientation(b: BRep, t: Tolerance, out: list[Problem], known: tuple | None = None,
                       extends: dict | None = None) -> None:
    """Outer shells enclose positive volume, voids negative (divergence theorem).

    For a B-rep sewn from face specs (``known``: :data:`_SEWN_FROM`'s record; ``extends``: ``{face:
    (n, spec)}`` of :func:`_trims_passed`), the volumes are summed from the faces' contributions,
    those of faces equal to a spec integrated before taken from then
    (:func:`~coons.topology.mass.carried_shell_volumes`: equal up to round-off, for this sign test)."""
    try:
        from coons.topology.mass import carried_shell_volumes, shell_volumes
    except ImportError:  # pragma: no cover - mass properties land with the primitives
        return
    try:
        vols = shell_volumes(b) if known is None else carried_shell_volumes(b, known[0], known[1], extends or {})
    except CoonsError as exc:  # geometry the integrator does not know: report, do not crash
        out.append(Problem("orientation-unchecked", "brep", 0, f"shell volumes could not be computed: {exc}"))
        return
    outer = np.zeros(b.n_shells, dtype=bool)
    outer[_outer_shells(b)] = True
    for s in range(b.n_shells):
        if outer[s] and not vols[s] > 0:
            out.append(Problem("inward-shell", "shell", s, f"outer shell encloses volume {vols[s]:.6g} (must be > 0)"))
        if not outer[s] and not vols[s] < 0:
            out.append(Problem("outward-void", "shell", s, f"void shell encloses volume {vols[s]:.6g} (must be < 0)"))
