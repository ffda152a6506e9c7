"""The ``bench`` command line, run as a user would: in a subprocess.

Every user error must exit with code 2 and print exactly one line,
``bench: error: <message>``, never a traceback.
"""

from __future__ import annotations

import os
import re
import subprocess
import sys

import numpy as np
import pytest

from bench.core.method import target_tolerance
from bench.io.meshio import load_mesh
from conftest import write

BUILTINS = {
    "methods": ["fast-simplification", "qslim", "qslim-texture"],
    "models": ["bunny", "bunny-textured", "torus"],
    "metrics": ["boundary_edges", "faces", "non_manifold_edges", "render_vertices",
                "welded_vertices"],
}
ENV = {k: v for k, v in os.environ.items() if k != "PYTHONWARNINGS"}


def bench(*args, cwd=None, timeout=120) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "bench", *map(str, args)], cwd=cwd,
                          capture_output=True, text=True, env=ENV, timeout=timeout)


def bench_many(commands: dict, cwd, at_once: int = 4) -> dict[str, subprocess.CompletedProcess]:
    """Run several ``bench`` commands, ``at_once`` at a time (start-up dominates)."""
    done, items = {}, list(commands.items())
    for start in range(0, len(items), at_once):
        procs = {key: subprocess.Popen([sys.executable, "-m", "bench", *map(str, args)],
                                       cwd=cwd, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                                       text=True, env=ENV)
                 for key, args in items[start:start + at_once]}
        for key, proc in procs.items():
            out, err = proc.communicate(timeout=120)
            done[key] = subprocess.CompletedProcess(proc.args, proc.returncode, out, err)
    return done


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    """Small input files, written once for the module."""
    d = tmp_path_factory.mktemp("cli")
    tri = "v 0 0 0\nv 1 0 0\nv 0 1 0\n"
    #   3---2
    #   | / |   a square as two triangles (no UVs)
    #   0---1
    write(d / "square.obj", "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3\nf 1 3 4\n")
    write(d / "quad.obj", "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3 4\n")
    write(d / "points.obj", tri)
    write(d / "bad.obj", tri + "f 1 2 7\n")
    write(d / "cloud.xyz", "0 0 0\n")
    (d / "outdir.obj").mkdir()
    return d


def assert_one_line_error(proc, *fragments):
    assert proc.returncode == 2, proc.stderr
    assert "Traceback" not in proc.stderr
    lines = proc.stderr.splitlines()
    assert len(lines) == 1, proc.stderr
    assert lines[0].startswith("bench: error: ")
    for fragment in fragments:
        assert fragment in lines[0]
    assert proc.stdout == ""


ERROR_CASES = {
    "missing file": (["nope.obj", "OUT/o.obj", "-m", "qslim", "-f", "1"],
                     ["nope.obj: no such file"]),
    "unknown format": (["cloud.xyz", "OUT/o.obj", "-m", "qslim", "-f", "1"],
                       ["cloud.xyz: unknown mesh format '.xyz'", "supported: .obj"]),
    "no faces": (["points.obj", "OUT/o.obj", "-m", "qslim", "-f", "1"],
                 ["points.obj: the mesh has no faces"]),
    "index out of range": (["bad.obj", "OUT/o.obj", "-m", "qslim", "-f", "1"],
                           ["bad.obj: line 4: face index 7 is out of range"]),
    "unknown method": (["square.obj", "OUT/o.obj", "-m", "qslm", "-f", "1"],
                       ["unknown method 'qslm'", "did you mean 'qslim'"]),
    "unknown model": (["bunnyy", "OUT/o.obj", "-m", "qslim", "-f", "1"],
                      ["unknown model 'bunnyy'", "did you mean 'bunny'"]),
    "bad param value": (["square.obj", "OUT/o.obj", "-m", "qslim", "-f", "1",
                         "-p", "qualitythr=abc"],
                        ["parameter 'qualitythr' expects float, got 'abc'"]),
    "bad bool param": (["square.obj", "OUT/o.obj", "-m", "qslim", "-f", "1",
                        "-p", "preserveboundary=maybe"],
                       ["parameter 'preserveboundary' expects true or false, got 'maybe'"]),
    "unknown param key": (["square.obj", "OUT/o.obj", "-m", "qslim", "-f", "1",
                           "-p", "qualitythx=1"],
                          ["unknown parameter 'qualitythx'", "did you mean 'qualitythr'"]),
    "param without value": (["square.obj", "OUT/o.obj", "-m", "qslim", "-f", "1",
                             "-p", "qualitythr"], ["expected key=value"]),
    "output folder missing": (["square.obj", "OUT/nodir/o.obj", "-m", "qslim", "-f", "1"],
                              ["does not exist; create it first"]),
    "unknown output format": (["square.obj", "OUT/o.xyz", "-m", "qslim", "-f", "1"],
                              ["o.xyz: unknown mesh format '.xyz'"]),
    "faces zero": (["square.obj", "OUT/o.obj", "-m", "qslim", "-f", "0"],
                   ["--faces must be at least 1, got 0"]),
    "ratio above one": (["square.obj", "OUT/o.obj", "-m", "qslim", "-r", "1.5"],
                        ["--ratio must be in (0, 1], got 1.5"]),
    "qslim-texture without uv": (["square.obj", "OUT/o.obj", "-m", "qslim-texture", "-f", "1"],
                                 ["square: qslim-texture needs texture coordinates",
                                  "use --method qslim"]),
}


