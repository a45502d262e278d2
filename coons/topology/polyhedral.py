"""Array helpers for faces that are implicit planes (polyhedral B-reps, meshes).

Formulas over all faces at once: the loop vertex rings of the faces as flat arrays,
Newell normals, plane deviation.  Nothing here changes topology.
"""

from __future__ import annotations

import numpy as np

from coons.topology.brep import BRep

__all__ = ["loop_rings", "newell_normals", "face_plane_deviation"]


def loop_rings(b: BRep, loops: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Coedges of the given loops, concatenated in order.

    Returns
    -------
    coedges : (k,) int64
    owner : (k,) int64, position in ``loops`` of each coedge's loop
    """
    loops = np.asarray(loops, dtype=np.int64)
    parts = [b.loop_coedges(int(l)) for l in loops]
    if not parts:
        return np.empty(0, np.int64), np.empty(0, np.int64)
    owner = np.repeat(np.arange(len(parts)), [len(p) for p in parts])
    return np.concatenate(parts), owner


def newell_normals(points: np.ndarray, nxt_points: np.ndarray, owner: np.ndarray, n: int) -> np.ndarray:
    """Newell's area vectors of polygons given as edge lists (``points[i] -> nxt_points[i]`` in polygon ``owner[i]``).

    Returns
    -------
    (n, 3) float64: twice the vector area of each polygon (not normalised).
    """
    cr = np.cross(points, nxt_points)
    out = np.zeros((n, 3))
    np.add.at(out, owner, cr)
    return out


def face_plane_deviation(b: BRep, faces: np.ndarray) -> np.ndarray:
    """Largest distance of a face's vertices from its Newell plane, ``(len(faces),)``."""
    faces = np.asarray(faces, dtype=np.int64)
    loops = np.concatenate([b.face_loop_ids(int(f)) for f in faces]) if faces.size else np.empty(0, np.int64)
    loop_owner = np.repeat(np.arange(faces.size), [len(b.face_loop_ids(int(f))) for f in faces])
    cs, lo = loop_rings(b, loops)
    owner = loop_owner[lo]
    P = b.vertex_point[b.coedge_origin[cs]]
    Q = b.vertex_point[b.coedge_target[cs]]
    N = newell_normals(P, Q, owner, faces.size)
    norm = np.linalg.norm(N, axis=1)
    unit = np.divide(N, norm[:, None], out=np.zeros_like(N), where=norm[:, None] > 0)
    counts = np.bincount(owner, minlength=faces.size)
    centroid = np.zeros((faces.size, 3))
    np.add.at(centroid, owner, P)
    centroid /= np.maximum(counts, 1)[:, None]
    d = np.abs(np.einsum("ij,ij->i", P - centroid[owner], unit[owner]))
    out = np.zeros(faces.size)
    np.maximum.at(out, owner, d)
    return out
