"""Building winged-edge B-reps: the Euler operators and a checked assembly from face loops.

:class:`BRepBuilder` is the only place where topology changes.  It holds growable
columns of the same tables as :class:`~coons.topology.brep.BRep` and offers the Euler
operators of Baumgart and Mäntylä (Cohen–Riesenfeld–Elber ch. 19; Mäntylä, *An
Introduction to Solid Modeling*, ch. 9), each of which keeps the Euler–Poincaré relation
``V − E + F − (L − F) = 2 (S − G)``:

======================  ==========================================  =====================
operator                effect                                      inverse
======================  ==========================================  =====================
``mvfs(p)``             vertex, face (lone-vertex loop), shell      ``kvfs``
``mev(l, c, p)``        edge from a loop vertex to a new vertex     ``kev``
``mef(l, a, b)``        edge splitting a loop into two faces         ``kef``
``kemr(e)``             kill an edge whose sides share a loop,       ``mekr``
                        making a ring (an inner loop)
``kfmrh(f, g)``         face ``f`` becomes an inner loop of ``g``    ``mfkrh``
                        (a hole through the solid, or joins shells)
``semv(e, p)``          split an edge at a new vertex               ``jekv``
======================  ==========================================  =====================

Coedge ids follow :mod:`coons.topology.brep`: ``c = 2 e + side``; ``mev``/``mef``/``mekr``
take the coedge *after which* the new edge is inserted (it ends at the vertex where the
new edge starts).  Geometry is attached with :meth:`set_vertex`, :meth:`set_edge_curve`,
:meth:`set_pcurve` and :meth:`set_face_surface` (for many entities at once, in the same pool
order: :meth:`set_vertex_tols`, :meth:`set_edge_curves`, :meth:`set_pcurves`).  :meth:`assemble` builds a whole shell
from face loops at once — the structure a sequence of Euler operators would produce, with
Euler–Poincaré verified rather than assumed; it serves meshes, importers and the
Boolean's sewing.  :meth:`build` compacts killed entities, checks every invariant and
returns an immutable ``BRep`` or raises :class:`~coons.errors.TopologyError`.
:func:`assembled_brep` is the sequence ``assemble``, ``set_*``, ``build`` on a fresh builder
for one shell given as arrays, with the same tables and pools (the sewing of a large result in
array passes); it declines (None) whatever that sequence would not take in bulk.
"""

from __future__ import annotations

from itertools import chain
from typing import Any, Sequence

import numpy as np

from coons.errors import InvalidInputError, TopologyError
from coons.tolerance import Tolerance, resolve
from coons.topology._components import components
from coons.topology._memo import seed_pool_ids
from coons.topology.brep import BRep

__all__ = ["BRepBuilder", "assembled_brep"]


