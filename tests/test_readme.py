"""The README's example runs as written, and the demo command produces its files."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]


def test_readme_example_runs(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)  # the example writes part.step and lens.stl to the working directory
    text = (ROOT / "README.md").read_text()
    blocks = re.findall(r"```python\n(.*?)```", text, re.S)
    assert blocks, "README has no python example"
    for block in blocks:
        namespace: dict = {}
        exec(compile(block, "README.md", "exec"), namespace)  # noqa: S102 - our own documentation
    # The example's quarter circle is exact.
    pts = namespace["pts"]
    np.testing.assert_allclose(np.linalg.norm(pts, axis=1), 2.0, rtol=1e-15)
    # The first example's part is exact: 1000 - 90 pi, and its files were written.
    first: dict = {}
    exec(compile(blocks[0], "README.md", "exec"), first)  # noqa: S102
    np.testing.assert_allclose(first["part"].volume, 1000 - 90 * np.pi, rtol=1e-12)
    assert (tmp_path / "part.step").stat().st_size > 1000 and (tmp_path / "lens.stl").stat().st_size > 1000


def test_demo_writes_a_picture_and_a_watertight_stl(tmp_path):
    import trimesh

    from coons.cli import main

    assert main(["demo", "--out", str(tmp_path)]) == 0
    png = tmp_path / "kernel.png"
    assert png.stat().st_size > 10_000
    mesh = trimesh.load(tmp_path / "torus.stl")
    assert mesh.is_watertight
    np.testing.assert_allclose(mesh.volume, 2 * np.pi**2 * 3.0 * 1.0**2, rtol=2e-2)
    plate = trimesh.load(tmp_path / "plate.stl")
    assert plate.is_watertight and plate.is_winding_consistent
    # Chords inside the holes: the mesh volume is off by at most deflection (0.01) x area.
    np.testing.assert_allclose(plate.volume, (8.0 * 6.0 - 4 * np.pi * 0.8**2) * 1.5, atol=0.01 * plate.area)
