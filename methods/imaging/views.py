"""The view sets of the rendered cost terms: the directions the image and entropy terms
look from, and which of them look at interiors (front faces culled)."""

from __future__ import annotations

import math

import numpy as np

from metrics.views import dodecahedron_directions

__all__ = ["view_directions", "interior_mask"]


def view_directions(count: int) -> np.ndarray:
    """Unit view directions: the 20 dodecahedron vertices for ``count == 20`` (§4.2),
    else a spherical Fibonacci set of ``count`` points."""
    if count == 20:
        return np.asarray(dodecahedron_directions(), dtype=np.float64)
    i = np.arange(count) + 0.5
    z = 1.0 - 2.0 * i / count
    phi = math.pi * (1.0 + math.sqrt(5.0)) * i
    r = np.sqrt(1.0 - z * z)
    return np.stack([r * np.cos(phi), r * np.sin(phi), z], axis=1)


def interior_mask(count: int, interior: int) -> np.ndarray:
    """(count,) bool: which views cull front faces, spread evenly over the set."""
    mask = np.zeros(count, bool)
    if interior > 0:
        mask[np.floor(np.arange(interior) * count / interior).astype(int)] = True
    return mask
