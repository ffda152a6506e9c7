"""Counting metrics: the size and topology of a simplified mesh (L&T 2000, Plate 1 d–f).

Seam cracks are welded boundary edges of the result that were not boundary in the
original but opened along its seams. Vertices move during simplification and external
methods report no provenance, so this is decided geometrically: a boundary edge of the
result is a crack when its midpoint is nearer to the original's seam edges than to the
original's boundary edges. (An original with no boundary makes every boundary edge of
the result a crack; one with no seams has none.) Distances to the boundary alone do
not work: a simplified hole's chords lie a few thousandths of the diagonal off the
original boundary, as far as cracks do.
"""

from __future__ import annotations

import numpy as np

from bench.mesh import Mesh
from bench.metric import Metric

__all__ = ["counts", "seam_cracks", "FACES", "RENDER_VERTICES",
           "WELDED_VERTICES", "BOUNDARY_EDGES", "SEAM_CRACKS", "NON_MANIFOLD_EDGES"]

def seam_cracks(original: Mesh, simplified: Mesh) -> int:
    """Number of boundary edges of ``simplified`` that follow the original's seams
    rather than its boundary (see the module docstring)."""
    w = simplified.welded
    edges = w.edges[w.boundary]
    if len(edges) == 0:
        return 0
    ow = original.welded
    midpoints = w.positions[edges].mean(axis=1)
    to_boundary = _distance_to_segments(midpoints, ow.positions[ow.edges[ow.boundary]])
    to_seam = _distance_to_segments(midpoints, ow.positions[ow.edges[ow.seam]])
    if not np.isfinite(to_boundary).any():
        return int(len(edges))
    return int((to_seam < to_boundary).sum())


def _distance_to_segments(points: np.ndarray, segments: np.ndarray, k: int = 8) -> np.ndarray:
    """Distance from each point (p, 3) to the nearest of the segments (s, 2, 3), exact
    over the k segments whose midpoints are nearest (the boundary of a mesh is a set of
    short segments, so the nearest one is among them)."""
    from scipy.spatial import cKDTree

    if len(segments) == 0:
        return np.full(len(points), np.inf)
    a, b = segments[:, 0], segments[:, 1]
    k = min(k, len(segments))
    _, idx = cKDTree((a + b) / 2).query(points, k=k)
    idx = idx.reshape(len(points), k)
    pa, ab = points[:, None, :] - a[idx], (b - a)[idx]
    denom = np.einsum("pkj,pkj->pk", ab, ab)
    t = np.clip(np.einsum("pkj,pkj->pk", pa, ab) / np.where(denom > 0, denom, 1), 0, 1)
    return np.linalg.norm(pa - t[..., None] * ab, axis=2).min(axis=1)


def counts(original: Mesh, simplified: Mesh) -> dict:
    """All counting metrics as a dict of ints."""
    summary = simplified.summary()
    keys = ("faces", "render_vertices", "welded_vertices", "boundary_edges",
            "non_manifold_edges")
    return {**{k: summary[k] for k in keys}, "seam_cracks": seam_cracks(original, simplified)}


def _count(key: str):
    """``compute`` of the count ``key``: read from ``ctx["topology"]`` (the protocol's
    :func:`counts`, computed once for all six metrics) or counted when absent."""
    def compute(original: Mesh, simplified: Mesh, ctx=None) -> int:
        ctx = ctx or {}
        found = ctx["topology"] if "topology" in ctx else counts(original, simplified)
        return int(found[key])

    return compute


FACES = Metric("faces", "faces", None, "triangles in the result", _count("faces"),
               needs={"topology"})
RENDER_VERTICES = Metric("render_vertices", "vertices", None,
                         "vertices as a GPU stores them (one per distinct attribute set)",
                         _count("render_vertices"), needs={"topology"})
WELDED_VERTICES = Metric("welded_vertices", "vertices", None,
                         "vertices with equal positions merged", _count("welded_vertices"),
                         needs={"topology"})
BOUNDARY_EDGES = Metric("boundary_edges", "edges", False,
                        "welded edges with one incident face (holes and cracks show here)",
                        _count("boundary_edges"), needs={"topology"})
SEAM_CRACKS = Metric("seam_cracks", "edges", False,
                     "boundary edges of the result that opened along the original's seams",
                     _count("seam_cracks"), needs={"topology"})
NON_MANIFOLD_EDGES = Metric("non_manifold_edges", "edges", False,
                            "welded edges with more than two incident faces",
                            _count("non_manifold_edges"), needs={"topology"})
