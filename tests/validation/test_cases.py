"""Tests of the reference catalogue (coons.validation.cases) and of the generated mesh inputs."""

from __future__ import annotations

import math

import numpy as np
import pytest

import coons
from coons.errors import BooleanError, InvalidInputError
from coons.validation.cases import CATALOGUE, MESHES, Case, is_curved, recipe_text, select_cases, validate_recipe
from coons.validation.engines import coons_solid, mesh_input


def test_catalogue_size_names_and_coverage():
    assert len(CATALOGUE) >= 60
    names = [c.name for c in CATALOGUE]
    assert len(set(names)) == len(names)
    assert all(n.replace("_", "").isalnum() and n == n.lower() for n in names)
    tags = {t for c in CATALOGUE for t in c.tags}
    assert tags >= {"primitive", "planar", "curved", "generic", "coplanar", "touching", "tangent", "nested",
                    "disjoint", "identical", "empty", "mesh"}
    kinds = {c.recipe[0] for c in CATALOGUE}
    assert kinds >= {"union", "difference", "intersection", "box", "pos", "rot", "mesh"}
    assert sum(c.expect_volume is not None for c in CATALOGUE) >= 40


def test_select_cases_by_name_and_glob():
    assert [c.name for c in select_cases(["box"])] == ["box"]
    sel = select_cases(["box_box_generic_*", "box"])
    assert [c.name for c in sel] == ["box", "box_box_generic_union", "box_box_generic_difference",
                                     "box_box_generic_intersection"]  # catalogue order, each once
    assert select_cases() == list(CATALOGUE)
    with pytest.raises(InvalidInputError, match="no case matches 'nope_\\*'"):
        select_cases(["box", "nope_*"])


@pytest.mark.parametrize("recipe, message", [
    (("cube", 1), "unknown recipe node 'cube'"),
    (("box", 1, 2), "box takes 3 arguments, got 2"),
    (("mesh", "teapot"), "unknown mesh 'teapot'"),
    (("pos", (1, 2), ("box", 1, 1, 1)), r"pos takes \(\(x, y, z\), node\)"),
    (("union", ("box", 1, 1, 1)), "union takes 2 operands, got 1"),
    ("box", "expected a recipe node"),
])
def test_invalid_recipes(recipe, message):
    with pytest.raises(InvalidInputError, match=message):
        validate_recipe(recipe)
    with pytest.raises(InvalidInputError, match=message):
        Case("bad", recipe, "")


def test_recipe_text_and_curvature():
    r = ("difference", ("box", 10, 10, 10), ("pos", (5, 0, 0), ("cylinder", 3, 12)))
    assert recipe_text(r) == "Box(10, 10, 10) - Pos(5, 0, 0) * Cylinder(3, 12)"
    assert is_curved(r) and not is_curved(("union", ("box", 1, 1, 1), ("mesh", "ring")))


@pytest.mark.parametrize("name, volume", [("octahedron", 4 / 3 * 6**3), ("ring", (144 - 36) * 4),
                                          ("xyz_cube", None), ("icosphere", None)])
def test_mesh_inputs_are_closed_valid_solids(name, volume):
    V, T = mesh_input(name)
    s = coons.from_mesh(V, T, merge_coplanar=True)
    assert coons.check(s).ok
    if volume is not None:
        np.testing.assert_allclose(s.volume, volume, rtol=1e-14)
    if name == "icosphere":
        assert len(T) == 320
        np.testing.assert_allclose(np.linalg.norm(V, axis=1), 6.0, rtol=1e-14)
        assert 0.95 * 4 / 3 * math.pi * 216 < s.volume < 4 / 3 * math.pi * 216
    if name == "xyz_cube":
        np.testing.assert_allclose(s.volume, 7938.682, rtol=1e-6)  # trimesh's figure (tests/data/README.md)
    assert set(MESHES) == {"xyz_cube", "octahedron", "icosphere", "ring"}
    with pytest.raises(InvalidInputError, match="unknown mesh input 'teapot'"):
        mesh_input("teapot")


def test_planar_closed_forms_hold_in_coons():
    """Every planar case and primitive with a closed form: coons matches it exactly, or refuses with BooleanError."""
    checked = 0
    for case in CATALOGUE:
        if case.expect_volume is None or (is_curved(case.recipe) and "primitive" not in case.tags):
            continue
        try:
            s = coons_solid(case.recipe)
        except BooleanError as exc:
            assert "not a manifold" in str(exc), case.name  # touching along an edge or at a vertex
            continue
        np.testing.assert_allclose(s.volume, case.expect_volume, rtol=1e-12, atol=1e-9, err_msg=case.name)
        checked += 1
    assert checked >= 33
