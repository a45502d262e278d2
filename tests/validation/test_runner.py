"""Tests of coons.validation.runner: one case in-process, cases in their own processes, timeouts, crashes, Dask."""

from __future__ import annotations

import io
import time

import pytest

from coons.errors import InvalidInputError
from coons.validation.cases import select_cases
from coons.validation.runner import Progress, RunOptions, recipe_scale, run_case, run_cases
from tests.validation import helpers

FAST = RunOptions(samples=2000)


@pytest.mark.occt
@pytest.mark.manifold
def test_run_case_in_process_agrees_with_both_references():
    (case,) = select_cases(["box_box_generic_intersection"])
    stages = []
    r = run_case(case, FAST, stages.append)
    assert stages == ["coons", "occt", "manifold", "compare"]
    assert r["verdict"]["kind"] == "agree", r["verdict"]["reasons"]
    e = r["engines"]
    assert e["coons"]["volume"] == pytest.approx(6.7 * 7.3 * 8.1, rel=1e-12)
    assert e["occt"]["volume"] == pytest.approx(e["coons"]["volume"], rel=1e-9)
    assert e["occt"]["counts"]["faces"] == e["coons"]["counts"]["faces"] == 6
    assert r["hausdorff"] < 1e-6
    assert r["deflection"] == pytest.approx(1e-3 * recipe_scale(case.recipe))
    assert r["images"] == {}


@pytest.mark.occt
def test_run_case_records_coons_refusal_and_the_references():
    (case,) = select_cases(["box_box_edge_union"])
    r = run_case(case, RunOptions(samples=2000, engines=("occt",)))
    assert r["verdict"]["kind"] == "coons-raised" and not r["verdict"]["coons_bug"]
    assert r["engines"]["coons"]["error"].startswith("BooleanError: [sew] the result is not a manifold")
    assert set(r["engines"]) == {"coons", "occt"}
    occt = r["engines"]["occt"]
    assert occt["volume"] == pytest.approx(2000.0, rel=1e-12)
    # OCCT keeps the two cubes as two solids sharing one edge: V 14, E 23, F 12 (a non-manifold chi of 3)
    assert (occt["counts"]["vertices"], occt["counts"]["edges"], occt["counts"]["faces"]) == (14, 23, 12)
    assert occt["counts"]["solids"] == 2 and occt["euler"] == 3


@pytest.mark.occt
def test_run_case_counts_seams_on_a_round_hole():
    (case,) = select_cases(["box_minus_cylinder"])
    r = run_case(case, RunOptions(samples=2000, engines=("occt",)))
    assert r["verdict"]["kind"] in ("agree", "coons-raised"), r["verdict"]["reasons"]  # curved Booleans are new
    occt = r["engines"]["occt"]
    assert occt["volume"] == pytest.approx(case.expect_volume, rel=1e-9)
    assert occt["counts"]["seam_edges"] == 1 and occt["counts"]["inner_loops"] == 2
    assert occt["euler"] == 0  # genus 1: 10 - 15 + 7 - 2


def test_recipe_scale_is_the_diagonal_of_the_placed_leaves():
    r = ("union", ("box", 2, 2, 2), ("pos", (10, 0, 0), ("rot", (0, 0, 45), ("box", 2, 2, 2))))
    # x from -1 to 10 + sqrt(2), y and z from -sqrt(2) / -1 to sqrt(2) / 1
    s2 = 2**0.5
    assert recipe_scale(r) == pytest.approx(((11 + s2) ** 2 + (2 * s2) ** 2 + 2**2) ** 0.5, rel=1e-12)


@pytest.mark.occt
@pytest.mark.manifold
def test_local_processes_keep_the_order_and_draw_progress():
    cases = select_cases(["box", "box_box_identical_difference", "mesh_octahedron"])
    stream = io.StringIO()
    res = run_cases(cases, options=FAST, jobs=2, timeout=120, progress=Progress(len(cases), stream, enabled=True))
    assert [r["name"] for r in res] == [c.name for c in cases]
    assert [r["verdict"]["kind"] for r in res] == ["agree"] * 3
    empty = next(r for r in res if r["name"] == "box_box_identical_difference")
    assert empty["engines"]["coons"]["empty"] and empty["engines"]["occt"]["empty"]
    out = stream.getvalue()
    assert "3/3" in out and "[" + "#" * 30 + "]" in out and out.endswith("\n")
    assert Progress(3, io.StringIO()).enabled is False  # not a terminal: no bar


