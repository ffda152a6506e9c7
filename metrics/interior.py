"""Where a simplified mesh spends its faces: on the exterior or on a hidden interior
(Lindstrom & Turk 2000, §5.2, Plates 2–3).

A model opts in by describing its exterior in its metadata (as the built-in ``interior``
model, :mod:`bench.catalog.interior`, does)::

    mesh.metadata["exterior_sphere"] = {"centre": [x, y, z], "radius": r}

A face is *exterior* when its centroid lies strictly farther than ``r`` from the centre.
The rule needs positions only, so it classifies any simplification of the model, whatever
the method did to vertex indices. The original's metadata is used, because methods are
not required to carry metadata through.
"""

from __future__ import annotations

import math

import numpy as np

from bench.core.mesh import Mesh
from bench.core.metric import Metric

__all__ = ["CLASSIFIER_KEY", "exterior_sphere", "exterior_faces", "exterior_share",
           "EXTERIOR_SHARE"]

#: Metadata key of the exterior classification.
CLASSIFIER_KEY = "exterior_sphere"


def exterior_sphere(mesh: Mesh) -> tuple[np.ndarray, float] | None:
    """``(centre, radius)`` from ``mesh.metadata``, or None when the model has none.

    Raises
    ------
    ValueError
        When the metadata entry exists but is malformed.
    """
    spec = mesh.metadata.get(CLASSIFIER_KEY)
    if spec is None:
        return None
    try:
        centre = np.asarray(spec["centre"], dtype=np.float64).reshape(3)
        radius = float(spec["radius"])
    except (KeyError, TypeError, ValueError) as exc:
        raise ValueError(f"{mesh.name}: metadata[{CLASSIFIER_KEY!r}] must be "
                         f"{{'centre': [x, y, z], 'radius': r}}, got {spec!r} ({exc})") from None
    if not (np.isfinite(centre).all() and math.isfinite(radius) and radius > 0):
        raise ValueError(f"{mesh.name}: metadata[{CLASSIFIER_KEY!r}] needs a finite centre "
                         f"and a positive radius, got {spec!r}")
    return centre, radius


def exterior_faces(mesh: Mesh, centre, radius: float) -> np.ndarray:
    """Boolean mask of ``mesh``'s faces whose centroid is farther than ``radius`` from
    ``centre``."""
    centroids = mesh.positions[mesh.faces].mean(axis=1)
    return np.linalg.norm(centroids - np.asarray(centre, dtype=np.float64), axis=1) > radius


def exterior_share(original: Mesh, simplified: Mesh, ctx=None) -> float:
    """Share of ``simplified``'s faces on the exterior, by the classification in
    ``original``'s metadata; NaN when the original has none or the result has no faces."""
    sphere = exterior_sphere(original)
    if sphere is None or simplified.n_faces == 0:
        return math.nan
    return float(exterior_faces(simplified, *sphere).mean())


EXTERIOR_SHARE = Metric(
    "exterior_share", "fraction of faces", True,
    "share of the result's faces on the visible exterior, for models that classify their "
    "faces (e.g. interior; L&T 2000 §5.2)", exterior_share)
