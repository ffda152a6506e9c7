"""``quadric``: Garland & Heckbert's quadric error metric on the suite's own engine.

Garland, M. & Heckbert, P. S. Surface simplification using quadric error metrics.
SIGGRAPH 1997: area-weighted plane quadrics per vertex (§5), the optimal position by
solving the 3×3 system, falling back to the best of the endpoints and the midpoint when
it is singular (§4), and boundary-preserving planes perpendicular to boundary faces
(§6.1). UVs and other wedge attributes are carried by the engine (interpolated along the
collapsed edge); the 1998 extension with texture coordinates inside the quadric is not
implemented yet.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

from bench.mesh import Mesh
from bench.method import Method, SimplifyResult
from methods.engine import Policy, simplify_mesh

__all__ = ["Quadric"]


class Quadric(Method):
    name = "quadric"
    version = "1"
    summary = "Garland-Heckbert 97 quadrics on the suite's edge-collapse engine"
    reference = ("Garland & Heckbert, Surface simplification using quadric error metrics, "
                 "SIGGRAPH 1997")
    requires = {"numba": "numba>=0.59"}

    @dataclass
    class Params:
        placement: Literal["optimal", "endpoints", "midpoint"] = "optimal"
        boundary_weight: float = 1000.0
        max_normal_rotation: float = 90.0
        boundary_lock: bool = False

    def policy(self) -> Policy:
        p = self.params
        return Policy(placement=p.placement, boundary_weight=p.boundary_weight,
                      max_normal_rotation=p.max_normal_rotation, boundary_lock=p.boundary_lock)

    def simplify(self, mesh: Mesh, target_faces: int, ctx=None) -> SimplifyResult:
        result = simplify_mesh(mesh, target_faces, self.policy())
        return SimplifyResult(result.mesh, result.stats, result.stop_reason)