def test_a_hanging_case_is_killed_and_recorded():
    cases = select_cases(["box", "sphere"])
    t0 = time.monotonic()
    res = run_cases(cases, jobs=2, timeout=1.5, target=helpers.sleepy, progress=Progress(2, io.StringIO()))
    assert time.monotonic() - t0 < 30
    for r in res:
        v = r["verdict"]
        assert v["kind"] == "timeout" and v["coons_bug"]  # it hung while coons was running
        assert v["reasons"] == ["no result after 1.5 s (killed while running coons)"]


def test_a_crashing_case_is_recorded_and_does_not_stop_the_run():
    res = run_cases(select_cases(["box"]), jobs=1, timeout=60, target=helpers.crashing,
                    progress=Progress(1, io.StringIO()))
    v = res[0]["verdict"]
    assert v["kind"] == "crashed" and not v["coons_bug"]  # OCCT's stage: a reference crash
    assert "exit code -9" in v["reasons"][0] and "while running occt" in v["reasons"][0]
    res = run_cases(select_cases(["box"]), jobs=1, timeout=60, target=helpers.raising,
                    progress=Progress(1, io.StringIO()))
    assert res[0]["verdict"]["kind"] == "crashed"
    assert "the harness failed while running None: RuntimeError: harness bug" in res[0]["verdict"]["reasons"][0]


@pytest.mark.parametrize("kwargs, message", [
    ({"jobs": 0}, "jobs must be an integer >= 1, got 0"),
    ({"timeout": 0}, "timeout must be a finite number of seconds > 0, got 0"),
    ({"timeout": float("inf")}, "timeout must be"),
])
def test_run_cases_errors(kwargs, message):
    with pytest.raises(InvalidInputError, match=message):
        run_cases(select_cases(["box"]), **kwargs)


def test_run_options_errors():
    with pytest.raises(InvalidInputError, match="relative_deflection must be in"):
        RunOptions(relative_deflection=0)
    with pytest.raises(InvalidInputError, match=r"unknown reference engines \['acis'\]"):
        RunOptions(engines=("acis",))


@pytest.mark.occt
@pytest.mark.manifold
def test_dask_local_cluster():
    from distributed import LocalCluster

    cases = select_cases(["box", "box_box_face_intersection", "box_box_vertex_union"])
    # manifold3d only: the workers need not import build123d (3.5 s each on this machine)
    options = RunOptions(samples=2000, engines=("manifold",))
    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, host="127.0.0.1",
                      dashboard_address=None) as cluster:
        res = run_cases(cases, options=options, timeout=120, scheduler=cluster.scheduler_address,
                        progress=Progress(3, io.StringIO()))
    assert [r["name"] for r in res] == [c.name for c in cases]
    assert [r["verdict"]["kind"] for r in res] == ["agree", "reference-failed", "coons-raised"]
    # manifold3d leaves a zero-volume sheet (a double-sided 10 x 10 square) where two cubes touch in a face
    assert res[1]["engines"]["manifold"]["area"] == pytest.approx(200.0)
    assert res[1]["engines"]["coons"]["empty"] and not res[1]["engines"]["manifold"]["empty"]
    assert "zero-volume sheet" in res[1]["verdict"]["failed_references"]["manifold"]


@pytest.mark.slow
def test_unreachable_scheduler():
    with pytest.raises(InvalidInputError, match="cannot reach the Dask scheduler at 'tcp://127.0.0.1:9'"):
        run_cases(select_cases(["box"]), scheduler="tcp://127.0.0.1:9", progress=Progress(1, io.StringIO()))


@pytest.mark.occt
@pytest.mark.manifold
def test_a_wrong_coons_result_is_caught_and_mapped(monkeypatch):
    """A coons answer 0.1 mm too tall: both references and the closed form catch it, and the deviation is drawn."""
    import coons
    import coons.validation.engines as engines

    monkeypatch.setattr(engines, "coons_solid", lambda recipe: coons.Box(10, 10, 10.1))
    (case,) = select_cases(["box"])
    r = run_case(case, RunOptions(samples=2000, render=True))
    v = r["verdict"]
    assert v["kind"] == "disagree" and v["reasons"][0].startswith("volume: coons 1010")
    bad = {(m["name"], m["reference"]) for m in v["measures"] if not m["ok"]}
    assert {("volume", "closed form"), ("volume", "occt"), ("volume", "manifold"), ("area", "occt"),
            ("bbox", "occt")} <= bad
    # top and bottom faces 0.05 off: below the Hausdorff tolerance (4 deflections = 0.069), a coarse check
    assert r["hausdorff"] == pytest.approx(0.05, rel=1e-9) and ("hausdorff", "occt") not in bad
    import matplotlib.image as mpimg

    for key in ("coons", "deviation"):
        img = mpimg.imread(io.BytesIO(r["images"][key]), format="png")
        assert img[..., :3].std() > 0.05
