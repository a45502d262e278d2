"""The layer rule: kernel -> topology -> booleans -> io, validation; the core never imports the reference engines.

import-linter checks the same contracts in `make test` (pyproject.toml); this test reads every module's
source with ``ast`` so lazy imports inside functions are caught too, and checks that ``import coons``
stays light.
"""

from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1] / "coons"
ENGINES = {"OCP", "build123d", "manifold3d", "trimesh"}
LAYERS = ["kernel", "topology", "booleans", "io", "validation", "cli"]
CORE = {"kernel", "topology", "booleans"}


def imported_modules(path: Path) -> list[tuple[int, str]]:
    tree = ast.parse(path.read_text(), filename=str(path))
    found = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            found += [(node.lineno, alias.name) for alias in node.names]
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            found.append((node.lineno, node.module))
    return found


def layer_of(path: Path) -> str | None:
    rel = path.relative_to(ROOT).parts
    name = rel[0].removesuffix(".py")
    return name if name in LAYERS else None


MODULES = sorted(ROOT.rglob("*.py"))


@pytest.mark.parametrize("path", MODULES, ids=lambda p: str(p.relative_to(ROOT)))
def test_module_respects_layers(path):
    layer = layer_of(path)
    if layer is None:
        return  # coons/__init__.py, errors.py, tolerance.py: checked by import-linter
    rank = LAYERS.index(layer)
    for line, module in imported_modules(path):
        top = module.split(".")[0]
        if layer in CORE:
            assert top not in ENGINES, f"{path}:{line} core module imports reference engine {module}"
        if module.startswith("coons."):
            other = module.split(".")[1]
            if other in LAYERS:
                assert LAYERS.index(other) <= rank or {layer, other} == {"io", "validation"} and layer == "validation", (
                    f"{path}:{line}: layer {layer!r} must not import the higher layer {other!r}"
                )


def test_import_coons_loads_no_reference_engine():
    code = "import sys, coons, coons.kernel; print(sorted(m for m in sys.modules if m.split('.')[0] in %r))" % (ENGINES,)
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]", out.stdout
