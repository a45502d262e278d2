"""Mesh interoperability: coons solids and triangle meshes to and from trimesh and manifold3d.

:func:`to_trimesh` and :func:`to_manifold` accept a :class:`~coons.topology.shape.Solid`,
a :class:`~coons.topology.brep.BRep` (tessellated with :func:`~coons.topology.tessellate.tessellate`,
keyword arguments passed through) or a :class:`~coons.topology.mesh.TriangleMesh`, and keep
coons's vertex order and triangle orientation (``trimesh.Trimesh(..., process=False)``; a
manifold3d mesh of float32 positions and uint32 indices).  :func:`mesh_from_trimesh` reads
a ``trimesh.Trimesh`` back into a ``TriangleMesh``.  trimesh and manifold3d are imported
inside the functions, so importing this module costs nothing and a missing library fails only
when used.  The module does not merge, repair or re-orient meshes, and it does not build
B-reps from meshes (see :meth:`coons.topology.builder.BRepBuilder.assemble`).
"""

from __future__ import annotations

import numpy as np

from coons.errors import InvalidInputError
from coons.topology.mesh import TriangleMesh

__all__ = ["as_triangle_mesh", "to_trimesh", "to_manifold", "mesh_from_trimesh"]


def as_triangle_mesh(shape_or_mesh, **tessellate_kwargs) -> TriangleMesh:
    """The ``TriangleMesh`` of a Solid or BRep (tessellated), or the mesh itself.

    Parameters
    ----------
    shape_or_mesh : Solid, BRep or TriangleMesh
    **tessellate_kwargs
        ``deflection``, ``angular_deflection``, ``tol`` for :func:`~coons.topology.tessellate.tessellate`
        (not allowed with a ``TriangleMesh``).

    Raises
    ------
    InvalidInputError
        Another type, or tessellation arguments given with a mesh.
    """
    if isinstance(shape_or_mesh, TriangleMesh):
        if tessellate_kwargs:
            raise InvalidInputError(
                f"tessellation arguments {sorted(tessellate_kwargs)} were given with an already tessellated TriangleMesh"
            )
        return shape_or_mesh
    from coons.topology.brep import BRep

    if isinstance(shape_or_mesh, BRep) or isinstance(getattr(shape_or_mesh, "brep", None), BRep):
        from coons.topology.tessellate import tessellate

        return tessellate(shape_or_mesh, **tessellate_kwargs)
    raise InvalidInputError(f"expected a Solid, BRep or TriangleMesh, got {type(shape_or_mesh).__name__}")


def to_trimesh(shape_or_mesh, **tessellate_kwargs):
    """A ``trimesh.Trimesh`` with coons's vertices and triangles, unprocessed (same order and orientation).

    Parameters
    ----------
    shape_or_mesh : Solid, BRep or TriangleMesh
    **tessellate_kwargs
        Passed to :func:`~coons.topology.tessellate.tessellate` for a Solid or BRep.

    Returns
    -------
    trimesh.Trimesh
        ``vertices (n, 3) float64``, ``faces (m, 3) int64``; the B-rep face of each triangle
        in ``face_attributes["face_ids"]`` when known.

    Raises
    ------
    InvalidInputError
        See :func:`as_triangle_mesh`.
    """
    import trimesh

    mesh = as_triangle_mesh(shape_or_mesh, **tessellate_kwargs)
    attrs = {} if mesh.face_ids is None else {"face_ids": np.array(mesh.face_ids)}
    return trimesh.Trimesh(
        vertices=np.array(mesh.vertices),
        faces=np.array(mesh.triangles),
        face_attributes=attrs,
        process=False,
        validate=False,
    )


def to_manifold(shape_or_mesh, **tessellate_kwargs):
    """A ``manifold3d.Manifold`` of the mesh (float32 positions, uint32 indices, as manifold3d stores them).

    Parameters
    ----------
    shape_or_mesh : Solid, BRep or TriangleMesh
    **tessellate_kwargs
        Passed to :func:`~coons.topology.tessellate.tessellate` for a Solid or BRep.

    Returns
    -------
    manifold3d.Manifold

    Raises
    ------
    InvalidInputError
        See :func:`as_triangle_mesh`; a mesh too large for uint32 indices; or manifold3d
        rejecting the mesh (its ``status()`` is not ``NoError``: not closed, not manifold),
        with the status in the message.
    """
    import manifold3d

    mesh = as_triangle_mesh(shape_or_mesh, **tessellate_kwargs)
    if mesh.n_vertices > np.iinfo(np.uint32).max:
        raise InvalidInputError(
            f"manifold3d indexes vertices with uint32: at most {np.iinfo(np.uint32).max}, got {mesh.n_vertices}"
        )
    m = manifold3d.Manifold(
        manifold3d.Mesh(
            vert_properties=np.ascontiguousarray(mesh.vertices, dtype=np.float32),
            tri_verts=np.ascontiguousarray(mesh.triangles, dtype=np.uint32),
        )
    )
    status = m.status()
    if status != manifold3d.Error.NoError:
        raise InvalidInputError(f"manifold3d rejected the mesh: status {status.name} (expected NoError)")
    return m


def mesh_from_trimesh(tm) -> TriangleMesh:
    """A ``TriangleMesh`` of a ``trimesh.Trimesh`` (vertices and faces as they are; ``face_ids`` from
    ``face_attributes["face_ids"]`` when present).

    Raises
    ------
    InvalidInputError
        An object without ``vertices`` and ``faces`` arrays, or arrays of the wrong shape.
    """
    V = getattr(tm, "vertices", None)
    F = getattr(tm, "faces", None)
    if V is None or F is None:
        raise InvalidInputError(f"expected a trimesh.Trimesh (with vertices and faces), got {type(tm).__name__}")
    attrs = getattr(tm, "face_attributes", None) or {}
    ids = attrs.get("face_ids")
    face_ids = None if ids is None else np.asarray(ids)
    return TriangleMesh(np.asarray(V, dtype=np.float64), np.asarray(F, dtype=np.int64), face_ids)
