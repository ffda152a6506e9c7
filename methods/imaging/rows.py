"""Per-vertex and per-face quantities of the image term: screen positions, pixel boxes,
vertex normals and lighting, and the per-face rows of :mod:`methods.imaging.raster`'s
table for the faces a collapse changes."""

from __future__ import annotations

import numpy as np
from numba import njit

from methods.corners import corners
from methods.imaging.raster import T_L, T_N, T_P, T_UV, T_W, T_X, T_Y, T_Z, ZERO

#: Faces around one vertex summed into its normal (:func:`vertex_normal` raises beyond).
NORMAL_FACES_CAP = 1024


@njit(cache=True, inline="always")
def _has(F, f, x):
    return F[f, 0] == x or F[f, 1] == x or F[f, 2] == x


@njit(cache=True, inline="always")
def removed_by(F, f, u, v):
    """Whether collapsing ``u`` into ``v`` removes face ``f`` (it holds both; never
    with ``u = -1``, the mesh as it is)."""
    return u >= 0 and _has(F, f, u) and _has(F, f, v)


@njit(cache=True)
def project(M, h, p, width, height, out):
    """Screen (x, y pixels with y down, NDC z, clip w) of point ``p`` in view ``h``."""
    cx = M[h, 0, 0] * p[0] + M[h, 0, 1] * p[1] + M[h, 0, 2] * p[2] + M[h, 0, 3]
    cy = M[h, 1, 0] * p[0] + M[h, 1, 1] * p[1] + M[h, 1, 2] * p[2] + M[h, 1, 3]
    cz = M[h, 2, 0] * p[0] + M[h, 2, 1] * p[1] + M[h, 2, 2] * p[2] + M[h, 2, 3]
    cw = M[h, 3, 0] * p[0] + M[h, 3, 1] * p[1] + M[h, 3, 2] * p[2] + M[h, 3, 3]
    inv_w = 1.0 / cw if cw > 0.0 else 0.0
    out[0] = (cx * inv_w + 1.0) * (0.5 * width)
    out[1] = (1.0 - cy * inv_w) * (0.5 * height)
    out[2] = cz * inv_w
    out[3] = cw


@njit(cache=True)
def row_box(t, k, width, height, out):
    """Pixel box (c0, c1, r0, r1) that :func:`methods.imaging.raster.scan_row` visits for row
    ``k`` (c0 > c1 when it visits nothing)."""
    out[0], out[1], out[2], out[3] = 0, -1, 0, -1
    if t[k, T_W] <= 0.0 or t[k, T_W + 1] <= 0.0 or t[k, T_W + 2] <= 0.0:
        return
    x0, x1, x2 = t[k, T_X], t[k, T_X + 1], t[k, T_X + 2]
    y0, y1, y2 = t[k, T_Y], t[k, T_Y + 1], t[k, T_Y + 2]
    if not (np.isfinite(x0) and np.isfinite(x1) and np.isfinite(x2) and np.isfinite(y0)
            and np.isfinite(y1) and np.isfinite(y2)):
        return
    out[0] = int(min(max(np.ceil(min(x0, x1, x2) - 0.5), 0.0), float(width)))
    out[1] = int(max(min(np.floor(max(x0, x1, x2) - 0.5), width - 1.0), -1.0))
    out[2] = int(min(max(np.ceil(min(y0, y1, y2) - 0.5), 0.0), float(height)))
    out[3] = int(max(min(np.floor(max(y0, y1, y2) - 0.5), height - 1.0), -1.0))


@njit(cache=True)
def _light(px, py, pz, n, eye, shading, out, o):
    """Headlight terms of a vertex for both sides, as :func:`methods.imaging.raster.vertex_light`:
    out[o:o+4] = (lit front, spec front, lit back, spec back)."""
    tx, ty, tz = eye[0] - px, eye[1] - py, eye[2] - pz
    length = np.sqrt(tx * tx + ty * ty + tz * tz)
    dot = (tx * n[0] + ty * n[1] + tz * n[2]) / length
    for side in range(2):
        c = max(dot if side == 0 else -dot, 0.0)
        out[o + 2 * side] = shading.ambient + shading.diffuse * c
        out[o + 2 * side + 1] = shading.ks * c ** shading.shininess if shading.specular else 0.0


@njit(cache=True)
def _sort_small(a, n):
    for i in range(1, n):
        x = a[i]
        j = i - 1
        while j >= 0 and a[j] > x:
            a[j + 1] = a[j]
            j -= 1
        a[j + 1] = x


@njit(cache=True)
def _pos(x, u, v, p, P, d):
    return p[d] if u >= 0 and (x == u or x == v) else P[x, d]


