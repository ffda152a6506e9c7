"""Silhouette histograms (Lindstrom & Turk 2000, §5.1 and Figure 7).

For a set of camera positions, count for every welded edge the number of views in which
it lies on the silhouette; the histogram gives the share of edges that are silhouette
edges in exactly i views, i = 0..V, and ⟨x⟩ its expectation. Coarser meshes have more
edges on the silhouette in more views, which is why an image metric also keeps the
geometric error low.

Facing is judged from the camera *position* (a perspective camera): a face is
front-facing when its outward normal n and the vector from a point p of the face to the
eye e satisfy n · (e − p) > 0, and back-facing otherwise (edge-on and zero-area faces
included). An edge is a silhouette edge in a view when, by the number of its faces:

====================  ===================================================================
faces at the edge     silhouette when
====================  ===================================================================
1 (boundary)          its face is front-facing (the outline of an open surface)
2 (manifold)          one face is front-facing and the other back-facing
more (non-manifold)   its faces are neither all front-facing nor all back-facing
====================  ===================================================================

The rule for non-manifold edges extends the manifold one: a fold between a visible and a
hidden sheet is drawn as an outline either way.

The :class:`~bench.core.metric.Metric` :data:`SILHOUETTE_MEAN` is called as
``compute(original, simplified, ctx)`` with ``ctx`` a dict that may hold ``"silhouette"``
(the protocol's :class:`SilhouetteHistogram` of the simplified mesh, which it then reads)
or ``"silhouette_eyes"``, ndarray of shape (V, 3); without it the eyes are the protocol's 20
dodecahedron cameras fitted to the original (:func:`metrics.views.silhouette_cameras`).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from bench.core.mesh import Mesh
from bench.core.metric import Metric

__all__ = ["SilhouetteHistogram", "silhouette_counts", "silhouette_histogram",
           "SILHOUETTE_MEAN"]


class SilhouetteHistogram(NamedTuple):
    """What :func:`silhouette_histogram` returns (unpacks as ``histogram, mean``).

    Attributes
    ----------
    histogram : ndarray of shape (V + 1,) float64
        Share of edges that are silhouette edges in exactly i views; sums to 1.
    mean : float
        ⟨x⟩ = Σ_i i · histogram[i], the expected number of views in which an edge is on
        the silhouette.
    """

    histogram: np.ndarray
    mean: float


def silhouette_histogram(mesh: Mesh, eyes: np.ndarray) -> SilhouetteHistogram:
    """Share of welded edges that are silhouette edges in exactly i of the views.

    Parameters
    ----------
    mesh : Mesh
        At least one face. Its welded topology is used, so texture seams do not split
        edges.
    eyes : ndarray of shape (V, 3) float
        Camera positions (the protocol uses the 20 dodecahedron views).

    Returns
    -------
    SilhouetteHistogram
        ``histogram`` of shape (V + 1,) and ``mean`` ⟨x⟩.

    References
    ----------
    .. [1] Lindstrom, P. & Turk, G. Image-driven simplification. ACM TOG 19(3), 2000,
       Figure 7.
    """
    counts = silhouette_counts(mesh, eyes)
    n_views = len(np.asarray(eyes))
    histogram = np.bincount(counts, minlength=n_views + 1) / len(counts)
    return SilhouetteHistogram(histogram, float(np.arange(n_views + 1) @ histogram))


def silhouette_counts(mesh: Mesh, eyes: np.ndarray) -> np.ndarray:
    """Number of views in which each welded edge is a silhouette edge.

    Parameters
    ----------
    mesh : Mesh
        At least one face.
    eyes : ndarray of shape (V, 3) float
        Camera positions.

    Returns
    -------
    ndarray of shape (e,) int64
        One count in 0..V per edge of ``mesh.welded.edges``, in that order.
    """
    eyes = _check(mesh, eyes)
    w = mesh.welded
    front = _front_facing(w.positions, w.faces, eyes)          # (m, V)
    front_at_edge = _count_per_edge(w.faces, w.edges, front)   # (e, V)
    faces_at_edge = w.edge_face_count[:, None]
    silhouette = np.where(faces_at_edge == 1, front_at_edge == 1,
                          (front_at_edge > 0) & (front_at_edge < faces_at_edge))
    return silhouette.sum(axis=1)


# -- stages ------------------------------------------------------------------------------

def _front_facing(positions: np.ndarray, faces: np.ndarray, eyes: np.ndarray) -> np.ndarray:
    """(m, V) bool: n · (e − p) > 0 with p the face's first corner (any point of the
    face's plane gives the same sign) and n = (p1 − p0) × (p2 − p0), whose length does
    not change the sign."""
    p = positions[faces]
    normals = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
    # n · (e − p) = n · e − n · p, one matrix product for all faces and views.
    return normals @ eyes.T - np.einsum("ij,ij->i", normals, p[:, 0])[:, None] > 0


def _count_per_edge(faces: np.ndarray, edges: np.ndarray, front: np.ndarray) -> np.ndarray:
    """(e, V) int: how many of each edge's faces are front-facing in each view."""
    n_views = front.shape[1]
    # Half-edges of every face, keyed like Welded.edges (sorted pair), located in the
    # sorted edge list by a scalar key.
    half = np.sort(faces[:, [[0, 1], [1, 2], [2, 0]]].reshape(-1, 2), axis=1).astype(np.int64)
    base = int(max(faces.max(), edges.max())) + 1
    edge_of = np.searchsorted(edges[:, 0].astype(np.int64) * base + edges[:, 1],
                              half[:, 0] * base + half[:, 1])
    face_of = np.repeat(np.arange(len(faces)), 3)
    # One bincount over (edge, view) cells adds every half-edge's facing in every view.
    cell = edge_of[:, None] * n_views + np.arange(n_views)
    counts = np.bincount(cell.ravel(), weights=front[face_of].ravel(),
                         minlength=len(edges) * n_views)
    return counts.reshape(len(edges), n_views).astype(np.int64)


