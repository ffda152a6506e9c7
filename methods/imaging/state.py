"""The image state the engine carries for its rendered cost terms, made and checked
from Python (:class:`ImageTerm`)."""

from __future__ import annotations

from collections import namedtuple
from dataclasses import dataclass

import numpy as np
from numba import njit, prange

from methods.corners import corners
from methods.imaging.counters import STAT_NAMES
from methods.imaging.entropy import entropy_init, view_entropy
from methods.imaging.raster import (
    NO_VERTEX,
    ROW,
    ZERO,
    Shading,
    scan_row,
    shade_region,
    shading_constants,
)
from methods.imaging.region import _MAX_RING, AFFECTED_CAP, NEW_UV_CAP
from methods.imaging.rows import (
    NORMAL_FACES_CAP,
    _light,
    fill_screen,
    fill_shading,
    project,
    row_box,
    vertex_normal,
)
from methods.imaging.share import new_job, new_partials
from methods.imaging.tiles import TILE, Tiles, build_tiles
from metrics.shading import BACKGROUND, DEFAULT_CONSTANTS, SHADINGS

#: The image state of the engine's rendered cost terms (arrays over V views of H x W
#: pixels, nv welded vertices, m faces): clip transforms ``M`` (V, 4, 4), ``eyes`` (V, 3),
#: ``cull`` (V,) bool, the original's luminance ``Y0`` and the maintained one ``Y``
#: (V, H, W), screen positions ``S`` (V, nv, 4), face pixel boxes ``fbox`` (V, m, 4)
#: int32, vertex normals ``vn`` (nv, 3), vertex lighting ``L`` (V, nv, 4), ``shading``
#: (:data:`methods.imaging.raster.Shading`), ``texture`` (h, w, 3) uint8, ``stats``
#: counters (indexed by methods.imaging.counters.STAT_*), the face seen at each pixel
#: ``IDS`` (V, H, W) int32 (-1 empty), its depth ``DZ`` (V, H, W), ``ent``
#: (:data:`Entropy`).
ImageState = namedtuple("ImageState", "M eyes cull Y0 Y S fbox vn L shading texture stats "
                                      "IDS DZ ent")

#: The viewpoint entropy's counts: face pixel ``counts`` (V, m + 1) (entry 0 the
#: background), per view ``sums`` of a log a (V,) and ``totals`` (V,), scratch
#: ``dcnt``/``emark``/``touched`` (m + 1,) and ``etick`` (1,); booleans ``on`` (the
#: entropy term is kept), ``background`` (counted as a face), ``shade`` (luminance is
#: shaded too); ``delta`` (1,) the sum of |dH| of the last evaluation, read by the engine.
Entropy = namedtuple("Entropy", "counts sums totals dcnt emark touched on background shade "
                                "delta etick")

#: Scratch of the region re-renders: face marks ``mark`` (m,) with ``tick`` (1,), the
#: candidate faces ``cand`` (m,) and their table rows ``t`` (m, ROW), a rectangle's
#: ``depth`` and ``ids`` (H, W; int32), ``vslot`` (nv,) slot of a vertex whose lighting changes
#: and its new lighting ``ov_light`` (V, MAX_RING, 4), ``wslot`` (n_wedges,) slot of a
#: wedge whose UV changes and its ``new_uv`` (NEW_UV_CAP, 2), the ``ring`` of vertices
#: whose normal changes (MAX_RING,), per-view ``rects`` (V, 4), ``buf`` (NORMAL_FACES_CAP,)
#: faces of a vertex normal, ``n3`` (3,), ``sp`` (4,) a screen position, ``box`` (4,),
#: the affected faces ``aff`` (AFFECTED_CAP,), marks ``amark``/``gmark``/``rowmark`` and
#: ``rowof`` (m,), ``hmark`` (tiles of a view,) the tiles holding an open hole,
#: ``holes`` (H * W, 2) the (row, column) of each hole of a rectangle, ``spans``
#: (H, 2) per image row the first and last column of its open holes, each view's
#: results ``vcost`` and ``vdh`` (V,), and the job whose views the threads share
#: (``vjob``, :func:`methods.imaging.share.new_job`; the kept vertex's position ``vp``
#: (3,); the order the views are taken in ``vorder`` (V,), each thread's running sum of
#: its views' |dH| ``vpart`` (:func:`methods.imaging.share.new_partials`) and the sum
#: past which the rest of the views cannot matter ``vbound`` (1,), see
#: :func:`methods.imaging.region.image_cost`).
ImageScratch = namedtuple("ImageScratch", "mark tick cand t depth ids vslot ov_light wslot "
                                          "new_uv ring rects buf n3 sp box aff amark gmark "
                                          "rowof rowmark hmark holes spans vcost vdh vjob vp "
                                          "vorder vpart vbound")


