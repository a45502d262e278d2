"""Tests of coons.validation.report: pictures, the HTML page, the table and the exit status."""

from __future__ import annotations

import io

import matplotlib.image as mpimg
import numpy as np

import coons
from coons.validation.report import exit_status, format_table, render_mesh_png, write_html


def decode(png: bytes) -> np.ndarray:
    return mpimg.imread(io.BytesIO(png), format="png")


def assert_picture(img: np.ndarray) -> None:
    assert img.ndim == 3 and img.shape[0] > 100 and img.shape[1] > 100
    assert img[..., :3].std() > 0.05  # not a blank image
    assert len(np.unique(img[..., :3].reshape(-1, 3).round(2), axis=0)) > 20  # shading, not flat colours


def synthetic(name: str, kind: str, images: dict | None = None, coons_bug: bool = False) -> dict:
    eng = {"status": "ok", "error": None, "volume": 1000.0, "area": 600.0, "bbox": [[-5, -5, -5], [5, 5, 5]],
           "counts": {"vertices": 8, "edges": 12, "faces": 6, "inner_loops": 0, "shells": 1, "solids": 1},
           "euler": 2, "valid": True, "validity": "valid", "seconds": 0.01}
    return {"name": name, "description": f"the {name} case", "recipe": "Box(10, 10, 10)", "tags": ["planar"],
            "expect_volume": 1000.0,
            "verdict": {"kind": kind, "reasons": [] if kind == "agree" else [f"{kind} because"],
                        "measures": [{"name": "volume", "reference": "occt", "coons": 1.0, "other": 2.0,
                                      "deviation": 1.0, "tolerance": 1e-6, "ok": kind == "agree"}],
                        "failed_references": {}, "coons_bug": coons_bug},
            "engines": {"coons": eng, "occt": {**eng, "counts": {**eng["counts"], "seam_edges": 0,
                                                                 "degenerate_edges": 0}}},
            "hausdorff": 1e-9, "deflection": 0.017, "seconds": 0.5, "images": images or {}}


def test_render_shaded_and_coloured_pictures():
    m = coons.tessellate(coons.Torus(4, 1.5), deflection=0.05)
    mesh = (m.vertices, m.triangles)
    assert_picture(decode(render_mesh_png(mesh, title="torus")))
    d = np.abs(m.vertices[:, 2])  # any per-vertex field
    assert_picture(decode(render_mesh_png(mesh, values=d, title="deviation")))


def test_html_report_with_pictures(tmp_path):
    m = coons.tessellate(coons.Box(10, 10, 10) - coons.Pos(5, 5, 5) * coons.Box(10, 10, 10))
    png = render_mesh_png((m.vertices, m.triangles), title="cut box")
    res = [synthetic("cut_box", "disagree", {"coons": png, "deviation": png}),
           synthetic("plain", "agree"), synthetic("refused", "coons-raised")]
    index = write_html(res, tmp_path / "rep", seconds=3.0, options={"jobs": 2})
    text = index.read_text()
    assert text.startswith("<!DOCTYPE html>") and text.rstrip().endswith("</html>")
    for name in ("cut_box", "plain", "refused", "disagree because", "coons-raised because", "χ = V − E + F − R"):
        assert name in text
    assert "<script" not in text and "http" not in text  # self-contained
    assert "src='cut_box.png'" in text and "src='cut_box-deviation.png'" in text
    for f in ("cut_box.png", "cut_box-deviation.png"):
        assert_picture(mpimg.imread(tmp_path / "rep" / f))
    assert sorted(p.name for p in (tmp_path / "rep").iterdir()) == ["cut_box-deviation.png", "cut_box.png",
                                                                    "index.html"]


def test_table_and_exit_status():
    res = [synthetic("a", "agree"), synthetic("b", "coons-raised"), synthetic("c", "reference-failed")]
    table = format_table(res, seconds=2.0)
    assert table.splitlines()[-1] == "3 cases: 1 agree, 1 coons-raised, 1 reference-failed in 2.0 s"
    assert "b" in table and "coons-raised because" in table
    assert exit_status(res) == 0
    assert exit_status(res + [synthetic("d", "disagree")]) == 1
    assert exit_status(res + [synthetic("e", "coons-raised", coons_bug=True)]) == 1  # an untyped exception
    assert exit_status(res + [synthetic("f", "timeout", coons_bug=False)]) == 0  # a reference engine hung
