"""LOD chains: ``bench simplify IN OUT --faces N1,N2,...`` (``bench.run.lods``).

The expected face counts are those of the method run directly on the level's source
(in this process), so a chain that simplified from the wrong mesh, wrote the wrong
level or mislabelled one fails. meshopt and qslim keep these tests free of the numba
engine's compile.
"""

from __future__ import annotations

import json
import math
import struct
import subprocess
import sys
from itertools import pairwise

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from test_cli import ENV, assert_one_line_error, bench

from bench.catalog import resolve_model
from bench.core.errors import InputError
from bench.core.method import run_method, target_tolerance
from bench.core.registry import registry
from bench.io.meshio import load_mesh, lod_path, save_lods, save_mesh
from bench.run.lods import build_levels, level_targets, sidecar_path
from conftest import blob
from methods.meshopt import node_problem
from metrics.protocol import Protocol, evaluate

pytestmark = pytest.mark.skipif(node_problem() is not None, reason=str(node_problem()))


def method(name: str):
    return registry("method").load(name)()


def glb_json(path) -> dict:
    """The JSON chunk of a GLB file."""
    data = path.read_bytes()
    (length,) = struct.unpack("<I", data[12:16])
    return json.loads(data[20:20 + length])


@pytest.fixture(scope="module")
def blob_obj(tmp_path_factory):
    """A 320-face closed blob (no ties between edge costs) as an OBJ file."""
    path = tmp_path_factory.mktemp("lod") / "blob.obj"
    save_mesh(blob(2), path)
    return path


# -- the levels asked for ---------------------------------------------------------------------

def test_level_targets_faces_and_ratios():
    assert level_targets(1000, faces=[500, 250, 1]) == [
        (500, {"faces": 500}), (250, {"faces": 250}), (1, {"faces": 1})]
    # ratios round as --ratio does: round(0.333 * 1000) = 333, never below one face
    assert level_targets(1000, ratios=[0.5, 0.333, 0.0001]) == [
        (500, {"ratio": 0.5}), (333, {"ratio": 0.333}), (1, {"ratio": 0.0001})]


@settings(max_examples=200, deadline=None)
@given(n_faces=st.integers(1, 10_000),
       faces=st.lists(st.integers(-5, 12_000), min_size=1, max_size=6))
def test_level_targets_accepts_exactly_strictly_decreasing_counts_below_the_input(n_faces, faces):
    valid = (all(f >= 1 for f in faces) and faces[0] < n_faces
             and all(b < a for a, b in pairwise(faces)))
    if valid:
        assert [t for t, _ in level_targets(n_faces, faces=faces)] == faces
    else:
        with pytest.raises(InputError):
            level_targets(n_faces, faces=faces)


@settings(max_examples=200, deadline=None)
@given(n_faces=st.integers(1, 10_000),
       ratios=st.lists(st.floats(-0.5, 1.5, allow_nan=False), min_size=1, max_size=6))
def test_level_targets_ratios(n_faces, ratios):
    counts = [max(1, round(r * n_faces)) for r in ratios]
    valid = (all(0 < r <= 1 for r in ratios) and counts[0] < n_faces
             and all(b < a for a, b in pairwise(counts)))
    if valid:
        assert level_targets(n_faces, ratios=ratios) == [
            (c, {"ratio": r}) for c, r in zip(counts, ratios)]
    else:
        with pytest.raises(InputError):
            level_targets(n_faces, ratios=ratios)


# -- building the levels ----------------------------------------------------------------------

def test_direct_levels_are_each_simplified_from_the_input():
    mesh, m = blob(2), method("meshopt")
    levels = build_levels(m, mesh, level_targets(mesh.n_faces, faces=[160, 80, 40]))
    assert [lv.name for lv in levels] == ["LOD1", "LOD2", "LOD3"]
    assert [lv.source for lv in levels] == ["LOD0"] * 3
    assert [lv.source_faces for lv in levels] == [320] * 3
    for level in levels:
        direct = run_method(m, mesh, level.target_faces).mesh
        np.testing.assert_array_equal(level.result.mesh.faces, direct.faces)
        np.testing.assert_array_equal(level.result.mesh.positions, direct.positions)