@njit(cache=True)
def vertex_normal(x, move, surface, buf, out):
    """Unit area-weighted normal of vertex ``x`` after ``move`` = (u, v, p), collapsing
    ``u`` into ``v`` at ``p`` (``u = -1``: the current mesh), on ``surface`` = (P, F,
    vhead, cnext, falive). Faces are summed in increasing index."""
    u, v, p = move
    P, F, vhead, cnext, falive = surface
    n = ZERO
    for side in range(2):
        y = np.int64(x) if side == 0 else np.int64(u)
        if side == 1 and not (u >= 0 and x == v):
            break
        for c in corners(y, vhead, cnext):
            f = c // 3
            if falive[f] and not removed_by(F, f, u, v):
                if n == buf.shape[0]:
                    raise ValueError("a vertex has more faces than NORMAL_FACES_CAP "
                                     "(methods.imaging.rows)")
                buf[n] = f
                n += 1
    _sort_small(buf, n)
    sx = sy = sz = 0.0
    for i in range(n):
        f = buf[i]
        a, b, c = F[f, 0], F[f, 1], F[f, 2]
        ax, ay, az = _pos(a, u, v, p, P, 0), _pos(a, u, v, p, P, 1), _pos(a, u, v, p, P, 2)
        e1x, e1y, e1z = (_pos(b, u, v, p, P, 0) - ax, _pos(b, u, v, p, P, 1) - ay,
                         _pos(b, u, v, p, P, 2) - az)
        e2x, e2y, e2z = (_pos(c, u, v, p, P, 0) - ax, _pos(c, u, v, p, P, 1) - ay,
                         _pos(c, u, v, p, P, 2) - az)
        sx += e1y * e2z - e1z * e2y
        sy += e1z * e2x - e1x * e2z
        sz += e1x * e2y - e1y * e2x
    length = np.sqrt(sx * sx + sy * sy + sz * sz)
    if length > 0.0:
        out[0], out[1], out[2] = sx / length, sy / length, sz / length
    else:
        out[0] = out[1] = out[2] = 0.0


@njit(cache=True)
def fill_screen(row, move, S, F):
    """Screen columns of ``row`` = (t, k, f, h), row ``k`` of table ``t``: face ``f`` in
    view ``h`` after ``move`` = (u, v, sp), collapsing ``u`` into ``v`` (whose screen
    position becomes ``sp``); ``u = -1`` for the current mesh."""
    t, k, f, h = row
    u, v, sp = move
    for j in range(3):
        x = F[f, j]
        if u >= 0 and (x == u or x == v):
            t[k, T_X + j], t[k, T_Y + j], t[k, T_Z + j], t[k, T_W + j] = sp[0], sp[1], \
                sp[2], sp[3]
        else:
            t[k, T_X + j], t[k, T_Y + j], t[k, T_Z + j], t[k, T_W + j] = S[h, x, 0], \
                S[h, x, 1], S[h, x, 2], S[h, x, 3]


@njit(cache=True)
def fill_shading(row, move, surface, light, wedges, shading):
    """Shading columns of ``row`` after ``move`` = (u, v, p) (as :func:`fill_screen`):
    corner positions and the face normal (flat), corner lighting (gouraud; ``light`` =
    (L, vslot, ov_light): the new lighting of the vertices in ``vslot``), texture
    coordinates (``wedges`` = (wslot, new_uv, wfrom, wto, npairs): the new ones of the
    wedges in ``wslot``, u's merged wedges renamed by the pairs) on ``surface`` = (P,
    F, FW, uv)."""
    t, k, f, h = row
    u, v, p = move
    P, F, FW, uv = surface
    L, vslot, ov_light = light
    wslot, new_uv, wfrom, wto, npairs = wedges
    gouraud, textured = shading.gouraud, shading.textured
    for j in range(3):
        x = F[f, j]
        moved = u >= 0 and (x == u or x == v)
        for d in range(3):
            t[k, T_P + 3 * j + d] = p[d] if moved else P[x, d]
        if gouraud:
            slot = vslot[v if moved else x]
            for d in range(4):
                t[k, T_L + 4 * j + d] = ov_light[h, slot, d] if slot >= 0 else L[h, x, d]
        if textured:
            w = FW[f, j]
            if u >= 0 and x == u:
                for i in range(npairs):
                    if wfrom[i] == w:
                        w = wto[i]
                        break
            s = wslot[w]
            t[k, T_UV + 2 * j] = new_uv[s, 0] if s >= 0 else uv[w, 0]
            t[k, T_UV + 2 * j + 1] = new_uv[s, 1] if s >= 0 else uv[w, 1]
    if not gouraud:
        e1x = t[k, T_P + 3] - t[k, T_P]
        e1y = t[k, T_P + 4] - t[k, T_P + 1]
        e1z = t[k, T_P + 5] - t[k, T_P + 2]
        e2x = t[k, T_P + 6] - t[k, T_P]
        e2y = t[k, T_P + 7] - t[k, T_P + 1]
        e2z = t[k, T_P + 8] - t[k, T_P + 2]
        nx, ny, nz = e1y * e2z - e1z * e2y, e1z * e2x - e1x * e2z, e1x * e2y - e1y * e2x
        length = np.sqrt(nx * nx + ny * ny + nz * nz)
        inv = 1.0 / length if length > 0.0 else 0.0
        t[k, T_N], t[k, T_N + 1], t[k, T_N + 2] = nx * inv, ny * inv, nz * inv
