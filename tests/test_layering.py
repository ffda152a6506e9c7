"""The layering rule (docs/architecture.md, "Layout and layering"), checked two ways.

* statically, by import-linter's contracts in pyproject.toml (``lint-imports``): the
  core imports neither methods nor metrics, methods import the core and the metric
  leaves only, plug-ins are independent, no import circles;
* dynamically: a simplification process that imports and runs a view-based method
  never loads pyrender or OpenGL (the renderer lives behind the protocol).
"""

from __future__ import annotations

import shutil
import subprocess
import sys
import textwrap
import tomllib
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]

_PROBE = textwrap.dedent("""
    import sys
    import numpy as np
    import trimesh
    from bench.core.mesh import Mesh
    from methods.entropy_twin import EntropyTwin
    from methods.image_driven import ImageDriven
    ico = trimesh.creation.icosphere(2)
    mesh = Mesh(ico.vertices, ico.faces.astype(np.int32), name="ball")
    method = {method}
    result = method.simplify(mesh, 120)
    loaded = sorted(m for m in sys.modules if m.split(".")[0] in ("pyrender", "OpenGL")
                    or m.startswith("metrics.") and m not in ("metrics.views", "metrics.shading"))
    print(result.mesh.n_faces, *loaded)
""")


@pytest.mark.parametrize("method", [
    "ImageDriven(resolution=32, presimplify_faces=240)",
    "EntropyTwin(resolution=32)",
])
def test_simplifying_never_loads_the_renderer(method):
    proc = subprocess.run([sys.executable, "-c", _PROBE.format(method=method)],
                          capture_output=True, text=True, cwd=ROOT, timeout=600)
    assert proc.returncode == 0, proc.stderr[-2000:]
    faces, *loaded = proc.stdout.split()
    assert abs(int(faces) - 120) <= 2
    assert loaded == [], f"a simplification process loaded {loaded}"


@pytest.mark.skipif(shutil.which("lint-imports", path=str(Path(sys.executable).parent)) is None,
                    reason="import-linter is not installed (pip install -e '.[test]')")
def test_import_contracts_are_kept():
    exe = str(Path(sys.executable).parent / "lint-imports")
    proc = subprocess.run([exe, "--no-cache"], capture_output=True, text=True, cwd=ROOT,
                          timeout=300)
    assert proc.returncode == 0, proc.stdout[-4000:]
    assert "0 broken" in proc.stdout


def test_the_independence_contract_names_every_method_plugin_module():
    """The plug-in independence contract lists modules by name; this keeps the list whole:
    every module directly under methods/ (the plug-ins; the machinery is in subpackages)
    is in it, and so is every module the ``bench.methods`` entry points name."""
    config = tomllib.loads((ROOT / "pyproject.toml").read_text())
    contracts = config["tool"]["importlinter"]["contracts"]
    listed = {m for c in contracts if c["type"] == "independence" for m in c["modules"]}
    on_disk = {f"methods.{p.stem}" for p in (ROOT / "methods").glob("*.py")
               if p.stem != "__init__"}
    registered = {value.split(":")[0]
                  for value in config["project"]["entry-points"]["bench.methods"].values()}
    assert listed == on_disk
    assert registered <= listed


def _functions():
    """Every function of the suite's packages: (path, name, lines, parameters, numba)."""
    import ast

    for package in ("bench", "methods", "metrics"):
        for path in sorted((ROOT / package).rglob("*.py")):
            for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
                if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                    a = node.args
                    count = (len(a.posonlyargs) + len(a.args) + len(a.kwonlyargs)
                             + (a.vararg is not None) + (a.kwarg is not None))
                    numba = any("jit" in ast.unparse(d) for d in node.decorator_list)
                    yield (f"{path.relative_to(ROOT)}::{node.name}",
                           node.end_lineno - node.lineno + 1, count, numba)


def test_kernels_take_at_most_eight_parameters():
    """docs/maintainers.md, "State in the numba kernels": a kernel takes named
    structures, or plain tuples named for what they hold, not loose arrays."""
    wide = [(name, count) for name, _, count, numba in _functions() if numba and count > 8]
    assert wide == []


def test_functions_stay_short():
    """None over 100 lines and at most three over 60, docstrings included."""
    lengths = [(name, lines) for name, lines, _, _ in _functions()]
    assert [x for x in lengths if x[1] > 100] == []
    assert len([x for x in lengths if x[1] > 60]) <= 3, [x for x in lengths if x[1] > 60]
