"""Which shell of a B-rep lies inside which: the nesting of lumps and voids.

A solid is one outer shell (oriented outward: it encloses positive volume) and any voids
(oriented inward) inside it; a B-rep may hold several solids (lumps), each apart from the
others or inside a void of another.  Shells are disjoint, so one shell lies inside another iff
any one of its vertices does (the *probe*), and that is decided by the generalised winding
number of the probe with respect to the other shell, computed from a closed triangle chain whose
answer is proven to be the exact surface's:

* *Cones* (no tessellation).  For a face, the cone from one of its vertices over the chords of
  its coedges (straight segments between their end vertices) has the same boundary as the face up
  to the strips between each edge curve and its chord, which cancel between the two faces of the
  edge.  So the face minus its cone, minus its strips, is a closed chain inside any convex set
  holding the face and its edges, and its winding number about a point outside that set is 0:
  when the probe lies outside every face box of the other shell
  (:func:`coons.topology.mass.face_box_bounds`), the cones' winding number is the shell's.
* *Mesh* (a probe inside some face box).  The other shell's triangles in the tessellation at the
  default deflection ``d`` (:func:`coons.topology.tessellate.tessellate`): far faces as above, and
  faces whose box holds the probe count when the probe is farther than ``2 (d + e)``, ``e`` the
  largest edge tolerance, plus ``10 tol.linear`` from their triangles (the band of
  :class:`coons.booleans.classify.Classifier`: mesh and face are within ``d`` of each other, so
  the straight homotopy between them misses the probe).  Where that fails, the deflection is
  divided by 8, at most three times and while it stays above ``tol.linear`` (finer meshes are not
  cached); a probe within the band's tolerance part, or still within the band at the finest
  deflection, means the shells touch, and raises.

The probe of a pair is the vertex of the inner shell inside the fewest face boxes of the outer
(none: the cones), else the one farthest from the mesh of the faces whose boxes hold it.  Only
pairs where every vertex of one shell lies in the box of the other are tested (a shell inside
another lies inside its box).

:func:`shell_parents` is used by sewing (:func:`coons.topology.sew._nest_voids`, which makes each
void a void of the shell around it and refuses a lump inside a lump) and by the checker (a void
must lie inside its solid's outer shell, an outer shell inside no other outer shell).  The parents
found for a B-rep are remembered for it and its tolerance (weakly) and shared with a rebuild that differs only in how
shells are grouped into solids (:func:`share_nesting`), so the check after sewing reads them.
"""

from __future__ import annotations

import numpy as np

from coons.errors import TopologyError
from coons.tolerance import Tolerance, resolve
from coons.topology._memo import IdentityMemo

__all__ = ["shell_parents", "share_nesting"]

#: B-rep -> ``(tolerance, (S,) parents)`` found by :func:`shell_parents` (a function of the geometry,
#: the shells' faces and the tolerance, not of the shells' grouping into solids).
_PARENTS = IdentityMemo()

# Divisions of the deflection by 8 before two shells are declared touching (1/512 of the
# default: about 2e-6 of the diagonal, far below any wall a Boolean leaves).
_REFINEMENTS = 3


def shell_parents(brep, tol: Tolerance | None = None, volumes: np.ndarray | None = None) -> np.ndarray:
    """For each shell, the shell immediately around it.

    Parameters
    ----------
    brep : BRep
    tol : Tolerance, optional
    volumes : (S,) float64, optional
        The shells' signed volumes (:func:`coons.topology.mass.shell_volumes`), if known: among
        the shells holding a shell, the immediate one is the one of least ``|volume|``.

    Returns
    -------
    (S,) int64
        The index of the smallest shell enclosing each shell, -1 for a shell inside no other.

    Raises
    ------
    TopologyError
        Two shells touch: every vertex of one lies within the mesh band of the other at the
        finest deflection tried, so which side it lies on is not proven.
    InvalidInputError
        A mesh is needed and the default deflection is not above ``tol.linear``.
    """
    t = resolve(tol)
    got = _PARENTS.get(brep)
    if got is not None and got[0] == t:
        return got[1].copy()
    S = brep.n_shells
    parents = np.full(S, -1, dtype=np.int64)
    if S < 2:
        return parents
    from coons.topology.mass import face_box_bounds, shell_volumes

    box = face_box_bounds(brep, t)
    face_shell = np.asarray(brep.face_shell, dtype=np.int64)
    lo = np.full((S, 3), np.inf)
    hi = np.full((S, 3), -np.inf)
    np.minimum.at(lo, face_shell, box[:, 0])
    np.maximum.at(hi, face_shell, box[:, 1])
    c_face = np.asarray(brep.coedge_face, dtype=np.int64)
    origin = np.asarray(brep.coedge_origin, dtype=np.int64)
    used = c_face >= 0
    c_shell = face_shell[c_face[used]]
    P = brep.vertex_point[origin[used]]
    vlo = np.full((S, 3), np.inf)
    vhi = np.full((S, 3), -np.inf)
    np.minimum.at(vlo, c_shell, P)
    np.maximum.at(vhi, c_shell, P)
    # (s, o): every vertex of shell s lies in the face-box hull of shell o.
    cand = ((vlo[:, None, :] >= lo[None, :, :]) & (vhi[:, None, :] <= hi[None, :, :])).all(axis=2)
    np.fill_diagonal(cand, False)
    if cand.any():
        vol = shell_volumes(brep, t) if volumes is None else np.asarray(volumes, dtype=np.float64)
        inside = np.zeros((S, S), dtype=bool)
        probe = _Probe(brep, t, box, face_shell, c_face, origin)
        for s, o in zip(*np.nonzero(cand)):
            inside[s, o] = probe.inside(int(s), int(o))
        for s in np.flatnonzero(inside.any(axis=1)).tolist():
            holders = np.flatnonzero(inside[s])
            parents[s] = int(holders[np.argmin(np.abs(vol[holders]))])
    _PARENTS.set(brep, (t, parents))
    return parents.copy()


