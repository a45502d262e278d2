"""The validity checker of B-reps: every invariant the structure promises, as a report.

:func:`check` returns a :class:`CheckReport` listing every problem found (never just the
first): pointer consistency of the winged-edge tables, closed loops, manifold edges with two
different faces and opposite senses, manifold vertices, Euler–Poincaré per shell, vertices
on their edges, p-curves agreeing with 3-D curves, loops closed in parameter space, planar
polyhedral faces, self-intersecting trim loops, and outward orientation of shells (outer
shells enclose positive volume, voids negative).  It does not repair anything.

Geometric checks sample each edge at a fixed number of parameters (``samples``); a sampled
check can miss a deviation between samples, so tolerances are verified, not proven.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from coons.errors import CoonsError
from coons.tolerance import Tolerance, resolve
from coons.topology.brep import BRep

__all__ = ["CheckReport", "Problem", "check"]


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
        _check_geometry(b, t, samples, problems)
        if not problems:
            _check_orientation(b, t, problems)
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
        bad = np.flatnonzero((arr < 0) | (arr >= hi))
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
        cyc_len = _cycle_lengths(nxt)
        per_loop = np.bincount(loop, minlength=b.n_loops)
        bad = np.flatnonzero(has & (cyc_len[np.where(has, first, 0)] != per_loop))
        for l in bad[:10]:
            out.append(Problem("loop-split", "loop", int(l), "its coedges form more than one cycle"))
        empty = np.flatnonzero(~has & (b.loop_vertex < 0))
        for l in empty[:10]:
            out.append(Problem("empty-loop", "loop", int(l), "no coedge and no vertex"))


def _cycle_lengths(perm: np.ndarray) -> np.ndarray:
    """Length of the cycle of the permutation through each element (vectorised labelling)."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    n = perm.shape[0]
    g = coo_matrix((np.ones(n), (np.arange(n), perm)), shape=(n, n))
    _, labels = connected_components(g, directed=True, connection="weak")
    return np.bincount(labels)[labels]


def _check_manifold(b: BRep, out: list[Problem]) -> None:
    ef = b.edge_face
    same = np.flatnonzero(ef[:, 0] == ef[:, 1])
    for e in same[:10]:
        out.append(Problem("seam-edge", "edge", int(e), f"both sides lie in face {int(ef[e, 0])}"))
    # Manifold vertices: the rotation around each vertex visits every coedge leaving it.
    nc = 2 * b.n_edges
    if nc:
        rot = b.coedge_next[np.arange(nc) ^ 1]  # next outgoing coedge around the origin vertex
        fan = _cycle_lengths(rot)
        degree = np.bincount(b.coedge_origin, minlength=b.n_vertices)
        v = b.coedge_origin
        bad = np.unique(v[fan != degree[v]])
        for vi in bad[:10]:
            out.append(Problem("non-manifold-vertex", "vertex", int(vi),
                               f"{int(degree[vi])} edges leave it but they form several fans"))
    isolated = np.flatnonzero((b.vertex_coedge < 0) & ~np.isin(np.arange(b.n_vertices), b.loop_vertex))
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
    E = np.bincount(shell_of_face[b.edge_face[:, 0]], minlength=ns) if b.n_edges else np.zeros(ns, int)
    edge_shell = shell_of_face[b.edge_face[:, 0]]
    vs_pairs = np.concatenate([
        np.stack([b.edge_vertex[:, 0], edge_shell], 1),
        np.stack([b.edge_vertex[:, 1], edge_shell], 1),
        np.stack([b.loop_vertex[b.loop_vertex >= 0], shell_of_face[b.loop_face[b.loop_vertex >= 0]]], 1),
    ])
    V = np.bincount(np.unique(vs_pairs, axis=0)[:, 1], minlength=ns)
    chi = V - E + F - (L - F)
    for s in range(ns):
        if chi[s] % 2 or chi[s] > 2:
            out.append(Problem("euler-poincare", "shell", s,
                               f"V - E + F - (L - F) = {int(chi[s])} (V={V[s]}, E={E[s]}, F={F[s]}, L={L[s]}) is not 2(1 - G)"))


# ---------------------------------------------------------------------- geometry
def _edge_samples(b: BRep, samples: int) -> tuple[np.ndarray, np.ndarray]:
    """Parameters ``(E, k)`` and 3-D points ``(E, k, 3)`` along every edge."""
    s = np.linspace(0.0, 1.0, samples)
    r = b.edge_range
    T = r[:, :1] + (r[:, 1:] - r[:, :1]) * s
    P = np.empty(T.shape + (3,))
    straight = b.edge_curve < 0
    if np.any(straight):
        a = b.vertex_point[b.edge_vertex[straight, 0]]
        c = b.vertex_point[b.edge_vertex[straight, 1]]
        P[straight] = a[:, None, :] + s[None, :, None] * (c - a)[:, None, :]
    for ci in np.unique(b.edge_curve[~straight]):
        rows = np.flatnonzero(b.edge_curve == ci)
        P[rows] = b.curves[int(ci)].evaluate(T[rows])
    return T, P