def _workspace(n_views, nv, m, n_wedges, height, width):
    """An :data:`ImageScratch` for the given sizes."""
    m = max(m, 1)
    return ImageScratch(mark=np.zeros(m, np.int64), tick=np.zeros(1, np.int64),
                        cand=np.empty(m, np.int64), t=np.empty((m, ROW)),
                        depth=np.empty((height, width)), ids=np.empty((height, width), np.int32),
                        vslot=np.full(nv, -1, np.int64),
                        ov_light=np.zeros((n_views, _MAX_RING, 4)),
                        wslot=np.full(n_wedges, -1, np.int64), new_uv=np.zeros((NEW_UV_CAP, 2)),
                        ring=np.empty(_MAX_RING, np.int64), rects=np.empty((n_views, 4), np.int64),
                        buf=np.empty(NORMAL_FACES_CAP, np.int64), n3=np.empty(3), sp=np.empty(4),
                        box=np.empty(4, np.int64), aff=np.empty(AFFECTED_CAP, np.int64),
                        amark=np.zeros(m, np.int64), gmark=np.zeros(m, np.int64),
                        rowof=np.zeros(m, np.int64), rowmark=np.zeros(m, np.int64),
                        hmark=np.zeros(-(-height // TILE) * -(-width // TILE), np.int64),
                        holes=np.zeros((height * width, 2), np.int64),
                        spans=np.zeros((height, 2), np.int64), vcost=np.zeros(n_views),
                        vdh=np.zeros(n_views), vjob=new_job(), vp=np.zeros(3),
                        vorder=np.arange(n_views, dtype=np.int64), vpart=new_partials(),
                        vbound=np.full(1, np.inf))


def entropy_state(n_views, m, on=False, background=True, shade=True):
    """The ``ent`` member of an image state (:data:`Entropy`): per-view face pixel
    counts and scratch (see :func:`entropy_init`); (1, 1) placeholders when the entropy
    term is off."""
    size = m + 1 if on else 1
    return Entropy(counts=np.zeros((n_views if on else 1, size), np.int64),
                   sums=np.zeros(max(n_views, 1)), totals=np.zeros(max(n_views, 1), np.int64),
                   dcnt=np.zeros(size, np.int64), emark=np.zeros(size, np.int64),
                   touched=np.zeros(size, np.int64), on=bool(on), background=bool(background),
                   shade=bool(shade), delta=np.zeros(1), etick=np.zeros(1, np.int64))


def dummy_state():
    """An image state of the right types for engine runs without the image term."""
    img = ImageState(M=np.zeros((1, 4, 4)), eyes=np.zeros((1, 3)), cull=np.zeros(1, np.bool_),
                     Y0=np.zeros((1, 1, 1)), Y=np.zeros((1, 1, 1)), S=np.zeros((1, 1, 4)),
                     fbox=np.zeros((1, 1, 4), np.int32), vn=np.zeros((1, 3)),
                     L=np.zeros((1, 1, 4)),
                     shading=Shading(ambient=0.0, diffuse=0.0, ks=0.0, shininess=0.0, albedo=0.0,
                                     specular=False, gouraud=False, textured=False),
                     texture=np.zeros((1, 1, 3), np.uint8),
                     stats=np.zeros(len(STAT_NAMES), np.int64), IDS=np.zeros((1, 1, 1), np.int32),
                     DZ=np.zeros((1, 1, 1)), ent=entropy_state(1, 1))
    tiles = Tiles(ptr=np.zeros((1, 2), np.int64), cnt=np.zeros((1, 1), np.int64),
                  items=np.zeros(1, np.int32), ibox=np.zeros((1, 1, 4), np.int32))
    return img, tiles, _workspace(1, 1, 1, 1, 1, 1)


def new_state(M, eyes, cull, Y0, shading, texture, nv, m, n_wedges, entropy=None):
    """Arrays of an image state; :func:`full_render` fills them (``Y`` only where the
    state keeps luminance: with the entropy alone it is left unwritten, zeros).

    Parameters
    ----------
    M : ndarray (V, 4, 4)
        Clip-space transform of each view, applied to engine positions.
    eyes : ndarray (V, 3)
        Eye positions in engine coordinates (the headlight).
    cull : ndarray (V,) bool
        Views drawn with front faces culled (interior views, §5.2).
    Y0 : ndarray (V, H, W)
        Luminance of the original model.
    shading : methods.imaging.raster.Shading
        :func:`methods.imaging.raster.shading_constants`.
    texture : ndarray (h, w, 3) uint8
    nv, m, n_wedges : int
        Vertices, faces and wedges of the engine mesh.
    entropy : (bool, bool), optional
        (background counted, luminance shaded): keep the viewpoint entropy's face pixel
        counts (:func:`entropy_init` fills them after :func:`full_render`).
    """
    n_views, height, width = Y0.shape
    img = ImageState(M=np.ascontiguousarray(M, np.float64),
                     eyes=np.ascontiguousarray(eyes, np.float64),
                     cull=np.ascontiguousarray(cull, np.bool_),
                     Y0=np.ascontiguousarray(Y0, np.float64),
                     Y=(np.full(Y0.shape, 128.0) if entropy is None or entropy[1]
                        else np.zeros(Y0.shape)),
                     S=np.zeros((n_views, nv, 4)), fbox=np.zeros((n_views, m, 4), np.int32),
                     vn=np.zeros((nv, 3)), L=np.zeros((n_views, nv, 4)), shading=shading,
                     texture=np.ascontiguousarray(texture, np.uint8),
                     stats=np.zeros(len(STAT_NAMES), np.int64), IDS=np.empty(Y0.shape, np.int32),
                     DZ=np.empty(Y0.shape),
                     ent=(entropy_state(n_views, m) if entropy is None
                          else entropy_state(n_views, m, True, entropy[0], entropy[1])))
    return img, _workspace(n_views, nv, m, n_wedges, height, width)


def full_render(img, iws, P, F, FW, uv, falive, vhead, cnext, valive, background):
    """Set every per-vertex and per-face quantity of the image state ``img`` from the
    mesh and render all views from scratch into ``IDS`` (the face seen at each pixel, -1
    empty), ``DZ`` (its depth) and, where the state keeps luminance, ``Y`` (the entropy
    alone keeps none, and ``Y`` is left as it is)."""
    # The parallel kernel takes the fields in plain tuples, unpacked before its prange
    # loops: numba's parfor lowering cannot trace a namedtuple taken from another one's
    # field into a prange body.
    _full_render((img.M, img.eyes, img.cull, img.Y, img.S, img.fbox, img.vn, img.L, img.IDS,
                  img.DZ), (iws.vslot, iws.ov_light, iws.wslot, iws.new_uv),
                 (P, F, FW, uv, falive, vhead, cnext, valive), img.shading, img.texture,
                 background, keeps_luminance(img))


def keeps_luminance(img) -> bool:
    """Whether the image state keeps ``Y`` up to date (not with the entropy alone)."""
    return bool(not img.ent.on or img.ent.shade)


@njit(cache=True, parallel=True)
def _full_render(image, workspace, surface, shading, texture, background, shade):
    """:func:`full_render` on the image state's fields (:data:`ImageState`: ``image`` =
    (M, eyes, cull, Y, S, fbox, vn, L, IDS, DZ)), the workspace's (:data:`ImageScratch`:
    ``workspace`` = (vslot, ov_light, wslot, new_uv)) and the mesh's (``surface`` = (P,
    F, FW, uv, falive, vhead, cnext, valive)); ``Y`` only with ``shade``."""
    M, eyes, cull, Y, S, fbox, vn, L, IDS, DZ = image
    vslot, ov_light, wslot, new_uv = workspace
    P, F, FW, uv, falive, vhead, cnext, valive = surface
    n_views, height, width = Y.shape
    nv, m = P.shape[0], F.shape[0]
    gouraud = shading.gouraud
    for i in prange(nv):
        if not valive[i]:
            continue
        for h in range(n_views):
            project(M, h, P[i], width, height, S[h, i])
    if gouraud:
        for i in prange(nv):
            if not valive[i]:
                continue
            n_faces = 0  # a fan wider than the capacity gets a buffer of its own
            for c in corners(i, vhead, cnext):
                n_faces += 1
            buf = np.empty(max(NORMAL_FACES_CAP, n_faces), np.int64)
            vertex_normal(i, (NO_VERTEX, NO_VERTEX, P[i]), (P, F, vhead, cnext, falive), buf,
                          vn[i])
            for h in range(n_views):
                _light(P[i, 0], P[i, 1], P[i, 2], vn[i], eyes[h], shading, L[h, i], 0)
    live = np.flatnonzero(falive)
    for h in prange(n_views):
        t = np.empty((max(live.shape[0], 1), ROW))
        # drawn in place: the view's depths, and its faces as places in ``live`` until
        # the shading has read them
        depth, local = DZ[h], IDS[h]
        depth[:] = np.inf
        local[:] = -1
        none_i = np.full(1, -1, np.int64)
        for k in range(live.shape[0]):
            fill_screen((t, k, live[k], h), (NO_VERTEX, NO_VERTEX, S[h, 0]), S, F)
            if shade:
                fill_shading((t, k, live[k], h), (NO_VERTEX, NO_VERTEX, P[0]), (P, F, FW, uv),
                             (L, vslot, ov_light), (wslot, new_uv, none_i, none_i, ZERO),
                             shading)
            row_box(t, k, width, height, fbox[h, live[k]])
            scan_row(t, k, k, (ZERO, width - 1, ZERO, height - 1), cull[h], depth, local)
        if shade:
            shade_region(t, local, (ZERO, width - 1, ZERO, height - 1), eyes[h], shading,
                         texture, background, Y[h])
        for r in range(height):
            for c in range(width):
                if local[r, c] >= 0:
                    local[r, c] = live[local[r, c]]


@dataclass(frozen=True)
class ImageTerm:
    """The image cost of :func:`methods.engine.simplify_mesh` (Lindstrom & Turk 2000).

    Attributes
    ----------
    cameras : sequence of V metrics.views.Camera
        Fitted to the ORIGINAL model, like ``reference``.
    reference : ndarray (V, H, W)
        Luminance of the original model in those views (``Y^0``), rendered with the
        same settings (:func:`methods.imaging.raster.rasterize_luminance`).
    shading : {"flat", "gouraud"}
    specular : bool
    cull_front : sequence of V bool, optional
        Views drawn with front faces culled (§5.2's interior views).
    weight : float
        Multiplies equation 8 in the engine's cost sum. 0 with ``entropy_weight`` set:
        only face ids are rendered (no shading, ``Y`` is not kept up to date).
    constants : metrics.render.ShadingConstants, optional
    entropy_weight : float
        Multiplies the sum over views of |change of the viewpoint entropy| (González et
        al. 2008, §3), computed from the same region re-renders (0: off).
    entropy_background : bool
        Count the background as one more "face" in the entropy (Vázquez et al.'s
        definition); otherwise only the faces' projected areas.
    """

    cameras: tuple
    reference: np.ndarray
    shading: str = "flat"
    specular: bool = False
    cull_front: tuple | None = None
    weight: float = 1.0
    constants: object = None
    entropy_weight: float = 0.0
    entropy_background: bool = True

    def _frame(self, lo, scale):
        """Per-view clip transforms and eyes in engine coordinates (p_world = p * scale
        + lo)."""
        n_views, height, width = self.reference.shape
        affine = np.eye(4)
        affine[:3, :3] *= scale
        affine[:3, 3] = lo
        M = np.stack([c.projection_matrix(width / height) @ c.view_matrix() @ affine
                      for c in self.cameras])
        eyes = (np.stack([np.asarray(c.eye, np.float64) for c in self.cameras]) - lo) / scale
        return M, eyes

    def _new(self, mesh, uv, nv, m, lo, scale):

        if self.shading not in SHADINGS:
            raise ValueError(f"shading must be one of {SHADINGS}, got {self.shading!r}")
        n_views = len(self.cameras)
        if self.reference.ndim != 3 or self.reference.shape[0] != n_views:
            raise ValueError(f"reference must hold one image per camera ({n_views}), got "
                             f"shape {self.reference.shape}")
        constants = self.constants
        if constants is None:
            constants = DEFAULT_CONSTANTS
        textured = bool(mesh.has_texture)
        shading = shading_constants(constants, self.specular, self.shading == "gouraud",
                                    textured)
        texture = (np.ascontiguousarray(mesh.texture[:, :, :3]) if textured
                   else np.zeros((1, 1, 3), np.uint8))
        cull = np.zeros(n_views, np.bool_)
        if self.cull_front is not None:
            cull[:] = np.asarray(self.cull_front, dtype=np.bool_).reshape(-1)
        M, eyes = self._frame(lo, scale)
        entropy = None
        if self.entropy_weight != 0.0:
            entropy = (bool(self.entropy_background), self.weight != 0.0)
        return new_state(M, eyes, cull, self.reference, shading, texture, nv, m, len(uv),
                         entropy)

    def state(self, mesh, P, F, FW, uv, falive, vhead, cnext, valive, lo, scale):
        """The engine's image state for its arrays, with the images rendered."""

        img, iws = self._new(mesh, uv, len(P), len(F), lo, scale)
        full_render(img, iws, P, F, FW, uv, falive, vhead, cnext, valive, float(BACKGROUND))
        if self.entropy_weight != 0.0:
            entropy_init(img.IDS, img.ent)
        height, width = self.reference.shape[1:]
        tiles = build_tiles(img.fbox, falive, np.int64(TILE), -(-width // TILE), -(-height // TILE))
        return img, tiles, iws

    def statistics(self, mesh, img, verify, P, F, FW, uv, falive, vhead, cnext, valive, lo, scale):
        """Counters of the run; with ``verify``, a from-scratch render of the final mesh
        compared with the maintained images."""

        counts = dict(zip(STAT_NAMES, (int(x) for x in img.stats)))
        out = {k: counts[k] for k in ("image_evaluations", "pixels_shaded", "face_rows",
                                      "tile_rebuilds", "helper_views")}
        if counts["run_cycles"] > 0:  # where the time goes
            for k in ("gather", "shade", "setup"):
                out[f"{k}_share"] = counts[f"{k}_cycles"] / counts["run_cycles"]
        out["rasterizer_share"] = (counts["raster_cycles"] / counts["run_cycles"]
                                   if counts["run_cycles"] > 0 else None)
        Y, Y0 = img.Y, img.Y0
        shaded = keeps_luminance(img)
        if shaded:
            out["image_sse"] = float(np.sum((Y0 - Y) ** 2))
        entropy = self.entropy_weight != 0.0
        if entropy:
            CNT, SUM, TOT = img.ent.counts, img.ent.sums, img.ent.totals
            out["view_entropy"] = [float(view_entropy(s, float(a))) for s, a in zip(SUM, TOT)]
        if verify:
            again, iws = self._new(mesh, uv, len(P), len(F), lo, scale)
            full_render(again, iws, P, F, FW, uv, falive, vhead, cnext, valive,
                        float(BACKGROUND))
            if shaded:
                out["image_mismatched_pixels"] = int(np.count_nonzero(again.Y != Y))
            out["face_id_mismatched_pixels"] = int(np.count_nonzero(again.IDS != img.IDS))
            out["depth_mismatched_pixels"] = int(np.count_nonzero(again.DZ != img.DZ))
            if entropy:  # the maintained counts and entropies against fresh ones
                entropy_init(again.IDS, again.ent)
                fresh = np.array([view_entropy(s, float(a))
                                  for s, a in zip(again.ent.sums, again.ent.totals)])
                out["entropy_count_mismatches"] = int(np.count_nonzero(again.ent.counts != CNT))
                out["entropy_max_error"] = float(np.max(np.abs(
                    fresh - np.asarray(out["view_entropy"]))))
        return out