def test_chained_levels_are_each_simplified_from_the_previous_level():
    mesh, m = blob(2), method("meshopt")
    targets = level_targets(mesh.n_faces, faces=[160, 80, 40])
    chained = build_levels(m, mesh, targets, chain=True)
    assert [lv.source for lv in chained] == ["LOD0", "LOD1", "LOD2"]
    sources = [mesh] + [lv.result.mesh for lv in chained[:-1]]
    for level, source in zip(chained, sources):
        assert level.source_faces == source.n_faces
        again = run_method(m, source, level.target_faces).mesh
        np.testing.assert_array_equal(level.result.mesh.faces, again.faces)
        np.testing.assert_array_equal(level.result.mesh.positions, again.positions)
    # and --chain matters: the last level differs from the one made from the input
    direct = build_levels(m, mesh, targets)
    last_c, last_d = chained[-1].result.mesh, direct[-1].result.mesh
    assert (last_c.n_vertices != last_d.n_vertices
            or not np.array_equal(last_c.positions, last_d.positions))


def test_evaluated_levels_are_measured_against_the_original(tmp_path, monkeypatch):
    """With --chain, LOD2 comes from LOD1 but its figures compare it with LOD0."""
    monkeypatch.setenv("BENCH_CACHE", str(tmp_path))  # never the user's image cache
    mesh, m = blob(2), method("meshopt")
    protocol = Protocol(resolution=64, msaa=1, hausdorff_samples=2000)
    levels = build_levels(m, mesh, level_targets(mesh.n_faces, faces=[160, 80]), chain=True,
                          protocol=protocol)
    for level in levels:
        expected = evaluate(mesh, level.result.mesh, protocol).metrics
        assert level.evaluation.metrics == expected
        assert level.evaluation_seconds > 0
    # against LOD1 (its source) LOD2's distances would be other numbers
    against_source = evaluate(levels[0].result.mesh, levels[1].result.mesh, protocol).metrics
    assert against_source["hausdorff_mean"] != levels[1].evaluation.metrics["hausdorff_mean"]


# -- writing them -------------------------------------------------------------------------------

