"""STEP (ISO 10303-21) exchange of coons solids as AP214 / AP242 advanced B-reps.

:func:`export_step` (``writer``) writes exact analytic and B-spline geometry with p-curves;
:func:`import_step` (``reader``) reads what OCCT, FreeCAD and build123d write, through three
separate layers: the Part 21 parser (``p21``), the schema mapping to coons geometry and neutral
faces (``schema``), and the conversion to checked solids (``reader`` and
:mod:`coons.io._faces`: seams split, poles, p-curves, sewing).
"""

from coons.io.step.reader import import_step, import_step_solids
from coons.io.step.writer import export_step

__all__ = ["export_step", "import_step", "import_step_solids"]
