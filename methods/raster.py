"""A CPU scan converter with the shading model of the evaluation renderer.

Image-driven simplification (Lindstrom & Turk 2000, §4.2) renders a model from the 20
dodecahedron views many times. This module does it on the CPU, without anti-aliasing,
with the same cameras (:mod:`metrics.views`) and the same classic shading as
:mod:`metrics.render` with ``msaa=False``:

* a headlight at the eye: at a surface point ``p`` the light vector is
  ``l = normalize(eye - p)`` (equal to the view vector), no fall-off;
* ``colour = albedo * (ambient + diffuse * max(0, n.l)) [+ ks * max(0, n.l)^shininess]``,
  clamped to [0, 1] and quantised to 8 bits per channel, as the framebuffer stores it;
* two-sided: nothing is culled; ``flat`` flips the face normal towards the viewer,
  ``gouraud`` lights each vertex for both sides and picks the side by the triangle's
  winding on screen (``gl_FrontFacing``: counter-clockwise in y-up window coordinates);
* ``flat``: the unit face normal with ``l`` evaluated at every pixel's surface point
  (the GLSL evaluates the lighting per fragment with a per-face normal);
* ``gouraud``: lighting per vertex from ``mesh.vertex_normals``, interpolated with
  perspective-correct barycentrics (GLSL's default ``smooth`` interpolation);
* textured meshes (texture and uv): albedo from the texture, bilinear with repeat
  wrapping. The evaluation renderer uses trilinear mipmaps for minification, so
  textures seen small differ (the untextured path is exact up to rounding);
* background 128.

Rasterisation conventions
-------------------------
Vertices go through ``P @ V`` of each camera to clip space and are divided by ``w``;
window coordinates are ``x = (x_ndc + 1) W / 2`` and ``y = (1 - y_ndc) H / 2`` (y
downwards, so row 0 is the top of the image, as in the evaluation renderer's output).
A pixel (row r, column c) is sampled once at its centre ``(c + 0.5, r + 0.5)``. A
centre exactly on an edge belongs to the triangle if the edge is a *top* edge
(horizontal, interior below it) or a *left* edge (interior to its right), so pixels on
an edge shared by two triangles are drawn exactly once. Depth is the NDC ``z``, affine
in screen space, tested with ``<`` (the first face drawn wins a tie, as ``GL_LESS`` with
faces drawn in index order) and clipped to [-1, 1] per pixel (the near and far planes).
Triangles with a vertex at or behind the eye plane (``w <= 0``) are skipped rather
than clipped; protocol cameras never produce them (the model lies in [r, 3r] of depth).

The per-triangle set-up (transforms, per-vertex lighting) is vectorised in NumPy; the
per-pixel work runs in numba kernels, parallel over views (each view is independent,
so the result does not depend on the number of threads).
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

__all__ = ["BACKGROUND", "SHADINGS", "face_id_buffers", "rasterize_luminance"]

#: Background grey of empty pixels (8-bit), as in :mod:`metrics.render`.
BACKGROUND = 128
#: Shading modes, as in :mod:`metrics.render`.
SHADINGS = ("flat", "gouraud")


def vertex_light(positions, normals, eyes, ambient, diffuse, ks, shininess, specular):
    """Per-vertex headlight terms for gouraud shading, lit from both sides.

    Parameters
    ----------
    positions, normals : ndarray of shape (n, 3)
    eyes : ndarray of shape (V, 3)

    Returns
    -------
    ndarray of shape (V, n, 4)
        (diffuse+ambient, specular) for the front side, then for the back side.
    """
    length = np.linalg.norm(normals, axis=1, keepdims=True)
    n = np.divide(normals, length, out=np.zeros_like(normals), where=length > 0.0)
    to_eye = eyes[:, None, :] - positions[None]
    to_eye /= np.linalg.norm(to_eye, axis=2, keepdims=True)
    dot = np.einsum("vnk,nk->vn", to_eye, n)
    light = np.empty(dot.shape + (4,))
    for k, side in ((0, dot), (2, -dot)):
        cos = np.maximum(side, 0.0)
        light[..., k] = ambient + diffuse * cos
        light[..., k + 1] = ks * cos ** shininess if specular else 0.0
    return light


# -- set-up in NumPy ----------------------------------------------------------------------

def _project(positions: np.ndarray, cameras, width: int, height: int):
    """Screen coordinates of every vertex in every view.

    Parameters
    ----------
    positions : ndarray of shape (n, 3) float64
    cameras : sequence of V metrics.views.Camera
    width, height : int

    Returns
    -------
    screen : ndarray of shape (V, n, 4) float64
        Columns x, y (pixels, y down), z (NDC depth) and w (clip w).
    """
    aspect = width / height
    mvp = np.stack([c.projection_matrix(aspect) @ c.view_matrix() for c in cameras])
    # Relative to the first target, like the evaluation renderer, for well-scaled sums.
    origin = np.asarray(cameras[0].target, dtype=np.float64)
    mvp = mvp.copy()
    mvp[:, :, 3] += mvp[:, :, :3] @ origin  # so that mvp @ (p - origin) == old mvp @ p
    rel = positions - origin
    clip = np.einsum("vij,nj->vni", mvp[:, :, :3], rel) + mvp[:, None, :, 3]
    w = clip[..., 3]
    with np.errstate(divide="ignore", invalid="ignore"):
        inv_w = np.where(w > 0.0, 1.0 / np.where(w > 0.0, w, 1.0), 0.0)
    screen = np.empty(clip.shape)
    screen[..., 0] = (clip[..., 0] * inv_w + 1.0) * (0.5 * width)
    screen[..., 1] = (1.0 - clip[..., 1] * inv_w) * (0.5 * height)
    screen[..., 2] = clip[..., 2] * inv_w
    screen[..., 3] = w
    return np.ascontiguousarray(screen)


def _check(mesh, cameras, width, height):
    cameras = list(cameras)
    width, height = int(width), int(height)
    if width < 1 or height < 1:
        raise ValueError(f"image size must be positive, got {width} x {height}")
    return cameras, width, height


# -- numba kernels --------------------------------------------------------------------------

@njit(cache=True, parallel=True)
def _raster_kernel(screen, faces, width, height):
    """Face index per pixel (-1 empty) by z-buffered scan conversion.

    screen : (V, n, 4) float64, faces : (m, 3) int32 -> (V, height, width) int32.
    """
    n_views = screen.shape[0]
    ids = np.full((n_views, height, width), -1, np.int32)
    for v in prange(n_views):
        depth = np.full((height, width), np.inf)
        s = screen[v]
        for f in range(faces.shape[0]):
            i0, i1, i2 = faces[f, 0], faces[f, 1], faces[f, 2]
            if s[i0, 3] <= 0.0 or s[i1, 3] <= 0.0 or s[i2, 3] <= 0.0:
                continue
            x0, y0, z0 = s[i0, 0], s[i0, 1], s[i0, 2]
            x1, y1, z1 = s[i1, 0], s[i1, 1], s[i1, 2]
            x2, y2, z2 = s[i2, 0], s[i2, 1], s[i2, 2]
            area = (x1 - x0) * (y2 - y0) - (x2 - x0) * (y1 - y0)
            if not area != 0.0:  # zero or NaN
                continue
            if area < 0.0:  # make the winding positive: swap vertices 1 and 2
                x1, y1, z1, x2, y2, z2 = x2, y2, z2, x1, y1, z1
                area = -area
            cmin = max(0, int(np.ceil(min(x0, x1, x2) - 0.5)))
            cmax = min(width - 1, int(np.floor(max(x0, x1, x2) - 0.5)))
            rmin = max(0, int(np.ceil(min(y0, y1, y2) - 0.5)))
            rmax = min(height - 1, int(np.floor(max(y0, y1, y2) - 0.5)))
            if cmin > cmax or rmin > rmax:
                continue
            # Edge k is opposite vertex k; top-left: dy < 0, or dy == 0 and dx > 0.
            dx0, dy0 = x2 - x1, y2 - y1
            dx1, dy1 = x0 - x2, y0 - y2
            dx2, dy2 = x1 - x0, y1 - y0
            tl0 = dy0 < 0.0 or (dy0 == 0.0 and dx0 > 0.0)
            tl1 = dy1 < 0.0 or (dy1 == 0.0 and dx1 > 0.0)
            tl2 = dy2 < 0.0 or (dy2 == 0.0 and dx2 > 0.0)
            inv_area = 1.0 / area
            for r in range(rmin, rmax + 1):
                py = r + 0.5
                for c in range(cmin, cmax + 1):
                    px = c + 0.5
                    e0 = dx0 * (py - y1) - dy0 * (px - x1)
                    if e0 < 0.0 or (e0 == 0.0 and not tl0):
                        continue
                    e1 = dx1 * (py - y2) - dy1 * (px - x2)
                    if e1 < 0.0 or (e1 == 0.0 and not tl1):
                        continue
                    e2 = dx2 * (py - y0) - dy2 * (px - x0)
                    if e2 < 0.0 or (e2 == 0.0 and not tl2):
                        continue
                    z = (e0 * z0 + e1 * z1 + e2 * z2) * inv_area
                    if z < -1.0 or z > 1.0:
                        continue
                    if z < depth[r, c]:
                        depth[r, c] = z
                        ids[v, r, c] = f
    return ids


@njit(cache=True)
def _weights(s, i0, i1, i2, px, py):
    """Perspective-correct barycentrics (b0, b1, b2) of pixel centre (px, py)."""
    x0, y0 = s[i0, 0], s[i0, 1]
    x1, y1 = s[i1, 0], s[i1, 1]
    x2, y2 = s[i2, 0], s[i2, 1]
    e0 = (x2 - x1) * (py - y1) - (y2 - y1) * (px - x1)
    e1 = (x0 - x2) * (py - y2) - (y0 - y2) * (px - x2)
    e2 = (x1 - x0) * (py - y0) - (y1 - y0) * (px - x0)
    q0, q1, q2 = e0 / s[i0, 3], e1 / s[i1, 3], e2 / s[i2, 3]
    total = q0 + q1 + q2
    return q0 / total, q1 / total, q2 / total


@njit(cache=True)
def _texel(tex, u, v):
    """Bilinear, repeat-wrapped texture colour (3 floats on 0..1); uv origin bottom-left,
    texture row 0 at the top."""
    h, w = tex.shape[0], tex.shape[1]
    x = u * w - 0.5
    y = (1.0 - v) * h - 0.5
    fx, fy = np.floor(x), np.floor(y)
    ax, ay = x - fx, y - fy
    c0, r0 = int(fx) % w, int(fy) % h
    c1, r1 = (c0 + 1) % w, (r0 + 1) % h
    out = np.empty(3)
    for k in range(3):
        top = tex[r0, c0, k] * (1.0 - ax) + tex[r0, c1, k] * ax
        bottom = tex[r1, c0, k] * (1.0 - ax) + tex[r1, c1, k] * ax
        out[k] = (top * (1.0 - ay) + bottom * ay) / 255.0
    return out


@njit(cache=True)
def _to_luma(base, lit, spec):
    """8-bit quantised colour base * lit + spec, then its luminance on 0..255."""
    y = 0.0
    for k in range(3):
        c = min(max(base[k] * lit + spec, 0.0), 1.0)
        y += np.floor(c * 255.0 + 0.5) * (0.299, 0.587, 0.114)[k]
    return y


@njit(cache=True, parallel=True)
def _shade_kernel(ids, screen, positions, faces, face_normals, eyes, vertex_light,
                  gouraud, specular, ambient, diffuse, ks, shininess, albedo,
                  uv, texture, textured, background):
    """Luminance per pixel of the face in ``ids``.

    ids : (V, H, W) int32; screen : (V, n, 4); positions : (n, 3); faces : (m, 3);
    face_normals : (m, 3); eyes : (V, 3); vertex_light : (V, n, 4) float64 holding
    (lit front, spec front, lit back, spec back); uv : (n, 2); texture : (h, w, c)
    uint8. Returns (V, H, W) float64.
    """
    n_views, height, width = ids.shape
    out = np.empty((n_views, height, width))
    for v in prange(n_views):
        s = screen[v]
        ex, ey, ez = eyes[v, 0], eyes[v, 1], eyes[v, 2]
        base = np.full(3, albedo)
        for r in range(height):
            py = r + 0.5
            for c in range(width):
                f = ids[v, r, c]
                if f < 0:
                    out[v, r, c] = background
                    continue
                px = c + 0.5
                i0, i1, i2 = faces[f, 0], faces[f, 1], faces[f, 2]
                b0, b1, b2 = _weights(s, i0, i1, i2, px, py)
                if gouraud:
                    x0, y0 = s[i0, 0], s[i0, 1]
                    area = ((s[i1, 0] - x0) * (s[i2, 1] - y0)
                            - (s[i2, 0] - x0) * (s[i1, 1] - y0))
                    k = 0 if area < 0.0 else 2  # y-down clockwise == GL front face
                    lit = (b0 * vertex_light[v, i0, k] + b1 * vertex_light[v, i1, k]
                           + b2 * vertex_light[v, i2, k])
                    spec = (b0 * vertex_light[v, i0, k + 1] + b1 * vertex_light[v, i1, k + 1]
                            + b2 * vertex_light[v, i2, k + 1])
                else:
                    qx = b0 * positions[i0, 0] + b1 * positions[i1, 0] + b2 * positions[i2, 0]
                    qy = b0 * positions[i0, 1] + b1 * positions[i1, 1] + b2 * positions[i2, 1]
                    qz = b0 * positions[i0, 2] + b1 * positions[i1, 2] + b2 * positions[i2, 2]
                    lx, ly, lz = ex - qx, ey - qy, ez - qz
                    norm = np.sqrt(lx * lx + ly * ly + lz * lz)
                    d = abs(face_normals[f, 0] * lx + face_normals[f, 1] * ly
                            + face_normals[f, 2] * lz) / norm
                    lit = ambient + diffuse * d
                    spec = ks * d ** shininess if specular else 0.0
                if textured:
                    tu = b0 * uv[i0, 0] + b1 * uv[i1, 0] + b2 * uv[i2, 0]
                    tv = b0 * uv[i0, 1] + b1 * uv[i1, 1] + b2 * uv[i2, 1]
                    out[v, r, c] = _to_luma(_texel(texture, tu, tv), lit, spec)
                else:
                    out[v, r, c] = _to_luma(base, lit, spec)
    return out


# -- public API ---------------------------------------------------------------------------

def face_id_buffers(mesh, cameras, width: int = 256, height: int = 256) -> np.ndarray:
    """The index of the face seen at each pixel centre, for each camera.

    Parameters
    ----------
    mesh : bench.mesh.Mesh
        Positions (n, 3) and faces (m, 3) are used.
    cameras : sequence of V metrics.views.Camera
    width, height : int
        Image size in pixels.

    Returns
    -------
    ndarray of shape (V, height, width) int32
        Face indices into ``mesh.faces``, -1 where no face covers the pixel centre; row
        0 is the top of the image. Same rasterisation as :func:`rasterize_luminance`.
    """
    cameras, width, height = _check(mesh, cameras, width, height)
    ids, _ = _ids_and_screen(mesh, cameras, width, height)
    return ids


def _ids_and_screen(mesh, cameras, width, height):
    if not cameras:
        return np.empty((0, height, width), np.int32), None
    if mesh.n_faces == 0:
        return np.full((len(cameras), height, width), -1, np.int32), None
    screen = _project(mesh.positions, cameras, width, height)
    faces = np.ascontiguousarray(mesh.faces, dtype=np.int32)
    return _raster_kernel(screen, faces, width, height), screen


def rasterize_luminance(mesh, cameras, width: int = 256, height: int = 256,
                        shading: str = "flat", specular: bool = False,
                        constants=None) -> np.ndarray:
    """Luminance images of ``mesh``, shaded as the evaluation renderer without MSAA.

    Parameters
    ----------
    mesh : bench.mesh.Mesh
        Positions (n, 3), faces (m, 3); ``vertex_normals`` for gouraud; ``uv`` (n, 2)
        and ``texture`` (h, w, 3|4) uint8 for the albedo when both are present.
    cameras : sequence of V metrics.views.Camera
    width, height : int
        Image size in pixels.
    shading : {"flat", "gouraud"}
    specular : bool
        Add the Blinn-Phong highlight ``ks * max(0, n.h)^shininess`` (h = l here).
    constants : metrics.render.ShadingConstants, optional
        Ambient, diffuse, albedo, specular and shininess; the defaults are the
        protocol's (ambient 0.1, diffuse 0.9, albedo 1).

    Returns
    -------
    ndarray of shape (V, height, width) float64
        Y = 0.299 R + 0.587 G + 0.114 B of the 8-bit colour on 0..255; 128 where no
        face covers the pixel centre; row 0 at the top.
    """
    if shading not in SHADINGS:
        raise ValueError(f"shading must be one of {SHADINGS}, got {shading!r}")
    cameras, width, height = _check(mesh, cameras, width, height)
    if constants is None:
        from metrics.render import DEFAULT_CONSTANTS as constants
    ids, screen = _ids_and_screen(mesh, cameras, width, height)
    if screen is None:
        return np.full(ids.shape, float(BACKGROUND))
    positions = np.ascontiguousarray(mesh.positions, dtype=np.float64)
    faces = np.ascontiguousarray(mesh.faces, dtype=np.int32)
    eyes = np.stack([np.asarray(c.eye, dtype=np.float64) for c in cameras])
    a, d = float(constants.ambient), float(constants.diffuse)
    ks, shin = float(constants.specular), float(constants.shininess)
    gouraud = shading == "gouraud"
    if gouraud:
        light = vertex_light(positions, np.asarray(mesh.vertex_normals, dtype=np.float64),
                             eyes, a, d, ks, shin, specular)
        face_n = np.zeros((1, 3))
    else:
        light = np.zeros((1, 1, 4))
        face_n = np.ascontiguousarray(mesh.face_normals, dtype=np.float64)
    textured = bool(mesh.has_texture)
    if textured:
        uv = np.ascontiguousarray(mesh.uv, dtype=np.float64)
        texture = np.ascontiguousarray(mesh.texture[:, :, :3])
    else:
        uv = np.zeros((1, 2))
        texture = np.zeros((1, 1, 3), np.uint8)
    return _shade_kernel(ids, screen, positions, faces, face_n, eyes, light, gouraud,
                         bool(specular), a, d, ks, shin, float(constants.albedo), uv,
                         texture, textured, float(BACKGROUND))