@pytest.fixture(scope="module")
def error_runs(files):
    commands = {case: ["simplify", *(a.replace("OUT", str(files)) for a in args)]
                for case, (args, _) in ERROR_CASES.items()}
    return bench_many(commands, cwd=files)


@pytest.mark.parametrize("case", list(ERROR_CASES))
def test_simplify_errors_are_one_line(files, error_runs, case):
    assert_one_line_error(error_runs[case], *ERROR_CASES[case][1])
    assert not (files / "o.obj").exists()


def test_debug_shows_the_traceback(files):
    proc = bench("--debug", "simplify", "nope.obj", files / "o.obj", "-m", "qslim", "-f", "1",
                 cwd=files)
    assert proc.returncode == 2
    assert "Traceback" in proc.stderr
    assert proc.stderr.splitlines()[-1] == "bench: error: nope.obj: no such file"


def test_warnings_are_one_line_each(files, tmp_path):
    proc = bench("simplify", "quad.obj", tmp_path / "o.obj", "-m", "qslim", "-f", "1", cwd=files)
    assert proc.returncode == 0, proc.stderr
    assert proc.stderr.splitlines() == [
        "bench: warning: quad.obj: triangulated 1 faces with more than 3 corners"]
    assert proc.stdout.startswith("quad: 2 -> 1 faces")
    assert load_mesh(tmp_path / "o.obj").n_faces == 1


def test_unreachable_target_warns_and_notes(files, tmp_path):
    proc = bench("simplify", "square.obj", tmp_path / "o.obj", "-m", "qslim", "-f", "5",
                 cwd=files)
    assert proc.returncode == 0, proc.stderr
    assert proc.stderr.splitlines() == [
        "bench: warning: target of 5 faces is not below the input's 2; returning the input "
        "unchanged",
        "bench: note: stopped short: input already has 2 faces"]
    assert load_mesh(tmp_path / "o.obj").n_faces == 2


def test_gltf_output(files, tmp_path):
    proc = bench("simplify", "square.obj", tmp_path / "o.gltf", "-m", "qslim", "-f", "1",
                 cwd=files)
    assert "Traceback" not in proc.stderr
    assert proc.returncode == 0
    assert load_mesh(tmp_path / "o.gltf").n_faces == 1


def test_output_is_a_directory(files):
    proc = bench("simplify", "square.obj", files / "outdir.obj", "-m", "qslim", "-f", "1",
                 cwd=files)
    assert_one_line_error(proc, "outdir.obj")


# -- bench list -------------------------------------------------------------------------------

