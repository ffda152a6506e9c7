"""``entropy-twin``: viewpoint-entropy simplification of game meshes with twin edges.

González, Gumbau, Chover & Castelló, Mesh simplification for interactive applications,
WSCG 2008 (seed 004_7b79a0217de1c060.txt, §3), with the cost of Castelló et al. 2007.
The pipeline of Algorithm 1:

1. images: face-id buffers of the mesh in ``views`` views (the 20 vertices of a regular
   dodecahedron around the original's bounding sphere, ``resolution``² pixels), drawn
   by our numba scan converter (:mod:`methods.imaging.raster`); per view and face the number
   of pixels it covers, its *projected area* a_i;
2. cost of a half-edge collapse (both directions simulated, the cheaper kept):
   ``sum_v |ΔH_v|``, the change of the viewpoint entropy
   ``H_v = -sum_i (a_i / a_t) log(a_i / a_t)`` in every view, plus on textured meshes
   the Canny texture-border term of González et al. 2007 (``canny_weight``, as
   ``canny-texture``). A candidate is costed by re-rendering only its screen
   rectangles (:mod:`methods.imaging.region`, in "face ids only" mode): only the faces
   whose pixel count changes there enter the entropy sums, so no view is re-rendered
   whole, and after each collapse the counts are updated from the changed pixels;
3. Algorithm 2 (real, twin and fake edges) is what the shared engine's welded topology
   does by construction: the collapse of a welded edge collapses every wedge pair of
   it at once, so at a UV seam or where two sub-meshes (materials) meet, the *twin*
   edge joining the duplicated vertices is collapsed with the *real* one, and a
   duplicate of the removed vertex that has no twin (a corner where three charts meet,
   or a seam vertex collapsed onto a chart's interior) is *translated* onto the kept
   vertex together with its faces — the paper's alternative to a fake vertex ("Other
   vertices are simply translated to cap the holes"). A fake vertex is needed only by
   index-only multiresolution schemes; here no seam can open, because the welded
   topology is never split (``seam_cracks`` counts none: the chords of a simplified
   hole keep their ends on the hole, see :mod:`metrics.topology`). Every collapse
   is of a real edge, so the statistics count the collapses (``collapses``), those
   that collapsed a twin with it (``twin_collapses``), those that translated stranded
   duplicates (``fake_collapses``: where the paper would add a fake edge) and the
   duplicates so translated (``translated_duplicates``); no fake vertex is ever made,
   so none is counted;
4. texture-coordinate correction (§3, the α, β equations; ``uv_correction``): a
   duplicate whose position changes takes the UV that the texture map of one of its own
   triangles gives the new position (:func:`methods.engine.barycentric_uv`);
5. normals rebuilt at the end (Algorithm 3; :func:`rebuild_normals`) with the angle
   threshold ``normals_angle``.

Choices where the paper is vague, and why:

* entropy in natural logarithms, the background counted as one more "face"
  (``background=True``, Vázquez et al.'s definition: a collapse that shrinks the
  silhouette changes the entropy through the background's share too); with
  ``background=False`` only faces count and a_t is their sum;
* the views: the dodecahedron of Lindstrom & Turk 2000 (the paper says only "several
  viewpoints uniformly distributed"); no anti-aliasing; back faces are drawn;
* ``seam_rule`` (the engine's rule that a seam vertex moves only along its seam) is off
  by default: the paper's twin/fake mechanism lets any real edge collapse, and the UV
  correction is its answer to the stretching that follows. Turning it on keeps every
  UV chart whole instead;
* open boundaries (the paper's game meshes are closed): ``boundary_rule`` keeps a
  boundary vertex when its edge leads inside, since the entropy barely notices a hole
  growing into a surface seen from few views (the textured bunny's bottom);
* re-costing after a collapse is the engine's lazy neighbourhood scheme, as Algorithm 1
  re-costs the "neighbour edges of a". It is not exact for this cost: a collapse can
  change the pixel count of a face far away on the surface (occlusion), and without the
  background it changes the total a_t, so queued costs elsewhere go slightly stale,
  as Lindstrom & Turk's image costs do;
* the Canny term: González 2007 adds its penalty (an edge's incident area over the
  total area) to the base cost with weight 1. Our entropy cost is a sum over views of
  changes that are each of the order of a projected-area share, so the penalty is
  added once per view (``canny_weight`` × ``views``); with weight 1 alone the median
  penalty of a crossing edge was 8-12 times smaller than the median entropy cost of
  the collapses that take ``bunny-textured-4698`` and ``crate`` to half their faces.
  Both terms are pure numbers (shares of pixels, shares of area) measured on images
  framed by the bounding sphere, so their sum does not depend on the mesh's size or on
  the engine's normalisation, and the penalty stays an area ratio here
  (``Policy.canny_units="area"``); ``canny-texture`` adds it to quadrics, which are
  lengths, and states it in their units instead. §3 of the paper only says that
  crossing edges are "penalised by incrementing their cost";
* pre-simplification (not in the paper, whose models had at most 13,810 faces): meshes
  with more than ``PRESIMPLIFY_RATIO`` (20) times the target faces are first brought
  to that size by the engine's Garland-Heckbert 1998 quadrics (seams closed, charts
  kept), as image-driven does with memoryless; Table 1's sizes are left untouched.
  ``presimplify_faces=-1`` turns it off;
* ``placement="optimal"`` puts the kept vertex at the quadric's optimal point (a
  full-edge collapse) instead of an endpoint, for ablation only: the paper's half-edge
  collapse is the default;
* the move bound (not in the paper, whose meshes were single closed surfaces): the cost
  has no geometric term, so on multi-part game assets a collapse could close a wheel
  arch or slice a cab that few views see (the glTF milk truck at 362 faces: Hausdorff
  max 3.1 times ``qslim-texture``'s). A collapse whose kept position lies farther than
  ``move_bound`` (0.7) times the target's face size, sqrt(surface area / target faces),
  off the plane of a face around the edge is rejected (the engine's
  ``Policy.max_move``), and lifted only if the run stalls. The bound scales with the
  budget: a fixed fraction of the diagonal that held the truck (5 %) forced
  ``bunny-textured-815`` at 100 faces to finish with the bound lifted, at 0.245 of
  the diagonal (0.066 without). Since version 5 it bounds the sum of each vertex's
  moves (``Policy.move_memory``): bounded one collapse at a time, a vertex walked
  across the `vehicle` analogue's cab in small steps, leaving a face 0.039 of the
  diagonal off the roof (Hausdorff max 3.5 times ``qslim-texture``'s at 362 faces).
  When the run stalls, the sum is dropped first (each collapse bounded alone), then
  the bound;
* ``normals_angle`` = 60° by default, the smoothing angle of Unity's model importer:
  a crate's 90° edges stay hard, a sphere's facets (a few degrees apart, tens of
  degrees after heavy simplification) are smoothed.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np

from bench.core import progress
from bench.core.errors import ParamError
from bench.core.mesh import Mesh, face_areas
from bench.core.method import Method, SimplifyResult, bounded
from methods.engine.policy import Policy
from methods.engine.scale import at_workable_scale
from methods.engine.simplify import simplify_mesh

__all__ = ["EntropyTwin", "viewpoint_entropy", "entropy_term", "rebuild_normals",
           "NORMALS_ANGLE"]

#: Default smoothing angle of :func:`rebuild_normals` in degrees (see the module notes).
NORMALS_ANGLE = 60.0
#: Default pre-simplification target as a multiple of the final one (see the notes).
PRESIMPLIFY_RATIO = 20


def viewpoint_entropy(ids: np.ndarray, background: bool = True) -> np.ndarray:
    """Viewpoint entropy of each view from face-id buffers (a plain NumPy oracle).

    Parameters
    ----------
    ids : ndarray of shape (V, H, W) int
        Face seen at each pixel, -1 for the background (:func:`methods.imaging.raster.face_id_buffers`).
    background : bool
        Count the background pixels as one more "face" (Vázquez et al.).

    Returns
    -------
    ndarray of shape (V,) float64
        ``H_v = -sum_i (a_i / a_t) log(a_i / a_t)`` in nats, a_i the pixels of face i
        (and of the background), a_t their sum; 0 for a view with nothing counted.
    """
    ids = np.asarray(ids)
    if ids.ndim != 3:
        raise ValueError(f"ids must have shape (V, H, W), got {ids.shape}")
    out = np.zeros(len(ids))
    for h, view in enumerate(ids):
        values = view.reshape(-1)
        if not background:
            values = values[values >= 0]
        _, counts = np.unique(values, return_counts=True)
        if counts.sum() == 0:
            continue
        share = counts / counts.sum()
        out[h] = float(-(share * np.log(share)).sum())
    return out


def entropy_term(mesh: Mesh, views: int = 20, resolution: int = 256,
                 background: bool = True, weight: float = 1.0):
    """The engine's viewpoint-entropy term for ``mesh`` (the original model): an
    :class:`methods.imaging.region.ImageTerm` that renders face ids only (equation 8 off)
    and costs a collapse by ``weight`` × sum over views of |ΔH_v|."""
    from methods.imaging.state import ImageTerm
    from methods.imaging.views import view_directions
    from metrics.views import cameras_for

    cameras = cameras_for(mesh, view_directions(views))
    reference = np.zeros((views, resolution, resolution))  # no luminance is compared
    return ImageTerm(tuple(cameras), reference, weight=0.0, entropy_weight=weight,
                     entropy_background=background)


def _corner_normals(mesh: Mesh, cos_limit: float) -> np.ndarray:
    """(3m, 3) each corner's normal for :func:`rebuild_normals`: the normalised sum of
    the unit normals of the faces at its position within the angle whose cosine is
    ``cos_limit`` of its own face's normal (the area-weighted normal of the position
    where that sum vanishes)."""
    m = mesh.n_faces
    w = mesh.welded
    fn = mesh.face_normals  # unit, zero for degenerate faces
    corner_vertex = w.faces.reshape(-1).astype(np.int64)  # welded vertex of each corner
    corner_face = np.repeat(np.arange(m), 3)
    order = np.argsort(corner_vertex, kind="stable")
    sv = corner_vertex[order]
    n = len(order)
    start = np.searchsorted(sv, sv, side="left")
    end = np.searchsorted(sv, sv, side="right")
    own = fn[corner_face[order]]
    acc = np.zeros((n, 3))
    widest = int((end - start).max())
    idx = np.arange(n)
    for d in range(-widest + 1, widest):  # every pair of corners at one position
        j = idx + d
        ok = (j >= start) & (j < end)
        other = np.zeros((n, 3))
        other[ok] = fn[corner_face[order[j[ok]]]]
        close = ok & (np.einsum("ij,ij->i", own, other) >= cos_limit - 1e-12)
        acc[close] += other[close]
    length = np.linalg.norm(acc, axis=1)
    smooth = np.zeros((n, 3))
    good = length > 0
    smooth[good] = acc[good] / length[good, None]
    if not good.all():  # degenerate faces: the area-weighted normal of the position
        fallback = mesh.replace(normals=None).vertex_normals[mesh.faces.reshape(-1)[order]]
        smooth[~good] = fallback[~good]
    normals = np.empty((n, 3))
    normals[order] = smooth
    return normals


def rebuild_normals(mesh: Mesh, angle: float = NORMALS_ANGLE) -> Mesh:
    """Algorithm 3 of González et al. 2008: per-corner normals smoothed across faces
    that meet at a position at less than ``angle`` degrees.

    Every face corner starts with its face's unit normal ("duplicate vertices so that
    each vertex is used by exactly one triangle"); a corner's normal becomes the
    normalised sum of the unit normals of the faces around the same position whose
    normal is within ``angle`` of its own face's (itself included), as the paper's
    pseudo-code adds ``Normal(Face2)`` for every such pair. Corners with the same render
    vertex and the same resulting normal share one vertex again, so render vertices
    split only along creases. A corner of a degenerate face takes the area-weighted
    normal of its position.

    Parameters
    ----------
    mesh : Mesh
    angle : float
        Degrees, in [0, 180]; 0 keeps every face flat.

    Returns
    -------
    Mesh
        Same positions, faces and attributes per corner, with ``normals`` set.
    """
    if not 0.0 <= angle <= 180.0:
        raise ValueError(f"normals angle must be in [0, 180] degrees, got {angle}")
    m = mesh.n_faces
    if m == 0:
        return mesh
    normals = _corner_normals(mesh, math.cos(math.radians(angle)))
    # render vertices: one per (original render vertex, normal)
    wedge = mesh.faces.reshape(-1).astype(np.int64)
    key = np.concatenate([wedge[:, None], np.ascontiguousarray(normals).view(np.int64)],
                         axis=1)
    _, first, inverse = np.unique(key, axis=0, return_index=True, return_inverse=True)
    src = wedge[first]
    return mesh.replace(
        positions=mesh.positions[src], faces=inverse.reshape(-1, 3).astype(np.int32),
        uv=None if mesh.uv is None else mesh.uv[src],
        colors=None if mesh.colors is None else mesh.colors[src],
        normals=normals[first])


class EntropyTwin(Method):
    name = "entropy-twin"
    kernels = ("engine", "imaging", "canny")
    # 2: the texture-quadric pre-simplification merges each wedge once; 3: the engine's
    # placement guard, parts and materials kept; 4: the move bound; 5: the bound holds
    # for the sum of a vertex's moves
    version = "5"
    summary = ("half-edge collapses by viewpoint-entropy change over 20 views, twin edges "
               "at seams, UV correction, normals rebuilt")
    reference = ("González, Gumbau, Chover & Castelló, Mesh simplification for interactive "
                 "applications, WSCG 2008")
    requires = {"numba": "numba>=0.59", "skimage": "scikit-image>=0.22"}

    @dataclass
    class Params:
        views: int = bounded(20, ge=1)
        resolution: int = bounded(256, ge=8, le=2048)
        #: count the background as a face in the entropy (Vázquez et al.)
        background: bool = True
        #: the Canny texture-border term (González 2007); used on textured meshes only
        canny: bool = True
        #: per view: the penalty enters the cost canny_weight x views times
        canny_weight: float = bounded(1.0, ge=0)
        #: the α, β texture-coordinate correction of §3
        uv_correction: bool = True
        #: Algorithm 3 at the end; normals_angle in degrees (negative: keep no normals)
        normals_angle: float = bounded(NORMALS_ANGLE, le=180)
        #: the engine's seam rule (seam vertices move only along their seam)
        seam_rule: bool = False
        #: a boundary vertex is never merged into an interior one
        boundary_rule: bool = True
        max_normal_rotation: float = bounded(90.0, gt=0, le=180)
        #: faces after a quadric pre-simplification; 0: twenty times the target; -1: none
        presimplify_faces: int = bounded(0, ge=-1)
        #: where the kept vertex goes: "endpoints" (a half-edge collapse, the paper's) or
        #: "optimal" (the quadric's point, a full-edge collapse; for ablation)
        placement: str = "endpoints"
        #: the move bound in the target's face size, sqrt(surface area / target faces)
        #: (the notes above); a large value is no bound
        move_bound: float = bounded(0.7, gt=0)

    def _check(self):
        p = self.params
        if p.views < 1:
            raise ParamError(f"entropy-twin: views must be at least 1, got {p.views}")
        if not 8 <= p.resolution <= 2048:
            raise ParamError(f"entropy-twin: resolution must be in 8..2048 pixels, got "
                             f"{p.resolution}")
        if p.normals_angle > 180:
            raise ParamError(f"entropy-twin: normals_angle must be at most 180 degrees "
                             f"(negative: no normals), got {p.normals_angle}")
        if p.canny_weight < 0:
            raise ParamError(f"entropy-twin: canny_weight must be >= 0, got {p.canny_weight}")
        if not 0 < p.max_normal_rotation <= 180:
            raise ParamError("entropy-twin: max_normal_rotation must be in (0, 180] degrees")
        if p.placement not in ("endpoints", "optimal"):
            raise ParamError(f"entropy-twin: placement must be endpoints or optimal, got "
                             f"{p.placement!r}")
        if p.presimplify_faces < -1:
            raise ParamError("entropy-twin: presimplify_faces must be >= -1 (0: twenty times "
                             "the target, -1: no pre-simplification)")

    def policy(self, canny: bool, max_move: float = float("inf")) -> Policy:
        """The engine's rules; ``max_move`` as a fraction of the diagonal
        (:meth:`max_move`)."""
        p = self.params
        return Policy(placement=p.placement, quadric_weight=0.0, memoryless_weight=0.0,
                      boundary_weight=0.0,
                      canny_weight=p.canny_weight * p.views if canny else 0.0,
                      max_normal_rotation=p.max_normal_rotation, seam_rule=p.seam_rule,
                      boundary_rule=p.boundary_rule,
                      uv_correction=p.uv_correction, max_move=max_move, move_memory=True)

    def max_move(self, mesh: Mesh, target_faces: int) -> float:
        """``move_bound`` times the target's face size, sqrt(surface area / target
        faces), as a fraction of ``mesh``'s bounding-box diagonal; no bound (inf) for a
        mesh without area, which has no face size."""
        area = float(face_areas(mesh.positions, mesh.faces).sum())
        if not (area > 0 and mesh.diagonal > 0):
            return math.inf
        return self.params.move_bound * math.sqrt(area / max(1, target_faces)) / mesh.diagonal

    @at_workable_scale  # cameras and images at unit scale; the result scaled back
    def simplify(self, mesh: Mesh, target_faces: int, ctx=None) -> SimplifyResult:
        self._check()
        p = self.params
        start = time.perf_counter()
        canny = p.canny and p.canny_weight > 0 and mesh.has_texture and mesh.uv is not None
        borders = None
        stats = {"canny_term": canny}
        if canny:
            from methods.engine.terms.canny import texture_borders

            borders = texture_borders(mesh.texture)
            stats["border_pixels"] = int(borders.sum())
        term = entropy_term(mesh, p.views, p.resolution, p.background)
        work = mesh
        pre_faces = PRESIMPLIFY_RATIO * target_faces if p.presimplify_faces == 0 \
            else p.presimplify_faces
        if 0 < pre_faces < mesh.n_faces:  # seams closed, charts kept, UVs by GH98 quadrics
            progress.stage(f"pre-simplifying to {pre_faces} faces (quadrics)")
            pre = simplify_mesh(mesh, pre_faces, Policy(texture_weight=1.0))
            work = pre.mesh
            stats["presimplify_collapses"] = pre.stats["collapses"]
            del pre  # its log and quadrics, while the image term works
        stats["presimplified_faces"] = work.n_faces
        stats["setup_seconds"] = time.perf_counter() - start
        progress.stage("collapsing by viewpoint entropy")
        policy = self.policy(canny, self.max_move(mesh, target_faces))
        result = simplify_mesh(work, target_faces, policy, borders=borders,
                               image=term)
        out = result.mesh
        if p.normals_angle >= 0:
            out = rebuild_normals(out, p.normals_angle)
        s = result.stats
        stats.update({
            "collapses": s["collapses"], "twin_collapses": s["twin_collapses"],
            # where the paper would add a fake edge: duplicates translated onto the kept
            # vertex (see the module notes)
            "fake_collapses": s["stranded_collapses"],
            "translated_duplicates": s["stranded_wedges"],
            "cost_evaluations": s["cost_evaluations"],
            "entropy_evaluations": s["image_evaluations"],
            "rejections": s["rejections"], "max_move": policy.max_move,
            "stall_phases": s.get("stall_phases", []),  # none without a bound
            "stall_collapses": s.get("stall_collapses", []),
            "mean_view_entropy": float(np.mean(s["view_entropy"])),
            "engine_seconds": s["engine_seconds"],
            "seconds": time.perf_counter() - start})
        return SimplifyResult(out, stats, result.stop_reason)