def share_nesting(src, dst) -> None:
    """Let ``dst`` reuse the parents found for ``src`` (two builds of the same shells, differing at
    most in how the shells are grouped into solids)."""
    got = _PARENTS.get(src)
    if got is not None and src.n_shells == dst.n_shells:
        _PARENTS.set(dst, got)


class _Probe:
    """Winding numbers of one shell's vertices with respect to another shell (see the module
    docstring); the meshes are made once, when a probe first needs them."""

    def __init__(self, brep, t: Tolerance, box: np.ndarray, face_shell: np.ndarray, c_face: np.ndarray,
                 origin: np.ndarray) -> None:
        self.brep, self.t, self.box, self.face_shell = brep, t, box, face_shell
        self.c_face, self.origin = c_face, origin
        # The cone chain of every shell: per coedge, its face's apex and its chord.
        used = np.flatnonzero(c_face >= 0)
        apex = np.full(brep.n_faces, -1, dtype=np.int64)
        apex[c_face[used]] = origin[used]  # any vertex of the face lies in its box
        V = brep.vertex_point
        self.cones = V[np.stack([apex[c_face[used]], origin[used], origin[brep.coedge_next[used]]], axis=1)]
        self.cone_shell = face_shell[c_face[used]]
        self.meshes: list = []

    def inside(self, s: int, o: int) -> bool:
        """Whether shell ``s`` lies inside shell ``o``."""
        from coons.topology.from_mesh import _triangle_distances, _winding_numbers
        from coons.topology.tessellate import ANGULAR_DEFLECTION, _resolve_deflection, _tessellate, tessellate

        brep, t = self.brep, self.t
        verts = np.unique(self.origin[np.isin(self.c_face, brep.shell_face_ids(s))])
        P = brep.vertex_point[verts]
        o_faces = np.flatnonzero(self.face_shell == o)
        B = self.box[o_faces]
        held = ((P[:, None, :] >= B[None, :, 0]) & (P[:, None, :] <= B[None, :, 1])).all(axis=2)
        k = int(np.argmin(held.sum(axis=1)))
        if not held[k].any():
            return abs(_winding_numbers(P[k][None], self.cones[self.cone_shell == o])[0]) > 0.5
        # (here every vertex lies in some face box of o: else the cones above decided)
        near = np.zeros((len(verts), brep.n_faces), dtype=bool)  # per vertex, the faces whose boxes hold it
        near[:, o_faces] = held
        d = _resolve_deflection(brep, None, t)
        etol = float(np.max(brep.edge_tol, initial=0.0))
        gap_floor = 2.0 * etol + 10.0 * t.linear  # (the band's part no deflection removes)
        for r in range(_REFINEMENTS + 1):
            if r == len(self.meshes):
                # The default mesh is cached (and shared with the result); finer ones are not kept.
                self.meshes.append(tessellate(brep, deflection=d, tol=t) if r == 0
                                   else _tessellate(brep, d, ANGULAR_DEFLECTION, t))
            mesh = self.meshes[r]
            tri = mesh.vertices[mesh.triangles]
            band = 2.0 * (d + etol) + 10.0 * t.linear
            # Any vertex serves as the probe (shells are disjoint): the one farthest from the
            # triangles of the faces whose boxes hold it.
            gaps = np.full(len(verts), np.inf)
            for i in range(len(verts)):
                at_near = near[i][mesh.face_ids]
                if at_near.any():
                    gaps[i] = _triangle_distances(P[i], tri[at_near]).min()
            k = int(np.argmax(gaps))
            gap = gaps[k]
            if gap > band:
                w = _winding_numbers(P[k][None], tri[self.face_shell[mesh.face_ids] == o])[0]
                return abs(w) > 0.5
            # A finer mesh helps only when the gap exceeds the band's fixed part (the tolerances)
            # and the tessellator accepts the finer deflection (above tol.linear).
            if gap <= gap_floor or d / 8.0 <= t.linear:
                break
            d /= 8.0
        raise TopologyError(
            f"shell {s} (faces {brep.shell_face_ids(s)[:8].tolist()}) has its vertex {int(verts[k])} "
            f"{gap:.3g} from shell {o}'s tessellation at deflection {d:.3g} (band {band:.3g}, "
            f"tolerances {gap_floor:.3g}): the shells touch"
        )