def test_gltf_chain_is_one_scene_with_a_named_mesh_per_level(tmp_path):
    import trimesh

    crate = resolve_model("crate")
    half = crate.replace(faces=crate.faces[: crate.n_faces // 2])  # same texture array
    written = save_lods([("LOD0", crate), ("LOD1", half)], tmp_path / "c.gltf")
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(
        p.name for p in written["LOD0"])
    assert written["LOD0"] == written["LOD1"]
    scene = trimesh.load(tmp_path / "c.gltf", process=False)
    assert {k: len(g.faces) for k, g in scene.geometry.items()} == {
        "LOD0": crate.n_faces, "LOD1": crate.n_faces // 2}


def test_cli_glb_chain_round_trip(tmp_path):
    import trimesh

    out = tmp_path / "crate.glb"
    proc = bench("simplify", "crate", out, "--method", "meshopt", "--faces", "1000,500,200")
    assert proc.returncode == 0, proc.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == ["crate.glb", "crate.glb.lods.json"]
    crate, m = resolve_model("crate"), method("meshopt")
    expected = {"LOD0": crate.n_faces}
    for name, target in (("LOD1", 1000), ("LOD2", 500), ("LOD3", 200)):
        expected[name] = run_method(m, crate, target).mesh.n_faces
    scene = trimesh.load(out, process=False)
    assert {k: len(g.faces) for k, g in scene.geometry.items()} == expected
    doc = glb_json(out)
    assert [mesh["name"] for mesh in doc["meshes"]] == ["LOD0", "LOD1", "LOD2", "LOD3"]
    assert sorted(node["name"] for node in doc["nodes"]) == ["LOD0", "LOD1", "LOD2", "LOD3"]
    assert len(doc["images"]) == 1 and len(doc["materials"]) == 1  # one shared texture
    # a line per level on stdout, the progress bar per level on stderr
    assert [line.split(":")[0] for line in proc.stdout.splitlines()[:3]] == [
        "crate LOD1", "crate LOD2", "crate LOD3"]
    assert "3/3" in proc.stderr and "level" in proc.stderr
    side = json.loads(sidecar_path(out).read_text())
    assert [lv["faces"] for lv in side["levels"]] == list(expected.values())
    assert all(lv["file"] == "crate.glb" for lv in side["levels"])


def test_cli_obj_chain_writes_a_file_per_level(tmp_path):
    out = tmp_path / "crate.obj"
    proc = bench("simplify", "crate", out, "-m", "qslim", "--ratios", "0.5,0.25")
    assert proc.returncode == 0, proc.stderr
    names = [f"crate_LOD{i}.{ext}" for i in range(3) for ext in ("mtl", "obj", "png")]
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(names + ["crate.obj.lods.json"])
    crate, m = resolve_model("crate"), method("qslim")
    lod0 = load_mesh(lod_path(out, "LOD0"))  # the input itself, not simplified
    assert (lod0.n_faces, lod0.n_vertices) == (crate.n_faces, crate.n_vertices)
    assert lod0.has_texture
    np.testing.assert_allclose(np.unique(lod0.positions, axis=0),
                               np.unique(crate.positions, axis=0), atol=1e-9)
    side = json.loads(sidecar_path(out).read_text())
    for i, ratio in ((1, 0.5), (2, 0.25)):
        level = load_mesh(lod_path(out, f"LOD{i}"))
        assert level.has_texture
        entry = side["levels"][i]
        assert entry["requested"] == {"ratio": ratio}
        assert entry["target_faces"] == round(ratio * crate.n_faces)
        assert entry["faces"] == level.n_faces == run_method(
            m, crate, entry["target_faces"]).mesh.n_faces
        assert entry["file"] == f"crate_LOD{i}.obj"
    assert sorted(side["files"]) == sorted(names)


def test_cli_chain_sidecar(tmp_path, blob_obj):
    out = tmp_path / "blob.ply"
    proc = bench("simplify", blob_obj, out, "-m", "meshopt", "-f", "160,80,40", "--chain",
                 "-p", "lock_border=true")
    assert proc.returncode == 0, proc.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == [
        "blob.ply.lods.json", "blob_LOD0.ply", "blob_LOD1.ply", "blob_LOD2.ply", "blob_LOD3.ply"]
    side = json.loads(sidecar_path(out).read_text())
    m = registry("method").load("meshopt")
    assert side["method"]["name"] == "meshopt" and side["method"]["version"] == m.version
    assert side["method"]["params"]["lock_border"] is True
    assert side["levels_from"] == "previous"
    assert side["input"]["faces"] == 320 and side["input"]["source"] == str(blob_obj)
    assert side["protocol"] is None
    levels = side["levels"]
    assert [lv["name"] for lv in levels] == ["LOD0", "LOD1", "LOD2", "LOD3"]
    assert [lv["source"] for lv in levels] == [None, "LOD0", "LOD1", "LOD2"]
    assert [lv["target_faces"] for lv in levels] == [None, 160, 80, 40]
    faces = [lv["faces"] for lv in levels]
    assert [lv["source_faces"] for lv in levels[1:]] == faces[:-1]
    assert all(b < a for a, b in pairwise(faces))
    # the same chain built here: same faces, same library error
    mesh = load_mesh(blob_obj)
    chained = build_levels(m(m.Params(lock_border=True)), mesh,
                           level_targets(mesh.n_faces, faces=[160, 80, 40]), chain=True)
    assert faces[1:] == [lv.result.mesh.n_faces for lv in chained]
    for entry, level in zip(levels[1:], chained):
        assert abs(entry["faces"] - entry["target_faces"]) <= target_tolerance(
            entry["target_faces"])
        assert entry["stop_reason"] is None
        assert entry["method_error"] == level.result.stats["result_error"]
        assert entry["method_error_units"] == "relative"
        assert entry["stats"]["result_error"] == entry["method_error"]
        assert entry["seconds"] == entry["stats"]["wall_seconds"] > 0
        assert entry["metrics"] is None
    for i in range(4):
        assert load_mesh(lod_path(out, f"LOD{i}")).n_faces == faces[i]


def test_cli_methods_without_an_own_error_record_none(tmp_path, blob_obj):
    out = tmp_path / "b.glb"
    proc = bench("simplify", blob_obj, out, "-m", "qslim", "-f", "100,50")
    assert proc.returncode == 0, proc.stderr
    side = json.loads(sidecar_path(out).read_text())
    assert side["levels_from"] == "original"
    assert [lv["source"] for lv in side["levels"]] == [None, "LOD0", "LOD0"]
    assert [lv["method_error"] for lv in side["levels"]] == [None, None, None]


def test_cli_single_level_writes_what_it_always_wrote(tmp_path, blob_obj):
    """One level: OUT alone, byte for byte what saving the method's result writes."""
    out = tmp_path / "one.obj"
    proc = bench("simplify", blob_obj, out, "-m", "qslim", "-f", "100")
    assert proc.returncode == 0, proc.stderr
    assert proc.stderr == ""
    assert [p.name for p in tmp_path.iterdir()] == ["one.obj"]
    direct = tmp_path / "direct" / "one.obj"
    direct.parent.mkdir()
    save_mesh(run_method(method("qslim"), load_mesh(blob_obj), 100).mesh, direct)
    assert out.read_bytes() == direct.read_bytes()


# -- bad input --------------------------------------------------------------------------------

BAD_LEVELS = {
    "not decreasing": (["-f", "100,100"], ["strictly decreasing", "LOD2 asks for 100 faces",
                                           "LOD1's 100"]),
    "increasing": (["-f", "50,100"], ["strictly decreasing", "LOD2 asks for 100 faces"]),
    "ratios rounding to one count": (["-r", "0.5,0.501"], ["strictly decreasing",
                                                           "(ratio 0.501)", "LOD1's 160"]),
    "ratio above one": (["-r", "0.5,1.5"], ["every ratio must be in (0, 1], got 1.5"]),
    "ratio zero": (["--ratios", "0.5,0"], ["every ratio must be in (0, 1], got 0.0"]),
    "above the input": (["-f", "400,100"], ["LOD1 asks for 400 faces",
                                            "not fewer than the input's 320"]),
    "the input's count": (["-f", "320,100"], ["LOD1 asks for 320 faces"]),
    "ratio one": (["-r", "1,0.5"], ["LOD1 asks for 320 faces (ratio 1)"]),
    "zero faces": (["-f", "100,0"], ["--faces must be at least 1, got 0"]),
    "not a number": (["-f", "100,many"], ["--faces '100,many': expected a face count"]),
    "empty item": (["-f", "100,,50"], ["--faces '100,,50'"]),
    "chain with one level": (["-f", "100", "--chain"], ["--chain applies to LOD chains"]),
    "evaluate with one level": (["-r", "0.5", "--evaluate"],
                                ["--evaluate applies to LOD chains", "bench run"]),
}


@pytest.mark.parametrize("case", list(BAD_LEVELS))
def test_bad_levels_are_one_line_errors(tmp_path, blob_obj, capsys, case):
    """In this process for speed (``bench.commands.cli.main`` is what the console script runs);
    the subprocess test below checks one case as a user sees it."""
    from bench.commands.cli import main

    args, fragments = BAD_LEVELS[case]
    code = main(["simplify", str(blob_obj), str(tmp_path / "o.glb"), "-m", "meshopt", *args])
    captured = capsys.readouterr()
    assert code == 2
    assert captured.out == ""
    lines = captured.err.splitlines()
    assert len(lines) == 1 and lines[0].startswith("bench: error: "), captured.err
    for fragment in fragments:
        assert fragment in lines[0]
    assert list(tmp_path.iterdir()) == []


def test_an_output_that_is_a_directory_is_a_one_line_error(tmp_path, blob_obj, capsys):
    from bench.commands.cli import main

    (tmp_path / "o_LOD2.obj").mkdir()
    (tmp_path / "s.glb.lods.json").mkdir()
    for out, fragment in (("o.obj", "o_LOD2.obj: is a directory"),
                          ("s.glb", "s.glb.lods.json: is a directory")):
        code = main(["simplify", str(blob_obj), str(tmp_path / out), "-m", "meshopt",
                     "-f", "100,50"])
        err = capsys.readouterr().err.splitlines()
        assert code == 2 and len(err) == 1 and fragment in err[0], err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["o_LOD2.obj", "s.glb.lods.json"]


def test_bad_levels_in_a_subprocess(tmp_path, blob_obj):
    proc = bench("simplify", blob_obj, tmp_path / "o.obj", "-m", "qslim", "-f", "100,200")
    assert_one_line_error(proc, "strictly decreasing")
    assert list(tmp_path.iterdir()) == []


@pytest.mark.slow
def test_cli_evaluate_records_the_protocol_figures(tmp_path, blob_obj):
    out = tmp_path / "e.glb"
    proc = subprocess.run(
        [sys.executable, "-m", "bench", "simplify", str(blob_obj), str(out), "-m", "meshopt",
         "-f", "100,40", "--chain", "--evaluate"], check=False, capture_output=True, text=True,
        env=dict(ENV, BENCH_CACHE=str(tmp_path / "cache")), timeout=600)
    assert proc.returncode == 0, proc.stderr
    side = json.loads(sidecar_path(out).read_text())
    assert side["protocol"] == Protocol().as_dict()
    assert side["levels"][0]["metrics"] is None
    for entry, line in zip(side["levels"][1:], proc.stdout.splitlines()):
        for key in ("d_rms", "flip", "hausdorff_mean", "hausdorff_max"):
            assert math.isfinite(entry["metrics"][key])
            assert f"{key} {entry['metrics'][key]:.4g}" in line
        assert entry["metrics"]["faces"] == entry["faces"]
        assert entry["evaluation_seconds"] > 0
