"""``perceptual-mt``: perceptually guided simplification over a Multi-Triangulation.

Williams, Luebke, Cohen, Kelley & Schubert, Perceptually Guided Simplification of Lit,
Textured Meshes, I3D 2003. The pipeline, in :meth:`PerceptualMT.simplify`::

    build_mt        engine collapse sequence -> MT (methods.mt.dag, §2.3, §4)
    preprocess      per node: sphere, normal cones, texel luminance range, texture
                    deviation (methods.mt.bounds, §4)
    node_errors     per view: visibility, silhouettes, contrast, frequency, CSF,
                    imperceptibility distance (§3, §5.2-5.4; methods.mt.csf), each
                    node's the largest of its subtree (§3.4, methods.mt.errors)
    refine          budget refinement with a raise and a lower queue, from the
                    previous view's cut (§5.1), which saves work but does not change
                    the cut (methods.mt.refine)

The MT and its bounds depend on the model and ``texture_weight`` only, so a run builds
them once per model and reuses them for every budget and ``error`` (methods.mt.cache;
``mt_cache`` in the statistics says whether a job built them, and ``mt_seconds`` is 0
when it did not).

The method is view-dependent: the runner images each evaluation view with that
view's cut at the budget (:class:`ViewCuts`), starting each view from the previous
one's cut; the mesh returned by ``simplify`` is the view-independent cut, refined where
the texture deviation of its own triangles is largest (object space;
methods.mt.refine.refine_where_farthest), which the geometric and silhouette metrics
use.

``error`` selects the paper's four compared metrics (§6): ``perceptual`` (the
imperceptibility distance), ``object`` (object-space texture deviation, view
independent), ``screen`` (texture deviation projected to pixels, the view-dependent
APS of Cohen et al. 1998) and ``screen-silhouette`` (screen, times
``silhouette_factor`` = 10 on nodes the cone test puts on the silhouette).

Choices where the paper is vague:

- *Visibility.* Nodes outside the view frustum or back-facing by the silhouette cone
  test get error 0 (§5.3) under all three view-dependent errors, not only the
  perceptual one, so that the comparison isolates the error measure. The cone test is
  Luebke & Erikson's: with ψ the angle between the cone axis and the direction to the
  eye, θ the cone's half-angle and α the half-angle the bounding sphere subtends,
  the node is front-facing if ψ + θ + α < 90°, back-facing if ψ − θ − α > 90°, and
  on the silhouette otherwise. Each error is then raised to the largest of the node's
  descendants' (applying the node applies them), so a node invisible by its own
  bounds whose descendants are not carries their error.
- *Lighting* follows the evaluation renderer (metrics.render): a headlight at the
  eye, so L = H = the direction to the eye; luminance ``T (ka + kd n·l) + ks
  (n·h)^s`` with ka 0.1, kd 0.9, ks 0.3, s 32, clipped at 1 (§5.4's formula with the
  renderer's constants). The range of n·l over a node is bounded from the angle
  between the light and the shading cone's axis, widened by the cone's half-angle and
  by α (the light direction varies over the node). ``lighting="auto"`` takes the
  protocol's shading: ``gouraud`` uses the shading cone (vertex normals), ``flat``
  the silhouette cone (face normals); ``none`` is unlit.
- *Feature size* (§3.2, §5.4): lit meshes are lit per vertex or per face, so a change
  spans the node: the bounding sphere's projected diameter. Unlit textured meshes use
  twice the projected texture deviation ("a texture deviation of ε can create or
  destroy features no larger than 2ε").
- *Observer model.* ``ppd`` pixels per degree of visual angle; the default 32 is a
  512-pixel image on a 96 dpi monitor seen from about 50 cm (1° ≈ 8.7 mm ≈ 33 px). It
  scales every imperceptibility distance by the same factor, so the cuts do not
  depend on it; it sets the reported distances (in multiples of the viewing distance).

Ablation switches (parameters whose defaults are the method; each turns one part of
the perceptual error off, for the ``w2003-ablation`` suite, and changes nothing at its
default):

- ``silhouette_contrast=false``: a node on the silhouette gets the contrast of its
  surface, as a front-facing node, instead of maximal contrast (§3.3, §5.3);
- ``lighting_contrast=false``: the contrast is the intrinsic (texture or material)
  luminance range alone, without §5.4's bound of the lighting over the shading cone
  (the untextured bunny then has contrast only on its silhouettes);
- ``feature_size``: ``sphere`` (the bounding sphere, §5.4's per-vertex lighting),
  ``deviation`` (twice the texture deviation, §3.2 and normal maps) or ``auto`` (the
  sphere when lit, the deviation unlit). With ``deviation`` the perceptual error is
  the ``screen`` error times 4 f_vis(c) / ppd, so it differs from ``screen`` only by
  the contrast's weight;
- ``refinement=scratch``: every view's refinement starts from the coarsest cut, the
  simple top-down algorithm of §5.1, instead of the previous view's cut; the cut is
  the same (methods.mt.refine), only the work differs.

``ppd`` and ``peak_sensitivity`` are the observer's; ``ppd`` and the resolution only
scale every distance (the cuts do not change, see "Observer model"), while
``peak_sensitivity`` moves the contrast threshold (nodes below it get distance 0) and
reshapes f_vis(c).
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Literal

import numpy as np

from bench.core.mesh import Mesh
from bench.core.method import Method, SimplifyResult, bounded
from methods.mt.cache import mt_and_bounds
from methods.mt.errors import ERRORS, FEATURE_SIZES
from methods.mt.refine import REFINEMENTS, Refiner


class ViewCuts:
    """Per-view cuts at a budget for the runner: ``view_cuts(cameras, protocol)``.

    Views are refined in the order given, each from the previous view's cut (the
    first from the view-independent cut); the cuts do not depend on that order, only
    the work does. ``stats`` collects the refinement times.
    """

    def __init__(self, refiner: Refiner, budget: int, lighting: str, specular: str):
        self.refiner, self.budget = refiner, budget
        self.lighting, self.specular = lighting, specular
        self.stats: dict = {}

    def __call__(self, cameras, protocol) -> list[Mesh]:
        r = self.refiner
        r.lighting = protocol.shading if self.lighting == "auto" else self.lighting
        r.specular = protocol.specular if self.specular == "auto" else self.specular == "true"
        meshes, seconds, faces, dist = [], [], [], []
        for camera in cameras:
            info = r.refine_view(camera, self.budget, protocol.resolution)
            seconds.append(info["seconds"])
            faces.append(info["faces"])
            dist.append(info["max_error"])
            meshes.append(r.cut.mesh())
        self.stats = {"view_faces": faces, "refine_ms_median": 1000 * float(np.median(seconds)),
                      "refine_ms": [1000 * s for s in seconds], "view_max_error": dist,
                      "view_lighting": r.lighting, "view_specular": r.specular}
        return meshes


class PerceptualMT(Method):
    name = "perceptual-mt"
    kernels = ("engine", "mt")
    # 2: the MT is built from the engine's logged wedges and UVs (exact, not re-derived);
    # 3: the engine merges each wedge pair once (texture quadrics were counted twice);
    # 4: a node's view error is the largest of its subtree and refinement ranks equal
    #    errors by node index, so a view's cut does not depend on where refinement starts
    # 5: the engine's placement guard, parts and materials kept (the MT's collapses)
    # 6: the MT's collapses go on past a stall with a wider fold-over limit (quadric's
    #    stall rule), so its coarsest cut reaches budgets it stopped above
    # 7: every phase of the stall rule runs
    # 8: a created triangle within one texel of UV names no point in the texture
    #    deviation (solid-coloured parts of atlases inflated it on game assets)
    # 9: the deviation's geometric part from the original vertices handed down the MT
    #    (the far corners of large original triangles inflated it)
    # 10: an exact node (deviation 0) has no silhouette or texture contrast
    # 11: the object-space cut is refined where its own triangles' deviation is largest
    version = "11"
    summary = ("Williams et al. 2003: CSF imperceptibility distance over a Multi-Triangulation, "
               "per-view budget cuts")
    reference = ("Williams, Luebke, Cohen, Kelley & Schubert, Perceptually Guided "
                 "Simplification of Lit, Textured Meshes, I3D 2003")
    view_dependent = True
    shares_work = True  # the MT and its bounds, built once per model (methods.mt.cache)
    requires = {"numba": "numba>=0.59"}

    @dataclass
    class Params:
        error: Literal["perceptual", "object", "screen", "screen-silhouette"] = "perceptual"
        lighting: Literal["auto", "none", "flat", "gouraud"] = "auto"
        specular: Literal["auto", "true", "false"] = "auto"
        ppd: float = bounded(32.0, gt=0)
        peak_sensitivity: float = bounded(200.0, gt=0)
        silhouette_factor: float = bounded(10.0, ge=0)
        texture_weight: float = bounded(1.0, ge=0)
        # ablation switches (the docstring's "Ablation switches"); defaults: the method
        silhouette_contrast: bool = True
        lighting_contrast: bool = True
        feature_size: Literal["auto", "sphere", "deviation"] = "auto"
        refinement: Literal["incremental", "scratch"] = "incremental"

    def simplify(self, mesh: Mesh, target_faces: int, ctx=None) -> SimplifyResult:
        p = self.params
        if p.error not in ERRORS:
            raise ValueError(f"error must be one of {', '.join(ERRORS)}, got {p.error!r}")
        if not p.ppd > 0:
            raise ValueError(f"ppd must be positive, got {p.ppd}")
        if p.feature_size not in FEATURE_SIZES:
            raise ValueError(f"feature_size must be one of {', '.join(FEATURE_SIZES)}, "
                             f"got {p.feature_size!r}")
        if p.refinement not in REFINEMENTS:
            raise ValueError(f"refinement must be one of {', '.join(REFINEMENTS)}, "
                             f"got {p.refinement!r}")
        # one MT and its bounds per (model, parameters), whatever the budget or error
        mt, bounds, source, t_mt = mt_and_bounds(mesh, p.texture_weight, self.version,
                                                 (ctx or {}).get("cache_dir"))
        lighting = "gouraud" if p.lighting == "auto" else p.lighting
        refiner = Refiner(mt, bounds, p.error, lighting, p.specular != "false", p.ppd,
                          p.peak_sensitivity, p.silhouette_factor, p.refinement,
                          silhouette_contrast=p.silhouette_contrast,
                          lighting_contrast=p.lighting_contrast, feature_size=p.feature_size)
        refiner.refine_object(target_faces)
        simplified = refiner.cut.mesh().replace(name=mesh.name, metadata=dict(mesh.metadata))
        stats = {"mt_nodes": mt.n_nodes, "mt_triangles": mt.n_triangles,
                 "mt_coarsest_faces": mt.coarsest_faces, "mt_cache": source,
                 "mt_seconds": t_mt,
                 "preprocess_seconds": bounds.seconds if source == "built" else 0.0,
                 "images": "per view, each view's cut at the budget; geometry and "
                           "silhouettes from the view-independent (object-space) cut"}
        stop = None
        if mt.coarsest_faces > target_faces:
            stop = (f"the MT's coarsest cut has {mt.coarsest_faces} faces, above the target "
                    f"{target_faces} ({mt.stats.get('engine_stop_reason')})")
        result = SimplifyResult(simplified, stats, stop)
        result.view_cuts = ViewCuts(refiner, target_faces, p.lighting, p.specular)
        return result
