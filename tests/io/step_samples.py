"""Hand-written (writer-free) STEP texts for the reader and fuzz tests: polyhedra of planes and lines.

The text is produced by a few string templates following ISO 10303-42/-21 directly (no coons or
OCCT writer involved), so that the reader is tested against an independent source.
"""

from __future__ import annotations

import numpy as np

_UNITS = {
    "mm": "#{u}=( LENGTH_UNIT() NAMED_UNIT(*) SI_UNIT(.MILLI.,.METRE.) );",
    "m": "#{u}=( LENGTH_UNIT() NAMED_UNIT(*) SI_UNIT($,.METRE.) );",
    "inch": ("#{m}=( LENGTH_UNIT() NAMED_UNIT(*) SI_UNIT(.MILLI.,.METRE.) );\n"
             "#{k}=LENGTH_MEASURE_WITH_UNIT(LENGTH_MEASURE(25.4),#{m});\n"
             "#{u}=( CONVERSION_BASED_UNIT('INCH',#{k}) LENGTH_UNIT() NAMED_UNIT(#{d}) );\n"
             "#{d}=DIMENSIONAL_EXPONENTS(1.,0.,0.,0.,0.,0.,0.);"),
}


class _Writer:
    def __init__(self) -> None:
        self.lines: list[str] = []
        self.n = 0

    def add(self, text: str) -> int:
        self.n += 1
        self.lines.append(f"#{self.n}={text};")
        return self.n

    def ids(self, k: int) -> list[int]:
        out = list(range(self.n + 1, self.n + 1 + k))
        self.n += k
        return out


def _f(x: float) -> str:
    return repr(float(x)).upper().replace("E+", "E")


def _pt(w: _Writer, p) -> int:
    return w.add(f"CARTESIAN_POINT('',({','.join(_f(c) for c in p)}))")


def _dir(w: _Writer, d) -> int:
    return w.add(f"DIRECTION('',({','.join(_f(c) for c in d)}))")


def _shell(w: _Writer, V: np.ndarray, faces: list[list[int]]) -> int:
    vp = [w.add(f"VERTEX_POINT('',#{_pt(w, p)})") for p in V]
    edges: dict[tuple[int, int], int] = {}
    face_ids = []
    for loop in faces:
        oes = []
        for a, b in zip(loop, loop[1:] + loop[:1]):
            key = (min(a, b), max(a, b))
            if key not in edges:
                p, q = V[key[0]], V[key[1]]
                d = q - p
                L = float(np.linalg.norm(d))
                vec = w.add(f"VECTOR('',#{_dir(w, d / L)},{_f(L)})")
                line = w.add(f"LINE('',#{_pt(w, p)},#{vec})")
                edges[key] = w.add(f"EDGE_CURVE('',#{vp[key[0]]},#{vp[key[1]]},#{line},.T.)")
            oes.append(w.add(f"ORIENTED_EDGE('',*,*,#{edges[key]},{'.T.' if a < b else '.F.'})"))
        P = V[loop]
        n = np.cross(P, np.roll(P, -1, axis=0)).sum(axis=0)
        n /= np.linalg.norm(n)
        x = P[1] - P[0]
        x /= np.linalg.norm(x)
        ax = w.add(f"AXIS2_PLACEMENT_3D('',#{_pt(w, P[0])},#{_dir(w, n)},#{_dir(w, x)})")
        plane = w.add(f"PLANE('',#{ax})")
        el = w.add(f"EDGE_LOOP('',({','.join(f'#{o}' for o in oes)}))")
        bound = w.add(f"FACE_OUTER_BOUND('',#{el},.T.)")
        face_ids.append(w.add(f"ADVANCED_FACE('',(#{bound}),#{plane},.T.)"))
    return w.add(f"CLOSED_SHELL('',({','.join(f'#{f}' for f in face_ids)}))")


def box_mesh(lo, hi) -> tuple[np.ndarray, list[list[int]]]:
    """Vertices and outward counter-clockwise quads of an axis-aligned box."""
    (x0, y0, z0), (x1, y1, z1) = lo, hi
    V = np.array([[x0, y0, z0], [x1, y0, z0], [x1, y1, z0], [x0, y1, z0],
                  [x0, y0, z1], [x1, y0, z1], [x1, y1, z1], [x0, y1, z1]], dtype=float)
    F = [[0, 3, 2, 1], [4, 5, 6, 7], [0, 1, 5, 4], [1, 2, 6, 5], [2, 3, 7, 6], [3, 0, 4, 7]]
    return V, F


def polyhedron_step(V, faces, unit: str = "mm", voids=(), header_schema: str = "AUTOMOTIVE_DESIGN") -> str:
    """STEP text of a closed polyhedron (planar faces, straight edges), optionally with voids.

    Parameters
    ----------
    V : (n, 3) vertices, in ``unit``
    faces : list of vertex index loops, counter-clockwise seen from outside
    unit : "mm", "m" or "inch"
    voids : sequence of (V, faces) for inner shells (given outward; written as ORIENTED_CLOSED_SHELL .F.)
    """
    w = _Writer()
    outer = _shell(w, np.asarray(V, float), faces)
    if voids:
        inner = [_shell(w, np.asarray(v, float), f) for v, f in voids]
        oriented = [w.add(f"ORIENTED_CLOSED_SHELL('',*,#{s},.F.)") for s in inner]
        solid = w.add(f"BREP_WITH_VOIDS('',#{outer},({','.join(f'#{o}' for o in oriented)}))")
    else:
        solid = w.add(f"MANIFOLD_SOLID_BREP('',#{outer})")
    u, m, k, d = w.ids(4)
    w.lines.append(_UNITS[unit].format(u=u, m=m, k=k, d=d))
    rad, sr, unc = w.ids(3)
    w.lines.append(f"#{rad}=( NAMED_UNIT(*) PLANE_ANGLE_UNIT() SI_UNIT($,.RADIAN.) );")
    w.lines.append(f"#{sr}=( NAMED_UNIT(*) SI_UNIT($,.STERADIAN.) SOLID_ANGLE_UNIT() );")
    w.lines.append(f"#{unc}=UNCERTAINTY_MEASURE_WITH_UNIT(LENGTH_MEASURE(1.E-07),#{u},'distance_accuracy_value','');")
    ctx = w.add(f"( GEOMETRIC_REPRESENTATION_CONTEXT(3) GLOBAL_UNCERTAINTY_ASSIGNED_CONTEXT((#{unc})) "
                f"GLOBAL_UNIT_ASSIGNED_CONTEXT((#{u},#{rad},#{sr})) REPRESENTATION_CONTEXT('',''))")
    w.add(f"ADVANCED_BREP_SHAPE_REPRESENTATION('',(#{solid}),#{ctx})")
    body = "\n".join(w.lines)
    return (
        "ISO-10303-21;\nHEADER;\nFILE_DESCRIPTION(('hand-written test file'),'2;1');\n"
        "FILE_NAME('sample.step','2026-01-01T00:00:00',(''),(''),'','','');\n"
        f"FILE_SCHEMA(('{header_schema}'));\nENDSEC;\nDATA;\n{body}\nENDSEC;\nEND-ISO-10303-21;\n"
    )
