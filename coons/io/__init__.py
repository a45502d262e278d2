"""coons.io: exchange with files and with other engines.

* :mod:`coons.io.step` — STEP (ISO 10303-21, AP214/AP242) export and import of solids: a Part 21
  parser (``p21``), the schema mapping to coons geometry (``schema``), and the conversion of
  neutral faces to checked solids (``reader`` through :mod:`coons.io._faces`, which also serves
  :func:`~coons.io.from_ocp.from_ocp`), and the writer (``writer``).
* :mod:`coons.io.stl` — STL export (of meshes or tessellated solids) and import.
* :mod:`coons.io.mesh` — trimesh and manifold3d meshes; :mod:`coons.io.ocp` and
  :mod:`coons.io.from_ocp` — OCCT shapes (TopoDS / build123d) built and read directly.

Only this package and :mod:`coons.validation` import the reference engines, and only inside the
functions that need them, so ``import coons`` never loads OCCT, manifold3d or trimesh.
"""
