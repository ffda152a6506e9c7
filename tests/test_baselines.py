"""The external baselines (pymeshlab QSlim, fast-simplification) and run_method."""

from __future__ import annotations

import dataclasses
import hashlib
import json
import subprocess
import sys

import numpy as np
import pytest

from bench.core.errors import InputError, MethodError
from bench.core.mesh import Mesh
from bench.core.method import Method, SimplifyResult, run_method, target_tolerance
from conftest import TET_FACES, TET_POSITIONS
from methods.baselines import FastSimplification, QSlim, QSlimTexture, split_wedges

METHODS = {"qslim": QSlim, "qslim-texture": QSlimTexture,
           "fast-simplification": FastSimplification}


def digest(mesh: Mesh) -> str:
    h = hashlib.sha256(mesh.positions.tobytes())
    h.update(mesh.faces.tobytes())
    return h.hexdigest()


# -- targets ------------------------------------------------------------------------------

@pytest.fixture(scope="module")
def results(bunny_textured, small_torus):
    """Each baseline on the textured bunny (target 1000) and the 64x32 torus (256)."""
    out = {}
    for name, cls in METHODS.items():
        out[name, "bunny"] = run_method(cls(), bunny_textured, 1000)
        out[name, "torus"] = run_method(cls(), small_torus, 256)
    return out


@pytest.mark.parametrize("mesh_key, target", [("bunny", 1000), ("torus", 256)])
@pytest.mark.parametrize("name", list(METHODS))
def test_baseline_hits_target(results, name, mesh_key, target):
    result = results[name, mesh_key]
    assert abs(result.mesh.n_faces - target) <= target_tolerance(target)
    assert result.stop_reason is None
    assert result.stats["wall_seconds"] >= 0 and result.stats["cpu_seconds"] >= 0
    assert result.mesh.faces.min() >= 0
    assert result.mesh.faces.max() < result.mesh.n_vertices
    # no unreferenced vertices left behind
    assert len(np.unique(result.mesh.faces)) == result.mesh.n_vertices


@pytest.mark.parametrize("mesh_key", ["bunny", "torus"])
def test_qslim_texture_keeps_uv_and_texture(results, bunny_textured, small_torus, mesh_key):
    source = {"bunny": bunny_textured, "torus": small_torus}[mesh_key]
    out = results["qslim-texture", mesh_key].mesh
    assert out.has_texture
    assert out.uv.shape == (out.n_vertices, 2)
    np.testing.assert_array_equal(out.texture, source.texture)
    assert np.isfinite(out.uv).all()  # (optimal placement may step slightly outside [0, 1])
    # wedges were split back into render vertices: seams are shared positions again
    assert out.welded.n_vertices < out.n_vertices
    assert out.welded.seam.sum() > 0


def test_qslim_texture_keeps_the_torus_closed(results):
    w = results["qslim-texture", "torus"].mesh.welded
    assert w.boundary.sum() == 0
    assert w.non_manifold.sum() == 0


def test_qslim_keeps_uv_and_texture_per_render_vertex(results, bunny_textured):
    out = results["qslim", "bunny"].mesh
    assert out.has_texture
    assert out.uv.shape == (out.n_vertices, 2)
    np.testing.assert_array_equal(out.texture, bunny_textured.texture)


@pytest.mark.parametrize("mesh_key", ["bunny", "torus"])
def test_fast_simplification_output_is_untextured(results, mesh_key):
    result = results["fast-simplification", mesh_key]
    assert result.mesh.uv is None and result.mesh.texture is None
    assert result.mesh.normals is None and result.mesh.colors is None
    assert result.stats["attributes_dropped"] is True


def test_fast_simplification_welds_so_the_torus_stays_closed(results):
    assert results["fast-simplification", "torus"].mesh.welded.boundary.sum() == 0


# -- determinism and pymeshlab's remembered parameters -------------------------------------

NON_DEFAULT = dict(qualitythr=0.9, optimalplacement=False, planarquadric=True,
                   planarweight=0.5, boundaryweight=3.0, preserveboundary=True)

