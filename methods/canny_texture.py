"""``canny-texture``: an engine cost plus the texture-border penalty of González,
Castelló & Chover 2007 (seed 003, §3, equations 1-2, Figure 3).

The texture's Canny borders are found once (:func:`methods.engine.terms.canny.texture_borders`,
sigma 0.75, thresholds 0.5 / 0.6 of the maximum gradient magnitude, MATLAB's
convention). While simplifying, an edge whose UV segment crosses a border pixel, in
any of its faces' UV charts, costs extra: equation 2 adds to its base cost c_e the area
of its faces over the mesh's total area, r_e = a_e / A_T. The base cost is the quadric
of ``quadric`` (with its texture quadrics, default) or the memoryless cost;
``canny_weight`` scales the penalty (the paper adds it with weight 1).

The penalty's units (``canny_units``), where the paper is open:

* r_e is a pure number and c_e is not. The paper's base is "our own geometric
  simplification method based on edge collapse operations that make use of quadrics"
  (§1, §4), so c_e is an area-weighted squared distance in the model's own units,
  which the paper neither gives nor normalises (its models have 308 to 5,400 polygons,
  Table 1, simplified to 75 %, 50 % and 25 % of their edges). The literal sum
  c_e + r_e therefore has no fixed balance: it depends on the model's size, and here on
  the engine's normalisation to a unit bounding-box diagonal, where quadric costs are
  tiny (the torus's mean initial cost is 7.6e-12, its mean r_e 3.1e-5): the penalty
  outweighed every quadric, the collapses went through the non-crossing edges first
  whatever their geometric error, and at 2 % of the torus d_rms was 29.8 against
  quadric's 15.6 (``reports/baselines/ci.json``, version 4).
* What the paper wants of the balance is in its own words: the penalty changes "the
  order of the collapses" (§3.1) so that "the regions with great changes in the
  texture are simplified later than the others that have fewer changes in the texture
  and a similar previous error" (§5), the area measuring how "noticeable" a removal is
  (§3.2). The penalty is a reordering among collapses of comparable base cost, not a
  partition of the edges. So ``canny_units="base-cost"`` (default) states r_e in the
  base cost's units, measured on the mesh before the first collapse: the penalty is
  r_e × c̄ / r̄, with c̄ the mean initial base cost of the edges and r̄ their mean area
  ratio (:func:`methods.engine.simplify._canny_units`). At weight 1, an edge of average
  area that crosses a border costs one average collapse more; larger faces more, in
  proportion to their area, as equation 2 says. Penalty and base cost then scale
  together: with a geometric base (``texture_weight=0``, or ``base="memoryless"``)
  changing the working diagonal (:data:`methods.engine.simplify.WORKING_DIAGONAL`),
  which version 4 depended on, chooses the same collapses
  (``tests/test_engine_methods.py``). The default base's texture quadrics add UV
  distances to lengths, so that base's own choices move with the normalisation,
  penalty or not. The unit is fixed once, so during the
  simplification the penalty and the base cost evolve as equation 2's terms do in fixed
  units: areas grow as faces are removed, accumulated quadrics grow faster, and the
  penalty matters most in the first half of the collapses, the range the paper shows.
  A mesh whose base costs are zero but for rounding (flat faces, affine UVs) has no
  scale to measure; its penalty is r_e / r̄ (see ``_canny_units``).
* ``canny_units="area"`` is the version-4 behaviour, r_e added as it is to costs at
  unit diagonal, kept to compare with (the ``g2007`` suite runs both).

The statistics give the crossing edges before and after (``crossing_share_*``, of the
welded edges) and, with ``canny_units="base-cost"`` and a non-zero weight, the measured
unit: ``canny_base_cost`` (c̄; 0 when the costs were rounding noise),
``canny_cost_noise`` (the magnitude of the most negative initial cost, the rounding
noise) and ``canny_edges_costed`` (the edges with a finite initial cost, over which c̄
and r̄ are means).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

from bench.core.errors import InputError
from bench.core.mesh import Mesh
from bench.core.method import Method, SimplifyResult, bounded
from methods.engine.policy import MAX_MOVE, Policy
from methods.engine.simplify import simplify_mesh

__all__ = ["CannyTexture", "crossing_share"]


class CannyTexture(Method):
    name = "canny-texture"
    kernels = ("engine", "canny")
    # 2: quadric base with texture quadrics; 3: superseded entries dropped; 4: a wedge
    # merges once per collapse (the quadric base counted it once per face of the edge);
    # 5: the penalty in the base cost's units (canny_units="base-cost"): as an area
    # ratio added to quadrics at unit diagonal it outweighed every quadric cost (by
    # 4 million times the mean on the torus) and so depended on our normalisation
    # 6: the engine's placement guard, parts and materials kept; 7: the engine's move
    # bound, the seam rule released when stalled (as ``quadric`` 7)
    version = "7"
    summary = "quadric (or memoryless) cost + Canny texture-border penalty (own engine)"
    reference = ("González, Castelló & Chover, A texture-based metric extension for "
                 "simplification methods, GRAPP 2007")
    requires = {"numba": "numba>=0.59", "skimage": "scikit-image>=0.22"}
    needs_uv = True

    @dataclass
    class Params:
        base: Literal["quadric", "memoryless"] = "quadric"
        canny_weight: float = bounded(1.0, ge=0)
        #: "base-cost": the area ratio in the base cost's units (see the module notes);
        #: "area": the area ratio added as it is to costs at unit diagonal (version 4)
        canny_units: Literal["base-cost", "area"] = "base-cost"
        sigma: float = bounded(0.75, ge=0)
        low: float = bounded(0.5, ge=0, le=1)
        high: float = bounded(0.6, ge=0, le=1)
        max_normal_rotation: float = bounded(90.0, gt=0, le=180)
        texture_weight: float = bounded(1.0, ge=0)  # of the quadric base, as in ``quadric``
        #: the engine's move bound (a fraction of the diagonal), as in ``quadric``
        max_move: float = bounded(MAX_MOVE, gt=0)

    def policy(self) -> Policy:
        p = self.params
        if p.base == "memoryless":
            return Policy(placement="memoryless", quadric_weight=0.0, memoryless_weight=1.0,
                          boundary_weight=0.0, canny_weight=p.canny_weight,
                          canny_units=p.canny_units,
                          max_normal_rotation=p.max_normal_rotation, max_move=p.max_move,
                          stall_seams=True)
        return Policy(canny_weight=p.canny_weight, canny_units=p.canny_units,
                      max_normal_rotation=p.max_normal_rotation,
                      texture_weight=p.texture_weight, max_move=p.max_move, stall_seams=True)

    def simplify(self, mesh: Mesh, target_faces: int, ctx=None) -> SimplifyResult:
        from methods.engine.terms.canny import texture_borders

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
    from methods.engine.terms.canny import border_image_with_edges, edge_penalties

    _, _, crossing = edge_penalties(mesh, borders=borders)
    scale = max(1, 1024 // max(borders.shape))
    return border_image_with_edges(mesh, borders, crossing, scale=scale)


def crossing_share(mesh: Mesh, borders) -> tuple[int, float]:
    """(number, share) of the mesh's welded edges whose UV segment crosses a border."""
    from methods.engine.terms.canny import edge_penalties

    _, _, crossing = edge_penalties(mesh, borders=borders)
    return int(crossing.sum()), float(crossing.mean()) if len(crossing) else 0.0
