"""``area_ratio``: the simplified surface's area over the original's.

1 means the area is kept; below 1 the result lost surface (collapsed parts, flattened
bumps), above 1 it gained some (spikes, folds). Neither direction is better in general,
so it is registered as descriptive (``higher_is_better=None``): recorded and tabulated,
never a regression in ``bench check``.
"""

from __future__ import annotations

from bench.mesh import Mesh, face_areas
from bench.metric import Metric

__all__ = ["AREA_RATIO", "area_ratio"]


def area_ratio(original: Mesh, simplified: Mesh, ctx) -> float | None:
    before = float(face_areas(original.positions, original.faces).sum())
    if before == 0:
        return None  # undefined for a mesh without area: left out of the record
    return float(face_areas(simplified.positions, simplified.faces).sum()) / before


AREA_RATIO = Metric(
    name="area_ratio",
    unit="ratio",
    higher_is_better=None,
    summary="simplified surface area / original",
    compute=area_ratio,
)
