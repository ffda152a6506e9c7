"""The interface of evaluation metrics.

A metric is a :class:`Metric` registered under the ``bench.metrics`` entry-point group,
exactly as the built-ins are in the suite's own ``pyproject.toml``::

    [project.entry-points."bench.metrics"]
    my_metric = "my_package.module:MY_METRIC"

It carries its unit and direction, so reports and the regression gate know whether a
change is an improvement without a table of special cases, and it declares what it
needs (:data:`NEEDS`): the protocol (:func:`metrics.protocol.evaluate`) computes each
shared input once per evaluation — renders once, samples the Hausdorff distance once —
and hands every registered metric the inputs it asked for in ``ctx``.

Build one with keywords, so that the direction reads as what it is::

    AREA_RATIO = Metric(name="area_ratio", unit="ratio", higher_is_better=None,
                        summary="simplified surface area / original", compute=area_ratio)

(The built-ins' positional form, ``Metric(name, unit, higher_is_better, summary,
compute)``, still works.)

``compute(original, simplified, ctx)`` returns a number, or a :class:`Value` (a float
that also carries per-view values, recorded under the record's ``per_view``). ``None`` or
NaN means "undefined for this model" (e.g. ``exterior_share`` on a model that does not
classify its faces): the metric is left out of that record. A metric that raises is
recorded as failed for that metric only (see :func:`metrics.protocol.evaluate`).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

from bench.core.mesh import Mesh

__all__ = ["Metric", "Value", "NEEDS"]

#: What a metric may ask for in :attr:`Metric.needs`, and where it finds it. ``ctx``
#: always holds ``"protocol"`` (the :class:`metrics.protocol.Protocol` of the evaluation).
NEEDS = {
    "meshes": "the original and simplified Mesh: the first two arguments (always given)",
    "images": "ctx['original_images'], ctx['simplified_images']: ndarray of shape "
              "(24, R, R, 3) uint8, the protocol views (a view-dependent result's view i "
              "shows that view's cut)",
    "view_meshes": "ctx['view_meshes']: a view-dependent result's 24 per-view meshes, or "
                   "None for a view-independent result",
    "hausdorff": "ctx['hausdorff']: the dict of metrics.geometry.hausdorff (Metro "
                 "distances both ways), sampled once per evaluation",
    "silhouette": "ctx['silhouette']: metrics.silhouette.SilhouetteHistogram of the "
                  "simplified mesh over the 20 dodecahedron views",
    "topology": "ctx['topology']: the dict of metrics.topology.counts",
    "parts": "ctx['parts']: the dict of metrics.parts.parts_lost (components and materials "
             "of the original with no face left)",
    "screen": "ctx['screen']: the screen-size evaluation (metrics.screen.summarise: the "
              "curve and switch sizes), present only when Protocol.screen_sizes is set",
}


class Value(float):
    """A metric's value with its per-view values: ``Value(2.5, per_view=[...])``.

    It is a float (compares, formats and sums as its scalar value); the protocol stores
    ``per_view`` in the record's ``per_view[name]``.
    """

    per_view: tuple[float, ...]

    def __new__(cls, value: float, per_view: Sequence[float] = ()):
        self = super().__new__(cls, value)
        self.per_view = tuple(float(v) for v in per_view)
        return self

    def __reduce__(self):  # pickles (worker processes) with its per-view values
        return (Value, (float(self), self.per_view))


@dataclass(frozen=True)
class Metric:
    """One scalar figure of a simplified mesh.

    Attributes
    ----------
    name : str
    unit : str
        "faces", "fraction of bbox diagonal", "luminance (0-255)", ...
    higher_is_better : bool or None
        The direction ``bench check`` judges by; None for descriptive counts, which are
        recorded and tabulated but never a regression.
    summary : str
    compute : callable (original: Mesh, simplified: Mesh, ctx: dict) -> float or Value
    requires : dict
        import name -> pip requirement of optional backends.
    needs : frozenset of str
        Keys of :data:`NEEDS`: the shared inputs the protocol must put in ``ctx``.
    """

    name: str
    unit: str
    higher_is_better: bool | None
    summary: str
    compute: Callable[[Mesh, Mesh, Any], float]
    requires: dict = field(default_factory=dict)
    needs: frozenset = frozenset({"meshes"})

    def __post_init__(self):
        needs = frozenset({self.needs} if isinstance(self.needs, str) else self.needs)
        unknown = sorted(needs - NEEDS.keys())
        if unknown:
            raise ValueError(f"metric {self.name!r} needs {unknown}, which the protocol does "
                             f"not provide; choose from {sorted(NEEDS)}")
        object.__setattr__(self, "needs", needs | {"meshes"})

    @property
    def direction(self) -> str:
        return {True: "higher is better", False: "lower is better", None: "descriptive"}[
            self.higher_is_better]
