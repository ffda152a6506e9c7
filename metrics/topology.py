"""Counting metrics: the size and topology of a simplified mesh (L&T 2000, Plate 1 d–f)."""

from __future__ import annotations

from bench.metric import Metric

__all__ = ["FACES", "RENDER_VERTICES", "WELDED_VERTICES", "BOUNDARY_EDGES", "NON_MANIFOLD_EDGES"]

FACES = Metric("faces", "faces", None, "triangles in the result",
               lambda original, mesh, ctx=None: float(mesh.n_faces))
RENDER_VERTICES = Metric("render_vertices", "vertices", None,
                         "vertices as a GPU stores them (one per distinct attribute set)",
                         lambda original, mesh, ctx=None: float(mesh.n_vertices))
WELDED_VERTICES = Metric("welded_vertices", "vertices", None,
                         "vertices with equal positions merged",
                         lambda original, mesh, ctx=None: float(mesh.welded.n_vertices))
BOUNDARY_EDGES = Metric("boundary_edges", "edges", False,
                        "welded edges with one incident face (holes and cracks show here)",
                        lambda original, mesh, ctx=None: float(mesh.welded.boundary.sum()))
NON_MANIFOLD_EDGES = Metric("non_manifold_edges", "edges", False,
                            "welded edges with more than two incident faces",
                            lambda original, mesh, ctx=None: float(mesh.welded.non_manifold.sum()))
