"""Per-view errors of Multi-Triangulation nodes (Williams et al. 2003, §3 and §5): the
imperceptibility distance of a node's perceptual bound, or the paper's object-space,
screen-space and silhouette-weighted comparison metrics.

Every error is monotone up the MT in every view — a parent's is at least each
child's — because the bounds are nested (methods.mt.bounds: the parent's sphere
encloses the child's, its cones contain the child's, its luminance range and deviation
hold the child's) and each term grows with the bounds:

- *culling*: a side, near or far plane that cuts no part of the parent's sphere cuts
  none of the child's; the cone of directions from the eye to the child's sphere lies
  within the parent's (angle between the two directions + α_child ≤ α_parent), so by
  the triangle inequality on angles ψ_child − θ_child − α_child ≥ ψ_parent −
  θ_parent − α_parent: a back-facing parent has back-facing children, a front-facing
  parent front-facing ones, and a child on the silhouette has its parent on it (an
  eye inside the parent's sphere, α = 90°, always puts the parent on the silhouette);
- *distance*: the parent's sphere reaches nearer the eye (dist − r), so its pixels per
  unit length are at least the child's;
- *contrast*: the n·l range of the parent's shading cone holds the child's, luminance
  rises with texel luminance and n·l, and (L_max − L_min) / (L_max + L_min) rises with
  L_max and falls with L_min; a silhouette node has contrast 1;
- *frequency and extent*: f_vis rises with contrast (the CSF's inverse), the extent
  with the radius or the deviation.

That holds in exact arithmetic. In floating point a parent whose bounds equal a
child's but for rounding (its own sphere inside the child's, its centre moved by
1e-16 in a merge) can come out an ulp below it, so :func:`node_errors` finally raises
each node's error to its children's, children first: §3.4's imperceptibility distance
of an LOD is "the maximum imperceptibility distance of all the local simplification
operations used to generate it", and applying a node applies its descendants. With
nested bounds this moves errors by rounding only (the tests hold the two within 1e-12);
it is what makes them exactly monotone, which refinement relies on
(methods.mt.refine): with monotone errors the cut at a budget does not depend on the
cut refinement starts from.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from methods.mt.bounds import NodeBounds
from methods.mt.csf import ContrastSensitivity, visible_frequency_kernel
from metrics.shading import DEFAULT_CONSTANTS

ERRORS = {"object": 0, "screen": 1, "screen-silhouette": 2, "perceptual": 3}


LIGHTINGS = {"none": 0, "flat": 1, "gouraud": 2}


#: The evaluation renderer's constants (metrics.render.ShadingConstants).
AMBIENT, DIFFUSE, SPECULAR, SHININESS = (DEFAULT_CONSTANTS.ambient, DEFAULT_CONSTANTS.diffuse,
                                       DEFAULT_CONSTANTS.specular, DEFAULT_CONSTANTS.shininess)


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


@njit(cache=True)
def _children_max(out, child_start, children):
    """Raise each node's error to its children's, in place, children first (a child's
    index is smaller): afterwards every node's error is the maximum over its subtree."""
    for i in range(out.shape[0]):
        for j in range(child_start[i], child_start[i + 1]):
            out[i] = max(out[i], out[children[j]])


def node_errors(bounds: NodeBounds, camera, resolution: int, error: str = "perceptual",
                lighting: str = "gouraud", specular: bool = True, ppd: float = 32.0,
                csf: ContrastSensitivity | None = None, silhouette_factor: float = 10.0,
                children_max: bool = True):
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
    children_max : bool
        Raise each node's error to its children's (the module docstring); False gives
        each node's own error, for tests and diagnostics.

    Returns
    -------
    errors : ndarray of shape (c,)
        Monotone up the MT when ``children_max``.
    status : ndarray of shape (c,) int8
        0 invisible (culled or back-facing), 1 front-facing, 2 silhouette: each node's
        own test.
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
    if children_max:
        _children_max(out, bounds.child_start, bounds.children)
    return out, status
