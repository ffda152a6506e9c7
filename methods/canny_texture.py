"""``canny-texture``: an engine cost plus the texture-border penalty of González,
Castelló & Chover 2007 (seed 003, §3, equations 1-2, Figure 3).

The texture's Canny borders are found once (:func:`methods.engine.canny.texture_borders`,
sigma 0.75, thresholds 0.5 / 0.6 of the maximum gradient magnitude, MATLAB's
convention). While simplifying, an edge whose UV segment crosses a border pixel, in
any of its faces' UV charts, costs extra: the area of its faces over the mesh's total
area, on geometry normalised to a unit bounding-box diagonal. The base cost is the
quadric of ``quadric`` (with its texture quadrics, default) or the memoryless cost;
``canny_weight`` scales the penalty (the paper adds it with weight 1).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

from bench.errors import InputError
from bench.mesh import Mesh
from bench.method import Method, SimplifyResult
from methods.engine.policy import Policy
from methods.engine.simplify import simplify_mesh

__all__ = ["CannyTexture", "crossing_share"]


class CannyTexture(Method):
    name = "canny-texture"
    # 2: quadric base with texture quadrics; 3: superseded entries dropped; 4: a wedge
    # merges once per collapse (the quadric base counted it once per face of the edge)
    version = "4"
    summary = "quadric (or memoryless) cost + Canny texture-border penalty (own engine)"
    reference = ("González, Castelló & Chover, A texture-based metric extension for "
                 "simplification methods, GRAPP 2007")
    requires = {"numba": "numba>=0.59", "skimage": "scikit-image>=0.22"}
    needs_uv = True

    @dataclass
    class Params:
        base: Literal["quadric", "memoryless"] = "quadric"
        canny_weight: float = 1.0
        sigma: float = 0.75
        low: float = 0.5
        high: float = 0.6
        max_normal_rotation: float = 90.0
        texture_weight: float = 1.0  # of the quadric base, as in ``quadric``

    def policy(self) -> Policy:
        p = self.params
        if p.base == "memoryless":
            return Policy(placement="memoryless", quadric_weight=0.0, memoryless_weight=1.0,
                          boundary_weight=0.0, canny_weight=p.canny_weight,
                          max_normal_rotation=p.max_normal_rotation)
        return Policy(canny_weight=p.canny_weight, max_normal_rotation=p.max_normal_rotation,
                      texture_weight=p.texture_weight)

    def simplify(self, mesh: Mesh, target_faces: int, ctx=None) -> SimplifyResult:
        from methods.engine.canny import texture_borders

        if mesh.uv is None or mesh.texture is None:
            raise InputError(f"{mesh.name}: canny-texture needs a texture and UVs; use "
                             "--method quadric")
        p = self.params
        borders = texture_borders(mesh.texture, sigma=p.sigma, low=p.low, high=p.high)
        result = simplify_mesh(mesh, target_faces, self.policy(), borders=borders)
        stats = dict(result.stats)
        stats["border_pixels"] = int(borders.sum())
        stats["crossing_edges_before"], stats["crossing_share_before"] = crossing_share(mesh, borders)
        stats["crossing_edges_after"], stats["crossing_share_after"] = crossing_share(
            result.mesh, borders)
        return SimplifyResult(result.mesh, stats, result.stop_reason,
                              artifacts={"texture borders and penalised edges (red)":
                                         _penalised_edges_image(mesh, borders)})


def _penalised_edges_image(mesh: Mesh, borders):
    """The border image with the input's penalised edges in red (the paper's Figure 3
    input), magnified so thin lines stay visible on small textures."""
    from methods.engine.canny import border_image_with_edges, edge_penalties

    _, _, crossing = edge_penalties(mesh, borders=borders)
    scale = max(1, 1024 // max(borders.shape))
    return border_image_with_edges(mesh, borders, crossing, scale=scale)


def crossing_share(mesh: Mesh, borders) -> tuple[int, float]:
    """(number, share) of the mesh's welded edges whose UV segment crosses a border."""
    from methods.engine.canny import edge_penalties

    _, _, crossing = edge_penalties(mesh, borders=borders)
    return int(crossing.sum()), float(crossing.mean()) if len(crossing) else 0.0
