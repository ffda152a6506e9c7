"""``vertex-clustering``: Rossignac & Borrel's vertex clustering on a uniform grid.

Every vertex moves to the mean position of the welded vertices in its grid cell; a face
whose three corners land in three different cells survives, the others collapse. The
grid is the finest whose survivors fit the face target, found by bisection over the
number of cells along the longest side. Render vertices keep their UVs and colours, so
seams stay where they were; two render vertices of one cell get bit-equal positions and
therefore weld again.

Rossignac, J. & Borrel, P. Multi-resolution 3D approximations for rendering complex
scenes. Modeling in Computer Graphics, 1993.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from bench.core.mesh import Mesh
from bench.core.method import Method, SimplifyResult, bounded

__all__ = ["VertexClustering", "cluster"]


def cluster(mesh: Mesh, cells: int) -> Mesh:
    """``mesh`` clustered on a grid of ``cells`` cells along its longest side."""
    lo, hi = mesh.bounding_box()
    size = max(float((hi - lo).max()), np.finfo(float).tiny) / cells
    welded = mesh.welded
    key = np.floor((welded.positions - lo) / size).astype(np.int64)
    np.clip(key, 0, cells - 1, out=key)
    _, cell_of_welded = np.unique(key, axis=0, return_inverse=True)
    cell_of_welded = cell_of_welded.reshape(-1)
    n_cells = int(cell_of_welded.max()) + 1
    # the mean position of each cell's welded vertices
    sums = np.zeros((n_cells, 3))
    np.add.at(sums, cell_of_welded, welded.positions)
    counts = np.bincount(cell_of_welded, minlength=n_cells)[:, None]
    centre = sums / counts
    cell = cell_of_welded[welded.vertex_of]  # the cell of every render vertex
    corners = cell[mesh.faces]
    distinct = ((corners[:, 0] != corners[:, 1]) & (corners[:, 1] != corners[:, 2])
                & (corners[:, 0] != corners[:, 2]))
    # one face per triple of cells (the first, in the input's order)
    triple = np.sort(corners[distinct], axis=1)
    _, first = np.unique(triple, axis=0, return_index=True)
    kept = mesh.faces[np.flatnonzero(distinct)[np.sort(first)]]
    moved = mesh.replace(positions=centre[cell], normals=None)  # the file's normals went stale
    return moved.keep_faces(kept)


class VertexClustering(Method):
    name = "vertex-clustering"
    version = "1"  # bump whenever the output for the same input changes
    summary = "vertex clustering on a uniform grid (an example plug-in)"
    reference = ("Rossignac & Borrel, Multi-resolution 3D approximations for rendering "
                 "complex scenes, Modeling in Computer Graphics 1993")
    requires = {"numpy": "numpy>=1.26"}

    @dataclass
    class Params:
        #: the finest grid tried, in cells along the longest side
        max_cells: int = bounded(1024, ge=2)

    def simplify(self, mesh: Mesh, target_faces: int, ctx=None) -> SimplifyResult:
        lo, hi = 1, self.params.max_cells
        best = None
        while lo <= hi:  # the finest grid whose result has at most target_faces faces
            mid = (lo + hi) // 2
            result = cluster(mesh, mid)
            if 0 < result.n_faces <= target_faces:
                best, lo = (mid, result), mid + 1
            else:
                hi = mid - 1
        if best is None:  # every grid left too many faces or none: the coarsest with some
            best = next(((c, r) for c in range(2, self.params.max_cells + 1)
                         if (r := cluster(mesh, c)).n_faces), (None, mesh))
        cells, result = best
        reason = None
        if result.n_faces > target_faces:
            reason = (f"no grid up to {self.params.max_cells} cells leaves between 1 and "
                      f"{target_faces} faces; the coarsest leaves {result.n_faces}")
        elif result.n_faces < target_faces:
            reason = (f"the finest grid under the target ({cells} cells along the longest "
                      f"side) leaves {result.n_faces} faces")
        return SimplifyResult(result, stats={"cells": cells}, stop_reason=reason)