def _check(mesh, eyes) -> np.ndarray:
    if not isinstance(mesh, Mesh):
        raise ValueError(f"mesh must be a bench.core.mesh.Mesh, got {type(mesh).__name__}")
    if mesh.n_faces == 0:
        raise ValueError("mesh has no faces, hence no edges to histogram; pass a mesh "
                         "with at least one triangle")
    eyes = np.asarray(eyes, dtype=np.float64)
    if eyes.ndim != 2 or eyes.shape[1] != 3 or len(eyes) == 0:
        raise ValueError(f"eyes must be camera positions of shape (V, 3) with V >= 1, "
                         f"got {eyes.shape}")
    if not np.isfinite(eyes).all():
        raise ValueError("eyes contain NaN or infinite coordinates; pass finite camera "
                         "positions")
    return eyes


# -- registered metric -------------------------------------------------------------------

def _compute_mean(original: Mesh, simplified: Mesh, ctx=None) -> float:
    """⟨x⟩ of ``simplified``: from ``ctx["silhouette"]`` (the protocol's histogram) when
    given, else from the eyes in ``ctx["silhouette_eyes"]`` (shape (V, 3)), or else the
    protocol's 20 dodecahedron cameras fitted to ``original``."""
    ctx = ctx or {}
    if "silhouette" in ctx:
        return ctx["silhouette"].mean
    eyes = ctx.get("silhouette_eyes")
    if eyes is None:
        from metrics.views import silhouette_cameras

        eyes = np.array([camera.eye for camera in silhouette_cameras(original)])
    return silhouette_histogram(simplified, eyes).mean


SILHOUETTE_MEAN = Metric("silhouette_mean", "views", None,
                         "expected number of the 20 dodecahedron views in which an edge is "
                         "on the silhouette (Figure 7's ⟨x⟩)", _compute_mean,
                         needs={"silhouette"})
