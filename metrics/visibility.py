"""Which faces of a mesh the protocol's views can see at all.

A face is *seen* when it is the nearest surface at the centre of at least one pixel of
one of the protocol's 24 views at the protocol's resolution (512²), with no back-face
culling: exactly what the image metrics can measure. Faces seen by no view are
*never seen*; Lindstrom & Turk 2000 (§5.2) claim the image-driven method spends no faces
on them. The face-id images are made by a small z-buffer rasterizer here (numba), not by
the evaluation renderer, so a face id per pixel needs no colour encoding and the result
is exact and the same on every machine.

A simplified mesh's faces do not correspond to the original's, so
:func:`never_seen_share` places each of its faces by its centroid's nearest original
face centroid and counts those that land on a never-seen one.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from bench.core.mesh import Mesh
from bench.core.metric import Metric
from bench.core.numba_cache import lock_cache_writes

lock_cache_writes()  # several processes compile at once (bench.core.numba_cache)

__all__ = ["NEVER_SEEN_SHARE", "never_seen_share", "seen_faces"]

#: Pixels per side of the face-id images (the protocol's resolution).
RESOLUTION = 512


@njit(cache=True)
def _rasterize_ids(sx, sy, sz, faces, size, ids, depth):
    """Write into ``ids`` (size, size) the nearest face at each pixel centre, given the
    vertices' screen coordinates (pixels, with y down) and NDC depths; ``depth`` holds
    the nearest depth so far."""
    for f in range(faces.shape[0]):
        a, b, c = faces[f, 0], faces[f, 1], faces[f, 2]
        x0, y0, z0 = sx[a], sy[a], sz[a]
        x1, y1, z1 = sx[b], sy[b], sz[b]
        x2, y2, z2 = sx[c], sy[c], sz[c]
        area = (x1 - x0) * (y2 - y0) - (x2 - x0) * (y1 - y0)
        if area == 0.0 or not math.isfinite(area):
            continue
        lo_x = max(0, math.floor(min(x0, x1, x2) - 0.5))
        hi_x = min(size - 1, math.ceil(max(x0, x1, x2) - 0.5))
        lo_y = max(0, math.floor(min(y0, y1, y2) - 0.5))
        hi_y = min(size - 1, math.ceil(max(y0, y1, y2) - 0.5))
        for py in range(lo_y, hi_y + 1):
            cy = py + 0.5
            for px in range(lo_x, hi_x + 1):
                cx = px + 0.5
                w0 = ((x1 - cx) * (y2 - cy) - (x2 - cx) * (y1 - cy)) / area
                w1 = ((x2 - cx) * (y0 - cy) - (x0 - cx) * (y2 - cy)) / area
                w2 = 1.0 - w0 - w1
                if w0 < 0.0 or w1 < 0.0 or w2 < 0.0:
                    continue
                z = w0 * z0 + w1 * z1 + w2 * z2  # NDC depth is affine on the screen
                if z < depth[py, px]:
                    depth[py, px] = z
                    ids[py, px] = f


def face_id_image(positions: np.ndarray, faces: np.ndarray, camera,
                  size: int = RESOLUTION) -> np.ndarray:
    """(size, size) int64: the face nearest the camera at each pixel centre, -1 where
    none is (row 0 at the top)."""
    p = np.c_[np.asarray(positions, np.float64), np.ones(len(positions))]
    clip = p @ (camera.projection_matrix() @ camera.view_matrix()).T
    w = clip[:, 3]
    faces = np.asarray(faces, np.int64)
    # the protocol's cameras see the whole bounding sphere between near and far, so no
    # vertex is behind the eye; a face with one that is would be clipped: left out
    keep = (w[faces] > 0).all(axis=1)
    ndc = clip[:, :3] / np.where(w > 0, w, 1.0)[:, None]
    sx = (ndc[:, 0] + 1.0) * 0.5 * size
    sy = (1.0 - ndc[:, 1]) * 0.5 * size
    ids = np.full((size, size), -1, np.int64)
    depth = np.full((size, size), np.inf)
    order = np.flatnonzero(keep)
    _rasterize_ids(sx, sy, ndc[:, 2], faces[order], size, ids, depth)
    return np.where(ids >= 0, order[np.maximum(ids, 0)], -1)


def seen_faces(mesh: Mesh, cameras=None, size: int = RESOLUTION) -> np.ndarray:
    """Boolean mask of ``mesh``'s faces seen by at least one of ``cameras`` (default:
    the protocol's 24)."""
    from metrics.views import protocol_cameras

    cameras = protocol_cameras(mesh) if cameras is None else cameras
    seen = np.zeros(mesh.n_faces, bool)
    for camera in cameras:
        ids = face_id_image(mesh.positions, mesh.faces, camera, size)
        seen[ids[ids >= 0]] = True
    return seen


def never_seen_share(original: Mesh, simplified: Mesh, ctx=None) -> float:
    """Share of ``simplified``'s faces whose centroid is nearest a face of ``original``
    that no protocol view sees; NaN when the original does not classify its faces (the
    metric is computed for those models only, as ``exterior_share`` is) or the result
    has no faces."""
    from metrics.interior import exterior_sphere

    if exterior_sphere(original) is None or simplified.n_faces == 0:
        return math.nan
    seen, tree = _original_visibility(original)
    _, nearest = tree.query(simplified.positions[simplified.faces].mean(axis=1))
    return float((~seen[nearest]).mean())


_VISIBILITY: dict = {}  # content hash -> (seen faces, centroid tree), for this process


def _original_visibility(original: Mesh):
    """``original``'s seen faces and a tree of its face centroids, made once per model
    and process (a job process evaluates the same original for every job of a model)."""
    from scipy.spatial import cKDTree

    key = original.content_hash
    if key not in _VISIBILITY:
        if len(_VISIBILITY) >= 4:
            _VISIBILITY.clear()
        _VISIBILITY[key] = (seen_faces(original),
                            cKDTree(original.positions[original.faces].mean(axis=1)))
    return _VISIBILITY[key]


NEVER_SEEN_SHARE = Metric(
    "never_seen_share", "fraction of faces", False,
    "share of the result's faces lying where no protocol view sees the original (for "
    "models that classify their faces, e.g. interior; L&T 2000 §5.2)", never_seen_share)
