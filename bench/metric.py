"""The interface of evaluation metrics.

A metric is a :class:`Metric` registered under the ``bench.metrics`` entry-point group.
It carries its unit and direction, so reports and the regression gate know whether a
change is an improvement without a table of special cases.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from bench.mesh import Mesh

__all__ = ["Metric"]


@dataclass(frozen=True)
class Metric:
    """One scalar figure of a simplified mesh.

    Attributes
    ----------
    name : str
    unit : str
        "faces", "fraction of bbox diagonal", "luminance (0-255)", ...
    higher_is_better : bool or None
        None for descriptive counts with no better direction.
    summary : str
    compute : callable (original: Mesh, simplified: Mesh, ctx) -> float
    requires : dict
        import name -> pip requirement of optional backends.
    """

    name: str
    unit: str
    higher_is_better: bool | None
    summary: str
    compute: Callable[[Mesh, Mesh, Any], float]
    requires: dict = field(default_factory=dict)

    @property
    def direction(self) -> str:
        return {True: "higher is better", False: "lower is better", None: "descriptive"}[
            self.higher_is_better]
