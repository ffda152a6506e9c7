"""The suite's PLY writer (bench.io.ply) writes the bytes trimesh's exporter writes for
the same mesh, whatever attributes it has; and save_mesh writes PLY without importing
trimesh."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
from hypothesis import given
from hypothesis import strategies as st

from bench.core.mesh import Mesh
from bench.io.ply import ply_bytes


def trimesh_ply(mesh: Mesh) -> bytes:
    """The oracle: trimesh's export of the mesh as the suite built it before."""
    import trimesh

    kwargs = {} if mesh.normals is None else {"vertex_normals": mesh.normals}
    tm = trimesh.Trimesh(mesh.positions, mesh.faces, process=False, **kwargs)
    if mesh.uv is not None:
        tm.visual = trimesh.visual.TextureVisuals(uv=mesh.uv)
    elif mesh.colors is not None:
        tm.visual = trimesh.visual.ColorVisuals(tm, vertex_colors=mesh.colors)
    return tm.export(file_type="ply")


@st.composite
def meshes(draw):
    n = draw(st.integers(3, 12))
    m = draw(st.integers(1, 10))
    rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
    scale = draw(st.sampled_from([1e-3, 1.0, 1e4]))
    positions = rng.normal(size=(n, 3)) * scale
    faces = np.stack([rng.permutation(n)[:3] for _ in range(m)]).astype(np.int32)
    uv = rng.random((n, 2)) * 3 - 1 if draw(st.booleans()) else None
    normals = rng.normal(size=(n, 3)) if draw(st.booleans()) else None
    colors = None
    if draw(st.booleans()):
        colors = rng.integers(0, 256, (n, 4), dtype=np.uint8)
        if draw(st.booleans()):
            colors[:] = colors[0]  # one colour for all
    return Mesh(positions, faces, uv=uv, normals=normals, colors=colors)


@given(meshes())
def test_the_bytes_are_trimeshs(mesh):
    assert ply_bytes(mesh) == trimesh_ply(mesh)


def test_save_mesh_writes_ply_without_trimesh(tmp_path):
    code = ("import sys, numpy as np; from bench.core.mesh import Mesh; "
            "from bench.io.meshio import save_mesh; "
            "save_mesh(Mesh(np.eye(3), np.array([[0, 1, 2]])), sys.argv[1]); "
            "print('trimesh' in sys.modules)")
    out = subprocess.run([sys.executable, "-c", code, str(tmp_path / "a.ply")],
                         capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False"
    assert (tmp_path / "a.ply").read_bytes() == trimesh_ply(Mesh(np.eye(3),
                                                                  np.array([[0, 1, 2]])))
