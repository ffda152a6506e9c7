"""Binary PLY, written without trimesh: importing trimesh takes about half a second,
which is half of what ``bench simplify`` may spend outside its method.

The bytes are those trimesh's exporter writes for the same mesh (header comment
included), so a file is the same whichever wrote it: positions and normals as 32-bit
floats, UVs as the vertex properties ``s`` and ``t`` in 64-bit floats, RGBA colours
(only for a mesh without UVs: trimesh keeps one kind of visual), and each face as a
count byte and three 32-bit indices. ``tests/test_ply.py`` compares the two.
"""

from __future__ import annotations

import numpy as np

from bench.core.mesh import Mesh

__all__ = ["ply_bytes"]

_HEADER = "ply\nformat binary_little_endian 1.0\ncomment https://github.com/mikedh/trimesh\n"


def ply_bytes(mesh: Mesh) -> bytes:
    """``mesh`` as a binary little-endian PLY file."""
    fields = [("vertex", "<f4", (3,))]
    props = ["x", "y", "z"]
    kinds = ["float"] * 3
    if mesh.normals is not None:
        fields.append(("normal", "<f4", (3,)))
        props += ["nx", "ny", "nz"]
        kinds += ["float"] * 3
    colors = mesh.colors is not None and mesh.uv is None
    if colors:
        fields.append(("rgba", "<u1", (4,)))
        props += ["red", "green", "blue", "alpha"]
        kinds += ["uchar"] * 4
    if mesh.uv is not None:
        fields += [("s", "<f8"), ("t", "<f8")]
        props += ["s", "t"]
        kinds += ["double"] * 2
    vertices = np.zeros(mesh.n_vertices, dtype=fields)
    vertices["vertex"] = mesh.positions
    if mesh.normals is not None:
        vertices["normal"] = mesh.normals
    if colors:
        vertices["rgba"] = mesh.colors
    if mesh.uv is not None:
        vertices["s"], vertices["t"] = mesh.uv[:, 0], mesh.uv[:, 1]
    faces = np.zeros(mesh.n_faces, dtype=[("count", "<u1"), ("index", "<i4", (3,))])
    faces["count"] = 3
    faces["index"] = mesh.faces
    header = (_HEADER + f"element vertex {mesh.n_vertices}\n"
              + "".join(f"property {k} {p}\n" for k, p in zip(kinds, props))
              + f"element face {mesh.n_faces}\nproperty list uchar int vertex_indices\n"
              + "end_header\n")
    return header.encode() + vertices.tobytes() + faces.tobytes()
