"""The report's scripts and style sheet are files of the package (bench/report/assets/):
each script parses (``node --check``, the JavaScript engine the project already needs for
meshoptimizer), each is installed as package data, and the pages inline them as they are."""

import fnmatch
import shutil
import subprocess
import tomllib
from pathlib import Path

import pytest

from bench.report import asset, script

ROOT = Path(__file__).parent.parent
ASSETS = ROOT / "bench" / "report" / "assets"
SCRIPTS = sorted(p.name for p in ASSETS.glob("*.js"))


def test_the_assets_are_there():
    assert {"errors.js", "table.js", "grid.js", "viewer.js"} <= set(SCRIPTS)
    assert (ASSETS / "report.css").is_file()


@pytest.mark.skipif(shutil.which("node") is None, reason="node is not installed")
@pytest.mark.parametrize("name", SCRIPTS)
def test_each_script_parses(name):
    done = subprocess.run(["node", "--check", str(ASSETS / name)], capture_output=True, check=False,
                          text=True, timeout=60)
    assert done.returncode == 0, done.stderr


@pytest.mark.skipif(shutil.which("node") is None, reason="node is not installed")
def test_node_check_finds_a_line_break_inside_a_string(tmp_path):
    # the error catcher's old defect: a "\n" of a Python string became a real line break
    broken = tmp_path / "broken.js"
    broken.write_text('var s = "a\n";\n')
    assert subprocess.run(["node", "--check", str(broken)], capture_output=True,
                          check=False).returncode


def test_every_asset_is_package_data():
    """A non-editable install holds what the pages load: every file of assets/ matches a
    package-data pattern of bench.report."""
    data = tomllib.loads((ROOT / "pyproject.toml").read_text())
    patterns = data["tool"]["setuptools"]["package-data"]["bench.report"]
    for path in ASSETS.iterdir():
        name = path.relative_to(ROOT / "bench" / "report").as_posix()
        assert any(fnmatch.fnmatch(name, p) for p in patterns), name


def test_the_pages_inline_the_files_as_they_are():
    from bench.report.page import ERRORS_SCRIPT, html_page

    assert asset("errors.js") in ERRORS_SCRIPT
    assert '"\\n"' in asset("errors.js")  # the two characters, not a line break
    page = html_page("t", ["<p>x</p>"])
    assert asset("report.css") in page
    assert page.index(ERRORS_SCRIPT) < page.index("<body>")
    assert script("table.js") in page and script("grid.js") in page
