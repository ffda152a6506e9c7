"""``perceptual-mt``: perceptually guided simplification over a Multi-Triangulation.

Williams, Luebke, Cohen, Kelley & Schubert, Perceptually Guided Simplification of Lit,
Textured Meshes, I3D 2003. The pipeline, in :meth:`PerceptualMT.simplify`::

    build_mt        engine collapse sequence -> MT (methods.mt, §2.3, §4)
    preprocess      per node: sphere, normal cones, texel luminance range, texture
                    deviation (methods.mt_preprocess, §4)
    node_errors     per view: visibility, silhouettes, contrast, frequency, CSF,
                    imperceptibility distance (§3, §5.2-5.4; methods.csf)
    refine          budget refinement with a raise and a lower queue, from the
                    previous view's cut (§5.1)

The method is view-dependent: the runner images each evaluation view with that
view's cut at the budget (:class:`ViewCuts`), starting each view from the previous
one's cut; the mesh returned by ``simplify`` is the view-independent cut (object-space
texture deviation), which the geometric and silhouette metrics use.

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
  on the silhouette otherwise.
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
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from typing import Literal

import numpy as np
from numba import njit

from bench.mesh import Mesh
from bench.method import Method, SimplifyResult
from methods.csf import ContrastSensitivity, visible_frequency_kernel
from methods.mt import Cut, MultiTriangulation, _set_applied, _set_refined, build_mt
from methods.mt_preprocess import NodeBounds, preprocess

__all__ = ["PerceptualMT", "Refiner", "ViewCuts", "ERRORS", "node_errors"]

ERRORS = {"object": 0, "screen": 1, "screen-silhouette": 2, "perceptual": 3}
LIGHTINGS = {"none": 0, "flat": 1, "gouraud": 2}
#: The evaluation renderer's constants (metrics.render.ShadingConstants).
AMBIENT, DIFFUSE, SPECULAR, SHININESS = 0.1, 0.9, 0.3, 32.0


# -- per-view node errors (§3, §5) --------------------------------------------------------------

@njit(cache=True)
def _node_errors(center, radius, sax, sang, hax, hang, lum, dev, eye, forward, right, up,
                 tan_half, near, far, resolution, ppd, mode, lighting, ks, sil_factor,
                 c_lo, c_hi, inv_table, out, status):
    """Error of every node from one view into ``out``; ``status`` gets 0 invisible,
    1 front-facing, 2 silhouette."""
    c = center.shape[0]
    norm_side = 1.0 / math.sqrt(1.0 + tan_half * tan_half)
    px_per_unit = 0.5 * resolution / tan_half  # pixels per unit length at distance 1
    for i in range(c):
        if mode == 0:
            out[i] = dev[i]
            status[i] = 1
            continue
        dx = center[i, 0] - eye[0]
        dy = center[i, 1] - eye[1]
        dz = center[i, 2] - eye[2]
        r = radius[i]
        z = dx * forward[0] + dy * forward[1] + dz * forward[2]
        x = dx * right[0] + dy * right[1] + dz * right[2]
        y = dx * up[0] + dy * up[1] + dz * up[2]
        # frustum: sphere beyond the near/far planes or a side plane
        visible = z + r >= near and z - r <= far
        if visible:
            for sx, sy in ((1.0, 0.0), (-1.0, 0.0), (0.0, 1.0), (0.0, -1.0)):
                dist_plane = (tan_half * z - sx * x - sy * y) * norm_side
                if dist_plane < -r:
                    visible = False
        dist = math.sqrt(dx * dx + dy * dy + dz * dz)
        # silhouette cone test (Luebke & Erikson 1997)
        kind = 2
        alpha = math.pi / 2 if dist <= r else math.asin(r / dist)
        if dist > 0.0:
            cos_psi = -(sax[i, 0] * dx + sax[i, 1] * dy + sax[i, 2] * dz) / dist
            psi = math.acos(max(-1.0, min(1.0, cos_psi)))
            if psi + sang[i] + alpha < 0.5 * math.pi:
                kind = 1
            elif psi - sang[i] - alpha > 0.5 * math.pi:
                visible = False
        if not visible:
            out[i] = 0.0
            status[i] = 0
            continue
        status[i] = kind
        dmin = max(dist - r, near)
        scale = px_per_unit / dmin  # pixels per unit length at the sphere's nearest point
        if mode == 1 or mode == 2:
            e = dev[i] * scale
            if mode == 2 and kind == 2:
                e *= sil_factor
            out[i] = e
            continue
        # perceptual: contrast (§3.3, §5.2, §5.4)
        if kind == 2:
            contrast = 1.0
        else:
            tmin, tmax = lum[i, 0], lum[i, 1]
            if lighting == 0:
                lmin, lmax = tmin, tmax
            else:
                if lighting == 1:
                    ax0, ax1, ax2, half = sax[i, 0], sax[i, 1], sax[i, 2], sang[i]
                else:
                    ax0, ax1, ax2, half = hax[i, 0], hax[i, 1], hax[i, 2], hang[i]
                cos_b = -(ax0 * dx + ax1 * dy + ax2 * dz) / dist
                beta = math.acos(max(-1.0, min(1.0, cos_b)))
                nl_max = max(0.0, math.cos(max(0.0, beta - half - alpha)))
                nl_min = max(0.0, math.cos(min(math.pi, beta + half + alpha)))
                lmin = tmin * (AMBIENT + DIFFUSE * nl_min) + ks * nl_min ** SHININESS
                lmax = tmax * (AMBIENT + DIFFUSE * nl_max) + ks * nl_max ** SHININESS
                lmin = min(1.0, lmin)
                lmax = min(1.0, lmax)
            contrast = 0.0 if lmax + lmin <= 0.0 else (lmax - lmin) / (lmax + lmin)
        # worst-case frequency from the feature's extent (§3.2, §5.4)
        if lighting == 0:
            extent_px = 2.0 * dev[i] * scale
        else:
            extent_px = 2.0 * r * scale
        f_vis = visible_frequency_kernel(contrast, c_lo, c_hi, inv_table)
        # imperceptibility distance in viewing distances: f_vis * 2 * extent in degrees
        out[i] = f_vis * 2.0 * extent_px / ppd
    return out


def node_errors(bounds: NodeBounds, camera, resolution: int, error: str = "perceptual",
                lighting: str = "gouraud", specular: bool = True, ppd: float = 32.0,
                csf: ContrastSensitivity | None = None, silhouette_factor: float = 10.0):
    """Per-node errors from one camera (see the module docstring).

    Parameters
    ----------
    bounds : NodeBounds
    camera : metrics.views.Camera
    resolution : int
        Image height in pixels (square images).
    error : str
        A key of :data:`ERRORS`.
    lighting : {"none", "flat", "gouraud"}
    specular : bool
    ppd : float
        Observer: pixels per degree of visual angle.
    csf : ContrastSensitivity, optional
    silhouette_factor : float

    Returns
    -------
    errors : ndarray of shape (c,)
    status : ndarray of shape (c,) int8
        0 invisible (culled or back-facing), 1 front-facing, 2 silhouette.
    """
    if error not in ERRORS:
        raise ValueError(f"error must be one of {', '.join(ERRORS)}, got {error!r}")
    if lighting not in LIGHTINGS:
        raise ValueError(f"lighting must be one of {', '.join(LIGHTINGS)}, got {lighting!r}")
    if not ppd > 0:
        raise ValueError(f"ppd (pixels per degree) must be positive, got {ppd}")
    csf = csf or ContrastSensitivity()
    c_lo, c_hi, table = csf.tables()
    forward = camera.direction
    right = np.cross(forward, camera.up)
    right /= np.linalg.norm(right)
    up = np.cross(right, forward)
    tan_half = math.tan(math.radians(camera.fov_y_deg) / 2)
    n = len(bounds.radius)
    out = np.empty(n)
    status = np.empty(n, np.int8)
    _node_errors(bounds.center, bounds.radius, bounds.silhouette_axis, bounds.silhouette_angle,
                 bounds.shading_axis, bounds.shading_angle, bounds.luminance, bounds.deviation,
                 np.asarray(camera.eye, np.float64), forward, right, up, tan_half,
                 float(camera.near), float(camera.far), float(resolution), float(ppd),
                 ERRORS[error], LIGHTINGS[lighting], SPECULAR if specular else 0.0,
                 float(silhouette_factor), c_lo, c_hi, table, out, status)
    return out, status


# -- budget refinement with two queues (§5.1) ---------------------------------------------------

@njit(cache=True)
def _heap_push(keys, vals, n, key, val):
    """Min-heap push on (keys, vals)[:n], growing the arrays when full; returns
    (keys, vals, new size)."""
    if n == keys.shape[0]:
        k2 = np.empty(2 * n + 16)
        v2 = np.empty(2 * n + 16, np.int64)
        k2[:n] = keys[:n]
        v2[:n] = vals[:n]
        keys, vals = k2, v2
    i = n
    keys[i] = key
    vals[i] = val
    while i > 0:
        p = (i - 1) // 2
        if keys[p] <= keys[i]:
            break
        keys[p], keys[i] = keys[i], keys[p]
        vals[p], vals[i] = vals[i], vals[p]
        i = p
    return keys, vals, n + 1


@njit(cache=True)
def _heap_pop(keys, vals, n):
    """Pop the minimum of (keys, vals)[:n]; returns (value, new size)."""
    top = vals[0]
    n -= 1
    keys[0] = keys[n]
    vals[0] = vals[n]
    i = 0
    while True:
        a = 2 * i + 1
        if a >= n:
            break
        b = a + 1
        s = a if b >= n or keys[a] <= keys[b] else b
        if keys[i] <= keys[s]:
            break
        keys[i], keys[s] = keys[s], keys[i]
        vals[i], vals[s] = vals[s], vals[i]
        i = s
    return top, n


@njit(cache=True)
def _lower_one(i, err, applied, delta, parent_start, parents, child_start, children, n_ap,
               n_rc, rk, rv, nr, lk, lv, nl):
    """Apply frontier node i; it joins R, parents that became lowerable join L."""
    _set_applied(i, applied, parent_start, parents, child_start, children, n_ap, n_rc)
    rk, rv, nr = _heap_push(rk, rv, nr, -err[i], i)
    for j in range(parent_start[i], parent_start[i + 1]):
        p = parents[j]
        if n_rc[p] == 0:
            lk, lv, nl = _heap_push(lk, lv, nl, err[p], p)
    return rk, rv, nr, lk, lv, nl


@njit(cache=True)
def _raise_one(i, err, applied, delta, parent_start, parents, child_start, children, n_ap,
               n_rc, rk, rv, nr, lk, lv, nl):
    """Refine frontier node i; it joins L, children that became raisable join R."""
    _set_refined(i, applied, parent_start, parents, child_start, children, n_ap, n_rc)
    lk, lv, nl = _heap_push(lk, lv, nl, err[i], i)
    for j in range(child_start[i], child_start[i + 1]):
        ch = children[j]
        if n_ap[ch] == 0:
            rk, rv, nr = _heap_push(rk, rv, nr, -err[ch], ch)
    return rk, rv, nr, lk, lv, nl


@njit(cache=True)
def _refine(budget, err, applied, n_faces, delta, parent_start, parents, child_start,
            children, n_ap, n_rc):
    """simplifyBudget of §5.1 on the cut ``applied``; returns (faces, raised, lowered).

    R holds applied nodes whose parents are all refined (candidates to raise), keyed
    by -error; L holds refined nodes whose children are all applied (candidates to
    lower), keyed by error. Both are rebuilt from the frontier at the start (the
    paper's updateErrorKeys). Entries go stale when the frontier moves and are skipped
    when popped. The loop alternates a lowering phase (while over budget) and a raising
    phase (while within it) and stops when the node lowered last is the node raised
    last, so it ends after a lowering phase: the cut meets the budget whenever the
    coarsest cut does, and is short of it by less than that node's faces."""
    c = applied.shape[0]
    rk = np.empty(c + 16)
    rv = np.empty(c + 16, np.int64)
    lk = np.empty(c + 16)
    lv = np.empty(c + 16, np.int64)
    nr = 0
    nl = 0
    for i in range(c):
        if applied[i] and n_ap[i] == 0:
            rk, rv, nr = _heap_push(rk, rv, nr, -err[i], i)
        elif not applied[i] and n_rc[i] == 0:
            lk, lv, nl = _heap_push(lk, lv, nl, err[i], i)
    last_raised = -1
    raised = 0
    lowered = 0
    # Each exchange trades a refined node for one of larger error, so the loop ends;
    # the cap is a guard against error ties cycling.
    for _ in range(4 * c + 16):
        last_dropped = -1
        while n_faces > budget and nl > 0:
            i, nl = _heap_pop(lk, lv, nl)
            if applied[i] or n_rc[i] != 0:
                continue  # stale
            rk, rv, nr, lk, lv, nl = _lower_one(i, err, applied, delta, parent_start, parents,
                                                child_start, children, n_ap, n_rc, rk, rv, nr,
                                                lk, lv, nl)
            n_faces -= delta[i]
            lowered += 1
            last_dropped = i
        if last_raised != -1 and last_dropped == last_raised:
            break
        last_raised = -1
        while n_faces <= budget and nr > 0:
            i, nr = _heap_pop(rk, rv, nr)
            if not applied[i] or n_ap[i] != 0:
                continue  # stale
            rk, rv, nr, lk, lv, nl = _raise_one(i, err, applied, delta, parent_start, parents,
                                                child_start, children, n_ap, n_rc, rk, rv, nr,
                                                lk, lv, nl)
            n_faces += delta[i]
            raised += 1
            last_raised = i
        if last_raised == -1:
            break
    while n_faces > budget and nl > 0:  # only after the guard tripped: back to the budget
        i, nl = _heap_pop(lk, lv, nl)
        if applied[i] or n_rc[i] != 0:
            continue
        rk, rv, nr, lk, lv, nl = _lower_one(i, err, applied, delta, parent_start, parents,
                                            child_start, children, n_ap, n_rc, rk, rv, nr,
                                            lk, lv, nl)
        n_faces -= delta[i]
        lowered += 1
    return n_faces, raised, lowered


def refine(cut: Cut, errors: np.ndarray, budget: int) -> tuple[int, int]:
    """Move ``cut`` to ``budget`` faces greedily by ``errors`` (§5.1), in place.

    Returns (nodes raised, nodes lowered). The result has at most ``budget`` faces
    (unless even the coarsest cut has more) and more than ``budget`` minus the faces of
    the last node lowered.
    """
    mt = cut.mt
    if budget < 1:
        raise ValueError(f"budget must be at least 1 face, got {budget}")
    errors = np.ascontiguousarray(errors, dtype=np.float64)
    if errors.shape != (mt.n_nodes,):
        raise ValueError(f"errors must have shape ({mt.n_nodes},), got {errors.shape}")
    faces, raised, lowered = _refine(int(budget), errors, cut.applied, int(cut.n_faces),
                                     mt.delta, mt.parent_start, mt.parents, mt.child_start,
                                     mt.children, cut.n_applied_parents,
                                     cut.n_refined_children)
    cut.n_faces = int(faces)
    return int(raised), int(lowered)


class Refiner:
    """Per-view cuts of one MT under one error, each view starting from the last cut."""

    def __init__(self, mt: MultiTriangulation, bounds: NodeBounds, error: str = "perceptual",
                 lighting: str = "gouraud", specular: bool = True, ppd: float = 32.0,
                 peak_sensitivity: float = 200.0, silhouette_factor: float = 10.0):
        self.mt, self.bounds = mt, bounds
        self.error, self.lighting, self.specular = error, lighting, specular
        self.ppd, self.silhouette_factor = ppd, silhouette_factor
        self.csf = ContrastSensitivity(peak_sensitivity)
        self.cut = mt.cut("coarsest")

    def errors(self, camera, resolution: int):
        return node_errors(self.bounds, camera, resolution, self.error, self.lighting,
                           self.specular, self.ppd, self.csf, self.silhouette_factor)

    def refine_view(self, camera, budget: int, resolution: int) -> dict:
        """Refine the current cut for ``camera``; returns timing and counts."""
        t = time.perf_counter()
        err, status = self.errors(camera, resolution)
        t_err = time.perf_counter() - t
        raised, lowered = refine(self.cut, err, budget)
        return {"seconds": time.perf_counter() - t, "error_seconds": t_err, "raised": raised,
                "lowered": lowered, "faces": self.cut.n_faces,
                "max_error": float(_max_on_cut(self.cut, err))}

    def refine_object(self, budget: int) -> None:
        """The view-independent cut: object-space texture deviation."""
        refine(self.cut, self.bounds.deviation, budget)


def _max_on_cut(cut: Cut, err: np.ndarray) -> float:
    """The largest error among the applied collapses that could be raised next (the
    simplifications in effect at the cut's frontier): the LOD's imperceptibility
    distance (§3.4) when ``err`` holds imperceptibility distances."""
    frontier = (~cut.applied) & (cut.n_refined_children == 0)
    below = cut.applied & (cut.n_applied_parents == 0)
    pick = err[below] if below.any() else err[frontier]
    return float(pick.max()) if pick.size else 0.0


# -- the method ----------------------------------------------------------------------------------

class ViewCuts:
    """Per-view cuts at a budget for the runner: ``view_cuts(cameras, protocol)``.

    Views are refined in the order given, each from the previous view's cut (the
    first from the view-independent cut); ``stats`` collects the refinement times.
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
    version = "1"
    summary = ("Williams et al. 2003: CSF imperceptibility distance over a Multi-Triangulation, "
               "per-view budget cuts")
    reference = ("Williams, Luebke, Cohen, Kelley & Schubert, Perceptually Guided "
                 "Simplification of Lit, Textured Meshes, I3D 2003")
    view_dependent = True
    requires = {"numba": "numba>=0.59"}

    @dataclass
    class Params:
        error: Literal["perceptual", "object", "screen", "screen-silhouette"] = "perceptual"
        lighting: Literal["auto", "none", "flat", "gouraud"] = "auto"
        specular: Literal["auto", "true", "false"] = "auto"
        ppd: float = 32.0
        peak_sensitivity: float = 200.0
        silhouette_factor: float = 10.0
        texture_weight: float = 1.0

    def simplify(self, mesh: Mesh, target_faces: int, ctx=None) -> SimplifyResult:
        p = self.params
        if p.error not in ERRORS:
            raise ValueError(f"error must be one of {', '.join(ERRORS)}, got {p.error!r}")
        if not p.ppd > 0:
            raise ValueError(f"ppd must be positive, got {p.ppd}")
        t = time.perf_counter()
        mt = build_mt(mesh, texture_weight=p.texture_weight)
        t_mt = time.perf_counter() - t
        bounds = preprocess(mt)
        lighting = "gouraud" if p.lighting == "auto" else p.lighting
        refiner = Refiner(mt, bounds, p.error, lighting, p.specular != "false", p.ppd,
                          p.peak_sensitivity, p.silhouette_factor)
        refiner.refine_object(target_faces)
        simplified = refiner.cut.mesh().replace(name=mesh.name, metadata=dict(mesh.metadata))
        stats = {"mt_nodes": mt.n_nodes, "mt_triangles": mt.n_triangles,
                 "mt_coarsest_faces": mt.coarsest_faces, "mt_seconds": t_mt,
                 "preprocess_seconds": bounds.seconds,
                 "images": "per view, each view's cut at the budget; geometry and "
                           "silhouettes from the view-independent (object-space) cut"}
        stop = None
        if mt.coarsest_faces > target_faces:
            stop = (f"the MT's coarsest cut has {mt.coarsest_faces} faces, above the target "
                    f"{target_faces} ({mt.stats.get('engine_stop_reason')})")
        result = SimplifyResult(simplified, stats, stop)
        result.view_cuts = ViewCuts(refiner, target_faces, p.lighting, p.specular)
        return result
