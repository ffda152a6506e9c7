"""Per-view errors of Multi-Triangulation nodes (Williams et al. 2003, §3 and §5): the
imperceptibility distance of a node's perceptual bound, or the paper's object-space,
screen-space and silhouette-weighted comparison metrics.

Errors are monotone up the MT: :func:`node_errors` gives each node the largest of its
own error and its descendants' (children first, in index order). A node's bounds are
its own (methods.mt.bounds), and a child's created triangles are shared among several
parents, so a parent's sphere can be smaller than a child's (on 17 % of
torus-puzzle's arcs) and its silhouette cone narrower (30 %); in a view, 13 % of the
arcs have a parent's own error below the child's, and 2 % a parent culled as
back-facing while the child is visible. Version 1 refined by these own errors, and
the two-queue refinement (§5.1) converged to a cut that depended on where it started
(at 98 % on torus-puzzle, d_rms 10.65 from the previous view's cut, 10.79 from the
object-space cut, 11.41 from the coarsest).

The maximum is §3.4's error of an LOD, "the maximum imperceptibility distance of all
the local simplification operations used to generate it", applied to the LOD that
applying a node implies (it applies all its descendants); the texture deviation is
made monotone the same way. With it the cut at a budget refines the nodes of largest
error, whatever cut refinement starts from (methods.mt.refine), and a node has error
0 (invisible, or below threshold) only if all its descendants have. The
alternative, nesting the bounds (a node's sphere enclosing its children's, its cones
containing theirs), also makes every error monotone, but replaces the paper's
per-node bounds by bounds of the node's whole history: a late collapse's sphere then
spans every collapse that fed its triangles. Measured at 98 % on torus-puzzle under
Gouraud shading with specular highlights, nested bounds gave d_rms 12.72 and FLIP
0.0792, the maximum 10.93 and 0.0675.
"""

from __future__ import annotations

import math
from collections import namedtuple

import numpy as np
from numba import njit

from methods.mt.bounds import NodeBounds
from methods.mt.bounds import subtree_max as _subtree_max
from methods.mt.csf import ContrastSensitivity, visible_frequency_kernel
from metrics.shading import DEFAULT_CONSTANTS

ERRORS = {"object": 0, "screen": 1, "screen-silhouette": 2, "perceptual": 3}


LIGHTINGS = {"none": 0, "flat": 1, "gouraud": 2}

#: A node whose texture deviation is at most this fraction of its bounding sphere's
#: radius is exact (it moves no point of the surface; see :func:`node_errors`).
EXACT_DEVIATION = 1e-9

#: Feature sizes of the perceptual error (:func:`node_errors`' ``feature_size``).
FEATURE_SIZES = ("auto", "sphere", "deviation")


#: The evaluation renderer's constants (metrics.render.ShadingConstants).
AMBIENT, DIFFUSE, SPECULAR, SHININESS = (DEFAULT_CONSTANTS.ambient, DEFAULT_CONSTANTS.diffuse,
                                       DEFAULT_CONSTANTS.specular, DEFAULT_CONSTANTS.shininess)


#: A node's bounds as :func:`_node_errors` reads them (methods.mt.bounds.NodeBounds):
#: sphere ``center`` and ``radius``, silhouette cone (``sax``, ``sang``), shading cone
#: (``hax``, ``hang``), luminance range ``lum`` and texture deviation ``dev``.
_Nodes = namedtuple("_Nodes", "center radius sax sang hax hang lum dev")
#: One view: ``eye``, its unit frame (``forward``, ``right``, ``up``), the tangent of
#: half the vertical field of view, the near and far planes and the image height in
#: pixels.
_View = namedtuple("_View", "eye forward right up tan_half near far resolution")
#: What an error is: ``mode`` (a value of :data:`ERRORS`), ``lighting`` (of
#: :data:`LIGHTINGS`), the specular weight ``ks``, the silhouette factor, the observer's
#: ``ppd`` and contrast sensitivity (``c_lo``, ``c_hi``, ``inv_table``), and the
#: ablation switches (:func:`node_errors`): ``sil_contrast`` gives silhouette nodes
#: maximal contrast, ``lit_contrast`` bounds the contrast under ``lighting`` (else the
#: intrinsic luminance range alone), ``sphere_extent`` takes the feature size from the
#: bounding sphere (else twice the texture deviation).
_Measure = namedtuple("_Measure", "mode lighting ks sil_factor ppd c_lo c_hi inv_table "
                                  "sil_contrast lit_contrast sphere_extent")


