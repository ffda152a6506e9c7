"""``area_change``: how far the simplified surface's area is from the original's.

``|simplified area / original area - 1|``: 0 when the area is kept, 0.1 when the result
lost (collapsed parts, flattened bumps) or gained (spikes, folds) a tenth of it. Lower
is better, so ``bench check`` gates it like the built-in errors.
"""

from __future__ import annotations

from bench.core.mesh import Mesh, face_areas
from bench.core.metric import Metric

__all__ = ["AREA_CHANGE", "area_change"]


def area_change(original: Mesh, simplified: Mesh, ctx) -> float | None:
    before = float(face_areas(original.positions, original.faces).sum())
    if before == 0:
        return None  # undefined for a mesh without area: left out of the record
    after = float(face_areas(simplified.positions, simplified.faces).sum())
    return abs(after / before - 1.0)


AREA_CHANGE = Metric(
    name="area_change",
    unit="fraction of the original area",
    higher_is_better=False,
    summary="|simplified surface area / original - 1|",
    compute=area_change,
)
