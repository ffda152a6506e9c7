"""``memoryless``: Lindstrom & Turk's memoryless simplification on the suite's engine.

Lindstrom, P. & Turk, G. Fast and memory efficient polygonal simplification. IEEE
Visualization 1998; Evaluation of memoryless simplification. IEEE TVCG 5(2), 1999.
Summarised in Lindstrom & Turk 2000, §4.1. No error is carried from the original mesh:
each collapse is placed and costed from the current triangles around the edge only —
volume preservation, boundary preservation, then volume and boundary optimisation and
triangle shape, added as linear constraints while they are α-compatible
(:mod:`methods.engine.terms.lindstrom_turk`). The cost is the same volume and boundary error at the
chosen point.

New texture coordinates come from the R^5 oriented volumes of Lindstrom & Turk 2000,
§4.1.1 (:func:`methods.engine.terms.lindstrom_turk.r5_texture_coordinates`), computed for every
wedge around the merged vertex from the triangles of its own texture patch, with κ per
patch; a degenerate patch profile falls back to interpolation along the edge.
"""

from __future__ import annotations

from dataclasses import dataclass

from bench.core.mesh import Mesh
from bench.core.method import Method, SimplifyResult, bounded
from methods.engine.policy import Policy
from methods.engine.simplify import simplify_mesh

__all__ = ["Memoryless"]


class Memoryless(Method):
    name = "memoryless"
    kernels = ("engine",)
    # 2: R^5 texture coordinates; 3: superseded queue entries dropped; 4: the engine's
    # placement guard (its fallback for a degenerate profile), parts and materials kept
    version = "4"
    summary = "Lindstrom-Turk 98/99 volume and boundary preserving collapses (own engine)"
    reference = ("Lindstrom & Turk, Fast and memory efficient polygonal simplification, "
                 "IEEE Visualization 1998")
    requires = {"numba": "numba>=0.59"}

    @dataclass
    class Params:
        max_normal_rotation: float = bounded(90.0, gt=0, le=180)
        boundary_lock: bool = False

    def policy(self) -> Policy:
        return Policy(placement="memoryless", quadric_weight=0.0, memoryless_weight=1.0,
                      boundary_weight=0.0, max_normal_rotation=self.params.max_normal_rotation,
                      boundary_lock=self.params.boundary_lock)

    def simplify(self, mesh: Mesh, target_faces: int, ctx=None) -> SimplifyResult:
        result = simplify_mesh(mesh, target_faces, self.policy())
        return SimplifyResult(result.mesh, result.stats, result.stop_reason)