@njit(cache=True)
def _node_errors(nodes, view, measure, out, status):
    """Error of every node from one view into ``out``; ``status`` gets 0 invisible,
    1 front-facing, 2 silhouette."""
    tan_half = view.tan_half
    norm_side = 1.0 / math.sqrt(1.0 + tan_half * tan_half)
    px_per_unit = 0.5 * view.resolution / tan_half  # pixels per unit length at distance 1
    for i in range(nodes.center.shape[0]):
        if measure.mode == 0:
            out[i] = nodes.dev[i]
            status[i] = 1
            continue
        kind, dx, dy, dz, dist, alpha = _seen(nodes, view, norm_side, i)
        status[i] = kind
        if kind == 0:
            out[i] = 0.0
            continue
        dmin = max(dist - nodes.radius[i], view.near)
        scale = px_per_unit / dmin  # pixels per unit length at the sphere's nearest point
        if measure.mode == 1 or measure.mode == 2:
            e = nodes.dev[i] * scale
            if measure.mode == 2 and kind == 2:
                e *= measure.sil_factor
            out[i] = e
            continue
        # perceptual: contrast (§3.3, §5.2, §5.4). An exact node moves no point of the
        # surface: no texel and no silhouette moves, so only Gouraud shading, whose
        # vertex normals it may change, can show it.
        exact = nodes.dev[i] <= EXACT_DEVIATION * nodes.radius[i]
        if exact and (measure.lighting != 2 or not measure.lit_contrast):
            out[i] = 0.0
            continue
        if kind == 2 and measure.sil_contrast and not exact:
            contrast = 1.0
        else:
            contrast = _contrast(nodes, measure, i, (dx, dy, dz), dist, alpha, exact)
        # worst-case frequency from the feature's extent (§3.2, §5.4)
        if measure.sphere_extent:
            extent_px = 2.0 * nodes.radius[i] * scale
        else:
            extent_px = 2.0 * nodes.dev[i] * scale
        f_vis = visible_frequency_kernel(contrast, measure.c_lo, measure.c_hi,
                                         measure.inv_table)
        # imperceptibility distance in viewing distances: f_vis * 2 * extent in degrees
        out[i] = f_vis * 2.0 * extent_px / measure.ppd
    return out


@njit(cache=True)
def _seen(nodes, view, norm_side, i):
    """How node ``i`` is seen: (0 invisible, 1 front-facing or 2 silhouette, its
    sphere's centre from the eye (dx, dy, dz), the distance, the sphere's angular
    radius)."""
    eye, forward, right, up = view.eye, view.forward, view.right, view.up
    dx = nodes.center[i, 0] - eye[0]
    dy = nodes.center[i, 1] - eye[1]
    dz = nodes.center[i, 2] - eye[2]
    r = nodes.radius[i]
    z = dx * forward[0] + dy * forward[1] + dz * forward[2]
    x = dx * right[0] + dy * right[1] + dz * right[2]
    y = dx * up[0] + dy * up[1] + dz * up[2]
    # frustum: sphere beyond the near/far planes or a side plane
    visible = z + r >= view.near and z - r <= view.far
    if visible:
        for sx, sy in ((1.0, 0.0), (-1.0, 0.0), (0.0, 1.0), (0.0, -1.0)):
            dist_plane = (view.tan_half * z - sx * x - sy * y) * norm_side
            if dist_plane < -r:
                visible = False
    dist = math.sqrt(dx * dx + dy * dy + dz * dz)
    # silhouette cone test (Luebke & Erikson 1997)
    kind = 2
    alpha = math.pi / 2 if dist <= r else math.asin(r / dist)
    if dist > 0.0:
        sax = nodes.sax
        cos_psi = -(sax[i, 0] * dx + sax[i, 1] * dy + sax[i, 2] * dz) / dist
        psi = math.acos(max(-1.0, min(1.0, cos_psi)))
        if psi + nodes.sang[i] + alpha < 0.5 * math.pi:
            kind = 1
        elif psi - nodes.sang[i] - alpha > 0.5 * math.pi:
            visible = False
    return (kind if visible else 0), dx, dy, dz, dist, alpha


@njit(cache=True)
def _contrast(nodes, measure, i, d, dist, alpha, exact):
    """Node ``i``'s contrast (§3.3, §5.2, §5.4): its luminance range, bounded under the
    lighting over its shading cone (the silhouette cone under flat shading) as seen
    from ``d`` = (dx, dy, dz) away at ``dist``, with the sphere's angular radius
    ``alpha``. An ``exact`` node moves no texel: the lighting's range over its brightest
    texel."""
    dx, dy, dz = d
    tmin, tmax = nodes.lum[i, 0], nodes.lum[i, 1]
    if exact:
        tmin = tmax
    if measure.lighting == 0 or not measure.lit_contrast:
        lmin, lmax = tmin, tmax
    else:
        if measure.lighting == 1:
            ax, half = nodes.sax, nodes.sang[i]
        else:
            ax, half = nodes.hax, nodes.hang[i]
        cos_b = -(ax[i, 0] * dx + ax[i, 1] * dy + ax[i, 2] * dz) / dist
        beta = math.acos(max(-1.0, min(1.0, cos_b)))
        nl_max = max(0.0, math.cos(max(0.0, beta - half - alpha)))
        nl_min = max(0.0, math.cos(min(math.pi, beta + half + alpha)))
        ks = measure.ks
        lmin = tmin * (AMBIENT + DIFFUSE * nl_min) + ks * nl_min ** SHININESS
        lmax = tmax * (AMBIENT + DIFFUSE * nl_max) + ks * nl_max ** SHININESS
        lmin = min(1.0, lmin)
        lmax = min(1.0, lmax)
    return 0.0 if lmax + lmin <= 0.0 else (lmax - lmin) / (lmax + lmin)