def sections(stdout: str) -> dict[str, tuple[int, dict[str, str]]]:
    """kind -> (count in the heading, {name: row}) for `bench list` output. Rows are the
    indented lines under a heading ``kind (count)``; the first is the column header."""
    out, kind = {}, None
    for line in stdout.splitlines():
        match = re.fullmatch(r"(\w+) \((\d+)\)", line)
        if match:
            kind = match[1]
            out[kind] = (int(match[2]), {})
        elif line.startswith("  ") and kind is not None:
            out[kind][1][line.split()[0]] = line
    return out


def check_section(kind: str, count: int, table: dict[str, str]) -> None:
    assert table.pop("name").split()[0] == "name"  # the column header
    assert count == len(table)  # other installed plug-ins may be listed too
    for name in BUILTINS[kind]:
        assert name in table, table
        assert "bench-simplify" in table[name]
        assert "unavailable" not in table[name]


@pytest.mark.parametrize("what", ["methods", "models", "metrics"])
def test_list_one_kind(what):
    proc = bench("list", what, timeout=120)
    assert proc.returncode == 0, proc.stderr
    assert proc.stderr == ""
    found = sections(proc.stdout)
    assert list(found) == [what]
    count, table = found[what]
    check_section(what, count, table)
    if what == "models":
        assert table["bunny"].split()[1:5] == ["56172", "28088", "28088", "no"]
        assert table["bunny-textured"].split()[1:5] == ["9999", "6451", "5051", "yes"]
        assert table["torus"].split()[1:5] == ["65536", "33153", "32768", "yes"]
        assert table["torus-13810"].split()[1] == "13810"
        assert "made by simplification when first used" in table["torus-13810"]


def test_listing_models_does_not_build_the_derived_ones():
    """The pre-decimated models cost an engine run each: a listing names them only."""
    code = ("import sys; from bench.commands.cli import main; main(['list', 'models']); "
            "sys.stdout.flush(); print('ENGINE' if 'methods.engine.simplify' in sys.modules "
            "else 'NO-ENGINE')")
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          timeout=120)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.strip().splitlines()[-1] == "NO-ENGINE"


def test_list_all():
    proc = bench("list", timeout=120)
    assert proc.returncode == 0, proc.stderr
    assert proc.stderr == ""
    found = sections(proc.stdout)
    assert list(found) == ["methods", "models", "metrics", "suites", "claims"]
    suites, claims = found.pop("suites"), found.pop("claims")
    for kind, (count, table) in found.items():
        check_section(kind, count, table)
    from bench.records.suites import SUITES

    count, table = suites
    assert count == len(SUITES) and set(table) - {"name"} == set(SUITES)
    count, table = claims
    names = {c.name for s in SUITES.values() for c in s.claims}
    assert count == len(names) and set(table) - {"name"} == names


def test_list_unknown_kind_is_a_usage_error():
    proc = bench("list", "nonsense")
    assert proc.returncode == 2
    assert "invalid choice: 'nonsense'" in proc.stderr


def test_version():
    proc = bench("--version")
    assert proc.returncode == 0
    assert proc.stdout.strip() == "bench 0.1.0"


# -- bench simplify ---------------------------------------------------------------------------

def test_simplify_bunny_textured_writes_textured_obj(tmp_path):
    out = tmp_path / "result.obj"
    proc = bench("simplify", "bunny-textured", out, "--method", "qslim-texture",
                 "--ratio", "0.2")
    assert proc.returncode == 0, proc.stderr
    assert proc.stderr == ""
    assert sorted(p.name for p in tmp_path.iterdir()) == ["result.mtl", "result.obj",
                                                          "result.png"]
    assert proc.stdout.startswith("bunny-textured: 9999 -> ")
    target = round(0.2 * 9999)
    mesh = load_mesh(out)
    assert mesh.has_texture
    assert mesh.texture.shape == (512, 512, 3)
    assert abs(mesh.n_faces - target) <= max(2, 0.005 * target)
    assert abs(mesh.n_faces - target) <= target_tolerance(target)
    assert f"-> {mesh.n_faces} faces ({mesh.n_vertices} vertices)" in proc.stdout
    # seam vertices are still shared positions (wedges split back into render vertices)
    assert np.isfinite(mesh.uv).all()
    assert mesh.welded.n_vertices < mesh.n_vertices
