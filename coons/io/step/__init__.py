"""STEP (ISO 10303-21) exchange: the writer (:func:`export_step`) of coons solids as AP214 / AP242 advanced B-reps.

The Part 21 parser, schema mapping and reader live beside it (``p21``, ``schema``, ``reader``).
"""

from coons.io.step.writer import export_step

__all__ = ["export_step"]
