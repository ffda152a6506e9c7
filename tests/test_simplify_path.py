"""What ``bench simplify`` loads: nothing of the evaluation, the report or the other
commands, and an OBJ input is read and scanned once."""

import subprocess
import sys

import numpy as np

from bench.io import meshio

HEAVY = ("pyrender", "OpenGL", "matplotlib", "pandas", "numba", "pymeshlab",
         "bench.commands.run", "bench.commands.report", "metrics.protocol")


def test_simplify_with_a_library_method_imports_nothing_heavy(tmp_path):
    out = tmp_path / "out.ply"
    code = ("import sys; from bench.commands.cli import main; "
            f"code = main(['simplify', 'torus', {str(out)!r}, '--method', 'meshopt', "
            "'--faces', '600']); sys.stdout.flush(); "
            f"print('LOADED', code, *sorted(m for m in {HEAVY!r} if m in sys.modules))")
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          timeout=300)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.strip().splitlines()[-1] == "LOADED 0"
    assert out.is_file()


def test_an_obj_is_scanned_once(tmp_path, monkeypatch):
    from bench.commands.cli import main

    path = tmp_path / "quad.obj"
    path.write_text("v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 0.5 0.5 0.2\n"
                    "f 1 2 5\nf 2 3 5\nf 3 4 5\nf 4 1 5\n")
    calls = []
    real = meshio._scan_obj
    monkeypatch.setattr(meshio, "_scan_obj", lambda p: calls.append(p) or real(p))
    assert main(["simplify", str(path), str(tmp_path / "out.obj"), "--method", "qslim",
                 "--faces", "2"]) == 0
    assert calls == [path]


def test_a_rewritten_obj_is_scanned_again(tmp_path):
    path = tmp_path / "t.obj"
    path.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    first = meshio.load_mesh(path)
    path.write_text("v 0 0 0\nv 2 0 0\nv 0 2 0\nv 2 2 0\nf 1 2 3\nf 2 4 3\n")
    second = meshio.load_mesh(path)
    assert first.n_faces == 1 and second.n_faces == 2
    assert np.array_equal(second.positions[:, :2].max(axis=0), [2, 2])