FRESH_SCRIPT = r"""
import hashlib, json
import numpy as np
import pymeshlab
from bench.catalog import BUNNY_TEXTURED
from bench.core.method import run_method
from methods.baselines import QSlim

mesh = run_method(QSlim(), BUNNY_TEXTURED.load(), 1000).mesh
h = hashlib.sha256(mesh.positions.tobytes()); h.update(mesh.faces.tobytes())
ms = pymeshlab.MeshSet()
ms.add_mesh(pymeshlab.Mesh(vertex_matrix=np.eye(3), face_matrix=np.array([[0, 1, 2]])))
print(json.dumps({
    "digest": h.hexdigest(),
    "qslim": ms.filter_parameter_values("meshing_decimation_quadric_edge_collapse"),
    "qslim-texture": ms.filter_parameter_values(
        "meshing_decimation_quadric_edge_collapse_with_texture"),
}))
"""


@pytest.fixture(scope="module")
def fresh_process():
    """A default QSlim run and pymeshlab's filter defaults in a brand-new process, where
    no earlier filter call can have changed pymeshlab's remembered parameters."""
    proc = subprocess.run([sys.executable, "-c", FRESH_SCRIPT], capture_output=True,
                          text=True, timeout=120, check=True)
    return json.loads(proc.stdout.strip().splitlines()[-1])


def test_qslim_default_is_deterministic(bunny_textured):
    a = run_method(QSlim(), bunny_textured, 1000).mesh
    b = run_method(QSlim(), bunny_textured, 1000).mesh
    assert a.n_faces == b.n_faces
    np.testing.assert_array_equal(a.positions, b.positions)
    np.testing.assert_array_equal(a.faces, b.faces)


def test_qslim_does_not_inherit_earlier_parameters(bunny_textured, fresh_process):
    other = run_method(QSlim(**NON_DEFAULT), bunny_textured, 1000).mesh
    again = run_method(QSlim(), bunny_textured, 1000).mesh
    assert digest(other) != digest(again)  # the non-default call did change something
    assert digest(again) == fresh_process["digest"]


def test_qslim_texture_does_not_inherit_earlier_parameters(small_torus):
    first = run_method(QSlimTexture(), small_torus, 256).mesh
    non_default = {k: v for k, v in NON_DEFAULT.items() if k in
                   {f.name for f in dataclasses.fields(QSlimTexture.Params)}}
    other = run_method(QSlimTexture(extratcoordw=5.0, **non_default), small_torus, 256).mesh
    again = run_method(QSlimTexture(), small_torus, 256).mesh
    assert digest(other) != digest(first)
    assert digest(again) == digest(first)
    np.testing.assert_array_equal(again.uv, first.uv)


@pytest.mark.parametrize("name", ["qslim", "qslim-texture"])
def test_params_cover_every_filter_parameter_with_its_default(fresh_process, name):
    # Every filter parameter must be passed explicitly (or pymeshlab reuses the last
    # value), and our defaults must be MeshLab's.
    filter_defaults = fresh_process[name]
    ours = dataclasses.asdict(METHODS[name].Params())
    explicit = {"targetfacenum", "targetperc", "selected"}
    assert set(ours) | explicit == set(filter_defaults)
    for key, value in ours.items():
        assert filter_defaults[key] == pytest.approx(value, rel=1e-6), key


# -- run_method -----------------------------------------------------------------------------

@pytest.mark.parametrize("extra", [0, 5])
def test_target_at_or_above_input_returns_input(extra):
    mesh = Mesh(TET_POSITIONS, TET_FACES)
    with pytest.warns(UserWarning, match=rf"target of {4 + extra} faces is not below the "
                                         r"input's 4; returning the input unchanged"):
        result = run_method(QSlim(), mesh, 4 + extra)
    assert result.mesh is mesh
    assert result.stop_reason == "input already has 4 faces"


def test_qslim_texture_needs_uvs():
    with pytest.raises(InputError, match=r"tet: qslim-texture needs texture coordinates"):
        run_method(QSlimTexture(), Mesh(TET_POSITIONS, TET_FACES, name="tet"), 2)


class _Broken(Method):
    name = "broken"

    def simplify(self, mesh, target_faces, ctx=None):
        raise RuntimeError("first line\nboom")


class _Lazy(Method):
    name = "lazy"

    def simplify(self, mesh, target_faces, ctx=None):
        return SimplifyResult(mesh, {"wall_seconds": 1.5})