def _check_geometry(b: BRep, t: Tolerance, samples: int, out: list[Problem]) -> None:
    T, P = _edge_samples(b, samples)
    ends = b.vertex_point[b.edge_vertex]  # (E, 2, 3)
    allow = b.edge_tol[:, None] + b.vertex_tol[b.edge_vertex] + t.linear
    gap = np.linalg.norm(P[:, [0, -1], :] - ends, axis=-1)
    bad = np.argwhere(gap > allow)
    for e, k in bad[:10]:
        out.append(Problem("vertex-off-edge", "edge", int(e),
                           f"its {'start' if k == 0 else 'end'} is {gap[e, k]:.3g} from vertex {int(b.edge_vertex[e, k])} "
                           f"(allowed {allow[e, k]:.3g})"))
    # p-curves: surface(pcurve(t)) == curve(t) within the edge tolerance.
    uv_end = {}
    for e in range(b.n_edges):
        for side in (0, 1):
            pi = int(b.edge_pcurve[e, side])
            f = int(b.edge_face[e, side])
            si = int(b.face_surface[f])
            if pi < 0 or si < 0:
                continue
            uv = b.pcurves[pi].evaluate(T[e])
            Q = b.surfaces[si].evaluate(uv[:, 0], uv[:, 1])
            dev = float(np.max(np.linalg.norm(Q - P[e], axis=-1)))
            if dev > b.edge_tol[e] + t.linear:
                out.append(Problem("pcurve-deviation", "edge", e,
                                   f"p-curve in face {f} is {dev:.3g} from the 3-D curve (edge tolerance {b.edge_tol[e]:.3g})"))
            c = 2 * e + side
            # Coedge start/end in parameter space (the right side runs backwards).
            uv_end[c] = (uv[0], uv[-1]) if side == 0 else (uv[-1], uv[0])
    # Loops closed in parameter space, allowing a jump along a collapsed side (a pole).
    nxt = b.coedge_next
    for c, (_, end) in uv_end.items():
        n = int(nxt[c])
        if n not in uv_end:
            continue
        start = uv_end[n][0]
        if np.linalg.norm(end - start) <= t.linear * 10 + 1e-12 * (1 + np.abs(end).max()):
            continue
        f = int(b.coedge_face[c])
        S = b.surfaces[int(b.face_surface[f])]
        seg = end[None, :] + np.linspace(0, 1, samples)[:, None] * (start - end)[None, :]
        img = S.evaluate(seg[:, 0], seg[:, 1])
        v = b.vertex_point[int(b.coedge_target[c])]
        if np.max(np.linalg.norm(img - v, axis=-1)) > b.vertex_tol[int(b.coedge_target[c])] + t.linear:
            out.append(Problem("pcurve-loop-open", "coedge", c,
                               f"in face {f} the p-curve ends at {end.round(9).tolist()} but the next starts at "
                               f"{start.round(9).tolist()}"))
    # Polyhedral faces: vertices on one plane.
    implicit = np.flatnonzero(b.face_surface < 0)
    if implicit.size:
        from coons.topology.polyhedral import face_plane_deviation

        dev = face_plane_deviation(b, implicit)
        for f, d in zip(implicit[dev > t.linear][:10], dev[dev > t.linear][:10]):
            out.append(Problem("non-planar-face", "face", int(f), f"vertices are up to {d:.3g} off the face's plane"))


def _check_orientation(b: BRep, t: Tolerance, out: list[Problem]) -> None:
    """Outer shells enclose positive volume, voids negative (divergence theorem)."""
    try:
        from coons.topology.mass import shell_volumes
    except ImportError:  # pragma: no cover - mass properties land with the primitives
        return
    try:
        vols = shell_volumes(b)
    except CoonsError as exc:  # geometry the integrator does not know: report, do not crash
        out.append(Problem("orientation-unchecked", "brep", 0, f"shell volumes could not be computed: {exc}"))
        return
    outer = np.zeros(b.n_shells, dtype=bool)
    outer[b.solid_shells[b.solid_shell_ptr[:-1]]] = True
    for s in range(b.n_shells):
        if outer[s] and not vols[s] > 0:
            out.append(Problem("inward-shell", "shell", s, f"outer shell encloses volume {vols[s]:.6g} (must be > 0)"))
        if not outer[s] and not vols[s] < 0:
            out.append(Problem("outward-void", "shell", s, f"void shell encloses volume {vols[s]:.6g} (must be < 0)"))
