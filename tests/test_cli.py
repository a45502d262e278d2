"""End-to-end tests of the ``coons`` command line: validate, convert, info, errors and exit codes."""

from __future__ import annotations

import subprocess
import sys
import types
from pathlib import Path

import matplotlib.image as mpimg
import numpy as np
import pytest

import coons
from coons.cli import main

DATA = Path(__file__).parent / "data"
CUBE_STL = DATA / "trimesh-20mm-xyz-cube.stl"


def one_error_line(err: str) -> str:
    lines = [line for line in err.splitlines() if line.strip()]
    assert len(lines) == 1, err
    assert lines[0].startswith("coons: error: ")
    return lines[0]


@pytest.mark.occt
@pytest.mark.manifold
def test_validate_writes_a_report_and_exits_0(tmp_path, capsys):
    rep = tmp_path / "report"
    code = main(["validate", "box_box_coplanar_*", "cylinder", "--jobs", "2", "--report", str(rep),
                 "--json", str(tmp_path / "r.json"), "--timeout", "120"])
    out = capsys.readouterr().out
    assert code == 0, out
    assert "4 cases: 4 agree" in out
    for name in ("box_box_coplanar_union", "box_box_coplanar_difference", "box_box_coplanar_intersection",
                 "cylinder"):
        assert name in out
        img = mpimg.imread(rep / f"{name}.png")
        assert img.shape[0] > 100 and img[..., :3].std() > 0.05  # a real picture
    assert "cylinder" in (rep / "index.html").read_text()
    import json

    data = json.loads((tmp_path / "r.json").read_text())
    assert [d["verdict"]["kind"] for d in data] == ["agree"] * 4
    cyl = next(d for d in data if d["name"] == "cylinder")["engines"]
    assert cyl["coons"]["counts"]["faces"] == 4 and cyl["occt"]["counts"]["faces"] == 3  # split vs seam
    assert cyl["coons"]["euler"] == cyl["occt"]["euler"] == 2


def test_validate_list_and_unknown_case(capsys):
    assert main(["validate", "--list", "mesh_*"]) == 0
    out = capsys.readouterr().out.splitlines()
    assert len(out) >= 6 and all(line.startswith("mesh_") for line in out)
    assert main(["validate", "no_such_case"]) == 2
    assert "no case matches 'no_such_case'" in one_error_line(capsys.readouterr().err)


@pytest.mark.parametrize("argv", [["validate", "--jobs", "0"], ["validate", "--timeout", "-1"],
                                  ["validate", "--timeout", "soon"], ["frobnicate"]])
def test_bad_arguments_exit_2(argv, capsys):
    with pytest.raises(SystemExit) as exc:
        main(argv)
    assert exc.value.code == 2
    assert "--help" in one_error_line(capsys.readouterr().err)


def test_validate_exits_1_when_coons_is_wrong(monkeypatch, capsys):
    import coons.validation.runner as runner

    def fake_run_cases(cases, **kwargs):
        return [{"name": c.name, "verdict": {"kind": "disagree", "reasons": ["volume: coons 1 vs occt 2"],
                                             "measures": [], "failed_references": {}, "coons_bug": False},
                 "engines": {}, "hausdorff": None, "seconds": 0.0} for c in cases]

    monkeypatch.setattr(runner, "run_cases", fake_run_cases)
    assert main(["validate", "box"]) == 1
    assert "1 cases: 1 disagree" in capsys.readouterr().out


@pytest.mark.slow
def test_validate_subprocess_exit_code(tmp_path):
    """The installed entry point, in a fresh interpreter, on a case coons refuses (not a failure)."""
    proc = subprocess.run([sys.executable, "-m", "coons.cli", "validate", "box_box_vertex_union", "--jobs", "1"],
                          capture_output=True, text=True, timeout=300, cwd=tmp_path)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert "coons-raised" in proc.stdout and "not a manifold" in proc.stdout


def test_info_on_stl(capsys):
    assert main(["info", str(CUBE_STL)]) == 0
    out = capsys.readouterr().out
    assert "1 solid" in out and "volume 7938.68187633" in out and "faces 74" in out and "valid: True" in out


def test_convert_stl_to_stl_and_step(tmp_path, capsys):
    out_stl = tmp_path / "cube.stl"
    assert main(["convert", str(CUBE_STL), str(out_stl)]) == 0
    V, T = coons.import_stl(out_stl)
    np.testing.assert_allclose(coons.from_mesh(V, T).volume, 7938.681876, rtol=1e-6)  # float32 STL
    out_step = tmp_path / "cube.step"
    assert main(["convert", str(CUBE_STL), str(out_step)]) == 0
    assert out_step.read_text().startswith("ISO-10303-21;")
    capsys.readouterr()
    assert main(["info", str(out_step)]) == 0
    assert "volume 7938.68187633" in capsys.readouterr().out


def test_convert_and_info_errors(tmp_path, capsys):
    assert main(["info", str(tmp_path / "missing.step")]) == 2
    assert "missing.step: no such file" in one_error_line(capsys.readouterr().err)
    bad = tmp_path / "x.obj"
    bad.write_text("v 0 0 0\n")
    assert main(["info", str(bad)]) == 2
    assert "unknown file type '.obj'" in one_error_line(capsys.readouterr().err)
    assert main(["convert", str(CUBE_STL), str(tmp_path / "out.iges")]) == 2
    assert "unknown output type '.iges'" in one_error_line(capsys.readouterr().err)
    broken = tmp_path / "broken.stl"
    broken.write_text("solid x\n facet normal 0 0 1\n")
    assert main(["info", str(broken)]) == 2
    one_error_line(capsys.readouterr().err)


def test_convert_many_solids_to_step_is_refused(tmp_path, monkeypatch, capsys):
    fake = types.ModuleType("coons.io.step.reader")
    fake.import_step = lambda path: [coons.Box(1, 1, 1), coons.Pos(5, 0, 0) * coons.Box(1, 1, 1)]
    monkeypatch.setitem(sys.modules, "coons.io.step.reader", fake)
    src = tmp_path / "two.step"
    src.write_text("ISO-10303-21;")
    assert main(["convert", str(src), str(tmp_path / "out.step")]) == 2
    assert "holds 2 solids; STEP output takes exactly 1" in one_error_line(capsys.readouterr().err)
    assert main(["convert", str(src), str(tmp_path / "out.stl")]) == 0  # STL takes both
    V, T = coons.import_stl(tmp_path / "out.stl")
    np.testing.assert_allclose(coons.from_mesh(V, T).volume, 2.0, rtol=1e-6)
    assert main(["info", str(src)]) == 0
    assert "2 solids" in capsys.readouterr().out