def test_backend_failure_becomes_method_error():
    mesh = Mesh(TET_POSITIONS, TET_FACES, name="tet")
    with pytest.raises(MethodError, match=r"method 'broken' failed on tet: RuntimeError: boom "
                                          r"\(run with --debug") as info:
        run_method(_Broken(), mesh, 2)
    assert isinstance(info.value.__cause__, RuntimeError)
    assert info.value.exit_code == 1


def test_missed_target_gets_a_stop_reason():
    mesh = Mesh(TET_POSITIONS, TET_FACES)
    result = run_method(_Lazy(), mesh, 1)
    assert result.stop_reason == "reached 4 faces for a target of 1 (tolerance 2)"
    assert result.stats["wall_seconds"] == 1.5  # a method's own timing is kept
    assert "cpu_seconds" in result.stats


def test_within_tolerance_is_not_a_miss():
    mesh = Mesh(TET_POSITIONS, TET_FACES)
    assert run_method(_Lazy(), mesh, 2).stop_reason is None  # |4 - 2| <= 2


def test_method_params_and_overrides():
    assert QSlim().params == QSlim.Params()
    m = QSlim(qualitythr=0.5)
    assert m.params.qualitythr == 0.5 and m.params.autoclean is True
    assert repr(m).startswith("QSlim(QSlimParams(qualitythr=0.5")
    assert FastSimplification(weld=False).params.weld is False


def test_qslim_carries_vertex_colors():
    #  a 4x4 grid of quads (32 triangles) in the plane z=0, coloured per vertex
    n = 5
    x, y = np.meshgrid(np.arange(n), np.arange(n), indexing="ij")
    positions = np.column_stack([x.ravel(), y.ravel(), np.zeros(n * n)]).astype(float)
    v = np.arange(n * n).reshape(n, n)[:-1, :-1].ravel()
    faces = np.concatenate([np.column_stack([v, v + n, v + n + 1]),
                            np.column_stack([v, v + n + 1, v + 1])])
    colors = np.zeros((n * n, 4), np.uint8)
    colors[:, 0] = 200
    colors[:, 3] = 255
    mesh = Mesh(positions, faces, colors=colors)
    out = run_method(QSlim(), mesh, 8).mesh
    assert out.colors is not None and out.colors.shape == (out.n_vertices, 4)
    np.testing.assert_array_equal(out.colors[:, 0], 200)


# -- split_wedges ---------------------------------------------------------------------------

def test_split_wedges_exact():
    #  0-----1      welded faces (0,2,1) and (1,2,3); the corners at vertex 2 have
    #  |    /|      different UVs in the two faces (a seam through vertex 2 only),
    #  |  /  |      vertex 1's corners agree.
    #  2-----3
    positions = np.array([[0, 1, 0], [1, 1, 0], [0, 0, 0], [1, 0, 0]], dtype=float)
    faces = np.array([[0, 2, 1], [1, 2, 3]])
    wedge_uv = np.array([[0.0, 1.0], [0.0, 0.0], [0.5, 1.0],    # face 0: corners 0, 2, 1
                         [0.5, 1.0], [0.7, 0.0], [1.0, 0.0]])   # face 1: corners 1, 2, 3
    pos, f, uv = split_wedges(positions, faces, wedge_uv)
    # render vertices = distinct (vertex, u, v) sorted: (0|0,1) (1|.5,1) (2|0,0) (2|.7,0) (3|1,0)
    np.testing.assert_array_equal(pos, positions[[0, 1, 2, 2, 3]])
    np.testing.assert_array_equal(f, [[0, 2, 1], [1, 3, 4]])
    np.testing.assert_array_equal(uv, [[0, 1], [0.5, 1], [0, 0], [0.7, 0], [1, 0]])
    assert f.dtype == np.int32
    mesh = Mesh(pos, f, uv=uv)
    assert mesh.welded.n_vertices == 4
    assert mesh.welded.seam.sum() == 1  # the diagonal 1-2


def test_split_wedges_without_seams_is_one_vertex_per_position():
    faces = np.array([[0, 1, 2]])
    pos, f, uv = split_wedges(TET_POSITIONS[:3], faces, np.array([[0, 0], [1, 0], [0, 1.0]]))
    np.testing.assert_array_equal(pos, TET_POSITIONS[:3])
    np.testing.assert_array_equal(f, faces)
    np.testing.assert_array_equal(uv, [[0, 0], [1, 0], [0, 1]])