def node_errors(bounds: NodeBounds, camera, resolution: int, error: str = "perceptual",
                lighting: str = "gouraud", specular: bool = True, ppd: float = 32.0,
                csf: ContrastSensitivity | None = None, silhouette_factor: float = 10.0,
                subtree_max: bool = True, silhouette_contrast: bool = True,
                lighting_contrast: bool = True, feature_size: str = "auto"):
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
    subtree_max : bool
        Give each node the largest error of its subtree (the module docstring); False
        gives each node's own error, for tests and diagnostics.
    silhouette_contrast, lighting_contrast, feature_size
        Ablation switches of the perceptual error (the defaults are the method):
        ``silhouette_contrast=False`` gives a node on the silhouette the contrast of
        its surface, as a front-facing node (§3.3 gives it maximal contrast);
        ``lighting_contrast=False`` takes the contrast from the intrinsic (texture or
        material) luminance range alone, without §5.4's bound of the lighting over the
        shading cone; ``feature_size`` is ``"sphere"`` (the bounding sphere's projected
        diameter), ``"deviation"`` (twice the projected texture deviation) or
        ``"auto"`` (§5.4: the sphere when lit, the deviation when unlit).

    A node whose texture deviation is at most :data:`EXACT_DEVIATION` times its sphere's
    radius is *exact*: its collapses move no point of the surface (coplanar regions of
    game assets, where most collapses are exact). It moves no texel and no silhouette,
    so its perceptual error is 0, except under Gouraud shading with
    ``lighting_contrast``, whose vertex normals it may change: there its contrast is
    the lighting's alone. The paper has no such case (its meshes are scans): with
    maximal silhouette contrast and the sphere as feature size, exact nodes of large
    flat parts got the largest errors of a view and took the budget, and the vehicle
    analogue's images were the same at 108 and 1,000 faces. Exactness is read from the
    texture deviation, which measures the original's vertices against the node's
    triangles, and the node's triangles against the original only through UVs: on a
    part without usable UVs (one texel) a collapse that adds surface while every
    original vertex stays on it (a concave corner of an open flat part filled in) would
    count as exact.

    Returns
    -------
    errors : ndarray of shape (c,)
        Monotone up the MT when ``subtree_max``.
    status : ndarray of shape (c,) int8
        0 invisible (culled or back-facing), 1 front-facing, 2 silhouette: each node's
        own test.
    """
    _check_error_options(error, lighting, ppd, feature_size)
    sphere_extent = lighting != "none" if feature_size == "auto" else feature_size == "sphere"
    c_lo, c_hi, table = (csf or ContrastSensitivity()).tables()
    view = _view(camera, resolution)
    measure = _Measure(ERRORS[error], LIGHTINGS[lighting], SPECULAR if specular else 0.0,
                       float(silhouette_factor), float(ppd), c_lo, c_hi, table,
                       bool(silhouette_contrast), bool(lighting_contrast), bool(sphere_extent))
    b = bounds
    nodes = _Nodes(b.center, b.radius, b.silhouette_axis, b.silhouette_angle, b.shading_axis,
                   b.shading_angle, b.luminance, b.deviation)
    out, status = np.empty(len(b.radius)), np.empty(len(b.radius), np.int8)
    _node_errors(nodes, view, measure, out, status)
    if subtree_max:
        _subtree_max(out, bounds.child_start, bounds.children)
    return out, status


def _view(camera, resolution: int):
    """``camera`` (metrics.views.Camera) as :data:`_View`, ``resolution`` pixels high."""
    forward = camera.direction
    right = np.cross(forward, camera.up)
    right /= np.linalg.norm(right)
    return _View(np.asarray(camera.eye, np.float64), forward, right, np.cross(right, forward),
                 math.tan(math.radians(camera.fov_y_deg) / 2), float(camera.near),
                 float(camera.far), float(resolution))


def _check_error_options(error: str, lighting: str, ppd: float, feature_size: str) -> None:
    """:func:`node_errors`' options, each a one-line error naming what is allowed."""
    if error not in ERRORS:
        raise ValueError(f"error must be one of {', '.join(ERRORS)}, got {error!r}")
    if lighting not in LIGHTINGS:
        raise ValueError(f"lighting must be one of {', '.join(LIGHTINGS)}, got {lighting!r}")
    if not ppd > 0:
        raise ValueError(f"ppd (pixels per degree) must be positive, got {ppd}")
    if feature_size not in FEATURE_SIZES:
        raise ValueError(f"feature_size must be one of {', '.join(FEATURE_SIZES)}, "
                         f"got {feature_size!r}")
