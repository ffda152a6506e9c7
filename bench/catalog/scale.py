"""Larger versions of a model for the engine's scaling benchmark: midpoint subdivision."""

from __future__ import annotations

import numpy as np

from bench.core.mesh import Mesh

__all__ = ["subdivide"]


def subdivide(mesh: Mesh) -> Mesh:
    """``mesh`` with every triangle cut into four at the midpoints of its edges: the
    same surface with four times the faces. Each render-vertex edge gets one new vertex
    (so a seam stays a seam); its position and texture coordinates are the edge's
    midpoint, so a UV stays inside its material's atlas cell. Normals and colours, if
    any, are dropped (the scaling benchmark needs positions only)."""
    faces = mesh.faces.astype(np.int64)
    edges = np.sort(faces[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2), axis=1)
    unique, index = np.unique(edges, axis=0, return_inverse=True)
    mid = len(mesh.positions) + index.reshape(-1, 3)  # the new vertex of each face edge
    positions = np.vstack([mesh.positions, mesh.positions[unique].mean(axis=1)])
    uv = None if mesh.uv is None else np.vstack([mesh.uv, mesh.uv[unique].mean(axis=1)])
    a, b, c = faces.T
    ab, bc, ca = mid.T
    new = np.stack([np.stack([a, ab, ca], 1), np.stack([ab, b, bc], 1),
                    np.stack([ca, bc, c], 1), np.stack([ab, bc, ca], 1)], 1).reshape(-1, 3)
    return mesh.replace(positions=positions, faces=new.astype(np.int32), uv=uv,
                        normals=None, colors=None)
