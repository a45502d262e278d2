"""coons.validation: ``coons validate``, the comparison of coons with OCCT and manifold3d on reference cases.

* :mod:`.cases` — the catalogue of named recipes (primitives, placements, Booleans, mesh inputs);
* :mod:`.engines` — each recipe built and measured by coons, by OCCT (through build123d / OCP)
  and by manifold3d (on coons's tessellations of the operands);
* :mod:`.compare` — measures, tolerances, the exact point–mesh distance and Hausdorff distance, and
  the verdict of a case (agree / disagree / coons-raised / reference-failed);
* :mod:`.runner` — one case per process (crashes and hangs recorded), or a Dask cluster;
* :mod:`.report` — the text table, the HTML report with pictures, the exit status.

This package is the only place besides :mod:`coons.io` that uses the reference engines, and it
imports them lazily: importing it loads neither OCP, build123d, manifold3d, trimesh nor matplotlib.
"""

from coons.validation.cases import CATALOGUE, Case, default_cases, select_cases
from coons.validation.compare import Verdict, hausdorff, judge, point_mesh_distance
from coons.validation.engines import EngineResult
from coons.validation.runner import RunOptions, run_case, run_cases

__all__ = [
    "CATALOGUE",
    "Case",
    "default_cases",
    "select_cases",
    "EngineResult",
    "Verdict",
    "judge",
    "hausdorff",
    "point_mesh_distance",
    "RunOptions",
    "run_case",
    "run_cases",
]
