"""``quadric``: Garland & Heckbert's quadric error metric on the suite's own engine.

Garland, M. & Heckbert, P. S. Surface simplification using quadric error metrics.
SIGGRAPH 1997: area-weighted plane quadrics per vertex (§5), the optimal position by
solving the 3×3 system, falling back to the best of the endpoints and the midpoint when
it is singular (§4), and boundary-preserving planes perpendicular to boundary faces
(§6.1).

For meshes with UVs, the 1998 extension (Garland & Heckbert, Simplifying surfaces with
color and texture using quadric error metrics, IEEE Visualization 1998): one quadric
per wedge over (x, y, z, w·u, w·v), so a seam vertex has a quadric per side; the
position minimises the sum over the merged vertex's wedges of each wedge quadric
minimised over its own UV, and each wedge's new UV is that minimiser. ``texture_weight``
(w, on geometry normalised to a unit bounding-box diagonal) defaults to 1, as MeshLab's
``extratcoordw``; 0 gives the 1997 metric with UVs interpolated along the edge.

A collapse leaves the planes of the faces it replaces by at most a tenth of the model's
bounding-box diagonal (the engine's move bound, ``Policy.max_move``): on a coarse
multi-part asset the cheapest collapses left under the seam rule would otherwise drag a
corner across a part. When no valid collapse remains above the target, the run goes on
with the seam rule released, then with the fold-over limit widened to 120°, 150° and
180° in turn, then without the move bound (``stall="widen"``, the engine's stall rule:
``Policy.stall_rotations``); ``stall="stop"`` has neither the bound nor the phases,
and stops there and says why.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

from bench.core.mesh import Mesh
from bench.core.method import Method, SimplifyResult, bounded
from methods.engine.policy import MAX_MOVE, STALL_ROTATIONS, Policy
from methods.engine.simplify import simplify_mesh

__all__ = ["Quadric"]


class Quadric(Method):
    name = "quadric"
    kernels = ("engine",)
    # 2: texture quadrics (GH98) on meshes with UVs; 3: a wedge merges once per
    # collapse (its quadric and UV were counted once per face of the edge); 4: the
    # placement guard, parts and materials kept (methods.engine: real assets); 5: the
    # stall rule (a stalled run goes on with a wider fold-over limit; only results that
    # stopped above their target change); 7: the move bound, the seam rule released
    # first when stalled (the milk truck's cut-off corners; changes results where a
    # collapse would leave its faces' planes by more than a tenth of the diagonal)
    version = "7"
    summary = "Garland-Heckbert 97/98 quadrics (texture per wedge) on the suite's engine"
    reference = ("Garland & Heckbert, Surface simplification using quadric error metrics, "
                 "SIGGRAPH 1997; ... with color and texture, IEEE Visualization 1998")
    requires = {"numba": "numba>=0.59"}

    @dataclass
    class Params:
        placement: Literal["optimal", "endpoints", "midpoint"] = "optimal"
        boundary_weight: float = bounded(1000.0, ge=0)
        max_normal_rotation: float = bounded(90.0, gt=0, le=180)
        boundary_lock: bool = False
        texture_weight: float = bounded(1.0, ge=0)
        stall: Literal["widen", "stop"] = "widen"
        #: the engine's move bound with ``stall="widen"`` (a fraction of the diagonal)
        max_move: float = bounded(MAX_MOVE, gt=0)

    def policy(self) -> Policy:
        p = self.params
        widen = p.stall == "widen"
        return Policy(placement=p.placement, boundary_weight=p.boundary_weight,
                      max_normal_rotation=p.max_normal_rotation, boundary_lock=p.boundary_lock,
                      texture_weight=p.texture_weight,
                      stall_rotations=STALL_ROTATIONS if widen else (),
                      max_move=p.max_move if widen else float("inf"), stall_seams=widen)

    def simplify(self, mesh: Mesh, target_faces: int, ctx=None) -> SimplifyResult:
        result = simplify_mesh(mesh, target_faces, self.policy())
        return SimplifyResult(result.mesh, result.stats, result.stop_reason)