class BRepBuilder:
    """Mutable winged-edge tables with Euler operators (see the module docstring)."""

    def __init__(self, tol: Tolerance | None = None) -> None:
        self.tol = resolve(tol)
        # vertices
        self.vpoint: list[np.ndarray] = []
        self.vtol: list[float] = []
        self.vcoedge: list[int] = []
        self.valive: list[bool] = []
        # edges (coedge columns: 2 per edge)
        self.ev: list[list[int]] = []
        self.ealive: list[bool] = []
        self.ecurve: list[int] = []
        self.erange: list[tuple[float, float]] = []
        self.epcurve: list[list[int]] = []
        self.etol: list[float] = []
        self.nxt: list[int] = []
        self.prv: list[int] = []
        self.cloop: list[int] = []
        # loops
        self.lface: list[int] = []
        self.lcoedge: list[int] = []
        self.lvertex: list[int] = []
        self.lalive: list[bool] = []
        # faces
        self.fsurface: list[int] = []
        self.fsense: list[bool] = []
        self.fshell: list[int] = []
        self.fouter: list[int] = []
        self.falive: list[bool] = []
        # shells and solids
        self.ssolid: list[int] = []
        self.salive: list[bool] = []
        self.souter: list[int] = []  # per solid: outer shell
        self.solive: list[bool] = []
        # geometry pools (deduplicated by identity)
        self.surfaces: list[Any] = []
        self.curves: list[Any] = []
        self.pcurves: list[Any] = []
        self._pool_index: dict[str, dict[int, int]] = {"surfaces": {}, "curves": {}, "pcurves": {}}

    # ================================================================ small helpers
    def _new_vertex(self, point) -> int:
        p = np.asarray(point, dtype=np.float64)
        if p.shape != (3,) or not np.all(np.isfinite(p)):
            raise InvalidInputError(f"vertex point must be 3 finite numbers, got {point!r}")
        self.vpoint.append(p)
        self.vtol.append(self.tol.linear)
        self.vcoedge.append(-1)
        self.valive.append(True)
        return len(self.vpoint) - 1

    def _new_edge(self, v0: int, v1: int) -> int:
        self.ev.append([v0, v1])
        self.ealive.append(True)
        self.ecurve.append(-1)
        self.erange.append((0.0, 1.0))
        self.epcurve.append([-1, -1])
        self.etol.append(self.tol.linear)
        self.nxt += [-1, -1]
        self.prv += [-1, -1]
        self.cloop += [-1, -1]
        return len(self.ev) - 1

    def _new_loop(self, face: int) -> int:
        self.lface.append(face)
        self.lcoedge.append(-1)
        self.lvertex.append(-1)
        self.lalive.append(True)
        return len(self.lface) - 1

    def _new_face(self, shell: int) -> int:
        return self._new_faces(1, shell)[0]

    def _new_faces(self, n: int, shell: int = -1, surfaces: list[int] | None = None,
                   senses: list[bool] | None = None) -> list[int]:
        """``n`` new face rows (pooled surface indices and senses, or none and forward), their indices."""
        f0 = len(self.fsurface)
        self.fsurface.extend([-1] * n if surfaces is None else surfaces)
        self.fsense.extend([True] * n if senses is None else senses)
        self.fshell.extend([shell] * n)
        self.fouter.extend([-1] * n)
        self.falive.extend([True] * n)
        return list(range(f0, f0 + n))

    def _link(self, a: int, b: int) -> None:
        self.nxt[a] = b
        self.prv[b] = a

    def origin(self, c: int) -> int:
        """Vertex a coedge starts from."""
        return self.ev[c >> 1][c & 1]

    def target(self, c: int) -> int:
        """Vertex a coedge ends at."""
        return self.ev[c >> 1][1 - (c & 1)]

    def _cycle(self, start: int) -> list[int]:
        out = [start]
        c = self.nxt[start]
        while c != start:
            out.append(c)
            c = self.nxt[c]
            if len(out) > len(self.nxt):
                raise TopologyError(f"coedge cycle from {start} does not close")
        return out

    def _set_loop(self, coedges: Sequence[int], loop: int) -> None:
        for c in coedges:
            self.cloop[c] = loop
        self.lcoedge[loop] = coedges[0]
        self.lvertex[loop] = -1

    def _check_coedge_in_loop(self, c: int, loop: int, what: str) -> None:
        if not (0 <= c < len(self.nxt)) or not self.ealive[c >> 1] or self.cloop[c] != loop:
            raise TopologyError(f"{what}: coedge {c} is not in loop {loop}")

    def loop_coedges(self, loop: int) -> list[int]:
        """Coedges of a loop in order (empty for a lone-vertex loop)."""
        first = self.lcoedge[loop]
        return [] if first < 0 else self._cycle(first)

    def coedge_ending_at(self, loop: int, vertex: int) -> int:
        """The coedge of ``loop`` that ends at ``vertex``.

        Raises
        ------
        TopologyError
            The vertex is not on the loop, or is met more than once (pass the coedge explicitly).
        """
        hits = [c for c in self.loop_coedges(loop) if self.target(c) == vertex]
        if len(hits) != 1:
            raise TopologyError(f"vertex {vertex} is met {len(hits)} times by loop {loop}; expected exactly once")
        return hits[0]

    # ================================================================ Euler operators
    def mvfs(self, point) -> tuple[int, int, int, int]:
        """Make vertex, face, shell (and a new solid holding the shell).

        Returns
        -------
        (vertex, face, loop, shell)
        """
        solid = len(self.souter)
        self.souter.append(-1)
        self.solive.append(True)
        shell = len(self.ssolid)
        self.ssolid.append(solid)
        self.salive.append(True)
        self.souter[solid] = shell
        v = self._new_vertex(point)
        f = self._new_face(shell)
        l = self._new_loop(f)
        self.fouter[f] = l
        self.lvertex[l] = v
        return v, f, l, shell

    def kvfs(self, vertex: int) -> None:
        """Kill a lone vertex with its face and shell (inverse of :meth:`mvfs`)."""
        if self.vcoedge[vertex] >= 0:
            raise TopologyError(f"kvfs: vertex {vertex} still has edges")
        loops = [l for l, v in enumerate(self.lvertex) if v == vertex and self.lalive[l]]
        if len(loops) != 1:
            raise TopologyError(f"kvfs: vertex {vertex} is not the lone vertex of exactly one loop")
        l = loops[0]
        f = self.lface[l]
        if any(self.lalive[k] and self.lface[k] == f and k != l for k in range(len(self.lface))):
            raise TopologyError(f"kvfs: face {f} has other loops")
        s = self.fshell[f]
        if sum(1 for g, a in enumerate(self.falive) if a and self.fshell[g] == s) != 1:
            raise TopologyError(f"kvfs: shell {s} has other faces")
        self.valive[vertex] = self.lalive[l] = self.falive[f] = self.salive[s] = False
        solid = self.ssolid[s]
        if self.souter[solid] == s:
            self.solive[solid] = False

    def mev(self, loop: int, after: int | None, point) -> tuple[int, int]:
        """Make an edge from a vertex of ``loop`` to a new vertex at ``point``.

        Parameters
        ----------
        loop : int
        after : int or None
            The coedge of ``loop`` ending at the start vertex, after which the new edge
            (a strut: out and back) is inserted; None for a lone-vertex loop.

        Returns
        -------
        (edge, new_vertex); the edge runs from the loop's vertex to the new vertex.
        """
        if after is None:
            v = self.lvertex[loop]
            if v < 0:
                raise TopologyError(f"mev: loop {loop} has edges; say after which coedge to insert")
        else:
            self._check_coedge_in_loop(after, loop, "mev")
            v = self.target(after)
        w = self._new_vertex(point)
        e = self._new_edge(v, w)
        c0, c1 = 2 * e, 2 * e + 1
        self.cloop[c0] = self.cloop[c1] = loop
        if after is None:
            self._link(c0, c1)
            self._link(c1, c0)
            self.lcoedge[loop] = c0
            self.lvertex[loop] = -1
        else:
            b = self.nxt[after]
            self._link(after, c0)
            self._link(c0, c1)
            self._link(c1, b)
        if self.vcoedge[v] < 0:
            self.vcoedge[v] = c0
        self.vcoedge[w] = c1
        return e, w

    def kev(self, edge: int) -> None:
        """Kill an edge and its dangling end vertex (inverse of :meth:`mev`)."""
        c0, c1 = 2 * edge, 2 * edge + 1
        if self.nxt[c0] == c1:
            keep_c, dangling = c0, self.target(c0)
        elif self.nxt[c1] == c0:
            keep_c, dangling = c1, self.target(c1)
        else:
            raise TopologyError(f"kev: edge {edge} has no dangling vertex")
        other = keep_c ^ 1
        loop = self.cloop[c0]
        keep_v = self.origin(keep_c)
        if self.nxt[other] == keep_c:  # the last edge of the loop: back to a lone vertex
            self.lcoedge[loop] = -1
            self.lvertex[loop] = keep_v
            self.vcoedge[keep_v] = -1
        else:
            a, b = self.prv[keep_c], self.nxt[other]
            self._link(a, b)
            if self.lcoedge[loop] in (c0, c1):
                self.lcoedge[loop] = b
            if self.vcoedge[keep_v] in (c0, c1):
                self.vcoedge[keep_v] = b
        self.ealive[edge] = False
        self.valive[dangling] = False

    def mef(self, loop: int, a: int, b: int) -> tuple[int, int, int]:
        """Make an edge and a face by joining two vertices of one loop.

        The new edge runs from the end of coedge ``a`` to the end of coedge ``b``. The
        part of the loop after ``b`` (with the edge's right side) becomes the new face.

        Returns
        -------
        (edge, new_face, new_loop)
        """
        self._check_coedge_in_loop(a, loop, "mef")
        self._check_coedge_in_loop(b, loop, "mef")
        v1, v2 = self.target(a), self.target(b)
        e = self._new_edge(v1, v2)
        c0, c1 = 2 * e, 2 * e + 1
        f_old = self.lface[loop]
        f_new = self._new_face(self.fshell[f_old])
        l_new = self._new_loop(f_new)
        self.fouter[f_new] = l_new
        self.fsurface[f_new] = self.fsurface[f_old]
        self.fsense[f_new] = self.fsense[f_old]
        if a == b:  # a closed edge at one vertex: the new face is bounded by that edge alone
            an = self.nxt[a]
            self._link(a, c0)
            self._link(c0, an)
            self._link(c1, c1)
        else:
            an, bn = self.nxt[a], self.nxt[b]
            self._link(a, c0)
            self._link(c0, bn)
            self._link(b, c1)
            self._link(c1, an)
        self.cloop[c0] = loop
        self.lcoedge[loop] = c0
        self._set_loop(self._cycle(c1), l_new)
        for c in self._cycle(c0):
            self.cloop[c] = loop
        return e, f_new, l_new

    def kef(self, edge: int) -> None:
        """Kill an edge between two faces, merging the right side's face into the left's (inverse of :meth:`mef`)."""
        c0, c1 = 2 * edge, 2 * edge + 1
        l0, l1 = self.cloop[c0], self.cloop[c1]
        f0, f1 = self.lface[l0], self.lface[l1]
        if f0 == f1:
            raise TopologyError(f"kef: edge {edge} has the same face {f0} on both sides; use kemr")
        if self.fouter[f1] != l1 or any(
            self.lalive[k] and self.lface[k] == f1 and k != l1 for k in range(len(self.lface))
        ):
            raise TopologyError(f"kef: face {f1} has inner loops; move them first")
        self._unlink_edge_join(edge, l0)
        self.lalive[l1] = False
        self.falive[f1] = False

    def _unlink_edge_join(self, edge: int, loop: int) -> None:
        """Remove an edge whose two sides lie in different cycles, joining them into ``loop``."""
        c0, c1 = 2 * edge, 2 * edge + 1
        p0, n0, p1, n1 = self.prv[c0], self.nxt[c0], self.prv[c1], self.nxt[c1]
        v0, v1 = self.origin(c0), self.origin(c1)
        if n0 == c0 or n1 == c1:
            raise TopologyError(f"edge {edge} is a closed edge alone in a loop; cannot remove it this way")
        self._link(p0, n1)
        self._link(p1, n0)
        for v, repl in ((v0, n1), (v1, n0)):
            if self.vcoedge[v] in (c0, c1):
                self.vcoedge[v] = repl
        self._set_loop(self._cycle(n0), loop)
        self.ealive[edge] = False

    def kemr(self, edge: int) -> int:
        """Kill an edge whose sides lie in one loop, making a ring (inverse of :meth:`mekr`).

        The cycle through the edge's right side's successor becomes the new loop; when a
        cycle is left without coedges, the new loop is the lone vertex there.

        Returns
        -------
        new loop
        """
        c0, c1 = 2 * edge, 2 * edge + 1
        loop = self.cloop[c0]
        if self.cloop[c1] != loop:
            raise TopologyError(f"kemr: the sides of edge {edge} lie in different loops; use kef")
        face = self.lface[loop]
        p0, n0, p1, n1 = self.prv[c0], self.nxt[c0], self.prv[c1], self.nxt[c1]
        v0, v1 = self.origin(c0), self.origin(c1)
        new = self._new_loop(face)
        # After removal: p0 -> n1 (cycle A, around v0) and p1 -> n0 (cycle B, around v1).
        a_empty = n1 == c0  # c0 is directly preceded by c1 at v0: v0 becomes isolated
        b_empty = n0 == c1
        if a_empty and b_empty:
            raise TopologyError(f"kemr: edge {edge} is the only edge of its loop; use kev")
        if not a_empty:
            self._link(p0, n1)
        if not b_empty:
            self._link(p1, n0)
        if a_empty:
            self.lcoedge[loop], self.lvertex[loop] = -1, -1
            self._set_loop(self._cycle(n0), loop)
            self.lcoedge[new], self.lvertex[new] = -1, v0
            self.vcoedge[v0] = -1
        elif b_empty:
            self._set_loop(self._cycle(n1), loop)
            self.lcoedge[new], self.lvertex[new] = -1, v1
            self.vcoedge[v1] = -1
        else:
            self._set_loop(self._cycle(n1), loop)
            self._set_loop(self._cycle(n0), new)
        for v, repl in ((v0, n1), (v1, n0)):
            if self.vcoedge[v] in (c0, c1):
                self.vcoedge[v] = repl
        self.ealive[edge] = False
        return new

    def mekr(self, loop_a: int, a: int | None, loop_b: int, b: int | None) -> int:
        """Make an edge joining two loops of one face, killing ``loop_b`` (inverse of :meth:`kemr`).

        ``a`` / ``b`` are the coedges after which the edge leaves / arrives (None for a
        lone-vertex loop).  The edge runs from ``loop_a`` to ``loop_b``.
        """
        if self.lface[loop_a] != self.lface[loop_b] or loop_a == loop_b:
            raise TopologyError(f"mekr: loops {loop_a} and {loop_b} must be two loops of one face")
        va = self.lvertex[loop_a] if a is None else self.target(a)
        vb = self.lvertex[loop_b] if b is None else self.target(b)
        if a is not None:
            self._check_coedge_in_loop(a, loop_a, "mekr")
        if b is not None:
            self._check_coedge_in_loop(b, loop_b, "mekr")
        if va < 0 or vb < 0:
            raise TopologyError("mekr: a loop with edges needs the coedge after which to insert")
        e = self._new_edge(va, vb)
        c0, c1 = 2 * e, 2 * e + 1
        # a -> c0 -> (b's old successor) ... b -> c1 -> (a's old successor); a lone-vertex
        # loop contributes no coedge, so the edge turns straight back there.
        an = self.nxt[a] if a is not None else c0
        bn = self.nxt[b] if b is not None else c1
        if a is not None:
            self._link(a, c0)
        if b is not None:
            self._link(b, c1)
        self._link(c0, bn)
        self._link(c1, an)
        for v, c in ((va, c0), (vb, c1)):
            if self.vcoedge[v] < 0:
                self.vcoedge[v] = c
        self._set_loop(self._cycle(c0), loop_a)
        if self.fouter[self.lface[loop_b]] == loop_b:
            self.fouter[self.lface[loop_b]] = loop_a
        self.lalive[loop_b] = False
        return e

    def kfmrh(self, face_kill: int, face_keep: int) -> None:
        """Turn ``face_kill`` (one loop) into an inner loop of ``face_keep`` and remove it.

        In one shell this makes a through hole (genus + 1); across two shells it merges them.
        """
        loops = [l for l in range(len(self.lface)) if self.lalive[l] and self.lface[l] == face_kill]
        if len(loops) != 1:
            raise TopologyError(f"kfmrh: face {face_kill} must have exactly one loop, has {len(loops)}")
        l = loops[0]
        self.lface[l] = face_keep
        self.falive[face_kill] = False
        s_kill, s_keep = self.fshell[face_kill], self.fshell[face_keep]
        if s_kill != s_keep:
            for g, alive in enumerate(self.falive):
                if alive and self.fshell[g] == s_kill:
                    self.fshell[g] = s_keep
            self.salive[s_kill] = False
            solid = self.ssolid[s_kill]
            if self.souter[solid] == s_kill:
                self.solive[solid] = False

    def mfkrh(self, loop: int) -> int:
        """Make a face from an inner loop (inverse of :meth:`kfmrh` within one shell).

        Returns
        -------
        the new face
        """
        f = self.lface[loop]
        if self.fouter[f] == loop:
            raise TopologyError(f"mfkrh: loop {loop} is the outer loop of face {f}")
        g = self._new_face(self.fshell[f])
        self.lface[loop] = g
        self.fouter[g] = loop
        self.fsurface[g] = self.fsurface[f]
        self.fsense[g] = self.fsense[f]
        return g

    def semv(self, edge: int, point, t: float | None = None) -> tuple[int, int]:
        """Split an edge at a new vertex (Euler: one vertex and one edge more).

        The old edge keeps its start and ends at the new vertex; the new edge runs from
        the new vertex to the old end.  Both keep the curve and p-curves; the parameter
        range splits at ``t`` (default: the middle of the range).

        Returns
        -------
        (new_vertex, new_edge)
        """
        c0, c1 = 2 * edge, 2 * edge + 1
        s, e_end = self.ev[edge]
        v = self._new_vertex(point)
        e2 = self._new_edge(v, e_end)
        d0, d1 = 2 * e2, 2 * e2 + 1
        self.ev[edge][1] = v
        n0 = self.nxt[c0]
        self._link(c0, d0)
        self._link(d0, n0)
        p1 = self.prv[c1]
        self._link(p1, d1)
        self._link(d1, c1)
        self.cloop[d0], self.cloop[d1] = self.cloop[c0], self.cloop[c1]
        if self.vcoedge[e_end] == c1:
            self.vcoedge[e_end] = d1
        self.vcoedge[v] = d0
        a, b = self.erange[edge]
        tm = 0.5 * (a + b) if t is None else float(t)
        if not a < tm < b:
            raise InvalidInputError(f"semv: split parameter {tm!r} is not inside the edge range ({a!r}, {b!r})")
        self.erange[edge] = (a, tm)
        self.erange[e2] = (tm, b)
        self.ecurve[e2] = self.ecurve[edge]
        self.epcurve[e2] = list(self.epcurve[edge])
        self.etol[e2] = self.etol[edge]
        return v, e2

    def sweep_loop(self, loop: int, offset) -> dict[str, list[int]]:
        """Translational sweep of one loop (Mäntylä's sweep by ``mev`` + ``mef``).

        Every vertex ``v`` of ``loop`` gets a strut edge to ``v + offset``; consecutive new
        vertices are joined, each join making a side face.  Afterwards ``loop`` is the
        swept copy (the lid) and the side faces follow the loop's edges.

        Returns
        -------
        dict with, per original coedge in loop order: ``"coedges"`` (the original coedge),
        ``"struts"`` (edge from its origin up), ``"lids"`` (edge of the lid above it, running
        like the original coedge) and ``"faces"`` (the side face on it).
        """
        off = np.asarray(offset, dtype=np.float64)
        cs = self.loop_coedges(loop)
        if not cs:
            raise TopologyError(f"sweep_loop: loop {loop} has no edges")
        struts = []
        for c in cs:
            e, _ = self.mev(loop, self.prv[c], self.vpoint[self.origin(c)] + off)
            struts.append(e)
        lids, faces = [], []
        n = len(cs)
        a = 2 * struts[0]
        for i in range(n):
            # New edge from the top of strut i (the end of ``a``, in the lid loop) to the top
            # of strut i + 1; the cycle through the original coedge i becomes the side face.
            e, f, _ = self.mef(loop, a, 2 * struts[(i + 1) % n])
            lids.append(e)
            faces.append(f)
            a = 2 * e
        return {"coedges": cs, "struts": struts, "lids": lids, "faces": faces}

    # ================================================================ geometry
    def _pool(self, kind: str, obj: Any) -> int:
        if obj is None:
            return -1
        index = self._pool_index[kind]
        key = id(obj)
        if key not in index:
            pool = getattr(self, kind)
            pool.append(obj)
            index[key] = len(pool) - 1
        return index[key]

    def set_vertex(self, vertex: int, point=None, tol: float | None = None) -> None:
        if point is not None:
            self.vpoint[vertex] = np.asarray(point, dtype=np.float64)
        if tol is not None:
            self.vtol[vertex] = float(tol)

    def set_edge_curve(self, edge: int, curve: Any, t_range: tuple[float, float], tol: float | None = None) -> None:
        """Attach a 3-D curve over ``t_range`` (curve(t0) at the start vertex, t0 < t1)."""
        t0, t1 = float(t_range[0]), float(t_range[1])
        if not t0 < t1:
            raise InvalidInputError(f"edge {edge}: curve range must increase, got ({t0!r}, {t1!r})")
        self.ecurve[edge] = self._pool("curves", curve)
        self.erange[edge] = (t0, t1)
        if tol is not None:
            self.etol[edge] = float(tol)

    def set_pcurve(self, coedge: int, pcurve: Any) -> None:
        """Attach the p-curve of one side of an edge (same parameter as the 3-D curve)."""
        self.epcurve[coedge >> 1][coedge & 1] = self._pool("pcurves", pcurve)

    def _pool_many(self, kind: str, objs: Sequence[Any]) -> list[int]:
        """:meth:`_pool` of each object in turn (the same pool order)."""
        index, pool, out = self._pool_index[kind], getattr(self, kind), []
        for obj in objs:
            if obj is None:
                out.append(-1)
                continue
            i = index.get(id(obj))
            if i is None:
                pool.append(obj)
                i = index[id(obj)] = len(pool) - 1
            out.append(i)
        return out

    def set_vertex_tols(self, vertices: np.ndarray, tols: np.ndarray) -> None:
        """:meth:`set_vertex` with ``tol`` for many vertices at once."""
        vtol = self.vtol
        for v, x in zip(np.asarray(vertices, dtype=np.int64).tolist(), np.asarray(tols, dtype=np.float64).tolist()):
            vtol[v] = x

    def set_edge_curves(self, edges: np.ndarray, curves: Sequence[Any], t_ranges: np.ndarray,
                        tols: np.ndarray | None = None) -> None:
        """:meth:`set_edge_curve` for many edges at once, in order (curves pooled in that order).

        Raises
        ------
        InvalidInputError
            A range that does not increase (the first such edge is named; nothing is set).
        """
        edges = np.asarray(edges, dtype=np.int64).ravel()
        r = np.asarray(t_ranges, dtype=np.float64).reshape(-1, 2)
        bad = np.flatnonzero(~(r[:, 0] < r[:, 1]))
        if bad.size:
            k = int(bad[0])
            raise InvalidInputError(f"edge {int(edges[k])}: curve range must increase, got ({r[k, 0]!r}, {r[k, 1]!r})")
        idx = self._pool_many("curves", curves)
        ecurve, erange, etol = self.ecurve, self.erange, self.etol
        el, rl = edges.tolist(), r.tolist()
        for e, i, (t0, t1) in zip(el, idx, rl):
            ecurve[e] = i
            erange[e] = (t0, t1)
        if tols is not None:
            for e, x in zip(el, np.asarray(tols, dtype=np.float64).tolist()):
                etol[e] = x

    def set_pcurves(self, coedges: np.ndarray, pcurves: Sequence[Any]) -> None:
        """:meth:`set_pcurve` for many coedges at once, in order (p-curves pooled in that order)."""
        ep = self.epcurve
        for c, i in zip(np.asarray(coedges, dtype=np.int64).tolist(), self._pool_many("pcurves", pcurves)):
            ep[c >> 1][c & 1] = i

    def set_face_surface(self, face: int, surface: Any, sense: bool = True) -> None:
        self.fsurface[face] = self._pool("surfaces", surface)
        self.fsense[face] = bool(sense)

    # ================================================================ assembly from loops
    def assemble(
        self,
        points: np.ndarray,
        edges: np.ndarray,
        face_loops: Sequence[Sequence[Sequence[int]]],
        *,
        face_surfaces: Sequence[Any] | None = None,
        face_senses: Sequence[bool] | None = None,
    ) -> None:
        """Add shells given as faces of oriented edge loops.

        Parameters
        ----------
        points : (V, 3) vertex positions (new vertices of this builder)
        edges : (E, 2) vertex index pairs (start, end), local to ``points``
        face_loops : per face, a list of loops (outer first), each a list of signed edge
            references ``+(e + 1)`` (edge traversed start → end) or ``-(e + 1)`` (reversed)
        face_surfaces, face_senses : optional geometry per face

        Each edge must be used exactly once in each direction.  Shells are the connected
        components of the faces; each becomes the outer shell of its own solid (use
        :meth:`nest_shells` to make voids).

        Raises
        ------
        TopologyError
            An edge used other than once forwards and once backwards, a loop whose
            consecutive edges do not meet, or a shell failing Euler–Poincaré.
        """
        points = np.asarray(points, dtype=np.float64)
        edges = np.asarray(edges, dtype=np.int64).reshape(-1, 2)
        v_off, e_off = len(self.vpoint), len(self.ev)
        if points.ndim == 2 and points.shape[1] == 3 and np.isfinite(points).all():
            # What _new_vertex does per point, in bulk (its checks hold for every row at once).
            nv = points.shape[0]
            self.vpoint.extend(list(points))
            self.vtol.extend([self.tol.linear] * nv)
            self.vcoedge.extend([-1] * nv)
            self.valive.extend([True] * nv)
        else:  # _new_vertex names the bad point
            for p in points:
                self._new_vertex(p)
        ne = edges.shape[0]
        self.ev.extend((edges + v_off).tolist())
        self.ealive.extend([True] * ne)
        self.ecurve.extend([-1] * ne)
        self.erange.extend([(0.0, 1.0)] * ne)
        self.epcurve.extend([[-1, -1] for _ in range(ne)])
        self.etol.extend([self.tol.linear] * ne)
        self.nxt.extend([-1] * (2 * ne))
        self.prv.extend([-1] * (2 * ne))
        self.cloop.extend([-1] * (2 * ne))
        face_ids = self._assemble_loops_bulk(edges, v_off, e_off, face_loops, face_surfaces, face_senses)
        if face_ids is None:
            face_ids = self._assemble_loops(edges, v_off, e_off, face_loops, face_surfaces, face_senses)
        # Shells: connected components of faces through shared edges.
        nf = len(face_ids)
        ce = np.arange(2 * e_off, 2 * len(self.ev))
        cf = np.asarray(self.lface, dtype=np.int64)[np.asarray(self.cloop[ce[0]:], dtype=np.int64)] - face_ids[0] \
            if nf and ce.size else np.empty(0, np.int64)
        a, b = cf[0::2], cf[1::2]
        n_comp, labels = components(nf, a, b)
        shell0 = len(self.ssolid)
        for k in range(n_comp):
            solid = len(self.souter)
            shell = len(self.ssolid)
            self.ssolid.append(solid)
            self.salive.append(True)
            self.souter.append(shell)
            self.solive.append(True)
        fshell = self.fshell
        for f, shell in zip(face_ids, (shell0 + np.asarray(labels, dtype=np.int64)).tolist()):
            fshell[f] = shell  # component k is shell shell0 + k

    def _assembled_face(self, fi: int, face_surfaces, face_senses) -> int:
        """A new face for input face ``fi`` of :meth:`assemble`, with its pooled surface and its sense."""
        f = self._new_face(-1)
        if face_surfaces is not None:
            self.fsurface[f] = self._pool("surfaces", face_surfaces[fi])
        if face_senses is not None:
            self.fsense[f] = bool(face_senses[fi])
        return f

    def _assemble_loops(self, edges: np.ndarray, v_off: int, e_off: int, face_loops, face_surfaces,
                        face_senses) -> list[int]:
        """Faces, loops and coedge links of :meth:`assemble`, one coedge at a time; raises on bad input."""
        used = np.zeros((len(edges), 2), dtype=np.int64)
        face_ids: list[int] = []
        loop_ids_per_face: list[list[int]] = []
        for fi, loops in enumerate(face_loops):
            f = self._assembled_face(fi, face_surfaces, face_senses)
            face_ids.append(f)
            lids = []
            for li, loop in enumerate(loops):
                l = self._new_loop(f)
                lids.append(l)
                if li == 0:
                    self.fouter[f] = l
                cs = []
                for ref in loop:
                    if isinstance(ref, bool) or not (isinstance(ref, (int, np.integer)) or (
                            isinstance(ref, (float, np.floating)) and float(ref).is_integer())):
                        raise InvalidInputError(f"face {fi}: edge reference {ref!r} must be a signed integer")
                    if ref == 0 or abs(ref) > len(edges):
                        raise TopologyError(f"face {fi}: edge reference {ref} out of range 1..{len(edges)}")
                    e = abs(int(ref)) - 1
                    side = 0 if ref > 0 else 1
                    used[e, side] += 1
                    cs.append(2 * (e + e_off) + side)
                for i, c in enumerate(cs):
                    n = cs[(i + 1) % len(cs)]
                    if self.target(c) != self.origin(n):
                        raise TopologyError(
                            f"face {fi}, loop {li}: edge {abs(loop[i]) - 1} ends at vertex {self.target(c) - v_off} "
                            f"but the next edge {abs(loop[(i + 1) % len(cs)]) - 1} starts at vertex {self.origin(n) - v_off}"
                        )
                    self._link(c, n)
                self._set_loop(cs, l)
            loop_ids_per_face.append(lids)
        bad = np.flatnonzero((used[:, 0] != 1) | (used[:, 1] != 1))
        if bad.size:
            e = int(bad[0])
            raise TopologyError(
                f"edge {e} (vertices {edges[e].tolist()}) is used {used[e, 0]} times forwards and "
                f"{used[e, 1]} times backwards; a closed manifold shell uses each edge once each way"
            )
        for e in range(len(edges)):
            for side in (0, 1):
                c = 2 * (e + e_off) + side
                v = self.origin(c)
                if self.vcoedge[v] < 0:
                    self.vcoedge[v] = c
        return face_ids

    def _assemble_loops_bulk(self, edges: np.ndarray, v_off: int, e_off: int, face_loops, face_surfaces,
                             face_senses) -> list[int] | None:
        """:meth:`_assemble_loops` in array passes over the coedges, or None (nothing changed).

        Taken only when every precondition the per-coedge path enforces is verified first: edge
        references in range, edge vertices among the new points, consecutive coedges of a loop
        meeting, every new edge used once each way, no empty loop.  Otherwise the per-coedge path
        runs and raises its own message.  Then the new coedges are exactly the contiguous range
        ``2 e_off .. 2 (e_off + E)``, so their links are written as slices (:func:`_bulk_loops`,
        offset here).
        """
        lens = list(map(len, chain.from_iterable(face_loops)))
        if any(x is not None and len(x) < len(face_loops) for x in (face_surfaces, face_senses)):
            return None  # (the per-coedge path fails on the missing entry)
        flat = list(chain.from_iterable(chain.from_iterable(face_loops)))
        # Python or numpy integers only (not bools, floats or strings, which int64 conversion would
        # truncate or parse): anything else goes to the per-coedge path, which refuses bools, strings and
        # fractional floats by name (and takes whole floats such as -1.0 as the integers they are).
        if not all(type(r) is int or isinstance(r, np.integer) for r in flat):
            return None
        try:
            refs = np.fromiter(flat, dtype=np.int64, count=len(flat))
        except OverflowError:
            return None  # (beyond int64: the per-coedge path reports it out of range)
        lens_a = np.asarray(lens, dtype=np.int64)
        bulk = _bulk_loops(edges, len(self.vpoint) - v_off, refs, lens_a)
        if bulk is None:
            return None
        c, first, link, back, cl, verts, at = bulk
        base = 2 * e_off
        c = c + base
        # Faces in input order (their geometry goes through the pools), then their loops, face by
        # face: the rows _new_loop would add, with their first coedges.
        nf = len(face_loops)
        face_ids = self._new_faces(  # what _assembled_face adds face by face, in bulk
            nf, surfaces=None if face_surfaces is None else self._pool_many("surfaces", face_surfaces[:nf]),
            senses=None if face_senses is None else [bool(x) for x in face_senses[:nf]])
        n_loops = [len(loops) for loops in face_loops]
        l0 = len(self.lface)
        lid = np.arange(l0, l0 + lens_a.size, dtype=np.int64)
        self.lface.extend(np.repeat(np.asarray(face_ids, dtype=np.int64), n_loops).tolist())
        self.lcoedge.extend(c[first].tolist())
        self.lvertex.extend([-1] * lens_a.size)
        self.lalive.extend([True] * lens_a.size)
        for f, l, k in zip(face_ids, (l0 + np.cumsum(n_loops) - n_loops).tolist(), n_loops):
            if k:
                self.fouter[f] = l  # the first loop is the outer one
        self.nxt[base:] = (link + base).tolist()
        self.prv[base:] = (back + base).tolist()
        self.cloop[base:] = lid[cl].tolist()
        # Each new vertex's coedge: the first new coedge (in coedge order) leaving it.
        for v, cv in zip((verts + v_off).tolist(), (at + base).tolist()):
            if self.vcoedge[v] < 0:
                self.vcoedge[v] = cv
        return face_ids

    def assemble_polygons(self, points: np.ndarray, face_vertex_loops: Sequence, **kwargs: Any) -> None:
        """:meth:`assemble` with faces given as vertex loops instead of signed edge references.

        Parameters
        ----------
        points : (V, 3) vertex positions
        face_vertex_loops : per face, a loop of vertex indices (outward, counter-clockwise), or a
            list of such loops (outer first, holes clockwise)
        **kwargs : ``face_surfaces``, ``face_senses`` as for :meth:`assemble`

        Each undirected vertex pair becomes one edge, oriented as it is first met; the faces
        then refer to it forwards or backwards.  Suited to hand-written fixtures and small
        polyhedra; :func:`coons.topology.from_mesh.from_mesh` does the same for meshes in numpy.
        """
        edge_of: dict[tuple[int, int], int] = {}
        edges: list[tuple[int, int]] = []
        faces = []
        for face in face_vertex_loops:
            loops = face if isinstance(face[0], (list, tuple, np.ndarray)) else [face]
            refs_f = []
            for loop in loops:
                loop = [int(v) for v in loop]
                refs = []
                for a, b in zip(loop, loop[1:] + loop[:1]):
                    key = (min(a, b), max(a, b))
                    if key not in edge_of:
                        edge_of[key] = len(edges)
                        edges.append((a, b))
                    e = edge_of[key]
                    refs.append(e + 1 if edges[e] == (a, b) else -(e + 1))
                refs_f.append(refs)
            faces.append(refs_f)
        self.assemble(points, np.asarray(edges, dtype=np.int64).reshape(-1, 2), faces, **kwargs)

    def nest_shells(self, outer_shell: int, void_shell: int) -> None:
        """Make ``void_shell`` (oriented inward) a void of the solid of ``outer_shell``."""
        solid_void = self.ssolid[void_shell]
        if self.souter[solid_void] == void_shell:
            self.solive[solid_void] = False
        self.ssolid[void_shell] = self.ssolid[outer_shell]

    # ================================================================ build
    def build(self, *, check: bool = True, caches_from: BRep | None = None, sewn_from: tuple | None = None) -> BRep:
        """Compact killed entities and return an immutable :class:`BRep`.

        ``caches_from``: an earlier build of this builder that differs from this one only in how
        shells are grouped into solids (:meth:`nest_shells` since); its meshes and mass integrals
        and the shells' nesting are shared with the new B-rep before the check (which then reuses them).  ``sewn_from``:
        ``(face specs, unchanged faces)`` of a B-rep sewn from specs, recorded for the check
        (``coons.topology.check._SEWN_FROM``) before it runs.

        Raises
        ------
        TopologyError
            When ``check`` is set and the B-rep breaks an invariant; the message lists the problems.
        """
        valive = np.asarray(self.valive, dtype=bool)
        ealive = np.asarray(self.ealive, dtype=bool)
        lalive = np.asarray(self.lalive, dtype=bool)
        falive = np.asarray(self.falive, dtype=bool)
        salive = np.asarray(self.salive, dtype=bool)
        solive = np.asarray(self.solive, dtype=bool)

        def remap(alive: np.ndarray) -> np.ndarray:
            m = np.full(alive.shape[0] + 1, -1, dtype=np.int64)  # index -1 maps to -1
            m[:-1][alive] = np.arange(int(alive.sum()))
            return m

        vm, em, lm, fm, sm, om = (remap(a) for a in (valive, ealive, lalive, falive, salive, solive))
        cm = np.full(2 * len(self.ev) + 1, -1, dtype=np.int64)
        alive_c = np.repeat(ealive, 2)
        cm[:-1][alive_c] = np.arange(int(alive_c.sum()))

        nxt = np.asarray(self.nxt, dtype=np.int64)[alive_c]
        prv = np.asarray(self.prv, dtype=np.int64)[alive_c]
        cloop = np.asarray(self.cloop, dtype=np.int64)[alive_c]
        wing = np.stack([cm[prv[0::2]], cm[nxt[0::2]], cm[prv[1::2]], cm[nxt[1::2]]], axis=1) if nxt.size else np.zeros((0, 4), np.int64)

        lface = fm[np.asarray(self.lface, dtype=np.int64)[lalive]]
        fshell = sm[np.asarray(self.fshell, dtype=np.int64)[falive]]
        ssolid = om[np.asarray(self.ssolid, dtype=np.int64)[salive]]
        fouter = lm[np.asarray(self.fouter, dtype=np.int64)[falive]]
        souter = sm[np.asarray(self.souter, dtype=np.int64)[solive]]

        def csr(owner: np.ndarray, n_owner: int, first: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
            items = np.arange(owner.shape[0])
            key = owner * 2 + (items != first[owner]).astype(np.int64) if owner.size else owner
            order = np.lexsort((items, key)) if owner.size else items
            ptr = np.zeros(n_owner + 1, dtype=np.int64)
            np.add.at(ptr, owner + 1, 1)
            return np.cumsum(ptr), items[order]

        face_loop_ptr, face_loops = csr(lface, int(falive.sum()), fouter)
        shell_face_ptr, shell_faces = csr(fshell, int(salive.sum()), np.zeros(int(salive.sum()), np.int64) - 1)
        solid_shell_ptr, solid_shells = csr(ssolid, int(solive.sum()), souter)

        brep = BRep(
            vertex_point=np.asarray(self.vpoint, dtype=np.float64).reshape(-1, 3)[valive],
            vertex_tol=np.asarray(self.vtol)[valive],
            vertex_coedge=cm[np.asarray(self.vcoedge, dtype=np.int64)[valive]],
            edge_vertex=vm[np.asarray(self.ev, dtype=np.int64).reshape(-1, 2)[ealive]],
            edge_loop=lm[cloop].reshape(-1, 2),
            edge_wing=wing,
            edge_curve=np.asarray(self.ecurve, dtype=np.int64)[ealive],
            edge_range=np.asarray(self.erange, dtype=np.float64).reshape(-1, 2)[ealive],
            edge_pcurve=np.asarray(self.epcurve, dtype=np.int64).reshape(-1, 2)[ealive],
            edge_tol=np.asarray(self.etol)[ealive],
            loop_face=lface,
            loop_coedge=cm[np.asarray(self.lcoedge, dtype=np.int64)[lalive]],
            loop_vertex=vm[np.asarray(self.lvertex, dtype=np.int64)[lalive]],
            face_surface=np.asarray(self.fsurface, dtype=np.int64)[falive],
            face_sense=np.asarray(self.fsense, dtype=bool)[falive],
            face_shell=fshell,
            face_loop_ptr=face_loop_ptr,
            face_loops=face_loops,
            shell_solid=ssolid,
            shell_face_ptr=shell_face_ptr,
            shell_faces=shell_faces,
            solid_shell_ptr=solid_shell_ptr,
            solid_shells=solid_shells,
            surfaces=tuple(self.surfaces),
            curves=tuple(self.curves),
            pcurves=tuple(self.pcurves),
        )
        return _finished(brep, self.tol, check, caches_from, sewn_from)


def _finished(brep: BRep, tol: Tolerance, check: bool, caches_from: BRep | None, sewn_from: tuple | None) -> BRep:
    """The end of :meth:`BRepBuilder.build` (and of :func:`assembled_brep`): caches shared from
    ``caches_from``, the sewing record, the check."""
    if caches_from is not None:
        from coons.topology.mass import share_mass_caches
        from coons.topology.nesting import share_nesting
        from coons.topology.tessellate import share_tessellations

        share_mass_caches(caches_from, brep)
        share_tessellations(caches_from, brep)
        share_nesting(caches_from, brep)
    if sewn_from is not None:
        from coons.topology.check import _SEWN_FROM

        _SEWN_FROM[brep] = sewn_from
    if check:
        from coons.topology.check import check as _check

        report = _check(brep, tol=tol)
        if not report.ok:
            raise TopologyError("the built B-rep is invalid:\n" + report.summary())
    return brep


def _pooled(objs: Sequence[Any], ids: np.ndarray | None = None) -> tuple[list[Any], np.ndarray, np.ndarray, np.ndarray]:
    """The pool an empty :meth:`BRepBuilder._pool_many` makes of ``objs``: the distinct objects (by
    identity, None left out) in the order first seen, ``(n,)`` int64 the index of each (-1 for None),
    and the pool's ids ``(p,)`` uint64 in pool order with the order ``(p,)`` that sorts them (for
    :func:`~coons.topology._memo.seed_pool_ids`).  ``ids (n,)`` int64: the objects' ``id`` when the
    caller has them (``objs`` holds the objects, so they stay theirs)."""
    n = len(objs)
    if ids is None:
        ids = np.fromiter(map(id, objs), dtype=np.int64, count=n)
    some = ids != id(None)
    uniq, first, inv = np.unique(ids[some], return_index=True, return_inverse=True)
    rank = np.empty(uniq.size, dtype=np.int64)
    by_first = np.argsort(first)
    rank[by_first] = np.arange(uniq.size)
    idx = np.full(n, -1, dtype=np.int64)
    idx[some] = rank[inv.reshape(-1)]
    at = np.flatnonzero(some)[first[by_first]]
    # (ids are addresses, >= 0: the same order as uint64; distinct, so the sort is the stable one)
    pool = objs[at].tolist() if isinstance(objs, np.ndarray) else [objs[i] for i in at.tolist()]
    return pool, idx, uniq[by_first].view(np.uint64), rank


def _bulk_loops(edges: np.ndarray, nv: int, refs: np.ndarray, lens: np.ndarray) -> tuple[np.ndarray, ...] | None:
    """The links of loops given as signed edge references, in array passes over the coedges, with
    coedges, loops and vertices numbered from 0 (the caller adds its offsets); None unless every
    precondition of the per-coedge :meth:`BRepBuilder._assemble_loops` holds (it then names the
    fault): edges present with vertices in ``0 .. nv - 1``, references in range, no empty loop,
    every edge used once each way, consecutive coedges of a loop meeting.

    Parameters
    ----------
    edges : (E, 2) int64, start and end vertex
    nv : the number of vertices
    refs : (K,) int64, the signed edge references of all loops in turn (``+(e + 1)`` forwards,
        ``-(e + 1)`` backwards)
    lens : (L,) int64, the references per loop

    Returns
    -------
    c : (K,) int64, the coedge ``2 e + side`` of each reference; first : (L,) int64, the position of
    each loop's first reference; link, back, cloop : (2E,) int64, each coedge's next and previous
    coedge and its loop; verts, at : the vertices with a coedge leaving them and the first such
    coedge (in coedge order).
    """
    ne = edges.shape[0]
    if ne == 0 or lens.size == 0 or lens.min() <= 0 or edges.min() < 0 or edges.max() >= nv:
        return None
    if (refs == 0).any() or (np.abs(refs) > ne).any():
        return None
    e = np.abs(refs) - 1
    side = (refs < 0).astype(np.int64)
    c = 2 * e + side
    if not (np.bincount(c, minlength=2 * ne) == 1).all():
        return None
    first = np.cumsum(lens) - lens
    idx = np.arange(refs.size)
    loop_of = np.repeat(np.arange(lens.size), lens)
    nxt = np.where(idx + 1 < first[loop_of] + lens[loop_of], idx + 1, first[loop_of])
    if not (edges[e, 1 - side] == edges[e, side][nxt]).all():
        return None
    # Every coedge is used once (the bincount), so c is a permutation of 0 .. 2E - 1.
    link = np.empty(2 * ne, dtype=np.int64)
    back = np.empty(2 * ne, dtype=np.int64)
    cloop = np.empty(2 * ne, dtype=np.int64)
    link[c] = c[nxt]
    back[c[nxt]] = c
    cloop[c] = loop_of
    verts, at = np.unique(edges.ravel(), return_index=True)  # the origin of coedge 2 e + side is edges[e, side]
    return c, first, link, back, cloop, verts, at


def assembled_brep(points: np.ndarray, vertex_tols: np.ndarray, edges: np.ndarray, refs: np.ndarray,
                   loop_lens: np.ndarray, face_loop_counts: np.ndarray, face_surfaces: Sequence[Any],
                   face_senses: Sequence[bool], edge_curves: Sequence[Any], edge_ranges: np.ndarray,
                   edge_tols: np.ndarray, pcurve_coedges: np.ndarray, pcurves: Sequence[Any],
                   tol: Tolerance, *, check: bool = True, sewn_from: tuple | None = None,
                   curve_ids: np.ndarray | None = None, pcurve_ids: np.ndarray | None = None) -> BRep | None:
    """The B-rep of one shell, built from arrays: what a fresh :class:`BRepBuilder` makes of

    ``assemble(points, edges, face_loops, face_surfaces=..., face_senses=...)``,
    ``set_vertex_tols(arange(V), vertex_tols)``, ``set_edge_curves(arange(E), edge_curves,
    edge_ranges, edge_tols)``, ``set_pcurves(pcurve_coedges, pcurves)`` and ``build(check=...,
    sewn_from=...)``, array for array and with the same pools, or None when that sequence would
    not go the bulk way: input it rejects (it then names the fault), faces forming more than one
    shell (which the sewing may nest), a lone-vertex loop.  Without the builder's per-entity lists
    it costs array passes over the coedges (the sewing of a large result).

    Parameters
    ----------
    points : (V, 3) float64, vertex_tols : (V,) float64
    edges : (E, 2) int64, start and end vertex
    refs : (K,) int64, the signed edge references of all loops in face and loop order
        (``+(e + 1)`` forwards, ``-(e + 1)`` backwards), ``face_loops`` flattened
    loop_lens : (L,) int64, the references per loop; face_loop_counts : (F,) int64, loops per face
    face_surfaces, face_senses : per face
    edge_curves : per edge; edge_ranges : (E, 2) float64; edge_tols : (E,) float64
    pcurve_coedges : (m,) int64 and pcurves : (m,), the p-curve of each listed coedge (pool order)
    curve_ids, pcurve_ids : (E,) and (m,) int64, optional: ``id`` of each of ``edge_curves`` and
        ``pcurves`` (else taken here); the curves may come as object arrays

    Raises
    ------
    TopologyError
        ``check`` found a problem (as :meth:`BRepBuilder.build`).
    """
    points = np.asarray(points, dtype=np.float64)
    edges = np.asarray(edges, dtype=np.int64).reshape(-1, 2)
    refs = np.asarray(refs, dtype=np.int64)
    lens = np.asarray(loop_lens, dtype=np.int64)
    per_face = np.asarray(face_loop_counts, dtype=np.int64)
    ranges = np.asarray(edge_ranges, dtype=np.float64).reshape(-1, 2)
    nv, ne, nl, nf = points.shape[0], edges.shape[0], lens.size, per_face.size
    # The checks that send the builder off the bulk path (BRepBuilder.assemble, _assemble_loops_bulk,
    # set_edge_curves): then the builder runs and raises its own message.
    if (points.ndim != 2 or points.shape[1] != 3 or not np.isfinite(points).all()
            or per_face.min(initial=1) <= 0 or int(per_face.sum()) != nl or int(lens.sum()) != refs.size
            or len(face_surfaces) < nf or len(face_senses) < nf or not (ranges[:, 0] < ranges[:, 1]).all()):
        return None
    bulk = _bulk_loops(edges, nv, refs, lens)
    if bulk is None:
        return None
    c, first, link, back, cloop, verts, at = bulk
    loop_face = np.repeat(np.arange(nf, dtype=np.int64), per_face)
    # Shells: components of the faces through their shared edges (coedges 2e and 2e + 1).
    cface = loop_face[cloop]
    n_comp, label = components(nf, cface[0::2], cface[1::2])
    if n_comp != 1:
        return None
    # Each vertex's coedge: the first coedge (in coedge order) leaving it (isolated vertices: -1).
    vcoedge = np.full(nv, -1, dtype=np.int64)
    vcoedge[verts] = at
    surfaces, fs, s_ids, s_order = _pooled(face_surfaces[:nf])
    curves, ci, c_ids, c_order = _pooled(edge_curves, curve_ids)
    pcurves_pool, pi, p_ids, p_order = _pooled(pcurves, pcurve_ids)
    epcurve = np.full(2 * ne, -1, dtype=np.int64)
    epcurve[np.asarray(pcurve_coedges, dtype=np.int64)] = pi
    face_loop_ptr = np.zeros(nf + 1, dtype=np.int64)
    np.cumsum(per_face, out=face_loop_ptr[1:])
    brep = BRep(
        vertex_point=points,
        vertex_tol=np.asarray(vertex_tols, dtype=np.float64),
        vertex_coedge=vcoedge,
        edge_vertex=edges,
        edge_loop=cloop.reshape(-1, 2),
        edge_wing=np.stack([back[0::2], link[0::2], back[1::2], link[1::2]], axis=1),
        edge_curve=ci,
        edge_range=ranges,
        edge_pcurve=epcurve.reshape(-1, 2),
        edge_tol=np.asarray(edge_tols, dtype=np.float64),
        loop_face=loop_face,
        loop_coedge=c[first],
        loop_vertex=np.full(nl, -1, dtype=np.int64),
        face_surface=fs,
        face_sense=np.array([bool(x) for x in face_senses[:nf]], dtype=bool),
        face_shell=np.zeros(nf, dtype=np.int64),
        face_loop_ptr=face_loop_ptr,
        face_loops=np.arange(nl, dtype=np.int64),
        shell_solid=np.zeros(1, dtype=np.int64),
        shell_face_ptr=np.array([0, nf], dtype=np.int64),
        shell_faces=np.arange(nf, dtype=np.int64),
        solid_shell_ptr=np.array([0, 1], dtype=np.int64),
        solid_shells=np.zeros(1, dtype=np.int64),
        surfaces=tuple(surfaces),
        curves=tuple(curves),
        pcurves=tuple(pcurves_pool),
    )
    # The pools' ids sorted above serve the next B-rep's gathers from this one (and its own from
    # its operand): _memo.pool_positions need not take them again.
    seed_pool_ids(brep, "surfaces", s_ids, s_order)
    seed_pool_ids(brep, "curves", c_ids, c_order)
    seed_pool_ids(brep, "pcurves", p_ids, p_order)
    return _finished(brep, tol, check, None, sewn_from)
